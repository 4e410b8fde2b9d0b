//! Facts about the machine the commands check before large allocations, and the checks
//! themselves: a grid's sample count without overflow, and whether its arrays fit in memory.

use anyhow::bail;

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
/// more than the memory available (the machine's, or the cap of `ZEROSET_MEMORY_LIMIT`):
/// `what` says what needs it (`--grid 64,64,64 (262144 cells)`), `advice` what to do
/// instead. Where the available memory cannot be read (not Linux) only the first limit is
/// checked ([`zeroset_field_core::limits::check_bytes`]).
pub(crate) fn ensure_memory(need: u64, what: &str, advice: &str) -> anyhow::Result<()> {
    zeroset_field_core::limits::check_bytes(what, need)
        .map_err(|e| anyhow::anyhow!("{e}; {advice}"))
}

#[cfg(test)]
mod tests {
    use super::*;

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
