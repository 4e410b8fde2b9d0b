//! ADMM (paper 004 §5.3) against independent methods: FISTA for one trace-norm term, the
//! generalized forward–backward splitting for MRAS's three, a direct solve for `λ = 0`; rank
//! reduction on a noisy low-rank tensor; specific errors; determinism.

use faer::prelude::Solve;
use faer::{Mat, Side};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zeroset_solvers::admm::{
    AdmmError, AdmmOptions, AdmmStop, ProxTerm, TraceNormTerm, admm, admm_with_progress, objective,
};
use zeroset_tensor::{Tensor3, TensorError, svt, thin_svd};

/// `H = QᵀQ + 0.1 I` (exactly symmetric) with `Q` uniform in `±1/√n`, and `b` uniform in `±1`.
fn random_problem(seed: u64, n: usize) -> (Mat<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let scale = 1.0 / (n as f64).sqrt();
    let q = Mat::from_fn(n, n, |_, _| (rng.random::<f64>() * 2.0 - 1.0) * scale);
    let mut h = Mat::zeros(n, n);
    for i in 0..n {
        for j in 0..n {
            h[(i, j)] = (0..n).map(|k| q[(k, i)] * q[(k, j)]).sum::<f64>();
        }
        h[(i, i)] += 0.1;
    }
    let b = (0..n).map(|_| rng.random::<f64>() * 2.0 - 1.0).collect();
    (h, b)
}

fn refs(terms: &[TraceNormTerm]) -> Vec<&dyn ProxTerm> {
    terms.iter().map(|t| t as &dyn ProxTerm).collect()
}

