//! Marching cubes: the level surface `{x : f(x) = c}` of a field sampled on a 3-D grid, as a
//! welded, watertight triangle mesh.
//!
//! ## What is computed
//!
//! The grid holds samples `v_ijk = f(x_i, y_j, z_k)`. As in [marching squares](crate::squares),
//! a sample is **inside** when `v < c` and **outside** when `v ≥ c`. Every grid edge whose two
//! samples lie on different sides carries one crossing, placed by linear interpolation
//! `p = p_a + t (p_b − p_a)`, `t = (c − v_a)/(v_b − v_a)`, and **exactly one vertex**: the cells
//! sharing the edge all use it (the mesh is welded). For a `C²` field with `∇f ≠ 0` on the
//! surface, every vertex lies within `O(h²)` of the true surface.
//!
//! ## Watertight by construction: the polygon walk
//!
//! The classic 256-case table of Lorensen & Cline leaves holes, because two cells sharing a face
//! whose four corners alternate in sign (an *ambiguous* face) may join its crossings
//! differently. Here no per-cell table is trusted for that choice. Each face of a cell
//! contributes the segments that [marching squares](crate::squares) draws on it — 0, 1 or 2,
//! the saddle case resolved by the **asymptotic decider** (Nielson & Hamann 1991) on the face's
//! four values alone — and the cell's polygons are the closed loops these segments form
//! (every crossing edge of the cell lies on two of its faces, so each crossing has one segment
//! arriving and one leaving). Two cells sharing a face see the same four values, make the same
//! decision and draw the same segments, so their polygons share exactly those edges: the
//! surface has no hole and every mesh edge inside the grid is used by exactly two triangles.
//! The polygons (3 to 12 vertices) are triangulated without any diagonal joining two vertices on
//! a common face of the cell (two such vertices lie on the two segments of an ambiguous face;
//! the neighbouring cell might join them too, and the edge would be used four times): the fan
//! from the vertex on the lowest-numbered cell edge when it qualifies, another triangulation
//! otherwise, and, for the few polygons that have none, a fan around an extra **centre vertex**
//! (the mean of the polygon's vertices). The triangles of all `256 × 2⁶` (corner signs × face
//! decisions) configurations are computed once, by this walk, on first use.
//!
//! The *interior* ambiguity of a cell (MC33's tunnels) is not resolved against the trilinear
//! interpolant: the walk always gives a valid closed surface, which may choose a tunnel where
//! the trilinear interpolant has none, or the reverse.
//!
//! ## Samples on the level and the boundary
//!
//! A sample equal to `c` counts as outside, so it never carries two crossings of one edge. A
//! crossing whose interpolated position rounds onto one of its edge's two samples — always the
//! case when the outside end lies exactly on the level — is **that sample**: all such crossings
//! around it are one vertex. Triangles that this merge makes degenerate (two equal corners) are
//! dropped, pairs of equal triangles wound opposite ways (the two sides of a zero-thickness
//! sheet of samples on the level) cancel, and vertices no triangle uses any more are removed.
//!
//! With [`McOptions::close_boundary`], every sample outside the grid counts as outside: the
//! surface is capped where it leaves the grid, the caps lying on the faces of the sampled box
//! and running through its inside samples, so the mesh is closed.
//!
//! ## Output
//!
//! - **Orientation**: triangles are wound counter-clockwise seen from outside (`f ≥ c`), so
//!   `(b − a) × (c − a)` points from `f < c` to `f > c`: outward for zeroset's negative-inside
//!   fields, along `+∇f`. Normals (optional) are `∇f/‖∇f‖`: the field's gradient in
//!   [`mesh_field`], central differences of the samples (one-sided at the border),
//!   interpolated along the edge, in [`marching_cubes`]; a zero gradient gives a zero normal.
//! - **Deterministic**: vertices are numbered by the grid edge (or sample) they sit on, in the
//!   grid's linear order, then the centre vertices in cell order; triangles follow the cells in linear order. The output does not
//!   depend on the number of threads.
//! - An empty surface is an empty mesh, not an error.
//!
//! Guaranteed when no sample lies on (or within rounding of) the level: every edge is used by
//! exactly two triangles, once each way (closed, edge-manifold, consistently oriented), except
//! edges on the grid border without `close_boundary`, used once; no degenerate triangle. With
//! samples on the level: no degenerate triangle and no unused vertex; every edge is used as
//! often in one direction as in the other (no hole; tested on random grids of −1, 0, 1), and
//! exactly once each way for grid-aligned planes, boxes and zero-thickness sheets; but merging
//! crossings at a sample can pinch the surface there (two sheets sharing a vertex) and, in
//! contrived patterns, leave an edge used twice each way. Not guaranteed: features smaller
//! than a cell are found; freedom from self-intersections (as for any marching cubes).
//!
//! ## Implementation
//!
//! Four passes, each parallel over slabs of constant `i` with results joined in slab order:
//! the inside bits of the samples, packed 64 to a word along the last axis (which also checks
//! that every sample is finite); the crossings, found by XOR of neighbouring words and
//! classified (own vertex or merged onto a sample); vertex positions, numbered by a prefix sum
//! of per-word counts; and the triangles of the cells whose eight corners are not all on one
//! side (found 64 cells at a time from the words), with vertex ids read off the per-word counts
//! by popcount. No hash map, no per-cell allocation.
//!
//! The same extractor, given a set of cells and of known samples, triangulates only those cells
//! and places no crossing next to an unknown sample: the [voxel-growing](crate::signed)
//! baseline uses it to mesh exactly the cells it has found, as plain marching cubes meshes them.
//!
//! ## Layout
//!
//! Samples are in the grid's linear order, last axis fastest:
//! `values[(i·n_y + j)·n_z + k] = f(x_i, y_j, z_k)` ([`Grid::linear_index`]`([i, j, k])`).
//!
//! ```
//! use zeroset_field_core::analytic::Sphere;
//! use zeroset_field_core::{Aabb, Grid};
//! use zeroset_mesh::cubes::{McOptions, mesh_field};
//!
//! let sphere = Sphere::new([0.0; 3], 0.5);
//! let grid = Grid::vertex_centered(Aabb::centered_cube(1.0)?, [32, 32, 32])?;
//! let mesh = mesh_field(&sphere, &grid, 0.0, &McOptions::default())?;
//! assert!(mesh.num_triangles() > 1000);
//! assert_eq!(mesh.normals().len(), mesh.num_vertices());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::sync::OnceLock;

use rayon::prelude::*;
use zeroset_field_core::geometry::Point3;
use zeroset_field_core::{Centering, Grid, ScalarField};

use crate::error::{MeshError, Result};
use crate::samples;
use crate::trimesh::TriMesh;

/// What the sample count check calls the samples.
pub(crate) const SAMPLES: &str = "marching-cubes samples (one per grid point)";

/// Options of [`marching_cubes`] and [`mesh_field`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct McOptions {
    /// Treat every sample outside the grid as outside, capping the surface where it leaves the
    /// grid so that the mesh is closed. Default `false`: the surface is open there.
    pub close_boundary: bool,
    /// Compute per-vertex normals. Default `true`.
    pub normals: bool,
}

impl Default for McOptions {
    fn default() -> Self {
        Self {
            close_boundary: false,
            normals: true,
        }
    }
}

impl McOptions {
    /// These options with [`close_boundary`](Self::close_boundary) set to `close`.
    pub fn with_close_boundary(mut self, close: bool) -> Self {
        self.close_boundary = close;
        self
    }

    /// These options with [`normals`](Self::normals) set to `normals`.
    pub fn with_normals(mut self, normals: bool) -> Self {
        self.normals = normals;
        self
    }
}

