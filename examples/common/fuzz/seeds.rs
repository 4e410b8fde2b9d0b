//! The seeds: real files from `data/` and `samples/` (whole when small, shrunk or cut when
//! not), and files written in-process by the library's own writers — PLY point clouds and
//! meshes in ascii and binary, xyz, CSV and value files, and `.zsf` files of every kind
//! (B-spline, RBF with each stored kernel, neural, MRAS; 2-D and 3-D). The generated ones are
//! cached in a folder (under `target/`), since the fits take seconds in a dev build.

use std::path::{Path, PathBuf};

use super::targets::Target;

/// A seed: its bytes and the extension of the file it came from.
#[derive(Clone, Debug)]
pub struct Seed {
    /// A name for reports.
    pub name: String,
    /// The extension (without the dot).
    pub ext: String,
    /// The content.
    pub bytes: Vec<u8>,
}

fn seed(name: &str, bytes: Vec<u8>) -> Seed {
    let ext = Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("dat")
        .to_owned();
    Seed {
        name: name.to_owned(),
        ext,
        bytes,
    }
}

/// The repository root (the root package's manifest directory).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The first `n` bytes of a file, cut back to the last newline.
fn prefix_lines(bytes: &[u8], n: usize) -> Vec<u8> {
    if bytes.len() <= n {
        return bytes.to_vec();
    }
    let cut = bytes[..n]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(n, |p| p + 1);
    bytes[..cut].to_vec()
}

/// A PLY file shrunk to its first `keep` vertices: ascii files keep the faces whose corners
/// are all kept; binary files keep the first element (the vertices, scalar properties only)
/// and drop the rest. `None` if the header is not of that shape.
fn shrink_ply(bytes: &[u8], keep: usize) -> Option<Vec<u8>> {
    let end = bytes.windows(11).position(|w| w == b"end_header\n")? + 11;
    let header = std::str::from_utf8(&bytes[..end]).ok()?;
    let ascii = header.contains("format ascii");
    let mut out = String::new();
    let mut elements: Vec<(String, usize, usize)> = Vec::new(); // name, count, record bytes
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["element", name, count] => elements.push((name.to_string(), count.parse().ok()?, 0)),
            ["property", ty, _] => {
                let size = match *ty {
                    "char" | "uchar" | "int8" | "uint8" => 1,
                    "short" | "ushort" | "int16" | "uint16" => 2,
                    "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
                    "double" | "float64" => 8,
                    _ => return None,
                };
                elements.last_mut()?.2 += size;
            }
            _ => {}
        }
    }
    let (first, count, record) = elements.first()?.clone();
    if first != "vertex" {
        return None;
    }
    let keep = keep.min(count);
    let mut skip = false;
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        if let ["element", name, _] = w.as_slice() {
            skip = !ascii && *name != "vertex";
            if !skip && *name == "vertex" {
                out.push_str(&format!("element vertex {keep}\n"));
                continue;
            }
        }
        if skip && line != "end_header" {
            continue;
        }
        if ascii && line.starts_with("element face") {
            out.push_str("element face @@FACES@@\n");
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    let body = &bytes[end..];
    let mut result;
    if ascii {
        let text = std::str::from_utf8(body).ok()?;
        let mut lines = text.lines();
        let verts: Vec<&str> = lines.by_ref().take(count).collect();
        let faces: Vec<&str> = lines
            .filter(|l| {
                l.split_whitespace()
                    .skip(1)
                    .all(|v| v.parse::<usize>().is_ok_and(|i| i < keep))
            })
            .collect();
        let header = out.replace("@@FACES@@", &faces.len().to_string());
        result = header.into_bytes();
        for l in verts.iter().take(keep).chain(faces.iter()) {
            result.extend_from_slice(l.as_bytes());
            result.push(b'\n');
        }
    } else {
        result = out.into_bytes();
        result.extend_from_slice(body.get(..keep * record)?);
    }
    Some(result)
}

