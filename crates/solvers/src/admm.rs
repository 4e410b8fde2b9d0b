//! The alternating direction method of multipliers (ADMM) for a convex quadratic plus a sum of
//! terms with cheap proximal operators, each seen through an orthogonal linear map:
//!
//! $$\min_{c \in ℝⁿ}\; ½\, cᵀ H c − bᵀ c + \sum_{i=1}^{k} g_i(P_i c),$$
//!
//! with `H` symmetric positive semi-definite (`n × n`, dense), `P_i : ℝⁿ → ℝ^{m_i}` linear with
//! `P_iᵀ P_i = I` (a permutation such as the vectorised mode-`i` unfolding of a coefficient
//! tensor) and `g_i` closed, convex and proper. This is MRAS's fitting problem (Pan, Tong & Chen,
//! paper 004 §5.3, eqs. 15–21) generalised: there `½cᵀHc − bᵀc` is the quadratic energy `E` of
//! eq. 14 (up to a constant), `k = 3`, `P_i` is the mode-`i` unfolding and
//! `g_i = λ γ_i ‖·‖_*` with `γ_i = 1/3` ([`TraceNormTerm::mras_terms`]). For a least-squares
//! energy `E(c) = ‖A c − d‖²` take `H = 2AᵀA`, `b = 2Aᵀd` (then `E = ½cᵀHc − bᵀc + ‖d‖²`).
//!
//! ## The iteration (paper 004, Algorithm 1)
//!
//! Splitting `z_i = P_i c` (eq. 16) and taking the augmented Lagrangian with penalty `η > 0`
//! (eq. 17), one iteration is
//!
//! * **c-step** (eq. 18): `(H + kηI) c = b + Σ_i P_iᵀ(η z_i − α_i)` — since `P_iᵀP_i = I` the
//!   matrix is fixed: it is factored once by dense Cholesky and every iteration costs two
//!   triangular solves;
//! * **z-step** (eqs. 19–21): `z_i = prox_{g_i/η}(P_i c + α_i/η)` — for the trace norm this is
//!   singular-value thresholding at `λγ_i/η`;
//! * **dual step**: `α_i += η (P_i c − z_i)`.
//!
//! It starts from `z_i = 0`, `α_i = 0`. With over-relaxation `ρ ∈ (0, 2)`
//! ([`AdmmOptions::relaxation`]; Boyd et al. §3.4.3) the z- and dual steps use
//! `ρ P_i c + (1 − ρ) z_i^{prev}` in place of `P_i c`; `ρ = 1` (the default) is the iteration
//! above, `ρ ≈ 1.5–1.8` often converges in fewer iterations at the same cost each.
//!
//! ## Stopping (Boyd, Parikh, Chu, Peleato & Eckstein 2011, §3.3.1)
//!
//! With `p = Σ m_i`, the primal residual `r = (Σ_i ‖P_i c − z_i‖²)^{1/2}` and the dual
//! residual `s = η ‖Σ_i P_iᵀ(z_i − z_i^{prev})‖`, ADMM stops when both
//!
//! * `r ≤ ε_abs √p + ε_rel · max((Σ‖P_i c‖²)^{1/2}, (Σ‖z_i‖²)^{1/2})` and
//! * `s ≤ ε_abs √n + ε_rel · ‖Σ_i P_iᵀ α_i‖`,
//!
//! or after [`AdmmOptions::max_iter`] iterations, or when the progress callback says stop; the
//! solution says which ([`AdmmStop`]). ADMM converges for any `η > 0` on this convex problem
//! (Boyd et al. §3.2); `η` changes only the speed.
//!
//! ## Guarantees
//!
//! Inputs are checked at the boundary (shapes, NaN/∞, symmetry of `H`, `η`, tolerances, and
//! `P_iᵀP_i = I` on a probe vector) and reported as specific [`AdmmError`]s; nothing panics on
//! bad input. Every step runs sequentially in a fixed order, so the same input gives the same
//! bits on every run and every thread count.
//!
//! ```
//! use faer::Mat;
//! use zeroset_solvers::admm::{AdmmOptions, ProxTerm, TraceNormTerm, admm};
//!
//! let shape = [3, 4, 5];
//! let n = 60;
//! let h = Mat::<f64>::identity(n, n);
//! let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
//! let terms = TraceNormTerm::mras_terms(shape, 0.5)?;
//! let refs: Vec<&dyn ProxTerm> = terms.iter().map(|t| t as &dyn ProxTerm).collect();
//! let sol = admm(h.as_ref(), &b, &refs, &AdmmOptions::default())?;
//! assert!(sol.converged);
//! # Ok::<(), zeroset_solvers::admm::AdmmError>(())
//! ```

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{
    LltError, LltRegularization, cholesky_in_place, cholesky_in_place_scratch,
};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, MatMut, MatRef, Par};
use zeroset_tensor::{TensorError, svt, trace_norm};

