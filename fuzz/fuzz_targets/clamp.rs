#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: stereotrace_kernels::fuzzing::run_on_this_thread(), |data: &[u8]| stereotrace_kernels::fuzzing::clamp(data));
