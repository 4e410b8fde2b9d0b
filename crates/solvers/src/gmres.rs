//! Restarted flexible GMRES for a square system `A x = b` (Saad, "A flexible inner-outer
//! preconditioned GMRES algorithm", SIAM J. Sci. Comput. 14(2), 1993).
//!
//! From a start `x₀` with residual `r₀ = b − A x₀`, `β = ‖r₀‖`, `v₁ = r₀/β`, each step `j`
//! applies the preconditioner to the newest basis vector and orthogonalises its image:
//!
//! ```text
//! z_j = M_j⁻¹ v_j,      w = A z_j,      h_ij = ⟨w, v_i⟩ (i ≤ j),      h_{j+1,j} v_{j+1} = w − Σ h_ij v_i
//! ```
//!
//! After `m` steps this is the flexible Arnoldi relation
//!
//! ```text
//! A Z_m = V_{m+1} H̄_m,     Z_m = [z_1 … z_m],  V_{m+1} = [v_1 … v_{m+1}] orthonormal,
//!                          H̄_m ∈ R^{(m+1)×m} upper Hessenberg,
//! ```
//!
//! and since `b − A(x₀ + Z_m y) = V_{m+1}(β e₁ − H̄_m y)`, the iterate
//!
//! ```text
//! x_m = x₀ + Z_m y_m,      y_m = argmin_y ‖β e₁ − H̄_m y‖₂
//! ```
//!
//! minimises the residual over `x₀ + span(Z_m)`. Because the `z_j` are stored, `M_j` may change
//! from step to step — a few sweeps of an inner iteration, an inner Krylov solve with a loose
//! tolerance — which is what "flexible" means. With a fixed `M` (or none) it is right-
//! preconditioned GMRES (Saad–Schultz 1986), and without a preconditioner `Z_m = V_m` is not
//! stored at all.
//!
//! **The small problem.** `H̄_m` is reduced to upper-triangular `R_m` by Givens rotations, one
//! per step, applied to `β e₁` as well; the last entry of the rotated right-hand side is
//! `±‖b − A x_m‖` (in exact arithmetic), so the residual is known every step at no cost, and
//! `y_m = R_m⁻¹ g_m` is computed only when the cycle ends.
//!
//! **Orthogonalisation.** Modified Gram–Schmidt, followed by a second pass when the first lost
//! more than `1 − 1/√2` of the vector: re-orthogonalise if `‖w_after‖ < ‖w_before‖/√2`
//! (Daniel–Gragg–Kaufman–Stewart 1976; "twice is enough", Giraud–Langou–Rozložník 2005). The
//! count of second passes is reported as the detail `"reorthogonalisations"`.
//!
//! **Restarts and the stopping test.** A cycle ends after `restart` steps, when the estimate
//! `|g_{j+1}|` meets `tolerance·‖b‖`, or at a breakdown. Then `x` is updated and the *true*
//! residual `b − A x` is recomputed with one product; the solve converges only if
//! `‖b − A x‖ ≤ tolerance·‖b‖` holds for that true residual (the estimate drifts from it once
//! the basis loses orthogonality or the preconditioner is inexact). Otherwise the next cycle
//! starts from the true residual.
//!
//! **Breakdown.** `h_{j+1,j} ≈ 0` (at most `10ε·‖A z_j‖`) means `A z_j` lies in the span of
//! the basis. If `R_j` is nonsingular this is the "lucky" breakdown: `x_j` solves the system
//! exactly (Saad 1993, Prop. 2.2) and the cycle ends. If it is singular (`A` singular, or a
//! preconditioner that returned something useless) the last direction is dropped, the cycle
//! ends, and the next one restarts from the true residual.
//!
//! **Stagnation and the limit.** `max_iterations` counts steps (products with `A`) over all
//! cycles. A cycle whose true residual is not smaller than the one it started from ends the
//! solve: with a fixed preconditioner the next cycle would repeat it (the classic GMRES(m)
//! stagnation on indefinite or skew problems — raise `restart`). Both end in
//! [`SolveError::NoConvergence`] carrying the iterate with the smallest true residual.
//!
//! **Reports.** Like every solver of the crate, the [`SolveInfo`] residuals are re-measured on
//! `A` at the end: `rel_residual = ‖b − A x‖/‖b‖` and `rel_normal_residual =
//! ‖Aᵀ r‖/(‖A‖ ‖r‖)`, exactly as [`Pcg`](crate::Pcg) reports them (one product with `Aᵀ`;
//! `‖A‖` is the Frobenius norm of a matrix, free, but for a matrix-free operator a 30-step
//! power iteration — 60 products, once per solve; [`Gmres::with_normal_residual`]`(false)`
//! skips it, in the report and in [`SolveError::NoConvergence`] alike: a 5,000-point RBF fit
//! whose GMRES stalled just short of its target spent 7 of its 9.7 s there). The monitor sees
//! the running estimate of the relative residual and `NaN` for the normal residual.
//!
//! **Determinism.** The Krylov loop uses the crate's fixed-order [`kernels`](crate::kernels)
//! (the same bits for 1 or N threads); the operator and the preconditioner must be
//! deterministic too.
//!
//! # When to use it
//!
//! For square systems that are nonsymmetric or indefinite, where [`Pcg`](crate::Pcg) does not
//! apply and least-squares solvers ([`Lsqr`](crate::Lsqr)) would square the conditioning:
//! convection–diffusion operators, and RBF interpolation systems
//! `[[Φ, P], [Pᵀ, 0]] [λ; c] = [f; 0]`, symmetric but indefinite saddle points, best
//! preconditioned by approximate local cardinal functions (Beatson–Cherrie–Mouat, Adv.
//! Comput. Math. 11, 1999). The preconditioner `M` should approximate `A` itself (`A M⁻¹ ≈ I`;
//! not `MᵀM ≈ AᵀA` as for LSQR): with `M⁻¹ = A⁻¹` the solve takes one step. Memory is
//! `(restart + 1)` vectors of length `n`, twice that with a preconditioner.
//!
//! ```
//! use faer::Mat;
//! use zeroset_solvers::Diagonal;
//! use zeroset_solvers::gmres::Gmres;
//!
//! // 1-D convection–diffusion −u'' + 20 u' = 1 on (0, 1), central differences: nonsymmetric.
//! let n = 50;
//! let h = 1.0 / (n + 1) as f64;
//! let a = Mat::from_fn(n, n, |i, j| match j as isize - i as isize {
//!     0 => 2.0 / (h * h),
//!     -1 => -1.0 / (h * h) - 20.0 / (2.0 * h),
//!     1 => -1.0 / (h * h) + 20.0 / (2.0 * h),
//!     _ => 0.0,
//! });
//! let b = vec![1.0; n];
//! let solver = Gmres::default().with_tolerance(1e-12);
//! let plain = solver.solve((&a).into(), &b, None, None)?;
//! assert!(plain.info.rel_residual < 1e-12);
//! assert!(plain.info.iterations <= n);
//!
//! // Jacobi (M = diag A) as a right preconditioner; warm start from the first solution.
//! let jacobi = Diagonal::new(&(0..n).map(|i| a[(i, i)]).collect::<Vec<_>>());
//! let warm = solver.solve((&a).into(), &b, Some(&plain.x), Some(&jacobi))?;
//! assert_eq!(warm.info.iterations, 0);
//! # Ok::<(), zeroset_field_core::lsq::SolveError>(())
//! ```

