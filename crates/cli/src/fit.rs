//! `zeroset fit POINTS --method rbf|neural`: fit an implicit field to an oriented point cloud
//! or to a file of value constraints, and report how well it fits.
//!
//! `--method neural` lives in [`crate::fit_neural`]; the rest of this module is the RBF fit.
//!
//! The radial-basis-function fit (`zeroset_bases::rbf`) of a point cloud interpolates either
//! Carr et al.'s off-surface constraints (value 0 at each point, `±ε` at `p ± ε n`) or Hermite
//! constraints (value 0 and gradient `n` at each point, kernel `r³` or Wendland). The command
//! prints the fit's report and a sanity check at a few input points; with `-o` it saves the RBF
//! field itself as a `.zsf` field file (exact, and fast to write), which `zeroset mesh`,
//! `zeroset restore` and `zeroset info` read. `--sampled` keeps the older output: the RBF field
//! sampled on a grid over the cloud and interpolated by a quadratic B-spline.
//!
//! `--smoothing auto|μ` approximates the values instead of interpolating them (the smoothing
//! spline, `μ` on the kernel matrix's diagonal: `RbfFit::with_smoothing`), for noisy scans,
//! whose interpolant folds between the points into bubbles. `auto` takes `μ` from the noise
//! the cloud measures (`zeroset_bases::noise`: `2 · (σ̂/s)² · D`, `D` the size of the object
//! the cloud mostly samples, `noise::object_size`); on value files and
//! with other kernels `μ` is given.
//!
//! A value-constraint file (`.xyv`: `x y value`, a 2-D curve; `.xyzv`: `x y z value`) is
//! interpolated as it is (Jiang–Turk, paper 003 §2: on-curve points 0, inside points negative,
//! outside points positive), by default with the thin-plate spline `r² ln r` in 2-D (as
//! `examples/rbf_curve_2d.rs`) and `r` in 3-D; `zeroset mesh FIELD.zsf -o CURVE.svg` traces a
//! 2-D field's zero curve.
//!
//! `--kernel wendland` is Wendland's compactly supported `ψ₃,₁` (the user kernel the field file
//! stores), with the support radius `--radius ρ`, by default [`WENDLAND_FRACTION`] = 1/2 of
//! the diagonal of the data's box. Too small a support leaves gaps between the constraints
//! where the field falls back to its linear polynomial and the zero set breaks up: on
//! `samples/curve.xyv` `ρ` = 1/16 and 1/8 of the diagonal give 8 and 11 loops, 1/4 and more
//! the one true loop (enclosed area within 0.1% of the true curve's from 1/4 to 2). Half the
//! diagonal keeps a factor of two from that edge; the solve is dense either way, so a larger
//! support costs nothing but conditioning (condition estimate 16 there, 5 at 1/4).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};

use zeroset_bases::bspline::{BSplineField, Degree};
use zeroset_bases::field_file::{StoredKernel, is_field_file, write_field, write_rbf_field};
use zeroset_bases::noise::object_size;
use zeroset_bases::normals::{FLAT_DIVERGENCE, outwardness};
use zeroset_bases::rbf::{
    Biharmonic, Constraints, FitReport, GreedyOptions, IterativeParams, Offset, OffsetReport,
    RbfField, RbfFit, Solver, ThinPlate, Triharmonic, Wendland,
};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point, dot, norm};
use zeroset_field_core::grid::Grid;
use zeroset_field_core::io::{ValuePoints, read_point_cloud_with, read_value_points};
use zeroset_field_core::lsq::Monitor;
use zeroset_field_core::{Error, PointCloud3};

use crate::info::{g, plural, point};
use crate::machine::{counts_text, ensure_memory, sample_count};
use crate::progress::{counter, seconds, spinner};
use crate::restore::{cubic_counts, parse_counts};

/// Shown after `zeroset fit --help`.
pub const EXAMPLES: &str = "\
Examples:
  # biharmonic RBF (kernel r) through off-surface points; prints the fit report
  zeroset fit samples/bunny_2k.xyzn --method rbf
  # Hermite constraints (the normals as gradients) with the r3 kernel, solved densely
  zeroset fit scan.ply --method rbf --hermite --solver dense
  # a fixed off-surface offset, and the RBF field itself saved, then meshed
  zeroset fit samples/bunny_2k.xyzn --method rbf --offset 0.001 -o bunny.zsf
  zeroset mesh bunny.zsf -o bunny.ply
  # a neural field (MLP 3 → 32 → 32 → 1 with the thin-plate curvature loss), then meshed
  zeroset fit samples/bunny_2k.xyzn --method neural --steps 1500 -o bunny_nn.zsf
  zeroset mesh bunny_nn.zsf -o bunny_nn.ply
  # a 2-D curve from value constraints (x y value per line: -1 inside, 0 on, +1 outside):
  # the thin-plate spline through them (Jiang–Turk), its zero curve drawn as SVG
  zeroset fit samples/curve.xyv --method rbf -o curve.zsf
  zeroset mesh curve.zsf -o curve.svg
  # the same with Wendland's compact kernel (support radius 0.5), or a neural field
  zeroset fit samples/curve.xyv --method rbf --kernel wendland --radius 0.5 -o curve_w.zsf
  zeroset fit samples/curve.xyv --method neural -o curve_nn.zsf
  zeroset preview curve_nn.zsf -o curve.png
  # the field sampled on a 96-cell grid as a quadratic B-spline, for `zeroset restore`
  zeroset fit samples/bunny_2k.xyzn --method rbf -o bunny_bs.zsf --sampled --grid 96,96,75
  zeroset restore bunny_bs.zsf --mode denoise --mask -0.05,0.05,-0.03:0.05,0.12,0.06 \\
      --coarse 6,6,4 -o smooth.zsf

A point cloud needs normals that point out of the solid (the field is negative inside); a
value file (.xyv, .xyzv) is interpolated as it is, values negative inside.
-o FIELD saves the RBF field itself (kernel, centres, weights, polynomial): exact, and quick
to write. With --sampled it saves the RBF field sampled on a grid and interpolated by a
quadratic B-spline instead: an approximation, on the grid `zeroset restore` works on.";

/// How to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// Radial basis functions: an exact interpolant of the constraints (dense or iterative).
    Rbf,
    /// A small neural net (MLP) trained with Adam on the data term plus Jiang–Turk's
    /// thin-plate curvature term; takes point clouds and .xyv/.xyzv value files.
    Neural,
    /// Multilevel rational algebraic splines (Pan–Tong–Chen): an octree of quadratic B-spline offsets
    /// stored as CP factors; compact files for large scans (oriented point clouds only).
    Mras,
}

/// The `--kernel` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum KernelArg {
    /// φ(r) = r, the biharmonic spline of 3-D (Carr et al.); not for --hermite.
    R,
    /// φ(r) = r³, the triharmonic spline of 3-D; smooth at 0, so it also takes --hermite.
    R3,
    /// φ(r) = r² ln r, the thin-plate spline of 2-D curves (.xyv files only).
    Tps,
    /// Wendland's compactly supported ψ₃,₁ = (1 − r/ρ)⁴₊ (4r/ρ + 1), radius ρ from --radius;
    /// smooth at 0, so it also takes --hermite.
    Wendland,
}

impl KernelArg {
    fn name(self) -> &'static str {
        match self {
            KernelArg::R => "r",
            KernelArg::R3 => "r3",
            KernelArg::Tps => "tps",
            KernelArg::Wendland => "wendland",
        }
    }

    /// Whether Hermite (gradient) constraints can use the kernel: twice differentiable at 0.
    fn takes_gradients(self) -> bool {
        matches!(self, KernelArg::R3 | KernelArg::Wendland)
    }
}

