//! Reusing M2L operators: a process-wide cache and an optional, versioned cache on disk.
//!
//! The M2L operators are the one part of a multipole field whose cost does not grow with the
//! data: they depend only on the kernel, the order `p`, the compression tolerance and the
//! compression (and, for a kernel that is not homogeneous, the cell width). Building them takes
//! about 0.01 s at `p = 5`, 0.1 s at `p = 8` and 0.25–0.3 s at `p = 10` on two cores (0.85–1.3 s
//! at `p = 12`), which a field of a few thousand centres would otherwise pay on every build,
//! often more than the build itself. So:
//!
//! - **In memory.** [`FmmField::new`](super::FmmField::new) and
//!   [`FmmField::operators`](super::FmmField::operators) take their operators from one cache per
//!   process, keyed by kernel, order, tolerance and compression. Every field of the same key
//!   shares them, including the two orders of the signed marching cubes across runs in one
//!   process: the second mesh of a session pays nothing for operators. The cache holds at most
//!   [`set_memory_limit`] bytes of built operators (default [`DEFAULT_MEMORY_LIMIT`]), dropping
//!   the least recently used set first; [`clear`] empties it.
//! - **On disk** (off unless [`set_disk_dir`] names a folder; the `zeroset` command turns it
//!   on). Each operator set is one file, `m2l-v{FORMAT}-{hash}.zso`, holding the full key (a
//!   hash collision is detected and rebuilt), the operators in little-endian `f64` and a CRC-32
//!   of everything before it; written atomically (a temporary file renamed into place), so
//!   concurrent processes never read half a file. A file that is missing, of another format
//!   version, for another key, truncated or corrupt is ignored and rebuilt: the cache can be
//!   deleted at any time.
//!
//! A kernel's key is its [`name`](crate::rbf::Kernel::name), its homogeneity, its `Debug`
//! form (which shows parameters such as a Wendland support radius) and its values at 25
//! radii from 10⁻⁶ to 10⁶, so two kernels that share a key compute the same operators.

use std::io::{self, Read as _};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard, RwLock};

use faer::Mat;

use super::operators::{Compressed, FmmOperators, LevelOperators, M2lCompression, OffsetOperator};
use crate::rbf::kernel::Kernel;

/// The default limit of the in-memory cache: 1 GiB of built operators (the shared basis at
/// `p = 12` takes about 260 MB).
pub const DEFAULT_MEMORY_LIMIT: usize = 1 << 30;

/// The version of the on-disk format; files of other versions are ignored.
pub const FORMAT: u32 = 1;

const MAGIC: &[u8; 8] = b"ZSFMMOPS";

/// The key of an operator set: everything its matrices depend on but the cell width.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct OperatorKey(String);

impl OperatorKey {
    pub fn new<K: Kernel + ?Sized>(
        kernel: &K,
        order: usize,
        tolerance: f64,
        compression: M2lCompression,
    ) -> Self {
        let fingerprint: Vec<String> = (-12..=12)
            .map(|k| {
                let r = 10f64.powf(f64::from(k) / 2.0);
                format!("{:016x}", kernel.value_of_squared(r * r).to_bits())
            })
            .collect();
        Self(format!(
            "kernel {} homogeneity {:?} {:?} values {}; order {order}; tolerance {:016x}; {:?}",
            kernel.name(),
            kernel.homogeneity(),
            kernel,
            fingerprint.join(","),
            tolerance.to_bits(),
            compression,
        ))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

/// What the caches hold and did since the process started (or [`clear`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct CacheStats {
    /// Operator sets held in memory.
    pub entries: usize,
    /// Bytes of built operators they hold.
    pub bytes: usize,
    /// Requests served by a set already in memory.
    pub memory_hits: u64,
    /// Requests that made a new set.
    pub memory_misses: u64,
    /// Operators of one cell width read from disk instead of computed.
    pub disk_reads: u64,
    /// Operators of one cell width computed (none in memory or on disk).
    pub builds: u64,
    /// Operator files written to disk.
    pub disk_writes: u64,
}

struct Registry {
    /// Most recently used last.
    entries: Vec<Arc<FmmOperators>>,
    limit: usize,
    stats: CacheStats,
}

/// No entries, nothing done yet (`CacheStats::default()`, usable in a `static`).
const NO_STATS: CacheStats = CacheStats {
    entries: 0,
    bytes: 0,
    memory_hits: 0,
    memory_misses: 0,
    disk_reads: 0,
    builds: 0,
    disk_writes: 0,
};

static REGISTRY: Mutex<Registry> = Mutex::new(Registry {
    entries: Vec::new(),
    limit: DEFAULT_MEMORY_LIMIT,
    stats: NO_STATS,
});

static DISK: RwLock<Option<PathBuf>> = RwLock::new(None);

fn registry() -> MutexGuard<'static, Registry> {
    // The registry is a list of complete entries and counters: still valid after a panic
    // elsewhere while the lock was held.
    REGISTRY.lock().unwrap_or_else(|e| e.into_inner())
}

