//! Times the B-spline prefilter and evaluation on an `n³` grid, the set-up `PEERS.md` times
//! scipy on (`spline_filter(order=2, mode='mirror')`, `map_coordinates(prefilter=False)` at 1M
//! points), and optionally writes the data so that a Python script can run scipy on the very
//! same input and compare.
//!
//! ```text
//! cargo run --release --example spline_timing -- [--n 256] [--points 1000000] [--repeat 5]
//!     [--mode mirror|reflect] [--order 2|3] [--threads N] [--write-dir DIR]
//! ```
//!
//! The grid holds `sin(0.11 i)·cos(0.07 j) + sin(0.05 k + 0.02 i) + 0.1·u` with `u` uniform in
//! `[−1, 1)` from a SplitMix64 stream seeded with 42; the points are continuous indices uniform in
//! `[0, n−1]³` from the stream seeded with 43. Times are medians of `--repeat` runs after one
//! warm-up; the prefilter is timed on a fresh copy of the grid each run (the copy is not timed).
//! `--mode mirror` is `Boundary::WholeSample`, `--mode reflect` (or `grid-mirror`)
//! `Boundary::HalfSample`.
//!
//! Threads: rayon's default (`RAYON_NUM_THREADS`, else one per CPU) or `--threads N` (a global
//! rayon pool of `N` threads); the count in effect (`rayon::current_num_threads()`) is printed.
//!
//! Prints one line `n=… points=… mode=… order=… threads=… runs=… prefilter_ms=… eval_ms=…`
//! (`runs`: timed runs of each, after one warm-up). With
//! `--write-dir DIR` it writes raw little-endian f64 files (read them with `numpy.fromfile`):
//! `DIR/grid.f64` (`n³`, C order), `DIR/coeffs.f64` (`n³`, C order), `DIR/points.f64` (`3 × P`,
//! axis-major: all first coordinates, then all second, then all third — the `coordinates`
//! array of `map_coordinates`) and `DIR/values.f64` (`P`).

#[path = "common/output.rs"]
mod output;
#[path = "common/rng.rs"]
mod rng;
#[path = "common/timing.rs"]
#[allow(dead_code)] // `median` and `set_threads` are used here
mod timing;

use std::path::PathBuf;
use std::time::Instant;

use zeroset::bases::bspline::{BSplineField, Boundary, Degree, prefilter};
use zeroset::core::geometry::Aabb;
use zeroset::core::grid::Grid;

use output::write_f64;
use rng::SplitMix64;

struct Args {
    n: usize,
    points: usize,
    repeat: usize,
    boundary: Boundary,
    mode: String,
    degree: Degree,
    order: usize,
    threads: Option<usize>,
    write_dir: Option<PathBuf>,
}

const USAGE: &str = "usage: spline_timing [--n 256] [--points 1000000] [--repeat 5] \
[--mode mirror|reflect] [--order 2|3] [--threads N] [--write-dir DIR]";

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        n: 256,
        points: 1_000_000,
        repeat: 5,
        boundary: Boundary::WholeSample,
        mode: "mirror".into(),
        degree: Degree::Quadratic,
        order: 2,
        threads: None,
        write_dir: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--n" => args.n = value()?.parse().map_err(|e| format!("--n: {e}"))?,
            "--points" => args.points = value()?.parse().map_err(|e| format!("--points: {e}"))?,
            "--repeat" => args.repeat = value()?.parse().map_err(|e| format!("--repeat: {e}"))?,
            "--mode" => {
                args.mode = value()?;
                args.boundary = match args.mode.as_str() {
                    "mirror" => Boundary::WholeSample,
                    "reflect" | "grid-mirror" => Boundary::HalfSample,
                    other => return Err(format!("--mode: {other}: expected mirror or reflect")),
                }
            }
            "--order" => {
                args.order = value()?.parse().map_err(|e| format!("--order: {e}"))?;
                args.degree = match args.order {
                    2 => Degree::Quadratic,
                    3 => Degree::Cubic,
                    other => return Err(format!("--order: {other}: expected 2 or 3")),
                }
            }
            "--threads" => {
                args.threads = Some(value()?.parse().map_err(|e| format!("--threads: {e}"))?)
            }
            "--write-dir" => args.write_dir = Some(value()?.into()),
            "--help" | "-h" => return Err(USAGE.into()),
            other => return Err(format!("unknown argument {other}\n{USAGE}")),
        }
    }
    if args.n == 0 || args.repeat == 0 {
        return Err("--n and --repeat must be positive".into());
    }
    Ok(args)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let threads = timing::set_threads(args.threads)?;
    let n = args.n;
    let shape = [n, n, n];

    let mut rng = SplitMix64(42);
    let mut grid_values = vec![0.0; n * n * n];
    for (l, v) in grid_values.iter_mut().enumerate() {
        let (i, j, k) = ((l / (n * n)) as f64, ((l / n) % n) as f64, (l % n) as f64);
        *v = (0.11 * i).sin() * (0.07 * j).cos()
            + (0.05 * k + 0.02 * i).sin()
            + 0.1 * (2.0 * rng.unit() - 1.0);
    }
    let mut rng = SplitMix64(43);
    let hi = (n - 1) as f64;
    let points: Vec<[f64; 3]> = (0..args.points)
        .map(|_| std::array::from_fn(|_| hi * rng.unit()))
        .collect();

    // Prefilter: one warm-up, then the median of `repeat` runs on fresh copies.
    let mut coefficients = Vec::new();
    let mut times = Vec::with_capacity(args.repeat);
    for r in 0..=args.repeat {
        let mut data = grid_values.clone();
        let start = Instant::now();
        prefilter(&mut data, shape, args.degree, args.boundary)?;
        let elapsed = start.elapsed();
        if r > 0 {
            times.push(elapsed);
        }
        coefficients = data;
    }
    let prefilter_time = timing::median(times);

    // Evaluation at continuous indices.
    let grid = Grid::cell_centered(Aabb::new([0.0; 3], [1.0; 3])?, shape)?;
    let field = BSplineField::from_coefficients(grid, coefficients, args.degree, args.boundary)?;
    let mut values = vec![0.0; points.len()];
    let mut times = Vec::with_capacity(args.repeat);
    for r in 0..=args.repeat {
        let start = Instant::now();
        field.values_at_indices(&points, &mut values);
        let elapsed = start.elapsed();
        if r > 0 {
            times.push(elapsed);
        }
    }
    let eval_time = timing::median(times);

    println!(
        "n={n} points={} mode={} order={} threads={threads} runs={} prefilter_ms={:.3} eval_ms={:.3}",
        args.points,
        args.mode,
        args.order,
        args.repeat,
        prefilter_time.as_secs_f64() * 1e3,
        eval_time.as_secs_f64() * 1e3,
    );

    if let Some(dir) = &args.write_dir {
        std::fs::create_dir_all(dir)?;
        write_f64(&dir.join("grid.f64"), grid_values.iter().copied())?;
        write_f64(
            &dir.join("coeffs.f64"),
            field.coefficients().iter().copied(),
        )?;
        write_f64(
            &dir.join("points.f64"),
            (0..3).flat_map(|a| points.iter().map(move |p| p[a])),
        )?;
        write_f64(&dir.join("values.f64"), values.iter().copied())?;
    }
    Ok(())
}
