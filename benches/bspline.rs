//! Criterion benchmarks of the B-spline prefilter and evaluation — the set-up `PEERS.md` times
//! scipy on: `spline_filter(order=2, mode='mirror')` of an `n³` grid (here
//! `Boundary::WholeSample`, the same boundary) and `map_coordinates(prefilter=False)` at 1M
//! random points (here continuous indices, uniform in `[0, n−1]³`, on a 128³ grid). For the ratio
//! against scipy on the same data in the same run, use `examples/spline_timing.rs` with a peer
//! script.
//!
//! ```text
//! cargo bench --bench bspline                # all
//! cargo bench --bench bspline -- prefilter   # one group
//! ```

#[path = "../examples/common/rng.rs"]
mod rng;

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use zeroset::bases::bspline::{BSplineField, Boundary, Degree, prefilter};
use zeroset::core::geometry::Aabb;
use zeroset::core::grid::Grid;

use rng::SplitMix64;

fn grid_values(n: usize) -> Vec<f64> {
    let mut rng = SplitMix64(42);
    (0..n * n * n)
        .map(|l| {
            let (i, j, k) = ((l / (n * n)) as f64, ((l / n) % n) as f64, (l % n) as f64);
            (0.11 * i).sin() * (0.07 * j).cos() + (0.05 * k + 0.02 * i).sin() + 0.1 * rng.unit()
        })
        .collect()
}

fn prefilter_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("prefilter quadratic mirror");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    for n in [128usize, 256] {
        let data = grid_values(n);
        group.bench_with_input(
            BenchmarkId::from_parameter(format!("{n}^3")),
            &n,
            |b, &n| {
                b.iter_batched_ref(
                    || data.clone(),
                    |d| prefilter(d, [n, n, n], Degree::Quadratic, Boundary::WholeSample).unwrap(),
                    criterion::BatchSize::LargeInput,
                )
            },
        );
    }
    group.finish();
}

fn evaluation_bench(c: &mut Criterion) {
    let n = 128;
    let points = 1_000_000;
    let mut data = grid_values(n);
    prefilter(
        &mut data,
        [n, n, n],
        Degree::Quadratic,
        Boundary::WholeSample,
    )
    .unwrap();
    let grid = Grid::cell_centered(Aabb::new([0.0; 3], [1.0; 3]).unwrap(), [n, n, n]).unwrap();
    let field =
        BSplineField::from_coefficients(grid, data, Degree::Quadratic, Boundary::WholeSample)
            .unwrap();
    let mut rng = SplitMix64(43);
    let hi = (n - 1) as f64;
    let indices: Vec<[f64; 3]> = (0..points)
        .map(|_| std::array::from_fn(|_| hi * rng.unit()))
        .collect();
    let mut out = vec![0.0; points];

    let mut group = c.benchmark_group("evaluate quadratic 128^3");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    group.bench_function(BenchmarkId::new("indices", "1M random"), |b| {
        b.iter(|| field.values_at_indices(&indices, &mut out))
    });
    group.finish();
}

criterion_group!(benches, prefilter_bench, evaluation_bench);
criterion_main!(benches);
