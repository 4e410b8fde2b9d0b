//! Solves the protrusion-removal least-squares problem (see `zeroset::solvers::problems`) with
//! every solver, prints a table of times (median of `--repeat` runs after a warm-up), iterations,
//! residuals and agreement, and optionally writes the system as MatrixMarket files so that
//! `benches/peers/restoration_peers.py` can solve the very same matrices with scipy.
//!
//! ```text
//! cargo run --release --example restoration_solvers -- --k 16,24,32 [--repeat 5] [--write-mtx DIR] [--csv FILE]
//! ```
//!
//! With `--write-mtx DIR` it also writes each solver's solution as
//! `DIR/restoration_k{k}_x_{solver}.mtx`; `--csv FILE` writes the table as CSV.

#[path = "common/mtx.rs"]
mod mtx;
#[path = "common/timing.rs"]
mod timing;

use std::sync::Arc;
use std::time::Instant;

use zeroset::core::lsq::{LeastSquaresSolver, LsqMatrix};
use zeroset::solvers::kernels::max_abs_diff;
use zeroset::solvers::{self, IterativeParams, problems::protrusion_problem};

struct Args {
    ks: Vec<usize>,
    repeat: usize,
    write_mtx: Option<std::path::PathBuf>,
    csv: Option<std::path::PathBuf>,
    skip_dense: bool,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        ks: vec![16, 24, 32],
        repeat: 5,
        write_mtx: None,
        csv: None,
        skip_dense: false,
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
            "--help" | "-h" => {
                return Err("usage: restoration_solvers [--k 16,24,32] [--repeat 5] [--write-mtx DIR] [--csv FILE] [--skip-dense]".into());
            }
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(args)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let mut csv =
        String::from("k,solver,median_ms,iterations,rel_residual,rel_normal_residual,max_abs_dx\n");
    // The same tolerance the peer script gives scipy.
    let tight = IterativeParams::default().with_tolerance(1e-12);
    println!(
        "{:<6} {:<16} {:>11} {:>7} {:>11} {:>11} {:>11}",
        "k", "solver", "median_ms", "iters", "rel_res", "rel_normal", "max|dx|"
    );
    for &k in &args.ks {
        let p = protrusion_problem(k, 1.0);
        if let Some(dir) = &args.write_mtx {
            write_problem(dir, k, &p)?;
        }
        let n = p.a.ncols();
        // LSQR right-preconditioned by the fast Poisson solve of the mask box: the Laplace
        // rows of this problem are exactly (1/6)·Δ_h on the k³ box.
        let poisson = Arc::new(solvers::DirichletLaplacian::new([k, k, k], 1.0 / 6.0)?);
        let mut list: Vec<(&str, Box<dyn LeastSquaresSolver>)> = vec![
            (
                "lsqr-poisson",
                Box::new(solvers::Lsqr::new(
                    tight.clone().with_preconditioner(poisson),
                )),
            ),
            ("lsqr", Box::new(solvers::Lsqr::new(tight.clone()))),
            ("cgls", Box::new(solvers::Cgls::new(tight.clone()))),
            (
                "pcg-normal",
                Box::new(solvers::Pcg::new(solvers::PcgParams {
                    tol: 1e-12,
                    ..Default::default()
                })),
            ),
            (
                "sparse-cholesky",
                Box::new(solvers::SparseCholesky::default()),
            ),
        ];
        if n <= 15_000 {
            list.push(("sparse-qr", Box::new(solvers::SparseQr::default())));
        }
        if !args.skip_dense && n <= 1000 {
            list.push(("dense-qr", Box::new(solvers::DenseQr::default())));
            list.push(("normal-lu", Box::new(solvers::NormalLu::default())));
        }
        let mut reference: Option<Vec<f64>> = None;
        for (label, solver) in &list {
            let a = LsqMatrix::SparseRow(p.a.as_ref());
            let mut times = Vec::new();
            let mut last = None;
            // One warm-up, then `repeat` timed runs. A fresh solver each time for the sparse
            // Cholesky would hide its analysis cache; keeping it shows the interactive re-solve.
            for r in 0..=args.repeat {
                let t = Instant::now();
                let s = solver.solve(a, &p.b)?;
                if r > 0 {
                    times.push(t.elapsed());
                }
                last = Some(s);
            }
            let s = last.expect("at least one run");
            let dx = match &reference {
                None => {
                    reference = Some(s.x.clone());
                    0.0
                }
                Some(r) => max_abs_diff(r, &s.x),
            };
            let ms = timing::median(times).as_secs_f64() * 1e3;
            csv.push_str(&format!(
                "{k},{},{ms},{},{:e},{:e},{:e}\n",
                label, s.info.iterations, s.info.rel_residual, s.info.rel_normal_residual, dx
            ));
            if let Some(dir) = &args.write_mtx {
                mtx::write_vector(&dir.join(format!("restoration_k{k}_x_{label}.mtx")), &s.x)?;
            }
            println!(
                "{:<6} {:<16} {:>11.2} {:>7} {:>11.2e} {:>11.2e} {:>11.2e}",
                k,
                label,
                ms,
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