/// What can go wrong in [`admm`], [`objective`] and [`TraceNormTerm::new`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AdmmError {
    /// `H` is not square.
    #[error("H must be square, not {rows} × {cols}")]
    NotSquare {
        /// Rows of `H`.
        rows: usize,
        /// Columns of `H`.
        cols: usize,
    },
    /// A vector whose length does not match the problem size.
    #[error("{what} has length {got}, expected {expected}")]
    Length {
        /// Which vector (`"b"`, `"c"`).
        what: &'static str,
        /// The length needed (`n`, the order of `H`).
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// A term whose map `P_i` does not act on `ℝⁿ`.
    #[error("term {term} maps ℝ^{got} (P_i has {got} columns), but H is {expected} × {expected}")]
    TermDimension {
        /// The term's index in the list.
        term: usize,
        /// `n`, the order of `H`.
        expected: usize,
        /// The number of columns of `P_i`.
        got: usize,
    },
    /// A term whose map does not satisfy `P_iᵀ P_i = I` (checked on a probe vector), which the
    /// fixed c-step matrix `H + kηI` relies on; `P_i` must have at least as many rows as columns.
    #[error("term {term}: P_iᵀ P_i is not the identity (relative defect {defect:e} on a probe)")]
    NotOrthogonal {
        /// The term's index in the list.
        term: usize,
        /// `‖P_iᵀP_i x − x‖_∞ / ‖x‖_∞` on the probe `x` (`∞` if `P_i` has too few rows).
        defect: f64,
    },
    /// A NaN or infinite entry of `H`.
    #[error("H[({row}, {col})] is not finite")]
    NonFiniteMatrix {
        /// Row of the entry.
        row: usize,
        /// Column of the entry.
        col: usize,
    },
    /// A NaN or infinite entry of a vector.
    #[error("{what}[{index}] is not finite")]
    NonFiniteVector {
        /// Which vector (`"b"`, `"c"`).
        what: &'static str,
        /// Index of the entry.
        index: usize,
    },
    /// `H` is not symmetric: `|H_ij − H_ji| > 1e-10 · max|H|`.
    #[error("H is not symmetric: H[({row}, {col})] ≠ H[({col}, {row})]")]
    NotSymmetric {
        /// Row of the first offending entry (below the diagonal).
        row: usize,
        /// Column of the first offending entry.
        col: usize,
    },
    /// A penalty `η` that is not a positive finite number.
    #[error("the ADMM penalty η must be positive and finite, not {eta}")]
    Eta {
        /// The value given.
        eta: f64,
    },
    /// A term weight that is negative or not finite.
    #[error("a term weight must be finite and non-negative, not {weight}")]
    Weight {
        /// The value given.
        weight: f64,
    },
    /// A tolerance that is negative or not finite, or a zero iteration limit.
    #[error("option {name} = {value} is out of range (tolerances: finite, ≥ 0; max_iter ≥ 1)")]
    InvalidOption {
        /// The option's name.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The c-step matrix `H + kηI` is not positive definite (Cholesky met a non-positive
    /// pivot): `H` is not positive semi-definite (or, with no terms, `H` is singular).
    #[error("H + {terms}·η·I is not positive definite (pivot {pivot})")]
    NotPositiveDefinite {
        /// The index of the failing pivot.
        pivot: usize,
        /// `k`, the number of terms.
        terms: usize,
    },
    /// The iterates ran away (a proximal operator failed on them, or they left the finite
    /// numbers) and `H` is not positive semi-definite: the objective is unbounded below, so
    /// ADMM has no minimiser to reach. Found by a Cholesky factorisation of `H + δI`,
    /// `δ = 10⁻¹⁰ max |H_ii|`, made only once the iterates have run away.
    #[error(
        "H is not positive semi-definite (the Cholesky factorisation of H + δI, δ = 1e-10 · \
         max |H_ii|, fails at pivot {pivot}): the objective is unbounded below and ADMM \
         diverged (at iteration {iteration})"
    )]
    NotPositiveSemiDefinite {
        /// The index of the failing pivot.
        pivot: usize,
        /// The iteration at which the iterates ran away.
        iteration: usize,
    },
    /// An error from the tensor machinery (a shape, a mode, an SVD that did not converge, a
    /// NaN reaching the SVD).
    #[error(transparent)]
    Tensor(#[from] TensorError),
}

/// A term `g(P c)` of the objective: a linear map `P` with `PᵀP = I` and a closed convex `g`
/// with a computable proximal operator. Object safe: [`admm`] takes `&[&dyn ProxTerm]`.
///
/// Contract: `apply` and `apply_transpose_add` are exact transposes of each other and
/// `PᵀP = I` (so `P` has at least as many rows as columns); [`admm`] checks the latter on a
/// probe vector.
pub trait ProxTerm {
    /// `(m, n)`: `P` maps `ℝⁿ` (the unknown `c`) to `ℝᵐ` (the split variable `z`).
    fn dims(&self) -> (usize, usize);

    /// `out = P c` (overwrites; `c.len() == n`, `out.len() == m`).
    fn apply(&self, c: &[f64], out: &mut [f64]);

    /// `out += Pᵀ z` (accumulates; `z.len() == m`, `out.len() == n`).
    fn apply_transpose_add(&self, z: &[f64], out: &mut [f64]);

    /// `out = prox_{step·g}(v) = argmin_z g(z) + ‖z − v‖² / (2·step)` (`step ≥ 0`,
    /// `v.len() == out.len() == m`).
    ///
    /// # Errors
    /// Whatever the operator can fail with (an SVD that does not converge, a NaN).
    fn prox(&self, v: &[f64], step: f64, out: &mut [f64]) -> Result<(), AdmmError>;

    /// `g(z)` (`z.len() == m`).
    ///
    /// # Errors
    /// As for [`ProxTerm::prox`].
    fn value(&self, z: &[f64]) -> Result<f64, AdmmError>;
}

