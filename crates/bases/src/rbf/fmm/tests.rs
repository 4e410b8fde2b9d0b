use super::*;
use crate::rbf::{Biharmonic, Constraints, RbfFit, ThinPlate, Triharmonic};

/// A bumpy closed surface (a sphere of radius `0.5 (1 + 0.2 sin 3θ cos 2φ)`) with values 0 on
/// it and ±0.05 along the radius: `n` on-surface points.
fn blob(n: usize) -> Constraints<3> {
    let mut c = Constraints::new();
    for k in 0..n {
        let z = -1.0 + (2 * k + 1) as f64 / n as f64;
        let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399_963_229_728_653);
        let u = [s * t.cos(), s * t.sin(), z];
        let r = 0.5 * (1.0 + 0.2 * (3.0 * z.acos()).sin() * (2.0 * t).cos());
        let p = u.map(|v| r * v + 0.1);
        c.push_value(p, 0.0);
        if k % 3 == 0 {
            c.push_value(std::array::from_fn(|a| p[a] + 0.05 * u[a]), 0.05);
            c.push_value(std::array::from_fn(|a| p[a] - 0.05 * u[a]), -0.05);
        }
    }
    c
}

fn fit<K: Kernel + Clone>(kernel: K, c: &Constraints<3>) -> RbfField<K, 3> {
    RbfFit::new(kernel).fit(c).expect("fit").field
}

/// Deterministic points filling `b` enlarged by `grow` on every side.
fn probes(b: &Aabb<3>, count: usize, grow: f64) -> Vec<Point<3>> {
    let (lo, hi) = (b.min(), b.max());
    (0..count)
        .map(|i| {
            let f = |m: f64| ((i as f64 + 0.5) * m).fract();
            let u = [f(0.754_877_666), f(0.569_840_291), f(0.430_159_709)];
            std::array::from_fn(|a| {
                let span = hi[a] - lo[a];
                lo[a] - grow * span + u[a] * span * (1.0 + 2.0 * grow)
            })
        })
        .collect()
}

/// `max |fast − exact| / max |exact|` over `points`.
fn relative_error<F: ScalarField<3>, G: ScalarField<3>>(
    fast: &F,
    exact: &G,
    points: &[Point<3>],
) -> f64 {
    let (mut a, mut b) = (vec![0.0; points.len()], vec![0.0; points.len()]);
    fast.values(points, &mut a);
    exact.values(points, &mut b);
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / scale
}

#[test]
fn the_error_falls_with_the_order_for_r_and_r3() {
    let c = blob(900);
    let points = probes(&Aabb::new([-0.5; 3], [0.7; 3]).expect("box"), 3000, 0.0);
    let r = fit(Biharmonic, &c);
    let r3 = fit(Triharmonic, &c);
    for (name, errors) in [
        (
            "r",
            [3, 5, 7, 9].map(|p| {
                let f = FmmField::new(&r, &FmmOptions::new(p).with_leaf_size(20)).expect("fmm");
                relative_error(&f, &r, &points)
            }),
        ),
        (
            "r3",
            [3, 5, 7, 9].map(|p| {
                let f = FmmField::new(&r3, &FmmOptions::new(p).with_leaf_size(20)).expect("fmm");
                relative_error(&f, &r3, &points)
            }),
        ),
    ] {
        eprintln!("{name}: p = 3, 5, 7, 9: {errors:?}");
        for w in errors.windows(2) {
            assert!(w[1] < 0.5 * w[0], "{name}: {errors:?}");
        }
        assert!(errors[3] < 1e-5, "{name}: {errors:?}");
    }
}

#[test]
fn gradients_match_the_direct_sum() {
    let c = blob(600);
    let exact = fit(Triharmonic, &c);
    let fast = FmmField::new(&exact, &FmmOptions::new(8).with_leaf_size(16)).expect("fmm");
    let points = probes(&exact.bounds().expect("bounds"), 300, 0.3);
    let scale = points
        .iter()
        .map(|x| exact.gradient(x).iter().fold(0.0f64, |m, v| m.max(v.abs())))
        .fold(0.0, f64::max);
    for x in &points {
        let (g, h) = (fast.gradient(x), exact.gradient(x));
        for a in 0..3 {
            // The derivative of the interpolant loses about p² of the value's accuracy.
            assert!((g[a] - h[a]).abs() < 1e-4 * scale, "{x:?}: {g:?} vs {h:?}");
        }
    }
}

