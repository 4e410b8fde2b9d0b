//! The two-step signed marching cubes (paper 002 §2.3) against plain marching cubes at its
//! fastest, on an RBF field of about 10,000 centres fitted to the bunny (`common/fmm_data.rs`),
//! with the paper's Table 3 counts and every cost counted.
//!
//! ```text
//! cargo run --release --example smc_timing -- [--kernel r|r3] [--sources N] [--low p]
//!     [--high P] [--grids 256,coarse,general,fine] [--step blocks|every] [--repeat R]
//!     [--direct-limit SECONDS] [--cloud FILE] [--data DIR]
//! ```
//!
//! A grid is `N` (voxels along the longest axis of the field's box) or `coarse` / `general` /
//! `fine` (the l0 rule of `zeroset_mesh::voxel`: 5·l0, l0, 0.3·l0). The M2L operators of both
//! orders are timed once, from an empty cache (they depend on the kernel and order only). Per
//! grid, everything SMC needs is timed as `zeroset mesh --method smc` does it: the `OrderPair`
//! (`pair_s`: the order-`p` and order-`P` fields, each shaped for the evaluations it will see
//! by `zeroset_mesh::expected_evaluations`, and both orders' errors sampled against the direct
//! sum at the same 4,096 points, which give the margin, 10 × their sum), and the signed
//! marching cubes (`smc_s`); `total_s` is their sum with the
//! operators reused, `first_s` with both orders' operators built (a one-shot program). Step 1
//! settles blocks by enclosures (`--step blocks`, the default) or evaluates every vertex
//! (`--step every`, the paper's step 1).
//!
//! The comparison is plain marching cubes at its fastest: an order-`P` field built for every
//! vertex (its tree shaped for them) and sampled at every vertex, its build included
//! (`tuned_s`; `tfirst_s` with its operators built too). Both sides take one warm-up, then the
//! median of `R` runs (default 3); `x_reuse = tuned_s / total_s`, `x_first = tfirst_s /
//! first_s`. `direct_s` is plain MC on the exact field (the direct sum at every vertex, what
//! `zeroset mesh` does without `--method smc`), one run, only where it should take under
//! `--direct-limit` seconds (default 30).
//!
//! Per grid it prints `N_MC` (plain MC's evaluations, one per vertex), `N_SMC,p` (order-`p`
//! evaluations: `N_MC` with `--step every`), `N_SMC,P`, `γ = N_SMC,P / N_MC` (the paper's
//! `N_SMC,P / N_SMC,p`, whose step 1 evaluates every vertex) and the margin; `identical` checks
//! that SMC's mesh is plain MC's on the same order-`P` field, the same vertices bit for bit and
//! the same triangles. That holds whenever the margin exceeds both orders' true errors at every
//! vertex: the margin is 10 × the errors sampled at 4,096 points per order, so it is a
//! measured, not a proven, bound.

#[path = "common/data.rs"]
mod data;
#[path = "common/fmm_data.rs"]
mod fmm_data;

use std::time::Instant;

use zeroset::bases::rbf::fmm::{
    DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY, FmmField, FmmOptions, OrderPair, cache,
};
use zeroset::bases::rbf::{Kernel, RbfField};
use zeroset::core::ScalarField;
use zeroset::mesh::signed::{
    CoarseStep, SmcOptions, expected_evaluations, settled_fraction, signed_marching_cubes,
};
use zeroset::mesh::voxel::{self, Detail};
use zeroset::mesh::{McOptions, mesh_field};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn main() -> Res<()> {
    let mut kernel = "r".to_string();
    let (mut sources, mut low, mut high) = (10_000usize, 5usize, 10usize);
    let mut grids: Vec<String> = ["256", "coarse", "general", "fine"]
        .map(String::from)
        .to_vec();
    let mut cloud = "bunny_points.ply".to_string();
    let mut data = data::data_dir();
    let mut repeat = 3usize;
    let mut direct_limit = 30.0f64;
    let mut step = CoarseStep::Blocks;
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let v = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--kernel" => kernel = v,
            "--sources" => sources = v.parse()?,
            "--low" => low = v.parse()?,
            "--high" => high = v.parse()?,
            "--grids" => grids = v.split(',').map(String::from).collect(),
            "--cloud" => cloud = v,
            "--repeat" => repeat = v.parse::<usize>()?.max(1),
            "--direct-limit" => direct_limit = v.parse()?,
            "--data" => data = v.into(),
            "--step" => {
                step = match v.as_str() {
                    "blocks" => CoarseStep::Blocks,
                    "every" => CoarseStep::EveryVertex,
                    other => return Err(format!("--step blocks|every, not {other}").into()),
                }
            }
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    let run = |f: &dyn Fn() -> Res<()>| f();
    match fmm_data::load(&data, &cloud, &kernel, sources)? {
        fmm_data::Field::R(f) => run(&|| table(&f, low, high, &grids, repeat, step, direct_limit)),
        fmm_data::Field::R3(f) => run(&|| table(&f, low, high, &grids, repeat, step, direct_limit)),
    }
}