/// Extracts the level surface `f = level` from samples of `f` at the points of a 3-D grid.
///
/// `values[grid.linear_index([i, j, k])]` is the sample at `grid.point([i, j, k])` (last axis
/// fastest). See the [module docs](self) for the algorithm and the guarantees. Normals, when
/// asked for, come from central differences of the samples.
///
/// # Errors
/// - [`MeshError::Field`] with [`Error::GridTooSmall`](zeroset_field_core::Error::GridTooSmall) if an axis has fewer than two samples,
///   or [`Error::ShapeMismatch`](zeroset_field_core::Error::ShapeMismatch) if `values.len() != grid.len()`;
/// - [`MeshError::NonFiniteLevel`] if `level` is NaN or infinite;
/// - [`MeshError::NonFiniteSample`] naming the first NaN or infinite sample;
/// - [`MeshError::InvalidMesh`] if the surface has more than `u32::MAX` vertices.
pub fn marching_cubes(
    grid: &Grid<3>,
    values: &[f64],
    level: f64,
    options: &McOptions,
) -> Result<TriMesh> {
    samples::check(grid, Some(values), level, SAMPLES)?;
    Ok(Extractor::new(grid, values, level, options).run()?.0)
}

/// [`marching_cubes`], and for each vertex of the mesh the largest of the eight samples of the
/// grid cell it was made in: the cell whose lowest corner is the vertex's edge's (or sample's)
/// lowest sample, moved inside the grid on each axis where that sample is the last, and for a
/// centre vertex its own cell: how high the data rises next to each vertex, for colour maps
/// (what scikit-image's `marching_cubes` returns as `values`, measured its own way). They are
/// gathered while the extractor reads those samples anyway, which costs far less than a pass
/// over the vertices afterwards, when the samples are no longer in cache.
///
/// # Errors
/// As [`marching_cubes`].
///
/// ```
/// use zeroset_field_core::{Aabb, Grid};
/// use zeroset_mesh::cubes::{McOptions, marching_cubes_with_cell_max};
///
/// // f = x on [−1, 1]³, 3 samples per axis: the plane x = 0.25 crosses the cells of x ∈ [0, 1].
/// let grid = Grid::vertex_centered(Aabb::centered_cube(1.0)?, [3, 3, 3])?;
/// let values: Vec<f64> = (0..27).map(|s| grid.point(grid.multi_index(s))[0]).collect();
/// let (mesh, cell_max) = marching_cubes_with_cell_max(&grid, &values, 0.25, &McOptions::default())?;
/// assert_eq!(cell_max.len(), mesh.num_vertices());
/// assert!(cell_max.iter().all(|&m| m == 1.0));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn marching_cubes_with_cell_max(
    grid: &Grid<3>,
    values: &[f64],
    level: f64,
    options: &McOptions,
) -> Result<(TriMesh, Vec<f64>)> {
    samples::check(grid, Some(values), level, SAMPLES)?;
    let mut ex = Extractor::new(grid, values, level, options);
    ex.cell_max = true;
    ex.run()
}

/// Samples `field` at every point of `grid` with its batched [`ScalarField::values`] (parallel
/// in the trait's default), runs [`marching_cubes`], and takes the normals (when asked for)
/// from the field's [`gradient`](ScalarField::gradient), normalised.
///
/// Every sample costs one evaluation of the field: for an RBF field (`zeroset_bases::rbf`)
/// that is a sum over all its centres, so a grid of `N` samples costs `N × centres`. Mesh one
/// with [`signed_marching_cubes`](crate::signed::signed_marching_cubes) instead, which
/// evaluates the accurate field only near the surface, on the two fast-multipole
/// approximations of `zeroset_bases::rbf::fmm::OrderPair` — what `zeroset mesh` does (6,150
/// centres on a 139 × 136 × 113 grid, both on 2 threads: 14.2 s this way, 1.9 s that way
/// with the FMM's set-up counted, the same triangles at general detail):
///
/// ```ignore
/// use zeroset_bases::rbf::fmm::{DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY, FmmOptions, OrderPair};
/// use zeroset_mesh::signed::{SmcOptions, signed_marching_cubes};
///
/// let pair = OrderPair::new(&rbf_field, &FmmOptions::new(5), &FmmOptions::new(10),
///                           DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY)?;
/// let (mesh, report) = signed_marching_cubes(&pair.low, &pair.high, &grid, 0.0, pair.margin,
///                                            &SmcOptions::default(), None)?;
/// ```
///
/// # Errors
/// As [`marching_cubes`]; a NaN or infinite value of the field is a
/// [`MeshError::NonFiniteSample`] naming the grid sample. The grid and level are checked before
/// the field is sampled, and the memory for its samples (`Error::Memory` where it is not
/// there).
pub fn mesh_field<F: ScalarField<3> + ?Sized>(
    field: &F,
    grid: &Grid<3>,
    level: f64,
    options: &McOptions,
) -> Result<TriMesh> {
    samples::check(grid, None, level, SAMPLES)?;
    let values = grid.try_sample(field)?;
    let mesh = marching_cubes(grid, &values, level, &options.with_normals(false))?;
    with_gradient_normals(mesh, field, grid, options)
}

/// `mesh` with normals `∇f/‖∇f‖` of `field` at its vertices when `options.normals`, as
/// [`mesh_field`] takes them (on `grid`; cap vertices as [`cap_normals`] sets them).
pub(crate) fn with_gradient_normals<F: ScalarField<3> + ?Sized>(
    mesh: TriMesh,
    field: &F,
    grid: &Grid<3>,
    options: &McOptions,
) -> Result<TriMesh> {
    if !options.normals {
        return Ok(mesh);
    }
    let mut normals: Vec<Point3> = mesh
        .vertices()
        .par_iter()
        .map(|p| unit(field.gradient(p)))
        .collect();
    if options.close_boundary {
        cap_normals(mesh.vertices(), grid, &mut normals);
    }
    mesh.with_normals(normals)
}

/// With [`McOptions::close_boundary`] the caps lie on the faces of the sampled box, through
/// its inside samples: a vertex at a sample of a border face takes that face's outward normal
/// (on an edge or corner of the box the normalised sum of its faces') instead of the field's
/// gradient, which there is the cut sheet's direction, not the cap's (47% of a capped
/// geological sheet's normals pointed against the winding). The rim — the crossings on the
/// border, shared by sheet and cap — keeps the gradient, but for a crossing merged onto a
/// border sample (the level running through it), which takes the face's normal.
fn cap_normals(vertices: &[Point3], grid: &Grid<3>, normals: &mut [Point3]) {
    let n = grid.counts();
    let first = grid.point([0; 3]);
    let last = grid.point([n[0] - 1, n[1] - 1, n[2] - 1]);
    vertices
        .par_iter()
        .zip(normals.par_iter_mut())
        .for_each(|(p, normal)| {
            let mut out = [0.0; 3];
            for a in 0..3 {
                if p[a] == first[a] {
                    out[a] = -1.0;
                } else if p[a] == last[a] {
                    out[a] = 1.0;
                }
            }
            if out == [0.0; 3] {
                return;
            }
            // A sample vertex's coordinates are the grid's own, exactly; a crossing's are not
            // on every axis (compared exactly: `continuous_index` loses the last digits far
            // from the origin, on georeferenced grids).
            let index = grid.continuous_index(p);
            let at_sample = (0..3).all(|a| {
                let i = index[a].round();
                i >= 0.0 && (i as usize) < n[a] && grid.coordinate(a, i as usize) == p[a]
            });
            if at_sample {
                *normal = unit(out);
            }
        });
}

