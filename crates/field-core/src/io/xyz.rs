//! XYZ text: `x y z` or `x y z nx ny nz [...]` per line, or columns named by a first line.
//!
//! Columns 4–6 carry no names, and `x y z r g b` files (colours) are common: they are read as
//! normals only if they look like normals ([`NormalColumns`]). A first line of names (`x y z
//! r g b nx ny nz`, or CloudCompare's `//X,Y,Z,R,G,B,Nx,Ny,Nz`) says where the coordinates
//! and the normal are instead ([`Layout::named`]).

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::{FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, malformed, open_nonempty};
use crate::cloud::CloudStats;
use crate::error::Error;
use crate::geometry::{Point3, norm};

/// The lengths columns 4–6 of an xyz file may have to be read as normals, `[1/2, 2]` (the ends
/// to print precision, [`CloudStats::UNIT_TOLERANCE`] relative).
///
/// Printed unit normals are unit to within print precision (the bundled samples: 1 ± 1e-6);
/// normals a factor of two off are still clearly directions, and the fits scale every normal
/// to unit length (the RBF constraints and the tangent-plane field both normalise), so they
/// are read as they are. Lengths further from 1 are refused: such columns are seldom normals
/// (colours, intensities, curvatures), and guessing would fit garbage. A zero normal is left
/// to the fits, which name it. Columns a header line names `nx ny nz` are read as they are.
pub const NORMAL_LENGTHS: (f64, f64) = (0.5, 2.0);

/// Where a file's coordinates and normal are, and how many numbers each line holds.
#[derive(Debug, Clone, Copy)]
struct Layout {
    /// The numbers on every line.
    count: usize,
    /// The line that set `count` (the header line, or the first line of numbers).
    since: usize,
    /// The columns of `x y z`.
    position: [usize; 3],
    /// The columns of the normal, if the file has one.
    normal: Option<[usize; 3]>,
    /// The normal's names as a header line gives them (for errors; `nx ny nz` without one).
    normal_names: [&'static str; 3],
    /// Whether a header line named the columns (its normals are read as they are).
    named: bool,
}

impl Layout {
    /// The layout a header line's `names` give (matched in any case): `x y z` required, the
    /// normal if [`NORMAL_NAMES`](super::NORMAL_NAMES) has a set named whole, other columns
    /// ignored.
    fn named(path: &Path, line: usize, names: &[&str]) -> crate::Result<Self> {
        let find = |name: &str| names.iter().position(|n| n.eq_ignore_ascii_case(name));
        let listed = || names.join(" ");
        let mut position = [0; 3];
        for (column, name) in position.iter_mut().zip(POSITION_FIELDS) {
            *column = find(name).ok_or_else(|| {
                malformed(
                    path,
                    Some(line),
                    format!(
                        "the header line names no column '{name}' (names: {}); name the \
                         coordinates x y z",
                        listed()
                    ),
                )
            })?;
        }
        let normal = super::normal_columns(find).map_err(|name| {
            malformed(
                path,
                Some(line),
                format!(
                    "the header line names part of a normal but no column '{name}' (names: {})",
                    listed()
                ),
            )
        })?;
        Ok(Self {
            count: names.len(),
            since: line,
            position,
            normal: normal.map(|(columns, _)| columns),
            normal_names: normal.map_or(NORMAL_FIELDS, |(_, names)| names),
            named: true,
        })
    }