/// The `--solver` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SolverArg {
    /// Dense up to 2,000 functionals; above, iterative for kernels r and wendland with value
    /// constraints only, mixed for wendland with --hermite, dense otherwise (each falls back to
    /// dense if it fails).
    Auto,
    /// The exact dense solve (projected Cholesky): O(n³) time, O(n²) memory.
    Dense,
    /// The projected Cholesky in f32 preconditioning GMRES on the f64 system: as exact as
    /// dense at ~0.6× the time, for condition numbers up to ~1e7 (kernels r and wendland; r3's
    /// systems are beyond it on real scans, and the f32 factorisation fails).
    Mixed,
    /// GMRES in a local cardinal basis: O(n²) per step, value constraints only.
    Iterative,
}

/// `--offset auto` or a fixed distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OffsetArg {
    /// Start at 1% of the bounding-box diagonal, shrinking per point where needed.
    Auto,
    /// The same distance for every point.
    Fixed(f64),
}

/// `--smoothing auto` or a fixed `μ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SmoothingArg {
    /// From the cloud's measured noise ([`zeroset_bases::noise::Noise::rbf_smoothing`]).
    Auto,
    /// `μ ≥ 0` in the kernel's units (SciPy's `RBFInterpolator(smoothing=μ, degree=1)`).
    Fixed(f64),
}

/// The starting offset of `--offset auto`, as a fraction of the bounding-box diagonal.
pub(crate) const AUTO_FRACTION: f64 = 0.01;

/// Cells along the longest axis of the default `-o` grid.
const DEFAULT_CELLS: usize = 64;

/// The `-o` grid covers the cloud's box grown by this fraction of its diagonal on every side.
const GRID_MARGIN: f64 = 0.05;

/// Input points shown in the sanity check.
const CHECK_POINTS: usize = 5;

/// The default support radius of `--kernel wendland`, as a fraction of the diagonal of the
/// data's box (see the module docs).
pub(crate) const WENDLAND_FRACTION: f64 = Wendland::DEFAULT_RADIUS_FRACTION;

/// Bytes per grid sample of `--sampled`: the samples and the spline's coefficients (with one
/// working copy), 8 bytes each.
const SAMPLED_BYTES_PER_SAMPLE: u64 = 24;

/// Arguments of `zeroset fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// An oriented point cloud: .ply (with nx ny nz), .pcd (PCL, with normal_x normal_y
    /// normal_z), .e57 (laser scans with the surface-normals extension), .xyzn/.xyz/.txt/.pts/.asc/.pwn (x y z nx ny nz per line, or columns named by
    /// a first line) or .csv (header with x,y,z,nx,ny,nz); or a mesh (.ply with faces, .obj,
    /// .stl, .off), read as its vertices with the triangles' normals. Normals point out of the
    /// solid. Or a value-constraint file: .xyv (x y value per line, a 2-D curve) or .xyzv (x y
    /// z value); values negative inside, 0 on the curve, positive outside.
    pub points: PathBuf,

    /// What the report calls the points (`zeroset reconstruct` sets the user's scan when it
    /// fits a copy of it); not an option.
    #[arg(skip)]
    pub points_shown_as: Option<String>,

    /// Whether the points were checked already (`zeroset reconstruct` reads their thickness
    /// and their normals' orientation, and turns unoriented normals, before its fit stage);
    /// not an option.
    #[arg(skip)]
    pub checked_by_reconstruct: bool,

    /// The fitting method (rbf: radial basis functions; neural: a small MLP; mras: multilevel
    /// rational algebraic splines, stored at low rank).
    #[arg(long, value_enum)]
    pub method: Method,

    /// The radial kernel [default: r, or r3 with --hermite; tps for .xyv curves].
    #[arg(long, value_enum)]
    pub kernel: Option<KernelArg>,

    /// With --kernel wendland: the support radius ρ > 0 in the data's units [default: 0.5 ×
    /// the diagonal of the data's box].
    #[arg(long, value_name = "RHO", allow_hyphen_values = true)]
    pub radius: Option<f64>,

    /// Off-surface offset: auto (1% of the bounding-box diagonal, halved per point until the
    /// offset point stays nearest its own point), or a fixed distance EPS > 0 in the cloud's
    /// units (an error if it reaches another part of the surface). [default: auto]
    #[arg(long, value_name = "auto|EPS", value_parser = parse_offset, allow_hyphen_values = true)]
    pub offset: Option<OffsetArg>,

    /// Approximate instead of interpolate, for noisy scans: auto (μ = 2 × (σ̂/s)² × D, from
    /// the noise σ̂ and spacing s `zeroset info` measures, D the box diagonal of the connected
    /// piece of the cloud that holds its median point: the object's size; kernel r), or MU ≥ 0
    /// added to the kernel matrix's diagonal (SciPy RBFInterpolator's `smoothing` with
    /// degree=1; in the kernel's units). [default: 0, interpolation]
    #[arg(long, value_name = "auto|MU", value_parser = parse_smoothing, allow_hyphen_values = true)]
    pub smoothing: Option<SmoothingArg>,

    /// Hermite constraints: value 0 and the unit normal as the gradient at every point,
    /// instead of off-surface points. Needs --kernel r3 (the default with --hermite) or
    /// wendland.
    #[arg(long)]
    pub hermite: bool,

    /// How to solve the RBF system.
    #[arg(long, value_enum, default_value_t = SolverArg::Auto)]
    pub solver: SolverArg,

    /// Save the field as a .zsf field file (written atomically): the RBF field itself
    /// (exact), or with --sampled a quadratic B-spline sampled from it.
    #[arg(short, long, value_name = "FIELD")]
    pub output: Option<PathBuf>,

    /// Overwrite an existing output file (-o, --outliers-out).
    #[arg(long)]
    pub force: bool,

    /// With -o: save the RBF field sampled on --grid over the cloud's box grown by 5% of its
    /// diagonal and interpolated by a quadratic B-spline, instead of the RBF field itself.
    #[arg(long)]
    pub sampled: bool,

    /// With -o --sampled: grid cells per axis, L,M,N [default: 64 along the longest axis, the
    /// others in proportion (near-cubic cells)].
    #[arg(long, value_name = "L,M,N", value_parser = parse_counts)]
    pub grid: Option<[usize; 3]>,

    #[arg(long, value_name = "FORMAT", help = crate::normals::FIT_FORMAT_HELP)]
    pub format: Option<String>,

    #[arg(long, value_name = "NAME", help = crate::normals::FORMATION_HELP)]
    pub formation: Option<String>,

    /// No progress spinner or bar.
    #[arg(long)]
    pub quiet: bool,

    #[command(flatten)]
    pub neural: crate::fit_neural::NeuralArgs,

    #[command(flatten)]
    pub mras: crate::fit_mras::MrasArgs,

    #[command(flatten)]
    pub outliers: crate::outliers::OutlierArgs,
}

