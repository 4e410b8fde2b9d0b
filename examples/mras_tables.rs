//! Reproduces paper 004's MRAS results (Pan, Tong & Chen) with zeroset.
//!
//! ```text
//! cargo run --release --example mras_tables [-- [shapes] [tables] [figure] [--out DIR]
//!     [--data DIR] [--rbf-sizes 1000,2000,4000] [option overrides]]
//! cargo run --release --example mras_tables -- fit FILE [option overrides]
//! ```
//!
//! - **shapes** (Fig. 5): single-level fits of a densely sampled sphere (3,000 points) and torus
//!   (5,760 points, radii 1 and 0.4): CP rank, relative error, storage; with the defaults and
//!   with the single-level settings (a stronger thin-plate weight, which pushes the free
//!   coefficients to low rank).
//! - **tables** (Tables 1–2): `bunny_points.ply` (34,834 points) and `kitten.xyz` (5,210): MRAS
//!   with the defaults — depth, relative error (max and mean distance from the points to the zero
//!   set over the points' bounding-box diagonal), storage as the paper counts it, fit time —
//!   against (a) the same MRAS uncompressed and (b) zeroset's RBF field (off-surface, kernel r)
//!   on seeded subsets of the points, measured the same way; also (a') the same MRAS with plain
//!   CP-ALS at every rank (`--plain-cp`), to show what the weighted CP fit saves. Each MRAS
//!   field is meshed at 256 cells along the box's longest side (the time is printed) and
//!   written to `OUT/<model>_mras.ply`, so that `benches/peers/poisson_peers.py --measure`
//!   measures it with the same point-to-triangle distance as Open3D's screened Poisson meshes.
//! - **figure** (Fig. 2): the bunny's MRAS surface after levels 1, 2, …, side by side,
//!   `OUT/mras_bunny_levels.png`.
//! - **fit FILE**: one fit with its per-level report (for trying options).
//!
//! Distances: each point is projected onto the zero set along the gradient
//! ([`distance_to_zero_set`]); the point reached lies on the surface, so the figure is an upper
//! bound of the true distance. Option overrides: `--tolerance T --max-level L --lambda λ
//! --omega1 ω₁ --omega2 ω₂ --omega2-root ω₂ --omega2-decay d --m0 m₀ --beta β --min-knots m --admm-iter N --admm-tol t
//! --cp-scale s --cp-points p --cp-refined c --n-min N --plain-cp --no-compress`.

#[path = "common/data.rs"]
mod data;
#[path = "common/rbf_storage.rs"]
mod rbf_storage;
#[path = "common/shapes.rs"]
mod shapes;

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use zeroset_bases::mras::{MrasFit, MrasOptions, fit_mras};
use zeroset_field_core::field::distance_to_zero_set;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::io::read_point_cloud;
use zeroset_mesh::preview::{Axis, Image, RenderOptions, render_mesh};
use zeroset_mesh::{McOptions, check, mesh_field, write_ply};

use shapes::{sphere, torus};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

struct Args {
    sections: Vec<String>,
    file: Option<PathBuf>,
    data: PathBuf,
    out: PathBuf,
    rbf_sizes: Vec<usize>,
    options: MrasOptions,
}

