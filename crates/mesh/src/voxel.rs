//! The voxel size of a marching-cubes grid, from the bounding box of the model.
//!
//! The signed-marching-cubes paper (Appl. Sci. 2022, 12(4), 1792, §3) picks the voxel edge
//! `S_c` from a reference length `l0`: `S_c = 5·l0` for coarse accuracy, `l0` for general and
//! `0.3·l0` for fine ([`Detail`], [`voxel_size`]). Its formula for `l0`, with the box's axis
//! lengths sorted `l1 ≤ l2 ≤ l3`, reads
//!
//! ```text
//! l0 = 0.1·l2    if l3 < 0.1·l2
//! l0 = 0.05·l3   if 0.1·l2 ≤ l3 ≤ 0.5·l2
//! l0 = 0.025·l3  if l3 > 0.5·l2
//! ```
//!
//! As printed only the last case can fire (`l3 ≥ l2`), and the cases do not meet where they
//! change (a jump by a factor of 20 at `l3 = 0.1·l2`, 2 at `l3 = 0.5·l2`). Its intent is
//! evidently to use finer voxels for flat (thin) bodies, so [`l0`] reads the comparison as one
//! between the **shortest** axis `l1` and the longest `l3`, and keeps the printed coefficients:
//!
//! ```text
//! l0 = clamp(0.05·l1, 0.005·l3, 0.025·l3)
//!    = 0.025·l3   if l1 ≥ 0.5·l3     (a chunky box: 40 general voxels along the longest axis)
//!    = 0.05·l1    if 0.1·l3 ≤ l1 ≤ 0.5·l3   (20 general voxels across the thickness)
//!    = 0.005·l3   if l1 ≤ 0.1·l3     (a flat box: at most 200 along the longest axis)
//! ```
//!
//! The three branches meet where they change (`0.05·l1 = 0.025·l3` at `l1 = 0.5·l3`,
//! `0.05·l1 = 0.005·l3` at `l1 = 0.1·l3`) — `l0` is a clamp of continuous functions, so it is
//! continuous in the box, non-decreasing in each axis length, and scales with the box
//! (`l0(s·B) = s·l0(B)`). The middle axis `l2` does not enter. Callers who want another rule
//! pass their own voxel edge to [`grid_for`].
//!
//! ```
//! use zeroset_field_core::Aabb;
//! use zeroset_mesh::voxel::{Detail, grid_for, l0, voxel_size};
//!
//! let bounds = Aabb::new([0.0; 3], [2.0, 1.5, 1.0])?;
//! assert!((l0(&bounds) - 0.05).abs() < 1e-12); // 0.025·l3 = 0.05·l1
//! let h = voxel_size(&bounds, Detail::General);
//! let grid = grid_for(&bounds, h, 0.0)?;
//! assert_eq!(grid.counts(), [41, 31, 21]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use zeroset_field_core::{Aabb, Grid};

use crate::error::{MeshError, Result};

/// The accuracy classes of the paper's voxel-size rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Detail {
    /// `S_c = 5·l0`.
    Coarse,
    /// `S_c = l0`.
    #[default]
    General,
    /// `S_c = 0.3·l0`.
    Fine,
}

impl Detail {
    /// The voxel edge as a multiple of [`l0`]: 5, 1 or 0.3.
    pub fn factor(self) -> f64 {
        match self {
            Detail::Coarse => 5.0,
            Detail::General => 1.0,
            Detail::Fine => 0.3,
        }
    }
}

/// The reference length `l0 = clamp(0.05·l1, 0.005·l3, 0.025·l3)` of a box whose sorted axis
/// lengths are `l1 ≤ l2 ≤ l3`; see the [module docs](self) for the reading of the paper. Zero
/// for a box that is a point.
pub fn l0(bounds: &Aabb<3>) -> f64 {
    let mut e = bounds.extent();
    e.sort_by(f64::total_cmp);
    let (l1, l3) = (e[0], e[2]);
    (0.05 * l1).clamp(0.005 * l3, 0.025 * l3)
}

