//! Criterion benchmarks of marching cubes (`zeroset::mesh`) on the torus of
//! `examples/mc_timing.rs` and `benches/peers/mc_peers.py` (`R = 0.3`, `r = 0.1`, centred at
//! `(0.5, 0.5, 0.5)`, its exact signed distance) on `n³` vertex grids over `[0, 1]³`, n = 128
//! and 256, in two groups:
//!
//! - `mc extract`: [`marching_cubes`] on samples computed once, outside the timed loop — the
//!   figure `mc_timing` reports and the one compared with scikit-image (normals by central
//!   differences of the samples);
//! - `mc sample+extract`: [`mesh_field`] on the analytic torus — sampling the field on the grid
//!   (parallel), the extraction, and the normals from the field's gradient.
//!
//! Threads: rayon's default (`RAYON_NUM_THREADS`, else one per CPU). Each iteration takes
//! tenths of a second at 256³, so the groups use flat sampling and ten samples.
//!
//! ```text
//! cargo bench --bench mesh
//! RAYON_NUM_THREADS=1 cargo bench --bench mesh     # one thread
//! ```

use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{
    BenchmarkGroup, BenchmarkId, Criterion, SamplingMode, criterion_group, criterion_main,
};
use zeroset::core::analytic::Torus;
use zeroset::core::{Aabb, Grid};
use zeroset::mesh::{McOptions, marching_cubes, mesh_field};

const SIZES: [usize; 2] = [128, 256];

fn torus() -> Torus {
    Torus::new([0.5; 3], 0.3, 0.1)
}

fn grid(n: usize) -> Grid<3> {
    Grid::vertex_centered(Aabb::new([0.0; 3], [1.0; 3]).expect("box"), [n; 3]).expect("grid")
}

/// A group with flat sampling, ten samples and `seconds` of measurement.
fn configure<'a>(c: &'a mut Criterion, name: &str, seconds: u64) -> BenchmarkGroup<'a, WallTime> {
    let mut group = c.benchmark_group(name);
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(seconds));
    group
}

fn extract(c: &mut Criterion) {
    let field = torus();
    let options = McOptions::default();
    let mut group = configure(c, "mc extract", 4);
    for n in SIZES {
        let grid = grid(n);
        let values = grid.sample(&field); // outside the timed loop
        group.bench_with_input(BenchmarkId::new("torus", format!("{n}^3")), &n, |b, _| {
            b.iter(|| {
                marching_cubes(&grid, &values, 0.0, &options)
                    .expect("marching cubes")
                    .num_triangles()
            })
        });
    }
    group.finish();
}

fn sample_and_extract(c: &mut Criterion) {
    let field = torus();
    let options = McOptions::default();
    // ~0.5 s per iteration at 256³ on 2 cores: ten of them need more than 4 s.
    let mut group = configure(c, "mc sample+extract", 8);
    for n in SIZES {
        let grid = grid(n);
        group.bench_with_input(BenchmarkId::new("torus", format!("{n}^3")), &n, |b, _| {
            b.iter(|| {
                mesh_field(&field, &grid, 0.0, &options)
                    .expect("mesh_field")
                    .num_triangles()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, extract, sample_and_extract);
criterion_main!(benches);
