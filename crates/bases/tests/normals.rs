//! Normal estimation against truth: analytic shapes (sphere, torus, a thin closed box, two
//! objects apart), the real scans with their own normals, thread independence and bad input.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zeroset_bases::noise::estimate_noise;
use zeroset_bases::normals::{
    EstimatedNormals, MAX_NEIGHBOURS, NOISY_NORMAL_NEIGHBOURS, NORMAL_NEIGHBOURS, NormalError,
    NormalOptions, default_neighbours, estimate_noise_unoriented, estimate_normals,
    estimate_normals_from_scanners, fill_missing_normals, orient_normals,
};
use zeroset_field_core::io::read_point_cloud;

type P = [f64; 3];

fn dot(a: &P, b: &P) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn estimate(points: &[P]) -> EstimatedNormals {
    estimate_normals(points, &NormalOptions::default()).expect("normals")
}

#[path = "../../../examples/common/shapes.rs"]
mod shapes;

/// `n` points spread over the sphere of radius `r` about `c` (Fibonacci lattice) and their
/// outward normals.
fn sphere(n: usize, c: P, r: f64) -> (Vec<P>, Vec<P>) {
    let (points, normals) = shapes::sphere(n, r);
    let moved = points
        .iter()
        .map(|p| [p[0] + c[0], p[1] + c[1], p[2] + c[2]])
        .collect();
    (moved, normals)
}

/// The points of the sphere of radius `r` (3,000 Fibonacci points) above the height `z`, with
/// outward normals.
fn cap(r: f64, z: f64) -> (Vec<P>, Vec<P>) {
    let (points, normals) = sphere(3000, [0.0; 3], r);
    points
        .into_iter()
        .zip(normals)
        .filter(|(p, _)| p[2] > z)
        .unzip()
}

/// The fraction of estimated normals that point against the truth, and the largest angle (in
/// degrees) between the estimated and the true line.
fn against(estimated: &[P], truth: &[P]) -> (f64, f64) {
    let flipped = estimated
        .iter()
        .zip(truth)
        .filter(|(a, b)| dot(a, b) < 0.0)
        .count();
    let worst = estimated
        .iter()
        .zip(truth)
        .map(|(a, b)| dot(a, b).abs().min(1.0).acos().to_degrees())
        .fold(0.0, f64::max);
    (flipped as f64 / truth.len() as f64, worst)
}

#[test]
fn a_torus_is_oriented_outward_including_its_hole() {
    // R = 1, r = 0.35, 6,000 random points (uniform in the angles), outward normals.
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (points, truth): (Vec<P>, Vec<P>) = (0..6000)
        .map(|_| {
            let (u, v) = (
                rng.random_range(0.0..std::f64::consts::TAU),
                rng.random_range(0.0..std::f64::consts::TAU),
            );
            let n = [v.cos() * u.cos(), v.cos() * u.sin(), v.sin()];
            let p = [
                (1.0 + 0.35 * v.cos()) * u.cos(),
                (1.0 + 0.35 * v.cos()) * u.sin(),
                0.35 * v.sin(),
            ];
            (p, n)
        })
        .unzip();
    let estimated = estimate(&points);
    let (flipped, worst) = against(&estimated.normals, &truth);
    assert_eq!(flipped, 0.0);
    assert!(worst < 20.0, "{worst}°");
    assert_eq!(
        (estimated.pieces, estimated.attached, estimated.undetermined),
        (1, 0, 0)
    );
    for n in &estimated.normals {
        assert!((dot(n, n) - 1.0).abs() < 1e-12);
    }
}

/// A closed box `1 × 1 × h` sampled about every `s` on its faces (positions jittered within
/// the faces), with outward normals.
fn thin_box(h: f64, s: f64, seed: u64) -> (Vec<P>, Vec<P>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut jitter = move || rng.random_range(-0.25 * s..0.25 * s);
    let cells = (1.0 / s).round() as usize;
    let clamp = |x: f64| x.clamp(0.0, 1.0);
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    for a in 0..=cells {
        for b in 0..=cells {
            let (x, y) = (a as f64 * s, b as f64 * s);
            for (z, nz) in [(h, 1.0), (0.0, -1.0)] {
                points.push([clamp(x + jitter()), clamp(y + jitter()), z]);
                normals.push([0.0, 0.0, nz]);
            }
        }
        // The four sides, one row half way up.
        let t = clamp(a as f64 * s + jitter());
        for (p, n) in [
            ([t, 0.0, 0.5 * h], [0.0, -1.0, 0.0]),
            ([t, 1.0, 0.5 * h], [0.0, 1.0, 0.0]),
            ([0.0, t, 0.5 * h], [-1.0, 0.0, 0.0]),
            ([1.0, t, 0.5 * h], [1.0, 0.0, 0.0]),
        ] {
            points.push(p);
            normals.push(n);
        }
    }
    (points, normals)
}

#[test]
fn a_thin_part_keeps_its_two_sheets_facing_apart() {
    // The large faces 2 spacings apart: a point's 16 nearest include some of the other sheet's,
    // whose plane is parallel — Hoppe's cost 1 − |n_i · n_j| alone links the sheets and turned
    // one inward (half the points flipped, each seed here, tried); the cost of running along
    // the normals keeps the walk within each sheet.
    for seed in [1, 2, 3] {
        let (points, truth) = thin_box(0.04, 0.02, seed);
        let estimated = estimate(&points);
        // The large faces away from the rim, where a patch mixes a face with the sides and no
        // plane is right.
        let inner = |p: &P| p.iter().take(2).all(|x| (0.06..=0.94).contains(x));
        let (estimated, truth): (Vec<P>, Vec<P>) = points
            .iter()
            .zip(estimated.normals.iter().zip(&truth))
            .filter(|(p, _)| inner(p))
            .map(|(_, (e, t))| (*e, *t))
            .unzip();
        assert!(estimated.len() > 3500, "{}", estimated.len());
        // A patch of 17 points straddling both sheets can be narrower across than between
        // them, and its plane stands up: a few points (1%), whose sign means nothing.
        let planar = |(e, t): &(&P, &P)| dot(e, t).abs() > 30f64.to_radians().cos();
        let (good, truth): (Vec<P>, Vec<P>) = estimated
            .iter()
            .zip(&truth)
            .filter(planar)
            .map(|(e, t)| (*e, *t))
            .unzip();

        let (flipped, _) = against(&good, &truth);
        assert!(
            good.len() * 100 > estimated.len() * 97,
            "{} of {}",
            good.len(),
            estimated.len()
        );
        assert_eq!(flipped, 0.0, "seed {seed}");
    }
}

