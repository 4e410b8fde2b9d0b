//! A mutation fuzzer for every file reader of zeroset, on the stable toolchain.
//!
//! No coverage-guided fuzzer runs here on stable Rust (cargo-fuzz needs nightly's sanitizer
//! coverage; cargo-afl needs AFL++ built and installed), so this is a mutation harness with a
//! cheap coverage proxy, shared by `examples/fuzz.rs` (the long run, by hand) and
//! `tests/fuzz.rs` (a short fixed-seed run and the regression files, in `cargo test`):
//!
//! - **Targets** ([`targets`]): every public reader and decoder — PLY point clouds and meshes
//!   (ascii and binary), STL and OBJ meshes, xyz, CSV, GemPy, `.xyv`/`.xyzv`, `.zsf` of every kind — and the
//!   `zeroset info` flow (OBJ and STL to the mesh reader). Each execution writes the input to a
//!   file with the target's extension and calls every reader of the format on it.
//! - **Seeds** ([`seeds`]): small real files and shrunk or cut copies of big ones, hand-written
//!   variants, and files written by the library's writers and fits (cached under `target/`).
//! - **Mutations** ([`mutate`]): 1–6 stacked byte-level and format-aware mutations of a corpus
//!   entry, spliced with another; `.zsf` inputs get their sizes and CRC-32 resealed most of the
//!   time, or nothing past the checksum would be reached.
//! - **Coverage proxy**: each execution's outcome (what every call returned, normalised:
//!   [`targets::normalise`]); an input with an outcome not seen before joins the corpus. The
//!   count of distinct outcomes is reported.
//! - **Findings**: a panic (caught with `catch_unwind`; the panic hook only records the
//!   message and location), an allocation that would take one execution over 1 GiB above what
//!   was live when it started ([`alloc`]: the request is refused, recorded, and aborts the
//!   process unless the reader handles the failure), an execution over 10 s ([`watchdog`]:
//!   the process aborts), and any other abort (the long run's supervisor restarts the worker
//!   and keeps the input that was being read).

#![allow(dead_code)]

pub mod alloc;
pub mod mutate;
#[path = "../rng.rs"]
pub mod rng;
pub mod seeds;
#[path = "../shapes.rs"]
pub mod shapes;
pub mod targets;

use std::collections::HashSet;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

use rng::SplitMix64;
use seeds::Seed;
use targets::Target;

/// An execution that runs longer than this is a hang.
pub const HANG: Duration = Duration::from_secs(10);

/// Written to stderr by the watchdog before it aborts the process.
pub const HANG_MARKER: &str = "fuzz: hang:";

/// The most inputs kept per target (a full corpus replaces a random entry).
pub const CORPUS_MAX: usize = 4000;

/// Inputs larger than this are not saved to the corpus folder (it would grow to gigabytes).
const SAVE_MAX: usize = 64 * 1024;

/// The per-execution hang watchdog: a thread that aborts the process when an execution has run
/// over [`HANG`], after writing [`HANG_MARKER`] and the target to stderr.
pub mod watchdog {
    use super::*;

    static START_MS: AtomicU64 = AtomicU64::new(0);
    static WHAT: Mutex<String> = Mutex::new(String::new());

    fn clock() -> &'static Instant {
        static T0: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
        T0.get_or_init(Instant::now)
    }

    /// Starts the watchdog thread (once).
    pub fn start() {
        static ONCE: std::sync::Once = std::sync::Once::new();
        ONCE.call_once(|| {
            clock();
            std::thread::spawn(|| {
                loop {
                    std::thread::sleep(Duration::from_millis(200));
                    let s = START_MS.load(Relaxed);
                    if s != 0 {
                        let now = clock().elapsed().as_millis() as u64 + 1;
                        if now - s > HANG.as_millis() as u64 {
                            let what = WHAT.lock().map(|w| w.clone()).unwrap_or_default();
                            eprintln!(
                                "{HANG_MARKER} an execution ran over {} s: {what}",
                                HANG.as_secs()
                            );
                            std::process::abort();
                        }
                    }
                }
            });
        });
    }

    /// Marks the start of an execution of `what` (a target and file).
    pub fn begin(what: &str) {
        if let Ok(mut w) = WHAT.lock() {
            w.clear();
            w.push_str(what);
        }
        START_MS.store(clock().elapsed().as_millis() as u64 + 1, Relaxed);
    }

    /// Marks the end of the execution.
    pub fn end() {
        START_MS.store(0, Relaxed);
    }
}

static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// Installs a panic hook that prints nothing and records the message and location of the
/// latest panic for [`Fuzzer::execute`].
pub fn quiet_panics() {
    std::panic::set_hook(Box::new(|info| {
        let msg = if let Some(s) = info.payload().downcast_ref::<&str>() {
            (*s).to_owned()
        } else if let Some(s) = info.payload().downcast_ref::<String>() {
            s.clone()
        } else {
            "(non-string payload)".to_owned()
        };
        let at = info
            .location()
            .map(|l| format!("{}:{}:{}", l.file(), l.line(), l.column()))
            .unwrap_or_default();
        let bt = std::backtrace::Backtrace::force_capture().to_string();
        // Keep the frames of the workspace's own code.
        let frames: Vec<&str> = bt
            .lines()
            .filter(|l| l.contains("zeroset") || l.contains("crates/"))
            .take(16)
            .collect();
        if let Ok(mut p) = LAST_PANIC.lock() {
            *p = Some(format!("panicked at {at}: {msg}\n{}", frames.join("\n")));
        }
    }));
}

