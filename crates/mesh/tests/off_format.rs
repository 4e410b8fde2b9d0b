//! OFF (Object File Format): round trips, files as other software writes them, read errors
//! naming the line, and the extension dispatch of `read_mesh` / `write_mesh`.

mod common;

use std::time::{Duration, Instant};

use common::{bunny_path, cube_at, cube_triangles};
use zeroset_mesh::io::{MeshFormat, off_from_bytes, off_to_string};
use zeroset_mesh::{
    MeshError, TriMesh, boundary_loops, check, is_mesh_file, read_mesh, read_off_mesh,
    read_ply_mesh, write_mesh, write_off,
};

/// The tetrahedron of these tests, at coordinates that are not all `f32` values, with
/// per-vertex normals.
fn tetrahedron() -> TriMesh {
    common::tetrahedron_at([0.1, -0.2, 0.3])
}

fn read(text: &str) -> TriMesh {
    match off_from_bytes(text.as_bytes(), "t.off") {
        Ok(m) => m,
        Err(e) => panic!("{text:?}: {e}"),
    }
}

/// The error reading `bytes`, which must be [`MeshError::Malformed`] for OFF, as text.
fn expect_err(bytes: &[u8]) -> String {
    match off_from_bytes(bytes, "bad.off") {
        Ok(m) => panic!(
            "{:?}: expected an error, read {} vertices and {} triangles",
            String::from_utf8_lossy(bytes),
            m.num_vertices(),
            m.num_triangles()
        ),
        Err(e) => {
            assert!(
                matches!(e, MeshError::Malformed { format: "OFF", .. }),
                "{e:?}"
            );
            let msg = e.to_string();
            assert!(msg.starts_with("bad.off: OFF line "), "{msg}");
            msg
        }
    }
}

/// The vertices' coordinates as bits: equal means bit-exact (`-0` is not `0`).
fn bits(mesh: &TriMesh) -> Vec<[u64; 3]> {
    mesh.vertices()
        .iter()
        .map(|p| p.map(f64::to_bits))
        .collect()
}

const TETRAHEDRON: &str = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
const TETRAHEDRON_FACES: &str = "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

/// The tetrahedron `[0, 1]³` corner, wound outward, as read from OFF text.
fn assert_tetrahedron(m: &TriMesh, what: &str) {
    assert_eq!(
        m.vertices(),
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0]
        ],
        "{what}"
    );
    assert_eq!(
        m.triangles(),
        &[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        "{what}"
    );
    let report = check(m);
    assert!(report.is_oriented_closed(), "{what}: {report}");
    assert!((report.signed_volume - 1.0 / 6.0).abs() < 1e-15, "{what}");
}

