//! OBJ and STL: round trips, files as other software writes them, read errors, and the
//! extension dispatch of `read_mesh` / `write_mesh`.

mod common;

use common::{bunny_path, cube_at, cube_triangles};
use zeroset_mesh::io::{
    MeshFormat, StlFormat, obj_from_bytes, obj_to_string, stl_from_bytes, stl_to_bytes,
};
use zeroset_mesh::{
    MeshError, TriMesh, boundary_loops, check, read_mesh, read_obj_mesh, read_ply_mesh,
    read_stl_mesh, write_mesh, write_obj, write_stl,
};

/// The tetrahedron of these tests, at coordinates that are not all `f32` values.
fn tetrahedron() -> TriMesh {
    common::tetrahedron_at([0.1, -0.2, 0.3])
}

/// Each triangle as its corners' coordinates (rounded to `f32`, as STL stores them): the
/// mesh's geometry and winding whatever its vertex numbering.
fn corner_triangles(mesh: &TriMesh) -> Vec<[[f32; 3]; 3]> {
    mesh.triangles()
        .iter()
        .map(|t| t.map(|v| mesh.vertices()[v as usize].map(|x| x as f32)))
        .collect()
}

fn expect_stl_err(bytes: &[u8]) -> String {
    match stl_from_bytes(bytes, "bad.stl") {
        Ok(m) => panic!("expected an error, read {} triangles", m.num_triangles()),
        Err(e) => {
            assert!(
                matches!(e, MeshError::Malformed { format: "STL", .. }),
                "{e:?}"
            );
            e.to_string()
        }
    }
}

fn expect_obj_err(text: &str) -> String {
    match obj_from_bytes(text.as_bytes(), "bad.obj") {
        Ok(m) => panic!("expected an error, read {} triangles", m.num_triangles()),
        Err(e) => {
            assert!(
                matches!(e, MeshError::Malformed { format: "OBJ", .. }),
                "{e:?}"
            );
            e.to_string()
        }
    }
}

#[test]
fn stl_round_trips_in_both_encodings_and_welds_the_corners() {
    for mesh in [cube_at([0.0; 3]), tetrahedron()] {
        let want = check(&mesh);
        for format in [StlFormat::Binary, StlFormat::Ascii] {
            let bytes = stl_to_bytes(&mesh, format).unwrap();
            let back = stl_from_bytes(&bytes, "m.stl").unwrap();
            // Corners welded back into the same number of shared vertices, same triangles and
            // winding, no normals (STL has facet normals only).
            assert_eq!(back.num_vertices(), mesh.num_vertices(), "{format:?}");
            assert_eq!(corner_triangles(&back), corner_triangles(&mesh));
            assert!(back.normals().is_empty());
            let got = check(&back);
            assert!(got.is_oriented_closed(), "{format:?}: {got}");
            assert_eq!(got.euler_characteristic, want.euler_characteristic);
            assert!((got.signed_volume - want.signed_volume).abs() < 1e-6);
            // Written again, the same bytes: the second trip is exact.
            assert_eq!(stl_to_bytes(&back, format).unwrap(), bytes);
        }
    }
}

