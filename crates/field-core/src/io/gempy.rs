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
//! `surface` is accepted in place of `formation` (GemPy's saved model tables use it); other
//! columns, such as a leading unnamed index, `X_r`, `series` or `G_x, G_y, G_z`, are ignored.
//! A table with a `dip`, `azimuth` or `polarity` column is an orientations table.
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
//! Coordinates are projected (easting, northing, elevation; metres in GemPy's examples) and
//! large: rescale before fitting.

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
    /// The unit normal from `dip`, `azimuth` and `polarity` ([`orientation_normal`]).
    pub normal: Point3,
    /// Degrees down from the horizontal.
    pub dip: f64,
    /// Dip direction, degrees clockwise from north (+y).
    pub azimuth: f64,
    /// +1 or −1: which side of the boundary the normal points to.
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

/// Whether a CSV header is a GemPy table: it names `formation` or `surface`, or all of `dip`,
/// `azimuth` and `polarity` (any case).
pub fn is_gempy_header<S: AsRef<str>>(header: &[S]) -> bool {
    let header: Vec<String> = header
        .iter()
        .map(|h| h.as_ref().trim().to_owned())
        .collect();
    let has = |name: &str| find_column(&header, &[name]).is_some();
    has("formation") || has("surface") || (has("dip") && has("azimuth") && has("polarity"))
}

/// Whether a header is an orientations table (it has a `dip`, `azimuth` or `polarity` column).
fn is_orientations_header(header: &[String]) -> bool {
    find_column(header, &["dip", "azimuth", "polarity"]).is_some()
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

/// Reads an orientations table (`X, Y, Z, azimuth, dip, polarity, formation`), computing each
/// normal with [`orientation_normal`].
///
/// # Errors
/// As [`read_surface_points`], for the columns `X, Y, Z, azimuth, dip, polarity, formation`; a
/// polarity other than ±1 is [`Error::Malformed`](crate::Error::Malformed).
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

/// Reads either table as a cloud (normals for orientations), for
/// [`read_point_cloud`](super::read_point_cloud).
pub(super) fn read_cloud(path: &Path, check: &FiniteCheck<'_>) -> Result<RawPoints> {
    let mut table = Table::open(path)?;
    if is_orientations_header(table.header()) {
        let o = orientations(&mut table, check)?;
        let positions = o.iter().map(|o| o.position).collect();
        let normals = o.into_iter().map(|o| o.normal).collect();
        Ok((positions, Some(normals)))
    } else {
        let p = surface_points(&mut table, check)?;
        Ok((p.into_iter().map(|p| p.position).collect(), None))
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

fn orientations(table: &mut Table, check: &FiniteCheck<'_>) -> Result<Vec<Orientation>> {
    let pos = position_columns(table)?;
    let angles = [
        table.require(&["dip"], "dip")?,
        table.require(&["azimuth"], "azimuth")?,
        table.require(&["polarity"], "polarity")?,
    ];
    let form = table.require(&FORMATION, FORMATION_COLUMN)?;
    let mut out = Vec::new();
    let what = format!("the orientations of {}", table.path().display());
    while let Some(row) = table.next_row()? {
        let position = table.numbers(&row, pos)?;
        check.check(row.record, Some(row.line), &POSITION_FIELDS, &position)?;
        let [dip, azimuth, polarity] = table.numbers(&row, angles)?;
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
