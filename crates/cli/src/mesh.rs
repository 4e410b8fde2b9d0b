//! `zeroset mesh FIELD -o OUT.ply|OUT.obj`: the level set of a field file as a triangle mesh.
//!
//! The field (a `.zsf` file of any kind: the RBF or neural field of `zeroset fit -o`, or a
//! B-spline field from `zeroset fit -o --sampled` or `zeroset restore`) is sampled on a
//! vertex-centred grid of cubic voxels covering its box and
//! its level set extracted by marching cubes (`zeroset_mesh::cubes`). The voxel edge comes from
//! the bounding box by the signed-marching-cubes paper's rule (`zeroset_mesh::voxel`: `5·l0`
//! coarse, `l0` general, `0.3·l0` fine), from `--resolution` (voxels along the longest axis) or
//! from `--voxel`. The mesh is checked, reported and written atomically as PLY or OBJ. Plain
//! marching cubes on a large RBF field (a direct sum over every centre at every vertex) says
//! its estimated time first when that is over half a minute, and points to `--method smc`.
//!
//! `--method smc` (RBF fields only) is the two-step signed marching cubes of paper 002: the
//! signs of the grid vertices are settled by the fast multipole method at a low order `p`
//! (`--order`), and the field is evaluated at a high order `P` (`--high-order`) only at the
//! vertices of voxels whose sign is uncertain or changes (`zeroset_bases::rbf::fmm::OrderPair`,
//! `zeroset_mesh::signed`). Step 1 settles whole blocks of vertices at once where the low-order
//! field's enclosure clears the level (`--step blocks`), evaluates every vertex as the paper
//! does (`--step every`), or picks one by probing 512 blocks (`--step auto`, the default). The
//! mesh is the one plain marching cubes gives with order `P` everywhere; the output reports the
//! paper's Table 3 counts.
//!
//! A 2-D field (a curve, e.g. from `zeroset fit curve.xyv --method neural`) has no surface: its
//! level curve is traced by marching squares on square cells (`--resolution` along the longer
//! axis, default 256, or `--voxel`) and written as an SVG (`-o OUT.svg`).

use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};

use zeroset_bases::field_file::{AnyField, RbfAny, read_any_field, read_dimension};
use zeroset_bases::outliers::DEFAULT_OUTLIER_RATIO;
use zeroset_bases::rbf::fmm::cache::{self, Cached};
use zeroset_bases::rbf::fmm::{DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY, FmmOptions, OrderPair};
use zeroset_bases::rbf::{Kernel, RbfField};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::Point;
use zeroset_field_core::{Aabb, Grid};
use zeroset_mesh::signed::{
    CoarseStep, SmcOptions, SmcStage, expected_evaluations, settled_fraction, signed_marching_cubes,
};
use zeroset_mesh::squares::contour_field;
use zeroset_mesh::svg::SvgPlot;
use zeroset_mesh::trim::{DEFAULT_REACH, Region, ScanSupport, split};
use zeroset_mesh::voxel::{self, Detail, ScanFloor, VoxelRule};
use zeroset_mesh::{
    McOptions, MeshFormat, TriMesh, boundary_loops, check, component_support, components,
    mesh_field, unsupported_components, write_mesh,
};

use crate::info::{g, point};
use crate::machine::ensure_memory;
use crate::progress::{seconds, spinner};

mod plan;

/// Shown after `zeroset mesh --help`.
pub const EXAMPLES: &str = "\
Examples:
  # fit a field, then mesh its zero set (binary PLY, voxel by the l0 rule)
  zeroset fit samples/bunny_2k.xyzn --method rbf -o bunny.zsf
  zeroset mesh bunny.zsf -o bunny.ply
  # finer voxels, an ASCII PLY; or a Wavefront OBJ
  zeroset mesh bunny.zsf -o bunny_fine.ply --detail fine --ascii
  zeroset mesh bunny.zsf -o bunny.obj --resolution 128
  # an explicit voxel edge, another level, capped where it leaves the grid
  zeroset mesh bunny.zsf -o shell.ply --voxel 0.002 --level 0.01 --close --force
  # a one-sided scan's surface cut where the scan ends (RBF fields: give the scan)
  zeroset mesh face.zsf -o face.ply --trim --scan face_scan.ply
  # two-step signed marching cubes with the fast multipole method (orders 5 and 10)
  zeroset mesh bunny.zsf -o bunny_smc.ply --method smc --order 5 --high-order 10 --detail fine
  # a 2-D field's zero curve by marching squares, as SVG
  zeroset fit samples/curve.xyv --method neural -o curve.zsf
  zeroset mesh curve.zsf -o curve.svg --resolution 400";

/// Surface-extraction method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// Marching cubes on the whole grid (watertight; ambiguous faces by the asymptotic decider).
    Mc,
    /// Two-step signed marching cubes (RBF fields): the fast multipole method at --order
    /// everywhere, at --high-order only where the sign is uncertain; the same mesh as `mc` at
    /// --high-order.
    Smc,
}

/// How step 1 of --method smc settles the grid vertices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StepArg {
    /// Blocks where a probe of 512 blocks finds that at least half settle, every vertex
    /// otherwise (biharmonic `r` fields settle most blocks, triharmonic `r3` ones few).
    Auto,
    /// Settle whole blocks of vertices by enclosures of the low-order field; evaluate it only
    /// in the blocks near the surface.
    Blocks,
    /// The paper's step 1: the low order at every grid vertex.
    Every,
}

/// Accuracy class of the voxel-size rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DetailArg {
    /// Voxel 5·l0.
    Coarse,
    /// Voxel l0.
    General,
    /// Voxel 0.3·l0.
    Fine,
}

impl From<DetailArg> for Detail {
    fn from(d: DetailArg) -> Self {
        match d {
            DetailArg::Coarse => Detail::Coarse,
            DetailArg::General => Detail::General,
            DetailArg::Fine => Detail::Fine,
        }
    }
}

/// Where `--close` caps the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CloseArg {
    /// On the faces of the field's box.
    Box,
    /// On the faces of the scan's bounding box.
    Scan,
}

/// Arguments of `zeroset mesh`.
#[derive(Debug, Args)]
pub struct MeshArgs {
    /// The field file (.zsf): an RBF, MRAS or neural field (`zeroset fit -o`) or a B-spline
    /// field (`zeroset fit -o --sampled`, `zeroset restore`); meshed over the box it records.
    pub field: PathBuf,

    /// The mesh file: .ply (binary little-endian, or --ascii), .obj, .stl (binary, or
    /// --ascii; for 3-D printing and CAD) or .off, written atomically; .svg for the level curve
    /// of a 2-D field.
    #[arg(short, long, value_name = "OUT.ply|OUT.obj|OUT.stl|OUT.off|OUT.svg")]
    pub output: PathBuf,

    /// Surface-extraction method.
    #[arg(long, value_enum, default_value_t = Method::Mc)]
    pub method: Method,

    /// Low expansion order p of --method smc (Chebyshev nodes per axis, 2 to 16). 5 suits
    /// biharmonic (r) fields; triharmonic (r3) ones need about 8 (their errors are larger).
    #[arg(long, default_value_t = 5, value_name = "p")]
    pub order: usize,

    /// High expansion order P of --method smc (at least --order).
    #[arg(long, default_value_t = 10, value_name = "P")]
    pub high_order: usize,

    /// With --method smc: run the signed marching cubes even where plain marching cubes on the
    /// exact field is estimated to be faster (by default that one runs then, and says so).
    #[arg(long)]
    pub always_smc: bool,

