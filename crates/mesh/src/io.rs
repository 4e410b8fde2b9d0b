//! Mesh files: PLY (read and write) and Wavefront OBJ (write).
//!
//! - [`write_ply`] writes a [`TriMesh`] as PLY, binary little-endian by default
//!   ([`PlyFormat`]): vertices as `float x y z`, normals as `float nx ny nz` when the mesh has
//!   them, and faces as `list uchar int vertex_indices`, with a `comment` naming zeroset. The
//!   header is the standard one that trimesh, Open3D, MeshLab and Blender read.
//! - [`write_obj`] writes `v`, `vn` (with normals) and 1-based `f a//a b//b c//c` (or `f a b c`)
//!   lines.
//! - [`read_ply_mesh`] reads a PLY mesh, ASCII or binary of either endianness: the `vertex`
//!   element's `x y z` (and `nx ny nz` when all three are there) are found by name among any
//!   other properties, of any scalar type (`char uchar short ushort int uint float double` and
//!   the `int8 uint8 int16 uint16 int32 uint32 float32 float64` aliases); faces are the list
//!   `vertex_indices` (or `vertex_index`) of the `face` element, with any count and index
//!   types; polygons with more than three corners are fan-triangulated; other elements are
//!   skipped. Vertices that no face uses are kept.
//!
//! All writes are atomic ([`write_atomic`]): a reader of the path sees the old file or the
//! complete new one. [`ply_to_bytes`], [`ply_from_bytes`] and [`obj_to_string`] do the same
//! in memory.
//!
//! Errors name the file and the place: the header line, or the record with its line (ASCII)
//! or byte offset (binary); a file that ends early is [`MeshError::PlyTruncated`] naming the
//! element and record; a face index out of range names the face. The header's element counts
//! are never trusted for allocations: room is reserved for at most as many records as the
//! bytes after the header can hold ([`records_that_fit`]), so a header that claims 10⁹
//! vertices in a 200-byte file is reported as truncated without a large allocation.
//!
//! Coordinates are written as 32-bit floats, so a round trip is exact for coordinates that are
//! `f32` values and otherwise rounds them to the nearest one.

use std::fmt::Write as _;
use std::path::Path;

use zeroset_field_core::Point;
use zeroset_field_core::io::{records_that_fit, write_atomic};

use crate::{MeshError, Result, TriMesh};

/// How [`write_ply`] encodes the records.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum PlyFormat {
    /// `format binary_little_endian 1.0`: compact and exact (the default).
    #[default]
    BinaryLittleEndian,
    /// `format ascii 1.0`: one record per line, human-readable.
    Ascii,
}

/// Writes `mesh` to `path` as PLY; see the [module docs](self).
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for a mesh with more vertices than a PLY `int` index can
/// hold; [`MeshError::Field`] wrapping an I/O error that names `path`.
pub fn write_ply(path: impl AsRef<Path>, mesh: &TriMesh, format: PlyFormat) -> Result<()> {
    let path = path.as_ref();
    let bytes = ply_bytes(path, mesh, format)?;
    write_atomic(path, |w| w.write_all(&bytes))?;
    Ok(())
}

/// The bytes [`write_ply`] writes.
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for a mesh with more than `i32::MAX` vertices.
pub fn ply_to_bytes(mesh: &TriMesh, format: PlyFormat) -> Result<Vec<u8>> {
    ply_bytes(Path::new("<memory>"), mesh, format)
}