/// The real files: everything under 1 MB whole unless `small`, plus shrunk and cut copies.
pub fn real_files(small: bool) -> Vec<Seed> {
    let root = repo_root();
    let read = |p: &str| std::fs::read(root.join(p)).ok();
    let mut out = Vec::new();
    if let Some(b) = read("data/bun_zipper.ply") {
        if let Some(s) = shrink_ply(&b, 40) {
            // The same small mesh as STL (binary and ASCII) and OBJ, for their readers.
            if let Ok(mesh) = zeroset::mesh::io::ply_from_bytes(&s, "seed") {
                use zeroset::mesh::io::{StlFormat, obj_to_string, stl_to_bytes};
                for (name, format) in [
                    ("bun_zipper_40.stl", StlFormat::Binary),
                    ("bun_zipper_40_ascii.stl", StlFormat::Ascii),
                ] {
                    if let Ok(bytes) = stl_to_bytes(&mesh, format) {
                        out.push(seed(name, bytes));
                    }
                }
                out.push(seed("bun_zipper_40.obj", obj_to_string(&mesh).into_bytes()));
                let off = zeroset::mesh::io::off_to_string(&mesh);
                out.push(seed("bun_zipper_40.off", off.into_bytes()));
            }
            out.push(seed("bun_zipper_40.ply", s));
        }
        out.push(seed("bun_zipper_head.ply", prefix_lines(&b, 4096)));
    }
    if let Some(b) = read("data/bunny_points.ply") {
        if let Some(s) = shrink_ply(&b, 50) {
            out.push(seed("bunny_points_50.ply", s));
        }
        if !small {
            out.push(seed("bunny_points.ply", b));
        }
    }
    for (name, ext) in [("data/kitten.xyz", "xyz"), ("data/bunny_2k.xyzn", "xyzn")] {
        if let Some(b) = read(name) {
            let base = Path::new(name).file_stem().unwrap().to_str().unwrap();
            out.push(seed(&format!("{base}_head.{ext}"), prefix_lines(&b, 2048)));
            if !small {
                out.push(seed(&format!("{base}.{ext}"), b));
            }
        }
    }
    if let Some(b) = read("samples/curve.xyv") {
        out.push(seed("curve.xyv", b));
    }
    // PCD as Open3D writes it, in its three encodings, LAS / LAZ as laspy does and E57 as
    // libE57Format does (300 points each, under 22 kB).
    for name in [
        "bunny300_ascii.pcd",
        "bunny300_binary.pcd",
        "bunny300_binary_compressed.pcd",
        "bunny300.las",
        "bunny300_14.las",
        "bunny300.laz",
        "bunny300_14.laz",
        "bunny300.e57",
        "bunny300_spherical.e57",
    ] {
        if let Some(b) = read(&format!("crates/field-core/tests/data/{name}")) {
            out.push(seed(name, b));
        }
    }
    for dir in ["data/geology/greenstone", "data/geology/perth_basin"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir)) else {
            continue;
        };
        let mut paths: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
        paths.sort();
        for p in paths {
            if let Ok(b) = std::fs::read(&p) {
                let name = p.file_name().unwrap().to_string_lossy().into_owned();
                out.push(seed(&name, if small { prefix_lines(&b, 1500) } else { b }));
            }
        }
    }
    out
}

