//! The agreement suite: every solver, the same properties.
//!
//! Truth comes from construction, not from another solver: a manufactured least-squares problem
//! `b = A x* + r` with `Aᵀr = 0` exactly (two rows of `A` are negatives of each other and `r`
//! lives on those two rows with equal entries), so `x*` is *the* minimiser and the residual is
//! not zero. Each solver module below runs the same tests through one macro.

use std::ops::ControlFlow;
use std::sync::Arc;

use faer::Mat;
use faer::sparse::{SparseColMat, Triplet};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zeroset_field_core::basis::{PolynomialBasis, fit_values};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::lsq::{LeastSquaresSolver, LinearOperator, LsqMatrix, Monitor, SolveError};
use zeroset_solvers::problems::protrusion_problem;
use zeroset_solvers::*;

/// A manufactured problem: `A` (sparse, full column rank), `b`, the exact minimiser `x*`.
struct Manufactured {
    a: SparseColMat<usize, f64>,
    b: Vec<f64>,
    x: Vec<f64>,
}

/// `n` columns, `m ≥ n + 2` rows. The top `n × n` block is diagonally dominant (full rank); the
/// other rows are sparse random; rows `m−2` and `m−1` are negatives of each other and carry the
/// residual `ρ(e_{m−2} + e_{m−1})`, which `Aᵀ` annihilates.
fn manufactured(seed: u64, n: usize, extra: usize, density: f64) -> Manufactured {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let m = n + extra + 2;
    let mut dense = vec![vec![0.0; n]; m];
    for (i, row) in dense.iter_mut().enumerate().take(m - 1) {
        for (j, v) in row.iter_mut().enumerate() {
            if i == j {
                *v = 2.0 * n as f64 * density + 1.0 + rng.random::<f64>();
            } else if rng.random::<f64>() < density {
                *v = rng.random::<f64>() * 2.0 - 1.0;
            }
        }
    }
    dense[m - 1] = dense[m - 2].iter().map(|v| -v).collect();
    let x: Vec<f64> = (0..n).map(|_| rng.random::<f64>() * 4.0 - 2.0).collect();
    // |ρ| in [0.1, 1]: a residual near zero (ρ = 1.7e-7 for the seed in
    // agreement.proptest-regressions) leaves ‖r‖ at the level of the rounding in b − A x, where
    // the relative normal residual ‖Aᵀr‖/(‖A‖‖r‖) measures noise, not the solver.
    let u = rng.random::<f64>() * 2.0 - 1.0;
    let rho = u.signum() * (0.1 + 0.9 * u.abs());
    let mut b: Vec<f64> = dense
        .iter()
        .map(|row| row.iter().zip(&x).map(|(a, x)| a * x).sum())
        .collect();
    b[m - 2] += rho;
    b[m - 1] += rho;
    let triplets: Vec<_> = dense
        .iter()
        .enumerate()
        .flat_map(|(i, row)| {
            row.iter()
                .enumerate()
                .filter(|(_, v)| **v != 0.0)
                .map(move |(j, &v)| Triplet::new(i, j, v))
        })
        .collect();
    let a = SparseColMat::try_new_from_triplets(m, n, &triplets).unwrap();
    Manufactured { a, b, x }
}

fn max_rel_error(x: &[f64], truth: &[f64]) -> f64 {
    let scale = truth.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    x.iter()
        .zip(truth)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale
}

/// A reference for the restoration problem: sparse QR (backward stable, never forms AᵀA).
fn restoration_reference(k: usize) -> Vec<f64> {
    let p = protrusion_problem(k, 1.0);
    SparseQr::default()
        .solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b)
        .unwrap()
        .x
}

fn tight() -> IterativeParams {
    IterativeParams::default().with_tolerance(1e-12)
}

/// A wrapper that exposes only `A x` and `Aᵀ y`.
struct OperatorOnly<'a>(LsqMatrix<'a>);
impl LinearOperator for OperatorOnly<'_> {
    fn nrows(&self) -> usize {
        self.0.shape().0
    }
    fn ncols(&self) -> usize {
        self.0.shape().1
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.0.apply(x, y)
    }
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
        self.0.apply_transpose(y, x)
    }
}

