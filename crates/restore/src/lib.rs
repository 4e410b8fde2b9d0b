//! # zeroset-restore
//!
//! Mask-based restoration of implicit surfaces (Ren–Fujita–Nakata 2022, "Interactive
//! restoration of three-dimensional implicit surface with irregular parts"). A field is
//! sampled on a grid; a box mask selects the part that went wrong; the samples inside are
//! rewritten and the whole grid is interpolated by a C¹ quadratic B-spline
//! ([`zeroset_bases::bspline`]), which is again a [`ScalarField`] — so restorations compose.
//!
//! - [`protrusion`] (§2.2): replace a protrusion by the least-squares solution of Laplace's
//!   equation with the Dirichlet ring of the mask and a Neumann slope α across the face the
//!   protrusion's base crosses. Exact and fast by default ([`laplace`]: a separable DST-I +
//!   Givens QR solve, no iteration), or any [`LeastSquaresSolver`](zeroset_field_core::lsq::LeastSquaresSolver).
//! - [`denoise`] (§2.3): resample the mask coarsely, interpolate, resample finely, interpolate.
//!
//! ```
//! use zeroset_field_core::analytic::Sphere;
//! use zeroset_field_core::geometry::Aabb;
//! use zeroset_field_core::grid::Grid;
//! use zeroset_field_core::mask::{BoxMask, Face, Side};
//! use zeroset_restore::{denoise::Denoise, protrusion::Protrusion};
//!
//! let grid = Grid::cell_centered(Aabb::centered_cube(1.0)?, [20, 20, 20])?;
//! let sphere = Sphere::new([0.0; 3], 0.6);
//! let top = BoxMask::from_corners(&grid, [-0.3, -0.3, 0.4], [0.3, 0.3, 0.9])?;
//! let side = BoxMask::from_corners(&grid, [0.3, -0.3, -0.3], [0.9, 0.3, 0.3])?;
//! let once = Protrusion::new(Face::new(2, Side::Lower)).apply(&sphere, &grid, &top)?;
//! let twice = Denoise::new([3, 3, 3]).apply(&once.field, &grid, &side)?;
//! assert_eq!(twice.field.grid().counts(), [20, 20, 20]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`ScalarField`]: zeroset_field_core::field::ScalarField

#![warn(missing_docs)]

pub mod denoise;
pub mod error;
mod index;
pub mod laplace;
pub mod protrusion;

pub use error::{RestoreError, Result};

use zeroset_bases::bspline::BSplineField;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::mask::BoxMask;

/// The cells along the longest axis of the grid a restoration samples a field on when the
/// field has no grid of its own (an RBF, neural or MRAS field, a point cloud's tangent-plane
/// field, a Python callable): [`sampling_grid`].
pub const SAMPLING_CELLS: usize = 64;

/// The cells [`sampling_grid`] adds beyond the field's box on every side. A scan's box touches
/// its surface (a bunny's ear tips are on the top face), and a mask must enclose a protrusion
/// with a ring of cells to spare: without the margin the tips outside the last mask cell would
/// stay behind as floating pieces, and the zero set would be cut open at the box.
pub const SAMPLING_MARGIN: usize = 3;

/// The cell-centred grid over `bounds` widened by [`SAMPLING_MARGIN`] cells on every side, with
/// [`SAMPLING_CELLS`] cells along the longest axis and the others in proportion
/// ([`zeroset_field_core::grid::cubic_counts`]): where `zeroset restore`, `zeroset studio` and
/// the Python `zeroset.restore` sample a field that has no grid of its own.
///
/// # Errors
/// As [`Grid::cell_centered`] (a box that is not finite).
pub fn sampling_grid(bounds: zeroset_field_core::geometry::Aabb<3>) -> Result<Grid<3>> {
    let longest = bounds.extent().into_iter().fold(0.0, f64::max);
    let cell = longest / (SAMPLING_CELLS - 2 * SAMPLING_MARGIN) as f64;
    let padded = bounds.expanded(SAMPLING_MARGIN as f64 * cell);
    Ok(Grid::cell_centered(
        padded,
        zeroset_field_core::grid::cubic_counts(&padded, SAMPLING_CELLS),
    )?)
}

