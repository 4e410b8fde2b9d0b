//! Point files as scanners, PCL, Open3D and CloudCompare write them: PCD in its three
//! encodings, text files whose first line names the columns, semicolon-separated tables and
//! PCL's normal names in PLY.
//!
//! `tests/data/bunny300_*.pcd` were written by Open3D 0.20 (`write_point_cloud` with
//! `write_ascii=True`, the default binary, and `compressed=True`) from the first 300 points
//! of `data/bunny_2k.xyzn` with random colours; `tests/data/bunny300.xyzn` holds those points
//! as printed to 9 significant digits (so each value's `f32` is exact). `bunny300.las` (LAS
//! 1.2, point format 0), `bunny300.laz` (LAZ, point format 3 with GPS time and colour) and
//! `bunny300_14.laz` (LAZ 1.4, point format 6) were written from the same points by laspy 2.5.4
//! (with lazrs), scale 10⁻⁷ (`benches/peers/format_fixtures.py`), and so were
//! `bunny300_normals.las` and `.laz`, with the normals in extra bytes (float32 `NormalX…` after
//! a `Curvature` field; int16 `nx ny nz` scaled by 1/30000 after a `confidence` byte). `bunny300.e57` (two scans
//! with poses, normals, scaled integers and invalid records) and `bunny300_spherical.e57` (one
//! scan in spherical coordinates) were written from them by libE57Format through pye57 0.4.19
//! (the same script says what each scan holds).

use std::fs;
use std::path::{Path, PathBuf};

use zeroset_field_core::Error;
use zeroset_field_core::cloud::PointCloud3;
use zeroset_field_core::io::{
    Format, ReadOptions, detect_format, read_point_cloud, read_point_cloud_with,
};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn temp_file(name: &str, bytes: impl AsRef<[u8]>) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    fs::write(&path, bytes).unwrap();
    (dir, path)
}

fn read(name: &str, bytes: impl AsRef<[u8]>) -> PointCloud3 {
    let (_dir, path) = temp_file(name, bytes);
    read_point_cloud(&path).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn read_err(name: &str, bytes: impl AsRef<[u8]>) -> Error {
    let (_dir, path) = temp_file(name, bytes);
    match read_point_cloud(&path) {
        Ok(cloud) => panic!("{name}: expected an error, read {} points", cloud.len()),
        Err(e) => e,
    }
}

/// `x` rounded to `f32`, as a PCD of `F 4` fields stores it.
fn f32_of(p: [f64; 3]) -> [f64; 3] {
    p.map(|v| f64::from(v as f32))
}

#[test]
fn open3d_pcd_files_in_all_three_encodings_read_as_the_points_they_were_written_from() {
    let truth = read_point_cloud(data("bunny300.xyzn")).unwrap();
    let normals = truth.normals().unwrap();
    for encoding in ["ascii", "binary", "binary_compressed"] {
        let path = data(&format!("bunny300_{encoding}.pcd"));
        assert_eq!(detect_format(&path).unwrap(), Format::Pcd);
        let cloud = read_point_cloud(&path).unwrap();
        assert_eq!(cloud.len(), 300, "{encoding}");
        let read_normals = cloud.normals().expect("normal_x normal_y normal_z");
        for (i, (p, n)) in cloud.positions().iter().zip(read_normals).enumerate() {
            if encoding == "ascii" {
                // Open3D prints its floats to 7 significant digits.
                let close = |a: [f64; 3], b: [f64; 3]| {
                    a.iter()
                        .zip(b)
                        .all(|(x, y)| (x - y).abs() <= 1e-6 * y.abs().max(1e-3))
                };
                assert!(close(*p, truth.positions()[i]), "{encoding} point {i}");
                assert!(close(*n, normals[i]), "{encoding} normal {i}");
            } else {
                assert_eq!(*p, f32_of(truth.positions()[i]), "{encoding} point {i}");
                assert_eq!(*n, f32_of(normals[i]), "{encoding} normal {i}");
            }
        }
    }
}

/// A PCD field: `name size type count`.
type PcdField<'a> = (&'a str, usize, char, usize);