    /// Step 1 of --method smc: settle blocks of vertices by enclosures, evaluate every vertex,
    /// or choose by a probe.
    #[arg(long, value_enum, default_value_t = StepArg::Auto)]
    pub step: StepArg,

    /// The level to extract (the zero set by default; fields are negative inside).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub level: f64,

    /// Voxel edge by the l0 rule of the field's box: coarse 5·l0, general l0, fine 0.3·l0, with
    /// l0 = clamp(0.05·shortest, 0.005·longest, 0.025·longest) axis length [default: general;
    /// fine for MRAS fields, fitted to scans within 1e-3 of their diagonal, which general
    /// voxels would not resolve; for an MRAS field of points denser than fine voxels, 2 × their
    /// median spacing, but no finer than half its finest splines' knot spacing (the finest
    /// detail it holds) nor 512 voxels along the longest axis: the l0 rule sees the box, not
    /// how densely it was scanned. The points: those the field records (--scan's for a field
    /// that records none)].
    #[arg(long, value_enum, conflicts_with_all = ["resolution", "voxel"])]
    pub detail: Option<DetailArg>,

    /// N cubic voxels along the longest axis of the field's box (at least 2).
    #[arg(long, value_name = "N", conflicts_with = "voxel")]
    pub resolution: Option<usize>,

    /// An explicit voxel edge, in world units.
    #[arg(long, value_name = "H", allow_hyphen_values = true)]
    pub voxel: Option<f64>,

    /// Cap the surface where it leaves the grid, so that the mesh is closed: on the faces of
    /// the field's box (`--close`, `--close=box`), or of the scan's own bounding box
    /// (`--close=scan`: the grid spans the points' box, so that a scan whose bottom was not
    /// seen — on a turntable, a table — is capped flat where its sides end, not a margin
    /// below; a tilted or ragged rim is capped at the box's face past its lowest point). The
    /// points: --scan's (isolated stray points set aside), or those an MRAS field records; the
    /// box is kept within the field's, and the voxel is the one chosen without --close, each
    /// axis's shrunk to fit a whole number into the scan's box. Not with --trim.
    #[arg(long, value_enum, value_name = "box|scan", num_args = 0..=1, require_equals = true,
          default_missing_value = "box", conflicts_with = "trim")]
    pub close: Option<CloseArg>,

    /// Remove the components of the mesh with no input point within 3 voxels, and those
    /// fitted to fewer than 4 input points (blobs around stray points near the surface; the
    /// points nearer to them than to any other component: the scan's with --scan, else those
    /// an MRAS field records; an RBF field's are counted only with --scan). RBF and MRAS
    /// fields record their points (an RBF field's centres); the report lists such components
    /// either way.
    #[arg(long)]
    pub drop_spurious: bool,

    /// Cut the mesh where it leaves the scan's reach, REACH local point spacings (default 1.5)
    /// beyond its nearest points: for one-sided scans (a face, a façade, terrain), whose
    /// surface otherwise runs on to the box, and to reopen holes the scan left. Needs the
    /// points: MRAS fields record them; for other fields give --scan.
    #[arg(long, value_name = "REACH", num_args = 0..=1, require_equals = true,
          default_missing_value = "1.5")]
    pub trim: Option<f64>,

    /// The scan the field was fitted to, for --trim and the report's coverage line (default:
    /// the points an MRAS field records; RBF fields record their centres, the off-surface ones
    /// among them); for an MRAS field that records none, also the density the default voxel
    /// follows. Stray points are set aside first, as `zeroset fit` does.
    #[arg(long, value_name = "SCAN")]
    pub scan: Option<PathBuf>,

    /// The stray-point ratio for --scan (as `zeroset fit --outlier-ratio`; 0 keeps every
    /// point). `zeroset reconstruct` passes its own.
    #[arg(long, value_name = "R", default_value_t = DEFAULT_OUTLIER_RATIO, hide = true)]
    pub scan_outlier_ratio: f64,

    /// Write an ASCII PLY or STL instead of binary (OBJ is always text).
    #[arg(long)]
    pub ascii: bool,

    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,

    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,

    /// Whether a closed mesh that comes out inside out is turned over before it is written
    /// (`zeroset reconstruct` does, for a scan whose normals point inward, unless they were
    /// turned towards a --viewpoint); not an option.
    #[arg(skip)]
    pub turn_inside_out: bool,
}

/// How far the level set `f = level` lies from the zero set near `points`: `|level|` over the
/// median gradient norm at up to 1,024 of them, evenly spread (0 at level 0, or where no
/// gradient there is finite and non-zero).
fn level_offset(field: &AnyField<3>, points: &[Point<3>], level: f64) -> f64 {
    if level == 0.0 || points.is_empty() {
        return 0.0;
    }
    let step = points.len().div_ceil(1024);
    let mut norms: Vec<f64> = points
        .iter()
        .step_by(step)
        .map(|p| field.gradient(p).iter().map(|v| v * v).sum::<f64>().sqrt())
        .filter(|n| n.is_finite() && *n > 0.0)
        .collect();
    if norms.is_empty() {
        return 0.0;
    }
    norms.sort_by(f64::total_cmp);
    level.abs() / norms[norms.len() / 2]
}

/// The share of the mesh's area below which a region beyond the scan's reach is a speck: not
/// counted with the regions of the `unseen:` line (only as specks), and no line where the
/// largest is one.
const UNSEEN_SHARE: f64 = 1e-4;

/// The `unseen:` line for the regions beyond the scan's reach (largest first) of a mesh of
/// area `area`: how many, the largest one's share, extent and centre; the specks (under
/// [`UNSEEN_SHARE`] of the area each) counted apart, so that crumbs do not swell the count.
/// `None` where the largest region is itself a speck.
fn unseen_line(unseen: &[Region], area: f64) -> Option<String> {
    let regions = unseen
        .iter()
        .take_while(|r| r.area >= UNSEEN_SHARE * area)
        .count();
    let largest = unseen.first().filter(|_| regions > 0)?;
    let specks = match unseen.len() - regions {
        0 => String::new(),
        n => format!(
            " (and {n} speck(s), each under {}% of the area)",
            100.0 * UNSEEN_SHARE
        ),
    };
    let b = &largest.bounds;
    Some(format!(
        "unseen: {regions} region(s){specks} beyond the scan's reach, where the surface is the \
         field's guess (holes in the scan it closed, sides never scanned); the largest, {:.2}% \
         of the area, spans {} around {}",
        100.0 * largest.area / area.max(f64::MIN_POSITIVE),
        b.extent().map(g).join(" × "),
        point(b.center())
    ))
}

/// A mesh component with no input point within this many voxels is reported as spurious.
const SPURIOUS_VOXELS: f64 = 3.0;

/// A component fitted to fewer input points than this (the points nearer to it than to any
/// other component, within [`SPURIOUS_VOXELS`]) is reported as weak: a closed surface through
/// three points or fewer is the field's guess, not a shape the scan measured — it is what an
/// implicit fit grows around a stray point a few spacings off the surface, which no spacing
/// rule tells from a point of the surface. Counted over the scan's points (`--scan`) or the
/// points an MRAS field records; not for an RBF field without `--scan`, whose centres are no
/// count of points.
const MIN_SUPPORT: usize = 4;

