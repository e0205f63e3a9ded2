//! The limits C sees, as constants of the header: the library checks exactly these values
//! (each equals the kernels' or the runtime's own limit, asserted at compile time).

/// The largest width or height of a plane, camera or pipeline frame, in pixels (2^15).
pub const STEREOTRACE_MAX_DIMENSION: u32 = 32768;
/// The most pixels of a plane, camera or pipeline frame (2^28: 16384 × 16384).
pub const STEREOTRACE_MAX_PIXELS: u64 = 268435456;
/// The largest row stride of a plane, in elements (4 × `STEREOTRACE_MAX_DIMENSION`).
pub const STEREOTRACE_MAX_STRIDE: u32 = 131072;
/// The most worker threads of a context or a pipeline (0 asks for one per logical CPU).
pub const STEREOTRACE_MAX_THREADS: u32 = 1024;
/// The most samples per pixel of a pipeline (2^20).
pub const STEREOTRACE_MAX_SPP: u32 = 1048576;
/// The largest per-frame budget of a pipeline, in milliseconds (0 means none).
pub const STEREOTRACE_MAX_BUDGET_MS: f64 = 1000000.0;
/// The smallest width and height `stereotrace_ssim` accepts: its 11×11 window.
pub const STEREOTRACE_SSIM_MIN_SIDE: u32 = 11;

// The limits C sees are the ones the library checks: validation uses the kernels' and the
// runtime's constants, and these must equal them (also checked against the header's text
// and at each limit by `tests/limits.rs`).
const _: () = {
    use stereotrace_kernels::frame::{MAX_DIMENSION, MAX_PIXELS};
    assert!(STEREOTRACE_MAX_DIMENSION as usize == MAX_DIMENSION);
    assert!(STEREOTRACE_MAX_PIXELS as usize == MAX_PIXELS);
    assert!(STEREOTRACE_MAX_STRIDE as usize == stereotrace_kernels::frame::MAX_STRIDE);
    assert!(STEREOTRACE_MAX_SPP == stereotrace_runtime::pipeline::MAX_SPP);
    assert!(STEREOTRACE_MAX_BUDGET_MS == stereotrace_runtime::pipeline::MAX_BUDGET_MS);
    assert!(STEREOTRACE_SSIM_MIN_SIDE as usize == stereotrace_kernels::ssim::MIN_SIDE);
};
