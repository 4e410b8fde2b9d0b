//! MRAS (paper 004) against truth: analytic shapes, finite differences, the field file's
//! exactness, thread-count independence, the errors bad clouds get, and a real scan (the
//! bunny in `data/`, or `$ZEROSET_DATA`).

use zeroset_bases::field_file::{AnyField, decode_any, encode_mras};
use zeroset_bases::mras::{CellSpline, MrasError, MrasFit, MrasOptions, MrasProgress, fit_mras};
use zeroset_field_core::field::{ScalarField, central_difference_gradient, distance_to_zero_set};
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::io::read_point_cloud;

#[path = "../../../examples/common/shapes.rs"]
mod shapes;

use shapes::{sphere, torus};

type P = [f64; 3];

fn fit(points: &[P], normals: &[P], options: &MrasOptions) -> MrasFit {
    fit_mras(points, normals, options, &|_| true).expect("fit")
}

fn max_distance(fit: &MrasFit, points: &[P]) -> f64 {
    points
        .iter()
        .map(|p| distance_to_zero_set(&fit.field, p, 1e-10, 100).expect("projects"))
        .fold(0.0, f64::max)
        / fit.diagonal
}

fn ranks(fit: &MrasFit) -> Vec<usize> {
    fit.field
        .levels()
        .iter()
        .flat_map(|l| {
            l.cells()
                .iter()
                .map(|c| c.spline.rank().unwrap_or(usize::MAX))
        })
        .collect()
}

#[test]
fn single_level_sphere_is_low_rank() {
    // Paper Fig. 5(a): one level, rank 4 at ε ≈ 9.7e-4. The paper gives neither λ nor the
    // knots; with its kind of setting (a strong trace norm, a weak thin-plate term) and 11
    // B-splines per axis over the cube zeroset reaches rank 4 at 9.1e-4 (measured; the sweep
    // is `cargo run --release --example mras_tables -- shapes`).
    let (p, n) = sphere(3000, 1.0);
    let paper = MrasOptions::default()
        .max_level(1)
        .lambda(20.0)
        .omega2_root(1e-8);
    let f = fit(&p, &n, &paper);
    let r = ranks(&f);
    assert_eq!(r.len(), 1);
    let err = max_distance(&f, &p);
    assert!(r[0] <= 4 && err < 1e-3, "rank {}, max distance {err}", r[0]);
    assert!(f.field.value(&[0.0; 3]) < 0.0);
    assert!(f.field.value(&[1.05, 0.0, 0.0]) > 0.0);
    // The defaults (λ = 0.3, the root's strong smoothing): rank 10 at 7.0e-4.
    let defaults = fit(&p, &n, &MrasOptions::default().max_level(1));
    assert!(ranks(&defaults)[0] <= 12 && max_distance(&defaults, &p) < 1.5e-3);
    // A weak smoothing without the strong trace norm leaves the coefficients away from the
    // points free, which costs rank (30).
    let weak = fit(
        &p,
        &n,
        &MrasOptions::default().max_level(1).omega2_root(1e-8),
    );
    assert!(max_distance(&weak, &p) < 2.5e-3);
    assert!(ranks(&weak)[0] > ranks(&defaults)[0]);
}

#[test]
fn single_level_torus_fits_within_the_root_cells_resolution() {
    // Paper Fig. 5(b): rank 10 at ε ≈ 8.3e-4. With 15 B-splines per axis, λ = 20 and a weak
    // thin-plate term: rank 10 at 8.1e-4 (measured). The defaults' one root cell of 11
    // B-splines reaches 2.1e-3 at rank 10, a weak root smoothing 9.7e-4 at rank 19; deeper
    // levels do the rest.
    let (p, n) = torus(120, 48, 1.0, 0.4);
    let paper = MrasOptions::default()
        .max_level(1)
        .lambda(20.0)
        .omega2_root(1e-8)
        .m0(16);
    let f = fit(&p, &n, &paper);
    let err = max_distance(&f, &p);
    assert!(
        ranks(&f)[0] <= 10 && err < 9e-4,
        "rank {:?}, max distance {err}",
        ranks(&f)
    );
    let f = fit(&p, &n, &MrasOptions::default().max_level(1));
    let err = max_distance(&f, &p);
    assert!(err < 5e-3, "max distance / diagonal {err}");
    assert!(ranks(&f)[0] <= 12, "rank {:?}", ranks(&f));
    let weak = fit(
        &p,
        &n,
        &MrasOptions::default().max_level(1).omega2_root(1e-8),
    );
    assert!(max_distance(&weak, &p) < 2e-3);
    let deep = fit(&p, &n, &MrasOptions::default().max_level(3));
    assert!(
        max_distance(&deep, &p) < err,
        "levels 2–3 must improve on the root"
    );
}