/// The components [`MIN_SUPPORT`] calls weak, given each one's support and which are spurious
/// already: never the best-supported of the others, so that the two rules together never
/// empty a mesh that has a component with an input point in reach.
fn weak_components(support: &[usize], far: &[bool]) -> Vec<bool> {
    let best = (0..support.len())
        .filter(|&l| !far[l])
        .max_by_key(|&l| (support[l], std::cmp::Reverse(l)));
    (0..support.len())
        .map(|l| !far[l] && support[l] < MIN_SUPPORT && Some(l) != best)
        .collect()
}

/// The share of a mesh's area beyond the scan's reach above which the report suggests --trim:
/// a closed scan's small holes stay under it (the bunny's five: 0.3%), the surface a
/// one-sided scan leaves to the field's guess does not (at the default reach: a half
/// sphere's 10%, a terrain patch's 19%, the bunny's front's 57%).
const OPEN_SCAN_SHARE: f64 = 0.05;

/// Refuses a `--resolution` under 2 or a `--voxel` that is not a finite positive length
/// (`zeroset mesh`'s, and `zeroset reconstruct`'s before its fit).
pub(crate) fn check_voxel(resolution: Option<usize>, voxel: Option<f64>) -> anyhow::Result<()> {
    if let Some(n) = resolution
        && n < 2
    {
        bail!("--resolution must be at least 2 voxels along the longest axis, got {n}");
    }
    if let Some(h) = voxel
        && !(h.is_finite() && h > 0.0)
    {
        bail!("--voxel must be a finite positive length, got {h}");
    }
    Ok(())
}

/// The box `--close=scan` caps on: the points' bounding box grown by [`SCAN_BOX_MARGIN`]
/// voxels of edge `h`, so that a face the scan samples lies inside the grid, not on it, and by
/// `offset` (the distance of an outer level set from the points). Refused where the points
/// are flat along an axis (a one-sided scan: terrain, a façade), whose box has no inside to
/// cap.
fn scan_box(points: &[Point<3>], h: f64, offset: f64) -> anyhow::Result<Aabb<3>> {
    let tight = Aabb::from_points(points).context("--close=scan: the scan has no points")?;
    let extent = tight.extent();
    if let Some(axis) = (0..3).find(|&a| extent[a] < SCAN_BOX_THINNEST * h) {
        bail!(
            "--close=scan: the scan's box is {} thick along {}, under {SCAN_BOX_THINNEST} voxels \
             ({}): a one-sided or flat scan has no inside to cap (--trim cuts its surface where \
             the scan ends instead)",
            g(extent[axis]),
            ["x", "y", "z"][axis],
            g(h)
        );
    }
    Ok(tight.expanded(SCAN_BOX_MARGIN * h + offset))
}

/// How far past the scan's points `--close=scan` caps, in voxels: a face the scan samples
/// would otherwise lie on the grid's last samples, where the field's zero meets the cap; this
/// puts the cap that little below a turntable scan's lowest points.
const SCAN_BOX_MARGIN: f64 = 0.01;

/// The fewest voxels the scan's box must span along every axis for `--close=scan`.
const SCAN_BOX_THINNEST: f64 = 2.0;

/// The points of `path` for trimming, the coverage line and `--close=scan`: positions, stray
/// points set aside with `ratio` (by the fit's rule where the scan has normals, else its
/// isolated points).
fn read_scan(path: &std::path::Path, ratio: f64) -> anyhow::Result<Vec<[f64; 3]>> {
    if !zeroset_bases::outliers::valid_ratio(ratio) {
        bail!("the stray-point ratio must be 0 (off) or at least 1.5, got {ratio}");
    }
    let (cloud, _) = crate::normals::read_positions(path, &Default::default(), "--scan", true)
        .context("--scan")?;
    // The stray-point rule below reads the normals: none may be zero.
    let (cloud, _) = crate::normals::complete_normals(path, cloud, None).context("--scan")?;
    let (kept, _) = zeroset_bases::outliers::remove_outliers(&cloud, ratio)
        .with_context(|| format!("--scan {}", path.display()))?;
    // A scan without normals keeps every point through that rule: its isolated ones are set
    // aside as `zeroset reconstruct` does before estimating normals (one stray point far off
    // would stretch --close=scan's box, and --trim's reach, to it).
    if kept.normals().is_some() || ratio == 0.0 {
        return Ok(kept.positions().to_vec());
    }
    let isolated = zeroset_bases::outliers::find_isolated(kept.positions(), ratio);
    let kept = zeroset_bases::outliers::without(&kept, &isolated.indices)
        .with_context(|| format!("--scan {}", path.display()))?;
    Ok(kept.positions().to_vec())
}

/// The report's lines ([`say_line`](crate::output::say_line): once stdout is closed,
/// `zeroset mesh ... | head`, printing stops but the work goes on and the mesh is written).
#[derive(Debug)]
struct Say;

impl Say {
    #[allow(clippy::unnecessary_wraps)] // `say!(out, …)?` reads like the writes around it
    fn line(&mut self, text: std::fmt::Arguments<'_>) -> anyhow::Result<()> {
        crate::output::say_line(text);
        Ok(())
    }
}

/// `println!` that survives a closed stdout: `say!(out, "...", args)?`.
macro_rules! say {
    ($out:expr, $($arg:tt)*) => {
        $out.line(format_args!($($arg)*))
    };
}

/// `--method smc` on a field it cannot evaluate (all but RBF fields).
fn smc_refusal(args: &MeshArgs, field: &AnyField<3>) -> anyhow::Error {
    anyhow::anyhow!(
        "--method smc evaluates RBF fields by the fast multipole method; {} holds a field of kind \
         {}: use --method mc",
        args.field.display(),
        field.kind()
    )
}

/// Runs `zeroset mesh`.
pub fn run(args: &MeshArgs) -> anyhow::Result<()> {
    mesh_and_count(args, false).map(|_| ())
}

/// [`run`], returning the triangles of each of the written surface's components, largest
/// first (`None` for a 2-D field's curves).
pub(crate) fn run_counting(args: &MeshArgs) -> anyhow::Result<Option<Vec<usize>>> {
    mesh_and_count(args, true)
}

