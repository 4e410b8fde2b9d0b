//! Fits RBF fields to real data — two scanned surfaces and two GemPy geology models — and
//! reports how the fits went and how well they predict data they were not given.
//!
//! ```text
//! cargo run --release --example rbf_real_data [-- --data DIR --csv FILE]
//! ```
//!
//! `--data DIR` is the data folder described by its `README.md` (default `$ZEROSET_DATA`, else
//! the repository's `data/`); `--csv FILE` also
//! writes every reported number as `section,dataset,method,quantity,value` rows. A missing
//! folder or file, or a fit that fails, prints the error and exits with status 1.
//!
//! ## 1. Surface fits (`bunny_2k.xyzn`, 2,000 points; `kitten.xyz`, 5,210 points)
//!
//! Each cloud is fitted two ways:
//! - **off-surface, r**: value 0 at every point and `±εᵢ` at `pᵢ ± εᵢ nᵢ` (Carr et al.),
//!   `Offset::Auto { fraction: 0.01 }` (εᵢ starts at 1% of the box diagonal and is halved until
//!   the offset point's nearest input point is its own); kernel `r` (biharmonic), `3N` values,
//!   `Solver::Auto` (GMRES in the cardinal basis above 2,000 functionals). The offset report:
//!   `eps0` the starting ε, `eps_min` the smallest used, `shrunk` offset points moved closer
//!   (of `2N`), `dropped` offset points left out.
//! - **Hermite, r3**: value 0 and gradient = unit normal at every point; kernel `r³`
//!   (triharmonic), `4N` functionals, `Solver::Dense` (projected Cholesky).
//!
//! Columns: `constr` constraints (a gradient counts 1), `unknowns` (functionals + 4
//! polynomial terms), `build_s` time to make the constraints, `fit_s` the fit's own time
//! (`FitReport::elapsed`), `solver`, `iters` (GMRES steps; 0 for a dense solve), `max_resid`
//! the largest constraint residual `|Lᵢf − tᵢ|` (values in the cloud's units, gradients as
//! unit normals), `cond` the dense solve's condition estimate (a lower bound; `n/a` for GMRES),
//! and any warnings below.
//!
//! ## 2. Held-out accuracy (bunny)
//!
//! `bunny_2k.xyzn` is a subset of `bunny_points.ply` (34,834 points) printed with 7
//! significant digits, so its points are matched to the PLY's by nearest neighbour within
//! `1e-6 ×` the PLY's box diagonal (exact coordinate matches are counted too). The PLY points
//! not matched are held out. At each held-out point `p`, `d(p) = |f(p)| / |∇f(p)|` (Sampson
//! distance, first-order distance to the zero set); `<1%` is the fraction with
//! `d < 0.01 × diagonal`, `median`, `p95` and `max` are `d / diagonal`.
//!
//! ## 3. Geology (`geology/perth_basin`, `geology/greenstone`)
//!
//! Every formation gets a level `0, 1, 2, …` and its surface points get that value; every
//! orientation becomes a gradient constraint. Coordinates (metres, ~1e5–1e6) are centred on
//! the data's box and divided by its largest extent, so they lie in `[-0.5, 0.5]³` (the kernel
//! is translation invariant, but large coordinates ruin the conditioning). Levels:
//! - greenstone: the explicit order of `Greenstone_surface_points.csv` (GemPy's `id` column,
//!   1 = youngest); level 0 = oldest, so `f` increases upwards, as GemPy's gradients point.
//! - perth_basin: the files hold no order, so, as stated in the output, the order of first
//!   appearance in the surface-points file (level 0 = first). That order mixes layers and
//!   faults and is not stratigraphic; a second run, `perth_basin layers`, takes only the five
//!   layers in the order GemPy's example script uses (youngest to oldest Cretaceous,
//!   Yarragadee, Eneabba, Lesueur, Permian — quoted in the data README, not in the CSV files).
//!
//! Gradient magnitude: the orientation's unit normal (the reader already multiplies by the
//! polarity) times `g`, an estimate of (level spacing)/(typical formation thickness): the
//! median `|∇f|` at the orientation points of a values-only `r³` fit to the same surface
//! points (so the gradients agree in size with what the levels imply); `L / diagonal` with
//! `L` formations if that median is not finite and positive. Kernel `r³`, `Solver::Dense`.
//!
//! Reported: the fit's constraint count, `max_resid` (levels and gradients in unit-box
//! coordinates) and condition estimate; the orientations reproduced — how many have
//! `cos(∇f, n) > 0.999999`, the smallest cosine and the range of `|∇f|/g` (1 up to rounding,
//! since every orientation is a constraint and none is held out); and a hold-out test: every 5th
//! surface point of each formation in file order (its 5th, 10th, … point) is left out, the
//! field refitted, and per formation `held` (count), `mean_err` and `max_err`, the mean and
//! largest `|f(p) − level|` of its held-out points in units of the level spacing (1). `ordered`
//! is the fraction of pairs of held-out points from different formations whose values are in
//! the order of their levels.