fn tight() -> AdmmOptions {
    AdmmOptions::default()
        .eps_abs(1e-13)
        .eps_rel(1e-13)
        .max_iter(50_000)
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn mat_vec(h: &Mat<f64>, x: &[f64]) -> Vec<f64> {
    (0..h.nrows())
        .map(|i| (0..h.ncols()).map(|j| h[(i, j)] * x[j]).sum())
        .collect()
}

/// `prox_{t·w‖(·)₍mode₎‖_*}(v)` through `Tensor3::unfold`/`fold` and `zeroset_tensor::svt`,
/// independent of `TraceNormTerm`'s own permutation and reconstruction.
fn tensor_prox(shape: [usize; 3], mode: usize, tau: f64, v: &[f64]) -> Vec<f64> {
    let x = Tensor3::new(shape, v.to_vec()).unwrap();
    let (y, _) = svt(x.unfold(mode).unwrap().as_ref(), tau).unwrap();
    Tensor3::fold(mode, &y, shape).unwrap().as_slice().to_vec()
}

fn extreme_eigenvalues(h: &Mat<f64>) -> (f64, f64) {
    let e = h.self_adjoint_eigenvalues(Side::Lower).unwrap();
    (e[0], e[e.len() - 1])
}

/// FISTA with the strongly convex momentum `(√L − √μ)/(√L + √μ)` on
/// `½cᵀHc − bᵀc + w‖C₍mode₎‖_*`, until the iterate stops moving.
fn fista(h: &Mat<f64>, b: &[f64], shape: [usize; 3], mode: usize, w: f64) -> (Vec<f64>, usize) {
    let n = b.len();
    let (mu, l) = extreme_eigenvalues(h);
    let beta = (l.sqrt() - mu.sqrt()) / (l.sqrt() + mu.sqrt());
    let (mut x, mut y) = (vec![0.0; n], vec![0.0; n]);
    for it in 1..=200_000 {
        let g = mat_vec(h, &y);
        let step: Vec<f64> = (0..n).map(|i| y[i] - (g[i] - b[i]) / l).collect();
        let x_new = tensor_prox(shape, mode, w / l, &step);
        let moved = max_diff(&x_new, &x);
        y = (0..n)
            .map(|i| x_new[i] + beta * (x_new[i] - x[i]))
            .collect();
        x = x_new;
        if moved < 1e-14 && it > 10 {
            return (x, it);
        }
    }
    (x, 200_000)
}

/// The generalized forward–backward splitting (Raguet, Fadili & Peyré 2013, Algorithm 1 with
/// `ω_i = 1/3`, `γ = 1/L`, `λ = 1`) on `½cᵀHc − bᵀc + Σ_i w‖C₍ᵢ₎‖_*`.
fn generalized_forward_backward(
    h: &Mat<f64>,
    b: &[f64],
    shape: [usize; 3],
    w: f64,
) -> (Vec<f64>, usize) {
    let n = b.len();
    let (_, l) = extreme_eigenvalues(h);
    let gamma = 1.0 / l;
    let omega = 1.0 / 3.0;
    let mut x = vec![0.0; n];
    let mut z = vec![vec![0.0; n]; 3];
    for it in 1..=400_000 {
        let g = mat_vec(h, &x);
        for (mode, zi) in z.iter_mut().enumerate() {
            let v: Vec<f64> = (0..n)
                .map(|j| 2.0 * x[j] - zi[j] - gamma * (g[j] - b[j]))
                .collect();
            let p = tensor_prox(shape, mode, gamma / omega * w, &v);
            for j in 0..n {
                zi[j] += p[j] - x[j];
            }
        }
        let x_new: Vec<f64> = (0..n)
            .map(|j| omega * (z[0][j] + z[1][j] + z[2][j]))
            .collect();
        let moved = max_diff(&x_new, &x);
        x = x_new;
        if moved < 1e-14 && it > 10 {
            return (x, it);
        }
    }
    (x, 400_000)
}

fn numerical_rank(m: &Mat<f64>) -> usize {
    let s = thin_svd(m.as_ref()).unwrap().s;
    s.iter().filter(|&&v| v > 1e-6 * s[0]).count()
}

#[test]
fn admm_trace_norm_term_is_the_column_major_unfolding() {
    let shape = [3, 4, 5];
    let c: Vec<f64> = (0..60).map(|i| i as f64 * 0.5 - 7.0).collect();
    let x = Tensor3::new(shape, c.clone()).unwrap();
    for mode in 0..3 {
        let t = TraceNormTerm::new(shape, mode, 2.0).unwrap();
        let (rows, cols) = t.unfolding_dims();
        let mut z = vec![0.0; 60];
        t.apply(&c, &mut z);
        let m = x.unfold(mode).unwrap();
        assert_eq!((m.nrows(), m.ncols()), (rows, cols));
        for j in 0..cols {
            for i in 0..rows {
                assert_eq!(z[i + rows * j], m[(i, j)]);
            }
        }
        let mut back = vec![0.0; 60];
        t.apply_transpose_add(&z, &mut back);
        assert_eq!(back, c);
        // Value and prox agree with the tensor crate's trace norm and SVT.
        let tn = zeroset_tensor::trace_norm(m.as_ref()).unwrap();
        assert!((t.value(&z).unwrap() - 2.0 * tn).abs() < 1e-12 * tn);
        let mut p = vec![0.0; 60];
        t.prox(&z, 0.7, &mut p).unwrap();
        let mut pc = vec![0.0; 60];
        t.apply_transpose_add(&p, &mut pc);
        assert!(max_diff(&pc, &tensor_prox(shape, mode, 1.4, &c)) < 1e-12);
    }
}

/// Test 1: one trace-norm term; ADMM against FISTA (accelerated proximal gradient).
#[test]
fn admm_one_trace_norm_term_matches_fista() {
    let shape = [3, 4, 5];
    let (h, b) = random_problem(1, 60);
    let mode = 1;
    let w = 2.0;
    let term = TraceNormTerm::new(shape, mode, w).unwrap();
    let sol = admm(h.as_ref(), &b, &[&term], &tight()).unwrap();
    assert!(sol.converged, "{sol:?}");
    let (x, fista_iterations) = fista(&h, &b, shape, mode, w);
    let f_fista = objective(h.as_ref(), &b, &[&term], &x).unwrap();
    let dc = max_diff(&sol.c, &x);
    let df = (sol.objective - f_fista).abs();
    eprintln!(
        "ADMM vs FISTA: max|Δc| = {dc:.3e}, |Δobjective| = {df:.3e}, objective {:.12}, \
         ADMM iterations {}, FISTA iterations {fista_iterations}",
        sol.objective, sol.iterations
    );
    assert!(dc < 1e-6 && df < 1e-6);
    // The term is active: the unfolding's rank drops below full.
    let rank = numerical_rank(
        &Tensor3::new(shape, sol.c.clone())
            .unwrap()
            .unfold(mode)
            .unwrap(),
    );
    eprintln!("mode-{mode} rank of the minimiser: {rank} (full: 4)");
    assert!((1..4).contains(&rank), "{rank}");
}

/// Over-relaxation changes the path, not the minimiser: `ρ = 1.6` reaches the `ρ = 1`
/// answer, and the reported objective is [`objective`] at the returned `c` (the solver computes
/// it from its last c-step, without a product with `H`). `ρ` outside `(0, 2)` is refused.
#[test]
fn over_relaxation_reaches_the_same_minimiser() {
    let shape = [4, 5, 3];
    let (h, b) = random_problem(5, 60);
    let terms = TraceNormTerm::mras_terms(shape, 2.0).unwrap();
    let plain = admm(h.as_ref(), &b, &refs(&terms), &tight()).unwrap();
    let relaxed = admm(h.as_ref(), &b, &refs(&terms), &tight().relaxation(1.6)).unwrap();
    assert!(plain.converged && relaxed.converged);
    let dc = max_diff(&plain.c, &relaxed.c);
    eprintln!(
        "ρ = 1: {} iterations, ρ = 1.6: {}; max|Δc| = {dc:.3e}",
        plain.iterations, relaxed.iterations
    );
    assert!(dc < 1e-8, "{dc}");
    for sol in [&plain, &relaxed] {
        let direct = objective(h.as_ref(), &b, &refs(&terms), &sol.c).unwrap();
        assert!(
            (sol.objective - direct).abs() <= 1e-10 * direct.abs().max(1.0),
            "{} vs {direct}",
            sol.objective
        );
    }
    for bad in [0.0, 2.0, f64::NAN] {
        let err = admm(h.as_ref(), &b, &refs(&terms), &tight().relaxation(bad)).unwrap_err();
        assert!(
            matches!(
                err,
                AdmmError::InvalidOption {
                    name: "relaxation",
                    ..
                }
            ),
            "{err:?}"
        );
    }
}

/// Test 2: the three MRAS terms; ADMM against the generalized forward–backward splitting.
#[test]
fn admm_mras_terms_match_generalized_forward_backward() {
    let shape = [3, 4, 5];
    let (h, noise) = random_problem(2, 60);
    // b = H·(a rank-2 tensor) + noise, so that the low-rank terms have something to find.
    let signal = Tensor3::from_fn(shape, |i, j, k| {
        let (x, y, z) = (i as f64, j as f64, k as f64);
        (1.0 + x) * (y - 1.5) * (0.5 + z) - 0.8 * (2.0 - x) * (1.0 + 0.5 * y) * (z - 2.0)
    });
    let hs = mat_vec(&h, signal.as_slice());
    let b: Vec<f64> = hs.iter().zip(&noise).map(|(s, e)| s + 0.03 * e).collect();
    let lambda = 3.0;
    let terms = TraceNormTerm::mras_terms(shape, lambda).unwrap();
    let sol = admm(h.as_ref(), &b, &refs(&terms), &tight()).unwrap();
    assert!(sol.converged, "{sol:?}");
    let (x, gfb_iterations) = generalized_forward_backward(&h, &b, shape, lambda / 3.0);
    let f_gfb = objective(h.as_ref(), &b, &refs(&terms), &x).unwrap();
    let dc = max_diff(&sol.c, &x);
    let df = (sol.objective - f_gfb).abs();
    let ranks: Vec<usize> = (0..3)
        .map(|m| {
            numerical_rank(
                &Tensor3::new(shape, sol.c.clone())
                    .unwrap()
                    .unfold(m)
                    .unwrap(),
            )
        })
        .collect();
    eprintln!(
        "ADMM vs GFB: max|Δc| = {dc:.3e}, |Δobjective| = {df:.3e}, objective {:.12}, \
         ADMM iterations {}, GFB iterations {gfb_iterations}, unfolding ranks {ranks:?}",
        sol.objective, sol.iterations
    );
    assert!(dc < 1e-6 && df < 1e-6);
    // The terms are active: every unfolding loses rank, and c is not 0.
    assert!(sol.objective < 0.0);
    assert!(
        ranks
            .iter()
            .zip([3, 4, 5])
            .all(|(&r, full)| 0 < r && r < full),
        "{ranks:?}"
    );
}

/// Test 3: with `λ = 0` ADMM solves `H c = b`.
#[test]
fn admm_zero_lambda_gives_the_linear_solve() {
    let shape = [3, 4, 5];
    let (h, b) = random_problem(3, 60);
    let terms = TraceNormTerm::mras_terms(shape, 0.0).unwrap();
    let sol = admm(h.as_ref(), &b, &refs(&terms), &tight()).unwrap();
    assert!(sol.converged);
    let rhs = Mat::from_fn(60, 1, |i, _| b[i]);
    let exact = h.partial_piv_lu().solve(&rhs);
    let exact: Vec<f64> = (0..60).map(|i| exact[(i, 0)]).collect();
    let rel = max_diff(&sol.c, &exact) / exact.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
    eprintln!(
        "λ = 0: relative error {rel:.3e} after {} iterations",
        sol.iterations
    );
    assert!(rel < 1e-10, "{rel}");
    // With no terms at all it is a direct solve.
    let direct = admm(h.as_ref(), &b, &[], &AdmmOptions::default()).unwrap();
    assert_eq!(direct.iterations, 0);
    assert!(max_diff(&direct.c, &exact) < 1e-12);
}

/// Test 4: trace-norm minimisation recovers the low unfolding ranks of a noisy rank-2 tensor.
#[test]
fn admm_trace_norm_lowers_the_unfolding_ranks() {
    let shape = [6, 6, 6];
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut factor = || -> Vec<f64> { (0..6).map(|_| rng.random::<f64>() * 2.0 - 1.0).collect() };
    let (a1, b1, c1, a2, b2, c2) = (factor(), factor(), factor(), factor(), factor(), factor());
    let clean = Tensor3::from_fn(shape, |i, j, k| {
        2.0 * a1[i] * b1[j] * c1[k] + a2[i] * b2[j] * c2[k]
    });
    let noisy: Vec<f64> = clean
        .as_slice()
        .iter()
        .map(|v| v + 1e-2 * (rng.random::<f64>() * 2.0 - 1.0))
        .collect();
    let noisy_t = Tensor3::new(shape, noisy.clone()).unwrap();
    let h = Mat::<f64>::identity(216, 216);
    let terms = TraceNormTerm::mras_terms(shape, 0.3).unwrap();
    let sol = admm(h.as_ref(), &noisy, &refs(&terms), &AdmmOptions::default()).unwrap();
    assert!(sol.converged, "{:?}", sol.stop);
    let result = Tensor3::new(shape, sol.c.clone()).unwrap();
    for mode in 0..3 {
        let before = numerical_rank(&noisy_t.unfold(mode).unwrap());
        let after = numerical_rank(&result.unfold(mode).unwrap());
        eprintln!("mode {mode}: rank {before} → {after}");
        assert_eq!(before, 6);
        assert!(after <= 3, "mode {mode}: rank {after}");
    }
    let err = result
        .as_slice()
        .iter()
        .zip(clean.as_slice())
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
        / clean.frobenius_norm();
    eprintln!(
        "relative distance to the clean tensor {err:.3e} ({} iterations)",
        sol.iterations
    );
    assert!(err < 0.2, "{err}");
}

/// A term whose map is `2·I`: not orthogonal.
struct Scaled(usize);

impl ProxTerm for Scaled {
    fn dims(&self) -> (usize, usize) {
        (self.0, self.0)
    }
    fn apply(&self, c: &[f64], out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(c) {
            *o = 2.0 * v;
        }
    }
    fn apply_transpose_add(&self, z: &[f64], out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(z) {
            *o += 2.0 * v;
        }
    }
    fn prox(&self, v: &[f64], _step: f64, out: &mut [f64]) -> Result<(), AdmmError> {
        out.copy_from_slice(v);
        Ok(())
    }
    fn value(&self, _z: &[f64]) -> Result<f64, AdmmError> {
        Ok(0.0)
    }
}

/// Test 5: bad inputs give specific errors.
#[test]
fn admm_bad_inputs_are_specific_errors() {
    let shape = [2, 3, 4];
    let (h, b) = random_problem(5, 24);
    let terms = TraceNormTerm::mras_terms(shape, 0.1).unwrap();
    let t = refs(&terms);
    let o = AdmmOptions::default();
    let run = |h: &Mat<f64>, b: &[f64], t: &[&dyn ProxTerm], o: &AdmmOptions| {
        admm(h.as_ref(), b, t, o).unwrap_err()
    };

    assert_eq!(
        run(&Mat::zeros(24, 23), &b, &t, &o),
        AdmmError::NotSquare { rows: 24, cols: 23 }
    );
    assert_eq!(
        run(&h, &b[..23], &t, &o),
        AdmmError::Length {
            what: "b",
            expected: 24,
            got: 23
        }
    );
    let small = TraceNormTerm::new([2, 2, 2], 0, 1.0).unwrap();
    assert_eq!(
        run(&h, &b, &[t[0], &small], &o),
        AdmmError::TermDimension {
            term: 1,
            expected: 24,
            got: 8
        }
    );
    assert!(matches!(
        run(&h, &b, &[&Scaled(24)], &o),
        AdmmError::NotOrthogonal { term: 0, .. }
    ));
    let mut bad_h = h.clone();
    bad_h[(3, 5)] = f64::NAN;
    assert_eq!(
        run(&bad_h, &b, &t, &o),
        AdmmError::NonFiniteMatrix { row: 3, col: 5 }
    );
    let mut bad_b = b.clone();
    bad_b[7] = f64::INFINITY;
    assert_eq!(
        run(&h, &bad_b, &t, &o),
        AdmmError::NonFiniteVector {
            what: "b",
            index: 7
        }
    );
    let mut asym = h.clone();
    asym[(4, 1)] += 1e-3;
    assert_eq!(
        run(&asym, &b, &t, &o),
        AdmmError::NotSymmetric { row: 4, col: 1 }
    );
    for eta in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            run(&h, &b, &t, &o.clone().eta(eta)),
            AdmmError::Eta { .. }
        ));
    }
    assert!(matches!(
        run(&h, &b, &t, &o.clone().eps_abs(-1.0)),
        AdmmError::InvalidOption {
            name: "eps_abs",
            ..
        }
    ));
    assert!(matches!(
        run(&h, &b, &t, &o.clone().eps_rel(f64::NAN)),
        AdmmError::InvalidOption {
            name: "eps_rel",
            ..
        }
    ));
    assert!(matches!(
        run(&h, &b, &t, &o.clone().max_iter(0)),
        AdmmError::InvalidOption {
            name: "max_iter",
            ..
        }
    ));
    // H = −10 I: H + 3ηI = −7 I is not positive definite.
    let neg = Mat::from_fn(24, 24, |i, j| if i == j { -10.0 } else { 0.0 });
    assert_eq!(
        run(&neg, &b, &t, &o),
        AdmmError::NotPositiveDefinite { pivot: 0, terms: 3 }
    );
    // H = −I: H + 3ηI = 2I factors (η = 1), but the objective is unbounded below and the
    // iterates run away; the error says why.
    let neg_one = Mat::from_fn(24, 24, |i, j| if i == j { -1.0 } else { 0.0 });
    let e = run(&neg_one, &b, &t, &o);
    assert!(
        matches!(e, AdmmError::NotPositiveSemiDefinite { pivot: 0, .. }),
        "{e:?}"
    );
    assert!(e.to_string().contains("not positive semi-definite"), "{e}");
    // With no terms a singular H has no Cholesky factor.
    assert!(matches!(
        run(&Mat::zeros(24, 24), &b, &[], &o),
        AdmmError::NotPositiveDefinite { terms: 0, .. }
    ));

    assert_eq!(
        TraceNormTerm::new(shape, 0, -1.0).unwrap_err(),
        AdmmError::Weight { weight: -1.0 }
    );
    assert!(matches!(
        TraceNormTerm::mras_terms(shape, f64::NAN),
        Err(AdmmError::Weight { .. })
    ));
    assert_eq!(
        TraceNormTerm::new(shape, 3, 1.0).unwrap_err(),
        AdmmError::Tensor(TensorError::Mode { mode: 3 })
    );
    assert_eq!(
        TraceNormTerm::new([2, 0, 4], 0, 1.0).unwrap_err(),
        AdmmError::Tensor(TensorError::EmptyShape { shape: [2, 0, 4] })
    );
    assert_eq!(
        objective(h.as_ref(), &b, &t, &b[..5]).unwrap_err(),
        AdmmError::Length {
            what: "c",
            expected: 24,
            got: 5
        }
    );
}

