//! Normals for point clouds: estimated where a scan has none, completed where some are
//! missing (`0 0 0`), and signed consistently where they were written unoriented
//! (`zeroset_bases::normals`).

use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use zeroset_bases::noise::estimate_noise;
use zeroset_bases::normals::estimate_noise_unoriented;
use zeroset_bases::normals::{
    NormalOptions, default_neighbours, estimate_normals as estimate,
    estimate_normals_from_scanners, fill_missing_normals as fill, orient_normals as orient,
};
use zeroset_bases::thickness::{VOLUME_THICKNESS, measure_thickness};

use crate::arrays::{points as rows, rows_array};
use crate::errors::to_py;

/// `(smallest scale, largest scale, thinnest median, fills a volume, threshold)`: see
/// [`thickness`].
type ThicknessReading = (usize, usize, f64, bool, f64);

/// How thick `points`' neighbourhoods are (`zeroset_bases::thickness`): `(smallest scale,
/// largest scale, the thinnest scale's median thickness, whether they fill a volume, the
/// threshold)`, the scales in neighbours; `None` for fewer than 256 distinct positions or a
/// non-finite coordinate. Where they are thick at every scale, the noise check decides (with
/// `normals` where given).
#[pyfunction]
#[pyo3(signature = (points, normals=None))]
pub(crate) fn thickness<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    normals: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Option<ThicknessReading>> {
    let positions = rows(&points, "points", false)?;
    let normals = normals
        .as_ref()
        .map(|n| rows(n, "normals", false))
        .transpose()?;
    Ok(py.detach(|| {
        let t = measure_thickness(positions)?;
        let noise = if t.thick_everywhere() {
            match normals {
                Some(normals) => estimate_noise(positions, Some(normals)),
                None => estimate_noise_unoriented(positions),
            }
        } else {
            None
        };
        let scales = t.scales();
        Some((
            scales[0].neighbours,
            scales[scales.len() - 1].neighbours,
            t.thinnest().thickness,
            t.fills_volume(noise.as_ref()),
            VOLUME_THICKNESS,
        ))
    }))
}

/// Outward unit normals for `points` (see `zeroset.estimate_normals`); with `scanners`, each
/// point faces its own scanner.
#[pyfunction]
#[pyo3(signature = (points, neighbours, viewpoint=None, scanners=None))]
pub(crate) fn estimate_normals<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    neighbours: Option<usize>,
    viewpoint: Option<[f64; 3]>,
    scanners: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let positions = rows(&points, "points", true)?;
    let options = NormalOptions {
        neighbours: neighbours_or_default(py, positions, neighbours),
        viewpoint,
    };
    let estimated = match &scanners {
        None => py.detach(|| estimate(positions, &options)),
        Some(scanners) => {
            let scanners = rows(scanners, "scanners", true)?;
            py.detach(|| estimate_normals_from_scanners(positions, scanners, &options))
        }
    }
    .map_err(to_py)?;
    Ok(rows_array(py, estimated.normals))
}

/// `neighbours`, or the count `zeroset normals` chooses for `positions` (16, or 32 where they
/// measure noisy).
fn neighbours_or_default(
    py: Python<'_>,
    positions: &[[f64; 3]],
    neighbours: Option<usize>,
) -> usize {
    neighbours.unwrap_or_else(|| py.detach(|| default_neighbours(positions).0))
}

/// `normals` with each zero one (`0 0 0`) estimated from its `neighbours` nearest points'
/// plane and signed as the normals around it (see `zeroset.fill_missing_normals`), and the
/// indices of those completed. The arrays given are not modified.
#[pyfunction]
pub(crate) fn fill_missing_normals<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    normals: PyReadonlyArray2<'py, f64>,
    neighbours: usize,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Vec<usize>)> {
    let positions = rows(&points, "points", false)?;
    // Non-finite values are the library's to name (position or normal, and which).
    let mut completed = rows(&normals, "normals", false)?.to_vec();
    let filled = py
        .detach(|| fill(positions, &mut completed, neighbours))
        .map_err(to_py)?;
    Ok((rows_array(py, completed), filled))
}

/// `normals` signed consistently over the scan (see `zeroset.orient_normals`) and what the
/// orientation found: `inconsistent`, `turned`, `facing_in` (with `rays_cast`, `rays_inward`)
/// and `unoriented`.
#[pyfunction]
#[pyo3(signature = (points, normals, neighbours, viewpoint=None))]
pub(crate) fn orient_normals<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    normals: PyReadonlyArray2<'py, f64>,
    neighbours: Option<usize>,
    viewpoint: Option<[f64; 3]>,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyDict>)> {
    let positions = rows(&points, "points", true)?;
    let lines = rows(&normals, "normals", true)?;
    let options = NormalOptions {
        neighbours: neighbours_or_default(py, positions, neighbours),
        viewpoint,
    };
    let orientation = py
        .detach(|| orient(positions, lines, &options))
        .map_err(to_py)?;
    let report = PyDict::new(py);
    report.set_item("points", positions.len())?;
    report.set_item("neighbours", options.neighbours)?;
    report.set_item("inconsistent", orientation.inconsistent)?;
    report.set_item("turned", orientation.turned)?;
    report.set_item("facing_in", orientation.facing_in())?;
    report.set_item("rays_cast", orientation.rays.cast)?;
    report.set_item("rays_inward", orientation.rays.inward)?;
    report.set_item("rays_outward", orientation.rays.outward)?;
    report.set_item("consistent_rays_cast", orientation.rays_consistent.cast)?;
    report.set_item("consistent_rays_inward", orientation.rays_consistent.inward)?;
    report.set_item("unoriented", orientation.unoriented())?;
    Ok((rows_array(py, orientation.estimated.normals), report))
}
