//! Scalar fields `f: Rᴰ → R`, the common currency of zeroset.
//!
//! Every representation (analytic shape, RBF, B-spline, MRAS, neural net) implements
//! [`ScalarField`], so restoration and meshing accept any of them. The zero set
//! `{x : f(x) = 0}` is the surface (`D` = 3) or curve (`D` = 2); see the crate docs for the sign
//! convention (negative inside, outward normal `+∇f/‖∇f‖`).
//!
//! The gradient has a default by central differences,
//!
//! ```text
//! ∂f/∂xᵢ(x) ≈ (f(x + h eᵢ) − f(x − h eᵢ)) / 2h,   h = ε^{1/3} · max(1, ‖x‖∞),
//! ```
//!
//! with truncation error `O(h²)` and rounding error `O(ε/h)`; the step balances the two (about
//! `1e-10` relative accuracy for smooth fields). Representations with an analytic gradient
//! override it.
//!
//! ```
//! use zeroset_field_core::analytic::Sphere;
//! use zeroset_field_core::field::ScalarField;
//!
//! let s = Sphere::new([0.0, 0.0, 0.0], 0.5);
//! let points = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
//! let mut out = vec![0.0; 2];
//! s.values(&points, &mut out); // parallel, deterministic
//! assert_eq!(out, vec![-0.5, 0.5]);
//! ```

use rayon::prelude::*;

use crate::geometry::{Aabb, Point, norm};

/// Points per rayon task in [`ScalarField::values`]: large enough to amortise scheduling,
/// small enough to balance two to sixty-four cores.
pub const VALUES_CHUNK: usize = 1024;

/// A scalar field `f: Rᴰ → R`.
///
/// Implementations must be pure (the same point gives the same value) and thread-safe, since the
/// batched evaluation runs in parallel.
pub trait ScalarField<const D: usize>: Send + Sync {
    /// `f(p)`.
    fn value(&self, p: &Point<D>) -> f64;

    /// `∇f(p)`. The default uses central differences (`2D` evaluations); override it where the
    /// gradient is known in closed form.
    fn gradient(&self, p: &Point<D>) -> Point<D> {
        central_difference_gradient(self, p)
    }

    /// Evaluates `f` at every point: `out[i] = f(points[i])`, in parallel chunks. The result does
    /// not depend on the number of threads. This is the hot path of meshing and grid sampling;
    /// representations that can share work between points (FMM, batched nets) override it.
    ///
    /// # Panics
    /// If `points.len() != out.len()`.
    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        assert_eq!(
            points.len(),
            out.len(),
            "ScalarField::values: {} points but {} output slots",
            points.len(),
            out.len()
        );
        points
            .par_chunks(VALUES_CHUNK)
            .zip(out.par_chunks_mut(VALUES_CHUNK))
            .for_each(|(ps, os)| {
                for (p, o) in ps.iter().zip(os) {
                    *o = self.value(p);
                }
            });
    }

    /// The box where the field is meaningful (where it was fitted, or where the shape lies).
    /// Meshing samples this box unless told otherwise. `None` for fields defined everywhere with
    /// no natural extent.
    fn bounds(&self) -> Option<Aabb<D>>;

    /// An **enclosure** of the field over the closed box `region`: `[lo, hi]` with
    /// `lo ≤ value(x) ≤ hi` for every `x` in it (the values as computed, rounding included), or
    /// `None` where the field cannot bound itself there. The default is `None`.
    ///
    /// A field that can enclose itself cheaply lets consumers settle whole regions at once:
    /// the signed marching cubes skip every block of grid vertices whose enclosure stays clear
    /// of the level. An enclosure need not be tight, only true and cheaper than evaluating the
    /// points it covers; a 1-Lipschitz field (a signed distance) encloses itself by
    /// `value(centre) ± half-diagonal` ([`lipschitz_range`]).
    fn value_range(&self, region: &Aabb<D>) -> Option<[f64; 2]> {
        let _ = region;
        None
    }
}