/// Hand-written text seeds (the variants the writers do not produce).
fn text_seeds() -> Vec<Seed> {
    let t = |name: &str, text: &str| seed(name, text.as_bytes().to_vec());
    let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for (k, p) in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]]
        .iter()
        .enumerate()
    {
        for v in p {
            be.extend_from_slice(&v.to_be_bytes());
        }
        be.push(k as u8);
    }
    be.push(3);
    for i in 0..3i32 {
        be.extend_from_slice(&i.to_be_bytes());
    }
    vec![
        t(
            "quads.ply",
            "ply\nformat ascii 1.0\ncomment a cube of quads\nelement vertex 8\nproperty double x\nproperty double y\nproperty double z\nelement face 6\nproperty list uchar uint vertex_index\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 2 3 7 6\n4 1 2 6 5\n4 0 4 7 3\n",
        ),
        t(
            "normals_ascii.ply",
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n0 0 0 0 0 1 255\n1 0 0 0 0 1 0\n0 1 0 0 0 1 7\n0 0 1 1 0 0 9\n0 1\n",
        ),
        seed("tri_be.ply", be),
        t("three.xyz", "# x y z\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"),
        t(
            "six.xyzn",
            "0,0,0, 0,0,1\n1 0 0 0 0 1 # comment\n\n0 1 0 0 0 1\n0 0 1 0.6 0.8 0\n",
        ),
        t("rgb.txt", "0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n"),
        t(
            "normals.csv",
            ",x,y,z,nx,ny,nz,label\n0,0,0,0,0,0,1,a\n1,1,0,0,0,0,1,b\n2,0,1,0,1,0,0,c\n",
        ),
        t("plain.csv", "X,Y,Z\n1,2,3\n4,5,6\n7,8,9.5\n"),
        t(
            "orient.csv",
            "X,Y,Z,azimuth,dip,polarity,formation\n0,0,0,90,30,1,A\n1,1,1,180,-10,-1,B\n",
        ),
        t("points.csv", "X,Y,Z,surface,series\n0,0,0,A,s\n1,1,1,B,s\n"),
        t("square.xyv", "# x y value\n0 0 -1\n1 0 0\n0 1 0\n2 2 1\n"),
        t(
            "sphere.xyzv",
            "0 0 0 -1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n2,2,2,1\n",
        ),
    ]
}

