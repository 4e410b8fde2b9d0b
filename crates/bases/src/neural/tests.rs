//! Derivatives against finite differences: the input jets of the field and the parameter
//! gradient of the loss (the double backward), for both activations, both dimensions and an
//! uneven architecture.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};

use super::engine::{self, Work};
use super::net::pairs;
use super::train::Trainer;
use super::*;

fn net<const D: usize>(widths: &[usize], act: Activation, seed: u64) -> NeuralField<D> {
    let domain = Aabb::new([-0.7; D], [1.3; D]).unwrap();
    let arch = Architecture::new(widths.to_vec(), act).unwrap();
    let f = NeuralField::initial(arch.clone(), domain, seed);
    // Non-zero biases and a non-trivial output scale, so that every parameter matters.
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
    let params: Vec<f64> = f
        .parameters()
        .iter()
        .map(|&w| w + 0.3 * (rng.random::<f64>() - 0.5))
        .collect();
    NeuralField::new(arch, params, f.centre(), f.input_scale(), 1.7, domain).unwrap()
}

fn random_points<const D: usize>(n: usize, seed: u64) -> Vec<Point<D>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| std::array::from_fn(|_| 2.0 * rng.random::<f64>() - 0.7))
        .collect()
}

fn check_jets<const D: usize>(f: &NeuralField<D>) {
    let h = 1e-5;
    for x in random_points::<D>(6, 3) {
        let (v, g, hess) = f.jet(&x);
        assert_eq!(v, f.value(&x));
        assert_eq!(g, f.gradient(&x));
        for k in 0..D {
            let mut a = x;
            let mut b = x;
            a[k] += h;
            b[k] -= h;
            let fd = (f.value(&a) - f.value(&b)) / (2.0 * h);
            assert!(
                (fd - g[k]).abs() < 1e-7 * (1.0 + g[k].abs()),
                "∂{k}: {fd} vs {}",
                g[k]
            );
            let (ga, gb) = (f.gradient(&a), f.gradient(&b));
            let full = f.hessian(&x);
            for l in 0..D {
                let fd = (ga[l] - gb[l]) / (2.0 * h);
                assert!(
                    (fd - full[k][l]).abs() < 1e-6 * (1.0 + full[k][l].abs()),
                    "∂{k}∂{l}: {fd} vs {}",
                    full[k][l]
                );
            }
        }
        assert_eq!(hess.len(), D * (D + 1) / 2);
    }
}

#[test]
fn input_derivatives_match_finite_differences() {
    for act in [Activation::Tanh, Activation::Softplus] {
        check_jets(&net::<2>(&[32, 32], act, 1));
        check_jets(&net::<3>(&[7, 5, 4], act, 2));
        check_jets(&net::<2>(&[3], act, 3));
    }
}

/// The batched pass with jets gives the pointwise jets (to rounding).
fn check_batched<const D: usize>(f: &NeuralField<D>) {
    let pts = random_points::<D>(37, 9);
    let mut work = Work::default();
    work.prepare(f.layout(), pts.len(), true, false);
    engine::forward(f, &pts, &mut work);
    let n = pts.len();
    let mut values = vec![0.0; n];
    f.values(&pts, &mut values);
    for (p, x) in pts.iter().enumerate() {
        let (v, g, h) = f.jet(x);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + b.abs());
        assert!(close(work.f[p], v), "{} vs {v}", work.f[p]);
        assert!(close(values[p], v));
        for (k, gk) in g.iter().enumerate() {
            assert!(close(work.f[(1 + k) * n + p], *gk));
        }
        for (q, hq) in h.iter().enumerate() {
            assert!(close(work.f[(1 + D + q) * n + p], *hq), "{q}");
        }
    }
}

#[test]
fn batched_jets_match_pointwise_jets() {
    for act in [Activation::Tanh, Activation::Softplus] {
        check_batched(&net::<2>(&[32, 32], act, 4));
        check_batched(&net::<3>(&[6, 9, 5], act, 5));
    }
}

