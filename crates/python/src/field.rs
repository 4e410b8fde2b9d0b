//! `NativeField`: any 3-D zeroset field (RBF, quadratic B-spline, neural, MRAS) behind one
//! Python object, evaluated in parallel with the GIL released; `load`, and the B-spline
//! through a numpy grid of samples.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;
use zeroset_bases::bspline::{BSplineField, Degree};
use zeroset_bases::field_file::{
    AnyField, decode_any, encode_any, read_any_field, read_dimension, write_any_field,
};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::Grid;

use crate::arrays::{points, rows_array, vector};
use crate::errors::{to_py, value_error};

/// A fitted, restored or loaded 3-D field (wrapped by `zeroset.Field`).
#[pyclass(frozen, module = "zeroset._zeroset")]
pub(crate) struct NativeField {
    pub(crate) inner: Arc<AnyField<3>>,
}

impl NativeField {
    pub(crate) fn new(field: AnyField<3>) -> Self {
        Self {
            inner: Arc::new(field),
        }
    }
}

#[pymethods]
impl NativeField {
    /// The field's values at the rows of an `(n, 3)` array.
    fn values<'py>(
        &self,
        py: Python<'py>,
        at: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let p = points(&at, "points", false)?;
        let field = &self.inner;
        let out = py.detach(|| {
            let mut out = vec![0.0; p.len()];
            field.values(p, &mut out);
            out
        });
        Ok(vector(py, out))
    }

    /// The field's gradients at the rows of an `(n, 3)` array, as an `(n, 3)` array.
    fn gradients<'py>(
        &self,
        py: Python<'py>,
        at: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let p = points(&at, "points", false)?;
        let field = &self.inner;
        let out = py.detach(|| {
            let mut out = vec![[0.0; 3]; p.len()];
            out.par_iter_mut()
                .zip(p.par_iter())
                .with_min_len(256)
                .for_each(|(g, x)| *g = field.gradient(x));
            out
        });
        Ok(rows_array(py, out))
    }

    /// `(lo, hi)`, the box the field is defined on (`None` if it has none).
    #[getter]
    fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        self.inner.bounds().map(|b| (b.min(), b.max()))
    }

    /// `"rbf"`, `"bspline"`, `"neural"` or `"mras"`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind()
    }

    /// The field in words.
    fn describe(&self) -> String {
        self.inner.describe()
    }

    /// The points an RBF field was fitted to (its centres), else `None`.
    fn centres<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        match self.inner.as_ref() {
            AnyField::Rbf(f) => Some(rows_array(py, f.centres().to_vec())),
            _ => None,
        }
    }

    /// Writes the field to a `.zsf` field file, atomically.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let field = &self.inner;
        py.detach(|| write_any_field(&path, field)).map_err(to_py)
    }

    /// The bytes of the field's `.zsf` file (for pickling).
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let field = &self.inner;
        let bytes = py.detach(|| encode_any(field));
        PyBytes::new(py, &bytes)
    }
}

/// The field in the bytes of a `.zsf` file (as `to_bytes` gives them; for unpickling).
#[pyfunction]
pub(crate) fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<NativeField> {
    let name = std::path::Path::new("<bytes>");
    py.detach(|| decode_any::<3>(data, name))
        .map(NativeField::new)
        .map_err(to_py)
}

/// Reads a 3-D field from a `.zsf` field file.
#[pyfunction]
pub(crate) fn load(py: Python<'_>, path: PathBuf) -> PyResult<NativeField> {
    py.detach(|| {
        if let Ok(d) = read_dimension(&path)
            && d != 3
        {
            return Err(value_error(format!(
                "{} holds a {d}-D field; the Python package handles 3-D fields (the `zeroset` \
                 command meshes 2-D ones as SVG curves)",
                path.display()
            )));
        }
        read_any_field::<3>(&path)
            .map(NativeField::new)
            .map_err(to_py)
    })
}

/// The quadratic B-spline through the samples of a 3-D array, sample `[i, j, k]` at
/// `origin + (i, j, k) · spacing` (the samples are the centres of the spline's cells).
#[pyfunction]
pub(crate) fn interpolate(
    py: Python<'_>,
    samples: PyReadonlyArray3<'_, f64>,
    origin: [f64; 3],
    spacing: [f64; 3],
) -> PyResult<NativeField> {
    let shape = samples.shape();
    let counts = [shape[0], shape[1], shape[2]];
    let bounds = sample_box(origin, spacing, counts)?;
    let values = samples
        .as_slice()
        .map_err(|_| value_error("the samples must be C-contiguous"))?
        .to_vec();
    py.detach(|| {
        let grid = Grid::cell_centered(bounds, counts).map_err(to_py)?;
        let spline = BSplineField::interpolate(grid, values, Degree::Quadratic).map_err(to_py)?;
        Ok(NativeField::new(AnyField::BSpline(spline)))
    })
}

/// The box whose cells of `spacing` are centred on the samples `origin + i · spacing`.
pub(crate) fn sample_box(
    origin: [f64; 3],
    spacing: [f64; 3],
    counts: [usize; 3],
) -> PyResult<Aabb<3>> {
    if spacing.iter().any(|h| !(h.is_finite() && *h > 0.0)) {
        return Err(value_error(format!(
            "spacing must be finite and positive, got {spacing:?}"
        )));
    }
    if origin.iter().any(|x| !x.is_finite()) {
        return Err(value_error(format!(
            "origin must be finite, got {origin:?}"
        )));
    }
    let lo: [f64; 3] = std::array::from_fn(|a| origin[a] - 0.5 * spacing[a]);
    let hi: [f64; 3] = std::array::from_fn(|a| origin[a] + (counts[a] as f64 - 0.5) * spacing[a]);
    Aabb::new(lo, hi).map_err(to_py)
}