#[test]
fn analytic_gradient_matches_finite_differences() {
    let (p, n) = torus(60, 24, 1.0, 0.4);
    let f = fit(&p, &n, &MrasOptions::default().max_level(3).tolerance(1e-4));
    assert!(
        f.field.levels().len() >= 2,
        "needs several levels to test the blend"
    );
    let probes = [
        [0.3, 1.1, 0.2],
        [1.35, -0.2, 0.1],
        [-0.9, 0.6, -0.25],
        [0.02, 0.03, 0.01],
    ];
    for x in probes {
        let g = f.field.gradient(&x);
        let fd = central_difference_gradient(&f.field, &x);
        for a in 0..3 {
            assert!(
                (g[a] - fd[a]).abs() < 1e-6 * (1.0 + fd[a].abs()),
                "{x:?}: {g:?} vs {fd:?}"
            );
        }
    }
    // The field's box, which meshing and restoring sample, is the points' box grown by 5% of
    // its diagonal within the cube: a torus's thin axis is not sampled over the cube's side.
    let points_box = zeroset_field_core::geometry::Aabb::from_points(&p).expect("box");
    let grown = points_box.expanded(0.05 * points_box.diagonal());
    let bounds = f.field.bounds().expect("bounds");
    let cube_side = f.field.side();
    assert!(
        (bounds.max()[2] - grown.max()[2]).abs() < 1e-6 * cube_side,
        "{bounds:?}"
    );
    assert!(
        (bounds.min()[2] - grown.min()[2]).abs() < 1e-6 * cube_side,
        "{bounds:?}"
    );
    assert!(
        bounds.max()[2] - bounds.min()[2] < 0.5 * cube_side,
        "{bounds:?}"
    );
    // A NaN or infinite point gives NaN, as the other fields give (its cell index overflowed:
    // a panic in debug builds).
    for bad in [[f64::NAN, 0.0, 0.0], [0.0, f64::INFINITY, 0.0]] {
        assert!(f.field.value(&bad).is_nan());
        assert!(f.field.gradient(&bad).iter().all(|v| v.is_nan()));
        let mut out = [0.0; 2];
        f.field.values(&[bad, probes[0]], &mut out);
        assert!(out[0].is_nan() && out[1] == f.field.value(&probes[0]));
    }
}

#[test]
fn field_file_round_trip_is_bit_exact() {
    let (p, n) = torus(60, 24, 1.0, 0.4);
    for compress in [true, false] {
        let f = fit(
            &p,
            &n,
            &MrasOptions::default().max_level(2).compress(compress),
        );
        let bytes = encode_mras(&f.field);
        let AnyField::Mras(back) = decode_any::<3>(&bytes, "t.zsf".as_ref()).unwrap() else {
            panic!("not an MRAS field");
        };
        assert_eq!(back, f.field);
        for x in [[0.3, 1.1, 0.2], [1.35, -0.2, 0.1]] {
            assert_eq!(back.value(&x).to_bits(), f.field.value(&x).to_bits());
        }
        assert_eq!(encode_mras(&back), bytes);
        // The fit records its input points (f32 in the cube), and they come back.
        let recorded = back.points();
        assert_eq!(recorded.len(), p.len());
        for (r, q) in recorded.iter().zip(&p) {
            for a in 0..3 {
                assert!((r[a] - q[a]).abs() <= 1e-6 * back.side(), "{r:?} vs {q:?}");
            }
        }
        // A field without recorded points (one built by hand, an older file) round trips too.
        let bare = f.field.clone().with_points(&[]);
        let bare_bytes = encode_mras(&bare);
        assert!(bare_bytes.len() + 12 * p.len() + 8 <= bytes.len());
        let AnyField::Mras(back) = decode_any::<3>(&bare_bytes, "t.zsf".as_ref()).unwrap() else {
            panic!("not an MRAS field");
        };
        assert_eq!(back, bare);
        assert!(back.points().is_empty());
        let full = f
            .field
            .levels()
            .iter()
            .flat_map(|l| l.cells())
            .any(|c| matches!(c.spline, CellSpline::Full { .. }));
        assert_eq!(full, !compress);
        // Truncated files are refused, not misread.
        for cut in [bytes.len() - 1, bytes.len() / 2, 60] {
            assert!(decode_any::<3>(&bytes[..cut], "t.zsf".as_ref()).is_err());
        }
    }
}

