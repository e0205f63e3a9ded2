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
mod kernels;
mod pipeline;
mod views;

use std::ffi::c_char;

pub use boundary::{StStatus, stereotrace_last_error};
pub use kernels::*;
pub use pipeline::*;
pub use views::{StPlaneF32, StPlaneMutF32, StPlaneMutU8, StPlaneU8, StPlaneU32, StRgb, StRgbMut};

use boundary::{Exclusive, Failure, guard};

/// The library's major version: a header and a library agree when their majors are equal.
pub const STEREOTRACE_VERSION_MAJOR: u32 = 0;
/// The library's minor version. 0.2: `ST_STATUS_CALLBACK_FAILED`, `_OUT_OF_MEMORY` and
/// `_BUSY`; the destroy functions return a status; the `STEREOTRACE_MAX_*` limits.
pub const STEREOTRACE_VERSION_MINOR: u32 = 2;
/// The library's patch version.
pub const STEREOTRACE_VERSION_PATCH: u32 = 0;

/// The library's version as `major * 10000 + minor * 100 + patch`, to compare with the
/// header's `STEREOTRACE_VERSION_*` constants at run time.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_version() -> u32 {
    STEREOTRACE_VERSION_MAJOR * 10_000 + STEREOTRACE_VERSION_MINOR * 100 + STEREOTRACE_VERSION_PATCH
}

/// The library's version as text (`"0.2.0"`); a static string, never freed.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_version_string() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// What the kernels run on: a pool of worker threads. Opaque to C. One call at a time:
/// a kernel call on a context that is in a call on another thread is refused with
/// `ST_STATUS_BUSY`.
pub struct StContext {
    pool: Exclusive<rayon::ThreadPool>,
}

impl StContext {
    /// Runs `f` on this context's threads for the exported function `call`, or refuses if
    /// the context is in another call.
    pub(crate) fn run<T: Send>(&self, call: &'static str, f: impl FnOnce() -> T + Send) -> Result<T, Failure> {
        let pool = self.pool.enter(call)?;
        Ok(pool.install(f))
    }
}

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

/// Creates a context with `threads` worker threads (0: one per logical CPU) and stores it in
/// `*out`. Destroy it with [`stereotrace_context_destroy`].
///
/// # Safety
/// `out` must be null (refused) or point to writable storage for one pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_context_create(threads: u32, out: *mut *mut StContext) -> StStatus {
    guard(|| {
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let pool = thread_pool(threads, "threads", "stereotrace")?;
        let context = Box::into_raw(Box::new(StContext { pool: Exclusive::new("context", pool) }));
        // SAFETY: checked non-null above; the caller's contract makes it writable.
        unsafe { out.write(context) };
        Ok(())
    })
}

/// A pool of `threads` workers named `name-i` (0: one per logical CPU), refusing more than
/// [`STEREOTRACE_MAX_THREADS`] (`what` names the argument).
pub(crate) fn thread_pool(threads: u32, what: &str, name: &'static str) -> Result<rayon::ThreadPool, Failure> {
    check_threads(threads, what)?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads as usize)
        .thread_name(move |i| format!("{name}-{i}"))
        .build()
        .map_err(|e| Failure::new(StStatus::OutOfMemory, format!("could not start {threads} worker threads: {e}")))
}

/// Refuses a thread count above [`STEREOTRACE_MAX_THREADS`] (`what` names the argument).
pub(crate) fn check_threads(threads: u32, what: &str) -> Result<(), Failure> {
    if threads > STEREOTRACE_MAX_THREADS {
        return Err(Failure::invalid(format!(
            "{what} must be at most STEREOTRACE_MAX_THREADS ({STEREOTRACE_MAX_THREADS}), got {threads}"
        )));
    }
    Ok(())
}

/// Destroys a context made by [`stereotrace_context_create`] (null is ignored: OK). A
/// context in a call (on another thread) is not destroyed: `ST_STATUS_BUSY`.
///
/// # Safety
/// `context` must be null or a context from [`stereotrace_context_create`] not yet
/// destroyed; no call may start on it once this one has returned OK.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_context_destroy(context: *mut StContext) -> StStatus {
    guard(|| {
        // SAFETY: null, or a live context (the caller's contract).
        let Some(c) = (unsafe { context.as_ref() }) else { return Ok(()) };
        c.pool.idle("stereotrace_context_destroy")?;
        // SAFETY: the caller's contract: made by `Box::into_raw` in `stereotrace_context_create`,
        // and no call holds it (checked above).
        drop(unsafe { Box::from_raw(context) });
        Ok(())
    })
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