/// The enclosure `value(centre) ± lipschitz · half-diagonal` of a field with Lipschitz constant
/// `lipschitz` over `region` (widened by a few units of rounding of the centre's value), as
/// [`ScalarField::value_range`] returns it; `None` if the centre's value is not finite.
///
/// ```
/// use zeroset_field_core::analytic::Sphere;
/// use zeroset_field_core::field::ScalarField;
/// use zeroset_field_core::Aabb;
///
/// let s = Sphere::new([0.0; 3], 1.0);
/// let [lo, hi] = s.value_range(&Aabb::new([2.0; 3], [2.5; 3])?).unwrap();
/// assert!(lo > 0.0 && lo <= s.value(&[2.0; 3]) && s.value(&[2.5; 3]) <= hi);
/// # Ok::<(), zeroset_field_core::Error>(())
/// ```
pub fn lipschitz_range<const D: usize, F: ScalarField<D> + ?Sized>(
    field: &F,
    region: &Aabb<D>,
    lipschitz: f64,
) -> Option<[f64; 2]> {
    let centre = region.center();
    let half_diagonal = 0.5 * norm(&region.extent());
    let v = field.value(&centre);
    // Each value is a handful of roundings away from the exact one, in the value and in the
    // coordinates it is computed from (times the slope).
    let size = centre.iter().fold(half_diagonal, |m, c| m.max(c.abs()));
    let slack = 16.0 * f64::EPSILON * (v.abs() + lipschitz * (half_diagonal + size) + 1.0);
    let spread = lipschitz * half_diagonal + slack;
    v.is_finite().then_some([v - spread, v + spread])
}

/// The distance from `p` to the zero set of `field`, found by projecting along the gradient:
/// `q ← q − f(q) ∇f(q)/|∇f(q)|²` from `q = p` until `|f(q)| ≤ tol` (at most `max_steps`
/// steps); returns `|p − q|` for the point `q` reached, which lies on the zero set, so the
/// figure is an **upper bound** of the true distance (equal to it where the projection runs
/// straight, as it does near a smooth surface). `None` where it does not converge or the
/// gradient vanishes.
///
/// ```
/// use zeroset_field_core::analytic::Sphere;
/// use zeroset_field_core::field::distance_to_zero_set;
///
/// let s = Sphere::new([0.0; 3], 1.0);
/// let d = distance_to_zero_set(&s, &[0.0, 0.0, 1.25], 1e-12, 20).unwrap();
/// assert!((d - 0.25).abs() < 1e-12);
/// ```
pub fn distance_to_zero_set<const D: usize, F: ScalarField<D> + ?Sized>(
    field: &F,
    p: &Point<D>,
    tol: f64,
    max_steps: usize,
) -> Option<f64> {
    let q = project_to_zero_set(field, p, tol, max_steps)?;
    let d2: f64 = (0..D).map(|a| (q[a] - p[a]).powi(2)).sum();
    Some(d2.sqrt())
}

/// The point [`distance_to_zero_set`] reaches from `p`: the steps
/// `q ← q − f(q) ∇f(q)/|∇f(q)|²` from `q = p` until `|f(q)| ≤ tol` (at most `max_steps`);
/// `None` where they do not get there, a value is not finite or the gradient vanishes.
///
/// ```
/// use zeroset_field_core::analytic::Sphere;
/// use zeroset_field_core::field::project_to_zero_set;
///
/// let s = Sphere::new([0.0; 3], 1.0);
/// let q = project_to_zero_set(&s, &[0.0, 0.0, 1.25], 1e-12, 20).unwrap();
/// assert!((q[2] - 1.0).abs() < 1e-12);
/// ```
pub fn project_to_zero_set<const D: usize, F: ScalarField<D> + ?Sized>(
    field: &F,
    p: &Point<D>,
    tol: f64,
    max_steps: usize,
) -> Option<Point<D>> {
    let mut q = *p;
    for _ in 0..=max_steps {
        let v = field.value(&q);
        if !v.is_finite() {
            return None;
        }
        if v.abs() <= tol {
            return Some(q);
        }
        let g = field.gradient(&q);
        let g2: f64 = g.iter().map(|x| x * x).sum();
        if !(g2 > 0.0 && g2.is_finite()) {
            return None;
        }
        for a in 0..D {
            q[a] -= v * g[a] / g2;
        }
    }
    None
}

/// A 2-D field (curves).
pub trait ScalarField2: ScalarField<2> {}
impl<T: ScalarField<2> + ?Sized> ScalarField2 for T {}
/// A 3-D field (surfaces).
pub trait ScalarField3: ScalarField<3> {}
impl<T: ScalarField<3> + ?Sized> ScalarField3 for T {}

/// The central-difference gradient that [`ScalarField::gradient`] uses by default; public so
/// that tests can compare an analytic gradient against it.
pub fn central_difference_gradient<const D: usize, F: ScalarField<D> + ?Sized>(
    field: &F,
    p: &Point<D>,
) -> Point<D> {
    let scale = p.iter().fold(1.0_f64, |m, x| m.max(x.abs()));
    let h = f64::EPSILON.cbrt() * scale;
    std::array::from_fn(|i| {
        let mut a = *p;
        let mut b = *p;
        a[i] += h;
        b[i] -= h;
        // (a[i] - b[i]) is the step actually taken after rounding.
        (field.value(&a) - field.value(&b)) / (a[i] - b[i])
    })
}