/// `g/‖g‖`, or zero when `g` is zero or not finite.
pub(crate) fn unit(g: Point3) -> Point3 {
    let n = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if n > 0.0 && n.is_finite() {
        g.map(|x| x / n)
    } else {
        [0.0; 3]
    }
}

// ---------------------------------------------------------------------------------------------
// Per-sample bits, packed 64 samples to a word along the last axis.
//
// For each row of samples `(i, j)` (all `k`), `⌈n_z/64⌉` words: which samples are inside, which
// edges from a sample along axis `a` (to the next sample on that axis) carry a vertex of their
// own, and which samples carry a vertex (a crossing merged onto the sample, or a cap vertex at an
// inside sample on the border). Vertex ids: samples in linear order, each contributing its
// vertices of the edges along x, y, z, then of the sample, in that order.
// ---------------------------------------------------------------------------------------------

/// The bits of 64 consecutive samples of a row.
#[derive(Debug, Clone, Copy, Default)]
struct Word {
    inside: u64,
    own: [u64; 3],
    sample: u64,
}

impl Word {
    /// The number of vertices of the samples selected by `mask`.
    #[inline]
    fn count(&self, mask: u64) -> u32 {
        (self.own[0] & mask).count_ones()
            + (self.own[1] & mask).count_ones()
            + (self.own[2] & mask).count_ones()
            + (self.sample & mask).count_ones()
    }
}

/// How a crossing edge is resolved.
enum Crossing {
    /// A vertex of its own.
    Own,
    /// Merged onto the lower sample.
    Lo,
    /// Merged onto the upper sample.
    Hi,
}

/// `t = (c − a) / (b − a)`, clamped to `[0, 1]`, as in marching squares (values so large that
/// `b − a` overflows are halved first).
fn crossing_parameter(a: f64, b: f64, c: f64) -> f64 {
    let d = b - a;
    let t = if d.is_finite() {
        (c - a) / d
    } else {
        (0.5 * c - 0.5 * a) / (0.5 * b - 0.5 * a)
    };
    t.clamp(0.0, 1.0)
}

/// The largest `f32` step, as a fraction of the edge, at which `Extractor::apart_in_f32`
/// still moves a vertex: far from the origin, where `f32` resolves a voxel coarsely, the
/// written file is coarse anyway and the `f64` mesh is left exact.
const F32_STEP_MAX: f64 = 1e-3;

/// Marks a centre vertex in a slab's triangles (its index within the slab in the low bits).
const CENTRE: u32 = 1 << 31;

fn too_many(count: u64) -> MeshError {
    MeshError::InvalidMesh {
        detail: format!(
            "the surface has at least {count} vertices, more than marching cubes numbers \
             (2³¹ − 1); use a coarser grid"
        ),
    }
}

/// The triangles of one slab of cells, and its centre vertices.
#[derive(Default)]
struct SlabOutput {
    triangles: Vec<[u32; 3]>,
    centres: Vec<Point3>,
    centre_normals: Vec<Point3>,
    /// The largest sample of each centre vertex's cell (when asked for).
    centre_max: Vec<f64>,
    dropped: bool,
}

/// A set of cells for [`marching_cubes_masked`]: cell `[ci, cj, ck]` (its lowest corner is
/// sample `[ci, cj, ck]`) for `ci ∈ −1..=n₀ − 1` on each axis, so that the cap cells outside the
/// grid with [`McOptions::close_boundary`] can be named too.
#[derive(Debug, Clone)]
pub(crate) struct CellMask {
    /// `n + 1` per axis.
    dims: [usize; 3],
    bits: Vec<bool>,
}

impl CellMask {
    /// The empty set of cells of a grid of `n` samples per axis.
    pub(crate) fn new(n: [usize; 3]) -> Self {
        let dims = n.map(|x| x + 1);
        Self {
            dims,
            bits: vec![false; dims[0] * dims[1] * dims[2]],
        }
    }

    /// The position of cell `c` (each index in `−1..=n − 1`) in `bits`.
    #[inline]
    fn index(&self, c: [isize; 3]) -> usize {
        let [_, d1, d2] = self.dims;
        debug_assert!(
            c.iter()
                .zip(&self.dims)
                .all(|(&x, &d)| x >= -1 && x < d as isize - 1)
        );
        let u = c.map(|x| (x + 1) as usize);
        (u[0] * d1 + u[1]) * d2 + u[2]
    }

    /// Adds cell `c`; returns whether it was new.
    pub(crate) fn insert(&mut self, c: [isize; 3]) -> bool {
        let k = self.index(c);
        !std::mem::replace(&mut self.bits[k], true)
    }

    /// Whether cell `c` is in the set.
    #[inline]
    pub(crate) fn contains(&self, c: [isize; 3]) -> bool {
        self.bits[self.index(c)]
    }
}

/// [`marching_cubes`] restricted to the cells of `cells`: the triangles are those plain marching
/// cubes gives in these cells, in the same order, and the vertices those they use, in the same
/// relative order (unused ones are dropped). Samples with `known[s] == false` are never read
/// except for their side (they must be finite; give them a value `≥ level` so that they count
/// as outside and carry no cap vertex): no crossing is placed on an edge with such an end. A
/// cell of `cells` must have all its real corners known. Normals are not computed (the caller
/// takes them from the field).
pub(crate) fn marching_cubes_masked(
    grid: &Grid<3>,
    values: &[f64],
    level: f64,
    known: &[bool],
    cells: &CellMask,
    close_boundary: bool,
) -> Result<TriMesh> {
    samples::check(grid, Some(values), level, SAMPLES)?;
    if known.len() != values.len() {
        return Err(zeroset_field_core::Error::ShapeMismatch {
            what: "marching-cubes known-sample mask",
            expected: values.len(),
            got: known.len(),
        }
        .into());
    }
    if cells.dims != grid.counts().map(|x| x + 1) {
        return Err(zeroset_field_core::Error::ShapeMismatch {
            what: "marching-cubes cell mask (one entry per cell, cap cells included)",
            expected: grid.counts().iter().map(|x| x + 1).product(),
            got: cells.bits.len(),
        }
        .into());
    }
    let options = McOptions::default()
        .with_close_boundary(close_boundary)
        .with_normals(false);
    let mut ex = Extractor::new(grid, values, level, &options);
    ex.known = Some(known);
    ex.cells = Some(cells);
    Ok(ex.run()?.0)
}

struct Extractor<'a> {
    grid: &'a Grid<3>,
    values: &'a [f64],
    level: f64,
    close: bool,
    normals: bool,
    /// Record each vertex's cell maximum ([`marching_cubes_with_cell_max`]).
    cell_max: bool,
    /// Samples whose value may be read (all when `None`); edges with an unknown end carry no
    /// crossing.
    known: Option<&'a [bool]>,
    /// The cells that emit triangles (all when `None`).
    cells: Option<&'a CellMask>,
    n: [usize; 3],
    /// Words per row.
    w: usize,
    offset: f64,
}

impl<'a> Extractor<'a> {
    fn new(grid: &'a Grid<3>, values: &'a [f64], level: f64, options: &McOptions) -> Self {
        let offset = match grid.centering() {
            Centering::Cell => 0.5,
            Centering::Vertex => 0.0,
        };
        let n = grid.counts();
        Self {
            grid,
            values,
            level,
            close: options.close_boundary,
            normals: options.normals,
            cell_max: false,
            known: None,
            cells: None,
            n,
            w: n[2].div_ceil(64),
            offset,
        }
    }

