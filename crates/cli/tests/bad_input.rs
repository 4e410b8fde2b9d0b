//! The bad-input catalogue (`docs/bad-input.md`), generated from the cases below.
//!
//! Every case gives one named class of bad input (an empty file, a NaN coordinate, a truncated
//! binary PLY, a corrupted `.zsf` checksum, a grid resolution of 0, an output directory that
//! does not exist, ...) to one `zeroset` command or one library reader, and checks what it gets:
//! no panic; for the binary, exit status 1 (an error it reports) or 2 (an argument clap
//! rejects) and an `error:` line; the file involved named in that line; the phrases the case
//! lists; an existing output left untouched and no output (nor temporary file) left behind.
//! A few classes are suspicious but legal ("accepted"): the case then checks the line of the
//! report that says what was noticed.
//!
//! The test then renders the catalogue. With `ZEROSET_BLESS=1` it writes `docs/bad-input.md`;
//! otherwise it fails when the committed file differs. The inputs are made in a temporary
//! directory from a few lines of `samples/bunny_2k.xyzn` and from fields, clouds and meshes
//! written by the library from fixed numbers, so that every message (sizes, checksums, record
//! numbers) is the same on every machine; the commands run in that directory on relative
//! paths with `ZEROSET_MEMORY_LIMIT` fixed, and any absolute temporary path left in a message
//! is cut down to the file name.

use std::fmt::Write as _;
use std::fs;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::Command;

use zeroset_bases::bspline::{BSplineField, Boundary, Degree};
use zeroset_bases::field_file::{read_any_field, write_field};
use zeroset_field_core::cloud::PointCloud3;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::io::gempy::read_gempy_file;
use zeroset_field_core::io::{read_point_cloud, read_value_points};
use zeroset_mesh::{PlyFormat, TriMesh};

/// The committed catalogue, relative to this crate.
const DOC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/bad-input.md");

/// The memory cap every command runs under, so that no message depends on this machine.
const MEMORY_LIMIT: &str = "1GiB";

/// What an existing output holds before a failing command; it must still hold it afterwards.
const SENTINEL: &[u8] = b"an existing output: a failed command must leave it as it is\n";

// ---------------------------------------------------------------------------------------------
// The inputs.

/// An input file (or directory) made in the temporary directory, and what it holds in words.
struct Input {
    name: &'static str,
    what: &'static str,
}

