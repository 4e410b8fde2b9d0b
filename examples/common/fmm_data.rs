//! RBF fields of about `N` centres from real scans, for the fast multipole examples: `N/3`
//! points of a cloud (evenly strided in file order), each with value 0 and `±ε` along its
//! normal (`Offset::Auto`, 1% of the diagonal), fitted with `Solver::Auto`. The fit is cached
//! as a `.zsf` file under `target/fmm_fields/` (fitting 10,000 centres takes seconds to tens of
//! seconds; the cache makes repeated runs cheap). Delete the folder to refit.

#![allow(dead_code)] // each example uses what it needs

use std::path::Path;

use zeroset::bases::field_file::{AnyField, RbfAny, read_any_field, write_rbf_field};
use zeroset::bases::rbf::{Biharmonic, Constraints, Offset, RbfField, RbfFit, Solver, Triharmonic};
use zeroset::core::PointCloud;
use zeroset::core::io::read_point_cloud;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// A field of `kernel` (`"r"` or `"r3"`) with about `sources` centres from `cloud_file`.
pub enum Field {
    R(RbfField<Biharmonic, 3>),
    R3(RbfField<Triharmonic, 3>),
}

pub fn load(data: &Path, cloud_file: &str, kernel: &str, sources: usize) -> Res<Field> {
    let cache = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fmm_fields");
    std::fs::create_dir_all(&cache)?;
    let stem = cloud_file.split('.').next().unwrap_or(cloud_file);
    let path = cache.join(format!("{stem}_{kernel}_{sources}.zsf"));
    if path.is_file()
        && let Ok(AnyField::Rbf(any)) = read_any_field::<3>(&path)
    {
        match (any, kernel) {
            (RbfAny::R(f), "r") => return Ok(Field::R(f)),
            (RbfAny::R3(f), "r3") => return Ok(Field::R3(f)),
            _ => {}
        }
    }
    let sub = picked_cloud(data, cloud_file, sources)?;
    let (c, _) = Constraints::off_surface(&sub, Offset::Auto { fraction: 0.01 })?;
    let field = match kernel {
        "r" => Field::R(fit(Biharmonic, &c)?),
        "r3" => Field::R3(fit(Triharmonic, &c)?),
        other => return Err(format!("unknown kernel {other} (r or r3)").into()),
    };
    match &field {
        Field::R(f) => write_rbf_field(&path, f)?,
        Field::R3(f) => write_rbf_field(&path, f)?,
    }
    Ok(field)
}

/// The `⌈sources / 3⌉` points of `cloud_file` the field of [`load`] is fitted to (evenly
/// strided in file order), with their normals: its on-surface centres, where it is 0.
pub fn picked_cloud(data: &Path, cloud_file: &str, sources: usize) -> Res<PointCloud<3>> {
    let cloud = read_point_cloud(data.join(cloud_file))?;
    let (positions, normals) = cloud.into_parts();
    let normals = normals.ok_or(format!("{cloud_file} has no normals"))?;
    let want = sources.div_ceil(3).min(positions.len());
    let picked: Vec<usize> = (0..want).map(|i| i * positions.len() / want).collect();
    Ok(PointCloud::with_normals(
        picked.iter().map(|&i| positions[i]).collect(),
        picked.iter().map(|&i| normals[i]).collect(),
    )?)
}

/// `count` points within one voxel of the zero set: on-surface points (cycled in order) moved
/// by a uniform (seeded) offset in `[−h, h]³`.
pub fn near_surface_targets(
    surface: &[[f64; 3]],
    h: f64,
    count: usize,
    seed: u64,
) -> Vec<[f64; 3]> {
    let mut next = uniform(seed);
    (0..count)
        .map(|i| {
            let p = surface[i % surface.len()];
            std::array::from_fn(|a| p[a] + h * (2.0 * next() - 1.0))
        })
        .collect()
}

/// The FMM's error as a distance near the zero set: per point `|s_fmm − s| / ‖∇s‖` (the
/// distance the zero set moves to first order), `(max, rms)` over the points.
pub fn distance_errors<F: zeroset::core::ScalarField<3> + ?Sized>(
    fast: &[f64],
    exact: &[f64],
    field: &F,
    points: &[[f64; 3]],
) -> (f64, f64) {
    let (mut max, mut sum) = (0.0f64, 0.0);
    for ((x, y), p) in fast.iter().zip(exact).zip(points) {
        let g = field.gradient(p);
        let d = (x - y).abs() / (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        max = max.max(d);
        sum += d * d;
    }
    (max, (sum / points.len().max(1) as f64).sqrt())
}

fn fit<K: zeroset::bases::rbf::Kernel + Clone>(
    kernel: K,
    c: &Constraints<3>,
) -> Res<RbfField<K, 3>> {
    eprintln!(
        "fitting {} constraints ({}), cached afterwards",
        c.len(),
        kernel.name()
    );
    Ok(RbfFit::new(kernel).with_solver(Solver::Auto).fit(c)?.field)
}

/// A seeded stream of numbers uniform in `[0, 1)` (a 64-bit LCG's high bits).
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `count` points drawn uniformly (seeded) in `field`'s bounds.
pub fn uniform_targets(bounds: &zeroset::core::Aabb<3>, count: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut next = uniform(seed);
    let (lo, hi) = (bounds.min(), bounds.max());
    (0..count)
        .map(|_| std::array::from_fn(|a| lo[a] + next() * (hi[a] - lo[a])))
        .collect()
}

/// `(max |a − b|, max |a − b| / max |b|, rms(a − b) / rms(b))`: the FMM's error against the
/// exact values `b`.
pub fn errors(a: &[f64], b: &[f64]) -> (f64, f64, f64) {
    let (mut max, mut sum, mut scale, mut norm) = (0.0f64, 0.0, 0.0f64, 0.0);
    for (x, y) in a.iter().zip(b) {
        max = max.max((x - y).abs());
        sum += (x - y) * (x - y);
        scale = scale.max(y.abs());
        norm += y * y;
    }
    (max, max / scale, (sum / norm).sqrt())
}
