//! Point-cloud files: readers for PLY, XYZ text, CSV, GemPy geology tables, PCD, LAS/LAZ and
//! E57, and an atomic
//! PLY writer; value constraints (`x y value`, `x y z value`) in [`values`].
//!
//! | [`Format`] | Extensions | What is read | Normals |
//! |---|---|---|---|
//! | [`Format::Ply`] | `.ply` | `ascii`, `binary_little_endian` or `binary_big_endian`; element `vertex`, properties `x y z` of any scalar type; other properties and elements (faces) are skipped | `nx ny nz` (or PCL's `normal_x normal_y normal_z`), all three or none |
//! | [`Format::Xyz`] | `.xyz` `.xyzn` `.txt` `.pts` `.asc` `.pwn` | one point per line: at least 3 numbers (`x y z`, columns after the third ignored unless there are 6 or more: `x y z nx ny nz`), separated by whitespace, commas or semicolons; or columns named by a first line (`x y z nx ny nz`, CloudCompare's `//X,Y,Z,R,G,B,Nx,Ny,Nz`, any order, other names ignored); `#` starts a comment; blank lines are skipped; every line has the same count; a `.pts` file's first line may be its point count | named `nx ny nz` (or `normal_x ...`: [`NORMAL_NAMES`]); unnamed columns 4–6 if they look like normals: not RGB colours (all whole numbers 0–255) and every non-zero length within [`NORMAL_LENGTHS`]; otherwise [`Error::NotNormals`] |
//! | [`Format::Csv`] | `.csv` | a header row naming `x`, `y`, `z` (any case); other columns, such as a leading unnamed index, are ignored; fields separated by commas, or by semicolons or tabs where the header has more of them | columns `nx ny nz` or `normal_x normal_y normal_z` (or, without them, GemPy's `G_x G_y G_z`), all three or none |
//! | [`Format::GemPy`] | `.csv` whose header names `formation` or `surface`, or two of `dip`, `azimuth` and `polarity` | GemPy surface points (`X,Y,Z,formation`) or orientations (`X,Y,Z,azimuth,dip,polarity,formation`, or `G_x,G_y,G_z` for the angles); see [`gempy`] | orientations only, from dip, azimuth and polarity ([`gempy::orientation_normal`]) or `G_x, G_y, G_z` |
//! | [`Format::Pcd`] | `.pcd` | PCL's PCD v0.5–0.7: `DATA ascii`, `binary` or `binary_compressed` (LZF); fields `x y z` of any type; other fields skipped; points whose `x y z` are all NaN (an organised cloud's gaps) left out; see [`pcd`] | `normal_x normal_y normal_z` (or `nx ny nz`), all three or none |
//! | [`Format::Las`] | `.las` `.laz` | ASPRS LAS 1.0–1.4, any point format; `x y z` scaled and offset as the header says; withheld points left out; LAZ (LASzip) too; see [`las`] | none (LAS has no standard normals) |
//! | [`Format::E57`] | `.e57` | ASTM E57 (terrestrial laser scanners): every scan, each moved into the file's frame by its pose; Cartesian or spherical coordinates; records flagged invalid left out; see [`e57`](mod@e57) | the surface-normals extension (`nor:normalX ...`), if every scan has it |
//!
//! [`read_point_cloud`] picks the format with [`detect_format`] (the extension, then the CSV
//! header) and returns a [`PointCloud3`]; [`read_point_cloud_with`] takes [`ReadOptions`] to force
//! a format or to accept NaN and infinite values.
//!
//! ## Guarantees
//!
//! - Values are returned as stored (converted to `f64`): nothing is rescaled, reordered,
//!   deduplicated or normalised. [`PointCloud::stats`](crate::cloud::PointCloud::stats) reports
//!   duplicates and normals that are not unit length (the fits scale normals to unit length).
//! - An xyz file's unnamed columns 4–6 are read as normals only if they look like normals; RGB
//!   colours (`x y z r g b`) or lengths far from 1 are an [`Error::NotNormals`] naming the
//!   line, never normals. PLY and CSV name their normals (`nx ny nz`) and are read as they are.
//! - By default a NaN or infinite coordinate or normal component is an [`Error::NonFinite`]
//!   naming the file, the 0-based record, the 1-based line (text formats) and the field.
//! - A file with no point is an error ([`Error::Malformed`] naming the file), never an empty
//!   cloud; a file that ends before the records its header announces is [`Error::Truncated`].
//! - Every error names the file; text formats also name the 1-based line.
//!
//! Not guaranteed: normal orientation. Normals are returned as the file gives them; zeroset
//! expects them to point out of the solid (see the [crate docs](crate)), and
//! [`PointCloud::flip_normals`](crate::cloud::PointCloud::flip_normals) reverses them.
//!
//! Writing goes through [`write_atomic`]: the data is written to a temporary file in the target's
//! directory and renamed over the target only once complete, so a failed write never leaves a
//! half-written file behind. [`write_ply`] writes binary little-endian PLY with `double`
//! properties, which every PLY reader accepts.

