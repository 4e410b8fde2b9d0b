//! Neural fields: training behaviour, determinism across thread counts, bad input, the
//! last-layer refit through any least-squares solver, and the field file.

use std::path::Path;

use zeroset_bases::field_file::{
    AnyField, FieldFileError, KIND_NEURAL, decode_any, encode_neural, read_any_field,
    read_dimension, read_field, read_metadata, write_neural_field,
};
use zeroset_bases::neural::{
    Activation, Architecture, CurvatureSites, HiddenBasis, NeuralError, NeuralField, NeuralFit,
    NeuralParams, Trained, Variant, auxiliary_points,
};
use zeroset_field_core::basis::Basis;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::lsq::{LeastSquaresSolver, SolveError};
use zeroset_solvers::{DenseQr, IterativeParams, Lsqr, SparseQr};

/// The circle of radius 0.5: points on it (0), inside (−1) and outside (+1).
fn circle() -> (Vec<Point<2>>, Vec<f64>) {
    let mut p = Vec::new();
    let mut z = Vec::new();
    for k in 0..24 {
        let t = std::f64::consts::TAU * k as f64 / 24.0;
        p.push([0.5 * t.cos(), 0.5 * t.sin()]);
        z.push(0.0);
        if k % 3 == 0 {
            p.push([0.2 * t.cos(), 0.2 * t.sin()]);
            z.push(-1.0);
            p.push([0.85 * t.cos(), 0.85 * t.sin()]);
            z.push(1.0);
        }
    }
    (p, z)
}

/// A sphere of radius 0.4 with the same three kinds of constraint.
fn sphere() -> (Vec<Point<3>>, Vec<f64>) {
    let n = 40;
    let mut p = Vec::new();
    let mut z = Vec::new();
    for k in 0..n {
        let c = 1.0 - (2 * k + 1) as f64 / n as f64;
        let (s, t) = ((1.0 - c * c).sqrt(), k as f64 * 2.399_963);
        let u = [s * t.cos(), s * t.sin(), c];
        for (r, v) in [(0.4, 0.0), (0.2, -1.0), (0.7, 1.0)] {
            if v == 0.0 || k % 4 == 0 {
                p.push(u.map(|x| r * x));
                z.push(v);
            }
        }
    }
    (p, z)
}

fn square() -> Aabb<2> {
    Aabb::new([-1.0, -1.0], [1.0, 1.0]).unwrap()
}

fn quick(steps: usize) -> NeuralParams {
    NeuralParams::default()
        .with_steps(steps)
        .with_aux_points(100)
}

fn train2(params: NeuralParams) -> Trained<2> {
    let (p, z) = circle();
    NeuralFit::new(params)
        .with_domain(square())
        .fit(&p, &z)
        .unwrap()
}

#[test]
fn training_fits_a_circle_with_the_right_signs() {
    let t = train2(quick(400));
    let r = &t.report;
    assert_eq!((r.steps, r.history.len()), (400, 400));
    assert!(r.max_residual < 0.4, "max residual {}", r.max_residual);
    assert!(
        r.loss < 0.2 * r.history[0],
        "{} vs {}",
        r.loss,
        r.history[0]
    );
    assert!((r.loss - (r.data_term + r.curvature_term)).abs() <= 1e-12 * r.loss);
    // λ|Ω|/P with |Ω| = 4.
    assert!((r.curvature_weight - 0.05 * 4.0 / 100.0).abs() < 1e-15);
    let f = &t.field;
    assert!(f.value(&[0.0, 0.0]) < 0.0, "negative inside");
    assert!(f.value(&[0.95, 0.0]) > 0.0, "positive outside");
    // The outward normal is +∇f on the curve.
    let g = f.gradient(&[0.5, 0.0]);
    assert!(g[0] > 0.0 && g[0].abs() > g[1].abs(), "{g:?}");
}

#[test]
fn three_d_training_and_softplus_work() {
    let (p, z) = sphere();
    let mut params = quick(250);
    params.architecture = Architecture::new(vec![16, 16], Activation::Softplus).unwrap();
    let t = NeuralFit::new(params).fit(&p, &z).unwrap();
    assert!(t.report.loss < t.report.history[0]);
    assert!(t.field.value(&[0.0; 3]) < 0.0);
    assert!(t.field.value(&[0.7, 0.0, 0.0]) > 0.0);
}

