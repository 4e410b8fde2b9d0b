//! Wavefront OBJ meshes (read and write).
//!
//! - [`write_obj`] writes a comment line, `v x y z` per vertex, `vn` per normal when the mesh
//!   has them, and 1-based `f a//a b//b c//c` (with normals) or `f a b c` per triangle, in
//!   full `f64` precision (the shortest text that reads back to the same number).
//! - [`read_obj_mesh`] reads the geometry statements: `v x y z` (a fourth coordinate `w`, or
//!   the colour `r g b` some exporters append, is ignored), `vn`, and `f` with corners written
//!   `v`, `v/vt`, `v/vt/vn` or `v//vn`, indices from 1 or negative (counted back from the
//!   last vertex read, as the format allows); convex polygons are fan-triangulated, others cut
//!   into ears inside them. Every other
//!   statement (`vt`, `g`, `o`, `s`, `usemtl`, `mtllib`, `l`, `p`, ...) is skipped, as are
//!   comments (`#`) and a UTF-8 byte-order mark; a line ending in `\` continues on the next.
//!   Texture indices are checked to be integers, not looked up: a mesh keeps no texture. The
//!   mesh gets per-vertex normals when every vertex is used by face corners that name a
//!   normal, and always the same one (by value: exporters that repeat a `vn` line per corner
//!   qualify) — what [`write_obj`] writes; otherwise it has none (other files' normals belong
//!   to corners, not vertices). A file of vertices and no face with as many `vn` as `v` is an
//!   oriented point cloud: the `i`-th normal is the `i`-th vertex's. Vertices that no face
//!   uses are kept. The normals are kept as written (not normalised).
//!
//! Errors name the file and the line: a coordinate that does not parse or is not finite, a
//! face with fewer than three corners, an index of 0, too large, or out of range (with the
//! count there was at that line).

use std::fmt::Write as _;
use std::path::Path;

use zeroset_field_core::Point;
use zeroset_field_core::io::write_atomic;

use crate::{MeshError, Result, TriMesh};

/// Writes `mesh` to `path` as Wavefront OBJ; see the [module docs](self). The write is atomic.
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

/// Reads a Wavefront OBJ mesh from `path`; see the [module docs](self).
///
/// # Errors
/// - [`MeshError::Field`] wrapping an I/O error that names `path`.
/// - [`MeshError::Malformed`] naming the line: text that is not UTF-8, a coordinate that does
///   not parse or is not finite, a face corner that does not parse, refers to vertex 0 or
///   beyond the vertices read so far, or a face with fewer than three corners.
/// - [`MeshError::UnsupportedFormat`] for more vertices than 32-bit indices hold.
pub fn read_obj_mesh(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let bytes = zeroset_field_core::io::ply::read_whole(path)?;
    parse_obj(path, &bytes)
}

/// Parses OBJ text as [`read_obj_mesh`] does; `name` stands for the file in errors.
///
/// # Errors
/// As [`read_obj_mesh`], less the I/O errors.
pub fn obj_from_bytes(bytes: &[u8], name: &str) -> Result<TriMesh> {
    parse_obj(Path::new(name), bytes)
}

/// The normal a vertex's corners name: none seen yet, always `Same(k)`, or not one normal.
#[derive(Clone, Copy, PartialEq)]
enum VertexNormal {
    Unused,
    Same(usize),
    Mixed,
}

fn parse_obj(path: &Path, bytes: &[u8]) -> Result<TriMesh> {
    let malformed = |line: usize, detail: String| MeshError::Malformed {
        path: path.to_owned(),
        format: "OBJ",
        place: format!("line {line}"),
        detail,
    };
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = 1 + bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        malformed(
            line,
            "the text is not UTF-8 (is this a binary file?)".into(),
        )
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut vertices: Vec<Point<3>> = Vec::new();
    let mut normals: Vec<Point<3>> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut vertex_normal: Vec<VertexNormal> = Vec::new();
    let mut corners: Vec<(u32, Option<usize>)> = Vec::new();
    for (line, statement) in statements(text) {
        let mut words = statement.split_whitespace();
        match words.next() {
            Some("v") => {
                let p = coordinates(words, "vertex").map_err(|d| malformed(line, d))?;
                vertices.push(p);
                vertex_normal.push(VertexNormal::Unused);
            }
            Some("vn") => {
                let n = coordinates(words, "normal").map_err(|d| malformed(line, d))?;
                normals.push(n);
            }
            Some("f") => {
                corners.clear();
                for (k, word) in words.enumerate() {
                    let corner = face_corner(word, vertices.len(), normals.len())
                        .map_err(|d| malformed(line, format!("corner {k} '{word}': {d}")))?;
                    corners.push(corner);
                }
                if corners.len() < 3 {
                    return Err(malformed(
                        line,
                        format!(
                            "the face has {} corner(s); at least 3 are needed",
                            corners.len()
                        ),
                    ));
                }
                for &(v, n) in &corners {
                    let seen = &mut vertex_normal[v as usize];
                    *seen = match (*seen, n) {
                        (VertexNormal::Unused, Some(n)) => VertexNormal::Same(n),
                        (VertexNormal::Same(m), Some(n)) if normals[m] == normals[n] => {
                            VertexNormal::Same(m)
                        }
                        _ => VertexNormal::Mixed,
                    };
                }
                let indices: Vec<u32> = corners.iter().map(|&(v, _)| v).collect();
                super::polygon::triangulate(&indices, &vertices, &mut triangles);
            }
            // Texture coordinates, groups, materials, smoothing, lines, points and the rest:
            // nothing a triangle mesh keeps.
            _ => {}
        }
    }
    // Vertices only, with as many normals: an oriented point cloud, normals in order.
    if triangles.is_empty() && !vertices.is_empty() && normals.len() == vertices.len() {
        return TriMesh::new(vertices, triangles)?.with_normals(normals);
    }
    let mesh = TriMesh::new(vertices, triangles)?;
    let per_vertex: Option<Vec<Point<3>>> = vertex_normal
        .iter()
        .map(|v| match v {
            VertexNormal::Same(n) => Some(normals[*n]),
            _ => None,
        })
        .collect();
    match per_vertex {
        Some(n) if !n.is_empty() => mesh.with_normals(n),
        _ => Ok(mesh),
    }
}

