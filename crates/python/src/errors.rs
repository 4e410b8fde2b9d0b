//! Rust errors as Python exceptions: `OSError` (or its `FileNotFoundError` /
//! `PermissionError` subclasses) when an I/O error is anywhere in the chain, `ValueError`
//! otherwise, with the whole chain of messages.

use std::error::Error;
use std::io::ErrorKind;

use pyo3::PyErr;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyValueError};

/// `e` with its sources as one message, each source once (`reading x.ply: line 3: …`).
pub(crate) fn message(e: &(dyn Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let part = s.to_string();
        if !text.contains(&part) {
            text.push_str(": ");
            text.push_str(&part);
        }
        source = s.source();
    }
    text
}

/// The Python exception for `e` (see the module docs).
pub(crate) fn to_py<E: Error + 'static>(e: E) -> PyErr {
    let text = message(&e);
    let mut source: Option<&(dyn Error + 'static)> = Some(&e);
    while let Some(s) = source {
        if let Some(io) = s.downcast_ref::<std::io::Error>() {
            return match io.kind() {
                ErrorKind::NotFound => PyFileNotFoundError::new_err(text),
                ErrorKind::PermissionDenied => PyPermissionError::new_err(text),
                _ => PyOSError::new_err(text),
            };
        }
        source = s.source();
    }
    PyValueError::new_err(text)
}

/// A `ValueError` with `text`.
pub(crate) fn value_error(text: impl Into<String>) -> PyErr {
    PyValueError::new_err(text.into())
}
