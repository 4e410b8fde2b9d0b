//! The least-squares contract: `min_x ‖A x − b‖₂`.
//!
//! For `A ∈ R^{m×n}` with full column rank the minimiser is unique,
//! `x* = (AᵀA)⁻¹Aᵀb`, and satisfies the normal equations `Aᵀ(b − A x*) = 0`. Every
//! [`LeastSquaresSolver`] must return that `x*` (to its tolerance) and report how close it got:
//!
//! ```text
//! rel_residual        = ‖b − A x‖ / ‖b‖
//! rel_normal_residual = ‖Aᵀ(b − A x)‖ / (‖A‖_F · ‖b − A x‖)
//! ```
//!
//! The second is Paige and Saunders' stopping test for LSQR (ACM TOMS 8(1), 1982, §6): it is
//! scale-free and tends to zero at the least-squares solution even when the residual itself does
//! not (an inconsistent system). For a consistent system (`rel_residual` near 0) it is a ratio
//! of rounding errors and means nothing. For a matrix-free operator `‖A‖_F` is not known:
//! `‖A‖₂ ≤ ‖A‖_F`, estimated by power iteration, stands in for it, so the same matrix reports
//! a larger figure as an operator than as a matrix. Neither figure bounds the error in `x`,
//! which can be `cond(A)` times larger. When `A` does not have full column rank the solution is not
//! unique: direct solvers report [`SolveError::RankDeficient`] naming the dependent column, and
//! iterative solvers return a least-squares solution (the minimum-norm one from a zero start).
//!
//! `A` reaches a solver as an [`LsqMatrix`]: a view of a dense or sparse matrix, or a matrix-free
//! [`LinearOperator`]. Nothing is copied to make the view; faer, ndarray and sprs matrices
//! convert with `.into()` (see [`crate::interop`]).
//!
//! ```
//! use faer::Mat;
//! use zeroset_field_core::lsq::{LsqMatrix, LinearOperator};
//!
//! let a = Mat::from_fn(3, 2, |i, j| (i + j) as f64);
//! let view: LsqMatrix<'_> = (&a).into();
//! assert_eq!(view.shape(), (3, 2));
//! let mut y = vec![0.0; 3];
//! view.apply(&[1.0, 1.0], &mut y);
//! assert_eq!(y, vec![1.0, 3.0, 5.0]);
//! ```

use std::fmt;
use std::ops::ControlFlow;
use std::sync::Arc;
use std::time::Duration;

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMat, SparseRowMatRef};
use faer::{Mat, MatRef};

/// A matrix-free linear map `A: Rⁿ → Rᵐ` with its transpose.
///
/// Implementations must be deterministic: the same input gives bit-identical output whatever
/// the number of threads.
pub trait LinearOperator: Send + Sync {
    /// `m`, the length of `A x`.
    fn nrows(&self) -> usize;
    /// `n`, the length of `x`.
    fn ncols(&self) -> usize;
    /// `y ← A x`. `x.len() == ncols()`, `y.len() == nrows()`.
    fn apply(&self, x: &[f64], y: &mut [f64]);
    /// `x ← Aᵀ y`. `y.len() == nrows()`, `x.len() == ncols()`.
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]);
}

