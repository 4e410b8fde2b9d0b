//! `zeroset restore`: mask-based restoration of a field (Ren–Fujita–Nakata) — protrusion
//! removal or de-noising inside a box — written as a `.zsf` field file.
//!
//! The input is a field file (a previous `zeroset restore`, or any `.zsf`) or an oriented point
//! cloud (PLY, xyzn, CSV…), which is turned into a field by Hoppe's tangent-plane distance
//! averaged over nearby samples. The field is sampled on a grid, restored in the mask and
//! interpolated by a quadratic B-spline; the result can be restored again.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};

use zeroset_bases::bspline::{BSplineField, Degree};
use zeroset_bases::field_file::{AnyField, is_field_file, read_any_field, write_field};
use zeroset_bases::tangent_plane::TangentPlaneField;
use zeroset_field_core::field::{ScalarField, distance_to_zero_set, project_to_zero_set};
use zeroset_field_core::geometry::Point;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::io::{ReadOptions, read_point_cloud_with};
use zeroset_field_core::mask::{BoxMask, Face};
use zeroset_restore::RestoreError;
use zeroset_restore::denoise::{Denoise, Resampling};
use zeroset_restore::error::face_name;
use zeroset_restore::protrusion::{Convention, Protrusion};

use crate::info::g;
use crate::machine::{counts_text, ensure_memory, sample_count};

/// Shown after `zeroset restore --help`.
pub const EXAMPLES: &str = "\
Examples:
  # remove the bunny's ears: the mask's bottom face (-y) is where they join the head
  zeroset restore samples/bunny_2k.xyzn --mode protrusion \\
      --mask -0.1,0.145,-0.07:0.005,0.2,0.05 --face -y -o no_ears.zsf
  # flatter: a steeper slope across the face
  zeroset restore samples/bunny_2k.xyzn --mode protrusion \\
      --mask -0.1,0.145,-0.07:0.005,0.2,0.05 --face -y --alpha 3 -o flat.zsf
  # then smooth a region of the result (restorations compose)
  zeroset restore no_ears.zsf --mode denoise --mask -0.05,0.05,-0.03:0.05,0.12,0.06 \\
      --coarse 6,6,4 -o smooth.zsf";

/// Which restoration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// Replace a protrusion by a least-squares harmonic fill with a slope α across --face.
    Protrusion,
    /// Resample the mask coarsely (--coarse) and interpolate: removes jaggy noise.
    Denoise,
}

/// Where a restoration's field comes from: the input and how to read it. Shared by `zeroset
/// restore` and `zeroset studio`.
#[derive(Debug, Args)]
pub struct Source {
    /// A field file (.zsf: a B-spline field, restored on its own grid; an RBF, MRAS or neural
    /// field, sampled onto the grid) or an oriented point cloud in any format zeroset reads
    /// (sampled through a tangent-plane field of its nearest points, which moves the surface
    /// outside the mask by up to a few thousandths of the diagonal: fit a field first where
    /// that matters).
    pub input: PathBuf,

    /// Grid cells per axis, L,M,N (default: a B-spline field file's grid, or 64 along the
    /// longest axis of another field's or a point cloud's box, 3 of them beyond it on each
    /// side, with near-cubic cells). Cells of other shapes are allowed for: the Laplace rows
    /// weigh each axis by its spacing.
    #[arg(long, value_parser = parse_counts)]
    pub grid: Option<[usize; 3]>,

    /// Point clouds: the number of nearest samples averaged by the tangent-plane field
    /// (default 8; refused for a field file, which has no samples to average).
    #[arg(long)]
    pub neighbours: Option<usize>,

    #[arg(long, value_name = "FORMAT", help = crate::normals::FORMAT_HELP)]
    pub format: Option<String>,

    /// The data are positive inside (zeroset's convention is negative inside).
    #[arg(long)]
    pub positive_inside: bool,
}

/// Arguments of `zeroset restore`.
#[derive(Debug, Args)]
pub struct RestoreArgs {
    #[command(flatten)]
    pub source: Source,

    /// The box to restore, two opposite corners in world coordinates: x0,y0,z0:x1,y1,z1 (cut
    /// to the grid's box where it reaches beyond it, with a note).
    #[arg(long, value_parser = parse_mask, allow_hyphen_values = true)]
    pub mask: [[f64; 3]; 2],

    /// protrusion or denoise.
    #[arg(long, value_enum)]
    pub mode: Mode,

    /// Protrusion: the mask face the protrusion's base crosses (+x, -x, +y, -y, +z, -z).
    /// Without it the mask is filled harmonically from its boundary (no slope condition).
    #[arg(long, value_parser = parse_face, allow_hyphen_values = true)]
    pub face: Option<Face>,

