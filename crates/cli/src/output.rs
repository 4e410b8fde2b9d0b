//! The one check every writing subcommand makes on its output path before any work, and the
//! one way the commands print their reports.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::bail;

use crate::restore::same_file;

/// Refuses an output whose extension is not one of `allowed_extensions` (compared without
/// regard to case; empty allows any), one of the `inputs`, a missing directory, a directory and
/// an existing file without `force`.
pub(crate) fn check_output(
    output: &Path,
    inputs: &[&Path],
    force: bool,
    allowed_extensions: &[&str],
) -> anyhow::Result<()> {
    if !allowed_extensions.is_empty() {
        let ext = output.extension().and_then(|e| e.to_str());
        let allowed =
            ext.is_some_and(|e| allowed_extensions.iter().any(|a| e.eq_ignore_ascii_case(a)));
        if !allowed {
            let list: Vec<String> = allowed_extensions.iter().map(|e| format!(".{e}")).collect();
            let note = if allowed_extensions.len() > 1 {
                " (the extension picks the format)"
            } else {
                ""
            };
            bail!(
                "the output {} must end in {}{note}",
                output.display(),
                list.join(" or ")
            );
        }
    }
    if let Some(input) = inputs.iter().find(|i| same_file(i, output)) {
        bail!(
            "the output would overwrite the input {}; choose another name",
            input.display()
        );
    }
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!(
            "the output directory {} does not exist (or is not a directory)",
            dir.display()
        );
    }
    if output.is_dir() {
        bail!("the output {} is a directory", output.display());
    }
    if output.exists() && !force {
        bail!(
            "the output {} exists; pass --force to overwrite it",
            output.display()
        );
    }
    check_writable(dir, output)
}

/// Whether a file can be created in `dir` (as the atomic write of `output` will, beside it):
/// a probe file is created and removed, so that a read-only or otherwise refusing directory is
/// an error before any work rather than after it.
fn check_writable(dir: &Path, output: &Path) -> anyhow::Result<()> {
    static PROBES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let probe = dir.join(format!(
        ".zeroset-probe-{}-{}",
        std::process::id(),
        PROBES.fetch_add(1, Ordering::Relaxed)
    ));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(file) => {
            drop(file);
            // A probe that cannot be removed is left behind, hidden; the write may still work.
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => bail!(
            "cannot write {}: creating a file in {} fails ({e})",
            output.display(),
            dir.display()
        ),
    }
}

/// Set once stdout has refused a line: nothing more is printed.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Writes one line of a command's report to stdout (the `outln!` macro). Where `println!` would
/// panic — stdout closed by the reader (`zeroset fit … | head`, a broken pipe) or failing — the
/// printing stops and the command goes on, so that the files it was asked for are still
/// written and its exit status says whether the work succeeded.
pub(crate) fn say_line(text: std::fmt::Arguments<'_>) {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut stdout = std::io::stdout().lock();
    if writeln!(stdout, "{text}")
        .and_then(|()| stdout.flush())
        .is_err()
    {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
    }
}
