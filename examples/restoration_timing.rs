//! Times protrusion removal through `zeroset::restore` — assembly and solve, sampling the field
//! excluded — on the set-up of `PEERS.md`, and optionally writes the very system it solved so
//! that `benches/peers/restoration_bar.py` can time scipy on it.
//!
//! Set-up: a cell-centred grid of `2k` cells per axis on `[−1, 1]³`, `f` = the signed distance
//! to the sphere of radius 0.6, the mask = the central `k³` block, the Neumann face = its top
//! (`+z`), α = 1. Unknowns: `k²(k − 1)` (the top layer is fixed by the Neumann rows).
//!
//! ```text
//! cargo run --release --example restoration_timing -- --k 32,64,128 [--repeat 5] [--threads N]
//!     [--solvers separable,lsqr-poisson,sparse-cholesky,cgls] [--write-dir DIR] [--csv FILE]
//! ```
//!
//! Timed (one warm-up, then the median of `--repeat` runs), per k:
//!
//! - `solve-only`: `BoxLaplace::solve` of the separable method on the ready right-hand side — the
//!   forward DSTs, the Givens QR of every line, the back substitution, the inverse DSTs and the
//!   exact residuals — the like-for-like figure for a NumPy port that solves from a ready `b`;
//! - each of `--solvers`: `Protrusion::restore_in_place` on a fresh copy of the samples (the copy
//!   is not timed): the assembly of the system from the samples, the solve and writing the
//!   solution back into the mask. Sampling the field is outside.
//!
//! Threads: rayon's default (`RAYON_NUM_THREADS`, else one per CPU) or `--threads N`; the count
//! in effect is printed and written to the CSV
//! (`k,unknowns,rows,solver,median_ms,iterations,rel_residual,max_rel_diff,runs,threads,warmup,times_ms`).
//!
//! `--write-dir DIR` writes, for each k, `restoration_bar_k{k}.A.mtx`, `.b.mtx` and the
//! separable solution `.h.mtx`, plus `.dims.txt` (the box of unknowns).

#[path = "common/mtx.rs"]
mod mtx;
#[path = "common/timing.rs"]
mod timing;

use std::sync::Arc;
use std::time::Instant;

use zeroset::core::analytic::Sphere;
use zeroset::core::geometry::Aabb;
use zeroset::core::grid::Grid;
use zeroset::core::mask::{BoxMask, Face, Side};
use zeroset::restore::protrusion::{Protrusion, Solver};
use zeroset::solvers::{Cgls, IterativeParams, SparseCholesky};

struct Args {
    ks: Vec<usize>,
    repeat: usize,
    threads: Option<usize>,
    solvers: Vec<String>,
    write_dir: Option<std::path::PathBuf>,
    csv: Option<std::path::PathBuf>,
}

const USAGE: &str = "usage: restoration_timing [--k 32,64,128] [--repeat 5] [--threads N] \
    [--solvers separable,lsqr-poisson,sparse-cholesky,cgls] [--write-dir DIR] [--csv FILE]";

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        ks: vec![32, 64, 128],
        repeat: 5,
        threads: None,
        solvers: vec!["separable".into(), "lsqr-poisson".into()],
        write_dir: None,
        csv: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--k" => args.ks = timing::parse_list("--k", &value()?)?,
            "--repeat" => {
                args.repeat = value()?.parse().map_err(|e| format!("--repeat: {e}"))?;
                args.repeat = args.repeat.max(1);
            }
            "--threads" => {
                args.threads = Some(value()?.parse().map_err(|e| format!("--threads: {e}"))?)
            }
            "--solvers" => args.solvers = value()?.split(',').map(str::to_string).collect(),
            "--write-dir" => args.write_dir = Some(value()?.into()),
            "--csv" => args.csv = Some(value()?.into()),
            "--help" | "-h" => return Err(USAGE.into()),
            other => return Err(format!("unknown argument {other}\n{USAGE}")),
        }
    }
    if args.ks.iter().any(|&k| k < 3) {
        return Err("--k values must be at least 3".into());
    }
    Ok(args)
}

