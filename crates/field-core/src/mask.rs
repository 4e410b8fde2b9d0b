//! Box masks: the region of a grid that restoration rewrites.
//!
//! A user gives two opposite corners `a`, `b` of a box in world coordinates; the mask is the set
//! of grid samples whose position lies in `[min(a,b), max(a,b)]` on every axis, which on a
//! uniform grid is a product of index ranges `lo_a ..= hi_a`. The paper (Ren–Fujita–Nakata §2.1)
//! selects masks exactly this way. A mask may touch the grid border; which faces it touches
//! decides between Dirichlet rows (an outside ring exists) and border interpolation.
//!
//! ```
//! use zeroset_field_core::geometry::Aabb;
//! use zeroset_field_core::grid::Grid;
//! use zeroset_field_core::mask::{BoxMask, Face, Side};
//!
//! let g = Grid::cell_centered(Aabb::centered_cube(1.0)?, [8, 8, 8])?;
//! let m = BoxMask::from_corners(&g, [-0.5, -0.5, 0.0], [0.5, 0.5, 1.0])?;
//! assert_eq!((m.lo(), m.hi()), ([2, 2, 4], [5, 5, 7]));
//! assert!(m.touches(Face::new(2, Side::Upper)));
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```

use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::grid::Grid;

/// Which end of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Side {
    /// The low end (index 0).
    Lower,
    /// The high end (index `N − 1`).
    Upper,
}

/// A face of a box: an axis and a side. In 3-D, `Face::new(2, Side::Upper)` is the top.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Face {
    /// The axis the face is normal to.
    pub axis: usize,
    /// Which end.
    pub side: Side,
}

impl Face {
    /// The face normal to `axis` on `side`.
    pub fn new(axis: usize, side: Side) -> Self {
        Self { axis, side }
    }

    /// The `2D` faces of a `D`-box, in the order (axis 0 lower, axis 0 upper, axis 1 lower, …).
    pub fn all<const D: usize>() -> impl Iterator<Item = Face> {
        (0..D).flat_map(|axis| [Side::Lower, Side::Upper].map(|side| Face { axis, side }))
    }

    /// The outward unit normal.
    pub fn normal<const D: usize>(&self) -> Point<D> {
        let s = match self.side {
            Side::Lower => -1.0,
            Side::Upper => 1.0,
        };
        std::array::from_fn(|a| if a == self.axis { s } else { 0.0 })
    }
}

/// A face from its name: `+x`, `-x`, `+y`, `-y`, `+z`, `-z` (surrounding spaces ignored).
///
/// ```
/// use zeroset_field_core::mask::{Face, Side};
///
/// assert_eq!("-z".parse::<Face>(), Ok(Face::new(2, Side::Lower)));
/// assert!("z".parse::<Face>().is_err());
/// ```
impl std::str::FromStr for Face {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let wrong = || format!("a face is +x, -x, +y, -y, +z or -z, got {s:?}");
        let (side, axis) = match s.trim().split_at_checked(1) {
            Some(("+", a)) => (Side::Upper, a),
            Some(("-", a)) => (Side::Lower, a),
            _ => return Err(wrong()),
        };
        let axis = match axis {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return Err(wrong()),
        };
        Ok(Face::new(axis, side))
    }
}

/// A box of grid samples `lo ..= hi` (inclusive on every axis) on a grid of `counts` samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BoxMask<const D: usize> {
    lo: [usize; D],
    hi: [usize; D],
    counts: [usize; D],
}

impl<const D: usize> BoxMask<D> {
    /// The samples of `grid` inside the box with opposite corners `a` and `b` (any two opposite
    /// corners, in any order).
    ///
    /// # Errors
    /// [`Error::InvalidBounds`] for a non-finite corner, [`Error::MaskOutsideBox`] when the box
    /// reaches outside the grid's bounds (by more than a rounding error), and
    /// [`Error::EmptyMask`] when it holds no sample on some axis.
    pub fn from_corners(grid: &Grid<D>, a: Point<D>, b: Point<D>) -> Result<Self> {
        let bounds = grid.bounds();
        let (bmin, bmax) = (bounds.min(), bounds.max());
        let mut lo = [0; D];
        let mut hi = [0; D];
        for axis in 0..D {
            let (l, h) = (a[axis].min(b[axis]), a[axis].max(b[axis]));
            if !(a[axis].is_finite() && b[axis].is_finite()) {
                return Err(Error::InvalidBounds {
                    axis,
                    min: a[axis],
                    max: b[axis],
                });
            }
            let slack = 1e-9 * grid.spacing()[axis];
            if l < bmin[axis] - slack || h > bmax[axis] + slack {
                return Err(Error::MaskOutsideBox {
                    axis,
                    lo: l,
                    hi: h,
                    min: bmin[axis],
                    max: bmax[axis],
                });
            }
            // Samples i with l <= x_i <= h; the tolerance keeps a corner placed exactly on a
            // sample (up to rounding) inside.
            let t = grid
                .continuous_index(&std::array::from_fn(|k| if k == axis { l } else { 0.0 }))[axis];
            let u = grid
                .continuous_index(&std::array::from_fn(|k| if k == axis { h } else { 0.0 }))[axis];
            let first = (t - 1e-9).ceil().max(0.0);
            let last = (u + 1e-9).floor().min((grid.counts()[axis] - 1) as f64);
            if first > last {
                return Err(Error::EmptyMask { axis, lo: l, hi: h });
            }
            lo[axis] = first as usize;
            hi[axis] = last as usize;
        }
        Ok(Self {
            lo,
            hi,
            counts: grid.counts(),
        })
    }