/// Training in a pool of `threads` threads.
fn train_in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn the_same_bits_on_one_and_three_threads() {
    // Every source of randomness and every chunked sum: aux points redrawn each step, dropout,
    // curvature at aux points, more constraints than one chunk holds.
    let (p, z) = sphere();
    let mut params = quick(60).with_dropout(0.2).with_aux_points(300);
    params.resample_aux = true;
    let fit = NeuralFit::new(params.clone());
    let one = train_in_pool(1, || fit.fit(&p, &z).unwrap());
    let three = train_in_pool(3, || fit.fit(&p, &z).unwrap());
    assert_eq!(one.field.parameters(), three.field.parameters());
    assert_eq!(one.report.history, three.report.history);
    let probes: Vec<Point<3>> = (0..3000)
        .map(|i| {
            let t = i as f64 * 0.013;
            [0.6 * t.sin(), 0.5 * (1.7 * t).cos(), 0.4 * (0.3 * t).sin()]
        })
        .collect();
    let (mut a, mut b) = (vec![0.0; probes.len()], vec![0.0; probes.len()]);
    train_in_pool(1, || one.field.values(&probes, &mut a));
    train_in_pool(3, || one.field.values(&probes, &mut b));
    assert_eq!(a, b);
    assert_eq!(
        train_in_pool(1, || one.field.thin_plate_energy(40)).to_bits(),
        train_in_pool(3, || one.field.thin_plate_energy(40)).to_bits()
    );
    // The 2-D paper variants too.
    for v in [Variant::Paper, Variant::CurvatureAtConstraints] {
        let params = NeuralParams::variant(v).with_steps(40).with_aux_points(200);
        let a = train_in_pool(1, || train2(params.clone()));
        let b = train_in_pool(3, || train2(params.clone()));
        assert_eq!(a.field.parameters(), b.field.parameters(), "{v:?}");
    }
}

#[test]
fn seeds_and_aux_schemes_are_honoured() {
    let a = train2(quick(30).with_seed(1));
    let b = train2(quick(30).with_seed(1));
    let c = train2(quick(30).with_seed(2));
    assert_eq!(a.field.parameters(), b.field.parameters());
    assert_ne!(a.field.parameters(), c.field.parameters());
    let mut resampled = quick(30).with_seed(1);
    resampled.resample_aux = true;
    let d = train2(resampled);
    assert_ne!(a.field.parameters(), d.field.parameters());
    // The fixed set is the head of the documented sequence, uniform in the domain.
    let aux = auxiliary_points(&square(), 1, 1000);
    assert!(aux.iter().all(|q| square().contains(q)));
    let mean: f64 = aux.iter().map(|q| q[0]).sum::<f64>() / 1000.0;
    assert!(mean.abs() < 0.1, "{mean}");
    assert_eq!(auxiliary_points(&square(), 1, 10)[..], aux[..10]);
}

#[test]
fn variants_are_the_paper_baselines() {
    let p = NeuralParams::variant(Variant::Paper);
    assert_eq!((p.lambda, p.aux_points, p.steps), (0.05, 250, 3000));
    assert_eq!(p.architecture.widths(), &[32, 32]);
    assert_eq!(NeuralParams::variant(Variant::NoCurvature).lambda, 0.0);
    let b = NeuralParams::variant(Variant::CurvatureAtConstraints);
    assert_eq!(
        (b.lambda, b.curvature_at),
        (0.05, CurvatureSites::Constraints)
    );
    let d = NeuralParams::variant(Variant::Dropout);
    assert_eq!((d.lambda, d.dropout), (0.0, 0.1));
    // Without curvature there is no curvature term; at the constraints its weight is λ|Ω|/N.
    let t = train2(NeuralParams::variant(Variant::NoCurvature).with_steps(5));
    assert_eq!(
        (t.report.curvature_term, t.report.curvature_weight),
        (0.0, 0.0)
    );
    let t = train2(NeuralParams::variant(Variant::CurvatureAtConstraints).with_steps(5));
    let n = circle().0.len() as f64;
    assert!((t.report.curvature_weight - 0.05 * 4.0 / n).abs() < 1e-15);
    assert!(t.report.curvature_term > 0.0);
}

