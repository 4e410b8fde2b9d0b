//! PLY, the one reader of the format: the header and the records of any element, in ASCII or
//! binary of either endianness. The point-cloud reader ([`read_point_cloud`]), the mesh reader
//! (`zeroset_mesh::read_ply_mesh`) and `zeroset info`'s question "is this a mesh?" all stand on
//! it, so that there is one place where the format is parsed and hardened.
//!
//! A file is `ply`, a `format` line, `element <name> <count>` lines each followed by its
//! `property <type> <name>` or `property list <count type> <item type> <name>` lines, and
//! `end_header`; then the records of each element in turn. [`Header::parse`] reads the header;
//! [`Records`] walks the records, each decoded into a [`Record`] of `f64` values.
//!
//! - Scalar types: `char uchar short ushort int uint float double` and the aliases
//!   `int8 uint8 int16 uint16 int32 uint32 float32 float64`. An ASCII value keeps the text's
//!   precision (an `f64`, even for a `float` property: georeferenced coordinates often have
//!   more digits than an `f32` holds); an ASCII integer must be a whole number in its type's
//!   range. `nan` and `inf` are read as such; whoever uses the values decides whether they
//!   are allowed.
//! - `comment` and `obj_info` lines are skipped; blank ASCII lines between records are too.
//! - Nothing is sized from the header alone: [`Records::records_that_fit`] caps a count by what
//!   the bytes after the header can hold, a list's items are read one by one, and a file that
//!   ends early is [`PlyError::Truncated`] naming the element and record.
//! - Every error says where: the header line, or the record with its line (ASCII) or byte
//!   offset (binary), as a [`Place`]. The file's name is added by the caller.
//!
//! ```
//! use zeroset_field_core::io::ply::{Header, Record, Records};
//!
//! let bytes = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n\
//!               property list uchar int ids\nend_header\n0.5 2 7 8\n1.5 0\n";
//! let header = Header::parse(bytes)?;
//! let vertex = header.element("vertex").unwrap();
//! let mut records = Records::new(&header, bytes);
//! let mut record = Record::default();
//! records.read(vertex, 0, &mut record)?;
//! assert_eq!(record.scalar(0), 0.5);
//! assert_eq!(record.list(1), &[7.0, 8.0]);
//! # Ok::<(), zeroset_field_core::io::ply::PlyError>(())
//! ```
//!
//! [`read_point_cloud`]: super::read_point_cloud

use std::fmt;
use std::io::Read;
use std::path::Path;

use super::records_that_fit;

mod points;

pub(super) use points::read;
pub use points::read_whole;
pub use points::write_ply;

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    /// `char`, `int8`.
    I8,
    /// `uchar`, `uint8`.
    U8,
    /// `short`, `int16`.
    I16,
    /// `ushort`, `uint16`.
    U16,
    /// `int`, `int32`.
    I32,
    /// `uint`, `uint32`.
    U32,
    /// `float`, `float32`.
    F32,
    /// `double`, `float64`.
    F64,
}