    /// The mesh, and its vertices' cell maxima when `cell_max` (else empty).
    fn run(&self) -> Result<(TriMesh, Vec<f64>)> {
        let [n0, n1, n2] = self.n;
        let w = self.w;
        // Pass 1: inside bits (and a finiteness check), row by row.
        let mut words = vec![Word::default(); n0 * n1 * w];
        let finite = words
            .par_chunks_mut(w)
            .zip(self.values.par_chunks(n2))
            .map(|(row, v)| {
                let mut finite = true;
                for (word, chunk) in row.iter_mut().zip(v.chunks(64)) {
                    let mut bits = 0u64;
                    for (b, &x) in chunk.iter().enumerate() {
                        bits |= u64::from(x < self.level) << b;
                        finite &= x.is_finite();
                    }
                    word.inside = bits;
                }
                finite
            })
            .reduce(|| true, |a, b| a && b);
        if !finite {
            let index = self
                .values
                .par_iter()
                .position_first(|v| !v.is_finite())
                .unwrap_or(0);
            return Err(samples::non_finite(self.grid, self.values, index));
        }
        // Pass 2: crossings, slab by slab (a slab reads the inside bits of the next one).
        let inside: Vec<u64> = words.par_iter().map(|x| x.inside).collect();
        let known: Option<Vec<u64>> = self.known.map(|known| {
            let mut bits = vec![0u64; n0 * n1 * w];
            bits.par_chunks_mut(w)
                .zip(known.par_chunks(n2))
                .for_each(|(row, k)| {
                    for (word, chunk) in row.iter_mut().zip(k.chunks(64)) {
                        *word = chunk
                            .iter()
                            .enumerate()
                            .fold(0u64, |acc, (b, &x)| acc | u64::from(x) << b);
                    }
                });
            bits
        });
        let results: Vec<(Vec<usize>, bool)> = words
            .par_chunks_mut(n1 * w)
            .enumerate()
            .map(|(i, slab)| self.slab_crossings(i, slab, &inside, known.as_deref()))
            .collect();
        drop(inside);
        drop(known);
        let mut degenerate = false;
        for (merged_up, merged) in results {
            degenerate |= merged;
            for s in merged_up {
                let k = s % n2;
                words[s / n2 * w + k / 64].sample |= 1 << (k % 64);
            }
        }
        // Word bases (sequential prefix sum: the numbering is fixed).
        let mut base = Vec::with_capacity(words.len() + 1);
        let mut total = 0u64;
        for x in &words {
            base.push(total as u32);
            total += u64::from(x.count(!0));
            if total >= u64::from(CENTRE) {
                return Err(too_many(total));
            }
        }
        base.push(total as u32);

        // Pass 3: vertex positions (and normals), slab by slab into disjoint ranges.
        let nv = total as usize;
        let mut vertices = vec![[0.0; 3]; nv];
        let mut normals = if self.normals {
            vec![[0.0; 3]; nv]
        } else {
            Vec::new()
        };
        let mut cell_max = if self.cell_max {
            vec![0.0; nv]
        } else {
            Vec::new()
        };
        {
            let mut vslices = Vec::with_capacity(n0);
            let mut nslices = Vec::with_capacity(n0);
            let mut mslices = Vec::with_capacity(n0);
            let mut vrest: &mut [Point3] = &mut vertices;
            let mut nrest: &mut [Point3] = &mut normals;
            let mut mrest: &mut [f64] = &mut cell_max;
            for i in 0..n0 {
                let len = (base[(i + 1) * n1 * w] - base[i * n1 * w]) as usize;
                let (v, r) = vrest.split_at_mut(len);
                vslices.push(v);
                vrest = r;
                let (nn, r) = nrest.split_at_mut(if self.normals { len } else { 0 });
                nslices.push(nn);
                nrest = r;
                let (m, r) = mrest.split_at_mut(if self.cell_max { len } else { 0 });
                mslices.push(m);
                mrest = r;
            }
            vslices
                .into_par_iter()
                .zip(nslices)
                .zip(mslices)
                .enumerate()
                .for_each(|(i, ((v, nn), m))| self.slab_vertices(i, &words, v, nn, m));
        }

        // Pass 4: triangles, slab of cells by slab of cells, concatenated in order.
        let table = table();
        let (lo, hi) = if self.close {
            (-1, n0 as isize)
        } else {
            (0, n0 as isize - 1)
        };
        let zero_row = vec![Word::default(); w];
        let ctx = Context {
            words: &words,
            base: &base,
            zero_row: &zero_row,
            vertices: &vertices,
            normals: &normals,
            table,
        };
        let slabs: Vec<SlabOutput> = (lo..hi)
            .into_par_iter()
            .map(|ci| self.slab_triangles(ci, &ctx))
            .collect();
        degenerate |= slabs.iter().any(|s| s.dropped);
        let mut triangles: Vec<[u32; 3]> =
            Vec::with_capacity(slabs.iter().map(|s| s.triangles.len()).sum());
        for s in slabs {
            // Centre vertices are numbered after the edge vertices, slab by slab.
            let first = vertices.len() as u64;
            if first + s.centres.len() as u64 >= u64::from(CENTRE) {
                return Err(too_many(first + s.centres.len() as u64));
            }
            let first = first as u32;
            triangles.extend(s.triangles.iter().map(|t| {
                t.map(|v| {
                    if v & CENTRE != 0 {
                        first + (v & !CENTRE)
                    } else {
                        v
                    }
                })
            }));
            vertices.extend_from_slice(&s.centres);
            normals.extend_from_slice(&s.centre_normals);
            cell_max.extend_from_slice(&s.centre_max);
        }
        if degenerate {
            triangles = cancel_opposite(triangles);
        }
        if degenerate || self.cells.is_some() {
            compact(&mut vertices, &mut normals, &mut cell_max, &mut triangles);
        }
        if self.normals && self.close {
            cap_normals(&vertices, self.grid, &mut normals);
        }
        let mesh = TriMesh::new(vertices, triangles)?;
        let mesh = if self.normals {
            mesh.with_normals(normals)?
        } else {
            mesh
        };
        Ok((mesh, cell_max))
    }

