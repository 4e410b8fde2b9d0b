//! The zeroset field file (`.zsf`): a B-spline field, versioned and checksummed.
//!
//! A restored or fitted field is saved so that the next command (restore again, mesh, …) can
//! load it bit for bit. Layout, all little-endian:
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `ZSFIELD\0` |
//! | 4 | format version (`u32`, currently 1) |
//! | 4 | dimension `D` (2 or 3) |
//! | 4 | degree (2 or 3) |
//! | 4 | boundary (0 = half-sample mirror, 1 = whole-sample mirror) |
//! | 4 | centering (0 = cell, 1 = vertex) |
//! | 8·D | samples per axis (`u64`) |
//! | 16·D | bounding box min then max (`f64`) |
//! | 8·Π counts | B-spline coefficients (`f64`, last axis fastest) |
//! | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! Writes are atomic (temporary file + rename). Reads check the magic, version, sizes,
//! checksum and values and say what is wrong.
//!
//! ```
//! use zeroset_bases::bspline::{BSplineField, Degree};
//! use zeroset_bases::field_file::{read_field, write_field};
//! use zeroset_field_core::geometry::Aabb;
//! use zeroset_field_core::grid::Grid;
//!
//! let grid = Grid::cell_centered(Aabb::centered_cube(1.0)?, [4, 5, 6])?;
//! let samples = (0..grid.len()).map(|i| i as f64 * 0.1).collect();
//! let field = BSplineField::interpolate(grid, samples, Degree::Quadratic)?;
//! let dir = std::env::temp_dir().join(format!("zsf-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("field.zsf");
//! write_field(&path, &field)?;
//! let back = read_field::<3>(&path)?;
//! assert_eq!(back.coefficients(), field.coefficients());
//! # std::fs::remove_dir_all(&dir).unwrap();
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```

use std::path::Path;

use zeroset_field_core::Error;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::{Centering, Grid};
use zeroset_field_core::io::write_atomic;

use crate::bspline::{BSplineField, Boundary, Degree};

/// The first 8 bytes of every field file.
pub const MAGIC: &[u8; 8] = b"ZSFIELD\0";
/// The format version this build writes and reads.
pub const VERSION: u32 = 1;

/// Whether `path` starts with the field-file magic (unreadable files are not field files).
pub fn is_field_file(path: impl AsRef<Path>) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .map(|()| &head == MAGIC)
        .unwrap_or(false)
}

/// Writes `field` to `path` atomically.
///
/// # Errors
/// [`Error::Io`] naming `path`.
pub fn write_field<const D: usize>(
    path: impl AsRef<Path>,
    field: &BSplineField<D>,
) -> Result<(), Error> {
    let bytes = encode(field);
    write_atomic(path, |w| w.write_all(&bytes))
}

/// The bytes of the field file of `field`.
pub fn encode<const D: usize>(field: &BSplineField<D>) -> Vec<u8> {
    let grid = field.grid();
    let coefficients = field.coefficients();
    let mut out = Vec::with_capacity(48 + 24 * D + 8 * coefficients.len());
    out.extend_from_slice(MAGIC);
    let header = [
        VERSION,
        D as u32,
        match field.degree() {
            Degree::Quadratic => 2,
            Degree::Cubic => 3,
        },
        match field.boundary() {
            Boundary::HalfSample => 0,
            Boundary::WholeSample => 1,
        },
        match grid.centering() {
            Centering::Cell => 0,
            Centering::Vertex => 1,
        },
    ];
    header
        .iter()
        .for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
    grid.counts()
        .iter()
        .for_each(|&c| out.extend_from_slice(&(c as u64).to_le_bytes()));
    let bounds = grid.bounds();
    bounds
        .min()
        .iter()
        .chain(bounds.max().iter())
        .chain(coefficients)
        .for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Reads a `D`-dimensional field file.
///
/// # Errors
/// [`Error::Io`] if the file cannot be read; [`Error::Malformed`] for a wrong magic, an
/// unknown version or code, a dimension other than `D`, a checksum mismatch or a non-finite
/// value; [`Error::Truncated`] for a file shorter than its header announces.
pub fn read_field<const D: usize>(path: impl AsRef<Path>) -> Result<BSplineField<D>, Error> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    decode(&bytes, path)
}

/// Parses the bytes of a field file; `path` is only used in error messages.
///
/// # Errors
/// As [`read_field`].
pub fn decode<const D: usize>(bytes: &[u8], path: &Path) -> Result<BSplineField<D>, Error> {
    let malformed = |reason: String| Error::Malformed {
        path: path.to_owned(),
        line: None,
        reason,
    };
    let mut cursor = Cursor { bytes, at: 0 };
    let truncated = |expected: usize, got: usize| Error::Truncated {
        path: path.to_owned(),
        element: "byte".into(),
        expected,
        got,
    };
    let magic = cursor.take(8).ok_or_else(|| truncated(8, bytes.len()))?;
    if magic != MAGIC {
        return Err(malformed("not a zeroset field file (bad magic)".into()));
    }
    let mut header = [0u32; 5];
    for h in &mut header {
        *h = cursor.u32().ok_or_else(|| truncated(28, bytes.len()))?;
    }
    let [version, dim, degree, boundary, centering] = header;
    if version != VERSION {
        return Err(malformed(format!(
            "field file version {version}; this build reads version {VERSION}"
        )));
    }
    if dim as usize != D {
        return Err(malformed(format!("a {dim}-D field, expected {D}-D")));
    }
    let degree = match degree {
        2 => Degree::Quadratic,
        3 => Degree::Cubic,
        d => return Err(malformed(format!("unknown B-spline degree {d}"))),
    };
    let boundary = match boundary {
        0 => Boundary::HalfSample,
        1 => Boundary::WholeSample,
        b => return Err(malformed(format!("unknown boundary code {b}"))),
    };
    let centering = match centering {
        0 => Centering::Cell,
        1 => Centering::Vertex,
        c => return Err(malformed(format!("unknown centering code {c}"))),
    };
    let header_len = 28 + 24 * D;
    let mut counts = [0usize; D];
    for c in &mut counts {
        let v = cursor
            .u64()
            .ok_or_else(|| truncated(header_len, bytes.len()))?;
        *c = usize::try_from(v).map_err(|_| malformed(format!("axis of {v} samples")))?;
    }
    let expected = counts
        .iter()
        .try_fold(1usize, |acc, &c| acc.checked_mul(c))
        .filter(|&n| n > 0)
        .and_then(|n| n.checked_mul(8))
        .and_then(|n| n.checked_add(header_len + 4))
        .ok_or_else(|| malformed(format!("impossible grid of {counts:?} samples")))?;
    let total = (expected - header_len - 4) / 8;
    if bytes.len() != expected {
        return Err(if bytes.len() < expected {
            truncated(expected, bytes.len())
        } else {
            malformed(format!(
                "{} bytes where the header announces {expected}",
                bytes.len()
            ))
        });
    }
    let stored = u32::from_le_bytes(bytes[expected - 4..].try_into().expect("4 bytes"));
    let actual = crc32fast::hash(&bytes[..expected - 4]);
    if stored != actual {
        return Err(malformed(format!(
            "checksum mismatch (stored {stored:08x}, computed {actual:08x}): the file is corrupt"
        )));
    }
    let mut min = [0.0; D];
    let mut max = [0.0; D];
    for v in min.iter_mut().chain(max.iter_mut()) {
        *v = cursor.f64().expect("length checked");
    }
    let coefficients: Vec<f64> = (0..total)
        .map(|_| cursor.f64().expect("length checked"))
        .collect();
    let grid = Grid::new(Aabb::new(min, max)?, counts, centering)?;
    BSplineField::from_coefficients(grid, coefficients, degree, boundary)
}

struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at + n)?;
        self.at += n;
        Some(s)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> Option<u64> {
        self.take(8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }
    fn f64(&mut self) -> Option<f64> {
        self.take(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field() -> BSplineField<3> {
        let grid = Grid::cell_centered(Aabb::centered_cube(2.0).unwrap(), [3, 4, 5]).unwrap();
        let samples = (0..grid.len()).map(|i| (i as f64 * 0.37).sin()).collect();
        BSplineField::interpolate(grid, samples, Degree::Quadratic).unwrap()
    }

    #[test]
    fn round_trips_bit_for_bit() {
        let f = field();
        let bytes = encode(&f);
        let back: BSplineField<3> = decode(&bytes, Path::new("mem")).unwrap();
        assert_eq!(back.coefficients(), f.coefficients());
        assert_eq!(back.grid(), f.grid());
        assert_eq!(back.degree(), f.degree());
    }

    #[test]
    fn corruption_truncation_and_wrong_kind_are_reported() {
        let bytes = encode(&field());
        let p = Path::new("x.zsf");
        let mut flipped = bytes.clone();
        flipped[100] ^= 1;
        let e = decode::<3>(&flipped, p).unwrap_err().to_string();
        assert!(e.contains("checksum"), "{e}");
        let e = decode::<3>(&bytes[..bytes.len() - 9], p).unwrap_err();
        assert!(matches!(e, Error::Truncated { .. }), "{e}");
        let e = decode::<3>(&bytes[..5], p).unwrap_err();
        assert!(matches!(e, Error::Truncated { .. }), "{e}");
        let e = decode::<2>(&bytes, p).unwrap_err().to_string();
        assert!(e.contains("3-D"), "{e}");
        let e = decode::<3>(b"ply\nformat ascii 1.0\n", p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("magic"), "{e}");
        let mut extra = bytes.clone();
        extra.push(0);
        assert!(decode::<3>(&extra, p).is_err());
    }
}
