//! Criterion benchmarks of neural fields (`zeroset::bases::neural`) on the 2-D curve set-up of
//! `PEERS.md` (Jiang–Turk, paper 003 §4.2: r(t) = 0.6 + 0.15 cos 3t, 60 constraints, an MLP
//! 2 → 32 → 32 → 1 with tanh, P = 250 auxiliary points in [−1, 1]², λ = 0.05): 100 Adam steps of
//! each variant (the set-up, one fixed set of auxiliary points, is inside the timing; 3000 steps
//! take about 30× as long), the paper's variant on one thread and on all, and the batched
//! evaluation of a trained field at 65,536 points. PyTorch on the same data and initial weights,
//! in the same run: `benches/peers/neural_peers.py` (it drives `examples/neural_curve.rs`).
//!
//! ```text
//! cargo bench --bench neural
//! ```

#[path = "../examples/common/curve.rs"]
mod curve;

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use zeroset::bases::neural::{NeuralFit, NeuralParams, Variant};
use zeroset::core::Aabb;
use zeroset::core::field::ScalarField;

const STEPS: usize = 100;

fn fit(variant: Variant, steps: usize) -> NeuralFit<2> {
    let domain = Aabb::new([-1.0, -1.0], [1.0, 1.0]).expect("a box");
    NeuralFit::new(NeuralParams::variant(variant).with_steps(steps)).with_domain(domain)
}

fn train_bench(c: &mut Criterion) {
    let (points, targets) = curve::points_and_targets(&curve::sites());
    let mut group = c.benchmark_group("neural_curve_100_steps");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(4));
    for v in Variant::ALL {
        let f = fit(v, STEPS);
        group.bench_with_input(BenchmarkId::new("variant", v.label()), &v, |b, _| {
            b.iter(|| f.fit(&points, &targets).map(|t| t.report.loss))
        });
    }
    let f = fit(Variant::Paper, STEPS);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    for (name, threads) in [
        ("1 thread", 1),
        ("all threads", rayon::current_num_threads()),
    ] {
        group.bench_with_input(BenchmarkId::new("paper", name), &threads, |b, &t| {
            b.iter(|| {
                if t == 1 {
                    one.install(|| f.fit(&points, &targets).map(|t| t.report.loss))
                } else {
                    f.fit(&points, &targets).map(|t| t.report.loss)
                }
            })
        });
    }
    group.finish();

    let field = fit(Variant::Paper, 300)
        .fit(&points, &targets)
        .expect("training")
        .field;
    let probes: Vec<[f64; 2]> = (0..65_536)
        .map(|i| {
            [
                (i % 256) as f64 / 128.0 - 1.0,
                (i / 256) as f64 / 128.0 - 1.0,
            ]
        })
        .collect();
    let mut out = vec![0.0; probes.len()];
    let mut group = c.benchmark_group("neural_eval");
    group.sample_size(20);
    group.bench_function("values 65536", |b| {
        b.iter(|| {
            field.values(&probes, &mut out);
            out[0]
        })
    });
    group.finish();
}

criterion_group!(benches, train_bench);
criterion_main!(benches);
