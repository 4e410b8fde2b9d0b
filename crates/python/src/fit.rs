//! Fitting a field to an oriented point cloud: RBF (Carr et al.'s off-surface or Hermite
//! constraints, any kernel, optional greedy centre reduction), neural (the MLP of Jiang–Turk
//! §3 through off-surface points) and MRAS (paper 004). Each returns the field and its report
//! as a dict (wrapped by `zeroset.Report`).

use std::ops::ControlFlow;
use std::sync::Arc;

use numpy::PyReadonlyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use zeroset_bases::field_file::{AnyField, StoredKernel};
use zeroset_bases::mras::{MrasOptions, MrasProgress, fit_mras};
use zeroset_bases::neural::{Activation, Architecture, NeuralFit, NeuralParams};
use zeroset_bases::noise::{estimate_noise, object_size};
use zeroset_bases::outliers::{DEFAULT_OUTLIER_RATIO, remove_outliers, valid_ratio};
use zeroset_bases::rbf::{
    Biharmonic, Constraints, GreedyOptions, IterativeParams, Offset, RbfFit, Solver, ThinPlate,
    Triharmonic, Wendland,
};
use zeroset_field_core::PointCloud3;
use zeroset_field_core::lsq::Monitor;

use crate::arrays::points;
use crate::errors::{to_py, value_error};
use crate::field::NativeField;
use crate::progress::Hook;

/// The cloud of `points` and `normals` (checked: shapes, finite values, equal lengths).
fn cloud(
    points_: &PyReadonlyArray2<'_, f64>,
    normals: &PyReadonlyArray2<'_, f64>,
) -> PyResult<PointCloud3> {
    let p = points(points_, "points", true)?;
    let n = points(normals, "normals", true)?;
    if p.len() != n.len() {
        return Err(value_error(format!(
            "points and normals must have the same length, got {} and {}",
            p.len(),
            n.len()
        )));
    }
    PointCloud3::from_raw(p.to_vec(), Some(n.to_vec())).map_err(to_py)
}

/// The diagonal of the cloud's box (0 for an empty cloud).
fn diagonal(cloud: &PointCloud3) -> f64 {
    cloud.bounds().map_or(0.0, |b| b.diagonal())
}

/// What an RBF fit is asked to do, besides its kernel.
struct RbfRequest {
    solver: Solver,
    tolerance: Option<f64>,
    /// The smoothing `μ` (0: interpolation).
    smoothing: f64,
    hook: Arc<Hook>,
}

/// Fits `constraints` with `kernel` (greedily to `tolerance` of the diagonal if given) and
/// fills `report`.
fn fit_kernel<K: StoredKernel>(
    kernel: K,
    constraints: &Constraints<3>,
    request: RbfRequest,
    diagonal: f64,
    report: &mut Vec<(&'static str, ReportValue)>,
) -> PyResult<AnyField<3>> {
    let hook = Arc::clone(&request.hook);
    let monitor = Monitor::new(move |p| {
        if hook.report("rbf", p.iteration, p.max_iterations) {
            ControlFlow::Continue(())
        } else {
            ControlFlow::Break(())
        }
    });
    let fit = RbfFit::new(kernel)
        .with_solver(request.solver)
        .with_monitor(monitor)
        .with_smoothing(request.smoothing);
    let fitted = match request.tolerance {
        None => fit.fit(constraints).map_err(to_py)?,
        Some(t) => {
            if !(t.is_finite() && t > 0.0 && t < 1.0) {
                return Err(value_error(format!(
                    "tolerance {t}: give a fraction of the diagonal, between 0 and 1"
                )));
            }
            let (fitted, greedy) = fit
                .fit_greedy(constraints, &GreedyOptions::new(t * diagonal))
                .map_err(to_py)?;
            report.push(("greedy_rounds", ReportValue::Int(greedy.rounds.len())));
            report.push((
                "greedy_max_residual",
                ReportValue::Float(greedy.max_residual),
            ));
            report.push(("greedy_converged", ReportValue::Bool(greedy.converged)));
            fitted
        }
    };
    let r = &fitted.report;
    report.extend([
        ("solver", ReportValue::Str(r.solver.to_owned())),
        ("iterations", ReportValue::Int(r.iterations)),
        ("constraints", ReportValue::Int(constraints.len())),
        ("centres", ReportValue::Int(fitted.field.num_centres())),
        ("max_residual", ReportValue::Float(r.max_residual)),
        ("residual_exact", ReportValue::Bool(r.residual_exact)),
        // None where GMRES reached its 1e-12 target (or the solve was direct).
        ("gmres_stalled_at", ReportValue::MaybeFloat(r.stalled_at)),
        ("smoothing", ReportValue::Float(request.smoothing)),
        ("misfit_rms", ReportValue::Float(r.misfit_rms)),
        ("misfit_max", ReportValue::Float(r.misfit_max)),
        ("seconds", ReportValue::Float(r.elapsed.as_secs_f64())),
        ("warnings", ReportValue::Strs(r.warnings.clone())),
    ]);
    Ok(AnyField::Rbf(K::into_any(fitted.field)))
}

/// A report entry, built without the GIL and turned into Python objects after.
pub(crate) enum ReportValue {
    Int(usize),
    Ints(Vec<usize>),
    Float(f64),
    /// A float or `None`.
    MaybeFloat(Option<f64>),
    Bool(bool),
    Str(String),
    Strs(Vec<String>),
    Floats(Vec<f64>),
}

/// `entries` as a dict.
pub(crate) fn report_dict<'py>(
    py: Python<'py>,
    entries: Vec<(&'static str, ReportValue)>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in entries {
        match v {
            ReportValue::Int(x) => d.set_item(k, x)?,
            ReportValue::Float(x) => d.set_item(k, x)?,
            ReportValue::MaybeFloat(x) => d.set_item(k, x)?,
            ReportValue::Bool(x) => d.set_item(k, x)?,
            ReportValue::Str(x) => d.set_item(k, x)?,
            ReportValue::Strs(x) => d.set_item(k, x)?,
            ReportValue::Floats(x) => d.set_item(k, x)?,
            ReportValue::Ints(x) => d.set_item(k, x)?,
        }
    }
    Ok(d)
}

