//! B-spline interpolation: exactness at the samples, polynomial reproduction, derivatives
//! against finite differences, a naive reference evaluation, the basis rows, determinism and
//! errors.

use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zeroset_bases::bspline::{
    BSplineField, BSplineSpace, Boundary, Degree, Derivatives, prefilter,
};
use zeroset_field_core::Error;
use zeroset_field_core::basis::{Basis, BasisField, BasisRow};
use zeroset_field_core::field::{FnField, ScalarField};
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::grid::Grid;

const DEGREES: [Degree; 2] = [Degree::Quadratic, Degree::Cubic];
const BOUNDARIES: [Boundary; 2] = [Boundary::HalfSample, Boundary::WholeSample];

fn random_values(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| rng.random::<f64>() * 2.0 - 1.0).collect()
}

fn box_of<const D: usize>() -> Aabb<D> {
    let min: Point<D> = std::array::from_fn(|a| -1.0 + 0.25 * a as f64);
    let max: Point<D> = std::array::from_fn(|a| 1.0 + 0.5 * a as f64);
    Aabb::new(min, max).unwrap()
}

/// A random point of the box, `margin` (in cells) away from its faces.
fn random_point<const D: usize>(grid: &Grid<D>, rng: &mut ChaCha8Rng, margin: f64) -> Point<D> {
    let (min, h, n) = (grid.bounds().min(), grid.spacing(), grid.counts());
    std::array::from_fn(|a| {
        let lo = min[a] + margin * h[a];
        let hi = min[a] + (n[a] as f64) * h[a] - margin * h[a];
        lo + (hi - lo) * rng.random::<f64>()
    })
}

// ---------------------------------------------------------------------------------------------
// An independent, naive reference: the piecewise kernels, the mirror, and a sum over every
// coefficient in a generous neighbourhood.

fn beta(degree: Degree, t: f64) -> f64 {
    let a = t.abs();
    match degree {
        Degree::Quadratic if a <= 0.5 => 0.75 - a * a,
        Degree::Quadratic if a < 1.5 => 0.5 * (1.5 - a) * (1.5 - a),
        Degree::Cubic if a <= 1.0 => 2.0 / 3.0 - a * a + 0.5 * a * a * a,
        Degree::Cubic if a < 2.0 => (2.0 - a).powi(3) / 6.0,
        _ => 0.0,
    }
}

/// Mirror a coefficient index into `[0, n)` by repeated reflection.
fn mirror(mut j: i64, n: i64, boundary: Boundary) -> usize {
    if n == 1 {
        return 0;
    }
    loop {
        if j < 0 {
            j = match boundary {
                Boundary::HalfSample => -1 - j,
                Boundary::WholeSample => -j,
            };
        } else if j >= n {
            j = match boundary {
                Boundary::HalfSample => 2 * n - 1 - j,
                Boundary::WholeSample => 2 * n - 2 - j,
            };
        } else {
            return j as usize;
        }
    }
}

fn naive_value<const D: usize>(
    coefficients: &[f64],
    counts: [usize; D],
    degree: Degree,
    boundary: Boundary,
    x: [f64; D],
) -> f64 {
    let mut total = 0.0;
    let ranges: [(i64, i64); D] = std::array::from_fn(|a| {
        let c = x[a].floor() as i64;
        (c - 3, c + 4)
    });
    let mut j: [i64; D] = std::array::from_fn(|a| ranges[a].0);
    'outer: loop {
        let w: f64 = (0..D).map(|a| beta(degree, x[a] - j[a] as f64)).product();
        if w != 0.0 {
            let linear = (0..D).fold(0, |acc, a| {
                acc * counts[a] + mirror(j[a], counts[a] as i64, boundary)
            });
            total += w * coefficients[linear];
        }
        for a in (0..D).rev() {
            j[a] += 1;
            if j[a] < ranges[a].1 {
                continue 'outer;
            }
            j[a] = ranges[a].0;
        }
        break;
    }
    total
}

// ---------------------------------------------------------------------------------------------

fn check_interpolates<const D: usize>(counts: [usize; D], vertex: bool) {
    let grid = if vertex {
        Grid::vertex_centered(box_of::<D>(), counts).unwrap()
    } else {
        Grid::cell_centered(box_of::<D>(), counts).unwrap()
    };
    for degree in DEGREES {
        for boundary in BOUNDARIES {
            let samples = random_values(grid.len(), 7);
            let f =
                BSplineField::interpolate_with(grid, samples.clone(), degree, boundary).unwrap();
            for (l, s) in samples.iter().enumerate() {
                let p = grid.point(grid.multi_index(l));
                let v = f.value(&p);
                assert!(
                    (v - s).abs() < 1e-12,
                    "{counts:?} {degree:?} {boundary:?} sample {l}: {v} vs {s}"
                );
                let idx = grid.multi_index(l).map(|i| i as f64);
                assert!((f.value_at_index(idx) - s).abs() < 1e-12);
            }
        }
    }
}

