use faer::Mat;
use faer::linalg::solvers::{PartialPivLu, Solve};
use proptest::prelude::*;
use zeroset_field_core::Point;
use zeroset_field_core::basis::design_matrix;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::lsq::{LinearOperator, LsqMatrix};

use super::*;

/// Fibonacci points on the sphere of `radius` around `centre`, with outward normals.
fn sphere(n: usize, centre: [f64; 3], radius: f64) -> Vec<([f64; 3], [f64; 3])> {
    (0..n)
        .map(|k| {
            let z = -1.0 + (2 * k + 1) as f64 / n as f64;
            let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399_963_229_728_653);
            let u = [s * t.cos(), s * t.sin(), z];
            (std::array::from_fn(|a| centre[a] + radius * u[a]), u)
        })
        .collect()
}

/// The issue's sphere set-up: N − 2⌊N/3⌋ on-surface points, ⌊N/3⌋ at ±0.05.
fn sphere_setup(n: usize) -> Constraints<3> {
    let third = n / 3;
    let on = sphere(n - 2 * third, [0.5; 3], 0.35);
    let mut c = Constraints::new();
    for (p, _) in &on {
        c.push_value(*p, 0.0);
    }
    for (k, (p, u)) in on.iter().take(third).enumerate() {
        let _ = k;
        c.push_value(std::array::from_fn(|a| p[a] + 0.05 * u[a]), 0.05);
        c.push_value(std::array::from_fn(|a| p[a] - 0.05 * u[a]), -0.05);
    }
    c
}

/// The full saddle-point system solved by LU: the reference for the projected Cholesky.
fn lu_reference<K: Kernel + Clone, const D: usize>(kernel: &K, c: &Constraints<D>) -> Vec<f64> {
    let f = system::Functionals::new(kernel, c.as_slice()).unwrap();
    let poly = system::Polynomial::fit(&f.points);
    let size = f.len() + D + 1;
    let a = system::assemble(kernel, &f, &poly);
    let a = Mat::from_fn(size, size, |i, j| a[j * size + i]);
    let mut rhs = Mat::from_fn(size, 1, |i, _| if i < f.len() { f.targets[i] } else { 0.0 });
    PartialPivLu::new(a.as_ref()).solve_in_place(rhs.as_mut());
    (0..size).map(|i| rhs[(i, 0)]).collect()
}

fn solution<K: Kernel, const D: usize>(field: &RbfField<K, D>) -> Vec<f64> {
    field
        .weights()
        .iter()
        .chain(field.polynomial_coefficients())
        .copied()
        .collect()
}

/// Two fits of the same constraints may centre their polynomials differently: compare the
/// kernel weights (basis-independent) and the values at probe points.
fn field_diff<K: Kernel>(a: &RbfField<K, 3>, b: &RbfField<K, 3>) -> f64 {
    let probes: Vec<[f64; 3]> = (0..64)
        .map(|i| {
            let t = i as f64 * 0.71;
            [t.sin().abs(), (1.7 * t).cos().abs(), (0.37 * t).sin().abs()]
        })
        .collect();
    let va: Vec<f64> = probes.iter().map(|p| a.value(p)).collect();
    let vb: Vec<f64> = probes.iter().map(|p| b.value(p)).collect();
    max_rel_diff(a.weights(), b.weights()).max(max_rel_diff(&va, &vb))
}

fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |s, (x, y)| s.max((x - y).abs()))
        / scale
}

#[test]
fn projected_cholesky_agrees_with_lu_on_the_whole_system() {
    let c = sphere_setup(300);
    for (name, got, want) in [
        (
            "r",
            solution(&RbfFit::new(Biharmonic).fit(&c).unwrap().field),
            lu_reference(&Biharmonic, &c),
        ),
        (
            "r3",
            solution(&RbfFit::new(Triharmonic).fit(&c).unwrap().field),
            lu_reference(&Triharmonic, &c),
        ),
    ] {
        let d = max_rel_diff(&got, &want);
        assert!(d < 1e-8, "{name}: {d:.1e}");
    }
}

#[test]
fn the_sphere_fit_interpolates_and_approximates_the_distance() {
    let c = sphere_setup(600);
    for fit in [
        RbfFit::new(Triharmonic).fit(&c).unwrap(),
        RbfFit::new(Triharmonic).fit(&c).unwrap(),
    ] {
        assert!(fit.report.max_residual < 1e-10, "{:?}", fit.report);
        for con in c.as_slice() {
            let Prescribed::Value(v) = con.prescribed else {
                unreachable!()
            };
            assert!((fit.field.value(&con.point) - v).abs() < 1e-10);
        }
        // Between the constraints, within the band, the field is close to the SDF.
        for (p, u) in sphere(200, [0.5; 3], 0.37) {
            let sd = 0.02;
            let _ = u;
            assert!(
                (fit.field.value(&p) - sd).abs() < 5e-3,
                "{}",
                fit.field.value(&p)
            );
        }
    }
    let r = RbfFit::new(Biharmonic).fit(&c).unwrap();
    assert!(r.report.max_residual < 1e-10, "{:?}", r.report);
}

