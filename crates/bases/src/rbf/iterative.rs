//! The iterative fit: GMRES in a basis of approximate cardinal functions (Beatson, Cherrie and
//! Mouat 1999; Beatson, Light and Billings 2000).
//!
//! For every centre `i` a small local interpolation problem on its `q` nearest centres `Sᵢ`
//! (plus a few centres spread over the whole set, which tame the far field) gives
//!
//! ```text
//!     ψᵢ(x) = Σ_{j∈Sᵢ} λᵢⱼ φ(|x − xⱼ|) + pᵢ(x),     ψᵢ(x_k) = δᵢₖ for k ∈ Sᵢ,  Σⱼ λᵢⱼ q(xⱼ) = 0
//! ```
//!
//! for every linear `q`. In the basis `s = Σᵢ μᵢ ψᵢ` the interpolation matrix
//! `B_kᵢ = ψᵢ(x_k) = (Φ Λᵀ + P Cᵀ)_kᵢ` is close to the identity (exact on `Sᵢ`), so GMRES
//! converges in few steps; the side conditions hold by construction
//! (`Pᵀ Λᵀ μ = Σᵢ μᵢ Pᵀ λᵢ = 0`). The set-up is `n` dense solves of size `q + D + 1`.
//!
//! **The coarse level.** Local sets see no far field: on their own the steps grow with `n`
//! (the full bunny, 104,502 off-surface functionals, stalled at a relative residual of 5e-2
//! after 100 steps). As in the two-level methods of Beatson, Light & Billings, the
//! interpolation problem on `|C|` centres spread over the set (farthest-point order,
//! [`IterativeParams::coarse`], default 2000) is factored once (the dense solve's projected Cholesky), and each
//! step adds its interpolant of `μ` on `C` to the local functions' sum (additively): the
//! bunny then converges in 80 steps; the sphere set-up in 34, 48 and 71 steps at `n` = 10⁴,
//! 3·10⁴, 10⁵ — still growing with `n` (a multilevel hierarchy would not).
//!
//! **The products.** A product with `B` is a sparse `Λᵀ μ`, the coarse solve, and one kernel
//! sum `Φ w` at the centres: a vectorised parallel direct sum, or from
//! [`IterativeParams::fmm_from`] centres on in 3-D the FMM over the same tree every step
//! ([`fmm::product`](super::fmm::product): `O(n)` memory; the M2L operators built once per
//! process). Inexact products let GMRES reach their own accuracy and no further, so the
//! tolerance is raised to
//! [`FMM_PRODUCT_TOLERANCE`] on that path; the
//! fit's report measures the constraint residual by the exact direct sum.
//!
//! Value constraints only: Hermite fits use the dense solve.

use std::num::NonZero;

use faer::Mat;
use faer::linalg::solvers::{PartialPivLu, Solve};
use kiddo::SquaredEuclidean;
use kiddo::kd_tree::KdTree;
use kiddo::leaf_strategies::FlatVec;
use kiddo::stem_strategies::Eytzinger;
use rayon::prelude::*;
use zeroset_field_core::lsq::{LinearOperator, LsqMatrix, Monitor};
use zeroset_solvers::gmres::Gmres;

use super::dense::{DenseFactor, Precision};
use super::fmm::product::FMM_PRODUCT_TOLERANCE;
use super::system::{self, Functional, Functionals, Polynomial};
use super::{Kernel, RbfError};

/// A local cardinal function: `(j, λⱼ)` over its local set, and its polynomial coefficients.
type Cardinal = (Vec<(u32, f64)>, [f64; 4]);

type Tree<const D: usize> = KdTree<f64, u32, Eytzinger, FlatVec<f64, u32, D, 32>, D, 32>;

/// Parameters of the iterative fit.
#[derive(Debug, Clone, PartialEq)]
pub struct IterativeParams {
    /// Nearest centres per local cardinal function, `q` (default 80: on the sphere set-up with
    /// `r` at N = 6000, 24 GMRES steps against 49 with 50 and 16 with 120, the best time).
    pub neighbours: usize,
    /// Centres spread over the whole set added to every local problem (default 8).
    pub far: usize,
    /// Relative residual `‖t − s(x)‖/‖t‖` to reach (default 1e-12; about 1e-13 is the rounding
    /// floor of the direct sums).
    pub tolerance: f64,
    /// Limit on GMRES steps (default 300).
    pub max_iterations: usize,
    /// GMRES restart length (default 100).
    pub restart: usize,
    /// Centres of the coarse level (default 2000): the interpolation problem on this many
    /// centres spread over the set, factored once, corrects every step's far field
    /// (additively, with the local cardinal functions); used when there are more than twice as
    /// many centres. 0: none.
    pub coarse: usize,
    /// From this many centres on (3-D fields), the products are formed by the FMM
    /// ([`fmm::product`](super::fmm::product)) rather than the direct sum (default
    /// [`FMM_PRODUCT_MIN`](super::FMM_PRODUCT_MIN)).
    pub fmm_from: usize,
}