/// A binary PCD header for `fields` and `points` points.
fn pcd_header(fields: &[PcdField<'_>], points: usize, data: &str) -> Vec<u8> {
    let column =
        |f: &dyn Fn(&PcdField<'_>) -> String| fields.iter().map(f).collect::<Vec<_>>().join(" ");
    format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {}\nSIZE {}\nTYPE {}\n\
         COUNT {}\nWIDTH {points}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n",
        column(&|f| f.0.to_owned()),
        column(&|f| f.1.to_string()),
        column(&|f| f.2.to_string()),
        column(&|f| f.3.to_string()),
    )
    .into_bytes()
}

#[test]
fn binary_pcd_reads_every_field_type_and_skips_the_fields_it_does_not_use() {
    // x: signed 4 bytes, y: unsigned 2, z: signed 1 (sign extension), a 3-value colour field
    // between them and a double-precision normal after.
    let fields = [
        ("x", 4, 'I', 1),
        ("rgb", 1, 'U', 3),
        ("y", 2, 'U', 1),
        ("z", 1, 'I', 1),
        ("normal_x", 8, 'F', 1),
        ("normal_y", 8, 'F', 1),
        ("normal_z", 4, 'F', 1),
        ("_", 1, 'U', 2),
    ];
    let mut bytes = pcd_header(&fields, 2, "binary");
    for (x, y, z, n) in [
        (-5i32, 65_535u16, -128i8, [0.6, 0.8, 0.0f64]),
        (7, 3, 127, [0.0, 0.0, -1.0]),
    ] {
        bytes.extend(x.to_le_bytes());
        bytes.extend([9, 9, 9]);
        bytes.extend(y.to_le_bytes());
        bytes.extend(z.to_le_bytes());
        bytes.extend(n[0].to_le_bytes());
        bytes.extend(n[1].to_le_bytes());
        bytes.extend((n[2] as f32).to_le_bytes());
        bytes.extend([0, 0]);
    }
    let cloud = read("typed.pcd", &bytes);
    assert_eq!(
        cloud.positions(),
        &[[-5.0, 65_535.0, -128.0], [7.0, 3.0, 127.0]]
    );
    assert_eq!(
        cloud.normals().unwrap(),
        &[[0.6, 0.8, 0.0], [0.0, 0.0, -1.0]]
    );
}

#[test]
fn an_organised_cloud_leaves_out_its_gaps_in_every_encoding() {
    // A 3 × 2 depth image whose second and fifth pixels had no return (all NaN).
    let pixels: [[f32; 3]; 6] = [
        [0.0, 0.0, 1.0],
        [f32::NAN; 3],
        [1.0, 0.0, 1.5],
        [0.0, 1.0, 2.0],
        [f32::NAN; 3],
        [1.0, 1.0, 2.5],
    ];
    let kept: Vec<[f64; 3]> = pixels
        .iter()
        .filter(|p| !p[0].is_nan())
        .map(|p| p.map(f64::from))
        .collect();
    let header = |data: &str| {
        format!(
            "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 2\n\
             POINTS 6\nDATA {data}\n"
        )
        .into_bytes()
    };
    let mut ascii = header("ascii");
    for p in pixels {
        ascii.extend(format!("{} {} {}\n", p[0], p[1], p[2]).bytes());
    }
    let mut binary = header("binary");
    // Field by field for the compressed encoding: every x, every y, every z.
    let mut columns = Vec::new();
    for p in pixels {
        binary.extend(p.iter().flat_map(|v| v.to_le_bytes()));
    }
    for axis in 0..3 {
        columns.extend(pixels.iter().flat_map(|p| p[axis].to_le_bytes()));
    }
    let compressed_of = |raw: &[u8]| lzf::compress(raw).unwrap();
    let packed = compressed_of(&columns);
    let mut compressed = header("binary_compressed");
    compressed.extend((packed.len() as u32).to_le_bytes());
    compressed.extend((columns.len() as u32).to_le_bytes());
    compressed.extend(&packed);
    for (name, bytes) in [("a", ascii), ("b", binary), ("c", compressed)] {
        let cloud = read(&format!("{name}.pcd"), &bytes);
        assert_eq!(cloud.positions(), kept.as_slice(), "{name}");
        assert!(cloud.normals().is_none());
    }
    // A gap is all three coordinates: one NaN alone is a bad value, named.
    let e = read_err(
        "half.pcd",
        [
            header("ascii"),
            b"0 0 1\nnan 2 3\n1 0 1\n0 1 2\n1 1 2\n2 2 2\n".to_vec(),
        ]
        .concat(),
    );
    assert!(
        matches!(
            &e,
            Error::NonFinite {
                record: 1,
                line: Some(11),
                field: "x",
                ..
            }
        ),
        "{e}"
    );
    let e = read_err(
        "empty.pcd",
        [header("ascii"), "nan nan nan\n".repeat(6).into_bytes()].concat(),
    );
    assert!(
        e.to_string().contains("every one of its 6 points has NaN"),
        "{e}"
    );
}

/// The message of reading `text` as a `.pcd` file, checked to name `line` when given.
fn pcd_error(text: &[u8], line: Option<usize>) -> String {
    let e = read_err("bad.pcd", text);
    if let Some(line) = line {
        assert!(
            matches!(&e, Error::Malformed { line: Some(l), .. } if *l == line),
            "expected line {line}: {e}"
        );
    }
    e.to_string()
}

#[test]
fn bad_pcd_files_are_named_errors_not_panics_or_huge_allocations() {
    let xyz = [("x", 4, 'F', 1), ("y", 4, 'F', 1), ("z", 4, 'F', 1)];
    // Truncated binary: 3 records announced, 2 and a half there.
    let mut bytes = pcd_header(&xyz, 3, "binary");
    bytes.extend([0u8; 30]);
    let e = read_err("short.pcd", &bytes);
    assert!(
        matches!(
            &e,
            Error::Truncated {
                expected: 3,
                got: 2,
                ..
            }
        ),
        "{e}"
    );
    // A count no file holds answers at once, in each encoding.
    for data in ["binary", "ascii", "binary_compressed"] {
        let mut bytes = pcd_header(&xyz, 1 << 40, data);
        bytes.extend(b"0 0 0\n");
        let e = read_err("huge.pcd", &bytes);
        let message = e.to_string();
        let expected = match data {
            "binary" => matches!(e, Error::Truncated { got: 0, .. }),
            "ascii" => matches!(e, Error::Truncated { got: 1, .. }),
            // The 6 bytes after the header are too few for the block's two sizes.
            _ => message.contains("before its two sizes"),
        };
        assert!(expected, "{data}: {message}");
    }
    // Many fields of the largest COUNT: the values a line must hold are counted, never
    // allocated for (this aborted on a 160 GB allocation before).
    let mut fields = xyz.to_vec();
    let names: Vec<String> = (0..3000).map(|i| format!("f{i}")).collect();
    fields.extend(names.iter().map(|n| (n.as_str(), 4, 'F', 1 << 20)));
    let message = pcd_error(
        &[pcd_header(&fields, 1, "ascii"), b"1 2 3\n".to_vec()].concat(),
        Some(12),
    );
    assert!(message.contains("found 3"), "{message}");
    // WIDTH × HEIGHT and POINTS disagree.
    let message = pcd_error(
        b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nHEIGHT 1\nPOINTS 2\nDATA ascii\n",
        Some(7),
    );
    assert!(message.contains("WIDTH × HEIGHT = 3 × 1"), "{message}");
    // ASCII ends early, a short line, a word.
    let mut ascii = pcd_header(&xyz, 3, "ascii");
    ascii.extend(b"0 0 0\n1 1 1\n");
    assert!(matches!(
        read_err("a.pcd", &ascii),
        Error::Truncated {
            expected: 3,
            got: 2,
            ..
        }
    ));
    let mut ascii = pcd_header(&xyz, 2, "ascii");
    ascii.extend(b"0 0 0\n1 1\n");
    let message = pcd_error(&ascii, Some(13));
    assert!(message.contains("expected 3 values"), "{message}");
    // A line of a million values is refused at the fourth (the line is not held as numbers).
    let mut ascii = pcd_header(&xyz, 1, "ascii");
    ascii.extend("1 ".repeat(1_000_000).as_bytes());
    ascii.push(b'\n');
    let message = pcd_error(&ascii, Some(12));
    assert!(
        message.contains("expected 3 values") && message.contains("found more"),
        "{message}"
    );
    let mut ascii = pcd_header(&xyz, 1, "ascii");
    ascii.extend(b"0 zero 0\n");
    assert!(pcd_error(&ascii, Some(12)).contains("not a number: 'zero'"));
    // Corrupt LZF data, and sizes that do not add up.
    let mut compressed = pcd_header(&xyz, 2, "binary_compressed");
    compressed.extend(6u32.to_le_bytes());
    compressed.extend(24u32.to_le_bytes());
    compressed.extend([0xff; 6]);
    assert!(pcd_error(&compressed, None).contains("does not decompress"));
    let mut compressed = pcd_header(&xyz, 2, "binary_compressed");
    compressed.extend(6u32.to_le_bytes());
    compressed.extend(20u32.to_le_bytes());
    compressed.extend([0; 6]);
    assert!(pcd_error(&compressed, None).contains("take 24"));
    let mut compressed = pcd_header(&xyz, 2, "binary_compressed");
    compressed.extend(600u32.to_le_bytes());
    compressed.extend(24u32.to_le_bytes());
    compressed.extend([0; 6]);
    assert!(matches!(
        read_err("c.pcd", &compressed),
        Error::Truncated { .. }
    ));
    let mut compressed = pcd_header(&xyz, 2, "binary_compressed");
    compressed.extend([1, 0]);
    assert!(pcd_error(&compressed, None).contains("before its two sizes"));
    // Headers.
    let header = |lines: &str| format!("VERSION 0.7\n{lines}\n").into_bytes();
    for (lines, line, says) in [
        (
            "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nPOINTS 1\nDATA ascii",
            3,
            "SIZE has 2 entries for 3",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F D\nPOINTS 1\nDATA ascii",
            4,
            "TYPE 'D'",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nPOINTS 1\nDATA ascii",
            3,
            "SIZE 3",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS -1\nDATA ascii",
            5,
            "POINTS '-1'",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA ascii",
            5,
            "neither POINTS",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA lzma",
            6,
            "DATA 'lzma'",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1",
            6,
            "without a 'DATA' line",
        ),
        (
            "SIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA ascii",
            5,
            "no FIELDS",
        ),
    ] {
        let message = pcd_error(&header(lines), Some(line));
        assert!(message.contains(says), "{lines:?}: {message}");
    }
    let message = pcd_error(b"ply\nformat ascii 1.0\n", Some(1));
    assert!(message.contains("not a PCD file"), "{message}");
    // Missing coordinates, a normal in part, a coordinate with several values.
    let e = read_err(
        "noz.pcd",
        [pcd_header(&xyz[..2], 1, "ascii"), b"0 0\n".to_vec()].concat(),
    );
    assert!(
        e.to_string().contains("PCD has no field 'z' (FIELDS x y)"),
        "{e}"
    );
    let fields = [
        xyz[0],
        xyz[1],
        xyz[2],
        ("normal_x", 4, 'F', 1),
        ("normal_y", 4, 'F', 1),
    ];
    let e = read_err(
        "nonz.pcd",
        [pcd_header(&fields, 1, "ascii"), b"0 0 0 1 0\n".to_vec()].concat(),
    );
    assert!(e.to_string().contains("no field 'normal_z'"), "{e}");
    let fields = [("x", 4, 'F', 2), xyz[1], xyz[2]];
    let message = pcd_error(
        &[pcd_header(&fields, 1, "ascii"), b"0 0 0 0\n".to_vec()].concat(),
        None,
    );
    assert!(message.contains("COUNT 2"), "{message}");
}

#[test]
fn a_pcd_file_is_told_by_its_header_whatever_its_name() {
    let bytes = fs::read(data("bunny300_binary.pcd")).unwrap();
    let (_dir, path) = temp_file("scan.dat", &bytes);
    assert_eq!(detect_format(&path).unwrap(), Format::Pcd);
    assert_eq!(read_point_cloud(&path).unwrap().len(), 300);
}

#[test]
fn a_first_line_of_names_places_the_coordinates_and_the_normal() {
    // Any order, any case; colour columns before the normal (CloudCompare's order).
    let cloud = read(
        "cc.txt",
        "//X,Y,Z,R,G,B,Nx,Ny,Nz\n1,2,3,255,0,10,0,0,1\n4,5,6,0,0,0,0,1,0\n",
    );
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(
        cloud.normals().unwrap(),
        &[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]
    );
    let cloud = read("o.xyz", "nz ny nx z y x\n1 0 0 3 2 1\n");
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0]]);
    assert_eq!(cloud.normals().unwrap(), &[[0.0, 0.0, 1.0]]);
    let cloud = read(
        "pcl.txt",
        "x y z normal_x normal_y normal_z curvature\n0 0 0 0 0 1 0.2\n",
    );
    assert_eq!(cloud.normals().unwrap(), &[[0.0, 0.0, 1.0]]);
    // Named normals are read as they are, like PLY's: no guess about their lengths.
    let cloud = read("long.xyz", "x y z nx ny nz\n0 0 0 0 0 3\n");
    assert_eq!(cloud.normals().unwrap(), &[[0.0, 0.0, 3.0]]);
    // Without normal names, the rest is not a normal, even where it would look like one.
    let cloud = read("x.xyz", "X Y Z a b c\n0 0 0 0 0 1\n");
    assert!(cloud.normals().is_none());
    // A name with a space, between separators; a pandas index column (empty name).
    let cloud = read("sf.txt", "//X;Y;Z;Scalar field\n1;2;3;0.5\n");
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0]]);
    let cloud = read("pandas.txt", ",x,y,z\n0,1,2,3\n1,4,5,6,\n");
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    // What is wrong with a header line, named.
    let e = read_err("noz.xyz", "x y w\n0 0 0\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(1), reason, .. }
            if reason.contains("no column 'z'") && reason.contains("x y w")),
        "{e}"
    );
    let e = read_err("part.xyz", "x y z nx ny\n0 0 0 0 1\n");
    assert!(e.to_string().contains("no column 'nz'"), "{e}");
    let e = read_err("count.xyz", "x y z nx ny nz\n0 0 0 0 0 1\n0 0 0\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(3), reason, .. }
            if reason.contains("expected 6 numbers (one per name on line 1), found 3")),
        "{e}"
    );
    // Names only on the first line: a word later is still an error.
    let e = read_err("late.xyz", "0 0 0\nx y z\n");
    assert!(e.to_string().contains("not a number: 'x'"), "{e}");
}

