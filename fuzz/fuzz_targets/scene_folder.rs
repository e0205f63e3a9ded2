#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| stereotrace::fuzzing::scene_folder(data));
