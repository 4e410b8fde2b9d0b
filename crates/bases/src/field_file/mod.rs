//! The zeroset field file (`.zsf`): a B-spline, RBF, neural or MRAS field, versioned and
//! checksummed.
//!
//! A restored or fitted field is saved so that the next command (restore again, mesh, …) can
//! load it bit for bit. All numbers are little-endian; `f64` values are stored as their IEEE
//! bits, so a field read back evaluates bit for bit as the one written.
//!
//! # Version 2 (written by this build)
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `ZSFIELD\0` |
//! | 4 | format version (`u32`, 2) |
//! | 4 | dimension `D` (`u32`, 2 or 3) |
//! | 8 | kind tag, ASCII padded with NULs: `bspline`, `rbf`, `neural` or `mras` |
//! | 4 | metadata length `m` (`u32`) |
//! | 8 | payload length `p` (`u64`) |
//! | m | metadata: UTF-8 `key=value` lines (`created-by`, `kind`, `dimension`, `kernel`, …); informative only |
//! | p | payload (below) |
//! | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! Each kind's payload is laid out in its own submodule of this one (`bspline.rs`, `rbf.rs`,
//! `neural.rs`, `mras.rs`), beside its encoder and decoder.
//!
//! # Version 1 (still read)
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `ZSFIELD\0` |
//! | 4 | format version (`u32`, 1) |
//! | 4 | dimension `D` (2 or 3) |
//! | … | the `bspline` payload (in `bspline.rs`) |
//! | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! Writes are atomic (temporary file + rename). Reads check the magic, version, sizes,
//! checksum, kind and values and say what is wrong ([`FieldFileError`]; [`read_field`] and
//! [`decode`] convert it into the crate-wide [`Error`] for compatibility).
//! [`read_field`] reads B-spline fields only; [`read_any_field`] reads every kind.
//!
//! ```
//! use zeroset_bases::bspline::{BSplineField, Degree};
//! use zeroset_bases::field_file::{read_field, write_field};
//! use zeroset_field_core::geometry::Aabb;
//! use zeroset_field_core::grid::Grid;
//!
//! let grid = Grid::cell_centered(Aabb::centered_cube(1.0)?, [4, 5, 6])?;
//! let samples = (0..grid.len()).map(|i| i as f64 * 0.1).collect();
//! let field = BSplineField::interpolate(grid, samples, Degree::Quadratic)?;
//! let dir = std::env::temp_dir().join(format!("zsf-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("field.zsf");
//! write_field(&path, &field)?;
//! let back = read_field::<3>(&path)?;
//! assert_eq!(back.coefficients(), field.coefficients());
//! # std::fs::remove_dir_all(&dir).unwrap();
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```
//!
//! An RBF field goes through [`write_rbf_field`] and comes back from [`read_any_field`] as
//! [`AnyField::Rbf`], a [`ScalarField`] like the field written; a neural field goes through
//! [`write_neural_field`] and comes back as [`AnyField::Neural`].

use std::path::{Path, PathBuf};

use zeroset_field_core::Error;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::io::write_atomic;

use crate::bspline::BSplineField;
use crate::mras::MrasField;
use crate::neural::NeuralField;
use crate::rbf::RbfField;

mod bspline;
mod mras;
mod neural;
mod rbf;

pub use bspline::encode;
pub use mras::encode_mras;
pub use neural::encode_neural;
pub use rbf::{RbfAny, StoredKernel, encode_rbf};

/// The first 8 bytes of every field file.
pub const MAGIC: &[u8; 8] = b"ZSFIELD\0";
/// The format version this build writes (it reads this and every older version).
pub const VERSION: u32 = 2;

/// The kind tag of a B-spline field.
pub const KIND_BSPLINE: &str = "bspline";
/// The kind tag of an RBF field.
pub const KIND_RBF: &str = "rbf";
/// The kind tag of a neural field.
pub const KIND_NEURAL: &str = "neural";
/// The kind tag of a multilevel rational algebraic spline (MRAS) field.
pub const KIND_MRAS: &str = "mras";

/// Bytes before the metadata in a version-2 file.
const V2_HEADER: usize = 36;

/// What is wrong with a field file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FieldFileError {
    /// The file cannot be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file does not start with [`MAGIC`].
    #[error("{}: not a zeroset field file (bad magic)", path.display())]
    BadMagic {
        /// The file.
        path: PathBuf,
    },
    /// The file is shorter than its header announces.
    #[error("{}: truncated: {got} bytes where {expected} are needed", path.display())]
    Truncated {
        /// The file.
        path: PathBuf,
        /// The bytes needed.
        expected: usize,
        /// The bytes present.
        got: usize,
    },
    /// A format version newer than this build reads.
    #[error(
        "{}: field file version {found}; this build reads versions 1 to {supported} (a newer zeroset wrote it)",
        path.display()
    )]
    NewerVersion {
        /// The file.
        path: PathBuf,
        /// The version in the file.
        found: u32,
        /// The newest version this build reads.
        supported: u32,
    },
    /// The stored checksum does not match the contents.
    #[error(
        "{}: checksum mismatch (stored {stored:08x}, computed {computed:08x}): the file is corrupt",
        path.display()
    )]
    Checksum {
        /// The file.
        path: PathBuf,
        /// The CRC-32 stored.
        stored: u32,
        /// The CRC-32 of the contents.
        computed: u32,
    },
    /// A kind tag other than `bspline`, `rbf` and `neural`.
    #[error("{}: unknown field kind {kind:?} (this build reads \"bspline\", \"rbf\" and \"neural\")", path.display())]
    UnknownKind {
        /// The file.
        path: PathBuf,
        /// The tag found.
        kind: String,
    },
    /// A field of another dimension than asked for.
    #[error("{}: a {found}-D field, expected {expected}-D", path.display())]
    WrongDimension {
        /// The file.
        path: PathBuf,
        /// The dimension in the file.
        found: u32,
        /// The dimension asked for.
        expected: usize,
    },
    /// A B-spline field was asked for ([`read_field`]) but the file holds an RBF field.
    #[error(
        "{}: this file holds an RBF field (kernel {kernel}), not a B-spline field",
        path.display()
    )]
    HoldsRbf {
        /// The file.
        path: PathBuf,
        /// The RBF kernel's tag.
        kernel: String,
    },
    /// A B-spline field was asked for ([`read_field`]) but the file holds a neural field.
    #[error(
        "{}: this file holds a neural field (hidden widths {widths:?}), not a B-spline field",
        path.display()
    )]
    HoldsNeural {
        /// The file.
        path: PathBuf,
        /// The hidden widths.
        widths: Vec<usize>,
    },
    /// A B-spline field was asked for ([`read_field`]) but the file holds an MRAS field.
    #[error(
        "{}: this file holds an MRAS field ({levels} levels), not a B-spline field",
        path.display()
    )]
    HoldsMras {
        /// The file.
        path: PathBuf,
        /// The number of levels.
        levels: usize,
    },
    /// An RBF kernel this build does not know.
    #[error(
        "{}: unknown RBF kernel {kernel:?} (this build reads \"r\", \"r3\", \"tps\" and \"wendland\")",
        path.display()
    )]
    UnknownKernel {
        /// The file.
        path: PathBuf,
        /// The tag found.
        kernel: String,
    },
    /// Any other inconsistency in the contents.
    #[error("{}: {reason}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A count in the file (cells, centres, coefficients, layers) that the bytes after it cannot
    /// hold, or whose values would need more memory than is available: refused before
    /// anything is allocated for it ([`limits`](zeroset_field_core::limits)).
    #[error("{}: {source}", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// [`Error::ExceedsInput`], [`Error::Memory`] or [`Error::SizeOverflow`].
        #[source]
        source: Error,
    },
    /// The contents do not make a valid field (grid, bounds, coefficients).
    #[error("{}: {source}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Why the field is invalid.
        #[source]
        source: Error,
    },
}

impl FieldFileError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. }
            | Self::BadMagic { path }
            | Self::Truncated { path, .. }
            | Self::NewerVersion { path, .. }
            | Self::Checksum { path, .. }
            | Self::UnknownKind { path, .. }
            | Self::WrongDimension { path, .. }
            | Self::HoldsRbf { path, .. }
            | Self::HoldsNeural { path, .. }
            | Self::HoldsMras { path, .. }
            | Self::UnknownKernel { path, .. }
            | Self::Malformed { path, .. }
            | Self::TooLarge { path, .. }
            | Self::Invalid { path, .. } => path,
        }
    }
}

impl From<FieldFileError> for Error {
    fn from(e: FieldFileError) -> Self {
        match e {
            FieldFileError::Io { path, source } => Error::Io { path, source },
            FieldFileError::Truncated {
                path,
                expected,
                got,
            } => Error::Truncated {
                path,
                element: "byte".into(),
                expected,
                got,
            },
            FieldFileError::Invalid { source, .. } => source,
            other => {
                let path = other.path().to_owned();
                let full = other.to_string();
                let prefix = format!("{}: ", path.display());
                let reason = full.strip_prefix(&prefix).unwrap_or(&full).to_string();
                Error::Malformed {
                    path,
                    line: None,
                    reason,
                }
            }
        }
    }
}

/// A field of any kind, as read by [`read_any_field`].
#[derive(Debug, Clone)]
pub enum AnyField<const D: usize> {
    /// A B-spline field.
    BSpline(BSplineField<D>),
    /// An RBF field.
    Rbf(RbfAny<D>),
    /// A neural field.
    Neural(NeuralField<D>),
    /// A multilevel rational algebraic spline (MRAS) field.
    Mras(MrasField<D>),
}

macro_rules! each_field {
    ($self:expr, $f:ident => $body:expr) => {
        match $self {
            AnyField::BSpline($f) => $body,
            AnyField::Rbf($f) => $body,
            AnyField::Neural($f) => $body,
            AnyField::Mras($f) => $body,
        }
    };
}

impl<const D: usize> AnyField<D> {
    /// Whether a mesh of the field needs finer voxels than the general class of the l0 rule by
    /// default (`zeroset mesh`, `zeroset.mesh`): an MRAS field is fitted to a scan with a
    /// target of 1e-3 of its diagonal by default (its mean distance is below that, its
    /// largest above where cells hold too few points to split), and the bunny's meshed at
    /// general detail (4.3 mm voxels)
    /// leaves the points 2.9× farther from the mesh on average (mean 1.1e-3 of the diagonal,
    /// max 1.3e-2) than at fine (1.3 mm: 3.8e-4, max 4.5e-3, about as close as the field
    /// itself), at about a second to mesh on 2 threads.
    pub fn wants_fine_mesh(&self) -> bool {
        matches!(self, AnyField::Mras(_))
    }

    /// The field in words: `Quadratic B-spline`, `RBF field (kernel r, 600 centres)`, `neural
    /// field (MLP 3 → 32 → 32 → 1, tanh)`, `MRAS field (4 levels, 512 cells, 384847 numbers)`.
    pub fn describe(&self) -> String {
        match self {
            AnyField::BSpline(f) => format!("{:?} B-spline", f.degree()),
            AnyField::Rbf(f) => format!(
                "RBF field (kernel {}, {} centres)",
                f.kernel_tag(),
                f.num_centres()
            ),
            AnyField::Neural(f) => format!("neural field ({})", f.network()),
            AnyField::Mras(f) => format!(
                "MRAS field ({} levels, {} cells, {} numbers)",
                f.levels().len(),
                f.levels().iter().map(|l| l.cells().len()).sum::<usize>(),
                f.storage()
            ),
        }
    }

    /// The kind tag: [`KIND_BSPLINE`], [`KIND_RBF`], [`KIND_NEURAL`] or [`KIND_MRAS`].
    pub fn kind(&self) -> &'static str {
        match self {
            Self::BSpline(_) => KIND_BSPLINE,
            Self::Rbf(_) => KIND_RBF,
            Self::Neural(_) => KIND_NEURAL,
            Self::Mras(_) => KIND_MRAS,
        }
    }

    /// The B-spline field, if it is one.
    pub fn into_bspline(self) -> Option<BSplineField<D>> {
        match self {
            Self::BSpline(f) => Some(f),
            _ => None,
        }
    }

    /// The RBF field, if it is one.
    pub fn into_rbf(self) -> Option<RbfAny<D>> {
        match self {
            Self::Rbf(f) => Some(f),
            _ => None,
        }
    }

    /// The neural field, if it is one.
    pub fn into_neural(self) -> Option<NeuralField<D>> {
        match self {
            Self::Neural(f) => Some(f),
            _ => None,
        }
    }

    /// The MRAS field, if it is one.
    pub fn into_mras(self) -> Option<MrasField<D>> {
        match self {
            Self::Mras(f) => Some(f),
            _ => None,
        }
    }
}

