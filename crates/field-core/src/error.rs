//! The error type of `zeroset-field-core`: geometry, grids, masks and point-cloud files.
//!
//! Least-squares solvers have their own error, [`SolveError`](crate::lsq::SolveError), because
//! it is the contract every solver crate shares.

use std::path::PathBuf;

/// Everything that can go wrong in field-core, with enough context to act on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A bounding box with a non-finite corner or `min > max` on some axis.
    #[error(
        "invalid bounding box on axis {axis}: min {min} and max {max} must be finite with min <= max"
    )]
    InvalidBounds {
        /// The axis (0 = x, 1 = y, 2 = z).
        axis: usize,
        /// The lower coordinate given.
        min: f64,
        /// The upper coordinate given.
        max: f64,
    },
    /// A grid with no cell (or, vertex-centred, fewer than two vertices) along some axis.
    #[error("grid needs at least {needed} samples along axis {axis}, got {got}")]
    GridTooSmall {
        /// The axis.
        axis: usize,
        /// The number of samples needed.
        needed: usize,
        /// The number given.
        got: usize,
    },
    /// A box mask that does not lie inside the grid's bounding box.
    #[error(
        "mask lies outside the bounding box on axis {axis}: mask [{lo}, {hi}], box [{min}, {max}]"
    )]
    MaskOutsideBox {
        /// The axis.
        axis: usize,
        /// The mask's lower coordinate.
        lo: f64,
        /// The mask's upper coordinate.
        hi: f64,
        /// The box's lower coordinate.
        min: f64,
        /// The box's upper coordinate.
        max: f64,
    },
    /// A box mask that contains no sample of the grid along some axis.
    #[error("mask [{lo}, {hi}] contains no grid sample along axis {axis}")]
    EmptyMask {
        /// The axis.
        axis: usize,
        /// The mask's lower coordinate.
        lo: f64,
        /// The mask's upper coordinate.
        hi: f64,
    },
    /// A mask given by grid indices that leaves the grid.
    #[error("mask index range {lo}..={hi} on axis {axis} leaves the grid of {len} samples")]
    MaskIndexOutOfRange {
        /// The axis.
        axis: usize,
        /// First index.
        lo: usize,
        /// Last index.
        hi: usize,
        /// Samples on that axis.
        len: usize,
    },
    /// Two arrays that must have matching shapes do not.
    #[error("shape mismatch for {what}: expected {expected}, got {got}")]
    ShapeMismatch {
        /// What was being matched.
        what: &'static str,
        /// The expected size.
        expected: usize,
        /// The size given.
        got: usize,
    },
    /// A point cloud with no points where at least one is needed.
    #[error("point cloud is empty")]
    EmptyCloud,
    /// A coordinate or normal component that is NaN or infinite.
    #[error(
        "{source_name}{}: record {record} has a non-finite {field} ({value})",
        line.map(|l| format!(":{l}")).unwrap_or_default()
    )]
    NonFinite {
        /// The file (or "input" for in-memory data).
        source_name: String,
        /// The record (0-based point index; for text files the 1-based line is in `line`).
        record: usize,
        /// The 1-based line in a text file, if any.
        line: Option<usize>,
        /// Which value: "x", "y", "z", "nx", "ny", "nz" (or "normal_x", ... where the file names
        /// them so), "azimuth", ...
        field: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A file whose format is not recognised from its extension or content.
    #[error("{}: unknown point-cloud format (expected .ply, .pcd, .las, .laz, .e57, .xyz, .xyzn, .txt, .pts, .asc, .pwn or .csv)", path.display())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// A value-constraint file (`.xyv`, `.xyzv`: `x y [z] value` per line) where a point cloud
    /// was expected.
    #[error("{}: a file of {dimension}-D value constraints ({} value per line), not a point cloud: `zeroset fit --method rbf` (or neural) interpolates it", path.display(), if *dimension == 2 { "x y" } else { "x y z" })]
    ValueFile {
        /// The file.
        path: PathBuf,
        /// 2 for `.xyv`, 3 for `.xyzv`.
        dimension: usize,
    },
    /// A compressed file (gzip, zip, bzip2, xz, zstd or 7-Zip archive), which zeroset does not
    /// unpack.
    #[error("{}: compressed with {compression}; zeroset reads the file inside: unpack it first ({hint})", path.display())]
    Compressed {
        /// The file.
        path: PathBuf,
        /// The compression's name (`gzip`, `zip`, …).
        compression: &'static str,
        /// The command that unpacks it, e.g. `gunzip -k scan.ply.gz`.
        hint: String,
    },
    /// A malformed file: what was wrong and where.
    #[error("{}{}: {reason}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// The 1-based line, for text formats.
        line: Option<usize>,
        /// What is wrong.
        reason: String,
    },
    /// A file that ends before all the records its header announces.
    #[error("{}: truncated: header announces {expected} {element} records, file holds {got}", path.display())]
    Truncated {
        /// The file.
        path: PathBuf,
        /// The element ("vertex", ...).
        element: String,
        /// Records announced.
        expected: usize,
        /// Records present (at most; the last may be partial).
        got: usize,
    },
    /// Columns 4–6 of an xyz file that do not look like unit normals: every value a whole
    /// number from 0 to 255 (RGB colours, `x y z r g b`), or a normal whose length lies outside
    /// [`NORMAL_LENGTHS`](crate::io::NORMAL_LENGTHS). Names the first line that shows it.
    #[error("{}", not_normals_message(path, *line, values, *colours))]
    NotNormals {
        /// The file.
        path: PathBuf,
        /// The 1-based line of the first record that shows it.
        line: usize,
        /// That record (0-based point index).
        record: usize,
        /// Its columns 4–6.
        values: [f64; 3],
        /// Whether the columns look like RGB colours (whole numbers from 0 to 255) rather than
        /// merely not unit length.
        colours: bool,
    },
    /// An E57 file in which some scans have normals and some do not, read with its normals
    /// (read the positions only, [`ReadOptions::positions_only`](crate::io::ReadOptions), to
    /// estimate normals for every scan).
    #[error(
        "{}: scans {} have normals and scans {} do not: a fit needs a normal at every point \
         (`zeroset normals` estimates them for every scan, and `zeroset reconstruct` does so \
         itself; or export the scans with normals alone)",
        path.display(),
        list(with),
        list(without)
    )]
    PartialNormals {
        /// The file.
        path: PathBuf,
        /// The scans (0-based) with normals.
        with: Vec<usize>,
        /// The scans without.
        without: Vec<usize>,
    },
    /// A PLY file without a required vertex property.
    #[error("{}: PLY element 'vertex' has no property '{property}'", path.display())]
    MissingProperty {
        /// The file.
        path: PathBuf,
        /// The property, e.g. "z".
        property: &'static str,
    },
    /// A CSV file whose header lacks a required column.
    #[error("{}: CSV header has no column '{column}' (header: {header})", path.display())]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column looked for.
        column: String,
        /// The header found.
        header: String,
    },
    /// An allocation the memory available cannot hold (or no allocation can), refused before it
    /// is made: names what needed it, how much and the limit
    /// ([`limits`](crate::limits)).
    #[error(transparent)]
    Memory(#[from] crate::memory::MemoryError),
    /// An allocation whose size in bytes overflows a 64-bit count.
    #[error(
        "{what}: {count} items of {bytes_each} bytes each overflow a 64-bit byte count: more \
         than any allocation can hold"
    )]
    SizeOverflow {
        /// What the allocation was for.
        what: String,
        /// The number of items asked for.
        count: u64,
        /// Bytes per item.
        bytes_each: u64,
    },
    /// A count announced by an input (a file header, a length field) that the rest of the input
    /// cannot hold: the input is corrupt or truncated, and nothing was allocated for it.
    #[error("{}", exceeds_input_message(what, *count, *min_bytes, *remaining))]
    ExceedsInput {
        /// What was counted ("level 2 cells", "RBF functionals").
        what: String,
        /// The count announced.
        count: u64,
        /// The fewest bytes one item takes in the input.
        min_bytes: u64,
        /// The bytes left in the input.
        remaining: u64,
    },
    /// A value of [`MEMORY_LIMIT_ENV`](crate::limits::MEMORY_LIMIT_ENV) that is not a size.
    #[error(
        "ZEROSET_MEMORY_LIMIT={value:?} is not a size: give bytes, or a number with a unit \
         (512MiB, 4GiB, 4G, 1.5GB)"
    )]
    InvalidMemoryLimit {
        /// The value found.
        value: String,
    },
}

