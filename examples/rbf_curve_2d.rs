//! Thin-plate interpolation of a closed curve, and adding constraints one at a time by block
//! inversion: Jiang–Turk (paper 003) §1–2 and §4.1, Figs. 1 and 2.
//!
//! ```text
//! cargo run --release --example rbf_curve_2d [-- --out DIR]
//! ```
//!
//! `--out DIR` (default `target/rbf_curve_2d`, created if needed) receives `curve_fit.svg`
//! (Fig. 1) and `curve_incremental.svg` (Fig. 2).
//!
//! ## Set-up (the "neural curve" set-up of `PEERS.md`)
//!
//! The curve is `r(t) = 0.6 + 0.15 cos 3t` in polar coordinates (a rounded trefoil, diameter
//! about 1.3). Constraints: 30 on-curve points at `t = 2πk/30` (value 0), 15 inside points at
//! `0.5 r(t)` and 15 outside points at `1.4 r(t)`, both at `t = 2πj/15`. The field is the
//! thin-plate interpolant `s(x) = Σ wᵢ φ(|x − xᵢ|) + c₀ + c·x`, `φ(r) = r² ln r` (003 Eq. 3,
//! solved densely), and the curve its zero set, traced by marching squares on a 257 × 257
//! vertex grid over `[−1.2, 1.2]²`.
//!
//! **Sign convention.** zeroset's fields are negative inside. The paper takes `+1` inside and
//! `−1` outside; here the **inside points take −1 and the outside points +1**, so the fitted
//! field is negative inside the curve (checked at the origin) and marching squares runs the loop
//! counter-clockwise (positive signed area).
//!
//! ## What is done and reported
//!
//! 1. **Fig. 1**: fit all 60 constraints. Reported: the largest constraint residual, the fit
//!    time, the number of closed loops and open pieces (must be one loop and nothing else), the
//!    enclosed area against the true `½∫r² dt`, and a Hausdorff-like distance to the true curve
//!    (sampled at 8,192 points): the largest distance from a contour vertex to the true curve
//!    and from a true-curve sample to the contour (point-to-segment distances), as fractions
//!    of the curve's diameter.
//! 2. **Fig. 2**: fit a coarse subset (12 on-curve, 4 inside, 4 outside points), then add the
//!    other 40 one at a time (ordered by angle) with [`IncrementalFit::add`], each a batch of
//!    one, timing each addition; after each, a full dense re-fit of the same constraints (same
//!    order) is timed and both fields are compared over the grid: `max |s_inc − s_full| /
//!    max |s_full|`, which must be ≤ 1e-8. Then the last 3 are removed again with
//!    [`IncrementalFit::remove_last`] and compared with the full fit of what is left.
//!
//! Timings are wall-clock, the best of 3 runs (an addition is timed, removed and added again),
//! in µs; on a busy machine small ones are still noisy. The run fails
//! (exit status 1, after writing the images) if a check fails; any other error is printed and
//! also exits with 1.
//!
//! Tests (a coarser grid): `cargo test --release --example rbf_curve_2d`.

use std::error::Error;
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use zeroset::bases::rbf::{
    Constraints, FitReport, IncrementalFit, RbfField, RbfFit, Solver, ThinPlate,
};
use zeroset::core::Aabb;
use zeroset::core::field::ScalarField;
use zeroset::core::geometry::{Point2, distance};
use zeroset::core::grid::Grid;
use zeroset::mesh::squares::{Contour, Polyline, contour_field, marching_squares};
use zeroset::mesh::svg::SvgPlot;

#[path = "common/curve.rs"]
mod curve;

use curve::{
    INSIDE, INSIDE_SCALE, Kind, ON_CURVE, OUTSIDE, OUTSIDE_SCALE, Site, curve_point, sites,
    true_area,
};

type BoxError = Box<dyn Error>;

const USAGE: &str = "usage: rbf_curve_2d [--out DIR]   (default DIR: target/rbf_curve_2d)";

