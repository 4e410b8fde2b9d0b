//! Ctrl-C and SIGTERM: what a command leaves behind when interrupted.
//!
//! The signals' default action ends the process at once, which leaves the hidden temporary
//! files of atomic writes in progress and `zeroset reconstruct`'s intermediate files for the
//! next run to find. [`install`] catches them instead: the handler removes both, then ends
//! the process by the same signal with its default action, so that a shell or a script sees
//! a command killed by Ctrl-C (a `for` loop stops; status 130, or 143 for SIGTERM). A signal
//! the process was started with ignored (`cmd &` in a script) stays ignored. `zeroset studio`
//! installs its own handler.

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

/// Removes what an interrupted command leaves; the number of files removed. Both lists stay
/// locked until the process ends, so that no temporary file is made after they were emptied.
fn clean_up() -> usize {
    let mut removed = zeroset_field_core::io::remove_unfinished_writes_before_exit();
    let mut list = temporaries();
    for path in list.drain(..) {
        removed += usize::from(std::fs::remove_file(path).is_ok());
    }
    std::mem::forget(list);
    removed
}

fn say_removed(removed: usize) {
    if removed == 0 {
        eprintln!("zeroset: interrupted");
    } else {
        eprintln!("zeroset: interrupted; {removed} unfinished or temporary file(s) removed");
    }
}

/// Installs the handler (see the [module docs](self)). If its thread or runtime cannot be
/// made, the signals keep their default action.
pub fn install() {
    #[cfg(unix)]
    let watched: Vec<i32> = [libc::SIGINT, libc::SIGTERM]
        .into_iter()
        .filter(|&s| !ignored(s))
        .collect();
    #[cfg(unix)]
    if watched.is_empty() {
        return;
    }
    let spawned = std::thread::Builder::new()
        .name("interrupt".into())
        .spawn(move || {
            let Ok(runtime) = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            else {
                return;
            };
            #[cfg(unix)]
            {
                let Some(signal) = runtime.block_on(first_of(&watched)) else {
                    return;
                };
                say_removed(clean_up());
                die_of(signal);
            }
            #[cfg(not(unix))]
            {
                if runtime.block_on(tokio::signal::ctrl_c()).is_err() {
                    return;
                }
                say_removed(clean_up());
                std::process::exit(130);
            }
        });
    drop(spawned);
}

/// Waits for the first of `signals`; `None` if none can be listened for.
#[cfg(unix)]
async fn first_of(signals: &[i32]) -> Option<i32> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut streams: Vec<_> = signals
        .iter()
        .filter_map(|&s| Some((s, signal(SignalKind::from_raw(s)).ok()?)))
        .collect();
    if streams.is_empty() {
        return None;
    }
    std::future::poll_fn(|cx| {
        for (s, stream) in &mut streams {
            if stream.poll_recv(cx).is_ready() {
                return std::task::Poll::Ready(Some(*s));
            }
        }
        std::task::Poll::Pending
    })
    .await
}

/// Whether `signal` is ignored in this process (as `cmd &` starts a script's jobs).
#[cfg(unix)]
fn ignored(signal: i32) -> bool {
    // SAFETY: `sigaction` with a null new action only reads the current one into `old`,
    // a zeroed `sigaction` being a valid value of the C struct.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(signal, std::ptr::null(), &mut old) == 0
            && old.sa_sigaction == libc::SIG_IGN
    }
}

/// Ends the process by `signal` with its default action (the shell then sees the signal).
#[cfg(unix)]
fn die_of(signal: i32) -> ! {
    // SAFETY: resetting a signal's action to the default and raising it are async-signal-safe
    // calls made from an ordinary thread; the process ends at the raise.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        libc::raise(signal);
    }
    std::process::exit(128 + signal)
}