/// Seeds written with the library's writers and fits: PLY clouds and meshes and `.zsf` files.
fn generated(dir: &Path) -> Result<Vec<Seed>, String> {
    use zeroset::bases::bspline::{BSplineField, Degree};
    use zeroset::bases::field_file;
    use zeroset::bases::mras::{MrasOptions, fit_mras};
    use zeroset::bases::neural::{NeuralFit, NeuralParams};
    use zeroset::bases::rbf::{Biharmonic, Constraints, RbfFit, ThinPlate, Triharmonic, Wendland};
    use zeroset::core::cloud::PointCloud3;
    use zeroset::core::geometry::Aabb;
    use zeroset::core::grid::Grid;
    use zeroset::mesh::{PlyFormat, TriMesh};

    let e = |e: &dyn std::fmt::Display| e.to_string();
    let sphere = |n: usize| super::shapes::sphere(n, 0.5);
    let mut out = Vec::new();
    let file = |name: &str| dir.join(name);

    // PLY point clouds (binary little-endian doubles).
    let (p, n) = sphere(30);
    let cloud = PointCloud3::with_normals(p.clone(), n.clone()).map_err(|x| e(&x))?;
    zeroset::core::io::write_ply(file("cloud_normals.ply"), &cloud).map_err(|x| e(&x))?;
    let bare = PointCloud3::new(p[..10].to_vec()).map_err(|x| e(&x))?;
    zeroset::core::io::write_ply(file("cloud.ply"), &bare).map_err(|x| e(&x))?;

    // PLY meshes: an octahedron, both encodings.
    let v = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let t = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    let mesh = TriMesh::new(v, t).map_err(|x| e(&x))?;
    zeroset::mesh::write_ply(file("octa_bin.ply"), &mesh, PlyFormat::BinaryLittleEndian)
        .map_err(|x| e(&x))?;
    zeroset::mesh::write_ply(file("octa_ascii.ply"), &mesh, PlyFormat::Ascii).map_err(|x| e(&x))?;

    // B-spline fields, 2-D and 3-D.
    let g3 = Grid::cell_centered(Aabb::centered_cube(1.0).map_err(|x| e(&x))?, [4, 5, 6])
        .map_err(|x| e(&x))?;
    let s3 = (0..g3.len()).map(|i| (i as f64 * 0.37).sin()).collect();
    let f3 = BSplineField::interpolate(g3, s3, Degree::Quadratic).map_err(|x| e(&x))?;
    field_file::write_field(file("bspline3.zsf"), &f3).map_err(|x| e(&x))?;
    let g2 = Grid::cell_centered(
        Aabb::new([-1.0, -1.0], [1.0, 2.0]).map_err(|x| e(&x))?,
        [5, 4],
    )
    .map_err(|x| e(&x))?;
    let s2 = (0..g2.len()).map(|i| (i as f64 * 0.51).cos()).collect();
    let f2 = BSplineField::interpolate(g2, s2, Degree::Cubic).map_err(|x| e(&x))?;
    field_file::write_field(file("bspline2.zsf"), &f2).map_err(|x| e(&x))?;

    // RBF fields: every stored kernel.
    let (p, n) = sphere(16);
    let mut c3 = Constraints::new();
    for (x, u) in p.iter().zip(&n) {
        c3.push_value(*x, 0.0);
        c3.push_value(std::array::from_fn(|a| x[a] + 0.1 * u[a]), 0.1);
    }
    c3.push_value([0.0; 3], -0.5);
    let mut c3g = c3.clone();
    c3g.push_gradient([0.0, 0.0, 0.5], [0.0, 0.0, 1.0]);
    let r = RbfFit::new(Biharmonic).fit(&c3).map_err(|x| e(&x))?;
    field_file::write_rbf_field(file("rbf_r.zsf"), &r.field).map_err(|x| e(&x))?;
    let r = RbfFit::new(Triharmonic).fit(&c3g).map_err(|x| e(&x))?;
    field_file::write_rbf_field(file("rbf_r3.zsf"), &r.field).map_err(|x| e(&x))?;
    let w = Wendland::new(1.5).ok_or("wendland radius")?;
    let r = RbfFit::new(w).fit(&c3).map_err(|x| e(&x))?;
    field_file::write_rbf_field(file("rbf_wendland.zsf"), &r.field).map_err(|x| e(&x))?;
    let mut c2 = Constraints::new();
    for k in 0..12 {
        let t = std::f64::consts::TAU * k as f64 / 12.0;
        c2.push_value([0.5 * t.cos(), 0.5 * t.sin()], 0.0);
    }
    c2.push_value([0.0, 0.0], -1.0);
    c2.push_value([1.0, 1.0], 1.0);
    let r = RbfFit::new(ThinPlate).fit(&c2).map_err(|x| e(&x))?;
    field_file::write_rbf_field(file("rbf_tps2.zsf"), &r.field).map_err(|x| e(&x))?;

    // Neural fields, 2-D and 3-D (a few steps: the weights need not be good).
    let params = NeuralParams::default().with_steps(3).with_aux_points(50);
    let mut pz: Vec<[f64; 2]> = Vec::new();
    let mut z = Vec::new();
    for k in 0..16 {
        let t = std::f64::consts::TAU * k as f64 / 16.0;
        pz.push([0.5 * t.cos(), 0.5 * t.sin()]);
        z.push(0.0);
    }
    pz.push([0.0, 0.0]);
    z.push(-1.0);
    let nf = NeuralFit::new(params.clone())
        .with_domain(Aabb::new([-1.0, -1.0], [1.0, 1.0]).map_err(|x| e(&x))?)
        .fit(&pz, &z)
        .map_err(|x| e(&x))?;
    field_file::write_neural_field(file("neural2.zsf"), &nf.field).map_err(|x| e(&x))?;
    let mut p3 = p.clone();
    let mut z3 = vec![0.0; p3.len()];
    p3.push([0.0; 3]);
    z3.push(-1.0);
    let nf = NeuralFit::new(params).fit(&p3, &z3).map_err(|x| e(&x))?;
    field_file::write_neural_field(file("neural3.zsf"), &nf.field).map_err(|x| e(&x))?;

    // MRAS: one and two levels.
    let (p, n) = sphere(400);
    for (levels, name) in [(1, "mras1.zsf"), (2, "mras2.zsf")] {
        let f = fit_mras(&p, &n, &MrasOptions::default().max_level(levels), &|_| true)
            .map_err(|x| e(&x))?;
        field_file::write_mras_field(file(name), &f.field).map_err(|x| e(&x))?;
    }

    for name in [
        "cloud_normals.ply",
        "cloud.ply",
        "octa_bin.ply",
        "octa_ascii.ply",
        "bspline3.zsf",
        "bspline2.zsf",
        "rbf_r.zsf",
        "rbf_r3.zsf",
        "rbf_wendland.zsf",
        "rbf_tps2.zsf",
        "neural2.zsf",
        "neural3.zsf",
        "mras1.zsf",
        "mras2.zsf",
    ] {
        let bytes = std::fs::read(file(name)).map_err(|x| e(&x))?;
        out.push(seed(name, bytes));
    }
    Ok(out)
}

