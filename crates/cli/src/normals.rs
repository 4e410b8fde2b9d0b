//! `zeroset normals`: outward normals for a scan that has none ([`zeroset_bases::normals`]:
//! planes of each point's nearest neighbours, their signs propagated along a minimum spanning
//! forest and each piece turned outward), written as an oriented cloud that every other
//! command reads.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use zeroset_bases::noise::NOISY_SCATTER;
use zeroset_bases::normals::{
    EstimatedNormals, FlatPiece, MAX_NEIGHBOURS, MIN_NEIGHBOURS, MIN_PIECE, NORMAL_NEIGHBOURS,
    NormalError, NormalOptions, default_neighbours, estimate_normals,
    estimate_normals_from_scanners, fill_missing_normals, orient_normals,
};
use zeroset_bases::thickness::{VOLUME_THICKNESS, thickness_at};
use zeroset_field_core::geometry;
use zeroset_field_core::io::{
    self, Format, ReadOptions, read_point_cloud_with, write_atomic, write_ply,
};
use zeroset_field_core::{Error, PointCloud3};

use crate::info::{plural, trim_zeros};
use crate::progress::{seconds, spinner};

/// Shown after `zeroset normals --help`.
pub const EXAMPLES: &str = "\
Examples:
  # a scan of positions only (x y z) to an oriented cloud, then a mesh from it
  zeroset normals scan.xyz -o scan_oriented.ply
  zeroset reconstruct scan_oriented.ply -o scan_mesh.ply
  # a sparse or noisy scan: planes over more neighbours
  zeroset normals scan.xyz --neighbours 30 -o scan_oriented.xyzn
  # terrain scanned from the air: face the sensor, far above
  zeroset normals terrain.xyz --viewpoint 0,0,10000 -o terrain_oriented.ply
  # a building scanned from several stations (E57): each part faces its own stations
  zeroset normals site.e57 --viewpoint scanners -o site_oriented.ply
  # a scan that has normals: estimate them anyway and report how far they differ
  zeroset normals samples/bunny_2k.xyzn -o /tmp/bunny_estimated.ply";

/// `zeroset normals`' arguments.
#[derive(Debug, Args)]
pub struct NormalsArgs {
    /// A point cloud: .ply, .pcd, .las/.laz (LiDAR), .e57 (laser scans),
    /// .xyz/.xyzn/.txt/.pts/.asc/.pwn or .csv, or a mesh (.ply with faces, .obj, .stl, .off).
    /// Only its positions are used; normals it has are compared with the estimate, not used.
    pub scan: PathBuf,

    /// The oriented cloud, in input order: .ply (binary little-endian, double x y z nx ny nz)
    /// or .xyzn (text, x y z nx ny nz with every digit a double needs), written atomically.
    #[arg(short, long, value_name = "CLOUD.ply|CLOUD.xyzn")]
    pub output: PathBuf,

    /// Neighbours of each point in its plane and in the orientation graph (2 to 256). More
    /// average noise and bridge gaps; fewer follow fine detail and thin parts. Default: 16, or
    /// 32 for a noisy scan (scatter about the surface above 0.2 of the point spacing, as
    /// `zeroset info` measures it).
    #[arg(long, value_name = "K")]
    pub neighbours: Option<usize>,

    /// Where the scanner stood: each piece is turned to face it instead of outward — for
    /// one-sided scans of flat surfaces (a wall, terrain), which have no inside to read, and
    /// scans from inside a room. `scanners` (an E57 file): each point faces the station that
    /// recorded it (its scan's origin in the file's frame); points seen at grazing incidence
    /// (beyond 75.5°) take their neighbours' sign.
    #[arg(long, value_name = "X,Y,Z|scanners", value_parser = parse_viewpoint,
          allow_hyphen_values = true)]
    pub viewpoint: Option<Viewpoint>,

    #[arg(long, value_name = "FORMAT", help = FORMAT_HELP)]
    pub format: Option<String>,

    #[arg(long, value_name = "NAME", help = FORMATION_HELP)]
    pub formation: Option<String>,

    /// Overwrite an existing output.
    #[arg(long)]
    pub force: bool,

    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,
}

