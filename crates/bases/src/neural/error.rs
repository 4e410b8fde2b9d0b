//! What can go wrong when building or training a neural field.

use zeroset_field_core::lsq::SolveError;

/// A neural fit that cannot be made, with the offending input named.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NeuralError {
    /// Training buffers (every point's activations through every layer) that would need more
    /// memory than is available: refused before anything is allocated.
    #[error(
        "{0}; use fewer or narrower layers, fewer auxiliary points or a subsample of the points"
    )]
    Memory(#[from] zeroset_field_core::memory::MemoryError),
    /// No constraint at all: there is nothing to fit.
    #[error("no constraints to fit (a neural field needs at least one point with a target value)")]
    NoConstraints,
    /// Points and targets of different lengths.
    #[error("{points} constraint points but {targets} target values")]
    LengthMismatch {
        /// Points given.
        points: usize,
        /// Targets given.
        targets: usize,
    },
    /// A NaN or infinite coordinate or target.
    #[error("constraint {index}: non-finite {what} ({value})")]
    NonFinite {
        /// The constraint index.
        index: usize,
        /// `"coordinate"` or `"target"`.
        what: &'static str,
        /// The value found.
        value: f64,
    },
    /// A hidden layer of width 0, or no hidden layer at all.
    #[error("invalid layer widths {widths:?}: {reason}")]
    InvalidWidths {
        /// The widths given.
        widths: Vec<usize>,
        /// What is wrong.
        reason: &'static str,
    },
    /// A parameter outside its range (λ < 0, a learning rate ≤ 0, a dropout rate outside
    /// `[0, 1)`, …).
    #[error("invalid {name} {value}: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// Curvature at auxiliary points was asked for with no auxiliary point.
    #[error(
        "λ = {lambda} > 0 with curvature at auxiliary points needs at least one auxiliary point (P = 0)"
    )]
    NoAuxiliaryPoints {
        /// λ.
        lambda: f64,
    },
    /// A domain of zero measure (a flat box) where the auxiliary points must be drawn.
    #[error(
        "the domain {min:?} – {max:?} has zero extent on some axis; auxiliary points need a box of positive measure"
    )]
    FlatDomain {
        /// Its lower corner.
        min: Vec<f64>,
        /// Its upper corner.
        max: Vec<f64>,
    },
    /// A parameter vector of the wrong length for the architecture.
    #[error("{got} parameters for an architecture that has {expected}")]
    ParameterCount {
        /// The count the widths imply.
        expected: usize,
        /// The count given.
        got: usize,
    },
    /// Training produced a NaN or infinite loss (a learning rate too large, usually).
    #[error("training diverged at step {step}: the loss is {loss} (try a smaller learning rate)")]
    Diverged {
        /// The step (1-based).
        step: usize,
        /// The loss seen.
        loss: f64,
    },
    /// The progress callback asked to stop.
    #[error("cancelled after {steps} steps")]
    Cancelled {
        /// Steps completed.
        steps: usize,
    },
    /// The last-layer least-squares refit failed.
    #[error("refitting the last layer: {0}")]
    Solve(#[from] SolveError),
}
