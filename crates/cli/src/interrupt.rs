//! Ctrl-C and SIGTERM: what a command leaves behind when interrupted.
//!
//! The signals' default action ends the process at once, which leaves the hidden temporary
//! files of atomic writes in progress and `zeroset reconstruct`'s intermediate files for the
//! next run to find. [`install`] replaces it: the handler removes both and exits with status
//! 130, as a shell reports a command stopped by Ctrl-C. `zeroset studio` installs its own.

use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard};

/// The [`TemporaryFile`]s that exist now.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn temporaries() -> MutexGuard<'static, Vec<PathBuf>> {
    TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner())
}

/// An intermediate file of a command, removed however the command ends: when dropped, and by
/// the interrupt handler.
pub struct TemporaryFile(Option<PathBuf>);

impl TemporaryFile {
    /// Takes charge of `path` (`None`: nothing to remove, as when the user named the file).
    pub fn new(path: Option<PathBuf>) -> Self {
        if let Some(p) = &path {
            temporaries().push(p.clone());
        }
        Self(path)
    }
}

impl Drop for TemporaryFile {
    fn drop(&mut self) {
        if let Some(path) = &self.0 {
            let _ = std::fs::remove_file(path);
            temporaries().retain(|p| p != path);
        }
    }
}

/// Installs the handler: on Ctrl-C or SIGTERM, removes the temporary files of unfinished
/// atomic writes and the [`TemporaryFile`]s, says so, and exits with status 130. If its thread
/// or runtime cannot be made, the signals keep their default action.
pub fn install() {
    let spawned = std::thread::Builder::new()
        .name("interrupt".into())
        .spawn(|| {
            let Ok(runtime) = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            else {
                return;
            };
            runtime.block_on(crate::studio::shutdown());
            zeroset_field_core::io::remove_unfinished_writes();
            for path in temporaries().drain(..) {
                let _ = std::fs::remove_file(path);
            }
            eprintln!("zeroset: interrupted; unfinished output and temporary files removed");
            std::process::exit(130);
        });
    drop(spawned);
}