/// The help of every command's `--format` (the names `Format` parses).
pub(crate) const FORMAT_HELP: &str = "Read the point cloud as this format whatever its \
    extension: ply, xyz (any text of x y z [nx ny nz] columns: .xyzn, .pts, .txt, .asc, .pwn), \
    csv, gempy, pcd, las (LAS or LAZ) or e57";

/// `zeroset fit`'s `--format` help: [`FORMAT_HELP`]'s formats and the value-constraint files.
pub(crate) const FIT_FORMAT_HELP: &str = "Read the input as this format whatever its \
    extension: ply, xyz (any text of x y z [nx ny nz] columns: .xyzn, .pts, .txt, .asc, .pwn), \
    csv, gempy, pcd, las (LAS or LAZ) or e57; or xyv / xyzv, a value-constraint file of \
    x y value / x y z value lines (--method rbf or neural). A .xyv or .xyzv file is always \
    read as value constraints";

/// The value-constraint formats `--format` names (`zeroset fit` and `zeroset info` read them):
/// the name and the dimension.
const VALUE_FORMATS: [(&str, usize); 2] = [("xyv", 2), ("xyzv", 3)];

/// The dimension of the value-constraint file `--format` names, `None` for any other name.
pub(crate) fn value_format(format: &str) -> Option<usize> {
    VALUE_FORMATS
        .iter()
        .find(|(name, _)| name.eq_ignore_ascii_case(format.trim()))
        .map(|&(_, dimension)| dimension)
}

/// The dimension of the value-constraint file a command reads at `path`, if it is one: by
/// `--format xyv|xyzv`, else by the extension (`.xyv`, `.xyzv`; a point-cloud `--format` on
/// such a file is then refused by the value-file checks, not taken to read it as a cloud).
pub(crate) fn value_dimension(path: &Path, format: Option<&str>) -> Option<usize> {
    format
        .and_then(value_format)
        .or_else(|| io::value_file_dimension(path))
}

/// Whether `--format` names a point-cloud format (given, and not `xyv` or `xyzv`).
pub(crate) fn cloud_format_given(format: Option<&str>) -> bool {
    format.is_some_and(|f| value_format(f).is_none())
}

/// `--formation`'s help, for every command that reads a point cloud.
pub(crate) const FORMATION_HELP: &str = "For a GemPy table: read only the rows of this \
    formation (or fault), by its exact name (`zeroset info TABLE.csv` lists them). By default \
    every row is read, all formations as one surface";

/// The read options of `--format` and `--formation`.
pub(crate) fn read_options(
    format: Option<&str>,
    formation: Option<&str>,
) -> anyhow::Result<ReadOptions> {
    let mut options = ReadOptions::default();
    if let Some(format) = format {
        if value_format(format).is_some() {
            anyhow::bail!(
                "--format {format} names a value-constraint file, which `zeroset fit --method \
                 rbf` (or neural) and `zeroset info` read; this command takes a point cloud"
            );
        }
        options = options.with_format(format.parse().context("--format")?);
    }
    if let Some(name) = formation {
        options = options.with_formation(name);
    }
    Ok(options)
}

/// Whether `path` is read as a GemPy table (by `--format`, else as detected).
pub(crate) fn is_gempy(path: &Path, options: &ReadOptions) -> bool {
    options.format.or_else(|| io::detect_format(path).ok()) == Some(Format::GemPy)
}

/// For a GemPy table of several formations read whole, what it holds and how to take one; for
/// anything else `None`.
pub(crate) fn formations_note(path: &Path, options: &ReadOptions) -> Option<String> {
    if options.formation.is_some() || !is_gempy(path, options) {
        return None;
    }
    let names = io::gempy::read_gempy_file(path).ok()?.formations();
    if names.len() < 2 {
        return None;
    }
    const SHOWN: usize = 6;
    let mut list = names[..names.len().min(SHOWN)].join(", ");
    if names.len() > SHOWN {
        list += &format!(", … {} more", names.len() - SHOWN);
    }
    Some(format!(
        "{} in this GemPy table ({list}), read as one surface: each is a surface of its own, \
         so --formation NAME takes one of them",
        names.len()
    ))
}

