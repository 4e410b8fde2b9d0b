//! XYZ text: `x y z` or `x y z nx ny nz [...]` per line.

use std::io::{BufRead, BufReader};
use std::path::Path;

use super::{FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, malformed, open_nonempty};

/// Reads an XYZ text file; see the module table in [`super`].
///
/// A first data line holding a single non-negative integer (the point count that `.pts` files
/// start with) is skipped.
pub(super) fn read(path: &Path, check: &FiniteCheck<'_>) -> crate::Result<RawPoints> {
    let mut positions = Vec::new();
    let mut normals: Option<Vec<_>> = None;
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
        positions.push([values[0], values[1], values[2]]);
        if let Some(n) = normals.as_mut() {
            check.check(record, Some(line_no), &NORMAL_FIELDS, &values[3..6])?;
            n.push([values[3], values[4], values[5]]);
        }
        Ok(())
    })?;
    Ok((positions, normals))
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
    let mut line_no = 0;
    let mut values: Vec<f64> = Vec::with_capacity(8);
    loop {
        buf.clear();
        let n = reader
            .read_line(&mut buf)
            .map_err(|e| malformed(path, Some(line_no + 1), format!("cannot read line: {e}")))?;
        if n == 0 {
            return Ok(());
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

/// Whether a line is a lone non-negative integer such as `5210`.
fn is_count_header(content: &str) -> bool {
    let t = content.trim().trim_end_matches(',');
    !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit())
}