fn ply_bytes(path: &Path, mesh: &TriMesh, format: PlyFormat) -> Result<Vec<u8>> {
    if i32::try_from(mesh.num_vertices()).is_err() {
        return Err(MeshError::UnsupportedFormat {
            path: path.to_owned(),
            detail: format!(
                "{} vertices do not fit the PLY 'int' vertex indices",
                mesh.num_vertices()
            ),
        });
    }
    let normals = !mesh.normals().is_empty();
    let mut header = String::from("ply\n");
    header.push_str(match format {
        PlyFormat::BinaryLittleEndian => "format binary_little_endian 1.0\n",
        PlyFormat::Ascii => "format ascii 1.0\n",
    });
    header.push_str("comment written by zeroset (zeroset-mesh)\n");
    let _ = writeln!(header, "element vertex {}", mesh.num_vertices());
    for name in ["x", "y", "z"] {
        let _ = writeln!(header, "property float {name}");
    }
    if normals {
        for name in ["nx", "ny", "nz"] {
            let _ = writeln!(header, "property float {name}");
        }
    }
    let _ = writeln!(header, "element face {}", mesh.num_triangles());
    header.push_str("property list uchar int vertex_indices\nend_header\n");

    let mut out = header.into_bytes();
    match format {
        PlyFormat::BinaryLittleEndian => {
            let per_vertex = if normals { 24 } else { 12 };
            out.reserve(mesh.num_vertices() * per_vertex + mesh.num_triangles() * 13);
            for (i, p) in mesh.vertices().iter().enumerate() {
                for v in p {
                    out.extend_from_slice(&(*v as f32).to_le_bytes());
                }
                if normals {
                    for v in &mesh.normals()[i] {
                        out.extend_from_slice(&(*v as f32).to_le_bytes());
                    }
                }
            }
            for tri in mesh.triangles() {
                out.push(3);
                for &v in tri {
                    // In range: v < num_vertices <= i32::MAX (checked above).
                    out.extend_from_slice(&(v as i32).to_le_bytes());
                }
            }
        }
        PlyFormat::Ascii => {
            let mut text = String::new();
            for (i, p) in mesh.vertices().iter().enumerate() {
                let _ = write!(text, "{} {} {}", p[0] as f32, p[1] as f32, p[2] as f32);
                if normals {
                    let n = mesh.normals()[i];
                    let _ = write!(text, " {} {} {}", n[0] as f32, n[1] as f32, n[2] as f32);
                }
                text.push('\n');
            }
            for [a, b, c] in mesh.triangles() {
                let _ = writeln!(text, "3 {a} {b} {c}");
            }
            out.extend_from_slice(text.as_bytes());
        }
    }
    Ok(out)
}

