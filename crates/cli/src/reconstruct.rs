//! `zeroset reconstruct`: from a scan to a mesh and its preview in one command — fit a field
//! (`zeroset fit`), mesh its zero set (`zeroset mesh`), render the mesh (`zeroset preview`) —
//! with each stage's report, then a summary of the stages' times.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Parser, ValueEnum};
use zeroset_bases::outliers::{find_isolated, remove_outliers, without};

use crate::fit::{FitArgs, SmoothingArg};
use crate::info::{g, plural};
use crate::interrupt::TemporaryFile;
use crate::mesh::{DetailArg, MeshArgs};
use crate::preview::PreviewArgs;
use crate::progress::seconds;

/// Shown after `zeroset reconstruct --help`.
pub const EXAMPLES: &str = "\
Examples:
  # the sample bunny to a mesh and bunny.png beside it (RBF: 2,000 points, fine voxels)
  zeroset reconstruct samples/bunny_2k.xyzn -o bunny.ply
  # a full scan with multilevel rational algebraic splines, the field kept
  zeroset reconstruct scan.ply --method mras --field scan.zsf -o scan_mesh.ply
  # a one-sided scan (a face, a façade, terrain): the surface cut where the scan ends
  zeroset reconstruct face_scan.ply --trim -o face.ply
  # a turntable scan without its bottom: closed, capped flat where its sides end
  zeroset reconstruct part_scan.ply --close -o part.stl";

/// Clouds of up to this many points are fitted by RBF under `--method auto`, larger ones by
/// MRAS. Measured on 2 threads (whole `zeroset reconstruct` commands): the full 34,834-point
/// bunny by RBF in ~21 s (fit ~18 s: 13 GMRES steps on FMM products; the points' distance to
/// the mesh 1.4e-4 of the diagonal on average, 3.2e-3 at most), by MRAS in ~10 s (3.8e-4,
/// 4.5e-3); 10⁵ sphere points (3·10⁵ functionals) by RBF take ~53 s to fit and 1.7 GB, where
/// MRAS's time grows with the detail rather than the count. Noisy clouds are not interpolated
/// ([`zeroset_bases::noise`]: RBF interpolation makes bubbles of the noise): see
/// [`AUTO_SMOOTHED_POINTS`].
pub const AUTO_RBF_POINTS: usize = 50_000;

/// Noisy clouds of up to this many points are fitted by RBF smoothed by their measured noise
/// (`--smoothing auto`) under `--method auto`, larger ones by MRAS. Measured on 2 threads,
/// whole `zeroset reconstruct` commands, the mesh's vertices against the clean scan's surface
/// (median, of the diagonal): random subsets of the bunny with Gaussian noise of 0.5% of the
/// diagonal per axis — 5,000 points: smoothed RBF 1.41e-3 in 3.4 s, MRAS 1.65e-3 in 5.6 s;
/// 10,000: 1.18e-3 in 4.3 s against 1.33e-3 in 8.1 s; 20,000: 1.00e-3 in 11.2 s against 1.06e-3
/// in 9.2 s (the 90th percentile 2.68e-3 against 2.52e-3); the whole 34,834 (`noise_peers.py`):
/// MRAS the closer at the points on average and the faster (15–17 s against 22–24 s). The
/// kitten (5,210) at 0.5% / 0.75%: the clean points 1.2e-3 / 1.6e-3 from the smoothed RBF mesh,
/// 1.5e-3 / 2.2e-3 from MRAS's, 2.3 s against 5.5 s; a 2,000-point sphere with noise of 5% of
/// its radius (a review's): RBF one sphere (χ 2), MRAS genus 17 (χ −32). MRAS fits each cell
/// to the points it holds, and sparse noisy cells leave it holes and handles.
pub const AUTO_SMOOTHED_POINTS: usize = 15_000;

/// The field `--method` fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ReconstructMethod {
    /// RBF up to 50,000 points, MRAS beyond; a noisy scan (its points scatter about their
    /// local surface by more than 0.2 of their spacing: `zeroset info` measures it) by RBF
    /// smoothed by that noise (--smoothing auto) up to 15,000 points, MRAS beyond.
    Auto,
    /// Radial basis functions (kernel r, off-surface points), meshed by the signed marching
    /// cubes.
    Rbf,
    /// Multilevel rational algebraic splines, meshed by marching cubes.
    Mras,
}

/// `zeroset reconstruct`'s arguments.
#[derive(Debug, Args)]
pub struct ReconstructArgs {
    /// A point cloud: .ply, .pcd, .las/.laz, .e57, .xyzn/.xyz/.txt/.pts/.asc/.pwn or .csv, with normals
    /// pointing out of the solid or without (then estimated); or a mesh (.ply with faces,
    /// .obj, .stl, .off).
    pub scan: PathBuf,

    /// The mesh: .ply (binary little-endian), .obj, .stl (binary) or .off, written atomically. The
    /// preview is written beside it, with the extension .png.
    #[arg(short, long, value_name = "MESH.ply|MESH.obj|MESH.stl|MESH.off")]
    pub output: PathBuf,