#[test]
fn round_trips_are_bit_exact_and_keep_the_topology() {
    // Coordinates that are not f32 values, signed zeros, subnormals and the extremes.
    let awkward = TriMesh::new(
        vec![
            [-0.0, 1e-300, f64::MAX],
            [0.1 + 0.2, 5e-324, -f64::MAX],
            [1.0 / 3.0, -2.0 / 3.0, std::f64::consts::PI],
            [1e8 + 1.0 / 7.0, -0.0, 1e15 + 0.3],
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    for mesh in [
        cube_at([0.5, -2.0, 1e-3]),
        cube_at([0.1, 0.2, 0.3]),
        tetrahedron(),
        awkward,
    ] {
        let text = off_to_string(&mesh);
        let back = off_from_bytes(text.as_bytes(), "m.off").unwrap();
        assert_eq!(back, mesh);
        assert_eq!(bits(&back), bits(&mesh));
        let normal_bits = |m: &TriMesh| -> Vec<[u64; 3]> {
            m.normals().iter().map(|n| n.map(f64::to_bits)).collect()
        };
        assert_eq!(normal_bits(&back), normal_bits(&mesh));
        let (want, got) = (check(&mesh), check(&back));
        assert_eq!(got.euler_characteristic, want.euler_characteristic);
        assert_eq!(got.closed, want.closed);
        assert_eq!(got.signed_volume.to_bits(), want.signed_volume.to_bits());
        // Written again, the same text.
        assert_eq!(off_to_string(&back), text);
    }
    let cube = off_from_bytes(off_to_string(&cube_at([0.0; 3])).as_bytes(), "c.off").unwrap();
    let report = check(&cube);
    assert!(report.is_oriented_closed() && report.euler_characteristic == 2);
    assert!((report.signed_volume - 1.0).abs() < 1e-15);
}

#[test]
fn written_text_is_as_documented() {
    // The tetrahedron without its normals.
    let tet = common::tetrahedron_at([0.0; 3]);
    let plain = TriMesh::new(tet.vertices().to_vec(), tet.triangles().to_vec()).unwrap();
    let text = off_to_string(&plain);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "OFF");
    assert!(lines[1].starts_with("# ") && lines[1].contains("zeroset"));
    assert_eq!(lines[2], "4 4 0");
    assert_eq!(
        &lines[3..],
        TETRAHEDRON
            .lines()
            .chain(TETRAHEDRON_FACES.lines())
            .collect::<Vec<_>>()
    );
    assert!(text.ends_with('\n'));

    // With normals: NOFF, each vertex line x y z nx ny nz.
    let text = off_to_string(&common::tetrahedron_at([0.0; 3]));
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "NOFF");
    assert_eq!(lines[2], "4 4 0");
    assert_eq!(lines[3], "0 0 0 -0.5 -0.5 -0.5");
    assert_eq!(lines[4], "1 0 0 0.75 -0.25 -0.25");
    assert_eq!(lines[7], "3 0 2 1");

    // No triangles: a point cloud, `nv 0 0`.
    let cloud = TriMesh::new(vec![[1.5, 2.0, -3.0]], Vec::new()).unwrap();
    assert_eq!(
        off_to_string(&cloud),
        "OFF\n# written by zeroset (zeroset-mesh)\n1 0 0\n1.5 2 -3\n"
    );
}

#[test]
fn read_and_write_by_path_and_extension() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = tetrahedron();

    let path = dir.path().join("t.off");
    write_off(&path, &mesh).unwrap();
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        off_to_string(&mesh)
    );
    assert_eq!(read_off_mesh(&path).unwrap(), mesh);
    assert!(is_mesh_file(&path));

    for (name, ascii) in [("w.off", false), ("W.OFF", true), ("w.Off", false)] {
        let path = dir.path().join(name);
        assert_eq!(MeshFormat::from_path(&path), Some(MeshFormat::Off));
        write_mesh(&path, &mesh, ascii).unwrap();
        // Text either way: `ascii` does not change OFF.
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            off_to_string(&mesh),
            "{name}"
        );
        assert_eq!(read_mesh(&path).unwrap(), mesh, "{name}");
    }
    assert!(!MeshFormat::Off.has_binary());
    assert!(MeshFormat::EXTENSIONS.contains(&"off"));

    // A missing file is named.
    let missing = dir.path().join("missing.off");
    let err = read_off_mesh(&missing).unwrap_err().to_string();
    assert!(err.contains("missing.off"), "{err}");
    let err = read_mesh(&missing).unwrap_err().to_string();
    assert!(err.contains("missing.off"), "{err}");
}

#[test]
fn the_bunny_through_off_keeps_its_topology() {
    let path = bunny_path();
    assert!(path.is_file(), "test data {} not found", path.display());
    let ply = read_ply_mesh(&path).unwrap();
    let want = check(&ply);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bunny.off");
    write_mesh(&out, &ply, false).unwrap();
    let back = read_mesh(&out).unwrap();
    // Every vertex (unused ones too) and triangle as they were, bit for bit.
    assert_eq!(back, ply);
    assert_eq!(bits(&back), bits(&ply));
    let got = check(&back);
    assert_eq!((got.edges, got.euler_characteristic), (104_288, -3));
    assert_eq!(
        (
            got.vertices,
            got.used_vertices,
            got.edges,
            got.boundary_edges,
            got.euler_characteristic,
            got.components
        ),
        (
            want.vertices,
            want.used_vertices,
            want.edges,
            want.boundary_edges,
            want.euler_characteristic,
            want.components
        )
    );
    assert_eq!(boundary_loops(&back), 5);
    assert!((got.signed_volume - want.signed_volume).abs() < 1e-12);
    // Read back and written again, the same text.
    let again = dir.path().join("again.off");
    write_off(&again, &back).unwrap();
    assert_eq!(std::fs::read(&again).unwrap(), std::fs::read(&out).unwrap());
}

