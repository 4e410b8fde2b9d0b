//! [`MrasField`]: the multilevel sum of blended low-rank spline offsets, evaluated from the CP
//! factors directly (see the module docs of [`crate::mras`] for the maths).

use rayon::prelude::*;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};

use crate::bspline::stencil::weights;

/// The coefficients of one cell's offset spline `φ`, a `m × … × m` tensor (`D` axes).
#[derive(Debug, Clone, PartialEq)]
pub enum CellSpline<const D: usize> {
    /// Rank-`R` CP factors: `c[i₀, …] = Σ_r Π_a factors[a][i_a·R + r]` (weights folded into the
    /// first axis), so `φ(u) = Σ_r Π_a g_{r,a}(u_a)` with `g_{r,a} = Σ_i N_i(u_a) factors[a][i, r]`.
    Cp {
        /// The rank `R`.
        rank: usize,
        /// Per axis an `m × R` row-major matrix.
        factors: [Vec<f64>; D],
    },
    /// The full coefficient tensor, row-major (the last axis fastest): the uncompressed MRAS.
    Full {
        /// `m^D` coefficients.
        coefficients: Vec<f64>,
    },
}

impl<const D: usize> CellSpline<D> {
    /// Per axis `a`, the largest `|c[…, i_a, …] − c[…, i_a − 1, …]|` over the coefficients
    /// with `span[b].0 ≤ i_b ≤ span[b].1` on every axis (`m` B-splines per axis): the window's
    /// coefficients are formed (from the CP factors where stored so) and differenced.
    fn difference_bounds(&self, m: usize, span: &[(usize, usize); D]) -> [f64; D] {
        let len: [usize; D] = std::array::from_fn(|a| span[a].1 - span[a].0 + 1);
        let mut window = Vec::with_capacity(len.iter().product());
        let (first, last) = (span.map(|s| s.0), span.map(|s| s.1));
        let mut index = first;
        loop {
            window.push(match self {
                CellSpline::Cp { rank, factors } => (0..*rank)
                    .map(|r| {
                        (0..D)
                            .map(|a| factors[a][index[a] * rank + r])
                            .product::<f64>()
                    })
                    .sum::<f64>(),
                CellSpline::Full { coefficients } => {
                    coefficients[index.iter().fold(0, |acc, &i| acc * m + i)]
                }
            });
            if !next_in_box(&mut index, &first, &last) {
                break;
            }
        }
        // Row-major strides of the window, the last axis fastest.
        let mut stride = [1usize; D];
        for a in (0..D.saturating_sub(1)).rev() {
            stride[a] = stride[a + 1] * len[a + 1];
        }
        let mut out = [0.0f64; D];
        for (flat, &v) in window.iter().enumerate() {
            for a in 0..D {
                if (flat / stride[a]) % len[a] > 0 {
                    out[a] = out[a].max((v - window[flat - stride[a]]).abs());
                }
            }
        }
        out
    }

    /// The numbers stored: `D·m·R` for CP factors, `m^D` for a full tensor.
    pub fn stored_numbers(&self) -> usize {
        match self {
            CellSpline::Cp { factors, .. } => factors.iter().map(Vec::len).sum(),
            CellSpline::Full { coefficients } => coefficients.len(),
        }
    }

    /// The CP rank (`None` for a full tensor).
    pub fn rank(&self) -> Option<usize> {
        match self {
            CellSpline::Cp { rank, .. } => Some(*rank),
            CellSpline::Full { .. } => None,
        }
    }
}

/// One fitted cell of a level: its lattice index and its offset spline.
#[derive(Debug, Clone, PartialEq)]
pub struct MrasCell<const D: usize> {
    /// The cell's index in the level's lattice of `2^{k−1}` cells per axis.
    pub index: [u32; D],
    /// The offset `φ` on the cell's support box.
    pub spline: CellSpline<D>,
}

/// One octree level `k` (from 1): the fitted cells of the lattice of `2^{k−1}` cells per axis,
/// each with `m` B-splines per axis.
#[derive(Debug, Clone)]
pub struct MrasLevel<const D: usize> {
    level: u32,
    knots: usize,
    cells: Vec<MrasCell<D>>,
    lookup: CellLookup,
}

impl<const D: usize> PartialEq for MrasLevel<D> {
    fn eq(&self, other: &Self) -> bool {
        self.level == other.level && self.knots == other.knots && self.cells == other.cells
    }
}

/// Lattice index → position in `cells` (derived, rebuilt on construction).
#[derive(Debug, Clone)]
enum CellLookup {
    /// One slot per lattice cell (`u32::MAX`: not fitted), and per lattice cell whether a
    /// fitted cell lies among its 3^D neighbours (else the level adds nothing there).
    Dense(Vec<u32>, Vec<bool>),
    /// Sorted linear indices, searched.
    Sorted(Vec<(u64, u32)>),
}

/// Lattices with at most this many cells get a dense lookup table.
const DENSE_LOOKUP: u64 = 1 << 22;

/// The deepest level a field may hold (`2^{19}` cells per axis; far beyond any real fit).
pub const MAX_LEVEL: u32 = 20;

impl<const D: usize> MrasLevel<D> {
    /// Level `level` (from 1) with `knots` B-splines per axis and these cells.
    ///
    /// # Errors
    /// A message for a level outside `1..=MAX_LEVEL`, fewer than 3 knots, a cell outside the
    /// lattice or listed twice, or a spline of the wrong size.
    pub fn new(level: u32, knots: usize, mut cells: Vec<MrasCell<D>>) -> Result<Self, String> {
        if !(1..=MAX_LEVEL).contains(&level) {
            return Err(format!("level {level} outside 1..={MAX_LEVEL}"));
        }
        if knots < 3 {
            return Err(format!(
                "level {level}: {knots} B-splines per axis (at least 3)"
            ));
        }
        let n = 1u64 << (level - 1);
        for cell in &cells {
            if cell.index.iter().any(|&i| u64::from(i) >= n) {
                return Err(format!(
                    "level {level}: cell {:?} outside the lattice of {n} cells per axis",
                    cell.index
                ));
            }
            let ok = match &cell.spline {
                CellSpline::Cp { rank, factors } => {
                    *rank >= 1 && factors.iter().all(|f| f.len() == knots * rank)
                }
                CellSpline::Full { coefficients } => coefficients.len() == knots.pow(D as u32),
            };
            let finite = match &cell.spline {
                CellSpline::Cp { factors, .. } => factors.iter().flatten().all(|v| v.is_finite()),
                CellSpline::Full { coefficients } => coefficients.iter().all(|v| v.is_finite()),
            };
            if !finite {
                return Err(format!(
                    "level {level}: cell {:?} has a coefficient that is not finite",
                    cell.index
                ));
            }
            if !ok {
                return Err(format!(
                    "level {level}: cell {:?} has coefficients of the wrong size for {knots} \
                     B-splines per axis",
                    cell.index
                ));
            }
        }
        cells.sort_by_key(|c| linear(&c.index, n));
        if cells
            .windows(2)
            .any(|w| linear(&w[0].index, n) == linear(&w[1].index, n))
        {
            return Err(format!("level {level}: a cell is listed twice"));
        }
        let total = n.checked_pow(D as u32).unwrap_or(u64::MAX);
        let lookup = if total <= DENSE_LOOKUP {
            let mut slots = vec![u32::MAX; total as usize];
            let mut near = vec![false; total as usize];
            for (pos, c) in cells.iter().enumerate() {
                slots[linear(&c.index, n) as usize] = pos as u32;
                for code in 0..3usize.pow(D as u32) {
                    let mut key = 0u64;
                    let mut c2 = code;
                    let mut inside = true;
                    for a in 0..D {
                        let i = i64::from(c.index[a]) + (c2 % 3) as i64 - 1;
                        c2 /= 3;
                        if i < 0 || i >= n as i64 {
                            inside = false;
                        }
                        key = key * n + i.max(0) as u64;
                    }
                    if inside {
                        near[key as usize] = true;
                    }
                }
            }
            CellLookup::Dense(slots, near)
        } else {
            CellLookup::Sorted(
                cells
                    .iter()
                    .enumerate()
                    .map(|(pos, c)| (linear(&c.index, n), pos as u32))
                    .collect(),
            )
        };
        Ok(Self {
            level,
            knots,
            cells,
            lookup,
        })
    }

