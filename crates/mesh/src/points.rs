//! A mesh as an oriented point cloud: the points a fit takes from a mesh file, so that a broken
//! mesh (holes, a ragged scan, an STL from another program) can be rebuilt into a closed one.
//!
//! The points are the vertices the triangles use — a vertex no triangle uses is not on the
//! surface the mesh describes — or, for a mesh without triangles (an OBJ of vertices only),
//! every vertex. Their normals, in this order ([`NormalSource`]):
//! 1. the mesh's own per-vertex normals (a PLY with `nx ny nz`, an OBJ whose every vertex
//!    names one `vn`), made unit; where one is zero or not finite, the next rule decides;
//! 2. the triangles' winding, where it is consistent (each edge shared by two triangles runs
//!    opposite ways in them, and by no more than two): each vertex's area-weighted face normal
//!    ([`TriMesh::winding_normals`]). In a closed mesh, each closed part wound inward (negative
//!    volume) is turned over on its own; an open mesh has no inside to measure and is taken as
//!    wound (counter-clockwise seen from outside, zeroset's and STL's convention). Where the
//!    winding holds, this is exact information a nearest-neighbour estimate can only
//!    approximate (thin parts, sparse CAD vertices);
//! 3. none otherwise — inconsistent winding, non-manifold edges, a vertex used only by
//!    triangles without area, a mesh without triangles and normals — for the caller to
//!    estimate (as `zeroset reconstruct` does, with `zeroset_bases::normals`).
//!
//! ```
//! use zeroset_mesh::TriMesh;
//! use zeroset_mesh::points::{NormalSource, mesh_points};
//!
//! // A tetrahedron wound inward (every triangle clockwise seen from outside), and a vertex
//! // no triangle uses.
//! let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [9.0; 3]];
//! let inward = TriMesh::new(v, vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])?;
//! let p = mesh_points(inward);
//! assert_eq!((p.positions.len(), p.left_out), (4, 1));
//! assert_eq!(p.source, NormalSource::Winding { turned: 1, closed_parts: 1 });
//! // Turned over: the normal at the apex (0, 0, 1) points up and out.
//! let n = p.normals.unwrap();
//! assert!(n[3][2] > 0.5);
//! # Ok::<(), zeroset_mesh::MeshError>(())
//! ```

use std::fmt;

use zeroset_field_core::Point;
use zeroset_field_core::geometry::{cross, dot, norm, sub};

use crate::{TriMesh, check, components};

/// The points of a mesh and their normals; see the [module docs](self).
#[derive(Debug, Clone, PartialEq)]
pub struct MeshPoints {
    /// The vertices the triangles use (every vertex of a mesh without triangles), in their
    /// order in the mesh.
    pub positions: Vec<Point<3>>,
    /// One unit normal per position, or `None` ([`source`](Self::source) says why).
    pub normals: Option<Vec<Point<3>>>,
    /// Where the normals came from, or why there are none.
    pub source: NormalSource,
    /// Vertices left out because no triangle uses them.
    pub left_out: usize,
}

/// Where [`MeshPoints::normals`] came from, or why there are none. Its `Display` is a phrase
/// that follows "normals" in a sentence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum NormalSource {
    /// The mesh's own per-vertex normals, made unit.
    File,
    /// The winding of a closed mesh, with `turned` of its `closed_parts` turned over (wound
    /// inward).
    Winding {
        /// Closed parts wound inward, turned over.
        turned: usize,
        /// Closed parts (edge-connected components).
        closed_parts: usize,
    },
    /// The winding of an open mesh, as wound.
    WindingOpen,
    /// None: the winding is inconsistent or edges are non-manifold.
    Inconsistent {
        /// Edges used twice the same way.
        inconsistent_edges: usize,
        /// Edges used by more than two triangles.
        non_manifold_edges: usize,
    },
    /// None: vertices lie only on triangles without area.
    Flat {
        /// Such vertices.
        vertices: usize,
    },
    /// None: a mesh without triangles and without normals.
    NoTriangles,
}

impl fmt::Display for NormalSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::File => write!(f, "from the file"),
            Self::Winding { turned: 0, .. } => write!(f, "from the triangles' winding"),
            Self::Winding {
                turned,
                closed_parts,
            } => write!(
                f,
                "from the triangles' winding, turned over on {turned} of {closed_parts} closed \
                 part(s) wound inward"
            ),
            Self::WindingOpen => write!(f, "from the triangles' winding (an open mesh: as wound)"),
            Self::Inconsistent {
                inconsistent_edges,
                non_manifold_edges,
            } => write!(
                f,
                "not taken from the triangles: their winding is inconsistent at \
                 {inconsistent_edges} edge(s) and {non_manifold_edges} edge(s) are non-manifold"
            ),
            Self::Flat { vertices } => write!(
                f,
                "not taken from the triangles: {vertices} vertex(es) lie only on triangles \
                 without area"
            ),
            Self::NoTriangles => write!(f, "none (no triangle to take them from)"),
        }
    }
}

/// The points of `mesh` and their normals; see the [module docs](self).
pub fn mesh_points(mesh: TriMesh) -> MeshPoints {
    let all = mesh.num_vertices();
    let mesh = if mesh.is_empty() {
        mesh
    } else {
        mesh.retain_triangles(|_| true)
    };
    let left_out = all - mesh.num_vertices();
    let (normals, source) = normals(&mesh);
    let (positions, _, _) = mesh.into_parts();
    MeshPoints {
        positions,
        normals,
        source,
        left_out,
    }
}

/// The normals of `mesh`'s vertices and where they came from.
fn normals(mesh: &TriMesh) -> (Option<Vec<Point<3>>>, NormalSource) {
    let unit: Option<Vec<Point<3>>> = mesh
        .normals()
        .iter()
        .map(|n| {
            let length = norm(n);
            (length > 0.0 && length.is_finite()).then(|| n.map(|x| x / length))
        })
        .collect();
    if let Some(unit) = unit.filter(|u| !u.is_empty()) {
        return (Some(unit), NormalSource::File);
    }
    if mesh.is_empty() {
        return (None, NormalSource::NoTriangles);
    }
    let report = check(mesh);
    if report.inconsistent_edges > 0 || report.non_manifold_edges > 0 {
        let source = NormalSource::Inconsistent {
            inconsistent_edges: report.inconsistent_edges,
            non_manifold_edges: report.non_manifold_edges,
        };
        return (None, source);
    }
    let mut normals = mesh.winding_normals();
    let flat = normals.iter().filter(|n| **n == [0.0; 3]).count();
    if flat > 0 {
        return (None, NormalSource::Flat { vertices: flat });
    }
    if report.boundary_edges > 0 {
        return (Some(normals), NormalSource::WindingOpen);
    }
    // Each closed part's volume, from a corner of the box (for fewer cancelling digits).
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
    let source = NormalSource::Winding {
        turned: volume.iter().filter(|v| **v < 0.0).count(),
        closed_parts: parts,
    };
    (Some(normals), source)
}