    /// The crossings of slab `i` (samples `[i, ·, ·]`) into its words; returns the samples of
    /// the next slab onto which a crossing merges, and whether any crossing merged.
    fn slab_crossings(
        &self,
        i: usize,
        slab: &mut [Word],
        inside: &[u64],
        known: Option<&[u64]>,
    ) -> (Vec<usize>, bool) {
        let [n0, n1, n2] = self.n;
        let w = self.w;
        let mut merged_up = Vec::new();
        let mut merged = false;
        let last = if n2 % 64 == 0 {
            !0
        } else {
            (1u64 << (n2 % 64)) - 1
        };
        for j in 0..n1 {
            let row = i * n1 + j;
            let border = self.close && (i == 0 || i + 1 == n0 || j == 0 || j + 1 == n1);
            for q in 0..w {
                let here = inside[row * w + q];
                let valid = if q + 1 == w { last } else { !0 };
                // Bit k: sample k + 1 (the next on the last axis) is inside.
                let next_bit = if q + 1 < w {
                    inside[row * w + q + 1] & 1
                } else {
                    0
                };
                let up = (here >> 1) | (next_bit << 63);
                // Edges along z exist below the last sample.
                let z_valid = if q + 1 == w {
                    if n2 % 64 == 0 { !0 >> 1 } else { last >> 1 }
                } else {
                    !0
                };
                let mut crossing = [
                    if i + 1 < n0 {
                        (here ^ inside[(row + n1) * w + q]) & valid
                    } else {
                        0
                    },
                    if j + 1 < n1 {
                        (here ^ inside[(row + 1) * w + q]) & valid
                    } else {
                        0
                    },
                    (here ^ up) & z_valid,
                ];
                if let Some(known) = known {
                    // Only edges with both ends known carry a crossing.
                    let k_here = known[row * w + q];
                    let k_next = if q + 1 < w {
                        known[row * w + q + 1] & 1
                    } else {
                        0
                    };
                    if i + 1 < n0 {
                        crossing[0] &= k_here & known[(row + n1) * w + q];
                    }
                    if j + 1 < n1 {
                        crossing[1] &= k_here & known[(row + 1) * w + q];
                    }
                    crossing[2] &= k_here & ((k_here >> 1) | (k_next << 63));
                }
                let stride = [n1 * n2, n2, 1];
                for (a, &bits) in crossing.iter().enumerate() {
                    let mut bits = bits;
                    while bits != 0 {
                        let b = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        let k = q * 64 + b;
                        let s = row * n2 + k;
                        let at = [i, j, k][a];
                        match self.classify(self.values[s], self.values[s + stride[a]], a, at) {
                            Crossing::Own => slab[j * w + q].own[a] |= 1 << b,
                            Crossing::Lo => {
                                slab[j * w + q].sample |= 1 << b;
                                merged = true;
                            }
                            Crossing::Hi => {
                                merged = true;
                                match a {
                                    0 => merged_up.push(s + stride[0]),
                                    1 => slab[(j + 1) * w + q].sample |= 1 << b,
                                    _ => {
                                        let (q2, b2) = ((k + 1) / 64, (k + 1) % 64);
                                        slab[j * w + q2].sample |= 1 << b2;
                                    }
                                }
                            }
                        }
                    }
                }
                if self.close {
                    // Cap vertices: inside samples on the border of the grid.
                    let mut cap = if border { here } else { 0 };
                    if q == 0 {
                        cap |= here & 1;
                    }
                    if q + 1 == w {
                        cap |= here & (1 << ((n2 - 1) % 64));
                    }
                    slab[j * w + q].sample |= cap;
                }
            }
        }
        (merged_up, merged)
    }

    /// The crossing on the edge from sample `at` to `at + 1` along `axis`, of values `lo` and
    /// `hi` on different sides of the level: merged onto an end when its position rounds onto
    /// that sample's (always so when the outside end lies on the level).
    #[inline]
    fn classify(&self, lo: f64, hi: f64, axis: usize, at: usize) -> Crossing {
        let t = crossing_parameter(lo, hi, self.level);
        let p = self.coordinate(axis, at as f64 + t);
        if p == self.coordinate(axis, at as f64) {
            Crossing::Lo
        } else if p == self.coordinate(axis, (at + 1) as f64) {
            Crossing::Hi
        } else {
            Crossing::Own
        }
    }

    /// Coordinate `x` of a vertex of its own on the edge from sample `at` to `at + 1` along
    /// `axis`, moved to the next `f32` value towards the other end where it would be written
    /// as the same `f32` as an end sample (at most 1.5 `f32` steps, and only where a step is
    /// under [`F32_STEP_MAX`] of the edge). A crossing just beside a sample otherwise puts the
    /// vertices of several edges around that sample at one position once written as `f32`
    /// (PLY, STL): zero-area triangles, and in STL — whose readers weld corners by position —
    /// edges shared by four triangles. Vertices on the other edges around the sample keep the
    /// sample's coordinate on this axis, so one `f32` step keeps them apart.
    #[inline]
    fn apart_in_f32(&self, axis: usize, at: usize, x: f64) -> f64 {
        let (lo, hi) = (
            self.coordinate(axis, at as f64),
            self.coordinate(axis, (at + 1) as f64),
        );
        let (x32, lo32, hi32) = (x as f32, lo as f32, hi as f32);
        let (above_lo, below_hi) = (lo32.next_up(), hi32.next_down());
        let step = f64::from(above_lo) - f64::from(lo32);
        let movable = above_lo < below_hi && step <= F32_STEP_MAX * (hi - lo);
        if !movable {
            // An edge a few f32 steps long, or one f32 cannot resolve: nothing to gain.
            x
        } else if x32 == lo32 {
            f64::from(above_lo)
        } else if x32 == hi32 {
            f64::from(below_hi)
        } else {
            x
        }
    }

    /// The coordinate at continuous index `s` on `axis` (the grid's formula, so that integer
    /// `s` gives exactly the sample's coordinate).
    #[inline]
    fn coordinate(&self, axis: usize, s: f64) -> f64 {
        self.grid.bounds().min()[axis] + (s + self.offset) * self.grid.spacing()[axis]
    }

    /// The central-difference gradient of the samples at sample `[i, j, k]` (one-sided on the
    /// border).
    fn sample_gradient(&self, idx: [usize; 3]) -> Point3 {
        let [_, n1, n2] = self.n;
        let stride = [n1 * n2, n2, 1];
        let s = (idx[0] * n1 + idx[1]) * n2 + idx[2];
        let h = self.grid.spacing();
        std::array::from_fn(|a| {
            let lo = if idx[a] > 0 { s - stride[a] } else { s };
            let hi = if idx[a] + 1 < self.n[a] {
                s + stride[a]
            } else {
                s
            };
            let steps = (hi - lo) / stride[a];
            (self.values[hi] - self.values[lo]) / (steps as f64 * h[a])
        })
    }

    /// The largest of the eight samples of the cell whose lowest corner is sample `idx`, moved
    /// inside the grid on each axis (the cells of a grid run from 0 to `n − 2`).
    fn cell_max_at(&self, idx: [isize; 3]) -> f64 {
        let [_, n1, n2] = self.n;
        let base: [usize; 3] =
            std::array::from_fn(|a| idx[a].clamp(0, self.n[a] as isize - 2) as usize);
        let s = (base[0] * n1 + base[1]) * n2 + base[2];
        let v = self.values;
        let mut max = f64::NEG_INFINITY;
        for row in [s, s + n2, s + n1 * n2, s + n1 * n2 + n2] {
            max = max.max(v[row]).max(v[row + 1]);
        }
        max
    }

    /// Positions (and normals, and cell maxima) of the vertices of slab `i`, in id order.
    fn slab_vertices(
        &self,
        i: usize,
        words: &[Word],
        out: &mut [Point3],
        normals: &mut [Point3],
        cell_max: &mut [f64],
    ) {
        let [_, n1, n2] = self.n;
        let w = self.w;
        let stride = [n1 * n2, n2, 1];
        let mut next = 0;
        for j in 0..n1 {
            let row = i * n1 + j;
            for (q, word) in words[row * w..(row + 1) * w].iter().enumerate() {
                let mut any = word.own[0] | word.own[1] | word.own[2] | word.sample;
                while any != 0 {
                    let b = any.trailing_zeros() as usize;
                    any &= any - 1;
                    let k = q * 64 + b;
                    let s = row * n2 + k;
                    let idx = [i, j, k];
                    for a in 0..3 {
                        if word.own[a] >> b & 1 == 0 {
                            continue;
                        }
                        let t = crossing_parameter(
                            self.values[s],
                            self.values[s + stride[a]],
                            self.level,
                        );
                        out[next] = std::array::from_fn(|c| {
                            let s = idx[c] as f64 + if c == a { t } else { 0.0 };
                            self.coordinate(c, s)
                        });
                        out[next][a] = self.apart_in_f32(a, idx[a], out[next][a]);
                        if self.normals {
                            let g0 = self.sample_gradient(idx);
                            let mut up = idx;
                            up[a] += 1;
                            let g1 = self.sample_gradient(up);
                            normals[next] =
                                unit(std::array::from_fn(|c| (1.0 - t) * g0[c] + t * g1[c]));
                        }
                        if self.cell_max {
                            cell_max[next] = self.cell_max_at(idx.map(|x| x as isize));
                        }
                        next += 1;
                    }
                    if word.sample >> b & 1 != 0 {
                        out[next] = std::array::from_fn(|c| self.coordinate(c, idx[c] as f64));
                        if self.normals {
                            normals[next] = unit(self.sample_gradient(idx));
                        }
                        if self.cell_max {
                            cell_max[next] = self.cell_max_at(idx.map(|x| x as isize));
                        }
                        next += 1;
                    }
                }
            }
        }
        debug_assert_eq!(next, out.len());
    }