#[test]
fn hermite_constraints_set_value_and_gradient() {
    let pts = sphere(80, [0.0; 3], 1.0);
    let mut c = Constraints::new();
    for (p, n) in &pts {
        c.push_value(*p, 0.0);
        c.push_gradient(*p, *n);
    }
    let fit = RbfFit::new(Triharmonic).fit(&c).unwrap();
    assert!(fit.report.max_residual < 1e-10, "{:?}", fit.report);
    for (p, n) in &pts {
        assert!(fit.field.value(p).abs() < 1e-10);
        let g = fit.field.gradient(p);
        for a in 0..3 {
            assert!((g[a] - n[a]).abs() < 1e-9, "{g:?} vs {n:?}");
        }
    }
    assert!(fit.field.value(&[0.0; 3]) < 0.0 && fit.field.value(&[0.0, 0.0, 1.6]) > 0.0);
    // Gradient and Hessian against central differences away from the centres.
    let x = [0.21, -0.33, 0.47];
    let h = 1e-5;
    let (g, hs) = (fit.field.gradient(&x), fit.field.hessian(&x));
    for a in 0..3 {
        let (mut p, mut m) = (x, x);
        p[a] += h;
        m[a] -= h;
        let fd = (fit.field.value(&p) - fit.field.value(&m)) / (2.0 * h);
        assert!((fd - g[a]).abs() < 1e-6 * g[a].abs().max(1.0));
        let (gp, gm) = (fit.field.gradient(&p), fit.field.gradient(&m));
        for b in 0..3 {
            let fd = (gp[b] - gm[b]) / (2.0 * h);
            assert!((fd - hs[a][b]).abs() < 1e-5 * hs[a][b].abs().max(1.0));
        }
    }
    // r is not differentiable enough for gradient constraints.
    assert!(matches!(
        RbfFit::new(Biharmonic).fit(&c).unwrap_err(),
        RbfError::KernelNotSmooth { .. }
    ));
}

#[test]
fn thin_plate_curve_with_inside_and_outside_points() {
    // Jiang–Turk's set-up (their +1 inside is −1 here).
    let mut c = Constraints::<2>::new();
    for k in 0..16 {
        let t = k as f64 * std::f64::consts::TAU / 16.0;
        let r = 0.6 + 0.15 * (3.0 * t).cos();
        c.push_value([r * t.cos(), r * t.sin()], 0.0);
    }
    c.push_value([0.0, 0.0], -1.0);
    for k in 0..4 {
        let t = k as f64 * std::f64::consts::FRAC_PI_2 + 0.3;
        c.push_value([1.2 * t.cos(), 1.2 * t.sin()], 1.0);
    }
    let fit = RbfFit::new(ThinPlate).fit(&c).unwrap();
    assert!(fit.report.max_residual < 1e-10);
    let want = lu_reference(&ThinPlate, &c);
    assert!(max_rel_diff(&solution(&fit.field), &want) < 1e-8);
    assert!(fit.field.value(&[0.1, 0.1]) < 0.0 && fit.field.value(&[1.0, 1.0]) > 0.0);
}

#[test]
fn bad_input_gets_specific_errors() {
    let fit = RbfFit::new(Triharmonic);
    assert_eq!(
        fit.fit(&Constraints::<3>::new()).unwrap_err(),
        RbfError::Empty
    );
    let mut dup = sphere_setup(30);
    let p = dup.as_slice()[4].point;
    dup.push_value(p, 0.1);
    assert!(matches!(
        fit.fit(&dup).unwrap_err(),
        RbfError::Duplicate {
            first: 4,
            second: 30,
            ..
        }
    ));
    let mut nan = sphere_setup(30);
    nan.push_value([0.0, f64::NAN, 0.0], 0.0);
    assert!(matches!(
        fit.fit(&nan).unwrap_err(),
        RbfError::NonFinite { index: 30, .. }
    ));
    let mut plane = Constraints::<3>::new();
    for i in 0..5 {
        for j in 0..5 {
            plane.push_value([i as f64, j as f64, 2.0], (i + j) as f64);
        }
    }
    assert!(matches!(
        fit.fit(&plane).unwrap_err(),
        RbfError::Degenerate { .. }
    ));
    let mut few = Constraints::<3>::new();
    few.push_value([0.0; 3], 0.0).push_value([1.0; 3], 1.0);
    assert!(matches!(
        fit.fit(&few).unwrap_err(),
        RbfError::Degenerate { .. }
    ));
    let mut inf = sphere_setup(30);
    inf.push_value([0.1, 0.2, 0.3], f64::INFINITY);
    assert!(matches!(
        fit.fit(&inf).unwrap_err(),
        RbfError::NonFinite { what: "value", .. }
    ));
}