/// The voxel edge `S_c` for `detail`: `5·l0`, `l0` or `0.3·l0`.
pub fn voxel_size(bounds: &Aabb<3>, detail: Detail) -> f64 {
    detail.factor() * l0(bounds)
}

/// The voxel edge [`scan_voxel`] refines to, in median point spacings of the scan.
pub const SCAN_SPACINGS: f64 = 2.0;

/// The most voxels along the box's longest axis [`scan_voxel`] refines to.
pub const SCAN_MAX_VOXELS: f64 = 512.0;

/// The finest voxel [`scan_voxel`] refines to, as a share of the smallest detail the field
/// holds: finer voxels only sample the same splines more densely.
pub const SCAN_DETAIL_SHARE: f64 = 0.5;

/// The voxel edge for meshing a field fitted to a scan whose median point spacing is
/// `spacing`, and which holds no detail smaller than `field_detail` (an MRAS field's finest
/// knot spacing; 0 where not known): `detail`'s voxel ([`voxel_size`]), or where the scan is
/// denser than that, [`SCAN_SPACINGS`] spacings — but no finer than [`SCAN_DETAIL_SHARE`] of
/// `field_detail`, nor than [`SCAN_MAX_VOXELS`] voxels along the box's longest axis (points
/// repeated with a jitter, as overlapping scans give, read as a spacing far below the
/// field's). Never coarser than `detail`'s voxel; [`scan_floor`] says which bound holds.
///
/// The `l0` rule sees the box only: fine voxels are 1/133 of a chunky box's longest axis
/// whether the scan has 35,000 points (the bunny: spacing 1.1 fine voxels) or a million (a
/// 100 mm ball sampled every 0.2 mm: a fine voxel spans 4.2 spacings), and on the denser scan the
/// mesh then loses what the field holds between the voxels. A `spacing` that is not finite
/// and positive leaves `detail`'s voxel.
///
/// ```
/// use zeroset_field_core::Aabb;
/// use zeroset_mesh::voxel::{Detail, scan_voxel, voxel_size};
///
/// let ball = Aabb::new([-50.0; 3], [50.0; 3])?;
/// let fine = voxel_size(&ball, Detail::Fine); // 0.75
/// assert_eq!(scan_voxel(&ball, Detail::Fine, 1.0, 0.0), fine); // sparse: the l0 rule
/// assert_eq!(scan_voxel(&ball, Detail::Fine, 0.2, 0.0), 0.4); // dense: 2 spacings
/// assert_eq!(scan_voxel(&ball, Detail::Fine, 0.2, 1.0), 0.5); // half the field's detail
/// assert_eq!(scan_voxel(&ball, Detail::Fine, 0.01, 0.0), 100.0 / 512.0); // at most 512
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn scan_voxel(bounds: &Aabb<3>, detail: Detail, spacing: f64, field_detail: f64) -> f64 {
    let h = voxel_size(bounds, detail);
    if !(spacing.is_finite() && spacing > 0.0) {
        return h;
    }
    h.min((SCAN_SPACINGS * spacing).max(scan_floor(bounds, field_detail).0))
}

/// Which bound [`scan_voxel`] refines no further than.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScanFloor {
    /// [`SCAN_MAX_VOXELS`] along the longest axis.
    MaxVoxels,
    /// [`SCAN_DETAIL_SHARE`] of the field's smallest detail.
    FieldDetail,
}

/// The finest voxel [`scan_voxel`] takes for a field of smallest detail `field_detail` over
/// `bounds`, and which bound it is.
pub fn scan_floor(bounds: &Aabb<3>, field_detail: f64) -> (f64, ScanFloor) {
    let longest = bounds.extent().into_iter().fold(0.0, f64::max);
    let by_count = longest / SCAN_MAX_VOXELS;
    let by_detail = SCAN_DETAIL_SHARE * field_detail;
    if by_detail.is_finite() && by_detail > by_count {
        (by_detail, ScanFloor::FieldDetail)
    } else {
        (by_count, ScanFloor::MaxVoxels)
    }
}

