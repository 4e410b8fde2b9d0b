//! Marching cubes against analytic truth: closed, manifold, consistently oriented meshes of the
//! right topology, volume and area, deterministic across thread counts.

use std::collections::HashMap;
use std::f64::consts::PI;

use proptest::prelude::*;
use zeroset_field_core::analytic::{Cuboid, Sphere, Torus};
use zeroset_field_core::field::FnField;
use zeroset_field_core::{Aabb, Centering, Error, Grid, Point3, ScalarField};
use zeroset_mesh::cubes::{McOptions, marching_cubes, marching_cubes_with_cell_max, mesh_field};
use zeroset_mesh::{MeshError, TriMesh};

/// For each undirected edge `(min, max)`: how often it is used as `(min → max)` and as
/// `(max → min)`.
fn edge_uses(mesh: &TriMesh) -> HashMap<(u32, u32), (usize, usize)> {
    let mut uses: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
    for t in mesh.triangles() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let e = uses.entry((a.min(b), a.max(b))).or_default();
            if a < b {
                e.0 += 1;
            } else {
                e.1 += 1;
            }
        }
    }
    uses
}

/// Every edge used exactly twice, once each way: closed, edge-manifold, consistently oriented.
fn check_closed(mesh: &TriMesh) -> Result<(), String> {
    for (e, uses) in edge_uses(mesh) {
        if uses != (1, 1) {
            return Err(format!("edge {e:?} used {uses:?} (forward, backward)"));
        }
    }
    Ok(())
}

/// Structure that holds for every output: indices valid, coordinates finite, no degenerate
/// triangle (two equal corners or zero area), every vertex used.
fn check_well_formed(mesh: &TriMesh) -> Result<(), String> {
    let mut used = vec![false; mesh.num_vertices()];
    for (t, tri) in mesh.triangles().iter().enumerate() {
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err(format!("triangle {t} {tri:?} is degenerate"));
        }
        if triangle_area(&mesh.corners(t)) <= 0.0 {
            return Err(format!("triangle {t} {:?} has zero area", mesh.corners(t)));
        }
        for &v in tri {
            used[v as usize] = true;
        }
    }
    if let Some(v) = used.iter().position(|u| !u) {
        return Err(format!("vertex {v} is not used"));
    }
    if mesh.vertices().iter().flatten().any(|x| !x.is_finite()) {
        return Err("non-finite coordinate".into());
    }
    Ok(())
}

fn cross(a: Point3, b: Point3) -> Point3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn sub(a: Point3, b: Point3) -> Point3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: Point3, b: Point3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn triangle_normal(c: &[Point3; 3]) -> Point3 {
    cross(sub(c[1], c[0]), sub(c[2], c[0]))
}

fn triangle_area(c: &[Point3; 3]) -> f64 {
    0.5 * dot(triangle_normal(c), triangle_normal(c)).sqrt()
}

/// `V − E + F`, counting the vertices triangles use.
fn euler(mesh: &TriMesh) -> i64 {
    let mut used: Vec<u32> = mesh.triangles().iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    used.len() as i64 - edge_uses(mesh).len() as i64 + mesh.num_triangles() as i64
}

/// The signed volume enclosed (divergence theorem): positive for an outward-wound mesh.
fn volume(mesh: &TriMesh) -> f64 {
    (0..mesh.num_triangles())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            dot(a, cross(b, c)) / 6.0
        })
        .sum()
}

fn area(mesh: &TriMesh) -> f64 {
    (0..mesh.num_triangles())
        .map(|t| triangle_area(&mesh.corners(t)))
        .sum()
}

fn cube_grid(lo: f64, hi: f64, n: usize) -> Grid<3> {
    Grid::vertex_centered(Aabb::new([lo; 3], [hi; 3]).unwrap(), [n; 3]).unwrap()
}

fn closed() -> McOptions {
    McOptions::default().with_close_boundary(true)
}

