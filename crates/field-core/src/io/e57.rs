//! ASTM E57, the format terrestrial laser scanners (FARO, Leica, Trimble, Z+F) and
//! photogrammetry exports write, read with the [`e57`] crate.
//!
//! An E57 file holds one or more scans (the `data3D` list), each with its own pose: a unit
//! quaternion `q = (w, x, y, z)` and a translation `t` that take the scan's own coordinates
//! `p` to the file's common frame, `R(q) p + t` (ASTM E2807 §8.4.8). All of them are read, in
//! file order, into one cloud in that common frame:
//!
//! - Positions: `cartesianX/Y/Z` (floats or scaled integers, converted with their scale and
//!   offset), or where a scan has no Cartesian coordinates, `sphericalRange`, `Azimuth` and
//!   `Elevation` `(r, θ, φ)`: `(r cos φ cos θ, r cos φ sin θ, r sin φ)` (§8.4.20).
//! - A record whose `cartesianInvalidState` or `sphericalInvalidState` (whichever the scan
//!   has, both where it has both) is not 0 is left out: 1 is a direction without a range (a
//!   beam that returned nothing), 2 no coordinate at all. Scanners write such records to keep
//!   their row/column grid.
//! - Normals: the surface-normals extension (`normalX normalY normalZ`, namespace
//!   [`NORMALS_URI`], written by libE57Format's simple API and CloudCompare under the prefix
//!   `nor`; fields of those names under another namespace are not normals and are skipped),
//!   rotated by the scan's pose. Read when every scan has them; a file where some scans
//!   have normals and some do not is an [`Error::PartialNormals`](crate::Error::PartialNormals)
//!   naming the scans, unless only the positions are read.
//! - Intensity, colour, row/column indices, time stamps and images are skipped.
//! - Every page's CRC is checked by the crate; errors name the file. Scans whose records cannot
//!   all be in the file are an error: two naming one binary section, records of no bits, or
//!   more record bits than the file has. A pose whose quaternion
//!   is zero or not finite is an error naming the scan; one of any other length is normalised.
//!   A panic in the decoder (none known: fuzzing with each mutated file's page checksums
//!   repaired found none) would be reported as the file's error, not a crash.
//!
//! [`read_point_cloud`](super::read_point_cloud) gives the points; [`read_e57`] gives them with
//! what each scan held ([`Scan`]: its name, records, the points kept, its coordinates and its
//! origin in the file's frame, where a terrestrial scanner stood).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use e57::{E57Reader, PointCloud, RecordDataType, RecordName, RecordValue};

use super::{FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, ReadOptions};
use crate::cloud::PointCloud3;
use crate::error::Result;
use crate::geometry::Point3;
use crate::limits;

/// The namespace URI of the E57 surface-normals extension (libE57Format's
/// `E57_EXT_surface_normals`).
pub const NORMALS_URI: &str = "http://www.libe57.org/E57_EXT_surface_normals.txt";

/// The names of the normal's components in the surface-normals extension.
const NORMAL_RECORDS: [&str; 3] = ["normalX", "normalY", "normalZ"];

/// How a scan stores its points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coordinates {
    /// `cartesianX/Y/Z`.
    Cartesian,
    /// `sphericalRange/Azimuth/Elevation` (a scanner's own measurements).
    Spherical,
}

/// One scan of an E57 file, as [`read_e57`] read it.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// Its name, if the file gives one.
    pub name: Option<String>,
    /// The records the file announces for it.
    pub records: u64,
    /// The points kept: the records not flagged invalid.
    pub points: usize,
    /// How its points are stored (Cartesian where it has both).
    pub coordinates: Coordinates,
    /// Whether it has normals (the surface-normals extension).
    pub normals: bool,
    /// Whether the file gives it a pose (without one, its frame is the file's).
    pub posed: bool,
    /// Its own origin in the file's frame (its pose's translation): where a terrestrial
    /// scanner stood, when the scan is stored in the scanner's frame (spherical coordinates
    /// always are; Cartesian ones usually are when the file gives each scan a pose).
    pub origin: Point3,
}

