//! The `zeroset` binary, run as a user would, on the shipped sample and on small broken files.

use std::ffi::OsStr;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn sample() -> PathBuf {
    let path = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/bunny_2k.xyzn"
    ));
    assert!(path.is_file(), "sample {} not found", path.display());
    path
}

fn zeroset<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Output {
    Command::new(env!("CARGO_BIN_EXE_zeroset"))
        .args(args)
        .output()
        .expect("cannot run the zeroset binary")
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
    let cases: [(&[&str], &str); 5] = [
        (
            &[
                "--mode",
                "protrusion",
                "--mask",
                "-0.095,0.145,-0.065:0.0,0.5,0.04",
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
            &["--mode", "denoise", "--mask", EARS, "--coarse", "100,2,2"],
            "coarse resolution 100",
        ),
        (&["--mode", "denoise", "--mask", EARS], "needs --coarse"),
        (
            &["--mode", "protrusion", "--mask", EARS, "--grid", "2,40,40"],
            "at least 3 samples",
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