/// The mask corners `a`, `b` cut to `grid`'s box on the axes where the mask reaches beyond it
/// but overlaps it, and those axes. A mask past the box on some axis (or with a NaN corner) is
/// left as it is there, for [`BoxMask::from_corners`] to refuse. `zeroset restore`, the studio
/// and the Python `zeroset.restore` cut masks so: the sampling grid's box is the field's plus
/// [`SAMPLING_MARGIN`] cells, which a user placing a mask does not see.
pub fn clamp_mask_corners<const D: usize>(
    grid: &Grid<D>,
    a: [f64; D],
    b: [f64; D],
) -> ([[f64; D]; 2], Vec<usize>) {
    let (min, max) = (grid.bounds().min(), grid.bounds().max());
    let mut corners = [a, b];
    let mut cut = Vec::new();
    for axis in 0..D {
        let (l, h) = (a[axis].min(b[axis]), a[axis].max(b[axis]));
        // (false for NaN: left for the mask's own error)
        let overlaps = l <= max[axis] && h >= min[axis];
        if overlaps && (l < min[axis] || h > max[axis]) {
            corners[0][axis] = l.max(min[axis]);
            corners[1][axis] = h.min(max[axis]);
            cut.push(axis);
        }
    }
    (corners, cut)
}

/// A restored field and the report of the restoration that made it.
#[derive(Debug, Clone)]
pub struct Restored<const D: usize, R> {
    /// The restored field: a quadratic B-spline (C¹) through the restored samples.
    pub field: BSplineField<D>,
    /// What the restoration did.
    pub report: R,
}

/// The restored samples `g` of `grid` interpolated by the quadratic B-spline (the paper's
/// Eqs. 6 and 9), and how long that took.
pub(crate) fn interpolate<const D: usize>(
    grid: &Grid<D>,
    g: Vec<f64>,
) -> Result<(BSplineField<D>, std::time::Duration)> {
    let start = std::time::Instant::now();
    let field = BSplineField::interpolate(*grid, g, zeroset_bases::bspline::Degree::Quadratic)?;
    Ok((field, start.elapsed()))
}

/// Checks what every restoration needs: at least 3 cells per axis, one finite sample per grid
/// point, a mask inside this grid that leaves something outside it.
pub(crate) fn check_samples<const D: usize>(
    grid: &Grid<D>,
    f: &[f64],
    mask: &BoxMask<D>,
) -> Result<()> {
    let counts = grid.counts();
    for (axis, &c) in counts.iter().enumerate() {
        if c < 3 {
            return Err(zeroset_field_core::Error::GridTooSmall {
                axis,
                needed: 3,
                got: c,
            }
            .into());
        }
    }
    if f.len() != grid.len() {
        return Err(zeroset_field_core::Error::ShapeMismatch {
            what: "samples of the grid",
            expected: grid.len(),
            got: f.len(),
        }
        .into());
    }
    if let Some(index) = f.iter().position(|v| !v.is_finite()) {
        return Err(RestoreError::NonFiniteSample {
            index,
            value: f[index],
        });
    }
    let (lo, hi) = (mask.lo(), mask.hi());
    for axis in 0..D {
        if mask.grid_counts()[axis] != counts[axis] {
            return Err(zeroset_field_core::Error::ShapeMismatch {
                what: "the samples on an axis of the grid the mask was made for (a mask for \
                       another grid, of another size: make it with BoxMask::from_corners on \
                       this one)",
                expected: counts[axis],
                got: mask.grid_counts()[axis],
            }
            .into());
        }
        if hi[axis] >= counts[axis] {
            return Err(zeroset_field_core::Error::MaskIndexOutOfRange {
                axis,
                lo: lo[axis],
                hi: hi[axis],
                len: counts[axis],
            }
            .into());
        }
    }
    if mask.len() == grid.len() {
        return Err(RestoreError::MaskCoversGrid);
    }
    Ok(())
}