#[test]
fn same_bits_on_one_and_several_threads() {
    let (p, n) = torus(60, 24, 1.0, 0.4);
    let options = MrasOptions::default().max_level(3).tolerance(1e-4);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| encode_mras(&fit(&p, &n, &options).field))
    };
    let one = run(1);
    assert_eq!(one, run(3));
    // Batched evaluation gives the single-point bits.
    let f = fit(&p, &n, &options).field;
    let pts: Vec<P> = (0..500)
        .map(|i| {
            [
                (i as f64 * 0.37).sin() * 1.5,
                (i as f64 * 0.11).cos() * 1.5,
                0.2,
            ]
        })
        .collect();
    let mut out = vec![0.0; pts.len()];
    f.values(&pts, &mut out);
    for (x, v) in pts.iter().zip(&out) {
        assert_eq!(v.to_bits(), f.value(x).to_bits());
    }
}

#[test]
fn bad_clouds_get_specific_errors() {
    let (p, n) = sphere(200, 1.0);
    let o = MrasOptions::default().max_level(1);
    let err = |p: &[P], n: &[P]| fit_mras(p, n, &o, &|_| true).unwrap_err();

    assert!(matches!(
        err(&p[..10], &n[..10]),
        MrasError::TooFewPoints { got: 10, .. }
    ));
    assert!(matches!(err(&p, &n[..5]), MrasError::Normals { .. }));
    let mut q = p.clone();
    q[7][1] = f64::NAN;
    assert!(matches!(
        err(&q, &n),
        MrasError::NonFinite {
            index: 7,
            what: "position",
            ..
        }
    ));
    let mut m = n.clone();
    m[3] = [0.0; 3];
    assert!(matches!(
        err(&p, &m),
        MrasError::ZeroNormal { index: 3, .. }
    ));
    // An outlier ratio that would call most of a surface isolated.
    assert!(matches!(
        fit_mras(&p, &n, &o.clone().outlier_ratio(1.0), &|_| true).unwrap_err(),
        MrasError::Option {
            name: "outlier_ratio",
            ..
        }
    ));
    // Duplicates with agreeing normals are merged; a repeat with its normal flipped is one
    // sheet sampled twice (all the points around face the first's way): the same field, bit
    // for bit, whichever copy comes first.
    let mut q = p.clone();
    let mut m = n.clone();
    q.push(p[5]);
    m.push(n[5]);
    let agreeing = fit_mras(&q, &m, &o, &|_| true).unwrap();
    assert_eq!(agreeing.duplicates, 1);
    let bits = |f: &MrasFit| encode_mras(&f.field);
    *m.last_mut().unwrap() = n[5].map(|v| -v);
    let flipped_repeat = fit_mras(&q, &m, &o, &|_| true).unwrap();
    assert_eq!((flipped_repeat.duplicates, flipped_repeat.touching), (1, 0));
    assert_eq!(bits(&flipped_repeat), bits(&agreeing));
    m[5] = n[5].map(|v| -v);
    *m.last_mut().unwrap() = n[5];
    let flipped_first = fit_mras(&q, &m, &o, &|_| true).unwrap();
    assert_eq!((flipped_first.duplicates, flipped_first.touching), (1, 0));
    assert_eq!(bits(&flipped_first), bits(&agreeing));
    // A crease's split normals (87° apart, not pointing apart): their mean is fitted, the
    // same field whichever copy comes first.
    let tilted = [n[5][1], n[5][2], n[5][0]];
    let crease = |first: P, second: P| {
        let mut m = n.clone();
        m[5] = first;
        m.push(second);
        let f = fit_mras(&q, &m, &o, &|_| true).unwrap();
        assert_eq!((f.duplicates, f.touching), (1, 0));
        bits(&f)
    };
    assert_eq!(crease(n[5], tilted), crease(tilted, n[5]));
    assert_ne!(crease(n[5], tilted), bits(&agreeing));
    // 20 copies of 10 points: 10 distinct.
    let q: Vec<P> = (0..20).flat_map(|_| p[..10].to_vec()).collect();
    let m: Vec<P> = (0..20).flat_map(|_| n[..10].to_vec()).collect();
    assert!(matches!(
        err(&q, &m),
        MrasError::TooFewPoints {
            got: 10,
            duplicates: 190,
            ..
        }
    ));
    // A plane and a line.
    let plane: Vec<P> = (0..100)
        .map(|i| [(i % 10) as f64, (i / 10) as f64, 2.0])
        .collect();
    let up = vec![[0.0, 0.0, 1.0]; 100];
    assert!(matches!(
        err(&plane, &up),
        MrasError::Degenerate { shape: "plane", .. }
    ));
    let line: Vec<P> = (0..100).map(|i| [i as f64, 2.0 * i as f64, 1.0]).collect();
    assert!(matches!(
        err(&line, &up),
        MrasError::Degenerate { shape: "line", .. }
    ));
    // Options.
    let bad = MrasOptions::default().tolerance(0.0);
    assert!(matches!(
        fit_mras(&p, &n, &bad, &|_| true),
        Err(MrasError::Option {
            name: "tolerance",
            ..
        })
    ));
    let bad = MrasOptions::default().max_level(0);
    assert!(matches!(
        fit_mras(&p, &n, &bad, &|_| true),
        Err(MrasError::Option {
            name: "max_level",
            ..
        })
    ));
}

