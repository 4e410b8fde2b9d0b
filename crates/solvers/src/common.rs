//! What every solver shares: input checks, the residual report, iteration parameters and
//! progress reporting.

use std::ops::ControlFlow;
use std::sync::Arc;
use std::time::Instant;

use zeroset_field_core::lsq::{
    LinearOperator, LsqMatrix, Monitor, Progress, SolveError, SolveInfo, Stage,
};

use crate::kernels::norm2;
use crate::operator::Prepared;
use crate::precond::Preconditioner;

/// Checks `b` against `A` and prepares `A`. Returns the prepared matrix.
pub(crate) fn prepare<'a>(a: LsqMatrix<'a>, b: &[f64]) -> Result<Prepared<'a>, SolveError> {
    let (m, _) = a.shape();
    if b.len() != m {
        return Err(SolveError::ShapeMismatch {
            what: "right-hand side b",
            expected: m,
            got: b.len(),
        });
    }
    if let Some((index, &value)) = b.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(SolveError::NonFinite {
            what: "right-hand side",
            index,
            value,
        });
    }
    Prepared::new(a)
}

/// `(‖b − Ax‖/‖b‖, ‖Aᵀ(b − Ax)‖/(‖A‖ ‖b − Ax‖))`, measured exactly.
pub(crate) fn residuals(a: &Prepared<'_>, a_norm: f64, x: &[f64], b: &[f64]) -> (f64, f64) {
    let (m, n) = a.shape();
    let mut r = vec![0.0; m];
    a.apply(x, &mut r);
    r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
    let mut atr = vec![0.0; n];
    a.apply_transpose(&r, &mut atr);
    let (rn, bn) = (norm2(&r), norm2(b));
    let rel = if bn > 0.0 { rn / bn } else { rn };
    let normal = if rn > 0.0 && a_norm > 0.0 {
        norm2(&atr) / (a_norm * rn)
    } else {
        0.0
    };
    (rel, normal)
}

