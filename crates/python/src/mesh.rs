//! Meshes: marching cubes on a numpy volume (scikit-image's layout), the zero set of a field
//! (marching cubes, or the two-step signed marching cubes of an RBF field by the FMM), and
//! triangle meshes read, written and trimmed to a scan.

use std::path::PathBuf;

use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rayon::prelude::*;
use zeroset_bases::field_file::{AnyField, RbfAny};
use zeroset_bases::rbf::fmm::{DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY, FmmOptions, OrderPair};
use zeroset_bases::rbf::{Kernel, RbfField};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::{Centering, Grid};
use zeroset_mesh::signed::{
    CoarseStep, SmcOptions, SmcStage, expected_evaluations, signed_marching_cubes,
};
use zeroset_mesh::trim::{DEFAULT_REACH, ScanSupport, trim};
use zeroset_mesh::voxel::{self, Detail};
use zeroset_mesh::{McOptions, MeshFormat, TriMesh, marching_cubes_with_cell_max, mesh_field};

use crate::arrays::{points, rows_array, vector};
use crate::errors::{to_py, value_error};
use crate::field::NativeField;
use crate::progress::Hook;

/// Vertices, triangles (indices of type `I`) and normals of a mesh as numpy arrays.
type MeshArrays<'py, I = i64> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<I>>,
    Bound<'py, PyArray2<f64>>,
);

/// A numpy index type for triangles: `i64` (the package's meshes) or `i32` (marching cubes,
/// as scikit-image's; its vertex ids stay below 2³¹).
trait FaceIndex: numpy::Element + Send {
    fn from_id(id: u32) -> Self;
}

impl FaceIndex for i64 {
    fn from_id(id: u32) -> Self {
        i64::from(id)
    }
}

impl FaceIndex for i32 {
    fn from_id(id: u32) -> Self {
        i32::try_from(id).expect("marching cubes numbers its vertices below 2^31")
    }
}

/// A mesh taken apart for numpy: vertices, flat triangle indices, normals.
struct MeshParts<I>(Vec<[f64; 3]>, Vec<I>, Vec<[f64; 3]>);

impl<I: FaceIndex> MeshParts<I> {
    /// `mesh` without copying its vertices (nor its triangles for `i32`, converted in place);
    /// with `flip` the triangles' orientation reversed, with `negate` the normals (in
    /// parallel: run it with the GIL released).
    fn new(mesh: TriMesh, flip: bool, negate: bool) -> Self {
        let (vertices, mut triangles, mut normals) = mesh.into_parts();
        if flip {
            triangles
                .par_iter_mut()
                .with_min_len(4096)
                .for_each(|t| t.swap(1, 2));
        }
        if negate {
            normals
                .par_iter_mut()
                .with_min_len(4096)
                .for_each(|n| *n = n.map(|x| -x));
        }
        let faces = triangles
            .into_flattened()
            .into_iter()
            .map(I::from_id)
            .collect();
        Self(vertices, faces, normals)
    }

    /// The parts as numpy arrays (the vectors' memory handed over).
    fn arrays(self, py: Python<'_>) -> MeshArrays<'_, I> {
        let n = self.1.len() / 3;
        let faces = Array2::from_shape_vec((n, 3), self.1)
            .expect("n × 3 indices")
            .into_pyarray(py);
        (rows_array(py, self.0), faces, rows_array(py, self.2))
    }
}

/// Marching cubes on a C-contiguous 3-D volume, sample `[i, j, k]` at `(i, j, k) · spacing`
/// (scikit-image's vertex coordinates): vertices, faces (`int32`, as scikit-image's), normals
/// and the largest sample of each vertex's grid cell, oriented as scikit-image's: normals down the gradient whatever
/// `descent` says, triangles wound so that their right-hand normal points up the gradient
/// with `descent` (scikit-image's default `gradient_direction='descent'`, its "left-hand
/// rule") and down it without.
#[pyfunction]
#[pyo3(signature = (volume, level, spacing, descent, close))]
#[allow(clippy::type_complexity)]
pub(crate) fn marching_cubes_volume<'py>(
    py: Python<'py>,
    volume: PyReadonlyArray3<'py, f64>,
    level: f64,
    spacing: [f64; 3],
    descent: bool,
    close: bool,
) -> PyResult<(
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<i32>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<f64>>,
)> {
    let shape = volume.shape();
    let counts = [shape[0], shape[1], shape[2]];
    if counts.iter().any(|&c| c < 2) {
        return Err(value_error(format!(
            "the volume needs at least 2 samples along every axis, got shape {counts:?}"
        )));
    }
    if spacing.iter().any(|h| !(h.is_finite() && *h > 0.0)) {
        return Err(value_error(format!(
            "spacing must be finite and positive, got {spacing:?}"
        )));
    }
    let values = volume
        .as_slice()
        .map_err(|_| value_error("the volume must be C-contiguous"))?;
    let hi: [f64; 3] = std::array::from_fn(|a| (counts[a] - 1) as f64 * spacing[a]);
    let bounds = Aabb::new([0.0; 3], hi).map_err(to_py)?;
    let (parts, at) = py.detach(|| -> PyResult<_> {
        let grid = Grid::new(bounds, counts, Centering::Vertex).map_err(to_py)?;
        let options = McOptions::default().with_close_boundary(close);
        let (mesh, at) =
            marching_cubes_with_cell_max(&grid, values, level, &options).map_err(to_py)?;
        // Our triangles and normals point up the gradient; scikit-image's normals always
        // point down it, and its 'ascent' flips the triangles only.
        Ok((MeshParts::new(mesh, !descent, true), at))
    })?;
    let (v, f, n) = parts.arrays(py);
    Ok((v, f, n, vector(py, at)))
}

