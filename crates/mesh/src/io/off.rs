//! OFF (Object File Format) meshes (read and write), the text format of Geomview, CGAL, the
//! Princeton Shape Benchmark and ModelNet.
//!
//! An OFF file is a keyword line (`OFF`, or with prefixes such as `NOFF` or `COFF`), a counts
//! line `nv nf ne` (vertices, faces, edges; the edge count is not used), then `nv` vertex
//! lines `x y z` and `nf` face lines `k i1 ... ik`: the number of corners and their 0-based
//! vertex indices.
//!
//! - [`write_off`] writes `OFF` (`NOFF` when the mesh has normals), a comment line naming
//!   zeroset, `nv nf 0`, `x y z` per vertex (then `nx ny nz` with normals) in full `f64`
//!   precision (the shortest text that reads back to the same number), and `3 a b c` per
//!   triangle.
//! - [`read_off_mesh`] reads text OFF liberally, as Geomview's specification allows:
//!   - The keyword is `OFF` with any of the prefixes `ST` (texture coordinates), `C`
//!     (colours) and `N` (normals), as in `COFF`, `NOFF` or `STCNOFF`; it may be followed on
//!     its line by the counts (`OFF 8 6 12`, or `OFF8 6 12` as in many ModelNet files), and
//!     it may be missing altogether (the file begins with the counts: the extension says it
//!     is OFF). `4OFF` (4-D vertices), `nOFF` (vertices of any dimension) and `OFF BINARY`
//!     are refused.
//!   - The vertex and face counts are read as words, on one line or two; the edge count, not
//!     used, is read only on the face count's line and may be omitted (`nv nf`): a lone
//!     number on the next line is the first vertex's.
//!   - Vertices and faces are read one a line. A vertex line begins `x y z`, then, for an
//!     `N` keyword, the normal `nx ny nz`, which the mesh keeps per vertex, as written (not
//!     normalised); the colour (`C`), texture coordinates (`ST`) and any other numbers after
//!     those are ignored. A face line is `k` and `k` indices; what follows them on the line
//!     (a colour) is ignored. Convex polygons are fan-triangulated (`i1 i2 i3`, `i1 i3 i4`, ...),
//!     others cut into ears inside them.
//!   - Comments (`#` to the end of the line), blank lines, any whitespace, lines ending in
//!     `\n`, `\r\n` or `\r`, and a UTF-8 byte-order mark are allowed anywhere; anything after
//!     the last announced face is ignored.
//!   - Vertices that no face uses are kept; a file without faces (`nf = 0`) is a mesh without
//!     triangles (a point cloud, with its normals for `NOFF`).
//!
//! Errors name the file and the line: a keyword or count that does not parse, a coordinate
//! that does not parse or is not finite, a vertex line with fewer numbers than its keyword
//! announces, a face with fewer than three corners, fewer indices than it announces, or an
//! index out of range (with the number of vertices). A file that ends before the records
//! its counts announce is reported as truncated, naming the last line, how many were read
//! and the counts' line; the counts are never trusted for allocations (room is reserved for
//! at most as many records as the rest of the file can hold), so a file that claims 10¹²
//! vertices is an error at once, not an attempt to allocate for them.
//!
//! ```
//! use zeroset_mesh::io::{off_from_bytes, off_to_string};
//!
//! // A unit square as one quad, with a colour after it and comments, as Geomview writes it.
//! let text = "COFF # colours follow the coordinates\n4 1 4\n\
//!             0 0 0  255 0 0 255\n1 0 0  0 255 0 255\n1 1 0  0 0 255 255\n0 1 0  9 9 9 255\n\
//!             4  0 1 2 3  0.8 0.8 0.8\n";
//! let square = off_from_bytes(text.as_bytes(), "square.off")?;
//! // The (convex) quad is fan-triangulated; the colours are not kept.
//! assert_eq!(square.triangles(), &[[0, 1, 2], [0, 2, 3]]);
//! assert!((zeroset_mesh::check(&square).area - 1.0).abs() < 1e-12);
//! // Written back: `OFF`, a comment, the counts, the vertices, the triangles.
//! let written = off_to_string(&square);
//! assert!(written.starts_with("OFF\n#") && written.ends_with("\n3 0 1 2\n3 0 2 3\n"));
//! assert_eq!(off_from_bytes(written.as_bytes(), "again.off")?, square);
//! # Ok::<(), zeroset_mesh::MeshError>(())
//! ```

use std::fmt::Write as _;
use std::path::Path;

use zeroset_field_core::Point;
use zeroset_field_core::io::write_atomic;

use crate::{MeshError, Result, TriMesh};

