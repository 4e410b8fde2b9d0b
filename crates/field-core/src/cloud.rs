//! Point clouds: positions with optional normals.
//!
//! Normals follow zeroset's convention (see the [crate docs](crate)): they point **out** of the
//! solid, along `+∇f`. Readers never alter the data they read; [`PointCloud::stats`] reports what
//! a user should know before fitting (non-finite values, normals that are not unit length,
//! duplicate points).

use crate::error::{Error, Result};
use crate::geometry::{Aabb, Point, norm};

/// Positions, and optionally one normal per position, in `D` dimensions.
///
/// Invariant: when normals are present there is exactly one per position. Finiteness is checked
/// by [`PointCloud::new`] and [`PointCloud::with_normals`], and reported rather than enforced by
/// [`PointCloud::from_raw`] (which `zeroset info` uses to count bad values).
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud<const D: usize> {
    positions: Vec<Point<D>>,
    normals: Option<Vec<Point<D>>>,
}

/// A point cloud in space.
pub type PointCloud3 = PointCloud<3>;
/// A point set in the plane.
pub type PointCloud2 = PointCloud<2>;

/// What [`PointCloud::stats`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct CloudStats<const D: usize> {
    /// Number of points.
    pub count: usize,
    /// Bounding box of the points whose coordinates are all finite (`None` if there are none).
    pub bounds: Option<Aabb<D>>,
    /// Whether normals are present.
    pub has_normals: bool,
    /// Points with a NaN or infinite coordinate.
    pub non_finite_positions: usize,
    /// Normals with a NaN or infinite component.
    pub non_finite_normals: usize,
    /// Finite normals whose length differs from 1 by more than [`CloudStats::UNIT_TOLERANCE`].
    pub non_unit_normals: usize,
    /// Shortest and longest finite normal (`None` without normals).
    pub normal_length_range: Option<(f64, f64)>,
    /// Normals that are the zero vector (`0 0 0`: what some writers put where a point has no
    /// normal; counted among [`non_unit_normals`](Self::non_unit_normals) too).
    pub zero_normals: usize,
    /// Points whose position exactly equals that of an earlier point.
    pub duplicate_points: usize,
}

impl<const D: usize> CloudStats<D> {
    /// Tolerance on `| ‖n‖ − 1 |` for a normal to count as unit length: loose enough for normals
    /// printed with 7 significant digits or stored as `float`.
    pub const UNIT_TOLERANCE: f64 = 1e-4;
}

impl<const D: usize> PointCloud<D> {
    /// A cloud of positions without normals.
    ///
    /// # Errors
    /// [`Error::EmptyCloud`] for no points, [`Error::NonFinite`] naming the first bad record.
    pub fn new(positions: Vec<Point<D>>) -> Result<Self> {
        let cloud = Self::from_raw(positions, None)?;
        cloud.validate("input")?;
        Ok(cloud)
    }

    /// A cloud of positions with one normal each.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if the counts differ, [`Error::EmptyCloud`],
    /// [`Error::NonFinite`] naming the first bad record.
    pub fn with_normals(positions: Vec<Point<D>>, normals: Vec<Point<D>>) -> Result<Self> {
        let cloud = Self::from_raw(positions, Some(normals))?;
        cloud.validate("input")?;
        Ok(cloud)
    }

    /// A cloud exactly as given, checking only that there is one normal per position.
    ///
    /// Use [`PointCloud::validate`] before fitting, or [`PointCloud::stats`] to report problems.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if `normals` has a different length from `positions`.
    pub fn from_raw(positions: Vec<Point<D>>, normals: Option<Vec<Point<D>>>) -> Result<Self> {
        if let Some(n) = &normals
            && n.len() != positions.len()
        {
            return Err(Error::ShapeMismatch {
                what: "normals per position",
                expected: positions.len(),
                got: n.len(),
            });
        }
        Ok(Self { positions, normals })
    }