#[test]
fn coff_with_colours_comments_and_quads() {
    // The unit cube as six quads, as Geomview writes it: a comment before the keyword,
    // colours after each vertex (RGBA floats) and each face (RGB integers), comments at the
    // ends of lines and on their own, blank lines, tabs and runs of spaces.
    let text = "# cube.off, from a modelling tool\nCOFF\n# vertices faces edges\n8  6\t12\n\n\
        0 0 0   1 0 0 1\n1 0 0   0 1 0 1  # second\n0 1 0   0 0 1 1\n1 1 0 1 1 1 1\n\
        0 0 1   1 0 0 1\n  1 0 1 0 1 0 1\n0 1 1\t0 0 1 1\n1 1 1 1 1 1 1   \n\
        # the faces\n\
        4 0 2 3 1  255 0 0\n4 4 5 7 6  0 255 0\n4  0 1 5 4\n\n4 2 6 7 3 0 0 255\n\
        4 0 4 6 2 10 10 10\t\n4 1 3 7 5 1 2 3 # last\n";
    let m = read(text);
    assert_eq!(m.num_vertices(), 8);
    assert_eq!(m.vertices(), cube_at([0.0; 3]).vertices());
    // Each quad fan-triangulated: (a b c), (a c d).
    assert_eq!(m.triangles(), cube_triangles(0).as_slice());
    assert!(m.normals().is_empty());
    let report = check(&m);
    assert!(report.is_oriented_closed(), "{report}");
    assert_eq!(report.euler_characteristic, 2);
    assert!((report.signed_volume - 1.0).abs() < 1e-15);

    // A pentagon fans out into three triangles; a colour with an alpha after a triangle.
    let pentagon =
        read("OFF\n5 1 5\n0 0 0\n2 0 0\n3 1 0\n1 2 0\n-1 1 0\n5 0 1 2 3 4 0.1 0.2 0.3 0.4\n");
    assert_eq!(pentagon.triangles(), &[[0, 1, 2], [0, 2, 3], [0, 3, 4]]);

    // Every prefix: texture coordinates, colours and normals on one vertex line; the normals
    // are kept, the rest is not.
    let m = read(
        "STCNOFF\n3 1 3\n0 0 0  0 0 1  1 0 0 1  0 0\n1 0 0  0 0 1  0 1 0 1  1 0\n\
         0 1 0  0 0 1  0 0 1 1  0 1\n3 0 1 2\n",
    );
    assert_eq!(m.normals(), &[[0.0, 0.0, 1.0]; 3]);
    for keyword in ["STOFF", "COFF", "STCOFF", "CSTOFF", "off"] {
        let m = read(&format!(
            "{keyword}\n4 4 6\n{TETRAHEDRON}{TETRAHEDRON_FACES}"
        ));
        assert_tetrahedron(&m, keyword);
    }
}

#[test]
fn noff_normals_are_read_back_as_written() {
    // Not unit length, not normalised: kept as written.
    let m = read(&format!(
        "NOFF\n4 4 0\n0 0 0 -1 -1 -1\n1 0 0 2 0 0\n0 1 0 0 2 0\n0 0 1 0 0 0.5\n\
         {TETRAHEDRON_FACES}"
    ));
    assert_tetrahedron(&m, "NOFF");
    assert_eq!(
        m.normals(),
        &[
            [-1.0, -1.0, -1.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 0.5]
        ]
    );
    // Numbers after the normal (a colour some writers append) are ignored.
    let m =
        read("NOFF\n3 1\n0 0 0 0 0 1 255 0 0\n1 0 0 0 0 1 0 255 0\n0 1 0 0 0 1 9 9 9\n3 0 1 2\n");
    assert_eq!(m.normals(), &[[0.0, 0.0, 1.0]; 3]);
    // A plain OFF has none, whatever numbers follow the coordinates.
    let m = read("OFF\n3 1\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n");
    assert!(m.normals().is_empty());
}