/// `n` points on the unit sphere with value 0 and gradient the outward normal.
fn hermite_sphere(n: usize) -> Constraints<3> {
    let mut c = Constraints::new();
    for k in 0..n {
        let z = -1.0 + (2 * k + 1) as f64 / n as f64;
        let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399_963_229_728_653);
        let u = [s * t.cos(), s * t.sin(), z];
        c.push_value(u, 0.0);
        c.push_gradient(u, u);
    }
    c
}

#[test]
fn hermite_fields_match_the_direct_sum() {
    let exact = fit(Triharmonic, &hermite_sphere(300));
    let fast = FmmField::new(&exact, &FmmOptions::new(9).with_leaf_size(12)).expect("fmm");
    assert!(fast.dipoles.is_some());
    let points = probes(&exact.bounds().expect("bounds"), 2000, 0.2);
    let e = relative_error(&fast, &exact, &points);
    assert!(e < 1e-6, "{e:e}");
    for x in points.iter().step_by(50) {
        let (g, h) = (fast.gradient(x), exact.gradient(x));
        for a in 0..3 {
            assert!(
                (g[a] - h[a]).abs() < 1e-5 * (1.0 + h[a].abs()),
                "{g:?} {h:?}"
            );
        }
    }
}

#[test]
fn points_outside_the_root_cube_are_exact_too() {
    let c = blob(500);
    let exact = fit(Biharmonic, &c);
    let fast = FmmField::new(&exact, &FmmOptions::new(8).with_leaf_size(16)).expect("fmm");
    // From just outside the bounds to five diameters away.
    let points = probes(&exact.bounds().expect("bounds"), 2000, 5.0);
    let outside = points
        .iter()
        .filter(|x| fast.tree.leaf_of(x).is_none())
        .count();
    assert!(outside > 1500, "{outside}");
    let e = relative_error(&fast, &exact, &points);
    assert!(e < 1e-5, "{e:e}");
    let x = [3.0, -2.0, 1.0];
    let (g, h) = (fast.gradient(&x), exact.gradient(&x));
    for a in 0..3 {
        assert!((g[a] - h[a]).abs() < 1e-5 * (1.0 + h[a].abs()));
    }
}

/// The default leaf size balances the near field against M2L once many points per source are
/// expected (`√(28 N p⁵ / E)`), keeps the order's default for few, and yields to an explicit one.
#[test]
fn many_expected_points_make_the_default_leaves_smaller() {
    let grid = FmmOptions::new(6).with_expected_points(13_577_824);
    assert_eq!(grid.leaf_size_for(10_002), 13);
    let bar = FmmOptions::new(8).with_expected_points(100_000);
    assert_eq!(bar.leaf_size_for(10_002), 256, "10⁵ points keep p³/2");
    assert_eq!(FmmOptions::new(10).leaf_size_for(10_002), 500);
    assert_eq!(FmmOptions::new(4).leaf_size_for(10), 64);
    let tiny = FmmOptions::new(4).with_expected_points(1 << 40);
    assert_eq!(tiny.leaf_size_for(100), 8, "never below 8");
    assert_eq!(grid.with_leaf_size(40).leaf_size_for(10_002), 40);
}

/// Expected points move far sources from cells' expansions (P2L) to the points' direct sums:
/// fewer P2L evaluations, the same accuracy (and gradients).
#[test]
fn expected_points_change_the_cost_not_the_accuracy() {
    let c = blob(2000);
    let exact = fit(Biharmonic, &c);
    let points = probes(&exact.bounds().expect("bounds"), 3000, 0.0);
    let options = FmmOptions::new(7).with_leaf_size(24);
    let plain = FmmField::new(&exact, &options).expect("fmm");
    let hinted = FmmField::new(&exact, &options.with_expected_points(3000)).expect("fmm");
    let p2l = |f: &FmmField<Biharmonic>| -> usize {
        f.tree
            .p2l
            .iter()
            .flatten()
            .map(|&s| f.cell(s).count())
            .sum()
    };
    assert!(
        p2l(&hinted) < p2l(&plain),
        "{} vs {}",
        p2l(&hinted),
        p2l(&plain)
    );
    let (a, b) = (
        relative_error(&plain, &exact, &points),
        relative_error(&hinted, &exact, &points),
    );
    assert!(a < 1e-4 && b < 1e-4 && b < 2.0 * a + 1e-12, "{a:e} {b:e}");
    for x in points.iter().step_by(100) {
        let (g, h) = (hinted.gradient(x), exact.gradient(x));
        for k in 0..3 {
            assert!(
                (g[k] - h[k]).abs() < 1e-3 * (1.0 + h[k].abs()),
                "{g:?} {h:?}"
            );
        }
    }
}