/// Writes every input into `dir` and returns their descriptions, in the catalogue's order.
fn make_inputs(dir: &Path) -> Vec<Input> {
    let mut m = Made {
        dir,
        list: Vec::new(),
    };

    // Point clouds: 50 lines of the sample, and variants.
    let sample = fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/bunny_2k.xyzn"
    ))
    .unwrap();
    let bunny: String = sample
        .lines()
        .step_by(40)
        .map(|l| format!("{l}\n"))
        .collect();
    let p = "0.1 0.2 0.3 0 0 1\n";
    m.put(
        "bunny.xyzn",
        "a valid oriented cloud: 50 points (every 40th line of `samples/bunny_2k.xyzn`)",
        bunny.as_bytes(),
    );
    m.put("empty.xyzn", "0 bytes", b"");
    m.put(
        "comments.xyzn",
        "a comment line and a blank line: no point",
        b"# x y z nx ny nz\n\n",
    );
    m.put(
        "nan.xyzn",
        "two oriented points, the second `1 NaN 0 0 0 1`",
        b"0 0 0 0 0 1\n1 NaN 0 0 0 1\n",
    );
    m.put(
        "inf_normal.xyzn",
        "two oriented points, the second with normal `0 0 inf`",
        b"0 0 0 0 0 1\n1 1 0 0 0 inf\n",
    );
    m.put(
        "word.xyzn",
        "line 2 holds `abc` where a number belongs",
        b"0 0 0 0 0 1\n1 abc 0 0 0 1\n",
    );
    m.put(
        "ragged.xyzn",
        "6 numbers on line 1, 4 on line 2",
        b"0 0 0 0 0 1\n1 1 0 0\n",
    );
    m.put(
        "rgb.xyz",
        "`x y z r g b`: colour columns where normals would be",
        b"0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n",
    );
    m.put(
        "positions.xyz",
        "the 50 points of `bunny.xyzn` without their normals (3 columns)",
        bunny
            .lines()
            .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" ") + "\n")
            .collect::<String>()
            .as_bytes(),
    );
    m.put(
        "zero_normals.xyzn",
        "the 50 points of `bunny.xyzn` with every normal `0 0 0` (placeholders, as CGAL writes \
         where a point has none)",
        bunny
            .lines()
            .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" ") + " 0 0 0\n")
            .collect::<String>()
            .as_bytes(),
    );
    m.put(
        "curves.xyzn",
        "64 points of a circle on the plane z = 0, their normals in that plane: 2-D data",
        (0..64)
            .map(|k| {
                let t = k as f64 * std::f64::consts::TAU / 64.0;
                format!("{} {} 0 {} {} 0\n", t.cos(), t.sin(), t.cos(), t.sin())
            })
            .collect::<String>()
            .as_bytes(),
    );
    m.put(
        "same.xyzn",
        "5 copies of one oriented point: a degenerate cloud with no extent",
        p.repeat(5).as_bytes(),
    );
    m.put(
        "dup.xyzn",
        "`bunny.xyzn` twice: every point repeated",
        bunny.repeat(2).as_bytes(),
    );
    m.put(
        "latin1.xyzn",
        "line 2 starts with the bytes FF FE: not UTF-8",
        b"0 0 0 0 0 1\n\xff\xfe 1 0 0 0 1\n",
    );
    m.put(
        "bunny.rcp",
        "the text of `bunny.xyzn` under an extension no reader knows (`.rcp`, Autodesk ReCap's project format)",
        bunny.as_bytes(),
    );
    m.put(
        "text.e57",
        "the text of `bunny.xyzn` named as an E57 laser scan",
        bunny.as_bytes(),
    );
    m.put(
        "cloud.stl",
        "the text of `bunny.xyzn` named as an STL mesh",
        bunny.as_bytes(),
    );
    m.put(
        "bunny.ply.gz",
        "the ten header bytes of a gzip stream: a scan shipped compressed",
        &[0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3],
    );
    fs::create_dir(dir.join("folder.xyzn")).unwrap();
    m.note("folder.xyzn", "a directory");
    fs::create_dir(dir.join("folder.e57")).unwrap();
    m.note("folder.e57", "a directory named like an E57 scan");
    m.note("missing.xyzn", "not there: no such file");

    // PLY point clouds.
    let positions: Vec<[f64; 3]> = bunny
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let cloud = PointCloud3::new(positions).unwrap();
    zeroset_field_core::io::write_ply(dir.join("cloud.ply"), &cloud).unwrap();
    let cloud_ply = fs::read(dir.join("cloud.ply")).unwrap();
    m.put(
        "cloud_trunc.ply",
        "a binary little-endian PLY of the 50 positions (`double x y z`), cut after 30 of its \
         50 vertex records",
        &cloud_ply[..cloud_ply.len() - 20 * 24],
    );
    fs::remove_file(dir.join("cloud.ply")).unwrap();
    let ascii_head = |count: usize, props: &str| {
        let mut h = format!("ply\nformat ascii 1.0\nelement vertex {count}\n");
        for p in props.split_whitespace() {
            let _ = writeln!(h, "property float {p}");
        }
        h + "end_header\n"
    };
    m.put(
        "cloud_count.ply",
        "an ascii PLY whose header announces 100 vertices; it holds 3",
        (ascii_head(100, "x y z") + "0 0 0\n1 0 0\n0 1 0\n").as_bytes(),
    );
    m.put(
        "cloud_nx.ply",
        "an ascii PLY with properties `x y z nx ny` (no `nz`)",
        (ascii_head(2, "x y z nx ny") + "0 0 0 0 0\n1 0 0 0 1\n").as_bytes(),
    );
    m.put(
        "cloud_xyz.ply",
        "an ascii PLY of 3 vertices with `x y z` only: no normals, no faces",
        (ascii_head(3, "x y z") + "0 0 0\n1 0 0\n0 1 0\n").as_bytes(),
    );
    m.put(
        "encoding.ply",
        "a PLY header saying `format binary_middle_endian 1.0`",
        ascii_head(1, "x y z")
            .replace("ascii", "binary_middle_endian")
            .as_bytes(),
    );
    m.put(
        "notply.ply",
        "the text of `bunny.xyzn` named `.ply`: no `ply` magic line",
        bunny.as_bytes(),
    );

    // CSV and GemPy tables.
    m.put(
        "noz.csv",
        "header `x,y,w`: no `z` column",
        b"x,y,w\n0,0,0\n",
    );
    m.put(
        "word.csv",
        "header `x,y,z`, the second row `1,abc,0`",
        b"x,y,z\n0,0,0\n1,abc,0\n",
    );
    m.put(
        "header_only.csv",
        "the header row `x,y,z,nx,ny,nz` and nothing else",
        b"x,y,z,nx,ny,nz\n",
    );
    m.put(
        "gempy_noz.csv",
        "a GemPy surface-points table with header `X,Y,formation`: no `Z`",
        b"X,Y,formation\n0,0,Sand\n",
    );
    m.put(
        "gempy_dip.csv",
        "a GemPy orientations table whose dip is `steep`",
        b"X,Y,Z,azimuth,dip,polarity,formation\n0,0,0,90,steep,1,Shale\n",
    );

    // Value constraints.
    m.put(
        "count.xyv",
        "2-D value constraints, line 2 with 4 numbers",
        b"0 0 -1\n1 0 0 5\n",
    );
    m.put(
        "nan.xyv",
        "2-D value constraints, line 2 with value `NaN`",
        b"0 0 -1\n1 0 NaN\n",
    );
    m.put("empty.xyv", "0 bytes", b"");
    m.put(
        "conflict.xyv",
        "2-D value constraints, line 5 at line 1's point (1e-17 away) with another value",
        b"0 0 -1\n1 0 1\n0 1 1\n1 1 1\n1e-17 0 1\n",
    );
    m.put(
        "level.xyzv",
        "3-D value constraints, every value 0 (one surface's points)",
        b"0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n",
    );

    // Field files: a B-spline field of the distance to a sphere, and corruptions of it.
    let sphere = bspline_field::<3>();
    write_field(dir.join("sphere.zsf"), &sphere).unwrap();
    m.note(
        "sphere.zsf",
        "a valid 3-D field file: a quadratic B-spline on an 8×8×8 grid over [-1, 1]³ (the \
               distance to a sphere of radius 0.5)",
    );
    write_field(dir.join("disc.zsf"), &bspline_field::<2>()).unwrap();
    m.note(
        "disc.zsf",
        "a valid 2-D field file: the same on an 8×8 grid over [-1, 1]²",
    );
    let zsf = fs::read(dir.join("sphere.zsf")).unwrap();
    let mut crc = zsf.clone();
    crc[zsf.len() / 2] ^= 0x10;
    m.put(
        "crc.zsf",
        "`sphere.zsf` with one bit of its payload flipped: the checksum does not match",
        &crc,
    );
    m.put(
        "trunc.zsf",
        "the first half of `sphere.zsf`",
        &zsf[..zsf.len() / 2],
    );
    m.put(
        "head.zsf",
        "the first 10 bytes of `sphere.zsf` (part of the magic and version)",
        &zsf[..10],
    );
    let mut newer = zsf.clone();
    newer[8..12].copy_from_slice(&9u32.to_le_bytes());
    m.put(
        "newer.zsf",
        "`sphere.zsf` with its version set to 9",
        &newer,
    );
    m.put(
        "magic.zsf",
        "a line of text named `.zsf`: no field-file magic",
        b"not a field file\n",
    );
    m.put("empty.zsf", "0 bytes", b"");

    // Meshes: a tetrahedron, and variants.
    let tet = TriMesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
    .unwrap();
    zeroset_mesh::write_ply(dir.join("tet.ply"), &tet, PlyFormat::BinaryLittleEndian).unwrap();
    m.note(
        "tet.ply",
        "a valid mesh: a binary PLY tetrahedron (4 vertices, 4 triangles)",
    );
    let tet_bytes = fs::read(dir.join("tet.ply")).unwrap();
    m.put(
        "tet_trunc.ply",
        "`tet.ply` without its last 10 bytes (inside the face records)",
        &tet_bytes[..tet_bytes.len() - 10],
    );
    let mesh_head = |vertices: usize, faces: usize| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex {vertices}\nproperty float x\n\
             property float y\nproperty float z\nelement face {faces}\n\
             property list uchar int vertex_indices\nend_header\n"
        )
    };
    let tet_vertices = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
    m.put(
        "tet_index.ply",
        "an ascii PLY tetrahedron whose last face refers to vertex 7 of 4",
        (mesh_head(4, 4) + tet_vertices + "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 7\n").as_bytes(),
    );
    m.put(
        "tet_count.ply",
        "an ascii PLY tetrahedron whose header announces 10 faces; it holds 4",
        (mesh_head(4, 10) + tet_vertices + "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n").as_bytes(),
    );
    m.put(
        "tet_nan.ply",
        "an ascii PLY tetrahedron with vertex 1 at `1 nan 0`",
        (mesh_head(4, 4)
            + "0 0 0\n1 nan 0\n0 1 0\n0 0 1\n"
            + "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
            .as_bytes(),
    );
    m.put(
        "tet_two.ply",
        "an ascii PLY tetrahedron whose last face has 2 corners",
        (mesh_head(4, 4) + tet_vertices + "3 0 2 1\n3 0 1 3\n3 0 3 2\n2 1 2\n").as_bytes(),
    );
    let stl = zeroset_mesh::io::stl_to_bytes(&tet, zeroset_mesh::StlFormat::Binary).unwrap();
    m.put(
        "tet_trunc.stl",
        "a binary STL tetrahedron without its last 30 bytes (inside triangle 3)",
        &stl[..stl.len() - 30],
    );
    m.put(
        "tet_nan.stl",
        "an ASCII STL facet with the corner `vertex 1 nan 0`",
        b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 nan 0\n\
          vertex 0 1 0\nendloop\nendfacet\nendsolid t\n",
    );
    m.put("tiny.stl", "a 10-byte file named .stl", b"not a mesh");
    let obj_vertices = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
    m.put(
        "tet_index.obj",
        "an OBJ tetrahedron whose last face refers to vertex 7 of 4",
        (obj_vertices.to_owned() + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 7\n").as_bytes(),
    );
    m.put(
        "tet_zero.obj",
        "an OBJ tetrahedron whose first face refers to vertex 0 (OBJ counts from 1)",
        (obj_vertices.to_owned() + "f 0 2 1\nf 1 2 4\nf 1 4 3\nf 2 3 4\n").as_bytes(),
    );
    m.put(
        "binary.obj",
        "bytes that are not text, named .obj",
        &[b'v', b' ', 0xff, 0xfe, 0, 1, b'\n'],
    );
    m.put(
        "tet_index.off",
        "an OFF tetrahedron whose last face refers to vertex 7 of 4 (OFF counts from 0)",
        b"OFF\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 7\n",
    );
    m.put(
        "tet_short.off",
        "an OFF whose counts announce 4 vertices and 4 faces; it ends after 2 vertices",
        b"OFF\n4 4 6\n0 0 0\n1 0 0\n",
    );
    let pcd_head = |points: usize, data: &str| {
        format!(
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n\
             SIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {points}\nHEIGHT 1\n\
             VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n"
        )
    };
    m.put(
        "short.pcd",
        "a binary PCD announcing 100 points of 12 bytes, holding 30 bytes",
        &[pcd_head(100, "binary").into_bytes(), vec![0; 30]].concat(),
    );
    m.put(
        "lzf.pcd",
        "a binary_compressed PCD whose LZF block is garbage (sizes 6 and 24)",
        &[
            pcd_head(2, "binary_compressed").into_bytes(),
            [6u32.to_le_bytes(), 24u32.to_le_bytes()].concat(),
            vec![0xff; 6],
        ]
        .concat(),
    );
    m.put(
        "gaps.pcd",
        "an ASCII PCD of 3 points whose x y z are all NaN (an organised cloud's gaps)",
        (pcd_head(3, "ascii") + &"nan nan nan\n".repeat(3)).as_bytes(),
    );
    m.put(
        "type.pcd",
        "a PCD header with TYPE `F F D` (D is no PCD type)",
        pcd_head(1, "ascii")
            .replace("TYPE F F F", "TYPE F F D")
            .as_bytes(),
    );
    let laz = fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../field-core/tests/data/bunny300.laz"
    ))
    .unwrap();
    m.put(
        "bunny300.laz",
        "300 bunny points as LAZ (LAS compressed with LASzip), written by laspy 2.5.4",
        &laz,
    );
    // Its chunk table's count of chunks set to 2³² − 1 (64 GB of entries for the decoder).
    let start = u32::from_le_bytes([laz[96], laz[97], laz[98], laz[99]]) as usize;
    let table = i64::from_le_bytes(laz[start..start + 8].try_into().unwrap()) as usize;
    let mut chunks = laz.clone();
    chunks[table + 4..table + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    m.put(
        "chunks.laz",
        "`bunny300.laz` with its chunk table claiming 4,294,967,295 chunks",
        &chunks,
    );
    m.put(
        "cut.laz",
        "the first 400 bytes after the header of `bunny300.laz` (its points cut short)",
        &laz[..start + 400],
    );
    let e57 = fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../field-core/tests/data/bunny300.e57"
    ))
    .unwrap();
    m.put(
        "bunny300.e57",
        "300 bunny points with normals as E57, two scans with poses, written by libE57Format (pye57 0.4.19)",
        &e57,
    );
    let mut flipped = e57.clone();
    flipped[3000] ^= 0x20;
    m.put(
        "flipped.e57",
        "`bunny300.e57` with one bit of byte 3000 (its third page) changed",
        &flipped,
    );
    let las = fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../field-core/tests/data/bunny300.las"
    ))
    .unwrap();
    m.put(
        "cut.las",
        "the first 5,000 bytes of a LAS file of 300 points (20 bytes each) written by laspy",
        &las[..5000],
    );
    m.put(
        "named_noz.xyz",
        "an xyz file whose first line names the columns `x y w nx ny nz`",
        b"x y w nx ny nz\n0 0 0 0 0 1\n",
    );
    m.put(
        "decimal_comma.txt",
        "points written with decimal commas and semicolons: `1,5;2,0;3,25`",
        b"1,5;2,0;3,25\n",
    );
    m.list
}

