//! Fuzzing in the test suite: every regression file under `tests/fuzz-regressions/<target>/`
//! is read by its target, then a short fixed-seed mutation pass runs over every reader (a few
//! hundred executions each, at most about 25 s in all). Either fails on a panic, an allocation
//! over 1 GiB above the execution's start (refused by the counting allocator) or an
//! execution over 10 s (the watchdog aborts the test binary, naming the input). The long run is
//! `cargo run --release --example fuzz -- --minutes 60`; see `docs/fuzzing.md`.

#[path = "../examples/common/fuzz/mod.rs"]
mod fuzz;

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use fuzz::targets::Target;
use fuzz::{Finding, Fuzzer};

#[global_allocator]
static ALLOC: fuzz::alloc::Counting = fuzz::alloc::Counting;

/// The allocator's counters are global: one test at a time.
static SERIAL: Mutex<()> = Mutex::new(());

fn scratch(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("fuzz-{name}-{}", std::process::id()))
}

fn seeds() -> Vec<fuzz::seeds::Seed> {
    fuzz::seeds::all(
        &PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fuzz-seeds"),
        true,
    )
}

fn describe(f: &Finding) -> String {
    match f {
        Finding::Panic(m) => m.clone(),
        Finding::BigAlloc(n) => format!("refused an allocation of {n} bytes"),
    }
}

#[test]
fn regression_files_are_read_without_panics() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    fuzz::quiet_panics();
    fuzz::watchdog::start();
    let root = fuzz::seeds::repo_root().join("tests/fuzz-regressions");
    let dir = scratch("regressions");
    let f = Fuzzer::new(&dir, &[], &[], 0);
    let mut failures = Vec::new();
    let files = fuzz::regression_files(&root);
    assert!(
        files.len() >= 3,
        "no regression files found under {}",
        root.display()
    );
    for (target, path, ext) in &files {
        let bytes = std::fs::read(path).expect("a regression file");
        let ex = f.execute(*target, &bytes, ext);
        if let Some(finding) = &ex.finding {
            failures.push(format!(
                "{} ({}): {}",
                path.display(),
                target.name(),
                describe(finding)
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        failures.is_empty(),
        "{} of {} regression files fail:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n\n")
    );
}

#[test]
fn short_mutation_run_finds_nothing() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    assert!(
        fuzz::alloc::installed(),
        "the counting allocator is not installed"
    );
    fuzz::quiet_panics();
    fuzz::watchdog::start();
    let dir = scratch("short");
    let seeds = seeds();
    let mut f = Fuzzer::new(&dir, &Target::ALL, &seeds, 0x5EED);
    let mut failures: Vec<String> = f
        .run_seeds()
        .into_iter()
        .map(|(t, e, finding)| {
            format!(
                "a seed of {} ({} bytes): {}",
                t.name(),
                e.bytes.len(),
                describe(&finding)
            )
        })
        .collect();
    // Round-robin over the targets: at most PER_TARGET executions each, within BUDGET.
    const PER_TARGET: u64 = 400;
    const BUDGET: Duration = Duration::from_secs(25);
    let start = Instant::now();
    let saved = scratch("short-findings");
    let mut done = false;
    while !done && start.elapsed() < BUDGET {
        done = true;
        for (i, t) in Target::ALL.iter().enumerate() {
            if f.stats(*t).execs >= PER_TARGET {
                continue;
            }
            done = false;
            for _ in 0..10 {
                let (ex, input) = f.step(i);
                if let Some(finding) = &ex.finding {
                    std::fs::create_dir_all(saved.join(t.name())).unwrap();
                    let p = saved.join(t.name()).join(format!(
                        "{:016x}.{}",
                        fuzz::hash(&input.bytes),
                        input.ext
                    ));
                    std::fs::write(&p, &input.bytes).unwrap();
                    failures.push(format!(
                        "{} ({}): {}",
                        p.display(),
                        t.name(),
                        describe(finding)
                    ));
                }
            }
        }
    }
    let mut table = String::new();
    for t in Target::ALL {
        let s = f.stats(t);
        table.push_str(&format!(
            "{:<12} {:>6} execs {:>5} outcomes {:>4} panics {:>3} allocs>1G  peak {:>7.1} MB  slowest {:>5} ms\n",
            t.name(),
            s.execs,
            s.outcomes,
            s.panics,
            s.big_allocs,
            s.max_peak as f64 / 1e6,
            s.max_time.as_millis()
        ));
    }
    eprintln!("{table}{:.1} s", start.elapsed().as_secs_f64());
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        failures.is_empty(),
        "{} findings (inputs kept; copy them to tests/fuzz-regressions/<target>/ once fixed):\n{}\n{table}",
        failures.len(),
        failures.join("\n\n")
    );
}
