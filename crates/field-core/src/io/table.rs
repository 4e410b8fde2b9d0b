//! CSV with a header row, shared by plain point tables and GemPy tables.

use std::fs::File;
use std::path::{Path, PathBuf};

use csv::{ErrorKind, StringRecord, Trim};

use super::{FiniteCheck, NORMAL_FIELDS, POSITION_FIELDS, RawPoints, malformed, open_nonempty};
use crate::error::{Error, Result};

/// A CSV file being read row by row, with its header trimmed.
pub(super) struct Table {
    path: PathBuf,
    header: Vec<String>,
    delimiter: u8,
    reader: csv::Reader<File>,
    records: usize,
}

/// One data row.
pub(super) struct Row {
    /// 0-based index among data rows.
    pub(super) record: usize,
    /// 1-based line where the row starts.
    pub(super) line: usize,
    fields: StringRecord,
}

impl Table {
    /// Opens a CSV file and reads its header; `#` lines are comments, fields are trimmed, and
    /// every row must have as many fields as the header. The fields are separated by commas,
    /// or by semicolons or tabs where the header holds more of those ([`sniff_delimiter`]).
    pub(super) fn open(path: &Path) -> Result<Self> {
        let delimiter = sniff_delimiter(path)?;
        let (file, _) = open_nonempty(path)?;
        let mut reader = csv::ReaderBuilder::new()
            .delimiter(delimiter)
            .has_headers(true)
            .trim(Trim::All)
            .comment(Some(b'#'))
            .flexible(false)
            .from_reader(file);
        let header = reader
            .headers()
            .map_err(|e| csv_error(path, e))?
            .iter()
            .enumerate()
            // Spreadsheets often start UTF-8 files with a byte-order mark.
            .map(|(i, h)| {
                if i == 0 {
                    h.trim_start_matches('\u{feff}')
                } else {
                    h
                }
            })
            .map(|h| h.trim().to_owned())
            .collect();
        Ok(Self {
            path: path.to_owned(),
            header,
            delimiter,
            reader,
            records: 0,
        })
    }

    /// The file.
    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// The trimmed column names.
    pub(super) fn header(&self) -> &[String] {
        &self.header
    }

    /// The first column named (case-insensitively) by one of `names`, in the order of `names`.
    pub(super) fn find(&self, names: &[&str]) -> Option<usize> {
        find_column(&self.header, names)
    }

    /// [`Table::find`], or [`Error::MissingColumn`] naming `column`.
    pub(super) fn require(&self, names: &[&str], column: &str) -> Result<usize> {
        self.find(names).ok_or_else(|| self.missing(column))
    }

    /// [`Error::MissingColumn`] for `column`, quoting the header.
    pub(super) fn missing(&self, column: &str) -> Error {
        Error::MissingColumn {
            path: self.path.clone(),
            column: column.to_owned(),
            header: self.header.join(","),
        }
    }

    /// The next data row, or `None` at the end.
    pub(super) fn next_row(&mut self) -> Result<Option<Row>> {
        let mut fields = StringRecord::new();
        let more = self
            .reader
            .read_record(&mut fields)
            .map_err(|e| csv_error(&self.path, e))?;
        if !more {
            return Ok(None);
        }
        let line = fields
            .position()
            .map_or(0, |p| usize::try_from(p.line()).unwrap_or(usize::MAX));
        let record = self.records;
        self.records += 1;
        Ok(Some(Row {
            record,
            line,
            fields,
        }))
    }

    /// The text in column `col` of `row`.
    pub(super) fn text<'r>(&self, row: &'r Row, col: usize) -> &'r str {
        row.fields.get(col).unwrap_or_default()
    }

    /// The number in column `col` of `row`; NaN and infinities parse (the caller checks them).
    pub(super) fn number(&self, row: &Row, col: usize) -> Result<f64> {
        let text = self.text(row, col);
        let name = &self.header[col];
        if text.is_empty() {
            return Err(malformed(
                &self.path,
                Some(row.line),
                format!("empty value in column '{name}'"),
            ));
        }
        super::parse_number(text).ok_or_else(|| {
            // Spreadsheets in many locales write `1,5` with `;` between fields.
            // In a comma-separated file such a field was quoted.
            let numeric = text
                .bytes()
                .all(|b| b.is_ascii_digit() || matches!(b, b',' | b'.' | b'-' | b'+'));
            let hint = if text.contains(',') && (self.delimiter != b',' || numeric) {
                " (decimal commas are not read: export the numbers with decimal points)"
            } else {
                ""
            };
            malformed(
                &self.path,
                Some(row.line),
                format!("not a number in column '{name}': '{text}'{hint}"),
            )
        })
    }

    /// Reads columns `cols` of `row` as numbers.
    pub(super) fn numbers<const N: usize>(&self, row: &Row, cols: [usize; N]) -> Result<[f64; N]> {
        let mut out = [0.0; N];
        for (o, c) in out.iter_mut().zip(cols) {
            *o = self.number(row, c)?;
        }
        Ok(out)
    }
}

