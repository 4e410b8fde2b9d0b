//! Fuzzes every file reader and decoder of zeroset with a mutation harness (see
//! `examples/common/fuzz/mod.rs` for the design and `docs/fuzzing.md` for how to use it).
//!
//! ```text
//! cargo run --release --example fuzz -- --minutes 60 [--seconds S] [--seed N] [--out DIR]
//!                                       [--targets ply-cloud,zsf-rbf,...]
//! ```
//!
//! The process is a supervisor: it runs a worker (this program with `--worker`) that fuzzes the
//! targets in turn, about 100 ms each, and reports its counts on stdout every second. Before
//! each execution the worker names the input file it is about to read; when the worker dies
//! (an abort, a refused allocation over 1 GiB, the 10 s hang watchdog, a signal, or 30 s of
//! silence), the supervisor copies that input to `DIR/<target>/` as a finding and starts a
//! new worker with the next seed. Panics are caught in the worker, which saves the input
//! itself. Progress is printed every 30 s; at the end a table per target: executions, distinct
//! outcomes, corpus size, panics, aborts, hangs, refused allocations, the largest peak of live
//! bytes of one execution and the slowest execution. The exit status is 1 if anything was
//! found. Inputs with new outcomes are kept in `target/fuzz/corpus/` and reused by later runs.
//!
//! Defaults: 10 minutes, seed 1, `--out target/fuzz/findings`.

#[path = "common/fuzz/mod.rs"]
mod fuzz;

use std::collections::{BTreeMap, HashSet};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use fuzz::targets::Target;
use fuzz::{Entry, Finding, Fuzzer, HANG_MARKER, alloc::REFUSAL_MARKER};

#[global_allocator]
static ALLOC: fuzz::alloc::Counting = fuzz::alloc::Counting;

struct Args {
    seconds: f64,
    seed: u64,
    out: PathBuf,
    targets: Vec<Target>,
    worker: bool,
    until_ms: u64,
    run_seeds: bool,
}

fn parse() -> Result<Args, String> {
    let root = fuzz::seeds::repo_root();
    let mut a = Args {
        seconds: 600.0,
        seed: 1,
        out: root.join("target/fuzz/findings"),
        targets: Target::ALL.to_vec(),
        worker: false,
        until_ms: 0,
        run_seeds: true,
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut val = || it.next().ok_or(format!("{k} needs a value"));
        match k.as_str() {
            "--minutes" => a.seconds = 60.0 * val()?.parse::<f64>().map_err(|e| e.to_string())?,
            "--seconds" => {
                a.seconds = val()?
                    .parse()
                    .map_err(|e: std::num::ParseFloatError| e.to_string())?
            }
            "--seed" => {
                a.seed = val()?
                    .parse()
                    .map_err(|e: std::num::ParseIntError| e.to_string())?
            }
            "--out" => a.out = PathBuf::from(val()?),
            "--targets" => {
                a.targets = val()?
                    .split(',')
                    .map(|n| Target::from_name(n).ok_or(format!("unknown target {n}")))
                    .collect::<Result<_, _>>()?
            }
            "--worker" => a.worker = true,
            "--until-ms" => {
                a.until_ms = val()?
                    .parse()
                    .map_err(|e: std::num::ParseIntError| e.to_string())?
            }
            "--no-seeds" => a.run_seeds = false,
            "-h" | "--help" => {
                println!(
                    "cargo run --release --example fuzz -- [--minutes M | --seconds S] [--seed N] [--out DIR] [--targets a,b]\ntargets: {}",
                    Target::ALL.map(|t| t.name()).join(", ")
                );
                std::process::exit(0);
            }
            _ => return Err(format!("unknown argument {k}")),
        }
    }
    Ok(a)
}

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

fn work_dir() -> PathBuf {
    fuzz::seeds::repo_root().join("target/fuzz")
}