#[test]
fn spheres_are_closed_outward_and_accurate() {
    let (centre, r) = ([0.013, -0.021, 0.007], 0.7);
    let sphere = Sphere::new(centre, r);
    for n in [8, 17, 33, 64, 128] {
        let grid = cube_grid(-1.0, 1.0, n);
        let h = grid.spacing()[0];
        let mesh = mesh_field(&sphere, &grid, 0.0, &McOptions::default()).unwrap();
        check_closed(&mesh).unwrap_or_else(|e| panic!("n = {n}: {e}"));
        check_well_formed(&mesh).unwrap_or_else(|e| panic!("n = {n}: {e}"));
        assert_eq!(euler(&mesh), 2, "n = {n}");
        let (v, a) = (volume(&mesh), area(&mesh));
        let (v_true, a_true) = (4.0 / 3.0 * PI * r.powi(3), 4.0 * PI * r * r);
        let max_sdf = mesh
            .vertices()
            .iter()
            .map(|p| sphere.value(p).abs())
            .fold(0.0, f64::max);
        let outward = (0..mesh.num_triangles())
            .filter(|&t| {
                let c = mesh.corners(t);
                let mid = [0, 1, 2].map(|a| (c[0][a] + c[1][a] + c[2][a]) / 3.0);
                dot(triangle_normal(&c), sub(mid, centre)) > 0.0
            })
            .count() as f64
            / mesh.num_triangles() as f64;
        let normals_ok = mesh
            .vertices()
            .iter()
            .zip(mesh.normals())
            .all(|(p, nrm)| dot(*nrm, sub(*p, centre)) > 0.99 * r.min(1.0) * 0.9);
        println!(
            "sphere n = {n}: V = {}, F = {}, volume error {:.3e}, area error {:.3e}, \
             max |sdf|/h = {:.4}, max |sdf|/h² = {:.4}, outward {outward}",
            mesh.num_vertices(),
            mesh.num_triangles(),
            (v - v_true) / v_true,
            (a - a_true) / a_true,
            max_sdf / h,
            max_sdf / (h * h)
        );
        assert!(v > 0.0);
        assert!(outward > 0.999, "n = {n}: {outward}");
        assert!(normals_ok, "n = {n}");
        // Linear interpolation of an SDF along an edge is off by at most ~h²/(2r).
        assert!(max_sdf <= h * h / r, "n = {n}: {max_sdf}");
        if n == 64 {
            assert!(((v - v_true) / v_true).abs() < 0.02, "{v} vs {v_true}");
            assert!(((a - a_true) / a_true).abs() < 0.02, "{a} vs {a_true}");
        }
        if n == 128 {
            // The bar: genus 0 (Euler 2, above) and the area within 1% at 128³.
            assert!(((a - a_true) / a_true).abs() < 0.01, "{a} vs {a_true}");
        }
    }
}

#[test]
fn sample_normals_match_the_field_gradient() {
    let sphere = Sphere::new([0.05, 0.0, -0.03], 0.6);
    let grid = cube_grid(-1.0, 1.0, 40);
    let values = grid.sample(&sphere);
    let from_samples = marching_cubes(&grid, &values, 0.0, &McOptions::default()).unwrap();
    let from_field = mesh_field(&sphere, &grid, 0.0, &McOptions::default()).unwrap();
    assert_eq!(from_samples.vertices(), from_field.vertices());
    assert_eq!(from_samples.triangles(), from_field.triangles());
    for (a, b) in from_samples.normals().iter().zip(from_field.normals()) {
        assert!((dot(*a, *a) - 1.0).abs() < 1e-12);
        assert!(dot(*a, *b) > 0.99, "{a:?} vs {b:?}");
    }
    let bare = mesh_field(
        &sphere,
        &grid,
        0.0,
        &McOptions::default().with_normals(false),
    )
    .unwrap();
    assert!(bare.normals().is_empty());
}

#[test]
fn a_torus_has_euler_characteristic_zero() {
    let torus = Torus::new([0.5, 0.5, 0.5], 0.3, 0.1);
    for n in [24, 41, 64] {
        let grid = cube_grid(0.0, 1.0, n);
        let mesh = mesh_field(&torus, &grid, 0.0, &McOptions::default()).unwrap();
        check_closed(&mesh).unwrap_or_else(|e| panic!("n = {n}: {e}"));
        check_well_formed(&mesh).unwrap_or_else(|e| panic!("n = {n}: {e}"));
        assert_eq!(euler(&mesh), 0, "n = {n}");
        let v_true = 2.0 * PI * PI * 0.3 * 0.01;
        let v = volume(&mesh);
        assert!(
            v > 0.0 && ((v - v_true) / v_true).abs() < 0.05,
            "{v} vs {v_true}"
        );
    }
}