/// Which rule gave [`default_voxel`]'s edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VoxelRule {
    /// The `detail` class's voxel ([`voxel_size`]): no spacing was measured, or the scan is no
    /// denser than that voxel.
    Detail,
    /// [`SCAN_SPACINGS`] × the scan's median spacing (the value held).
    Spacing(f64),
    /// A floor of [`scan_floor`] (which one): [`SCAN_SPACINGS`] × the scan's median
    /// `spacing` would be finer still.
    Floor {
        /// The scan's median spacing.
        spacing: f64,
        /// The bound that holds.
        floor: ScanFloor,
    },
}

/// The default voxel edge for a field of smallest detail `field_detail` fitted to a scan, and
/// the rule that gave it: [`scan_voxel`] of the spacing `measure` returns (the scan's median
/// point spacing; `None` where there is no scan to measure), or `detail`'s voxel. `measure` is
/// called only where a finer voxel could follow — not where [`scan_floor`] is already no finer
/// than `detail`'s voxel (a smooth field): measuring a scan's spacing is the costly part (about
/// 2 s for 10⁶ points).
///
/// ```
/// use zeroset_field_core::Aabb;
/// use zeroset_mesh::voxel::{default_voxel, Detail, ScanFloor, VoxelRule};
///
/// let ball = Aabb::new([-50.0; 3], [50.0; 3])?;
/// let (edge, rule) = default_voxel(&ball, Detail::Fine, 0.0, || Some(0.2));
/// assert_eq!((edge, rule), (0.4, VoxelRule::Spacing(0.2)));
/// let (edge, rule) = default_voxel(&ball, Detail::Fine, 1.0, || Some(0.2));
/// assert_eq!((edge, rule), (0.5, VoxelRule::Floor { spacing: 0.2, floor: ScanFloor::FieldDetail }));
/// // A field whose finest knots are 4 apart: no voxel finer than fine follows, nothing measured.
/// let (_, rule) = default_voxel(&ball, Detail::Fine, 4.0, || unreachable!());
/// assert_eq!(rule, VoxelRule::Detail);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn default_voxel(
    bounds: &Aabb<3>,
    detail: Detail,
    field_detail: f64,
    measure: impl FnOnce() -> Option<f64>,
) -> (f64, VoxelRule) {
    let by_detail = voxel_size(bounds, detail);
    let (floor, which) = scan_floor(bounds, field_detail);
    if floor >= by_detail {
        return (by_detail, VoxelRule::Detail);
    }
    let Some(spacing) = measure().filter(|s| s.is_finite() && *s > 0.0) else {
        return (by_detail, VoxelRule::Detail);
    };
    let h = scan_voxel(bounds, detail, spacing, field_detail);
    let rule = if h >= by_detail {
        VoxelRule::Detail
    } else if h <= SCAN_SPACINGS * spacing {
        VoxelRule::Spacing(spacing)
    } else {
        VoxelRule::Floor {
            spacing,
            floor: which,
        }
    };
    (h, rule)
}

/// The most samples [`grid_for`] makes: `2^48` (2 PiB of `f64` samples), far past any memory,
/// so that sample counts and byte estimates never overflow.
pub const MAX_SAMPLES: u64 = 1 << 48;