#[test]
fn a_thin_part_is_not_taken_for_noise() {
    // From the positions alone each patch of the box straddles both sheets, and their distance
    // reads as scatter: noisy, which sent the default to 32 neighbours, and those turned one
    // face inward (half the points). Measured again with the 16-neighbour normals the box is
    // clean, so the default stays at the 16 the test above checks.
    for seed in [1, 2, 3] {
        let (points, _) = thin_box(0.04, 0.02, seed);
        let trap = estimate_noise(&points, None).unwrap();
        assert!(trap.is_noisy(), "seed {seed}: {trap:?}");
        let (k, noise) = default_neighbours(&points);
        assert_eq!(k, NORMAL_NEIGHBOURS, "seed {seed}: {noise:?}");
        let noise = estimate_noise_unoriented(&points).unwrap();
        assert!(noise.relative() < 0.1, "seed {seed}: {noise:?}");
    }
}

#[test]
fn a_cavity_wall_faces_into_the_cavity() {
    // A hollow ball (radii 1 and 0.6) with a ball of radius 0.3 in its cavity: the cavity's
    // wall lies inside the outer sphere once and faces inward, the ball inside it twice and
    // faces outward. Each turned outward on its own, the fit filled the cavity.
    let (mut points, mut truth) = sphere(2000, [0.0; 3], 1.0);
    let (wall, wall_out) = sphere(800, [0.0; 3], 0.6);
    points.extend(wall);
    truth.extend(wall_out.iter().map(|n| n.map(|x| -x)));
    let (ball, ball_out) = sphere(300, [0.1, 0.0, 0.0], 0.3);
    points.extend(ball);
    truth.extend(ball_out);
    let estimated = estimate(&points);
    assert_eq!(against(&estimated.normals, &truth).0, 0.0);
    assert_eq!((estimated.pieces, estimated.nested), (3, 1));
}

#[test]
fn a_piece_merely_behind_another_is_not_taken_for_a_cavity() {
    // Every chord of a convex surface lies behind it: a cap cut off a sphere by a gap in the
    // scan, and a ball resting in a bowl, lie "behind" the other piece's nearest points, and
    // a first version of the nesting rule turned both inward. Neither is surrounded.
    // The cap: within 20° of (1, 1, 1)/√3, the ring from 20° to 30° missing (a review's case;
    // the cap's box lies in the rest's).
    let axis = [1.0 / 3f64.sqrt(); 3];
    let (points, truth): (Vec<P>, Vec<P>) = {
        let (p, n) = sphere(6000, [0.0; 3], 1.0);
        p.into_iter()
            .zip(n)
            .filter(|(p, _)| !(20f64..30.0).contains(&dot(p, &axis).acos().to_degrees()))
            .unzip()
    };
    let estimated = estimate(&points);
    assert_eq!((estimated.pieces, estimated.nested), (2, 0));
    assert_eq!(against(&estimated.normals, &truth).0, 0.0);
    // A ball in a bowl (the lower half of a unit sphere, one sheet).
    let (bowl, _) = sphere(8000, [0.0; 3], 1.0);
    let mut points: Vec<P> = bowl.into_iter().filter(|p| p[2] < -0.05).collect();
    let bowl_len = points.len();
    let (ball, ball_out) = sphere(1500, [0.0, 0.0, -0.5], 0.3);
    points.extend(ball);
    let estimated = estimate(&points);
    assert_eq!(estimated.nested, 0);
    assert_eq!(against(&estimated.normals[bowl_len..], &ball_out).0, 0.0);
}

#[test]
fn separate_objects_are_each_turned_outward() {
    let (mut points, mut truth) = sphere(1500, [0.0; 3], 1.0);
    let (p2, n2) = sphere(700, [10.0, 0.0, 0.0], 0.5);
    points.extend(p2);
    truth.extend(n2);
    let estimated = estimate(&points);
    assert_eq!(against(&estimated.normals, &truth).0, 0.0);
    assert_eq!(
        (estimated.pieces, estimated.attached, estimated.nested),
        (2, 0, 0)
    );
}

#[test]
fn objects_closer_than_their_sampling_keep_their_own_normals() {
    // Two unit spheres 0.02–0.2 apart, sampled every 0.05–0.15, with their own outward
    // normals: the walk's only edges between them cross the gap with normals facing each
    // other, and carried one sphere's sign onto the other (50% read inconsistent, as
    // unoriented normals do; `reconstruct` turned one sphere inside out).
    let options = NormalOptions::default();
    for (gap, n) in [(0.02, 2000), (0.1, 560), (0.2, 560)] {
        let (mut points, mut truth) = sphere(n, [-1.0 - gap / 2.0, 0.0, 0.0], 1.0);
        let (p2, n2) = sphere(n, [1.0 + gap / 2.0, 0.0, 0.0], 1.0);
        points.extend(p2);
        truth.extend(n2);
        let o = orient_normals(&points, &truth, &options).expect("oriented");
        assert_eq!((o.inconsistent, o.turned), (0, 0), "gap {gap}");
        assert_eq!(o.estimated.pieces, 2, "gap {gap}");
        // Turned to face up they are still told unoriented: on a curved surface neighbours
        // whose signs differ face the same way along their edge, which stays in the walk.
        let up: Vec<P> = truth
            .iter()
            .map(|t| if t[2] < 0.0 { t.map(|x| -x) } else { *t })
            .collect();
        let o = orient_normals(&points, &up, &options).expect("oriented");
        assert!(
            o.unoriented(),
            "gap {gap}: {} of {}",
            o.inconsistent,
            points.len()
        );
    }
}

