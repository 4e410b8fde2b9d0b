//! Resource limits: the one check every allocation sized from input goes through first.
//!
//! A count read from a file header, a grid given on the command line or a rank chosen by a
//! fit is never trusted for an allocation. Before a buffer sized by it is made, it is checked
//!
//! - against the **input's real size** ([`check_count`]): a count announced by a file must fit
//!   in the bytes that remain, so a corrupted count in a 1 KB file is an error, not a
//!   multi-gigabyte `Vec::with_capacity`;
//! - against **arithmetic** ([`check_alloc`]): `count × bytes_per_item` is computed with checked
//!   arithmetic, and an overflow is an error;
//! - against **available memory** ([`check_alloc`], [`check_bytes`]): the machine's
//!   `MemAvailable` (Linux, `/proc/meminfo`, read once and cached), or the cap in the
//!   environment variable [`MEMORY_LIMIT_ENV`] (`ZEROSET_MEMORY_LIMIT`: bytes, or a size such
//!   as `512MiB`, `4G`, `1.5GB`), whichever is smaller. Where neither is known, only the
//!   largest single allocation (`isize::MAX`) is checked.
//!
//! The errors name what needed the memory, how much and how much there is, so a request the
//! machine cannot hold fails at once with a message instead of aborting the process:
//!
//! ```
//! use zeroset_field_core::limits::{Limit, check_alloc_within, check_count};
//!
//! // 10⁹ samples of 8 bytes with a 4 GiB cap.
//! let e = check_alloc_within("the grid 1000×1000×1000", 1_000_000_000, 8, Limit::Cap(4 << 30))
//!     .unwrap_err();
//! assert_eq!(
//!     e.to_string(),
//!     "the grid 1000×1000×1000 needs about 7.5 GiB of memory, more than the 4.0 GiB allowed \
//!      by ZEROSET_MEMORY_LIMIT"
//! );
//! // A header announcing 2³² records of at least 12 bytes, 1000 bytes left in the file.
//! assert!(check_count("vertex records", 1 << 32, 12, 1000).is_err());
//! assert_eq!(check_count("vertex records", 80, 12, 1000).unwrap(), 80);
//! ```

use std::sync::OnceLock;

use crate::error::{Error, Result};
use crate::memory::{self, MemoryError};

/// The environment variable that caps the memory zeroset assumes it may use, in bytes or
/// with a unit: `1073741824`, `1GiB`, `1 G`, `512MiB`, `1.5GB` (`K`, `M`, `G`, `T` and
/// `KiB`… are powers of 1024, `KB`, `MB`, `GB`, `TB` powers of 1000). Empty: no cap.
pub const MEMORY_LIMIT_ENV: &str = "ZEROSET_MEMORY_LIMIT";

/// The memory an allocation is checked against, and where that number comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limit {
    /// Nothing is known (not Linux, no cap): only the largest single allocation is checked.
    Unknown,
    /// The machine's available memory (`MemAvailable`), or a budget a caller gives, in bytes.
    Machine(u64),
    /// The cap set by [`MEMORY_LIMIT_ENV`], in bytes (smaller than what the machine has).
    Cap(u64),
}

impl Limit {
    /// The limit in bytes, `None` for [`Limit::Unknown`].
    pub fn bytes(self) -> Option<u64> {
        match self {
            Limit::Unknown => None,
            Limit::Machine(b) | Limit::Cap(b) => Some(b),
        }
    }
}

/// The machine's available memory (`MemAvailable`, Linux), read once and cached for the life of
/// the process; `None` where it cannot be read.
pub fn machine_available() -> Option<u64> {
    static MACHINE: OnceLock<Option<u64>> = OnceLock::new();
    *MACHINE.get_or_init(memory::available)
}

