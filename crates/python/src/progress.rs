//! Long computations run on a thread of their own with the GIL released ([`Hook::run`]) while
//! the calling thread watches for Ctrl-C, and report to Python: a report takes the GIL briefly
//! and calls the user's `progress(stage, done, total)` if there is one (from a worker thread,
//! not Python's main thread). An exception raised there stops the
//! computation and is raised from the call that started it. Reports closer than
//! [`INTERVAL`] to the previous one are skipped (the first and the last of a stage never are):
//! taking the GIL at every LSQR iteration cost 7% of a solve.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The shortest time between two reports that reach Python.
pub(crate) const INTERVAL: Duration = Duration::from_millis(20);

/// How often [`Hook::run`] checks for Ctrl-C while the work runs.
const WATCH: Duration = Duration::from_millis(50);

use pyo3::prelude::*;

/// The reporting end of one computation (see the module docs).
pub(crate) struct Hook {
    callback: Option<Py<PyAny>>,
    error: Mutex<Option<PyErr>>,
    last: Mutex<Option<Instant>>,
}

impl Hook {
    /// A hook calling `callback` (or only checking for signals without one).
    pub(crate) fn new(callback: Option<Py<PyAny>>) -> Self {
        Self {
            callback,
            error: Mutex::new(None),
            last: Mutex::new(None),
        }
    }

    /// Reports `done` of `total` in `stage`; `false` when the computation must stop (a signal,
    /// or the callback raised; the exception is kept for [`Hook::finish`]). No lock is held
    /// while the GIL is awaited: [`Hook::run`]'s thread takes the error lock holding the GIL.
    pub(crate) fn report(&self, stage: &str, done: usize, total: usize) -> bool {
        if self.stopped() {
            return false;
        }
        {
            let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
            let now = Instant::now();
            if last.is_some_and(|t| now - t < INTERVAL) && done > 1 && done < total {
                return true;
            }
            *last = Some(now);
        }
        let outcome = Python::attach(|py| -> PyResult<()> {
            py.check_signals()?;
            if let Some(callback) = &self.callback {
                callback.call1(py, (stage, done, total))?;
            }
            Ok(())
        });
        match outcome {
            Ok(()) => !self.stopped(),
            Err(e) => {
                self.stop(e);
                false
            }
        }
    }

    /// Whether an exception stopped the computation.
    fn stopped(&self) -> bool {
        self.error
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some()
    }

    /// Stops the computation with `e`, unless an earlier exception did.
    fn stop(&self, e: PyErr) {
        let mut error = self.error.lock().unwrap_or_else(|e| e.into_inner());
        if error.is_none() {
            *error = Some(e);
        }
    }

    /// Runs `work` with the GIL released on a thread of its own, while the calling thread (the
    /// one Python delivers signals to) watches for Ctrl-C every [`WATCH`]: a signal stops the
    /// work at its next report ([`Hook::report`] answers `false`; work without reports runs to
    /// its end) and is raised by [`Hook::finish`]. Reports from the worker threads cannot see
    /// signals themselves: `PyErr_CheckSignals` does nothing off the main thread.
    pub(crate) fn run<T: Send>(&self, py: Python<'_>, work: impl FnOnce() -> T + Send) -> T {
        std::thread::scope(|scope| {
            let (finished, waiting) = std::sync::mpsc::channel::<()>();
            // The stack of the thread the work had before (Python's main thread: 8 MiB on
            // Linux), not a spawned thread's 2 MiB.
            let worker = std::thread::Builder::new()
                .stack_size(8 << 20)
                .spawn_scoped(scope, move || {
                    let out = work();
                    let _ = finished.send(());
                    out
                })
                .expect("a thread for the computation");
            let mut waiting = Some(waiting);
            let mut interrupted = false;
            while let Some(rx) = waiting.take() {
                let (outcome, rx) = py.detach(move || (rx.recv_timeout(WATCH), rx));
                match outcome {
                    Err(std::sync::mpsc::RecvTimeoutError::Timeout) => waiting = Some(rx),
                    // Done (or the worker panicked before saying so: join reports it).
                    Ok(()) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {}
                }
                if !interrupted && let Err(e) = py.check_signals() {
                    interrupted = true;
                    self.stop(e);
                }
            }
            match py.detach(|| worker.join()) {
                Ok(out) => out,
                Err(panic) => std::panic::resume_unwind(panic),
            }
        })
    }

    /// The computation's result, unless the hook stopped it: then the exception that did.
    pub(crate) fn finish<T>(&self, result: PyResult<T>) -> PyResult<T> {
        match self.error.lock().unwrap_or_else(|e| e.into_inner()).take() {
            Some(e) => Err(e),
            None => result,
        }
    }
}
