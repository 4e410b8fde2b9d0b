//! PCD, the Point Cloud Library's point-cloud format (v0.5–0.7): a text header, then the
//! points as text, as binary records, or LZF-compressed field by field.
//!
//! ```text
//! # .PCD v0.7 - Point Cloud Data file format
//! VERSION 0.7
//! FIELDS x y z normal_x normal_y normal_z curvature
//! SIZE 4 4 4 4 4 4 4
//! TYPE F F F F F F F
//! COUNT 1 1 1 1 1 1 1
//! WIDTH 5210
//! HEIGHT 1
//! VIEWPOINT 0 0 0 1 0 0 0
//! POINTS 5210
//! DATA binary
//! ```
//!
//! - Header: `FIELDS` names the fields; `SIZE` (bytes: 1, 2, 4 or 8; default 4), `TYPE` (`I`
//!   signed, `U` unsigned, `F` floating point of 4 or 8 bytes; default `F`, as PCL reads files
//!   older than v0.7) and `COUNT` (values per field, default 1) give one entry per field;
//!   `POINTS` the count (default `WIDTH × HEIGHT`; both given, they must agree); `DATA` ends
//!   the header and says how the points follow. `VERSION`, `VIEWPOINT` and `#` comments are
//!   skipped, as is any other keyword. Text after the announced points is not read.
//! - `DATA ascii`: one point per line, every field's values separated by whitespace.
//!   `DATA binary`: `POINTS` records of the fields' bytes in turn, little-endian (PCL writes
//!   the memory of an x86 or ARM machine). `DATA binary_compressed`: the compressed and the
//!   uncompressed size (`u32` each), then LZF-compressed data which holds each field of all
//!   points in turn (every point's `x`, then every point's `y`, ...).
//! - Read: `x y z` (required) and the normal, `normal_x normal_y normal_z` as PCL names it (or
//!   `nx ny nz`; [`NORMAL_NAMES`](super::NORMAL_NAMES)). Colours, intensities, curvature and
//!   descriptors are skipped.
//! - A point whose `x`, `y` and `z` are all NaN is where an organised cloud (a depth camera's
//!   image, `HEIGHT` > 1) had no measurement: it is not a point and is left out. Any other NaN
//!   or infinite value is [`Error::NonFinite`] unless allowed, as in
//!   every format. A file whose points are all such gaps is an error.
//! - Nothing is sized from the header alone: the bytes after it must hold the records
//!   announced ([`Error::Truncated`] otherwise), and the compressed
//!   block's sizes are checked against the file and against what LZF can expand to before
//!   anything is allocated. Errors name the file and the header line, the text line, or the
//!   point (0-based record).

use std::path::Path;

use super::{FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, malformed};
use crate::error::{Error, Result};
use crate::geometry::Point3;
use crate::limits;

/// The most LZF can expand data by: a 2-byte back reference copies up to 8 bytes, a 3-byte one
/// up to 264 (so at most 88× per input byte); rounded up.
const LZF_MAX_EXPANSION: u64 = 90;

/// How the points follow the header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Data {
    /// `DATA ascii`.
    Ascii,
    /// `DATA binary`.
    Binary,
    /// `DATA binary_compressed`.
    Compressed,
}

/// The numeric type of a field's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// `TYPE I`.
    Signed,
    /// `TYPE U`.
    Unsigned,
    /// `TYPE F`.
    Float,
}

/// One field of the header.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Field {
    name: String,
    /// Bytes per value: 1, 2, 4 or 8 (4 or 8 for floats).
    size: usize,
    kind: Kind,
    /// Values per point.
    count: usize,
    /// The field's first byte in a binary record.
    offset: usize,
    /// The field's first value on an ASCII line.
    column: usize,
}

impl Field {
    /// Bytes per point.
    fn bytes(&self) -> usize {
        self.size * self.count
    }

    /// The value in little-endian `bytes` (exactly `size` of them).
    fn decode(&self, bytes: &[u8]) -> f64 {
        let mut b = [0u8; 8];
        b[..bytes.len()].copy_from_slice(bytes);
        // Sign extension for signed integers shorter than 8 bytes.
        let signed = |bits: u32| {
            let shift = 64 - bits;
            ((u64::from_le_bytes(b) << shift) as i64 >> shift) as f64
        };
        match (self.kind, self.size) {
            (Kind::Float, 4) => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            (Kind::Float, _) => f64::from_le_bytes(b),
            (Kind::Signed, size) => signed(8 * size as u32),
            (Kind::Unsigned, _) => u64::from_le_bytes(b) as f64,
        }
    }
}