/// The message of [`Error::ExceedsInput`].
fn exceeds_input_message(what: &str, count: u64, min_bytes: u64, remaining: u64) -> String {
    let need = match count.checked_mul(min_bytes) {
        Some(n) => format!("{n} bytes"),
        None => format!("{:.1e} bytes", count as f64 * min_bytes as f64),
    };
    format!(
        "{what}: {count} announced, which need at least {need} ({min_bytes} each), but only \
         {remaining} bytes remain: the input is corrupt or truncated"
    )
}

/// `0, 2, 5`: scan numbers for a message (the first 20, then how many more).
fn list(scans: &[usize]) -> String {
    let mut text: Vec<String> = scans.iter().take(20).map(ToString::to_string).collect();
    if scans.len() > 20 {
        text.push(format!("and {} more", scans.len() - 20));
    }
    text.join(", ")
}

/// The message of [`Error::NotNormals`]: what was found, and what to do.
fn not_normals_message(
    path: &std::path::Path,
    line: usize,
    values: &[f64; 3],
    colours: bool,
) -> String {
    let [a, b, c] = *values;
    let length = (a * a + b * b + c * c).sqrt();
    let (low, high) = crate::io::NORMAL_LENGTHS;
    let found = if colours {
        "every value in columns 4–6 is a whole number from 0 to 255, as in RGB colours (x y z r \
         g b)"
            .to_owned()
    } else {
        format!("the normal's length is {length:.4}, outside {low}–{high}")
    };
    format!(
        "{}:{line}: columns 4–6 ({a} {b} {c}) do not look like unit normals: {found}; zeroset \
         reads an xyz file's columns 4–6 as the normal nx ny nz, so keep only x y z if they are \
         colours or another attribute (`zeroset normals` then estimates normals from the \
         positions, and `zeroset reconstruct` does so itself), or scale them to unit length if \
         they are normals",
        path.display()
    )
}

/// Shorthand for results with field-core's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
