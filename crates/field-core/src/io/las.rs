//! LAS, the ASPRS LiDAR format (versions 1.0–1.4, every point format), and LAZ (LAS compressed
//! with LASzip), read with the [`las`] crate (LAZ by the [`laz`](https://docs.rs/laz) crate it
//! uses).
//!
//! - Read: each point's `x y z`, the stored integers times the header's scale plus its offset
//!   (so georeferenced coordinates keep their full precision in `f64`). Intensity,
//!   classification, returns, colour and the rest are skipped; so are points flagged withheld
//!   (the format's "deleted").
//! - Normals: LAS has no standard field for them, but writers put them in each record's
//!   "extra bytes", described by the Extra Bytes VLR (LAS 1.4 R15 §2.6.3: user `LASF_Spec`,
//!   record 4, 192 bytes a field giving its name, type, and optional scale and offset). Three
//!   fields named `NormalX NormalY NormalZ` (PDAL's `filters.normal`, written by
//!   `writers.las` with `extra_dims`) or `nx ny nz` (any case; `_`, `-` and spaces ignored:
//!   `normal_x`), of any numeric type, are read as the normals, scaled and offset as their
//!   descriptions say; so is one deprecated three-component field named `normal` or `normals`.
//!   Without them the cloud has none (`zeroset normals` or `zeroset reconstruct` estimate
//!   them, with `--viewpoint` above an airborne scan); so it has where the description places
//!   them past the record's extra bytes, or names a set in part (`NormalX` without `NormalZ`):
//!   the positions are still read. PDAL turns its normals up (`+z`, its `always_up` default):
//!   right for airborne terrain, inward under overhangs of an object or a terrestrial scan —
//!   `zeroset normals scan.las --viewpoint X,Y,Z` estimates them again from the positions.
//! - Before the crates read the file, what they would size buffers by is checked against the
//!   file ([`Error::Truncated`] or [`Error::Malformed`] otherwise): for LAS the header's point
//!   count times the record length against the bytes after the header; every extended VLR's
//!   length (LAS 1.4) against the file's size; for LAZ the LASzip VLR (at least one item,
//!   item sizes adding up to the record length, at most [`MAX_LAZ_RECORD`] bytes) and the
//!   chunk table's count of chunks against the compressed bytes. Fuzzing the `laz` decoder
//!   without these checks found crafted files that made it panic or allocate without bound
//!   (a chunk table of 2³² entries: 64 GB) before any point was read. A panic the checks do
//!   not foresee is caught and reported as the file's error.
//! - The points are read in blocks of at most [`BLOCK`] (fewer for long records: a block's
//!   bytes stay under 16 MiB). Errors name the file.

use std::path::Path;

use super::{FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, io_error};
use crate::error::{Error, Result};
use crate::limits;

/// Points read at a time (at most).
pub const BLOCK: u64 = 1 << 16;

/// The longest LAZ point record read, in bytes: the standard formats take 20–67 bytes, the rest
/// is "extra bytes", for each of which the decoder keeps its own models.
pub const MAX_LAZ_RECORD: u64 = 512;

/// Reads a LAS or LAZ file (its normals too with `with_normals`, if it has them); see the
/// [module docs](self).
pub(super) fn read(path: &Path, check: &FiniteCheck<'_>, with_normals: bool) -> Result<RawPoints> {
    let (file, len) = super::open_nonempty(path)?;
    check_raw_header(path, file, len)?;
    // The checks above rule out what fuzzing found; a panic in the decoders beyond them is the
    // file's error, not the caller's crash.
    super::guard_decoder(path, "LAS/LAZ", || read_points(path, check, with_normals))
}

