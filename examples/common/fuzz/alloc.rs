//! A counting global allocator: the live heap bytes, the peak of one execution above the
//! live bytes when it started, and a refusal of any request that would take the execution
//! past [`LIMIT`].
//!
//! The binary that wants it declares it (`#[global_allocator] static A: Counting = Counting;`);
//! [`begin`] arms it for an execution and [`end`] disarms it and reports. A refused request
//! returns null: `try_reserve` callers see an error (recorded as a finding all the same, by
//! [`end`]), everyone else reaches `handle_alloc_error`, which aborts — the marker
//! [`REFUSAL_MARKER`] is written to stderr first so that a supervisor can tell that abort from
//! the others.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering::Relaxed};

/// The most one execution may hold on top of what was live when it started: 1 GiB.
pub const LIMIT: usize = 1 << 30;

/// Written to stderr (followed by the size) when a request is refused.
pub const REFUSAL_MARKER: &str = "fuzz: refused an allocation of";

static LIVE: AtomicUsize = AtomicUsize::new(0);
static BASE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static ARMED: AtomicBool = AtomicBool::new(false);
static REFUSED: AtomicUsize = AtomicUsize::new(0);
static INSTALLED: AtomicBool = AtomicBool::new(false);

/// The counting allocator (a wrapper of [`System`]).
pub struct Counting;

impl Counting {
    fn admit(&self, size: usize) -> bool {
        INSTALLED.store(true, Relaxed);
        let live = LIVE.fetch_add(size, Relaxed).saturating_add(size);
        if ARMED.load(Relaxed) && live.saturating_sub(BASE.load(Relaxed)) > LIMIT {
            LIVE.fetch_sub(size, Relaxed);
            if REFUSED.fetch_max(size, Relaxed) == 0 {
                report_refusal(size);
            }
            return false;
        }
        PEAK.fetch_max(live, Relaxed);
        true
    }
}

/// Writes the refusal marker without allocating.
fn report_refusal(size: usize) {
    let mut buf = [0u8; 96];
    let mut n = 0;
    for &b in REFUSAL_MARKER.as_bytes().iter().chain(b" ") {
        buf[n] = b;
        n += 1;
    }
    let mut digits = [0u8; 20];
    let (mut k, mut v) = (0, size);
    loop {
        digits[k] = b'0' + (v % 10) as u8;
        k += 1;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    while k > 0 {
        k -= 1;
        buf[n] = digits[k];
        n += 1;
    }
    for &b in b" bytes\n" {
        buf[n] = b;
        n += 1;
    }
    let _ = std::io::stderr().write_all(&buf[..n]);
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !self.admit(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !self.admit(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old && !self.admit(new_size - old) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > old {
                LIVE.fetch_sub(new_size - old, Relaxed);
            }
        } else if new_size < old {
            LIVE.fetch_sub(old - new_size, Relaxed);
        }
        p
    }
}

/// Whether the binary uses [`Counting`] as its global allocator (known after its first
/// allocation).
pub fn installed() -> bool {
    INSTALLED.load(Relaxed)
}

/// Arms the limit for an execution starting now.
pub fn begin() {
    let live = LIVE.load(Relaxed);
    BASE.store(live, Relaxed);
    PEAK.store(live, Relaxed);
    REFUSED.store(0, Relaxed);
    ARMED.store(true, Relaxed);
}

/// Disarms the limit; returns the execution's peak above its start and the largest refused
/// request (0 if none).
pub fn end() -> (usize, usize) {
    ARMED.store(false, Relaxed);
    let peak = PEAK.load(Relaxed).saturating_sub(BASE.load(Relaxed));
    (peak, REFUSED.swap(0, Relaxed))
}