const _: Option<&dyn ProxTerm> = None; // object safety, checked at compile time

/// `g(Z) = weight · ‖Z‖_*` on the mode-`mode` unfolding of `c` seen as a [`Tensor3`](zeroset_tensor::Tensor3) of
/// `shape`: the MRAS low-rank term `λ γ_i ‖C_(i)‖_*` (paper 004 eq. 15).
///
/// Layout: `c` holds the tensor in row-major order (`i₂` fastest, as [`Tensor3::as_slice`](zeroset_tensor::Tensor3::as_slice));
/// `z = P c` is the unfolding `C₍ₙ₎` of [`Tensor3::unfold`](zeroset_tensor::Tensor3::unfold) (`Iₙ × ∏_{m≠n} I_m`, Kolda–Bader
/// column order) vectorised **column-major**: `z[r + Iₙ·col] = C₍ₙ₎[(r, col)]`. `P` is a
/// permutation, so `PᵀP = I`. The prox is singular-value thresholding at `weight · step`
/// (paper 004 eq. 21).
#[derive(Debug, Clone, PartialEq)]
pub struct TraceNormTerm {
    shape: [usize; 3],
    mode: usize,
    weight: f64,
    rows: usize,
    cols: usize,
    /// `perm[k]` = the row-major index in `c` of entry `k` of `z`.
    perm: Vec<usize>,
}

impl TraceNormTerm {
    /// MRAS's mode weight `γ_i = 1/3` (paper 004 §5.3 and §6: the three unfoldings weigh the
    /// same and `Σ γ_i = 1`).
    pub const MRAS_GAMMA: f64 = 1.0 / 3.0;

    /// `weight · ‖C₍mode₎‖_*` for coefficient tensors of `shape`.
    ///
    /// # Errors
    /// [`AdmmError::Tensor`] with [`TensorError::EmptyShape`] for a zero extent or
    /// [`TensorError::Mode`] for `mode > 2`; [`AdmmError::Weight`] for a negative or non-finite
    /// weight.
    pub fn new(shape: [usize; 3], mode: usize, weight: f64) -> Result<Self, AdmmError> {
        if shape.contains(&0) {
            return Err(TensorError::EmptyShape { shape }.into());
        }
        if mode > 2 {
            return Err(TensorError::Mode { mode }.into());
        }
        if !(weight.is_finite() && weight >= 0.0) {
            return Err(AdmmError::Weight { weight });
        }
        let [a, b] = match mode {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        };
        let rows = shape[mode];
        let cols = shape[a] * shape[b];
        let mut perm = vec![0; rows * cols];
        for i0 in 0..shape[0] {
            for i1 in 0..shape[1] {
                for i2 in 0..shape[2] {
                    let idx = [i0, i1, i2];
                    let lin = (i0 * shape[1] + i1) * shape[2] + i2;
                    let col = idx[a] + shape[a] * idx[b];
                    perm[idx[mode] + rows * col] = lin;
                }
            }
        }
        Ok(Self {
            shape,
            mode,
            weight,
            rows,
            cols,
            perm,
        })
    }

    /// The three MRAS terms `λ γ_i ‖C₍ᵢ₎‖_*`, `i = 0, 1, 2`, with `γ_i` =
    /// [`TraceNormTerm::MRAS_GAMMA`] `= 1/3` (paper 004 eq. 15; the paper takes
    /// `λ ∈ [0.01, 0.05]`).
    ///
    /// # Errors
    /// As [`TraceNormTerm::new`] (`lambda` negative or not finite: [`AdmmError::Weight`]).
    pub fn mras_terms(shape: [usize; 3], lambda: f64) -> Result<[Self; 3], AdmmError> {
        if !(lambda.is_finite() && lambda >= 0.0) {
            return Err(AdmmError::Weight { weight: lambda });
        }
        let w = lambda * Self::MRAS_GAMMA;
        Ok([
            Self::new(shape, 0, w)?,
            Self::new(shape, 1, w)?,
            Self::new(shape, 2, w)?,
        ])
    }

    /// The tensor shape `[I₀, I₁, I₂]`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// The unfolding mode `n`.
    pub fn mode(&self) -> usize {
        self.mode
    }

    /// The weight in front of the trace norm.
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// The unfolding's dimensions `(Iₙ, ∏_{m≠n} I_m)`.
    pub fn unfolding_dims(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }

    /// `z` (column-major) as the unfolding matrix.
    fn matrix<'a>(&self, z: &'a [f64]) -> MatRef<'a, f64> {
        MatRef::from_column_major_slice(&z[..self.rows * self.cols], self.rows, self.cols)
    }
}

impl ProxTerm for TraceNormTerm {
    fn dims(&self) -> (usize, usize) {
        (self.perm.len(), self.perm.len())
    }

    fn apply(&self, c: &[f64], out: &mut [f64]) {
        for (o, &p) in out.iter_mut().zip(&self.perm) {
            *o = c[p];
        }
    }

    fn apply_transpose_add(&self, z: &[f64], out: &mut [f64]) {
        for (&v, &p) in z.iter().zip(&self.perm) {
            out[p] += v;
        }
    }