/// [`run`]; with `count`, the components' triangles as [`run_counting`] gives them (a second
/// labelling of the mesh, which plain `zeroset mesh` does not pay for).
fn mesh_and_count(args: &MeshArgs, count: bool) -> anyhow::Result<Option<Vec<usize>>> {
    let mut out = Say;
    match read_dimension(&args.field) {
        Ok(2) => return curve(args, &mut out).map(|()| None),
        // An SVG is a curve's output: say why the field cannot be read rather than that the
        // extension is not a mesh's.
        Err(e)
            if args
                .output
                .extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("svg")) =>
        {
            return Err(e).with_context(|| format!("reading {}", args.field.display()));
        }
        _ => {}
    }
    let format = check_output(args)?;
    if !args.level.is_finite() {
        bail!("--level must be finite, got {}", args.level);
    }
    if let Some(reach) = args.trim
        && !(reach.is_finite() && reach > 0.0)
    {
        bail!("--trim takes a finite positive reach (in local point spacings), got {reach}");
    }
    let total = Instant::now();

    let start = Instant::now();
    let scan = args
        .scan
        .as_deref()
        .map(|path| read_scan(path, args.scan_outlier_ratio))
        .transpose()?;
    let field = read_any_field::<3>(&args.field)
        .with_context(|| format!("reading {}", args.field.display()))?;
    let reading = start.elapsed();
    if args.method == Method::Smc && !matches!(field, AnyField::Rbf(_)) {
        return Err(smc_refusal(args, &field));
    }
    let bounds = field
        .bounds()
        .with_context(|| format!("the field in {} has no bounds", args.field.display()))?;
    say!(
        out,
        "field {}: {} over min {} max {}",
        args.field.display(),
        field.describe(),
        point(bounds.min()),
        point(bounds.max())
    )?;

    let l0 = voxel::l0(&bounds);
    check_voxel(args.resolution, args.voxel)?;
    // The points the field was fitted to, where an MRAS field records them.
    let recorded = match &field {
        AnyField::Mras(f) if !f.unit_points().is_empty() => Some(f.points()),
        _ => None,
    };
    // The scan's reach (its local spacings), for the coverage check and --trim below; measured
    // here already when the default voxel follows the density of the same points.
    let reach = args.trim.unwrap_or(DEFAULT_REACH);
    let mut support = None;
    // The time that takes, counted with the meshing (it chose the grid).
    let mut measuring = Duration::ZERO;
    let (h, how) = match (args.resolution, args.voxel) {
        (Some(n), _) => {
            let longest = bounds.extent().into_iter().fold(0.0, f64::max);
            (
                longest / n as f64,
                format!("{n} voxels along the longest axis"),
            )
        }
        (None, Some(h)) => (h, "--voxel".to_string()),
        (None, None) => {
            let default = if field.wants_fine_mesh() {
                DetailArg::Fine
            } else {
                DetailArg::General
            };
            let detail = Detail::from(args.detail.unwrap_or(default));
            let by_l0 = voxel::voxel_size(&bounds, detail);
            let rule = format!(
                "{} × l0, {detail:?} detail; l0 = {}",
                g(detail.factor()),
                g(l0)
            );
            // By default an MRAS field is meshed no coarser than the points it was fitted to
            // are spaced (those it records; --scan's for a field that records none): it holds
            // no finer detail than they do.
            let fitted = recorded.as_deref().or(scan.as_deref());
            // The smallest detail the field holds: its finest splines' knot spacing.
            let field_detail = match &field {
                AnyField::Mras(f) => f.finest_spacing().unwrap_or(0.0),
                _ => 0.0,
            };
            let measure = || {
                let (None, true, Some(points)) = (args.detail, field.wants_fine_mesh(), fitted)
                else {
                    return None;
                };
                let t = Instant::now();
                let measured = ScanSupport::new(points, reach).ok();
                let spacing = measured.as_ref().map(ScanSupport::median_spacing);
                measuring = t.elapsed();
                // The checks below measure --scan's points when given, these otherwise.
                if scan.is_none() {
                    support = measured;
                }
                spacing
            };
            let (h, chosen) = voxel::default_voxel(&bounds, detail, field_detail, measure);
            // Why the scan's spacing gave a finer voxel than the l0 rule, in the grid line.
            let dense = |s: f64, why: String| {
                format!(
                    "{why}: the points the field was fitted to, spaced {}, are denser than \
                     {detail:?} voxels of {} ({rule}), which --detail fine keeps",
                    g(s),
                    g(by_l0)
                )
            };
            let spacings = |s: f64| g(voxel::SCAN_SPACINGS * s);
            let how = match chosen {
                VoxelRule::Detail => rule.clone(),
                VoxelRule::Spacing(s) => dense(
                    s,
                    format!("{} × the scan's median spacing", voxel::SCAN_SPACINGS),
                ),
                VoxelRule::Floor {
                    spacing: s,
                    floor: ScanFloor::MaxVoxels,
                } => dense(
                    s,
                    format!(
                        "{} voxels along the longest axis, the most for a dense scan ({} × its \
                         median spacing would be {})",
                        voxel::SCAN_MAX_VOXELS,
                        voxel::SCAN_SPACINGS,
                        spacings(s)
                    ),
                ),
                VoxelRule::Floor {
                    spacing: s,
                    floor: ScanFloor::FieldDetail,
                } => dense(
                    s,
                    format!(
                        "{} × the knot spacing {} of the field's finest splines, the finest \
                         detail it holds ({} × the scan's median spacing would be {})",
                        voxel::SCAN_DETAIL_SHARE,
                        g(field_detail),
                        voxel::SCAN_SPACINGS,
                        spacings(s)
                    ),
                ),
            };
            (h, how)
        }
    };
    if !(h.is_finite() && h > 0.0) {
        bail!(
            "the field's box is a point: no voxel size follows from it; give --voxel (got {})",
            g(h)
        );
    }
    let grid = match args.close {
        Some(CloseArg::Scan) => {
            let points = match (&scan, &field) {
                (Some(points), _) => points.clone(),
                (None, AnyField::Mras(f)) if !f.unit_points().is_empty() => f.points(),
                _ => bail!(
                    "--close=scan caps the surface on the scan's bounding box: give the scan \
                     with --scan (only MRAS fields record their points)"
                ),
            };
            // A level set outside the zero set (level > 0) lies that far past the points.
            let offset = if args.level > 0.0 {
                level_offset(&field, &points, args.level)
            } else {
                0.0
            };
            let wanted = scan_box(&points, h, offset)?;
            let min = std::array::from_fn(|a| wanted.min()[a].max(bounds.min()[a]));
            let max = std::array::from_fn(|a| wanted.max()[a].min(bounds.max()[a]));
            let capped = Aabb::new(min, max)
                .ok()
                .filter(|b| b.extent().iter().all(|&e| e > 0.0))
                .context(
                    "--close=scan: the scan's box does not overlap the field's (is --scan the \
                     scan this field was fitted to?)",
                )?;
            say!(
                out,
                "close: capped on the scan's box{}, min {} max {}",
                if capped == wanted {
                    String::new()
                } else {
                    " where it lies inside the field's (the scan reaches past it)".to_owned()
                },
                point(capped.min()),
                point(capped.max())
            )?;
            voxel::grid_spanning(&capped, h)
        }
        _ => voxel::grid_for(&bounds, h, 0.0),
    }
    .with_context(|| {
        format!(
            "building the sampling grid for a voxel of {} ({how}); choose a larger --voxel, a \
             smaller --resolution or a coarser --detail",
            g(h)
        )
    })?;
    let c = grid.counts();
    let samples = grid.len();
    // grid_spanning's voxels are at most h, each axis its own.
    let spacing = grid.spacing();
    let voxel_shown = if spacing.iter().all(|&d| (d - h).abs() <= 1e-9 * h) {
        g(h)
    } else {
        format!(
            "{} × {} × {} (at most {}, fitted to the scan's box)",
            g(spacing[0]),
            g(spacing[1]),
            g(spacing[2]),
            g(h)
        )
    };
    say!(
        out,
        "grid {}×{}×{} = {samples} samples, voxel {voxel_shown} ({how})",
        c[0],
        c[1],
        c[2],
    )?;
    ensure_memory(
        voxel::estimate_bytes(&grid),
        &format!("the grid {}×{}×{}", c[0], c[1], c[2]),
        "choose a larger --voxel, a smaller --resolution or a coarser --detail",
    )?;

    let start = Instant::now();
    let options = McOptions::default().with_close_boundary(args.close.is_some());
    if args.method == Method::Mc {
        hint_signed(&field, &grid, &mut out)?;
    }
    let mesh = match args.method {
        Method::Mc => with_spinner(args.quiet, "sampling the field and marching cubes", || {
            mesh_field(&field, &grid, args.level, &options)
        })
        .context("extracting the level set")?,
        Method::Smc => match &field {
            AnyField::Rbf(RbfAny::R(f)) => smc_or_plain(f, &grid, &options, args, &mut out)?,
            AnyField::Rbf(RbfAny::R3(f)) => smc_or_plain(f, &grid, &options, args, &mut out)?,
            AnyField::Rbf(RbfAny::Tps(f)) => smc_or_plain(f, &grid, &options, args, &mut out)?,
            AnyField::Rbf(RbfAny::Wendland(f)) => smc_or_plain(f, &grid, &options, args, &mut out)?,
            AnyField::BSpline(_) | AnyField::Neural(_) | AnyField::Mras(_) => {
                return Err(smc_refusal(args, &field));
            }
        },
    };
    let meshing = start.elapsed() + measuring;

    let start = Instant::now();
    let mut report = check(&mesh);
    // Components far from every input point (RBF and MRAS fields record their points).
    let points = match &field {
        AnyField::Rbf(f) => Some(f.centres()),
        _ => recorded.as_deref(),
    };
    let mut mesh = mesh;
    let mut dropped_all = false;
    match points {
        Some(points) if !mesh.is_empty() => {
            let (labels, count) = components(&mesh);
            // At a level other than 0 the surface is an offset of the one fitted to the
            // points: their distance to it is no sign of a spurious piece.
            let offset = level_offset(&field, points, args.level);
            let radius = SPURIOUS_VOXELS * h + offset;
            let within = if offset > 0.0 {
                format!(
                    "{SPURIOUS_VOXELS} voxels plus the level's offset {}",
                    g(offset)
                )
            } else {
                format!("{SPURIOUS_VOXELS} voxels")
            };
            let far = unsupported_components(&mesh, &labels, count, points, radius);
            // The input points each component is fitted to: the scan's when given, else those
            // an MRAS field records. An RBF field's centres are no count of points (about 3
            // per point off-surface, 4 at one position with --hermite, fewer than the points
            // after a greedy fit), so without --scan its components are not counted.
            let support = scan
                .as_deref()
                .or(recorded.as_deref())
                .map(|input| component_support(&mesh, &labels, count, input, radius));
            let weak = support
                .as_deref()
                .map_or_else(|| vec![false; count], |s| weak_components(s, &far));
            // The other way round: input points no component is near (stray points, or parts
            // thinner than the voxels, which the grid steps over).
            if let (Some(s), Some(input)) = (&support, scan.as_deref().or(recorded.as_deref())) {
                let finite = input
                    .iter()
                    .filter(|p| p.iter().all(|v| v.is_finite()))
                    .count();
                let missed = finite.saturating_sub(s.iter().sum());
                if missed > 0 {
                    say!(
                        out,
                        "missed: {missed} of {finite} input points ({:.2}%) have no vertex \
                         within {within} ({}): stray points, or parts smaller than the voxels \
                         (a smaller --voxel meshes those)",
                        100.0 * missed as f64 / finite.max(1) as f64,
                        g(radius),
                    )?;
                }
            }
            let support = support.unwrap_or_default();
            let triangles_in =
                |which: &[bool]| labels.iter().filter(|&&l| which[l as usize]).count();
            let removal = if args.drop_spurious {
                "; dropped"
            } else {
                "; --drop-spurious removes them"
            };
            let spurious = far.iter().filter(|f| **f).count();
            if spurious > 0 {
                say!(
                    out,
                    "spurious: {spurious} of {count} component(s), {} triangles, have no \
                     input point within {within} ({}){removal}",
                    triangles_in(&far),
                    g(radius),
                )?;
            } else {
                say!(
                    out,
                    "spurious: none (every component has an input point within {within})"
                )?;
            }
            let weak_count = weak.iter().filter(|w| **w).count();
            if weak_count > 0 {
                let most = (0..count)
                    .filter(|&l| weak[l])
                    .map(|l| support[l])
                    .max()
                    .unwrap_or(0);
                let fitted = match most {
                    0 => "no input point".to_owned(),
                    1 => "at most 1 input point each".to_owned(),
                    n => format!("at most {n} input points each"),
                };
                say!(
                    out,
                    "weak: {weak_count} of {count} component(s), {} triangles, are fitted to \
                     {fitted} (fewer than {MIN_SUPPORT}: blobs around stray points near the \
                     surface?){removal}",
                    triangles_in(&weak),
                )?;
            }
            if args.drop_spurious && (spurious > 0 || weak_count > 0) {
                mesh = mesh.retain_triangles(|t| {
                    let l = labels[t] as usize;
                    !far[l] && !weak[l]
                });
                report = check(&mesh);
                dropped_all = mesh.is_empty();
            }
        }
        Some(_) => {}
        None if args.drop_spurious => bail!(
            "--drop-spurious needs the points the field was fitted to; {} holds a {} field, \
             which does not record them (RBF fields and MRAS fields fitted by this version do)",
            args.field.display(),
            field.kind()
        ),
        None => {}
    }
    // The scan's reach: trim to it, or say how much of the mesh lies beyond it.
    let scan = scan.or(recorded);
    // Whether --trim removed anything (the open edges' cause below).
    let mut trim_cut = false;
    match (scan, args.trim) {
        (None, Some(_)) => bail!(
            "--trim needs the points the field was fitted to: give --scan SCAN ({} holds a {} \
             field{})",
            args.field.display(),
            field.kind(),
            if matches!(field, AnyField::Rbf(_)) {
                ", whose centres include its off-surface points"
            } else {
                ", which does not record them"
            }
        ),
        (Some(points), trimming) if !mesh.is_empty() => {
            let support = match support.map_or_else(|| ScanSupport::new(&points, reach), Ok) {
                Ok(support) => Some(support),
                Err(e) if trimming.is_some() => return Err(e).context("--trim"),
                Err(_) => None,
            };
            if let Some(support) = support {
                // A level set off the fitted one lies that far from the points throughout.
                let offset = level_offset(&field, &points, args.level);
                let (trimmed, unseen) = split(&mesh, &support, offset);
                let kept = check(&trimmed.mesh);
                let share = if report.area > 0.0 {
                    (1.0 - kept.area / report.area).max(0.0)
                } else {
                    0.0
                };
                let how = format!(
                    "{} local spacings (median spacing {}){}",
                    g(reach),
                    g(support.median_spacing()),
                    if offset > 0.0 {
                        format!(" plus the level's offset {}", g(offset))
                    } else {
                        String::new()
                    }
                );
                if trimming.is_some() {
                    say!(
                        out,
                        "trim: cut {:.2}% of the area beyond the scan's reach of {how}: {} \
                         triangles dropped, {} cut; {} boundary loop(s)",
                        100.0 * share,
                        trimmed.dropped_triangles,
                        trimmed.cut_triangles,
                        boundary_loops(&trimmed.mesh)
                    )?;
                    trim_cut = trimmed.dropped_triangles + trimmed.cut_triangles > 0;
                    mesh = trimmed.mesh;
                    report = kept;
                } else {
                    say!(
                        out,
                        "coverage: {:.2}% of the area lies beyond the scan's reach of {how}{}",
                        100.0 * share,
                        match (share > OPEN_SCAN_SHARE, args.close) {
                            (false, _) => "",
                            (true, None) => " (an open scan?); --trim cuts it there",
                            (true, Some(_)) => " (the caps --close made are in it)",
                        }
                    )?;
                    if let Some(line) = unseen_line(&unseen, report.area) {
                        say!(out, "{line}")?;
                    }
                }
            }
        }
        _ => {}
    }
    let checking = start.elapsed();
    say!(
        out,
        "mesh: {} vertices, {} triangles at level {}",
        mesh.num_vertices(),
        mesh.num_triangles(),
        g(args.level)
    )?;
    if dropped_all {
        say!(
            out,
            "every component was dropped by --drop-spurious: the mesh is empty"
        )?;
    } else if mesh.is_empty() && trim_cut {
        say!(
            out,
            "--trim cut the whole mesh: none of it lies within the reach of the scan's points \
             (a larger --trim=REACH keeps more)"
        )?;
    } else if mesh.is_empty() {
        let (lo, hi) = lattice_range(&field, &bounds);
        if lo == args.level && hi == args.level {
            say!(
                out,
                "the field equals the level {} at every point tried (a lattice of {} across \
                 the box): a constant field has no surface (a fit to values that are all equal \
                 gives one)",
                g(args.level),
                LATTICE.pow(3)
            )?;
        } else if lo < args.level && args.level < hi {
            // The level is crossed, between the grid's vertices: the voxels are too coarse.
            say!(
                out,
                "the field crosses the level {} (it runs from {} to {} on a lattice of {} \
                 across the box) but no voxel of edge {} has corners on both sides of it: the \
                 surface lies between the grid's vertices, the mesh is empty; a smaller --voxel \
                 or a larger --resolution catches it",
                g(args.level),
                g(lo),
                g(hi),
                LATTICE.pow(3),
                g(h)
            )?;
        } else {
            say!(
                out,
                "the level set does not cross the grid: the mesh is empty (the field runs from \
                 {} to {} on a lattice of {} across the box; --level picks another level)",
                g(lo),
                g(hi),
                LATTICE.pow(3)
            )?;
        }
    }
    // Marching cubes face the triangles along the gradient: a field positive inside gives a
    // closed mesh that encloses a negative volume.
    let inside_out = report.closed && report.signed_volume < 0.0 && !mesh.is_empty();
    if inside_out && args.turn_inside_out {
        mesh = mesh.turned_over();
        report.signed_volume = -report.signed_volume;
        say!(
            out,
            "turned: the mesh came out inside out (closed, with a negative signed volume: the \
             field is positive inside, the scan's normals pointing inward), so its triangles \
             are turned over to face out (--keep-inside-out keeps it as fitted, for normals \
             that face into the solid on purpose); a field kept with --field stays as fitted"
        )?;
    }
    say!(
        out,
        "report: {}, Euler characteristic {}, {} component(s), {} boundary edge(s), {} \
         non-manifold, signed volume {}, area {}",
        if mesh.is_empty() {
            "empty"
        } else if report.closed {
            "closed"
        } else {
            "open"
        },
        report.euler_characteristic,
        report.components,
        report.boundary_edges,
        report.non_manifold_edges,
        g(report.signed_volume),
        g(report.area)
    )?;
    if report.boundary_edges > 0 {
        let why = if trim_cut {
            "where --trim cut it (or where the surface leaves the grid)"
        } else if args.close.is_some() {
            "at holes in the surface"
        } else {
            "where the surface leaves the grid (`zeroset mesh FIELD --close` caps it on the box, \
             --close=scan on the scan's own box: `zeroset reconstruct --close`) or at holes"
        };
        say!(
            out,
            "open: {} boundary edge(s), {why}; the signed volume of an open mesh encloses \
             nothing",
            report.boundary_edges,
        )?;
    }

    if inside_out && !args.turn_inside_out {
        say!(
            out,
            "warning: the mesh is inside out (closed, with a negative signed volume): the field \
             is positive inside it, where zeroset's fits to outward normals are negative; a fit \
             to a scan whose normals point inward gives this (zeroset normals SCAN -o \
             ORIENTED.ply estimates outward ones)"
        )?;
    }

    // Only STL needs the measure here; the PLY writer takes its own.
    let rounding = if format == MeshFormat::Stl {
        mesh.f32_rounding()
    } else {
        0.0
    };
    if rounding > zeroset_mesh::io::ply::F32_ROUNDING_LIMIT {
        // STL holds 32-bit floats only; PLY switches to doubles, OBJ and OFF write f64 text.
        let diagonal = mesh.bounds().map_or(0.0, |b| b.diagonal());
        say!(
            out,
            "warning: STL stores 32-bit floats, which move these vertices by up to {} ({:.1e} \
             of the diagonal): the mesh lies far from the origin for its size; .ply, .obj or \
             .off keep them exactly (or shift the scan nearer the origin)",
            g(rounding * diagonal),
            rounding
        )?;
    }
    let start = Instant::now();
    write_mesh(&args.output, &mesh, args.ascii)
        .with_context(|| format!("writing {}", args.output.display()))?;
    let writing = start.elapsed();
    say!(
        out,
        "wrote {} ({})",
        args.output.display(),
        match (format, args.ascii) {
            (MeshFormat::Obj, _) => "OBJ",
            (MeshFormat::Ply, true) => "ASCII PLY",
            (MeshFormat::Ply, false) => "binary PLY",
            (MeshFormat::Stl, true) => "ASCII STL",
            (MeshFormat::Stl, false) => "binary STL",
            (MeshFormat::Off, _) => "OFF",
        }
    )?;
    say!(
        out,
        "time: read {}, mesh {}, check {}, write {}, total {}",
        seconds(reading),
        seconds(meshing),
        seconds(checking),
        seconds(writing),
        seconds(total.elapsed())
    )?;
    if !count {
        return Ok(None);
    }
    let (labels, count) = components(&mesh);
    let mut sizes = vec![0; count];
    for label in labels {
        sizes[label as usize] += 1;
    }
    sizes.sort_unstable_by(|a, b| b.cmp(a));
    Ok(Some(sizes))
}