/// A view of the matrix `A` of a least-squares problem. Cheap to copy; borrows the data.
#[derive(Clone, Copy)]
pub enum LsqMatrix<'a> {
    /// A dense matrix (any strides).
    Dense(MatRef<'a, f64>),
    /// A compressed sparse column matrix.
    SparseCol(SparseColMatRef<'a, usize, f64>),
    /// A compressed sparse row matrix (how design matrices are naturally assembled).
    SparseRow(SparseRowMatRef<'a, usize, f64>),
    /// A matrix-free operator. Direct solvers cannot factor it and say so.
    Operator(&'a dyn LinearOperator),
}

impl fmt::Debug for LsqMatrix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (m, n) = self.shape();
        let kind = match self {
            Self::Dense(_) => "Dense",
            Self::SparseCol(_) => "SparseCol",
            Self::SparseRow(_) => "SparseRow",
            Self::Operator(_) => "Operator",
        };
        write!(f, "LsqMatrix::{kind}({m}×{n})")
    }
}

impl LsqMatrix<'_> {
    /// `(m, n)`.
    pub fn shape(&self) -> (usize, usize) {
        match self {
            Self::Dense(a) => (a.nrows(), a.ncols()),
            Self::SparseCol(a) => (a.nrows(), a.ncols()),
            Self::SparseRow(a) => (a.nrows(), a.ncols()),
            Self::Operator(a) => (a.nrows(), a.ncols()),
        }
    }

    /// The stored entries (`m·n` for dense, the structural non-zeros for sparse), or `None`
    /// for an operator.
    pub fn stored_values(&self) -> Option<Box<dyn Iterator<Item = f64> + '_>> {
        match self {
            Self::Dense(a) => Some(Box::new(
                (0..a.ncols()).flat_map(move |j| (0..a.nrows()).map(move |i| a[(i, j)])),
            )),
            Self::SparseCol(a) => Some(Box::new(a.val().iter().copied())),
            Self::SparseRow(a) => Some(Box::new(a.val().iter().copied())),
            Self::Operator(_) => None,
        }
    }
}

/// Sequential reference products. Solvers in `zeroset-solvers` use parallel deterministic
/// kernels instead; these keep the view usable on its own.
impl LinearOperator for LsqMatrix<'_> {
    fn nrows(&self) -> usize {
        self.shape().0
    }
    fn ncols(&self) -> usize {
        self.shape().1
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let (m, n) = self.shape();
        assert_eq!(
            (x.len(), y.len()),
            (n, m),
            "LsqMatrix::apply: wrong lengths"
        );
        match self {
            Self::Dense(a) => {
                for (i, yi) in y.iter_mut().enumerate() {
                    *yi = (0..n).map(|j| a[(i, j)] * x[j]).sum();
                }
            }
            Self::SparseCol(a) => {
                y.fill(0.0);
                for (j, &xj) in x.iter().enumerate() {
                    for (i, v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
                        y[i] += v * xj;
                    }
                }
            }
            Self::SparseRow(a) => {
                for (i, yi) in y.iter_mut().enumerate() {
                    *yi = a
                        .col_idx_of_row(i)
                        .zip(a.val_of_row(i))
                        .map(|(j, v)| v * x[j])
                        .sum();
                }
            }
            Self::Operator(op) => op.apply(x, y),
        }
    }
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
        let (m, n) = self.shape();
        assert_eq!(
            (y.len(), x.len()),
            (m, n),
            "LsqMatrix::apply_transpose: wrong lengths"
        );
        match self {
            Self::Dense(a) => {
                for (j, xj) in x.iter_mut().enumerate() {
                    *xj = (0..m).map(|i| a[(i, j)] * y[i]).sum();
                }
            }
            Self::SparseCol(a) => {
                for (j, xj) in x.iter_mut().enumerate() {
                    *xj = a
                        .row_idx_of_col(j)
                        .zip(a.val_of_col(j))
                        .map(|(i, v)| v * y[i])
                        .sum();
                }
            }
            Self::SparseRow(a) => {
                x.fill(0.0);
                for (i, &yi) in y.iter().enumerate() {
                    for (j, v) in a.col_idx_of_row(i).zip(a.val_of_row(i)) {
                        x[j] += v * yi;
                    }
                }
            }
            Self::Operator(op) => op.apply_transpose(y, x),
        }
    }
}