/// A smooth closed egg: the upper half of the unit sphere on the lower half of a spheroid 0.3
/// deep, `2n` points on the top (uniform in `z`, so by area) and `1.2 n` below (by about the
/// same density), with outward normals. 37.5% of the points face down.
fn egg(n: usize) -> (Vec<P>, Vec<P>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let depth = 0.3;
    let top = (0..2 * n).map(|i| {
        let z = (i as f64 + 0.5) / (2 * n) as f64;
        let r = (1.0 - z * z).sqrt();
        let t = golden * i as f64;
        let p = [r * t.cos(), r * t.sin(), z];
        (p, p)
    });
    let below = 6 * n / 5;
    let bottom = (0..below).map(move |i| {
        let z = -(i as f64 + 0.5) / below as f64;
        let r = (1.0 - z * z).sqrt();
        let t = golden * i as f64;
        let p = [r * t.cos(), r * t.sin(), depth * z];
        let g = [p[0], p[1], p[2] / (depth * depth)];
        let length = dot(&g, &g).sqrt();
        (p, g.map(|x| x / length))
    });
    top.chain(bottom).unzip()
}

/// The three upper faces of a regular tetrahedron of edge 1 standing on its base (no base),
/// each sampled on a triangular grid of `m` rows, with exact outward normals: a one-sided
/// scan with sharp creases, across which neighbouring normals are 109° apart.
fn tetrahedron_top(m: usize) -> (Vec<P>, Vec<P>) {
    let s3 = 3f64.sqrt();
    let base = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, s3 / 2.0, 0.0]];
    let apex = [0.5, s3 / 6.0, (2.0f64 / 3.0).sqrt()];
    let middle = [0.5, s3 / 6.0, apex[2] / 4.0];
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for k in 0..3 {
        let (a, b) = (base[k], base[(k + 1) % 3]);
        let u = std::array::from_fn::<f64, 3, _>(|i| b[i] - a[i]);
        let v = std::array::from_fn::<f64, 3, _>(|i| apex[i] - a[i]);
        let c = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let length = dot(&c, &c).sqrt();
        let mut n = c.map(|x| x / length);
        if dot(&n, &std::array::from_fn(|i| a[i] - middle[i])) < 0.0 {
            n = n.map(|x| -x);
        }
        for i in 0..m {
            for j in 0..m - i {
                let (x, y) = (
                    (i as f64 + 1.0 / 3.0) / m as f64,
                    (j as f64 + 1.0 / 3.0) / m as f64,
                );
                points.push(std::array::from_fn(|d| a[d] + x * u[d] + y * v[d]));
                normals.push(n);
            }
        }
    }
    (points, normals)
}

#[test]
fn a_closed_objects_side_turned_to_face_in_is_told_by_rays() {
    let options = NormalOptions::default();
    // Normals turned to face +z (Open3D's `orient_normals_to_align_with_direction` default):
    // on an egg whose lower side is the smaller only that side (37.5%) reads inconsistent,
    // under the share that tells arbitrary signs, and the fit got a bottom facing into the egg.
    // Rays along those normals cross the top from inside: turned back outward.
    let (points, truth) = egg(1000);
    let up: Vec<P> = truth
        .iter()
        .map(|t| if t[2] < 0.0 { t.map(|x| -x) } else { *t })
        .collect();
    let o = orient_normals(&points, &up, &options).expect("oriented");
    assert_eq!((o.inconsistent, o.turned), (1200, 1200));
    assert!(!o.unoriented_by_share());
    assert!(o.facing_in() && o.unoriented(), "{:?}", o.rays);
    assert!(o.rays.inward * 10 >= o.rays.cast * 9, "{:?}", o.rays);
    assert_eq!(against(&o.estimated.normals, &truth).0, 0.0);
    // Their own normals: consistent, no ray cast.
    let o = orient_normals(&points, &truth, &options).expect("oriented");
    assert_eq!((o.inconsistent, o.rays.cast), (0, 0));
    assert!(!o.unoriented());
    // A patch flipped by hand, a fifth of a sphere (its cap above z = 0.6).
    let (points, truth) = sphere(3000, [0.0; 3], 1.0);
    let flipped: Vec<P> = points
        .iter()
        .zip(&truth)
        .map(|(p, t)| if p[2] > 0.6 { t.map(|x| -x) } else { *t })
        .collect();
    let o = orient_normals(&points, &flipped, &options).expect("oriented");
    assert!(o.facing_in() && o.unoriented(), "{:?}", o.rays);
    assert_eq!(against(&o.estimated.normals, &truth).0, 0.0);
    // A one-sided scan whose walk disagrees with its correct normals across sharp creases
    // (the sign flips over an edge where neighbours are 109° apart): a third reads
    // inconsistent, but rays along those normals leave the tetrahedron or meet a face from
    // inside, as outward normals do. Nothing is turned.
    let (points, truth) = tetrahedron_top(40);
    let o = orient_normals(&points, &truth, &options).expect("oriented");
    let share = o.inconsistent as f64 / points.len() as f64;
    assert!((0.3..0.4).contains(&share), "{share}");
    assert!(o.rays.cast > 100, "{:?}", o.rays);
    assert_eq!(o.rays.inward, 0, "{:?}", o.rays);
    assert!(!o.facing_in() && !o.unoriented());
    // Such a sheet under another, both facing up (a creased ground under a canopy, a faulted
    // horizon under a smooth one): a ray up from the lower one meets the upper one from
    // behind, as a closed object's top is met from its turned underside. But the two are
    // separate pieces of the walk, and the upper one says nothing of the lower one's side.
    // Terrain rising at 30° to a crest, then falling at 65° (the walk disagrees across the
    // crest), under a flat sheet twice as wide at z = 0.6, both sampled every 1/80.
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut jitter = |i: usize| (i as f64 + rng.random_range(-0.3..0.3)) / 80.0;
    let (tan_gentle, tan_steep) = (30f64.to_radians().tan(), 65f64.to_radians().tan());
    let (mut points, mut truth) = (Vec::new(), Vec::new());
    for i in 0..80 {
        for j in 0..80 {
            let (x, y) = (jitter(i), jitter(j));
            let (z, slope) = if x <= 0.6 {
                (tan_gentle * x, tan_gentle)
            } else {
                let z = tan_gentle * 0.6 - tan_steep * (x - 0.6);
                if z > 0.0 { (z, -tan_steep) } else { (0.0, 0.0) }
            };
            let length = (1.0 + slope * slope).sqrt();
            points.push([x, y, z]);
            truth.push([-slope / length, 0.0, 1.0 / length]);
        }
    }
    for i in 0..160 {
        for j in 0..160 {
            points.push([jitter(i) - 0.5, jitter(j) - 0.5, 0.6]);
            truth.push([0.0, 0.0, 1.0]);
        }
    }
    let o = orient_normals(&points, &truth, &options).expect("oriented");
    let share = o.inconsistent as f64 / points.len() as f64;
    assert!((0.05..0.1).contains(&share), "{share}");
    // Read without the pieces, 187 of 253 rays were inward, the other points' 32 of 255: told.
    assert!(o.rays.cast > 200, "{:?}", o.rays);
    assert!(o.rays.inward * 10 < o.rays.cast, "{:?}", o.rays);
    assert!(!o.facing_in() && !o.unoriented());
}