    /// The field to fit.
    #[arg(long, value_enum, default_value_t = ReconstructMethod::Auto)]
    pub method: ReconstructMethod,

    /// Voxel size by the l0 rule of the field's box (as `zeroset mesh --detail`) [default:
    /// fine; for an MRAS field of a scan denser than that, 2 × the scan's median point spacing
    /// where the field holds detail that fine, as `zeroset mesh` chooses]. On the full
    /// bunny (MRAS) the points' mean distance to the mesh is 3.8e-4 of the diagonal with fine
    /// voxels (the field's own: 3.5e-4), 1.1e-3 with general ones; on a million-point ridged
    /// ball (spacing 1/4 of a fine voxel) 3.7e-4 with 2 spacings (the field's own: 3.3e-4),
    /// 4.7e-4 with fine voxels.
    #[arg(long, value_enum)]
    pub detail: Option<DetailArg>,

    /// N cubic voxels along the longest axis of the field's box, instead of --detail (as
    /// `zeroset mesh --resolution`).
    #[arg(long, value_name = "N", conflicts_with_all = ["voxel", "detail"])]
    pub resolution: Option<usize>,

    /// An explicit voxel edge in the scan's units, instead of --detail (as `zeroset mesh
    /// --voxel`): finer than fine voxels where sharp edges or thin parts want it.
    #[arg(
        long,
        value_name = "H",
        conflicts_with = "detail",
        allow_hyphen_values = true
    )]
    pub voxel: Option<f64>,

    /// Keep the fitted field in this .zsf file (by default it is a temporary file, removed).
    #[arg(long, value_name = "FIELD.zsf")]
    pub field: Option<PathBuf>,

    /// Remove the mesh's components with no input point within 3 voxels, and those fitted to
    /// fewer than 4 input points (blobs around stray points near the surface). The default;
    /// accepted for scripts written before it was.
    #[arg(long, conflicts_with = "keep_spurious")]
    pub drop_spurious: bool,

    /// Keep the components --drop-spurious removes (the mesh stage still reports them).
    #[arg(long)]
    pub keep_spurious: bool,

    /// Cut the mesh where it leaves the scan's reach, REACH local point spacings (default 1.5)
    /// beyond its nearest points (as `zeroset mesh --trim`): for one-sided scans (a face, a
    /// façade, terrain), and to reopen holes the scan left.
    #[arg(long, value_name = "REACH", num_args = 0..=1, require_equals = true,
          default_missing_value = "1.5")]
    pub trim: Option<f64>,

    /// Cap the surface where it leaves the scan's bounding box, so that the mesh is closed
    /// (as `zeroset mesh --close=scan`): for a scan whose bottom was not seen (on a
    /// turntable, a table), capped flat where its sides end rather than run on to the field's
    /// box; a tilted or ragged rim is capped at the box's face past its lowest point.
    #[arg(long, conflicts_with = "trim")]
    pub close: bool,

    /// RBF fits: approximate instead of interpolate (as `zeroset fit --smoothing`): auto (from
    /// the measured noise) or MU ≥ 0.
    #[arg(long, value_name = "auto|MU", value_parser = crate::fit::parse_smoothing,
          allow_hyphen_values = true)]
    pub smoothing: Option<SmoothingArg>,

    /// MRAS fits: the target largest distance from the points to the surface, as a fraction
    /// of the box diagonal (as `zeroset fit --method mras --tolerance`; default 0.001). On a
    /// very noisy scan a looser one smooths the bubbles the finest levels make of the noise.
    #[arg(long, value_name = "T")]
    pub tolerance: Option<f64>,

    /// The fit's stray-point options (as `zeroset fit`'s).
    #[command(flatten)]
    pub outliers: crate::outliers::OutlierArgs,

    /// Neighbours of each point when the scan has no normals and they are estimated (as
    /// `zeroset normals --neighbours`; default 16, or 32 for a noisy scan), and of each point
    /// whose normal is 0 0 0 when it is completed (default 16).
    #[arg(long, value_name = "K")]
    pub normal_neighbours: Option<usize>,

    /// Where the scanner stood, for a scan without normals taken from one side (a room, a
    /// facade, terrain): the estimated normals are turned to face it instead of outward (as
    /// `zeroset normals --viewpoint`; `scanners` for an E57 file: each point faces the station
    /// that recorded it). Refused for a scan with normals of its own.
    #[arg(long, value_name = "X,Y,Z|scanners", value_parser = crate::normals::parse_viewpoint,
          allow_hyphen_values = true)]
    pub viewpoint: Option<crate::normals::Viewpoint>,

    /// Keep a closed mesh that comes out inside out (a negative signed volume) as fitted,
    /// instead of turning it over: for normals that face into the solid on purpose (a room
    /// scanned from inside, its normals facing the scanner, as `zeroset normals --viewpoint`
    /// writes them). Implied by --viewpoint.
    #[arg(long)]
    pub keep_inside_out: bool,

    #[arg(long, value_name = "FORMAT", help = crate::normals::FORMAT_HELP)]
    pub format: Option<String>,

    #[arg(long, value_name = "NAME", help = crate::normals::FORMATION_HELP)]
    pub formation: Option<String>,

    /// Write no PNG preview.
    #[arg(long)]
    pub no_preview: bool,

    /// The axis the preview draws up (as `zeroset preview --up`): z, y (the Stanford bunny,
    /// most meshes from graphics tools) or x.
    #[arg(long, value_enum, default_value_t = crate::preview::Up::Z)]
    pub up: crate::preview::Up,

    /// Overwrite existing outputs.
    #[arg(long)]
    pub force: bool,

    /// No progress spinners.
    #[arg(long)]
    pub quiet: bool,
}