/// Writes `mesh` to `path` as OFF (`NOFF` with normals); see the [module docs](self). The
/// write is atomic.
///
/// # Errors
/// [`MeshError::Field`] wrapping an I/O error that names `path`.
pub fn write_off(path: impl AsRef<Path>, mesh: &TriMesh) -> Result<()> {
    let text = off_to_string(mesh);
    write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

/// The text [`write_off`] writes.
pub fn off_to_string(mesh: &TriMesh) -> String {
    let normals = mesh.normals();
    let mut s = String::from(if normals.is_empty() {
        "OFF\n"
    } else {
        "NOFF\n"
    });
    s.push_str("# written by zeroset (zeroset-mesh)\n");
    let _ = writeln!(s, "{} {} 0", mesh.num_vertices(), mesh.num_triangles());
    for (i, [x, y, z]) in mesh.vertices().iter().enumerate() {
        let _ = write!(s, "{x} {y} {z}");
        if let Some([nx, ny, nz]) = normals.get(i) {
            let _ = write!(s, " {nx} {ny} {nz}");
        }
        s.push('\n');
    }
    for [a, b, c] in mesh.triangles() {
        let _ = writeln!(s, "3 {a} {b} {c}");
    }
    s
}

/// Reads an OFF mesh from `path`; see the [module docs](self).
///
/// # Errors
/// - [`MeshError::Field`] wrapping an I/O error that names `path`.
/// - [`MeshError::Malformed`] naming the line: a keyword that is not OFF's, a count that is
///   not a whole number, a line (outside comments) that is not UTF-8, a coordinate or normal
///   component that does not parse or is not finite, a vertex line with too few numbers, a
///   face with fewer than three corners or fewer indices than it announces, an index out of
///   range; a file that ends before the vertices and faces its counts announce (truncated).
/// - [`MeshError::UnsupportedFormat`] for `4OFF`, `nOFF` and binary OFF, and for more
///   vertices than 32-bit indices hold.
pub fn read_off_mesh(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let bytes = zeroset_field_core::io::ply::read_whole(path)?;
    parse_off(path, &bytes)
}

/// Parses OFF text as [`read_off_mesh`] does; `name` stands for the file in errors.
///
/// # Errors
/// As [`read_off_mesh`], less the I/O errors.
pub fn off_from_bytes(bytes: &[u8], name: &str) -> Result<TriMesh> {
    parse_off(Path::new(name), bytes)
}

/// The UTF-8 byte-order mark some editors put before text.
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// The fewest bytes a vertex line takes (`0 0 0\n`), and a face line (`3 0 1 2\n`): the
/// counts are trusted for allocations only as far as the rest of the file can hold them.
const MIN_VERTEX_BYTES: usize = 6;
const MIN_FACE_BYTES: usize = 8;

/// The lines of OFF text that hold something, with their numbers (from 1): comments (`#` to
/// the end of the line) dropped, whitespace trimmed; lines end at `\n`, `\r\n` or a lone
/// `\r`. Comments may hold any bytes; the rest of a line must be UTF-8.
struct Lines<'a> {
    rest: &'a [u8],
    /// The number of the line `rest` begins.
    next: usize,
    /// The number of the last line returned (0 before the first).
    last: usize,
}

impl<'a> Lines<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self {
            rest: bytes,
            next: 1,
            last: 0,
        }
    }

    /// The next line that holds something, `None` at the end of the file, or `Err(line)` for
    /// a line that is not UTF-8.
    fn next_line(&mut self) -> std::result::Result<Option<(usize, &'a str)>, usize> {
        while !self.rest.is_empty() {
            let end = self
                .rest
                .iter()
                .position(|&b| b == b'\n' || b == b'\r')
                .unwrap_or(self.rest.len());
            let raw = &self.rest[..end];
            let skip = match self.rest.get(end..end + 2) {
                Some(b"\r\n") => end + 2,
                _ => (end + 1).min(self.rest.len()),
            };
            self.rest = &self.rest[skip..];
            let line = self.next;
            self.next += 1;
            let content = raw.split(|&b| b == b'#').next().unwrap_or(raw);
            let text = std::str::from_utf8(content).map_err(|_| line)?.trim();
            if !text.is_empty() {
                self.last = line;
                return Ok(Some((line, text)));
            }
        }
        Ok(None)
    }

    /// How many more records of at least `min_bytes` the rest of the file can hold.
    fn room(&self, min_bytes: usize) -> usize {
        self.rest.len() / min_bytes + 1
    }
}

/// What the keyword announces about each vertex line.
#[derive(Default)]
struct Keyword {
    /// `N`: the normal `nx ny nz` follows the coordinates.
    normals: bool,
}

