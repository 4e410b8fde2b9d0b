//! Solves the protrusion-removal least-squares problem (see `zeroset::solvers::problems`) with
//! every solver, prints a table of times (median of `--repeat` runs after a warm-up), iterations,
//! residuals and agreement, and optionally writes the system as MatrixMarket files so that
//! `benches/peers/restoration_peers.py` can solve the very same matrices with scipy.
//!
//! ```text
//! cargo run --release --example restoration_solvers -- --k 16,24,32 [--repeat 5] [--threads N]
//!     [--write-mtx DIR] [--csv FILE] [--skip-dense]
//! ```
//!
//! Every cost counted: each timed run builds the solver afresh (the Poisson preconditioner of
//! `lsqr-poisson`, the symbolic analysis of `sparse-cholesky`) and solves from the matrix and the
//! right-hand side; one warm-up, then the median of `--repeat` runs. The warm-up's own time is
//! kept as `first_ms` (this solver's first solve; work buffers kept by
//! `zeroset::solvers::scratch` from earlier solves may serve it). One more row,
//! `sparse-cholesky-reused`, times the interactive re-solve: one solver whose symbolic analysis
//! (made in its warm-up) is reused — the analysis is *not* counted there (`setup` = `reused`;
//! `counted` for the others).
//!
//! Threads: rayon's default (`RAYON_NUM_THREADS`, else one per CPU) or `--threads N` (a global
//! rayon pool of `N` threads); the count in effect (`rayon::current_num_threads()`, which also
//! drives faer) is printed and written to the CSV.
//!
//! With `--write-mtx DIR` it also writes each solver's solution as
//! `DIR/restoration_k{k}_x_{solver}.mtx`; `--csv FILE` writes the table as CSV
//! (`k,solver,median_ms,iterations,rel_residual,rel_normal_residual,max_abs_dx,runs,threads,`
//! `warmup,first_ms,setup,times_ms`).

#[path = "common/mtx.rs"]
mod mtx;
#[path = "common/timing.rs"]
mod timing;

use std::sync::Arc;
use std::time::{Duration, Instant};

use zeroset::core::lsq::{LeastSquaresSolver, LsqMatrix, Solution};
use zeroset::solvers::kernels::max_abs_diff;
use zeroset::solvers::{self, IterativeParams, problems::protrusion_problem};

struct Args {
    ks: Vec<usize>,
    repeat: usize,
    write_mtx: Option<std::path::PathBuf>,
    csv: Option<std::path::PathBuf>,
    skip_dense: bool,
    threads: Option<usize>,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        ks: vec![16, 24, 32],
        repeat: 5,
        write_mtx: None,
        csv: None,
        skip_dense: false,
        threads: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--k" => args.ks = timing::parse_list("--k", &value()?)?,
            "--repeat" => args.repeat = value()?.parse().map_err(|e| format!("--repeat: {e}"))?,
            "--write-mtx" => args.write_mtx = Some(value()?.into()),
            "--csv" => args.csv = Some(value()?.into()),
            "--skip-dense" => args.skip_dense = true,
            "--threads" => {
                args.threads = Some(value()?.parse().map_err(|e| format!("--threads: {e}"))?)
            }
            "--help" | "-h" => {
                return Err("usage: restoration_solvers [--k 16,24,32] [--repeat 5] [--threads N] [--write-mtx DIR] [--csv FILE] [--skip-dense]".into());
            }
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if args.repeat == 0 {
        return Err("--repeat must be at least 1".into());
    }
    Ok(args)
}

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// Builds a solver from nothing: every timed run calls it, so its set-up is counted.
type Make = Box<dyn Fn() -> Res<Box<dyn LeastSquaresSolver>>>;

