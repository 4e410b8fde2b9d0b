//! Trimming a mesh to the scan it was fitted to.
//!
//! A field is defined everywhere in its box, so the zero set of a field fitted to a one-sided
//! scan — a face, a façade, a terrain, the front of a statue — goes on past the scan's edge
//! until it meets the box or closes on itself, and a closed scan's holes are capped. Both are
//! guesses the data did not make. Trimming keeps the part of the mesh the scan supports.
//!
//! Each point `p` has a local spacing `s(p)`, the mean distance to its `k = 8` nearest other
//! points (clamped to `[¼, 4]` times the median spacing, so that duplicates and stray points
//! do not set the scale — 4 is beyond what the outlier rule keeps by default, 3), and reaches
//! `ρ·s(p)`. The *coverage distance* of a place `x` is
//!
//! ```text
//! c(x) = min ‖x − p‖ / (ρ·s(p))   over the k points p nearest to x,
//! ```
//!
//! below 1 inside the union of the balls the points reach. Taken at the mesh's vertices — with
//! each reach lengthened by half the mesh's mean edge `ē`, as a mesh of long edges lies farther
//! from the points where it cuts across curved surface —, it is smoothed over about half a spacing by a few passes of neighbour averaging (the union of
//! balls has a scalloped edge, one scallop per point). [`trim`] keeps the part of the mesh
//! where `c < 1`: triangles whose three corners have `c < 1` stay, triangles whose corners all
//! have `c ≥ 1` go, and the others are cut along the line where `c`, interpolated linearly
//! along their edges, is 1. A cut edge gets one new vertex, shared by the two triangles beside
//! it, so the trimmed mesh stays welded: a closed edge-manifold mesh becomes an edge-manifold
//! mesh whose boundary is the cut. Every kept corner keeps a piece of each of its triangles, so
//! no vertex is left joining two pieces (no bow-tie).
//!
//! The default reach `ρ = 1.5` ([`DEFAULT_REACH`]) is twice the reach at which holes first
//! open where there are points: on the meshes of closed scans (the bunny, its 2,000-point
//! sample, the kitten, 1,000 and 3,000 random points on a sphere; RBF fields meshed at coarse,
//! general and fine voxels), reach 1 cuts none — the bunny's cuts all lie within 5.2 mm of its
//! base (of its 154), where its five holes are —, while 0.75 cuts 8 in the 1,000 random points on fine
//! voxels (the largest empty disc of a random sample is wider than its mean spacing). Without
//! the half-edge slack, coarse voxels lost 3% of the bunny's area even at reach 2. On one-sided
//! scans the cut then runs a few point spacings beyond the scan's last points
//! (`benches/peers/trim_peers.py` measures how far, against Open3D's density trimming); a
//! smaller `ρ` follows the edge more closely.
//!
//! Like screened Poisson's density trimming (Kazhdan–Hoppe 2013, the `SurfaceTrimmer` of
//! PoissonRecon), the cut follows where the samples are; unlike it, it needs no octree and
//! works on any mesh, whatever field or program made it.
//!
//! ```
//! use zeroset_mesh::TriMesh;
//! use zeroset_mesh::trim::{ScanSupport, trim};
//!
//! // The unit square as a 20 × 20 grid of cells, two triangles each; a scan of its left
//! // quarter, a point every 0.025.
//! let n = 20;
//! let at = |i: usize| i as f64 / n as f64;
//! let v: Vec<[f64; 3]> = (0..=n).flat_map(|i| (0..=n).map(move |j| [at(i), at(j), 0.0])).collect();
//! let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
//! let mut t = Vec::new();
//! for (i, j) in (0..n).flat_map(|i| (0..n).map(move |j| (i, j))) {
//!     t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
//!     t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
//! }
//! let mesh = TriMesh::new(v, t)?;
//! let scan: Vec<[f64; 3]> = (0..=10)
//!     .flat_map(|i| (0..=40).map(move |j| [0.025 * i as f64, 0.025 * j as f64, 0.0]))
//!     .collect();
//! let trimmed = trim(&mesh, &ScanSupport::new(&scan, 1.5)?);
//! // Cut a little beyond x = 0.25: the reach, 1.5 local spacings, and half an edge.
//! let area = zeroset_mesh::check(&trimmed.mesh).area;
//! assert!(area > 0.3 && area < 0.37, "{area}");
//! assert_eq!(zeroset_mesh::boundary_loops(&trimmed.mesh), 1);
//! # Ok::<(), zeroset_mesh::MeshError>(())
//! ```