impl<const D: usize> ScalarField<D> for AnyField<D> {
    fn value(&self, p: &Point<D>) -> f64 {
        each_field!(self, f => f.value(p))
    }
    fn gradient(&self, p: &Point<D>) -> Point<D> {
        each_field!(self, f => f.gradient(p))
    }
    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        each_field!(self, f => f.values(points, out))
    }
    fn bounds(&self) -> Option<Aabb<D>> {
        each_field!(self, f => ScalarField::bounds(f))
    }
    fn value_range(&self, region: &Aabb<D>) -> Option<[f64; 2]> {
        each_field!(self, f => f.value_range(region))
    }
}

/// The bytes of the field file of `field`, whatever its kind: what [`write_any_field`] writes,
/// and what [`decode_any`] reads back bit for bit (to keep a field in memory or send it).
pub fn encode_any<const D: usize>(field: &AnyField<D>) -> Vec<u8> {
    match field {
        AnyField::BSpline(f) => encode(f),
        AnyField::Rbf(r) => rbf::encode_any(r),
        AnyField::Neural(f) => encode_neural(f),
        AnyField::Mras(f) => encode_mras(f),
    }
}

/// The body of a version-2 payload of `kind`; `short` is the error for running out.
///
/// The one place a kind tag is matched on read: a new kind adds its arm here.
fn decode_body<const D: usize>(
    kind: &str,
    c: &mut Cursor<'_>,
    path: &Path,
    short: impl Fn() -> FieldFileError,
) -> Result<AnyField<D>, FieldFileError> {
    Ok(match kind {
        KIND_BSPLINE => AnyField::BSpline(bspline::bspline_body(c, path, short)?),
        KIND_RBF => AnyField::Rbf(rbf::rbf_body(c, path, short)?),
        KIND_NEURAL => AnyField::Neural(neural::neural_body(c, path, short)?),
        KIND_MRAS => AnyField::Mras(mras::mras_body(c, path, short)?),
        _ => {
            return Err(FieldFileError::UnknownKind {
                path: path.to_owned(),
                kind: kind.to_owned(),
            });
        }
    })
}

