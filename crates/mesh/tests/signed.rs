//! Two-step signed marching cubes against plain marching cubes on the fine field (identical
//! meshes when the margin bounds the coarse error), and the voxel-growing baseline (identical
//! on the components it has seeds on, blind to the others).

use std::collections::{BTreeSet, HashMap};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use zeroset_field_core::{Aabb, Grid, Point3, ScalarField};
use zeroset_mesh::cubes::{McOptions, marching_cubes, mesh_field};
use zeroset_mesh::signed::{
    BATCH, CoarseStep, SmcOptions, SmcReport, SmcStage, expected_evaluations, settled_fraction,
    signed_marching_cubes, voxel_growing,
};
use zeroset_mesh::{MeshError, TriMesh};

/// An analytic field `f`, optionally perturbed by `δ·sin(37x + 11y + 5z)`, counting its batched
/// calls, the points they held, and its single-point calls; with `lipschitz`, it encloses
/// itself over boxes by `value(centre) ± L · half-diagonal` (without counting an evaluation).
struct Field {
    f: fn(&Point3) -> f64,
    delta: f64,
    batches: AtomicUsize,
    points: AtomicUsize,
    singles: AtomicUsize,
    lipschitz: Option<f64>,
    enclosures: AtomicUsize,
}

impl Field {
    fn new(f: fn(&Point3) -> f64, delta: f64) -> Self {
        Self {
            f,
            delta,
            batches: AtomicUsize::new(0),
            points: AtomicUsize::new(0),
            singles: AtomicUsize::new(0),
            lipschitz: None,
            enclosures: AtomicUsize::new(0),
        }
    }

    /// The field with enclosures: `f` is 1-Lipschitz (a signed distance), the perturbation
    /// `δ √(37² + 11² + 5²)`-Lipschitz.
    fn enclosing(f: fn(&Point3) -> f64, delta: f64) -> Self {
        let lipschitz = 1.0 + delta * (37.0f64 * 37.0 + 11.0 * 11.0 + 5.0 * 5.0).sqrt();
        Self {
            lipschitz: Some(lipschitz),
            ..Self::new(f, delta)
        }
    }

    fn eval(&self, p: &Point3) -> f64 {
        (self.f)(p) + self.delta * (37.0 * p[0] + 11.0 * p[1] + 5.0 * p[2]).sin()
    }
}

impl ScalarField<3> for Field {
    fn value(&self, p: &Point3) -> f64 {
        self.singles.fetch_add(1, Ordering::Relaxed);
        self.eval(p)
    }

    fn values(&self, points: &[Point3], out: &mut [f64]) {
        self.batches.fetch_add(1, Ordering::Relaxed);
        self.points.fetch_add(points.len(), Ordering::Relaxed);
        for (p, o) in points.iter().zip(out) {
            *o = self.eval(p);
        }
    }

    fn bounds(&self) -> Option<Aabb<3>> {
        None
    }

    fn value_range(&self, region: &Aabb<3>) -> Option<[f64; 2]> {
        let lipschitz = self.lipschitz?;
        self.enclosures.fetch_add(1, Ordering::Relaxed);
        let e = region.extent();
        let half_diagonal = 0.5 * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
        let v = self.eval(&region.center());
        let spread = lipschitz * half_diagonal * (1.0 + 1e-12) + 1e-14;
        Some([v - spread, v + spread])
    }
}

fn sphere(p: &Point3) -> f64 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.6
}