/// A vertex-centred grid of cubic voxels (square cells in 2-D) of edge `voxel` covering `bounds`
/// grown by `margin` on every side: `⌈extent/voxel⌉` voxels per axis (at least one), centred on the box, so the
/// grid reaches past the grown box by less than a voxel per axis (and falls short of it by at
/// most a relative `1e-12` when the extent is a whole number of voxels up to rounding).
///
/// # Errors
/// - [`MeshError::InvalidSize`] if `voxel` is not finite and positive, or `margin` is negative
///   or not finite;
/// - [`MeshError::GridTooLarge`] if the grid would hold more than [`MAX_SAMPLES`] samples.
pub fn grid_for<const D: usize>(bounds: &Aabb<D>, voxel: f64, margin: f64) -> Result<Grid<D>> {
    if !(voxel.is_finite() && voxel > 0.0) {
        return Err(MeshError::InvalidSize {
            what: "voxel size",
            value: voxel,
        });
    }
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(MeshError::InvalidSize {
            what: "grid margin (finite, non-negative)",
            value: margin,
        });
    }
    let grown = bounds.expanded(margin);
    let cells = cells_for(&grown, voxel)?;
    let centre = grown.center();
    let min = std::array::from_fn(|a| centre[a] - 0.5 * cells[a] as f64 * voxel);
    let max = std::array::from_fn(|a| centre[a] + 0.5 * cells[a] as f64 * voxel);
    let covering = Aabb::new(min, max)?;
    Ok(Grid::vertex_centered(covering, cells.map(|c| c + 1))?)
}

/// A vertex-centred grid whose outer samples lie on the faces of `bounds`: `⌈extent/voxel⌉`
/// voxels per axis (at least one), each axis's spacing its extent over its count — at most
/// `voxel`, so the voxels are nearly but not exactly cubic. For capping a surface on a box of
/// one's choosing ([`McOptions::close_boundary`](crate::McOptions::close_boundary)), where
/// [`grid_for`]'s overhang would put the caps up to a voxel off it.
///
/// ```
/// use zeroset_field_core::geometry::Aabb;
/// use zeroset_mesh::voxel::grid_spanning;
///
/// let grid = grid_spanning(&Aabb::new([0.0; 3], [1.0, 0.5, 0.26])?, 0.1)?;
/// assert_eq!(grid.bounds(), Aabb::new([0.0; 3], [1.0, 0.5, 0.26])?);
/// assert_eq!(grid.counts(), [11, 6, 4]);
/// assert!((grid.spacing()[2] - 0.26 / 3.0).abs() < 1e-15);
/// // A box flat along z spans nothing.
/// assert!(grid_spanning(&Aabb::new([0.0; 3], [1.0, 1.0, 0.0])?, 0.1).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`grid_for`]; [`MeshError::InvalidSize`] for `bounds` flat along an axis (no voxel
/// spans it).
pub fn grid_spanning<const D: usize>(bounds: &Aabb<D>, voxel: f64) -> Result<Grid<D>> {
    if !(voxel.is_finite() && voxel > 0.0) {
        return Err(MeshError::InvalidSize {
            what: "voxel size",
            value: voxel,
        });
    }
    if let Some(&flat) = bounds.extent().iter().find(|&&e| e.is_nan() || e <= 0.0) {
        return Err(MeshError::InvalidSize {
            what: "box extent along an axis (positive)",
            value: flat,
        });
    }
    let cells = cells_for(bounds, voxel)?;
    Ok(Grid::vertex_centered(*bounds, cells.map(|c| c + 1))?)
}

/// `⌈extent/voxel⌉` voxels per axis of `bounds` (at least one).
fn cells_for<const D: usize>(bounds: &Aabb<D>, voxel: f64) -> Result<[usize; D]> {
    let extent = bounds.extent();
    let too_large = || MeshError::GridTooLarge {
        voxel,
        extent: extent.to_vec(),
        limit: MAX_SAMPLES,
    };
    let mut cells = [0usize; D];
    let mut samples: u64 = 1;
    for axis in 0..D {
        // A ratio a rounding error above a whole number does not take another voxel.
        let n = (extent[axis] / voxel * (1.0 - 1e-12)).ceil().max(1.0);
        if n >= MAX_SAMPLES as f64 {
            return Err(too_large());
        }
        cells[axis] = n as usize;
        samples = samples
            .checked_mul(n as u64 + 1)
            .filter(|&s| s <= MAX_SAMPLES)
            .ok_or_else(too_large)?;
    }
    Ok(cells)
}

