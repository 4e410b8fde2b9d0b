//! GemPy geology tables: surface points and orientations.
//!
//! [GemPy](https://www.gempy.org) (de la Varga, Schaaf & Wellmann, *GemPy 1.0*, Geosci. Model
//! Dev. 12, 2019) models geological surfaces as level sets of a potential field, fitted to two
//! tables:
//!
//! | Table | Columns read (any case, any order) | Record |
//! |---|---|---|
//! | surface points ("interfaces") | `X, Y, Z, formation` | [`SurfacePoint`] |
//! | orientations ("foliations") | `X, Y, Z, azimuth, dip, polarity, formation` | [`Orientation`] |
//!
//! `surface` is accepted in place of `formation` (GemPy's saved model tables use it). An
//! orientations table may give its poles as `G_x, G_y, G_z` (the gradient, as GemPy 3's
//! `read_orientations` reads them) instead of the angles; where it has both, they must agree
//! (within 1°; GemPy computes one from the other). Other columns, such as a leading unnamed
//! index, `X_r` or `series`, are ignored. A table with a `dip`, `azimuth` or `polarity` column,
//! or all of `G_x, G_y, G_z`, is an orientations table.
//!
//! ## Orientation convention
//!
//! `azimuth` is the dip direction in degrees clockwise from north (+y); `dip` is in degrees
//! down from the horizontal; `polarity` is +1 or −1. The unit normal
//! ([`orientation_normal`]) is
//!
//! ```text
//! n = p · (sin δ · sin α,  sin δ · cos α,  cos δ)
//! ```
//!
//! for dip δ, azimuth α and polarity p: the direction of GemPy's gradient `G_x, G_y, G_z` (the
//! potential field increases along it). Read into a [`PointCloud3`], it is the normal of the
//! point, so in zeroset's convention `n` points to the positive ("outside") side. A negative dip
//! (which GemPy files do contain) is used as it stands, as GemPy does.
//!
//! Coordinates are projected (easting, northing, elevation; metres in GemPy's examples). They
//! need no rescaling: the fits centre and scale coordinates themselves (an RBF fit in UTM
//! coordinates agrees with one in local coordinates to 1e-13 of the values), and PLY and OBJ
//! meshes are written in double precision (STL's single precision warns of the vertices it
//! moves).
//!
//! A table usually holds several formations (and faults), each its own surface: read it with
//! [`ReadOptions::formation`](super::ReadOptions::formation) to take one of them as a cloud.

use std::collections::BTreeMap;
use std::path::Path;

use super::table::{Table, find_column};
use super::{FiniteCheck, POSITION_FIELDS, RawPoints};
use crate::cloud::PointCloud3;
use crate::error::Result;
use crate::geometry::Point3;

const FORMATION: [&str; 2] = ["formation", "surface"];
const FORMATION_COLUMN: &str = "formation (or surface)";

/// A point on a geological boundary (an "interface").
#[derive(Debug, Clone, PartialEq)]
pub struct SurfacePoint {
    /// `X, Y, Z`.
    pub position: Point3,
    /// The formation (or fault) whose boundary the point lies on.
    pub formation: String,
}

/// A measured orientation of a boundary at a point.
#[derive(Debug, Clone, PartialEq)]
pub struct Orientation {
    /// `X, Y, Z`.
    pub position: Point3,
    /// The unit normal from `dip`, `azimuth` and `polarity` ([`orientation_normal`]), or the
    /// table's `G_x, G_y, G_z` normalised.
    pub normal: Point3,
    /// Degrees down from the horizontal (from `G_x, G_y, G_z`: in [0, 90]).
    pub dip: f64,
    /// Dip direction, degrees clockwise from north (+y) (from `G_x, G_y, G_z`: in [0, 360)).
    pub azimuth: f64,
    /// +1 or −1: which side of the boundary the normal points to (from `G_x, G_y, G_z`: the
    /// sign of `G_z`, +1 for a vertical layer).
    pub polarity: f64,
    /// The formation (or fault) measured.
    pub formation: String,
}

/// The input of a GemPy model: surface points and orientations.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GeoModelData {
    /// Points on the boundaries.
    pub surface_points: Vec<SurfacePoint>,
    /// Orientations of the boundaries.
    pub orientations: Vec<Orientation>,
}

/// How many records a formation has in each table; see [`GeoModelData::formation_counts`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FormationCount {
    /// The formation's name.
    pub name: String,
    /// Its surface points.
    pub surface_points: usize,
    /// Its orientations.
    pub orientations: usize,
}

impl GeoModelData {
    /// The formation names found in either table, sorted and without repeats.
    pub fn formations(&self) -> Vec<String> {
        self.formation_counts()
            .into_iter()
            .map(|c| c.name)
            .collect()
    }