use std::collections::HashMap;
use std::num::NonZero;

use kiddo::SquaredEuclidean;
use kiddo::kd_tree::KdTree;
use kiddo::leaf_strategies::FlatVec;
use kiddo::stem_strategies::Eytzinger;
use rayon::prelude::*;
use zeroset_field_core::geometry::{distance, norm};
use zeroset_field_core::{Aabb, Point};

use crate::checks::components;
use crate::trimesh::area_vector;
use crate::{MeshError, Result, TriMesh};

/// Neighbours a point's spacing is measured over, and points a coverage distance is taken over.
pub const TRIM_NEIGHBOURS: usize = 8;

/// The default reach `ρ`, in local spacings; see the [module docs](self).
pub const DEFAULT_REACH: f64 = 1.5;

/// The local spacings are clamped to `[SPACING_CLAMP.0, SPACING_CLAMP.1]` times their median.
const SPACING_CLAMP: (f64, f64) = (0.25, 4.0);

/// The k-d tree over 3-D points (`u32` indices) the mesh checks and the trim search.
pub(crate) type Tree = KdTree<f64, u32, Eytzinger, FlatVec<f64, u32, 3, 32>, 3, 32>;

/// Where a scan reaches: its points, each with its reach `ρ·s(p)`; see the
/// [module docs](self).
pub struct ScanSupport {
    points: Vec<Point<3>>,
    reach: Vec<f64>,
    tree: Tree,
    median_spacing: f64,
}

impl std::fmt::Debug for ScanSupport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScanSupport")
            .field("points", &self.points.len())
            .field("median_spacing", &self.median_spacing)
            .finish_non_exhaustive()
    }
}