    /// Singular-value thresholding `U max(Σ − weight·step, 0) Vᵀ` ([`zeroset_tensor::svt`],
    /// sequential).
    fn prox(&self, v: &[f64], step: f64, out: &mut [f64]) -> Result<(), AdmmError> {
        // `svt` rejects NaN/∞ entries (index in column-major order, as `v`) and bad thresholds.
        let (y, _) = svt(self.matrix(v), self.weight * step)?;
        for (j, col) in out.chunks_exact_mut(self.rows).take(self.cols).enumerate() {
            col.copy_from_slice(y.col_as_slice(j));
        }
        Ok(())
    }

    fn value(&self, z: &[f64]) -> Result<f64, AdmmError> {
        if self.weight == 0.0 {
            return Ok(0.0);
        }
        Ok(self.weight * trace_norm(self.matrix(z))?)
    }
}

/// Options of [`admm`]: penalty, iteration limit and stopping tolerances.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct AdmmOptions {
    /// The penalty `η > 0` (default `1.0`, the paper's value).
    pub eta: f64,
    /// The iteration limit (default `2000`).
    pub max_iter: usize,
    /// Absolute tolerance `ε_abs` (default `1e-9`).
    pub eps_abs: f64,
    /// Relative tolerance `ε_rel` (default `1e-7`).
    pub eps_rel: f64,
    /// A warm start `c⁰` (default none: `z_i = 0`): the iteration starts from `z_i = P_i c⁰`,
    /// `α_i = 0`, so that its first c-step returns `c⁰` itself when `c⁰` minimises the quadratic.
    pub start: Option<Vec<f64>>,
    /// The over-relaxation `ρ ∈ (0, 2)` (default `1.0`: none; see the module docs).
    pub relaxation: f64,
}

impl Default for AdmmOptions {
    fn default() -> Self {
        Self {
            eta: 1.0,
            max_iter: 2000,
            eps_abs: 1e-9,
            eps_rel: 1e-7,
            start: None,
            relaxation: 1.0,
        }
    }
}

impl AdmmOptions {
    /// With penalty `eta`.
    pub fn eta(mut self, eta: f64) -> Self {
        self.eta = eta;
        self
    }

    /// With iteration limit `max_iter`.
    pub fn max_iter(mut self, max_iter: usize) -> Self {
        self.max_iter = max_iter;
        self
    }

    /// With absolute tolerance `eps_abs`.
    pub fn eps_abs(mut self, eps_abs: f64) -> Self {
        self.eps_abs = eps_abs;
        self
    }

    /// With relative tolerance `eps_rel`.
    pub fn eps_rel(mut self, eps_rel: f64) -> Self {
        self.eps_rel = eps_rel;
        self
    }

    /// Starting from `z_i = P_i c⁰` instead of 0.
    pub fn start(mut self, c0: Vec<f64>) -> Self {
        self.start = Some(c0);
        self
    }

    /// With over-relaxation `relaxation` (`ρ ∈ (0, 2)`).
    pub fn relaxation(mut self, relaxation: f64) -> Self {
        self.relaxation = relaxation;
        self
    }

    fn validate(&self) -> Result<(), AdmmError> {
        if !(self.eta.is_finite() && self.eta > 0.0) {
            return Err(AdmmError::Eta { eta: self.eta });
        }
        for (name, value) in [("eps_abs", self.eps_abs), ("eps_rel", self.eps_rel)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(AdmmError::InvalidOption { name, value });
            }
        }
        if !(self.relaxation > 0.0 && self.relaxation < 2.0) {
            return Err(AdmmError::InvalidOption {
                name: "relaxation",
                value: self.relaxation,
            });
        }
        if self.max_iter == 0 {
            return Err(AdmmError::InvalidOption {
                name: "max_iter",
                value: 0.0,
            });
        }
        Ok(())
    }
}

/// Why [`admm`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AdmmStop {
    /// Both residuals met their tolerances (also: no terms, solved directly).
    Converged,
    /// [`AdmmOptions::max_iter`] iterations ran first.
    MaxIterations,
    /// The progress callback returned `false`.
    Cancelled,
}

/// One iteration's figures, handed to the progress callback of [`admm_with_progress`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdmmProgress {
    /// Iterations done (from 1).
    pub iteration: usize,
    /// The primal residual `r`.
    pub primal_residual: f64,
    /// The dual residual `s`.
    pub dual_residual: f64,
    /// The tolerance `r` must reach.
    pub primal_tolerance: f64,
    /// The tolerance `s` must reach.
    pub dual_tolerance: f64,
}

/// The result of [`admm`].
#[derive(Debug, Clone, PartialEq)]
pub struct AdmmSolution {
    /// The minimiser `c` (from the last c-step).
    pub c: Vec<f64>,
    /// The split variables `z_i ≈ P_i c` from the last z-step, one per term: in the prox's
    /// image (for [`TraceNormTerm`], exactly low-rank unfoldings, where `c` is only close).
    pub z: Vec<Vec<f64>>,
    /// Iterations run.
    pub iterations: usize,
    /// The final primal residual `r`.
    pub primal_residual: f64,
    /// The final dual residual `s`.
    pub dual_residual: f64,
    /// Whether both residuals met their tolerances (`stop == AdmmStop::Converged`).
    pub converged: bool,
    /// Why it stopped.
    pub stop: AdmmStop,
    /// The objective `½cᵀHc − bᵀc + Σ g_i(P_i c)` at `c` ([`objective`]).
    pub objective: f64,
}