    /// Record counts per formation, sorted by name.
    pub fn formation_counts(&self) -> Vec<FormationCount> {
        let mut counts: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
        for p in &self.surface_points {
            counts.entry(&p.formation).or_default().0 += 1;
        }
        for o in &self.orientations {
            counts.entry(&o.formation).or_default().1 += 1;
        }
        counts
            .into_iter()
            .map(|(name, (surface_points, orientations))| FormationCount {
                name: name.to_owned(),
                surface_points,
                orientations,
            })
            .collect()
    }

    /// The surface points as a cloud without normals.
    ///
    /// # Errors
    /// [`Error::EmptyCloud`](crate::Error::EmptyCloud) if there is none.
    pub fn surface_point_cloud(&self) -> Result<PointCloud3> {
        PointCloud3::new(self.surface_points.iter().map(|p| p.position).collect())
    }

    /// The orientations as a cloud with normals.
    ///
    /// # Errors
    /// [`Error::EmptyCloud`](crate::Error::EmptyCloud) if there is none.
    pub fn orientation_cloud(&self) -> Result<PointCloud3> {
        PointCloud3::with_normals(
            self.orientations.iter().map(|o| o.position).collect(),
            self.orientations.iter().map(|o| o.normal).collect(),
        )
    }
}

/// The unit normal of an orientation:
/// `polarity · (sin dip · sin azimuth, sin dip · cos azimuth, cos dip)`, angles in degrees,
/// azimuth clockwise from north (+y), dip down from the horizontal. See the
/// [module docs](self).
///
/// ```
/// use zeroset_field_core::io::gempy::orientation_normal;
/// // A layer dipping 90° towards the east has a horizontal normal pointing east (+x).
/// let n = orientation_normal(90.0, 90.0, 1.0);
/// assert!((n[0] - 1.0).abs() < 1e-12 && n[1].abs() < 1e-12 && n[2].abs() < 1e-12);
/// // A flat layer: the normal points up, or down for polarity −1.
/// assert_eq!(orientation_normal(0.0, 123.0, -1.0), [0.0, 0.0, -1.0]);
/// ```
pub fn orientation_normal(dip_deg: f64, azimuth_deg: f64, polarity: f64) -> Point3 {
    let (sd, cd) = dip_deg.to_radians().sin_cos();
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    [polarity * sd * sa, polarity * sd * ca, polarity * cd]
}

/// The inverse of [`orientation_normal`] for a pole `g` (any length, not zero): `(dip,
/// azimuth, polarity)` with the polarity the sign of `g_z` (+1 for `g_z = 0`), the dip in
/// [0, 90] and the azimuth in [0, 360); `None` for a zero or non-finite `g`.
///
/// ```
/// use zeroset_field_core::io::gempy::{orientation_angles, orientation_normal};
/// let (dip, azimuth, polarity) = orientation_angles([0.3, -0.4, -0.5]).unwrap();
/// let n = orientation_normal(dip, azimuth, polarity);
/// let norm = 0.5f64.sqrt();
/// assert!((n[0] - 0.3 / norm).abs() < 1e-12 && (n[2] + 0.5 / norm).abs() < 1e-12);
/// assert_eq!(polarity, -1.0);
/// ```
pub fn orientation_angles(g: Point3) -> Option<(f64, f64, f64)> {
    let norm = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    let polarity = if g[2] < 0.0 { -1.0 } else { 1.0 };
    let m = g.map(|c| polarity * c / norm);
    let dip = m[2].clamp(-1.0, 1.0).acos().to_degrees();
    let azimuth = m[0].atan2(m[1]).to_degrees().rem_euclid(360.0);
    Some((dip, azimuth, polarity))
}

/// GemPy's gradient columns.
const GRADIENT: [&str; 3] = ["G_x", "G_y", "G_z"];

/// Whether a CSV header is a GemPy table: it names `formation` or `surface`, or two of `dip`,
/// `azimuth` and `polarity` (any case). (`G_x, G_y, G_z` without a formation column is a
/// plain CSV, which reads them as normals.)
pub fn is_gempy_header<S: AsRef<str>>(header: &[S]) -> bool {
    let header: Vec<String> = header
        .iter()
        .map(|h| h.as_ref().trim().to_owned())
        .collect();
    let has = |name: &str| find_column(&header, &[name]).is_some();
    let angles = ["dip", "azimuth", "polarity"]
        .iter()
        .filter(|n| has(n))
        .count();
    has("formation") || has("surface") || angles >= 2
}

/// Whether a header has all of `G_x, G_y, G_z`.
fn has_gradient(header: &[String]) -> bool {
    GRADIENT.iter().all(|n| find_column(header, &[n]).is_some())
}

/// Whether a header is an orientations table (a `dip`, `azimuth` or `polarity` column, or all
/// of `G_x, G_y, G_z`).
fn is_orientations_header(header: &[String]) -> bool {
    find_column(header, &["dip", "azimuth", "polarity"]).is_some() || has_gradient(header)
}