/// Writes the inputs and keeps their descriptions.
struct Made<'a> {
    dir: &'a Path,
    list: Vec<Input>,
}

impl Made<'_> {
    /// Writes `bytes` to the file `name`, described as `what`.
    fn put(&mut self, name: &'static str, what: &'static str, bytes: &[u8]) {
        fs::write(self.dir.join(name), bytes).unwrap();
        self.note(name, what);
    }

    /// Describes `name`, made otherwise (or not at all: a missing file).
    fn note(&mut self, name: &'static str, what: &'static str) {
        self.list.push(Input { name, what });
    }
}

/// The quadratic B-spline whose coefficients are the distance to the sphere (circle) of radius
/// 0.5 about the origin, sampled on an 8ᴰ cell-centred grid over [-1, 1]ᴰ: fixed numbers, so
/// the file's bytes (and checksum) are the same on every machine.
fn bspline_field<const D: usize>() -> BSplineField<D> {
    let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [8; D]).unwrap();
    let coefficients = (0..grid.len())
        .map(|mut i| {
            let mut r2 = 0.0;
            for _ in 0..D {
                let x = -1.0 + 0.125 + 0.25 * (i % 8) as f64;
                r2 += x * x;
                i /= 8;
            }
            f64::sqrt(r2) - 0.5
        })
        .collect();
    BSplineField::from_coefficients(grid, coefficients, Degree::Quadratic, Boundary::HalfSample)
        .unwrap()
}

// ---------------------------------------------------------------------------------------------
// The cases.

/// A command of the binary or a library reader: one section of the catalogue each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Target {
    Info,
    Fit,
    Restore,
    Mesh,
    Preview,
    Reconstruct,
    Normals,
    CloudReader,
    GemPyReader,
    ValueReader,
    MeshReader,
    FieldReader,
}

impl Target {
    const ALL: [Target; 12] = [
        Target::Info,
        Target::Fit,
        Target::Restore,
        Target::Mesh,
        Target::Preview,
        Target::Reconstruct,
        Target::Normals,
        Target::CloudReader,
        Target::GemPyReader,
        Target::ValueReader,
        Target::MeshReader,
        Target::FieldReader,
    ];