/// The points of each kind in the coarse set of Fig. 2.
const COARSE: [usize; 3] = [12, 4, 4];
/// The grid: `GRID_N × GRID_N` vertices over `[−HALF, HALF]²`.
const GRID_N: usize = 257;
const HALF: f64 = 1.2;
/// Samples of the true curve for the distances.
const TRUE_SAMPLES: usize = 8192;
/// The largest allowed relative difference between incremental and full fits.
const TOLERANCE: f64 = 1e-8;
/// How many additions are removed again.
const REMOVE: usize = 3;
/// Each timing is the best of this many runs.
const REPEAT: usize = 3;

fn colour(kind: Kind) -> &'static str {
    match kind {
        Kind::OnCurve => "black",
        Kind::Inside => "#9467bd",
        Kind::Outside => "#ff7f0e",
    }
}

fn constraints(sites: &[Site]) -> Constraints<2> {
    let mut c = Constraints::new();
    for s in sites {
        c.push_value(s.point, s.kind.value());
    }
    c
}

fn points_of(sites: &[Site], kind: Option<Kind>) -> Vec<Point2> {
    sites
        .iter()
        .filter(|s| kind.is_none_or(|k| s.kind == k))
        .map(|s| s.point)
        .collect()
}

fn domain() -> Result<Aabb<2>, BoxError> {
    Ok(Aabb::new([-HALF, -HALF], [HALF, HALF])?)
}

fn grid(n: usize) -> Result<Grid<2>, BoxError> {
    Ok(Grid::vertex_centered(domain()?, [n, n])?)
}

fn dense_fit() -> RbfFit<ThinPlate> {
    RbfFit::new(ThinPlate).with_solver(Solver::Dense)
}

// ---------------------------------------------------------------------------------------------
// Distances between a contour and the true curve.

/// The distance from `p` to the segment `ab`.
fn point_segment_distance(p: &Point2, a: &Point2, b: &Point2) -> f64 {
    let (ab, ap) = ([b[0] - a[0], b[1] - a[1]], [p[0] - a[0], p[1] - a[1]]);
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let s = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    distance(p, &[a[0] + s * ab[0], a[1] + s * ab[1]])
}

/// The distance from `p` to the nearest segment of `lines` (infinite if there is none).
fn distance_to_lines(p: &Point2, lines: &[Polyline]) -> f64 {
    lines
        .iter()
        .flat_map(Polyline::segments)
        .map(|(a, b)| point_segment_distance(p, &a, &b))
        .fold(f64::INFINITY, f64::min)
}

/// The true curve as a closed polyline of `n` samples.
fn true_curve(n: usize) -> Polyline {
    Polyline {
        points: (0..n)
            .map(|k| curve_point(TAU * k as f64 / n as f64, 1.0))
            .collect(),
        closed: true,
    }
}

/// The largest distance between two points of `points`.
fn diameter(points: &[Point2]) -> f64 {
    let mut d: f64 = 0.0;
    for (i, a) in points.iter().enumerate() {
        for b in &points[i + 1..] {
            d = d.max(distance(a, b));
        }
    }
    d
}

/// The two one-sided distances between a contour and the true curve.
#[derive(Debug, Clone, Copy)]
struct CurveDistance {
    /// `max` over contour vertices of the distance to the true curve.
    contour_to_curve: f64,
    /// `max` over true-curve samples of the distance to the contour.
    curve_to_contour: f64,
    /// The true curve's diameter.
    diameter: f64,
}

impl CurveDistance {
    fn of(contour: &Contour) -> Self {
        let truth = true_curve(TRUE_SAMPLES);
        let truth_lines = std::slice::from_ref(&truth);
        let contour_to_curve = contour
            .lines
            .iter()
            .flat_map(|l| &l.points)
            .map(|p| distance_to_lines(p, truth_lines))
            .fold(0.0, f64::max);
        let curve_to_contour = truth
            .points
            .iter()
            .map(|p| distance_to_lines(p, &contour.lines))
            .fold(0.0, f64::max);
        Self {
            contour_to_curve,
            curve_to_contour,
            diameter: diameter(&truth.points),
        }
    }

    /// The larger of the two, as a fraction of the diameter.
    fn hausdorff_fraction(&self) -> f64 {
        self.contour_to_curve.max(self.curve_to_contour) / self.diameter
    }
}

