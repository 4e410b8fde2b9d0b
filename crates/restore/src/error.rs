//! What can go wrong in a restoration, with enough context to fix the call.

use zeroset_field_core::lsq::SolveError;
use zeroset_field_core::mask::Face;

/// The error type of `zeroset-restore`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RestoreError {
    /// A grid, mask or sample problem reported by field-core (mask outside the box, zero-width
    /// mask, non-finite sample, grid too small, …).
    #[error(transparent)]
    Field(#[from] zeroset_field_core::Error),
    /// The least-squares solver failed.
    #[error("least-squares solve failed: {0}")]
    Solve(#[from] SolveError),
    /// The field is NaN or infinite at a grid sample.
    #[error("the field is not finite at grid sample {index} (value {value})")]
    NonFiniteSample {
        /// The linear index of the sample (last axis fastest).
        index: usize,
        /// The value.
        value: f64,
    },
    /// The mask is the whole grid: nothing outside it is left to restore from.
    #[error("the mask covers the whole grid; restoration needs data outside the mask")]
    MaskCoversGrid,
    /// A face whose axis does not exist in this dimension.
    #[error("face axis {axis} does not exist in {dim}-D")]
    FaceAxisOutOfRange {
        /// The axis given.
        axis: usize,
        /// The dimension.
        dim: usize,
    },
    /// The Neumann face lies on the grid border: there is no cell beyond it to take the slope
    /// from.
    #[error(
        "the Neumann face {face} of the mask lies on the grid border; choose the face the \
         protrusion's base crosses, which must have grid cells beyond it"
    )]
    NeumannFaceOnBorder {
        /// The face, as `±x`, `±y`, `±z`.
        face: String,
    },
    /// After fixing the Neumann and border layers no unknown is left (the mask is one or two
    /// cells thick along some axis).
    #[error(
        "the mask leaves no unknown after its fixed layers on axis {axis} (extent {extent}); \
         make it at least {needed} cells thick there"
    )]
    NoUnknowns {
        /// The axis.
        axis: usize,
        /// The mask's extent on it.
        extent: usize,
        /// The extent needed.
        needed: usize,
    },
    /// α (the slope across the Neumann face) is NaN or infinite.
    #[error("alpha must be finite, got {0}")]
    InvalidAlpha(f64),
    /// A coarse resolution of zero, or larger than the mask, on some axis.
    #[error(
        "coarse resolution {coarse} on axis {axis} must be between 1 and the mask's extent \
         {extent} (grid cells)"
    )]
    InvalidCoarse {
        /// The axis.
        axis: usize,
        /// The coarse count given.
        coarse: usize,
        /// The mask's extent in grid cells on that axis.
        extent: usize,
    },
    /// The chosen solver cannot run in this configuration.
    #[error("{0}")]
    Unsupported(String),
}

/// Shorthand for results of this crate.
pub type Result<T, E = RestoreError> = std::result::Result<T, E>;

/// `+x`, `-z`, … for a face (axes beyond z are written `a3`, `a4`, …).
pub fn face_name(face: Face) -> String {
    let sign = match face.side {
        zeroset_field_core::mask::Side::Lower => '-',
        zeroset_field_core::mask::Side::Upper => '+',
    };
    match face.axis {
        0 => format!("{sign}x"),
        1 => format!("{sign}y"),
        2 => format!("{sign}z"),
        a => format!("{sign}a{a}"),
    }
}
