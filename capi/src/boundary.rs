//! What every exported function does at the language boundary: turn a Rust error into a
//! status code plus a message the caller can read, and stop a panic before it unwinds into
//! C (undefined behaviour) by reporting it as [`StStatus::Panic`].
//!
//! # The entry-point contract
//! Every exported function's body is one `unsafe` block inside [`guard`], under one
//! contract, which its `SAFETY` comment names: the raw pointers it reads are its own
//! arguments, which the caller keeps valid as the function's `# Safety` section (and the
//! header) states; each pointer is checked for null (`required`, `as_ref`) before it is
//! read; and planes are only read or written through the views of `views.rs`, which check
//! each plane's extent and stride and refuse any output that overlaps another buffer of the
//! call. Nothing else in a body is unsafe. `clippy::undocumented_unsafe_blocks` is denied in
//! this crate, so a new block without its reason does not build.

use std::cell::RefCell;
use std::ffi::{CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::{Mutex, MutexGuard, PoisonError, TryLockError};

use stereotrace_kernels::FrameError;

/// What a call returned. Every function that can fail returns one; the message of the last
/// failure on the calling thread is [`stereotrace_last_error`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StStatus {
    /// The call did what it says; its outputs are written.
    Ok = 0,
    /// A required pointer was null (the message names it).
    NullPointer = 1,
    /// A size, stride, extent, camera or parameter was refused (the message says which and why).
    InvalidArgument = 2,
    /// An output buffer overlaps another buffer of the same call.
    Aliasing = 3,
    /// A pointer is not aligned for its element type.
    Misaligned = 4,
    /// A bug inside the library was caught before it could unwind into the caller; the
    /// outputs may be partly written, and the pipeline or context it happened in refuses
    /// every later call but its destruction. Please report it with the message.
    Panic = 5,
    /// A callback of the caller's (`fill_gbuffers` or `trace`) returned non-zero; the
    /// message gives its return value. The frame was refused: output, history and
    /// statistics are as before the call.
    CallbackFailed = 6,
    /// Memory for a buffer the call needed could not be allocated (the message gives the
    /// size). Nothing was created or changed; the process goes on.
    OutOfMemory = 7,
    /// The pipeline or context is in a call already: this call came from one of its own
    /// callbacks or from another thread while that call runs. The message names the call in
    /// progress. Nothing was changed; calls on other pipelines and contexts are unaffected.
    Busy = 8,
}

/// A refused call: the status and what to tell the caller.
#[derive(Debug)]
pub(crate) struct Failure {
    pub status: StStatus,
    pub message: String,
}

impl Failure {
    pub fn new(status: StStatus, message: impl Into<String>) -> Self {
        Self { status, message: message.into() }
    }

    pub fn null(what: &str) -> Self {
        Self::new(StStatus::NullPointer, format!("{what} is a null pointer"))
    }

    pub fn invalid(message: impl Into<String>) -> Self {
        Self::new(StStatus::InvalidArgument, message)
    }
}

impl From<FrameError> for Failure {
    fn from(e: FrameError) -> Self {
        let status = match e {
            FrameError::OutOfMemory { .. } => StStatus::OutOfMemory,
            _ => StStatus::InvalidArgument,
        };
        Self::new(status, e.to_string())
    }
}

/// An object of the C ABI (a pipeline, a context) that one call at a time may use. Every
/// exported function on it enters first: a second call while one runs (from the running
/// call's own callbacks, or from another thread) is refused with [`StStatus::Busy`] and
/// changes nothing, instead of forming a second `&mut` to the same state (undefined
/// behaviour in Rust, and a nested frame inside the outer one's buffers).
pub(crate) struct Exclusive<T> {
    /// `"pipeline"` or `"context"`, for messages.
    what: &'static str,
    state: Mutex<T>,
    /// The exported function that holds `state` (or held it last).
    call: Mutex<&'static str>,
}

impl<T> Exclusive<T> {
    pub fn new(what: &'static str, state: T) -> Self {
        Self { what, state: Mutex::new(state), call: Mutex::new("") }
    }

    /// The state, for the duration of `call` (the exported function's name), or why not.
    pub fn enter(&self, call: &'static str) -> Result<MutexGuard<'_, T>, Failure> {
        // The name's lock is held while the state is taken and named, so a call refused in
        // between reads the running call's name, not the one before it (or none: CI's
        // ThreadSanitizer run once saw "busy in " from a refusal that landed there).
        let mut current = self.call.lock().unwrap_or_else(PoisonError::into_inner);
        match self.state.try_lock() {
            Ok(state) => {
                *current = call;
                Ok(state)
            }
            Err(TryLockError::WouldBlock) => {
                let current = *current;
                Err(Failure::new(
                    StStatus::Busy,
                    format!(
                        "{call}: this {} is busy in {current} (called from one of its callbacks, or from another \
                         thread during that call); nothing was changed",
                        self.what
                    ),
                ))
            }
            Err(TryLockError::Poisoned(_)) => Err(Failure::new(
                StStatus::Panic,
                format!(
                    "{call}: an earlier call on this {} panicked and left it in an unknown state; destroy it",
                    self.what
                ),
            )),
        }
    }

    /// Whether no call is in progress (a destroy checks it; a panicked object may be
    /// destroyed).
    pub fn idle(&self, call: &'static str) -> Result<(), Failure> {
        match self.enter(call) {
            Ok(_) => Ok(()),
            Err(f) if f.status == StStatus::Panic => Ok(()),
            Err(f) => Err(f),
        }
    }
}

/// Adds which argument a kernel error is about.
pub(crate) trait Context<T> {
    fn about(self, what: &str) -> Result<T, Failure>;
}

impl<T> Context<T> for Result<T, FrameError> {
    fn about(self, what: &str) -> Result<T, Failure> {
        self.map_err(|e| Failure::invalid(format!("{what}: {e}")))
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: &str) {
    // A message with an interior NUL would be cut there by C anyway; say so instead.
    let text = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// Runs one exported call: `Ok` clears the last error; a failure or a panic sets it.
pub(crate) fn guard(call: impl FnOnce() -> Result<(), Failure>) -> StStatus {
    match catch_unwind(AssertUnwindSafe(call)) {
        Ok(Ok(())) => {
            set_last_error("");
            StStatus::Ok
        }
        Ok(Err(failure)) => {
            set_last_error(&failure.message);
            failure.status
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".into());
            set_last_error(&format!("internal error (please report): {what}"));
            StStatus::Panic
        }
    }
}

/// The message of the last failed call on this thread, or an empty string after a call
/// that succeeded. Never null. The text stays valid until the next call into the library
/// on this thread; copy it to keep it.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}