#[test]
fn two_far_spheres_are_two_closed_components() {
    let f = FnField::new(
        |p: &Point3| {
            let a = Sphere::new([-0.5, -0.4, 0.01], 0.3).value(p);
            let b = Sphere::new([0.5, 0.45, -0.02], 0.25).value(p);
            a.min(b)
        },
        None,
    );
    let mesh = mesh_field(&f, &cube_grid(-1.0, 1.0, 48), 0.0, &McOptions::default()).unwrap();
    check_closed(&mesh).unwrap();
    check_well_formed(&mesh).unwrap();
    assert_eq!(euler(&mesh), 4);
    // Components by union-find over triangle edges.
    let mut parent: Vec<usize> = (0..mesh.num_vertices()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for t in mesh.triangles() {
        for k in 0..3 {
            let (a, b) = (
                find(&mut parent, t[k] as usize),
                find(&mut parent, t[(k + 1) % 3] as usize),
            );
            parent[a] = b;
        }
    }
    let mut roots: Vec<usize> = (0..mesh.num_vertices())
        .map(|v| find(&mut parent, v))
        .collect();
    roots.sort_unstable();
    roots.dedup();
    assert_eq!(roots.len(), 2);
}

#[test]
fn samples_exactly_on_the_level_keep_the_mesh_closed() {
    // h = 1/16 exactly: the planes and box faces below fall on grid planes, so whole planes of
    // samples are exactly 0.
    let grid = cube_grid(0.0, 1.0, 17);
    let fields: Vec<(&str, Box<dyn ScalarField<3>>, i64)> = vec![
        (
            "plane x = 6h",
            Box::new(FnField::new(|p: &Point3| p[0] - 0.375, None)),
            2,
        ),
        (
            "plane z = 5h, inside above",
            Box::new(FnField::new(|p: &Point3| 0.3125 - p[2], None)),
            2,
        ),
        (
            "grid-aligned box",
            Box::new(Cuboid::new([0.5; 3], [0.25, 0.3125, 0.1875])),
            2,
        ),
        (
            "box touching the grid border",
            Box::new(Cuboid::new([0.25; 3], [0.25, 0.125, 0.25])),
            2,
        ),
        (
            "zero-thickness sheet: inside on both sides of x = 8h",
            Box::new(FnField::new(|p: &Point3| -(p[0] - 0.5).abs(), None)),
            2,
        ),
        (
            "two boxes sharing a face of samples on the level",
            Box::new(FnField::new(
                |p: &Point3| {
                    let a = Cuboid::new([0.375, 0.5, 0.5], [0.125; 3]).value(p);
                    let b = Cuboid::new([0.625, 0.5, 0.5], [0.125; 3]).value(p);
                    a.max(-(p[0] - 0.5).abs()).min(b.max(-(p[0] - 0.5).abs()))
                },
                None,
            )),
            2,
        ),
    ];
    for (name, f, chi) in fields {
        let values = grid.sample(&f);
        assert!(values.contains(&0.0), "{name}");
        let mesh = marching_cubes(&grid, &values, 0.0, &closed()).unwrap();
        assert!(!mesh.is_empty(), "{name}");
        check_well_formed(&mesh).unwrap_or_else(|e| panic!("{name}: {e}"));
        check_closed(&mesh).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(euler(&mesh), chi, "{name}");
        assert!(volume(&mesh) > 0.0, "{name}");
        assert!(mesh.normals().iter().flatten().all(|x| x.is_finite()));
    }
    // The box's faces are grid planes, but its edges are bevelled: the samples on a box edge
    // count as outside and have no inside neighbour along a grid edge, so a prism of section
    // h²/2 is cut along each of the 12 edges (total length 6).
    let mesh = mesh_field(
        &Cuboid::new([0.5; 3], [0.25, 0.3125, 0.1875]),
        &grid,
        0.0,
        &closed(),
    )
    .unwrap();
    let (v, v_true, h) = (volume(&mesh), 0.5 * 0.625 * 0.375, 1.0 / 16.0);
    assert!(v < v_true && v > v_true - 6.0 * h * h / 2.0, "{v}");
}

#[test]
fn a_plane_leaving_the_grid_is_open_unless_capped() {
    let f = FnField::new(|p: &Point3| 0.3 * p[0] - 0.2 * p[1] + p[2] - 0.1, None);
    let bounds = Aabb::new([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]).unwrap();
    let grid = Grid::vertex_centered(bounds, [13, 17, 11]).unwrap();
    let on_border = |p: &Point3| (0..3).any(|a| (p[a].abs() - 1.0).abs() < 1e-12);
    let open = mesh_field(&f, &grid, 0.0, &McOptions::default()).unwrap();
    check_well_formed(&open).unwrap();
    let mut boundary = 0;
    for ((a, b), uses) in edge_uses(&open) {
        match uses {
            (1, 1) => {}
            (1, 0) | (0, 1) => {
                boundary += 1;
                let (pa, pb) = (open.vertices()[a as usize], open.vertices()[b as usize]);
                assert!(on_border(&pa) && on_border(&pb), "{pa:?} {pb:?}");
            }
            other => panic!("edge ({a}, {b}) used {other:?}"),
        }
    }
    assert!(boundary > 0);
    assert_eq!(euler(&open), 1); // a disc
    // On the plane, but for crossings beside a sample (the plane runs through the sample at
    // (−1, −1, 0.2), up to rounding): those are moved to the next f32 value (at most 1.5
    // f32 steps, < 2·10⁻⁷ for coordinates within ±1), so that the vertices around it stay
    // distinct when written as f32.
    for p in open.vertices() {
        assert!(f.value(p).abs() < 2e-7, "{p:?} {}", f.value(p));
    }
    let capped = mesh_field(&f, &grid, 0.0, &closed()).unwrap();
    check_closed(&capped).unwrap();
    check_well_formed(&capped).unwrap();
    assert_eq!(euler(&capped), 2);
    // The region below the plane inside the box.
    let exact = {
        // ∫∫ over (x, y) of (clamp(0.1 − 0.3x + 0.2y, −1, 1) + 1): the plane stays inside the
        // box in z, so no clamp is active.
        4.0 * (0.1 + 1.0)
    };
    // (To 1e-7, not rounding: the vertices beside the sample the plane runs through moved.)
    assert!(
        (volume(&capped) - exact).abs() < 1e-7,
        "{}",
        volume(&capped)
    );
    // Cell-centred grids work the same way.
    let cells = Grid::new(bounds, [9, 8, 10], Centering::Cell).unwrap();
    let capped = mesh_field(&f, &cells, 0.0, &closed()).unwrap();
    check_closed(&capped).unwrap();
    assert_eq!(euler(&capped), 2);
}

#[test]
fn a_field_entirely_inside_gives_the_box_when_capped() {
    let grid = cube_grid(-1.0, 1.0, 6);
    let values = vec![-1.0; grid.len()];
    assert!(
        marching_cubes(&grid, &values, 0.0, &McOptions::default())
            .unwrap()
            .is_empty()
    );
    let mesh = marching_cubes(&grid, &values, 0.0, &closed()).unwrap();
    check_closed(&mesh).unwrap();
    check_well_formed(&mesh).unwrap();
    assert_eq!(euler(&mesh), 2);
    assert!((volume(&mesh) - 8.0).abs() < 1e-12);
    // All outside: nothing, capped or not.
    let values = vec![1.0; grid.len()];
    assert!(
        marching_cubes(&grid, &values, 0.0, &closed())
            .unwrap()
            .is_empty()
    );
}

#[test]
fn output_is_identical_with_one_and_three_threads() {
    let f = FnField::new(
        |p: &Point3| {
            (3.1 * p[0]).sin() * (2.3 * p[1]).cos() + (1.7 * p[2] + 0.4 * p[0]).sin() * 0.8 - 0.1
                + 0.3 * (-(p[0] * p[0] + p[1] * p[1]) * 4.0).exp()
        },
        None,
    );
    let grid = cube_grid(-1.5, 1.5, 48);
    let run = |threads: usize, options: McOptions| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| mesh_field(&f, &grid, 0.0, &options).unwrap())
    };
    for options in [McOptions::default(), closed()] {
        let one = run(1, options);
        assert!(one.num_triangles() > 1000);
        assert_eq!(one, run(3, options));
        assert_eq!(one, run(3, options));
    }
    check_closed(&run(3, closed())).unwrap();
}