fn table<K: Kernel + Clone>(
    field: &RbfField<K, 3>,
    low: usize,
    high: usize,
    grids: &[String],
    repeat: usize,
    step: CoarseStep,
    direct_limit: f64,
) -> Res<()> {
    let (low_options, high_options) = (FmmOptions::new(low), FmmOptions::new(high));
    // What a one-shot program pays for the operators (computed on first use; the cache
    // emptied first), then shared by every later field of the same kernel and order.
    cache::clear();
    cache::set_disk_dir(None);
    let low_ops_s = FmmField::new(field, &low_options)?
        .report()
        .operator_seconds;
    let high_ops_s = FmmField::new(field, &high_options)?
        .report()
        .operator_seconds;
    println!(
        "smc_timing: {} centres ({}), orders {low}/{high}, step 1 {step:?}, {} threads; \
         operators (once per kernel and order): order {low} {low_ops_s:.3} s, order {high} \
         {high_ops_s:.3} s; one warm-up then the median of {repeat} runs for SMC and tuned MC",
        field.num_centres(),
        field.kernel().name(),
        rayon::current_num_threads()
    );
    println!(
        "{:>8} {:>14} {:>10} {:>10} {:>10} {:>10} {:>7} {:>9} {:>6} {:>6} {:>7} {:>7} {:>7} \
         {:>8} {:>8} {:>8} {:>8} {:>9}",
        "grid",
        "shape",
        "voxel",
        "N_MC",
        "N_SMC,p",
        "N_SMC,P",
        "gamma",
        "margin",
        "pair_s",
        "smc_s",
        "total_s",
        "first_s",
        "tuned_s",
        "tfirst_s",
        "x_reuse",
        "x_first",
        "direct_s",
        "identical"
    );
    let bounds = field.bounds().ok_or("no bounds")?;
    let options = McOptions::default().with_normals(false);
    let smc_options = SmcOptions::from(options).with_coarse_step(step);
    for spec in grids {
        let h = match spec.as_str() {
            "coarse" => voxel::voxel_size(&bounds, Detail::Coarse),
            "general" => voxel::voxel_size(&bounds, Detail::General),
            "fine" => voxel::voxel_size(&bounds, Detail::Fine),
            n => {
                let longest = bounds.extent().into_iter().fold(0.0, f64::max);
                longest / n.parse::<f64>()?
            }
        };
        let grid = voxel::grid_for(&bounds, h, 0.0)?;
        let c = grid.counts();
        let [e_low, e_high] = expected_evaluations(&grid, step);
        let build = |options: FmmOptions, points: usize| {
            timed(|| Ok(FmmField::new(field, &options.with_expected_points(points))?))
        };
        // Everything `zeroset mesh --method smc` does once the operators exist: both fields,
        // each shaped for the evaluations it will see, their errors sampled against the direct
        // sum (the margin), then the signed marching cubes.
        let smc_run = || -> Res<_> {
            let (pair, pair_s) = timed(|| {
                Ok(OrderPair::new(
                    field,
                    &low_options.with_expected_points(e_low),
                    &high_options.with_expected_points(e_high),
                    DEFAULT_ERROR_SAMPLES,
                    DEFAULT_SAFETY,
                )?)
            })?;
            let ((mesh, r), smc_s) = timed(|| {
                Ok(signed_marching_cubes(
                    &pair.low,
                    &pair.high,
                    &grid,
                    0.0,
                    pair.margin,
                    &smc_options,
                    None,
                )?)
            })?;
            Ok((mesh, r, pair, [pair_s, smc_s]))
        };
        // Plain MC at its fastest: an order-P field shaped for every vertex, build included.
        let tuned_run = || -> Res<f64> {
            let ((), s) = timed(|| {
                let (dense, _) = build(high_options, grid.len())?;
                mesh_field(&dense, &grid, 0.0, &options)?;
                Ok(())
            })?;
            Ok(s)
        };
        let mut runs = Vec::new();
        let mut tuned = Vec::new();
        let mut last = None;
        for run in 0..=repeat {
            let out = smc_run()?;
            let t = tuned_run()?;
            if run > 0 {
                runs.push(out.3);
                tuned.push(t);
            }
            last = Some(out);
        }
        let (mesh, r, pair, _) = last.ok_or("no run")?;
        let (margin, low_field, high_field) = (pair.margin, &pair.low, &pair.high);
        // The median run by total time, and its stages.
        runs.sort_by(|a, b| a.iter().sum::<f64>().total_cmp(&b.iter().sum::<f64>()));
        let [pair_s, smc_s] = runs[runs.len() / 2];
        let total_s = pair_s + smc_s;
        let first_s = total_s + low_ops_s + high_ops_s;
        tuned.sort_by(f64::total_cmp);
        let tuned_s = tuned[tuned.len() / 2];
        let tuned_first_s = tuned_s + high_ops_s;
        // The mesh is plain MC's on the order-P field, bit for bit, whenever the margin holds
        // the errors of both orders (checked here on every grid; timed once, not a ratio).
        let reference = mesh_field(high_field, &grid, 0.0, &options)?;
        let same = reference.triangles() == mesh.triangles()
            && reference.vertices().len() == mesh.vertices().len()
            && reference
                .vertices()
                .iter()
                .zip(mesh.vertices())
                .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits));
        // Plain MC on the exact field (the direct sum at every vertex: `zeroset mesh` without
        // --method smc), one run, where it takes less than about `direct_limit` seconds.
        let pairs = grid.len() as f64 * field.num_centres() as f64;
        let direct_s = if pairs * 0.6e-9 <= direct_limit {
            timed(|| Ok(mesh_field(field, &grid, 0.0, &options)?))?.1
        } else {
            f64::NAN
        };
        println!(
            "{spec:>8} {:>14} {h:>10.3e} {:>10} {:>10} {:>10} {:>6.2}% {margin:>9.2e} \
             {pair_s:>6.2} {smc_s:>6.2} {total_s:>7.2} \
             {first_s:>7.2} {tuned_s:>7.2} {tuned_first_s:>7.2} {:>8.2} {:>8.2} {direct_s:>8.2} \
             {:>9}",
            format!("{}x{}x{}", c[0], c[1], c[2]),
            r.n_mc,
            r.n_smc_low,
            r.n_smc_high,
            100.0 * r.gamma,
            tuned_s / total_s,
            tuned_first_s / first_s,
            if same { "yes" } else { "NO" },
        );
        let lr = low_field.report();
        let probe = settled_fraction(low_field, &grid, 0.0, margin, 512);
        println!(
            "{:>8} order-{low} field for {e_low} points: {} leaves, {} M2L pairs; order-{high} \
             for {e_high}: {} leaves; probe: {:.0}% of 512 blocks settle; {} enclosures \
             settled {} blocks ({} vertices, {:.1}%); step 1 {:.2} s, step 2 {:.2} s, \
             extraction {:.2} s",
            "",
            lr.leaves,
            lr.m2l_pairs,
            high_field.report().leaves,
            100.0 * probe,
            r.enclosures,
            r.settled_blocks,
            r.settled_vertices,
            100.0 * r.settled_vertices as f64 / r.n_mc as f64,
            r.coarse_seconds,
            r.fine_seconds,
            r.extract_seconds
        );
    }
    Ok(())
}

/// `f()` and the seconds it took.
fn timed<T>(f: impl FnOnce() -> Res<T>) -> Res<(T, f64)> {
    let t = Instant::now();
    let out = f()?;
    Ok((out, t.elapsed().as_secs_f64()))
}