/// Fits an RBF field (see `zeroset.fit`).
#[pyfunction]
#[pyo3(signature = (
    points, normals, kernel, offset, hermite, solver, tolerance, radius, outlier_ratio, smoothing,
    smoothing_auto, progress
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_rbf<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    normals: PyReadonlyArray2<'py, f64>,
    kernel: &str,
    offset: Option<f64>,
    hermite: bool,
    solver: &str,
    tolerance: Option<f64>,
    radius: Option<f64>,
    outlier_ratio: Option<f64>,
    smoothing: Option<f64>,
    smoothing_auto: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(NativeField, Bound<'py, PyDict>)> {
    if let Some(mu) = smoothing
        && !(mu.is_finite() && mu >= 0.0)
    {
        return Err(value_error(format!(
            "smoothing must be 'auto' or a finite number >= 0 (added to the kernel matrix's \
             diagonal; 0 interpolates), got {mu}"
        )));
    }
    if (smoothing.is_some() || smoothing_auto) && hermite {
        return Err(value_error(
            "smoothing= approximates value constraints; hermite=True fits the gradients exactly \
             too: drop hermite= for a noisy scan",
        ));
    }
    if (smoothing.is_some() || smoothing_auto) && tolerance.is_some() {
        return Err(value_error(
            "tolerance= keeps the centres whose constraints the field misses by more than it, \
             and a smoothed field misses them on purpose: give one or the other",
        ));
    }
    if smoothing_auto && kernel != "r" {
        return Err(value_error(format!(
            "smoothing='auto' is calibrated for kernel='r' (its μ is a length); with kernel=\
             {kernel:?} give smoothing as a number in that kernel's units"
        )));
    }
    let ratio = outlier_ratio.unwrap_or(DEFAULT_OUTLIER_RATIO);
    if !valid_ratio(ratio) {
        return Err(value_error(format!(
            "outlier_ratio must be 0 (off) or at least 1.5, got {ratio}"
        )));
    }
    let (cloud, outliers) = remove_outliers(&cloud(&points, &normals)?, ratio).map_err(to_py)?;
    let solver = match solver {
        "auto" => Solver::Auto,
        "dense" => Solver::Dense,
        "mixed" => Solver::MixedPrecision,
        "iterative" => Solver::Iterative(IterativeParams::default()),
        other => {
            return Err(value_error(format!(
                "solver must be 'auto', 'dense', 'mixed' or 'iterative', got {other:?}"
            )));
        }
    };
    if radius.is_some() && kernel != "wendland" {
        return Err(value_error("radius applies to kernel='wendland'"));
    }
    let hook = Arc::new(Hook::new(progress));
    let mut request = RbfRequest {
        solver,
        tolerance,
        smoothing: smoothing.unwrap_or(0.0),
        hook: Arc::clone(&hook),
    };
    let kernel = kernel.to_owned();
    let result = hook.run(py, || -> PyResult<_> {
        let mut report = vec![
            ("method", ReportValue::Str("rbf".into())),
            ("outliers", ReportValue::Ints(outliers.indices)),
            ("kept_sparse", ReportValue::Int(outliers.kept_sparse)),
        ];
        if let Some(noise) = estimate_noise(cloud.positions(), cloud.normals()) {
            report.extend([
                ("scatter", ReportValue::Float(noise.relative())),
                ("noisy", ReportValue::Bool(noise.is_noisy())),
            ]);
            if smoothing_auto {
                let size = object_size(cloud.positions(), noise.spacing)
                    .unwrap_or_else(|| diagonal(&cloud));
                request.smoothing = noise.rbf_smoothing(size);
                if !request.smoothing.is_finite() {
                    return Err(value_error(
                        "smoothing='auto': the smoothing from the noise is not finite (the \
                         object size overflows): give smoothing as a number",
                    ));
                }
            }
        }
        let constraints = if hermite {
            let c = Constraints::hermite(&cloud).map_err(to_py)?;
            report.push(("merged", ReportValue::Int(cloud.len() - c.len() / 2)));
            c
        } else {
            let offset = offset.map_or(Offset::default(), Offset::Fixed);
            let (c, o) = Constraints::off_surface(&cloud, offset).map_err(to_py)?;
            report.extend([
                ("offset", ReportValue::Float(o.initial)),
                ("smallest_offset", ReportValue::Float(o.smallest)),
                ("offsets_shrunk", ReportValue::Int(o.shrunk)),
                ("offsets_dropped", ReportValue::Int(o.dropped)),
                ("merged", ReportValue::Int(o.merged)),
                ("touching", ReportValue::Int(o.touching)),
            ]);
            c
        };
        let d = diagonal(&cloud);
        let field = match kernel.as_str() {
            "r" => fit_kernel(Biharmonic, &constraints, request, d, &mut report),
            "r3" => fit_kernel(Triharmonic, &constraints, request, d, &mut report),
            "tps" => fit_kernel(ThinPlate, &constraints, request, d, &mut report),
            "wendland" => {
                let w = match radius {
                    Some(rho) => Wendland::new(rho),
                    None => Wendland::for_diagonal(d),
                }
                .ok_or_else(|| {
                    value_error(
                        "kernel='wendland' needs a finite positive radius (the cloud's box is a \
                         point: give radius=)",
                    )
                })?;
                report.push(("radius", ReportValue::Float(w.radius())));
                fit_kernel(w, &constraints, request, d, &mut report)
            }
            other => Err(value_error(format!(
                "kernel must be 'r', 'r3', 'tps' or 'wendland', got {other:?}"
            ))),
        }?;
        Ok((field, report))
    });
    let (field, report) = hook.finish(result)?;
    Ok((NativeField::new(field), report_dict(py, report)?))
}