    fn title(self) -> &'static str {
        match self {
            Target::Info => "`zeroset info`",
            Target::Fit => "`zeroset fit`",
            Target::Restore => "`zeroset restore`",
            Target::Mesh => "`zeroset mesh`",
            Target::Preview => "`zeroset preview`",
            Target::Reconstruct => "`zeroset reconstruct`",
            Target::Normals => "`zeroset normals`",
            Target::CloudReader => {
                "Point clouds: `zeroset_field_core::io::read_point_cloud` (PLY, xyz, CSV, GemPy)"
            }
            Target::GemPyReader => "GemPy tables: `zeroset_field_core::io::gempy::read_gempy_file`",
            Target::ValueReader => {
                "Value constraints: `zeroset_field_core::io::read_value_points::<2>` (xyv)"
            }
            Target::MeshReader => {
                "Meshes: `zeroset_mesh::read_mesh` (PLY, OBJ, STL or OFF, by the extension)"
            }
            Target::FieldReader => "Field files: `zeroset_bases::field_file::read_any_field::<3>`",
        }
    }

    fn subcommand(word: &str) -> Target {
        match word {
            "info" => Target::Info,
            "fit" => Target::Fit,
            "restore" => Target::Restore,
            "mesh" => Target::Mesh,
            "preview" => Target::Preview,
            "reconstruct" => Target::Reconstruct,
            "normals" => Target::Normals,
            _ => panic!("no subcommand {word}"),
        }
    }

    /// Runs this reader on `path`: a summary of what it read, or the error in words.
    fn read(self, path: &Path) -> Result<String, String> {
        let text = |e: &dyn std::fmt::Display| e.to_string();
        match self {
            Target::CloudReader => read_point_cloud(path)
                .map(|c| format!("{} points", c.len()))
                .map_err(|e| text(&e)),
            Target::GemPyReader => read_gempy_file(path)
                .map(|g| {
                    format!(
                        "{} surface points, {} orientations",
                        g.surface_points.len(),
                        g.orientations.len()
                    )
                })
                .map_err(|e| text(&e)),
            Target::ValueReader => read_value_points::<2>(path)
                .map(|v| format!("{} constraints", v.points.len()))
                .map_err(|e| text(&e)),
            Target::MeshReader => zeroset_mesh::read_mesh(path)
                .map(|m| {
                    format!(
                        "{} vertices, {} triangles",
                        m.vertices().len(),
                        m.triangles().len()
                    )
                })
                .map_err(|e| text(&e)),
            Target::FieldReader => read_any_field::<3>(path)
                .map(|f| f.describe())
                .map_err(|e| text(&e)),
            _ => unreachable!("{self:?} is a command"),
        }
    }
}

/// One case: an input class given to a command (`args`, run in the inputs' directory) or a
/// reader (`args` is then the file).
struct Case {
    target: Target,
    class: &'static str,
    args: &'static str,
    /// The file the error must name (`None`: no file is involved, e.g. a bad option value).
    names: Option<&'static str>,
    /// Phrases the error must hold (or, when accepted, the report line that says so).
    expect: Vec<&'static str>,
    /// Outputs that exist before the command (the sentinel) and must be untouched after it.
    keeps: Vec<&'static str>,
    /// Accepted: the input is legal, and the report says what was noticed.
    accepted: bool,
}

impl Case {
    /// The error names `file` (instead of the input).
    fn names(mut self, file: &'static str) -> Self {
        self.names = Some(file);
        self
    }

    /// No file is involved.
    fn no_file(mut self) -> Self {
        self.names = None;
        self
    }

    /// The error holds `phrase`.
    fn says(mut self, phrase: &'static str) -> Self {
        self.expect.push(phrase);
        self
    }

    /// `output` exists before the run and must be left as it was.
    fn keeps(mut self, output: &'static str) -> Self {
        self.keeps.push(output);
        self
    }

    /// The input is accepted; the report line holding `phrase` says what was noticed.
    fn accepted(mut self, phrase: &'static str) -> Self {
        self.accepted = true;
        self.names = None;
        self.expect.push(phrase);
        self
    }
}

/// A command line after `zeroset` (whitespace-separated words); the error must name its input
/// (the word after the subcommand) unless the case says otherwise.
fn cli(class: &'static str, args: &'static str) -> Case {
    let mut words = args.split_whitespace();
    let target = Target::subcommand(words.next().unwrap());
    Case {
        target,
        class,
        args,
        names: words.next(),
        expect: Vec::new(),
        keeps: Vec::new(),
        accepted: false,
    }
}

/// `file` given to a library reader; the error must name it.
fn reader(target: Target, class: &'static str, file: &'static str) -> Case {
    Case {
        target,
        class,
        args: file,
        names: Some(file),
        expect: Vec::new(),
        keeps: Vec::new(),
        accepted: false,
    }
}

/// A mask inside the box of `bunny.xyzn`.
macro_rules! bunny_mask {
    () => {
        "--mask -0.05,0.05,-0.03:0.05,0.12,0.06"
    };
}

