//! `zeroset info FILE`: what a point-cloud file holds, and what to fix before fitting it; or,
//! for a `.zsf` field file, its kind (B-spline, RBF, MRAS or neural; 2-D or 3-D), box and
//! metadata; or, for a mesh (a PLY with a face element, an OBJ or an STL file), the mesh's
//! counts and `zeroset_mesh::checks` report.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::{Args, ValueEnum};
use zeroset_bases::field_file::{
    AnyField, is_field_file, read_any_field, read_dimension, read_metadata,
};
use zeroset_bases::outliers::{DEFAULT_OUTLIER_RATIO, MIN_POINTS_FOR_OUTLIERS, find_outliers};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::Point;
use zeroset_field_core::io::gempy::{self, GeoModelData};
use zeroset_field_core::io::{self, Format, ReadOptions};
use zeroset_field_core::{CloudStats, Error, PointCloud3};

/// Shown after `zeroset info --help`.
pub const EXAMPLES: &str = "\
Examples:
  zeroset info samples/bunny_2k.xyzn
  zeroset info scan.ply
  zeroset info points.dat --format csv
  zeroset info geology/greenstone/SandStone_Points.csv
  zeroset info bunny.zsf        # a field file: kind, box, kernel and centres, B-spline grid
                                # or network
  zeroset info bunny_mesh.ply   # a PLY with faces: triangles, boundary loops, Euler char., volume
  zeroset info part.stl         # an STL (or OBJ) mesh: the same report

NaN and infinite values do not stop the report: they are counted and the first is named
(record, line, field).";

/// Arguments of `zeroset info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The point-cloud file: .ply (ascii or binary), .pcd (PCL), .las/.laz (LiDAR), .e57
    /// (laser scans),
    /// .xyz/.xyzn/.txt/.pts/.asc/.pwn (x y z [nx ny nz] per line, or columns named by a first
    /// line), or .csv (header with x,y,z[,nx,ny,nz], or a GemPy table); a .zsf field file (told
    /// by its contents); a mesh: .ply with faces, .obj, .stl or .off; or value constraints
    /// (.xyv, .xyzv: x y [z] value per line, what `zeroset fit` interpolates).
    pub file: PathBuf,

    /// Read the file as this format instead of detecting it from the extension and header.
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,

    /// Accepted for symmetry with the other subcommands (info shows no progress spinner).
    #[arg(long)]
    pub quiet: bool,
}

/// The `--format` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// Stanford PLY.
    Ply,
    /// Text, one point per line.
    Xyz,
    /// CSV with a header row.
    Csv,
    /// A GemPy surface-points or orientations table.
    Gempy,
    /// The Point Cloud Library's PCD (ascii, binary or binary_compressed).
    Pcd,
    /// LiDAR LAS or LAZ.
    Las,
    /// ASTM E57 laser scans.
    E57,
    /// A 2-D value-constraint file: x y value per line.
    Xyv,
    /// A 3-D value-constraint file: x y z value per line.
    Xyzv,
}

impl FormatArg {
    /// The point-cloud format; `Err` with the dimension for a value-constraint file.
    fn cloud_format(self) -> Result<Format, usize> {
        Ok(match self {
            FormatArg::Ply => Format::Ply,
            FormatArg::Xyz => Format::Xyz,
            FormatArg::Csv => Format::Csv,
            FormatArg::Gempy => Format::GemPy,
            FormatArg::Pcd => Format::Pcd,
            FormatArg::Las => Format::Las,
            FormatArg::E57 => Format::E57,
            FormatArg::Xyv => return Err(2),
            FormatArg::Xyzv => return Err(3),
        })
    }
}

/// Reads the file and prints the report on stdout.
pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let report = report(args)?;
    let mut out = std::io::stdout().lock();
    match out.write_all(report.as_bytes()).and_then(|()| out.flush()) {
        // `zeroset info f | head` closes the pipe early: not an error.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.context("cannot write to stdout"),
    }
}

