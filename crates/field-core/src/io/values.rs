//! Value constraints in text: `x y value` (2-D) or `x y z value` (3-D), one per line.
//!
//! The format of the constraint files that `zeroset fit --method rbf` and `--method neural`
//! read for curves (and for 3-D value constraints without normals):
//!
//! | extension | per line | dimension |
//! |---|---|---|
//! | `.xyv` | `x y value` | 2 |
//! | `.xyzv` | `x y z value` | 3 |
//!
//! Numbers are separated by whitespace, commas or semicolons; `#` starts a comment (to the end of the
//! line); blank lines are skipped; every data line holds exactly `D + 1` numbers. Values follow
//! zeroset's convention — negative inside, 0 on the curve or surface, positive outside —
//! e.g. −1 inside, 0 on, +1 outside. Errors name the file and the 1-based line: a token that is
//! not a number, a wrong count, a NaN or infinite coordinate or value
//! ([`Error::NonFinite`](crate::Error::NonFinite), field `x`, `y`, `z` or `value`), and a file
//! with no constraint.
//!
//! ```no_run
//! use zeroset_field_core::io::read_value_points;
//!
//! // curve.xyv:  # on the curve (0), inside (-1), outside (+1)
//! //             0.6 0.0 0
//! //             0.2 0.0 -1
//! //             0.9 0.0 1
//! let c = read_value_points::<2>("curve.xyv")?;
//! println!("{} constraints", c.points.len());
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```

use std::path::Path;

use super::xyz::{TextLine, for_each_number_line};
use super::{FiniteCheck, malformed};
use crate::error::Result;
use crate::geometry::Point;

/// Points with prescribed values, in file order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ValuePoints<const D: usize> {
    /// The points.
    pub points: Vec<Point<D>>,
    /// The value prescribed at each point.
    pub values: Vec<f64>,
    /// The line of the file each point is on (1-based), for messages.
    pub lines: Vec<usize>,
}

/// The dimension a value-constraint file holds, from its extension (case-insensitive):
/// `.xyv` → 2, `.xyzv` → 3, anything else `None`.
pub fn value_file_dimension(path: impl AsRef<Path>) -> Option<usize> {
    let ext = path.as_ref().extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "xyv" => Some(2),
        "xyzv" => Some(3),
        _ => None,
    }
}

const FIELDS: [&str; 4] = ["x", "y", "z", "value"];

/// Reads a file of `D`-dimensional value constraints (see the [module docs](self)).
///
/// # Errors
/// [`Error::Io`](crate::Error::Io) if the file cannot be read;
/// [`Error::Malformed`](crate::Error::Malformed) naming the line for a token that is not a
/// number or a line without `D + 1` numbers, and for a file without a constraint;
/// [`Error::NonFinite`](crate::Error::NonFinite) naming the record, line and field.
pub fn read_value_points<const D: usize>(path: impl AsRef<Path>) -> Result<ValuePoints<D>> {
    let path = path.as_ref();
    let check = FiniteCheck { path, allow: false };
    let names: Vec<&'static str> = FIELDS[..D.min(3)]
        .iter()
        .copied()
        .chain(["value"])
        .collect();
    let mut out = ValuePoints::default();
    let what = format!("the constraints of {}", path.display());
    for_each_number_line(path, false, |line, text| {
        let TextLine::Numbers(values, _) = text else {
            return Ok(());
        };
        if values.len() != D + 1 {
            let want = names.join(" ");
            return Err(malformed(
                path,
                Some(line),
                format!(
                    "expected {} numbers ({want}), found {}",
                    D + 1,
                    values.len()
                ),
            ));
        }
        check.check(out.points.len(), Some(line), &names, values)?;
        crate::limits::grow(&mut out.points, 1, &what)?;
        crate::limits::grow(&mut out.values, 1, &what)?;
        crate::limits::grow(&mut out.lines, 1, &what)?;
        out.points.push(std::array::from_fn(|a| values[a]));
        out.values.push(values[D]);
        out.lines.push(line);
        Ok(())
    })?;
    if out.points.is_empty() {
        return Err(malformed(path, None, "the file holds no constraint"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;

    fn file(name: &str, text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        (dir, p)
    }

    #[test]
    fn reads_both_dimensions_with_comments() {
        let (_d, p) = file(
            "c.xyv",
            "# header\n0.5 0 0\n\n0.1, 0.0, -1 # inside\n 1 1 1\n",
        );
        let c = read_value_points::<2>(&p).unwrap();
        assert_eq!(c.points, vec![[0.5, 0.0], [0.1, 0.0], [1.0, 1.0]]);
        assert_eq!(c.values, vec![0.0, -1.0, 1.0]);
        let (_d, p) = file("c.xyzv", "1 2 3 -0.5\n");
        let c = read_value_points::<3>(&p).unwrap();
        assert_eq!((c.points, c.values), (vec![[1.0, 2.0, 3.0]], vec![-0.5]));
        assert_eq!(value_file_dimension("a/b.XYV"), Some(2));
        assert_eq!(value_file_dimension("b.xyzv"), Some(3));
        assert_eq!(value_file_dimension("b.xyz"), None);
    }

    #[test]
    fn errors_name_the_file_and_line() {
        let (_d, p) = file("bad.xyv", "0 0 0\n1 2\n");
        let e = read_value_points::<2>(&p).unwrap_err().to_string();
        assert!(
            e.contains("bad.xyv:2") && e.contains("expected 3 numbers (x y value)"),
            "{e}"
        );
        let (_d, p) = file("nan.xyv", "0 0 0\n# c\n1 2 nan\n");
        match read_value_points::<2>(&p).unwrap_err() {
            Error::NonFinite {
                record,
                line,
                field,
                ..
            } => assert_eq!((record, line, field), (1, Some(3), "value")),
            e => panic!("{e}"),
        }
        let (_d, p) = file("word.xyv", "0 zero 0\n");
        let e = read_value_points::<2>(&p).unwrap_err().to_string();
        assert!(e.contains("word.xyv:1") && e.contains("'zero'"), "{e}");
        let (_d, p) = file("none.xyv", "# nothing\n\n");
        let e = read_value_points::<2>(&p).unwrap_err().to_string();
        assert!(e.contains("no constraint"), "{e}");
        let (_d, p) = file("empty.xyv", "");
        assert!(read_value_points::<2>(&p).is_err());
        assert!(matches!(
            read_value_points::<2>("/nonexistent/x.xyv").unwrap_err(),
            Error::Io { .. }
        ));
    }
}
