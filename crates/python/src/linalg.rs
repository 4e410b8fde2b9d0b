//! Least squares with any of zeroset's solvers on a dense or CSR matrix; CP-ALS of a 3-way
//! tensor; singular-value thresholding.

use std::ops::ControlFlow;
use std::sync::Arc;

use faer::MatRef;
use faer::sparse::{SparseRowMatRef, SymbolicSparseRowMatRef};
use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use zeroset_field_core::lsq::{LeastSquaresSolver, LsqMatrix, Monitor};
use zeroset_solvers::{
    Cgls, DenseQr, IterativeParams, Lsqr, NormalLu, Pcg, PcgParams, SparseCholesky, SparseQr,
};
use zeroset_tensor::{CpInit, CpOptions, Tensor3, cp_als as cp_als_rust, svt as svt_rust};

use crate::arrays::vector;
use crate::errors::{to_py, value_error};
use crate::fit::{ReportValue, report_dict};
use crate::progress::Hook;

/// The solver `name` with tolerance `tol` and iteration limit `max_iter` (iterative ones)
/// reporting to `hook`.
fn solver(
    name: &str,
    tol: Option<f64>,
    max_iter: Option<usize>,
    hook: &Arc<Hook>,
) -> PyResult<Box<dyn LeastSquaresSolver>> {
    let hook = Arc::clone(hook);
    let monitor = Monitor::new(move |p| {
        if hook.report(p.solver, p.iteration, p.max_iterations) {
            ControlFlow::Continue(())
        } else {
            ControlFlow::Break(())
        }
    });
    let mut iterative = IterativeParams {
        max_iterations: max_iter,
        monitor: Some(monitor),
        ..IterativeParams::default()
    };
    if let Some(t) = tol {
        if !(t.is_finite() && t >= 0.0) {
            return Err(value_error(format!("tol must be finite and ≥ 0, got {t}")));
        }
        iterative.atol = t;
        iterative.btol = t;
    }
    Ok(match name {
        "lsqr" => Box::new(Lsqr::new(iterative)),
        "cgls" => Box::new(Cgls::new(iterative)),
        "pcg" => Box::new(Pcg::new(PcgParams {
            tol: tol.unwrap_or(PcgParams::default().tol),
            max_iterations: max_iter,
            monitor: iterative.monitor.clone(),
            ..PcgParams::default()
        })),
        "qr" => Box::new(DenseQr::default()),
        "lu" => Box::new(NormalLu::default()),
        "sparse_qr" => Box::new(SparseQr::default()),
        "cholesky" => Box::new(SparseCholesky::default()),
        other => {
            return Err(value_error(format!(
                "solver must be 'lsqr', 'cgls', 'pcg', 'qr', 'lu', 'sparse_qr' or 'cholesky', \
                 got {other:?}"
            )));
        }
    })
}

/// Solves `min ‖A x − b‖` for a dense C-contiguous `A` or a CSR matrix given by its arrays;
/// returns `x` and the solver's report.
#[pyfunction]
#[pyo3(signature = (b, solver_name, tol, max_iter, dense=None, csr=None, progress=None))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn lstsq_native<'py>(
    py: Python<'py>,
    b: PyReadonlyArray1<'py, f64>,
    solver_name: &str,
    tol: Option<f64>,
    max_iter: Option<usize>,
    dense: Option<PyReadonlyArray2<'py, f64>>,
    csr: Option<(
        (usize, usize),
        PyReadonlyArray1<'py, i64>,
        PyReadonlyArray1<'py, i64>,
        PyReadonlyArray1<'py, f64>,
    )>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyDict>)> {
    let b = b
        .as_slice()
        .map_err(|_| value_error("b must be C-contiguous"))?;
    let hook = Arc::new(Hook::new(progress));
    let s = solver(solver_name, tol, max_iter, &hook)?;
    let solution = match (dense, csr) {
        (Some(a), None) => {
            let shape = a.shape();
            let (m, n) = (shape[0], shape[1]);
            let data = a
                .as_slice()
                .map_err(|_| value_error("A must be C-contiguous"))?;
            let a = MatRef::from_row_major_slice(data, m, n);
            hook.run(py, || s.solve(LsqMatrix::Dense(a), b))
        }
        (None, Some(((m, n), indptr, indices, data))) => {
            let to_usize = |a: &[i64], what: &str| -> PyResult<Vec<usize>> {
                a.iter()
                    .map(|&x| usize::try_from(x))
                    .collect::<Result<_, _>>()
                    .map_err(|_| value_error(format!("negative entry in the CSR {what}")))
            };
            let row_ptr = to_usize(indptr.as_slice()?, "indptr")?;
            let col_idx = to_usize(indices.as_slice()?, "indices")?;
            let values = data.as_slice()?;
            let symbolic = SymbolicSparseRowMatRef::new_checked(m, n, &row_ptr, None, &col_idx);
            let a = SparseRowMatRef::new(symbolic, values);
            hook.run(py, || s.solve(LsqMatrix::SparseRow(a), b))
        }
        _ => return Err(value_error("give A as a dense array or a CSR matrix")),
    };
    let solution = hook.finish(solution.map_err(to_py))?;
    let info = &solution.info;
    let mut report = vec![
        ("solver", ReportValue::Str(info.solver.to_owned())),
        ("iterations", ReportValue::Int(info.iterations)),
        ("rel_residual", ReportValue::Float(info.rel_residual)),
        (
            "rel_normal_residual",
            ReportValue::Float(info.rel_normal_residual),
        ),
        ("seconds", ReportValue::Float(info.elapsed.as_secs_f64())),
    ];
    report.extend(
        info.details
            .iter()
            .map(|&(k, v)| (k, ReportValue::Float(v))),
    );
    Ok((vector(py, solution.x), report_dict(py, report)?))
}