/// The report as text.
fn report(args: &InfoArgs) -> anyhow::Result<String> {
    let path = &args.file;
    // A `.zsf` file without the magic (empty, or cut short) is a broken field file: the field
    // reader says what is wrong with it, where the point-cloud readers would not know the
    // extension.
    let zsf = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("zsf"));
    if args.format.is_none() && (zsf || is_field_file(path)) {
        return field_report(path);
    }
    let format = args.format.map(FormatArg::cloud_format).transpose();
    let value_dimension = match format {
        Err(dimension) => Some(dimension),
        Ok(Some(_)) => None,
        Ok(None) => io::value_file_dimension(path),
    };
    match value_dimension {
        Some(2) => return value_report::<2>(path),
        Some(3) => return value_report::<3>(path),
        _ => {}
    }
    if args.format.is_none() {
        match zeroset_mesh::MeshFormat::from_path(path) {
            Some(zeroset_mesh::MeshFormat::Obj) => return mesh_report(path, "obj"),
            Some(zeroset_mesh::MeshFormat::Stl) => return mesh_report(path, "stl"),
            Some(zeroset_mesh::MeshFormat::Off) => return mesh_report(path, "off"),
            _ => {}
        }
    }
    let format = match format {
        Ok(Some(f)) => f,
        _ => io::detect_format(path).context("cannot tell the file's format")?,
    };
    if format == Format::Ply && zeroset_mesh::io::ply_face_count(path).is_some() {
        return mesh_report(path, "ply");
    }
    let mut options = ReadOptions::default().with_format(format);
    // An E57 file is read with its scans' summaries, in the same pass.
    let read = |options: &ReadOptions| {
        if format == Format::E57 {
            io::e57::read_e57(path, options).map(|e57| (e57.cloud, e57.scans))
        } else {
            io::read_point_cloud_with(path, options).map(|cloud| (cloud, Vec::new()))
        }
    };
    // Read strictly first, so that a non-finite value is named with its line; then read again
    // accepting it, to count them all. Columns 4–6 of an xyz file that are not normals
    // (colours): describe the positions and say why the rest is left out, rather than refuse
    // the file.
    let mut strict = read(&options);
    let mut not_normals = None;
    if let Err(e @ (Error::NotNormals { .. } | Error::PartialNormals { .. })) = strict {
        not_normals = Some(e);
        options = options.with_positions_only(true);
        strict = read(&options);
    }
    let ((cloud, scans), first_non_finite) = match strict {
        Ok(read) => (read, None),
        Err(e @ Error::NonFinite { .. }) => {
            let lenient = read(&options.clone().with_allow_non_finite(true))
                .context("cannot read point cloud")?;
            (lenient, Some(e))
        }
        Err(e) => return Err(anyhow::Error::new(e).context("cannot read point cloud")),
    };
    let geology = (format == Format::GemPy).then(|| gempy::read_gempy_file(path));

    let mut s = String::new();
    let stats = cloud.stats();
    line(&mut s, "file", &path.display().to_string());
    line(&mut s, "format", format.name());
    let n = stats.count;
    line(&mut s, "points", &format!("{n} point{}", plural(n)));
    if format == Format::E57 {
        write_scans(&mut s, &scans);
    }
    write_bounds(&mut s, &cloud);
    if let Some(Error::PartialNormals { with, without, .. }) = &not_normals {
        line(
            &mut s,
            "normals",
            &format!(
                "in {} of the {} scans only: not read; zeroset fit and restore refuse this file \
                 (zeroset normals and reconstruct estimate normals for every scan)",
                with.len(),
                with.len() + without.len()
            ),
        );
    } else {
        write_normals(&mut s, &stats);
    }
    if let Some(Error::NotNormals { colours, .. }) = &not_normals {
        line(
            &mut s,
            "columns 4–6",
            if *colours {
                "not read as normals: whole numbers from 0 to 255, as in RGB colours; zeroset fit \
                 and restore refuse this file (keep only x y z, or give unit normals)"
            } else {
                "not read as normals: their lengths are far from 1; zeroset fit and restore \
                 refuse this file (give unit normals)"
            },
        );
    }
    write_non_finite(&mut s, &stats, first_non_finite.as_ref());
    let dup = stats.duplicate_points;
    line(
        &mut s,
        "duplicates",
        &if dup == 0 {
            "none".to_owned()
        } else {
            format!(
                "{dup} point{} an earlier position",
                if dup == 1 { " repeats" } else { "s repeat" }
            )
        },
    );
    if let Some(normals) = cloud.normals()
        && stats.non_finite_positions + stats.non_finite_normals == 0
    {
        write_outliers(&mut s, cloud.positions(), normals);
    }
    if stats.non_finite_positions == 0 {
        let measured = crate::noise::measure(&cloud);
        line(
            &mut s,
            "noise",
            &measured.as_ref().map_or_else(
                || {
                    "not measured (fewer than 64 points, or too few neighbourhoods of 17 on one \
                     side of a surface)"
                        .to_owned()
                },
                |m| m.verdict(),
            ),
        );
        line(
            &mut s,
            "thickness",
            &crate::thickness::info_line(cloud.positions(), measured.as_ref().map(|m| &m.noise)),
        );
    }
    match geology {
        None => {}
        Some(Ok(data)) => write_formations(&mut s, &data),
        Some(Err(e)) => line(&mut s, "formations", &format!("not listed: {e}")),
    }
    Ok(s)
}

