//! Radial-basis-function implicit fields (Carr et al.; Zhang–Zhong–Wang 002 §2.1; Jiang–Turk
//! 003 §2): fitting, Hermite constraints, and incremental constraints.
//!
//! A field `s(x) = Σⱼ wⱼ Lⱼʸ φ(|x − y|) + c₀ + c · (x − m)/h` interpolates linear functionals
//! `Lᵢ s = tᵢ` — values at points (on-surface 0, off-surface `±ε`, inside/outside values) and,
//! with a smooth kernel, partial derivatives (the normal as the gradient, HRBF). The weights
//! solve the symmetric saddle-point system `[Φ P; Pᵀ 0] [w; c] = [t; 0]` of [`system`]:
//! `Φᵢⱼ = Lᵢˣ Lⱼʸ φ`, `P` the polynomial's functionals, with the side conditions `Pᵀw = 0`.
//!
//! - [`kernel`]: `r` (biharmonic, 3-D), `r³` (triharmonic, 3-D, Hermite-capable), `r² ln r`
//!   (thin plate, 2-D) and Wendland's compact `ψ₃,₁` as the example of a user kernel.
//! - [`constraints`]: on/off-surface points with Carr's per-point offset test, Hermite.
//! - [`RbfFit`] with a [`Solver`]: the exact dense solve — Cholesky of the system projected
//!   onto the null space of `Pᵀ` (half the flops of LU on the indefinite matrix; [`dense`]),
//!   one step of iterative refinement with the exact direct-sum residual; the same Cholesky in
//!   f32 as the preconditioner of FGMRES on the f64 system (mixed precision, ~0.6× the time);
//!   or GMRES in a basis of local cardinal functions with a coarse level ([`iterative`]), no
//!   matrix, its products by direct sums (`O(n²)` per step) or, from [`FMM_PRODUCT_MIN`]
//!   centres, by the FMM ([`fmm::product`], `O(n)` time and memory). [`Solver::Auto`] picks by
//!   size and kernel, and no dense solve or fallback starts that needs more memory than the
//!   machine has ([`RbfError::Memory`] names the amount). Every [`FitReport`] has the largest
//!   constraint residual by direct sums, the steps taken and a condition estimate; a
//!   [`Monitor`] sees every GMRES step ([`RbfFit::with_monitor`]).
//! - **Smoothing** ([`RbfFit::with_smoothing`]): for noisy data, the smoothing spline instead
//!   of the interpolant (Carr et al. 2001 §4.2, Wahba 1990): `σμ` on `Φ`'s diagonal, in every
//!   solver (dense, mixed precision, the local cardinal functions, the coarse level and the
//!   FMM products), the same as SciPy's `RBFInterpolator(smoothing=μ, degree=1)` with the
//!   same kernel;
//!   [`crate::noise::Noise::rbf_smoothing`] chooses `μ` for a scan from its measured noise.
//! - [`RbfFit::fit_greedy`] ([`greedy`]): Carr et al.'s centre reduction — fit a subset, add
//!   the constraints over the tolerance, refit — for a field that keeps only the centres it
//!   needs.
//! - [`IncrementalFit`]: add `M` constraints to a solved `N`-constraint fit through the Schur
//!   complement `S = D − C A⁻¹ Cᵀ` (003 Eq. 9) in `O(N² M)`, and remove the last ones again.
//! - [`RbfField`] is a [`ScalarField`](zeroset_field_core::field::ScalarField) with analytic
//!   gradient and Hessian; [`RbfSpace`] is the [`Basis`](zeroset_field_core::basis::Basis).
//!   Each evaluation is a sum over every centre: to mesh or sample a field on a grid, build
//!   [`fmm::OrderPair`] (two fast-multipole approximations and the margin between them) and
//!   give it to `zeroset_mesh::signed::signed_marching_cubes`, which evaluates the accurate one
//!   only near the surface (`zeroset_mesh::mesh_field`'s docs have the recipe; 7× faster on
//!   6,150 centres, both on 2 threads with the FMM's set-up counted).
//!
//! zeroset's convention is negative inside. Jiang–Turk take +1 inside: flip their values.
//!
//! ```
//! use zeroset_bases::rbf::{Constraints, RbfFit, Triharmonic};
//! use zeroset_field_core::field::ScalarField;
//!
//! // Points on the unit sphere (values 0) and its centre (value −1).
//! let mut c = Constraints::<3>::new();
//! for k in 0..40 {
//!     let z = -1.0 + (2 * k + 1) as f64 / 40.0;
//!     let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399963);
//!     c.push_value([s * t.cos(), s * t.sin(), z], 0.0);
//! }
//! c.push_value([0.0, 0.0, 0.0], -1.0);
//! let fit = RbfFit::new(Triharmonic).fit(&c)?;
//! assert!(fit.report.max_residual < 1e-10);
//! assert!(fit.field.value(&[0.0, 0.0, 0.5]) < 0.0 && fit.field.value(&[0.0, 0.0, 1.5]) > 0.0);
//! # Ok::<(), zeroset_bases::rbf::RbfError>(())
//! ```