/// The points of a file that passed [`check_raw_header`].
fn read_points(path: &Path, check: &FiniteCheck<'_>, with_normals: bool) -> Result<RawPoints> {
    let mut reader = las::Reader::from_path(path).map_err(|e| las_error(path, e))?;
    let header = reader.header();
    let announced = header.number_of_points();
    let what = format!("the points of {}", path.display());
    let extra = usize::from(header.point_format().extra_bytes);
    let normals_at = if with_normals {
        ExtraNormals::of(header.all_vlrs(), extra)
    } else {
        None
    };
    let mut normals = normals_at.as_ref().map(|_| Vec::new());
    let mut positions = Vec::new();
    let mut block = las::PointDataBuilder::new().for_header(header).build();
    let mut read = 0u64;
    let record = u64::from(header.point_format().len()).max(1);
    let per_block = ((16u64 << 20) / record).clamp(1, BLOCK);
    while read < announced {
        let n = reader
            .fill_points(per_block, &mut block)
            .map_err(|e| match e {
                las::Error::Io(ref io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                    truncated(path, announced, read)
                }
                e => las_error(path, e),
            })?;
        if n == 0 {
            break;
        }
        limits::grow(&mut positions, n as usize, &what)?;
        if let Some(normals) = &mut normals {
            limits::grow(normals, n as usize, &what)?;
        }
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
            if let (Some(at), Some(normals)) = (&normals_at, &mut normals) {
                let n = at.read(&point.extra_bytes);
                let index = usize::try_from(read).unwrap_or(usize::MAX) + i;
                check.check(index, None, &NORMAL_FIELDS, &n)?;
                normals.push(n);
            }
        }
        read += n;
    }
    Ok((positions, normals))
}

/// Where the normals are in a record's extra bytes, from the Extra Bytes VLR.
#[derive(Debug)]
struct ExtraNormals([ExtraValue; 3]);

/// One number in a record's extra bytes: `raw · scale + offset`.
#[derive(Debug, Clone, Copy)]
struct ExtraValue {
    /// Its first byte among the extra bytes.
    at: usize,
    /// Its type, 1–10 (`u8 i8 u16 i16 u32 i32 u64 i64 f32 f64`).
    kind: u8,
    scale: f64,
    offset: f64,
}

/// The bytes of a number of extra-bytes type `kind` (1–10).
fn extra_size(kind: u8) -> usize {
    match kind {
        1 | 2 => 1,
        3 | 4 => 2,
        5 | 6 | 9 => 4,
        _ => 8,
    }
}

impl ExtraValue {
    /// Its value in a record's extra bytes (NaN, refused by the caller, if they are too few).
    fn read(&self, extra: &[u8]) -> f64 {
        let Some(b) = extra.get(self.at..self.at + extra_size(self.kind)) else {
            return f64::NAN;
        };
        let raw = match self.kind {
            1 => f64::from(b[0]),
            2 => f64::from(b[0] as i8),
            3 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            4 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            5 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            6 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            9 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            k => {
                let w = u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]);
                match k {
                    7 => w as f64,
                    8 => w as i64 as f64,
                    _ => f64::from_bits(w),
                }
            }
        };
        raw * self.scale + self.offset
    }
}

impl ExtraNormals {
    /// The normals described among `vlrs`, in records carrying `extra` extra bytes: `None` if
    /// none are, or where the description places them past those bytes or names a set in part.
    fn of<'a>(vlrs: impl Iterator<Item = &'a las::Vlr>, extra: usize) -> Option<Self> {
        // The names of the three components, matched without case, `_`, `-` or spaces.
        const SETS: [[&str; 3]; 2] = [["normalx", "normaly", "normalz"], ["nx", "ny", "nz"]];
        let mut found: [[Option<ExtraValue>; 3]; 2] = [[None; 3]; 2];
        let mut triple = None;
        let vlr = vlrs
            .filter(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
            .last()?;
        let mut at = 0;
        for d in vlr.data.chunks_exact(192) {
            let (kind, options) = (d[2], d[3]);
            let name: String = d[4..36]
                .iter()
                .take_while(|&&c| c != 0)
                .map(|&c| char::from(c).to_ascii_lowercase())
                .filter(|c| !matches!(c, '_' | '-' | ' '))
                .collect();
            let (base, count) = match kind {
                // Undocumented bytes: `options` of them.
                0 => {
                    at += usize::from(options);
                    continue;
                }
                1..=10 => (kind, 1),
                11..=20 => (kind - 10, 2),
                21..=30 => (kind - 20, 3),
                // A type the format does not define: the fields after it cannot be placed.
                _ => break,
            };
            let f64_at = |i: usize| f64::from_le_bytes(d[i..i + 8].try_into().unwrap_or([0; 8]));
            let value = |k: usize| ExtraValue {
                at: at + k * extra_size(base),
                kind: base,
                scale: if options & 8 != 0 {
                    f64_at(112 + 8 * k)
                } else {
                    1.0
                },
                offset: if options & 16 != 0 {
                    f64_at(136 + 8 * k)
                } else {
                    0.0
                },
            };
            let end = at + count * extra_size(base);
            let mut wanted = false;
            if count == 1 {
                for (set, slots) in SETS.iter().zip(&mut found) {
                    if let Some(k) = set.iter().position(|s| *s == name) {
                        slots[k] = Some(value(0));
                        wanted = true;
                    }
                }
            } else if count == 3 && matches!(name.as_str(), "normal" | "normals") {
                triple = Some([value(0), value(1), value(2)]);
                wanted = true;
            }
            if wanted && end > extra {
                return None;
            }
            at = end;
        }
        // A whole set of three fields first, else the deprecated triple; a set in part is none.
        found
            .iter()
            .find_map(|slots| match slots {
                [Some(x), Some(y), Some(z)] => Some(Self([*x, *y, *z])),
                _ => None,
            })
            .or(triple.map(Self))
    }

    /// The normal in a record's extra bytes.
    fn read(&self, extra: &[u8]) -> [f64; 3] {
        self.0.map(|v| v.read(extra))
    }
}

