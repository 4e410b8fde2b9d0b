//! `zeroset demo`: the main job on built-in sample data. It describes the bundled point cloud
//! and then solves a restoration-shaped least-squares problem with every solver, printing how
//! long each took, how many iterations, the residuals, and how far each answer is from the
//! sparse-QR reference — the solvers must agree.

use std::sync::Arc;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use zeroset_field_core::lsq::{LeastSquaresSolver, LsqMatrix};
use zeroset_solvers::kernels::max_abs_diff;
use zeroset_solvers::problems::protrusion_problem;
use zeroset_solvers::{
    Cgls, DenseQr, DirichletLaplacian, IterativeParams, Lsqr, NormalLu, Pcg, PcgParams,
    SparseCholesky, SparseQr,
};

/// The bundled sample (Stanford bunny, 2,000 oriented points; see `samples/README.md`).
const SAMPLE: &str = include_str!("../../../samples/bunny_2k.xyzn");

/// Shown after `zeroset demo --help`.
pub const EXAMPLES: &str = "\
Examples:
  zeroset demo                 the bundled bunny sample, then all solvers at k = 16
  zeroset demo --k 24          a bigger restoration problem (13,824 unknowns)
  zeroset demo --k 8 --quiet   small enough for the dense solvers too; no progress spinner";

/// Dense solvers are run only up to this many unknowns (they densify `A`).
const DENSE_LIMIT: usize = 1500;

/// Arguments of `zeroset demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Mask size of the restoration problem: k³ unknowns, k³ + k² equations.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(2..=64))]
    pub k: u32,

    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs the demo.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    describe_sample()?;
    solve_all(args.k as usize, args.quiet)
}

fn describe_sample() -> anyhow::Result<()> {
    // The readers take paths; give them the bundled sample as a file.
    let dir = std::env::temp_dir().join(format!("zeroset-demo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join("bunny_2k.xyzn");
    std::fs::write(&path, SAMPLE).with_context(|| format!("writing {}", path.display()))?;
    println!("== the bundled sample (samples/bunny_2k.xyzn) ==");
    let result = crate::info::run(&crate::info::InfoArgs {
        file: path.clone(),
        format: None,
    });
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn solve_all(k: usize, quiet: bool) -> anyhow::Result<()> {
    let p = protrusion_problem(k, 1.0);
    let (m, n) = (p.a.nrows(), p.a.ncols());
    println!();
    println!("== restoration least squares: {} ==", p.name);
    println!(
        "   grid {}³ cells on [-1,1]³, f = sphere SDF r=0.6, mask = central {k}³ box,",
        2 * k
    );
    println!(
        "   {m} equations (Laplace + Neumann rows), {n} unknowns, {} non-zeros",
        p.a.val().len()
    );
    let tight = IterativeParams::default().with_tolerance(1e-12);
    let poisson = Arc::new(DirichletLaplacian::new([k, k, k], 1.0 / 6.0)?);
    let mut solvers: Vec<(&str, Box<dyn LeastSquaresSolver>)> = vec![
        ("sparse-qr", Box::new(SparseQr::default())),
        ("sparse-cholesky", Box::new(SparseCholesky::default())),
        ("lsqr", Box::new(Lsqr::new(tight.clone()))),
        (
            "lsqr + poisson",
            Box::new(Lsqr::new(tight.clone().with_preconditioner(poisson))),
        ),
        ("cgls", Box::new(Cgls::new(tight))),
        (
            "pcg-normal",
            Box::new(Pcg::new(PcgParams {
                tol: 1e-12,
                ..Default::default()
            })),
        ),
    ];
    if n <= DENSE_LIMIT {
        solvers.push(("dense-qr", Box::new(DenseQr::default())));
        solvers.push(("normal-lu", Box::new(NormalLu::default())));
    }
    println!();
    println!(
        "{:<16} {:>10} {:>7} {:>11} {:>11} {:>13}",
        "solver", "time_ms", "iters", "rel_res", "rel_normal", "max|x - x_qr|"
    );
    let spinner = if quiet {
        ProgressBar::hidden()
    } else {
        let s = ProgressBar::new_spinner();
        s.set_style(ProgressStyle::with_template("{spinner} {msg}").expect("valid template"));
        s.enable_steady_tick(std::time::Duration::from_millis(100));
        s
    };
    let mut reference: Option<Vec<f64>> = None;
    for (label, solver) in &solvers {
        spinner.set_message(format!("solving with {label}"));
        let start = Instant::now();
        let s = solver
            .solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b)
            .with_context(|| format!("{label} failed"))?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let diff = match &reference {
            None => {
                reference = Some(s.x.clone());
                0.0
            }
            Some(r) => max_abs_diff(r, &s.x),
        };
        spinner.suspend(|| {
            println!(
                "{:<16} {:>10.1} {:>7} {:>11.2e} {:>11.2e} {:>13.2e}",
                label, ms, s.info.iterations, s.info.rel_residual, s.info.rel_normal_residual, diff
            )
        });
    }
    spinner.finish_and_clear();
    if n > DENSE_LIMIT {
        println!("(dense-qr and normal-lu skipped above {DENSE_LIMIT} unknowns; try --k 11)");
    }
    Ok(())
}