/// Minimises `½cᵀHc − bᵀc + Σ_i g_i(P_i c)` by ADMM (see the module docs).
///
/// # Errors
/// [`AdmmError::NotSquare`], [`AdmmError::Length`], [`AdmmError::TermDimension`],
/// [`AdmmError::NotOrthogonal`], [`AdmmError::NonFiniteMatrix`],
/// [`AdmmError::NonFiniteVector`], [`AdmmError::NotSymmetric`], [`AdmmError::Eta`],
/// [`AdmmError::InvalidOption`] for bad input; [`AdmmError::NotPositiveDefinite`] if
/// `H + kηI` has no Cholesky factor; [`AdmmError::NotPositiveSemiDefinite`] when the iterates
/// run away because `H` is not positive semi-definite; whatever a term's prox returns
/// ([`AdmmError::Tensor`] for an SVD that fails).
pub fn admm(
    h: MatRef<'_, f64>,
    b: &[f64],
    terms: &[&dyn ProxTerm],
    options: &AdmmOptions,
) -> Result<AdmmSolution, AdmmError> {
    admm_with_progress(h, b, terms, options, |_| true)
}

/// [`admm`], calling `progress` after every iteration; it returns `false` to stop
/// ([`AdmmStop::Cancelled`], with the current iterate).
///
/// # Errors
/// As [`admm`].
pub fn admm_with_progress(
    h: MatRef<'_, f64>,
    b: &[f64],
    terms: &[&dyn ProxTerm],
    options: &AdmmOptions,
    progress: impl FnMut(&AdmmProgress) -> bool,
) -> Result<AdmmSolution, AdmmError> {
    options.validate()?;
    Quadratic::new(h, b)?.admm_with_progress(terms, options, progress)
}

/// `½cᵀHc − bᵀc` with `H` and `b` checked once (square, matching lengths, finite, `H`
/// symmetric), so that the solves of one problem — [`Quadratic::ridge_solution`], then
/// [`Quadratic::admm`] from it — do not each read all of `H` again to check it.
///
/// ```
/// use faer::Mat;
/// use zeroset_solvers::admm::{AdmmOptions, ProxTerm, Quadratic, TraceNormTerm};
///
/// let h = Mat::<f64>::identity(24, 24);
/// let b: Vec<f64> = (0..24).map(|i| (i % 5) as f64).collect();
/// let problem = Quadratic::new(h.as_ref(), &b)?;
/// let start = problem.ridge_solution(0.0)?;
/// assert_eq!(start, b);
/// let terms = TraceNormTerm::mras_terms([2, 3, 4], 0.1)?;
/// let refs: Vec<&dyn ProxTerm> = terms.iter().map(|t| t as &dyn ProxTerm).collect();
/// let solved = problem.admm(&refs, &AdmmOptions::default().start(start))?;
/// assert!(solved.converged);
/// # Ok::<(), zeroset_solvers::admm::AdmmError>(())
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Quadratic<'a> {
    h: MatRef<'a, f64>,
    b: &'a [f64],
}

impl<'a> Quadratic<'a> {
    /// Checks `H` and `b` once.
    ///
    /// # Errors
    /// [`AdmmError::NotSquare`], [`AdmmError::Length`], [`AdmmError::NonFiniteMatrix`],
    /// [`AdmmError::NonFiniteVector`], [`AdmmError::NotSymmetric`]
    /// (`|H_ij − H_ji| > 10⁻¹⁰ max |H|`).
    pub fn new(h: MatRef<'a, f64>, b: &'a [f64]) -> Result<Self, AdmmError> {
        check_problem(h, b, &[])?;
        check_matrix(h, true)?;
        Ok(Self { h, b })
    }

    /// [`ridge_solution`] of this problem.
    ///
    /// # Errors
    /// [`AdmmError::NotPositiveDefinite`] if `H + ridge·I` has no Cholesky factor.
    pub fn ridge_solution(&self, ridge: f64) -> Result<Vec<f64>, AdmmError> {
        let factor = factor_shifted(self.h, ridge, 0)?;
        let mut c = self.b.to_vec();
        solve_in_place(factor.as_ref(), &mut c);
        Ok(c)
    }

    /// [`admm`] on this problem.
    ///
    /// # Errors
    /// As [`admm`], less the checks of `H` and `b` already made.
    pub fn admm(
        &self,
        terms: &[&dyn ProxTerm],
        options: &AdmmOptions,
    ) -> Result<AdmmSolution, AdmmError> {
        self.admm_with_progress(terms, options, |_| true)
    }

