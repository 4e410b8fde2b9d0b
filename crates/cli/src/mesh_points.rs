//! Mesh files (`.obj`, `.stl`, and `.ply` with a `face` element) where a point cloud is
//! expected: `zeroset fit`, `normals`, `reconstruct` and `restore` take the mesh's vertices as
//! the points — so that a broken mesh (holes, a ragged scan, STL from another program) can be
//! rebuilt into a closed one with `zeroset reconstruct broken.stl -o closed.stl`, and a mesh
//! gives the same points and normals in each of the three formats.
//!
//! The points are the vertices the triangles use: a vertex no triangle uses is not on the
//! surface the mesh describes (an OBJ of vertices and no face is read as a point cloud, with
//! its normals when it has one per vertex). Their normals, in this order:
//! 1. the file's own per-vertex normals (a PLY with `nx ny nz`, an OBJ whose every vertex
//!    names one `vn`), made unit (where one is zero, the next rule decides);
//! 2. the triangles' winding, where it is consistent (each edge shared by two triangles runs
//!    opposite ways in them, and by no more than two): each vertex's area-weighted face
//!    normal ([`TriMesh::winding_normals`]). A closed mesh's parts wound inward (negative
//!    volume) are turned over, each on its own; an open mesh has no inside to measure and is
//!    taken as wound (counter-clockwise seen from outside, STL's convention). Where the
//!    winding holds, this is exact information the nearest-neighbour estimate can only
//!    approximate (thin parts, sparse CAD vertices);
//! 3. none otherwise (inconsistent winding, non-manifold edges, a vertex used only by
//!    triangles without area): `reconstruct` estimates them as `zeroset normals` does, and
//!    `fit` asks for them.

use std::path::Path;

use anyhow::{Context, bail};
use zeroset_field_core::PointCloud3;
use zeroset_field_core::geometry::{cross, dot, norm, sub};
use zeroset_field_core::io::ReadOptions;
use zeroset_mesh::{MeshFormat, TriMesh, check, components};

/// The points of `path` if it is a mesh — OBJ or STL (told by the extension), or PLY with a
/// `face` element; unless `options` name a point-cloud format — with the normals the
/// [module docs](self) describe; `None` for any other file. A line says what was taken and
/// why.
pub(crate) fn read(path: &Path, options: &ReadOptions) -> anyhow::Result<Option<PointCloud3>> {
    if options.format.is_some() {
        return Ok(None);
    }
    let Some(format) =
        MeshFormat::from_path(path).filter(|f| *f != MeshFormat::Ply || has_faces(path, 1))
    else {
        return Ok(None);
    };
    let mesh = zeroset_mesh::read_mesh(path)
        .with_context(|| format!("reading the mesh {}", path.display()))?;
    if mesh.is_empty() {
        if format == MeshFormat::Obj && mesh.num_vertices() > 0 {
            // An OBJ of vertices only: a point cloud (with its normals when it pairs them).
            let has_normals = !mesh.normals().is_empty();
            outln!(
                "{:<14}{}: an OBJ of {} vertices and no face, read as a point cloud{}",
                "points",
                path.display(),
                mesh.num_vertices(),
                if has_normals { " with its normals" } else { "" }
            );
            let (positions, _, normals) = mesh.into_parts();
            return Ok(Some(PointCloud3::from_raw(
                positions,
                has_normals.then_some(normals),
            )?));
        }
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
            MeshFormat::Ply => "a PLY",
            MeshFormat::Stl => "an STL",
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
        // The file's own, made unit; a zero or non-finite one and the winding decides.
        let unit: Option<Vec<[f64; 3]>> = mesh
            .normals()
            .iter()
            .map(|n| {
                let length = norm(n);
                (length > 0.0 && length.is_finite()).then(|| n.map(|x| x / length))
            })
            .collect();
        if let Some(unit) = unit {
            return (Some(unit), "from the file".into());
        }
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
    if report.boundary_edges > 0 {
        // An open surface has no inside to measure: the winding is taken as written (STL's
        // convention, and zeroset's, is counter-clockwise seen from outside).
        return (
            Some(normals),
            "from the triangles' winding (an open mesh: as wound)".into(),
        );
    }
    // A closed mesh: each closed part wound inward (negative volume) is turned over.
    let (labels, parts) = components(mesh);
    let origin = mesh.bounds().map_or([0.0; 3], |b| b.min());
    let mut volume = vec![0.0; parts];
    for (t, &part) in labels.iter().enumerate() {
        let [a, b, c] = mesh.corners(t).map(|p| sub(&p, &origin));
        volume[part as usize] += dot(&a, &cross(&b, &c)) / 6.0;
    }
    let mut turn = vec![false; normals.len()];
    for (tri, &part) in mesh.triangles().iter().zip(&labels) {
        if volume[part as usize] < 0.0 {
            for &v in tri {
                turn[v as usize] = true;
            }
        }
    }
    for (n, turn) in normals.iter_mut().zip(&turn) {
        if *turn {
            *n = n.map(|x| -x);
        }
    }
    let inward = volume.iter().filter(|v| **v < 0.0).count();
    let how = match inward {
        0 => "from the triangles' winding".to_owned(),
        k => format!(
            "from the triangles' winding, turned over on {k} of {parts} closed part(s) wound \
             inward"
        ),
    };
    (Some(normals), how)
}

/// Whether the PLY header declares a `face` element of at least `least` records (a mesh
/// rather than a point cloud). An unreadable header answers `false`: the point-cloud reader
/// then names the problem.
pub(crate) fn has_faces(path: &Path, least: usize) -> bool {
    matches!(
        zeroset_field_core::io::ply::read_header(path),
        Ok(Ok(header)) if header.element("face").is_some_and(|f| f.count >= least)
    )
}
