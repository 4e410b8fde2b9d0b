//! Output files of the timing examples, written atomically through field-core.

#![allow(dead_code)] // each example uses what it writes

use std::path::Path;

use zeroset::core::io::write_atomic;

/// Writes raw little-endian f64 values (read them with `numpy.fromfile`).
pub fn write_f64(
    path: &Path,
    values: impl IntoIterator<Item = f64>,
) -> Result<(), zeroset::core::Error> {
    let bytes: Vec<u8> = values.into_iter().flat_map(f64::to_le_bytes).collect();
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes `text` (a CSV table).
pub fn write_text(path: &Path, text: &str) -> Result<(), zeroset::core::Error> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}
