//! Criterion benchmarks of the tensor crate (`zeroset::tensor`): CP-ALS on planted tensors
//! (30³ rank 10 and 60³ rank 20, noise 1e-6, tolerance 1e-10, SVD initialisation), and
//! singular-value thresholding of a 64 × 4096 unfolding. TensorLy on the same tensors and
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
    group.finish();
}

criterion_group!(benches, tensor_bench);
criterion_main!(benches);
