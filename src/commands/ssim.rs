//! `stereotrace ssim A.exr B.exr`: SSIM (the paper's 3-D volume and the per-channel
//! variant) and RMSE of two linear HDR images.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::image_io::read_exr;
use crate::kernels::ssim::{SsimParams, SsimVariant, ssim};

/// `v` with six significant digits: plain where that reads well, scientific otherwise (an
/// RMSE of 0.578 reads `0.578633`, not `5.786326e-1`).
fn six_digits(v: f64) -> String {
    if v == 0.0 || (1e-3..1e6).contains(&v.abs()) {
        let decimals = if v == 0.0 { 6 } else { (5 - v.abs().log10().floor() as i32).max(0) as usize };
        format!("{v:.decimals$}")
    } else {
        format!("{v:.5e}")
    }
}

/// Options of `stereotrace ssim`.
#[derive(Args, Clone, Debug)]
pub struct SsimOptions {
    /// First image (EXR).
    pub a: PathBuf,
    /// Second image (EXR).
    pub b: PathBuf,
    /// Leave non-finite and out-of-range samples out instead of failing.
    #[arg(long)]
    pub exclude_nonfinite: bool,
}

/// `stereotrace ssim`: compares the two images of `opts`.
pub fn run_command(opts: &SsimOptions) -> Result<String, String> {
    run(&opts.a, &opts.b, opts.exclude_nonfinite)
}

/// Compares two EXR files; returns the report. Every error names the file at fault. Samples
/// that are not finite (or out of the kernel's range) in either image are an error unless
/// `exclude_nonfinite`; a comparison with no usable sample is an error either way.
pub fn run(a: &Path, b: &Path, exclude_nonfinite: bool) -> Result<String, String> {
    let img_a = read_exr(a).map_err(|e| e.to_string())?;
    let img_b = read_exr(b).map_err(|e| e.to_string())?;
    let (ea, eb) = (img_a.extent(), img_b.extent());
    if ea != eb {
        return Err(format!("{} is {ea} but {} is {eb}: the images must have the same size", a.display(), b.display()));
    }
    let volume = ssim(&img_a.view(), &img_b.view(), &SsimParams::with_variant(SsimVariant::Volume))
        .map_err(|e| e.to_string())?;
    let per_channel = ssim(&img_a.view(), &img_b.view(), &SsimParams::with_variant(SsimVariant::PerChannel))
        .map_err(|e| e.to_string())?;
    let samples = 3 * ea.pixels();
    if volume.non_finite > 0 && !exclude_nonfinite {
        return Err(format!(
            "{} of {samples} samples of {} vs {} are non-finite or out of range; SSIM and RMSE \
             would leave them out (pass --exclude-nonfinite to compare the rest)",
            volume.non_finite,
            a.display(),
            b.display()
        ));
    }
    if volume.voxels == 0 || !volume.ssim.is_finite() || !per_channel.ssim.is_finite() {
        return Err(format!(
            "{} vs {}: no sample is finite in both images ({} of {samples} excluded), nothing to compare",
            a.display(),
            b.display(),
            volume.non_finite
        ));
    }
    let mut out = String::new();
    let c = volume.per_channel;
    let p = per_channel.per_channel;
    let _ = writeln!(out, "images:               {} vs {} ({ea})", a.display(), b.display());
    let _ = writeln!(
        out,
        "SSIM (3-D RGB volume): {:.6}   (R {:.6}, G {:.6}, B {:.6} slices)",
        volume.ssim, c[0], c[1], c[2]
    );
    let _ =
        writeln!(out, "SSIM (per channel):    {:.6}   (R {:.6}, G {:.6}, B {:.6})", per_channel.ssim, p[0], p[1], p[2]);
    let _ = write!(out, "RMSE:                  {}", six_digits(volume.rmse));
    if volume.non_finite > 0 {
        let _ = write!(
            out,
            "\nwarning: {} non-finite or out-of-range samples were excluded ({} of {} SSIM voxels used)",
            volume.non_finite, volume.voxels, samples
        );
    }
    Ok(out)
}