/// Runs `zeroset fit`.
pub fn run(args: &FitArgs) -> anyhow::Result<()> {
    match args.method {
        Method::Neural => return crate::fit_neural::run(args),
        Method::Mras => return crate::fit_mras::run(args),
        Method::Rbf => {}
    }
    if let Some(flag) = args.mras.given_besides_tolerance() {
        bail!("{flag} is an option of --method mras, not of --method rbf");
    }
    if let Some(flag) = args.neural.given() {
        bail!("{flag} is an option of --method neural, not of --method rbf");
    }
    args.mras.check_tolerance()?;
    let start = Instant::now();
    if let Some(dim) = crate::normals::value_dimension(&args.points, args.format.as_deref()) {
        if let Some(flag) = args.outliers.given() {
            bail!("{flag} applies to oriented point clouds, not to value files");
        }
        let kernel = check_value_request(args, dim)?;
        if dim == 2 {
            fit_values::<2>(args, kernel)?;
        } else {
            fit_values::<3>(args, kernel)?;
        }
    } else {
        let kernel = check_request(args)?;
        args.outliers
            .check(&args.points, args.output.as_deref(), args.force)?;
        let input = load(args)?;
        print_input(args, &input);
        let (cloud, outliers) = crate::outliers::set_aside(&args.outliers, &input)?;
        let diagonal = cloud.bounds().map_or(0.0, |b| b.diagonal());
        let noise = crate::noise::measure(&cloud);
        let spacing = noise.as_ref().map(|m| m.noise.spacing);
        let smoothing = match args.smoothing {
            Some(SmoothingArg::Fixed(mu)) => {
                line("smoothing", &format!("μ = {} (--smoothing)", g(mu)));
                mu
            }
            Some(SmoothingArg::Auto) => auto_smoothing(noise.as_ref(), &cloud)?,
            None => 0.0,
        };
        if smoothing == 0.0
            && let Some(warning) = noise.and_then(|m| m.rbf_warning())
        {
            line("noise", &warning);
        }
        with_kernel(
            kernel,
            args,
            (diagonal, spacing),
            CloudFit {
                args,
                cloud: &cloud,
                input: &input,
                outliers: &outliers,
                smoothing,
            },
        )?;
    }
    if let Some(output) = &args.output {
        outln!(
            "wrote {} ({}) in {:.2} s",
            output.display(),
            if args.sampled {
                "a quadratic B-spline field sampled from the RBF field"
            } else {
                "the RBF field"
            },
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// A fit to run with whichever kernel `--kernel` names ([`with_kernel`]).
trait KernelJob {
    /// Fits with `kernel`, reports, and writes `-o`.
    fn run<K: StoredKernel>(self, kernel: K) -> anyhow::Result<()>;
}

/// The fewest median point spacings a Wendland support radius should span: on the bunny
/// sample the mesh was open at 1, 2 and 3 spacings (Euler characteristic −229, −11, −1) and
/// closed from 5.
const WENDLAND_MIN_SPACINGS: f64 = 5.0;

/// Runs `job` with the kernel `kernel` names; Wendland's radius is `--radius` or
/// [`WENDLAND_FRACTION`] of `diagonal`, the diagonal of the data's box, and is said to be too
/// small for a cloud's median point `spacing` (when known).
fn with_kernel(
    kernel: KernelArg,
    args: &FitArgs,
    (diagonal, spacing): (f64, Option<f64>),
    job: impl KernelJob,
) -> anyhow::Result<()> {
    match kernel {
        KernelArg::R => job.run(Biharmonic),
        KernelArg::R3 => job.run(Triharmonic),
        KernelArg::Tps => job.run(ThinPlate),
        KernelArg::Wendland => {
            let (radius, how) = match args.radius {
                Some(rho) => (rho, "--radius".to_owned()),
                None => (
                    WENDLAND_FRACTION * diagonal,
                    format!(
                        "{} × the diagonal {} of the data's box; --radius sets it",
                        g(WENDLAND_FRACTION),
                        g(diagonal)
                    ),
                ),
            };
            let Some(wendland) = Wendland::new(radius) else {
                bail!(
                    "the data's box is a point, so --kernel wendland has no default support \
                     radius: give --radius RHO"
                );
            };
            line("radius", &format!("{} ({how})", g(radius)));
            if let Some(s) = spacing.filter(|s| radius < WENDLAND_MIN_SPACINGS * s) {
                more(&format!(
                    "warning: under {} median point spacings ({}): the field vanishes beyond \
                     each centre's reach, and the surface breaks open between points (the \
                     bunny sample's mesh was open up to 3 spacings, closed from 5)",
                    g(WENDLAND_MIN_SPACINGS),
                    g(s)
                ));
            }
            job.run(wendland)
        }
    }
}

/// Checks `--kernel` and `--radius` for `dim`-dimensional input (`input`: what the file is,
/// for the message); returns the kernel or `default`.
fn check_kernel(
    args: &FitArgs,
    default: KernelArg,
    dim: usize,
    input: &str,
) -> anyhow::Result<KernelArg> {
    let kernel = args.kernel.unwrap_or(default);
    if kernel == KernelArg::Tps && dim != 2 {
        bail!(
            "--kernel tps (r² ln r, the thin-plate spline) is the kernel for 2-D curves, and \
             {} {input}: use --kernel r, r3 or wendland",
            args.points.display()
        );
    }
    if let Some(rho) = args.radius {
        if kernel != KernelArg::Wendland {
            bail!(
                "--radius is the support radius of --kernel wendland; --kernel {} has none",
                kernel.name()
            );
        }
        if !(rho.is_finite() && rho > 0.0) {
            bail!(
                "--radius must be a finite distance > 0 in the data's units, got {rho} (the \
                 Wendland kernel vanishes beyond it)"
            );
        }
    }
    Ok(kernel)
}

/// Refuses what cannot work on a point cloud before reading or fitting anything; returns the
/// kernel.
fn check_request(args: &FitArgs) -> anyhow::Result<KernelArg> {
    let default = if args.hermite {
        KernelArg::R3
    } else {
        KernelArg::R
    };
    // The point-cloud readers read x, y and z: every cloud is 3-D.
    let kernel = check_kernel(args, default, 3, "is read as a 3-D point cloud")?;
    if args.hermite {
        if !kernel.takes_gradients() {
            bail!(
                "--hermite needs --kernel r3 (or wendland): the gradient (Hermite) constraints \
                 need a kernel that is twice differentiable at 0, and {} is not",
                kernel.name()
            );
        }
        if args.offset.is_some() {
            bail!("--offset applies to off-surface constraints; --hermite uses none");
        }
        if args.solver == SolverArg::Iterative {
            bail!(
                "--solver iterative takes value constraints only; Hermite constraints are \
                 solved densely (--solver auto or dense)"
            );
        }
        if args.mras.tolerance.is_some() || args.mras.tolerance_distance.is_some() {
            bail!(
                "--tolerance selects centres by Carr's greedy fit, which takes value \
                 constraints only; a Hermite fit keeps a centre at every point (drop \
                 --hermite for the off-surface fit, which the greedy fit reduces)"
            );
        }
    }
    check_smoothing(args, kernel)?;
    if let Some(OffsetArg::Fixed(eps)) = args.offset
        && !(eps.is_finite() && eps > 0.0)
    {
        bail!(
            "--offset must be auto or a finite distance > 0 in the cloud's units, got {eps} \
             (the off-surface points sit at ±offset along the normals)"
        );
    }
    if let Some(output) = &args.output {
        crate::output::check_output(output, &[&args.points], args.force, &["zsf"])?;
    } else if args.grid.is_some() {
        bail!("--grid is the grid of the -o field file; give -o FIELD.zsf too");
    } else if args.sampled {
        bail!("--sampled chooses what -o writes; give -o FIELD.zsf too");
    }
    if args.grid.is_some() && !args.sampled {
        bail!(
            "--grid is the sampling grid of --sampled; -o alone writes the RBF field itself, \
             which has no grid"
        );
    }
    if let Some(counts) = args.grid {
        if counts.iter().any(|&c| c < 3) {
            bail!("--grid needs at least 3 cells per axis, got {counts:?}");
        }
        check_sampled_memory(&counts)?;
    }
    Ok(kernel)
}

/// Refuses a `--smoothing` that is negative or not finite, and `auto` with a kernel other than
/// `r` (its rule is calibrated for `r`, whose `μ` is a length).
fn check_smoothing(args: &FitArgs, kernel: KernelArg) -> anyhow::Result<()> {
    if args.smoothing.is_some() && args.hermite {
        bail!(
            "--smoothing approximates value constraints; --hermite fits gradients exactly too, \
             so use off-surface constraints (drop --hermite) for a noisy scan"
        );
    }
    if args.smoothing.is_some()
        && (args.mras.tolerance.is_some() || args.mras.tolerance_distance.is_some())
    {
        bail!(
            "--tolerance with --method rbf keeps the centres whose constraints the field misses \
             by more than it, and a smoothed field misses them on purpose: use one or the other"
        );
    }
    check_mu(args.smoothing)?;
    match args.smoothing {
        Some(SmoothingArg::Auto) if kernel != KernelArg::R => bail!(
            "--smoothing auto is calibrated for --kernel r (its μ is a length); with --kernel \
             {} give --smoothing MU in that kernel's units",
            kernel.name()
        ),
        _ => Ok(()),
    }
}

/// Refuses a `--smoothing` μ that is negative or not finite (`fit` and `reconstruct`).
pub(crate) fn check_mu(smoothing: Option<SmoothingArg>) -> anyhow::Result<()> {
    match smoothing {
        Some(SmoothingArg::Fixed(mu)) if !(mu.is_finite() && mu >= 0.0) => bail!(
            "--smoothing must be auto or a finite μ ≥ 0 (added to the kernel matrix's diagonal; \
             0 interpolates), got {mu}"
        ),
        _ => Ok(()),
    }
}

/// Refuses a `--sampled` grid whose samples and spline cannot fit in memory (or whose sample
/// count overflows), before the cloud is read.
fn check_sampled_memory(counts: &[usize; 3]) -> anyhow::Result<()> {
    let samples = sample_count(counts, "--grid")?;
    ensure_memory(
        (samples as u64).saturating_mul(SAMPLED_BYTES_PER_SAMPLE),
        &format!(
            "--grid {} ({} cells)",
            counts_text(counts),
            g(samples as f64)
        ),
        "choose fewer cells per axis with --grid L,M,N",
    )
}

/// Refuses what cannot work on a value-constraint file of dimension `dim` before reading or
/// fitting anything; returns the kernel (by default `tps` in 2-D, `r` in 3-D).
fn check_value_request(args: &FitArgs, dim: usize) -> anyhow::Result<KernelArg> {
    let file = args.points.display();
    let columns = if dim == 2 { "x y value" } else { "x y z value" };
    let cloud_only = [
        (args.hermite, "--hermite"),
        (args.offset.is_some(), "--offset"),
        (args.sampled, "--sampled"),
        (args.grid.is_some(), "--grid"),
        (
            crate::normals::cloud_format_given(args.format.as_deref()),
            "--format",
        ),
        (args.formation.is_some(), "--formation"),
    ];
    if let Some((_, flag)) = cloud_only.iter().find(|(given, _)| *given) {
        bail!(
            "{flag} applies to oriented point clouds; {file} holds {dim}-D value constraints \
             ({columns} per line), which --method rbf interpolates as they are: drop {flag}"
        );
    }
    let default = if dim == 2 {
        KernelArg::Tps
    } else {
        KernelArg::R
    };
    let kernel = check_kernel(args, default, dim, "holds 3-D value constraints")?;
    if args.smoothing == Some(SmoothingArg::Auto) {
        bail!(
            "--smoothing auto measures a scan's noise, and {file} holds value constraints: give \
             --smoothing MU (added to the kernel matrix's diagonal, as SciPy's \
             RBFInterpolator smoothing)"
        );
    }
    check_smoothing(args, kernel)?;
    if let Some(output) = &args.output {
        crate::output::check_output(output, &[&args.points], args.force, &["zsf"])?;
    }
    Ok(kernel)
}

/// Reads a `D`-dimensional value-constraint file, naming the file, line and field of a
/// non-finite value, and reports what it holds.
pub(crate) fn load_values<const D: usize>(args: &FitArgs) -> anyhow::Result<ValuePoints<D>> {
    let path = &args.points;
    let c = read_value_points::<D>(path)
        .map_err(|e| read_error(path, e, "constraint", "the constraints must be finite"))?;
    let n = c.points.len();
    if n > 1 && c.values.iter().all(|v| *v == c.values[0]) {
        bail!(
            "{}: all {n} values are {}: the interpolant is that constant everywhere and has no \
             level set; give values on both sides of the surface (another surface's points at \
             another value, or points off it)",
            path.display(),
            g(c.values[0])
        );
    }
    line(
        "constraints",
        &format!(
            "{}: {n} {D}-D value constraint{} ({} negative, {} zero, {} positive)",
            path.display(),
            if n == 1 { "" } else { "s" },
            c.values.iter().filter(|v| **v < 0.0).count(),
            c.values.iter().filter(|v| **v == 0.0).count(),
            c.values.iter().filter(|v| **v > 0.0).count()
        ),
    );
    let (_, kept) = distinct_values(path, &c)?;
    let merged = n - kept.len();
    if merged > 0 {
        more(&format!(
            "({merged} row{} within {:e} of the diagonal of an earlier one, with its value, \
             merged into it)",
            plural(merged),
            zeroset_bases::rbf::MERGE_DISTANCE
        ));
    }
    Ok(ValuePoints {
        points: kept.iter().map(|&i| c.points[i]).collect(),
        values: kept.iter().map(|&i| c.values[i]).collect(),
        lines: kept.iter().map(|&i| c.lines[i]).collect(),
    })
}

/// [`Constraints::from_values`] of a value file's rows, naming the lines of two rows at one
/// place with different values.
pub(crate) fn distinct_values<const D: usize>(
    path: &Path,
    c: &ValuePoints<D>,
) -> anyhow::Result<(Constraints<D>, Vec<usize>)> {
    Constraints::from_values(&c.points, &c.values).map_err(|e| match e {
        zeroset_bases::rbf::RbfError::ConflictingValues {
            first,
            second,
            values,
            ..
        } => anyhow::anyhow!(
            "{}: lines {} and {} are at the same place (within {:e} of the diagonal) with \
             different values, {} and {}: an interpolant cannot take both",
            path.display(),
            c.lines[first],
            c.lines[second],
            zeroset_bases::rbf::MERGE_DISTANCE,
            g(values.0),
            g(values.1)
        ),
        e => anyhow::Error::new(e).context(format!("the value constraints of {}", path.display())),
    })
}

/// Under the constraints line: how many input points were merged into an earlier one, if any.
pub(crate) fn print_merged(merged: usize) {
    if merged > 0 {
        more(&format!(
            "({merged} input point{} within {:e} of the diagonal of an earlier one merged into it: \
             repeated samples, one centre each)",
            plural(merged),
            zeroset_bases::rbf::MERGE_DISTANCE
        ));
    }
}

/// `--method rbf` on a value-constraint file: the RBF interpolant of the values.
fn fit_values<const D: usize>(args: &FitArgs, kernel: KernelArg) -> anyhow::Result<()> {
    let c = load_values::<D>(args)?;
    // The rows are distinct already: nothing more merges.
    let (constraints, _) = distinct_values(&args.points, &c)?;
    let bounds = Aabb::from_points(&c.points);
    if let Some(b) = &bounds {
        line("bounds", &format!("min {}", crate::info::point_n(&b.min())));
        more(&format!("max {}", crate::info::point_n(&b.max())));
    }
    let diagonal = bounds.map_or(0.0, |b| b.diagonal());
    with_kernel(
        kernel,
        args,
        (diagonal, None),
        ValueFit {
            args,
            constraints: &constraints,
            diagonal,
        },
    )
}

/// The RBF fit of value constraints ([`fit_values`]).
struct ValueFit<'a, const D: usize> {
    args: &'a FitArgs,
    constraints: &'a Constraints<D>,
    /// The diagonal of the constraints' box (every constraint is a data point here).
    diagonal: f64,
}

impl<const D: usize> KernelJob for ValueFit<'_, D> {
    fn run<K: StoredKernel>(self, kernel: K) -> anyhow::Result<()> {
        let smoothing = match self.args.smoothing {
            Some(SmoothingArg::Fixed(mu)) => mu,
            _ => 0.0,
        };
        let field = solve(
            kernel,
            self.args,
            self.constraints,
            (smoothing, self.diagonal),
            &[],
        )?;
        if let Some(output) = &self.args.output {
            save_rbf(&field, output)?;
        }
        Ok(())
    }
}

/// The RBF fit of an oriented point cloud ([`fit_with`]).
struct CloudFit<'a> {
    args: &'a FitArgs,
    /// The points fitted.
    cloud: &'a PointCloud3,
    /// The input, and the indices of the stray points not fitted.
    input: &'a PointCloud3,
    outliers: &'a [usize],
    /// The smoothing `μ` (0: interpolation).
    smoothing: f64,
}