impl Scalar {
    /// The type a header names, or `None`.
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    /// The type's name in PLY 1.0 (`char`, `uchar`, ..., `double`).
    pub fn name(self) -> &'static str {
        match self {
            Self::I8 => "char",
            Self::U8 => "uchar",
            Self::I16 => "short",
            Self::U16 => "ushort",
            Self::I32 => "int",
            Self::U32 => "uint",
            Self::F32 => "float",
            Self::F64 => "double",
        }
    }

    /// Bytes of one binary value.
    pub fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// Whether this is one of the integer types.
    pub fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    /// The range of an integer type.
    fn range(self) -> (i64, i64) {
        match self {
            Self::I8 => (i8::MIN.into(), i8::MAX.into()),
            Self::U8 => (0, u8::MAX.into()),
            Self::I16 => (i16::MIN.into(), i16::MAX.into()),
            Self::U16 => (0, u16::MAX.into()),
            Self::I32 => (i32::MIN.into(), i32::MAX.into()),
            Self::U32 => (0, u32::MAX.into()),
            Self::F32 | Self::F64 => (i64::MIN, i64::MAX),
        }
    }

    /// Decodes one value from exactly `self.size()` bytes.
    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(b);
                if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            Self::I8 => f64::from(b[0] as i8),
            Self::U8 => f64::from(b[0]),
            Self::I16 => f64::from(num!(i16, 2)),
            Self::U16 => f64::from(num!(u16, 2)),
            Self::I32 => f64::from(num!(i32, 4)),
            Self::U32 => f64::from(num!(u32, 4)),
            Self::F32 => f64::from(num!(f32, 4)),
            Self::F64 => num!(f64, 8),
        }
    }

    /// Parses one ASCII token; `None` if it is not a value of this type. A float keeps the
    /// text's value (`f64`), so that a `float` column of 15-digit coordinates loses nothing;
    /// an integer must be a whole number (`7`, `7.0`, `7e0`) in its type's range.
    fn parse_token(self, token: &str) -> Option<f64> {
        let v: f64 = token.parse().ok()?;
        if !self.is_integer() {
            return Some(v);
        }
        let (lo, hi) = self.range();
        (v.fract() == 0.0 && v >= lo as f64 && v <= hi as f64).then_some(v)
    }
}

/// What a property holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// One value.
    Scalar(Scalar),
    /// A count of type `count`, then that many values of type `item`.
    List {
        /// The type of the count (an integer type).
        count: Scalar,
        /// The type of the items.
        item: Scalar,
    },
}

/// One property of an element.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Property {
    /// The name, as the header gives it.
    pub name: String,
    /// Scalar or list, and the types.
    pub kind: Kind,
}

/// One element: its name, the number of records the header announces, its properties.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Element {
    /// The name (`vertex`, `face`, ...).
    pub name: String,
    /// The number of records the header announces (not trusted for allocations).
    pub count: usize,
    /// The properties, in record order.
    pub properties: Vec<Property>,
}

impl Element {
    /// The index of the property named `name`.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }

    /// The index of the scalar property named `name`, `None` if there is none.
    ///
    /// # Errors
    /// [`PlyError::Syntax`] if `name` is a list.
    pub fn scalar(&self, name: &str) -> Result<Option<usize>, PlyError> {
        match self.find(name) {
            Some(i) if matches!(self.properties[i].kind, Kind::List { .. }) => Err(syntax(
                Place::Header(None),
                format!(
                    "{} property '{name}' is a list, expected a scalar",
                    self.name
                ),
            )),
            found => Ok(found),
        }
    }

    /// Where `x y z`, and the normal if the element has all three components (`nx ny nz`, or
    /// PCL's `normal_x normal_y normal_z`: [`NORMAL_NAMES`](super::NORMAL_NAMES)), are among
    /// the properties.
    ///
    /// # Errors
    /// [`PlyError::MissingProperty`] for a missing coordinate, or for a missing normal
    /// component when the others are there; [`PlyError::Syntax`] if one of them is a list.
    pub fn position_normal_slots(&self) -> Result<([usize; 3], Option<[usize; 3]>), PlyError> {
        let missing = |property| PlyError::MissingProperty {
            element: self.name.clone(),
            property,
        };
        let mut xyz = [0; 3];
        for (slot, name) in xyz.iter_mut().zip(POSITION_NAMES) {
            *slot = self.scalar(name)?.ok_or_else(|| missing(name))?;
        }
        match super::normal_columns(|name| self.find(name)) {
            Ok(None) => Ok((xyz, None)),
            Ok(Some((_, names))) => {
                let mut slots = [0; 3];
                for (slot, name) in slots.iter_mut().zip(names) {
                    *slot = self.scalar(name)?.ok_or_else(|| missing(name))?;
                }
                Ok((xyz, Some(slots)))
            }
            Err(name) => Err(missing(name)),
        }
    }
}

/// The coordinate property names.
const POSITION_NAMES: [&str; 3] = ["x", "y", "z"];

/// How the records are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// `format ascii 1.0`: one record per line.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

