//! Restoration on real data: the Stanford bunny's oriented points (`data/bunny_points.ply`,
//! 34,834 points, or the file given), as a tangent-plane field on a grid, with
//!
//! 1. its ears removed (a mask above the head, Neumann face −y where they join it), for a few α;
//! 2. its base cut flat (a mask over the bottom slab that touches the grid's border, so the
//!    paper's border rule fixes the bottom layer; Neumann face +y where the body meets it);
//! 3. a de-noising pass over the back.
//!
//! ```text
//! cargo run --release --example bunny_restore -- [PATH.ply] [--cells 128] [--write DIR]
//! ```
//!
//! The field is sampled once; each restoration rewrites a copy of the samples and interpolates
//! them. It prints how high/low the surface reaches in each mask before and after, and the timings;
//! `--write DIR` saves each result as a `.zsf` field file.

use std::path::PathBuf;
use std::time::Instant;

#[path = "common/data.rs"]
mod data;

use zeroset::bases::bspline::{BSplineField, Degree};
use zeroset::bases::field_file::write_field;
use zeroset::bases::tangent_plane::TangentPlaneField;
use zeroset::core::field::ScalarField;
use zeroset::core::geometry::{Aabb, Point};
use zeroset::core::grid::Grid;
use zeroset::core::io::read_point_cloud;
use zeroset::core::mask::{BoxMask, Face, Side};
use zeroset::restore::denoise::Denoise;
use zeroset::restore::protrusion::{Protrusion, Report};

