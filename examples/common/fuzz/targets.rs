//! The readers under test ("targets") and how one input is fed to each.
//!
//! Each target writes nothing: the engine has already put the input in a file with the
//! target's extension, and the target calls every public reader of its format on that file
//! (and on the bytes, for the readers that take bytes), then uses what was read the way the
//! `zeroset` command does (statistics, mesh checks, field evaluation), because a reader that
//! accepts an inconsistent file and leaves a later step to panic is a reader bug as well.
//! The result is the *outcome*: a short normalised description of what each call returned
//! (`ok …` or the error's variant and message, with the file name, digits and quoted text
//! taken out), which the engine uses as a cheap coverage proxy.

use std::path::Path;

use zeroset::bases::field_file::{self, AnyField};
use zeroset::core::field::ScalarField;
use zeroset::core::io::{self, Format, ReadOptions, gempy};

/// A reader (or family of readers) under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Target {
    /// PLY point clouds: `read_point_cloud_with(Format::Ply)`, strict and lenient.
    PlyCloud,
    /// PLY meshes: `zeroset_mesh::read_ply_mesh` and `ply_from_bytes`, then the mesh checks.
    PlyMesh,
    /// STL meshes, binary and ASCII: `zeroset_mesh::read_stl_mesh` and `stl_from_bytes`, then
    /// the mesh checks.
    StlMesh,
    /// Wavefront OBJ meshes: `zeroset_mesh::read_obj_mesh` and `obj_from_bytes`, then the mesh
    /// checks.
    ObjMesh,
    /// OFF meshes: `zeroset_mesh::read_off_mesh` and `off_from_bytes`, then the mesh checks.
    OffMesh,
    /// xyz text: `read_point_cloud_with(Format::Xyz)`, with and without normals.
    Xyz,
    /// PCL's PCD (ascii, binary, binary_compressed): `read_point_cloud_with(Format::Pcd)`,
    /// strict and lenient.
    Pcd,
    /// LiDAR LAS and LAZ: `read_point_cloud_with(Format::Las)`, strict and lenient.
    Las,
    /// ASTM E57 laser scans: `read_point_cloud_with(Format::E57)`, strict and lenient, most
    /// inputs with their page checksums repaired after mutation.
    E57,
    /// CSV with a header: `read_point_cloud_with(Format::Csv)` and `detect_format`.
    Csv,
    /// GemPy tables: `read_gempy_file`, `read_surface_points`, `read_orientations` and the
    /// point-cloud reader with `Format::GemPy`.
    GemPy,
    /// `.xyv`: `read_value_points::<2>`.
    Xyv,
    /// `.xyzv`: `read_value_points::<3>`.
    Xyzv,
    /// `.zsf` seeded with B-spline fields: `decode_any`, `decode`, `read_any_field`,
    /// `read_metadata`, `read_dimension`, `is_field_file`, then evaluation.
    ZsfBspline,
    /// `.zsf` seeded with RBF fields (every stored kernel).
    ZsfRbf,
    /// `.zsf` seeded with neural fields.
    ZsfNeural,
    /// `.zsf` seeded with MRAS fields.
    ZsfMras,
    /// What `zeroset info FILE` does (crates/cli/src/info.rs) through the library: sniff a
    /// field file, detect the format, sniff a PLY header for faces, read strictly then
    /// leniently, statistics, formations; inputs keep their own extension.
    Info,
}

impl Target {
    /// Every target, in table order.
    pub const ALL: [Target; 18] = [
        Target::PlyCloud,
        Target::PlyMesh,
        Target::StlMesh,
        Target::ObjMesh,
        Target::OffMesh,
        Target::Xyz,
        Target::Pcd,
        Target::Las,
        Target::E57,
        Target::Csv,
        Target::GemPy,
        Target::Xyv,
        Target::Xyzv,
        Target::ZsfBspline,
        Target::ZsfRbf,
        Target::ZsfNeural,
        Target::ZsfMras,
        Target::Info,
    ];