/// Both compressions of the M2L operators reach the accuracy of the order, for `r`, `r³` and
/// the thin plate (operators per level), and agree with each other to it; operators built for
/// one are refused for the other.
#[test]
fn both_m2l_compressions_match_the_direct_sum() {
    let c = blob(1500);
    let r = fit(Biharmonic, &c);
    let r3 = fit(Triharmonic, &c);
    let tps = fit(ThinPlate, &c);
    let points = probes(&r.bounds().expect("bounds"), 2000, 0.1);
    for p in [6, 8] {
        let options = |m| FmmOptions::new(p).with_leaf_size(24).with_compression(m);
        let errors = |m: M2lCompression| {
            [
                relative_error(&FmmField::new(&r, &options(m)).expect("r"), &r, &points),
                relative_error(&FmmField::new(&r3, &options(m)).expect("r3"), &r3, &points),
                relative_error(
                    &FmmField::new(&tps, &options(m)).expect("tps"),
                    &tps,
                    &points,
                ),
            ]
        };
        let (per, shared) = (
            errors(M2lCompression::PerOperator),
            errors(M2lCompression::SharedBasis),
        );
        eprintln!("p = {p}: per operator {per:?}, shared basis {shared:?}");
        for (a, b) in per.iter().zip(&shared) {
            assert!(*b < 2.0 * a + 1e-9, "p = {p}: {per:?} vs {shared:?}");
        }
    }
    let ops = FmmField::operators(
        &Biharmonic,
        &FmmOptions::new(6).with_compression(M2lCompression::SharedBasis),
    )
    .expect("ops");
    let per = FmmOptions::new(6).with_compression(M2lCompression::PerOperator);
    assert!(matches!(
        FmmField::with_operators(&r, &per, ops),
        Err(FmmError::Operators { .. })
    ));
}

#[test]
fn thin_plate_uses_operators_per_level() {
    let c = blob(500);
    let exact = fit(ThinPlate, &c);
    let fast = FmmField::new(&exact, &FmmOptions::new(8).with_leaf_size(16)).expect("fmm");
    let points = probes(&exact.bounds().expect("bounds"), 1000, 0.0);
    let e = relative_error(&fast, &exact, &points);
    assert!(e < 1e-5, "{e:e}");
}

#[test]
fn values_have_the_same_bits_for_any_thread_count_and_batch() {
    let c = blob(700);
    let exact = fit(Biharmonic, &c);
    let points = probes(&exact.bounds().expect("bounds"), 5000, 0.1);
    let run = |threads: usize, compression: M2lCompression| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| {
                let options = FmmOptions::new(6)
                    .with_leaf_size(10)
                    .with_compression(compression);
                let fast = FmmField::new(&exact, &options).expect("fmm");
                let mut out = vec![0.0; points.len()];
                fast.values(&points, &mut out);
                (fast, out)
            })
    };
    let (_, s1) = run(1, M2lCompression::SharedBasis);
    let (_, s3) = run(3, M2lCompression::SharedBasis);
    assert!(s1.iter().zip(&s3).all(|(x, y)| x.to_bits() == y.to_bits()));
    let (one, a) = run(1, M2lCompression::PerOperator);
    let (_, b) = run(3, M2lCompression::PerOperator);
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    // One point at a time, or in another batch: the same bits.
    for (i, x) in points.iter().enumerate().step_by(97) {
        assert_eq!(one.value(x).to_bits(), a[i].to_bits());
    }
    let mut tail = vec![0.0; 1000];
    one.values(&points[4000..], &mut tail);
    assert!(
        tail.iter()
            .zip(&a[4000..])
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
}