#[test]
fn a_small_piece_takes_the_sign_of_the_large_one_beside_it() {
    // 30 points on a cap of the sphere of radius 1.25 (too few to read an inside from), beside
    // the unit sphere: their outward (radial) normals agree with the nearest sphere points'.
    let (mut points, mut truth) = sphere(2000, [0.0; 3], 1.0);
    let (patch, patch_normals) = cap(1.5, 1.465);
    assert!((10..50).contains(&patch.len()), "{}", patch.len());
    let small = patch.len();
    points.extend(patch);
    truth.extend(patch_normals);
    let estimated = estimate(&points);
    assert_eq!(against(&estimated.normals, &truth).0, 0.0);
    assert_eq!((estimated.pieces, estimated.attached), (1, small));
    // Seen from the other side: the cap inside the sphere (radius 0.8, normals still radial
    // outward) agrees with the sphere's outward normals too — it is signed by its neighbours,
    // not by its own (open, tiny) inside.
    let (mut points, mut truth) = sphere(2000, [0.0; 3], 1.0);
    let (patch, patch_normals) = cap(0.8, 0.78);
    points.extend(patch);
    truth.extend(patch_normals);
    let estimated = estimate(&points);
    assert_eq!(against(&estimated.normals, &truth).0, 0.0);
}

#[test]
fn points_on_a_line_take_a_neighbours_normal() {
    // A whisker of 40 points along the z axis above the sphere: their neighbourhoods span no
    // plane; they are oriented along the walk, and the sphere is not disturbed.
    let (mut points, truth) = sphere(2000, [0.0; 3], 1.0);
    points.extend((0..40).map(|i| [0.0, 0.0, 1.05 + 0.002 * i as f64]));
    let estimated = estimate(&points);
    assert!(estimated.undetermined >= 30, "{estimated:?}");
    assert_eq!(against(&estimated.normals[..2000], &truth).0, 0.0);
    for n in &estimated.normals[2000..] {
        assert!((dot(n, n) - 1.0).abs() < 1e-9, "{n:?}");
    }
}

#[test]
fn a_large_piece_without_any_plane_takes_its_neighbours_normals() {
    // A scanner's missed returns written as 100 copies of one point, and a 100-point wire,
    // apart from the sphere: neither spans a plane, however many points they hold. They take
    // the normals of the sphere points nearest to them, unit length, and leave the sphere's
    // own alone.
    let (sphere_points, truth) = sphere(1500, [0.0; 3], 1.0);
    let heap = [[3.0, 0.0, 0.0]; 100];
    let wire: Vec<P> = (0..100)
        .map(|i| [0.0, 3.0 + 0.01 * i as f64, 0.0])
        .collect();
    for extra in [heap.to_vec(), wire] {
        let mut points = sphere_points.clone();
        points.extend(&extra);
        let estimated = estimate(&points);
        assert_eq!(against(&estimated.normals[..1500], &truth).0, 0.0);
        assert_eq!((estimated.pieces, estimated.undetermined), (1, 100));
        for n in &estimated.normals[1500..] {
            assert!((dot(n, n) - 1.0).abs() < 1e-12, "{n:?}");
        }
    }
}

#[test]
fn a_viewpoint_turns_flat_and_inside_scans_towards_the_scanner() {
    // Terrain seen from above (a gently curved 40 × 40 sheet, one side only): its divergence
    // reads no inside; towards a viewpoint above every normal faces up, below every one down.
    let terrain: Vec<P> = (0..1600)
        .map(|i| {
            let (x, y) = ((i % 40) as f64 * 0.025, (i / 40) as f64 * 0.025);
            [x, y, 0.05 * (3.0 * x).sin() * (2.0 * y).cos()]
        })
        .collect();
    for (height, sign) in [(10.0, 1.0), (-10.0, -1.0)] {
        let options = NormalOptions::default().viewpoint([0.5, 0.5, height]);
        let estimated = estimate_normals(&terrain, &options).unwrap();
        for n in &estimated.normals {
            assert!(sign * n[2] > 0.8, "{height}: {n:?}");
        }
    }
    // A room scanned from its middle (the inside of a sphere): facing the scanner is inward,
    // where by default the normals face out of the closed surface.
    let (room, outward) = sphere(2000, [0.0; 3], 3.0);
    let inside = NormalOptions::default().viewpoint([0.2, -0.1, 0.3]);
    let estimated = estimate_normals(&room, &inside).unwrap();
    assert_eq!(against(&estimated.normals, &outward).0, 1.0);
    assert_eq!(against(&estimate(&room).normals, &outward).0, 0.0);
    let nan = NormalOptions::default().viewpoint([0.0, f64::NAN, 0.0]);
    assert!(matches!(
        estimate_normals(&room, &nan),
        Err(NormalError::Viewpoint { .. })
    ));
}

