//! Sparse Cholesky on the normal equations, with the symbolic analysis kept for reuse.
//!
//! `AᵀA x = Aᵀb` with `AᵀA = L Lᵀ` (faer's supernodal or simplicial Cholesky after an
//! approximate-minimum-degree ordering). For the sparse, well-conditioned systems of
//! restoration and spline fitting this is the fastest exact route: one sparse product, one
//! factorisation, two triangular solves.
//!
//! The work splits into a **symbolic** part that depends only on the sparsity pattern of `A`
//! (the pattern of `AᵀA`, the ordering, the elimination tree, the supernodes) and a **numeric**
//! part. Interactive restoration re-solves with the same pattern and new values (a new α, a new
//! field), so the analysis is cached: [`SparseCholesky`] keeps the last [`NormalAnalysis`] and
//! reuses it whenever the pattern of `A` matches exactly; [`NormalAnalysis`] can also be built
//! and handed over explicitly.
//!
//! Rank: a pivot `l_kk² ≤ τ·(AᵀA)_kk` (default `τ = 1e-12`, see
//! [`NORMAL_RANK_TOLERANCE`](crate::NORMAL_RANK_TOLERANCE)) or a non-positive pivot means the
//! column is dependent; the error names it in the caller's numbering.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError as DenseLltError, LltRegularization};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky, supernodal::SupernodalLltRef,
};
use faer::sparse::linalg::matmul::{
    SparseMatMulInfo, sparse_sparse_matmul_numeric, sparse_sparse_matmul_numeric_scratch,
    sparse_sparse_matmul_symbolic,
};
use faer::sparse::{
    SparseColMatMut, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef,
};
use faer::{Accum, Conj, MatMut, Par, Side};
use zeroset_field_core::lsq::{
    LeastSquaresSolver, LinearOperator, LsqMatrix, Monitor, Solution, SolveError, Stage,
};

use crate::common::{NORMAL_RANK_TOLERANCE, finish, prepare, rank_tolerance, stage};
use crate::operator::{Compressed, Prepared};

/// The fill-reducing ordering of `AᵀA`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Ordering {
    /// Approximate minimum degree (Amestoy–Davis–Duff). The default.
    #[default]
    Amd,
    /// No reordering: the columns' own order.
    Natural,
}

/// Parameters of [`SparseCholesky`].
#[derive(Clone, Debug, Default)]
pub struct SparseCholeskyParams {
    /// Relative pivot threshold (default [`NORMAL_RANK_TOLERANCE`]).
    pub rank_tolerance: Option<f64>,
    /// The fill-reducing ordering.
    pub ordering: Ordering,
    /// Progress callback between stages; it may cancel.
    pub monitor: Option<Monitor>,
}

/// The symbolic analysis of `AᵀA` for one sparsity pattern of `A`.
pub struct NormalAnalysis {
    nrows: usize,
    ncols: usize,
    /// `A`'s compressed columns (pointer and row indices): the key for reuse.
    pattern_ptr: Vec<usize>,
    pattern_idx: Vec<usize>,
    ata: SymbolicSparseColMat<usize>,
    ata_info: SparseMatMulInfo,
    cholesky: SymbolicCholesky<usize>,
}

fn factorization_error(solver: &'static str, e: impl std::fmt::Debug) -> SolveError {
    SolveError::Factorization {
        solver,
        reason: format!("{e:?}"),
    }
}

const NAME: &str = "sparse-cholesky";

/// What a non-positive pivot is replaced by during factorisation (then reported).
const TINY_PIVOT: f64 = 1e-200;

/// `Aᵀ` as compressed columns: `A`'s compressed rows, reinterpreted.
fn transpose_view<'r>(
    rows: &'r Compressed<'_>,
    nrows: usize,
    ncols: usize,
) -> SparseColMatRef<'r, usize, f64> {
    let s = SymbolicSparseColMatRef::new_checked(ncols, nrows, &rows.ptr, None, &rows.idx);
    SparseColMatRef::new(s, &rows.val)
}

impl std::fmt::Debug for NormalAnalysis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NormalAnalysis")
            .field("nrows", &self.nrows)
            .field("ncols", &self.ncols)
            .field("normal_nnz", &self.normal_nnz())
            .field("factor_len", &self.factor_len())
            .finish_non_exhaustive()
    }
}

impl NormalAnalysis {
    /// Analyses `A`'s pattern: the pattern of `AᵀA`, its ordering and symbolic factor.
    ///
    /// # Errors
    /// [`SolveError::Unsupported`] for an operator; [`SolveError::Factorization`] when an
    /// allocation fails.
    pub fn new(a: LsqMatrix<'_>, ordering: Ordering) -> Result<Self, SolveError> {
        let prepared = Prepared::new(a)?;
        Self::from_prepared(&prepared, ordering)
    }