/// How `--method auto`'s reason names a scan that measures noisy: as such, or, where two
/// parallel sheets explain the reading, as a thin wall that reads noisy.
fn noisy_scan(m: &crate::noise::Measured) -> &'static str {
    if m.noise.two_sheets_explain() {
        "a scan that reads noisy, though two parallel sheets closer than its spacing explain \
         it (a wall thinner than the sampling, or scans out of register)"
    } else {
        "a noisy scan"
    }
}

/// Whether `--smoothing` asks for a smoothed RBF fit: `auto` or `μ > 0` (`0` interpolates).
fn asks_to_smooth(smoothing: Option<SmoothingArg>) -> bool {
    match smoothing {
        Some(SmoothingArg::Fixed(mu)) => mu > 0.0,
        Some(SmoothingArg::Auto) => true,
        None => false,
    }
}

/// The field `zeroset reconstruct` fits, with the reason `--method auto` gives for it.
#[derive(Debug)]
struct Choice {
    /// Rbf or Mras (never Auto).
    method: ReconstructMethod,
    /// ` (auto: …)` after the method's name, or empty where the user named the method.
    why: String,
    /// Whether `auto` chose an RBF fit smoothed by the measured noise (`--smoothing auto`).
    auto_smoothing: bool,
}

/// What `--method auto` fits: MRAS beyond [`AUTO_RBF_POINTS`]; RBF where `--smoothing` asks to
/// smooth; otherwise by the scan's noise, which `measure` reads only then — a noisy scan by RBF
/// smoothed by that noise up to [`AUTO_SMOOTHED_POINTS`] (unless `--smoothing` was given, as 0),
/// MRAS beyond, and a clean one by RBF.
fn choose(
    asked: ReconstructMethod,
    points: usize,
    smoothing: Option<SmoothingArg>,
    measure: impl FnOnce() -> anyhow::Result<Option<crate::noise::Measured>>,
) -> anyhow::Result<Choice> {
    let chosen = |method, why: String| Choice {
        method,
        why,
        auto_smoothing: false,
    };
    Ok(match asked {
        ReconstructMethod::Auto if points > AUTO_RBF_POINTS => chosen(
            ReconstructMethod::Mras,
            format!(" (auto: more than {AUTO_RBF_POINTS} points)"),
        ),
        ReconstructMethod::Auto if asks_to_smooth(smoothing) => chosen(
            ReconstructMethod::Rbf,
            format!(" (auto: RBF up to {AUTO_RBF_POINTS} points, smoothed as --smoothing asks)"),
        ),
        ReconstructMethod::Auto => match measure()? {
            // `--smoothing 0` asks to interpolate: then MRAS, not an RBF of the noise.
            Some(m)
                if m.noise.is_noisy() && points <= AUTO_SMOOTHED_POINTS && smoothing.is_none() =>
            {
                Choice {
                    method: ReconstructMethod::Rbf,
                    why: format!(
                        " (auto: {}, {}; up to {AUTO_SMOOTHED_POINTS} points RBF smoothed by \
                         that noise, --smoothing auto, MRAS beyond)",
                        noisy_scan(&m),
                        m.describe()
                    ),
                    auto_smoothing: true,
                }
            }
            Some(m) if m.noise.is_noisy() => chosen(
                ReconstructMethod::Mras,
                format!(
                    " (auto: {}, {}, {}; RBF would interpolate {})",
                    noisy_scan(&m),
                    m.describe(),
                    if points > AUTO_SMOOTHED_POINTS {
                        format!("of more than {AUTO_SMOOTHED_POINTS} points")
                    } else {
                        "and --smoothing 0 asks not to smooth it".to_owned()
                    },
                    if m.noise.two_sheets_explain() {
                        "between the sheets"
                    } else {
                        "the noise"
                    }
                ),
            ),
            _ => chosen(
                ReconstructMethod::Rbf,
                format!(" (auto: RBF up to {AUTO_RBF_POINTS} points unless noisy)"),
            ),
        },
        m => chosen(m, String::new()),
    })
}

/// The arguments of one stage, parsed as the command line would be.
#[derive(Debug, Parser)]
struct Stage<T: Args> {
    #[command(flatten)]
    args: T,
}