/// A parsed header.
#[derive(Debug, Clone)]
struct Header {
    fields: Vec<Field>,
    points: usize,
    data: Data,
    /// The byte after the `DATA` line.
    start: usize,
    /// The number of header lines (the `DATA` line's number).
    lines: usize,
}

impl Header {
    /// Bytes per binary record.
    fn record(&self) -> usize {
        self.fields.iter().map(Field::bytes).sum()
    }

    /// Values per ASCII line.
    fn values(&self) -> usize {
        self.fields.iter().map(|f| f.count).sum()
    }

    /// The field called `name` (exactly, as PCL names them).
    fn find(&self, name: &str) -> Option<usize> {
        self.fields.iter().position(|f| f.name == name)
    }
}

/// Reads a PCD file; see the [module docs](self).
pub(super) fn read(path: &Path, check: &FiniteCheck<'_>) -> Result<RawPoints> {
    let bytes = super::ply::read_whole(path)?;
    if bytes.is_empty() {
        return Err(malformed(path, None, "the file is empty (0 bytes)"));
    }
    let header = parse_header(path, &bytes)?;
    let missing = |name: &str| {
        let fields: Vec<&str> = header.fields.iter().map(|f| f.name.as_str()).collect();
        malformed(
            path,
            None,
            format!("PCD has no field '{name}' (FIELDS {})", fields.join(" ")),
        )
    };
    let slot = |name: &'static str| {
        let i = header.find(name).ok_or_else(|| missing(name))?;
        let field = &header.fields[i];
        if field.count != 1 {
            return Err(malformed(
                path,
                None,
                format!(
                    "PCD field '{name}' has COUNT {}, expected 1 (one value per point)",
                    field.count
                ),
            ));
        }
        Ok(i)
    };
    let position = [slot("x")?, slot("y")?, slot("z")?];
    let (normal, normal_names) = match super::normal_columns(|name| header.find(name)) {
        Ok(None) => (None, NORMAL_FIELDS),
        Ok(Some((_, names))) => (
            Some([slot(names[0])?, slot(names[1])?, slot(names[2])?]),
            names,
        ),
        Err(name) => return Err(missing(name)),
    };
    let body = &bytes[header.start..];
    let normals = normal.is_some();
    match header.data {
        Data::Ascii => {
            // Each value takes at least two bytes ("0 "): the count is capped by what the text
            // can hold, the file's end then telling how many there were.
            let fit = records_in(body.len() + 1, 2 * header.values());
            let mut points =
                Points::new(path, check, header.points.min(fit), normals, normal_names)?;
            read_ascii(path, &header, body, position, normal, &mut points)?;
            points.finish(header.points)
        }
        Data::Binary => {
            let record = header.record();
            let available = records_in(body.len(), record);
            if available < header.points {
                return Err(truncated(path, &header, available));
            }
            let mut points = Points::new(path, check, header.points, normals, normal_names)?;
            for (r, chunk) in body
                .chunks_exact(record.max(1))
                .take(header.points)
                .enumerate()
            {
                let value = |i: usize| {
                    let f = &header.fields[i];
                    f.decode(&chunk[f.offset..f.offset + f.size])
                };
                points.push(r, None, position.map(value), normal.map(|n| n.map(value)))?;
            }
            points.finish(header.points)
        }
        Data::Compressed => {
            let columns = decompress(path, &header, body)?;
            let mut points = Points::new(path, check, header.points, normals, normal_names)?;
            // Field `i` of point `r` at `start_i + r · size_i` (each field's block in turn).
            let starts: Vec<usize> = header
                .fields
                .iter()
                .scan(0, |start, f| {
                    let here = *start;
                    *start += f.bytes() * header.points;
                    Some(here)
                })
                .collect();
            for r in 0..header.points {
                let value = |i: usize| {
                    let f = &header.fields[i];
                    let at = starts[i] + r * f.size;
                    f.decode(&columns[at..at + f.size])
                };
                points.push(r, None, position.map(value), normal.map(|n| n.map(value)))?;
            }
            points.finish(header.points)
        }
    }
}

/// The positions and normals read so far, without the points that are gaps.
struct Points<'a> {
    path: &'a Path,
    check: &'a FiniteCheck<'a>,
    positions: Vec<Point3>,
    normals: Option<Vec<Point3>>,
    /// The normal's field names as the file gives them (for errors).
    normal_names: [&'static str; 3],
}