#[test]
fn coincident_centres_and_tiny_leaves_are_handled() {
    // 40 centres at one point (more than a leaf holds: the depth limit stops the splitting),
    // interleaved with a ring (consecutive equal centres would be merged into one source).
    let points: Vec<[f64; 3]> = (0..100)
        .map(|k| {
            let t = k as f64 * 0.1;
            if k % 5 < 2 {
                [0.25; 3]
            } else {
                [t.cos(), t.sin(), 0.0]
            }
        })
        .collect();
    let n = points.len();
    let weights: Vec<f64> = (0..n).map(|j| ((j * 7919) % 13) as f64 - 6.0).collect();
    let field = RbfField::from_parts(
        Biharmonic,
        points.clone(),
        vec![Functional::Value; n],
        vec![0.0; n],
        weights,
        Polynomial::fit(&points),
        vec![0.5, 0.1, -0.2, 0.3],
        Aabb::new([-1.0; 3], [1.0; 3]).expect("box"),
    );
    let fast = FmmField::new(
        &field,
        &FmmOptions::new(6).with_leaf_size(4).with_max_depth(12),
    )
    .expect("fmm");
    assert_eq!(fast.report().depth, 12);
    let probes = probes(&Aabb::new([-1.0; 3], [1.0; 3]).expect("box"), 1000, 0.5);
    let e = relative_error(&fast, &field, &probes);
    assert!(e < 1e-4, "{e:e}");
    // At the coincident point itself: φ(0) = 0 from every copy.
    let x = [0.25; 3];
    assert!((fast.value(&x) - field.value(&x)).abs() < 1e-4 * field.value(&x).abs().max(1.0));
}

#[test]
fn bad_options_are_specific_errors() {
    let c = blob(60);
    let field = fit(Biharmonic, &c);
    for p in [0, 1, 17] {
        assert_eq!(
            FmmField::new(&field, &FmmOptions::new(p)).err(),
            Some(FmmError::Order { order: p })
        );
    }
    assert_eq!(
        FmmField::new(&field, &FmmOptions::new(4).with_leaf_size(0)).err(),
        Some(FmmError::LeafSize)
    );
    for t in [0.0, 1.0, f64::NAN] {
        assert!(matches!(
            FmmField::new(&field, &FmmOptions::new(4).with_tolerance(t)),
            Err(FmmError::Tolerance { .. })
        ));
    }
    let ops = FmmField::operators(&Biharmonic, &FmmOptions::new(5)).expect("ops");
    assert!(matches!(
        FmmField::with_operators(&field, &FmmOptions::new(6), ops.clone()),
        Err(FmmError::Operators { .. })
    ));
    let r3 = fit(Triharmonic, &c);
    let ops3 = FmmField::operators(&Triharmonic, &FmmOptions::new(5)).expect("ops");
    assert!(FmmField::with_operators(&r3, &FmmOptions::new(5), ops3).is_ok());
    let empty = RbfField::from_parts(
        Biharmonic,
        vec![],
        vec![],
        vec![],
        vec![],
        Polynomial::fit(&[]),
        vec![0.0; 4],
        Aabb::new([0.0; 3], [1.0; 3]).expect("box"),
    );
    assert_eq!(
        FmmField::new(&empty, &FmmOptions::new(4)).err(),
        Some(FmmError::NoSources)
    );
    // An empty batch is no work.
    let fast = FmmField::new(&field, &FmmOptions::new(4)).expect("fmm");
    fast.values(&[], &mut []);
}

/// The values at the corners, centre and scattered points of a box lie in its enclosure.
fn check_enclosure<K: Kernel>(f: &FmmField<K>, b: &Aabb<3>) -> Option<[f64; 2]> {
    let [lo, hi] = f.value_range(b)?;
    assert!(lo <= hi, "{lo} > {hi}");
    let mut points: Vec<Point<3>> = (0..8)
        .map(|k| {
            std::array::from_fn(|a| {
                if (k >> a) & 1 == 0 {
                    b.min()[a]
                } else {
                    b.max()[a]
                }
            })
        })
        .collect();
    points.extend(probes(b, 40, 0.0));
    for x in &points {
        let v = f.value(x);
        assert!(
            lo <= v && v <= hi,
            "{x:?}: {v} outside [{lo}, {hi}] of {b:?}"
        );
    }
    Some([lo, hi])
}