/// Leaves the box [−1, 1]³: the caps of `close_boundary` appear.
fn big_sphere(p: &Point3) -> f64 {
    let q = [p[0] - 0.3, p[1] + 0.2, p[2] - 0.1];
    (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt() - 1.1
}

fn torus(p: &Point3) -> f64 {
    let r = (p[0] * p[0] + p[1] * p[1]).sqrt() - 0.55;
    (r * r + p[2] * p[2]).sqrt() - 0.22
}

fn sphere_a(p: &Point3) -> f64 {
    ((p[0] + 0.5).powi(2) + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.3
}

fn sphere_b(p: &Point3) -> f64 {
    ((p[0] - 0.5).powi(2) + (p[1] - 0.1).powi(2) + p[2] * p[2]).sqrt() - 0.25
}

fn two_spheres(p: &Point3) -> f64 {
    sphere_a(p).min(sphere_b(p))
}

fn cube_grid(n: usize) -> Grid<3> {
    Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [n, n, n]).unwrap()
}

/// Bitwise equality of vertices, normals and triangles.
fn assert_identical(a: &TriMesh, b: &TriMesh, what: &str) {
    assert_eq!(a.num_vertices(), b.num_vertices(), "{what}: vertex count");
    assert_eq!(a.triangles(), b.triangles(), "{what}: triangles");
    let bits = |m: &TriMesh| -> Vec<[u64; 3]> {
        m.vertices().iter().map(|v| v.map(f64::to_bits)).collect()
    };
    assert_eq!(bits(a), bits(b), "{what}: vertex coordinates");
    let nbits = |m: &TriMesh| -> Vec<[u64; 3]> {
        m.normals().iter().map(|v| v.map(f64::to_bits)).collect()
    };
    assert_eq!(nbits(a), nbits(b), "{what}: normals");
}

/// The triangles as coordinate triples (bit patterns), rotated so the smallest corner comes
/// first (orientation kept): independent of vertex numbering.
fn triangle_set(m: &TriMesh) -> BTreeSet<[[u64; 3]; 3]> {
    (0..m.num_triangles())
        .map(|t| {
            let c = m.corners(t).map(|v| v.map(f64::to_bits));
            let r = (0..3).min_by_key(|&k| c[k]).unwrap_or(0);
            [c[r], c[(r + 1) % 3], c[(r + 2) % 3]]
        })
        .collect()
}

/// Connected components of the triangles through shared vertices.
fn components(m: &TriMesh) -> usize {
    let mut parent: Vec<usize> = (0..m.num_vertices()).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for t in m.triangles() {
        for k in 1..3 {
            let (a, b) = (
                find(&mut parent, t[0] as usize),
                find(&mut parent, t[k] as usize),
            );
            parent[a] = b;
        }
    }
    let mut roots = HashMap::new();
    for t in m.triangles() {
        let r = find(&mut parent, t[0] as usize);
        roots.insert(r, ());
    }
    roots.len()
}

/// SMC with a coarse field `f + δ sin(…)`, margin `2δ`, against `mesh_field` and
/// `marching_cubes` on the exact field; returns the report.
fn check_smc(f: fn(&Point3) -> f64, grid: &Grid<3>, options: McOptions, what: &str) -> SmcReport {
    let delta = 0.01;
    let coarse = Field::new(f, delta);
    let fine = Field::new(f, 0.0);
    let (mesh, report) = signed_marching_cubes(
        &coarse,
        &fine,
        grid,
        0.0,
        2.0 * delta,
        &SmcOptions::from(options),
        None,
    )
    .unwrap();
    let exact = Field::new(f, 0.0);
    let reference = mesh_field(&exact, grid, 0.0, &options).unwrap();
    assert!(
        mesh.num_triangles() > 100,
        "{what}: {} triangles",
        mesh.num_triangles()
    );
    assert_identical(&mesh, &reference, what);
    let plain = marching_cubes(
        grid,
        &grid.sample(&exact),
        0.0,
        &options.with_normals(false),
    )
    .unwrap();
    let bare = signed_marching_cubes(
        &coarse,
        &fine,
        grid,
        0.0,
        2.0 * delta,
        &SmcOptions::from(options.with_normals(false)),
        None,
    )
    .unwrap()
    .0;
    assert_identical(&bare, &plain, what);
    // Counts: one coarse evaluation per vertex, in large batches, never one point at a time;
    // fine evaluations are distinct vertices.
    let n = grid.len() as u64;
    assert_eq!(report.n_mc, n);
    assert_eq!(report.n_smc_low, n);
    assert_eq!(coarse.points.load(Ordering::Relaxed) as u64, 2 * n);
    assert_eq!(
        coarse.batches.load(Ordering::Relaxed),
        2 * grid.len().div_ceil(BATCH)
    );
    assert_eq!(
        fine.points.load(Ordering::Relaxed) as u64,
        2 * report.n_smc_high
    );
    assert_eq!(coarse.singles.load(Ordering::Relaxed), 0);
    assert_eq!(report.gamma, report.n_smc_high as f64 / n as f64);
    assert!(report.surface_cells <= report.candidate_cells);
    assert!(report.uncertain_vertices <= report.n_smc_high);
    println!(
        "{what}: N_MC = {}, N_SMC,P = {}, γ = {:.2}%, uncertain {}, candidates {}, surface \
         cells {}, {} triangles",
        report.n_mc,
        report.n_smc_high,
        100.0 * report.gamma,
        report.uncertain_vertices,
        report.candidate_cells,
        report.surface_cells,
        mesh.num_triangles()
    );
    report
}

#[test]
fn smc_equals_plain_marching_cubes_on_sphere_and_torus() {
    let grid = cube_grid(64);
    for close in [false, true] {
        let options = McOptions::default().with_close_boundary(close);
        for (f, name) in [
            (sphere as fn(&Point3) -> f64, "sphere"),
            (torus, "torus"),
            (big_sphere, "sphere leaving the grid"),
        ] {
            let report = check_smc(f, &grid, options, &format!("{name}, close {close}"));
            assert!(
                report.n_smc_high * 4 < report.n_mc,
                "{name}: γ = {}",
                report.gamma
            );
        }
    }
}

#[test]
fn smc_equals_plain_marching_cubes_on_odd_cell_centred_grids() {
    let grid = Grid::cell_centered(
        Aabb::new([-1.0, -0.9, -1.1], [1.0, 0.8, 1.0]).unwrap(),
        [37, 70, 45],
    )
    .unwrap();
    for close in [false, true] {
        let options = McOptions::default().with_close_boundary(close);
        check_smc(
            torus,
            &grid,
            options,
            &format!("cell-centred torus, close {close}"),
        );
        check_smc(
            big_sphere,
            &grid,
            options,
            &format!("cell-centred big sphere, close {close}"),
        );
    }
}

#[test]
fn gamma_falls_as_the_grid_refines() {
    let mut last = f64::INFINITY;
    for n in [32, 64, 128] {
        let r = check_smc(
            sphere,
            &cube_grid(n),
            McOptions::default(),
            &format!("sphere {n}³"),
        );
        assert!(r.gamma < last);
        last = r.gamma;
    }
}

#[test]
fn exact_coarse_field_with_zero_margin_is_plain_marching_cubes() {
    let grid = cube_grid(40);
    let f = Field::new(torus, 0.0);
    let (mesh, report) = signed_marching_cubes(
        &f,
        &f,
        &grid,
        0.0,
        0.0,
        &SmcOptions::from(McOptions::default()),
        None,
    )
    .unwrap();
    assert_identical(
        &mesh,
        &mesh_field(&f, &grid, 0.0, &McOptions::default()).unwrap(),
        "margin 0",
    );
    // Only the vertices of surface cells (plus exact zeros) are refined.
    assert_eq!(report.candidate_cells, report.surface_cells);
}

#[test]
fn too_small_margin_may_differ_but_does_not_panic() {
    // The perturbation (0.05) flips signs near the surface; margin 0 trusts them anyway.
    let grid = cube_grid(48);
    let coarse = Field::new(sphere, 0.05);
    let fine = Field::new(sphere, 0.0);
    for close in [false, true] {
        let options = McOptions::default().with_close_boundary(close);
        let (mesh, report) = signed_marching_cubes(
            &coarse,
            &fine,
            &grid,
            0.0,
            0.0,
            &SmcOptions::from(options),
            None,
        )
        .unwrap();
        let reference = mesh_field(&fine, &grid, 0.0, &options).unwrap();
        println!(
            "margin 0 with δ = 0.05, close {close}: {} triangles (plain MC {}), γ = {:.2}%, \
             identical: {}",
            mesh.num_triangles(),
            reference.num_triangles(),
            100.0 * report.gamma,
            triangle_set(&mesh) == triangle_set(&reference)
        );
    }
}

#[test]
fn progress_reports_the_stages_in_order() {
    let grid = cube_grid(20);
    let coarse = Field::new(sphere, 0.01);
    let fine = Field::new(sphere, 0.0);
    let stages = Mutex::new(Vec::new());
    let progress = |s: SmcStage| stages.lock().unwrap().push(s);
    let (_, report) = signed_marching_cubes(
        &coarse,
        &fine,
        &grid,
        0.0,
        0.02,
        &SmcOptions::from(McOptions::default()),
        Some(&progress),
    )
    .unwrap();
    assert_eq!(
        stages.into_inner().unwrap(),
        vec![
            SmcStage::Coarse {
                vertices: grid.len() as u64
            },
            SmcStage::Fine {
                vertices: report.n_smc_high
            },
            SmcStage::Extract
        ]
    );
}

#[test]
fn voxel_growing_misses_unseeded_components_and_smc_does_not() {
    let grid = cube_grid(64);
    let options = McOptions::default();
    let field = Field::new(two_spheres, 0.0);
    let full = mesh_field(&field, &grid, 0.0, &options).unwrap();
    assert_eq!(components(&full), 2);

    // SMC finds both.
    let coarse = Field::new(two_spheres, 0.01);
    let (smc, _) = signed_marching_cubes(
        &coarse,
        &field,
        &grid,
        0.0,
        0.02,
        &SmcOptions::from(options),
        None,
    )
    .unwrap();
    assert_identical(&smc, &full, "two spheres, SMC");

    // VG from a point of sphere A: sphere A only.
    let on_a = [[-0.5 + 0.3, 0.0, 0.0]];
    let (vg_a, report) = voxel_growing(&field, &grid, 0.0, &on_a, &options).unwrap();
    assert_eq!(components(&vg_a), 1);
    let only_a = mesh_field(&Field::new(sphere_a, 0.0), &grid, 0.0, &options).unwrap();
    assert_eq!(triangle_set(&vg_a), triangle_set(&only_a));
    assert_eq!(report.seed_cells, 1);
    assert_eq!(report.skipped_seeds, 0);
    assert!(report.evaluations * 10 < grid.len() as u64);
    // Batched calls only, each vertex once (the gradients of the normals use single values).
    let counted = Field::new(two_spheres, 0.0);
    let (bare, bare_report) =
        voxel_growing(&counted, &grid, 0.0, &on_a, &options.with_normals(false)).unwrap();
    assert_eq!(bare.triangles(), vg_a.triangles());
    assert_eq!(counted.singles.load(Ordering::Relaxed), 0);
    assert_eq!(
        counted.points.load(Ordering::Relaxed) as u64,
        bare_report.evaluations
    );
    println!(
        "VG from one seed on A: {} evaluations of {} ({:.2}%), {} surface cells, {} triangles \
         of {}",
        report.evaluations,
        grid.len(),
        100.0 * report.evaluations as f64 / grid.len() as f64,
        report.surface_cells,
        vg_a.num_triangles(),
        full.num_triangles()
    );

    // VG from both: plain marching cubes, vertex order included.
    let both = [[-0.5, 0.0, 0.3], [0.5, 0.1, -0.25], [0.5, 0.1, -0.25]];
    let (vg, report) = voxel_growing(&field, &grid, 0.0, &both, &options).unwrap();
    assert_eq!(triangle_set(&vg), triangle_set(&full));
    assert_identical(&vg, &full, "two spheres, VG from both");
    assert_eq!(report.seed_cells, 2);
}

#[test]
fn voxel_growing_follows_caps_with_close_boundary() {
    let grid = cube_grid(48);
    for close in [false, true] {
        let options = McOptions::default().with_close_boundary(close);
        let field = Field::new(big_sphere, 0.0);
        let full = mesh_field(&field, &grid, 0.0, &options).unwrap();
        // A point on the sphere inside the box.
        let seed = [[0.3 - 1.1, -0.2, 0.1]];
        let (vg, report) = voxel_growing(&field, &grid, 0.0, &seed, &options).unwrap();
        assert_identical(&vg, &full, &format!("big sphere VG, close {close}"));
        assert!(report.evaluations < grid.len() as u64);
        // The torus: one seed finds the whole (connected) surface.
        let torus_field = Field::new(torus, 0.0);
        let (vg, _) =
            voxel_growing(&torus_field, &grid, 0.0, &[[0.77, 0.0, 0.0]], &options).unwrap();
        assert_identical(
            &vg,
            &mesh_field(&torus_field, &grid, 0.0, &options).unwrap(),
            &format!("torus VG, close {close}"),
        );
    }
}

#[test]
fn voxel_growing_seed_far_from_the_surface_finds_nothing() {
    // A seed cell that is not a surface cell does not grow.
    let grid = cube_grid(32);
    let field = Field::new(sphere, 0.0);
    let (mesh, report) = voxel_growing(
        &field,
        &grid,
        0.0,
        &[[0.0, 0.0, 0.0]],
        &McOptions::default(),
    )
    .unwrap();
    assert!(mesh.is_empty());
    assert_eq!(report.evaluations, 8);
    assert_eq!(report.surface_cells, 0);
}

#[test]
fn bad_input_is_an_error_or_skipped_never_a_panic() {
    let grid = cube_grid(16);
    let options = McOptions::default();
    let f = Field::new(sphere, 0.0);
    for margin in [f64::NAN, -0.1, f64::INFINITY, f64::NEG_INFINITY] {
        let r = signed_marching_cubes(&f, &f, &grid, 0.0, margin, &SmcOptions::from(options), None);
        assert!(
            matches!(r, Err(MeshError::InvalidMargin { .. })),
            "margin {margin}: {r:?}"
        );
    }
    assert_eq!(
        f.points.load(Ordering::Relaxed),
        0,
        "checked before evaluating"
    );
    assert!(matches!(
        signed_marching_cubes(
            &f,
            &f,
            &grid,
            f64::NAN,
            0.1,
            &SmcOptions::from(options),
            None
        ),
        Err(MeshError::NonFiniteLevel { .. })
    ));
    assert!(matches!(
        voxel_growing(&f, &grid, f64::INFINITY, &[[0.6, 0.0, 0.0]], &options),
        Err(MeshError::NonFiniteLevel { .. })
    ));

    // Seeds: NaN, infinite and outside points are skipped and counted; none is an empty mesh.
    let seeds = [
        [f64::NAN, 0.0, 0.0],
        [0.0, f64::INFINITY, 0.0],
        [3.0, 0.0, 0.0],
        [-1.0 - 1e-9, 0.0, 0.0],
    ];
    let (mesh, report) = voxel_growing(&f, &grid, 0.0, &seeds, &options).unwrap();
    assert!(mesh.is_empty());
    assert_eq!(report.skipped_seeds, 4);
    assert_eq!(report.evaluations, 0);
    let (mesh, report) = voxel_growing(&f, &grid, 0.0, &[], &options).unwrap();
    assert!(mesh.is_empty());
    assert_eq!(report.seed_cells, 0);
    // Seeds on the corners of the box are inside its cells.
    let (_, report) =
        voxel_growing(&f, &grid, 0.0, &[[1.0, 1.0, 1.0], [-1.0; 3]], &options).unwrap();
    assert_eq!(report.seed_cells, 2);

    // NaN from the field: an error naming the sample, not a panic.
    fn nan_near_surface(p: &Point3) -> f64 {
        let d = sphere(p);
        if p[0] > 0.3 && d.abs() < 0.1 {
            f64::NAN
        } else {
            d
        }
    }
    fn nan_far(p: &Point3) -> f64 {
        if p[0] < -0.9 { f64::NAN } else { sphere(p) }
    }
    let bad = Field::new(nan_near_surface, 0.0);
    let far = Field::new(nan_far, 0.0);
    let good = Field::new(sphere, 0.0);
    fn nan_sample<T>(r: Result<T, MeshError>) -> bool {
        matches!(r, Err(MeshError::NonFiniteSample { value, .. }) if value.is_nan())
    }
    // In the fine field where it is evaluated, in the coarse field anywhere.
    assert!(nan_sample(signed_marching_cubes(
        &good,
        &bad,
        &grid,
        0.0,
        0.01,
        &SmcOptions::from(options),
        None
    )));
    assert!(nan_sample(signed_marching_cubes(
        &far,
        &good,
        &grid,
        0.0,
        0.01,
        &SmcOptions::from(options),
        None
    )));
    // A NaN of the fine field away from the surface is never evaluated.
    let (mesh, _) = signed_marching_cubes(
        &good,
        &far,
        &grid,
        0.0,
        0.01,
        &SmcOptions::from(options),
        None,
    )
    .unwrap();
    assert!(!mesh.is_empty());
    assert!(nan_sample(voxel_growing(
        &bad,
        &grid,
        0.0,
        &[[0.6, 0.0, 0.0]],
        &options
    )));
}

/// A field that reads a table of samples at the grid points (nearest sample elsewhere), plus a
/// deterministic per-sample perturbation in `[−noise, noise]`.
struct Table {
    grid: Grid<3>,
    values: Vec<f64>,
    noise: f64,
}

impl ScalarField<3> for Table {
    fn value(&self, p: &Point3) -> f64 {
        let n = self.grid.counts();
        let c = self.grid.continuous_index(p);
        let idx: [usize; 3] =
            std::array::from_fn(|a| (c[a].round().max(0.0) as usize).min(n[a] - 1));
        let l = self.grid.linear_index(idx);
        let hash = (l as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
        let unit = hash as f64 / (1u64 << 53) as f64; // [0, 1)
        self.values[l] + self.noise * (2.0 * unit - 1.0)
    }

    fn bounds(&self) -> Option<Aabb<3>> {
        None
    }
}

mod random {
    use proptest::prelude::*;

    use super::*;

    /// The centre of every cell (cap cells included with `close`), as seeds.
    fn every_cell(grid: &Grid<3>, close: bool) -> Vec<Point3> {
        let n = grid.counts().map(|x| x as isize);
        let (lo, hi) = if close { (-1, 0) } else { (0, -1) };
        let h = grid.spacing();
        let o = grid.point([0, 0, 0]);
        let mut seeds = Vec::new();
        for i in lo..n[0] + hi {
            for j in lo..n[1] + hi {
                for k in lo..n[2] + hi {
                    let c = [i, j, k];
                    seeds.push(std::array::from_fn(|a| o[a] + (c[a] as f64 + 0.5) * h[a]));
                }
            }
        }
        seeds
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        /// Samples in {−1, 0, 1} (many on the level: merged crossings, cancelled sheets,
        /// ambiguous faces) or continuous, coarse = fine ± 0.3, margin 0.5: SMC is plain MC;
        /// VG from every cell is plain MC; VG from one seed gives a subset of its triangles.
        #[test]
        fn smc_and_vg_match_plain_marching_cubes_on_random_samples(
            n in [2usize..9, 2usize..9, 2usize..9],
            raw in proptest::collection::vec(-1.0..1.0f64, 512),
            quantise in any::<bool>(),
            close in any::<bool>(),
            seed in 0usize..512,
        ) {
            let grid = Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), n).unwrap();
            let values: Vec<f64> = raw[..grid.len()]
                .iter()
                .map(|&x| if quantise { (1.5 * x).round() } else { x })
                .collect();
            let fine = Table { grid, values: values.clone(), noise: 0.0 };
            let coarse = Table { grid, values: values.clone(), noise: 0.3 };
            let options = McOptions::default().with_close_boundary(close).with_normals(false);
            let plain = marching_cubes(&grid, &values, 0.0, &options).unwrap();
            let (smc, report) =
                signed_marching_cubes(&coarse, &fine, &grid, 0.0, 0.5, &SmcOptions::from(options), None).unwrap();
            prop_assert_eq!(smc.triangles(), plain.triangles());
            prop_assert_eq!(smc.vertices(), plain.vertices());
            prop_assert!(report.n_smc_high <= report.n_mc);

            let (vg, _) =
                voxel_growing(&fine, &grid, 0.0, &every_cell(&grid, close), &options).unwrap();
            prop_assert_eq!(vg.triangles(), plain.triangles());
            prop_assert_eq!(vg.vertices(), plain.vertices());

            let cells = every_cell(&grid, close);
            let one = [cells[seed % cells.len()]];
            let (vg, _) = voxel_growing(&fine, &grid, 0.0, &one, &options).unwrap();
            let all = triangle_set(&plain);
            prop_assert!(triangle_set(&vg).is_subset(&all));
        }
    }
}