/// Saves a finding's input and its description; returns the input's path.
fn save_finding(
    out: &Path,
    target: Target,
    kind: &str,
    bytes: &[u8],
    ext: &str,
    text: &str,
) -> PathBuf {
    let dir = out.join(target.name());
    let _ = std::fs::create_dir_all(&dir);
    let name = format!("{kind}-{:016x}", fuzz::hash(bytes));
    let path = dir.join(format!("{name}.{ext}"));
    let _ = std::fs::write(&path, bytes);
    let _ = std::fs::write(dir.join(format!("{name}.txt")), text);
    path
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("fuzz: {e}");
            return ExitCode::from(2);
        }
    };
    if args.worker {
        worker(&args)
    } else {
        supervisor(&args)
    }
}

// ---------------------------------------------------------------------------------------------
// The worker.

fn worker(args: &Args) -> ExitCode {
    fuzz::quiet_panics();
    fuzz::watchdog::start();
    let work = work_dir();
    let seeds = fuzz::seeds::all(&work.join("seeds"), false);
    let mut f = Fuzzer::new(&work.join("inputs"), &args.targets, &seeds, args.seed);
    f.current_file = Some(work.join("current"));
    let corpus = work.join("corpus");
    // The inputs earlier runs found interesting.
    for t in f.targets() {
        let Ok(rd) = std::fs::read_dir(corpus.join(t.name())) else {
            continue;
        };
        let mut entries = Vec::new();
        for p in rd.flatten().map(|e| e.path()).take(fuzz::CORPUS_MAX) {
            if let Ok(bytes) = std::fs::read(&p) {
                let ext = p
                    .extension()
                    .and_then(|e| e.to_str())
                    .unwrap_or(t.ext())
                    .to_owned();
                entries.push(Entry { bytes, ext });
            }
        }
        f.extend_corpus(t, entries);
    }
    f.corpus_dir = Some(corpus);
    let mut sites: HashSet<String> = HashSet::new();
    let mut report = |t: Target, e: &Entry, finding: &Finding| {
        let (kind, text) = match finding {
            Finding::Panic(m) => ("panic", m.clone()),
            Finding::BigAlloc(n) => ("alloc", format!("refused an allocation of {n} bytes")),
        };
        let site = format!("{} {}", t.name(), text.lines().next().unwrap_or(""));
        // At most one file per target and panic site per worker.
        if sites.insert(site) {
            let p = save_finding(&args.out, t, kind, &e.bytes, &e.ext, &text);
            println!(
                "finding {} {kind} {} {}",
                t.name(),
                p.display(),
                text.lines().next().unwrap_or("")
            );
        } else {
            println!("repeat {} {kind}", t.name());
        }
    };
    if args.run_seeds {
        for (t, e, finding) in f.run_seeds() {
            report(t, &e, &finding);
        }
    }
    let print_stats = |f: &Fuzzer| {
        for t in f.targets() {
            let s = f.stats(t);
            println!(
                "stats {} {} {} {} {} {} {} {}",
                t.name(),
                s.execs,
                s.outcomes,
                s.panics,
                s.big_allocs,
                s.max_peak,
                s.max_time.as_millis(),
                s.corpus
            );
        }
    };
    let mut last = Instant::now();
    let mut lane = 0;
    while now_ms() < args.until_ms {
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_millis(100) {
            let (ex, input) = f.step(lane);
            if let Some(finding) = &ex.finding {
                report(f.targets()[lane], &input, finding);
            }
        }
        lane = (lane + 1) % f.lanes();
        if last.elapsed() >= Duration::from_secs(1) {
            print_stats(&f);
            last = Instant::now();
        }
    }
    print_stats(&f);
    ExitCode::SUCCESS
}

// ---------------------------------------------------------------------------------------------
// The supervisor.

#[derive(Default, Clone)]
struct Row {
    execs: u64,
    panics: u64,
    big_allocs: u64,
    aborts: u64,
    hangs: u64,
    max_peak: usize,
    max_ms: u64,
    corpus: usize,
}

