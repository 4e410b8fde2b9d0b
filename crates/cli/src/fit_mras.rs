//! `zeroset fit POINTS --method mras`: a multilevel rational algebraic spline (MRAS) field (Pan–Tong–Chen,
//! paper 004; [`zeroset_bases::mras`]).
//!
//! `--tolerance T` is the target largest distance from the points to the surface as a fraction
//! of the cloud's bounding-box diagonal: cells whose points' Sampson distance exceeds it are
//! split, down to `--max-level`. `--lambda` weighs the trace norm that pushes each cell's
//! coefficient tensor to low rank (larger: smaller files, larger errors). A bar per level counts
//! the cells fitted and shows the largest error left by the level before; a table per level
//! follows (cells, CP ranks, numbers stored, error). `-o` writes the `mras` kind of `.zsf` field
//! file (exact), which `zeroset mesh`, `restore`, `preview` and `info` read.

use std::sync::Mutex;
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::Args;

use zeroset_bases::field_file::write_mras_field;
use zeroset_bases::mras::{MAX_LEVEL, MrasOptions, MrasProgress, fit_mras};
use zeroset_field_core::PointCloud3;

use crate::fit::{FitArgs, inward_normals, line, load, more, print_check, print_input};
use crate::info::g;
use crate::progress::counter;

const HEADING: &str = "MRAS (--method mras)";

/// The options of `--method mras` (`--lambda` is shared with `--method neural`).
#[derive(Debug, Args, Default)]
pub struct MrasArgs {
    /// Target largest distance from the points to the surface, as a fraction of the cloud's
    /// bounding-box diagonal [default: 1e-3]. With --method rbf: the largest residual allowed
    /// at any constraint, met by Carr's greedy centre reduction (the field keeps only the
    /// centres it needs).
    #[arg(long, value_name = "T", help_heading = HEADING, allow_hyphen_values = true)]
    pub tolerance: Option<f64>,
    /// The same target as a distance in the cloud's own units (instead of --tolerance).
    #[arg(long, value_name = "D", conflicts_with = "tolerance", help_heading = HEADING,
          allow_hyphen_values = true)]
    pub tolerance_distance: Option<f64>,
    /// The deepest octree level (the root is 1) [default: 8; cells holding 16 points or
    /// fewer are not split, which stops the bunny at level 7].
    #[arg(long, value_name = "L", help_heading = HEADING)]
    pub max_level: Option<u32>,
    /// Keep every cell's full coefficient tensor instead of its CP factors (for comparison).
    #[arg(long, help_heading = HEADING)]
    pub no_compress: bool,
}

impl MrasArgs {
    /// The target as a fraction of the cloud's diagonal (`diagonal`, computed only for
    /// --tolerance-distance), from --tolerance or --tolerance-distance, if either was given.
    ///
    /// # Errors
    /// A distance that is not finite and positive.
    pub fn tolerance_fraction(
        &self,
        diagonal: impl FnOnce() -> f64,
    ) -> anyhow::Result<Option<f64>> {
        let Some(d) = self.tolerance_distance.filter(|_| self.tolerance.is_none()) else {
            return Ok(self.tolerance);
        };
        let diagonal = diagonal();
        match d {
            d if d.is_finite() && d > 0.0 && diagonal > 0.0 => Ok(Some(d / diagonal)),
            d => bail!(
                "--tolerance-distance {d}: give a positive distance in the cloud's units (its \
                 diagonal is {})",
                g(diagonal)
            ),
        }
    }

    /// Refuses a `--tolerance` outside (0, 1) or a `--tolerance-distance` that is not a
    /// positive distance, before any file is read.
    ///
    /// # Errors
    /// The value given, and what it should be.
    pub fn check_tolerance(&self) -> anyhow::Result<()> {
        if let Some(t) = self.tolerance
            && !(t.is_finite() && t > 0.0 && t < 1.0)
        {
            bail!(
                "--tolerance {t}: give a fraction of the diagonal, between 0 and 1 (or \
                 --tolerance-distance in the cloud's units)"
            );
        }
        if let Some(d) = self.tolerance_distance
            && !(d.is_finite() && d > 0.0)
        {
            bail!("--tolerance-distance {d}: give a positive distance in the cloud's units");
        }
        Ok(())
    }

