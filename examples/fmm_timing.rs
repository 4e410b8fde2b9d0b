//! Times the fast multipole evaluation of an RBF field against zeroset's exact parallel direct
//! sum, on a field fitted to real data (see `common/fmm_data.rs`): the issue's bar is 10,000
//! sources × 100,000 targets.
//!
//! ```text
//! cargo run --release --example fmm_timing -- [--kernel r|r3] [--sources N] [--targets M,…]
//!     [--order P] [--leaf L] [--tolerance T] [--repeat K] [--cloud FILE] [--data DIR] [--dump DIR] [--no-direct]
//!     [--unknown-targets] [--compression shared|per-operator]
//! ```
//!
//! Targets are drawn uniformly (seeded) in the field's bounds, and each field is built for
//! their count (`FmmOptions::with_expected_points`; `--unknown-targets` leaves it unset). The operators' precomputation
//! (`ops`) depends on the kernel and order only: it is done once, on the first build, timed,
//! and shared by all later builds (as `FmmField::with_operators` lets an application do). For
//! each target count it prints the median over `K` runs of the build (tree, P2M/M2M, M2L, L2L)
//! and the evaluation, their sum (`total`), the direct sum, the ratio `direct / total`, the
//! ratio with the one-time operators counted too (`ratio_ops`), and the max / RMS error
//! relative to the direct sum's largest value; then the stages of the last build. `--dump DIR` (one target count) also writes `sources.npy`,
//! `weights.npy`, `poly.npy` (constant, x, y, z), `targets.npy`, `fmm_values.npy`,
//! `direct_values.npy` and `timing.json` for `benches/peers/fmm_peers.py`.

#[path = "common/data.rs"]
mod data;
#[path = "common/fmm_data.rs"]
mod fmm_data;
#[path = "common/npy.rs"]
mod npy;
#[path = "common/timing.rs"]
mod timing;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use zeroset::bases::rbf::fmm::{FmmField, FmmOptions, M2lCompression};
use zeroset::bases::rbf::{Kernel, RbfField};
use zeroset::core::ScalarField;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

struct Args {
    kernel: String,
    sources: usize,
    targets: Vec<usize>,
    order: usize,
    leaf: Option<usize>,
    tolerance: Option<f64>,
    compression: Option<M2lCompression>,
    repeat: usize,
    cloud: String,
    data: PathBuf,
    dump: Option<PathBuf>,
    direct: bool,
    expected: bool,
}