/// Step 1 by blocks settles most vertices through enclosures and yields the statuses, the
/// counts and the mesh (bit for bit) of step 1 at every vertex, which are plain marching
/// cubes on the fine field; closed boundaries and odd grids too.
#[test]
fn block_step_settles_most_vertices_and_gives_the_same_mesh() {
    let delta = 0.004;
    type Shape = fn(&Point3) -> f64;
    let cases: [(Shape, Grid<3>, bool, &str); 4] = [
        (sphere, cube_grid(64), false, "sphere 64"),
        (torus, cube_grid(61), false, "torus 61"),
        (two_spheres, cube_grid(48), false, "two spheres 48"),
        (big_sphere, cube_grid(40), true, "big sphere 40, closed"),
    ];
    for (f, grid, close, what) in cases {
        let options = McOptions::default().with_close_boundary(close);
        let fine = Field::new(f, 0.0);
        let run = |step| {
            let coarse = Field::enclosing(f, delta);
            let o = SmcOptions::from(options).with_coarse_step(step);
            let (mesh, report) =
                signed_marching_cubes(&coarse, &fine, &grid, 0.0, 2.0 * delta, &o, None).unwrap();
            let evaluated = coarse.points.load(Ordering::Relaxed) as u64;
            let enclosed = coarse.enclosures.load(Ordering::Relaxed) as u64;
            (mesh, report, evaluated, enclosed)
        };
        let (blocks, rb, evaluated, enclosed) = run(CoarseStep::Blocks);
        let (every, re, _, none) = run(CoarseStep::EveryVertex);
        let reference = mesh_field(&fine, &grid, 0.0, &options).unwrap();
        assert_identical(&blocks, &reference, what);
        assert_identical(&every, &reference, what);
        assert!(blocks.num_triangles() > 100, "{what}");
        // The same statuses, hence the same fine work.
        assert_eq!(rb.n_smc_high, re.n_smc_high, "{what}");
        assert_eq!(rb.uncertain_vertices, re.uncertain_vertices, "{what}");
        assert_eq!(rb.candidate_cells, re.candidate_cells, "{what}");
        assert_eq!(rb.surface_cells, re.surface_cells, "{what}");
        assert_eq!(rb.gamma, re.gamma, "{what}");
        // Far fewer coarse evaluations, all accounted for.
        let n = grid.len() as u64;
        assert_eq!(re.n_smc_low, n);
        assert_eq!((none, re.enclosures, re.settled_vertices), (0, 0, 0));
        assert_eq!(rb.n_smc_low + rb.settled_vertices, n, "{what}");
        assert_eq!(evaluated, rb.n_smc_low, "{what}");
        assert_eq!(enclosed, rb.enclosures, "{what}");
        assert!(rb.settled_blocks > 0 && rb.settled_blocks <= rb.enclosures);
        assert!(
            rb.settled_vertices > n / 2,
            "{what}: {} of {n} settled",
            rb.settled_vertices
        );
    }
}