fn cases() -> Vec<Case> {
    use Target::*;
    vec![
        // zeroset info
        cli("empty file", "info empty.xyzn").says("empty"),
        cli("no point (comments only)", "info comments.xyzn").says("no point"),
        cli("not a number", "info word.xyzn").says("'abc'"),
        cli("rows of different lengths", "info ragged.xyzn"),
        cli("not UTF-8", "info latin1.xyzn").says("UTF-8"),
        cli("missing file", "info missing.xyzn"),
        cli("directory instead of file", "info folder.xyzn"),
        cli("directory named .e57", "info folder.e57").says("a directory, not a file"),
        cli("a gzip-compressed scan", "info bunny.ply.gz").says("gunzip -k"),
        cli("wrong extension", "info bunny.rcp").says("unknown point-cloud format"),
        cli("a point cloud named .stl", "info cloud.stl").says("not ASCII STL"),
        cli("truncated binary PLY", "info cloud_trunc.ply").says("truncated"),
        cli("header count larger than the file", "info cloud_count.ply"),
        cli("unsupported PLY encoding", "info encoding.ply").says("binary_middle_endian"),
        cli("CSV without a z column", "info noz.csv").says("'z'"),
        cli("GemPy table without a Z column", "info gempy_noz.csv"),
        cli("corrupted .zsf checksum", "info crc.zsf").says("checksum"),
        cli("truncated .zsf", "info trunc.zsf").says("truncated"),
        cli(".zsf of a newer version", "info newer.zsf").says("version 9"),
        cli("out-of-range face index", "info tet_index.ply").says("vertex 7"),
        cli("truncated binary STL", "info tet_trunc.stl").says("triangle 3"),
        cli("OBJ face index out of range", "info tet_index.obj").says("line 8"),
        cli("OFF face index out of range", "info tet_index.off").says("line 10"),
        cli("truncated binary PCD", "info short.pcd").says("truncated"),
        cli("LAZ (compressed LAS)", "info bunny300.laz").accepted("300"),
        cli("LAZ with a crafted chunk table", "info chunks.laz").says("chunk table lists"),
        cli("LAZ cut short", "info cut.laz").names("cut.laz"),
        cli("E57 (laser scans with normals)", "info bunny300.e57").accepted("300"),
        cli("E57 with a changed byte", "info flipped.e57").says("checksum"),
        cli("text named .e57", "info text.e57").says("E57"),
        cli("truncated LAS", "info cut.las").says("truncated"),
        cli("PCD gaps only", "info gaps.pcd").says("NaN"),
        cli("header line without z", "info named_noz.xyz").says("'z'"),
        cli("decimal commas", "info decimal_comma.txt").says("decimal commas"),
        cli("unknown option value", "info bunny.xyzn --format stl")
            .no_file()
            .says("possible values"),
        cli("NaN coordinate", "info nan.xyzn").accepted("non-finite:"),
        cli("duplicate points", "info dup.xyzn").accepted("duplicates:"),
        cli("all points identical (degenerate cloud)", "info same.xyzn").accepted("diagonal"),
        // zeroset fit
        cli("empty file", "fit empty.xyzn --method rbf").says("empty"),
        cli("NaN coordinate", "fit nan.xyzn --method rbf").says("NaN"),
        cli(
            "infinite normal component",
            "fit inf_normal.xyzn --method rbf",
        )
        .says("inf"),
        cli("no normals", "fit positions.xyz --method rbf").says("normals"),
        cli("colour columns read as normals", "fit rgb.xyz --method rbf"),
        cli("every normal 0 0 0", "fit zero_normals.xyzn --method rbf").says("no normals"),
        cli(
            "curves in a plane (2-D data)",
            "fit curves.xyzn --method rbf",
        )
        .says("2-D"),
        cli(
            "all points identical (degenerate cloud)",
            "fit same.xyzn --method rbf",
        ),
        cli(
            "all points identical (degenerate cloud)",
            "fit same.xyzn --method mras",
        ),
        cli("duplicate points", "fit dup.xyzn --method rbf --quiet").accepted("merged"),
        cli("not UTF-8", "fit latin1.xyzn --method rbf").says("UTF-8"),
        cli("missing file", "fit missing.xyzn --method rbf"),
        cli("wrong extension", "fit bunny.rcp --method rbf"),
        cli("truncated OFF mesh", "fit tet_short.off --method rbf").says("truncated"),
        cli("corrupt LZF in PCD", "fit lzf.pcd --method rbf").says("decompress"),
        cli(
            "a field file where points belong",
            "fit sphere.zsf --method rbf",
        ),
        cli(
            "value file: wrong count on a line",
            "fit count.xyv --method rbf",
        )
        .says("count.xyv:2"),
        cli("value file: NaN value", "fit nan.xyv --method neural").says("NaN"),
        cli(
            "value file: two values at one place",
            "fit conflict.xyv --method rbf",
        )
        .says("lines 1 and 5 are at the same place"),
        cli(
            "value file: every value equal",
            "fit level.xyzv --method rbf",
        )
        .says("all 4 values are 0"),
        cli(
            "a value file where a point cloud belongs",
            "fit level.xyzv --method mras",
        )
        .says("not a point cloud"),
        cli(
            "--format naming a value file for a point cloud",
            "normals bunny.xyzn --format xyzv -o n.ply",
        )
        .no_file()
        .says("names a value-constraint file"),
        cli("unknown option value", "fit bunny.xyzn --method spline")
            .no_file()
            .says("possible values"),
        cli("negative offset", "fit bunny.xyzn --method rbf --offset=-1").no_file(),
        cli(
            "kernel for another dimension",
            "fit bunny.xyzn --method rbf --kernel tps",
        )
        .no_file()
        .says("tps"),
        cli(
            "zero grid resolution",
            "fit bunny.xyzn --method rbf -o out.zsf --sampled --grid 0,4,4",
        )
        .no_file(),
        cli(
            "output directory does not exist",
            "fit bunny.xyzn --method rbf -o nodir/out.zsf",
        )
        .names("nodir"),
        cli(
            "output exists (no --force)",
            "fit bunny.xyzn --method rbf -o out.zsf",
        )
        .names("out.zsf")
        .keeps("out.zsf"),
        cli(
            "bad input with an existing output and --force",
            "fit nan.xyzn --method rbf -o out.zsf --force",
        )
        .keeps("out.zsf"),
        // zeroset restore
        cli(
            "mask outside the box",
            "restore bunny.xyzn --mode protrusion --mask 5,5,5:6,6,6 -o out.zsf",
        )
        .no_file()
        .says("outside"),
        cli(
            "mask partly outside the box",
            "restore bunny.xyzn --mode protrusion --mask -5,0.05,-0.03:0.05,0.12,0.06 -o out.zsf",
        )
        .accepted("cut to that box"),
        cli(
            "mask of zero width",
            "restore bunny.xyzn --mode protrusion --mask 0,0.1,0:0,0.15,0.05 -o out.zsf",
        )
        .no_file(),
        cli(
            "malformed mask",
            "restore bunny.xyzn --mode protrusion --mask 0,0,0,1,1,1 -o out.zsf",
        )
        .no_file()
        .says("two corners"),
        cli(
            "denoise without --coarse",
            concat!(
                "restore bunny.xyzn --mode denoise ",
                bunny_mask!(),
                " -o out.zsf"
            ),
        )
        .no_file()
        .says("--coarse"),
        cli(
            "negative grid resolution",
            concat!(
                "restore bunny.xyzn --mode protrusion ",
                bunny_mask!(),
                " --grid=-3,4,4 -o out.zsf"
            ),
        )
        .no_file(),
        cli(
            ".zsf of another dimension",
            "restore disc.zsf --mode protrusion --mask 0,0,0:1,1,1 -o out.zsf",
        )
        .says("2-D"),
        cli(
            "corrupted .zsf checksum",
            "restore crc.zsf --mode protrusion --mask 0,0,0:0.5,0.5,0.5 -o out.zsf",
        )
        .says("checksum"),
        cli(
            "all points identical (degenerate cloud)",
            "restore same.xyzn --mode protrusion --mask 0,0,0:1,1,1 -o out.zsf",
        ),
        cli(
            "no normals",
            concat!(
                "restore positions.xyz --mode protrusion ",
                bunny_mask!(),
                " -o out.zsf"
            ),
        ),
        cli(
            "a mesh as the cloud (its vertices, normals from its winding)",
            "restore tet.ply --mode protrusion --mask 0,0,0:0.5,0.5,0.5 -o out.zsf",
        )
        .accepted("normals from the triangles' winding"),
        cli(
            "output overwrites the input",
            "restore sphere.zsf --mode protrusion --mask 0,0,0:0.5,0.5,0.5 -o sphere.zsf \
             --force",
        )
        .says("overwrite the input")
        .keeps("sphere.zsf"),
        cli(
            "bad input with an existing output and --force",
            "restore nan.xyzn --mode protrusion --mask 0,0,0:1,1,1 -o out.zsf --force",
        )
        .keeps("out.zsf"),
        // zeroset mesh
        cli(
            "a point cloud where a field belongs",
            "mesh bunny.xyzn -o out.ply",
        ),
        cli("empty .zsf", "mesh empty.zsf -o out.ply"),
        cli("header-only .zsf", "mesh head.zsf -o out.ply").says("truncated"),
        cli("truncated .zsf", "mesh trunc.zsf -o out.ply").says("truncated"),
        cli("corrupted .zsf checksum", "mesh crc.zsf -o out.ply").says("checksum"),
        cli(".zsf of a newer version", "mesh newer.zsf -o out.ply").says("version 9"),
        cli("not a field file (bad magic)", "mesh magic.zsf -o out.ply").says("magic"),
        cli("missing file", "mesh missing.zsf -o out.ply"),
        cli("directory instead of file", "mesh folder.xyzn -o out.ply"),
        cli(
            "zero grid resolution",
            "mesh sphere.zsf -o out.ply --resolution 0",
        )
        .no_file(),
        cli("negative voxel", "mesh sphere.zsf -o out.ply --voxel=-1").no_file(),
        cli("NaN voxel", "mesh sphere.zsf -o out.ply --voxel NaN").no_file(),
        cli(
            "unknown option value",
            "mesh sphere.zsf -o out.ply --detail ultra",
        )
        .no_file()
        .says("possible values"),
        cli("wrong output extension", "mesh sphere.zsf -o out.3mf").names("out.3mf"),
        cli(
            "--ascii with OBJ output",
            "mesh sphere.zsf -o out.obj --ascii",
        )
        .names("out.obj")
        .says("always text"),
        cli(
            "2-D field meshed to a 3-D format",
            "mesh disc.zsf -o out.ply",
        )
        .names("out.ply"),
        cli(
            "output directory does not exist",
            "mesh sphere.zsf -o nodir/out.ply",
        )
        .names("nodir"),
        cli("output exists (no --force)", "mesh sphere.zsf -o out.ply")
            .names("out.ply")
            .keeps("out.ply"),
        cli(
            "--trim for a field that records no points, without --scan",
            "mesh sphere.zsf -o out.ply --trim",
        )
        .no_file()
        .says("--scan"),
        cli("--trim for a 2-D field", "mesh disc.zsf -o out.svg --trim")
            .no_file()
            .says("3-D fields"),
        cli("--trim of zero", "mesh sphere.zsf -o out.ply --trim=0")
            .no_file()
            .says("finite positive"),
        cli("--trim of NaN", "mesh sphere.zsf -o out.ply --trim=nan")
            .no_file()
            .says("finite positive"),
        cli(
            "--scan file missing",
            "mesh sphere.zsf -o out.ply --trim --scan missing.xyzn",
        )
        .no_file()
        .names("missing.xyzn"),
        cli(
            "--scan with a NaN coordinate",
            "mesh sphere.zsf -o out.ply --trim --scan nan.xyzn",
        )
        .no_file()
        .says("NaN"),
        cli(
            "--trim to a scan of 5 copies of one point",
            "mesh sphere.zsf -o out.ply --trim --scan same.xyzn",
        )
        .no_file()
        .says("cannot trim"),
        cli(
            "bad input with an existing output and --force",
            "mesh crc.zsf -o out.ply --force",
        )
        .keeps("out.ply"),
        // zeroset preview
        cli(
            "neither a mesh nor a field",
            "preview bunny.xyzn -o out.png",
        ),
        cli(
            "out-of-range face index",
            "preview tet_index.ply -o out.png",
        )
        .says("vertex 7"),
        cli("truncated binary PLY", "preview tet_trunc.ply -o out.png").says("truncated"),
        cli("truncated binary STL", "preview tet_trunc.stl -o out.png").says("truncated"),
        cli("OBJ face index 0", "preview tet_zero.obj -o out.png").says("start at 1"),
        cli(
            "a mesh with no triangle",
            "preview cloud_xyz.ply -o out.png",
        ),
        cli("corrupted .zsf checksum", "preview crc.zsf -o out.png").says("checksum"),
        cli(
            "zero image width",
            "preview sphere.zsf -o out.png --width 0",
        )
        .no_file(),
        cli(
            "NaN camera angle",
            "preview tet.ply -o out.png --azimuth NaN",
        )
        .no_file(),
        cli(
            "unknown option value",
            "preview sphere.zsf -o out.png --slice w",
        )
        .no_file(),
        cli(
            "slice outside the field's box",
            "preview sphere.zsf -o out.png --slice z=40",
        )
        .says("outside the field's box")
        .no_file(),
        cli("wrong output extension", "preview sphere.zsf -o out.jpg").names("out.jpg"),
        cli(
            "bad input with an existing output and --force",
            "preview tet_nan.ply -o out.png --force",
        )
        .keeps("out.png"),
        // zeroset reconstruct
        cli("empty file", "reconstruct empty.xyzn -o out.ply --quiet"),
        cli(
            "a viewpoint for a scan with normals",
            "reconstruct bunny.xyzn -o out.ply --viewpoint 0,0,1 --quiet",
        )
        .says("normals of its own"),
        cli(
            "negative --trim",
            "reconstruct bunny.xyzn -o out.ply --trim=-1 --quiet",
        )
        .no_file()
        .says("finite positive"),
        cli(
            "NaN viewpoint",
            "reconstruct positions.xyz -o out.ply --viewpoint 0,nan,1 --quiet",
        )
        .no_file()
        .says("finite"),
        cli("NaN coordinate", "reconstruct nan.xyzn -o out.ply --quiet"),
        cli("no normals", "reconstruct positions.xyz -o out.ply --quiet")
            .accepted("has no normals: estimating them"),
        cli(
            "every normal 0 0 0",
            "reconstruct zero_normals.xyzn -o out.ply --quiet",
        )
        .accepted("every normal is 0 0 0"),
        cli(
            "curves in a plane (2-D data)",
            "reconstruct curves.xyzn -o out.ply --quiet",
        )
        .says("2-D"),
        cli(
            "all points identical (degenerate cloud)",
            "reconstruct same.xyzn -o out.ply --quiet",
        ),
        cli(
            "missing file",
            "reconstruct missing.xyzn -o out.ply --quiet",
        ),
        cli(
            "wrong output extension",
            "reconstruct bunny.xyzn -o out.3mf --quiet",
        )
        .names("out.3mf"),
        cli(
            "output directory does not exist",
            "reconstruct bunny.xyzn -o nodir/out.ply --quiet",
        )
        .names("nodir"),
        cli(
            "bad input with an existing output and --force",
            "reconstruct nan.xyzn -o out.ply --force --quiet",
        )
        .keeps("out.ply"),
        // zeroset normals
        cli("empty file", "normals empty.xyzn -o out.ply --quiet"),
        cli("NaN coordinate", "normals nan.xyzn -o out.ply --quiet"),
        cli(
            "all points identical (degenerate cloud)",
            "normals same.xyzn -o out.ply --quiet",
        ),
        cli(
            "colour columns read as normals",
            "normals rgb.xyz -o out.ply --quiet",
        )
        .accepted("are not unit normals"),
        cli("missing file", "normals missing.xyzn -o out.ply --quiet"),
        cli(
            "wrong output extension",
            "normals bunny.xyzn -o out.stl --quiet",
        )
        .names("out.stl"),
        cli(
            "neighbours out of range",
            "normals bunny.xyzn -o out.ply --neighbours 1 --quiet",
        )
        .no_file()
        .says("--neighbours"),
        cli(
            "viewpoint not finite",
            "normals bunny.xyzn -o out.ply --viewpoint 0,inf,0 --quiet",
        )
        .no_file(),
        cli(
            "the scanners' viewpoints of a file without scans",
            "normals positions.xyz -o out.ply --viewpoint scanners --quiet",
        )
        .no_file()
        .says("E57"),
        cli(
            "bad input with an existing output and --force",
            "normals nan.xyzn -o out.ply --force --quiet",
        )
        .keeps("out.ply"),
        // read_point_cloud
        reader(CloudReader, "empty file", "empty.xyzn").says("empty"),
        reader(CloudReader, "no point (comments only)", "comments.xyzn"),
        reader(CloudReader, "NaN coordinate", "nan.xyzn").says("NaN"),
        reader(CloudReader, "infinite normal component", "inf_normal.xyzn"),
        reader(CloudReader, "not a number", "word.xyzn").says("word.xyzn:2"),
        reader(CloudReader, "rows of different lengths", "ragged.xyzn").says("ragged.xyzn:2"),
        reader(CloudReader, "colour columns read as normals", "rgb.xyz"),
        reader(CloudReader, "not UTF-8", "latin1.xyzn"),
        reader(CloudReader, "missing file", "missing.xyzn"),
        reader(CloudReader, "directory instead of file", "folder.xyzn"),
        reader(CloudReader, "wrong extension", "bunny.rcp"),
        reader(CloudReader, "truncated binary PLY", "cloud_trunc.ply").says("truncated"),
        reader(
            CloudReader,
            "header count larger than the file",
            "cloud_count.ply",
        ),
        reader(
            CloudReader,
            "normals incomplete (nx ny, no nz)",
            "cloud_nx.ply",
        ),
        reader(CloudReader, "unsupported PLY encoding", "encoding.ply"),
        reader(CloudReader, "no PLY magic", "notply.ply"),
        reader(CloudReader, "CSV without a z column", "noz.csv"),
        reader(CloudReader, "CSV: not a number", "word.csv"),
        reader(CloudReader, "CSV header only", "header_only.csv"),
        reader(CloudReader, "truncated binary PCD", "short.pcd").says("truncated"),
        reader(CloudReader, "LAZ with a crafted chunk table", "chunks.laz").says("4294967295"),
        reader(CloudReader, "LAZ cut short", "cut.laz"),
        reader(CloudReader, "E57 with a changed byte", "flipped.e57").says("checksum"),
        reader(CloudReader, "text named .e57", "text.e57").says("E57"),
        reader(CloudReader, "truncated LAS", "cut.las").says("truncated"),
        reader(CloudReader, "corrupt LZF in PCD", "lzf.pcd").says("decompress"),
        reader(CloudReader, "PCD gaps only", "gaps.pcd").says("NaN"),
        reader(CloudReader, "PCD TYPE not I, U or F", "type.pcd").says("type.pcd:5"),
        reader(CloudReader, "header line without z", "named_noz.xyz").says("named_noz.xyz:1"),
        reader(CloudReader, "decimal commas", "decimal_comma.txt").says("decimal commas"),
        reader(CloudReader, "duplicate points", "dup.xyzn").accepted("100 points"),
        // GemPy
        reader(
            GemPyReader,
            "GemPy table without a Z column",
            "gempy_noz.csv",
        ),
        reader(GemPyReader, "GemPy: not a number", "gempy_dip.csv").says("steep"),
        reader(GemPyReader, "not a GemPy table", "noz.csv"),
        // xyv
        reader(ValueReader, "wrong count on a line", "count.xyv").says("count.xyv:2"),
        reader(ValueReader, "NaN value", "nan.xyv").says("NaN"),
        reader(ValueReader, "empty file", "empty.xyv"),
        reader(
            ValueReader,
            "an oriented cloud (6 numbers a line)",
            "bunny.xyzn",
        ),
        // read_ply_mesh
        reader(MeshReader, "out-of-range face index", "tet_index.ply").says("vertex 7"),
        reader(MeshReader, "truncated binary PLY", "tet_trunc.ply").says("truncated"),
        reader(
            MeshReader,
            "header count larger than the file",
            "tet_count.ply",
        ),
        reader(MeshReader, "NaN coordinate", "tet_nan.ply"),
        reader(MeshReader, "a face with 2 corners", "tet_two.ply"),
        reader(MeshReader, "no PLY magic", "notply.ply"),
        reader(MeshReader, "unsupported PLY encoding", "encoding.ply"),
        reader(MeshReader, "missing file", "missing.ply"),
        reader(MeshReader, "no faces (a point cloud)", "cloud_xyz.ply").accepted("0 triangles"),
        reader(MeshReader, "truncated binary STL", "tet_trunc.stl").says("triangle 3"),
        reader(MeshReader, "NaN corner in ASCII STL", "tet_nan.stl").says("line 5"),
        reader(MeshReader, "too short for STL", "tiny.stl").says("10 bytes"),
        reader(MeshReader, "OBJ face index out of range", "tet_index.obj").says("line 8"),
        reader(MeshReader, "OBJ face index 0", "tet_zero.obj").says("start at 1"),
        reader(MeshReader, "OBJ that is not text", "binary.obj").says("UTF-8"),
        reader(MeshReader, "OFF face index out of range", "tet_index.off").says("line 10"),
        reader(MeshReader, "truncated OFF", "tet_short.off").says("truncated"),
        // read_any_field
        reader(FieldReader, "corrupted .zsf checksum", "crc.zsf").says("checksum"),
        reader(FieldReader, "truncated .zsf", "trunc.zsf").says("truncated"),
        reader(FieldReader, "header-only .zsf", "head.zsf").says("truncated"),
        reader(FieldReader, ".zsf of a newer version", "newer.zsf").says("version 9"),
        reader(FieldReader, "not a field file (bad magic)", "magic.zsf").says("magic"),
        reader(FieldReader, "empty file", "empty.zsf"),
        reader(FieldReader, ".zsf of another dimension", "disc.zsf").says("2-D"),
        reader(FieldReader, "missing file", "missing.xyzn"),
        reader(FieldReader, "directory instead of file", "folder.xyzn"),
    ]
}

