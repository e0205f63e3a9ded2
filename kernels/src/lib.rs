//! # stereotrace-kernels
//!
//! The hand-vectorized kernels of stereotrace: bilinear resampling, backward reprojection
//! (stereo and temporal are one kernel with different cameras), EMA accumulation and stereo
//! blending, temporal gradients, and an edge-avoiding à-trous filter. Each kernel has a scalar reference and a SIMD body (`wide`, 8 lanes) in the
//! same module; the scalar one is always compiled and public, and the two agree bit for bit
//! (see the determinism policy in [`simd`]). SSIM also has a 16-lane AVX-512 body, chosen at
//! run time where the CPU has it ([`isa`]).
//!
//! Callers own every buffer. Views are validated once at the boundary ([`frame`]); inside,
//! kernels do not fail, do not panic and do not allocate. Parallel kernels split their output
//! into row bands and run them with rayon on the caller's current pool (use
//! `ThreadPool::install` to choose it).

#![warn(missing_docs)]

pub mod accumulate;
pub mod atrous;
mod bands;
pub mod bilinear;
pub mod bvh;
pub mod camera;
pub mod check;
pub mod clamp;
pub mod colour;
pub mod frame;
pub mod fuzzing;
pub mod gbuffer;
pub mod gradient;
pub mod isa;
mod lanes;
pub mod raster;
pub mod reproject;
pub mod simd;
pub mod ssim;
pub mod synth;
pub mod traverse;

pub use camera::CameraModel;
pub use frame::{Extent, FrameError, Plane, PlaneBuf, PlaneMut, RgbBuf, RgbPlanes, RgbPlanesMut};
pub use gbuffer::{CompactGBuffer, GBuffer, GBufferBuf, SurfaceLayout};