macro_rules! agreement_suite {
    ($($name:ident: $make:expr, iterative = $iterative:expr;)*) => {$(
        mod $name {
            use super::*;

            fn solver() -> Box<dyn LeastSquaresSolver> {
                Box::new($make)
            }

            proptest! {
                #![proptest_config(ProptestConfig::with_cases(200))]

                /// The solver returns the manufactured minimiser.
                #[test]
                fn random_full_rank_problems_give_the_exact_minimiser(
                    seed in any::<u64>(), n in 1usize..12, extra in 0usize..20, density in 0.05f64..0.6,
                ) {
                    let p = manufactured(seed, n, extra, density);
                    let s = solver().solve(LsqMatrix::SparseCol(p.a.as_ref()), &p.b).unwrap();
                    let err = max_rel_error(&s.x, &p.x);
                    prop_assert!(err < 1e-8, "error {err:e} for n={n}, m={}", p.b.len());
                    prop_assert!(s.info.rel_normal_residual < 1e-8);
                }

                /// Dense, column-compressed and row-compressed views of the same matrix agree.
                #[test]
                fn every_matrix_layout_gives_the_same_answer(seed in any::<u64>(), n in 1usize..8) {
                    let p = manufactured(seed, n, 5, 0.3);
                    let dense: Mat<f64> = p.a.to_dense();
                    let csr = p.a.to_row_major().unwrap();
                    let s = solver();
                    let xs = [
                        s.solve(LsqMatrix::SparseCol(p.a.as_ref()), &p.b).unwrap().x,
                        s.solve(LsqMatrix::Dense(dense.as_ref()), &p.b).unwrap().x,
                        s.solve(LsqMatrix::SparseRow(csr.as_ref()), &p.b).unwrap().x,
                    ];
                    for x in &xs[1..] {
                        prop_assert!(max_rel_error(x, &xs[0]) < 1e-9);
                    }
                }
            }

            #[test]
            fn restoration_problem_agrees_with_sparse_qr() {
                for k in [3, 6] {
                    let p = protrusion_problem(k, 1.0);
                    let s = solver().solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b).unwrap();
                    let err = max_rel_error(&s.x, &restoration_reference(k));
                    assert!(err < 1e-9, "k={k}: {err:e}");
                    assert!(s.info.rel_residual > 1e-3, "the problem is inconsistent");
                }
            }

            #[test]
            fn rank_deficiency_is_named_or_gives_a_least_squares_solution() {
                // Column 3 = column 0 + column 1.
                let mut p = manufactured(7, 6, 8, 0.4);
                let mut dense: Mat<f64> = p.a.to_dense();
                for i in 0..dense.nrows() {
                    dense[(i, 3)] = dense[(i, 0)] + dense[(i, 1)];
                }
                p.b.iter_mut().enumerate().for_each(|(i, v)| *v += 0.1 * i as f64);
                match solver().solve(LsqMatrix::Dense(dense.as_ref()), &p.b) {
                    Err(SolveError::RankDeficient { column, pivot, threshold }) => {
                        assert!(!$iterative, "iterative solvers do not detect rank");
                        assert!([0, 1, 3].contains(&column), "column {column} is not in the dependent set");
                        assert!(pivot <= threshold);
                        let msg = SolveError::RankDeficient { column, pivot, threshold }.to_string();
                        assert!(msg.contains(&format!("column {column}")), "{msg}");
                    }
                    Ok(s) => {
                        assert!($iterative, "a direct solver must report rank deficiency");
                        assert!(s.info.rel_normal_residual < 1e-8, "{:?}", s.info);
                        // From a zero start: the minimum-norm solution, orthogonal to the null
                        // vector e0 + e1 − e3.
                        let along = s.x[0] + s.x[1] - s.x[3];
                        assert!(along.abs() < 1e-6 * (1.0 + s.x.iter().map(|v| v.abs()).fold(0.0, f64::max)), "{along}");
                    }
                    Err(e) => panic!("unexpected error {e}"),
                }
                // An all-zero column is named exactly.
                let mut zero_col = p.a.to_dense();
                for i in 0..zero_col.nrows() {
                    zero_col[(i, 4)] = 0.0;
                }
                if let Err(e) = solver().solve(LsqMatrix::Dense(zero_col.as_ref()), &p.b) {
                    assert!(matches!(e, SolveError::RankDeficient { column: 4, .. }), "{e}");
                } else {
                    assert!($iterative);
                }
            }

            #[test]
            fn bad_inputs_are_specific_errors() {
                let p = manufactured(3, 4, 3, 0.5);
                let a = LsqMatrix::SparseCol(p.a.as_ref());
                let s = solver();
                assert!(matches!(
                    s.solve(a, &p.b[1..]),
                    Err(SolveError::ShapeMismatch { expected: 9, got: 8, .. })
                ));
                let mut b = p.b.clone();
                b[2] = f64::NAN;
                assert!(matches!(
                    s.solve(a, &b),
                    Err(SolveError::NonFinite { what: "right-hand side", index: 2, .. })
                ));
                let mut dense = p.a.to_dense();
                dense[(1, 1)] = f64::INFINITY;
                assert!(matches!(
                    s.solve(LsqMatrix::Dense(dense.as_ref()), &p.b),
                    Err(SolveError::NonFinite { what: "matrix", .. })
                ));
            }

            #[test]
            fn operators_are_solved_or_refused_clearly() {
                let p = manufactured(11, 5, 6, 0.4);
                let op = OperatorOnly(LsqMatrix::SparseCol(p.a.as_ref()));
                match solver().solve(LsqMatrix::Operator(&op), &p.b) {
                    Ok(s) => {
                        assert!($iterative);
                        assert!(max_rel_error(&s.x, &p.x) < 1e-8);
                    }
                    Err(SolveError::Unsupported { reason, .. }) => {
                        assert!(!$iterative);
                        assert!(reason.contains("operator"), "{reason}");
                    }
                    Err(e) => panic!("unexpected {e}"),
                }
            }

            #[test]
            fn one_thread_and_many_give_the_same_bits() {
                // 512 unknowns: faer's parallel QR and LU kernels split their sums by the
                // thread count from this size on (216 did not show it).
                let p = protrusion_problem(8, 1.0);
                let run = || solver().solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b).unwrap().x;
                let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
                let one = pool(1).install(run);
                let many = pool(3).install(run);
                assert!(many.iter().zip(&one).all(|(a, b)| a.to_bits() == b.to_bits()));
                // A scattered pattern: the protrusion problem's banded one gives faer's sparse
                // Cholesky no supernodes to split among threads.
                let q = manufactured(7, 600, 2400, 0.01);
                let run = || solver().solve(LsqMatrix::SparseCol(q.a.as_ref()), &q.b).unwrap().x;
                let one = pool(1).install(run);
                let many = pool(3).install(run);
                assert!(many.iter().zip(&one).all(|(a, b)| a.to_bits() == b.to_bits()));
            }

            #[test]
            fn a_polynomial_is_fitted_exactly_through_the_basis_trait() {
                let bounds = Aabb::new([-1.0, 0.0, 2.0], [1.0, 3.0, 4.0]).unwrap();
                let basis = PolynomialBasis::<3>::new(bounds, 2);
                let truth = |p: &[f64; 3]| 1.0 - 2.0 * p[0] + p[1] * p[2] - 0.5 * p[2] * p[2];
                let points: Vec<[f64; 3]> = (0..60)
                    .map(|i| {
                        let t = i as f64;
                        [(t * 0.37).sin(), 1.5 + 1.5 * (t * 0.71).cos(), 3.0 + (t * 0.13).sin()]
                    })
                    .collect();
                let values: Vec<f64> = points.iter().map(truth).collect();
                let (field, _) = fit_values(basis, &points, &values, solver().as_ref()).unwrap();
                for p in [[0.2, 1.0, 2.5], [-0.7, 2.9, 3.9]] {
                    assert!((field.value(&p) - truth(&p)).abs() < 1e-8);
                }
            }

            #[test]
            fn a_monitor_can_cancel() {
                let p = protrusion_problem(4, 1.0);
                let monitor = Monitor::new(|_| ControlFlow::Break(()));
                let s = with_monitor(solver_with_monitor_slot(), monitor);
                assert!(matches!(
                    s.solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b),
                    Err(SolveError::Cancelled { .. })
                ));
            }

            /// The same solver type with default settings, as a concrete value to configure.
            fn solver_with_monitor_slot() -> Box<dyn std::any::Any> {
                Box::new($make)
            }
        }
    )*};
}

