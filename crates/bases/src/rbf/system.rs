//! The interpolation system of generalised (Hermite) RBF interpolation.
//!
//! Each constraint is a linear functional `Lᵢ` at a point `xᵢ`: a value `δ_{xᵢ}` or a partial
//! derivative `∂_a δ_{xᵢ}` (a gradient constraint is `D` of them). The field is
//!
//! ```text
//!     s(x) = Σⱼ wⱼ Lⱼʸ φ(|x − y|) + Σₖ cₖ pₖ(x),     pₖ ∈ {1, (x_a − m_a)/h}
//! ```
//!
//! and `Lᵢ s = tᵢ` with the side conditions `Σⱼ wⱼ Lⱼ pₖ = 0` give the symmetric system
//!
//! ```text
//!     [ Φ  P ] [w]   [t]       Φᵢⱼ = Lᵢˣ Lⱼʸ φ(|x − y|):  φ(r), −∂_bφ(d), ∂_aφ(d), −∂_a∂_bφ(d)
//!     [ Pᵀ 0 ] [c] = [0],      Pᵢₖ = Lᵢ pₖ,               d = xᵢ − xⱼ
//! ```
//!
//! for (value, value), (value, ∂_b), (∂_a, value) and (∂_a, ∂_b) pairs. The polynomial is
//! centred on the points' centroid `m` and scaled by their half-extent `h`, which keeps `P`'s
//! columns comparable (conditioning only; the interpolant is the same).

use rayon::prelude::*;
use zeroset_field_core::Point;

use super::kernel::{self, Kernel};
use super::{Constraint, Prescribed, RbfError};

/// One linear functional: a value or a partial derivative at a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Functional {
    Value,
    Derivative(usize),
}

/// The functionals of a constraint list, with their points and targets.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Functionals<const D: usize> {
    pub points: Vec<Point<D>>,
    pub kinds: Vec<Functional>,
    pub targets: Vec<f64>,
    /// `points[i]` coordinates as structure of arrays, for the vectorised value-only sums.
    pub soa: [Vec<f64>; D],
    /// Added to `Φᵢᵢ` of every value functional: the smoothing `σμ` of a fit that
    /// approximates its values (0: interpolation). It changes the weights, not how the field
    /// is evaluated: `s(xᵢ) = tᵢ − σμ wᵢ`.
    pub diagonal: f64,
}

impl<const D: usize> Functionals<D> {
    /// What functional `i` adds to its own diagonal entry: [`Functionals::diagonal`] for a
    /// value, 0 for a gradient component (fitted exactly).
    pub fn diagonal_at(&self, i: usize) -> f64 {
        match self.kinds[i] {
            Functional::Value => self.diagonal,
            _ => 0.0,
        }
    }

    /// Expands and checks `constraints` (finite, gradient kernels smooth enough).
    pub fn new<K: Kernel + ?Sized>(
        kernel: &K,
        constraints: &[Constraint<D>],
    ) -> Result<Self, RbfError> {
        let mut f = Self {
            points: Vec::new(),
            kinds: Vec::new(),
            targets: Vec::new(),
            soa: std::array::from_fn(|_| Vec::new()),
            diagonal: 0.0,
        };
        for (index, c) in constraints.iter().enumerate() {
            if let Some(&value) = c.point.iter().find(|v| !v.is_finite()) {
                return Err(RbfError::NonFinite {
                    index,
                    what: "coordinate",
                    value,
                });
            }
            match c.prescribed {
                Prescribed::Value(v) => {
                    if !v.is_finite() {
                        return Err(RbfError::NonFinite {
                            index,
                            what: "value",
                            value: v,
                        });
                    }
                    f.push(c.point, Functional::Value, v);
                }
                Prescribed::Gradient(g) => {
                    if let Some(&value) = g.iter().find(|v| !v.is_finite()) {
                        return Err(RbfError::NonFinite {
                            index,
                            what: "gradient",
                            value,
                        });
                    }
                    if kernel.hessian_at_zero().is_none() {
                        return Err(RbfError::KernelNotSmooth {
                            kernel: kernel.name().to_string(),
                        });
                    }
                    for (a, &ga) in g.iter().enumerate() {
                        f.push(c.point, Functional::Derivative(a), ga);
                    }
                }
            }
        }
        Ok(f)
    }

