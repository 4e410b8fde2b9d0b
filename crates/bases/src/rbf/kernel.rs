//! Radial kernels `φ(r)` and their derivatives.
//!
//! Every derivative of a radial function `φ(|d|)` is a polynomial in `d` whose coefficients are
//! the *radial derivatives* `D₀ = φ`, `D_{k+1} = (1/r) dD_k/dr`:
//!
//! ```text
//!     ∇φ      = D₁ d
//!     ∇²φ     = D₂ d dᵀ + D₁ I
//!     ∂³φ_abc = D₃ d_a d_b d_c + D₂ (δ_ab d_c + δ_ac d_b + δ_bc d_a)
//! ```
//!
//! so a kernel is just `r ↦ [D₀, D₁, D₂, D₃]` for `r > 0`, plus its Hessian at `r = 0`, which
//! the Hermite (gradient) constraints need. At `r = 0` the value is `φ(0)`, the gradient is 0,
//! and terms whose `D_k` blows up are multiplied by powers of `d` that vanish faster — except
//! where the kernel is not smooth enough, which [`Kernel::hessian_at_zero`] reports.
//!
//! | kernel | φ(r) | D₁ | D₂ | D₃ | definite | smooth at 0 |
//! |---|---|---|---|---|---|---|
//! | [`Biharmonic`] | r | 1/r | −1/r³ | 3/r⁵ | −φ, order 1 | C⁰ |
//! | [`Triharmonic`] | r³ | 3r | 3/r | −3/r³ | +φ, order 2 | C² |
//! | [`ThinPlate`] | r² ln r | 2 ln r + 1 | 2/r² | −4/r⁴ | +φ, order 2 | C¹ |
//! | [`Wendland`] | (1−s)⁴₊(4s+1), s = r/ρ | −20(1−s)³/ρ² | 60(1−s)²/(ρ³r) | −60(1−s)(1+s)/(ρ³r³) | +φ, order 0 | C² |
//!
//! "Order m, sign σ" means σ·φ is conditionally positive definite of order m: the quadratic
//! form `Σ cᵢcⱼ σφ(|xᵢ − xⱼ|)` is positive for every `c ≠ 0` annihilating the polynomials of
//! degree `< m`. All four need at most the linear polynomial zeroset adds, and the fit uses σ to
//! factor the projected system by Cholesky.
//!
//! ## Adding a kernel
//! Implement [`Kernel`]: the radial derivatives for `r > 0`, the definiteness, and the Hessian
//! at 0 (or `None`). Then `RbfFit::new(MyKernel)` fits with it. Optionally give
//! [`Kernel::slope_bound`] and [`Kernel::curvature_bound`], which let multipole fields of the
//! kernel enclose their values over boxes (the block step of the signed marching cubes). [`Wendland`] is the worked
//! example of a compactly supported kernel.

use std::fmt::Debug;

/// A radial kernel; see the [module docs](self) for the radial derivatives.
pub trait Kernel: Send + Sync + Debug {
    /// A short name for reports (`"r"`, `"r3"`, …).
    fn name(&self) -> &str;

    /// `φ(0)`.
    fn value_at_zero(&self) -> f64;

    /// The radial derivatives `[D₀, D₁, D₂, D₃]` at `r > 0`.
    fn radial(&self, r: f64) -> [f64; 4];

    /// `h` with `∇²φ(0) = h I`, or `None` if `φ(|d|)` is not twice differentiable at 0 (then
    /// Hermite constraints cannot use the kernel).
    fn hessian_at_zero(&self) -> Option<f64>;

    /// `σ = ±1` such that `σ φ` is conditionally positive definite of [`Kernel::order`].
    fn sign(&self) -> f64;

    /// The order `m` of conditional positive definiteness (`≤ 2`: the linear polynomial
    /// suffices).
    fn order(&self) -> usize;

