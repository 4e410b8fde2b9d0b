//! Criterion benchmarks of MRAS (`zeroset::bases::mras`, paper 004): the whole fit of a torus
//! sampled on a 120 × 48 parameter grid (5,760 points, radii 1 and 0.4; default options, 3
//! levels), and batched evaluation of the fitted field at 100,000 random points in its cube and
//! on a 97³ vertex grid over it (the meshing hot path: along a grid row only the last coordinate
//! changes, and `values` reuses each cell's contraction over the fixed ones). The full-size runs (the bunny, Open3D alongside) are the example
//! `mras_tables` and `benches/peers/poisson_peers.py`.
//!
//! ```text
//! cargo bench --bench mras
//! ```

#[path = "../examples/common/shapes.rs"]
mod shapes;

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use zeroset::bases::mras::{MrasOptions, fit_mras};
use zeroset::core::field::ScalarField;
use zeroset::core::grid::Grid;

fn mras_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("mras");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(10));
    let (p, n) = shapes::torus(120, 48, 1.0, 0.4);
    let options = MrasOptions::default().max_level(3);
    group.bench_function("fit torus 5760 points, 3 levels", |b| {
        b.iter(|| fit_mras(&p, &n, &options, &|_| true).map(|f| f.field.storage()))
    });
    let field = fit_mras(&p, &n, &options, &|_| true).expect("fit").field;
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let (o, side) = (field.origin(), field.side());
    let points: Vec<[f64; 3]> = (0..100_000)
        .map(|_| std::array::from_fn(|a| o[a] + side * next()))
        .collect();
    let mut out = vec![0.0; points.len()];
    group.bench_function("values 100k points", |b| {
        b.iter(|| {
            field.values(&points, &mut out);
            out[0]
        })
    });
    let bounds = field.bounds().expect("the field's cube");
    let grid = Grid::vertex_centered(bounds, [97; 3]).expect("grid");
    group.bench_function("grid 97^3 samples", |b| b.iter(|| grid.sample(&field)[0]));
    group.finish();
}

criterion_group!(benches, mras_bench);
criterion_main!(benches);
