//! The error of the fast multipole evaluation against the exact direct sum as the order grows:
//! paper 002's Tables 1–2 (biharmonic `r` and triharmonic `r³`, `N_s ≈ 10,000` sources) on real
//! data, the bunny and the kitten (`common/fmm_data.rs`).
//!
//! ```text
//! cargo run --release --example fmm_error -- [--orders 4,5,…,12] [--targets M] [--sources N]
//!     [--clouds bunny_points.ply,kitten.xyz] [--kernels r,r3] [--data DIR]
//! ```
//!
//! Targets: `M` (default 100,000) points drawn uniformly (seeded) in the field's box. Columns:
//! `max_abs` the largest `|s_fmm − s|` (the paper's "max residual"), `max_rel` that divided by
//! `max |s|` over the targets, `rms_rel` the RMS error over the RMS value, the compression's
//! largest kept rank, and the build and evaluation times.

#[path = "common/data.rs"]
mod data;
#[path = "common/fmm_data.rs"]
mod fmm_data;

use std::time::Instant;

use zeroset::bases::rbf::fmm::{FmmField, FmmOptions};
use zeroset::bases::rbf::{Kernel, RbfField};
use zeroset::core::ScalarField;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn main() -> Res<()> {
    let mut orders: Vec<usize> = (4..=12).collect();
    let (mut targets, mut sources) = (100_000usize, 10_000usize);
    let mut clouds: Vec<String> = vec!["bunny_points.ply".into(), "kitten.xyz".into()];
    let mut kernels: Vec<String> = vec!["r".into(), "r3".into()];
    let mut data = data::data_dir();
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let v = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--orders" => {
                orders = v
                    .split(',')
                    .map(|s| s.trim().parse::<usize>())
                    .collect::<Result<_, _>>()?
            }
            "--targets" => targets = v.parse()?,
            "--sources" => sources = v.parse()?,
            "--clouds" => clouds = v.split(',').map(String::from).collect(),
            "--kernels" => kernels = v.split(',').map(String::from).collect(),
            "--data" => data = v.into(),
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    for cloud in &clouds {
        for kernel in &kernels {
            match fmm_data::load(&data, cloud, kernel, sources)? {
                fmm_data::Field::R(f) => table(cloud, &f, &orders, targets)?,
                fmm_data::Field::R3(f) => table(cloud, &f, &orders, targets)?,
            }
        }
    }
    Ok(())
}

fn table<K: Kernel + Clone>(
    cloud: &str,
    field: &RbfField<K, 3>,
    orders: &[usize],
    m: usize,
) -> Res<()> {
    let bounds = field.bounds().ok_or("no bounds")?;
    let targets = fmm_data::uniform_targets(&bounds, m, 7);
    let mut exact = vec![0.0; m];
    let t = Instant::now();
    field.values(&targets, &mut exact);
    let direct = t.elapsed().as_secs_f64();
    let scale = exact.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    println!(
        "\n{cloud}, kernel {}: {} centres, {m} targets, direct sum {direct:.2} s, max |s| {scale:.3e}",
        field.kernel().name(),
        field.num_centres()
    );
    println!(
        "{:>3} {:>10} {:>10} {:>10} {:>5} {:>8} {:>8} {:>8}",
        "p", "max_abs", "max_rel", "rms_rel", "rank", "ops_s", "build_s", "eval_s"
    );
    let mut fast = vec![0.0; m];
    for &p in orders {
        let t = Instant::now();
        let f = FmmField::new(field, &FmmOptions::new(p))?;
        let build = t.elapsed().as_secs_f64();
        let t = Instant::now();
        f.values(&targets, &mut fast);
        let eval = t.elapsed().as_secs_f64();
        let (max, max_rel, rms_rel) = fmm_data::errors(&fast, &exact);
        let r = f.report();
        println!(
            "{p:>3} {max:>10.2e} {:>10.2e} {:>10.2e} {:>5} {:>8.2} {:>8.2} {eval:>8.2}",
            max_rel,
            rms_rel,
            r.max_rank,
            r.operator_seconds,
            build - r.operator_seconds
        );
    }
    Ok(())
}
