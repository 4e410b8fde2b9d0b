//! Flexible GMRES against truth: exact termination where theory gives it (at most `n` steps
//! unrestarted; 1 step with `M⁻¹ = A⁻¹`; 2 or 3 steps with the ideal saddle-point
//! preconditioners of Murphy–Golub–Wathen; `d` steps for `d` distinct eigenvalues; `n` steps and
//! none fewer on the cyclic shift), dense LU for the solutions, and the error contract.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicUsize, Ordering};

use faer::Mat;
use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::sparse::{SparseColMat, Triplet};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zeroset_field_core::lsq::{LinearOperator, LsqMatrix, Monitor, SolveError};
use zeroset_solvers::gmres::Gmres;
use zeroset_solvers::{Diagonal, Preconditioner};

// ---------------------------------------------------------------------------------------------
// Problems and helpers

/// `−Δu + c(u_x + u_y)` on a `k × k` interior grid of the unit square, central differences,
/// scaled by `h²`: diagonal 4, neighbours `−1 ± c h/2`. Nonsymmetric; its symmetric part is
/// the (SPD) Laplacian, so GMRES(m) converges for every `m` (Elman 1982).
fn convection_diffusion(k: usize, c: f64) -> SparseColMat<usize, f64> {
    let h = 1.0 / (k + 1) as f64;
    let p = c * h / 2.0;
    let idx = |i: usize, j: usize| i * k + j;
    let mut t = Vec::new();
    for i in 0..k {
        for j in 0..k {
            let row = idx(i, j);
            t.push(Triplet::new(row, row, 4.0));
            if i > 0 {
                t.push(Triplet::new(row, idx(i - 1, j), -1.0 - p));
            }
            if i + 1 < k {
                t.push(Triplet::new(row, idx(i + 1, j), -1.0 + p));
            }
            if j > 0 {
                t.push(Triplet::new(row, idx(i, j - 1), -1.0 - p));
            }
            if j + 1 < k {
                t.push(Triplet::new(row, idx(i, j + 1), -1.0 + p));
            }
        }
    }
    SparseColMat::try_new_from_triplets(k * k, k * k, &t).unwrap()
}

fn to_dense(a: &SparseColMat<usize, f64>) -> Mat<f64> {
    let mut d = Mat::zeros(a.nrows(), a.ncols());
    for j in 0..a.ncols() {
        for (i, v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
            d[(i, j)] += v;
        }
    }
    d
}

fn lu_solve(a: &Mat<f64>, b: &[f64]) -> Vec<f64> {
    let rhs = Mat::from_fn(b.len(), 1, |i, _| b[i]);
    let x = PartialPivLu::new(a.as_ref()).solve(rhs);
    (0..b.len()).map(|i| x[(i, 0)]).collect()
}

fn inverse(a: &Mat<f64>) -> Mat<f64> {
    PartialPivLu::new(a.as_ref()).solve(Mat::<f64>::identity(a.nrows(), a.ncols()))
}

fn mat_vec(a: &Mat<f64>, x: &[f64]) -> Vec<f64> {
    (0..a.nrows())
        .map(|i| (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum())
        .collect()
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn rel_diff(x: &[f64], truth: &[f64]) -> f64 {
    let d: Vec<f64> = x.iter().zip(truth).map(|(a, b)| a - b).collect();
    norm(&d) / norm(truth)
}

fn measured_residual(a: &Mat<f64>, x: &[f64], b: &[f64]) -> f64 {
    let ax = mat_vec(a, x);
    let r: Vec<f64> = b.iter().zip(&ax).map(|(b, y)| b - y).collect();
    norm(&r) / norm(b)
}

fn random_vec(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
    (0..n).map(|_| rng.random::<f64>() * 2.0 - 1.0).collect()
}

/// A dense matrix behind the matrix-free interface (the operator path of the solver).
struct DenseOperator(Mat<f64>);

impl LinearOperator for DenseOperator {
    fn nrows(&self) -> usize {
        self.0.nrows()
    }
    fn ncols(&self) -> usize {
        self.0.ncols()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        y.copy_from_slice(&mat_vec(&self.0, x));
    }
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
        x.copy_from_slice(&mat_vec(&self.0.transpose().to_owned(), y));
    }
}

/// `M⁻¹` given explicitly as a dense matrix.
#[derive(Debug)]
struct DenseInverse(Mat<f64>);

impl Preconditioner for DenseInverse {
    fn name(&self) -> &'static str {
        "dense-inverse"
    }
    fn dim(&self) -> usize {
        self.0.nrows()
    }
    fn apply_inverse(&self, v: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&mat_vec(&self.0, v));
    }
}

