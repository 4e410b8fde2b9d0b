//! Times marching-cubes extraction on an `n³` vertex grid over `[0, 1]³`, the set-up `PEERS.md`
//! times scikit-image's `marching_cubes` on, and optionally writes the samples so that a Python
//! script can run scikit-image on the very same input and compare.
//!
//! ```text
//! cargo run --release --example mc_timing -- [--n 128,256] [--shape torus|sphere] [--repeat 5]
//!     [--threads N] [--write-dir DIR] [--csv FILE]
//! ```
//!
//! The samples are the signed distance of a torus (`R = 0.3`, `r = 0.1`) or a sphere
//! (`r = 0.35`), centred at `(0.5, 0.5, 0.5)`, at the coordinates `numpy.linspace(0, 1, n)` on
//! each axis, in C order with the last axis fastest: `values[(i·n + j)·n + k]` is the sample at
//! `(x_i, y_j, z_k)`. Only the extraction is timed: one call of `marching_cubes` on the ready
//! samples — the samples' check, the cell walk, welding the vertices into an indexed mesh and the
//! normals (central differences of the samples), i.e. what scikit-image's `marching_cubes`
//! returns — the median of `--repeat` runs after one warm-up. Building the `Grid` (a few
//! numbers) is outside; sampling the field is outside (the peer reads the samples from a file).
//!
//! Threads: rayon's default (`RAYON_NUM_THREADS`, else one per CPU), or `--threads N` (a global
//! rayon pool of `N` threads); the count in effect is printed and written to the CSV.
//!
//! Prints one line per size and, with `--csv FILE`, writes the table
//! `n,shape,extract_ms,vertices,triangles,euler,watertight,max_abs_sdf_over_h,runs,threads,warmup,times_ms`
//! (`euler` is `V − E + F`, `watertight` whether every edge is used by exactly two triangles,
//! once each way, `max_abs_sdf_over_h` the largest `|sdf|` at a vertex over the spacing `h`,
//! `warmup` 1 when a warm-up run preceded the timed ones, `times_ms` every timed run). With
//! `--write-dir DIR` it writes the samples as raw little-endian f64,
//! `DIR/mc_{shape}_{n}.f64` (read them with `numpy.fromfile(path).reshape(n, n, n)`).

#[path = "common/output.rs"]
mod output;
#[path = "common/timing.rs"]
mod timing;

use std::fmt::Write as _;
use std::path::PathBuf;

use zeroset::core::analytic::{Sphere, Torus};
use zeroset::core::field::ScalarField;
use zeroset::core::geometry::Aabb;
use zeroset::core::grid::Grid;
use zeroset::mesh::checks::check;
use zeroset::mesh::cubes::{McOptions, marching_cubes};

use output::{write_f64, write_text};

struct Args {
    sizes: Vec<usize>,
    shape: String,
    repeat: usize,
    threads: Option<usize>,
    write_dir: Option<PathBuf>,
    csv: Option<PathBuf>,
}

const USAGE: &str = "usage: mc_timing [--n 128,256] [--shape torus|sphere] [--repeat 5] \
[--threads N] [--write-dir DIR] [--csv FILE]";

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        sizes: vec![128, 256],
        shape: "torus".into(),
        repeat: 5,
        threads: None,
        write_dir: None,
        csv: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--n" => args.sizes = timing::parse_list("--n", &value()?)?,
            "--shape" => {
                args.shape = value()?;
                if args.shape != "torus" && args.shape != "sphere" {
                    return Err(format!("--shape: {}: expected torus or sphere", args.shape));
                }
            }
            "--repeat" => args.repeat = value()?.parse().map_err(|e| format!("--repeat: {e}"))?,
            "--threads" => {
                args.threads = Some(value()?.parse().map_err(|e| format!("--threads: {e}"))?)
            }
            "--write-dir" => args.write_dir = Some(value()?.into()),
            "--csv" => args.csv = Some(value()?.into()),
            "--help" | "-h" => return Err(USAGE.into()),
            other => return Err(format!("unknown argument {other}\n{USAGE}")),
        }
    }
    if args.sizes.iter().any(|&n| n < 2) || args.repeat == 0 {
        return Err("--n must be at least 2 and --repeat positive".into());
    }
    Ok(args)
}

/// `numpy.linspace(0, 1, n)`, bit for bit: numpy computes `i · step` with `step = 1/(n − 1)`
/// and sets the last point to `stop` exactly.
fn linspace(n: usize) -> Vec<f64> {
    let step = 1.0 / (n - 1) as f64;
    let mut x: Vec<f64> = (0..n).map(|i| i as f64 * step).collect();
    x[n - 1] = 1.0;
    x
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let field: Box<dyn ScalarField<3>> = match args.shape.as_str() {
        "sphere" => Box::new(Sphere::new([0.5; 3], 0.35)),
        _ => Box::new(Torus::new([0.5; 3], 0.3, 0.1)),
    };
    let threads = timing::set_threads(args.threads)?;
    let mut csv = String::from(
        "n,shape,extract_ms,vertices,triangles,euler,watertight,max_abs_sdf_over_h,runs,threads,\
         warmup,times_ms\n",
    );
    for &n in &args.sizes {
        let x = linspace(n);
        let mut values = vec![0.0; n * n * n];
        for (l, v) in values.iter_mut().enumerate() {
            let (i, j, k) = (l / (n * n), (l / n) % n, l % n);
            *v = field.value(&[x[i], x[j], x[k]]);
        }
        let grid = Grid::vertex_centered(Aabb::new([0.0; 3], [1.0; 3])?, [n, n, n])?;
        let options = McOptions::default();
        let timed = timing::measure(args.repeat, None, || {
            marching_cubes(&grid, &values, 0.0, &options)
        })?;
        let ms = timed.ms();
        let mesh = &timed.last;
        // Watertight: every edge in exactly two triangles, traversed once each way.
        let report = check(mesh);
        let (euler, watertight) = (
            report.euler_characteristic,
            report.closed && report.inconsistent_edges == 0,
        );
        let h = 1.0 / (n - 1) as f64;
        let max_sdf = mesh
            .vertices()
            .iter()
            .map(|p| field.value(p).abs())
            .fold(0.0, f64::max);
        println!(
            "n={n} shape={} threads={threads} extract_ms={ms:.3} ({}) vertices={} triangles={} \
             euler={euler} watertight={watertight} max_abs_sdf_over_h={:.3e}",
            args.shape,
            timed.how(),
            mesh.num_vertices(),
            mesh.num_triangles(),
            max_sdf / h,
        );
        writeln!(
            csv,
            "{n},{},{ms:.3},{},{},{euler},{watertight},{:.6e},{},{threads},{},{}",
            args.shape,
            mesh.num_vertices(),
            mesh.num_triangles(),
            max_sdf / h,
            timed.runs(),
            u8::from(timed.warmup),
            timing::times_cell(&timed.times),
        )?;
        if let Some(dir) = &args.write_dir {
            std::fs::create_dir_all(dir)?;
            write_f64(
                &dir.join(format!("mc_{}_{n}.f64", args.shape)),
                values.iter().copied(),
            )?;
        }
    }
    if let Some(path) = &args.csv {
        write_text(path, &csv)?;
    }
    Ok(())
}