    /// [`admm_with_progress`] on this problem.
    ///
    /// # Errors
    /// As [`admm`], less the checks of `H` and `b` already made.
    pub fn admm_with_progress(
        &self,
        terms: &[&dyn ProxTerm],
        options: &AdmmOptions,
        mut progress: impl FnMut(&AdmmProgress) -> bool,
    ) -> Result<AdmmSolution, AdmmError> {
        options.validate()?;
        let (h, b) = (self.h, self.b);
        let n = check_terms(h.nrows(), terms)?;
        check_orthogonal(terms, n)?;
        let eta = options.eta;
        let k = terms.len();
        let factor = factor_shifted(h, k as f64 * eta, k)?;

        let mut c = b.to_vec();
        if k == 0 {
            solve_in_place(factor.as_ref(), &mut c);
            let objective = objective(h, b, terms, &c)?;
            return Ok(AdmmSolution {
                c,
                z: Vec::new(),
                iterations: 0,
                primal_residual: 0.0,
                dual_residual: 0.0,
                converged: true,
                stop: AdmmStop::Converged,
                objective,
            });
        }

        let dims: Vec<usize> = terms.iter().map(|t| t.dims().0).collect();
        let p: usize = dims.iter().sum();
        let mut z: Vec<Vec<f64>> = dims.iter().map(|&m| vec![0.0; m]).collect();
        if let Some(c0) = &options.start {
            check_vector("start", c0, n)?;
            for (zi, term) in z.iter_mut().zip(terms) {
                term.apply(c0, zi);
            }
        }
        let mut z_prev = z.clone();
        let mut alpha: Vec<Vec<f64>> = dims.iter().map(|&m| vec![0.0; m]).collect();
        let mut pc = z.clone();
        let mut work: Vec<Vec<f64>> = z.clone();
        let mut dual = vec![0.0; n];
        let mut at_alpha = vec![0.0; n];
        let mut rhs = vec![0.0; n];
        let rho = options.relaxation;

        let mut stop = AdmmStop::MaxIterations;
        let (mut iterations, mut r, mut s) = (0, f64::INFINITY, f64::INFINITY);
        for iteration in 1..=options.max_iter {
            iterations = iteration;
            // c-step: (H + kηI) c = b + Σ P_iᵀ(η z_i − α_i).
            c.copy_from_slice(b);
            for (i, term) in terms.iter().enumerate() {
                for ((w, &zi), &ai) in work[i].iter_mut().zip(&z[i]).zip(&alpha[i]) {
                    *w = eta * zi - ai;
                }
                term.apply_transpose_add(&work[i], &mut c);
            }
            rhs.copy_from_slice(&c);
            solve_in_place(factor.as_ref(), &mut c);
            if let Some(index) = c.iter().position(|v| !v.is_finite()) {
                let e = AdmmError::NonFiniteVector {
                    what: "the iterate c",
                    index,
                };
                return Err(runaway(h, e, iteration));
            }

            // z-step and dual step, with the residuals' ingredients.
            let (mut r2, mut pc2, mut z2) = (0.0, 0.0, 0.0);
            dual.fill(0.0);
            at_alpha.fill(0.0);
            for (i, term) in terms.iter().enumerate() {
                term.apply(&c, &mut pc[i]);
                // The relaxed P_i c: ρ P_i c + (1 − ρ) z_i^{prev} (exactly P_i c for ρ = 1).
                let relaxed = |j: usize, z_prev: &[f64]| rho * pc[i][j] + (1.0 - rho) * z_prev[j];
                for j in 0..dims[i] {
                    work[i][j] = relaxed(j, &z[i]) + alpha[i][j] / eta;
                }
                std::mem::swap(&mut z[i], &mut z_prev[i]);
                term.prox(&work[i], 1.0 / eta, &mut z[i])
                    .map_err(|e| runaway(h, e, iteration))?;
                for j in 0..dims[i] {
                    alpha[i][j] += eta * (relaxed(j, &z_prev[i]) - z[i][j]);
                    let ri = pc[i][j] - z[i][j];
                    r2 += ri * ri;
                    pc2 += pc[i][j] * pc[i][j];
                    z2 += z[i][j] * z[i][j];
                    work[i][j] = z[i][j] - z_prev[i][j];
                }
                term.apply_transpose_add(&work[i], &mut dual);
                term.apply_transpose_add(&alpha[i], &mut at_alpha);
            }
            r = r2.sqrt();
            s = eta * norm(&dual);
            if !(r.is_finite() && s.is_finite() && pc2.is_finite() && z2.is_finite()) {
                // Squares past f64's range: the tolerances, scaled by the iterates, would be
                // infinite too and take the run for converged.
                let e = AdmmError::NonFiniteVector {
                    what: "the residual norms ‖P c − z‖, ‖P c‖, ‖z‖ (index 0: all of them)",
                    index: 0,
                };
                return Err(runaway(h, e, iteration));
            }
            let report = AdmmProgress {
                iteration,
                primal_residual: r,
                dual_residual: s,
                primal_tolerance: options.eps_abs * (p as f64).sqrt()
                    + options.eps_rel * pc2.sqrt().max(z2.sqrt()),
                dual_tolerance: options.eps_abs * (n as f64).sqrt()
                    + options.eps_rel * norm(&at_alpha),
            };
            if r <= report.primal_tolerance && s <= report.dual_tolerance {
                stop = AdmmStop::Converged;
                progress(&report);
                break;
            }
            if !progress(&report) {
                stop = AdmmStop::Cancelled;
                break;
            }
        }
        // The last c-step solved (H + kηI) c = rhs: cᵀHc = cᵀ(rhs − kηc), no product with H.
        let quadratic = c
            .iter()
            .zip(&rhs)
            .zip(b)
            .map(|((&ci, &ri), &bi)| ci * (0.5 * (ri - k as f64 * eta * ci) - bi))
            .sum::<f64>();
        let objective = quadratic + terms_value(terms, &c)?;
        Ok(AdmmSolution {
            c,
            z,
            iterations,
            primal_residual: r,
            dual_residual: s,
            converged: stop == AdmmStop::Converged,
            stop,
            objective,
        })
    }
}

