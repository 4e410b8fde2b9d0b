//! Analytic shapes with exact signed distance functions and gradients: the truth that fitting,
//! restoration and meshing are tested against.
//!
//! | shape | field | zero set |
//! |---|---|---|
//! | [`Ball<D>`] ([`Sphere`], [`Circle`]) | `‖x − c‖ − r` | sphere / circle |
//! | [`Torus`] | `‖(‖(x−c)_{xy}‖ − R, (x−c)_z)‖ − r` | torus about the z axis (genus 1) |
//! | [`Annulus`] | `|‖x − c‖ − R| − r` | ring between radii `R − r` and `R + r` |
//! | [`BoxSdf<D>`] ([`Cuboid`], [`Rectangle`]) | exact box SDF | box boundary |
//!
//! All are negative inside and have `‖∇f‖ = 1` wherever the gradient exists. Where it does not
//! (the centre of a ball, the axis circle of a torus, the medial axis of a box) a unit vector is
//! returned so that normals stay finite. Being 1-Lipschitz, each encloses itself over a box by
//! `value(centre) ± half-diagonal` ([`ScalarField::value_range`]). Bounds are the shape's box grown by 10 % of its largest
//! extent, so a grid over them brackets the zero set.
//!
//! ```
//! use zeroset_field_core::analytic::Torus;
//! use zeroset_field_core::field::ScalarField;
//!
//! let t = Torus::new([0.0; 3], 1.0, 0.25);
//! assert_eq!(t.value(&[1.0, 0.0, 0.0]), -0.25); // on the core circle
//! assert_eq!(t.gradient(&[1.5, 0.0, 0.0]), [1.0, 0.0, 0.0]);
//! ```

use crate::field::{ScalarField, lipschitz_range};
use crate::geometry::{Aabb, Point, norm, sub};

fn padded<const D: usize>(min: Point<D>, max: Point<D>) -> Option<Aabb<D>> {
    let b = Aabb::new(min, max).ok()?;
    let pad = 0.1 * b.extent().iter().fold(0.0_f64, |m, &e| m.max(e));
    Some(b.expanded(pad))
}

fn unit_or_axis<const D: usize>(v: Point<D>) -> Point<D> {
    let n = norm(&v);
    if n > 0.0 {
        v.map(|x| x / n)
    } else {
        std::array::from_fn(|i| if i == 0 { 1.0 } else { 0.0 })
    }
}

/// A ball of radius `r` about `c`: `f(x) = ‖x − c‖ − r`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ball<const D: usize> {
    /// The centre.
    pub center: Point<D>,
    /// The radius.
    pub radius: f64,
}

/// A sphere in space.
pub type Sphere = Ball<3>;
/// A circle in the plane.
pub type Circle = Ball<2>;

impl<const D: usize> Ball<D> {
    /// A ball of radius `radius` about `center`.
    pub fn new(center: Point<D>, radius: f64) -> Self {
        Self { center, radius }
    }
}

impl<const D: usize> ScalarField<D> for Ball<D> {
    fn value(&self, p: &Point<D>) -> f64 {
        norm(&sub(p, &self.center)) - self.radius
    }
    fn gradient(&self, p: &Point<D>) -> Point<D> {
        unit_or_axis(sub(p, &self.center))
    }
    fn bounds(&self) -> Option<Aabb<D>> {
        padded(
            self.center.map(|c| c - self.radius),
            self.center.map(|c| c + self.radius),
        )
    }
    fn value_range(&self, region: &Aabb<D>) -> Option<[f64; 2]> {
        // A signed distance is 1-Lipschitz.
        lipschitz_range(self, region, 1.0)
    }
}

/// A torus about the z axis through `center`: tube radius `minor` around a circle of radius
/// `major` in the plane `z = center.z`. Genus 1, Euler characteristic 0 — the test shape for
/// topology.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Torus {
    /// The centre.
    pub center: Point<3>,
    /// The radius of the core circle, `R`.
    pub major: f64,
    /// The radius of the tube, `r < R`.
    pub minor: f64,
}

impl Torus {
    /// A torus with core radius `major` and tube radius `minor`.
    pub fn new(center: Point<3>, major: f64, minor: f64) -> Self {
        Self {
            center,
            major,
            minor,
        }
    }

    /// `(q, ρ)`: the in-plane distance from the axis minus `R`, paired with the height, and the
    /// in-plane distance itself.
    fn tube_coordinates(&self, p: &Point<3>) -> ([f64; 2], f64, Point<3>) {
        let d = sub(p, &self.center);
        let rho = (d[0] * d[0] + d[1] * d[1]).sqrt();
        ([rho - self.major, d[2]], rho, d)
    }
}

