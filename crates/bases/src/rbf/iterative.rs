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
//! after 100 steps). As in the two-level methods of Beatson, Light & Billings (2000), the
//! interpolation problem on `|C|` centres spread over the set (farthest-point order; 2000,
//! growing as `n/25` to 4000 above 50,000 centres: [`IterativeParams::coarse_size`]) is
//! factored once (the dense solve's projected
//! Cholesky) and corrects what the local functions leave, **multiplicatively**: the map from
//! values to coefficients is
//!
//! ```text
//!     M μ = L μ + K_C (μ − s_L)|_C,      s_L the field of L μ = (Λᵀ μ, Cᵀ μ),
//! ```
//!
//! `K_C` the coarse interpolant of the values it is given at `C`: the local functions' sum,
//! then the coarse interpolant of what that sum misses at the coarse centres (one direct sum
//! from all centres to `C` per step, `n·|C|` kernel values). Adding the coarse interpolant of
//! `μ` itself instead (additively) took 80 steps on the bunny and 34, 48, 71 on the sphere
//! set-up at `n` = 10⁴, 3·10⁴, 10⁵; the multiplicative correction with 2000 coarse centres
//! takes 15 and 7, 7, 8 (2 threads, `cargo run --release --example rbf_timing -- --n …
//! --solvers iterative`). The steps stay flat while a coarse centre stands for fewer points
//! than a local set holds (`n/|C| ≲ q`: 25 with the growing level against `q` = 80, up to
//! 10⁵ centres); far beyond (10⁶) a deeper hierarchy would be needed.
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
use kiddo::SquaredEuclidean;
use kiddo::kd_tree::KdTree;
use kiddo::leaf_strategies::FlatVec;
use kiddo::stem_strategies::Eytzinger;
use rayon::prelude::*;
use zeroset_field_core::Point;
use zeroset_field_core::lsq::{LinearOperator, LsqMatrix, Monitor};
use zeroset_solvers::gmres::Gmres;
use zeroset_solvers::sequential::PartialPivLu;

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
    /// The most centres of the coarse level (default 4000): the interpolation problem on
    /// `n/25` centres spread over the set, at least [`COARSE_MIN`] and at most this many,
    /// factored once, corrects what the local cardinal functions leave at them
    /// (multiplicatively, see the module docs); used when there are more than twice as many
    /// centres. 0: none.
    pub coarse: usize,
    /// From this many centres on (3-D fields), the products are formed by the FMM
    /// ([`fmm::product`](super::fmm::product)) rather than the direct sum (default
    /// [`FMM_PRODUCT_MIN`](super::FMM_PRODUCT_MIN)).
    pub fmm_from: usize,
    /// On the FMM path, above this many functionals the fit's report measures the constraint
    /// residual by the FMM rather than by exact direct sums (default
    /// [`EXACT_RESIDUAL_MAX`](super::EXACT_RESIDUAL_MAX)).
    pub exact_residual_max: usize,
}

impl Default for IterativeParams {
    fn default() -> Self {
        Self {
            neighbours: 80,
            far: 8,
            tolerance: 1e-12,
            max_iterations: 300,
            restart: 100,
            coarse: 4000,
            fmm_from: super::FMM_PRODUCT_MIN,
            exact_residual_max: super::EXACT_RESIDUAL_MAX,
        }
    }
}

/// The fewest centres of the coarse level (or [`IterativeParams::coarse`] if that is less).
/// 2000 up to 50,000 centres; above, the level grows with `n/25` to
/// [`IterativeParams::coarse`]: at the full bunny's 104,502 functionals 4000 centres take 13
/// steps and 18.7 s for the whole `zeroset fit` against 15 steps with 2000, and on 10⁵ sphere
/// points (3·10⁵ functionals) 15 steps and 53 s against 17 and 63 s (2 threads).
pub const COARSE_MIN: usize = 2000;

