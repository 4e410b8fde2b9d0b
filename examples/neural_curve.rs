//! Neural implicit curves with the thin-plate curvature loss: Jiang–Turk (paper 003) §3–4.2,
//! Figs. 3–4 — the paper's method and its three baselines, side by side.
//!
//! ```text
//! cargo run --release --example neural_curve [-- --out DIR] [--steps N] [--seed S]
//!     [--only paper] [--repeat R] [--export DIR] [--json FILE]
//! ```
//!
//! ## Set-up (the "neural curve" line of `PEERS.md`)
//!
//! The curve `r(t) = 0.6 + 0.15 cos 3t`; 30 on-curve points (value 0), 15 inside at `0.5 r`
//! and 15 outside at `1.4 r` (`examples/common/curve.rs`). **Signs**: zeroset's fields are
//! negative inside, so the inside points take −1 and the outside ones +1 (the paper's +1 inside
//! / −1 outside, flipped). The net is 2 → 32 → 32 → 1 with `tanh`, trained by Adam for 3000
//! steps (learning rate 1e-2) on `Ω = [−1, 1]²`; the defaults of
//! `zeroset::bases::neural::NeuralParams` otherwise (Glorot-uniform initial weights from the
//! seed, one fixed set of auxiliary points).
//!
//! The four variants ([`Variant`]): **(paper)** λ = 0.05, curvature at P = 250 uniform
//! auxiliary points (weight `λ|Ω|/P`, `|Ω| = 4`); **(a)** λ = 0; **(b)** the curvature term at
//! the 60 constraint points instead; **(c)** no curvature term, dropout 0.1 on the hidden
//! activations while training. Two more rows, not in the picture: a fifth redraws the auxiliary points at
//! every step, a sixth refits the paper variant's output layer by least squares
//! (`NeuralField::refit_last_layer`, dense QR).
//!
//! ## Output
//!
//! A table: max constraint residual `maxᵢ |f(xᵢ) − zᵢ|`, the final data and curvature terms of
//! the loss, the **curvature energy** `∫_Ω f_xx² + 2f_xy² + f_yy²` estimated independently of
//! the training points (midpoint rule on a 256 × 256 grid over `Ω`, exact Hessians), the zero
//! contour's loops and open pieces (marching squares on 257 × 257 samples), and the training
//! time. `DIR/neural_curve.png` (default `DIR = target/neural_curve`) shows the four zero
//! contours left to right in the order above: each panel is the field over `Ω` (blue inside,
//! red outside), the true curve in grey, the zero contour in black, on-curve points black,
//! inside points purple, outside points orange.
//!
//! For the peer script (`benches/peers/neural_peers.py`): `--only paper` trains the paper
//! variant only, `--repeat R` times it R more times (after the first run, which is the warm-up)
//! and reports the median, `--export DIR` writes the data, the initial weights and the
//! auxiliary points as `.npy` (weights as PyTorch stores them, `out × in`), `--json FILE` the
//! timings and residuals.

#[path = "common/curve.rs"]
mod curve;
#[path = "common/npy.rs"]
mod npy;
#[path = "common/timing.rs"]
#[allow(dead_code)] // only `median` is used here
mod timing;

use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use zeroset::bases::neural::{
    NeuralField, NeuralFit, NeuralParams, Trained, Variant, auxiliary_points,
};
use zeroset::core::Aabb;
use zeroset::core::geometry::Point2;
use zeroset::core::grid::Grid;
use zeroset::mesh::preview::{Image, pixel_of, render_field_2d};
use zeroset::mesh::squares::{Contour, contour_field};
use zeroset::solvers::DenseQr;

use curve::{Kind, Site, curve_point, points_and_targets, sites};

type BoxError = Box<dyn Error>;

const USAGE: &str = "usage: neural_curve [--out DIR] [--steps N] [--seed S] [--only paper] \
                     [--repeat R] [--export DIR] [--json FILE]";

/// Pixels per panel side, and the white gap between panels.
const PANEL: usize = 300;
const GAP: usize = 8;
/// Grid of the curvature-energy estimate (cells per axis) and of the contours (samples).
const ENERGY_CELLS: usize = 256;
const CONTOUR_SAMPLES: usize = 257;

#[derive(Debug, Clone)]
struct Args {
    out: PathBuf,
    steps: usize,
    seed: u64,
    only_paper: bool,
    repeat: usize,
    export: Option<PathBuf>,
    json: Option<PathBuf>,
}