/// A finding of one execution.
#[derive(Debug, Clone, PartialEq)]
pub enum Finding {
    /// A panic: the message, location and the workspace's frames.
    Panic(String),
    /// A refused allocation: the size of the largest refused request.
    BigAlloc(usize),
}

/// What one execution did.
#[derive(Debug, Clone)]
pub struct Execution {
    /// The outcome ([`targets::run`]); `panic` for a panic.
    pub outcome: String,
    /// A panic or a refused allocation.
    pub finding: Option<Finding>,
    /// Peak bytes held above the start (0 without the counting allocator).
    pub peak: usize,
    /// Wall time.
    pub elapsed: Duration,
}

/// Per-target counts.
#[derive(Debug, Clone, Default)]
pub struct Stats {
    /// Executions.
    pub execs: u64,
    /// Distinct outcomes.
    pub outcomes: usize,
    /// Executions that panicked.
    pub panics: u64,
    /// Executions whose allocations were refused (over 1 GiB).
    pub big_allocs: u64,
    /// The largest peak of an execution, bytes.
    pub max_peak: usize,
    /// The slowest execution.
    pub max_time: Duration,
    /// The corpus size.
    pub corpus: usize,
}

/// An input of the corpus.
#[derive(Clone, Debug)]
pub struct Entry {
    /// The content.
    pub bytes: Vec<u8>,
    /// The extension of its file.
    pub ext: String,
}

/// One target's state.
struct Lane {
    target: Target,
    corpus: Vec<Entry>,
    seen: HashSet<String>,
    stats: Stats,
}

/// The engine: a corpus and a set of outcomes per target, a seeded generator, and a scratch
/// folder for the input files.
pub struct Fuzzer {
    dir: PathBuf,
    lanes: Vec<Lane>,
    rng: SplitMix64,
    /// If set, `"<target>\t<input path>"` is written here before each execution, so that a
    /// supervisor knows which input killed the process.
    pub current_file: Option<PathBuf>,
    /// If set, inputs with a new outcome are also saved here (`<target>/<hash>.<ext>`).
    pub corpus_dir: Option<PathBuf>,
}

/// A 64-bit FNV-1a hash, for file names.
pub fn hash(bytes: &[u8]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for &b in bytes {
        h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
    }
    h
}

impl Fuzzer {
    /// A fuzzer over `targets`, seeded from `seeds`, writing inputs under `dir`.
    pub fn new(dir: &Path, targets: &[Target], seeds: &[Seed], seed: u64) -> Self {
        std::fs::create_dir_all(dir).expect("the fuzzer's scratch folder");
        let lanes = targets
            .iter()
            .map(|&t| Lane {
                target: t,
                corpus: seeds::for_target(t, seeds)
                    .into_iter()
                    .map(|s| Entry {
                        ext: if t == Target::Info {
                            s.ext
                        } else {
                            t.ext().into()
                        },
                        bytes: s.bytes,
                    })
                    .collect(),
                seen: HashSet::new(),
                stats: Stats::default(),
            })
            .collect();
        Fuzzer {
            dir: dir.to_owned(),
            lanes,
            rng: SplitMix64(seed),
            current_file: None,
            corpus_dir: None,
        }
    }

    /// The targets, in order.
    pub fn targets(&self) -> Vec<Target> {
        self.lanes.iter().map(|l| l.target).collect()
    }

    /// Adds inputs to a target's corpus (a saved corpus from an earlier run).
    pub fn extend_corpus(&mut self, target: Target, entries: Vec<Entry>) {
        if let Some(l) = self.lanes.iter_mut().find(|l| l.target == target) {
            l.corpus.extend(entries);
        }
    }

    /// The counts of `target`.
    pub fn stats(&self, target: Target) -> Stats {
        let l = self
            .lanes
            .iter()
            .find(|l| l.target == target)
            .expect("a target of this fuzzer");
        Stats {
            outcomes: l.seen.len(),
            corpus: l.corpus.len(),
            ..l.stats.clone()
        }
    }

    /// The path an input of `target` with extension `ext` is written to.
    pub fn input_path(&self, target: Target, ext: &str) -> PathBuf {
        self.dir.join(format!("input-{}.{ext}", target.name()))
    }