#[test]
fn bad_inputs_are_specific_errors() {
    let grid = cube_grid(0.0, 1.0, 4);
    let mut values = vec![1.0; 64];
    values[21] = f64::NAN;
    match marching_cubes(&grid, &values, 0.0, &McOptions::default()) {
        Err(MeshError::NonFiniteSample {
            index, grid_index, ..
        }) => {
            assert_eq!(index, 21);
            assert_eq!(grid_index, vec![1, 1, 1]);
        }
        other => panic!("{other:?}"),
    }
    values[21] = 1.0;
    values[63] = f64::INFINITY;
    assert!(matches!(
        marching_cubes(&grid, &values, 0.0, &McOptions::default()),
        Err(MeshError::NonFiniteSample { index: 63, .. })
    ));
    assert!(matches!(
        marching_cubes(&grid, &values[..60], 0.0, &McOptions::default()),
        Err(MeshError::Field(Error::ShapeMismatch {
            expected: 64,
            got: 60,
            ..
        }))
    ));
    assert!(matches!(
        marching_cubes(&grid, &[0.0; 64], f64::NAN, &McOptions::default()),
        Err(MeshError::NonFiniteLevel { .. })
    ));
    let thin = Grid::cell_centered(Aabb::new([0.0; 3], [1.0; 3]).unwrap(), [3, 1, 3]).unwrap();
    assert!(matches!(
        marching_cubes(&thin, &[0.0; 9], 0.0, &McOptions::default()),
        Err(MeshError::Field(Error::GridTooSmall {
            axis: 1,
            needed: 2,
            got: 1
        }))
    ));
    let nan_field = FnField::new(|p: &Point3| if p[2] > 0.9 { f64::NAN } else { 0.0 }, None);
    assert!(matches!(
        mesh_field(&nan_field, &grid, 0.5, &McOptions::default()),
        Err(MeshError::NonFiniteSample { index: 3, .. })
    ));
}