/// Sets the monitor on whichever solver type this is.
fn with_monitor(solver: Box<dyn std::any::Any>, m: Monitor) -> Box<dyn LeastSquaresSolver> {
    let solver = match solver.downcast::<Cgls>() {
        Ok(mut s) => {
            s.params.monitor = Some(m);
            return s;
        }
        Err(s) => s,
    };
    let solver = match solver.downcast::<Lsqr>() {
        Ok(mut s) => {
            s.params.monitor = Some(m);
            return s;
        }
        Err(s) => s,
    };
    let solver = match solver.downcast::<Pcg>() {
        Ok(mut s) => {
            s.params.monitor = Some(m);
            return s;
        }
        Err(s) => s,
    };
    let solver = match solver.downcast::<DenseQr>() {
        Ok(mut s) => {
            s.params.monitor = Some(m);
            return s;
        }
        Err(s) => s,
    };
    let solver = match solver.downcast::<NormalLu>() {
        Ok(mut s) => {
            s.params.monitor = Some(m);
            return s;
        }
        Err(s) => s,
    };
    let solver = match solver.downcast::<SparseQr>() {
        Ok(mut s) => {
            s.params.monitor = Some(m);
            return s;
        }
        Err(s) => s,
    };
    match solver.downcast::<SparseCholesky>() {
        Ok(mut s) => {
            s.params.monitor = Some(m);
            s
        }
        Err(_) => panic!("unknown solver type"),
    }
}