/// A parsed PLY header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    /// How the records are stored.
    pub encoding: Encoding,
    /// The elements, in file order.
    pub elements: Vec<Element>,
    /// The byte offset of the first record (just after `end_header`'s newline).
    pub body: usize,
    /// The number of header lines: the first record is on line `lines + 1`.
    pub lines: usize,
}

/// Where in a file something went wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Place {
    /// The header: a 1-based line, or the header as a whole.
    Header(Option<usize>),
    /// A record.
    Record {
        /// The element's name.
        element: String,
        /// The 0-based record index in its element.
        record: usize,
        /// The 1-based line (ASCII).
        line: Option<usize>,
        /// The byte offset of the record (binary).
        byte: Option<usize>,
    },
}

impl Place {
    /// The 1-based line, if known.
    pub fn line(&self) -> Option<usize> {
        match self {
            Place::Header(line) => *line,
            Place::Record { line, .. } => *line,
        }
    }
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::Header(Some(l)) => write!(f, "header line {l}"),
            Place::Header(None) => f.write_str("header"),
            Place::Record {
                element,
                record,
                line,
                byte,
            } => match (line, byte) {
                (Some(l), _) => write!(f, "line {l} ({element} {record})"),
                (None, Some(b)) => write!(f, "{element} {record} (byte {b})"),
                (None, None) => write!(f, "{element} {record}"),
            },
        }
    }
}

/// Why a PLY file cannot be read. The file's name is the caller's to add.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PlyError {
    /// The first line is not `ply`.
    #[error("not a PLY file (the first line is not 'ply')")]
    NotPly,
    /// The header or a record does not parse.
    #[error("{place}: {detail}")]
    Syntax {
        /// Where.
        place: Place,
        /// What is wrong.
        detail: String,
    },
    /// A valid PLY feature zeroset does not read (an unknown encoding or version).
    #[error("{place}: {detail}")]
    Unsupported {
        /// Where.
        place: Place,
        /// What is not supported.
        detail: String,
    },
    /// An element lacks a property the reader needs.
    #[error("the {element} element has no '{property}'")]
    MissingProperty {
        /// The element.
        element: String,
        /// The property.
        property: &'static str,
    },
    /// The file ends before the records its header announces.
    #[error("truncated: the file ends in {element} record {record} of the {expected} announced")]
    Truncated {
        /// The element being read.
        element: String,
        /// The 0-based record that is incomplete or missing.
        record: usize,
        /// The count the header announces.
        expected: usize,
    },
}

fn syntax(place: Place, detail: impl Into<String>) -> PlyError {
    PlyError::Syntax {
        place,
        detail: detail.into(),
    }
}