/// Runs `zeroset normals`.
pub fn run(args: &NormalsArgs) -> anyhow::Result<()> {
    crate::output::check_output(&args.output, &[&args.scan], args.force, &["ply", "xyzn"])?;
    if let Some(k) = args.neighbours {
        check_neighbours(k)?;
    }
    let start = Instant::now();
    let options = read_options(args.format.as_deref(), args.formation.as_deref())?;
    let (cloud, _) = read_positions(&args.scan, &options, "zeroset normals", true)?;
    crate::fit::check_extent(&args.scan, &cloud)?;
    if let Some(note) = formations_note(&args.scan, &options) {
        outln!("{:<14}{note}", "formations");
    }
    outln!(
        "{:<14}{}: {} points{}",
        "scan",
        args.scan.display(),
        cloud.len(),
        if cloud.normals().is_some() {
            " (its normals are compared below, not used)"
        } else {
            ""
        }
    );
    if let Some(warning) = crate::thickness::warning(&args.scan, &cloud) {
        outln!("{:<14}{warning}", "points");
    }
    let facing = facing(args.viewpoint, &args.scan, &options, &cloud)?;
    let (oriented, _) = orient(&cloud, args.neighbours, &facing, args.quiet)?;
    if let (Some(given), Some(estimated)) = (cloud.normals(), oriented.normals()) {
        outln!("{:<14}{}", "compared", compare(estimated, given));
    }
    write_cloud(&args.output, &oriented)
        .with_context(|| format!("writing {}", args.output.display()))?;
    outln!(
        "{:<14}{} ({} points with normals) in {}",
        "wrote",
        args.output.display(),
        oriented.len(),
        seconds(start.elapsed())
    );
    Ok(())
}

/// Reads `path` with its normals where it has some, or its positions only where an xyz file's
/// columns 4–6 are not normals (colours: the note says so) — and, with `normals_optional`
/// (the caller estimates normals where the file has none), where a normal is not finite (PCL
/// writes NaN for the normals it could not estimate) or only some of an E57 file's scans have
/// normals (the note says so). `command` names the caller in a
/// non-finite value's error. The flag says the normals come from a mesh's winding
/// ([`crate::mesh_points::MeshCloud::wound`]).
pub(crate) fn read_positions(
    path: &Path,
    options: &ReadOptions,
    command: &str,
    normals_optional: bool,
) -> anyhow::Result<(PointCloud3, bool)> {
    if let Some(mesh) = crate::mesh_points::read(path, options)? {
        return Ok((mesh.cloud, mesh.wound));
    }
    read_file_positions(path, options, command, normals_optional).map(|cloud| (cloud, false))
}

/// [`read_positions`] of a point-cloud file.
fn read_file_positions(
    path: &Path,
    options: &ReadOptions,
    command: &str,
    normals_optional: bool,
) -> anyhow::Result<PointCloud3> {
    let needs = if normals_optional {
        "finite coordinates"
    } else {
        "finite coordinates and normals"
    };
    let error = |e| {
        crate::fit::read_error(
            path,
            e,
            "record",
            &format!("{command} needs {needs} (`zeroset info` counts them all)"),
        )
    };
    let positions_only =
        || read_point_cloud_with(path, &options.clone().with_positions_only(true)).map_err(error);
    match read_point_cloud_with(path, options) {
        Err(Error::NotNormals { line, values, .. }) => {
            outln!(
                "{:<14}{}:{line}: columns 4–6 ({} {} {}) are not unit normals (colours?): the \
                 positions only are read",
                "note",
                path.display(),
                values[0],
                values[1],
                values[2]
            );
            positions_only()
        }
        Err(Error::PartialNormals { without, .. }) if normals_optional => {
            outln!(
                "{:<14}{}: {} of its scans have no normals: the positions of every scan are \
                 read, and normals estimated for all",
                "note",
                path.display(),
                without.len()
            );
            positions_only()
        }
        Err(Error::NonFinite { record, field, .. })
            if normals_optional && field.starts_with('n') =>
        {
            outln!(
                "{:<14}{}: record {record} has a non-finite normal ({field}; PCL writes NaN \
                 where it could not estimate one): the file's normals are not read",
                "note",
                path.display()
            );
            // Every reader checks the normals it meets: read them unchecked, then drop them and
            // check the positions here.
            let unchecked = options
                .clone()
                .with_positions_only(true)
                .with_allow_non_finite(true);
            let cloud = read_point_cloud_with(path, &unchecked).map_err(error)?;
            if let Some(record) = cloud
                .positions()
                .iter()
                .position(|p| !p.iter().all(|x| x.is_finite()))
            {
                anyhow::bail!(
                    "{}: record {record}: non-finite position {:?}; {command} needs {needs}",
                    path.display(),
                    cloud.positions()[record]
                );
            }
            Ok(cloud)
        }
        read => read.map_err(error),
    }
}