fn parse_args() -> Result<Option<Args>, String> {
    let mut a = Args {
        out: PathBuf::from("target/neural_curve"),
        steps: NeuralParams::default().steps,
        seed: 0,
        only_paper: false,
        repeat: 0,
        export: None,
        json: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |flag: &str| {
            it.next()
                .filter(|v| !v.is_empty())
                .ok_or_else(|| format!("{flag} needs a value\n{USAGE}"))
        };
        let number = |flag: &str, v: String| {
            v.parse::<u64>()
                .map_err(|e| format!("{flag} {v:?}: {e}\n{USAGE}"))
        };
        match arg.as_str() {
            "--out" => a.out = value("--out")?.into(),
            "--steps" => a.steps = number("--steps", value("--steps")?)? as usize,
            "--seed" => a.seed = number("--seed", value("--seed")?)?,
            "--repeat" => a.repeat = number("--repeat", value("--repeat")?)? as usize,
            "--export" => a.export = Some(value("--export")?.into()),
            "--json" => a.json = Some(value("--json")?.into()),
            "--only" => match value("--only")?.as_str() {
                "paper" => a.only_paper = true,
                v => return Err(format!("--only takes `paper`, got {v:?}\n{USAGE}")),
            },
            "--help" | "-h" => return Ok(None),
            _ => return Err(format!("unknown argument {arg:?}\n{USAGE}")),
        }
    }
    Ok(Some(a))
}

/// `Ω = [−1, 1]²`.
fn domain() -> Result<Aabb<2>, BoxError> {
    Ok(Aabb::new([-1.0, -1.0], [1.0, 1.0])?)
}

/// One trained variant and what is reported about it.
struct Row {
    label: String,
    trained: Trained<2>,
    energy: f64,
    contour: Contour,
    time: Duration,
}

/// `row` with its output layer refitted to the constraints by least squares (dense QR): the
/// field, residual and curvature energy after the refit; the data term and time are the
/// refit's, the curvature term the training's.
fn refit(row: &Row, grid: &Grid<2>) -> Result<Row, BoxError> {
    let (points, targets) = points_and_targets(&sites());
    let start = Instant::now();
    let (field, report) =
        row.trained
            .field
            .refit_last_layer(&points, &targets, &DenseQr::default())?;
    let time = row.time + start.elapsed();
    let mut trained = row.trained.clone();
    trained.report.max_residual = report.max_residual_after;
    trained.report.data_term = report.data_after;
    trained.field = field;
    Ok(Row {
        label: format!("{} + refit", row.label),
        energy: trained.field.thin_plate_energy(ENERGY_CELLS),
        contour: contour_field(&trained.field, grid, 0.0)?,
        trained,
        time,
    })
}

fn params(variant: Variant, args: &Args) -> NeuralParams {
    NeuralParams::variant(variant)
        .with_steps(args.steps)
        .with_seed(args.seed)
}

fn train(params: NeuralParams, label: &str, grid: &Grid<2>) -> Result<Row, BoxError> {
    let (points, targets) = points_and_targets(&sites());
    let fit = NeuralFit::new(params).with_domain(domain()?);
    let start = Instant::now();
    let trained = fit.fit(&points, &targets)?;
    let time = start.elapsed();
    Ok(Row {
        label: label.to_string(),
        energy: trained.field.thin_plate_energy(ENERGY_CELLS),
        contour: contour_field(&trained.field, grid, 0.0)?,
        trained,
        time,
    })
}

fn print_table(rows: &[Row]) {
    println!(
        "{:<40} {:>10} {:>10} {:>11} {:>12} {:>9} {:>8} {:>8}",
        "variant",
        "max resid",
        "data term",
        "curv. term",
        "energy ∫Ω",
        "loops/open",
        "time s",
        "ms/step"
    );
    for r in rows {
        let rep = &r.trained.report;
        println!(
            "{:<40} {:>10.4} {:>10.4} {:>11.4} {:>12.2} {:>7}/{:<2} {:>8.2} {:>8.3}",
            r.label,
            rep.max_residual,
            rep.data_term,
            rep.curvature_term,
            r.energy,
            r.contour.num_closed(),
            r.contour.num_open(),
            r.time.as_secs_f64(),
            1e3 * r.time.as_secs_f64() / rep.steps.max(1) as f64
        );
    }
}

// ---------------------------------------------------------------------------------------------
// The picture.

fn colour(kind: Kind) -> [u8; 3] {
    match kind {
        Kind::OnCurve => [0, 0, 0],
        Kind::Inside => [148, 103, 189],
        Kind::Outside => [255, 127, 14],
    }
}