    fn from_prepared(a: &Prepared<'_>, ordering: Ordering) -> Result<Self, SolveError> {
        let (m, n) = a.shape();
        let csc = a.to_csc().ok_or(SolveError::Unsupported {
            solver: NAME,
            reason: "a matrix-free operator (it needs the pattern of A)".into(),
        })?;
        let owned_rows;
        let rows = match a.rows() {
            Some(r) => r,
            None => {
                owned_rows = Prepared::new(LsqMatrix::SparseCol(csc.as_ref()))?;
                return Self::from_prepared(&owned_rows, ordering);
            }
        };
        let at = transpose_view(rows, m, n);
        let (ata, ata_info) = sparse_sparse_matmul_symbolic(at.symbolic(), csc.symbolic())
            .map_err(|e| factorization_error(NAME, e))?;
        let ord = match ordering {
            Ordering::Amd => SymmetricOrdering::Amd,
            Ordering::Natural => SymmetricOrdering::Identity,
        };
        let cholesky = factorize_symbolic_cholesky(
            ata.as_ref(),
            Side::Lower,
            ord,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| factorization_error(NAME, e))?;
        Ok(Self {
            nrows: m,
            ncols: n,
            pattern_ptr: csc.symbolic().col_ptr().to_vec(),
            pattern_idx: csc.symbolic().row_idx().to_vec(),
            ata,
            ata_info,
            cholesky,
        })
    }

    /// Whether `a` has exactly the pattern this analysis was made for.
    fn matches(&self, a: &Prepared<'_>) -> bool {
        match a {
            Prepared::Sparse {
                nrows, ncols, cols, ..
            } => {
                *nrows == self.nrows
                    && *ncols == self.ncols
                    && *cols.ptr == *self.pattern_ptr
                    && *cols.idx == *self.pattern_idx
            }
            _ => false,
        }
    }

    /// Non-zeros in the Cholesky factor `L` (the fill), counting supernodal blocks in full.
    pub fn factor_len(&self) -> usize {
        self.cholesky.len_val()
    }

    /// Non-zeros of `AᵀA` (both triangles).
    pub fn normal_nnz(&self) -> usize {
        self.ata.row_idx().len()
    }

    /// Forms `AᵀA` and `Aᵀb`, factors, checks the pivots and solves.
    fn factor_and_solve(
        &self,
        a: &Prepared<'_>,
        b: &[f64],
        tau: f64,
        monitor: &Option<Monitor>,
    ) -> Result<Vec<f64>, SolveError> {
        let (m, n) = (self.nrows, self.ncols);
        // Sequential: faer's supernodal kernels split their sums by the thread count, so the
        // answer would change with it (see `crate::sequential`).
        let par = Par::Seq;
        let rows = a.rows().expect("sparse input");
        let Prepared::Sparse { cols, .. } = a else {
            unreachable!("sparse input")
        };
        let a_csc = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(m, n, &cols.ptr, None, &cols.idx),
            &cols.val,
        );
        let at = transpose_view(rows, m, n);

        stage(monitor, NAME, Stage::Factorize, 1)?;
        let mut ata_val = vec![0.0; self.ata.row_idx().len()];
        {
            let dst = SparseColMatMut::new(self.ata.as_ref(), &mut ata_val);
            let mut buf = MemBuffer::new(sparse_sparse_matmul_numeric_scratch::<usize, f64>(
                self.ata.as_ref(),
                par,
            ));
            sparse_sparse_matmul_numeric(
                dst,
                Accum::Replace,
                at,
                a_csc,
                1.0,
                &self.ata_info,
                par,
                MemStack::new(&mut buf),
            );
        }
        let ata = SparseColMatRef::new(self.ata.as_ref(), &ata_val);
        let diag: Vec<f64> = (0..n)
            .map(|j| ata.get(j, j).copied().unwrap_or(0.0))
            .collect();
        let perm_fwd: Vec<usize> = match self.cholesky.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };

        let mut l_val = vec![0.0; self.cholesky.len_val()];
        let mut rhs = vec![0.0; n];
        a.apply_transpose(b, &mut rhs);
        {
            let mut buf = MemBuffer::try_new(
                self.cholesky
                    .factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            )
            .map_err(|e| factorization_error(NAME, e))?;
            let llt = self
                .cholesky
                .factorize_numeric_llt(
                    &mut l_val,
                    ata,
                    Side::Lower,
                    // A non-positive pivot must not stop the factorisation: faer's error index
                    // is not in a documented numbering. Replace it by a tiny value instead,
                    // which the pivot check below then finds in factor order and names.
                    LltRegularization {
                        dynamic_regularization_delta: TINY_PIVOT,
                        dynamic_regularization_epsilon: TINY_PIVOT,
                    },
                    par,
                    MemStack::new(&mut buf),
                    Default::default(),
                )
                .map_err(|e| match e {
                    DenseLltError::NonPositivePivot { index } => SolveError::Factorization {
                        solver: NAME,
                        reason: format!("non-positive pivot {index} despite regularisation"),
                    },
                })?;
            stage(monitor, NAME, Stage::Solve, 2)?;
            let mut buf = MemBuffer::new(self.cholesky.solve_in_place_scratch::<f64>(1, par));
            llt.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(&mut rhs, n, 1),
                par,
                MemStack::new(&mut buf),
            );
        }
        // Pivot check on the diagonal of L (in the permuted numbering). The solve above is
        // cheap next to the factorisation; its result is dropped if a pivot fails.
        for (k, lkk) in self.factor_diagonal(&l_val).into_iter().enumerate() {
            let column = perm_fwd[k];
            let pivot = lkk * lkk;
            // An empty column has (AᵀA)_kk = 0; its regularised pivot is caught by the floor.
            let threshold = (tau * diag[column]).max(TINY_PIVOT);
            if pivot <= threshold || !pivot.is_finite() {
                return Err(SolveError::RankDeficient {
                    column,
                    pivot,
                    threshold,
                });
            }
        }
        Ok(rhs)
    }

    /// The diagonal of `L`, in the factor's (permuted) order.
    fn factor_diagonal(&self, l_val: &[f64]) -> Vec<f64> {
        let n = self.ncols;
        match self.cholesky.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => (0..n)
                .map(|j| {
                    let (ptr, idx) = (s.col_ptr(), s.row_idx());
                    (ptr[j]..ptr[j + 1])
                        .find(|&p| idx[p] == j)
                        .map_or(0.0, |p| l_val[p])
                })
                .collect(),
            SymbolicCholeskyRaw::Supernodal(s) => {
                let l = SupernodalLltRef::new(s, l_val);
                let mut d = Vec::with_capacity(n);
                for node in 0..s.n_supernodes() {
                    let width = s.supernode_end()[node] - s.supernode_begin()[node];
                    let v = l.supernode(node).val();
                    d.extend((0..width).map(|i| v[(i, i)]));
                }
                d
            }
        }
    }
}

