//! STL meshes (read and write), the format 3-D printing and CAD software exchange.
//!
//! An STL file is a list of triangles, each with its three corners written out and a facet
//! normal; there are no shared vertices. Binary STL is an 80-byte header, a little-endian
//! `u32` triangle count and 50 bytes per triangle (normal, three corners as `f32`, a 2-byte
//! attribute); ASCII STL is `solid NAME`, then `facet normal nx ny nz / outer loop / vertex x
//! y z (×3) / endloop / endfacet` per triangle, then `endsolid NAME`.
//!
//! - [`write_stl`] writes a [`TriMesh`]'s triangles, binary by default ([`StlFormat`]), each
//!   with its unit normal `(b − a) × (c − a)` (zeroset's outward winding; zero for a
//!   triangle without area). The binary header names zeroset and does not begin with `solid`,
//!   so no reader takes it for ASCII. Vertices no triangle uses, and per-vertex normals, have
//!   no place in STL and are not written.
//! - [`read_stl_mesh`] reads either encoding and welds the corners back into shared vertices:
//!   corners with the same coordinates (`−0` and `0` alike) become one vertex, numbered in
//!   the order they first appear, so the mesh's topology (closed, Euler characteristic,
//!   boundary loops) can be checked. Facet normals are not read: the winding gives the
//!   orientation, and many writers leave the normals zero. A file is binary when its length
//!   is exactly what its count announces (many binary files begin with `solid` too), ASCII
//!   when it begins with `solid` and its first bytes are text, and otherwise binary (text
//!   that does not begin with `solid` is an error that says so, not a binary count). ASCII
//!   coordinates are rounded to `f32`, as binary ones are stored, so one mesh reads back the
//!   same from either encoding.
//!
//! Errors name the file and the place: the triangle and its byte offset (binary) or the line
//! (ASCII). A binary file shorter than its count announces is reported as truncated, naming
//! the first triangle that is missing, without allocating for the count; bytes after the
//! last triangle are ignored (some writers pad). Non-finite coordinates are errors.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use zeroset_field_core::Point;
use zeroset_field_core::io::write_atomic;

use crate::trimesh::{area_vector, unit_or_zero};
use crate::{MeshError, Result, TriMesh};

/// How [`write_stl`] encodes the triangles.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum StlFormat {
    /// Binary STL: 50 bytes a triangle, exact for `f32` coordinates (the default).
    #[default]
    Binary,
    /// ASCII STL: `facet normal ... endfacet` blocks, the shortest text for each `f32`.
    Ascii,
}

/// Bytes before the first triangle of a binary STL: the header and the count.
const BINARY_HEADER: usize = 84;
/// Bytes per triangle of a binary STL.
const BINARY_TRIANGLE: usize = 50;

/// Writes `mesh`'s triangles to `path` as STL; see the [module docs](self). The write is
/// atomic.
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for more triangles than a binary STL's `u32` count holds;
/// [`MeshError::Field`] wrapping an I/O error that names `path`.
pub fn write_stl(path: impl AsRef<Path>, mesh: &TriMesh, format: StlFormat) -> Result<()> {
    let path = path.as_ref();
    let bytes = stl_bytes(path, mesh, format)?;
    write_atomic(path, |w| w.write_all(&bytes))?;
    Ok(())
}

/// The bytes [`write_stl`] writes.
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for more than `u32::MAX` triangles (binary).
pub fn stl_to_bytes(mesh: &TriMesh, format: StlFormat) -> Result<Vec<u8>> {
    stl_bytes(Path::new("<memory>"), mesh, format)
}