/// The stray points `zeroset fit` would set aside at the default `--outlier-ratio`.
fn write_outliers(s: &mut String, positions: &[Point<3>], normals: &[Point<3>]) {
    if positions.len() < MIN_POINTS_FOR_OUTLIERS {
        line(
            s,
            "outliers",
            &format!("not looked for (fewer than {MIN_POINTS_FOR_OUTLIERS} points)"),
        );
        return;
    }
    let ratio = DEFAULT_OUTLIER_RATIO;
    let found = find_outliers(positions, normals, ratio);
    let spacing = format!(
        "median spacing {} (mean distance to the 8 nearest)",
        g(found.median_spacing)
    );
    let k = found.indices.len();
    line(
        s,
        "outliers",
        &if k == 0 {
            format!("none; {spacing}")
        } else {
            format!(
                "{k} stray point{}, which zeroset fit sets aside: {} isolated (spacing > {}× \
                 the median, not on a surface with their neighbours), {} off a clean patch of \
                 surface with a normal of their own; {spacing}",
                plural(k),
                found.isolated,
                g(ratio),
                found.floating
            )
        },
    );
}

/// The report of a field file: kind, dimension, box, and the kind's particulars.
fn field_report(path: &Path) -> anyhow::Result<String> {
    match read_dimension(path).context("cannot read field file")? {
        2 => field_report_d::<2>(path),
        _ => field_report_d::<3>(path),
    }
}

fn field_report_d<const D: usize>(path: &Path) -> anyhow::Result<String> {
    let field = read_any_field::<D>(path).context("cannot read field file")?;
    let metadata = read_metadata(path).context("cannot read field file")?;
    let mut s = String::new();
    line(&mut s, "file", &path.display().to_string());
    line(&mut s, "format", "zeroset field file (.zsf)");
    line(&mut s, "kind", field.kind());
    line(&mut s, "dimension", &D.to_string());
    match &field {
        AnyField::BSpline(f) => {
            let c = f.grid().counts().map(|n| n.to_string());
            line(
                &mut s,
                "B-spline",
                &format!("{:?}, grid {}", f.degree(), c.join("×")),
            );
        }
        AnyField::Rbf(f) => {
            line(&mut s, "kernel", f.kernel_tag());
            line(&mut s, "centres", &f.num_centres().to_string());
        }
        AnyField::Neural(f) => {
            line(&mut s, "network", &f.network());
            line(&mut s, "parameters", &f.parameters().len().to_string());
        }
        AnyField::Mras(f) => mras_report(&mut s, f),
    }
    if let Some(b) = field.bounds() {
        line(&mut s, "bounds", &format!("min {}", point_n(&b.min())));
        more(&mut s, &format!("max {}", point_n(&b.max())));
    }
    for (i, (key, value)) in metadata.iter().enumerate() {
        let text = format!("{key} = {value}");
        if i == 0 {
            line(&mut s, "metadata", &text);
        } else {
            more(&mut s, &text);
        }
    }
    Ok(s)
}