fn parse_off(path: &Path, bytes: &[u8]) -> Result<TriMesh> {
    let malformed = |line: usize, detail: String| MeshError::Malformed {
        path: path.to_owned(),
        format: "OFF",
        place: format!("line {line}"),
        detail,
    };
    let not_utf8 = |line: usize| {
        malformed(
            line,
            "the text is not UTF-8 (is this a binary file?)".into(),
        )
    };
    let unsupported = |line: usize, detail: String| MeshError::UnsupportedFormat {
        path: path.to_owned(),
        detail: format!("OFF line {line}: {detail}"),
    };
    let mut lines = Lines::new(bytes.strip_prefix(BOM).unwrap_or(bytes));

    // The keyword, if any, and the counts: words, on one line or several.
    let Some((first_line, text)) = lines.next_line().map_err(not_utf8)? else {
        return Err(malformed(
            1,
            "the file is empty: an OFF file begins with the keyword OFF and the counts \
             (vertices, faces, edges)"
                .into(),
        ));
    };
    let mut words = text.split_whitespace();
    let mut line = first_line;
    // A line returned holds a word. `pending`: a count read with it.
    let first = words.next().unwrap_or_default();
    let (keyword, mut pending) = if is_whole_number(first) {
        // No keyword: the file begins with the counts.
        (Keyword::default(), Some(first))
    } else {
        // `OFF490 518 0`: the keyword run into the vertex count, as in many ModelNet files.
        let (first, glued) = match first.find("OFF") {
            Some(at) if is_whole_number(&first[at + 3..]) => first.split_at(at + 3),
            _ => (first, ""),
        };
        let keyword = parse_keyword(first).map_err(|e| match e {
            KeywordError::Unsupported(d) => unsupported(line, d),
            KeywordError::Malformed(d) => malformed(line, d),
        })?;
        if let Some(b) = words
            .clone()
            .next()
            .filter(|b| b.eq_ignore_ascii_case("binary"))
        {
            return Err(unsupported(
                line,
                format!("'{first} {b}': binary OFF is not supported; write it as text OFF"),
            ));
        }
        (keyword, Some(glued).filter(|g| !g.is_empty()))
    };
    // The next count: `pending`, the rest of this line, or the next lines.
    let mut next_count = |what: &str| -> Result<usize> {
        let word = loop {
            if let Some(w) = pending.take().or_else(|| words.next()) {
                break w;
            }
            match lines.next_line().map_err(not_utf8)? {
                Some((l, text)) => {
                    line = l;
                    words = text.split_whitespace();
                }
                None => {
                    return Err(malformed(
                        lines.last,
                        format!(
                            "truncated: the file ends before the {what} count (the counts are \
                             vertices, faces and edges)"
                        ),
                    ));
                }
            }
        };
        count(word, what).map_err(|d| malformed(line, d))
    };
    let nv = next_count("vertex")?;
    let nf = next_count("face")?;
    let counts_line = line;
    // The edge count, on the face count's line if at all: not used.
    if let Some(w) = words.next() {
        count(w, "edge").map_err(|d| malformed(line, d))?;
    }
    if let Some(w) = words.next() {
        return Err(malformed(
            line,
            format!(
                "'{w}' after the counts (vertices {nv}, faces {nf}, edges): vertices begin on \
                 the next line, one a line"
            ),
        ));
    }

    // The vertices, one a line.
    let what = if keyword.normals {
        "x y z nx ny nz"
    } else {
        "x y z"
    };
    let truncated = |read: usize, announced: usize, what: &str| {
        format!(
            "truncated: the file ends after {read} of the {announced} {what} the counts on line \
             {counts_line} announce"
        )
    };
    let capacity = nv.min(lines.room(MIN_VERTEX_BYTES));
    let mut vertices: Vec<Point<3>> = Vec::with_capacity(capacity);
    let mut normals: Vec<Point<3>> = Vec::with_capacity(if keyword.normals { capacity } else { 0 });
    for i in 0..nv {
        let Some((line, text)) = lines.next_line().map_err(not_utf8)? else {
            return Err(malformed(lines.last, truncated(i, nv, "vertices")));
        };
        let mut words = text.split_whitespace();
        let mut numbers = |names: [&str; 3], kind: &str| -> Result<Point<3>> {
            let mut p: Point<3> = [0.0; 3];
            for (value, name) in p.iter_mut().zip(names) {
                let Some(word) = words.next() else {
                    return Err(malformed(
                        line,
                        format!(
                            "vertex {i} has no {name}: a vertex line is {what} (one vertex a \
                             line)"
                        ),
                    ));
                };
                *value = word.parse().map_err(|_| {
                    malformed(
                        line,
                        format!("vertex {i} {kind} {name} '{word}' is not a number"),
                    )
                })?;
                if !value.is_finite() {
                    return Err(malformed(
                        line,
                        format!("vertex {i} {kind} {name} is not finite: {word}"),
                    ));
                }
            }
            Ok(p)
        };
        vertices.push(numbers(["x", "y", "z"], "coordinate")?);
        if keyword.normals {
            normals.push(numbers(["nx", "ny", "nz"], "normal component")?);
        }
        // Colours, texture coordinates and any other numbers: not kept.
    }
    if u32::try_from(nv.saturating_sub(1)).is_err() {
        return Err(MeshError::UnsupportedFormat {
            path: path.to_owned(),
            detail: format!("{nv} vertices: more than 32-bit indices hold"),
        });
    }

    // The faces, one a line.
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(nf.min(lines.room(MIN_FACE_BYTES)));
    for j in 0..nf {
        let Some((line, text)) = lines.next_line().map_err(not_utf8)? else {
            return Err(malformed(lines.last, truncated(j, nf, "faces")));
        };
        let mut words = text.split_whitespace();
        let k = words.next().unwrap_or("");
        let k: u64 = k.parse().map_err(|_| {
            malformed(
                line,
                format!("face {j}: the corner count '{k}' is not a whole number"),
            )
        })?;
        if k < 3 {
            return Err(malformed(
                line,
                format!("face {j} has {k} corner(s); at least 3 are needed"),
            ));
        }
        // Grown as the corners are read, never allocated for `k`: the line holds what it
        // holds.
        let mut corners = Vec::new();
        for c in 0..k {
            let Some(word) = words.next() else {
                return Err(malformed(
                    line,
                    format!("face {j} announces {k} corners, but the line holds only {c}"),
                ));
            };
            let v = match word.parse::<u64>() {
                Ok(v) if v < nv as u64 => v as u32, // nv <= 2³² (checked above)
                Ok(v) => {
                    return Err(malformed(
                        line,
                        format!(
                            "face {j} corner {c} refers to vertex {v}, out of range for the \
                             {nv} vertices"
                        ),
                    ));
                }
                Err(_) => {
                    return Err(malformed(
                        line,
                        format!(
                            "face {j} corner {c} '{word}' is not a vertex index (a whole \
                             number, from 0)"
                        ),
                    ));
                }
            };
            corners.push(v);
        }
        super::polygon::triangulate(&corners, &vertices, &mut triangles);
        // A colour after the indices: not kept.
    }
    // Anything after the announced faces is ignored.

    let mesh = TriMesh::new(vertices, triangles)?;
    if keyword.normals {
        mesh.with_normals(normals)
    } else {
        Ok(mesh)
    }
}