#[test]
fn keyword_and_counts_may_share_a_line_or_spread_over_lines() {
    for head in [
        "OFF 4 4 6\n",
        "OFF 4 4\n",
        "OFF\n4 4\n",
        "OFF 4\n4 6\n",
        "OFF\n4\n# faces next\n4 6\n",
        "OFF # the keyword\n4 4 6 # the counts\n",
        "OFF\n+4 4 0\n",
        // The keyword run into the vertex count, as in many ModelNet files.
        "OFF4 4 0\n",
        "COFF4 4\n",
    ] {
        assert_tetrahedron(
            &read(&format!("{head}{TETRAHEDRON}{TETRAHEDRON_FACES}")),
            head,
        );
    }
    // Anything after the announced faces is ignored.
    let m = read(&format!(
        "OFF\n4 4 6\n{TETRAHEDRON}{TETRAHEDRON_FACES}3 0 1 2\nextra\n"
    ));
    assert_tetrahedron(&m, "trailing");
}

#[test]
fn the_keyword_may_be_missing() {
    for head in ["4 4 6\n", "# a comment first\n\n4 4 6\n", "4 4\n"] {
        assert_tetrahedron(
            &read(&format!("{head}{TETRAHEDRON}{TETRAHEDRON_FACES}")),
            head,
        );
    }
}

#[test]
fn byte_order_mark_and_line_endings() {
    let lf = format!("OFF\n# comment\n4 4 6\n{TETRAHEDRON}\n{TETRAHEDRON_FACES}");
    let cases = [
        ("BOM", format!("\u{feff}{lf}")),
        (
            "BOM, no keyword",
            format!("\u{feff}4 4 6\n{TETRAHEDRON}{TETRAHEDRON_FACES}"),
        ),
        ("CRLF", lf.replace('\n', "\r\n")),
        (
            "BOM and CRLF",
            format!("\u{feff}{}", lf.replace('\n', "\r\n")),
        ),
        ("CR (classic Mac)", lf.replace('\n', "\r")),
        ("no final newline", lf.trim_end().to_owned()),
    ];
    for (what, text) in cases {
        assert_tetrahedron(&read(&text), what);
    }
    // Line numbers count CRLF and CR line ends once each.
    let msg = expect_err(b"OFF\r\n3 1 0\r\n0 0 0\r\n\r\n1 0 x\r0 1 0\r3 0 1 2\r");
    assert!(
        msg.contains("OFF line 5: vertex 1 coordinate z 'x'"),
        "{msg}"
    );
    // A comment may hold bytes that are not UTF-8 (Latin-1); the rest of a line may not.
    let latin1 = b"OFF # caf\xe9\n3 1 0\n0 0 0\n1 0 0\n0 1 0 # \xff\xfe\n3 0 1 2\n";
    assert_eq!(off_from_bytes(latin1, "l.off").unwrap().num_triangles(), 1);
    let msg = expect_err(b"OFF\n3 1 0\n0 0 \xff\n");
    assert!(msg.contains("OFF line 3: the text is not UTF-8"), "{msg}");
}