/// Parses a size: a non-negative number of bytes, optionally with a unit (case-insensitive,
/// spaces allowed before it): `B`; `K`, `M`, `G`, `T`, `KiB`, `MiB`, `GiB`, `TiB` (powers of
/// 1024); `KB`, `MB`, `GB`, `TB` (powers of 1000). `None` for anything else.
///
/// ```
/// use zeroset_field_core::limits::parse_size;
/// assert_eq!(parse_size("4096"), Some(4096));
/// assert_eq!(parse_size("2 GiB"), Some(2 << 30));
/// assert_eq!(parse_size("1.5k"), Some(1536));
/// assert_eq!(parse_size("3GB"), Some(3_000_000_000));
/// assert_eq!(parse_size("lots"), None);
/// ```
pub fn parse_size(text: &str) -> Option<u64> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let multiplier: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" => 1024.0,
        "m" | "mib" => 1024.0 * 1024.0,
        "g" | "gib" => 1024.0 * 1024.0 * 1024.0,
        "t" | "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "tb" => 1e12,
        _ => return None,
    };
    if number.is_empty() {
        return None;
    }
    if !number.contains('.')
        && let Ok(n) = number.parse::<u64>()
    {
        return n.checked_mul(multiplier as u64);
    }
    let value: f64 = number.parse().ok()?;
    let bytes = (value * multiplier).round();
    (bytes.is_finite() && bytes < u64::MAX as f64).then_some(bytes as u64)
}

/// The limit in force: the cap of [`MEMORY_LIMIT_ENV`] where it is set and below what the
/// machine has, else the machine's available memory ([`machine_available`]).
///
/// # Errors
/// [`Error::InvalidMemoryLimit`] where the variable is set to something that is not a size.
pub fn current_limit() -> Result<Limit> {
    let machine = machine_available();
    let from_machine = machine.map_or(Limit::Unknown, Limit::Machine);
    let Some(value) = std::env::var_os(MEMORY_LIMIT_ENV) else {
        return Ok(from_machine);
    };
    let text = value.to_string_lossy();
    if text.trim().is_empty() {
        return Ok(from_machine);
    }
    let cap = parse_size(&text).ok_or_else(|| Error::InvalidMemoryLimit {
        value: text.to_string(),
    })?;
    Ok(match machine {
        Some(m) if m < cap => Limit::Machine(m),
        _ => Limit::Cap(cap),
    })
}

/// The memory available in bytes, as [`current_limit`] has it (`None`: unknown). A malformed
/// [`MEMORY_LIMIT_ENV`] is ignored here (the machine's figure is used); the `check_*`
/// functions report it.
pub fn available() -> Option<u64> {
    current_limit()
        .unwrap_or_else(|_| machine_available().map_or(Limit::Unknown, Limit::Machine))
        .bytes()
}

/// `count × bytes_per_item` in bytes, `None` where it overflows 64 bits.
pub fn bytes_for(count: usize, bytes_per_item: usize) -> Option<u64> {
    (count as u64).checked_mul(bytes_per_item as u64)
}

/// Refuses an allocation of `count` items of `bytes_per_item` bytes each that overflows, is
/// larger than any allocation can be, or is more than the memory available
/// ([`current_limit`]). `what` names the buffer in the message ("the grid 512×512×512",
/// "the dense RBF system of 10⁶ unknowns").
///
/// # Errors
/// [`Error::SizeOverflow`], [`Error::Memory`] naming `what`, the amount and the limit, or
/// [`Error::InvalidMemoryLimit`].
pub fn check_alloc(what: &str, count: usize, bytes_per_item: usize) -> Result<()> {
    check_alloc_within(what, count, bytes_per_item, current_limit()?)
}

/// [`check_alloc`] against a given `limit` (no environment, no machine): for tests and for
/// callers with a budget of their own.
///
/// # Errors
/// As [`check_alloc`], but for the environment.
pub fn check_alloc_within(
    what: &str,
    count: usize,
    bytes_per_item: usize,
    limit: Limit,
) -> Result<()> {
    let bytes = bytes_for(count, bytes_per_item).ok_or_else(|| Error::SizeOverflow {
        what: what.to_owned(),
        count: count as u64,
        bytes_each: bytes_per_item as u64,
    })?;
    check_bytes_within(what, bytes, limit)
}

