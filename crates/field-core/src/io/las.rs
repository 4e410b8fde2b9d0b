//! LAS, the ASPRS LiDAR format (versions 1.0–1.4, every point format), read with the [`las`]
//! crate.
//!
//! LAZ (LAS compressed with LASzip) is refused with a message saying how to decompress it
//! (`laszip`, `pdal translate`): fuzzing the `laz` crate's decoder found crafted files that
//! make it panic or allocate without bound before any point is read, and zeroset neither
//! panics nor aborts on a bad file.
//!
//! - Read: each point's `x y z`, the stored integers times the header's scale plus its offset
//!   (so georeferenced coordinates keep their full precision in `f64`). LAS has no standard
//!   normals: the cloud has none (`zeroset normals` or `zeroset reconstruct` estimate them,
//!   with `--viewpoint` above an airborne scan). Intensity, classification, returns, colour
//!   and the rest are skipped; so are points flagged withheld (the format's "deleted").
//! - Before the crate reads the file, the header's point count times the record length is
//!   checked against the bytes after the header ([`Error::Truncated`] otherwise), and every
//!   extended VLR's length (LAS 1.4) against the file's size: the crate sizes buffers by them.
//!   The points are then read in blocks of [`BLOCK`]. Errors name the file.

use std::path::Path;

use super::{FiniteCheck, POSITION_FIELDS, RawPoints, io_error};
use crate::error::{Error, Result};
use crate::limits;

/// Points read at a time.
pub const BLOCK: u64 = 1 << 16;

/// Reads a LAS or LAZ file; see the [module docs](self).
pub(super) fn read(path: &Path, check: &FiniteCheck<'_>) -> Result<RawPoints> {
    let (file, len) = super::open_nonempty(path)?;
    check_raw_header(path, file, len)?;
    let mut reader = las::Reader::from_path(path).map_err(|e| las_error(path, e))?;
    let header = reader.header();
    let announced = header.number_of_points();
    let what = format!("the points of {}", path.display());
    let mut positions = Vec::new();
    let mut block = las::PointDataBuilder::new().for_header(header).build();
    let mut read = 0u64;
    while read < announced {
        let n = reader.fill_points(BLOCK, &mut block).map_err(|e| match e {
            las::Error::Io(ref io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                truncated(path, announced, read)
            }
            e => las_error(path, e),
        })?;
        if n == 0 {
            break;
        }
        limits::grow(&mut positions, n as usize, &what)?;
        for (i, point) in block.points().enumerate() {
            let point = point.map_err(|e| las_error(path, e))?;
            if point.is_withheld {
                continue;
            }
            let p = [point.x, point.y, point.z];
            check.check(
                usize::try_from(read).unwrap_or(usize::MAX) + i,
                None,
                &POSITION_FIELDS,
                &p,
            )?;
            positions.push(p);
        }
        read += n;
    }
    Ok((positions, None))
}

/// Checks what the `las` crate would size allocations by against the file's `len` bytes,
/// before it reads them: the point count times the record length (after the header's "offset
/// to point data") and each extended VLR's length (LAS 1.4). The fields are at the same bytes
/// in every version (ASPRS LAS 1.4 R15, table 3); a file too short for them is left to the
/// crate, which reads the header with bounded reads.
fn check_raw_header(path: &Path, mut file: std::fs::File, len: u64) -> Result<()> {
    use std::io::{Read, Seek, SeekFrom};
    let mut head = [0u8; 375];
    let have = usize::try_from(len).map_or(head.len(), |n| n.min(head.len()));
    if have < 227 {
        return Ok(());
    }
    file.read_exact(&mut head[..have]).map_err(io_error(path))?;
    if &head[..4] != b"LASF" {
        return Err(super::malformed(
            path,
            None,
            "not a LAS file: it does not start with the signature LASF",
        ));
    }
    // Bit 7 of the point format marks LASzip compression (its points are smaller than the
    // record length says).
    if head[104] & 0x80 != 0 {
        return Err(laz_refused(path));
    }
    let u16_at = |at: usize| u64::from(u16::from_le_bytes([head[at], head[at + 1]]));
    let u32_at = |at: usize| {
        u64::from(u32::from_le_bytes([
            head[at],
            head[at + 1],
            head[at + 2],
            head[at + 3],
        ]))
    };
    let u64_at = |at: usize| u64::from_le_bytes(head[at..at + 8].try_into().unwrap_or([0; 8]));
    let minor = head[25];
    let start = u32_at(96);
    let record = u16_at(105).max(1);
    let mut count = u32_at(107);
    let extended = minor >= 4 && have >= 375;
    if extended {
        count = count.max(u64_at(247));
    }
    let room = len.saturating_sub(start);
    if count.checked_mul(record).is_none_or(|need| need > room) {
        return Err(truncated(path, count, room / record));
    }
    if extended {
        let (mut at, evlrs) = (u64_at(235), u32_at(243));
        for i in 0..evlrs {
            let mut evlr = [0u8; 60];
            let fits = at.checked_add(60).is_some_and(|end| end <= len);
            if !fits {
                return Err(super::malformed(
                    path,
                    None,
                    format!(
                        "extended VLR {i} of {evlrs} starts at byte {at}, past the file's end ({len} bytes)"
                    ),
                ));
            }
            file.seek(SeekFrom::Start(at))
                .and_then(|_| file.read_exact(&mut evlr))
                .map_err(io_error(path))?;
            let length = u64::from_le_bytes(evlr[20..28].try_into().unwrap_or([0; 8]));
            let left = len - at - 60;
            if length > left {
                return Err(super::malformed(
                    path,
                    None,
                    format!(
                        "extended VLR {i} claims {length} bytes; the file holds {left} after its header"
                    ),
                ));
            }
            at += 60 + length;
        }
    }
    Ok(())
}

/// [`Error::Truncated`] for `expected` points of which the file holds `got`.
fn truncated(path: &Path, expected: u64, got: u64) -> Error {
    Error::Truncated {
        path: path.to_owned(),
        element: "point".to_owned(),
        expected: usize::try_from(expected).unwrap_or(usize::MAX),
        got: usize::try_from(got).unwrap_or(usize::MAX),
    }
}

/// The error for a LAZ file: what it is, and how to decompress it.
fn laz_refused(path: &Path) -> Error {
    super::malformed(
        path,
        None,
        "a LAZ file (LAS compressed with LASzip), which zeroset does not read: decompress it \
         first (`laszip -i scan.laz -o scan.las` or `pdal translate scan.laz scan.las`)",
    )
}

/// The reader's error for a `las` error in `path`.
fn las_error(path: &Path, e: las::Error) -> Error {
    match e {
        las::Error::Io(source) => io_error(path)(source),
        las::Error::LaszipNotEnabled => laz_refused(path),
        e => super::malformed(path, None, format!("not a readable LAS/LAZ file: {e}")),
    }
}