/// Per level: cells, CP ranks, numbers stored and the uncompressed count (paper 004 §6.2) of
/// the stored cells (the file does not record the cells a fit left out because `φ = 0` met
/// its compression bound; `zeroset fit` counts those too).
fn mras_report<const D: usize>(s: &mut String, f: &zeroset_bases::mras::MrasField<D>) {
    line(
        s,
        "cube",
        &format!("origin {}, side {}", point_n(&f.origin()), g(f.side())),
    );
    line(
        s,
        "levels",
        "level  m  cells  ranks min/mean/max  full  stored  uncompressed",
    );
    for l in f.levels() {
        let ranks: Vec<usize> = l.cells().iter().filter_map(|c| c.spline.rank()).collect();
        let full = l.cells().len() - ranks.len();
        let r = if ranks.is_empty() {
            "-".to_owned()
        } else {
            format!(
                "{}/{:.1}/{}",
                ranks.iter().min().unwrap_or(&0),
                ranks.iter().sum::<usize>() as f64 / ranks.len() as f64,
                ranks.iter().max().unwrap_or(&0)
            )
        };
        more(
            s,
            &format!(
                "{:5} {:2} {:6}  {:>18}  {:4}  {:6}  {:12}",
                l.level(),
                l.knots(),
                l.cells().len(),
                r,
                full,
                l.stored_numbers() + l.cells().len() * (D + 1),
                l.uncompressed_numbers() + l.cells().len() * (D + 1)
            ),
        );
    }
    line(
        s,
        "storage",
        &format!(
            "{} numbers (the stored cells uncompressed: {}; {:.1}× smaller)",
            f.storage(),
            f.uncompressed_storage(),
            f.uncompressed_storage() as f64 / f.storage().max(1) as f64
        ),
    );
    let n = f.unit_points().len();
    line(
        s,
        "points",
        &if n == 0 {
            "none recorded (mesh --drop-spurious needs them)".to_owned()
        } else {
            format!(
                "{n} input point{} recorded (f32, for mesh's spurious-component check; not in \
                 the storage count)",
                plural(n)
            )
        },
    );
}