#[test]
fn interpolates_its_samples_in_3d() {
    for counts in [
        [5, 7, 3],
        [1, 4, 2],
        [2, 2, 2],
        [6, 1, 5],
        [1, 1, 1],
        [9, 2, 11],
    ] {
        check_interpolates(counts, false);
    }
    check_interpolates([5, 2, 4], true);
}

#[test]
fn interpolates_its_samples_in_2d() {
    for counts in [[5, 7], [1, 3], [2, 9], [1, 1], [13, 2]] {
        check_interpolates(counts, false);
    }
    check_interpolates([3, 6], true);
}

#[test]
fn sample_interpolates_an_analytic_field() {
    let grid = Grid::cell_centered(box_of::<3>(), [6, 5, 7]).unwrap();
    let field = FnField::new(|p: &Point<3>| (p[0] * 2.0).sin() + p[1] * p[2], None);
    let f = BSplineField::sample(&field, grid, Degree::Quadratic).unwrap();
    assert_eq!(f.boundary(), Boundary::HalfSample);
    assert_eq!(f.degree(), Degree::Quadratic);
    for l in 0..grid.len() {
        let p = grid.point(grid.multi_index(l));
        assert!((f.value(&p) - field.value(&p)).abs() < 1e-12);
    }
}

#[test]
fn constants_are_reproduced_everywhere() {
    let grid = Grid::cell_centered(box_of::<3>(), [4, 6, 5]).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for degree in DEGREES {
        for boundary in BOUNDARIES {
            let f = BSplineField::interpolate_with(grid, vec![-1.75; grid.len()], degree, boundary)
                .unwrap();
            for _ in 0..200 {
                // Including points up to a cell outside the box (clamped).
                let p = random_point(&grid, &mut rng, -1.0);
                let e = f.evaluate(&p, Derivatives::Hessian);
                assert!((e.value + 1.75).abs() < 1e-13);
                assert!(e.gradient.iter().all(|g| g.abs() < 1e-11));
                assert!(e.hessian.iter().flatten().all(|h| h.abs() < 1e-9));
            }
        }
    }
}

/// Polynomials up to the spline's degree are reproduced away from the boundary, where the mirror
/// no longer reaches (its effect decays like |z|^distance, z = −0.17 or −0.27).
fn check_polynomial_reproduction<const D: usize>(
    degree: Degree,
    counts: [usize; D],
    margin: f64,
    poly: impl Fn(&Point<D>) -> f64 + Send + Sync,
) {
    let grid = Grid::cell_centered(box_of::<D>(), counts).unwrap();
    let field = FnField::new(poly, None);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for boundary in BOUNDARIES {
        let samples = grid.sample(&field);
        let f = BSplineField::interpolate_with(grid, samples, degree, boundary).unwrap();
        let mut worst: f64 = 0.0;
        for _ in 0..300 {
            let p = random_point(&grid, &mut rng, margin);
            worst = worst.max((f.value(&p) - field.value(&p)).abs());
        }
        assert!(worst < 1e-10, "{degree:?} {boundary:?}: error {worst:e}");
    }
}

#[test]
fn quadratics_are_reproduced_in_the_interior() {
    let q2 = |p: &Point<2>| {
        0.5 + p[0] - 0.7 * p[1] + 0.3 * p[0] * p[0] - 0.4 * p[0] * p[1] + 0.2 * p[1] * p[1]
    };
    check_polynomial_reproduction(Degree::Quadratic, [40, 44], 15.0, q2);
    check_polynomial_reproduction(Degree::Cubic, [48, 48], 20.0, q2);
    let q3 = |p: &Point<3>| 1.0 - p[2] + 0.5 * p[0] * p[2] + 0.25 * p[1] * p[1] - 0.3 * p[2] * p[2];
    check_polynomial_reproduction(Degree::Quadratic, [34, 33, 32], 15.0, q3);
}

