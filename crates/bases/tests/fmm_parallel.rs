//! Fast multipole fields built inside a caller's parallel loop: the operator cache held its
//! lock while building operators with rayon, and a worker that stole an outer job asking for
//! the same operators waited for that lock forever (a reviewer's loop of 8 fields on 4
//! threads hung in 4 of 8 runs; this test, on the old code, in 3 of 6). Its own test binary, so
//! that the operators are built here.

use std::sync::mpsc;
use std::time::Duration;

use rayon::prelude::*;
use zeroset_bases::rbf::fmm::{FmmField, FmmOptions};
use zeroset_bases::rbf::{Biharmonic, Constraints, Offset, RbfFit};
use zeroset_field_core::PointCloud;
use zeroset_field_core::field::ScalarField;

#[path = "../../../examples/common/shapes.rs"]
mod shapes;

#[test]
fn fmm_fields_built_in_parallel_do_not_deadlock() {
    let fields: Vec<_> = (0..8)
        .map(|i| {
            let (points, normals) = shapes::sphere(200 + 10 * i, 1.0 + 0.1 * i as f64);
            let cloud = PointCloud::with_normals(points, normals).expect("cloud");
            let (c, _) = Constraints::off_surface(&cloud, Offset::default()).expect("constraints");
            RbfFit::new(Biharmonic).fit(&c).expect("fit").field
        })
        .collect();
    let (done, finished) = mpsc::channel();
    std::thread::spawn(move || {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .expect("pool");
        // A new order each round: its operators are built, not found in the cache.
        for order in [6, 7, 8, 9, 10, 11] {
            let values: Vec<f64> = pool.install(|| {
                fields
                    .par_iter()
                    .enumerate()
                    .map(|(i, f)| {
                        if i % 2 == 1 {
                            // Other work in the same loop: its worker then idles, and steals
                            // part of an operator build.
                            return -(0..2_000_000u64).map(|k| (k as f64).sqrt()).sum::<f64>();
                        }
                        let fast = FmmField::new(f, &FmmOptions::new(order).with_leaf_size(8))
                            .expect("fmm");
                        fast.value(&[0.0; 3])
                    })
                    .collect()
            });
            assert!(values.iter().all(|v| *v < 0.0), "{values:?}");
        }
        done.send(()).expect("send");
    });
    finished
        .recv_timeout(Duration::from_secs(300))
        .expect("FMM fields built in parallel did not finish in 300 s: a deadlock");
}