    /// `Some(k)` if `φ(λr) = λᵏ φ(r)` for every `λ > 0` (`r`: 1, `r³`: 3). The fast multipole
    /// method then computes its M2L operators once, for cells of unit width, and scales them
    /// per level; other kernels get operators per level. Default `None`.
    fn homogeneity(&self) -> Option<i32> {
        None
    }

    /// `φ(√r2)`, the hot path of evaluation: override it with a branch-free form where there
    /// is one (it is inlined into vectorised loops over the centres).
    #[inline]
    fn value_of_squared(&self, r2: f64) -> f64 {
        if r2 == 0.0 {
            self.value_at_zero()
        } else {
            self.radial(r2.sqrt())[0]
        }
    }

    /// `D₁(√r2) = φ′(r)/r`, so that `∇φ(|d|) = D₁ d`, and 0 at `r2 = 0` (where the gradient
    /// is taken as 0): the hot path of gradients. Override it with a branch-free form where
    /// there is one (it is inlined into vectorised loops over the centres).
    #[inline]
    fn slope_factor_of_squared(&self, r2: f64) -> f64 {
        if r2 > 0.0 {
            self.radial(r2.sqrt())[1]
        } else {
            0.0
        }
    }

    /// An upper bound of `|φ′(r)|` over `0 ≤ r ≤ r_max`: how fast one centre's term can change
    /// (its Lipschitz constant on the ball of radius `r_max`). Together with
    /// [`Kernel::curvature_bound`] it lets a field enclose its values over a box
    /// (`ScalarField::value_range`), which the signed marching cubes use to settle whole blocks
    /// of grid vertices. Default `None`: the kernel cannot bound itself, and fields built on it
    /// give no enclosures (everything still works, vertex by vertex).
    fn slope_bound(&self, r_max: f64) -> Option<f64> {
        let _ = r_max;
        None
    }

    /// An upper bound of the spectral norm of the Hessian of `φ(|d|)` over
    /// `r_min ≤ |d| ≤ r_max`, i.e. of `max(|φ″(r)|, |φ′(r)/r|)` there (the radial and the
    /// tangential curvature, `D₂r² + D₁` and `D₁`); `+∞` where it is unbounded. Default `None`
    /// (see [`Kernel::slope_bound`]).
    fn curvature_bound(&self, r_min: f64, r_max: f64) -> Option<f64> {
        let _ = (r_min, r_max);
        None
    }
}

/// `φ(r) = r`, the biharmonic spline in 3-D (Carr et al.): `−φ` is conditionally positive
/// definite of order 1. Not differentiable at 0, so not for Hermite constraints.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Biharmonic;

impl Kernel for Biharmonic {
    fn name(&self) -> &str {
        "r"
    }
    #[inline]
    fn value_of_squared(&self, r2: f64) -> f64 {
        r2.sqrt()
    }
    #[inline]
    fn slope_factor_of_squared(&self, r2: f64) -> f64 {
        if r2 > 0.0 { 1.0 / r2.sqrt() } else { 0.0 }
    }
    fn value_at_zero(&self) -> f64 {
        0.0
    }
    fn radial(&self, r: f64) -> [f64; 4] {
        let inv = 1.0 / r;
        let inv2 = inv * inv;
        [r, inv, -inv * inv2, 3.0 * inv * inv2 * inv2]
    }
    fn hessian_at_zero(&self) -> Option<f64> {
        None
    }
    fn sign(&self) -> f64 {
        -1.0
    }
    fn order(&self) -> usize {
        1
    }
    fn homogeneity(&self) -> Option<i32> {
        Some(1)
    }
    fn slope_bound(&self, _r_max: f64) -> Option<f64> {
        Some(1.0)
    }
    fn curvature_bound(&self, r_min: f64, _r_max: f64) -> Option<f64> {
        // φ″ = 0, φ′/r = 1/r.
        Some(if r_min > 0.0 {
            1.0 / r_min
        } else {
            f64::INFINITY
        })
    }
}

/// `φ(r) = r³`, the triharmonic spline in 3-D: conditionally positive definite of order 2 and
/// C² at 0, so it also takes Hermite (gradient) constraints.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Triharmonic;