/// Refuses `bytes` bytes for `what` when they are more than any allocation can hold or more
/// than the memory available ([`current_limit`]).
///
/// # Errors
/// [`Error::Memory`] naming `what`, the amount and the limit, or
/// [`Error::InvalidMemoryLimit`].
pub fn check_bytes(what: &str, bytes: u64) -> Result<()> {
    check_bytes_within(what, bytes, current_limit()?)
}

/// [`check_bytes`] against a given `limit`.
///
/// # Errors
/// [`Error::Memory`].
pub fn check_bytes_within(what: &str, bytes: u64, limit: Limit) -> Result<()> {
    memory_error(what, bytes, limit).map_or(Ok(()), |e| Err(Error::Memory(e)))
}

/// The [`MemoryError`] for `bytes` bytes of `what` under `limit`, `None` where they fit: for
/// crates whose error type carries a [`MemoryError`] rather than a field-core [`Error`].
pub fn memory_error(what: &str, bytes: u64, limit: Limit) -> Option<MemoryError> {
    let mut e = memory::ensure(bytes, limit.bytes(), what).err()?;
    e.capped = e.available.is_some() && matches!(limit, Limit::Cap(_));
    Some(e)
}

/// Refuses a count announced by an input (a file header, a length field) that the `remaining`
/// bytes of that input cannot hold, each item taking at least `min_bytes_each` bytes; returns
/// the count as a `usize`. Call it before reserving room for, or looping over, the items: the
/// allocation that follows is then bounded by the input's size.
///
/// # Errors
/// [`Error::ExceedsInput`] naming `what`, the count and the bytes.
pub fn check_count(what: &str, count: u64, min_bytes_each: u64, remaining: u64) -> Result<usize> {
    let fits = count
        .checked_mul(min_bytes_each)
        .is_some_and(|need| need <= remaining);
    match usize::try_from(count) {
        Ok(n) if fits => Ok(n),
        _ => Err(Error::ExceedsInput {
            what: what.to_owned(),
            count,
            min_bytes: min_bytes_each,
            remaining,
        }),
    }
}