/// Fits a neural field through the cloud's off-surface points (see `zeroset.fit`).
#[pyfunction]
#[pyo3(signature = (points, normals, steps, lam, widths, activation, seed, offset, progress))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_neural<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    normals: PyReadonlyArray2<'py, f64>,
    steps: usize,
    lam: f64,
    widths: Vec<usize>,
    activation: &str,
    seed: u64,
    offset: Option<f64>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(NativeField, Bound<'py, PyDict>)> {
    let cloud = cloud(&points, &normals)?;
    let activation = Activation::from_name(activation).ok_or_else(|| {
        value_error(format!(
            "activation must be 'tanh' or 'softplus', got {activation:?}"
        ))
    })?;
    let architecture = Architecture::new(widths, activation).map_err(to_py)?;
    let params = NeuralParams::default()
        .with_steps(steps)
        .with_lambda(lam)
        .with_seed(seed)
        .with_architecture(architecture);
    let hook = Hook::new(progress);
    let result = hook.run(py, || -> PyResult<_> {
        let offset = offset.map_or(Offset::default(), Offset::Fixed);
        let (constraints, o) = Constraints::off_surface(&cloud, offset).map_err(to_py)?;
        let (at, targets) = constraints.values();
        let fit = NeuralFit::new(params);
        // Every step reports (the hook passes one every 20 ms on to Python): a Ctrl-C stops
        // the training at the next step.
        let trained = fit
            .fit_scaled(&at, &targets, o.initial, &mut |p| {
                if hook.report("neural", p.step, p.steps) {
                    ControlFlow::Continue(())
                } else {
                    ControlFlow::Break(())
                }
            })
            .map_err(to_py)?;
        let r = &trained.report;
        let report = vec![
            ("method", ReportValue::Str("neural".into())),
            ("network", ReportValue::Str(trained.field.network())),
            ("steps", ReportValue::Int(r.steps)),
            ("constraints", ReportValue::Int(at.len())),
            ("offset", ReportValue::Float(o.initial)),
            ("loss", ReportValue::Float(r.loss)),
            ("data_term", ReportValue::Float(r.data_term)),
            ("curvature_term", ReportValue::Float(r.curvature_term)),
            (
                "max_residual",
                ReportValue::Float(r.max_residual * o.initial),
            ),
            ("loss_history", ReportValue::Floats(r.history.clone())),
            ("seconds", ReportValue::Float(r.elapsed.as_secs_f64())),
        ];
        Ok((AnyField::Neural(trained.field), report))
    });
    let (field, report) = hook.finish(result)?;
    Ok((NativeField::new(field), report_dict(py, report)?))
}

