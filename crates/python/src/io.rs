//! Point clouds in: every format `zeroset` reads (PLY, PCD, LAS/LAZ, E57, xyz / xyzn / pts
//! text, CSV, GemPy tables, and meshes' vertices).

use std::path::PathBuf;

use numpy::PyArray2;
use pyo3::prelude::*;
use zeroset_field_core::io::{ReadOptions, read_point_cloud, read_point_cloud_with};

use crate::arrays::rows_array;
use crate::errors::to_py;

/// Reads a point cloud: `(points, normals)`, normals `None` when the file has none. A mesh
/// file (OBJ, STL, PLY with faces) gives its vertices, normals from the file or the
/// triangles' winding (`zeroset_mesh::points`). `formation`: one formation of a GemPy table.
#[pyfunction]
#[pyo3(signature = (path, formation=None))]
#[allow(clippy::type_complexity)]
pub(crate) fn read_points(
    py: Python<'_>,
    path: PathBuf,
    formation: Option<String>,
) -> PyResult<(Bound<'_, PyArray2<f64>>, Option<Bound<'_, PyArray2<f64>>>)> {
    if let Some(name) = formation {
        let options = ReadOptions::default().with_formation(name);
        let cloud = py
            .detach(|| read_point_cloud_with(&path, &options))
            .map_err(to_py)?;
        let normals = cloud.normals().map(|n| rows_array(py, n.to_vec()));
        return Ok((rows_array(py, cloud.positions().to_vec()), normals));
    }
    if zeroset_mesh::is_mesh_file(&path) {
        let mesh = py
            .detach(|| zeroset_mesh::read_mesh(&path))
            .map_err(to_py)?;
        let is_ply =
            zeroset_mesh::MeshFormat::from_path(&path) == Some(zeroset_mesh::MeshFormat::Ply);
        // A PLY whose few faces use under half its vertices is a point cloud (as the CLI reads it).
        if !(is_ply && zeroset_mesh::points::is_mostly_unused(&mesh)) {
            let points = zeroset_mesh::points::mesh_points(mesh);
            let normals = points.normals.map(|n| rows_array(py, n));
            return Ok((rows_array(py, points.positions), normals));
        }
    }
    let cloud = py.detach(|| read_point_cloud(&path)).map_err(to_py)?;
    let normals = cloud.normals().map(|n| rows_array(py, n.to_vec()));
    Ok((rows_array(py, cloud.positions().to_vec()), normals))
}

/// The bundled sample (`samples/bunny_2k.xyzn`: 2,000 points of the Stanford bunny with
/// normals), as the text of its file.
#[pyfunction]
pub(crate) fn sample_xyzn() -> &'static str {
    include_str!("../samples/bunny_2k.xyzn")
}

/// One E57 scan's summary: name, records, points kept, coordinates (`"cartesian"` or
/// `"spherical"`), normals, posed, origin.
type ScanRow = (
    Option<String>,
    u64,
    usize,
    &'static str,
    bool,
    bool,
    [f64; 3],
);

/// Reads an E57 file: `(points, normals or None, origins, scans)`, `origins[i]` the origin of
/// point `i`'s scan (see `zeroset.read_e57`).
#[pyfunction]
#[allow(clippy::type_complexity)]
pub(crate) fn read_e57(
    py: Python<'_>,
    path: PathBuf,
) -> PyResult<(
    Bound<'_, PyArray2<f64>>,
    Option<Bound<'_, PyArray2<f64>>>,
    Bound<'_, PyArray2<f64>>,
    Vec<ScanRow>,
)> {
    use zeroset_field_core::io::e57::Coordinates;
    // Normals where every scan has them; where only some do, the positions (for
    // `estimate_normals(…, scanners=origins)`).
    let read = py
        .detach(|| {
            use zeroset_field_core::io::{ReadOptions, e57::read_e57};
            match read_e57(&path, &ReadOptions::default()) {
                Err(zeroset_field_core::Error::PartialNormals { .. }) => {
                    read_e57(&path, &ReadOptions::default().with_positions_only(true))
                }
                read => read,
            }
        })
        .map_err(to_py)?;
    let origins = rows_array(py, read.origins());
    let scans = read
        .scans
        .iter()
        .map(|s| {
            let coordinates = match s.coordinates {
                Coordinates::Cartesian => "cartesian",
                Coordinates::Spherical => "spherical",
            };
            let name = s.name.clone();
            (
                name,
                s.records,
                s.points,
                coordinates,
                s.normals,
                s.posed,
                s.origin,
            )
        })
        .collect();
    let normals = read.cloud.normals().map(|n| rows_array(py, n.to_vec()));
    let points = rows_array(py, read.cloud.positions().to_vec());
    Ok((points, normals, origins, scans))
}