/// `--method smc`: the signed marching cubes where the cost model says they win (or with
/// `--always-smc`), else plain marching cubes on the exact field, saying why.
fn smc_or_plain<K: Kernel + Clone>(
    field: &RbfField<K, 3>,
    grid: &Grid<3>,
    options: &McOptions,
    args: &MeshArgs,
    out: &mut Say,
) -> anyhow::Result<TriMesh> {
    let disk = plan::cache_dir().map(|dir| dir.join("fmm"));
    cache::set_disk_dir(disk.clone());
    let [low, high] = [args.order, args.high_order].map(FmmOptions::new);
    OrderPair::<K>::check(&low, &high, DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY)
        .context("--method smc")?;
    let term = plan::calibrate(field, grid);
    let verdict = plan::plan(field, grid, &low, &high, term);
    let describe = |c: Cached| match c {
        Cached::InMemory => "in memory",
        Cached::OnDisk => "in the disk cache",
        Cached::NotYet => "to be built",
    };
    say!(
        out,
        "plan: plain marching cubes about {}, signed about {} (operators of order {} {}, of \
         order {} {}{})",
        seconds(Duration::from_secs_f64(verdict.plain_seconds)),
        seconds(Duration::from_secs_f64(verdict.signed_seconds)),
        args.order,
        describe(verdict.operators[0]),
        args.high_order,
        describe(verdict.operators[1]),
        disk.as_ref()
            .map(|d| format!("; cache {}", d.display()))
            .unwrap_or_default()
    )?;
    if verdict.signed_wins() || args.always_smc {
        return smc(field, grid, options, args, out);
    }
    say!(
        out,
        "--method smc: plain marching cubes on the exact field is faster here, so it runs \
         instead (its mesh is exact; the signed one matches it to the order-{} error); \
         --always-smc runs the signed marching cubes anyway",
        args.high_order
    )?;
    with_spinner(args.quiet, "sampling the field and marching cubes", || {
        mesh_field(field, grid, args.level, options)
    })
    .context("extracting the level set")
}

