//! What can go wrong when extracting a contour or writing a preview, with enough context to fix
//! the call.

/// The error type of `zeroset-mesh`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// A grid, shape or file problem reported by field-core: a grid with fewer than two samples
    /// on an axis ([`GridTooSmall`](zeroset_field_core::Error::GridTooSmall)), a sample array of
    /// the wrong length ([`ShapeMismatch`](zeroset_field_core::Error::ShapeMismatch)), a file
    /// that could not be written ([`Io`](zeroset_field_core::Error::Io)).
    #[error(transparent)]
    Field(#[from] zeroset_field_core::Error),
    /// A sample (given, or returned by the field) is NaN or infinite.
    #[error(
        "sample {index} (grid index {grid_index:?}, position {position:?}) is not finite: {value}"
    )]
    NonFiniteSample {
        /// The linear index of the sample (last axis fastest, as
        /// [`Grid::linear_index`](zeroset_field_core::Grid::linear_index)).
        index: usize,
        /// The multi-index of the sample.
        grid_index: Vec<usize>,
        /// Where the sample sits.
        position: Vec<f64>,
        /// The value found.
        value: f64,
    },
    /// Points that cannot support a trim ([`crate::trim`]): too few, all repeated, or a reach
    /// that is not finite and positive.
    #[error("cannot trim to the scan: {detail}")]
    Trim {
        /// What is wrong.
        detail: String,
    },
    /// A mesh whose triangles refer to missing vertices, or with non-finite coordinates.
    #[error("invalid mesh: {detail}")]
    InvalidMesh {
        /// What is wrong, naming the element.
        detail: String,
    },
    /// The level to contour is NaN or infinite.
    #[error("the contour level must be finite, got {level}")]
    NonFiniteLevel {
        /// The level given.
        level: f64,
    },
    /// An SVG colour that is not `#rgb`, `#rgba`, `#rrggbb`, `#rrggbbaa` or a name of ASCII
    /// letters (`steelblue`, `none`).
    #[error(
        "invalid SVG colour {color:?}: expected #rgb, #rgba, #rrggbb, #rrggbbaa or a colour name \
         of 1 to 32 ASCII letters"
    )]
    InvalidColor {
        /// The colour given.
        color: String,
    },
    /// A stroke width, point radius or image width that is not finite and positive.
    #[error("{what} must be finite and positive, got {value}")]
    InvalidSize {
        /// Which size: "stroke width", "point radius", "image width".
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// The certainty margin of the signed marching cubes is negative, NaN or infinite.
    #[error(
        "the signed marching cubes margin must be finite and at least 0 (a bound on the \
         coarse field's error), got {margin}"
    )]
    InvalidMargin {
        /// The margin given.
        margin: f64,
    },
    /// Plot bounds with zero extent on an axis: there is no scale that maps them to pixels.
    #[error(
        "plot bounds are flat on axis {axis} ([{min}, {max}]); an SVG plot needs a box with \
         positive extent"
    )]
    FlatBounds {
        /// The axis (0 = x, 1 = y).
        axis: usize,
        /// The lower coordinate.
        min: f64,
        /// The upper coordinate.
        max: f64,
    },
    /// A point or polyline vertex to be drawn has a NaN or infinite coordinate.
    #[error("{} has a non-finite coordinate {point:?}", describe_point(*.polyline, *.index))]
    NonFinitePoint {
        /// The polyline (0-based, within the call) holding the vertex, or `None` for a point.
        polyline: Option<usize>,
        /// The vertex or point (0-based).
        index: usize,
        /// Its coordinates.
        point: [f64; 2],
    },
    /// A sampling grid with more samples than can be indexed (a voxel far too small for its
    /// box).
    #[error(
        "a grid of voxel {voxel:e} over a box of extent {extent:?} has more than {limit} samples; \
         choose a larger voxel"
    )]
    GridTooLarge {
        /// The voxel edge asked for.
        voxel: f64,
        /// The extent of the box (margin included), per axis.
        extent: Vec<f64>,
        /// The most samples allowed.
        limit: u64,
    },
    /// A mesh file (PLY) that cannot be read: a header or record problem, naming the file and
    /// the place (`header line 4`, `line 17 (face 3)`, `vertex 5 (byte 120)`).
    #[error("{}: {place}: {detail}", path.display())]
    Ply {
        /// The file (or the name given for in-memory data).
        path: std::path::PathBuf,
        /// Where: a header line, or a record with its line (ASCII) or byte offset (binary).
        place: String,
        /// What is wrong.
        detail: String,
    },
    /// A PLY file that ends before all the records its header announces.
    #[error(
        "{}: truncated: the file ends in {element} record {record} (0-based) of the {expected} \
         the header announces",
        path.display()
    )]
    PlyTruncated {
        /// The file (or the name given for in-memory data).
        path: std::path::PathBuf,
        /// The element being read (`vertex`, `face`, ...).
        element: String,
        /// The first record (0-based) that is missing or incomplete.
        record: usize,
        /// The number of records announced.
        expected: usize,
    },
    /// An OBJ, STL or OFF mesh file that cannot be read: the file, its format and the place
    /// (`line 12`, `triangle 7 (byte 434)`), and what is wrong there.
    #[error("{}: {format} {place}: {detail}", path.display())]
    Malformed {
        /// The file (or the name given for in-memory data).
        path: std::path::PathBuf,
        /// `"OBJ"`, `"STL"` or `"OFF"`.
        format: &'static str,
        /// Where: a line, or a triangle with its byte offset.
        place: String,
        /// What is wrong.
        detail: String,
    },
    /// A file, or a feature of it, that this crate does not handle (not PLY, an unknown PLY
    /// encoding, a mesh too large for the output format).
    #[error("{}: unsupported format: {detail}", path.display())]
    UnsupportedFormat {
        /// The file (or the name given for in-memory data).
        path: std::path::PathBuf,
        /// What is not supported.
        detail: String,
    },
    /// A preview image size outside `1..=max` pixels.
    #[error("image {what} must be between 1 and {max} pixels, got {value}")]
    ImageSize {
        /// Which size: "width", "height", "slice resolution".
        what: &'static str,
        /// The value given.
        value: usize,
        /// The largest size allowed.
        max: usize,
    },
    /// A mesh with no triangle was given where something must be drawn.
    #[error("the mesh has no triangle: there is nothing to render")]
    EmptyMesh,
    /// A slice that cannot be drawn: an axis other than 0, 1, 2, a non-finite position, or a
    /// box with zero extent across the slice.
    #[error("invalid slice (axis {axis}, position {position}): {detail}")]
    InvalidSlice {
        /// The axis normal to the slice.
        axis: usize,
        /// Where the slice cuts that axis.
        position: f64,
        /// What is wrong.
        detail: String,
    },
}

/// "vertex 3 of polyline 1" or "point 3".
fn describe_point(polyline: Option<usize>, index: usize) -> String {
    match polyline {
        Some(p) => format!("vertex {index} of polyline {p}"),
        None => format!("point {index}"),
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = MeshError> = std::result::Result<T, E>;