    /// The level `k` (from 1).
    pub fn level(&self) -> u32 {
        self.level
    }

    /// B-splines per axis `m_k`.
    pub fn knots(&self) -> usize {
        self.knots
    }

    /// The fitted cells, sorted by lattice index.
    pub fn cells(&self) -> &[MrasCell<D>] {
        &self.cells
    }

    /// Cells per axis of the level's lattice, `2^{k−1}`.
    pub fn lattice(&self) -> u64 {
        1u64 << (self.level - 1)
    }

    /// Numbers stored for the level's splines (CP factors or full tensors).
    pub fn stored_numbers(&self) -> usize {
        self.cells.iter().map(|c| c.spline.stored_numbers()).sum()
    }

    /// Numbers the level's splines would take as full tensors, `cells · m^D`.
    pub fn uncompressed_numbers(&self) -> usize {
        self.cells.len() * self.knots.pow(D as u32)
    }

    /// Whether a fitted cell lies among the 3^D neighbours of lattice cell `index` (true when
    /// the level keeps no table for it).
    fn near(&self, index: &[u64; D]) -> bool {
        match &self.lookup {
            CellLookup::Dense(_, near) => {
                let n = self.lattice();
                near[index.iter().fold(0u64, |acc, &i| acc * n + i) as usize]
            }
            CellLookup::Sorted(_) => true,
        }
    }

    /// The position in [`MrasLevel::cells`] of the fitted cell at `index`.
    fn position(&self, index: &[u64; D]) -> Option<usize> {
        let n = self.lattice();
        let key = index.iter().fold(0u64, |acc, &i| acc * n + i);
        let pos = match &self.lookup {
            CellLookup::Dense(slots, _) => match slots[key as usize] {
                u32::MAX => return None,
                p => p,
            },
            CellLookup::Sorted(keys) => {
                let at = keys.binary_search_by_key(&key, |&(k, _)| k).ok()?;
                keys[at].1
            }
        };
        Some(pos as usize)
    }
}

fn linear<const D: usize>(index: &[u32; D], n: u64) -> u64 {
    index.iter().fold(0u64, |acc, &i| acc * n + u64::from(i))
}

/// The geometry of one level's cells in the unit cube: side `s = 2^{1−k}`, partition-of-unity
/// radius `ρ = α·√D·s` (α times the cell's full diagonal), and the support box `c ± b` holding
/// `m` B-splines of spacing `h = 2b/(m − 2)`: `b = ρ` (the box around the weight's support) on
/// levels 2, 3, …, and `b = ½` — the cube itself — on the root level, whose single cell's
/// weight is the whole partition of unity (`w/Σw = 1`), so that its splines are spent where the
/// points are rather than on the 2.6× wider box around a support nobody evaluates outside the
/// cube.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelGeometry {
    /// Cells per axis.
    pub lattice: u64,
    /// Cell side `s`.
    pub side: f64,
    /// Partition-of-unity support radius `ρ`.
    pub radius: f64,
    /// Half the side `b` of the support box holding the splines.
    pub half_box: f64,
    /// B-splines per axis `m`.
    pub knots: usize,
    /// Knot spacing `h`.
    pub spacing: f64,
}

impl LevelGeometry {
    /// The geometry of level `level` (from 1) in `D` dimensions.
    pub fn new(dim: usize, level: u32, knots: usize, alpha: f64) -> Self {
        let lattice = 1u64 << (level - 1);
        let side = 1.0 / lattice as f64;
        let radius = alpha * (dim as f64).sqrt() * side;
        let half_box = if level == 1 { 0.5 } else { radius };
        Self {
            lattice,
            side,
            radius,
            half_box,
            knots,
            spacing: 2.0 * half_box / (knots as f64 - 2.0),
        }
    }

    /// The centre of the cell with lattice index `i` along one axis.
    #[inline]
    pub fn centre(&self, i: u64) -> f64 {
        (i as f64 + 0.5) * self.side
    }

    /// The continuous B-spline index of the unit-cube coordinate `u` in the cell whose centre
    /// is `centre` (clamped to the support box `[½, m − 3/2]`).
    #[inline]
    pub fn spline_index(&self, u: f64, centre: f64) -> f64 {
        ((u - centre + self.half_box) / self.spacing + 0.5).clamp(0.5, self.knots as f64 - 1.5)
    }
}

/// The partition-of-unity weight `w(r) = β²(3r / 2ρ)` (eq. 8) and `dw/dr`.
#[inline]
pub(crate) fn pu_weight(r: f64, radius: f64) -> (f64, f64) {
    let t = 1.5 * r / radius;
    let dt = 1.5 / radius;
    if t >= 1.5 {
        (0.0, 0.0)
    } else if t <= 0.5 {
        (0.75 - t * t, -2.0 * t * dt)
    } else {
        let l = 1.5 - t;
        (0.5 * l * l, -l * dt)
    }
}

/// Steps `index` to the next index of the box `first ..= last` (each axis), the last axis
/// fastest; `false` (and `index` back at `first`) after the box's last index.
fn next_in_box<const D: usize, T>(index: &mut [T; D], first: &[T; D], last: &[T; D]) -> bool
where
    T: Copy + PartialOrd + std::ops::AddAssign + From<u8>,
{
    for a in (0..D).rev() {
        if index[a] < last[a] {
            index[a] += T::from(1);
            return true;
        }
        index[a] = first[a];
    }
    false
}