/// The grid a field is meshed on: `resolution` voxels along the longest axis, an explicit
/// `voxel` edge, or the `detail` class of the l0 rule (`None`: fine for a field that
/// [`AnyField::wants_fine_mesh`], general otherwise; for an MRAS field whose scan is denser
/// than that, [`voxel::default_voxel`] of its median spacing), over the field's box.
fn field_grid(
    field: &AnyField<3>,
    detail: Option<&str>,
    resolution: Option<usize>,
    voxel_edge: Option<f64>,
) -> PyResult<Grid<3>> {
    let bounds = field
        .bounds()
        .ok_or_else(|| value_error("the field has no bounds to mesh in"))?;
    let h = match (resolution, voxel_edge) {
        (Some(_), Some(_)) => return Err(value_error("give resolution= or voxel=, not both")),
        (Some(n), None) => {
            if n < 2 {
                return Err(value_error(format!(
                    "resolution must be at least 2 voxels along the longest axis, got {n}"
                )));
            }
            bounds.extent().into_iter().fold(0.0, f64::max) / n as f64
        }
        (None, Some(h)) => h,
        (None, None) => {
            let default = if field.wants_fine_mesh() {
                "fine"
            } else {
                "general"
            };
            let class = match detail.unwrap_or(default) {
                "coarse" => Detail::Coarse,
                "general" => Detail::General,
                "fine" => Detail::Fine,
                other => {
                    return Err(value_error(format!(
                        "detail must be 'coarse', 'general' or 'fine', got {other:?}"
                    )));
                }
            };
            match (detail, field) {
                // As `zeroset mesh`: no coarser than the scan an MRAS field records is sampled.
                (None, AnyField::Mras(f)) if !f.unit_points().is_empty() => {
                    let field_detail = f.finest_spacing().unwrap_or(0.0);
                    let spacing = || {
                        ScanSupport::new(&f.points(), DEFAULT_REACH)
                            .ok()
                            .map(|s| s.median_spacing())
                    };
                    voxel::default_voxel(&bounds, class, field_detail, spacing).0
                }
                _ => voxel::voxel_size(&bounds, class),
            }
        }
    };
    if !(h.is_finite() && h > 0.0) {
        return Err(value_error(format!(
            "the voxel edge must be finite and positive, got {h}"
        )));
    }
    voxel::grid_for(&bounds, h, 0.0).map_err(to_py)
}