impl Default for IterativeParams {
    fn default() -> Self {
        Self {
            neighbours: 80,
            far: 8,
            tolerance: 1e-12,
            max_iterations: 300,
            restart: 100,
            coarse: 2000,
            fmm_from: super::FMM_PRODUCT_MIN,
        }
    }
}

/// `w ↦ Φ w` at the centres by a fast method (the FMM), instead of the direct sum.
pub(crate) type KernelProduct<'a> = dyn Fn(&[f64], &mut [f64]) + Sync + 'a;

/// The operator `μ ↦ B μ = Φ Λᵀ μ + P Cᵀ μ` of the module docs.
struct CardinalBasis<'a, K: ?Sized, const D: usize> {
    kernel: &'a K,
    /// `Φ w` by a fast method; `None`: the direct sum.
    product: Option<&'a KernelProduct<'a>>,
    f: &'a Functionals<D>,
    poly: &'a Polynomial<D>,
    /// `Λᵀ` by rows: for centre `j`, the `(i, λᵢⱼ)` with `j ∈ Sᵢ`, sorted by `i`.
    lambda_t: Vec<Vec<(u32, f64)>>,
    /// `Λ` by rows: `(j, λᵢⱼ)` for `j ∈ Sᵢ`.
    lambda: Vec<Vec<(u32, f64)>>,
    /// The polynomial coefficients `cᵢ` of each `ψᵢ`.
    c: Vec<[f64; 4]>,
    /// The coarse level, if any.
    coarse: Option<Coarse>,
}

/// The coarse level: the interpolation problem on a subset `C` of the centres spread over the
/// set, factored once. It maps the values `v` to the weights (on `C`) and polynomial of the
/// field interpolating `v` on `C`: `[w_C; c_C] = A_C⁻¹ [v_C; t]` (`t`: the polynomial rows'
/// right-hand side, 0 in the forward map).
struct Coarse {
    index: Vec<u32>,
    factor: DenseFactor,
}

impl Coarse {
    fn new<K: Kernel + ?Sized, const D: usize>(
        kernel: &K,
        f: &Functionals<D>,
        poly: &Polynomial<D>,
        count: usize,
    ) -> Result<Self, RbfError> {
        let mut index = spread(&f.points, count);
        index.sort_unstable();
        let points: Vec<_> = index.iter().map(|&i| f.points[i]).collect();
        let k = points.len();
        let subset = Functionals {
            soa: std::array::from_fn(|a| points.iter().map(|p| p[a]).collect()),
            points,
            kinds: vec![Functional::Value; k],
            targets: vec![0.0; k],
        };
        let a = system::assemble(kernel, &subset, poly);
        let factor = DenseFactor::new(
            a,
            k,
            Polynomial::<D>::len(),
            kernel.sign(),
            Precision::Double,
        )?;
        Ok(Self {
            index: index.into_iter().map(|i| i as u32).collect(),
            factor,
        })
    }

    /// `A_C⁻¹ [v_C; tail]`: `|C|` weights, then the polynomial's.
    fn solve(&self, v: &[f64], tail: &[f64]) -> Vec<f64> {
        let mut rhs: Vec<f64> = self.index.iter().map(|&i| v[i as usize]).collect();
        rhs.extend_from_slice(tail);
        self.factor.solve(&rhs)
    }
}