#[test]
fn text_points_with_an_intensity_column_or_semicolons_read_their_positions() {
    let cloud = read("i.xyz", "0 0 0 0.5\n1 1 1 0.7\n");
    assert_eq!(cloud.positions(), &[[0.0; 3], [1.0; 3]]);
    assert!(cloud.normals().is_none());
    let cloud = read("il.xyz", "0 0 0 0.5 3\n");
    assert_eq!(cloud.positions(), &[[0.0; 3]]);
    let cloud = read("s.txt", "1.5;2;3;0;0;1\n");
    assert_eq!(cloud.positions(), &[[1.5, 2.0, 3.0]]);
    assert_eq!(cloud.normals().unwrap(), &[[0.0, 0.0, 1.0]]);
    assert_eq!(Format::from_path("scan.asc"), Some(Format::Xyz));
    assert_eq!(Format::from_path("oni.PWN"), Some(Format::Xyz));
    // Decimal commas are refused, never read as more numbers.
    let e = read_err("eu.txt", "1,5;2,0;3,25\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(1), reason, .. } if reason.contains("decimal commas")),
        "{e}"
    );
}

#[test]
fn csv_tables_separated_by_semicolons_or_tabs_and_pcl_normal_names() {
    let cloud = read(
        "s.csv",
        "# exported\nX;Y;Z;normal_x;normal_y;normal_z\n1;2;3;0;1;0\n",
    );
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0]]);
    assert_eq!(cloud.normals().unwrap(), &[[0.0, 1.0, 0.0]]);
    let cloud = read("t.csv", "x\ty\tz\n1\t2\t3\n");
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0]]);
    let e = read_err("eu.csv", "x;y;z\n1,5;2;3\n");
    assert!(e.to_string().contains("decimal commas are not read"), "{e}");
    // Quoted in a comma-separated file (a spreadsheet's export), and a quoted word is not.
    let e = read_err("q.csv", "x,y,z\n\"735484,81\",2,3\n");
    assert!(e.to_string().contains("decimal commas are not read"), "{e}");
    let e = read_err("w.csv", "x,y,z\n\"a,b\",2,3\n");
    assert!(!e.to_string().contains("decimal commas"), "{e}");
    let e = read_err("part.csv", "x,y,z,normal_x,normal_y\n0,0,0,0,1\n");
    assert!(
        matches!(&e, Error::MissingColumn { column, .. } if column == "normal_z"),
        "{e}"
    );
}