impl IterativeParams {
    /// The coarse level's size for `n` centres: `n/25` within [`COARSE_MIN`] and
    /// [`IterativeParams::coarse`] (never above the latter).
    pub fn coarse_size(&self, n: usize) -> usize {
        (n / 25).clamp(COARSE_MIN.min(self.coarse), self.coarse)
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
    coarse: Option<Coarse<D>>,
}

/// The coarse level: the interpolation problem on a subset `C` of the centres spread over the
/// set, factored once. It maps values `v` at `C` to the weights (on `C`) and polynomial of the
/// field interpolating them: `[w_C; c_C] = A_C⁻¹ [v; t]` (`t`: the polynomial rows'
/// right-hand side, 0 in the forward map).
struct Coarse<const D: usize> {
    index: Vec<u32>,
    points: Vec<Point<D>>,
    /// `points` by coordinate, for the vectorised sums of the transpose.
    soa: [Vec<f64>; D],
    factor: DenseFactor,
}

impl<const D: usize> Coarse<D> {
    fn new<K: Kernel + ?Sized>(
        kernel: &K,
        f: &Functionals<D>,
        poly: &Polynomial<D>,
        count: usize,
    ) -> Result<Self, RbfError> {
        let mut index = spread(&f.points, count);
        index.sort_unstable();
        let points: Vec<_> = index.iter().map(|&i| f.points[i]).collect();
        let k = points.len();
        let soa: [Vec<f64>; D] = std::array::from_fn(|a| points.iter().map(|p| p[a]).collect());
        let subset = Functionals {
            soa: soa.clone(),
            points: points.clone(),
            kinds: vec![Functional::Value; k],
            targets: vec![0.0; k],
            diagonal: f.diagonal,
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
            points,
            soa,
            factor,
        })
    }

    /// `A_C⁻¹ [v; tail]` for values `v` at `C` (in `index` order): `|C|` weights, then the
    /// polynomial's.
    fn solve(&self, v: &[f64], tail: &[f64]) -> Vec<f64> {
        let mut rhs = v.to_vec();
        rhs.extend_from_slice(tail);
        self.factor.solve(&rhs)
    }
}

