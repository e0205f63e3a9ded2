//! What every exported function does at the language boundary: turn a Rust error into a
//! status code plus a message the caller can read, and stop a panic before it unwinds into
//! C (undefined behaviour) by reporting it as [`StStatus::Panic`].

use std::cell::RefCell;
use std::ffi::{CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

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
    /// outputs may be partly written. Please report it with the message.
    Panic = 5,
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
        Self::invalid(e.to_string())
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