/// Test 6: the same input gives the same bits; the callback sees every iteration and can stop.
#[test]
fn admm_runs_are_deterministic_and_cancellable() {
    let shape = [3, 4, 5];
    let (h, b) = random_problem(6, 60);
    let terms = TraceNormTerm::mras_terms(shape, 1.0).unwrap();
    let first = admm(h.as_ref(), &b, &refs(&terms), &AdmmOptions::default()).unwrap();
    let second = admm(h.as_ref(), &b, &refs(&terms), &AdmmOptions::default()).unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&first.c), bits(&second.c));
    assert_eq!(first.objective.to_bits(), second.objective.to_bits());
    assert_eq!(first.iterations, second.iterations);

    let mut seen = Vec::new();
    let stopped = admm_with_progress(
        h.as_ref(),
        &b,
        &refs(&terms),
        &AdmmOptions::default(),
        |p| {
            seen.push(p.iteration);
            p.iteration < 5
        },
    )
    .unwrap();
    assert_eq!(stopped.stop, AdmmStop::Cancelled);
    assert!(!stopped.converged);
    assert_eq!((stopped.iterations, seen), (5, vec![1, 2, 3, 4, 5]));

    let limited = admm(
        h.as_ref(),
        &b,
        &refs(&terms),
        &AdmmOptions::default().max_iter(3),
    )
    .unwrap();
    assert_eq!(
        (limited.stop, limited.iterations),
        (AdmmStop::MaxIterations, 3)
    );
}