/// `[lo, hi]` widened by a few units of rounding of its magnitude: evaluation sums and
/// divides in floating point, so a value may leave the exact hull by that much.
fn widened(lo: f64, hi: f64) -> [f64; 2] {
    let slack = 1e-12 * lo.abs().max(hi.abs());
    [lo - slack, hi + slack]
}

/// A multilevel rational algebraic spline (MRAS) field (paper 004 §4, eqs. 6–9):
/// `f = side · Σ_k o_k(u)` with `u = (p − origin)/side` in the unit cube and `o_k` the level's
/// blended offsets `Σ_j w_j φ_j / Σ_i w_i` (the denominator summing over every cell of the
/// level's lattice, fitted or not).
///
/// Points outside the cube are clamped onto it (the field is constant along the clamped
/// directions there). Evaluation reads the CP factors directly; the full tensors are never
/// formed. Single and batched evaluation give the same bits on any number of threads.
/// [`ScalarField::value_range`] encloses the field over a box from each level's cells near it
/// (none of the box's points evaluated): what the signed marching cubes settle blocks with. For
/// meshing, plain marching cubes remains the faster on MRAS fields (batched evaluation along
/// grid rows: 0.67 s against 1.41 s for the bunny's field at 136×136×116, 2 threads; the
/// `mras_enclosures` example).
///
/// A fitted field also records the points it was fitted to ([`MrasField::points`]), in `f32`
/// unit-cube coordinates: not part of the field's value, but what `zeroset mesh` checks a
/// mesh's components against (a component far from every point is a spurious sheet).
#[derive(Debug, Clone, PartialEq)]
pub struct MrasField<const D: usize> {
    origin: Point<D>,
    side: f64,
    alpha: f64,
    levels: Vec<MrasLevel<D>>,
    /// The recorded input points, `(p − origin)/side` rounded to `f32`.
    points: Vec<[f32; D]>,
}

/// Points per rayon task in [`MrasField::values`].
const CHUNK: usize = 1024;

impl<const D: usize> MrasField<D> {
    /// The field on the cube `origin + [0, side]^D` with partition-of-unity factor `alpha` and
    /// these levels (1, 2, … in order).
    ///
    /// # Errors
    /// A message for a non-finite origin, a side or `alpha` that is not positive and finite, or
    /// levels not numbered 1, 2, ….
    pub fn new(
        origin: Point<D>,
        side: f64,
        alpha: f64,
        levels: Vec<MrasLevel<D>>,
    ) -> Result<Self, String> {
        if origin.iter().any(|v| !v.is_finite()) {
            return Err(format!("origin {origin:?} is not finite"));
        }
        if !(side.is_finite() && side > 0.0) {
            return Err(format!("cube side {side} is not positive and finite"));
        }
        // Σw > 0 in every cell needs ρ = α√D·s above the half-diagonal √D·s/2.
        if !(alpha.is_finite() && alpha > 0.5) {
            return Err(format!(
                "partition-of-unity factor α = {alpha}: must exceed 1/2 so that every point \
                 of a cell lies inside its support"
            ));
        }
        for (i, l) in levels.iter().enumerate() {
            if l.level as usize != i + 1 {
                return Err(format!(
                    "levels must be numbered 1, 2, …: position {} holds level {}",
                    i + 1,
                    l.level
                ));
            }
        }
        Ok(Self {
            origin,
            side,
            alpha,
            levels,
            points: Vec::new(),
        })
    }

    /// This field recording `points` (world coordinates) as the points it was fitted to,
    /// rounded to `f32` in the cube's unit coordinates (a relative precision of 6e-8 of the
    /// side: ample for telling whether a point lies within a few voxels of a mesh).
    pub fn with_points(self, points: &[Point<D>]) -> Self {
        let unit = points
            .iter()
            .map(|p| std::array::from_fn(|a| ((p[a] - self.origin[a]) / self.side) as f32))
            .collect();
        self.with_unit_points(unit)
    }

    /// This field recording points already in `f32` unit-cube coordinates (the file's form).
    pub(crate) fn with_unit_points(mut self, points: Vec<[f32; D]>) -> Self {
        self.points = points;
        self
    }

    /// The recorded points in the cube's unit coordinates (empty if none were recorded).
    pub fn unit_points(&self) -> &[[f32; D]] {
        &self.points
    }

    /// The recorded input points in world coordinates, `origin + side · u` (empty if none
    /// were recorded: fields built by hand, or read from a file written before fields recorded
    /// them).
    pub fn points(&self) -> Vec<Point<D>> {
        self.points
            .iter()
            .map(|u| std::array::from_fn(|a| self.origin[a] + self.side * f64::from(u[a])))
            .collect()
    }

    /// The cube's lowest corner.
    pub fn origin(&self) -> Point<D> {
        self.origin
    }

    /// The cube's side.
    pub fn side(&self) -> f64 {
        self.side
    }

    /// The partition-of-unity factor `α` (the support radius is `α` times the cell diagonal).
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// The levels, coarse to fine.
    pub fn levels(&self) -> &[MrasLevel<D>] {
        &self.levels
    }

    /// Appends the next level.
    pub(crate) fn push_level(&mut self, level: MrasLevel<D>) -> Result<(), String> {
        if level.level as usize != self.levels.len() + 1 {
            return Err(format!(
                "level {} appended after {} levels",
                level.level,
                self.levels.len()
            ));
        }
        self.levels.push(level);
        Ok(())
    }

    /// The same field truncated to its first `levels` levels (`f^k` of the paper).
    pub fn truncated(&self, levels: usize) -> Self {
        Self {
            levels: self.levels[..levels.min(self.levels.len())].to_vec(),
            ..self.clone()
        }
    }

    /// The geometry of level `k` (from 1).
    pub fn geometry(&self, level: &MrasLevel<D>) -> LevelGeometry {
        LevelGeometry::new(D, level.level, level.knots, self.alpha)
    }