/// Makes room in `v` for `additional` more items, checking the grown buffer (amortised
/// doubling) with [`check_alloc`] first and reserving without aborting on failure: for vectors
/// that grow record by record while an input is read.
///
/// # Errors
/// As [`check_alloc`]; [`Error::Memory`] where the allocator refuses.
pub fn grow<T>(v: &mut Vec<T>, additional: usize, what: &str) -> Result<()> {
    if v.capacity() - v.len() >= additional {
        return Ok(());
    }
    let item = std::mem::size_of::<T>().max(1);
    let needed = v.len().checked_add(additional);
    let doubled = needed
        .map(|n| n.max(v.capacity().saturating_mul(2)).max(8))
        .unwrap_or(usize::MAX);
    // Doubling keeps pushes amortised; near the limit, just what is needed.
    let target = match (check_alloc(what, doubled, item), needed) {
        (Ok(()), _) => doubled,
        (Err(_), Some(exact)) if exact < doubled => {
            check_alloc(what, exact, item)?;
            exact
        }
        (Err(e), _) => return Err(e),
    };
    v.try_reserve_exact(target - v.len()).map_err(|_| {
        Error::Memory(MemoryError {
            what: what.to_owned(),
            needed: bytes_for(target, item).unwrap_or(u64::MAX),
            available: available(),
            capped: false,
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overflow_is_an_error_naming_the_count() {
        let e = check_alloc_within("coefficients", usize::MAX / 2, 16, Limit::Unknown).unwrap_err();
        assert!(matches!(e, Error::SizeOverflow { .. }), "{e}");
        let text = e.to_string();
        assert!(
            text.starts_with("coefficients: ") && text.contains("overflow"),
            "{text}"
        );
        assert_eq!(bytes_for(usize::MAX, 2), None);
        assert_eq!(bytes_for(3, 8), Some(24));
    }

    #[test]
    fn the_largest_allocation_is_checked_without_any_limit() {
        assert!(check_alloc_within("x", 1 << 20, 8, Limit::Unknown).is_ok());
        let e = check_alloc_within("a grid", 1 << 62, 4, Limit::Unknown).unwrap_err();
        assert!(
            e.to_string().contains("more than any allocation can hold"),
            "{e}"
        );
    }

    #[test]
    fn messages_name_what_how_much_and_the_limit() {
        let e = check_alloc_within(
            "the dense RBF system",
            100_000,
            800_000,
            Limit::Machine(22 << 30),
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "the dense RBF system needs about 74.5 GiB of memory, more than the 22.0 GiB available"
        );
        let e = check_bytes_within("the grid", 3 << 30, Limit::Cap(1 << 30)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the grid needs about 3.0 GiB of memory, more than the 1.0 GiB allowed by \
             ZEROSET_MEMORY_LIMIT"
        );
        let Error::Memory(m) = e else { panic!() };
        assert!(m.capped);
        assert_eq!((m.needed, m.available), (3 << 30, Some(1 << 30)));
        assert!(check_bytes_within("the grid", 1 << 30, Limit::Cap(1 << 30)).is_ok());
    }

    #[test]
    fn counts_are_checked_against_the_bytes_left() {
        assert_eq!(check_count("cells", 10, 16, 160).unwrap(), 10);
        let e = check_count("cells", 11, 16, 160).unwrap_err();
        assert_eq!(
            e.to_string(),
            "cells: 11 announced, which need at least 176 bytes (16 each), but only 160 bytes \
             remain: the input is corrupt or truncated"
        );
        assert!(check_count("cells", u64::MAX, 2, u64::MAX).is_err());
        assert_eq!(check_count("empty", 0, 8, 0).unwrap(), 0);
        let e = check_count("huge", u64::MAX, 1 << 20, 10).unwrap_err();
        assert!(
            e.to_string().contains("which need at least 1.9e25 bytes"),
            "{e}"
        );
    }

    #[test]
    fn sizes_parse_with_and_without_units() {
        assert_eq!(parse_size("0"), Some(0));
        assert_eq!(parse_size(" 1024 "), Some(1024));
        assert_eq!(parse_size("1GiB"), Some(1 << 30));
        assert_eq!(parse_size("1 g"), Some(1 << 30));
        assert_eq!(parse_size("512MiB"), Some(512 << 20));
        assert_eq!(parse_size("2.5 GB"), Some(2_500_000_000));
        assert_eq!(parse_size("1e9"), None);
        assert_eq!(parse_size("-1"), None);
        assert_eq!(parse_size("GiB"), None);
        assert_eq!(parse_size("99999999999 TiB"), None);
    }

    #[test]
    fn the_environment_cap_applies() {
        // The variable is process-wide: this test only reads it, as the test run set it (or
        // not). A run with ZEROSET_MEMORY_LIMIT=1MiB checks the cap end to end.
        match std::env::var(MEMORY_LIMIT_ENV)
            .ok()
            .as_deref()
            .and_then(parse_size)
        {
            Some(cap) => {
                let limit = current_limit().unwrap();
                assert!(limit.bytes().is_some_and(|b| b <= cap), "{limit:?}");
                assert!(check_alloc("too much", usize::try_from(cap).unwrap(), 2).is_err());
            }
            None => assert_eq!(
                current_limit().ok(),
                Some(machine_available().map_or(Limit::Unknown, Limit::Machine))
            ),
        }
    }

    #[test]
    fn growing_checks_the_doubled_buffer() {
        let mut v: Vec<u64> = Vec::new();
        grow(&mut v, 1, "points").unwrap();
        assert!(v.capacity() >= 8);
        for i in 0..100 {
            grow(&mut v, 1, "points").unwrap();
            v.push(i);
        }
        let e = grow(&mut v, usize::MAX, "points").unwrap_err();
        assert!(
            matches!(e, Error::SizeOverflow { .. } | Error::Memory(_)),
            "{e}"
        );
    }
}