use std::collections::HashMap;
use std::error::Error;
use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use rayon::prelude::*;
use zeroset::bases::rbf::{
    Biharmonic, Constraints, FitReport, Fitted, Offset, OffsetReport, RbfFit, Solver, Triharmonic,
};
use zeroset::core::field::ScalarField;
use zeroset::core::geometry::{dot, norm};
use zeroset::core::io::{gempy, read_point_cloud};
use zeroset::core::{Aabb, Point3, PointCloud3};

#[path = "common/data.rs"]
mod data;

type Res<T> = Result<T, Box<dyn Error>>;

const USAGE: &str = "usage: rbf_real_data [--data DIR] [--csv FILE]";

struct Args {
    data: PathBuf,
    csv: Option<PathBuf>,
}

fn parse_args() -> Res<Args> {
    let mut data = None;
    let mut csv = None;
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value\n{USAGE}"));
        match flag.as_str() {
            "--data" => data = Some(PathBuf::from(value()?)),
            "--csv" => csv = Some(PathBuf::from(value()?)),
            "--help" | "-h" => return Err(USAGE.into()),
            other => return Err(format!("unknown argument {other}\n{USAGE}").into()),
        }
    }
    let data = data.unwrap_or_else(data::data_dir);
    if !data.is_dir() {
        return Err(format!(
            "data folder {} not found: pass --data DIR (the folder with bunny_2k.xyzn, \
             bunny_points.ply, kitten.xyz and geology/)",
            data.display()
        )
        .into());
    }
    Ok(Args { data, csv })
}

/// `section,dataset,method,quantity,value` rows for `--csv`.
#[derive(Default)]
struct Csv(Vec<String>);

impl Csv {
    fn add(&mut self, section: &str, dataset: &str, method: &str, quantity: &str, v: impl Display) {
        self.0
            .push(format!("{section},{dataset},{method},{quantity},{v}"));
    }

    fn write(&self, path: &Path) -> Res<()> {
        let mut text = String::from("section,dataset,method,quantity,value\n");
        for row in &self.0 {
            text.push_str(row);
            text.push('\n');
        }
        std::fs::write(path, text)
            .map_err(|e| format!("cannot write --csv {}: {e}", path.display()))?;
        Ok(())
    }
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}

