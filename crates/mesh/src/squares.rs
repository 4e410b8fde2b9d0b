//! Marching squares: the level curve `{x : f(x) = c}` of a field sampled on a 2-D grid, as
//! polylines.
//!
//! ## What is computed
//!
//! The grid holds samples `v_ij = f(x_i, y_j)`. A sample is **inside** when `v < c` and
//! **outside** when `v ≥ c`. Every cell edge whose two samples lie on different sides carries one
//! crossing, placed by linear interpolation,
//!
//! ```text
//! t = (c − v_a) / (v_b − v_a) ∈ [0, 1],        p = p_a + t (p_b − p_a),
//! ```
//!
//! and inside every cell straight segments join its crossings. The segments separate the
//! inside samples from the outside ones, so the polylines approximate the boundary of
//! `{f < c}`: for a `C²` field with `∇f ≠ 0` on the curve, every vertex lies within `O(h²)` of
//! the true curve (`h` the grid spacing) and the length converges as `O(h²)`.
//!
//! ## The 16 cases and the ambiguity
//!
//! The sides of a cell's four corners form one of `2⁴ = 16` cases. Two have no crossing (all
//! inside, all outside); twelve have two crossings, joined by one segment. The two **saddle**
//! cases — diagonal corners on the same side, the other diagonal on the other — have four
//! crossings, which can be paired in two ways: either the inside corners are joined through the
//! cell or the outside ones are. Neither choice can make segments cross in 2-D, but they give
//! different topologies.
//!
//! zeroset resolves them with the **asymptotic decider** (Nielson & Hamann, *The asymptotic
//! decider: resolving the ambiguity in marching cubes*, IEEE Visualization 1991). On a cell with
//! corners `v₀₀, v₁₀, v₁₁, v₀₁` (counter-clockwise from the lower left) the bilinear interpolant
//! has a saddle of value
//!
//! ```text
//! B* = (v₀₀ v₁₁ − v₁₀ v₀₁) / (v₀₀ + v₁₁ − v₁₀ − v₀₁),
//! ```
//!
//! and the inside corners are joined through the cell exactly when `B* < c`. With `w = v − c`
//! this reads `w_a w_b > w_c w_d`, where `a, b` are the inside diagonal and `c, d` the outside
//! one, which is how it is evaluated (after scaling by the largest `|w|`, so the products
//! neither overflow nor divide by zero). A saddle exactly on the level (`B* = c`) counts as
//! outside, like a sample on the level. The polylines therefore have the topology of the
//! level set of the bilinear interpolant, which the cell-centre mean (a cheaper rule) does not
//! guarantee. No lookup table is used: the segments of a cell follow from its corner sides
//! (walking the cell counter-clockwise, each inside→outside crossing is joined to an
//! outside→inside one).
//!
//! ## Samples exactly on the level
//!
//! A sample equal to `c` counts as **outside** (above), so each edge has at most one crossing and
//! the cases stay the sixteen above. A crossing on an edge whose end lies on the level is that
//! sample itself, and the crossings of all edges meeting at such a sample are one vertex: no
//! zero-length segment and no repeated consecutive vertex is produced. Parts of the boundary of
//! zero width are dropped: an isolated sample on the level with every neighbour inside (its loop
//! collapses to a point), and a row of samples on the level with the inside on both sides (its
//! two sides are the same segments run both ways, which cancel). Two curves may still touch at a
//! sample on the level; there a polyline turns as far left as it can, which keeps inside regions
//! apart, consistent with the sample counting as outside. Finally, crossings that rounding puts
//! on the same point are merged, and a loop left with fewer than three distinct vertices (or an
//! open piece with fewer than two) is dropped.
//!
//! ## Output
//!
//! - **Orientation**: every polyline has the inside (`f < c`) on its **left**, so a loop around
//!   an inside region runs counter-clockwise (x right, y up) and a loop around a hole clockwise.
//!   With zeroset's negative-inside convention, `+∇f` points to the right of the direction of
//!   travel.
//! - **Closed loops** have `closed == true`, at least three vertices, each stored once (the first
//!   is not repeated at the end). **Open polylines** have at least two vertices and both ends on
//!   the border of the sampled region: the box for a vertex-centred grid, half a cell inside it
//!   for a cell-centred one.
//! - No two consecutive vertices are equal and no two segments cross (they may touch at a sample
//!   on the level).
//! - **Deterministic**: open polylines come first, then loops, each group ordered by the vertex
//!   it starts from; the output does not depend on the number of threads.
//!
//! Not guaranteed: features smaller than a cell (a small loop with every corner of its cell on
//! one side) are missed, and the topology is that of the bilinear interpolant of the samples,
//! not of `f` itself.
//!
//! ## Layout
//!
//! Samples are in the grid's linear order, last axis fastest: `values[i·n_y + j] = f(x_i, y_j)`
//! ([`Grid::linear_index`]`([i, j])`), `i` along x and `j` along y.
//!
//! ```
//! use zeroset_field_core::{Aabb, Grid};
//! use zeroset_mesh::squares::marching_squares;
//!
//! // f = x + y on the 2 × 2 grid over [0, 1]²: samples (0,0), (0,1), (1,0), (1,1).
//! let grid = Grid::vertex_centered(Aabb::new([0.0, 0.0], [1.0, 1.0])?, [2, 2])?;
//! let contour = marching_squares(&grid, &[0.0, 1.0, 1.0, 2.0], 0.5)?;
//! assert_eq!(contour.lines.len(), 1);
//! // Inside (f < 0.5) is the lower-left corner, on the left of the segment.
//! assert_eq!(contour.lines[0].points, vec![[0.5, 0.0], [0.0, 0.5]]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use rayon::prelude::*;
use zeroset_field_core::geometry::{Point2, distance};
use zeroset_field_core::{Centering, Grid, ScalarField};

use crate::error::Result;
use crate::samples;