impl<'a> From<MatRef<'a, f64>> for LsqMatrix<'a> {
    fn from(a: MatRef<'a, f64>) -> Self {
        Self::Dense(a)
    }
}
impl<'a> From<&'a Mat<f64>> for LsqMatrix<'a> {
    fn from(a: &'a Mat<f64>) -> Self {
        Self::Dense(a.as_ref())
    }
}
impl<'a> From<SparseColMatRef<'a, usize, f64>> for LsqMatrix<'a> {
    fn from(a: SparseColMatRef<'a, usize, f64>) -> Self {
        Self::SparseCol(a)
    }
}
impl<'a> From<&'a SparseColMat<usize, f64>> for LsqMatrix<'a> {
    fn from(a: &'a SparseColMat<usize, f64>) -> Self {
        Self::SparseCol(a.as_ref())
    }
}
impl<'a> From<SparseRowMatRef<'a, usize, f64>> for LsqMatrix<'a> {
    fn from(a: SparseRowMatRef<'a, usize, f64>) -> Self {
        Self::SparseRow(a)
    }
}
impl<'a> From<&'a SparseRowMat<usize, f64>> for LsqMatrix<'a> {
    fn from(a: &'a SparseRowMat<usize, f64>) -> Self {
        Self::SparseRow(a.as_ref())
    }
}
impl<'a, T: LinearOperator> From<&'a T> for LsqMatrix<'a> {
    fn from(a: &'a T) -> Self {
        Self::Operator(a)
    }
}

/// What a solver reports with its answer. Every solver fills the residuals the same way (see
/// the module docs), so reports are comparable across solvers.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SolveInfo {
    /// The solver's name, e.g. `"lsqr"`.
    pub solver: &'static str,
    /// Iterations taken (iterative solvers); 0 for direct solvers.
    pub iterations: usize,
    /// `‖b − A x‖ / ‖b‖` (0 when `b = 0`).
    pub rel_residual: f64,
    /// `‖Aᵀ(b − A x)‖ / (‖A‖_F ‖b − A x‖)` (0 when the residual is 0; `‖A‖₂`, estimated,
    /// for an operator: see the [module docs](self)).
    pub rel_normal_residual: f64,
    /// Wall-clock time of the whole solve, set-up included.
    pub elapsed: Duration,
    /// Solver-specific figures, e.g. `("nnz_l", 1.2e6)` for a Cholesky factor.
    pub details: Vec<(&'static str, f64)>,
}

impl SolveInfo {
    /// A report with no details.
    pub fn new(
        solver: &'static str,
        iterations: usize,
        rel_residual: f64,
        rel_normal_residual: f64,
        elapsed: Duration,
    ) -> Self {
        Self {
            solver,
            iterations,
            rel_residual,
            rel_normal_residual,
            elapsed,
            details: Vec::new(),
        }
    }

    /// Looks a detail up by name.
    pub fn detail(&self, name: &str) -> Option<f64> {
        self.details
            .iter()
            .find(|(k, _)| *k == name)
            .map(|&(_, v)| v)
    }
}

/// A solver's answer: `x` and the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The minimiser, length `n`.
    pub x: Vec<f64>,
    /// How it was obtained.
    pub info: SolveInfo,
}

/// `, relative normal-equation residual …` where it was measured.
fn normal_clause(rel_normal_residual: f64) -> String {
    if rel_normal_residual.is_nan() {
        String::new()
    } else {
        format!(", relative normal-equation residual {rel_normal_residual:.3e}")
    }
}