/// The points of an E57 file (every scan, in file order) and what each scan held.
#[derive(Debug, Clone)]
pub struct E57Cloud {
    /// The points, scan after scan.
    pub cloud: PointCloud3,
    /// The scans, in file order; scan `i`'s [`Scan::points`] follow scan `i − 1`'s.
    pub scans: Vec<Scan>,
}

impl E57Cloud {
    /// For each point, the origin of the scan it came from ([`Scan::origin`]).
    pub fn origins(&self) -> Vec<Point3> {
        self.scans
            .iter()
            .flat_map(|scan| std::iter::repeat_n(scan.origin, scan.points))
            .collect()
    }
}

/// Reads an E57 file with each scan's summary; `options.format` is ignored (the file is read
/// as E57), the rest applies as for [`read_point_cloud_with`](super::read_point_cloud_with).
///
/// # Errors
/// As [`read_point_cloud_with`](super::read_point_cloud_with) for an E57 file.
pub fn read_e57(path: impl AsRef<Path>, options: &ReadOptions) -> Result<E57Cloud> {
    let path = path.as_ref();
    super::refuse_directory(path)?;
    let check = FiniteCheck {
        path,
        allow: options.allow_non_finite,
    };
    let ((positions, normals), scans) = read_with_scans(path, &check, !options.positions_only)?;
    if positions.is_empty() {
        return Err(super::malformed(path, None, "the file holds no point"));
    }
    Ok(E57Cloud {
        cloud: PointCloud3::from_raw(positions, normals)?,
        scans,
    })
}

/// Reads an E57 file (its normals too with `with_normals`, unchecked otherwise); see the
/// [module docs](self).
pub(super) fn read(path: &Path, check: &FiniteCheck<'_>, with_normals: bool) -> Result<RawPoints> {
    read_with_scans(path, check, with_normals).map(|(points, _)| points)
}

/// The points of an E57 file and its scans' summaries.
fn read_with_scans(
    path: &Path,
    check: &FiniteCheck<'_>,
    with_normals: bool,
) -> Result<(RawPoints, Vec<Scan>)> {
    let (file, len) = super::open_nonempty(path)?;
    super::guard_decoder(path, "E57", || {
        read_scans(path, (file, len), check, with_normals)
    })
}

/// Where a scan's fields are in its records.
struct Layout {
    /// `x y z`.
    cartesian: Option<[usize; 3]>,
    /// Range, azimuth, elevation.
    spherical: Option<[usize; 3]>,
    /// The invalid-state fields it has (`cartesianInvalidState`, `sphericalInvalidState`):
    /// a record is kept only where each of them is 0, whichever coordinates are read — both
    /// describe the same point, and a writer may flag it in either.
    states: Vec<usize>,
    normals: Option<[usize; 3]>,
}

impl Layout {
    /// Where `pc`'s fields are; the normals are the extension's fields under `normals`, the
    /// namespace prefix the file declares for [`NORMALS_URI`] (none without one).
    fn of(pc: &PointCloud, normals: Option<&str>) -> Self {
        let find = |name: &RecordName| pc.prototype.iter().position(|r| &r.name == name);
        let three = |names: [RecordName; 3]| match names.map(|n| find(&n)) {
            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
            _ => None,
        };
        let cartesian = three([
            RecordName::CartesianX,
            RecordName::CartesianY,
            RecordName::CartesianZ,
        ]);
        let spherical = three([
            RecordName::SphericalRange,
            RecordName::SphericalAzimuth,
            RecordName::SphericalElevation,
        ]);
        let states = [
            RecordName::CartesianInvalidState,
            RecordName::SphericalInvalidState,
        ]
        .iter()
        .filter_map(find)
        .collect();
        let normal = |name: &str| {
            pc.prototype.iter().position(|r| {
                matches!(&r.name, RecordName::Unknown { namespace, name: n }
                    if n == name && Some(namespace.as_str()) == normals)
            })
        };
        let normals = match NORMAL_RECORDS.map(normal) {
            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
            _ => None,
        };
        Self {
            cartesian,
            spherical,
            states,
            normals,
        }
    }
}

