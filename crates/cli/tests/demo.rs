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
fn demo_writes_restored_and_fitted_meshes_previews_and_a_report() {
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

    // The restored (earless) bunny and the unrestored fit: both closed spheres.
    let mut max_y = Vec::new();
    for name in ["bunny", "bunny_fitted"] {
        let mesh = zeroset_mesh::io::read_ply_mesh(out.join(format!("{name}.ply")))
            .unwrap_or_else(|e| panic!("reading {name}.ply: {e}"));
        assert!(mesh.num_triangles() > 0, "{name}");
        let report = zeroset_mesh::checks::check(&mesh);
        assert!(report.closed, "{name}: {report:?}");
        assert_eq!(report.euler_characteristic, 2, "{name}: {report:?}");
        assert!(report.signed_volume > 0.0, "{name}: {report:?}");
        max_y.push(
            mesh.vertices()
                .iter()
                .map(|p| p[1])
                .fold(f64::NEG_INFINITY, f64::max),
        );

        let png = std::fs::read(out.join(format!("{name}.png")))
            .unwrap_or_else(|e| panic!("reading {name}.png: {e}"));
        assert!(
            png.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{name}.png is not a PNG"
        );
    }
    // The ears are the bunny's highest part: removing them lowers the top.
    assert!(
        max_y[0] < max_y[1],
        "restored max y {} not below fitted {}",
        max_y[0],
        max_y[1]
    );

    let text = std::fs::read_to_string(out.join("report.txt")).expect("reading report.txt");
    for word in [
        "solver",
        "steps",
        "residual",
        "vertices",
        "triangles",
        "closed",
        "Euler",
        "restore",
        "volume",
        "bunny_fitted.ply",
    ] {
        assert!(text.contains(word), "report.txt lacks {word}: {text}");
    }
}