#[test]
fn a_flat_piece_faces_its_nearest_axis_by_convention() {
    // Terrain has no inside: its side was what the sign of a divergence of about 0 gave (a
    // sheet of 3,000 points with relief of 3% of its width faced down). A sheet with relief of
    // 5% of its width (one low hill, divergence 0.05 of its spread) is now reported flat and
    // faces +z, whichever way it is tilted or mirrored (a hill or a hollow); a wall faces +x;
    // closed and curved pieces are not flat.
    let sheet = |mirror: f64, tilt: f64| -> Vec<P> {
        (0..1600)
            .map(|i| {
                let (x, y) = ((i % 40) as f64 * 0.025, (i / 40) as f64 * 0.025);
                let z = mirror * 0.05 * (3.0 * x).sin() * (2.0 * y).cos() + tilt * x;
                [x, y, z]
            })
            .collect()
    };
    for (mirror, tilt) in [(1.0, 0.0), (-1.0, 0.0), (1.0, 0.3), (-1.0, -0.5)] {
        let estimated = estimate(&sheet(mirror, tilt));
        assert_eq!(estimated.flat.len(), 1, "{mirror} {tilt}");
        assert_eq!(estimated.flat[0].points, 1600);
        assert!(estimated.flat[0].facing[2] > 0.8, "{:?}", estimated.flat[0]);
        let up = estimated.normals.iter().filter(|n| n[2] > 0.0).count();
        assert_eq!(up, 1600, "{mirror} {tilt}");
    }
    let wall: Vec<P> = sheet(1.0, 0.0).iter().map(|p| [p[2], p[1], p[0]]).collect();
    let estimated = estimate(&wall);
    assert_eq!(estimated.flat.len(), 1);
    assert!(estimated.normals.iter().all(|n| n[0] > 0.0));
    // A sphere, and a one-sided scan of a 60° cap of one (divergence 0.4 of its spread),
    // keep their outward normals.
    for (points, truth) in [sphere(2000, [0.0; 3], 1.0), cap(1.0, 0.5)] {
        let estimated = estimate(&points);
        assert!(estimated.flat.is_empty());
        assert_eq!(against(&estimated.normals, &truth).0, 0.0);
    }
    // Closed or curved pieces whose divergence is small against their spread are not flat
    // (a first rule on the divergence alone turned them all inside out, a review found): a
    // thin closed rod sampled more densely on one side, and one side of a long pipe.
    let rod: (Vec<P>, Vec<P>) = (0..4000)
        .map(|i| {
            let t = std::f64::consts::PI
                * (if i % 4 == 0 { 2.0 } else { 1.0 })
                * ((i as f64 * 0.618_034) % 1.0)
                + if i % 4 == 0 {
                    0.0
                } else {
                    std::f64::consts::FRAC_PI_2
                };
            let x = (i as f64 * 0.754_877) % 1.0;
            ([x, 0.01 * t.cos(), 0.01 * t.sin()], [0.0, t.cos(), t.sin()])
        })
        .unzip();
    let pipe: (Vec<P>, Vec<P>) = (0..4000)
        .map(|i| {
            let t = std::f64::consts::PI * ((i as f64 * 0.618_034) % 1.0);
            let x = 40.0 * ((i as f64 * 0.754_877) % 1.0);
            ([x, t.cos(), -t.sin()], [0.0, t.cos(), -t.sin()])
        })
        .unzip();
    for (name, (points, truth)) in [("rod", rod), ("pipe", pipe)] {
        let estimated = estimate(&points);
        assert!(estimated.flat.is_empty(), "{name}");
        assert!(against(&estimated.normals, &truth).0 < 0.01, "{name}");
    }
    // With a viewpoint the side is the viewpoint's, and nothing is called flat.
    let below = NormalOptions::default().viewpoint([0.5, 0.5, -10.0]);
    let estimated = estimate_normals(&sheet(1.0, 0.0), &below).unwrap();
    assert!(estimated.flat.is_empty());
    assert!(estimated.normals.iter().all(|n| n[2] < 0.0));
}

#[test]
fn each_point_faces_the_scanner_that_recorded_it() {
    // Two stations: one inside a room (the inside of a sphere of radius 3 about the origin),
    // one at x = 8 facing a wall outside it (a curved 2 × 2 sheet about x = 5). From each
    // station its own points face it: the room inward, the wall towards +x.
    let (room, outward) = sphere(2000, [0.0; 3], 3.0);
    let wall: Vec<P> = (0..1600)
        .map(|i| {
            let (y, z) = ((i % 40) as f64 * 0.05 - 1.0, (i / 40) as f64 * 0.05 - 1.0);
            [5.0 + 0.1 * (2.0 * y).sin() * z.cos(), y, z]
        })
        .collect();
    let points: Vec<P> = room.iter().chain(&wall).copied().collect();
    let (inside, outside) = ([0.2, -0.1, 0.3], [8.0, 0.0, 0.0]);
    let scanners: Vec<P> = (0..points.len())
        .map(|i| if i < room.len() { inside } else { outside })
        .collect();
    let options = NormalOptions::default();
    let estimated = estimate_normals_from_scanners(&points, &scanners, &options).unwrap();
    let (room_normals, wall_normals) = estimated.normals.split_at(room.len());
    assert_eq!(against(room_normals, &outward).0, 1.0);
    assert!(wall_normals.iter().all(|n| n[0] > 0.8));
    // One viewpoint for both (the room's station) sees the wall from behind: it turns the
    // wall away from the scanner that recorded it.
    let one = estimate_normals(&points, &options.viewpoint(inside)).unwrap();
    assert!(one.normals[room.len()..].iter().all(|n| n[0] < -0.8));
    // One scanner position per point, each finite.
    assert_eq!(
        estimate_normals_from_scanners(&points, &scanners[1..], &options),
        Err(NormalError::Scanners {
            got: points.len() - 1,
            points: points.len()
        })
    );
    let mut nan = scanners.clone();
    nan[7] = [0.0, f64::NAN, 0.0];
    assert!(matches!(
        estimate_normals_from_scanners(&points, &nan, &options),
        Err(NormalError::Viewpoint { .. })
    ));
}

#[test]
fn duplicated_points_get_the_same_normal() {
    let (points, truth) = sphere(1000, [0.0; 3], 1.0);
    let doubled: Vec<P> = points.iter().flat_map(|p| [*p, *p]).collect();
    let estimated = estimate(&doubled);
    for (i, t) in truth.iter().enumerate() {
        let (a, b) = (estimated.normals[2 * i], estimated.normals[2 * i + 1]);
        assert_eq!(a, b);
        assert!(dot(&a, t) > 0.99, "{a:?} {t:?}");
    }
}

#[test]
fn the_result_does_not_depend_on_the_threads() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (points, _) = sphere(4000, [0.0; 3], 1.0);
    let noisy: Vec<P> = points
        .iter()
        .map(|p| p.map(|x| x + rng.random_range(-0.01..0.01)))
        .collect();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| estimate(&noisy))
    };
    let one = run(1);
    let three = run(3);
    assert_eq!(one, three);
}

