//! The mutations: generic byte-level ones (bit flips, interesting bytes, random runs,
//! truncation, chunk deletion and duplication, splices) and format-aware ones (numbers in text
//! replaced by huge counts, NaN and infinity; header words swapped for other PLY or CSV
//! keywords; over-long lines; CRLF; invalid UTF-8; binary `u32`/`u64` fields set to huge
//! values; a `.zsf` file's sizes and CRC-32 resealed so that its payload decoder is reached).

use super::rng::SplitMix64;

/// The largest input produced: inputs stay under 1 MB, the size the acceptance bar is about.
pub const MAX_LEN: usize = 1_000_000 - 1;

const INTERESTING_BYTES: [u8; 8] = [0, 0xFF, 0x7F, 0x80, 0x01, b'\n', b' ', b'-'];

/// Numbers put in place of numbers in text.
pub const NUMBERS: [&str; 30] = [
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999",
    "-1",
    "-2147483649",
    "0",
    "-0",
    "1e308",
    "-1e308",
    "1e309",
    "1e-320",
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "infinity",
    "1.#INF",
    "0x10",
    "1_000",
    "",
    "3",
    "65536",
];

/// Words put in place of words: PLY keywords and types, CSV column names.
pub const WORDS: [&str; 46] = [
    "ply",
    "format",
    "ascii",
    "binary_little_endian",
    "binary_big_endian",
    "1.0",
    "2.0",
    "element",
    "vertex",
    "face",
    "edge",
    "property",
    "list",
    "char",
    "uchar",
    "int8",
    "uint8",
    "short",
    "ushort",
    "int",
    "uint",
    "int32",
    "uint32",
    "float",
    "float32",
    "double",
    "float64",
    "vertex_indices",
    "vertex_index",
    "end_header",
    "comment",
    "obj_info",
    "x",
    "y",
    "z",
    "nx",
    "ny",
    "nz",
    "X",
    "formation",
    "surface",
    "dip",
    "azimuth",
    "polarity",
    "value",
    "#",
];

fn is_num(b: u8) -> bool {
    b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'e' | b'E')
}

fn is_word(b: u8) -> bool {
    b.is_ascii_alphanumeric() || matches!(b, b'_' | b'.' | b'-' | b'+')
}

/// A position to work at: half the time in the first 512 bytes, where the headers are.
fn position(rng: &mut SplitMix64, len: usize) -> usize {
    if rng.next_u64() & 1 == 0 {
        rng.below(len.min(512))
    } else {
        rng.below(len)
    }
}

/// The span `[a, b)` of a token (per `class`) at or after `from`, searching at most 4 KiB.
fn token_at(
    data: &[u8],
    from: usize,
    class: fn(u8) -> bool,
    must_digit: bool,
) -> Option<(usize, usize)> {
    let end = data.len().min(from + 4096);
    let mut i = from;
    while i < end {
        let ok = if must_digit {
            data[i].is_ascii_digit()
        } else {
            data[i].is_ascii_alphabetic()
        };
        if ok {
            let mut a = i;
            while a > 0 && class(data[a - 1]) {
                a -= 1;
            }
            let mut b = i;
            while b < data.len() && class(data[b]) {
                b += 1;
            }
            return Some((a, b));
        }
        i += 1;
    }
    None
}

fn replace(data: &mut Vec<u8>, (a, b): (usize, usize), with: &[u8]) {
    data.splice(a..b, with.iter().copied());
}

/// The start of the line holding byte `i` and the end of it (excluding `\n`).
fn line_at(data: &[u8], i: usize) -> (usize, usize) {
    let a = data[..i]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |p| p + 1);
    let b = data[i..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(data.len(), |p| i + p);
    (a, b)
}