impl<K: Kernel + ?Sized, const D: usize> CardinalBasis<'_, K, D> {
    /// `(w, c) = (Λᵀ μ, Cᵀ μ)`: the ordinary RBF coefficients of `Σ μᵢ ψᵢ`, plus the coarse
    /// level's interpolant of `μ` on `C`.
    fn coefficients(&self, mu: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let mut w: Vec<f64> = self
            .lambda_t
            .par_iter()
            .map(|row| row.iter().map(|&(i, l)| l * mu[i as usize]).sum())
            .collect();
        let m = Polynomial::<D>::len();
        let mut c = vec![0.0; m];
        for (ci, mi) in self.c.iter().zip(mu) {
            for k in 0..m {
                c[k] += ci[k] * mi;
            }
        }
        if let Some(coarse) = &self.coarse {
            let s = coarse.solve(mu, &vec![0.0; m]);
            let k = coarse.index.len();
            for (t, &i) in coarse.index.iter().enumerate() {
                w[i as usize] += s[t];
            }
            for j in 0..m {
                c[j] += s[k + j];
            }
        }
        (w, c)
    }
}

impl<K: Kernel + ?Sized, const D: usize> LinearOperator for CardinalBasis<'_, K, D> {
    fn nrows(&self) -> usize {
        self.f.len()
    }
    fn ncols(&self) -> usize {
        self.f.len()
    }
    fn apply(&self, mu: &[f64], y: &mut [f64]) {
        let n = self.f.len();
        let (w, c) = self.coefficients(mu);
        if let Some(product) = self.product {
            product(&w, y);
            y.par_iter_mut()
                .zip(&self.f.points)
                .for_each(|(yi, x)| *yi += self.poly.value(&c, x));
            return;
        }
        let mut x = w;
        x.extend_from_slice(&c);
        let mut full = vec![0.0; n + Polynomial::<D>::len()];
        system::apply(self.kernel, self.f, self.poly, &x, &mut full);
        y.copy_from_slice(&full[..n]);
    }
    fn apply_transpose(&self, y: &[f64], out: &mut [f64]) {
        // Bᵀ y = Λ (Φ y) + C (Pᵀ y); Φ is symmetric, so Φ y is the top of A [y; 0].
        let n = self.f.len();
        let m = Polynomial::<D>::len();
        let mut full = vec![0.0; n + m];
        if let Some(product) = self.product {
            product(y, &mut full[..n]);
            for (yj, x) in y.iter().zip(&self.f.points) {
                let row = self.poly.row(x, system::Functional::Value);
                for k in 0..m {
                    full[n + k] += row[k] * yj;
                }
            }
        } else {
            let mut x = y.to_vec();
            x.resize(n + m, 0.0);
            system::apply(self.kernel, self.f, self.poly, &x, &mut full);
        }
        let (phi_y, pt_y) = full.split_at(n);
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            let local: f64 = self.lambda[i]
                .iter()
                .map(|&(j, l)| l * phi_y[j as usize])
                .sum();
            *o = local + (0..m).map(|k| self.c[i][k] * pt_y[k]).sum::<f64>();
        });
        // The coarse map's transpose: A_C is symmetric.
        if let Some(coarse) = &self.coarse {
            let s = coarse.solve(phi_y, pt_y);
            for (t, &i) in coarse.index.iter().enumerate() {
                out[i as usize] += s[t];
            }
        }
    }
}

/// The outcome of an iterative solve.
pub(crate) struct Iterated {
    /// `[w; c]`.
    pub x: Vec<f64>,
    /// GMRES steps.
    pub iterations: usize,
    /// The relative residual GMRES stalled at, if it stopped short of its tolerance (but
    /// within [`system::ACCEPTABLE_STALL`]).
    pub stalled: Option<f64>,
}