    /// An enclosure `[lo, hi]` of one level's blended offset `o_k` over the unit-cube box
    /// `[lo_u, hi_u]` (inside the cube). `o_k(u) = Σ_j w_j φ_j(u) / Σ_i w_i(u)`, the
    /// denominator over every lattice cell within reach, fitted or not, is a convex combination
    /// of the fitted cells' `φ_j(u)` and of 0 (an unfitted cell's offset). Each `φ_j` differs
    /// from its value at the box's centre `c` by at most `Σ_a D_a |u_a − c_a|`, `D_a` the
    /// largest first difference of the coefficients along axis `a` over the B-splines that reach
    /// the box, divided by the knot spacing (the derivative of a quadratic B-spline sum is a
    /// linear B-spline sum of those differences; evaluation's clamping only flattens it). So
    /// `o_k` lies in the hull of `φ_j(c) ± Σ_a D_a r_a` over the cells whose support box meets
    /// the region, and of 0 where one of the lattice cells there is not fitted. (The
    /// coefficients' own extremes, the B-splines' convex hull, would do too, but they span
    /// three knot intervals: a third of the cube at the root.)
    fn level_range(&self, level: &MrasLevel<D>, lo_u: &Point<D>, hi_u: &Point<D>) -> [f64; 2] {
        let g = self.geometry(level);
        let n = g.lattice;
        let centre: Point<D> = std::array::from_fn(|a| 0.5 * (lo_u[a] + hi_u[a]));
        let reach: Point<D> = std::array::from_fn(|a| 0.5 * (hi_u[a] - lo_u[a]));
        // The lattice cells whose support box c ± ρ meets the region, per axis.
        let mut first = [0u64; D];
        let mut last = [0u64; D];
        for a in 0..D {
            let from = ((lo_u[a] - g.radius) / g.side - 0.5).ceil().max(0.0);
            let to = ((hi_u[a] + g.radius) / g.side - 0.5).floor();
            if to < from {
                return [0.0, 0.0];
            }
            first[a] = from as u64;
            last[a] = (to as u64).min(n - 1);
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut fitted = 0u64;
        let mut meets = |cell: &MrasCell<D>| {
            let index: [u64; D] = std::array::from_fn(|a| u64::from(cell.index[a]));
            if (0..D).any(|a| index[a] < first[a] || index[a] > last[a]) {
                return;
            }
            fitted += 1;
            // The B-splines that reach the region in this cell's box: indices ⌊x + ½⌋ − 1 …
            // ⌊x + ½⌋ + 1 of the region's ends, clamped as evaluation clamps.
            let span: [(usize, usize); D] = std::array::from_fn(|a| {
                let c = g.centre(index[a]);
                let from = g.spline_index(lo_u[a], c);
                let to = g.spline_index(hi_u[a], c);
                let i0 = ((from + 0.5).floor() as usize).saturating_sub(1);
                let i1 = ((to + 0.5).floor() as usize + 1).min(g.knots - 1);
                (i0, i1)
            });
            let slopes = cell.spline.difference_bounds(g.knots, &span);
            let spread: f64 = (0..D).map(|a| slopes[a] / g.spacing * reach[a]).sum();
            let (v, _) = spline_at(&cell.spline, &g, &index, &centre, false);
            lo = lo.min(v - spread);
            hi = hi.max(v + spread);
        };
        let boxed: u64 = (0..D).map(|a| last[a] - first[a] + 1).product();
        if boxed < level.cells.len() as u64 {
            let mut index = first;
            loop {
                if let Some(pos) = level.position(&index) {
                    meets(&level.cells[pos]);
                }
                if !next_in_box(&mut index, &first, &last) {
                    break;
                }
            }
        } else {
            level.cells.iter().for_each(&mut meets);
        }
        // A lattice cell there without an offset blends in as 0.
        if fitted < boxed {
            lo = lo.min(0.0);
            hi = hi.max(0.0);
        }
        widened(lo, hi)
    }

    /// The knot spacing of the finest level's splines, in the points' units: about the
    /// smallest detail the field holds (`None` without levels).
    pub fn finest_spacing(&self) -> Option<f64> {
        self.levels
            .last()
            .map(|l| self.geometry(l).spacing * self.side)
    }

    /// Numbers stored as the paper counts them (§6.2): every cell's spline (`3·m·R` for CP
    /// factors) plus its blending function (centre and radius, `D + 1`).
    pub fn storage(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.stored_numbers() + l.cells.len() * (D + 1))
            .sum()
    }

    /// The storage the same cells would need as full tensors (plus the blending functions).
    pub fn uncompressed_storage(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.uncompressed_numbers() + l.cells.len() * (D + 1))
            .sum()
    }

    /// Unit-cube coordinates of `p`, clamped onto the cube.
    #[inline]
    pub fn to_unit(&self, p: &Point<D>) -> Point<D> {
        let mut u = [0.0; D];
        for a in 0..D {
            u[a] = ((p[a] - self.origin[a]) / self.side).clamp(0.0, 1.0);
        }
        u
    }

    /// The value and unit-cube gradient of one level's blended offset `o_k(u)`.
    pub fn level_offset(
        &self,
        level: &MrasLevel<D>,
        u: &Point<D>,
        with_gradient: bool,
    ) -> (f64, Point<D>) {
        let g = self.geometry(level);
        let columns = Columns::new(&g, u);
        self.blend(level, &g, &columns, u, with_gradient, |position, index| {
            spline_at(&level.cells[position].spline, &g, index, u, with_gradient)
        })
    }

    /// `o_k(u)` and its gradient, with `columns` the lattice neighbours of `u` along the first
    /// `D − 1` axes (the same for every point of a grid row) and `spline(position, index)` the
    /// offset `φ` (and its gradient) of the fitted cell at `position` in the level's cells,
    /// lattice index `index`.
    #[inline]
    fn blend(
        &self,
        level: &MrasLevel<D>,
        g: &LevelGeometry,
        columns: &Columns<D>,
        u: &Point<D>,
        with_gradient: bool,
        mut spline: impl FnMut(usize, &[u64; D]) -> (f64, Point<D>),
    ) -> (f64, Point<D>) {
        let n = g.lattice;
        let mut home = columns.home;
        home[D - 1] = ((u[D - 1] * n as f64) as u64).min(n - 1);
        // No fitted cell within reach (ρ < 1.5 s): the level adds nothing here.
        if !level.near(&home) {
            return (0.0, [0.0; D]);
        }
        let (mut wsum, mut num) = (0.0, 0.0);
        let (mut dwsum, mut dnum) = ([0.0; D], [0.0; D]);
        let radius2 = g.radius * g.radius;
        // The 3^D lattice cells around the home cell (ρ < 1.5 s: no others reach u), the first
        // axis fastest: the last axis's three, each with the columns.
        for off in 0..3 {
            let Some(i) = (home[D - 1] + off).checked_sub(1).filter(|&i| i < n) else {
                continue;
            };
            let dz = u[D - 1] - g.centre(i);
            for c in &columns.cells[..columns.len] {
                let r2 = c.r2 + dz * dz;
                if r2 >= radius2 {
                    continue;
                }
                let mut index = c.index;
                index[D - 1] = i;
                let r = r2.sqrt();
                let (w, dw) = pu_weight(r, g.radius);
                wsum += w;
                let mut grad_w = [0.0; D];
                if with_gradient && r > 0.0 {
                    let mut d = c.d;
                    d[D - 1] = dz;
                    for a in 0..D {
                        grad_w[a] = dw * d[a] / r;
                        dwsum[a] += grad_w[a];
                    }
                }
                let Some(position) = level.position(&index) else {
                    continue;
                };
                let (phi, dphi) = spline(position, &index);
                num += w * phi;
                if with_gradient {
                    for a in 0..D {
                        dnum[a] += grad_w[a] * phi + w * dphi[a];
                    }
                }
            }
        }
        if wsum <= 0.0 {
            return (0.0, [0.0; D]);
        }
        let value = num / wsum;
        let mut grad = [0.0; D];
        if with_gradient {
            for a in 0..D {
                grad[a] = (dnum[a] - value * dwsum[a]) / wsum;
            }
        }
        (value, grad)
    }

    /// `f(p)` and `∇f(p)` (world units).
    pub fn value_and_gradient(&self, p: &Point<D>) -> (f64, Point<D>) {
        if !is_finite(p) {
            return (f64::NAN, [f64::NAN; D]);
        }
        let u = self.to_unit(p);
        let (mut v, mut g) = (0.0, [0.0; D]);
        for level in &self.levels {
            let (lv, lg) = self.level_offset(level, &u, true);
            v += lv;
            for a in 0..D {
                g[a] += lg[a];
            }
        }
        // Clamped directions have zero derivative outside the cube.
        for a in 0..D {
            let t = (p[a] - self.origin[a]) / self.side;
            if !(0.0..=1.0).contains(&t) {
                g[a] = 0.0;
            }
        }
        (v * self.side, g)
    }
}

