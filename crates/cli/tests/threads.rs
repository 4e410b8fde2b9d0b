//! `--threads N` changes the speed and nothing else: for every field kind, every mesher and
//! `zeroset restore`, the output file of a run on 1 thread and on [`MANY`] threads (more than
//! this machine's cores, to stress the scheduling) is the same, byte for byte.
//!
//! The inputs are subsets of the bundled sample written by the tests, and the grids are small,
//! so that the whole file takes seconds in the dev profile. Paths the command line reaches only
//! on large inputs (the coarse level of the iterative RBF fit from 4,000 functionals on, its
//! FMM products from 15,000) are checked on the same kind of 1-against-3-thread comparison in
//! `zeroset-bases`' `tests/rbf_threads.rs`.

use std::ffi::OsStr;
use std::fs;
use std::path::{Path, PathBuf};

/// The thread count compared with 1.
const MANY: &str = "4";

mod common;
use common::{sample, zeroset};

/// Every `every`-th point of the sample (2,000 points), as `name` in `dir`.
fn subset(dir: &Path, name: &str, every: usize) -> PathBuf {
    let text = fs::read_to_string(sample()).unwrap();
    let lines: String = text
        .lines()
        .step_by(every)
        .flat_map(|l| [l, "\n"])
        .collect();
    let path = dir.join(name);
    fs::write(&path, lines).unwrap();
    path
}

/// Runs `zeroset --threads T <args> -o <dir/T-name>` for T = 1 and [`MANY`], asserts that both
/// succeed and wrote the same bytes, and returns the 1-thread output's path.
fn same_output(dir: &Path, name: &str, args: &[&OsStr]) -> PathBuf {
    let mut outputs = Vec::new();
    for threads in ["1", MANY] {
        let out = dir.join(format!("{threads}-{name}"));
        let mut all: Vec<&OsStr> = vec![OsStr::new("--threads"), OsStr::new(threads)];
        all.extend_from_slice(args);
        all.extend([OsStr::new("-o"), out.as_os_str()]);
        let o = zeroset(&all);
        assert!(
            o.status.success(),
            "zeroset {all:?}:\n{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        outputs.push(out);
    }
    assert_same_files(&outputs[0], &outputs[1]);
    outputs.swap_remove(0)
}

/// Asserts that two files hold the same, non-empty bytes; otherwise names the first byte
/// that differs.
fn assert_same_files(a: &Path, b: &Path) {
    let (x, y) = (fs::read(a).unwrap(), fs::read(b).unwrap());
    assert!(!x.is_empty(), "{} is empty", a.display());
    if x != y {
        let at = x.iter().zip(&y).position(|(p, q)| p != q);
        panic!(
            "{} ({} bytes) and {} ({} bytes) differ, first at byte {at:?}",
            a.display(),
            x.len(),
            b.display(),
            y.len()
        );
    }
}

fn os<'a>(args: &[&'a str]) -> Vec<&'a OsStr> {
    args.iter().map(|a| OsStr::new(*a)).collect()
}

/// `fit <points> --method … --quiet <extra>` on 1 and [`MANY`] threads: the field files agree.
fn fit(dir: &Path, points: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let mut args = vec![OsStr::new("fit"), points.as_os_str(), OsStr::new("--quiet")];
    args.extend(os(extra));
    same_output(dir, name, &args)
}

/// `mesh <field> --quiet <extra>` on 1 and [`MANY`] threads: the mesh files agree.
fn mesh(dir: &Path, field: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let mut args = vec![OsStr::new("mesh"), field.as_os_str(), OsStr::new("--quiet")];
    args.extend(os(extra));
    same_output(dir, name, &args)
}

// ---- field kinds, each also meshed by marching cubes ----

#[test]
fn rbf_dense_and_mixed_fits_and_their_meshes_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b500.xyzn", 4);
    // The dense solve (projected Cholesky, then its triangular solves), off-surface points.
    let dense = fit(
        dir.path(),
        &points,
        "dense.zsf",
        &["--method", "rbf", "--solver", "dense"],
    );
    // Hermite constraints with r3: gradient functionals, dense.
    fit(
        dir.path(),
        &points,
        "hermite.zsf",
        &["--method", "rbf", "--hermite", "--solver", "dense"],
    );
    // The f32 Cholesky preconditioning GMRES.
    fit(
        dir.path(),
        &points,
        "mixed.zsf",
        &["--method", "rbf", "--solver", "mixed"],
    );
    // Carr's greedy centre reduction (incremental dense solves).
    fit(
        dir.path(),
        &points,
        "greedy.zsf",
        &["--method", "rbf", "--tolerance", "1e-4"],
    );
    mesh(
        dir.path(),
        &dense,
        "dense.ply",
        &["--resolution", "24", "--drop-spurious"],
    );
}

#[test]
fn rbf_iterative_fit_and_its_mesh_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b500.xyzn", 4);
    // GMRES in the cardinal basis, direct-sum products (1,500 functionals: no coarse level
    // and no FMM, which start at 4,000 and 15,000; see the module docs).
    let field = fit(
        dir.path(),
        &points,
        "iterative.zsf",
        &["--method", "rbf", "--solver", "iterative"],
    );
    mesh(dir.path(), &field, "iterative.obj", &["--resolution", "20"]);
}

#[test]
fn bspline_fit_and_its_mesh_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b500.xyzn", 4);
    let field = fit(
        dir.path(),
        &points,
        "bspline.zsf",
        &["--method", "rbf", "--sampled", "--grid", "24,24,20"],
    );
    mesh(
        dir.path(),
        &field,
        "bspline.ply",
        &["--resolution", "24", "--close"],
    );
}

