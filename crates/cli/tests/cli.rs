//! The `zeroset` binary, run as a user would, on the shipped sample and on small broken files.

use std::ffi::OsStr;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::{sample, zeroset};

/// Runs the binary with its operator disk cache in `cache` (empty: none).
fn zeroset_with_cache<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>, cache: &Path) -> Output {
    common::zeroset_with(args, &[("ZEROSET_CACHE_DIR", cache.as_os_str())])
}

fn info(path: &Path, extra: &[&str]) -> Output {
    let mut args: Vec<&OsStr> = vec![OsStr::new("info"), path.as_os_str()];
    args.extend(extra.iter().map(OsStr::new));
    zeroset(args)
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A failure must be a message, not a panic.
fn assert_clean_failure(o: &Output) {
    assert!(!o.status.success(), "expected failure, got:\n{}", stdout(o));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(o));
    assert!(stderr(o).starts_with("error: "), "{}", stderr(o));
    assert!(!stderr(o).contains("panicked"), "{}", stderr(o));
}

fn temp_file(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    fs::write(&path, text).unwrap();
    (dir, path)
}

#[test]
fn info_describes_the_sample() {
    let o = info(&sample(), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("format:      xyz\n"), "{out}");
    assert!(out.contains("points:      2000 points\n"), "{out}");
    assert!(out.contains("normals:     yes; 0 not unit length"), "{out}");
    assert!(
        out.contains("min (-0.0946685, 0.0333795, -0.0618413)"),
        "{out}"
    );
    assert!(
        out.contains("max (0.0610039, 0.186115, 0.0580036)"),
        "{out}"
    );
    assert!(out.contains("non-finite:  none\n"), "{out}");
    assert!(out.contains("duplicates:  none\n"), "{out}");
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
}

#[test]
fn help_shows_examples() {
    for args in [&["--help"][..], &["info", "--help"], &["help", "info"]] {
        let o = zeroset(args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        let out = stdout(&o);
        assert!(out.contains("Examples:"), "{args:?}:\n{out}");
        assert!(out.contains("zeroset info samples/bunny_2k.xyzn"), "{out}");
    }
    let o = zeroset(["--help"]);
    assert!(stdout(&o).contains("info"), "{}", stdout(&o));
}

#[test]
fn missing_file_fails_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "no_such_cloud.xyz",
        "no_such_cloud.csv",
        "no_such_cloud.unknown",
    ] {
        let o = info(&dir.path().join(name), &[]);
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(name), "{}", stderr(&o));
    }
}

#[test]
fn nan_is_reported_with_record_line_and_field() {
    let (_d, path) = temp_file("nan.xyz", "0 0 0\n# comment\n1 NaN 2\n3 4 inf\n");
    let o = info(&path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("points:      3 points"), "{out}");
    assert!(
        out.contains("non-finite:  2 positions with NaN or infinite values"),
        "{out}"
    );
    assert!(out.contains("first: record 1 (line 3), y = NaN"), "{out}");
}

#[test]
fn malformed_file_fails_with_file_and_line() {
    let (_d, path) = temp_file("bad.xyz", "0 0 0\n1 2 abc\n");
    let o = info(&path, &[]);
    assert_clean_failure(&o);
    let err = stderr(&o);
    assert!(err.contains("bad.xyz:2") && err.contains("'abc'"), "{err}");

    let (_d, path) = temp_file("bad.csv", "x,y,w\n0,0,0\n");
    let o = info(&path, &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("no column 'z'"), "{}", stderr(&o));

    let (_d, path) = temp_file("empty.ply", "");
    assert_clean_failure(&info(&path, &[]));
}