/// The lattice cells around a point's home cell along the first `D − 1` axes (the coordinates
/// a grid row holds fixed) that lie in the lattice and whose partial squared distance leaves
/// the point within the support radius: what [`MrasField::blend`] pairs with the last axis's
/// three neighbours. In the order of the 3^D loop, the first axis fastest.
struct Columns<const D: usize> {
    /// The home cell along the first `D − 1` axes (the last entry unused).
    home: [u64; D],
    len: usize,
    cells: [Column<D>; MAX_COLUMNS],
}

/// The most columns, `3^{D−1}` for `D ≤ 4`.
const MAX_COLUMNS: usize = 27;

/// One of [`Columns`]: a lattice index, the offsets `u_a − centre_a` and `Σ_a (u_a − centre_a)²`
/// along the first `D − 1` axes (the last entries unused).
#[derive(Clone, Copy)]
struct Column<const D: usize> {
    index: [u64; D],
    d: [f64; D],
    r2: f64,
}

impl<const D: usize> Columns<D> {
    #[inline]
    fn new(g: &LevelGeometry, u: &Point<D>) -> Self {
        const { assert!(D >= 1 && D <= 4, "MRAS fields have 1 to 4 dimensions") };
        let n = g.lattice;
        let mut home = [0u64; D];
        for a in 0..D - 1 {
            home[a] = ((u[a] * n as f64) as u64).min(n - 1);
        }
        let mut columns = Self {
            home,
            len: 0,
            cells: [Column {
                index: [0; D],
                d: [0.0; D],
                r2: 0.0,
            }; MAX_COLUMNS],
        };
        let radius2 = g.radius * g.radius;
        'codes: for code in 0..3usize.pow(D as u32 - 1) {
            let mut column = columns.cells[0];
            let mut c = code;
            let mut r2 = 0.0;
            for a in 0..D - 1 {
                let Some(i) = (home[a] + (c % 3) as u64).checked_sub(1).filter(|&i| i < n) else {
                    continue 'codes;
                };
                c /= 3;
                column.index[a] = i;
                column.d[a] = u[a] - g.centre(i);
                r2 += column.d[a] * column.d[a];
            }
            // Adding the last axis's square cannot bring it back within the radius.
            if r2 >= radius2 {
                continue;
            }
            column.r2 = r2;
            columns.cells[columns.len] = column;
            columns.len += 1;
        }
        columns
    }
}

/// What [`MrasField::values`] keeps between consecutive points that differ in the last
/// coordinate only (a grid's rows, as [`zeroset_field_core::grid::Grid::sample`] passes them):
/// per CP cell met on the row, the last factor's rows contracted with the products of the
/// other axes' B-spline sums, `c_i = F_{D−1}[i,·] · Π_{a<D−1} g_{·,a}` for every `i < m`, so
/// that a point costs its last-axis B-spline weights and three products. The numbers are the
/// ones [`cp_rows`] forms, in its order, so the values keep its bits.
struct RowCache<const D: usize> {
    /// The fixed coordinates' bits (the last entry unused).
    key: Option<[u64; D]>,
    /// The row's number: a cell's coefficients are valid when stamped with it.
    generation: u32,
    levels: Vec<LevelRows<D>>,
    /// Scratch: one fixed axis's B-spline sums `g_{·,a}`, and their products over the fixed axes.
    scratch: (Vec<f64>, Vec<f64>),
}

/// [`RowCache`] of one level.
struct LevelRows<const D: usize> {
    /// The level's lattice neighbours along the row's fixed axes (set on the row's first point).
    columns: Option<Columns<D>>,
    cells: RowCoefficients,
}

/// The row's `c_i` of a level's CP cells: per cell (its position in the level) a stamp and an
/// offset into `coefficients`.
struct RowCoefficients {
    stamp: Vec<u32>,
    offset: Vec<u32>,
    coefficients: Vec<f64>,
}

impl<const D: usize> RowCache<D> {
    fn new(field: &MrasField<D>) -> Self {
        Self {
            key: None,
            generation: 0,
            levels: field
                .levels
                .iter()
                .map(|l| LevelRows {
                    columns: None,
                    cells: RowCoefficients {
                        stamp: vec![0; l.cells.len()],
                        offset: vec![0; l.cells.len()],
                        coefficients: Vec::new(),
                    },
                })
                .collect(),
            scratch: (Vec::new(), Vec::new()),
        }
    }

    /// Starts a new row unless `u` lies on the current one.
    fn enter(&mut self, u: &Point<D>) {
        let key = std::array::from_fn(|a| if a + 1 < D { u[a].to_bits() } else { 0 });
        if self.key != Some(key) {
            self.key = Some(key);
            if self.generation == u32::MAX {
                // Stamps would repeat: start them over.
                self.generation = 0;
                for l in &mut self.levels {
                    l.cells.stamp.fill(0);
                }
            }
            self.generation += 1;
            for l in &mut self.levels {
                l.columns = None;
                l.cells.coefficients.clear();
            }
        }
    }
}