/// A different `M` every call: `1 + (call mod 4)` Jacobi sweeps on `A z = v` from `z = 0`.
#[derive(Debug)]
struct VaryingJacobi {
    a: Mat<f64>,
    calls: AtomicUsize,
}

impl Preconditioner for VaryingJacobi {
    fn name(&self) -> &'static str {
        "varying-jacobi"
    }
    fn dim(&self) -> usize {
        self.a.nrows()
    }
    fn apply_inverse(&self, v: &[f64], out: &mut [f64]) {
        let sweeps = 1 + self.calls.fetch_add(1, Ordering::Relaxed) % 4;
        let n = v.len();
        out.fill(0.0);
        for _ in 0..sweeps {
            let prev = out.to_vec();
            for i in 0..n {
                let off: f64 = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| self.a[(i, j)] * prev[j])
                    .sum();
                out[i] = (v[i] - off) / self.a[(i, i)];
            }
        }
    }
}

/// A different `M` every call: an inner unpreconditioned GMRES of `2 + (call mod 5)` steps.
#[derive(Debug)]
struct InnerGmres {
    a: Mat<f64>,
    calls: AtomicUsize,
}

impl Preconditioner for InnerGmres {
    fn name(&self) -> &'static str {
        "inner-gmres"
    }
    fn dim(&self) -> usize {
        self.a.nrows()
    }
    fn apply_inverse(&self, v: &[f64], out: &mut [f64]) {
        let steps = 2 + self.calls.fetch_add(1, Ordering::Relaxed) % 5;
        let inner = Gmres::default()
            .with_restart(steps)
            .with_max_iterations(steps)
            .with_tolerance(1e-14);
        let x = match inner.solve((&self.a).into(), v, None, None) {
            Ok(s) => s.x,
            Err(SolveError::NoConvergence { x, .. }) => x,
            Err(e) => panic!("inner solve: {e}"),
        };
        out.copy_from_slice(&x);
    }
}

/// The RBF-interpolation shape `K = [[A, B], [Bᵀ, 0]]`: `A` SPD random (`n₁ × n₁`), `B`
/// random `n₁ × n₂` (full column rank with probability 1). Symmetric indefinite: `n₁` positive
/// and `n₂` negative eigenvalues.
struct SaddlePoint {
    k: Mat<f64>,
    a: Mat<f64>,
    b: Mat<f64>,
}

fn saddle_point(seed: u64, n1: usize, n2: usize) -> SaddlePoint {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let g = Mat::from_fn(n1, n1, |_, _| rng.random::<f64>() * 2.0 - 1.0);
    let a = Mat::from_fn(n1, n1, |i, j| {
        let gtg: f64 = (0..n1).map(|l| g[(l, i)] * g[(l, j)]).sum();
        gtg / n1 as f64 + if i == j { 0.05 } else { 0.0 }
    });
    let b = Mat::from_fn(n1, n2, |_, _| rng.random::<f64>() * 2.0 - 1.0);
    let n = n1 + n2;
    let k = Mat::from_fn(n, n, |i, j| match (i < n1, j < n1) {
        (true, true) => a[(i, j)],
        (true, false) => b[(i, j - n1)],
        (false, true) => b[(j, i - n1)],
        (false, false) => 0.0,
    });
    SaddlePoint { k, a, b }
}