enum Msg {
    Line(String),
    Eof,
}

fn supervisor(args: &Args) -> ExitCode {
    let work = work_dir();
    let _ = std::fs::create_dir_all(&work);
    let _ = std::fs::create_dir_all(&args.out);
    let start = Instant::now();
    let until = now_ms() + (args.seconds * 1000.0) as u64;
    let exe = std::env::current_exe().expect("the example's path");
    let names: Vec<&str> = args.targets.iter().map(|t| t.name()).collect();
    println!(
        "fuzz: {} targets for {:.0} s, seed {}, findings in {}",
        names.len(),
        args.seconds,
        args.seed,
        args.out.display()
    );
    let mut totals: BTreeMap<&str, Row> = names.iter().map(|n| (*n, Row::default())).collect();
    let mut outcomes: BTreeMap<&str, usize> = BTreeMap::new();
    let mut findings: Vec<String> = Vec::new();
    let mut restarts = 0u64;
    let mut last_progress = Instant::now();
    while now_ms() < until {
        let stderr_path = work.join(format!("worker-{restarts}.stderr"));
        let stderr = std::fs::File::create(&stderr_path).expect("the worker's stderr file");
        let _ = std::fs::remove_file(work.join("current"));
        let mut child = Command::new(&exe)
            .args(["--worker", "--until-ms", &until.to_string()])
            .args([
                "--seed",
                &(args.seed.wrapping_add(restarts.wrapping_mul(0x9E37_79B9))).to_string(),
            ])
            .args([
                "--out",
                &args.out.display().to_string(),
                "--targets",
                &names.join(","),
            ])
            .args(if restarts > 0 {
                &["--no-seeds"][..]
            } else {
                &[][..]
            })
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .expect("starting the worker");
        let (tx, rx) = mpsc::channel();
        let stdout = child.stdout.take().expect("the worker's stdout");
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                match line {
                    Ok(l) => {
                        if tx.send(Msg::Line(l)).is_err() {
                            return;
                        }
                    }
                    Err(_) => break,
                }
            }
            let _ = tx.send(Msg::Eof);
        });
        let mut current: BTreeMap<String, Row> = BTreeMap::new();
        let mut silent_kill = false;
        let mut last_line = Instant::now();
        loop {
            match rx.recv_timeout(Duration::from_millis(500)) {
                Ok(Msg::Line(l)) => {
                    last_line = Instant::now();
                    let w: Vec<&str> = l.split_whitespace().collect();
                    match w.as_slice() {
                        ["stats", name, rest @ ..] if rest.len() == 7 => {
                            let n: Vec<u64> = rest.iter().map(|v| v.parse().unwrap_or(0)).collect();
                            current.insert(
                                name.to_string(),
                                Row {
                                    execs: n[0],
                                    panics: n[2],
                                    big_allocs: n[3],
                                    max_peak: n[4] as usize,
                                    max_ms: n[5],
                                    corpus: n[6] as usize,
                                    ..Row::default()
                                },
                            );
                            if let Some(k) = names.iter().find(|k| **k == *name) {
                                let o = outcomes.entry(k).or_default();
                                *o = (*o).max(n[1] as usize);
                            }
                        }
                        ["finding", ..] => {
                            println!("{l}");
                            findings.push(l.clone());
                        }
                        _ => {}
                    }
                }
                Ok(Msg::Eof) => break,
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    if last_line.elapsed() > Duration::from_secs(30) {
                        let _ = child.kill();
                        silent_kill = true;
                    }
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
            if last_progress.elapsed() >= Duration::from_secs(30) {
                last_progress = Instant::now();
                let execs: u64 = totals.values().map(|r| r.execs).sum::<u64>()
                    + current.values().map(|r| r.execs).sum::<u64>();
                let outs: usize = outcomes.values().sum();
                println!(
                    "[{:>5.0} s] {execs} executions, {outs} distinct outcomes, {} findings, {restarts} worker restarts",
                    start.elapsed().as_secs_f64(),
                    findings.len()
                );
            }
        }
        let status = child.wait().expect("waiting for the worker");
        for (name, r) in &current {
            if let Some(t) = totals.get_mut(name.as_str()) {
                t.execs += r.execs;
                t.panics += r.panics;
                t.big_allocs += r.big_allocs;
                t.max_peak = t.max_peak.max(r.max_peak);
                t.max_ms = t.max_ms.max(r.max_ms);
                t.corpus = t.corpus.max(r.corpus);
            }
        }
        if !status.success() {
            let err = std::fs::read_to_string(&stderr_path).unwrap_or_default();
            let cur = std::fs::read_to_string(work.join("current")).unwrap_or_default();
            let (name, input) = cur.trim_end().split_once('\t').unwrap_or(("?", ""));
            let kind = if silent_kill || err.contains(HANG_MARKER) {
                "hang"
            } else if err.contains(REFUSAL_MARKER) {
                "alloc"
            } else {
                "abort"
            };
            let target = Target::from_name(name);
            let tail: String = {
                let lines: Vec<&str> = err.lines().collect();
                lines[lines.len().saturating_sub(40)..].join("\n")
            };
            let text = format!("worker exit: {status}\n{tail}\n");
            match (target, std::fs::read(input)) {
                (Some(t), Ok(bytes)) => {
                    let ext = Path::new(input)
                        .extension()
                        .and_then(|e| e.to_str())
                        .unwrap_or("dat");
                    let p = save_finding(&args.out, t, kind, &bytes, ext, &text);
                    let row = totals.get_mut(t.name()).expect("a target");
                    match kind {
                        "hang" => row.hangs += 1,
                        "alloc" => row.big_allocs += 1,
                        _ => row.aborts += 1,
                    }
                    let l = format!("finding {} {kind} {} {}", t.name(), p.display(), status);
                    println!("{l}");
                    findings.push(l);
                }
                _ => {
                    let l = format!(
                        "finding ? {kind}: worker exit {status} outside an execution:\n{tail}"
                    );
                    println!("{l}");
                    findings.push(l);
                }
            }
            restarts += 1;
        } else {
            break;
        }
    }
    println!();
    println!(
        "{:<12} {:>10} {:>9} {:>7} {:>7} {:>7} {:>6} {:>10} {:>10} {:>9}",
        "target",
        "execs",
        "outcomes",
        "corpus",
        "panics",
        "aborts",
        "hangs",
        "allocs>1G",
        "peak MB",
        "slowest"
    );
    let mut total = Row::default();
    for (name, r) in &totals {
        println!(
            "{:<12} {:>10} {:>9} {:>7} {:>7} {:>7} {:>6} {:>10} {:>10.1} {:>7} ms",
            name,
            r.execs,
            outcomes.get(name).copied().unwrap_or(0),
            r.corpus,
            r.panics,
            r.aborts,
            r.hangs,
            r.big_allocs,
            r.max_peak as f64 / 1e6,
            r.max_ms
        );
        total.execs += r.execs;
        total.panics += r.panics;
        total.aborts += r.aborts;
        total.hangs += r.hangs;
        total.big_allocs += r.big_allocs;
    }
    println!(
        "{:<12} {:>10} {:>9} {:>7} {:>7} {:>7} {:>6} {:>10}",
        "all",
        total.execs,
        outcomes.values().sum::<usize>(),
        "",
        total.panics,
        total.aborts,
        total.hangs,
        total.big_allocs
    );
    println!(
        "{:.0} s, {} worker restarts, {} findings saved under {}",
        start.elapsed().as_secs_f64(),
        restarts,
        findings.len(),
        args.out.display()
    );
    if findings.is_empty() {
        ExitCode::SUCCESS
    } else {
        println!("copy each finding's input to tests/fuzz-regressions/<target>/ once it is fixed");
        ExitCode::from(1)
    }
}