pub mod constraints;
pub mod dense;
mod error;
mod field;
pub mod fmm;
pub mod greedy;
pub mod incremental;
pub mod iterative;
pub mod kernel;
pub mod system;

use std::time::{Duration, Instant};

pub use constraints::{
    Constraint, Constraints, MERGE_DISTANCE, NORMAL_NEIGHBOURS, Offset, OffsetReport, Prescribed,
};
pub use error::RbfError;
pub use field::{RbfField, RbfSpace};
pub use greedy::{GreedyOptions, GreedyReport, GreedyRound};
pub use incremental::IncrementalFit;
pub use iterative::IterativeParams;
pub use kernel::{Biharmonic, Kernel, ThinPlate, Triharmonic, Wendland};

use dense::{DenseFactor, Precision};
use fmm::product::{FMM_RESIDUAL_ORDER, FmmProduct};
use system::{Functionals, Polynomial};
use zeroset_field_core::Aabb;
use zeroset_field_core::limits::{self, Limit};
use zeroset_field_core::lsq::{LinearOperator, LsqMatrix, Monitor, SolveError};
use zeroset_solvers::gmres::Gmres;
use zeroset_solvers::precond::Preconditioner;

/// The relative residual the mixed-precision solve iterates to (the direct sums' rounding
/// floor is ~1e-13).
const MIXED_TOLERANCE: f64 = 1e-12;

/// A condition estimate above this makes the fit warn (see [`FitReport::warnings`]).
pub const CONDITION_WARNING: f64 = 1e13;

/// The iterative fit of a 3-D field forms its products by the FMM
/// ([`fmm::product`]) from this many centres on, by the direct sum below. Measured per GMRES
/// step on the sphere set-up, kernel `r`, 2 threads (`examples/rbf_timing`,
/// `ZEROSET_RBF_FMM_FROM`): direct 39 / 76 / 385 ms, FMM 48 / 85 / 120 ms at 6,000 / 12,000 /
/// 24,000 centres. Below, the direct sum also reaches the tighter tolerance.
pub const FMM_PRODUCT_MIN: usize = 15_000;

/// Up to this many functionals the fit's report measures the constraint residual exactly, by
/// direct sums (`n²` kernel values: 4 s at the full bunny's 104,502 on 2 threads); above, on
/// the FMM path, by the FMM of the products ([`FitReport::residual_exact`]), so that the check
/// grows like the fit and not like `n²` (at 3·10⁵ it would take longer than the fit).
pub const EXACT_RESIDUAL_MAX: usize = 150_000;

/// [`Solver::Auto`] solves systems of up to this many unknowns densely.
pub const AUTO_DENSE_LIMIT: usize = 2000;