    /// The triangles of the cells `[ci, ·, ·]` (between sample slabs `ci` and `ci + 1`; `−1`
    /// and `n₀ − 1` are the cap cells outside the grid with `close_boundary`).
    fn slab_triangles(&self, ci: isize, ctx: &Context<'_>) -> SlabOutput {
        let [n0, n1, n2] = self.n;
        let w = self.w;
        let mut out = SlabOutput::default();
        let (lo, hi) = if self.close {
            (-1, n1 as isize)
        } else {
            (0, n1 as isize - 1)
        };
        let last_cell = n2 - 2; // cells 0..=n2−2 lie inside the grid along z
        for cj in lo..hi {
            // The four sample rows of this row of cells: r = dx | dy << 1.
            let mut rows: [&[Word]; 4] = [ctx.zero_row; 4];
            let mut row_index = [usize::MAX; 4];
            let mut virt = 0u8;
            for r in 0..4 {
                let (i, j) = (ci + (r & 1) as isize, cj + (r >> 1) as isize);
                if i < 0 || j < 0 || i >= n0 as isize || j >= n1 as isize {
                    virt |= (1 << r) | (1 << (r + 4));
                } else {
                    let row = i as usize * n1 + j as usize;
                    rows[r] = &ctx.words[row * w..(row + 1) * w];
                    row_index[r] = row;
                }
            }
            let cells = CellRow {
                ex: self,
                ctx,
                rows,
                row_index,
                ci,
                cj,
            };
            if self.close {
                // The cap cells before the first and after the last sample of the rows.
                let case = (0..4).fold(0usize, |acc, r| {
                    acc | ((rows[r][0].inside & 1) as usize) << (r + 4)
                });
                cells.emit(case, -1, virt | 0x0F, &mut out);
                let (q, b) = ((n2 - 1) / 64, (n2 - 1) % 64);
                let case = (0..4).fold(0usize, |acc, r| {
                    acc | ((rows[r][q].inside >> b & 1) as usize) << r
                });
                cells.emit(case, n2 as isize - 1, virt | 0xF0, &mut out);
            }
            for q in 0..w {
                let word = |r: usize| rows[r][q].inside;
                let up = |r: usize| {
                    let next = if q + 1 < w {
                        rows[r][q + 1].inside & 1
                    } else {
                        0
                    };
                    (rows[r][q].inside >> 1) | (next << 63)
                };
                let c = [
                    word(0),
                    word(1),
                    word(2),
                    word(3),
                    up(0),
                    up(1),
                    up(2),
                    up(3),
                ];
                let any = c.iter().fold(0, |a, x| a | x);
                let all = c.iter().fold(!0, |a, x| a & x);
                let mut mixed = any & !all;
                if q * 64 + 63 > last_cell {
                    let keep = last_cell + 1 - q * 64; // cells q·64 .. last_cell
                    mixed &= if keep >= 64 { !0 } else { (1u64 << keep) - 1 };
                }
                while mixed != 0 {
                    let b = mixed.trailing_zeros() as usize;
                    mixed &= mixed - 1;
                    let case = c.iter().enumerate().fold(0usize, |acc, (corner, x)| {
                        acc | ((x >> b & 1) as usize) << corner
                    });
                    cells.emit(case, (q * 64 + b) as isize, virt, &mut out);
                }
            }
        }
        out
    }
}

/// What the cell pass reads.
struct Context<'a> {
    words: &'a [Word],
    base: &'a [u32],
    zero_row: &'a [Word],
    vertices: &'a [Point3],
    normals: &'a [Point3],
    table: &'static Table,
}

/// One row of cells `[ci, cj, ·]`.
struct CellRow<'a, 'b> {
    ex: &'b Extractor<'a>,
    ctx: &'b Context<'b>,
    /// The words of the four sample rows (`r = dx | dy << 1`; zero for rows outside the grid).
    rows: [&'b [Word]; 4],
    /// Their row numbers (`usize::MAX` outside the grid).
    row_index: [usize; 4],
    ci: isize,
    cj: isize,
}

impl CellRow<'_, '_> {
    /// The id of vertex `kind` (0–2: the edge along that axis, 3: the sample) of the sample at
    /// corner `c` of cell `ck`.
    #[inline]
    fn vertex(&self, c: usize, ck: isize, kind: usize) -> u32 {
        let r = c & 3;
        let k = (ck + (c >> 2) as isize) as usize;
        let (q, b) = (k / 64, k % 64);
        let word = &self.rows[r][q];
        let below = (1u64 << b) - 1;
        let mut id = self.ctx.base[self.row_index[r] * self.ex.w + q] + word.count(below);
        for own in &word.own[..kind] {
            id += (own >> b & 1) as u32;
        }
        id
    }

    /// The value at corner `c` of cell `ck` (a real corner).
    #[inline]
    fn value(&self, c: usize, ck: isize) -> f64 {
        let k = (ck + (c >> 2) as isize) as usize;
        self.ex.values[self.row_index[c & 3] * self.ex.n[2] + k]
    }

    /// Appends the triangles of cell `ck` of this row with inside corners `case`, `virt` the
    /// corners outside the grid; notes in `out.dropped` whether a triangle was dropped as
    /// degenerate.
    fn emit(&self, case: usize, ck: isize, virt: u8, out: &mut SlabOutput) {
        if case == 0 {
            return;
        }
        if let Some(cells) = self.ex.cells
            && !cells.contains([self.ci, self.cj, ck])
        {
            return;
        }
        let table = self.ctx.table;
        let mut decisions = 0usize;
        let ambiguous = table.ambiguous[case];
        if ambiguous != 0 {
            for (f, corners) in FACES.iter().enumerate() {
                if ambiguous & (1 << f) != 0 && self.joins_inside(ck, corners, case) {
                    decisions |= 1 << f;
                }
            }
        }
        let id = |e: u8| -> u32 {
            let (ca, cb, axis) = EDGES[e as usize];
            if virt & (1 << ca) != 0 {
                // A cap edge: the vertex is the real end.
                return self.vertex(cb, ck, 3);
            }
            if virt & (1 << cb) != 0 {
                return self.vertex(ca, ck, 3);
            }
            let k = (ck + (ca >> 2) as isize) as usize;
            if self.rows[ca & 3][k / 64].own[axis] >> (k % 64) & 1 != 0 {
                return self.vertex(ca, ck, axis);
            }
            // Merged onto an end (rare): which one, as pass 2 decided.
            let at = [
                (self.ci + (ca & 1) as isize) as usize,
                (self.cj + (ca >> 1 & 1) as isize) as usize,
                k,
            ][axis];
            match self
                .ex
                .classify(self.value(ca, ck), self.value(cb, ck), axis, at)
            {
                Crossing::Hi => self.vertex(cb, ck, 3),
                _ => self.vertex(ca, ck, 3),
            }
        };
        let config = case * 64 + decisions;
        let mut centre_ids = [0u32; 4];
        let centres = table.centres(config);
        let mut k = 0;
        let mut p = 0;
        while k < centres.len() {
            let len = centres[k] as usize;
            let ids = &centres[k + 1..k + 1 + len];
            let mean = |points: &[Point3]| -> Point3 {
                let mut sum = [0.0; 3];
                for &e in ids {
                    let x = points[id(e) as usize];
                    for a in 0..3 {
                        sum[a] += x[a];
                    }
                }
                sum.map(|x| x / len as f64)
            };
            centre_ids[p] = CENTRE | out.centres.len() as u32;
            out.centres.push(mean(self.ctx.vertices));
            if !self.ctx.normals.is_empty() {
                out.centre_normals.push(unit(mean(self.ctx.normals)));
            }
            if self.ex.cell_max {
                out.centre_max
                    .push(self.ex.cell_max_at([self.ci, self.cj, ck]));
            }
            k += 1 + len;
            p += 1;
        }
        for tri in table.triangles(config) {
            let t = tri.map(|e| {
                if e < 12 {
                    id(e)
                } else {
                    centre_ids[(e - 12) as usize]
                }
            });
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                out.triangles.push(t);
            } else {
                out.dropped = true;
            }
        }
    }