// ---------------------------------------------------------------------------------------------
// Running a case.

/// What a case got: the exit status (`None` for a reader) and the message's first line.
struct Row {
    status: String,
    message: String,
}

/// `text` with the temporary directory cut out of every path.
fn scrub(text: &str, dir: &Path) -> String {
    let dir = dir.display().to_string();
    text.replace(&format!("{dir}/"), "").replace(&dir, ".")
}

/// The words after `-o`, `--output` and `--field`: the outputs of a command line.
fn outputs(args: &str) -> Vec<&str> {
    let words: Vec<&str> = args.split_whitespace().collect();
    words
        .windows(2)
        .filter(|w| matches!(w[0], "-o" | "--output" | "--field"))
        .map(|w| w[1])
        .collect()
}

/// Runs `case` in `dir`: its row, or what went wrong.
fn run_case(dir: &Path, case: &Case) -> Result<Row, String> {
    let (status, first, whole) = if case.target < Target::CloudReader {
        run_command(dir, case)?
    } else {
        let path = dir.join(case.args);
        let result = catch_unwind(AssertUnwindSafe(|| case.target.read(&path)))
            .map_err(|_| "the reader panicked".to_string())?;
        match (result, case.accepted) {
            (Ok(summary), true) => ("Ok".to_string(), summary.clone(), summary),
            (Ok(summary), false) => return Err(format!("expected an error, read {summary}")),
            (Err(e), false) => {
                let e = scrub(&e, dir);
                let first = e.lines().next().unwrap_or("").to_string();
                ("Err".to_string(), first, e)
            }
            (Err(e), true) => return Err(format!("expected it to be accepted, got: {e}")),
        }
    };
    if first.contains("Error {") || first.contains("unwrap()") || first.contains("panicked") {
        return Err(format!("not a message for a user: {first}"));
    }
    if let Some(file) = case.names
        && !first.contains(file)
    {
        return Err(format!("the message does not name {file}: {first}"));
    }
    for phrase in &case.expect {
        if !whole.contains(phrase) {
            return Err(format!("{phrase:?} missing in: {whole}"));
        }
    }
    Ok(Row {
        status,
        message: if case.accepted {
            format!("accepted: {first}")
        } else {
            first
        },
    })
}