impl SaddlePoint {
    /// The Schur complement `S = Bᵀ A⁻¹ B` (SPD) and `A⁻¹`.
    fn schur(&self) -> (Mat<f64>, Mat<f64>) {
        let a_inv = inverse(&self.a);
        let s = self.b.transpose() * &a_inv * &self.b;
        (s, a_inv)
    }

    /// `M⁻¹` for `M = diag(A, S)`: `K M⁻¹` has the three eigenvalues `1, (1 ± √5)/2`.
    fn block_diagonal(&self) -> DenseInverse {
        let (s, a_inv) = self.schur();
        let s_inv = inverse(&s);
        let (n1, n) = (self.a.nrows(), self.k.nrows());
        DenseInverse(Mat::from_fn(n, n, |i, j| match (i < n1, j < n1) {
            (true, true) => a_inv[(i, j)],
            (false, false) => s_inv[(i - n1, j - n1)],
            _ => 0.0,
        }))
    }

    /// `M⁻¹` for `M = [[A, B], [0, −S]]`: `K M⁻¹` has the single eigenvalue 1 and minimal
    /// polynomial of degree 2.
    fn block_triangular(&self) -> DenseInverse {
        let (s, a_inv) = self.schur();
        let s_inv = inverse(&s);
        let top_right = &a_inv * &self.b * &s_inv;
        let (n1, n) = (self.a.nrows(), self.k.nrows());
        DenseInverse(Mat::from_fn(n, n, |i, j| match (i < n1, j < n1) {
            (true, true) => a_inv[(i, j)],
            (true, false) => top_right[(i, j - n1)],
            (false, false) => -s_inv[(i - n1, j - n1)],
            (false, true) => 0.0,
        }))
    }
}

// ---------------------------------------------------------------------------------------------
// Convergence

#[test]
fn unrestarted_gmres_solves_convection_diffusion_in_at_most_n_steps() {
    let a = convection_diffusion(10, 20.0);
    let n = a.nrows();
    let dense = to_dense(&a);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let b = random_vec(&mut rng, n);
    let solver = Gmres::default().with_restart(n).with_max_iterations(n);
    let s = solver.solve((&a).into(), &b, None, None).unwrap();
    println!(
        "convection-diffusion n = {n}: {} iterations, rel residual {:.2e}",
        s.info.iterations, s.info.rel_residual
    );
    assert!(s.info.iterations <= n);
    assert!(s.info.rel_residual <= 1e-10, "{}", s.info.rel_residual);
    assert!(measured_residual(&dense, &s.x, &b) <= 1e-10);
    assert!(rel_diff(&s.x, &lu_solve(&dense, &b)) <= 1e-8);
    assert_eq!(s.info.solver, "gmres");
    assert_eq!(s.info.detail("cycles"), Some(1.0));

    // The same through the dense view and the matrix-free operator.
    let via_dense = solver.solve((&dense).into(), &b, None, None).unwrap();
    let op = DenseOperator(dense.clone());
    let via_op = solver
        .solve(LsqMatrix::Operator(&op), &b, None, None)
        .unwrap();
    assert!(rel_diff(&via_dense.x, &s.x) <= 1e-12);
    assert!(rel_diff(&via_op.x, &s.x) <= 1e-12);
}

#[test]
fn a_restart_shorter_than_needed_still_converges() {
    let a = convection_diffusion(10, 20.0);
    let n = a.nrows();
    let dense = to_dense(&a);
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let b = random_vec(&mut rng, n);
    let full = Gmres::default()
        .with_restart(n)
        .solve((&a).into(), &b, None, None)
        .unwrap();
    for restart in [5, 10, 20] {
        let s = Gmres::default()
            .with_restart(restart)
            .with_max_iterations(5000)
            .solve((&a).into(), &b, None, None)
            .unwrap();
        println!(
            "GMRES({restart}): {} iterations, {} cycles (unrestarted: {})",
            s.info.iterations,
            s.info.detail("cycles").unwrap(),
            full.info.iterations
        );
        assert!(s.info.detail("cycles").unwrap() > 1.0);
        assert!(s.info.iterations > full.info.iterations);
        assert!(s.info.rel_residual <= 1e-10);
        assert!(rel_diff(&s.x, &lu_solve(&dense, &b)) <= 1e-8);
    }
}