fn panel(field: &NeuralField<2>, contour: &Contour, sites: &[Site]) -> Result<Image, BoxError> {
    let omega = domain()?;
    let mut image = render_field_2d(field, omega, PANEL)?;
    let (w, h) = (image.width(), image.height());
    let px = |p: &Point2| pixel_of(&omega, w, h, p);
    let n = 720;
    for k in 0..n {
        let t0 = std::f64::consts::TAU * k as f64 / n as f64;
        let t1 = std::f64::consts::TAU * (k + 1) as f64 / n as f64;
        image.draw_line(
            px(&curve_point(t0, 1.0)),
            px(&curve_point(t1, 1.0)),
            5.0,
            [200, 200, 200],
        );
    }
    for line in &contour.lines {
        for (a, b) in line.segments() {
            image.draw_line(px(&a), px(&b), 2.5, [0, 0, 0]);
        }
    }
    for s in sites {
        let radius = if s.kind == Kind::OnCurve { 3.0 } else { 4.0 };
        image.fill_disc(px(&s.point), radius + 1.0, [255, 255, 255]);
        image.fill_disc(px(&s.point), radius, colour(s.kind));
    }
    Ok(image)
}

fn write_png(rows: &[Row], path: &Path) -> Result<(), BoxError> {
    compose(rows)?.write_png(path)?;
    Ok(())
}

/// The panels of `rows` side by side.
fn compose(rows: &[Row]) -> Result<Image, BoxError> {
    let sites = sites();
    let panels: Vec<Image> = rows
        .iter()
        .map(|r| panel(&r.trained.field, &r.contour, &sites))
        .collect::<Result<_, _>>()?;
    let width = panels.iter().map(Image::width).sum::<usize>() + GAP * (panels.len() + 1);
    let height = panels.iter().map(Image::height).max().unwrap_or(1) + 2 * GAP;
    let mut image = Image::filled(width, height, [255, 255, 255])?;
    let mut x = GAP;
    for p in &panels {
        image.blit(p, x, GAP);
        x += p.width() + GAP;
    }
    Ok(image)
}

// ---------------------------------------------------------------------------------------------
// For the peer script.

/// Writes the constraints, the initial weights (PyTorch's `out × in` layout) and the
/// auxiliary points of `params` as `.npy` files into `dir`.
fn export(params: &NeuralParams, dir: &Path) -> Result<(), BoxError> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let (points, targets) = points_and_targets(&sites());
    let fit = NeuralFit::new(params.clone()).with_domain(domain()?);
    let init = fit.initial_field(&points)?;
    if init.centre() != [0.0, 0.0] || init.input_scale() != 1.0 || init.output_scale() != 1.0 {
        return Err("the input map of Ω = [−1, 1]² should be the identity".into());
    }
    let flat: Vec<f64> = points.iter().flatten().copied().collect();
    npy::write_npy(&dir.join("points.npy"), &[points.len(), 2], &flat)?;
    npy::write_npy(&dir.join("targets.npy"), &[targets.len()], &targets)?;
    let layers = params.architecture.widths().len() + 1;
    for l in 0..layers {
        let (w, b) = init.layer(l);
        let out = b.len();
        let inputs = w.len() / out;
        // Column-major (zeroset) to row-major out × in (torch.nn.Linear.weight).
        let row_major: Vec<f64> = (0..out)
            .flat_map(|j| (0..inputs).map(move |k| w[j + out * k]))
            .collect();
        npy::write_npy(&dir.join(format!("w{l}.npy")), &[out, inputs], &row_major)?;
        npy::write_npy(&dir.join(format!("b{l}.npy")), &[out], b)?;
    }
    let count = if params.resample_aux {
        params.aux_points * params.steps.max(1)
    } else {
        params.aux_points
    };
    let aux = auxiliary_points(&domain()?, params.seed, count);
    let flat: Vec<f64> = aux.iter().flatten().copied().collect();
    npy::write_npy(&dir.join("aux.npy"), &[count, 2], &flat)?;
    println!(
        "exported the constraints, initial weights and {count} auxiliary points to {}",
        dir.display()
    );
    Ok(())
}