#[test]
fn two_spheres_touching_at_one_sampled_point_fit_as_two_solids() {
    // Unit spheres centred at z = ±1, both sampled at the origin where they touch (normal down
    // on the upper one, up on the lower): one place with normals pointing apart, two sheets.
    let (p, n) = sphere(1500, 1.0);
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for dz in [1.0, -1.0] {
        points.extend(p.iter().map(|q| [q[0], q[1], q[2] + dz]));
        normals.extend(n.iter().copied());
        points.push([0.0; 3]);
        normals.push([0.0, 0.0, -dz]);
    }
    let o = MrasOptions::default().max_level(5);
    let f = fit(&points, &normals, &o);
    assert_eq!((f.duplicates, f.touching), (1, 1));
    // The field is flat only around the meeting place (the warning is above 1%).
    assert!(
        f.flat_points * 100 < f.fitted_points,
        "{} flat points",
        f.flat_points
    );
    let value = |x: P| f.field.value(&x);
    for z in [0.5, 1.0, -0.5, -1.0] {
        let v = value([0.0, 0.0, z]);
        assert!(v < 0.0, "inside at z = {z}: {v}");
    }
    // Between the spheres near where they touch, and beside it: outside.
    for x in [0.3, 0.6] {
        let v = value([x, 0.0, 0.0]);
        assert!(v > 0.0, "outside at x = {x}: {v}");
    }
    let apart: Vec<usize> = (0..points.len())
        .filter(|&i| points[i] != [0.0; 3])
        .collect();
    let without = fit(
        &apart.iter().map(|&i| points[i]).collect::<Vec<_>>(),
        &apart.iter().map(|&i| normals[i]).collect::<Vec<_>>(),
        &o,
    );
    // The place's value 0 holds the field nearer 0 there than without its sample, and its
    // gradient, the mean of two opposite normals, vanishes: a saddle between the two solids
    // (keeping one of the two normals pulled it to 0.10).
    let (at, without_at) = (value([0.0; 3]), without.field.value(&[0.0; 3]));
    assert!(
        at.abs() < without_at.abs(),
        "f = {at} where they touch, {without_at} without"
    );
    let slope = geometry_norm(f.field.gradient(&[0.0; 3]));
    assert!(slope < 0.03, "|∇f| = {slope} where they touch");
    // Near where they touch the gap between the spheres closes as the square of the distance
    // and no smooth field follows both sheets there (the place itself is not measured): the
    // shared sample must not make the rest worse than the same fit without it.
    assert!(
        f.max_error() <= without.max_error(),
        "largest distance {:.2e} of the diagonal, {:.2e} without the shared sample",
        f.max_error(),
        without.max_error()
    );
}

fn geometry_norm(v: P) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[test]
fn storage_counts_the_paper_way() {
    let (p, n) = torus(60, 24, 1.0, 0.4);
    let f = fit(&p, &n, &MrasOptions::default().max_level(2));
    let mut want = 0;
    let mut full = 0;
    for l in f.field.levels() {
        for c in l.cells() {
            want += 4 + match &c.spline {
                CellSpline::Cp { rank, .. } => 3 * l.knots() * rank,
                CellSpline::Full { coefficients } => coefficients.len(),
            };
            full += 4 + l.knots().pow(3);
        }
    }
    assert_eq!(f.field.storage(), want);
    assert_eq!(f.field.uncompressed_storage(), full);
    assert_eq!(f.levels.iter().map(|l| l.stored).sum::<usize>(), want);
}