fn stage<T: Args>(argv: &[&std::ffi::OsStr]) -> anyhow::Result<T> {
    Ok(Stage::<T>::try_parse_from(argv)
        .context("internal: a stage's arguments")?
        .args)
}

/// Runs `zeroset reconstruct`.
pub fn run(args: &ReconstructArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let preview = (!args.no_preview).then(|| args.output.with_extension("png"));
    // Every output is checked before any work: its extension, its directory, and --force.
    let outputs: [(Option<&PathBuf>, &[&str]); 3] = [
        (Some(&args.output), &zeroset_mesh::MeshFormat::EXTENSIONS),
        (preview.as_ref(), &["png"]),
        (args.field.as_ref(), &["zsf"]),
    ];
    for (path, extensions) in outputs {
        if let Some(path) = path {
            crate::output::check_output(path, &[&args.scan], args.force, extensions)?;
        }
    }
    if args.field.as_deref() == Some(args.output.as_path()) {
        bail!("--field and -o name the same file");
    }
    args.outliers.ratio()?;
    args.outliers.check(&args.scan, None, args.force)?;
    crate::fit::check_mu(args.smoothing)?;
    if let Some(k) = args.normal_neighbours {
        crate::normals::check_neighbours(k)?;
    }
    if let Some(reach) = args.trim
        && !(reach.is_finite() && reach > 0.0)
    {
        bail!("--trim takes a finite positive reach (in local point spacings), got {reach}");
    }
    crate::mesh::check_voxel(args.resolution, args.voxel)?;
    let smoothed = asks_to_smooth(args.smoothing);
    // Read once here for `auto`'s size rule and a bad file's error before any output exists;
    // the fit stage reads it again (milliseconds beside the fit).
    let options = crate::normals::read_options(args.format.as_deref(), args.formation.as_deref())?;
    let (cloud, wound) =
        crate::normals::read_positions(&args.scan, &options, "zeroset reconstruct", true)?;
    // Curves in a plane before zero normals are completed (across the plane, there).
    crate::fit::check_not_curves(&args.scan, &cloud).context("reconstruct, stage 1 (fit)")?;
    if let Some(warning) = crate::thickness::warning(&args.scan, &cloud) {
        outln!("{:<14}{warning}", "points");
    }
    let (cloud, completed) =
        crate::normals::complete_normals(&args.scan, cloud, args.normal_neighbours)?;
    // (After the completion: normals all 0 0 0 are none, and --viewpoint turns estimated ones.)
    if let (Some(v), Some(_)) = (args.viewpoint, cloud.normals()) {
        bail!(
            "--viewpoint {v} turns estimated normals, but {} has normals of its own, which \
             the fit uses as they are (drop --viewpoint, or give the positions only to have \
             them estimated)",
            args.scan.display()
        );
    }
    // Unoriented normals (signs set arbitrarily): their lines kept, signed by the orientation
    // propagated over the scan, and the stages given that copy. (Not a mesh's winding: it is
    // consistent by construction.)
    let (cloud, turned) = match (!wound)
        .then(|| crate::normals::unoriented(&cloud))
        .flatten()
    {
        Some(o) => {
            outln!(
                "{:<14}{}: turned as the orientation propagated over the scan gives (their lines \
                 kept, each piece outward; {} of them turned; `zeroset fit` takes them as they \
                 are)",
                "normals",
                crate::normals::unoriented_text(&args.scan, &o),
                o.turned
            );
            let (positions, _) = cloud.into_parts();
            (
                zeroset_field_core::PointCloud3::with_normals(positions, o.estimated.normals)?,
                true,
            )
        }
        None => (cloud, false),
    };
    let points = cloud.len();
    // A scan without normals: estimate them, and fit the oriented copy (a temporary file
    // beside the output, removed however the command ends). The isolated points set aside
    // before normals are estimated (`None`: the scan has its own).
    let mut isolated_count = None;
    let (cloud, scan, _oriented) = if cloud.normals().is_none() {
        crate::fit::check_extent(&args.scan, &cloud)?;
        // (With normals, the fit stage reads the table and says this.)
        if let Some(note) = crate::normals::formations_note(&args.scan, &options) {
            outln!("{:<14}{note}", "formations");
        }
        if crate::normals::is_gempy(&args.scan, &options) {
            outln!(
                "{:<14}a GemPy surface-points table: its normals are estimated from the points' \
                 spread, which scattered interface points give poorly (the measured \
                 orientations are in the orientations table; a value file of the formations \
                 models several interfaces)",
                "note"
            );
        }
        outln!(
            "{:<14}{} has no normals: estimating them (as zeroset normals)",
            "normals",
            args.scan.display()
        );
        let facing = crate::normals::facing(args.viewpoint, &args.scan, &options, &cloud)?;
        // Isolated points first: estimated from the planes of other stray points, their
        // normals would agree with their neighbours' and pass the fit's test for a sparse patch
        // of surface.
        let isolated = find_isolated(cloud.positions(), args.outliers.ratio()?);
        isolated_count = Some(isolated.isolated);
        let (cloud, facing) = if isolated.indices.is_empty() {
            (cloud, facing)
        } else {
            outln!(
                "{:<14}{} isolated point{} set aside before the estimate (spacing > {}× the \
                 median, not on a plane with their neighbours; not fitted, and not in \
                 --outliers-out, which lists the fit's)",
                "outliers",
                isolated.isolated,
                plural(isolated.isolated),
                g(args.outliers.ratio()?)
            );
            let kept = without(&cloud, &isolated.indices)?;
            (kept, facing.without(&isolated.indices))
        };
        let (oriented, _) =
            crate::normals::orient(&cloud, args.normal_neighbours, &facing, args.quiet)?;
        drop(cloud);
        let path = temporary_file(&args.output, "ply");
        let temporary = TemporaryFile::new(Some(path.clone()));
        crate::normals::write_cloud(&path, &oriented)
            .with_context(|| format!("writing the oriented scan {}", path.display()))?;
        (oriented, path, temporary)
    } else if args.format.is_some() || args.formation.is_some() || completed > 0 || turned {
        // The stages read the scan by its extension, and whole: give them a copy that has the
        // right one, holds the formation asked for and the normals completed or turned above.
        let path = temporary_file(&args.output, "ply");
        let temporary = TemporaryFile::new(Some(path.clone()));
        crate::normals::write_cloud(&path, &cloud)
            .with_context(|| format!("writing a copy of the scan, {}", path.display()))?;
        (cloud, path, temporary)
    } else {
        (cloud, args.scan.clone(), TemporaryFile::new(None))
    };
    // The noise `auto` measured, if it did (for the bubbles' hint below).
    let mut measured = None;
    let Choice {
        method,
        why,
        auto_smoothing,
    } = choose(args.method, points, args.smoothing, || {
        // Measured on the points the fit will take, as the RBF fit's own warning is.
        let (kept, _) = remove_outliers(&cloud, args.outliers.ratio()?)?;
        measured = crate::noise::measure(&kept);
        Ok(measured)
    })?;
    drop(cloud);
    if smoothed && method == ReconstructMethod::Mras {
        bail!(
            "--smoothing applies to RBF fits, and this reconstruction fits MRAS{why}, which \
             fits by least squares already: drop --smoothing, or give --method rbf"
        );
    }
    if let (Some(t), ReconstructMethod::Rbf) = (args.tolerance, method) {
        bail!(
            "--tolerance {t} applies to MRAS fits, and this reconstruction fits RBF{why}, which \
             interpolates (or smooths, --smoothing): drop --tolerance, or give --method mras"
        );
    }
    let smoothing = args
        .smoothing
        .or(auto_smoothing.then_some(SmoothingArg::Auto));
    let smoothing = smoothing.map(|s| match s {
        SmoothingArg::Auto => "auto".to_owned(),
        SmoothingArg::Fixed(mu) => mu.to_string(),
    });
    let (fit_method, mesh_method) = match method {
        ReconstructMethod::Mras => ("mras", "mc"),
        _ => ("rbf", "smc"),
    };
    outln!(
        "reconstruct:  {} ({points} points) → {}, {fit_method} field{why}",
        args.scan.display(),
        args.output.display(),
    );
    // The field file: the user's, or a temporary one removed however the command ends.
    let (field, temporary) = match &args.field {
        Some(f) => (f.clone(), TemporaryFile::new(None)),
        None => {
            let t = temporary_file(&args.output, "zsf");
            (t.clone(), TemporaryFile::new(Some(t)))
        }
    };
    let os = |s: &'static str| std::ffi::OsStr::new(s);
    // Fine unless told; an MRAS field's mesh stage picks its own default (fine, or finer for
    // a dense scan).
    let detail = match (args.detail, fit_method) {
        (None, "mras") => None,
        (detail, _) => detail
            .unwrap_or(DetailArg::Fine)
            .to_possible_value()
            .map(|v| v.get_name().to_owned()),
    };
    let mut times = Vec::new();
    // The flags every stage takes from the user (the fit always overwrites its field file).
    let common = |argv: &mut Vec<&std::ffi::OsStr>, force: bool| {
        if force {
            argv.push(os("--force"));
        }
        if args.quiet {
            argv.push(os("--quiet"));
        }
    };

    outln!("\n== 1/3 fit");
    let t = Instant::now();
    let mut argv = vec![os("fit"), scan.as_os_str(), os("--method"), os(fit_method)];
    let shown = format!(
        "{}{}",
        args.scan.display(),
        match &isolated_count {
            Some(0) => " (its normals estimated above)".to_owned(),
            Some(k) => format!(" (its normals estimated above, less the {k} isolated points)"),
            None => String::new(),
        }
    );

    argv.extend([os("-o"), field.as_os_str()]);
    let ratio = args.outliers.outlier_ratio.map(|r| r.to_string());
    if let Some(r) = &ratio {
        argv.extend([os("--outlier-ratio"), std::ffi::OsStr::new(r)]);
    }
    if let Some(path) = &args.outliers.outliers_out {
        argv.extend([os("--outliers-out"), path.as_os_str()]);
    }
    if let Some(mu) = smoothing.as_ref().filter(|_| fit_method == "rbf") {
        argv.extend([os("--smoothing"), std::ffi::OsStr::new(mu)]);
    }
    let tolerance = args.tolerance.map(|t| t.to_string());
    if let Some(t) = tolerance.as_ref().filter(|_| fit_method == "mras") {
        argv.extend([os("--tolerance"), std::ffi::OsStr::new(t)]);
    }
    common(&mut argv, true);
    let mut fit_args = stage::<FitArgs>(&argv)?;
    if scan != args.scan {
        fit_args.points_shown_as = Some(shown);
    }
    // Their thickness and orientation were read above (turned where they were unoriented).
    fit_args.checked_by_reconstruct = true;
    crate::fit::run(&fit_args).context("reconstruct, stage 1 (fit)")?;
    times.push(("fit", t.elapsed()));

    outln!("\n== 2/3 mesh");
    let t = Instant::now();
    let mut argv = vec![
        os("mesh"),
        field.as_os_str(),
        os("-o"),
        args.output.as_os_str(),
    ];
    argv.extend([os("--method"), os(mesh_method)]);
    let resolution = args.resolution.map(|n| n.to_string());
    let voxel = args.voxel.map(|h| h.to_string());
    match (&resolution, &voxel) {
        (Some(n), _) => argv.extend([os("--resolution"), std::ffi::OsStr::new(n)]),
        (None, Some(h)) => argv.extend([os("--voxel"), std::ffi::OsStr::new(h)]),
        (None, None) => {
            if let Some(detail) = &detail {
                argv.extend([os("--detail"), std::ffi::OsStr::new(detail)]);
            }
        }
    }
    // A scan's mesh wants neither sheets no point supports nor blobs around stray points:
    // dropped unless the user keeps them (`zeroset mesh` only reports them by default).
    if !args.keep_spurious {
        argv.push(os("--drop-spurious"));
    }
    let trim = args.trim.map(|r| format!("--trim={r}"));
    if let Some(trim) = &trim {
        argv.push(std::ffi::OsStr::new(trim));
    }
    if args.close {
        argv.push(os("--close=scan"));
    }
    // MRAS fields record the points they fitted; RBF fields' centres include the off-surface
    // points, so the mesh stage reads the scan again (stray points set aside as the fit did).
    let scan_ratio = args.outliers.ratio()?.to_string();
    if method != ReconstructMethod::Mras {
        argv.extend([os("--scan"), scan.as_os_str()]);
        argv.extend([
            os("--scan-outlier-ratio"),
            std::ffi::OsStr::new(&scan_ratio),
        ]);
    }
    common(&mut argv, args.force);
    let mut mesh_args = stage::<MeshArgs>(&argv)?;
    // Normals turned towards a viewpoint face into the solid by request (a room scanned from
    // inside: the solid is what lies outside it).
    mesh_args.turn_inside_out = args.viewpoint.is_none() && !args.keep_inside_out;
    let components =
        crate::mesh::run_counting(&mesh_args).context("reconstruct, stage 2 (mesh)")?;
    times.push(("mesh", t.elapsed()));
    let bubbles = bubbles_hint(
        method,
        args.tolerance,
        components.as_deref(),
        measured.as_ref(),
    );

    if let Some(png) = &preview {
        outln!("\n== 3/3 preview");
        let t = Instant::now();
        let mut argv = vec![
            os("preview"),
            args.output.as_os_str(),
            os("-o"),
            png.as_os_str(),
            os("--up"),
            os(match args.up {
                crate::preview::Up::X => "x",
                crate::preview::Up::Y => "y",
                crate::preview::Up::Z => "z",
            }),
        ];
        common(&mut argv, args.force);
        crate::preview::run(&stage::<PreviewArgs>(&argv)?)
            .context("reconstruct, stage 3 (preview)")?;
        times.push(("preview", t.elapsed()));
    }
    drop(temporary);

    outln!("\n== summary");
    for (name, d) in &times {
        outln!("{name:<14}{}", seconds(*d));
    }
    outln!("{:<14}{}", "total", seconds(start.elapsed()));
    outln!(
        "{:<14}{}{}",
        "wrote",
        args.output.display(),
        preview
            .as_ref()
            .map_or(String::new(), |p| format!(", {}", p.display()))
    );
    if let Some(f) = &args.field {
        outln!("{:<14}{}", "field", f.display());
    }
    if let Some(hint) = bubbles {
        outln!("{:<14}{hint}", "note");
    }
    Ok(())
}