impl Kernel for Triharmonic {
    fn name(&self) -> &str {
        "r3"
    }
    #[inline]
    fn value_of_squared(&self, r2: f64) -> f64 {
        r2 * r2.sqrt()
    }
    #[inline]
    fn slope_factor_of_squared(&self, r2: f64) -> f64 {
        3.0 * r2.sqrt()
    }
    fn value_at_zero(&self) -> f64 {
        0.0
    }
    fn radial(&self, r: f64) -> [f64; 4] {
        [r * r * r, 3.0 * r, 3.0 / r, -3.0 / (r * r * r)]
    }
    fn hessian_at_zero(&self) -> Option<f64> {
        Some(0.0)
    }
    fn sign(&self) -> f64 {
        1.0
    }
    fn order(&self) -> usize {
        2
    }
    fn homogeneity(&self) -> Option<i32> {
        Some(3)
    }
    fn slope_bound(&self, r_max: f64) -> Option<f64> {
        Some(3.0 * r_max * r_max)
    }
    fn curvature_bound(&self, _r_min: f64, r_max: f64) -> Option<f64> {
        // φ″ = 6r, φ′/r = 3r.
        Some(6.0 * r_max)
    }
}

/// `φ(r) = r² ln r` (`φ(0) = 0`), the thin-plate spline of 2-D (Jiang–Turk): conditionally
/// positive definite of order 2; its Hessian has a logarithmic singularity at 0.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ThinPlate;

impl Kernel for ThinPlate {
    fn name(&self) -> &str {
        "tps"
    }
    #[inline]
    fn value_of_squared(&self, r2: f64) -> f64 {
        // r² ln r = ½ r² ln r²; the clamp makes r = 0 give 0 · (finite) = 0.
        0.5 * r2 * r2.max(f64::MIN_POSITIVE).ln()
    }
    #[inline]
    fn slope_factor_of_squared(&self, r2: f64) -> f64 {
        // 2 ln r + 1 = ln r² + 1.
        if r2 > 0.0 { r2.ln() + 1.0 } else { 0.0 }
    }
    fn value_at_zero(&self) -> f64 {
        0.0
    }
    fn radial(&self, r: f64) -> [f64; 4] {
        let inv2 = 1.0 / (r * r);
        [
            r * r * r.ln(),
            2.0 * r.ln() + 1.0,
            2.0 * inv2,
            -4.0 * inv2 * inv2,
        ]
    }
    fn hessian_at_zero(&self) -> Option<f64> {
        None
    }
    fn sign(&self) -> f64 {
        1.0
    }
    fn order(&self) -> usize {
        2
    }
    fn slope_bound(&self, r_max: f64) -> Option<f64> {
        // φ′ = r (2 ln r + 1): 0 at 0, least (−2e^{−3/2}) at r = e^{−3/2}, increasing beyond.
        let at_max = if r_max > 0.0 {
            (r_max * (2.0 * r_max.ln() + 1.0)).abs()
        } else {
            0.0
        };
        Some(at_max.max(2.0 * (-1.5f64).exp()))
    }
    fn curvature_bound(&self, r_min: f64, r_max: f64) -> Option<f64> {
        // φ″ = 2 ln r + 3 and φ′/r = 2 ln r + 1 are monotone: their extremes are at the ends.
        if r_min <= 0.0 {
            return Some(f64::INFINITY);
        }
        let ends = [r_min.ln(), r_max.ln()];
        Some(
            ends.iter()
                .flat_map(|&l| [(2.0 * l + 3.0).abs(), (2.0 * l + 1.0).abs()])
                .fold(0.0, f64::max),
        )
    }
}

/// Wendland's compactly supported `ψ₃,₁(r) = (1 − r/ρ)⁴₊ (4r/ρ + 1)`: positive definite in up
/// to 3 dimensions and C², zero beyond the support radius `ρ`. The fit stays dense (the
/// solvers here do not exploit the sparsity), so it is the example of a user kernel rather
/// than a fast path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wendland {
    radius: f64,
}