use std::fmt;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::cloud::PointCloud3;
use crate::error::{Error, Result};
use crate::geometry::Point3;

pub mod e57;
pub mod gempy;
pub mod las;
pub mod pcd;
pub mod ply;
mod table;
pub mod values;
mod xyz;

pub use ply::write_ply;
pub use values::{ValuePoints, read_value_points, value_file_dimension};
pub use xyz::NORMAL_LENGTHS;

/// A point-cloud file format; see the [module docs](self) for what each one reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// Stanford PLY: ascii or binary, element `vertex` with `x y z [nx ny nz]`.
    Ply,
    /// Plain text, one point per line: `x y z` or `x y z nx ny nz`.
    Xyz,
    /// Comma-separated values with a header row naming `x, y, z [, nx, ny, nz]`.
    Csv,
    /// A GemPy geology table (surface points or orientations); see [`gempy`].
    GemPy,
    /// The Point Cloud Library's PCD: a text header, then the points as text, binary or
    /// LZF-compressed binary; see [`pcd`].
    Pcd,
    /// The ASPRS LiDAR format LAS, and LAZ (positions only); see
    /// [`las`].
    Las,
    /// ASTM E57, terrestrial laser scans (every scan in the file's frame); see
    /// [`e57`](mod@e57).
    E57,
}

impl Format {
    /// Every format, in the order of the module table.
    pub const ALL: [Format; 7] = [
        Format::Ply,
        Format::Xyz,
        Format::Csv,
        Format::GemPy,
        Format::Pcd,
        Format::Las,
        Format::E57,
    ];

    /// The format implied by the file extension (case-insensitive), without reading the file:
    /// `.ply` → [`Format::Ply`]; `.xyz`, `.xyzn`, `.txt`, `.pts`, `.asc`, `.pwn` →
    /// [`Format::Xyz`]; `.csv` → [`Format::Csv`]; `.pcd` → [`Format::Pcd`]; `.las`, `.laz` →
    /// [`Format::Las`]; `.e57` → [`Format::E57`]. A `.csv` file may
    /// hold a GemPy table: [`detect_format`] reads the header to tell. `None` for any other
    /// extension.
    pub fn from_path(path: impl AsRef<Path>) -> Option<Format> {
        let ext = path.as_ref().extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "ply" => Some(Format::Ply),
            "xyz" | "xyzn" | "txt" | "pts" | "asc" | "pwn" => Some(Format::Xyz),
            "csv" => Some(Format::Csv),
            "pcd" => Some(Format::Pcd),
            "las" | "laz" => Some(Format::Las),
            "e57" => Some(Format::E57),
            _ => None,
        }
    }

    /// The lower-case name used on the command line: `ply`, `xyz`, `csv`, `gempy`, `pcd`,
    /// `las` or `e57`.
    pub fn name(self) -> &'static str {
        match self {
            Format::Ply => "ply",
            Format::Xyz => "xyz",
            Format::Csv => "csv",
            Format::GemPy => "gempy",
            Format::Pcd => "pcd",
            Format::Las => "las",
            Format::E57 => "e57",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The error of [`Format::from_str`]: the name given is not a format.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown format '{0}' (expected ply, xyz, csv, gempy, pcd, las or e57)")]
pub struct UnknownFormatName(pub String);

impl FromStr for Format {
    type Err = UnknownFormatName;

    /// Parses `ply`, `xyz`, `csv`, `gempy`, `pcd`, `las` or `e57` (case-insensitive).
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Format::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| UnknownFormatName(s.to_owned()))
    }
}

/// The format of a file: the extension first ([`Format::from_path`]); a `.csv` file whose
/// header names `formation` or `surface`, or all of `dip`, `azimuth` and `polarity`, is
/// [`Format::GemPy`]. A file with an unknown extension that starts with the PLY magic line
/// `ply` is [`Format::Ply`]; one that starts as PCL writes PCD files (`# .PCD` or `VERSION`) is
/// [`Format::Pcd`]; one that starts with `LASF` is [`Format::Las`]; one that starts with
/// `ASTM-E57` is [`Format::E57`].
///
/// # Errors
/// [`Error::UnknownFormat`] when neither the extension nor the content tells;
/// [`Error::ValueFile`] for a value-constraint file (`.xyv`, `.xyzv`), which holds no point
/// cloud;
/// [`Error::Compressed`] for a compressed file (`scan.ply.gz`), naming the command that unpacks
/// it;
/// [`Error::Io`] if a `.csv` file (or a file with an unknown extension) cannot be read;
/// [`Error::Malformed`] for a `.csv` file whose header cannot be parsed.
pub fn detect_format(path: impl AsRef<Path>) -> Result<Format> {
    let path = path.as_ref();
    if let Some(dimension) = value_file_dimension(path) {
        return Err(Error::ValueFile {
            path: path.to_owned(),
            dimension,
        });
    }
    match Format::from_path(path) {
        Some(Format::Csv) => {
            let header = table::read_header(path)?;
            Ok(if gempy::is_gempy_header(&header) {
                Format::GemPy
            } else {
                Format::Csv
            })
        }
        Some(format) => Ok(format),
        None => {
            let mut magic = [0u8; 8];
            let mut file = File::open(path).map_err(io_error(path))?;
            let n = read_prefix(&mut file, &mut magic).map_err(io_error(path))?;
            match &magic[..n] {
                [b'p', b'l', b'y', b'\n' | b'\r', ..] => Ok(Format::Ply),
                [b'#', b' ', b'.', b'P', b'C', b'D', ..]
                | [b'V', b'E', b'R', b'S', b'I', b'O', b'N', ..] => Ok(Format::Pcd),
                [b'L', b'A', b'S', b'F', ..] => Ok(Format::Las),
                b"ASTM-E57" => Ok(Format::E57),
                prefix => Err(match compression(prefix) {
                    Some((compression, unpack)) => Error::Compressed {
                        path: path.to_owned(),
                        compression,
                        hint: format!("{unpack} {}", shell_word(path)),
                    },
                    None => Error::UnknownFormat {
                        path: path.to_owned(),
                    },
                }),
            }
        }
    }
}