use std::time::Instant;

use zeroset_field_core::lsq::{
    LinearOperator, LsqMatrix, Monitor, Solution, SolveError, SolveInfo, Stage,
};

use crate::common::{check_answer, check_residual, finish, no_convergence, prepare, report};
use crate::kernels::{axpy, dot, norm2, scale};
use crate::operator::Prepared;
use crate::precond::Preconditioner;

/// The name in reports.
const NAME: &str = "gmres";

/// Re-orthogonalise when one Gram–Schmidt pass leaves less than this fraction of the norm.
const REORTHOGONALISE_BELOW: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// `h_{j+1,j}` (and a pivot of `R`) at or below this multiple of `ε‖A z_j‖` counts as zero.
const BREAKDOWN: f64 = 10.0 * f64::EPSILON;

/// Restarted flexible GMRES, FGMRES(m), for square `A x = b`.
///
/// Defaults: `restart = 50`, `tolerance = 1e-10` on `‖b − A x‖/‖b‖`, `max_iterations = 1000`,
/// no monitor. Build with the `with_*` methods:
///
/// ```
/// use zeroset_solvers::gmres::Gmres;
/// let solver = Gmres::default().with_restart(30).with_tolerance(1e-8);
/// assert_eq!((solver.restart, solver.max_iterations), (30, 1000));
/// ```
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct Gmres {
    /// Krylov steps per cycle, `m` (clamped to `1..=n`). Memory grows like `m·n`.
    pub restart: usize,
    /// Relative residual `‖b − A x‖/‖b‖` to reach, checked on the true residual.
    pub tolerance: f64,
    /// Limit on the total number of steps (products with `A`) over all cycles.
    pub max_iterations: usize,
    /// Progress callback, called every step; it may cancel.
    pub monitor: Option<Monitor>,
    /// Whether the report measures `‖Aᵀ r‖/(‖A‖ ‖r‖)` (default true). For a matrix-free
    /// operator whose products are expensive (an RBF direct sum) that costs ~61 extra
    /// products; with `false` the report (and [`SolveError::NoConvergence`]) gives NaN there
    /// and costs at most one product.
    pub normal_residual: bool,
}

