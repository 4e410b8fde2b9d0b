//! Neural implicit fields with a curvature loss (Jiang–Turk, paper 003 §3).
//!
//! A small multilayer perceptron `f_θ: Rᴰ → R` (`D` = 2 as in the paper, or 3) is trained so that
//! `f(xᵢ) ≈ zᵢ` at the constraint points while staying smooth: the loss is the paper's Eq. 11,
//!
//! ```text
//! E(θ) = Σᵢ (f(xᵢ) − zᵢ)²  +  (λ |Ω| / P) Σⱼ ‖∇²f(yⱼ)‖_F²,
//! ‖∇²f‖_F² = f_xx² + 2 f_xy² + f_yy²      (3-D: Σₖₗ (∂ₖ∂ₗ f)²),
//! ```
//!
//! the second sum a Monte-Carlo estimate of λ ∫_Ω ‖∇²f‖_F² (the thin-plate energy, Eq. 2) at
//! `P` points `yⱼ` drawn uniformly in the domain `Ω`. The paper assumes `|Ω| = 1`; zeroset
//! multiplies by the measure `|Ω|` (area or volume of the domain box) so that λ weighs the
//! integral itself for any box. Paper values: `P = 250`, `λ = 0.05`, two hidden layers of 32.
//!
//! **Sign convention.** The paper takes `z = +1` inside, `−1` outside and 0 on the curve.
//! zeroset's fields are negative inside: give inside points negative targets (−1) and outside
//! points positive ones (+1), as [`Variant`]'s example and `examples/neural_curve.rs` do.
//!
//! ## The net
//!
//! `f(x) = o · N((x − c)/h)` with `N(u) = w_out·σ(W_L ⋯ σ(W₁u + b₁) ⋯ + b_L) + b_out`,
//! widths configurable ([`Architecture`], default 32, 32) and a smooth activation
//! ([`Activation`]: `tanh`, the default, or softplus; ReLU would zero the curvature term).
//! The input map (centre `c`, scale `h`, the domain's centre and longest half-extent) and the
//! output scale `o` (1 unless [`NeuralField::transformed`]) are fixed, not trained.
//! Parameters are one flat vector, layer after layer:
//!
//! | block | size | layout |
//! |---|---|---|
//! | `W₁`, `b₁` | `w₁·D`, `w₁` | `W[j, k]` at `j + w₁ k` (column-major) |
//! | `W_l`, `b_l` (l = 2…L) | `w_l·w_{l−1}`, `w_l` | column-major |
//! | `w_out`, `b_out` | `w_L`, 1 | |
//!
//! ## How the loss and its gradient are computed
//!
//! No deep-learning framework: the loss needs `∇²f` inside it and then `∂/∂θ` of that (a
//! double backward), which is written out for this shape. The forward pass carries, for every
//! point that needs it, the value, the `D` input derivatives and the `D(D+1)/2` second
//! derivatives of every neuron (`1 + D + D(D+1)/2` columns per point, 6 in 2-D, 10 in 3-D), so a
//! hidden layer is one matrix product of `W_l` against all the columns of a chunk, followed by the
//! chain rule for the activation; the reverse pass runs the adjoint of each step (two products
//! per layer). The first layer's derivatives are known in closed form (no product), and the last
//! hidden layer carries only values and first derivatives: the output's Hessian is
//! `Σⱼ wⱼ σ''(aⱼ) ∇aⱼ∇aⱼᵀ + Σᵢ vᵢ ∇²hᵢ` with `v = W_Lᵀ(w ⊙ σ'(a))` and `h` the layer below, one
//! product of `W_Lᵀ` per point instead of `D(D+1)/2` of `W_L`. The products are faer's. Points
//! are processed in fixed chunks (64 points with derivatives, 256 without) in parallel, and the
//! chunks' gradients are added in chunk order: the result has the same bits for any number of
//! threads. Constraint points carry derivatives only when the curvature is evaluated at them.
//!
//! The domain `Ω` is given with [`NeuralFit::with_domain`]; by default it is the constraints'
//! bounding box grown by [`DOMAIN_MARGIN`] (5%) of its diagonal on every side.
//!
//! ## Training
//!
//! - **Optimiser**: Adam with PyTorch's arithmetic (bias-corrected; see [`NeuralParams`]):
//!   learning rate `1e-2`, `β₁ = 0.9`, `β₂ = 0.999`, `ε = 1e-8`, constant rate, 3000 steps.
//!   The paper gives none of these. Every step uses every constraint and every auxiliary point
//!   (full batch): the paper's shuffled mini-batches only matter for sets far larger than its
//!   60 constraints and 250 auxiliary points.
//! - **Initialisation**: Glorot (Xavier) uniform weights, zero biases ([`NeuralField::initial`]).
//! - **Auxiliary points**: drawn uniformly in `Ω` once, before the first step, and kept (the
//!   paper's fixed set of `P` points, shuffled with the constraints into its mini-batches);
//!   [`NeuralParams::resample_aux`] draws a new set at every step instead. [`auxiliary_points`]
//!   gives the sequence. The choice matters: with a fixed set the net can keep its curvature
//!   low at those 250 points and high between them — on the paper's curve the energy measured
//!   on a fine grid was 1,302 against 924 for λ = 0 (seed 0), while redrawn points bring it to
//!   97, at the price of a larger residual (0.64 against 0.44). `examples/neural_curve.rs`
//!   prints both.
//! - **Randomness**: ChaCha8 seeded with [`NeuralParams::seed`], one stream each for the
//!   initial weights (0), the auxiliary points (1) and the dropout masks (2). The same seed and
//!   input give the same field, bit for bit, on any number of threads.
//! - **Baselines** of the paper ([`Variant`]): λ = 0; the curvature term at the `N` constraint
//!   points instead (weight `λ|Ω|/N`); and dropout instead of curvature — every hidden
//!   activation is zeroed with probability [`DROPOUT_BASELINE_RATE`] = 0.1 at each step (the
//!   others scaled by `1/0.9`), with dropout off when the field is evaluated.
//!
//! ## The hidden layers as a learned basis
//!
//! For fixed hidden layers `f = Σⱼ cⱼ bⱼ` is linear in the output layer: [`HiddenBasis`] is that
//! [`Basis`](zeroset_field_core::basis::Basis), and [`NeuralField::refit_last_layer`] solves
//! the data term's least-squares problem over it with any
//! [`LeastSquaresSolver`](zeroset_field_core::lsq::LeastSquaresSolver), which never raises the
//! data term.
//!
//! ## What is guaranteed, and what is not
//!
//! Guaranteed: exact gradients and Hessians ([`NeuralField::jet`]), checked against finite
//! differences in the tests, as is the parameter gradient of the loss; determinism as above;
//! specific errors for bad input ([`NeuralError`]). Not guaranteed: that training reaches the
//! constraints — a gradient method on a non-convex loss gives no such promise (the paper says
//! so too); [`TrainReport::max_residual`] says how close it came.
//!
//! ```
//! use zeroset_bases::neural::{NeuralFit, NeuralParams};
//! use zeroset_field_core::field::ScalarField;
//! use zeroset_field_core::geometry::Aabb;
//!
//! // A circle of radius 0.5: 16 points on it (0), 8 inside at radius 0.25 (−1), 8 outside at
//! // radius 0.75 (+1).
//! let mut points = Vec::new();
//! let mut targets = Vec::new();
//! for k in 0..16 {
//!     let t = std::f64::consts::TAU * k as f64 / 16.0;
//!     for (r, z) in [(0.5, 0.0), (0.25, -1.0), (0.75, 1.0)] {
//!         if z == 0.0 || k % 2 == 0 {
//!             points.push([r * t.cos(), r * t.sin()]);
//!             targets.push(z);
//!         }
//!     }
//! }
//! let params = NeuralParams::default().with_steps(400).with_aux_points(100);
//! let fit = NeuralFit::new(params).with_domain(Aabb::new([-1.0, -1.0], [1.0, 1.0])?);
//! let trained = fit.fit(&points, &targets)?;
//! // λ trades the fit for smoothness: the constraints are met approximately.
//! assert!(trained.report.max_residual < 0.5, "{}", trained.report.max_residual);
//! assert!(trained.field.value(&[0.0, 0.0]) < 0.0 && trained.field.value(&[0.9, 0.9]) > 0.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod activation;
mod basis;
mod engine;
mod error;
mod field;
mod net;
mod train;

pub use activation::Activation;
pub use basis::{HiddenBasis, RefitReport};
pub use error::NeuralError;
pub use field::NeuralField;
pub use net::{Architecture, MAX_WIDTH};
pub use train::{
    CurvatureSites, DOMAIN_MARGIN, DROPOUT_BASELINE_RATE, MAX_AUX_POINTS, NeuralFit, NeuralParams,
    TrainProgress, TrainReport, Trained, Variant, auxiliary_points, to_unit_frame, unit_frame,
};

/// The random stream of the initial weights.
const STREAM_INIT: u64 = 0;
/// The random stream of the auxiliary points.
const STREAM_AUX: u64 = 1;
/// The random stream of the dropout masks.
const STREAM_DROPOUT: u64 = 2;

#[cfg(test)]
mod tests;
