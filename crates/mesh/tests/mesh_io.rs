//! Mesh file round trips (PLY, OBJ), read errors, and mesh checks on small solids and on the
//! Stanford bunny.

mod common;

use std::path::Path;

use common::{bunny_path, cube_at, cube_triangles, unit_cube};
use zeroset_mesh::io::{ply_from_bytes, ply_to_bytes};
use zeroset_mesh::{
    MeshError, PlyFormat, TriMesh, boundary_loops, check, read_ply_mesh, write_obj, write_ply,
};

/// The tetrahedron of these tests, its corner at the origin.
fn tetrahedron() -> TriMesh {
    common::tetrahedron_at([0.0; 3])
}

#[test]
fn ply_round_trips_in_both_formats() {
    let dir = tempfile::tempdir().unwrap();
    for mesh in [unit_cube(), tetrahedron()] {
        for format in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
            let path = dir.path().join(format!("m-{format:?}.ply"));
            write_ply(&path, &mesh, format).unwrap();
            let back = read_ply_mesh(&path).unwrap();
            assert_eq!(back, mesh, "{format:?}");
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(bytes, ply_to_bytes(&mesh, format).unwrap());
            assert_eq!(ply_from_bytes(&bytes, "mem").unwrap(), mesh);
            // The point-cloud reader (the same PLY layer, read for points) finds the same
            // vertices and normals.
            let cloud = zeroset_field_core::io::read_point_cloud(&path).unwrap();
            assert_eq!(cloud.positions(), mesh.vertices());
            assert_eq!(cloud.normals().unwrap_or_default(), mesh.normals());
        }
    }
    // The header is the standard one.
    let bytes = ply_to_bytes(&tetrahedron(), PlyFormat::default()).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    let header = &text[..text.find("end_header\n").unwrap() + 11];
    assert_eq!(
        header,
        "ply\nformat binary_little_endian 1.0\ncomment written by zeroset (zeroset-mesh)\n\
         element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nelement face 4\n\
         property list uchar int vertex_indices\nend_header\n"
    );
    assert_eq!(bytes.len(), header.len() + 4 * 24 + 4 * 13);
}

#[test]
fn obj_text_is_as_documented() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tet.obj");
    write_obj(&path, &tetrahedron()).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("# ") && lines[0].contains("zeroset"));
    assert_eq!(&lines[1..5], ["v 0 0 0", "v 1 0 0", "v 0 1 0", "v 0 0 1"]);
    assert_eq!(lines[5], "vn -0.5 -0.5 -0.5");
    assert_eq!(lines[9], "f 1//1 3//3 2//2");
    assert_eq!(lines.len(), 1 + 4 + 4 + 4);

    let path = dir.path().join("cube.obj");
    write_obj(&path, &unit_cube()).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 8);
    assert!(!text.contains("vn "));
    assert!(text.contains("\nv 1 1 1\n"));
    assert!(text.contains("\nf 1 3 4\n"), "{text}");
    assert_eq!(text.lines().filter(|l| l.starts_with("f ")).count(), 12);
}