/// The two-step signed marching cubes of an RBF field, with its counts reported.
fn smc<K: Kernel + Clone>(
    field: &RbfField<K, 3>,
    grid: &Grid<3>,
    options: &McOptions,
    args: &MeshArgs,
    out: &mut Say,
) -> anyhow::Result<TriMesh> {
    let (p, high) = (args.order, args.high_order);
    let bar = spinner(args.quiet);
    bar.set_message(format!(
        "building the multipole expansions of orders {p} and {high} and sampling their errors"
    ));
    let start = Instant::now();
    let blocks_first = args.step != StepArg::Every;
    let first = if blocks_first {
        CoarseStep::Blocks
    } else {
        CoarseStep::EveryVertex
    };
    // Each field's tree is shaped for the evaluations it will see.
    let [low_points, high_points] = expected_evaluations(grid, first);
    let mut pair = OrderPair::new(
        field,
        &FmmOptions::new(p).with_expected_points(low_points),
        &FmmOptions::new(high).with_expected_points(high_points),
        DEFAULT_ERROR_SAMPLES,
        DEFAULT_SAFETY,
    )
    .context("--method smc")?;
    let mut step = first;
    let mut probe_note = String::new();
    if args.step == StepArg::Auto {
        let settled = settled_fraction(&pair.low, grid, args.level, pair.margin, 512);
        probe_note = format!("; probe: {:.0}% of 512 blocks settle", 100.0 * settled);
        if settled < 0.5 {
            step = CoarseStep::EveryVertex;
            bar.set_message(format!(
                "few blocks settle: rebuilding order {p} for every grid vertex"
            ));
            let every = expected_evaluations(grid, step)[0];
            pair = pair
                .with_low(field, &FmmOptions::new(p).with_expected_points(every))
                .context("--method smc")?;
        }
    }
    let built = start.elapsed();
    let operators = pair.low.report().operator_seconds + pair.high.report().operator_seconds;
    bar.suspend(|| {
        say!(
            out,
            "fmm: order {p} (sampled max error {}), order {high} ({}), margin {} = {} × their \
             sum; built in {} (operators {}); step 1: {}{probe_note}",
            g(pair.low_error),
            g(pair.high_error),
            g(pair.margin),
            g(DEFAULT_SAFETY),
            seconds(built),
            seconds(Duration::from_secs_f64(operators)),
            match step {
                CoarseStep::Blocks => "blocks settled by enclosures",
                _ => "every vertex",
            }
        )
    })?;
    let progress = |stage: SmcStage| {
        bar.set_message(match stage {
            SmcStage::Coarse { vertices } => {
                format!("step 1: settling {vertices} grid vertices with order {p}")
            }
            SmcStage::Fine { vertices } => {
                format!("step 2: order {high} at {vertices} vertices of uncertain voxels")
            }
            _ => "triangulating the surface voxels".to_string(),
        })
    };
    let result = signed_marching_cubes(
        &pair.low,
        &pair.high,
        grid,
        args.level,
        pair.margin,
        &SmcOptions::from(*options).with_coarse_step(step),
        Some(&progress),
    );
    bar.finish_and_clear();
    let (mesh, r) = result.context("extracting the level set")?;
    say!(
        out,
        "signed marching cubes: N_MC {} (plain MC's evaluations), N_SMC,p {} ({} vertices in {} \
         blocks settled by {} enclosures), N_SMC,P {}, gamma = N_SMC,P / N_MC = {:.2}%; {} \
         uncertain vertices, {} candidate and {} surface voxels; step 1 {}, step 2 {}, \
         triangulation {}",
        r.n_mc,
        r.n_smc_low,
        r.settled_vertices,
        r.settled_blocks,
        r.enclosures,
        r.n_smc_high,
        100.0 * r.gamma,
        r.uncertain_vertices,
        r.candidate_cells,
        r.surface_cells,
        seconds(Duration::from_secs_f64(r.coarse_seconds)),
        seconds(Duration::from_secs_f64(r.fine_seconds)),
        seconds(Duration::from_secs_f64(r.extract_seconds))
    )?;
    Ok(mesh)
}

