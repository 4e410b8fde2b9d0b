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
//! `fine` (the l0 rule of `zeroset_mesh::voxel`: 5·l0, l0, 0.3·l0). Both fields are built once
//! (`OrderPair`: orders `p` and `P`, their errors sampled against the direct sum, margin =
//! 10 × their sum). Per grid: `N_MC` (plain MC's evaluations, one per vertex), `N_SMC,p`,
//! `N_SMC,P`, `γ = N_SMC,P / N_SMC,p`, the signed marching cubes' time, plain marching cubes'
//! time with order `P` at every vertex, their ratio, and whether the two meshes are identical
//! (same vertices, bit for bit, and same triangles).

#[path = "common/fmm_data.rs"]
mod fmm_data;

use std::time::Instant;

use zeroset::bases::rbf::fmm::{DEFAULT_ERROR_SAMPLES, DEFAULT_SAFETY, FmmOptions, OrderPair};
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
    let pair = OrderPair::new(
        field,
        &FmmOptions::new(low),
        &FmmOptions::new(high),
        DEFAULT_ERROR_SAMPLES,
        DEFAULT_SAFETY,
    )?;
    println!(
        "smc_timing: {} centres ({}), orders {low}/{high}, sampled errors {:.2e}/{:.2e}, margin \
         {:.2e}, fields built in {:.2} s, {} threads",
        field.num_centres(),
        field.kernel().name(),
        pair.low_error,
        pair.high_error,
        pair.margin,
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    println!(
        "{:>8} {:>14} {:>10} {:>10} {:>10} {:>7} {:>8} {:>9} {:>6} {:>9}",
        "grid",
        "shape",
        "voxel",
        "N_MC",
        "N_SMC,P",
        "gamma",
        "smc_s",
        "plain_s",
        "ratio",
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
        let t = Instant::now();
        let (mesh, r) = signed_marching_cubes(
            &pair.low,
            &pair.high,
            &grid,
            0.0,
            pair.margin,
            &options,
            None,
        )?;
        let smc = t.elapsed().as_secs_f64();
        let (plain_s, same) = if plain {
            let t = Instant::now();
            let reference = mesh_field(&pair.high, &grid, 0.0, &options)?;
            let s = t.elapsed().as_secs_f64();
            let same = reference.triangles() == mesh.triangles()
                && reference.vertices().len() == mesh.vertices().len()
                && reference
                    .vertices()
                    .iter()
                    .zip(mesh.vertices())
                    .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits));
            (s, if same { "yes" } else { "NO" })
        } else {
            (f64::NAN, "-")
        };
        println!(
            "{spec:>8} {:>14} {h:>10.3e} {:>10} {:>10} {:>6.2}% {smc:>8.2} {plain_s:>9.2} {:>6.1} {same:>9}",
            format!("{}x{}x{}", c[0], c[1], c[2]),
            r.n_mc,
            r.n_smc_high,
            100.0 * r.gamma,
            plain_s / smc
        );
    }
    Ok(())
}