/// A scan's pose as a rotation matrix (rows) and a translation.
struct Pose {
    rotation: [[f64; 3]; 3],
    translation: [f64; 3],
}

impl Pose {
    /// The pose of `pc` (the identity if it has none); an error for a quaternion that is zero
    /// or not finite, or a translation that is not finite.
    fn of(pc: &PointCloud, scan: usize, path: &Path) -> Result<Self> {
        let Some(t) = &pc.transform else {
            return Ok(Self {
                rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                translation: [0.0; 3],
            });
        };
        let q = &t.rotation;
        // Scaled by its largest component first, so that any finite non-zero quaternion
        // normalises (its squares would overflow above 1e154 and vanish below 1e-162).
        let largest = [q.w, q.x, q.y, q.z]
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        let translation = [t.translation.x, t.translation.y, t.translation.z];
        let finite = |v: &[f64]| v.iter().all(|c| c.is_finite());
        if !(finite(&[q.w, q.x, q.y, q.z]) && largest > 0.0 && finite(&translation)) {
            return Err(super::malformed(
                path,
                None,
                format!(
                    "scan {scan}'s pose is not a rotation and translation: quaternion \
                     ({}, {}, {}, {}), translation ({}, {}, {})",
                    q.w, q.x, q.y, q.z, translation[0], translation[1], translation[2]
                ),
            ));
        }
        let [w, x, y, z] = [q.w, q.x, q.y, q.z].map(|v| v / largest);
        let norm = (w * w + x * x + y * y + z * z).sqrt();
        let [w, x, y, z] = [w, x, y, z].map(|v| v / norm);
        Ok(Self {
            rotation: [
                [
                    1.0 - 2.0 * (y * y + z * z),
                    2.0 * (x * y - w * z),
                    2.0 * (x * z + w * y),
                ],
                [
                    2.0 * (x * y + w * z),
                    1.0 - 2.0 * (x * x + z * z),
                    2.0 * (y * z - w * x),
                ],
                [
                    2.0 * (x * z - w * y),
                    2.0 * (y * z + w * x),
                    1.0 - 2.0 * (x * x + y * y),
                ],
            ],
            translation,
        })
    }

    fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        self.rotation
            .map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
    }

    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = self.rotate(p);
        [
            r[0] + self.translation[0],
            r[1] + self.translation[1],
            r[2] + self.translation[2],
        ]
    }
}

/// Checks that every scan has coordinates and, `with_normals`, normals in every scan or none;
/// returns whether they have normals (whether all do, where some do).
fn check_layouts(path: &Path, layouts: &[Layout], with_normals: bool) -> Result<bool> {
    if let Some(i) = layouts
        .iter()
        .position(|l| l.cartesian.is_none() && l.spherical.is_none())
    {
        return Err(super::malformed(
            path,
            None,
            format!(
                "scan {i} has neither Cartesian (cartesianX/Y/Z) nor spherical \
                 (sphericalRange/Azimuth/Elevation) coordinates"
            ),
        ));
    }
    let (with, without): (Vec<usize>, Vec<usize>) =
        (0..layouts.len()).partition(|&i| layouts[i].normals.is_some());
    if with_normals && !with.is_empty() && !without.is_empty() {
        return Err(crate::Error::PartialNormals {
            path: path.to_owned(),
            with,
            without,
        });
    }
    Ok(without.is_empty())
}

/// The bits one record of `pc` takes in its binary section (as the E57 bitpacked codec stores
/// it: floats whole, integers in `⌈log₂(max − min + 1)⌉` bits).
fn record_bits(pc: &PointCloud) -> u128 {
    pc.prototype
        .iter()
        .map(|r| match r.data_type {
            RecordDataType::Single { .. } => 32,
            RecordDataType::Double { .. } => 64,
            RecordDataType::ScaledInteger { min, max, .. }
            | RecordDataType::Integer { min, max } => {
                let range = i128::from(max) - i128::from(min);
                if range > 0 {
                    u128::from(range.ilog2()) + 1
                } else {
                    0
                }
            }
        })
        .sum()
}

