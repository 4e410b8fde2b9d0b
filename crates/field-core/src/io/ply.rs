//! PLY: the header and binary records are parsed by `ply-rs-bw`; ASCII records are tokenised
//! here so that `nan` and `inf` reach the finiteness check with their line number.

use std::io::{BufRead, BufReader, Seek, Write};
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};

use super::{
    FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, io_error, malformed, open_nonempty,
    parse_number, records_that_fit, write_atomic,
};
use crate::cloud::PointCloud3;
use crate::error::{Error, Result};
use crate::geometry::Point3;

/// The vertex properties read, in slot order.
const SLOTS: [&str; 6] = ["x", "y", "z", "nx", "ny", "nz"];

fn slot(name: &str) -> Option<usize> {
    SLOTS.iter().position(|s| *s == name)
}

/// One vertex: `x y z nx ny nz` in slots 0..6; other properties are ignored.
struct VertexRecord([f64; 6]);

impl PropertyAccess for VertexRecord {
    fn new() -> Self {
        Self([0.0; 6])
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let value = match property {
            Property::Char(v) => f64::from(v),
            Property::UChar(v) => f64::from(v),
            Property::Short(v) => f64::from(v),
            Property::UShort(v) => f64::from(v),
            Property::Int(v) => f64::from(v),
            Property::UInt(v) => f64::from(v),
            Property::Float(v) => f64::from(v),
            Property::Double(v) => v,
            _ => return PropertyAccessResult::Ignored,
        };
        match slot(name) {
            Some(i) => {
                self.0[i] = value;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::Ignored,
        }
    }
}

/// An element whose values are all dropped (elements before `vertex`).
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

fn scalar_size(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// Bytes per record of a binary element, if all its properties are scalars.
fn record_size(def: &ElementDef) -> Option<usize> {
    def.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) => Some(scalar_size(t)),
            PropertyType::List(..) => None,
        })
        .sum()
}

/// The fewest bytes a binary record of `def` can take: its scalars, and each list's count.
fn min_binary_record_size(def: &ElementDef) -> usize {
    def.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
        })
        .sum()
}

/// Which of the six slots the vertex element defines, after checking that `x y z` are all
/// there and scalar and that `nx ny nz` are all or none.
fn vertex_layout(path: &Path, def: &ElementDef) -> Result<bool> {
    let mut present = [false; 6];
    for (i, name) in SLOTS.iter().enumerate() {
        if let Some(p) = def.properties.get(*name) {
            if matches!(p.data_type, PropertyType::List(..)) {
                return Err(malformed(
                    path,
                    None,
                    format!("PLY vertex property '{name}' is a list, expected a scalar"),
                ));
            }
            present[i] = true;
        }
    }
    for i in 0..3 {
        if !present[i] {
            return Err(Error::MissingProperty {
                path: path.to_owned(),
                property: SLOTS[i],
            });
        }
    }
    let normals = present[3..].iter().filter(|p| **p).count();
    if normals != 0 && normals != 3 {
        let missing = (3..6).find(|i| !present[*i]).unwrap_or(3);
        return Err(Error::MissingProperty {
            path: path.to_owned(),
            property: SLOTS[missing],
        });
    }
    Ok(normals == 3)
}

/// The first line of a `ply-rs` error, without its `Line N: ` prefix (the line is reported
/// separately) or the parser's debug dump.
fn brief(e: &ply_rs_bw::parser::ParseError) -> String {
    let text = e.to_string();
    let first = text.lines().next().unwrap_or_default();
    let first = match e.line() {
        Some(l) => first.strip_prefix(&format!("Line {l}: ")).unwrap_or(first),
        None => first,
    };
    first.trim().to_owned()
}