    fn push(&mut self, p: Point<D>, kind: Functional, target: f64) {
        self.points.push(p);
        self.kinds.push(kind);
        self.targets.push(target);
        for (coords, v) in self.soa.iter_mut().zip(p) {
            coords.push(v);
        }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether every functional is a value (the fast, vectorised paths apply).
    pub fn values_only(&self) -> bool {
        self.kinds.iter().all(|k| *k == Functional::Value)
    }

    /// Appends `other`.
    pub fn extend(&mut self, other: &Self) {
        for i in 0..other.len() {
            self.push(other.points[i], other.kinds[i], other.targets[i]);
        }
    }

    /// Refuses two functionals of the same kind at the same point (a singular system),
    /// naming the constraints by functional index.
    pub fn check_duplicates(&self) -> Result<(), RbfError> {
        let mut order: Vec<usize> = (0..self.len()).collect();
        let key = |i: usize| (self.points[i].map(f64::to_bits), self.kinds[i]);
        order.sort_by(|&i, &j| {
            let (pi, pj) = (self.points[i], self.points[j]);
            pi.partial_cmp(&pj)
                .unwrap_or(std::cmp::Ordering::Equal)
                .then(kind_rank(self.kinds[i]).cmp(&kind_rank(self.kinds[j])))
                .then(i.cmp(&j))
        });
        for w in order.windows(2) {
            if key(w[0]) == key(w[1]) {
                return Err(RbfError::Duplicate {
                    first: w[0].min(w[1]),
                    second: w[0].max(w[1]),
                    point: self.points[w[0]].to_vec(),
                });
            }
        }
        Ok(())
    }
}

fn kind_rank(k: Functional) -> usize {
    match k {
        Functional::Value => 0,
        Functional::Derivative(a) => 1 + a,
    }
}

/// The linear polynomial `1, (x_a − m_a)/h`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Polynomial<const D: usize> {
    pub centre: Point<D>,
    pub scale: f64,
}

impl<const D: usize> Polynomial<D> {
    /// Centred on the centroid of `points`, scaled by their largest half-extent.
    pub fn fit(points: &[Point<D>]) -> Self {
        let n = points.len().max(1) as f64;
        let centre = std::array::from_fn(|a| points.iter().map(|p| p[a]).sum::<f64>() / n);
        let half = (0..D)
            .map(|a| {
                let (lo, hi) = points
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |m, p| {
                        (m.0.min(p[a]), m.1.max(p[a]))
                    });
                0.5 * (hi - lo)
            })
            .fold(0.0, f64::max);
        Self {
            centre,
            scale: if half > 0.0 { half } else { 1.0 },
        }
    }

    /// `m = D + 1` terms.
    pub const fn len() -> usize {
        D + 1
    }

    /// `L pₖ` for every term `k`.
    pub fn row(&self, p: &Point<D>, kind: Functional) -> [f64; 4] {
        let mut row = [0.0; 4];
        match kind {
            Functional::Value => {
                row[0] = 1.0;
                for a in 0..D {
                    row[1 + a] = (p[a] - self.centre[a]) / self.scale;
                }
            }
            Functional::Derivative(a) => row[1 + a] = 1.0 / self.scale,
        }
        row
    }

    /// `Σₖ cₖ pₖ(x)`.
    pub fn value(&self, c: &[f64], x: &Point<D>) -> f64 {
        let row = self.row(x, Functional::Value);
        (0..=D).map(|k| c[k] * row[k]).sum()
    }

    /// `∇ Σₖ cₖ pₖ`.
    pub fn gradient(&self, c: &[f64]) -> Point<D> {
        std::array::from_fn(|a| c[1 + a] / self.scale)
    }
}

/// `Lᵢˣ Lⱼʸ φ(|x − y|)`.
pub(crate) fn entry<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    (xi, li): (&Point<D>, Functional),
    (xj, lj): (&Point<D>, Functional),
) -> f64 {
    let d: Point<D> = std::array::from_fn(|a| xi[a] - xj[a]);
    match (li, lj) {
        (Functional::Value, Functional::Value) => kernel::value(kernel, &d),
        (Functional::Value, Functional::Derivative(b)) => -kernel::gradient(kernel, &d)[b],
        (Functional::Derivative(a), Functional::Value) => kernel::gradient(kernel, &d)[a],
        (Functional::Derivative(a), Functional::Derivative(b)) => {
            -kernel::hessian(kernel, &d)[a][b]
        }
    }
}