fn run() -> Res<()> {
    let start = Instant::now();
    let args = parse_args()?;
    let mut csv = Csv::default();
    println!(
        "rbf_real_data: data from {} ({} threads)",
        args.data.display(),
        rayon::current_num_threads()
    );

    let bunny = read_cloud(&args.data.join("bunny_2k.xyzn"))?;
    let kitten = read_cloud(&args.data.join("kitten.xyz"))?;
    let full = read_cloud(&args.data.join("bunny_points.ply"))?;

    println!("\n1. Surface fits");
    print_surface_header();
    let mut bunny_fits = Vec::new();
    for (name, cloud) in [("bunny_2k", &bunny), ("kitten", &kitten)] {
        let off = fit_off_surface(name, cloud)?;
        print_surface_row(&off, &mut csv);
        let hermite = fit_hermite(name, cloud)?;
        print_surface_row(&hermite, &mut csv);
        if name == "bunny_2k" {
            bunny_fits.push(off);
            bunny_fits.push(hermite);
        } // the kitten's fields (the Hermite one holds ~20,000 centres) are dropped here
    }
    println!(
        "  max_resid: largest |L_i f - t_i| (values in the cloud's units; gradients vs unit \
         normals); cond: lower bound from the dense factor (n/a for GMRES)"
    );

    println!("\n2. Held-out accuracy: bunny_points.ply points not in bunny_2k.xyzn");
    held_out_bunny(&bunny, &full, &bunny_fits, &mut csv)?;
    drop(bunny_fits);

    println!("\n3. Geology (kernel r3, dense; coordinates centred and scaled to the unit box)");
    for set in geology_sets(&args.data)? {
        geology(&set, &mut csv)?;
    }

    if let Some(path) = &args.csv {
        csv.write(path)?;
        println!("\nwrote {} rows to {}", csv.0.len(), path.display());
    }
    println!("\ntotal run time {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

fn read_cloud(path: &Path) -> Res<PointCloud3> {
    let cloud = read_point_cloud(path)?;
    if cloud.normals().is_none() {
        return Err(format!("{} has no normals", path.display()).into());
    }
    Ok(cloud)
}

// ---------------------------------------------------------------------------------------------
// 1. Surface fits

/// A fitted surface and what it took.
struct SurfaceFit {
    dataset: &'static str,
    method: &'static str,
    kernel: &'static str,
    build: Duration,
    points: usize,
    offset: Option<OffsetReport>,
    diagonal: f64,
    report: FitReport,
    field: Box<dyn ScalarField<3>>,
}

fn fit_off_surface(dataset: &'static str, cloud: &PointCloud3) -> Res<SurfaceFit> {
    let t = Instant::now();
    let (c, offset) = Constraints::off_surface(cloud, Offset::Auto { fraction: 0.01 })
        .map_err(|e| format!("{dataset}: off-surface constraints: {e}"))?;
    let build = t.elapsed();
    let Fitted { field, report } = RbfFit::new(Biharmonic)
        .with_solver(Solver::Auto)
        .fit(&c)
        .map_err(|e| format!("{dataset}: off-surface fit (r): {e}"))?;
    Ok(SurfaceFit {
        dataset,
        method: "off-surface",
        kernel: "r",
        build,
        points: cloud.len(),
        offset: Some(offset),
        diagonal: diagonal_of(cloud),
        report,
        field: Box::new(field),
    })
}

fn fit_hermite(dataset: &'static str, cloud: &PointCloud3) -> Res<SurfaceFit> {
    let t = Instant::now();
    let c =
        Constraints::hermite(cloud).map_err(|e| format!("{dataset}: Hermite constraints: {e}"))?;
    let build = t.elapsed();
    let Fitted { field, report } = RbfFit::new(Triharmonic)
        .with_solver(Solver::Dense)
        .fit(&c)
        .map_err(|e| format!("{dataset}: Hermite fit (r3): {e}"))?;
    Ok(SurfaceFit {
        dataset,
        method: "hermite",
        kernel: "r3",
        build,
        points: cloud.len(),
        offset: None,
        diagonal: diagonal_of(cloud),
        report,
        field: Box::new(field),
    })
}

fn diagonal_of(cloud: &PointCloud3) -> f64 {
    cloud.bounds().map_or(0.0, |b| b.diagonal())
}

fn print_surface_header() {
    println!(
        "{:<9} {:>6} {:<12} {:<3} {:>7} {:>8} {:>8} {:>7} {:<20} {:>5} {:>10} {:>8}",
        "dataset",
        "points",
        "method",
        "ker",
        "constr",
        "unknowns",
        "build_s",
        "fit_s",
        "solver",
        "iters",
        "max_resid",
        "cond"
    );
}

fn print_surface_row(f: &SurfaceFit, csv: &mut Csv) {
    let r = &f.report;
    let points = f.points;
    let cond = if r.condition_estimate.is_nan() {
        "n/a".to_string()
    } else {
        format!("{:.1e}", r.condition_estimate)
    };
    println!(
        "{:<9} {:>6} {:<12} {:<3} {:>7} {:>8} {:>8.3} {:>7.2} {:<20} {:>5} {:>10.2e} {:>8}",
        f.dataset,
        points,
        f.method,
        f.kernel,
        r.constraints,
        r.unknowns,
        f.build.as_secs_f64(),
        r.elapsed.as_secs_f64(),
        r.solver,
        r.iterations,
        r.max_residual,
        cond
    );
    let (d, m) = (f.dataset, f.method);
    csv.add("surface", d, m, "kernel", f.kernel);
    csv.add("surface", d, m, "points", points);
    csv.add("surface", d, m, "constraints", r.constraints);
    csv.add("surface", d, m, "unknowns", r.unknowns);
    csv.add("surface", d, m, "build_s", f.build.as_secs_f64());
    csv.add("surface", d, m, "fit_s", r.elapsed.as_secs_f64());
    csv.add("surface", d, m, "solver", r.solver);
    csv.add("surface", d, m, "iterations", r.iterations);
    csv.add("surface", d, m, "max_residual", r.max_residual);
    csv.add("surface", d, m, "condition_estimate", r.condition_estimate);
    csv.add("surface", d, m, "warnings", r.warnings.len());
    if let Some(o) = &f.offset {
        let line = format!(
            "          offsets: eps0 {:.3e} ({:.2}% of diag), eps_min {:.3e} ({:.3}% of diag), \
             shrunk {} of {}, dropped {}",
            o.initial,
            100.0 * o.initial / f.diagonal,
            o.smallest,
            100.0 * o.smallest / f.diagonal,
            o.shrunk,
            2 * points,
            o.dropped
        );
        println!("{line}");
        csv.add("surface", d, m, "offset_initial", o.initial);
        csv.add("surface", d, m, "offset_smallest", o.smallest);
        csv.add("surface", d, m, "offset_shrunk", o.shrunk);
        csv.add("surface", d, m, "offset_dropped", o.dropped);
    }
    for w in &r.warnings {
        println!("          warning: {w}");
    }
}

// ---------------------------------------------------------------------------------------------
// 2. Held-out bunny

fn held_out_bunny(
    subset: &PointCloud3,
    full: &PointCloud3,
    fits: &[SurfaceFit],
    csv: &mut Csv,
) -> Res<()> {
    let diag = diagonal_of(full);
    let tol = 1e-6 * diag;
    let pts = full.positions();
    // Nearest PLY point of every subset point, by brute force (2,000 × 34,834).
    let nearest: Vec<(usize, f64)> = subset
        .positions()
        .par_iter()
        .map(|p| {
            pts.iter().enumerate().map(|(j, q)| (j, dist2(p, q))).fold(
                (usize::MAX, f64::INFINITY),
                |b, c| if c.1 < b.1 { c } else { b },
            )
        })
        .collect();
    let exact = subset
        .positions()
        .iter()
        .zip(&nearest)
        .filter(|(p, (j, _))| pts[*j] == **p)
        .count();
    let mut in_subset = vec![false; pts.len()];
    let (mut matched, mut collisions) = (0, 0);
    let mut max_d = 0.0f64;
    for &(j, d2) in &nearest {
        let d = d2.sqrt();
        if d <= tol {
            matched += 1;
            max_d = max_d.max(d);
            if in_subset[j] {
                collisions += 1;
            }
            in_subset[j] = true;
        }
    }
    let held: Vec<Point3> = pts
        .iter()
        .zip(&in_subset)
        .filter(|(_, s)| !**s)
        .map(|(p, _)| *p)
        .collect();
    println!(
        "  bunny_points.ply: {} points, box diagonal {diag:.6}; bunny_2k.xyzn is printed with 7 \
         significant digits, so exact coordinate matches: {exact} of {}",
        pts.len(),
        subset.len()
    );
    println!(
        "  matched by nearest neighbour within 1e-6 x diagonal ({tol:.2e}): {matched} of {} \
         (largest distance {:.2e} x diagonal; {collisions} PLY points matched twice); held out: {}",
        subset.len(),
        max_d / diag,
        held.len()
    );
    csv.add("heldout", "bunny", "", "ply_points", pts.len());
    csv.add("heldout", "bunny", "", "exact_matches", exact);
    csv.add("heldout", "bunny", "", "nn_matches", matched);
    csv.add("heldout", "bunny", "", "held_out", held.len());
    if matched != subset.len() || collisions > 0 {
        println!(
            "  note: not every subset point matched a distinct PLY point; unmatched ones stay \
             in the held-out set"
        );
    }
    println!(
        "  d = |f|/|grad f| (Sampson distance) at the held-out points, relative to the diagonal"
    );
    println!(
        "  {:<12} {:<3} {:>9} {:>10} {:>10} {:>10} {:>7}",
        "method", "ker", "<1%", "median", "p95", "max", "eval_s"
    );
    for f in fits {
        let t = Instant::now();
        let mut d: Vec<f64> = held
            .par_iter()
            .map(|p| {
                let g = norm(&f.field.gradient(p));
                let v = f.field.value(p).abs();
                if g > 0.0 { v / g } else { f64::INFINITY }
            })
            .collect();
        let eval = t.elapsed();
        d.iter_mut().for_each(|v| *v /= diag);
        d.sort_by(f64::total_cmp);
        let within = d.iter().filter(|v| **v < 0.01).count() as f64 / d.len().max(1) as f64;
        let (med, p95) = (quantile(&d, 0.5), quantile(&d, 0.95));
        let max = d.last().copied().unwrap_or(f64::NAN);
        println!(
            "  {:<12} {:<3} {:>8.2}% {:>10.2e} {:>10.2e} {:>10.2e} {:>7.2}",
            f.method,
            f.kernel,
            100.0 * within,
            med,
            p95,
            max,
            eval.as_secs_f64()
        );
        csv.add("heldout", "bunny", f.method, "frac_below_1pct", within);
        csv.add("heldout", "bunny", f.method, "median_rel", med);
        csv.add("heldout", "bunny", f.method, "p95_rel", p95);
        csv.add("heldout", "bunny", f.method, "max_rel", max);
        csv.add("heldout", "bunny", f.method, "eval_s", eval.as_secs_f64());
    }
    Ok(())
}

/// The nearest-rank `q`-quantile of sorted `v` (NaN for none).
fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let k = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[k - 1]
}

fn dist2(a: &Point3, b: &Point3) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

// ---------------------------------------------------------------------------------------------
// 3. Geology

/// A geology data set with its level assignment.
struct GeoSet {
    name: &'static str,
    /// Surface points (metres) and formations.
    points: Vec<(Point3, String)>,
    /// Orientations: position (metres), unit normal (polarity applied), formation.
    orientations: Vec<(Point3, Point3, String)>,
    /// Formations in level order (level = index).
    levels: Vec<String>,
    /// Where the files and the order came from.
    notes: Vec<String>,
}

fn geology_sets(data: &Path) -> Res<Vec<GeoSet>> {
    let mut sets = Vec::new();

    // Perth basin: no order in the files; first appearance in the surface-points file.
    let dir = data.join("geology/perth_basin");
    let pts = dir.join("Paper_GU2F_sc_faults_topo_Points.csv");
    let ori = dir.join("Paper_GU2F_sc_faults_topo_Foliations.csv");
    let model = gempy::read_gempy(&pts, &ori)?;
    let mut first_seen: Vec<String> = Vec::new();
    for p in &model.surface_points {
        if !first_seen.contains(&p.formation) {
            first_seen.push(p.formation.clone());
        }
    }
    let points: Vec<(Point3, String)> = model
        .surface_points
        .iter()
        .map(|p| (p.position, p.formation.clone()))
        .collect();
    let orientations: Vec<(Point3, Point3, String)> = model
        .orientations
        .iter()
        .map(|o| (o.position, o.normal, o.formation.clone()))
        .collect();
    sets.push(GeoSet {
        name: "perth_basin",
        points: points.clone(),
        orientations: orientations.clone(),
        levels: first_seen,
        notes: vec![
            format!("files: {} and {}", file_name(&pts), file_name(&ori)),
            "order: the files give NO stratigraphic order: levels follow the order of first \
             appearance in the surface-points file (level 0 = first); this mixes faults and \
             layers and is not stratigraphic, so levels and orientation directions may disagree"
                .into(),
        ],
    });

    // The same data, layers only, in the order GemPy's example script uses (data README §3).
    let layers = ["Permian", "Lesueur", "Eneabba", "Yarragadee", "Cretaceous"];
    let keep = |f: &str| layers.contains(&f);
    sets.push(GeoSet {
        name: "perth_basin layers",
        points: points.into_iter().filter(|p| keep(&p.1)).collect(),
        orientations: orientations.into_iter().filter(|o| keep(&o.2)).collect(),
        levels: layers.iter().map(|s| s.to_string()).collect(),
        notes: vec![
            "extra run: the 5 layers only (faults, Cadda, Woodada_Kockatea, Cattamarra left \
             out), ordered as GemPy's example script does (youngest to oldest Cretaceous, \
             Yarragadee, Eneabba, Lesueur, Permian; from the data README, not the CSV); level \
             0 = oldest"
                .into(),
        ],
    });

    // Greenstone: GemPy's saved tables carry the order in their `id` column.
    let dir = data.join("geology/greenstone");
    let pts = dir.join("Greenstone_surface_points.csv");
    let ori = dir.join("Greenstone_orientations.csv");
    let model = gempy::read_gempy(&pts, &ori)?;
    let mut ids = gempy_ids(&pts)?;
    for (name, id) in gempy_ids(&ori)? {
        match ids.iter().find(|(n, _)| *n == name) {
            Some((_, i)) if *i != id => {
                return Err(format!(
                    "{}: formation {name} has id {id} but {i} in {}",
                    ori.display(),
                    file_name(&pts)
                )
                .into());
            }
            Some(_) => {}
            None => ids.push((name, id)),
        }
    }
    // id 1 is the youngest (top); level 0 = the oldest.
    ids.sort_by_key(|(_, id)| std::cmp::Reverse(*id));
    let order_text: Vec<String> = ids.iter().map(|(n, id)| format!("{n} (id {id})")).collect();
    sets.push(GeoSet {
        name: "greenstone",
        points: model
            .surface_points
            .iter()
            .map(|p| (p.position, p.formation.clone()))
            .collect(),
        orientations: model
            .orientations
            .iter()
            .map(|o| (o.position, o.normal, o.formation.clone()))
            .collect(),
        levels: ids.into_iter().map(|(n, _)| n).collect(),
        notes: vec![
            format!(
                "files: {} and {} (GemPy's saved tables of the SandStone_* data)",
                file_name(&pts),
                file_name(&ori)
            ),
            format!(
                "order: explicit, GemPy's `id` column (1 = youngest); level 0 = oldest: {}",
                order_text.join(" < ")
            ),
            "GemPy models its three series as separate fields; here one field holds all four \
             surfaces"
                .into(),
        ],
    });
    Ok(sets)
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into())
}