/// [`Error::Io`] "a directory, not a file" for a directory (`scans.e57/`), before a reader
/// says something less clear.
pub(crate) fn refuse_directory(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::Io {
            path: path.to_owned(),
            source: io::Error::new(io::ErrorKind::InvalidInput, "a directory, not a file"),
        });
    }
    Ok(())
}

/// `path` as one shell word, to paste into a command line (the studio's command lines, the
/// unpack hint of [`Error::Compressed`]): as it is when it holds only safe characters, else single-quoted;
/// `./` before a relative path that starts with `-` (else it reads as an option); a name that
/// is not UTF-8 in bash's `$'…'` with its bytes escaped.
pub fn shell_word(path: &Path) -> String {
    let Some(text) = path.to_str() else {
        return escaped_bytes(path);
    };
    let text = if text.starts_with('-') {
        format!("./{text}")
    } else {
        text.to_owned()
    };
    let safe = !text.is_empty()
        && text
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+=:,@%".contains(c));
    if safe {
        text
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

/// `path` as bash's `$'…'`, each byte outside printable ASCII as `\xHH`.
fn escaped_bytes(path: &Path) -> String {
    #[cfg(unix)]
    let bytes = std::os::unix::ffi::OsStrExt::as_bytes(path.as_os_str()).to_vec();
    #[cfg(not(unix))]
    let bytes = path.to_string_lossy().into_owned().into_bytes();
    let prefix = if bytes.first() == Some(&b'-') {
        "./"
    } else {
        ""
    };
    let mut out = format!("{prefix}$'");
    for b in bytes {
        match b {
            b'\'' | b'\\' => {
                out.push('\\');
                out.push(char::from(b));
            }
            0x20..=0x7e => out.push(char::from(b)),
            _ => out.push_str(&format!("\\x{b:02x}")),
        }
    }
    out.push('\'');
    out
}

/// The compression whose signature starts `prefix`, and the command that unpacks it.
fn compression(prefix: &[u8]) -> Option<(&'static str, &'static str)> {
    Some(match prefix {
        [0x1f, 0x8b, ..] => ("gzip", "gunzip -k"),
        [b'P', b'K', 3, 4, ..] => ("zip", "unzip"),
        [b'B', b'Z', b'h', ..] => ("bzip2", "bunzip2 -k"),
        [0xfd, b'7', b'z', b'X', b'Z', 0, ..] => ("xz", "unxz -k"),
        [0x28, 0xb5, 0x2f, 0xfd, ..] => ("zstd", "unzstd"),
        [b'7', b'z', 0xbc, 0xaf, 0x27, 0x1c, ..] => ("7-Zip", "7z x"),
        _ => return None,
    })
}

/// Reads up to `buf.len()` bytes, fewer only at the end of the file.
fn read_prefix(r: &mut impl io::Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Options for [`read_point_cloud_with`]. `ReadOptions::default()` detects the format and
/// rejects NaN and infinite values.
///
/// ```
/// use zeroset_field_core::io::{Format, ReadOptions};
/// let options = ReadOptions::default().with_format(Format::Xyz).with_allow_non_finite(true);
/// assert_eq!(options.format, Some(Format::Xyz));
/// ```
#[derive(Debug, Clone, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct ReadOptions {
    /// The format to read; `None` (the default) detects it with [`detect_format`].
    pub format: Option<Format>,
    /// Accept NaN and infinite coordinates and normal components (default `false`: they are
    /// an [`Error::NonFinite`]). Use [`PointCloud::stats`](crate::cloud::PointCloud::stats) to
    /// count them and [`PointCloud::validate`](crate::cloud::PointCloud::validate) to reject
    /// them later.
    pub allow_non_finite: bool,
    /// Read the positions only (default `false`): any normal columns or properties are dropped
    /// without being checked, so that a file whose columns 4–6 are not normals (an `x y z r g
    /// b` xyz file: [`Error::NotNormals`]) can still be described.
    pub positions_only: bool,
    /// For a GemPy table, read only the rows of this formation (or fault), matched exactly
    /// (default `None`: every row, all formations as one cloud). A name no row has is
    /// [`Error::Malformed`] listing the table's formations; a file of another format is
    /// [`Error::Malformed`] too.
    pub formation: Option<String>,
}

impl ReadOptions {
    /// These options, reading only `formation`'s rows of a GemPy table.
    #[must_use]
    pub fn with_formation(mut self, formation: impl Into<String>) -> Self {
        self.formation = Some(formation.into());
        self
    }

    /// These options, reading the positions only (`true`) or the normals too (`false`).
    #[must_use]
    pub fn with_positions_only(mut self, positions_only: bool) -> Self {
        self.positions_only = positions_only;
        self
    }

    /// These options, reading `format` instead of detecting it.
    #[must_use]
    pub fn with_format(mut self, format: Format) -> Self {
        self.format = Some(format);
        self
    }

    /// These options, accepting (`true`) or rejecting (`false`) non-finite values.
    #[must_use]
    pub fn with_allow_non_finite(mut self, allow: bool) -> Self {
        self.allow_non_finite = allow;
        self
    }
}

/// Reads a point cloud, detecting the format ([`detect_format`]) and rejecting NaN and
/// infinite values. Same as [`read_point_cloud_with`] with [`ReadOptions::default`].
///
/// ```no_run
/// let cloud = zeroset_field_core::io::read_point_cloud("bunny.ply")?;
/// println!("{} points, normals: {}", cloud.len(), cloud.normals().is_some());
/// # Ok::<(), zeroset_field_core::Error>(())
/// ```
///
/// # Errors
/// See [`read_point_cloud_with`].
pub fn read_point_cloud(path: impl AsRef<Path>) -> Result<PointCloud3> {
    read_point_cloud_with(path, &ReadOptions::default())
}

/// Reads a point cloud with the given options.
///
/// A GemPy orientations table gives positions with normals ([`gempy::orientation_normal`]); a
/// GemPy surface-points table gives positions only.
///
/// # Errors
/// - [`Error::Io`]: the file cannot be opened or read.
/// - [`Error::UnknownFormat`]: no format given and none detected; [`Error::ValueFile`]: no
///   format given and the file is a value-constraint file (`.xyv`, `.xyzv`).
/// - [`Error::Malformed`]: the content does not parse (with the 1-based line for text
///   formats), or the file holds no point (an empty file included).
/// - [`Error::Truncated`]: a PLY file ends before the vertices its header announces.
/// - [`Error::MissingProperty`]: a PLY vertex lacks `x`, `y` or `z`, or has some but not all
///   of `nx ny nz`.
/// - [`Error::MissingColumn`]: a CSV header lacks `x`, `y` or `z` (or a GemPy column).
/// - [`Error::NonFinite`]: a NaN or infinite value, unless
///   [`ReadOptions::allow_non_finite`].
/// - [`Error::NotNormals`]: an xyz file whose columns 4–6 do not look like unit normals
///   (RGB colours, or lengths outside [`NORMAL_LENGTHS`]).
/// - [`Error::PartialNormals`]: an E57 file whose scans have normals in part (unless
///   [`ReadOptions::positions_only`]).
pub fn read_point_cloud_with(path: impl AsRef<Path>, options: &ReadOptions) -> Result<PointCloud3> {
    let path = path.as_ref();
    refuse_directory(path)?;
    let format = match options.format {
        Some(format) => format,
        None => detect_format(path)?,
    };
    let checker = FiniteCheck {
        path,
        allow: options.allow_non_finite,
    };
    if let (Some(name), false) = (&options.formation, format == Format::GemPy) {
        return Err(malformed(
            path,
            None,
            format!(
                "formation '{name}' asked for, but this is a {} file, not a GemPy table",
                format.name()
            ),
        ));
    }
    let (positions, normals) = match format {
        Format::Ply => ply::read(path, &checker)?,
        Format::Xyz => xyz::read(path, &checker, !options.positions_only)?,
        Format::Csv => table::read_xyz_table(path, &checker)?,
        Format::GemPy => gempy::read_cloud(path, &checker, options.formation.as_deref())?,
        Format::Pcd => pcd::read(path, &checker)?,
        Format::Las => las::read(path, &checker, !options.positions_only)?,
        Format::E57 => e57::read(path, &checker, !options.positions_only)?,
    };
    if positions.is_empty() {
        return Err(malformed(path, None, "the file holds no point"));
    }
    let normals = if options.positions_only {
        None
    } else {
        normals
    };
    PointCloud3::from_raw(positions, normals)
}

/// Writes a file atomically: `write` fills a temporary file in the same directory as `path`,
/// which is flushed to disk and then renamed over `path`. Readers of `path` see either the old
/// file or the complete new one, never a partial write; on any error the temporary file is
/// removed and an existing `path` is left untouched.
///
/// An existing file's permission bits (`rwx` for user, group and others; not setuid, setgid
/// or sticky) are kept, a `chmod 600` file staying private, and on Unix its owner and group
/// where the process may set them (root rewriting another user's file). A symbolic link at
/// `path` to a regular file is followed: that file is replaced and the link kept. A link to
/// anything else (a device, a FIFO, a directory), and one whose target does not exist or
/// cannot be resolved (a loop), is itself replaced by the file, as a plain `path` is.
///
/// The temporary file is named `.<name>.<pid>.<n>.tmp` (`<name>` is `path`'s file name, `<pid>`
/// the writing process, `<n>` a counter). A process killed while writing (SIGKILL, a power
/// cut) leaves it behind; the next `write_atomic` to the same `path` removes it first. On
/// Linux, it removes every file of that directory whose name has exactly that form for the same
/// `<name>`, that is a regular file owned by the current user, and whose `<pid>` names no
/// running process (`/proc/<pid>` does not exist): a live writer's temporary file, in this
/// process or another, is never touched; nor is anything else that merely looks similar. If
/// `/proc` is not mounted nothing is removed. Elsewhere stale temporary files are left alone
/// (they are hidden, and never mistaken for `path`). A writer that this process cannot see in
/// `/proc` though it is running (another PID namespace writing to a shared directory, `/proc`
/// mounted with `hidepid`) may have its temporary file removed; its write then fails with an
/// error, and `path` is still never left partial.
///
/// ```no_run
/// use std::io::Write;
/// zeroset_field_core::io::write_atomic("out.txt", |w| writeln!(w, "hello"))?;
/// # Ok::<(), zeroset_field_core::Error>(())
/// ```
///
/// # Errors
/// [`Error::Io`] naming `path` (as given, not a link's target), for an error from `write` or
/// from the file system (for instance a directory that does not exist).
pub fn write_atomic<F>(path: impl AsRef<Path>, write: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let path = path.as_ref();
    // A link to a regular file: write that file (the link stays a link).
    let linked = fs::symlink_metadata(path)
        .ok()
        .filter(|m| m.file_type().is_symlink())
        .and_then(|_| fs::canonicalize(path).ok())
        .filter(|target| fs::metadata(target).is_ok_and(|m| m.is_file()));
    let target = linked.as_deref().unwrap_or(path);
    let Some(name) = target.file_name() else {
        return Err(Error::Io {
            path: path.to_owned(),
            source: io::Error::new(io::ErrorKind::InvalidInput, "not a file name"),
        });
    };
    let existing = fs::metadata(target).ok().filter(|m| m.is_file());
    let dir = match target.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    remove_stale_files(dir, |file| temp_writer(file, name));
    let (tmp_path, file, _unfinished) = Unfinished::create(dir, name).map_err(io_error(path))?;
    let result = (|| {
        if let Some(existing) = &existing {
            keep_attributes(&file, existing)?;
        }
        let mut writer = BufWriter::new(file);
        write(&mut writer)?;
        let file = writer
            .into_inner()
            .map_err(io::IntoInnerError::into_error)?;
        file.sync_all()?;
        drop(file);
        fs::rename(&tmp_path, target)
    })();
    if let Err(source) = result {
        // Best effort: the temporary file may already be gone.
        let _ = fs::remove_file(&tmp_path);
        return Err(Error::Io {
            path: path.to_owned(),
            source,
        });
    }
    Ok(())
}

/// Gives the new file `file` the permission bits of the file it replaces (and, on Unix, its
/// owner and group where this process may: an error there is ignored, as for any user but
/// root giving a file away).
fn keep_attributes(file: &File, existing: &fs::Metadata) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let _ = std::os::unix::fs::fchown(file, Some(existing.uid()), Some(existing.gid()));
        file.set_permissions(fs::Permissions::from_mode(existing.mode() & 0o777))
    }
    #[cfg(not(unix))]
    {
        file.set_permissions(existing.permissions())
    }
}