/// How [`RbfFit`] solves the system.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Solver {
    /// Up to [`AUTO_DENSE_LIMIT`] functionals [`Solver::Dense`]; above, [`Solver::Iterative`]
    /// for kernels of order ≤ 1 (`r`, Wendland) with value constraints only,
    /// [`Solver::MixedPrecision`] for the positive definite Wendland kernel with gradient
    /// constraints, and [`Solver::Dense`] otherwise (`r³`: its f32 factorisation broke down on
    /// every scan tried, the bunny sample and the kitten, values or Hermite, which cost the
    /// failed attempt before the dense solve); either falls back to the f64 dense solve, with a
    /// warning, if
    /// it does not converge (GMRES in the cardinal basis: 300 steps) — unless the dense solve
    /// would need more memory than the limit, which is then an error ([`RbfError::Memory`])
    /// naming both failures. Measured on the sphere set-up: with
    /// `r`, GMRES in the cardinal basis converges in ~25 steps and beats the dense solve from
    /// ~2,000 points; with `r³` (order 2) local sets of 50–100 leave it stalling near 1e-1 (200
    /// converge, but cost as much as the dense solve), so `r³` stays dense.
    #[default]
    Auto,
    /// The exact dense solve (projected Cholesky), `O(n³)` time and `O(n²)` memory.
    Dense,
    /// GMRES in the local cardinal basis ([`iterative`]), `O(n²)` per step by direct sums.
    Iterative(IterativeParams),
    /// The projected Cholesky in f32 (half the time of f64) as the preconditioner of FGMRES
    /// on the f64 system: mixed-precision refinement, as exact as [`Solver::Dense`] (same
    /// residual test) while the f32 factor exists, i.e. for condition numbers up to ~1e7.
    MixedPrecision,
}

/// What a fit did.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct FitReport {
    /// The solver used (`"dense-cholesky"` or `"gmres-cardinal"`).
    pub solver: &'static str,
    /// GMRES steps (0 for the dense solve).
    pub iterations: usize,
    /// Constraints given (a gradient constraint is one).
    pub constraints: usize,
    /// Unknowns: one weight per functional plus the polynomial's `D + 1`.
    pub unknowns: usize,
    /// Wall-clock time of the fit.
    pub elapsed: Duration,
    /// `maxᵢ |Lᵢ s − tᵢ|`, evaluated after the solve by direct sums, or by the FMM of the
    /// products above [`IterativeParams::exact_residual_max`] functionals
    /// ([`FitReport::residual_exact`]).
    pub max_residual: f64,
    /// Whether `max_residual` comes from exact direct sums (`false`: from the FMM of the
    /// products, relative error about 1e-9 of the field's scale).
    pub residual_exact: bool,
    /// With smoothing ([`RbfFit::with_smoothing`]): the largest `|s(xᵢ) − tᵢ| = μ |wᵢ|` over
    /// the value constraints, by how much the field misses them on purpose (0 without
    /// smoothing; `max_residual` is then the residual of the smoothed system).
    pub misfit_max: f64,
    /// The root mean square of the same misfits.
    pub misfit_rms: f64,
    /// A lower bound on the condition number of the projected system (NaN for the iterative
    /// solve, which forms no matrix).
    pub condition_estimate: f64,
    /// Iterative-refinement steps taken (0 or 1).
    pub refinement_steps: usize,
    /// The relative residual `‖b − Ax‖/‖b‖` GMRES stopped at where rounding kept it short of
    /// its target (it is accepted up to 1e-10, far below what matters for a fit:
    /// `max_residual` is measured after); `None` where it reached the target or the solve was
    /// direct. Not a warning: ordinary scans stop at a few 1e-12.
    pub stalled_at: Option<f64>,
    /// Things the user should know (an ill-conditioned system, …).
    pub warnings: Vec<String>,
}

/// What a solver produced.
struct Solved {
    solver: &'static str,
    /// `[w; c]`.
    x: Vec<f64>,
    iterations: usize,
    /// The relative residual GMRES stalled at, if it stopped short of its target.
    stalled: Option<f64>,
    condition: f64,
    refinement_steps: usize,
}

/// A fitted field and its report.
#[derive(Debug, Clone)]
pub struct Fitted<K, const D: usize> {
    /// The field.
    pub field: RbfField<K, D>,
    /// How the fit went.
    pub report: FitReport,
}

/// Fits RBF fields with one kernel; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct RbfFit<K> {
    kernel: K,
    solver: Solver,
    /// Bytes a dense solve may use (`None`: what the machine has available when it starts).
    memory_limit: Option<u64>,
    /// Called every step of an iterative solve (GMRES in the cardinal basis, or the
    /// mixed-precision refinement).
    monitor: Option<Monitor>,
    /// The smoothing `μ ≥ 0` ([`RbfFit::with_smoothing`]; 0: interpolation).
    smoothing: f64,
}

impl<K: Kernel + Clone> RbfFit<K> {
    /// A fit with `kernel` and [`Solver::Auto`].
    pub fn new(kernel: K) -> Self {
        Self {
            kernel,
            solver: Solver::Auto,
            memory_limit: None,
            monitor: None,
            smoothing: 0.0,
        }
    }