/// A trainer with constraints and auxiliary points for the loss-gradient checks.
fn trainer<const D: usize>(
    f: &NeuralField<D>,
    at: CurvatureSites,
    dropout: f64,
) -> (Trainer<D>, NeuralParams) {
    let pts = random_points::<D>(70, 11);
    let targets: Vec<f64> = pts.iter().map(|p| p[0] * p[0] - 0.3).collect();
    let mut params = NeuralParams::default()
        .with_aux_points(150)
        .with_dropout(dropout);
    params.curvature_at = at;
    let t = Trainer::new(f, &pts, &targets, &params, f.domain(), 0.37);
    (t, params)
}

fn check_loss_gradient<const D: usize>(f: &NeuralField<D>, at: CurvatureSites, dropout: f64) {
    let (mut t, _) = trainer(f, at, dropout);
    if dropout > 0.0 {
        t.draw_masks();
    }
    let mut grad = vec![0.0; f.parameters().len()];
    let parts = t.evaluate(f, true, &mut grad);
    assert!(parts.curvature > 0.0 && parts.data > 0.0);
    let mut scratch = vec![0.0; grad.len()];
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    // Every parameter of small nets, a random sample of large ones.
    let picks: Vec<usize> = if grad.len() <= 200 {
        (0..grad.len()).collect()
    } else {
        (0..120).map(|_| rng.random_range(0..grad.len())).collect()
    };
    let mut worst: f64 = 0.0;
    for i in picks {
        let h = 1e-6 * (1.0 + f.parameters()[i].abs());
        let mut a = f.clone();
        a.parameters_mut()[i] += h;
        let mut b = f.clone();
        b.parameters_mut()[i] -= h;
        let la = t.evaluate(&a, false, &mut scratch);
        let lb = t.evaluate(&b, false, &mut scratch);
        let fd = ((la.data + la.curvature) - (lb.data + lb.curvature)) / (2.0 * h);
        let err = (fd - grad[i]).abs() / (1.0 + grad[i].abs());
        worst = worst.max(err);
        assert!(
            err < 1e-5,
            "parameter {i}: finite difference {fd}, gradient {}",
            grad[i]
        );
    }
    assert!(worst < 1e-5);
}

#[test]
fn loss_gradient_matches_finite_differences() {
    for act in [Activation::Tanh, Activation::Softplus] {
        for at in [CurvatureSites::Auxiliary, CurvatureSites::Constraints] {
            check_loss_gradient(&net::<2>(&[6, 5], act, 6), at, 0.0);
            check_loss_gradient(&net::<3>(&[5, 4, 3], act, 7), at, 0.0);
            check_loss_gradient(&net::<2>(&[4], act, 8), at, 0.0);
        }
    }
    check_loss_gradient(
        &net::<2>(&[32, 32], Activation::Tanh, 9),
        CurvatureSites::Auxiliary,
        0.0,
    );
    check_loss_gradient(
        &net::<3>(&[32, 32], Activation::Tanh, 10),
        CurvatureSites::Auxiliary,
        0.0,
    );
}

#[test]
fn dropout_gradient_matches_finite_differences_for_fixed_masks() {
    check_loss_gradient(
        &net::<2>(&[6, 5], Activation::Tanh, 12),
        CurvatureSites::Auxiliary,
        0.3,
    );
    check_loss_gradient(
        &net::<3>(&[5, 4], Activation::Softplus, 13),
        CurvatureSites::Constraints,
        0.2,
    );
}