/// The temporary files of [`write_atomic`] calls in progress in this process.
static UNFINISHED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn unfinished() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    UNFINISHED.lock().unwrap_or_else(|e| e.into_inner())
}

/// A temporary file listed in [`UNFINISHED`] while its write is in progress.
struct Unfinished(PathBuf);

impl Unfinished {
    /// Creates the temporary file (see [`create_temp`]) and lists it, holding the list's lock
    /// meanwhile: an interrupt's [`remove_unfinished_writes`] either runs before the file exists
    /// or sees it listed, never in between.
    fn create(dir: &Path, name: &std::ffi::OsStr) -> io::Result<(PathBuf, File, Self)> {
        let mut list = unfinished();
        let (tmp_path, file) = create_temp(dir, name)?;
        list.push(tmp_path.clone());
        Ok((tmp_path.clone(), file, Self(tmp_path)))
    }
}

impl Drop for Unfinished {
    fn drop(&mut self) {
        unfinished().retain(|p| *p != self.0);
    }
}

/// Removes the temporary files of the [`write_atomic`] calls in progress in this process (best
/// effort), for a program about to exit on a signal: Ctrl-C's default action would leave them
/// until the next write to the same file. The writes they belong to then fail, and their
/// targets keep their old contents (or stay absent); a write that has already renamed its file
/// into place is complete and not touched. Returns how many files were removed.
pub fn remove_unfinished_writes() -> usize {
    remove_listed(&mut unfinished())
}