/// Builds the report after a solve: residuals are re-measured on the original `A`, so every
/// solver's report means the same thing.
///
/// # Errors
/// [`SolveError::NonFinite`] where the answer or its residual is NaN or infinite (checked
/// input cannot make one; a user's operator or preconditioner that returns one can, and the
/// answer must not pass for a solution).
pub(crate) fn finish(
    solver: &'static str,
    a: &Prepared<'_>,
    x: Vec<f64>,
    b: &[f64],
    iterations: usize,
    start: Instant,
    details: Vec<(&'static str, f64)>,
) -> Result<zeroset_field_core::lsq::Solution, SolveError> {
    check_answer(&x)?;
    let a_norm = a.norm_estimate();
    let (rel, normal) = residuals(a, a_norm, &x, b);
    check_residual(rel)?;
    let mut info = SolveInfo::new(solver, iterations, rel, normal, start.elapsed());
    info.details = details;
    Ok(zeroset_field_core::lsq::Solution { x, info })
}

/// [`SolveError::NonFinite`] for the first NaN or infinity in an answer.
pub(crate) fn check_answer(x: &[f64]) -> Result<(), SolveError> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(SolveError::NonFinite {
            what: "the solution (a NaN or infinity from the operator or preconditioner?)",
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// [`SolveError::NonFinite`] for a NaN or infinite relative residual `‖b − Ax‖/‖b‖` of a
/// finite answer (the operator returned one).
pub(crate) fn check_residual(rel: f64) -> Result<(), SolveError> {
    if rel.is_finite() {
        Ok(())
    } else {
        Err(SolveError::NonFinite {
            what: "the residual b − A x of the solution (a NaN or infinity from the operator?)",
            index: 0,
            value: rel,
        })
    }
}

/// [`SolveError::InvalidTolerance`] for a tolerance that is negative or NaN (`+∞` is a
/// number: it stops at the first test).
pub(crate) fn check_tolerance(what: &'static str, value: f64) -> Result<(), SolveError> {
    if value >= 0.0 {
        Ok(())
    } else {
        Err(SolveError::InvalidTolerance { what, value })
    }
}

/// A direct solver's rank tolerance: the one given (checked by [`check_tolerance`]: a NaN
/// would switch the rank check off) or `default`.
pub(crate) fn rank_tolerance(given: Option<f64>, default: f64) -> Result<f64, SolveError> {
    let tau = given.unwrap_or(default);
    check_tolerance("rank_tolerance", tau)?;
    Ok(tau)
}

/// A tolerance as the stopping tests use it: at least the machine epsilon, so that `0` (or any
/// smaller value) stops where rounding leaves nothing to gain instead of iterating on rounding
/// noise (CGLS's iterate grew without bound that way, to `x ≈ 3·10¹⁰` on a 10 × 3 problem
/// after 100 iterations at `tol = 0`), as SciPy's `lsqr` stops "at machine precision".
pub(crate) fn effective_tolerance(tol: f64) -> f64 {
    tol.max(f64::EPSILON)
}

/// Parameters shared by the iterative least-squares solvers (CGLS, LSQR).
///
/// The stopping rule is Paige and Saunders': stop when
/// `‖r‖ ≤ btol·‖b‖ + atol·‖A‖·‖x‖` (a compatible system is solved) or when
/// `‖Aᵀr‖ ≤ atol·‖A‖·‖r‖` (a least-squares solution is found). Tolerances below the machine
/// epsilon (`0` included) count as the epsilon; negative or NaN ones are refused
/// ([`SolveError::InvalidTolerance`]).
///
/// The second test, [`SolveInfo::rel_normal_residual`](zeroset_field_core::lsq::SolveInfo),
/// is what tells a least-squares solution of an inconsistent system; for a consistent one
/// (`b` in the range of `A`: `rel_residual` near 0) it is a ratio of two rounding errors and
/// says nothing (an exact QR answer reports 0.1–0.5 there): read `rel_residual` instead. LSQR
/// stops on its own estimates of `‖r‖` and `‖Aᵀr‖`, so the report's exact figure can exceed
/// `atol` by a small factor (SciPy's `lsqr` alike).
///
/// Neither test bounds the error in `x`: where `A` is ill-conditioned the error can be
/// `cond(A)` times larger. On a 300 × 60 problem with one column scaled by 1e-7 (cond 1.5e7)
/// both iterative solvers stopped with `rel_normal_residual` 3.9e-11 and that column's
/// coefficient 100% wrong; [`Diagonal::column_scaling`](crate::precond::Diagonal::column_scaling) as the
/// preconditioner, or a direct solver, finds it.
///
/// The first test grows with `‖x‖`: on an ill-conditioned problem whose answer is large (a
/// column scaled by 1e-7, `‖x‖ ≈ 4·10⁷`) it stops where `Aᵀr` is still far from 0, as SciPy's
/// `lsqr` does. The report's [`SolveInfo::rel_normal_residual`](zeroset_field_core::lsq::SolveInfo)
/// (3e-2 there; 1e-10 and below for a least-squares solution) says which kind of answer it is:
/// check it, or use a direct solver, on such problems.
#[derive(Clone, Debug)]
pub struct IterativeParams {
    /// Relative accuracy of `A` (default `1e-10`).
    pub atol: f64,
    /// Relative accuracy of `b` (default `1e-10`).
    pub btol: f64,
    /// Iteration limit; `None` means `max(2n, 100)`.
    pub max_iterations: Option<usize>,
    /// A right preconditioner `M`: the solver works on `A M⁻¹` and returns `x = M⁻¹ y`.
    pub preconditioner: Option<Arc<dyn Preconditioner>>,
    /// Progress callback, called every iteration; it may cancel.
    pub monitor: Option<Monitor>,
}

impl Default for IterativeParams {
    fn default() -> Self {
        Self {
            atol: 1e-10,
            btol: 1e-10,
            max_iterations: None,
            preconditioner: None,
            monitor: None,
        }
    }
}

impl IterativeParams {
    /// [`SolveError::InvalidTolerance`] for a negative or NaN `atol` or `btol`.
    pub(crate) fn check(&self) -> Result<(), SolveError> {
        check_tolerance("atol", self.atol)?;
        check_tolerance("btol", self.btol)
    }

    /// Sets `atol = btol = tol`.
    pub fn with_tolerance(mut self, tol: f64) -> Self {
        self.atol = tol;
        self.btol = tol;
        self
    }

    /// Sets the iteration limit.
    pub fn with_max_iterations(mut self, max: usize) -> Self {
        self.max_iterations = Some(max);
        self
    }

    /// Sets the right preconditioner.
    pub fn with_preconditioner(mut self, p: Arc<dyn Preconditioner>) -> Self {
        self.preconditioner = Some(p);
        self
    }

    /// Sets the progress callback.
    pub fn with_monitor(mut self, m: Monitor) -> Self {
        self.monitor = Some(m);
        self
    }

    pub(crate) fn limit(&self, n: usize) -> usize {
        self.max_iterations.unwrap_or((2 * n).max(100))
    }
}

/// Default relative pivot threshold of the normal-equation solvers: a pivot (`u_kk` or `l_kk²`)
/// at or below `τ·(AᵀA)_kk` marks column `k` as dependent.
pub const NORMAL_RANK_TOLERANCE: f64 = 1e-12;

/// Parameters shared by the direct solvers.
#[derive(Clone, Debug, Default)]
pub struct DirectParams {
    /// Relative pivot threshold below which a column counts as dependent; `None` picks a
    /// default suited to the factorisation (documented on each solver).
    pub rank_tolerance: Option<f64>,
    /// Progress callback, called between stages (analyse, factorise, solve); it may cancel.
    pub monitor: Option<Monitor>,
}

impl DirectParams {
    /// Sets the rank tolerance.
    pub fn with_rank_tolerance(mut self, tol: f64) -> Self {
        self.rank_tolerance = Some(tol);
        self
    }

    /// Sets the progress callback.
    pub fn with_monitor(mut self, m: Monitor) -> Self {
        self.monitor = Some(m);
        self
    }
}

/// Reports a direct solver's stage to the monitor; `Err(Cancelled)` if it says stop.
pub(crate) fn stage(
    monitor: &Option<Monitor>,
    solver: &'static str,
    stage: Stage,
    done: usize,
) -> Result<(), SolveError> {
    report(monitor, solver, stage, done, 3, f64::NAN, f64::NAN)
}

/// Reports progress; `Err(Cancelled)` if the monitor says stop.
pub(crate) fn report(
    monitor: &Option<Monitor>,
    solver: &'static str,
    stage: Stage,
    iteration: usize,
    max_iterations: usize,
    rel_residual: f64,
    rel_normal_residual: f64,
) -> Result<(), SolveError> {
    if let Some(m) = monitor {
        let p = Progress::new(
            solver,
            stage,
            iteration,
            max_iterations,
            rel_residual,
            rel_normal_residual,
        );
        if let ControlFlow::Break(()) = m.report(&p) {
            return Err(SolveError::Cancelled {
                iterations: iteration,
            });
        }
    }
    Ok(())
}

/// The error for an iterative solver that ran out of iterations, with exact residuals and the
/// last iterate.
pub(crate) fn no_convergence(
    a: &Prepared<'_>,
    x: Vec<f64>,
    b: &[f64],
    iterations: usize,
) -> SolveError {
    let (rel_residual, rel_normal_residual) = residuals(a, a.norm_estimate(), &x, b);
    SolveError::NoConvergence {
        iterations,
        rel_residual,
        rel_normal_residual,
        x,
    }
}
