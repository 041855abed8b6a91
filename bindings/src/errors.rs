//! The exceptions of the core's errors ([`dynmesh::Error`]), one class per kind, and the
//! guard that turns a panic inside the core into [`InternalError`] rather than pyo3's
//! `PanicException`. `dynmesh` and `dynmesh.api` re-export the classes.
//!
//! - [`InputError`] (`ValueError`): input the codec refuses (a malformed mesh, an option or
//!   argument out of range); args `(message,)`.
//! - [`DecodeError`] (`ValueError`): data that cannot be decoded; args `(message, frame or
//!   None, byte offset)` for a stream, `(message,)` for a coded block given on its own (a UV
//!   atlas, a texture unit payload).
//! - [`UnsupportedError`] (`ValueError`): well-formed data this build does not read (another
//!   format version, an unknown texture codec); args `(message,)`.
//! - [`InternalError`] (`RuntimeError`): a bug in dynmesh (a panic in the core); args
//!   `(message,)`, the message saying so and naming where the panic happened.
//!
//! The panic hook ([`install_panic_hook`]) records where a panic happened for that message
//! instead of printing Rust's report on stderr, so that the command line's error stays one
//! line; with `RUST_BACKTRACE` set, Rust's report (and backtrace) is printed as well.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Mutex;

use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

use dynmesh::Error;

create_exception!(_core, InputError, PyValueError, "Input the codec refuses: a malformed mesh, an option or argument out of range; args are (message,).");
create_exception!(
    _core,
    DecodeError,
    PyValueError,
    "Data that cannot be decoded; args are (message, frame or None, byte offset) for a stream, (message,) for a coded block given on its own."
);
create_exception!(
    _core,
    UnsupportedError,
    PyValueError,
    "Well-formed data this build does not read: a stream of another format version, a texture unit of an unknown codec; args are (message,)."
);
create_exception!(_core, InternalError, PyRuntimeError, "A bug in dynmesh (a panic in its core); args are (message,), which says so.");

/// The exception of `e`, its message the error's text.
pub(crate) fn core_error(e: Error) -> PyErr {
    let message = e.to_string();
    match e {
        Error::Input(_) => InputError::new_err(message),
        Error::Decode { frame, offset: Some(offset), .. } => DecodeError::new_err((message, frame, offset)),
        Error::Decode { offset: None, .. } => DecodeError::new_err(message),
        Error::Unsupported(_) => UnsupportedError::new_err(message),
        Error::Internal(_) => InternalError::new_err(message),
        _ => InternalError::new_err(format!("internal error (a bug in dynmesh, please report it): unclassified error: {message}")),
    }
}

/// [`InputError`] with `message`: the bindings' own checks of their arguments.
pub(crate) fn input_error(message: impl Into<String>) -> PyErr {
    InputError::new_err(message.into())
}

/// Where the last panic happened (`file:line:column`), as the hook recorded it.
static LAST_PANIC_AT: Mutex<Option<String>> = Mutex::new(None);

/// Makes panics record their location for [`InternalError`]'s message rather than print
/// Rust's report, unless `RUST_BACKTRACE` asks for it.
fn install_panic_hook() {
    let report = std::panic::take_hook();
    let verbose = std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0");
    std::panic::set_hook(Box::new(move |info| {
        if let Some(at) = info.location() {
            *LAST_PANIC_AT.lock().unwrap_or_else(|e| e.into_inner()) = Some(at.to_string());
        }
        if verbose {
            report(info);
        }
    }));
}

/// The [`InternalError`] of a caught panic, naming where it happened.
fn panic_error(payload: Box<dyn std::any::Any + Send>) -> PyErr {
    let e = match Error::from_panic(payload.as_ref()) {
        Error::Internal(m) => match LAST_PANIC_AT.lock().unwrap_or_else(|e| e.into_inner()).take() {
            Some(at) => Error::Internal(format!("{m} (at {at})")),
            None => Error::Internal(m),
        },
        other => other,
    };
    core_error(e)
}

/// `f()` with the GIL released, as `py.allow_threads` runs it, a panic inside it (on this
/// thread or on the core's worker threads, which hand theirs back) raised as [`InternalError`].
pub(crate) fn released<T: Send>(py: Python<'_>, f: impl FnOnce() -> T + Send) -> PyResult<T> {
    py.allow_threads(|| catch_unwind(AssertUnwindSafe(f))).map_err(panic_error)
}

/// `f()` with the GIL held, a panic inside it raised as [`InternalError`].
pub(crate) fn guarded<T>(f: impl FnOnce() -> T) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).map_err(panic_error)
}

/// A panic inside the guard, for the tests of the mapping (`tests/test_errors.py`): raises
/// InternalError with `message`.
#[pyfunction]
fn _panic_for_tests(py: Python<'_>, message: String) -> PyResult<()> {
    released(py, || panic!("{message}"))
}

/// Adds the exception classes (and the test hook) to the module, and installs the panic hook.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    install_panic_hook();
    let py = m.py();
    for (name, class) in [
        ("InputError", py.get_type::<InputError>()),
        ("DecodeError", py.get_type::<DecodeError>()),
        ("UnsupportedError", py.get_type::<UnsupportedError>()),
        ("InternalError", py.get_type::<InternalError>()),
    ] {
        // Where `import` finds the class, so that its exceptions pickle (worker processes).
        class.setattr("__module__", "dynmesh._core")?;
        m.add(name, class)?;
    }
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    Ok(())
}
