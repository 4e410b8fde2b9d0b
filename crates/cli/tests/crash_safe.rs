//! Crash-safe outputs: `zeroset mesh`, `fit` and `restore` are killed (SIGKILL) 100 times, on a
//! seeded schedule, while they write over an existing output. After every kill the output is
//! either the old file, byte for byte, or the complete new one (the commands are
//! deterministic, so "complete" is "identical to an unkilled run's output"); never a partial
//! file. A kill between the temporary file's creation and its rename leaves that temporary
//! file (`.<name>.<pid>.<n>.tmp`) behind; the next run over the same output removes it.
//!
//! The kills are aimed: some at a random time in the command's run (most land before the
//! write starts), most while the temporary file exists (the write and its fsync), some just
//! after the rename. The test prints how many landed in each phase.
#![cfg(unix)]

use std::ffi::OsString;
use std::fs;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

/// The schedule's random numbers, the same on every run.
use zeroset_field_core::rng::SplitMix64 as Rng;

/// Kills in all.
const KILLS: usize = 100;
/// The schedule's seed.
const SEED: u64 = 0x5eed_2024_0024_0004;
/// What the output holds before each killed run.
const OLD: &[u8] = b"old output: a killed run must leave these bytes or the complete new file\n";

/// A command under test: its arguments (output last) and what an unkilled run writes.
struct Case {
    name: &'static str,
    args: Vec<OsString>,
    output: PathBuf,
    reference: Vec<u8>,
    /// In unkilled runs: from the start to the temporary file's appearance (median), how long
    /// it lived (the shortest time seen: the fsync's time varies), and the run's length
    /// (median).
    appear: Duration,
    window: Duration,
    total: Duration,
}

/// How the kill is aimed.
#[derive(Debug, Clone, Copy)]
enum Aim {
    /// At a uniform time in [0, the unkilled run's length].
    Timed(f64),
    /// Once the temporary file exists, after a fraction of half the shortest time it lived in
    /// unkilled runs.
    DuringWrite(f64),
    /// Once the temporary file has been renamed (or the command has ended).
    AfterRename,
}

/// Where the kill landed, as the file system tells it afterwards.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Killed before the temporary file was created: the old output, no temporary file.
    Before,
    /// Killed between its creation and the rename: the old output and a temporary file.
    During,
    /// Killed after the rename: the new output.
    After,
    /// The command had ended before the kill.
    Exited,
}

fn command(args: &[OsString]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_zeroset"));
    // No operator disk cache: the tests never write to the user's.
    c.args(args)
        .env("ZEROSET_CACHE_DIR", "")
        .env_remove("ZEROSET_MEMORY_LIMIT");
    c
}

fn run_ok(args: &[OsString]) -> Output {
    let o = command(args)
        .output()
        .expect("cannot run the zeroset binary");
    assert!(
        o.status.success(),
        "zeroset {args:?} failed:\n{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn os(args: &[&str]) -> Vec<OsString> {
    args.iter().map(OsString::from).collect()
}

/// The names in `dir` of the form `.<name>.<...>.tmp`: `output`'s temporary files.
fn temporaries(output: &Path) -> Vec<String> {
    let dir = output.parent().unwrap();
    let name = output.file_name().unwrap().to_str().unwrap();
    let prefix = format!(".{name}.");
    let mut found: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|f| f.starts_with(&prefix) && f.ends_with(".tmp"))
        .collect();
    found.sort();
    found
}

/// Whether the temporary file of the process `pid` for `output` exists.
fn has_temporary_of(output: &Path, pid: u32) -> bool {
    let name = output.file_name().unwrap().to_str().unwrap();
    let prefix = format!(".{name}.{pid}.");
    temporaries(output).iter().any(|f| f.starts_with(&prefix))
}

/// Runs `args` to the end, watching `output`'s directory: the times from the start to the
/// temporary file's appearance and disappearance, and to the exit.
fn watched_run(args: &[OsString], output: &Path) -> (Option<Duration>, Option<Duration>, Duration) {
    let start = Instant::now();
    let mut child = spawn(args);
    let pid = child.id();
    let (mut appear, mut gone) = (None, None);
    let status = loop {
        let seen = has_temporary_of(output, pid);
        let t = start.elapsed();
        if seen && appear.is_none() {
            appear = Some(t);
        }
        if !seen && appear.is_some() && gone.is_none() {
            gone = Some(t);
        }
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
    };
    assert!(status.success(), "zeroset {args:?} failed: {status}");
    (appear, gone, start.elapsed())
}