#[test]
fn saddle_point_matches_dense_lu_with_and_without_preconditioners() {
    let p = saddle_point(3, 40, 4);
    let n = p.k.nrows();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    // RBF-like right-hand side: values on the first block, zeros for the polynomial rows.
    let mut b = random_vec(&mut rng, n);
    b[40..].fill(0.0);
    let truth = lu_solve(&p.k, &b);
    let solver = Gmres::default().with_tolerance(1e-10);

    let plain = solver.solve((&p.k).into(), &b, None, None).unwrap();
    let (diag, tri) = (p.block_diagonal(), p.block_triangular());
    let with_diag = solver.solve((&p.k).into(), &b, None, Some(&diag)).unwrap();
    let with_tri = solver.solve((&p.k).into(), &b, None, Some(&tri)).unwrap();
    for (name, s) in [
        ("none", &plain),
        ("block-diagonal diag(A, S)", &with_diag),
        ("block-triangular [[A, B], [0, -S]]", &with_tri),
    ] {
        println!(
            "saddle point n = {n}, preconditioner {name}: {} iterations, rel residual {:.2e}, \
             error vs LU {:.2e}",
            s.info.iterations,
            s.info.rel_residual,
            rel_diff(&s.x, &truth)
        );
        assert!(s.info.rel_residual <= 1e-10, "{name}");
        assert!(rel_diff(&s.x, &truth) <= 1e-8, "{name}");
    }
    assert!(plain.info.iterations <= n);
    // Murphy–Golub–Wathen (SIAM J. Sci. Comput. 21, 2000): three and two distinct eigenvalues.
    assert!(
        with_diag.info.iterations <= 3,
        "{}",
        with_diag.info.iterations
    );
    assert!(
        with_tri.info.iterations <= 2,
        "{}",
        with_tri.info.iterations
    );
}

#[test]
fn the_exact_inverse_as_preconditioner_takes_one_step() {
    let p = saddle_point(5, 30, 3);
    let a = convection_diffusion(8, 10.0);
    for k in [p.k, to_dense(&a)] {
        let n = k.nrows();
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
        let m = DenseInverse(inverse(&k));
        let s = Gmres::default()
            .solve((&k).into(), &b, None, Some(&m))
            .unwrap();
        assert_eq!(s.info.iterations, 1);
        assert!(s.info.rel_residual <= 1e-10);
        assert!(rel_diff(&s.x, &lu_solve(&k, &b)) <= 1e-10);
    }
}