impl ScanSupport {
    /// The support of the finite points among `points` with reach `reach` (`ρ`, in local
    /// spacings). The spacings are measured once here (`O(n log n)`, in parallel, the same
    /// result on any number of threads).
    ///
    /// # Errors
    /// [`MeshError::Trim`] if `reach` is not finite and positive, if fewer than
    /// [`TRIM_NEIGHBOURS`]` + 1` points are finite, or if the median spacing is 0 (most points
    /// repeated: there is no scale to trim at).
    pub fn new(points: &[Point<3>], reach: f64) -> Result<Self> {
        if !(reach.is_finite() && reach > 0.0) {
            return Err(MeshError::Trim {
                detail: format!("the reach must be finite and positive, got {reach}"),
            });
        }
        let points: Vec<Point<3>> = points
            .iter()
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .copied()
            .collect();
        let n = points.len();
        if n <= TRIM_NEIGHBOURS {
            return Err(MeshError::Trim {
                detail: format!(
                    "{n} finite point(s): a point's spacing is measured over its \
                     {TRIM_NEIGHBOURS} nearest, so at least {} are needed",
                    TRIM_NEIGHBOURS + 1
                ),
            });
        }
        if n > u32::MAX as usize {
            return Err(MeshError::Trim {
                detail: format!("{n} points: at most {} can be indexed", u32::MAX),
            });
        }
        let tree = Tree::new_from_slice(&points).map_err(|e| MeshError::Trim {
            detail: format!("indexing the points: {e}"),
        })?;
        let k = NonZero::new(TRIM_NEIGHBOURS + 1).unwrap_or(NonZero::<usize>::MIN);
        let mut spacing: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| {
                let found = tree
                    .query(&points[i])
                    .nearest_n::<SquaredEuclidean<f64>>(k)
                    .execute();
                let sum: f64 = found
                    .iter()
                    .filter(|f| f.item as usize != i)
                    .take(TRIM_NEIGHBOURS)
                    .map(|f| f.distance.sqrt())
                    .sum();
                sum / TRIM_NEIGHBOURS as f64
            })
            .collect();
        let mut sorted = spacing.clone();
        sorted.sort_by(f64::total_cmp);
        let median = 0.5 * (sorted[(n - 1) / 2] + sorted[n / 2]);
        if !(median > 0.0 && median.is_finite()) {
            return Err(MeshError::Trim {
                detail: format!(
                    "the points' median spacing is {median}: most of the {n} points are \
                     repeated, so there is no scale to trim at"
                ),
            });
        }
        let (lo, hi) = (SPACING_CLAMP.0 * median, SPACING_CLAMP.1 * median);
        for s in &mut spacing {
            *s = reach * s.clamp(lo, hi);
        }
        Ok(Self {
            points,
            reach: spacing,
            tree,
            median_spacing: median,
        })
    }

    /// The median local spacing `s` (mean distance to the [`TRIM_NEIGHBOURS`] nearest), in the
    /// points' units.
    pub fn median_spacing(&self) -> f64 {
        self.median_spacing
    }

    /// The number of points the support was built from (the finite ones).
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Never true: a support holds at least [`TRIM_NEIGHBOURS`]` + 1` points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The coverage distance `c(x)` of the [module docs](self): below 1 where the scan reaches.
    pub fn coverage(&self, x: &Point<3>) -> f64 {
        self.coverage_with_slack(x, 0.0)
    }

    /// [`coverage`](Self::coverage) with each point's reach lengthened by `slack` (in the
    /// points' units): `min ‖x − p‖ / (ρ·s(p) + slack)`.
    pub fn coverage_with_slack(&self, x: &Point<3>, slack: f64) -> f64 {
        let k = NonZero::new(TRIM_NEIGHBOURS).unwrap_or(NonZero::<usize>::MIN);
        self.tree
            .query(x)
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute()
            .iter()
            .map(|f| {
                let i = f.item as usize;
                distance(x, &self.points[i]) / (self.reach[i] + slack)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// [`coverage_with_slack`](Self::coverage_with_slack) at each of `xs`, in parallel (the
    /// same values on any number of threads).
    pub fn coverages(&self, xs: &[Point<3>], slack: f64) -> Vec<f64> {
        xs.par_iter()
            .map(|x| self.coverage_with_slack(x, slack))
            .collect()
    }
}

/// What [`trim`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct Trimmed {
    /// The trimmed mesh: the kept triangles, the pieces of the cut ones, and only the vertices
    /// they use, in the order the triangles first use them (each cut edge's new vertex where
    /// it is first met). A mesh wholly within reach comes back as it was.
    pub mesh: TriMesh,
    /// Triangles whose corners were all beyond the scan's reach, dropped whole.
    pub dropped_triangles: usize,
    /// Triangles cut along the reach.
    pub cut_triangles: usize,
    /// Edges cut (each gave one new vertex).
    pub cut_edges: usize,
}

/// `mesh` trimmed to where `support` reaches; see the [module docs](self). Normals, if the mesh
/// has them, are interpolated to the new vertices (and made unit again). Deterministic: the same
/// mesh and support give the same output, with any number of threads.
pub fn trim(mesh: &TriMesh, support: &ScanSupport) -> Trimmed {
    trim_by(mesh, &coverage(mesh, support, 0.0))
}

/// One connected piece of a mesh beyond a scan's reach: where the surface is the field's
/// guess (a hole in the scan it closed, a side it never saw).
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// Its area.
    pub area: f64,
    /// Its bounding box.
    pub bounds: Aabb<3>,
}