#[test]
fn faceless_files_and_unused_vertices() {
    // No faces: a mesh without triangles (a point cloud), with normals for NOFF.
    let m = read("OFF\n2 0 0\n0 0 0\n1 2 3\n");
    assert_eq!((m.num_vertices(), m.num_triangles()), (2, 0));
    let m = read("NOFF\n2 0 0\n0 0 0 1 0 0\n1 2 3 0 1 0\n");
    assert_eq!(m.normals(), &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    // Nothing at all.
    let m = read("OFF\n0 0 0\n");
    assert_eq!((m.num_vertices(), m.num_triangles()), (0, 0));
    // Vertices no face uses are kept, in their place.
    let m = read("OFF\n5 1 3\n9 9 9\n0 0 0\n1 0 0\n0 1 0\n8 8 8\n3 1 2 3\n");
    assert_eq!(m.num_vertices(), 5);
    assert_eq!(m.vertices()[4], [8.0, 8.0, 8.0]);
    assert_eq!(m.triangles(), &[[1, 2, 3]]);
}

#[test]
fn errors_name_the_line() {
    let tet = |faces: &str| format!("OFF\n4 4 6\n{TETRAHEDRON}{faces}");
    let cases: Vec<(String, &str)> = vec![
        // Truncated vertices and faces, and counts.
        (
            "OFF\n4 4 6\n0 0 0\n1 0 0\n".into(),
            "line 4: truncated: the file ends after 2 of the 4 vertices the counts on line 2 \
             announce",
        ),
        (
            tet("3 0 2 1\n3 0 1 3\n# cut here\n"),
            "line 8: truncated: the file ends after 2 of the 4 faces the counts on line 2 \
             announce",
        ),
        (
            "OFF\n".into(),
            "line 1: truncated: the file ends before the vertex count",
        ),
        (
            "OFF 4\n".into(),
            "line 1: truncated: the file ends before the face count",
        ),
        // Faces.
        (
            tet("3 0 2 1\n2 0 1\n"),
            "line 8: face 1 has 2 corner(s); at least 3 are needed",
        ),
        (
            tet("3 0 2 1\n3 0 1 3\n3 0 3 4\n"),
            "line 9: face 2 corner 2 refers to vertex 4, out of range for the 4 vertices",
        ),
        (
            tet("3 0 2 -1\n"),
            "line 7: face 0 corner 2 '-1' is not a vertex index",
        ),
        (
            tet("3 0 2 1.5\n"),
            "line 7: face 0 corner 2 '1.5' is not a vertex index",
        ),
        (
            tet("3 0 2\n3 0 1 3\n"),
            "line 7: face 0 announces 3 corners, but the line holds only 2",
        ),
        (
            tet("three 0 2 1\n"),
            "line 7: face 0: the corner count 'three' is not a whole number",
        ),
        // Vertices.
        (
            "OFF\n3 1 0\n0 0 0\n0 nan 0\n".into(),
            "line 4: vertex 1 coordinate y is not finite: nan",
        ),
        (
            "OFF\n3 1 0\n0 0 0\n0 NaN 0\n".into(),
            "line 4: vertex 1 coordinate y is not finite: NaN",
        ),
        (
            "OFF\n3 1 0\n0 0 -inf\n".into(),
            "line 3: vertex 0 coordinate z is not finite: -inf",
        ),
        (
            "OFF\n3 1 0\n0 0 1e999\n".into(),
            "line 3: vertex 0 coordinate z is not finite: 1e999",
        ),
        (
            "OFF\n3 1 0\n0 zero 0\n".into(),
            "line 3: vertex 0 coordinate y 'zero' is not a number",
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0\n".into(),
            "line 4: vertex 1 has no z: a vertex line is x y z (one vertex a line)",
        ),
        (
            "NOFF\n3 1 0\n0 0 0\n".into(),
            "line 3: vertex 0 has no nx: a vertex line is x y z nx ny nz",
        ),
        (
            "NOFF\n3 1 0\n0 0 0 0 inf 1\n".into(),
            "line 3: vertex 0 normal component ny is not finite: inf",
        ),
        // Counts and keywords.
        (
            "OFF\nfour 4 6\n".into(),
            "line 2: the vertex count 'four' is not a whole number",
        ),
        (
            "OFF\n4 -4 6\n".into(),
            "line 2: the face count '-4' is not a whole number",
        ),
        (
            "OFF\n4.0 4 6\n".into(),
            "line 2: the vertex count '4.0' is not a whole number",
        ),
        (
            "OFF\n4 4 six\n".into(),
            "line 2: the edge count 'six' is not a whole number",
        ),
        (
            "OFF\n4 4 6 0 0 0\n".into(),
            "line 2: '0' after the counts (vertices 4, faces 4, edges): vertices begin on the \
             next line",
        ),
        (
            "OFF\n99999999999999999999999 1 0\n".into(),
            "line 2: the vertex count 99999999999999999999999 is too large",
        ),
        (
            "99999999999999999999999 1 0\n".into(),
            "line 1: the vertex count 99999999999999999999999 is too large",
        ),
        (
            "ply\nformat ascii 1.0\n".into(),
            "line 1: 'ply' is neither the OFF keyword ([ST][C][N]OFF) nor a vertex count",
        ),
        (
            "OFF4.5 4 6\n".into(),
            "line 1: 'OFF4.5' is neither the OFF keyword",
        ),
        (
            "OFF4\n".into(),
            "line 1: truncated: the file ends before the face count",
        ),
        (
            "# header\nXOFF\n4 4 6\n".into(),
            "line 2: 'XOFF' is neither the OFF keyword",
        ),
        // The text of an oriented point cloud (.xyzn) named .off.
        (
            "-0.0378 0.1279 0.0044 0.1 0.9 0.2\n".into(),
            "line 1: '-0.0378' is neither the OFF keyword",
        ),
        ("".into(), "line 1: the file is empty"),
        ("# nothing\n\n  \n".into(), "line 1: the file is empty"),
    ];
    for (text, want) in cases {
        let msg = expect_err(text.as_bytes());
        assert!(msg.contains(want), "{text:?}:\n  got  {msg}\n  want {want}");
    }
}

#[test]
fn huge_counts_are_answered_at_once() {
    let start = Instant::now();
    let cases = [
        (
            "OFF\n1000000000000 1000000000000 0\n0 0 0\n".to_owned(),
            "line 3: truncated: the file ends after 1 of the 1000000000000 vertices",
        ),
        (
            format!("OFF\n18446744073709551615 1 0\n{TETRAHEDRON}"),
            "line 6: truncated: the file ends after 4 of the 18446744073709551615 vertices",
        ),
        (
            format!("OFF\n4 1000000000000 0\n{TETRAHEDRON}{TETRAHEDRON_FACES}"),
            "line 10: truncated: the file ends after 4 of the 1000000000000 faces",
        ),
        (
            format!("OFF\n4 1 0\n{TETRAHEDRON}1000000000000 0 1 2\n"),
            "line 7: face 0 announces 1000000000000 corners, but the line holds only 3",
        ),
    ];
    for (text, want) in cases {
        let msg = expect_err(text.as_bytes());
        assert!(msg.contains(want), "{text:?}:\n  got  {msg}\n  want {want}");
    }
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "{:?}",
        start.elapsed()
    );
}