/// Reads a surface-points table (`X, Y, Z, formation`).
///
/// # Errors
/// [`Error::MissingColumn`](crate::Error::MissingColumn) for a missing `X`, `Y`, `Z` or
/// `formation`/`surface` column; [`Error::Malformed`](crate::Error::Malformed) for a value that is
/// not a number or an empty formation name, with its line; [`Error::NonFinite`](crate::Error::NonFinite);
/// [`Error::Io`](crate::Error::Io).
pub fn read_surface_points(path: impl AsRef<Path>) -> Result<Vec<SurfacePoint>> {
    let path = path.as_ref();
    let check = FiniteCheck { path, allow: false };
    surface_points(&mut Table::open(path)?, &check)
}

/// Reads an orientations table (`X, Y, Z, azimuth, dip, polarity, formation`, or `G_x, G_y,
/// G_z` in place of the angles), computing each normal with [`orientation_normal`] (or
/// normalising `G`).
///
/// # Errors
/// As [`read_surface_points`], for the columns `X, Y, Z, azimuth, dip, polarity, formation`; a
/// polarity other than ±1, a zero `G`, or `G` and the angles more than 1° apart are
/// [`Error::Malformed`](crate::Error::Malformed).
pub fn read_orientations(path: impl AsRef<Path>) -> Result<Vec<Orientation>> {
    let path = path.as_ref();
    let check = FiniteCheck { path, allow: false };
    orientations(&mut Table::open(path)?, &check)
}

/// Reads a model's two tables.
///
/// # Errors
/// See [`read_surface_points`] and [`read_orientations`].
pub fn read_gempy(
    points_path: impl AsRef<Path>,
    orientations_path: impl AsRef<Path>,
) -> Result<GeoModelData> {
    Ok(GeoModelData {
        surface_points: read_surface_points(points_path)?,
        orientations: read_orientations(orientations_path)?,
    })
}

/// Reads one table of either kind, telling them apart by the header (a `dip`, `azimuth` or
/// `polarity` column makes an orientations table); the other list is left empty.
///
/// # Errors
/// See [`read_surface_points`] and [`read_orientations`].
pub fn read_gempy_file(path: impl AsRef<Path>) -> Result<GeoModelData> {
    let path = path.as_ref();
    let check = FiniteCheck { path, allow: false };
    let mut table = Table::open(path)?;
    let mut data = GeoModelData::default();
    if is_orientations_header(table.header()) {
        data.orientations = orientations(&mut table, &check)?;
    } else {
        data.surface_points = surface_points(&mut table, &check)?;
    }
    Ok(data)
}

/// Reads either table as a cloud (normals for orientations), all rows or those of
/// `formation`, for [`read_point_cloud`](super::read_point_cloud).
pub(super) fn read_cloud(
    path: &Path,
    check: &FiniteCheck<'_>,
    formation: Option<&str>,
) -> Result<RawPoints> {
    let mut table = Table::open(path)?;
    let mut data = GeoModelData::default();
    if is_orientations_header(table.header()) {
        data.orientations = orientations(&mut table, check)?;
    } else {
        data.surface_points = surface_points(&mut table, check)?;
    }
    if let Some(name) = formation {
        let names = data.formations();
        if !names.iter().any(|n| n == name) {
            return Err(super::malformed(
                path,
                None,
                format!(
                    "no row of formation '{name}'; the table's formations: {}",
                    names.join(", ")
                ),
            ));
        }
        data.surface_points.retain(|p| p.formation == name);
        data.orientations.retain(|o| o.formation == name);
    }
    if data.orientations.is_empty() {
        let positions = data.surface_points.into_iter().map(|p| p.position);
        Ok((positions.collect(), None))
    } else {
        let positions = data.orientations.iter().map(|o| o.position).collect();
        let normals = data.orientations.into_iter().map(|o| o.normal).collect();
        Ok((positions, Some(normals)))
    }
}

fn position_columns(table: &Table) -> Result<[usize; 3]> {
    Ok([
        table.require(&["x"], "X")?,
        table.require(&["y"], "Y")?,
        table.require(&["z"], "Z")?,
    ])
}

fn formation(table: &Table, row: &super::table::Row, col: usize) -> Result<String> {
    let name = table.text(row, col);
    if name.is_empty() {
        return Err(super::malformed(
            table.path(),
            Some(row.line),
            format!("empty formation name in column '{}'", table.header()[col]),
        ));
    }
    Ok(name.to_owned())
}