/// [`trim`], and the pieces it cuts away: the connected regions of `mesh` beyond `support`'s
/// reach, cut along the same line, largest area first (ties in the order of their first
/// triangle). Their areas add up to the mesh's less the trimmed one's. `offset` lengthens every
/// point's reach: for a mesh that lies that far from the points by construction (a level set
/// other than the one fitted to them), so that the offset itself does not read as beyond
/// reach; 0 cuts as [`trim`] does.
///
/// ```
/// use zeroset_mesh::TriMesh;
/// use zeroset_mesh::trim::{DEFAULT_REACH, ScanSupport, split};
///
/// // Two unit squares 10 apart (a row of triangles each), a scan of the first only.
/// let mut v = Vec::new();
/// for x in [0.0, 10.0] {
///     v.extend([[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x + 1.0, 1.0, 0.0], [x, 1.0, 0.0]]);
/// }
/// let mesh = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])?;
/// let scan: Vec<[f64; 3]> = (0..=20)
///     .flat_map(|i| (0..=20).map(move |j| [i as f64 / 20.0, j as f64 / 20.0, 0.0]))
///     .collect();
/// let (kept, beyond) = split(&mesh, &ScanSupport::new(&scan, DEFAULT_REACH)?, 0.0);
/// assert_eq!(kept.mesh.num_triangles(), 2);
/// assert_eq!(beyond.len(), 1);
/// assert!((beyond[0].area - 1.0).abs() < 1e-12);
/// assert_eq!(beyond[0].bounds.min(), [10.0, 0.0, 0.0]);
/// # Ok::<(), zeroset_mesh::MeshError>(())
/// ```
pub fn split(mesh: &TriMesh, support: &ScanSupport, offset: f64) -> (Trimmed, Vec<Region>) {
    let coverage = coverage(mesh, support, offset.max(0.0));
    let kept = trim_by(mesh, &coverage);
    // The complement cut along the same line: 2 − c crosses 1 where c does.
    let flipped: Vec<f64> = coverage.iter().map(|c| 2.0 - c).collect();
    let beyond = trim_by(mesh, &flipped).mesh;
    let (labels, count) = components(&beyond);
    // Per region: area, and the box's corners.
    let mut sums = vec![(0.0, [f64::INFINITY; 3], [f64::NEG_INFINITY; 3]); count];
    for (t, &label) in labels.iter().enumerate() {
        let corners = beyond.corners(t);
        let (area, min, max) = &mut sums[label as usize];
        *area += 0.5 * norm(&area_vector(&corners));
        for c in &corners {
            for a in 0..3 {
                min[a] = min[a].min(c[a]);
                max[a] = max[a].max(c[a]);
            }
        }
    }
    let regions = sums.into_iter().filter_map(|(area, min, max)| {
        Aabb::new(min, max)
            .ok()
            .map(|bounds| Region { area, bounds })
    });
    let mut regions: Vec<Region> = regions.collect();
    regions.sort_by(|a, b| b.area.total_cmp(&a.area));
    (kept, regions)
}

/// The coverage distance at each vertex of `mesh` ([`ScanSupport::coverages`] with half the
/// mean edge plus `offset` as slack), smoothed over about half a median spacing: below 1
/// within reach.
fn coverage(mesh: &TriMesh, support: &ScanSupport, offset: f64) -> Vec<f64> {
    let edge = mean_edge(mesh);
    let coverage = support.coverages(mesh.vertices(), 0.5 * edge + offset);
    let passes = smoothing_passes(edge, support.median_spacing());
    smoothed(mesh, coverage, passes)
}

/// The mean length of the triangles' sides (0 without triangles).
fn mean_edge(mesh: &TriMesh) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for t in 0..mesh.num_triangles() {
        let c = mesh.corners(t);
        for k in 0..3 {
            sum += distance(&c[k], &c[(k + 1) % 3]);
            count += 1;
        }
    }
    sum / count.max(1) as f64
}

/// The passes of neighbour averaging that smooth the coverage distance over about half a
/// median spacing `s`: one pass of averaging over a vertex and its edge neighbours spreads a
/// value by about `0.65·ē` (standard deviation; `ē` the mean edge length, a vertex having six
/// neighbours on average), `n` passes by `0.65·ē·√n`, so `n = 0.6·(s/ē)²`, at most 16.
fn smoothing_passes(edge: f64, spacing: f64) -> usize {
    if !(edge > 0.0 && spacing.is_finite()) {
        return 0;
    }
    (0.6 * (spacing / edge).powi(2)).round().min(16.0) as usize
}

/// `values` (one per vertex) after `passes` of replacing each by the mean of itself and its
/// edge neighbours (an edge counted once per triangle that has it: the same weights on any
/// number of threads, as the sums run in triangle order).
fn smoothed(mesh: &TriMesh, mut values: Vec<f64>, passes: usize) -> Vec<f64> {
    let n = mesh.num_vertices();
    for _ in 0..passes {
        let mut sum = values.clone();
        let mut weight = vec![1.0f64; n];
        for t in mesh.triangles() {
            for k in 0..3 {
                let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
                sum[a] += values[b];
                sum[b] += values[a];
                weight[a] += 1.0;
                weight[b] += 1.0;
            }
        }
        for ((v, s), w) in values.iter_mut().zip(&sum).zip(&weight) {
            *v = s / w;
        }
    }
    values
}