    /// Checks that the cloud is non-empty and every value is finite.
    ///
    /// # Errors
    /// [`Error::EmptyCloud`], or [`Error::NonFinite`] naming the first bad record, with
    /// `source_name` (a file name, or "input") in the message.
    pub fn validate(&self, source_name: &str) -> Result<()> {
        if self.positions.is_empty() {
            return Err(Error::EmptyCloud);
        }
        const POS: [&str; 3] = ["x", "y", "z"];
        const NRM: [&str; 3] = ["nx", "ny", "nz"];
        let check = |points: &[Point<D>], names: &[&'static str; 3]| -> Result<()> {
            for (record, p) in points.iter().enumerate() {
                if let Some(axis) = p.iter().position(|v| !v.is_finite()) {
                    return Err(Error::NonFinite {
                        source_name: source_name.to_owned(),
                        record,
                        line: None,
                        field: names[axis.min(2)],
                        value: p[axis],
                    });
                }
            }
            Ok(())
        };
        check(&self.positions, &POS)?;
        if let Some(n) = &self.normals {
            check(n, &NRM)?;
        }
        Ok(())
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether the cloud holds no point.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The positions.
    pub fn positions(&self) -> &[Point<D>] {
        &self.positions
    }

    /// The normals, if any.
    pub fn normals(&self) -> Option<&[Point<D>]> {
        self.normals.as_deref()
    }

    /// Consumes the cloud, returning positions and normals.
    pub fn into_parts(self) -> (Vec<Point<D>>, Option<Vec<Point<D>>>) {
        (self.positions, self.normals)
    }

    /// The bounding box of the finite points (`None` if there is none).
    pub fn bounds(&self) -> Option<Aabb<D>> {
        let finite: Vec<Point<D>> = self
            .positions
            .iter()
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .copied()
            .collect();
        Aabb::from_points(&finite)
    }

    /// Reverses every normal, for data whose normals point into the solid.
    pub fn flip_normals(&mut self) {
        if let Some(normals) = &mut self.normals {
            for n in normals {
                *n = n.map(|v| -v);
            }
        }
    }

    /// Scales every non-zero finite normal to unit length; returns how many could not be scaled
    /// (zero or non-finite), which are left as they were.
    pub fn normalize_normals(&mut self) -> usize {
        let mut skipped = 0;
        if let Some(normals) = &mut self.normals {
            for n in normals {
                let len = norm(n);
                if len > 0.0 && len.is_finite() {
                    *n = n.map(|v| v / len);
                } else {
                    skipped += 1;
                }
            }
        }
        skipped
    }

    /// Counts of everything worth knowing before a fit; see [`CloudStats`]. O(n log n).
    pub fn stats(&self) -> CloudStats<D> {
        let finite = |p: &Point<D>| p.iter().all(|v| v.is_finite());
        let non_finite_positions = self.positions.iter().filter(|p| !finite(p)).count();
        let (mut non_finite_normals, mut non_unit_normals, mut zero_normals) = (0, 0, 0);
        let mut range: Option<(f64, f64)> = None;
        if let Some(normals) = &self.normals {
            for n in normals {
                if !finite(n) {
                    non_finite_normals += 1;
                    continue;
                }
                let len = norm(n);
                if len == 0.0 {
                    zero_normals += 1;
                }
                if (len - 1.0).abs() > CloudStats::<D>::UNIT_TOLERANCE {
                    non_unit_normals += 1;
                }
                range = Some(match range {
                    None => (len, len),
                    Some((lo, hi)) => (lo.min(len), hi.max(len)),
                });
            }
        }
        CloudStats {
            count: self.positions.len(),
            bounds: self.bounds(),
            has_normals: self.normals.is_some(),
            non_finite_positions,
            non_finite_normals,
            non_unit_normals,
            normal_length_range: range,
            zero_normals,
            duplicate_points: count_duplicates(&self.positions),
        }
    }
}

/// Number of points equal (coordinate by coordinate, with `-0.0 == 0.0`) to an earlier point.
/// Points with a NaN coordinate never count as duplicates.
pub fn count_duplicates<const D: usize>(points: &[Point<D>]) -> usize {
    let mut keys: Vec<Point<D>> = points
        .iter()
        .filter(|p| !p.iter().any(|v| v.is_nan()))
        .map(|p| p.map(|v| if v == 0.0 { 0.0 } else { v }))
        .collect();
    let cmp = |a: &Point<D>, b: &Point<D>| {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.total_cmp(y))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    };
    keys.sort_unstable_by(cmp);
    keys.windows(2)
        .filter(|w| cmp(&w[0], &w[1]).is_eq())
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_count_problems() {
        let cloud = PointCloud::from_raw(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 0.0, -0.0],
                [f64::NAN, 0.0, 0.0],
            ],
            Some(vec![
                [1.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 1.0],
            ]),
        )
        .unwrap();
        let s = cloud.stats();
        assert_eq!(s.count, 4);
        assert_eq!(s.non_finite_positions, 1);
        assert_eq!(s.non_unit_normals, 2);
        assert_eq!(s.zero_normals, 1);
        assert_eq!(s.duplicate_points, 1);
        assert_eq!(s.normal_length_range, Some((0.0, 2.0)));
        assert_eq!(s.bounds.unwrap().max(), [1.0, 0.0, 0.0]);
    }

    #[test]
    fn validate_names_the_record() {
        let err = PointCloud::new(vec![[0.0, 0.0], [0.0, f64::INFINITY]]).unwrap_err();
        assert!(
            matches!(
                err,
                Error::NonFinite {
                    record: 1,
                    field: "y",
                    ..
                }
            ),
            "{err}"
        );
        assert!(matches!(
            PointCloud::<3>::new(vec![]),
            Err(Error::EmptyCloud)
        ));
        assert!(matches!(
            PointCloud::with_normals(vec![[0.0; 3]], vec![]),
            Err(Error::ShapeMismatch { .. })
        ));
    }

    #[test]
    fn normals_flip_and_normalise() {
        let mut c =
            PointCloud::with_normals(vec![[0.0; 2]; 2], vec![[3.0, 4.0], [0.0, 0.0]]).unwrap();
        assert_eq!(c.normalize_normals(), 1);
        c.flip_normals();
        assert_eq!(c.normals().unwrap()[0], [-0.6, -0.8]);
    }
}
