//! Point-cloud readers and the atomic PLY writer, on the real files in the repository's `data/`
//! folder (see its README for provenance and the counts checked here) and on small broken files.
//!
//! The data directory is `$ZEROSET_DATA` if set, else `data/` at the workspace root, which ships
//! with the repository. If a file is missing the data tests fail: they never pass silently.

use std::fs;
use std::path::{Path, PathBuf};

use zeroset_field_core::io::gempy::{
    self, FormationCount, GeoModelData, orientation_normal, read_gempy, read_gempy_file,
    read_orientations, read_surface_points,
};
use zeroset_field_core::io::{
    Format, ReadOptions, detect_format, read_point_cloud, read_point_cloud_with, write_atomic,
    write_ply,
};
use zeroset_field_core::{CloudStats, Error, PointCloud3};

// ---------------------------------------------------------------------------------------------
// helpers

fn data_dir() -> PathBuf {
    let dir = match std::env::var_os("ZEROSET_DATA") {
        Some(d) => PathBuf::from(d),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data"),
    };
    assert!(
        dir.is_dir(),
        "test data directory {} not found: set ZEROSET_DATA to the folder holding \
         bun_zipper.ply, bunny_points.ply, bunny_2k.xyzn, kitten.xyz and geology/",
        dir.display()
    );
    dir
}

fn data(name: &str) -> PathBuf {
    let path = data_dir().join(name);
    assert!(
        path.is_file(),
        "test data file {} not found",
        path.display()
    );
    path
}

/// A file `name` holding `bytes` in a fresh temporary directory (kept alive by the guard).
fn temp_file(name: &str, bytes: impl AsRef<[u8]>) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    fs::write(&path, bytes).unwrap();
    (dir, path)
}

fn read_err(name: &str, bytes: impl AsRef<[u8]>) -> Error {
    let (_dir, path) = temp_file(name, bytes);
    match read_point_cloud(&path) {
        Ok(cloud) => panic!("{name}: expected an error, read {} points", cloud.len()),
        Err(e) => e,
    }
}

fn assert_all_finite(cloud: &PointCloud3) {
    let s = cloud.stats();
    assert_eq!(s.non_finite_positions, 0);
    assert_eq!(s.non_finite_normals, 0);
    cloud.validate("test").unwrap();
}

fn assert_unit_normals(cloud: &PointCloud3) {
    let s = cloud.stats();
    assert!(s.has_normals);
    assert_eq!(s.non_unit_normals, 0, "{s:?}");
    let (lo, hi) = s.normal_length_range.unwrap();
    let tol = CloudStats::<3>::UNIT_TOLERANCE;
    assert!(
        1.0 - tol <= lo && hi <= 1.0 + tol,
        "normal lengths in [{lo}, {hi}]"
    );
}

fn assert_close(a: [f64; 3], b: [f64; 3], tol: f64) {
    for i in 0..3 {
        assert!((a[i] - b[i]).abs() <= tol, "{a:?} vs {b:?}");
    }
}

fn counts(data: &GeoModelData) -> Vec<(String, usize, usize)> {
    data.formation_counts()
        .into_iter()
        .map(
            |FormationCount {
                 name,
                 surface_points,
                 orientations,
             }| (name, surface_points, orientations),
        )
        .collect()
}

// ---------------------------------------------------------------------------------------------
// real data: exact counts (see data/README.md)

/// The files are the ones the data README describes, byte for byte in size (a line-ending
/// conversion or a truncated checkout would change them), and the bundled sample is the same
/// file as the data folder's copy.
#[test]
fn data_files_have_the_sizes_their_readme_gives() {
    for (name, bytes) in [
        ("bun_zipper.ply", 3_033_195),
        ("bunny_points.ply", 836_383),
        ("bunny_2k.xyzn", 124_441),
        ("kitten.xyz", 302_220),
        (
            "geology/perth_basin/Paper_GU2F_sc_faults_topo_Points.csv",
            5_345,
        ),
        (
            "geology/perth_basin/Paper_GU2F_sc_faults_topo_Foliations.csv",
            2_072,
        ),
        ("geology/greenstone/SandStone_Points.csv", 3_212),
        ("geology/greenstone/SandStone_Foliations.csv", 2_602),
        ("geology/greenstone/Greenstone_surface_points.csv", 9_559),
        ("geology/greenstone/Greenstone_orientations.csv", 9_132),
    ] {
        let len = fs::metadata(data(name)).unwrap().len();
        assert_eq!(len, bytes, "{name}");
    }
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../samples/bunny_2k.xyzn");
    assert!(
        fs::read(sample).unwrap() == fs::read(data("bunny_2k.xyzn")).unwrap(),
        "samples/bunny_2k.xyzn and data/bunny_2k.xyzn differ"
    );
}

#[test]
fn bun_zipper_ascii_ply_reads_every_vertex_and_skips_faces() {
    let path = data("bun_zipper.ply");
    assert_eq!(detect_format(&path).unwrap(), Format::Ply);
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.len(), 35_947);
    assert!(cloud.normals().is_none());
    assert_all_finite(&cloud);
    let b = cloud.bounds().unwrap();
    assert_close(b.min(), [-0.0946899, 0.0329874, -0.0618736], 1e-7);
    assert_close(b.max(), [0.0610091, 0.1873210, 0.0587997], 1e-7);
    // First vertex, as printed in the file.
    assert_close(
        cloud.positions()[0],
        [-0.0378297, 0.12794, 0.00447467],
        1e-8,
    );
}

#[test]
fn bunny_points_binary_ply_has_unit_normals() {
    let path = data("bunny_points.ply");
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.len(), 34_834);
    assert_eq!(cloud.normals().unwrap().len(), 34_834);
    assert_all_finite(&cloud);
    assert_unit_normals(&cloud);
    let b = cloud.bounds().unwrap();
    assert_close(b.min(), [-0.0946899, 0.0329874, -0.0618736], 1e-7);
    assert_close(b.max(), [0.0610091, 0.1873210, 0.0587997], 1e-7);
}

