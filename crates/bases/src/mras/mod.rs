//! Multilevel rational algebraic splines (MRAS) compressed by low-rank tensor approximation
//! (Pan, Tong & Chen 2016, paper 004): a compact implicit surface fitted to an oriented point
//! cloud.
//!
//! ## The representation (§4, eqs. 6–9)
//!
//! The cloud's bounding box is enlarged to a cube and mapped to the unit cube, `u = (p − o)/L`.
//! Level `k = 1, 2, …` is the lattice of `2^{k−1}` cells per axis; some of its cells hold an
//! **offset** `φ_j(u) = Σ c_{rst} N_r(x) N_s(y) N_t(z)`, a tensor-product quadratic B-spline
//! with `m_k = m₀ − ⌊βk⌋` uniform B-splines per axis. The offsets of a level are blended by a
//! partition of unity and added to the previous level:
//!
//! ```text
//! f^k(u) = f^{k−1}(u) + Σ_j w_j(u) φ_j(u) / Σ_i w_i(u),    w_j(u) = β²(3|u − c_j| / 2ρ),
//! ```
//!
//! `f⁰ = 0`, `β²` the centred quadratic B-spline (support `|t| < 3/2`), `c_j` the cell's centre
//! and `ρ = αR` with `α = 0.75` (eq. 8). The world field is `L·f^K`, close to a signed distance
//! (negative inside, where the normals point away from).
//!
//! Two readings of the paper, both forced by its gaps (`../shared/DESIGN.md`):
//! - **`R` is the cell's full diagonal** `√3·s`, not half of it: with the half-diagonal the
//!   support `0.65 s` misses the cell's edges (`0.707 s` from the centre) and `Σw = 0` there.
//!   With the full diagonal `ρ ≈ 1.30 s` covers the cell's corners (`0.87 s`), so every point of
//!   the domain has `Σw > 0`. Each cell's knots are placed on its **support box** `c ± ρ`, since
//!   `φ_j` is used wherever `w_j > 0` — except the root's: its one weight is the whole
//!   partition of unity (`w/Σw = 1`) and the field is only evaluated in the cube, so its knots
//!   span the cube itself (the box `c ± ρ` would be 2.6 times wider and spend most of its
//!   B-splines outside: 11 per axis then reached the torus of Fig. 5 at 6.9e-3 and rank 24,
//!   over the cube 2.6e-3 at rank 9).
//! - **The denominator sums over every cell of the level's lattice**, fitted or not (an unfitted
//!   cell has offset 0). The paper writes `Ω = ∪_j Ω_j^k` — the level's cells cover the domain —
//!   and this keeps `f^k` as smooth as `w` where a refined region ends; a sum over the fitted
//!   cells only would jump there.
//!
//! ## The local fit (§5.2–5.3, eqs. 14–21)
//!
//! Each cell to fit minimises, over its coefficient tensor `C` (unit-cube coordinates),
//!
//! ```text
//! (1/N) Σ_u (f^{k−1} + φ)(p_u)² + ω₁ (1/N) Σ_u ‖∇(f^{k−1} + φ)(p_u) − n_u‖²
//!     + ω₂(k) mean_box ‖∇²φ‖_F² + τ Σ_i γ_i ‖C_(i)‖_*,   γ_i = 1/3,
//! ```
//!
//! over the `N` points inside its support (where `w_j > 0`, as in MPU: the paper sums over the
//! cell's own points, but `φ_j` is used on the whole support). Departures, each for a reason:
//! - the normal term is on `∇(f^{k−1} + φ)`, not `∇φ` alone: the paper's form pulls every
//!   level's gradient to `n` again, so the sum's gradient would grow with the depth;
//! - the energy is **per point** and the thin-plate term is the box's **mean** curvature, so
//!   that the weights balance the same way at every level and sampling density;
//! - `ω₂(k) = max(ω₂_root / d^{k−1}, ω₂)` (`d` = [`MrasOptions::omega2_decay`], 10): the coarse
//!   levels' large cells decide the field far from the points and need a strong thin-plate term
//!   there (a weak one leaves spurious sheets: bunny_2k meshed with 2–5 components; with `d` =
//!   100 a noisy bunny kept a sheet at the cube's corner), the fine levels must follow the points;
//! - the root level also gets **outside constraints** on the cube's boundary (value: the
//!   distance to the nearest point, gradient: away from it — what a signed distance takes
//!   there, which the normal term makes the field resemble), so that the far field's sign is
//!   held by more than the weak normal term;
//! - the trace-norm weight is `τ = λ ε₀² / (a √(m³))`, `a` the RMS coefficient of the fit
//!   without it: a dimensionless `λ` that costs about `λ ε₀²` per unit rank at every level (the
//!   paper's absolute λ flattens the root level, whose amplitude only the normal term holds,
//!   or does nothing at the fine ones); `ε₀` there stops growing at a tolerance of 1% of the
//!   diagonal (past it, `τ` outweighed the normal term and shrank every offset to nothing);
//! - the root cell is never dropped at rank 0: with `f⁰ = 0` its offset is the whole field,
//!   whose values at the points are near 0 however well or badly it fits;
//! - ADMM's penalty `η` is in units of the c-step matrix's mean diagonal, and ADMM starts from
//!   the fit without the trace norm (from zero it crawls along the directions only the weak
//!   normal term fixes, and its stopping rule takes the crawl for convergence); it is
//!   over-relaxed (`ρ = 1.6`, Boyd et al. §3.4.3) at `η = 0.3`: from the warm start, plain ADMM
//!   at `η = 1` met its tolerances after 1–3 iterations at the middle levels, before the trace
//!   norm had lowered the ranks.
//!
//! ADMM (Algorithm 1, [`zeroset_solvers::admm`]) factors the c-step matrix `H + 3ηI` once per
//! cell; the z-step thresholds the three unfoldings' singular values. The split variables'
//! mean (exactly low multilinear rank) is compressed by CP-ALS with Algorithm 2's rank schedule
//! — rank 0 first (a cell whose `φ = 0` meets the bound is not stored: the blend counts a
//! missing cell as `φ = 0`, its weight still in `Σw`, so leaving it out is exact; where the
//! offset fitted without the trace norm, ADMM's warm start, already meets it, ADMM is not run),
//! then
//! `R⁰ = ⌈Σ γ_i ‖C_(i)‖_* / ‖C‖_F⌉` (the paper's start divided by the tensor's norm, so that
//! it does not depend on the coefficients' units), then `R += ⌈3 ln(error/ε)⌉`, then a
//! bisection back between the last rank that failed and the first that held — until the CP
//! factors change `φ` at each of the cell's data points by at most `0.5 · ε₀ · slack`
//! ([`MrasOptions::cp_points`]). `slack = 1` where the field ends; where the next level refines
//! a cell (decided on the level before compression, by the rule below), its points allow
//! `slack = max(1, r_j/ε₀)` ([`MrasOptions::cp_refined`]), `r_j` the largest residual
//! `|f^k|` its own points keep: the next level fits those points again, so coarse levels may
//! compress harder, as with the paper's `10^{−k−1}`, yet the residual a point hands on grows
//! by at most half of the largest one in its cell (the blend is a convex combination of the
//! cells' errors there, each within the point's own bound). (A bound
//! from the previous level's largest Sampson distance, tried first, was inflated at points
//! where `∇f` nearly vanished and then let every cell of a level go at rank 0, and the next
//! level, seeing the same error, too: the bunny with `m₀ = 11` ended at 0.33 of the
//! diagonal.) The paper's
//! bound `‖C − Ĉ‖_F ≤ 10^{−k−1}` is available ([`MrasOptions::cp_scale`]) but spends rank on
//! coefficients no point sees.
//!
//! From level 2 on, each point's bound is also scaled by `min(1, |∇f^{k−1}(p)|/0.5)` (at least
//! 10⁻³): the tolerance bounds the Sampson distance `|f|/|∇f|`, and where the field so far is
//! flat a small change of the value moves the surface far — without it, a loose tolerance
//! let a flat coarse field's cells pass at rank 0 level after level (the bunny at
//! `--tolerance 0.02` kept 8,029 points beyond it, up to 10% of the diagonal; now 45, up to
//! 2.6%). The screen uses the same factor.
//!
//! Plain CP-ALS spends rank on those coefficients too, even under the bound at the points: it
//! fits every coefficient alike. So each rank tried is fitted by plain CP-ALS and, where that
//! misses the bound, from there by **weighted CP-ALS** (≤ 15 sweeps; the bound is checked
//! after sweeps 1, 2, 4, 8 and at the end) ([`zeroset_tensor::weighted`]) in the weights
//! `W_c = Σ_p (B_c(x_p)/s_p)²` — the diagonal of the points' least-squares form
//! `Σ_p (φ̂ − φ)²(x_p)/s_p²` — plus `10⁻³ max W` on every coefficient, which holds those no
//! point reads (they still shape the field beside the points: with 0, every
//! scan tried meshed with 5–10 components) ([`MrasOptions::cp_weighted`]). The bound is
//! still checked exactly at every point; the same rank meets it more often, so lower ranks
//! are stored: bunny 290k → 218k numbers, kitten 101k → 68k, max distances within 2%. (The full
//! least-squares form instead of its diagonal, an ALS over each whole factor, stored 9% less
//! again on the bunny but took 7× as long and left its max distance at 5.2e-3, not 4.5e-3.)
//! The rank is capped at `m²/3`, where `3mR` numbers stop being fewer than `m³` (a cell that
//! needs more is stored full). `f^k` is built from the CP factors, so the next level corrects
//! the compression error too.
//!
//! ## Subdivision (§5.1, eq. 10)
//!
//! After level `k`, a cell is split into its 8 children when its own points' largest Sampson
//! distance `|f^k|/|∇f^k|` exceeds `ε₀` and it holds more than `N_min = 16` points, up to the
//! level cap. The cells of one level are fitted in parallel; each fit is sequential and the
//! results are gathered in lattice order, so the field has the same bits on any number of
//! threads.
//!
//! ## Storage (§6.2)
//!
//! A cell stores `3·m·R` numbers (weights folded into a factor) plus its blending function
//! (centre and radius, 4 numbers): [`MrasField::storage`]; [`MrasField::uncompressed_storage`]
//! counts the same cells as full `m³` tensors. A fitted field also records its input points
//! (`f32` unit-cube coordinates, [`MrasField::points`]) for the mesh's spurious-component check;
//! they are not part of the field and not counted.
//!
//! ```
//! use zeroset_bases::mras::{MrasOptions, fit_mras};
//! use zeroset_field_core::field::ScalarField;
//!
//! // 600 points with outward normals on the unit sphere.
//! let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
//! let (mut points, mut normals) = (Vec::new(), Vec::new());
//! for i in 0..600 {
//!     let z = 1.0 - 2.0 * (i as f64 + 0.5) / 600.0;
//!     let r = (1.0 - z * z).sqrt();
//!     let p = [r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z];
//!     points.push(p);
//!     normals.push(p);
//! }
//! let fit = fit_mras(&points, &normals, &MrasOptions::default().max_level(1), &|_| true)?;
//! let f = &fit.field;
//! assert!(f.value(&[0.0, 0.0, 0.0]) < 0.0 && f.value(&[1.3, 0.0, 0.0]) > 0.0);
//! assert!(f.value(&[0.0, 1.0, 0.0]).abs() < 0.01);
//! # Ok::<(), zeroset_bases::mras::MrasError>(())
//! ```

