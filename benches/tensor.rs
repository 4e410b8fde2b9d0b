//! Criterion benchmarks of the tensor crate (`zeroset::tensor`) and of ADMM
//! (`zeroset::solvers::admm`): CP-ALS on planted tensors (30³ rank 10 and 60³ rank 20, noise
//! 1e-6, tolerance 1e-10, SVD initialisation); singular-value thresholding of a 64 × 4096
//! unfolding; and ADMM on the MRAS energy of a 16³ coefficient block (4096 unknowns, a dense
//! SPD `H`, λ = 0.02, γᵢ = 1/3, η = 1), run for 1 and for 11 iterations: the first includes
//! the one Cholesky factorisation, the difference over 10 is the cost of one iteration (three
//! SVTs of 16 × 256 unfoldings and two triangular solves). TensorLy on the same tensors and
//! initial factors: `benches/peers/tensor_peers.py`.
//!
//! ```text
//! cargo bench --bench tensor
//! ```

#[path = "../examples/common/rng.rs"]
mod rng;

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use faer::Mat;
use zeroset::solvers::admm::{AdmmOptions, ProxTerm, TraceNormTerm, admm};
use zeroset::tensor::{CpOptions, cp_als, svt};

fn tensor_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("tensor");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    for (n, rank) in [(30usize, 10usize), (60, 20)] {
        let x = rng::planted_tensor([n; 3], rank, 1e-6, 7).expect("planted tensor");
        let options = CpOptions::new(rank).with_tol(1e-10).with_max_iter(1000);
        group.bench_with_input(
            BenchmarkId::new("cp_als", format!("{n}^3 r{rank}")),
            &n,
            |b, _| b.iter(|| cp_als(&x, &options, |_| true).map(|f| f.iterations)),
        );
    }
    let mut g = rng::SplitMix64(3);
    let m = Mat::from_fn(64, 4096, |_, _| g.normal());
    group.bench_function("svt 64x4096", |b| {
        b.iter(|| svt(m.as_ref(), 40.0).map(|(_, rank)| rank))
    });
    // ADMM on a 16³ block: H = 2I + a symmetric band (SPD), b from a smooth low-rank tensor.
    let n = 16 * 16 * 16;
    let h = Mat::from_fn(n, n, |i, j| match i.abs_diff(j) {
        0 => 2.5,
        1 | 16 | 256 => -0.2,
        _ => 0.0,
    });
    let b: Vec<f64> = (0..n)
        .map(|l| {
            let (i, j, k) = ((l / 256) as f64, ((l / 16) % 16) as f64, (l % 16) as f64);
            (0.3 * i).sin() * (0.2 * j).cos() + 0.1 * k * (0.1 * i).cos() + 0.01 * g.normal()
        })
        .collect();
    let terms = TraceNormTerm::mras_terms([16, 16, 16], 0.02).expect("terms");
    let refs: Vec<&dyn ProxTerm> = terms.iter().map(|t| t as &dyn ProxTerm).collect();
    for iterations in [1usize, 11] {
        let options = AdmmOptions::default()
            .max_iter(iterations)
            .eps_abs(0.0)
            .eps_rel(0.0);
        group.bench_with_input(
            BenchmarkId::new("admm 16^3 iterations", iterations),
            &iterations,
            |bench, _| bench.iter(|| admm(h.as_ref(), &b, &refs, &options).map(|s| s.iterations)),
        );
    }
    group.finish();
}

criterion_group!(benches, tensor_bench);
criterion_main!(benches);