/// The report of a mesh (PLY with faces, OBJ, STL): counts and the `zeroset_mesh::checks`
/// report.
fn mesh_report(path: &Path, format: &str) -> anyhow::Result<String> {
    let mesh = zeroset_mesh::read_mesh(path).context("cannot read mesh")?;
    let r = zeroset_mesh::check(&mesh);
    let loops = zeroset_mesh::boundary_loops(&mesh);
    let mut s = String::new();
    line(&mut s, "file", &path.display().to_string());
    line(&mut s, "format", &format!("{format} (mesh)"));
    line(
        &mut s,
        "vertices",
        &format!("{}, {} used by triangles", r.vertices, r.used_vertices),
    );
    line(&mut s, "triangles", &r.triangles.to_string());
    if r.triangles == 0 {
        // An OBJ of vertices only (or an empty mesh): what the fitting commands make of it.
        line(
            &mut s,
            "points",
            &format!(
                "no triangle: zeroset fit, normals and reconstruct read the {} vertices as a \
                 point cloud{}",
                r.vertices,
                if mesh.normals().is_empty() {
                    " without normals"
                } else {
                    " with their normals"
                }
            ),
        );
        mesh_bounds(&mut s, &mesh);
        return Ok(s);
    }
    line(
        &mut s,
        "closed",
        if r.closed {
            "yes"
        } else {
            "no (boundary or non-manifold edges)"
        },
    );
    line(
        &mut s,
        "edges",
        &format!(
            "{}; {} boundary in {loops} loop{}, {} non-manifold, {} inconsistent",
            r.edges,
            r.boundary_edges,
            plural(loops),
            r.non_manifold_edges,
            r.inconsistent_edges
        ),
    );
    line(
        &mut s,
        "topology",
        &format!(
            "Euler characteristic {}, {} component{}",
            r.euler_characteristic,
            r.components,
            plural(r.components)
        ),
    );
    line(&mut s, "volume", &format!("signed {}", g(r.signed_volume)));
    line(&mut s, "area", &g(r.area));
    mesh_bounds(&mut s, &mesh);
    Ok(s)
}

/// The `bounds:` lines of a mesh report.
fn mesh_bounds(s: &mut String, mesh: &zeroset_mesh::TriMesh) {
    match mesh.bounds() {
        None => line(s, "bounds", "none (no vertex)"),
        Some(b) => corners(s, b.min(), b.max()),
    }
}

/// The `bounds:` min and max lines. Coordinates far from the origin (georeferenced) get the
/// decimals that resolve 10⁻⁴ of the box's diagonal, which 7 significant digits would hide.
fn corners(s: &mut String, lo: [f64; 3], hi: [f64; 3]) {
    let d = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
    let far = lo.iter().chain(&hi).map(|v| v.abs()).fold(0.0, f64::max) > 1e3 * d;
    let corner = |p: [f64; 3]| {
        if far && d > 0.0 {
            let decimals = (4 - d.log10().floor() as i32).clamp(0, 17) as usize;
            let parts: Vec<String> = p.iter().map(|v| format!("{v:.decimals$}")).collect();
            format!("({})", parts.join(", "))
        } else {
            point(p)
        }
    };
    line(s, "bounds", &format!("min {}", corner(lo)));
    more(s, &format!("max {}", corner(hi)));
}

const LABEL_WIDTH: usize = 12;

fn line(s: &mut String, label: &str, value: &str) {
    let label = format!("{label}:");
    let _ = writeln!(s, "{label:<LABEL_WIDTH$} {value}");
}

/// A continuation line, aligned under the values.
fn more(s: &mut String, value: &str) {
    let _ = writeln!(s, "{:<LABEL_WIDTH$} {value}", "");
}

pub(crate) fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}

/// An E57 file's scans: one row each.
fn write_scans(s: &mut String, scans: &[io::e57::Scan]) {
    use io::e57::Coordinates;
    let n = scans.len();
    line(
        s,
        "scans",
        &format!(
            "{n} scan{}, each moved into the file's frame by its pose; origin: the scan's own \
             origin there (where a terrestrial scanner stood)",
            plural(n)
        ),
    );
    more(
        s,
        " scan  records   points  coordinates  normals  pose  origin                    name",
    );
    for (i, scan) in scans.iter().enumerate() {
        let invalid = scan.records.saturating_sub(scan.points as u64);
        more(
            s,
            &format!(
                "{i:>5}  {:>7}  {:>7}  {:<11}  {:<7}  {:<4}  {:<24}  {}{}",
                scan.records,
                scan.points,
                match scan.coordinates {
                    Coordinates::Cartesian => "Cartesian",
                    Coordinates::Spherical => "spherical",
                },
                if scan.normals { "yes" } else { "no" },
                if scan.posed { "yes" } else { "no" },
                point(scan.origin),
                scan.name.as_deref().unwrap_or("-"),
                if invalid > 0 {
                    format!(
                        " ({invalid} invalid record{} left out)",
                        plural(invalid as usize)
                    )
                } else {
                    String::new()
                }
            ),
        );
    }
    if scans.iter().all(|scan| !scan.normals) {
        more(
            s,
            "no normals: `--viewpoint scanners` (zeroset normals, reconstruct) turns each \
             estimated one towards the scanner that recorded it",
        );
    }
}

