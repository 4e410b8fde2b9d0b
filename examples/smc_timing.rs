//! The two-step signed marching cubes (paper 002 §2.3) against plain marching cubes with the
//! high order everywhere, on an RBF field of about 10,000 centres fitted to the bunny
//! (`common/fmm_data.rs`), with the paper's Table 3 counts.
//!
//! ```text
//! cargo run --release --example smc_timing -- [--kernel r|r3] [--sources N] [--low p]
//!     [--high P] [--grids 256,coarse,general,fine] [--step blocks|every] [--cloud FILE]
//!     [--data DIR] [--no-plain]
//! ```
//!
//! A grid is `N` (voxels along the longest axis of the field's box) or `coarse` / `general` /
//! `fine` (the l0 rule of `zeroset_mesh::voxel`: 5·l0, l0, 0.3·l0). The operators of both
//! orders are built once (they depend on the kernel and order only). Per grid, everything SMC
//! needs is timed as `zeroset mesh --method smc` does it: the order-`p` and order-`P` fields,
//! each shaped for the evaluations it will see (`zeroset_mesh::expected_evaluations`;
//! `low_s`, `high_s`), the errors of both orders sampled against the direct sum as `OrderPair`
//! does, which give the margin (10 × their sum; `margin_s`), and the signed marching cubes
//! (`smc_s`); `total_s` is their sum. Step 1 settles blocks by enclosures (`--step blocks`, the
//! default) or evaluates every vertex (`--step every`, the paper's step 1).
//!
//! Per grid it prints `N_MC` (plain MC's evaluations, one per vertex), `N_SMC,p` (order-`p`
//! evaluations: `N_MC` with `--step every`), `N_SMC,P`, `γ = N_SMC,P / N_MC` (the paper's
//! `N_SMC,P / N_SMC,p`, whose step 1 evaluates every vertex), the margin, the times, and plain
//! marching cubes twice: with the same order-`P` field at every vertex (`plain_s`, the field's
//! build not counted on either side; the mesh must be identical, same vertices bit for bit and
//! same triangles) and with an order-`P` field built for every vertex (`tuned_s`, its build
//! included: plain MC at its fastest, against `total_s`).

#[path = "common/data.rs"]
mod data;
#[path = "common/fmm_data.rs"]
mod fmm_data;

use std::sync::Arc;
use std::time::Instant;

use zeroset::bases::rbf::fmm::{
    DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY, FmmField, FmmOperators, FmmOptions,
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
    let mut plain = true;
    let mut step = CoarseStep::Blocks;
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        if flag == "--no-plain" {
            plain = false;
            continue;
        }
        let v = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--kernel" => kernel = v,
            "--sources" => sources = v.parse()?,
            "--low" => low = v.parse()?,
            "--high" => high = v.parse()?,
            "--grids" => grids = v.split(',').map(String::from).collect(),
            "--cloud" => cloud = v,
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
        fmm_data::Field::R(f) => run(&|| table(&f, low, high, &grids, plain, step)),
        fmm_data::Field::R3(f) => run(&|| table(&f, low, high, &grids, plain, step)),
    }
}

fn table<K: Kernel + Clone>(
    field: &RbfField<K, 3>,
    low: usize,
    high: usize,
    grids: &[String],
    plain: bool,
    step: CoarseStep,
) -> Res<()> {
    let t = Instant::now();
    let (low_options, high_options) = (FmmOptions::new(low), FmmOptions::new(high));
    let low_ops = FmmField::operators(field.kernel(), &low_options)?;
    let high_ops = FmmField::operators(field.kernel(), &high_options)?;
    // The compressed M2L operators are computed on first use: build a field of each order.
    FmmField::with_operators(field, &low_options, low_ops.clone())?;
    FmmField::with_operators(field, &high_options, high_ops.clone())?;
    println!(
        "smc_timing: {} centres ({}), orders {low}/{high}, step 1 {step:?}, operators built in \
         {:.2} s (once per kernel and order, not counted below), {} threads",
        field.num_centres(),
        field.kernel().name(),
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    println!(
        "{:>8} {:>14} {:>10} {:>10} {:>10} {:>10} {:>7} {:>9} {:>6} {:>6} {:>8} {:>6} {:>7} \
         {:>7} {:>7} {:>6} {:>6} {:>9}",
        "grid",
        "shape",
        "voxel",
        "N_MC",
        "N_SMC,p",
        "N_SMC,P",
        "gamma",
        "margin",
        "low_s",
        "high_s",
        "margin_s",
        "smc_s",
        "total_s",
        "plain_s",
        "tuned_s",
        "same",
        "tuned",
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
        let build = |options: FmmOptions, ops: &Arc<FmmOperators>, points: usize| {
            timed(|| {
                Ok(FmmField::with_operators(
                    field,
                    &options.with_expected_points(points),
                    ops.clone(),
                )?)
            })
        };
        let (low_field, low_s) = build(low_options, &low_ops, e_low)?;
        let (high_field, high_s) = build(high_options, &high_ops, e_high)?;
        let (margin, margin_s) = timed(|| {
            let (low_error, _) = low_field.sampled_error(field, DEFAULT_ERROR_SAMPLES, 1);
            let (high_error, _) = high_field.sampled_error(field, DEFAULT_ERROR_SAMPLES, 2);
            Ok(DEFAULT_SAFETY * (low_error + high_error))
        })?;
        let probe = settled_fraction(&low_field, &grid, 0.0, margin, 512);
        let ((mesh, r), smc_s) = timed(|| {
            Ok(signed_marching_cubes(
                &low_field,
                &high_field,
                &grid,
                0.0,
                margin,
                &smc_options,
                None,
            )?)
        })?;
        let total_s = low_s + high_s + margin_s + smc_s;
        let (plain_s, tuned_s, same) = if plain {
            let (reference, plain_s) =
                timed(|| Ok(mesh_field(&high_field, &grid, 0.0, &options)?))?;
            let same = reference.triangles() == mesh.triangles()
                && reference.vertices().len() == mesh.vertices().len()
                && reference
                    .vertices()
                    .iter()
                    .zip(mesh.vertices())
                    .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits));
            // Plain MC at its best: the order-P field shaped for every vertex, build included.
            let ((), tuned_s) = timed(|| {
                let (dense, _) = build(high_options, &high_ops, grid.len())?;
                mesh_field(&dense, &grid, 0.0, &options)?;
                Ok(())
            })?;
            (plain_s, tuned_s, if same { "yes" } else { "NO" })
        } else {
            (f64::NAN, f64::NAN, "-")
        };
        println!(
            "{spec:>8} {:>14} {h:>10.3e} {:>10} {:>10} {:>10} {:>6.2}% {margin:>9.2e} \
             {low_s:>6.2} {high_s:>6.2} {margin_s:>8.2} {smc_s:>6.2} {total_s:>7.2} \
             {plain_s:>7.2} {tuned_s:>7.2} {:>6.1} {:>6.1} {same:>9}",
            format!("{}x{}x{}", c[0], c[1], c[2]),
            r.n_mc,
            r.n_smc_low,
            r.n_smc_high,
            100.0 * r.gamma,
            plain_s / (total_s - high_s),
            tuned_s / total_s,
        );
        let lr = low_field.report();
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