#[test]
fn bunny_2k_xyzn_matches_the_binary_cloud() {
    let path = data("bunny_2k.xyzn");
    assert_eq!(detect_format(&path).unwrap(), Format::Xyz);
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.len(), 2_000);
    assert_all_finite(&cloud);
    assert_unit_normals(&cloud);
    assert_eq!(cloud.stats().duplicate_points, 0);
    let (lo, hi) = cloud.stats().normal_length_range.unwrap();
    assert!(
        lo >= 0.9999999 - 1e-9 && hi <= 1.0000001 + 1e-9,
        "[{lo}, {hi}]"
    );
    let b = cloud.bounds().unwrap();
    assert_close(b.min(), [-0.094668, 0.033380, -0.061841], 1e-6);
    assert_close(b.max(), [0.061004, 0.186115, 0.058004], 1e-6);
    // Every point is one of bunny_points.ply's (printed with 7 significant digits).
    let full = read_point_cloud(data("bunny_points.ply")).unwrap();
    let mut full_pos: Vec<[f64; 3]> = full.positions().to_vec();
    full_pos.sort_by(|a, b| a[0].total_cmp(&b[0]));
    for p in cloud.positions() {
        let i = full_pos.partition_point(|q| q[0] < p[0] - 1e-7);
        let found = full_pos[i..]
            .iter()
            .take_while(|q| q[0] <= p[0] + 1e-7)
            .any(|q| (0..3).all(|k| (q[k] - p[k]).abs() <= 1e-7));
        assert!(found, "{p:?} is not in bunny_points.ply");
    }
}

#[test]
fn kitten_xyz_has_5210_oriented_points() {
    let path = data("kitten.xyz");
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.len(), 5_210);
    assert_all_finite(&cloud);
    assert_unit_normals(&cloud);
    assert_eq!(cloud.stats().duplicate_points, 0);
    let b = cloud.bounds().unwrap();
    assert_close(b.min(), [-0.325311, -0.499731, -0.295610], 1e-6);
    assert_close(b.max(), [0.325692, 0.498900, 0.294955], 1e-6);
}

const PERTH: &str = "geology/perth_basin/Paper_GU2F_sc_faults_topo";

#[test]
fn perth_basin_tables() {
    let points = data(&format!("{PERTH}_Points.csv"));
    let foliations = data(&format!("{PERTH}_Foliations.csv"));
    assert_eq!(detect_format(&points).unwrap(), Format::GemPy);
    assert_eq!(detect_format(&foliations).unwrap(), Format::GemPy);

    let model = read_gempy(&points, &foliations).unwrap();
    assert_eq!(model.surface_points.len(), 103);
    assert_eq!(model.orientations.len(), 27);
    let expected: Vec<(&str, usize, usize)> = vec![
        ("Abrolhos_Transfer", 3, 2),
        ("Cadda", 1, 0),
        ("Cattamarra", 1, 1),
        ("Coomallo", 7, 2),
        ("Cretaceous", 14, 1),
        ("Darling", 5, 2),
        ("Eneabba", 5, 0),
        ("Eneabba_South", 6, 2),
        ("Hypo_fault_E", 3, 2),
        ("Hypo_fault_W", 3, 2),
        ("Lesueur", 9, 1),
        ("Permian", 22, 6),
        ("Urella_North", 3, 2),
        ("Urella_South", 3, 2),
        ("Woodada_Kockatea", 2, 1),
        ("Yarragadee", 16, 1),
    ];
    let expected: Vec<(String, usize, usize)> = expected
        .into_iter()
        .map(|(n, p, o)| (n.to_owned(), p, o))
        .collect();
    assert_eq!(counts(&model), expected);
    assert_eq!(model.formations().len(), 16);
    assert_eq!(model.formations()[0], "Abrolhos_Transfer");

    let b = model.surface_point_cloud().unwrap().bounds().unwrap();
    assert_close(b.min(), [337375.40, 6642333.0, -10480.34], 0.01);
    assert_close(b.max(), [398507.11, 6709119.0, 986.96], 0.01);
    assert!(model.orientations.iter().any(|o| o.polarity == -1.0));
    for o in &model.orientations {
        assert_eq!(o.normal, orientation_normal(o.dip, o.azimuth, o.polarity));
        assert!((0.0..=90.0).contains(&o.dip));
    }

    // Through read_point_cloud: orientations carry normals, surface points do not.
    let cloud = read_point_cloud(&foliations).unwrap();
    assert_eq!(cloud.len(), 27);
    assert_unit_normals(&cloud);
    let cloud = read_point_cloud(&points).unwrap();
    assert_eq!(cloud.len(), 103);
    assert!(cloud.normals().is_none());
    assert_all_finite(&cloud);
}

fn greenstone_counts() -> Vec<(String, usize, usize)> {
    [
        ("EarlyGranite", 27, 26),
        ("SimpleBIF", 15, 2),
        ("SimpleMafic1", 17, 13),
        ("SimpleMafic2", 11, 0),
    ]
    .into_iter()
    .map(|(n, p, o)| (n.to_owned(), p, o))
    .collect()
}

#[test]
fn greenstone_sandstone_tables() {
    let model = read_gempy(
        data("geology/greenstone/SandStone_Points.csv"),
        data("geology/greenstone/SandStone_Foliations.csv"),
    )
    .unwrap();
    assert_eq!(model.surface_points.len(), 70);
    assert_eq!(model.orientations.len(), 41);
    assert_eq!(counts(&model), greenstone_counts());
    assert_eq!(
        model.formations(),
        ["EarlyGranite", "SimpleBIF", "SimpleMafic1", "SimpleMafic2"]
    );
    // Two SimpleMafic1 rows have dip = -60; 26 of 41 dip 80.
    assert_eq!(
        model.orientations.iter().filter(|o| o.dip == -60.0).count(),
        2
    );
    assert_eq!(
        model.orientations.iter().filter(|o| o.dip == 80.0).count(),
        26
    );
    let b = model.surface_point_cloud().unwrap().bounds().unwrap();
    assert_close(b.min(), [697047.375, 6869214.0, -8458.17], 0.01);
    assert_close(b.max(), [745312.75, 6916017.0, 555.45], 0.01);
}

/// Parses GemPy's own `G_x, G_y, G_z` columns, to check [`orientation_normal`] against them.
fn gempy_gradients(path: &Path) -> Vec<[f64; 3]> {
    let text = fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (gx, gy, gz) = (col("G_x"), col("G_y"), col("G_z"));
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            [gx, gy, gz].map(|c| f[c].parse::<f64>().unwrap())
        })
        .collect()
}