impl KernelJob for CloudFit<'_> {
    fn run<K: StoredKernel>(self, kernel: K) -> anyhow::Result<()> {
        fit_with(kernel, self)
    }
}

/// Reads the oriented point cloud, naming the file, line and field of a non-finite value.
pub(crate) fn load(args: &FitArgs) -> anyhow::Result<PointCloud3> {
    let path = &args.points;
    if is_field_file(path) {
        bail!(
            "{} is a field file; zeroset fit takes an oriented point cloud (PLY, xyzn, CSV)",
            path.display()
        );
    }
    let options = crate::normals::read_options(args.format.as_deref(), args.formation.as_deref())?;
    let (cloud, wound) = match crate::mesh_points::read(path, &options)? {
        Some(mesh) => (mesh.cloud, mesh.wound),
        None => (
            read_point_cloud_with(path, &options).map_err(|e| {
                read_error(
                    path,
                    e,
                    "record",
                    "zeroset fit needs finite coordinates and normals (`zeroset info` counts \
                     them all)",
                )
            })?,
            false,
        ),
    };
    // Curves in a plane first: a zero normal completed there would stand across the plane.
    check_not_curves(path, &cloud)?;
    let (cloud, _) = crate::normals::complete_normals(path, cloud, None)?;
    if let Some(note) = crate::normals::formations_note(path, &options) {
        line("formations", &note);
    }
    if cloud.normals().is_none() && crate::normals::is_gempy(path, &options) {
        bail!(
            "{} is a GemPy surface-points table: its points have no orientations, and estimating \
             normals from scattered interface points says little of the layers; fit the \
             orientations table (normals from dip, azimuth and polarity), or write the points \
             as an `x y z value` file (.xyzv), each formation at its own value, and fit that",
            path.display()
        );
    }
    if cloud.normals().is_none() {
        bail!(
            "{} has no normals: zeroset fit needs an oriented point cloud (x y z nx ny nz; PLY \
             properties nx ny nz; CSV columns nx,ny,nz); `zeroset normals {} -o ORIENTED.ply` \
             estimates them (and `zeroset reconstruct` does so itself)",
            path.display(),
            path.display()
        );
    }
    check_extent(path, &cloud)?;
    if !args.checked_by_reconstruct
        && let Some(warning) = crate::thickness::warning(path, &cloud)
    {
        line("points", &warning);
    }
    let unoriented = (!args.checked_by_reconstruct && !wound)
        .then(|| crate::normals::unoriented(&cloud))
        .flatten();
    if let Some(o) = unoriented {
        line(
            "normals",
            &format!(
                "warning: {}: the fit takes them as they are, and {} of the surface comes out \
                 inside out; estimate normals from the positions (`zeroset normals {} -o \
                 ORIENTED.ply`), or let `zeroset reconstruct` turn these",
                crate::normals::unoriented_text(path, &o),
                if o.unoriented_by_share() {
                    "half"
                } else {
                    "that part"
                },
                path.display()
            ),
        );
    }
    Ok(cloud)
}

