//! The instruction set a kernel runs with, chosen at run time.
//!
//! The crate is compiled for the x86-64-v3 baseline (AVX2 + FMA), so every kernel has an
//! 8-lane body that runs anywhere the binary does. Kernels whose time is in arithmetic also
//! have a 16-lane AVX-512 body, compiled into the same binary inside
//! `#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]` functions and taken only
//! when the CPU reports those features ([`Isa::detected`]). Today that is SSIM
//! ([`crate::ssim::ssim_with`]) and reprojection ([`crate::reproject::reproject_with`]),
//! whose AVX-512 body takes 16 pixels at a time where both G-buffers are compact and the
//! group is an ordinary one, and is its 8-lane body compiled with AVX-512 elsewhere. The BVH
//! traversal loops (single rays and packets) are also compiled a second time with AVX-512, at
//! eight lanes still: the tree runs the build its [`crate::bvh::TriangleBvh::isa`] names.
//!
//! The choice is made once per process ([`Isa::active`]) and can be narrowed with the
//! environment variable [`ISA_ENV`] (`STEREOTRACE_ISA=avx2` forces the 8-lane bodies on an
//! AVX-512 machine, to compare the two in one binary). Entry points that take an `Isa`
//! argument let tests and benches run both bodies in one process.

use std::sync::OnceLock;

/// The environment variable that narrows the instruction set: `avx2` or `avx512`.
pub const ISA_ENV: &str = "STEREOTRACE_ISA";

/// An instruction set a kernel body is written for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Isa {
    /// 8 lanes: AVX2 + FMA (or two SSE halves in a build for the SSE2 baseline).
    Avx2,
    /// 16 lanes: AVX-512 F, BW, DQ and VL.
    Avx512,
}

/// `STEREOTRACE_ISA` named something this CPU or this crate cannot run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IsaError(String);

impl std::fmt::Display for IsaError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for IsaError {}

impl Isa {
    /// Every instruction set, narrowest first.
    pub const ALL: [Isa; 2] = [Isa::Avx2, Isa::Avx512];

    /// The name `STEREOTRACE_ISA` takes.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// Whether this CPU can run the body (the 8-lane body always can: the binary's baseline).
    pub fn is_supported(self) -> bool {
        match self {
            Isa::Avx2 => true,
            Isa::Avx512 => avx512_detected(),
        }
    }

    /// Every instruction set this CPU supports, narrowest first (the bodies a test compares).
    pub fn supported() -> impl Iterator<Item = Isa> {
        Isa::ALL.into_iter().filter(|isa| isa.is_supported())
    }

    /// The widest instruction set this CPU supports.
    pub fn detected() -> Isa {
        if Isa::Avx512.is_supported() { Isa::Avx512 } else { Isa::Avx2 }
    }

    /// The choice [`ISA_ENV`] asks for: `Ok(None)` when it is unset or empty, an error when it
    /// names an unknown set or one this CPU lacks. The CLI calls this at start-up, so a typo
    /// is reported instead of ignored.
    pub fn from_env() -> Result<Option<Isa>, IsaError> {
        match std::env::var(ISA_ENV) {
            Ok(v) if v.trim().is_empty() => Ok(None),
            Ok(v) => Isa::parse(v.trim()).map(Some),
            Err(std::env::VarError::NotPresent) => Ok(None),
            Err(std::env::VarError::NotUnicode(_)) => {
                Err(IsaError(format!("{ISA_ENV} is not valid Unicode; use avx2 or avx512")))
            }
        }
    }

    /// Parses a name (`avx2` or `avx512`, any case) and checks that this CPU supports it.
    pub fn parse(name: &str) -> Result<Isa, IsaError> {
        let isa = Isa::ALL
            .into_iter()
            .find(|isa| isa.name().eq_ignore_ascii_case(name))
            .ok_or_else(|| IsaError(format!("{ISA_ENV}={name:?} is not an instruction set; use avx2 or avx512")))?;
        if !isa.is_supported() {
            return Err(IsaError(format!(
                "{ISA_ENV}={name} but this CPU lacks AVX-512 (F, BW, DQ and VL are needed); use avx2 or unset it"
            )));
        }
        Ok(isa)
    }

    /// The instruction set the kernels use in this process: [`ISA_ENV`] where it names a
    /// supported set, [`Isa::detected`] otherwise (an invalid value is ignored here; call
    /// [`Isa::from_env`] to report it). Read once.
    pub fn active() -> Isa {
        static ACTIVE: OnceLock<Isa> = OnceLock::new();
        *ACTIVE.get_or_init(|| Isa::from_env().ok().flatten().unwrap_or_else(Isa::detected))
    }
}

#[cfg(target_arch = "x86_64")]
fn avx512_detected() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512vl")
}

#[cfg(not(target_arch = "x86_64"))]
fn avx512_detected() -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_unknown_names_are_refused() {
        assert_eq!(Isa::parse("AVX2"), Ok(Isa::Avx2));
        let err = Isa::parse("sse9").unwrap_err().to_string();
        assert!(err.contains("sse9") && err.contains("avx2 or avx512"), "{err}");
        match Isa::parse("avx512") {
            Ok(isa) => assert!(isa.is_supported() && Isa::detected() == Isa::Avx512),
            Err(e) => assert!(e.to_string().contains("lacks AVX-512") && Isa::detected() == Isa::Avx2),
        }
    }

    #[test]
    fn the_active_set_is_supported() {
        assert!(Isa::active().is_supported());
    }
}