impl ScalarField<3> for Torus {
    fn value(&self, p: &Point<3>) -> f64 {
        let (q, _, _) = self.tube_coordinates(p);
        norm(&q) - self.minor
    }
    fn gradient(&self, p: &Point<3>) -> Point<3> {
        let (q, rho, d) = self.tube_coordinates(p);
        let [qx, qz] = unit_or_axis(q);
        let (cx, cy) = if rho > 0.0 {
            (d[0] / rho, d[1] / rho)
        } else {
            (1.0, 0.0)
        };
        [qx * cx, qx * cy, qz]
    }
    fn bounds(&self) -> Option<Aabb<3>> {
        let (a, r) = (self.major + self.minor, self.minor);
        let c = self.center;
        padded(
            [c[0] - a, c[1] - a, c[2] - r],
            [c[0] + a, c[1] + a, c[2] + r],
        )
    }
    fn value_range(&self, region: &Aabb<3>) -> Option<[f64; 2]> {
        // A signed distance is 1-Lipschitz.
        lipschitz_range(self, region, 1.0)
    }
}

/// A ring in the plane: the points within `half_width` of the circle of radius `radius`
/// about `center`. Two boundary components, so its zero set tests hole handling in 2-D.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Annulus {
    /// The centre.
    pub center: Point<2>,
    /// The radius of the middle circle.
    pub radius: f64,
    /// Half the ring's width (`< radius`).
    pub half_width: f64,
}

impl Annulus {
    /// The ring between radii `radius − half_width` and `radius + half_width`.
    pub fn new(center: Point<2>, radius: f64, half_width: f64) -> Self {
        Self {
            center,
            radius,
            half_width,
        }
    }
}

impl ScalarField<2> for Annulus {
    fn value(&self, p: &Point<2>) -> f64 {
        (norm(&sub(p, &self.center)) - self.radius).abs() - self.half_width
    }
    fn gradient(&self, p: &Point<2>) -> Point<2> {
        let d = sub(p, &self.center);
        let radial = unit_or_axis(d);
        let s = if norm(&d) >= self.radius { 1.0 } else { -1.0 };
        radial.map(|x| s * x)
    }
    fn bounds(&self) -> Option<Aabb<2>> {
        let a = self.radius + self.half_width;
        padded(self.center.map(|c| c - a), self.center.map(|c| c + a))
    }
    fn value_range(&self, region: &Aabb<2>) -> Option<[f64; 2]> {
        // A signed distance is 1-Lipschitz.
        lipschitz_range(self, region, 1.0)
    }
}

/// An axis-aligned box with exact signed distance: outside, the distance to the box; inside,
/// minus the distance to the nearest face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxSdf<const D: usize> {
    /// The centre.
    pub center: Point<D>,
    /// Half the side length along each axis.
    pub half_extent: Point<D>,
}

/// A box in space.
pub type Cuboid = BoxSdf<3>;
/// A rectangle in the plane.
pub type Rectangle = BoxSdf<2>;

impl<const D: usize> BoxSdf<D> {
    /// The box `center ± half_extent`.
    pub fn new(center: Point<D>, half_extent: Point<D>) -> Self {
        Self {
            center,
            half_extent,
        }
    }

    /// `|x − c| − half_extent` per axis.
    fn q(&self, p: &Point<D>) -> Point<D> {
        std::array::from_fn(|i| (p[i] - self.center[i]).abs() - self.half_extent[i])
    }
}