/// The minimiser of `½cᵀHc − bᵀc + ½ ridge ‖c‖²`, by a sequential dense Cholesky of
/// `H + ridge·I`: the solution without the proximal terms, a warm start for [`admm`]
/// ([`AdmmOptions::start`]).
///
/// # Errors
/// [`AdmmError::NotSquare`], [`AdmmError::Length`], [`AdmmError::NonFiniteMatrix`],
/// [`AdmmError::NonFiniteVector`], [`AdmmError::NotSymmetric`];
/// [`AdmmError::NotPositiveDefinite`] if `H + ridge·I` has no Cholesky factor.
pub fn ridge_solution(h: MatRef<'_, f64>, b: &[f64], ridge: f64) -> Result<Vec<f64>, AdmmError> {
    Quadratic::new(h, b)?.ridge_solution(ridge)
}

/// The objective `½cᵀHc − bᵀc + Σ_i g_i(P_i c)`, summed in a fixed order.
///
/// # Errors
/// [`AdmmError::NotSquare`], [`AdmmError::Length`] (of `b` or `c`),
/// [`AdmmError::TermDimension`], [`AdmmError::NonFiniteMatrix`] / [`AdmmError::NonFiniteVector`]
/// (`H`, `b`, `c`); whatever a term's `value` returns.
pub fn objective(
    h: MatRef<'_, f64>,
    b: &[f64],
    terms: &[&dyn ProxTerm],
    c: &[f64],
) -> Result<f64, AdmmError> {
    let n = check_problem(h, b, terms)?;
    check_matrix(h, false)?;
    check_vector("c", c, n)?;
    let mut quadratic = 0.0;
    for (j, &cj) in c.iter().enumerate() {
        let hc_j: f64 = with_column(h, j, |col| col.iter().zip(c).map(|(a, x)| a * x).sum());
        quadratic += cj * (0.5 * hc_j - b[j]);
    }
    Ok(quadratic + terms_value(terms, c)?)
}

/// `Σ_i g_i(P_i c)`, in order.
fn terms_value(terms: &[&dyn ProxTerm], c: &[f64]) -> Result<f64, AdmmError> {
    let mut total = 0.0;
    for term in terms {
        let mut z = vec![0.0; term.dims().0];
        term.apply(c, &mut z);
        total += term.value(&z)?;
    }
    Ok(total)
}

/// Checks the shapes of `H`, `b` and the terms, and that `b` is finite; returns `n`.
fn check_problem(
    h: MatRef<'_, f64>,
    b: &[f64],
    terms: &[&dyn ProxTerm],
) -> Result<usize, AdmmError> {
    let (rows, cols) = (h.nrows(), h.ncols());
    if rows != cols {
        return Err(AdmmError::NotSquare { rows, cols });
    }
    let n = rows;
    if b.len() != n {
        return Err(AdmmError::Length {
            what: "b",
            expected: n,
            got: b.len(),
        });
    }
    check_terms(n, terms)?;
    if let Some(index) = b.iter().position(|v| !v.is_finite()) {
        return Err(AdmmError::NonFiniteVector { what: "b", index });
    }
    Ok(n)
}

/// Checks that the vector `what` has length `n` and finite entries.
fn check_vector(what: &'static str, v: &[f64], n: usize) -> Result<(), AdmmError> {
    if v.len() != n {
        return Err(AdmmError::Length {
            what,
            expected: n,
            got: v.len(),
        });
    }
    if let Some(index) = v.iter().position(|x| !x.is_finite()) {
        return Err(AdmmError::NonFiniteVector { what, index });
    }
    Ok(())
}

/// Checks that every term maps `ℝⁿ`; returns `n`.
fn check_terms(n: usize, terms: &[&dyn ProxTerm]) -> Result<usize, AdmmError> {
    for (term, t) in terms.iter().enumerate() {
        let got = t.dims().1;
        if got != n {
            return Err(AdmmError::TermDimension {
                term,
                expected: n,
                got,
            });
        }
    }
    Ok(n)
}