/// What one solver row timed.
struct Row {
    median: Duration,
    first: Duration,
    times: Vec<Duration>,
    solution: Solution,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn main() -> Res<()> {
    let args = parse_args()?;
    let threads = timing::set_threads(args.threads)?;
    let mut csv = String::from(
        "k,solver,median_ms,iterations,rel_residual,rel_normal_residual,max_abs_dx,runs,threads,\
         warmup,first_ms,setup,times_ms\n",
    );
    // The same tolerance the peer script gives scipy.
    let tight = IterativeParams::default().with_tolerance(1e-12);
    println!(
        "threads {threads}; one warm-up, then the median of {} runs, each building its solver \
         afresh (sparse-cholesky-reused: the symbolic analysis kept from the warm-up)",
        args.repeat
    );
    println!(
        "{:<6} {:<22} {:>11} {:>11} {:>7} {:>11} {:>11} {:>11}",
        "k", "solver", "median_ms", "first_ms", "iters", "rel_res", "rel_normal", "max|dx|"
    );
    for &k in &args.ks {
        let p = protrusion_problem(k, 1.0);
        if let Some(dir) = &args.write_mtx {
            write_problem(dir, k, &p)?;
        }
        let n = p.a.ncols();
        let it = tight.clone();
        let mut list: Vec<(&str, Make)> = vec![(
            // LSQR right-preconditioned by the fast Poisson solve of the mask box: the
            // Laplace rows of this problem are exactly (1/6)·Δ_h on the k³ box.
            "lsqr-poisson",
            Box::new(move || {
                let poisson = Arc::new(solvers::DirichletLaplacian::new([k, k, k], 1.0 / 6.0)?);
                Ok(
                    Box::new(solvers::Lsqr::new(it.clone().with_preconditioner(poisson)))
                        as Box<dyn LeastSquaresSolver>,
                )
            }),
        )];
        let it = tight.clone();
        list.push((
            "lsqr",
            Box::new(move || Ok(Box::new(solvers::Lsqr::new(it.clone())) as _)),
        ));
        let it = tight.clone();
        list.push((
            "cgls",
            Box::new(move || Ok(Box::new(solvers::Cgls::new(it.clone())) as _)),
        ));
        list.push((
            "pcg-normal",
            Box::new(|| {
                Ok(Box::new(solvers::Pcg::new(solvers::PcgParams {
                    tol: 1e-12,
                    ..Default::default()
                })) as _)
            }),
        ));
        list.push((
            "sparse-cholesky",
            Box::new(|| Ok(Box::new(solvers::SparseCholesky::default()) as _)),
        ));
        if n <= 15_000 {
            list.push((
                "sparse-qr",
                Box::new(|| Ok(Box::new(solvers::SparseQr::default()) as _)),
            ));
        }
        if !args.skip_dense && n <= 1000 {
            list.push((
                "dense-qr",
                Box::new(|| Ok(Box::new(solvers::DenseQr::default()) as _)),
            ));
            list.push((
                "normal-lu",
                Box::new(|| Ok(Box::new(solvers::NormalLu::default()) as _)),
            ));
        }
        let a = LsqMatrix::SparseRow(p.a.as_ref());
        let mut rows: Vec<(String, &str, Row)> = Vec::new();
        for (label, make) in &list {
            // Every run: the solver built afresh, then the solve.
            let row = time_runs(args.repeat, || make()?.solve(a, &p.b).map_err(Into::into))?;
            rows.push((label.to_string(), "counted", row));
        }
        // The interactive re-solve: one solver, its symbolic analysis made in the warm-up.
        let kept = solvers::SparseCholesky::default();
        let row = time_runs(args.repeat, || kept.solve(a, &p.b).map_err(Into::into))?;
        rows.push(("sparse-cholesky-reused".into(), "reused", row));

        let reference = rows[0].2.solution.x.clone();
        for (label, setup, row) in &rows {
            let s = &row.solution;
            let dx = max_abs_diff(&reference, &s.x);
            csv.push_str(&format!(
                "{k},{label},{},{},{:e},{:e},{:e},{},{threads},1,{},{setup},{}\n",
                ms(row.median),
                s.info.iterations,
                s.info.rel_residual,
                s.info.rel_normal_residual,
                dx,
                row.times.len(),
                ms(row.first),
                timing::times_cell(&row.times),
            ));
            if let Some(dir) = &args.write_mtx {
                mtx::write_vector(&dir.join(format!("restoration_k{k}_x_{label}.mtx")), &s.x)?;
            }
            println!(
                "{:<6} {:<22} {:>11.2} {:>11.2} {:>7} {:>11.2e} {:>11.2e} {:>11.2e}",
                k,
                label,
                ms(row.median),
                ms(row.first),
                s.info.iterations,
                s.info.rel_residual,
                s.info.rel_normal_residual,
                dx
            );
        }
    }
    if let Some(path) = &args.csv {
        std::fs::write(path, csv)?;
    }
    Ok(())
}

/// One warm-up run of `f` (its time kept as `first`), then `repeat` timed runs.
fn time_runs(repeat: usize, mut f: impl FnMut() -> Res<Solution>) -> Res<Row> {
    let t = Instant::now();
    let mut solution = f()?;
    let first = t.elapsed();
    let mut times = Vec::with_capacity(repeat);
    for _ in 0..repeat {
        let t = Instant::now();
        solution = f()?;
        times.push(t.elapsed());
    }
    Ok(Row {
        median: timing::median(times.clone()),
        first,
        times,
        solution,
    })
}

fn write_problem(
    dir: &std::path::Path,
    k: usize,
    p: &solvers::problems::Problem,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    mtx::write_sparse(
        &dir.join(format!("restoration_k{k}_A.mtx")),
        p.a.as_ref(),
        &format!("zeroset protrusion-removal least-squares matrix, k={k}"),
    )?;
    mtx::write_vector(&dir.join(format!("restoration_k{k}_b.mtx")), &p.b)
}