/// The dense symmetric `(n + m) × (n + m)` matrix `[Φ P; Pᵀ 0]` (with
/// [`Functionals::diagonal`] on `Φ`'s value diagonal), column-major, filled in parallel by
/// columns.
pub(crate) fn assemble<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    f: &Functionals<D>,
    poly: &Polynomial<D>,
) -> Vec<f64> {
    let n = f.len();
    let m = Polynomial::<D>::len();
    let size = n + m;
    let mut a = vec![0.0; size * size];
    let arch = pulp::Arch::new();
    let values_only = f.values_only();
    a.par_chunks_mut(size).enumerate().for_each(|(j, col)| {
        if j < n && values_only {
            arch.dispatch(ValueColumn {
                kernel,
                f,
                j,
                col: &mut col[..n],
            });
            col[j] += f.diagonal;
            let row = poly.row(&f.points[j], Functional::Value);
            col[n..].copy_from_slice(&row[..m]);
        } else if j < n {
            let (xj, lj) = (&f.points[j], f.kinds[j]);
            for (i, out) in col[..n].iter_mut().enumerate() {
                *out = entry(kernel, (&f.points[i], f.kinds[i]), (xj, lj));
            }
            col[j] += f.diagonal_at(j);
            let row = poly.row(xj, lj);
            col[n..].copy_from_slice(&row[..m]);
        } else {
            for (i, out) in col[..n].iter_mut().enumerate() {
                *out = poly.row(&f.points[i], f.kinds[i])[j - n];
            }
        }
    });
    a
}

/// `y ← [Φ P; Pᵀ 0] [w; c]` (with [`Functionals::diagonal`]) by direct sums, in parallel over
/// rows (fixed order per row, so the result does not depend on the thread count).
pub(crate) fn apply<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    f: &Functionals<D>,
    poly: &Polynomial<D>,
    x: &[f64],
    y: &mut [f64],
) {
    let n = f.len();
    let m = Polynomial::<D>::len();
    let (w, c) = x.split_at(n);
    let (top, bottom) = y.split_at_mut(n);
    let arch = pulp::Arch::new();
    let values_only = f.values_only();
    top.par_iter_mut().enumerate().for_each(|(i, out)| {
        let (xi, li) = (&f.points[i], f.kinds[i]);
        if values_only {
            let sum = arch.dispatch(SlicesSumAt {
                kernel,
                sources: std::array::from_fn(|a| &f.soa[a][..n]),
                weights: w,
                x: xi,
            });
            *out = sum + poly.value(c, xi) + f.diagonal * w[i];
            return;
        }
        let s: f64 = w
            .iter()
            .enumerate()
            .map(|(j, wj)| entry(kernel, (xi, li), (&f.points[j], f.kinds[j])) * wj)
            .sum();
        let row = poly.row(xi, li);
        *out = s + (0..m).map(|k| row[k] * c[k]).sum::<f64>() + f.diagonal_at(i) * w[i];
    });
    bottom.fill(0.0);
    for (j, wj) in w.iter().enumerate() {
        let row = poly.row(&f.points[j], f.kinds[j]);
        for k in 0..m {
            bottom[k] += row[k] * wj;
        }
    }
}

/// `Σⱼ wⱼ φ(|x − yⱼ|)` at each target `x`, over centres `yⱼ` given as coordinate slices
/// (`sources[a][j]`, all as long as `weights`): vectorised per target, in parallel over the
/// targets (fixed order per target, so the result does not depend on the thread count).
pub(crate) fn kernel_sums_at<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    sources: [&[f64]; D],
    weights: &[f64],
    targets: &[Point<D>],
) -> Vec<f64> {
    let arch = pulp::Arch::new();
    targets
        .par_iter()
        .map(|x| {
            arch.dispatch(SlicesSumAt {
                kernel,
                sources,
                weights,
                x,
            })
        })
        .collect()
}

