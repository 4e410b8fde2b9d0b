//! NumPy `.npy` files of little-endian `f64` (`'<f8'`), C order, shared by the examples that hand
//! arrays to the peer scripts in `benches/peers` (`numpy.load(path)` reads them as they are).
//!
//! Writing produces format version 1.0: the magic `\x93NUMPY`, version bytes `1 0`, a
//! little-endian `u16` header length, then the header — a Python dict literal such as
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (100, 3), }` — padded with spaces and ended
//! by `\n` so that the data starts at a multiple of 64 bytes, then the values, little-endian, last
//! index fastest. Reading accepts versions 1.0, 2.0 and 3.0 (`u32` header length) but only the
//! dtype `'<f8'` in C order; anything else is an `InvalidData` error. Only what `numpy.save`
//! writes is parsed (no general Python-literal parser).

#![allow(dead_code)] // each example uses what it needs

use std::io::{BufWriter, Read, Write};
use std::path::Path;

const MAGIC: &[u8; 6] = b"\x93NUMPY";
/// The data offset (magic + version + length + header) is a multiple of this.
const ALIGN: usize = 64;

fn invalid(msg: impl Into<String>) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidData, msg.into())
}

/// The shape as NumPy writes it: `()`, `(n,)`, `(a, b)`, ….
fn shape_literal(shape: &[usize]) -> String {
    match shape {
        [] => "()".to_string(),
        [n] => format!("({n},)"),
        _ => {
            let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
            format!("({})", dims.join(", "))
        }
    }
}

/// Writes `data` (C order, last index fastest) as an array of shape `shape`, dtype `'<f8'`.
///
/// Fails with `InvalidInput` if `data.len()` is not the product of `shape` (1 for `[]`).
pub fn write_npy(path: &Path, shape: &[usize], data: &[f64]) -> std::io::Result<()> {
    let count = shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "shape overflows"))?;
    if count != data.len() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "write_npy: shape {shape:?} has {count} elements, data has {}",
                data.len()
            ),
        ));
    }
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': {}, }}",
        shape_literal(shape)
    );
    // magic (6) + version (2) + header length (2) + header + '\n' ≡ 0 (mod 64)
    let unpadded = MAGIC.len() + 2 + 2 + header.len() + 1;
    header.extend(std::iter::repeat_n(' ', (ALIGN - unpadded % ALIGN) % ALIGN));
    header.push('\n');
    let header_len = u16::try_from(header.len()).map_err(|_| {
        std::io::Error::new(std::io::ErrorKind::InvalidInput, "npy header too long")
    })?;

    let mut out = BufWriter::with_capacity(1 << 20, std::fs::File::create(path)?);
    out.write_all(MAGIC)?;
    out.write_all(&[1, 0])?;
    out.write_all(&header_len.to_le_bytes())?;
    out.write_all(header.as_bytes())?;
    for chunk in data.chunks(8192) {
        let bytes: Vec<u8> = chunk.iter().flat_map(|v| v.to_le_bytes()).collect();
        out.write_all(&bytes)?;
    }
    out.flush()
}

/// The text after `'key':` in the header dict, leading spaces removed.
fn header_value<'a>(header: &'a str, key: &str) -> std::io::Result<&'a str> {
    for quote in ['\'', '"'] {
        let pat = format!("{quote}{key}{quote}");
        if let Some(i) = header.find(&pat) {
            let rest = header[i + pat.len()..].trim_start();
            let rest = rest
                .strip_prefix(':')
                .ok_or_else(|| invalid(format!("npy header: no ':' after {key}: {header}")))?;
            return Ok(rest.trim_start());
        }
    }
    Err(invalid(format!("npy header: no key {key}: {header}")))
}

/// Reads an `.npy` file of dtype `'<f8'` in C order; returns its shape and its values (C order).
pub fn read_npy(path: &Path) -> std::io::Result<(Vec<usize>, Vec<f64>)> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)?.read_to_end(&mut bytes)?;
    let name = path.display();
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err(invalid(format!("{name}: not an .npy file")));
    }
    let (header_start, header_len) = match bytes[6] {
        1 => (10, u16::from_le_bytes([bytes[8], bytes[9]]) as usize),
        2 | 3 if bytes.len() >= 12 => (
            12,
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
        ),
        v => {
            return Err(invalid(format!(
                "{name}: unsupported .npy version {v}.{}",
                bytes[7]
            )));
        }
    };
    let data_start = header_start + header_len;
    if bytes.len() < data_start {
        return Err(invalid(format!("{name}: truncated header")));
    }
    let header = std::str::from_utf8(&bytes[header_start..data_start])
        .map_err(|_| invalid(format!("{name}: header is not text")))?;

    let descr = header_value(header, "descr")?;
    let descr = descr
        .get(1..)
        .and_then(|d| d.split(['\'', '"']).next())
        .unwrap_or("");
    if descr != "<f8" {
        return Err(invalid(format!(
            "{name}: dtype {descr:?}, only '<f8' is supported"
        )));
    }
    if !header_value(header, "fortran_order")?.starts_with("False") {
        return Err(invalid(format!("{name}: Fortran order is not supported")));
    }
    let shape_text = header_value(header, "shape")?;
    let inner = shape_text
        .strip_prefix('(')
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| invalid(format!("{name}: cannot parse shape in {header}")))?;
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('L').parse::<usize>())
        .collect::<Result<Vec<_>, _>>()
        .map_err(|_| invalid(format!("{name}: cannot parse shape in {header}")))?;

    let count = shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| invalid(format!("{name}: shape overflows")))?;
    let data = &bytes[data_start..];
    if data.len() != count * 8 {
        return Err(invalid(format!(
            "{name}: shape {shape:?} needs {} data bytes, file has {}",
            count * 8,
            data.len()
        )));
    }
    let values = data
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
        .collect();
    Ok((shape, values))
}
