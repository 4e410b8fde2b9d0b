//! Uniform grids over a box, cell- or vertex-centred.
//!
//! A grid with `N_a` samples along axis `a` over `[min_a, max_a]` places sample `i` at
//!
//! ```text
//! cell-centred:    x_i = min + (i + ½)·h,   h = (max − min) / N          (restoration, splines)
//! vertex-centred:  x_i = min + i·h,         h = (max − min) / (N − 1)    (marching cubes)
//! ```
//!
//! Samples are numbered with the **last axis fastest**: the linear index of `[i, j, k]` is
//! `(i·N₁ + j)·N₂ + k`, which is the C order of an ndarray `Array3` indexed `[i, j, k]`, so a
//! sampled grid converts to ndarray without a copy (see [`crate::interop`]).
//!
//! ```
//! use zeroset_field_core::analytic::Sphere;
//! use zeroset_field_core::geometry::Aabb;
//! use zeroset_field_core::grid::Grid;
//!
//! let g = Grid::cell_centered(Aabb::centered_cube(1.0)?, [4, 4, 4])?;
//! assert_eq!(g.point([0, 0, 0]), [-0.75, -0.75, -0.75]);
//! let values = g.sample(&Sphere::new([0.0; 3], 0.5));
//! assert_eq!(values.len(), 64);
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::field::ScalarField;
use crate::geometry::{Aabb, Point};

/// Where the samples sit in the box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Centering {
    /// At cell centres: `N` cells, none on the box boundary.
    Cell,
    /// At cell corners: `N` vertices, the first and last on the boundary.
    Vertex,
}

/// A uniform grid of `counts[0] × … × counts[D−1]` samples over a box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid<const D: usize> {
    bounds: Aabb<D>,
    counts: [usize; D],
    centering: Centering,
    spacing: [f64; D],
}

/// A grid in the plane.
pub type Grid2 = Grid<2>;
/// A grid in space.
pub type Grid3 = Grid<3>;

/// Points generated per task in [`Grid::sample`].
const SAMPLE_CHUNK: usize = 1 << 16;

/// `longest` cells along the longest axis of `bounds` and the others in proportion (rounded,
/// at least 3): cells as close to cubes as whole counts allow.
///
/// ```
/// use zeroset_field_core::geometry::Aabb;
/// use zeroset_field_core::grid::cubic_counts;
///
/// let b = Aabb::new([0.0, 0.0, 0.0], [2.0, 1.0, 0.01]).unwrap();
/// assert_eq!(cubic_counts(&b, 64), [64, 32, 3]);
/// ```
pub fn cubic_counts<const D: usize>(bounds: &Aabb<D>, longest: usize) -> [usize; D] {
    let e = bounds.extent();
    let m = e.iter().copied().fold(0.0, f64::max);
    e.map(|x| ((x / m * longest as f64).round() as usize).max(3))
}

impl<const D: usize> Grid<D> {
    /// A grid with the given sample counts.
    ///
    /// # Errors
    /// [`Error::GridTooSmall`] for fewer than one cell (cell-centred) or two vertices
    /// (vertex-centred) on some axis; [`Error::InvalidBounds`] for a box that is flat on an axis
    /// carrying more than one sample, or whose extent overflows to infinity; [`Error::SizeOverflow`] for more samples than one `f64`
    /// each can address (whether the machine has the memory for a grid's samples is checked
    /// by those that allocate them: [`crate::limits::check_alloc`]).
    pub fn new(bounds: Aabb<D>, counts: [usize; D], centering: Centering) -> Result<Self> {
        let needed = match centering {
            Centering::Cell => 1,
            Centering::Vertex => 2,
        };
        let extent = bounds.extent();
        let mut spacing = [0.0; D];
        for axis in 0..D {
            if counts[axis] < needed {
                return Err(Error::GridTooSmall {
                    axis,
                    needed,
                    got: counts[axis],
                });
            }
            // Not positive, or overflowing (a box from ±1e308 has an infinite extent).
            if !(extent[axis] > 0.0 && extent[axis].is_finite()) {
                return Err(Error::InvalidBounds {
                    axis,
                    min: bounds.min()[axis],
                    max: bounds.max()[axis],
                });
            }
            spacing[axis] = match centering {
                Centering::Cell => extent[axis] / counts[axis] as f64,
                Centering::Vertex => extent[axis] / (counts[axis] - 1) as f64,
            };
        }
        // Every sample must be countable and addressable as one f64 each: a grid beyond that
        // is no grid any machine can sample (len() would wrap to a small number).
        let samples = counts.iter().try_fold(1usize, |a, &n| a.checked_mul(n));
        if samples
            .and_then(|n| n.checked_mul(8))
            .is_none_or(|b| b > isize::MAX as usize)
        {
            return Err(Error::SizeOverflow {
                what: format!("a grid of {counts:?} samples"),
                count: counts.iter().fold(1u64, |a, &n| a.saturating_mul(n as u64)),
                bytes_each: 8,
            });
        }
        Ok(Self {
            bounds,
            counts,
            centering,
            spacing,
        })
    }