#[test]
fn curvature_term_is_the_thin_plate_sum() {
    // With λ weight w the curvature term is w Σⱼ (f_xx² + 2 f_xy² + f_yy²) at the aux points.
    let f = net::<2>(&[8, 8], Activation::Tanh, 14);
    let (mut t, params) = trainer(&f, CurvatureSites::Auxiliary, 0.0);
    let mut g = vec![0.0; f.parameters().len()];
    let parts = t.evaluate(&f, false, &mut g);
    let aux = auxiliary_points(&f.domain(), params.seed, params.aux_points);
    let expected: f64 = aux
        .iter()
        .map(|y| {
            let h = f.hessian(y);
            0.37 * (h[0][0] * h[0][0] + 2.0 * h[0][1] * h[0][1] + h[1][1] * h[1][1])
        })
        .sum();
    assert!(
        (parts.curvature - expected).abs() < 1e-10 * expected,
        "{} vs {expected}",
        parts.curvature
    );
    assert_eq!(pairs(2), vec![(0, 0), (0, 1), (1, 1)]);
}

#[test]
fn thin_plate_energy_of_a_quadratic_is_exact() {
    // A 1-neuron tanh net is not quadratic, so check the midpoint rule against pointwise
    // Hessians on a coarse grid instead.
    let f = net::<2>(&[5], Activation::Tanh, 15);
    let e = f.thin_plate_energy(4);
    let b = f.domain();
    let (lo, ext) = (b.min(), b.extent());
    let mut s = 0.0;
    for i in 0..4 {
        for j in 0..4 {
            let p = [
                lo[0] + ext[0] * (i as f64 + 0.5) / 4.0,
                lo[1] + ext[1] * (j as f64 + 0.5) / 4.0,
            ];
            let h = f.hessian(&p);
            s += h[0][0].powi(2) + 2.0 * h[0][1].powi(2) + h[1][1].powi(2);
        }
    }
    let expected = s * ext[0] * ext[1] / 16.0;
    assert!((e - expected).abs() < 1e-10 * expected, "{e} vs {expected}");
}

#[test]
fn frames_map_into_the_unit_box() {
    let (c, s) = unit_frame(&[[1.0, 2.0], [3.0, 3.0]]);
    assert_eq!((c, s), ([2.0, 2.5], 1.0));
    let u = to_unit_frame(&[[1.0, 2.0], [3.0, 3.0]], c, s);
    assert_eq!(u, vec![[-1.0, -0.5], [1.0, 0.5]]);
    assert_eq!(unit_frame(&[[5.0, 5.0]]), ([5.0, 5.0], 1.0));
    assert_eq!(unit_frame::<2>(&[]), ([0.0, 0.0], 1.0));
}

#[test]
fn a_scaled_fit_is_the_unit_fit_moved_back() {
    // Points of a circle of radius 40 around (100, -50), targets in units of 5: the scaled fit
    // is the fit of the unit-frame constraints, moved back, value for value.
    let circle: Vec<Point<2>> = (0..24)
        .map(|i| {
            let t = i as f64 * std::f64::consts::TAU / 24.0;
            [100.0 + 40.0 * t.cos(), -50.0 + 40.0 * t.sin()]
        })
        .collect();
    let mut points = circle.clone();
    points.push([100.0, -50.0]);
    let mut targets = vec![0.0; circle.len()];
    targets.push(-5.0);
    let fit = NeuralFit::new(NeuralParams::default().with_steps(40));
    let scaled = fit
        .fit_scaled(&points, &targets, 5.0, &mut |_| {
            std::ops::ControlFlow::Continue(())
        })
        .unwrap();
    let (c, s) = unit_frame(&points);
    let u = to_unit_frame(&points, c, s);
    let z: Vec<f64> = targets.iter().map(|t| t / 5.0).collect();
    let unit = fit.fit(&u, &z).unwrap();
    assert_eq!(scaled.report.loss, unit.report.loss);
    for (p, q) in points.iter().zip(&u) {
        let (a, b) = (scaled.field.value(p), 5.0 * unit.field.value(q));
        assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
    }
    assert!(matches!(
        fit.fit_scaled(&points, &targets, 0.0, &mut |_| {
            std::ops::ControlFlow::Continue(())
        }),
        Err(NeuralError::InvalidParameter { .. })
    ));
}