#[test]
fn grid_rows_give_the_single_point_bits() {
    // `values` reuses, along points that differ only in z (a grid's rows), each level's x·y
    // lattice neighbours and each CP cell's z-factor rows contracted with its x·y products:
    // the values must keep `value`'s bits — on CP and full cells, rows that
    // start mid-chunk, rows of one point, and points outside the cube (clamped).
    let (p, n) = torus(60, 24, 1.0, 0.4);
    let options = MrasOptions::default().max_level(4).tolerance(1e-4);
    for compress in [true, false] {
        let f = fit(&p, &n, &options.clone().compress(compress)).field;
        let b = f.bounds().expect("a cube");
        let (lo, side) = (b.min(), b.max()[0] - b.min()[0]);
        let mut pts: Vec<P> = Vec::new();
        for i in 0..23 {
            for j in 0..19 {
                let len = if (i + j) % 7 == 0 { 1 } else { 31 };
                for k in 0..len {
                    pts.push([
                        lo[0] - 0.05 * side + 1.1 * side * i as f64 / 22.0,
                        lo[1] + side * j as f64 / 18.0,
                        lo[2] - 0.05 * side + 1.1 * side * k as f64 / 30.0,
                    ]);
                }
            }
        }
        let mut out = vec![0.0; pts.len()];
        f.values(&pts, &mut out);
        for (x, v) in pts.iter().zip(&out) {
            assert_eq!(v.to_bits(), f.value(x).to_bits(), "at {x:?}");
        }
        let grid = zeroset_field_core::grid::Grid::vertex_centered(b, [17, 13, 40]).expect("grid");
        let sampled = grid.sample(&f);
        for (l, v) in sampled.iter().enumerate() {
            let x = grid.point(grid.multi_index(l));
            assert_eq!(v.to_bits(), f.value(&x).to_bits(), "at {x:?}");
        }
    }
}

#[test]
fn value_range_encloses_the_field_and_settles_boxes_away_from_the_surface() {
    // Every value in a box lies in the box's enclosure: on CP and full cells; boxes from a
    // point and flat ones (where the rounding of the evaluation itself is all the enclosure's
    // width) to 30% of the cube, inside it, across its faces and outside it (clamped); at the
    // box's corners, its centre and random points, each by `value` and by batched `values`.
    // Small boxes away from the torus are settled: their enclosure clears 0.
    let (p, n) = torus(60, 24, 1.0, 0.4);
    let options = MrasOptions::default().max_level(4).tolerance(1e-4);
    let mut rng = zeroset_field_core::rng::SplitMix64::new(11);
    for compress in [true, false] {
        let f = fit(&p, &n, &options.clone().compress(compress)).field;
        assert!(f.levels().len() >= 3, "a multilevel field");
        let (origin, side) = (f.origin(), f.side());
        // Boxes of 1% of the cube, and how many of them the enclosure settles.
        let (mut settled, mut small) = (0, 0);
        for k in 0..600 {
            let centre: P =
                std::array::from_fn(|a| origin[a] - 0.1 * side + 1.2 * side * rng.unit());
            let size = [0.0, 1e-4, 1e-3, 0.01, 0.05, 0.3][k % 6] * side;
            let flat = k % 4 == 1;
            let half: P =
                std::array::from_fn(|a| if flat && a == k % 3 { 0.0 } else { 0.5 * size });
            let region = Aabb::new(
                std::array::from_fn(|a| centre[a] - half[a]),
                std::array::from_fn(|a| centre[a] + half[a]),
            )
            .expect("a box");
            let [rl, rh] = f.value_range(&region).expect("an enclosure");
            let (lo, hi) = (region.min(), region.max());
            let mut at: Vec<P> = (0..8)
                .map(|c| std::array::from_fn(|a| if c >> a & 1 == 1 { hi[a] } else { lo[a] }))
                .collect();
            at.push(centre);
            at.extend(
                (0..40).map(|_| std::array::from_fn(|a| lo[a] + rng.unit() * (hi[a] - lo[a]))),
            );
            let mut batched = vec![0.0; at.len()];
            f.values(&at, &mut batched);
            for (x, &vb) in at.iter().zip(&batched) {
                for v in [f.value(x), vb] {
                    assert!(
                        rl <= v && v <= rh,
                        "{v} outside [{rl}, {rh}] at {x:?} (box {lo:?}–{hi:?}, compress {compress})"
                    );
                }
            }
            if k % 6 == 3 && !flat {
                small += 1;
                if rl > 0.0 || rh < 0.0 {
                    settled += 1;
                }
            }
        }
        // At a point the enclosure's width is the rounding of the evaluation (the blend's sums
        // and quotients) and its own widening: thousands of points, where a few lose to it
        // without the widening.
        for _ in 0..3000 {
            let x: P = std::array::from_fn(|a| origin[a] + side * rng.unit());
            let [rl, rh] = f
                .value_range(&Aabb::new(x, x).expect("a point"))
                .expect("an enclosure");
            let v = f.value(&x);
            assert!(rl <= v && v <= rh, "{v} outside [{rl}, {rh}] at {x:?}");
        }
        // The torus fills a small part of its box: most small boxes miss the surface by far,
        // and their enclosures clear it.
        assert!(
            settled * 3 > small * 2,
            "only {settled} of {small} boxes settled (compress {compress})"
        );
        let b = f.bounds().expect("a box");
        let corner = Aabb::new(
            b.min(),
            std::array::from_fn(|a| b.min()[a] + 0.05 * (b.max()[a] - b.min()[a])),
        )
        .expect("a box");
        let [rl, _] = f.value_range(&corner).expect("an enclosure");
        assert!(rl > 0.0, "the box's corner is outside the torus: {rl}");
        // A field read from its file (as the CLI and Python hold it) encloses itself the same.
        let any = decode_any::<3>(&encode_mras(&f), "t.zsf".as_ref()).expect("a field file");
        assert_eq!(any.value_range(&corner), f.value_range(&corner));
        // A box far larger than the cube is clamped onto it: the whole field's range.
        let huge = Aabb::new([-1e300; 3], [1e300; 3]).expect("a box");
        let [rl, rh] = f.value_range(&huge).expect("an enclosure");
        for x in [b.min(), b.max(), p[0]] {
            let v = f.value(&x);
            assert!(rl <= v && v <= rh, "{v} outside [{rl}, {rh}]");
        }
    }
}

