//! Facts about the machine the commands check before large allocations, and the checks
//! themselves: a grid's sample count without overflow, and whether its arrays fit in memory.

use anyhow::bail;

/// `MemAvailable` from `/proc/meminfo`, in bytes; `None` where it cannot be read (not Linux).
pub(crate) fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// A byte count in binary units: `512 B`, `1.5 KiB`, `3.0 GiB`.
pub(crate) fn bytes(n: u64) -> String {
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

/// `counts` written as the user gives them: `64,64,48`.
pub(crate) fn counts_text(counts: &[usize]) -> String {
    counts
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

/// The number of samples of a grid with `counts` per axis, `Π counts`; an error naming `flag`
/// (`--grid`, `--coarse`) when the product overflows, before anything is allocated.
pub(crate) fn sample_count(counts: &[usize], flag: &str) -> anyhow::Result<usize> {
    match counts.iter().try_fold(1usize, |n, &c| n.checked_mul(c)) {
        Some(n) => Ok(n),
        None => bail!(
            "{flag} {}: the grid would have more samples than a 64-bit count can hold \
             (about {:.1e}); choose fewer cells per axis",
            counts_text(counts),
            counts.iter().map(|&c| c as f64).product::<f64>()
        ),
    }
}

/// Refuses work that would need `need` bytes when that is more than one allocation can hold or
/// more than the machine has available: `what` says what needs it (`--grid 64,64,64 (262144
/// cells)`), `advice` what to do instead. Where the available memory cannot be read (not
/// Linux) only the first limit is checked.
pub(crate) fn ensure_memory(need: u64, what: &str, advice: &str) -> anyhow::Result<()> {
    // No allocation can exceed isize::MAX bytes (`Vec` fails with a panic above it).
    let limit = u64::try_from(isize::MAX).unwrap_or(u64::MAX);
    let available = available_memory();
    if need > limit {
        bail!(
            "{what} needs about {} of memory, more than any allocation can hold; {advice}",
            bytes(need)
        );
    }
    if let Some(available) = available
        && need > available
    {
        bail!(
            "{what} needs about {} of memory, more than the {} available; {advice}",
            bytes(need),
            bytes(available)
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_byte_counts() {
        assert_eq!(bytes(512), "512 B");
        assert_eq!(bytes(1536), "1.5 KiB");
        assert_eq!(bytes(3 << 30), "3.0 GiB");
        assert_eq!(bytes(u64::MAX), "16384.0 PiB");
    }

    #[test]
    fn counts_samples_without_overflow() {
        assert_eq!(sample_count(&[4, 5, 6], "--grid").unwrap(), 120);
        let e = sample_count(&[10_000_000; 3], "--grid").unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("--grid 10000000,10000000,10000000") && text.contains("1.0e21"),
            "{text}"
        );
    }

    #[test]
    fn refuses_more_memory_than_an_allocation_can_hold() {
        assert!(ensure_memory(1024, "x", "y").is_ok());
        let e = ensure_memory(u64::MAX, "--grid 1,1,1", "choose less").unwrap_err();
        let text = e.to_string();
        assert!(
            text.starts_with("--grid 1,1,1 needs about 16384.0 PiB") && text.ends_with("less"),
            "{text}"
        );
    }
}