agreement_suite! {
    cgls: Cgls::new(tight()), iterative = true;
    lsqr: Lsqr::new(tight()), iterative = true;
    pcg: Pcg::new(PcgParams { tol: 1e-13, ..Default::default() }), iterative = true;
    dense_qr: DenseQr::default(), iterative = false;
    normal_lu: NormalLu::default(), iterative = false;
    sparse_qr: SparseQr::default(), iterative = false;
    sparse_cholesky: SparseCholesky::default(), iterative = false;
}

#[test]
fn iterative_solvers_that_run_out_of_iterations_say_how_far_they_got() {
    let p = protrusion_problem(6, 1.0);
    let a = LsqMatrix::SparseRow(p.a.as_ref());
    let limited: Vec<Box<dyn LeastSquaresSolver>> = vec![
        Box::new(Cgls::new(tight().with_max_iterations(3))),
        Box::new(Lsqr::new(tight().with_max_iterations(3))),
        Box::new(Pcg::new(PcgParams {
            max_iterations: Some(3),
            ..Default::default()
        })),
    ];
    for s in limited {
        match s.solve(a, &p.b) {
            Err(e) => {
                assert!(e.to_string().contains("after 3 iterations"), "{e}");
                let SolveError::NoConvergence {
                    iterations,
                    rel_residual,
                    rel_normal_residual,
                    x,
                } = e
                else {
                    panic!("{}: expected NoConvergence", s.name())
                };
                assert_eq!(iterations, 3);
                assert!(
                    rel_residual > 0.0 && rel_normal_residual > 1e-6,
                    "{}",
                    s.name()
                );
                assert_eq!(x.len(), p.a.ncols());
            }
            other => panic!("{}: expected NoConvergence, got {other:?}", s.name()),
        }
    }
}