    /// The name used in reports and as the folder of regression files.
    pub fn name(self) -> &'static str {
        match self {
            Target::PlyCloud => "ply-cloud",
            Target::PlyMesh => "ply-mesh",
            Target::StlMesh => "stl-mesh",
            Target::ObjMesh => "obj-mesh",
            Target::OffMesh => "off-mesh",
            Target::Xyz => "xyz",
            Target::Pcd => "pcd",
            Target::Las => "las",
            Target::E57 => "e57",
            Target::Csv => "csv",
            Target::GemPy => "gempy",
            Target::Xyv => "xyv",
            Target::Xyzv => "xyzv",
            Target::ZsfBspline => "zsf-bspline",
            Target::ZsfRbf => "zsf-rbf",
            Target::ZsfNeural => "zsf-neural",
            Target::ZsfMras => "zsf-mras",
            Target::Info => "info",
        }
    }

    /// The target of a name.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }

    /// The extension of the input file (for [`Target::Info`], the default for inputs without
    /// one).
    pub fn ext(self) -> &'static str {
        match self {
            Target::PlyCloud | Target::PlyMesh => "ply",
            Target::StlMesh => "stl",
            Target::ObjMesh => "obj",
            Target::OffMesh => "off",
            Target::Xyz => "xyz",
            Target::Pcd => "pcd",
            Target::Las => "las",
            Target::E57 => "e57",
            Target::Csv | Target::GemPy => "csv",
            Target::Xyv => "xyv",
            Target::Xyzv => "xyzv",
            Target::ZsfBspline | Target::ZsfRbf | Target::ZsfNeural | Target::ZsfMras => "zsf",
            Target::Info => "dat",
        }
    }

    /// The checksums the target's inputs keep, repaired after mutation.
    pub fn seal(self) -> super::mutate::Seal {
        use super::mutate::Seal;
        match self {
            Target::ZsfBspline | Target::ZsfRbf | Target::ZsfNeural | Target::ZsfMras => Seal::Zsf,
            Target::E57 => Seal::E57,
            Target::Info => Seal::Any,
            _ => Seal::None,
        }
    }
}

/// A mesh format's two readers, from the file and from its bytes, each then checked.
fn read_mesh_both(
    path: &Path,
    bytes: &[u8],
    from_file: fn(&Path) -> zeroset::mesh::Result<zeroset::mesh::TriMesh>,
    from_bytes: fn(&[u8], &str) -> zeroset::mesh::Result<zeroset::mesh::TriMesh>,
) -> String {
    let a = outcome(&from_file(path), path, mesh_ok);
    let b = outcome(&from_bytes(bytes, "F"), Path::new("F"), mesh_ok);
    format!("{a} | {b}")
}

/// The normalised outcome of a `Result`: `ok <what>` or `<Variant>: <message>` with the path,
/// quoted text and digits taken out, at most 64 characters.
fn outcome<T, E: std::fmt::Debug + std::fmt::Display>(
    r: &Result<T, E>,
    path: &Path,
    ok: impl FnOnce(&T) -> String,
) -> String {
    match r {
        Ok(v) => format!("ok {}", ok(v)),
        Err(e) => {
            let debug = format!("{e:?}");
            let variant: String = debug
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let text = e.to_string().replace(&path.display().to_string(), "F");
            format!("{variant}: {}", normalise(&text))
        }
    }
}

/// Digits become `#`, quoted text `'…'`, the result cut at 64 characters.
pub fn normalise(text: &str) -> String {
    let mut out = String::new();
    let mut quote: Option<char> = None;
    let mut last_digit = false;
    for c in text.chars() {
        if let Some(q) = quote {
            if c == q {
                quote = None;
                out.push('…');
                out.push(c);
            }
            continue;
        }
        if c == '\'' || c == '"' || c == '`' {
            quote = Some(c);
            out.push(c);
            continue;
        }
        if c.is_ascii_digit() {
            if !last_digit {
                out.push('#');
            }
            last_digit = true;
            continue;
        }
        last_digit = false;
        out.push(c);
        if out.chars().count() >= 64 {
            break;
        }
    }
    out
}

