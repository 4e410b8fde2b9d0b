//! One cell's local fit (paper 004 §5.2–5.4): assemble the quadratic energy of eq. 14, minimise
//! it plus the trace norm by ADMM (the c-step matrix factored once), and compress the
//! coefficient tensor by CP-ALS with Algorithm 2's adaptive rank.

use faer::Mat;
use zeroset_field_core::geometry::Point;
use zeroset_solvers::admm::{AdmmOptions, ProxTerm, Quadratic, TraceNormTerm};
use zeroset_tensor::cp::{search_from_below, svd_start};
use zeroset_tensor::{
    CpInit, CpOptions, Kruskal, Tensor3, WeightedOptions, cp_als, cp_als_weighted, thin_svd,
};

use super::MrasError;
use super::field::{CellSpline, LevelGeometry};
use crate::bspline::stencil::weights;

/// The 1-D Gram matrices `∫ N_i^{(q)} N_j^{(q)}` (`q = 0, 1, 2`) of the `m` B-splines over the
/// support box, in the box's local coordinate `t ∈ [0, 1]`, and the thin-plate matrix
/// `T = Σ_a M₂^{(a)} ⊗ M₀ ⊗ M₀ + 2 Σ_{a<b} M₁^{(a)} ⊗ M₁^{(b)} ⊗ M₀` with
/// `cᵀTc = ∭_{[0,1]³} ‖∇²φ‖_F²` (the Hessian in local coordinates, so that the term weighs the
/// same at every level).
#[derive(Debug, Clone)]
pub(crate) struct ThinPlate {
    m: usize,
    /// `T` by rows: `(column, value)` pairs of the (at most 125) non-zeros of each row.
    rows: Vec<Vec<(u32, f64)>>,
}

impl ThinPlate {
    pub(crate) fn new(m: usize) -> Self {
        // Gauss–Legendre, 3 points: exact for the degree-4 products on each knot interval.
        let gl = [
            (-(0.6f64).sqrt() / 2.0 + 0.5, 5.0 / 18.0),
            (0.5, 8.0 / 18.0),
            ((0.6f64).sqrt() / 2.0 + 0.5, 5.0 / 18.0),
        ];
        let mut gram = [vec![0.0; m * m], vec![0.0; m * m], vec![0.0; m * m]];
        // Knot intervals [j + ½, j + 3/2], j = 0 … m − 3, in B-spline index space.
        for j in 0..m - 2 {
            for &(s, wq) in &gl {
                let x = j as f64 + 0.5 + s;
                let aw = weights::<3>(x);
                let vals = [aw.w, aw.d1, aw.d2];
                for (q, v) in vals.iter().enumerate() {
                    for a in 0..3 {
                        let ia = aw.first + a as isize;
                        if ia < 0 || ia as usize >= m {
                            continue;
                        }
                        for b in 0..3 {
                            let ib = aw.first + b as isize;
                            if ib < 0 || ib as usize >= m {
                                continue;
                            }
                            gram[q][ia as usize * m + ib as usize] += wq * v[a] * v[b];
                        }
                    }
                }
            }
        }
        // Index space → local t: x = ½ + t(m − 2); d/dt = (m − 2) d/dx, dt = dx/(m − 2).
        let k = (m - 2) as f64;
        for (q, g) in gram.iter_mut().enumerate() {
            let scale = k.powi(2 * q as i32 - 1);
            g.iter_mut().for_each(|v| *v *= scale);
        }
        let n = m * m * m;
        let mut rows = vec![Vec::new(); n];
        // (q_x, q_y, q_z, multiplicity): Hessian entries ∂²/∂a∂b.
        let terms = [
            (2, 0, 0, 1.0),
            (0, 2, 0, 1.0),
            (0, 0, 2, 1.0),
            (1, 1, 0, 2.0),
            (1, 0, 1, 2.0),
            (0, 1, 1, 2.0),
        ];
        let band = |i: usize| i.saturating_sub(2)..(i + 3).min(m);
        for i in 0..m {
            for j in 0..m {
                for l in 0..m {
                    let row = (i * m + j) * m + l;
                    for i2 in band(i) {
                        for j2 in band(j) {
                            for l2 in band(l) {
                                let col = (i2 * m + j2) * m + l2;
                                let mut v = 0.0;
                                for &(qx, qy, qz, mult) in &terms {
                                    v += mult
                                        * gram[qx][i * m + i2]
                                        * gram[qy][j * m + j2]
                                        * gram[qz][l * m + l2];
                                }
                                rows[row].push((col as u32, v));
                            }
                        }
                    }
                }
            }
        }
        Self { m, rows }
    }

    /// `cᵀ T c`.
    #[cfg(test)]
    pub(crate) fn energy(&self, c: &[f64]) -> f64 {
        let mut e = 0.0;
        for (i, row) in self.rows.iter().enumerate() {
            let s: f64 = row.iter().map(|&(j, v)| v * c[j as usize]).sum();
            e += c[i] * s;
        }
        e
    }
}