#[test]
fn ply_files_from_pcl_name_their_normals_normal_x() {
    let cloud = read(
        "pcl.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         property float z\nproperty float normal_x\nproperty float normal_y\n\
         property float normal_z\nproperty float curvature\nend_header\n0 0 0 0 0 1 0.5\n",
    );
    assert_eq!(cloud.normals().unwrap(), &[[0.0, 0.0, 1.0]]);
    let e = read_err(
        "part.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         property float z\nproperty float normal_x\nend_header\n0 0 0 1\n",
    );
    assert!(
        matches!(
            e,
            Error::MissingProperty {
                property: "normal_y",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn a_non_finite_normal_is_named_as_the_file_names_it() {
    let field = |e: Error| match e {
        Error::NonFinite { field, .. } => field,
        other => panic!("expected NonFinite, got {other}"),
    };
    let ply = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
               property float z\nproperty float normal_x\nproperty float normal_y\n\
               property float normal_z\nend_header\n0 0 0 0 nan 1\n";
    assert_eq!(field(read_err("pcl.ply", ply)), "normal_y");
    let plain = ply.replace("normal_", "n");
    assert_eq!(field(read_err("plain.ply", plain)), "ny");
    let pcd = pcd_header(
        &[
            ("x", 4, 'F', 1),
            ("y", 4, 'F', 1),
            ("z", 4, 'F', 1),
            ("normal_x", 4, 'F', 1),
            ("normal_y", 4, 'F', 1),
            ("normal_z", 4, 'F', 1),
        ],
        1,
        "ascii",
    );
    let mut pcd = pcd;
    pcd.extend_from_slice(b"0 0 0 0 0 inf\n");
    assert_eq!(field(read_err("pcl.pcd", pcd)), "normal_z");
    assert_eq!(
        field(read_err(
            "named.csv",
            "x,y,z,normal_x,normal_y,normal_z\n0,0,0,nan,0,1\n"
        )),
        "normal_x"
    );
    assert_eq!(
        field(read_err(
            "named.xyz",
            "X Y Z Normal_X Normal_Y Normal_Z\n0 0 0 0 nan 1\n"
        )),
        "normal_y"
    );
    assert_eq!(field(read_err("plain.xyzn", "0 0 0 0 nan 1\n")), "ny");
}

/// `points` written by the `las` crate as LAS 1.4, point format 1
/// (GPS time), georeferenced: millimetre scale about a UTM-like offset. Points whose index is
/// in `withheld` carry the withheld flag.
fn las_bytes(points: &[[f64; 3]], withheld: &[usize]) -> Vec<u8> {
    use las::{Builder, Point, Transform, Vector, Writer};
    let mut builder = Builder::from((1, 4));
    builder.point_format = las::point::Format::new(1).unwrap();
    let transform = |offset| Transform {
        scale: 0.001,
        offset,
    };
    builder.transforms = Vector {
        x: transform(512_000.0),
        y: transform(4_101_000.0),
        z: transform(0.0),
    };
    let mut writer = Writer::new(
        std::io::Cursor::new(Vec::new()),
        builder.into_header().unwrap(),
    )
    .unwrap();
    for (i, p) in points.iter().enumerate() {
        writer
            .write_point(Point {
                x: p[0],
                y: p[1],
                z: p[2],
                gps_time: Some(i as f64),
                is_withheld: withheld.contains(&i),
                ..Default::default()
            })
            .unwrap();
    }
    writer.into_inner().unwrap().into_inner()
}

#[test]
fn laspy_written_las_and_laz_read_as_the_points_they_were_written_from() {
    let truth = read_point_cloud(data("bunny300.xyzn")).unwrap();
    let las = read_point_cloud(data("bunny300.las")).unwrap();
    assert_eq!(las.len(), 300);
    // The LAZ (another point format, compressed) holds the same integers.
    let laz = read_point_cloud(data("bunny300.laz")).unwrap();
    assert_eq!(laz.positions(), las.positions());
    assert!(laz.normals().is_none() && las.normals().is_none());
    // LAS 1.4's point format 6, compressed by LASzip's layered chunks.
    let layered = read_point_cloud(data("bunny300_14.laz")).unwrap();
    assert_eq!(layered.positions(), las.positions());
    for (got, want) in las.positions().iter().zip(truth.positions()) {
        // Stored as whole multiples of the scale, 10⁻⁷: within half of it.
        for a in 0..3 {
            assert!(
                (got[a] - want[a]).abs() <= 0.5e-7 + 1e-15,
                "{got:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn las_normals_in_extra_bytes_are_read_as_their_description_says() {
    let truth = read_point_cloud(data("bunny300.xyzn")).unwrap();
    let positions = read_point_cloud(data("bunny300.las")).unwrap();
    // PDAL's names, float32, after a `Curvature` field (LAS 1.4).
    let pdal = read_point_cloud(data("bunny300_normals.las")).unwrap();
    // `nx ny nz` as int16 scaled by 1/30000 after a uint8 field, in a LAZ.
    let scaled = read_point_cloud(data("bunny300_normals.laz")).unwrap();
    for (cloud, within) in [(&pdal, 1e-7), (&scaled, 0.5 / 30000.0 + 1e-12)] {
        assert_eq!(cloud.positions(), positions.positions());
        let normals = cloud.normals().expect("the normals in the extra bytes");
        for (got, want) in normals.iter().zip(truth.normals().unwrap()) {
            for a in 0..3 {
                assert!((got[a] - want[a]).abs() <= within, "{got:?} vs {want:?}");
            }
        }
    }
    // Positions only: the normals are not read.
    let options = ReadOptions::default().with_positions_only(true);
    let (_d, path) = temp_file(
        "p.las",
        std::fs::read(data("bunny300_normals.las")).unwrap(),
    );
    assert!(
        read_point_cloud_with(&path, &options)
            .unwrap()
            .normals()
            .is_none()
    );

    // Crafted descriptions: the bytes of the fixture with its Extra Bytes record edited. A
    // set in part (`NormalZ` renamed), or normals placed past the 16 extra bytes each point
    // carries (`Curvature` said to be a double, 8 bytes, not 4): the positions, no normals.
    let bytes = std::fs::read(data("bunny300_normals.las")).unwrap();
    let find = |name: &[u8]| bytes.windows(name.len()).position(|w| w == name).unwrap();
    let mut partial = bytes.clone();
    partial[find(b"NormalZ") + 6] = b'Q';
    let mut wide = bytes.clone();
    wide[find(b"Curvature") - 2] = 10;
    for (what, crafted) in [("partial", partial), ("wide", wide)] {
        let (_d, path) = temp_file("crafted.las", crafted);
        let cloud = read_point_cloud(&path).unwrap();
        assert_eq!(cloud.positions(), positions.positions(), "{what}");
        assert!(cloud.normals().is_none(), "{what}");
    }
    // A file without the record reads positions only, as before.
    let mut unnamed = bytes.clone();
    for name in [&b"NormalX"[..], b"NormalY", b"NormalZ"] {
        let at = find(name);
        unnamed[at..at + 7].copy_from_slice(b"Other_1");
    }
    let (_d, path) = temp_file("unnamed.las", unnamed);
    assert!(read_point_cloud(&path).unwrap().normals().is_none());
}

/// The byte where `laz`'s LASzip VLR data starts.
fn laszip_record(laz: &[u8]) -> usize {
    let u16_at = |i: usize| u16::from_le_bytes([laz[i], laz[i + 1]]) as usize;
    let (mut at, count) = (u16_at(94), u16_at(100));
    for _ in 0..count {
        if laz[at + 2..].starts_with(b"laszip encoded") && u16_at(at + 18) == 22204 {
            return at + 54;
        }
        at += 54 + u16_at(at + 20);
    }
    panic!("no LASzip VLR");
}

#[test]
fn crafted_laz_files_are_refused_before_the_decoder_sizes_anything_by_them() {
    let laz = fs::read(data("bunny300.laz")).unwrap();
    let vlr = laszip_record(&laz);
    let start = u32::from_le_bytes(laz[96..100].try_into().unwrap()) as usize;
    let table = i64::from_le_bytes(laz[start..start + 8].try_into().unwrap()) as usize;
    let reason = |bytes: Vec<u8>| match read_err("crafted.laz", bytes) {
        Error::Malformed { reason, .. } => reason,
        other => panic!("expected Malformed, got {other}"),
    };
    // No items (the decoder's `expect` on the first item).
    let mut none = laz.clone();
    none[vlr + 32..vlr + 34].copy_from_slice(&0u16.to_le_bytes());
    assert!(reason(none).contains("lists 0 items"));
    // A chunk table of 2³² − 1 chunks (64 GB of entries).
    let mut chunks = laz.clone();
    chunks[table + 4..table + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(reason(chunks).contains("chunk table lists 4294967295 chunks"));
    // A chunk table past the end, and items that do not make up the record.
    let mut past = laz.clone();
    past[start..start + 8].copy_from_slice(&(laz.len() as i64 + 100).to_le_bytes());
    assert!(reason(past).contains("past the file's end"));
    let mut sizes = laz.clone();
    sizes[vlr + 34 + 2] ^= 1;
    assert!(reason(sizes).contains("bytes a point, the header's record length"));
    // Cut inside the VLRs, before the LASzip record: said so, not "no LASzip record".
    let header = u16::from_le_bytes([laz[94], laz[95]]) as usize;
    let reason_cut = reason(laz[..header + 10].to_vec());
    assert!(
        reason_cut.contains("the file ends inside VLR 0"),
        "{reason_cut}"
    );
    // Cut anywhere in the points: an error naming the file, never a panic.
    for cut in [
        start + 8,
        start + 100,
        (start + table) / 2,
        table,
        laz.len() - 3,
    ] {
        let e = read_err("cut.laz", &laz[..cut]);
        assert!(e.to_string().contains("cut.laz"), "{cut}: {e}");
    }
}

#[test]
fn las_reads_georeferenced_points_exactly_without_the_withheld_ones() {
    // Whole millimetres, as the scale stores them.
    let points: Vec<[f64; 3]> = (0..70_000)
        .map(|i| {
            let (a, b) = ((i % 300) as f64, (i / 300) as f64);
            [
                512_345.0 + a * 0.25,
                4_101_234.0 + b * 0.125,
                100.0 + (a * b) * 0.001,
            ]
        })
        .collect();
    let withheld = [3, 65_540];
    let kept: Vec<[f64; 3]> = points
        .iter()
        .enumerate()
        .filter(|(i, _)| !withheld.contains(i))
        .map(|(_, p)| *p)
        .collect();
    for name in ["scan.las", "SCAN.LAS"] {
        let (_dir, path) = temp_file(name, las_bytes(&points, &withheld));
        assert_eq!(detect_format(&path).unwrap(), Format::Las);
        let cloud = read_point_cloud(&path).unwrap();
        assert!(cloud.normals().is_none());
        assert_eq!(cloud.len(), kept.len(), "{name}");
        for (got, want) in cloud.positions().iter().zip(&kept) {
            for a in 0..3 {
                assert!(
                    (got[a] - want[a]).abs() < 1e-6,
                    "{name}: {got:?} vs {want:?}"
                );
            }
        }
    }
    // Told by its magic `LASF` under another name.
    let (_dir, path) = temp_file("scan.bin", las_bytes(&points[..10], &[]));
    assert_eq!(detect_format(&path).unwrap(), Format::Las);
}

#[test]
fn bad_las_files_are_named_errors() {
    let points: Vec<[f64; 3]> = (0..1000)
        .map(|i| [512_000.0 + i as f64, 4_101_000.0, 0.0])
        .collect();
    let bytes = las_bytes(&points, &[]);
    let e = read_err("cut.las", &bytes[..bytes.len() * 2 / 3]);
    assert!(matches!(e, Error::Truncated { expected: 1000, .. }), "{e}");
    // A header that announces far more points than the file holds answers at once.
    let mut bytes = las_bytes(&points, &[]);
    // The legacy 32-bit point count at byte 107, LAS 1.4's 64-bit one at byte 247.
    bytes[107..111].copy_from_slice(&u32::MAX.to_le_bytes());
    bytes[247..255].copy_from_slice(&(1u64 << 40).to_le_bytes());
    let e = read_err("huge.las", &bytes);
    assert!(matches!(e, Error::Truncated { .. }), "{e}");
    let e = read_err("text.las", "LASF but not really a LAS file\n");
    assert!(
        e.to_string()
            .contains("a LAS header takes at least 227 bytes, the file has 31"),
        "{e}"
    );
    let e = read_err("words.las", "not a LAS file at all\n");
    assert!(e.to_string().contains("signature LASF"), "{e}");
}

#[test]
fn what_an_independent_review_found_reads_or_is_refused_as_it_should() {
    // PCD older than v0.7 may leave SIZE and TYPE out: 4-byte floats, as PCL reads them.
    let cloud = read(
        "v5.pcd",
        "FIELDS x y z\nPOINTS 2\nDATA ascii\n0 0 1\n1 2 3\n",
    );
    assert_eq!(cloud.positions(), &[[0.0, 0.0, 1.0], [1.0, 2.0, 3.0]]);
    // Decimal commas between spaces are refused, not read as more columns.
    let e = read_err("eu.xyz", "0,5 1,25 2\n");
    assert!(e.to_string().contains("decimal commas"), "{e}");
    // A mistyped number on the first line is a number's error, not a header's.
    for (text, word) in [("1e 2 3\n", "'1e'"), ("- 2 3\n", "'-'"), (". 2 3\n", "'.'")] {
        let e = read_err("typo.xyz", text);
        assert!(
            e.to_string().contains(&format!("not a number: {word}")),
            "{e}"
        );
    }
    // Quoted names, and separators inside quotes do not pick the CSV delimiter.
    let cloud = read("q.txt", "\"x\",\"y\",\"z\"\n1,2,3\n");
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0]]);
    let cloud = read("q.csv", "x,y,z,\"note; a; b; c\"\n1,2,3,n\n");
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0]]);
}

#[test]
fn las_1_4_with_an_extended_vlr_reads_and_crafted_lengths_are_refused_before_any_allocation() {
    let path = data("bunny300_14.las");
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.len(), 300);
    assert_eq!(
        cloud.positions(),
        read_point_cloud(data("bunny300.las")).unwrap().positions()
    );
    let bytes = fs::read(&path).unwrap();
    let u64_at = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
    // The extended VLR's length (at its byte 20) set to 2⁶²: the `las` crate would allocate it.
    let evlr = usize::try_from(u64_at(235)).unwrap();
    let mut crafted = bytes.clone();
    crafted[evlr + 20..evlr + 28].copy_from_slice(&(1u64 << 62).to_le_bytes());
    let e = read_err("evlr.las", &crafted);
    assert!(e.to_string().contains("extended VLR 0 claims"), "{e}");
    // The 64-bit point count set to 2⁶⁰: its product with the record length overflows.
    let mut crafted = bytes.clone();
    crafted[247..255].copy_from_slice(&(1u64 << 60).to_le_bytes());
    let e = read_err("count.las", &crafted);
    assert!(matches!(e, Error::Truncated { .. }), "{e}");
    // Not LAS at all under the extension.
    let e = read_err("x.las", [b"PLYF".as_slice(), &[0u8; 400]].concat());
    assert!(e.to_string().contains("signature LASF"), "{e}");
}

/// Points within `tol` of the truth, in order (and normals, if `normals`).
fn assert_close(cloud: &PointCloud3, truth: &PointCloud3, tol: f64, normals: bool) {
    assert_eq!(cloud.len(), truth.len());
    for (got, want) in cloud.positions().iter().zip(truth.positions()) {
        for a in 0..3 {
            assert!((got[a] - want[a]).abs() <= tol, "{got:?} vs {want:?}");
        }
    }
    if normals {
        let (got, want) = (cloud.normals().unwrap(), truth.normals().unwrap());
        for (g, w) in got.iter().zip(want) {
            for a in 0..3 {
                // f32 components, rotated: within a few f32 ulps of 1.
                assert!((g[a] - w[a]).abs() <= 1e-6, "{g:?} vs {w:?}");
            }
        }
    }
}

#[test]
fn libe57_written_files_read_as_the_points_they_were_written_from() {
    let truth = read_point_cloud(data("bunny300.xyzn")).unwrap();
    // Two scans, the second under a pose, stored as integers scaled by 1e-7 with four invalid
    // records among them: each point within the scale (rotated) of the truth, normals rotated
    // back with it, the invalid records left out.
    let scans = read_point_cloud(data("bunny300.e57")).unwrap();
    assert_eq!(detect_format(data("bunny300.e57")).unwrap(), Format::E57);
    assert_close(&scans, &truth, 2e-7, true);
    // Spherical coordinates seen from a scanner under a pose, three invalid records.
    let spherical = read_point_cloud(data("bunny300_spherical.e57")).unwrap();
    assert!(spherical.normals().is_none());
    assert_close(&spherical, &truth, 1e-12, false);
    // Told by its magic `ASTM-E57` under another name.
    let (_dir, path) = temp_file("scan.bin", fs::read(data("bunny300.e57")).unwrap());
    assert_eq!(detect_format(&path).unwrap(), Format::E57);
}

/// An E57 file written by the `e57` crate: one scan per entry of `scans`, each with its
/// prototype and records; `xml` may edit the XML section before it is written.
fn e57_bytes(
    scans: Vec<(Vec<e57::Record>, Vec<Vec<e57::RecordValue>>)>,
    xml: impl Fn(String) -> String,
) -> Vec<u8> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    {
        let mut writer = e57::E57Writer::new(&mut bytes, "{test}").unwrap();
        writer
            .register_extension(e57::Extension {
                namespace: "nor".into(),
                url: zeroset_field_core::io::e57::NORMALS_URI.into(),
            })
            .unwrap();
        for (i, (prototype, records)) in scans.into_iter().enumerate() {
            let mut pc = writer
                .add_pointcloud(&format!("{{scan {i}}}"), prototype)
                .unwrap();
            for r in records {
                pc.add_point(r).unwrap();
            }
            pc.finalize().unwrap();
        }
        writer.finalize_customized_xml(|x| Ok(xml(x))).unwrap();
    }
    bytes.into_inner()
}