/// Whether `path` starts with the field-file magic (unreadable files are not field files).
pub fn is_field_file(path: impl AsRef<Path>) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .map(|()| &head == MAGIC)
        .unwrap_or(false)
}

/// Writes the B-spline `field` to `path` atomically (format version [`VERSION`]).
///
/// # Errors
/// [`Error::Io`] naming `path`.
pub fn write_field<const D: usize>(
    path: impl AsRef<Path>,
    field: &BSplineField<D>,
) -> Result<(), Error> {
    let bytes = encode(field);
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes the RBF `field` to `path` atomically (format version [`VERSION`]).
///
/// # Errors
/// [`Error::Io`] naming `path`.
pub fn write_rbf_field<K: StoredKernel, const D: usize>(
    path: impl AsRef<Path>,
    field: &RbfField<K, D>,
) -> Result<(), Error> {
    let bytes = encode_rbf(field);
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes the neural `field` to `path` atomically (format version [`VERSION`]).
///
/// # Errors
/// [`Error::Io`] naming `path`.
pub fn write_neural_field<const D: usize>(
    path: impl AsRef<Path>,
    field: &NeuralField<D>,
) -> Result<(), Error> {
    let bytes = encode_neural(field);
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes the MRAS `field` to `path` atomically (format version [`VERSION`]).
///
/// # Errors
/// [`Error::Io`] naming `path`.
pub fn write_mras_field<const D: usize>(
    path: impl AsRef<Path>,
    field: &MrasField<D>,
) -> Result<(), Error> {
    let bytes = encode_mras(field);
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes a field of any kind to `path` atomically.
///
/// # Errors
/// [`Error::Io`] naming `path`.
pub fn write_any_field<const D: usize>(
    path: impl AsRef<Path>,
    field: &AnyField<D>,
) -> Result<(), Error> {
    let bytes = encode_any(field);
    write_atomic(path, |w| w.write_all(&bytes))
}

fn put_f64s<'a>(out: &mut Vec<u8>, values: impl IntoIterator<Item = &'a f64>) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Frames a version-2 file around `payload`.
fn frame(dim: usize, kind: &str, metadata: &[(&str, String)], payload: &[u8]) -> Vec<u8> {
    let mut meta = String::new();
    meta.push_str(&format!(
        "created-by=zeroset-bases {}\n",
        env!("CARGO_PKG_VERSION")
    ));
    meta.push_str(&format!("kind={kind}\ndimension={dim}\n"));
    for (k, v) in metadata {
        meta.push_str(&format!("{k}={v}\n"));
    }
    let mut tag = [0u8; 8];
    tag[..kind.len()].copy_from_slice(kind.as_bytes());
    let mut out = Vec::with_capacity(V2_HEADER + meta.len() + payload.len() + 4);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(dim as u32).to_le_bytes());
    out.extend_from_slice(&tag);
    out.extend_from_slice(&(meta.len() as u32).to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(meta.as_bytes());
    out.extend_from_slice(payload);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, FieldFileError> {
    std::fs::read(path).map_err(|source| FieldFileError::Io {
        path: path.to_owned(),
        source,
    })
}

/// Reads a `D`-dimensional B-spline field file (any version).
///
/// # Errors
/// [`Error::Io`] if the file cannot be read; [`Error::Truncated`] for a file shorter than its
/// header announces; [`Error::Malformed`] for a wrong magic, a newer version, an unknown kind
/// or code, a dimension other than `D`, a checksum mismatch, a non-finite value, or an RBF
/// field ("this file holds an RBF field"). [`read_any_field`] gives the specific
/// [`FieldFileError`].
pub fn read_field<const D: usize>(path: impl AsRef<Path>) -> Result<BSplineField<D>, Error> {
    let path = path.as_ref();
    let bytes = read_bytes(path)?;
    decode(&bytes, path)
}

/// Parses the bytes of a B-spline field file; `path` is only used in error messages.
///
/// # Errors
/// As [`read_field`].
pub fn decode<const D: usize>(bytes: &[u8], path: &Path) -> Result<BSplineField<D>, Error> {
    match decode_any(bytes, path)? {
        AnyField::BSpline(f) => Ok(f),
        AnyField::Rbf(r) => Err(FieldFileError::HoldsRbf {
            path: path.to_owned(),
            kernel: r.kernel_tag().to_string(),
        }
        .into()),
        AnyField::Neural(n) => Err(FieldFileError::HoldsNeural {
            path: path.to_owned(),
            widths: n.architecture().widths().to_vec(),
        }
        .into()),
        AnyField::Mras(m) => Err(FieldFileError::HoldsMras {
            path: path.to_owned(),
            levels: m.levels().len(),
        }
        .into()),
    }
}

/// Reads a `D`-dimensional field file of any kind (any version).
///
/// # Errors
/// The [`FieldFileError`] saying what is wrong.
pub fn read_any_field<const D: usize>(
    path: impl AsRef<Path>,
) -> Result<AnyField<D>, FieldFileError> {
    let path = path.as_ref();
    let bytes = read_bytes(path)?;
    decode_any(&bytes, path)
}

/// The metadata lines of a field file as `(key, value)` pairs (empty for version 1).
///
/// # Errors
/// As [`read_any_field`], for the frame (magic, version, sizes, checksum).
pub fn read_metadata(path: impl AsRef<Path>) -> Result<Vec<(String, String)>, FieldFileError> {
    let path = path.as_ref();
    let bytes = read_bytes(path)?;
    let version = check_head(&bytes, path)?;
    if version == 1 {
        return Ok(Vec::new());
    }
    let frame = parse_frame(&bytes, path)?;
    Ok(frame
        .metadata
        .lines()
        .filter_map(|l| l.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect())
}

/// The dimension `D` of the field in a field file (any version and kind), from its header,
/// without reading the rest: to pick `read_any_field::<2>` or `::<3>`.
///
/// # Errors
/// [`FieldFileError::Io`], [`FieldFileError::BadMagic`], [`FieldFileError::Truncated`] (a
/// file shorter than its header), [`FieldFileError::NewerVersion`].
pub fn read_dimension(path: impl AsRef<Path>) -> Result<u32, FieldFileError> {
    use std::io::Read;
    let path = path.as_ref();
    let mut head = Vec::with_capacity(16);
    std::fs::File::open(path)
        .and_then(|f| f.take(16).read_to_end(&mut head))
        .map_err(|source| FieldFileError::Io {
            path: path.to_owned(),
            source,
        })?;
    check_head(&head, path)?;
    let mut cursor = Cursor {
        bytes: &head,
        at: 12,
    };
    cursor.u32().ok_or(FieldFileError::Truncated {
        path: path.to_owned(),
        expected: 16,
        got: head.len(),
    })
}

/// Checks the magic and returns the version (refusing newer ones).
fn check_head(bytes: &[u8], path: &Path) -> Result<u32, FieldFileError> {
    let truncated = |expected: usize| FieldFileError::Truncated {
        path: path.to_owned(),
        expected,
        got: bytes.len(),
    };
    let mut cursor = Cursor { bytes, at: 0 };
    let magic = cursor.take(8).ok_or_else(|| truncated(8))?;
    if magic != MAGIC {
        return Err(FieldFileError::BadMagic {
            path: path.to_owned(),
        });
    }
    let version = cursor.u32().ok_or_else(|| truncated(12))?;
    match version {
        1 | 2 => Ok(version),
        v if v > VERSION => Err(FieldFileError::NewerVersion {
            path: path.to_owned(),
            found: v,
            supported: VERSION,
        }),
        v => Err(FieldFileError::Malformed {
            path: path.to_owned(),
            reason: format!("invalid field file version {v}"),
        }),
    }
}

/// Parses the bytes of a field file of any kind; `path` is only used in error messages.
///
/// # Errors
/// As [`read_any_field`].
pub fn decode_any<const D: usize>(
    bytes: &[u8],
    path: &Path,
) -> Result<AnyField<D>, FieldFileError> {
    match check_head(bytes, path)? {
        1 => bspline::decode_v1(bytes, path).map(AnyField::BSpline),
        _ => decode_v2(bytes, path),
    }
}

struct Frame<'a> {
    dim: u32,
    kind: &'a [u8],
    metadata: &'a str,
    payload: &'a [u8],
}

/// Checks a version-2 file's sizes and checksum and splits it.
fn parse_frame<'a>(bytes: &'a [u8], path: &Path) -> Result<Frame<'a>, FieldFileError> {
    let malformed = |reason: String| FieldFileError::Malformed {
        path: path.to_owned(),
        reason,
    };
    if bytes.len() < V2_HEADER {
        return Err(FieldFileError::Truncated {
            path: path.to_owned(),
            expected: V2_HEADER,
            got: bytes.len(),
        });
    }
    // The fixed header fields, all within the V2_HEADER bytes checked above.
    let mut cursor = Cursor { bytes, at: 12 };
    let short = || malformed("header shorter than its fixed fields".into());
    let dim = cursor.u32().ok_or_else(short)?;
    let kind = cursor.take(8).ok_or_else(short)?;
    let meta_len = cursor.u32().ok_or_else(short)? as usize;
    let payload_len = cursor.u64().ok_or_else(short)?;
    let expected = usize::try_from(payload_len)
        .ok()
        .and_then(|p| p.checked_add(V2_HEADER + meta_len + 4))
        .ok_or_else(|| malformed(format!("impossible payload of {payload_len} bytes")))?;
    if bytes.len() != expected {
        return Err(if bytes.len() < expected {
            FieldFileError::Truncated {
                path: path.to_owned(),
                expected,
                got: bytes.len(),
            }
        } else {
            malformed(format!(
                "{} bytes where the header announces {expected}",
                bytes.len()
            ))
        });
    }
    check_crc(bytes, path)?;
    let metadata = std::str::from_utf8(&bytes[V2_HEADER..V2_HEADER + meta_len])
        .map_err(|_| malformed("metadata is not UTF-8".into()))?;
    Ok(Frame {
        dim,
        kind,
        metadata,
        payload: &bytes[V2_HEADER + meta_len..expected - 4],
    })
}

fn check_crc(bytes: &[u8], path: &Path) -> Result<(), FieldFileError> {
    let n = bytes.len();
    let Some(&stored) = bytes.last_chunk::<4>() else {
        return Err(FieldFileError::Truncated {
            path: path.to_owned(),
            expected: 4,
            got: n,
        });
    };
    let stored = u32::from_le_bytes(stored);
    let computed = crc32fast::hash(&bytes[..n - 4]);
    if stored != computed {
        return Err(FieldFileError::Checksum {
            path: path.to_owned(),
            stored,
            computed,
        });
    }
    Ok(())
}

fn decode_v2<const D: usize>(bytes: &[u8], path: &Path) -> Result<AnyField<D>, FieldFileError> {
    let frame = parse_frame(bytes, path)?;
    if frame.dim as usize != D {
        return Err(FieldFileError::WrongDimension {
            path: path.to_owned(),
            found: frame.dim,
            expected: D,
        });
    }
    let end = frame
        .kind
        .iter()
        .rposition(|&b| b != 0)
        .map_or(0, |i| i + 1);
    let kind = &frame.kind[..end];
    let short = || FieldFileError::Malformed {
        path: path.to_owned(),
        reason: "the payload is shorter than its contents".into(),
    };
    let mut cursor = Cursor {
        bytes: frame.payload,
        at: 0,
    };
    let field = decode_body(&String::from_utf8_lossy(kind), &mut cursor, path, short)?;
    if cursor.at != frame.payload.len() {
        return Err(FieldFileError::Malformed {
            path: path.to_owned(),
            reason: format!(
                "{} bytes of payload left over",
                frame.payload.len() - cursor.at
            ),
        });
    }
    Ok(field)
}

struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

/// Checks a `count` read from the file before anything is allocated for it: each item takes
/// at least `min_bytes_each` of the bytes left after the cursor
/// ([`limits::check_count`](zeroset_field_core::limits::check_count)), and `count` items of
/// `bytes_per_item` bytes in memory fit in the memory available
/// ([`limits::check_alloc`](zeroset_field_core::limits::check_alloc)). `what` names the items.
fn counted(
    c: &Cursor<'_>,
    path: &Path,
    what: &str,
    count: u64,
    min_bytes_each: usize,
    bytes_per_item: usize,
) -> Result<usize, FieldFileError> {
    use zeroset_field_core::limits;
    let too_large = |source| FieldFileError::TooLarge {
        path: path.to_owned(),
        source,
    };
    let n = limits::check_count(what, count, min_bytes_each as u64, c.remaining() as u64)
        .map_err(too_large)?;
    limits::check_alloc(what, n, bytes_per_item).map_err(too_large)?;
    Ok(n)
}

impl<'a> Cursor<'a> {
    /// The bytes after the cursor.
    fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.at)
    }
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }
    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, _) = self.bytes.get(self.at..)?.split_first_chunk::<N>()?;
        self.at += N;
        Some(*head)
    }
    fn u32(&mut self) -> Option<u32> {
        self.array().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }
    fn f64(&mut self) -> Option<f64> {
        self.array().map(f64::from_le_bytes)
    }
    fn point<const D: usize>(&mut self) -> Option<Point<D>> {
        let mut p = [0.0; D];
        for v in &mut p {
            *v = self.f64()?;
        }
        Some(p)
    }
    /// `n` values, refusing (before allocating) more than the bytes left.
    fn f64s(&mut self, n: usize) -> Option<Vec<f64>> {
        let b = self.take(n.checked_mul(8)?)?;
        Some(
            b.as_chunks::<8>()
                .0
                .iter()
                .map(|c| f64::from_le_bytes(*c))
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bspline::Degree;
    use zeroset_field_core::grid::Grid;

    fn field() -> BSplineField<3> {
        let grid = Grid::cell_centered(Aabb::centered_cube(2.0).unwrap(), [3, 4, 5]).unwrap();
        let samples = (0..grid.len()).map(|i| (i as f64 * 0.37).sin()).collect();
        BSplineField::interpolate(grid, samples, Degree::Quadratic).unwrap()
    }

    #[test]
    fn round_trips_bit_for_bit() {
        let f = field();
        let bytes = encode(&f);
        let back: BSplineField<3> = decode(&bytes, Path::new("mem")).unwrap();
        assert_eq!(back.coefficients(), f.coefficients());
        assert_eq!(back.grid(), f.grid());
        assert_eq!(back.degree(), f.degree());
    }

    /// A version-2 file of `kind` around `payload`, its checksum right: only the counts inside
    /// are forged.
    fn forged(kind: &str, payload: &[u8]) -> Vec<u8> {
        frame(3, kind, &[], payload)
    }

    fn u32s(values: &[u32]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    fn u64s(values: &[u64]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    fn f64s(values: &[f64]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    /// Decodes `bytes`, expecting [`FieldFileError::TooLarge`] for a count the file cannot
    /// hold, whose message names `what`.
    fn assert_too_large(bytes: &[u8], what: &str) {
        let start = std::time::Instant::now();
        let e = decode_any::<3>(bytes, Path::new("forged.zsf")).unwrap_err();
        assert!(start.elapsed().as_secs_f64() < 1.0, "slow refusal: {e}");
        assert!(
            matches!(
                &e,
                FieldFileError::TooLarge {
                    source: Error::ExceedsInput { .. },
                    ..
                }
            ),
            "{e:?}"
        );
        let text = e.to_string();
        assert!(
            text.starts_with("forged.zsf: ") && text.contains(what) && text.contains("corrupt"),
            "{text}"
        );
        // Converted to the crate-wide error, the message stays.
        let e: Error = decode_any::<3>(bytes, Path::new("forged.zsf"))
            .unwrap_err()
            .into();
        assert!(e.to_string().contains(what), "{e}");
    }

    #[test]
    fn a_forged_bspline_grid_is_refused_before_allocating() {
        let mut p = u32s(&[2, 0, 0]);
        p.extend(u64s(&[1 << 20, 1 << 20, 1 << 20]));
        p.extend(f64s(&[-1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 0.5]));
        assert_too_large(&forged(KIND_BSPLINE, &p), "B-spline coefficients");
    }

    #[test]
    fn forged_rbf_counts_are_refused_before_allocating() {
        let mut p = u32s(&[1]);
        p.extend(b"r");
        p.extend(u32s(&[0]));
        p.extend(u64s(&[1 << 40]));
        p.extend(f64s(&[0.0; 8]));
        assert_too_large(&forged(KIND_RBF, &p), "RBF functionals");
        let mut p = u32s(&[1]);
        p.extend(b"r");
        p.extend(u32s(&[u32::MAX]));
        p.extend(f64s(&[0.0; 4]));
        assert_too_large(&forged(KIND_RBF, &p), "kernel parameters");
    }

    #[test]
    fn forged_neural_counts_are_refused_before_allocating() {
        let p = u32s(&[0, u32::MAX, 32, 0, 32, 0]);
        assert_too_large(&forged(KIND_NEURAL, &p), "hidden layers");
        // Widths within range, the parameter count right for them, the parameters missing.
        let mut p = u32s(&[0, 2]);
        p.extend(u64s(&[4096, 4096]));
        p.extend(f64s(&[
            0.0, 0.0, 0.0, 1.0, 1.0, -1.0, -1.0, -1.0, 1.0, 1.0, 1.0,
        ]));
        let n = crate::neural::Architecture::new(vec![4096, 4096], Default::default())
            .unwrap()
            .num_parameters(3);
        p.extend(u64s(&[n as u64]));
        assert_too_large(&forged(KIND_NEURAL, &p), "network parameters");
    }

    #[test]
    fn forged_mras_counts_are_refused_before_allocating() {
        let head = f64s(&[0.0, 0.0, 0.0, 1.0, 0.75]);
        // One level announcing 2⁶⁰ cells.
        let mut p = head.clone();
        p.extend(u32s(&[1, 1, 3]));
        p.extend(u64s(&[1 << 60]));
        p.extend(u32s(&[0; 6]));
        assert_too_large(&forged(KIND_MRAS, &p), "level 1 cells");
        // A cell announcing a CP rank whose factors the file does not hold.
        let mut p = head.clone();
        p.extend(u32s(&[1, 1, 64]));
        p.extend(u64s(&[1]));
        p.extend(u32s(&[0, 0, 0, 0, 4096]));
        p.extend(f64s(&[0.0; 8]));
        assert_too_large(&forged(KIND_MRAS, &p), "CP factors of rank 4096");
        // Millions of levels, or levels out of order, are refused before any level is built.
        let mut p = head.clone();
        p.extend(u32s(&[u32::MAX]));
        let e = decode_any::<3>(&forged(KIND_MRAS, &p), Path::new("m.zsf")).unwrap_err();
        assert!(e.to_string().contains("4294967295 levels (at most"), "{e}");
        let mut p = head;
        p.extend(u32s(&[2, 1, 3]));
        p.extend(u64s(&[0]));
        p.extend(u32s(&[1, 3]));
        p.extend(u64s(&[0]));
        let e = decode_any::<3>(&forged(KIND_MRAS, &p), Path::new("m.zsf")).unwrap_err();
        assert!(e.to_string().contains("position 2 holds level 1"), "{e}");
    }

    #[test]
    fn corruption_truncation_and_wrong_kind_are_reported() {
        let bytes = encode(&field());
        let p = Path::new("x.zsf");
        let mut flipped = bytes.clone();
        flipped[100] ^= 1;
        let e = decode::<3>(&flipped, p).unwrap_err().to_string();
        assert!(e.contains("checksum"), "{e}");
        let e = decode::<3>(&bytes[..bytes.len() - 9], p).unwrap_err();
        assert!(matches!(e, Error::Truncated { .. }), "{e}");
        let e = decode::<3>(&bytes[..5], p).unwrap_err();
        assert!(matches!(e, Error::Truncated { .. }), "{e}");
        let e = decode::<2>(&bytes, p).unwrap_err().to_string();
        assert!(e.contains("3-D"), "{e}");
        let e = decode::<3>(b"ply\nformat ascii 1.0\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("magic"), "{e}");
        let mut extra = bytes.clone();
        extra.push(0);
        assert!(decode::<3>(&extra, p).is_err());
    }
}