    /// Limits the memory a dense solve may use to `bytes` (default: the cap of
    /// `ZEROSET_MEMORY_LIMIT` or what the machine has available, [`limits::current_limit`]).
    /// A dense solve, or a fallback to one, that needs more is refused with
    /// [`RbfError::Memory`] before anything is allocated.
    pub fn with_memory_limit(mut self, bytes: u64) -> Self {
        self.memory_limit = Some(bytes);
        self
    }

    /// Reports every step of an iterative solve to `monitor` (step, relative residual); it
    /// may cancel the fit ([`RbfError::Solve`] with `Cancelled`).
    pub fn with_monitor(mut self, monitor: Monitor) -> Self {
        self.monitor = Some(monitor);
        self
    }

    /// Approximates the value constraints instead of interpolating them: the weights solve
    /// `[Φ + σμI, P; Pᵀ, 0]`, `σ` the kernel's sign ([`Kernel::sign`]; `σΦ + μI` is then
    /// positive definite where `σΦ` is), so that the field is
    /// the smoothing spline that minimises `Σᵢ (s(xᵢ) − tᵢ)² + μ'·J(s)`, `J` the kernel's
    /// semi-norm and `μ'` proportional to `μ` (Carr et al. 2001 §4.2; Wahba 1990). The field
    /// misses each value by `s(xᵢ) − tᵢ = −σμ wᵢ` ([`FitReport::misfit_rms`]); gradient
    /// constraints are still interpolated. `μ` is in the kernel's units (a length for `r`, a
    /// length cubed for `r³`) and means what `smoothing` means to SciPy's
    /// `RBFInterpolator` with the same kernel and `degree=1` (its `"linear"`, `-r`, is `σ r`);
    /// 0 (the default) interpolates. The greedy fit ([`RbfFit::fit_greedy`]) judges the
    /// constraints by their misfit, so it is not meant for a smoothed fit.
    /// Every solver takes it: the diagonal also enters the local cardinal functions, the
    /// coarse level and the FMM products of the iterative fit.
    ///
    /// # Panics
    /// If `mu` is negative or not finite (a programming error: validate user input first).
    pub fn with_smoothing(mut self, mu: f64) -> Self {
        assert!(
            mu.is_finite() && mu >= 0.0,
            "the RBF smoothing must be finite and ≥ 0, not {mu}"
        );
        self.smoothing = mu;
        self
    }

    /// The smoothing `μ` ([`RbfFit::with_smoothing`]).
    pub fn smoothing(&self) -> f64 {
        self.smoothing
    }