/// Solves the value-only system of `f` iteratively.
pub(crate) fn solve<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    f: &Functionals<D>,
    poly: &Polynomial<D>,
    params: &IterativeParams,
    product: Option<&KernelProduct<'_>>,
    monitor: Option<Monitor>,
) -> Result<Iterated, RbfError> {
    let n = f.len();
    let m = Polynomial::<D>::len();
    if !f.values_only() {
        return Err(RbfError::Degenerate {
            detail: "the iterative fit takes value constraints only; use the dense fit".into(),
        });
    }
    let tree = Tree::<D>::new_from_slice(&f.points).map_err(|e| RbfError::Degenerate {
        detail: format!("cannot index the points: {e}"),
    })?;
    let far = spread(&f.points, params.far.min(n));
    let q = params.neighbours.clamp(m + 1, n);
    let locals: Vec<Result<Cardinal, RbfError>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let found = tree
                .query(&f.points[i])
                .nearest_n::<SquaredEuclidean<f64>>(
                    NonZero::new(q).unwrap_or(NonZero::<usize>::MIN),
                )
                .execute();
            let mut set: Vec<usize> = found.iter().map(|r| r.item as usize).collect();
            for &j in &far {
                if !set.contains(&j) {
                    set.push(j);
                }
            }
            set.sort_unstable();
            local_cardinal(kernel, f, poly, i, &set)
        })
        .collect();
    let mut lambda = Vec::with_capacity(n);
    let mut c = Vec::with_capacity(n);
    for local in locals {
        let (l, ci) = local?;
        lambda.push(l);
        c.push(ci);
    }
    let mut lambda_t: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
    for (i, row) in lambda.iter().enumerate() {
        for &(j, l) in row {
            lambda_t[j as usize].push((i as u32, l));
        }
    }
    let coarse = if params.coarse > 0 && n > 2 * params.coarse {
        Some(Coarse::new(kernel, f, poly, params.coarse)?)
    } else {
        None
    };
    let op = CardinalBasis {
        kernel,
        product,
        coarse,
        f,
        poly,
        lambda_t,
        lambda,
        c,
    };
    // Inexact products: no lower than their own error.
    let tolerance = match product {
        Some(_) => params.tolerance.max(FMM_PRODUCT_TOLERANCE),
        None => params.tolerance,
    };
    let mut gmres = Gmres::default()
        .with_tolerance(tolerance)
        .with_max_iterations(params.max_iterations)
        .with_restart(params.restart)
        .with_normal_residual(false);
    if let Some(m) = monitor {
        gmres = gmres.with_monitor(m);
    }
    let (mu, iterations, stalled) =
        system::accept_stall(gmres.solve(LsqMatrix::Operator(&op), &f.targets, None, None))?;
    let (w, cc) = op.coefficients(&mu);
    let mut x = w;
    x.extend_from_slice(&cc);
    debug_assert_eq!(x.len(), n + m);
    Ok(Iterated {
        x,
        iterations,
        stalled,
    })
}

/// The cardinal function of centre `i` on the local set `set` (sorted, containing `i`).
fn local_cardinal<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    f: &Functionals<D>,
    poly: &Polynomial<D>,
    i: usize,
    set: &[usize],
) -> Result<Cardinal, RbfError> {
    let (k, m) = (set.len(), Polynomial::<D>::len());
    let size = k + m;
    let a = Mat::from_fn(size, size, |r, s| match (r < k, s < k) {
        (true, true) => system::entry(
            kernel,
            (&f.points[set[r]], Functional::Value),
            (&f.points[set[s]], Functional::Value),
        ),
        (true, false) => poly.row(&f.points[set[r]], Functional::Value)[s - k],
        (false, true) => poly.row(&f.points[set[s]], Functional::Value)[r - k],
        (false, false) => 0.0,
    });
    let mut rhs = Mat::from_fn(size, 1, |r, _| if r < k && set[r] == i { 1.0 } else { 0.0 });
    PartialPivLu::new(a.as_ref()).solve_in_place(rhs.as_mut());
    if (0..size).any(|r| !rhs[(r, 0)].is_finite()) {
        return Err(RbfError::Singular(format!(
            "the local problem of centre {i} ({k} neighbours) is singular: duplicate or coplanar points"
        )));
    }
    let lambda = (0..k).map(|r| (set[r] as u32, rhs[(r, 0)])).collect();
    let mut c = [0.0; 4];
    for s in 0..m {
        c[s] = rhs[(k + s, 0)];
    }
    Ok((lambda, c))
}

/// `count` centres spread over the set: the first, then repeatedly the one farthest from those
/// chosen (deterministic).
pub(crate) fn spread<const D: usize>(points: &[[f64; D]], count: usize) -> Vec<usize> {
    let mut chosen = Vec::with_capacity(count);
    if count == 0 || points.is_empty() {
        return chosen;
    }
    let d2 = |a: &[f64; D], b: &[f64; D]| -> f64 { (0..D).map(|k| (a[k] - b[k]).powi(2)).sum() };
    let mut nearest: Vec<f64> = vec![f64::INFINITY; points.len()];
    let mut next = 0;
    for _ in 0..count {
        chosen.push(next);
        let p = points[next];
        nearest
            .iter_mut()
            .zip(points)
            .for_each(|(d, q)| *d = d.min(d2(&p, q)));
        next = (0..points.len())
            .max_by(|&a, &b| nearest[a].total_cmp(&nearest[b]).then(b.cmp(&a)))
            .unwrap_or(0);
    }
    chosen
}
