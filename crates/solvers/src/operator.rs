//! A matrix prepared for iteration: both products `A x` and `Aᵀ y` as parallel gathers.
//!
//! A sparse matrix arrives in one compressed orientation; the other is built once (a counting
//! sort, `O(nnz)`), so that `A x` runs over rows and `Aᵀ y` over columns, each output element
//! summed sequentially — deterministic for any thread count, and free of write conflicts.

use std::borrow::Cow;

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Mat, MatRef};
use rayon::prelude::*;
use zeroset_field_core::lsq::{LinearOperator, LsqMatrix, SolveError};

use crate::kernels::{dot, norm2};

/// Rows or columns per rayon task in the products.
const CHUNK: usize = 512;

/// One compressed orientation: `ptr[o]..ptr[o+1]` indexes the inner indices and values of
/// outer slice `o`.
#[derive(Debug, Clone)]
pub(crate) struct Compressed<'a> {
    pub ptr: Cow<'a, [usize]>,
    pub idx: Cow<'a, [usize]>,
    pub val: Cow<'a, [f64]>,
}

impl Compressed<'_> {
    fn outer_len(&self) -> usize {
        self.ptr.len() - 1
    }

    /// `out[o] = Σ_k val[k] · x[idx[k]]` over outer slice `o`.
    fn gather(&self, x: &[f64], out: &mut [f64]) {
        out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, os)| {
            for (r, o) in os.iter_mut().enumerate() {
                let outer = c * CHUNK + r;
                let range = self.ptr[outer]..self.ptr[outer + 1];
                *o = self.idx[range.clone()]
                    .iter()
                    .zip(&self.val[range])
                    .map(|(&i, v)| v * x[i])
                    .sum();
            }
        });
    }

    /// The other orientation, by a stable counting sort (inner indices stay increasing).
    fn transposed(&self, inner_len: usize) -> Compressed<'static> {
        let mut count = vec![0usize; inner_len + 1];
        for &i in self.idx.iter() {
            count[i + 1] += 1;
        }
        for i in 0..inner_len {
            count[i + 1] += count[i];
        }
        let ptr = count.clone();
        let mut next = count;
        let mut idx = vec![0usize; self.idx.len()];
        let mut val = vec![0.0; self.val.len()];
        for o in 0..self.outer_len() {
            for k in self.ptr[o]..self.ptr[o + 1] {
                let i = self.idx[k];
                idx[next[i]] = o;
                val[next[i]] = self.val[k];
                next[i] += 1;
            }
        }
        Compressed {
            ptr: Cow::Owned(ptr),
            idx: Cow::Owned(idx),
            val: Cow::Owned(val),
        }
    }
}

/// Dense storage, column-major with unit row stride (copied once if the input was not).
pub(crate) enum DenseStore<'a> {
    Borrowed(MatRef<'a, f64>),
    Owned(Mat<f64>),
}

impl DenseStore<'_> {
    pub fn get(&self) -> MatRef<'_, f64> {
        match self {
            Self::Borrowed(a) => *a,
            Self::Owned(a) => a.as_ref(),
        }
    }
}