fn parse() -> Res<Args> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut a = Args {
        sections: Vec::new(),
        file: None,
        data: data::data_dir(),
        out: PathBuf::from("target/mras_tables"),
        rbf_sizes: vec![1000, 2000, 4000],
        options: MrasOptions::default(),
    };
    let o = &mut a.options;
    let mut i = 0;
    while i < args.len() {
        let flag = args[i].as_str();
        let value = || -> Res<&String> {
            args.get(i + 1)
                .ok_or_else(|| format!("{flag} needs a value").into())
        };
        let num = || -> Res<f64> { Ok(value()?.parse()?) };
        let mut takes = true;
        match flag {
            "shapes" | "tables" | "figure" | "fit" => {
                a.sections.push(flag.to_owned());
                takes = false;
            }
            "--data" => a.data = PathBuf::from(value()?),
            "--out" => a.out = PathBuf::from(value()?),
            "--rbf-sizes" => {
                a.rbf_sizes = value()?
                    .split(',')
                    .map(|v| v.trim().parse())
                    .collect::<Result<_, _>>()?
            }
            "--tolerance" => o.tolerance = num()?,
            "--max-level" => o.max_level = num()? as u32,
            "--lambda" => o.lambda = num()?,
            "--omega1" => o.omega1 = num()?,
            "--omega2" => o.omega2 = num()?,
            "--omega2-root" => o.omega2_root = num()?,
            "--omega2-decay" => o.omega2_decay = num()?,
            "--m0" => o.m0 = num()? as usize,
            "--beta" => o.beta = num()?,
            "--min-knots" => o.min_knots = num()? as usize,
            "--n-min" => o.n_min = num()? as usize,
            "--admm-iter" => o.admm_max_iter = num()? as usize,
            "--admm-tol" => o.admm_tol = num()?,
            "--eta" => o.eta = num()?,
            "--relaxation" => o.relaxation = num()?,
            "--cp-scale" => o.cp_scale = num()?,
            "--cp-points" => o.cp_points = num()?,
            "--cp-refined" => o.cp_refined = num()?,
            "--plain-cp" => {
                o.cp_weighted = false;
                takes = false;
            }
            "--no-compress" => {
                o.compress = false;
                takes = false;
            }
            other
                if !other.starts_with("--")
                    && a.sections.last().map(String::as_str) == Some("fit") =>
            {
                a.file = Some(PathBuf::from(other));
                takes = false;
            }
            other => return Err(format!("unknown argument {other}").into()),
        }
        i += if takes { 2 } else { 1 };
    }
    if a.sections.is_empty() {
        a.sections = vec!["shapes".into(), "tables".into(), "figure".into()];
    }
    Ok(a)
}

