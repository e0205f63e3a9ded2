//! # stereotrace-capi
//!
//! The C ABI of stereotrace: the kernels on caller-owned buffers (stereo and temporal
//! backward reprojection in full and compact G-buffer layouts, EMA accumulation, the stereo
//! blend, SSIM) and the frame pipeline, over this project's renderer on a scene or over an
//! engine's own G-buffers and tracer given as callbacks. `include/stereotrace.h` is generated from this crate by cbindgen (the `header`
//! test regenerates it and fails on a difference; `STEREOTRACE_BLESS=1` rewrites it).
//!
//! Rules every function keeps (the header repeats them):
//! * A **context** ([`stereotrace_context_create`] / [`stereotrace_context_destroy`]) owns
//!   the worker threads the kernels run on; one context may be used by one thread at a time.
//! * Buffers are the caller's: planes of `float`, `uint8_t` or `uint32_t` given as pointer,
//!   width, height and stride in elements. Nothing is retained after a call returns.
//! * Every pointer, size, stride, camera and parameter is checked; a refused call returns a
//!   status other than `ST_STATUS_OK`, writes no output, and [`stereotrace_last_error`]
//!   says why. An output that overlaps another buffer of the call is refused.
//! * No panic crosses the boundary: a bug inside is reported as `ST_STATUS_PANIC`.

#![deny(clippy::undocumented_unsafe_blocks)]
#![warn(missing_docs)]

mod boundary;
mod context;
mod kernels;
mod limits;
mod pipeline;
mod views;

use std::ffi::c_char;

pub use boundary::{StStatus, stereotrace_last_error};
pub use context::{StContext, stereotrace_context_create, stereotrace_context_destroy};
pub use kernels::*;
pub use limits::*;
pub use pipeline::*;
pub use views::{StPlaneF32, StPlaneMutF32, StPlaneMutU8, StPlaneU8, StPlaneU32, StRgb, StRgbMut};

/// The library's major version. A header and a library agree when their majors are equal
/// and, while the major is 0, their minors too (a 0.x minor may grow a struct).
pub const STEREOTRACE_VERSION_MAJOR: u32 = 0;
/// The library's minor version. 0.5: `StPipelineConfig.background` (`StBackground`).
/// 0.4: `ST_HISTORY_CLAMP` and
/// `StFrameStats.history_clamped`. 0.3: `StPipelineConfig.history`, `.blend` and `.filter`,
/// and their counts and times in `StFrameStats`. 0.2: `ST_STATUS_CALLBACK_FAILED`,
/// `_OUT_OF_MEMORY` and `_BUSY`; the destroy functions return a status; the
/// `STEREOTRACE_MAX_*` limits.
pub const STEREOTRACE_VERSION_MINOR: u32 = 5;
/// The library's patch version.
pub const STEREOTRACE_VERSION_PATCH: u32 = 0;

/// The library's version as `major * 10000 + minor * 100 + patch`, to compare with the
/// header's `STEREOTRACE_VERSION_*` constants at run time.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_version() -> u32 {
    STEREOTRACE_VERSION_MAJOR * 10_000 + STEREOTRACE_VERSION_MINOR * 100 + STEREOTRACE_VERSION_PATCH
}

/// The library's version as text (`"0.5.0"`); a static string, never freed.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_version_string() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A context's destroy uses the guard every call on it takes; holding the guard here is
    /// a call in progress, deterministically (the C test can only race for it).
    #[test]
    #[allow(clippy::undocumented_unsafe_blocks)] // each call gets the context it just made
    fn a_context_in_a_call_is_not_destroyed() {
        let mut context = std::ptr::null_mut();
        assert_eq!(unsafe { stereotrace_context_create(1, &mut context) }, StStatus::Ok);
        let in_call = unsafe { &*context }.pool.enter("stereotrace_ssim").unwrap();
        assert_eq!(unsafe { stereotrace_context_destroy(context) }, StStatus::Busy);
        let message = unsafe { std::ffi::CStr::from_ptr(stereotrace_last_error()) }.to_string_lossy().into_owned();
        assert!(message.contains("stereotrace_context_destroy: this context is busy in stereotrace_ssim"), "{message}");
        drop(in_call);
        assert_eq!(unsafe { stereotrace_context_destroy(context) }, StStatus::Ok);
    }
}