/// Refuses a cloud whose points all lie on one axis-aligned plane (`z = 0`, as 2-D data is
/// written) with every normal in that plane: samples of curves in the plane, bounding no solid
/// in space, whose field every 3-D fit leaves undetermined across the plane (the RBF solve
/// fails on a singular polynomial block, MRAS on its flat box). Sheets scanned flat have
/// normals across their plane and pass.
pub(crate) fn check_not_curves(path: &Path, cloud: &PointCloud3) -> anyhow::Result<()> {
    let (Some(normals), Some(bounds)) = (cloud.normals(), cloud.bounds()) else {
        return Ok(());
    };
    // A cloud without extent is `check_extent`'s to refuse.
    if bounds.diagonal().is_nan() || bounds.diagonal() <= 0.0 {
        return Ok(());
    }
    let flat = (0..3).find(|&a| bounds.extent()[a] <= 1e-12 * bounds.diagonal());
    let Some(axis) = flat else {
        return Ok(());
    };
    // Zero normals (none there) lie in every plane; all zero, the cloud has none.
    let in_plane = normals.iter().any(|n| n.iter().any(|&x| x != 0.0))
        && normals
            .iter()
            .all(|n| n[axis].abs() <= 1e-3 * zeroset_field_core::geometry::norm(n));
    if in_plane {
        let name = ["x", "y", "z"][axis];
        let others = match axis {
            0 => "y z",
            1 => "x z",
            _ => "x y",
        };
        bail!(
            "{}: every point lies on the plane {name} = {} and every normal lies in it: these are \
             samples of curves in that plane (2-D data), which bound no solid in space. Fit them \
             as 2-D constraints: a value file (.xyv) of `{others} value` lines (0 at each point, \
             ±d at the point moved ±d along its normal), which `zeroset fit` and `zeroset mesh` \
             (SVG) take; or, for a flat sheet, give normals across the plane",
            path.display(),
            g(bounds.min()[axis])
        );
    }
    Ok(())
}

/// Refuses a cloud whose points all lie at one position (a box of diagonal 0): no surface
/// passes through it, and every length zeroset derives from the box would be 0.
pub(crate) fn check_extent(path: &Path, cloud: &PointCloud3) -> anyhow::Result<()> {
    if cloud.bounds().is_none_or(|b| b.diagonal() <= 0.0) {
        bail!(
            "{}: all {} points lie at one position (the cloud has no extent); a surface needs \
             points spread over it",
            path.display(),
            cloud.len()
        );
    }
    Ok(())
}

/// A reading error for the user: a non-finite value named by file, line, `noun` (record,
/// constraint) and field, followed by `advice`; any other error with the file as context.
pub(crate) fn read_error(path: &Path, e: Error, noun: &str, advice: &str) -> anyhow::Error {
    match e {
        Error::NonFinite {
            record,
            line,
            field,
            value,
            ..
        } => {
            let at = line.map(|l| format!("line {l}, ")).unwrap_or_default();
            anyhow::anyhow!(
                "{}: {at}{noun} {record}: non-finite {field} ({value}); {advice}",
                path.display()
            )
        }
        e => anyhow::Error::new(e).context(format!("reading {}", path.display())),
    }
}