/// Writes `mesh` to `path` as Wavefront OBJ: a comment line, `v x y z` per vertex, `vn` per
/// normal if the mesh has them, and `f a//a b//b c//c` (with normals) or `f a b c` per
/// triangle, 1-based. Coordinates are written in full `f64` precision (shortest round-trip
/// form).
///
/// # Errors
/// [`MeshError::Field`] wrapping an I/O error that names `path`.
pub fn write_obj(path: impl AsRef<Path>, mesh: &TriMesh) -> Result<()> {
    let text = obj_to_string(mesh);
    write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

/// The text [`write_obj`] writes.
pub fn obj_to_string(mesh: &TriMesh) -> String {
    let mut s = String::from("# written by zeroset (zeroset-mesh)\n");
    for [x, y, z] in mesh.vertices() {
        let _ = writeln!(s, "v {x} {y} {z}");
    }
    for [x, y, z] in mesh.normals() {
        let _ = writeln!(s, "vn {x} {y} {z}");
    }
    let normals = !mesh.normals().is_empty();
    for tri in mesh.triangles() {
        let [a, b, c] = tri.map(|v| u64::from(v) + 1);
        if normals {
            let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
        } else {
            let _ = writeln!(s, "f {a} {b} {c}");
        }
    }
    s
}

/// Reads a PLY mesh from `path`; see the [module docs](self).
///
/// # Errors
/// - [`MeshError::Field`] wrapping an I/O error that names `path` (a missing file, ...).
/// - [`MeshError::UnsupportedFormat`] for a file that does not start with `ply`, or an unknown
///   encoding.
/// - [`MeshError::Ply`] naming the header line or the record: a malformed header, no `vertex`
///   element or no `x`/`y`/`z`, a value that does not parse or fit its type, a non-finite
///   coordinate, a face with fewer than 3 corners or an index out of range.
/// - [`MeshError::PlyTruncated`] naming the element and record where the file ends.
pub fn read_ply_mesh(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| zeroset_field_core::Error::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_ply(path, &bytes)
}

/// Parses PLY `bytes` as [`read_ply_mesh`] does; `name` stands for the file in errors.
///
/// # Errors
/// As [`read_ply_mesh`], less the I/O errors.
pub fn ply_from_bytes(bytes: &[u8], name: &str) -> Result<TriMesh> {
    parse_ply(Path::new(name), bytes)
}

// ---------------------------------------------------------------------------------------------
// Reading.

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    /// The range of an integer type.
    fn range(self) -> (i64, i64) {
        match self {
            Self::I8 => (i8::MIN.into(), i8::MAX.into()),
            Self::U8 => (0, u8::MAX.into()),
            Self::I16 => (i16::MIN.into(), i16::MAX.into()),
            Self::U16 => (0, u16::MAX.into()),
            Self::I32 => (i32::MIN.into(), i32::MAX.into()),
            Self::U32 => (0, u32::MAX.into()),
            Self::F32 | Self::F64 => (i64::MIN, i64::MAX),
        }
    }

    /// Decodes one value from exactly `self.size()` bytes.
    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(b);
                if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            Self::I8 => f64::from(b[0] as i8),
            Self::U8 => f64::from(b[0]),
            Self::I16 => f64::from(num!(i16, 2)),
            Self::U16 => f64::from(num!(u16, 2)),
            Self::I32 => f64::from(num!(i32, 4)),
            Self::U32 => f64::from(num!(u32, 4)),
            Self::F32 => f64::from(num!(f32, 4)),
            Self::F64 => num!(f64, 8),
        }
    }

    /// Parses one ASCII token; `None` if it is not a number of this type.
    fn parse_token(self, token: &str) -> Option<f64> {
        if self.is_integer() {
            let v: i64 = token.parse().ok()?;
            let (lo, hi) = self.range();
            (lo..=hi).contains(&v).then_some(v as f64)
        } else {
            let v: f64 = token.parse().ok()?;
            Some(if self == Self::F32 {
                f64::from(v as f32)
            } else {
                v
            })
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    fn find(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { big: bool },
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the first record.
    body: usize,
    /// The number of header lines (the body starts on line `lines + 1`).
    lines: usize,
}

fn ply_error(path: &Path, place: impl Into<String>, detail: impl Into<String>) -> MeshError {
    MeshError::Ply {
        path: path.to_owned(),
        place: place.into(),
        detail: detail.into(),
    }
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() {
            return Err(ply_error(
                path,
                format!("header line {}", line_no + 1),
                "the file ends before 'end_header'",
            ));
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| pos + i);
        let raw = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        line_no += 1;
        let place = format!("header line {line_no}");
        let Ok(line) = std::str::from_utf8(raw) else {
            if line_no == 1 {
                return Err(not_ply(path));
            }
            return Err(ply_error(path, place, "the header line is not ASCII text"));
        };
        let line = line.trim_end_matches('\r');
        let mut words = line.split_ascii_whitespace();
        let keyword = words.next().unwrap_or("");
        if line_no == 1 {
            if line.trim() != "ply" {
                return Err(not_ply(path));
            }
            continue;
        }
        match keyword {
            "" | "comment" | "obj_info" => {}
            "format" => {
                let name = words.next().unwrap_or("");
                let version = words.next().unwrap_or("");
                encoding = Some(match name {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Binary { big: false },
                    "binary_big_endian" => Encoding::Binary { big: true },
                    _ => {
                        return Err(MeshError::UnsupportedFormat {
                            path: path.to_owned(),
                            detail: format!(
                                "{place}: PLY encoding {name:?} (expected ascii, \
                                 binary_little_endian or binary_big_endian)"
                            ),
                        });
                    }
                });
                if version != "1.0" {
                    return Err(MeshError::UnsupportedFormat {
                        path: path.to_owned(),
                        detail: format!("{place}: PLY version {version:?} (expected 1.0)"),
                    });
                }
            }
            "element" => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(ply_error(path, place, "expected 'element <name> <count>'"));
                };
                let count = count.parse::<usize>().map_err(|_| {
                    ply_error(
                        path,
                        &place,
                        format!("element count {count:?} is not a non-negative integer"),
                    )
                })?;
                elements.push(Element {
                    name: name.to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(ply_error(path, place, "'property' before any 'element'"));
                };
                let words: Vec<&str> = words.collect();
                let bad_type = |t: &str| {
                    ply_error(
                        path,
                        &place,
                        format!(
                            "unknown property type {t:?} (expected char, uchar, short, ushort, \
                             int, uint, float, double or int8 ... float64)"
                        ),
                    )
                };
                let (kind, name) = match words.as_slice() {
                    ["list", count, item, name] => {
                        let count = Scalar::parse(count).ok_or_else(|| bad_type(count))?;
                        let item = Scalar::parse(item).ok_or_else(|| bad_type(item))?;
                        if !count.is_integer() {
                            return Err(ply_error(
                                path,
                                place,
                                format!("list count type of '{name}' must be an integer type"),
                            ));
                        }
                        (Kind::List { count, item }, *name)
                    }
                    [t, name] if *t != "list" => (
                        Kind::Scalar(Scalar::parse(t).ok_or_else(|| bad_type(t))?),
                        *name,
                    ),
                    _ => {
                        return Err(ply_error(
                            path,
                            place,
                            "expected 'property <type> <name>' or \
                             'property list <count type> <item type> <name>'",
                        ));
                    }
                };
                if element.find(name).is_some() {
                    return Err(ply_error(
                        path,
                        place,
                        format!("property '{name}' repeated in element '{}'", element.name),
                    ));
                }
                element.properties.push(Property {
                    name: name.to_owned(),
                    kind,
                });
            }
            "end_header" => break,
            other => {
                return Err(ply_error(
                    path,
                    place,
                    format!("unknown header keyword {other:?}"),
                ));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(ply_error(path, "header", "no 'format' line"));
    };
    if let Some(e) = elements
        .iter()
        .find(|e| e.count > 0 && e.properties.is_empty())
    {
        return Err(ply_error(
            path,
            "header",
            format!(
                "element '{}' has {} records but no property",
                e.name, e.count
            ),
        ));
    }
    Ok(Header {
        encoding,
        elements,
        body: pos,
        lines: line_no,
    })
}

fn not_ply(path: &Path) -> MeshError {
    MeshError::UnsupportedFormat {
        path: path.to_owned(),
        detail: "not a PLY file (the first line is not 'ply')".to_owned(),
    }
}

/// One record's values, flattened: a scalar is one value, a list is its count then its items;
/// `starts[p]` is where property `p` begins.
#[derive(Default)]
struct Record {
    values: Vec<f64>,
    starts: Vec<usize>,
}

/// The record source: ASCII lines or binary bytes.
enum Body<'a> {
    Ascii {
        rest: &'a [u8],
        /// The 1-based line number of the next line in `rest`.
        line: usize,
    },
    Binary {
        bytes: &'a [u8],
        pos: usize,
        big: bool,
    },
}

/// Where a record sits, for messages.
fn place(element: &Element, record: usize, line: Option<usize>, byte: Option<usize>) -> String {
    match (line, byte) {
        (Some(l), _) => format!("line {l} ({} {record})", element.name),
        (None, Some(b)) => format!("{} {record} (byte {b})", element.name),
        (None, None) => format!("{} {record}", element.name),
    }
}

impl Body<'_> {
    /// How many records of `element` the bytes left can hold at most (see
    /// [`records_that_fit`]): a binary record takes at least its scalars and list counts, an
    /// ASCII record at least two bytes (a digit and a separator) per property.
    fn records_that_fit(&self, element: &Element) -> usize {
        let (left, min_record) = match self {
            Body::Ascii { rest, .. } => (rest.len() + 1, 2 * element.properties.len()),
            Body::Binary { bytes, pos, .. } => (
                bytes.len().saturating_sub(*pos),
                element
                    .properties
                    .iter()
                    .map(|p| match p.kind {
                        Kind::Scalar(t) | Kind::List { count: t, .. } => t.size(),
                    })
                    .sum(),
            ),
        };
        records_that_fit(element.count, left as u64, min_record)
    }

    /// Reads record `index` of `element` into `out`; returns its place for messages.
    fn read(
        &mut self,
        path: &Path,
        element: &Element,
        index: usize,
        out: &mut Record,
    ) -> Result<String> {
        out.values.clear();
        out.starts.clear();
        let truncated = || MeshError::PlyTruncated {
            path: path.to_owned(),
            element: element.name.clone(),
            record: index,
            expected: element.count,
        };
        match self {
            Body::Ascii { rest, line } => {
                // The next non-blank line.
                let text = loop {
                    if rest.is_empty() {
                        return Err(truncated());
                    }
                    let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
                    let raw = &rest[..end];
                    *rest = &rest[(end + 1).min(rest.len())..];
                    *line += 1;
                    if raw.iter().any(|b| !b.is_ascii_whitespace()) {
                        break raw;
                    }
                };
                let here = place(element, index, Some(*line - 1), None);
                let text = std::str::from_utf8(text)
                    .map_err(|_| ply_error(path, &here, "the line is not ASCII text"))?;
                let mut tokens = text.split_ascii_whitespace();
                let mut next = |name: &str, t: Scalar| -> Result<f64> {
                    let token = tokens.next().ok_or_else(|| {
                        ply_error(path, &here, format!("the line ends before '{name}'"))
                    })?;
                    t.parse_token(token).ok_or_else(|| {
                        ply_error(
                            path,
                            &here,
                            format!("'{name}' = {token:?} is not a valid {t:?} value"),
                        )
                    })
                };
                for p in &element.properties {
                    out.starts.push(out.values.len());
                    match p.kind {
                        Kind::Scalar(t) => out.values.push(next(&p.name, t)?),
                        Kind::List { count, item } => {
                            let n = next(&p.name, count)?;
                            let n = list_len(path, &here, &p.name, n)?;
                            out.values.push(n as f64);
                            for _ in 0..n {
                                out.values.push(next(&p.name, item)?);
                            }
                        }
                    }
                }
                if let Some(extra) = tokens.next() {
                    return Err(ply_error(
                        path,
                        &here,
                        format!("unexpected value {extra:?} after the record's last property"),
                    ));
                }
                Ok(here)
            }
            Body::Binary { bytes, pos, big } => {
                let here = place(element, index, None, Some(*pos));
                let big = *big;
                let mut take = |t: Scalar| -> Result<f64> {
                    let n = t.size();
                    let b = bytes.get(*pos..*pos + n).ok_or_else(truncated)?;
                    *pos += n;
                    Ok(t.decode(b, big))
                };
                for p in &element.properties {
                    out.starts.push(out.values.len());
                    match p.kind {
                        Kind::Scalar(t) => out.values.push(take(t)?),
                        Kind::List { count, item } => {
                            let n = take(count)?;
                            let n = list_len(path, &here, &p.name, n)?;
                            out.values.push(n as f64);
                            for _ in 0..n {
                                out.values.push(take(item)?);
                            }
                        }
                    }
                }
                Ok(here)
            }
        }
    }
}