    /// The mask `lo ..= hi` given by sample indices.
    ///
    /// # Errors
    /// [`Error::MaskIndexOutOfRange`] when `lo > hi` or `hi` is past the grid on some axis.
    pub fn from_indices(grid: &Grid<D>, lo: [usize; D], hi: [usize; D]) -> Result<Self> {
        let counts = grid.counts();
        for axis in 0..D {
            if lo[axis] > hi[axis] || hi[axis] >= counts[axis] {
                return Err(Error::MaskIndexOutOfRange {
                    axis,
                    lo: lo[axis],
                    hi: hi[axis],
                    len: counts[axis],
                });
            }
        }
        Ok(Self { lo, hi, counts })
    }

    /// First index on each axis.
    pub fn lo(&self) -> [usize; D] {
        self.lo
    }

    /// Last index on each axis (inclusive).
    pub fn hi(&self) -> [usize; D] {
        self.hi
    }

    /// Samples per axis inside the mask.
    pub fn extent(&self) -> [usize; D] {
        std::array::from_fn(|a| self.hi[a] - self.lo[a] + 1)
    }

    /// The number of samples in the mask.
    pub fn len(&self) -> usize {
        self.extent().iter().product()
    }

    /// Never true: a mask holds at least one sample.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Whether a grid multi-index lies in the mask.
    pub fn contains(&self, index: [usize; D]) -> bool {
        (0..D).all(|a| self.lo[a] <= index[a] && index[a] <= self.hi[a])
    }

    /// Samples per axis of the grid the mask was made for.
    pub fn grid_counts(&self) -> [usize; D] {
        self.counts
    }

    /// Whether the mask reaches the grid border on `face` (so no sample lies beyond it there);
    /// false for a face whose axis the grid does not have (`face.axis ≥ D`).
    pub fn touches(&self, face: Face) -> bool {
        if face.axis >= D {
            return false;
        }
        match face.side {
            Side::Lower => self.lo[face.axis] == 0,
            Side::Upper => self.hi[face.axis] + 1 == self.counts[face.axis],
        }
    }

    /// The faces on which the mask touches the grid border.
    pub fn border_faces(&self) -> Vec<Face> {
        Face::all::<D>().filter(|&f| self.touches(f)).collect()
    }

    /// The grid multi-indices of the mask, last axis fastest (the order of the mask's own
    /// unknowns in restoration).
    pub fn indices(&self) -> impl Iterator<Item = [usize; D]> + '_ {
        let extent = self.extent();
        (0..self.len()).map(move |mut l| {
            let mut index = [0; D];
            for a in (0..D).rev() {
                index[a] = self.lo[a] + l % extent[a];
                l /= extent[a];
            }
            index
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;

    fn grid() -> Grid<3> {
        Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [10, 10, 10]).unwrap()
    }

    #[test]
    fn corners_in_any_order_select_the_same_samples() {
        let g = grid();
        let m1 = BoxMask::from_corners(&g, [-0.3, 0.1, -1.0], [0.3, 0.5, 0.0]).unwrap();
        let m2 = BoxMask::from_corners(&g, [0.3, 0.1, 0.0], [-0.3, 0.5, -1.0]).unwrap();
        assert_eq!(m1, m2);
        // Centres at -0.9, -0.7, ..., 0.9; a corner on a centre (±0.3, 0.1, 0.5) includes it.
        assert_eq!(m1.lo(), [3, 5, 0]);
        assert_eq!(m1.hi(), [6, 7, 4]);
        assert_eq!(m1.border_faces(), vec![Face::new(2, Side::Lower)]);
        assert_eq!(m1.len(), 4 * 3 * 5);
        let idx: Vec<_> = m1.indices().collect();
        assert_eq!(idx.len(), m1.len());
        assert_eq!(idx[0], [3, 5, 0]);
        assert_eq!(idx[1], [3, 5, 1]);
        assert_eq!(idx[5], [3, 6, 0]);
        assert!(idx.iter().all(|&i| m1.contains(i)));
    }

    #[test]
    fn masks_outside_or_between_samples_are_errors() {
        let g = grid();
        assert!(matches!(
            BoxMask::from_corners(&g, [0.0, 0.0, 0.0], [1.5, 0.5, 0.5]),
            Err(Error::MaskOutsideBox { axis: 0, .. })
        ));
        assert!(matches!(
            BoxMask::from_corners(&g, [0.0, 0.01, 0.0], [0.5, 0.09, 0.5]),
            Err(Error::EmptyMask { axis: 1, .. })
        ));
        assert!(matches!(
            BoxMask::from_corners(&g, [0.0, f64::NAN, 0.0], [0.5, 0.5, 0.5]),
            Err(Error::InvalidBounds { axis: 1, .. })
        ));
        assert!(matches!(
            BoxMask::from_indices(&g, [0, 0, 0], [3, 10, 3]),
            Err(Error::MaskIndexOutOfRange { axis: 1, .. })
        ));
    }
}