fn normal_record(name: &str) -> e57::Record {
    e57::Record {
        name: e57::RecordName::Unknown {
            namespace: "nor".into(),
            name: name.into(),
        },
        data_type: e57::RecordDataType::F32,
    }
}

/// A scan of `n` points along a line, with normals if `normals`, its first x `first`.
fn e57_scan(n: usize, normals: bool, first: f64) -> (Vec<e57::Record>, Vec<Vec<e57::RecordValue>>) {
    use e57::{Record, RecordValue};
    let mut prototype = vec![
        Record::CARTESIAN_X_F64,
        Record::CARTESIAN_Y_F64,
        Record::CARTESIAN_Z_F64,
    ];
    if normals {
        prototype.extend(["normalX", "normalY", "normalZ"].map(normal_record));
    }
    let records = (0..n)
        .map(|i| {
            let mut r = vec![
                RecordValue::Double(if i == 0 { first } else { i as f64 }),
                RecordValue::Double(0.5),
                RecordValue::Double(-1.0),
            ];
            if normals {
                r.extend([0.0, 0.0, 1.0].map(RecordValue::Single));
            }
            r
        })
        .collect();
    (prototype, records)
}

/// A scan of 6 records with Cartesian and spherical coordinates and both invalid states:
/// record `i` is flagged in `cartesian[i]` and `spherical[i]`.
fn e57_flagged_scan(
    cartesian: [i64; 6],
    spherical: [i64; 6],
) -> (Vec<e57::Record>, Vec<Vec<e57::RecordValue>>) {
    use e57::{Record, RecordValue};
    let prototype = vec![
        Record::CARTESIAN_X_F64,
        Record::CARTESIAN_Y_F64,
        Record::CARTESIAN_Z_F64,
        Record::SPHERICAL_RANGE_F64,
        Record::SPHERICAL_AZIMUTH_F64,
        Record::SPHERICAL_ELEVATION_F64,
        Record::CARTESIAN_INVALID_STATE,
        Record::SPHERICAL_INVALID_STATE,
    ];
    let records = (0..6)
        .map(|i| {
            // A flagged record has no range: its coordinates are the scanner's origin.
            let r = if cartesian[i] == 0 && spherical[i] == 0 {
                2.0
            } else {
                0.0
            };
            let mut v = vec![r, 0.0, 0.0, r, 0.0, 0.0]
                .into_iter()
                .map(RecordValue::Double)
                .collect::<Vec<_>>();
            v.push(RecordValue::Integer(cartesian[i]));
            v.push(RecordValue::Integer(spherical[i]));
            v
        })
        .collect();
    (prototype, records)
}