/// Default marching-squares cells along the longer axis of a 2-D field.
const CURVE_CELLS: usize = 256;
/// The most samples of a 2-D field's grid (0.8 GB of values).
const CURVE_SAMPLES: usize = 100_000_000;

/// `zeroset mesh` of a 2-D field: its level curve by marching squares, as SVG.
fn curve(args: &MeshArgs, out: &mut Say) -> anyhow::Result<()> {
    crate::output::check_output(&args.output, &[&args.field], args.force, &["svg"])
        .context("a 2-D field's level curve is written as SVG")?;
    let refused = [
        (args.method == Method::Smc, "--method smc"),
        (args.close.is_some(), "--close"),
        (args.ascii, "--ascii"),
        (args.trim.is_some(), "--trim"),
        (args.scan.is_some(), "--scan"),
        (args.drop_spurious, "--drop-spurious"),
        (args.always_smc, "--always-smc"),
        (
            args.order != 5 || args.high_order != 10,
            "--order/--high-order",
        ),
        (args.step != StepArg::Auto, "--step"),
        // The l0 rule sizes cubic voxels; a curve is traced on 256 cells along the longer
        // side unless --resolution or --voxel says otherwise.
        (args.detail.is_some(), "--detail"),
    ];
    if let Some((_, flag)) = refused.iter().find(|(given, _)| *given) {
        bail!(
            "{flag} applies to 3-D fields; {} holds a 2-D field{}",
            args.field.display(),
            if *flag == "--detail" {
                " (its curve is traced on 256 cells along the longer side: --resolution or \
                 --voxel sets them)"
            } else {
                ""
            }
        );
    }
    if !args.level.is_finite() {
        bail!("--level must be finite, got {}", args.level);
    }
    let field = read_any_field::<2>(&args.field)
        .with_context(|| format!("reading {}", args.field.display()))?;
    let bounds = field
        .bounds()
        .with_context(|| format!("the field in {} has no bounds", args.field.display()))?;
    let ext = bounds.extent();
    let longest = ext[0].max(ext[1]);
    let h = match (args.resolution, args.voxel) {
        (Some(n), _) if n < 2 => bail!("--resolution must be at least 2 cells, got {n}"),
        (Some(n), _) => longest / n as f64,
        (None, Some(h)) if !(h.is_finite() && h > 0.0) => {
            bail!("--voxel must be a finite positive length, got {h}")
        }
        (None, Some(h)) => h,
        (None, None) => longest / CURVE_CELLS as f64,
    };
    if !(h.is_finite() && h > 0.0) {
        bail!("the field's box is a point: nothing to trace");
    }
    // The same guard as the 3-D grids: counts that cannot overflow, then a size the curve's
    // samples fit in.
    let grid = voxel::grid_for(&bounds, h, 0.0).with_context(|| {
        format!(
            "building the sampling grid for cells of {}; choose a larger --voxel or a smaller \
             --resolution",
            g(h)
        )
    })?;
    let counts = grid.counts();
    if grid.len() > CURVE_SAMPLES {
        bail!(
            "a {}×{} grid is too fine for a curve ({} samples, at most {CURVE_SAMPLES}); choose a \
             larger --voxel or a smaller --resolution",
            counts[0],
            counts[1],
            grid.len()
        );
    }
    say!(
        out,
        "field {}: 2-D {} over min {} max {}",
        args.field.display(),
        field.describe(),
        crate::info::point_n(&bounds.min()),
        crate::info::point_n(&bounds.max())
    )?;
    let start = Instant::now();
    let contour = contour_field(&field, &grid, args.level).context("tracing the level curve")?;
    let area: f64 = contour
        .lines
        .iter()
        .filter(|l| l.closed)
        .map(|l| l.signed_area())
        .sum();
    say!(
        out,
        "curve: {} closed loop(s), {} open piece(s), {} vertices, length {}, enclosed area {} \
         (marching squares on {}×{} samples, {})",
        contour.num_closed(),
        contour.num_open(),
        contour.num_points(),
        g(contour.total_length()),
        g(area),
        counts[0],
        counts[1],
        seconds(start.elapsed())
    )?;
    let mut plot = SvgPlot::new(bounds, 800).context("the SVG canvas")?;
    plot.title(&format!(
        "level {} of {}",
        g(args.level),
        args.field.display()
    ))
    .frame("#999999", 1.0)?
    .polylines(&contour, "#1f77b4", 2.0)?;
    plot.write(&args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
    say!(out, "wrote {}", args.output.display())?;
    Ok(())
}

/// Points per axis of [`lattice_range`]'s lattice.
const LATTICE: usize = 5;

/// The least and greatest values of `field` on a lattice of [`LATTICE`]³ points spanning
/// `bounds`: what an empty mesh's message quotes.
fn lattice_range(field: &AnyField<3>, bounds: &Aabb<3>) -> (f64, f64) {
    let (min, ext) = (bounds.min(), bounds.extent());
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..LATTICE.pow(3) {
        let k = [i % LATTICE, i / LATTICE % LATTICE, i / LATTICE / LATTICE];
        let p = std::array::from_fn(|a| min[a] + ext[a] * k[a] as f64 / (LATTICE - 1) as f64);
        let v = field.value(&p);
        range = (range.0.min(v), range.1.max(v));
    }
    range
}

/// The output's format from its extension; refuses the input, an existing file without
/// --force and a missing directory — all before any work.
fn check_output(args: &MeshArgs) -> anyhow::Result<MeshFormat> {
    let out = &args.output;
    crate::output::check_output(out, &[&args.field], args.force, &MeshFormat::EXTENSIONS)?;
    let format = MeshFormat::from_path(out).context("a mesh file's extension")?;
    if args.ascii && !format.has_binary() {
        bail!(
            "--ascii applies to PLY and STL output; {} is {}, which is always text",
            out.display(),
            format.name()
        );
    }
    Ok(format)
}

/// Runs `work`; a spinner appears if it takes longer than a second (never with `quiet`).
fn with_spinner<T: Send>(quiet: bool, message: &str, work: impl FnOnce() -> T + Send) -> T {
    if quiet {
        return work();
    }
    let (done, finished) = mpsc::channel::<()>();
    std::thread::scope(|s| {
        let worker = s.spawn(move || {
            let out = work();
            let _ = done.send(());
            out
        });
        if finished.recv_timeout(Duration::from_secs(1)).is_err() {
            let spinner = spinner(false);
            spinner.set_message(message.to_string());
            let _ = finished.recv();
            spinner.finish_and_clear();
        }
        match worker.join() {
            Ok(out) => out,
            Err(panic) => std::panic::resume_unwind(panic),
        }
    })
}

/// Plain marching cubes on an RBF field costs a direct sum over every centre at every grid
/// vertex: above this many estimated seconds `zeroset mesh` says so before it starts, and
/// names `--method smc`.
const SLOW_PLAIN_SECONDS: f64 = 30.0;

/// Before plain marching cubes on an RBF field: its time estimated from a timed direct sum at a
/// few hundred grid vertices ([`plan::calibrate`]), printed with a pointer to `--method smc`
/// when it exceeds [`SLOW_PLAIN_SECONDS`] (the full bunny's 104,502 centres at the fine grid:
/// about 200 s, against 4 s for the signed marching cubes).
fn hint_signed(field: &AnyField<3>, grid: &Grid<3>, out: &mut Say) -> anyhow::Result<()> {
    fn estimate<K: Kernel + Clone>(f: &RbfField<K, 3>, grid: &Grid<3>) -> (f64, usize) {
        let centres = f.num_centres();
        (
            plan::calibrate(f, grid) * grid.len() as f64 * centres as f64,
            centres,
        )
    }
    let (seconds, centres) = match field {
        AnyField::Rbf(RbfAny::R(f)) => estimate(f, grid),
        AnyField::Rbf(RbfAny::R3(f)) => estimate(f, grid),
        AnyField::Rbf(RbfAny::Tps(f)) => estimate(f, grid),
        AnyField::Rbf(RbfAny::Wendland(f)) => estimate(f, grid),
        AnyField::BSpline(_) | AnyField::Neural(_) | AnyField::Mras(_) => return Ok(()),
    };
    if seconds > SLOW_PLAIN_SECONDS {
        let time = if seconds < 120.0 {
            format!("{seconds:.0} s")
        } else {
            format!("{:.0} min", seconds / 60.0)
        };
        say!(
            out,
            "plain marching cubes: about {time} on this RBF field ({centres} centres at every \
             vertex); --method smc (the fast multipole method) is usually many times faster"
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_unseen_line_counts_specks_apart() {
        let region = |area: f64, at: f64| Region {
            area,
            bounds: zeroset_field_core::Aabb::new([at; 3], [at + 1.0; 3]).unwrap(),
        };
        // Two regions and two specks of a mesh of area 10,000 (specks under 1).
        let unseen = [
            region(300.0, 0.0),
            region(1.0, 5.0),
            region(0.5, 9.0),
            region(0.2, 7.0),
        ];
        let line = unseen_line(&unseen, 10_000.0).unwrap();
        assert!(
            line.starts_with(
                "unseen: 2 region(s) (and 2 speck(s), each under 0.01% of the area) beyond"
            ),
            "{line}"
        );
        assert!(
            line.ends_with(
                "the largest, 3.00% of the area, spans 1 × 1 × 1 around (0.5, 0.5, 0.5)"
            ),
            "{line}"
        );
        // No specks: no parenthesis; only specks, or nothing beyond reach: no line.
        let line = unseen_line(&unseen[..1], 10_000.0).unwrap();
        assert!(line.starts_with("unseen: 1 region(s) beyond"), "{line}");
        assert_eq!(unseen_line(&unseen[2..], 10_000.0), None);
        assert_eq!(unseen_line(&[], 10_000.0), None);
    }

    #[test]
    fn spinner_returns_the_work() {
        assert_eq!(with_spinner(true, "x", || 3), 3);
        assert_eq!(with_spinner(false, "x", || 4), 4);
    }

    #[test]
    fn weak_components_spare_the_best_supported_and_the_spurious() {
        // Fewer than MIN_SUPPORT points, not already spurious, not the best supported.
        let weak = weak_components(&[500, 1, 3, 4, 0], &[false, false, false, false, true]);
        assert_eq!(weak, vec![false, true, true, false, false]);
        // A mesh of weakly supported pieces keeps its best one (the first of a tie).
        assert_eq!(
            weak_components(&[2, 2, 1], &[false; 3]),
            vec![false, true, true]
        );
        assert_eq!(weak_components(&[], &[]), Vec::<bool>::new());
        // The best is chosen among the components that are not spurious.
        assert_eq!(
            weak_components(&[0, 2, 1], &[true, false, false]),
            vec![false, false, true]
        );
    }
}
