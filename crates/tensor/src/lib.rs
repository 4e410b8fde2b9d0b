//! # zeroset-tensor
//!
//! Dense 3-way tensors and the low-rank machinery that MRAS (paper 004 §3) compresses spline
//! coefficients with: unfoldings, n-mode and Khatri–Rao products, the trace norm and
//! singular-value thresholding (here), CP decomposition by alternating least squares and the
//! paper's adaptive rank ([`cp`]), and CP fitted in entry weights ([`weighted`]).
//!
//! ## The maths
//!
//! A tensor `X ∈ ℝ^{I₀×I₁×I₂}` has three **mode-n unfoldings** `X₍ₙ₎ ∈ ℝ^{Iₙ × ∏_{m≠n} I_m}`
//! (Kolda & Bader 2009, §2.4): entry `(i₀, i₁, i₂)` goes to row `iₙ` and column
//! `Σ_{k≠n} i_k J_k` with `J_k = ∏_{m<k, m≠n} I_m` (the lower remaining mode runs fastest).
//! With this ordering a Kruskal tensor `X = Σ_r a_r ∘ b_r ∘ c_r` unfolds as
//! `X₍₀₎ = A (C ⊙ B)ᵀ`, `X₍₁₎ = B (C ⊙ A)ᵀ`, `X₍₂₎ = C (B ⊙ A)ᵀ`, where `⊙` is the
//! [`khatri_rao`] product. The **n-mode product** `X ×ₙ U` multiplies every mode-n fibre by
//! `U`: `(X ×ₙ U)₍ₙ₎ = U X₍ₙ₎`.
//!
//! The **trace norm** of an unfolding is the sum of its singular values, `‖X₍ₙ₎‖_*`, the convex
//! surrogate of its rank that paper 004 (eq. 7) penalises over the three modes. Its proximal
//! operator is **singular-value thresholding** (Cai, Candès & Shen 2010):
//! `D_τ(M) = U max(Σ − τ, 0) Vᵀ` minimises `τ‖Y‖_* + ½‖Y − M‖²_F` ([`svt`]).
//!
//! ## Layout
//!
//! [`Tensor3`] stores its entries contiguously in row-major (C) order, `i₂` fastest: the
//! standard layout of an `ndarray::Array3`, which converts both ways without reordering.
//!
//! ```
//! use zeroset_tensor::Tensor3;
//!
//! let x = Tensor3::from_fn([2, 3, 4], |i, j, k| (100 * i + 10 * j + k) as f64);
//! let m = x.unfold(1)?;
//! assert_eq!((m.nrows(), m.ncols()), (3, 8));
//! assert_eq!(m[(2, 1 + 2 * 3)], 123.0); // (i₀, i₁, i₂) = (1, 2, 3) → row 2, column 1 + 3·2
//! assert_eq!(Tensor3::fold(1, &m, [2, 3, 4])?, x);
//! # Ok::<(), zeroset_tensor::TensorError>(())
//! ```

pub mod cp;
mod dense;
mod lowrank;
mod mttkrp;
pub mod weighted;

pub use cp::{
    AdaptiveOptions, AdaptiveResult, CpInit, CpOptions, CpProgress, CpResult, CpStop, Kruskal,
    cp_adaptive, cp_als, paper_initial_rank, planted,
};
pub use dense::{Tensor3, khatri_rao};
/// The `faer` this crate is built with (its `Mat` and `MatRef` appear in the API: factors,
/// unfoldings, SVDs): use it through this re-export to get the same version.
pub use faer;
pub use lowrank::{ThinSvd, svt, thin_svd, trace_norm};
pub use weighted::{WeightedOptions, WeightedResult, cp_als_weighted};

/// What can go wrong with tensor shapes and data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TensorError {
    /// Given starting factors with a component that is zero in some mode (or of weight 0):
    /// ALS keeps such a component at zero, and would report its error as converged.
    #[error(
        "the given starting factors' component {component} is zero in mode {mode} (or has \
         weight 0): ALS never moves it from zero; start from other factors (CpInit::Random, \
         CpInit::Svd)"
    )]
    ZeroComponent {
        /// The mode whose factor column is zero (0 for a zero weight).
        mode: usize,
        /// The component (column).
        component: usize,
    },
    /// A tensor with a zero extent.
    #[error("a tensor needs every extent at least 1, not {shape:?}")]
    EmptyShape {
        /// The shape given.
        shape: [usize; 3],
    },
    /// The data does not fill the shape.
    #[error("{len} entries cannot fill a tensor of shape {shape:?}")]
    Length {
        /// The shape given.
        shape: [usize; 3],
        /// The number of entries given.
        len: usize,
    },
    /// A mode outside `0..3`.
    #[error("a 3-way tensor has modes 0, 1 and 2, not {mode}")]
    Mode {
        /// The mode asked for.
        mode: usize,
    },
    /// Matrix dimensions that do not match the operation.
    #[error("{what}: expected {}, got {}", dims(*expected), dims(*got))]
    Dimensions {
        /// The operation and operand.
        what: &'static str,
        /// The dimensions it needs (rows, columns; `usize::MAX` for any).
        expected: (usize, usize),
        /// The dimensions given.
        got: (usize, usize),
    },
    /// An entry is NaN or infinite.
    #[error("entry {index} is not finite")]
    NonFinite {
        /// The entry's index in row-major order.
        index: usize,
    },
    /// A threshold that is negative or not finite.
    #[error("the threshold must be finite and non-negative, not {tau}")]
    Threshold {
        /// The threshold given.
        tau: f64,
    },
    /// A CP rank of 0, or above the largest a tensor of this shape can need.
    #[error("the CP rank must be between 1 and {max} for this shape, not {rank}")]
    Rank {
        /// The rank asked for.
        rank: usize,
        /// The largest allowed, `min(I₀I₁, I₀I₂, I₁I₂)`.
        max: usize,
    },
    /// A stopping tolerance or error bound that is negative, zero where it must be positive, or
    /// NaN.
    #[error("the tolerance must be a non-negative number (an error bound: positive), not {tol}")]
    Tolerance {
        /// The value given.
        tol: f64,
    },
    /// An entry weight that is negative, NaN or infinite.
    #[error("weight {index} is {value}: entry weights must be finite and non-negative")]
    Weight {
        /// The weight's index in row-major order.
        index: usize,
        /// The weight given.
        value: f64,
    },
    /// A noise level that is negative or not finite ([`planted`]).
    #[error("the noise level must be finite and non-negative, not {noise}")]
    Noise {
        /// The value given.
        noise: f64,
    },
    /// The SVD did not converge.
    #[error("the singular value decomposition did not converge")]
    Svd,
    /// The work space of a fit, or a tensor, is more than the memory available
    /// ([`zeroset_field_core::limits`]); the message names what, the amount and the limit.
    #[error("{0}")]
    Memory(String),
}

/// `(rows, columns)` for messages, `usize::MAX` (any) as "any".
fn dims((rows, columns): (usize, usize)) -> String {
    let show = |n: usize| {
        if n == usize::MAX {
            "any".to_owned()
        } else {
            n.to_string()
        }
    };
    format!("({} × {})", show(rows), show(columns))
}