#[test]
fn huge_values_neither_overflow_nor_panic() {
    let grid = cube_grid(0.0, 1.0, 3);
    let values: Vec<f64> = (0..27)
        .map(|l| if l % 3 == 1 { -f64::MAX } else { f64::MAX })
        .collect();
    let mesh = marching_cubes(&grid, &values, 0.0, &closed()).unwrap();
    check_closed(&mesh).unwrap();
    assert!(mesh.vertices().iter().flatten().all(|x| x.is_finite()));
}

/// A random smooth field: a constant, a few plane waves and a few Gaussians.
type Wave = (f64, [f64; 3], f64);
type Bump = (f64, [f64; 3], f64);

fn smooth_field() -> impl Strategy<Value = (f64, Vec<Wave>, Vec<Bump>)> {
    let v3 = || [-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64];
    (
        -0.5..0.5f64,
        prop::collection::vec(
            (
                -1.0..1.0f64,
                v3().prop_map(|k| k.map(|x| 6.0 * x)),
                0.0..6.3f64,
            ),
            0..3,
        ),
        prop::collection::vec((-1.5..1.5f64, v3(), 0.05..0.5f64), 0..4),
    )
}

fn eval(field: &(f64, Vec<Wave>, Vec<Bump>), p: &Point3) -> f64 {
    let waves: f64 = field
        .1
        .iter()
        .map(|&(a, k, phase)| a * (dot(k, *p) + phase).sin())
        .sum();
    let bumps: f64 = field
        .2
        .iter()
        .map(|&(a, c, s)| {
            let d = sub(*p, c);
            a * (-dot(d, d) / (s * s)).exp()
        })
        .sum();
    field.0 + waves + bumps
}