#[test]
fn mras_fit_and_its_mesh_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b200.xyzn", 10);
    // Three levels with CP factors in every level (the ALS of the tensor crate).
    let field = fit(
        dir.path(),
        &points,
        "mras.zsf",
        &[
            "--method",
            "mras",
            "--max-level",
            "3",
            "--tolerance",
            "1e-2",
        ],
    );
    mesh(dir.path(), &field, "mras.ply", &["--resolution", "20"]);
}

#[test]
fn neural_fit_and_its_mesh_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    // 1,000 points: the last layer's least-squares refit is large enough for faer's parallel
    // QR (its answer changed with the thread count until it ran sequentially).
    let points = subset(dir.path(), "b1000.xyzn", 2);
    let field = fit(
        dir.path(),
        &points,
        "neural.zsf",
        &[
            "--method",
            "neural",
            "--steps",
            "60",
            "--resample-aux",
            "--refit-last-layer",
        ],
    );
    mesh(dir.path(), &field, "neural.ply", &["--resolution", "20"]);
}

#[test]
fn two_d_fits_and_their_curves_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let curve = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/curve.xyv"
    ));
    let tps = fit(dir.path(), &curve, "tps.zsf", &["--method", "rbf"]);
    mesh(dir.path(), &tps, "tps.svg", &["--resolution", "100"]);
    let neural = fit(
        dir.path(),
        &curve,
        "curve_nn.zsf",
        &["--method", "neural", "--steps", "100"],
    );
    mesh(
        dir.path(),
        &neural,
        "curve_nn.svg",
        &["--resolution", "100"],
    );
}

// ---- meshers ----

#[test]
fn marching_cubes_does_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b250.xyzn", 8);
    let field = dir.path().join("field.zsf");
    let o = zeroset([
        OsStr::new("fit"),
        points.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("rbf"),
        OsStr::new("--quiet"),
        OsStr::new("-o"),
        field.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Binary and ASCII PLY, another level, capped where it leaves the grid.
    mesh(dir.path(), &field, "mc.ply", &["--resolution", "32"]);
    mesh(
        dir.path(),
        &field,
        "mc_ascii.ply",
        &[
            "--resolution",
            "24",
            "--ascii",
            "--level",
            "0.002",
            "--close",
        ],
    );
}

#[test]
fn signed_marching_cubes_does_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b250.xyzn", 8);
    let field = dir.path().join("field.zsf");
    let o = zeroset([
        OsStr::new("fit"),
        points.as_os_str(),
        OsStr::new("--method"),
        OsStr::new("rbf"),
        OsStr::new("--quiet"),
        OsStr::new("-o"),
        field.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Step 1 by enclosures of blocks, and at every vertex (the FMM at both orders).
    for step in ["blocks", "every"] {
        mesh(
            dir.path(),
            &field,
            &format!("smc_{step}.ply"),
            &[
                "--method",
                "smc",
                "--always-smc",
                "--step",
                step,
                "--resolution",
                "32",
            ],
        );
    }
}

// ---- restore, and the whole pipeline ----

#[test]
fn restore_does_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b500.xyzn", 4);
    let ears = ["--mask", "-0.095,0.145,-0.065:0.0,0.19,0.04"];
    // Protrusion from a point cloud (the tangent-plane field sampled on the grid).
    let restored = same_output(
        dir.path(),
        "protrusion.zsf",
        &os(&[
            &["restore", points.to_str().unwrap(), "--mode", "protrusion"][..],
            &ears,
            &["--face", "-y", "--grid", "32,32,26"],
        ]
        .concat()),
    );
    // Without --face (harmonic from the boundary), from the restored field file.
    let harmonic = same_output(
        dir.path(),
        "harmonic.zsf",
        &os(&[
            &[
                "restore",
                restored.to_str().unwrap(),
                "--mode",
                "protrusion",
            ][..],
            &["--mask", "-0.05,0.05,-0.03:0.05,0.12,0.06"],
        ]
        .concat()),
    );
    // Denoise, by cell averages and by point resampling.
    for extra in [&[][..], &["--point-resampling"][..]] {
        same_output(
            dir.path(),
            &format!("denoise{}.zsf", extra.len()),
            &os(&[
                &["restore", harmonic.to_str().unwrap(), "--mode", "denoise"][..],
                &[
                    "--mask",
                    "-0.05,0.05,-0.03:0.05,0.12,0.06",
                    "--coarse",
                    "6,6,4",
                ],
                extra,
            ]
            .concat()),
        );
    }
}

#[test]
fn reconstruct_writes_the_same_mesh_preview_and_field_on_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let points = subset(dir.path(), "b250.xyzn", 8);
    let mut files = Vec::new();
    for threads in ["1", MANY] {
        let out = dir.path().join(format!("{threads}-scan.ply"));
        let field = dir.path().join(format!("{threads}-scan.zsf"));
        let o = zeroset([
            OsStr::new("--threads"),
            OsStr::new(threads),
            OsStr::new("reconstruct"),
            points.as_os_str(),
            OsStr::new("--quiet"),
            OsStr::new("--detail"),
            OsStr::new("coarse"),
            OsStr::new("--field"),
            field.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        files.push([out.clone(), out.with_extension("png"), field]);
    }
    for (a, b) in files[0].iter().zip(&files[1]) {
        assert_same_files(a, b);
    }
}
