//! The kernels' context: the worker threads the kernel calls run on, one call at a time.

use crate::boundary::{Exclusive, Failure, StStatus, guard};
use crate::limits::STEREOTRACE_MAX_THREADS;

/// What the kernels run on: a pool of worker threads. Opaque to C. One call at a time:
/// a kernel call on a context that is in a call on another thread is refused with
/// `ST_STATUS_BUSY`.
pub struct StContext {
    pub(crate) pool: Exclusive<rayon::ThreadPool>,
}

impl StContext {
    /// Runs `f` on this context's threads for the exported function `call`, or refuses if
    /// the context is in another call.
    pub(crate) fn run<T: Send>(&self, call: &'static str, f: impl FnOnce() -> T + Send) -> Result<T, Failure> {
        let pool = self.pool.enter(call)?;
        Ok(pool.install(f))
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
