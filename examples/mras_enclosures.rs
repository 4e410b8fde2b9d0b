//! MRAS enclosures (`ScalarField::value_range` of an MRAS field) in the signed marching cubes
//! against plain marching cubes, on one field file: both meshes (asserted identical), their
//! times (median of `R` runs after a warm-up, the machine's threads), and how many grid
//! vertices the enclosures settle.
//!
//! ```text
//! cargo run --release --example mras_enclosures -- FIELD.zsf [--resolution N,N,...] [--repeat R]
//! ```
//!
//! `FIELD.zsf` is an MRAS field file (`zeroset fit scan.ply --method mras -o FIELD.zsf`); each
//! `N` is a grid of `N` voxels along the longest axis of the field's box (default 135,256).
//! The signed marching cubes run with the field as both its coarse and its fine field and a
//! margin of 0, so their mesh is plain marching cubes' bit for bit; they skip the blocks whose
//! enclosure clears the level. Plain marching cubes samples MRAS fields along grid rows (each
//! cell's factors contracted over a row's fixed coordinates), which the scattered vertices of
//! the signed method cannot share.

use std::time::Instant;

use zeroset::bases::field_file::{AnyField, read_any_field};
use zeroset::core::field::ScalarField;
use zeroset::mesh::cubes::{McOptions, mesh_field};
use zeroset::mesh::signed::{CoarseStep, SmcOptions, signed_marching_cubes};
use zeroset::mesh::voxel::grid_for;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (mut path, mut resolutions, mut repeat): (_, Vec<f64>, usize) =
        (None, vec![135.0, 256.0], 3);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--resolution" => {
                let list = args.next().ok_or("--resolution needs N,N,...")?;
                resolutions = list.split(',').map(str::parse).collect::<Result<_, _>>()?;
            }
            "--repeat" => repeat = args.next().ok_or("--repeat needs R")?.parse()?,
            _ => path = Some(a),
        }
    }
    let path = path.ok_or("usage: mras_enclosures FIELD.zsf [--resolution N,..] [--repeat R]")?;
    if repeat == 0 {
        return Err("--repeat needs at least 1 run".into());
    }
    if let Some(n) = resolutions.iter().find(|&&n| !(n.is_finite() && n >= 2.0)) {
        return Err(format!("--resolution: {n} is not a count of at least 2 voxels").into());
    }
    let AnyField::Mras(field) = read_any_field::<3>(&path)? else {
        return Err(format!("{path} does not hold an MRAS field").into());
    };
    let bounds = field.bounds().ok_or("the field has no box")?;
    let longest = bounds.extent().into_iter().fold(0.0, f64::max);
    println!(
        "{path}: {} levels; {} threads",
        field.levels().len(),
        rayon::current_num_threads()
    );
    println!("grid            plain_s  smc_s  ratio  settled  evaluated  enclosures  same");
    for n in resolutions {
        let grid = grid_for(&bounds, longest / n, 0.0)?;
        let options = McOptions::default();
        let smc_options = SmcOptions::default().with_coarse_step(CoarseStep::Blocks);
        let (mut plain_t, mut smc_t) = (Vec::new(), Vec::new());
        let (mut plain, mut signed) = (None, None);
        for run in 0..=repeat {
            let t = Instant::now();
            let mesh = mesh_field(&field, &grid, 0.0, &options)?;
            let tp = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let out = signed_marching_cubes(&field, &field, &grid, 0.0, 0.0, &smc_options, None)?;
            let ts = t.elapsed().as_secs_f64();
            if run > 0 {
                plain_t.push(tp);
                smc_t.push(ts);
            }
            plain = Some(mesh);
            signed = Some(out);
        }
        let (plain, (signed, report)) = (plain.expect("ran"), signed.expect("ran"));
        assert_eq!(plain, signed, "the signed marching cubes changed the mesh");
        let (p, s) = (median(plain_t), median(smc_t));
        let c = grid.counts();
        println!(
            "{:<15} {p:>7.2} {s:>6.2} {:>6.2} {:>7.1}% {:>9.1}% {:>11}  yes",
            format!("{}×{}×{}", c[0], c[1], c[2]),
            p / s,
            100.0 * report.settled_vertices as f64 / report.n_mc as f64,
            100.0 * (report.n_smc_low + report.n_smc_high) as f64 / report.n_mc as f64,
            report.enclosures
        );
    }
    Ok(())
}