    /// Chooses the solver.
    pub fn with_solver(mut self, solver: Solver) -> Self {
        self.solver = solver;
        self
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The field interpolating `constraints` exactly (up to rounding).
    ///
    /// # Errors
    /// [`RbfError::Empty`]; [`RbfError::NonFinite`] naming the constraint;
    /// [`RbfError::Duplicate`] naming the two functionals at one point (a gradient
    /// constraint expands to `D` functionals, numbered after the values before it);
    /// [`RbfError::Degenerate`] for too few or coplanar (2-D: collinear) points;
    /// [`RbfError::KernelNotSmooth`] for gradient constraints with `r` or `r² ln r`;
    /// [`RbfError::Singular`] if the factorisation fails anyway.
    pub fn fit<const D: usize>(
        &self,
        constraints: &Constraints<D>,
    ) -> Result<Fitted<K, D>, RbfError> {
        let start = Instant::now();
        let (functionals, poly) = self.prepare(constraints.as_slice())?;
        let n = functionals.len();
        let mut warnings = Vec::new();
        let iterative = match &self.solver {
            Solver::Dense | Solver::MixedPrecision => None,
            Solver::Iterative(p) => Some(p.clone()),
            Solver::Auto => {
                (n > AUTO_DENSE_LIMIT && functionals.values_only() && self.kernel.order() <= 1)
                    .then(IterativeParams::default)
            }
        };
        let mixed = match &self.solver {
            Solver::MixedPrecision => true,
            Solver::Auto => n > AUTO_DENSE_LIMIT && iterative.is_none() && self.kernel.order() == 0,
            _ => false,
        };
        let rhs = self.rhs(&functionals);
        let mut solved = None;
        let unknowns = n + Polynomial::<D>::len();
        if mixed {
            self.check_memory(
                unknowns,
                Precision::Single,
                "the mixed-precision dense solve",
            )?;
            match self.solve_mixed(&functionals, &poly, &rhs) {
                Ok(s) => solved = Some(s),
                Err(e @ RbfError::Solve(SolveError::Cancelled { .. })) => return Err(e),
                Err(e) if self.solver == Solver::Auto => warnings.push(format!(
                    "the mixed-precision solve failed ({e}); solved in f64 instead"
                )),
                Err(e) => return Err(e),
            }
        }
        let mut failed = None;
        let mut fmm = None;
        let mut exact_residual_max = usize::MAX;
        if let Some(params) = iterative {
            exact_residual_max = params.exact_residual_max;
            // From `fmm_from` centres on in 3-D, GMRES's products by the FMM.
            fmm = if D == 3 && n >= params.fmm_from {
                Some(
                    FmmProduct::new(&self.kernel, &functionals.points)
                        .map_err(|e| RbfError::Singular(format!("the FMM product: {e}")))?,
                )
            } else {
                None
            };
            let product = fmm
                .as_ref()
                .map(|p| move |w: &[f64], out: &mut [f64]| p.apply(w, out));
            match iterative::solve(
                &self.kernel,
                &functionals,
                &poly,
                &params,
                product.as_ref().map(|p| p as &iterative::KernelProduct<'_>),
                self.monitor.clone(),
            ) {
                Ok(done) => {
                    solved = Some(Solved {
                        solver: "gmres-cardinal",
                        x: done.x,
                        iterations: done.iterations,
                        stalled: done.stalled,
                        condition: f64::NAN,
                        refinement_steps: 0,
                    })
                }
                Err(e @ RbfError::Solve(SolveError::Cancelled { .. })) => return Err(e),
                Err(e) if self.solver == Solver::Auto => {
                    warnings.push(format!(
                        "the iterative solve failed ({e}); solved densely instead"
                    ));
                    failed = Some(e);
                }
                Err(e) => return Err(e),
            }
        }
        let solved = match solved {
            Some(s) => s,
            None => {
                let what = match &failed {
                    Some(e) => format!(
                        "the iterative solve failed ({e}); the dense fallback of {unknowns} unknowns"
                    ),
                    None => format!("the dense solve of {unknowns} unknowns"),
                };
                self.check_memory(unknowns, Precision::Double, &what)?;
                self.solve_dense(&functionals, &poly, &rhs)?
            }
        };
        if solved.condition > CONDITION_WARNING {
            warnings.push(condition_warning(solved.condition));
        }
        // The exact residual costs `n²` kernel values (4 s at the full bunny's 104,502 on 2
        // threads); above `exact_residual_max` it would outgrow the fit, and the FMM of the
        // products measures it instead.
        let by_fmm = match &fmm {
            Some(_) if n > exact_residual_max => Some(
                FmmProduct::with_order(&self.kernel, &functionals.points, FMM_RESIDUAL_ORDER)
                    .map_err(|e| RbfError::Singular(format!("the FMM residual check: {e}")))?,
            ),
            _ => None,
        };
        let residual = match &by_fmm {
            Some(product) => {
                let mut ax = vec![0.0; n];
                product.apply(&solved.x[..n], &mut ax);
                let (w, c) = solved.x.split_at(n);
                let diagonal = functionals.diagonal;
                ax.iter()
                    .zip(&functionals.points)
                    .zip(&rhs)
                    .zip(w)
                    .map(|(((a, x), b), wi)| b - a - diagonal * wi - poly.value(c, x))
                    .collect()
            }
            None => self.residual(&functionals, &poly, &solved.x, &rhs),
        };
        let (misfit_max, misfit_rms) = misfits(&functionals, &solved.x[..n]);
        let report = FitReport {
            misfit_max,
            misfit_rms,
            residual_exact: by_fmm.is_none(),
            solver: solved.solver,
            iterations: solved.iterations,
            constraints: constraints.len(),
            unknowns: rhs.len(),
            elapsed: Duration::ZERO,
            max_residual: max_abs(&residual[..n]),
            condition_estimate: solved.condition,
            refinement_steps: solved.refinement_steps,
            stalled_at: solved.stalled,
            warnings,
        };
        Ok(self.finish(functionals, poly, &solved.x, report, start))
    }

    /// Refuses a dense solve of `unknowns` whose matrices would not fit in the memory limit:
    /// the `f64` system (`8 n²` bytes), and for the single-precision factor its `f32` copy too.
    fn check_memory(
        &self,
        unknowns: usize,
        precision: Precision,
        what: &str,
    ) -> Result<(), RbfError> {
        let per_entry = match precision {
            Precision::Double => 8,
            Precision::Single => 12,
        };
        let needed = (unknowns as u64)
            .saturating_mul(unknowns as u64)
            .saturating_mul(per_entry);
        // A budget given here wins; else ZEROSET_MEMORY_LIMIT or what the machine has.
        let limit = match self.memory_limit {
            Some(bytes) => Limit::Machine(bytes),
            None => limits::current_limit().unwrap_or_else(|_| {
                limits::machine_available().map_or(Limit::Unknown, Limit::Machine)
            }),
        };
        match limits::memory_error(what, needed, limit) {
            Some(e) => Err(e.into()),
            None => Ok(()),
        }
    }

    /// The exact dense solve with one step of iterative refinement (the exact residual of the
    /// whole system by direct sums).
    fn solve_dense<const D: usize>(
        &self,
        functionals: &Functionals<D>,
        poly: &Polynomial<D>,
        rhs: &[f64],
    ) -> Result<Solved, RbfError> {
        let factor = self.factor(functionals, poly, Precision::Double)?;
        let mut x = factor.solve(rhs);
        let mut refinement_steps = 0;
        let residual = self.residual(functionals, poly, &x, rhs);
        if max_abs(&residual) > 1e-14 * max_abs(rhs).max(1e-300) {
            let dx = factor.solve(&residual);
            x.iter_mut().zip(&dx).for_each(|(a, b)| *a += b);
            refinement_steps = 1;
        }
        Ok(Solved {
            solver: "dense-cholesky",
            x,
            iterations: 0,
            stalled: None,
            condition: factor.condition(),
            refinement_steps,
        })
    }

    fn finish<const D: usize>(
        &self,
        functionals: Functionals<D>,
        poly: Polynomial<D>,
        x: &[f64],
        mut report: FitReport,
        start: Instant,
    ) -> Fitted<K, D> {
        let field = self.field(functionals, poly, x);
        report.elapsed = start.elapsed();
        Fitted { field, report }
    }

    /// `[t; 0]`.
    fn rhs<const D: usize>(&self, f: &Functionals<D>) -> Vec<f64> {
        let mut rhs = f.targets.clone();
        rhs.resize(f.len() + Polynomial::<D>::len(), 0.0);
        rhs
    }

    /// Expands and checks `constraints`.
    fn prepare<const D: usize>(
        &self,
        constraints: &[Constraint<D>],
    ) -> Result<(Functionals<D>, Polynomial<D>), RbfError> {
        if !(D == 2 || D == 3) {
            return Err(RbfError::Degenerate {
                detail: format!("RBF fields are 2-D or 3-D, not {D}-D"),
            });
        }
        if constraints.is_empty() {
            return Err(RbfError::Empty);
        }
        let mut functionals = Functionals::new(&self.kernel, constraints)?;
        functionals.check_duplicates()?;
        functionals.diagonal = self.kernel.sign() * self.smoothing;
        let poly = Polynomial::fit(&functionals.points);
        Ok((functionals, poly))
    }

    /// Factors the system of `functionals`.
    fn factor<const D: usize>(
        &self,
        functionals: &Functionals<D>,
        poly: &Polynomial<D>,
        precision: Precision,
    ) -> Result<DenseFactor, RbfError> {
        let a = system::assemble(&self.kernel, functionals, poly);
        DenseFactor::new(
            a,
            functionals.len(),
            Polynomial::<D>::len(),
            self.kernel.sign(),
            precision,
        )
    }

    /// The mixed-precision solve: FGMRES on the f64 system (direct-sum products), with the
    /// f32 projected Cholesky as the preconditioner.
    fn solve_mixed<const D: usize>(
        &self,
        functionals: &Functionals<D>,
        poly: &Polynomial<D>,
        rhs: &[f64],
    ) -> Result<Solved, RbfError> {
        let factor = self.factor(functionals, poly, Precision::Single)?;
        let x0 = factor.solve(rhs);
        let op = SystemOperator {
            kernel: &self.kernel,
            f: functionals,
            poly,
        };
        let precond = FactorPreconditioner(&factor);
        let mut gmres = Gmres::default()
            .with_tolerance(MIXED_TOLERANCE)
            .with_max_iterations(60)
            .with_normal_residual(false);
        if let Some(m) = &self.monitor {
            gmres = gmres.with_monitor(m.clone());
        }
        let result = gmres.solve(LsqMatrix::Operator(&op), rhs, Some(&x0), Some(&precond));
        let (x, iterations, stalled) = system::accept_stall(result)?;
        Ok(Solved {
            solver: "mixed-cholesky-gmres",
            x,
            iterations,
            stalled,
            condition: factor.condition(),
            refinement_steps: 0,
        })
    }

    /// `rhs − A x` by direct sums.
    fn residual<const D: usize>(
        &self,
        f: &Functionals<D>,
        poly: &Polynomial<D>,
        x: &[f64],
        rhs: &[f64],
    ) -> Vec<f64> {
        let mut ax = vec![0.0; x.len()];
        system::apply(&self.kernel, f, poly, x, &mut ax);
        rhs.iter().zip(&ax).map(|(b, a)| b - a).collect()
    }

    /// The field of the solution `x = [w; c]`.
    fn field<const D: usize>(
        &self,
        mut functionals: Functionals<D>,
        poly: Polynomial<D>,
        x: &[f64],
    ) -> RbfField<K, D> {
        // The smoothing shaped the weights; the field is evaluated without it (and so equals
        // its copy read back from a field file).
        functionals.diagonal = 0.0;
        let n = functionals.len();
        let bounds = Aabb::from_points(&functionals.points)
            .map(|b| b.expanded(0.05 * b.diagonal().max(1e-12)))
            .unwrap_or_else(unreachable_bounds::<D>);
        RbfField {
            kernel: self.kernel.clone(),
            functionals,
            weights: x[..n].to_vec(),
            poly,
            poly_coefficients: x[n..].to_vec(),
            bounds,
        }
    }
}

fn condition_warning(condition: f64) -> String {
    format!(
        "condition estimate {condition:.1e} exceeds {CONDITION_WARNING:.0e}: the fit may be unreliable (points nearly coincident relative to their spread?)"
    )
}

/// `[Φ P; Pᵀ 0]` as an operator: direct sums, no matrix (symmetric).
struct SystemOperator<'a, K, const D: usize> {
    kernel: &'a K,
    f: &'a Functionals<D>,
    poly: &'a Polynomial<D>,
}

impl<K: Kernel, const D: usize> LinearOperator for SystemOperator<'_, K, D> {
    fn nrows(&self) -> usize {
        self.f.len() + Polynomial::<D>::len()
    }
    fn ncols(&self) -> usize {
        self.nrows()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        system::apply(self.kernel, self.f, self.poly, x, y);
    }
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
        system::apply(self.kernel, self.f, self.poly, y, x);
    }
}