/// Enclosures hold for r, r³ and the thin plate at several orders and box sizes; away from the
/// surface most boxes a few grid cells wide clear the level (the signed marching cubes' block
/// step), and they are not much wider than the values they enclose.
#[test]
fn enclosures_hold_and_settle_boxes_away_from_the_surface() {
    let c = blob(700);
    fn run<K: Kernel + Clone>(field: &RbfField<K, 3>, p: usize) -> (usize, usize, usize) {
        let f = FmmField::new(field, &FmmOptions::new(p).with_leaf_size(24)).expect("fmm");
        let bounds = field.bounds().expect("bounds");
        let (mut some, mut clear, mut total) = (0, 0, 0);
        for (k, centre) in probes(&bounds, 400, 0.0).iter().enumerate() {
            let half = [0.002, 0.01, 0.03][k % 3];
            let b = Aabb::new(centre.map(|v| v - half), centre.map(|v| v + half)).expect("box");
            total += 1;
            if let Some([lo, hi]) = check_enclosure(&f, &b) {
                some += 1;
                if lo > 0.0 || hi < 0.0 {
                    clear += 1;
                }
            }
        }
        (some, clear, total)
    }
    for p in [4, 6] {
        for (name, (some, clear, total)) in [
            ("r", run(&fit(Biharmonic, &c), p)),
            ("r3", run(&fit(Triharmonic, &c), p)),
            ("tps", run(&fit(ThinPlate, &c), p)),
        ] {
            eprintln!("{name} p={p}: {some} enclosures of {total} boxes, {clear} clear of 0");
            assert!(some * 10 >= total * 9, "{name} p={p}: {some} of {total}");
            assert!(clear * 2 >= total, "{name} p={p}: {clear} of {total} clear");
        }
    }
}

/// No enclosure outside the root, for Hermite fields, or over too many leaves; a box over two
/// leaves is the union of its pieces.
#[test]
fn enclosures_are_refused_where_they_cannot_hold() {
    let c = blob(400);
    let field = fit(Biharmonic, &c);
    let f = FmmField::new(&field, &FmmOptions::new(5).with_leaf_size(8)).expect("fmm");
    let b = field.bounds().expect("bounds");
    let outside = Aabb::new(b.max().map(|v| v + 0.1), b.max().map(|v| v + 0.2)).expect("box");
    assert_eq!(f.value_range(&outside), None);
    assert_eq!(f.value_range(&b), None, "the whole box meets every leaf");
    // A box straddling the root's centre plane meets at least two leaves.
    let root = f.tree.cells[0];
    let mut lo = root.centre.map(|v| v - 0.004);
    lo[1] += 0.3;
    let straddle = Aabb::new(lo, lo.map(|v| v + 0.008)).expect("box");
    assert!(check_enclosure(&f, &straddle).is_some());

    let hermite =
        FmmField::new(&fit(Triharmonic, &hermite_sphere(100)), &FmmOptions::new(5)).expect("fmm");
    let small = Aabb::new([0.01; 3], [0.02; 3]).expect("box");
    assert_eq!(hermite.value_range(&small), None);
}

/// An order pair measures both errors and sets the margin from them; rebuilding the low field
/// for another number of points keeps its order and operators and updates the margin.
#[test]
fn order_pairs_measure_their_margin_and_rebuild_the_low_field() {
    let c = blob(500);
    let field = fit(Biharmonic, &c);
    let pair =
        OrderPair::new(&field, &FmmOptions::new(4), &FmmOptions::new(8), 512, 10.0).expect("pair");
    assert!(pair.low_error > pair.high_error && pair.high_error > 0.0);
    assert_eq!(pair.margin, 10.0 * (pair.low_error + pair.high_error));
    let ops = pair.low.shared_operators();
    let rebuilt = pair
        .clone()
        .with_low(&field, &FmmOptions::new(4).with_expected_points(1 << 22))
        .expect("rebuilt");
    assert!(Arc::ptr_eq(&ops, &rebuilt.low.shared_operators()));
    assert!(rebuilt.low.report().leaves != pair.low.report().leaves);
    assert_eq!(
        rebuilt.margin,
        10.0 * (rebuilt.low_error + rebuilt.high_error)
    );
    assert_eq!(rebuilt.high_error, pair.high_error);
    let other_order = pair.with_low(&field, &FmmOptions::new(5));
    assert!(matches!(other_order, Err(FmmError::Operators { .. })));
    assert!(matches!(
        OrderPair::new(&field, &FmmOptions::new(8), &FmmOptions::new(4), 16, 10.0),
        Err(FmmError::Orders { low: 8, high: 4 })
    ));
    assert!(matches!(
        OrderPair::new(&field, &FmmOptions::new(4), &FmmOptions::new(8), 16, 0.5),
        Err(FmmError::Safety { .. })
    ));
}