/// Checks the square `H` in one pass over its entries: every entry finite, and with
/// `symmetric`, `|H_ij − H_ji| ≤ 10⁻¹⁰ · max |H_ij|`. The pass visits 64 × 64 tiles of the
/// lower triangle with their mirrored upper tiles, so that the transposed reads stay in
/// cache, and keeps branch-free running figures (a sum that turns NaN at a non-finite entry,
/// the largest magnitude and the largest asymmetry); the position of a failure is searched
/// for only when there is one (the first non-finite entry in column order; the first
/// asymmetric pair in tile order).
fn check_matrix(h: MatRef<'_, f64>, symmetric: bool) -> Result<(), AdmmError> {
    let n = h.nrows();
    let owned;
    let h = match h.try_as_col_major() {
        Some(_) => h,
        None => {
            owned = h.to_owned();
            owned.as_ref()
        }
    };
    let columns: Vec<&[f64]> = (0..n)
        .map(|j| {
            h.col(j)
                .try_as_col_major()
                .expect("a column-major matrix")
                .as_slice()
        })
        .collect();
    // `0·x` is 0 for a finite x and NaN otherwise: the sum is NaN where any entry is not
    // finite. Selects instead of f64::max keep the loops vectorisable.
    let (mut poison, mut largest, mut asymmetry) = (0.0f64, 0.0f64, 0.0f64);
    const TILE: usize = 64;
    for c0 in (0..n).step_by(TILE) {
        for r0 in (c0..n).step_by(TILE) {
            for col in c0..(c0 + TILE).min(n) {
                let (first, end) = (r0.max(col), (r0 + TILE).min(n));
                if first >= end {
                    continue;
                }
                let below = &columns[col][first..end];
                let above = &columns[first..end];
                let (p, l, a) = below.iter().zip(above).fold(
                    (0.0f64, 0.0f64, 0.0f64),
                    |(p, l, a), (&x, column)| {
                        let y = column[col];
                        let m = if x.abs() > y.abs() { x.abs() } else { y.abs() };
                        let d = (x - y).abs();
                        (
                            p + x * 0.0 + y * 0.0,
                            if m > l { m } else { l },
                            if d > a { d } else { a },
                        )
                    },
                );
                poison += p;
                largest = if l > largest { l } else { largest };
                asymmetry = if a > asymmetry { a } else { asymmetry };
            }
        }
    }
    if !poison.is_finite() {
        for (col, column) in columns.iter().enumerate() {
            if let Some(row) = column.iter().position(|v| !v.is_finite()) {
                return Err(AdmmError::NonFiniteMatrix { row, col });
            }
        }
    }
    let tol = 1e-10 * largest;
    if symmetric && asymmetry > tol {
        for c0 in (0..n).step_by(TILE) {
            for r0 in (c0..n).step_by(TILE) {
                let tile = columns.iter().enumerate().take((c0 + TILE).min(n)).skip(c0);
                for (col, column) in tile {
                    let rows = r0.max(col + 1)..(r0 + TILE).min(n);
                    if let Some(row) = rows
                        .into_iter()
                        .find(|&row| (column[row] - columns[row][col]).abs() > tol)
                    {
                        return Err(AdmmError::NotSymmetric { row, col });
                    }
                }
            }
        }
    }
    Ok(())
}

/// `f` of column `j` of `h` as a slice (copied where `h`'s rows are not contiguous).
fn with_column<R>(h: MatRef<'_, f64>, j: usize, f: impl FnOnce(&[f64]) -> R) -> R {
    match h.col(j).try_as_col_major() {
        Some(col) => f(col.as_slice()),
        None => f(&h.col(j).iter().copied().collect::<Vec<_>>()),
    }
}

/// Checks `PᵀP x = x` on a fixed irregular probe `x`.
fn check_orthogonal(terms: &[&dyn ProxTerm], n: usize) -> Result<(), AdmmError> {
    let x: Vec<f64> = (0..n)
        .map(|j| 1.0 + ((j * 7919 + 13) % 101) as f64 / 101.0)
        .collect();
    for (term, t) in terms.iter().enumerate() {
        let m = t.dims().0;
        if m < n {
            return Err(AdmmError::NotOrthogonal {
                term,
                defect: f64::INFINITY,
            });
        }
        let mut y = vec![0.0; m];
        t.apply(&x, &mut y);
        let mut back = vec![0.0; n];
        t.apply_transpose_add(&y, &mut back);
        let defect = back
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / 2.0; // ‖x‖_∞ ≤ 2
        if defect.is_nan() || defect > 1e-10 {
            return Err(AdmmError::NotOrthogonal { term, defect });
        }
    }
    Ok(())
}

/// The lower Cholesky factor of `H + shift·I`, computed sequentially (strict upper part
/// zeroed).
fn factor_shifted(h: MatRef<'_, f64>, shift: f64, terms: usize) -> Result<Mat<f64>, AdmmError> {
    let n = h.nrows();
    let mut l = h.to_owned();
    for i in 0..n {
        l[(i, i)] += shift;
    }
    let par = Par::Seq;
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(n, par, Default::default()));
    cholesky_in_place(
        l.as_mut(),
        LltRegularization::default(),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|e| match e {
        LltError::NonPositivePivot { index } => AdmmError::NotPositiveDefinite {
            pivot: index,
            terms,
        },
    })?;
    for col in 1..n {
        l.col_as_slice_mut(col)[..col].fill(0.0);
    }
    Ok(l)
}

/// The error to report when the iterates ran away with `error` at `iteration`:
/// [`AdmmError::NotPositiveSemiDefinite`] where `H + δI` has no Cholesky factor (the cause),
/// else `error` itself.
fn runaway(h: MatRef<'_, f64>, error: AdmmError, iteration: usize) -> AdmmError {
    let largest = (0..h.nrows()).fold(0.0f64, |a, i| a.max(h[(i, i)].abs()));
    if largest == 0.0 {
        // A zero diagonal: H is 0 (positive semi-definite) or indefinite; no shift to test
        // with, so the error stands.
        return error;
    }
    match factor_shifted(h, 1e-10 * largest, 0) {
        Err(AdmmError::NotPositiveDefinite { pivot, .. }) => {
            AdmmError::NotPositiveSemiDefinite { pivot, iteration }
        }
        _ => error,
    }
}

/// `x ← (L Lᵀ)⁻¹ x`, sequentially.
fn solve_in_place(l: MatRef<'_, f64>, x: &mut [f64]) {
    let n = x.len();
    let mut rhs = MatMut::from_column_major_slice_mut(x, n, 1);
    solve_lower_triangular_in_place(l, rhs.as_mut(), Par::Seq);
    solve_upper_triangular_in_place(l.transpose(), rhs.as_mut(), Par::Seq);
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}