/// Runs a command line in `dir`: the exit status, the line to catalogue (the `error:` line, or
/// for an accepted input the report line holding the case's phrase) and all of the message.
fn run_command(dir: &Path, case: &Case) -> Result<(String, String, String), String> {
    let outputs = outputs(case.args);
    for out in &outputs {
        let path = dir.join(out);
        if case.keeps.contains(out) {
            // An output that is also an input (sphere.zsf) is compared with what it holds.
            if !path.exists() {
                fs::write(&path, SENTINEL).unwrap();
            }
        } else if path.exists() {
            return Err(format!("{out} exists before the run"));
        }
    }
    let before: Vec<(PathBuf, Vec<u8>)> = case
        .keeps
        .iter()
        .map(|k| (dir.join(k), fs::read(dir.join(k)).unwrap()))
        .collect();
    let listing = |d: &Path| -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let files_before = listing(dir);
    let o = Command::new(env!("CARGO_BIN_EXE_zeroset"))
        .args(case.args.split_whitespace())
        .current_dir(dir)
        .env("ZEROSET_CACHE_DIR", "")
        .env("ZEROSET_MEMORY_LIMIT", MEMORY_LIMIT)
        .env_remove("RUST_BACKTRACE")
        .output()
        .map_err(|e| format!("cannot run zeroset: {e}"))?;
    let stdout = scrub(&String::from_utf8_lossy(&o.stdout), dir);
    let stderr = scrub(&String::from_utf8_lossy(&o.stderr), dir);
    if stderr.contains("panicked") || stderr.contains("RUST_BACKTRACE") {
        return Err(format!("it panicked:\n{stderr}"));
    }
    let code = o.status.code();
    for (path, bytes) in &before {
        if fs::read(path).ok().as_ref() != Some(bytes) {
            return Err(format!("{} was changed", path.display()));
        }
    }
    let result = if case.accepted {
        if code != Some(0) {
            return Err(format!("expected success, got {code:?}:\n{stderr}"));
        }
        let phrase = case.expect[0];
        let line = stdout
            .lines()
            .find(|l| l.contains(phrase))
            .ok_or_else(|| format!("no line holds {phrase:?} in:\n{stdout}"))?;
        let line = line.split_whitespace().collect::<Vec<_>>().join(" ");
        ("0".to_string(), line, stdout.clone())
    } else {
        if !matches!(code, Some(1 | 2)) {
            return Err(format!(
                "expected exit status 1 or 2, got {code:?}:\n{stdout}{stderr}"
            ));
        }
        let line = stderr
            .lines()
            .find(|l| l.starts_with("error"))
            .ok_or_else(|| format!("no error line in:\n{stderr}"))?
            .to_string();
        (code.unwrap().to_string(), line, stderr)
    };
    // Nothing new is left behind: no output, no temporary file.
    let files_after = listing(dir);
    if files_after != files_before && !case.accepted {
        return Err(format!(
            "files changed: before {files_before:?}, after {files_after:?}"
        ));
    }
    for out in &outputs {
        if !case.keeps.contains(out) && dir.join(out).exists() && !case.accepted {
            return Err(format!("{out} was written"));
        }
    }
    // Leave the directory as it was for the next case.
    for k in &case.keeps {
        if fs::read(dir.join(k)).unwrap() == SENTINEL {
            fs::remove_file(dir.join(k)).unwrap();
        }
    }
    for name in listing(dir) {
        if !files_before.contains(&name) {
            let p = dir.join(&name);
            if p.is_dir() {
                fs::remove_dir_all(p).unwrap();
            } else {
                fs::remove_file(p).unwrap();
            }
        }
    }
    Ok(result)
}