fn parse() -> Res<Args> {
    let mut a = Args {
        kernel: "r".into(),
        sources: 10_000,
        targets: vec![100_000],
        order: 6,
        leaf: None,
        tolerance: None,
        compression: None,
        repeat: 3,
        cloud: "bunny_points.ply".into(),
        data: data::data_dir(),
        dump: None,
        direct: true,
        expected: true,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        if flag == "--no-direct" {
            a.direct = false;
            continue;
        }
        if flag == "--unknown-targets" {
            a.expected = false;
            continue;
        }
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--kernel" => a.kernel = value,
            "--sources" => a.sources = value.parse()?,
            "--targets" => a.targets = timing::parse_list("--targets", &value)?,
            "--order" => a.order = value.parse()?,
            "--leaf" => a.leaf = Some(value.parse()?),
            "--tolerance" => a.tolerance = Some(value.parse()?),
            "--compression" => {
                a.compression = Some(match value.as_str() {
                    "shared" => M2lCompression::SharedBasis,
                    "per-operator" => M2lCompression::PerOperator,
                    _ => {
                        return Err(format!("--compression {value}: shared or per-operator").into());
                    }
                })
            }
            "--repeat" => a.repeat = value.parse::<usize>()?.max(1),
            "--cloud" => a.cloud = value,
            "--data" => a.data = value.into(),
            "--dump" => a.dump = Some(value.into()),
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    if a.dump.is_some() && a.targets.len() != 1 {
        return Err("--dump takes one target count".into());
    }
    Ok(a)
}

fn main() -> Res<()> {
    let args = parse()?;
    match fmm_data::load(&args.data, &args.cloud, &args.kernel, args.sources)? {
        fmm_data::Field::R(f) => run(&args, &f),
        fmm_data::Field::R3(f) => run(&args, &f),
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn run<K: Kernel + Clone>(args: &Args, field: &RbfField<K, 3>) -> Res<()> {
    let bounds = field.bounds().ok_or("field without bounds")?;
    let mut options = FmmOptions::new(args.order);
    if let Some(l) = args.leaf {
        options = options.with_leaf_size(l);
    }
    if let Some(t) = args.tolerance {
        options = options.with_tolerance(t);
    }
    if let Some(c) = args.compression {
        options = options.with_compression(c);
    }
    println!(
        "fmm_timing: {} ({}), {} centres, order {}, {} threads, medians of {}",
        args.cloud,
        args.kernel,
        field.num_centres(),
        args.order,
        rayon::current_num_threads(),
        args.repeat
    );
    println!(
        "{:>9} {:>8} {:>9} {:>9} {:>10} {:>10} {:>7} {:>9} {:>9} {:>9} {:>6} {:>5} {:>6}",
        "targets",
        "ops_ms",
        "build_ms",
        "eval_ms",
        "total_ms",
        "direct_ms",
        "ratio",
        "ratio_ops",
        "max_rel",
        "rms_rel",
        "cells",
        "depth",
        "rank"
    );
    // The operators depend on the kernel and order only: built once (on the first field's
    // first use), timed, and shared by every later build, as an application would.
    let shared = FmmField::operators(field.kernel(), &options)?;
    for &m in &args.targets {
        let targets = fmm_data::uniform_targets(&bounds, m, 7);
        let options = if args.expected {
            options.with_expected_points(m)
        } else {
            options
        };
        let (mut ops, mut build, mut eval, mut direct) = (vec![], vec![], vec![], vec![]);
        let mut fast_values = vec![0.0; m];
        let mut exact = vec![0.0; m];
        let mut last = None;
        for _ in 0..args.repeat {
            let t = Instant::now();
            let fast = FmmField::with_operators(field, &options, shared.clone())?;
            let total = t.elapsed();
            let op = Duration::from_secs_f64(fast.report().operator_seconds);
            if op > Duration::from_millis(1) {
                ops.push(op);
            }
            build.push(total - op);
            let t = Instant::now();
            fast.values(&targets, &mut fast_values);
            eval.push(t.elapsed());
            if args.direct {
                let t = Instant::now();
                field.values(&targets, &mut exact);
                direct.push(t.elapsed());
            }
            last = Some(fast);
        }
        let fast = last.ok_or("no run")?;
        let (ops, build, eval) = (
            ops.first().copied().unwrap_or_default(),
            timing::median(build),
            timing::median(eval),
        );
        let total = build + eval;
        let (direct_ms, ratio, ratio_ops, max_rel, rms_rel) = if args.direct {
            let d = timing::median(direct);
            let (_, max_rel, rms_rel) = fmm_data::errors(&fast_values, &exact);
            (
                ms(d),
                ms(d) / ms(total),
                ms(d) / ms(total + ops),
                max_rel,
                rms_rel,
            )
        } else {
            (f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN)
        };
        let r = fast.report();
        println!(
            "{m:>9} {:>8.1} {:>9.1} {:>9.1} {:>10.1} {direct_ms:>10.1} {ratio:>7.1} {ratio_ops:>9.2} {max_rel:>9.2e} {rms_rel:>9.2e} {:>6} {:>5} {:>6}",
            ms(ops),
            ms(build),
            ms(eval),
            ms(total),
            r.cells,
            r.depth,
            r.max_rank
        );
        println!(
            "          stages of the last build: tree {:.1} ms, upward {:.1} ms, m2l+p2l {:.1} ms ({} pairs), downward {:.1} ms, {} leaves",
            1e3 * r.tree_seconds,
            1e3 * r.upward_seconds,
            1e3 * r.m2l_seconds,
            r.m2l_pairs,
            1e3 * r.downward_seconds,
            r.leaves
        );
        if let Some(dir) = &args.dump {
            std::fs::create_dir_all(dir)?;
            let centres = field.centres();
            let flat: Vec<f64> = centres.iter().flatten().copied().collect();
            npy::write_npy(&dir.join("sources.npy"), &[centres.len(), 3], &flat)?;
            npy::write_npy(&dir.join("weights.npy"), &[centres.len()], field.weights())?;
            let (a, b) = field.linear_part();
            npy::write_npy(&dir.join("poly.npy"), &[4], &[a, b[0], b[1], b[2]])?;
            let flat: Vec<f64> = targets.iter().flatten().copied().collect();
            npy::write_npy(&dir.join("targets.npy"), &[m, 3], &flat)?;
            npy::write_npy(&dir.join("fmm_values.npy"), &[m], &fast_values)?;
            npy::write_npy(&dir.join("direct_values.npy"), &[m], &exact)?;
            let json = format!(
                "{{\"kernel\": \"{}\", \"order\": {}, \"sources\": {}, \"targets\": {m}, \
                 \"fmm_build_ms\": {}, \"fmm_eval_ms\": {}, \"fmm_total_ms\": {}, \
                 \"fmm_operators_ms\": {}, \"direct_ms\": {direct_ms}, \"threads\": {}}}\n",
                args.kernel,
                args.order,
                centres.len(),
                ms(build),
                ms(eval),
                ms(total),
                ms(ops),
                rayon::current_num_threads()
            );
            std::fs::write(dir.join("timing.json"), json)?;
        }
    }
    Ok(())
}