/// One data point of a local fit: unit-cube position, the value the offset must reach
/// (`−f^{k−1}(p)`) and the gradient it must reach (`n − ∇f^{k−1}(p)`), and how many times
/// [`CpBound::Points`]' `ε` the compression may change the offset there (`slack > 0`: more
/// than 1 where a finer level will fit the point again, less where the field so far is flat,
/// so that the bound is on the distance).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Target {
    pub u: Point<3>,
    pub value: f64,
    pub gradient: Point<3>,
    pub slack: f64,
}

/// The largest tolerance, as a fraction of the box diagonal, whose `ε₀` scales the trace-norm
/// weight `τ = λ ε₀² / (a √m³)`: a looser `--tolerance` loosens the subdivision and the CP
/// bound, not `τ` further. `τ` grows with `ε₀²`, and past this it outweighs the normal term
/// and shrinks every offset to nothing: a unit sphere (20k points) at a tolerance of 0.03 meshed
/// as 10 components with `|∇f| ≈ 0.01` at the points, at 0.1 the field was 0 everywhere; the
/// bunny sample at 0.03–0.05 had 20–292 components. With the weight held at 1%'s: one closed
/// component each (sphere at 0.03 / 0.1: 70 / 309 numbers; bunny at 0.03 / 0.05 / 0.2: 5,276 /
/// 3,342 / 1,731; the torus at 0.05–0.5 genus 1). Tolerances up to 1% fit as before (the
/// bunny's at 0.02 too).
pub(crate) const LAMBDA_SCALE_CAP: f64 = 0.01;

/// The weights of the local energy and its solver.
#[derive(Debug, Clone)]
pub(crate) struct LocalSettings {
    pub omega1: f64,
    pub omega2: f64,
    /// The trace-norm weight in the energy per point (the user's `λ` times `ε₀`).
    pub lambda: f64,
    /// A value scale (`ε₀`, unit-cube units) for ADMM's absolute tolerance.
    pub value_scale: f64,
    /// The value scale of the trace-norm weight: `ε₀`, capped (see [`LAMBDA_SCALE_CAP`]).
    pub lambda_scale: f64,
    /// Whether `φ = 0` may stand for the cell (rank 0): not at the root level, whose offset is
    /// the whole field (`f⁰ = 0`), so that `φ = 0` has no surface however small it is at the
    /// points.
    pub zero_allowed: bool,
    pub eta: f64,
    pub relaxation: f64,
    pub admm_max_iter: usize,
    pub admm_tol: f64,
    /// How far the CP factors may be from the tensor; `None`: keep the full tensor (the
    /// uncompressed MRAS).
    pub cp_bound: Option<CpBound>,
}

/// What one cell's fit produced.
#[cfg(test)]
#[derive(Debug, Clone)]
pub(crate) struct LocalFit {
    /// `None`: `φ = 0` meets the CP bound (Algorithm 2 at rank 0), so the cell is not stored —
    /// the blend counts a cell that is not stored as `φ = 0`, so leaving it out is exact.
    pub spline: Option<CellSpline<3>>,
    pub admm_iterations: usize,
    /// `‖C − Ĉ‖` of the CP approximation (0 for a full tensor).
    pub cp_error: f64,
}

/// One cell's minimiser of eq. 14, before compression.
#[derive(Debug, Clone)]
pub(crate) struct CellSolve {
    /// The coefficient tensor; `None` where the screen found `φ = 0` within the CP bound at
    /// every point before ADMM (rank 0: not stored).
    pub coefficients: Option<Vec<f64>>,
    pub admm_iterations: usize,
    /// The screen's error (the largest `|φ| / slack` of the fit without the trace norm at the
    /// points) for a screened cell, 0 otherwise.
    pub screen_error: f64,
}

/// Fits and compresses one cell: [`solve_cell`] then [`compress_cell`].
#[cfg(test)]
pub(crate) fn fit_cell(
    g: &LevelGeometry,
    index: [u64; 3],
    targets: &[Target],
    plate: &ThinPlate,
    s: &LocalSettings,
) -> Result<LocalFit, MrasError> {
    let solved = solve_cell(g, index, targets, plate, s)?;
    let (spline, cp_error) = match solved.coefficients {
        None => (None, solved.screen_error),
        Some(c) => compress_cell(g, index, targets, c, s.cp_bound, s.zero_allowed)?,
    };
    Ok(LocalFit {
        spline,
        admm_iterations: solved.admm_iterations,
        cp_error,
    })
}

