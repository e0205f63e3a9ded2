//! Fuzz entry points: each takes arbitrary bytes, builds kernel inputs from them, runs the
//! SIMD body and the scalar reference, and panics if a property fails:
//!
//! * no panic inside a kernel, and every refusal is a `FrameError`, never a crash;
//! * SIMD output equals the scalar reference bit for bit;
//! * no non-finite value is written from finite inputs;
//! * weights lie in [0, 1], reason codes are valid and their counts add up.
//!
//! The cargo-fuzz targets in `fuzz/` are one-line shims over these, and `cargo test`
//! replays the committed seed corpus through them (`kernels/tests/fuzz_corpus.rs`).
//!
//! Input format: a few leading bytes pick the extent, stride padding, cameras and
//! tolerances; the rest is a list of 6-byte edits `(plane, index: u8 u8 → u16, value: f32)`
//! applied over an analytic scene, so short inputs already reach deep into the kernels and
//! every edit can place a NaN, an infinity, a subnormal or a huge value anywhere.

mod images;
mod input;
mod raster;
mod traverse;

pub use images::{accumulate, atrous, bilinear, clamp, gradient, reproject, ssim, variance_blend};
pub use input::{Bytes, replay_dir, run_on_this_thread};
pub use raster::{RASTER_FUZZ_EXTENT, plane_depth, raster, raster_fixed, screen_boundary};
pub use traverse::traverse;