/// Checks what the `las` crate would size allocations by against the file's `len` bytes,
/// before it reads them: the point count times the record length (after the header's "offset
/// to point data") and each extended VLR's length (LAS 1.4). The fields are at the same bytes
/// in every version (ASPRS LAS 1.4 R15, table 3); a file shorter than the smallest header is
/// refused as truncated.
fn check_raw_header(path: &Path, mut file: std::fs::File, len: u64) -> Result<()> {
    use std::io::Read;
    let mut head = [0u8; 375];
    let have = usize::try_from(len).map_or(head.len(), |n| n.min(head.len()));
    file.read_exact(&mut head[..have]).map_err(io_error(path))?;
    if have >= 4 && &head[..4] != b"LASF" {
        return Err(super::malformed(
            path,
            None,
            "not a LAS file: it does not start with the signature LASF",
        ));
    }
    if have < 227 {
        // The smallest header (LAS 1.0–1.2) is 227 bytes.
        return Err(super::malformed(
            path,
            None,
            format!("truncated: a LAS header takes at least 227 bytes, the file has {len}"),
        ));
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
    let mut bytes = Bounded { file, path, len };
    // Bit 7 of the point format marks LASzip compression: its points are smaller than the
    // record length says.
    if head[104] & 0x80 != 0 {
        let vlrs = (u16_at(94), u32_at(100));
        check_laszip(&mut bytes, vlrs, start, record)?;
    } else if count.checked_mul(record).is_none_or(|need| need > room) {
        return Err(truncated(path, count, room / record));
    }
    if extended {
        let (mut at, evlrs) = (u64_at(235), u32_at(243));
        for i in 0..evlrs {
            let mut evlr = [0u8; 60];
            if !bytes.read_at(at, &mut evlr)? {
                return Err(super::malformed(
                    path,
                    None,
                    format!(
                        "extended VLR {i} of {evlrs} starts at byte {at}, past the file's end ({len} bytes)"
                    ),
                ));
            }
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

/// Checks a LAZ file's LASzip VLR and chunk table before the `laz` crate sizes buffers by them:
/// the VLRs start at byte `vlrs.0` (the header's size) and number `vlrs.1`; the points at
/// `start`, each `record` bytes once decompressed. The layouts are LASzip's (`laszip_dll.h`):
/// the VLR data is compressor `u16`, coder `u16`, version `u8 u8 u16`, options `u32`, chunk
/// size `u32`, two `i64`, the item count `u16`, then per item type, size and version (`u16`
/// each); the points start with the chunk table's offset (`i64`; where it is not past that,
/// the file's last 8 bytes hold it), and the table with a version and its count of chunks
/// (`u32` each).
fn check_laszip(bytes: &mut Bounded<'_>, vlrs: (u64, u64), start: u64, record: u64) -> Result<()> {
    let (path, len) = (bytes.path, bytes.len);
    let bad = |reason: String| super::malformed(path, None, format!("LAZ: {reason}"));
    let (mut at, count) = vlrs;
    let mut items = None;
    for i in 0..count.min(65_536) {
        let mut head = [0u8; 54];
        if !bytes.read_at(at, &mut head)? {
            return Err(bad(format!(
                "truncated: the file ends inside VLR {i} of the {count} its header announces \
                 (the LASzip record is among them)"
            )));
        }
        let length = u64::from(u16::from_le_bytes([head[20], head[21]]));
        let user = &head[2..18];
        let id = u16::from_le_bytes([head[18], head[19]]);
        if user.starts_with(b"laszip encoded") && id == 22204 {
            let mut data = vec![0u8; usize::try_from(length).unwrap_or(0)];
            if !bytes.read_at(at + 54, &mut data)? {
                return Err(bad(format!(
                    "the LASzip record claims {length} bytes past the file's end"
                )));
            }
            items = Some(data);
            break;
        }
        at += 54 + length;
    }
    let data = items.ok_or_else(|| {
        bad("no LASzip record (user \"laszip encoded\", id 22204) among the VLRs".to_owned())
    })?;
    let u16_at = |d: &[u8], i: usize| u64::from(u16::from_le_bytes([d[i], d[i + 1]]));
    if data.len() < 34 {
        return Err(bad(format!(
            "the LASzip record holds {} bytes, fewer than its 34-byte head",
            data.len()
        )));
    }
    let compressor = u16_at(&data, 0);
    if !(1..=3).contains(&compressor) {
        return Err(bad(format!(
            "unknown compressor {compressor} (LASzip has 1 to 3)"
        )));
    }
    let n = u16_at(&data, 32);
    if n == 0 || data.len() < 34 + 6 * n as usize {
        return Err(bad(format!(
            "the LASzip record lists {n} items in {} bytes",
            data.len()
        )));
    }
    let sizes: u64 = (0..n as usize).map(|i| u16_at(&data, 34 + 6 * i + 2)).sum();
    if sizes != record {
        return Err(bad(format!(
            "the LASzip items take {sizes} bytes a point, the header's record length {record}"
        )));
    }
    if record > MAX_LAZ_RECORD {
        return Err(bad(format!(
            "points of {record} bytes: zeroset reads LAZ records of at most {MAX_LAZ_RECORD} \
             (decompress it with `laszip -i scan.laz -o scan.las` to read it as LAS)"
        )));
    }
    // The chunk table: its count sizes an allocation of 16 bytes a chunk. Every chunk holds a
    // point, its first stored raw: at most one chunk per record's bytes of compressed data.
    let mut offset = [0u8; 8];
    if compressor >= 2 && bytes.read_at(start, &mut offset)? {
        let mut table = i64::from_le_bytes(offset);
        if table <= start as i64 && bytes.read_at(len.saturating_sub(8), &mut offset)? {
            table = i64::from_le_bytes(offset);
        }
        if table > start as i64 {
            let mut head = [0u8; 8];
            if !bytes.read_at(table as u64, &mut head)? {
                return Err(bad(format!(
                    "the chunk table is said to start at byte {table}, past the file's end ({len} \
                     bytes)"
                )));
            }
            let chunks = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
            let most = (table as u64 - start) / record.max(1) + 1;
            if chunks > most {
                return Err(bad(format!(
                    "the chunk table lists {chunks} chunks; the {} bytes of points hold at most \
                     {most}",
                    table as u64 - start
                )));
            }
        }
    }
    Ok(())
}

/// Reads at given bytes of a file of `len` bytes, never past its end.
struct Bounded<'a> {
    file: std::fs::File,
    path: &'a Path,
    len: u64,
}

impl Bounded<'_> {
    /// Fills `buf` from byte `at`: `Ok(false)`, reading nothing, where it would run past the end.
    fn read_at(&mut self, at: u64, buf: &mut [u8]) -> Result<bool> {
        use std::io::{Read, Seek, SeekFrom};
        if at
            .checked_add(buf.len() as u64)
            .is_none_or(|end| end > self.len)
        {
            return Ok(false);
        }
        self.file
            .seek(SeekFrom::Start(at))
            .and_then(|_| self.file.read_exact(buf))
            .map_err(io_error(self.path))?;
        Ok(true)
    }
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

/// The reader's error for a `las` error in `path`.
fn las_error(path: &Path, e: las::Error) -> Error {
    match e {
        // The crate reads the header, the VLRs and the points with `read_exact`: a file that
        // ends inside them.
        las::Error::Io(source) if source.kind() == std::io::ErrorKind::UnexpectedEof => {
            super::malformed(
                path,
                None,
                "truncated or corrupt: the file ends inside its header, its variable-length \
                 records or its points (for LAZ, the compressed data may be damaged)",
            )
        }
        las::Error::Io(source) => io_error(path)(source),
        e => super::malformed(path, None, format!("not a readable LAS/LAZ file: {e}")),
    }
}