#[test]
fn four_d_n_d_and_binary_off_are_refused() {
    for (text, want) in [
        (
            "4OFF\n3 1 0\n0 0 0 1\n",
            "OFF line 1: the keyword '4OFF' announces 4-D vertices",
        ),
        (
            "# 4-D\nC4OFF\n",
            "OFF line 2: the keyword 'C4OFF' announces 4-D vertices",
        ),
        (
            "nOFF\n3\n3 1 0\n",
            "OFF line 1: the keyword 'nOFF' announces vertices of any dimension",
        ),
        (
            "OFF BINARY\n",
            "OFF line 1: 'OFF BINARY': binary OFF is not supported",
        ),
    ] {
        let err = off_from_bytes(text.as_bytes(), "bad.off").unwrap_err();
        assert!(
            matches!(err, MeshError::UnsupportedFormat { .. }),
            "{err:?}"
        );
        let msg = err.to_string();
        assert!(
            msg.contains("bad.off") && msg.contains(want),
            "{text:?}:\n  got  {msg}\n  want {want}"
        );
    }
}

#[test]
fn a_non_convex_face_is_cut_inside_itself() {
    // An L-shaped hexagon (area 3) whose first corner does not see the whole of it: a fan
    // from there laid a triangle outside it, wound the other way (CGAL's `mpi.off`, whose
    // faces are the letters of a logo, came out in bubbles).
    let text = "OFF\n6 1 0\n2 0 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n0 0 0\n6 0 1 2 3 4 5\n";
    let mesh = off_from_bytes(text.as_bytes(), "l.off").unwrap();
    assert_eq!(mesh.num_triangles(), 4);
    let report = zeroset_mesh::check(&mesh);
    assert!((report.area - 3.0).abs() < 1e-12, "{report}");
    for t in 0..4 {
        let [a, b, c] = mesh.corners(t);
        let z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        assert!(z > 0.0, "triangle {t} faces −z");
    }
}