impl RowCoefficients {
    /// `φ(u)` of the CP cell at `position` (rank `r`, factors `factors`, lattice index `index`)
    /// from the row's coefficients, forming them on the cell's first point of the row.
    #[allow(clippy::too_many_arguments)]
    fn cp_value<const D: usize>(
        &mut self,
        generation: u32,
        scratch: &mut (Vec<f64>, Vec<f64>),
        g: &LevelGeometry,
        position: usize,
        index: &[u64; D],
        factors: &[Vec<f64>; D],
        r: usize,
        u: &Point<D>,
    ) -> f64 {
        let m = g.knots;
        let weights_at = |a: usize| weights::<3>(g.spline_index(u[a], g.centre(index[a])));
        if self.stamp[position] != generation {
            self.stamp[position] = generation;
            // `head_k = Π_{a<D−1} Σ_q N_q F_a[first + q, k]`, as `cp_rows` forms it.
            let (sums, head) = scratch;
            head.clear();
            head.resize(r, 1.0);
            sums.resize(r, 0.0);
            for (a, factor) in factors[..D - 1].iter().enumerate() {
                let aw = weights_at(a);
                sums.fill(0.0);
                add_axis_sums(factor, m, aw.first as usize, &aw.w, sums);
                for (h, &x) in head.iter_mut().zip(&*sums) {
                    *h *= x;
                }
            }
            self.offset[position] = self.coefficients.len() as u32;
            let last = &factors[D - 1];
            self.coefficients
                .extend((0..m).map(|i| factor_dot(last, r, i, head)));
        }
        let aw = weights_at(D - 1);
        let start = self.offset[position] as usize;
        let c = &self.coefficients[start..start + m];
        stencil_sum(aw.first as usize, &aw.w, m, |i| c[i])
    }
}

impl<const D: usize> MrasField<D> {
    /// [`ScalarField::value`] with the row coefficients of `rows` (the same bits).
    fn value_along_row(&self, p: &Point<D>, rows: &mut RowCache<D>) -> f64 {
        let u = self.to_unit(p);
        rows.enter(&u);
        let generation = rows.generation;
        let mut v = 0.0;
        for (level, cache) in self.levels.iter().zip(&mut rows.levels) {
            let g = self.geometry(level);
            let scratch = &mut rows.scratch;
            let columns = cache.columns.get_or_insert_with(|| Columns::new(&g, &u));
            let cells = &mut cache.cells;
            v += self
                .blend(
                    level,
                    &g,
                    columns,
                    &u,
                    false,
                    |position, index| match &level.cells[position].spline {
                        CellSpline::Cp { rank, factors } if *rank <= FAST_RANK => {
                            let value = cells.cp_value(
                                generation, scratch, &g, position, index, factors, *rank, &u,
                            );
                            (value, [0.0; D])
                        }
                        other => spline_at(other, &g, index, &u, false),
                    },
                )
                .0;
        }
        v * self.side
    }
}

/// Ranks up to this are evaluated row-wise on the stack ([`cp_rows`]).
const FAST_RANK: usize = 64;

/// The B-splines one point reads in a cell: per axis the first of the (at most 3) indices,
/// their weights and derivatives (unit-cube units; 0 for the spline past the box).
struct Stencil<const D: usize> {
    first: [usize; D],
    w: [[f64; 3]; D],
    d1: [[f64; 3]; D],
}

/// [`cp_rows`] with stack buffers of the smallest of 4, 8, 16, 32 and [`FAST_RANK`] ranks that
/// holds `r` (zeroing a 64-rank buffer for a rank-1 cell was a fifth of an evaluation).
#[inline]
fn cp_rows_sized<const D: usize>(
    factors: &[Vec<f64>; D],
    r: usize,
    m: usize,
    s: &Stencil<D>,
    with_gradient: bool,
) -> (f64, [f64; D]) {
    match r {
        0..=4 => cp_rows::<D, 4>(factors, r, m, s, with_gradient),
        5..=8 => cp_rows::<D, 8>(factors, r, m, s, with_gradient),
        9..=16 => cp_rows::<D, 16>(factors, r, m, s, with_gradient),
        17..=32 => cp_rows::<D, 32>(factors, r, m, s, with_gradient),
        _ => cp_rows::<D, FAST_RANK>(factors, r, m, s, with_gradient),
    }
}

/// `φ` and its gradient from CP factors of rank `r ≤ N`: per axis, the weighted sum of
/// the (at most 3) factor rows the point reads, a contiguous loop over the ranks that the
/// compiler vectorises; then the products over all axes but the last, contracted with the last
/// axis's rows ([`stencil_sum`]). Same operations in the same order for
/// every point, so batched and single evaluation agree bit for bit.
#[inline]
fn cp_rows<const D: usize, const N: usize>(
    factors: &[Vec<f64>; D],
    r: usize,
    m: usize,
    s: &Stencil<D>,
    with_gradient: bool,
) -> (f64, [f64; D]) {
    debug_assert!(r <= N);
    let (first, w, d1) = (&s.first, &s.w, &s.d1);
    let mut gv = [[0.0; N]; D];
    let mut gd = [[0.0; N]; D];
    // The value reads the last axis's rows through `stencil_sum`; only the gradient needs its sums.
    let summed = if with_gradient { D } else { D - 1 };
    for a in 0..summed {
        add_axis_sums(&factors[a], m, first[a], &w[a], &mut gv[a][..r]);
        if with_gradient {
            add_axis_sums(&factors[a], m, first[a], &d1[a], &mut gd[a][..r]);
        }
    }
    // The value contracts the last axis through its factor rows (`Σ_q N_q (F[i_q,·] · head)`,
    // with `head_k = Π_{a<D−1} g_{k,a}`): the order [`MrasField::values`] keeps along grid rows.
    let mut head = [1.0; N];
    for (k, h) in head[..r].iter_mut().enumerate() {
        for g in &gv[..D - 1] {
            *h *= g[k];
        }
    }
    let last = &factors[D - 1];
    let value = stencil_sum(first[D - 1], &w[D - 1], m, |i| {
        factor_dot(last, r, i, &head[..r])
    });
    let mut grad = [0.0; D];
    if !with_gradient {
        return (value, grad);
    }
    for k in 0..r {
        for a in 0..D {
            let mut p = gd[a][k];
            for (b, g) in gv.iter().enumerate() {
                if b != a {
                    p *= g[k];
                }
            }
            grad[a] += p;
        }
    }
    (value, grad)
}

/// `Σ_q w_q c(first + q)` over the (at most 3) B-splines a point reads on one axis, those past
/// `m` left out. How every CP value ends, `c_i = F_{D−1}[i,·] · head` being the last factor's
/// row `i` contracted with the other axes' products: formed on the spot one point at a time
/// ([`cp_rows`]) or kept for a grid row ([`MrasField::values`]) — the same sum either way.
#[inline]
fn stencil_sum(first: usize, w: &[f64; 3], m: usize, c: impl Fn(usize) -> f64) -> f64 {
    let mut value = 0.0;
    for (q, &wq) in w.iter().enumerate() {
        let i = first + q;
        if i < m {
            value += wq * c(i);
        }
    }
    value
}

