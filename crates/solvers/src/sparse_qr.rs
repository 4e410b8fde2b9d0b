//! Sparse QR: `A P = Q R` by Householder reflections on a COLAMD-ordered `A` (faer's
//! multifrontal/supernodal QR), then `x = P R⁻¹ (Qᵀb)[..n]`.
//!
//! The simplicial (column-by-column) variant is used: it is the one whose `R` faer lays out
//! in documented compressed columns, which the rank check reads. It never forms `AᵀA`, so it
//! keeps QR's accuracy (error `∝ cond(A)`, not `cond(A)²`), at the
//! price of storing the Householder vectors. There is no rank-revealing pivoting: a dependent
//! column shows as a tiny `|r_kk|` in elimination order. The test is `|r_kk| ≤ τ·‖A e_{P[k]}‖`
//! (relative to the column's own norm, so invariant under column scaling), default
//! `τ = 1000·max(m, n)·ε`, and the error names column `P[k]`.
//!
//! The simplicial factorisation is slow on large problems: the 14,400 × 13,824 protrusion
//! system of `problems::protrusion_problem(24)` takes 15.9 s against 0.46 s for
//! [`SparseCholesky`](crate::SparseCholesky) and 0.10 s for [`Lsqr`](crate::Lsqr) (2 cores).
//! It is the accurate reference for moderately sized or ill-conditioned problems; for large
//! well-conditioned ones use those.

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::qr::{QrSymbolicParams, factorize_symbolic_qr};
use faer::{Conj, MatMut, Par};
use zeroset_field_core::lsq::{LeastSquaresSolver, LsqMatrix, Solution, SolveError, Stage};

use crate::common::{DirectParams, finish, prepare, rank_tolerance, stage};

const NAME: &str = "sparse-qr";

/// Sparse QR (faer).
#[derive(Clone, Debug, Default)]
pub struct SparseQr {
    /// Rank tolerance `τ` (default `1000·max(m, n)·ε`) and monitor.
    pub params: DirectParams,
}

impl SparseQr {
    /// Sparse QR with the given parameters.
    pub fn new(params: DirectParams) -> Self {
        Self { params }
    }
}

impl LeastSquaresSolver for SparseQr {
    fn name(&self) -> &'static str {
        NAME
    }

    fn solve(&self, a: LsqMatrix<'_>, b: &[f64]) -> Result<Solution, SolveError> {
        let start = Instant::now();
        let prepared = prepare(a, b)?;
        let (m, n) = prepared.shape();
        prepared.require_direct(NAME)?;
        let csc = prepared.to_csc().expect("require_direct refused operators");
        let col_norms = prepared
            .column_norms()
            .expect("require_direct refused operators");
        // Sequential: faer's supernodal kernels split their sums by the thread count, so the
        // answer would change with it (see `crate::sequential`).
        let par = Par::Seq;

        stage(&self.params.monitor, NAME, Stage::Analyze, 0)?;
        let params = QrSymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_qr(csc.symbolic(), params).map_err(|e| {
            SolveError::Factorization {
                solver: NAME,
                reason: format!("{e:?}"),
            }
        })?;
        stage(&self.params.monitor, NAME, Stage::Factorize, 1)?;
        let mut indices = vec![0usize; symbolic.len_idx()];
        let mut val = vec![0.0; symbolic.len_val()];
        let mut rhs = b.to_vec();
        {
            let mut buf = MemBuffer::new(
                symbolic.factorize_numeric_qr_scratch::<f64>(par, Default::default()),
            );
            let qr = symbolic.factorize_numeric_qr(
                &mut indices,
                &mut val,
                csc.as_ref(),
                par,
                MemStack::new(&mut buf),
                Default::default(),
            );
            let mut buf = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, par));
            qr.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(&mut rhs, m, 1),
                par,
                MemStack::new(&mut buf),
            );
        }
        // The diagonal of R, in factor order, from the simplicial layout of
        // `factorize_numeric_qr`: `indices` opens with R's column pointers (n + 1) and row
        // indices (unsorted within a column), `val` with R's values.
        let ptr = &indices[..n + 1];
        let row = &indices[n + 1..n + 1 + ptr[n]];
        let diag: Vec<f64> = (0..n)
            .map(|j| {
                (ptr[j]..ptr[j + 1])
                    .find(|&p| row[p] == j)
                    .map_or(0.0, |p| val[p])
            })
            .collect();
        let perm_fwd = symbolic.col_perm().arrays().0;
        let tau = rank_tolerance(
            self.params.rank_tolerance,
            1000.0 * m.max(n) as f64 * f64::EPSILON,
        )?;
        for (k, rkk) in diag.iter().enumerate() {
            let column = perm_fwd[k];
            let (pivot, threshold) = (rkk.abs(), tau * col_norms[column]);
            if pivot <= threshold || !pivot.is_finite() {
                return Err(SolveError::RankDeficient {
                    column,
                    pivot,
                    threshold,
                });
            }
        }
        stage(&self.params.monitor, NAME, Stage::Solve, 2)?;
        rhs.truncate(n);
        finish(
            NAME,
            &prepared,
            rhs,
            b,
            0,
            start,
            vec![("factor_len", val.len() as f64)],
        )
    }
}