    /// As [`MrasArgs::given`], leaving out `--tolerance` and `--tolerance-distance` (which
    /// --method rbf takes too).
    pub fn given_besides_tolerance(&self) -> Option<&'static str> {
        [
            (self.max_level.is_some(), "--max-level"),
            (self.no_compress, "--no-compress"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
    }

    /// The first option given, as its flag, if any (for refusing them with other methods).
    pub fn given(&self) -> Option<&'static str> {
        [
            (self.tolerance.is_some(), "--tolerance"),
            (self.tolerance_distance.is_some(), "--tolerance-distance"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
        .or_else(|| self.given_besides_tolerance())
    }
}

/// Refuses the options of the other methods; checks -o.
fn check_request(args: &FitArgs) -> anyhow::Result<MrasOptions> {
    let other = args
        .rbf_flag_given()
        .or(args.offset.is_some().then_some("--offset"));
    if let Some(flag) = other {
        bail!("{flag} is not an option of --method mras");
    }
    if let Some(flag) = args.neural.given_besides_lambda() {
        bail!("{flag} is an option of --method neural, not of --method mras");
    }
    if let Some(output) = &args.output {
        crate::output::check_output(output, &[&args.points], args.force, &["zsf"])?;
    }
    args.outliers
        .check(&args.points, args.output.as_deref(), args.force)?;
    let mut o = MrasOptions::default();
    if let Some(t) = args.mras.tolerance {
        o.tolerance = t;
    }
    if let Some(l) = args.mras.max_level {
        o.max_level = l;
    }
    if let Some(l) = args.neural.lambda {
        o.lambda = l;
    }
    o.outlier_ratio = args.outliers.ratio()?;
    o.compress = !args.mras.no_compress;
    // Refused before the points are read, which can take a while.
    args.mras.check_tolerance()?;
    if !(1..=MAX_LEVEL).contains(&o.max_level) {
        bail!(
            "--max-level {}: give a level from 1 (the root) to {MAX_LEVEL}",
            o.max_level
        );
    }
    if !(o.lambda.is_finite() && o.lambda >= 0.0) {
        bail!(
            "--lambda {}: give a finite weight, 0 or more (0: no trace norm)",
            o.lambda
        );
    }
    o.validate().context("the MRAS options")?;
    Ok(o)
}

/// Runs `zeroset fit --method mras`.
pub fn run(args: &FitArgs) -> anyhow::Result<()> {
    let options = check_request(args)?;
    let start = Instant::now();
    let cloud = load(args)?;
    print_input(args, &cloud);
    inward_normals(&cloud);
    let normals = cloud.normals().context("the cloud has no normals")?;
    let mut options = options;
    let diagonal = || cloud.bounds().map_or(0.0, |b| b.diagonal());
    if let Some(t) = args.mras.tolerance_fraction(diagonal)? {
        options.tolerance = t;
    }
    line(
        "MRAS",
        &format!(
            "tolerance {} of the diagonal, up to {} levels, λ = {}, {}",
            g(options.tolerance),
            options.max_level,
            g(options.lambda),
            if options.compress {
                "CP factors"
            } else {
                "full tensors (--no-compress)"
            }
        ),
    );
    let bar = Mutex::new(((0u32, false), counter(args.quiet, 1, "level 1")));
    let progress = |p: &MrasProgress| {
        let mut b = bar.lock().unwrap_or_else(|e| e.into_inner());
        if b.0 != (p.level, p.compressing) {
            b.1.finish_and_clear();
            let stage = if p.compressing {
                "compressing"
            } else {
                "fitting"
            };
            let message = match p.error {
                Some(e) => format!("level {} {stage} (max error {})", p.level, g(e)),
                None => format!("level {} {stage}", p.level),
            };
            b.1 = counter(args.quiet, p.cells_total, "");
            b.1.set_message(message);
            b.0 = (p.level, p.compressing);
        }
        b.1.set_position(p.cells_done as u64);
        true
    };
    let fit = fit_mras(cloud.positions(), normals, &options, &progress);
    bar.lock()
        .unwrap_or_else(|e| e.into_inner())
        .1
        .finish_and_clear();
    let fit = fit.context("fitting the MRAS field")?;
    if fit.duplicates > 0 {
        line(
            "duplicates",
            &format!("{} exact duplicate positions merged", fit.duplicates),
        );
    }
    if fit.touching > 0 {
        more(&format!(
            "(at {} of the places repeated, normals pointing apart meet as two sheets: a mesh \
             touching itself, two solids touching, a crease's split normals; each fitted with \
             value 0 and the mean of the two normals as the gradient, and not measured in the \
             errors below: no smooth field follows two sheets into the place where they touch)",
            fit.touching
        ));
    }
    args.outliers.report(
        &cloud,
        &fit.outliers,
        fit.kept_sparse,
        options.outlier_ratio,
    )?;
    line(
        "levels",
        "level  m  cells  ranks min/mean/max  stored  uncompressed  max error  mean error  split",
    );
    for l in &fit.levels {
        more(&format!(
            "{:5} {:2} {:6}  {:>18}  {:6}  {:12}  {:9}  {:10}  {:5}{}",
            l.level,
            l.knots,
            l.cells,
            if l.full_cells > 0 && l.ranks.2 == 0 {
                // Every stored cell is a full tensor: no rank to show (0 reads as "not stored").
                "full".to_owned()
            } else {
                format!("{}/{:.1}/{}", l.ranks.0, l.ranks.1, l.ranks.2)
            },
            l.stored,
            l.uncompressed,
            g(l.max_error),
            g(l.mean_error),
            l.split,
            [
                (l.full_cells, "stored full"),
                (l.dropped, "φ = 0, not stored")
            ]
            .iter()
            .filter(|(n, _)| *n > 0)
            .map(|(n, what)| format!("  ({n} cells {what})"))
            .collect::<String>()
        ));
    }
    let field = &fit.field;
    let uncompressed: usize = fit.levels.iter().map(|l| l.uncompressed).sum();
    line(
        "storage",
        &format!(
            "{} numbers ({:.1}× fewer than the {} of the fitted cells uncompressed)",
            field.storage(),
            uncompressed as f64 / field.storage().max(1) as f64,
            uncompressed
        ),
    );
    line("tolerance", &tolerance_summary(&fit, &options));
    if !fit.tolerance_met()
        && let Some(hint) = scatter_hint(&cloud, &fit)
    {
        more(&hint);
    }
    // A few flat points are saddles of a noisy scan's field (17 of the 34,786 of a bunny with
    // noise at 0.5% of the diagonal); over 1% is a field that misses the surface.
    let fitted = fit.fitted_points;
    if fit.flat_points * 100 > fitted {
        line(
            "warning",
            &format!(
                "the field is nearly flat (|∇f| < {}, where a fit has about 1) at {} of the {} \
                 fitted points: its surface need not pass near them, whatever their distance \
                 above says. Levels too coarse for them (--max-level {}) or a trace norm that \
                 shrank the offsets (λ = {}, --lambda) leave a field this flat",
                g(zeroset_bases::mras::FLAT_GRADIENT),
                fit.flat_points,
                fitted,
                options.max_level,
                g(options.lambda)
            ),
        );
    }
    line("time", &format!("{:.2} s", fit.seconds));
    print_check(field, &cloud, &fit.outliers);
    if let Some(output) = &args.output {
        line(
            "output",
            &format!("{}: the MRAS field (exact)", output.display()),
        );
        write_mras_field(output, field).with_context(|| format!("writing {}", output.display()))?;
        outln!(
            "wrote {} (the MRAS field) in {:.2} s",
            output.display(),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Where the fit missed its tolerance on a noisy cloud: the scatter the cloud has about its
/// surface ([`zeroset_bases::noise`], measured on the points fitted), when the cloud is noisy
/// (as `zeroset info` says: `σ̂` above [`zeroset_bases::noise::NOISY_SCATTER`] of the spacing;
/// on a sparse clean cloud `σ̂` measures curvature, `bunny_2k.xyzn`'s 1.1e-3 of the diagonal at
/// 0.05 of its spacing) and the points' spread about it (`3σ̂`) exceeds the tolerance. The distances are then mostly the noise, and
/// finer levels would follow it: on the bunny with Gaussian noise of 0.5% of the diagonal per
/// axis (`σ̂` 0.39%), the default tolerance of 1e-3 gave the mesh closest to the clean scan
/// (median distance 0.92e-3 of the diagonal; 1.18e-3 at `--tolerance 0.005`, 2.11e-3 at 0.01),
/// so the hint explains the miss and does not ask for a looser tolerance — except where the
/// surface comes out in bubbles: CGAL's `sphere_20k_normal.xyz` (21,000 points of a unit
/// sphere, radial noise σ 0.041 = 1.1% of the diagonal, about 1.6 spacings, and noisy normals;
/// `σ̂` 0.61%) gave 48 components at the default, the mesh's vertices 4.3e-3 of the diagonal
/// from the true sphere (median); at `--tolerance` 1σ̂ 4 components, 2.1e-3; 1.5σ̂ one, 1.4e-3;
/// 2.5σ̂ one, 0.98e-3 (the bunny at 0.5%: 0.93e-3 at the default, 1.06e-3 at 1σ̂, 1.26e-3 at
/// 1.5σ̂, 2.0e-3 at 2.5σ̂, one component each; 2026-12-07, `fit` + `mesh`, 2 threads). So the
/// hint names 2σ̂ for that case. Where two parallel
/// sheets explain the scatter ([`zeroset_bases::noise::Noise::two_sheets_explain`]: a thin
/// wall, not noise), the hint says that instead.
fn scatter_hint(cloud: &PointCloud3, fit: &zeroset_bases::mras::MrasFit) -> Option<String> {
    let normals = cloud.normals()?;
    let set_aside: std::collections::HashSet<usize> = fit.outliers.iter().copied().collect();
    let (positions, normals): (Vec<_>, Vec<_>) = cloud
        .positions()
        .iter()
        .zip(normals)
        .enumerate()
        .filter(|(i, _)| !set_aside.contains(i))
        .map(|(_, (p, n))| (*p, *n))
        .unzip();
    let noise = zeroset_bases::noise::estimate_noise(&positions, Some(&normals))?;
    let sigma = noise.sigma / fit.diagonal;
    if noise.two_sheets_explain() && 3.0 * sigma > fit.tolerance {
        return Some(format!(
            "{:.0}% of the points' patches lie on two parallel sheets closer than their spacing \
             (clean about them: σ ≈ {} of the spacing), so no smooth surface passes within {} of \
             the diagonal of every one: a wall thinner than the sampling, which the fit fuses, \
             thickens or breaks (where the normals were estimated, they cannot tell the wall's \
             faces apart: give the scan its own, or sample the wall more densely), or scans of \
             one surface out of register, which it averages; the distances above are that, not \
             noise",
            100.0 * noise.two_sheet_share(),
            g(noise.sigma_within_sheets / noise.spacing),
            g(fit.tolerance)
        ));
    }
    (noise.is_noisy() && 3.0 * sigma > fit.tolerance).then(|| {
        format!(
            "the points scatter about their surface by σ ≈ {} of the diagonal ({:.3} of their \
             spacing; zeroset info measures it), so no smooth surface passes within {} of every \
             one: the fit averages them, and the distances above are mostly that scatter (a \
             smaller --tolerance or a larger --max-level would follow the noise, not the \
             surface; if the mesh comes out in bubbles, the finest levels followed it: \
             --tolerance {:.1e}, about 2σ, smooths them)",
            g(sigma),
            noise.relative(),
            g(fit.tolerance),
            2.0 * sigma
        )
    })
}

/// Whether the fit met its tolerance, and if not, what stopped the subdivision short of it.
fn tolerance_summary(fit: &zeroset_bases::mras::MrasFit, options: &MrasOptions) -> String {
    if fit.tolerance_met() {
        return format!(
            "met: every point's Sampson distance within {} of the diagonal",
            g(fit.tolerance)
        );
    }
    let over = fit.points_over_tolerance;
    // The cap is the reason a user can act on; without it, N_min stopped every split.
    let stops = format!(
        "the subdivision stops at cells of {} points or fewer (too few to fit an offset to) \
         and at cells whose points were within the tolerance when their level was fitted",
        options.n_min
    );
    let why = if fit.capped_cells > 0 {
        format!(
            "{} cell(s) at the level cap would split further (--max-level {}); elsewhere {stops}",
            fit.capped_cells, options.max_level
        )
    } else {
        stops
    };
    format!(
        "not met: {over} point{} farther than {} of the diagonal (largest {}); {}",
        if over == 1 { "" } else { "s" },
        g(fit.tolerance),
        g(fit.max_error()),
        why
    )
}
