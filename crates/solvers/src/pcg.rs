//! Preconditioned conjugate gradients for a symmetric positive definite system `K x = f`, and
//! for least squares through the normal equations `AᵀA x = Aᵀb` (matrix-free: `K v = Aᵀ(A v)`).
//!
//! With a preconditioner `M` (`MᵀM ≈ K`, see [`crate::precond`]) each iteration applies
//! `z = M⁻¹M⁻ᵀ r`. In exact arithmetic PCG converges in at most `n` steps, and the error in the
//! `K`-norm falls like `2((√κ − 1)/(√κ + 1))ᵏ` with `κ = cond(M⁻ᵀKM⁻¹)` (Saad, *Iterative
//! Methods for Sparse Linear Systems* §6.11). It stops when `‖f − K x‖ ≤ tol·‖f‖`. This is the
//! solver MRAS's ADMM c-step uses (Pan–Tong–Chen §4).
//!
//! A direction with `pᵀKp ≤ 0` proves `K` is not positive definite:
//! [`SolveError::NotPositiveDefinite`] reports the iteration and the value.

use std::sync::Arc;
use std::time::Instant;

use zeroset_field_core::lsq::{
    LeastSquaresSolver, LinearOperator, LsqMatrix, Monitor, Solution, SolveError, Stage,
};

use crate::common::{
    check_tolerance, effective_tolerance, finish, no_convergence, prepare, report,
};
use crate::kernels::{axpy, dot, norm2, xpby};
use crate::operator::Prepared;
use crate::precond::Preconditioner;

/// Parameters of [`Pcg`].
#[derive(Clone, Debug)]
pub struct PcgParams {
    /// Relative residual of the SPD system to reach (default `1e-10`; below the machine
    /// epsilon, `0` included, it counts as the epsilon; negative or NaN is refused).
    pub tol: f64,
    /// Iteration limit; `None` means `max(2n, 100)`.
    pub max_iterations: Option<usize>,
    /// `M` with `MᵀM ≈ K`.
    pub preconditioner: Option<Arc<dyn Preconditioner>>,
    /// Progress callback, every iteration; it may cancel.
    pub monitor: Option<Monitor>,
}

impl Default for PcgParams {
    fn default() -> Self {
        Self {
            tol: 1e-10,
            max_iterations: None,
            preconditioner: None,
            monitor: None,
        }
    }
}

/// Preconditioned conjugate gradients.
#[derive(Clone, Debug, Default)]
pub struct Pcg {
    /// Tolerance, limit, preconditioner, monitor.
    pub params: PcgParams,
}

/// `K v = Aᵀ(A v)` without forming `AᵀA`.
struct NormalOperator<'p, 'a> {
    a: &'p Prepared<'a>,
}

impl LinearOperator for NormalOperator<'_, '_> {
    fn nrows(&self) -> usize {
        self.a.shape().1
    }
    fn ncols(&self) -> usize {
        self.a.shape().1
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let mut ax = vec![0.0; self.a.shape().0];
        self.a.apply(x, &mut ax);
        self.a.apply_transpose(&ax, y);
    }
    fn apply_transpose(&self, x: &[f64], y: &mut [f64]) {
        self.apply(x, y)
    }
}

enum Outcome {
    Converged(Vec<f64>, usize),
    Exhausted(Vec<f64>, usize),
}

impl Pcg {
    /// PCG with the given parameters.
    pub fn new(params: PcgParams) -> Self {
        Self { params }
    }