fn list_len(path: &Path, here: &str, name: &str, n: f64) -> Result<usize> {
    if n < 0.0 {
        return Err(ply_error(
            path,
            here,
            format!("list '{name}' has a negative length {n}"),
        ));
    }
    Ok(n as usize)
}

fn parse_ply(path: &Path, bytes: &[u8]) -> Result<TriMesh> {
    let header = parse_header(path, bytes)?;
    let Some(vertex_el) = header.elements.iter().position(|e| e.name == "vertex") else {
        return Err(ply_error(path, "header", "no 'vertex' element"));
    };
    let scalar_prop = |name: &str| -> Result<Option<usize>> {
        let el = &header.elements[vertex_el];
        match el.find(name) {
            Some(i) if matches!(el.properties[i].kind, Kind::List { .. }) => Err(ply_error(
                path,
                "header",
                format!("vertex property '{name}' is a list, expected a scalar"),
            )),
            found => Ok(found),
        }
    };
    let mut xyz = [0; 3];
    for (slot, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
        *slot = scalar_prop(name)?.ok_or_else(|| {
            ply_error(
                path,
                "header",
                format!("the vertex element has no '{name}'"),
            )
        })?;
    }
    let nxyz = [scalar_prop("nx")?, scalar_prop("ny")?, scalar_prop("nz")?];
    let normal_slots = match nxyz {
        [Some(a), Some(b), Some(c)] => Some([a, b, c]),
        [None, None, None] => None,
        _ => {
            let missing = ["nx", "ny", "nz"][nxyz.iter().position(Option::is_none).unwrap_or(0)];
            return Err(ply_error(
                path,
                "header",
                format!("the vertex element has some normal components but no '{missing}'"),
            ));
        }
    };
    let face_el = header.elements.iter().position(|e| e.name == "face");
    let face_list = match face_el {
        None => None,
        Some(f) => {
            let el = &header.elements[f];
            let i = el
                .find("vertex_indices")
                .or_else(|| el.find("vertex_index"))
                .ok_or_else(|| {
                    ply_error(
                        path,
                        "header",
                        "the face element has no 'vertex_indices' (or 'vertex_index') list",
                    )
                })?;
            if !matches!(el.properties[i].kind, Kind::List { .. }) {
                return Err(ply_error(
                    path,
                    "header",
                    format!("face property '{}' is not a list", el.properties[i].name),
                ));
            }
            Some(i)
        }
    };

    let mut body = match header.encoding {
        Encoding::Ascii => Body::Ascii {
            rest: &bytes[header.body..],
            line: header.lines + 1,
        },
        Encoding::Binary { big } => Body::Binary {
            bytes,
            pos: header.body,
            big,
        },
    };
    let vertex_count = header.elements[vertex_el].count;
    let mut vertices: Vec<Point<3>> = Vec::new();
    let mut normals: Vec<Point<3>> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut record = Record::default();
    for (e, element) in header.elements.iter().enumerate() {
        if e == vertex_el {
            // Never from the header's count alone: a file whose count it cannot hold is
            // reported as truncated by `body.read`, after at most that many records.
            let capacity = body.records_that_fit(element);
            vertices.reserve(capacity);
            if normal_slots.is_some() {
                normals.reserve(capacity);
            }
        } else if Some(e) == face_el {
            triangles.reserve(body.records_that_fit(element));
        }
        for r in 0..element.count {
            let here = body.read(path, element, r, &mut record)?;
            if e == vertex_el {
                let get = |slots: [usize; 3]| slots.map(|s| record.values[record.starts[s]]);
                let p = get(xyz);
                if let Some(axis) = p.iter().position(|v| !v.is_finite()) {
                    return Err(ply_error(
                        path,
                        here,
                        format!(
                            "coordinate {} is not finite: {}",
                            ["x", "y", "z"][axis],
                            p[axis]
                        ),
                    ));
                }
                vertices.push(p);
                if let Some(slots) = normal_slots {
                    let n = get(slots);
                    if let Some(axis) = n.iter().position(|v| !v.is_finite()) {
                        return Err(ply_error(
                            path,
                            here,
                            format!(
                                "normal component {} is not finite: {}",
                                ["nx", "ny", "nz"][axis],
                                n[axis]
                            ),
                        ));
                    }
                    normals.push(n);
                }
            } else if Some(e) == face_el {
                let start = record.starts[face_list.unwrap_or(0)];
                let n = record.values[start] as usize;
                let items = &record.values[start + 1..start + 1 + n];
                if n < 3 {
                    return Err(ply_error(
                        path,
                        here,
                        format!("the face has {n} corner(s); at least 3 are needed"),
                    ));
                }
                let mut corners = [0u32; 3];
                let fan = |k: usize, v: f64| -> Result<u32> {
                    if v.fract() != 0.0 || v < 0.0 || v >= vertex_count as f64 {
                        return Err(ply_error(
                            path,
                            &here,
                            format!(
                                "corner {k} refers to vertex {v}, out of range for the \
                                 {vertex_count} vertices"
                            ),
                        ));
                    }
                    u32::try_from(v as u64).map_err(|_| MeshError::UnsupportedFormat {
                        path: path.to_owned(),
                        detail: format!("{here}: vertex index {v} does not fit 32 bits"),
                    })
                };
                corners[0] = fan(0, items[0])?;
                corners[2] = fan(1, items[1])?;
                for (k, &v) in items.iter().enumerate().skip(2) {
                    corners[1] = corners[2];
                    corners[2] = fan(k, v)?;
                    triangles.push(corners);
                }
            }
        }
    }
    let mesh = TriMesh::new(vertices, triangles)?;
    if normal_slots.is_some() {
        mesh.with_normals(normals)
    } else {
        Ok(mesh)
    }
}