#[test]
fn the_space_reproduces_the_field_and_values_are_thread_independent() {
    let fit = RbfFit::new(Biharmonic).fit(&sphere_setup(90)).unwrap();
    let space = RbfSpace::of(&fit.field);
    let xs: Vec<[f64; 3]> = (0..50)
        .map(|i| {
            let t = i as f64 * 0.37;
            [
                0.5 + 0.4 * t.sin(),
                0.5 + 0.3 * (1.3 * t).cos(),
                0.2 + 0.01 * i as f64,
            ]
        })
        .collect();
    let a = design_matrix(&space, &xs);
    let coef = solution(&fit.field);
    let mut via_basis = vec![0.0; xs.len()];
    LsqMatrix::SparseRow(a.as_ref()).apply(&coef, &mut via_basis);
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut out = vec![0.0; xs.len()];
        pool.install(|| fit.field.values(&xs, &mut out));
        out
    };
    let (one, three) = (on(1), on(3));
    assert_eq!(one, three);
    for (i, x) in xs.iter().enumerate() {
        assert!((one[i] - fit.field.value(x)).abs() < 1e-12);
        assert!((one[i] - via_basis[i]).abs() < 1e-10);
    }
}

#[test]
fn removing_every_batch_gives_back_the_base_fit() {
    let base = sphere_setup(60);
    let fit = RbfFit::new(Triharmonic);
    let mut inc = IncrementalFit::new(&fit, &base).unwrap();
    let mut extra = Constraints::new();
    extra
        .push_value([0.5, 0.5, 0.5], -0.35)
        .push_value([0.5, 0.5, 1.0], 0.15);
    inc.add(&extra).unwrap();
    let mut more = Constraints::new();
    more.push_gradient([0.5, 0.5, 0.85], [0.0, 0.0, 1.0]);
    inc.add(&more).unwrap();
    assert_eq!(inc.batches(), 2);
    assert_eq!(inc.remove_last(), Some(3));
    assert_eq!(inc.remove_last(), Some(2));
    assert_eq!(inc.remove_last(), None);
    let full = fit.fit(&base).unwrap();
    assert!(field_diff(&inc.field(), &full.field) < 1e-10);
    // A duplicate of an old point is refused and leaves the fit as it was.
    let mut dup = Constraints::new();
    dup.push_value(base.as_slice()[3].point, 1.0);
    assert!(matches!(
        inc.add(&dup).unwrap_err(),
        RbfError::Duplicate { .. }
    ));
    assert_eq!(inc.batches(), 0);
}

fn random_constraints(seed: u64, n: usize) -> Constraints<3> {
    // A smooth target on scattered points (a deterministic pseudo-random sequence).
    let mut c = Constraints::new();
    let mut rng = zeroset_field_core::rng::SplitMix64::new(seed);
    let mut next = || rng.unit();
    for _ in 0..n {
        let p = [next(), next(), next()];
        c.push_value(p, (3.0 * p[0]).sin() + p[1] * p[2]);
    }
    c
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Adding M constraints (in one or two batches, values and gradients) equals a full
    /// re-solve to 1e-8 relative.
    #[test]
    fn incremental_constraints_equal_a_full_solve(
        seed in 0u64..1000,
        n in 8usize..80,
        m in 1usize..6,
        split in 0usize..6,
        gradient in any::<bool>(),
    ) {
        let all = random_constraints(seed, n + m);
        let (base, extra) = all.as_slice().split_at(n);
        let mut base_c = Constraints::new();
        for c in base { base_c.push_value(c.point, match c.prescribed { Prescribed::Value(v) => v, _ => 0.0 }); }
        let fit = RbfFit::new(Triharmonic);
        let mut inc = IncrementalFit::new(&fit, &base_c).unwrap();
        let mut full = base_c.clone();
        let cut = split.min(extra.len());
        for part in [&extra[..cut], &extra[cut..]] {
            if part.is_empty() { continue; }
            let mut batch = Constraints::new();
            for c in part {
                if let Prescribed::Value(v) = c.prescribed { batch.push_value(c.point, v); }
            }
            if gradient {
                let p = part[0].point;
                batch.push_gradient(p, [0.3, -0.2, 0.5]);
            }
            inc.add(&batch).unwrap();
            full.extend(&batch);
        }
        let want = fit.fit(&full).unwrap();
        let got = inc.field();
        let d = field_diff(&got, &want.field);
        prop_assert!(d < 1e-8, "relative difference {d:.1e}");
        if std::env::var_os("ZEROSET_REPORT").is_some() {
            eprintln!("incremental n={n} m={m} gradient={gradient}: {d:.1e}");
        }
    }
}

