//! [`BSplineSpace`]: the uniform B-splines on a grid as a [`Basis`], for least-squares fits.

use zeroset_field_core::basis::{Basis, BasisRow};
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::grid::Grid;

use super::stencil::{fold, strides, weights};
use super::{Boundary, Degree, clamp_range};

/// The space of tensor-product B-splines of one degree on a grid, one basis function per grid
/// sample (so [`Basis::num_coefficients`] is `grid.len()`, in the grid's C order), with
/// coefficients outside the grid mirrored in by `boundary`.
///
/// A row at `p` holds the `3ᴰ` (quadratic) or `4ᴰ` (cubic) B-splines that overlap `p`; near the
/// boundary, B-splines that fold onto the same coefficient are summed into one entry, so a row
/// has at most that many entries, with strictly increasing indices. Points are clamped to the
/// grid's box exactly as in [`BSplineField`](super::BSplineField), so that
/// `BasisField::new(space, c)` and `BSplineField::from_coefficients(grid, c, ..)` are the same
/// function (up to rounding).
///
/// ```
/// use zeroset_bases::bspline::{BSplineSpace, Boundary, Degree};
/// use zeroset_field_core::basis::{Basis, BasisRow};
/// use zeroset_field_core::geometry::Aabb;
/// use zeroset_field_core::grid::Grid;
///
/// let grid = Grid::cell_centered(Aabb::centered_cube(1.0)?, [8, 8, 8])?;
/// let space = BSplineSpace::new(grid, Degree::Quadratic, Boundary::HalfSample);
/// let mut row = BasisRow::new();
/// space.eval_row(&[0.1, 0.2, -0.3], false, &mut row);
/// assert_eq!(row.indices.len(), 27);
/// assert!((row.values.iter().sum::<f64>() - 1.0).abs() < 1e-15); // partition of unity
/// # Ok::<(), zeroset_field_core::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct BSplineSpace<const D: usize> {
    grid: Grid<D>,
    degree: Degree,
    boundary: Boundary,
}

/// One axis's B-splines after folding, duplicates merged, sorted by index.
struct MergedAxis {
    len: usize,
    index: [usize; 4],
    w: [f64; 4],
    d1: [f64; 4],
}

fn merged_axis<const K: usize>(x: f64, n: usize, boundary: Boundary) -> MergedAxis {
    let aw = weights::<K>(x);
    let mut m = MergedAxis {
        len: 0,
        index: [0; 4],
        w: [0.0; 4],
        d1: [0.0; 4],
    };
    for k in 0..K {
        let j = fold(aw.first + k as isize, n, boundary);
        match m.index[..m.len].iter().position(|&i| i == j) {
            Some(pos) => {
                m.w[pos] += aw.w[k];
                m.d1[pos] += aw.d1[k];
            }
            None => {
                // Insert keeping the indices sorted.
                let mut pos = m.len;
                while pos > 0 && m.index[pos - 1] > j {
                    m.index[pos] = m.index[pos - 1];
                    m.w[pos] = m.w[pos - 1];
                    m.d1[pos] = m.d1[pos - 1];
                    pos -= 1;
                }
                m.index[pos] = j;
                m.w[pos] = aw.w[k];
                m.d1[pos] = aw.d1[k];
                m.len += 1;
            }
        }
    }
    m
}

impl<const D: usize> BSplineSpace<D> {
    /// The B-splines of `degree` on `grid`, mirrored at the boundary by `boundary`.
    pub fn new(grid: Grid<D>, degree: Degree, boundary: Boundary) -> Self {
        Self {
            grid,
            degree,
            boundary,
        }
    }

    /// The grid (one B-spline per sample, centred on it).
    pub fn grid(&self) -> &Grid<D> {
        &self.grid
    }

    /// The degree.
    pub fn degree(&self) -> Degree {
        self.degree
    }

    /// The boundary rule.
    pub fn boundary(&self) -> Boundary {
        self.boundary
    }
}

impl<const D: usize> Basis<D> for BSplineSpace<D> {
    fn num_coefficients(&self) -> usize {
        self.grid.len()
    }

    fn bounds(&self) -> Aabb<D> {
        self.grid.bounds()
    }

    fn max_row_nnz(&self) -> usize {
        self.degree.stencil_len().pow(D as u32)
    }

    fn eval_row(&self, p: &Point<D>, with_gradients: bool, row: &mut BasisRow<D>) {
        row.clear();
        let counts = self.grid.counts();
        let stride = strides(counts);
        let spacing = self.grid.spacing();
        let (lo, hi) = clamp_range(&self.grid);
        let x = self.grid.continuous_index(p);
        let axes: [MergedAxis; D] = std::array::from_fn(|a| {
            let xa = x[a].clamp(lo, hi[a]);
            match self.degree {
                Degree::Quadratic => merged_axis::<3>(xa, counts[a], self.boundary),
                Degree::Cubic => merged_axis::<4>(xa, counts[a], self.boundary),
            }
        });
        let total: usize = axes.iter().map(|m| m.len).product();
        // Odometer over the per-axis entries, last axis fastest: with sorted, unique indices
        // per axis the linear indices come out strictly increasing.
        for flat in 0..total {
            let mut r = flat;
            let mut k = [0usize; D];
            for a in (0..D).rev() {
                k[a] = r % axes[a].len;
                r /= axes[a].len;
            }
            let index = (0..D).map(|a| axes[a].index[k[a]] * stride[a]).sum();
            let value = (0..D).map(|a| axes[a].w[k[a]]).product();
            row.indices.push(index);
            row.values.push(value);
            if with_gradients {
                row.gradients.push(std::array::from_fn(|b| {
                    (0..D)
                        .map(|a| {
                            if a == b {
                                axes[a].d1[k[a]] / spacing[a]
                            } else {
                                axes[a].w[k[a]]
                            }
                        })
                        .product()
                }));
            }
        }
    }
}