/// An operator that returns NaN in its first output entry.
struct Poisoned;
impl LinearOperator for Poisoned {
    fn nrows(&self) -> usize {
        4
    }
    fn ncols(&self) -> usize {
        3
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().enumerate().for_each(|(i, v)| *v = x[i % 3]);
        y[0] = f64::NAN;
    }
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
        x.fill(0.0);
        y.iter().enumerate().for_each(|(i, v)| x[i % 3] += v);
    }
}

#[test]
fn an_operator_that_returns_nan_is_an_error_not_a_solution() {
    let b = [1.0; 4];
    let solvers: Vec<Box<dyn LeastSquaresSolver>> = vec![
        Box::new(Cgls::default()),
        Box::new(Lsqr::default()),
        Box::new(Pcg::default()),
    ];
    for s in solvers {
        match s.solve(LsqMatrix::Operator(&Poisoned), &b) {
            Err(SolveError::NonFinite { what, .. }) => {
                assert!(what.contains("operator"), "{}: {what}", s.name());
            }
            other => panic!("{}: expected NonFinite, got {other:?}", s.name()),
        }
    }
}

#[test]
fn poisson_preconditioned_lsqr_agrees_in_a_fraction_of_the_iterations() {
    let k = 8;
    let p = protrusion_problem(k, 1.0);
    let a = LsqMatrix::SparseRow(p.a.as_ref());
    let plain = Lsqr::new(tight()).solve(a, &p.b).unwrap();
    let m = Arc::new(DirichletLaplacian::new([k, k, k], 1.0 / 6.0).unwrap());
    let pre = Lsqr::new(tight().with_preconditioner(m.clone()))
        .solve(a, &p.b)
        .unwrap();
    let cg = Cgls::new(tight().with_preconditioner(m))
        .solve(a, &p.b)
        .unwrap();
    let truth = restoration_reference(k);
    assert!(max_rel_error(&pre.x, &truth) < 1e-9);
    assert!(max_rel_error(&cg.x, &truth) < 1e-9);
    assert!(
        pre.info.iterations * 3 < plain.info.iterations,
        "{} vs {}",
        pre.info.iterations,
        plain.info.iterations
    );
    // Column scaling is a valid (if weak here) preconditioner too.
    let d = Arc::new(Diagonal::column_scaling(a).unwrap());
    let scaled = Lsqr::new(tight().with_preconditioner(d))
        .solve(a, &p.b)
        .unwrap();
    assert!(max_rel_error(&scaled.x, &truth) < 1e-9);
    // A preconditioner of the wrong size is refused.
    let wrong = Arc::new(DirichletLaplacian::new([k, k, k + 1], 1.0).unwrap());
    assert!(matches!(
        Lsqr::new(tight().with_preconditioner(wrong)).solve(a, &p.b),
        Err(SolveError::ShapeMismatch {
            what: "preconditioner",
            ..
        })
    ));
}

#[test]
fn sparse_cholesky_reuses_its_analysis_when_only_values_change() {
    let s = SparseCholesky::default();
    let p1 = protrusion_problem(5, 1.0);
    let p2 = protrusion_problem(5, 3.0); // same pattern, new right-hand side
    let first = s.solve(LsqMatrix::SparseRow(p1.a.as_ref()), &p1.b).unwrap();
    assert_eq!(first.info.detail("analysis_reused"), Some(0.0));
    let mut scaled = p2.a.clone();
    scaled.val_mut().iter_mut().for_each(|v| *v *= 2.0);
    let second = s
        .solve(LsqMatrix::SparseRow(scaled.as_ref()), &p2.b)
        .unwrap();
    assert_eq!(second.info.detail("analysis_reused"), Some(1.0));
    let fresh = SparseQr::default()
        .solve(LsqMatrix::SparseRow(scaled.as_ref()), &p2.b)
        .unwrap();
    assert!(max_rel_error(&second.x, &fresh.x) < 1e-10);
    // A different pattern is analysed afresh.
    let p3 = protrusion_problem(4, 1.0);
    let third = s.solve(LsqMatrix::SparseRow(p3.a.as_ref()), &p3.b).unwrap();
    assert_eq!(third.info.detail("analysis_reused"), Some(0.0));
    // And an analysis can be made up front and handed over.
    let analysis =
        Arc::new(NormalAnalysis::new(LsqMatrix::SparseRow(p1.a.as_ref()), Ordering::Amd).unwrap());
    let handed = SparseCholesky::with_analysis(SparseCholeskyParams::default(), analysis);
    let r = handed
        .solve(LsqMatrix::SparseRow(p1.a.as_ref()), &p1.b)
        .unwrap();
    assert_eq!(r.info.detail("analysis_reused"), Some(1.0));
}