mod field;
mod fit;
mod local;

pub use field::{CellSpline, LevelGeometry, MAX_LEVEL, MrasCell, MrasField, MrasLevel};
pub use fit::{FLAT_GRADIENT, LevelReport, MrasFit, MrasOptions, MrasProgress, fit_mras};

use zeroset_solvers::admm::AdmmError;
use zeroset_tensor::TensorError;

/// What can go wrong in [`fit_mras`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MrasError {
    /// Fewer points than a fit needs.
    #[error(
        "MRAS needs at least {needed} distinct points with normals, got {got}{}{}",
        if *duplicates > 0 { format!(" ({duplicates} duplicates merged)") } else { String::new() },
        if *outliers > 0 {
            format!(" ({outliers} outliers set aside; outlier_ratio 0 fits them)")
        } else {
            String::new()
        }
    )]
    TooFewPoints {
        /// The minimum (`N_min`).
        needed: usize,
        /// Distinct points given.
        got: usize,
        /// Exact duplicates merged before counting.
        duplicates: usize,
        /// Outliers set aside before counting ([`MrasOptions::outlier_ratio`]).
        outliers: usize,
    },
    /// Positions and normals of different lengths, or no normals.
    #[error("MRAS needs one normal per point: {points} points, {normals} normals")]
    Normals {
        /// Points.
        points: usize,
        /// Normals.
        normals: usize,
    },
    /// A coordinate or normal that is NaN or infinite.
    #[error("point {index}: {what} {value:?} is not finite")]
    NonFinite {
        /// The record.
        index: usize,
        /// "position" or "normal".
        what: &'static str,
        /// The values.
        value: [f64; 3],
    },
    /// A normal of (nearly) zero length.
    #[error("point {index}: normal {normal:?} has length {length:.3e}; MRAS needs unit normals")]
    ZeroNormal {
        /// The record.
        index: usize,
        /// The normal.
        normal: [f64; 3],
        /// Its length.
        length: f64,
    },
    /// All points on one plane or line: no volume to wrap a surface around.
    #[error(
        "all points lie within {thickness:.3e} of a {shape} (extent {extent:.3e}): MRAS sizes \
         its cells from the points' spread and needs them spread in 3 dimensions, not on a \
         single {shape}"
    )]
    Degenerate {
        /// "plane", "line" or "point".
        shape: &'static str,
        /// The largest distance of a point from it.
        thickness: f64,
        /// The cloud's largest extent.
        extent: f64,
    },
    /// Coordinates so large that the cloud's extent or diagonal overflows.
    #[error(
        "the points span {extent:e}: coordinates this large overflow the box's diagonal; scale \
         them down"
    )]
    Overflow {
        /// The cloud's largest extent (infinite where it overflowed itself).
        extent: f64,
    },
    /// An option outside its range.
    #[error("MRAS option {name} = {value}: {reason}")]
    Option {
        /// The option.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range.
        reason: &'static str,
    },
    /// The fit was cancelled.
    #[error("MRAS fit cancelled")]
    Cancelled,
    /// A local ADMM solve failed (a bug or a numerical breakdown).
    #[error("local fit: {0}")]
    Admm(#[from] AdmmError),
    /// A CP decomposition failed.
    #[error("CP compression: {0}")]
    Tensor(TensorError),
    /// The fitted levels do not form a field (a bug).
    #[error("MRAS field: {0}")]
    Field(String),
}