/// A component under this share of the largest one's triangles is small enough to be a bubble
/// ([`bubbles_hint`]).
const BUBBLE_SHARE: f64 = 0.05;

/// Where an MRAS reconstruction of a scan `auto` measured noisy (not two sheets: a thin wall)
/// came out with small pieces beside its largest (under [`BUBBLE_SHARE`] of its triangles):
/// one object's scan so noisy that the finest levels followed the noise into bubbles (CGAL's
/// `sphere_20k_normal.xyz`: 48 components at the default tolerance, one sphere at 1.5–2.5σ̂,
/// see `fit_mras::scatter_hint`), unless `--tolerance` was given. The hint names about 2σ̂.
/// `components`: each component's triangles, largest first.
fn bubbles_hint(
    method: ReconstructMethod,
    tolerance: Option<f64>,
    components: Option<&[usize]>,
    measured: Option<&crate::noise::Measured>,
) -> Option<String> {
    let m = measured
        .filter(|m| m.noise.is_noisy() && !m.noise.two_sheets_explain() && m.diagonal > 0.0)?;
    let sizes = components?;
    let largest = *sizes.first()?;
    let small = sizes
        .iter()
        .filter(|&&t| (t as f64) < BUBBLE_SHARE * largest as f64)
        .count();
    let pieces = sizes.len();
    if small == 0 {
        return None;
    }
    (method == ReconstructMethod::Mras && tolerance.is_none()).then(|| {
        format!(
            "the mesh has {pieces} components, {small} of them under {}% of the largest: if the \
             scan is of one object, they are bubbles of its noise, which the finest MRAS levels \
             followed (scatter σ ≈ {} of the diagonal); --tolerance {:.1e}, about 2σ, smooths \
             them",
            100.0 * BUBBLE_SHARE,
            g(m.noise.sigma / m.diagonal),
            2.0 * m.noise.sigma / m.diagonal
        )
    })
}