/// A cloud's normals made whole where some are missing: a zero normal (`0 0 0`, what CGAL and
/// others write where a point has none) is estimated from the plane of the point's `k` nearest
/// ([`NORMAL_NEIGHBOURS`] by default) and signed as the normals around it
/// ([`fill_missing_normals`]); where every normal is zero they are placeholders, and the cloud
/// is returned without them. A note says which. Returns the cloud and how many normals were
/// estimated.
pub(crate) fn complete_normals(
    path: &Path,
    cloud: PointCloud3,
    k: Option<usize>,
) -> anyhow::Result<(PointCloud3, usize)> {
    if cloud.normals().is_none() {
        return Ok((cloud, 0));
    }
    let k = k.unwrap_or(NORMAL_NEIGHBOURS);
    let (positions, normals) = cloud.into_parts();
    let mut normals = normals.unwrap_or_default();
    let filled = match fill_missing_normals(&positions, &mut normals, k) {
        Err(NormalError::NoneGiven { .. }) => {
            outln!(
                "{:<14}{}: every normal is 0 0 0 (placeholders, which some writers put where a \
                 point has none): read as positions only",
                "note",
                path.display()
            );
            return Ok((PointCloud3::new(positions)?, 0));
        }
        filled => filled
            .with_context(|| format!("estimating the missing normals of {}", path.display()))?,
    };
    if filled.is_empty() {
        return Ok((PointCloud3::with_normals(positions, normals)?, 0));
    }
    const SHOWN: usize = 5;
    let records: Vec<String> = filled.iter().take(SHOWN).map(usize::to_string).collect();
    outln!(
        "{:<14}{}: {} point{} without a normal (0 0 0; record{} {}{}, counted from 0): \
         estimated from the plane of {} {k} nearest points, signed as the normals around {}",
        "normals",
        path.display(),
        filled.len(),
        plural(filled.len()),
        plural(filled.len()),
        records.join(", "),
        if filled.len() > SHOWN { ", …" } else { "" },
        if filled.len() == 1 {
            "its"
        } else {
            "each one's"
        },
        if filled.len() == 1 { "it" } else { "them" },
    );
    Ok((PointCloud3::with_normals(positions, normals)?, filled.len()))
}

