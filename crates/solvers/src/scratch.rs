//! Work buffers kept between solves.
//!
//! A fresh multi-megabyte buffer costs a page fault per 4 KiB page on first touch, and with
//! several threads touching it the faults contend for the address-space lock: for the
//! separable restoration solve at 262,144 unknowns that was half the run time. Repeated solves
//! of one size — a mask being dragged, or the iterations of a preconditioned LSQR — are the
//! common case, so solvers take their large scratch from here and give it back when done.
//!
//! At most [`KEEP`] buffers are kept (the memory of two solves of the largest size seen);
//! contents of a buffer taken are unspecified, so callers overwrite before they read.
//!
//! ```
//! use zeroset_solvers::scratch;
//!
//! let mut work = scratch::take(1000);
//! work.fill(1.0);
//! scratch::give_back(work);
//! assert_eq!(scratch::take(10).len(), 10);
//! ```

use std::sync::Mutex;

/// Buffers kept at most.
pub const KEEP: usize = 4;

static BUFFERS: Mutex<Vec<Vec<f64>>> = Mutex::new(Vec::new());

/// A buffer of `len` values, contents unspecified: a kept one (the largest) if any, else new.
pub fn take(len: usize) -> Vec<f64> {
    let kept = BUFFERS.lock().ok().and_then(|mut kept| {
        let largest = (0..kept.len()).max_by_key(|&i| kept[i].capacity())?;
        Some(kept.swap_remove(largest))
    });
    let mut buffer = kept.unwrap_or_default();
    buffer.resize(len, 0.0);
    buffer
}

/// Keeps `buffer` for a later [`take`], unless [`KEEP`] are kept already.
pub fn give_back(buffer: Vec<f64>) {
    if let Ok(mut kept) = BUFFERS.lock()
        && kept.len() < KEEP
    {
        kept.push(buffer);
    }
}