/// Refuses scans whose records cannot all be in the file: two scans naming one binary section,
/// records of no bits at all (every field a constant: the decoder would produce them without
/// end), or more records than the file's bytes can hold — else a small file could announce
/// any number of points (thousands of scans naming one section, or sections whose headers all
/// point at one data area, read a 9.7 MB file as 20M points).
fn check_sections(path: &Path, scans: &[PointCloud], file_bytes: u64) -> Result<()> {
    let mut offsets: Vec<(u64, usize)> = scans
        .iter()
        .enumerate()
        .filter(|(_, pc)| pc.records > 0)
        .map(|(i, pc)| (pc.file_offset, i))
        .collect();
    offsets.sort_unstable();
    if let Some(w) = offsets.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(super::malformed(
            path,
            None,
            format!(
                "scans {} and {} name the same binary section (at byte {}): each scan's \
                 records are its own",
                w[0].1, w[1].1, w[0].0
            ),
        ));
    }
    let mut bits = 0u128;
    for (i, pc) in scans.iter().enumerate() {
        let each = record_bits(pc);
        if pc.records > 0 && each == 0 {
            return Err(super::malformed(
                path,
                None,
                format!("scan {i}'s records take no bits (every field is a constant)"),
            ));
        }
        bits += u128::from(pc.records) * each;
    }
    if bits > u128::from(file_bytes) * 8 {
        return Err(super::malformed(
            path,
            None,
            format!(
                "its scans announce {} records, {} bytes of data, more than the file's {file_bytes} \
                 bytes",
                scans.iter().map(|pc| pc.records).sum::<u64>(),
                bits.div_ceil(8)
            ),
        ));
    }
    Ok(())
}

/// Every scan's valid points (and normals, with `with_normals`), in the file's frame, and the
/// scans' summaries.
fn read_scans(
    path: &Path,
    (file, file_bytes): (File, u64),
    check: &FiniteCheck<'_>,
    with_normals: bool,
) -> Result<(RawPoints, Vec<Scan>)> {
    let bad = |e: e57::Error| {
        let reason = format!("not a readable E57 file: {e}");
        super::malformed(path, None, reason)
    };
    let mut reader = E57Reader::new(BufReader::with_capacity(1 << 16, file)).map_err(bad)?;
    let scans = reader.pointclouds();
    let extensions = reader.extensions();
    let prefix = extensions
        .iter()
        .find(|e| e.url == NORMALS_URI)
        .map(|e| e.namespace.as_str());
    let layouts: Vec<Layout> = scans.iter().map(|pc| Layout::of(pc, prefix)).collect();
    check_sections(path, &scans, file_bytes)?;
    let mut positions: Vec<Point3> = Vec::new();
    let has_normals = check_layouts(path, &layouts, with_normals)?;
    let mut normals: Option<Vec<Point3>> = (has_normals && with_normals).then(Vec::new);
    let what = format!("the points of {}", path.display());
    let mut record = 0usize;
    let mut summaries = Vec::with_capacity(scans.len());
    for (scan, (pc, layout)) in scans.iter().zip(&layouts).enumerate() {
        let pose = Pose::of(pc, scan, path)?;
        let before = positions.len();
        let types: Vec<RecordDataType> = pc.prototype.iter().map(|r| r.data_type.clone()).collect();
        let value = |values: &[RecordValue], at: usize| -> Result<f64> {
            let v = values.get(at).ok_or_else(|| {
                super::malformed(
                    path,
                    None,
                    format!("scan {scan}: a record is missing fields"),
                )
            })?;
            v.to_f64(&types[at]).map_err(bad)
        };
        for raw in reader.pointcloud_raw(pc).map_err(bad)? {
            let values = raw.map_err(bad)?;
            let here = record;
            record += 1;
            let mut flagged = false;
            for &at in &layout.states {
                flagged |= value(&values, at)? != 0.0;
            }
            if flagged {
                continue;
            }
            let local = match (layout.cartesian, layout.spherical) {
                (Some(at), _) => [
                    value(&values, at[0])?,
                    value(&values, at[1])?,
                    value(&values, at[2])?,
                ],
                (None, Some(at)) => {
                    let (r, azimuth, elevation) = (
                        value(&values, at[0])?,
                        value(&values, at[1])?,
                        value(&values, at[2])?,
                    );
                    [
                        r * elevation.cos() * azimuth.cos(),
                        r * elevation.cos() * azimuth.sin(),
                        r * elevation.sin(),
                    ]
                }
                // check_layouts refuses a scan without coordinates.
                (None, None) => continue,
            };
            check.check(here, None, &POSITION_FIELDS, &local)?;
            limits::grow(&mut positions, 1, &what)?;
            positions.push(pose.apply(local));
            if let (Some(normals), Some(at)) = (normals.as_mut(), layout.normals) {
                let n = [
                    value(&values, at[0])?,
                    value(&values, at[1])?,
                    value(&values, at[2])?,
                ];
                check.check(here, None, &NORMAL_FIELDS, &n)?;
                limits::grow(normals, 1, &what)?;
                normals.push(pose.rotate(n));
            }
        }
        summaries.push(Scan {
            name: pc.name.clone(),
            records: pc.records,
            points: positions.len() - before,
            coordinates: if layout.cartesian.is_some() {
                Coordinates::Cartesian
            } else {
                Coordinates::Spherical
            },
            normals: layout.normals.is_some(),
            posed: pc.transform.is_some(),
            origin: pose.translation,
        });
    }
    Ok(((positions, normals), summaries))
}