/// The report of a value-constraint file (`.xyv`, `.xyzv`): what `zeroset fit` reads from it.
fn value_report<const D: usize>(path: &Path) -> anyhow::Result<String> {
    let c = io::read_value_points::<D>(path)
        .with_context(|| format!("reading the value constraints {}", path.display()))?;
    let mut s = String::new();
    line(&mut s, "file", &path.display().to_string());
    line(
        &mut s,
        "format",
        &format!(
            "{D}-D value constraints (x y{} value per line)",
            if D == 3 { " z" } else { "" }
        ),
    );
    let n = c.points.len();
    let count = |f: fn(f64) -> bool| c.values.iter().filter(|v| f(**v)).count();
    line(
        &mut s,
        "constraints",
        &format!(
            "{n} ({} negative, {} zero, {} positive)",
            count(|v| v < 0.0),
            count(|v| v == 0.0),
            count(|v| v > 0.0)
        ),
    );
    let mut distinct = c.values.clone();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if let (Some(lo), Some(hi)) = (distinct.first(), distinct.last()) {
        let levels = if distinct.len() <= 8 {
            let shown: Vec<String> = distinct.iter().map(|v| g(*v)).collect();
            format!(": {}", shown.join(", "))
        } else {
            String::new()
        };
        line(
            &mut s,
            "values",
            &format!(
                "from {} to {}, {} distinct{levels}",
                g(*lo),
                g(*hi),
                distinct.len()
            ),
        );
    }
    if let Some(b) = zeroset_field_core::Aabb::from_points(&c.points) {
        line(&mut s, "bounds", &format!("min {}", point_n(&b.min())));
        more(&mut s, &format!("max {}", point_n(&b.max())));
    }
    match crate::fit::distinct_values(path, &c) {
        Ok((_, kept)) if kept.len() == n => line(&mut s, "duplicates", "none"),
        Ok((_, kept)) => line(
            &mut s,
            "duplicates",
            &format!(
                "{} row{} at an earlier row's place with its value (merged by fit)",
                n - kept.len(),
                plural(n - kept.len())
            ),
        ),
        Err(e) => line(
            &mut s,
            "duplicates",
            &format!("{e:#} (fit refuses the file)"),
        ),
    }
    Ok(s)
}

fn write_bounds(s: &mut String, cloud: &PointCloud3) {
    match cloud.bounds() {
        None => line(s, "bounds", "none (no finite point)"),
        Some(b) => {
            corners(s, b.min(), b.max());
            more(
                s,
                &format!("extent {}, diagonal {}", point(b.extent()), g(b.diagonal())),
            );
        }
    }
}

fn write_normals(s: &mut String, stats: &CloudStats<3>) {
    if !stats.has_normals {
        line(
            s,
            "normals",
            "no (fit and restore need them: `zeroset normals` estimates them; `zeroset \
             reconstruct` does so itself)",
        );
        return;
    }
    let (bad, zero) = (stats.non_unit_normals, stats.zero_normals);
    if zero > 0 && zero == stats.count {
        line(
            s,
            "normals",
            "all 0 0 0: placeholders (some writers put them where a point has none), read as \
             positions only (`zeroset normals` estimates normals; `zeroset reconstruct` does so \
             itself)",
        );
        return;
    }
    let mut text = format!(
        "yes; {bad} not unit length (tolerance {})",
        g(CloudStats::<3>::UNIT_TOLERANCE)
    );
    if let Some((lo, hi)) = stats.normal_length_range {
        let _ = write!(text, "; lengths from {lo:.7} to {hi:.7}");
    }
    line(s, "normals", &text);
    if zero > 0 {
        more(
            s,
            &format!(
                "{zero} of them 0 0 0 (no normal there): fit, restore, studio, reconstruct and \
                 mesh --scan estimate those from their neighbours' plane, signed as the normals \
                 around them"
            ),
        );
    }
}

