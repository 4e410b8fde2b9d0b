//! Times the fast multipole evaluation of an RBF field against zeroset's exact parallel direct
//! sum, on a field fitted to real data (see `common/fmm_data.rs`), with every cost counted.
//!
//! ```text
//! cargo run --release --example fmm_timing -- [--kernel r|r3] [--sources N] [--targets M,…]
//!     [--order P] [--leaf L] [--tolerance T] [--repeat K] [--cloud FILE] [--data DIR]
//!     [--dump DIR] [--disk-cache DIR] [--no-direct] [--unknown-targets]
//!     [--compression shared|per-operator]
//! ```
//!
//! Targets are drawn uniformly (seeded) in the field's bounds, and each field is built for
//! their count (`FmmOptions::with_expected_points`; `--unknown-targets` leaves it unset). Per
//! target count:
//!
//! - **first call** (`first_ms`): the operator cache emptied, one `FmmField::new` (which
//!   computes the M2L operators, `ops_ms`, then the tree and expansions) and one evaluation —
//!   what a one-shot program pays;
//! - `disk_ms` (with `--disk-cache DIR`): the operators read back from the on-disk cache, what a
//!   later process pays instead of `ops_ms`;
//! - **reused** (`total_ms` = `build_ms` + `eval_ms`): `FmmField::new` with the operators of
//!   the process-wide cache (a second field of the same kernel and order), then the
//!   evaluation; one warm-up, then the median of `K` runs, the direct sum timed by the same
//!   rule in the same loop;
//! - `x_reuse` = direct / total and `x_first` = direct / first: how much faster than the direct
//!   sum, with the operators reused and with them built;
//! - the error against the direct sum, relative to its largest value (`max_rel`, `rms_rel`),
//!   and as a **distance near the zero set**: at 20,000 points within one voxel (`l0`, the
//!   general detail of `zeroset mesh`) of on-surface points, `|s_fmm − s| / ‖∇s‖`, the
//!   largest in voxels (`near_vox`), also printed absolute and relative to the diagonal.
//!
//! `--dump DIR` (one target count) also writes `sources.npy`, `weights.npy`, `poly.npy`
//! (constant, x, y, z), `targets.npy`, `fmm_values.npy`, `direct_values.npy` and `timing.json`
//! for `benches/peers/fmm_peers.py`.

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

use zeroset::bases::rbf::fmm::{FmmField, FmmOptions, M2lCompression, cache};
use zeroset::bases::rbf::{Kernel, RbfField};
use zeroset::core::ScalarField;
use zeroset::mesh::voxel;