impl FitArgs {
    /// The first option of `--method rbf` only that is given, as its flag.
    pub(crate) fn rbf_flag_given(&self) -> Option<&'static str> {
        [
            (self.kernel.is_some(), "--kernel"),
            (self.radius.is_some(), "--radius"),
            (self.smoothing.is_some(), "--smoothing"),
            (self.hermite, "--hermite"),
            (self.solver != SolverArg::Auto, "--solver"),
            (self.sampled, "--sampled"),
            (self.grid.is_some(), "--grid"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
    }
}

pub(crate) fn print_input(args: &FitArgs, cloud: &PointCloud3) {
    let n = cloud.len();
    line(
        "points",
        &format!(
            "{}: {n} point{} with normals{}",
            args.points_shown_as
                .clone()
                .unwrap_or_else(|| args.points.display().to_string()),
            if n == 1 { "" } else { "s" },
            args.formation
                .as_ref()
                .map_or(String::new(), |f| format!(" (formation {f})"))
        ),
    );
    if let Some(b) = cloud.bounds() {
        line("bounds", &format!("min {}", point(b.min())));
        more(&format!("max {}", point(b.max())));
        more(&format!("diagonal {}", g(b.diagonal())));
    }
}

/// Where the cloud's normals point inward on the whole ([`outwardness`] below
/// `−`[`FLAT_DIVERGENCE`]), prints a `normals` warning and returns it: zeroset's fields are
/// negative inside, where the normals point away from, so the fit comes out inside out (its
/// mesh of negative volume) — said before the fit rather than only by `mesh`.
pub(crate) fn inward_normals(cloud: &PointCloud3) -> Option<String> {
    let normals = cloud.normals()?;
    let r = outwardness(cloud.positions(), normals);
    (r < -FLAT_DIVERGENCE).then(|| {
        let warning = format!(
            "the normals point inward on the whole (Σ (p − c)·n / Σ ‖p − c‖ = {r:.2}, about 1 \
             for outward normals on a closed surface): the field will be positive inside and \
             its mesh inside out. Flip them, or let `zeroset normals` estimate them (unless \
             the scan is of a hollow's inside, a bowl or a room, facing its scanner)"
        );
        line("normals", &format!("warning: {warning}"));
        warning
    })
}

/// `--smoothing auto`: the smoothing [`Noise::rbf_smoothing`] gives the measured noise at the
/// size of the object `cloud` mostly samples ([`object_size`]), or none (interpolation) where
/// the noise cannot be measured; says which.
///
/// [`Noise::rbf_smoothing`]: zeroset_bases::noise::Noise::rbf_smoothing
fn auto_smoothing(
    noise: Option<&crate::noise::Measured>,
    cloud: &PointCloud3,
) -> anyhow::Result<f64> {
    let Some(m) = noise else {
        line(
            "smoothing",
            "none (auto: the noise cannot be measured on so few or so degenerate points; \
             --smoothing MU sets it)",
        );
        return Ok(0.0);
    };
    let size = object_size(cloud.positions(), m.noise.spacing).unwrap_or(m.diagonal);
    let mu = m.noise.rbf_smoothing(size);
    if !mu.is_finite() {
        bail!(
            "--smoothing auto: μ from the noise is not finite (the object size {} \
             overflows): give --smoothing MU, or move the cloud nearer the origin",
            g(size)
        );
    }
    let size_note = if size < m.diagonal * (1.0 - 1e-9) {
        format!(
            "the object size {} (the box diagonal of the piece of the cloud that holds its \
             median point; the whole cloud's {})",
            g(size),
            g(m.diagonal)
        )
    } else {
        format!("the diagonal {}", g(size))
    };
    line(
        "smoothing",
        &format!(
            "μ = {} (auto: {} × {:.3}² × {size_note}, from the noise: {})",
            g(mu),
            g(zeroset_bases::noise::RBF_SMOOTHING_SCALE),
            m.noise.relative(),
            m.describe()
        ),
    );
    Ok(mu)
}

/// Builds the constraints, fits with `kernel`, reports, and writes `-o`.
fn fit_with<K: StoredKernel>(kernel: K, job: CloudFit<'_>) -> anyhow::Result<()> {
    let (args, cloud) = (job.args, job.cloud);
    let n = cloud.len();
    // Warnings about the input, repeated on the report's `warnings` line.
    let mut warnings: Vec<String> = inward_normals(cloud).into_iter().collect();
    let constraints = if args.hermite {
        let c = Constraints::hermite(cloud).context("building the Hermite constraints")?;
        let kept = c.len() / 2;
        line(
            "constraints",
            &format!(
                "{} Hermite: {kept} values 0 on the surface, {kept} gradients (the unit normals)",
                c.len()
            ),
        );
        print_merged(n - kept);
        c
    } else {
        let offset = match args.offset.unwrap_or(OffsetArg::Auto) {
            OffsetArg::Auto => Offset::Auto {
                fraction: AUTO_FRACTION,
            },
            OffsetArg::Fixed(eps) => Offset::Fixed(eps),
        };
        let (c, report) = Constraints::off_surface(cloud, offset)
            .context("building the off-surface constraints")?;
        line(
            "constraints",
            &format!(
                "{} off-surface (Carr et al.): {} values 0 on the surface, {} at ±offset along \
                 the normals",
                c.len(),
                n - report.merged,
                c.len() - (n - report.merged)
            ),
        );
        warnings.extend(print_offset(
            args.offset.is_none(),
            &report,
            n - report.merged,
        ));
        c
    };
    // The cloud's diagonal, not the constraints' (their off-surface points reach past it).
    let diagonal = cloud.bounds().map_or(0.0, |b| b.diagonal());
    let field = solve(
        kernel,
        args,
        &constraints,
        (job.smoothing, diagonal),
        &warnings,
    )?;
    print_check(&field, job.input, job.outliers);
    if let Some(output) = &args.output {
        if args.sampled {
            save_sampled(&field, cloud, args, output)?;
        } else {
            save_rbf(&field, output)?;
        }
    }
    Ok(())
}

/// Fits `constraints` with `kernel` and the `--solver`, showing the iterative solver's steps,
/// and prints the report (its `warnings` line with `input_warnings` first).
fn solve<K: StoredKernel, const D: usize>(
    kernel: K,
    args: &FitArgs,
    constraints: &Constraints<D>,
    (smoothing, diagonal): (f64, f64),
    input_warnings: &[String],
) -> anyhow::Result<RbfField<K, D>> {
    line(
        "kernel",
        &format!("{} ({})", kernel.name(), kernel_words(kernel.name())),
    );
    let solver = match args.solver {
        SolverArg::Auto => Solver::Auto,
        SolverArg::Dense => Solver::Dense,
        SolverArg::Mixed => Solver::MixedPrecision,
        SolverArg::Iterative => Solver::Iterative(IterativeParams::default()),
    };
    let spinner = spinner(args.quiet);
    spinner.set_message(format!(
        "fitting {} constraints ({} solver)",
        constraints.len(),
        args.solver
            .to_possible_value()
            .map_or("auto".into(), |v| v.get_name().to_owned())
    ));
    // A dense solve the machine cannot hold, or a fallback to one, is refused by the fit
    // before it allocates (RbfError::Memory names the amount).
    let shown = spinner.clone();
    let base = spinner.message();
    let monitor = Monitor::new(move |p| {
        shown.set_message(format!(
            "{base}: step {}, residual {:.1e}",
            p.iteration, p.rel_residual
        ));
        ControlFlow::Continue(())
    });
    let fit = RbfFit::new(kernel)
        .with_solver(solver)
        .with_monitor(monitor)
        .with_smoothing(smoothing);
    let context = if args.solver == SolverArg::Iterative {
        "fitting the RBF field (--solver dense is exact, at O(n³) time)"
    } else {
        "fitting the RBF field"
    };
    let Some(fraction) = args.mras.tolerance_fraction(|| diagonal)? else {
        let fitted = fit.fit(constraints);
        spinner.finish_and_clear();
        let fitted = fitted.context(context)?;
        print_report(&fitted.report, input_warnings, Scope::All);
        return Ok(fitted.field);
    };
    // Greedy centre reduction to a tolerance given as a fraction of the data's diagonal (the
    // cloud's, or the value constraints') or as a distance.
    if !(fraction.is_finite() && fraction > 0.0 && fraction < 1.0) {
        bail!(
            "--tolerance {fraction}: give a fraction of the diagonal, between 0 and 1 (or \
             --tolerance-distance in the cloud's units)"
        );
    }
    let tolerance = args.mras.tolerance_distance.unwrap_or(fraction * diagonal);
    let result = fit.fit_greedy(constraints, &GreedyOptions::new(tolerance));
    spinner.finish_and_clear();
    let (fitted, greedy) = result.context(context)?;
    print_report(&fitted.report, input_warnings, Scope::Centres);
    let first = greedy.rounds.first().map_or(0, |r| r.centres);
    line(
        "greedy",
        &format!(
            "{} round(s), {first} → {} of {} centres; largest residual {} over all constraints \
             (tolerance {} = {} of the diagonal){}",
            greedy.rounds.len(),
            fitted.field.num_centres(),
            constraints.len(),
            g(greedy.max_residual),
            g(tolerance),
            g(fraction),
            if greedy.converged {
                ""
            } else {
                "; NOT met: the round limit stopped it"
            }
        ),
    );
    Ok(fitted.field)
}

fn kernel_words(name: &str) -> &'static str {
    match name {
        "r" => "biharmonic",
        "r3" => "triharmonic",
        "tps" => "thin-plate spline, r² ln r",
        "wendland" => "Wendland ψ₃,₁, compactly supported",
        _ => "",
    }
}