/// Where a cloud's normals are unoriented ([`zeroset_bases::normals::Orientation::unoriented`]:
/// principal-component normals written without a sign, half of them inward), the orientation
/// propagated over the scan, their lines kept; `None` where they are oriented, or the cloud has
/// none or too few points to tell. A cloud of more than [`ORIENTATION_SAMPLE`] points is
/// judged on a hashed sample of one point in `⌈n / ORIENTATION_SAMPLE⌉` first (the share is a
/// proportion; the propagation costs about 4 µs and 380 bytes a point at 16 neighbours: 4.1 s
/// and 380 MB for 10⁶), and oriented whole only where that reads unoriented.
pub(crate) fn unoriented(cloud: &PointCloud3) -> Option<zeroset_bases::normals::Orientation> {
    let normals = cloud.normals()?;
    let options = NormalOptions::default();
    let stride = cloud.len().div_ceil(ORIENTATION_SAMPLE).max(1) as u64;
    if stride > 1 {
        // A hashed pick, not every stride-th record, which could keep one laser ring of a
        // scanner's file.
        let picked = |i: usize| {
            ((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 24).is_multiple_of(stride)
        };
        let (positions, lines): (Vec<_>, Vec<_>) = cloud
            .positions()
            .iter()
            .zip(normals)
            .enumerate()
            .filter(|(i, _)| picked(*i))
            .map(|(_, (p, n))| (*p, *n))
            .unzip();
        if !orient_normals(&positions, &lines, &options).is_ok_and(|o| o.unoriented()) {
            return None;
        }
    }
    orient_normals(cloud.positions(), normals, &options)
        .ok()
        .filter(|o| o.unoriented())
}

/// The most points [`unoriented`] reads the orientation on before it takes a sample.
pub(crate) const ORIENTATION_SAMPLE: usize = 200_000;

/// The line that says `orientation` found the normals of `path` unoriented.
pub(crate) fn unoriented_text(path: &Path, o: &zeroset_bases::normals::Orientation) -> String {
    let n = o.estimated.normals.len();
    if !o.unoriented_by_share() {
        return format!(
            "{}'s normals face into the object on part of it: {} of {n} ({}%) point against \
             the sign the rest of their surface gives them, and of the rays cast along them \
             {} of {} meet the surface as from inside ({} as from outside): as where a program \
             turned every normal towards one direction and a closed object's far side came to \
             face in",
            path.display(),
            o.inconsistent,
            percent(o.inconsistent, n),
            o.rays.inward,
            o.rays.cast,
            o.rays.outward
        );
    }
    format!(
        "{}'s normals look unoriented: {} of {n} ({}%) point against the sign the rest of their \
         surface gives them (about half: signs set arbitrarily, as principal-component normals \
         are written)",
        path.display(),
        o.inconsistent,
        percent(o.inconsistent, n)
    )
}

/// `--viewpoint`: where the scanner stood, or each point's scanner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Viewpoint {
    /// One position for every point.
    Point([f64; 3]),
    /// Each point's scan's origin (an E57 file).
    Scanners,
}

impl std::fmt::Display for Viewpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Viewpoint::Point(v) => write!(f, "{v:?}"),
            Viewpoint::Scanners => f.write_str("scanners"),
        }
    }
}

/// `--viewpoint`: three finite comma-separated numbers, or `scanners`.
pub(crate) fn parse_viewpoint(s: &str) -> Result<Viewpoint, String> {
    if s.trim().eq_ignore_ascii_case("scanners") {
        return Ok(Viewpoint::Scanners);
    }
    let v: [f64; 3] = crate::restore::parse_triple(s, "--viewpoint")
        .map_err(|e| format!("{e} (or `scanners`: each point's E57 scan origin)"))?;
    if v.iter().all(|x| x.is_finite()) {
        Ok(Viewpoint::Point(v))
    } else {
        Err(format!("--viewpoint must be finite, got {s:?}"))
    }
}

/// Which way the estimated normals are turned.
pub(crate) enum Facing {
    /// Outward (each piece by its divergence).
    Outward,
    /// Towards one viewpoint.
    Point([f64; 3]),
    /// Each point towards its scan's origin; the count of scans.
    Scanners(Vec<[f64; 3]>, usize),
}

impl Facing {
    /// The same facing for the cloud without the points at `indices` (increasing).
    pub(crate) fn without(self, indices: &[usize]) -> Self {
        match self {
            Facing::Scanners(origins, scans) => {
                let mut dropped = indices.iter().peekable();
                let kept = origins
                    .into_iter()
                    .enumerate()
                    .filter(|(i, _)| dropped.next_if_eq(&i).is_none())
                    .map(|(_, o)| o)
                    .collect();
                Facing::Scanners(kept, scans)
            }
            other => other,
        }
    }
}