fn solver(name: &str) -> Result<Solver, String> {
    let tight = IterativeParams::default().with_tolerance(1e-12);
    Ok(match name {
        "separable" => Solver::Separable,
        "lsqr-poisson" => Solver::PreconditionedLsqr { tolerance: 1e-12 },
        "sparse-cholesky" => Solver::General(Arc::new(SparseCholesky::default())),
        "cgls" => Solver::General(Arc::new(Cgls::new(tight))),
        other => return Err(format!("unknown solver {other}")),
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let threads = timing::set_threads(args.threads)?;
    let mut csv = String::from(
        "k,unknowns,rows,solver,median_ms,iterations,rel_residual,max_rel_diff,runs,threads,\
         warmup,times_ms\n",
    );
    println!(
        "threads {threads}; one warm-up, then the median of {}",
        args.repeat
    );
    println!(
        "{:<5} {:>9} {:<16} {:>10} {:>6} {:>10} {:>10}",
        "k", "unknowns", "solver", "median_ms", "iters", "rel_res", "vs_sep"
    );
    for &k in &args.ks {
        let grid = Grid::cell_centered(Aabb::centered_cube(1.0)?, [2 * k; 3])?;
        let f = grid.sample(&Sphere::new([0.0; 3], 0.6));
        let lo = k / 2;
        let mask = BoxMask::from_indices(&grid, [lo; 3], [lo + k - 1; 3])?;
        let base = Protrusion::new(Face::new(2, Side::Upper)).with_alpha(1.0);
        let reference = base.restore_samples(&grid, &f, &mask)?.0;
        let system = base.system(&grid, &f, &mask)?;
        if let Some(dir) = &args.write_dir {
            std::fs::create_dir_all(dir)?;
            let stem = dir.join(format!("restoration_bar_k{k}"));
            let a = system.operator().to_sparse();
            mtx::write_sparse(
                &stem.with_extension("A.mtx"),
                a.as_ref(),
                &format!(
                    "zeroset restoration bar system, k={k}, unknown box {:?}",
                    system.unknown_box().1
                ),
            )?;
            mtx::write_vector(&stem.with_extension("b.mtx"), system.rhs())?;
            let h = system.operator().solve(system.rhs())?.x;
            mtx::write_vector(&stem.with_extension("h.mtx"), &h)?;
            let dims = system.unknown_box().1;
            std::fs::write(
                stem.with_extension("dims.txt"),
                format!("{} {} {}\n", dims[0], dims[1], dims[2]),
            )?;
        }
        // The separable solve alone (right-hand side ready, residual checks included): the
        // like-for-like figure for a NumPy port of the same method.
        {
            let timed = timing::measure(args.repeat, None, || {
                system
                    .operator()
                    .solve(system.rhs())
                    .map(std::hint::black_box)
            })?;
            let ms = timed.ms();
            let n = system.operator().unknowns();
            println!("{k:<5} {n:>9} {:<16} {ms:>10.2}", "solve-only");
            csv.push_str(&format!(
                "{k},{n},{},solve-only,{ms:.4},0,,0,{},{threads},1,{}\n",
                system.rhs().len(),
                timed.runs(),
                timing::times_cell(&timed.times),
            ));
        }
        for name in &args.solvers {
            let params = base.clone().with_solver(solver(name)?);
            // Warm-up, then the median of `repeat` runs of the in-place restoration on a fresh
            // copy of the samples (the copy is not timed).
            let (g, report) = params.restore_samples(&grid, &f, &mask)?;
            let mut times = Vec::with_capacity(args.repeat);
            for _ in 0..args.repeat {
                let mut samples = f.clone();
                let start = Instant::now();
                params.restore_in_place(&grid, &mut samples, &mask)?;
                times.push(start.elapsed());
                std::hint::black_box(samples);
            }
            let scale = reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let diff = g
                .iter()
                .zip(&reference)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
                / scale;
            let ms = timing::median(times.clone()).as_secs_f64() * 1e3;
            if std::env::var_os("ZEROSET_PHASES").is_some() {
                eprintln!(
                    "  phases: assembly {:.1} ms, solve {:.1} ms",
                    report.assembly.as_secs_f64() * 1e3,
                    report.solve.elapsed.as_secs_f64() * 1e3
                );
            }
            println!(
                "{k:<5} {:>9} {name:<16} {ms:>10.2} {:>6} {:>10.2e} {diff:>10.1e}",
                report.unknowns, report.solve.iterations, report.solve.rel_residual
            );
            csv.push_str(&format!(
                "{k},{},{},{name},{ms:.4},{},{:.3e},{diff:.3e},{},{threads},1,{}\n",
                report.unknowns,
                report.rows,
                report.solve.iterations,
                report.solve.rel_residual,
                times.len(),
                timing::times_cell(&times),
            ));
        }
    }
    if let Some(path) = &args.csv {
        std::fs::write(path, csv)?;
    }
    Ok(())
}
