//! The CLI subcommands' logic (the binary in `main.rs` only parses arguments and reports
//! errors).

pub mod eval;
pub mod render;
pub mod ssim;
pub mod throughput;
pub mod tradeoff;

use crate::kernels::Extent;

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

pub use crate::pipeline::{MAX_BUDGET_MS, MAX_SPP, budget_duration};

/// The most frames a command renders or measures (10⁶; every frame is kept or written).
pub const MAX_FRAMES: u32 = 1_000_000;

/// Parses a sample count: a whole number in 1 ..= [`MAX_SPP`].
pub fn parse_spp(s: &str) -> Result<u32, String> {
    parse_count(s, "samples per pixel", MAX_SPP)
}

/// Parses a frame count: a whole number in 1 ..= [`MAX_FRAMES`].
pub fn parse_frames(s: &str) -> Result<u32, String> {
    parse_count(s, "frame count", MAX_FRAMES)
}

fn parse_count(s: &str, what: &str, max: u32) -> Result<u32, String> {
    let v: u64 = s.trim().parse().map_err(|_| format!("{what} '{s}' is not a whole number"))?;
    if (1..=u64::from(max)).contains(&v) { Ok(v as u32) } else { Err(format!("{what} {v} must be in 1..={max}")) }
}

/// Parses a per-frame budget in milliseconds: finite, > 0 and at most [`MAX_BUDGET_MS`] (NaN,
/// infinite, zero or negative budgets have no meaning, and a huge one overflows a duration).
pub fn parse_budget_ms(s: &str) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|_| format!("budget '{s}' is not a number"))?;
    budget_duration(v).map(|_| v)
}

/// `stereotrace export-scene`: writes `spec` at frame 0 into `out` in the shared folder format.
pub fn export_scene(spec: &str, out: &std::path::Path) -> Result<String, String> {
    let scene = crate::scene::resolve(spec).map_err(|e| e.to_string())?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let s = crate::scene::export::export_folder(&scene, out).map_err(|e| e.to_string())?;
    let frozen = if s.frozen_lights > 0 {
        format!(", {} moving light(s) frozen at frame 0", s.frozen_lights)
    } else {
        String::new()
    };
    Ok(format!(
        "exported {}: {} triangles, {} materials, {} images{frozen} to {}",
        scene.name,
        s.triangles,
        s.materials,
        s.images,
        out.display()
    ))
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
}