/// Why a solve failed. Every variant carries what a user needs to act on it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolveError {
    /// `b` (or an initial guess) does not match `A`.
    #[error("shape mismatch: {what} has length {got}, expected {expected}")]
    ShapeMismatch {
        /// Which vector.
        what: &'static str,
        /// The length `A` implies.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// A NaN or infinity in the input.
    #[error("non-finite value ({value}) in {what} at index {index}")]
    NonFinite {
        /// `"matrix"` or `"right-hand side"`; or what a solver found non-finite in its own
        /// work (the solution, a product of a user's operator or preconditioner).
        what: &'static str,
        /// The position (stored-entry index for a sparse matrix).
        index: usize,
        /// The value.
        value: f64,
    },
    /// More unknowns than equations: a direct least-squares solver needs `m ≥ n`.
    #[error(
        "underdetermined: {nrows} equations for {ncols} unknowns; use an iterative solver for a minimum-norm solution"
    )]
    Underdetermined {
        /// `m`.
        nrows: usize,
        /// `n`.
        ncols: usize,
    },
    /// `A` does not have full column rank (to working precision): the solution is not unique.
    #[error(
        "rank deficient: column {column} is (numerically) a combination of other columns: pivot {pivot:.3e} at or below threshold {threshold:.3e}"
    )]
    RankDeficient {
        /// The dependent column, in the caller's numbering.
        column: usize,
        /// The pivot that revealed it (`|r_kk|` for QR, `|u_kk|` or `l_kk²` for the normal
        /// equations).
        pivot: f64,
        /// The threshold it fell below.
        threshold: f64,
    },
    /// A symmetric system that is not positive definite (PCG, Cholesky on a given SPD matrix).
    #[error("matrix is not positive definite: pivot {index} is {value:.3e}")]
    NotPositiveDefinite {
        /// The pivot or iteration where it showed.
        index: usize,
        /// The non-positive value (a pivot, or `pᵀAp`).
        value: f64,
    },
    /// An iterative solver stopped at its iteration limit before meeting its tolerance.
    #[error(
        "no convergence after {iterations} iterations: relative residual {rel_residual:.3e}{}",
        normal_clause(*.rel_normal_residual)
    )]
    NoConvergence {
        /// Iterations taken.
        iterations: usize,
        /// `‖b − A x‖/‖b‖` at the last iterate.
        rel_residual: f64,
        /// `‖Aᵀr‖/(‖A‖‖r‖)` at the last iterate (NaN where the solver was asked not to measure
        /// it: for an expensive operator it costs a norm estimate).
        rel_normal_residual: f64,
        /// The last iterate, so that the work is not lost.
        x: Vec<f64>,
    },
    /// A tolerance that is negative or NaN.
    #[error("{what} = {value}: a tolerance must be a number >= 0 (0 asks for machine precision)")]
    InvalidTolerance {
        /// Which tolerance (`atol`, `btol`, `tol`, `rank_tolerance`).
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// The progress callback asked to stop.
    #[error("cancelled after {iterations} iterations")]
    Cancelled {
        /// Iterations (or stages, for direct solvers) completed.
        iterations: usize,
    },
    /// The solver cannot take this kind of matrix (a direct solver given an operator).
    #[error("{solver} cannot solve with {reason}")]
    Unsupported {
        /// The solver.
        solver: &'static str,
        /// What it cannot take.
        reason: String,
    },
    /// A failure inside a factorisation that none of the above describes.
    #[error("{solver}: factorisation failed: {reason}")]
    Factorization {
        /// The solver.
        solver: &'static str,
        /// What the factorisation reported.
        reason: String,
    },
}

/// Where a solve stands, passed to a [`Monitor`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Progress {
    /// The solver's name.
    pub solver: &'static str,
    /// The stage (direct solvers go through several; iterative solvers iterate).
    pub stage: Stage,
    /// Iterations completed (iterative) or stages completed (direct).
    pub iteration: usize,
    /// The iteration limit (iterative), or the number of stages (direct).
    pub max_iterations: usize,
    /// Current `‖b − A x‖/‖b‖` estimate (`NaN` where not known yet).
    pub rel_residual: f64,
    /// Current `‖Aᵀr‖/(‖A‖‖r‖)` estimate (`NaN` where not known yet).
    pub rel_normal_residual: f64,
}

impl Progress {
    /// A progress report (solver crates build these; the struct is non-exhaustive).
    pub fn new(
        solver: &'static str,
        stage: Stage,
        iteration: usize,
        max_iterations: usize,
        rel_residual: f64,
        rel_normal_residual: f64,
    ) -> Self {
        Self {
            solver,
            stage,
            iteration,
            max_iterations,
            rel_residual,
            rel_normal_residual,
        }
    }
}

/// The phase a solver is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Stage {
    /// An iteration of an iterative method.
    Iterate,
    /// Symbolic analysis: orderings, elimination trees, the pattern of `AᵀA`.
    Analyze,
    /// Numeric factorisation.
    Factorize,
    /// Triangular solves.
    Solve,
}

type MonitorFn = dyn Fn(&Progress) -> ControlFlow<()> + Send + Sync;