#[test]
fn pcg_solves_spd_systems_and_rejects_indefinite_ones() {
    // K = tridiag(-1, 2, -1), SPD.
    let n = 50;
    let k = Mat::from_fn(n, n, |i, j| match i.abs_diff(j) {
        0 => 2.0,
        1 => -1.0,
        _ => 0.0,
    });
    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).cos()).collect();
    let mut f = vec![0.0; n];
    LsqMatrix::Dense(k.as_ref()).apply(&x, &mut f);
    let jacobi = Arc::new(Diagonal::jacobi(&vec![2.0; n]));
    let pcg = Pcg::new(PcgParams {
        tol: 1e-13,
        preconditioner: Some(jacobi),
        ..Default::default()
    });
    let s = pcg.solve_spd(LsqMatrix::Dense(k.as_ref()), &f).unwrap();
    assert!(max_rel_error(&s.x, &x) < 1e-10);
    let neg = Mat::from_fn(n, n, |i, j| if i == j { -1.0 } else { 0.0 });
    assert!(matches!(
        pcg.solve_spd(LsqMatrix::Dense(neg.as_ref()), &f),
        Err(SolveError::NotPositiveDefinite { index: 1, .. })
    ));
}

#[test]
fn underdetermined_systems_go_to_iterative_solvers() {
    let a = Mat::from_fn(2, 3, |i, j| (i + 2 * j) as f64 + 1.0);
    let b = [1.0, 2.0];
    for s in [
        &DenseQr::default() as &dyn LeastSquaresSolver,
        &SparseCholesky::default(),
        &SparseQr::default(),
    ] {
        assert!(matches!(
            s.solve(LsqMatrix::Dense(a.as_ref()), &b),
            Err(SolveError::Underdetermined { nrows: 2, ncols: 3 })
        ));
    }
    // LSQR finds the minimum-norm solution of the consistent system.
    let s = Lsqr::new(tight())
        .solve(LsqMatrix::Dense(a.as_ref()), &b)
        .unwrap();
    assert!(s.info.rel_residual < 1e-10);
}

#[test]
fn unsorted_sparse_columns_are_accepted_by_every_solver() {
    use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
    // The manufactured matrix with each column's entries stored in reverse order.
    let p = manufactured(5, 6, 6, 0.5);
    let (m, n) = (p.a.nrows(), p.a.ncols());
    let mut ptr = vec![0];
    let (mut rows, mut vals) = (Vec::new(), Vec::new());
    for j in 0..n {
        let col: Vec<(usize, f64)> =
            p.a.as_ref()
                .row_idx_of_col(j)
                .zip(p.a.val_of_col(j).iter().copied())
                .collect();
        for &(i, v) in col.iter().rev() {
            rows.push(i);
            vals.push(v);
        }
        ptr.push(rows.len());
    }
    let sym = SymbolicSparseColMatRef::new_unsorted_checked(m, n, &ptr, None, &rows);
    let unsorted = SparseColMatRef::new(sym, &vals);
    for s in all_solvers() {
        let x = s.solve(LsqMatrix::SparseCol(unsorted), &p.b).unwrap().x;
        assert!(max_rel_error(&x, &p.x) < 1e-8, "{}", s.name());
    }
}

