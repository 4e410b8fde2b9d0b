//! The two-step signed marching cubes (paper 002 §2.3) against plain marching cubes with the
//! high order everywhere, on an RBF field of about 10,000 centres fitted to the bunny
//! (`common/fmm_data.rs`), with the paper's Table 3 counts.
//!
//! ```text
//! cargo run --release --example smc_timing -- [--kernel r|r3] [--sources N] [--low p]
//!     [--high P] [--grids 256,coarse,general,fine] [--cloud FILE] [--data DIR] [--no-plain]
//! ```
//!
//! A grid is `N` (voxels along the longest axis of the field's box) or `coarse` / `general` /
//! `fine` (the l0 rule of `zeroset_mesh::voxel`: 5·l0, l0, 0.3·l0). The operators of both
//! orders and the order-`P` field (default options: step 2 evaluates few points) are built
//! once; per grid, the order-`p` field is built for one evaluation per grid vertex
//! (`FmmOptions::with_expected_points`, as `zeroset mesh --method smc` does), its build timed
//! as SMC's cost (`low_s`), and the errors of both orders, sampled against the direct sum as
//! `OrderPair` does, give the margin (10 × their sum). Per grid: `N_MC` (plain MC's
//! evaluations, one per vertex), `N_SMC,P` (`N_SMC,p = N_MC`), `γ = N_SMC,P / N_SMC,p`, the
//! margin, `low_s`, the signed marching cubes' time, plain marching cubes with the same order-`P`
//! field at every vertex (`plain_s`: the mesh must be identical, same vertices bit for bit and
//! same triangles) and with an order-`P` field built for every vertex (`tuned_s`, its build
//! included: plain MC at its fastest), and the ratios `plain_s` and `tuned_s` over
//! `low_s + smc_s`.

#[path = "common/fmm_data.rs"]
mod fmm_data;

use std::time::Instant;

use zeroset::bases::rbf::fmm::{DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY, FmmField, FmmOptions};
use zeroset::bases::rbf::{Kernel, RbfField};
use zeroset::core::ScalarField;
use zeroset::mesh::signed::signed_marching_cubes;
use zeroset::mesh::voxel::{self, Detail};
use zeroset::mesh::{McOptions, mesh_field};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn main() -> Res<()> {
    let mut kernel = "r".to_string();
    let (mut sources, mut low, mut high) = (10_000usize, 6usize, 10usize);
    let mut grids: Vec<String> = ["256", "coarse", "general", "fine"]
        .map(String::from)
        .to_vec();
    let mut cloud = "bunny_points.ply".to_string();
    let mut data = fmm_data::data_dir();
    let mut plain = true;
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
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    let run = |f: &dyn Fn() -> Res<()>| f();
    match fmm_data::load(&data, &cloud, &kernel, sources)? {
        fmm_data::Field::R(f) => run(&|| table(&f, low, high, &grids, plain)),
        fmm_data::Field::R3(f) => run(&|| table(&f, low, high, &grids, plain)),
    }
}

fn table<K: Kernel + Clone>(
    field: &RbfField<K, 3>,
    low: usize,
    high: usize,
    grids: &[String],
    plain: bool,
) -> Res<()> {
    let t = Instant::now();
    let (low_options, high_options) = (FmmOptions::new(low), FmmOptions::new(high));
    let low_ops = FmmField::operators(field.kernel(), &low_options)?;
    let high_ops = FmmField::operators(field.kernel(), &high_options)?;
    let high_field = FmmField::with_operators(field, &high_options, high_ops.clone())?;
    let (high_error, _) = high_field.sampled_error(field, DEFAULT_ERROR_SAMPLES, 2);
    println!(
        "smc_timing: {} centres ({}), orders {low}/{high}, order {high} sampled error {:.2e}, \
         operators and order-{high} field built in {:.2} s, {} threads",
        field.num_centres(),
        field.kernel().name(),
        high_error,
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    println!(
        "{:>8} {:>14} {:>10} {:>10} {:>10} {:>7} {:>9} {:>7} {:>7} {:>8} {:>8} {:>6} {:>6} {:>9}",
        "grid",
        "shape",
        "voxel",
        "N_MC",
        "N_SMC,P",
        "gamma",
        "margin",
        "low_s",
        "smc_s",
        "plain_s",
        "tuned_s",
        "ratio",
        "tuned",
        "identical"
    );
    let bounds = field.bounds().ok_or("no bounds")?;
    let options = McOptions::default().with_normals(false);
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
        // Step 1's field, shaped for one evaluation per grid vertex (its build is SMC's cost).
        let t = Instant::now();
        let low_field = FmmField::with_operators(
            field,
            &low_options.with_expected_points(grid.len()),
            low_ops.clone(),
        )?;
        let low_s = t.elapsed().as_secs_f64();
        let (low_error, _) = low_field.sampled_error(field, DEFAULT_ERROR_SAMPLES, 1);
        let margin = DEFAULT_SAFETY * (low_error + high_error);
        let t = Instant::now();
        let (mesh, r) =
            signed_marching_cubes(&low_field, &high_field, &grid, 0.0, margin, &options, None)?;
        let smc = t.elapsed().as_secs_f64();
        let (plain_s, tuned_s, same) = if plain {
            let t = Instant::now();
            let reference = mesh_field(&high_field, &grid, 0.0, &options)?;
            let plain_s = t.elapsed().as_secs_f64();
            let same = reference.triangles() == mesh.triangles()
                && reference.vertices().len() == mesh.vertices().len()
                && reference
                    .vertices()
                    .iter()
                    .zip(mesh.vertices())
                    .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits));
            // Plain MC at its best: the order-P field shaped for every vertex, build included.
            let t = Instant::now();
            let dense = FmmField::with_operators(
                field,
                &high_options.with_expected_points(grid.len()),
                high_ops.clone(),
            )?;
            mesh_field(&dense, &grid, 0.0, &options)?;
            let tuned_s = t.elapsed().as_secs_f64();
            (plain_s, tuned_s, if same { "yes" } else { "NO" })
        } else {
            (f64::NAN, f64::NAN, "-")
        };
        println!(
            "{spec:>8} {:>14} {h:>10.3e} {:>10} {:>10} {:>6.2}% {margin:>9.2e} {low_s:>7.2} \
             {smc:>7.2} {plain_s:>8.2} {tuned_s:>8.2} {:>6.1} {:>6.1} {same:>9}",
            format!("{}x{}x{}", c[0], c[1], c[2]),
            r.n_mc,
            r.n_smc_high,
            100.0 * r.gamma,
            plain_s / (low_s + smc),
            tuned_s / (low_s + smc),
        );
        println!(
            "{:>8} signed MC stages: step 1 (order {low} everywhere, certainty) {:.2} s, step 2 \
             {:.2} s, extraction {:.2} s",
            "", r.coarse_seconds, r.fine_seconds, r.extract_seconds
        );
    }
    Ok(())
}