/// Reads the `vertex` element of a PLY file.
pub(super) fn read(path: &Path, check: &FiniteCheck<'_>) -> Result<RawPoints> {
    let (file, file_len) = open_nonempty(path)?;
    let mut reader = Reader::new(BufReader::new(file));
    let header = Parser::<VertexRecord>::new()
        .read_header(&mut reader)
        .map_err(|e| {
            let reason = format!("not a valid PLY header: {}", brief(&e));
            malformed(path, e.line(), reason)
        })?;
    let Some(vertex_index) = header.elements.get_index_of("vertex") else {
        return Err(malformed(path, None, "PLY file has no 'vertex' element"));
    };
    let vertex_def = &header.elements[vertex_index];
    let has_normals = vertex_layout(path, vertex_def)?;
    let header_len = reader.get_mut().stream_position().map_err(io_error(path))?;
    let payload_len = file_len.saturating_sub(header_len);
    // Never trust a header count for an allocation (`records_that_fit`).
    let capacity = match header.encoding {
        Encoding::Ascii => records_that_fit(
            vertex_def.count,
            payload_len.saturating_add(1),
            2 * vertex_def.properties.len(),
        ),
        _ => records_that_fit(
            vertex_def.count,
            payload_len,
            min_binary_record_size(vertex_def),
        ),
    };
    let mut positions = Vec::with_capacity(capacity);
    let mut normals = has_normals.then(|| Vec::with_capacity(capacity));
    let mut push = |record: usize, line: Option<usize>, v: &[f64; 6]| -> Result<()> {
        check.check(record, line, &POSITION_FIELDS, &v[..3])?;
        positions.push([v[0], v[1], v[2]]);
        if let Some(n) = normals.as_mut() {
            check.check(record, line, &NORMAL_FIELDS, &v[3..])?;
            n.push([v[3], v[4], v[5]]);
        }
        Ok(())
    };
    match header.encoding {
        Encoding::Ascii => {
            let first_line = reader.line();
            read_ascii(
                path,
                reader.get_mut(),
                &header,
                vertex_index,
                first_line,
                &mut push,
            )?;
        }
        encoding => {
            precheck_binary_size(path, &header, vertex_index, payload_len)?;
            read_binary(
                path,
                reader.get_mut(),
                &header,
                vertex_index,
                encoding,
                &mut push,
            )?;
        }
    }
    Ok((positions, normals))
}

/// Fails fast with [`Error::Truncated`] when the payload is too short for the vertices, if the
/// byte count is known (every element up to `vertex` has only scalar properties).
fn precheck_binary_size(
    path: &Path,
    header: &Header,
    vertex_index: usize,
    payload_len: u64,
) -> Result<()> {
    let mut offset: u64 = 0;
    for def in header.elements.values().take(vertex_index) {
        let Some(size) = record_size(def) else {
            return Ok(());
        };
        offset = offset.saturating_add((size as u64).saturating_mul(def.count as u64));
    }
    let def = &header.elements[vertex_index];
    let Some(size) = record_size(def) else {
        return Ok(());
    };
    if size == 0 {
        return Ok(());
    }
    let available = payload_len.saturating_sub(offset) / size as u64;
    if available < def.count as u64 {
        return Err(Error::Truncated {
            path: path.to_owned(),
            element: def.name.clone(),
            expected: def.count,
            got: usize::try_from(available).unwrap_or(usize::MAX),
        });
    }
    Ok(())
}

fn read_binary<R: BufRead>(
    path: &Path,
    reader: &mut R,
    header: &Header,
    vertex_index: usize,
    encoding: Encoding,
    push: &mut impl FnMut(usize, Option<usize>, &[f64; 6]) -> Result<()>,
) -> Result<()> {
    let big = encoding == Encoding::BinaryBigEndian;
    let map = |def: &ElementDef, i: usize, e: ply_rs_bw::parser::ParseError| -> Error {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            Error::Truncated {
                path: path.to_owned(),
                element: def.name.clone(),
                expected: def.count,
                got: i,
            }
        } else {
            malformed(
                path,
                None,
                format!("PLY element '{}' record {i}: {}", def.name, brief(&e)),
            )
        }
    };
    let skip = Parser::<Skip>::new();
    for def in header.elements.values().take(vertex_index) {
        for i in 0..def.count {
            let r = if big {
                skip.read_big_endian_element(reader, def)
            } else {
                skip.read_little_endian_element(reader, def)
            };
            r.map_err(|e| map(def, i, e))?;
        }
    }
    let parser = Parser::<VertexRecord>::new();
    let def = &header.elements[vertex_index];
    for i in 0..def.count {
        let r = if big {
            parser.read_big_endian_element(reader, def)
        } else {
            parser.read_little_endian_element(reader, def)
        };
        let record = r.map_err(|e| map(def, i, e))?;
        push(i, None, &record.0)?;
    }
    Ok(())
}