    /// Protrusion: the field's slope entering the mask across --face, in field units per unit
    /// length. Larger = flatter. The default, the field's own mean slope across the face,
    /// counts the protrusion's cross-section too and can keep part of it; on a distance-like
    /// field (|∇f| ≈ 1, as fitted fields are near their surface) 1 continues the body and 2–5
    /// flatten it, while values far above the field's slope (past ~30) make the spline
    /// overshoot into thin sheets outside the mask.
    #[arg(long, allow_hyphen_values = true)]
    pub alpha: Option<f64>,

    /// Denoise: coarse cells per axis inside the mask, m,n,l (fewer = smoother; as many as
    /// the mask has cells leaves it as it is).
    #[arg(long, value_parser = parse_counts)]
    pub coarse: Option<[usize; 3]>,

    /// Denoise: sample the field at the coarse points (the paper's rule) instead of averaging
    /// the fine samples over each coarse cell.
    #[arg(long)]
    pub point_resampling: bool,

    /// The output field file (.zsf), written atomically.
    #[arg(short, long)]
    pub output: PathBuf,

    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,

    /// No progress spinner (sampling the field, restoring, measuring the drift).
    #[arg(long)]
    pub quiet: bool,
}

impl RestoreArgs {
    /// The restoration the flags ask for, refusing flags of the other mode.
    fn restoration(&self) -> anyhow::Result<Restoration> {
        match self.mode {
            Mode::Protrusion => {
                if self.coarse.is_some() {
                    bail!("--coarse applies to --mode denoise");
                }
                if self.alpha.is_some() && self.face.is_none() {
                    bail!("--alpha is the slope across --face: give --face too");
                }
                Ok(Restoration::Protrusion {
                    mask: self.mask,
                    face: self.face,
                    alpha: self.alpha,
                })
            }
            Mode::Denoise => {
                if self.face.is_some() || self.alpha.is_some() {
                    bail!("--face and --alpha apply to --mode protrusion");
                }
                let Some(coarse) = self.coarse else {
                    bail!(
                        "--mode denoise needs --coarse m,n,l (coarse cells per axis in the mask)"
                    );
                };
                Ok(Restoration::Denoise {
                    mask: self.mask,
                    coarse,
                    point_resampling: self.point_resampling,
                })
            }
        }
    }
}

/// Bytes per grid sample that a restoration holds at once: the field's samples, the restored
/// samples and the quadratic spline's coefficients, 8 bytes each.
const BYTES_PER_SAMPLE: u64 = 24;

/// Bytes per mask cell (and per coarse cell) for the least-squares system or the coarse fit:
/// an estimate of the local copy of the field, the right-hand side, the solution and the
/// solver's or spline's work vectors, 8 bytes each.
const BYTES_PER_MASK_CELL: u64 = 64;