/// The oriented points of scan `name` in `data/` (or in `$ZEROSET_DATA`).
fn scan(name: &str) -> (Vec<P>, Vec<P>) {
    let dir = match std::env::var_os("ZEROSET_DATA") {
        Some(d) => std::path::PathBuf::from(d),
        None => std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data"),
    };
    let path = dir.join(name);
    let cloud = read_point_cloud(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (set ZEROSET_DATA)", path.display()));
    let normals = cloud.normals().expect("normals").to_vec();
    (cloud.positions().to_vec(), normals)
}

#[test]
fn real_scans_get_their_own_normals_back() {
    // The scans' normals come from their meshes (bunny) or the scanner's software (kitten);
    // from the positions alone every point is turned the same way, and the lines agree to a
    // few degrees at most points.
    for name in ["bunny_points.ply", "kitten.xyz"] {
        let (points, truth) = scan(name);
        let estimated = estimate(&points);
        let (flipped, _) = against(&estimated.normals, &truth);
        assert_eq!(flipped, 0.0, "{name}");
        let mut angles: Vec<f64> = estimated
            .normals
            .iter()
            .zip(&truth)
            .map(|(a, b)| dot(a, b).min(1.0).acos().to_degrees())
            .collect();
        angles.sort_by(f64::total_cmp);
        let median = angles[angles.len() / 2];
        assert!(median < 3.0, "{name}: median {median}°");
    }
}

#[test]
fn bad_input_gets_specific_errors() {
    let (points, _) = sphere(100, [0.0; 3], 1.0);
    let options = NormalOptions::default();
    let mut nan = points.clone();
    nan[17][1] = f64::NAN;
    assert!(matches!(
        estimate_normals(&nan, &options),
        Err(NormalError::NonFinite { index: 17, .. })
    ));
    assert!(matches!(
        estimate_normals(&points[..2], &options),
        Err(NormalError::TooFewPoints { needed: 3, got: 2 })
    ));
    for k in [0, 1, MAX_NEIGHBOURS + 1] {
        assert_eq!(
            estimate_normals(&points, &NormalOptions::default().neighbours(k)),
            Err(NormalError::Neighbours { got: k })
        );
    }
    let line: Vec<P> = (0..50).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
    let error = estimate_normals(&line, &options).unwrap_err();
    assert!(
        matches!(
            error,
            NormalError::Degenerate {
                undetermined: 50,
                points: 50,
                ..
            }
        ),
        "{error:?}"
    );
    assert!(error.to_string().contains("span no plane"), "{error}");
    // Three points: a plane, fitted from fewer neighbours than asked.
    let three = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let estimated = estimate(&three);
    for n in &estimated.normals {
        assert!(n[2].abs() > 1.0 - 1e-12, "{n:?}");
    }
}

#[test]
fn a_board_scanned_from_both_faces_faces_each_scanner() {
    // A board 1.5 spacings thick (two 50 × 50 sheets 0.02 apart in x and y, 0.03 apart in z),
    // one station above it and one below: each point's neighbours reach the other sheet, and
    // the spanning forest joins the two into one piece.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (h, t) = (0.02, 0.03);
    let (mut points, mut truth, mut scanners) = (Vec::new(), Vec::new(), Vec::new());
    for side in [1.0, -1.0] {
        for i in 0..50 {
            for j in 0..50 {
                let (dx, dy): (f64, f64) = (rng.random(), rng.random());
                let (x, y) = (i as f64 + 0.2 * (dx - 0.5), j as f64 + 0.2 * (dy - 0.5));
                points.push([x * h, y * h, side * t / 2.0]);
                truth.push([0.0, 0.0, side]);
                scanners.push([0.5, 0.4, 2.0 * side]);
            }
        }
    }
    let options = NormalOptions::default();
    let estimated = estimate_normals_from_scanners(&points, &scanners, &options).unwrap();
    assert_eq!(estimated.pieces, 1);
    assert_eq!(against(&estimated.normals, &truth).0, 0.0);
    // Without the scanners (outward, the one piece signed as a whole) one face is turned
    // inward: the case per-point signing is for.
    let (wrong, _) = against(&estimate(&points).normals, &truth);
    assert!(wrong > 0.4, "{wrong}");
    // A heap of 20 copies of one point above the board, recorded by the upper station: a piece
    // of its own without a plane, it takes the normal of its nearest point on the board — as
    // that point ends up, facing the upper station.
    let heap = points.len();
    points.extend(std::iter::repeat_n([0.5, 0.4, 0.3], 20));
    scanners.extend(std::iter::repeat_n([0.5, 0.4, 2.0], 20));
    let estimated = estimate_normals_from_scanners(&points, &scanners, &options).unwrap();
    assert_eq!(estimated.attached, 20);
    assert!(
        estimated.normals[heap..].iter().all(|n| n[2] > 0.9),
        "{:?}",
        &estimated.normals[heap..]
    );
}

#[test]
fn a_floor_seen_at_grazing_incidence_takes_its_sign_from_the_near_floor() {
    // A rough floor (12 × 12, spacing 0.1, heights jittered by up to ±0.02) under a scanner 0.3
    // above its middle: beyond 1.2 the line of sight is within 14.5° of the floor, and a plane
    // tilted by the roughness can face away from the scanner. Signed from the near floor along
    // the forest, every normal is up.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let points: Vec<P> = (0..120 * 120)
        .map(|i| {
            let (x, y) = ((i % 120) as f64 * 0.1 - 6.0, (i / 120) as f64 * 0.1 - 6.0);
            let z: f64 = 0.02 * (rng.random::<f64>() - 0.5) * 2.0;
            [x, y, z]
        })
        .collect();
    let scanner = [0.05, 0.05, 0.3];
    let scanners = vec![scanner; points.len()];
    let estimated =
        estimate_normals_from_scanners(&points, &scanners, &NormalOptions::default()).unwrap();
    assert!(estimated.normals.iter().all(|n| n[2] > 0.5));
    assert!(estimated.facing_scanner < points.len());
    // Some of those up normals face away from the scanner: signed each by its own line of
    // sight, they would have been turned down.
    let away = points
        .iter()
        .zip(&estimated.normals)
        .filter(|(p, n)| {
            dot(
                n,
                &[scanner[0] - p[0], scanner[1] - p[1], scanner[2] - p[2]],
            ) < 0.0
        })
        .count();
    assert!(away > 100, "{away} planes face away from the scanner");
}

#[test]
fn a_noisy_scan_is_estimated_from_more_neighbours() {
    // The unit sphere's 4,000 lattice points, moved along the radius by Gaussian noise of 0.03
    // (0.37 of the point spacing as measured; Box–Muller from a seeded generator).
    let (points, outward) = sphere(4000, [0.0; 3], 1.0);
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let noisy: Vec<P> = points
        .iter()
        .map(|p| {
            let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
            let r = 1.0 + 0.03 * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
            p.map(|x| x * r)
        })
        .collect();
    assert_eq!(default_neighbours(&points).0, NORMAL_NEIGHBOURS);
    let (k, noise) = default_neighbours(&noisy);
    assert_eq!(k, NOISY_NORMAL_NEIGHBOURS);
    assert!(noise.unwrap().relative() > 0.3, "{noise:?}");
    // More neighbours tilt the planes less: the median angle to the true normal drops.
    let median_angle = |k: usize| {
        let options = NormalOptions::default().neighbours(k);
        let estimated = estimate_normals(&noisy, &options).unwrap();
        assert_eq!(against(&estimated.normals, &outward).0, 0.0);
        let mut angles: Vec<f64> = estimated
            .normals
            .iter()
            .zip(&outward)
            .map(|(a, b)| dot(a, b).clamp(-1.0, 1.0).acos())
            .collect();
        angles.sort_by(f64::total_cmp);
        angles[angles.len() / 2]
    };
    let (few, many) = (median_angle(NORMAL_NEIGHBOURS), median_angle(k));
    assert!(many < 0.8 * few, "{many} vs {few}");
}

#[test]
fn missing_normals_are_completed_from_their_neighbours_and_the_given_ones_kept() {
    // The bunny's own normals, every 7th zeroed, and a cap of 300 points around one point
    // zeroed whole (each point there has no given normal among its 16 nearest: the nearest
    // given normal signs it).
    let (points, truth) = scan("bunny_points.ply");
    let mut normals = truth.clone();
    for n in normals.iter_mut().step_by(7) {
        *n = [0.0; 3];
    }
    let centre = points[20_000];
    let mut by_distance: Vec<usize> = (0..points.len()).collect();
    let d2 = |p: &P| (0..3).map(|a| (p[a] - centre[a]).powi(2)).sum::<f64>();
    by_distance.sort_by(|&a, &b| d2(&points[a]).total_cmp(&d2(&points[b])).then(a.cmp(&b)));
    for &i in &by_distance[..300] {
        normals[i] = [0.0; 3];
    }
    let before = normals.clone();
    let filled = fill_missing_normals(&points, &mut normals, NORMAL_NEIGHBOURS).expect("filled");
    let zeroed: Vec<usize> = (0..points.len())
        .filter(|&i| before[i] == [0.0; 3])
        .collect();
    assert_eq!(filled, zeroed);
    // The given ones untouched, bit for bit.
    for i in (0..points.len()).filter(|i| !zeroed.contains(i)) {
        assert_eq!(normals[i], before[i]);
    }
    // The completed ones unit, none against the scan's own, close to it at most points (the
    // planes of 17 points against area-weighted mesh normals: a few degrees).
    let (estimated, truth): (Vec<P>, Vec<P>) =
        filled.iter().map(|&i| (normals[i], truth[i])).unzip();
    assert!(estimated.iter().all(|n| (dot(n, n) - 1.0).abs() < 1e-12));
    let (flipped, _) = against(&estimated, &truth);
    assert_eq!(flipped, 0.0);
    let mut angles: Vec<f64> = estimated
        .iter()
        .zip(&truth)
        .map(|(a, b)| dot(a, b).min(1.0).acos().to_degrees())
        .collect();
    angles.sort_by(f64::total_cmp);
    assert!(
        angles[angles.len() / 2] < 3.0,
        "median {}°",
        angles[angles.len() / 2]
    );
    // The same bits on one thread and on three.
    let run = |threads: usize| {
        let mut n = before.clone();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| fill_missing_normals(&points, &mut n, NORMAL_NEIGHBOURS))
            .expect("filled");
        n
    };
    assert_eq!(run(1), normals);
    assert_eq!(run(3), normals);
}