/// [`kernel_sum_slices`] as a [`pulp::WithSimd`] operation, compiled per instruction set (a
/// closure would not be compiled for AVX2).
struct SlicesSumAt<'a, K: ?Sized, const D: usize> {
    kernel: &'a K,
    sources: [&'a [f64]; D],
    weights: &'a [f64],
    x: &'a Point<D>,
}

impl<K: Kernel + ?Sized, const D: usize> pulp::WithSimd for SlicesSumAt<'_, K, D> {
    type Output = f64;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> f64 {
        kernel_sum_slices(self.kernel, self.sources, self.weights, self.x)
    }
}

/// Column `j` of `Φ` when every functional is a value: `φ(|xᵢ − xⱼ|)` from squared distances,
/// compiled per instruction set so the loop vectorises.
struct ValueColumn<'a, K: ?Sized, const D: usize> {
    kernel: &'a K,
    f: &'a Functionals<D>,
    j: usize,
    col: &'a mut [f64],
}

impl<K: Kernel + ?Sized, const D: usize> pulp::WithSimd for ValueColumn<'_, K, D> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let n = self.col.len();
        let xj = self.f.points[self.j];
        let (out_chunks, out_tail) = self.col.as_chunks_mut::<LANES>();
        let coords: [(&[[f64; LANES]], &[f64]); D] =
            std::array::from_fn(|a| self.f.soa[a][..n].as_chunks::<LANES>());
        for (k, out) in out_chunks.iter_mut().enumerate() {
            let mut r2 = [0.0; LANES];
            for (a, (chunks, _)) in coords.iter().enumerate() {
                let ca = &chunks[k];
                for l in 0..LANES {
                    let d = ca[l] - xj[a];
                    r2[l] += d * d;
                }
            }
            for l in 0..LANES {
                out[l] = self.kernel.value_of_squared(r2[l]);
            }
        }
        for (t, out) in out_tail.iter_mut().enumerate() {
            let r2: f64 = (0..D).map(|a| (coords[a].1[t] - xj[a]).powi(2)).sum();
            *out = self.kernel.value_of_squared(r2);
        }
    }
}

/// Lanes of the vectorised sums.
const LANES: usize = 8;

/// `Σⱼ wⱼ φ(|x − xⱼ|)` over value functionals, with eight fixed-order partial sums so that the
/// loop vectorises and the result does not depend on how calls are spread over threads.
/// Callers inline it into a [`pulp`] dispatch to get AVX2.
#[inline(always)]
pub(crate) fn kernel_sum<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    f: &Functionals<D>,
    weights: &[f64],
    x: &Point<D>,
) -> f64 {
    let n = f.len();
    kernel_sum_slices(
        kernel,
        std::array::from_fn(|a| &f.soa[a][..n]),
        &weights[..n],
        x,
    )
}

/// [`kernel_sum`] over centres given as coordinate slices (`coords[a][j]`, all as long as
/// `weights`): the fast multipole method's direct (near-field) sums.
#[inline(always)]
pub(crate) fn kernel_sum_slices<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    coords: [&[f64]; D],
    weights: &[f64],
    x: &Point<D>,
) -> f64 {
    let n = weights.len();
    let (w_chunks, w_tail) = weights.as_chunks::<LANES>();
    let chunks: [(&[[f64; LANES]], &[f64]); D] =
        std::array::from_fn(|a| coords[a][..n].as_chunks::<LANES>());
    let mut acc = [0.0; LANES];
    for (k, wk) in w_chunks.iter().enumerate() {
        let mut r2 = [0.0; LANES];
        for (a, (c, _)) in chunks.iter().enumerate() {
            let ca = &c[k];
            for l in 0..LANES {
                let d = x[a] - ca[l];
                r2[l] += d * d;
            }
        }
        for l in 0..LANES {
            acc[l] += wk[l] * kernel.value_of_squared(r2[l]);
        }
    }
    let full = n - w_tail.len();
    let tail: f64 = (0..w_tail.len())
        .map(|t| {
            let r2: f64 = (0..D).map(|a| (x[a] - coords[a][full + t]).powi(2)).sum();
            w_tail[t] * kernel.value_of_squared(r2)
        })
        .sum();
    acc.iter().sum::<f64>() + tail
}