#[test]
fn cubics_are_reproduced_in_the_interior_by_the_cubic_spline() {
    let c2 = |p: &Point<2>| {
        0.1 + p[0] * p[0] * p[0] - 0.5 * p[0] * p[0] * p[1] + 0.3 * p[1] * p[1] * p[1] - p[0]
    };
    check_polynomial_reproduction(Degree::Cubic, [48, 50], 20.0, c2);
}

#[test]
fn values_match_a_naive_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for counts in [[5usize, 7, 3], [1, 4, 2], [2, 3, 6]] {
        let grid = Grid::cell_centered(box_of::<3>(), counts).unwrap();
        let c = random_values(grid.len(), 9);
        for degree in DEGREES {
            for boundary in BOUNDARIES {
                let f = BSplineField::from_coefficients(grid, c.clone(), degree, boundary).unwrap();
                for _ in 0..200 {
                    let p = random_point(&grid, &mut rng, 0.0);
                    let x = grid.continuous_index(&p);
                    let naive = naive_value(&c, counts, degree, boundary, x);
                    assert!(
                        (f.value(&p) - naive).abs() < 1e-13,
                        "{counts:?} {degree:?} {boundary:?} at {x:?}"
                    );
                }
            }
        }
    }
}

/// Random points whose continuous indices stay `gap` away from the knots (half-integers for
/// the quadratic, integers for the cubic), so that finite differences see one polynomial piece.
fn points_off_knots<const D: usize>(
    grid: &Grid<D>,
    degree: Degree,
    rng: &mut ChaCha8Rng,
    gap: f64,
) -> Vec<Point<D>> {
    let knot_offset = match degree {
        Degree::Quadratic => 0.5,
        Degree::Cubic => 0.0,
    };
    let mut out = Vec::new();
    while out.len() < 100 {
        let p = random_point(grid, rng, 0.0);
        let x = grid.continuous_index(&p);
        let ok = x.iter().all(|&xa| {
            let f = (xa - knot_offset).rem_euclid(1.0);
            f > gap && f < 1.0 - gap
        });
        if ok {
            out.push(p);
        }
    }
    out
}