impl Header {
    /// Parses the header at the start of `bytes`; the records may follow or not.
    ///
    /// # Errors
    /// [`PlyError::NotPly`] if the first line is not `ply`; [`PlyError::Syntax`] naming the
    /// header line for anything malformed, a header that never reaches `end_header` included;
    /// [`PlyError::Unsupported`] for an encoding or version other than the three of PLY 1.0.
    pub fn parse(bytes: &[u8]) -> Result<Header, PlyError> {
        let mut pos = 0;
        let mut line_no = 0;
        let mut encoding = None;
        let mut elements: Vec<Element> = Vec::new();
        // The current element's property names: a header of 10⁵ properties is checked for
        // repeats in linear time.
        let mut names = std::collections::HashSet::new();
        loop {
            if pos >= bytes.len() {
                return Err(syntax(
                    Place::Header(Some(line_no + 1)),
                    "the file ends before 'end_header'",
                ));
            }
            let end = bytes[pos..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(bytes.len(), |i| pos + i);
            let raw = &bytes[pos..end];
            pos = (end + 1).min(bytes.len());
            line_no += 1;
            let place = Place::Header(Some(line_no));
            let Ok(line) = std::str::from_utf8(raw) else {
                if line_no == 1 {
                    return Err(PlyError::NotPly);
                }
                return Err(syntax(place, "the header line is not ASCII text"));
            };
            let line = line.trim_end_matches('\r');
            if line_no == 1 {
                if line.trim() != "ply" {
                    return Err(PlyError::NotPly);
                }
                continue;
            }
            let mut words = line.split_ascii_whitespace();
            match words.next().unwrap_or("") {
                "" | "comment" | "obj_info" => {}
                "format" => encoding = Some(parse_format(place, words)?),
                "element" => {
                    let (Some(name), Some(count), None) =
                        (words.next(), words.next(), words.next())
                    else {
                        return Err(syntax(place, "expected 'element <name> <count>'"));
                    };
                    let count = count.parse::<usize>().map_err(|_| {
                        syntax(
                            place,
                            format!("element count {count:?} is not a non-negative integer"),
                        )
                    })?;
                    elements.push(Element {
                        name: name.to_owned(),
                        count,
                        properties: Vec::new(),
                    });
                    names.clear();
                }
                "property" => {
                    let Some(element) = elements.last_mut() else {
                        return Err(syntax(place, "'property' before any 'element'"));
                    };
                    let property = parse_property(&place, words)?;
                    if !names.insert(property.name.clone()) {
                        return Err(syntax(
                            place,
                            format!(
                                "property '{}' repeated in element '{}'",
                                property.name, element.name
                            ),
                        ));
                    }
                    element.properties.push(property);
                }
                "end_header" => break,
                other => {
                    return Err(syntax(place, format!("unknown header keyword {other:?}")));
                }
            }
        }
        let Some(encoding) = encoding else {
            return Err(syntax(Place::Header(None), "no 'format' line"));
        };
        if let Some(e) = elements
            .iter()
            .find(|e| e.count > 0 && e.properties.is_empty())
        {
            return Err(syntax(
                Place::Header(None),
                format!(
                    "element '{}' has {} records but no property",
                    e.name, e.count
                ),
            ));
        }
        Ok(Header {
            encoding,
            elements,
            body: pos,
            lines: line_no,
        })
    }

    /// The element named `name`.
    pub fn element(&self, name: &str) -> Option<&Element> {
        self.elements.iter().find(|e| e.name == name)
    }
}

fn parse_format<'a>(
    place: Place,
    mut words: impl Iterator<Item = &'a str>,
) -> Result<Encoding, PlyError> {
    let name = words.next().unwrap_or("");
    let version = words.next().unwrap_or("");
    let encoding = match name {
        "ascii" => Encoding::Ascii,
        "binary_little_endian" => Encoding::BinaryLittleEndian,
        "binary_big_endian" => Encoding::BinaryBigEndian,
        _ => {
            return Err(PlyError::Unsupported {
                place,
                detail: format!(
                    "PLY encoding {name:?} (expected ascii, binary_little_endian or \
                     binary_big_endian)"
                ),
            });
        }
    };
    if version != "1.0" {
        return Err(PlyError::Unsupported {
            place,
            detail: format!("PLY version {version:?} (expected 1.0)"),
        });
    }
    Ok(encoding)
}

fn parse_property<'a>(
    place: &Place,
    words: impl Iterator<Item = &'a str>,
) -> Result<Property, PlyError> {
    let words: Vec<&str> = words.collect();
    let scalar = |t: &str| {
        Scalar::parse(t).ok_or_else(|| {
            syntax(
                place.clone(),
                format!(
                    "unknown property type {t:?} (expected char, uchar, short, ushort, int, \
                     uint, float, double or int8 ... float64)"
                ),
            )
        })
    };
    let (kind, name) = match words.as_slice() {
        ["list", count, item, name] => {
            let count = scalar(count)?;
            let item = scalar(item)?;
            if !count.is_integer() {
                return Err(syntax(
                    place.clone(),
                    format!("list count type of '{name}' must be an integer type"),
                ));
            }
            (Kind::List { count, item }, *name)
        }
        [t, name] if *t != "list" => (Kind::Scalar(scalar(t)?), *name),
        _ => {
            return Err(syntax(
                place.clone(),
                "expected 'property <type> <name>' or \
                 'property list <count type> <item type> <name>'",
            ));
        }
    };
    Ok(Property {
        name: name.to_owned(),
        kind,
    })
}