/// Prints the offsets' report; returns its warnings (flipped normals, a thin wall) for the
/// report's `warnings` line.
fn print_offset(auto: bool, r: &OffsetReport, points: usize) -> Vec<String> {
    let how = if auto {
        "auto, starting at 1% of the diagonal"
    } else {
        "fixed"
    };
    line(
        "offset",
        &format!(
            "{how}: initial {}, smallest {}; {} shrunk, {} dropped",
            g(r.initial),
            g(r.smallest),
            r.shrunk,
            r.dropped
        ),
    );
    if r.dropped > 0 {
        more(&format!(
            "({} offset point{} crossed the surface even at 1/256 of the offset and got no \
             constraint)",
            r.dropped,
            if r.dropped == 1 { "" } else { "s" }
        ));
    }
    let warning = (r.opposed_normals > 0).then(|| {
        let one = r.opposed_normals == 1;
        format!(
            "{} normal{} point{} against most of {} nearest neighbours' (flipped?): fitted \
             through with value 0 only, without the offsets that would put a bump or a bubble \
             there",
            r.opposed_normals,
            if one { "" } else { "s" },
            if one { "s" } else { "" },
            if one { "its" } else { "their" },
        )
    });
    if let Some(w) = &warning {
        more(&format!("warning: {w}"));
    }
    print_merged(r.merged);
    if r.touching > 0 {
        more(&format!(
            "({} of them at a place where an earlier point's normal points the other way: two \
             sheets meeting there (a mesh touching itself, two solids touching, a sharp edge's \
             split normals; or a flipped normal), each fitted with value 0 and offsets on the \
             side where the other sheet's points around it say the outside is)",
            r.touching
        ));
    }
    let thin = thin_wall_warning(r.thin_wall, points);
    if let Some(w) = &thin {
        more(&format!("warning: {w}"));
    }
    warning.into_iter().chain(thin).collect()
}

/// Above 1% of the points: a wall thinner than the sampling (a point's nearest neighbours
/// include the far face's, behind it and facing away), which a fit between its two faces
/// thickens or breaks. Measured on a clean tube of wall 1.1% of its diagonal, 20,000 exact
/// samples about a wall's thickness apart: RBF +23% volume with bumps of 0.9 walls, MRAS a
/// hole through it.
fn thin_wall_warning(thin: usize, points: usize) -> Option<String> {
    (thin * 100 > points).then(|| {
        format!(
            "{thin} points ({:.1}%) lie on a wall thinner than the points' spacing (their \
             nearest neighbours include the far face's, facing away): a fit thickens such a \
             wall, pits it or opens holes in it; sampling it more densely than its thickness \
             keeps it",
            100.0 * thin as f64 / points.max(1) as f64
        )
    })
}

/// Which constraints a fit's residual was measured over.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Scope {
    /// Every constraint (each is a centre).
    All,
    /// The constraints at the centres a greedy fit kept (the `greedy` line gives all).
    Centres,
}

fn print_report(r: &FitReport, input_warnings: &[String], scope: Scope) {
    line("solver", r.solver);
    line(
        "iterations",
        &match r.stalled_at {
            Some(rel) => format!(
                "{} (GMRES stopped at a relative residual of {rel:.1e}, short of its target \
                 by rounding, and was accepted: up to 1e-10 is; the max residual below is \
                 measured after)",
                r.iterations
            ),
            None => r.iterations.to_string(),
        },
    );
    line("unknowns", &r.unknowns.to_string());
    line("fit time", &format!("{:.3} s", r.elapsed.as_secs_f64()));
    let refined = match r.refinement_steps {
        0 => String::new(),
        1 => ", after 1 refinement step".to_owned(),
        s => format!(", after {s} refinement steps"),
    };
    line(
        "max residual",
        &format!(
            "{:.2e} (the largest |target − field| over the {over}{smoothed}{refined}{by})",
            r.max_residual,
            over = match scope {
                Scope::All => "constraints",
                Scope::Centres => "centres' constraints; over all of them, below",
            },
            smoothed = if r.misfit_max > 0.0 {
                ", of the smoothed system: its targets less the misfit below"
            } else {
                ""
            },
            by = if r.residual_exact { "" } else { ", by the FMM" }
        ),
    );
    if r.misfit_max > 0.0 {
        line(
            "misfit",
            &format!(
                "rms {:.2e}, max {:.2e} (how far the smoothed field misses the constraint values \
                 on purpose)",
                r.misfit_rms, r.misfit_max
            ),
        );
    }
    let condition = if r.condition_estimate.is_nan() {
        "n/a (the iterative solve forms no matrix)".to_owned()
    } else {
        format!("{:.2e} (a lower bound)", r.condition_estimate)
    };
    line("condition", &condition);
    let warnings: Vec<&String> = input_warnings.iter().chain(&r.warnings).collect();
    match warnings.split_first() {
        None => line("warnings", "none"),
        Some((first, rest)) => {
            line("warnings", first);
            for w in rest {
                more(w);
            }
        }
    }
}