/// The bunny's 34,834 oriented points (`data/bunny_points.ply`, or in `$ZEROSET_DATA`).
fn bunny() -> (Vec<P>, Vec<P>) {
    scan("bunny_points.ply")
}

/// The oriented points of scan `name` in `data/` (or in `$ZEROSET_DATA`).
fn scan(name: &str) -> (Vec<P>, Vec<P>) {
    let dir = match std::env::var_os("ZEROSET_DATA") {
        Some(d) => std::path::PathBuf::from(d),
        None => std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data"),
    };
    let path = dir.join(name);
    let cloud = read_point_cloud(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (set ZEROSET_DATA to the data folder)",
            path.display()
        )
    });
    let normals = cloud
        .normals()
        .unwrap_or_else(|| panic!("{name} has normals"))
        .to_vec();
    (cloud.positions().to_vec(), normals)
}

/// Regression: the CP bound of levels 2, 3, … was once a sixteenth of the largest Sampson
/// distance the previous level left. After the bunny's root with 9 or 10 B-splines per axis
/// (`m₀` 10 or 11) that distance is 0.79 / 0.35 of the diagonal, at points where `∇f` nearly
/// vanishes, while `|f|` stays below 1.3e-2 of the cube (`m₀` 11) — so the bound exceeded
/// every cell's offset, each level was dropped whole at rank 0 and the field ended at those
/// errors (0.18 / 0.33 after 7 levels). The bound now follows each refined cell's own
/// residual: every level stores cells and lowers the error.
#[test]
fn compression_never_drops_the_offsets_a_coarse_level_needs() {
    let (points, normals) = bunny();
    for m0 in [10, 11] {
        let fit = fit(
            &points,
            &normals,
            &MrasOptions::default().m0(m0).max_level(4),
        );
        let levels = &fit.levels;
        assert_eq!(levels.len(), 4, "m0 {m0}");
        for l in levels {
            assert!(
                l.cells > 0,
                "m0 {m0}: level {} stores no cell: {l:?}",
                l.level
            );
        }
        let last = levels[3].max_error;
        assert!(
            last < 0.03 && last < levels[0].max_error / 10.0,
            "m0 {m0}: largest Sampson distance {} after the root, {last} after level 4",
            levels[0].max_error
        );
    }
}

/// Regression: the CP bound and the rank-0 screen bounded value changes, the tolerance the
/// Sampson distance. With a loose tolerance the coarse field is flat in places (`|∇f| ≪ 1`),
/// where small values are far surfaces: at 0.02 every cell from level 4 on was dropped at
/// rank 0 and 8,029 points stayed beyond the tolerance, the farthest at 0.104 of the
/// diagonal. Now 45, the farthest at 0.026. The report counts them exactly.
#[test]
fn a_loose_tolerance_is_not_met_by_dropping_every_cell() {
    let (points, normals) = bunny();
    let tolerance = 0.02;
    let fit = fit(
        &points,
        &normals,
        &MrasOptions {
            tolerance,
            ..MrasOptions::default()
        },
    );
    assert!(
        fit.points_over_tolerance < 200 && fit.max_error() < 1.5 * tolerance,
        "{} points beyond {tolerance}, the farthest at {}",
        fit.points_over_tolerance,
        fit.max_error()
    );
    assert_eq!(fit.tolerance, tolerance);
    assert_eq!(fit.tolerance_met(), fit.max_error() <= tolerance);
    assert_eq!(fit.capped_cells, 0);
    // The count is of the Sampson distances |f|/|∇f| beyond the tolerance, recomputed here
    // from the field (unit-cube arithmetic inside the fit: a margin of 1e-9 either side).
    let sampson: Vec<f64> = points
        .iter()
        .map(|p| {
            let g = fit.field.gradient(p);
            fit.field.value(p).abs() / g.iter().map(|v| v * v).sum::<f64>().sqrt() / fit.diagonal
        })
        .collect();
    let over = |t: f64| sampson.iter().filter(|&&d| d > t).count();
    assert!(
        (over(tolerance * (1.0 + 1e-9))..=over(tolerance * (1.0 - 1e-9)))
            .contains(&fit.points_over_tolerance),
        "{} against {}",
        fit.points_over_tolerance,
        over(tolerance)
    );
    // The level cap is counted where it stops the subdivision.
    let capped = fit_mras(
        &points,
        &normals,
        &MrasOptions::default().max_level(3),
        &|_| true,
    )
    .expect("fit");
    assert!(
        capped.capped_cells > 0 && !capped.tolerance_met(),
        "{}",
        capped.capped_cells
    );
}