/// Sparse Cholesky on the normal equations, reusing the last symbolic analysis when the
/// pattern of `A` is unchanged.
#[derive(Debug, Default)]
pub struct SparseCholesky {
    /// Rank tolerance, ordering, monitor.
    pub params: SparseCholeskyParams,
    cache: Mutex<Option<Arc<NormalAnalysis>>>,
}

impl Clone for SparseCholesky {
    fn clone(&self) -> Self {
        Self {
            params: self.params.clone(),
            cache: Mutex::new(self.cached_analysis()),
        }
    }
}

impl SparseCholesky {
    /// A solver with the given parameters and an empty cache.
    pub fn new(params: SparseCholeskyParams) -> Self {
        Self {
            params,
            cache: Mutex::new(None),
        }
    }

    /// A solver that starts with `analysis` in its cache.
    pub fn with_analysis(params: SparseCholeskyParams, analysis: Arc<NormalAnalysis>) -> Self {
        Self {
            params,
            cache: Mutex::new(Some(analysis)),
        }
    }

    /// The analysis currently cached, if any.
    pub fn cached_analysis(&self) -> Option<Arc<NormalAnalysis>> {
        self.cache.lock().map(|c| c.clone()).unwrap_or(None)
    }
}

impl LeastSquaresSolver for SparseCholesky {
    fn name(&self) -> &'static str {
        NAME
    }

    fn solve(&self, a: LsqMatrix<'_>, b: &[f64]) -> Result<Solution, SolveError> {
        let start = Instant::now();
        let prepared = prepare(a, b)?;
        prepared.require_direct(NAME)?;
        // Dense input goes through compressed storage like any other.
        let sparse_owned;
        let prepared = match prepared {
            p @ Prepared::Sparse { .. } => p,
            other => {
                sparse_owned = other.to_csc().expect("require_direct refused operators");
                Prepared::new(LsqMatrix::SparseCol(sparse_owned.as_ref()))?
            }
        };
        stage(&self.params.monitor, NAME, Stage::Analyze, 0)?;
        let cached = self.cached_analysis().filter(|an| an.matches(&prepared));
        let reused = cached.is_some();
        let analysis = match cached {
            Some(an) => an,
            None => {
                let an = Arc::new(NormalAnalysis::from_prepared(
                    &prepared,
                    self.params.ordering,
                )?);
                if let Ok(mut c) = self.cache.lock() {
                    *c = Some(an.clone());
                }
                an
            }
        };
        let tau = rank_tolerance(self.params.rank_tolerance, NORMAL_RANK_TOLERANCE)?;
        let x = analysis.factor_and_solve(&prepared, b, tau, &self.params.monitor)?;
        let details = vec![
            ("analysis_reused", if reused { 1.0 } else { 0.0 }),
            ("nnz_normal", analysis.normal_nnz() as f64),
            ("factor_len", analysis.factor_len() as f64),
        ];
        finish(NAME, &prepared, x, b, 0, start, details)
    }
}