    /// The layout of a file without a header line, from its first line's `count` numbers: `x
    /// y z` first; columns 4–6 the normal if there are at least 6 (checked to look like
    /// normals); a fourth and fifth column alone (an intensity, a label) ignored.
    fn unnamed(path: &Path, line: usize, count: usize) -> crate::Result<Self> {
        if count < 3 {
            return Err(malformed(
                path,
                Some(line),
                format!("expected at least 3 numbers (x y z [nx ny nz]), found {count}"),
            ));
        }
        Ok(Self {
            count,
            since: line,
            position: [0, 1, 2],
            normal: (count >= 6).then_some([3, 4, 5]),
            normal_names: NORMAL_FIELDS,
            named: false,
        })
    }
}

/// Reads an XYZ text file; see the module table in [`super`].
///
/// A first line of names (no number on it; a leading `//` dropped) names the columns
/// ([`Layout::named`]). A first data line holding a single non-negative integer (the point
/// count that `.pts` files start with) is skipped.
pub(super) fn read(
    path: &Path,
    check: &FiniteCheck<'_>,
    check_normals: bool,
) -> crate::Result<RawPoints> {
    let mut positions = Vec::new();
    let mut normals: Option<Vec<_>> = None;
    let what = format!("the points of {}", path.display());
    let mut normal_columns = NormalColumns::default();
    let mut layout: Option<Layout> = None;
    for_each_number_line(path, true, |line_no, line| {
        let (values, content) = match line {
            TextLine::Names(names) => {
                let named = Layout::named(path, line_no, names)?;
                normals = named.normal.map(|_| Vec::new());
                layout = Some(named);
                return Ok(());
            }
            TextLine::Numbers(values, content) => (values, content),
        };
        if values.len() == 1 && positions.is_empty() && is_count_header(content) {
            return Ok(());
        }
        let layout = match layout {
            Some(layout) => layout,
            None => {
                let first = Layout::unnamed(path, line_no, values.len())?;
                normals = first.normal.map(|_| Vec::new());
                *layout.insert(first)
            }
        };
        if values.len() != layout.count {
            let since = if layout.named {
                format!("one per name on line {}", layout.since)
            } else {
                format!("as on line {}", layout.since)
            };
            return Err(malformed(
                path,
                Some(line_no),
                format!(
                    "expected {} numbers ({since}), found {}",
                    layout.count,
                    values.len()
                ),
            ));
        }
        let record = positions.len();
        let position = layout.position.map(|c| values[c]);
        check.check(record, Some(line_no), &POSITION_FIELDS, &position)?;
        crate::limits::grow(&mut positions, 1, &what)?;
        positions.push(position);
        if let (Some(n), Some(columns)) = (normals.as_mut(), layout.normal) {
            let normal = columns.map(|c| values[c]);
            check.check(record, Some(line_no), &layout.normal_names, &normal)?;
            if !layout.named {
                normal_columns.see(record, line_no, &normal);
            }
            crate::limits::grow(n, 1, &what)?;
            n.push(normal);
        }
        Ok(())
    })?;
    if check_normals {
        normal_columns.check(path)?;
    }
    Ok((positions, normals))
}

/// What columns 4–6 of an xyz file look like, seen record by record: RGB colours when every
/// value is a whole number from 0 to 255 and one is at least 2 (unit normals with whole
/// components lie on the axes: 0 and ±1), otherwise normals if every finite non-zero length
/// lies in [`NORMAL_LENGTHS`].
#[derive(Debug, Clone, Copy)]
struct NormalColumns {
    /// Every value so far is a whole number from 0 to 255.
    colour_like: bool,
    /// The first record with a value of at least 2: `(record, line, values)`.
    first_large: Option<(usize, usize, Point3)>,
    /// The first record whose finite, non-zero length lies outside [`NORMAL_LENGTHS`].
    first_off_length: Option<(usize, usize, Point3)>,
}

impl Default for NormalColumns {
    fn default() -> Self {
        Self {
            colour_like: true,
            first_large: None,
            first_off_length: None,
        }
    }
}

impl NormalColumns {
    /// Takes record `record` (on line `line`) with columns 4–6 `n`.
    fn see(&mut self, record: usize, line: usize, n: &Point3) {
        self.colour_like &= n
            .iter()
            .all(|v| v.fract() == 0.0 && (0.0..=255.0).contains(v));
        if self.first_large.is_none() && n.iter().any(|v| *v >= 2.0) {
            self.first_large = Some((record, line, *n));
        }
        let length = norm(n);
        // The ends themselves count as inside, to print precision.
        let (low, high) = NORMAL_LENGTHS;
        let slack = CloudStats::<3>::UNIT_TOLERANCE;
        if self.first_off_length.is_none()
            && length.is_finite()
            && length > 0.0
            && !(low * (1.0 - slack)..=high * (1.0 + slack)).contains(&length)
        {
            self.first_off_length = Some((record, line, *n));
        }
    }

    /// [`Error::NotNormals`] unless the columns seen look like normals.
    fn check(&self, path: &Path) -> crate::Result<()> {
        let (found, colours) = match (self.colour_like, self.first_large) {
            (true, Some(large)) => (Some(large), true),
            _ => (self.first_off_length, false),
        };
        match found {
            None => Ok(()),
            Some((record, line, values)) => Err(Error::NotNormals {
                path: path.to_owned(),
                line,
                record,
                values,
                colours,
            }),
        }
    }
}

/// A line of a text file that holds something: numbers, or (first, where asked for) names.
pub(super) enum TextLine<'a> {
    /// The first line's names, where it holds no number ([`for_each_number_line`]).
    Names(&'a [&'a str]),
    /// The numbers of a line, and its text before any `#`.
    Numbers(&'a [f64], &'a str),
}

