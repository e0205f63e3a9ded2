//! `stereotrace ssim A.exr B.exr`: SSIM (the paper's 3-D volume and the per-channel
//! variant) and RMSE of two linear HDR images.

use std::fmt::Write as _;
use std::path::Path;

use crate::image_io::read_exr;
use crate::kernels::ssim::{SsimParams, SsimVariant, ssim};

/// Compares two EXR files; returns the report. Every error names the file at fault.
pub fn run(a: &Path, b: &Path) -> Result<String, String> {
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
    let _ = write!(out, "RMSE:                  {:.6e}", volume.rmse);
    if volume.non_finite > 0 {
        let _ = write!(
            out,
            "\nwarning: {} non-finite or out-of-range samples were excluded ({} of {} SSIM voxels used)",
            volume.non_finite,
            volume.voxels,
            3 * ea.pixels()
        );
    }
    Ok(out)
}