impl Default for Gmres {
    fn default() -> Self {
        Self {
            restart: 50,
            tolerance: 1e-10,
            max_iterations: 1000,
            monitor: None,
            normal_residual: true,
        }
    }
}

/// The Krylov basis of one cycle: `V` (orthonormal) and, with a preconditioner, `Z`.
struct Basis {
    v: Vec<Vec<f64>>,
    z: Vec<Vec<f64>>,
}

impl Basis {
    /// Makes sure vector `j` of `V` (and of `Z` when `with_z`) exists.
    fn reserve(&mut self, j: usize, n: usize, with_z: bool) {
        while self.v.len() <= j {
            self.v.push(vec![0.0; n]);
        }
        while with_z && self.z.len() <= j {
            self.z.push(vec![0.0; n]);
        }
    }
}

/// `(c, s, ρ)` with `[c s; −s c] [f; g] = [ρ; 0]`, `ρ ≥ 0`.
fn givens(f: f64, g: f64) -> (f64, f64, f64) {
    let rho = f.hypot(g);
    if rho == 0.0 {
        (1.0, 0.0, 0.0)
    } else {
        (f / rho, g / rho, rho)
    }
}

/// `r ← b − A x`; returns `‖r‖`.
fn residual(a: &Prepared<'_>, x: &[f64], b: &[f64], r: &mut [f64]) -> f64 {
    a.apply(x, r);
    r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
    norm2(r)
}

/// The first non-finite entry of `v`, as an error about `what`.
fn check_finite(what: &'static str, v: &[f64]) -> Result<(), SolveError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(SolveError::NonFinite {
            what,
            index,
            value: v[index],
        }),
        None => Ok(()),
    }
}

/// How a cycle ended.
struct Cycle {
    /// Columns of `R` in the least-squares solution.
    columns: usize,
    /// `|g_{k+1}|`, the estimated residual norm.
    estimate: f64,
}

impl Gmres {
    /// Sets the restart length `m`.
    pub fn with_restart(mut self, restart: usize) -> Self {
        self.restart = restart;
        self
    }

    /// Sets the relative residual to reach.
    pub fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Sets the limit on the total number of steps.
    pub fn with_max_iterations(mut self, max_iterations: usize) -> Self {
        self.max_iterations = max_iterations;
        self
    }