/// Forwards every method through a pointer type, so that `&F`, `Box<F>` and `Arc<F>` are
/// fields whenever `F` is (including `dyn ScalarField<D>`).
macro_rules! forward_scalar_field {
    ($($pointer:ty),*) => {$(
        impl<const D: usize, F: ScalarField<D> + ?Sized> ScalarField<D> for $pointer {
            fn value(&self, p: &Point<D>) -> f64 {
                (**self).value(p)
            }
            fn gradient(&self, p: &Point<D>) -> Point<D> {
                (**self).gradient(p)
            }
            fn values(&self, points: &[Point<D>], out: &mut [f64]) {
                (**self).values(points, out)
            }
            fn bounds(&self) -> Option<Aabb<D>> {
                (**self).bounds()
            }
            fn value_range(&self, region: &Aabb<D>) -> Option<[f64; 2]> {
                (**self).value_range(region)
            }
        }
    )*};
}

forward_scalar_field!(&F, Box<F>, std::sync::Arc<F>);

/// `−f`: flips inside and outside. This is where a paper's positive-inside convention meets
/// zeroset's negative-inside one.
#[derive(Debug, Clone, Copy)]
pub struct Negated<F>(pub F);

impl<const D: usize, F: ScalarField<D>> ScalarField<D> for Negated<F> {
    fn value(&self, p: &Point<D>) -> f64 {
        -self.0.value(p)
    }
    fn gradient(&self, p: &Point<D>) -> Point<D> {
        self.0.gradient(p).map(|g| -g)
    }
    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        self.0.values(points, out);
        out.iter_mut().for_each(|v| *v = -*v);
    }
    fn bounds(&self) -> Option<Aabb<D>> {
        self.0.bounds()
    }
    fn value_range(&self, region: &Aabb<D>) -> Option<[f64; 2]> {
        self.0.value_range(region).map(|[lo, hi]| [-hi, -lo])
    }
}

/// A field given by a closure, with central-difference gradients. Handy in tests and examples.
pub struct FnField<const D: usize, F> {
    f: F,
    bounds: Option<Aabb<D>>,
}

impl<const D: usize, F: Fn(&Point<D>) -> f64 + Send + Sync> FnField<D, F> {
    /// Wraps `f`, meaningful on `bounds`.
    pub fn new(f: F, bounds: Option<Aabb<D>>) -> Self {
        Self { f, bounds }
    }
}

impl<const D: usize, F: Fn(&Point<D>) -> f64 + Send + Sync> ScalarField<D> for FnField<D, F> {
    fn value(&self, p: &Point<D>) -> f64 {
        (self.f)(p)
    }
    fn bounds(&self) -> Option<Aabb<D>> {
        self.bounds
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quadratic() -> FnField<3, impl Fn(&Point<3>) -> f64 + Send + Sync> {
        FnField::new(|p: &Point<3>| p[0] * p[0] + 2.0 * p[1] * p[2] - p[2], None)
    }

    #[test]
    fn central_differences_match_a_quadratic() {
        let f = quadratic();
        let p = [0.3, -1.2, 2.5];
        let g = f.gradient(&p);
        let exact = [2.0 * p[0], 2.0 * p[2], 2.0 * p[1] - 1.0];
        for i in 0..3 {
            assert!((g[i] - exact[i]).abs() < 1e-8, "{g:?} vs {exact:?}");
        }
    }

    #[test]
    fn batched_values_match_single_values_and_negation_flips_them() {
        let f = quadratic();
        let pts: Vec<Point<3>> = (0..3000)
            .map(|i| {
                let t = i as f64 * 0.001;
                [t.sin(), t.cos(), t]
            })
            .collect();
        let mut out = vec![0.0; pts.len()];
        f.values(&pts, &mut out);
        let mut neg = vec![0.0; pts.len()];
        Negated(&f).values(&pts, &mut neg);
        for ((p, v), n) in pts.iter().zip(&out).zip(&neg) {
            assert_eq!(*v, f.value(p));
            assert_eq!(*n, -v);
        }
    }

    #[test]
    #[should_panic(expected = "2 points but 1 output slots")]
    fn batched_values_reject_mismatched_lengths() {
        let f = quadratic();
        f.values(&[[0.0; 3], [1.0; 3]], &mut [0.0]);
    }
}
