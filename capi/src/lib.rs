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

use boundary::{Failure, guard};

/// The library's major version: a header and a library agree when their majors are equal.
pub const STEREOTRACE_VERSION_MAJOR: u32 = 0;
/// The library's minor version.
pub const STEREOTRACE_VERSION_MINOR: u32 = 1;
/// The library's patch version.
pub const STEREOTRACE_VERSION_PATCH: u32 = 0;

/// The library's version as `major * 10000 + minor * 100 + patch`, to compare with the
/// header's `STEREOTRACE_VERSION_*` constants at run time.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_version() -> u32 {
    STEREOTRACE_VERSION_MAJOR * 10_000 + STEREOTRACE_VERSION_MINOR * 100 + STEREOTRACE_VERSION_PATCH
}

/// The library's version as text (`"0.1.0"`); a static string, never freed.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_version_string() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// What the kernels run on: a pool of worker threads. Opaque to C.
pub struct StContext {
    pool: rayon::ThreadPool,
}

impl StContext {
    /// Runs `f` on this context's threads.
    pub(crate) fn run<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        self.pool.install(f)
    }
}

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
        if threads > 1024 {
            return Err(Failure::invalid(format!("threads must be at most 1024, got {threads}")));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads as usize)
            .thread_name(|i| format!("stereotrace-{i}"))
            .build()
            .map_err(|e| Failure::invalid(format!("could not start {threads} worker threads: {e}")))?;
        let context = Box::into_raw(Box::new(StContext { pool }));
        // SAFETY: checked non-null above; the caller's contract makes it writable.
        unsafe { out.write(context) };
        Ok(())
    })
}

/// Destroys a context made by [`stereotrace_context_create`] (null is ignored).
///
/// # Safety
/// `context` must be null or a context from [`stereotrace_context_create`] not yet
/// destroyed, with no call using it in progress.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_context_destroy(context: *mut StContext) {
    if !context.is_null() {
        // SAFETY: the caller's contract: made by `Box::into_raw` in `stereotrace_context_create`.
        drop(unsafe { Box::from_raw(context) });
    }
}