/// `Σⱼ wⱼ ∇φ(|x − yⱼ|) = Σⱼ wⱼ D₁(|x − yⱼ|²) (x − yⱼ)` over centres given as coordinate slices,
/// vectorised as [`kernel_sum_slices`] ([`Kernel::slope_factor_of_squared`]).
#[inline(always)]
pub(crate) fn kernel_gradient_sum_slices<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    coords: [&[f64]; D],
    weights: &[f64],
    x: &Point<D>,
) -> [f64; D] {
    let n = weights.len();
    let (w_chunks, w_tail) = weights.as_chunks::<LANES>();
    let chunks: [(&[[f64; LANES]], &[f64]); D] =
        std::array::from_fn(|a| coords[a][..n].as_chunks::<LANES>());
    let mut acc = [[0.0; LANES]; D];
    for (k, wk) in w_chunks.iter().enumerate() {
        let mut d = [[0.0; LANES]; D];
        let mut r2 = [0.0; LANES];
        for (a, (c, _)) in chunks.iter().enumerate() {
            let ca = &c[k];
            for l in 0..LANES {
                d[a][l] = x[a] - ca[l];
                r2[l] += d[a][l] * d[a][l];
            }
        }
        let mut s = [0.0; LANES];
        for l in 0..LANES {
            s[l] = wk[l] * kernel.slope_factor_of_squared(r2[l]);
        }
        for a in 0..D {
            for l in 0..LANES {
                acc[a][l] += s[l] * d[a][l];
            }
        }
    }
    let full = n - w_tail.len();
    let mut g: [f64; D] = std::array::from_fn(|a| acc[a].iter().sum::<f64>());
    for (t, &w) in w_tail.iter().enumerate() {
        let d: [f64; D] = std::array::from_fn(|a| x[a] - coords[a][full + t]);
        let r2: f64 = d.iter().map(|v| v * v).sum();
        let s = w * kernel.slope_factor_of_squared(r2);
        for a in 0..D {
            g[a] += s * d[a];
        }
    }
    g
}

/// [`kernel_gradient_sum_slices`] over a fit's centres, compiled for the machine's vector
/// instructions.
pub(crate) fn kernel_gradient_sum<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    f: &Functionals<D>,
    weights: &[f64],
    x: &Point<D>,
) -> [f64; D] {
    let n = f.len();
    pulp::Arch::new().dispatch(GradientAt {
        kernel,
        coords: std::array::from_fn(|a| &f.soa[a][..n]),
        weights: &weights[..n],
        x,
    })
}

/// [`kernel_gradient_sum_slices`] as a [`pulp::WithSimd`] operation.
pub(crate) struct GradientAt<'a, K: ?Sized, const D: usize> {
    pub kernel: &'a K,
    pub coords: [&'a [f64]; D],
    pub weights: &'a [f64],
    pub x: &'a Point<D>,
}

impl<K: Kernel + ?Sized, const D: usize> pulp::WithSimd for GradientAt<'_, K, D> {
    type Output = [f64; D];

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> [f64; D] {
        kernel_gradient_sum_slices(self.kernel, self.coords, self.weights, self.x)
    }
}

/// The relative residual `‖b − A x‖/‖b‖` a stalled GMRES iterate may still be accepted at.
/// The solvers aim at 1e-12; on real data rounding in the direct sums can stall them a little
/// above (the bunny: 4e-12), far below what matters for a fit.
pub(crate) const ACCEPTABLE_STALL: f64 = 1e-10;

/// GMRES's solution, or its last iterate when it stalled at a relative residual of at most
/// [`ACCEPTABLE_STALL`] (with the residual reached, for a warning).
pub(crate) fn accept_stall(
    result: Result<zeroset_field_core::lsq::Solution, zeroset_field_core::lsq::SolveError>,
) -> Result<(Vec<f64>, usize, Option<f64>), zeroset_field_core::lsq::SolveError> {
    use zeroset_field_core::lsq::SolveError;
    match result {
        Ok(s) => Ok((s.x, s.info.iterations, None)),
        Err(SolveError::NoConvergence {
            iterations,
            rel_residual,
            x,
            ..
        }) if rel_residual <= ACCEPTABLE_STALL => Ok((x, iterations, Some(rel_residual))),
        Err(e) => Err(e),
    }
}