/// One mutation of `data`, with `other` for splices.
pub fn mutate_once(rng: &mut SplitMix64, data: &mut Vec<u8>, other: &[u8]) {
    if data.is_empty() {
        let n = 1 + rng.below(64);
        data.extend((0..n).map(|_| rng.next_u64() as u8));
        return;
    }
    let len = data.len();
    match rng.below(20) {
        0 => {
            // bit flips
            for _ in 0..1 + rng.below(4) {
                let i = position(rng, len);
                data[i] ^= 1 << rng.below(8);
            }
        }
        1 => {
            let i = position(rng, len);
            data[i] = INTERESTING_BYTES[rng.below(INTERESTING_BYTES.len())];
        }
        2 => {
            // a run of random bytes
            let i = position(rng, len);
            let n = (1 + rng.below(16)).min(len - i);
            for b in &mut data[i..i + n] {
                *b = rng.next_u64() as u8;
            }
        }
        3 => data.truncate(rng.below(len)),
        4 => {
            let a = rng.below(len);
            let b = (a + 1 + rng.below(256.min(len - a))).min(len);
            data.drain(a..b);
        }
        5 => {
            // duplicate a chunk somewhere
            let a = rng.below(len);
            let n = 1 + rng.below(256.min(len - a));
            let chunk = data[a..a + n].to_vec();
            let at = rng.below(len + 1);
            data.splice(at..at, chunk);
        }
        6 => {
            // splice: a prefix of this input, a suffix of the other
            if !other.is_empty() {
                let a = rng.below(len + 1);
                let b = rng.below(other.len());
                data.truncate(a);
                data.extend_from_slice(&other[b..]);
            }
        }
        7..=9 => {
            // a number in text
            let from = position(rng, len);
            if let Some(span) = token_at(data, from, is_num, true) {
                let n = NUMBERS[rng.below(NUMBERS.len())];
                replace(data, span, n.as_bytes());
            }
        }
        10 | 11 => {
            let from = position(rng, len);
            if let Some(span) = token_at(data, from, is_word, false) {
                let w = WORDS[rng.below(WORDS.len())];
                replace(data, span, w.as_bytes());
            }
        }
        12 => {
            // an over-long line (up to 300 kB)
            let i = position(rng, len);
            let n = 1000 << rng.below(9);
            let fill: &[u8] = match rng.below(4) {
                0 => b"1",
                1 => b" ",
                2 => b"1 ",
                _ => b",",
            };
            let run: Vec<u8> = fill.iter().copied().cycle().take(n).collect();
            data.splice(i..i, run);
        }
        13 => {
            // CRLF, or no newline at all
            let out: Vec<u8> = if rng.next_u64() & 1 == 0 {
                data.iter()
                    .flat_map(|&b| {
                        if b == b'\n' {
                            vec![b'\r', b'\n']
                        } else {
                            vec![b]
                        }
                    })
                    .collect()
            } else {
                data.iter()
                    .map(|&b| if b == b'\n' { b'\r' } else { b })
                    .collect()
            };
            *data = out;
        }
        14 => {
            // invalid UTF-8
            let i = position(rng, len + 1);
            let bad: &[u8] = match rng.below(3) {
                0 => &[0xFF, 0xFE],
                1 => &[0xC3],
                _ => &[0xE2, 0x82],
            };
            data.splice(i..i, bad.iter().copied());
        }
        15 | 16 => {
            // a binary u32/u64 field set to a huge value, little- or big-endian
            let wide = rng.next_u64() & 1 == 0;
            let w = if wide { 8 } else { 4 };
            if len >= w {
                let i = position(rng, len - w + 1) & !(if rng.next_u64() & 1 == 0 { 3 } else { 0 });
                let i = i.min(len - w);
                let v: u64 = match rng.below(8) {
                    0 => u64::MAX,
                    1 => 1 << 31,
                    2 => 1 << 32,
                    3 => (1 << 32) - 1,
                    4 => 1 << 63,
                    5 => 1 << 40,
                    6 => 0,
                    _ => rng.next_u64(),
                };
                let bytes = if wide {
                    if rng.next_u64() & 1 == 0 {
                        v.to_le_bytes()
                    } else {
                        v.to_be_bytes()
                    }
                    .to_vec()
                } else {
                    let v = v as u32;
                    if rng.next_u64() & 1 == 0 {
                        v.to_le_bytes()
                    } else {
                        v.to_be_bytes()
                    }
                    .to_vec()
                };
                data[i..i + w].copy_from_slice(&bytes);
            }
        }
        17 => {
            // a line repeated many times
            let i = rng.below(len);
            let (a, b) = line_at(data, i);
            let line = data[a..(b + 1).min(len)].to_vec();
            let copies = 1 + rng.below(2000);
            let mut rep = Vec::with_capacity(line.len() * copies);
            for _ in 0..copies {
                rep.extend_from_slice(&line);
                if rep.len() > 200_000 {
                    break;
                }
            }
            data.splice(a..a, rep);
        }
        18 => {
            // a line deleted
            let i = rng.below(len);
            let (a, b) = line_at(data, i);
            data.drain(a..(b + 1).min(len));
        }
        _ => {
            // a float in binary: NaN, ±inf, huge, subnormal
            if len >= 8 {
                let i = rng.below(len - 7);
                let v = [
                    f64::NAN,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    1e308,
                    5e-324,
                    -0.0,
                ][rng.below(6)];
                if rng.next_u64() & 1 == 0 {
                    data[i..i + 8].copy_from_slice(&v.to_le_bytes());
                } else {
                    data[i..i + 4].copy_from_slice(&(v as f32).to_le_bytes());
                }
            }
        }
    }
}