/// The `(surface, id)` pairs of a GemPy saved table, in order of first appearance. The files
/// are plain comma-separated text without quotes; the reader in `zeroset::core::io::gempy`
/// does not keep the `id` column, so it is read here.
fn gempy_ids(path: &Path) -> Res<Vec<(String, i64)>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut lines = text.lines().enumerate();
    let header: Vec<String> = lines
        .next()
        .map(|(_, l)| l.split(',').map(|s| s.trim().to_lowercase()).collect())
        .unwrap_or_default();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{}: no '{name}' column", path.display()))
    };
    let (surface, id) = (col("surface")?, col("id")?);
    let mut out: Vec<(String, i64)> = Vec::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        let bad = || {
            format!(
                "{}: line {}: cannot read surface and id",
                path.display(),
                i + 1
            )
        };
        let name = cells.get(surface).ok_or_else(bad)?.trim().to_string();
        let value: i64 = cells
            .get(id)
            .ok_or_else(bad)?
            .trim()
            .parse()
            .map_err(|_| bad())?;
        match out.iter().find(|(n, _)| *n == name) {
            Some((_, v)) if *v != value => {
                return Err(format!(
                    "{}: line {}: formation {name} has id {value}, earlier {v}",
                    path.display(),
                    i + 1
                )
                .into());
            }
            Some(_) => {}
            None => out.push((name, value)),
        }
    }
    Ok(out)
}

