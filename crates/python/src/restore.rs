//! Restoration (Ren–Fujita–Nakata 2022): a protrusion removed or noise smoothed inside a box
//! mask, by least squares on the field's samples; the result is a quadratic B-spline field.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use zeroset_bases::field_file::AnyField;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::mask::{BoxMask, Face};
use zeroset_restore::denoise::{Denoise, Resampling};
use zeroset_restore::protrusion::{Convention, Protrusion};
use zeroset_restore::sampling_grid;

use crate::arrays::corners;
use crate::errors::{to_py, value_error};
use crate::field::NativeField;
use crate::fit::{ReportValue, report_dict};

/// Restores `field` inside the mask `lo .. hi` (see `zeroset.restore`).
#[pyfunction]
#[pyo3(signature = (field, lo, hi, mode, face, alpha, coarse, grid, positive_inside, point_resampling))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn restore<'py>(
    py: Python<'py>,
    field: &NativeField,
    lo: [f64; 3],
    hi: [f64; 3],
    mode: &str,
    face: Option<&str>,
    alpha: Option<f64>,
    coarse: Option<[usize; 3]>,
    grid: Option<[usize; 3]>,
    positive_inside: bool,
    point_resampling: bool,
) -> PyResult<(NativeField, Bound<'py, PyDict>)> {
    let [a, b] = corners(lo, hi, "mask")?;
    let face: Option<Face> = face.map(str::parse).transpose().map_err(value_error)?;
    let source = &field.inner;
    let result = py.detach(|| -> PyResult<_> {
        // A B-spline is restored on its own grid; other fields are sampled on the default
        // grid over their box, or on `grid` cells over it.
        let default = match source.as_ref() {
            AnyField::BSpline(s) if grid.is_none() => *s.grid(),
            other => {
                let bounds = other
                    .bounds()
                    .ok_or_else(|| value_error("the field has no bounds to restore in"))?;
                sampling_grid(bounds).map_err(to_py)?
            }
        };
        let grid = match grid {
            Some(counts) if counts.iter().any(|&c| c < 3) => {
                return Err(value_error(format!(
                    "grid= needs at least 3 cells per axis (a restoration keeps a layer on each \
                     side of its unknowns), got {counts:?}"
                )));
            }
            Some(counts) => Grid::cell_centered(default.bounds(), counts).map_err(to_py)?,
            None => default,
        };
        // A mask reaching beyond the grid's box but overlapping it is cut to it (said in the
        // report, and warned of), as `zeroset restore` does.
        let ([a, b], cut) = zeroset_restore::clamp_mask_corners(&grid, a, b);
        let mask = BoxMask::from_corners(&grid, a, b).map_err(|e| {
            let bb = grid.bounds();
            value_error(format!(
                "{e}: the mask must lie in the field's box {:?} .. {:?}",
                bb.min(),
                bb.max()
            ))
        })?;
        let mut report = vec![
            ("mode", ReportValue::Str(mode.to_owned())),
            ("grid", ReportValue::Ints(grid.counts().to_vec())),
            ("mask_cells", ReportValue::Int(mask.len())),
            ("mask_cut_axes", ReportValue::Ints(cut)),
        ];
        let restored = match mode {
            "protrusion" => {
                if coarse.is_some() || point_resampling {
                    return Err(value_error(
                        "coarse= and point_resampling= apply to mode='denoise'",
                    ));
                }
                let params = Protrusion {
                    face,
                    alpha,
                    convention: if positive_inside {
                        Convention::PositiveInside
                    } else {
                        Convention::NegativeInside
                    },
                    ..Protrusion::default()
                };
                let out = params.apply(source.as_ref(), &grid, &mask).map_err(to_py)?;
                let r = &out.report;
                if let Some(alpha) = r.alpha {
                    report.push(("alpha", ReportValue::Float(alpha)));
                }
                report.extend([
                    ("unknowns", ReportValue::Int(r.unknowns)),
                    ("solver", ReportValue::Str(r.solve.solver.to_owned())),
                    ("rel_residual", ReportValue::Float(r.solve.rel_residual)),
                    ("seconds", ReportValue::Float(r.solve.elapsed.as_secs_f64())),
                ]);
                out.field
            }
            "denoise" => {
                if face.is_some() || alpha.is_some() {
                    return Err(value_error("face= and alpha= apply to mode='protrusion'"));
                }
                let coarse = coarse.ok_or_else(|| {
                    value_error(
                        "mode='denoise' needs coarse=(m, n, l), coarse cells per axis in the mask",
                    )
                })?;
                let resampling = if point_resampling {
                    Resampling::Point
                } else {
                    Resampling::Area
                };
                let out = Denoise::new(coarse)
                    .with_resampling(resampling)
                    .apply(source.as_ref(), &grid, &mask)
                    .map_err(to_py)?;
                report.push((
                    "seconds",
                    ReportValue::Float(out.report.coarse_fit.as_secs_f64()),
                ));
                out.field
            }
            other => {
                return Err(value_error(format!(
                    "mode must be 'protrusion' or 'denoise', got {other:?}"
                )));
            }
        };
        Ok((AnyField::BSpline(restored), report))
    });
    let (field, report) = result?;
    Ok((NativeField::new(field), report_dict(py, report)?))
}
