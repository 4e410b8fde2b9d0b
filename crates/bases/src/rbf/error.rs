//! What can go wrong when fitting an RBF field.

use zeroset_field_core::lsq::SolveError;
use zeroset_field_core::memory::MemoryError;

/// An RBF fit that cannot be made, with the offending input named.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RbfError {
    /// No constraint at all.
    #[error("no constraints to fit")]
    Empty,
    /// A NaN or infinite coordinate, value or gradient.
    #[error("constraint {index}: non-finite {what} ({value})")]
    NonFinite {
        /// The constraint (or input point) index.
        index: usize,
        /// What was not finite: "coordinate", "value", "gradient", "normal".
        what: &'static str,
        /// The value found.
        value: f64,
    },
    /// A normal of (near) zero length where one is needed.
    #[error("point {index}: zero-length normal")]
    ZeroNormal {
        /// The point index.
        index: usize,
    },
    /// Two constraints of the same kind at the same point: the system is singular.
    #[error(
        "constraints {first} and {second} are at the same point {point:?} (duplicate points make the system singular)"
    )]
    Duplicate {
        /// The first constraint's index.
        first: usize,
        /// The second constraint's index.
        second: usize,
        /// The shared point.
        point: Vec<f64>,
    },
    /// Two input points at one place (within [`MERGE_DISTANCE`](super::MERGE_DISTANCE) of
    /// the diagonal) with opposite normals, given as gradients
    /// ([`Constraints::hermite`](super::Constraints::hermite); off-surface constraints fit
    /// them as two sheets touching).
    #[error(
        "points {first} and {second} are at the same place {point:?} with opposite normals \
         (dot product {dot:.3}): the gradient there cannot be both (two sheets touching, or a \
         flipped normal); off-surface constraints (not Hermite) fit such a place"
    )]
    ConflictingDuplicates {
        /// The first point's index.
        first: usize,
        /// The second point's index.
        second: usize,
        /// The first point.
        point: Vec<f64>,
        /// The unit normals' dot product.
        dot: f64,
    },
    /// Two value constraints at one place (within [`MERGE_DISTANCE`](super::MERGE_DISTANCE)
    /// of the diagonal) with different values.
    #[error(
        "value constraints {first} and {second} are at the same place {point:?} with different \
         values ({} and {}): an interpolant cannot take both", values.0, values.1
    )]
    ConflictingValues {
        /// The first constraint's index.
        first: usize,
        /// The second constraint's index.
        second: usize,
        /// The first constraint's point.
        point: Vec<f64>,
        /// Their values.
        values: (f64, f64),
    },
    /// The constraints do not determine the linear polynomial: too few points, or all of
    /// them on one plane (3-D) or line (2-D).
    #[error("the constraints cannot determine a linear polynomial: {detail}")]
    Degenerate {
        /// What is degenerate, naming points.
        detail: String,
    },
    /// A kernel that is not twice differentiable at 0 asked to take gradient constraints.
    #[error(
        "kernel {kernel} is not twice differentiable at 0: gradient (Hermite) constraints need one that is, such as r3"
    )]
    KernelNotSmooth {
        /// The kernel's name.
        kernel: String,
    },
    /// A fixed off-surface offset that reaches another part of the surface.
    #[error(
        "off-surface offset {eps} at point {index} crosses the surface: the nearest input point to the offset point is {nearest}, not {index} (use a smaller offset or --offset auto)"
    )]
    OffsetCrossesSurface {
        /// The point whose offset point is nearer another input point.
        index: usize,
        /// The offset.
        eps: f64,
        /// The input point nearest the offset point.
        nearest: usize,
    },
    /// An offset that is not finite and positive.
    #[error("off-surface offset must be finite and > 0, got {0}")]
    InvalidOffset(f64),
    /// The (projected) system is not positive definite or the factorisation failed.
    #[error("the RBF system is singular or indefinite: {0}")]
    Singular(String),
    /// An iterative or general solve failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// A dense solve (or a fallback to one) that needs more memory than the limit
    /// ([`RbfFit::with_memory_limit`](super::RbfFit::with_memory_limit), by default what the
    /// machine has available): refused before anything is allocated.
    #[error(
        "{0}; fit a subset of the points, or a field that needs no dense system (kernel r or wendland with value constraints, or MRAS)"
    )]
    Memory(#[from] MemoryError),
    /// A constraint index outside the fit.
    #[error("{what}: {got} is out of range (at most {limit})")]
    OutOfRange {
        /// What was asked for.
        what: &'static str,
        /// The value given.
        got: usize,
        /// The largest allowed.
        limit: usize,
    },
}