fn write_json(path: &Path, row: &Row, refitted: &Row, times: &[Duration]) -> Result<(), BoxError> {
    let ms: Vec<String> = times
        .iter()
        .map(|t| format!("{:.6}", t.as_secs_f64() * 1e3))
        .collect();
    let median = timing::median(times.to_vec());
    let rep = &row.trained.report;
    let threads = rayon::current_num_threads();
    let text = format!(
        "{{\"steps\": {}, \"threads\": {threads}, \"ms\": {:.6}, \"ms_per_step\": {:.6}, \
         \"times_ms\": [{}], \"max_residual\": {:e}, \"data_term\": {:e}, \
         \"curvature_term\": {:e}, \"energy\": {:e}, \"curvature_weight\": {:e}, \
         \"refit_max_residual\": {:e}, \"refit_energy\": {:e}, \"refit_ms\": {:.6}}}\n",
        rep.steps,
        median.as_secs_f64() * 1e3,
        median.as_secs_f64() * 1e3 / rep.steps.max(1) as f64,
        ms.join(", "),
        rep.max_residual,
        rep.data_term,
        rep.curvature_term,
        row.energy,
        rep.curvature_weight,
        refitted.trained.report.max_residual,
        refitted.energy,
        (refitted.time - row.time).as_secs_f64() * 1e3
    );
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------

fn run() -> Result<(), BoxError> {
    let Some(args) = parse_args()? else {
        println!("{USAGE}");
        return Ok(());
    };
    let grid = Grid::vertex_centered(domain()?, [CONTOUR_SAMPLES, CONTOUR_SAMPLES])?;
    println!(
        "curve r(t) = 0.6 + 0.15 cos 3t; 30 on-curve (0), 15 inside at 0.5 r (-1), 15 outside at \
         1.4 r (+1); negative inside"
    );
    println!(
        "MLP 2 -> 32 -> 32 -> 1 tanh, Adam lr {} for {} steps, seed {}, Omega = [-1, 1]^2; {} \
         rayon thread(s)\n",
        NeuralParams::default().learning_rate,
        args.steps,
        args.seed,
        rayon::current_num_threads()
    );
    if let Some(dir) = &args.export {
        export(&params(Variant::Paper, &args), dir)?;
    }
    let mut rows = Vec::new();
    let variants: &[Variant] = if args.only_paper {
        &[Variant::Paper]
    } else {
        &Variant::ALL
    };
    for &v in variants {
        rows.push(train(params(v, &args), v.label(), &grid)?);
    }
    let mut times = Vec::new();
    for _ in 0..args.repeat {
        let again = train(params(Variant::Paper, &args), "paper (repeat)", &grid)?;
        if again.trained.field.parameters() != rows[0].trained.field.parameters() {
            return Err("a repeated run gave other weights: training is not deterministic".into());
        }
        times.push(again.time);
    }
    let refitted = refit(&rows[0], &grid)?;
    if !args.only_paper {
        let mut redrawn = params(Variant::Paper, &args);
        redrawn.resample_aux = true;
        rows.push(train(redrawn, "(extra) λ=0.05, aux redrawn/step", &grid)?);
        let mut extra = refit(&rows[0], &grid)?;
        extra.label = format!("(extra) {}", extra.label);
        rows.push(extra);
    }
    print_table(&rows);
    if !times.is_empty() {
        println!(
            "\npaper variant, {} timed runs after a warm-up: median {:.3} s ({:.3} ms/step)",
            times.len(),
            timing::median(times.clone()).as_secs_f64(),
            timing::median(times.clone()).as_secs_f64() * 1e3 / args.steps.max(1) as f64
        );
    }
    if let Some(path) = &args.json {
        let all = if times.is_empty() {
            vec![rows[0].time]
        } else {
            times
        };
        write_json(path, &rows[0], &refitted, &all)?;
        println!("wrote {}", path.display());
    }
    if !args.only_paper {
        std::fs::create_dir_all(&args.out)
            .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
        let png = args.out.join("neural_curve.png");
        write_png(&rows[..4], &png)?;
        println!(
            "\nwrote {} (left to right: {})",
            png.display(),
            Variant::ALL.map(Variant::label).join(" | ")
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use zeroset::core::field::ScalarField;

    #[test]
    fn every_variant_trains_and_draws() {
        let args = Args {
            out: PathBuf::new(),
            steps: 150,
            seed: 0,
            only_paper: false,
            repeat: 0,
            export: None,
            json: None,
        };
        let grid = Grid::vertex_centered(domain().unwrap(), [65, 65]).unwrap();
        let rows: Vec<Row> = Variant::ALL
            .iter()
            .map(|&v| train(params(v, &args), v.label(), &grid).unwrap())
            .collect();
        for r in &rows {
            assert!(r.trained.field.value(&[0.0, 0.0]) < 0.0, "{}", r.label);
            assert!(r.energy.is_finite() && r.energy > 0.0);
        }
        let image = compose(&rows).unwrap();
        assert_eq!(image.width(), 4 * PANEL + 5 * GAP);
        assert!(image.to_png_bytes().len() > 1000);
    }
}