impl Wendland {
    /// The kernel with support radius `radius`, or `None` unless `radius` is finite and `> 0`.
    pub fn new(radius: f64) -> Option<Self> {
        (radius.is_finite() && radius > 0.0).then_some(Self { radius })
    }

    /// The default support radius as a fraction of the diagonal of the data's box: too small
    /// a support leaves gaps between the constraints where the field falls back to its linear
    /// polynomial and the zero set breaks up (on `samples/curve.xyv` 1/16 and 1/8 of the
    /// diagonal give 8 and 11 loops, 1/4 and more the one true loop); half the diagonal keeps
    /// a factor of two from that edge.
    pub const DEFAULT_RADIUS_FRACTION: f64 = 0.5;

    /// The kernel with the default support radius for data whose box has diagonal
    /// `diagonal` ([`Wendland::DEFAULT_RADIUS_FRACTION`] of it), or `None` for a box that is a
    /// point.
    pub fn for_diagonal(diagonal: f64) -> Option<Self> {
        Self::new(Self::DEFAULT_RADIUS_FRACTION * diagonal)
    }

    /// The support radius `ρ`.
    pub fn radius(&self) -> f64 {
        self.radius
    }
}

impl Kernel for Wendland {
    fn name(&self) -> &str {
        "wendland"
    }
    fn value_at_zero(&self) -> f64 {
        1.0
    }
    fn radial(&self, r: f64) -> [f64; 4] {
        let rho = self.radius;
        let s = r / rho;
        if s >= 1.0 {
            return [0.0; 4];
        }
        let t = 1.0 - s;
        let rho3 = rho * rho * rho;
        [
            t.powi(4) * (4.0 * s + 1.0),
            -20.0 * t.powi(3) / (rho * rho),
            60.0 * t * t / (rho3 * r),
            -60.0 * t * (1.0 + s) / (rho3 * r * r * r),
        ]
    }
    fn hessian_at_zero(&self) -> Option<f64> {
        Some(-20.0 / (self.radius * self.radius))
    }
    fn sign(&self) -> f64 {
        1.0
    }
    fn order(&self) -> usize {
        0
    }
    fn slope_bound(&self, _r_max: f64) -> Option<f64> {
        // |φ′| = 20 s (1 − s)³ / ρ, largest at s = 1/4: 20 · 27/256 / ρ.
        Some(20.0 * 27.0 / 256.0 / self.radius)
    }
    fn curvature_bound(&self, _r_min: f64, _r_max: f64) -> Option<f64> {
        // φ″ = 20 (1 − s)² (4s − 1) / ρ² and φ′/r = −20 (1 − s)³ / ρ², both at most 20/ρ².
        Some(20.0 / (self.radius * self.radius))
    }
}

/// `φ(|d|)`.
pub(crate) fn value<K: Kernel + ?Sized, const D: usize>(kernel: &K, d: &[f64; D]) -> f64 {
    let r = norm(d);
    if r == 0.0 {
        kernel.value_at_zero()
    } else {
        kernel.radial(r)[0]
    }
}

/// `∇φ(|d|)` (0 at `d = 0`).
pub(crate) fn gradient<K: Kernel + ?Sized, const D: usize>(kernel: &K, d: &[f64; D]) -> [f64; D] {
    let r = norm(d);
    if r == 0.0 {
        return [0.0; D];
    }
    let d1 = kernel.radial(r)[1];
    d.map(|v| d1 * v)
}

/// `∇²φ(|d|)`; at `d = 0` the kernel's [`Kernel::hessian_at_zero`] (NaN where undefined).
pub(crate) fn hessian<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    d: &[f64; D],
) -> [[f64; D]; D] {
    let r = norm(d);
    let mut h = [[0.0; D]; D];
    if r == 0.0 {
        let h0 = kernel.hessian_at_zero().unwrap_or(f64::NAN);
        for (a, row) in h.iter_mut().enumerate() {
            row[a] = h0;
        }
        return h;
    }
    let [_, d1, d2, _] = kernel.radial(r);
    for a in 0..D {
        for b in 0..D {
            h[a][b] = d2 * d[a] * d[b] + if a == b { d1 } else { 0.0 };
        }
    }
    h
}

