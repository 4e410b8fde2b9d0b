//! Small helpers shared by the timing examples.
//!
//! The timing rule of the examples and of the peer scripts in `benches/peers` (`timed` in
//! `benches/peers/common.py`): one warm-up run, then the median of `repeat` timed runs (the
//! upper median for an even count). [`measure`] applies it; where a single run is already slow
//! it may stop after that one run, and says so ([`Timed::warmup`] is then `false`).

use std::time::{Duration, Instant};

/// The median of `v` (the upper one for an even count). `v` must not be empty.
pub fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// Parses `"16,24,32"` for the flag `flag`.
#[allow(dead_code)]
pub fn parse_list(flag: &str, value: &str) -> Result<Vec<usize>, String> {
    value
        .split(',')
        .map(|s| s.trim().parse().map_err(|e| format!("{flag}: {s}: {e}")))
        .collect()
}

/// What [`measure`] timed.
#[allow(dead_code)] // each example uses what it needs (so below)
pub struct Timed<T> {
    /// The median of [`times`](Self::times).
    pub median: Duration,
    /// Every timed run (the warm-up excluded).
    pub times: Vec<Duration>,
    /// Whether a warm-up run preceded the timed runs (`false`: one run, no warm-up).
    pub warmup: bool,
    /// The result of the last run.
    pub last: T,
}

#[allow(dead_code)]
impl<T> Timed<T> {
    /// The number of timed runs.
    pub fn runs(&self) -> usize {
        self.times.len()
    }

    /// The median in milliseconds.
    pub fn ms(&self) -> f64 {
        self.median.as_secs_f64() * 1e3
    }

    /// `"warm-up + median of R"` or `"1 run, no warm-up"`, for tables and reports.
    pub fn how(&self) -> String {
        if self.warmup {
            format!("warm-up + median of {}", self.runs())
        } else {
            "1 run, no warm-up".into()
        }
    }
}

/// One warm-up run of `f`, then `repeat` (at least 1) timed runs; the median of those.
///
/// With `once_above`, a warm-up run that alone takes longer than that is kept as the only
/// timed run (`warmup == false`, one run): the rule for runs of several seconds.
#[allow(dead_code)]
pub fn measure<T, E>(
    repeat: usize,
    once_above: Option<Duration>,
    mut f: impl FnMut() -> Result<T, E>,
) -> Result<Timed<T>, E> {
    let start = Instant::now();
    let mut last = f()?;
    let first = start.elapsed();
    if once_above.is_some_and(|limit| first > limit) {
        return Ok(Timed {
            median: first,
            times: vec![first],
            warmup: false,
            last,
        });
    }
    let mut times = Vec::with_capacity(repeat.max(1));
    for _ in 0..repeat.max(1) {
        let start = Instant::now();
        last = f()?;
        times.push(start.elapsed());
    }
    Ok(Timed {
        median: median(times.clone()),
        times,
        warmup: true,
        last,
    })
}

/// Sets the number of rayon threads for the whole run (`Some(n)`, `--threads N`) or keeps
/// rayon's default (`RAYON_NUM_THREADS`, else one per CPU); returns the count in effect.
/// Call it before anything runs in parallel.
#[allow(dead_code)]
pub fn set_threads(threads: Option<usize>) -> Result<usize, String> {
    if let Some(n) = threads {
        if n == 0 {
            return Err("--threads must be at least 1".into());
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| format!("--threads {n}: {e}"))?;
    }
    Ok(rayon::current_num_threads())
}

/// Milliseconds of each run, space-separated (a CSV cell).
#[allow(dead_code)]
pub fn times_cell(times: &[Duration]) -> String {
    times
        .iter()
        .map(|t| format!("{:.3}", t.as_secs_f64() * 1e3))
        .collect::<Vec<_>>()
        .join(" ")
}