/// [`remove_unfinished_writes`] for a process about to exit: the list stays locked afterwards,
/// so that a [`write_atomic`] starting in another thread before the exit waits instead of
/// creating a temporary file that nothing would remove. Every later `write_atomic` in this
/// process blocks: call it only on the way out.
pub fn remove_unfinished_writes_before_exit() -> usize {
    let mut list = unfinished();
    let removed = remove_listed(&mut list);
    std::mem::forget(list);
    removed
}

fn remove_listed(list: &mut Vec<PathBuf>) -> usize {
    list.drain(..)
        .filter(|path| fs::remove_file(path).is_ok())
        .count()
}

/// Creates a new, uniquely named hidden file `.<name>.<pid>.<n>.tmp` in `dir` (parsed back by
/// [`temp_writer`]).
fn create_temp(dir: &Path, name: &std::ffi::OsStr) -> io::Result<(PathBuf, File)> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let pid = std::process::id();
    let mut last_error = None;
    for _ in 0..64 {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp_path = dir.join(temp_name(name, pid, n));
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp_path)
        {
            Ok(file) => return Ok((tmp_path, file)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last_error = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last_error.unwrap_or_else(|| io::Error::other("could not create a temporary file")))
}

/// `.<name>.<pid>.<n>.tmp`: the name of [`create_temp`]'s temporary files.
fn temp_name(name: &std::ffi::OsStr, pid: u32, n: u64) -> std::ffi::OsString {
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".{pid}.{n}.tmp"));
    tmp_name
}