fn surface_points(table: &mut Table, check: &FiniteCheck<'_>) -> Result<Vec<SurfacePoint>> {
    let pos = position_columns(table)?;
    let form = table.require(&FORMATION, FORMATION_COLUMN)?;
    let mut out = Vec::new();
    let what = format!("the surface points of {}", table.path().display());
    while let Some(row) = table.next_row()? {
        let position = table.numbers(&row, pos)?;
        check.check(row.record, Some(row.line), &POSITION_FIELDS, &position)?;
        crate::limits::grow(&mut out, 1, &what)?;
        out.push(SurfacePoint {
            position,
            formation: formation(table, &row, form)?,
        });
    }
    Ok(out)
}

/// The largest angle between a table's `G_x, G_y, G_z` and its dip, azimuth and polarity.
const GRADIENT_AGREEMENT_DEG: f64 = 1.0;

fn orientations(table: &mut Table, check: &FiniteCheck<'_>) -> Result<Vec<Orientation>> {
    let pos = position_columns(table)?;
    let gradient = if has_gradient(table.header()) {
        let g = GRADIENT.map(|n| table.find(&[n]));
        Some([g[0], g[1], g[2]].map(|c| c.unwrap_or_default()))
    } else {
        None
    };
    let with_gradient = |name: &'static str| {
        if gradient.is_some() {
            Ok(table.find(&[name]))
        } else {
            table
                .require(&[name], &format!("{name} (or G_x, G_y, G_z)"))
                .map(Some)
        }
    };
    let angles = [
        with_gradient("dip")?,
        with_gradient("azimuth")?,
        with_gradient("polarity")?,
    ];
    // Without G all three angles are required (above); with it, the angles are read (and
    // checked against G) when all three are there.
    let angles = match angles {
        [Some(d), Some(a), Some(p)] => Some([d, a, p]),
        _ => None,
    };
    let form = table.require(&FORMATION, FORMATION_COLUMN)?;
    let mut out = Vec::new();
    let what = format!("the orientations of {}", table.path().display());
    while let Some(row) = table.next_row()? {
        let position = table.numbers(&row, pos)?;
        check.check(row.record, Some(row.line), &POSITION_FIELDS, &position)?;
        let from_angles = match angles {
            Some(cols) => {
                let [dip, azimuth, polarity] = table.numbers(&row, cols)?;
                check.check(
                    row.record,
                    Some(row.line),
                    &["dip", "azimuth", "polarity"],
                    &[dip, azimuth, polarity],
                )?;
                if polarity.is_finite() && polarity.abs() != 1.0 {
                    return Err(super::malformed(
                        table.path(),
                        Some(row.line),
                        format!("polarity must be 1 or -1, found {polarity}"),
                    ));
                }
                Some((dip, azimuth, polarity))
            }
            None => None,
        };
        let from_gradient = match gradient {
            Some(cols) => {
                let g = table.numbers(&row, cols)?;
                check.check(row.record, Some(row.line), &GRADIENT, &g)?;
                if g.iter().any(|c| !c.is_finite()) {
                    // Allowed non-finite: the normal is what the angles give, or NaN.
                    Some((g, None))
                } else {
                    let Some(angles) = orientation_angles(g) else {
                        return Err(super::malformed(
                            table.path(),
                            Some(row.line),
                            "G_x, G_y, G_z is the zero vector: it gives no orientation",
                        ));
                    };
                    Some((g, Some(angles)))
                }
            }
            None => None,
        };
        let (dip, azimuth, polarity) = match (from_angles, from_gradient) {
            // Non-finite angles (allowed by the options) give way to a finite G.
            (Some(a), Some((_, Some(from_g))))
                if ![a.0, a.1, a.2].iter().all(|x| x.is_finite()) =>
            {
                from_g
            }
            (Some(a), Some((g, Some(_)))) => {
                let n = orientation_normal(a.0, a.1, a.2);
                let norm = g.iter().map(|c| c * c).sum::<f64>().sqrt();
                let cos = (n[0] * g[0] + n[1] * g[1] + n[2] * g[2]) / norm;
                let apart = cos.clamp(-1.0, 1.0).acos().to_degrees();
                if apart > GRADIENT_AGREEMENT_DEG {
                    return Err(super::malformed(
                        table.path(),
                        Some(row.line),
                        format!(
                            "G_x, G_y, G_z ({}, {}, {}) and dip {}, azimuth {}, polarity {} are \
                             {apart:.1}° apart; GemPy computes one from the other, so one of \
                             them is wrong (drop the columns you do not trust)",
                            g[0], g[1], g[2], a.0, a.1, a.2
                        ),
                    ));
                }
                a
            }
            (Some(a), _) => a,
            (None, Some((_, Some(a)))) => a,
            (None, _) => (f64::NAN, f64::NAN, f64::NAN),
        };
        crate::limits::grow(&mut out, 1, &what)?;
        out.push(Orientation {
            position,
            normal: orientation_normal(dip, azimuth, polarity),
            dip,
            azimuth,
            polarity,
            formation: formation(table, &row, form)?,
        });
    }
    Ok(out)
}
