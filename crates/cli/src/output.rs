//! The one check every writing subcommand makes on its output path before any work.

use std::path::Path;

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
    Ok(())
}