/// A data point's quadratic B-splines in a cell's support box: the 1-D values and derivatives
/// (unit-cube units) over its knot interval, which starts at B-spline `first`. Their 27 tensor
/// products are formed where they are used ([`PointBasis::expand`]), so that a cell of a
/// million points holds 168 bytes a point here rather than the 888 of the products.
struct PointBasis {
    first: [usize; 3],
    w: [[f64; 3]; 3],
    d1: [[f64; 3]; 3],
}

impl PointBasis {
    fn new(g: &LevelGeometry, centre: &Point<3>, u: &Point<3>) -> Self {
        let m = g.knots;
        let mut first = [0usize; 3];
        let mut w = [[0.0; 3]; 3];
        let mut d1 = [[0.0; 3]; 3];
        for a in 0..3 {
            let aw = weights::<3>(g.spline_index(u[a], centre[a]));
            first[a] = aw.first as usize;
            for q in 0..3 {
                if first[a] + q < m {
                    w[a][q] = aw.w[q];
                    d1[a][q] = aw.d1[q] / g.spacing;
                }
            }
        }
        Self { first, w, d1 }
    }

    /// The 27 tensor-product values and their gradients, local basis function `k = (9i + 3j +
    /// l)` the product of the 1-D splines `i`, `j`, `l` along x, y, z.
    fn expand(&self) -> ([f64; 27], [[f64; 27]; 3]) {
        let (w, d1) = (&self.w, &self.d1);
        let mut val = [0.0; 27];
        let mut grad = [[0.0; 27]; 3];
        for i in 0..3 {
            for j in 0..3 {
                for l in 0..3 {
                    let k = (i * 3 + j) * 3 + l;
                    val[k] = w[0][i] * w[1][j] * w[2][l];
                    grad[0][k] = d1[0][i] * w[1][j] * w[2][l];
                    grad[1][k] = w[0][i] * d1[1][j] * w[2][l];
                    grad[2][k] = w[0][i] * w[1][j] * d1[2][l];
                }
            }
        }
        (val, grad)
    }

    /// The knot interval, as the flat index of its first coefficient.
    fn key(&self, m: usize) -> usize {
        (self.first[0] * m + self.first[1]) * m + self.first[2]
    }

    /// The flat index of local basis function `k` (of 27), if it is inside the `m³` tensor.
    fn global(&self, m: usize, k: usize) -> Option<usize> {
        let f = self.first;
        let (a, b, c) = (f[0] + k / 9, f[1] + (k / 3) % 3, f[2] + k % 3);
        (a < m && b < m && c < m).then_some((a * m + b) * m + c)
    }

    /// The point's row of the evaluation matrix, with its target's `slack`.
    fn row(&self, m: usize, slack: f64) -> Row {
        let mut row = Row {
            len: 0,
            idx: [0; 27],
            val: [0.0; 27],
            inv_slack: 1.0 / slack,
        };
        let (val, _) = self.expand();
        for (k, &v) in val.iter().enumerate() {
            if let Some(i) = self.global(m, k) {
                // i < m³, and the cell's dense m³ × m³ matrix already bounds m³ far below 2³².
                debug_assert!(i <= u32::MAX as usize);
                row.idx[row.len] = i as u32;
                row.val[row.len] = v;
                row.len += 1;
            }
        }
        row
    }
}