#[test]
fn e57_records_flagged_in_either_coordinate_system_are_left_out() {
    let plain = |x: String| x;
    for (cartesian, spherical, kept) in [
        ([0, 1, 2, 0, 0, 0], [0; 6], 4),
        ([0; 6], [0, 1, 0, 2, 0, 0], 4),
        ([1, 0, 0, 0, 0, 0], [0, 2, 0, 0, 0, 0], 4),
        ([0; 6], [0; 6], 6),
    ] {
        let bytes = e57_bytes(vec![e57_flagged_scan(cartesian, spherical)], plain);
        let cloud = read("flagged.e57", bytes);
        assert_eq!(cloud.len(), kept, "{cartesian:?} {spherical:?}");
        assert!(
            cloud.positions().iter().all(|p| p[0] == 2.0),
            "{cartesian:?}"
        );
    }
}

#[test]
fn e57_poses_normalise_their_quaternion_whatever_its_scale() {
    // Half a turn about z, (0, 0, 0, s) for any scale s, then a shift of 10 along x.
    let posed = |w: &str, z: &str| {
        let pose = format!(
            "<pose type=\"Structure\"><rotation type=\"Structure\">\
             <w type=\"Float\">{w}</w><x type=\"Float\">0</x><y type=\"Float\">0</y>\
             <z type=\"Float\">{z}</z></rotation><translation type=\"Structure\">\
             <x type=\"Float\">10</x><y type=\"Float\">0</y><z type=\"Float\">0</z>\
             </translation></pose><points "
        );
        e57_bytes(vec![e57_scan(3, false, 0.0)], move |x| {
            x.replacen("<points ", &pose, 1)
        })
    };
    for scale in ["1", "1e300", "1e-200", "-3"] {
        let cloud = read("posed.e57", posed("0", scale));
        // the scan's points (0, 0.5, -1), (1, 0.5, -1), (2, 0.5, -1), turned and shifted
        assert_eq!(
            cloud.positions(),
            &[[10.0, -0.5, -1.0], [9.0, -0.5, -1.0], [8.0, -0.5, -1.0]],
            "scale {scale}"
        );
    }
    for (w, z) in [("0", "0"), ("NaN", "1"), ("1", "inf")] {
        let e = read_err("posed.e57", posed(w, z)).to_string();
        assert!(
            e.contains("scan 0's pose is not a rotation"),
            "({w}, {z}): {e}"
        );
    }
}