/// A temporary file beside the output, `.NAME.reconstruct-PID.EXTENSION` (the field, or the
/// scan with estimated normals); the ones a killed run left (their process gone from this
/// machine's `/proc`) are removed first. A run on another machine or in another PID namespace
/// writing to the same directory looks gone: give such runs `--field` files of their own.
fn temporary_file(output: &Path, extension: &str) -> PathBuf {
    // The whole name: `x.ply` and `x.obj` written at once do not share a field.
    let name = output
        .file_name()
        .map_or("mesh".into(), |s| s.to_string_lossy().into_owned());
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let prefix = format!(".{name}.reconstruct-");
    zeroset_field_core::io::remove_stale_files(dir, |file| {
        let pid = file
            .to_str()?
            .strip_prefix(&prefix)?
            .strip_suffix(&format!(".{extension}"))?;
        if pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        pid.parse().ok()
    });
    output.with_file_name(format!("{prefix}{}.{extension}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::Measured;
    use zeroset_bases::noise::{NOISY_SCATTER, Noise};

    /// A scan whose scatter is `relative` of its spacing; two sheets explain all of it where
    /// `sheets`.
    fn measured(relative: f64, sheets: bool) -> Measured {
        Measured {
            noise: Noise {
                sigma: relative * 0.01,
                spacing: 0.01,
                patches: 100,
                two_sheets: if sheets { 10 } else { 0 },
                sheet_patches: 10,
                sigma_within_sheets: if sheets { 1e-4 } else { relative * 0.01 },
            },
            diagonal: 1.0,
        }
    }

    /// `choose` under `--method auto`, with `--smoothing` as given, on `points` points that
    /// measure as `noise` (`None`: too few to measure); and whether it measured.
    fn auto(points: usize, smoothing: Option<f64>, noise: Option<Measured>) -> (Choice, bool) {
        let mut asked = false;
        let choice = choose(
            ReconstructMethod::Auto,
            points,
            smoothing.map(SmoothingArg::Fixed),
            || {
                asked = true;
                Ok(noise)
            },
        )
        .unwrap();
        (choice, asked)
    }

    #[test]
    fn auto_chooses_by_size_then_by_noise_and_measures_only_where_it_decides() {
        let noisy = Some(measured(2.0 * NOISY_SCATTER, false));
        let clean = Some(measured(0.5 * NOISY_SCATTER, false));
        // Beyond the RBF bound: MRAS, noisy or not, unmeasured.
        let (c, asked) = auto(AUTO_RBF_POINTS + 1, None, noisy);
        assert_eq!(c.method, ReconstructMethod::Mras);
        assert!(!asked && !c.auto_smoothing);
        assert!(
            c.why
                .contains(&format!("more than {AUTO_RBF_POINTS} points")),
            "{}",
            c.why
        );
        // ... even where --smoothing asks to smooth (the run then says MRAS takes none).
        let (c, asked) = auto(AUTO_RBF_POINTS + 1, Some(0.1), noisy);
        assert_eq!(c.method, ReconstructMethod::Mras);
        assert!(!asked && c.why.contains("more than"), "{}", c.why);
        // Up to it, a clean scan: RBF, interpolating.
        let (c, asked) = auto(AUTO_RBF_POINTS, None, clean);
        assert_eq!(c.method, ReconstructMethod::Rbf);
        assert!(asked && !c.auto_smoothing);
        assert!(c.why.contains("unless noisy"), "{}", c.why);
        // --smoothing asks for a smoothed RBF: no measurement.
        let (c, asked) = auto(AUTO_RBF_POINTS, Some(0.1), noisy);
        assert_eq!(c.method, ReconstructMethod::Rbf);
        assert!(!asked && !c.auto_smoothing);
        assert!(c.why.contains("smoothed as --smoothing asks"), "{}", c.why);
        // A noisy scan up to the smoothed bound: RBF smoothed by its noise.
        let (c, _) = auto(AUTO_SMOOTHED_POINTS, None, noisy);
        assert_eq!(c.method, ReconstructMethod::Rbf);
        assert!(c.auto_smoothing);
        assert!(
            c.why.contains("a noisy scan") && c.why.contains("--smoothing auto, MRAS beyond"),
            "{}",
            c.why
        );
        // One point more: MRAS, and why.
        let (c, _) = auto(AUTO_SMOOTHED_POINTS + 1, None, noisy);
        assert_eq!(c.method, ReconstructMethod::Mras);
        assert!(!c.auto_smoothing);
        assert!(
            c.why
                .contains(&format!("of more than {AUTO_SMOOTHED_POINTS} points"))
                && c.why.contains("interpolate the noise"),
            "{}",
            c.why
        );
        // --smoothing 0 on a noisy scan up to that bound: not an RBF through the noise.
        for points in [100, AUTO_SMOOTHED_POINTS] {
            let (c, _) = auto(points, Some(0.0), noisy);
            assert_eq!(c.method, ReconstructMethod::Mras);
            assert!(
                c.why.contains("--smoothing 0 asks not to smooth it")
                    && !c.why.contains("more than"),
                "{}",
                c.why
            );
        }
        // Two sheets that explain the reading are named as such.
        let (c, _) = auto(AUTO_SMOOTHED_POINTS + 1, None, Some(measured(1.0, true)));
        assert_eq!(c.method, ReconstructMethod::Mras);
        assert!(
            c.why.contains("two parallel sheets") && c.why.contains("between the sheets"),
            "{}",
            c.why
        );
        // Too few points to measure: as clean.
        let (c, asked) = auto(20, None, None);
        assert_eq!(c.method, ReconstructMethod::Rbf);
        assert!(asked && !c.auto_smoothing);
    }

    #[test]
    fn a_failed_measure_fails_the_choice() {
        let failed = choose(ReconstructMethod::Auto, 100, None, || {
            anyhow::bail!("unreadable")
        });
        assert_eq!(failed.unwrap_err().to_string(), "unreadable");
    }

    #[test]
    fn a_named_method_is_kept_unmeasured_and_unexplained() {
        for asked in [ReconstructMethod::Rbf, ReconstructMethod::Mras] {
            let c = choose(asked, AUTO_RBF_POINTS + 1, None, || {
                panic!("a named method measures nothing")
            })
            .unwrap();
            assert_eq!(c.method, asked);
            assert!(c.why.is_empty() && !c.auto_smoothing);
        }
    }

    #[test]
    fn bubbles_are_hinted_only_for_an_mras_mesh_of_a_noisy_scan_in_pieces() {
        use ReconstructMethod::{Mras, Rbf};
        // σ = 0.6 of a spacing of 0.01: 0.006 of the diagonal, so 2σ is 1.2e-2.
        let noisy = measured(0.6, false);
        // A large piece and 47 small ones.
        let mut pieces = vec![100_000];
        pieces.extend([400; 47]);
        let pieces = Some(pieces.as_slice());
        let hint = bubbles_hint(Mras, None, pieces, Some(&noisy)).expect("a hint");
        assert!(
            hint.contains("48 components, 47 of them under 5%"),
            "{hint}"
        );
        assert!(hint.contains("--tolerance 1.2e-2"), "{hint}");
        // One piece, pieces of like size (two objects), a tolerance given, an RBF fit, a clean,
        // two-sheet (a thin wall) or unmeasured scan, curves: none.
        assert_eq!(
            bubbles_hint(Mras, None, Some(&[100_000]), Some(&noisy)),
            None
        );
        let two = Some([100_000, 90_000].as_slice());
        assert_eq!(bubbles_hint(Mras, None, two, Some(&noisy)), None);
        assert_eq!(bubbles_hint(Mras, Some(0.01), pieces, Some(&noisy)), None);
        assert_eq!(bubbles_hint(Rbf, None, pieces, Some(&noisy)), None);
        let clean = measured(0.1, false);
        assert_eq!(bubbles_hint(Mras, None, pieces, Some(&clean)), None);
        let sheets = measured(0.6, true);
        assert!(sheets.noise.is_noisy() && sheets.noise.two_sheets_explain());
        assert_eq!(bubbles_hint(Mras, None, pieces, Some(&sheets)), None);
        assert_eq!(bubbles_hint(Mras, None, pieces, None), None);
        assert_eq!(bubbles_hint(Mras, None, None, Some(&noisy)), None);
    }
}