#[test]
fn a_few_given_normals_sign_the_whole_cloud_round_by_round() {
    // 3,000 sphere points with 6 normals given (one of them 100 long): the signs spread from
    // them outward through the completed ones, and every normal comes out outward.
    let (points, truth) = sphere(3000, [0.0; 3], 1.0);
    let mut normals = vec![[0.0; 3]; 3000];
    for i in (0..3000).step_by(500) {
        normals[i] = truth[i];
    }
    normals[500] = truth[500].map(|x| 100.0 * x);
    let filled = fill_missing_normals(&points, &mut normals, NORMAL_NEIGHBOURS).expect("filled");
    assert_eq!(filled.len(), 2994);
    let (flipped, worst) = against(&normals, &truth);
    assert_eq!(flipped, 0.0);
    assert!(worst < 5.0, "{worst}°");
}

#[test]
fn completing_normals_refuses_what_it_cannot_complete() {
    let (points, truth) = sphere(200, [0.0; 3], 1.0);
    // Nothing missing: nothing done.
    let mut normals = truth.clone();
    assert_eq!(fill_missing_normals(&points, &mut normals, 16), Ok(vec![]));
    assert_eq!(normals, truth);
    let mut zero = vec![[0.0; 3]; 200];
    assert_eq!(
        fill_missing_normals(&points, &mut zero, 16),
        Err(NormalError::NoneGiven { points: 200 })
    );
    assert_eq!(
        fill_missing_normals(&points, &mut normals[..199], 16),
        Err(NormalError::Normals {
            got: 199,
            points: 200
        })
    );
    normals[3] = [0.0; 3];
    assert_eq!(
        fill_missing_normals(&points, &mut normals, 1),
        Err(NormalError::Neighbours { got: 1 })
    );
    let mut bad = points.clone();
    bad[5][1] = f64::NAN;
    assert!(matches!(
        fill_missing_normals(&bad, &mut normals, 16),
        Err(NormalError::NonFinite { index: 5, .. })
    ));
    let mut infinite = normals.clone();
    infinite[9][0] = f64::INFINITY;
    assert!(matches!(
        fill_missing_normals(&points, &mut infinite, 16),
        Err(NormalError::NonFiniteNormal { index: 9, .. })
    ));
    // A point whose neighbours lie on a line takes the reference direction itself.
    let line: Vec<P> = (0..50).map(|i| [i as f64, 0.0, 0.0]).collect();
    let mut up = vec![[0.0, 0.0, 2.0]; 50];
    up[20] = [0.0; 3];
    assert_eq!(fill_missing_normals(&line, &mut up, 4), Ok(vec![20]));
    assert_eq!(up[20], [0.0, 0.0, 1.0]);
}

