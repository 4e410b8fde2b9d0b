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

#[path = "../examples/common/rng.rs"]
mod rng;

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use zeroset::bases::rbf::{
    Biharmonic, Constraints, IncrementalFit, IterativeParams, RbfFit, Solver, Triharmonic,
};
use zeroset::core::field::ScalarField;

use rng::SplitMix64;

fn sphere_setup(n: usize) -> Constraints<3> {
    let third = n / 3;
    let on = n - 2 * third;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let unit: Vec<[f64; 3]> = (0..on)
        .map(|k| {
            let z = 1.0 - (2 * k + 1) as f64 / on as f64;
            let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * golden);
            [s * t.cos(), s * t.sin(), z]
        })
        .collect();
    let at = |u: &[f64; 3], r: f64| u.map(|v| 0.5 + r * v);
    let mut c = Constraints::new();
    for u in &unit {
        c.push_value(at(u, 0.35), 0.0);
    }
    for u in &unit[..third] {
        c.push_value(at(u, 0.40), 0.05);
        c.push_value(at(u, 0.30), -0.05);
    }
    c
}

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
