//! Point clouds from PLY: the `vertex` element's `x y z` and, when all three are there,
//! `nx ny nz`, read with the shared layer ([`super`]); and the binary PLY writer.

use std::io::Write;
use std::path::Path;

use super::{Header, PlyError, Record, Records};
use crate::cloud::PointCloud3;
use crate::error::{Error, Result};
use crate::geometry::Point3;
use crate::io::{
    FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, io_error, malformed, write_atomic,
};
use crate::limits;

/// Reads the `vertex` element of a PLY file; records after it (faces) are not read.
pub(in crate::io) fn read(path: &Path, check: &FiniteCheck<'_>) -> Result<RawPoints> {
    let bytes = read_whole(path)?;
    if bytes.is_empty() {
        return Err(malformed(path, None, "the file is empty (0 bytes)"));
    }
    let error = |e| point_error(path, e);
    let header = Header::parse(&bytes).map_err(error)?;
    let Some(vertex) = header.elements.iter().position(|e| e.name == "vertex") else {
        return Err(malformed(path, None, "PLY file has no 'vertex' element"));
    };
    let (xyz, normal_slots) = header.elements[vertex]
        .position_normal_slots()
        .map_err(error)?;
    let mut records = Records::new(&header, &bytes);
    let mut record = Record::default();
    for element in &header.elements[..vertex] {
        for r in 0..element.count {
            records.read(element, r, &mut record).map_err(error)?;
        }
    }
    let element = &header.elements[vertex];
    // Never from the header's count alone (`records_that_fit`).
    let per_point = if normal_slots.is_some() { 48 } else { 24 };
    let capacity =
        records.capacity(element, per_point, &format!("points of {}", path.display()))?;
    let mut positions = Vec::with_capacity(capacity);
    let mut normals = normal_slots.map(|_| Vec::with_capacity(capacity));
    let get = |record: &Record, slots: [usize; 3]| slots.map(|s| record.scalar(s));
    // Errors name the normal's components as the file does (`nx` or PCL's `normal_x`).
    let normal_names = normal_slots.map_or(NORMAL_FIELDS, |s| {
        super::super::normal_field_names(&element.properties[s[0]].name)
    });
    for r in 0..element.count {
        let line = records.read(element, r, &mut record).map_err(error)?.line();
        let p: Point3 = get(&record, xyz);
        check.check(r, line, &POSITION_FIELDS, &p)?;
        positions.push(p);
        if let (Some(slots), Some(normals)) = (normal_slots, normals.as_mut()) {
            let n: Point3 = get(&record, slots);
            check.check(r, line, &normal_names, &n)?;
            normals.push(n);
        }
    }
    Ok((positions, normals))
}

/// The bytes of the file at `path`, after checking that they fit in the memory available
/// ([`limits`]).
///
/// # Errors
/// [`Error::Io`] naming `path`; [`Error::Memory`] for a file larger than the memory available.
pub fn read_whole(path: &Path) -> Result<Vec<u8>> {
    let len = std::fs::metadata(path).map_err(io_error(path))?.len();
    limits::check_bytes(&format!("reading {}", path.display()), len)?;
    std::fs::read(path).map_err(io_error(path))
}

/// The point-cloud reader's error for a PLY error in `path`.
fn point_error(path: &Path, e: PlyError) -> Error {
    match e {
        PlyError::NotPly => malformed(path, Some(1), e.to_string()),
        PlyError::Syntax { place, detail } | PlyError::Unsupported { place, detail } => match place
        {
            super::Place::Header(line) => {
                malformed(path, line, format!("not a valid PLY header: {detail}"))
            }
            super::Place::Record {
                ref element,
                record,
                line,
                byte,
            } => {
                let at = byte.map(|b| format!(" (byte {b})")).unwrap_or_default();
                malformed(path, line, format!("PLY {element} {record}{at}: {detail}"))
            }
        },
        PlyError::MissingProperty { property, .. } => Error::MissingProperty {
            path: path.to_owned(),
            property,
        },
        PlyError::Truncated {
            element,
            record,
            expected,
        } => Error::Truncated {
            path: path.to_owned(),
            element,
            expected,
            got: record,
        },
    }
}

/// Writes a cloud as binary little-endian PLY with `double` properties `x y z` (and
/// `nx ny nz` if the cloud has normals), atomically ([`write_atomic`]).
///
/// Values are written as they are, non-finite ones included; an empty cloud gives a valid
/// file with 0 vertices (which [`read_point_cloud`](crate::io::read_point_cloud) rejects).
///
/// # Errors
/// [`Error::Io`] naming `path`.
pub fn write_ply(path: impl AsRef<Path>, cloud: &PointCloud3) -> Result<()> {
    write_atomic(path, |w| {
        let normals = cloud.normals();
        writeln!(w, "ply")?;
        writeln!(w, "format binary_little_endian 1.0")?;
        writeln!(
            w,
            "comment written by zeroset {}",
            env!("CARGO_PKG_VERSION")
        )?;
        writeln!(w, "element vertex {}", cloud.len())?;
        for name in ["x", "y", "z"] {
            writeln!(w, "property double {name}")?;
        }
        if normals.is_some() {
            for name in ["nx", "ny", "nz"] {
                writeln!(w, "property double {name}")?;
            }
        }
        writeln!(w, "end_header")?;
        let write_point = |w: &mut dyn Write, p: &Point3| -> std::io::Result<()> {
            for v in p {
                w.write_all(&v.to_le_bytes())?;
            }
            Ok(())
        };
        for (i, p) in cloud.positions().iter().enumerate() {
            write_point(w, p)?;
            if let Some(n) = normals {
                write_point(w, &n[i])?;
            }
        }
        Ok(())
    })
}