/// Fits an MRAS field (see `zeroset.fit`).
#[pyfunction]
#[pyo3(signature = (points, normals, tolerance, lam, max_level, compress, outlier_ratio, progress))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_mras_cloud<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    normals: PyReadonlyArray2<'py, f64>,
    tolerance: Option<f64>,
    lam: Option<f64>,
    max_level: Option<u32>,
    compress: bool,
    outlier_ratio: Option<f64>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(NativeField, Bound<'py, PyDict>)> {
    let cloud = cloud(&points, &normals)?;
    let mut options = MrasOptions {
        compress,
        ..MrasOptions::default()
    };
    if let Some(t) = tolerance {
        options.tolerance = t;
    }
    if let Some(l) = lam {
        options.lambda = l;
    }
    if let Some(l) = max_level {
        options.max_level = l;
    }
    if let Some(r) = outlier_ratio {
        options.outlier_ratio = r;
    }
    let hook = Hook::new(progress);
    let result = hook.run(py, || -> PyResult<_> {
        let report_cell = |p: &MrasProgress| {
            let stage = if p.compressing {
                "compressing"
            } else {
                "fitting"
            };
            hook.report(
                &format!("mras level {} {stage}", p.level),
                p.cells_done,
                p.cells_total,
            )
        };
        let normals = cloud.normals().unwrap_or_default();
        let fit = fit_mras(cloud.positions(), normals, &options, &report_cell).map_err(to_py)?;
        let max_error = fit.levels.last().map_or(f64::NAN, |l| l.max_error);
        let (met, over, capped, flat) = (
            fit.tolerance_met(),
            fit.points_over_tolerance,
            fit.capped_cells,
            fit.flat_points,
        );
        let fitted = fit.fitted_points;
        let report = vec![
            ("method", ReportValue::Str("mras".into())),
            ("levels", ReportValue::Int(fit.levels.len())),
            (
                "cells",
                ReportValue::Int(fit.levels.iter().map(|l| l.cells).sum()),
            ),
            ("storage", ReportValue::Int(fit.field.storage())),
            (
                "uncompressed_storage",
                ReportValue::Int(fit.field.uncompressed_storage()),
            ),
            ("max_error", ReportValue::Float(max_error)),
            ("duplicates", ReportValue::Int(fit.duplicates)),
            ("touching", ReportValue::Int(fit.touching)),
            ("outliers", ReportValue::Ints(fit.outliers.clone())),
            ("kept_sparse", ReportValue::Int(fit.kept_sparse)),
            ("tolerance", ReportValue::Float(options.tolerance)),
            ("tolerance_met", ReportValue::Bool(met)),
            ("points_over_tolerance", ReportValue::Int(over)),
            ("capped_cells", ReportValue::Int(capped)),
            ("flat_points", ReportValue::Int(flat)),
            ("fitted_points", ReportValue::Int(fitted)),
            ("lam", ReportValue::Float(options.lambda)),
            ("seconds", ReportValue::Float(fit.seconds)),
        ];
        Ok((AnyField::Mras(fit.field), report))
    });
    let (field, report) = hook.finish(result)?;
    Ok((NativeField::new(field), report_dict(py, report)?))
}
