//! PLY meshes (read and write).
//!
//! - [`write_ply`] writes a [`TriMesh`] as PLY, binary little-endian by default
//!   ([`PlyFormat`]): vertices as `float x y z` — `double x y z` where 32-bit floats would
//!   move them by more than [`F32_ROUNDING_LIMIT`] of the mesh's diagonal
//!   ([`TriMesh::f32_rounding`]: georeferenced meshes far from the origin) —, normals as
//!   `float nx ny nz` when the mesh has them, and faces as `list uchar int vertex_indices`, with a `comment` naming zeroset. The
//!   header is the standard one that trimesh, Open3D, MeshLab and Blender read.
//! - [`read_ply_mesh`] reads a PLY mesh with zeroset's one PLY layer
//!   ([`zeroset_field_core::io::ply`]: ASCII or binary of either endianness, any scalar type
//!   and its `int8 ... float64` alias): the `vertex` element's `x y z` (and `nx ny nz` when
//!   all three are there) found by name among any other properties; faces are the list
//!   `vertex_indices` (or `vertex_index`) of the `face` element, with any count and index
//!   types; polygons with more than three corners are fan-triangulated where convex, cut into ears
//!   inside them otherwise; other elements are
//!   skipped. Vertices that no face uses are kept.
//!
//! Errors name the file and the place: the header line, or the record with its line (ASCII)
//! or byte offset (binary); a file that ends early is [`MeshError::PlyTruncated`] naming the
//! element and record; a face index out of range names the face. The header's element counts
//! are never trusted for allocations: room is reserved for at most as many records as the
//! bytes after the header can hold
//! ([`Records::records_that_fit`](zeroset_field_core::io::ply::Records::records_that_fit)), so
//! a header that claims 10⁹ vertices in a 200-byte file is reported as truncated without a
//! large allocation.
//!
//! Coordinates written as 32-bit floats round trip exactly where they are `f32` values and are
//! otherwise rounded to the nearest one (by at most [`F32_ROUNDING_LIMIT`] of the diagonal);
//! written as doubles, exactly.

use std::fmt::Write as _;
use std::path::Path;

use zeroset_field_core::Point;
use zeroset_field_core::io::ply::{Header, Kind, Place, PlyError, Record, Records, Scalar};
use zeroset_field_core::io::write_atomic;

use crate::{MeshError, Result, TriMesh};

