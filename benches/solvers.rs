//! Criterion benchmarks of the least-squares solvers on the restoration problem
//! (`zeroset::solvers::problems::protrusion_problem`) at k = 16, 24, 32 (4,096 / 13,824 /
//! 32,768 unknowns) — the set-up `PEERS.md` times scipy on. For the ratio against scipy on the
//! same matrices in the same run, use `benches/peers/restoration_peers.py`.
//!
//! ```text
//! cargo bench --bench solvers            # all
//! cargo bench --bench solvers -- k=32    # one size
//! ```

use std::sync::Arc;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use zeroset::core::lsq::{LeastSquaresSolver, LsqMatrix};
use zeroset::solvers::problems::protrusion_problem;
use zeroset::solvers::{
    Cgls, DirichletLaplacian, IterativeParams, Lsqr, Pcg, PcgParams, SparseCholesky,
};

fn restoration(c: &mut Criterion) {
    for k in [16usize, 24, 32] {
        let p = protrusion_problem(k, 1.0);
        let mut group = c.benchmark_group(format!("restoration k={k}"));
        group.sample_size(10);
        group.warm_up_time(Duration::from_secs(1));
        group.measurement_time(Duration::from_secs(if k >= 32 { 20 } else { 8 }));
        let tight = IterativeParams::default().with_tolerance(1e-12);
        let poisson = Arc::new(DirichletLaplacian::new([k, k, k], 1.0 / 6.0).unwrap());
        let solvers: Vec<(&str, Box<dyn LeastSquaresSolver>)> = vec![
            (
                "lsqr+poisson",
                Box::new(Lsqr::new(tight.clone().with_preconditioner(poisson))),
            ),
            ("lsqr", Box::new(Lsqr::new(tight.clone()))),
            ("cgls", Box::new(Cgls::new(tight))),
            (
                "pcg-normal",
                Box::new(Pcg::new(PcgParams {
                    tol: 1e-12,
                    ..Default::default()
                })),
            ),
            // Repeated solves reuse the symbolic analysis: this times the re-solve of an
            // interactive session (new values, same pattern).
            (
                "sparse-cholesky (cached analysis)",
                Box::new(SparseCholesky::default()),
            ),
        ];
        for (name, solver) in &solvers {
            group.bench_function(BenchmarkId::new(*name, k), |bench| {
                bench.iter(|| {
                    solver
                        .solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b)
                        .expect("restoration problem has full rank")
                })
            });
        }
        // Sparse Cholesky from scratch: AᵀA pattern, ordering and symbolic factor each time.
        group.bench_function(BenchmarkId::new("sparse-cholesky (fresh)", k), |bench| {
            bench.iter(|| {
                SparseCholesky::default()
                    .solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b)
                    .expect("full rank")
            })
        });
        group.finish();
    }
}

criterion_group!(benches, restoration);
criterion_main!(benches);