#[test]
fn the_iterative_and_dense_fits_agree_to_the_solver_tolerance() {
    let c = sphere_setup(900);
    let dense = RbfFit::new(Biharmonic)
        .with_solver(Solver::Dense)
        .fit(&c)
        .unwrap();
    let iterative = RbfFit::new(Biharmonic)
        .with_solver(Solver::Iterative(IterativeParams::default()))
        .fit(&c)
        .unwrap();
    assert_eq!(iterative.report.solver, "gmres-cardinal");
    assert!(iterative.report.iterations > 0 && iterative.report.iterations < 60);
    assert!(
        iterative.report.max_residual < 1e-10,
        "{:?}",
        iterative.report
    );
    let d = field_diff(&iterative.field, &dense.field);
    assert!(d < 1e-9, "dense vs iterative: {d:.1e}");
    // Hermite constraints are refused by the iterative solve, with a clear message.
    let mut h = Constraints::new();
    for (p, n) in sphere(20, [0.0; 3], 1.0) {
        h.push_value(p, 0.0).push_gradient(p, n);
    }
    let err = RbfFit::new(Triharmonic)
        .with_solver(Solver::Iterative(IterativeParams::default()))
        .fit(&h)
        .unwrap_err();
    assert!(err.to_string().contains("value constraints only"), "{err}");
}

#[test]
fn the_mixed_precision_fit_agrees_with_the_dense_one() {
    let c = sphere_setup(900);
    let dense = RbfFit::new(Triharmonic)
        .with_solver(Solver::Dense)
        .fit(&c)
        .unwrap();
    let mixed = RbfFit::new(Triharmonic)
        .with_solver(Solver::MixedPrecision)
        .fit(&c)
        .unwrap();
    assert_eq!(mixed.report.solver, "mixed-cholesky-gmres");
    assert!(mixed.report.iterations > 0 && mixed.report.iterations < 20);
    assert!(mixed.report.max_residual < 1e-10, "{:?}", mixed.report);
    let d = field_diff(&mixed.field, &dense.field);
    assert!(d < 1e-9, "dense vs mixed: {d:.1e}");
    // Biharmonic (σ = −1) goes through the same path.
    let r = RbfFit::new(Biharmonic)
        .with_solver(Solver::MixedPrecision)
        .fit(&c)
        .unwrap();
    assert!(r.report.max_residual < 1e-10, "{:?}", r.report);
}

#[test]
fn a_user_kernel_fits_too_wendland() {
    // Wendland's ψ₃,₁ is positive definite: the projected Cholesky takes it as it is.
    let c = sphere_setup(300);
    let kernel = Wendland::new(0.6).unwrap();
    let fit = RbfFit::new(kernel).fit(&c).unwrap();
    assert!(fit.report.max_residual < 1e-10, "{:?}", fit.report);
    let want = lu_reference(&kernel, &c);
    assert!(max_rel_diff(&solution(&fit.field), &want) < 1e-8);
    assert!(fit.field.value(&[0.5; 3]) < 0.0);
}

/// The vectorised gradient of a value-only field is the sum of the centres' kernel gradients
/// (plus the polynomial's), including at a centre, where the kernel term's gradient is 0.
#[test]
fn vectorised_gradients_equal_the_termwise_sum() {
    let c = sphere_setup(301);
    let check = |field: &dyn ScalarField<3>, terms: &dyn Fn(&Point<3>) -> [f64; 3]| {
        let mut probes: Vec<Point<3>> = sphere(50, [0.5; 3], 0.31)
            .into_iter()
            .map(|(p, _)| p)
            .collect();
        probes.push(c.as_slice()[7].point);
        for x in &probes {
            let (g, want) = (field.gradient(x), terms(x));
            let scale = want.iter().map(|v| v.abs()).fold(1.0, f64::max);
            for a in 0..3 {
                assert!((g[a] - want[a]).abs() < 1e-12 * scale, "{g:?} vs {want:?}");
            }
        }
    };
    macro_rules! case {
        ($kernel:expr) => {{
            let f = RbfFit::new($kernel).fit(&c).unwrap().field;
            // Not a whole number of vector lanes: the tail is summed too.
            assert_ne!(f.centres().len() % 4, 0);
            let (_, b) = f.linear_part();
            let termwise = |x: &Point<3>| {
                let mut g = b;
                for (y, w) in f.centres().iter().zip(f.weights()) {
                    let d: [f64; 3] = std::array::from_fn(|a| x[a] - y[a]);
                    let k = kernel::gradient(f.kernel(), &d);
                    for a in 0..3 {
                        g[a] += w * k[a];
                    }
                }
                g
            };
            check(&f, &termwise);
        }};
    }
    case!(Biharmonic);
    case!(Triharmonic);
    case!(ThinPlate);
}