/// The largest move, as a fraction of the mesh's diagonal, that [`write_ply`] lets rounding
/// the vertices to 32-bit floats make (10⁻⁶: far below a marching-cubes voxel, which is 10⁻³
/// to 10⁻² of the diagonal); beyond it the coordinates are written as `double`.
pub const F32_ROUNDING_LIMIT: f64 = 1e-6;

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
    let double = mesh.f32_rounding() > F32_ROUNDING_LIMIT;
    let mut header = String::from("ply\n");
    header.push_str(match format {
        PlyFormat::BinaryLittleEndian => "format binary_little_endian 1.0\n",
        PlyFormat::Ascii => "format ascii 1.0\n",
    });
    header.push_str("comment written by zeroset (zeroset-mesh)\n");
    let _ = writeln!(header, "element vertex {}", mesh.num_vertices());
    let coordinate = if double { "double" } else { "float" };
    for name in ["x", "y", "z"] {
        let _ = writeln!(header, "property {coordinate} {name}");
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
            let per_vertex = if double { 24 } else { 12 } + if normals { 12 } else { 0 };
            out.reserve(mesh.num_vertices() * per_vertex + mesh.num_triangles() * 13);
            for (i, p) in mesh.vertices().iter().enumerate() {
                for v in p {
                    if double {
                        out.extend_from_slice(&v.to_le_bytes());
                    } else {
                        out.extend_from_slice(&(*v as f32).to_le_bytes());
                    }
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
                if double {
                    let _ = write!(text, "{} {} {}", p[0], p[1], p[2]);
                } else {
                    let _ = write!(text, "{} {} {}", p[0] as f32, p[1] as f32, p[2] as f32);
                }
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
    let bytes = zeroset_field_core::io::ply::read_whole(path)?;
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

/// The mesh reader's error for a PLY error in `path`.
fn mesh_error(path: &Path, e: PlyError) -> MeshError {
    match e {
        PlyError::NotPly => MeshError::UnsupportedFormat {
            path: path.to_owned(),
            detail: e.to_string(),
        },
        PlyError::Unsupported { .. } => MeshError::UnsupportedFormat {
            path: path.to_owned(),
            detail: e.to_string(),
        },
        PlyError::Syntax { place, detail } => ply_error(path, place.to_string(), detail),
        PlyError::MissingProperty { .. } => ply_error(path, "header", e.to_string()),
        PlyError::Truncated {
            element,
            record,
            expected,
        } => MeshError::PlyTruncated {
            path: path.to_owned(),
            element,
            record,
            expected,
        },
    }
}

fn ply_error(path: &Path, place: impl Into<String>, detail: impl Into<String>) -> MeshError {
    MeshError::Ply {
        path: path.to_owned(),
        place: place.into(),
        detail: detail.into(),
    }
}

fn parse_ply(path: &Path, bytes: &[u8]) -> Result<TriMesh> {
    let error = |e| mesh_error(path, e);
    let header = Header::parse(bytes).map_err(error)?;
    let Some(vertex_el) = header.elements.iter().position(|e| e.name == "vertex") else {
        return Err(ply_error(path, "header", "no 'vertex' element"));
    };
    let (xyz, normal_slots) = header.elements[vertex_el]
        .position_normal_slots()
        .map_err(error)?;
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

    let mut records = Records::new(&header, bytes);
    let vertex_count = header.elements[vertex_el].count;
    let mut vertices: Vec<Point<3>> = Vec::new();
    let mut normals: Vec<Point<3>> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut record = Record::default();
    for (e, element) in header.elements.iter().enumerate() {
        if e == vertex_el {
            // Never from the header's count alone: a file whose count it cannot hold is
            // reported as truncated by `records.read`, after at most that many records.
            let per_vertex = if normal_slots.is_some() { 48 } else { 24 };
            let capacity = records.capacity(
                element,
                per_vertex,
                &format!("vertices of {}", path.display()),
            )?;
            vertices.reserve(capacity);
            if normal_slots.is_some() {
                normals.reserve(capacity);
            }
        } else if Some(e) == face_el {
            let what = format!("faces of {}", path.display());
            triangles.reserve(records.capacity(element, 12, &what)?);
        }
        for r in 0..element.count {
            let here = records.read(element, r, &mut record).map_err(error)?;
            if e == vertex_el {
                // A `float` property holds an `f32`: an ASCII one is rounded to it as a binary
                // one is, so that a mesh reads back the same from either encoding.
                let get = |slots: [usize; 3]| {
                    slots.map(|s| match element.properties[s].kind {
                        Kind::Scalar(Scalar::F32) => f64::from(record.scalar(s) as f32),
                        _ => record.scalar(s),
                    })
                };
                let p = get(xyz);
                if let Some(axis) = p.iter().position(|v| !v.is_finite()) {
                    return Err(ply_error(
                        path,
                        here.to_string(),
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
                            here.to_string(),
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
                let items = record.list(face_list.unwrap_or(0));
                push_face(path, &here, items, &vertices, vertex_count, &mut triangles)?;
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

/// Triangulates one face's corner indices `items` into `triangles` (a fan where it is convex
/// or the vertices come after the faces; see `polygon`).
fn push_face(
    path: &Path,
    here: &Place,
    items: &[f64],
    vertices: &[Point<3>],
    vertex_count: usize,
    triangles: &mut Vec<[u32; 3]>,
) -> Result<()> {
    let n = items.len();
    if n < 3 {
        return Err(ply_error(
            path,
            here.to_string(),
            format!("the face has {n} corner(s); at least 3 are needed"),
        ));
    }
    let corner = |k: usize, v: f64| -> Result<u32> {
        if v.fract() != 0.0 || v < 0.0 || v >= vertex_count as f64 {
            return Err(ply_error(
                path,
                here.to_string(),
                format!(
                    "corner {k} refers to vertex {v}, out of range for the {vertex_count} \
                     vertices"
                ),
            ));
        }
        u32::try_from(v as u64).map_err(|_| MeshError::UnsupportedFormat {
            path: path.to_owned(),
            detail: format!("{here}: vertex index {v} does not fit 32 bits"),
        })
    };
    let corners = items
        .iter()
        .enumerate()
        .map(|(k, &v)| corner(k, v))
        .collect::<Result<Vec<u32>>>()?;
    super::polygon::triangulate(&corners, vertices, triangles);
    Ok(())
}