#[cfg(test)]
mod tests {
    use super::*;
    use e57::{Quaternion, Transform, Translation};

    fn cloud_with_pose(q: [f64; 4], t: [f64; 3]) -> PointCloud {
        let mut pc = PointCloud::default();
        pc.transform = Some(Transform {
            rotation: Quaternion {
                w: q[0],
                x: q[1],
                y: q[2],
                z: q[3],
            },
            translation: Translation {
                x: t[0],
                y: t[1],
                z: t[2],
            },
        });
        pc
    }

    #[test]
    fn a_pose_rotates_then_translates() {
        // A quarter turn about z (q = (cos 45°, 0, 0, sin 45°)), given at twice unit length.
        let h = std::f64::consts::FRAC_1_SQRT_2 * 2.0;
        let pc = cloud_with_pose([h, 0.0, 0.0, h], [1.0, 2.0, 3.0]);
        let pose = Pose::of(&pc, 0, Path::new("x.e57")).unwrap();
        let p = pose.apply([1.0, 0.0, 5.0]);
        for (got, want) in p.iter().zip([1.0, 3.0, 8.0]) {
            assert!((got - want).abs() < 1e-12, "{p:?}");
        }
        let n = pose.rotate([0.0, 1.0, 0.0]);
        for (got, want) in n.iter().zip([-1.0, 0.0, 0.0]) {
            assert!((got - want).abs() < 1e-12, "{n:?}");
        }
    }

    #[test]
    fn a_degenerate_pose_is_an_error_naming_the_scan() {
        for (q, t) in [
            ([0.0; 4], [0.0; 3]),
            ([f64::NAN, 0.0, 0.0, 0.0], [0.0; 3]),
            ([1.0, 0.0, 0.0, 0.0], [f64::INFINITY, 0.0, 0.0]),
        ] {
            let pc = cloud_with_pose(q, t);
            let e = Pose::of(&pc, 3, Path::new("x.e57")).err().unwrap();
            assert!(e.to_string().contains("scan 3's pose"), "{e}");
        }
    }
}
