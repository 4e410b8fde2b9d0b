//! XYZ text: `x y z` or `x y z nx ny nz [...]` per line.
//!
//! Columns 4–6 carry no names, and `x y z r g b` files (colours) are common: they are read as
//! normals only if they look like normals ([`NormalColumns`]).

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
/// to the fits, which name it.
pub const NORMAL_LENGTHS: (f64, f64) = (0.5, 2.0);

/// Reads an XYZ text file; see the module table in [`super`].
///
/// A first data line holding a single non-negative integer (the point count that `.pts` files
/// start with) is skipped.
pub(super) fn read(
    path: &Path,
    check: &FiniteCheck<'_>,
    check_normals: bool,
) -> crate::Result<RawPoints> {
    let mut positions = Vec::new();
    let mut normals: Option<Vec<_>> = None;
    let what = format!("the points of {}", path.display());
    let mut normal_columns = NormalColumns::default();
    // Column count and the line that set it.
    let mut columns: Option<(usize, usize)> = None;
    for_each_number_line(path, |line_no, values, content| {
        let (count, since) = match columns {
            Some(c) => c,
            None => {
                let count = values.len();
                if count == 1 && positions.is_empty() && is_count_header(content) {
                    return Ok(());
                }
                if count != 3 && count < 6 {
                    return Err(malformed(
                        path,
                        Some(line_no),
                        format!("expected 3 or 6 numbers (x y z [nx ny nz]), found {count}"),
                    ));
                }
                if count >= 6 {
                    normals = Some(Vec::new());
                }
                columns = Some((count, line_no));
                (count, line_no)
            }
        };
        if values.len() != count {
            return Err(malformed(
                path,
                Some(line_no),
                format!(
                    "expected {count} numbers as on line {since}, found {}",
                    values.len()
                ),
            ));
        }
        let record = positions.len();
        check.check(record, Some(line_no), &POSITION_FIELDS, &values[..3])?;
        crate::limits::grow(&mut positions, 1, &what)?;
        positions.push([values[0], values[1], values[2]]);
        if let Some(n) = normals.as_mut() {
            check.check(record, Some(line_no), &NORMAL_FIELDS, &values[3..6])?;
            let normal = [values[3], values[4], values[5]];
            normal_columns.see(record, line_no, &normal);
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

/// Calls `line` with the 1-based line number, the numbers and the text before any `#` of every
/// line of `path` that holds at least one number. Numbers are separated by whitespace or
/// commas; `#` starts a comment; a leading byte-order mark is skipped. A token that is not a
/// number is an error naming the line and column.
pub(super) fn for_each_number_line(
    path: &Path,
    mut line: impl FnMut(usize, &[f64], &str) -> crate::Result<()>,
) -> crate::Result<()> {
    let (file, _) = open_nonempty(path)?;
    let mut reader = BufReader::new(file);
    let mut buf = String::new();
    // A line is read at most MAX_LINE bytes at a time: a file without line breaks (a binary
    // file given by mistake, a corrupted one) does not become one string the size of the file.
    let limit = MAX_LINE as u64 + 1;
    let mut line_no = 0;
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
        values.clear();
        for token in content
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
        {
            let value = super::parse_number(token).ok_or_else(|| {
                malformed(
                    path,
                    Some(line_no),
                    format!("not a number: '{token}' (column {})", values.len() + 1),
                )
            })?;
            values.push(value);
        }
        if !values.is_empty() {
            line(line_no, &values, content)?;
        }
    }
}

/// The longest line the text readers take, in bytes (1 MiB).
pub(super) const MAX_LINE: usize = 1 << 20;

/// Whether a line is a lone non-negative integer such as `5210`.
fn is_count_header(content: &str) -> bool {
    let t = content.trim().trim_end_matches(',');
    !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit())
}
