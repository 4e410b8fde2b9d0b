//! The native module `zeroset._zeroset` of the Python package `zeroset`.
//!
//! The package's public API is the pure-Python layer in `python/zeroset/__init__.py`: it
//! normalises arguments (dtypes, strides, `scipy.sparse` matrices, Python callables and
//! numpy grids as fields) and calls the functions here with C-contiguous `float64` arrays,
//! which are viewed without copying. Every computation here runs with the GIL released
//! (`Python::detach`); long ones report to a `progress(stage, done, total)` callback and
//! stop on Ctrl-C (the `progress` module). Errors become `ValueError`, or `OSError` and its
//! subclasses for I/O (the `errors` module).

use pyo3::prelude::*;

mod arrays;
mod errors;
mod field;
mod fit;
mod io;
mod linalg;
mod mesh;
mod normals;
mod progress;
mod restore;

#[pymodule]
fn _zeroset(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // NumPy's C API is loaded on the first array made, by running Python code; made at import,
    // not inside a long call, a pending Ctrl-C cannot strike there (rust-numpy turns the
    // failed load into a panic).
    numpy::PyArray1::<f64>::zeros(m.py(), [0], false);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<field::NativeField>()?;
    m.add_function(wrap_pyfunction!(field::load, m)?)?;
    m.add_function(wrap_pyfunction!(field::from_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(field::interpolate, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit_rbf, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit_neural, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit_mras_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_points, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_e57, m)?)?;
    m.add_function(wrap_pyfunction!(normals::estimate_normals, m)?)?;
    m.add_function(wrap_pyfunction!(normals::fill_missing_normals, m)?)?;
    m.add_function(wrap_pyfunction!(normals::orient_normals, m)?)?;
    m.add_function(wrap_pyfunction!(normals::thickness, m)?)?;
    m.add_function(wrap_pyfunction!(io::sample_xyzn, m)?)?;
    m.add_function(wrap_pyfunction!(linalg::lstsq_native, m)?)?;
    m.add_function(wrap_pyfunction!(linalg::cp_als, m)?)?;
    m.add_function(wrap_pyfunction!(linalg::svt, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::marching_cubes_volume, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::mesh_native, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::write_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::trim_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(restore::restore, m)?)?;
    Ok(())
}