fn cloud_ok(c: &zeroset::core::cloud::PointCloud3) -> String {
    let s = c.stats();
    format!(
        "normals={} nonfinite={}",
        s.has_normals,
        s.non_finite_positions + s.non_finite_normals > 0
    )
}

fn mesh_ok(m: &zeroset::mesh::TriMesh) -> String {
    // What `zeroset info` does with a mesh.
    let r = zeroset::mesh::check(m);
    let loops = zeroset::mesh::boundary_loops(m);
    format!(
        "tri={} closed={} loops={}",
        r.triangles > 0,
        r.closed,
        loops > 0
    )
}

fn read_cloud(path: &Path, format: Format, lenient: bool, positions_only: bool) -> String {
    let options = ReadOptions::default()
        .with_format(format)
        .with_allow_non_finite(lenient)
        .with_positions_only(positions_only);
    outcome(&io::read_point_cloud_with(path, &options), path, cloud_ok)
}

fn field<const D: usize>(bytes: &[u8], path: &Path) -> String {
    let decoded = field_file::decode_any::<D>(bytes, path);
    let mut s = outcome(&decoded, path, |f| {
        // Use what was read: describe it and evaluate it where `zeroset mesh` would.
        let _ = f.describe();
        let p = match f.bounds() {
            Some(b) => {
                let (lo, hi) = (b.min(), b.max());
                std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]))
            }
            None => [0.25; D],
        };
        let v = f.value(&p);
        let g = f.gradient(&p);
        let mut vs = [0.0; 2];
        f.values(&[p, [0.0; D]], &mut vs);
        if let AnyField::Mras(m) = f {
            let _ = (m.storage(), m.uncompressed_storage());
        }
        format!(
            "{} finite={}",
            f.kind(),
            v.is_finite() && g.iter().all(|x| x.is_finite())
        )
    });
    s.push_str(" | ");
    s.push_str(&outcome(
        &field_file::decode::<D>(bytes, path),
        path,
        |_| "bspline".into(),
    ));
    s
}

/// Runs `target` on the input, which is in `path` and is `bytes`; returns the outcome.
pub fn run(target: Target, path: &Path, bytes: &[u8]) -> String {
    match target {
        Target::PlyCloud => [
            read_cloud(path, Format::Ply, false, false),
            read_cloud(path, Format::Ply, true, false),
        ]
        .join(" | "),
        Target::PlyMesh => read_mesh_both(
            path,
            bytes,
            |p| zeroset::mesh::read_ply_mesh(p),
            zeroset::mesh::io::ply_from_bytes,
        ),
        Target::StlMesh => read_mesh_both(
            path,
            bytes,
            |p| zeroset::mesh::read_stl_mesh(p),
            zeroset::mesh::io::stl_from_bytes,
        ),
        Target::ObjMesh => read_mesh_both(
            path,
            bytes,
            |p| zeroset::mesh::read_obj_mesh(p),
            zeroset::mesh::io::obj_from_bytes,
        ),
        Target::OffMesh => read_mesh_both(
            path,
            bytes,
            |p| zeroset::mesh::read_off_mesh(p),
            zeroset::mesh::io::off_from_bytes,
        ),
        Target::Pcd => [
            read_cloud(path, Format::Pcd, false, false),
            read_cloud(path, Format::Pcd, true, true),
        ]
        .join(" | "),
        Target::Las => [
            read_cloud(path, Format::Las, false, false),
            read_cloud(path, Format::Las, true, true),
        ]
        .join(" | "),
        Target::E57 => [
            read_cloud(path, Format::E57, false, false),
            read_cloud(path, Format::E57, true, true),
        ]
        .join(" | "),
        Target::Xyz => [
            read_cloud(path, Format::Xyz, false, false),
            read_cloud(path, Format::Xyz, true, true),
        ]
        .join(" | "),
        Target::Csv => [
            outcome(&io::detect_format(path), path, |f| f.name().into()),
            read_cloud(path, Format::Csv, false, false),
            read_cloud(path, Format::Csv, true, false),
        ]
        .join(" | "),
        Target::GemPy => [
            outcome(&gempy::read_gempy_file(path), path, |d| {
                format!("formations={}", d.formation_counts().len().min(2))
            }),
            outcome(&gempy::read_surface_points(path), path, |_| String::new()),
            outcome(&gempy::read_orientations(path), path, |_| String::new()),
            read_cloud(path, Format::GemPy, false, false),
        ]
        .join(" | "),
        Target::Xyv => outcome(&io::read_value_points::<2>(path), path, |_| String::new()),
        Target::Xyzv => outcome(&io::read_value_points::<3>(path), path, |_| String::new()),
        Target::ZsfBspline | Target::ZsfRbf | Target::ZsfNeural | Target::ZsfMras => {
            let dim = field_file::read_dimension(path);
            let mut s = outcome(&dim, path, |d| format!("{}", (*d).min(4)));
            s.push_str(&format!(" | is={}", field_file::is_field_file(path)));
            s.push_str(" | ");
            s.push_str(&outcome(&field_file::read_metadata(path), path, |m| {
                format!("{}", m.len().min(3))
            }));
            s.push_str(" | ");
            s.push_str(&field::<2>(bytes, path));
            s.push_str(" | ");
            s.push_str(&field::<3>(bytes, path));
            s.push_str(" | ");
            s.push_str(&outcome(
                &field_file::read_any_field::<3>(path),
                path,
                |f| f.kind().into(),
            ));
            s
        }
        Target::Info => info(path),
    }
}