/// A progress callback that can cancel: it sees a [`Progress`] every iteration (iterative) or
/// stage (direct) and returns `ControlFlow::Break(())` to stop; the solver then returns
/// [`SolveError::Cancelled`].
///
/// ```
/// use std::ops::ControlFlow;
/// use zeroset_field_core::lsq::Monitor;
///
/// let stop_after_ten = Monitor::new(|p| {
///     if p.iteration >= 10 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
/// });
/// # let _ = stop_after_ten;
/// ```
#[derive(Clone)]
pub struct Monitor(Arc<MonitorFn>);

impl Monitor {
    /// Wraps a callback.
    pub fn new(f: impl Fn(&Progress) -> ControlFlow<()> + Send + Sync + 'static) -> Self {
        Self(Arc::new(f))
    }

    /// Reports progress; `Break` means stop.
    pub fn report(&self, progress: &Progress) -> ControlFlow<()> {
        (self.0)(progress)
    }
}

impl fmt::Debug for Monitor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Monitor(..)")
    }
}

/// A solver of `min ‖A x − b‖₂`. Object safe: `Box<dyn LeastSquaresSolver>` lets a user or a
/// benchmark pick one at run time.
pub trait LeastSquaresSolver: Send + Sync {
    /// A short stable name, e.g. `"sparse-cholesky"`.
    fn name(&self) -> &'static str;

    /// Solves `min ‖A x − b‖₂`.
    ///
    /// # Errors
    /// See [`SolveError`]: bad shapes or values, rank deficiency (direct solvers), no
    /// convergence (iterative solvers), cancellation, an operator given to a direct solver.
    fn solve(&self, a: LsqMatrix<'_>, b: &[f64]) -> Result<Solution, SolveError>;
}

/// Convenience on every solver: pass anything that converts into an [`LsqMatrix`].
pub trait LeastSquaresSolverExt: LeastSquaresSolver {
    /// `self.solve(a.into(), b)`.
    fn solve_with<'a>(
        &self,
        a: impl Into<LsqMatrix<'a>>,
        b: &[f64],
    ) -> Result<Solution, SolveError> {
        self.solve(a.into(), b)
    }
}
impl<S: LeastSquaresSolver + ?Sized> LeastSquaresSolverExt for S {}

const _: () = {
    // The solver trait must stay object safe.
    fn _assert_object_safe(_: &dyn LeastSquaresSolver) {}
};

impl<S: LeastSquaresSolver + ?Sized> LeastSquaresSolver for Box<S> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn solve(&self, a: LsqMatrix<'_>, b: &[f64]) -> Result<Solution, SolveError> {
        (**self).solve(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::Triplet;

    #[test]
    fn every_view_applies_the_same_matrix() {
        let dense = Mat::from_fn(4, 3, |i, j| {
            if (i + j) % 2 == 0 {
                (i * 3 + j) as f64
            } else {
                0.0
            }
        });
        let triplets: Vec<_> = (0..4)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .filter(|&(i, j)| dense[(i, j)] != 0.0)
            .map(|(i, j)| Triplet::new(i, j, dense[(i, j)]))
            .collect();
        let csc = SparseColMat::<usize, f64>::try_new_from_triplets(4, 3, &triplets).unwrap();
        let csr = SparseRowMat::<usize, f64>::try_new_from_triplets(4, 3, &triplets).unwrap();
        let x = [1.0, -2.0, 0.5];
        let y = [0.5, 1.0, -1.0, 2.0];
        let views: [LsqMatrix<'_>; 3] = [(&dense).into(), (&csc).into(), (&csr).into()];
        let mut first = None;
        for v in views {
            let (mut ax, mut aty) = (vec![0.0; 4], vec![0.0; 3]);
            v.apply(&x, &mut ax);
            v.apply_transpose(&y, &mut aty);
            let op = LsqMatrix::Operator(&v);
            let (mut ax2, mut aty2) = (vec![0.0; 4], vec![0.0; 3]);
            op.apply(&x, &mut ax2);
            op.apply_transpose(&y, &mut aty2);
            assert_eq!((&ax, &aty), (&ax2, &aty2));
            match &first {
                None => first = Some((ax, aty)),
                Some(f) => assert_eq!(f, &(ax, aty), "{v:?}"),
            }
        }
    }
}
