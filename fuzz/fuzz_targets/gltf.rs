#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(
    init: {
        stereotrace_kernels::fuzzing::run_on_this_thread();
        stereotrace::fuzzing::let_caught_panics_pass();
    },
    |data: &[u8]| stereotrace::fuzzing::gltf(data)
);