/// The cut of [`trim`], by the coverage distance at each vertex.
fn trim_by(mesh: &TriMesh, coverage: &[f64]) -> Trimmed {
    let inside = |v: u32| coverage[v as usize] < 1.0;
    if mesh.triangles().iter().flatten().all(|&v| inside(v)) {
        return Trimmed {
            mesh: mesh.clone(),
            dropped_triangles: 0,
            cut_triangles: 0,
            cut_edges: 0,
        };
    }
    let normals = mesh.normals();
    let mut out = Builder {
        source: mesh,
        coverage,
        index: vec![u32::MAX; mesh.num_vertices()],
        cuts: HashMap::new(),
        vertices: Vec::new(),
        normals: Vec::new(),
        with_normals: !normals.is_empty(),
    };
    let mut triangles = Vec::with_capacity(mesh.num_triangles());
    let (mut dropped, mut cut) = (0, 0);
    for tri in mesh.triangles() {
        let count = tri.iter().filter(|&&v| inside(v)).count();
        match count {
            3 => triangles.push(tri.map(|v| out.kept(v))),
            0 => dropped += 1,
            _ => {
                cut += 1;
                // Rotate (keeping the winding) so that the odd corner comes first: the one
                // inside (count 1) or the one outside (count 2).
                let odd = (0..3)
                    .find(|&k| inside(tri[k]) == (count == 1))
                    .unwrap_or(0);
                let [a, b, c] = [tri[odd], tri[(odd + 1) % 3], tri[(odd + 2) % 3]];
                if count == 1 {
                    // a inside: the corner triangle a, ab, ca.
                    let (a_, ab, ca) = (out.kept(a), out.cut(a, b), out.cut(a, c));
                    triangles.push([a_, ab, ca]);
                } else {
                    // a outside: the quadrilateral b, c, ca, ab, split along its shorter
                    // diagonal.
                    let (b_, c_, ca, ab) = (out.kept(b), out.kept(c), out.cut(c, a), out.cut(b, a));
                    let d1 = distance(&out.vertices[b_ as usize], &out.vertices[ca as usize]);
                    let d2 = distance(&out.vertices[c_ as usize], &out.vertices[ab as usize]);
                    if d1 <= d2 {
                        triangles.push([b_, c_, ca]);
                        triangles.push([b_, ca, ab]);
                    } else {
                        triangles.push([b_, c_, ab]);
                        triangles.push([c_, ca, ab]);
                    }
                }
            }
        }
    }
    let cut_edges = out.cuts.len();
    let Builder {
        vertices,
        normals,
        with_normals,
        ..
    } = out;
    // Every index was made by the builder and every position interpolated between finite ones,
    // so the checks of `TriMesh::new` hold; `Default` only stands in for the unreachable.
    let mut trimmed = TriMesh::new(vertices, triangles).unwrap_or_default();
    if with_normals {
        trimmed = trimmed.clone().with_normals(normals).unwrap_or(trimmed);
    }
    Trimmed {
        mesh: trimmed,
        dropped_triangles: dropped,
        cut_triangles: cut,
        cut_edges,
    }
}

/// The trimmed mesh's vertices as they are made.
struct Builder<'a> {
    source: &'a TriMesh,
    coverage: &'a [f64],
    /// The new index of each source vertex kept (`u32::MAX` until it is).
    index: Vec<u32>,
    /// The new vertex of each cut edge, by its (smaller, larger) source vertices.
    cuts: HashMap<(u32, u32), u32>,
    vertices: Vec<Point<3>>,
    normals: Vec<Point<3>>,
    with_normals: bool,
}