#[test]
fn greenstone_model_tables_match_gempy_gradients_and_sandstone_files() {
    let points_path = data("geology/greenstone/Greenstone_surface_points.csv");
    let orient_path = data("geology/greenstone/Greenstone_orientations.csv");
    assert_eq!(detect_format(&points_path).unwrap(), Format::GemPy);
    assert_eq!(detect_format(&orient_path).unwrap(), Format::GemPy);
    let model = read_gempy(&points_path, &orient_path).unwrap();
    assert_eq!(model.surface_points.len(), 70);
    assert_eq!(model.orientations.len(), 41);
    assert_eq!(counts(&model), greenstone_counts());

    // Our normal formula against GemPy's gradient columns.
    let g = gempy_gradients(&orient_path);
    assert_eq!(g.len(), 41);
    for (o, g) in model.orientations.iter().zip(&g) {
        assert_close(o.normal, *g, 1e-9);
    }

    // Same data as the SandStone files, rows in another order.
    let sand = read_gempy(
        data("geology/greenstone/SandStone_Points.csv"),
        data("geology/greenstone/SandStone_Foliations.csv"),
    )
    .unwrap();
    let key = |p: &[f64; 3]| p.map(|v| (v * 1e3).round() as i64);
    let sorted = |mut v: Vec<([i64; 3], String)>| {
        v.sort();
        v
    };
    let a = sorted(
        model
            .surface_points
            .iter()
            .map(|p| (key(&p.position), p.formation.clone()))
            .collect(),
    );
    let b = sorted(
        sand.surface_points
            .iter()
            .map(|p| (key(&p.position), p.formation.clone()))
            .collect(),
    );
    assert_eq!(a, b);

    // read_gempy_file tells the tables apart by their header.
    let one = read_gempy_file(&orient_path).unwrap();
    assert_eq!((one.surface_points.len(), one.orientations.len()), (0, 41));
    let one = read_gempy_file(&points_path).unwrap();
    assert_eq!((one.surface_points.len(), one.orientations.len()), (70, 0));
    assert_eq!(read_surface_points(&points_path).unwrap().len(), 70);
    assert_eq!(read_orientations(&orient_path).unwrap().len(), 41);
}

// ---------------------------------------------------------------------------------------------
// GemPy conventions

#[test]
fn orientation_normal_follows_the_documented_convention() {
    // Dip 90° towards north (+y): horizontal normal along +y.
    assert_close(orientation_normal(90.0, 0.0, 1.0), [0.0, 1.0, 0.0], 1e-15);
    // Dip 90° towards east: +x.
    assert_close(orientation_normal(90.0, 90.0, 1.0), [1.0, 0.0, 0.0], 1e-15);
    // Flat: up, and down for polarity -1.
    assert_close(orientation_normal(0.0, 200.0, 1.0), [0.0, 0.0, 1.0], 1e-15);
    assert_close(
        orientation_normal(0.0, 200.0, -1.0),
        [0.0, 0.0, -1.0],
        1e-15,
    );
    // 45° towards south-west.
    let s = 0.5;
    assert_close(
        orientation_normal(45.0, 225.0, 1.0),
        [-s, -s, 0.5f64.sqrt()],
        1e-15,
    );
    for (dip, az) in [(10.0, 33.0), (-60.0, 300.0), (89.0, 181.0)] {
        let n = orientation_normal(dip, az, 1.0);
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-15);
    }
}

#[test]
fn gempy_header_detection() {
    assert!(gempy::is_gempy_header(&["X", "Y", "Z", "formation"]));
    assert!(gempy::is_gempy_header(&[
        "", "X", "Y", "Z", "surface", "series"
    ]));
    assert!(gempy::is_gempy_header(&[
        "x", "y", "z", "Dip", "Azimuth", "Polarity"
    ]));
    assert!(!gempy::is_gempy_header(&["x", "y", "z", "nx", "ny", "nz"]));
    assert!(!gempy::is_gempy_header(&["x", "y", "z", "dip"]));
    // Poles without a formation: a plain CSV, which reads them as normals.
    assert!(!gempy::is_gempy_header(&[
        "X", "Y", "Z", "G_x", "G_y", "G_z"
    ]));
    let (_d, path) = temp_file("poles.csv", "X,Y,Z,G_x,G_y,G_z\n1,2,3,0,0.6,0.8\n");
    assert_eq!(detect_format(&path).unwrap(), Format::Csv);
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.normals().unwrap(), &[[0.0, 0.6, 0.8]]);
}