/// The facing `--viewpoint` asks for on the scan `path` (read with `options` as `cloud`):
/// `scanners` reads the origins of an E57 file's scans, one per point.
pub(crate) fn facing(
    viewpoint: Option<Viewpoint>,
    path: &Path,
    options: &ReadOptions,
    cloud: &PointCloud3,
) -> anyhow::Result<Facing> {
    match viewpoint {
        None => Ok(Facing::Outward),
        Some(Viewpoint::Point(v)) => Ok(Facing::Point(v)),
        Some(Viewpoint::Scanners) => {
            let format = options.format.or_else(|| io::detect_format(path).ok());
            if format != Some(Format::E57) {
                anyhow::bail!(
                    "--viewpoint scanners takes where each point's scanner stood from an E57 \
                     file's scans (their poses); {} is not an E57 file: give --viewpoint X,Y,Z",
                    path.display()
                );
            }
            // The positions were checked when the cloud was read; normals are not read.
            let read = options
                .clone()
                .with_positions_only(true)
                .with_allow_non_finite(true);
            let e57 = io::e57::read_e57(path, &read)
                .with_context(|| format!("reading the scans of {}", path.display()))?;
            let origins = e57.origins();
            if origins.len() != cloud.len() {
                anyhow::bail!(
                    "{}: {} points read, but its scans hold {}",
                    path.display(),
                    cloud.len(),
                    origins.len()
                );
            }
            for (i, scan) in e57.scans.iter().enumerate() {
                if !scan.posed && scan.coordinates == io::e57::Coordinates::Cartesian {
                    outln!(
                        "{:<14}scan {i} has Cartesian coordinates and no pose: its scanner is \
                         taken to stand at the file's origin (0, 0, 0)",
                        "note"
                    );
                }
            }
            Ok(Facing::Scanners(origins, e57.scans.len()))
        }
    }
}

/// Refuses a neighbour count outside the estimate's range, before any reading.
pub(crate) fn check_neighbours(k: usize) -> anyhow::Result<()> {
    if !(MIN_NEIGHBOURS..=MAX_NEIGHBOURS).contains(&k) {
        anyhow::bail!(
            "--neighbours must be from {MIN_NEIGHBOURS} to {MAX_NEIGHBOURS} (a plane through a \
             point and its neighbours), got {k}"
        );
    }
    Ok(())
}