/// Without enclosures the block step evaluates every vertex, as the paper's step 1, in grid order.
#[test]
fn block_step_without_enclosures_evaluates_every_vertex() {
    let grid = cube_grid(24);
    let coarse = Field::new(torus, 0.01);
    let fine = Field::new(torus, 0.0);
    let o = SmcOptions::default();
    assert_eq!(o.coarse_step, CoarseStep::Blocks);
    let (mesh, r) = signed_marching_cubes(&coarse, &fine, &grid, 0.0, 0.02, &o, None).unwrap();
    assert_eq!(r.n_smc_low, grid.len() as u64);
    assert_eq!((r.settled_blocks, r.settled_vertices), (0, 0));
    assert_eq!(r.enclosures, 7, "the probe's seven boxes, then no blocks");
    assert_eq!(
        coarse.batches.load(Ordering::Relaxed),
        grid.len().div_ceil(BATCH)
    );
    let reference = mesh_field(&fine, &grid, 0.0, &McOptions::default()).unwrap();
    assert_identical(&mesh, &reference, "torus without enclosures");
}

/// The block step gives the same mesh and counts on 1 and 3 threads.
#[test]
fn block_step_is_the_same_on_any_thread_count() {
    let grid = cube_grid(50);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let coarse = Field::enclosing(two_spheres, 0.003);
            let fine = Field::new(two_spheres, 0.0);
            signed_marching_cubes(
                &coarse,
                &fine,
                &grid,
                0.0,
                0.006,
                &SmcOptions::default(),
                None,
            )
            .unwrap()
        })
    };
    let (a, ra) = run(1);
    let (b, rb) = run(3);
    assert_identical(&a, &b, "1 vs 3 threads");
    assert_eq!(
        (
            ra.n_smc_low,
            ra.n_smc_high,
            ra.enclosures,
            ra.settled_blocks
        ),
        (
            rb.n_smc_low,
            rb.n_smc_high,
            rb.enclosures,
            rb.settled_blocks
        )
    );
}

/// The probe finds that most blocks settle where the field encloses itself and none where it
/// cannot; the expected evaluations are at most one per vertex and smaller for blocks.
#[test]
fn probe_and_expected_evaluations() {
    let grid = cube_grid(64);
    let settled = settled_fraction(&Field::enclosing(torus, 0.002), &grid, 0.0, 0.004, 512);
    assert!(settled > 0.5, "{settled}");
    assert_eq!(
        settled_fraction(&Field::new(torus, 0.0), &grid, 0.0, 0.0, 512),
        0.0
    );
    // A level far outside the field's range: every block settles.
    let all = settled_fraction(&Field::enclosing(torus, 0.0), &grid, -5.0, 0.0, 64);
    assert_eq!(all, 1.0);
    let [every, fine] = expected_evaluations(&grid, CoarseStep::EveryVertex);
    assert_eq!(every, grid.len());
    let [blocks, fine_b] = expected_evaluations(&grid, CoarseStep::Blocks);
    assert!(
        blocks < every && fine == fine_b && fine < blocks,
        "{blocks} {fine}"
    );
    let tiny = cube_grid(4);
    assert_eq!(expected_evaluations(&tiny, CoarseStep::Blocks), [64, 64]);
}
