//! Restoration against shapes whose truth is known: a sphere with a protrusion, and a noisy
//! sphere.

use zeroset_bases::bspline::{BSplineField, Degree};
use zeroset_field_core::analytic::Sphere;
use zeroset_field_core::field::{FnField, ScalarField};
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::grid::Grid;
use zeroset_field_core::mask::{BoxMask, Face, Side};
use zeroset_restore::denoise::{Denoise, Resampling};
use zeroset_restore::protrusion::Protrusion;

const R: f64 = 0.5;
const CELLS: usize = 48;

fn grid() -> Grid<3> {
    Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [CELLS; 3]).unwrap()
}

fn spacing() -> f64 {
    2.0 / CELLS as f64
}

/// A sphere of radius R with a capsule of radius 0.1 standing on its top, reaching
/// `R + 8` cells: the union of the two signed distances.
fn bumped_sphere() -> impl ScalarField<3> {
    let sphere = Sphere::new([0.0; 3], R);
    let top = R + 8.0 * spacing();
    FnField::new(
        move |p: &Point<3>| {
            let z = p[2].clamp(0.3, top);
            let capsule = (p[0] * p[0] + p[1] * p[1] + (p[2] - z).powi(2)).sqrt() - 0.1;
            sphere.value(p).min(capsule)
        },
        Some(Aabb::centered_cube(1.0).unwrap()),
    )
}

/// The highest z inside the mask's (x, y) range where `field ≤ 0`, scanned in steps of h/8.
fn highest_inside(field: &impl ScalarField<3>, mask_lo: Point<3>, mask_hi: Point<3>) -> f64 {
    let h = spacing();
    let mut best = f64::NEG_INFINITY;
    let steps = ((mask_hi[2] - mask_lo[2]) / (h / 8.0)) as usize;
    let mut x = mask_lo[0];
    while x <= mask_hi[0] {
        let mut y = mask_lo[1];
        while y <= mask_hi[1] {
            for s in (0..=steps).rev() {
                let z = mask_lo[2] + s as f64 * h / 8.0;
                if field.value(&[x, y, z]) <= 0.0 {
                    best = best.max(z);
                    break;
                }
            }
            y += h / 2.0;
        }
        x += h / 2.0;
    }
    best
}

#[test]
fn protrusion_removal_restores_the_sphere_top_and_alpha_flattens() {
    let grid = grid();
    let h = spacing();
    let (lo, hi) = ([-0.3, -0.3, 0.36], [0.3, 0.3, 0.95]);
    let mask = BoxMask::from_corners(&grid, lo, hi).unwrap();
    let bumped = bumped_sphere();
    let before = highest_inside(&bumped, lo, hi);
    assert!(
        before >= R + 6.0 * h,
        "the bump is {} cells high",
        (before - R) / h
    );

    let alphas = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0];
    let mut heights = Vec::new();
    for alpha in alphas {
        let restored = Protrusion::new(Face::new(2, Side::Lower))
            .with_alpha(alpha)
            .apply(&bumped, &grid, &mask)
            .unwrap();
        heights.push(highest_inside(&restored.field, lo, hi));
    }
    let report: Vec<String> = alphas
        .iter()
        .zip(&heights)
        .map(|(a, z)| format!("α={a}: {:+.2} cells", (z - R) / h))
        .collect();
    eprintln!(
        "bump {:.2} cells; top after removal: {}",
        (before - R) / h,
        report.join(", ")
    );
    // A larger α gives a flatter (lower) top.
    for w in heights.windows(2) {
        assert!(w[1] <= w[0], "heights not falling with α: {report:?}");
    }
    // The field's own slope (|∇f| = 1 for a distance) restores the sphere's top within 2 cells.
    let at_one = heights[3];
    assert!((at_one - R).abs() <= 2.0 * h, "α = 1: {report:?}");
    // The default α (f's mean slope across E) too.
    let default = Protrusion::new(Face::new(2, Side::Lower))
        .apply(&bumped, &grid, &mask)
        .unwrap();
    let z = highest_inside(&default.field, lo, hi);
    eprintln!(
        "default α = {:?}: top {:+.2} cells",
        default.report.alpha,
        (z - R) / h
    );
    assert!((z - R).abs() <= 2.0 * h);
}