fn stl_bytes(path: &Path, mesh: &TriMesh, format: StlFormat) -> Result<Vec<u8>> {
    if let Some(p) = mesh
        .vertices()
        .iter()
        .find(|p| p.iter().any(|x| !(*x as f32).is_finite()))
    {
        return Err(MeshError::UnsupportedFormat {
            path: path.to_owned(),
            detail: format!("vertex {p:?} is beyond the 32-bit float range of STL"),
        });
    }
    // The corners as written (f32), and the normal of those: a file read back and written
    // again is byte-identical.
    let corners =
        |tri: &[u32; 3]| tri.map(|v| mesh.vertices()[v as usize].map(|x| f64::from(x as f32)));
    match format {
        StlFormat::Binary => {
            let count =
                u32::try_from(mesh.num_triangles()).map_err(|_| MeshError::UnsupportedFormat {
                    path: path.to_owned(),
                    detail: format!(
                        "{} triangles do not fit a binary STL's 32-bit count",
                        mesh.num_triangles()
                    ),
                })?;
            let mut out = Vec::with_capacity(BINARY_HEADER + BINARY_TRIANGLE * count as usize);
            out.extend_from_slice(b"binary STL written by zeroset (zeroset-mesh)");
            out.resize(80, b' ');
            out.extend_from_slice(&count.to_le_bytes());
            for tri in mesh.triangles() {
                let p = corners(tri);
                for v in facet_normal(&p).iter().chain(p.iter().flatten()) {
                    out.extend_from_slice(&(*v as f32).to_le_bytes());
                }
                out.extend_from_slice(&0u16.to_le_bytes());
            }
            Ok(out)
        }
        StlFormat::Ascii => {
            let mut s = String::from("solid zeroset\n");
            for tri in mesh.triangles() {
                let p = corners(tri);
                let [nx, ny, nz] = facet_normal(&p).map(|v| v as f32);
                let _ = writeln!(s, "  facet normal {nx} {ny} {nz}\n    outer loop");
                for [x, y, z] in p.map(|c| c.map(|v| v as f32)) {
                    let _ = writeln!(s, "      vertex {x} {y} {z}");
                }
                s.push_str("    endloop\n  endfacet\n");
            }
            s.push_str("endsolid zeroset\n");
            Ok(s.into_bytes())
        }
    }
}

/// The unit normal `(b − a) × (c − a) / |…|` of a triangle, or zero for one without area.
fn facet_normal(corners: &[Point<3>; 3]) -> Point<3> {
    unit_or_zero(&area_vector(corners))
}

/// Reads an STL mesh (binary or ASCII) from `path`; see the [module docs](self).
///
/// # Errors
/// - [`MeshError::Field`] wrapping an I/O error that names `path`.
/// - [`MeshError::Malformed`] naming the triangle (binary, with its byte offset) or the line
///   (ASCII): a file that ends before the triangles its count announces, a non-finite
///   coordinate, an ASCII statement out of place or a number that does not parse, a facet
///   without three corners; a file too short to be either encoding.
/// - [`MeshError::UnsupportedFormat`] for more distinct vertices than 32-bit indices hold.
pub fn read_stl_mesh(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let bytes = zeroset_field_core::io::ply::read_whole(path)?;
    parse_stl(path, &bytes)
}

/// Parses STL `bytes` as [`read_stl_mesh`] does; `name` stands for the file in errors.
///
/// # Errors
/// As [`read_stl_mesh`], less the I/O errors.
pub fn stl_from_bytes(bytes: &[u8], name: &str) -> Result<TriMesh> {
    parse_stl(Path::new(name), bytes)
}

fn parse_stl(path: &Path, bytes: &[u8]) -> Result<TriMesh> {
    let announced = (bytes.len() >= BINARY_HEADER).then(|| {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]);
        BINARY_HEADER as u64 + BINARY_TRIANGLE as u64 * u64::from(count)
    });
    if announced == Some(bytes.len() as u64) {
        return parse_binary(path, bytes);
    }
    if looks_ascii(bytes) {
        return parse_ascii(path, bytes);
    }
    let header_error = |detail: String| MeshError::Malformed {
        path: path.to_owned(),
        format: "STL",
        place: "header".into(),
        detail,
    };
    if announced.is_none() {
        return Err(header_error(format!(
            "{} bytes: too short for a binary STL (its header and count take 84) and not ASCII \
             STL (which begins with 'solid')",
            bytes.len()
        )));
    }
    if is_text(bytes) {
        // A binary file's count and coordinates are almost never all printable bytes.
        return Err(header_error(
            "the file is text, but not ASCII STL (which begins with 'solid'); a point cloud or \
             another format named .stl?"
                .into(),
        ));
    }
    parse_binary(path, bytes)
}