#[test]
fn binary_stl_layout_and_facet_normals() {
    let cube = cube_at([0.0; 3]);
    let bytes = stl_to_bytes(&cube, StlFormat::Binary).unwrap();
    assert_eq!(bytes.len(), 84 + 12 * 50);
    assert!(
        !bytes.starts_with(b"solid"),
        "a binary header must not begin with 'solid'"
    );
    assert_eq!(u32::from_le_bytes(bytes[80..84].try_into().unwrap()), 12);
    let f = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    for t in 0..12 {
        let at = 84 + 50 * t;
        let normal = [f(at), f(at + 4), f(at + 8)];
        let corners: Vec<[f32; 3]> = (0..3)
            .map(|c| [0, 1, 2].map(|k| f(at + 12 + 12 * c + 4 * k)))
            .collect();
        // The facet normal is the outward unit axis of the face the triangle lies on.
        let axis = normal.iter().position(|v| v.abs() == 1.0).unwrap();
        let side = corners[0][axis];
        assert!(corners.iter().all(|c| c[axis] == side), "triangle {t}");
        assert_eq!(normal[axis], if side == 1.0 { 1.0 } else { -1.0 });
        assert_eq!(normal.iter().filter(|v| **v == 0.0).count(), 2);
        assert_eq!(&bytes[at + 48..at + 50], &[0, 0]);
    }
    // A vertex beyond f32 is refused, not written as infinity.
    let far = TriMesh::new(
        vec![[0.0; 3], [1e39, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    for format in [StlFormat::Binary, StlFormat::Ascii] {
        let err = stl_to_bytes(&far, format).unwrap_err();
        assert!(err.to_string().contains("32-bit float range"), "{err}");
    }
    // A triangle without area gets a zero normal, not NaN.
    let flat = TriMesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let bytes = stl_to_bytes(&flat, StlFormat::Binary).unwrap();
    assert!(bytes[84..96].iter().all(|&b| b == 0));
}

#[test]
fn stl_as_other_software_writes_it() {
    // A binary file whose header begins with "solid" (as many exporters write it) is binary:
    // its length is what its count announces.
    let mut bytes = stl_to_bytes(&cube_at([0.0; 3]), StlFormat::Binary).unwrap();
    bytes[..11].copy_from_slice(b"solid cube ");
    let m = stl_from_bytes(&bytes, "cube.stl").unwrap();
    assert_eq!((m.num_vertices(), m.num_triangles()), (8, 12));
    // Bytes after the last triangle (padding) are ignored.
    bytes.extend_from_slice(&[0; 7]);
    assert_eq!(stl_from_bytes(&bytes, "cube.stl").unwrap(), m);

    // ASCII with upper-case keywords, CRLF, tabs, exponents, -0 beside 0 (one vertex), two
    // solids, a quad facet (fan-triangulated), and no final endsolid.
    let text = "SOLID part one\r\n\
        facet normal 0 0 -1\r\n outer loop\r\n\
        \tvertex 0 0 0\r\n vertex 0 1e0 0\r\n vertex 1.0E+00 1 -0\r\n vertex 1 -0.0 0\r\n\
        endloop\r\n endfacet\r\nendsolid part one\r\n\
        solid two\nfacet normal 0 0 0\nouter loop\nvertex 0 0 -0\nvertex 1 0 0\n\
        vertex 0.5 0.5 2.5e-1\nendloop\nendfacet\n";
    let m = stl_from_bytes(text.as_bytes(), "parts.stl").unwrap();
    assert_eq!(m.num_triangles(), 3);
    assert_eq!(m.num_vertices(), 5, "{:?}", m.vertices());
    assert_eq!(m.triangles(), &[[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    assert_eq!(m.vertices()[4], [0.5, 0.5, 0.25]);
    // An empty solid is an empty mesh.
    let m = stl_from_bytes(b"solid empty\nendsolid empty\n", "e.stl").unwrap();
    assert_eq!((m.num_vertices(), m.num_triangles()), (0, 0));

    // One facet written every other way: old-Mac line ends (CR only), all on one line, a
    // UTF-8 byte-order mark, a solid named in UTF-8 or Latin-1, NUL padding after the end.
    let facet = "facet normal 0 0 1 outer loop vertex 0 0 0 vertex 1 0 0 vertex 0 1 0 \
                 endloop endfacet";
    let variants: Vec<Vec<u8>> = vec![
        format!("solid cr\r{}\rendsolid cr\r", facet.replace(' ', "\r")).into_bytes(),
        format!("solid one line {facet} endsolid one line").into_bytes(),
        [
            b"\xEF\xBB\xBF".as_slice(),
            format!("solid bom\n{facet}\nendsolid\n").as_bytes(),
        ]
        .concat(),
        format!("solid Körper\n{facet}\nendsolid Körper\n").into_bytes(),
        [
            b"solid K\xf6rper\n".as_slice(),
            format!("{facet}\nendsolid\n").as_bytes(),
        ]
        .concat(),
        [
            format!("solid pad\n{facet}\nendsolid pad\n").as_bytes(),
            &[0u8; 40],
        ]
        .concat(),
    ];
    for bytes in &variants {
        let m = stl_from_bytes(bytes, "v.stl")
            .unwrap_or_else(|e| panic!("{:?}: {e}", String::from_utf8_lossy(bytes)));
        assert_eq!(
            (m.num_vertices(), m.triangles()),
            (3, &[[0, 1, 2]][..]),
            "{:?}",
            String::from_utf8_lossy(bytes)
        );
    }

    // A binary file whose count was left at 0 by a streaming writer: the length says 12.
    let mut zero = stl_to_bytes(&cube_at([0.0; 3]), StlFormat::Binary).unwrap();
    zero[80..84].copy_from_slice(&0u32.to_le_bytes());
    assert_eq!(stl_from_bytes(&zero, "z.stl").unwrap().num_triangles(), 12);
}

#[test]
fn stl_errors_name_the_place() {
    let bytes = stl_to_bytes(&cube_at([0.0; 3]), StlFormat::Binary).unwrap();
    // Cut in triangle 7.
    let msg = expect_stl_err(&bytes[..84 + 7 * 50 + 20]);
    assert!(
        msg.contains("bad.stl")
            && msg.contains("triangle 7 (byte 434)")
            && msg.contains("truncated"),
        "{msg}"
    );
    // A count of 4·10⁹ triangles in a 200-byte file: truncated at once, nothing allocated
    // for the count.
    let mut huge = bytes[..200].to_vec();
    huge[80..84].copy_from_slice(&4_000_000_000u32.to_le_bytes());
    let msg = expect_stl_err(&huge);
    assert!(
        msg.contains("triangle 2 ") && msg.contains("4000000000"),
        "{msg}"
    );
    // A NaN corner.
    let mut nan = bytes.clone();
    let at = 84 + 3 * 50 + 12 + 12 + 8;
    nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let msg = expect_stl_err(&nan);
    assert!(
        msg.contains("triangle 3") && msg.contains("corner 1 coordinate z"),
        "{msg}"
    );
    // Too short for either encoding.
    let msg = expect_stl_err(b"not a mesh");
    assert!(
        msg.contains("10 bytes") && msg.contains("too short"),
        "{msg}"
    );

    let facet = |body: &str| format!("solid s\nfacet normal 0 0 1\nouter loop\n{body}");
    let cases: [(String, &str); 9] = [
        (
            facet("vertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n"),
            "line 6: the facet has 2 corner(s)",
        ),
        (
            facet("vertex 0 0 0\nvertex 1 nan 0\nvertex 0 1 0\nendloop\nendfacet\n"),
            "line 5: vertex coordinate y is not finite",
        ),
        (
            facet("vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 1e39\nendloop\nendfacet\n"),
            "line 6: vertex coordinate z 1e39 is beyond the 32-bit float range of STL",
        ),
        (
            facet("vertex 0 0 0\nvertex 1 0,5 0\n"),
            "line 5: vertex coordinate y '0,5' is not a number",
        ),
        (
            facet("vertex 0 0 0\nvertex 1 0 0\n"),
            "line 2: truncated: the file ends inside the facet",
        ),
        (
            "solid s\nvertex 0 0 0\n".into(),
            "line 2: 'vertex' is a corner, which belongs inside an outer loop (the file is between facets)",
        ),
        (
            "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendfacet\n"
                .into(),
            "line 7: 'endfacet' ends a facet whose loop is not closed",
        ),
        (
            "solid s\nfacets 3\n".into(),
            "line 2: 'facets' is not an ASCII STL keyword",
        ),
        (
            "solid a\nendsolid a\nsolid b\nsolid c\n".into(),
            "line 4: 'solid' begins a solid, but one is open",
        ),
    ];
    for (text, want) in &cases {
        let msg = expect_stl_err(text.as_bytes());
        assert!(msg.contains(want), "{text:?}:\n  got  {msg}\n  want {want}");
    }
}

#[test]
fn obj_round_trips_exactly() {
    for mesh in [cube_at([0.5, -2.0, 1e-3]), tetrahedron()] {
        let text = obj_to_string(&mesh);
        // Full f64 text: the same mesh back, normals included (one per vertex).
        assert_eq!(obj_from_bytes(text.as_bytes(), "m.obj").unwrap(), mesh);
    }
}

#[test]
fn obj_as_other_software_writes_it() {
    // Colours after a vertex, texture coordinates, groups, materials, smoothing, comments, a
    // continued line, corners v/vt/vn with negative (relative) indices, a quad.
    let text = "# exported\nmtllib part.mtl\no part\n\
        v 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 1 1 0\nv 0 1 0 # the fourth\n\
        vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n\
        g top\nusemtl steel\ns 1\n\
        f -4/1/1 -3/2/1 \\\n  -2/3/1 -1/1/1\nl 1 2\n";
    let m = obj_from_bytes(text.as_bytes(), "part.obj").unwrap();
    assert_eq!(m.num_vertices(), 4);
    assert_eq!(m.triangles(), &[[0, 1, 2], [0, 2, 3]]);
    // Every vertex named the same normal: it becomes the vertex's.
    assert_eq!(m.normals(), &[[0.0, 0.0, 1.0]; 4]);

    // A vertex with two different normals (a crease), or one no face uses: no per-vertex
    // normals, the geometry kept.
    let crease = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nvn 1 0 0\n\
        f 1//1 2//1 3//1\nf 1//2 2//2 4//2\n";
    let m = obj_from_bytes(crease.as_bytes(), "c.obj").unwrap();
    assert_eq!((m.num_triangles(), m.normals().len()), (2, 0));
    let unused = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nvn 0 0 1\nf 1//1 2//1 3//1\n";
    let m = obj_from_bytes(unused.as_bytes(), "u.obj").unwrap();
    assert_eq!((m.num_vertices(), m.normals().len()), (4, 0));

    // One `vn` line per corner, equal values: per-vertex normals all the same. A byte-order
    // mark, texture indices without `vt` lines (a mesh keeps no texture), and a continuation
    // on the last line.
    let repeated = "\u{feff}v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\n\
                    f 1/1/1 2/2/2 \\\n3/3/3";
    let m = obj_from_bytes(repeated.as_bytes(), "r.obj").unwrap();
    assert_eq!(m.triangles(), &[[0, 1, 2]]);
    assert_eq!(m.normals(), &[[0.0, 0.0, 1.0]; 3]);

    // Vertices and as many normals, no face: an oriented point cloud.
    let cloud = "v 0 0 0\nvn 1 0 0\nv 1 0 0\nvn 0 1 0\n";
    let m = obj_from_bytes(cloud.as_bytes(), "c.obj").unwrap();
    assert_eq!(m.num_triangles(), 0);
    assert_eq!(m.normals(), &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
}

#[test]
fn obj_errors_name_the_line() {
    let cases = [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            "line 4: corner 0 '0': vertex index 0: OBJ indices start at 1",
        ),
        (
            "v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n",
            "line 3: corner 2 '3': vertex index 3 is out of range: 2 vertices read so far",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n",
            "line 4: corner 2 '-4': vertex index -4 is out of range",
        ),
        (
            "v 0 0 0\nv 1 0 0\nf 1 2\n",
            "line 3: the face has 2 corner(s)",
        ),
        ("v 0 0\n", "line 1: the vertex has no z coordinate"),
        (
            "# c\nv 0 zero 0\n",
            "line 2: vertex coordinate y 'zero' is not a number",
        ),
        (
            "v 0 0 inf\n",
            "line 1: vertex coordinate z is not finite: inf",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//2 2//1 3//1\n",
            "line 5: corner 0 '1//2': normal index 2 is out of range",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/a 2 3\n",
            "line 4: corner 0 '1/a': ",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n",
            "at most three parts",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n",
            "index 99999999999999999999 is too large",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/0 2 3\n",
            "texture coordinate index 0",
        ),
    ];
    for (text, want) in cases {
        let msg = expect_obj_err(text);
        assert!(msg.contains(want), "{text:?}:\n  got  {msg}\n  want {want}");
    }
    let msg = expect_obj_err("v 0 0 0\nv \u{0}\u{1}\n");
    assert!(msg.contains("line 2: vertex coordinate x"), "{msg}");
    let binary = [b'v', b' ', 0xff, 0xfe, b'\n'];
    let err = obj_from_bytes(&binary, "bin.obj").unwrap_err().to_string();
    assert!(err.contains("line 1") && err.contains("not UTF-8"), "{err}");
}

#[test]
fn read_and_write_by_extension() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = tetrahedron();
    for (name, ascii) in [
        ("t.ply", false),
        ("t.PLY", true),
        ("t.obj", false),
        ("t.stl", false),
        ("t.Stl", true),
        ("t.off", false),
        ("t.OFF", true),
    ] {
        let path = dir.path().join(name);
        write_mesh(&path, &mesh, ascii).unwrap();
        let back = read_mesh(&path).unwrap();
        let format = MeshFormat::from_path(&path).unwrap();
        assert_eq!(corner_triangles(&back), corner_triangles(&mesh), "{name}");
        if format == MeshFormat::Stl {
            let text = std::fs::read(&path).unwrap().starts_with(b"solid");
            assert_eq!(text, ascii, "{name}");
            assert_eq!(back, read_stl_mesh(&path).unwrap());
        } else {
            assert_eq!(back.normals().len(), 4, "{name}");
        }
    }
    for bad in ["t.3mf", "t", "t.ply.gz"] {
        let path = dir.path().join(bad);
        let err = write_mesh(&path, &mesh, false).unwrap_err();
        assert!(
            matches!(err, MeshError::UnsupportedFormat { .. }) && err.to_string().contains(".stl"),
            "{err}"
        );
        assert!(!path.exists());
        assert!(read_mesh(&path).is_err());
    }
    // A missing file is named.
    let missing = dir.path().join("missing.stl");
    let err = read_stl_mesh(&missing).unwrap_err().to_string();
    assert!(err.contains("missing.stl"), "{err}");
    let err = read_obj_mesh(dir.path().join("missing.obj"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.obj"), "{err}");
}

#[test]
fn the_bunny_through_stl_and_obj_keeps_its_topology() {
    let path = bunny_path();
    assert!(path.is_file(), "test data {} not found", path.display());
    let ply = read_ply_mesh(&path).unwrap();
    let want = check(&ply);
    let dir = tempfile::tempdir().unwrap();
    for name in ["bunny.stl", "bunny_ascii.stl", "bunny.obj"] {
        let out = dir.path().join(name);
        write_mesh(&out, &ply, name.contains("ascii")).unwrap();
        let back = read_mesh(&out).unwrap();
        let got = check(&back);
        // STL keeps only the vertices triangles use (34,834 of 35,947); every other count —
        // edges, the 5 holes' 223 boundary edges, Euler characteristic −3 — is the same.
        let vertices = if name.ends_with(".stl") {
            want.used_vertices
        } else {
            want.vertices
        };
        assert_eq!(got.vertices, vertices, "{name}");
        assert_eq!(
            (
                got.edges,
                got.boundary_edges,
                got.euler_characteristic,
                got.components
            ),
            (
                want.edges,
                want.boundary_edges,
                want.euler_characteristic,
                want.components
            ),
            "{name}"
        );
        assert_eq!(boundary_loops(&back), 5);
        assert!(
            (got.signed_volume - want.signed_volume).abs() < 1e-12,
            "{name}"
        );
        assert_eq!(corner_triangles(&back), corner_triangles(&ply));
    }
    // Read back and written again, the STL is byte-identical.
    let stl = dir.path().join("bunny.stl");
    let bytes = std::fs::read(&stl).unwrap();
    let again = dir.path().join("again.stl");
    write_stl(&again, &read_stl_mesh(&stl).unwrap(), StlFormat::Binary).unwrap();
    assert_eq!(std::fs::read(&again).unwrap(), bytes);
    write_obj(dir.path().join("x.obj"), &ply).unwrap();
}

#[test]
fn a_surface_beside_a_sample_survives_f32_files() {
    // A sphere of radius 0.5 + 10⁻¹³ about (0.25, 0.25, 0.25) on a grid with a sample at
    // (0.75, 0.25, 0.25): that sample is inside by 10⁻¹³ and five of its six neighbours
    // outside, so five crossings lie within 10⁻¹² of an edge length of it — distinct in f64,
    // one point once written as f32. They
    // are kept apart, so the STL reads back (its corners welded by position) as the same
    // closed sphere, and the PLY has no zero-area triangle.
    use zeroset_field_core::field::FnField;
    use zeroset_field_core::{Aabb, Grid};
    use zeroset_mesh::io::{PlyFormat, ply_from_bytes, ply_to_bytes};
    use zeroset_mesh::{McOptions, mesh_field};
    let r = 0.5 + 1e-13;
    let sphere = FnField::new(
        move |p: &[f64; 3]| {
            let d = p.map(|x| x - 0.25);
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - r
        },
        None,
    );
    let grid = Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [33; 3]).unwrap();
    let mesh = mesh_field(&sphere, &grid, 0.0, &McOptions::default()).unwrap();
    let want = check(&mesh);
    assert!(
        want.is_oriented_closed() && want.euler_characteristic == 2,
        "{want}"
    );
    let near = mesh
        .vertices()
        .iter()
        .filter(|p| {
            (p[0] - 0.75).abs() < 1e-6 && (p[1] - 0.25).abs() < 1e-6 && (p[2] - 0.25).abs() < 1e-6
        })
        .count();
    assert_eq!(near, 5, "the crossings around the sample");
    for format in [StlFormat::Binary, StlFormat::Ascii] {
        let back = stl_from_bytes(&stl_to_bytes(&mesh, format).unwrap(), "s.stl").unwrap();
        let got = check(&back);
        assert_eq!(back.num_vertices(), mesh.num_vertices(), "{format:?}");
        assert!(
            got.is_oriented_closed() && got.euler_characteristic == 2,
            "{got}"
        );
    }
    let ply = ply_from_bytes(
        &ply_to_bytes(&mesh, PlyFormat::BinaryLittleEndian).unwrap(),
        "s",
    )
    .unwrap();
    assert_eq!(check(&ply).degenerate_triangles, 0);
}

#[test]
fn far_from_the_origin_the_f64_mesh_is_left_exact() {
    // A sphere of radius 10 about (500000, 500000, 500000) on voxels of 0.625: an f32 step
    // there (0.03) is 5% of an edge, too coarse to separate anything, so no vertex is moved:
    // the vertices lie on the sphere as closely as linear interpolation puts them.
    use zeroset_field_core::field::{FnField, ScalarField};
    use zeroset_field_core::{Aabb, Grid};
    use zeroset_mesh::{McOptions, mesh_field};
    let c = 500_000.0;
    let sphere = FnField::new(
        move |p: &[f64; 3]| {
            let d = p.map(|x| x - c);
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - 10.0
        },
        None,
    );
    let bounds = Aabb::new([c - 12.5; 3], [c + 12.5; 3]).unwrap();
    let grid = Grid::vertex_centered(bounds, [41; 3]).unwrap();
    let mesh = mesh_field(&sphere, &grid, 0.0, &McOptions::default()).unwrap();
    let worst = mesh
        .vertices()
        .iter()
        .map(|p| sphere.value(p).abs() / 0.625)
        .fold(0.0, f64::max);
    assert!(worst < 0.02, "{worst}");
    assert!(check(&mesh).is_oriented_closed());
}

/// Whether every normal of `p` points away from the centre of its cube (unit cubes with
/// their lowest corners at x = each of `corners`).
fn away_from_cube_centres(p: &zeroset_mesh::points::MeshPoints, corners: &[f64]) -> bool {
    use zeroset_field_core::geometry::{dot, sub};
    let n = p.normals.as_ref().unwrap();
    p.positions.iter().zip(n).all(|(x, n)| {
        let o = corners
            .iter()
            .copied()
            .min_by(|a, b| (x[0] - a - 0.5).abs().total_cmp(&(x[0] - b - 0.5).abs()))
            .unwrap();
        dot(&sub(x, &[o + 0.5, 0.5, 0.5]), n) > 0.0
    })
}

#[test]
fn mesh_points_turn_closed_parts_wound_inward_each_on_its_own() {
    use zeroset_mesh::points::{NormalSource, mesh_points};
    let (mut v, mut t, _) = cube_at([0.0; 3]).into_parts();
    v.extend(cube_at([3.0, 0.0, 0.0]).vertices());
    t.extend(cube_triangles(8).iter().map(|&[a, b, c]| [a, c, b]));
    let p = mesh_points(TriMesh::new(v, t).unwrap());
    let want = NormalSource::Winding {
        turned: 1,
        closed_parts: 2,
    };
    assert_eq!(p.source, want);
    assert!(away_from_cube_centres(&p, &[0.0, 3.0]));
}

#[test]
fn mesh_points_take_an_open_mesh_as_wound_and_give_none_for_bad_windings() {
    use zeroset_mesh::points::{NormalSource, mesh_points};
    // A unit square at z = 0.3 wound counter-clockwise seen from +z: normals +z; wound the
    // other way, −z (a sheet's signed volume, about 0, says nothing of its sides).
    let v = vec![
        [0.0, 0.0, 0.3],
        [1.0, 0.0, 0.3],
        [1.0, 1.0, 0.3],
        [0.0, 1.0, 0.3],
    ];
    for (tris, z) in [
        ([[0, 1, 2], [0, 2, 3]], 1.0),
        ([[0, 2, 1], [0, 3, 2]], -1.0),
    ] {
        let p = mesh_points(TriMesh::new(v.clone(), tris.to_vec()).unwrap());
        assert_eq!(p.source, NormalSource::WindingOpen);
        let n = p.normals.unwrap();
        assert_eq!(n.len(), 4 + p.sampled);
        assert!(n.iter().all(|n| *n == [0.0, 0.0, z]));
    }
    // Two squares side by side, unwelded (the seam's vertices repeated), the second wound the
    // other way: each part is consistent, and the seam says they disagree — the second (the
    // tie goes to the first) is turned over, its sampled points with it. Moved apart, without
    // a seam, each keeps its winding.
    for (gap, turned) in [(0.0, true), (0.5, false)] {
        let mut two = v.clone();
        two.extend(v.iter().map(|p| [p[0] + 1.0 + gap, p[1], p[2]]));
        let mesh = TriMesh::new(two, vec![[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]]).unwrap();
        let p = mesh_points(mesh);
        let n = p.normals.expect("normals");
        if turned {
            assert_eq!(
                p.source,
                NormalSource::WindingOpenParts {
                    turned: 1,
                    inward: 0,
                    parts: 2
                }
            );
            assert!(n.iter().all(|n| *n == [0.0, 0.0, 1.0]), "{n:?}");
        } else {
            assert_eq!(p.source, NormalSource::WindingOpen);
            let right = |x: &[f64; 3]| x[0] > 1.2;
            assert!(
                p.positions
                    .iter()
                    .zip(&n)
                    .all(|(x, n)| n[2] == if right(x) { -1.0 } else { 1.0 })
            );
        }
    }
    // Cubes whose every triangle is a part of its own (a soup), wound outward: one alone, two
    // sharing an edge, two stacked (their faces coincide) — edges of four triangles are no
    // seams of a surface, and nothing is turned; one triangle wound inward is turned back.
    let soup = |offsets: &[[f64; 3]], inward: Option<usize>| {
        let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
        for o in offsets {
            let cube = cube_at(*o);
            for t in 0..cube.num_triangles() {
                let base = vertices.len() as u32;
                vertices.extend(cube.corners(t));
                triangles.push(if inward == Some(triangles.len()) {
                    [base, base + 2, base + 1]
                } else {
                    [base, base + 1, base + 2]
                });
            }
        }
        mesh_points(TriMesh::new(vertices, triangles).unwrap()).source
    };
    assert_eq!(soup(&[[0.0; 3]], None), NormalSource::WindingOpen);
    assert_eq!(
        soup(&[[0.0; 3], [1.0, 1.0, 0.0]], None),
        NormalSource::WindingOpen
    );
    assert_eq!(
        soup(&[[0.0; 3], [0.0, 0.0, 1.0]], None),
        NormalSource::WindingOpen
    );
    assert_eq!(
        soup(&[[0.0; 3]], Some(5)),
        NormalSource::WindingOpenParts {
            turned: 1,
            inward: 0,
            parts: 12
        }
    );
    // A tetrahedron as four unwelded faces (each its own part, every edge a seam, the faces
    // 70.5° apart: a crease no normal-propagation signs reliably): wound outward, none is
    // turned; one face wound inward is turned back.
    let corners = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    for inward in [None, Some(2)] {
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for (f, face) in faces.iter().enumerate() {
            let base = vertices.len() as u32;
            vertices.extend(face.iter().map(|&c| corners[c]));
            triangles.push(if inward == Some(f) {
                [base, base + 2, base + 1]
            } else {
                [base, base + 1, base + 2]
            });
        }
        let p = mesh_points(TriMesh::new(vertices, triangles).unwrap());
        let want = match inward {
            None => NormalSource::WindingOpen,
            Some(_) => NormalSource::WindingOpenParts {
                turned: 1,
                inward: 0,
                parts: 4,
            },
        };
        assert_eq!(p.source, want);
        let centroid = [0.25; 3];
        let n = p.normals.expect("normals");
        assert!(
            p.positions
                .iter()
                .zip(&n)
                .all(|(x, n)| { (0..3).map(|a| (x[a] - centroid[a]) * n[a]).sum::<f64>() > 0.0 })
        );
    }
    // A closed tetrahedron wound inward beside an open square (the mesh is open, so no
    // closed-mesh rule applied; CGAL's `tetra_intersected_by_triangle.off` is such a pair):
    // the closed part meets nothing along seams and faces out by its own volume.
    let mut vertices = corners.to_vec();
    vertices.extend(v.iter().map(|p| [p[0] + 3.0, p[1], p[2]]));
    let mut triangles: Vec<[u32; 3]> = faces
        .iter()
        .map(|&[a, b, c]| [a as u32, c as u32, b as u32])
        .collect();
    triangles.extend([[4, 5, 6], [4, 6, 7]]);
    let p = mesh_points(TriMesh::new(vertices, triangles).unwrap());
    assert_eq!(
        p.source,
        NormalSource::WindingOpenParts {
            turned: 0,
            inward: 1,
            parts: 2
        }
    );
    assert!(
        p.source
            .to_string()
            .contains("but 1 closed part(s) wound inward turned over)"),
        "{}",
        p.source
    );
    let n = p.normals.expect("normals");
    for (x, n) in p.positions.iter().zip(&n) {
        if x[0] < 2.0 {
            let out: f64 = (0..3).map(|a| (x[a] - 0.25) * n[a]).sum();
            assert!(out > 0.0, "{x:?} {n:?}");
        } else {
            assert_eq!(n[2], 1.0);
        }
    }
    // The second triangle wound the other way: inconsistent, no normals.
    let p = mesh_points(TriMesh::new(v.clone(), vec![[0, 1, 2], [0, 3, 2]]).unwrap());
    assert!(p.normals.is_none());
    assert!(
        matches!(p.source, NormalSource::Inconsistent { .. }),
        "{}",
        p.source
    );
    // A vertex only on a triangle without area.
    let mut w = v;
    w.push([2.0, 0.0, 0.3]);
    let p = mesh_points(TriMesh::new(w, vec![[0, 1, 2], [1, 4, 1]]).unwrap());
    assert!(p.normals.is_none() && matches!(p.source, NormalSource::Flat { vertices: 1 }));
}

#[test]
fn mesh_points_make_the_files_normals_unit_and_a_zero_one_defers_to_the_winding() {
    use zeroset_field_core::geometry::{norm, sub};
    use zeroset_mesh::points::{NormalSource, mesh_points};
    let cube = cube_at([0.0; 3]);
    let scaled: Vec<[f64; 3]> = cube.vertices().iter().map(|p| sub(p, &[0.5; 3])).collect();
    let p = mesh_points(cube.clone().with_normals(scaled.clone()).unwrap());
    assert_eq!(p.source, NormalSource::File);
    assert!(
        p.normals
            .unwrap()
            .iter()
            .all(|n| (norm(n) - 1.0).abs() < 1e-15)
    );
    let mut zero = scaled;
    zero[3] = [0.0; 3];
    let p = mesh_points(cube.clone().with_normals(zero).unwrap());
    assert!(matches!(p.source, NormalSource::Winding { turned: 0, .. }));
    assert!(away_from_cube_centres(&p, &[0.0]));
    // Vertices only: all of them, no normals.
    let p = mesh_points(TriMesh::new(cube.vertices().to_vec(), vec![]).unwrap());
    assert_eq!(
        (p.positions.len(), p.source),
        (8, NormalSource::NoTriangles)
    );
}

#[test]
fn mesh_points_sample_a_coarse_mesh_inside_its_triangles() {
    use zeroset_field_core::geometry::dot;
    use zeroset_mesh::points::{MIN_MESH_POINTS, mesh_points};
    // A cube's 8 corners are too few to fit: points on its 6 faces, about MIN_MESH_POINTS of
    // them, every one on a face with that face's outward normal; the same points every time.
    let p = mesh_points(cube_at([0.0; 3]));
    let enough = MIN_MESH_POINTS * 8 / 10..=MIN_MESH_POINTS;
    assert!(enough.contains(&p.sampled), "{}", p.sampled);
    let n = p.normals.as_ref().unwrap();
    for (x, n) in p.positions.iter().zip(n).skip(8) {
        let axis = (0..3).find(|&a| n[a] != 0.0).unwrap();
        let side = if n[axis] > 0.0 { 1.0 } else { 0.0 };
        assert!(
            (x[axis] - side).abs() < 1e-12 && n[axis].abs() == 1.0,
            "{x:?} {n:?}"
        );
        assert!(dot(&[x[0] - 0.5, x[1] - 0.5, x[2] - 0.5], n) > 0.0);
    }
    assert_eq!(mesh_points(cube_at([0.0; 3])), p);
    // The bunny's own mesh has vertices enough: nothing sampled.
    let bunny = read_ply_mesh(bunny_path()).unwrap();
    assert_eq!(mesh_points(bunny).sampled, 0);
}

#[test]
fn ply_keeps_a_georeferenced_mesh_in_doubles_and_a_mesh_near_the_origin_in_floats() {
    use zeroset_mesh::io::{PlyFormat, ply::F32_ROUNDING_LIMIT, ply_from_bytes, ply_to_bytes};
    // A 1 m cube at UTM-like coordinates, where f32's step is 0.5 m: as floats its corners
    // would collapse onto each other.
    let far = cube_at([512_345.678, 4_101_234.567, 123.4]);
    assert!(far.f32_rounding() > 1e-3);
    let near = tetrahedron();
    assert!(near.f32_rounding() < F32_ROUNDING_LIMIT);
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
        let bytes = ply_to_bytes(&far, format).unwrap();
        let header = String::from_utf8_lossy(&bytes[..200]).into_owned();
        assert!(header.contains("property double x"), "{header}");
        let back = ply_from_bytes(&bytes, "far.ply").unwrap();
        assert_eq!(back.vertices(), far.vertices(), "{format:?}");
        let report = check(&back);
        assert!(report.is_oriented_closed() && (report.signed_volume - 1.0).abs() < 1e-6);

        let bytes = ply_to_bytes(&near, format).unwrap();
        let header = String::from_utf8_lossy(&bytes[..200]).into_owned();
        assert!(header.contains("property float x"), "{header}");
    }
}

#[test]
fn a_cad_cylinder_of_slivers_is_sampled_on_every_face() {
    use zeroset_mesh::points::{MIN_MESH_POINTS, mesh_points};
    // A closed cylinder as CAD exports it: radius 1, height 6, 256 segments: its side slivers
    // 6 × 0.025, its caps fans of slivers about their centres. The lattice sampling put no
    // point inside a triangle expecting fewer than 4.5 (here every cap triangle: a cup's
    // bottom and a plate's hole walls came out missing); each triangle now gets its share by
    // area, spread over it, with its face's normal.
    let segments = 256u32;
    let ring = |z: f64| -> Vec<[f64; 3]> {
        (0..segments)
            .map(|i| {
                let t = 2.0 * std::f64::consts::PI * f64::from(i) / f64::from(segments);
                [t.cos(), t.sin(), z]
            })
            .collect()
    };
    let mut v = ring(0.0);
    v.extend(ring(6.0));
    v.push([0.0, 0.0, 0.0]);
    v.push([0.0, 0.0, 6.0]);
    let (s, bottom, top) = (segments, 2 * segments, 2 * segments + 1);
    let mut t = Vec::new();
    for i in 0..s {
        let j = (i + 1) % s;
        t.push([i, j, s + j]);
        t.push([i, s + j, s + i]);
        t.push([bottom, j, i]);
        t.push([top, s + i, s + j]);
    }
    let p = mesh_points(TriMesh::new(v, t).unwrap());
    assert_eq!(p.sampled, MIN_MESH_POINTS);
    let n = p.normals.as_ref().unwrap();
    let sampled = p
        .positions
        .iter()
        .zip(n)
        .skip(p.positions.len() - p.sampled);
    // Points per sector of the side, the bottom and the top; normals radial or ±z.
    let sectors = segments as usize;
    let mut counts = vec![[0usize; 3]; sectors];
    for (x, n) in sampled {
        let angle = x[1].atan2(x[0]).rem_euclid(2.0 * std::f64::consts::PI);
        let sector = ((angle / (2.0 * std::f64::consts::PI) * f64::from(segments)) as usize)
            .min(sectors - 1);
        let r = x[0].hypot(x[1]);
        if x[2] > 1e-9 && x[2] < 6.0 - 1e-9 {
            counts[sector][0] += 1;
            assert!(r > 0.99 && r <= 1.0 + 1e-12, "{x:?}");
            assert!(
                (n[0] * x[0] + n[1] * x[1]) / r > 0.99 && n[2].abs() < 1e-12,
                "{n:?}"
            );
        } else {
            let (face, outward) = if x[2] < 3.0 { (1, -1.0) } else { (2, 1.0) };
            counts[sector][face] += 1;
            assert!((n[2] - outward).abs() < 1e-12, "{x:?} {n:?}");
        }
    }
    // By area: 6/7 on the side, 1/14 on each cap (the polygon's a little less); every
    // triangle some (a cap's expects 2.8).
    let side: usize = counts.iter().map(|c| c[0]).sum();
    assert!(
        (side as f64 / MIN_MESH_POINTS as f64 - 6.0 / 7.0).abs() < 0.01,
        "{side}"
    );
    assert!(
        counts.iter().all(|c| c.iter().all(|&k| k > 0)),
        "{counts:?}"
    );
}