/// The highest (`top`) or lowest y inside the box's (x, z) range where `field ≤ 0`.
fn extreme_y(field: &BSplineField<3>, lo: Point<3>, hi: Point<3>, h: f64, top: bool) -> f64 {
    let steps = ((hi[1] - lo[1]) / (h / 4.0)).round() as usize;
    let mut best = if top { lo[1] } else { hi[1] };
    let mut x = lo[0];
    while x <= hi[0] {
        let mut z = lo[2];
        while z <= hi[2] {
            let ys = (0..=steps).map(|s| lo[1] + s as f64 * h / 4.0);
            let hit = if top {
                ys.rev().find(|&y| field.value(&[x, y, z]) <= 0.0)
            } else {
                ys.clone().find(|&y| field.value(&[x, y, z]) <= 0.0)
            };
            if let Some(y) = hit {
                best = if top { best.max(y) } else { best.min(y) };
            }
            z += h / 2.0;
        }
        x += h / 2.0;
    }
    best
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut path = data::data_dir().join("bunny_points.ply");
    let mut cells = 128usize;
    let mut write: Option<PathBuf> = None;
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--cells" => cells = it.next().ok_or("--cells N")?.parse()?,
            "--write" => write = Some(it.next().ok_or("--write DIR")?.into()),
            "--help" | "-h" => {
                println!("usage: bunny_restore [PATH.ply] [--cells 128] [--write DIR]");
                return Ok(());
            }
            p => path = p.into(),
        }
    }
    let start = Instant::now();
    let cloud = read_point_cloud(&path)?;
    let field = TangentPlaneField::new(&cloud, 8)?;
    let bounds = field.bounds().ok_or("empty cloud")?;
    let e = bounds.extent();
    let longest = e.iter().copied().fold(0.0, f64::max);
    let counts = e.map(|x| ((x / longest * cells as f64).round() as usize).max(3));
    let grid = Grid::cell_centered(bounds, counts)?;
    let h = grid.spacing()[1];
    // Sample once; every restoration below starts from these samples.
    let samples = grid.sample(&field);
    let sampled = BSplineField::interpolate(grid, samples.clone(), Degree::Quadratic)?;
    println!(
        "{}: {} points; tangent-plane field (k = 8) sampled on {counts:?} cells, h = {h:.2e} \
         ({:.2} s)",
        path.display(),
        cloud.len(),
        start.elapsed().as_secs_f64()
    );
    // Restore the samples in `mask` and interpolate: the field of the paper's Eq. 6.
    let restore = |p: &Protrusion,
                   mask: &BoxMask<3>|
     -> Result<(BSplineField<3>, Report), Box<dyn std::error::Error>> {
        let (g, report) = p.restore_samples(&grid, &samples, mask)?;
        Ok((
            BSplineField::interpolate(grid, g, Degree::Quadratic)?,
            report,
        ))
    };
    let save = |name: &str, f: &BSplineField<3>| -> Result<(), Box<dyn std::error::Error>> {
        if let Some(dir) = &write {
            std::fs::create_dir_all(dir)?;
            write_field(dir.join(name), f)?;
        }
        Ok(())
    };

    // 1. The ears.
    let (lo, hi) = ([-0.095, 0.145, -0.065], [0.0, 0.2, 0.04]);
    let mask = BoxMask::from_corners(&grid, lo, hi)?;
    let before = extreme_y(&sampled, lo, hi, h, true);
    println!(
        "\nears: mask {lo:?} .. {hi:?} ({} cells), face -y; the surface reaches {:.1} cells above it",
        mask.len(),
        (before - lo[1]) / h
    );
    println!(
        "{:>22} {:>9} {:>9} {:>11} {:>10}",
        "alpha", "unknowns", "ms", "rel_res", "top"
    );
    for alpha in [None, Some(0.5), Some(1.0), Some(2.0), Some(4.0)] {
        let mut p = Protrusion::new(Face::new(1, Side::Lower));
        p.alpha = alpha;
        let t = Instant::now();
        let (restored, report) = restore(&p, &mask)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let top = extreme_y(&restored, lo, hi, h, true);
        let label = match alpha {
            None => format!("{:.3} (default)", report.alpha.unwrap_or(f64::NAN)),
            Some(a) => format!("{a}"),
        };
        println!(
            "{label:>22} {:>9} {ms:>9.1} {:>11.2e} {:>10.1}",
            report.unknowns,
            report.solve.rel_residual,
            (top - lo[1]) / h
        );
        if alpha == Some(1.0) {
            save("bunny_no_ears.zsf", &restored)?;
        }
    }

    // 2. The base: a slab at the bottom that touches the grid's border (border rule).
    let b = grid.bounds();
    let (lo, hi) = ([-0.07, b.min()[1], -0.05], [0.05, 0.045, 0.05]);
    let mask = BoxMask::from_corners(&grid, lo, hi)?;
    let low_before = extreme_y(&sampled, lo, hi, h, false);
    let t = Instant::now();
    let (restored, report) = restore(&Protrusion::new(Face::new(1, Side::Upper)), &mask)?;
    let low_after = extreme_y(&restored, lo, hi, h, false);
    println!(
        "\nbase: mask {lo:?} .. {hi:?} touching the border {:?}, face +y: alpha {:.3}, {} unknowns, \
         {:.1} ms; lowest surface point {:.1} -> {:.1} cells below the face",
        mask.border_faces(),
        report.alpha.unwrap_or(f64::NAN),
        report.unknowns,
        t.elapsed().as_secs_f64() * 1e3,
        (hi[1] - low_before) / h,
        (hi[1] - low_after) / h
    );
    save("bunny_no_base.zsf", &restored)?;

    // 3. De-noise the back.
    let (lo, hi) = ([-0.02, 0.06, -0.06], [0.06, 0.14, 0.0]);
    let mask = BoxMask::from_corners(&grid, lo, hi)?;
    let t = Instant::now();
    let coarse = mask.extent().map(|n| (n / 4).max(1));
    let smooth = Denoise::new(coarse).restore_samples(&sampled, &grid, &samples, &mask)?;
    let smooth = BSplineField::interpolate(grid, smooth, Degree::Quadratic)?;
    let region = Aabb::new(lo, hi)?;
    let pts: Vec<Point<3>> = mask.indices().map(|i| grid.point(i)).collect();
    let (mut a, mut c) = (vec![0.0; pts.len()], vec![0.0; pts.len()]);
    sampled.values(&pts, &mut a);
    smooth.values(&pts, &mut c);
    let change = a.iter().zip(&c).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / pts.len() as f64;
    println!(
        "\nback: de-noised {:?} with coarse {coarse:?} in {:.1} ms; RMS change {:.2e} ({:.2} cells)",
        region,
        t.elapsed().as_secs_f64() * 1e3,
        change.sqrt(),
        change.sqrt() / h
    );
    save("bunny_smooth_back.zsf", &smooth)?;
    Ok(())
}