/// The checksums a format keeps, which a mutated input usually gets repaired so that the
/// mutation reaches the decoder behind them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seal {
    /// None.
    None,
    /// A `.zsf` field file's sizes and trailing CRC-32 ([`fix_zsf_sizes`], [`reseal_zsf`]).
    Zsf,
    /// An E57 file's page checksums ([`reseal_e57`]).
    E57,
    /// Whichever of the above the input's signature names (inputs of any format, as
    /// `zeroset info` reads them).
    Any,
}

/// `data` mutated 1–6 times (stacked, as AFL's havoc stage does), kept under [`MAX_LEN`]; an
/// input of a format with checksums (`seal`) usually gets them repaired afterwards.
pub fn mutate(rng: &mut SplitMix64, data: &[u8], other: &[u8], seal: Seal) -> Vec<u8> {
    let mut out = data.to_vec();
    let most = if rng.next_u64() & 3 == 0 { 6 } else { 2 };
    let n = 1 + rng.below(most);
    for _ in 0..n {
        mutate_once(rng, &mut out, other);
        out.truncate(MAX_LEN);
    }
    let r = rng.below(10);
    // Each repair leaves an input without its format's signature as it is.
    if matches!(seal, Seal::Zsf | Seal::Any) {
        if r < 5 {
            fix_zsf_sizes(&mut out);
        }
        if r < 9 {
            reseal_zsf(&mut out);
        }
    }
    if matches!(seal, Seal::E57 | Seal::Any) && r < 9 {
        reseal_e57(&mut out);
    }
    out
}

/// The page size of E57 files (ASTM E2807 §7: the last 4 bytes of each page are its CRC-32C).
const E57_PAGE: usize = 1024;

/// Recomputes the checksum of every whole page of an E57 file (CRC-32C of its first 1020
/// bytes, stored big-endian in its last 4, as libE57Format writes it).
pub fn reseal_e57(data: &mut [u8]) {
    if !data.starts_with(b"ASTM-E57") {
        return;
    }
    for page in data.chunks_exact_mut(E57_PAGE) {
        let crc = crc32c(&page[..E57_PAGE - 4]);
        page[E57_PAGE - 4..].copy_from_slice(&crc.to_be_bytes());
    }
}

/// Sets a version-2 `.zsf` header's payload length to what the file holds (keeping the
/// metadata length), so that a length change reaches the payload decoder.
pub fn fix_zsf_sizes(data: &mut [u8]) {
    if data.len() < 40 || &data[..8] != b"ZSFIELD\0" || data[8..12] != 2u32.to_le_bytes() {
        return;
    }
    let meta = u32::from_le_bytes(data[24..28].try_into().unwrap()) as usize;
    if let Some(payload) = data
        .len()
        .checked_sub(36 + 4)
        .and_then(|n| n.checked_sub(meta))
    {
        data[28..36].copy_from_slice(&(payload as u64).to_le_bytes());
    }
}

/// Rewrites the CRC-32 at the end of a `.zsf` file (magic present) over the bytes before it.
pub fn reseal_zsf(data: &mut [u8]) {
    let n = data.len();
    if n < 16 || &data[..8] != b"ZSFIELD\0" {
        return;
    }
    let crc = crc32(&data[..n - 4]);
    data[n - 4..].copy_from_slice(&crc.to_le_bytes());
}

/// CRC-32 (IEEE), by table: the root package does not depend on `crc32fast`.
pub fn crc32(bytes: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    reflected_crc(bytes, TABLE.get_or_init(|| crc_table(0xEDB8_8320)))
}

/// CRC-32C (Castagnoli), E57's page checksum.
pub fn crc32c(bytes: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    reflected_crc(bytes, TABLE.get_or_init(|| crc_table(0x82F6_3B78)))
}

/// The byte table of the reflected CRC-32 of polynomial `poly` (bit-reversed).
fn crc_table(poly: u32) -> [u32; 256] {
    std::array::from_fn(|i| {
        let mut c = i as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { poly ^ (c >> 1) } else { c >> 1 };
        }
        c
    })
}

/// A reflected CRC-32 by `table` (initial and final value all ones).
fn reflected_crc(bytes: &[u8], table: &[u32; 256]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c = table[((c ^ b as u32) & 0xFF) as usize] ^ (c >> 8);
    }
    !c
}