fn spawn(args: &[OsString]) -> Child {
    command(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("cannot run the zeroset binary")
}

/// Unkilled runs of `args`: checks that the output is deterministic and measures the phases.
fn case(name: &'static str, args: Vec<OsString>, output: PathBuf) -> Case {
    run_ok(&args);
    let reference = fs::read(&output).unwrap();
    assert_ne!(reference, OLD);
    let (mut appear, mut window, mut total) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..5 {
        fs::write(&output, OLD).unwrap();
        let (a, g, t) = watched_run(&args, &output);
        assert_eq!(
            fs::read(&output).unwrap(),
            reference,
            "{name}: the output differs between two unkilled runs"
        );
        assert_eq!(temporaries(&output), Vec::<String>::new());
        if let (Some(a), Some(g)) = (a, g) {
            appear.push(a);
            window.push(g - a);
        }
        total.push(t);
    }
    let median = |v: &mut Vec<Duration>, default: Duration| {
        v.sort();
        v.get(v.len() / 2).copied().unwrap_or(default)
    };
    let total = median(&mut total, Duration::ZERO);
    // The temporary file may live too briefly to be seen: then aim at the end of the run.
    let appear = median(&mut appear, total.mul_f64(0.9));
    let window = window
        .into_iter()
        .min()
        .unwrap_or(Duration::from_micros(200));
    Case {
        name,
        args,
        output,
        reference,
        appear,
        window,
        total,
    }
}

/// Kills one run of `case` as `aim` says; returns its exit status, its pid and whether the
/// temporary file was seen before the kill.
fn killed_run(case: &Case, aim: Aim) -> (ExitStatus, u32, bool) {
    let start = Instant::now();
    let mut child = spawn(&case.args);
    let pid = child.id();
    let exited = |child: &mut Child| child.try_wait().unwrap().is_some();
    let mut seen = false;
    match aim {
        Aim::Timed(f) => {
            let at = case.total.mul_f64(f);
            while start.elapsed() < at && !exited(&mut child) {
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        Aim::DuringWrite(f) => {
            // Polls as fast as it can: the window is a few milliseconds.
            while !seen && !exited(&mut child) {
                seen = has_temporary_of(&case.output, pid);
            }
            let at = Instant::now();
            let wait = case.window.mul_f64(0.5 * f);
            while at.elapsed() < wait {
                std::hint::spin_loop();
            }
        }
        Aim::AfterRename => loop {
            let now = has_temporary_of(&case.output, pid);
            if (seen && !now) || exited(&mut child) {
                break;
            }
            seen |= now;
        },
    }
    // SIGKILL; an error only says that the command has already ended.
    let _ = child.kill();
    (child.wait().unwrap(), pid, seen)
}

#[test]
fn killed_writers_leave_the_old_output_or_the_complete_new_one() {
    let begin = Instant::now();
    // On the target's disk, not a tmpfs /tmp: fsync there takes long enough for kills to land
    // while the temporary file exists.
    let dir = tempfile::tempdir_in(env!("CARGO_TARGET_TMPDIR")).unwrap();
    let d = |name: &str| dir.path().join(name);

    // Small inputs: 300 points of the sample, a 24³ sampled field.
    let sample = fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/bunny_2k.xyzn"
    ))
    .unwrap();
    let points: String = sample.lines().take(300).flat_map(|l| [l, "\n"]).collect();
    fs::write(d("points.xyzn"), points).unwrap();
    let points = d("points.xyzn").into_os_string();
    let field = d("field.zsf").into_os_string();
    let mut setup = vec![points.clone()];
    setup.extend(os(&["--method", "rbf", "--sampled", "--grid", "24,24,24"]));
    setup.extend(os(&["--quiet", "-o"]));
    setup.push(field.clone());
    setup.insert(0, "fit".into());
    run_ok(&setup);

    let with_output = |mut args: Vec<OsString>, output: &Path| {
        args.extend(os(&["--threads", "1", "--force", "-o"]));
        args.push(output.into());
        args
    };
    let mut fit = vec!["fit".into(), points.clone()];
    fit.extend(os(&["--method", "rbf", "--quiet"]));
    let mut mesh = vec!["mesh".into(), field.clone()];
    mesh.extend(os(&["--resolution", "48", "--quiet"]));
    let mut restore = vec!["restore".into(), field.clone()];
    restore.extend(os(&[
        "--mode",
        "denoise",
        "--mask",
        "-0.05,0.05,-0.03:0.05,0.12,0.06",
        "--coarse",
        "6,6,4",
    ]));
    let cases = [
        case("mesh", with_output(mesh, &d("mesh.ply")), d("mesh.ply")),
        case("fit", with_output(fit, &d("fit.zsf")), d("fit.zsf")),
        case(
            "restore",
            with_output(restore, &d("restore.zsf")),
            d("restore.zsf"),
        ),
    ];
    for c in &cases {
        eprintln!(
            "{:8} unkilled: temporary file from {:.1} ms for {:.2} ms, exit at {:.1} ms, {} bytes",
            c.name,
            c.appear.as_secs_f64() * 1e3,
            c.window.as_secs_f64() * 1e3,
            c.total.as_secs_f64() * 1e3,
            c.reference.len()
        );
    }

    let mut rng = Rng(SEED);
    let mut tally = [[0usize; 4]; 3];
    for kill in 0..KILLS {
        let which = kill % cases.len();
        let c = &cases[which];
        let r = rng.unit();
        let aim = if r < 0.25 {
            Aim::Timed(rng.unit())
        } else if r < 0.85 {
            Aim::DuringWrite(rng.unit())
        } else {
            Aim::AfterRename
        };
        fs::write(&c.output, OLD).unwrap();
        let start = Instant::now();
        let (status, pid, seen) = killed_run(c, aim);
        let what = format!(
            "kill {kill} ({}, {aim:?}, pid {pid}, temporary file seen: {seen}, {status})",
            c.name
        );
        let bytes = fs::read(&c.output).unwrap_or_else(|e| panic!("{what}: output gone: {e}"));
        let own_temporary = has_temporary_of(&c.output, pid);
        let phase = if status.signal().is_none() {
            assert!(status.success(), "{what}: failed");
            Phase::Exited
        } else if bytes == OLD {
            if own_temporary {
                Phase::During
            } else {
                Phase::Before
            }
        } else {
            Phase::After
        };
        assert!(
            bytes == OLD || bytes == c.reference,
            "{what}: a partial output of {} bytes (old {}, complete {})",
            bytes.len(),
            OLD.len(),
            c.reference.len()
        );
        if matches!(phase, Phase::After | Phase::Exited) {
            assert!(
                !own_temporary,
                "{what}: a temporary file beside the new output"
            );
        }
        tally[which][phase as usize] += 1;
        // Shown when the test fails (or with --nocapture).
        eprintln!(
            "{what}: {phase:?} after {:.1} ms",
            start.elapsed().as_secs_f64() * 1e3
        );
        // A rerun completes the output and removes every stale temporary file.
        if !temporaries(&c.output).is_empty() {
            run_ok(&c.args);
            assert_eq!(fs::read(&c.output).unwrap(), c.reference, "{what}: rerun");
            assert_eq!(
                temporaries(&c.output),
                Vec::<String>::new(),
                "{what}: the rerun left temporary files"
            );
        }
    }

    // Every output ends complete, and nothing but the inputs and outputs is left.
    for c in &cases {
        run_ok(&c.args);
        assert_eq!(fs::read(&c.output).unwrap(), c.reference, "{}", c.name);
    }
    let mut left: Vec<String> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(
        left,
        [
            "field.zsf",
            "fit.zsf",
            "mesh.ply",
            "points.xyzn",
            "restore.zsf"
        ]
    );

    let sum = |p: Phase| tally.iter().map(|t| t[p as usize]).sum::<usize>();
    for (c, t) in cases.iter().zip(&tally) {
        eprintln!(
            "{:8} killed before the write {:3}, during {:3}, after the rename {:3}; exited first {:3}",
            c.name, t[0], t[1], t[2], t[3]
        );
    }
    eprintln!(
        "all      killed before the write {:3}, during {:3}, after the rename {:3}; exited first {:3} \
         ({:.1} s)",
        sum(Phase::Before),
        sum(Phase::During),
        sum(Phase::After),
        sum(Phase::Exited),
        begin.elapsed().as_secs_f64()
    );
    // The aim must work, or the test proves little: most aimed kills land in the window of a
    // few milliseconds (the write and its fsync).
    assert!(
        sum(Phase::During) >= KILLS / 10,
        "only {} of {KILLS} kills landed during the write",
        sum(Phase::During)
    );
}
