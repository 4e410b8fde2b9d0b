//! Criterion benchmarks of the fast multipole evaluation (`zeroset::bases::rbf::fmm`) and the
//! two-step signed marching cubes, on the sphere set-up of `benches/rbf.rs` (3,000 centres,
//! kernel `r`): the operators' precomputation, the build of the expansions, evaluation at
//! 10,000 points against the direct sum, and signed against plain marching cubes on a 64³
//! grid. The issue-size runs (10,000 bunny centres × 100,000 targets, 256³ grids) are the
//! examples `fmm_timing`, `fmm_error` and `smc_timing`; the NumPy peer is
//! `benches/peers/fmm_peers.py`.
//!
//! ```text
//! cargo bench --bench fmm
//! ```

#[path = "../examples/common/rbf_sphere.rs"]
mod rbf_sphere;
#[path = "../examples/common/rng.rs"]
mod rng;

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use zeroset::bases::rbf::fmm::{FmmField, FmmOptions, OrderPair};
use zeroset::bases::rbf::{Biharmonic, RbfFit};
use zeroset::core::field::ScalarField;
use zeroset::core::{Aabb, Centering, Grid};
use zeroset::mesh::signed::{CoarseStep, SmcOptions, signed_marching_cubes};
use zeroset::mesh::{McOptions, mesh_field};

use rbf_sphere::sphere_setup;
use rng::SplitMix64;

fn fmm_bench(c: &mut Criterion) {
    let field = RbfFit::new(Biharmonic)
        .fit(&sphere_setup(3000))
        .expect("sphere fit")
        .field;
    let mut rng = SplitMix64(5);
    let targets: Vec<[f64; 3]> = (0..10_000)
        .map(|_| std::array::from_fn(|_| rng.unit()))
        .collect();
    let mut out = vec![0.0; targets.len()];
    let mut group = c.benchmark_group("fmm");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    for p in [4usize, 6, 8] {
        let options = FmmOptions::new(p).with_expected_points(targets.len());
        group.bench_with_input(BenchmarkId::new("operators+build", p), &p, |b, _| {
            b.iter(|| FmmField::new(&field, &options).map(|f| f.report().cells))
        });
        let ops = FmmField::operators(field.kernel(), &options).expect("operators");
        let fast = FmmField::with_operators(&field, &options, ops.clone()).expect("fmm");
        group.bench_with_input(
            BenchmarkId::new("build (shared operators)", p),
            &p,
            |b, _| {
                b.iter(|| {
                    FmmField::with_operators(&field, &options, ops.clone())
                        .map(|f| f.report().cells)
                })
            },
        );
        group.bench_with_input(BenchmarkId::new("evaluate 10k", p), &p, |b, _| {
            b.iter(|| fast.values(&targets, &mut out))
        });
    }
    group.bench_function("direct sum 10k", |b| {
        b.iter(|| field.values(&targets, &mut out))
    });
    group.finish();
}

fn smc_bench(c: &mut Criterion) {
    let field = RbfFit::new(Biharmonic)
        .fit(&sphere_setup(3000))
        .expect("sphere fit")
        .field;
    let pair = OrderPair::new(&field, &FmmOptions::new(5), &FmmOptions::new(9), 2048, 10.0)
        .expect("orders");
    let grid = Grid::new(
        Aabb::new([0.1; 3], [0.9; 3]).expect("box"),
        [65; 3],
        Centering::Vertex,
    )
    .expect("grid");
    let options = McOptions::default().with_normals(false);
    let mut group = c.benchmark_group("smc");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(8));
    for (name, step) in [
        ("signed MC 64^3 (p 5, P 9), blocks", CoarseStep::Blocks),
        (
            "signed MC 64^3 (p 5, P 9), every vertex",
            CoarseStep::EveryVertex,
        ),
    ] {
        let smc = SmcOptions::from(options).with_coarse_step(step);
        group.bench_function(name, |b| {
            b.iter(|| {
                signed_marching_cubes(&pair.low, &pair.high, &grid, 0.0, pair.margin, &smc, None)
                    .map(|(m, _)| m.num_triangles())
            })
        });
    }
    group.bench_function("plain MC 64^3 (P 9)", |b| {
        b.iter(|| mesh_field(&pair.high, &grid, 0.0, &options).map(|m| m.num_triangles()))
    });
    group.finish();
}

criterion_group!(benches, fmm_bench, smc_bench);
criterion_main!(benches);