/// Bump when [`generated`] changes, so that stale caches are not used.
const CACHE_VERSION: u32 = 1;

/// All seeds: the real files, the hand-written ones and the generated ones (read from the
/// cache folder `cache` if it holds them, else generated and written there).
pub fn all(cache: &Path, small: bool) -> Vec<Seed> {
    let dir = cache.join(format!("v{CACHE_VERSION}"));
    let stamp = dir.join("complete");
    let mut gen_seeds = Vec::new();
    if stamp.exists() {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
            .map(|d| d.flatten().map(|e| e.path()).collect())
            .unwrap_or_default();
        paths.sort();
        for p in paths {
            if p == stamp {
                continue;
            }
            if let Ok(b) = std::fs::read(&p) {
                gen_seeds.push(seed(&p.file_name().unwrap().to_string_lossy(), b));
            }
        }
    } else {
        let _ = std::fs::create_dir_all(&dir);
        match generated(&dir) {
            Ok(s) => {
                let _ = std::fs::write(&stamp, b"");
                gen_seeds = s;
            }
            Err(e) => panic!("fuzz: cannot generate the seeds in {}: {e}", dir.display()),
        }
    }
    let mut out = real_files(small);
    out.extend(text_seeds());
    out.extend(gen_seeds);
    out
}

/// The seeds of `target` among `seeds`.
pub fn for_target(target: Target, seeds: &[Seed]) -> Vec<Seed> {
    let zsf_kind = |prefix: &str| {
        seeds
            .iter()
            .filter(|s| s.ext == "zsf" && s.name.starts_with(prefix))
            .cloned()
            .collect()
    };
    let by_ext = |exts: &[&str]| -> Vec<Seed> {
        seeds
            .iter()
            .filter(|s| exts.contains(&s.ext.as_str()))
            .cloned()
            .collect()
    };
    match target {
        Target::PlyCloud | Target::PlyMesh => by_ext(&["ply"]),
        Target::StlMesh => by_ext(&["stl"]),
        Target::ObjMesh => by_ext(&["obj"]),
        Target::OffMesh => by_ext(&["off"]),
        Target::Xyz => by_ext(&["xyz", "xyzn", "txt"]),
        Target::Pcd => by_ext(&["pcd"]),
        Target::Las => by_ext(&["las", "laz"]),
        Target::E57 => by_ext(&["e57"]),
        Target::Csv | Target::GemPy => by_ext(&["csv"]),
        Target::Xyv => by_ext(&["xyv"]),
        Target::Xyzv => by_ext(&["xyzv"]),
        Target::ZsfBspline => zsf_kind("bspline"),
        Target::ZsfRbf => zsf_kind("rbf"),
        Target::ZsfNeural => zsf_kind("neural"),
        Target::ZsfMras => zsf_kind("mras"),
        Target::Info => seeds
            .iter()
            .filter(|s| s.bytes.len() < 64 * 1024)
            .cloned()
            .collect(),
    }
}