/// Minimises eq. 14 over one cell's coefficients (centre index `index` on the level of
/// geometry `g`) for `targets`: the fit without the trace norm, then ADMM from it — unless the
/// screen finds `φ = 0` within `s.cp_bound` at every point.
pub(crate) fn solve_cell(
    g: &LevelGeometry,
    index: [u64; 3],
    targets: &[Target],
    plate: &ThinPlate,
    s: &LocalSettings,
) -> Result<CellSolve, MrasError> {
    let m = g.knots;
    debug_assert_eq!(plate.m, m);
    let n = m * m * m;
    let centre = [g.centre(index[0]), g.centre(index[1]), g.centre(index[2])];
    // Normal equations of Σ (φ − y)² + ω₁ Σ ‖∇φ − t‖²: H' c = b'. Points in the same knot
    // interval read the same 27 coefficients: their 27 × 27 blocks are summed in a small dense
    // buffer and added to H once per interval (a scattered add per point into the m³ × m³
    // matrix was the fit's largest cost).
    let mut hm = Mat::<f64>::zeros(n, n);
    let mut b = vec![0.0; n];
    let bases: Vec<PointBasis> = targets
        .iter()
        .map(|t| PointBasis::new(g, &centre, &t.u))
        .collect();
    let o1 = s.omega1;
    for (p, t) in bases.iter().zip(targets) {
        let (val, grad) = p.expand();
        for k in 0..27 {
            if let Some(i) = p.global(m, k) {
                b[i] += val[k] * t.value
                    + o1 * (grad[0][k] * t.gradient[0]
                        + grad[1][k] * t.gradient[1]
                        + grad[2][k] * t.gradient[2]);
            }
        }
    }
    let mut order: Vec<usize> = (0..bases.len()).collect();
    order.sort_by_key(|&i| bases[i].key(m));
    let mut block = [[0.0f64; 27]; 27];
    let mut start = 0;
    while start < order.len() {
        let interval = &bases[order[start]];
        let key = interval.key(m);
        let mut end = start;
        for row in block.iter_mut() {
            row.fill(0.0);
        }
        // The block is symmetric: its upper triangle (q ≥ p) only, mirrored in the scatter.
        while end < order.len() && bases[order[end]].key(m) == key {
            let (val, grad) = bases[order[end]].expand();
            for (p, row) in block.iter_mut().enumerate() {
                let (vp, g0, g1, g2) = (
                    val[p],
                    s.omega1 * grad[0][p],
                    s.omega1 * grad[1][p],
                    s.omega1 * grad[2][p],
                );
                for q in p..27 {
                    row[q] += vp * val[q] + g0 * grad[0][q] + g1 * grad[1][q] + g2 * grad[2][q];
                }
            }
            end += 1;
        }
        let global = |k: usize| interval.global(m, k);
        for (p, row) in block.iter().enumerate() {
            let Some(gp) = global(p) else { continue };
            let col = hm.col_as_slice_mut(gp);
            for (q, (&upper, mirror)) in row.iter().zip(&block).enumerate() {
                if let Some(gq) = global(q) {
                    col[gq] += if q >= p { upper } else { mirror[p] };
                }
            }
        }
        start = end;
    }
    // The energy per data point, (1/N)(Σ (φ − y)² + ω₁ Σ ‖∇φ − t‖²) + ω₂ ∭‖∇²φ‖², so that the
    // weights balance the same way at every level and sampling density. ADMM minimises
    // ½cᵀHc − bᵀc: H = 2(H'/N + ω₂T), b = 2b'/N.
    let inv = 1.0 / targets.len().max(1) as f64;
    for j in 0..n {
        for v in hm.col_as_slice_mut(j) {
            *v *= 2.0 * inv;
        }
    }
    // T is in the box's local coordinates (Hessian × S², S = 2ρ the box side): divide by S⁴
    // for the mean of ‖∇²φ‖² over the box in unit-cube coordinates, a curvature that means the
    // same at every level.
    let box_side = 2.0 * g.half_box;
    let smooth = 2.0 * s.omega2 / box_side.powi(4);
    for (i, row) in plate.rows.iter().enumerate() {
        let col = hm.col_as_slice_mut(i);
        for &(j, v) in row {
            col[j as usize] += smooth * v;
        }
    }
    b.iter_mut().for_each(|v| *v *= 2.0 * inv);
    // η in units of H's mean diagonal (the paper's η = 1 is for its unnormalised energy).
    let mean_diag = (0..n).map(|i| hm[(i, i)]).sum::<f64>() / n as f64;
    let shape = [m, m, m];
    // H and b are checked once for both solves.
    let problem = Quadratic::new(hm.as_ref(), &b)?;
    let start = problem.ridge_solution(1e-12 * mean_diag)?;
    // A screen: where even the offset the data asks for without the trace norm stays within the
    // CP bound at every point, `φ = 0` will do (rank 0) and ADMM need not run. (On the bunny,
    // when the screen came, the ADMM offset then met the bound too in all but 1 of 728 cells.
    // The fit screens with the refinement slack at 1 — the tightest bound compression may get,
    // both scaled by the same steepness — so a screened cell is one the compression would
    // drop too.)
    if let Some(bound) = s.cp_bound.filter(|_| s.zero_allowed) {
        let rows: Vec<Row> = bases
            .iter()
            .zip(targets)
            .map(|(p, t)| p.row(m, t.slack))
            .collect();
        let error = zero_error(&start, bound, &rows);
        if error <= bound.epsilon() {
            return Ok(CellSolve {
                coefficients: None,
                admm_iterations: 0,
                screen_error: error,
            });
        }
    }
    // λ is made dimensionless: the trace norm of the offset costs about λ ε₀² √rank whatever
    // its amplitude a (the start's RMS coefficient, at least ε₀), as much as a residual of ε₀
    // at every point — at every level and density. (Unscaled, it would flatten the root
    // level, whose amplitude only the weak normal term holds.)
    let amplitude = (start.iter().map(|v| v * v).sum::<f64>() / n as f64)
        .sqrt()
        .max(s.value_scale);
    let weight = s.lambda * s.lambda_scale * s.lambda_scale / (amplitude * (n as f64).sqrt());
    let terms = TraceNormTerm::mras_terms(shape, weight)?;
    let refs: Vec<&dyn ProxTerm> = terms.iter().map(|t| t as &dyn ProxTerm).collect();
    let opts = AdmmOptions::default()
        .start(start)
        .eta(s.eta * mean_diag)
        .relaxation(s.relaxation)
        .max_iter(s.admm_max_iter)
        .eps_abs(s.admm_tol * s.value_scale)
        .eps_rel(s.admm_tol);
    let sol = problem.admm(&refs, &opts)?;
    // The split variables z_i are exactly low-rank unfoldings (c is only close): their mean,
    // folded back, is the tensor to compress.
    let mut c = vec![0.0; n];
    for (t, z) in terms.iter().zip(&sol.z) {
        t.apply_transpose_add(z, &mut c);
    }
    c.iter_mut().for_each(|v| *v /= terms.len() as f64);
    Ok(CellSolve {
        coefficients: Some(c),
        admm_iterations: sol.iterations,
        screen_error: 0.0,
    })
}