/// Runs `zeroset restore`.
pub fn run(args: &RestoreArgs) -> anyhow::Result<()> {
    let input = &args.source.input;
    crate::output::check_output(&args.output, &[input], args.force, &["zsf"])?;
    // Counts whose product overflows are refused before anything is read.
    args.source.check_counts()?;
    if let Some(coarse) = &args.coarse {
        sample_count(coarse, "--coarse")?;
    }
    let restoration = args.restoration()?;
    let start = Instant::now();
    let loaded = args.source.load()?;
    outln!("{}", loaded.description);
    let grid = loaded.grid;
    let mask = restoration.mask(&grid)?;
    if let Some(note) = restoration.clamp_note(&grid) {
        outln!("{note}");
    }
    restoration.check_size(&grid, &mask, args.source.grid.is_some())?;
    let counts = grid.counts();
    outln!(
        "grid {}×{}×{} cells over {:?} .. {:?}; mask cells {:?} ..= {:?} ({} cells)",
        counts[0],
        counts[1],
        counts[2],
        grid.bounds().min(),
        grid.bounds().max(),
        mask.lo(),
        mask.hi(),
        mask.len()
    );
    if let Restoration::Protrusion { face: None, .. } = restoration {
        outln!("no --face: filling the mask harmonically from its boundary");
    }
    let bar = crate::progress::spinner(args.quiet);
    bar.set_message(format!("sampling the field at {} grid points", grid.len()));
    let samples = grid.sample(loaded.field.as_ref());
    let near_surface = near_surface_probes(&grid, &samples, &mask);
    if let Some(note) = no_surface_note(&grid, &samples, &mask) {
        bar.suspend(|| outln!("{note}"));
    }
    bar.set_message("restoring the mask");
    let restored = restoration.restore(
        loaded.field.as_ref(),
        &grid,
        &samples,
        &mask,
        args.source.convention(),
    );
    bar.finish_and_clear();
    let restored = restored?;
    match &restored.report {
        Report::Protrusion(r) => {
            if let Some(alpha) = r.alpha {
                outln!(
                    "alpha {alpha:.4}{}",
                    if args.alpha.is_none() {
                        " (the field's mean slope across the face)"
                    } else {
                        ""
                    }
                );
                if alpha <= 0.0 && args.alpha.is_some() {
                    // Asked for, the field falls (or stays) entering the mask: the inside grows.
                    // (The default, the field's mean slope across the face, counts the
                    // protrusion's cross-section and can be negative while it removes it.)
                    outln!(
                        "warning: alpha {} does not rise into the mask across the face, so the \
                         part inside grows (or spreads sideways) instead of flattening: positive \
                         values flatten it (on a distance-like field 1 continues the body)",
                        g(alpha)
                    );
                }
            }
            outln!(
                "{} unknowns, {} equations, solver {}: assembly {:.1} ms, solve {:.1} ms; \
                 relative residual {:.3e}",
                r.unknowns,
                r.rows,
                r.solve.solver,
                r.assembly.as_secs_f64() * 1e3,
                r.solve.elapsed.as_secs_f64() * 1e3,
                r.solve.rel_residual
            );
        }
        Report::Denoise { coarse, resampling } => outln!(
            "coarse {coarse:?} ({resampling:?} resampling): {:.1} ms",
            restored.elapsed.as_secs_f64() * 1e3,
        ),
    }
    let spline = Instant::now();
    let field = interpolate(&grid, restored.samples)?;
    outln!(
        "quadratic spline through the restored samples: {:.1} ms",
        spline.elapsed().as_secs_f64() * 1e3
    );
    // A field file's surface is what the user had (a point cloud's tangent-plane field is only
    // a means to a field, and resampling it is the point).
    if !loaded.own_grid && loaded.points.is_none() {
        let bar = crate::progress::spinner(args.quiet);
        bar.set_message("measuring how far resampling moved the surface outside the mask");
        report_drift(loaded.field.as_ref(), &field, &grid, &near_surface, bar);
    }
    write_field(&args.output, &field)
        .with_context(|| format!("writing {}", args.output.display()))?;
    outln!(
        "wrote {} in {:.2} s",
        args.output.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The points [`report_drift`] compares the input and the restored field at: between the
/// grid's samples (half a cell from a sample on every axis, where a spline through the samples
/// strays most), beside samples within a cell's diagonal of the surface (`|f| <` it: the
/// fields zeroset fits are distance-like there), [`DRIFT_MARGIN`] cells or more from the mask;
/// at most [`DRIFT_PROBES`], spread evenly over them.
fn near_surface_probes(grid: &Grid<3>, samples: &[f64], mask: &BoxMask<3>) -> Vec<Point<3>> {
    let counts = grid.counts();
    let h = grid.spacing();
    let reach = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let (lo, hi) = (mask.lo(), mask.hi());
    let near_mask = |index: [usize; 3]| {
        (0..3).all(|a| index[a] + DRIFT_MARGIN >= lo[a] && index[a] <= hi[a] + DRIFT_MARGIN)
    };
    let candidates: Vec<Point<3>> = (0..grid.len())
        .filter_map(|linear| {
            let index = grid.multi_index(linear);
            let inner = (0..3).all(|a| index[a] + 1 < counts[a]);
            (inner && samples[linear].abs() < reach && !near_mask(index)).then(|| {
                let p = grid.point(index);
                std::array::from_fn(|a| p[a] + 0.5 * h[a])
            })
        })
        .collect();
    let stride = candidates.len().div_ceil(DRIFT_PROBES).max(1);
    candidates.into_iter().step_by(stride).collect()
}

/// Where the field's samples do not cross 0 (its surface) in the mask, or nowhere on the grid:
/// a mask with no surface in it has nothing to restore (its corners are most often in other
/// coordinates than the field's), and a field with no zero set meshes to nothing.
fn no_surface_note(grid: &Grid<3>, samples: &[f64], mask: &BoxMask<3>) -> Option<String> {
    let range = |values: &mut dyn Iterator<Item = f64>| {
        values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
    };
    let crosses = |(lo, hi): (f64, f64)| lo <= 0.0 && hi >= 0.0;
    let whole = range(&mut samples.iter().copied());
    if !crosses(whole) {
        return Some(format!(
            "warning: the field does not reach 0 anywhere on the grid (its samples run from {} \
             to {}): it has no surface here to restore, and its mesh at level 0 is empty",
            g(whole.0),
            g(whole.1)
        ));
    }
    let (lo, hi) = (mask.lo(), mask.hi());
    let in_mask = |linear: &usize| {
        let index = grid.multi_index(*linear);
        (0..3).all(|a| lo[a] <= index[a] && index[a] <= hi[a])
    };
    let masked = range(&mut (0..grid.len()).filter(in_mask).map(|l| samples[l]));
    (!crosses(masked)).then(|| {
        format!(
            "warning: the field does not reach 0 inside the mask (its samples there run from {} \
             to {}): the mask holds no surface to restore; are its corners in the field's \
             coordinates?",
            g(masked.0),
            g(masked.1)
        )
    })
}

/// The cells around the mask [`near_surface_probes`] leaves out: the spline through the
/// samples is global, and a sample changed in the mask moves its coefficients outside by a
/// factor of about 0.17 per cell (quadratic B-spline interpolation), 5e-3 at 3 cells; here 4.
const DRIFT_MARGIN: usize = 4;

/// The most points [`report_drift`] evaluates both fields at (20,000 doubled a restore of the
/// 34,834-point bunny's RBF field, 104,502 centres, on one thread: 35 s → 68 s).
const DRIFT_PROBES: usize = 2_000;

/// Reports how far the restored field's surface lies from the input's outside the mask, where
/// only the resampling changed it: each probe is moved onto the input's zero set along its
/// gradient, and from there onto the restored field's
/// ([`distance_to_zero_set`]: an upper bound of the distance between the two surfaces there);
/// with a warning where the median exceeds [`DRIFT_WARNING`] of the box diagonal (the whole
/// surface moved), the largest [`DRIFT_MAX_WARNING`] (a part moved) or more than
/// [`DRIFT_LOST_WARNING`] of the probes find no restored surface near (a part lost).
fn report_drift(
    input: &dyn ScalarField<3>,
    restored: &BSplineField<3>,
    grid: &Grid<3>,
    probes: &[Point<3>],
    bar: indicatif::ProgressBar,
) {
    use rayon::prelude::*;
    let h = grid.spacing();
    let reach = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let tol = 1e-9 * grid.bounds().diagonal();
    // Per probe on the input's surface: the restored surface's distance, or `None` where the
    // walk onto it fails (no restored surface near: a part the grid lost).
    let found: Vec<Option<f64>> = probes
        .par_iter()
        .filter_map(|p| {
            // The input's surface point nearest `p` along its gradient (within `reach`: where
            // the gradient vanishes, a thin part's axis, the walk goes nowhere useful), then
            // the restored surface's distance from it along the restored field's gradient.
            let q = project_to_zero_set(input, p, tol, 20)?;
            let moved: f64 = (0..3).map(|a| (q[a] - p[a]).powi(2)).sum::<f64>().sqrt();
            if moved > reach {
                return None;
            }
            Some(distance_to_zero_set(restored, &q, tol, 20))
        })
        .collect();
    bar.finish_and_clear();
    let lost = found.iter().filter(|d| d.is_none()).count();
    let mut drift: Vec<f64> = found.into_iter().flatten().collect();
    if drift.is_empty() && lost == 0 {
        return;
    }
    drift.sort_by(f64::total_cmp);
    let at = |q: f64| {
        drift
            .get(((drift.len() as f64 - 1.0) * q).round() as usize)
            .copied()
    };
    let (median, p99, max) = (
        at(0.5).unwrap_or(0.0),
        at(0.99).unwrap_or(0.0),
        at(1.0).unwrap_or(0.0),
    );
    let diagonal = grid.bounds().diagonal();
    let tested = drift.len() + lost;
    outln!(
        "outside the mask: the resampled surface lies a median {} ({} of the diagonal) from \
         the input's, 99% within {}, at most {} ({} of the diagonal), measured from {} points \
         of the input's surface{}",
        g(median),
        g(median / diagonal),
        g(p99),
        g(max),
        g(max / diagonal),
        tested,
        if lost > 0 {
            format!("; at {lost} of them it has no surface near (a part the grid lost)")
        } else {
            String::new()
        }
    );
    let lost_share = lost as f64 / tested as f64;
    if median > DRIFT_WARNING * diagonal
        || max > DRIFT_MAX_WARNING * diagonal
        || lost_share > DRIFT_LOST_WARNING
    {
        outln!(
            "warning: the grid's cells ({}) are coarse for this surface: resampled on them, the \
             field moves it outside the mask as well (a part thinner than a few cells shrinks, \
             swells or vanishes); a finer --grid keeps it (memory and time grow with the cells)",
            g(h.iter().copied().fold(0.0, f64::max)),
        );
    }
}

/// [`report_drift`] warns where the median drift exceeds this fraction of the box diagonal
/// (the whole surface moved). Measured with the default grid (64 cells along the longest
/// side): a rod of radius 0.05 and length 4 (its cells 0.077 across) 6.2e-4, its radius 6%
/// smaller (the review that found it measured the mesh); the kitten's MRAS field 1.4e-5, the
/// 2,000-point bunny's RBF field 2.7e-5, the 34,834-point bunny's MRAS field 3.3e-5 (both with
/// their ears removed), a torus's RBF field 1.2e-5, the MRAS field of a sphere with a knob
/// 8e-7 (the knob removed); the rod on 256 × 16 × 16 cells 4e-5.
const DRIFT_WARNING: f64 = 2e-4;

/// [`report_drift`] warns where the largest drift exceeds this fraction of the box diagonal (a
/// part moved). Measured (2,000 probes): a ball of radius 1 with a rod of radius 0.01 / 0.02 (a
/// second review's; resampled on the default grid the rod swelled by 77% / 34% of its radius)
/// 2.0e-3 / 2.5e-3, the rod of radius 0.05 alone 3.5e-3; the ordinary restorations above at
/// most 9.4e-4 (the 2,000-point bunny's RBF field; the 34,834-point bunny's MRAS field 5.9e-4,
/// the kitten's 3.7e-4). A largest figure over 2,000 probes: a part few of them land on can
/// escape it, and a thinner rod on the same ball would.
const DRIFT_MAX_WARNING: f64 = 1.5e-3;

/// [`report_drift`] warns where more than this share of the probes find no restored surface
/// near them.
const DRIFT_LOST_WARNING: f64 = 0.01;

/// One restoration, as `zeroset restore`'s flags (or a studio request) give it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Restoration {
    /// `--mode protrusion`.
    Protrusion {
        /// Two opposite corners of the box, world coordinates.
        mask: [[f64; 3]; 2],
        /// `--face`, or the harmonic fill.
        face: Option<Face>,
        /// `--alpha`, or the field's mean slope across the face.
        alpha: Option<f64>,
    },
    /// `--mode denoise`.
    Denoise {
        /// Two opposite corners of the box, world coordinates.
        mask: [[f64; 3]; 2],
        /// `--coarse`.
        coarse: [usize; 3],
        /// `--point-resampling`.
        point_resampling: bool,
    },
}

/// What a restoration did.
#[derive(Debug, Clone)]
pub(crate) enum Report {
    /// The least-squares solve's report.
    Protrusion(zeroset_restore::protrusion::Report),
    /// The coarse grid and its resampling rule.
    Denoise {
        coarse: [usize; 3],
        resampling: Resampling,
    },
}

/// The restored samples of the grid and how they were made.
#[derive(Debug, Clone)]
pub(crate) struct Restored {
    /// `f` outside the mask, the restoration inside (last axis fastest).
    pub samples: Vec<f64>,
    pub report: Report,
    /// Time to restore the samples (not the spline through them).
    pub elapsed: std::time::Duration,
}

impl Restoration {
    /// The mask's corners.
    pub(crate) fn corners(&self) -> [[f64; 3]; 2] {
        match self {
            Self::Protrusion { mask, .. } | Self::Denoise { mask, .. } => *mask,
        }
    }

    /// The mask's corners cut to `grid`'s box, and the axes cut
    /// ([`zeroset_restore::clamp_mask_corners`]).
    fn clamped_corners(&self, grid: &Grid<3>) -> ([[f64; 3]; 2], Vec<usize>) {
        let [a, b] = self.corners();
        zeroset_restore::clamp_mask_corners(grid, a, b)
    }

    /// A note saying on which axes the mask was cut to `grid`'s box, if it was.
    pub(crate) fn clamp_note(&self, grid: &Grid<3>) -> Option<String> {
        let (_, cut) = self.clamped_corners(grid);
        (!cut.is_empty()).then(|| {
            let bb = grid.bounds();
            let axes: Vec<&str> = cut.iter().map(|&a| ["x", "y", "z"][a]).collect();
            format!(
                "note: the mask reaches beyond the sampling grid's box on {}: cut to that box, {} .. {}",
                axes.join(", "),
                crate::info::point(bb.min()),
                crate::info::point(bb.max()),
            )
        })
    }

    /// The mask on `grid`: the cells whose centres lie in the box, the box cut to the grid's
    /// where it reaches beyond it ([`clamp_note`](Self::clamp_note) says so).
    ///
    /// # Errors
    /// A box outside the grid's, or one holding no cell centre.
    pub(crate) fn mask(&self, grid: &Grid<3>) -> anyhow::Result<BoxMask<3>> {
        let ([a, b], _) = self.clamped_corners(grid);
        let mask = BoxMask::from_corners(grid, a, b);
        if let Err(zeroset_field_core::Error::EmptyMask { axis, lo, hi }) = mask {
            // Inside the box, but between two samples: thinner than a cell there.
            bail!(
                "the mask holds no grid sample along {} (from {} to {}, where the grid's samples \
                 lie {} apart): widen it there or sample the field finer (--grid)",
                ["x", "y", "z"][axis],
                g(lo),
                g(hi),
                g(grid.spacing()[axis])
            );
        }
        mask.with_context(|| {
            let bb = grid.bounds();
            format!(
                "the mask must lie in the field's box {} .. {}",
                crate::info::point(bb.min()),
                crate::info::point(bb.max())
            )
        })
    }

    /// Refuses a restoration that cannot run here, before the field is sampled: `--coarse`
    /// finer than the mask on some axis, or more memory than is available
    /// ([`BYTES_PER_SAMPLE`] per grid sample plus [`BYTES_PER_MASK_CELL`] per mask and coarse
    /// cell). `explicit_grid`: the grid came from `--grid` (for the message).
    pub(crate) fn check_size(
        &self,
        grid: &Grid<3>,
        mask: &BoxMask<3>,
        explicit_grid: bool,
    ) -> anyhow::Result<()> {
        let coarse_cells = match self {
            Self::Denoise { coarse, .. } => {
                let extent = mask.extent();
                if let Some(axis) = (0..3).find(|&a| coarse[a] > extent[a]) {
                    return Err(anyhow::Error::new(RestoreError::InvalidCoarse {
                        axis,
                        coarse: coarse[axis],
                        extent: extent[axis],
                    })
                    .context(format!("--coarse {}", counts_text(coarse))));
                }
                sample_count(coarse, "--coarse")?
            }
            Self::Protrusion { .. } => 0,
        };
        let extra = (mask.len() as u64)
            .saturating_add(coarse_cells as u64)
            .saturating_mul(BYTES_PER_MASK_CELL);
        check_grid_memory(grid, explicit_grid, 1, extra)
    }

    /// Restores `samples` (of `field` on `grid`) in `mask`: the same computation, on the same
    /// samples, whether `zeroset restore` or the studio asks, so their fields are the same bits.
    ///
    /// # Errors
    /// The restoration's (a face on the grid's border, a mask covering the grid, …).
    pub(crate) fn restore(
        &self,
        field: &dyn ScalarField<3>,
        grid: &Grid<3>,
        samples: &[f64],
        mask: &BoxMask<3>,
        convention: Convention,
    ) -> anyhow::Result<Restored> {
        let start = Instant::now();
        match *self {
            Self::Protrusion { face, alpha, .. } => {
                let params = Protrusion {
                    face,
                    alpha,
                    convention,
                    ..Protrusion::default()
                };
                let (samples, report) = params
                    .restore_samples(grid, samples, mask)
                    .context("protrusion removal")?;
                if let Some(v) = samples.iter().find(|v| !v.is_finite()) {
                    bail!(
                        "protrusion removal gave a non-finite value ({v}): α = {} is too large \
                         for this field",
                        report.alpha.unwrap_or(f64::NAN)
                    );
                }
                Ok(Restored {
                    samples,
                    report: Report::Protrusion(report),
                    elapsed: start.elapsed(),
                })
            }
            Self::Denoise {
                coarse,
                point_resampling,
                ..
            } => {
                let resampling = if point_resampling {
                    Resampling::Point
                } else {
                    Resampling::Area
                };
                let samples = Denoise::new(coarse)
                    .with_resampling(resampling)
                    .restore_samples(field, grid, samples, mask)
                    .context("de-noising")?;
                Ok(Restored {
                    samples,
                    report: Report::Denoise { coarse, resampling },
                    elapsed: start.elapsed(),
                })
            }
        }
    }

    /// The `zeroset restore` flags that ask for this restoration (numbers written so that they
    /// parse back to the same `f64`).
    pub(crate) fn flags(&self) -> String {
        let [a, b] = self.corners();
        let mask = format!(
            "--mask {},{},{}:{},{},{}",
            a[0], a[1], a[2], b[0], b[1], b[2]
        );
        match self {
            Self::Protrusion { face, alpha, .. } => {
                let mut text = format!("--mode protrusion {mask}");
                if let Some(face) = face {
                    text.push_str(&format!(" --face {}", face_name(*face)));
                }
                if let Some(alpha) = alpha {
                    text.push_str(&format!(" --alpha {alpha}"));
                }
                text
            }
            Self::Denoise {
                coarse,
                point_resampling,
                ..
            } => {
                let mut text = format!("--mode denoise {mask} --coarse {}", counts_text(coarse));
                if *point_resampling {
                    text.push_str(" --point-resampling");
                }
                text
            }
        }
    }
}

/// Refuses a grid whose `copies` sets of samples (each with its spline coefficients and the
/// restored samples: [`BYTES_PER_SAMPLE`] per sample), plus `extra` bytes, do not fit in the
/// memory available. `explicit_grid`: the grid came from `--grid` (for the message).
pub(crate) fn check_grid_memory(
    grid: &Grid<3>,
    explicit_grid: bool,
    copies: u64,
    extra: u64,
) -> anyhow::Result<()> {
    let counts = grid.counts();
    let samples = sample_count(&counts, "--grid")? as u64;
    let what = if explicit_grid {
        format!("--grid {}", counts_text(&counts))
    } else {
        format!("the grid {}", counts_text(&counts).replace(',', "×"))
    };
    ensure_memory(
        samples
            .saturating_mul(BYTES_PER_SAMPLE)
            .saturating_mul(copies)
            .saturating_add(extra),
        &format!("{what} ({} cells)", g(samples as f64)),
        "choose fewer cells per axis with --grid L,M,N",
    )
}

/// The bytes one state of a restoration history holds: its samples and its spline's
/// coefficients.
pub(crate) fn state_bytes(grid: &Grid<3>) -> u64 {
    (grid.len() as u64).saturating_mul(16)
}

/// The quadratic B-spline through the samples of `grid` (the paper's Eqs. 6 and 9): the
/// restored field.
///
/// # Errors
/// The spline's (wrong sample count), and a coefficient that is not finite or whose square
/// would overflow (beyond `√f64::MAX` ≈ 1.3e154: gradients, norms and sums of squares of the
/// field would): values that large come from a slope α far beyond the field's own.
pub(crate) fn interpolate(grid: &Grid<3>, samples: Vec<f64>) -> anyhow::Result<BSplineField<3>> {
    let field = BSplineField::interpolate(*grid, samples, Degree::Quadratic)
        .context("interpolating the restored samples")?;
    let limit = f64::MAX.sqrt();
    if let Some(c) = field
        .coefficients()
        .iter()
        .find(|c| !c.is_finite() || c.abs() > limit)
    {
        bail!(
            "the restored field overflows (a spline coefficient is {c:e}): the restoration's \
             values are too large, is α far beyond the field's own slope?"
        );
    }
    Ok(field)
}

/// The input, read: the field to restore, the grid to restore it on, and what it is.
pub(crate) struct Loaded {
    /// The field (a point cloud's tangent-plane field, or the field file's).
    pub field: Box<dyn ScalarField<3>>,
    /// The grid: `--grid` over the field's box, a B-spline field's own grid, or
    /// [`zeroset_restore::sampling_grid`].
    pub grid: Grid<3>,
    /// One line saying what was read.
    pub description: String,
    /// A point cloud's points (none for a field file).
    pub points: Option<Vec<Point<3>>>,
    /// The grid is a B-spline field's own: its samples give the field back, so the restored
    /// field equals it outside the mask (no drift to report).
    pub own_grid: bool,
}

impl Source {
    /// Refuses `--grid` counts whose product overflows, before anything is read.
    pub(crate) fn check_counts(&self) -> anyhow::Result<()> {
        if let Some(counts) = &self.grid {
            sample_count(counts, "--grid")?;
        }
        Ok(())
    }

    /// The sign convention of the data.
    pub(crate) fn convention(&self) -> Convention {
        if self.positive_inside {
            Convention::PositiveInside
        } else {
            Convention::NegativeInside
        }
    }

    /// Reads the input as a field and picks the grid to restore it on.
    pub(crate) fn load(&self) -> anyhow::Result<Loaded> {
        let mut loaded = self.load_field()?;
        if let Some(counts) = self.grid {
            let grid =
                Grid::cell_centered(loaded.grid.bounds(), counts).context("building the --grid")?;
            if loaded.own_grid && grid == loaded.grid {
                return Ok(loaded);
            }
            loaded.grid = grid;
            if loaded.own_grid {
                // Said, since a B-spline field is otherwise given back exactly outside the mask.
                loaded.description += ", resampled on the --grid (not its own)";
            }
            loaded.own_grid = false;
        }
        Ok(loaded)
    }

    /// The input as a field, and the grid to restore it on by default.
    fn load_field(&self) -> anyhow::Result<Loaded> {
        let input = &self.input;
        let zsf = input.extension().and_then(|e| e.to_str()) == Some("zsf");
        if zsf || is_field_file(input) {
            if let Some(k) = self.neighbours {
                bail!(
                    "--neighbours {k} applies to point clouds (the tangent-plane field averages \
                     that many samples); {} is a field file, restored as it is",
                    input.display()
                );
            }
            let field = read_any_field::<3>(input)
                .with_context(|| format!("reading {}", input.display()))?;
            let described = field.describe();
            return match field {
                AnyField::BSpline(field) => {
                    let grid = *field.grid();
                    Ok(Loaded {
                        field: Box::new(field),
                        grid,
                        description: format!("field file {}: {described}", input.display()),
                        points: None,
                        own_grid: true,
                    })
                }
                field @ (AnyField::Rbf(_) | AnyField::Neural(_) | AnyField::Mras(_)) => {
                    // Sampled onto a grid over the field's box, like a point cloud's field.
                    let bounds = field.bounds().context("the field has no bounds")?;
                    let grid = zeroset_restore::sampling_grid(bounds)?;
                    Ok(Loaded {
                        field: Box::new(field),
                        grid,
                        description: format!(
                            "field file {}: {described}, sampled on the grid",
                            input.display()
                        ),
                        points: None,
                        own_grid: false,
                    })
                }
            };
        }
        let mut options = ReadOptions::default();
        if let Some(format) = &self.format {
            options = options.with_format(format.parse().context("--format")?);
        }
        let cloud = match crate::mesh_points::read(input, &options)? {
            Some(mesh) => mesh.cloud,
            None => read_point_cloud_with(input, &options).map_err(|e| {
                crate::fit::read_error(
                    input,
                    e,
                    "record",
                    "zeroset restore needs finite coordinates and normals (`zeroset info` \
                     counts them all)",
                )
            })?,
        };
        let (cloud, _) = crate::normals::complete_normals(input, cloud, None)?;
        if cloud.normals().is_none() {
            bail!(
                "{} has no normals: a point cloud is restored through its tangent-plane field, \
                 which needs an oriented cloud (x y z nx ny nz; PLY properties nx ny nz; CSV \
                 columns nx,ny,nz); `zeroset normals {} -o ORIENTED.ply` estimates them",
                input.display(),
                input.display()
            );
        }
        crate::fit::check_extent(input, &cloud)?;
        let field = TangentPlaneField::new(&cloud, self.neighbours.unwrap_or(TANGENT_NEIGHBOURS))
            .context("building the tangent-plane field (the cloud needs normals)")?;
        let bounds = field.bounds().context("the point cloud has no extent")?;
        let description = format!(
            "point cloud {}: {} points, tangent-plane field over {} neighbours",
            input.display(),
            cloud.len(),
            field.k()
        );
        let grid = zeroset_restore::sampling_grid(bounds)?;
        Ok(Loaded {
            field: Box::new(field),
            grid,
            description,
            points: Some(cloud.into_parts().0),
            own_grid: false,
        })
    }
}

/// The samples a point cloud's tangent-plane field averages by default (`--neighbours`).
pub const TANGENT_NEIGHBOURS: usize = 8;

pub use zeroset_field_core::grid::cubic_counts;

pub(crate) fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

pub(crate) fn parse_triple<T: std::str::FromStr>(s: &str, what: &str) -> Result<[T; 3], String>
where
    T::Err: std::fmt::Display,
{
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "{what} needs three comma-separated numbers, got {s:?}"
        ));
    }
    let mut out = Vec::with_capacity(3);
    for p in parts {
        out.push(p.parse::<T>().map_err(|e| format!("{what}: {p:?}: {e}"))?);
    }
    out.try_into().map_err(|_| "three values".to_string())
}