/// Looser still, the trace norm's weight `λ ε₀²` used to shrink every offset to nothing and
/// the root cell was dropped at rank 0 (its values at the points are all near 0, the offset
/// being the whole field there): a unit sphere at 0.03 meshed as 10 components, at 0.1 the
/// field was 0 everywhere. Now the weight stops growing past a tolerance of 1% and the root is
/// always stored; a field flat at the points is counted.
#[test]
fn a_very_loose_tolerance_still_gives_the_surface() {
    let (points, normals) = sphere(2000, 1.0);
    for tolerance in [0.03, 0.1, 0.5] {
        let fit = fit(
            &points,
            &normals,
            &MrasOptions::default().tolerance(tolerance),
        );
        assert_eq!(fit.levels[0].dropped, 0, "{tolerance}");
        assert_eq!(fit.flat_points, 0, "{tolerance}");
        if tolerance > 0.1 {
            // Half the diagonal: one rank-1 root cell, within 0.26 of it, is all it asks.
            continue;
        }
        assert!(fit.field.value(&[0.0; 3]) < -0.2, "{tolerance}");
        for axis in 0..3 {
            let at = |r: f64| std::array::from_fn(|a| if a == axis { r } else { 0.0 });
            assert!(fit.field.value(&at(0.92)) < 0.0, "{tolerance}");
            assert!(fit.field.value(&at(1.08)) > 0.0, "{tolerance}");
        }
    }
    // A weight far too large flattens the field: counted, not hidden.
    let flat = fit(
        &points,
        &normals,
        &MrasOptions {
            lambda: 1e6,
            ..MrasOptions::default().max_level(2)
        },
    );
    assert!(flat.flat_points > points.len() / 2, "{}", flat.flat_points);
}

/// The fit works in its unit cube: coordinates of 1e155 or 1e-100 fit as the unit sphere does
/// (1e155's squares overflowed: "the SVD did not converge"); a cloud whose extent overflows is
/// refused by name. (Below about 1e-150 the neighbour searches' squared distances underflow,
/// and the stray-point screen then sets aside other points.)
#[test]
fn tiny_and_huge_coordinates_fit_as_unit_ones() {
    let (points, normals) = sphere(500, 1.0);
    let unit = fit(&points, &normals, &MrasOptions::default());
    for scale in [1e155, 1e-100] {
        let scaled: Vec<P> = points.iter().map(|p| p.map(|v| v * scale)).collect();
        let f = fit(&scaled, &normals, &MrasOptions::default());
        assert_eq!(f.field.storage(), unit.field.storage(), "{scale}");
        assert!((f.max_error() - unit.max_error()).abs() < 1e-9, "{scale}");
    }
    // A sphere of radius 1e308: its extent, 2e308, overflows.
    let far: Vec<P> = points.iter().map(|p| p.map(|v| v * 1e308)).collect();
    assert!(matches!(
        fit_mras(&far, &normals, &MrasOptions::default(), &|_| true),
        Err(MrasError::Overflow { .. })
    ));
}