impl<'a> Points<'a> {
    /// Room for `count` points (a count the file's bytes can hold), checked against the memory
    /// available.
    fn new(
        path: &'a Path,
        check: &'a FiniteCheck<'a>,
        count: usize,
        normals: bool,
        normal_names: [&'static str; 3],
    ) -> Result<Self> {
        let what = format!("the points of {}", path.display());
        let per_point = if normals { 48 } else { 24 };
        limits::check_alloc(&what, count, per_point)?;
        Ok(Self {
            path,
            check,
            positions: Vec::with_capacity(count),
            normals: normals.then(|| Vec::with_capacity(count)),
            normal_names,
        })
    }

    /// Takes point `record` (on text line `line`), unless its coordinates are all NaN.
    fn push(
        &mut self,
        record: usize,
        line: Option<usize>,
        position: Point3,
        normal: Option<Point3>,
    ) -> Result<()> {
        if position.iter().all(|v| v.is_nan()) {
            return Ok(());
        }
        self.check
            .check(record, line, &POSITION_FIELDS, &position)?;
        self.positions.push(position);
        if let (Some(normals), Some(n)) = (self.normals.as_mut(), normal) {
            self.check.check(record, line, &self.normal_names, &n)?;
            normals.push(n);
        }
        Ok(())
    }

    /// The points, or an error if every one of the `count` announced was a gap.
    fn finish(self, count: usize) -> Result<RawPoints> {
        if self.positions.is_empty() && count > 0 {
            return Err(malformed(
                self.path,
                None,
                format!(
                    "every one of its {count} points has NaN coordinates (no measurement): no \
                     point to read"
                ),
            ));
        }
        Ok((self.positions, self.normals))
    }
}

/// How many whole `record`-byte records `len` bytes hold.
fn records_in(len: usize, record: usize) -> usize {
    len.checked_div(record).unwrap_or(usize::MAX)
}

/// [`Error::Truncated`] for `header`'s points, of which `got` are in the file.
fn truncated(path: &Path, header: &Header, got: usize) -> Error {
    Error::Truncated {
        path: path.to_owned(),
        element: "point".to_owned(),
        expected: header.points,
        got,
    }
}

/// Reads `DATA ascii` points from `body`, which starts on line `header.lines + 1`.
fn read_ascii(
    path: &Path,
    header: &Header,
    body: &[u8],
    position: [usize; 3],
    normal: Option<[usize; 3]>,
    points: &mut Points<'_>,
) -> Result<()> {
    let values_per_line = header.values();
    // Grown by the values a line holds, never sized by the header's counts.
    let mut values = Vec::new();
    let mut record = 0;
    for (i, line) in body.split(|&b| b == b'\n').enumerate() {
        if record == header.points {
            break;
        }
        let line_no = header.lines + 1 + i;
        let text = std::str::from_utf8(line)
            .map_err(|_| malformed(path, Some(line_no), "not UTF-8 text"))?;
        let text = text.split('#').next().unwrap_or_default();
        if text.trim().is_empty() {
            continue;
        }
        values.clear();
        // At most one value past the expected count is parsed: a line of millions of
        // numbers is refused without holding them.
        for token in text.split_whitespace().take(values_per_line + 1) {
            let value = super::parse_number(token).ok_or_else(|| {
                malformed(
                    path,
                    Some(line_no),
                    format!("not a number: '{token}' (value {})", values.len() + 1),
                )
            })?;
            values.push(value);
        }
        if values.len() != values_per_line {
            return Err(malformed(
                path,
                Some(line_no),
                format!(
                    "expected {values_per_line} values (the header's fields and counts), found {}",
                    if values.len() > values_per_line {
                        "more".to_owned()
                    } else {
                        values.len().to_string()
                    }
                ),
            ));
        }
        let value = |f: usize| values[header.fields[f].column];
        let line = Some(line_no);
        points.push(
            record,
            line,
            position.map(value),
            normal.map(|n| n.map(value)),
        )?;
        record += 1;
    }
    if record < header.points {
        return Err(truncated(path, header, record));
    }
    Ok(())
}

/// The fields' bytes of a `DATA binary_compressed` body, each field's block in turn.
fn decompress(path: &Path, header: &Header, body: &[u8]) -> Result<Vec<u8>> {
    let word = |at: usize| {
        body.get(at..at + 4)
            .map(|b| u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
    };
    let (Some(compressed), Some(size)) = (word(0), word(4)) else {
        return Err(malformed(
            path,
            None,
            "PCD binary_compressed data ends before its two sizes (8 bytes after the header)",
        ));
    };
    let expected = (header.record() as u64).saturating_mul(header.points as u64);
    if size != expected {
        return Err(malformed(
            path,
            None,
            format!(
                "PCD binary_compressed data would expand to {size} bytes, but {} points of {} \
                 bytes take {expected}",
                header.points,
                header.record()
            ),
        ));
    }
    let data = &body[8..];
    if compressed > data.len() as u64 {
        return Err(Error::Truncated {
            path: path.to_owned(),
            element: "compressed byte".to_owned(),
            expected: usize::try_from(compressed).unwrap_or(usize::MAX),
            got: data.len(),
        });
    }
    if expected == 0 {
        return Ok(Vec::new());
    }
    let data = &data[..compressed as usize];
    if size > compressed.saturating_mul(LZF_MAX_EXPANSION) {
        return Err(malformed(
            path,
            None,
            format!(
                "PCD binary_compressed data of {compressed} bytes cannot expand to {size} (LZF \
                 expands at most {LZF_MAX_EXPANSION}×): the header's point count is wrong"
            ),
        ));
    }
    limits::check_bytes(&format!("decompressing {}", path.display()), size)?;
    let size = size as usize;
    match lzf::decompress(data, size) {
        Ok(out) if out.len() == size => Ok(out),
        Ok(out) => Err(malformed(
            path,
            None,
            format!(
                "PCD binary_compressed data expands to {} bytes, not the {size} announced",
                out.len()
            ),
        )),
        Err(e) => Err(malformed(
            path,
            None,
            format!("PCD binary_compressed data does not decompress (LZF: {e:?})"),
        )),
    }
}

/// Parses the header, up to and including the `DATA` line.
fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let mut names: Option<Vec<String>> = None;
    // Each with the line that gave it.
    let mut sizes: Option<(usize, Vec<usize>)> = None;
    let mut types: Option<(usize, Vec<Kind>)> = None;
    let mut counts: Option<(usize, Vec<usize>)> = None;
    let (mut width, mut height, mut points) = (None, None, None);
    let mut at = 0;
    let mut line_no = 0;
    // Whether a line other than a comment has been read.
    let mut keyed = false;
    loop {
        line_no += 1;
        let Some(len) = bytes[at..].iter().position(|&b| b == b'\n') else {
            return Err(malformed(
                path,
                Some(line_no),
                "PCD header ends without a 'DATA' line",
            ));
        };
        let raw = &bytes[at..at + len];
        at += len + 1;
        let error = |detail: String| malformed(path, Some(line_no), detail);
        let text = std::str::from_utf8(raw)
            .map_err(|_| error("PCD header line is not UTF-8 text".to_owned()))?;
        let text = if line_no == 1 {
            text.trim_start_matches('\u{feff}')
        } else {
            text
        };
        let text = text.split('#').next().unwrap_or_default();
        let mut words = text.split_whitespace();
        let Some(key) = words.next() else { continue };
        let rest: Vec<&str> = words.collect();
        let numbers = |what: &str| -> Result<Vec<usize>> {
            rest.iter()
                .map(|w| {
                    w.parse::<usize>().map_err(|_| {
                        error(format!(
                            "PCD {what} '{w}' is not a non-negative whole number"
                        ))
                    })
                })
                .collect()
        };
        let one = |what: &str| -> Result<usize> {
            match numbers(what)?.as_slice() {
                [n] => Ok(*n),
                _ => Err(error(format!("PCD {what} takes one number"))),
            }
        };
        match key.to_ascii_uppercase().as_str() {
            "FIELDS" | "COLUMNS" => names = Some(rest.iter().map(|s| (*s).to_owned()).collect()),
            "SIZE" => sizes = Some((line_no, numbers("SIZE")?)),
            "COUNT" => counts = Some((line_no, numbers("COUNT")?)),
            "TYPE" => {
                let kinds = rest
                    .iter()
                    .map(|t| match *t {
                        "I" | "i" => Ok(Kind::Signed),
                        "U" | "u" => Ok(Kind::Unsigned),
                        "F" | "f" => Ok(Kind::Float),
                        other => Err(error(format!(
                            "PCD TYPE '{other}' is not I, U or F (signed, unsigned, floating \
                             point)"
                        ))),
                    })
                    .collect::<Result<_>>()?;
                types = Some((line_no, kinds));
            }
            "WIDTH" => width = Some(one("WIDTH")?),
            "HEIGHT" => height = Some(one("HEIGHT")?),
            "POINTS" => points = Some(one("POINTS")?),
            "DATA" => {
                let data = match rest.as_slice() {
                    [d] if d.eq_ignore_ascii_case("ascii") => Data::Ascii,
                    [d] if d.eq_ignore_ascii_case("binary") => Data::Binary,
                    [d] if d.eq_ignore_ascii_case("binary_compressed") => Data::Compressed,
                    _ => {
                        return Err(error(format!(
                            "PCD DATA '{}' is not ascii, binary or binary_compressed",
                            rest.join(" ")
                        )));
                    }
                };
                let names = names.ok_or_else(|| error("PCD header has no FIELDS line".into()))?;
                let n = names.len();
                // Files older than v0.7 may leave SIZE and TYPE out: PCL reads 4-byte floats.
                let sizes = sizes.unwrap_or_else(|| (line_no, vec![4; n]));
                let types = types.unwrap_or_else(|| (line_no, vec![Kind::Float; n]));
                let counts = counts.unwrap_or_else(|| (line_no, vec![1; n]));
                let at_line = |line: usize, detail: String| malformed(path, Some(line), detail);
                for (what, line, len) in [
                    ("SIZE", sizes.0, sizes.1.len()),
                    ("TYPE", types.0, types.1.len()),
                    ("COUNT", counts.0, counts.1.len()),
                ] {
                    if len != n {
                        return Err(at_line(
                            line,
                            format!("PCD {what} has {len} entries for {n} FIELDS"),
                        ));
                    }
                }
                let ((size_line, sizes), (_, types), (count_line, counts)) = (sizes, types, counts);
                let mut fields = Vec::with_capacity(n);
                let (mut offset, mut column) = (0usize, 0usize);
                for (((name, size), kind), count) in
                    names.into_iter().zip(sizes).zip(types).zip(counts)
                {
                    let valid = match kind {
                        Kind::Float => matches!(size, 4 | 8),
                        _ => matches!(size, 1 | 2 | 4 | 8),
                    };
                    if !valid {
                        return Err(at_line(
                            size_line,
                            format!(
                                "PCD field '{name}' has SIZE {size}, not a size its TYPE has (1, 2, \
                             4 or 8 bytes; 4 or 8 for F)"
                            ),
                        ));
                    }
                    if count == 0 || count > 1 << 20 {
                        return Err(at_line(
                            count_line,
                            format!(
                                "PCD field '{name}' has COUNT {count}, expected 1 to {}",
                                1 << 20
                            ),
                        ));
                    }
                    fields.push(Field {
                        name,
                        size,
                        kind,
                        count,
                        offset,
                        column,
                    });
                    offset += size * count;
                    column += count;
                }
                let points = match (points, width, height) {
                    (Some(p), Some(w), Some(h)) if w.checked_mul(h) != Some(p) => {
                        return Err(error(format!(
                            "PCD POINTS {p} is not WIDTH × HEIGHT = {w} × {h} (PCL refuses such \
                             a header too)"
                        )));
                    }
                    (Some(p), _, _) => p,
                    (None, Some(w), Some(h)) => w.saturating_mul(h),
                    _ => {
                        return Err(error(
                            "PCD header has neither POINTS nor WIDTH and HEIGHT".to_owned(),
                        ));
                    }
                };
                return Ok(Header {
                    fields,
                    points,
                    data,
                    start: at,
                    lines: line_no,
                });
            }
            _ => {}
        }
        if !std::mem::replace(&mut keyed, true) && !is_keyword(key) {
            return Err(error(format!(
                "not a PCD file: it starts with '{}', not a PCD header (VERSION, FIELDS, ...)",
                key.chars().take(40).collect::<String>()
            )));
        }
    }
}

/// Whether `key` is a keyword of the PCD header.
fn is_keyword(key: &str) -> bool {
    const KEYWORDS: [&str; 11] = [
        "VERSION",
        "FIELDS",
        "COLUMNS",
        "SIZE",
        "TYPE",
        "COUNT",
        "WIDTH",
        "HEIGHT",
        "VIEWPOINT",
        "POINTS",
        "DATA",
    ];
    KEYWORDS.iter().any(|k| k.eq_ignore_ascii_case(key))
}