    /// A cell-centred grid (see [`Grid::new`] for errors).
    pub fn cell_centered(bounds: Aabb<D>, counts: [usize; D]) -> Result<Self> {
        Self::new(bounds, counts, Centering::Cell)
    }

    /// A vertex-centred grid (see [`Grid::new`] for errors).
    pub fn vertex_centered(bounds: Aabb<D>, counts: [usize; D]) -> Result<Self> {
        Self::new(bounds, counts, Centering::Vertex)
    }

    /// The box.
    pub fn bounds(&self) -> Aabb<D> {
        self.bounds
    }

    /// Samples per axis.
    pub fn counts(&self) -> [usize; D] {
        self.counts
    }

    /// Where samples sit.
    pub fn centering(&self) -> Centering {
        self.centering
    }

    /// The distance between neighbouring samples on each axis.
    pub fn spacing(&self) -> [f64; D] {
        self.spacing
    }

    /// The number of samples, `Π counts`.
    pub fn len(&self) -> usize {
        self.counts.iter().product()
    }

    /// Never true: a grid holds at least one sample. Present for API symmetry with `len`.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The coordinate of sample `i` on `axis` (not bounds-checked: any `i` extrapolates).
    pub fn coordinate(&self, axis: usize, i: usize) -> f64 {
        let offset = match self.centering {
            Centering::Cell => 0.5,
            Centering::Vertex => 0.0,
        };
        self.bounds.min()[axis] + (i as f64 + offset) * self.spacing[axis]
    }

    /// The position of the sample with multi-index `index`.
    pub fn point(&self, index: [usize; D]) -> Point<D> {
        std::array::from_fn(|a| self.coordinate(a, index[a]))
    }

    /// The linear (last-axis-fastest) index of a multi-index.
    ///
    /// # Panics
    /// In debug builds, if `index` is outside the grid.
    pub fn linear_index(&self, index: [usize; D]) -> usize {
        debug_assert!(
            (0..D).all(|a| index[a] < self.counts[a]),
            "{index:?} outside grid"
        );
        index
            .iter()
            .zip(&self.counts)
            .fold(0, |acc, (&i, &n)| acc * n + i)
    }

    /// The multi-index of a linear index.
    pub fn multi_index(&self, mut linear: usize) -> [usize; D] {
        let mut index = [0; D];
        for a in (0..D).rev() {
            index[a] = linear % self.counts[a];
            linear /= self.counts[a];
        }
        index
    }

    /// The continuous index of a point: `(x − x₀)/h` per axis, so that sample `i` sits at `i`.
    pub fn continuous_index(&self, p: &Point<D>) -> [f64; D] {
        std::array::from_fn(|a| (p[a] - self.coordinate(a, 0)) / self.spacing[a])
    }

    /// Every sample position, in linear order.
    pub fn points(&self) -> Vec<Point<D>> {
        (0..self.len())
            .into_par_iter()
            .map(|l| self.point(self.multi_index(l)))
            .collect()
    }