/// Whether every coordinate of `p` is finite: a NaN or infinite point gives NaN (its cell
/// index would overflow), as the other fields give.
fn is_finite<const D: usize>(p: &Point<D>) -> bool {
    p.iter().all(|v| v.is_finite())
}

/// `out_k += Σ_q w_q F[first + q, k]`: one axis's B-spline sums of a factor stored row-major
/// with `out.len()` columns (rows past `m` left out); a contiguous loop the compiler vectorises.
#[inline]
fn add_axis_sums(factor: &[f64], m: usize, first: usize, w: &[f64; 3], out: &mut [f64]) {
    let r = out.len();
    for (q, &wq) in w.iter().enumerate() {
        let i = first + q;
        if i >= m {
            continue;
        }
        for (o, &x) in out.iter_mut().zip(&factor[i * r..(i + 1) * r]) {
            *o += wq * x;
        }
    }
}

/// `F[i,·] · head` for a factor stored row-major with `r` columns.
#[inline]
fn factor_dot(factor: &[f64], r: usize, i: usize, head: &[f64]) -> f64 {
    factor[i * r..(i + 1) * r]
        .iter()
        .zip(head)
        .fold(0.0, |s, (&x, &h)| s + x * h)
}

/// `φ(u)` and its unit-cube gradient for one cell.
#[inline]
fn spline_at<const D: usize>(
    spline: &CellSpline<D>,
    g: &LevelGeometry,
    index: &[u64; D],
    u: &Point<D>,
    with_gradient: bool,
) -> (f64, Point<D>) {
    let m = g.knots;
    let mut first = [0usize; D];
    let mut w = [[0.0; 3]; D];
    let mut d1 = [[0.0; 3]; D];
    for a in 0..D {
        let x = g.spline_index(u[a], g.centre(index[a]));
        let aw = weights::<3>(x);
        first[a] = aw.first as usize;
        for q in 0..3 {
            // B-spline m sits past the box; its weight is 0 on it (x ≤ m − 3/2).
            if first[a] + q < m {
                w[a][q] = aw.w[q];
                d1[a][q] = aw.d1[q] / g.spacing;
            }
        }
    }
    match spline {
        CellSpline::Cp { rank, factors } => {
            let r = *rank;
            if r <= FAST_RANK {
                let stencil = Stencil { first, w, d1 };
                return cp_rows_sized(factors, r, m, &stencil, with_gradient);
            }
            let (mut value, mut grad) = (0.0, [0.0; D]);
            for k in 0..r {
                let mut gv = [0.0; D];
                let mut gd = [0.0; D];
                for a in 0..D {
                    let f = &factors[a];
                    for q in 0..3 {
                        let i = first[a] + q;
                        if i < m {
                            let x = f[i * r + k];
                            gv[a] += w[a][q] * x;
                            gd[a] += d1[a][q] * x;
                        }
                    }
                }
                value += gv.iter().product::<f64>();
                if with_gradient {
                    for a in 0..D {
                        let p = gv
                            .iter()
                            .enumerate()
                            .filter(|&(b, _)| b != a)
                            .fold(gd[a], |p, (_, g)| p * g);
                        grad[a] += p;
                    }
                }
            }
            (value, grad)
        }
        CellSpline::Full { coefficients } => {
            let (mut value, mut grad) = (0.0, [0.0; D]);
            for code in 0..3usize.pow(D as u32) {
                let mut c = code;
                let mut flat = 0usize;
                let mut q = [0usize; D];
                let mut skip = false;
                for a in 0..D {
                    q[a] = c % 3;
                    c /= 3;
                    let i = first[a] + q[a];
                    if i >= m {
                        skip = true;
                    }
                    flat = flat * m + i;
                }
                if skip {
                    continue;
                }
                let coef = coefficients[flat];
                let mut prod = coef;
                for a in 0..D {
                    prod *= w[a][q[a]];
                }
                value += prod;
                if with_gradient {
                    for a in 0..D {
                        let mut p = coef * d1[a][q[a]];
                        for b in 0..D {
                            if b != a {
                                p *= w[b][q[b]];
                            }
                        }
                        grad[a] += p;
                    }
                }
            }
            (value, grad)
        }
    }
}

impl<const D: usize> ScalarField<D> for MrasField<D> {
    fn value(&self, p: &Point<D>) -> f64 {
        if !is_finite(p) {
            return f64::NAN;
        }
        let u = self.to_unit(p);
        let mut v = 0.0;
        for level in &self.levels {
            v += self.level_offset(level, &u, false).0;
        }
        v * self.side
    }

