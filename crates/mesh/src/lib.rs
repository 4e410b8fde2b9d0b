//! # zeroset-mesh
//!
//! Curves and surfaces from scalar fields: the zero set (or any level set) of a
//! [`ScalarField`](zeroset_field_core::field::ScalarField), extracted on a grid of samples.
//!
//! - [`squares`] — **marching squares**: the level curve `{x : f(x) = c}` of a 2-D field as
//!   polylines. Crossings are placed on cell edges by linear interpolation; the two saddle cases
//!   are resolved by the asymptotic decider, so the curve has the topology of the bilinear
//!   interpolant of the samples; a sample exactly on the level counts as above it.
//! - [`cubes`] — **marching cubes**: the level surface `{x : f(x) = c}` of a 3-D field as a
//!   welded [`TriMesh`]. Each cell's polygons are walked from the marching-squares segments of
//!   its six faces, ambiguous faces resolved by the asymptotic decider on the face's own four
//!   values, so neighbouring cells always agree: the mesh is watertight by construction.
//! - [`signed`] — **two-step signed marching cubes** (paper 002 §2.3): a cheap coarse field at
//!   every vertex, the accurate field only at the vertices of cells whose signs the coarse values
//!   (within a caller-given error margin) cannot settle; the mesh equals plain marching cubes on
//!   the accurate field. Also the paper's voxel-growing baseline, which follows the surface from
//!   seeds and misses components without one.
//! - [`svg`] — SVG previews of 2-D results (contours, polylines, points), written atomically.
//! - [`preview`] — software-rendered PNG previews: shaded meshes (orthographic, z-buffered,
//!   back faces darker) and field slices (diverging colour map, zero contour in black).
//! - [`trim`] — a mesh trimmed to the scan it was fitted to: cut where it leaves the reach of
//!   the points (a few local spacings), for one-sided scans and holes the scan left open.
//! - [`trimesh`] — indexed triangle meshes ([`TriMesh`]), wound outward.
//! - [`io`] — mesh files, each read and written: PLY (ASCII and binary, any vertex
//!   properties, polygons fan-triangulated), Wavefront OBJ, STL (binary and ASCII, corners
//!   welded into shared vertices on reading), and OFF (text, `[ST][C][N]OFF`);
//!   [`read_mesh`] / [`write_mesh`] by extension; writes are atomic.
//! - [`points`] — a mesh as an oriented point cloud: its vertices, normals from the file or
//!   the triangles' winding (closed parts wound inward turned over).
//! - [`voxel`] — the voxel size of a marching-cubes grid from the bounding box (the
//!   signed-marching-cubes paper's rule: `S_c = 5·l0` coarse, `l0` general, `0.3·l0` fine, with
//!   a continuous reading of the reference length `l0`), the cubic-voxel grid covering a box,
//!   and its memory estimate.
//! - [`checks`] — mesh checks ([`MeshReport`]): boundary, non-manifold and inconsistently
//!   oriented edges, components, Euler characteristic, closedness, signed volume, area.
//!
//! ## Guaranteed
//!
//! - Every polyline separates samples below the level (on its left) from samples at or above it
//!   (on its right); loops around the inside run counter-clockwise. With zeroset's
//!   negative-inside convention and level 0, `+∇f` points to the right of the direction of
//!   travel.
//! - Closed loops are flagged `closed` and store each vertex once; open polylines end on the
//!   border of the grid. No zero-length segment, no repeated consecutive vertex, no two segments
//!   crossing.
//! - Vertices lie within `O(h²)` of the true curve for a smooth field with non-zero gradient,
//!   and lengths converge as `O(h²)`.
//! - The same input gives the same polylines in the same order, with any number of threads.
//! - An empty contour is an empty result, not an error; a NaN or infinite sample is an error
//!   naming the sample.
//!
//! - Marching cubes: one vertex per crossed grid edge, shared by every cell around it;
//!   triangles wound counter-clockwise seen from outside (`f ≥ c`), normals along `+∇f`. When
//!   no sample lies exactly on the level, every edge is used by exactly two triangles wound
//!   opposite ways (watertight, edge-manifold, consistently oriented) except on the grid border;
//!   with `close_boundary` the surface is capped on the border and closed everywhere. Samples on
//!   the level count as outside; crossings merged onto them leave no degenerate (two equal
//!   corners) triangle and no unused vertex. The same input gives the same mesh with any
//!   number of threads.
//!
//! Not guaranteed: features smaller than a grid cell are found; marching cubes resolves a
//! cell's interior ambiguity (MC33 tunnels) like the trilinear interpolant; a surface with
//! samples on the level stays manifold at those samples (two sheets may touch there).
//!
//! ```
//! use zeroset_field_core::field::FnField;
//! use zeroset_field_core::{Aabb, Grid};
//! use zeroset_mesh::squares::contour_field;
//!
//! // f(x) = ‖x‖ − 0.5: negative inside the circle of radius 0.5.
//! let circle = FnField::new(|p: &[f64; 2]| p[0].hypot(p[1]) - 0.5, None);
//! let grid = Grid::vertex_centered(Aabb::centered_cube(1.0)?, [64, 64])?;
//! let contour = contour_field(&circle, &grid, 0.0)?;
//! println!(
//!     "{} loop(s), {} open, length {:.4} (2πr = {:.4})",
//!     contour.num_closed(),
//!     contour.num_open(),
//!     contour.total_length(),
//!     std::f64::consts::PI,
//! );
//! assert_eq!(contour.num_closed(), 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![warn(missing_docs)]

pub mod checks;
pub mod cubes;
pub mod error;
pub mod io;
pub mod points;
pub mod preview;
mod samples;
pub mod signed;
pub mod squares;
pub mod svg;
pub mod trim;
pub mod trimesh;
pub mod voxel;

pub use checks::{
    MeshReport, boundary_loops, check, component_support, components, unsupported_components,
};
pub use cubes::{McOptions, marching_cubes, marching_cubes_with_cell_max, mesh_field};
pub use error::{MeshError, Result};
pub use io::{
    MeshFormat, PlyFormat, StlFormat, is_mesh_file, read_mesh, read_obj_mesh, read_off_mesh,
    read_ply_mesh, read_stl_mesh, write_mesh, write_obj, write_off, write_ply, write_stl,
};
pub use signed::{
    CoarseStep, SmcOptions, SmcReport, SmcStage, VgReport, expected_evaluations, settled_fraction,
    signed_marching_cubes, voxel_growing,
};
pub use squares::{Contour, Polyline, contour_field, marching_squares};
pub use svg::SvgPlot;
pub use trimesh::TriMesh;