/// The operators for `key`, from the cache or new (and then cached).
pub(crate) fn operators<K: Kernel + ?Sized>(
    kernel: &K,
    order: usize,
    tolerance: f64,
    compression: M2lCompression,
) -> Arc<FmmOperators> {
    let key = OperatorKey::new(kernel, order, tolerance, compression);
    let mut reg = registry();
    if let Some(i) = reg.entries.iter().position(|o| *o.key() == key) {
        let ops = reg.entries.remove(i);
        reg.entries.push(ops.clone());
        reg.stats.memory_hits += 1;
        return ops;
    }
    reg.stats.memory_misses += 1;
    let ops = Arc::new(FmmOperators::new(kernel, order, tolerance, compression));
    reg.entries.push(ops.clone());
    trim(&mut reg);
    ops
}

/// Where the operators a field of `kernel` with `options` would use are already, without
/// building or fetching anything.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cached {
    /// Built, in this process's cache: a new field pays nothing for them.
    InMemory,
    /// In the disk cache: a new field reads them (milliseconds).
    OnDisk,
    /// Not built yet (a kernel that is not homogeneous needs operators per cell width, which
    /// depend on the data: always `NotYet`).
    NotYet,
}

/// Where the operators for `kernel` at `options` are (see [`Cached`]); `NotYet` for options
/// out of range.
pub fn cached<K: Kernel + ?Sized>(kernel: &K, options: &super::FmmOptions) -> Cached {
    if options.check().is_err() || kernel.homogeneity().is_none() {
        return Cached::NotYet;
    }
    let key = OperatorKey::new(
        kernel,
        options.order,
        options.tolerance(),
        options.compression(),
    );
    let in_memory = registry().entries.iter().find(|o| *o.key() == key).cloned();
    if in_memory.is_some_and(|o| o.has_level(1.0)) {
        return Cached::InMemory;
    }
    match disk_dir() {
        Some(dir) if file_for(&dir, &key, 1.0).is_file() => Cached::OnDisk,
        _ => Cached::NotYet,
    }
}

/// Drops the least recently used sets until the rest fit the limit (the newest always stays).
fn trim(reg: &mut Registry) {
    let mut total: usize = reg.entries.iter().map(|o| o.bytes()).sum();
    while total > reg.limit && reg.entries.len() > 1 {
        let dropped = reg.entries.remove(0);
        total -= dropped.bytes();
    }
}

/// Counts a width's operators as read from disk (`true`) or computed, and a file written; and
/// re-applies the memory limit now that a set has grown. Never called with an operator set's
/// own lock held (the registry's lock is taken first everywhere else).
pub(crate) fn record(from_disk: bool, written: bool) {
    let mut reg = registry();
    if from_disk {
        reg.stats.disk_reads += 1;
    } else {
        reg.stats.builds += 1;
    }
    if written {
        reg.stats.disk_writes += 1;
    }
    trim(&mut reg);
}

/// Empties the in-memory cache and resets its counters (fields keep the operators they hold).
pub fn clear() {
    let mut reg = registry();
    reg.entries.clear();
    reg.stats = NO_STATS;
}

/// Sets the most bytes of built operators the in-memory cache keeps (0: keep only the set in
/// use), and trims it to that.
pub fn set_memory_limit(bytes: usize) {
    let mut reg = registry();
    reg.limit = bytes;
    trim(&mut reg);
}