fn check_derivatives<const D: usize>(counts: [usize; D]) {
    let grid = Grid::cell_centered(box_of::<D>(), counts).unwrap();
    let c = random_values(grid.len(), 13);
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for degree in DEGREES {
        for boundary in BOUNDARIES {
            let f = BSplineField::from_coefficients(grid, c.clone(), degree, boundary).unwrap();
            for p in points_off_knots(&grid, degree, &mut rng, 0.05) {
                let e = f.evaluate(&p, Derivatives::Hessian);
                assert!((e.value - f.value(&p)).abs() < 1e-14);
                assert_eq!(e.gradient, f.gradient(&p));
                assert_eq!(e.gradient, ScalarField::gradient(&f, &p));
                assert_eq!(e.hessian, f.hessian(&p));
                let h = 1e-5 * grid.spacing().iter().fold(f64::INFINITY, |m, &s| m.min(s));
                for a in 0..D {
                    let (mut plus, mut minus) = (p, p);
                    plus[a] += h;
                    minus[a] -= h;
                    let fd = (f.value(&plus) - f.value(&minus)) / (plus[a] - minus[a]);
                    let scale = 1.0 + e.gradient[a].abs();
                    assert!(
                        (fd - e.gradient[a]).abs() < 1e-7 * scale,
                        "{degree:?} {boundary:?} ∂{a}: {fd} vs {}",
                        e.gradient[a]
                    );
                    let (gp, gm) = (f.gradient(&plus), f.gradient(&minus));
                    for b in 0..D {
                        let fd = (gp[b] - gm[b]) / (plus[a] - minus[a]);
                        let scale = 1.0 + e.hessian[a][b].abs();
                        assert!(
                            (fd - e.hessian[a][b]).abs() < 1e-6 * scale,
                            "{degree:?} {boundary:?} ∂{a}∂{b}: {fd} vs {}",
                            e.hessian[a][b]
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn gradient_and_hessian_match_finite_differences() {
    check_derivatives([6, 5, 7]);
    check_derivatives([9, 4]);
}

#[test]
fn points_outside_are_clamped_to_the_box() {
    let grid = Grid::cell_centered(box_of::<2>(), [5, 6]).unwrap();
    let f = BSplineField::interpolate(grid, random_values(30, 2), Degree::Quadratic).unwrap();
    let (min, max) = (grid.bounds().min(), grid.bounds().max());
    for (outside, clamped) in [
        ([min[0] - 3.0, 0.3], [min[0], 0.3]),
        ([max[0] + 0.1, max[1] + 7.0], [max[0], max[1]]),
        ([0.2, min[1] - 1e-3], [0.2, min[1]]),
    ] {
        // The box face maps to index −½ (or n − ½) only up to rounding.
        assert!((f.value(&outside) - f.value(&clamped)).abs() < 1e-12);
        let (g, gc) = (f.gradient(&outside), f.gradient(&clamped));
        assert!((0..2).all(|a| (g[a] - gc[a]).abs() < 1e-10 * (1.0 + gc[a].abs())));
    }
    assert_eq!(ScalarField::bounds(&f), Some(grid.bounds()));
}

/// Batched evaluation (which reorders large batches on large grids) against pointwise calls.
fn check_batched<const D: usize>(counts: [usize; D], points: usize) {
    let grid = Grid::cell_centered(box_of::<D>(), counts).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let mut pts: Vec<Point<D>> = (0..points)
        .map(|_| random_point(&grid, &mut rng, -0.5))
        .collect();
    pts[7][0] = f64::NAN;
    for degree in DEGREES {
        let f = BSplineField::interpolate(grid, random_values(grid.len(), 21), degree).unwrap();
        for n in [pts.len(), 100] {
            let pts = &pts[..n];
            let mut out = vec![0.0; n];
            ScalarField::values(&f, pts, &mut out);
            for (p, v) in pts.iter().zip(&out) {
                let single = f.value(p);
                assert!(v.to_bits() == single.to_bits() || (v.is_nan() && single.is_nan()));
            }
            assert!(out[7].is_nan());
            let indices: Vec<[f64; D]> = pts.iter().map(|p| grid.continuous_index(p)).collect();
            let mut out_idx = vec![0.0; n];
            f.values_at_indices(&indices, &mut out_idx);
            for (a, b) in out.iter().zip(&out_idx) {
                assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
            }
        }
    }
}

#[test]
fn batched_values_equal_pointwise_values_bit_for_bit() {
    // Large enough (≥ 32,768 coefficients, ≥ 16,384 points) for the reordered path.
    check_batched([40, 40, 40], 20_000);
    check_batched([50, 37, 23], 20_000);
    check_batched([300, 217], 20_000);
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let shape = [37, 41, 29];
    let data = random_values(shape.iter().product(), 31);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut c = data.clone();
                prefilter(&mut c, shape, Degree::Quadratic, Boundary::WholeSample).unwrap();
                let grid = Grid::cell_centered(box_of::<3>(), shape).unwrap();
                let f = BSplineField::from_coefficients(
                    grid,
                    c.clone(),
                    Degree::Quadratic,
                    Boundary::WholeSample,
                )
                .unwrap();
                let mut rng = ChaCha8Rng::seed_from_u64(1);
                let pts: Vec<Point<3>> = (0..30_000)
                    .map(|_| random_point(&grid, &mut rng, 0.0))
                    .collect();
                let mut v = vec![0.0; pts.len()];
                f.values(&pts, &mut v);
                (c, v)
            })
    };
    let one = run(1);
    let four = run(4);
    assert!(
        one.0
            .iter()
            .zip(&four.0)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    assert!(
        one.1
            .iter()
            .zip(&four.1)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
}

#[test]
fn basis_rows_give_the_same_field() {
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    for degree in DEGREES {
        for boundary in BOUNDARIES {
            for counts in [[5usize, 4, 6], [1, 3, 2]] {
                let grid = Grid::cell_centered(box_of::<3>(), counts).unwrap();
                let c = random_values(grid.len(), 43);
                let space = BSplineSpace::new(grid, degree, boundary);
                assert_eq!(space.num_coefficients(), grid.len());
                let basis_field = BasisField::new(space.clone(), c.clone()).unwrap();
                let f = BSplineField::from_coefficients(grid, c, degree, boundary).unwrap();
                assert_eq!(f.space(), space);
                let mut row = BasisRow::new();
                for _ in 0..200 {
                    let p = random_point(&grid, &mut rng, -0.7);
                    assert!((basis_field.value(&p) - f.value(&p)).abs() < 1e-14);
                    let (g1, g2) = (basis_field.gradient(&p), f.gradient(&p));
                    for a in 0..3 {
                        assert!((g1[a] - g2[a]).abs() < 1e-14 * (1.0 + g2[a].abs()));
                    }
                    space.eval_row(&p, true, &mut row);
                    assert!(row.indices.windows(2).all(|w| w[0] < w[1]));
                    assert!(row.indices.len() <= space.max_row_nnz());
                    assert_eq!(row.values.len(), row.indices.len());
                    assert_eq!(row.gradients.len(), row.indices.len());
                    assert!((row.values.iter().sum::<f64>() - 1.0).abs() < 1e-14);
                }
            }
        }
    }
}

#[test]
fn interior_rows_have_27_or_64_entries() {
    let grid = Grid::cell_centered(box_of::<3>(), [8, 8, 8]).unwrap();
    let p = grid.point([4, 4, 4]);
    let mut row = BasisRow::new();
    BSplineSpace::new(grid, Degree::Quadratic, Boundary::HalfSample).eval_row(&p, false, &mut row);
    assert_eq!(row.indices.len(), 27);
    assert!(row.gradients.is_empty());
    BSplineSpace::new(grid, Degree::Cubic, Boundary::HalfSample).eval_row(&p, false, &mut row);
    assert_eq!(row.indices.len(), 64);
    // At the corner sample the mirrored B-splines fold onto their images: 2×2×2 entries.
    let corner = grid.point([0, 0, 0]);
    BSplineSpace::new(grid, Degree::Quadratic, Boundary::HalfSample)
        .eval_row(&corner, false, &mut row);
    assert_eq!(row.indices.len(), 8);
}

#[test]
fn errors_name_the_problem() {
    let grid = Grid::cell_centered(box_of::<2>(), [3, 4]).unwrap();
    match BSplineField::interpolate(grid, vec![0.0; 11], Degree::Quadratic) {
        Err(Error::ShapeMismatch {
            expected: 12,
            got: 11,
            ..
        }) => {}
        other => panic!("expected ShapeMismatch, got {other:?}"),
    }
    let mut samples = vec![0.0; 12];
    samples[5] = f64::NAN;
    match BSplineField::interpolate(grid, samples, Degree::Cubic) {
        Err(Error::NonFinite { record: 5, .. }) => {}
        other => panic!("expected NonFinite, got {other:?}"),
    }
    let mut coefficients = vec![0.0; 12];
    coefficients[11] = f64::INFINITY;
    assert!(matches!(
        BSplineField::from_coefficients(grid, coefficients, Degree::Cubic, Boundary::HalfSample),
        Err(Error::NonFinite { record: 11, .. })
    ));
    assert!(matches!(
        BSplineField::from_coefficients(grid, vec![0.0; 13], Degree::Cubic, Boundary::HalfSample),
        Err(Error::ShapeMismatch {
            expected: 12,
            got: 13,
            ..
        })
    ));
    let mut data = vec![0.0; 12];
    assert!(matches!(
        prefilter(&mut data, [3, 5], Degree::Quadratic, Boundary::HalfSample),
        Err(Error::ShapeMismatch {
            expected: 15,
            got: 12,
            ..
        })
    ));
}

fn degree_strategy() -> impl Strategy<Value = Degree> {
    prop_oneof![Just(Degree::Quadratic), Just(Degree::Cubic)]
}

fn boundary_strategy() -> impl Strategy<Value = Boundary> {
    prop_oneof![Just(Boundary::HalfSample), Just(Boundary::WholeSample)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn prefilter_then_evaluate_at_the_samples_gives_the_data_back(
        shape in prop::array::uniform3(1usize..7),
        degree in degree_strategy(),
        boundary in boundary_strategy(),
        seed in any::<u64>(),
    ) {
        let data = random_values(shape.iter().product(), seed);
        let grid = Grid::cell_centered(box_of::<3>(), shape).unwrap();
        let f = BSplineField::interpolate_with(grid, data.clone(), degree, boundary).unwrap();
        for (l, d) in data.iter().enumerate() {
            let x = grid.multi_index(l).map(|i| i as f64);
            prop_assert!((f.value_at_index(x) - d).abs() < 1e-12);
        }
    }

    #[test]
    fn prefilter_in_2d_matches_the_naive_sampled_kernel(
        shape in prop::array::uniform2(1usize..9),
        degree in degree_strategy(),
        boundary in boundary_strategy(),
        seed in any::<u64>(),
    ) {
        let data = random_values(shape.iter().product(), seed);
        let mut c = data.clone();
        prefilter(&mut c, shape, degree, boundary).unwrap();
        for (l, d) in data.iter().enumerate() {
            let x = [(l / shape[1]) as f64, (l % shape[1]) as f64];
            prop_assert!((naive_value(&c, shape, degree, boundary, x) - d).abs() < 1e-12);
        }
    }
}