    /// Runs `target` on `bytes` (in a file with extension `ext`), catching panics and
    /// watching allocations and time. Does not touch the corpus.
    pub fn execute(&self, target: Target, bytes: &[u8], ext: &str) -> Execution {
        let path = self.input_path(target, ext);
        std::fs::write(&path, bytes).expect("writing the input file");
        let what = format!("{} {}", target.name(), path.display());
        if let Some(c) = &self.current_file {
            std::fs::write(c, format!("{}\t{}\n", target.name(), path.display()))
                .expect("writing the current-input file");
        }
        if let Ok(mut p) = LAST_PANIC.lock() {
            *p = None;
        }
        watchdog::begin(&what);
        let t0 = Instant::now();
        alloc::begin();
        let r = std::panic::catch_unwind(AssertUnwindSafe(|| targets::run(target, &path, bytes)));
        let (peak, refused) = alloc::end();
        let elapsed = t0.elapsed();
        watchdog::end();
        let (outcome, finding) = match r {
            Ok(o) => (o, None),
            Err(_) => {
                let msg = LAST_PANIC
                    .lock()
                    .ok()
                    .and_then(|mut p| p.take())
                    .unwrap_or_else(|| "panic (no message recorded)".into());
                ("panic".to_owned(), Some(Finding::Panic(msg)))
            }
        };
        let finding = finding.or((refused > 0).then_some(Finding::BigAlloc(refused)));
        Execution {
            outcome,
            finding,
            peak,
            elapsed,
        }
    }

    /// One fuzzing step on lane `i`: mutate a corpus entry, execute, keep it if its outcome is
    /// new. Returns the execution and the input.
    pub fn step(&mut self, i: usize) -> (Execution, Entry) {
        let n = self.lanes[i].corpus.len();
        let target = self.lanes[i].target;
        let input = if n == 0 {
            Entry {
                bytes: Vec::new(),
                ext: target.ext().into(),
            }
        } else {
            let a = self.rng.below(n);
            let b = self.rng.below(n);
            let lane = &self.lanes[i];
            let bytes = mutate::mutate(
                &mut self.rng,
                &lane.corpus[a].bytes,
                &lane.corpus[b].bytes,
                target.seal(),
            );
            Entry {
                bytes,
                ext: lane.corpus[a].ext.clone(),
            }
        };
        let ex = self.execute(target, &input.bytes, &input.ext);
        self.record(i, &ex, &input);
        (ex, input)
    }

    /// Counts an execution of lane `i` and keeps its input if the outcome is new.
    fn record(&mut self, i: usize, ex: &Execution, input: &Entry) {
        let replace = self.rng.below(CORPUS_MAX);
        let lane = &mut self.lanes[i];
        let s = &mut lane.stats;
        s.execs += 1;
        s.max_peak = s.max_peak.max(ex.peak);
        s.max_time = s.max_time.max(ex.elapsed);
        match &ex.finding {
            Some(Finding::Panic(_)) => s.panics += 1,
            Some(Finding::BigAlloc(_)) => s.big_allocs += 1,
            None => {}
        }
        if ex.finding.is_none() && lane.seen.insert(ex.outcome.clone()) {
            if let Some(dir) = self
                .corpus_dir
                .as_ref()
                .filter(|_| input.bytes.len() <= SAVE_MAX)
            {
                let d = dir.join(lane.target.name());
                let _ = std::fs::create_dir_all(&d);
                let _ = std::fs::write(
                    d.join(format!("{:016x}.{}", hash(&input.bytes), input.ext)),
                    &input.bytes,
                );
            }
            if lane.corpus.len() < CORPUS_MAX {
                lane.corpus.push(input.clone());
            } else {
                lane.corpus[replace] = input.clone();
            }
        }
    }

    /// Runs the seeds of every lane once (they define the first outcomes); returns the
    /// findings as `(target, seed index, finding)`.
    pub fn run_seeds(&mut self) -> Vec<(Target, Entry, Finding)> {
        let mut found = Vec::new();
        for i in 0..self.lanes.len() {
            let target = self.lanes[i].target;
            let entries = self.lanes[i].corpus.clone();
            for e in entries {
                let ex = self.execute(target, &e.bytes, &e.ext);
                let lane = &mut self.lanes[i];
                lane.stats.execs += 1;
                lane.seen.insert(ex.outcome.clone());
                if let Some(f) = ex.finding {
                    found.push((target, e, f));
                }
            }
        }
        found
    }

    /// The number of lanes.
    pub fn lanes(&self) -> usize {
        self.lanes.len()
    }
}

/// The regression files: `tests/fuzz-regressions/<target>/<file>`, each with its target and
/// extension (the file's own, else the target's).
pub fn regression_files(root: &Path) -> Vec<(Target, PathBuf, String)> {
    let mut out = Vec::new();
    let Ok(dirs) = std::fs::read_dir(root) else {
        return out;
    };
    let mut dirs: Vec<PathBuf> = dirs.flatten().map(|e| e.path()).collect();
    dirs.sort();
    for d in dirs {
        let Some(target) = d
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(Target::from_name)
        else {
            continue;
        };
        let mut files: Vec<PathBuf> = std::fs::read_dir(&d)
            .map(|r| {
                r.flatten()
                    .map(|e| e.path())
                    .filter(|p| p.is_file())
                    .collect()
            })
            .unwrap_or_default();
        files.sort();
        for f in files {
            let ext = match target {
                Target::Info => f
                    .extension()
                    .and_then(|e| e.to_str())
                    .unwrap_or("dat")
                    .to_owned(),
                t => t.ext().to_owned(),
            };
            out.push((target, f, ext));
        }
    }
    out
}