/// Calls `line` with the 1-based line number and the content of every line of `path` that
/// holds something. Numbers are separated by whitespace, commas or semicolons (a line holding
/// both of the last two is refused: decimal commas are not read); `#` starts a comment; a
/// leading byte-order mark is skipped. With `names_first`, a first such line that does not
/// start with a number is a line of names ([`TextLine::Names`]; a leading `//` dropped, split
/// at commas, semicolons or tabs where it has them, else at whitespace). Any other token that
/// is not a number is an error naming the line and column.
pub(super) fn for_each_number_line(
    path: &Path,
    names_first: bool,
    mut line: impl FnMut(usize, TextLine<'_>) -> crate::Result<()>,
) -> crate::Result<()> {
    let (file, _) = open_nonempty(path)?;
    let mut reader = BufReader::new(file);
    let mut buf = String::new();
    // A line is read at most MAX_LINE bytes at a time: a file without line breaks (a binary
    // file given by mistake, a corrupted one) does not become one string the size of the file.
    let limit = MAX_LINE as u64 + 1;
    let mut line_no = 0;
    let mut first = true;
    let mut values: Vec<f64> = Vec::with_capacity(8);
    loop {
        buf.clear();
        let n = (&mut reader)
            .take(limit)
            .read_line(&mut buf)
            .map_err(|e| malformed(path, Some(line_no + 1), format!("cannot read line: {e}")))?;
        if n == 0 {
            return Ok(());
        }
        if n > MAX_LINE {
            return Err(malformed(
                path,
                Some(line_no + 1),
                format!("line longer than {MAX_LINE} bytes: not a text file of numbers"),
            ));
        }
        line_no += 1;
        let text = if line_no == 1 {
            buf.trim_start_matches('\u{feff}')
        } else {
            &buf
        };
        let content = text.split('#').next().unwrap_or_default();
        let mut tokens = content
            .split(|c: char| c.is_whitespace() || c == ',' || c == ';')
            .filter(|t| !t.is_empty())
            .peekable();
        let Some(&head) = tokens.peek() else {
            continue;
        };
        let was_first = std::mem::replace(&mut first, false);
        // A name starts with a letter, `_` or a quote (`1e`, `-` or `.` are mistyped numbers).
        let named = content.trim_start().starts_with("//")
            || head.starts_with(|c: char| c.is_alphabetic() || c == '_' || c == '"');
        if names_first && was_first && named && super::parse_number(head).is_none() {
            let names = header_names(content);
            line(line_no, TextLine::Names(&names))?;
            continue;
        }
        if content.contains(';') && content.contains(',') {
            return Err(malformed(
                path,
                Some(line_no),
                "both ',' and ';' on one line: decimal commas are not read (export the numbers \
                 with decimal points)",
            ));
        }
        if has_decimal_comma(content) {
            return Err(malformed(
                path,
                Some(line_no),
                "numbers separated by spaces hold commas between digits (`0,5 1,25`): decimal \
                 commas are not read (export the numbers with decimal points)",
            ));
        }
        values.clear();
        for token in tokens {
            let value = super::parse_number(token).ok_or_else(|| {
                malformed(
                    path,
                    Some(line_no),
                    format!("not a number: '{token}' (column {})", values.len() + 1),
                )
            })?;
            values.push(value);
        }
        line(line_no, TextLine::Numbers(&values, content))?;
    }
}

/// Whether a line separated by whitespace has a word that reads as one number with a decimal
/// comma: exactly one comma, between two digits, and no decimal point. `0,5 1,25 2` is three
/// numbers, not five; `1,2,3`, `1, 2, 3`, `0,0,0, 0,0,1` and `1.5,2.5 3` are lists.
fn has_decimal_comma(content: &str) -> bool {
    let mut words = content.split_whitespace();
    let (Some(_), Some(_)) = (words.next(), words.next()) else {
        return false;
    };
    content.split_whitespace().any(|word| {
        let b = word.as_bytes();
        let commas: Vec<usize> = (0..b.len()).filter(|&i| b[i] == b',').collect();
        match commas[..] {
            [i] => {
                i > 0
                    && i + 1 < b.len()
                    && b[i - 1].is_ascii_digit()
                    && b[i + 1].is_ascii_digit()
                    && !word.contains('.')
            }
            _ => false,
        }
    })
}

/// The names of a header line: a leading `//` dropped (CloudCompare writes one), split at
/// commas, semicolons or tabs where the line has any (a name may hold a space; an empty name,
/// such as a pandas index column's, is a column too, except after a trailing separator), else
/// at whitespace; each trimmed.
fn header_names(content: &str) -> Vec<&str> {
    let content = content.trim();
    let content = content.strip_prefix("//").unwrap_or(content);
    let separators = [',', ';', '\t'];
    if content.contains(separators) {
        let mut names: Vec<&str> = content
            .split(separators)
            .map(|n| n.trim().trim_matches('"'))
            .collect();
        while names.last().is_some_and(|n| n.is_empty()) {
            names.pop();
        }
        names
    } else {
        content
            .split_whitespace()
            .map(|n| n.trim_matches('"'))
            .collect()
    }
}

/// The longest line the text readers take, in bytes (1 MiB).
pub(super) const MAX_LINE: usize = 1 << 20;

/// Whether a line is a lone non-negative integer such as `5210`.
fn is_count_header(content: &str) -> bool {
    let t = content.trim().trim_end_matches(',');
    !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit())
}