/// The writer's process id if `file_name` is exactly a temporary file name of [`create_temp`]
/// for the target `name`: `.<name>.<pid>.<n>.tmp` with `<pid>` and `<n>` written as
/// [`temp_name`] writes them (decimal digits, no sign, no leading zero, `<pid>` not 0).
/// Anything else, such as a temporary file of a target whose name extends `name`
/// (`.<name>.1.<pid>.<n>.tmp`) or a copy (`...tmp.bak`), is `None`.
fn temp_writer(file_name: &std::ffi::OsStr, name: &std::ffi::OsStr) -> Option<u32> {
    let file_name = file_name.as_encoded_bytes();
    let rest = file_name
        .strip_prefix(b".")?
        .strip_prefix(name.as_encoded_bytes())?
        .strip_prefix(b".")?
        .strip_suffix(b".tmp")?;
    let rest = std::str::from_utf8(rest).ok()?;
    let (pid, n) = rest.split_once('.')?;
    let canonical = |s: &str| {
        !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()) && (s == "0" || !s.starts_with('0'))
    };
    if !canonical(pid) || !canonical(n) {
        return None;
    }
    n.parse::<u64>().ok()?;
    pid.parse::<u32>().ok().filter(|&pid| pid != 0)
}

/// Removes, best effort, the files in `dir` that a process left behind when it was killed:
/// those for which `writer` gives the id of the process that made them (parsed from the name)
/// and that process has ended. [`write_atomic`] calls it with its own temporary names; a
/// command that keeps an intermediate file of its own (named with its process id) calls it
/// with that name's pattern before making one. Only regular files of this user are removed,
/// never one of this process; errors are ignored (a file another process removed first, an
/// unreadable directory).
///
/// On Linux a process has ended when `/proc/<pid>` is gone; without `/proc`, and on other
/// systems, where nothing tells a live writer from a dead one, nothing is removed.
pub fn remove_stale_files(dir: &Path, writer: impl Fn(&std::ffi::OsStr) -> Option<u32>) {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::MetadataExt;
        // Without procfs every process would look gone.
        let Ok(me) = fs::metadata("/proc/self") else {
            return;
        };
        let Ok(entries) = fs::read_dir(dir) else {
            return;
        };
        for entry in entries.flatten() {
            let Some(pid) = writer(&entry.file_name()) else {
                continue;
            };
            // Not a symbolic link, a directory or someone else's file.
            let Ok(meta) = entry.metadata() else {
                continue;
            };
            if !meta.file_type().is_file() || meta.uid() != me.uid() {
                continue;
            }
            if pid == std::process::id() || process_exists(pid) {
                continue;
            }
            let _ = fs::remove_file(entry.path());
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (dir, writer);
}

/// Whether process `pid` exists (a zombie counts): `/proc/<pid>` does. Any answer but "no
/// such file" (a permission error, say) counts as yes.
#[cfg(target_os = "linux")]
fn process_exists(pid: u32) -> bool {
    !matches!(
        fs::symlink_metadata(format!("/proc/{pid}")),
        Err(e) if e.kind() == io::ErrorKind::NotFound
    )
}

/// How many records to reserve room for when a file's header announces `count` records, each
/// at least `min_record_bytes` long, and `bytes` bytes are left to hold them: `count`, capped
/// at what the bytes can hold. A header's count may be wrong (a corrupt or truncated file), so
/// it never sizes an allocation by itself: a header that claims 10⁹ vertices in a 200-byte file
/// reserves room for at most 200, and the reader then reports the file as truncated.
///
/// For PLY, a binary record takes at least the sizes of its scalars and list counts; an ASCII
/// record at least two bytes per property (a digit and a separator), with one byte added to
/// `bytes` for a last line without its newline.
///
/// ```
/// use zeroset_field_core::io::records_that_fit;
/// assert_eq!(records_that_fit(1_000_000_000, 200, 12), 16);
/// assert_eq!(records_that_fit(8, 96, 12), 8);
/// ```
pub fn records_that_fit(count: usize, bytes: u64, min_record_bytes: usize) -> usize {
    let fit = bytes / min_record_bytes.max(1) as u64;
    count.min(usize::try_from(fit).unwrap_or(usize::MAX))
}

/// Positions and, if the file has them, normals, before the cloud is assembled.
pub(crate) type RawPoints = (Vec<Point3>, Option<Vec<Point3>>);

/// Names of the position and normal fields, for [`Error::NonFinite`].
pub(crate) const POSITION_FIELDS: [&str; 3] = ["x", "y", "z"];
/// See [`POSITION_FIELDS`].
pub(crate) const NORMAL_FIELDS: [&str; 3] = ["nx", "ny", "nz"];

/// The names point files give a normal's components, one set per family of writers: `nx ny nz`
/// (Open3D, MeshLab, CloudCompare, zeroset) and `normal_x normal_y normal_z` (PCL's PCD and PLY
/// files). Text headers and CSV match them in any case, PLY and PCD exactly.
pub const NORMAL_NAMES: [[&str; 3]; 2] = [["nx", "ny", "nz"], ["normal_x", "normal_y", "normal_z"]];

/// The normal's three columns (or properties) and the names they were found under.
pub(crate) type NormalColumns = ([usize; 3], [&'static str; 3]);

/// Where the normal's components are among named columns or properties, `find` telling where
/// a name is: the first set of [`NORMAL_NAMES`] found whole, with its names; `Ok(None)` if no
/// name of any set is found; `Err(name)`, the first missing component of a set found in part.
pub(crate) fn normal_columns(
    find: impl Fn(&str) -> Option<usize>,
) -> std::result::Result<Option<NormalColumns>, &'static str> {
    let mut partial = None;
    for names in NORMAL_NAMES {
        match names.map(&find) {
            [Some(a), Some(b), Some(c)] => return Ok(Some(([a, b, c], names))),
            [None, None, None] => {}
            found => {
                let i = found.iter().position(Option::is_none).unwrap_or(0);
                partial = partial.or(Some(names[i]));
            }
        }
    }
    partial.map_or(Ok(None), Err)
}

/// The names of a file's normal components for error messages: the set of [`NORMAL_NAMES`]
/// whose first name is `first` (any case), else [`NORMAL_FIELDS`].
pub(crate) fn normal_field_names(first: &str) -> [&'static str; 3] {
    NORMAL_NAMES
        .into_iter()
        .find(|names| names[0].eq_ignore_ascii_case(first))
        .unwrap_or(NORMAL_FIELDS)
}

/// Rejects non-finite values unless allowed, naming the file, record, line and field.
pub(crate) struct FiniteCheck<'a> {
    pub(crate) path: &'a Path,
    pub(crate) allow: bool,
}

impl FiniteCheck<'_> {
    /// Checks `values`, whose fields are named by `fields`.
    pub(crate) fn check(
        &self,
        record: usize,
        line: Option<usize>,
        fields: &[&'static str],
        values: &[f64],
    ) -> Result<()> {
        if self.allow {
            return Ok(());
        }
        match values.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => Err(Error::NonFinite {
                source_name: self.path.display().to_string(),
                record,
                line,
                field: fields[i],
                value: values[i],
            }),
        }
    }
}