#[test]
fn gempy_bad_tables() {
    let e = read_err(
        "o.csv",
        "X,Y,Z,azimuth,dip,polarity,formation\n0,0,0,10,20,0,A\n",
    );
    assert!(
        matches!(&e, Error::Malformed { line: Some(2), reason, .. } if reason.contains("polarity")),
        "{e}"
    );
    let (_d, path) = temp_file("p.csv", "X,Y,Z,formation\n0,0,0,\n");
    let e = read_surface_points(&path).unwrap_err();
    assert!(matches!(e, Error::Malformed { line: Some(2), .. }), "{e}");
    let (_d, path) = temp_file("p.csv", "X,Y,Z\n0,0,0\n");
    let e = read_surface_points(&path).unwrap_err();
    assert!(
        matches!(&e, Error::MissingColumn { column, .. } if column.contains("formation")),
        "{e}"
    );
    let (_d, path) = temp_file("o.csv", "X,Y,Z,dip,polarity,formation\n0,0,0,10,1,A\n");
    let e = read_orientations(&path).unwrap_err();
    assert!(
        matches!(&e, Error::MissingColumn { column, .. } if column == "azimuth (or G_x, G_y, G_z)"),
        "{e}"
    );
    // Angles without polarity (and without a formation) are a GemPy table that lacks it, not
    // a plain CSV whose angle columns are dropped.
    let (_d, path) = temp_file("o.csv", "X,Y,Z,dip,azimuth\n0,0,0,10,20\n");
    assert_eq!(detect_format(&path).unwrap(), Format::GemPy);
    let e = read_point_cloud(&path).unwrap_err();
    assert!(
        matches!(&e, Error::MissingColumn { column, .. } if column.starts_with("polarity")),
        "{e}"
    );
    let e = read_err("o.csv", "X,Y,Z,G_x,G_y,G_z,surface\n0,0,0,0,0,0,A\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(2), reason, .. } if reason.contains("zero vector")),
        "{e}"
    );
    let e = read_err(
        "o.csv",
        "X,Y,Z,azimuth,dip,polarity,formation\n0,0,0,10,nan,1,A\n",
    );
    assert!(
        matches!(
            e,
            Error::NonFinite {
                record: 0,
                line: Some(2),
                field: "dip",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn gempy_orientations_from_gradient_columns_alone_or_checked_against_the_angles() {
    // GemPy 3's orientation tables may carry the poles alone: the Greenstone table without its
    // angle columns reads the same normals, and the angles recovered give them back.
    let orient_path = data("geology/greenstone/Greenstone_orientations.csv");
    let full = read_orientations(&orient_path).unwrap();
    let mut text = String::from("X,Y,Z,G_x,G_y,G_z,surface\n");
    for (o, g) in full.iter().zip(gempy_gradients(&orient_path)) {
        let [x, y, z] = o.position;
        // Poles of any length.
        let [gx, gy, gz] = g.map(|c| 3.0 * c);
        text += &format!("{x},{y},{z},{gx},{gy},{gz},{}\n", o.formation);
    }
    let (_d, path) = temp_file("g.csv", &text);
    assert_eq!(detect_format(&path).unwrap(), Format::GemPy);
    let poles = read_orientations(&path).unwrap();
    assert_eq!(poles.len(), full.len());
    for (p, o) in poles.iter().zip(&full) {
        assert_close(p.normal, o.normal, 1e-9);
        assert_close(
            orientation_normal(p.dip, p.azimuth, p.polarity),
            o.normal,
            1e-9,
        );
        assert!((0.0..=90.0).contains(&p.dip) && (0.0..360.0).contains(&p.azimuth));
        assert_eq!(p.formation, o.formation);
    }
    let cloud = read_point_cloud(&path).unwrap();
    assert_close(cloud.normals().unwrap()[7], full[7].normal, 1e-9);
    // Both, disagreeing: refused, naming the line.
    let e = read_err(
        "o.csv",
        "X,Y,Z,azimuth,dip,polarity,G_x,G_y,G_z,formation\n\
         0,0,0,90,90,1,1,0,0,A\n0,0,0,90,90,1,0,0,-1,A\n",
    );
    assert!(
        matches!(&e, Error::Malformed { line: Some(3), reason, .. } if reason.contains("90.0° apart")),
        "{e}"
    );
}

#[test]
fn one_formation_of_a_gempy_table_is_read_by_name() {
    let points = data(&format!("{PERTH}_Points.csv"));
    let foliations = data(&format!("{PERTH}_Foliations.csv"));
    let options = ReadOptions::default().with_formation("Permian");
    let cloud = read_point_cloud_with(&points, &options).unwrap();
    assert_eq!(cloud.len(), 22);
    assert!(cloud.normals().is_none());
    let model = read_gempy(&points, &foliations).unwrap();
    let permian: Vec<_> = model
        .orientations
        .iter()
        .filter(|o| o.formation == "Permian")
        .collect();
    let cloud = read_point_cloud_with(&foliations, &options).unwrap();
    assert_eq!(cloud.len(), 6);
    for (n, o) in cloud.normals().unwrap().iter().zip(&permian) {
        assert_eq!(*n, o.normal);
    }
    // A name no row has lists the formations; another format is refused.
    let e = read_point_cloud_with(&points, &ReadOptions::default().with_formation("permian"))
        .unwrap_err();
    assert!(
        matches!(&e, Error::Malformed { line: None, reason, .. }
            if reason.contains("no row of formation 'permian'") && reason.contains("Permian, Urella_North")),
        "{e}"
    );
    let e = read_point_cloud_with(data("kitten.xyz"), &options).unwrap_err();
    assert!(e.to_string().contains("not a GemPy table"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// non-finite values

#[test]
fn nan_in_xyz_names_record_line_and_field() {
    let e = read_err("a.xyz", "0 0 0\n# comment\n\n1 nan 2\n");
    match e {
        Error::NonFinite {
            source_name,
            record,
            line,
            field,
            value,
        } => {
            assert!(source_name.ends_with("a.xyz"), "{source_name}");
            assert_eq!((record, line, field), (1, Some(4), "y"));
            assert!(value.is_nan());
        }
        e => panic!("{e}"),
    }
}

#[test]
fn inf_normal_in_xyzn_is_named() {
    let e = read_err("a.xyzn", "0 0 0 0 0 1\n1 1 1 0 0 -inf\n");
    assert!(
        matches!(e, Error::NonFinite { record: 1, line: Some(2), field: "nz", value, .. } if value == f64::NEG_INFINITY),
        "{e}"
    );
}

#[test]
fn inf_in_csv_names_record_line_and_field() {
    let e = read_err("a.csv", "x,y,z\n0,0,0\n1,2,inf\n");
    assert!(
        matches!(e, Error::NonFinite { record: 1, line: Some(3), field: "z", value, .. } if value == f64::INFINITY),
        "{e}"
    );
    let msg = e.to_string();
    assert!(
        msg.contains("a.csv") && msg.contains("record 1") && msg.contains('z'),
        "{msg}"
    );
}

#[test]
fn nan_in_ascii_ply_names_record_line_and_field() {
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
               property float z\nend_header\n0 0 0\n1 1 1\n2 NaN 2\n";
    let e = read_err("a.ply", ply);
    // The header is 7 lines: record 2 is on line 10.
    assert!(
        matches!(
            e,
            Error::NonFinite {
                record: 2,
                line: Some(10),
                field: "y",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn nan_in_binary_ply_names_the_record() {
    let cloud = PointCloud3::from_raw(
        vec![[0.0; 3], [1.0, 2.0, 3.0]],
        Some(vec![[0.0, 0.0, 1.0], [f64::NAN, 0.0, 0.0]]),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.ply");
    write_ply(&path, &cloud).unwrap();
    let e = read_point_cloud(&path).unwrap_err();
    assert!(
        matches!(
            e,
            Error::NonFinite {
                record: 1,
                line: None,
                field: "nx",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn allow_non_finite_reads_and_reports() {
    let (_d, path) = temp_file("a.xyz", "0 0 0\n1 nan 2\ninf 0 0\n");
    let options = ReadOptions::default().with_allow_non_finite(true);
    let cloud = read_point_cloud_with(&path, &options).unwrap();
    assert_eq!(cloud.len(), 3);
    assert_eq!(cloud.stats().non_finite_positions, 2);
    assert!(matches!(
        cloud.validate("a.xyz"),
        Err(Error::NonFinite { record: 1, .. })
    ));
}

// ---------------------------------------------------------------------------------------------
// broken PLY files

/// The byte length of a PLY header, through `end_header\n`.
fn ply_header_len(bytes: &[u8]) -> usize {
    let marker = b"end_header\n";
    bytes
        .windows(marker.len())
        .position(|w| w == marker)
        .unwrap()
        + marker.len()
}

#[test]
fn truncated_binary_ply_reports_announced_and_present_counts() {
    let bytes = fs::read(data("bunny_points.ply")).unwrap();
    let header = ply_header_len(&bytes);
    assert_eq!(
        bytes.len(),
        header + 34_834 * 24,
        "bunny_points.ply has 24-byte records"
    );
    // Cut in the middle of record 17 000.
    let cut = header + 17_000 * 24 + 10;
    let e = read_err("cut.ply", &bytes[..cut]);
    match e {
        Error::Truncated {
            element,
            expected,
            got,
            ..
        } => {
            assert_eq!(element, "vertex");
            assert_eq!((expected, got), (34_834, 17_000));
        }
        e => panic!("{e}"),
    }
    // Cut right after the header: no record at all.
    let e = read_err("cut.ply", &bytes[..header]);
    assert!(
        matches!(
            e,
            Error::Truncated {
                expected: 34_834,
                got: 0,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn truncated_binary_ply_after_a_list_element_is_still_truncated() {
    // A list element before `vertex` defeats the size pre-check: the record reader must
    // report the truncation itself.
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement info 1\n\
                      property list uchar int ids\nelement vertex 3\nproperty float x\n\
                      property float y\nproperty float z\nend_header\n"
        .to_vec();
    bytes.push(2);
    bytes.extend(7i32.to_le_bytes());
    bytes.extend(8i32.to_le_bytes());
    for v in [1.0f32, 2.0, 3.0, 4.0, 5.0] {
        bytes.extend(v.to_le_bytes());
    }
    let e = read_err("list.ply", &bytes);
    assert!(
        matches!(
            e,
            Error::Truncated {
                expected: 3,
                got: 1,
                ..
            }
        ),
        "{e}"
    );
    // Complete it: it reads.
    for v in [6.0f32, 7.0, 8.0, 9.0] {
        bytes.extend(v.to_le_bytes());
    }
    let (_d, path) = temp_file("list.ply", &bytes);
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(
        cloud.positions(),
        &[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]
    );
}

#[test]
fn truncated_ascii_ply() {
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
               property float z\nend_header\n0 0 0\n1 1 1\n";
    let e = read_err("a.ply", ply);
    assert!(
        matches!(
            e,
            Error::Truncated {
                expected: 3,
                got: 2,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn a_ply_count_the_file_cannot_hold_is_truncated_not_allocated() {
    // 10⁹ vertices claimed in a file of about 200 bytes: reading must neither reserve room
    // for 10⁹ points (24 GB) nor take long, and must report the file as truncated.
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\n\
                  property float x\nproperty float y\nproperty float z\nend_header\n";
    let mut bytes = header.as_bytes().to_vec();
    bytes.extend([0u8; 100]);
    let e = read_err("huge.ply", &bytes);
    assert!(
        matches!(
            e,
            Error::Truncated {
                expected: 1_000_000_000,
                got: 8,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("truncated"), "{e}");
    // The same in ASCII (no size pre-check: the reader runs out of lines).
    let ascii = "ply\nformat ascii 1.0\nelement vertex 1000000000\nproperty float x\n\
                 property float y\nproperty float z\nend_header\n0 0 0\n1 1 1\n";
    let e = read_err("huge.ply", ascii);
    assert!(
        matches!(
            e,
            Error::Truncated {
                expected: 1_000_000_000,
                got: 2,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn records_that_fit_caps_a_header_count_by_the_bytes() {
    use zeroset_field_core::io::records_that_fit;
    assert_eq!(records_that_fit(1_000_000_000, 200, 12), 16);
    assert_eq!(records_that_fit(8, 96, 12), 8);
    assert_eq!(records_that_fit(8, 95, 12), 7);
    assert_eq!(records_that_fit(usize::MAX, u64::MAX, 0), usize::MAX);
    assert_eq!(records_that_fit(3, 0, 6), 0);
}

#[test]
fn ply_without_z_is_missing_property() {
    let ply = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
               end_header\n0 0\n";
    let e = read_err("a.ply", ply);
    assert!(
        matches!(e, Error::MissingProperty { property: "z", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("'z'"), "{e}");
}

#[test]
fn ply_with_partial_normals_is_missing_property() {
    let ply = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
               property float z\nproperty float nx\nproperty float nz\nend_header\n0 0 0 1 0\n";
    let e = read_err("a.ply", ply);
    assert!(
        matches!(e, Error::MissingProperty { property: "ny", .. }),
        "{e}"
    );
}

#[test]
fn ply_malformed_records_and_headers() {
    let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                property float z\nend_header\n";
    let e = read_err("a.ply", format!("{head}0 0 0\n1 abc 1\n"));
    assert!(
        matches!(&e, Error::Malformed { line: Some(9), reason, .. } if reason.contains("'abc'")),
        "{e}"
    );
    let e = read_err("a.ply", format!("{head}0 0 0\n1 1\n"));
    assert!(matches!(e, Error::Malformed { line: Some(9), .. }), "{e}");
    let e = read_err("a.ply", format!("{head}0 0 0\n1 1 1 1\n"));
    assert!(matches!(e, Error::Malformed { line: Some(9), .. }), "{e}");
    let e = read_err(
        "a.ply",
        "ply\nformat ascii 1.0\nelement face 0\nend_header\n",
    );
    assert!(
        matches!(&e, Error::Malformed { reason, .. } if reason.contains("vertex")),
        "{e}"
    );
    let e = read_err("a.ply", "not a ply file\n");
    assert!(matches!(e, Error::Malformed { line: Some(1), .. }), "{e}");
    assert!(
        e.to_string()
            .ends_with("a.ply:1: not a PLY file (the first line is not 'ply')"),
        "{e}"
    );
    let e = read_err(
        "a.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\nend_header\n",
    );
    assert!(matches!(e, Error::Malformed { line: Some(4), .. }), "{e}");
    assert!(!e.to_string().contains('\n'), "one-line message: {e}");
    let e = read_err(
        "a.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
    );
    assert!(matches!(e, Error::Malformed { .. }), "{e}");
}

#[test]
fn ascii_ply_with_integer_properties_and_elements_before_vertex() {
    let ply = "ply\nformat ascii 1.0\ncomment test\nelement camera 2\nproperty float view\n\
               property list uchar int ids\nelement vertex 2\nproperty uchar x\nproperty int y\n\
               property short z\nproperty uchar red\nproperty double nx\nproperty double ny\n\
               property double nz\nelement face 1\nproperty list uchar int vertex_indices\n\
               end_header\n1.5 2 4 5\n2.5 0\n255 -7 -300 12 0 0 1\n0 1 2 0 1 0 0\n3 0 1 1\n";
    let (_d, path) = temp_file("ints.ply", ply);
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.positions(), &[[255.0, -7.0, -300.0], [0.0, 1.0, 2.0]]);
    assert_eq!(
        cloud.normals().unwrap(),
        &[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]
    );
}

#[test]
fn big_endian_binary_ply() {
    let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\n\
                      property float y\nproperty int z\nproperty uchar alpha\nend_header\n"
        .to_vec();
    for (x, y, z) in [(0.5f64, -1.25f32, 7i32), (1e10, 3.5, -2)] {
        bytes.extend(x.to_be_bytes());
        bytes.extend(y.to_be_bytes());
        bytes.extend(z.to_be_bytes());
        bytes.push(255);
    }
    let (_d, path) = temp_file("be.ply", &bytes);
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.positions(), &[[0.5, -1.25, 7.0], [1e10, 3.5, -2.0]]);
    assert!(cloud.normals().is_none());
}

// ---------------------------------------------------------------------------------------------
// broken text files

#[test]
fn empty_files_are_errors_for_every_format() {
    for name in ["e.ply", "e.xyz", "e.csv", "e.txt"] {
        let e = read_err(name, "");
        assert!(
            matches!(&e, Error::Malformed { reason, .. } if reason.contains("empty")),
            "{name}: {e}"
        );
    }
    // Comments only, a header only, no vertex: no point.
    for (name, text) in [
        ("c.xyz", "# nothing\n\n"),
        ("h.csv", "x,y,z\n"),
        (
            "z.ply",
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
             property float z\nend_header\n",
        ),
    ] {
        let e = read_err(name, text);
        assert!(
            matches!(&e, Error::Malformed { reason, .. } if reason.contains("no point")),
            "{name}: {e}"
        );
    }
}

#[test]
fn xyz_malformed_lines_name_the_line() {
    let e = read_err("a.xyz", "0 0 0\n1 2 abc\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(2), reason, .. } if reason.contains("not a number: 'abc'")),
        "{e}"
    );
    let e = read_err("a.xyz", "# header\n1 2\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(2), reason, .. }
            if reason.contains("expected at least 3 numbers") && reason.contains("found 2")),
        "{e}"
    );
    let e = read_err("a.xyz", "0 0 0\n1 1 1\n2 2 2 0 0 1\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(3), reason, .. } if reason.contains("found 6")),
        "{e}"
    );
    assert!(e.to_string().contains("a.xyz:3"), "{e}");
}

#[test]
fn xyz_separators_comments_extra_columns_and_pts_count() {
    let (_d, path) = temp_file(
        "a.pts",
        "2\n# x y z nx ny nz intensity\n0,0,0, 0,0,1, 9\r\n1\t2 3  1 0 0 7 # trailing comment\n",
    );
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.positions(), &[[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]);
    assert_eq!(
        cloud.normals().unwrap(),
        &[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]
    );
    let (_d, path) = temp_file("a.txt", "\u{feff}1e-3 -2 +3.5\n");
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.positions(), &[[1e-3, -2.0, 3.5]]);
}

/// `n` points of the unit sphere as `x y z a b c` lines, with `extra(k, normal)` as columns
/// 4–6.
fn sphere_with_columns(n: usize, extra: impl Fn(usize, [f64; 3]) -> [f64; 3]) -> String {
    (0..n)
        .map(|k| {
            let z = -1.0 + (2 * k + 1) as f64 / n as f64;
            let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399_963);
            let p = [s * t.cos(), s * t.sin(), z];
            let c = extra(k, p);
            format!(
                "{:.6} {:.6} {:.6} {} {} {}\n",
                p[0], p[1], p[2], c[0], c[1], c[2]
            )
        })
        .collect()
}

#[test]
fn xyz_colours_are_not_read_as_normals() {
    // x y z r g b, colours as whole numbers 0..=255 (black included).
    let text = sphere_with_columns(50, |k, _| {
        [(k * 37 % 256) as f64, (k * 91 % 256) as f64, 0.0].map(|v| if k == 0 { 0.0 } else { v })
    });
    let e = read_err("colours.xyz", &text);
    match &e {
        Error::NotNormals {
            line,
            record,
            values,
            colours,
            ..
        } => {
            assert!(*colours, "{e}");
            // The first line with a value of at least 2 (line 1 is black).
            assert_eq!((*line, *record), (2, 1));
            assert_eq!(*values, [37.0, 91.0, 0.0]);
        }
        other => panic!("{other}"),
    }
    let msg = e.to_string();
    for want in [
        "colours.xyz:2",
        "do not look like unit normals",
        "RGB colours",
        "keep only x y z",
    ] {
        assert!(msg.contains(want), "{want:?} missing: {msg}");
    }
    // Also with more columns after the colours, and as .xyzn.
    let (_d, path) = temp_file("c.xyzn", "0 0 0 255 128 0 7\n1 0 0 0 0 255 7\n");
    assert!(matches!(
        read_point_cloud(&path),
        Err(Error::NotNormals { colours: true, .. })
    ));
}

#[test]
fn xyz_normals_far_from_unit_length_are_refused() {
    // Normals ten times too long, then a single short one among unit normals.
    let text = sphere_with_columns(20, |_, n| n.map(|v| 10.0 * v));
    let e = read_err("long.xyzn", &text);
    assert!(
        matches!(
            &e,
            Error::NotNormals {
                line: 1,
                colours: false,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("length is 10.0000"), "{e}");
    let text = sphere_with_columns(20, |k, n| if k == 7 { n.map(|v| 0.1 * v) } else { n });
    let e = read_err("short.xyzn", &text);
    assert!(
        matches!(
            e,
            Error::NotNormals {
                line: 8,
                record: 7,
                colours: false,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn xyz_normals_near_unit_length_are_read_as_stored() {
    // Lengths from 0.5 to 2 are directions: read as they are (the fits normalise them).
    let scale = |k: usize| [0.5, 0.7, 1.0, 1.5, 2.0][k % 5];
    let text = sphere_with_columns(25, |k, n| n.map(|v| scale(k) * v));
    let (_d, path) = temp_file("scaled.xyzn", &text);
    let cloud = read_point_cloud(&path).unwrap();
    let (lo, hi) = cloud.stats().normal_length_range.unwrap();
    assert!(
        (lo - 0.5).abs() < 1e-5 && (hi - 2.0).abs() < 1e-5,
        "[{lo}, {hi}]"
    );
    // Whole-number normals along the axes, and a zero normal (the fits name it), are read.
    let (_d, path) = temp_file("axes.xyz", "0 0 0 0 0 1\n1 0 0 -1 0 0\n2 0 0 0 0 0\n");
    assert_eq!(read_point_cloud(&path).unwrap().len(), 3);
    // The shipped scans print unit normals to 7 digits (lengths 1 ± 1e-6): read.
    for name in ["bunny_2k.xyzn", "kitten.xyz"] {
        let cloud = read_point_cloud(data(name)).unwrap();
        assert_eq!(cloud.stats().non_unit_normals, 0, "{name}");
    }
}

#[test]
fn csv_missing_column_names_column_and_header() {
    let e = read_err("a.csv", "x,y,w\n0,0,0\n");
    match &e {
        Error::MissingColumn { column, header, .. } => {
            assert_eq!(column, "z");
            assert_eq!(header, "x,y,w");
        }
        e => panic!("{e}"),
    }
    let msg = e.to_string();
    assert!(msg.contains("'z'") && msg.contains("x,y,w"), "{msg}");
    let e = read_err("a.csv", "x,y,z,nx,ny\n0,0,0,1,0\n");
    assert!(
        matches!(&e, Error::MissingColumn { column, .. } if column == "nz"),
        "{e}"
    );
}

#[test]
fn csv_malformed_values_name_the_line() {
    let e = read_err("a.csv", "x,y,z\n0,0,0\n1,two,3\n");
    assert!(
        matches!(&e, Error::Malformed { line: Some(3), reason, .. } if reason.contains("'two'")),
        "{e}"
    );
    let e = read_err("a.csv", "x,y,z\n0,0,0\n1,2\n");
    assert!(matches!(e, Error::Malformed { line: Some(3), .. }), "{e}");
    let e = read_err("a.csv", "x,y,z\n0,,0\n");
    assert!(matches!(e, Error::Malformed { line: Some(2), .. }), "{e}");
}

#[test]
fn csv_header_any_case_with_index_column_and_normals() {
    // With a byte-order mark, as spreadsheets write.
    let (_d, path) = temp_file(
        "a.csv",
        "\u{feff},X,Y,Z,label,NX,NY,NZ\n0, 1.5,2,3,a,0,0,1\n# comment\n1,4,5,6,b,0,1,0\n",
    );
    assert_eq!(detect_format(&path).unwrap(), Format::Csv);
    let cloud = read_point_cloud(&path).unwrap();
    assert_eq!(cloud.positions(), &[[1.5, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(
        cloud.normals().unwrap(),
        &[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]
    );
    let (_d, path) = temp_file("b.csv", "\u{feff}x,y,z\n1,2,3\n");
    assert_eq!(
        read_point_cloud(&path).unwrap().positions(),
        &[[1.0, 2.0, 3.0]]
    );
}

// ---------------------------------------------------------------------------------------------
// formats

#[test]
fn format_from_extension_name_and_content() {
    assert_eq!(Format::from_path("a.PLY"), Some(Format::Ply));
    for ext in ["xyz", "xyzn", "txt", "pts", "XYZ"] {
        assert_eq!(Format::from_path(format!("dir/a.{ext}")), Some(Format::Xyz));
    }
    assert_eq!(Format::from_path("a.csv"), Some(Format::Csv));
    assert_eq!(Format::from_path("a.obj"), None);
    assert_eq!(Format::from_path("noext"), None);
    assert_eq!("GemPy".parse::<Format>().unwrap(), Format::GemPy);
    assert!("stl".parse::<Format>().is_err());
    assert_eq!(Format::Xyz.to_string(), "xyz");

    let e = read_err("a.obj", "v 0 0 0\n");
    assert!(matches!(e, Error::UnknownFormat { .. }), "{e}");
    // A value file is named as one: `zeroset fit` reads it, not the point-cloud readers.
    let e = read_err("curve.XYV", "0 0 1\n1 0 0\n");
    assert!(
        matches!(e, Error::ValueFile { dimension: 2, .. })
            && e.to_string()
                .contains("2-D value constraints (x y value per line)"),
        "{e}"
    );
    let e = read_err("layers.xyzv", "0 0 0 1\n");
    assert!(matches!(e, Error::ValueFile { dimension: 3, .. }), "{e}");
    // An unknown extension that starts like a PLY file is read as one.
    let ply = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
               property float z\nend_header\n1 2 3\n";
    let (_d, path) = temp_file("scan.dat", ply);
    assert_eq!(detect_format(&path).unwrap(), Format::Ply);
    assert_eq!(
        read_point_cloud(&path).unwrap().positions(),
        &[[1.0, 2.0, 3.0]]
    );
}

#[test]
fn compressed_files_are_named_with_the_command_that_unpacks_them() {
    let cases: [(&str, &[u8], &str); 6] = [
        (
            "scan.ply.gz",
            &[0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3],
            "gzip; ",
        ),
        ("scan.zip", b"PK\x03\x04\x14\0\0\0", "zip; "),
        ("scan.xyz.bz2", b"BZh91AY&SY", "bzip2; "),
        (
            "scan.las.xz",
            &[0xfd, b'7', b'z', b'X', b'Z', 0, 0, 4],
            "xz; ",
        ),
        ("scan.e57.zst", &[0x28, 0xb5, 0x2f, 0xfd, 0, 0], "zstd; "),
        (
            "scan.7z",
            &[b'7', b'z', 0xbc, 0xaf, 0x27, 0x1c, 0, 4],
            "7-Zip; ",
        ),
    ];
    for (name, bytes, says) in cases {
        let (_d, path) = temp_file(name, bytes);
        let e = read_point_cloud(&path).unwrap_err();
        assert!(matches!(e, Error::Compressed { .. }), "{name}: {e}");
        let text = e.to_string();
        assert!(text.contains(says) && text.contains(name), "{text}");
    }
    let (_d, path) = temp_file("scan.ply.gz", [0x1f, 0x8b, 8, 0]);
    let text = read_point_cloud(&path).unwrap_err().to_string();
    assert!(
        text.ends_with(&format!("(gunzip -k {})", path.display())),
        "{text}"
    );
    // A name with a space is quoted, so the command can be pasted.
    let (_d, path) = temp_file("my scan.ply.gz", [0x1f, 0x8b, 8, 0]);
    let text = read_point_cloud(&path).unwrap_err().to_string();
    assert!(
        text.ends_with(&format!("(gunzip -k '{}')", path.display())),
        "{text}"
    );
}

#[test]
fn format_option_overrides_detection() {
    let (_d, path) = temp_file("points.dat", "x,y,z\n1,2,3\n");
    assert!(matches!(
        read_point_cloud(&path),
        Err(Error::UnknownFormat { .. })
    ));
    let options = ReadOptions::default().with_format(Format::Csv);
    let cloud = read_point_cloud_with(&path, &options).unwrap();
    assert_eq!(cloud.positions(), &[[1.0, 2.0, 3.0]]);
}

#[test]
fn missing_file_is_io_error_naming_the_file() {
    for name in ["missing.xyz", "missing.csv", "missing.ply", "missing.bin"] {
        let path = std::env::temp_dir().join("zeroset-no-such-dir").join(name);
        let e = read_point_cloud(&path).unwrap_err();
        assert!(matches!(e, Error::Io { .. }), "{name}: {e}");
        assert!(e.to_string().contains(name), "{e}");
    }
}

// ---------------------------------------------------------------------------------------------
// writing

#[test]
fn write_ply_round_trips_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let original = read_point_cloud(data("bunny_2k.xyzn")).unwrap();
    let path = dir.path().join("out.ply");
    write_ply(&path, &original).unwrap();
    let bytes = fs::read(&path).unwrap();
    assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    assert_eq!(bytes.len(), ply_header_len(&bytes) + 2_000 * 48);
    assert_eq!(read_point_cloud(&path).unwrap(), original);

    // Without normals, with awkward values.
    let cloud = PointCloud3::new(vec![[0.1, -0.0, 1e-300], [f64::MAX, -1.5, 3.0]]).unwrap();
    write_ply(&path, &cloud).unwrap();
    assert_eq!(read_point_cloud(&path).unwrap(), cloud);
    // No temporary file is left behind.
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn atomic_write_into_missing_directory_fails_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-dir");
    let path = missing.join("out.ply");
    let cloud = PointCloud3::new(vec![[0.0; 3]]).unwrap();
    let e = write_ply(&path, &cloud).unwrap_err();
    assert!(matches!(&e, Error::Io { path: p, .. } if p == &path), "{e}");
    assert!(!missing.exists());
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn atomic_write_replaces_an_existing_file_intact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cloud.ply");
    let big = read_point_cloud(data("bunny_points.ply")).unwrap();
    let small = PointCloud3::new(vec![[1.0, 2.0, 3.0]]).unwrap();
    write_ply(&path, &big).unwrap();
    write_ply(&path, &small).unwrap();
    assert_eq!(read_point_cloud(&path).unwrap(), small);
    write_ply(&path, &big).unwrap();
    assert_eq!(read_point_cloud(&path).unwrap(), big);
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// A private file stays private, and a link stays a link (its target rewritten): a `chmod 600`
/// output became 644 and a symlink a plain file.
#[cfg(unix)]
#[test]
fn atomic_write_keeps_permissions_and_links() {
    use std::os::unix::fs::PermissionsExt;
    use zeroset_field_core::io::write_atomic;
    let dir = tempfile::tempdir().unwrap();
    let private = dir.path().join("private.txt");
    fs::write(&private, "old").unwrap();
    fs::set_permissions(&private, fs::Permissions::from_mode(0o600)).unwrap();
    write_atomic(&private, |w| w.write_all(b"new")).unwrap();
    assert_eq!(fs::read_to_string(&private).unwrap(), "new");
    let mode = fs::metadata(&private).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600, "{mode:o}");
    let target = dir.path().join("target.txt");
    let link = dir.path().join("link.txt");
    fs::write(&target, "old").unwrap();
    std::os::unix::fs::symlink(&target, &link).unwrap();
    write_atomic(&link, |w| w.write_all(b"new")).unwrap();
    assert!(
        fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(fs::read_to_string(&target).unwrap(), "new");
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 3);
    // A link to anything but a regular file (here a directory), or to nothing, is replaced
    // itself: what it points to is never touched.
    let folder = dir.path().join("folder");
    fs::create_dir(&folder).unwrap();
    for (name, to) in [
        ("to_dir.txt", folder.clone()),
        ("dangling.txt", dir.path().join("none")),
    ] {
        let link = dir.path().join(name);
        std::os::unix::fs::symlink(&to, &link).unwrap();
        write_atomic(&link, |w| w.write_all(b"file")).unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().is_file(), "{name}");
    }
    assert!(folder.is_dir() && fs::read_dir(&folder).unwrap().count() == 0);
    assert!(!dir.path().join("none").exists());
}

#[test]
fn atomic_write_failure_keeps_the_old_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("notes.txt");
    fs::write(&path, "old contents\n").unwrap();
    let e = write_atomic(&path, |w| {
        w.write_all(b"half of the new")?;
        Err(std::io::Error::other("simulated failure"))
    })
    .unwrap_err();
    assert!(e.to_string().contains("simulated failure"), "{e}");
    assert_eq!(fs::read_to_string(&path).unwrap(), "old contents\n");
    assert_eq!(
        fs::read_dir(dir.path()).unwrap().count(),
        1,
        "temporary file left behind"
    );
    write_atomic(&path, |w| w.write_all(b"new contents\n")).unwrap();
    assert_eq!(fs::read_to_string(&path).unwrap(), "new contents\n");
    // A path with no file name is refused.
    let e = write_atomic("", |_| Ok(())).unwrap_err();
    assert!(matches!(e, Error::Io { .. }));
}