#[test]
fn dense_solves_beyond_the_memory_limit_are_refused_before_allocating() {
    let c = sphere_setup(2400);
    let unknowns = 2400 + 4;
    let limited = |solver| {
        RbfFit::new(Biharmonic)
            .with_solver(solver)
            .with_memory_limit(1 << 20)
            .fit(&c)
            .unwrap_err()
    };
    let err = limited(Solver::Dense);
    let RbfError::Memory(m) = &err else {
        panic!("{err}")
    };
    assert_eq!(m.needed, (unknowns * unknowns * 8) as u64);
    assert_eq!(m.available, Some(1 << 20));
    let text = err.to_string();
    assert!(
        text.starts_with(
            "the dense solve of 2404 unknowns needs about 44.1 MiB of memory, more than the 1.0 MiB available"
        ),
        "{text}"
    );
    // The f32 factor needs its copy of the system as well.
    let RbfError::Memory(m) = limited(Solver::MixedPrecision) else {
        panic!("mixed precision not refused")
    };
    assert_eq!(m.needed, (unknowns * unknowns * 12) as u64);
    // r³ goes straight to the dense solve (its f32 factor breaks down on real scans).
    let RbfError::Memory(m) = RbfFit::new(Triharmonic)
        .with_memory_limit(1 << 20)
        .fit(&c)
        .unwrap_err()
    else {
        panic!("the r³ fit was not refused")
    };
    assert_eq!(m.needed, (unknowns * unknowns * 8) as u64);
    // The iterative solve needs no dense matrix: the same limit fits it.
    let fit = RbfFit::new(Biharmonic)
        .with_solver(Solver::Auto)
        .with_memory_limit(1 << 20)
        .fit(&c)
        .unwrap();
    assert_eq!(fit.report.solver, "gmres-cardinal");
}