#[test]
fn a_preconditioner_that_changes_every_call_still_converges() {
    // Jacobi sweeps, 1 to 4 of them in turn, on convection–diffusion.
    let a = to_dense(&convection_diffusion(10, 10.0));
    let n = a.nrows();
    let b: Vec<f64> = (0..n).map(|i| 1.0 + (i % 7) as f64).collect();
    let truth = lu_solve(&a, &b);
    let plain = Gmres::default().solve((&a).into(), &b, None, None).unwrap();
    let m = VaryingJacobi {
        a: a.clone(),
        calls: AtomicUsize::new(0),
    };
    let s = Gmres::default()
        .solve((&a).into(), &b, None, Some(&m))
        .unwrap();
    println!(
        "varying Jacobi: {} iterations (none: {})",
        s.info.iterations, plain.info.iterations
    );
    assert!(s.info.rel_residual <= 1e-10);
    assert!(rel_diff(&s.x, &truth) <= 1e-8);
    assert!(s.info.iterations < plain.info.iterations);

    // An inner GMRES of 2 to 6 steps, on the saddle point; with restarts too.
    let p = saddle_point(6, 40, 4);
    let n = p.k.nrows();
    let b: Vec<f64> = (0..n).map(|i| (i as f64).cos()).collect();
    let truth = lu_solve(&p.k, &b);
    // Plain GMRES(4) crawls on this indefinite system (1.5e-6 after 1000 steps); the inner
    // iteration is what makes a restart of 4 work.
    let plain4 = Gmres::default()
        .with_restart(4)
        .solve((&p.k).into(), &b, None, None);
    assert!(matches!(plain4, Err(SolveError::NoConvergence { .. })));
    for restart in [50, 4] {
        let m = InnerGmres {
            a: p.k.clone(),
            calls: AtomicUsize::new(0),
        };
        let s = Gmres::default()
            .with_restart(restart)
            .solve((&p.k).into(), &b, None, Some(&m))
            .unwrap();
        println!(
            "inner GMRES, restart {restart}: {} outer iterations",
            s.info.iterations
        );
        assert!(s.info.rel_residual <= 1e-10);
        assert!(rel_diff(&s.x, &truth) <= 1e-8);
    }
}

#[test]
fn d_distinct_eigenvalues_end_in_a_lucky_breakdown_after_d_steps() {
    let n = 30;
    let d: Vec<f64> = (0..n).map(|i| [1.0, 2.5, -4.0][i % 3]).collect();
    let a = Mat::from_fn(n, n, |i, j| if i == j { d[i] } else { 0.0 });
    let b: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
    let s = Gmres::default().solve((&a).into(), &b, None, None).unwrap();
    assert_eq!(s.info.iterations, 3);
    for i in 0..n {
        assert!((s.x[i] - b[i] / d[i]).abs() <= 1e-13 * (b[i] / d[i]).abs());
    }
}