/// Points near the zero set at which the distance error is measured.
const NEAR_POINTS: usize = 20_000;

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
    disk_cache: Option<PathBuf>,
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
        disk_cache: None,
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
            "--disk-cache" => a.disk_cache = Some(value.into()),
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
    // Points within one voxel (l0, the general detail of `zeroset mesh`) of the zero set.
    let h = voxel::l0(&bounds);
    let surface = fmm_data::picked_cloud(&args.data, &args.cloud, args.sources)?;
    let near = fmm_data::near_surface_targets(surface.positions(), h, NEAR_POINTS, 11);
    let mut near_exact = vec![0.0; near.len()];
    field.values(&near, &mut near_exact);
    println!(
        "fmm_timing: {} ({}), {} centres, order {}, {} threads, one warm-up then medians of {} \
         (FMM build and evaluation, direct sum alike); voxel l0 = {h:.4e}",
        args.cloud,
        args.kernel,
        field.num_centres(),
        args.order,
        rayon::current_num_threads(),
        args.repeat
    );
    println!(
        "{:>9} {:>8} {:>8} {:>9} {:>9} {:>10} {:>10} {:>10} {:>8} {:>8} {:>9} {:>9} {:>9} {:>6} {:>5} {:>5}",
        "targets",
        "ops_ms",
        "disk_ms",
        "build_ms",
        "eval_ms",
        "total_ms",
        "first_ms",
        "direct_ms",
        "x_reuse",
        "x_first",
        "max_rel",
        "rms_rel",
        "near_vox",
        "cells",
        "depth",
        "rank"
    );
    for &m in &args.targets {
        let targets = fmm_data::uniform_targets(&bounds, m, 7);
        let options = if args.expected {
            options.with_expected_points(m)
        } else {
            options
        };
        // First call: no operators in memory (nor on disk), built by this field; every cost a
        // one-shot user pays.
        cache::clear();
        cache::set_disk_dir(None);
        let t = Instant::now();
        let first = FmmField::new(field, &options)?;
        let first_build = t.elapsed();
        let ops = Duration::from_secs_f64(first.report().operator_seconds);
        let mut fast_values = vec![0.0; m];
        let t = Instant::now();
        first.values(&targets, &mut fast_values);
        let first_total = first_build + t.elapsed();
        drop(first);
        // From the disk cache: a later process of the same kernel and order.
        let disk = match &args.disk_cache {
            Some(dir) => {
                cache::set_disk_dir(Some(dir.clone()));
                cache::clear();
                FmmField::new(field, &options)?; // writes the file if it is not there
                cache::clear();
                let f = FmmField::new(field, &options)?;
                cache::set_disk_dir(None);
                Some(Duration::from_secs_f64(f.report().operator_seconds))
            }
            None => None,
        };
        // Reused operators (in memory): warm-up, then the medians.
        let mut exact = vec![0.0; m];
        let (mut build, mut eval, mut direct) = (vec![], vec![], vec![]);
        let mut last = None;
        for run in 0..=args.repeat {
            let t = Instant::now();
            let fast = FmmField::new(field, &options)?;
            let b = t.elapsed();
            let t = Instant::now();
            fast.values(&targets, &mut fast_values);
            let e = t.elapsed();
            let d = if args.direct {
                let t = Instant::now();
                field.values(&targets, &mut exact);
                t.elapsed()
            } else {
                Duration::ZERO
            };
            if run > 0 {
                build.push(b);
                eval.push(e);
                direct.push(d);
            }
            last = Some(fast);
        }
        let fast = last.ok_or("no run")?;
        let (build, eval) = (timing::median(build), timing::median(eval));
        let total = build + eval;
        let mut near_fast = vec![0.0; near.len()];
        fast.values(&near, &mut near_fast);
        let (near_max, near_rms) = fmm_data::distance_errors(&near_fast, &near_exact, field, &near);
        let (direct_ms, x_reuse, x_first, max_rel, rms_rel) = if args.direct {
            let d = timing::median(direct);
            let (_, max_rel, rms_rel) = fmm_data::errors(&fast_values, &exact);
            (
                ms(d),
                ms(d) / ms(total),
                ms(d) / ms(first_total),
                max_rel,
                rms_rel,
            )
        } else {
            (f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN)
        };
        let disk_ms = disk.map_or(f64::NAN, ms);
        let r = fast.report();
        println!(
            "{m:>9} {:>8.1} {disk_ms:>8.1} {:>9.1} {:>9.1} {:>10.1} {:>10.1} {direct_ms:>10.1} {x_reuse:>8.2} {x_first:>8.2} {max_rel:>9.2e} {rms_rel:>9.2e} {:>9.2e} {:>6} {:>5} {:>5}",
            ms(ops),
            ms(build),
            ms(eval),
            ms(total),
            ms(first_total),
            near_max / h,
            r.cells,
            r.depth,
            r.max_rank
        );
        println!(
            "          stages of the last build: tree {:.1} ms, upward {:.1} ms, m2l+p2l {:.1} ms ({} pairs), downward {:.1} ms, {} leaves; \
             near the zero set ({NEAR_POINTS} points within a voxel): max distance error {near_max:.3e} ({:.2e} voxels, {:.2e} of the diagonal), rms {near_rms:.3e}",
            1e3 * r.tree_seconds,
            1e3 * r.upward_seconds,
            1e3 * r.m2l_seconds,
            r.m2l_pairs,
            1e3 * r.downward_seconds,
            r.leaves,
            near_max / h,
            near_max / bounds.diagonal(),
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
                 \"fmm_operators_ms\": {}, \"fmm_operators_disk_ms\": {}, \"fmm_first_ms\": {}, \
                 \"direct_ms\": {direct_ms}, \"near_max_distance\": {near_max}, \
                 \"near_rms_distance\": {near_rms}, \"voxel\": {h}, \"diagonal\": {}, \
                 \"threads\": {}, \"repeat\": {}}}\n",
                args.kernel,
                args.order,
                centres.len(),
                ms(build),
                ms(eval),
                ms(total),
                ms(ops),
                if disk_ms.is_nan() {
                    "null".to_string()
                } else {
                    disk_ms.to_string()
                },
                ms(first_total),
                bounds.diagonal(),
                rayon::current_num_threads(),
                args.repeat
            );
            std::fs::write(dir.join("timing.json"), json)?;
        }
    }
    Ok(())
}