/// `cloud`'s positions with estimated outward normals, and what the estimate found (its counts;
/// the normals are in the cloud); prints the `normals` line. Without `neighbours`, as many as
/// [`default_neighbours`] says for the positions (more for a noisy scan).
pub(crate) fn orient(
    cloud: &PointCloud3,
    neighbours: Option<usize>,
    facing: &Facing,
    quiet: bool,
) -> anyhow::Result<(PointCloud3, EstimatedNormals)> {
    let t = Instant::now();
    // The noise, measured whether or not a count is given: for the count, and for the
    // two-sheet warning.
    let (default, noise) = default_neighbours(cloud.positions());
    let diagonal = cloud.bounds().map_or(0.0, |b| b.diagonal());
    let two_sheets =
        noise.and_then(|noise| crate::noise::Measured { noise, diagonal }.two_sheets());
    let (neighbours, why) = match (neighbours, noise) {
        (Some(k), _) => (k, String::new()),
        (None, Some(noise)) if default != NORMAL_NEIGHBOURS => (
            default,
            format!(
                " (a noisy scan{}: scatter {:.3} of the point spacing, above {NOISY_SCATTER})",
                if two_sheets.is_some() {
                    " on its face"
                } else {
                    ""
                },
                noise.relative()
            ),
        ),
        (None, _) => (default, String::new()),
    };
    // Fewer points than the neighbours asked for: each takes all the others.
    let used = neighbours.min(cloud.len().saturating_sub(1));
    let bar = spinner(quiet);
    bar.set_message("estimating normals: planes of neighbours, signs along a spanning forest");
    let options = NormalOptions::default().neighbours(neighbours.min(MAX_NEIGHBOURS));
    let estimated = match facing {
        Facing::Outward => estimate_normals(cloud.positions(), &options),
        Facing::Point(v) => estimate_normals(cloud.positions(), &options.viewpoint(*v)),
        Facing::Scanners(origins, _) => {
            estimate_normals_from_scanners(cloud.positions(), origins, &options)
        }
    };
    bar.finish_and_clear();
    let mut estimated = estimated.context("estimating normals")?;
    // A clause for a count that is not zero.
    let clause = |count: usize, text: &str| {
        if count > 0 {
            format!(", {count} points {text}")
        } else {
            String::new()
        }
    };
    let small = clause(
        estimated.attached,
        &format!("in pieces under {MIN_PIECE} points (or without a plane) signed by their nearest"),
    );
    let lines = clause(
        estimated.undetermined,
        "whose neighbours span no plane took a neighbour's",
    );
    outln!(
        "{:<14}estimated from {used} neighbours each{why}: {} piece{} {}{small}{lines} ({})",
        "normals",
        estimated.pieces,
        if estimated.pieces == 1 { "" } else { "s" },
        match facing {
            Facing::Point(v) => format!("turned towards the viewpoint {v:?}"),
            Facing::Scanners(_, scans) => format!(
                "with each point turned towards the scanner of its scan ({scans} scan{}; {} of {} \
                 points by their line of sight, the others, seen at grazing incidence or not \
                 at all, by their neighbours)",
                plural(*scans),
                estimated.facing_scanner,
                estimated.normals.len()
            ),
            Facing::Outward => {
                let mut how = "turned outward".to_owned();
                if estimated.nested > 0 {
                    how += &format!(
                        ", {} of them inside another and so turned to face into it (the wall \
                         of a cavity)",
                        estimated.nested
                    );
                }
                if !estimated.flat.is_empty() {
                    how += &format!(", {} of them flat (below)", estimated.flat.len());
                }
                how
            }
        },
        seconds(t.elapsed())
    );
    if let Some(note) = flat_note(&estimated.flat) {
        outln!("{:<14}{note}", "note");
    }
    if let Some(clause) = two_sheets {
        outln!("{:<14}warning: {clause}", "normals");
    }
    if let Some(warning) = few_points_warning(used, cloud.positions()) {
        outln!("{:<14}{warning}", "normals");
    }
    // The normals move into the cloud; the report keeps the counts.
    let normals = std::mem::take(&mut estimated.normals);
    let oriented = PointCloud3::with_normals(cloud.positions().to_vec(), normals)
        .context("the oriented cloud")?;
    Ok((oriented, estimated))
}

/// A plane fitted to more than this share of a cloud's points may stand for the cloud's
/// overall shape rather than a patch of its surface ([`few_points_warning`]).
const MOST_OF_THE_CLOUD: f64 = 0.25;

/// The warning where each normal's plane takes a point and its `used` nearest, more than
/// [`MOST_OF_THE_CLOUD`] of the `positions`, *and* those planes are about as thick as they
/// are wide ([`thickness_at`] at least [`VOLUME_THICKNESS`]): 8 points at a cube's corners
/// (every plane through all 8, thickness 1; `reconstruct` meshed two open pieces with
/// "warnings: none"). Small clouds whose planes are thin pass: 20–63 points on a sphere (their
/// normals within 22° of the truth, the 40-point one reconstructed within 0.7% of its volume),
/// a flat grid.
fn few_points_warning(used: usize, positions: &[geometry::Point<3>]) -> Option<String> {
    let points = positions.len();
    if used as f64 <= MOST_OF_THE_CLOUD * points as f64 {
        return None;
    }
    let thickness = thickness_at(positions, used + 1).filter(|&t| t >= VOLUME_THICKNESS)?;
    Some(format!(
        "warning: each normal's plane is fitted to a point and its {used} nearest, {} of the \
         {points} points, and those planes are {thickness:.2} as thick as they are wide (the \
         median): too few points for planes of patches of the surface, so the normals, and the \
         surface fitted to them, may be a guess at the cloud's overall shape; give more points, \
         or their normals",
        used + 1
    ))
}