// ---------------------------------------------------------------------------------------------
// Fig. 1.

struct Figure1 {
    report: FitReport,
    fit_time: Duration,
    contour: Contour,
    distance: CurveDistance,
    value_at_origin: f64,
}

fn figure1(sites: &[Site], grid: &Grid<2>) -> Result<Figure1, BoxError> {
    let c = constraints(sites);
    let start = Instant::now();
    let fitted = dense_fit().fit(&c)?;
    let fit_time = start.elapsed();
    let contour = contour_field(&fitted.field, grid, 0.0)?;
    let distance = CurveDistance::of(&contour);
    Ok(Figure1 {
        value_at_origin: fitted.field.value(&[0.0, 0.0]),
        report: fitted.report,
        fit_time,
        contour,
        distance,
    })
}

fn write_figure1(fig: &Figure1, sites: &[Site], path: &Path) -> Result<(), BoxError> {
    let mut plot = SvgPlot::new(domain()?, 800)?;
    plot.title(
        "Fig. 1: fit (blue), true curve (grey); on-curve 0 black, inside -1 purple, outside +1 orange",
    )
    .polylines(&[true_curve(1024)], "#cccccc", 6.0)?
    .polylines(&fig.contour, "#1f77b4", 2.0)?;
    for kind in [Kind::Inside, Kind::Outside, Kind::OnCurve] {
        plot.points(&points_of(sites, Some(kind)), colour(kind), 4.0)?;
    }
    plot.write(path)?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Fig. 2.

/// One row of the incremental table.
struct Step {
    constraints: usize,
    /// The time of `add` (or `remove_last`).
    update: Duration,
    refit: Duration,
    rel_diff: f64,
}

struct Figure2 {
    base: Vec<Site>,
    added: Vec<Site>,
    first: Contour,
    last: Contour,
    additions: Vec<Step>,
    removals: Vec<Step>,
}

impl Figure2 {
    fn max_rel_diff(&self) -> f64 {
        self.additions
            .iter()
            .chain(&self.removals)
            .map(|s| s.rel_diff)
            .fold(0.0, f64::max)
    }
}

/// `count` of `n` indices spread evenly, starting `shift` of a gap past 0.
fn spread(n: usize, count: usize, shift: f64) -> Vec<usize> {
    (0..count)
        .map(|j| ((j as f64 + shift) * n as f64 / count as f64).round() as usize % n)
        .collect()
}

/// Splits the sites into the coarse base set and the rest, the rest ordered by angle (and by
/// kind at equal angles).
fn split_coarse(sites: &[Site]) -> (Vec<Site>, Vec<Site>) {
    let mut base = Vec::new();
    let mut rest = Vec::new();
    for (kind, count, shift) in [
        (Kind::OnCurve, COARSE[0], 0.0),
        (Kind::Inside, COARSE[1], 0.0),
        (Kind::Outside, COARSE[2], 0.5),
    ] {
        let of_kind: Vec<Site> = sites.iter().filter(|s| s.kind == kind).copied().collect();
        let picked = spread(of_kind.len(), count, shift);
        for (i, s) in of_kind.into_iter().enumerate() {
            if picked.contains(&i) {
                base.push(s);
            } else {
                rest.push(s);
            }
        }
    }
    // A stable sort keeps on-curve before inside before outside at equal angles.
    rest.sort_by(|a, b| a.t.total_cmp(&b.t));
    (base, rest)
}

/// `max |a − b| / max |b|`.
fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    let scale = b.iter().map(|y| y.abs()).fold(0.0, f64::max).max(1e-300);
    diff / scale
}

