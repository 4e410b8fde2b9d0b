//! How much memory the machine has for one allocation, checked before large dense work (an RBF
//! system matrix, a sampled grid) so that a request the machine cannot hold gets an error that
//! names the amount instead of aborting the process on a failed allocation.
//!
//! ```
//! use zeroset_field_core::memory::{MemoryError, ensure, format_bytes};
//!
//! assert_eq!(format_bytes(3 << 30), "3.0 GiB");
//! assert!(ensure(1024, Some(1 << 20), "a small buffer").is_ok());
//! let e = ensure(2 << 30, Some(1 << 30), "the dense solve").unwrap_err();
//! assert_eq!(e.to_string(), "the dense solve needs about 2.0 GiB of memory, more than the 1.0 GiB available");
//! ```

/// A request for more memory than the machine (or one allocation) can hold.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{what} needs about {} of memory, more than {}", format_bytes(*.needed), limit_text(*.available, *.capped))]
pub struct MemoryError {
    /// What needed it, as the message shows it.
    pub what: String,
    /// Bytes needed.
    pub needed: u64,
    /// Bytes available (`None`: the limit was the largest single allocation, `isize::MAX`).
    pub available: Option<u64>,
    /// Whether `available` is the cap set by
    /// [`MEMORY_LIMIT_ENV`](crate::limits::MEMORY_LIMIT_ENV) rather than what the machine has.
    pub capped: bool,
}

fn limit_text(available: Option<u64>, capped: bool) -> String {
    match available {
        Some(a) if capped => format!(
            "the {} allowed by {}",
            format_bytes(a),
            crate::limits::MEMORY_LIMIT_ENV
        ),
        Some(a) => format!("the {} available", format_bytes(a)),
        None => "any allocation can hold".to_owned(),
    }
}

/// `MemAvailable` from `/proc/meminfo`, in bytes; `None` where it cannot be read (not Linux).
/// Read afresh on every call; checks before an allocation go through
/// [`limits`](crate::limits), which reads it once and applies the `ZEROSET_MEMORY_LIMIT` cap.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// Refuses `needed` bytes when that is more than one allocation can hold (`isize::MAX`) or
/// more than `available` (the machine's, from [`available`], where the caller has no budget of
/// its own; `None`: only the first limit is checked).
///
/// # Errors
/// [`MemoryError`] naming `what`, the amount needed and the limit.
pub fn ensure(needed: u64, available: Option<u64>, what: &str) -> Result<(), MemoryError> {
    let limit = u64::try_from(isize::MAX).unwrap_or(u64::MAX);
    let error = |available| MemoryError {
        what: what.to_owned(),
        needed,
        available,
        capped: false,
    };
    if needed > limit {
        return Err(error(None));
    }
    match available {
        Some(a) if needed > a => Err(error(Some(a))),
        _ => Ok(()),
    }
}

/// A byte count in binary units: `512 B`, `1.5 KiB`, `3.0 GiB`.
pub fn format_bytes(n: u64) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = n as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} B")
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_byte_counts() {
        assert_eq!(format_bytes(512), "512 B");
        assert_eq!(format_bytes(1536), "1.5 KiB");
        assert_eq!(format_bytes(3 << 30), "3.0 GiB");
        assert_eq!(format_bytes(u64::MAX), "16384.0 PiB");
    }

    #[test]
    fn refuses_more_than_one_allocation_or_the_machine_holds() {
        assert!(ensure(1024, None, "x").is_ok());
        let e = ensure(u64::MAX, None, "a grid").unwrap_err();
        assert_eq!(e.available, None);
        assert_eq!(
            e.to_string(),
            "a grid needs about 16384.0 PiB of memory, more than any allocation can hold"
        );
        let e = ensure(3 << 30, Some(1 << 30), "a grid").unwrap_err();
        assert_eq!(e.available, Some(1 << 30));
        assert!(ensure(1 << 30, Some(1 << 30), "a grid").is_ok());
    }

    #[test]
    fn reads_the_machine_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(available().is_some_and(|a| a > 0));
        }
    }
}