/// A finer level keeps the singular values down to the coarsest level's absolute cut-off:
/// fewer of them, never none; an uncompressed operator keeps all.
#[test]
fn finer_levels_keep_fewer_singular_values() {
    let sigma = [1.0, 0.5, 0.1, 0.01, 1e-4];
    assert_eq!(m2l::rank_for(&sigma, 5, 1e-5), 5);
    assert_eq!(m2l::rank_for(&sigma, 5, 0.05), 3);
    assert_eq!(m2l::rank_for(&sigma, 5, 0.5), 2);
    assert_eq!(m2l::rank_for(&sigma, 5, 2.0), 1, "at least one");
    assert_eq!(m2l::rank_for(&sigma, 3, 1e-5), 3, "at most the columns");
    assert_eq!(m2l::rank_for(&[], 7, 0.5), 7, "uncompressed");
}

/// A compactly supported user kernel (operators per level; at the coarser levels many far
/// operators vanish, so the shared basis is degenerate there) works with either compression,
/// to the same accuracy.
#[test]
fn a_compactly_supported_kernel_works_with_either_compression() {
    use crate::rbf::Wendland;
    let c = blob(900);
    let exact = fit(Wendland::new(0.4).expect("radius"), &c);
    let points = probes(&exact.bounds().expect("bounds"), 1500, 0.1);
    let errors = [M2lCompression::PerOperator, M2lCompression::SharedBasis].map(|compression| {
        let options = FmmOptions::new(6)
            .with_leaf_size(16)
            .with_compression(compression);
        let fast = FmmField::new(&exact, &options).expect("fmm");
        assert!(fast.report().depth >= 4, "{:?}", fast.report());
        relative_error(&fast, &exact, &points)
    });
    eprintln!(
        "Wendland, p = 6: per operator {:e}, shared basis {:e}",
        errors[0], errors[1]
    );
    // The kernel is only C² at its support's edge, so the error falls slowly with the order
    // (8e-4 at p = 6); the shared basis adds nothing to it.
    assert!(errors[0] < 3e-3, "{errors:?}");
    assert!(errors[1] < 1.5 * errors[0], "{errors:?}");
}

/// Fields of one kernel, order, tolerance and compression share one set of operators from the
/// process-wide cache; another tolerance or compression gets its own.
#[test]
fn fields_of_the_same_key_share_the_cached_operators() {
    let field = fit(Biharmonic, &blob(300));
    // A tolerance no other test uses, so that the keys are this test's own.
    let options = FmmOptions::new(4).with_tolerance(3.1e-6);
    let a = FmmField::new(&field, &options).expect("fmm");
    let b = FmmField::new(&field, &options.with_expected_points(1 << 20)).expect("fmm");
    assert!(Arc::ptr_eq(&a.shared_operators(), &b.shared_operators()));
    assert!(a.shared_operators().bytes() > 0);
    let c = FmmField::new(&field, &options.with_tolerance(3.2e-6)).expect("fmm");
    assert!(!Arc::ptr_eq(&a.shared_operators(), &c.shared_operators()));
    let d = FmmField::new(
        &field,
        &options.with_compression(M2lCompression::SharedBasis),
    )
    .expect("fmm");
    assert!(!Arc::ptr_eq(&a.shared_operators(), &d.shared_operators()));
    // Another kernel at the same settings never gets them.
    let r3 = fit(Triharmonic, &blob(300));
    let e = FmmField::new(&r3, &options).expect("fmm");
    assert!(!Arc::ptr_eq(&a.shared_operators(), &e.shared_operators()));
    assert!(matches!(
        FmmField::with_operators(&r3, &options, a.shared_operators()),
        Err(FmmError::Operators { .. })
    ));
}