#[test]
fn a_warm_start_at_the_answer_stays_there() {
    use zeroset_solvers::admm::ridge_solution;
    let shape = [3, 4, 5];
    let n = 60;
    let h = Mat::<f64>::from_fn(n, n, |i, j| {
        (if i == j { 2.0 } else { 0.0 }) + 0.01 * ((i + 1) * (j + 1)) as f64 / n as f64
    });
    let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
    let c0 = ridge_solution(h.as_ref(), &b, 0.0).unwrap();
    let terms = TraceNormTerm::mras_terms(shape, 0.0).unwrap();
    let refs: Vec<&dyn ProxTerm> = terms.iter().map(|t| t as &dyn ProxTerm).collect();
    let opts = AdmmOptions::default().start(c0.clone());
    let sol = admm(h.as_ref(), &b, &refs, &opts).unwrap();
    assert!(sol.converged);
    assert!(sol.iterations <= 2, "{} iterations", sol.iterations);
    for (a, e) in sol.c.iter().zip(&c0) {
        assert!((a - e).abs() < 1e-12, "{a} vs {e}");
    }
    let bad = AdmmOptions::default().start(vec![0.0; 3]);
    assert!(matches!(
        admm(h.as_ref(), &b, &refs, &bad),
        Err(AdmmError::Length { what: "start", .. })
    ));
}