/// Times a full dense fit of `sites` and compares `field` with it on `grid`; returns the fit
/// time, the relative difference and the incremental field's samples.
fn compare_with_refit(
    field: &RbfField<ThinPlate, 2>,
    sites: &[Site],
    grid: &Grid<2>,
) -> Result<(Duration, f64, Vec<f64>), BoxError> {
    let c = constraints(sites);
    let mut refit = Duration::MAX;
    let mut full = None;
    for _ in 0..REPEAT {
        let start = Instant::now();
        let fitted = dense_fit().fit(&c)?;
        refit = refit.min(start.elapsed());
        full = Some(fitted);
    }
    let full = full.ok_or("no re-fit was made")?;
    let incremental = grid.sample(field);
    let reference = grid.sample(&full.field);
    Ok((
        refit,
        relative_difference(&incremental, &reference),
        incremental,
    ))
}

fn figure2(sites: &[Site], grid: &Grid<2>) -> Result<Figure2, BoxError> {
    let (base, added) = split_coarse(sites);
    let fit = dense_fit();
    let mut inc = IncrementalFit::new(&fit, &constraints(&base))?;
    let first = contour_field(&inc.field(), grid, 0.0)?;
    let mut current = base.clone();
    let mut additions = Vec::with_capacity(added.len());
    let mut last_samples = Vec::new();
    for site in &added {
        let batch = constraints(std::slice::from_ref(site));
        // Best of REPEAT: removing the batch again restores the state before the addition.
        let mut update = Duration::MAX;
        for r in 0..REPEAT {
            if r > 0 {
                inc.remove_last();
            }
            let start = Instant::now();
            inc.add(&batch)?;
            update = update.min(start.elapsed());
        }
        current.push(*site);
        let (refit, rel_diff, samples) = compare_with_refit(&inc.field(), &current, grid)?;
        last_samples = samples;
        additions.push(Step {
            constraints: current.len(),
            update,
            refit,
            rel_diff,
        });
    }
    let last = if added.is_empty() {
        first.clone()
    } else {
        marching_squares(grid, &last_samples, 0.0)?
    };
    let mut removals = Vec::with_capacity(REMOVE);
    for _ in 0..REMOVE.min(added.len()) {
        let start = Instant::now();
        let removed = inc.remove_last();
        let update = start.elapsed();
        if removed != Some(1) {
            return Err(format!("remove_last removed {removed:?} functionals, expected 1").into());
        }
        current.pop();
        let (refit, rel_diff, _) = compare_with_refit(&inc.field(), &current, grid)?;
        removals.push(Step {
            constraints: current.len(),
            update,
            refit,
            rel_diff,
        });
    }
    Ok(Figure2 {
        base,
        added,
        first,
        last,
        additions,
        removals,
    })
}