/// Checks `marching_cubes_with_cell_max` against `marching_cubes` (the same mesh) and against
/// the cell maxima computed from the vertex positions: the largest of the eight samples of the
/// grid cell holding each vertex (on a cell face, the cell above; moved inside the grid).
fn check_cell_max(
    grid: &Grid<3>,
    values: &[f64],
    level: f64,
    options: &McOptions,
) -> Result<(), String> {
    let plain = marching_cubes(grid, values, level, options).unwrap();
    let (mesh, cell_max) = marching_cubes_with_cell_max(grid, values, level, options).unwrap();
    if mesh != plain {
        return Err("the mesh differs from marching_cubes'".into());
    }
    if cell_max.len() != mesh.num_vertices() {
        return Err(format!(
            "{} maxima for {} vertices",
            cell_max.len(),
            mesh.num_vertices()
        ));
    }
    let (lo, h, n) = (grid.bounds().min(), grid.spacing(), grid.counts());
    for (v, (p, &got)) in mesh.vertices().iter().zip(&cell_max).enumerate() {
        let base: [usize; 3] = std::array::from_fn(|a| {
            let u = ((p[a] - lo[a]) / h[a] + 1e-9).floor() as isize;
            u.clamp(0, n[a] as isize - 2) as usize
        });
        let mut want = f64::NEG_INFINITY;
        for c in 0..8 {
            let idx = [
                base[0] + (c & 1),
                base[1] + (c >> 1 & 1),
                base[2] + (c >> 2),
            ];
            want = want.max(values[grid.linear_index(idx)]);
        }
        if got != want {
            return Err(format!(
                "vertex {v} at {p:?}: cell maximum {got}, want {want}"
            ));
        }
    }
    Ok(())
}