impl<const D: usize> ScalarField<D> for BoxSdf<D> {
    fn value(&self, p: &Point<D>) -> f64 {
        let q = self.q(p);
        let outside = norm(&q.map(|x| x.max(0.0)));
        let inside = q.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x)).min(0.0);
        outside + inside
    }
    fn gradient(&self, p: &Point<D>) -> Point<D> {
        let q = self.q(p);
        let sign: Point<D> =
            std::array::from_fn(|i| if p[i] >= self.center[i] { 1.0 } else { -1.0 });
        if q.iter().any(|&x| x > 0.0) {
            let g = unit_or_axis(q.map(|x| x.max(0.0)));
            std::array::from_fn(|i| sign[i] * g[i])
        } else {
            let axis = (0..D).fold(0, |best, i| if q[i] > q[best] { i } else { best });
            std::array::from_fn(|i| if i == axis { sign[i] } else { 0.0 })
        }
    }
    fn bounds(&self) -> Option<Aabb<D>> {
        padded(
            std::array::from_fn(|i| self.center[i] - self.half_extent[i]),
            std::array::from_fn(|i| self.center[i] + self.half_extent[i]),
        )
    }
    fn value_range(&self, region: &Aabb<D>) -> Option<[f64; 2]> {
        // A signed distance is 1-Lipschitz.
        lipschitz_range(self, region, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::central_difference_gradient;

    /// Points spread over a box, avoiding nothing: the gradient check below skips the few
    /// points near a shape's non-smooth set.
    fn probe_points<const D: usize>(b: &Aabb<D>, n: usize) -> Vec<Point<D>> {
        (0..n)
            .map(|k| {
                std::array::from_fn(|i| {
                    // A low-discrepancy sequence: fractional parts of k·√prime.
                    let alpha = [2.0_f64.sqrt(), 3.0_f64.sqrt(), 5.0_f64.sqrt()][i];
                    let t = (k as f64 * alpha + 0.5).fract();
                    b.min()[i] + t * b.extent()[i]
                })
            })
            .collect()
    }

    fn check_field<const D: usize>(f: &impl ScalarField<D>, skip: impl Fn(&Point<D>) -> bool) {
        let b = f.bounds().unwrap();
        let mut checked = 0;
        for p in probe_points(&b, 400) {
            if skip(&p) {
                continue;
            }
            let g = f.gradient(&p);
            let fd = central_difference_gradient(f, &p);
            for i in 0..D {
                assert!((g[i] - fd[i]).abs() < 1e-6, "at {p:?}: {g:?} vs {fd:?}");
            }
            assert!(
                (norm(&g) - 1.0).abs() < 1e-12,
                "SDF gradient not unit at {p:?}"
            );
            checked += 1;
        }
        assert!(checked > 300, "only {checked} points checked");
    }

    #[test]
    fn sphere_is_a_signed_distance() {
        let s = Sphere::new([0.1, -0.2, 0.3], 0.6);
        assert!((s.value(&[0.7, -0.2, 0.3])).abs() < 1e-15);
        assert!((s.value(&[0.1, -0.2, 0.3]) + 0.6).abs() < 1e-15);
        check_field(&s, |p| norm(&sub(p, &s.center)) < 1e-3);
    }

    #[test]
    fn torus_gradient_matches_finite_differences() {
        let t = Torus::new([0.0, 0.0, 0.1], 0.6, 0.2);
        assert!((t.value(&[0.8, 0.0, 0.1])).abs() < 1e-15);
        assert!((t.value(&[0.0, 0.0, 0.1]) - 0.4).abs() < 1e-15);
        check_field(&t, |p| {
            let (q, rho, _) = t.tube_coordinates(p);
            rho < 1e-3 || norm(&q) < 1e-3
        });
    }

    #[test]
    fn annulus_and_rectangle_gradients_match_finite_differences() {
        let a = Annulus::new([0.0, 0.0], 0.5, 0.1);
        assert!((a.value(&[0.6, 0.0])).abs() < 1e-15);
        assert!((a.value(&[0.5, 0.0]) + 0.1).abs() < 1e-15);
        check_field(&a, |p| (norm(p) - 0.5).abs() < 1e-3 || norm(p) < 1e-3);

        let r = Rectangle::new([0.0, 0.0], [0.4, 0.2]);
        assert_eq!(r.value(&[0.0, 0.0]), -0.2);
        assert!((r.value(&[0.7, 0.6]) - 0.5).abs() < 1e-15);
        // Skip the medial axis (|x| - 0.2 = |y| inside) and the corners' neighbourhoods.
        check_field(&r, |p| {
            let q = r.q(p);
            (q[0] - q[1]).abs() < 1e-3
                || q.iter().any(|x| x.abs() < 1e-3)
                || p.iter().any(|x| x.abs() < 1e-3)
        });
    }

    #[test]
    fn cuboid_distance_outside_a_corner() {
        let c = Cuboid::new([0.0; 3], [1.0, 2.0, 3.0]);
        assert!((c.value(&[2.0, 3.0, 4.0]) - 3.0_f64.sqrt()).abs() < 1e-15);
        assert_eq!(c.value(&[0.0, 0.0, 0.0]), -1.0);
        assert_eq!(c.gradient(&[0.5, 0.0, 0.0]), [1.0, 0.0, 0.0]);
    }

    /// The enclosures hold at the corners and inside, for every shape.
    #[test]
    fn enclosures_hold() {
        fn check<const D: usize>(f: &impl ScalarField<D>) {
            let b = f.bounds().expect("bounds");
            for (k, c) in probe_points(&b, 200).iter().enumerate() {
                let half = [0.01, 0.1, 0.4][k % 3];
                let region = Aabb::new(c.map(|v| v - half), c.map(|v| v + half)).expect("box");
                let [lo, hi] = f.value_range(&region).expect("enclosure");
                for x in probe_points(&region, 30) {
                    let v = f.value(&x);
                    assert!(lo <= v && v <= hi, "{v} outside [{lo}, {hi}]");
                }
            }
        }
        check(&Ball::new([0.1, -0.2, 0.3], 0.7));
        check(&Torus::new([0.0; 3], 1.0, 0.3));
        check(&Annulus::new([0.2, 0.1], 1.0, 0.2));
        check(&BoxSdf::new([0.0; 3], [0.5, 0.3, 0.8]));
    }
}
