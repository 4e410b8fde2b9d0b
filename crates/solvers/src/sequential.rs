//! faer's dense factorisations and products pinned to one thread, so that their answers do
//! not depend on the number of threads.
//!
//! faer's high-level `ColPivQr`, `PartialPivLu` and `*` run with the global parallelism, and
//! their parallel kernels split sums by the thread count: the same problem solved under
//! `--threads 1` and `--threads 2` differed in its last bits (dense QR and LU from about 500
//! unknowns). These wrappers call the same kernels with `Par::Seq`. zeroset's parallelism is
//! across independent pieces of work instead (cells, chunks of points, blocks), which keeps
//! results bit-identical on any thread count.
//!
//! ```
//! use faer::Mat;
//! use zeroset_solvers::sequential::{ColPivQr, PartialPivLu, product};
//! let a = Mat::from_fn(4, 2, |i, j| (1 + i + 2 * j) as f64 + if i == j { 3.0 } else { 0.0 });
//! let x = [2.0, -1.0];
//! let b: Vec<f64> = (0..4).map(|i| a[(i, 0)] * x[0] + a[(i, 1)] * x[1]).collect();
//! let qr = ColPivQr::new(a.as_ref());
//! let solved = qr.solve_lstsq(&b);
//! assert!((solved[0] - 2.0).abs() < 1e-12 && (solved[1] + 1.0).abs() < 1e-12);
//! // The normal equations by LU.
//! let normal = product(a.transpose(), a.as_ref());
//! let mut rhs = product(a.transpose(), Mat::from_fn(4, 1, |i, _| b[i]).as_ref());
//! PartialPivLu::new(normal.as_ref()).solve_in_place(rhs.as_mut());
//! assert!((rhs[(0, 0)] - 2.0).abs() < 1e-10 && (rhs[(1, 0)] + 1.0).abs() < 1e-10);
//! ```

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting as lu;
use faer::linalg::matmul::matmul;
use faer::linalg::qr::{col_pivoting as qr, no_pivoting};
use faer::perm::PermRef;
use faer::{Accum, Mat, MatMut, MatRef, Par};

/// `a · b`.
pub fn product(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(a.nrows(), b.ncols());
    matmul(out.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    out
}

/// `A P = Q R` by Householder QR with column pivoting (Businger–Golub), for `A` with at least
/// as many rows as columns.
#[derive(Debug, Clone)]
pub struct ColPivQr {
    /// The Householder vectors below a unit diagonal (`m × n`).
    basis: Mat<f64>,
    /// The block Householder coefficients.
    coefficients: Mat<f64>,
    /// `R` (`n × n`).
    r: Mat<f64>,
    forward: Vec<usize>,
    inverse: Vec<usize>,
}

impl ColPivQr {
    /// Factors `a`.
    ///
    /// # Panics
    /// If `a` has fewer rows than columns.
    pub fn new(a: MatRef<'_, f64>) -> Self {
        let (m, n) = a.shape();
        assert!(
            m >= n,
            "a least-squares QR needs at least as many rows as columns"
        );
        let mut basis = a.to_owned();
        let block = no_pivoting::factor::recommended_block_size::<f64>(m, n);
        let mut coefficients = Mat::zeros(block, n);
        let (mut forward, mut inverse) = (vec![0usize; n], vec![0usize; n]);
        let scratch = qr::factor::qr_in_place_scratch::<usize, f64>(
            m,
            n,
            block,
            Par::Seq,
            Default::default(),
        );
        qr::factor::qr_in_place(
            basis.as_mut(),
            coefficients.as_mut(),
            &mut forward,
            &mut inverse,
            Par::Seq,
            MemStack::new(&mut MemBuffer::new(scratch)),
            Default::default(),
        );
        let mut r = Mat::zeros(n, n);
        for j in 0..n {
            for i in 0..=j {
                r[(i, j)] = basis[(i, j)];
                basis[(i, j)] = if i == j { 1.0 } else { 0.0 };
            }
        }
        Self {
            basis,
            coefficients,
            r,
            forward,
            inverse,
        }
    }

    /// `R`, upper triangular with `|r₀₀| ≥ |r₁₁| ≥ …`.
    pub fn r(&self) -> MatRef<'_, f64> {
        self.r.as_ref()
    }

    /// The column pivoting: column `k` of `R` is column `permutation()[k]` of `A`.
    pub fn permutation(&self) -> &[usize] {
        &self.forward
    }

    /// `x` minimising `‖A x − b‖₂`.
    ///
    /// # Panics
    /// If `b` does not have `A`'s row count.
    pub fn solve_lstsq(&self, b: &[f64]) -> Vec<f64> {
        let (m, n) = self.basis.shape();
        assert_eq!(b.len(), m, "a right-hand side of the matrix's row count");
        let mut rhs = Mat::from_fn(m, 1, |i, _| b[i]);
        let perm = PermRef::new_checked(&self.forward, &self.inverse, n);
        let block = self.coefficients.nrows();
        let scratch =
            qr::solve::solve_lstsq_in_place_scratch::<usize, f64>(m, n, block, 1, Par::Seq);
        qr::solve::solve_lstsq_in_place(
            self.basis.as_ref(),
            self.coefficients.as_ref(),
            self.r.as_ref(),
            perm,
            rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
        (0..n).map(|i| rhs[(i, 0)]).collect()
    }
}

/// `P A = L U` by LU with partial (row) pivoting, for a square `A`.
#[derive(Debug, Clone)]
pub struct PartialPivLu {
    /// `L` below a unit diagonal, `U` on and above it.
    factors: Mat<f64>,
    forward: Vec<usize>,
    inverse: Vec<usize>,
}

impl PartialPivLu {
    /// Factors `a`.
    ///
    /// # Panics
    /// If `a` is not square.
    pub fn new(a: MatRef<'_, f64>) -> Self {
        let n = a.nrows();
        assert_eq!(n, a.ncols(), "LU of a square matrix");
        let mut factors = a.to_owned();
        let (mut forward, mut inverse) = (vec![0usize; n], vec![0usize; n]);
        let scratch =
            lu::factor::lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, Default::default());
        lu::factor::lu_in_place(
            factors.as_mut(),
            &mut forward,
            &mut inverse,
            Par::Seq,
            MemStack::new(&mut MemBuffer::new(scratch)),
            Default::default(),
        );
        Self {
            factors,
            forward,
            inverse,
        }
    }

    /// `U`: read its entries on and above the diagonal (below it lie `L`'s).
    pub fn u(&self) -> MatRef<'_, f64> {
        self.factors.as_ref()
    }

    /// Overwrites the columns of `rhs` with the solutions `x` of `A x = rhs`.
    ///
    /// # Panics
    /// If `rhs` does not have `A`'s order of rows.
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        let n = self.factors.nrows();
        assert_eq!(rhs.nrows(), n, "right-hand sides of the matrix's order");
        let perm = PermRef::new_checked(&self.forward, &self.inverse, n);
        let scratch = lu::solve::solve_in_place_scratch::<usize, f64>(n, rhs.ncols(), Par::Seq);
        // The unit lower solve reads below the diagonal only, the upper solve on and above.
        lu::solve::solve_in_place(
            self.factors.as_ref(),
            self.factors.as_ref(),
            perm,
            rhs,
            Par::Seq,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
    }
}