#[test]
fn cell_maxima_of_a_torus_are_those_of_the_vertices_cells() {
    let grid = cube_grid(-1.0, 1.0, 40);
    let values = grid.sample(&Torus::new([0.0; 3], 0.6, 0.25));
    for options in [
        McOptions::default(),
        closed(),
        McOptions::default().with_normals(false),
    ] {
        check_cell_max(&grid, &values, 0.0, &options).unwrap();
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn cell_maxima_match_the_vertices_cells(
        field in smooth_field(),
        n in [2usize..10, 2usize..10, 2usize..10],
        seed in prop::collection::vec(-1i8..=1, 729),
        close in any::<bool>(),
    ) {
        let grid = Grid::vertex_centered(Aabb::new([-1.0; 3], [1.0; 3]).unwrap(), n).unwrap();
        let options = McOptions::default().with_close_boundary(close);
        // A smooth field (edge vertices, some centre vertices) and samples on the level
        // (merged vertices, dropped triangles, compaction).
        let f = FnField::new(|p: &Point3| eval(&field, p), None);
        check_cell_max(&grid, &grid.sample(&f), 0.05, &options).map_err(TestCaseError::fail)?;
        let steps: Vec<f64> = (0..grid.len()).map(|l| f64::from(seed[l])).collect();
        check_cell_max(&grid, &steps, 0.0, &options).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn random_smooth_fields_give_closed_consistently_wound_meshes(
        field in smooth_field(),
        n in [2usize..12, 2usize..12, 2usize..12],
        level in -0.3..0.3f64,
    ) {
        let grid = Grid::vertex_centered(Aabb::new([-1.0; 3], [1.0; 3]).unwrap(), n).unwrap();
        let f = FnField::new(|p: &Point3| eval(&field, p), None);
        let values = grid.sample(&f);
        // Keep every sample off the level.
        let mut level = level;
        while values.contains(&level) {
            level += 1e-9;
        }
        let mesh = marching_cubes(&grid, &values, level, &closed()).unwrap();
        if let Err(e) = check_closed(&mesh) {
            return Err(TestCaseError::fail(e));
        }
        if let Err(e) = check_well_formed(&mesh) {
            return Err(TestCaseError::fail(e));
        }
        // Open meshes: every interior edge still used once each way.
        let open = marching_cubes(&grid, &values, level, &McOptions::default()).unwrap();
        for (e, uses) in edge_uses(&open) {
            prop_assert!(uses == (1, 1) || uses == (1, 0) || uses == (0, 1), "{:?} {:?}", e, uses);
        }
        // Euler characteristic is even for a closed orientable surface.
        prop_assert_eq!(euler(&mesh) % 2, 0);
    }

    #[test]
    fn samples_on_the_level_give_well_formed_meshes(
        n in [2usize..7, 2usize..7, 2usize..7],
        seed in prop::collection::vec(-1i8..=1, 343),
    ) {
        let grid = Grid::vertex_centered(Aabb::new([-1.0; 3], [1.0; 3]).unwrap(), n).unwrap();
        let values: Vec<f64> = (0..grid.len()).map(|l| f64::from(seed[l])).collect();
        let mesh = marching_cubes(&grid, &values, 0.0, &closed()).unwrap();
        if let Err(e) = check_well_formed(&mesh) {
            return Err(TestCaseError::fail(format!("{e}\nvalues {values:?}")));
        }
        // No edge is used by more triangles one way than the other: no hole.
        for (e, (fwd, bwd)) in edge_uses(&mesh) {
            prop_assert_eq!(fwd, bwd, "edge {:?}; values {:?}", e, values);
        }
    }
}

/// Capped meshes: every vertex normal points the way the winding does around it (the caps'
/// vertices took the field's gradient, the cut sheet's direction: on a tilted plane capped in
/// a box, every cap vertex's normal was the plane's), and a vertex inside a cap has its box
/// face's outward normal exactly — also on a georeferenced grid far from the origin.
#[test]
fn capped_meshes_have_their_caps_normals() {
    for o in [[0.0; 3], [612_345.5, 5_012_345.25, 301.0]] {
        let f = FnField::new(
            move |p: &Point3| (p[2] - o[2]) - 0.1 + 0.3 * (p[0] - o[0]) - 0.2 * (p[1] - o[1]),
            None,
        );
        let bounds = Aabb::new(
            [o[0] - 1.0, o[1] - 1.0, o[2] - 1.0],
            [o[0] + 1.0, o[1] + 1.0, o[2] + 1.0],
        )
        .unwrap();
        let cells = Grid::new(bounds, [9, 8, 10], Centering::Cell).unwrap();
        let values = cells.sample(&f);
        for (how, mesh) in [
            ("field", mesh_field(&f, &cells, 0.0, &closed()).unwrap()),
            (
                "samples",
                marching_cubes(&cells, &values, 0.0, &closed()).unwrap(),
            ),
        ] {
            check_closed(&mesh).unwrap();
            // The area-weighted winding normal at each vertex.
            let mut winding = vec![[0.0; 3]; mesh.num_vertices()];
            for (ti, t) in mesh.triangles().iter().enumerate() {
                let [a, b, c] = mesh.corners(ti);
                let (u, v) = (
                    [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
                    [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
                );
                let n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                for &i in t {
                    for k in 0..3 {
                        winding[i as usize][k] += n[k];
                    }
                }
            }
            let (first, last) = (cells.point([0; 3]), cells.point([8, 7, 9]));
            let mut caps = 0;
            for ((p, n), w) in mesh.vertices().iter().zip(mesh.normals()).zip(&winding) {
                let dot: f64 = (0..3).map(|k| n[k] * w[k]).sum();
                assert!(
                    dot > 0.0,
                    "{how} {o:?}: vertex {p:?}: normal {n:?} against the winding {w:?}"
                );
                // Inside the bottom cap (z at the first sample, below the plane, off its sides).
                let off_sides = (0..2).all(|a| p[a] != first[a] && p[a] != last[a]);
                if p[2] == first[2] && f.value(p) < -1e-6 && off_sides {
                    assert_eq!(*n, [0.0, 0.0, -1.0], "{how} {o:?}: {p:?}");
                    caps += 1;
                }
            }
            assert!(
                caps > 10,
                "{how} {o:?}: {caps} vertices inside the bottom cap"
            );
        }
    }
}