/// `A` ready for `A x` and `Aᵀ y`.
pub(crate) enum Prepared<'a> {
    Dense(DenseStore<'a>),
    Sparse {
        nrows: usize,
        ncols: usize,
        rows: Compressed<'a>,
        cols: Compressed<'a>,
    },
    Operator(&'a dyn LinearOperator),
}

/// Compact, sorted compressed columns. faer admits unsorted inner indices (and column
/// lengths apart from the pointers); faer's checked constructors, which the factorisations use,
/// do not. Borrow when the input is already compact and sorted; otherwise copy each column,
/// sorted, with repeated indices summed.
fn compact_csc_col(a: faer::sparse::SparseColMatRef<'_, usize, f64>) -> Compressed<'_> {
    let s = a.symbolic();
    let sorted = (0..a.ncols()).all(|j| {
        let rows = a.row_idx_of_col_raw(j);
        rows.windows(2).all(|w| w[0] < w[1])
    });
    if sorted && s.col_nnz().is_none() && s.col_ptr()[0] == 0 {
        return Compressed {
            ptr: Cow::Borrowed(s.col_ptr()),
            idx: Cow::Borrowed(s.row_idx()),
            val: Cow::Borrowed(a.val()),
        };
    }
    let mut ptr = vec![0];
    let mut idx = Vec::new();
    let mut val = Vec::new();
    let mut column: Vec<(usize, f64)> = Vec::new();
    for j in 0..a.ncols() {
        column.clear();
        column.extend(a.row_idx_of_col(j).zip(a.val_of_col(j).iter().copied()));
        column.sort_by_key(|e| e.0);
        for &(i, v) in &column {
            if idx.len() > ptr[j] && idx.last() == Some(&i) {
                *val.last_mut().expect("a previous entry") += v;
            } else {
                idx.push(i);
                val.push(v);
            }
        }
        ptr.push(idx.len());
    }
    Compressed {
        ptr: Cow::Owned(ptr),
        idx: Cow::Owned(idx),
        val: Cow::Owned(val),
    }
}

fn compact_csr_row(a: faer::sparse::SparseRowMatRef<'_, usize, f64>) -> Compressed<'_> {
    // A CSR matrix is the CSC storage of its transpose.
    compact_csc_col(a.transpose())
}

impl<'a> Prepared<'a> {
    /// Validates `A` (finite entries) and builds both orientations.
    pub fn new(a: LsqMatrix<'a>) -> Result<Self, SolveError> {
        if let Some(values) = a.stored_values()
            && let Some((index, value)) = values.enumerate().find(|(_, v)| !v.is_finite())
        {
            return Err(SolveError::NonFinite {
                what: "matrix",
                index,
                value,
            });
        }
        Ok(match a {
            LsqMatrix::Dense(m) => {
                if m.row_stride() == 1 {
                    Prepared::Dense(DenseStore::Borrowed(m))
                } else {
                    Prepared::Dense(DenseStore::Owned(m.to_owned()))
                }
            }
            LsqMatrix::SparseCol(m) => {
                let cols = compact_csc_col(m);
                let rows = cols.transposed(m.nrows());
                Prepared::Sparse {
                    nrows: m.nrows(),
                    ncols: m.ncols(),
                    rows,
                    cols,
                }
            }
            LsqMatrix::SparseRow(m) => {
                let rows = compact_csr_row(m);
                let cols = rows.transposed(m.ncols());
                Prepared::Sparse {
                    nrows: m.nrows(),
                    ncols: m.ncols(),
                    rows,
                    cols,
                }
            }
            LsqMatrix::Operator(op) => Prepared::Operator(op),
        })
    }

    pub fn shape(&self) -> (usize, usize) {
        match self {
            Self::Dense(d) => (d.get().nrows(), d.get().ncols()),
            Self::Sparse { nrows, ncols, .. } => (*nrows, *ncols),
            Self::Operator(op) => (op.nrows(), op.ncols()),
        }
    }

    /// `‖A‖_F`, or for an operator an estimate of `‖A‖₂` by 30 power iterations on `AᵀA`
    /// from a fixed pseudo-random start (deterministic). A constant start, which it was, is
    /// annihilated by difference operators and Laplacians (`‖A‖` came out 0, and CGLS's
    /// stopping test with it never held).
    pub fn norm_estimate(&self) -> f64 {
        match self {
            Self::Dense(d) => {
                let a = d.get();
                let sums: Vec<f64> = (0..a.ncols())
                    .into_par_iter()
                    .map(|j| {
                        let c = a.col(j).try_as_col_major().expect("unit row stride");
                        dot(c.as_slice(), c.as_slice())
                    })
                    .collect();
                sums.iter().sum::<f64>().sqrt()
            }
            Self::Sparse { cols, .. } => norm2(&cols.val),
            Self::Operator(_) => {
                let (m, n) = self.shape();
                let mut rng = zeroset_field_core::rng::SplitMix64::new(0x6e6f_726d);
                let mut v: Vec<f64> = (0..n).map(|_| rng.unit() - 0.5).collect();
                let start = norm2(&v);
                if start > 0.0 {
                    v.iter_mut().for_each(|x| *x /= start);
                }
                let mut av = vec![0.0; m];
                let mut sigma = 0.0;
                for _ in 0..30 {
                    self.apply(&v, &mut av);
                    self.apply_transpose(&av, &mut v);
                    let nv = norm2(&v);
                    if nv == 0.0 {
                        return 0.0;
                    }
                    sigma = nv.sqrt();
                    v.iter_mut().for_each(|x| *x /= nv);
                }
                sigma
            }
        }
    }

    /// Euclidean norms of the columns of `A` (for column scaling). `None` for an operator.
    pub fn column_norms(&self) -> Option<Vec<f64>> {
        match self {
            Self::Dense(d) => {
                let a = d.get();
                Some(
                    (0..a.ncols())
                        .into_par_iter()
                        .map(|j| norm2(a.col(j).try_as_col_major().expect("unit").as_slice()))
                        .collect(),
                )
            }
            Self::Sparse { cols, .. } => Some(
                (0..cols.outer_len())
                    .into_par_iter()
                    .map(|j| norm2(&cols.val[cols.ptr[j]..cols.ptr[j + 1]]))
                    .collect(),
            ),
            Self::Operator(_) => None,
        }
    }

    /// The matrix as compressed columns (sorted row indices, no copy for sparse input).
    /// `None` for an operator.
    pub fn to_csc(&self) -> Option<SparseColMat<usize, f64>> {
        let (m, n) = self.shape();
        let (ptr, idx, val) = match self {
            Self::Sparse { cols, .. } => (cols.ptr.to_vec(), cols.idx.to_vec(), cols.val.to_vec()),
            Self::Dense(d) => {
                let a = d.get();
                let mut ptr = vec![0];
                let mut idx = Vec::new();
                let mut val = Vec::new();
                for j in 0..n {
                    for i in 0..m {
                        let v = a[(i, j)];
                        if v != 0.0 {
                            idx.push(i);
                            val.push(v);
                        }
                    }
                    ptr.push(idx.len());
                }
                (ptr, idx, val)
            }
            Self::Operator(_) => return None,
        };
        let s = SymbolicSparseColMat::new_checked(m, n, ptr, None, idx);
        Some(SparseColMat::new(s, val))
    }

    /// For a direct solver: `m ≥ n` and a matrix (not an operator).
    ///
    /// # Errors
    /// [`SolveError::Underdetermined`] or [`SolveError::Unsupported`].
    pub fn require_direct(&self, solver: &'static str) -> Result<(), SolveError> {
        let (m, n) = self.shape();
        if let Self::Operator(_) = self {
            return Err(SolveError::Unsupported {
                solver,
                reason: "a matrix-free operator (it needs the entries of A)".into(),
            });
        }
        if m < n {
            return Err(SolveError::Underdetermined { nrows: m, ncols: n });
        }
        Ok(())
    }

    /// The transpose's compressed columns (= `A`'s compressed rows), for `AᵀA` products.
    pub fn rows(&self) -> Option<&Compressed<'a>> {
        match self {
            Self::Sparse { rows, .. } => Some(rows),
            _ => None,
        }
    }

    /// The matrix as a dense `m × n` matrix. `None` for an operator.
    pub fn to_dense(&self) -> Option<Cow<'_, Mat<f64>>> {
        match self {
            Self::Dense(DenseStore::Owned(a)) => Some(Cow::Borrowed(a)),
            Self::Dense(DenseStore::Borrowed(a)) => Some(Cow::Owned(a.to_owned())),
            Self::Sparse {
                cols, nrows, ncols, ..
            } => {
                let mut a = Mat::zeros(*nrows, *ncols);
                for j in 0..*ncols {
                    for k in cols.ptr[j]..cols.ptr[j + 1] {
                        a[(cols.idx[k], j)] = cols.val[k];
                    }
                }
                Some(Cow::Owned(a))
            }
            Self::Operator(_) => None,
        }
    }
}

impl LinearOperator for Prepared<'_> {
    fn nrows(&self) -> usize {
        self.shape().0
    }
    fn ncols(&self) -> usize {
        self.shape().1
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        match self {
            Self::Dense(d) => {
                let a = d.get();
                // Rows in blocks; within a block, columns in order: each y[i] is summed in the
                // same order whatever the thread count.
                y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
                    let r0 = c * CHUNK;
                    ys.fill(0.0);
                    for (j, &xj) in x.iter().enumerate() {
                        let col = a.col(j).try_as_col_major().expect("unit row stride");
                        let col = &col.as_slice()[r0..r0 + ys.len()];
                        ys.iter_mut().zip(col).for_each(|(y, v)| *y += v * xj);
                    }
                });
            }
            Self::Sparse { rows, .. } => rows.gather(x, y),
            Self::Operator(op) => op.apply(x, y),
        }
    }
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
        match self {
            Self::Dense(d) => {
                let a = d.get();
                x.par_iter_mut().enumerate().for_each(|(j, xj)| {
                    let col = a.col(j).try_as_col_major().expect("unit row stride");
                    *xj = col.as_slice().iter().zip(y).map(|(v, w)| v * w).sum();
                });
            }
            Self::Sparse { cols, .. } => cols.gather(y, x),
            Self::Operator(op) => op.apply_transpose(y, x),
        }
    }
}