/// The level set of a field (see `zeroset.mesh`).
#[pyfunction]
#[pyo3(signature = (field, level, detail, resolution, voxel, method, close, progress))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn mesh_native<'py>(
    py: Python<'py>,
    field: &NativeField,
    level: f64,
    detail: Option<&str>,
    resolution: Option<usize>,
    voxel: Option<f64>,
    method: &str,
    close: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<MeshArrays<'py>> {
    if !level.is_finite() {
        return Err(value_error(format!("level must be finite, got {level}")));
    }
    let f = &field.inner;
    // Without the GIL: an MRAS field's default voxel measures the spacing of the points it
    // records (about 2 s for a million).
    let grid = py.detach(|| field_grid(f, detail, resolution, voxel))?;
    // As `zeroset mesh`: refused before anything is allocated (signed marching cubes had no
    // check of its own, and aborted the process on a 2000³ grid).
    let c = grid.counts();
    zeroset_field_core::limits::check_bytes(
        &format!("meshing on a {}×{}×{} grid", c[0], c[1], c[2]),
        voxel::estimate_bytes(&grid),
    )
    .map_err(|e| value_error(format!("{e}; give a smaller resolution or a larger voxel")))?;
    let options = McOptions::default().with_close_boundary(close);
    let hook = Hook::new(progress);
    let result = hook.run(py, || -> PyResult<MeshParts<i64>> {
        let mesh = match (method, f.as_ref()) {
            ("mc", f) => mesh_field(f, &grid, level, &options).map_err(to_py),
            ("smc", AnyField::Rbf(RbfAny::R(f))) => smc(f, &grid, level, &options, &hook),
            ("smc", AnyField::Rbf(RbfAny::R3(f))) => smc(f, &grid, level, &options, &hook),
            ("smc", AnyField::Rbf(RbfAny::Tps(f))) => smc(f, &grid, level, &options, &hook),
            ("smc", AnyField::Rbf(RbfAny::Wendland(f))) => smc(f, &grid, level, &options, &hook),
            ("smc", other) => Err(value_error(format!(
                "method='smc' evaluates RBF fields by the fast multipole method; this is a {} \
                 field: use method='mc'",
                other.kind()
            ))),
            (other, _) => Err(value_error(format!(
                "method must be 'mc' or 'smc', got {other:?}"
            ))),
        }?;
        Ok(MeshParts::new(mesh, false, false))
    });
    Ok(hook.finish(result)?.arrays(py))
}

/// Expansion orders of the signed marching cubes: `p` settles vertices, `P` the rest (the
/// `zeroset mesh --method smc` defaults).
const LOW_ORDER: usize = 5;
const HIGH_ORDER: usize = 10;

/// The two-step signed marching cubes of an RBF field, blocks settled by enclosures first.
fn smc<K: Kernel + Clone>(
    field: &RbfField<K, 3>,
    grid: &Grid<3>,
    level: f64,
    options: &McOptions,
    hook: &Hook,
) -> PyResult<TriMesh> {
    let step = CoarseStep::Blocks;
    let [low, high] = expected_evaluations(grid, step);
    let pair = OrderPair::new(
        field,
        &FmmOptions::new(LOW_ORDER).with_expected_points(low),
        &FmmOptions::new(HIGH_ORDER).with_expected_points(high),
        DEFAULT_ERROR_SAMPLES,
        DEFAULT_SAFETY,
    )
    .map_err(to_py)?;
    let stages = |stage: SmcStage| {
        let (name, n) = match stage {
            SmcStage::Coarse { vertices } => ("smc step 1", vertices),
            SmcStage::Fine { vertices } => ("smc step 2", vertices),
            _ => ("smc triangulation", 0),
        };
        hook.report(name, 0, usize::try_from(n).unwrap_or(usize::MAX));
    };
    signed_marching_cubes(
        &pair.low,
        &pair.high,
        grid,
        level,
        pair.margin,
        &SmcOptions::from(*options).with_coarse_step(step),
        Some(&stages),
    )
    .map(|(mesh, _)| mesh)
    .map_err(to_py)
}

/// Reads a triangle mesh from a PLY, OBJ, STL or OFF file: vertices, faces, and normals when it has
/// them.
#[pyfunction]
#[allow(clippy::type_complexity)]
pub(crate) fn read_mesh(
    py: Python<'_>,
    path: PathBuf,
) -> PyResult<(
    Bound<'_, PyArray2<f64>>,
    Bound<'_, PyArray2<i64>>,
    Option<Bound<'_, PyArray2<f64>>>,
)> {
    if MeshFormat::from_path(&path).is_none() {
        return Err(value_error(format!(
            "{}: read a mesh from .ply, .obj, .stl or .off",
            path.display()
        )));
    }
    let mesh = py
        .detach(|| zeroset_mesh::read_mesh(&path))
        .map_err(to_py)?;
    let has_normals = !mesh.normals().is_empty();
    let (v, f, n) = MeshParts::new(mesh, false, false).arrays(py);
    Ok((v, f, has_normals.then_some(n)))
}

