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

/// `d` in seconds, two decimals.
pub(crate) fn seconds(d: Duration) -> String {
    format!("{:.2} s", d.as_secs_f64())
}