/// Maps an I/O error to [`Error::Io`] naming `path`.
pub(crate) fn io_error(path: &Path) -> impl FnOnce(io::Error) -> Error + '_ {
    move |source| Error::Io {
        path: path.to_owned(),
        source,
    }
}

/// An [`Error::Malformed`].
pub(crate) fn malformed(path: &Path, line: Option<usize>, reason: impl Into<String>) -> Error {
    Error::Malformed {
        path: path.to_owned(),
        line,
        reason: reason.into(),
    }
}

/// Runs a third-party decoder on `path`: a panic in it becomes the file's
/// [`Error::Malformed`] ("not a readable `format` file: its decoder failed (…)"), not the
/// caller's crash.
pub(crate) fn guard_decoder<T>(
    path: &Path,
    format: &str,
    decode: impl FnOnce() -> Result<T>,
) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(decode)).unwrap_or_else(|panic| {
        let what = panic
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".to_owned());
        Err(malformed(
            path,
            None,
            format!("not a readable {format} file: its decoder failed ({what})"),
        ))
    })
}

/// Opens a file for reading; a 0-byte file is [`Error::Malformed`]. Returns the file and its
/// length in bytes.
pub(crate) fn open_nonempty(path: &Path) -> Result<(File, u64)> {
    let file = File::open(path).map_err(io_error(path))?;
    let len = file.metadata().map_err(io_error(path))?.len();
    if len == 0 {
        return Err(malformed(path, None, "the file is empty (0 bytes)"));
    }
    Ok((file, len))
}

