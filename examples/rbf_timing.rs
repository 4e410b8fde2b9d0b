//! Times RBF fitting and evaluation on the sphere set-up of `PEERS.md` (the one scipy's
//! `RBFInterpolator(kernel, degree=1)` is timed on), and writes the very same points so that
//! `benches/peers/rbf_peers.py` can run scipy on them.
//!
//! ```text
//! cargo run --release --example rbf_timing -- [--n 1000,3000,6000] [--kernels r,r3]
//!     [--eval 100000] [--repeat 5] [--threads N] [--solvers auto,dense,mixed,iterative]
//!     [--write-dir DIR] [--csv FILE]
//! ```
//!
//! Set-up: sphere centre (0.5, 0.5, 0.5), radius 0.35; `N − 2⌊N/3⌋` Fibonacci points on it
//! (value 0) and, for the first `⌊N/3⌋` of them, points at `±0.05` along the outward normal
//! (values `±0.05`). Evaluation: `--eval` points uniform in `[0, 1]³` (SplitMix64, seed 7).
//!
//! What is timed (the rule of `benches/peers`: one warm-up, then the median of `--repeat` runs;
//! a single run without warm-up when the first run alone takes over 2 s, reported as such):
//!
//! - **fit**: from the plain arrays of points and values (what scipy's `RBFInterpolator`
//!   constructor is given) to a field ready to evaluate: building the `Constraints`, then
//!   `RbfFit::fit` — validation, duplicate check, the polynomial's scaling, the kernel matrix's
//!   assembly, the factorisation and solve (or GMRES), the refinement step when it is taken, the
//!   residual by direct sums, and the field's construction. Nothing is cached between runs.
//! - **eval**: `ScalarField::values` at the `--eval` points into a freshly allocated output
//!   (scipy's `__call__` returns a new array).
//!
//! Figures: fit and evaluation times, the largest error against the sphere's signed distance over
//! the evaluation points with `|sd| < 0.05`, and the largest constraint residual.
//!
//! Threads: rayon's default (`RAYON_NUM_THREADS`, else one per CPU) or `--threads N`; the count
//! in effect (it also sets faer's dense products) is printed and written to the CSV.
//!
//! `--solvers iterative` reads `ZEROSET_RBF_NEIGHBOURS`, `ZEROSET_RBF_FAR`,
//! `ZEROSET_RBF_MAX_ITER` (default 300), `ZEROSET_RBF_COARSE` (coarse centres, 0 = none) and
//! `ZEROSET_RBF_FMM_FROM` (centres from which the products use the FMM) from the environment,
//! for tuning experiments.
//!
//! `--write-dir DIR` writes `DIR/rbf_sphere_n{N}.csv` (`x,y,z,value`) and `DIR/rbf_eval_{M}.csv`
//! (`x,y,z`), numbers with 17 significant digits (exact round trip); `--csv FILE` writes
//! `n,kernel,solver,fit_ms,eval_ms,max_err_band,max_constraint_residual,runs,threads,fit_warmup,`
//! `eval_runs,eval_warmup,fit_times_ms,eval_times_ms` (`runs` = timed fit runs; `*_warmup` 1
//! when a warm-up preceded the timed runs).

#[path = "common/output.rs"]
mod output;
#[path = "common/rbf_sphere.rs"]
mod rbf_sphere;
#[path = "common/rng.rs"]
mod rng;
#[path = "common/timing.rs"]
mod timing;

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Duration;

use zeroset::bases::rbf::{
    Biharmonic, Constraints, Fitted, IterativeParams, Kernel, Prescribed, RbfFit, Solver,
    Triharmonic,
};
use zeroset::core::field::ScalarField;

use output::write_text;
use rbf_sphere::{CENTRE, OFFSET, RADIUS, sphere_setup};
use rng::SplitMix64;

struct Args {
    ns: Vec<usize>,
    kernels: Vec<String>,
    eval: usize,
    repeat: usize,
    threads: Option<usize>,
    write_dir: Option<PathBuf>,
    csv: Option<PathBuf>,
    solvers: Vec<String>,
}

const USAGE: &str = "usage: rbf_timing [--n 1000,3000,6000] [--kernels r,r3] [--eval 100000] \
    [--repeat 5] [--threads N] [--solvers auto,dense,mixed,iterative] [--write-dir DIR] \
    [--csv FILE]";