    /// The asymptotic decider on an ambiguous face: whether its two inside corners are joined
    /// through the face, i.e. `w_a w_b > w_c w_d` with `w = v − c`, `a, b` the inside diagonal.
    /// Symmetric in the face's values, so both cells sharing the face decide alike. (An
    /// ambiguous face never has a corner outside the grid: those count as outside and come in
    /// adjacent pairs.)
    fn joins_inside(&self, ck: isize, corners: &[usize; 4], case: usize) -> bool {
        let level = self.ex.level;
        let v = corners.map(|c| self.value(c, ck));
        let mut w = v.map(|x| x - level);
        if w.iter().any(|x| !x.is_finite()) {
            w = v.map(|x| 0.5 * x - 0.5 * level);
        }
        let s = w.iter().fold(0.0_f64, |s, x| s.max(x.abs()));
        let w = w.map(|x| x / s);
        let (in_diag, out_diag) = if case & (1 << corners[0]) != 0 {
            (w[0] * w[2], w[1] * w[3])
        } else {
            (w[1] * w[3], w[0] * w[2])
        };
        in_diag > out_diag
    }
}

/// Removes pairs of equal triangles wound opposite ways (the two sides of a zero-thickness
/// sheet of samples on the level), keeping the order of the others.
fn cancel_opposite(triangles: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
    let mut keyed: Vec<([u32; 3], bool, usize)> = triangles
        .iter()
        .enumerate()
        .map(|(t, &[a, b, c])| {
            // Rotate the smallest index first; the orientation is whether the rest ascend.
            let [m, p, q] = if a < b && a < c {
                [a, b, c]
            } else if b < c {
                [b, c, a]
            } else {
                [c, a, b]
            };
            ([m, p.min(q), p.max(q)], p < q, t)
        })
        .collect();
    keyed.sort_unstable();
    let mut removed = vec![false; triangles.len()];
    let mut any = false;
    let mut k = 0;
    while k < keyed.len() {
        let end = k + keyed[k..].iter().take_while(|e| e.0 == keyed[k].0).count();
        let group = &keyed[k..end];
        let backward: Vec<usize> = group.iter().filter(|e| !e.1).map(|e| e.2).collect();
        let forward: Vec<usize> = group.iter().filter(|e| e.1).map(|e| e.2).collect();
        for (&f, &b) in forward.iter().zip(&backward) {
            removed[f] = true;
            removed[b] = true;
            any = true;
        }
        k = end;
    }
    if !any {
        return triangles;
    }
    triangles
        .into_iter()
        .zip(removed)
        .filter(|(_, r)| !r)
        .map(|(t, _)| t)
        .collect()
}

/// Drops the vertices no triangle uses (with their normals and cell maxima, where present),
/// keeping the order of the others, and renumbers the triangles.
fn compact(
    vertices: &mut Vec<Point3>,
    normals: &mut Vec<Point3>,
    cell_max: &mut Vec<f64>,
    triangles: &mut [[u32; 3]],
) {
    let mut new_id = vec![u32::MAX; vertices.len()];
    for t in triangles.iter() {
        for &v in t {
            new_id[v as usize] = 0;
        }
    }
    let mut next = 0u32;
    for id in new_id.iter_mut() {
        if *id == 0 {
            *id = next;
            next += 1;
        }
    }
    if next as usize == vertices.len() {
        return;
    }
    fn keep<T>(v: &mut Vec<T>, new_id: &[u32]) {
        let mut k = 0;
        v.retain(|_| {
            k += 1;
            new_id[k - 1] != u32::MAX
        });
    }
    keep(vertices, &new_id);
    if !normals.is_empty() {
        keep(normals, &new_id);
    }
    if !cell_max.is_empty() {
        keep(cell_max, &new_id);
    }
    for t in triangles.iter_mut() {
        *t = t.map(|v| new_id[v as usize]);
    }
}

// ---------------------------------------------------------------------------------------------
// The configuration table, computed by the polygon walk.
//
// Corner `c = dx | dy << 1 | dz << 2`. Edge `e` along axis `a` joins corners `ca` (bit `a`
// clear) and `cb = ca | 1 << a`; edges are numbered `4a + (the other two bits of ca, lower
// axis first)`.
// ---------------------------------------------------------------------------------------------

/// `(ca, cb, axis)` of each of the 12 cell edges.
const EDGES: [(usize, usize, usize); 12] = {
    let mut e = [(0, 0, 0); 12];
    let mut a = 0;
    while a < 3 {
        let (u, v) = other_axes(a);
        let mut q = 0;
        while q < 4 {
            let ca = ((q & 1) << u) | ((q >> 1) << v);
            e[4 * a + q] = (ca, ca | (1 << a), a);
            q += 1;
        }
        a += 1;
    }
    e
};