/// `∂³φ(|d|)/∂d_a∂d_b∂d_c` contracted with nothing: the full tensor (0 at `d = 0`, where it
/// is undefined for every kernel here but [`Wendland`], whose value there is 0 too).
pub(crate) fn third<K: Kernel + ?Sized, const D: usize>(
    kernel: &K,
    d: &[f64; D],
) -> [[[f64; D]; D]; D] {
    let r = norm(d);
    let mut t = [[[0.0; D]; D]; D];
    if r == 0.0 {
        return t;
    }
    let [_, _, d2, d3] = kernel.radial(r);
    for a in 0..D {
        for b in 0..D {
            for c in 0..D {
                let delta = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 };
                t[a][b][c] = d3 * d[a] * d[b] * d[c]
                    + d2 * (delta(a, b) * d[c] + delta(a, c) * d[b] + delta(b, c) * d[a]);
            }
        }
    }
    t
}

pub(crate) fn norm<const D: usize>(d: &[f64; D]) -> f64 {
    d.iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `D_{k+1} = (1/r) dD_k/dr`, checked by central differences for every kernel.
    fn check_radial<K: Kernel>(kernel: &K, rs: &[f64]) {
        for &r in rs {
            let h = 1e-5 * r;
            let [lo, hi] = [kernel.radial(r - h), kernel.radial(r + h)];
            let at = kernel.radial(r);
            for k in 0..3 {
                let fd = (hi[k] - lo[k]) / (2.0 * h) / r;
                let tol = 1e-6 * at[k + 1].abs().max(1.0);
                assert!(
                    (fd - at[k + 1]).abs() < tol,
                    "{} r={r} D{}: {fd} vs {}",
                    kernel.name(),
                    k + 1,
                    at[k + 1]
                );
            }
        }
    }

    /// The slope and curvature bounds hold on a fine sampling of their ranges, for every kernel.
    fn check_bounds<K: Kernel>(kernel: &K, intervals: &[(f64, f64)]) {
        for &(lo, hi) in intervals {
            let slope = kernel.slope_bound(hi).unwrap();
            let curvature = kernel.curvature_bound(lo, hi).unwrap();
            for k in 0..=2000 {
                let r = lo + (hi - lo) * k as f64 / 2000.0;
                let [_, d1, d2, _] = kernel.radial(r);
                let tol = 1e-12 * (1.0 + slope + curvature);
                assert!(
                    (d1 * r).abs() <= slope + tol,
                    "{} slope at {r}",
                    kernel.name()
                );
                let radial = d2 * r * r + d1;
                assert!(
                    radial.abs().max(d1.abs()) <= curvature + tol,
                    "{} curvature at {r} in [{lo}, {hi}]",
                    kernel.name()
                );
            }
            // The slope bound covers [0, hi], not only [lo, hi].
            for k in 1..=2000 {
                let r = hi * k as f64 / 2000.0;
                let d1 = kernel.radial(r)[1];
                assert!(
                    (d1 * r).abs() <= slope * (1.0 + 1e-12),
                    "{} slope at {r}",
                    kernel.name()
                );
            }
        }
    }

    #[test]
    fn slope_and_curvature_bounds_hold() {
        let intervals = [(0.05, 0.3), (0.2, 0.25), (0.7, 2.5), (1e-3, 5.0)];
        check_bounds(&Biharmonic, &intervals);
        check_bounds(&Triharmonic, &intervals);
        check_bounds(&ThinPlate, &intervals);
        check_bounds(&Wendland::new(2.0).unwrap(), &intervals);
        assert_eq!(Biharmonic.curvature_bound(0.0, 1.0), Some(f64::INFINITY));
        assert_eq!(ThinPlate.curvature_bound(0.0, 1.0), Some(f64::INFINITY));
    }

    /// The fast forms of the value and the slope factor agree with the radial derivatives,
    /// and are 0 (not NaN) at `r = 0`, for every kernel.
    fn check_squared_forms<K: Kernel>(kernel: &K) {
        for r in [1e-6, 0.1, 0.37, 0.8, 1.3, 1.99, 3.0] {
            let [d0, d1, _, _] = kernel.radial(r);
            let (v, s) = (
                kernel.value_of_squared(r * r),
                kernel.slope_factor_of_squared(r * r),
            );
            assert!(
                (v - d0).abs() <= 1e-13 * d0.abs().max(1.0),
                "{}",
                kernel.name()
            );
            assert!(
                (s - d1).abs() <= 1e-12 * d1.abs().max(1.0),
                "{} {r}: {s} vs {d1}",
                kernel.name()
            );
        }
        assert_eq!(
            kernel.slope_factor_of_squared(0.0),
            0.0,
            "{}",
            kernel.name()
        );
        assert_eq!(
            kernel.value_of_squared(0.0),
            kernel.value_at_zero(),
            "{}",
            kernel.name()
        );
    }

    #[test]
    fn squared_forms_match_the_radial_derivatives() {
        check_squared_forms(&Biharmonic);
        check_squared_forms(&Triharmonic);
        check_squared_forms(&ThinPlate);
        check_squared_forms(&Wendland::new(2.0).unwrap());
    }

    #[test]
    fn radial_derivatives_match_finite_differences() {
        let rs = [0.1, 0.37, 0.8, 1.3];
        check_radial(&Biharmonic, &rs);
        check_radial(&Triharmonic, &rs);
        check_radial(&ThinPlate, &rs);
        check_radial(&Wendland::new(2.0).unwrap(), &rs);
        assert_eq!(Wendland::new(0.5).unwrap().radial(0.6), [0.0; 4]);
        assert!(Wendland::new(0.0).is_none() && Wendland::new(f64::NAN).is_none());
    }

    #[test]
    fn gradient_hessian_and_third_derivative_match_finite_differences() {
        let d = [0.3, -0.2, 0.45];
        let h = 1e-5;
        for kernel in [
            &Triharmonic as &dyn Kernel,
            &Biharmonic,
            &Wendland::new(1.5).unwrap(),
        ] {
            let g = gradient(kernel, &d);
            let hs = hessian(kernel, &d);
            let t = third(kernel, &d);
            for a in 0..3 {
                let (mut p, mut m) = (d, d);
                p[a] += h;
                m[a] -= h;
                let fd = (value(kernel, &p) - value(kernel, &m)) / (2.0 * h);
                assert!((fd - g[a]).abs() < 1e-8, "{}", kernel.name());
                let (gp, gm) = (gradient(kernel, &p), gradient(kernel, &m));
                let (hp, hm) = (hessian(kernel, &p), hessian(kernel, &m));
                for b in 0..3 {
                    let fd = (gp[b] - gm[b]) / (2.0 * h);
                    assert!((fd - hs[a][b]).abs() < 1e-7, "{}", kernel.name());
                    for c in 0..3 {
                        let fd = (hp[b][c] - hm[b][c]) / (2.0 * h);
                        assert!((fd - t[a][b][c]).abs() < 1e-6, "{}", kernel.name());
                    }
                }
            }
        }
    }

    #[test]
    fn values_at_zero_are_the_limits() {
        let z = [0.0; 3];
        assert_eq!(value(&Triharmonic, &z), 0.0);
        assert_eq!(value(&Wendland::new(1.0).unwrap(), &z), 1.0);
        assert_eq!(hessian(&Triharmonic, &z), [[0.0; 3]; 3]);
        assert!(hessian(&Biharmonic, &z)[0][0].is_nan());
        let tiny = [1e-7, 0.0, 0.0];
        let w = Wendland::new(1.0).unwrap();
        assert!((hessian(&w, &tiny)[1][1] - w.hessian_at_zero().unwrap()).abs() < 1e-5);
    }
}
