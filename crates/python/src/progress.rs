//! Long computations report to Python while the GIL is released: a report takes the GIL
//! briefly, checks for signals (Ctrl-C stops the work with `KeyboardInterrupt`) and calls the
//! user's `progress(stage, done, total)` if there is one. An exception raised there stops the
//! computation and is raised from the call that started it. Reports closer than
//! [`INTERVAL`] to the previous one are skipped (the first and the last of a stage never are):
//! taking the GIL at every LSQR iteration cost 7% of a solve.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The shortest time between two reports that reach Python.
pub(crate) const INTERVAL: Duration = Duration::from_millis(20);

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
    /// or the callback raised; the exception is kept for [`Hook::finish`]).
    pub(crate) fn report(&self, stage: &str, done: usize, total: usize) -> bool {
        let mut error = self.error.lock().unwrap_or_else(|e| e.into_inner());
        if error.is_some() {
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
            Ok(()) => true,
            Err(e) => {
                *error = Some(e);
                false
            }
        }
    }

    /// The computation's result, unless the hook stopped it: then the exception that did.
    pub(crate) fn finish<T>(&self, result: PyResult<T>) -> PyResult<T> {
        match self.error.lock().unwrap_or_else(|e| e.into_inner()).take() {
            Some(e) => Err(e),
            None => result,
        }
    }
}