/// What became of the pieces too flat to have an inside (terrain, a wall), if any: their side
/// is a convention, and `--viewpoint` picks it.
fn flat_note(flat: &[FlatPiece]) -> Option<String> {
    const HOW: &str = "--viewpoint X,Y,Z turns each piece towards where the scanner stood";
    let axis = |n: &[f64; 3]| {
        let a = (0..3).max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()));
        ["+x", "+y", "+z"][a.unwrap_or(2)]
    };
    match flat {
        [] => None,
        [one] => Some(format!(
            "a piece of {} points is flat, with no inside to read its side from: turned by \
             convention to face {} (its mean normal {:.2}, {:.2}, {:.2}); {HOW}",
            one.points,
            axis(&one.facing),
            one.facing[0],
            one.facing[1],
            one.facing[2]
        )),
        many => Some(format!(
            "{} pieces ({} points) are flat, with no inside to read their side from: each \
             turned by convention to face +x, +y or +z, whichever axis its mean normal lies \
             nearest; {HOW}",
            many.len(),
            many.iter().map(|f| f.points).sum::<usize>()
        )),
    }
}

/// How the estimate differs from normals the file had: points turned the other way, and the
/// angle between the lines.
fn compare(estimated: &[[f64; 3]], given: &[[f64; 3]]) -> String {
    let mut opposite = 0;
    let mut angles: Vec<f64> = Vec::with_capacity(given.len());
    for (e, n) in estimated.iter().zip(given) {
        let length = geometry::norm(n);
        if length <= 0.0 {
            continue;
        }
        let cos = geometry::dot(e, n) / length;
        if cos < 0.0 {
            opposite += 1;
        }
        angles.push(cos.abs().min(1.0).acos().to_degrees());
    }
    if angles.is_empty() {
        return "the file's normals are all zero".to_owned();
    }
    angles.sort_by(f64::total_cmp);
    let at = |q: f64| angles[((angles.len() - 1) as f64 * q).round() as usize];
    format!(
        "with the file's normals: {opposite} of {} ({}%) point the other way; the lines differ \
         by {:.2}° (median), {:.2}° (90%), {:.2}° (99%)",
        angles.len(),
        percent(opposite, angles.len()),
        at(0.5),
        at(0.9),
        at(0.99)
    )
}

/// `part` of `whole` in percent, to 3 significant digits (0 exactly for none).
fn percent(part: usize, whole: usize) -> String {
    let p = 100.0 * part as f64 / whole.max(1) as f64;
    if part == 0 {
        "0".to_owned()
    } else {
        let decimals = (2 - p.log10().floor() as i32).clamp(0, 15) as usize;
        trim_zeros(format!("{p:.decimals$}"))
    }
}

/// Writes an oriented cloud as binary PLY or xyzn text by `path`'s extension, atomically.
pub(crate) fn write_cloud(path: &Path, cloud: &PointCloud3) -> anyhow::Result<()> {
    let text = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("xyzn"));
    if !text {
        return Ok(write_ply(path, cloud)?);
    }
    let normals = cloud.normals().context("the cloud has normals")?;
    write_atomic(path, |w| {
        let mut w = std::io::BufWriter::new(w);
        for (p, n) in cloud.positions().iter().zip(normals) {
            // `{}` of an f64 is the shortest text that reads back to the same bits.
            writeln!(w, "{} {} {} {} {} {}", p[0], p[1], p[2], n[0], n[1], n[2])?;
        }
        w.flush()
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_facing_without_points_keeps_the_other_points_scanners_in_order() {
        let origins = (0..6).map(|i| [i as f64, 0.0, 0.0]).collect();
        let Facing::Scanners(kept, scans) = Facing::Scanners(origins, 2).without(&[0, 3, 5]) else {
            panic!("not scanners")
        };
        assert_eq!(kept, [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [4.0, 0.0, 0.0]]);
        assert_eq!(scans, 2);
        assert!(matches!(
            Facing::Point([1.0, 2.0, 3.0]).without(&[0]),
            Facing::Point([1.0, 2.0, 3.0])
        ));
    }

    #[test]
    fn percentages_keep_three_digits() {
        assert_eq!(percent(0, 10), "0");
        assert_eq!(percent(981, 34_834), "2.82");
        assert_eq!(percent(9, 34_834), "0.0258");
        assert_eq!(percent(10, 10), "100");
    }
}