/// The two axes other than `a`, lower first.
const fn other_axes(a: usize) -> (usize, usize) {
    match a {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// The corners of face `f = 2a + side`, in cyclic order counter-clockwise seen from inside the
/// cell (the right-hand normal points into the cell).
const FACES: [[usize; 4]; 6] = {
    let mut faces = [[0; 4]; 6];
    let mut a = 0;
    while a < 3 {
        // (u, v) with e_u × e_v = e_a.
        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
        let mut side = 0;
        while side < 2 {
            let s = side << a;
            let ring = [s, s | (1 << u), s | (1 << u) | (1 << v), s | (1 << v)];
            faces[2 * a + side] = if side == 0 {
                ring
            } else {
                [ring[3], ring[2], ring[1], ring[0]]
            };
            side += 1;
        }
        a += 1;
    }
    faces
};

/// The edge joining corners `p` and `q` (which differ in one bit).
fn edge_between(p: usize, q: usize) -> usize {
    let a = (p ^ q).trailing_zeros() as usize;
    let lo = p.min(q);
    let (u, v) = other_axes(a);
    4 * a + ((lo >> u) & 1) + 2 * ((lo >> v) & 1)
}

/// Triangles (as cell-edge triples) for every corner case and face decision.
struct Table {
    /// `offsets[case · 64 + decisions]..offsets[… + 1]` indexes `triangles`. A corner `e < 12`
    /// is the vertex on cell edge `e`, `12 + p` the centre of the configuration's `p`-th
    /// centred polygon.
    offsets: Vec<u32>,
    triangles: Vec<[u8; 3]>,
    /// `centre_offsets[config]..[config + 1]` indexes `centre_data`: for each polygon fanned
    /// around a centre vertex, its length and its edges.
    centre_offsets: Vec<u32>,
    centre_data: Vec<u8>,
    /// The ambiguous faces of each case (bit `f`).
    ambiguous: [u8; 256],
}

impl Table {
    #[inline]
    fn triangles(&self, config: usize) -> &[[u8; 3]] {
        &self.triangles[self.offsets[config] as usize..self.offsets[config + 1] as usize]
    }

    #[inline]
    fn centres(&self, config: usize) -> &[u8] {
        &self.centre_data
            [self.centre_offsets[config] as usize..self.centre_offsets[config + 1] as usize]
    }
}

fn table() -> &'static Table {
    static TABLE: OnceLock<Table> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut offsets = Vec::with_capacity(256 * 64 + 1);
        let mut triangles = Vec::new();
        let mut ambiguous = [0u8; 256];
        offsets.push(0);
        let mut centre_offsets = vec![0u32];
        let mut centre_data = Vec::new();
        for (case, amb) in ambiguous.iter_mut().enumerate() {
            for (f, corners) in FACES.iter().enumerate() {
                let inside = corners.map(|c| case >> c & 1 == 1);
                if inside[0] == inside[2] && inside[1] == inside[3] && inside[0] != inside[1] {
                    *amb |= 1 << f;
                }
            }
            for decisions in 0..64 {
                let mut centred = 0u8;
                for polygon in cell_polygons(case, decisions) {
                    match triangulate(&polygon) {
                        Some(t) => triangles.extend(t),
                        None => {
                            // Fan around a centre vertex: no diagonal at all.
                            let m = polygon.len();
                            triangles.extend(
                                (0..m).map(|k| [polygon[k], polygon[(k + 1) % m], 12 + centred]),
                            );
                            centre_data.push(m as u8);
                            centre_data.extend_from_slice(&polygon);
                            centred += 1;
                        }
                    }
                }
                offsets.push(triangles.len() as u32);
                centre_offsets.push(centre_data.len() as u32);
            }
        }
        Table {
            offsets,
            triangles,
            centre_offsets,
            centre_data,
            ambiguous,
        }
    })
}

/// The polygons of a cell with inside corners `case` (bit `c`) and face decisions `decisions`
/// (bit `f` set: the inside corners of ambiguous face `f` are joined): each face's marching
/// squares segments, walked into closed loops. Each loop starts at its lowest-numbered edge and
/// runs counter-clockwise seen from outside.
pub(crate) fn cell_polygons(case: usize, decisions: usize) -> Vec<Vec<u8>> {
    let mut next = [u8::MAX; 12];
    for (f, corners) in FACES.iter().enumerate() {
        let inside = corners.map(|c| case >> c & 1 == 1);
        let edges: [usize; 4] =
            std::array::from_fn(|k| edge_between(corners[k], corners[(k + 1) % 4]));
        let exits: Vec<usize> = (0..4)
            .filter(|&k| inside[k] && !inside[(k + 1) % 4])
            .collect();
        let step = match exits.len() {
            0 => continue,
            1 => (1..4)
                .find(|&d| !inside[(exits[0] + d) % 4] && inside[(exits[0] + d + 1) % 4])
                .unwrap_or(1),
            _ if decisions & (1 << f) != 0 => 1,
            _ => 3,
        };
        for &k in &exits {
            next[edges[k]] = edges[(k + step) % 4] as u8;
        }
    }
    let mut seen = [false; 12];
    let mut polygons = Vec::new();
    for start in 0..12 {
        if next[start] == u8::MAX || seen[start] {
            continue;
        }
        let mut polygon = Vec::new();
        let mut e = start;
        while !seen[e] {
            seen[e] = true;
            polygon.push(e as u8);
            e = next[e] as usize;
        }
        debug_assert_eq!(e, start, "case {case:#x}: the face segments do not close");
        polygons.push(polygon);
    }
    polygons
}

/// Whether two cell edges lie on a common face.
fn share_face(e: u8, f: u8) -> bool {
    let faces = |e: u8| {
        let (ca, _, axis) = EDGES[e as usize];
        let (u, v) = other_axes(axis);
        [2 * u + ((ca >> u) & 1), 2 * v + ((ca >> v) & 1)]
    };
    let (a, b) = (faces(e), faces(f));
    a.iter().any(|x| b.contains(x))
}

/// Triangulates a cell polygon without a diagonal between two vertices on a common face (they
/// lie on an ambiguous face, on its two different segments): the neighbouring cell may join the
/// same two vertices, and the edge would then be used four times. Among the allowed
/// triangulations, the fan from the first vertex is preferred.
///
/// `None` when there is none; the polygon is then fanned around a centre vertex.
fn triangulate(polygon: &[u8]) -> Option<Vec<[u8; 3]>> {
    let m = polygon.len();
    let allowed = |i: usize, j: usize| {
        j == i + 1 || (i == 0 && j == m - 1) || !share_face(polygon[i], polygon[j])
    };
    // apex[i][j]: the apex of the triangle on side (i, j) in a triangulation of the chain
    // i..=j, or None when the chain cannot be triangulated.
    let mut apex = vec![vec![None; m]; m];
    for len in 2..m {
        for i in 0..m - len {
            let j = i + len;
            apex[i][j] = (i + 1..j).rev().find(|&k| {
                (k == i + 1 || (allowed(i, k) && apex[i][k].is_some()))
                    && (k + 1 == j || (allowed(k, j) && apex[k][j].is_some()))
            });
        }
    }
    let mut out = Vec::with_capacity(m - 2);
    let mut stack = vec![(0, m - 1)];
    while let Some((i, j)) = stack.pop() {
        if j < i + 2 {
            continue;
        }
        let k = apex[i][j]?;
        out.push([polygon[i], polygon[k], polygon[j]]);
        stack.push((i, k));
        stack.push((k, j));
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_configuration_gives_closed_loops_through_each_crossing_once() {
        for case in 0..256 {
            let crossing: Vec<u8> = (0..12u8)
                .filter(|&e| {
                    let (a, b, _) = EDGES[e as usize];
                    (case >> a & 1) != (case >> b & 1)
                })
                .collect();
            for decisions in 0..64 {
                let polys = cell_polygons(case, decisions);
                let mut used: Vec<u8> = polys.iter().flatten().copied().collect();
                used.sort_unstable();
                assert_eq!(used, crossing, "case {case:#x}, decisions {decisions:#x}");
                assert!(polys.iter().all(|p| p.len() >= 3));
            }
        }
    }

    #[test]
    fn few_polygons_need_a_centre_vertex() {
        let t = table();
        let centred = (0..256 * 64).filter(|&c| !t.centres(c).is_empty()).count();
        println!(
            "{centred} of {} configurations use a centre vertex",
            256 * 64
        );
        assert!(centred > 0 && centred < 256 * 64 / 4);
    }

    #[test]
    fn one_inside_corner_is_wound_outward() {
        // Corner 0 inside: crossings on edges 0 (x), 4 (y), 8 (z); outward normal (1, 1, 1)
        // is given by the order x → y → z.
        assert_eq!(cell_polygons(1, 0), vec![vec![0, 4, 8]]);
    }

    #[test]
    fn edges_and_faces_are_consistent() {
        for (e, &(a, b, axis)) in EDGES.iter().enumerate() {
            assert_eq!(a ^ b, 1 << axis);
            assert_eq!(edge_between(a, b), e);
        }
        for face in FACES {
            for k in 0..4 {
                assert_eq!((face[k] ^ face[(k + 1) % 4]).count_ones(), 1);
            }
        }
    }
}