fn read_ascii<R: BufRead>(
    path: &Path,
    reader: &mut R,
    header: &Header,
    vertex_index: usize,
    first_line: usize,
    push: &mut impl FnMut(usize, Option<usize>, &[f64; 6]) -> Result<()>,
) -> Result<()> {
    let mut line_no = first_line.max(1) - 1;
    let mut buf = String::new();
    for (index, def) in header.elements.values().enumerate().take(vertex_index + 1) {
        let is_vertex = index == vertex_index;
        // For each property: the slot it fills, if any.
        let slots: Vec<(Option<usize>, &PropertyType)> = def
            .properties
            .values()
            .map(|p| (if is_vertex { slot(&p.name) } else { None }, &p.data_type))
            .collect();
        for record in 0..def.count {
            buf.clear();
            let n = reader.read_line(&mut buf).map_err(|e| {
                malformed(path, Some(line_no + 1), format!("cannot read line: {e}"))
            })?;
            if n == 0 {
                return Err(Error::Truncated {
                    path: path.to_owned(),
                    element: def.name.clone(),
                    expected: def.count,
                    got: record,
                });
            }
            line_no += 1;
            let values = parse_ascii_record(&buf, &slots, &def.name)
                .map_err(|reason| malformed(path, Some(line_no), reason))?;
            if is_vertex {
                push(record, Some(line_no), &values)?;
            }
        }
    }
    Ok(())
}

/// Parses one ASCII record against its property list; returns the six slots.
fn parse_ascii_record(
    line: &str,
    slots: &[(Option<usize>, &PropertyType)],
    element: &str,
) -> std::result::Result<[f64; 6], String> {
    let mut values = [0.0; 6];
    let mut tokens = line.split_ascii_whitespace();
    let expected_more = |what: &str| format!("PLY element '{element}': line ends before {what}");
    for (slot, data_type) in slots {
        match data_type {
            PropertyType::Scalar(_) => {
                let token = tokens
                    .next()
                    .ok_or_else(|| expected_more("all properties"))?;
                let value =
                    parse_number(token).ok_or_else(|| format!("not a number: '{token}'"))?;
                if let Some(i) = slot {
                    values[*i] = value;
                }
            }
            PropertyType::List(..) => {
                let token = tokens
                    .next()
                    .ok_or_else(|| expected_more("a list length"))?;
                let len: usize = token
                    .parse()
                    .map_err(|_| format!("not a list length: '{token}'"))?;
                for _ in 0..len {
                    let token = tokens
                        .next()
                        .ok_or_else(|| expected_more("the list ends"))?;
                    parse_number(token).ok_or_else(|| format!("not a number: '{token}'"))?;
                }
            }
        }
    }
    if let Some(extra) = tokens.next() {
        return Err(format!(
            "PLY element '{element}': unexpected value '{extra}' after the last property"
        ));
    }
    Ok(values)
}

/// Writes a cloud as binary little-endian PLY with `double` properties `x y z` (and
/// `nx ny nz` if the cloud has normals), atomically ([`write_atomic`]).
///
/// Values are written as they are, non-finite ones included; an empty cloud gives a valid
/// file with 0 vertices (which [`read_point_cloud`](super::read_point_cloud) rejects).
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