/// Operators written to the disk cache read back exactly (both compressions), and a file that
/// is truncated, corrupt or for another key or width is ignored.
#[test]
fn operators_read_back_from_disk_exactly_and_bad_files_are_ignored() {
    let dir = tempfile::tempdir().expect("temp dir");
    for compression in [M2lCompression::PerOperator, M2lCompression::SharedBasis] {
        let ops = operators::FmmOperators::new(&Triharmonic, 4, 2.7e-6, compression);
        let (level, _) = ops.level(&Triharmonic, 1.0);
        let key = ops.key();
        let path = cache::file_for(dir.path(), key, 1.0);
        cache::save(&path, key, 1.0, &level).expect("saved");
        let back = cache::load(&path, key, 1.0, 64).expect("read back");
        // The same bytes when written again: every matrix, singular value and sign.
        let again = dir.path().join("again.zso");
        cache::save(&again, key, 1.0, &back).expect("saved");
        let bytes = std::fs::read(&path).expect("read");
        assert_eq!(bytes, std::fs::read(&again).expect("read"));
        assert_eq!(back.bytes(), level.bytes());
        // Another width or order, a truncated or flipped file: ignored.
        assert!(cache::load(&path, key, 0.5, 64).is_none());
        assert!(cache::load(&path, key, 1.0, 125).is_none());
        let other = operators::FmmOperators::new(&Biharmonic, 4, 2.7e-6, compression);
        assert!(cache::load(&path, other.key(), 1.0, 64).is_none());
        let bad = dir.path().join("bad.zso");
        std::fs::write(&bad, &bytes[..bytes.len() / 2]).expect("written");
        assert!(cache::load(&bad, key, 1.0, 64).is_none());
        let mut flipped = bytes.clone();
        flipped[bytes.len() / 3] ^= 0x10;
        std::fs::write(&bad, &flipped).expect("written");
        assert!(cache::load(&bad, key, 1.0, 64).is_none());
        assert!(cache::load(&dir.path().join("missing.zso"), key, 1.0, 64).is_none());
    }
}

/// With a disk cache, a field whose operators were dropped from memory reads them back from
/// disk and gives the same bits as the field that built them.
#[test]
fn a_field_from_disk_cached_operators_has_the_same_bits() {
    let dir = tempfile::tempdir().expect("temp dir");
    let field = fit(Triharmonic, &blob(400));
    let options = FmmOptions::new(5).with_tolerance(4.3e-7);
    cache::set_disk_dir(Some(dir.path().to_owned()));
    let built = FmmField::new(&field, &options).expect("fmm");
    // Drop the operators from memory (the field keeps its own; the counters restart), then
    // build again.
    cache::clear();
    let again = FmmField::new(&field, &options).expect("fmm");
    cache::set_disk_dir(None);
    assert!(cache::stats().disk_reads >= 1, "{:?}", cache::stats());
    assert!(!Arc::ptr_eq(
        &built.shared_operators(),
        &again.shared_operators()
    ));
    let points = probes(&field.bounds().expect("bounds"), 700, 0.05);
    let (mut a, mut b) = (vec![0.0; points.len()], vec![0.0; points.len()]);
    built.values(&points, &mut a);
    again.values(&points, &mut b);
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    assert!(
        std::fs::read_dir(dir.path())
            .expect("listed")
            .any(|e| e.is_ok_and(|e| e.file_name().to_string_lossy().starts_with("m2l-v")))
    );
}

#[test]
fn new_weights_give_the_bits_of_a_field_built_with_them() {
    let c = blob(1500);
    let exact = fit(Biharmonic, &c);
    let options = FmmOptions::new(6);
    let mut reused = FmmField::new(&exact, &options).unwrap();
    // Other weights over the same centres: a field fitted to other targets.
    let mut other = Constraints::new();
    for (k, con) in c.as_slice().iter().enumerate() {
        other.push_value(con.point, (k as f64 * 0.37).sin() * 0.1);
    }
    let second = fit(Biharmonic, &other);
    reused.set_weights(second.weights()).unwrap();
    let fresh = FmmField::new(
        &RbfField::from_parts(
            Biharmonic,
            second.centres().to_vec(),
            vec![Functional::Value; second.num_centres()],
            vec![0.0; second.num_centres()],
            second.weights().to_vec(),
            *exact.polynomial(),
            exact.polynomial_coefficients().to_vec(),
            exact.bounds().unwrap(),
        ),
        &options,
    )
    .unwrap();
    for x in probes(&exact.bounds().unwrap(), 200, 0.1) {
        assert_eq!(reused.value(&x).to_bits(), fresh.value(&x).to_bits());
    }
    assert!(matches!(
        reused.set_weights(&[1.0; 3]),
        Err(FmmError::Sources { given: 3, .. })
    ));
    let mut bad = second.weights().to_vec();
    bad[7] = f64::NAN;
    assert!(matches!(
        reused.set_weights(&bad),
        Err(FmmError::NonFinite { index: 7, .. })
    ));
}