/// `tol = 0` asks for machine precision: CGLS used to iterate on rounding noise once converged,
/// its iterate growing without bound (x ≈ 3·10¹⁰ on this 10 × 3 problem after 100
/// iterations), and PCG met 0/0 after an exact solve and blamed the operator.
#[test]
fn a_zero_tolerance_stops_at_machine_precision() {
    let a = Mat::from_fn(10, 3, |i, j| {
        ((i * 3 + j * 7) % 5) as f64 + if i == j { 4.0 } else { 0.5 }
    });
    let truth = [1.0, -2.0, 0.5];
    let mut b = vec![0.0; 10];
    LsqMatrix::Dense(a.as_ref()).apply(&truth, &mut b);
    b[9] += 0.25; // inconsistent
    let reference = DenseQr::default()
        .solve(LsqMatrix::Dense(a.as_ref()), &b)
        .unwrap()
        .x;
    let exact = IterativeParams::default()
        .with_tolerance(0.0)
        .with_max_iterations(100);
    for solver in [
        Box::new(Cgls::new(exact.clone())) as Box<dyn LeastSquaresSolver>,
        Box::new(Lsqr::new(exact.clone())),
        Box::new(Pcg::new(PcgParams {
            tol: 0.0,
            max_iterations: Some(100),
            ..Default::default()
        })),
    ] {
        let s = solver
            .solve(LsqMatrix::Dense(a.as_ref()), &b)
            .unwrap_or_else(|e| panic!("{}: {e}", solver.name()));
        assert!(
            max_rel_error(&s.x, &reference) < 1e-10,
            "{}: {:?}",
            solver.name(),
            s.x
        );
    }
    // A tolerance that is negative or NaN is refused, by name.
    for (tol, what) in [(-1.0, "atol"), (f64::NAN, "atol")] {
        let e = Cgls::new(IterativeParams::default().with_tolerance(tol))
            .solve(LsqMatrix::Dense(a.as_ref()), &b)
            .unwrap_err();
        assert!(
            matches!(e, SolveError::InvalidTolerance { what: w, .. } if w == what),
            "{e}"
        );
    }
    let e = Pcg::new(PcgParams {
        tol: -1e-3,
        ..Default::default()
    })
    .solve(LsqMatrix::Dense(a.as_ref()), &b)
    .unwrap_err();
    assert!(
        matches!(e, SolveError::InvalidTolerance { what: "tol", .. }),
        "{e}"
    );
    let e = DenseQr::new(DirectParams::default().with_rank_tolerance(f64::NAN))
        .solve(LsqMatrix::Dense(a.as_ref()), &b)
        .unwrap_err();
    assert!(
        matches!(
            e,
            SolveError::InvalidTolerance {
                what: "rank_tolerance",
                ..
            }
        ),
        "{e}"
    );
}

/// `[D; D]`, `D` the forward difference: `A·1 = 0`. A constant start vector made the operator's
/// norm estimate 0, and CGLS's stopping test with it never held (400 iterations, "no
/// convergence", where the same matrix passed densely converged in 199).
#[test]
fn an_operator_that_annihilates_constants_is_solved_as_its_matrix_is() {
    let n = 200;
    let a = Mat::from_fn(2 * n, n, |i, j| {
        let r = i % n;
        if r == j && r + 1 < n {
            -1.0
        } else if r + 1 == j {
            1.0
        } else {
            0.0
        }
    });
    let b: Vec<f64> = (0..2 * n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
    let dense = Cgls::default()
        .solve(LsqMatrix::Dense(a.as_ref()), &b)
        .unwrap();
    let operator = OperatorOnly(LsqMatrix::Dense(a.as_ref()));
    let matrix_free = Cgls::default()
        .solve(LsqMatrix::Operator(&operator), &b)
        .unwrap();
    assert!(max_rel_error(&matrix_free.x, &dense.x) < 1e-8);
    // The report is a ratio at most 1 (‖A‖₂ for the operator, ‖A‖_F for the matrix).
    assert!(
        matrix_free.info.rel_normal_residual < 1e-9,
        "{}",
        matrix_free.info.rel_normal_residual
    );
}