/// The first column of `header` named (case-insensitively) by one of `names`.
pub(super) fn find_column(header: &[String], names: &[&str]) -> Option<usize> {
    names
        .iter()
        .find_map(|n| header.iter().position(|h| h.eq_ignore_ascii_case(n)))
}

/// The field separator of a CSV file: `;` or a tab where its first line that is not blank or
/// a `#` comment holds more of it than of commas (and of the other), outside double quotes,
/// else `,`.
fn sniff_delimiter(path: &Path) -> Result<u8> {
    use std::io::{BufRead, BufReader, Read};
    let (file, _) = open_nonempty(path)?;
    let mut reader = BufReader::new(file).take(super::xyz::MAX_LINE as u64);
    let mut line = Vec::new();
    loop {
        line.clear();
        let n = reader
            .read_until(b'\n', &mut line)
            .map_err(|e| malformed(path, None, format!("cannot read the header: {e}")))?;
        let text = line.trim_ascii();
        if n == 0 || !(text.is_empty() || text.starts_with(b"#")) {
            break;
        }
    }
    // Separators inside a quoted name (`"note; a"`) do not count.
    let mut quoted = false;
    let outside: Vec<u8> = line
        .iter()
        .filter(|&&b| {
            quoted ^= b == b'"';
            !quoted && b != b'"'
        })
        .copied()
        .collect();
    let count = |byte: u8| outside.iter().filter(|&&b| b == byte).count();
    Ok([b',', b';', b'\t']
        .into_iter()
        .max_by_key(|&byte| (count(byte), byte == b','))
        .unwrap_or(b','))
}

/// The trimmed header of a CSV file.
pub(super) fn read_header(path: &Path) -> Result<Vec<String>> {
    Ok(Table::open(path)?.header)
}

/// Maps a `csv` error to [`Error::Io`] or [`Error::Malformed`] with the line.
fn csv_error(path: &Path, e: csv::Error) -> Error {
    let line = e
        .position()
        .map(|p| usize::try_from(p.line()).unwrap_or(usize::MAX));
    let reason = match e.kind() {
        ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => format!("found {len} fields, expected {expected_len} as in the header"),
        ErrorKind::Utf8 { err, .. } => format!("invalid UTF-8 in field {}", err.field() + 1),
        ErrorKind::Io(_) => match e.into_kind() {
            ErrorKind::Io(source) => {
                return Error::Io {
                    path: path.to_owned(),
                    source,
                };
            }
            _ => unreachable!("kind checked above"),
        },
        _ => e.to_string(),
    };
    malformed(path, line, reason)
}

/// Reads a CSV point table: columns `x y z` and optionally the normal (`nx ny nz` or
/// `normal_x normal_y normal_z`, [`NORMAL_NAMES`](super::NORMAL_NAMES); or GemPy's gradient
/// `G_x G_y G_z` where none of those is there; any case).
pub(super) fn read_xyz_table(path: &Path, check: &FiniteCheck<'_>) -> Result<RawPoints> {
    let mut table = Table::open(path)?;
    let pos = [
        table.require(&["x"], "x")?,
        table.require(&["y"], "y")?,
        table.require(&["z"], "z")?,
    ];
    const GRADIENT: [&str; 3] = ["G_x", "G_y", "G_z"];
    let (nrm, normal_names) = match super::normal_columns(|name| table.find(&[name])) {
        Ok(None) => match GRADIENT.map(|name| table.find(&[name])) {
            [Some(a), Some(b), Some(c)] => (Some([a, b, c]), GRADIENT),
            _ => (None, NORMAL_FIELDS),
        },
        Ok(found) => (
            found.map(|(columns, _)| columns),
            found.map_or(NORMAL_FIELDS, |(_, names)| names),
        ),
        Err(name) => return Err(table.missing(name)),
    };
    let mut positions = Vec::new();
    let mut normals = nrm.map(|_| Vec::new());
    let what = format!("the points of {}", path.display());
    while let Some(row) = table.next_row()? {
        let p = table.numbers(&row, pos)?;
        check.check(row.record, Some(row.line), &POSITION_FIELDS, &p)?;
        crate::limits::grow(&mut positions, 1, &what)?;
        positions.push(p);
        if let (Some(cols), Some(normals)) = (nrm, normals.as_mut()) {
            let n = table.numbers(&row, cols)?;
            check.check(row.record, Some(row.line), &normal_names, &n)?;
            crate::limits::grow(normals, 1, &what)?;
            normals.push(n);
        }
    }
    Ok((positions, normals))
}