#[test]
fn warm_starts_and_cancellation() {
    let (p, z) = circle();
    let fit = NeuralFit::new(quick(50)).with_domain(square());
    let first = fit.fit(&p, &z).unwrap();
    let again = fit
        .fit_with(&p, &z, Some(first.field.clone()), &mut |_| {
            std::ops::ControlFlow::Continue(())
        })
        .unwrap();
    assert!(again.report.history[0] < first.report.history[0]);
    let mut seen = 0;
    let e = fit
        .fit_with(&p, &z, None, &mut |progress| {
            seen = progress.step;
            assert!(progress.loss.is_finite() && progress.steps == 50);
            if progress.step == 7 {
                std::ops::ControlFlow::Break(())
            } else {
                std::ops::ControlFlow::Continue(())
            }
        })
        .unwrap_err();
    assert_eq!((e, seen), (NeuralError::Cancelled { steps: 7 }, 7));
}

#[test]
fn bad_input_gives_specific_errors() {
    let (p, z) = circle();
    let fit = NeuralFit::<2>::new(quick(5));
    assert_eq!(fit.fit(&[], &[]).unwrap_err(), NeuralError::NoConstraints);
    assert!(matches!(
        fit.fit(&p, &z[1..]).unwrap_err(),
        NeuralError::LengthMismatch { .. }
    ));
    let mut nan = z.clone();
    nan[3] = f64::NAN;
    let e = fit.fit(&p, &nan).unwrap_err();
    assert!(
        matches!(
            e,
            NeuralError::NonFinite {
                index: 3,
                what: "target",
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("constraint 3"), "{e}");
    let mut bad = p.clone();
    bad[5][1] = f64::INFINITY;
    assert!(matches!(
        fit.fit(&bad, &z).unwrap_err(),
        NeuralError::NonFinite {
            index: 5,
            what: "coordinate",
            ..
        }
    ));
    for (params, name) in [
        (quick(5).with_lambda(-0.1), "λ"),
        (quick(5).with_lambda(f64::NAN), "λ"),
        (quick(5).with_learning_rate(0.0), "learning rate"),
        (quick(5).with_dropout(1.0), "dropout"),
        (quick(5).with_aux_points(usize::MAX), "auxiliary points"),
    ] {
        let e = NeuralFit::new(params).fit(&p, &z).unwrap_err();
        assert!(
            matches!(&e, NeuralError::InvalidParameter { name: n, .. } if n.contains(name)),
            "{e}"
        );
    }
    for widths in [vec![32, 0], vec![0], vec![]] {
        let e = Architecture::new(widths, Activation::Tanh).unwrap_err();
        assert!(matches!(e, NeuralError::InvalidWidths { .. }), "{e}");
    }
    assert!(matches!(
        NeuralFit::new(quick(5).with_aux_points(0))
            .fit(&p, &z)
            .unwrap_err(),
        NeuralError::NoAuxiliaryPoints { .. }
    ));
    // λ = 0 needs no auxiliary point; one constraint point gives a flat default domain.
    assert!(
        NeuralFit::new(quick(3).with_aux_points(0).with_lambda(0.0))
            .fit(&p, &z)
            .is_ok()
    );
    assert!(matches!(
        fit.fit(&[[0.5, 0.5]], &[0.0]).unwrap_err(),
        NeuralError::FlatDomain { .. }
    ));
    // A learning rate far too large diverges with an error, not a NaN field.
    let huge = NeuralFit::new(quick(200).with_learning_rate(1e12)).with_domain(square());
    match huge.fit(&p, &z) {
        Err(NeuralError::Diverged { .. }) | Ok(_) => {}
        Err(e) => panic!("{e}"),
    }
}

fn data_term(f: &NeuralField<2>, p: &[Point<2>], z: &[f64]) -> f64 {
    p.iter().zip(z).map(|(x, z)| (f.value(x) - z).powi(2)).sum()
}

#[test]
fn refitting_the_last_layer_lowers_the_data_term_with_any_solver() {
    let (p, z) = circle();
    let t = train2(quick(150));
    let basis = HiddenBasis::of(&t.field);
    assert_eq!(basis.num_coefficients(), 33);
    // The net is the basis expansion with c = (w_out, b_out).
    let mut row = zeroset_field_core::basis::BasisRow::new();
    basis.eval_row(&[0.1, -0.3], true, &mut row);
    let (w, b) = t.field.layer(2);
    let expansion: f64 = row
        .values
        .iter()
        .zip(w.iter().chain(b))
        .map(|(v, c)| v * c)
        .sum();
    assert!((expansion - t.field.value(&[0.1, -0.3])).abs() < 1e-12);
    let grad = t.field.gradient(&[0.1, -0.3]);
    for a in 0..2 {
        let g: f64 = row
            .gradients
            .iter()
            .zip(w.iter().chain(b))
            .map(|(v, c)| v[a] * c)
            .sum();
        assert!((g - grad[a]).abs() < 1e-12);
    }

    // The hidden features are nearly dependent (condition ~1e7): solvers on the normal
    // equations call the matrix rank deficient; orthogonal ones solve it.
    let lsqr = IterativeParams {
        max_iterations: Some(5000),
        ..IterativeParams::default().with_tolerance(1e-13)
    };
    let solvers: [(&str, Box<dyn LeastSquaresSolver>); 3] = [
        ("dense QR", Box::new(DenseQr::default())),
        ("sparse QR", Box::new(SparseQr::default())),
        ("LSQR", Box::new(Lsqr::new(lsqr))),
    ];
    let mut fields = Vec::new();
    for (name, solver) in &solvers {
        let (refit, report) = t.field.refit_last_layer(&p, &z, solver.as_ref()).unwrap();
        assert!(report.data_after < report.data_before, "{name}: {report:?}");
        assert!((report.data_before - data_term(&t.field, &p, &z)).abs() < 1e-9);
        assert!((report.data_after - data_term(&refit, &p, &z)).abs() < 1e-9);
        // The hidden layers are untouched.
        let n = t.field.parameters().len();
        assert_eq!(refit.parameters()[..n - 33], t.field.parameters()[..n - 33]);
        fields.push(refit);
    }
    // The solvers agree: the same field.
    for f in &fields[1..] {
        for x in [[0.0, 0.0], [0.3, -0.6], [0.9, 0.9]] {
            let (a, b) = (fields[0].value(&x), f.value(&x));
            assert!((a - b).abs() < 1e-5 * (1.0 + a.abs()), "{a} vs {b}");
        }
    }
    // Fewer points than coefficients: the direct solver says so.
    let e = t
        .field
        .refit_last_layer(&p[..10], &z[..10], &DenseQr::default())
        .unwrap_err();
    assert!(
        matches!(e, NeuralError::Solve(SolveError::Underdetermined { .. })),
        "{e}"
    );
    let e = t
        .field
        .refit_last_layer(&p, &z[..3], &DenseQr::default())
        .unwrap_err();
    assert!(matches!(e, NeuralError::LengthMismatch { .. }), "{e}");
}

#[test]
fn rescaling_moves_the_field() {
    let t = train2(quick(20));
    let (c, s) = ([3.0, -2.0], 0.25);
    let moved = t.field.transformed(c, s, s).unwrap();
    for u in [[0.1, 0.2], [-0.7, 0.4]] {
        let x = [c[0] + s * u[0], c[1] + s * u[1]];
        let want = s * t.field.value(&u);
        assert!(
            (moved.value(&x) - want).abs() < 1e-14,
            "{} vs {want}",
            moved.value(&x)
        );
        let (g0, g1) = (t.field.gradient(&u), moved.gradient(&x));
        assert!((g0[0] - g1[0]).abs() < 1e-12 && (g0[1] - g1[1]).abs() < 1e-12);
    }
    let b = moved.domain();
    assert_eq!((b.min(), b.max()), ([2.75, -2.25], [3.25, -1.75]));
    assert!(t.field.transformed(c, 0.0, 1.0).is_err());
    assert!(t.field.transformed(c, 1.0, 0.0).is_err());
    let plain = t.field.transformed(c, s, 1.0).unwrap();
    assert!((plain.value(&[c[0], c[1]]) - t.field.value(&[0.0, 0.0])).abs() < 1e-15);
}

fn assert_same_field<const D: usize>(a: &NeuralField<D>, b: &NeuralField<D>, probes: &[Point<D>]) {
    assert_eq!(a, b);
    for x in probes {
        assert_eq!(a.value(x).to_bits(), b.value(x).to_bits());
        assert_eq!(a.gradient(x), b.gradient(x));
    }
}

#[test]
fn field_files_round_trip_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let two = train2(quick(20))
        .field
        .transformed([0.5, 0.25], 2.0, 2.0)
        .unwrap();
    let path2 = dir.path().join("curve.zsf");
    write_neural_field(&path2, &two).unwrap();
    let AnyField::Neural(back) = read_any_field::<2>(&path2).unwrap() else {
        panic!("not a neural field");
    };
    assert_same_field(&two, &back, &[[0.0, 0.0], [1.3, -0.2], [0.5, 0.5]]);

    let (p, z) = sphere();
    let mut params = quick(10);
    params.architecture = Architecture::new(vec![7, 5, 3], Activation::Softplus).unwrap();
    let three = NeuralFit::new(params).fit(&p, &z).unwrap().field;
    let path3 = dir.path().join("sphere.zsf");
    write_neural_field(&path3, &three).unwrap();
    let back = read_any_field::<3>(&path3).unwrap();
    assert_eq!(back.kind(), KIND_NEURAL);
    let back = back.into_neural().unwrap();
    assert_same_field(&three, &back, &[[0.0; 3], [0.3, -0.2, 0.5]]);
    assert_eq!(
        (
            read_dimension(&path2).unwrap(),
            read_dimension(&path3).unwrap()
        ),
        (2, 3)
    );
    let meta = read_metadata(&path3).unwrap();
    assert!(
        meta.contains(&("widths".into(), "7,5,3".into())),
        "{meta:?}"
    );
    assert!(
        meta.contains(&("activation".into(), "softplus".into())),
        "{meta:?}"
    );
}

#[test]
fn corrupt_truncated_and_mismatched_files_are_reported() {
    let field = train2(quick(5)).field;
    let bytes = encode_neural(&field);
    let path = Path::new("net.zsf");
    let mut flipped = bytes.clone();
    flipped[200] ^= 0x10;
    let e = decode_any::<2>(&flipped, path).unwrap_err();
    assert!(matches!(e, FieldFileError::Checksum { .. }), "{e}");
    let e = decode_any::<2>(&bytes[..bytes.len() - 20], path).unwrap_err();
    assert!(matches!(e, FieldFileError::Truncated { .. }), "{e}");
    let e = decode_any::<3>(&bytes, path).unwrap_err();
    assert!(
        matches!(e, FieldFileError::WrongDimension { found: 2, .. }),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("net.zsf");
    write_neural_field(&file, &field).unwrap();
    let e = read_field::<2>(&file).unwrap_err().to_string();
    assert!(e.contains("neural field") && e.contains("[32, 32]"), "{e}");

    // A well-framed file whose payload lies: an unknown activation, a wrong parameter count.
    let reframe = |edit: &dyn Fn(&mut Vec<u8>)| -> Vec<u8> {
        let mut b = bytes.clone();
        edit(&mut b);
        let n = b.len();
        let crc = crc32fast::hash(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&crc.to_le_bytes());
        b
    };
    let meta_len = u32::from_le_bytes(bytes[24..28].try_into().unwrap()) as usize;
    let payload = 36 + meta_len;
    let bad_activation = reframe(&|b| b[payload] = 9);
    let e = decode_any::<2>(&bad_activation, path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("activation code 9"), "{e}");
    let zero_width =
        reframe(&|b| b[payload + 8..payload + 16].copy_from_slice(&0u64.to_le_bytes()));
    let e = decode_any::<2>(&zero_width, path).unwrap_err().to_string();
    assert!(e.contains("invalid network"), "{e}");
    let count_at = payload + 8 + 16 + 8 * (3 * 2 + 2);
    let bad_count = reframe(&|b| b[count_at..count_at + 8].copy_from_slice(&7u64.to_le_bytes()));
    let e = decode_any::<2>(&bad_count, path).unwrap_err().to_string();
    assert!(e.contains("7 parameters"), "{e}");
    let nan_scale_at = payload + 8 + 16 + 16;
    let nan_scale =
        reframe(&|b| b[nan_scale_at..nan_scale_at + 8].copy_from_slice(&f64::NAN.to_le_bytes()));
    let e = decode_any::<2>(&nan_scale, path).unwrap_err().to_string();
    assert!(e.contains("input scale"), "{e}");
}