#[test]
fn the_monitor_sees_every_step_and_its_cancel_is_not_a_fallback() {
    use std::ops::ControlFlow;
    use std::sync::{Arc, Mutex};
    let c = sphere_setup(2400);
    let seen = Arc::new(Mutex::new(Vec::new()));
    let log = seen.clone();
    let monitor = Monitor::new(move |p| {
        log.lock().unwrap().push((p.iteration, p.rel_residual));
        ControlFlow::Continue(())
    });
    let fit = RbfFit::new(Biharmonic)
        .with_monitor(monitor)
        .fit(&c)
        .unwrap();
    let seen = seen.lock().unwrap();
    assert_eq!(seen.len(), fit.report.iterations, "{seen:?}");
    let (first, last) = (seen[0].1, seen[seen.len() - 1].1);
    assert!(last < 1e-3 * first, "{first} → {last}");
    // Cancelled after three steps: the fit stops, with no dense solve behind the user's back.
    let cancel = Monitor::new(|p| {
        if p.iteration >= 3 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    let err = RbfFit::new(Biharmonic)
        .with_monitor(cancel)
        .fit(&c)
        .unwrap_err();
    assert!(
        matches!(err, RbfError::Solve(SolveError::Cancelled { .. })),
        "{err}"
    );
}

/// The iterative fit with FMM products whose report measures the residual by the FMM too
/// (above `exact_residual_max`, here 0).
fn fit_with_residual_by_fmm(c: &Constraints<3>, mu: f64) -> Fitted<Biharmonic, 3> {
    RbfFit::new(Biharmonic)
        .with_smoothing(mu)
        .with_solver(Solver::Iterative(IterativeParams {
            fmm_from: 0,
            exact_residual_max: 0,
            ..IterativeParams::default()
        }))
        .fit(c)
        .unwrap()
}

#[test]
fn fmm_products_give_the_dense_fit_to_their_accuracy() {
    let c = sphere_setup(3000);
    let dense = RbfFit::new(Biharmonic)
        .with_solver(Solver::Dense)
        .fit(&c)
        .unwrap();
    let fmm = RbfFit::new(Biharmonic)
        .with_solver(Solver::Iterative(IterativeParams {
            fmm_from: 0,
            ..IterativeParams::default()
        }))
        .fit(&c)
        .unwrap();
    assert_eq!(fmm.report.solver, "gmres-cardinal");
    // The report's residual is the exact direct sum; the targets are ±0.05.
    assert!(fmm.report.max_residual < 1e-7, "{:?}", fmm.report);
    // Away from the constraints the two solutions differ by the system's conditioning times
    // the 1e-8 residual GMRES stops at on inexact products (measured 4.9e-5 of fields ~0.3).
    let d = field_diff(&fmm.field, &dense.field);
    assert!(d < 2e-4, "dense vs FMM products: {d:.1e}");
    assert!(fmm.report.residual_exact);
    // Above `exact_residual_max` the report's residual comes from an FMM of higher order than
    // the products' (one of the same order sees only 3.6e-10 here: the solve absorbed its
    // error): the exact figure to 1%.
    let by_fmm = fit_with_residual_by_fmm(&c, 0.0);
    assert!(!by_fmm.report.residual_exact);
    let exact = c
        .as_slice()
        .iter()
        .map(|con| match con.prescribed {
            Prescribed::Value(v) => (by_fmm.field.value(&con.point) - v).abs(),
            _ => unreachable!(),
        })
        .fold(0.0, f64::max);
    let got = by_fmm.report.max_residual;
    assert!(
        (got - exact).abs() < 0.01 * exact,
        "FMM residual {got:.3e}, exact {exact:.3e}"
    );
}

#[test]
fn greedy_reduction_meets_the_tolerance_at_every_constraint_with_fewer_centres() {
    let c = sphere_setup(3000);
    let tol = 1e-4;
    let (fit, report) = RbfFit::new(Biharmonic)
        .fit_greedy(
            &c,
            &GreedyOptions {
                initial: 200,
                ..GreedyOptions::new(tol)
            },
        )
        .unwrap();
    assert!(report.converged, "{report:?}");
    assert!(fit.field.num_centres() < 3000, "{report:?}");
    assert_eq!(
        report.rounds.last().unwrap().centres,
        fit.field.num_centres()
    );
    // The claim checked independently: every constraint, by the field's own evaluation.
    for con in c.as_slice() {
        let Prescribed::Value(v) = con.prescribed else {
            unreachable!()
        };
        assert!((fit.field.value(&con.point) - v).abs() <= tol);
    }
    assert!(report.max_residual <= tol);
    // Rounds only add centres; the first is the spread start.
    assert_eq!(report.rounds[0].centres, 200);
    assert!(
        report
            .rounds
            .windows(2)
            .all(|w| w[1].centres > w[0].centres)
    );
    // Gradients and a bad tolerance are refused.
    let mut h = Constraints::new();
    h.push_value([0.0; 3], 0.0)
        .push_gradient([0.0; 3], [1.0, 0.0, 0.0]);
    let fit = RbfFit::new(Triharmonic);
    assert!(matches!(
        fit.fit_greedy(&h, &GreedyOptions::new(1e-3)),
        Err(RbfError::Degenerate { .. })
    ));
    assert!(fit.fit_greedy(&c, &GreedyOptions::new(f64::NAN)).is_err());
}

/// The sphere set-up with every value moved by a seeded uniform error of up to `amplitude`.
fn noisy_sphere_setup(n: usize, amplitude: f64) -> Constraints<3> {
    let mut rng = zeroset_field_core::rng::SplitMix64::new(11);
    let mut c = Constraints::new();
    for con in sphere_setup(n).as_slice() {
        let Prescribed::Value(v) = con.prescribed else {
            unreachable!()
        };
        c.push_value(con.point, v + amplitude * (2.0 * rng.unit() - 1.0));
    }
    c
}

/// `[σΦ + μI, P; Pᵀ, 0]` assembled without smoothing, its diagonal shifted here, solved by LU:
/// the reference for every solver's smoothing.
fn smoothed_reference<K: Kernel + Clone>(kernel: &K, c: &Constraints<3>, mu: f64) -> Vec<f64> {
    let f = system::Functionals::new(kernel, c.as_slice()).unwrap();
    let poly = system::Polynomial::fit(&f.points);
    let (n, size) = (f.len(), f.len() + 4);
    let a = system::assemble(kernel, &f, &poly);
    let a = Mat::from_fn(size, size, |i, j| {
        a[j * size + i]
            + if i == j && i < n {
                kernel.sign() * mu
            } else {
                0.0
            }
    });
    let mut rhs = Mat::from_fn(size, 1, |i, _| if i < n { f.targets[i] } else { 0.0 });
    PartialPivLu::new(a.as_ref()).solve_in_place(rhs.as_mut());
    (0..size).map(|i| rhs[(i, 0)]).collect()
}

#[test]
fn every_solver_solves_the_smoothed_system() {
    let c = noisy_sphere_setup(900, 0.01);
    let mu = 0.02;
    let dense = RbfFit::new(Biharmonic)
        .with_smoothing(mu)
        .with_solver(Solver::Dense)
        .fit(&c)
        .unwrap();
    let want = smoothed_reference(&Biharmonic, &c, mu);
    let d = max_rel_diff(&solution(&dense.field), &want);
    assert!(d < 1e-8, "dense vs LU of the smoothed system: {d:.1e}");
    assert!(dense.report.max_residual < 1e-10, "{:?}", dense.report);
    for (solver, tolerance) in [
        (Solver::MixedPrecision, 1e-9),
        (Solver::Iterative(IterativeParams::default()), 1e-9),
        // With a coarse level (more than twice its centres) and FMM products.
        (
            Solver::Iterative(IterativeParams {
                coarse: 300,
                fmm_from: 0,
                ..IterativeParams::default()
            }),
            2e-4,
        ),
    ] {
        let got = RbfFit::new(Biharmonic)
            .with_smoothing(mu)
            .with_solver(solver.clone())
            .fit(&c)
            .unwrap();
        let d = field_diff(&got.field, &dense.field);
        assert!(d < tolerance, "{solver:?}: {d:.1e} from the dense fit");
        assert!(got.report.max_residual < 1e-7, "{:?}", got.report);
    }
    // The residual the FMM measures (above `exact_residual_max`) is the smoothed system's: near
    // 0, far below the misfit (without the diagonal it would be the misfit itself).
    let by_fmm = fit_with_residual_by_fmm(&c, mu);
    assert!(!by_fmm.report.residual_exact);
    assert!(
        by_fmm.report.max_residual < 1e-3 * by_fmm.report.misfit_max,
        "{:?}",
        by_fmm.report
    );
    // r³ (σ = +1) through the same paths.
    let mu3 = 1e-3;
    let tri = RbfFit::new(Triharmonic)
        .with_smoothing(mu3)
        .fit(&c)
        .unwrap();
    let d = max_rel_diff(
        &solution(&tri.field),
        &smoothed_reference(&Triharmonic, &c, mu3),
    );
    assert!(d < 1e-8, "r³: {d:.1e}");
}

#[test]
fn a_smoothed_field_misses_each_value_by_its_weight() {
    let c = noisy_sphere_setup(600, 0.01);
    let mu = 0.05;
    let fit = RbfFit::new(Biharmonic).with_smoothing(mu).fit(&c).unwrap();
    // s(xᵢ) − tᵢ = −σμ wᵢ = μ wᵢ for r.
    let mut sum = 0.0;
    for (con, w) in c.as_slice().iter().zip(fit.field.weights()) {
        let Prescribed::Value(t) = con.prescribed else {
            unreachable!()
        };
        let miss = fit.field.value(&con.point) - t;
        assert!(
            (miss - mu * w).abs() < 1e-10,
            "{miss} against μw = {}",
            mu * w
        );
        sum += miss * miss;
    }
    let rms = (sum / c.len() as f64).sqrt();
    assert!(
        rms > 1e-3,
        "the field should miss the noisy values, rms {rms:.1e}"
    );
    assert!((fit.report.misfit_rms - rms).abs() < 1e-9 * rms.max(1.0));
    // More smoothing misses more; none misses nothing.
    let misfit = |mu: f64| {
        RbfFit::new(Biharmonic)
            .with_smoothing(mu)
            .fit(&c)
            .unwrap()
            .report
            .misfit_rms
    };
    let rising: Vec<f64> = [0.0, 1e-3, 1e-2, 1e-1, 1.0]
        .into_iter()
        .map(misfit)
        .collect();
    assert_eq!(rising[0], 0.0);
    assert!(rising.windows(2).all(|w| w[1] > w[0]), "{rising:?}");
}

#[test]
fn smoothing_recovers_a_smooth_function_from_noisy_values() {
    // 500 scattered values of a smooth function with a seeded uniform error of ±0.1.
    let truth = |p: &[f64; 3]| (3.0 * p[0]).sin() + p[1] * p[2];
    let mut rng = zeroset_field_core::rng::SplitMix64::new(5);
    let mut c = Constraints::new();
    for _ in 0..500 {
        let p = [rng.unit(), rng.unit(), rng.unit()];
        c.push_value(p, truth(&p) + 0.1 * (2.0 * rng.unit() - 1.0));
    }
    let error = |mu: f64| {
        let field = RbfFit::new(Biharmonic)
            .with_smoothing(mu)
            .fit(&c)
            .unwrap()
            .field;
        let mut probe = zeroset_field_core::rng::SplitMix64::new(99);
        let sum: f64 = (0..400)
            .map(|_| {
                let p = std::array::from_fn(|_| 0.2 + 0.6 * probe.unit());
                (field.value(&p) - truth(&p)).powi(2)
            })
            .sum();
        (sum / 400.0).sqrt()
    };
    // Measured rms errors: 0.031 interpolated; μ 0.03, 0.1, 0.3, 1, 3: 0.026, 0.022, 0.019,
    // 0.019, 0.045 (too smooth: the sine flattens).
    let (interpolated, smoothed, flattened) = (error(0.0), error(0.3), error(10.0));
    assert!(
        smoothed < 0.7 * interpolated && flattened > interpolated,
        "rms error {smoothed:.3} smoothed, {interpolated:.3} interpolated, {flattened:.3} at μ 10"
    );
}

#[test]
fn incremental_constraints_keep_the_smoothing() {
    let all = noisy_sphere_setup(300, 0.01);
    let (base, extra) = all.as_slice().split_at(250);
    let to_constraints = |s: &[Constraint<3>]| {
        let mut c = Constraints::new();
        for con in s {
            if let Prescribed::Value(v) = con.prescribed {
                c.push_value(con.point, v);
            }
        }
        c
    };
    let fit = RbfFit::new(Biharmonic).with_smoothing(0.05);
    let mut inc = IncrementalFit::new(&fit, &to_constraints(base)).unwrap();
    inc.add(&to_constraints(extra)).unwrap();
    let want = fit.fit(&all).unwrap();
    let d = field_diff(&inc.field(), &want.field);
    assert!(d < 1e-8, "incremental vs full smoothed fit: {d:.1e}");
}

#[test]
fn two_spheres_touching_at_a_point_fit_with_the_outside_between_them() {
    // Unit spheres around (±1, 0, 0) meet at the origin, which each samples with its own
    // normal (±x, pointing into the other sphere): two points at one place with opposite
    // normals, whose outside offsets would lie inside the other sphere.
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for centre in [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]] {
        for (p, u) in sphere(400, centre, 1.0) {
            points.push(p);
            normals.push(u);
        }
        points.push([0.0; 3]);
        normals.push([-centre[0], 0.0, 0.0]);
    }
    let cloud = zeroset_field_core::PointCloud::with_normals(points, normals).unwrap();
    let (c, report) = Constraints::off_surface(&cloud, Offset::Auto { fraction: 0.01 }).unwrap();
    assert_eq!((report.merged, report.touching), (1, 1));
    let fit = RbfFit::new(Biharmonic).fit(&c).unwrap();
    let f = |p: [f64; 3]| fit.field.value(&p);
    assert!(f([0.0; 3]).abs() < 1e-9, "{}", f([0.0; 3]));
    // Inside each sphere beside the contact — within half the offset of it, and farther —
    // and outside between them above and below it.
    let half = 0.5 * report.initial;
    for x in [-half, half, -0.1, 0.1, -1.0, 1.0] {
        assert!(f([x, 0.0, 0.0]) < 0.0, "{x}: {}", f([x, 0.0, 0.0]));
    }
    for y in [-0.3, 0.3] {
        assert!(f([0.0, y, 0.0]) > 0.0, "{y}: {}", f([0.0, y, 0.0]));
    }
}

#[test]
fn a_flipped_normal_at_a_repeated_sample_takes_its_sheets_side() {
    // A sphere whose point 0 was recorded twice, the first record with its normal flipped:
    // the flipped one is the point kept, but its neighbours all face the other copy's way,
    // so that is the side its offsets take (the other sheet's rule put −ε outside).
    let on = sphere(400, [0.0; 3], 1.0);
    let mut points = vec![on[0].0];
    let mut normals = vec![on[0].1.map(|x| -x)];
    for (p, u) in &on {
        points.push(*p);
        normals.push(*u);
    }
    let cloud = zeroset_field_core::PointCloud::with_normals(points, normals).unwrap();
    let (c, report) = Constraints::off_surface(&cloud, Offset::Auto { fraction: 0.01 }).unwrap();
    assert_eq!((report.merged, report.touching), (1, 0));
    let fit = RbfFit::new(Biharmonic).fit(&c).unwrap();
    let (p, u) = on[0];
    let at = |t: f64| fit.field.value(&std::array::from_fn(|a| p[a] + t * u[a]));
    let half = 0.5 * report.initial;
    assert!(
        at(half) > 0.0 && at(-half) < 0.0,
        "{} {}",
        at(half),
        at(-half)
    );
}
