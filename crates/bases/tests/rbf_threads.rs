//! Every RBF solver gives the same bits on 1 and 3 threads: the dense Cholesky, the
//! mixed-precision solve, GMRES in the cardinal basis with its coarse level (direct sums), and
//! the same with FMM products (the path of `zeroset fit` from 15,000 functionals on, too slow
//! for the command-line tests).

use zeroset_bases::rbf::{
    Biharmonic, Constraints, IterativeParams, Kernel, RbfFit, Solver, Triharmonic,
};

/// `n` points on a sphere (Fibonacci) with values 0, and ±0.05 at ±0.05 along the normal of
/// every third one.
fn sphere_setup(n: usize) -> Constraints<3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut c = Constraints::new();
    for i in 0..n {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - z * z).sqrt();
        let t = golden * i as f64;
        let u = [r * t.cos(), r * t.sin(), z];
        let at = |d: f64| std::array::from_fn(|a| 0.5 + (0.35 + d) * u[a]);
        c.push_value(at(0.0), 0.0);
        if i % 3 == 0 {
            c.push_value(at(0.05), 0.05);
            c.push_value(at(-0.05), -0.05);
        }
    }
    c
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// The fit's weights and polynomial coefficients as bits, and its solver's name.
fn fit_bits(
    threads: usize,
    fit: impl FnOnce() -> (Vec<f64>, &'static str) + Send,
) -> (Vec<u64>, &'static str) {
    let (x, solver) = in_pool(threads, fit);
    (x.iter().map(|v| v.to_bits()).collect(), solver)
}

fn assert_same_bits(what: &str, fit: impl Fn() -> (Vec<f64>, &'static str) + Sync) {
    let (one, solver) = fit_bits(1, &fit);
    let (three, again) = fit_bits(3, &fit);
    assert_eq!(solver, again, "{what}");
    assert_eq!(one.len(), three.len(), "{what}");
    let differ = one.iter().zip(&three).filter(|(a, b)| a != b).count();
    assert!(
        differ == 0,
        "{what} ({solver}): {differ} of {} coefficients differ between 1 and 3 threads",
        one.len()
    );
}

fn solution<K: Kernel>(fitted: &zeroset_bases::rbf::Fitted<K, 3>) -> Vec<f64> {
    let mut x = fitted.field.weights().to_vec();
    x.extend_from_slice(fitted.field.polynomial_coefficients());
    x
}

#[test]
fn dense_and_mixed_fits_have_the_same_bits_on_any_thread_count() {
    let c = sphere_setup(900);
    assert_same_bits("dense, r", || {
        let f = RbfFit::new(Biharmonic)
            .with_solver(Solver::Dense)
            .fit(&c)
            .unwrap();
        (solution(&f), f.report.solver)
    });
    assert_same_bits("mixed, r3", || {
        let f = RbfFit::new(Triharmonic)
            .with_solver(Solver::MixedPrecision)
            .fit(&c)
            .unwrap();
        (solution(&f), f.report.solver)
    });
}

#[test]
fn iterative_fits_have_the_same_bits_on_any_thread_count() {
    let c = sphere_setup(1500);
    // Direct-sum products, with a coarse level (factored and solved densely every step).
    assert_same_bits("iterative, coarse level", || {
        let f = RbfFit::new(Biharmonic)
            .with_solver(Solver::Iterative(IterativeParams {
                coarse: 400,
                ..IterativeParams::default()
            }))
            .fit(&c)
            .unwrap();
        (solution(&f), f.report.solver)
    });
    // FMM products, and the report's residual by the FMM too.
    assert_same_bits("iterative, FMM products", || {
        let f = RbfFit::new(Biharmonic)
            .with_solver(Solver::Iterative(IterativeParams {
                coarse: 400,
                fmm_from: 0,
                exact_residual_max: 0,
                ..IterativeParams::default()
            }))
            .fit(&c)
            .unwrap();
        assert!(!f.report.residual_exact);
        (
            {
                let mut x = solution(&f);
                x.push(f.report.max_residual);
                x
            },
            f.report.solver,
        )
    });
}