/// A geology fit: the field, its report, the gradient magnitude used.
struct GeoFit {
    fitted: Fitted<Triharmonic, 3>,
    g: f64,
    g_from_prefit: bool,
}

/// Fits levels at `points` and `g ×` normals at `orientations` (unit-box coordinates); `g` from
/// a values-only prefit (see the module docs), `fallback` if that gives nothing usable.
fn fit_geology(
    points: &[(Point3, f64)],
    orientations: &[(Point3, Point3)],
    fallback: f64,
) -> Res<GeoFit> {
    let mut values = Constraints::new();
    for (p, level) in points {
        values.push_value(*p, *level);
    }
    let pre = RbfFit::new(Triharmonic)
        .with_solver(Solver::Dense)
        .fit(&values)
        .map_err(|e| format!("values-only prefit: {e}"))?;
    let mut mags: Vec<f64> = orientations
        .iter()
        .map(|(p, _)| norm(&pre.field.gradient(p)))
        .collect();
    mags.sort_by(f64::total_cmp);
    let median = quantile(&mags, 0.5);
    let (g, g_from_prefit) = if median.is_finite() && median > 0.0 {
        (median, true)
    } else {
        (fallback, false)
    };
    let mut c = values;
    for (p, n) in orientations {
        c.push_gradient(*p, n.map(|v| g * v));
    }
    let fitted = RbfFit::new(Triharmonic)
        .with_solver(Solver::Dense)
        .fit(&c)
        .map_err(|e| format!("fit with orientations: {e}"))?;
    Ok(GeoFit {
        fitted,
        g,
        g_from_prefit,
    })
}