/// Bytes per grid sample while meshing: the `f64` sample and marching cubes' per-sample bits
/// (inside, crossed edges, sample vertices) and row bookkeeping, rounded up.
const BYTES_PER_SAMPLE: u64 = 12;

/// Bytes per mesh vertex: position and normal (48), about two triangles (24), and the
/// extraction's vertex ids and welding, rounded up.
const BYTES_PER_VERTEX: u64 = 128;

/// Surface vertices assumed per grid sample on a face of the box, summed over the three
/// face orientations: room for a surface of about four times the box's area.
const VERTICES_PER_FACE_SAMPLE: u64 = 4;

/// An upper estimate of the memory, in bytes, of [`mesh_field`](crate::cubes::mesh_field) on
/// `grid`: the samples (`12` bytes each) plus a mesh of `4·(nx·ny + ny·nz + nx·nz)` vertices at
/// `128` bytes each — a surface of about four times the box's area, which a smooth closed
/// surface inside the box rarely exceeds (a sphere touching the faces has under half). The
/// mesh of a very wrinkled surface can exceed it. Saturates instead of overflowing.
pub fn estimate_bytes(grid: &Grid<3>) -> u64 {
    let [nx, ny, nz] = grid.counts().map(|n| n as u64);
    let samples = nx.saturating_mul(ny).saturating_mul(nz);
    let faces = nx
        .saturating_mul(ny)
        .saturating_add(ny.saturating_mul(nz))
        .saturating_add(nx.saturating_mul(nz));
    samples.saturating_mul(BYTES_PER_SAMPLE).saturating_add(
        faces
            .saturating_mul(VERTICES_PER_FACE_SAMPLE)
            .saturating_mul(BYTES_PER_VERTEX),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(e: [f64; 3]) -> Aabb<3> {
        Aabb::new([-1.0, 2.0, 0.5], [e[0] - 1.0, e[1] + 2.0, e[2] + 0.5]).unwrap()
    }

    #[test]
    fn l0_follows_the_three_branches_and_ignores_axis_order() {
        // Chunky: 0.025·l3.
        assert!((l0(&boxed([4.0, 3.0, 2.5])) - 0.1).abs() < 1e-12);
        assert!((l0(&boxed([2.5, 4.0, 3.0])) - 0.1).abs() < 1e-12);
        // Middle: 0.05·l1.
        assert!((l0(&boxed([10.0, 5.0, 3.0])) - 0.15).abs() < 1e-12);
        // Flat: 0.005·l3, also for a box of zero thickness.
        assert!((l0(&boxed([10.0, 5.0, 0.5])) - 0.05).abs() < 1e-12);
        assert!((l0(&boxed([10.0, 0.0, 0.0])) - 0.05).abs() < 1e-12);
        assert_eq!(l0(&boxed([0.0; 3])), 0.0);
    }

    #[test]
    fn l0_is_continuous_monotone_and_homogeneous() {
        let f = |l1: f64| l0(&boxed([10.0, 7.0, l1]));
        // At the branch changes (l1 = 1 and l1 = 5) both sides agree.
        for at in [1.0, 5.0] {
            let (lo, hi) = (f(at - 1e-9), f(at + 1e-9));
            assert!((lo - hi).abs() < 1e-9, "{at}: {lo} vs {hi}");
        }
        let mut last = f(0.0);
        for k in 0..=100 {
            let v = f(k as f64 * 0.1);
            assert!(v >= last - 1e-15, "not monotone at {k}");
            assert!((v - last).abs() <= 0.05 * 0.1 + 1e-12, "jump at {k}");
            last = v;
        }
        let b = boxed([3.0, 1.0, 0.7]);
        let scaled = Aabb::new(b.min().map(|x| 3.0 * x), b.max().map(|x| 3.0 * x)).unwrap();
        assert!((l0(&scaled) - 3.0 * l0(&b)).abs() < 1e-12);
    }

    #[test]
    fn scan_voxel_refines_for_dense_scans_only_and_never_coarsens() {
        let chunky = boxed([4.0, 3.0, 2.5]);
        let fine = voxel_size(&chunky, Detail::Fine); // 0.03
        // Sparser than 2 spacings per fine voxel, or no spacing: the l0 rule.
        for s in [0.015, 0.1, f64::NAN, 0.0, -1.0, f64::INFINITY] {
            assert_eq!(scan_voxel(&chunky, Detail::Fine, s, 0.0), fine, "{s}");
        }
        assert_eq!(scan_voxel(&chunky, Detail::Fine, 0.01, 0.0), 0.02);
        // At most 512 voxels along the longest axis (4).
        assert_eq!(scan_voxel(&chunky, Detail::Fine, 1e-6, 0.0), 4.0 / 512.0);
        // A flat box whose fine voxels are already finer than that keeps them.
        let flat = boxed([10.0, 5.0, 0.5]);
        let flat_fine = voxel_size(&flat, Detail::Fine);
        assert!(flat_fine < 10.0 / 512.0);
        assert_eq!(scan_voxel(&flat, Detail::Fine, 1e-6, 0.0), flat_fine);
        // No finer than half the field's detail, where that is coarser than 1/512 of the box.
        assert_eq!(scan_voxel(&chunky, Detail::Fine, 1e-6, 0.05), 0.025);
        assert_eq!(scan_floor(&chunky, 0.05), (0.025, ScanFloor::FieldDetail));
        assert_eq!(
            scan_floor(&chunky, 0.01),
            (4.0 / 512.0, ScanFloor::MaxVoxels)
        );
        assert_eq!(scan_voxel(&chunky, Detail::Fine, 0.01, 0.01), 0.02);
        // Coarser details are refined the same way.
        assert_eq!(scan_voxel(&chunky, Detail::General, 0.01, 0.0), 0.02);
    }

    #[test]
    fn default_voxel_names_its_rule_and_measures_only_where_it_may_refine() {
        let chunky = boxed([4.0, 3.0, 2.5]);
        let fine = voxel_size(&chunky, Detail::Fine); // 0.03
        let calls = &std::cell::Cell::new(0);
        let measured = |s: Option<f64>| {
            move || {
                calls.set(calls.get() + 1);
                s
            }
        };
        // No scan, or none that a number can be read from: the l0 rule, measured once.
        for s in [None, Some(f64::NAN), Some(0.0)] {
            assert_eq!(
                default_voxel(&chunky, Detail::Fine, 0.0, measured(s)),
                (fine, VoxelRule::Detail)
            );
        }
        assert_eq!(calls.replace(0), 3);
        // A sparse scan keeps the l0 rule; a dense one gets 2 spacings, then the floors.
        assert_eq!(
            default_voxel(&chunky, Detail::Fine, 0.0, measured(Some(0.1))),
            (fine, VoxelRule::Detail)
        );
        assert_eq!(
            default_voxel(&chunky, Detail::Fine, 0.0, measured(Some(0.01))),
            (0.02, VoxelRule::Spacing(0.01))
        );
        assert_eq!(
            default_voxel(&chunky, Detail::Fine, 0.0, measured(Some(1e-6))),
            (
                4.0 / 512.0,
                VoxelRule::Floor {
                    spacing: 1e-6,
                    floor: ScanFloor::MaxVoxels
                }
            )
        );
        assert_eq!(
            default_voxel(&chunky, Detail::Fine, 0.05, measured(Some(0.01))),
            (
                0.025,
                VoxelRule::Floor {
                    spacing: 0.01,
                    floor: ScanFloor::FieldDetail
                }
            )
        );
        assert_eq!(calls.replace(0), 4);
        // Each agrees with `scan_voxel`.
        for (s, d) in [
            (0.1, 0.0),
            (0.01, 0.0),
            (1e-6, 0.0),
            (0.01, 0.05),
            (0.002, 0.01),
        ] {
            let (h, _) = default_voxel(&chunky, Detail::Fine, d, || Some(s));
            assert_eq!(h, scan_voxel(&chunky, Detail::Fine, s, d), "{s} {d}");
        }
        // A field whose finest knots are 2 fine voxels apart: nothing finer can follow, and
        // the scan is not measured.
        assert_eq!(
            default_voxel(&chunky, Detail::Fine, 2.0 * fine, measured(Some(1e-6))),
            (fine, VoxelRule::Detail)
        );
        assert_eq!(calls.get(), 0);
    }

    #[test]
    fn voxel_sizes_scale_with_detail() {
        let b = boxed([4.0, 3.0, 2.5]);
        assert!((voxel_size(&b, Detail::Coarse) - 0.5).abs() < 1e-12);
        assert!((voxel_size(&b, Detail::General) - 0.1).abs() < 1e-12);
        assert!((voxel_size(&b, Detail::Fine) - 0.03).abs() < 1e-12);
        assert_eq!(Detail::default(), Detail::General);
    }

    #[test]
    fn grid_covers_the_grown_box_with_cubic_voxels() {
        let b = boxed([1.0, 0.45, 0.0]);
        let g = grid_for(&b, 0.1, 0.05).unwrap();
        // Extents 1.1, 0.55, 0.1 → 11, 6, 1 voxels.
        assert_eq!(g.counts(), [12, 7, 2]);
        for s in g.spacing() {
            assert!((s - 0.1).abs() < 1e-12, "{s}");
        }
        let (gb, grown) = (g.bounds(), b.expanded(0.05));
        for a in 0..3 {
            assert!(gb.min()[a] <= grown.min()[a] + 1e-12);
            assert!(gb.max()[a] >= grown.max()[a] - 1e-12);
            assert!(gb.extent()[a] < grown.extent()[a] + 0.1 + 1e-12);
            assert!((gb.center()[a] - grown.center()[a]).abs() < 1e-12);
        }
        // A point box still gives one voxel per axis.
        assert_eq!(
            grid_for(&boxed([0.0; 3]), 0.1, 0.0).unwrap().counts(),
            [2; 3]
        );
    }

    #[test]
    fn grid_refuses_bad_voxels_and_huge_grids() {
        let b = boxed([1.0; 3]);
        for v in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                grid_for(&b, v, 0.0),
                Err(MeshError::InvalidSize { .. })
            ));
        }
        assert!(matches!(
            grid_for(&b, 0.1, -1.0),
            Err(MeshError::InvalidSize { .. })
        ));
        for v in [1e-6, 1e-30, f64::MIN_POSITIVE] {
            let e = grid_for(&b, v, 0.0).unwrap_err();
            assert!(matches!(e, MeshError::GridTooLarge { .. }), "{e}");
            assert!(e.to_string().contains("larger voxel"), "{e}");
        }
    }

    #[test]
    fn memory_estimate_counts_samples_and_surface() {
        let g = grid_for(&boxed([1.0; 3]), 0.01, 0.0).unwrap();
        assert_eq!(g.counts(), [101; 3]);
        let n = 101u64;
        assert_eq!(estimate_bytes(&g), n * n * n * 12 + 3 * n * n * 4 * 128);
        // Grows like the samples.
        let fine = grid_for(&boxed([1.0; 3]), 0.005, 0.0).unwrap();
        assert!(estimate_bytes(&fine) > 4 * estimate_bytes(&g));
    }
}