/// The UTF-8 byte-order mark some editors put before text.
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// Whether the first bytes (up to 512, after a byte-order mark) are text: no control bytes
/// but whitespace (bytes above 127 are allowed: a name in UTF-8 or Latin-1).
fn is_text(bytes: &[u8]) -> bool {
    let bytes = bytes.strip_prefix(BOM).unwrap_or(bytes);
    bytes[..bytes.len().min(512)]
        .iter()
        .all(|&b| !b.is_ascii_control() || b.is_ascii_whitespace())
}

/// Whether the file reads as ASCII STL: `solid` first (after a byte-order mark and
/// whitespace), then text ([`is_text`]) or `facet` or `endsolid` among its first kilobyte —
/// which a binary file whose header happens to begin with `solid` does not hold.
fn looks_ascii(bytes: &[u8]) -> bool {
    let bytes = bytes.strip_prefix(BOM).unwrap_or(bytes);
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    let head = &bytes[start..bytes.len().min(start + 1024)];
    let lower = head.to_ascii_lowercase();
    let holds = |word: &[u8]| lower.windows(word.len()).any(|w| w == word);
    lower.starts_with(b"solid") && (holds(b"facet") || holds(b"endsolid") || is_text(bytes))
}

/// Corners welded into shared vertices by their coordinates.
#[derive(Default)]
struct Welder {
    vertices: Vec<Point<3>>,
    index: HashMap<[u64; 3], u32>,
}

impl Welder {
    /// The vertex at `p` (`−0` and `0` are one coordinate), added if new; `None` past
    /// `u32::MAX` vertices.
    fn vertex(&mut self, p: Point<3>) -> Option<u32> {
        let key = p.map(|v| (v + 0.0).to_bits());
        if let Some(&i) = self.index.get(&key) {
            return Some(i);
        }
        let i = u32::try_from(self.vertices.len()).ok()?;
        self.vertices.push(p);
        self.index.insert(key, i);
        Some(i)
    }
}

fn too_many_vertices(path: &Path) -> MeshError {
    MeshError::UnsupportedFormat {
        path: path.to_owned(),
        detail: "more distinct vertices than 32-bit indices hold".into(),
    }
}

fn parse_binary(path: &Path, bytes: &[u8]) -> Result<TriMesh> {
    let present = (bytes.len() - BINARY_HEADER) / BINARY_TRIANGLE;
    let mut count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    if count == 0 && present > 0 && (bytes.len() - BINARY_HEADER).is_multiple_of(BINARY_TRIANGLE) {
        // A count left at 0 by a writer that streams the triangles: the file's length says
        // how many it holds.
        count = present;
    }
    let malformed = |t: usize, detail: String| MeshError::Malformed {
        path: path.to_owned(),
        format: "STL",
        place: format!(
            "binary triangle {t} (byte {})",
            BINARY_HEADER + t * BINARY_TRIANGLE
        ),
        detail,
    };
    if present < count {
        return Err(malformed(
            present,
            format!(
                "truncated: the file ends in this triangle, of the {count} its count announces \
                 ({} bytes expected, {} found)",
                BINARY_HEADER as u64 + BINARY_TRIANGLE as u64 * count as u64,
                bytes.len()
            ),
        ));
    }
    let mut welder = Welder::default();
    let mut triangles = Vec::with_capacity(count);
    for (t, record) in bytes[BINARY_HEADER..]
        .chunks_exact(BINARY_TRIANGLE)
        .take(count)
        .enumerate()
    {
        let value = |k: usize| {
            let at = 12 + 4 * k;
            f64::from(f32::from_le_bytes([
                record[at],
                record[at + 1],
                record[at + 2],
                record[at + 3],
            ]))
        };
        let mut tri = [0; 3];
        for (corner, slot) in tri.iter_mut().enumerate() {
            let p = [
                value(3 * corner),
                value(3 * corner + 1),
                value(3 * corner + 2),
            ];
            if let Some(axis) = p.iter().position(|v| !v.is_finite()) {
                return Err(malformed(
                    t,
                    format!(
                        "corner {corner} coordinate {} is not finite: {}",
                        ["x", "y", "z"][axis],
                        p[axis]
                    ),
                ));
            }
            *slot = welder.vertex(p).ok_or_else(|| too_many_vertices(path))?;
        }
        triangles.push(tri);
    }
    TriMesh::new(welder.vertices, triangles)
}