fn write_figure2(fig: &Figure2, path: &Path) -> Result<(), BoxError> {
    let mut plot = SvgPlot::new(domain()?, 800)?;
    plot.title(&format!(
        "Fig. 2: {}-constraint fit (grey), after {} one-at-a-time additions (blue); added ringed green",
        fig.base.len(),
        fig.added.len()
    ))
    .polylines(&fig.first, "#999999", 2.0)?
    .polylines(&fig.last, "#1f77b4", 2.0)?
    .points(&points_of(&fig.added, None), "#2ca02c", 6.5)?;
    for kind in [Kind::Inside, Kind::Outside, Kind::OnCurve] {
        let mut points = points_of(&fig.base, Some(kind));
        points.extend(points_of(&fig.added, Some(kind)));
        plot.points(&points, colour(kind), 3.5)?;
    }
    plot.write(path)?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Driver.

fn micros(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn loops_text(c: &Contour) -> String {
    format!(
        "{} closed loop(s), {} open piece(s)",
        c.num_closed(),
        c.num_open()
    )
}

/// `Ok(None)` for `--help`.
fn parse_args() -> Result<Option<PathBuf>, String> {
    let mut out = PathBuf::from("target/rbf_curve_2d");
    let mut args = std::env::args_os().skip(1);
    while let Some(arg) = args.next() {
        match arg.to_str() {
            Some("--out") => {
                let dir = args
                    .next()
                    .filter(|d| !d.is_empty())
                    .ok_or_else(|| format!("--out needs a directory\n{USAGE}"))?;
                out = dir.into();
            }
            Some("--help" | "-h") => return Ok(None),
            _ => return Err(format!("unknown argument {arg:?}\n{USAGE}")),
        }
    }
    Ok(Some(out))
}

fn run() -> Result<(), BoxError> {
    let Some(out) = parse_args()? else {
        println!("{USAGE}");
        return Ok(());
    };
    std::fs::create_dir_all(&out)
        .map_err(|e| format!("cannot create the output directory {}: {e}", out.display()))?;
    let grid = grid(GRID_N)?;
    let sites = sites();
    let mut failures = Vec::new();

    println!(
        "curve r(t) = 0.6 + 0.15 cos 3t; {ON_CURVE} on-curve (0), {INSIDE} inside at \
         {INSIDE_SCALE} r (-1), {OUTSIDE} outside at {OUTSIDE_SCALE} r (+1); negative inside"
    );
    println!(
        "kernel r^2 ln r (thin plate), dense solve; grid {GRID_N}x{GRID_N} over [-{HALF}, {HALF}]^2\n"
    );

    // Fig. 1.
    let f1 = figure1(&sites, &grid)?;
    let d = &f1.distance;
    let area = f1
        .contour
        .lines
        .iter()
        .map(Polyline::signed_area)
        .sum::<f64>();
    println!("Fig. 1: all {} constraints", sites.len());
    println!("  fit time                {:.0} us", micros(f1.fit_time));
    println!("  max constraint residual {:.2e}", f1.report.max_residual);
    println!(
        "  condition estimate      {:.2e}",
        f1.report.condition_estimate
    );
    for w in &f1.report.warnings {
        println!("  warning: {w}");
    }
    println!(
        "  field at the origin     {:+.4} (negative inside)",
        f1.value_at_origin
    );
    println!(
        "  contour                 {}, {} vertices",
        loops_text(&f1.contour),
        f1.contour.num_points()
    );
    println!(
        "  signed area             {area:.5} (true {:.5}, rel. diff {:.2e})",
        true_area(),
        (area - true_area()).abs() / true_area()
    );
    println!(
        "  contour -> true curve   max {:.3e} = {:.3e} x diameter ({:.4})",
        d.contour_to_curve,
        d.contour_to_curve / d.diameter,
        d.diameter
    );
    println!(
        "  true curve -> contour   max {:.3e} = {:.3e} x diameter",
        d.curve_to_contour,
        d.curve_to_contour / d.diameter
    );
    println!(
        "  Hausdorff-like distance {:.3e} x diameter",
        d.hausdorff_fraction()
    );
    if f1.contour.num_closed() != 1 || f1.contour.num_open() != 0 {
        failures.push(format!(
            "Fig. 1: expected one closed loop, got {}",
            loops_text(&f1.contour)
        ));
    }
    if f1.value_at_origin >= 0.0 {
        failures.push("Fig. 1: the field is not negative at the origin".to_string());
    }
    let fit_svg = out.join("curve_fit.svg");
    write_figure1(&f1, &sites, &fit_svg)?;

    // Fig. 2.
    let f2 = figure2(&sites, &grid)?;
    println!(
        "\nFig. 2: base fit of {} constraints ({} on-curve, {} inside, {} outside): {}",
        f2.base.len(),
        COARSE[0],
        COARSE[1],
        COARSE[2],
        loops_text(&f2.first)
    );
    println!(
        "  adding {} constraints one at a time (batches of 1), ordered by angle",
        f2.added.len()
    );
    println!(
        "  {:>4}  {:>11}  {:>13}  {:>18}  {:>14}",
        "step", "constraints", "add time (us)", "full re-fit (us)", "max rel. diff"
    );
    for (k, s) in f2.additions.iter().enumerate() {
        println!(
            "  {:>4}  {:>11}  {:>13.1}  {:>18.1}  {:>14.2e}",
            k + 1,
            s.constraints,
            micros(s.update),
            micros(s.refit),
            s.rel_diff
        );
    }
    println!("  removing the last {REMOVE} again with remove_last:");
    println!(
        "  {:>4}  {:>11}  {:>13}  {:>18}  {:>14}",
        "step", "constraints", "remove (us)", "full re-fit (us)", "max rel. diff"
    );
    for (k, s) in f2.removals.iter().enumerate() {
        println!(
            "  {:>4}  {:>11}  {:>13.1}  {:>18.1}  {:>14.2e}",
            format!("-{}", k + 1),
            s.constraints,
            micros(s.update),
            micros(s.refit),
            s.rel_diff
        );
    }
    let median = |mut v: Vec<Duration>| {
        v.sort();
        v.get(v.len() / 2).copied().unwrap_or_default()
    };
    let add = median(f2.additions.iter().map(|s| s.update).collect());
    let refit = median(f2.additions.iter().map(|s| s.refit).collect());
    println!(
        "  median add {:.1} us, median full re-fit {:.1} us ({:.1}x); largest rel. diff {:.2e} (limit {TOLERANCE:.0e})",
        micros(add),
        micros(refit),
        refit.as_secs_f64() / add.as_secs_f64().max(1e-12),
        f2.max_rel_diff()
    );
    for (name, c) in [("base", &f2.first), ("final", &f2.last)] {
        let d = CurveDistance::of(c);
        let area = c.lines.iter().map(Polyline::signed_area).sum::<f64>();
        println!(
            "  {name:>5} contour: {}, area {area:.4}, Hausdorff-like distance {:.3e} x diameter",
            loops_text(c),
            d.hausdorff_fraction()
        );
    }
    if f2.max_rel_diff() > TOLERANCE || f2.max_rel_diff().is_nan() {
        failures.push(format!(
            "Fig. 2: incremental and full fits differ by {:.2e} > {TOLERANCE:.0e}",
            f2.max_rel_diff()
        ));
    }
    let inc_svg = out.join("curve_incremental.svg");
    write_figure2(&f2, &inc_svg)?;

    println!("\nwrote {}\nwrote {}", fit_svg.display(), inc_svg.display());
    if failures.is_empty() {
        Ok(())
    } else {
        Err(failures.join("; ").into())
    }
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_is_one_loop_near_the_true_curve() {
        let fig = figure1(&sites(), &grid(129).unwrap()).unwrap();
        assert_eq!((fig.contour.num_closed(), fig.contour.num_open()), (1, 0));
        assert!(fig.report.max_residual < 1e-10, "{:?}", fig.report);
        assert!(fig.value_at_origin < 0.0);
        let area: f64 = fig.contour.lines.iter().map(Polyline::signed_area).sum();
        assert!((area - true_area()).abs() < 0.01 * true_area(), "{area}");
        assert!(
            fig.distance.hausdorff_fraction() < 0.02,
            "{:?}",
            fig.distance
        );
    }

    #[test]
    fn adding_and_removing_matches_a_full_refit() {
        let fig = figure2(&sites(), &grid(33).unwrap()).unwrap();
        assert_eq!(fig.base.len(), COARSE.iter().sum::<usize>());
        assert_eq!(
            fig.base.len() + fig.added.len(),
            ON_CURVE + INSIDE + OUTSIDE
        );
        assert_eq!(fig.additions.len(), fig.added.len());
        assert_eq!(fig.removals.len(), REMOVE);
        assert!(fig.max_rel_diff() <= TOLERANCE, "{}", fig.max_rel_diff());
    }

    #[test]
    fn distances_of_a_circle() {
        // The circle of radius 0.6 is 0.15 from the tips (r = 0.75) and the valleys (r = 0.45)
        // of the true curve, and nearer everywhere else.
        let circle = Polyline {
            points: (0..400)
                .map(|k| {
                    let t = TAU * k as f64 / 400.0;
                    [0.6 * t.cos(), 0.6 * t.sin()]
                })
                .collect(),
            closed: true,
        };
        let d = CurveDistance::of(&Contour {
            lines: vec![circle],
            level: 0.0,
        });
        assert!((d.contour_to_curve - 0.15).abs() < 1e-3, "{d:?}");
        assert!((d.curve_to_contour - 0.15).abs() < 1e-3, "{d:?}");
        // At least the distance between two tips, at most twice the largest radius.
        assert!(d.diameter > 0.75 * 3f64.sqrt() && d.diameter < 1.5, "{d:?}");
    }
}
