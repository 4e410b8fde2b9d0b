//! The field file with RBF fields: bit-for-bit round trips, version-1 compatibility and the
//! specific errors for corrupt, truncated, newer and unknown files.

use std::path::{Path, PathBuf};

use zeroset_bases::bspline::{BSplineField, Degree};
use zeroset_bases::field_file::{
    AnyField, FieldFileError, RbfAny, StoredKernel, VERSION, decode_any, encode, encode_rbf,
    read_any_field, read_field, read_metadata, write_field, write_rbf_field,
};
use zeroset_bases::rbf::{Biharmonic, Constraints, RbfField, RbfFit, Triharmonic, Wendland};
use zeroset_field_core::Error;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::grid::Grid;

struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("zsf-rbf-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }
    fn file(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Points on a sphere around (0.5, 0.5, 0.5) with outward normals.
fn sphere(n: usize) -> Vec<(Point<3>, Point<3>)> {
    (0..n)
        .map(|k| {
            let z = -1.0 + (2 * k + 1) as f64 / n as f64;
            let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * 2.399_963_229_728_653);
            let u = [s * t.cos(), s * t.sin(), z];
            (std::array::from_fn(|a| 0.5 + 0.35 * u[a]), u)
        })
        .collect()
}

fn constraints(with_gradient: bool) -> Constraints<3> {
    let on = sphere(40);
    let mut c = Constraints::new();
    for (p, _) in &on {
        c.push_value(*p, 0.0);
    }
    for (p, u) in on.iter().take(10) {
        c.push_value(std::array::from_fn(|a| p[a] + 0.05 * u[a]), 0.05);
        c.push_value(std::array::from_fn(|a| p[a] - 0.05 * u[a]), -0.05);
    }
    if with_gradient {
        c.push_gradient([0.5, 0.5, 0.85 + 0.1], [0.0, 0.0, 1.0]);
    }
    c
}

fn probes() -> Vec<Point<3>> {
    let mut p: Vec<Point<3>> = (0..64)
        .map(|i| {
            let t = i as f64 * 0.173;
            [
                0.5 + 0.6 * t.sin(),
                0.5 + 0.5 * (1.3 * t).cos(),
                0.5 + 0.4 * (0.7 * t).sin(),
            ]
        })
        .collect();
    p.extend(sphere(40).into_iter().take(5).map(|(q, _)| q));
    p.push([0.5, 0.5, 0.95]);
    p
}

fn assert_same<F: ScalarField<3>, G: ScalarField<3>>(a: &F, b: &G) {
    let pts = probes();
    for x in &pts {
        assert_eq!(a.value(x).to_bits(), b.value(x).to_bits(), "value at {x:?}");
        let (ga, gb) = (a.gradient(x), b.gradient(x));
        for k in 0..3 {
            assert_eq!(ga[k].to_bits(), gb[k].to_bits(), "gradient at {x:?}");
        }
    }
    let (mut va, mut vb) = (vec![0.0; pts.len()], vec![0.0; pts.len()]);
    a.values(&pts, &mut va);
    b.values(&pts, &mut vb);
    assert!(va.iter().zip(&vb).all(|(x, y)| x.to_bits() == y.to_bits()));
    assert_eq!(a.bounds(), b.bounds());
}

fn round_trip<K: StoredKernel>(field: &RbfField<K, 3>, name: &str) -> RbfAny<3> {
    let dir = TempDir::new(name);
    let path = dir.file("field.zsf");
    write_rbf_field(&path, field).unwrap();
    let back = match read_any_field::<3>(&path).unwrap() {
        AnyField::Rbf(r) => r,
        other => panic!("an RBF file read as a {} field", other.kind()),
    };
    assert_eq!(back.kernel_tag(), field.kernel().name());
    assert_eq!(back.num_centres(), field.num_centres());
    assert_eq!(back.weights(), field.weights());
    assert_eq!(
        back.polynomial_coefficients(),
        field.polynomial_coefficients()
    );
    assert_same(field, &back);
    let any = read_any_field::<3>(&path).unwrap();
    assert_eq!(any.kind(), "rbf");
    assert_same(field, &any);
    let meta = read_metadata(&path).unwrap();
    assert!(
        meta.iter()
            .any(|(k, v)| k == "kernel" && v == field.kernel().tag())
    );
    assert!(meta.iter().any(|(k, _)| k == "created-by"));
    back
}

#[test]
fn triharmonic_with_gradient_round_trips_bit_for_bit() {
    let fitted = RbfFit::new(Triharmonic).fit(&constraints(true)).unwrap();
    let back = round_trip(&fitted.field, "r3");
    assert!(matches!(back, RbfAny::R3(_)));
    // The Hessian (third kernel derivatives at gradient centres) is reproduced too.
    let x = [0.61, 0.42, 0.77];
    assert_eq!(back.hessian(&x), fitted.field.hessian(&x));
}

#[test]
fn biharmonic_round_trips_bit_for_bit() {
    let fitted = RbfFit::new(Biharmonic).fit(&constraints(false)).unwrap();
    assert!(matches!(round_trip(&fitted.field, "r"), RbfAny::R(_)));
}

#[test]
fn wendland_keeps_its_radius() {
    let fitted = RbfFit::new(Wendland::new(0.8).unwrap())
        .fit(&constraints(false))
        .unwrap();
    match round_trip(&fitted.field, "wendland") {
        RbfAny::Wendland(f) => assert_eq!(f.kernel().radius(), 0.8),
        other => panic!("read back as {}", other.kernel_tag()),
    }
}

#[test]
fn read_field_refuses_an_rbf_file() {
    let dir = TempDir::new("refuse");
    let path = dir.file("rbf.zsf");
    let fitted = RbfFit::new(Biharmonic).fit(&constraints(false)).unwrap();
    write_rbf_field(&path, &fitted.field).unwrap();
    let e = read_field::<3>(&path).unwrap_err();
    assert!(matches!(e, Error::Malformed { .. }), "{e}");
    assert!(
        e.to_string().contains("this file holds an RBF field"),
        "{e}"
    );
}

fn bspline() -> BSplineField<3> {
    let grid = Grid::cell_centered(Aabb::centered_cube(2.0).unwrap(), [3, 4, 5]).unwrap();
    let samples = (0..grid.len()).map(|i| (i as f64 * 0.37).sin()).collect();
    BSplineField::interpolate(grid, samples, Degree::Cubic).unwrap()
}

/// The version-1 bytes of `field` (cell-centred, half-sample boundary), as the old encoder
/// wrote them.
fn encode_v1(field: &BSplineField<3>) -> Vec<u8> {
    let mut out = b"ZSFIELD\0".to_vec();
    for v in [1u32, 3, 3, 0, 0] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for c in field.grid().counts() {
        out.extend_from_slice(&(c as u64).to_le_bytes());
    }
    let b = field.grid().bounds();
    for v in b
        .min()
        .iter()
        .chain(b.max().iter())
        .chain(field.coefficients())
    {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

#[test]
fn version_1_files_still_read() {
    let f = bspline();
    let dir = TempDir::new("v1");
    let path = dir.file("old.zsf");
    std::fs::write(&path, encode_v1(&f)).unwrap();
    let back = read_field::<3>(&path).unwrap();
    assert_eq!(back.coefficients(), f.coefficients());
    assert_eq!(back.grid(), f.grid());
    assert_eq!(back.degree(), f.degree());
    let any = read_any_field::<3>(&path).unwrap();
    assert_eq!(any.kind(), "bspline");
    assert_same(&f, &any);
    assert!(read_metadata(&path).unwrap().is_empty());
    // And the current writer's B-spline files read both ways.
    let new = dir.file("new.zsf");
    write_field(&new, &f).unwrap();
    assert_eq!(
        read_field::<3>(&new).unwrap().coefficients(),
        f.coefficients()
    );
    assert_eq!(
        u32::from_le_bytes(encode(&f)[8..12].try_into().unwrap()),
        VERSION
    );
}

fn rbf_bytes() -> Vec<u8> {
    let fitted = RbfFit::new(Triharmonic).fit(&constraints(true)).unwrap();
    encode_rbf(&fitted.field)
}

fn reseal(bytes: &mut [u8]) {
    let n = bytes.len();
    let crc = crc32fast::hash(&bytes[..n - 4]);
    bytes[n - 4..].copy_from_slice(&crc.to_le_bytes());
}

#[test]
fn damaged_files_give_specific_errors() {
    let p = Path::new("x.zsf");
    for bytes in [rbf_bytes(), encode(&bspline()), encode_v1(&bspline())] {
        // A flipped byte anywhere after the version.
        for at in [
            14,
            20,
            40,
            bytes.len() / 2,
            bytes.len() - 9,
            bytes.len() - 1,
        ] {
            let mut flipped = bytes.clone();
            flipped[at] ^= 0x10;
            let e = decode_any::<3>(&flipped, p).unwrap_err();
            assert!(
                matches!(
                    e,
                    FieldFileError::Checksum { .. }
                        | FieldFileError::Truncated { .. }
                        | FieldFileError::Malformed { .. }
                        | FieldFileError::WrongDimension { .. }
                ),
                "byte {at}: {e}"
            );
        }
        let mut flipped = bytes.clone();
        let mid = bytes.len() / 2;
        flipped[mid] ^= 1;
        let e = decode_any::<3>(&flipped, p).unwrap_err();
        assert!(matches!(e, FieldFileError::Checksum { .. }), "{e}");
        assert!(e.to_string().contains("checksum"), "{e}");
        // Truncations, in the header and in the body.
        for len in [0, 5, 10, 20, 40, bytes.len() / 2, bytes.len() - 1] {
            let e = decode_any::<3>(&bytes[..len], p).unwrap_err();
            assert!(matches!(e, FieldFileError::Truncated { .. }), "{len}: {e}");
        }
        // Trailing garbage.
        let mut extra = bytes.clone();
        extra.push(0);
        assert!(matches!(
            decode_any::<3>(&extra, p).unwrap_err(),
            FieldFileError::Malformed { .. }
        ));
        // Another dimension.
        assert!(matches!(
            decode_any::<2>(&bytes, p).unwrap_err(),
            FieldFileError::WrongDimension { found: 3, .. }
        ));
        // A newer version.
        let mut newer = bytes.clone();
        newer[8..12].copy_from_slice(&(VERSION + 1).to_le_bytes());
        reseal(&mut newer);
        let e = decode_any::<3>(&newer, p).unwrap_err();
        assert!(
            matches!(e, FieldFileError::NewerVersion { found, supported, .. } if found == VERSION + 1 && supported == VERSION),
            "{e}"
        );
        let e = read_field_error(&newer);
        assert!(e.contains("version 3"), "{e}");
    }
    // Not a field file at all.
    assert!(matches!(
        decode_any::<3>(b"ply\nformat ascii 1.0\n", p).unwrap_err(),
        FieldFileError::BadMagic { .. }
    ));
}

fn read_field_error(bytes: &[u8]) -> String {
    zeroset_bases::field_file::decode::<3>(bytes, Path::new("x.zsf"))
        .unwrap_err()
        .to_string()
}

#[test]
fn unknown_kind_and_kernel_are_named() {
    let p = Path::new("x.zsf");
    let mut bytes = rbf_bytes();
    bytes[16..24].copy_from_slice(b"nurbs\0\0\0");
    reseal(&mut bytes);
    let e = decode_any::<3>(&bytes, p).unwrap_err();
    assert!(
        matches!(&e, FieldFileError::UnknownKind { kind, .. } if kind == "nurbs"),
        "{e}"
    );
    assert!(read_field_error(&bytes).contains("unknown field kind"));

    // The kernel tag `r3` follows the header, the metadata and its own 4-byte length.
    let mut bytes = rbf_bytes();
    let meta = u32::from_le_bytes(bytes[24..28].try_into().unwrap()) as usize;
    let at = 36 + meta + 4;
    assert_eq!(&bytes[at..at + 2], b"r3");
    bytes[at..at + 2].copy_from_slice(b"r9");
    reseal(&mut bytes);
    let e = decode_any::<3>(&bytes, p).unwrap_err();
    assert!(
        matches!(&e, FieldFileError::UnknownKernel { kernel, .. } if kernel == "r9"),
        "{e}"
    );
    // Converted into the crate-wide error, the specific message survives.
    let e: Error = e.into();
    assert!(e.to_string().contains("unknown RBF kernel"), "{e}");
}
