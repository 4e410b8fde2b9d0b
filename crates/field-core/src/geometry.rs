//! Points and axis-aligned boxes in `D` dimensions (`D` = 2 for curves, 3 for surfaces).
//!
//! Points are plain arrays `[f64; D]`: they cost nothing to pass around and interoperate with
//! every other crate. The few vector operations zeroset needs are free functions here.

use crate::error::{Error, Result};

/// A point (or vector) in `D` dimensions.
pub type Point<const D: usize> = [f64; D];
/// A point in the plane.
pub type Point2 = Point<2>;
/// A point in space.
pub type Point3 = Point<3>;

/// `a + b`.
#[inline]
pub fn add<const D: usize>(a: &Point<D>, b: &Point<D>) -> Point<D> {
    std::array::from_fn(|i| a[i] + b[i])
}

/// `a - b`.
#[inline]
pub fn sub<const D: usize>(a: &Point<D>, b: &Point<D>) -> Point<D> {
    std::array::from_fn(|i| a[i] - b[i])
}

/// `s * a`.
#[inline]
pub fn scale<const D: usize>(s: f64, a: &Point<D>) -> Point<D> {
    std::array::from_fn(|i| s * a[i])
}

/// The dot product `a · b`.
#[inline]
pub fn dot<const D: usize>(a: &Point<D>, b: &Point<D>) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The cross product `a × b` of two 3-D vectors.
#[inline]
pub fn cross(a: &Point<3>, b: &Point<3>) -> Point<3> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The Euclidean norm `‖a‖₂`.
#[inline]
pub fn norm<const D: usize>(a: &Point<D>) -> f64 {
    dot(a, a).sqrt()
}

/// The Euclidean distance `‖a − b‖₂`.
#[inline]
pub fn distance<const D: usize>(a: &Point<D>, b: &Point<D>) -> f64 {
    norm(&sub(a, b))
}

/// An axis-aligned box `[min₀, max₀] × … × [min_{D−1}, max_{D−1}]`.
///
/// Invariant: every coordinate is finite and `min[i] <= max[i]`; a box may be flat (zero width on
/// an axis), which is how a degenerate point cloud shows itself.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb<const D: usize> {
    min: Point<D>,
    max: Point<D>,
}

/// A box in the plane.
pub type Aabb2 = Aabb<2>;
/// A box in space.
pub type Aabb3 = Aabb<3>;