/// Why a keyword is refused: not OFF's, or an OFF this crate does not read.
enum KeywordError {
    Malformed(String),
    Unsupported(String),
}

/// The keyword `[ST][C][N][4][n]OFF` (the prefixes in any order; `off` in lower case too).
fn parse_keyword(word: &str) -> std::result::Result<Keyword, KeywordError> {
    let malformed = || {
        KeywordError::Malformed(format!(
            "'{word}' is neither the OFF keyword ([ST][C][N]OFF) nor a vertex count (a whole \
             number)"
        ))
    };
    if word == "off" {
        return Ok(Keyword::default());
    }
    let mut prefix = word.strip_suffix("OFF").ok_or_else(malformed)?;
    let mut keyword = Keyword::default();
    while !prefix.is_empty() {
        prefix = if let Some(rest) = prefix.strip_prefix("ST") {
            rest
        } else if let Some(rest) = prefix.strip_prefix('C') {
            rest
        } else if let Some(rest) = prefix.strip_prefix('N') {
            keyword.normals = true;
            rest
        } else if prefix.starts_with('4') {
            return Err(KeywordError::Unsupported(format!(
                "the keyword '{word}' announces 4-D vertices (x y z w); only 3-D OFF is read"
            )));
        } else if prefix.starts_with('n') {
            return Err(KeywordError::Unsupported(format!(
                "the keyword '{word}' announces vertices of any dimension (nOFF); only 3-D OFF \
                 is read"
            )));
        } else {
            return Err(malformed());
        };
    }
    Ok(keyword)
}

/// A count of the counts line: a whole number.
fn count(word: &str, what: &str) -> std::result::Result<usize, String> {
    match word.parse::<u64>() {
        Ok(n) => usize::try_from(n).map_err(|_| format!("the {what} count {n} is too large")),
        Err(_) if is_whole_number(word) => Err(format!("the {what} count {word} is too large")),
        Err(_) => Err(format!(
            "the {what} count '{word}' is not a whole number (the counts are vertices, faces \
             and edges)"
        )),
    }
}

/// Whether `word` is written as a whole number (digits, perhaps after `+`), whatever its size.
fn is_whole_number(word: &str) -> bool {
    let digits = word.strip_prefix('+').unwrap_or(word);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}