/// The words of ASCII STL text with their line numbers (lines end at `\n`, `\r\n` or a lone
/// `\r`, as old Mac files have them).
fn words(text: &str) -> impl Iterator<Item = (&str, usize)> {
    let mut line = 1;
    let mut rest = text;
    std::iter::from_fn(move || {
        loop {
            let start = rest.find(|c: char| !c.is_whitespace())?;
            for (i, c) in rest[..start].char_indices() {
                if c == '\n' || (c == '\r' && !rest[i + 1..].starts_with('\n')) {
                    line += 1;
                }
            }
            rest = &rest[start..];
            let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            let word = &rest[..end];
            rest = &rest[end..];
            if !word.is_empty() {
                return Some((word, line));
            }
        }
    })
}

/// Where the ASCII reader is in the `solid ... endsolid` grammar.
#[derive(Clone, Copy, PartialEq, Debug)]
enum State {
    /// Before `solid`, or after `endsolid` and its name.
    Outside,
    /// Inside a solid, between facets (or on the `solid` line, reading its name).
    Solid,
    /// After `facet normal nx ny nz`, before `outer loop`.
    Facet,
    /// Inside `outer loop`, reading corners.
    Loop,
    /// After `endloop`, before `endfacet`.
    Looped,
}

fn parse_ascii(path: &Path, bytes: &[u8]) -> Result<TriMesh> {
    let malformed = |line: usize, detail: String| MeshError::Malformed {
        path: path.to_owned(),
        format: "STL",
        place: format!("line {line}"),
        detail,
    };
    // Names may be in any encoding; the keywords and numbers are ASCII. Trailing NUL padding
    // is not part of the text.
    let bytes = bytes.strip_prefix(BOM).unwrap_or(bytes);
    let end = bytes.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    let text = String::from_utf8_lossy(&bytes[..end]);
    let mut welder = Welder::default();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut corners: Vec<u32> = Vec::new();
    let mut state = State::Outside;
    // The line of the last `solid` or `endsolid`: words after it on that line are its name.
    let mut name_line = 0;
    let mut facet_line = 0;
    let mut solids = 0;
    let mut words = words(&text);
    let truncated = |line: usize| {
        malformed(
            line,
            "truncated: the file ends inside the facet that begins here".into(),
        )
    };
    while let Some((word, line)) = words.next() {
        let keyword = word.to_ascii_lowercase();
        let expect = |wanted: State, what: &str| {
            if state == wanted {
                Ok(())
            } else {
                Err(malformed(
                    line,
                    format!("'{word}' {what} (the file is {})", describe(state)),
                ))
            }
        };
        state = match keyword.as_str() {
            "solid" if state == State::Outside => {
                solids += 1;
                name_line = line;
                State::Solid
            }
            "facet" => {
                expect(State::Solid, "begins a facet, which belongs inside a solid")?;
                facet_line = line;
                match words.next() {
                    Some((w, _)) if w.eq_ignore_ascii_case("normal") => {}
                    Some((w, l)) => {
                        return Err(malformed(
                            l,
                            format!("'facet {w}': expected 'facet normal'"),
                        ));
                    }
                    None => return Err(truncated(facet_line)),
                }
                // The facet normal: read past, not used (the winding gives the orientation).
                for _ in 0..3 {
                    words.next().ok_or_else(|| truncated(facet_line))?;
                }
                State::Facet
            }
            "outer" => {
                expect(State::Facet, "begins a loop, which belongs inside a facet")?;
                match words.next() {
                    Some((w, _)) if w.eq_ignore_ascii_case("loop") => {}
                    Some((w, l)) => {
                        return Err(malformed(l, format!("'outer {w}': expected 'outer loop'")));
                    }
                    None => return Err(truncated(facet_line)),
                }
                corners.clear();
                State::Loop
            }
            "vertex" => {
                expect(
                    State::Loop,
                    "is a corner, which belongs inside an outer loop",
                )?;
                let mut p = [0.0; 3];
                for (axis, value) in p.iter_mut().enumerate() {
                    let name = ["x", "y", "z"][axis];
                    let Some((w, l)) = words.next() else {
                        return Err(truncated(facet_line));
                    };
                    *value = ascii_coordinate(w, name).map_err(|d| malformed(l, d))?;
                }
                corners.push(welder.vertex(p).ok_or_else(|| too_many_vertices(path))?);
                State::Loop
            }
            "endloop" => {
                expect(State::Loop, "ends a loop that is not open")?;
                if corners.len() < 3 {
                    return Err(malformed(
                        line,
                        format!(
                            "the facet has {} corner(s); at least 3 are needed",
                            corners.len()
                        ),
                    ));
                }
                for k in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                }
                State::Looped
            }
            "endfacet" => {
                expect(State::Looped, "ends a facet whose loop is not closed")?;
                State::Solid
            }
            "endsolid" => {
                expect(State::Solid, "ends a solid with a facet open, or none open")?;
                name_line = line;
                State::Outside
            }
            // The name after `solid` or `endsolid`, on its line.
            _ if line == name_line && matches!(state, State::Solid | State::Outside) => state,
            "solid" => {
                return Err(malformed(
                    line,
                    format!(
                        "'{word}' begins a solid, but one is open (the file is {}; is an \
                         'endsolid' missing?)",
                        describe(state)
                    ),
                ));
            }
            _ => {
                return Err(malformed(
                    line,
                    format!(
                        "'{word}' is not an ASCII STL keyword (solid, facet normal, outer loop, \
                         vertex, endloop, endfacet, endsolid)"
                    ),
                ));
            }
        };
    }
    if matches!(state, State::Facet | State::Loop | State::Looped) {
        return Err(truncated(facet_line));
    }
    if solids == 0 {
        return Err(malformed(1, "no 'solid' in the file".into()));
    }
    TriMesh::new(welder.vertices, triangles)
}

/// Where the ASCII reader is, for its errors.
fn describe(state: State) -> &'static str {
    match state {
        State::Outside => "outside any solid",
        State::Solid => "between facets",
        State::Facet => "after 'facet normal', before 'outer loop'",
        State::Loop => "inside an outer loop",
        State::Looped => "after 'endloop', before 'endfacet'",
    }
}

/// An ASCII vertex coordinate, rounded to `f32` as binary STL stores it.
fn ascii_coordinate(word: &str, name: &str) -> std::result::Result<f64, String> {
    let v: f32 = word
        .parse()
        .map_err(|_| format!("vertex coordinate {name} '{word}' is not a number"))?;
    if v.is_finite() {
        return Ok(f64::from(v));
    }
    Err(if word.parse::<f64>().is_ok_and(f64::is_finite) {
        format!("vertex coordinate {name} {word} is beyond the 32-bit float range of STL")
    } else {
        format!("vertex coordinate {name} is not finite: {word}")
    })
}
