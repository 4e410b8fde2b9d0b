//! # zeroset-solvers
//!
//! Solvers of `min ‖A x − b‖₂`, tested to agree, behind the
//! [`LeastSquaresSolver`] trait of field-core:
//!
//! | solver | method | `A` as | accuracy | cost |
//! |---|---|---|---|---|
//! | [`Cgls`] | CG on the normal equations, implicit | any, incl. operators | `∝ cond(A)` per step | 2 products / iteration |
//! | [`Lsqr`] | Golub–Kahan bidiagonalisation (Paige–Saunders) | any, incl. operators | stabler than CGLS | 2 products / iteration |
//! | [`Pcg`] | preconditioned CG on `AᵀA` (or any SPD `K`) | any, incl. operators | `∝ cond(A)²` | 2 products / iteration |
//! | [`DenseQr`] | Householder QR, column pivoting | dense (sparse densified) | backward stable | `2mn² − 2n³/3` |
//! | [`NormalLu`] | LU of `AᵀA` | dense (sparse densified) | `∝ cond(A)²` | `mn² + n³/3` |
//! | [`SparseQr`] | sparse Householder QR (COLAMD) | sparse | `∝ cond(A)` | fill-dependent |
//! | [`SparseCholesky`] | Cholesky of `AᵀA` (AMD), symbolic analysis reused | sparse | `∝ cond(A)²` | fill-dependent; fastest here |
//!
//! Where `A` has full column rank the minimiser is unique and they all return it, to within
//! their tolerances (the test suite holds them to it, on random and restoration-shaped
//! problems). A tolerance bounds residuals, not the error in `x`: on an ill-conditioned `A`
//! the iterative solvers can stop with a small residual and some coefficients far off, as
//! SciPy's `lsqr` does (see [`IterativeParams`]). Where `A` is rank deficient, the direct solvers say which column is dependent
//! ([`SolveError::RankDeficient`]) and the
//! iterative ones return the minimum-norm solution.
//!
//! Every solver validates its input (shapes, NaN/inf), reports residuals measured the same way,
//! calls an optional progress [`Monitor`] that can cancel, and
//! is deterministic: the same bits for 1 or N threads (see [`kernels`]).
//!
//! Beyond least squares, [`admm`] minimises a quadratic plus a sum of proximable terms seen
//! through orthogonal maps (MRAS's trace-norm-regularised fit, paper 004 §5.3), factoring the
//! c-step matrix once.
//!
//! ```
//! use zeroset_solvers::{LeastSquaresSolverExt, Lsqr, SparseCholesky, problems::protrusion_problem};
//!
//! let p = protrusion_problem(8, 1.0);
//! let direct = SparseCholesky::default().solve_with(&p.a, &p.b)?;
//! let iterative = Lsqr::default().solve_with(&p.a, &p.b)?;
//! let diff = direct.x.iter().zip(&iterative.x).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
//! assert!(diff < 1e-8, "{diff}");
//! assert!(iterative.info.iterations > 0);
//! # Ok::<(), zeroset_field_core::lsq::SolveError>(())
//! ```

#![warn(missing_docs)]

pub mod admm;
mod common;
mod dense;
pub mod dst;
pub mod gmres;
mod iterative;
pub mod kernels;
mod operator;
mod pcg;
pub mod precond;
pub mod problems;
pub mod scratch;
pub mod sequential;
mod sparse_cholesky;
mod sparse_qr;

pub use common::{DirectParams, IterativeParams, NORMAL_RANK_TOLERANCE};
pub use dense::{DenseQr, NormalLu};
/// The `faer` these crates are built with: its `Mat`, `MatRef` and sparse matrices appear in
/// the public API (`LsqMatrix` converts from them), so name them through this re-export rather
/// than a `faer` dependency of your own, which must otherwise be the same version.
pub use faer;
pub use iterative::{Cgls, Lsqr};
pub use pcg::{Pcg, PcgParams};
pub use precond::{Diagonal, DirichletLaplacian, Preconditioner};
pub use sparse_cholesky::{NormalAnalysis, Ordering, SparseCholesky, SparseCholeskyParams};
pub use sparse_qr::SparseQr;
/// The solver interface and its types, defined in `zeroset-field-core` (so that every crate
/// can name them) and re-exported here, so that using a solver takes this crate alone.
pub use zeroset_field_core::lsq::{
    LeastSquaresSolver, LeastSquaresSolverExt, LinearOperator, LsqMatrix, Monitor, Progress,
    Solution, SolveError, SolveInfo, Stage,
};

/// One of each solver with default parameters, in the order of the table above.
///
/// For comparing solvers on problems of modest size: [`DenseQr`] and [`NormalLu`] densify a
/// sparse `A` (`8mn` bytes; a 14,400 × 13,824 problem needs 1.6 GB) and [`SparseQr`] factors
/// column by column (15.9 s on that problem); on large problems pick from the others.
pub fn all_solvers() -> Vec<Box<dyn LeastSquaresSolver>> {
    vec![
        Box::new(Cgls::default()),
        Box::new(Lsqr::default()),
        Box::new(Pcg::default()),
        Box::new(DenseQr::default()),
        Box::new(NormalLu::default()),
        Box::new(SparseQr::default()),
        Box::new(SparseCholesky::default()),
    ]
}
