//! Dense direct solvers: Householder QR with column pivoting, and LU on the normal equations.
//!
//! **QR.** `A P = Q R` with `Q` orthogonal, `R` upper triangular and `P` the column pivoting
//! (Businger–Golub) that puts the largest remaining column first, so `|r₀₀| ≥ |r₁₁| ≥ …`.
//! Then `x = P R⁻¹ (Qᵀb)[..n]`. It is backward stable: the error grows like `cond(A)·ε`.
//! A column is dependent when `|r_kk| ≤ τ·|r₀₀|`, default `τ = 1000·max(m, n)·ε` (the LAPACK
//! `xGELSY` rule with a margin for rounding in the factorisation); the error names the
//! original column `P[k]`.
//!
//! **LU on the normal equations.** `AᵀA x = Aᵀb` by LU with partial pivoting. It costs
//! `mn² + n³/3` flops against QR's `2mn² − 2n³/3`, but squares the condition number, so it
//! loses twice the digits — the textbook trade (Björck §2.2). A pivot `|u_kk| ≤ τ·(AᵀA)_kk`,
//! default `τ = 1e-12`, reports column `k` (partial pivoting permutes rows only, so columns
//! keep their numbering). Relative to the column's own squared norm, the test is invariant
//! under column scaling; it flags `cond(A) ≳ 10⁶`, where the normal equations keep no more
//! than four digits.
//!
//! Both densify a sparse `A` (fine up to a few thousand columns); neither takes an operator.
//! Both run faer's kernels sequentially ([`crate::sequential`]): their parallel versions split
//! sums by the thread count, so that an answer would change in its last bits with `--threads`.

use std::time::Instant;

use faer::{Mat, MatRef};
use zeroset_field_core::lsq::{LeastSquaresSolver, LsqMatrix, Solution, SolveError, Stage};

use crate::common::{DirectParams, NORMAL_RANK_TOLERANCE, finish, prepare, rank_tolerance, stage};
use crate::operator::Prepared;
use crate::sequential;

fn dense_input<'p>(
    solver: &'static str,
    a: &'p Prepared<'_>,
) -> Result<std::borrow::Cow<'p, Mat<f64>>, SolveError> {
    a.require_direct(solver)?;
    Ok(a.to_dense().expect("require_direct refused operators"))
}

fn column(b: &[f64]) -> Mat<f64> {
    Mat::from_fn(b.len(), 1, |i, _| b[i])
}

/// Householder QR with column pivoting (faer's `ColPivQr`).
#[derive(Clone, Debug, Default)]
pub struct DenseQr {
    /// Rank tolerance `τ` (default `1000·max(m, n)·ε`) and monitor.
    pub params: DirectParams,
}

impl DenseQr {
    /// Dense QR with the given parameters.
    pub fn new(params: DirectParams) -> Self {
        Self { params }
    }
}

impl LeastSquaresSolver for DenseQr {
    fn name(&self) -> &'static str {
        "dense-qr"
    }

    fn solve(&self, a: LsqMatrix<'_>, b: &[f64]) -> Result<Solution, SolveError> {
        let start = Instant::now();
        let name = self.name();
        let prepared = prepare(a, b)?;
        let (m, n) = prepared.shape();
        let dense = dense_input(name, &prepared)?;
        stage(&self.params.monitor, name, Stage::Factorize, 0)?;
        let qr = sequential::ColPivQr::new(dense.as_ref().as_ref());
        let r: MatRef<'_, f64> = qr.r();
        let perm_fwd = qr.permutation();
        if n > 0 {
            let tau = rank_tolerance(
                self.params.rank_tolerance,
                1000.0 * m.max(n) as f64 * f64::EPSILON,
            )?;
            let threshold = tau * r[(0, 0)].abs();
            for k in 0..n {
                let pivot = r[(k, k)].abs();
                if pivot <= threshold || !pivot.is_finite() {
                    return Err(SolveError::RankDeficient {
                        column: perm_fwd[k],
                        pivot,
                        threshold,
                    });
                }
            }
        }
        stage(&self.params.monitor, name, Stage::Solve, 1)?;
        let x = qr.solve_lstsq(b);
        finish(name, &prepared, x, b, 0, start, vec![])
    }
}

/// LU with partial pivoting on `AᵀA x = Aᵀb` (faer's `PartialPivLu`).
#[derive(Clone, Debug, Default)]
pub struct NormalLu {
    /// Rank tolerance `τ` (default `1e-12`) and monitor.
    pub params: DirectParams,
}

impl NormalLu {
    /// LU on the normal equations with the given parameters.
    pub fn new(params: DirectParams) -> Self {
        Self { params }
    }
}

impl LeastSquaresSolver for NormalLu {
    fn name(&self) -> &'static str {
        "normal-lu"
    }

    fn solve(&self, a: LsqMatrix<'_>, b: &[f64]) -> Result<Solution, SolveError> {
        let start = Instant::now();
        let name = self.name();
        let prepared = prepare(a, b)?;
        let (_, n) = prepared.shape();
        let dense = dense_input(name, &prepared)?;
        stage(&self.params.monitor, name, Stage::Factorize, 0)?;
        let at = dense.transpose();
        let normal = sequential::product(at, dense.as_ref().as_ref());
        let mut rhs = sequential::product(at, column(b).as_ref());
        let lu = sequential::PartialPivLu::new(normal.as_ref());
        let u = lu.u();
        let tau = rank_tolerance(self.params.rank_tolerance, NORMAL_RANK_TOLERANCE)?;
        for k in 0..n {
            let pivot = u[(k, k)].abs();
            let threshold = tau * normal[(k, k)];
            if pivot <= threshold || !pivot.is_finite() {
                return Err(SolveError::RankDeficient {
                    column: k,
                    pivot,
                    threshold,
                });
            }
        }
        stage(&self.params.monitor, name, Stage::Solve, 1)?;
        lu.solve_in_place(rhs.as_mut());
        let x: Vec<f64> = (0..n).map(|i| rhs[(i, 0)]).collect();
        finish(name, &prepared, x, b, 0, start, vec![])
    }
}