/// A factorisation's solve as a (right) preconditioner.
#[derive(Debug)]
struct FactorPreconditioner<'a>(&'a DenseFactor);

impl Preconditioner for FactorPreconditioner<'_> {
    fn name(&self) -> &'static str {
        "projected-cholesky"
    }
    fn dim(&self) -> usize {
        self.0.size()
    }
    fn apply_inverse(&self, v: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&self.0.solve(v));
    }
}

/// The largest and root-mean-square `|σμ wᵢ|` over the value functionals: how far a smoothed
/// field misses its values (both 0 without smoothing).
fn misfits<const D: usize>(f: &Functionals<D>, w: &[f64]) -> (f64, f64) {
    let (mut max, mut sum, mut count) = (0.0f64, 0.0, 0usize);
    for (kind, wi) in f.kinds.iter().zip(w) {
        if *kind == system::Functional::Value {
            let m = (f.diagonal * wi).abs();
            max = max.max(m);
            sum += m * m;
            count += 1;
        }
    }
    (max, (sum / count.max(1) as f64).sqrt())
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |s, x| s.max(x.abs()))
}

/// A fit always has points (it refuses empty input), so its box exists; this is the unit box
/// for completeness.
fn unreachable_bounds<const D: usize>() -> Aabb<D> {
    Aabb::from_points(&[[0.0; D], [1.0; D]]).expect("two distinct finite points have a box")
}

#[cfg(test)]
mod tests;
