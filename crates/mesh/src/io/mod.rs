//! Mesh files: PLY, Wavefront OBJ, STL and OFF, each read and written.
//!
//! | format | read | write | normals | vertices no triangle uses |
//! |---|---|---|---|---|
//! | [`ply`] | ASCII, binary either endian | binary little-endian or ASCII; `float` coordinates, `double` where `float` would move them ([`ply::F32_ROUNDING_LIMIT`]) | per vertex | kept |
//! | [`obj`] (Wavefront) | text | text | per vertex when each vertex has one | kept |
//! | [`stl`] | binary or ASCII, corners welded | binary or ASCII | facet normals written, not read | dropped |
//! | [`off`] (Object File Format) | text: `[ST][C][N]OFF`, or no keyword | text (`OFF`, or `NOFF` with normals) | per vertex (`NOFF`) | kept |
//!
//! [`read_mesh`] and [`write_mesh`] pick the format by the file's extension ([`MeshFormat`]);
//! each format's module has its reader and writer (re-exported here). All writes are atomic
//! ([`write_atomic`](zeroset_field_core::io::write_atomic)): a reader of the path sees the old
//! file or the complete new one. Every reader names the file and the place of a problem (a
//! header line, a line, a record or triangle with its byte offset), reports a file that ends
//! early as truncated, and never allocates for a count the file's bytes cannot hold.
//!
//! ```
//! use zeroset_mesh::TriMesh;
//! use zeroset_mesh::io::{StlFormat, stl_from_bytes, stl_to_bytes};
//!
//! // A tetrahedron, wound outward; STL stores its 4 triangles' 12 corners...
//! let v = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let mesh = TriMesh::new(v, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])?;
//! let bytes = stl_to_bytes(&mesh, StlFormat::Binary)?;
//! assert_eq!(bytes.len(), 84 + 4 * 50);
//! // ...and reading welds them back into 4 shared vertices: the same closed solid.
//! let back = stl_from_bytes(&bytes, "tetrahedron.stl")?;
//! let report = zeroset_mesh::check(&back);
//! assert_eq!((back.num_vertices(), report.euler_characteristic), (4, 2));
//! assert!(report.is_oriented_closed() && (report.signed_volume - 1.0 / 6.0).abs() < 1e-12);
//! # Ok::<(), zeroset_mesh::MeshError>(())
//! ```

pub mod obj;
pub mod off;
pub mod ply;
mod polygon;
pub mod stl;

use std::path::Path;

pub use obj::{obj_from_bytes, obj_to_string, read_obj_mesh, write_obj};
pub use off::{off_from_bytes, off_to_string, read_off_mesh, write_off};
pub use ply::{PlyFormat, ply_from_bytes, ply_to_bytes, read_ply_mesh, write_ply};
pub use stl::{StlFormat, read_stl_mesh, stl_from_bytes, stl_to_bytes, write_stl};

use crate::{MeshError, Result, TriMesh};

/// A mesh file format, told by the file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// Stanford PLY (`.ply`).
    Ply,
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// STL (`.stl`).
    Stl,
    /// OFF, the Object File Format (`.off`).
    Off,
}

impl MeshFormat {
    /// The extensions of the formats, lower case, as [`from_path`](Self::from_path) accepts
    /// them (in any case).
    pub const EXTENSIONS: [&'static str; 4] = ["ply", "obj", "stl", "off"];

    /// The format's name as users know it: `PLY`, `OBJ`, `STL` or `OFF`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ply => "PLY",
            Self::Obj => "OBJ",
            Self::Stl => "STL",
            Self::Off => "OFF",
        }
    }

    /// The format `path`'s extension names (in any case), or `None`.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "ply" => Some(Self::Ply),
            "obj" => Some(Self::Obj),
            "stl" => Some(Self::Stl),
            "off" => Some(Self::Off),
            _ => None,
        }
    }

    /// Whether the format has an ASCII and a binary encoding (PLY, STL); OBJ and OFF are
    /// text only (binary OFF is not read or written).
    pub fn has_binary(self) -> bool {
        !matches!(self, Self::Obj | Self::Off)
    }
}

/// Whether `path` is a mesh file: `.obj`, `.stl` or `.off` (by the extension), or `.ply` whose
/// header declares at least one face (a PLY without faces is a point cloud). An unreadable PLY
/// header answers `false`, for the point-cloud reader to name the problem.
pub fn is_mesh_file(path: impl AsRef<Path>) -> bool {
    let path = path.as_ref();
    match MeshFormat::from_path(path) {
        Some(MeshFormat::Obj | MeshFormat::Stl | MeshFormat::Off) => true,
        Some(MeshFormat::Ply) => ply_face_count(path).is_some_and(|faces| faces > 0),
        None => false,
    }
}

/// The number of faces a PLY file's header declares, or `None` when it declares no `face`
/// element (a point cloud) or its header cannot be read (for the reader to name the problem).
pub fn ply_face_count(path: impl AsRef<Path>) -> Option<usize> {
    match zeroset_field_core::io::ply::read_header(path.as_ref()) {
        Ok(Ok(header)) => header.element("face").map(|f| f.count),
        _ => None,
    }
}

fn unknown_extension(path: &Path) -> MeshError {
    MeshError::UnsupportedFormat {
        path: path.to_owned(),
        detail: "a mesh file is .ply, .obj, .stl or .off (told by the extension)".into(),
    }
}

/// Reads a mesh in the format `path`'s extension names ([`MeshFormat::from_path`]).
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for another extension; otherwise as
/// [`read_ply_mesh`], [`read_obj_mesh`], [`read_stl_mesh`] or [`read_off_mesh`].
pub fn read_mesh(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    match MeshFormat::from_path(path).ok_or_else(|| unknown_extension(path))? {
        MeshFormat::Ply => read_ply_mesh(path),
        MeshFormat::Obj => read_obj_mesh(path),
        MeshFormat::Stl => read_stl_mesh(path),
        MeshFormat::Off => read_off_mesh(path),
    }
}

/// Writes `mesh` in the format `path`'s extension names, atomically: binary PLY or STL, or
/// their ASCII form with `ascii` (OBJ and OFF are always text, and `ascii` does not change
/// them).
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for another extension; otherwise as [`write_ply`],
/// [`write_obj`], [`write_stl`] or [`write_off`].
pub fn write_mesh(path: impl AsRef<Path>, mesh: &TriMesh, ascii: bool) -> Result<()> {
    let path = path.as_ref();
    match MeshFormat::from_path(path).ok_or_else(|| unknown_extension(path))? {
        MeshFormat::Ply if ascii => write_ply(path, mesh, PlyFormat::Ascii),
        MeshFormat::Ply => write_ply(path, mesh, PlyFormat::BinaryLittleEndian),
        MeshFormat::Obj => write_obj(path, mesh),
        MeshFormat::Stl if ascii => write_stl(path, mesh, StlFormat::Ascii),
        MeshFormat::Stl => write_stl(path, mesh, StlFormat::Binary),
        MeshFormat::Off => write_off(path, mesh),
    }
}
