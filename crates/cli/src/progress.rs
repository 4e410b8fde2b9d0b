//! Progress on the terminal: spinners for long steps, and durations as text.

use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// A ticking spinner showing its message and the elapsed time, or a hidden one when `quiet`.
pub(crate) fn spinner(quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let s = ProgressBar::new_spinner();
    s.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid template"));
    s.enable_steady_tick(Duration::from_millis(100));
    s
}

/// A bar counting `len` steps under `message`, with the estimated time left, or a hidden one
/// when `quiet`.
pub(crate) fn counter(quiet: bool, len: usize, message: &'static str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta} left)")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_message(message);
    bar
}

/// `d` in seconds, two decimals.
pub(crate) fn seconds(d: Duration) -> String {
    format!("{:.2} s", d.as_secs_f64())
}