#[test]
fn e57_files_the_reader_cannot_use_are_named_errors() {
    let reason = |name: &str, bytes: Vec<u8>| match read_err(name, bytes) {
        Error::Malformed { reason, path, .. } => {
            assert!(path.ends_with(name));
            reason
        }
        other => panic!("{name}: expected Malformed, got {other}"),
    };
    let plain = |x: String| x;
    // The e57 crate's own writer, read back.
    let two = read(
        "two.e57",
        e57_bytes(vec![e57_scan(5, true, 0.0), e57_scan(4, true, 0.0)], plain),
    );
    assert_eq!((two.len(), two.normals().map(<[_]>::len)), (9, Some(9)));
    // Normals in some scans only.
    let mixed = e57_bytes(
        vec![
            e57_scan(5, true, 0.0),
            e57_scan(5, false, 0.0),
            e57_scan(3, true, 0.0),
        ],
        plain,
    );
    let e = read_err("mixed.e57", &mixed);
    assert!(
        matches!(&e, Error::PartialNormals { with, without, .. }
            if with == &[0, 2] && without == &[1]),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("scans 0, 2 have normals and scans 1 do not"),
        "{e}"
    );
    // Its positions are read (for `zeroset normals` to estimate the normals of every scan).
    let (_dir, path) = temp_file("mixed.e57", &mixed);
    let positions = ReadOptions::default().with_positions_only(true);
    let cloud = read_point_cloud_with(&path, &positions).unwrap();
    assert_eq!((cloud.len(), cloud.normals().is_none()), (13, true));
    // Fields named like normals under another namespace are not normals.
    let foreign = e57_bytes(vec![e57_scan(5, true, 0.0)], |x| {
        x.replace(
            zeroset_field_core::io::e57::NORMALS_URI,
            "http://example.com/other",
        )
    });
    assert!(read("foreign.e57", foreign).normals().is_none());
    // Two scans naming one binary section.
    let shared = e57_bytes(
        vec![e57_scan(5, false, 0.0), e57_scan(5, false, 0.0)],
        |x| {
            let offsets: Vec<&str> = x
                .split("fileOffset=\"")
                .skip(1)
                .map(|rest| &rest[..rest.find('"').unwrap()])
                .collect();
            x.replace(
                &format!("fileOffset=\"{}\"", offsets[1]),
                &format!("fileOffset=\"{}\"", offsets[0]),
            )
        },
    );
    assert!(reason("shared.e57", shared).contains("scans 0 and 1 name the same binary section"));
    // More records than the file's bytes can hold (each of these takes 24 bytes).
    let inflated = e57_bytes(vec![e57_scan(5, false, 0.0)], |x| {
        x.replace("recordCount=\"5\"", "recordCount=\"100000000\"")
    });
    let r = reason("inflated.e57", inflated);
    assert!(
        r.contains("announce 100000000 records, 2400000000 bytes of data"),
        "{r}"
    );
    // A scan whose records hold no coordinate the reader knows.
    let renamed = e57_bytes(vec![e57_scan(5, false, 0.0)], |x| {
        x.replace("cartesianX", "cartesianQ")
    });
    assert!(reason("renamed.e57", renamed).contains("scan 0 has neither Cartesian"));
    // No scan at all, and a NaN coordinate.
    assert!(reason("empty.e57", e57_bytes(vec![], plain)).contains("holds no point"));
    let e = read_err(
        "nan.e57",
        e57_bytes(vec![e57_scan(5, false, f64::NAN)], plain),
    );
    assert!(
        matches!(
            e,
            Error::NonFinite {
                record: 0,
                field: "x",
                ..
            }
        ),
        "{e}"
    );
    // A NaN normal: named as a normal, and not read (nor checked) for the positions alone.
    let (prototype, mut records) = e57_scan(5, true, 0.0);
    records[3][4] = e57::RecordValue::Single(f32::NAN);
    let (_dir, path) = temp_file(
        "nan_normal.e57",
        e57_bytes(vec![(prototype, records)], plain),
    );
    let e = read_point_cloud(&path).unwrap_err();
    assert!(
        matches!(
            e,
            Error::NonFinite {
                record: 3,
                field: "ny",
                ..
            }
        ),
        "{e}"
    );
    let positions = ReadOptions::default().with_positions_only(true);
    let cloud = read_point_cloud_with(&path, &positions).unwrap();
    assert_eq!((cloud.len(), cloud.normals().is_none()), (5, true));
    let scans = zeroset_field_core::io::e57::read_e57(&path, &positions).unwrap();
    assert_eq!((scans.scans.len(), scans.scans[0].points), (1, 5));
    // A changed byte breaks its page's checksum; a file cut anywhere is not whole pages.
    let good = fs::read(data("bunny300.e57")).unwrap();
    for at in [0, 100, 2000, good.len() / 2, good.len() - 10] {
        let mut bad = good.clone();
        bad[at] ^= 0x20;
        let e = read_err("flipped.e57", bad);
        assert!(e.to_string().contains("flipped.e57"), "{at}: {e}");
    }
    for cut in [4, 48, 1024, 5000, good.len() - 1] {
        let e = read_err("cut.e57", &good[..cut]);
        assert!(e.to_string().contains("cut.e57"), "{cut}: {e}");
    }
}