fn geology(set: &GeoSet, csv: &mut Csv) -> Res<()> {
    let name = set.name;
    println!("\n  {name}");
    for n in &set.notes {
        println!("    {n}");
    }
    let level_of: HashMap<&str, usize> = set
        .levels
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    // Points of formations without a level (none in these sets) are left out.
    let points: Vec<(Point3, usize, &str)> = set
        .points
        .iter()
        .filter_map(|(p, f)| level_of.get(f.as_str()).map(|&l| (*p, l, f.as_str())))
        .collect();
    let mut all: Vec<Point3> = points.iter().map(|p| p.0).collect();
    all.extend(set.orientations.iter().map(|o| o.0));
    let bounds = Aabb::from_points(&all).ok_or(format!("{name}: no points"))?;
    let centre = bounds.center();
    let scale = bounds.extent().iter().fold(0.0f64, |s, v| s.max(*v));
    if scale <= 0.0 {
        return Err(format!("{name}: all points coincide").into());
    }
    let unit = |p: &Point3| -> Point3 { std::array::from_fn(|a| (p[a] - centre[a]) / scale) };
    let unit_diag = bounds.diagonal() / scale;
    let fallback = set.levels.len() as f64 / unit_diag;
    println!(
        "    {} surface points, {} orientations, {} levels; centre ({:.0}, {:.0}, {:.0}) m, \
         scale 1/{:.0} m",
        points.len(),
        set.orientations.len(),
        set.levels.len(),
        centre[0],
        centre[1],
        centre[2],
        scale
    );
    let levels_text: Vec<String> = set
        .levels
        .iter()
        .enumerate()
        .map(|(i, n)| format!("{n}={i}"))
        .collect();
    println!("    levels: {}", levels_text.join(", "));

    let orients: Vec<(Point3, Point3)> = set
        .orientations
        .iter()
        .map(|(p, n, _)| (unit(p), *n))
        .collect();

    // Full fit.
    let all_points: Vec<(Point3, f64)> = points.iter().map(|p| (unit(&p.0), p.1 as f64)).collect();
    let full = fit_geology(&all_points, &orients, fallback).map_err(|e| format!("{name}: {e}"))?;
    let g_text = if full.g_from_prefit {
        "median |grad f| of a values-only r3 fit at the orientation points"
    } else {
        "fallback L / unit-box diagonal"
    };
    println!(
        "    gradient constraints: unit normal (polarity applied) x g, g = {:.3} per unit-box \
         length ({g_text}; ~ level spacing / typical thickness = {:.0} m)",
        full.g,
        scale / full.g
    );
    let report_fit = |label: &str, fit: &GeoFit, csv: &mut Csv| {
        let r = &fit.fitted.report;
        let (min_cos, close, mut ratios) = orientation_agreement(fit, &orients);
        ratios.sort_by(f64::total_cmp);
        let (rmin, rmax) = (
            ratios.first().copied().unwrap_or(f64::NAN),
            ratios.last().copied().unwrap_or(f64::NAN),
        );
        println!(
            "    {label}: {} constraints ({} unknowns), {} in {:.3} s, max_resid {:.2e}, cond \
             {:.1e}\n      orientations reproduced: {close} of {} with cos(grad f, n) > 0.999999 \
             (min cos {:.9}), |grad f|/g in [{:.6}, {:.6}]",
            r.constraints,
            r.unknowns,
            r.solver,
            r.elapsed.as_secs_f64(),
            r.max_residual,
            r.condition_estimate,
            orients.len(),
            min_cos,
            rmin,
            rmax
        );
        for w in &r.warnings {
            println!("      warning: {w}");
        }
        csv.add("geology", name, label, "constraints", r.constraints);
        csv.add("geology", name, label, "fit_s", r.elapsed.as_secs_f64());
        csv.add("geology", name, label, "max_residual", r.max_residual);
        csv.add(
            "geology",
            name,
            label,
            "condition_estimate",
            r.condition_estimate,
        );
        csv.add("geology", name, label, "gradient_scale", fit.g);
        csv.add("geology", name, label, "orientations", orients.len());
        csv.add(
            "geology",
            name,
            label,
            "orientations_cos_above_0.999999",
            close,
        );
        csv.add("geology", name, label, "orientation_min_cos", min_cos);
        csv.add("geology", name, label, "orientation_ratio_min", rmin);
        csv.add("geology", name, label, "orientation_ratio_max", rmax);
    };
    report_fit("full fit", &full, csv);

    // Hold-out: every 5th surface point of each formation (file order) left out.
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let mut held_in = Vec::new();
    let mut held_out: Vec<(Point3, usize, &str)> = Vec::new();
    for &(p, level, f) in &points {
        let k = seen.entry(f).or_insert(0);
        *k += 1;
        if k.is_multiple_of(5) {
            held_out.push((unit(&p), level, f));
        } else {
            held_in.push((unit(&p), level as f64));
        }
    }
    let refit =
        fit_geology(&held_in, &orients, fallback).map_err(|e| format!("{name} hold-out: {e}"))?;
    report_fit("hold-out fit", &refit, csv);
    let values: Vec<f64> = held_out
        .iter()
        .map(|(p, _, _)| refit.fitted.field.value(p))
        .collect();
    println!(
        "    {:<20} {:>5} {:>6} {:>6} {:>5} {:>9} {:>9}",
        "formation", "level", "points", "orient", "held", "mean_err", "max_err"
    );
    for (level, f) in set.levels.iter().enumerate() {
        let errs: Vec<f64> = held_out
            .iter()
            .zip(&values)
            .filter(|((_, _, hf), _)| *hf == f.as_str())
            .map(|(_, v)| (v - level as f64).abs())
            .collect();
        let n_points = points.iter().filter(|p| p.2 == f.as_str()).count();
        let n_orient = set.orientations.iter().filter(|o| o.2 == *f).count();
        let (mean, max) = if errs.is_empty() {
            ("-".to_string(), "-".to_string())
        } else {
            let mean = errs.iter().sum::<f64>() / errs.len() as f64;
            let max = errs.iter().fold(0.0f64, |s, v| s.max(*v));
            csv.add("geology", name, f, "mean_abs_err_levels", mean);
            csv.add("geology", name, f, "max_abs_err_levels", max);
            (format!("{mean:.3}"), format!("{max:.3}"))
        };
        csv.add("geology", name, f, "level", level);
        csv.add("geology", name, f, "held_out", errs.len());
        println!(
            "    {f:<20} {level:>5} {n_points:>6} {n_orient:>6} {:>5} {mean:>9} {max:>9}",
            errs.len()
        );
    }
    let (mut pairs, mut right) = (0usize, 0usize);
    for i in 0..held_out.len() {
        for j in i + 1..held_out.len() {
            let dl = held_out[i].1 as f64 - held_out[j].1 as f64;
            if dl != 0.0 {
                pairs += 1;
                if dl * (values[i] - values[j]) > 0.0 {
                    right += 1;
                }
            }
        }
    }
    let all_errs: Vec<f64> = held_out
        .iter()
        .zip(&values)
        .map(|((_, l, _), v)| (v - *l as f64).abs())
        .collect();
    let mean_all = all_errs.iter().sum::<f64>() / all_errs.len().max(1) as f64;
    println!(
        "    all held out: {} points, mean |f - level| {mean_all:.3}; ordered: {right} of {pairs} \
         pairs from different formations ({:.1}%)",
        held_out.len(),
        100.0 * right as f64 / pairs.max(1) as f64
    );
    csv.add("geology", name, "hold-out fit", "held_out", held_out.len());
    csv.add(
        "geology",
        name,
        "hold-out fit",
        "mean_abs_err_levels",
        mean_all,
    );
    csv.add("geology", name, "hold-out fit", "ordered_pairs", right);
    csv.add("geology", name, "hold-out fit", "pairs", pairs);
    Ok(())
}

/// The smallest `cos(∇f, n)` over the orientations, how many have `cos > 0.999999`, and
/// `|∇f| / g` at each.
fn orientation_agreement(fit: &GeoFit, orients: &[(Point3, Point3)]) -> (f64, usize, Vec<f64>) {
    let mut min_cos = f64::NAN;
    let mut close = 0;
    let mut ratios = Vec::with_capacity(orients.len());
    for (p, n) in orients {
        let g = fit.fitted.field.gradient(p);
        let len = norm(&g);
        let cos = dot(&g, n) / (len * norm(n));
        min_cos = if min_cos.is_nan() {
            cos
        } else {
            min_cos.min(cos)
        };
        if cos > 0.999_999 {
            close += 1;
        }
        ratios.push(len / fit.g);
    }
    (min_cos, close, ratios)
}