    fn gradient(&self, p: &Point<D>) -> Point<D> {
        self.value_and_gradient(p).1
    }

    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        assert_eq!(
            points.len(),
            out.len(),
            "MrasField::values: {} points but {} output slots",
            points.len(),
            out.len()
        );
        points
            .par_chunks(CHUNK)
            .zip(out.par_chunks_mut(CHUNK))
            // One row cache per rayon job, not per chunk: its tables grow with the field's cells.
            .for_each_init(
                || RowCache::new(self),
                |rows, (ps, os)| {
                    for (p, o) in ps.iter().zip(os) {
                        *o = if is_finite(p) {
                            self.value_along_row(p, rows)
                        } else {
                            f64::NAN
                        };
                    }
                },
            );
    }

    /// The recorded points' box grown by 5% of its diagonal on every side (as an RBF field's),
    /// within the cube; the cube where no points are recorded. Meshing and restoring sample
    /// this box: the cube, a slab's longest side on every axis, left a 2 × 2 × 0.02 plate
    /// meshed 38% thin at fine detail (its thin axis never reached the l0 rule).
    fn bounds(&self) -> Option<Aabb<D>> {
        let mut max = self.origin;
        for m in &mut max {
            *m += self.side;
        }
        let cube = Aabb::new(self.origin, max).ok()?;
        let Some(first) = self.points.first() else {
            return Some(cube);
        };
        let (mut lo, mut hi) = (first.map(f64::from), first.map(f64::from));
        for p in &self.points {
            for a in 0..D {
                lo[a] = lo[a].min(f64::from(p[a]));
                hi[a] = hi[a].max(f64::from(p[a]));
            }
        }
        let world = |u: [f64; D]| -> Point<D> {
            std::array::from_fn(|a| self.origin[a] + self.side * u[a])
        };
        let points = Aabb::new(world(lo), world(hi)).ok()?;
        let grown = points.expanded(0.05 * points.diagonal());
        let min = std::array::from_fn(|a| grown.min()[a].max(cube.min()[a]));
        let max = std::array::from_fn(|a| grown.max()[a].min(cube.max()[a]));
        Aabb::new(min, max).ok().or(Some(cube))
    }

    /// The sum over the levels of each level's enclosure (see `level_range`): per cell whose
    /// support box meets the region, its offset at the region's centre widened by its
    /// coefficients' largest differences times the region's half-extent — per cell one offset
    /// evaluated and a window of coefficients formed, in all 7–32 times the work of one
    /// `value` (the bunny's field, a box of 1% of the cube: 45 µs against 4.6 µs; measured in
    /// review). Tight for small regions, loose where the fine levels' cells disagree; far from
    /// the surface only the coarse levels have cells and their values clear the level set.
    /// `None` for a region that is not finite.
    fn value_range(&self, region: &Aabb<D>) -> Option<[f64; 2]> {
        let (min, max) = (region.min(), region.max());
        if !(is_finite(&min) && is_finite(&max)) {
            return None;
        }
        // Points outside the cube are clamped onto it: so is the region.
        let (lo_u, hi_u) = (self.to_unit(&min), self.to_unit(&max));
        let (mut lo, mut hi) = (0.0, 0.0);
        for level in &self.levels {
            let [l, h] = self.level_range(level, &lo_u, &hi_u);
            lo += l;
            hi += h;
        }
        let [lo, hi] = widened(lo, hi);
        Some([lo * self.side, hi * self.side])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Σ_i w_i(u) over the level's lattice (what the blend divides by).
    fn weight_sum(level: u32, alpha: f64, u: [f64; 3]) -> f64 {
        let g = LevelGeometry::new(3, level, 6, alpha);
        let n = g.lattice;
        let mut s = 0.0;
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let c = [g.centre(i), g.centre(j), g.centre(k)];
                    let r = ((u[0] - c[0]).powi(2) + (u[1] - c[1]).powi(2) + (u[2] - c[2]).powi(2))
                        .sqrt();
                    s += pu_weight(r, g.radius).0;
                }
            }
        }
        s
    }

    #[test]
    fn partition_of_unity_covers_the_whole_domain() {
        // Corners, edge midpoints and face centres of cells (the points farthest from centres),
        // and a deterministic scatter, at levels 1–4.
        let mut rng = zeroset_field_core::rng::SplitMix64::new(0x9e37_79b9_7f4a_7c15);
        let mut next = || rng.unit();
        for level in 1..=4u32 {
            let s = 1.0 / f64::from(1u32 << (level - 1));
            let mut probes = vec![
                [0.0; 3],
                [1.0; 3],
                [s, 0.5 * s, 0.0],
                [0.5 * s, 0.5 * s, 0.0],
            ];
            probes.extend((0..200).map(|_| [next(), next(), next()]));
            for u in probes {
                let w = weight_sum(level, 0.75, u);
                assert!(w > 0.05, "level {level}: Σw = {w} at {u:?}");
            }
        }
        // The paper's radius read as half the diagonal (α·R = 0.65 s) leaves a cell's edge
        // midpoints uncovered: Σw = 0 there. That is why R is the full diagonal.
        let half = 0.75 * 3f64.sqrt() / 2.0;
        let g = LevelGeometry::new(3, 2, 6, 0.75);
        let edge_midpoint_distance = (2.0f64).sqrt() / 2.0 * g.side;
        assert!(half * g.side < edge_midpoint_distance);
        assert!(g.radius > 3f64.sqrt() / 2.0 * g.side);
    }

    #[test]
    fn a_cell_left_out_blends_as_a_zero_offset() {
        // A fit stores no cell whose offset φ = 0 meets its compression bound: the blend must
        // count a missing cell exactly as a stored φ = 0 (its weight stays in Σw).
        let m = 5;
        let ramp = |k: u32| CellSpline::<3>::Cp {
            rank: 1,
            factors: [
                (0..m).map(|i| 0.01 * (i as f64 + f64::from(k))).collect(),
                vec![1.0; m],
                (0..m).map(|i| 1.0 - 0.1 * i as f64).collect(),
            ],
        };
        let zero = CellSpline::<3>::Cp {
            rank: 1,
            factors: [vec![0.0; m], vec![0.0; m], vec![0.0; m]],
        };
        let cell = |index, spline| MrasCell { index, spline };
        let with_zero = vec![
            cell([0, 0, 0], ramp(1)),
            cell([1, 0, 0], zero),
            cell([1, 1, 0], ramp(2)),
        ];
        let without: Vec<_> = vec![cell([0, 0, 0], ramp(1)), cell([1, 1, 0], ramp(2))];
        let root = || MrasLevel::new(1, m, vec![cell([0, 0, 0], ramp(0))]).unwrap();
        let levels = |cells| vec![root(), MrasLevel::new(2, m, cells).unwrap()];
        let a = MrasField::new([0.0; 3], 1.0, 0.75, levels(with_zero)).unwrap();
        let b = MrasField::new([0.0; 3], 1.0, 0.75, levels(without)).unwrap();
        let mut rng = zeroset_field_core::rng::SplitMix64::new(7);
        for _ in 0..500 {
            let p = [rng.unit(), rng.unit(), 0.5 * rng.unit()];
            let (va, ga) = a.value_and_gradient(&p);
            let (vb, gb) = b.value_and_gradient(&p);
            assert_eq!(va, vb, "at {p:?}");
            assert_eq!(ga, gb, "at {p:?}");
        }
        // Not a comparison of zeros: level 2 adds to the root inside the zero cell too.
        let u = [0.75, 0.25, 0.25];
        let root_only = MrasField::new([0.0; 3], 1.0, 0.75, vec![root()]).unwrap();
        assert!((a.value(&u) - root_only.value(&u)).abs() > 1e-4);
    }

    #[test]
    fn level_checks_its_cells() {
        let cp = |rank: usize, len: usize| CellSpline::<3>::Cp {
            rank,
            factors: [vec![1.0; len], vec![1.0; len], vec![1.0; len]],
        };
        let cell = |index, spline| MrasCell { index, spline };
        assert!(MrasLevel::new(2, 5, vec![cell([0, 1, 1], cp(2, 10))]).is_ok());
        assert!(MrasLevel::new(2, 5, vec![cell([2, 0, 0], cp(2, 10))]).is_err());
        assert!(MrasLevel::new(2, 5, vec![cell([0, 0, 0], cp(2, 9))]).is_err());
        assert!(
            MrasLevel::new(
                2,
                5,
                vec![cell([0, 0, 0], cp(1, 5)), cell([0, 0, 0], cp(1, 5))]
            )
            .is_err()
        );
        let nan = CellSpline::Full {
            coefficients: vec![f64::NAN; 125],
        };
        assert!(MrasLevel::new(1, 5, vec![cell([0, 0, 0], nan)]).is_err());
        assert!(MrasLevel::<3>::new(0, 5, vec![]).is_err());
        assert!(MrasField::<3>::new([0.0; 3], 1.0, 0.5, vec![]).is_err());
    }
}