/// The closed box `[0, 1] × [0, 1] × [0, height]` sampled on every face every `step` (faces'
/// shared edges once per face), with outward normals.
fn closed_box(height: f64, step: f64) -> (Vec<P>, Vec<P>) {
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    let size = [1.0, 1.0, height];
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let (nu, nv) = (
            ((size[u] / step).round() as usize).max(1),
            ((size[v] / step).round() as usize).max(1),
        );
        for side in [0.0, 1.0] {
            for a in 0..=nu {
                for b in 0..=nv {
                    let mut p = [0.0; 3];
                    p[axis] = side * size[axis];
                    p[u] = a as f64 * size[u] / nu as f64;
                    p[v] = b as f64 * size[v] / nv as f64;
                    let mut n = [0.0; 3];
                    n[axis] = if side == 0.0 { -1.0 } else { 1.0 };
                    points.push(p);
                    normals.push(n);
                }
            }
        }
    }
    (points, normals)
}

#[test]
fn unoriented_normals_are_told_from_oriented_ones_and_turned_outward() {
    let options = NormalOptions::default();
    // Principal-component normals written without a sign: the box's estimated normals (tilted
    // where a patch straddles two faces, which carries the sign round the edges), each turned
    // to point to the positive side of its face's axis — the three faces at the origin inward
    // (CGAL's cube.pwn is such a file).
    let (points, truth) = closed_box(0.6, 0.04);
    let estimated = estimate(&points).normals;
    assert_eq!(against(&estimated, &truth).0, 0.0);
    let unsigned: Vec<P> = estimated
        .iter()
        .zip(&truth)
        .map(|(e, t)| {
            let axis = t.map(f64::abs);
            if dot(e, &axis) < 0.0 {
                e.map(|x| -x)
            } else {
                *e
            }
        })
        .collect();
    let inward = unsigned
        .iter()
        .zip(&truth)
        .filter(|(u, t)| dot(u, t) < 0.0)
        .count();
    assert!(inward * 3 > points.len(), "{inward}");
    let o = orient_normals(&points, &unsigned, &options).expect("oriented");
    assert!(o.unoriented(), "{} of {}", o.inconsistent, points.len());
    let differ = o
        .estimated
        .normals
        .iter()
        .zip(&estimated)
        .filter(|(a, b)| dot(a, b) < 1.0 - 1e-12)
        .count();
    assert_eq!(differ, 0, "of {}", points.len());
    assert_eq!(o.turned, inward);
    // A wall thinner than its sampling is round, with its own normals: the walk does not
    // cross it (normals pointing apart), so its faces are not taken for inconsistent (47% were,
    // before crossing such an edge cost the most).
    for (height, step) in [(0.02, 0.01), (0.01, 0.01)] {
        let (points, truth) = closed_box(height, step);
        let o = orient_normals(&points, &truth, &options).expect("oriented");
        assert_eq!((o.inconsistent, o.turned), (0, 0), "{height} {step}");
    }
    // A sparse scan's normals turned to face up: where the signs change (round the sides)
    // neighbours' normals point apart along the surface, and the walk must cross there, not
    // over the ears' two faces (2,000 points of the bunny: 33 read inconsistent while every
    // edge between normals pointing apart cost 3).
    let (points, truth) = scan("bunny_2k.xyzn");
    let up: Vec<P> = truth
        .iter()
        .map(|n| if n[2] < 0.0 { n.map(|x| -x) } else { *n })
        .collect();
    let o = orient_normals(&points, &up, &options).expect("oriented");
    assert!(o.unoriented(), "{} of {}", o.inconsistent, points.len());
    // As right as the normals estimated from the positions alone (2.5% against 2.85% turned
    // the wrong way: a sparse sample's thin parts).
    let wrong = against(&o.estimated.normals, &truth).0;
    let unsigned = against(&estimate(&points).normals, &truth).0;
    assert!(wrong <= unsigned, "{wrong} against {unsigned}");
    // Oriented normals are consistent whichever way they face: the bunny's own, and turned
    // all inward (then each is turned back outward: that is for the fit's inward warning).
    let (points, truth) = scan("bunny_points.ply");
    let o = orient_normals(&points, &truth, &options).expect("oriented");
    assert_eq!((o.inconsistent, o.turned), (0, 0));
    assert!(!o.unoriented());
    let inward: Vec<P> = truth.iter().map(|n| n.map(|x| -x)).collect();
    let o = orient_normals(&points, &inward, &options).expect("oriented");
    assert_eq!((o.inconsistent, o.turned), (0, points.len()));
    assert!(!o.unoriented());
    assert_eq!(
        orient_normals(&points, &truth[1..], &options),
        Err(NormalError::Normals {
            got: points.len() - 1,
            points: points.len()
        })
    );
    // A line with a NaN or infinite component is refused, named; a zero one is a point without
    // a line, and takes its neighbours' normal.
    for bad in [f64::NAN, f64::INFINITY] {
        let mut lines = truth.clone();
        lines[17][1] = bad;
        assert!(matches!(
            orient_normals(&points, &lines, &options),
            Err(NormalError::NonFiniteNormal { index: 17, .. })
        ));
    }
    let mut lines = truth.clone();
    lines[17] = [0.0; 3];
    let o = orient_normals(&points, &lines, &options).expect("oriented");
    assert!(dot(&o.estimated.normals[17], &truth[17]) > 0.9);
}