/// A mesh from numpy arrays: vertices `(n, 3)`, faces `(m, 3)` indexing them, optional normals
/// `(n, 3)` (checked: finite, indices in range).
fn mesh_of(
    vertices: &PyReadonlyArray2<'_, f64>,
    faces: &PyReadonlyArray2<'_, i64>,
    normals: Option<&PyReadonlyArray2<'_, f64>>,
) -> PyResult<TriMesh> {
    let v = points(vertices, "vertices", true)?.to_vec();
    let shape = faces.shape();
    if shape[1] != 3 {
        return Err(value_error(format!(
            "faces must have shape (m, 3), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    let flat = faces
        .as_slice()
        .map_err(|_| value_error("faces must be C-contiguous"))?;
    let mut triangles = Vec::with_capacity(flat.len() / 3);
    for (i, t) in flat.as_chunks::<3>().0.iter().enumerate() {
        let mut tri = [0u32; 3];
        for (slot, &x) in tri.iter_mut().zip(t) {
            *slot = u32::try_from(x)
                .ok()
                .filter(|&x| (x as usize) < v.len())
                .ok_or_else(|| {
                    value_error(format!(
                        "faces[{i}] = {t:?} has an index outside 0 .. {} (the vertices)",
                        v.len()
                    ))
                })?;
        }
        triangles.push(tri);
    }
    let mut mesh = TriMesh::new(v, triangles).map_err(to_py)?;
    if let Some(n) = normals {
        mesh = mesh
            .with_normals(points(n, "normals", true)?.to_vec())
            .map_err(to_py)?;
    }
    Ok(mesh)
}

/// Writes a triangle mesh, atomically: binary PLY or STL (ASCII with `ascii`) for `.ply` and
/// `.stl`, Wavefront OBJ for `.obj`, OFF for `.off`; returns how far STL's 32-bit floats moved
/// the vertices (relative to the diagonal) where that is over `F32_ROUNDING_LIMIT`.
#[pyfunction]
#[pyo3(signature = (path, vertices, faces, normals, ascii))]
pub(crate) fn write_mesh(
    py: Python<'_>,
    path: PathBuf,
    vertices: PyReadonlyArray2<'_, f64>,
    faces: PyReadonlyArray2<'_, i64>,
    normals: Option<PyReadonlyArray2<'_, f64>>,
    ascii: bool,
) -> PyResult<Option<f64>> {
    let Some(format) = MeshFormat::from_path(&path) else {
        return Err(value_error(format!(
            "{}: write a mesh as .ply, .obj, .stl or .off",
            path.display()
        )));
    };
    let mesh = mesh_of(&vertices, &faces, normals.as_ref())?;
    py.detach(|| {
        // STL holds 32-bit floats only: how far that moves the vertices, for a warning
        // where `zeroset mesh` gives one.
        let rounding = if format == MeshFormat::Stl {
            mesh.f32_rounding()
        } else {
            0.0
        };
        zeroset_mesh::write_mesh(&path, &mesh, ascii).map_err(to_py)?;
        Ok((rounding > zeroset_mesh::io::ply::F32_ROUNDING_LIMIT).then_some(rounding))
    })
}

/// A mesh cut where it leaves the reach of `scan` (`reach` local point spacings; see
/// `zeroset_mesh::trim`): vertices, faces, normals (`None` when none were given), and the
/// counts of dropped and cut triangles.
#[pyfunction]
#[pyo3(signature = (vertices, faces, normals, scan, reach))]
#[allow(clippy::type_complexity)]
pub(crate) fn trim_mesh<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    normals: Option<PyReadonlyArray2<'py, f64>>,
    scan: PyReadonlyArray2<'py, f64>,
    reach: f64,
) -> PyResult<(
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<i64>>,
    Option<Bound<'py, PyArray2<f64>>>,
    usize,
    usize,
)> {
    let mesh = mesh_of(&vertices, &faces, normals.as_ref())?;
    let scan = points(&scan, "scan", true)?.to_vec();
    let trimmed = py.detach(|| -> PyResult<_> {
        let support = ScanSupport::new(&scan, reach).map_err(to_py)?;
        Ok(trim(&mesh, &support))
    })?;
    let has_normals = !trimmed.mesh.normals().is_empty();
    let (v, f, n) = MeshParts::new(trimmed.mesh, false, false).arrays(py);
    Ok((
        v,
        f,
        has_normals.then_some(n),
        trimmed.dropped_triangles,
        trimmed.cut_triangles,
    ))
}