/// What the caches hold and did.
pub fn stats() -> CacheStats {
    let reg = registry();
    CacheStats {
        entries: reg.entries.len(),
        bytes: reg.entries.iter().map(|o| o.bytes()).sum(),
        ..reg.stats
    }
}

/// Keeps operators on disk in `dir` (created when first written), or nowhere (`None`, the
/// default). Applies to every operator set from then on, including sets already in memory
/// whose other cell widths are still to be built.
pub fn set_disk_dir(dir: Option<PathBuf>) {
    *DISK.write().unwrap_or_else(|e| e.into_inner()) = dir;
}

/// The folder operators are kept in on disk, if any.
pub fn disk_dir() -> Option<PathBuf> {
    DISK.read().unwrap_or_else(|e| e.into_inner()).clone()
}

/// The file of the operators of `key` for cells of `width`.
pub(crate) fn file_for(dir: &Path, key: &OperatorKey, width: f64) -> PathBuf {
    // FNV-1a, 64 bits: a name, not a check (the file holds the whole key).
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for b in key.as_str().bytes().chain(width.to_bits().to_le_bytes()) {
        hash = (hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    dir.join(format!("m2l-v{FORMAT}-{hash:016x}.zso"))
}

/// The operators of `key` and `width` in `path`, or `None` if the file is missing or not a
/// valid file for them (`n = p³` rows).
pub(crate) fn load(path: &Path, key: &OperatorKey, width: f64, n: usize) -> Option<LevelOperators> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .ok()?
        .read_to_end(&mut bytes)
        .ok()?;
    if bytes.len() < 4 {
        return None;
    }
    let (body, crc) = bytes.split_at(bytes.len() - 4);
    if crc32fast::hash(body).to_le_bytes() != crc {
        return None;
    }
    let mut r = Reader(body);
    if r.take(8)? != MAGIC || r.u32()? != FORMAT {
        return None;
    }
    let key_len = r.u32()? as usize;
    let stored_key = r.take(key_len)?;
    if stored_key != key.as_str().as_bytes() || r.f64()?.to_bits() != width.to_bits() {
        return None;
    }
    let ops = match r.u32()? {
        0 => {
            let count = r.u32()? as usize;
            let mut ops = Vec::with_capacity(count.min(16));
            for _ in 0..count {
                let us = r.mat()?;
                let v = r.mat()?;
                let sigma = r.vec()?;
                if us.nrows() != n || v.nrows() != n || us.ncols() != v.ncols() {
                    return None;
                }
                ops.push(Compressed { us, v, sigma });
            }
            (count == 16).then_some(LevelOperators::PerOperator(ops))?
        }
        1 => {
            let basis = r.mat()?;
            let basis_sigma = r.vec()?;
            let rank = basis.ncols();
            if basis.nrows() != n || basis_sigma.len() != rank {
                return None;
            }
            let signs: Vec<Vec<f64>> = (0..8).map(|_| r.vec()).collect::<Option<_>>()?;
            if signs.iter().any(|s| s.len() != rank) {
                return None;
            }
            let count = r.u32()? as usize;
            if count != 343 {
                return None;
            }
            let mut offsets = Vec::with_capacity(count);
            for _ in 0..count {
                offsets.push(match r.u32()? {
                    0 => None,
                    _ => {
                        let a = r.mat()?;
                        let b = r.mat()?;
                        let sigma = r.vec()?;
                        if a.nrows() != rank || b.nrows() != rank || a.ncols() != b.ncols() {
                            return None;
                        }
                        Some(OffsetOperator { a, b, sigma })
                    }
                });
            }
            LevelOperators::Shared {
                basis,
                basis_sigma,
                signs,
                offsets,
            }
        }
        _ => return None,
    };
    r.0.is_empty().then_some(ops)
}

/// Writes the operators of `key` and `width` to `path`, atomically.
pub(crate) fn save(
    path: &Path,
    key: &OperatorKey,
    width: f64,
    ops: &LevelOperators,
) -> io::Result<()> {
    let mut body = Vec::new();
    body.extend_from_slice(MAGIC);
    put_u32(&mut body, FORMAT);
    put_u32(&mut body, key.as_str().len() as u32);
    body.extend_from_slice(key.as_str().as_bytes());
    body.extend_from_slice(&width.to_le_bytes());
    match ops {
        LevelOperators::PerOperator(canonical) => {
            put_u32(&mut body, 0);
            put_u32(&mut body, canonical.len() as u32);
            for c in canonical {
                put_mat(&mut body, &c.us);
                put_mat(&mut body, &c.v);
                put_vec(&mut body, &c.sigma);
            }
        }
        LevelOperators::Shared {
            basis,
            basis_sigma,
            signs,
            offsets,
        } => {
            put_u32(&mut body, 1);
            put_mat(&mut body, basis);
            put_vec(&mut body, basis_sigma);
            for s in signs {
                put_vec(&mut body, s);
            }
            put_u32(&mut body, offsets.len() as u32);
            for op in offsets {
                match op {
                    None => put_u32(&mut body, 0),
                    Some(op) => {
                        put_u32(&mut body, 1);
                        put_mat(&mut body, &op.a);
                        put_mat(&mut body, &op.b);
                        put_vec(&mut body, &op.sigma);
                    }
                }
            }
        }
    }
    let crc = crc32fast::hash(&body);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    zeroset_field_core::io::write_atomic(path, |w| {
        w.write_all(&body)?;
        w.write_all(&crc.to_le_bytes())
    })
    .map_err(io::Error::other)
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_vec(out: &mut Vec<u8>, v: &[f64]) {
    put_u32(out, v.len() as u32);
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// Rows, columns, then the entries column by column.
fn put_mat(out: &mut Vec<u8>, m: &Mat<f64>) {
    put_u32(out, m.nrows() as u32);
    put_u32(out, m.ncols() as u32);
    for j in 0..m.ncols() {
        for x in m.col(j).iter() {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

/// A cursor over the bytes of an operator file; every read is bounds-checked.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, len: usize) -> Option<&'a [u8]> {
        if len > self.0.len() {
            return None;
        }
        let (head, tail) = self.0.split_at(len);
        self.0 = tail;
        Some(head)
    }

    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }

    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }

    fn vec(&mut self) -> Option<Vec<f64>> {
        let len = self.u32()? as usize;
        let raw = self.take(len.checked_mul(8)?)?;
        Some(
            raw.chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
                .collect(),
        )
    }

    fn mat(&mut self) -> Option<Mat<f64>> {
        let rows = self.u32()? as usize;
        let cols = self.u32()? as usize;
        let raw = self.take(rows.checked_mul(cols)?.checked_mul(8)?)?;
        let at = |i: usize, j: usize| {
            let k = 8 * (j * rows + i);
            f64::from_le_bytes(raw[k..k + 8].try_into().unwrap_or([0; 8]))
        };
        let m = Mat::from_fn(rows, cols, at);
        (0..cols)
            .all(|j| m.col(j).iter().all(|x| x.is_finite()))
            .then_some(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbf::kernel::{Biharmonic, Triharmonic, Wendland};

    #[test]
    fn keys_tell_kernels_orders_tolerances_and_compressions_apart() {
        let key = |k: &dyn Kernel, p, t, c| OperatorKey::new(k, p, t, c);
        let base = key(&Biharmonic, 6, 1e-7, M2lCompression::PerOperator);
        assert_eq!(base, key(&Biharmonic, 6, 1e-7, M2lCompression::PerOperator));
        for other in [
            key(&Triharmonic, 6, 1e-7, M2lCompression::PerOperator),
            key(&Biharmonic, 7, 1e-7, M2lCompression::PerOperator),
            key(&Biharmonic, 6, 2e-7, M2lCompression::PerOperator),
            key(&Biharmonic, 6, 1e-7, M2lCompression::SharedBasis),
        ] {
            assert_ne!(base, other);
        }
        let w = |r| Wendland::new(r).expect("a valid radius");
        let (a, b) = (w(0.05), w(0.0501));
        assert_ne!(
            key(&a, 6, 1e-7, M2lCompression::PerOperator),
            key(&b, 6, 1e-7, M2lCompression::PerOperator)
        );
    }
}