/// Reads the header of the PLY file at `path`, without its records: at most the first MiB of
/// the file is read, which holds any real header.
///
/// # Errors
/// The outer error when the file cannot be read; the inner one for a header that does not
/// parse ([`Header::parse`]).
pub fn read_header(path: impl AsRef<Path>) -> std::io::Result<Result<Header, PlyError>> {
    const MAX_HEADER: u64 = 1 << 20;
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(MAX_HEADER)
        .read_to_end(&mut bytes)?;
    Ok(Header::parse(&bytes))
}

/// One record's values, flattened: a scalar is one value, a list its count then its items.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Record {
    values: Vec<f64>,
    starts: Vec<usize>,
}

impl Record {
    /// The value of scalar property `p`.
    ///
    /// # Panics
    /// If `p` is out of range for the element read.
    pub fn scalar(&self, p: usize) -> f64 {
        self.values[self.starts[p]]
    }

    /// The items of list property `p`; empty if `p` is not a list property of the element
    /// last read successfully.
    pub fn list(&self, p: usize) -> &[f64] {
        let Some(&start) = self.starts.get(p) else {
            return &[];
        };
        let n = self.values.get(start).map_or(0, |&v| v as usize);
        self.values
            .get(start + 1..(start + 1).saturating_add(n))
            .unwrap_or(&[])
    }
}

/// The records after a [`Header`], read element by element in file order.
#[derive(Debug, Clone)]
pub struct Records<'a> {
    bytes: &'a [u8],
    pos: usize,
    encoding: Encoding,
    /// The 1-based line number of the line at `pos` (ASCII).
    line: usize,
}

impl<'a> Records<'a> {
    /// The records of the file `bytes`, whose header is `header`.
    pub fn new(header: &Header, bytes: &'a [u8]) -> Self {
        Records {
            bytes,
            pos: header.body.min(bytes.len()),
            encoding: header.encoding,
            line: header.lines + 1,
        }
    }

    /// How many records of `element` the bytes left can hold at most ([`records_that_fit`]):
    /// a binary record takes at least its scalars and list counts, an ASCII record at least
    /// two bytes (a digit and a separator) per property. Reserve room for this many, never
    /// for `element.count` itself.
    pub fn records_that_fit(&self, element: &Element) -> usize {
        let left = self.bytes.len() - self.pos;
        let (left, min_record) = match self.encoding {
            Encoding::Ascii => (left + 1, 2 * element.properties.len()),
            _ => (
                left,
                element
                    .properties
                    .iter()
                    .map(|p| match p.kind {
                        Kind::Scalar(t) | Kind::List { count: t, .. } => t.size(),
                    })
                    .sum(),
            ),
        };
        records_that_fit(element.count, left as u64, min_record)
    }

    /// How many records of `element` to reserve room for when each takes `bytes_each` bytes
    /// once read: [`Records::records_that_fit`], checked against the memory available
    /// ([`crate::limits`]). `what` names them in the error ("points of scan.ply").
    ///
    /// # Errors
    /// [`crate::Error::Memory`] (or `SizeOverflow`) naming the count and `what`.
    pub fn capacity(
        &self,
        element: &Element,
        bytes_each: usize,
        what: &str,
    ) -> crate::Result<usize> {
        let n = self.records_that_fit(element);
        crate::limits::check_alloc(&format!("the {n} {what}"), n, bytes_each)?;
        Ok(n)
    }