/// Parses a number as Rust does (`1`, `-2.5e-3`, `nan`, `inf`, ...), after trimming.
pub(crate) fn parse_number(token: &str) -> Option<f64> {
    token.trim().parse::<f64>().ok()
}

#[cfg(test)]
mod stale_temp_tests {
    use super::*;
    use std::ffi::OsStr;

    #[test]
    fn temp_names_parse_strictly() {
        let name = OsStr::new("out.ply");
        let pid = |s: &str| temp_writer(OsStr::new(s), name);
        assert_eq!(pid(".out.ply.123.4.tmp"), Some(123));
        assert_eq!(pid(".out.ply.7.0.tmp"), Some(7));
        assert_eq!(temp_name(name, 42, 9), ".out.ply.42.9.tmp");
        assert_eq!(temp_writer(&temp_name(name, 42, 9), name), Some(42));
        for other in [
            "out.ply",
            ".out.ply.123.4.tmp.bak",
            ".out.ply.123.4.tmpx",
            "..out.ply.123.4.tmp",
            ".out.ply.123.tmp",
            ".out.ply.1.123.4.tmp", // a temporary file of `out.ply.1`
            ".out.ply.0123.4.tmp",
            ".out.ply.123.04.tmp",
            ".out.ply.+123.4.tmp",
            ".out.ply.-1.4.tmp",
            ".out.ply.0.4.tmp",
            ".out.ply..4.tmp",
            ".out.ply.123..tmp",
            ".out.ply.x.4.tmp",
            ".out.ply.99999999999.4.tmp", // beyond u32
            ".out.plyx.123.4.tmp",
            ".out.123.4.tmp",
            ".other.ply.123.4.tmp",
        ] {
            assert_eq!(pid(other), None, "{other}");
        }
        // For the target `out.ply.1`, `out.ply`'s temporary file does not parse either.
        assert_eq!(
            temp_writer(OsStr::new(".out.ply.1.4.tmp"), OsStr::new("out.ply.1")),
            None
        );
    }

    /// The id of a process that has ended and been reaped.
    #[cfg(target_os = "linux")]
    fn dead_pid() -> u32 {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        assert!(!process_exists(pid));
        pid
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn stale_temps_of_the_target_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.ply");
        fs::write(&target, b"old").unwrap();
        let dead = dead_pid();
        let me = std::process::id();
        let stale = [
            format!(".out.ply.{dead}.0.tmp"),
            format!(".out.ply.{dead}.17.tmp"),
        ];
        let kept = [
            format!(".out.ply.{me}.999999.tmp"), // this process: maybe a live writer
            ".out.ply.1.5.tmp".to_owned(),       // pid 1 is alive
            format!(".out.ply.{dead}.0.tmp.bak"), // looks similar
            format!(".out.ply.0{dead}.0.tmp"),
            format!(".other.ply.{dead}.0.tmp"), // another target
            format!(".out.ply.1.{dead}.0.tmp"), // the target `out.ply.1`
        ];
        for f in stale.iter().chain(&kept) {
            fs::write(dir.path().join(f), b"partial").unwrap();
        }
        // A directory and a symbolic link named like stale temporaries stay too.
        let stale_dir = format!(".out.ply.{dead}.1.tmp");
        fs::create_dir(dir.path().join(&stale_dir)).unwrap();
        let stale_link = format!(".out.ply.{dead}.2.tmp");
        std::os::unix::fs::symlink(&target, dir.path().join(&stale_link)).unwrap();

        write_atomic(&target, |w| w.write_all(b"new")).unwrap();

        assert_eq!(fs::read(&target).unwrap(), b"new");
        for f in &stale {
            assert!(!dir.path().join(f).exists(), "{f} was not removed");
        }
        for f in kept.iter().chain([&stale_dir, &stale_link]) {
            assert!(
                dir.path().join(f).symlink_metadata().is_ok(),
                "{f} was removed"
            );
        }
        let mut names: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(names.len(), 1 + kept.len() + 2, "{names:?}");
    }
}

#[cfg(test)]
mod shell_word_tests {
    use super::*;

    #[test]
    fn shell_words_run_as_the_file_they_name() {
        assert_eq!(shell_word(Path::new("out/a.zsf")), "out/a.zsf");
        assert_eq!(shell_word(Path::new("-b.xyzn")), "./-b.xyzn");
        assert_eq!(shell_word(Path::new("my scan.ply")), "'my scan.ply'");
        assert_eq!(shell_word(Path::new("it's.ply")), r"'it'\''s.ply'");
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            let name = std::ffi::OsStr::from_bytes(b"b\xff'.xyzn");
            assert_eq!(shell_word(Path::new(name)), r"$'b\xff\'.xyzn'");
        }
    }
}
