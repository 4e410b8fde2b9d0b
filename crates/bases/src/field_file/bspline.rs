//! The `bspline` kind: its encoder, its body decoder and the version-1 reader.
//!
//! The `bspline` payload is the version-1 body:
//!
//! | bytes | content |
//! |---|---|
//! | 4 | degree (2 or 3) |
//! | 4 | boundary (0 = half-sample mirror, 1 = whole-sample mirror) |
//! | 4 | centering (0 = cell, 1 = vertex) |
//! | 8·D | samples per axis (`u64`) |
//! | 16·D | bounding box min then max (`f64`) |
//! | 8·Π counts | B-spline coefficients (`f64`, last axis fastest) |

use std::path::Path;

use zeroset_field_core::Error;
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::grid::{Centering, Grid};

use super::{Cursor, FieldFileError, KIND_BSPLINE, check_crc, counted, frame, put_f64s};
use crate::bspline::{BSplineField, Boundary, Degree};

/// The bytes of the field file of the B-spline `field` (version [`VERSION`](super::VERSION)).
pub fn encode<const D: usize>(field: &BSplineField<D>) -> Vec<u8> {
    let grid = field.grid();
    let coefficients = field.coefficients();
    let mut payload = Vec::with_capacity(12 + 24 * D + 8 * coefficients.len());
    let degree = match field.degree() {
        Degree::Quadratic => 2u32,
        Degree::Cubic => 3,
    };
    let codes = [
        degree,
        match field.boundary() {
            Boundary::HalfSample => 0,
            Boundary::WholeSample => 1,
        },
        match grid.centering() {
            Centering::Cell => 0,
            Centering::Vertex => 1,
        },
    ];
    codes
        .iter()
        .for_each(|v| payload.extend_from_slice(&v.to_le_bytes()));
    grid.counts()
        .iter()
        .for_each(|&c| payload.extend_from_slice(&(c as u64).to_le_bytes()));
    let bounds = grid.bounds();
    put_f64s(
        &mut payload,
        bounds
            .min()
            .iter()
            .chain(bounds.max().iter())
            .chain(coefficients),
    );
    let samples = grid
        .counts()
        .iter()
        .map(|c| c.to_string())
        .collect::<Vec<_>>()
        .join("x");
    frame(
        D,
        KIND_BSPLINE,
        &[("degree", degree.to_string()), ("samples", samples)],
        &payload,
    )
}

/// A version-1 file: magic, version, dimension, the B-spline body, CRC.
pub(super) fn decode_v1<const D: usize>(
    bytes: &[u8],
    path: &Path,
) -> Result<BSplineField<D>, FieldFileError> {
    let malformed = |reason: String| FieldFileError::Malformed {
        path: path.to_owned(),
        reason,
    };
    let truncated = |expected: usize| FieldFileError::Truncated {
        path: path.to_owned(),
        expected,
        got: bytes.len(),
    };
    let header_len = 28 + 8 * D;
    let mut cursor = Cursor { bytes, at: 12 };
    let dim = cursor.u32().ok_or_else(|| truncated(28))?;
    if dim as usize != D {
        return Err(FieldFileError::WrongDimension {
            path: path.to_owned(),
            found: dim,
            expected: D,
        });
    }
    cursor.take(12).ok_or_else(|| truncated(28))?;
    let mut counts = [0usize; D];
    for c in &mut counts {
        let v = cursor.u64().ok_or_else(|| truncated(header_len))?;
        *c = usize::try_from(v).map_err(|_| malformed(format!("axis of {v} samples")))?;
    }
    let expected = counts
        .iter()
        .try_fold(1usize, |acc, &c| acc.checked_mul(c))
        .filter(|&n| n > 0)
        .and_then(|n| n.checked_mul(8))
        .and_then(|n| n.checked_add(header_len + 16 * D + 4))
        .ok_or_else(|| malformed(format!("impossible grid of {counts:?} samples")))?;
    if bytes.len() != expected {
        return Err(if bytes.len() < expected {
            truncated(expected)
        } else {
            malformed(format!(
                "{} bytes where the header announces {expected}",
                bytes.len()
            ))
        });
    }
    check_crc(bytes, path)?;
    let mut body = Cursor {
        bytes: &bytes[..expected - 4],
        at: 16,
    };
    bspline_body(&mut body, path, || malformed("inconsistent sizes".into()))
}

/// The B-spline body (degree … coefficients); `short` is the error for running out.
pub(super) fn bspline_body<const D: usize>(
    c: &mut Cursor<'_>,
    path: &Path,
    short: impl Fn() -> FieldFileError,
) -> Result<BSplineField<D>, FieldFileError> {
    let malformed = |reason: String| FieldFileError::Malformed {
        path: path.to_owned(),
        reason,
    };
    let degree = match c.u32().ok_or_else(&short)? {
        2 => Degree::Quadratic,
        3 => Degree::Cubic,
        d => return Err(malformed(format!("unknown B-spline degree {d}"))),
    };
    let boundary = match c.u32().ok_or_else(&short)? {
        0 => Boundary::HalfSample,
        1 => Boundary::WholeSample,
        b => return Err(malformed(format!("unknown boundary code {b}"))),
    };
    let centering = match c.u32().ok_or_else(&short)? {
        0 => Centering::Cell,
        1 => Centering::Vertex,
        k => return Err(malformed(format!("unknown centering code {k}"))),
    };
    let mut counts = [0usize; D];
    for n in &mut counts {
        let v = c.u64().ok_or_else(&short)?;
        *n = usize::try_from(v).map_err(|_| malformed(format!("axis of {v} samples")))?;
    }
    let total = counts
        .iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .filter(|&n| n > 0)
        .ok_or_else(|| malformed(format!("impossible grid of {counts:?} samples")))?;
    let min: Point<D> = c.point().ok_or_else(&short)?;
    let max: Point<D> = c.point().ok_or_else(&short)?;
    let what = format!("B-spline coefficients of the grid {counts:?}");
    let total = counted(c, path, &what, total as u64, 8, 8)?;
    let coefficients = c.f64s(total).ok_or_else(&short)?;
    let invalid = |source: Error| FieldFileError::Invalid {
        path: path.to_owned(),
        source,
    };
    let grid =
        Grid::new(Aabb::new(min, max).map_err(invalid)?, counts, centering).map_err(invalid)?;
    BSplineField::from_coefficients(grid, coefficients, degree, boundary).map_err(invalid)
}