impl Builder<'_> {
    /// The new index of the kept source vertex `v`.
    fn kept(&mut self, v: u32) -> u32 {
        let slot = &mut self.index[v as usize];
        if *slot == u32::MAX {
            *slot = self.vertices.len() as u32;
            self.vertices.push(self.source.vertices()[v as usize]);
            if self.with_normals {
                self.normals.push(self.source.normals()[v as usize]);
            }
        }
        *slot
    }

    /// The new vertex where the edge from `inner` (inside) to `outer` (outside) crosses the
    /// reach: `c` interpolated linearly along the edge is 1 there.
    fn cut(&mut self, inner: u32, outer: u32) -> u32 {
        let key = (inner.min(outer), inner.max(outer));
        if let Some(&i) = self.cuts.get(&key) {
            return i;
        }
        let (ci, co) = (self.coverage[inner as usize], self.coverage[outer as usize]);
        // ci < 1 ≤ co, so t ∈ (0, 1]; an infinite co (no point at all nearby) puts the cut
        // at the inner end's side of the edge, never on the inner vertex itself.
        let t = if co.is_finite() {
            ((1.0 - ci) / (co - ci)).clamp(1e-6, 1.0)
        } else {
            1e-6
        };
        let lerp = |a: &Point<3>, b: &Point<3>| -> Point<3> {
            std::array::from_fn(|k| a[k] + t * (b[k] - a[k]))
        };
        let (vi, vo) = (
            self.source.vertices()[inner as usize],
            self.source.vertices()[outer as usize],
        );
        let i = self.vertices.len() as u32;
        self.vertices.push(lerp(&vi, &vo));
        if self.with_normals {
            let (ni, no) = (
                self.source.normals()[inner as usize],
                self.source.normals()[outer as usize],
            );
            let n = lerp(&ni, &no);
            let length = norm(&n);
            self.normals.push(if length > 0.0 && length.is_finite() {
                n.map(|x| x / length)
            } else {
                ni
            });
        }
        self.cuts.insert(key, i);
        i
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{boundary_loops, check};

    /// A triangulated `n × n` grid over `[0, 1]²` in the plane z = 0, wound upward.
    fn square(n: usize) -> TriMesh {
        let mut v = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                v.push([i as f64 / n as f64, j as f64 / n as f64, 0.0]);
            }
        }
        let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
        let mut t = Vec::new();
        for i in 0..n {
            for j in 0..n {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriMesh::new(v, t).unwrap()
    }

    #[test]
    fn a_disc_of_points_cuts_a_disc() {
        // Points every 0.01 inside the disc of radius 0.3 about (0.5, 0.5): the trimmed square
        // is a disc (one boundary loop, Euler characteristic 1), a little wider than 0.3.
        let mut scan = Vec::new();
        for i in 0..=100 {
            for j in 0..=100 {
                let p = [i as f64 / 100.0, j as f64 / 100.0, 0.0];
                if (p[0] - 0.5).hypot(p[1] - 0.5) <= 0.3 {
                    scan.push(p);
                }
            }
        }
        let support = ScanSupport::new(&scan, DEFAULT_REACH).unwrap();
        let trimmed = trim(&square(60), &support);
        let report = check(&trimmed.mesh);
        assert_eq!(report.components, 1);
        assert_eq!(report.euler_characteristic, 1);
        assert_eq!(report.non_manifold_edges, 0);
        assert_eq!(report.degenerate_triangles, 0);
        assert_eq!(boundary_loops(&trimmed.mesh), 1);
        // The cut lies about ρ·s beyond the last points; s is the mean distance to the 8
        // nearest on a grid of step 0.01, (4·0.01 + 4·0.01414) / 8 = 0.0121.
        let s = support.median_spacing();
        assert!((s - 0.01207).abs() < 1e-4, "{s}");
        // The reach is lengthened by half the mean edge, (2 + √2)/3 / 60 / 2.
        let slack = 0.5 * mean_edge(&square(60));
        assert!((slack - 0.009_48).abs() < 1e-4, "{slack}");
        let radius = (report.area / std::f64::consts::PI).sqrt();
        let expected = 0.3 + 2.0 * s + slack;
        assert!(
            (radius - expected).abs() < 0.01,
            "radius {radius}, expected about {expected}"
        );
        // Every vertex within reach, up to the interpolation along edges of 1/60.
        for v in trimmed.mesh.vertices() {
            assert!(support.coverage_with_slack(v, slack) < 1.0 + 1.0 / 60.0 / (2.0 * s));
        }
    }

    #[test]
    fn split_returns_each_hole_the_scan_left_as_a_region_largest_first() {
        // A scan of the unit square with two holes: radius 0.15 about (0.3, 0.3), 0.1 about
        // (0.7, 0.7). The mesh beyond reach is two discs, a little smaller than the holes.
        let holes = [([0.3, 0.3], 0.15), ([0.7, 0.7], 0.1)];
        let mut scan = Vec::new();
        for i in 0..=100 {
            for j in 0..=100 {
                let p = [i as f64 / 100.0, j as f64 / 100.0, 0.0];
                if holes
                    .iter()
                    .all(|(c, r)| (p[0] - c[0]).hypot(p[1] - c[1]) > *r)
                {
                    scan.push(p);
                }
            }
        }
        let support = ScanSupport::new(&scan, DEFAULT_REACH).unwrap();
        let mesh = square(80);
        let (kept, regions) = split(&mesh, &support, 0.0);
        assert_eq!(kept, trim(&mesh, &support));
        assert_eq!(regions.len(), 2, "{regions:?}");
        assert!(regions[0].area > regions[1].area);
        let kept_area = check(&kept.mesh).area;
        let total: f64 = regions.iter().map(|r| r.area).sum();
        assert!(
            (kept_area + total - 1.0).abs() < 1e-9,
            "{kept_area} + {total}"
        );
        for (region, (centre, radius)) in regions.iter().zip(holes) {
            let c = region.bounds.center();
            assert!(
                (c[0] - centre[0]).hypot(c[1] - centre[1]) < 0.02,
                "{region:?}"
            );
            let width = region.bounds.extent()[0];
            assert!(width > 0.0 && width < 2.0 * radius, "{region:?}");
        }
        // Nothing beyond reach: no regions.
        let all: Vec<Point<3>> = mesh.vertices().to_vec();
        let (_, none) = split(&mesh, &ScanSupport::new(&all, DEFAULT_REACH).unwrap(), 0.0);
        assert!(none.is_empty());
    }

    #[test]
    fn a_fully_covered_mesh_is_unchanged() {
        let mesh = square(10);
        let scan: Vec<Point<3>> = mesh.vertices().to_vec();
        let trimmed = trim(&mesh, &ScanSupport::new(&scan, 1.0).unwrap());
        assert_eq!(trimmed.mesh, mesh);
        assert_eq!(
            (
                trimmed.dropped_triangles,
                trimmed.cut_triangles,
                trimmed.cut_edges
            ),
            (0, 0, 0)
        );
    }

    #[test]
    fn a_mesh_far_from_the_scan_is_removed() {
        let scan: Vec<Point<3>> = (0..20).map(|i| [10.0 + 0.1 * i as f64, 0.0, 0.0]).collect();
        let mesh = square(4);
        let trimmed = trim(&mesh, &ScanSupport::new(&scan, DEFAULT_REACH).unwrap());
        assert!(trimmed.mesh.is_empty());
        assert_eq!(trimmed.mesh.num_vertices(), 0);
        assert_eq!(trimmed.dropped_triangles, mesh.num_triangles());
    }

    #[test]
    fn cut_edges_are_shared_and_winding_kept() {
        // A line of points along x = 0.5: the kept strip is welded (its edges have at most two
        // triangles, traversed opposite ways) and wound like the source (+z).
        let scan: Vec<Point<3>> = (0..=200).map(|j| [0.5, j as f64 / 200.0, 0.0]).collect();
        let mesh = square(16)
            .with_normals(vec![[0.0, 0.0, 1.0]; 17 * 17])
            .unwrap();
        let trimmed = trim(&mesh, &ScanSupport::new(&scan, 20.0).unwrap());
        let report = check(&trimmed.mesh);
        assert_eq!(report.inconsistent_edges, 0);
        assert_eq!(report.non_manifold_edges, 0);
        assert_eq!(report.components, 1);
        assert!(trimmed.cut_edges > 0);
        assert_eq!(trimmed.mesh.normals().len(), trimmed.mesh.num_vertices());
        for t in 0..trimmed.mesh.num_triangles() {
            let [a, b, c] = trimmed.mesh.corners(t);
            let z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(z > 0.0, "triangle {t} turned over");
        }
        for n in trimmed.mesh.normals() {
            assert!((norm(n) - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_supports_are_errors() {
        let few: Vec<Point<3>> = (0..8).map(|i| [i as f64, 0.0, 0.0]).collect();
        assert!(matches!(
            ScanSupport::new(&few, 2.0),
            Err(MeshError::Trim { .. })
        ));
        let many: Vec<Point<3>> = (0..20).map(|i| [i as f64, 0.0, 0.0]).collect();
        for reach in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(ScanSupport::new(&many, reach).is_err(), "{reach}");
        }
        let repeated = vec![[1.0, 2.0, 3.0]; 50];
        let e = ScanSupport::new(&repeated, 2.0).unwrap_err().to_string();
        assert!(e.contains("repeated"), "{e}");
        // Non-finite points are left out, not an error while enough finite ones remain.
        let mut mixed = many.clone();
        mixed.push([f64::NAN, 0.0, 0.0]);
        assert_eq!(ScanSupport::new(&mixed, 2.0).unwrap().len(), 20);
    }
}
