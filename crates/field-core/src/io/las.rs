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
//! - The points are read in blocks of [`BLOCK`], so memory follows the points the file holds,
//!   never the header's count alone; a file that ends before the points it announces is
//!   [`Error::Truncated`]. Errors name the file.

use std::path::Path;

use super::{FiniteCheck, POSITION_FIELDS, RawPoints, io_error};
use crate::error::{Error, Result};
use crate::limits;

/// Points read at a time.
pub const BLOCK: u64 = 1 << 16;

/// Reads a LAS or LAZ file; see the [module docs](self).
pub(super) fn read(path: &Path, check: &FiniteCheck<'_>) -> Result<RawPoints> {
    let (_, len) = super::open_nonempty(path)?;
    let mut reader = las::Reader::from_path(path).map_err(|e| las_error(path, e))?;
    let header = reader.header();
    let announced = header.number_of_points();
    let record = u64::from(header.point_format().len()).max(1);
    // The bytes after the header bound the count (the header's "offset to point data", a
    // u32 at byte 96 in every LAS version, says where the points start).
    let start = point_data_offset(path)?;
    let room = len.saturating_sub(start);
    if announced.saturating_mul(record) > room {
        return Err(Error::Truncated {
            path: path.to_owned(),
            element: "point".to_owned(),
            expected: usize::try_from(announced).unwrap_or(usize::MAX),
            got: usize::try_from(room / record).unwrap_or(usize::MAX),
        });
    }
    let what = format!("the points of {}", path.display());
    let mut positions = Vec::new();
    let mut block = las::PointDataBuilder::new().for_header(header).build();
    let mut read = 0u64;
    while read < announced {
        let n = reader.fill_points(BLOCK, &mut block).map_err(|e| match e {
            las::Error::Io(ref io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                Error::Truncated {
                    path: path.to_owned(),
                    element: "point".to_owned(),
                    expected: usize::try_from(announced).unwrap_or(usize::MAX),
                    got: usize::try_from(read).unwrap_or(usize::MAX),
                }
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

/// The byte where the point records start: the header's "offset to point data".
fn point_data_offset(path: &Path) -> Result<u64> {
    use std::io::Read;
    let mut head = [0u8; 100];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .map_err(io_error(path))?;
    Ok(u64::from(u32::from_le_bytes([
        head[96], head[97], head[98], head[99],
    ])))
}

/// The reader's error for a `las` error in `path`.
fn las_error(path: &Path, e: las::Error) -> Error {
    match e {
        las::Error::Io(source) => io_error(path)(source),
        las::Error::LaszipNotEnabled => super::malformed(
            path,
            None,
            "a LAZ file (LAS compressed with LASzip), which zeroset does not read: decompress \
             it first (`laszip -i scan.laz -o scan.las` or `pdal translate scan.laz scan.las`)",
        ),
        e => super::malformed(path, None, format!("not a readable LAS/LAZ file: {e}")),
    }
}
