//! Mesh files (`.obj`, `.stl`, and `.ply` with faces) where a point cloud is expected:
//! `zeroset fit`, `normals`, `reconstruct` and `restore` take the mesh's vertices as the
//! points (a PLY whose faces use fewer than half of its vertices is a point cloud with a few
//! faces, and is read as one), with normals from the file or the triangles' winding
//! ([`zeroset_mesh::points`]) — so that a broken mesh (holes, a ragged scan, STL from another
//! program) is rebuilt into a closed one with `zeroset reconstruct broken.stl -o closed.stl`,
//! and a mesh gives the same points and normals in each of the three formats. Where the
//! winding gives no normals, `reconstruct` estimates them as `zeroset normals` does and `fit`
//! asks for them.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::{Context, bail};
use zeroset_field_core::PointCloud3;
use zeroset_field_core::io::ReadOptions;
use zeroset_mesh::points::{NormalSource, is_mostly_unused, mesh_points};
use zeroset_mesh::{MeshFormat, is_mesh_file};

/// The mesh files this process has described: `reconstruct`'s stages each read the input, and
/// the line saying what was taken is printed once.
static DESCRIBED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Whether `path` is described for the first time (and from now on, has been).
fn first_description(path: &Path) -> bool {
    let mut described = DESCRIBED.lock().unwrap_or_else(|e| e.into_inner());
    let first = !described.iter().any(|p| p == path);
    if first {
        described.push(path.to_path_buf());
    }
    first
}

/// The points of a mesh file.
pub(crate) struct MeshCloud {
    /// Its vertices (and points inside its triangles), with their normals.
    pub(crate) cloud: PointCloud3,
    /// Whether the normals come from the triangles' winding, consistent by construction:
    /// they need no check that their signs agree (the propagation that check runs crosses a
    /// mesh's sharp creases badly, and read CGAL's closed, consistently wound `3torus.off`
    /// as 48% unoriented).
    pub(crate) wound: bool,
}

/// The points of `path` if it is a mesh file ([`is_mesh_file`]; unless `options` name a
/// point-cloud format), `None` for any other file. A line says what was taken and why (once
/// per file and process).
pub(crate) fn read(path: &Path, options: &ReadOptions) -> anyhow::Result<Option<MeshCloud>> {
    if options.format.is_some() || !is_mesh_file(path) {
        return Ok(None);
    }
    let say = first_description(path);
    if options.formation.is_some() {
        bail!(
            "--formation picks the rows of a GemPy table; {} is a mesh",
            path.display()
        );
    }
    let mesh = zeroset_mesh::read_mesh(path)
        .with_context(|| format!("reading the mesh {}", path.display()))?;
    let (triangles, vertices) = (mesh.num_triangles(), mesh.num_vertices());
    if MeshFormat::from_path(path) == Some(MeshFormat::Ply) && is_mostly_unused(&mesh) {
        // A scan's PLY that carries a few faces is still a point cloud.
        say.then(|| {
            outln!(
                "{:<14}{}: its {triangles} faces use fewer than half of its {vertices} vertices: \
             read as a point cloud of every vertex, the faces ignored",
                "note",
                path.display()
            )
        });
        return Ok(None);
    }
    let points = mesh_points(mesh);
    let format = match MeshFormat::from_path(path) {
        Some(MeshFormat::Obj) => "an OBJ",
        Some(MeshFormat::Ply) => "a PLY",
        Some(MeshFormat::Off) => "an OFF",
        _ => "an STL",
    };
    if triangles == 0 {
        // An OBJ of vertices only is a point cloud; an STL without facets holds nothing.
        if vertices == 0 {
            bail!("{}: the mesh is empty: no points to fit", path.display());
        }
        say.then(|| outln!(
            "{:<14}{}: {format} of {vertices} vertices and no triangle, read as a point cloud{}",
            "points",
            path.display(),
            if points.normals.is_some() {
                " with its normals"
            } else {
                ""
            }
        ));
    } else if say {
        outln!(
            "{:<14}{}: {format} mesh of {triangles} triangles; its {} vertices{} are the \
             points{}, normals {}",
            "mesh",
            path.display(),
            points.positions.len() - points.sampled,
            if points.sampled > 0 {
                format!(
                    " and {} points inside its triangles (fewer than {} vertices: a coarse mesh)",
                    points.sampled,
                    zeroset_mesh::points::MIN_MESH_POINTS
                )
            } else {
                String::new()
            },
            if points.left_out > 0 {
                format!(" ({} that no triangle uses left out)", points.left_out)
            } else {
                String::new()
            },
            points.source
        );
    }
    let wound = matches!(
        points.source,
        NormalSource::Winding { .. }
            | NormalSource::WindingOpen
            | NormalSource::WindingOpenParts { .. }
    );
    Ok(Some(MeshCloud {
        cloud: PointCloud3::from_raw(points.positions, points.normals)?,
        wound,
    }))
}
