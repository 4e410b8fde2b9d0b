//! Criterion benchmarks of protrusion removal through `zeroset::restore` — assembly and solve
//! of the least-squares system, in place on the grid's samples (sampling the field excluded) —
//! on the set-up of `PEERS.md`: `2k` cells per axis on `[−1, 1]³`, the sphere of radius 0.6,
//! the central `k³` mask, Neumann face `+z`, α = 1. The issue's bars: k = 64 under 0.1 s,
//! k = 128 under 1 s. For ratios against scipy on the same system, run
//! `benches/peers/restoration_bar.py`.
//!
//! ```text
//! cargo bench --bench restore                # all
//! cargo bench --bench restore -- k=64        # one size
//! ```

use std::sync::Arc;
use std::time::Duration;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use zeroset::core::analytic::Sphere;
use zeroset::core::geometry::Aabb;
use zeroset::core::grid::Grid;
use zeroset::core::mask::{BoxMask, Face, Side};
use zeroset::restore::protrusion::{Protrusion, Solver};
use zeroset::solvers::SparseCholesky;

fn protrusion(c: &mut Criterion) {
    for k in [32usize, 64, 128] {
        let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [2 * k; 3]).unwrap();
        let f = grid.sample(&Sphere::new([0.0; 3], 0.6));
        let mask = BoxMask::from_indices(&grid, [k / 2; 3], [k / 2 + k - 1; 3]).unwrap();
        let mut group = c.benchmark_group(format!("protrusion k={k}"));
        group.sample_size(10);
        group.warm_up_time(Duration::from_secs(1));
        group.measurement_time(Duration::from_secs(if k >= 128 { 15 } else { 5 }));
        let mut solvers = vec![("separable", Solver::Separable)];
        if k <= 64 {
            solvers.push((
                "lsqr+poisson",
                Solver::PreconditionedLsqr { tolerance: 1e-12 },
            ));
        }
        if k <= 32 {
            solvers.push((
                "sparse-cholesky",
                Solver::General(Arc::new(SparseCholesky::default())),
            ));
        }
        for (name, solver) in solvers {
            let params = Protrusion::new(Face::new(2, Side::Upper))
                .with_alpha(1.0)
                .with_solver(solver);
            group.bench_function(name, |b| {
                b.iter_batched_ref(
                    || f.clone(),
                    |samples| params.restore_in_place(&grid, samples, &mask).unwrap(),
                    BatchSize::LargeInput,
                )
            });
        }
        group.finish();
    }
}

criterion_group!(benches, protrusion);
criterion_main!(benches);