/// A run slower than this is timed once, without warm-up.
const ONCE_ABOVE: Duration = Duration::from_secs(2);

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        ns: vec![1000, 3000, 6000],
        kernels: vec!["r".into(), "r3".into()],
        eval: 100_000,
        repeat: 5,
        threads: None,
        write_dir: None,
        csv: None,
        solvers: vec!["auto".into()],
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value\n{USAGE}"));
        match flag.as_str() {
            "--n" => args.ns = timing::parse_list("--n", &value()?)?,
            "--kernels" => args.kernels = value()?.split(',').map(str::to_string).collect(),
            "--eval" => args.eval = value()?.parse().map_err(|e| format!("--eval: {e}"))?,
            "--repeat" => {
                args.repeat = value()?.parse().map_err(|e| format!("--repeat: {e}"))?;
                args.repeat = args.repeat.max(1);
            }
            "--threads" => {
                args.threads = Some(value()?.parse().map_err(|e| format!("--threads: {e}"))?)
            }
            "--write-dir" => args.write_dir = Some(value()?.into()),
            "--csv" => args.csv = Some(value()?.into()),
            "--solvers" => args.solvers = value()?.split(',').map(str::to_string).collect(),
            "--help" | "-h" => return Err(USAGE.into()),
            other => return Err(format!("unknown argument {other}\n{USAGE}")),
        }
    }
    if args.ns.iter().any(|&n| n < 10) {
        return Err("--n values must be at least 10".into());
    }
    if let Some(s) = args
        .solvers
        .iter()
        .find(|s| !matches!(s.as_str(), "auto" | "dense" | "mixed" | "iterative"))
    {
        return Err(format!(
            "--solvers: unknown solver {s} (auto, dense, mixed, iterative)"
        ));
    }
    if let Some(k) = args
        .kernels
        .iter()
        .find(|k| !matches!(k.as_str(), "r" | "r3"))
    {
        return Err(format!("--kernels: unknown kernel {k} (r, r3)"));
    }
    Ok(args)
}

fn signed_distance(p: &[f64; 3]) -> f64 {
    p.iter()
        .map(|v| (v - CENTRE) * (v - CENTRE))
        .sum::<f64>()
        .sqrt()
        - RADIUS
}

