//! Criterion benchmarks of RBF fitting and evaluation on the sphere set-up of `PEERS.md`
//! (centre 0.5, radius 0.35; `N − 2⌊N/3⌋` points on it and `⌊N/3⌋` at `±0.05` along the
//! normals): the fit with each solver, evaluation at 10,000 points, and adding one constraint
//! to a solved fit. For ratios against scipy on the same data in the same run, use
//! `benches/peers/rbf_peers.py` (it drives `examples/rbf_timing.rs`).
//!
//! ```text
//! cargo bench --bench rbf              # all
//! cargo bench --bench rbf -- fit       # one group
//! ```

#[path = "../examples/common/rbf_sphere.rs"]
mod rbf_sphere;
#[path = "../examples/common/rng.rs"]
mod rng;

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use zeroset::bases::rbf::{
    Biharmonic, Constraints, IncrementalFit, IterativeParams, RbfFit, Solver, Triharmonic,
};
use zeroset::core::field::ScalarField;

use rbf_sphere::sphere_setup;
use rng::SplitMix64;

fn fit_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("fit");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(8));
    for n in [1000usize, 3000] {
        let constraints = sphere_setup(n);
        let cases: [(&str, Solver); 3] = [
            ("r3 dense", Solver::Dense),
            ("r3 mixed", Solver::MixedPrecision),
            ("r iterative", Solver::Iterative(IterativeParams::default())),
        ];
        for (name, solver) in cases {
            group.bench_with_input(BenchmarkId::new(name, n), &constraints, |b, c| {
                b.iter(|| {
                    if name.starts_with("r3") {
                        RbfFit::new(Triharmonic)
                            .with_solver(solver.clone())
                            .fit(c)
                            .map(|f| f.report.max_residual)
                    } else {
                        RbfFit::new(Biharmonic)
                            .with_solver(solver.clone())
                            .fit(c)
                            .map(|f| f.report.max_residual)
                    }
                    .expect("the sphere set-up fits")
                })
            });
        }
    }
    group.finish();
}

fn eval_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("evaluate 10k points");
    group.sample_size(10);
    let mut rng = SplitMix64(7);
    let points: Vec<[f64; 3]> = (0..10_000)
        .map(|_| [rng.unit(), rng.unit(), rng.unit()])
        .collect();
    for n in [1000usize, 6000] {
        let fitted = RbfFit::new(Biharmonic)
            .fit(&sphere_setup(n))
            .expect("the sphere set-up fits");
        let mut out = vec![0.0; points.len()];
        group.bench_function(BenchmarkId::from_parameter(n), |b| {
            b.iter(|| fitted.field.values(&points, &mut out))
        });
    }
    group.finish();
}

fn incremental_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("add one constraint");
    group.sample_size(20);
    for n in [1000usize, 3000] {
        let fit = RbfFit::new(Triharmonic);
        let mut inc = IncrementalFit::new(&fit, &sphere_setup(n)).expect("the sphere set-up fits");
        let mut extra = Constraints::new();
        extra.push_value([0.5, 0.5, 0.5], -0.35);
        group.bench_function(BenchmarkId::from_parameter(n), |b| {
            b.iter(|| {
                inc.add(&extra).expect("a new point");
                inc.remove_last()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, fit_bench, eval_bench, incremental_bench);
criterion_main!(benches);