    /// Reads record `index` of `element` (the next record in the file) into `out`; returns
    /// its place, for messages about its values.
    ///
    /// # Errors
    /// [`PlyError::Truncated`] if the file ends first; [`PlyError::Syntax`] for a value that
    /// does not parse as its type, a negative list length, or a line with too few or too many
    /// values.
    pub fn read(
        &mut self,
        element: &Element,
        index: usize,
        out: &mut Record,
    ) -> Result<Place, PlyError> {
        out.values.clear();
        out.starts.clear();
        let truncated = || PlyError::Truncated {
            element: element.name.clone(),
            record: index,
            expected: element.count,
        };
        let place = |line, byte| Place::Record {
            element: element.name.clone(),
            record: index,
            line,
            byte,
        };
        if self.encoding == Encoding::Ascii {
            // The next non-blank line.
            let text = loop {
                let rest = &self.bytes[self.pos..];
                if rest.is_empty() {
                    return Err(truncated());
                }
                let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
                self.pos += (end + 1).min(rest.len());
                self.line += 1;
                if rest[..end].iter().any(|b| !b.is_ascii_whitespace()) {
                    break &rest[..end];
                }
            };
            let here = place(Some(self.line - 1), None);
            let Ok(text) = std::str::from_utf8(text) else {
                return Err(syntax(here, "the line is not ASCII text"));
            };
            let mut tokens = text.split_ascii_whitespace();
            let mut next = |name: &str, t: Scalar| -> Result<f64, PlyError> {
                let token = tokens.next().ok_or_else(|| {
                    syntax(here.clone(), format!("the line ends before '{name}'"))
                })?;
                t.parse_token(token).ok_or_else(|| {
                    syntax(
                        here.clone(),
                        format!(
                            "'{name}' = '{}' is not a valid {} value",
                            brief(token),
                            t.name()
                        ),
                    )
                })
            };
            // Each list item takes a value and a separator of the line.
            let room = |name: &str, n: f64, _: Scalar| {
                if n * 2.0 <= text.len() as f64 + 1.0 {
                    Ok(())
                } else {
                    Err(syntax(
                        here.clone(),
                        format!("list '{name}' announces {n} items, more than the line holds"),
                    ))
                }
            };
            read_properties(element, &here, out, &mut next, &room)?;
            if let Some(extra) = tokens.next() {
                return Err(syntax(
                    here,
                    format!(
                        "unexpected value '{}' after the record's last property",
                        brief(extra)
                    ),
                ));
            }
            Ok(here)
        } else {
            let here = place(None, Some(self.pos));
            let big = self.encoding == Encoding::BinaryBigEndian;
            let (bytes, pos) = (self.bytes, &mut self.pos);
            // The record cannot extend past the file.
            let left = bytes.len() - *pos;
            let mut take = |_: &str, t: Scalar| -> Result<f64, PlyError> {
                let n = t.size();
                let b = bytes.get(*pos..*pos + n).ok_or_else(truncated)?;
                *pos += n;
                Ok(t.decode(b, big))
            };
            let room = |_: &str, n: f64, item: Scalar| {
                if n * item.size() as f64 <= left as f64 {
                    Ok(())
                } else {
                    Err(truncated())
                }
            };
            read_properties(element, &here, out, &mut take, &room)?;
            Ok(here)
        }
    }
}

/// `token`, cut to 40 characters for a message.
fn brief(token: &str) -> String {
    match token.char_indices().nth(40) {
        Some((end, _)) => format!("{}...", &token[..end]),
        None => token.to_owned(),
    }
}