/// Stores one cell's coefficients `c` (from [`solve_cell`] on the same cell and targets): as
/// CP factors of the smallest rank Algorithm 2 finds within `bound` at the targets (each
/// allowed its `slack`), `None` where `φ = 0` already is; the full tensor without a bound.
/// Returns the spline and the error it stopped at.
pub(crate) fn compress_cell(
    g: &LevelGeometry,
    index: [u64; 3],
    targets: &[Target],
    c: Vec<f64>,
    bound: Option<CpBound>,
    zero_allowed: bool,
) -> Result<(Option<CellSpline<3>>, f64), MrasError> {
    let m = g.knots;
    let Some(bound) = bound else {
        return Ok((Some(CellSpline::Full { coefficients: c }), 0.0));
    };
    let centre = [g.centre(index[0]), g.centre(index[1]), g.centre(index[2])];
    let rows: Vec<Row> = targets
        .iter()
        .map(|t| PointBasis::new(g, &centre, &t.u).row(m, t.slack))
        .collect();
    compress(c, m, bound, &rows, zero_allowed)
}

/// CP-ALS stops when its relative error changes by less than this between sweeps …
const CP_TOL: f64 = 1e-5;
/// … or after this many sweeps (the bound is checked after; a rank that stalls grows).
const CP_MAX_ITER: usize = 60;

/// Weighted sweeps at most per rank tried (30: 0.7% fewer numbers, 0.6 s more on the bunny).
const CP_WEIGHTED_MAX_ITER: usize = 15;
/// The weighted sweeps stop when their relative error changes by less than this.
const CP_WEIGHTED_TOL: f64 = 1e-6;
/// The weight of a coefficient no data point reads, relative to the most-read coefficient's,
/// in the weighted CP fit. Such coefficients still shape the field between and beside the
/// points: with 0 the bunny, the kitten and their noisy copies all meshed with 5–10
/// components (sheets up to 0.47 of the diagonal from any point); 1e-4 and 1e-3 keep one on
/// all of them. Bunny / kitten numbers: 1e-2 → 230k / 75.7k, **1e-3 → 218k / 68.2k**,
/// 1e-4 → 211k / 65.8k, 0 → 210k / 64.8k; max distances within 2% of each other.
const CP_UNSEEN_WEIGHT: f64 = 1e-3;

/// The error Algorithm 2 grows the CP rank until it meets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CpBound {
    /// The paper's `‖C − Ĉ‖_F ≤ ε` over the whole tensor.
    Tensor(f64),
    /// `|φ̂ − φ| ≤ ε` at every data point of the cell: the error where the surface is.
    Points(f64),
    /// The bound of [`CpBound::Points`], each rank fitted first by plain CP-ALS and then, if
    /// that misses the bound, by CP-ALS weighted by how much the data points read each
    /// coefficient ([`point_weights`]): the plain fit spends rank on coefficients no point
    /// reads.
    PointsWeighted(f64),
}

impl CpBound {
    /// The bound's `ε`.
    fn epsilon(self) -> f64 {
        match self {
            CpBound::Tensor(e) | CpBound::Points(e) | CpBound::PointsWeighted(e) => e,
        }
    }

    /// Whether the bound is at the data points (not over the whole tensor).
    pub(crate) fn at_points(self) -> bool {
        !matches!(self, CpBound::Tensor(_))
    }
}

/// The error of `φ = 0` (rank 0) for coefficients `c` under `bound`: `‖C‖_F`, or the largest
/// `|φ|` at the data points.
fn zero_error(c: &[f64], bound: CpBound, rows: &[Row]) -> f64 {
    match bound {
        CpBound::Tensor(_) => c.iter().map(|v| v * v).sum::<f64>().sqrt(),
        _ => max_at_points(rows, |i| c[i]),
    }
}

