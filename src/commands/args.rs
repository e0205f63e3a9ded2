//! The argument groups that several commands share, and the parsers that validate each value
//! where it is read. A command flattens the groups it takes and sets its own defaults with
//! [`default`] (`#[command(mut_arg("res", default("1280x720")))]`), so a flag, its help and
//! its check are written once.

use std::path::PathBuf;

use clap::{Arg, Args};

use crate::eval::EvalSpec;
use crate::kernels::Extent;
use crate::pipeline::{MAX_SPP, budget_duration, check_spp};
use crate::render::{FirstSample, GBufferPass, RendererOptions};

/// The scene a command renders and its size per eye.
#[derive(Args, Clone, Debug)]
pub struct SceneArgs {
    /// A built-in scene name (see `stereotrace scenes`), a manifest (*.toml) or a scene folder.
    #[arg(long)]
    pub scene: String,
    /// Resolution per eye, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_resolution)]
    pub res: Extent,
}

/// The worker threads of a timed command.
#[derive(Args, Clone, Copy, Debug)]
pub struct ThreadsArg {
    /// Worker threads.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub threads: u16,
}

impl ThreadsArg {
    /// A pool of that many threads.
    pub fn pool(self) -> Result<rayon::ThreadPool, String> {
        rayon::ThreadPoolBuilder::new()
            .num_threads(usize::from(self.threads))
            .build()
            .map_err(|e| format!("cannot start {} threads: {e}", self.threads))
    }
}

/// The references and error curves a quality measurement compares against, and the cache
/// that keeps them (shared by `eval` and `tradeoff`, whose measurements reuse each other's).
#[derive(Args, Clone, Debug)]
pub struct ReferenceArgs {
    /// Samples per pixel of the references (default: the preset's; tradeoff: the quick
    /// preset's 256).
    #[arg(long, value_parser = parse_spp)]
    pub reference_spp: Option<u32>,
    /// Last spp of the path-traced error curves (default: the preset's; tradeoff: 128).
    #[arg(long, value_parser = parse_spp)]
    pub curve_spp: Option<u32>,
    /// Cache folder for references, curves and results.
    #[arg(long, default_value = "out/eval-cache")]
    pub cache: PathBuf,
}

impl ReferenceArgs {
    /// `spec` with the values given on the command line.
    pub fn apply(&self, spec: &mut EvalSpec) {
        if let Some(r) = self.reference_spp {
            spec.reference_spp = r;
        }
        if let Some(m) = self.curve_spp {
            spec.curve_spp = m;
        }
    }
}

/// How the pipelines make their G-buffers.
#[derive(Args, Clone, Copy, Debug)]
pub struct GBufferArg {
    /// How the G-buffers are made: rasterised in fixed point as GPUs do (default), traced (the
    /// reference), or rasterised with the tracer's triangle test (exact).
    #[arg(long, value_enum, default_value_t = GBufferPass::Raster)]
    pub gbuffer: GBufferPass,
    /// Where each pixel's first sample of a frame starts: jittered in the pixel (default, the
    /// paper's) or at its centre, whose hit a rasterised G-buffer pass has already found.
    #[arg(long, value_enum, default_value_t = FirstSample::Jittered)]
    pub first_sample: FirstSample,
}

impl GBufferArg {
    /// The renderer's options these flags name.
    pub fn options(&self) -> RendererOptions {
        RendererOptions::with_first_sample(self.gbuffer, self.first_sample)
    }
}

/// A command's own default for a flag of a shared group: `value`, and the flag no longer
/// required.
pub fn default(value: &'static str) -> impl FnOnce(Arg) -> Arg {
    move |arg| arg.default_value(value).required(false)
}

/// Parses `WxH` into a validated extent.
pub fn parse_resolution(s: &str) -> Result<Extent, String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("resolution '{s}' is not of the form WIDTHxHEIGHT"))?;
    let parse = |v: &str, what: &str| {
        v.trim().parse::<usize>().map_err(|_| format!("resolution '{s}': {what} '{v}' is not a whole number"))
    };
    let (w, h) = (parse(w, "width")?, parse(h, "height")?);
    Extent::new(w, h).map_err(|e| format!("resolution '{s}': {e}"))
}

/// Parses an exposure multiplier: finite and positive (NaN, inf, 0 or a negative value would
/// write black or meaningless previews).
pub fn parse_exposure(s: &str) -> Result<f32, String> {
    let v: f32 = s.trim().parse().map_err(|_| format!("exposure '{s}' is not a number"))?;
    if v.is_finite() && v > 0.0 { Ok(v) } else { Err(format!("exposure {s} must be finite and > 0")) }
}

/// The most frames a command renders or measures (10⁶; every frame is kept or written).
pub const MAX_FRAMES: u32 = 1_000_000;

/// Parses a sample count, checked by the pipeline's own rule ([`check_spp`]).
pub fn parse_spp(s: &str) -> Result<u32, String> {
    // A count beyond u32 is refused here, naming what was typed (not a clamped number).
    let v: u32 =
        s.trim().parse().map_err(|_| format!("samples per pixel '{s}' is not a whole number in 1..={MAX_SPP}"))?;
    check_spp(v)
}

/// Parses a frame count: a whole number in 1 ..= [`MAX_FRAMES`].
pub fn parse_frames(s: &str) -> Result<u32, String> {
    let v: u64 = s.trim().parse().map_err(|_| format!("frame count '{s}' is not a whole number"))?;
    if (1..=u64::from(MAX_FRAMES)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(format!("frame count {v} must be in 1..={MAX_FRAMES}"))
    }
}

/// Parses a per-frame budget in milliseconds, checked by the pipeline's own rule
/// ([`budget_duration`]).
pub fn parse_budget_ms(s: &str) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|_| format!("budget '{s}' is not a number"))?;
    budget_duration(v).map(|_| v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolutions_parse_and_bad_ones_are_explained() {
        assert_eq!(parse_resolution("1280x720").unwrap(), Extent::new(1280, 720).unwrap());
        assert!(parse_resolution("1280").unwrap_err().contains("WIDTHxHEIGHT"));
        assert!(parse_resolution("0x10").unwrap_err().contains("zero"));
        assert!(parse_resolution("axb").unwrap_err().contains("whole number"));
        assert!(parse_resolution("100000x10").unwrap_err().contains("too large"));
    }

    #[test]
    fn exposures_must_be_finite_and_positive() {
        assert_eq!(parse_exposure("2.5").unwrap(), 2.5);
        for bad in ["NaN", "inf", "-1", "0", "x"] {
            assert!(parse_exposure(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn counts_are_refused_by_the_pipelines_rule() {
        assert_eq!(parse_spp("4").unwrap(), 4);
        for bad in ["0", "-1", "4294967296", "99999999999", "x"] {
            assert!(parse_spp(bad).is_err(), "{bad}");
        }
        assert!(parse_frames("0").is_err() && parse_frames("1000001").is_err());
        assert!(parse_budget_ms("NaN").is_err() && parse_budget_ms("0").is_err());
    }
}
