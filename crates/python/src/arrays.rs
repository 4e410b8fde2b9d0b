//! numpy arrays in and out. The Python layer hands over C-contiguous `float64` arrays
//! (`numpy.ascontiguousarray`, which copies only when it must); these helpers check the
//! shapes again and view the data without copying.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::value_error;

/// The rows of an `(n, 3)` array as points, without copying.
///
/// # Errors
/// `ValueError` for another shape, a non-contiguous array, or (with `finite`) a NaN or
/// infinite coordinate, naming `name` and the row.
pub(crate) fn points<'a>(
    a: &'a PyReadonlyArray2<'_, f64>,
    name: &str,
    finite: bool,
) -> PyResult<&'a [[f64; 3]]> {
    let shape = a.shape();
    if shape[1] != 3 {
        return Err(value_error(format!(
            "{name} must have shape (n, 3), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    let flat = a
        .as_slice()
        .map_err(|_| value_error(format!("{name} must be C-contiguous")))?;
    let (rows, _) = flat.as_chunks::<3>();
    if finite && let Some(i) = rows.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
        return Err(value_error(format!(
            "{name}[{i}] = {:?} is not finite",
            rows[i]
        )));
    }
    Ok(rows)
}

/// `rows` as an `(n, 3)` array (the vector's memory handed to numpy).
pub(crate) fn rows_array(py: Python<'_>, rows: Vec<[f64; 3]>) -> Bound<'_, PyArray2<f64>> {
    let n = rows.len();
    Array2::from_shape_vec((n, 3), rows.into_flattened())
        .expect("n × 3 values")
        .into_pyarray(py)
}

/// `v` as a 1-D array (the vector's memory handed to numpy).
pub(crate) fn vector(py: Python<'_>, v: Vec<f64>) -> Bound<'_, PyArray1<f64>> {
    v.into_pyarray(py)
}

/// `(lo, hi)` from two 3-sequences.
pub(crate) fn corners(lo: [f64; 3], hi: [f64; 3], name: &str) -> PyResult<[[f64; 3]; 2]> {
    if lo.iter().chain(&hi).any(|x| !x.is_finite()) {
        return Err(value_error(format!(
            "{name} must be finite, got {lo:?} .. {hi:?}"
        )));
    }
    Ok([lo, hi])
}
