//! Mesh files (`.obj`, `.stl`) where a point cloud is expected: `zeroset fit`, `normals`,
//! `reconstruct` and `restore` take the mesh's vertices as the points — so that a broken mesh
//! (holes, a ragged scan, STL from another program) can be rebuilt into a closed one with
//! `zeroset reconstruct broken.stl -o closed.stl`. (A PLY mesh is read as a point cloud by the
//! PLY reader itself: its vertices, with its normals when it has `nx ny nz`.)
//!
//! The points are the vertices the triangles use: a vertex no triangle uses is not on the
//! surface the mesh describes. Their normals, in this order:
//! 1. the file's own per-vertex normals (an OBJ whose every vertex names one `vn`);
//! 2. the triangles' winding, where it is consistent (each edge shared by two triangles runs
//!    opposite ways in them, and by no more than two): each vertex's area-weighted face
//!    normal ([`TriMesh::winding_normals`]), all turned over when the mesh's signed volume is
//!    negative (a mesh wound inward). Where the winding holds, this is exact information the
//!    nearest-neighbour estimate can only approximate (thin parts, sparse CAD vertices);
//! 3. none otherwise (inconsistent winding, non-manifold edges, a vertex used only by
//!    triangles without area): `reconstruct` estimates them as `zeroset normals` does, and
//!    `fit` asks for them.

use std::path::Path;

use anyhow::{Context, bail};
use zeroset_field_core::PointCloud3;
use zeroset_field_core::io::ReadOptions;
use zeroset_mesh::{MeshFormat, TriMesh, check};

/// The points of `path` if it is an OBJ or STL mesh (told by its extension, unless `options`
/// name a point-cloud format), with the normals the [module docs](self) describe; `None` for
/// any other file. A line says what was taken and why.
pub(crate) fn read(path: &Path, options: &ReadOptions) -> anyhow::Result<Option<PointCloud3>> {
    if options.format.is_some() {
        return Ok(None);
    }
    let Some(format) = MeshFormat::from_path(path).filter(|f| *f != MeshFormat::Ply) else {
        return Ok(None);
    };
    let mesh = zeroset_mesh::read_mesh(path)
        .with_context(|| format!("reading the mesh {}", path.display()))?;
    if mesh.is_empty() {
        bail!(
            "{}: the mesh has no triangle, so no surface to take points from",
            path.display()
        );
    }
    let loose = mesh.num_vertices();
    let mesh = mesh.retain_triangles(|_| true);
    let loose = loose - mesh.num_vertices();
    let (normals, how) = normals(&mesh);
    let triangles = mesh.num_triangles();
    let (positions, _, _) = mesh.into_parts();
    outln!(
        "{:<14}{}: {} mesh of {} triangles; its {} vertices are the points{}, normals {how}",
        "mesh",
        path.display(),
        match format {
            MeshFormat::Obj => "an OBJ",
            _ => "an STL",
        },
        triangles,
        positions.len(),
        if loose > 0 {
            format!(" ({loose} that no triangle uses left out)")
        } else {
            String::new()
        }
    );
    Ok(Some(PointCloud3::from_raw(positions, normals)?))
}

/// The normals of `mesh`'s vertices (all used by triangles) and how they were found.
fn normals(mesh: &TriMesh) -> (Option<Vec<[f64; 3]>>, String) {
    if !mesh.normals().is_empty() {
        return (Some(mesh.normals().to_vec()), "from the file".into());
    }
    let report = check(mesh);
    if report.inconsistent_edges > 0 || report.non_manifold_edges > 0 {
        return (
            None,
            format!(
                "not taken from the triangles: their winding is inconsistent at {} edge(s) and \
                 {} edge(s) are non-manifold",
                report.inconsistent_edges, report.non_manifold_edges
            ),
        );
    }
    let mut normals = mesh.winding_normals();
    let flat = normals.iter().filter(|n| **n == [0.0; 3]).count();
    if flat > 0 {
        return (
            None,
            format!(
                "not taken from the triangles: {flat} vertex(es) lie only on triangles without \
                 area"
            ),
        );
    }
    if report.signed_volume < 0.0 {
        for n in &mut normals {
            *n = n.map(|x| -x);
        }
        return (
            Some(normals),
            "from the triangles' winding, turned over (the mesh is wound inward)".into(),
        );
    }
    (Some(normals), "from the triangles' winding".into())
}