    /// Solves `K x = f` for a symmetric positive definite `K` (only `K x` is used, so a
    /// non-symmetric `K` is not detected; an indefinite one usually is).
    ///
    /// # Errors
    /// Shape or value errors, [`SolveError::NotPositiveDefinite`],
    /// [`SolveError::NoConvergence`] (with the last iterate), [`SolveError::Cancelled`].
    pub fn solve_spd(&self, k: LsqMatrix<'_>, f: &[f64]) -> Result<Solution, SolveError> {
        let start = Instant::now();
        let (m, n) = k.shape();
        if m != n {
            return Err(SolveError::ShapeMismatch {
                what: "columns of the SPD matrix (it must be square)",
                expected: m,
                got: n,
            });
        }
        let k = prepare(k, f)?;
        match self.iterate("pcg", &k, f)? {
            Outcome::Converged(x, it) => finish("pcg", &k, x, f, it, start, vec![]),
            Outcome::Exhausted(x, it) => Err(no_convergence(&k, x, f, it)),
        }
    }

    fn iterate(
        &self,
        name: &'static str,
        k: &dyn LinearOperator,
        f: &[f64],
    ) -> Result<Outcome, SolveError> {
        let p = &self.params;
        check_tolerance("tol", p.tol)?;
        let tol = effective_tolerance(p.tol);
        let n = k.ncols();
        if let Some(m) = &p.preconditioner
            && m.dim() != n
        {
            return Err(SolveError::ShapeMismatch {
                what: "preconditioner",
                expected: n,
                got: m.dim(),
            });
        }
        let max_it = p.max_iterations.unwrap_or((2 * n).max(100));
        let precondition = |r: &[f64], tmp: &mut [f64], z: &mut [f64]| match &p.preconditioner {
            Some(m) => {
                m.apply_inverse_transpose(r, tmp);
                m.apply_inverse(tmp, z);
            }
            None => z.copy_from_slice(r),
        };
        let f_norm = norm2(f);
        let mut x = vec![0.0; n];
        if f_norm == 0.0 {
            return Ok(Outcome::Converged(x, 0));
        }
        let mut r = f.to_vec();
        let (mut z, mut tmp, mut q) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        precondition(&r, &mut tmp, &mut z);
        let mut dir = z.clone();
        let mut rz = dot(&r, &z);
        for it in 1..=max_it {
            k.apply(&dir, &mut q);
            let pq = dot(&dir, &q);
            if !pq.is_finite() {
                return Err(SolveError::NonFinite {
                    what: "pᵀKp, a product of the operator (a NaN or infinity from the operator \
                           or preconditioner?)",
                    index: it,
                    value: pq,
                });
            }
            if pq <= 0.0 {
                return Err(SolveError::NotPositiveDefinite {
                    index: it,
                    value: pq,
                });
            }
            let alpha = rz / pq;
            axpy(alpha, &dir, &mut x);
            axpy(-alpha, &q, &mut r);
            let rel = norm2(&r) / f_norm;
            report(&p.monitor, name, Stage::Iterate, it, max_it, f64::NAN, rel)?;
            if rel <= tol {
                return Ok(Outcome::Converged(x, it));
            }
            precondition(&r, &mut tmp, &mut z);
            let rz_new = dot(&r, &z);
            xpby(&z, rz_new / rz, &mut dir);
            rz = rz_new;
        }
        Ok(Outcome::Exhausted(x, max_it))
    }
}

impl LeastSquaresSolver for Pcg {
    fn name(&self) -> &'static str {
        "pcg-normal"
    }

    /// PCG on `AᵀA x = Aᵀb`; `tol` applies to `‖Aᵀ(b − A x)‖/‖Aᵀb‖`.
    fn solve(&self, a: LsqMatrix<'_>, b: &[f64]) -> Result<Solution, SolveError> {
        // On a worker of the pool, as in LSQR's solve.
        rayon::scope(|_| {
            let start = Instant::now();
            let a = prepare(a, b)?;
            let mut rhs = vec![0.0; a.shape().1];
            a.apply_transpose(b, &mut rhs);
            let normal = NormalOperator { a: &a };
            match self.iterate(self.name(), &normal, &rhs)? {
                Outcome::Converged(x, it) => finish(self.name(), &a, x, b, it, start, vec![]),
                Outcome::Exhausted(x, it) => Err(no_convergence(&a, x, b, it)),
            }
        })
    }
}