// ---------------------------------------------------------------------------------------------
// The catalogue.

/// `text` safe in a Markdown table cell.
fn cell(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '|' => out.push_str("\\|"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '*' => out.push_str("\\*"),
            _ => out.push(c),
        }
    }
    out
}

fn render(inputs: &[Input], cases: &[Case], rows: &[Row]) -> String {
    let mut doc = String::new();
    doc.push_str(
        "# Bad-input catalogue\n\
         \n\
         <!-- Generated by crates/cli/tests/bad_input.rs: do not edit. To update it run\n     \
         ZEROSET_BLESS=1 cargo test -p zeroset-cli --test bad_input -->\n\
         \n\
         What zeroset does with input it cannot use: each named class of bad input (an empty \
         file, a NaN coordinate, a truncated binary PLY, a corrupted field file, a grid \
         resolution of 0, an output directory that does not exist, ...) given to each `zeroset` \
         command and each library reader, with the exit status and the first line of the error \
         it gets. It is generated by the test `crates/cli/tests/bad_input.rs`, which runs every \
         case and checks that none panics, that the error names the file involved, and that an \
         existing output is left untouched and no output or temporary file is left behind on \
         failure; the test fails when this file is stale. Random corruptions of every reader \
         are the fuzz harness's job ([fuzzing.md](fuzzing.md)); this catalogue covers named \
         classes, one case each.\n\
         \n\
         Exit status 1 is an error the command reports, 2 an argument the command line parser \
         rejects (the usage follows the first line). A reader gives `Err` and the error's \
         text. *Accepted* rows are suspicious inputs that are not errors: the line of the \
         report that says what was noticed is shown instead.\n\
         \n\
         ## The inputs\n\
         \n\
         The cases run in a directory holding these files, on relative paths.\n\
         \n\
         | file | what it holds |\n\
         |---|---|\n",
    );
    for input in inputs {
        let _ = writeln!(doc, "| `{}` | {} |", input.name, input.what);
    }
    for target in Target::ALL {
        let (is_command, given) = if target < Target::CloudReader {
            (true, "command line")
        } else {
            (false, "file")
        };
        let _ = write!(
            doc,
            "\n## {}\n\n| input class | {given} | {} | the error |\n|---|---|---|---|\n",
            target.title(),
            if is_command { "exit" } else { "result" }
        );
        for (case, row) in cases.iter().zip(rows).filter(|(c, _)| c.target == target) {
            let given = if is_command {
                format!("`zeroset {}`", case.args)
            } else {
                format!("`{}`", case.args)
            };
            let _ = writeln!(
                doc,
                "| {} | {given} | {} | {} |",
                cell(case.class),
                row.status,
                cell(&row.message)
            );
        }
    }
    doc
}

#[test]
fn bad_input_catalogue() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = make_inputs(dir.path());
    let cases = cases();
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    for case in &cases {
        match run_case(dir.path(), case) {
            Ok(row) => rows.push(row),
            Err(e) => {
                failures.push(format!(
                    "{:?} {:?} `{}`: {e}",
                    case.target, case.class, case.args
                ));
                rows.push(Row {
                    status: "?".into(),
                    message: e.lines().next().unwrap_or("").to_string(),
                });
            }
        }
    }
    let doc = render(&inputs, &cases, &rows);
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    if std::env::var_os("ZEROSET_BLESS").is_some_and(|v| v == "1") {
        fs::write(DOC, &doc).unwrap();
        return;
    }
    let committed = fs::read_to_string(DOC).unwrap_or_default();
    if committed != doc {
        let line = committed
            .lines()
            .zip(doc.lines())
            .position(|(a, b)| a != b)
            .map_or_else(
                || {
                    if committed.is_empty() {
                        "it is missing or empty".to_string()
                    } else {
                        "one is a prefix of the other".to_string()
                    }
                },
                |i| {
                    format!(
                        "first difference on line {}:\n  committed: {}\n  now:       {}",
                        i + 1,
                        committed.lines().nth(i).unwrap_or(""),
                        doc.lines().nth(i).unwrap_or("")
                    )
                },
            );
        panic!(
            "docs/bad-input.md is stale: rerun with ZEROSET_BLESS=1 cargo test -p zeroset-cli \
             --test bad_input\n{line}"
        );
    }
}
