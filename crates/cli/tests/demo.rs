//! `zeroset demo --out DIR`: the whole pipeline on the bundled sample, run as a user would.

use std::ffi::OsStr;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn zeroset<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Output {
    Command::new(env!("CARGO_BIN_EXE_zeroset"))
        .args(args)
        .output()
        .expect("cannot run the zeroset binary")
}

#[test]
fn demo_writes_a_closed_mesh_a_preview_and_a_report() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("nested").join("demo");
    let start = Instant::now();
    let o = zeroset([
        OsStr::new("demo"),
        OsStr::new("--quiet"),
        OsStr::new("--out"),
        out.as_os_str(),
    ]);
    let took = start.elapsed();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "demo failed: {}\n{stdout}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(took < Duration::from_secs(60), "demo took {took:?}");
    assert!(stdout.contains("== pipeline"), "{stdout}");

    let mesh = zeroset_mesh::io::read_ply_mesh(out.join("bunny.ply")).expect("reading the PLY");
    assert!(mesh.num_triangles() > 0);
    let report = zeroset_mesh::checks::check(&mesh);
    assert!(report.closed, "{report:?}");
    assert_eq!(report.euler_characteristic, 2, "{report:?}");
    assert!(report.signed_volume > 0.0, "{report:?}");

    let png = std::fs::read(out.join("bunny.png")).expect("reading the PNG");
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");

    let text = std::fs::read_to_string(out.join("report.txt")).expect("reading report.txt");
    for word in [
        "solver",
        "steps",
        "residual",
        "vertices",
        "triangles",
        "closed",
        "Euler",
    ] {
        assert!(text.contains(word), "report.txt lacks {word}: {text}");
    }
}