fn run() -> Res<()> {
    let args = parse()?;
    let start = Instant::now();
    println!(
        "zeroset MRAS tables — {} threads (rayon), {}",
        rayon::current_num_threads(),
        std::env::consts::ARCH
    );
    for section in &args.sections {
        match section.as_str() {
            "fit" => {
                let file = args
                    .file
                    .clone()
                    .unwrap_or_else(|| args.data.join("bunny_points.ply"));
                fit_and_report(&file, &args.options)?;
            }
            "shapes" => shapes(&args)?,
            "tables" => tables(&args)?,
            "figure" => figure(&args)?,
            _ => unreachable!(),
        }
    }
    println!("\ntotal {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// Fig. 5: single-level fits of a sphere and a torus.
fn shapes(args: &Args) -> Res<()> {
    println!(
        "\n## Fig. 5: single-level fits (paper: sphere rank 4 at 9.68e-4, torus rank 10 at 8.32e-4)"
    );
    println!(
        "{:<8} {:<26} {:>4} {:>5} {:>10} {:>10} {:>8} {:>7}",
        "shape", "settings", "m", "rank", "max/diag", "mean/diag", "storage", "time s"
    );
    let single = args.options.clone().max_level(1);
    // The defaults, then the paper's kind of setting (a weak thin-plate term, a strong trace
    // norm) over λ and the root's knots: the paper gives neither for Fig. 5.
    let mut variants = vec![("defaults".to_owned(), single.clone())];
    for m0 in [12, 16] {
        for lambda in [3.0, 10.0, 20.0] {
            variants.push((
                format!("λ = {lambda}, ω₂ = 1e-8"),
                single.clone().lambda(lambda).omega2_root(1e-8).m0(m0),
            ));
        }
    }
    for (name, (p, n), paper) in [
        ("sphere", sphere(3000, 1.0), (4, 9.68e-4)),
        ("torus", torus(120, 48, 1.0, 0.4), (10, 8.32e-4)),
    ] {
        for (label, o) in &variants {
            let t = Instant::now();
            let fit = fit_mras(&p, &n, o, &|_| true)?;
            let secs = t.elapsed().as_secs_f64();
            let (max, mean, _) = distances(&fit, &p);
            let level = &fit.field.levels()[0];
            let rank = level.cells()[0].spline.rank();
            // Meets the paper's point: its rank or lower at its error or lower.
            let meets = rank.is_some_and(|r| r <= paper.0) && max / fit.diagonal <= paper.1;
            println!(
                "{name:<8} {label:<26} {:>4} {:>5} {:>10.3e} {:>10.3e} {:>8} {secs:>7.2}{}",
                level.knots(),
                rank.map_or("full".to_owned(), |r| r.to_string()),
                max / fit.diagonal,
                mean / fit.diagonal,
                fit.field.storage(),
                if meets {
                    "  ← the paper's rank and error"
                } else {
                    ""
                }
            );
        }
    }
    Ok(())
}

/// Tables 1–2 on the two scans.
fn tables(args: &Args) -> Res<()> {
    std::fs::create_dir_all(&args.out)?;
    for (model, file) in [("bunny", "bunny_points.ply"), ("kitten", "kitten.xyz")] {
        let path = args.data.join(file);
        println!("\n## {model}: {}", path.display());
        let fit = fit_and_report(&path, &args.options)?;
        let cloud = read_point_cloud(&path)?;
        let (max, mean, _) = distances(&fit, cloud.positions());
        // The same fit with one option changed: max and mean distance, storage, fit seconds.
        let variant = |o: MrasOptions| -> Res<(f64, f64, usize, f64)> {
            let t = Instant::now();
            let u = fit_mras(
                cloud.positions(),
                cloud.normals().ok_or("no normals")?,
                &o,
                &|_| true,
            )?;
            let secs = t.elapsed().as_secs_f64();
            let (a, b, _) = distances(&u, cloud.positions());
            Ok((a, b, u.field.storage(), secs))
        };
        let (umax, umean, ustore, usecs) = variant(args.options.clone().compress(false))?;
        // (a') only where the fit above used the weighted CP fit: compressed, at the points.
        let o = &args.options;
        let weighted = o.compress && o.cp_weighted && o.cp_scale == 0.0;
        let plain = match weighted {
            true => Some(variant(o.clone().cp_weighted(false))?),
            false => None,
        };
        // Mesh at 256 cells along the longest side, for the peer script's distance.
        let bounds = points_box(cloud.positions(), fit.diagonal)?;
        let t = Instant::now();
        let grid = grid_for(&bounds, 256)?;
        let mesh = mesh_field(&fit.field, &grid, 0.0, &McOptions::default())?;
        let mesh_secs = t.elapsed().as_secs_f64();
        let report = check(&mesh);
        let ply = args.out.join(format!("{model}_mras.ply"));
        write_ply(&ply, &mesh, zeroset_mesh::PlyFormat::BinaryLittleEndian)?;
        println!(
            "mesh: grid {}×{}×{} in {mesh_secs:.2} s, {} vertices, {} triangles, {} component(s), Euler {} → {}",
            grid.counts()[0],
            grid.counts()[1],
            grid.counts()[2],
            mesh.vertices().len(),
            mesh.triangles().len(),
            report.components,
            report.euler_characteristic,
            ply.display()
        );
        let rbf = rbf_storage::rbf_rows(
            cloud.positions(),
            cloud.normals().ok_or("no normals")?,
            fit.diagonal,
            &args.rbf_sizes,
            7,
        )?;
        println!(
            "\nTable 1/2 row ({model}; relative = / bounding-box diagonal {:.4}):",
            fit.diagonal
        );
        println!(
            "{:<34} {:>9} {:>10} {:>10} {:>9} {:>8}",
            "method", "points", "max", "mean", "storage", "time s"
        );
        println!(
            "{:<34} {:>9} {:>10.3e} {:>10.3e} {:>9} {:>8.2}",
            format!("MRAS (depth {})", fit.levels.len()),
            cloud.len(),
            max / fit.diagonal,
            mean / fit.diagonal,
            fit.field.storage(),
            fit.seconds
        );
        println!(
            "{:<34} {:>9} {:>10.3e} {:>10.3e} {:>9} {:>8.2}",
            "(a) MRAS uncompressed",
            cloud.len(),
            umax / fit.diagonal,
            umean / fit.diagonal,
            ustore,
            usecs
        );
        if let Some(plain) = plain {
            println!(
                "{:<34} {:>9} {:>10.3e} {:>10.3e} {:>9} {:>8.2}",
                "(a') MRAS, plain CP-ALS",
                cloud.len(),
                plain.0 / fit.diagonal,
                plain.1 / fit.diagonal,
                plain.2,
                plain.3
            );
        }
        for r in &rbf {
            println!(
                "{:<34} {:>9} {:>10.3e} {:>10.3e} {:>9} {:>8.2}",
                format!("(b) RBF {} ({} centres)", r.method, r.centres),
                r.centres,
                r.max_rel,
                r.mean_rel,
                r.stored,
                r.fit_seconds
            );
        }
        println!(
            "storage: MRAS {:.1}× smaller than uncompressed; {}",
            ustore as f64 / fit.field.storage() as f64,
            match rbf
                .iter()
                .find(|r| r.max_rel <= max / fit.diagonal && r.mean_rel <= mean / fit.diagonal)
            {
                Some(r) => format!(
                    "{:.2}× smaller than the first RBF row at equal or better error ({} numbers)",
                    r.stored as f64 / fit.field.storage() as f64,
                    r.stored
                ),
                None => "no RBF row reached MRAS's max and mean error".to_owned(),
            }
        );
    }
    Ok(())
}

/// Fig. 2: the bunny after each level.
fn figure(args: &Args) -> Res<()> {
    std::fs::create_dir_all(&args.out)?;
    let path = args.data.join("bunny_points.ply");
    let cloud = read_point_cloud(&path)?;
    let fit = fit_mras(
        cloud.positions(),
        cloud.normals().ok_or("no normals")?,
        &args.options,
        &|_| true,
    )?;
    let bounds = points_box(cloud.positions(), fit.diagonal)?;
    let grid = grid_for(&bounds, 160)?;
    let size = 320;
    let levels = fit.field.levels().len();
    let mut sheet = Image::filled(size * levels, size, [255, 255, 255])?;
    let opts = RenderOptions {
        width: size,
        height: size,
        up: Axis::Y,
        ..RenderOptions::default()
    };
    for k in 1..=levels {
        let field = fit.field.truncated(k);
        let mesh = mesh_field(&field, &grid, 0.0, &McOptions::default())?;
        let image = render_mesh(&mesh, &opts)?;
        sheet.blit(&image, (k - 1) * size, 0);
        println!(
            "level {k}: {} triangles, storage {}",
            mesh.triangles().len(),
            field.storage()
        );
    }
    let png = args.out.join("mras_bunny_levels.png");
    sheet.write_png(&png)?;
    println!("wrote {}", png.display());
    Ok(())
}

/// The points' bounding box grown by 3% of its diagonal on every side.
fn points_box(points: &[[f64; 3]], diagonal: f64) -> Res<Aabb<3>> {
    Ok(Aabb::from_points(points)
        .ok_or("no points")?
        .expanded(0.03 * diagonal))
}

/// A cell-centred grid over `bounds` with `cells` along the longest side.
fn grid_for(bounds: &Aabb<3>, cells: usize) -> Res<Grid<3>> {
    let e = bounds.extent();
    let longest = e.iter().cloned().fold(0.0, f64::max);
    let counts = e.map(|v| ((v / longest * cells as f64).round() as usize).max(2));
    Ok(Grid::cell_centered(*bounds, counts)?)
}

fn fit_and_report(path: &Path, opts: &MrasOptions) -> Res<MrasFit> {
    let cloud = read_point_cloud(path)?;
    let normals = cloud.normals().ok_or("no normals")?.to_vec();
    let t = Instant::now();
    let fit = fit_mras(cloud.positions(), &normals, opts, &|_| true)?;
    let secs = t.elapsed().as_secs_f64();
    println!(
        "{}: {} points, fit {:.2} s, storage {} (the fitted cells uncompressed {})",
        path.display(),
        cloud.len(),
        secs,
        fit.field.storage(),
        fit.levels.iter().map(|l| l.uncompressed).sum::<usize>()
    );
    println!(
        "level knots cells zero full rank(min/mean/max) stored uncompr pts admm max_err mean_err split secs"
    );
    for l in &fit.levels {
        println!(
            "{:5} {:5} {:5} {:4} {:4} {:3}/{:5.1}/{:3} {:8} {:8} {:6.0} {:5.0} {:.3e} {:.3e} {:5} {:.2}",
            l.level,
            l.knots,
            l.cells,
            l.dropped,
            l.full_cells,
            l.ranks.0,
            l.ranks.1,
            l.ranks.2,
            l.stored,
            l.uncompressed,
            l.mean_points,
            l.mean_admm_iterations,
            l.max_error,
            l.mean_error,
            l.split,
            l.seconds
        );
    }
    let each = point_distances(&fit, cloud.positions());
    let (max, mean, failed) = summary(&each);
    println!(
        "distance to the zero set / diagonal: max {:.3e} mean {:.3e} ({} not projected)",
        max / fit.diagonal,
        mean / fit.diagonal,
        failed
    );
    // Where the worst points are: the quantiles, and the five farthest with their normals
    // (a point that did not project counts as infinitely far).
    let mut d: Vec<(f64, usize)> = each
        .iter()
        .enumerate()
        .map(|(i, d)| (d.unwrap_or(f64::INFINITY) / fit.diagonal, i))
        .collect();
    d.sort_by(|a, b| b.0.total_cmp(&a.0));
    let quantile = |q: f64| d[((1.0 - q) * d.len() as f64) as usize].0;
    println!(
        "  quantiles: 50% {:.3e}, 90% {:.3e}, 99% {:.3e}, 99.9% {:.3e}; {} points above 1.5e-3",
        quantile(0.5),
        quantile(0.9),
        quantile(0.99),
        quantile(0.999),
        d.iter().filter(|x| x.0 > 1.5e-3).count()
    );
    for (e, i) in d.iter().take(5) {
        let (p, n) = (cloud.positions()[*i], normals[*i]);
        println!("  {e:.3e} at point {i} {p:.4?}, normal {n:.2?}");
    }
    Ok(fit)
}

/// Max and mean distance from the points to the zero set (projection), and failures.
fn distances(fit: &MrasFit, points: &[[f64; 3]]) -> (f64, f64, usize) {
    summary(&point_distances(fit, points))
}

/// Each point's distance to the zero set (projection along the gradient; `None`: it did not
/// project).
fn point_distances(fit: &MrasFit, points: &[[f64; 3]]) -> Vec<Option<f64>> {
    let tol = 1e-9 * fit.diagonal;
    points
        .par_iter()
        .map(|p| distance_to_zero_set(&fit.field, p, tol, 50))
        .collect()
}

/// Max and mean of the distances that projected, and the count that did not.
fn summary(d: &[Option<f64>]) -> (f64, f64, usize) {
    let ok: Vec<f64> = d.iter().flatten().copied().collect();
    let max = ok.iter().fold(0.0f64, |a, &b| a.max(b));
    let mean = ok.iter().sum::<f64>() / ok.len().max(1) as f64;
    (max, mean, d.len() - ok.len())
}