/// The statements of OBJ text with the line each begins on: comments (`#` to the end of the
/// line) dropped, a line ending in `\` joined to the next (the last line too).
fn statements(text: &str) -> impl Iterator<Item = (usize, String)> + '_ {
    let mut lines = text.lines().enumerate();
    std::iter::from_fn(move || {
        let mut statement = String::new();
        let mut first = None;
        for (i, raw) in lines.by_ref() {
            first.get_or_insert(i + 1);
            let content = raw.split('#').next().unwrap_or("").trim_end();
            match content.strip_suffix('\\') {
                Some(head) => {
                    statement.push_str(head);
                    statement.push(' ');
                }
                None => {
                    statement.push_str(content);
                    return first.map(|line| (line, statement));
                }
            }
        }
        first.map(|line| (line, statement))
    })
}

/// The first three numbers of a `v` or `vn` statement (more are ignored: `w`, or colours).
fn coordinates<'a>(
    mut words: impl Iterator<Item = &'a str>,
    what: &str,
) -> std::result::Result<Point<3>, String> {
    let mut p: Point<3> = [0.0; 3];
    for (axis, value) in p.iter_mut().enumerate() {
        let name = ["x", "y", "z"][axis];
        let word = words
            .next()
            .ok_or_else(|| format!("the {what} has no {name} coordinate"))?;
        *value = word
            .parse()
            .map_err(|_| format!("{what} coordinate {name} '{word}' is not a number"))?;
        if !value.is_finite() {
            return Err(format!("{what} coordinate {name} is not finite: {word}"));
        }
    }
    Ok(p)
}

/// One face corner `v`, `v/vt`, `v/vt/vn` or `v//vn`: the 0-based vertex and normal (the
/// texture coordinate, which a triangle mesh does not keep, is only checked to be an index).
fn face_corner(
    word: &str,
    vertices: usize,
    normals: usize,
) -> std::result::Result<(u32, Option<usize>), String> {
    if word.split('/').count() > 3 {
        return Err("a corner has at most three parts, v/vt/vn".into());
    }
    let mut parts = word.split('/');
    let v = resolve(parts.next().unwrap_or(""), vertices, ["vertex", "vertices"])?;
    if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
        index(t, "texture coordinate")?;
    }
    let n = match parts.next() {
        Some(n) if !n.is_empty() => Some(resolve(n, normals, ["normal", "normals"])?),
        _ => None,
    };
    let v = u32::try_from(v).map_err(|_| format!("vertex index {v} does not fit 32 bits"))?;
    Ok((v, n))
}

/// An OBJ index as written: a non-zero integer.
fn index(text: &str, what: &str) -> std::result::Result<i64, String> {
    match text.parse::<i64>() {
        Ok(0) => Err(format!("{what} index 0: OBJ indices start at 1")),
        Ok(i) => Ok(i),
        Err(_)
            if !text.is_empty()
                && text
                    .trim_start_matches('-')
                    .bytes()
                    .all(|b| b.is_ascii_digit()) =>
        {
            Err(format!("the {what} index {text} is too large"))
        }
        Err(_) => Err(format!("the {what} index '{text}' is not an integer")),
    }
}

/// A 1-based (or negative, relative) OBJ index among `count` items read so far, 0-based;
/// `[what, whats]` names one item and several.
fn resolve(
    text: &str,
    count: usize,
    [what, whats]: [&str; 2],
) -> std::result::Result<usize, String> {
    let i = index(text, what)?;
    let resolved = if i > 0 {
        (i - 1) as u64
    } else {
        (count as u64).wrapping_sub(i.unsigned_abs())
    };
    if resolved >= count as u64 {
        return Err(format!(
            "{what} index {i} is out of range: {count} {} read so far",
            if count == 1 { what } else { whats }
        ));
    }
    Ok(resolved as usize)
}