#[test]
fn format_flag_overrides_detection() {
    let (_d, path) = temp_file("points.dat", "x,y,z\n1,2,3\n1,2,3\n");
    assert_clean_failure(&info(&path, &[]));
    let o = info(&path, &["--format", "csv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("points:      2 points"), "{out}");
    assert!(out.contains("normals:     no"), "{out}");
    assert!(out.contains("duplicates:  1 point repeat"), "{out}");

    // An unknown format name is a usage error (exit 2) listing the choices.
    let o = info(&path, &["--format", "stl"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("possible values"), "{}", stderr(&o));
}

#[test]
fn gempy_table_lists_formations() {
    let (_d, path) = temp_file(
        "foliations.csv",
        "X,Y,Z,azimuth,dip,polarity,formation\n\
         0,0,0,90,90,1,Shale\n1,0,0,0,0,1,Sand\n2,0,0,0,10,-1,Shale\n",
    );
    let o = info(&path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("format:      gempy"), "{out}");
    assert!(out.contains("points:      3 points"), "{out}");
    assert!(out.contains("normals:     yes; 0 not unit length"), "{out}");
    assert!(
        out.contains("formations:  2 (orientations per formation)"),
        "{out}"
    );
    assert!(out.contains("Sand       1\n"), "{out}");
    assert!(out.contains("Shale      2\n"), "{out}");
}

#[test]
fn one_formation_of_a_gempy_table_is_fitted_and_reconstructed_by_name() {
    // Two formations, each a sphere's surface points (no normals): "Upper" around the sphere
    // of the other tests, "Lower" the same sphere 5 below.
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("points.csv");
    let mut text = String::from("X,Y,Z,formation\n");
    for (name, dz) in [("Upper", 0.0), ("Lower", -5.0)] {
        for (p, _) in sphere_points(300) {
            text += &format!("{},{},{},{name}\n", p[0], p[1], p[2] + dz);
        }
    }
    fs::write(&table, text).unwrap();
    let t = table.to_str().unwrap();
    let mesh = dir.path().join("upper.ply");
    let m = mesh.to_str().unwrap();
    let o = zeroset([
        "reconstruct",
        t,
        "-o",
        m,
        "--formation",
        "Upper",
        "--no-preview",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(!out.contains("formations:"), "{out}");
    assert!(
        out.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{out}"
    );
    let upper = zeroset_mesh::read_mesh(&mesh).unwrap();
    for v in upper.vertices() {
        let r = (0..3)
            .map(|a| (v[a] - CENTRE[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!((r - RADIUS).abs() < 0.02, "a vertex {r} from the centre");
    }
    // Read whole, the table says what it holds and how to take one formation.
    let o = zeroset(["fit", t, "--method", "rbf"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("is a GemPy surface-points table: its points have no orientations"),
        "{}",
        stderr(&o)
    );
    assert!(
        stdout(&o)
            .contains("formations:   2 in this GemPy table (Lower, Upper), read as one surface"),
        "{}",
        stdout(&o)
    );
    let o = zeroset(["normals", t, "-o", m, "--force", "--formation", "Clay"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("no row of formation 'Clay'; the table's formations: Lower, Upper"),
        "{}",
        stderr(&o)
    );
    // The names of one cloud format do not apply to another.
    let xyzn = dir.path().join("s.xyzn");
    fs::write(&xyzn, sphere_xyzn(50)).unwrap();
    let o = zeroset([
        "fit".as_ref(),
        xyzn.as_os_str(),
        "--method".as_ref(),
        "rbf".as_ref(),
        "--formation".as_ref(),
        "Upper".as_ref(),
    ]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("not a GemPy table"), "{}", stderr(&o));
}

const EARS: &str = "-0.095,0.145,-0.065:0.0,0.2,0.04";

#[test]
fn restore_removes_a_protrusion_then_denoises_the_result() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("no_ears.zsf");
    let o = zeroset([
        OsStr::new("restore"),
        sample().as_os_str(),
        OsStr::new("--mode"),
        OsStr::new("protrusion"),
        OsStr::new("--mask"),
        OsStr::new(EARS),
        OsStr::new("--face"),
        OsStr::new("-y"),
        OsStr::new("--alpha"),
        OsStr::new("1"),
        OsStr::new("-o"),
        first.as_os_str(),
    ]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("separable-dst"), "{}", stdout(&o));
    let bytes = fs::read(&first).unwrap();
    assert_eq!(&bytes[..8], b"ZSFIELD\0");
    // The output is a field that the next restoration takes.
    let second = dir.path().join("smooth.zsf");
    let o = zeroset([
        OsStr::new("restore"),
        first.as_os_str(),
        OsStr::new("--mode"),
        OsStr::new("denoise"),
        OsStr::new("--mask"),
        OsStr::new("-0.05,0.05,-0.03:0.05,0.12,0.06"),
        OsStr::new("--coarse"),
        OsStr::new("6,6,4"),
        OsStr::new("-o"),
        second.as_os_str(),
    ]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("field file"), "{}", stdout(&o));
    // The input is untouched.
    assert_eq!(fs::read(&first).unwrap(), bytes);
}

/// A closed rod of radius 0.05 and length 4 along x, sampled about every 0.02 (its side in
/// rings, its ends in discs), with outward normals.
fn rod_xyzn() -> String {
    let (h, r, half) = (0.02, 0.05, 2.0);
    let ring = (2.0 * std::f64::consts::PI * r / h).round() as usize;
    let mut text = String::new();
    let mut push = |p: [f64; 3], n: [f64; 3]| {
        text.push_str(&format!(
            "{} {} {} {} {} {}\n",
            p[0], p[1], p[2], n[0], n[1], n[2]
        ));
    };
    for i in 0..=(2.0 * half / h).round() as usize {
        let x = -half + i as f64 * h;
        for k in 0..ring {
            let t = 2.0 * std::f64::consts::PI * k as f64 / ring as f64;
            push([x, r * t.cos(), r * t.sin()], [0.0, t.cos(), t.sin()]);
        }
    }
    for side in [-1.0, 1.0] {
        for j in 0..(r / h).ceil() as usize {
            let rr = h / 2.0 + j as f64 * h;
            let m = ((2.0 * std::f64::consts::PI * rr / h).round() as usize).max(1);
            for k in 0..m {
                let t = 2.0 * std::f64::consts::PI * k as f64 / m as f64;
                push([side * half, rr * t.cos(), rr * t.sin()], [side, 0.0, 0.0]);
            }
        }
    }
    text
}

#[test]
fn restore_says_how_far_resampling_moves_the_surface_outside_the_mask() {
    // A field file's surface is resampled on the restoration grid everywhere, not only in the
    // mask: on the default grid a thin rod's cells are wider than the rod, and it shrank (6% of
    // its radius) with no word. Now the drift is measured and warned of; a finer grid keeps it.
    let (dir, rod) = temp_file("rod.xyzn", &rod_xyzn());
    let field = dir.path().join("rod.zsf");
    let o = fit(&rod, &["-o", field.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Denoise a box away from the rod's ends: `input` to out.zsf, with `extra` flags.
    let out = dir.path().join("out.zsf");
    let restore = |input: &Path, extra: &[&str]| {
        let mut args = vec![
            "restore",
            input.to_str().unwrap(),
            "--mode",
            "denoise",
            "--mask",
            "1.5,-0.2,-0.2:1.9,0.2,0.2",
            "--coarse",
            "3,3,3",
            "--force",
        ];
        args.extend(extra);
        zeroset(args)
    };
    let succeeds = |o: Output| {
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    let o_out = out.to_str().unwrap();
    const DRIFT: &str = "outside the mask: the resampled surface lies a median";
    let coarse = succeeds(restore(&field, &["-o", o_out]));
    assert!(coarse.contains(DRIFT), "{coarse}");
    assert!(coarse.contains("warning: the grid's cells"), "{coarse}");
    let median = reported(&coarse, DRIFT);
    assert!((0.001..0.01).contains(&median), "{coarse}");
    let fine = succeeds(restore(&field, &["--grid", "256,48,48", "-o", o_out]));
    assert!(!fine.contains("warning: the grid's cells"), "{fine}");
    assert!(reported(&fine, DRIFT) < 0.2 * median, "{fine}");
    // --neighbours belongs to point clouds: on a field file it was silently ignored.
    let other = dir.path().join("other.zsf");
    let o = restore(
        &field,
        &["--neighbours", "30", "-o", other.to_str().unwrap()],
    );
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("--neighbours 30 applies to point clouds"),
        "{}",
        stderr(&o)
    );
    // A B-spline field on its own grid is given back outside the mask: nothing to report.
    let again = succeeds(restore(&out, &["-o", other.to_str().unwrap()]));
    assert!(!again.contains("outside the mask"), "{again}");
    // On another --grid it is resampled, which is said and measured.
    let regrid = succeeds(restore(
        &out,
        &["--grid", "128,24,24", "-o", other.to_str().unwrap()],
    ));
    assert!(
        regrid.contains("resampled on the --grid (not its own)"),
        "{regrid}"
    );
    assert!(regrid.contains(DRIFT), "{regrid}");
}

#[test]
fn restore_warns_of_a_slope_that_grows_the_protrusion() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.zsf");
    let run = |alpha: &str| {
        let o = zeroset([
            "restore",
            sample().to_str().unwrap(),
            "--mode",
            "protrusion",
            "--mask",
            EARS,
            "--face",
            "-y",
            &format!("--alpha={alpha}"),
            "--force",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    let grows = "does not rise into the mask across the face";
    assert!(run("-1").contains(grows), "{}", run("-1"));
    assert!(run("0").contains(grows), "{}", run("0"));
    assert!(!run("2").contains(grows), "{}", run("2"));
}

#[test]
fn restore_warns_of_a_mask_with_no_surface_in_it() {
    // A mask in empty space (its corners in other units, say) restored nothing and said nothing.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.zsf");
    let restore = |input: &Path, mask: &str| {
        let o = zeroset([
            "restore",
            input.to_str().unwrap(),
            "--mode",
            "protrusion",
            &format!("--mask={mask}"),
            "--force",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    const EMPTY_MASK: &str = "the mask holds no surface to restore";
    let beside = restore(&sample(), "-0.09,0.035,-0.06:-0.07,0.05,-0.04");
    assert!(beside.contains(EMPTY_MASK), "{beside}");
    assert!(!restore(&sample(), EARS).contains(EMPTY_MASK));
    // A field positive everywhere (values 1 + |p|² interpolated) has no surface at all.
    let values: String = (0..64)
        .map(|i| {
            let p = [
                (i % 4) as f64 - 1.5,
                ((i / 4) % 4) as f64 - 1.5,
                (i / 16) as f64 - 1.5,
            ];
            format!(
                "{} {} {} {}\n",
                p[0],
                p[1],
                p[2],
                1.0 + p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
            )
        })
        .collect();
    let (_d, path) = temp_file("positive.xyzv", &values);
    let field = dir.path().join("positive.zsf");
    let o = zeroset([
        "fit",
        path.to_str().unwrap(),
        "--method",
        "rbf",
        "-o",
        field.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let nowhere = restore(&field, "-0.5,-0.5,-0.5:0.5,0.5,0.5");
    assert!(
        nowhere.contains("the field does not reach 0 anywhere on the grid"),
        "{nowhere}"
    );
}

#[test]
fn restore_refuses_bad_requests_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.zsf");
    let run = |extra: &[&str]| {
        let mut args: Vec<&OsStr> = vec![OsStr::new("restore"), sample_os()];
        args.extend(extra.iter().map(OsStr::new));
        args.extend([OsStr::new("-o"), out.as_os_str()]);
        zeroset(args)
    };
    let cases: [(&[&str], &str); 7] = [
        (
            &[
                "--mode",
                "protrusion",
                "--mask",
                "-0.095,0.3,-0.065:0.0,0.5,0.04",
            ],
            "outside the bounding box",
        ),
        (
            &[
                "--mode",
                "protrusion",
                "--mask",
                EARS,
                "--face",
                "-y",
                "--alpha",
                "inf",
            ],
            "alpha must be finite",
        ),
        (
            &["--mode", "protrusion", "--mask", EARS, "--alpha", "2"],
            "--alpha is the slope across --face",
        ),
        (
            &["--mode", "denoise", "--mask", EARS, "--coarse", "100,2,2"],
            "coarse resolution 100",
        ),
        (&["--mode", "denoise", "--mask", EARS], "needs --coarse"),
        (
            &["--mode", "protrusion", "--mask", EARS, "--grid", "2,40,40"],
            "at least 3 samples",
        ),
        (
            // Inside the box, between two samples along x: not "outside the box".
            &[
                "--mode",
                "protrusion",
                "--mask",
                "-0.05,0.1,-0.02:-0.0499,0.14,0.02",
            ],
            "the mask holds no grid sample along x",
        ),
    ];
    for (extra, expected) in cases {
        let o = run(extra);
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(expected), "{extra:?}: {}", stderr(&o));
    }
    assert!(!out.exists(), "a failed run must not leave an output");
    // A corrupt field file is named as such.
    let bad = dir.path().join("bad.zsf");
    fs::write(&bad, b"ZSFIELD\0\x01\x00").unwrap();
    let o = zeroset([
        OsStr::new("restore"),
        bad.as_os_str(),
        OsStr::new("--mode"),
        OsStr::new("denoise"),
        OsStr::new("--mask"),
        OsStr::new(EARS),
        OsStr::new("--coarse"),
        OsStr::new("2,2,2"),
        OsStr::new("-o"),
        out.as_os_str(),
    ]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("truncated"), "{}", stderr(&o));
}

fn sample_os() -> &'static OsStr {
    static SAMPLE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    SAMPLE.get_or_init(sample).as_os_str()
}

// ---- zeroset fit ----

/// The sphere of the fit tests: centre and radius.
const CENTRE: [f64; 3] = [0.1, -0.2, 0.3];
const RADIUS: f64 = 0.5;

/// `n` points on the sphere (a Fibonacci lattice) with outward unit normals.
fn sphere_points(n: usize) -> Vec<([f64; 3], [f64; 3])> {
    (0..n)
        .map(|k| {
            let z = -1.0 + (2 * k + 1) as f64 / n as f64;
            let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399_963_229_728_653);
            let normal = [s * t.cos(), s * t.sin(), z];
            (
                std::array::from_fn(|a| CENTRE[a] + RADIUS * normal[a]),
                normal,
            )
        })
        .collect()
}

/// The sphere as `x y z nx ny nz` lines.
fn sphere_xyzn(n: usize) -> String {
    sphere_points(n)
        .iter()
        .map(|(p, q)| format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], q[0], q[1], q[2]))
        .collect()
}

/// The sphere as an ASCII PLY with normals.
fn sphere_ply(n: usize) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {n}\nproperty double x\nproperty double y\n\
         property double z\nproperty double nx\nproperty double ny\nproperty double nz\n\
         end_header\n"
    );
    s.push_str(&sphere_xyzn(n));
    s
}

#[test]
fn a_point_cloud_ply_with_a_few_faces_is_read_as_a_point_cloud() {
    // 300 sphere points with normals, and one face on 3 of them.
    let ply = sphere_ply(300).replace(
        "end_header\n",
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n",
    ) + "3 0 1 2\n";
    let (dir, path) = temp_file("scan.ply", &ply);
    let field = dir.path().join("s.zsf");
    let o = zeroset([
        OsStr::new("fit"),
        path.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("rbf"),
        OsStr::new("-o"),
        field.as_os_str(),
    ]);
    let out = stdout(&o);
    assert!(o.status.success(), "{out}{}", stderr(&o));
    assert!(
        out.contains("its 1 faces use fewer than half of its 300 vertices: read as a point cloud"),
        "{out}"
    );
    assert!(out.contains("300 points"), "{out}");
}

fn fit(path: &Path, extra: &[&str]) -> Output {
    let mut args: Vec<&OsStr> = vec![
        OsStr::new("fit"),
        path.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("rbf"),
        OsStr::new("--quiet"),
    ];
    args.extend(extra.iter().map(OsStr::new));
    zeroset(args)
}

/// The number after `label` on its line of the report.
fn reported(out: &str, label: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with(label))
        .unwrap_or_else(|| panic!("no {label:?} line in:\n{out}"));
    let value = line[label.len()..].split_whitespace().next().unwrap();
    value
        .parse()
        .unwrap_or_else(|e| panic!("{label} {value:?}: {e}"))
}

#[test]
fn fit_sphere_with_defaults_reports_an_exact_fit() {
    let (_d, path) = temp_file("sphere.xyzn", &sphere_xyzn(300));
    let before = fs::read(&path).unwrap();
    let o = fit(&path, &[]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("300 points with normals"), "{out}");
    assert!(
        out.contains("constraints:  900 off-surface (Carr et al.)"),
        "{out}"
    );
    assert!(out.contains("0 shrunk, 0 dropped"), "{out}");
    assert!(out.contains("kernel:       r (biharmonic)"), "{out}");
    assert!(out.contains("solver:       dense-cholesky"), "{out}");
    assert_eq!(reported(&out, "unknowns:"), 904.0, "{out}");
    let residual = reported(&out, "max residual:");
    assert!(residual < 1e-8, "residual {residual}:\n{out}");
    assert!(reported(&out, "condition:").is_finite(), "{out}");
    assert!(out.contains("warnings:     none"), "{out}");
    // The sanity check: 5 input points, value ~0 and |∇f| ~1 at each.
    let rows: Vec<&str> = out
        .lines()
        .skip_while(|l| !l.starts_with("check:"))
        .skip(2)
        .take(5)
        .collect();
    assert_eq!(rows.len(), 5, "{out}");
    for row in rows {
        let cols: Vec<&str> = row.split_whitespace().collect();
        let n = cols.len();
        let (value, grad): (f64, f64) =
            (cols[n - 3].parse().unwrap(), cols[n - 2].parse().unwrap());
        assert!(value.abs() < 1e-8 && (grad - 1.0).abs() < 0.05, "{row}");
    }
    // Nothing written without -o, and the input is untouched.
    assert_eq!(fs::read_dir(_d.path()).unwrap().count(), 1);
    assert_eq!(fs::read(&path).unwrap(), before);
}

#[test]
fn fit_hermite_needs_r3() {
    let (_d, path) = temp_file("sphere.ply", &sphere_ply(200));
    for extra in [&["--hermite"][..], &["--hermite", "--kernel", "r3"]] {
        let o = fit(&path, extra);
        assert!(
            o.status.success(),
            "{extra:?}: {}{}",
            stdout(&o),
            stderr(&o)
        );
        let out = stdout(&o);
        assert!(out.contains("400 Hermite"), "{out}");
        assert!(out.contains("kernel:       r3 (triharmonic)"), "{out}");
        assert!(out.contains("solver:       dense-cholesky"), "{out}");
        assert!(reported(&out, "max residual:") < 1e-8, "{out}");
    }
    let o = fit(&path, &["--hermite", "--kernel", "r"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("--hermite needs --kernel r3"),
        "{}",
        stderr(&o)
    );
    assert!(
        stdout(&o).is_empty(),
        "refused before reading: {}",
        stdout(&o)
    );
}

#[test]
fn fit_refuses_bad_requests_with_a_message() {
    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(100));
    let out = dir.path().join("out.zsf");
    let out = out.to_str().unwrap();
    let cases: [(&[&str], &str); 9] = [
        (
            &["--offset", "0"],
            "--offset must be auto or a finite distance > 0",
        ),
        (
            &["--offset", "-0.01"],
            "--offset must be auto or a finite distance > 0",
        ),
        (&["--offset", "0.6"], "crosses the surface"),
        (&["--kernel", "tps"], "2-D curves"),
        (&["--hermite", "--offset", "0.01"], "--hermite uses none"),
        (&["--grid", "8,8,8"], "give -o"),
        (&["--sampled"], "give -o"),
        (
            &["-o", out, "--grid", "8,8,8"],
            "--grid is the sampling grid of --sampled",
        ),
        (
            &["-o", out, "--sampled", "--grid", "2,8,8"],
            "at least 3 cells per axis",
        ),
    ];
    for (extra, expected) in cases {
        let o = fit(&path, extra);
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(expected), "{extra:?}: {}", stderr(&o));
    }
    assert!(
        !Path::new(out).exists(),
        "a failed run must not leave an output"
    );
    // The method is required and named.
    let o = zeroset([OsStr::new("fit"), path.as_os_str()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--method"), "{}", stderr(&o));
}

#[test]
fn flipped_normals_are_on_the_fit_reports_warnings_line() {
    // Two of the sphere's 300 normals turned inward.
    let text: String = sphere_points(300)
        .iter()
        .enumerate()
        .map(|(i, (p, q))| {
            let s = if i == 40 || i == 200 { -1.0 } else { 1.0 };
            format!(
                "{} {} {} {} {} {}\n",
                p[0],
                p[1],
                p[2],
                s * q[0],
                s * q[1],
                s * q[2]
            )
        })
        .collect();
    let (_d, path) = temp_file("flipped.xyzn", &text);
    let o = fit(&path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("warnings:     2 normals point against most of their nearest"),
        "{out}"
    );
    assert!(!out.contains("point inward on the whole"), "{out}");
}

#[test]
fn normals_inward_on_the_whole_are_warned_of_before_the_fit() {
    // Every normal of the sphere turned inward: each agrees with its neighbours, so only the
    // mesh said (inside out, negative volume); every fit method says so now, the RBF fit on
    // its warnings line too.
    let text: String = sphere_points(400)
        .iter()
        .map(|(p, q)| format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], -q[0], -q[1], -q[2]))
        .collect();
    let (dir, path) = temp_file("inward.xyzn", &text);
    const INWARD: &str = "normals:      warning: the normals point inward on the whole";
    for method in ["rbf", "mras", "neural"] {
        let mut args = vec!["fit", path.to_str().unwrap(), "--method", method, "--quiet"];
        if method == "neural" {
            args.extend(["--steps", "1"]);
        }
        let o = zeroset(&args);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        assert!(stdout(&o).contains(INWARD), "{method}: {}", stdout(&o));
        if method == "rbf" {
            assert!(
                stdout(&o).contains("warnings:     the normals point inward"),
                "{}",
                stdout(&o)
            );
        }
    }
    let (_d, outward) = temp_file("outward.xyzn", &sphere_xyzn(400));
    let o = fit(&outward, &[]);
    assert!(!stdout(&o).contains("point inward"), "{}", stdout(&o));
    drop(dir);
}

#[test]
#[cfg(target_os = "linux")]
fn an_output_that_cannot_be_written_is_refused_before_any_work() {
    // /proc takes no new files, whoever runs the test.
    let (_d, scan) = temp_file("sphere.xyzn", &sphere_xyzn(300));
    for (command, output) in [("fit", "/proc/x.zsf"), ("reconstruct", "/proc/x.ply")] {
        let mut args = vec![command, scan.to_str().unwrap(), "-o", output];
        if command == "fit" {
            args.extend(["--method", "rbf"]);
        }
        let o = zeroset(args);
        assert_clean_failure(&o);
        let err = stderr(&o);
        assert!(
            err.contains(&format!(
                "cannot write {output}: creating a file in /proc fails"
            )),
            "{err}"
        );
        assert!(!stdout(&o).contains("fit time"), "{}", stdout(&o));
    }
}

#[cfg(unix)]
#[test]
fn an_interrupted_reconstruct_leaves_no_file_behind() {
    use std::os::unix::process::ExitStatusExt;
    // Terminated while it meshes (its temporary field exists then): it ends by the signal, as a
    // shell needs to stop a script's loop, and neither the temporary field nor any output's
    // unfinished temporary file is left. SIGTERM, handled as Ctrl-C's SIGINT is: a test run in
    // the background of a script has SIGINT ignored, and so has the binary then. A run that
    // finishes before the signal is sent proves nothing, so it is tried again.
    let sample = sample();
    for attempt in 0..4 {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("bunny.ply");
        let mut child = Command::new(env!("CARGO_BIN_EXE_zeroset"))
            .args(["reconstruct".as_ref(), sample.as_os_str(), "-o".as_ref()])
            .arg(&out)
            .args(["--detail", "fine", "--quiet"])
            .env("ZEROSET_CACHE_DIR", "")
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let field = dir
            .path()
            .join(format!(".bunny.ply.reconstruct-{}.zsf", child.id()));
        while !field.exists() && child.try_wait().unwrap().is_none() {
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        let signalled = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap()
            .success();
        let o = child.wait_with_output().unwrap();
        if !signalled || o.status.success() {
            assert!(attempt < 3, "every run finished before Ctrl-C reached it");
            continue;
        }
        assert_eq!(o.status.signal(), Some(15), "{}", stderr(&o));
        assert!(stderr(&o).contains("interrupted"), "{}", stderr(&o));
        let left: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|name| name.starts_with('.'))
            .collect();
        assert!(left.is_empty(), "left behind: {left:?}");
        return;
    }
}

#[test]
fn reconstruct_reads_a_scan_whose_extension_says_nothing_by_format() {
    let (dir, scan) = temp_file("sphere.dat", &sphere_xyzn(400));
    let mesh = dir.path().join("mesh.ply");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "reconstruct",
            scan.to_str().unwrap(),
            "-o",
            mesh.to_str().unwrap(),
            "--no-preview",
            "--quiet",
            "--force",
        ];
        args.extend(extra);
        zeroset(args)
    };
    let o = run(&[]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("unknown point-cloud format"),
        "{}",
        stderr(&o)
    );
    let o = run(&["--format", "xyz"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("report: closed, Euler characteristic 2"),
        "{}",
        stdout(&o)
    );
    // The copy the stages read is gone.
    let mut names: Vec<_> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["mesh.ply", "sphere.dat"]);
}

#[test]
fn fit_names_a_non_finite_coordinate_and_missing_normals() {
    let (_d, path) = temp_file(
        "nan.xyzn",
        "0 0 0 0 0 1\n# comment\n1 NaN 2 0 0 1\n1 1 1 0 1 0\n",
    );
    let o = fit(&path, &[]);
    assert_clean_failure(&o);
    let err = stderr(&o);
    assert!(
        err.contains("nan.xyzn: line 3, record 1: non-finite y (NaN)"),
        "{err}"
    );
    let (_d, path) = temp_file("bare.xyz", "0 0 0\n1 0 0\n0 1 0\n0 0 1\n");
    let o = fit(&path, &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("has no normals"), "{}", stderr(&o));
}

#[test]
fn fit_writes_a_field_file_that_restore_takes() {
    use zeroset_bases::field_file::{read_any_field, read_field};
    use zeroset_field_core::field::ScalarField;

    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(300));

    // By default -o writes the RBF field itself: exact at the input points.
    let rbf = dir.path().join("sphere_rbf.zsf");
    let o = fit(&path, &["-o", rbf.to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("the RBF field itself (kernel r, "), "{out}");
    assert!(out.contains("(the RBF field) in"), "{out}");
    assert!(!out.contains("B-spline"), "{out}");
    let any = read_any_field::<3>(&rbf).expect("a valid field file");
    assert_eq!(any.kind(), "rbf");
    let at = |d: [f64; 3]| any.value(&std::array::from_fn(|a| CENTRE[a] + d[a]));
    assert!(at([0.0; 3]) < -0.1, "centre {}", at([0.0; 3]));
    for d in [[0.56, 0.0, 0.0], [0.0, -0.56, 0.0], [0.4, 0.4, 0.4]] {
        assert!(at(d) > 0.0, "{d:?}: {}", at(d));
    }
    for (p, _) in sphere_points(300).iter().step_by(37) {
        assert!(any.value(p).abs() < 1e-6, "{p:?}: {}", any.value(p));
    }
    // read_field takes B-splines only, and says so.
    let e = read_field::<3>(&rbf).unwrap_err().to_string();
    assert!(e.contains("RBF"), "{e}");
    // `zeroset info` reports its kind, kernel and centres.
    let o = info(&rbf, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for text in ["rbf", "kernel:", " r\n", "centres:", "metadata:", "bounds:"] {
        assert!(out.contains(text), "{text:?}:\n{out}");
    }

    // --sampled writes the quadratic B-spline sampled from it.
    let field = dir.path().join("sphere.zsf");
    let o = fit(&path, &["-o", field.to_str().unwrap(), "--sampled"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("sampled on 64×64×64 cells"), "{out}");
    assert!(out.contains("quadratic B-spline"), "{out}");
    assert!(out.contains("wrote "), "{out}");
    let o = info(&field, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("bspline"), "{}", stdout(&o));
    assert!(stdout(&o).contains("64×64×64"), "{}", stdout(&o));

    let spline = read_field::<3>(&field).expect("a valid field file");
    let b = spline.grid().bounds();
    // The grid covers the sphere's box grown by 5% of its diagonal.
    let margin = 0.05 * (2.0 * RADIUS) * 3f64.sqrt();
    for ((lo, hi), c) in b.min().into_iter().zip(b.max()).zip(CENTRE) {
        assert!((lo - (c - RADIUS - margin)).abs() < 0.01, "{b:?}");
        assert!((hi - (c + RADIUS + margin)).abs() < 0.01, "{b:?}");
    }
    let at = |d: [f64; 3]| spline.value(&std::array::from_fn(|a| CENTRE[a] + d[a]));
    assert!(at([0.0; 3]) < -0.1, "centre {}", at([0.0; 3]));
    assert!(at([0.0, 0.0, 0.25]) < 0.0);
    for d in [[0.56, 0.0, 0.0], [0.0, -0.56, 0.0], [0.4, 0.4, 0.4]] {
        assert!(at(d) > 0.0, "{d:?}: {}", at(d));
    }
    for (p, _) in sphere_points(300).iter().step_by(37) {
        assert!(spline.value(p).abs() < 2e-3, "{p:?}: {}", spline.value(p));
    }

    // `zeroset restore` takes it.
    let smooth = dir.path().join("smooth.zsf");
    let o = zeroset([
        OsStr::new("restore"),
        field.as_os_str(),
        OsStr::new("--mode"),
        OsStr::new("denoise"),
        OsStr::new("--mask"),
        OsStr::new("0,-0.3,0.2:0.2,-0.1,0.4"),
        OsStr::new("--coarse"),
        OsStr::new("4,4,4"),
        OsStr::new("-o"),
        smooth.as_os_str(),
    ]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(smooth.is_file());
    // It also takes the RBF field, sampled onto a grid over its box.
    let from_rbf = dir.path().join("from_rbf.zsf");
    let o = zeroset([
        OsStr::new("restore"),
        rbf.as_os_str(),
        OsStr::new("--mode"),
        OsStr::new("denoise"),
        OsStr::new("--mask"),
        OsStr::new("0,-0.3,0.2:0.2,-0.1,0.4"),
        OsStr::new("--coarse"),
        OsStr::new("4,4,4"),
        OsStr::new("-o"),
        from_rbf.as_os_str(),
    ]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("RBF field"), "{}", stdout(&o));
    assert!(read_field::<3>(&from_rbf).is_ok());

    // Never the input: -o must be a .zsf and not the input; a .zsf input is not a point cloud.
    let before = fs::read(&path).unwrap();
    let o = fit(&path, &["-o", path.to_str().unwrap()]);
    assert_clean_failure(&o);
    assert_eq!(fs::read(&path).unwrap(), before);
    let field_bytes = fs::read(&field).unwrap();
    let o = fit(&field, &["-o", field.to_str().unwrap()]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("would overwrite the input"),
        "{}",
        stderr(&o)
    );
    assert_eq!(fs::read(&field).unwrap(), field_bytes);
    let o = fit(&field, &["-o", smooth.to_str().unwrap(), "--force"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("is a field file"), "{}", stderr(&o));
}

#[test]
fn fit_is_in_the_help() {
    let o = zeroset(["--help"]);
    assert!(stdout(&o).contains("  fit "), "{}", stdout(&o));
    let o = zeroset(["fit", "--help"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for text in [
        "Examples:",
        "--method",
        "--hermite",
        "--offset <auto|EPS>",
        "--solver",
        "--sampled",
        "quadratic B-spline",
        "RBF field itself",
    ] {
        assert!(out.contains(text), "{text:?}:\n{out}");
    }
}

// ---- zeroset mesh ----

/// A sphere RBF field file (`zeroset fit -o`) in a fresh directory.
fn sphere_field() -> (tempfile::TempDir, PathBuf) {
    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(300));
    let field = dir.path().join("sphere.zsf");
    let o = fit(&path, &["-o", field.to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    (dir, field)
}

fn mesh(field: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args: Vec<&OsStr> = vec![
        OsStr::new("mesh"),
        field.as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--quiet"),
    ];
    args.extend(extra.iter().map(OsStr::new));
    zeroset(args)
}

#[test]
fn an_offset_level_set_is_not_called_spurious_and_dropping_all_is_said() {
    let (dir, field) = sphere_field();
    let ply = dir.path().join("shell.ply");
    // An offset surface farther from the points than 3 voxels: the whole mesh was called
    // spurious, and --drop-spurious deleted it saying the level set did not cross the grid.
    let o = mesh(
        &field,
        &ply,
        &["--level", "0.05", "--voxel", "0.01", "--drop-spurious"],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains(
            "spurious: none (every component has an input point within 3 voxels plus \
                      the level's offset"
        ) && out.contains("closed, Euler characteristic 2, 1 component(s)"),
        "{out}"
    );
}

#[test]
fn a_coarse_meshs_winding_is_trusted_not_read_as_unoriented() {
    // The coarsest torus: 3 × 3 vertices, 9 quads, closed and wound outward. Its points (the
    // vertices and points sampled inside the quads) cross creases of 120° everywhere, where
    // the orientation propagated over them read 44% of the winding's normals as flipped:
    // `reconstruct` turned them "as unoriented" and made an open mesh (CGAL's `3torus.off`
    // the same, 48%). A mesh's winding is consistent by construction: taken as it is.
    let mut off = String::from("OFF\n9 9 0\n");
    for i in 0..3 {
        let u = 2.0 * std::f64::consts::PI * i as f64 / 3.0;
        for j in 0..3 {
            let v = 2.0 * std::f64::consts::PI * j as f64 / 3.0;
            let r = 1.0 + 0.5 * v.cos();
            off += &format!("{} {} {}\n", r * u.cos(), r * u.sin(), 0.5 * v.sin());
        }
    }
    for i in 0..3 {
        for j in 0..3 {
            let (next_i, next_j) = ((i + 1) % 3, (j + 1) % 3);
            let corners = [
                i * 3 + j,
                next_i * 3 + j,
                next_i * 3 + next_j,
                i * 3 + next_j,
            ];
            off += &format!(
                "4 {} {} {} {}\n",
                corners[0], corners[1], corners[2], corners[3]
            );
        }
    }
    let (dir, path) = temp_file("ring.off", &off);
    let out = dir.path().join("ring.ply");
    let o = zeroset([
        "reconstruct",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--no-preview",
    ]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(!stdout(&o).contains("unoriented"), "{}", stdout(&o));
    let r = zeroset_mesh::check(&zeroset_mesh::read_mesh(&out).unwrap());
    assert!(
        r.is_oriented_closed() && r.euler_characteristic == 0 && r.signed_volume > 0.0,
        "{r}"
    );
}

#[test]
fn two_spheres_sampled_where_they_touch_are_fitted_by_either_method() {
    // Unit spheres centred at z = ±1, both sampled at the origin where they touch: one
    // position, two normals pointing apart. MRAS refused it ("the same position with opposite
    // normals"); both methods now say how many such places they fitted as two sheets.
    let mut text = String::new();
    for dz in [1.0, -1.0] {
        for (_, n) in sphere_points(600) {
            text += &format!(
                "{} {} {} {} {} {}\n",
                n[0],
                n[1],
                n[2] + dz,
                n[0],
                n[1],
                n[2]
            );
        }
        text += &format!("0 0 0 0 0 {}\n", -dz);
    }
    let (dir, cloud) = temp_file("touching.xyzn", &text);
    for (method, said) in [
        (
            "rbf",
            "(1 of them at a place where an earlier point's normal points the other way",
        ),
        (
            "mras",
            "(at 1 of the places repeated, normals pointing apart meet as two sheets",
        ),
    ] {
        let field = dir.path().join(format!("{method}.zsf"));
        let o = zeroset([
            "fit",
            cloud.to_str().unwrap(),
            "--method",
            method,
            "-o",
            field.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{method}: {}{}", stdout(&o), stderr(&o));
        assert!(stdout(&o).contains(said), "{method}: {}", stdout(&o));
        let ply = dir.path().join(format!("{method}.ply"));
        let o = mesh(&field, &ply, &[]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let r = zeroset_mesh::check(&zeroset_mesh::read_mesh(&ply).unwrap());
        assert!(
            r.is_oriented_closed() && r.signed_volume > 0.0,
            "{method}: {r}"
        );
    }
}

/// `p` and `n` as a line of an `x y z nx ny nz` file.
fn xyzn_line(p: [f64; 3], n: [f64; 3]) -> String {
    format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], n[0], n[1], n[2])
}

/// `zeroset reconstruct` (defaults, no preview) of the cloud `text`, written to a file named
/// `name` in a temporary directory: its standard output and the mesh's check. Fails the test
/// where the command fails.
fn reconstruct_text(name: &str, text: &str) -> (String, zeroset_mesh::MeshReport) {
    let (dir, cloud) = temp_file(name, text);
    let ply = dir.path().join("mesh.ply");
    let o = zeroset([
        "reconstruct",
        cloud.to_str().unwrap(),
        "-o",
        ply.to_str().unwrap(),
        "--no-preview",
    ]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let report = zeroset_mesh::check(&zeroset_mesh::read_mesh(&ply).unwrap());
    (stdout(&o), report)
}

#[test]
fn two_objects_closer_than_their_sampling_keep_their_own_sides() {
    // Two unit spheres 0.1 apart, sampled about every 0.15 with their own outward normals:
    // the orientation check carried one sphere's sign across the gap, read the normals as
    // unoriented (50%), turned them, and the mesh came out open with one sphere inside out.
    let text: String = [-1.05, 1.05]
        .iter()
        .flat_map(|dx| {
            sphere_points(560)
                .into_iter()
                .map(move |(_, n)| xyzn_line([n[0] + dx, n[1], n[2]], n))
        })
        .collect();
    let (out, r) = reconstruct_text("near.xyzn", &text);
    assert!(!out.contains("unoriented"), "{out}");
    assert!(r.is_oriented_closed(), "{r}");
    assert_eq!((r.components, r.euler_characteristic), (2, 4), "{r}");
    // Both outward: the two balls' volume (4.19 each, less the marching cubes' cut corners).
    assert!((r.signed_volume - 8.38).abs() < 0.1, "{r}");
}

#[test]
fn flipped_normals_among_their_neighbours_make_no_bubbles() {
    // A sphere of 3,000 points, every 50th normal flipped: each flipped offset put the
    // field's other sign on its side of the surface, a bump or a bubble there. Fitted through
    // with value 0 only, they leave one closed sphere.
    let text: String = sphere_points(3000)
        .iter()
        .enumerate()
        .map(|(k, (p, n))| {
            let s = if k % 50 == 7 { -1.0 } else { 1.0 };
            xyzn_line(*p, n.map(|x| s * x))
        })
        .collect();
    let (out, r) = reconstruct_text("flipped.xyzn", &text);
    assert!(
        out.contains("60 normals point against most of their nearest neighbours'"),
        "{out}"
    );
    assert_one_closed_sphere(&r);
}

/// `r` is one closed sphere of radius [`RADIUS`], outward, its volume within 1%.
fn assert_one_closed_sphere(r: &zeroset_mesh::MeshReport) {
    assert!(r.is_oriented_closed(), "{r}");
    assert_eq!((r.components, r.euler_characteristic), (1, 2), "{r}");
    let sphere = 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3);
    assert!((r.signed_volume / sphere - 1.0).abs() < 0.01, "{r}");
}

#[test]
fn a_side_whose_normals_face_in_is_turned_back_out() {
    // A sphere of 3,000 points whose normals above z = 0.6 (a fifth of them: what a program
    // turning every normal to one direction does to a closed object's smaller side) face in:
    // under the share that tells arbitrary signs, the fit took that cap as it was (open,
    // Euler characteristic -153). Rays along those normals cross the sphere from inside, so
    // the orientation turns them back.
    let text: String = sphere_points(3000)
        .iter()
        .map(|(p, n)| {
            let s = if n[2] > 0.6 { -1.0 } else { 1.0 };
            xyzn_line(*p, n.map(|x| s * x))
        })
        .collect();
    let (out, r) = reconstruct_text("cap_in.xyzn", &text);
    assert!(
        out.contains("normals face into the object on part of it: 600 of 3000 (20%)"),
        "{out}"
    );
    assert!(out.contains("600 of them turned"), "{out}");
    assert_one_closed_sphere(&r);
}

#[test]
fn an_inside_out_mesh_and_voxels_too_coarse_are_said() {
    // A sphere whose normals all point inward fits a field positive inside: the closed mesh
    // encloses a negative volume, which was reported as if nothing were wrong.
    let inward: String = sphere_points(300)
        .iter()
        .map(|(p, n)| format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], -n[0], -n[1], -n[2]))
        .collect();
    let (dir, cloud) = temp_file("inward.xyzn", &inward);
    let field = dir.path().join("inward.zsf");
    let o = fit(&cloud, &["-o", field.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ply = dir.path().join("inward.ply");
    let o = mesh(&field, &ply, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let inside_out = "warning: the mesh is inside out";
    assert!(stdout(&o).contains(inside_out), "{}", stdout(&o));
    let inside_out_volume = zeroset_mesh::check(&zeroset_mesh::read_mesh(&ply).unwrap());
    assert!(inside_out_volume.signed_volume < 0.0, "{inside_out_volume}");
    // `reconstruct` turns such a mesh over: the same surface, facing out.
    let turned = dir.path().join("turned.ply");
    let o = zeroset([
        "reconstruct",
        cloud.to_str().unwrap(),
        "-o",
        turned.to_str().unwrap(),
        "--method",
        "rbf",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("turned: the mesh came out inside out")
            && !stdout(&o).contains(inside_out),
        "{}",
        stdout(&o)
    );
    let r = zeroset_mesh::check(&zeroset_mesh::read_mesh(&turned).unwrap());
    assert!(r.is_oriented_closed() && r.signed_volume > 0.0, "{r}");
    // Normals that face into the solid on purpose (a room seen from inside): kept as fitted.
    let kept = dir.path().join("kept.ply");
    let o = zeroset([
        "reconstruct",
        cloud.to_str().unwrap(),
        "-o",
        kept.to_str().unwrap(),
        "--method",
        "rbf",
        "--keep-inside-out",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(inside_out), "{}", stdout(&o));
    let k = zeroset_mesh::check(&zeroset_mesh::read_mesh(&kept).unwrap());
    assert!(k.signed_volume < 0.0, "{k}");
    assert!(
        (r.signed_volume + inside_out_volume.signed_volume).abs() < 0.02 * r.signed_volume,
        "{r} against {inside_out_volume}"
    );
    let (_d, outward) = sphere_field();
    let o = mesh(&outward, &ply, &["--force"]);
    assert!(!stdout(&o).contains(inside_out), "{}", stdout(&o));
    // Voxels wider than the sphere: the field crosses the level between the grid's vertices.
    // The message blamed the level and the report called the empty mesh open.
    let o = mesh(&outward, &ply, &["--force", "--voxel", "10"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("a smaller --voxel or a larger --resolution catches it")
            && out.contains("report: empty")
            && !out.contains("--level picks another level"),
        "{out}"
    );
}

#[test]
fn scan_points_no_component_reaches_are_reported() {
    // The sphere and, beside it, a ball a tenth its size sampled by 60 points: at a coarse
    // resolution the grid steps over the ball, and the scan's points there are said to be
    // missed; at a fine one they are not.
    let mut text = sphere_xyzn(400);
    for (p, n) in sphere_points(60) {
        let q: Vec<f64> = (0..3).map(|a| 1.2 + (p[a] - CENTRE[a]) * 0.1).collect();
        text.push_str(&format!(
            "{} {} {} {} {} {}\n",
            q[0], q[1], q[2], n[0], n[1], n[2]
        ));
    }
    let (dir, cloud) = temp_file("two.xyzn", &text);
    let field = dir.path().join("two.zsf");
    let o = fit(
        &cloud,
        &["--outlier-ratio", "0", "-o", field.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let ply = dir.path().join("two.ply");
    let scan = cloud.to_str().unwrap();
    let coarse = mesh(&field, &ply, &["--scan", scan, "--resolution", "12"]);
    let out = stdout(&coarse);
    assert!(out.contains("missed: 60 of 460 input points"), "{out}");
    let fine = mesh(
        &field,
        &ply,
        &["--scan", scan, "--resolution", "96", "--force"],
    );
    let out = stdout(&fine);
    assert!(
        !out.contains("missed:") && out.contains("2 component(s)"),
        "{out}"
    );
}

#[test]
fn mesh_writes_a_closed_sphere_as_ply_and_obj() {
    let (dir, field) = sphere_field();
    let ply = dir.path().join("s.ply");
    let o = mesh(&field, &ply, &[]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    for text in [
        "RBF field (kernel r, ",
        "grid ",
        "voxel ",
        "l0 = ",
        "vertices",
        "triangles",
        "closed",
        "Euler characteristic 2",
        "1 component(s)",
        "0 boundary edge(s)",
        "signed volume",
        "binary PLY",
        "time: ",
    ] {
        assert!(out.contains(text), "{text:?}:\n{out}");
    }
    let m = zeroset_mesh::io::read_ply_mesh(&ply).expect("a readable PLY");
    let r = zeroset_mesh::check(&m);
    assert!(r.is_oriented_closed(), "{r}");
    assert_eq!(r.euler_characteristic, 2, "{r}");
    let sphere = 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3);
    assert!(
        (r.signed_volume - sphere).abs() < 0.05 * sphere,
        "volume {} vs {sphere}",
        r.signed_volume
    );

    // OBJ by extension, ASCII PLY, --resolution, --voxel and --detail.
    let obj = dir.path().join("s.obj");
    let o = mesh(&field, &obj, &["--resolution", "24"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let text = fs::read_to_string(&obj).unwrap();
    assert!(text.lines().any(|l| l.starts_with("v ")));
    assert!(text.lines().any(|l| l.starts_with("f ")));
    assert!(stdout(&o).contains("24 voxels along the longest axis"));
    let ascii = dir.path().join("a.ply");
    let o = mesh(&field, &ascii, &["--ascii", "--voxel", "0.05", "--close"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(
        fs::read_to_string(&ascii)
            .unwrap()
            .contains("format ascii 1.0")
    );
    let coarse = dir.path().join("c.ply");
    let o = mesh(&field, &coarse, &["--detail", "coarse"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("Coarse detail"), "{}", stdout(&o));

    // A sampled B-spline field (`fit -o --sampled`) meshes too, over its grid's box.
    let sampled = dir.path().join("sampled.zsf");
    let o = fit(
        &dir.path().join("sphere.xyzn"),
        &[
            "-o",
            sampled.to_str().unwrap(),
            "--sampled",
            "--grid",
            "32,32,32",
        ],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let bs = dir.path().join("bs.ply");
    let o = mesh(&sampled, &bs, &[]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("Quadratic B-spline"), "{}", stdout(&o));
    let r = zeroset_mesh::check(&zeroset_mesh::io::read_ply_mesh(&bs).unwrap());
    assert!(r.is_oriented_closed(), "{r}");
    assert_eq!(r.euler_characteristic, 2, "{r}");

    // STL (binary, or ASCII) and OBJ: the same closed sphere, which info and preview read.
    for (name, extra, kind) in [
        ("s.stl", &[][..], "binary STL"),
        ("a.stl", &["--ascii"][..], "ASCII STL"),
        ("w.obj", &[][..], "OBJ"),
    ] {
        let out = dir.path().join(name);
        let o = mesh(&sampled, &out, extra);
        assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
        assert!(stdout(&o).contains(&format!("({kind})")), "{}", stdout(&o));
        let m = zeroset_mesh::read_mesh(&out).unwrap();
        let r = zeroset_mesh::check(&m);
        assert!(
            r.is_oriented_closed() && r.euler_characteristic == 2,
            "{name}: {r}"
        );
        let o = zeroset(["info", out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = stdout(&o);
        assert!(
            text.contains("(mesh)") && text.contains("closed:      yes"),
            "{text}"
        );
        let png = dir.path().join(format!("{name}.png"));
        let o = zeroset([
            "preview",
            out.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ]);
        assert!(o.status.success() && png.is_file(), "{}", stderr(&o));
    }
    let o = mesh(&sampled, &dir.path().join("t.obj"), &["--ascii"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("which is always text"),
        "{}",
        stderr(&o)
    );

    // A mesh file is a point cloud too: its vertices, normals from its winding — outward, as
    // the fit's check at the input points shows (|∇f| ≈ 1 along the normal).
    let stl = dir.path().join("s.stl");
    let o = fit(
        &stl,
        &["-o", dir.path().join("from_stl.zsf").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains("an STL mesh of") && text.contains("normals from the triangles' winding"),
        "{text}"
    );
    let refit = dir.path().join("from_stl.ply");
    let o = mesh(&dir.path().join("from_stl.zsf"), &refit, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r = zeroset_mesh::check(&zeroset_mesh::read_mesh(&refit).unwrap());
    assert!(
        r.is_oriented_closed() && r.euler_characteristic == 2 && r.signed_volume > 0.0,
        "{r}"
    );
    // `reconstruct` reads the mesh in each stage and says what it took once.
    let o = zeroset([
        "reconstruct",
        stl.to_str().unwrap(),
        "-o",
        dir.path().join("rebuilt.ply").to_str().unwrap(),
        "--no-preview",
    ]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(
        stdout(&o).matches("an STL mesh of").count(),
        1,
        "{}",
        stdout(&o)
    );

    // The same sphere wound inward beside a copy wound outward, as OBJ: the inward part is
    // turned over on its own, and the fit is outward on both.
    let sphere = zeroset_mesh::read_mesh(&stl).unwrap();
    let (v, t, _) = sphere.into_parts();
    let n = v.len() as u32;
    let mut vertices = v.clone();
    vertices.extend(v.iter().map(|p| [p[0] + 3.0, p[1], p[2]]));
    let mut triangles: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    triangles.extend(t.iter().map(|tri| tri.map(|i| i + n)));
    let two = dir.path().join("two.obj");
    zeroset_mesh::write_obj(
        &two,
        &zeroset_mesh::TriMesh::new(vertices, triangles).unwrap(),
    )
    .unwrap();
    let o = fit(&two, &["-o", dir.path().join("two.zsf").to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(
        stdout(&o).contains("turned over on 1 of 2 closed part(s) wound inward"),
        "{}",
        stdout(&o)
    );
    let o = mesh(
        &dir.path().join("two.zsf"),
        &dir.path().join("two.ply"),
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let r = zeroset_mesh::check(&zeroset_mesh::read_mesh(dir.path().join("two.ply")).unwrap());
    assert!(
        r.is_oriented_closed() && r.components == 2 && r.signed_volume > 0.0,
        "{r}"
    );

    // A CAD-like mesh: a cube of 12 triangles. Its 8 corners alone fit a blob; the points
    // sampled inside its faces give a closed box of about its volume.
    let cube = dir.path().join("cube.obj");
    fs::write(
        &cube,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n\
         f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n",
    )
    .unwrap();
    let o = fit(
        &cube,
        &["-o", dir.path().join("cube.zsf").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(
        stdout(&o).contains("points inside its triangles"),
        "{}",
        stdout(&o)
    );
    let o = mesh(
        &dir.path().join("cube.zsf"),
        &dir.path().join("cube.stl"),
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let r = zeroset_mesh::check(&zeroset_mesh::read_mesh(dir.path().join("cube.stl")).unwrap());
    assert!(r.is_oriented_closed() && r.components == 1, "{r}");
    assert!((r.signed_volume - 1.0).abs() < 0.02, "{r}");

    // The sphere as two patches modelled apart (an OFF whose bottom cap, 30% of its height,
    // has vertices of its own along the seam) and wound against each other: open, so taken
    // as wound — but the seam says the two disagree, the cap (fewer triangles) is turned to
    // agree with the rest, and the fit closes one outward sphere.
    let (bottom, top) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[2]), hi.max(p[2]))
        });
    let cut = bottom + 0.3 * (top - bottom);
    let lower = |tri: &[u32; 3]| tri.iter().map(|&i| v[i as usize][2]).sum::<f64>() < 3.0 * cut;
    let mut vertices = v.clone();
    let mut triangles: Vec<[u32; 3]> = t.iter().filter(|tri| !lower(tri)).copied().collect();
    triangles.extend(
        t.iter()
            .filter(|tri| lower(tri))
            .map(|&[a, b, c]| [c + n, b + n, a + n]),
    );
    vertices.extend(v.iter().copied());
    let halves = zeroset_mesh::TriMesh::new(vertices, triangles)
        .unwrap()
        .retain_triangles(|_| true);
    let patches = dir.path().join("halves.off");
    zeroset_mesh::write_off(&patches, &halves).unwrap();
    let o = fit(
        &patches,
        &["-o", dir.path().join("halves.zsf").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(
        stdout(&o).contains(
            "(an open mesh: as wound, but 1 of its 2 parts turned over to agree with the parts \
             they meet along seams)"
        ),
        "{}",
        stdout(&o)
    );
    let o = mesh(
        &dir.path().join("halves.zsf"),
        &dir.path().join("halves.ply"),
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let r = zeroset_mesh::check(&zeroset_mesh::read_mesh(dir.path().join("halves.ply")).unwrap());
    assert!(
        r.is_oriented_closed()
            && r.components == 1
            && r.euler_characteristic == 2
            && r.signed_volume > 0.0,
        "{r}"
    );
}

#[test]
fn a_wendland_radius_under_a_few_spacings_is_warned_of() {
    let (_d, path) = temp_file("s.xyzn", &sphere_xyzn(300));
    let o = fit(&path, &["--kernel", "wendland", "--radius", "0.2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("warning: under 5 median point spacings"),
        "{}",
        stdout(&o)
    );
    let o = fit(&path, &["--kernel", "wendland"]);
    assert!(!stdout(&o).contains("point spacings"), "{}", stdout(&o));
}

#[test]
fn info_describes_a_value_file() {
    let curve = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/curve.xyv"
    ));
    let o = info(&curve, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for phrase in [
        "format:      2-D value constraints",
        "constraints: 60 (15 negative, 30 zero, 15 positive)",
        "values:      from -1 to 1, 3 distinct: -1, 0, 1",
        "duplicates:  none",
    ] {
        assert!(out.contains(phrase), "{phrase:?} missing in:\n{out}");
    }
}

#[test]
fn format_xyv_reads_a_value_file_of_any_name() {
    let curve = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/curve.xyv"
    ));
    let dir = tempfile::tempdir().unwrap();
    let txt = dir.path().join("curve.txt");
    std::fs::copy(&curve, &txt).unwrap();
    let field = |input: &Path, name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec!["-o", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = fit(input, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(out).unwrap()
    };
    assert_eq!(
        field(&txt, "txt.zsf", &["--format", "xyv"]),
        field(&curve, "xyv.zsf", &[])
    );
    let o = info(&txt, &["--format", "xyv"]);
    assert!(
        stdout(&o).contains("constraints: 60 (15 negative, 30 zero, 15 positive)"),
        "{}",
        stdout(&o)
    );
    // Commands that take point clouds say what a value file is.
    let refused = |args: &[&OsStr], phrase: &str| {
        let o = zeroset(args);
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(phrase), "{}", stderr(&o));
    };
    let (m, n) = (dir.path().join("m.zsf"), dir.path().join("n.ply"));
    let os = OsStr::new;
    refused(
        &[
            os("fit"),
            curve.as_os_str(),
            os("--method"),
            os("mras"),
            os("-o"),
            m.as_os_str(),
        ],
        "a file of 2-D value constraints (x y value per line), not a point cloud",
    );
    refused(
        &[
            os("normals"),
            txt.as_os_str(),
            os("--format"),
            os("xyv"),
            os("-o"),
            n.as_os_str(),
        ],
        "--format xyv names a value-constraint file",
    );
}

#[test]
fn equal_values_are_refused_and_an_empty_mesh_says_where_the_field_runs() {
    // One surface's points, all at value 0: the interpolant would be 0 everywhere.
    let (_d, values) = temp_file("horizon.xyzv", "0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n");
    let o = fit(&values, &["--formation", "A"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("--formation applies"), "{}", stderr(&o));
    let o = fit(&values, &[]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("all 4 values are 0: the interpolant is that constant everywhere"),
        "{}",
        stderr(&o)
    );
    let (dir, field) = sphere_field();
    let o = mesh(&field, &dir.path().join("e.ply"), &["--level", "100"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains(
            "the level set does not cross the grid: the mesh is empty (the field runs from"
        ),
        "{}",
        stdout(&o)
    );
}

#[test]
fn mesh_refuses_bad_outputs_and_grids_with_a_message() {
    let (dir, field) = sphere_field();
    let out = dir.path().join("s.ply");
    fs::write(&out, "keep me").unwrap();

    // An existing output needs --force, and stays as it was without.
    let o = mesh(&field, &out, &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(fs::read_to_string(&out).unwrap(), "keep me");
    let o = mesh(&field, &out, &["--force", "--detail", "coarse"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(zeroset_mesh::io::read_ply_mesh(&out).is_ok());

    // Never the input, even with --force.
    let before = fs::read(&field).unwrap();
    let o = mesh(&field, &field, &["--force"]);
    assert_clean_failure(&o);
    assert_eq!(fs::read(&field).unwrap(), before);

    let cases: [(PathBuf, &[&str], &str); 8] = [
        (
            dir.path().join("s.3mf"),
            &[],
            ".ply or .obj or .stl or .off",
        ),
        (dir.path().join("s"), &[], ".ply or .obj or .stl or .off"),
        (
            dir.path().join("missing").join("s.ply"),
            &[],
            "does not exist",
        ),
        (
            dir.path().join("r.ply"),
            &["--resolution", "1"],
            "at least 2",
        ),
        (
            dir.path().join("v.ply"),
            &["--voxel", "0"],
            "finite positive",
        ),
        (
            dir.path().join("n.ply"),
            &["--voxel", "-0.1"],
            "finite positive",
        ),
        (dir.path().join("m.ply"), &["--voxel", "1e-4"], "memory"),
        (
            dir.path().join("h.ply"),
            &["--voxel", "1e-7"],
            "larger voxel",
        ),
    ];
    for (path, extra, text) in cases {
        let o = mesh(&field, &path, extra);
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(text), "{extra:?}: {}", stderr(&o));
        assert!(!path.exists(), "{}", path.display());
    }
    // Nothing but the field, its cloud and the forced output was left behind.
    let mut names: Vec<String> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["s.ply", "sphere.xyzn", "sphere.zsf"]);

    // A missing field file.
    let o = mesh(&dir.path().join("none.zsf"), &dir.path().join("x.ply"), &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("none.zsf"), "{}", stderr(&o));
}

#[test]
fn mesh_is_in_the_help() {
    let o = zeroset(["--help"]);
    assert!(stdout(&o).contains("  mesh "), "{}", stdout(&o));
    let o = zeroset(["mesh", "--help"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for text in [
        "Examples:",
        "--detail",
        "--resolution",
        "--voxel",
        "--close",
        "--force",
    ] {
        assert!(out.contains(text), "{text:?}:\n{out}");
    }
}

// ---- zeroset preview ----

fn preview(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args: Vec<&OsStr> = vec![
        OsStr::new("preview"),
        input.as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--quiet"),
    ];
    args.extend(extra.iter().map(OsStr::new));
    zeroset(args)
}

/// A sphere field file from `zeroset fit -o` alone (whatever kind fit writes by default).
fn preview_field() -> (tempfile::TempDir, PathBuf) {
    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(300));
    let field = dir.path().join("s.zsf");
    let o = fit(&path, &["-o", field.to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    (dir, field)
}

/// An octahedron as an ASCII PLY, wound outward.
const OCTAHEDRON_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\n\
property float y\nproperty float z\nelement face 8\nproperty list uchar int vertex_indices\n\
end_header\n1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0 1\n0 0 -1\n3 0 2 4\n3 2 1 4\n3 1 3 4\n\
3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n3 0 3 5\n";

/// The width and height of a PNG file, checking its signature and IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.len() > 33,
        "{} is too short for a PNG",
        path.display()
    );
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    (w, h)
}

#[test]
fn preview_renders_a_field_a_slice_and_a_mesh() {
    let (dir, field) = preview_field();
    let a = dir.path().join("a.png");
    let o = preview(&field, &a, &["--width", "300", "--height", "200"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(png_size(&a), (300, 200));
    assert!(stdout(&o).contains("triangles"), "{}", stdout(&o));

    let s = dir.path().join("slice.png");
    let o = preview(
        &field,
        &s,
        &["--slice", "z", "--width", "160", "--height", "160"],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(png_size(&s), (160, 160));
    assert!(stdout(&o).contains("slice z"), "{}", stdout(&o));
    let s2 = dir.path().join("slice_x.png");
    let o = preview(
        &field,
        &s2,
        &["--slice", "x=0.1", "--width", "64", "--height", "64"],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let (w, h) = png_size(&s2);
    assert!(w.max(h) == 64, "{w}×{h}");

    let ply = dir.path().join("s.ply");
    std::fs::write(&ply, OCTAHEDRON_PLY).unwrap();
    let b = dir.path().join("b.png");
    let o = preview(&ply, &b, &["--azimuth", "-60", "--elevation", "10"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(png_size(&b), (800, 800));
    assert!(stdout(&o).contains("triangles"), "{}", stdout(&o));

    // --up: the octahedron stretched along y is drawn standing up with --up y; the same view
    // with z up draws it otherwise (meshes from graphics tools lay on their side).
    let tall = dir.path().join("tall.ply");
    std::fs::write(
        &tall,
        OCTAHEDRON_PLY.replace("\n0 1 0\n0 -1 0\n", "\n0 2 0\n0 -2 0\n"),
    )
    .unwrap();
    let [y, z] = ["y", "z"].map(|up| {
        let png = dir.path().join(format!("up_{up}.png"));
        let o = preview(
            &tall,
            &png,
            &["--up", up, "--width", "100", "--height", "100"],
        );
        assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
        std::fs::read(&png).unwrap()
    });
    assert_ne!(y, z);
    let o = preview(&tall, &dir.path().join("w.png"), &["--up", "w"]);
    assert!(
        !o.status.success() && stderr(&o).contains("'w'"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn preview_refuses_bad_outputs_and_inputs_with_a_message() {
    let (dir, field) = preview_field();
    let a = dir.path().join("a.png");
    std::fs::write(&a, b"old").unwrap();

    // An existing output needs --force, and is left alone without it.
    let o = preview(&field, &a, &["--width", "32", "--height", "32"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&a).unwrap(), b"old");
    let o = preview(&field, &a, &["--width", "32", "--height", "32", "--force"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(png_size(&a), (32, 32));

    // The output must be a .png, in a directory that exists, and never the input.
    let o = preview(&field, &dir.path().join("a.jpg"), &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains(".png"), "{}", stderr(&o));
    let o = preview(&field, &dir.path().join("no/such/dir/a.png"), &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
    let o = preview(&a, &a, &["--force"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("input"), "{}", stderr(&o));

    // Bad slices, a slice of a mesh, a malformed OBJ mesh, a missing input.
    let o = preview(&field, &dir.path().join("w.png"), &["--slice", "w"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("x, y or z"), "{}", stderr(&o));
    let o = preview(&field, &dir.path().join("w.png"), &["--slice", "z=1e3"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("outside the field's box"),
        "{}",
        stderr(&o)
    );
    let obj = dir.path().join("s.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap();
    let o = preview(&obj, &dir.path().join("o.png"), &[]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("OBJ line 4: corner 2 '4': vertex index 4 is out of range"),
        "{}",
        stderr(&o)
    );
    let o = preview(&obj, &dir.path().join("o.png"), &["--slice", "z"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("--slice"), "{}", stderr(&o));
    let o = preview(&dir.path().join("none.zsf"), &dir.path().join("n.png"), &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("none.zsf"), "{}", stderr(&o));
    for name in ["w.png", "o.png", "n.png", "a.jpg"] {
        assert!(!dir.path().join(name).exists(), "{name} was written");
    }
}

#[test]
fn preview_is_in_the_help() {
    let o = zeroset(["--help"]);
    assert!(stdout(&o).contains("preview"), "{}", stdout(&o));
    let o = zeroset(["preview", "--help"]);
    assert!(o.status.success());
    for flag in ["--slice", "--width", "--azimuth", "--force", "Examples:"] {
        assert!(stdout(&o).contains(flag), "{flag}: {}", stdout(&o));
    }
}

// ---- --threads ----

#[test]
fn threads_do_not_change_the_report() {
    let one = zeroset([
        OsStr::new("--threads"),
        OsStr::new("1"),
        OsStr::new("info"),
        sample().as_os_str(),
    ]);
    let three = zeroset([
        OsStr::new("--threads"),
        OsStr::new("3"),
        OsStr::new("info"),
        sample().as_os_str(),
    ]);
    assert!(one.status.success(), "{}", stderr(&one));
    assert!(three.status.success(), "{}", stderr(&three));
    assert!(!one.stdout.is_empty());
    assert_eq!(stdout(&one), stdout(&three));
    // Global: also accepted after the subcommand.
    let after = info(&sample(), &["--threads", "2"]);
    assert!(after.status.success(), "{}", stderr(&after));
    assert_eq!(stdout(&one), stdout(&after));
}

#[test]
fn threads_zero_is_a_clear_error() {
    for bad in ["0", "x", "-1"] {
        let o = zeroset([
            OsStr::new("--threads"),
            OsStr::new(bad),
            OsStr::new("info"),
            sample().as_os_str(),
        ]);
        assert!(!o.status.success(), "--threads {bad} accepted");
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
        assert!(stderr(&o).contains("--threads"), "{}", stderr(&o));
        assert!(stderr(&o).contains("at least 1"), "{}", stderr(&o));
        assert!(o.stdout.is_empty());
    }
    let o = zeroset(["--help"]);
    assert!(stdout(&o).contains("--threads"), "{}", stdout(&o));
}

// ---- zeroset info on a mesh ----

#[test]
fn an_obj_of_vertices_only_is_a_point_cloud() {
    // 200 points on a sphere with their normals, as `v` and `vn` lines and no face: info says
    // what the fitting commands make of it, and fit reads it with its normals.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cloud.obj");
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut text = String::new();
    for i in 0..200 {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / 200.0;
        let r = (1.0 - z * z).sqrt();
        let (x, y) = (r * (golden * i as f64).cos(), r * (golden * i as f64).sin());
        text.push_str(&format!("v {x} {y} {z}\nvn {x} {y} {z}\n"));
    }
    fs::write(&path, text).unwrap();
    let o = info(&path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("read the 200 vertices as a point cloud with their normals"),
        "{}",
        stdout(&o)
    );
    let o = fit(&path, &[]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(
        stdout(&o).contains("200 points with normals"),
        "{}",
        stdout(&o)
    );
}

#[test]
fn info_reports_a_ply_mesh() {
    let path = std::env::var_os("ZEROSET_DATA")
        .map_or_else(
            || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data"),
            PathBuf::from,
        )
        .join("bun_zipper.ply");
    assert!(path.is_file(), "test data {} not found", path.display());
    let o = info(&path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for text in [
        "ply (mesh)",
        "triangles:   69451",
        "used by triangles",
        "closed:      no",
        "in 5 loops",
        "0 non-manifold",
        "0 inconsistent",
        "Euler characteristic -3",
        "1 component",
        "volume:",
        "area:",
        "bounds:",
    ] {
        assert!(out.contains(text), "{text:?}:\n{out}");
    }
}

#[test]
fn info_reports_a_written_mesh_and_keeps_point_clouds() {
    let (dir, field) = sphere_field();
    let ply = dir.path().join("s.ply");
    let o = mesh(&field, &ply, &["--resolution", "20"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = info(&ply, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for text in ["ply (mesh)", "closed:      yes", "Euler characteristic 2"] {
        assert!(out.contains(text), "{text:?}:\n{out}");
    }
    // A PLY without faces is still a point cloud.
    let (_d, cloud) = temp_file("cloud.ply", &sphere_ply(50));
    let o = info(&cloud, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("50 points"), "{}", stdout(&o));
    assert!(!stdout(&o).contains("mesh"), "{}", stdout(&o));
}

#[test]
fn commands_survive_a_closed_stdout() {
    use std::process::Stdio;
    let (dir, field) = sphere_field();
    let cloud = dir.path().join("sphere.xyzn");
    let fitted = dir.path().join("refit.zsf");
    let mesh = dir.path().join("p.ply");
    let restored = dir.path().join("no_ears.zsf");
    let (cloud, field, sample) = (cloud.to_str().unwrap(), field.to_str().unwrap(), sample());
    let sample = sample.to_str().unwrap();
    let runs: [(&[&str], &Path); 3] = [
        (&["fit", cloud, "--method", "rbf", "-o"], &fitted),
        (&["mesh", field, "--resolution", "16", "-o"], &mesh),
        (
            &[
                "restore",
                sample,
                "--mode",
                "protrusion",
                "--mask",
                EARS,
                "--face",
                "-y",
                "-o",
            ],
            &restored,
        ),
    ];
    for (args, out) in runs {
        let mut child = Command::new(env!("CARGO_BIN_EXE_zeroset"))
            .args(args)
            .arg(out)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Close the read end at once, like `| head -0`: the report goes nowhere, the work and
        // its output file are still done.
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        let what = args[0];
        assert!(!stderr(&o).contains("panicked"), "{what}: {}", stderr(&o));
        assert!(o.status.success(), "{what}: {}", stderr(&o));
        assert!(out.is_file(), "{what}: {} was not written", out.display());
    }
}

#[test]
fn fit_and_restore_refuse_an_existing_output_without_force() {
    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(100));
    let out = dir.path().join("field.zsf");
    fs::write(&out, "keep me").unwrap();

    // fit -o: refused without --force, the file left as it was.
    let o = fit(&path, &["-o", out.to_str().unwrap()]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(fs::read_to_string(&out).unwrap(), "keep me");
    // With --force it is overwritten by a field file.
    let o = fit(&path, &["-o", out.to_str().unwrap(), "--force"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(&fs::read(&out).unwrap()[..8], b"ZSFIELD\0");

    // restore -o: the same.
    let restored = dir.path().join("restored.zsf");
    fs::write(&restored, "keep me").unwrap();
    let restore = |extra: &[&str]| {
        let mut args: Vec<&OsStr> = vec![
            OsStr::new("restore"),
            path.as_os_str(),
            OsStr::new("--mode"),
            OsStr::new("protrusion"),
            OsStr::new("--mask"),
            OsStr::new("0.1,0.1,0.1:0.3,0.3,0.3"),
            OsStr::new("--grid"),
            OsStr::new("16,16,16"),
            OsStr::new("-o"),
            restored.as_os_str(),
        ];
        args.extend(extra.iter().map(OsStr::new));
        zeroset(args)
    };
    let o = restore(&[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(fs::read_to_string(&restored).unwrap(), "keep me");
    let o = restore(&["--force"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(&fs::read(&restored).unwrap()[..8], b"ZSFIELD\0");
}

#[test]
fn mesh_smc_reports_the_counts_and_matches_plain_marching_cubes() {
    let (dir, field) = sphere_field();
    let smc = dir.path().join("smc.ply");
    let args = [
        "--method",
        "smc",
        "--always-smc",
        "--order",
        "5",
        "--high-order",
        "9",
        "--resolution",
        "32",
    ];
    let o = mesh(&field, &smc, &args);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    for text in [
        "fmm: order 5 (sampled max error ",
        "margin ",
        "N_MC ",
        "N_SMC,p ",
        "N_SMC,P ",
        "gamma = ",
        "Euler characteristic 2",
    ] {
        assert!(out.contains(text), "{text:?}:\n{out}");
    }
    assert!(out.contains("step 1: ") && out.contains("probe: "), "{out}");
    // Step 1 by blocks or at every vertex: the same mesh, byte for byte.
    let steps: Vec<Vec<u8>> = ["blocks", "every"]
        .iter()
        .map(|step| {
            let path = dir.path().join(format!("smc-{step}.ply"));
            let o = mesh(&field, &path, &[&args[..], &["--step", step]].concat());
            assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
            let out = stdout(&o);
            let expect = if *step == "blocks" {
                "step 1: blocks settled by enclosures"
            } else {
                "step 1: every vertex"
            };
            assert!(out.contains(expect), "{out}");
            fs::read(&path).expect("mesh file")
        })
        .collect();
    assert_eq!(
        steps[0], steps[1],
        "blocks and every vertex give the same mesh"
    );
    // The exact field meshed by plain marching cubes: the same surface up to the expansion's
    // error (the meshes are not bitwise equal: order 9 is not the direct sum).
    let mc = dir.path().join("mc.ply");
    let o = mesh(&field, &mc, &["--resolution", "32"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let a = zeroset_mesh::io::read_ply_mesh(&smc).expect("smc mesh");
    let b = zeroset_mesh::io::read_ply_mesh(&mc).expect("mc mesh");
    assert_eq!(a.num_triangles(), b.num_triangles());
    let ra = zeroset_mesh::check(&a);
    let rb = zeroset_mesh::check(&b);
    assert!((ra.signed_volume - rb.signed_volume).abs() < 1e-6 * rb.signed_volume.abs());

    // Bad orders are messages, not panics.
    for (p, high) in [("1", "9"), ("8", "6"), ("5", "17")] {
        let bad = dir.path().join("bad.ply");
        let o = mesh(
            &field,
            &bad,
            &[
                "--method",
                "smc",
                "--order",
                p,
                "--high-order",
                high,
                "--force",
            ],
        );
        assert_clean_failure(&o);
        assert!(stderr(&o).contains("order"), "{}", stderr(&o));
    }
}

/// `--method smc` where plain marching cubes is cheaper (a small field on a coarse grid): the
/// plan says so and plain marching cubes on the exact field runs, byte for byte the mesh of
/// `--method mc`.
#[test]
fn mesh_smc_picks_plain_marching_cubes_where_it_is_faster() {
    let (dir, field) = sphere_field();
    let (smc, mc) = (dir.path().join("smc.ply"), dir.path().join("mc.ply"));
    let o = mesh(&field, &smc, &["--method", "smc", "--resolution", "12"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("plan: plain marching cubes about "), "{out}");
    assert!(
        out.contains("plain marching cubes on the exact field is faster here"),
        "{out}"
    );
    assert!(!out.contains("N_SMC,p"), "{out}");
    let o = mesh(&field, &mc, &["--resolution", "12"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(fs::read(&smc).expect("smc") == fs::read(&mc).expect("mc"));
}

/// The operators go to the disk cache on the first `--method smc` and are read back by the
/// next run, which writes the same mesh.
#[test]
fn mesh_smc_reuses_operators_from_the_disk_cache() {
    let (dir, field) = sphere_field();
    let cache = dir.path().join("cache");
    let run = |name: &str| {
        let out = dir.path().join(name);
        let o = zeroset_with_cache(
            [
                OsStr::new("mesh"),
                field.as_os_str(),
                OsStr::new("-o"),
                out.as_os_str(),
                OsStr::new("--quiet"),
                OsStr::new("--method"),
                OsStr::new("smc"),
                OsStr::new("--always-smc"),
                OsStr::new("--resolution"),
                OsStr::new("24"),
            ],
            &cache,
        );
        assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
        (stdout(&o), fs::read(&out).expect("mesh"))
    };
    let (first, a) = run("a.ply");
    assert!(
        first.contains("operators of order 5 to be built, of order 10 to be built"),
        "{first}"
    );
    // One file per order whose tree has M2L pairs (this small field's order-10 tree, with
    // its larger leaves, may have none).
    let files = fs::read_dir(cache.join("fmm"))
        .expect("cache written")
        .count();
    assert!((1..=2).contains(&files), "{files} files");
    let (second, b) = run("b.ply");
    assert!(second.contains("in the disk cache"), "{second}");
    assert!(a == b, "the same mesh from cached operators");
}

// ---- zeroset fit --method neural ----

fn curve_sample() -> PathBuf {
    let path = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/curve.xyv"
    ));
    assert!(path.is_file(), "sample {} not found", path.display());
    path
}

fn fit_neural(path: &Path, extra: &[&str]) -> Output {
    let mut args: Vec<&OsStr> = vec![
        OsStr::new("fit"),
        path.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("neural"),
        OsStr::new("--quiet"),
    ];
    args.extend(extra.iter().map(OsStr::new));
    zeroset(args)
}

#[test]
fn fit_neural_on_a_small_cloud_then_mesh_info_preview_and_restore() {
    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(150));
    let field = dir.path().join("sphere_nn.zsf");
    let o = fit_neural(
        &path,
        &[
            "--steps",
            "150",
            "--aux",
            "100",
            "-o",
            field.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    for want in [
        "network:      MLP 3 → 32 → 32 → 1, tanh",
        "150 steps",
        "max residual:",
        "wrote ",
    ] {
        assert!(out.contains(want), "{want:?} missing in:\n{out}");
    }
    let o = info(&field, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("kind:        neural") && out.contains("dimension:   3"),
        "{out}"
    );
    let ply = dir.path().join("sphere_nn.ply");
    let o = mesh(&field, &ply, &["--resolution", "24"]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("neural field (MLP 3 → 32 → 32 → 1, tanh)"),
        "{out}"
    );
    let vertices = reported(&out, "mesh:");
    assert!(vertices > 100.0, "{out}");
    let png = dir.path().join("sphere_nn.png");
    let o = preview(&field, &png, &["--slice", "z"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(png_size(&png).0 > 0);
    // smc needs an RBF field.
    let o = mesh(&field, &dir.path().join("smc.ply"), &["--method", "smc"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("field of kind neural: use --method mc"),
        "{}",
        stderr(&o)
    );
    // Refused as soon as the field is read, before the grid is laid out.
    assert!(!stdout(&o).contains("grid"), "{}", stdout(&o));
    // Restoration samples the neural field on a grid like an RBF field.
    let restored = dir.path().join("restored.zsf");
    let (f, r) = (field.to_str().unwrap(), restored.to_str().unwrap());
    let o = zeroset(
        [
            "restore",
            f,
            "--mode",
            "denoise",
            "--mask",
            "0.0,-0.3,0.2:0.2,-0.1,0.4",
        ]
        .into_iter()
        .chain(["--coarse", "3,3,3", "--grid", "24,24,24", "-o", r]),
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("neural field"), "{}", stdout(&o));
}

#[test]
fn fit_neural_on_the_curve_sample_then_trace_and_draw_it() {
    let dir = tempfile::tempdir().unwrap();
    let field = dir.path().join("curve.zsf");
    let o = fit_neural(
        &curve_sample(),
        &[
            "--steps",
            "600",
            "--refit-last-layer",
            "-o",
            field.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("60 2-D value constraints (15 negative, 30 zero, 15 positive)"),
        "{out}"
    );
    assert!(out.contains("refit:") && out.contains("dense-qr"), "{out}");
    let o = info(&field, &[]);
    assert!(
        stdout(&o).contains("dimension:   2"),
        "{}{}",
        stdout(&o),
        stderr(&o)
    );
    let svg = dir.path().join("curve.svg");
    let o = mesh(&field, &svg, &[]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(
        stdout(&o).contains("curve: 1 closed loop(s)"),
        "{}",
        stdout(&o)
    );
    assert!(fs::read_to_string(&svg).unwrap().contains("<svg"));
    let o = mesh(&field, &dir.path().join("curve.ply"), &[]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains(".svg"), "{}", stderr(&o));
    let png = dir.path().join("curve.png");
    let o = preview(&field, &png, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("2-D neural field"), "{}", stdout(&o));
    let o = preview(&field, &dir.path().join("s.png"), &["--slice", "z"]);
    assert_clean_failure(&o);
    // Options of 3-D meshes and cameras are refused for a curve, not ignored.
    for (flags, says) in [
        (&["--detail", "fine"][..], "--detail"),
        (&["--drop-spurious"][..], "--drop-spurious"),
        (&["--order", "8"][..], "--order"),
    ] {
        let o = mesh(&field, &dir.path().join("c2.svg"), flags);
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
    }
    let o = preview(&field, &dir.path().join("a.png"), &["--azimuth", "20"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("drawn flat"), "{}", stderr(&o));
    // A missing field with an SVG output is named as missing.
    let o = mesh(&dir.path().join("none.zsf"), &svg, &["--force"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("reading") && stderr(&o).contains("none.zsf"),
        "{}",
        stderr(&o)
    );
    // An untrained net is said to be one.
    let o = fit_neural(&curve_sample(), &["--steps", "0"]);
    assert!(
        stdout(&o).contains("warnings:     no training step"),
        "{}{}",
        stdout(&o),
        stderr(&o)
    );
}

#[test]
fn fit_neural_refuses_bad_requests_with_a_message() {
    let curve = curve_sample();
    let cases: [(&[&str], &str); 7] = [
        (&["--lambda", "-1"], "λ (curvature weight) -1"),
        (
            &["--widths", "32,0"],
            "every hidden layer needs at least one neuron",
        ),
        (&["--widths", "32,x"], "comma-separated layer widths"),
        (&["--dropout", "1.5"], "dropout rate"),
        (&["--learning-rate", "0"], "learning rate"),
        (&["--kernel", "r3"], "--kernel is an option of --method rbf"),
        (
            &["--offset", "0.1"],
            "--offset, --format and --formation apply to point clouds",
        ),
    ];
    for (extra, want) in cases {
        let o = fit_neural(&curve, extra);
        if extra[0] == "--widths" && extra[1] == "32,x" {
            // clap refuses it before the command runs.
            assert!(
                !o.status.success() && stderr(&o).contains(want),
                "{}",
                stderr(&o)
            );
            continue;
        }
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(want), "{extra:?}: {}", stderr(&o));
    }
    let (_d, bad) = temp_file("bad.xyv", "0 0 0\n0.5 0.5 nan\n");
    let o = fit_neural(&bad, &[]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("bad.xyv") && stderr(&o).contains("line 2"),
        "{}",
        stderr(&o)
    );
    let o = fit(&sample(), &["--steps", "10"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("--steps is an option of --method neural"),
        "{}",
        stderr(&o)
    );
}

// ---- bad input: one line, exit status 1, no output ----

/// A refusal as the user sees it: exit status 1, one line on stderr holding `phrase`, no
/// panic.
fn assert_one_line_refusal(o: &Output, phrase: &str) {
    assert_clean_failure(o);
    let err = stderr(o);
    assert_eq!(err.lines().count(), 1, "not one line:\n{err}");
    assert!(err.contains(phrase), "{phrase:?} missing in: {err}");
}

#[test]
fn restore_and_fit_refuse_grids_before_allocating_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.zsf");
    let o_str = out.to_str().unwrap();
    let sample = sample();
    let s = sample.to_str().unwrap();
    let restore = |extra: &[&str]| {
        let mut args = vec!["restore", s, "--mask", EARS, "-o", o_str];
        args.extend(extra);
        zeroset(args)
    };
    let denoise = ["--mode", "denoise", "--coarse", "4,4,4"];
    let cases: Vec<(Output, &str)> = vec![
        // More memory than this machine has (read from /proc/meminfo).
        (
            restore(&["--mode", "protrusion", "--grid", "100000,100000,100000"]),
            "--grid 100000,100000,100000 (1e15 cells) needs about",
        ),
        // More than any allocation can hold, on any system.
        (
            restore(&[&denoise[..], &["--grid", "2000000,2000000,2000000"]].concat()),
            "more than any allocation can hold",
        ),
        // A count whose product overflows.
        (
            restore(&[&denoise[..], &["--grid", "10000000,10000000,10000000"]].concat()),
            "more samples than a 64-bit count can hold",
        ),
        (
            restore(&["--mode", "denoise", "--coarse", "1000000,1000000,1000000"]),
            "--coarse 1000000,1000000,1000000: coarse resolution 1000000 on axis 0",
        ),
        (
            restore(&[
                "--mode",
                "denoise",
                "--coarse",
                "10000000,10000000,10000000",
            ]),
            "--coarse 10000000,10000000,10000000: the grid would have more samples",
        ),
        (
            fit(
                &sample,
                &["-o", o_str, "--sampled", "--grid", "100000,100000,100000"],
            ),
            "of memory, more than the",
        ),
        (
            fit(
                &sample,
                &[
                    "-o",
                    o_str,
                    "--sampled",
                    "--grid",
                    "10000000,10000000,10000000",
                ],
            ),
            "more samples than a 64-bit count can hold",
        ),
    ];
    for (o, phrase) in &cases {
        assert_one_line_refusal(o, phrase);
        assert!(stdout(o).lines().count() <= 2, "{}", stdout(o));
    }
    assert!(!out.exists(), "a refused run must not leave an output");
}

#[test]
fn a_ply_count_the_file_cannot_hold_is_reported_as_truncated() {
    let dir = tempfile::tempdir().unwrap();
    // A mesh (faces: the mesh reader) and a point cloud (no faces: the cloud reader), each
    // claiming 10⁹ vertices in about 250 bytes.
    for (name, faces) in [("mesh.ply", true), ("cloud.ply", false)] {
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\n\
                          property float x\nproperty float y\nproperty float z\n"
            .to_vec();
        if faces {
            bytes.extend(b"element face 1\nproperty list uchar int vertex_indices\n");
        }
        bytes.extend(b"end_header\n");
        bytes.extend([0u8; 120]);
        let path = dir.path().join(name);
        fs::write(&path, &bytes).unwrap();
        let o = info(&path, &[]);
        assert_one_line_refusal(&o, "truncated");
        assert!(stderr(&o).contains("1000000000"), "{}", stderr(&o));
    }
    let png = dir.path().join("mesh.png");
    let o = zeroset([
        OsStr::new("preview"),
        dir.path().join("mesh.ply").as_os_str(),
        OsStr::new("-o"),
        png.as_os_str(),
    ]);
    assert_one_line_refusal(&o, "truncated");
    assert!(!png.exists());
}

#[test]
fn zero_normals_are_estimated_where_some_are_missing_and_read_as_none_where_all_are() {
    // CGAL and others write `0 0 0` where a point has no normal.
    let points = sphere_points(400);
    let text = |zero: &dyn Fn(usize) -> bool| -> String {
        points
            .iter()
            .enumerate()
            .map(|(k, (p, n))| {
                let n = if zero(k) { [0.0; 3] } else { *n };
                format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], n[0], n[1], n[2])
            })
            .collect()
    };
    let volume = |out: &str| -> f64 {
        out.split("signed volume ")
            .nth(1)
            .and_then(|s| s.split(',').next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no volume in {out}"))
    };
    let sphere = 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3);
    let reconstruct = |path: &Path| -> String {
        let mesh = path.with_extension("ply");
        let o = zeroset([
            "reconstruct",
            path.to_str().unwrap(),
            "-o",
            mesh.to_str().unwrap(),
            "--no-preview",
        ]);
        assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
        stdout(&o)
    };

    // Every 50th normal missing (8 of them): estimated, outward, and the file untouched.
    let (dir, path) = temp_file("some.xyzn", &text(&|k| k % 50 == 0));
    let before = fs::read(&path).unwrap();
    let said = "8 points without a normal (0 0 0; records 0, 50, 100, 150, 200, …, counted from 0)";
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains("8 of them 0 0 0 (no normal there)"),
        "{described}"
    );
    let field = dir.path().join("some.zsf");
    let o = zeroset([
        OsStr::new("fit"),
        path.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("rbf"),
        OsStr::new("-o"),
        field.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(said), "{}", stdout(&o));
    let out = reconstruct(&path);
    assert!(out.contains(said), "{out}");
    // Said once: the later stages read the completed copy.
    assert_eq!(out.matches("without a normal").count(), 1, "{out}");
    assert!(
        out.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{out}"
    );
    assert!((volume(&out) / sphere - 1.0).abs() < 0.01, "{out}");
    let restored = dir.path().join("restored.zsf");
    let o = zeroset([
        "restore",
        path.to_str().unwrap(),
        "--mode",
        "denoise",
        "--mask",
        "0,0,0:0.2,0.2,0.2",
        "--coarse",
        "2,2,2",
        "-o",
        restored.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(said), "{}", stdout(&o));
    assert_eq!(fs::read(&path).unwrap(), before);

    // Every normal 0 0 0: placeholders, read as none.
    let (dir, path) = temp_file("none.xyzn", &text(&|_| true));
    let described = stdout(&info(&path, &[]));
    assert!(described.contains("normals:     all 0 0 0"), "{described}");
    // Their noise is measured from the positions (it was "not measured": no patch of points
    // whose normals face the same way).
    assert!(
        described.contains("noise:       scatter about the local surface"),
        "{described}"
    );
    let field = dir.path().join("none.zsf");
    let o = fit(&path, &["-o", field.to_str().unwrap()]);
    assert_one_line_refusal(&o, "has no normals");
    assert!(!field.exists());
    let out = reconstruct(&path);
    assert!(out.contains("every normal is 0 0 0 (placeholders"), "{out}");
    assert!(out.contains("has no normals: estimating them"), "{out}");
    // They are none: --viewpoint, which turns estimated normals, is taken.
    let o = zeroset([
        "reconstruct",
        path.to_str().unwrap(),
        "-o",
        dir.path().join("facing.ply").to_str().unwrap(),
        "--viewpoint",
        "0,0,10",
        "--no-preview",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        out.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{out}"
    );
    assert!((volume(&out) / sphere - 1.0).abs() < 0.01, "{out}");
}

#[test]
fn points_that_fill_a_volume_are_told_from_a_surfaces() {
    // 2,000 points of a low-discrepancy (R₃) sequence filling a 2 × 1 × 1 brick, each with a
    // made-up unit normal (away from the brick's centre), and 2,000 points on a sphere.
    let phi: f64 = 1.220_744_084_605_759_5;
    let step = [1.0 / phi, 1.0 / (phi * phi), 1.0 / (phi * phi * phi)];
    let brick: String = (1..=2000)
        .map(|i| {
            let p: [f64; 3] = std::array::from_fn(|d| (0.5 + step[d] * i as f64) % 1.0);
            let p = [2.0 * p[0], p[1], p[2]];
            let away = [p[0] - 1.0, p[1] - 0.5, p[2] - 0.5];
            let length = away.iter().map(|x| x * x).sum::<f64>().sqrt();
            let n = away.map(|x| x / length);
            format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], n[0], n[1], n[2])
        })
        .collect();
    let (dir, path) = temp_file("brick.xyzn", &brick);
    let said = "the points fill a volume rather than sample a surface: at every scale from 32 to \
                128 neighbours a point's neighbourhood is at least 0.";
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains("thickness:   a volume's, not a surface's: at every scale from 32"),
        "{described}"
    );
    let o = fit(
        &path,
        &["-o", dir.path().join("brick.zsf").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(said), "{}", stdout(&o));
    let o = zeroset([
        "normals",
        path.to_str().unwrap(),
        "-o",
        dir.path().join("oriented.xyzn").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(said), "{}", stdout(&o));
    // A closed plate 0.6 × 0.6 × 0.04 sampled every 0.02 (2,042 points, the faces' shared
    // edges once): thick at 32 neighbours, which span both faces (0.53: it was called a
    // volume while only that scale was read under 2,048 points), thin at 128.
    let mut plate = std::collections::BTreeSet::new();
    for i in 0..=30 {
        for j in 0..=30 {
            for k in 0..=2 {
                let on_face = i == 0 || i == 30 || j == 0 || j == 30 || k == 0 || k == 2;
                if on_face {
                    plate.insert((i, j, k));
                }
            }
        }
    }
    let plate: String = plate
        .iter()
        .map(|&(i, j, k)| {
            format!(
                "{} {} {}\n",
                0.02 * i as f64,
                0.02 * j as f64,
                0.02 * k as f64
            )
        })
        .collect();
    let path = dir.path().join("plate.xyz");
    fs::write(&path, plate).unwrap();
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains("points:      2042 points"),
        "{described}"
    );
    assert!(
        described.contains("thickness:   a surface's: at 128 neighbours"),
        "{described}"
    );
    // Two sheets of 12 × 12 points every 0.02, 0.04 apart (288 points): thick at the one scale
    // read, but clean about the sheets: a surface's, and nothing is said.
    let sheets: String = (0..288)
        .map(|i| {
            format!(
                "{} {} {}\n",
                0.02 * (i % 12) as f64,
                0.02 * (i / 12 % 12) as f64,
                0.04 * (i / 144) as f64
            )
        })
        .collect();
    let path = dir.path().join("sheets.xyz");
    fs::write(&path, sheets).unwrap();
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains(
            "thickness:   a surface's: at 32 neighbours a point's neighbourhood is 0.50 as thick \
             as it is wide (the median), as a volume's is, but the points lie on smooth sheets"
        ),
        "{described}"
    );
    let o = zeroset([
        "normals",
        path.to_str().unwrap(),
        "-o",
        dir.path().join("sheets.xyzn").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stdout(&o).contains("fill a volume"), "{}", stdout(&o));
    // The sphere reads as a surface, and nothing is said.
    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(2000));
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains("thickness:   a surface's: at 32 neighbours"),
        "{described}"
    );
    let o = fit(
        &path,
        &["-o", dir.path().join("sphere.zsf").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stdout(&o).contains("fill a volume"), "{}", stdout(&o));
}

#[test]
fn normals_of_a_cloud_too_small_for_local_planes_are_called_a_guess() {
    // The 8 corners of a cube (CGAL's cube.xyz): each plane is fitted to all the others.
    let corners: String = (0..8)
        .map(|i| format!("{} {} {}\n", i & 1, (i >> 1) & 1, i >> 2))
        .collect();
    let (dir, path) = temp_file("corners.xyz", &corners);
    let normals = |path: &Path| {
        let o = zeroset([
            "normals",
            path.to_str().unwrap(),
            "-o",
            dir.path().join("oriented.xyzn").to_str().unwrap(),
            "--force",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    let out = normals(&path);
    assert!(
        out.contains(
            "warning: each normal's plane is fitted to a point and its 7 nearest, 8 of the 8 \
             points, and those planes are 1.00 as thick as they are wide"
        ),
        "{out}"
    );
    // 40 points on a sphere, 16 neighbours each: caps of it, thin enough to stand for it.
    let sphere: String = sphere_points(40)
        .iter()
        .map(|(p, _)| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    let path = dir.path().join("sphere.xyz");
    fs::write(&path, sphere).unwrap();
    let out = normals(&path);
    assert!(out.contains("estimated from 16 neighbours each"), "{out}");
    assert!(!out.contains("a guess"), "{out}");
}

#[test]
fn curves_in_a_plane_are_refused_as_2d_data_and_a_flat_sheet_is_fitted() {
    // Two circles on z = 0 with normals in the plane (CGAL's circles.ply is such a file).
    let circles: String = (0..200)
        .map(|k| {
            let t = k as f64 * std::f64::consts::TAU / 100.0;
            let r = if k < 100 { 1.0 } else { 0.4 };
            let (c, s) = (t.cos(), t.sin());
            format!("{} {} 0 {c} {s} 0\n", r * c + 0.5, r * s)
        })
        .collect();
    // Two of them with no normal (0 0 0): completed, they would stand across the plane.
    let gaps: String = circles
        .lines()
        .enumerate()
        .map(|(k, l)| {
            if k == 5 || k == 150 {
                let xyz: Vec<&str> = l.split_whitespace().take(3).collect();
                format!("{} 0 0 0\n", xyz.join(" "))
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    let (dir, path) = temp_file("circles.xyzn", &circles);
    let (_gaps_dir, gaps) = temp_file("gaps.xyzn", &gaps);
    let out = dir.path().join("c.zsf");
    for (method, path) in [("rbf", &path), ("mras", &path), ("rbf", &gaps)] {
        let o = zeroset([
            "fit",
            path.to_str().unwrap(),
            "--method",
            method,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_one_line_refusal(
            &o,
            "every point lies on the plane z = 0 and every normal lies in it",
        );
        assert!(stderr(&o).contains("value file (.xyv)"), "{}", stderr(&o));
        assert!(!out.exists());
    }
    // A flat sheet on z = 0 facing +z is a surface: the check lets it through.
    let sheet: String = (0..400)
        .map(|k| {
            format!(
                "{} {} 0 0 0 1\n",
                (k % 20) as f64 * 0.05,
                (k / 20) as f64 * 0.05
            )
        })
        .collect();
    let (dir, path) = temp_file("sheet.xyzn", &sheet);
    let out = dir.path().join("s.zsf");
    let o = fit(&path, &["-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn reconstruct_passes_tolerance_to_an_mras_fit_and_refuses_it_for_rbf() {
    let (dir, path) = temp_file("sphere.xyzn", &sphere_xyzn(400));
    let mesh = dir.path().join("sphere.ply");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "reconstruct",
            path.to_str().unwrap(),
            "-o",
            mesh.to_str().unwrap(),
            "--no-preview",
            "--force",
        ];
        args.extend(extra);
        zeroset(args)
    };
    let o = run(&["--method", "mras", "--tolerance", "0.005"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("tolerance 0.005 of the diagonal"),
        "{}",
        stdout(&o)
    );
    // 400 clean points: auto fits RBF, which takes no tolerance.
    fs::remove_file(&mesh).unwrap();
    let o = run(&["--tolerance", "0.005"]);
    assert_one_line_refusal(&o, "--tolerance 0.005 applies to MRAS fits");
    assert!(!mesh.exists());
}

#[test]
fn unoriented_normals_are_turned_by_reconstruct_and_warned_of_by_fit() {
    // A sphere whose normals all point up (principal components written without a sign, as in
    // CGAL's cube.pwn): half of them inward.
    let text: String = sphere_points(800)
        .iter()
        .map(|(p, n)| {
            let n = if n[2] < 0.0 { n.map(|x| -x) } else { *n };
            format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], n[0], n[1], n[2])
        })
        .collect();
    let (dir, path) = temp_file("up.xyzn", &text);
    let mesh = dir.path().join("up.ply");
    let o = zeroset([
        "reconstruct",
        path.to_str().unwrap(),
        "-o",
        mesh.to_str().unwrap(),
        "--no-preview",
    ]);
    let out = stdout(&o);
    assert!(o.status.success(), "{out}{}", stderr(&o));
    assert!(out.contains("normals look unoriented"), "{out}");
    assert!(
        out.contains("(their lines kept, each piece outward; 400 of them turned;"),
        "{out}"
    );
    assert!(
        out.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{out}"
    );
    let volume: f64 = out
        .split("signed volume ")
        .nth(1)
        .and_then(|s| s.split(',').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no volume in {out}"));
    let sphere = 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3);
    assert!((volume / sphere - 1.0).abs() < 0.01, "{out}");
    // `fit` fits what it is given, and says so.
    let field = dir.path().join("up.zsf");
    let o = zeroset([
        OsStr::new("fit"),
        path.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("rbf"),
        OsStr::new("-o"),
        field.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("normals:      warning: ") && stdout(&o).contains("look unoriented"),
        "{}",
        stdout(&o)
    );
    // Oriented normals draw no such line.
    let (_d, good) = temp_file("good.xyzn", &sphere_xyzn(800));
    let o = fit(
        &good,
        &["-o", dir.path().join("good.zsf").to_str().unwrap()],
    );
    assert!(!stdout(&o).contains("unoriented"), "{}", stdout(&o));
}

#[test]
fn fit_refuses_colours_and_non_unit_normals_in_xyz_files() {
    let points = sphere_points(100);
    let colours: String = points
        .iter()
        .enumerate()
        .map(|(k, (p, _))| {
            format!(
                "{} {} {} {} {} {}\n",
                p[0],
                p[1],
                p[2],
                k * 7 % 256,
                k * 13 % 256,
                200
            )
        })
        .collect();
    let long: String = points
        .iter()
        .map(|(p, n)| {
            format!(
                "{} {} {} {} {} {}\n",
                p[0],
                p[1],
                p[2],
                5.0 * n[0],
                5.0 * n[1],
                5.0 * n[2]
            )
        })
        .collect();
    for (name, text, phrase) in [
        ("rgb.xyz", &colours, "as in RGB colours (x y z r g b)"),
        ("long.xyzn", &long, "the normal's length is 5.0000"),
    ] {
        let (dir, path) = temp_file(name, text);
        let out = dir.path().join("out.zsf");
        let o = fit(&path, &["-o", out.to_str().unwrap()]);
        assert_one_line_refusal(&o, phrase);
        assert!(
            stderr(&o).contains("do not look like unit normals"),
            "{}",
            stderr(&o)
        );
        assert!(!out.exists());
        let o = zeroset([
            "restore",
            path.to_str().unwrap(),
            "--mode",
            "denoise",
            "--mask",
            "0,0,0:0.2,0.2,0.2",
            "--coarse",
            "2,2,2",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_one_line_refusal(&o, "do not look like unit normals");
        assert!(!out.exists());
        // `zeroset info` still describes the positions, and says why columns 4–6 are left out.
        let o = info(&path, &[]);
        assert!(o.status.success(), "{}", stderr(&o));
        let described = stdout(&o);
        assert!(described.contains("normals:     no"), "{described}");
        assert!(
            described.contains("columns 4–6: not read as normals"),
            "{described}"
        );
        if name == "rgb.xyz" {
            assert!(described.contains("RGB colours"), "{described}");
        }
    }
    // Normals half or twice unit length are directions: fitted (after normalising).
    let scaled: String = points
        .iter()
        .enumerate()
        .map(|(k, (p, n))| {
            let c = if k % 2 == 0 { 0.5 } else { 2.0 };
            format!(
                "{} {} {} {} {} {}\n",
                p[0],
                p[1],
                p[2],
                c * n[0],
                c * n[1],
                c * n[2]
            )
        })
        .collect();
    let (_d, path) = temp_file("scaled.xyzn", &scaled);
    let o = fit(&path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        reported(&stdout(&o), "max residual:") < 1e-8,
        "{}",
        stdout(&o)
    );
}

// ---- 2-D RBF fits ----

#[test]
fn fit_rbf_on_the_curve_sample_then_trace_it_for_every_kernel() {
    let dir = tempfile::tempdir().unwrap();
    for (i, (kernel, extra)) in [
        ("tps", &[][..]),
        ("r", &[]),
        ("r3", &[]),
        ("wendland", &[]),
        ("wendland", &["--radius", "0.8"]),
    ]
    .into_iter()
    .enumerate()
    {
        let field = dir.path().join(format!("curve_{i}_{kernel}.zsf"));
        let mut args = vec!["--kernel", kernel, "-o", field.to_str().unwrap()];
        args.extend(extra);
        let o = fit(&curve_sample(), &args);
        assert!(o.status.success(), "{kernel}: {}{}", stdout(&o), stderr(&o));
        let out = stdout(&o);
        assert!(
            out.contains("60 2-D value constraints (15 negative, 30 zero, 15 positive)"),
            "{out}"
        );
        assert!(out.contains(&format!("kernel:       {kernel} (")), "{out}");
        assert!(out.contains("solver:       dense-cholesky"), "{out}");
        let residual = reported(&out, "max residual:");
        assert!(residual < 1e-10, "{kernel}: residual {residual}\n{out}");
        if kernel == "wendland" {
            assert!(out.contains("radius:"), "{out}");
        }
        let o = info(&field, &[]);
        let described = stdout(&o);
        assert!(
            described.contains("dimension:   2") && described.contains("rbf"),
            "{described}{}",
            stderr(&o)
        );
        let svg = dir.path().join(format!("curve_{i}_{kernel}.svg"));
        let o = mesh(&field, &svg, &[]);
        assert!(o.status.success(), "{kernel}: {}{}", stdout(&o), stderr(&o));
        assert!(
            stdout(&o).contains("curve: 1 closed loop(s), 0 open piece(s)"),
            "{kernel}: {}",
            stdout(&o)
        );
        // The enclosed area of r(t) = 0.6 + 0.15 cos 3t is π (0.36 + 0.01125) = 1.1663.
        let area: f64 = stdout(&o)
            .split("enclosed area ")
            .nth(1)
            .and_then(|t| t.split_whitespace().next())
            .and_then(|t| t.parse().ok())
            .unwrap_or(f64::NAN);
        assert!((area - 1.1663).abs() < 0.02, "{kernel}: area {area}");
        assert!(fs::read_to_string(&svg).unwrap().contains("<svg"));
    }
    // The default kernel of a 2-D file is the thin-plate spline.
    let o = fit(&curve_sample(), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("kernel:       tps"), "{}", stdout(&o));
    // Cells far too small for the curve's grid: one line, no panic, no file.
    let field = dir.path().join("curve_0_tps.zsf");
    for (voxel, says) in [("1e-300", "more than"), ("1e-5", "too fine for a curve")] {
        let svg = dir.path().join("tiny.svg");
        let o = mesh(&field, &svg, &["--voxel", voxel]);
        assert_clean_failure(&o);
        assert!(stderr(&o).contains(says), "{voxel}: {}", stderr(&o));
        assert!(!svg.exists());
    }
}

#[test]
fn fit_rbf_refuses_what_value_files_cannot_take() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.zsf");
    let o_str = out.to_str().unwrap();
    let cases: [(&[&str], &str); 9] = [
        (&["--hermite"], "--hermite applies to oriented point clouds"),
        (
            &["--offset", "0.01"],
            "--offset applies to oriented point clouds",
        ),
        (&["--sampled"], "--sampled applies to oriented point clouds"),
        (
            &["--grid", "8,8,8"],
            "--grid applies to oriented point clouds",
        ),
        (
            &["--format", "xyz"],
            "--format applies to oriented point clouds",
        ),
        (
            &["--radius", "0.5"],
            "--radius is the support radius of --kernel wendland; --kernel tps has none",
        ),
        (
            &["--kernel", "wendland", "--radius", "-1"],
            "--radius must be a finite distance > 0",
        ),
        (
            &["--kernel", "wendland", "--radius", "inf"],
            "--radius must be a finite distance > 0",
        ),
        (
            &["--steps", "10"],
            "--steps is an option of --method neural",
        ),
    ];
    for (extra, phrase) in cases {
        let mut args = vec!["-o", o_str];
        args.extend(extra);
        let o = fit(&curve_sample(), &args);
        assert_one_line_refusal(&o, phrase);
        assert!(
            stdout(&o).is_empty(),
            "refused before reading: {}",
            stdout(&o)
        );
    }
    // An unknown kernel is refused by the argument parser, naming the choices.
    let o = fit(&curve_sample(), &["--kernel", "gauss", "-o", o_str]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("invalid value 'gauss' for '--kernel")
            && stderr(&o).contains("r, r3, tps, wendland")
            && !stderr(&o).contains("panicked"),
        "{}",
        stderr(&o)
    );
    // tps is for 2-D curves; a single point gives Wendland no default radius.
    let (_d, xyzv) = temp_file("s.xyzv", "0 0 0 -1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n1 1 1 1\n");
    let o = fit(&xyzv, &["--kernel", "tps", "-o", o_str]);
    assert_one_line_refusal(
        &o,
        "holds 3-D value constraints: use --kernel r, r3 or wendland",
    );
    let (_d, one) = temp_file("one.xyv", "0.5 0.5 0\n");
    let o = fit(&one, &["--kernel", "wendland", "-o", o_str]);
    assert_one_line_refusal(&o, "give --radius RHO");
    // --radius belongs to --method rbf.
    let o = fit_neural(&curve_sample(), &["--radius", "1"]);
    assert_one_line_refusal(&o, "--radius is an option of --method rbf");
    assert!(!out.exists(), "a refused run must not leave an output");
}

#[test]
fn mras_fit_info_mesh_and_restore() {
    let dir = tempfile::tempdir().unwrap();
    let zsf = dir.path().join("bunny_mras.zsf");
    let o = zeroset([
        OsStr::new("fit"),
        sample().as_os_str(),
        OsStr::new("--method"),
        OsStr::new("mras"),
        OsStr::new("--max-level"),
        OsStr::new("4"),
        OsStr::new("--quiet"),
        OsStr::new("-o"),
        zsf.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("levels:") && out.contains("storage:"), "{out}");
    // info lists every level with its cells, ranks and storage.
    let o = info(&zsf, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("kind:        mras"), "{text}");
    for level in 1..=4 {
        assert!(
            text.lines()
                .any(|l| l.trim_start().starts_with(&format!("{level} "))),
            "level {level} missing:\n{text}"
        );
    }
    // mesh: a closed surface.
    let ply = dir.path().join("bunny_mras.ply");
    let o = zeroset([
        OsStr::new("mesh"),
        zsf.as_os_str(),
        OsStr::new("-o"),
        ply.as_os_str(),
        OsStr::new("--quiet"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("closed"), "{}", stdout(&o));
    // at fine detail by default (the field is fitted within 1e-3 of the diagonal).
    assert!(stdout(&o).contains("Fine detail"), "{}", stdout(&o));
    // --method smc refuses it with a reason.
    let o = zeroset([
        OsStr::new("mesh"),
        zsf.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("smc"),
        OsStr::new("-o"),
        dir.path().join("x.ply").as_os_str(),
    ]);
    assert_clean_failure(&o);
    // Options of other methods are refused.
    let o = zeroset([
        OsStr::new("fit"),
        sample().as_os_str(),
        OsStr::new("--method"),
        OsStr::new("mras"),
        OsStr::new("--kernel"),
        OsStr::new("r"),
    ]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("--kernel"), "{}", stderr(&o));
    let o = zeroset([
        OsStr::new("fit"),
        sample().as_os_str(),
        OsStr::new("--method"),
        OsStr::new("rbf"),
        OsStr::new("--max-level"),
        OsStr::new("3"),
    ]);
    assert_clean_failure(&o);
}

#[test]
fn mras_refuses_bad_clouds_with_reasons() {
    // Fewer than 16 points.
    let few: String = (0..10)
        .map(|i| format!("{} {} {} 0 0 1\n", i, i * i, 1))
        .collect();
    let (_d, path) = temp_file("few.xyzn", &few);
    let o = zeroset(["fit", path.to_str().unwrap(), "--method", "mras"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("at least 16"), "{}", stderr(&o));
    // All points on a plane.
    let flat: String = (0..100)
        .map(|i| format!("{} {} 0 0 0 1\n", i % 10, i / 10))
        .collect();
    let (_d, path) = temp_file("flat.xyzn", &flat);
    let o = zeroset(["fit", path.to_str().unwrap(), "--method", "mras"]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("plane"), "{}", stderr(&o));
    // Bad tolerance.
    let o = zeroset([
        "fit",
        sample().to_str().unwrap(),
        "--method",
        "mras",
        "--tolerance",
        "2",
    ]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("tolerance"), "{}", stderr(&o));
    // Options out of range are refused before the points are read (a large scan took its
    // reading time, and printed its header, before being told): here there is no file at all.
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("not-there.ply");
    for (method, flags, named) in [
        ("mras", &["--tolerance", "-1"][..], "--tolerance -1"),
        ("mras", &["--max-level", "0"][..], "--max-level 0"),
        ("mras", &["--lambda", "-2"][..], "--lambda -2"),
        (
            "mras",
            &["--tolerance-distance", "0"][..],
            "--tolerance-distance 0",
        ),
        ("rbf", &["--tolerance", "2"][..], "--tolerance 2"),
    ] {
        let mut args = vec!["fit", missing.to_str().unwrap(), "--method", method];
        args.extend(flags);
        let o = zeroset(&args);
        assert_clean_failure(&o);
        assert!(
            stderr(&o).contains(named),
            "{method} {flags:?}: {}",
            stderr(&o)
        );
    }
}

#[test]
fn stray_points_are_set_aside_by_rbf_and_mras_fits() {
    // The fit tests' sphere (2,000 points) and 8 points well off it, inside and out, with
    // normals at random: both methods report and set aside exactly those 8 (input lines 2001–
    // 2008, indices 2000–2007); `--outlier-ratio 0` fits every point.
    let mut text = sphere_xyzn(2000);
    let stray = [
        [0.1, -0.2, 0.3],
        [0.35, -0.05, 0.4],
        [-0.3, -0.9, 0.3],
        [0.9, 0.5, -0.4],
        [0.8, -0.9, 1.0],
        [-0.6, 0.5, 0.9],
        [0.1, 0.6, -0.5],
        [-0.7, -0.4, -0.4],
    ];
    for (k, p) in stray.iter().enumerate() {
        let n = [(k as f64).cos(), (k as f64 * 1.7).sin(), 0.3];
        text.push_str(&format!(
            "{} {} {} {} {} {}\n",
            p[0], p[1], p[2], n[0], n[1], n[2]
        ));
    }
    let (_d, path) = temp_file("stray.xyzn", &text);
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains("outliers:    8 stray points"),
        "{described}"
    );
    for method in ["rbf", "mras"] {
        let argv = |extra: &[&str]| -> Vec<String> {
            let mut a = vec!["fit", path.to_str().unwrap(), "--method", method];
            if method == "mras" {
                a.extend(["--max-level", "2"]);
            }
            a.extend_from_slice(extra);
            a.into_iter().map(str::to_owned).collect()
        };
        let o = zeroset(argv(&[]));
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let out = stdout(&o);
        assert!(
            out.contains("outliers:     8 stray points set aside") && out.contains("#2000 "),
            "{method}: {out}"
        );
        // --outliers-out: the 8 points, as given; an existing file needs --force.
        let aside = path.with_file_name(format!("aside_{method}.xyzn"));
        let a = aside.to_str().unwrap();
        let o = zeroset(argv(&["--outliers-out", a]));
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let written: Vec<Vec<f64>> = std::fs::read_to_string(&aside)
            .unwrap()
            .lines()
            .map(|l| l.split(' ').map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(written.len(), 8);
        for (w, p) in written.iter().zip(&stray) {
            assert_eq!(&w[..3], &p[..]);
        }
        let o = zeroset(argv(&["--outliers-out", a]));
        assert_clean_failure(&o);
        assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
        let o = zeroset(argv(&["--outlier-ratio", "0"]));
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        assert!(stdout(&o).contains("every point fitted"), "{}", stdout(&o));
        let o = zeroset(argv(&["--outlier-ratio", "1"]));
        assert_clean_failure(&o);
        assert!(stderr(&o).contains("outlier"), "{}", stderr(&o));
    }
    // The clean sphere: none.
    let (_d, clean) = temp_file("clean.xyzn", &sphere_xyzn(2000));
    let out = stdout(&fit(&clean, &[]));
    assert!(out.contains("outliers:     none"), "{out}");
}

/// The fit tests' sphere (2,000 points, spacing ≈ 0.1 of its radius) with every point moved
/// along its normal by uniform pseudo-random noise of standard deviation `amplitude` of the
/// radius (0.03: noisy, a scatter about 0.3 of the spacing). (Not ±`amplitude`: a random sign
/// puts the points on two concentric spheres, which the noise check reads as two sheets.)
fn noisy_sphere_xyzn(amplitude: f64) -> String {
    noisy_sphere_of(2000, amplitude)
}

/// [`noisy_sphere_xyzn`] with `n` points.
fn noisy_sphere_of(n: usize, amplitude: f64) -> String {
    sphere_points(n)
        .iter()
        .enumerate()
        .map(|(i, (p, n))| {
            // Uniform on [−√3, √3) (variance 1) from the top 53 bits of a mixed hash of the
            // index (SplitMix64's finaliser; a bare golden-ratio hash would follow the
            // lattice's own golden-angle azimuth).
            let mut x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            let u = ((x ^ (x >> 31)) >> 11) as f64 / (1u64 << 53) as f64;
            let h = 3f64.sqrt() * (2.0 * u - 1.0) * amplitude * RADIUS;
            let q: [f64; 3] = std::array::from_fn(|a| p[a] + h * n[a]);
            format!("{} {} {} {} {} {}\n", q[0], q[1], q[2], n[0], n[1], n[2])
        })
        .collect()
}

#[test]
fn auto_smoothing_follows_the_object_not_the_scene() {
    // A noisy sphere of 500 points, and the same with a copy 20 radii away: the scene's
    // diagonal is 6.4× the sphere's, the smoothing the same (μ scales with the object's size,
    // not the box's).
    let one = noisy_sphere_of(500, 0.06);
    let shifted: String = one
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            format!(
                "{} {} {} {} {} {}\n",
                v[0] + 20.0 * RADIUS,
                v[1],
                v[2],
                v[3],
                v[4],
                v[5]
            )
        })
        .collect();
    let mu = |text: &str| -> f64 {
        let (dir, path) = temp_file("c.xyzn", text);
        let field = dir.path().join("f.zsf");
        let args = ["--smoothing", "auto", "-o", field.to_str().unwrap()];
        let o = fit(&path, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = stdout(&o);
        out.split("μ = ")
            .nth(1)
            .and_then(|s| s.split_whitespace().next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no μ in {out}"))
    };
    let (alone, scene) = (mu(&one), mu(&format!("{one}{shifted}")));
    assert!(
        (scene / alone - 1.0).abs() < 0.05,
        "one sphere μ {alone}, two μ {scene}"
    );
}

#[test]
fn smoothing_approximates_a_noisy_scan_into_one_surface() {
    // Twice the noise of the test below: interpolated, 15 components (measured); smoothed, the
    // sphere, its area within 2% (measured 1.5%).
    let (dir, path) = temp_file("noisy.xyzn", &noisy_sphere_xyzn(0.06));
    let surface = |extra: &[&str]| {
        let field = dir.path().join("f.zsf");
        let mut args = vec!["-o", field.to_str().unwrap(), "--force"];
        args.extend(extra);
        let o = fit(&path, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = dir.path().join("f.ply");
        let m = mesh(&field, &out, &["--force"]);
        assert!(m.status.success(), "{}", stderr(&m));
        (stdout(&o), stdout(&m))
    };
    let (_, interpolated) = surface(&[]);
    let (text, smoothed) = surface(&["--smoothing", "auto"]);
    assert!(text.contains("smoothing:    μ = "), "{text}");
    assert!(text.contains("(auto: 2 ×"), "{text}");
    assert!(text.contains("misfit:       rms"), "{text}");
    assert!(
        !text.contains("warning:"),
        "no warning once smoothed: {text}"
    );
    assert!(
        !interpolated.contains(" 1 component(s)"),
        "interpolated: {interpolated}"
    );
    assert!(
        smoothed.contains("Euler characteristic 2, 1 component(s)"),
        "smoothed: {smoothed}"
    );
    let area: f64 = smoothed
        .split("area ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no area in {smoothed}"));
    let sphere = 4.0 * std::f64::consts::PI * RADIUS * RADIUS;
    assert!(
        (area / sphere - 1.0).abs() < 0.02,
        "area {area} against {sphere}"
    );
    // A given μ is used as it is; bad ones are refused before any fit.
    let (text, _) = surface(&["--smoothing", "0.01"]);
    assert!(text.contains("μ = 0.01 (--smoothing)"), "{text}");
    for (extra, message) in [
        (&["--smoothing", "-1"][..], "finite μ ≥ 0"),
        (&["--smoothing", "nan"][..], "finite μ ≥ 0"),
        (&["--smoothing", "big"][..], "auto or a number"),
        (
            &["--smoothing", "auto", "--kernel", "r3"][..],
            "calibrated for --kernel r",
        ),
        (&["--smoothing", "0.1", "--hermite"][..], "drop --hermite"),
        (&["--smoothing", "auto", "--hermite"][..], "drop --hermite"),
        (
            &["--smoothing", "0.1", "--tolerance", "0.01"][..],
            "one or the other",
        ),
    ] {
        let o = fit(&path, extra);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(message), "{extra:?}: {}", stderr(&o));
    }
    let mesh = dir.path().join("m.ply");
    for (extra, message) in [
        (
            ["--method", "mras", "--smoothing", "auto"],
            "--smoothing applies to RBF fits",
        ),
        (["--method", "rbf", "--smoothing", "-1"], "finite μ ≥ 0"),
    ] {
        let mut args = vec!["reconstruct", path.to_str().unwrap(), "-o"];
        args.push(mesh.to_str().unwrap());
        args.extend(extra);
        let o = zeroset(args);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(message), "{extra:?}: {}", stderr(&o));
        assert!(!mesh.exists());
    }
}

#[test]
fn close_caps_a_scan_without_its_bottom_on_the_scans_box() {
    // The box [−1, 1]² × [0, 1] without its bottom face, as a turntable scan sees it: its top
    // and four sides on a lattice of spacing 0.1, with their normals (1,200 points).
    let mut cloud = String::new();
    let c = |i: usize| -1.0 + 0.1 * (i as f64 + 0.5);
    let h = |i: usize| 0.1 * (i as f64 + 0.5);
    for i in 0..20 {
        for j in 0..20 {
            cloud += &format!("{} {} 1 0 0 1\n", c(i), c(j));
        }
        for k in 0..10 {
            cloud += &format!("{} -1 {} 0 -1 0\n", c(i), h(k));
            cloud += &format!("{} 1 {} 0 1 0\n", c(i), h(k));
            cloud += &format!("-1 {} {} -1 0 0\n", c(i), h(k));
            cloud += &format!("1 {} {} 1 0 0\n", c(i), h(k));
        }
    }
    let (dir, scan) = temp_file("open_box.xyzn", &cloud);
    let mesh = dir.path().join("box.ply");
    let field = dir.path().join("box.zsf");
    let reconstruct = |extra: &[&str]| {
        let mut args = vec![
            "reconstruct",
            scan.to_str().unwrap(),
            "-o",
            mesh.to_str().unwrap(),
            "--field",
            field.to_str().unwrap(),
            "--no-preview",
            "--force",
            "--quiet",
        ];
        args.extend(extra);
        let o = zeroset(args);
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    let volume = |text: &str| -> f64 {
        text.split("signed volume ")
            .nth(1)
            .and_then(|s| s.split(',').next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no volume in {text}"))
    };
    // Without --close the sides run on to the field's box: open.
    let text = reconstruct(&[]);
    assert!(text.contains("report: open"), "{text}");
    assert!(text.contains("--close=scan"), "{text}");
    // With it, capped where the sides end (their lowest points at z = 0.05): closed, one box,
    // its volume 2 × 2 × 0.95 within 1%.
    let text = reconstruct(&["--close"]);
    assert!(text.contains("close: capped on the scan's box"), "{text}");
    assert!(
        text.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{text}"
    );
    assert!((volume(&text) / 3.8 - 1.0).abs() < 0.01, "{text}");
    assert!(text.contains("the caps --close made are in it"), "{text}");
    // reconstruct passes --voxel and --resolution to its mesh stage (refused before the fit
    // where they are out of range).
    let text = reconstruct(&["--close", "--voxel", "0.04"]);
    assert!(
        text.contains("(at most 0.04, fitted to the scan's box) (--voxel)"),
        "{text}"
    );
    let text = reconstruct(&["--resolution", "40"]);
    assert!(
        text.contains("(40 voxels along the longest axis)"),
        "{text}"
    );
    let o = zeroset([
        "reconstruct",
        scan.to_str().unwrap(),
        "-o",
        mesh.to_str().unwrap(),
        "--voxel",
        "-1",
        "--force",
    ]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("--voxel must be a finite positive"),
        "{}",
        stderr(&o)
    );
    assert!(!stdout(&o).contains("== 1/3 fit"), "{}", stdout(&o));
    // zeroset mesh --close (the field's box) caps it lower: more volume.
    let capped = dir.path().join("capped.ply");
    let mesh_with = |extra: &[&str]| {
        let mut args = vec![
            "mesh",
            field.to_str().unwrap(),
            "-o",
            capped.to_str().unwrap(),
            "--force",
        ];
        args.extend(extra);
        zeroset(args)
    };
    let o = mesh_with(&["--close"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(volume(&stdout(&o)) > 1.1 * 3.8, "{}", stdout(&o));
    // An RBF field's centres are not its scan: --close=scan wants --scan...
    let o = mesh_with(&["--close=scan"]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("give the scan with --scan"),
        "{}",
        stderr(&o)
    );
    let o = mesh_with(&["--close=scan", "--scan", scan.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        (volume(&stdout(&o)) / 3.8 - 1.0).abs() < 0.01,
        "{}",
        stdout(&o)
    );
    // Its positions alone with a stray point far below: set aside, not capped at.
    let positions: String = cloud
        .lines()
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" ") + "\n")
        .collect();
    let (_p, stray) = temp_file("stray.xyz", &(positions + "0.5 0.5 -20\n"));
    let o = mesh_with(&["--close=scan", "--scan", stray.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        (volume(&stdout(&o)) / 3.8 - 1.0).abs() < 0.01,
        "{}",
        stdout(&o)
    );
    // An outer level set lies past the scan: its box grows by the level's offset (about
    // 0.05 here), not clipped back to the zero set's.
    let o = mesh_with(&[
        "--close=scan",
        "--scan",
        scan.to_str().unwrap(),
        "--level",
        "0.05",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(volume(&stdout(&o)) > 1.1 * 3.8, "{}", stdout(&o));
    // --close and --trim pull opposite ways.
    let o = mesh_with(&["--close=scan", "--trim"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("cannot be used with"), "{}", stderr(&o));
    // ...and a flat scan has no inside to cap.
    let (_f, flat) = temp_file("flat.xyz", "0 0 0\n1 0 0\n0 1 0\n1 1 0\n");
    let o = mesh_with(&["--close=scan", "--scan", flat.to_str().unwrap()]);
    assert_clean_failure(&o);
    assert!(stderr(&o).contains("no inside to cap"), "{}", stderr(&o));
}

#[test]
fn a_thin_wall_without_normals_is_called_two_sheets_not_noise() {
    // Both faces of a tube wall 0.02 thick (radii 1 and 1.02, height 2), 4,000 points each
    // (a spacing of about 0.05): from its positions the wall's thickness reads as scatter.
    let golden = (5f64.sqrt() - 1.0) / 2.0;
    let face = |r: f64, shift: f64| -> String {
        (0..4000)
            .map(|i| {
                let t = std::f64::consts::TAU * (i as f64 * golden).fract();
                let z = 2.0 * (i as f64 + 0.5) / 4000.0 - 1.0 + shift;
                format!("{} {} {z}\n", r * t.cos(), r * t.sin())
            })
            .collect()
    };
    let (dir, path) = temp_file("tube.xyz", &(face(1.0, 0.0) + &face(1.02, 0.013)));
    let two_sheets = "of the patches lie on two parallel sheets";
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains("noisy (above 0.2) on its face, but"),
        "{described}"
    );
    assert!(described.contains(two_sheets), "{described}");
    assert!(described.contains("not noise"), "{described}");
    // zeroset normals warns that it cannot tell the faces apart.
    let out = dir.path().join("tube.xyzn");
    let o = zeroset([
        "normals",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("warning: "), "{text}");
    assert!(
        text.contains(two_sheets) && text.contains("cannot tell"),
        "{text}"
    );
    // With a neighbour count given, too.
    let o = zeroset([
        "normals",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--neighbours",
        "12",
        "--force",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(two_sheets), "{}", stdout(&o));
    // One face alone is a clean scan, with nothing said of sheets.
    let (_d, one) = temp_file("face.xyz", &face(1.0, 0.0));
    let described = stdout(&info(&one, &[]));
    assert!(
        described.contains("clean enough to interpolate"),
        "{described}"
    );
    assert!(!described.contains("sheets"), "{described}");
}

#[test]
fn a_noisy_scan_is_measured_warned_of_and_not_interpolated() {
    // Interpolating the noisy sphere would make bubbles: info says so, an RBF fit warns, and
    // reconstruct's automatic choice smooths. The clean sphere: none of it.
    let (dir, path) = temp_file("noisy.xyzn", &noisy_sphere_xyzn(0.03));
    let (_c, clean) = temp_file("clean.xyzn", &sphere_xyzn(2000));
    let described = stdout(&info(&path, &[]));
    assert!(
        described.contains("of the point spacing: noisy"),
        "{described}"
    );
    let described = stdout(&info(&clean, &[]));
    assert!(
        described.contains("clean enough to interpolate"),
        "{described}"
    );
    let o = fit(&path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("RBF interpolates every point"),
        "{}",
        stdout(&o)
    );
    let o = fit(&clean, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stdout(&o).contains("noise:"), "{}", stdout(&o));
    let mesh = dir.path().join("noisy.ply");
    let reconstruct = |scan: &Path, extra: &[&str]| {
        let mut args = vec![
            "reconstruct",
            scan.to_str().unwrap(),
            "-o",
            mesh.to_str().unwrap(),
            "--detail",
            "coarse",
            "--no-preview",
            "--force",
            "--quiet",
        ];
        args.extend(extra);
        let out = zeroset(args);
        assert!(out.status.success(), "{}", stderr(&out));
        stdout(&out)
    };
    let text = reconstruct(&path, &[]);
    // Up to 15,000 points, RBF smoothed by the measured noise (on sparse noisy clouds MRAS
    // made handles: a review's 2,000-point sphere came out genus 17).
    assert!(text.contains("rbf field (auto: a noisy scan"), "{text}");
    assert!(text.contains("(auto: 2 × "), "{text}");
    assert!(
        text.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{text}"
    );
    // An MRAS fit misses its tolerance because of the noise, and says so; on the clean sample
    // (sparse: its curvature reads as a scatter of 1e-3 of the diagonal) it does not.
    // --smoothing 0 asks not to smooth: MRAS then, not an RBF through the noise (its fit
    // stage's report is the `fit --method mras` command's).
    let scatter = "the points scatter about their surface by σ ≈";
    let text = reconstruct(&path, &["--smoothing", "0"]);
    assert!(
        text.contains("and --smoothing 0 asks not to smooth it"),
        "{text}"
    );
    assert!(text.contains(scatter), "{text}");
    // More points than that: MRAS.
    let (_d, large) = temp_file("large.xyzn", &noisy_sphere_of(15_001, 0.03));
    let text = reconstruct(&large, &[]);
    assert!(
        text.contains("mras field (auto: a noisy scan") && text.contains("of more than 15000"),
        "{text}"
    );
    let o = zeroset([
        "fit",
        sample().to_str().unwrap(),
        "--method",
        "mras",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("tolerance:    not met"), "{text}");
    assert!(!text.contains(scatter), "{text}");
}

#[test]
fn reconstruct_goes_from_a_scan_to_a_mesh_and_its_preview() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("bunny.ply");
    let m = mesh.to_str().unwrap();
    let sample = sample();
    let s = sample.to_str().unwrap();
    // What a killed run leaves (its process gone) is removed; a live run's file is not.
    let mut ended = std::process::Command::new("true").spawn().unwrap();
    ended.wait().unwrap();
    let stale = dir
        .path()
        .join(format!(".bunny.ply.reconstruct-{}.zsf", ended.id()));
    let live = dir
        .path()
        .join(format!(".bunny.ply.reconstruct-{}.zsf", std::process::id()));
    std::fs::write(&stale, b"left by a killed run").unwrap();
    std::fs::write(&live, b"a run still going").unwrap();
    let out = zeroset(["reconstruct", s, "-o", m, "--detail", "general", "--quiet"]);
    assert!(!stale.exists(), "a killed run's field file is left");
    assert!(live.exists(), "a live run's field file was removed");
    std::fs::remove_file(&live).unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    for phrase in [
        "2000 points",
        "rbf field (auto: RBF up to 50000 points unless noisy)",
        "== 1/3 fit",
        "== 2/3 mesh",
        "report: closed, Euler characteristic 2, 1 component(s)",
        "== summary",
        "total",
    ] {
        assert!(text.contains(phrase), "{phrase:?} missing in:\n{text}");
    }
    assert!(mesh.is_file() && dir.path().join("bunny.png").is_file());
    // The temporary field is gone: only the mesh and its preview are left.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
    // Existing outputs are refused before any work, and nothing is touched.
    let before = std::fs::read(&mesh).unwrap();
    let again = zeroset(["reconstruct", s, "-o", m, "--quiet"]);
    assert!(!again.status.success());
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(err.contains("exists; pass --force"), "{err}");
    assert_eq!(std::fs::read(&mesh).unwrap(), before);
    // MRAS on request, keeping the field.
    let field = dir.path().join("bunny.zsf");
    let out = zeroset([
        "reconstruct",
        s,
        "-o",
        m,
        "--method",
        "mras",
        "--detail",
        "coarse",
        "--field",
        field.to_str().unwrap(),
        "--no-preview",
        "--force",
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("mras field"));
    assert!(field.is_file());
    // MRAS fields record their points, so their meshes are checked for spurious components too.
    let out = zeroset([
        "reconstruct",
        s,
        "-o",
        m,
        "--method",
        "mras",
        "--drop-spurious",
        "--force",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("spurious: none"));
    let out = zeroset([
        "reconstruct",
        s,
        "-o",
        m,
        "--drop-spurious",
        "--force",
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("spurious: none"));
}

#[test]
fn mesh_reports_and_drops_blobs_around_stray_points_near_the_surface() {
    // The sample and one stray point 3.5 spacings (0.02) outside it, along the normal of the
    // point farthest along +x: an implicit fit wraps a small closed blob around it, which the
    // spurious rule cannot see (the stray is an input point) but the support count can.
    let dir = tempfile::tempdir().unwrap();
    let text = fs::read_to_string(sample()).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    let side = rows
        .iter()
        .max_by(|a, b| a[0].total_cmp(&b[0]))
        .unwrap()
        .clone();
    let stray: Vec<f64> = (0..3).map(|a| side[a] + 0.02 * side[3 + a]).collect();
    let points = dir.path().join("stray.xyzn");
    let extra = format!(
        "{} {} {} {} {} {}\n",
        stray[0], stray[1], stray[2], side[3], side[4], side[5]
    );
    fs::write(&points, text + &extra).unwrap();
    let field = dir.path().join("stray.zsf");
    let mesh = dir.path().join("stray.ply");
    let (p, f, m) = (
        points.to_str().unwrap(),
        field.to_str().unwrap(),
        mesh.to_str().unwrap(),
    );
    // The fit would set the stray aside (its spacing is 3.5 times the median): keep it.
    let out = zeroset([
        "fit",
        p,
        "--method",
        "rbf",
        "--outlier-ratio",
        "0",
        "-o",
        f,
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut args = vec![
        "mesh", f, "-o", m, "--force", "--quiet", "--detail", "fine", "--method", "smc",
    ];
    // An RBF field's centres are no count of input points: without --scan no component is
    // called weak (the blob is still there: two components).
    let out = zeroset(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("spurious: none")
            && !text.contains("weak:")
            && text.contains("Euler characteristic 4, 2 component(s)"),
        "{text}"
    );
    // With the scan, its points are counted: the blob is fitted to the stray alone.
    args.extend(["--scan", p, "--scan-outlier-ratio", "0"]);
    let out = zeroset(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("weak: 1 of 2 component(s)")
            && text.contains("at most 1 input point each")
            && text.contains("--drop-spurious removes them")
            && text.contains("Euler characteristic 4, 2 component(s)"),
        "{text}"
    );
    args.push("--drop-spurious");
    let out = zeroset(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("; dropped") && text.contains("Euler characteristic 2, 1 component(s)"),
        "{text}"
    );
    // reconstruct drops them by default (it gives the mesh stage the scan), and keeps them
    // when asked.
    let rebuilt = dir.path().join("rebuilt.ply");
    let r = rebuilt.to_str().unwrap();
    let mut args = vec![
        "reconstruct",
        p,
        "-o",
        r,
        "--outlier-ratio",
        "0",
        "--no-preview",
        "--quiet",
    ];
    let out = zeroset(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("weak: 1 of 2 component(s)")
            && text.contains("; dropped")
            && text.contains("Euler characteristic 2, 1 component(s)"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    args.extend(["--keep-spurious", "--force"]);
    let out = zeroset(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("--drop-spurious removes them") && text.contains(", 2 component(s)"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn mesh_reports_and_drops_components_no_point_supports() {
    // A unit sphere of value constraints, and far from it a cluster of negative values: the
    // RBF's zero set also wraps around the cluster, a surface no point lies on.
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::new();
    let n = 300;
    for k in 0..n {
        let z = -1.0 + (2 * k + 1) as f64 / n as f64;
        let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399_963_229_728_653);
        let u = [s * t.cos(), s * t.sin(), z];
        text += &format!("{} {} {} 0\n", u[0], u[1], u[2]);
        if k % 3 == 0 {
            for (scale, value) in [(1.1, 0.1), (0.9, -0.1)] {
                let p = u.map(|c| c * scale);
                text += &format!("{} {} {} {value}\n", p[0], p[1], p[2]);
            }
        }
    }
    for k in 0..8 {
        let p = [
            6.0 + 0.05 * (k % 2) as f64,
            0.05 * ((k / 2) % 2) as f64,
            0.05 * (k / 4) as f64,
        ];
        text += &format!("{} {} {} -1\n", p[0], p[1], p[2]);
    }
    let points = dir.path().join("two.xyzv");
    std::fs::write(&points, text).unwrap();
    let field = dir.path().join("two.zsf");
    let (f, p) = (field.to_str().unwrap(), points.to_str().unwrap());
    let out = zeroset(["fit", p, "--method", "rbf", "-o", f, "--quiet"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mesh = dir.path().join("two.ply");
    let m = mesh.to_str().unwrap();
    let out = zeroset(["mesh", f, "-o", m, "--quiet"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("spurious: 1 of 2 component(s)")
            && text.contains("--drop-spurious removes them")
            && text.contains(", 2 component(s)"),
        "{text}"
    );
    let out = zeroset(["mesh", f, "-o", m, "--force", "--drop-spurious", "--quiet"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("; dropped")
            && text.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{text}"
    );
    // An MRAS field records its points: its mesh is checked against them.
    let mras = dir.path().join("mras.zsf");
    let out = zeroset([
        "fit",
        sample().to_str().unwrap(),
        "--method",
        "mras",
        "--max-level",
        "2",
        "-o",
        mras.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = zeroset(["info", mras.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("2000 input points recorded"), "{text}");
    let out = zeroset([
        "mesh",
        mras.to_str().unwrap(),
        "-o",
        m,
        "--force",
        "--drop-spurious",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("spurious: none"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A field that records no points (restored: a B-spline on a grid) cannot say what is
    // spurious.
    let sampled = dir.path().join("sampled.zsf");
    let out = zeroset([
        "restore",
        mras.to_str().unwrap(),
        "--mode",
        "protrusion",
        "--mask",
        EARS,
        "--face",
        "-y",
        "--grid",
        "24,24,24",
        "-o",
        sampled.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = zeroset([
        "mesh",
        sampled.to_str().unwrap(),
        "-o",
        m,
        "--force",
        "--drop-spurious",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--drop-spurious needs the points"), "{err}");
}

#[test]
fn rbf_tolerance_keeps_only_the_centres_it_needs() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("g.zsf");
    let sample = sample();
    let out = zeroset([
        "fit",
        sample.to_str().unwrap(),
        "--method",
        "rbf",
        "--tolerance",
        "1e-3",
        "-o",
        out_path.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("greedy:"))
        .unwrap_or_else(|| panic!("no greedy line in:\n{text}"));
    // "N round(s), 1000 → K of 6000 centres; largest residual R … (tolerance T = 0.001 …)"
    let kept: usize = line
        .split("→ ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(kept < 6000, "{line}");
    assert!(!line.contains("NOT met"), "{line}");
    // The field file holds just those centres.
    let info = zeroset(["info", out_path.to_str().unwrap()]);
    let info = String::from_utf8_lossy(&info.stdout);
    assert!(info.contains(&format!("centres = {kept}")), "{info}");
    // A tolerance that is not a fraction, and MRAS-only options, are refused.
    let bad = zeroset([
        "fit",
        sample.to_str().unwrap(),
        "--method",
        "rbf",
        "--tolerance",
        "2",
    ]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("between 0 and 1"));
    // The same target as a distance in the cloud's units: the greedy line names it and its
    // fraction of the diagonal.
    let by_distance = zeroset([
        "fit",
        sample.to_str().unwrap(),
        "--method",
        "rbf",
        "--tolerance-distance",
        "2e-4",
        "--quiet",
    ]);
    let text = String::from_utf8_lossy(&by_distance.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("greedy:"))
        .unwrap_or_else(|| panic!("no greedy line in:\n{text}"));
    assert!(line.contains("(tolerance 0.0002 = "), "{line}");
    assert!(!line.contains("NOT met"), "{line}");
    for (flags, want) in [
        (&["--tolerance-distance", "0"][..], "positive distance"),
        (
            &["--tolerance", "1e-3", "--tolerance-distance", "1"][..],
            "cannot be used with",
        ),
    ] {
        let mut argv = vec!["fit", sample.to_str().unwrap(), "--method", "rbf"];
        argv.extend_from_slice(flags);
        let bad = zeroset(argv);
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(
            !bad.status.success() && err.contains(want),
            "{flags:?}: {err}"
        );
    }
    let bad = zeroset([
        "fit",
        sample.to_str().unwrap(),
        "--method",
        "rbf",
        "--max-level",
        "3",
    ]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("an option of --method mras"));
}

/// The upper half of the sphere of the fit tests (points with normal z ≥ 0), as `x y z nx ny
/// nz` lines: an open scan.
fn hemisphere_xyzn(n: usize) -> String {
    sphere_points(n)
        .iter()
        .filter(|(_, q)| q[2] >= 0.0)
        .map(|(p, q)| format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], q[0], q[1], q[2]))
        .collect()
}

#[test]
fn reconstruct_and_mesh_trim_an_open_scan_to_its_points() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("dome.xyzn");
    fs::write(&scan, hemisphere_xyzn(12000)).unwrap();
    let reconstruct = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            OsStr::new("reconstruct"),
            scan.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
            OsStr::new("--no-preview"),
            OsStr::new("--quiet"),
        ];
        args.extend(extra.iter().map(OsStr::new));
        zeroset(args)
    };
    let half_area = 2.0 * std::f64::consts::PI * RADIUS * RADIUS;
    // Untrimmed, the zero set runs on below the dome's rim; the report says how much of it
    // the scan does not reach, and what cuts it.
    let whole = dir.path().join("whole.ply");
    let o = reconstruct(&whole, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("(an open scan?); --trim cuts it there"),
        "{}",
        stdout(&o)
    );
    // ... and where: the largest region beyond reach is the lid the field closed the dome
    // with, below its rim (at z = 0.3) and as wide as the dome.
    let text = stdout(&o);
    let unseen = text
        .lines()
        .find(|l| l.starts_with("unseen: "))
        .unwrap_or_else(|| panic!("no unseen line in {text}"));
    assert!(unseen.contains("beyond the scan's reach"), "{unseen}");
    let centre: Vec<f64> = unseen
        .rsplit_once("around (")
        .and_then(|(_, rest)| rest.strip_suffix(')'))
        .map(|c| c.split(", ").map(|v| v.parse().unwrap()).collect())
        .unwrap_or_else(|| panic!("no centre in {unseen}"));
    assert!(centre[2] < CENTRE[2], "{unseen}");
    assert!(unseen.contains(" spans 1.0"), "{unseen}");
    let untrimmed = zeroset_mesh::check(&zeroset_mesh::read_mesh(&whole).unwrap());
    assert!(untrimmed.area > 1.1 * half_area, "{}", untrimmed.area);
    // Trimmed: one disc (Euler characteristic 1, one boundary loop) a little larger than
    // the half sphere, reaching about two local spacings below its rim.
    let dome = dir.path().join("dome.ply");
    let o = reconstruct(&dome, &["--trim"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("trim: cut "), "{}", stdout(&o));
    let trimmed = zeroset_mesh::read_mesh(&dome).unwrap();
    let r = zeroset_mesh::check(&trimmed);
    assert_eq!(
        (r.components, r.euler_characteristic, r.non_manifold_edges),
        (1, 1, 0),
        "{r}"
    );
    assert_eq!(zeroset_mesh::boundary_loops(&trimmed), 1);
    assert!(
        r.area > half_area && r.area < 1.12 * half_area,
        "area {} against the half sphere's {half_area}",
        r.area
    );
    let lowest = trimmed
        .vertices()
        .iter()
        .map(|v| v[2] - CENTRE[2])
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > -0.25 * RADIUS && lowest < 0.0, "{lowest}");
    // A tighter reach cuts closer to the rim.
    let tight = dir.path().join("tight.ply");
    let o = reconstruct(&tight, &["--trim=1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let tight_area = zeroset_mesh::check(&zeroset_mesh::read_mesh(&tight).unwrap()).area;
    assert!(
        tight_area < r.area && tight_area > half_area,
        "{tight_area} {}",
        r.area
    );
    // An MRAS field records its points: `zeroset mesh --trim` needs no --scan.
    let field = dir.path().join("dome.zsf");
    let o = zeroset([
        OsStr::new("fit"),
        scan.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("mras"),
        OsStr::new("--quiet"),
        OsStr::new("-o"),
        field.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mras = dir.path().join("mras.ply");
    let o = mesh(&field, &mras, &["--trim"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = zeroset_mesh::read_mesh(&mras).unwrap();
    let r = zeroset_mesh::check(&m);
    assert_eq!((r.components, r.euler_characteristic), (1, 1), "{r}");
    assert!(
        r.area > half_area && r.area < 1.12 * half_area,
        "{}",
        r.area
    );
}

/// An E57 file of two stations: scan 0 from inside a room (the inside of a sphere of radius 3
/// about the origin), its scanner at `(0.2, −0.1, 0.3)`; scan 1 of a wall outside it (a curved
/// 2 × 2 sheet about x = 5), its scanner at `(8, 0, 0)` and turned a quarter about z. Each
/// scan stores its points in its own frame, as a scanner does. Returns the file's points in
/// the common frame, scan after scan.
fn two_station_e57(path: &Path) -> Vec<[f64; 3]> {
    use e57::{Quaternion, Record, RecordValue, Transform, Translation};
    let room: Vec<[f64; 3]> = sphere_points(2000)
        .into_iter()
        .map(|(_, n)| n.map(|x| 3.0 * x))
        .collect();
    let wall: Vec<[f64; 3]> = (0..1600)
        .map(|i| {
            let (y, z) = ((i % 40) as f64 * 0.05 - 1.0, (i / 40) as f64 * 0.05 - 1.0);
            [5.0 + 0.1 * (2.0 * y).sin() * z.cos(), y, z]
        })
        .collect();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    // (station, quaternion (w, x, y, z) of its rotation, its points).
    let stations = [
        ([0.2, -0.1, 0.3], [1.0, 0.0, 0.0, 0.0], &room),
        ([8.0, 0.0, 0.0], [h, 0.0, 0.0, h], &wall),
    ];
    let mut writer = e57::E57Writer::from_file(path, "{two stations}").unwrap();
    for (i, (t, q, points)) in stations.iter().enumerate() {
        let prototype = vec![
            Record::CARTESIAN_X_F64,
            Record::CARTESIAN_Y_F64,
            Record::CARTESIAN_Z_F64,
        ];
        let mut scan = writer
            .add_pointcloud(&format!("{{scan {i}}}"), prototype)
            .unwrap();
        scan.set_transform(Some(Transform {
            rotation: Quaternion {
                w: q[0],
                x: q[1],
                y: q[2],
                z: q[3],
            },
            translation: Translation {
                x: t[0],
                y: t[1],
                z: t[2],
            },
        }));
        // A rotation about z by 0 or a quarter turn: local = Rᵀ (p − t).
        let quarter = q[3] != 0.0;
        for p in points.iter() {
            let d = [p[0] - t[0], p[1] - t[1], p[2] - t[2]];
            let local = if quarter { [d[1], -d[0], d[2]] } else { d };
            scan.add_point(local.map(RecordValue::Double).to_vec())
                .unwrap();
        }
        scan.finalize().unwrap();
    }
    writer.finalize().unwrap();
    room.iter().chain(&wall).copied().collect()
}

#[test]
fn normals_turns_each_e57_scan_towards_its_own_scanner() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.e57");
    let points = two_station_e57(&scene);
    let o = info(&scene, &[]);
    assert!(stdout(&o).contains("2 scans"), "{}", stdout(&o));
    let normals = |viewpoint: &str| {
        let out = dir.path().join("out.xyzn");
        let o = zeroset([
            OsStr::new("normals"),
            scene.as_os_str(),
            OsStr::new("--viewpoint"),
            OsStr::new(viewpoint),
            OsStr::new("--force"),
            OsStr::new("-o"),
            out.as_os_str(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let rows: Vec<Vec<f64>> = fs::read_to_string(&out)
            .unwrap()
            .lines()
            .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
            .collect();
        (stdout(&o), rows)
    };
    // Each station's points face it: the room inward (against the radius), the wall towards +x.
    let (out, rows) = normals("scanners");
    assert!(
        out.contains("towards the scanner of its scan (2 scans; "),
        "{out}"
    );
    assert_eq!(rows.len(), points.len());
    for (row, p) in rows.iter().zip(&points) {
        for a in 0..3 {
            assert!((row[a] - p[a]).abs() < 1e-12, "{row:?} vs {p:?}");
        }
        let facing = if p[0] < 4.0 {
            -(0..3).map(|a| row[3 + a] * p[a]).sum::<f64>() / 3.0
        } else {
            row[3]
        };
        assert!(facing > 0.8, "{row:?}");
    }
    // One viewpoint for both (the room's scanner) sees the wall from behind and turns it away
    // from the scanner that recorded it.
    let (_, rows) = normals("0.2,-0.1,0.3");
    assert!(rows[2000..].iter().all(|row| row[3] < -0.8));
}

#[test]
fn normals_says_a_flat_scan_faces_up_by_convention() {
    // Terrain (one side of a gently rolling sheet, z up) has no inside to read: it faced
    // down, with no word. It faces +z now, and the note says it is a convention.
    let text: String = (0..2500)
        .map(|i| {
            let (x, y) = ((i % 50) as f64 * 0.2, (i / 50) as f64 * 0.2);
            format!("{x} {y} {}\n", 0.3 * x.sin() * (0.7 * y).cos())
        })
        .collect();
    let (dir, scan) = temp_file("terrain.xyz", &text);
    let oriented = dir.path().join("terrain.xyzn");
    let o = zeroset([
        "normals",
        scan.to_str().unwrap(),
        "-o",
        oriented.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("1 piece turned outward, 1 of them flat (below)"),
        "{out}"
    );
    assert!(
        out.contains(
            "a piece of 2500 points is flat, with no inside to read its side from: \
             turned by convention to face +z"
        ),
        "{out}"
    );
    let up = fs::read_to_string(&oriented)
        .unwrap()
        .lines()
        .filter(|l| l.split_whitespace().nth(5).unwrap().parse::<f64>().unwrap() > 0.0)
        .count();
    assert_eq!(up, 2500);
}

#[test]
fn normals_orients_a_scan_of_positions_and_reconstruct_uses_them() {
    let dir = tempfile::tempdir().unwrap();
    // The sphere's positions alone, as `x y z r g b` with colours in columns 4–6.
    let points = sphere_points(1500);
    let rgb: String = points
        .iter()
        .enumerate()
        .map(|(i, (p, _))| format!("{} {} {} {} 0 255\n", p[0], p[1], p[2], i % 256))
        .collect();
    let scan = dir.path().join("sphere.xyz");
    fs::write(&scan, rgb).unwrap();
    let normals = |input: &Path, output: &Path| {
        zeroset([
            OsStr::new("normals"),
            input.as_os_str(),
            OsStr::new("-o"),
            output.as_os_str(),
        ])
    };
    let oriented = dir.path().join("sphere.xyzn");
    let o = normals(&scan, &oriented);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("are not unit normals (colours?)"), "{out}");
    assert!(out.contains("1 piece turned outward"), "{out}");
    // Every normal unit and outward (within 3° of the radius), in the input's order.
    let text = fs::read_to_string(&oriented).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), points.len());
    for (row, (p, n)) in rows.iter().zip(&points) {
        assert_eq!(&row[..3], p);
        let cos: f64 = (0..3).map(|a| row[3 + a] * n[a]).sum();
        assert!(cos > 3f64.to_radians().cos(), "{row:?} against {n:?}");
    }
    // Seen from the centre (a room scanned from inside) with --viewpoint: every normal inward.
    let inside = dir.path().join("inside.xyzn");
    let o = zeroset([
        OsStr::new("normals"),
        scan.as_os_str(),
        OsStr::new("--viewpoint"),
        OsStr::new("0.1,-0.2,0.3"),
        OsStr::new("-o"),
        inside.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("turned towards the viewpoint [0.1, -0.2, 0.3]"));
    let text = fs::read_to_string(&inside).unwrap();
    for (line, (_, n)) in text.lines().zip(&points) {
        let row: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        let cos: f64 = (0..3).map(|a| row[3 + a] * n[a]).sum();
        assert!(cos < -3f64.to_radians().cos(), "{row:?} against {n:?}");
    }
    // With the file's own normals it says how far they are.
    let given = dir.path().join("given.xyzn");
    fs::write(&given, sphere_xyzn(1500)).unwrap();
    let compared = dir.path().join("compared.ply");
    let o = normals(&given, &compared);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("with the file's normals: 0 of 1500 (0%) point the other way"),
        "{}",
        stdout(&o)
    );
    // `reconstruct` estimates them itself and meshes a closed sphere; no temporary is left.
    let reconstruct = |scan: &Path, mesh: &Path, extra: &[&str]| {
        let mut args = vec![
            OsStr::new("reconstruct"),
            scan.as_os_str(),
            OsStr::new("-o"),
            mesh.as_os_str(),
            OsStr::new("--detail"),
            OsStr::new("general"),
            OsStr::new("--no-preview"),
            OsStr::new("--quiet"),
        ];
        args.extend(extra.iter().map(OsStr::new));
        zeroset(args)
    };
    let mesh = dir.path().join("mesh.ply");
    let o = reconstruct(&scan, &mesh, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("has no normals: estimating them"), "{out}");
    assert!(
        out.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{out}"
    );
    let volume =
        |path: &Path| zeroset_mesh::check(&zeroset_mesh::read_mesh(path).unwrap()).signed_volume;
    let ball = 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3);
    assert!(
        (volume(&mesh) / ball - 1.0).abs() < 0.02,
        "{}",
        volume(&mesh)
    );
    // Seen from its centre (CENTRE), as a scan of a room is: the normals face the viewpoint,
    // and the solid is what lies outside the sphere (the mesh wound inward, its volume
    // negative).
    let room = dir.path().join("room.ply");
    let o = reconstruct(&scan, &room, &["--viewpoint", "0.1,-0.2,0.3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("towards the viewpoint [0.1, -0.2, 0.3]"),
        "{}",
        stdout(&o)
    );
    assert!(
        (volume(&room) / ball + 1.0).abs() < 0.02,
        "{}",
        volume(&room)
    );
    // A scan whose normals include NaN (PCL writes them where it could not estimate one):
    // the file's normals are set aside and estimated, as for a scan without normals.
    let holes = dir.path().join("holes.xyzn");
    let text: String = sphere_xyzn(1500)
        .lines()
        .enumerate()
        .map(|(i, line)| {
            let mut words: Vec<&str> = line.split_whitespace().collect();
            if i == 7 {
                words[3] = "nan";
            }
            words.join(" ") + "\n"
        })
        .collect();
    fs::write(&holes, &text).unwrap();
    let patched = dir.path().join("patched.ply");
    let o = reconstruct(&holes, &patched, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("record 7 has a non-finite normal"),
        "{}",
        stdout(&o)
    );
    assert!(
        (volume(&patched) / ball - 1.0).abs() < 0.02,
        "{}",
        volume(&patched)
    );
    // Stray points far from the sphere, positions only: set aside before the estimate (their
    // estimated normals would agree with each other's and pass for a sparse patch).
    let strays = dir.path().join("strays.xyz");
    let mut text: String = sphere_xyzn(1500)
        .lines()
        .map(|line| {
            line.split_whitespace()
                .take(3)
                .collect::<Vec<_>>()
                .join(" ")
                + "\n"
        })
        .collect();
    let mut state = 12345u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut added = 0;
    while added < 30 {
        let q = [uniform(), uniform(), uniform()];
        if ((q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt() - RADIUS).abs() > 0.25 {
            let p: Vec<String> = (0..3).map(|a| (q[a] + CENTRE[a]).to_string()).collect();
            text += &(p.join(" ") + "\n");
            added += 1;
        }
    }
    fs::write(&strays, text).unwrap();
    let cleaned = dir.path().join("cleaned.ply");
    let o = reconstruct(&strays, &cleaned, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("30 isolated points set aside before the estimate"),
        "{out}"
    );
    assert!(
        out.contains("report: closed, Euler characteristic 2, 1 component(s)"),
        "{out}"
    );
    // A scan with normals of its own keeps them: a viewpoint is refused, before any work.
    let o = zeroset([
        OsStr::new("reconstruct"),
        given.as_os_str(),
        OsStr::new("-o"),
        dir.path().join("refused.ply").as_os_str(),
        OsStr::new("--viewpoint"),
        OsStr::new("0,0,0"),
    ]);
    assert_clean_failure(&o);
    assert!(
        stderr(&o).contains("has normals of its own"),
        "{}",
        stderr(&o)
    );
    let mut names: Vec<_> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "cleaned.ply",
            "compared.ply",
            "given.xyzn",
            "holes.xyzn",
            "inside.xyzn",
            "mesh.ply",
            "patched.ply",
            "room.ply",
            "sphere.xyz",
            "sphere.xyzn",
            "strays.xyz"
        ]
    );
}

#[test]
fn an_mras_field_of_a_dense_scan_is_meshed_no_coarser_than_the_scan() {
    let dir = tempfile::tempdir().unwrap();
    // Two balls of radius 0.05 at opposite corners of a chunky box, 10,000 points each (spaced
    // about 0.002): dense against the fine voxels of the box (1/133 of its longest axis, 0.009),
    // fitted by MRAS to `tolerance`.
    let r = 0.05;
    let balls = |name: &str, tolerance: &str| -> PathBuf {
        let mut cloud = String::new();
        for c in [[0.0, 0.0, 0.0], [1.0, 1.0, 0.5]] {
            for (_, n) in sphere_points(10_000) {
                let p: [f64; 3] = std::array::from_fn(|a| c[a] + r * n[a]);
                cloud += &format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], n[0], n[1], n[2]);
            }
        }
        let path = dir.path().join(format!("{name}.xyzn"));
        fs::write(&path, cloud).unwrap();
        let field = dir.path().join(format!("{name}.zsf"));
        let o = zeroset([
            "fit",
            path.to_str().unwrap(),
            "--method",
            "mras",
            "--tolerance",
            tolerance,
            "-o",
            field.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        field
    };
    let out = dir.path().join("m.ply");
    let grid_line = |field: &Path, extra: &[&str]| -> (String, usize) {
        let mut args = vec!["--force"];
        args.extend(extra);
        let o = mesh(field, &out, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = stdout(&o);
        let grid = text
            .lines()
            .find(|l| l.starts_with("grid "))
            .unwrap_or_else(|| panic!("no grid line in {text}"))
            .to_owned();
        let vertices = text
            .split("mesh: ")
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no vertex count in {text}"));
        (grid, vertices)
    };
    let number = |after: &str, line: &str| -> f64 {
        line.split(after)
            .nth(1)
            .and_then(|s| s.split([' ', ',', ')']).next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no number after {after:?} in {line}"))
    };
    // At the default tolerance the field's finest splines are coarser than the fine voxels:
    // nothing to gain from finer ones.
    let smooth = balls("smooth", "0.001");
    let (l0_rule, _) = grid_line(&smooth, &[]);
    assert!(l0_rule.contains("(0.3 × l0, Fine detail;"), "{l0_rule}");
    // At 1e-4 its finest knots are 0.012 apart: half of that, coarser than 2 spacings.
    let medium = balls("medium", "0.0001");
    let (by_knots, _) = grid_line(&medium, &[]);
    assert!(
        by_knots.contains("(0.5 × the knot spacing ")
            && by_knots.contains("of the field's finest splines, the finest detail it holds"),
        "{by_knots}"
    );
    let knots = number("the knot spacing ", &by_knots);
    assert!(
        (number("voxel ", &by_knots) / knots - 0.5).abs() < 1e-6,
        "{by_knots}"
    );
    // At 2e-5 they are finer than that: 2 spacings, finer than the fine voxel.
    let field = balls("balls", "0.00002");
    let (dense, dense_vertices) = grid_line(&field, &[]);
    assert!(
        dense.contains(
            "(2 × the scan's median spacing: the points the field was fitted to, spaced "
        ),
        "{dense}"
    );
    assert!(dense.contains("which --detail fine keeps"), "{dense}");
    let (voxel, spacing) = (number("voxel ", &dense), number("spaced ", &dense));
    assert!((voxel / spacing - 2.0).abs() < 1e-6, "{dense}");
    // An explicit --detail keeps the l0 rule: coarser, fewer vertices.
    let (fine, fine_vertices) = grid_line(&field, &["--detail", "fine"]);
    assert!(fine.contains("(0.3 × l0, Fine detail;"), "{fine}");
    assert!(voxel < number("voxel ", &fine), "{dense} against {fine}");
    assert!(
        dense_vertices > 2 * fine_vertices,
        "{dense_vertices} against {fine_vertices}"
    );
    // The density is the fitted points': a sparser --scan (for the coverage check) leaves it.
    let sparse = dir.path().join("sparse.xyz");
    let kept: String = sphere_points(500)
        .iter()
        .map(|(_, n)| format!("{} {} {}\n", r * n[0], r * n[1], r * n[2]))
        .collect();
    fs::write(&sparse, kept).unwrap();
    let (with_scan, _) = grid_line(&field, &["--scan", sparse.to_str().unwrap()]);
    assert_eq!(with_scan, dense);
    // A level set 0.01 out lies 5 spacings from the points throughout: --trim measures its
    // reach past that offset, and cuts (almost) nothing.
    let o = mesh(&field, &out, &["--force", "--level", "0.01", "--trim"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("plus the level's offset 0.01"), "{text}");
    let cut = number("trim: cut ", &text.replace('%', " "));
    assert!(cut < 1.0, "{text}");
}