    /// Sets the progress callback.
    pub fn with_monitor(mut self, monitor: Monitor) -> Self {
        self.monitor = Some(monitor);
        self
    }

    /// Sets whether the report measures the normal-equation residual (see the field).
    pub fn with_normal_residual(mut self, measure: bool) -> Self {
        self.normal_residual = measure;
        self
    }

    /// The error for an `x` that missed the tolerance, `r_norm` the norm of its (true) residual:
    /// [`no_convergence`], or without the normal residual (no product at all).
    fn no_convergence(
        &self,
        a: &Prepared<'_>,
        x: Vec<f64>,
        b: &[f64],
        r_norm: f64,
        iterations: usize,
    ) -> SolveError {
        if self.normal_residual {
            return no_convergence(a, x, b, iterations);
        }
        let b_norm = norm2(b);
        SolveError::NoConvergence {
            iterations,
            rel_residual: if b_norm > 0.0 {
                r_norm / b_norm
            } else {
                r_norm
            },
            rel_normal_residual: f64::NAN,
            x,
        }
    }

    /// The report for a converged `x`: [`finish`], or without the normal residual.
    #[allow(clippy::too_many_arguments)]
    fn report(
        &self,
        a: &Prepared<'_>,
        x: Vec<f64>,
        b: &[f64],
        iterations: usize,
        start: Instant,
        details: Vec<(&'static str, f64)>,
    ) -> Result<Solution, SolveError> {
        if self.normal_residual {
            return finish(NAME, a, x, b, iterations, start, details);
        }
        check_answer(&x)?;
        let mut r = vec![0.0; b.len()];
        let b_norm = norm2(b);
        let r_norm = residual(a, &x, b, &mut r);
        let rel = if b_norm > 0.0 { r_norm / b_norm } else { 0.0 };
        check_residual(rel)?;
        let mut info = SolveInfo::new(NAME, iterations, rel, f64::NAN, start.elapsed());
        info.details = details;
        Ok(Solution { x, info })
    }

    /// Solves the square system `A x = b` from `x0` (zero if `None`), with `preconditioner` `M`
    /// on the right (`A M⁻¹ ≈ I` is the aim; `M⁻¹` may change from call to call).
    ///
    /// `A` is any [`LsqMatrix`]: a dense or sparse matrix, or a matrix-free operator
    /// (`LsqMatrix::Operator(&op)`). With `b = 0` the answer is `x = 0` after no iterations,
    /// whatever `x0`.
    ///
    /// # Errors
    /// - [`SolveError::ShapeMismatch`]: `A` not square (`what` names the columns), `b`, `x0` or
    ///   the preconditioner of the wrong size;
    /// - [`SolveError::NonFinite`]: a NaN or infinity in `b` (`"right-hand side"`), `x0`
    ///   (`"initial guess"`), a stored entry of `A` (`"matrix"`), or produced by the
    ///   preconditioner (`"preconditioner output"`) or the operator (`"operator output"`) during
    ///   the iteration;
    /// - [`SolveError::NoConvergence`]: `max_iterations` reached, or a restart cycle that did
    ///   not reduce the true residual (stagnation), with the best iterate and its exact
    ///   residuals;
    /// - [`SolveError::Cancelled`]: the monitor said stop.
    pub fn solve(
        &self,
        a: LsqMatrix<'_>,
        b: &[f64],
        x0: Option<&[f64]>,
        preconditioner: Option<&dyn Preconditioner>,
    ) -> Result<Solution, SolveError> {
        let start = Instant::now();
        let (m, n) = a.shape();
        if m != n {
            return Err(SolveError::ShapeMismatch {
                what: "columns of A (GMRES needs a square matrix)",
                expected: m,
                got: n,
            });
        }
        let a = prepare(a, b)?;
        if let Some(x0) = x0 {
            if x0.len() != n {
                return Err(SolveError::ShapeMismatch {
                    what: "initial guess x0",
                    expected: n,
                    got: x0.len(),
                });
            }
            check_finite("initial guess", x0)?;
        }
        if let Some(p) = preconditioner
            && p.dim() != n
        {
            return Err(SolveError::ShapeMismatch {
                what: "preconditioner",
                expected: n,
                got: p.dim(),
            });
        }

        let restart = self.restart.clamp(1, n.max(1));
        let mut details = vec![("restart", restart as f64)];
        let b_norm = norm2(b);
        if b_norm == 0.0 {
            return self.report(&a, vec![0.0; n], b, 0, start, details);
        }
        let target = self.tolerance * b_norm;

        let mut x = x0.map_or_else(|| vec![0.0; n], <[f64]>::to_vec);
        let mut r = vec![0.0; n];
        let mut r_norm = match x0 {
            Some(x0) => residual(&a, x0, b, &mut r),
            None => {
                r.copy_from_slice(b);
                b_norm
            }
        };
        if r_norm <= target {
            return self.report(&a, x, b, 0, start, details);
        }

        let mut state = State {
            basis: Basis {
                v: Vec::new(),
                z: Vec::new(),
            },
            h: vec![0.0; (restart + 1) * restart],
            rotations: vec![(1.0, 0.0); restart],
            g: vec![0.0; restart + 1],
            w: vec![0.0; n],
            restart,
            target,
            b_norm,
            iterations: 0,
            reorthogonalisations: 0,
        };
        let mut x_try = vec![0.0; n];
        let mut r_try = vec![0.0; n];
        let mut cycles = 0usize;
        loop {
            if state.iterations >= self.max_iterations {
                return Err(self.no_convergence(&a, x, b, r_norm, state.iterations));
            }
            cycles += 1;
            let cycle = self.cycle(&a, preconditioner, &r, r_norm, &mut state)?;

            // x_try = x + Z y, y = R⁻¹ g.
            let k = cycle.columns;
            let y = state.back_substitute(k);
            x_try.copy_from_slice(&x);
            let directions = if preconditioner.is_some() {
                &state.basis.z
            } else {
                &state.basis.v
            };
            for (yi, d) in y.iter().zip(directions) {
                axpy(*yi, d, &mut x_try);
            }
            let r_try_norm = residual(&a, &x_try, b, &mut r_try);
            if r_try_norm <= target {
                details.extend([
                    ("cycles", cycles as f64),
                    ("reorthogonalisations", state.reorthogonalisations as f64),
                    ("estimated_rel_residual", cycle.estimate / b_norm),
                ]);
                return self.report(&a, x_try, b, state.iterations, start, details);
            }
            if r_try_norm.is_nan() || r_try_norm >= r_norm {
                // Stagnation (or a NaN): the previous iterate is the best.
                return Err(self.no_convergence(&a, x, b, r_norm, state.iterations));
            }
            std::mem::swap(&mut x, &mut x_try);
            std::mem::swap(&mut r, &mut r_try);
            r_norm = r_try_norm;
        }
    }

    /// One cycle of at most `restart` steps from the residual `r` (norm `r_norm`). Leaves the
    /// triangular factor, the rotated right-hand side and the basis in `state`.
    fn cycle(
        &self,
        a: &Prepared<'_>,
        preconditioner: Option<&dyn Preconditioner>,
        r: &[f64],
        r_norm: f64,
        state: &mut State,
    ) -> Result<Cycle, SolveError> {
        let (restart, target, b_norm) = (state.restart, state.target, state.b_norm);
        let n = r.len();
        let ld = restart + 1;
        let flexible = preconditioner.is_some();
        state.basis.reserve(0, n, flexible);
        state.basis.v[0].copy_from_slice(r);
        scale(1.0 / r_norm, &mut state.basis.v[0]);
        state.g.fill(0.0);
        state.g[0] = r_norm;
        let mut estimate = r_norm;

        for j in 0..restart {
            if state.iterations >= self.max_iterations {
                return Ok(Cycle {
                    columns: j,
                    estimate,
                });
            }
            state.basis.reserve(j + 1, n, flexible);
            // w = A z_j, z_j = M⁻¹ v_j (stored) or v_j.
            let Basis { v, z } = &mut state.basis;
            let w = &mut state.w;
            match preconditioner {
                Some(p) => {
                    p.apply_inverse(&v[j], &mut z[j]);
                    check_finite("preconditioner output", &z[j])?;
                    a.apply(&z[j], w);
                }
                None => a.apply(&v[j], w),
            }
            check_finite("operator output", w)?;
            state.iterations += 1;

            // Modified Gram–Schmidt, and a second pass if the first cancelled too much.
            let col = &mut state.h[j * ld..(j + 1) * ld];
            col.fill(0.0);
            let w_norm = norm2(w);
            for (i, vi) in v.iter().enumerate().take(j + 1) {
                let hij = dot(w, vi);
                axpy(-hij, vi, w);
                col[i] = hij;
            }
            let mut h_next = norm2(w);
            if h_next < REORTHOGONALISE_BELOW * w_norm {
                state.reorthogonalisations += 1;
                for (i, vi) in v.iter().enumerate().take(j + 1) {
                    let c = dot(w, vi);
                    axpy(-c, vi, w);
                    col[i] += c;
                }
                h_next = norm2(w);
            }
            let breakdown = h_next <= BREAKDOWN * w_norm;
            col[j + 1] = if breakdown { 0.0 } else { h_next };

            // Previous rotations, then a new one to annihilate h_{j+1,j}.
            for (i, &(c, s)) in state.rotations.iter().enumerate().take(j) {
                let (hi, hi1) = (col[i], col[i + 1]);
                col[i] = c * hi + s * hi1;
                col[i + 1] = -s * hi + c * hi1;
            }
            let (c, s, rho) = givens(col[j], col[j + 1]);
            if rho <= BREAKDOWN * w_norm {
                // R_j singular: A z_j adds nothing; drop it and end the cycle.
                report(
                    &self.monitor,
                    NAME,
                    Stage::Iterate,
                    state.iterations,
                    self.max_iterations,
                    estimate / b_norm,
                    f64::NAN,
                )?;
                return Ok(Cycle {
                    columns: j,
                    estimate,
                });
            }
            state.rotations[j] = (c, s);
            col[j] = rho;
            col[j + 1] = 0.0;
            state.g[j + 1] = -s * state.g[j];
            state.g[j] *= c;
            estimate = state.g[j + 1].abs();
            report(
                &self.monitor,
                NAME,
                Stage::Iterate,
                state.iterations,
                self.max_iterations,
                estimate / b_norm,
                f64::NAN,
            )?;
            if breakdown || estimate <= target {
                return Ok(Cycle {
                    columns: j + 1,
                    estimate,
                });
            }
            v[j + 1].copy_from_slice(w);
            scale(1.0 / h_next, &mut v[j + 1]);
        }
        Ok(Cycle {
            columns: restart,
            estimate,
        })
    }
}

/// Work space of a solve, kept across cycles.
struct State {
    basis: Basis,
    /// `H̄`, then `R`, column-major with leading dimension `restart + 1`.
    h: Vec<f64>,
    /// `(c, s)` of each step's rotation.
    rotations: Vec<(f64, f64)>,
    /// The rotated `β e₁`.
    g: Vec<f64>,
    /// `A z_j`, orthogonalised into `h_{j+1,j} v_{j+1}`.
    w: Vec<f64>,
    /// Steps per cycle, `m`.
    restart: usize,
    /// `tolerance·‖b‖`.
    target: f64,
    /// `‖b‖`.
    b_norm: f64,
    iterations: usize,
    reorthogonalisations: usize,
}

impl State {
    /// `y = R_k⁻¹ g_k`, the leading `k × k` block (nonsingular by construction).
    fn back_substitute(&self, k: usize) -> Vec<f64> {
        let ld = self.restart + 1;
        let mut y = self.g[..k].to_vec();
        for i in (0..k).rev() {
            for l in i + 1..k {
                y[i] -= self.h[l * ld + i] * y[l];
            }
            y[i] /= self.h[i * ld + i];
        }
        y
    }
}