/// The field at a few input points: the value should be ~0, the gradient ~unit length and
/// along the normal.
pub(crate) fn print_check<F: ScalarField<3> + ?Sized>(
    field: &F,
    cloud: &PointCloud3,
    set_aside: &[usize],
) {
    // Spread over the points fitted (`set_aside`, increasing, were not), named by their
    // index in the input.
    let fitted: Vec<usize> = (0..cloud.len())
        .filter(|i| set_aside.binary_search(i).is_err())
        .collect();
    let n = fitted.len();
    let normals = cloud.normals().unwrap_or_default();
    let mut picks: Vec<usize> = (0..CHECK_POINTS)
        .filter_map(|k| {
            fitted
                .get(k * n.saturating_sub(1) / (CHECK_POINTS - 1))
                .copied()
        })
        .collect();
    picks.dedup();
    line(
        "check",
        &format!(
            "the field at {} input point{} (want value ≈ 0, |∇f| ≈ 1, ∇f along the normal):",
            picks.len(),
            if picks.len() == 1 { "" } else { "s" }
        ),
    );
    more(&format!(
        "{:>6}  {:<36} {:>10} {:>9} {:>9}",
        "point", "position", "value", "|∇f|", "∠(∇f, n)"
    ));
    for i in picks {
        let p = cloud.positions()[i];
        let grad = field.gradient(&p);
        let angle = normals
            .get(i)
            .map(|nrm| angle_degrees(&grad, nrm))
            .map_or("-".to_owned(), |a| format!("{a:.2}°"));
        more(&format!(
            "{i:>6}  {:<36} {:>10.2e} {:>9.4} {:>9}",
            point(p),
            field.value(&p),
            norm(&grad),
            angle
        ));
    }
}

fn angle_degrees(a: &Point<3>, b: &Point<3>) -> f64 {
    let c = dot(a, b) / (norm(a) * norm(b));
    c.clamp(-1.0, 1.0).acos().to_degrees()
}

/// Writes the RBF field itself: kernel, centres, weights and polynomial (exact).
fn save_rbf<K: StoredKernel, const D: usize>(
    field: &RbfField<K, D>,
    output: &Path,
) -> anyhow::Result<()> {
    line(
        "output",
        &format!(
            "{}: the RBF field itself (kernel {}, {} centres; exact)",
            output.display(),
            field.kernel().tag(),
            field.num_centres()
        ),
    );
    write_rbf_field(output, field).with_context(|| format!("writing {}", output.display()))?;
    Ok(())
}

/// Samples `field` on the `--grid` and writes the quadratic B-spline through the samples.
fn save_sampled<F: ScalarField<3> + ?Sized>(
    field: &F,
    cloud: &PointCloud3,
    args: &FitArgs,
    output: &Path,
) -> anyhow::Result<()> {
    let bounds = cloud.bounds().context("the point cloud has no extent")?;
    let bounds = bounds.expanded(GRID_MARGIN * bounds.diagonal());
    let counts = args
        .grid
        .unwrap_or_else(|| cubic_counts(&bounds, DEFAULT_CELLS));
    let grid = Grid::cell_centered(bounds, counts).context("building the -o grid")?;
    line(
        "output",
        &format!(
            "{}: the RBF field sampled on {}×{}×{} cells and interpolated by a quadratic B-spline",
            output.display(),
            counts[0],
            counts[1],
            counts[2]
        ),
    );
    more(&format!(
        "grid over min {} max {} (the cloud's box grown by 5% of its diagonal)",
        point(grid.bounds().min()),
        point(grid.bounds().max())
    ));
    let start = Instant::now();
    let samples = sample(field, &grid, args.quiet);
    let sampling = start.elapsed();
    let start = Instant::now();
    let spline = BSplineField::interpolate(grid, samples, Degree::Quadratic)
        .context("interpolating the grid samples by a quadratic B-spline")?;
    let interpolation = start.elapsed();
    // How far the spline's zero set is from the input points, in field units (≈ distance).
    let mut at_points = vec![0.0; cloud.len()];
    spline.values(cloud.positions(), &mut at_points);
    let worst = at_points.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    more(&format!(
        "sampling {}, interpolation {}; the spline at the input points: max |value| {} (cell {})",
        seconds(sampling),
        seconds(interpolation),
        g(worst),
        g(grid.spacing().into_iter().fold(0.0, f64::max))
    ));
    write_field(output, &spline).with_context(|| format!("writing {}", output.display()))?;
    Ok(())
}

/// `field` at every grid point (linear order), in chunks through its batched, parallel
/// `values`, with a progress bar.
fn sample<F: ScalarField<3> + ?Sized>(field: &F, grid: &Grid<3>, quiet: bool) -> Vec<f64> {
    const CHUNK: usize = 1 << 14;
    let bar = counter(quiet, grid.len(), "sampling the RBF field");
    let mut out = vec![0.0; grid.len()];
    let mut points = Vec::with_capacity(CHUNK.min(grid.len()));
    for (c, chunk) in out.chunks_mut(CHUNK).enumerate() {
        let first = c * CHUNK;
        points.clear();
        points.extend((first..first + chunk.len()).map(|l| grid.point(grid.multi_index(l))));
        field.values(&points, chunk);
        bar.inc(chunk.len() as u64);
    }
    bar.finish_and_clear();
    out
}

const LABEL_WIDTH: usize = 13;

pub(crate) fn line(label: &str, value: &str) {
    let label = format!("{label}:");
    outln!("{label:<LABEL_WIDTH$} {value}");
}

/// A continuation line, aligned under the values.
pub(crate) fn more(value: &str) {
    outln!("{:<LABEL_WIDTH$} {value}", "");
}

pub(crate) fn parse_smoothing(s: &str) -> Result<SmoothingArg, String> {
    auto_or_number(s, SmoothingArg::Auto, SmoothingArg::Fixed)
        .map_err(|s| format!("the smoothing is auto or a number μ ≥ 0, got {s:?}"))
}

fn parse_offset(s: &str) -> Result<OffsetArg, String> {
    auto_or_number(s, OffsetArg::Auto, OffsetArg::Fixed)
        .map_err(|s| format!("the offset is auto or a distance, got {s:?}"))
}

/// `auto` (any case) or a number, surrounding blanks ignored; the trimmed text on failure.
fn auto_or_number<T>(s: &str, auto: T, number: fn(f64) -> T) -> Result<T, &str> {
    let s = s.trim();
    if s.eq_ignore_ascii_case("auto") {
        return Ok(auto);
    }
    s.parse::<f64>().map(number).map_err(|_| s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_offsets() {
        assert_eq!(parse_offset("auto").unwrap(), OffsetArg::Auto);
        assert_eq!(parse_offset(" AUTO ").unwrap(), OffsetArg::Auto);
        assert_eq!(parse_offset("0.01").unwrap(), OffsetArg::Fixed(0.01));
        // Checked (with a message) when the command runs, not by the parser.
        assert_eq!(parse_offset("-1").unwrap(), OffsetArg::Fixed(-1.0));
        assert!(parse_offset("small").is_err());
    }

    #[test]
    fn parses_smoothings() {
        assert_eq!(parse_smoothing(" Auto ").unwrap(), SmoothingArg::Auto);
        assert_eq!(parse_smoothing("0.5").unwrap(), SmoothingArg::Fixed(0.5));
        // Checked (with a message) when the command runs, not by the parser.
        assert_eq!(parse_smoothing("-1").unwrap(), SmoothingArg::Fixed(-1.0));
        assert!(parse_smoothing("lots").is_err());
    }

    #[test]
    fn angles_between_vectors() {
        assert!(angle_degrees(&[1.0, 0.0, 0.0], &[2.0, 0.0, 0.0]).abs() < 1e-12);
        assert!((angle_degrees(&[1.0, 0.0, 0.0], &[0.0, 3.0, 0.0]) - 90.0).abs() < 1e-12);
    }
}