/// The weights of the `m³` coefficients for the weighted CP fit: `W_c = Σ_p (B_c(x_p)/s_p)²`,
/// the diagonal of the points' least-squares form `Σ_p (Σ_c B_c(x_p) e_c / s_p)²` (`s_p` the
/// point's slack), plus [`CP_UNSEEN_WEIGHT`] times the largest, so that the coefficients no
/// point reads keep a hold on the fit.
fn point_weights(rows: &[Row], m: usize) -> Vec<f64> {
    let mut w = vec![0.0; m * m * m];
    for r in rows {
        for k in 0..r.len {
            let v = r.val[k] * r.inv_slack;
            w[r.idx[k] as usize] += v * v;
        }
    }
    let floor = CP_UNSEEN_WEIGHT * w.iter().copied().fold(0.0, f64::max);
    w.iter_mut().for_each(|v| *v += floor);
    w
}

/// `max_p |Σ_k row_p[k] · coefficient(idx_p[k])| / slack_p` over the data points' rows.
fn max_at_points(rows: &[Row], coefficient: impl Fn(usize) -> f64) -> f64 {
    rows.iter()
        .map(|r| {
            (0..r.len)
                .map(|k| r.val[k] * coefficient(r.idx[k] as usize))
                .sum::<f64>()
                .abs()
                * r.inv_slack
        })
        .fold(0.0, f64::max)
}

/// One data point's basis row (up to 27 entries) and `1 / slack` of its target.
struct Row {
    len: usize,
    idx: [u32; 27],
    val: [f64; 27],
    inv_slack: f64,
}

/// CP factors of the `m³` tensor `c` by Algorithm 2, made scale-free and tightened:
///
/// - the rank starts at `R⁰ = ⌈Σ γ_i ‖C_(i)‖_* / ‖C‖_F⌉` — the paper's `⌈Σ γ_i ‖C_(i)‖_*⌉`
///   divided by the tensor's norm, so that it does not depend on the units of the coefficients
///   (1 for a rank-1 tensor, `√r` for `r` equal singular values: never above the rank of the
///   unfoldings) — after rank 0: where `φ = 0` itself meets `bound`, nothing is stored (`None`);
/// - it grows by the paper's `⌈3 ln(error/ε)⌉` until `bound` holds (the natural log);
/// - then it searches the ranks between the last that failed and the first that held from below
///   ([`search_from_below`]), so the stored rank is not the overshoot of the growth's last step
///   (against plain bisection of that gap: the bunny's field identical, the kitten's 69,910
///   numbers instead of 69,862 at the same errors);
/// - capped at `m²/3` (where CP factors stop being smaller than the tensor): the full tensor
///   where the cap does not meet the bound.
fn compress(
    c: Vec<f64>,
    m: usize,
    bound: CpBound,
    rows: &[Row],
    zero_allowed: bool,
) -> Result<(Option<CellSpline<3>>, f64), MrasError> {
    let x = Tensor3::new([m, m, m], c).map_err(MrasError::Tensor)?;
    let norm = x.as_slice().iter().map(|v| v * v).sum::<f64>().sqrt();
    let eps = bound.epsilon();
    // Rank 0.
    let error = zero_error(x.as_slice(), bound, rows);
    if zero_allowed && error <= eps {
        return Ok((None, error));
    }
    let cap = (m * m / 3).max(1);
    // Each unfolding's SVD, once: its singular values give the starting rank, its left
    // singular vectors every attempt's starting factors.
    let mut trace = 0.0;
    let mut bases: [Mat<f64>; 3] = std::array::from_fn(|_| Mat::zeros(0, 0));
    for (mode, basis) in bases.iter_mut().enumerate() {
        let svd = thin_svd(x.unfold(mode).map_err(MrasError::Tensor)?.as_ref())
            .map_err(MrasError::Tensor)?;
        trace += svd.s.iter().sum::<f64>() / 3.0;
        *basis = svd.u;
    }
    let weights = matches!(bound, CpBound::PointsWeighted(_)).then(|| point_weights(rows, m));
    let at_points = |k: &Kruskal| {
        let approx = k.to_tensor();
        let (a, b) = (x.as_slice(), approx.as_slice());
        max_at_points(rows, |i| a[i] - b[i])
    };
    // The CP fit of one rank and its error under `bound`.
    let attempt = |rank: usize| -> Result<(Kruskal, f64), MrasError> {
        // Plain CP-ALS first, to convergence: where it meets the bound, it is kept. (Cut to
        // 20 sweeps as a mere start, it missed the bound where 60 meet it, and the weighted
        // fit, which stops as soon as the bound holds, took over less accurately: the
        // single-level sphere of Fig. 5 ended at 1.04e-3 of the diagonal, not below 1e-3.)
        let opts = CpOptions::new(rank)
            .with_init(CpInit::Given(
                svd_start(&bases, rank).map_err(MrasError::Tensor)?,
            ))
            .with_tol(CP_TOL)
            .with_max_iter(CP_MAX_ITER)
            .with_line_search(true);
        // Every B-spline row sums to 1 with non-negative entries, so `|φ̂ − φ| ≤ ‖C − Ĉ‖_F`
        // at any point: a sweep whose (tracked) Frobenius error meets ε meets every bound,
        // and the sweeps stop there (the bound is checked exactly below).
        let fit = cp_als(&x, &opts, |p| p.rel_error * norm > eps).map_err(MrasError::Tensor)?;
        let error = match bound {
            CpBound::Tensor(_) => fit.abs_error,
            _ => at_points(&fit.kruskal),
        };
        let Some(w) = weights.as_deref().filter(|_| error > eps) else {
            return Ok((fit.kruskal, error));
        };
        let options = WeightedOptions {
            max_iter: CP_WEIGHTED_MAX_ITER,
            tol: CP_WEIGHTED_TOL,
        };
        // The bound is checked after sweeps 1, 2, 4, 8, … (each check reads every point).
        // A weighted fit that fails (only by overflow) leaves the plain one.
        let Ok(weighted) = cp_als_weighted(&x, w, &fit.kruskal, &options, |sweep, k| {
            !sweep.is_power_of_two() || at_points(k) > eps
        }) else {
            return Ok((fit.kruskal, error));
        };
        let weighted_error = at_points(&weighted.kruskal);
        Ok(if weighted_error < error {
            (weighted.kruskal, weighted_error)
        } else {
            (fit.kruskal, error)
        })
    };
    let mut rank = ((trace / norm).ceil() as usize).clamp(1, cap);
    let mut failed = 0;
    let mut best = loop {
        let (k, error) = attempt(rank)?;
        if error <= eps {
            break (k, error);
        }
        if rank >= cap {
            let full = CellSpline::Full {
                coefficients: x.as_slice().to_vec(),
            };
            return Ok((Some(full), 0.0));
        }
        failed = rank;
        let step = (3.0 * (error / eps).ln()).ceil().max(1.0) as usize;
        rank = (rank + step).min(cap);
    };
    if let Some((_, smaller)) = search_from_below(failed, rank, |r| {
        let (k, error) = attempt(r)?;
        Ok::<_, MrasError>((error <= eps).then_some((k, error)))
    })? {
        best = smaller;
    }
    Ok((Some(factors_of(&best.0, m)), best.1))
}