    /// Samples `field` at every grid point, in linear order, calling the field's batched
    /// [`ScalarField::values`] on chunks (so positions are never all held at once).
    ///
    /// Allocates `8 · len()` bytes, which aborts the process where the memory is not there:
    /// [`Grid::try_sample`] checks it first.
    pub fn sample<F: ScalarField<D> + ?Sized>(&self, field: &F) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        let mut points = Vec::with_capacity(SAMPLE_CHUNK.min(self.len()));
        for (c, chunk) in out.chunks_mut(SAMPLE_CHUNK).enumerate() {
            let start = c * SAMPLE_CHUNK;
            points.clear();
            points.extend((start..start + chunk.len()).map(|l| self.point(self.multi_index(l))));
            field.values(&points, chunk);
        }
        out
    }

    /// [`Grid::sample`] after checking that its `8 · len()` bytes are available
    /// ([`crate::limits::check_alloc`]).
    ///
    /// # Errors
    /// [`Error::Memory`] naming the grid, the amount and the limit.
    pub fn try_sample<F: ScalarField<D> + ?Sized>(&self, field: &F) -> Result<Vec<f64>> {
        crate::limits::check_alloc(
            &format!("the samples of a grid of {:?}", self.counts),
            self.len(),
            8,
        )?;
        Ok(self.sample(field))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analytic::Sphere;

    #[test]
    // Off Linux without ZEROSET_MEMORY_LIMIT there is no memory figure to refuse 8 PB by:
    // the allocation itself would abort the test process.
    #[cfg(target_os = "linux")]
    fn a_grid_whose_sample_count_overflows_is_refused() {
        let cube = Aabb::new([-1.0; 3], [1.0; 3]).unwrap();
        // 2⁶⁶ samples: len() would have wrapped to 0.
        let e = Grid::cell_centered(cube, [1 << 22; 3]).unwrap_err();
        assert!(matches!(e, Error::SizeOverflow { .. }), "{e}");
        // 10¹⁵ samples are addressable, but try_sample refuses them before allocating.
        let g = Grid::vertex_centered(cube, [100_000; 3]).unwrap();
        let e = g.try_sample(&Sphere::new([0.0; 3], 0.5)).unwrap_err();
        assert!(matches!(e, Error::Memory { .. }), "{e}");
    }

    #[test]
    fn cell_and_vertex_positions() {
        let b = Aabb::new([0.0, -1.0], [1.0, 1.0]).unwrap();
        let c = Grid::cell_centered(b, [2, 4]).unwrap();
        assert_eq!(c.spacing(), [0.5, 0.5]);
        assert_eq!(c.point([1, 3]), [0.75, 0.75]);
        let v = Grid::vertex_centered(b, [3, 5]).unwrap();
        assert_eq!(v.point([0, 0]), [0.0, -1.0]);
        assert_eq!(v.point([2, 4]), [1.0, 1.0]);
        assert_eq!(v.continuous_index(&[0.25, 0.0]), [0.5, 2.0]);
    }

    #[test]
    fn linear_index_is_last_axis_fastest_and_inverts() {
        let g = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [3, 4, 5]).unwrap();
        assert_eq!(g.linear_index([0, 0, 1]), 1);
        assert_eq!(g.linear_index([0, 1, 0]), 5);
        assert_eq!(g.linear_index([1, 0, 0]), 20);
        for l in 0..g.len() {
            assert_eq!(g.linear_index(g.multi_index(l)), l);
        }
    }

    #[test]
    fn sampling_matches_pointwise_evaluation() {
        let g = Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [41, 42, 43]).unwrap();
        let s = Sphere::new([0.1, 0.0, 0.0], 0.5);
        let v = g.sample(&s);
        assert_eq!(v.len(), 41 * 42 * 43);
        for l in (0..g.len()).step_by(97) {
            assert_eq!(v[l], s.value(&g.point(g.multi_index(l))));
        }
    }

    #[test]
    fn degenerate_grids_are_errors() {
        let b = Aabb::centered_cube(1.0).unwrap();
        assert!(matches!(
            Grid::vertex_centered(b, [4, 1, 4]),
            Err(Error::GridTooSmall {
                axis: 1,
                needed: 2,
                got: 1
            })
        ));
        let flat = Aabb::new([0.0, 0.0], [1.0, 0.0]).unwrap();
        assert!(matches!(
            Grid::cell_centered(flat, [2, 2]),
            Err(Error::InvalidBounds { axis: 1, .. })
        ));
    }
}