fn write_non_finite(s: &mut String, stats: &CloudStats<3>, first: Option<&Error>) {
    let (p, n) = (stats.non_finite_positions, stats.non_finite_normals);
    if p == 0 && n == 0 {
        line(s, "non-finite", "none");
        return;
    }
    let mut text = format!("{p} position{}", plural(p));
    if stats.has_normals {
        let _ = write!(text, ", {n} normal{}", plural(n));
    }
    text.push_str(" with NaN or infinite values");
    line(s, "non-finite", &text);
    if let Some(Error::NonFinite {
        record,
        line: file_line,
        field,
        value,
        ..
    }) = first
    {
        let at = file_line
            .map(|l| format!(" (line {l})"))
            .unwrap_or_default();
        more(s, &format!("first: record {record}{at}, {field} = {value}"));
    }
}

fn write_formations(s: &mut String, data: &GeoModelData) {
    let (table, count): (&str, fn(&gempy::FormationCount) -> usize) =
        if data.orientations.is_empty() {
            ("surface points", |c| c.surface_points)
        } else {
            ("orientations", |c| c.orientations)
        };
    let counts = data.formation_counts();
    line(
        s,
        "formations",
        &format!("{} ({table} per formation)", counts.len()),
    );
    let width = counts.iter().map(|c| c.name.len()).max().unwrap_or(0);
    for c in &counts {
        more(s, &format!("{:<width$}  {:>5}", c.name, count(c)));
    }
}

/// `(x, y, z)` with 7 significant digits.
pub(crate) fn point(p: [f64; 3]) -> String {
    point_n(&p)
}

/// A point of any dimension as `(x, y, …)`, 7 significant digits each.
pub(crate) fn point_n(p: &[f64]) -> String {
    let parts: Vec<String> = p.iter().map(|&v| g(v)).collect();
    format!("({})", parts.join(", "))
}

/// A number with 7 significant digits, like C's `%.7g`.
pub(crate) fn g(v: f64) -> String {
    const DIGITS: i32 = 7;
    if v == 0.0 {
        return "0".to_owned();
    }
    if !v.is_finite() {
        return v.to_string();
    }
    let exp = v.abs().log10().floor() as i32;
    if (-4..DIGITS).contains(&exp) {
        let decimals = usize::try_from(DIGITS - 1 - exp).unwrap_or(0);
        trim_zeros(format!("{v:.decimals$}"))
    } else {
        let text = format!("{v:.prec$e}", prec = (DIGITS - 1) as usize);
        match text.split_once('e') {
            Some((mantissa, exponent)) => format!("{}e{exponent}", trim_zeros(mantissa.into())),
            None => text,
        }
    }
}

pub(crate) fn trim_zeros(text: String) -> String {
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::g;

    #[test]
    fn seven_significant_digits() {
        assert_eq!(g(0.0), "0");
        assert_eq!(g(-0.0), "0");
        assert_eq!(g(1.0), "1");
        assert_eq!(g(-0.094668), "-0.094668");
        assert_eq!(g(0.09468989819288254), "0.0946899");
        assert_eq!(g(745312.75), "745312.8");
        assert_eq!(g(6916017.0), "6916017");
        assert_eq!(g(1e-4), "0.0001");
        assert_eq!(g(1.5e-7), "1.5e-7");
        assert_eq!(g(1.0e10), "1e10");
        assert_eq!(g(f64::NAN), "NaN");
    }
}