#[test]
fn outside_the_mask_the_field_is_unchanged_up_to_interpolation_error() {
    let grid = grid();
    let mask = BoxMask::from_corners(&grid, [-0.3, -0.3, 0.36], [0.3, 0.3, 0.95]).unwrap();
    let bumped = bumped_sphere();
    let restored = Protrusion::new(Face::new(2, Side::Lower))
        .apply(&bumped, &grid, &mask)
        .unwrap()
        .field;
    let samples = grid.sample(&bumped);
    let plain = BSplineField::interpolate(grid, samples.clone(), Degree::Quadratic).unwrap();
    let mut worst_sample = 0.0f64;
    let mut worst_between = 0.0f64;
    let mut worst_change = 0.0f64;
    for (l, &sample) in samples.iter().enumerate() {
        let index = grid.multi_index(l);
        if mask.contains(index) {
            continue;
        }
        worst_sample = worst_sample.max((restored.value(&grid.point(index)) - sample).abs());
        // Half a cell off the samples, at least three cells from the mask: the spline's
        // interpolation error of f, plus the prefilter's tail (0.17 per cell) of the change.
        let far = (0..3).any(|a| index[a] + 3 < mask.lo()[a] || index[a] > mask.hi()[a] + 3);
        if far && index.iter().all(|&i| i + 1 < CELLS) {
            let p = grid.point(index).map(|x| x + 0.5 * spacing());
            let truth = bumped.value(&p);
            worst_change = worst_change.max((restored.value(&p) - plain.value(&p)).abs());
            // Beyond f's own interpolation error (large at the distance's kinks).
            let excess = (restored.value(&p) - truth).abs() - (plain.value(&p) - truth).abs();
            worst_between = worst_between.max(excess);
        }
    }
    eprintln!(
        "outside the mask: at samples {worst_sample:.1e}; 3+ cells off, vs f beyond f's interpolation error {worst_between:.1e}, \
         vs f's own spline {worst_change:.1e}"
    );
    assert!(worst_sample < 1e-10, "{worst_sample:e}");
    assert!(worst_between < 0.01 * spacing(), "{worst_between:e}");
    assert!(worst_change < 0.01 * spacing(), "{worst_change:e}");
}

/// Noise at the grid scale: a fixed sum of plane waves with wavelengths of 2–3 cells.
fn noisy_sphere(amplitude: f64) -> (Sphere, impl ScalarField<3>) {
    let sphere = Sphere::new([0.0; 3], 0.6);
    let h = spacing();
    let waves: Vec<([f64; 3], f64)> = (0..12)
        .map(|j| {
            let t = j as f64;
            let dir = [
                (1.3 * t).cos(),
                (2.1 * t + 0.4).sin(),
                (0.7 * t + 1.0).cos(),
            ];
            let norm = dir.iter().map(|d| d * d).sum::<f64>().sqrt();
            let k = std::f64::consts::PI / h * (0.7 + 0.25 * (t * 0.9).sin());
            (dir.map(|d| d / norm * k), 1.7 * t)
        })
        .collect();
    let field = FnField::new(
        move |p: &Point<3>| {
            let noise: f64 = waves
                .iter()
                .map(|(k, phase)| (k[0] * p[0] + k[1] * p[1] + k[2] * p[2] + phase).sin())
                .sum::<f64>()
                / (waves.len() as f64 / 2.0).sqrt();
            sphere.value(p) + amplitude * noise
        },
        Some(Aabb::centered_cube(1.0).unwrap()),
    );
    (sphere, field)
}

fn rms_in_mask(a: &impl ScalarField<3>, b: &Sphere, grid: &Grid<3>, mask: &BoxMask<3>) -> f64 {
    let (sum, n) = mask.indices().fold((0.0, 0), |(s, n), i| {
        let p = grid.point(i);
        (s + (a.value(&p) - b.value(&p)).powi(2), n + 1)
    });
    (sum / n as f64).sqrt()
}

#[test]
fn denoising_a_noisy_sphere_lowers_the_rms_error_at_least_threefold() {
    let grid = grid();
    // Noise of half a cell's amplitude at wavelengths of 2–3 cells.
    let (sphere, noisy) = noisy_sphere(0.5 * spacing());
    // A box around the sphere's top cap (22 × 22 × 14 cells).
    let mask = BoxMask::from_corners(&grid, [-0.45, -0.45, 0.3], [0.45, 0.45, 0.9]).unwrap();
    let before = rms_in_mask(&noisy, &sphere, &grid, &mask);
    let mut ratios = Vec::new();
    for resampling in [Resampling::Area, Resampling::Point] {
        // Coarse cells of about 3.5 fine cells.
        let out = Denoise::new([6, 6, 4])
            .with_resampling(resampling)
            .apply(&noisy, &grid, &mask)
            .unwrap();
        let after = rms_in_mask(&out.field, &sphere, &grid, &mask);
        eprintln!(
            "{resampling:?}: RMS in mask {before:.2e} -> {after:.2e} ({:.1}x)",
            before / after
        );
        ratios.push(before / after);
    }
    assert!(ratios[0] >= 3.0, "area resampling: only {:.2}x", ratios[0]);
}