impl<K: Kernel + ?Sized, const D: usize> CardinalBasis<'_, K, D> {
    /// `L μ = (Λᵀ μ, Cᵀ μ)`: the ordinary RBF coefficients of `Σ μᵢ ψᵢ`.
    fn local(&self, mu: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let w: Vec<f64> = self
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
        (w, c)
    }

    /// `Lᵀ (v_w, v_c)`: `(Lᵀ v)ᵢ = Σⱼ λᵢⱼ v_w[j] + cᵢ · v_c`.
    fn local_transpose(&self, vw: &[f64], vc: &[f64]) -> Vec<f64> {
        let m = Polynomial::<D>::len();
        self.lambda
            .par_iter()
            .zip(&self.c)
            .map(|(row, ci)| {
                row.iter().map(|&(j, l)| l * vw[j as usize]).sum::<f64>()
                    + (0..m).map(|k| ci[k] * vc[k]).sum::<f64>()
            })
            .collect()
    }

    /// `M μ = L μ + K_C (μ − s)|_C`, `s` the field of `L μ`: the local cardinal functions'
    /// sum, then the coarse level's interpolant of what that sum misses at `C`
    /// (multiplicative, see the module docs). Returns the ordinary coefficients `(w, c)`.
    fn coefficients(&self, mu: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (mut w, mut c) = self.local(mu);
        if let Some(coarse) = &self.coarse {
            let n = self.f.len();
            let sums = system::kernel_sums_at(
                self.kernel,
                std::array::from_fn(|a| &self.f.soa[a][..n]),
                &w,
                &coarse.points,
            );
            let missed: Vec<f64> = coarse
                .index
                .iter()
                .zip(coarse.points.iter().zip(&sums))
                .map(|(&i, (x, s))| {
                    let smoothing = self.f.diagonal * w[i as usize];
                    mu[i as usize] - s - smoothing - self.poly.value(&c, x)
                })
                .collect();
            let m = Polynomial::<D>::len();
            let s = coarse.solve(&missed, &vec![0.0; m]);
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
            let diagonal = self.f.diagonal;
            y.par_iter_mut()
                .zip(&self.f.points)
                .zip(&w)
                .for_each(|((yi, x), wi)| *yi += self.poly.value(&c, x) + diagonal * wi);
            return;
        }
        let mut x = w;
        x.extend_from_slice(&c);
        let mut full = vec![0.0; n + Polynomial::<D>::len()];
        system::apply(self.kernel, self.f, self.poly, &x, &mut full);
        y.copy_from_slice(&full[..n]);
    }
    fn apply_transpose(&self, y: &[f64], out: &mut [f64]) {
        // Bᵀ y = Mᵀ Âᵀ y with Âᵀ y = (Φ y, Pᵀ y) (Φ is symmetric: the top of A [y; 0]) and
        // Mᵀ v = Lᵀ v + (I − Lᵀ Âᵀ) R_Cᵀ K_Cᵀ v.
        let n = self.f.len();
        let m = Polynomial::<D>::len();
        let mut full = vec![0.0; n + m];
        if let Some(product) = self.product {
            product(y, &mut full[..n]);
            for (fj, yj) in full[..n].iter_mut().zip(y) {
                *fj += self.f.diagonal * yj;
            }
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
        let local = self.local_transpose(phi_y, pt_y);
        out.copy_from_slice(&local);
        let Some(coarse) = &self.coarse else { return };
        // K_Cᵀ v: A_C is symmetric, so the weights of A_C⁻¹ [v_w|_C; v_c].
        let at_c: Vec<f64> = coarse.index.iter().map(|&i| phi_y[i as usize]).collect();
        let k = coarse.index.len();
        let g = &coarse.solve(&at_c, pt_y)[..k];
        for (t, &i) in coarse.index.iter().enumerate() {
            out[i as usize] += g[t];
        }
        // − Lᵀ Âᵀ R_Cᵀ g: Âᵀ of a vector that lives on C.
        let mut hw = system::kernel_sums_at(
            self.kernel,
            std::array::from_fn(|a| &coarse.soa[a][..]),
            g,
            &self.f.points,
        );
        for (t, &i) in coarse.index.iter().enumerate() {
            hw[i as usize] += self.f.diagonal * g[t];
        }
        let mut hc = vec![0.0; m];
        for (gt, x) in g.iter().zip(&coarse.points) {
            let row = self.poly.row(x, system::Functional::Value);
            for j in 0..m {
                hc[j] += row[j] * gt;
            }
        }
        let back = self.local_transpose(&hw, &hc);
        out.iter_mut().zip(&back).for_each(|(o, b)| *o -= b);
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
    if !f.values_only() {
        return Err(RbfError::Degenerate {
            detail: "the iterative fit takes value constraints only; use the dense fit".into(),
        });
    }
    let op = CardinalBasis::new(kernel, f, poly, params, product)?;
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
    debug_assert_eq!(x.len(), f.len() + Polynomial::<D>::len());
    Ok(Iterated {
        x,
        iterations,
        stalled,
    })
}

impl<'a, K: Kernel + ?Sized, const D: usize> CardinalBasis<'a, K, D> {
    /// The local cardinal functions of every centre and the coarse level.
    fn new(
        kernel: &'a K,
        f: &'a Functionals<D>,
        poly: &'a Polynomial<D>,
        params: &IterativeParams,
        product: Option<&'a KernelProduct<'a>>,
    ) -> Result<Self, RbfError> {
        let n = f.len();
        let m = Polynomial::<D>::len();
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
        let size = params.coarse_size(n);
        let coarse = if size > 0 && n > 2 * size {
            Some(Coarse::new(kernel, f, poly, size)?)
        } else {
            None
        };
        Ok(CardinalBasis {
            kernel,
            product,
            coarse,
            f,
            poly,
            lambda_t,
            lambda,
            c,
        })
    }
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
    // The kernel block's lower triangle column by column from the local points' coordinates
    // by axis (a loop that vectorises), mirrored; the polynomial rows once per point.
    let coords: [Vec<f64>; D] =
        std::array::from_fn(|a| set.iter().map(|&j| f.points[j][a]).collect());
    let mut a = Mat::<f64>::zeros(size, size);
    let mut r2 = vec![0.0; k];
    for s in 0..k {
        r2[s..].fill(0.0);
        for axis in &coords {
            let xs = axis[s];
            for (d2, x) in r2[s..].iter_mut().zip(&axis[s..]) {
                *d2 += (x - xs) * (x - xs);
            }
        }
        let mut col = a.col_mut(s);
        for (r, d2) in (s..k).zip(&r2[s..]) {
            col[r] = kernel.value_of_squared(*d2);
        }
        let row = poly.row(&f.points[set[s]], Functional::Value);
        for t in 0..m {
            a[(k + t, s)] = row[t];
            a[(s, k + t)] = row[t];
        }
    }
    for s in 0..k {
        a[(s, s)] += f.diagonal;
        for r in s + 1..k {
            a[(s, r)] = a[(r, s)];
        }
    }
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
    // Each round updates the distances to the chosen set and finds the farthest point in one
    // pass, in parallel over fixed chunks; the largest distance, ties to the lowest index, is
    // the same however the chunks are spread over threads.
    const CHUNK: usize = 4096;
    let mut nearest: Vec<f64> = vec![f64::INFINITY; points.len()];
    let mut next = 0;
    for _ in 0..count {
        chosen.push(next);
        let p = points[next];
        next = nearest
            .par_chunks_mut(CHUNK)
            .zip(points.par_chunks(CHUNK))
            .enumerate()
            .map(|(c, (near, pts))| {
                let mut best = (f64::NEG_INFINITY, usize::MAX);
                for (j, (d, q)) in near.iter_mut().zip(pts).enumerate() {
                    *d = d.min(d2(&p, q));
                    if *d > best.0 {
                        best = (*d, c * CHUNK + j);
                    }
                }
                best
            })
            .reduce(
                || (f64::NEG_INFINITY, usize::MAX),
                |a, b| {
                    if b.0 > a.0 || (b.0 == a.0 && b.1 < a.1) {
                        b
                    } else {
                        a
                    }
                },
            )
            .1
            .min(points.len() - 1);
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbf::Biharmonic;

    /// `n` points on a sphere (Fibonacci) with values `z`: value functionals only.
    fn functionals(n: usize) -> (Functionals<3>, Polynomial<3>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut constraints = crate::rbf::Constraints::new();
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            // Three shells, so that the points span a volume as off-surface constraints do.
            let s = 1.0 + 0.05 * (i % 3) as f64;
            let p = [
                s * r * (golden * i as f64).cos(),
                s * r * (golden * i as f64).sin(),
                s * z,
            ];
            constraints.push_value(p, p[2] + 0.1 * p[0] * p[1]);
        }
        let f = Functionals::new(&Biharmonic, constraints.as_slice()).unwrap();
        let poly = Polynomial::fit(&f.points);
        (f, poly)
    }

    #[test]
    fn the_transpose_is_the_adjoint_with_the_coarse_level() {
        let (f0, poly) = functionals(700);
        // Interpolation and smoothing (the diagonal in the local, coarse and product terms),
        // with the products by direct sums inside and passed in as a fast product would be.
        let mut smoothed = f0.clone();
        smoothed.diagonal = -0.05;
        for f in [f0, smoothed] {
            let outside = |w: &[f64], out: &mut [f64]| {
                let soa = std::array::from_fn(|a| &f.soa[a][..]);
                out.copy_from_slice(&system::kernel_sums_at(&Biharmonic, soa, w, &f.points));
            };
            for product in [None, Some(&outside as &KernelProduct<'_>)] {
                check_adjoint(&f, &poly, product);
            }
        }
    }

    fn check_adjoint(
        f: &Functionals<3>,
        poly: &Polynomial<3>,
        product: Option<&KernelProduct<'_>>,
    ) {
        let op = CardinalBasis::new(
            &Biharmonic,
            f,
            poly,
            &IterativeParams {
                neighbours: 30,
                coarse: 100,
                ..IterativeParams::default()
            },
            product,
        )
        .unwrap();
        assert!(op.coarse.is_some());
        let n = f.len();
        let mu: Vec<f64> = (0..n)
            .map(|i| ((i * 37 % 101) as f64 - 50.0) / 50.0)
            .collect();
        let y: Vec<f64> = (0..n)
            .map(|i| ((i * 53 % 97) as f64 - 48.0) / 48.0)
            .collect();
        let (mut b_mu, mut bt_y) = (vec![0.0; n], vec![0.0; n]);
        op.apply(&mu, &mut b_mu);
        op.apply_transpose(&y, &mut bt_y);
        let lhs: f64 = b_mu.iter().zip(&y).map(|(a, b)| a * b).sum();
        let rhs: f64 = mu.iter().zip(&bt_y).map(|(a, b)| a * b).sum();
        assert!(
            (lhs - rhs).abs() <= 1e-10 * lhs.abs().max(1.0),
            "diagonal {}: <Bμ, y> = {lhs}, <μ, Bᵀy> = {rhs}",
            f.diagonal
        );
    }

    #[test]
    fn the_coarse_correction_keeps_the_steps_from_growing_with_n() {
        // The same coarse level at 4× the points: the steps stay put while each coarse centre
        // stands for fewer points than a local set holds (here 7–27 against 80; measured
        // 11, 11, 12 steps at 1000, 2000, 4000 points, where 30 neighbours take 16, 19, 25).
        let steps = |n: usize| {
            let (f, poly) = functionals(n);
            let params = IterativeParams {
                coarse: 150,
                ..IterativeParams::default()
            };
            let out = solve(&Biharmonic, &f, &poly, &params, None, None).unwrap();
            let mut ax = vec![0.0; n + 4];
            system::apply(&Biharmonic, &f, &poly, &out.x, &mut ax);
            let res = f
                .targets
                .iter()
                .zip(&ax)
                .map(|(t, a)| (t - a).abs())
                .fold(0.0, f64::max);
            assert!(res < 1e-9, "n {n}: residual {res:.1e}");
            out.iterations
        };
        let (small, large) = (steps(1000), steps(4000));
        assert!(
            large <= small + 2 && large < 20,
            "{small} steps at 1000 points, {large} at 4000"
        );
    }
}