#[test]
fn stray_points_are_set_aside_not_made_surface() {
    // A sphere of 3,000 points and 60 points scattered in its box, at least 0.3 off the
    // sphere, with random normals (a scan's stray samples). The default fit sets exactly those
    // aside and keeps its zero set away from them, inside and outside where they are; told to
    // fit every point, MRAS makes them surface.
    use rand::{RngExt, SeedableRng};
    let (mut p, mut n) = sphere(3000, 1.0);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut stray = Vec::new();
    while stray.len() < 60 {
        let q: P = std::array::from_fn(|_| rng.random_range(-1.25..1.25));
        let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        if (r - 1.0).abs() > 0.3 {
            stray.push(p.len());
            p.push(q);
            n.push(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
        }
    }
    let o = MrasOptions::default().max_level(3);
    let near = |f: &MrasFit| {
        stray
            .iter()
            .filter(|&&i| {
                distance_to_zero_set(&f.field, &p[i], 1e-10, 100).is_some_and(|d| d < 0.05)
            })
            .count()
    };
    let clean = fit(&p, &n, &o);
    assert_eq!(clean.outliers, stray);
    let wrong_side = stray
        .iter()
        .filter(|&&i| {
            let r = (p[i][0] * p[i][0] + p[i][1] * p[i][1] + p[i][2] * p[i][2]).sqrt();
            (clean.field.value(&p[i]) > 0.0) != (r > 1.0)
        })
        .count();
    assert_eq!(wrong_side, 0);
    assert_eq!(near(&clean), 0);
    // The sphere itself as without the strays (7.0e-4 of the diagonal at 3 levels).
    let sphere_error = max_distance(&clean, &p[..3000]);
    assert!(sphere_error < 1.5e-3, "{sphere_error}");
    // Measured: all 60 within 0.05 of the zero set.
    let all = fit(&p, &n, &o.clone().outlier_ratio(0.0));
    assert!(all.outliers.is_empty());
    assert!(near(&all) >= 50, "{}", near(&all));
}

/// The CP fit weighted by what the data points read stores fewer numbers than plain CP-ALS
/// under the same bound at the points, with the same distances (the bound is checked exactly
/// at every point either way).
#[test]
fn weighted_cp_stores_less_for_the_same_bound() {
    let (p, n) = torus(60, 24, 1.0, 0.4);
    let options = MrasOptions::default().max_level(4).tolerance(1e-4);
    let weighted = fit(&p, &n, &options);
    let plain = fit(&p, &n, &options.clone().cp_weighted(false));
    let (w, q) = (weighted.field.storage(), plain.field.storage());
    let (dw, dq) = (max_distance(&weighted, &p), max_distance(&plain, &p));
    eprintln!("weighted {w} numbers, max {dw:.3e}; plain {q}, max {dq:.3e}");
    assert!((w as f64) < 0.85 * q as f64, "weighted {w}, plain {q}");
    assert!(dw < 1.1 * dq + 1e-5, "weighted {dw:.3e}, plain {dq:.3e}");
}

/// The weighted CP fit keeps a hold on the coefficients no data point reads
/// (`CP_UNSEEN_WEIGHT`): without it the 2,000-point bunny sample's field crossed zero far
/// from every point (sheets: 6 mesh components, up to 0.23 of the diagonal from the scan).
/// Every sign change between neighbouring samples of a 32³ grid over the cube lies within a
/// tenth of the diagonal of a point (the capped holes of the base reach 0.05).
#[test]
fn the_zero_set_stays_near_the_points() {
    let (points, normals) = scan("bunny_2k.xyzn");
    let f = fit(&points, &normals, &MrasOptions::default());
    let b = f.field.bounds().expect("a cube");
    let (lo, side) = (b.min(), b.max()[0] - b.min()[0]);
    let n = 33;
    let at = |i: usize, j: usize, k: usize| -> P {
        let t = [i, j, k];
        std::array::from_fn(|a| lo[a] + side * t[a] as f64 / (n - 1) as f64)
    };
    let mut grid = Vec::with_capacity(n * n * n);
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                grid.push(at(i, j, k));
            }
        }
    }
    let mut values = vec![0.0; grid.len()];
    f.field.values(&grid, &mut values);
    let nearest = |x: &P| {
        points
            .iter()
            .map(|p| (0..3).map(|a| (p[a] - x[a]).powi(2)).sum::<f64>())
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    };
    let index = |i: usize, j: usize, k: usize| (i * n + j) * n + k;
    let mut worst: f64 = 0.0;
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let here = index(i, j, k);
                for (di, dj, dk) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                    let (a, b, c) = (i + di, j + dj, k + dk);
                    if a == n || b == n || c == n {
                        continue;
                    }
                    let there = index(a, b, c);
                    if (values[here] > 0.0) != (values[there] > 0.0) {
                        let mid: P =
                            std::array::from_fn(|d| 0.5 * (grid[here][d] + grid[there][d]));
                        worst = worst.max(nearest(&mid));
                    }
                }
            }
        }
    }
    assert!(
        worst < 0.1 * f.diagonal,
        "a zero crossing {:.3} of the diagonal from every point",
        worst / f.diagonal
    );
}

#[test]
fn a_progress_callback_answering_false_cancels_the_fit() {
    let (points, normals) = sphere(600, 1.0);
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let stop_after_three =
        |_: &MrasProgress| calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst) < 3;
    let result = fit_mras(
        &points,
        &normals,
        &MrasOptions::default(),
        &stop_after_three,
    );
    assert!(matches!(result, Err(MrasError::Cancelled)), "{result:?}");
    // A few cells in progress may still report; the fit does not go on to its other levels.
    assert!(calls.load(std::sync::atomic::Ordering::SeqCst) < 20);
}