#[test]
fn the_cyclic_shift_needs_all_n_steps_and_stagnates_when_restarted() {
    // A e_i = e_{i+1 mod n}, b = e_1, x = e_n: every Krylov space short of n is orthogonal to
    // the residual, so GMRES makes no progress before step n (the classic worst case).
    let n = 10;
    let a = Mat::from_fn(n, n, |i, j| if i == (j + 1) % n { 1.0 } else { 0.0 });
    let mut b = vec![0.0; n];
    b[0] = 1.0;
    let full = Gmres::default().solve((&a).into(), &b, None, None).unwrap();
    assert_eq!(full.info.iterations, n);
    assert!((full.x[n - 1] - 1.0).abs() < 1e-14);
    match Gmres::default()
        .with_restart(5)
        .solve((&a).into(), &b, None, None)
    {
        Err(SolveError::NoConvergence {
            iterations,
            rel_residual,
            x,
            ..
        }) => {
            // One cycle without progress ends the solve, with the (zero) start.
            assert_eq!(iterations, 5);
            assert!((rel_residual - 1.0).abs() < 1e-14);
            assert!(x.iter().all(|&v| v == 0.0));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_warm_start_at_the_solution_takes_no_steps() {
    let a = to_dense(&convection_diffusion(6, 5.0));
    let b: Vec<f64> = (0..a.nrows()).map(|i| i as f64 - 10.0).collect();
    let x = lu_solve(&a, &b);
    let s = Gmres::default()
        .solve((&a).into(), &b, Some(&x), None)
        .unwrap();
    assert_eq!(s.info.iterations, 0);
    assert_eq!(s.x, x);
    // A warm start near it takes fewer steps than a cold one.
    let near: Vec<f64> = x.iter().map(|v| v * (1.0 + 1e-6)).collect();
    let warm = Gmres::default()
        .solve((&a).into(), &b, Some(&near), None)
        .unwrap();
    let cold = Gmres::default().solve((&a).into(), &b, None, None).unwrap();
    assert!(warm.info.iterations < cold.info.iterations);
    assert!(warm.info.rel_residual <= 1e-10);
}

// ---------------------------------------------------------------------------------------------
// Limits, cancellation, determinism

#[test]
fn two_iterations_are_not_enough_and_the_error_says_so() {
    let a = to_dense(&convection_diffusion(10, 20.0));
    let n = a.nrows();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let b = random_vec(&mut rng, n);
    match Gmres::default()
        .with_max_iterations(2)
        .solve((&a).into(), &b, None, None)
    {
        Err(SolveError::NoConvergence {
            iterations,
            rel_residual,
            rel_normal_residual,
            x,
        }) => {
            assert_eq!(iterations, 2);
            assert_eq!(x.len(), n);
            let measured = measured_residual(&a, &x, &b);
            assert!(
                (rel_residual - measured).abs() <= 1e-12,
                "{rel_residual} vs {measured}"
            );
            assert!(rel_residual < 1.0 && rel_residual > 1e-10);
            assert!(rel_normal_residual.is_finite() && rel_normal_residual > 0.0);
        }
        other => panic!("{other:?}"),
    }
    // With no steps at all, the start comes back.
    match Gmres::default()
        .with_max_iterations(0)
        .solve((&a).into(), &b, None, None)
    {
        Err(SolveError::NoConvergence {
            iterations: 0, x, ..
        }) => {
            assert!(x.iter().all(|&v| v == 0.0))
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn without_the_normal_residual_a_failure_costs_no_extra_products() {
    // An operator that counts its products (both ways).
    struct Counted<'a>(&'a Mat<f64>, AtomicUsize);
    impl LinearOperator for Counted<'_> {
        fn nrows(&self) -> usize {
            self.0.nrows()
        }
        fn ncols(&self) -> usize {
            self.0.ncols()
        }
        fn apply(&self, x: &[f64], y: &mut [f64]) {
            self.1.fetch_add(1, Ordering::Relaxed);
            LsqMatrix::from(self.0).apply(x, y);
        }
        fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
            self.1.fetch_add(1, Ordering::Relaxed);
            LsqMatrix::from(self.0).apply_transpose(y, x);
        }
    }
    let a = to_dense(&convection_diffusion(10, 20.0));
    let b = vec![1.0; a.nrows()];
    let run = |measure: bool| {
        let op = Counted(&a, Default::default());
        let result = Gmres::default()
            .with_max_iterations(3)
            .with_normal_residual(measure)
            .solve(LsqMatrix::Operator(&op), &b, None, None);
        let Err(SolveError::NoConvergence {
            rel_residual,
            rel_normal_residual,
            x,
            ..
        }) = result
        else {
            panic!("{result:?}")
        };
        let products = op.1.load(Ordering::Relaxed);
        (rel_residual, rel_normal_residual, x, products)
    };
    let (r1, n1, x1, p1) = run(true);
    let (r0, n0, x0, p0) = run(false);
    assert_eq!((x0, r0), (x1, r1));
    assert!(n1.is_finite() && n0.is_nan());
    // The norm estimate's 60 products and the residual's two are not paid.
    assert!(p0 + 60 <= p1, "{p0} vs {p1}");
    let message = SolveError::NoConvergence {
        iterations: 3,
        rel_residual: r0,
        rel_normal_residual: n0,
        x: Vec::new(),
    }
    .to_string();
    assert!(!message.contains("normal-equation"), "{message}");
}

#[test]
fn the_monitor_sees_every_step_and_can_cancel() {
    let a = to_dense(&convection_diffusion(8, 10.0));
    let b = vec![1.0; a.nrows()];
    let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let log = seen.clone();
    let monitor = Monitor::new(move |p| {
        log.lock().unwrap().push((p.iteration, p.rel_residual));
        if p.iteration >= 3 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    let r = Gmres::default()
        .with_monitor(monitor)
        .solve((&a).into(), &b, None, None);
    assert_eq!(r, Err(SolveError::Cancelled { iterations: 3 }));
    let seen = seen.lock().unwrap();
    assert_eq!(seen.iter().map(|s| s.0).collect::<Vec<_>>(), vec![1, 2, 3]);
    // GMRES minimises the residual: the estimates never increase.
    assert!(seen.windows(2).all(|w| w[1].1 <= w[0].1));
}

#[test]
fn zero_rhs_gives_zero_at_once() {
    let a = to_dense(&convection_diffusion(5, 1.0));
    let n = a.nrows();
    let x0 = vec![3.0; n];
    let s = Gmres::default()
        .solve((&a).into(), &vec![0.0; n], Some(&x0), None)
        .unwrap();
    assert_eq!(s.x, vec![0.0; n]);
    assert_eq!(s.info.iterations, 0);
    assert_eq!(s.info.rel_residual, 0.0);
}

#[test]
fn same_bits_for_one_thread_and_many() {
    // n = 4900 > kernels::BLOCK, so the reductions run blocked in parallel.
    let a = convection_diffusion(70, 30.0);
    let n = a.nrows();
    let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect();
    let m = Diagonal::new(&vec![4.0; n]);
    let solve = || match Gmres::default()
        .with_restart(15)
        .with_max_iterations(40)
        .solve((&a).into(), &b, None, Some(&m))
    {
        Err(SolveError::NoConvergence { x, .. }) => x,
        other => panic!("{other:?}"),
    };
    let pool = |t| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
    };
    let one = pool(1).install(solve);
    let four = pool(4).install(solve);
    assert!(
        one.iter()
            .zip(&four)
            .all(|(p, q)| p.to_bits() == q.to_bits())
    );
}

// ---------------------------------------------------------------------------------------------
// Input errors

#[test]
fn bad_input_gets_a_specific_error() {
    let solver = Gmres::default();
    let rect = Mat::from_fn(3, 4, |i, j| (i + j) as f64);
    assert!(matches!(
        solver.solve((&rect).into(), &[1.0; 3], None, None),
        Err(SolveError::ShapeMismatch {
            expected: 3,
            got: 4,
            ..
        })
    ));
    let op = DenseOperator(rect);
    assert!(matches!(
        solver.solve(LsqMatrix::Operator(&op), &[1.0; 3], None, None),
        Err(SolveError::ShapeMismatch { .. })
    ));

    let a = to_dense(&convection_diffusion(3, 1.0));
    let mut b = vec![1.0; 9];
    b[2] = f64::NAN;
    assert!(matches!(
        solver.solve((&a).into(), &b, None, None),
        Err(SolveError::NonFinite {
            what: "right-hand side",
            index: 2,
            ..
        })
    ));
    assert!(matches!(
        solver.solve((&a).into(), &[1.0; 8], None, None),
        Err(SolveError::ShapeMismatch {
            expected: 9,
            got: 8,
            ..
        })
    ));
    assert!(matches!(
        solver.solve((&a).into(), &[1.0; 9], Some(&[0.0; 8]), None),
        Err(SolveError::ShapeMismatch {
            what: "initial guess x0",
            ..
        })
    ));
    let mut x0 = vec![0.0; 9];
    x0[4] = f64::INFINITY;
    assert!(matches!(
        solver.solve((&a).into(), &[1.0; 9], Some(&x0), None),
        Err(SolveError::NonFinite {
            what: "initial guess",
            index: 4,
            ..
        })
    ));
    let small = Diagonal::new(&[1.0; 5]);
    assert!(matches!(
        solver.solve((&a).into(), &[1.0; 9], None, Some(&small)),
        Err(SolveError::ShapeMismatch {
            what: "preconditioner",
            expected: 9,
            got: 5,
        })
    ));
    let mut bad = a.clone();
    bad[(1, 1)] = f64::NAN;
    assert!(matches!(
        solver.solve((&bad).into(), &[1.0; 9], None, None),
        Err(SolveError::NonFinite { what: "matrix", .. })
    ));
}
