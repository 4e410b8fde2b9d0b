//! Small helpers shared by the timing examples.

use std::time::Duration;

/// The median of `v` (the upper one for an even count). `v` must not be empty.
pub fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// Parses `"16,24,32"` for the flag `flag`.
pub fn parse_list(flag: &str, value: &str) -> Result<Vec<usize>, String> {
    value
        .split(',')
        .map(|s| s.trim().parse().map_err(|e| format!("{flag}: {s}: {e}")))
        .collect()
}