impl<const D: usize> Aabb<D> {
    /// A box from its two corners.
    ///
    /// # Errors
    /// [`Error::InvalidBounds`] if a coordinate is not finite or `min[i] > max[i]`.
    pub fn new(min: Point<D>, max: Point<D>) -> Result<Self> {
        for axis in 0..D {
            let (lo, hi) = (min[axis], max[axis]);
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(Error::InvalidBounds {
                    axis,
                    min: lo,
                    max: hi,
                });
            }
        }
        Ok(Self { min, max })
    }

    /// The box `[-h, h]^D` centred on the origin.
    ///
    /// # Errors
    /// [`Error::InvalidBounds`] if `h` is negative or not finite.
    pub fn centered_cube(h: f64) -> Result<Self> {
        Self::new([-h; D], [h; D])
    }

    /// The smallest box holding every point, or `None` for an empty slice or a slice holding a
    /// non-finite coordinate.
    pub fn from_points(points: &[Point<D>]) -> Option<Self> {
        let first = points.first()?;
        let (mut min, mut max) = (*first, *first);
        for p in points {
            for i in 0..D {
                min[i] = min[i].min(p[i]);
                max[i] = max[i].max(p[i]);
            }
        }
        Self::new(min, max).ok()
    }

    /// The lower corner.
    pub fn min(&self) -> Point<D> {
        self.min
    }

    /// The upper corner.
    pub fn max(&self) -> Point<D> {
        self.max
    }

    /// `max − min` per axis.
    pub fn extent(&self) -> Point<D> {
        sub(&self.max, &self.min)
    }

    /// The centre point.
    pub fn center(&self) -> Point<D> {
        std::array::from_fn(|i| 0.5 * (self.min[i] + self.max[i]))
    }

    /// The length of the diagonal. Computed with the largest extent factored out where the
    /// plain sum of squares overflows or underflows (sides of 1e155 or 1e-200), so that it is
    /// finite and non-zero for every box of finite extent that is not a point (infinite where
    /// the extent itself overflows, as for corners at ±1e308).
    pub fn diagonal(&self) -> f64 {
        let e = self.extent();
        let plain = norm(&e);
        let largest = e.iter().fold(0.0f64, |m, v| m.max(*v));
        if (plain.is_finite() && (plain > 0.0 || largest == 0.0)) || largest.is_infinite() {
            // An extent that overflows itself (corners at ±1e308) has an infinite diagonal.
            return plain;
        }
        largest * norm(&e.map(|v| v / largest))
    }

    /// Whether `p` lies in the closed box.
    pub fn contains(&self, p: &Point<D>) -> bool {
        (0..D).all(|i| self.min[i] <= p[i] && p[i] <= self.max[i])
    }

    /// The box grown by `margin` on every side (shrunk for a negative margin, never past flat).
    /// The corners stay finite, as the type promises: they stop at `±f64::MAX` (an infinite
    /// margin, or one that overflows), and a NaN margin leaves the box as it is. A grid over a
    /// box whose extent overflows is refused ([`Grid::new`](crate::grid::Grid::new)).
    pub fn expanded(&self, margin: f64) -> Self {
        if margin.is_nan() {
            return *self;
        }
        let mut min = self.min;
        let mut max = self.max;
        for i in 0..D {
            min[i] = (min[i] - margin).clamp(f64::MIN, f64::MAX);
            max[i] = (max[i] + margin).clamp(f64::MIN, f64::MAX);
            if min[i] > max[i] {
                let c = 0.5 * (self.min[i] + self.max[i]);
                min[i] = c;
                max[i] = c;
            }
        }
        Self { min, max }
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &Self) -> Self {
        Self {
            min: std::array::from_fn(|i| self.min[i].min(other.min[i])),
            max: std::array::from_fn(|i| self.max[i].max(other.max[i])),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_inverted_and_non_finite_boxes() {
        assert!(matches!(
            Aabb::new([0.0, 1.0], [1.0, 0.0]),
            Err(Error::InvalidBounds { axis: 1, .. })
        ));
        assert!(matches!(
            Aabb::new([f64::NAN, 0.0, 0.0], [1.0; 3]),
            Err(Error::InvalidBounds { axis: 0, .. })
        ));
    }

    #[test]
    fn from_points_is_tight() {
        let b = Aabb::from_points(&[[0.0, 2.0, -1.0], [1.0, -3.0, 4.0]]).unwrap();
        assert_eq!(b.min(), [0.0, -3.0, -1.0]);
        assert_eq!(b.max(), [1.0, 2.0, 4.0]);
        assert!(b.contains(&[0.5, 0.0, 0.0]));
        assert!(!b.contains(&[1.5, 0.0, 0.0]));
        assert!(Aabb::<3>::from_points(&[]).is_none());
        assert!(Aabb::from_points(&[[f64::INFINITY, 0.0]]).is_none());
    }

    #[test]
    fn expanded_never_inverts() {
        let b = Aabb::new([0.0, 0.0], [1.0, 4.0]).unwrap().expanded(-1.0);
        assert_eq!(b.min(), [0.5, 1.0]);
        assert_eq!(b.max(), [0.5, 3.0]);
    }

    #[test]
    fn the_diagonal_of_huge_and_tiny_boxes_is_finite() {
        for side in [1e-200, 1e155, 1e300, 1.0] {
            let b = Aabb::new([0.0; 3], [side; 3]).unwrap();
            assert!((b.diagonal() / side - 3f64.sqrt()).abs() < 1e-15, "{side}");
        }
        assert_eq!(Aabb::new([2.0; 3], [2.0; 3]).unwrap().diagonal(), 0.0);
        let overflowing = Aabb::new([-1e308; 3], [1e308; 3]).unwrap();
        assert_eq!(overflowing.diagonal(), f64::INFINITY);
    }

    #[test]
    fn expanded_keeps_the_corners_finite() {
        let b = Aabb::new([0.0, 0.0], [1.0, 4.0]).unwrap();
        let wide = b.expanded(f64::INFINITY);
        assert_eq!(wide.min(), [f64::MIN; 2]);
        assert_eq!(wide.max(), [f64::MAX; 2]);
        assert_eq!(b.expanded(f64::NAN), b);
        // Its extent overflows: no grid over it.
        assert!(matches!(
            crate::grid::Grid::vertex_centered(wide, [4, 4]),
            Err(Error::InvalidBounds { axis: 0, .. })
        ));
        let huge = Aabb::new([-1e308; 3], [1e308; 3]).unwrap();
        assert!(crate::grid::Grid::vertex_centered(huge, [4, 4, 4]).is_err());
    }
}