fn write_csv(
    path: &std::path::Path,
    header: &str,
    rows: impl Iterator<Item = Vec<f64>>,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut text = String::from(header);
    text.push('\n');
    for row in rows {
        let cells: Vec<String> = row.iter().map(|v| format!("{v:.16e}")).collect();
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    Ok(write_text(path, &text)?)
}

/// The constraints as plain arrays: the points and the prescribed values (what scipy's
/// `RBFInterpolator` is given).
fn plain_arrays(c: &Constraints<3>) -> (Vec<[f64; 3]>, Vec<f64>) {
    c.as_slice()
        .iter()
        .map(|con| match con.prescribed {
            Prescribed::Value(v) => (con.point, v),
            Prescribed::Gradient(_) => (con.point, f64::NAN),
        })
        .unzip()
}

/// The timed fit: from plain arrays to a fitted field (see the module docs).
fn fit_from_arrays<K: Kernel + Clone>(
    fit: &RbfFit<K>,
    points: &[[f64; 3]],
    values: &[f64],
) -> Result<Fitted<K, 3>, zeroset::bases::rbf::RbfError> {
    let mut c = Constraints::new();
    for (p, &v) in points.iter().zip(values) {
        c.push_value(*p, v);
    }
    fit.fit(&c)
}

fn run<K: Kernel + Clone>(
    kernel: K,
    solver: &str,
    n: usize,
    c: &Constraints<3>,
    eval: &[[f64; 3]],
    repeat: usize,
    csv: &mut String,
) -> Result<(), Box<dyn std::error::Error>> {
    let name = kernel.name().to_string();
    let solver = match solver {
        "dense" => Solver::Dense,
        "mixed" => Solver::MixedPrecision,
        "iterative" => {
            let d = IterativeParams::default();
            Solver::Iterative(IterativeParams {
                neighbours: env_or("ZEROSET_RBF_NEIGHBOURS", d.neighbours),
                far: env_or("ZEROSET_RBF_FAR", d.far),
                max_iterations: env_or("ZEROSET_RBF_MAX_ITER", 300),
                coarse: env_or("ZEROSET_RBF_COARSE", d.coarse),
                fmm_from: env_or("ZEROSET_RBF_FMM_FROM", d.fmm_from),
                ..d
            })
        }
        _ => Solver::Auto,
    };
    let fit = RbfFit::new(kernel).with_solver(solver);
    let (points, targets) = plain_arrays(c);
    let fit_timed = timing::measure(repeat, Some(ONCE_ABOVE), || {
        fit_from_arrays(&fit, &points, &targets)
    })?;
    let fitted = &fit_timed.last;
    let eval_timed = timing::measure(repeat, Some(ONCE_ABOVE), || {
        let mut values = vec![0.0; eval.len()];
        fitted.field.values(eval, &mut values);
        Ok::<_, std::convert::Infallible>(values)
    })?;
    let values = &eval_timed.last;
    let max_err = eval
        .iter()
        .zip(values)
        .filter(|(p, _)| signed_distance(p).abs() < OFFSET)
        .map(|(p, v)| (v - signed_distance(p)).abs())
        .fold(0.0, f64::max);
    let residual = c
        .as_slice()
        .iter()
        .map(|con| match con.prescribed {
            Prescribed::Value(v) => (fitted.field.value(&con.point) - v).abs(),
            Prescribed::Gradient(_) => 0.0,
        })
        .fold(0.0, f64::max);
    let (fit_ms, eval_ms) = (fit_timed.ms(), eval_timed.ms());
    println!(
        "{n:<6} {name:<4} {:<15} {fit_ms:>10.1} {eval_ms:>10.1} {max_err:>12.3e} {residual:>12.2e} {:>9.1e} {:>5}  fit: {}; eval: {}",
        fitted.report.solver,
        fitted.report.condition_estimate,
        fitted.report.iterations,
        fit_timed.how(),
        eval_timed.how(),
    );
    for w in &fitted.report.warnings {
        eprintln!("  warning: {w}");
    }
    writeln!(
        csv,
        "{n},{name},{},{fit_ms:.4},{eval_ms:.4},{max_err:.6e},{residual:.6e},{},{},{},{},{},{},{}",
        fitted.report.solver,
        fit_timed.runs(),
        rayon::current_num_threads(),
        u8::from(fit_timed.warmup),
        eval_timed.runs(),
        u8::from(eval_timed.warmup),
        timing::times_cell(&fit_timed.times),
        timing::times_cell(&eval_timed.times),
    )?;
    Ok(())
}

fn main() {
    if let Err(e) = run_all() {
        eprintln!("rbf_timing: {e}");
        std::process::exit(1);
    }
}

fn run_all() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let threads = timing::set_threads(args.threads)?;
    let mut rng = SplitMix64(7);
    let eval: Vec<[f64; 3]> = (0..args.eval)
        .map(|_| [rng.unit(), rng.unit(), rng.unit()])
        .collect();
    if let Some(dir) = &args.write_dir {
        std::fs::create_dir_all(dir)?;
        write_csv(
            &dir.join(format!("rbf_eval_{}.csv", args.eval)),
            "x,y,z",
            eval.iter().map(|p| p.to_vec()),
        )?;
    }
    println!("threads {threads}; evaluation at {} points", args.eval);
    println!(
        "{:<6} {:<4} {:<15} {:>10} {:>10} {:>12} {:>12} {:>9} {:>5}",
        "n", "kern", "solver", "fit_ms", "eval_ms", "max_err_band", "residual", "cond_est", "iters"
    );
    let mut csv = String::from(
        "n,kernel,solver,fit_ms,eval_ms,max_err_band,max_constraint_residual,runs,threads,\
         fit_warmup,eval_runs,eval_warmup,fit_times_ms,eval_times_ms\n",
    );
    for &n in &args.ns {
        let c = sphere_setup(n);
        if let Some(dir) = &args.write_dir {
            write_csv(
                &dir.join(format!("rbf_sphere_n{n}.csv")),
                "x,y,z,value",
                c.as_slice().iter().map(|con| {
                    let v = match con.prescribed {
                        Prescribed::Value(v) => v,
                        Prescribed::Gradient(_) => f64::NAN,
                    };
                    vec![con.point[0], con.point[1], con.point[2], v]
                }),
            )?;
        }
        for k in &args.kernels {
            for s in &args.solvers {
                match k.as_str() {
                    "r" => run(Biharmonic, s, n, &c, &eval, args.repeat, &mut csv)?,
                    _ => run(Triharmonic, s, n, &c, &eval, args.repeat, &mut csv)?,
                }
            }
        }
    }
    if let Some(path) = &args.csv {
        write_text(path, &csv)?;
    }
    Ok(())
}

/// The environment variable `name` as a count, or `default` when unset or not a number.
fn env_or(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}