/// What the sample count check calls the samples.
const SAMPLES: &str = "marching-squares samples (one per grid point)";

/// A piecewise-linear curve: vertices joined in order, and the last joined back to the first
/// when `closed`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Polyline {
    /// The vertices. A closed polyline stores each vertex once: the first is not repeated at
    /// the end.
    pub points: Vec<Point2>,
    /// Whether the last vertex is joined back to the first.
    pub closed: bool,
}

impl Polyline {
    /// The number of segments: `points.len()` for a closed polyline (of at least two points),
    /// `points.len() − 1` for an open one.
    pub fn num_segments(&self) -> usize {
        match self.points.len() {
            0 | 1 => 0,
            n if self.closed => n,
            n => n - 1,
        }
    }

    /// The segments `(start, end)` in order, including the closing one of a closed polyline.
    pub fn segments(&self) -> impl Iterator<Item = (Point2, Point2)> + '_ {
        let n = self.points.len();
        (0..self.num_segments()).map(move |k| (self.points[k], self.points[(k + 1) % n]))
    }

    /// The length: the sum of the segment lengths, the closing segment included.
    pub fn length(&self) -> f64 {
        self.segments().map(|(a, b)| distance(&a, &b)).sum()
    }

    /// The signed area enclosed (shoelace formula, the polygon closed by joining the last
    /// vertex to the first even for an open polyline): positive for a counter-clockwise loop.
    /// A loop of [`marching_squares`] is positive around an inside region, negative around a
    /// hole.
    pub fn signed_area(&self) -> f64 {
        let n = self.points.len();
        // Relative to the first vertex: the products of coordinates far from the origin (a
        // curve at UTM coordinates) would cancel their digits away.
        let Some(&o) = self.points.first() else {
            return 0.0;
        };
        let twice: f64 = (0..n)
            .map(|k| {
                let (a, b) = (self.points[k], self.points[(k + 1) % n]);
                let (a, b) = ([a[0] - o[0], a[1] - o[1]], [b[0] - o[0], b[1] - o[1]]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum();
        0.5 * twice
    }
}

/// The level curve of a field: the polylines of [`marching_squares`] and the level they trace.
#[derive(Debug, Clone, PartialEq)]
pub struct Contour {
    /// The polylines: open ones first, then closed loops (see the [module docs](self) for the
    /// order and orientation).
    pub lines: Vec<Polyline>,
    /// The level `c` of the curve `f = c`.
    pub level: f64,
}

impl Contour {
    /// The summed length of every polyline.
    pub fn total_length(&self) -> f64 {
        self.lines.iter().map(Polyline::length).sum()
    }

    /// The number of closed loops.
    pub fn num_closed(&self) -> usize {
        self.lines.iter().filter(|l| l.closed).count()
    }

    /// The number of open polylines (those leaving the grid).
    pub fn num_open(&self) -> usize {
        self.lines.len() - self.num_closed()
    }

    /// The number of vertices over all polylines.
    pub fn num_points(&self) -> usize {
        self.lines.iter().map(|l| l.points.len()).sum()
    }

    /// Whether there is no polyline (the level is not crossed on the grid). An empty contour
    /// is a valid result, not an error.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }
}

impl AsRef<[Polyline]> for Contour {
    fn as_ref(&self) -> &[Polyline] {
        &self.lines
    }
}

/// Extracts the level curve `f = level` from samples of `f` at the points of a 2-D grid.
///
/// `values[grid.linear_index([i, j])]` is the sample at `grid.point([i, j])` (last axis fastest;
/// see the [module docs](self) for the algorithm, the saddle rule, samples on the level and the
/// guarantees on the output). The grid's centering only decides where the samples sit.
///
/// # Errors
/// - [`MeshError::Field`](crate::MeshError::Field) with [`Error::GridTooSmall`](zeroset_field_core::Error::GridTooSmall) if an axis has fewer than two samples,
///   or [`Error::ShapeMismatch`](zeroset_field_core::Error::ShapeMismatch) if `values.len() != grid.len()`;
/// - [`MeshError::NonFiniteLevel`](crate::MeshError::NonFiniteLevel) if `level` is NaN or infinite;
/// - [`MeshError::NonFiniteSample`](crate::MeshError::NonFiniteSample) naming the first NaN or infinite sample.
pub fn marching_squares(grid: &Grid<2>, values: &[f64], level: f64) -> Result<Contour> {
    samples::check(grid, Some(values), level, SAMPLES)?;
    if let Some(index) = values.iter().position(|v| !v.is_finite()) {
        return Err(samples::non_finite(grid, values, index));
    }
    let marcher = Marcher::new(grid, values, level);
    let segments = marcher.segments();
    let lines = trace(&marcher, segments);
    Ok(Contour { lines, level })
}

/// Samples `field` at every point of `grid` with its batched [`ScalarField::values`] (parallel
/// in the trait's default), then runs [`marching_squares`].
///
/// ```
/// use zeroset_field_core::{Aabb, Grid, field::FnField};
/// use zeroset_mesh::squares::contour_field;
///
/// let circle = FnField::new(|p: &[f64; 2]| p[0].hypot(p[1]) - 0.5, None);
/// let grid = Grid::vertex_centered(Aabb::centered_cube(1.0)?, [101, 101])?;
/// let contour = contour_field(&circle, &grid, 0.0)?;
/// assert_eq!(contour.num_closed(), 1);
/// assert!((contour.total_length() - std::f64::consts::PI).abs() < 1e-3);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`marching_squares`]; a NaN or infinite value of the field is a
/// [`MeshError::NonFiniteSample`](crate::MeshError::NonFiniteSample) naming the grid sample. The grid and level are checked before
/// the field is sampled.
pub fn contour_field<F: ScalarField<2> + ?Sized>(
    field: &F,
    grid: &Grid<2>,
    level: f64,
) -> Result<Contour> {
    samples::check(grid, None, level, SAMPLES)?;
    let values = grid.try_sample(field)?;
    marching_squares(grid, &values, level)
}

/// A directed segment between two vertex ids (see [`Marcher`]), the inside on its left.
type Segment = (usize, usize);

/// The samples and the numbering of crossings.
///
/// A crossing is identified by a **vertex id**: the linear index of a sample when the crossing
/// is that sample (it lies on the level), otherwise `n + e` for the crossing inside edge `e`,
/// where `n` is the number of samples. Edges along x, from `[i, j]` to `[i + 1, j]`, are numbered
/// `e = i·n_y + j`; edges along y, from `[i, j]` to `[i, j + 1]`, follow them as
/// `e = (n_x − 1)·n_y + i·(n_y − 1) + j`.
struct Marcher<'a> {
    grid: &'a Grid<2>,
    values: &'a [f64],
    level: f64,
    nx: usize,
    ny: usize,
    /// Half a cell for cell-centred grids, 0 for vertex-centred ones.
    offset: f64,
}

impl<'a> Marcher<'a> {
    fn new(grid: &'a Grid<2>, values: &'a [f64], level: f64) -> Self {
        let [nx, ny] = grid.counts();
        let offset = match grid.centering() {
            Centering::Cell => 0.5,
            Centering::Vertex => 0.0,
        };
        Self {
            grid,
            values,
            level,
            nx,
            ny,
            offset,
        }
    }

    fn inside(&self, l: usize) -> bool {
        self.values[l] < self.level
    }

    fn x_edge(&self, i: usize, j: usize) -> usize {
        i * self.ny + j
    }

    fn y_edge(&self, i: usize, j: usize) -> usize {
        (self.nx - 1) * self.ny + i * (self.ny - 1) + j
    }

    /// The vertex id of the crossing on the edge from sample `lo` to sample `hi` (`lo < hi`),
    /// numbered `edge`: the sample itself when it lies on the level.
    fn crossing_id(&self, lo: usize, hi: usize, edge: usize) -> usize {
        if self.values[lo] == self.level {
            lo
        } else if self.values[hi] == self.level {
            hi
        } else {
            self.values.len() + edge
        }
    }

    /// Every segment, cell by cell (rows of cells in parallel), sorted.
    fn segments(&self) -> Vec<Segment> {
        let rows: Vec<Vec<Segment>> = (0..self.nx - 1)
            .into_par_iter()
            .map(|i| {
                let mut out = Vec::new();
                for j in 0..self.ny - 1 {
                    self.cell_segments(i, j, &mut out);
                }
                out
            })
            .collect();
        let mut segments = cancel_opposite(rows.into_iter().flatten().collect());
        segments.sort_unstable();
        segments
    }

    /// Appends the segments of cell `[i, j]` (corners `[i, j]`, `[i+1, j]`, `[i+1, j+1]`,
    /// `[i, j+1]`, counter-clockwise).
    fn cell_segments(&self, i: usize, j: usize, out: &mut Vec<Segment>) {
        let ny = self.ny;
        let corner = [
            i * ny + j,
            (i + 1) * ny + j,
            (i + 1) * ny + j + 1,
            i * ny + j + 1,
        ];
        let inside = corner.map(|l| self.inside(l));
        if inside.iter().all(|&b| b) || inside.iter().all(|&b| !b) {
            return;
        }
        // Edge k runs from corner k to corner k + 1; its crossing's vertex id, if any.
        let ids = [
            self.crossing_id(corner[0], corner[1], self.x_edge(i, j)),
            self.crossing_id(corner[1], corner[2], self.y_edge(i + 1, j)),
            self.crossing_id(corner[3], corner[2], self.x_edge(i, j + 1)),
            self.crossing_id(corner[0], corner[3], self.y_edge(i, j)),
        ];
        let exits: Vec<usize> = (0..4)
            .filter(|&k| inside[k] && !inside[(k + 1) % 4])
            .collect();
        let step = if exits.len() == 1 {
            // One segment: from the exit to the only entry, the next crossing either way.
            (1..4)
                .find(|&d| !inside[(exits[0] + d) % 4] && inside[(exits[0] + d + 1) % 4])
                .unwrap_or(1)
        } else if self.saddle_joins_inside(corner, inside) {
            1 // each exit to the next entry counter-clockwise: the inside passes the centre
        } else {
            3 // each exit to the next entry clockwise: the inside corners are cut off
        };
        for &k in &exits {
            let (from, to) = (ids[k], ids[(k + step) % 4]);
            if from != to {
                out.push((from, to));
            }
        }
    }

    /// The asymptotic decider for a saddle cell: whether the bilinear interpolant's saddle lies
    /// inside (`B* < c`), i.e. `w_a w_b > w_c w_d` for the inside diagonal `a, b`.
    fn saddle_joins_inside(&self, corner: [usize; 4], inside: [bool; 4]) -> bool {
        let v = corner.map(|l| self.values[l]);
        let mut w = v.map(|x| x - self.level);
        if w.iter().any(|x| !x.is_finite()) {
            // v − c overflowed: halve both (exact for values this large).
            w = v.map(|x| 0.5 * x - 0.5 * self.level);
        }
        let m = w.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let w = w.map(|x| x / m);
        let (in_diag, out_diag) = if inside[0] {
            (w[0] * w[2], w[1] * w[3])
        } else {
            (w[1] * w[3], w[0] * w[2])
        };
        in_diag > out_diag
    }

    /// The position of a vertex id.
    fn position(&self, id: usize) -> Point2 {
        let n = self.values.len();
        if id < n {
            return self.grid.point(self.grid.multi_index(id));
        }
        let e = id - n;
        let x_edges = (self.nx - 1) * self.ny;
        let (i, j, axis) = if e < x_edges {
            (e / self.ny, e % self.ny, 0)
        } else {
            let e = e - x_edges;
            (e / (self.ny - 1), e % (self.ny - 1), 1)
        };
        let lo = i * self.ny + j;
        let hi = if axis == 0 { lo + self.ny } else { lo + 1 };
        let t = crossing_parameter(self.values[lo], self.values[hi], self.level);
        let (mut s, mut r) = (i as f64, j as f64);
        if axis == 0 {
            s += t;
        } else {
            r += t;
        }
        [self.coordinate(0, s), self.coordinate(1, r)]
    }

    /// The coordinate at continuous index `s` on `axis` (the grid's formula, so that integer
    /// `s` gives exactly the sample's coordinate).
    fn coordinate(&self, axis: usize, s: f64) -> f64 {
        self.grid.bounds().min()[axis] + (s + self.offset) * self.grid.spacing()[axis]
    }
}

/// `t = (c − a) / (b − a)`, clamped to `[0, 1]`, for `a` and `b` on different sides of `c`:
/// exactly 0 when `a = c` and exactly 1 when `b = c`. Values so large that `b − a` overflows are
/// halved first.
fn crossing_parameter(a: f64, b: f64, c: f64) -> f64 {
    let d = b - a;
    let t = if d.is_finite() {
        (c - a) / d
    } else {
        (0.5 * c - 0.5 * a) / (0.5 * b - 0.5 * a)
    };
    t.clamp(0.0, 1.0)
}

/// Removes pairs of segments that are the same segment run both ways: the two sides of a
/// zero-width part of the inside region (a row of samples on the level with the inside on both
/// sides).
fn cancel_opposite(segments: Vec<Segment>) -> Vec<Segment> {
    let mut keyed: Vec<(usize, usize, bool)> = segments
        .into_iter()
        .map(|(a, b)| if a < b { (a, b, true) } else { (b, a, false) })
        .collect();
    keyed.sort_unstable();
    let mut out = Vec::with_capacity(keyed.len());
    let mut k = 0;
    while k < keyed.len() {
        let (a, b, _) = keyed[k];
        let end = k + keyed[k..]
            .iter()
            .take_while(|s| s.0 == a && s.1 == b)
            .count();
        let forward = keyed[k..end].iter().filter(|s| s.2).count();
        let backward = end - k - forward;
        let cancelled = forward.min(backward);
        out.extend(std::iter::repeat_n((a, b), forward - cancelled));
        out.extend(std::iter::repeat_n((b, a), backward - cancelled));
        k = end;
    }
    out
}

/// Joins sorted segments into maximal polylines: open ones from the vertices where more
/// segments leave than arrive (the curve enters the grid), then closed loops; at a vertex where
/// two curves touch, the turn furthest to the left.
fn trace(marcher: &Marcher<'_>, segments: Vec<Segment>) -> Vec<Polyline> {
    if segments.is_empty() {
        return Vec::new();
    }
    // Compact vertex numbering: the sorted distinct ids.
    let mut ids: Vec<usize> = segments.iter().flat_map(|&(a, b)| [a, b]).collect();
    ids.sort_unstable();
    ids.dedup();
    let compact = |id: usize| ids.partition_point(|&x| x < id);
    let to: Vec<usize> = segments.iter().map(|&(_, b)| compact(b)).collect();
    let nv = ids.len();
    // Segments are sorted by origin: those leaving v are out_start[v]..out_start[v + 1].
    let mut out_start = vec![0usize; nv + 1];
    let mut in_degree = vec![0usize; nv];
    for (&(a, _), &b) in segments.iter().zip(&to) {
        out_start[compact(a) + 1] += 1;
        in_degree[b] += 1;
    }
    for v in 0..nv {
        out_start[v + 1] += out_start[v];
    }
    let out_degree = |v: usize| out_start[v + 1] - out_start[v];
    let position: Vec<Point2> = ids.iter().map(|&id| marcher.position(id)).collect();
    let mut used = vec![false; segments.len()];

    // The unused segment to leave `v` by, having arrived from `prev`.
    let choose = |used: &[bool], v: usize, prev: Option<usize>| -> Option<usize> {
        let mut candidates = (out_start[v]..out_start[v + 1]).filter(|&s| !used[s]);
        let first = candidates.next()?;
        let Some(prev) = prev else {
            return Some(first);
        };
        let p = position[v];
        let d_in = [p[0] - position[prev][0], p[1] - position[prev][1]];
        let turn = |s: usize| {
            let q = position[to[s]];
            let d = [q[0] - p[0], q[1] - p[1]];
            (d_in[0] * d[1] - d_in[1] * d[0]).atan2(d_in[0] * d[0] + d_in[1] * d[1])
        };
        let mut best = (first, turn(first));
        for s in candidates {
            let a = turn(s);
            if a > best.1 {
                best = (s, a);
            }
        }
        Some(best.0)
    };

    let walk = |used: &mut [bool], start: usize, closed: bool| -> Polyline {
        let mut points = vec![position[start]];
        let (mut v, mut prev) = (start, None);
        while let Some(s) = choose(used, v, prev) {
            used[s] = true;
            let next = to[s];
            if closed && next == start {
                break;
            }
            points.push(position[next]);
            (prev, v) = (Some(v), next);
        }
        clean(Polyline { points, closed })
    };

    let mut lines = Vec::new();
    for (v, &arrive) in in_degree.iter().enumerate() {
        for _ in arrive..out_degree(v) {
            lines.push(walk(&mut used, v, false));
        }
    }
    // Loops start at a vertex where no curves touch when there is one, so that the turn rule
    // decides every touching.
    for simple_only in [true, false] {
        for v in 0..nv {
            if simple_only && out_degree(v) != 1 {
                continue;
            }
            while (out_start[v]..out_start[v + 1]).any(|s| !used[s]) {
                lines.push(walk(&mut used, v, true));
            }
        }
    }
    lines.retain(|l| l.points.len() >= if l.closed { 3 } else { 2 });
    lines
}

/// Drops consecutive equal vertices (crossings rounded onto each other), and a closed
/// polyline's last vertex while it equals the first.
fn clean(mut line: Polyline) -> Polyline {
    line.points.dedup();
    if line.closed {
        while line.points.len() > 1 && line.points.first() == line.points.last() {
            line.points.pop();
        }
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MeshError;
    use proptest::prelude::*;
    use std::f64::consts::PI;
    use zeroset_field_core::Error;
    use zeroset_field_core::geometry::norm;
    use zeroset_field_core::{Aabb, field::FnField};

    fn square_grid(n: usize) -> Grid<2> {
        Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [n, n]).unwrap()
    }

    fn circle(r: f64) -> FnField<2, impl Fn(&Point2) -> f64 + Send + Sync> {
        FnField::new(move |p: &Point2| p[0] * p[0] + p[1] * p[1] - r * r, None)
    }

    /// The side of line `ab` that `c` lies on: `1` left, `-1` right, `0` on it (up to
    /// rounding: collinear segments must not count as crossing).
    fn side(a: Point2, b: Point2, c: Point2) -> i32 {
        let (u, v) = ([b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]]);
        let cross = u[0] * v[1] - u[1] * v[0];
        if cross.abs() <= 1e-12 * norm(&u) * norm(&v) {
            0
        } else if cross > 0.0 {
            1
        } else {
            -1
        }
    }

    /// A pair of segments that cross properly (each one's ends strictly on both sides of the
    /// other), if any.
    fn crossing_pair(contour: &Contour) -> Option<((Point2, Point2), (Point2, Point2))> {
        let segs: Vec<(Point2, Point2)> = contour.lines.iter().flat_map(|l| l.segments()).collect();
        for (k, &(a, b)) in segs.iter().enumerate() {
            for &(c, d) in &segs[k + 1..] {
                if side(a, b, c) * side(a, b, d) < 0 && side(c, d, a) * side(c, d, b) < 0 {
                    return Some(((a, b), (c, d)));
                }
            }
        }
        None
    }

    /// Checks that `p` lies on a grid edge (or sample) where the linear interpolation of the
    /// samples equals `level`; returns a description of the failure.
    fn check_on_edge(grid: &Grid<2>, values: &[f64], level: f64, p: Point2) -> Result<(), String> {
        let [nx, ny] = grid.counts();
        let ci = grid.continuous_index(&p);
        let n = [nx, ny];
        let tol_index = 1e-9;
        for a in 0..2 {
            if ci[a] < -tol_index || ci[a] > (n[a] - 1) as f64 + tol_index {
                return Err(format!("{p:?} (index {ci:?}) outside the sampled region"));
            }
        }
        let scale = values
            .iter()
            .fold(level.abs(), |m, v| m.max(v.abs()))
            .max(1e-300);
        for a in 0..2 {
            let r = ci[a].round();
            if (ci[a] - r).abs() > tol_index {
                continue;
            }
            // On grid line `a = r`: interpolate along the other axis.
            let b = 1 - a;
            let k = (ci[b].floor().max(0.0) as usize).min(n[b] - 2);
            let s = (ci[b] - k as f64).clamp(0.0, 1.0);
            let mut lo = [0usize; 2];
            lo[a] = r as usize;
            lo[b] = k;
            let mut hi = lo;
            hi[b] += 1;
            let (va, vb) = (values[grid.linear_index(lo)], values[grid.linear_index(hi)]);
            let interp = (1.0 - s) * va + s * vb;
            if (interp - level).abs() <= 1e-9 * scale {
                return Ok(());
            }
            return Err(format!(
                "{p:?} on edge {lo:?}-{hi:?} interpolates to {interp}, not {level}"
            ));
        }
        Err(format!("{p:?} (index {ci:?}) is on no grid edge"))
    }

    fn on_border(grid: &Grid<2>, p: Point2) -> bool {
        let ci = grid.continuous_index(&p);
        let n = grid.counts();
        (0..2).any(|a| ci[a].abs() < 1e-9 || (ci[a] - (n[a] - 1) as f64).abs() < 1e-9)
    }

    /// The structural guarantees of the module docs, for any input.
    fn check_structure(grid: &Grid<2>, values: &[f64], c: &Contour) -> Result<(), String> {
        let diagonal = norm(&grid.spacing());
        for (k, line) in c.lines.iter().enumerate() {
            let n = line.points.len();
            if line.closed {
                if n < 3 {
                    return Err(format!("loop {k} has {n} points"));
                }
                if line.points[0] == line.points[n - 1] {
                    return Err(format!("loop {k} repeats its first point at the end"));
                }
            } else {
                if n < 2 {
                    return Err(format!("open line {k} has {n} points"));
                }
                for end in [line.points[0], line.points[n - 1]] {
                    if !on_border(grid, end) {
                        return Err(format!("open line {k} ends at {end:?}, inside the grid"));
                    }
                }
            }
            for (a, b) in line.segments() {
                if a == b {
                    return Err(format!("line {k} has a zero-length segment at {a:?}"));
                }
                // Every segment (the closing one included) lies in one cell.
                if distance(&a, &b) > diagonal * (1.0 + 1e-12) {
                    return Err(format!("line {k} jumps from {a:?} to {b:?}"));
                }
            }
            for &p in &line.points {
                check_on_edge(grid, values, c.level, p)?;
            }
        }
        // No segment twice, in either direction.
        let mut keys: Vec<[u64; 4]> = c
            .lines
            .iter()
            .flat_map(|l| l.segments())
            .map(|(a, b)| {
                let (a, b) = if a < b { (a, b) } else { (b, a) };
                [a[0], a[1], b[0], b[1]].map(f64::to_bits)
            })
            .collect();
        let total = keys.len();
        keys.sort_unstable();
        keys.dedup();
        if keys.len() != total {
            return Err(format!("{} duplicate segments", total - keys.len()));
        }
        if let Some(pair) = crossing_pair(c) {
            return Err(format!("segments cross: {pair:?}"));
        }
        Ok(())
    }

    #[test]
    fn circle_is_one_closed_loop_converging_in_length_as_h_squared() {
        let r = 0.7;
        let mut errors = Vec::new();
        for n in [17, 33, 65, 129, 257] {
            let grid = square_grid(n);
            let h = grid.spacing()[0];
            let c = contour_field(&circle(r), &grid, 0.0).unwrap();
            assert_eq!(c.lines.len(), 1, "n = {n}");
            assert_eq!(c.num_closed(), 1);
            let line = &c.lines[0];
            assert!(
                line.signed_area() > 0.0,
                "a loop around the inside is counter-clockwise"
            );
            for p in &line.points {
                let d = (norm(p) - r).abs();
                assert!(
                    d <= h * h / (4.0 * r),
                    "n = {n}: {p:?} is {d} from the circle"
                );
            }
            let error = (c.total_length() - 2.0 * PI * r).abs();
            assert!(error < 2.0 * h * h, "n = {n}: length error {error}");
            errors.push(error);
        }
        for w in errors.windows(2) {
            assert!(
                w[0] / w[1] >= 3.0,
                "length errors {errors:?} do not converge as h²"
            );
        }
    }

    #[test]
    fn cell_centred_grids_work_too() {
        let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [40, 50]).unwrap();
        let c = contour_field(&circle(0.5), &grid, 0.0).unwrap();
        assert_eq!(c.num_closed(), 1);
        assert!((c.total_length() - PI).abs() < 5e-3);
    }

    #[test]
    fn two_disjoint_circles_are_two_counter_clockwise_loops() {
        let f = FnField::new(
            |p: &Point2| {
                let a = (p[0] + 0.5).hypot(p[1]) - 0.3;
                let b = (p[0] - 0.5).hypot(p[1] - 0.2) - 0.2;
                a.min(b)
            },
            None,
        );
        let c = contour_field(&f, &square_grid(81), 0.0).unwrap();
        assert_eq!(c.lines.len(), 2);
        assert_eq!(c.num_closed(), 2);
        let mut areas: Vec<f64> = c.lines.iter().map(Polyline::signed_area).collect();
        areas.sort_by(f64::total_cmp);
        assert!((areas[0] - PI * 0.04).abs() < 2e-3, "{areas:?}");
        assert!((areas[1] - PI * 0.09).abs() < 2e-3, "{areas:?}");
    }

    #[test]
    fn an_area_far_from_the_origin_keeps_its_digits() {
        // A 0.1 × 0.2 rectangle (and a thin sliver) at UTM-like coordinates.
        for origin in [0.0, 6.9e6] {
            let rectangle = Polyline {
                points: vec![
                    [origin + 0.3, origin],
                    [origin + 0.4, origin],
                    [origin + 0.4, origin + 0.2],
                    [origin + 0.3, origin + 0.2],
                ],
                closed: true,
            };
            let area = rectangle.signed_area();
            // The corners themselves are rounded by 1e-9 there; uncentred products lost 1e-3.
            assert!((area - 0.02).abs() < 1e-9, "{origin}: {area}");
        }
    }

    #[test]
    fn an_annulus_has_a_counter_clockwise_outside_and_a_clockwise_hole() {
        let f = FnField::new(|p: &Point2| (p[0].hypot(p[1]) - 0.6).abs() - 0.2, None);
        let c = contour_field(&f, &square_grid(101), 0.0).unwrap();
        assert_eq!(c.num_closed(), 2);
        let mut areas: Vec<f64> = c.lines.iter().map(Polyline::signed_area).collect();
        areas.sort_by(f64::total_cmp);
        assert!((areas[0] + PI * 0.16).abs() < 5e-3, "{areas:?}");
        assert!((areas[1] - PI * 0.64).abs() < 5e-3, "{areas:?}");
    }

    #[test]
    fn a_line_across_the_box_is_one_open_polyline_ending_on_the_border() {
        let f = FnField::new(|p: &Point2| p[0] - 0.3 * p[1] - 0.1, None);
        let grid = square_grid(23);
        let c = contour_field(&f, &grid, 0.0).unwrap();
        assert_eq!(c.lines.len(), 1);
        let line = &c.lines[0];
        assert!(!line.closed);
        let (first, last) = (line.points[0], line.points[line.points.len() - 1]);
        // Inside (x < 0.3 y + 0.1) on the left: the line runs upwards, from y = −1 to y = 1.
        assert_eq!(first[1], -1.0);
        assert_eq!(last[1], 1.0);
        for p in &line.points {
            assert!((p[0] - 0.3 * p[1] - 0.1).abs() < 1e-12, "{p:?}");
        }
        let exact = 2.0 * (1.0f64 + 0.09).sqrt();
        assert!((line.length() - exact).abs() < 1e-12);
    }

    #[test]
    fn samples_on_the_level_give_one_vertex_each() {
        // f = x on a grid with a column of samples at x = 0: the line runs through them.
        let grid = square_grid(11);
        let c = contour_field(&FnField::new(|p: &Point2| p[0], None), &grid, 0.0).unwrap();
        assert_eq!(c.lines.len(), 1);
        let expected: Vec<Point2> = (0..11).map(|j| grid.point([5, j])).collect();
        assert_eq!(c.lines[0].points, expected);
        // A single sample touching the level from below (f = −x² − y², level 0) encloses
        // nothing; nor does a ridge of samples on the level (f = −x²), nor a valley (f = x²).
        for f in [
            |p: &Point2| -(p[0] * p[0] + p[1] * p[1]),
            |p: &Point2| -(p[0] * p[0]),
            |p: &Point2| p[0] * p[0],
        ] {
            let c = contour_field(&FnField::new(f, None), &grid, 0.0).unwrap();
            assert!(c.is_empty(), "{c:?}");
        }
    }

    #[test]
    fn curves_touching_at_a_sample_on_the_level_stay_apart() {
        // Inside columns left and right of a centre column that is outside, with its middle
        // sample on the level: the two boundaries touch there but each keeps to its side.
        let grid = Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [3, 3]).unwrap();
        let values = [-1.0, -1.0, -1.0, 1.0, 0.0, 1.0, -1.0, -1.0, -1.0];
        let c = marching_squares(&grid, &values, 0.0).unwrap();
        check_structure(&grid, &values, &c).unwrap();
        assert_eq!(c.lines.len(), 2, "{c:?}");
        for line in &c.lines {
            assert_eq!(line.points.len(), 3);
            assert_eq!(line.points[1], [0.0, 0.0]);
            let left = line.points.iter().all(|p| p[0] <= 0.0);
            let right = line.points.iter().all(|p| p[0] >= 0.0);
            assert!(
                left != right,
                "{line:?} crosses over at the touching sample"
            );
        }
    }

    #[test]
    fn a_loop_that_rounds_to_a_point_is_dropped() {
        // The crossings around a sample a hair below the level all round onto the sample.
        let grid = Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [3, 3]).unwrap();
        let mut values = [1.0; 9];
        values[4] = -1e-20;
        let c = marching_squares(&grid, &values, 0.0).unwrap();
        assert!(c.is_empty(), "{c:?}");
        // A little further below, the loop is resolved.
        values[4] = -1e-3;
        let c = marching_squares(&grid, &values, 0.0).unwrap();
        check_structure(&grid, &values, &c).unwrap();
        assert_eq!((c.num_closed(), c.num_points()), (1, 4));
    }

    #[test]
    fn a_ridge_ending_inside_the_grid_keeps_only_its_true_boundary() {
        // Samples on the level along x = 0 for y ≤ 0, the inside on both sides of them; above
        // y = 0 the column is outside. The contour is the boundary of the inside region, with
        // the zero-width slit removed, and stays well formed.
        let grid = square_grid(11);
        let values: Vec<f64> = (0..grid.len())
            .map(|l| {
                let p = grid.point(grid.multi_index(l));
                if p[0].abs() < 1e-12 {
                    if p[1] <= 0.0 { 0.0 } else { 1.0 }
                } else {
                    -1.0
                }
            })
            .collect();
        let c = marching_squares(&grid, &values, 0.0).unwrap();
        check_structure(&grid, &values, &c).unwrap();
        assert_eq!(c.lines.len(), 1);
        assert!(c.lines[0].points.iter().all(|p| p[1] >= -1e-12), "{c:?}");
    }

    #[test]
    fn saddle_cells_follow_the_asymptotic_decider() {
        // One cell over [0, 1]²; samples in linear order (0,0), (0,1), (1,0), (1,1).
        let grid =
            Grid::vertex_centered(Aabb::new([0.0, 0.0], [1.0, 1.0]).unwrap(), [2, 2]).unwrap();
        // Inside diagonal (0,0)-(1,1) at −1, outside at 2: B* = 0.5 > 0, the inside corners
        // are cut off.
        let c = marching_squares(&grid, &[-1.0, 2.0, 2.0, -1.0], 0.0).unwrap();
        check_structure(&grid, &[-1.0, 2.0, 2.0, -1.0], &c).unwrap();
        let mut segs: Vec<(Point2, Point2)> = c.lines.iter().flat_map(|l| l.segments()).collect();
        segs.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
        let third = 1.0 / 3.0;
        assert_eq!(segs.len(), 2);
        assert_eq!(segs[0], ([third, 0.0], [0.0, third]));
        assert_eq!(segs[1], ([2.0 * third, 1.0], [1.0, 2.0 * third]));
        // A saddle exactly on the level (B* = 0) counts as outside: the inside corners are cut
        // off.
        let values = [-1.0, 1.0, 1.0, -1.0];
        let c = marching_squares(&grid, &values, 0.0).unwrap();
        let mut segs: Vec<(Point2, Point2)> = c.lines.iter().flat_map(|l| l.segments()).collect();
        segs.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
        assert_eq!(
            segs,
            vec![([0.5, 0.0], [0.0, 0.5]), ([0.5, 1.0], [1.0, 0.5])]
        );
        // Inside at −2, outside at 1: B* = −0.5 < 0, the inside passes the centre.
        let values = [-2.0, 1.0, 1.0, -2.0];
        let c = marching_squares(&grid, &values, 0.0).unwrap();
        check_structure(&grid, &values, &c).unwrap();
        let mut segs: Vec<(Point2, Point2)> = c.lines.iter().flat_map(|l| l.segments()).collect();
        segs.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
        assert_eq!(segs.len(), 2);
        assert_eq!(segs[0], ([third, 1.0], [0.0, 2.0 * third]));
        assert_eq!(segs[1], ([2.0 * third, 0.0], [1.0, third]));
    }

    #[test]
    fn the_saddle_field_xy_gives_two_lines_that_never_cross() {
        // Saddle at a cell centre (even counts) and at a sample (odd counts), on and off the
        // level.
        for n in [10, 11, 40, 41] {
            let grid = square_grid(n);
            let f = FnField::new(|p: &Point2| p[0] * p[1], None);
            let values = grid.sample(&f);
            for level in [0.0, 0.01, -0.01] {
                let c = marching_squares(&grid, &values, level).unwrap();
                check_structure(&grid, &values, &c).unwrap_or_else(|e| panic!("n = {n}: {e}"));
                assert_eq!(c.lines.len(), 2, "n = {n}, level {level}: {c:?}");
                assert_eq!(c.num_open(), 2);
            }
        }
    }

    #[test]
    fn constant_fields_have_no_contour() {
        let grid = square_grid(9);
        for value in [-1.0, 0.0, 1.0] {
            let c = marching_squares(&grid, &vec![value; grid.len()], 0.0).unwrap();
            assert!(c.is_empty());
            assert_eq!(c.total_length(), 0.0);
        }
    }

    #[test]
    fn bad_inputs_are_specific_errors() {
        let grid = square_grid(4);
        let mut values = vec![1.0; 16];
        values[6] = f64::NAN;
        match marching_squares(&grid, &values, 0.0) {
            Err(MeshError::NonFiniteSample {
                index,
                grid_index,
                value,
                ..
            }) => {
                assert_eq!(index, 6);
                assert_eq!(grid_index, vec![1, 2]);
                assert!(value.is_nan());
            }
            other => panic!("{other:?}"),
        }
        values[6] = 1.0;
        values[15] = f64::NEG_INFINITY;
        assert!(matches!(
            marching_squares(&grid, &values, 0.0),
            Err(MeshError::NonFiniteSample { index: 15, .. })
        ));
        assert!(matches!(
            marching_squares(&grid, &values[..15], 0.0),
            Err(MeshError::Field(Error::ShapeMismatch {
                expected: 16,
                got: 15,
                ..
            }))
        ));
        assert!(matches!(
            marching_squares(&grid, &[0.0; 16], f64::NAN),
            Err(MeshError::NonFiniteLevel { .. })
        ));
        let thin = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [5, 1]).unwrap();
        assert!(matches!(
            marching_squares(&thin, &[0.0; 5], 0.0),
            Err(MeshError::Field(Error::GridTooSmall {
                axis: 1,
                needed: 2,
                got: 1
            }))
        ));
        let nan_field = FnField::new(|p: &Point2| if p[0] > 0.5 { f64::NAN } else { p[0] }, None);
        let err = contour_field(&nan_field, &grid, 0.0).unwrap_err();
        assert!(
            matches!(err, MeshError::NonFiniteSample { index: 12, .. }),
            "{err}"
        );
        assert!(err.to_string().contains("sample 12"), "{err}");
    }

    #[test]
    fn huge_values_neither_overflow_nor_panic() {
        let grid =
            Grid::vertex_centered(Aabb::new([0.0, 0.0], [1.0, 1.0]).unwrap(), [2, 2]).unwrap();
        let values = [-f64::MAX, f64::MAX, f64::MAX, -f64::MAX];
        let c = marching_squares(&grid, &values, 0.0).unwrap();
        check_structure(&grid, &values, &c).unwrap();
        assert_eq!(c.lines.len(), 2);
        for p in c.lines.iter().flat_map(|l| &l.points) {
            assert!(p.contains(&0.5), "{p:?}");
        }
    }

    #[test]
    fn output_is_deterministic_across_runs_and_thread_counts() {
        let f = FnField::new(
            |p: &Point2| (3.0 * p[0]).sin() * (2.0 * p[1]).cos() + 0.3 * p[0] * p[1],
            None,
        );
        let grid = Grid::vertex_centered(Aabb::centered_cube(2.0).unwrap(), [200, 180]).unwrap();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| contour_field(&f, &grid, 0.1).unwrap())
        };
        let one = run(1);
        assert!(one.lines.len() > 3);
        assert_eq!(one, run(4));
        assert_eq!(one, run(4));
    }

    /// A random smooth field: a constant plus a few plane waves.
    fn smooth_field() -> impl Strategy<Value = (f64, Vec<(f64, f64, f64, f64)>)> {
        (
            -0.5..0.5f64,
            prop::collection::vec(
                (-1.0..1.0f64, -6.0..6.0f64, -6.0..6.0f64, 0.0..6.3f64),
                1..4,
            ),
        )
    }

    fn eval(field: &(f64, Vec<(f64, f64, f64, f64)>), p: &Point2) -> f64 {
        field.0
            + field
                .1
                .iter()
                .map(|&(a, kx, ky, phase)| a * (kx * p[0] + ky * p[1] + phase).sin())
                .sum::<f64>()
    }

    /// Edges whose samples lie on different sides of `level`.
    fn crossing_edges(grid: &Grid<2>, values: &[f64], level: f64) -> usize {
        let [nx, ny] = grid.counts();
        let side = |i: usize, j: usize| values[grid.linear_index([i, j])] < level;
        let mut count = 0;
        for i in 0..nx {
            for j in 0..ny {
                if i + 1 < nx && side(i, j) != side(i + 1, j) {
                    count += 1;
                }
                if j + 1 < ny && side(i, j) != side(i, j + 1) {
                    count += 1;
                }
            }
        }
        count
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(96))]

        #[test]
        fn smooth_fields_give_well_formed_contours(
            field in smooth_field(),
            nx in 2usize..28,
            ny in 2usize..28,
            cell in any::<bool>(),
            level in -0.3..0.3f64,
        ) {
            let bounds = Aabb::new([-1.0, -0.5], [1.0, 1.5]).unwrap();
            let centering = if cell { Centering::Cell } else { Centering::Vertex };
            let grid = Grid::new(bounds, [nx, ny], centering).unwrap();
            let f = FnField::new(|p: &Point2| eval(&field, p), None);
            let values = grid.sample(&f);
            let c = marching_squares(&grid, &values, level).unwrap();
            prop_assert_eq!(&c, &contour_field(&f, &grid, level).unwrap());
            if let Err(e) = check_structure(&grid, &values, &c) {
                return Err(TestCaseError::fail(e));
            }
            // Every crossing edge gives exactly one vertex (no sample lies on the level here).
            prop_assert_eq!(c.num_points(), crossing_edges(&grid, &values, level));
        }

        #[test]
        fn samples_on_the_level_never_break_the_structure(
            nx in 2usize..16,
            ny in 2usize..16,
            seed in prop::collection::vec(-1i8..=1, 256),
        ) {
            let grid = Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [nx, ny]).unwrap();
            let values: Vec<f64> = (0..grid.len()).map(|l| f64::from(seed[l % 256])).collect();
            let c = marching_squares(&grid, &values, 0.0).unwrap();
            if let Err(e) = check_structure(&grid, &values, &c) {
                return Err(TestCaseError::fail(format!("{e}\nvalues {values:?}\n{c:?}")));
            }
        }
    }
}
