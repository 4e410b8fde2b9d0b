//! Resource limits end to end: requests sized from arguments or files that cannot be held are
//! refused at once with a message naming the amount, exit status 1 and no panic or abort.
//! `ZEROSET_MEMORY_LIMIT` caps the memory each run assumes, so the answers do not depend on
//! this machine's memory.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::{Duration, Instant};

use zeroset_bases::bspline::{BSplineField, Degree};
use zeroset_bases::field_file::write_field;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::Grid;

mod common;
use common::sample;

/// Runs the binary with `ZEROSET_MEMORY_LIMIT=limit` and its disk cache off.
fn zeroset_capped<S: AsRef<OsStr>>(limit: &str, args: impl IntoIterator<Item = S>) -> Output {
    common::zeroset_with(args, &[("ZEROSET_MEMORY_LIMIT", OsStr::new(limit))])
}

/// A refusal as the user sees it: status 1, an `error:` line holding every phrase, no panic,
/// within `seconds`.
fn assert_refused(o: &Output, started: Instant, phrases: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.starts_with("error: "), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for p in phrases {
        assert!(err.contains(p), "{p:?} missing in: {err}");
    }
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "slow refusal ({:?}): {err}",
        started.elapsed()
    );
}

/// A small B-spline field file on the cube [-1, 1]³.
fn field_file(dir: &Path) -> PathBuf {
    let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [6, 6, 6]).unwrap();
    let samples = (0..grid.len()).map(|i| i as f64 * 0.01 - 0.5).collect();
    let field = BSplineField::interpolate(grid, samples, Degree::Quadratic).unwrap();
    let path = dir.join("sphere.zsf");
    write_field(&path, &field).unwrap();
    path
}

#[test]
fn mesh_refuses_a_grid_beyond_the_memory_cap() {
    let dir = tempfile::tempdir().unwrap();
    let field = field_file(dir.path());
    let out = dir.path().join("m.ply");
    let started = Instant::now();
    let o = zeroset_capped(
        "16MiB",
        [
            OsStr::new("mesh"),
            field.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
            OsStr::new("--resolution"),
            OsStr::new("400"),
        ],
    );
    assert_refused(
        &o,
        started,
        &[
            "the grid 401×401×401 needs about 973.5 MiB of memory, more than the 16.0 MiB \
             allowed by ZEROSET_MEMORY_LIMIT",
        ],
    );
    assert!(!out.exists());
}

#[test]
fn a_dense_rbf_system_beyond_the_memory_cap_is_refused() {
    let sample = sample();
    let started = Instant::now();
    let o = zeroset_capped(
        "1MiB",
        [
            OsStr::new("fit"),
            sample.as_os_str(),
            OsStr::new("--method"),
            OsStr::new("rbf"),
            OsStr::new("--solver"),
            OsStr::new("dense"),
            OsStr::new("--quiet"),
        ],
    );
    assert_refused(
        &o,
        started,
        &[
            "needs about",
            "MiB of memory, more than the 1.0 MiB allowed by ZEROSET_MEMORY_LIMIT",
        ],
    );
}

#[test]
fn restore_refuses_a_grid_beyond_the_memory_cap() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.zsf");
    let sample = sample();
    let started = Instant::now();
    let o = zeroset_capped(
        "1MiB",
        [
            OsStr::new("restore"),
            sample.as_os_str(),
            OsStr::new("--mask"),
            OsStr::new("-0.095,0.145,-0.065:0.0,0.2,0.04"),
            OsStr::new("--mode"),
            OsStr::new("protrusion"),
            OsStr::new("--grid"),
            OsStr::new("200,200,200"),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
    );
    assert_refused(
        &o,
        started,
        &[
            "--grid 200,200,200",
            "needs about",
            "allowed by ZEROSET_MEMORY_LIMIT",
        ],
    );
    assert!(!out.exists());
}

#[test]
fn neural_training_beyond_the_memory_cap_is_refused() {
    let sample = sample();
    let started = Instant::now();
    let o = zeroset_capped(
        "64MiB",
        [
            OsStr::new("fit"),
            sample.as_os_str(),
            OsStr::new("--method"),
            OsStr::new("neural"),
            OsStr::new("--widths"),
            OsStr::new("4096,4096"),
            OsStr::new("--aux"),
            OsStr::new("1000000"),
            OsStr::new("--quiet"),
        ],
    );
    assert_refused(
        &o,
        started,
        &[
            "training the net [4096, 4096]",
            "needs about",
            "allowed by ZEROSET_MEMORY_LIMIT",
        ],
    );
}

#[test]
fn a_malformed_memory_cap_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let field = field_file(dir.path());
    let out = dir.path().join("m.ply");
    let started = Instant::now();
    let o = zeroset_capped(
        "lots",
        [
            OsStr::new("mesh"),
            field.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
    );
    assert_refused(
        &o,
        started,
        &["ZEROSET_MEMORY_LIMIT=\"lots\" is not a size"],
    );
}

/// CRC-32 (IEEE), bit by bit: the field file's checksum, so that only the counts are forged.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[test]
fn a_forged_count_in_a_tiny_field_file_is_refused() {
    // A B-spline payload announcing a 2²⁰ × 2²⁰ × 2²⁰ grid (8 EiB of coefficients) in 112
    // bytes, its checksum right.
    let mut payload = Vec::new();
    for v in [2u32, 0, 0] {
        payload.extend(v.to_le_bytes());
    }
    for _ in 0..3 {
        payload.extend((1u64 << 20).to_le_bytes());
    }
    for v in [-1.0f64, -1.0, -1.0, 1.0, 1.0, 1.0, 0.5] {
        payload.extend(v.to_le_bytes());
    }
    let mut bytes = b"ZSFIELD\0".to_vec();
    bytes.extend(2u32.to_le_bytes());
    bytes.extend(3u32.to_le_bytes());
    bytes.extend(b"bspline\0");
    bytes.extend(0u32.to_le_bytes());
    bytes.extend((payload.len() as u64).to_le_bytes());
    bytes.extend(&payload);
    let crc = crc32(&bytes);
    bytes.extend(crc.to_le_bytes());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("forged.zsf");
    std::fs::write(&path, &bytes).unwrap();
    let out = dir.path().join("m.ply");
    let started = Instant::now();
    let o = zeroset_capped(
        "",
        [
            OsStr::new("mesh"),
            path.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
    );
    assert_refused(
        &o,
        started,
        &[
            "B-spline coefficients",
            "1152921504606846976 announced",
            "the input is corrupt or truncated",
        ],
    );
}