#[test]
fn reads_other_types_endianness_and_polygons() {
    // Big-endian, double coordinates, an extra leading property, uint count and ushort indices,
    // a quad (fan-triangulated), an extra element before the vertices.
    let mut b = b"ply\r\nformat binary_big_endian 1.0\r\ncomment hi\r\nelement camera 1\r\n\
property uint8 id\r\nelement vertex 4\r\nproperty uchar flag\r\nproperty double x\r\n\
property float64 y\r\nproperty double z\r\nelement face 1\r\n\
property list uint ushort vertex_index\r\nproperty int16 tag\r\nend_header\r\n"
        .to_vec();
    b.push(7);
    let quad = [
        [0.0, 0.0, 0.5],
        [1.0, 0.0, 0.5],
        [1.0, 1.0, 0.5],
        [0.0, 1.0, 0.1],
    ];
    for p in quad {
        b.push(1);
        for c in p {
            b.extend_from_slice(&f64::to_be_bytes(c));
        }
    }
    b.extend_from_slice(&4u32.to_be_bytes());
    for i in [0u16, 1, 2, 3] {
        b.extend_from_slice(&i.to_be_bytes());
    }
    b.extend_from_slice(&(-3i16).to_be_bytes());
    let m = ply_from_bytes(&b, "quad.ply").unwrap();
    assert_eq!(m.vertices(), quad);
    assert_eq!(m.triangles(), [[0, 1, 2], [0, 2, 3]]);
    assert!(m.normals().is_empty());

    // ASCII with a pentagon, int8 counts, extra properties and blank lines.
    let text = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
property int confidence\nproperty float z\nelement face 1\nproperty list char uint \
vertex_indices\nend_header\n0 0 9 0\n1 0 9 0\n\n2 1 9 0\n1 2 9 0\n0 1 9 0\n5 0 1 2 3 4\n";
    let m = ply_from_bytes(text.as_bytes(), "penta.ply").unwrap();
    assert_eq!(m.num_vertices(), 5);
    assert_eq!(m.triangles(), [[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
}

fn expect_err(bytes: &[u8]) -> String {
    match ply_from_bytes(bytes, "bad.ply") {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn truncated_binary_names_element_and_record() {
    let bytes = ply_to_bytes(&unit_cube(), PlyFormat::BinaryLittleEndian).unwrap();
    // Cut in the middle of face 5 (each face is 13 bytes, at the end).
    let cut = bytes.len() - 6 * 13 - 4;
    let err = ply_from_bytes(&bytes[..cut], "cube.ply").unwrap_err();
    match &err {
        MeshError::PlyTruncated {
            path,
            element,
            record,
            expected,
        } => {
            assert_eq!(path, Path::new("cube.ply"));
            assert_eq!((element.as_str(), *record, *expected), ("face", 5, 12));
        }
        other => panic!("unexpected {other:?}"),
    }
    let msg = err.to_string();
    assert!(
        msg.contains("cube.ply") && msg.contains("face record 5"),
        "{msg}"
    );
    // Cut in the vertices.
    let header_len = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let err = ply_from_bytes(&bytes[..header_len + 12 * 3 + 2], "cube.ply").unwrap_err();
    assert!(
        matches!(&err, MeshError::PlyTruncated { element, record: 3, expected: 8, .. } if element == "vertex"),
        "{err:?}"
    );
    // ASCII too.
    let text = ply_to_bytes(&unit_cube(), PlyFormat::Ascii).unwrap();
    let cut = text.len() - 2 * "3 1 3 7\n".len();
    let err = ply_from_bytes(&text[..cut], "cube.ply").unwrap_err();
    assert!(
        matches!(&err, MeshError::PlyTruncated { record: 10, .. }),
        "{err:?}"
    );
}

#[test]
fn a_count_the_file_cannot_hold_is_truncated_without_a_large_allocation() {
    // 10⁹ vertices (and 10⁹ faces) claimed in a file of about 300 bytes: room is reserved for
    // what the bytes can hold, and the file is reported as truncated where it ends.
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\n\
                  property float x\nproperty float y\nproperty float z\n\
                  element face 1000000000\nproperty list uchar int vertex_indices\nend_header\n";
    let mut bytes = header.as_bytes().to_vec();
    bytes.extend([0u8; 100]);
    let err = ply_from_bytes(&bytes, "huge.ply").unwrap_err();
    assert!(
        matches!(
            &err,
            MeshError::PlyTruncated { element, record: 8, expected: 1_000_000_000, .. }
                if element == "vertex"
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("truncated"), "{err}");
    // Vertices complete, the faces' count too large.
    let cube = ply_to_bytes(&unit_cube(), PlyFormat::BinaryLittleEndian).unwrap();
    let at = ply_header_len(&cube);
    let header = String::from_utf8(cube[..at].to_vec())
        .unwrap()
        .replace("element face 12\n", "element face 999999999\n");
    let bytes = [header.as_bytes(), &cube[at..]].concat();
    let err = ply_from_bytes(&bytes, "faces.ply").unwrap_err();
    assert!(
        matches!(
            &err,
            MeshError::PlyTruncated { element, record: 12, expected: 999_999_999, .. }
                if element == "face"
        ),
        "{err:?}"
    );
    // ASCII: two vertex lines of the 10⁹ announced.
    let ascii = "ply\nformat ascii 1.0\nelement vertex 1000000000\nproperty float x\n\
                 property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n";
    let err = ply_from_bytes(ascii.as_bytes(), "huge.ply").unwrap_err();
    assert!(
        matches!(
            &err,
            MeshError::PlyTruncated {
                record: 2,
                expected: 1_000_000_000,
                ..
            }
        ),
        "{err:?}"
    );
}

/// The length of a PLY file's header, `end_header\n` included.
fn ply_header_len(bytes: &[u8]) -> usize {
    bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("a PLY header")
        + 11
}

#[test]
fn bad_face_index_and_other_errors_are_specific() {
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n";
    let err = ply_from_bytes(text.as_bytes(), "tri.ply").unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, MeshError::Ply { .. }), "{err:?}");
    assert!(
        msg.contains("tri.ply") && msg.contains("line 14 (face 1)") && msg.contains("vertex 3"),
        "{msg}"
    );
    // A face index out of range in a binary file.
    let mut bytes = ply_to_bytes(&unit_cube(), PlyFormat::BinaryLittleEndian).unwrap();
    let at = bytes.len() - 4;
    bytes[at..].copy_from_slice(&8i32.to_le_bytes());
    let msg = expect_err(&bytes);
    assert!(
        msg.contains("face 11 (byte") && msg.contains("vertex 8"),
        "{msg}"
    );
    let at = bytes.len() - 4;
    bytes[at..].copy_from_slice(&(-1i32).to_le_bytes());
    assert!(expect_err(&bytes).contains("face 11"));

    assert!(expect_err(b"solid x\n").contains("not a PLY file"));
    assert!(expect_err(b"ply\nformat ascii 1.0\nelement vertex 0\n").contains("end_header"));
    let msg =
        expect_err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty floot x\nend_header\n");
    assert!(
        msg.contains("header line 4") && msg.contains("floot"),
        "{msg}"
    );
    let msg = expect_err(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n",
    );
    assert!(msg.contains("no 'z'"), "{msg}");
    let msg = expect_err(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\n1 2 nan\n",
    );
    assert!(
        msg.contains("line 8 (vertex 0)") && msg.contains("z"),
        "{msg}"
    );
    let msg = expect_err(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\n1 2\n",
    );
    assert!(
        msg.contains("line 8 (vertex 0)") && msg.contains("before 'z'"),
        "{msg}"
    );
    let msg = expect_err(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty uchar x\nproperty float y\n\
property float z\nend_header\n300 2 3\n",
    );
    assert!(msg.contains("'x' = '300'"), "{msg}");
    assert!(
        expect_err(b"ply\nformat binary_middle_endian 1.0\nend_header\n").contains("unsupported")
    );
}

#[test]
fn missing_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no-such-mesh.ply");
    let err = read_ply_mesh(&path).unwrap_err();
    assert!(err.to_string().contains("no-such-mesh.ply"), "{err}");
    // Writing into a directory that does not exist fails, naming the file.
    let bad = dir.path().join("missing-dir").join("out.ply");
    let err = write_ply(&bad, &unit_cube(), PlyFormat::Ascii).unwrap_err();
    assert!(err.to_string().contains("out.ply"), "{err}");
}

#[test]
fn checks_on_cube_and_tetrahedron() {
    let r = check(&unit_cube());
    assert_eq!(
        (r.vertices, r.triangles, r.edges, r.components),
        (8, 12, 18, 1)
    );
    assert_eq!(r.euler_characteristic, 2);
    assert!(r.closed && r.is_oriented_closed());
    assert_eq!(
        (r.boundary_edges, r.non_manifold_edges, r.inconsistent_edges),
        (0, 0, 0)
    );
    assert!((r.signed_volume - 1.0).abs() < 1e-12);
    assert!((r.area - 6.0).abs() < 1e-12);

    let r = check(&tetrahedron());
    assert_eq!((r.euler_characteristic, r.edges), (2, 6));
    assert!(r.closed && r.inconsistent_edges == 0);
    assert!((r.signed_volume - 1.0 / 6.0).abs() < 1e-12);
    // Also after a round trip through a file.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.ply");
    write_ply(&path, &unit_cube(), PlyFormat::default()).unwrap();
    assert_eq!(check(&read_ply_mesh(&path).unwrap()), check(&unit_cube()));
}

#[test]
fn flipped_removed_and_disjoint() {
    let cube = unit_cube();
    let mut t = cube.triangles().to_vec();
    t[4] = [t[4][0], t[4][2], t[4][1]];
    let flipped = TriMesh::new(cube.vertices().to_vec(), t).unwrap();
    let r = check(&flipped);
    assert_eq!(r.inconsistent_edges, 3);
    assert!(r.closed && !r.is_oriented_closed());
    // The flipped triangle (area 1/2) now subtracts its share instead of adding it.
    assert!((r.signed_volume - 1.0).abs() > 1e-3, "{r}");

    let mut t = cube.triangles().to_vec();
    t.remove(7);
    let open = TriMesh::new(cube.vertices().to_vec(), t).unwrap();
    let r = check(&open);
    assert_eq!((r.boundary_edges, r.edges, r.triangles), (3, 18, 11));
    assert!(!r.closed);
    assert_eq!(r.euler_characteristic, 1);
    assert_eq!(boundary_loops(&open), 1);

    let mut v = cube.vertices().to_vec();
    v.extend(cube_at([3.0, 0.0, 0.0]).vertices());
    let mut t = cube_triangles(0);
    t.extend(cube_triangles(8));
    let two = TriMesh::new(v, t).unwrap();
    let r = check(&two);
    assert_eq!((r.components, r.euler_characteristic), (2, 4));
    assert!(r.closed);
    assert!((r.signed_volume - 2.0).abs() < 1e-12, "{r}");
    assert_eq!(boundary_loops(&two), 0);
}

#[test]
fn stanford_bunny() {
    let path = bunny_path();
    assert!(path.is_file(), "test data {} not found", path.display());
    let mesh = read_ply_mesh(&path).unwrap();
    assert_eq!(
        (mesh.num_vertices(), mesh.num_triangles()),
        (35_947, 69_451)
    );
    assert_eq!(
        mesh.vertices()[0],
        [
            f64::from(-0.0378297f32),
            f64::from(0.12794f32),
            f64::from(0.00447467f32)
        ]
    );
    let r = check(&mesh);
    eprintln!("bunny: {r}");
    assert_eq!(r.used_vertices, 34_834);
    assert_eq!(r.edges, 104_288);
    assert_eq!(r.euler_characteristic, -3);
    assert_eq!(r.boundary_edges, 223);
    assert_eq!(
        (
            r.non_manifold_edges,
            r.inconsistent_edges,
            r.degenerate_triangles
        ),
        (0, 0, 0)
    );
    assert_eq!(r.components, 1);
    assert!(!r.closed);
    assert_eq!(boundary_loops(&mesh), 5);
    assert!(
        (r.signed_volume - 7.39e-4).abs() < 1e-5,
        "{}",
        r.signed_volume
    );

    // Binary round trip of the bunny keeps everything.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bunny.ply");
    write_ply(&out, &mesh, PlyFormat::BinaryLittleEndian).unwrap();
    assert_eq!(read_ply_mesh(&out).unwrap(), mesh);
}