/// CP-ALS of a 3-way tensor: `(weights, [A, B, C], report)`.
#[pyfunction]
#[pyo3(signature = (tensor, rank, max_iter, tol, init, seed, line_search, progress))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn cp_als<'py>(
    py: Python<'py>,
    tensor: PyReadonlyArray3<'py, f64>,
    rank: usize,
    max_iter: usize,
    tol: f64,
    init: &str,
    seed: u64,
    line_search: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Vec<Bound<'py, PyArray2<f64>>>,
    Bound<'py, PyDict>,
)> {
    let shape = tensor.shape();
    let shape = [shape[0], shape[1], shape[2]];
    let data = tensor
        .as_slice()
        .map_err(|_| value_error("the tensor must be C-contiguous"))?
        .to_vec();
    let x = Tensor3::new(shape, data).map_err(to_py)?;
    let init = match init {
        "svd" => CpInit::Svd,
        "random" => CpInit::Random(seed),
        other => {
            return Err(value_error(format!(
                "init must be 'svd' or 'random', got {other:?}"
            )));
        }
    };
    let options = CpOptions::new(rank)
        .with_max_iter(max_iter)
        .with_tol(tol)
        .with_init(init)
        .with_line_search(line_search);
    let hook = Hook::new(progress);
    let result = hook.run(py, || {
        cp_als_rust(&x, &options, |p| {
            hook.report("cp_als", p.iteration, max_iter)
        })
        .map_err(to_py)
    });
    let fit = hook.finish(result)?;
    let k = &fit.kruskal;
    let factors = k
        .factors()
        .iter()
        .map(|f| {
            let (r, c) = (f.nrows(), f.ncols());
            Array2::from_shape_fn((r, c), |(i, j)| f[(i, j)]).into_pyarray(py)
        })
        .collect();
    let report = vec![
        ("iterations", ReportValue::Int(fit.iterations)),
        ("rel_error", ReportValue::Float(fit.rel_error)),
        ("errors", ReportValue::Floats(fit.errors.clone())),
        (
            "converged",
            ReportValue::Bool(matches!(fit.stop, zeroset_tensor::CpStop::Converged)),
        ),
    ];
    Ok((
        vector(py, k.weights().to_vec()),
        factors,
        report_dict(py, report)?,
    ))
}

/// Singular-value thresholding `U max(Σ − τ, 0) Vᵀ` of a matrix, and the rank kept.
#[pyfunction]
pub(crate) fn svt<'py>(
    py: Python<'py>,
    matrix: PyReadonlyArray2<'py, f64>,
    tau: f64,
) -> PyResult<(Bound<'py, PyArray2<f64>>, usize)> {
    let shape = matrix.shape();
    let (m, n) = (shape[0], shape[1]);
    let data = matrix
        .as_slice()
        .map_err(|_| value_error("the matrix must be C-contiguous"))?;
    let (out, rank) = py
        .detach(|| svt_rust(MatRef::from_row_major_slice(data, m, n), tau))
        .map_err(to_py)?;
    let out = Array2::from_shape_fn((m, n), |(i, j)| out[(i, j)]).into_pyarray(py);
    Ok((out, rank))
}
