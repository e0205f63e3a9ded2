//! The CPU level the binary was built for, and a check that this CPU has it.

/// Fails with a readable message when the binary was compiled for AVX2 + FMA (the project's
/// x86-64-v3 baseline, set in `.cargo/config.toml`) and this CPU lacks them. Call it before
/// any kernel runs: an illegal-instruction crash is the alternative.
pub fn check_cpu() -> Result<(), String> {
    #[cfg(target_arch = "x86_64")]
    {
        let needed = [
            ("avx2", cfg!(target_feature = "avx2"), std::arch::is_x86_feature_detected!("avx2")),
            ("fma", cfg!(target_feature = "fma"), std::arch::is_x86_feature_detected!("fma")),
            ("f16c", cfg!(target_feature = "f16c"), std::arch::is_x86_feature_detected!("f16c")),
        ];
        let missing: Vec<&str> = needed.iter().filter(|(_, built, has)| *built && !*has).map(|(n, _, _)| *n).collect();
        if !missing.is_empty() {
            return Err(format!(
                "this binary was built for x86-64-v3 but the CPU lacks {}; rebuild with RUSTFLAGS=\"-C target-cpu=x86-64\" (slower SSE2 kernels)",
                missing.join(", ")
            ));
        }
    }
    Ok(())
}

/// Fails with a readable message when `STEREOTRACE_ISA` names an unknown instruction set or
/// one this CPU lacks ([`stereotrace_kernels::isa::Isa::from_env`]): a typo is an error, not a
/// silent fallback to the detected set.
pub fn check_isa_env() -> Result<(), String> {
    stereotrace_kernels::isa::Isa::from_env().map(|_| ()).map_err(|e| e.to_string())
}

/// A one-line description of the SIMD level: the level compiled in, and the wider bodies
/// chosen at run time where the CPU has them ([`stereotrace_kernels::isa`]), for benchmark
/// and driver output.
pub fn simd_level() -> String {
    match stereotrace_kernels::isa::Isa::active() {
        stereotrace_kernels::isa::Isa::Avx512 => format!("{}, AVX-512 bodies at run time", build_level()),
        stereotrace_kernels::isa::Isa::Avx2 => build_level().to_string(),
    }
}

/// The SIMD level compiled in.
fn build_level() -> &'static str {
    if cfg!(target_feature = "avx512f") {
        "x86-64-v4 (AVX-512)"
    } else if cfg!(all(target_feature = "avx2", target_feature = "fma")) {
        "x86-64-v3 (AVX2+FMA)"
    } else if cfg!(target_arch = "x86_64") {
        "x86-64 (SSE2)"
    } else {
        "non-x86"
    }
}