/// The spline of Kruskal factors, the weights folded into the first axis.
fn factors_of(k: &Kruskal, m: usize) -> CellSpline<3> {
    let r = k.rank();
    let weights = k.weights();
    let f = k.factors();
    let mut factors: [Vec<f64>; 3] = [vec![0.0; m * r], vec![0.0; m * r], vec![0.0; m * r]];
    for (a, out) in factors.iter_mut().enumerate() {
        for i in 0..m {
            for q in 0..r {
                let scale = if a == 0 { weights[q] } else { 1.0 };
                out[i * r + q] = f[a][(i, q)] * scale;
            }
        }
    }
    CellSpline::Cp { rank: r, factors }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Coefficients reproducing `t ↦ poly(t)` along each axis for the quadratic B-splines of
    /// the box: `Σ_j β(x − j) = 1`, `Σ_j j β(x − j) = x`, `Σ_j j² β(x − j) = x² + ¼`, with
    /// `x = ½ + t(m − 2)`.
    fn coefficient(m: usize, j: usize, power: u32) -> f64 {
        let k = (m - 2) as f64;
        let j = j as f64;
        match power {
            0 => 1.0,
            1 => (j - 0.5) / k,
            _ => (j * j - j) / (k * k),
        }
    }

    #[test]
    fn thin_plate_energy_is_exact_on_quadratics() {
        for m in [5, 8] {
            let plate = ThinPlate::new(m);
            let tensor = |p: [u32; 3]| -> Vec<f64> {
                let mut c = Vec::new();
                for i in 0..m {
                    for j in 0..m {
                        for l in 0..m {
                            c.push(
                                coefficient(m, i, p[0])
                                    * coefficient(m, j, p[1])
                                    * coefficient(m, l, p[2]),
                            );
                        }
                    }
                }
                c
            };
            // φ = t_x²: Hessian diag(2, 0, 0), ∭‖H‖² = 4. φ = t_x t_y: two off-diagonal 1s, 2.
            // φ = t_z (affine): 0.
            let cases = [
                ([2, 0, 0], 4.0),
                ([0, 2, 0], 4.0),
                ([1, 1, 0], 2.0),
                ([0, 0, 1], 0.0),
            ];
            for (p, want) in cases {
                let e = plate.energy(&tensor(p));
                assert!((e - want).abs() < 1e-10, "m {m} {p:?}: {e} vs {want}");
            }
        }
    }

    #[test]
    fn a_cell_its_points_do_not_need_is_screened_before_admm() {
        // Level 2, cell (0, 0, 0): a plane of points at x = 0.25 whose residuals are a tilt
        // `a·(y − 0.25)` in value (gradient targets 0). Below the bound at every point: rank 0
        // without ADMM; above it: ADMM runs and a spline is stored.
        let g = LevelGeometry::new(3, 2, 6, 0.75);
        let plate = ThinPlate::new(6);
        let targets = |a: f64| -> Vec<Target> {
            (0..100)
                .map(|i| {
                    let (y, z) = (0.05 * (i % 10) as f64, 0.05 * (i / 10) as f64);
                    Target {
                        u: [0.25, y, z],
                        value: a * (y - 0.25),
                        gradient: [0.0; 3],
                        slack: 1.0,
                    }
                })
                .collect()
        };
        let settings = LocalSettings {
            omega1: 5e-5,
            omega2: 1e-8,
            lambda: 0.3,
            value_scale: 1e-3,
            lambda_scale: 1e-3,
            zero_allowed: true,
            eta: 0.3,
            relaxation: 1.6,
            admm_max_iter: 50,
            admm_tol: 1e-3,
            cp_bound: Some(CpBound::Points(1e-3)),
        };
        // Largest |target| 0.25·a: 2.5e-4 for a = 1e-3, 2.5e-2 for a = 0.1.
        let small = fit_cell(&g, [0, 0, 0], &targets(1e-3), &plate, &settings).unwrap();
        assert!(small.spline.is_none() && small.admm_iterations == 0);
        assert!(small.cp_error <= 1e-3, "{}", small.cp_error);
        let large = fit_cell(&g, [0, 0, 0], &targets(0.1), &plate, &settings).unwrap();
        assert!(large.spline.is_some() && large.admm_iterations > 0);
        // Uncompressed (no bound): never screened.
        let full = LocalSettings {
            cp_bound: None,
            ..settings
        };
        let kept = fit_cell(&g, [0, 0, 0], &targets(1e-3), &plate, &full).unwrap();
        assert!(matches!(kept.spline, Some(CellSpline::Full { .. })));
    }

    #[test]
    fn points_bound_measures_the_change_at_the_data() {
        // A rank-2 tensor ((i+1)·j·0.01 + sin(l)·0.02): the paper's bound on the whole tensor
        // needs rank ≥ 2 (Algorithm 2 may overshoot), a loose bound at one data point
        // stops at the first rank tried.
        let m = 6;
        let c: Vec<f64> = (0..m * m * m)
            .map(|f| {
                let (i, j, l) = (f / 36, (f / 6) % 6, f % 6);
                (i as f64 + 1.0) * (j as f64) * 0.01 + (l as f64).sin() * 0.02
            })
            .collect();
        let mut row = Row {
            len: 1,
            idx: [0; 27],
            val: [0.0; 27],
            inv_slack: 1.0,
        };
        row.idx[0] = 100;
        row.val[0] = 1.0;
        let rows = std::slice::from_ref(&row);
        let (spline, err) = compress(c.clone(), m, CpBound::Tensor(1e-8), rows, true).unwrap();
        let rank = spline.and_then(|s| s.rank()).expect("CP factors");
        assert!(
            (2..=12).contains(&rank) && err <= 1e-8,
            "rank {rank}, error {err}"
        );
        let (loose, err) = compress(c.clone(), m, CpBound::Points(0.05), rows, true).unwrap();
        // Algorithm 2 starts at R⁰ = ⌈Σ γᵢ‖C₍ᵢ₎‖_*⌉ (2 here) and stops there.
        assert!(loose.and_then(|s| s.rank()).expect("CP factors") <= rank.min(2));
        assert!(err <= 0.05, "{err}");
        // φ = c[100] = 0.1 + 0.02 sin 4 ≈ 0.0849 at the one data point: rank 0 (nothing
        // stored) exactly when the bound allows that much, and then the error is |φ|.
        let phi = c[100];
        let (none, err) = compress(c.clone(), m, CpBound::Points(phi * 1.001), rows, true).unwrap();
        assert!(none.is_none() && err == phi.abs(), "{err} vs {phi}");
        // Where φ = 0 may not stand (the root level), the same bound stores factors.
        let (kept, _) = compress(c.clone(), m, CpBound::Points(phi * 1.001), rows, false).unwrap();
        assert!(kept.is_some());
        let (some, _) = compress(c.clone(), m, CpBound::Points(phi * 0.999), rows, true).unwrap();
        assert!(some.is_some());
        // The tensor bound: rank 0 when ‖C‖_F meets it.
        let norm = c.iter().map(|v| v * v).sum::<f64>().sqrt();
        let (none, err) =
            compress(c.clone(), m, CpBound::Tensor(norm * 1.001), rows, true).unwrap();
        assert!(none.is_none() && err == norm);
        let zeros = vec![0.0; m * m * m];
        assert!(
            compress(zeros, m, CpBound::Points(0.0), rows, true)
                .unwrap()
                .0
                .is_none()
        );
    }
}