/// `zeroset info` (crates/cli/src/info.rs `report`), through the library.
fn info(path: &Path) -> String {
    if field_file::is_field_file(path) {
        return match field_file::read_dimension(path) {
            Ok(2) => outcome(&field_file::read_any_field::<2>(path), path, |f| {
                let _ = (f.describe(), f.bounds(), field_file::read_metadata(path));
                f.kind().into()
            }),
            Ok(_) => outcome(&field_file::read_any_field::<3>(path), path, |f| {
                let _ = (f.describe(), f.bounds(), field_file::read_metadata(path));
                f.kind().into()
            }),
            Err(e) => outcome::<(), _>(&Err(e), path, |_| String::new()),
        };
    }
    if matches!(
        zeroset::mesh::MeshFormat::from_path(path),
        Some(
            zeroset::mesh::MeshFormat::Obj
                | zeroset::mesh::MeshFormat::Stl
                | zeroset::mesh::MeshFormat::Off
        )
    ) {
        return outcome(&zeroset::mesh::read_mesh(path), path, mesh_ok);
    }
    let format = match io::detect_format(path) {
        Ok(f) => f,
        Err(e) => return outcome::<(), _>(&Err(e), path, |_| String::new()),
    };
    if format == Format::Ply && zeroset::mesh::io::ply_face_count(path).is_some() {
        return outcome(&zeroset::mesh::read_ply_mesh(path), path, mesh_ok);
    }
    let mut options = ReadOptions::default().with_format(format);
    let first = io::read_point_cloud_with(path, &options);
    if let Err(zeroset::core::Error::NotNormals { .. }) = first {
        options = options.with_positions_only(true);
    }
    let mut s = format!("{format} ");
    match io::read_point_cloud_with(path, &options) {
        Ok(c) => s.push_str(&format!("ok {}", cloud_ok(&c))),
        Err(zeroset::core::Error::NonFinite { .. }) => {
            let r = io::read_point_cloud_with(path, &options.with_allow_non_finite(true));
            s.push_str(&outcome(&r, path, cloud_ok));
        }
        Err(e) => s.push_str(&outcome::<(), _>(&Err(e), path, |_| String::new())),
    }
    if format == Format::GemPy {
        s.push_str(" | ");
        s.push_str(&outcome(&gempy::read_gempy_file(path), path, |d| {
            format!("{}", d.formation_counts().len().min(2))
        }));
    }
    s
}