/// The largest `|a_i − b_i|`.
fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// A harmonic quadratic is its own discrete harmonic fill (second differences are exact on
/// quadratics): restored inside a mask with no Neumann face, on cells of three different
/// shapes — cubes, twice as tall as wide, and a quarter as tall — it must come back to
/// rounding, by every route. Weighing the neighbours alike whatever the cells (the paper's
/// cubic stencil) misses by 0.2 on the flat cells.
#[test]
fn a_harmonic_field_is_restored_exactly_on_cells_that_are_not_cubes() {
    use std::sync::Arc;
    use zeroset_restore::protrusion::Solver;
    let u = |p: &Point<3>| p[0] * p[0] + 0.5 * p[1] * p[1] - 1.5 * p[2] * p[2];
    let cube = Aabb::centered_cube(1.0).unwrap();
    for counts in [[40, 40, 40], [40, 40, 20], [20, 40, 80]] {
        let grid = Grid::cell_centered(cube, counts).unwrap();
        let f: Vec<f64> = grid.points().iter().map(u).collect();
        let mask = BoxMask::from_corners(&grid, [-0.5; 3], [0.5; 3]).unwrap();
        for solver in [
            Solver::Separable,
            Solver::PreconditionedLsqr { tolerance: 1e-14 },
            Solver::General(Arc::new(zeroset_solvers::SparseQr::default())),
        ] {
            let name = format!("{solver:?}");
            let (g, _) = Protrusion::default()
                .with_solver(solver)
                .restore_samples(&grid, &f, &mask)
                .unwrap();
            let worst = max_difference(&g, &f);
            assert!(worst < 1e-10, "{counts:?} {name}: off by {worst:e}");
        }
    }
}

/// De-noising never makes noise larger: with as many coarse cells as the mask has fine ones it
/// gives the samples back (each coarse cell is one sample: nothing to smooth), and with fewer it
/// lowers the error of a sphere with a checkerboard of noise, the finest oscillation a grid
/// holds. Fitting the coarse data as the spline's continuous cell means amplified it 3.4×.
#[test]
fn denoising_never_amplifies_the_finest_noise() {
    let grid = grid();
    let sphere = Sphere::new([0.0; 3], R);
    let clean: Vec<f64> = grid.points().iter().map(|p| sphere.value(p)).collect();
    let noisy: Vec<f64> = grid
        .points()
        .iter()
        .zip(&clean)
        .enumerate()
        .map(|(l, (_, v))| {
            let [i, j, k] = [l / (CELLS * CELLS), (l / CELLS) % CELLS, l % CELLS];
            v + if (i + j + k) % 2 == 0 { 0.01 } else { -0.01 }
        })
        .collect();
    let field = BSplineField::interpolate(grid, noisy.clone(), Degree::Quadratic).unwrap();
    let mask = BoxMask::from_corners(&grid, [-0.3; 3], [0.3; 3]).unwrap();
    let extent = mask.extent();
    let rms = |g: &[f64]| {
        let strides = [CELLS * CELLS, CELLS, 1];
        let sum: f64 = mask
            .indices()
            .map(|i| {
                let l: usize = (0..3).map(|a| i[a] * strides[a]).sum();
                (g[l] - clean[l]).powi(2)
            })
            .sum();
        (sum / mask.len() as f64).sqrt()
    };
    let before = rms(&noisy);
    let same = Denoise::new(extent)
        .restore_samples(&field, &grid, &noisy, &mask)
        .unwrap();
    let moved = max_difference(&same, &noisy);
    assert!(
        moved < 1e-12,
        "coarse = extent moved the samples by {moved:e}"
    );
    for c in (extent[0] / 2..extent[0]).rev() {
        let g = Denoise::new([c; 3])
            .restore_samples(&field, &grid, &noisy, &mask)
            .unwrap();
        let after = rms(&g);
        assert!(
            after < before,
            "coarse {c} of {extent:?}: RMS {before:.2e} -> {after:.2e}"
        );
    }
}