fn parse_mask(s: &str) -> Result<[[f64; 3]; 2], String> {
    let Some((a, b)) = s.split_once(':') else {
        return Err(format!(
            "the mask is two corners x0,y0,z0:x1,y1,z1, got {s:?}"
        ));
    };
    let a: Point<3> = parse_triple(a, "mask corner")?;
    let b: Point<3> = parse_triple(b, "mask corner")?;
    if a.iter().chain(&b).any(|v| !v.is_finite()) {
        return Err("mask corners must be finite".into());
    }
    Ok([a, b])
}

pub(crate) fn parse_counts(s: &str) -> Result<[usize; 3], String> {
    let c: [usize; 3] = parse_triple(s, "counts")?;
    if c.contains(&0) {
        return Err(format!("counts must be positive, got {s:?}"));
    }
    Ok(c)
}

fn parse_face(s: &str) -> Result<Face, String> {
    s.parse()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_masks_faces_and_counts() {
        assert_eq!(
            parse_mask("0,1,2:3,4.5,-6").unwrap(),
            [[0.0, 1.0, 2.0], [3.0, 4.5, -6.0]]
        );
        assert!(parse_mask("0,1:3,4,5").is_err());
        assert!(parse_mask("0,1,2").is_err());
        assert!(parse_mask("0,1,nan:1,2,3").is_err());
        assert_eq!(
            parse_face("-z").unwrap(),
            Face::new(2, zeroset_field_core::mask::Side::Lower)
        );
        assert_eq!(
            parse_face("+x").unwrap(),
            Face::new(0, zeroset_field_core::mask::Side::Upper)
        );
        assert!(parse_face("z").is_err());
        assert!(parse_face("+w").is_err());
        assert_eq!(parse_counts("4,5,6").unwrap(), [4, 5, 6]);
        assert!(parse_counts("4,0,6").is_err());
    }
}