/// Reads the properties of one record with `next(name, type)`, one value at a time;
/// `room(name, n, item)` refuses a list of `n` items of type `item` that the rest of the
/// record cannot hold, before any item is read or stored.
fn read_properties(
    element: &Element,
    here: &Place,
    out: &mut Record,
    next: &mut impl FnMut(&str, Scalar) -> Result<f64, PlyError>,
    room: &impl Fn(&str, f64, Scalar) -> Result<(), PlyError>,
) -> Result<(), PlyError> {
    for p in &element.properties {
        out.starts.push(out.values.len());
        match p.kind {
            Kind::Scalar(t) => out.values.push(next(&p.name, t)?),
            Kind::List { count, item } => {
                let n = next(&p.name, count)?;
                if n < 0.0 {
                    return Err(syntax(
                        here.clone(),
                        format!("list '{}' has a negative length {n}", p.name),
                    ));
                }
                room(&p.name, n, item)?;
                out.values.push(n);
                // Never reserved from `n`: the items are read one by one.
                for _ in 0..n as usize {
                    out.values.push(next(&p.name, item)?);
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_first(header: &str, body: &str) -> Result<Record, PlyError> {
        let bytes = format!("{header}{body}").into_bytes();
        let h = Header::parse(&bytes)?;
        let mut records = Records::new(&h, &bytes);
        let mut record = Record::default();
        records.read(&h.elements[0], 0, &mut record)?;
        Ok(record)
    }

    const ONE: &str = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
                       property uchar red\nend_header\n";

    #[test]
    fn ascii_values_keep_the_text_precision_and_integers_must_be_whole() {
        // A georeferenced coordinate in a `float` column is not rounded to f32.
        let r = read_first(ONE, "4500000.37 255.0\n").unwrap();
        assert_eq!((r.scalar(0), r.scalar(1)), (4_500_000.37, 255.0));
        assert!(read_first(ONE, "1 1e2\n").is_ok());
        for bad in ["1 1.5\n", "1 256\n", "1 -1\n", "1 nan\n"] {
            let e = read_first(ONE, bad).unwrap_err();
            assert!(e.to_string().contains("not a valid uchar"), "{bad}: {e}");
        }
        // A huge token is cut in the message.
        let long = "9".repeat(10_000);
        let e = read_first(ONE, &format!("1 {long}\n")).unwrap_err();
        assert!(e.to_string().len() < 200, "{e}");
    }

    #[test]
    fn repeated_properties_are_found_in_a_long_header() {
        let mut header = String::from("ply\nformat ascii 1.0\nelement vertex 1\n");
        for i in 0..50_000 {
            header.push_str(&format!("property char p{i}\n"));
        }
        header.push_str("property char p7\nend_header\n");
        let e = Header::parse(header.as_bytes()).unwrap_err();
        assert!(e.to_string().contains("'p7' repeated"), "{e}");
        assert!(matches!(
            e,
            PlyError::Syntax {
                place: Place::Header(Some(50_004)),
                ..
            }
        ));
    }

    #[test]
    fn list_is_empty_rather_than_a_panic_for_a_wrong_property() {
        let r = read_first(
            "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int ids\nend_header\n",
            "2 7 8\n",
        )
        .unwrap();
        assert_eq!(r.list(0), &[7.0, 8.0]);
        assert!(r.list(1).is_empty());
        assert!(Record::default().list(0).is_empty());
    }

    #[test]
    fn a_list_longer_than_the_rest_of_the_file_is_refused_before_its_items_are_read() {
        // Binary: 2³² − 1 one-byte items announced, 1 MiB follows (read item by item, they
        // took 8 MiB as values before the file ran out).
        let header = "ply\nformat binary_little_endian 1.0\nelement junk 1\n\
                      property list uint uchar stuff\nend_header\n";
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend_from_slice(&u32::MAX.to_le_bytes());
        bytes.extend_from_slice(&[1; 1 << 20]);
        let h = Header::parse(&bytes).unwrap();
        let mut record = Record::default();
        let e = Records::new(&h, &bytes)
            .read(&h.elements[0], 0, &mut record)
            .unwrap_err();
        assert!(matches!(e, PlyError::Truncated { record: 0, .. }), "{e}");
        assert!(
            record.values.capacity() < 16,
            "{}",
            record.values.capacity()
        );
        // A list of 4 items is read.
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend_from_slice(&4u32.to_le_bytes());
        bytes.extend_from_slice(&[1, 2, 3, 4]);
        Records::new(&h, &bytes)
            .read(&h.elements[0], 0, &mut record)
            .unwrap();
        assert_eq!(record.list(0), &[1.0, 2.0, 3.0, 4.0]);
        // ASCII: a line of 3 items cannot hold the 1000 announced.
        let e = read_first(
            "ply\nformat ascii 1.0\nelement face 1\nproperty list uint int ids\nend_header\n",
            "1000 7 8 9\n",
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("announces 1000 items, more than the line holds"),
            "{e}"
        );
    }
}
