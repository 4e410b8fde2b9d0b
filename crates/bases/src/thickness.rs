//! Whether a cloud samples a surface or fills a volume: how thick its neighbourhoods are
//! against how wide, from a few dozen neighbours up to a few thousand.
//!
//! Around a point `p`, its `k` nearest points (itself among them) have a covariance
//! `C = (1/k) Σ (q − q̄)(q − q̄)ᵀ` with eigenvalues `λ₀ ≤ λ₁ ≤ λ₂`; the neighbourhood's
//! **thickness** is
//!
//! ```text
//! t_k(p) = λ₀ / λ₂        (0 for points on a plane, 1 for a ball of them).
//! ```
//!
//! On a surface, `t_k` is the square of the patch's sag and scatter over its width: small
//! (`≈ 0.01` on a clean scan at 32 neighbours), growing with curvature at large `k` and with
//! noise at small `k` (where the noise is as wide as the patch, the patch is a piece of a
//! slab). On a cloud that fills a volume — points of a solid (a CT segmentation, a particle
//! simulation, a dense photogrammetric fog) rather than of its boundary — every neighbourhood
//! is about as thick as it is wide, at every scale, until it reaches the volume's own
//! boundary: `t_k ≈ 0.5–0.7` in the interior, ≥ 0.3 in a half ball at the boundary.
//!
//! So the cloud's distinct positions are read at the scales `k ∈ {32, 64, …, 2048}` that hold
//! at most an eighth of them ([`THICKNESS_SCALES`], [`POINTS_PER_SCALE`]), on every
//! `⌈n / 1000⌉`-th ([`THICKNESS_SAMPLES`]), and each scale's median thickness kept; the
//! **thinnest** scale decides. A surface is thin at some scale — above its noise, below its
//! curvature — and a volume at none: [`Thickness::thick_everywhere`] where even the thinnest
//! reads at least [`VOLUME_THICKNESS`]. A few surfaces are thick everywhere too (a small cloud
//! of a thin part, whose neighbourhoods span it, up to the scales it has points for), but their
//! points lie on smooth sheets, where a volume's scatter about every local quadric:
//! [`Thickness::fills_volume`] also asks the noise check ([`crate::noise`]) to read them noisy.
//!
//! **Not told**: a volume sampled in layers or along lines spaced more than about two of their
//! own spacings apart (a CT segmentation whose slices lie 3–5 pixels apart) reads 0 at 32
//! neighbours, each neighbourhood in one slice, as a stack of close parallel sheets does; and
//! a cloud at least half of whose points sample a surface (the median decides).
//!
//! Why it matters: zeroset fits a surface through points that lie on one (the zero set of a
//! field that vanishes at every point). Given a volume's points, every fit reads them as a
//! very noisy surface (the noise check of [`crate::noise`] saturates near 0.58 of the spacing
//! on uniform random points, as on a scan whose noise is wider than its patches), and the mesh
//! is a crumpled sheet through the volume, not its boundary; nothing else in the run tells the
//! user why.

use std::num::NonZero;

use faer::{Mat, Side};
use kiddo::SquaredEuclidean;
use rayon::prelude::*;
use zeroset_field_core::geometry::{self, Point};

use crate::noise::{Noise, Tree, median};

/// The neighbourhood sizes the thickness is read at (those a cloud has points for:
/// [`POINTS_PER_SCALE`]).
pub const THICKNESS_SCALES: [usize; 7] = [32, 64, 128, 256, 512, 1024, 2048];

/// A scale of `k` neighbours is read only on a cloud of at least `POINTS_PER_SCALE · k`
/// distinct positions: a neighbourhood holding a large share of a volume's points reaches its
/// boundary from most of them, and reads thinner (a uniform ball of 20,000 points: 0.69 at 512
/// neighbours, 0.47 at 2048; volumes of 512–3,300 points, read at a quarter of their points:
/// 0.40–0.43). Larger scales matter on small clouds of thin parts: a tube sampled with 8 points
/// round it reads 0.52 at 32 neighbours and 0.04 at 128. The smallest cloud judged has
/// `8 × 32 = 256` points.
pub const POINTS_PER_SCALE: usize = 8;

/// The most points whose neighbourhoods are read per scale (every `⌈n / 1000⌉`-th): a median
/// needs no more, and a million-point cloud is read in about a second.
pub const THICKNESS_SAMPLES: usize = 1000;

/// A cloud is thick everywhere ([`Thickness::thick_everywhere`]) where its median thickness is
/// at least this at every scale read. Measured (2026-12-08, the thinnest scale's median):
/// clean scans 0.000–0.012 (the bunny, the kitten, CGAL's `hippo1`, `ball`, `spheres`,
/// `cube.pwn`), 0.035–0.058 (CGAL's `fin90_with_PCA_normals`, `building`), 0.047 (CGAL's noisy
/// `sphere_20k`), 0.12 (its sparse `oni`, 1,435 points), the bunny with Gaussian noise of
/// 0.25 / 0.5 / 1 / 2% of its diagonal 0.042 / 0.073 / 0.122 / 0.197, 400 random points on a
/// torus 0.194; volumes 0.42 (CGAL's `oneK`: 1,000 random points in a cube), 0.44 (its
/// `blobby`, 3,288 points filling a blob), 0.46–0.49 (5,000 and 50,000 random points in a
/// cube, 20,000 in a ball), 0.37–0.39 (400 in a ball or a cube). Some surfaces are thick at
/// every scale too — a small cloud of a thin part, whose neighbourhoods span it (two 12 × 12
/// sheets two spacings apart: 0.50), an under-sampled lattice — but their points lie on smooth
/// sheets, where a volume's points scatter about every quadric: [`Thickness::fills_volume`]
/// asks the noise check too.
pub const VOLUME_THICKNESS: f64 = 0.35;

/// One scale's reading: the median thickness of the sampled points' neighbourhoods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleThickness {
    /// `k`: the points in each neighbourhood, the point itself among them.
    pub neighbours: usize,
    /// The median over the sampled points of `λ₀ / λ₂` (see the [module docs](self)).
    pub thickness: f64,
}

/// What [`measure_thickness`] read: one [`ScaleThickness`] per scale the cloud has points for,
/// smallest first.
#[derive(Debug, Clone, PartialEq)]
pub struct Thickness {
    /// The scales read, `neighbours` ascending; never empty.
    scales: Vec<ScaleThickness>,
}

impl Thickness {
    /// The scales read, `neighbours` ascending (at least one).
    pub fn scales(&self) -> &[ScaleThickness] {
        &self.scales
    }

    /// The scale whose median neighbourhood is thinnest (the first of equals).
    pub fn thinnest(&self) -> ScaleThickness {
        self.scales.iter().copied().fold(self.scales[0], |a, b| {
            if b.thickness < a.thickness { b } else { a }
        })
    }

    /// Whether the points are thick ([`VOLUME_THICKNESS`]) at every scale read.
    pub fn thick_everywhere(&self) -> bool {
        self.thinnest().thickness >= VOLUME_THICKNESS
    }

    /// Whether the points fill a volume: thick at every scale read, and scattered about the
    /// local quadrics of the noise check ([`Noise::is_noisy`]; `noise` measured on the same
    /// points). A volume's points are noisy as no surface's are (uniform random points read
    /// 0.54–0.58 of their spacing); the surfaces that are thick at every scale — small clouds
    /// of thin parts, a few copies of a scan out of register — lie on smooth sheets
    /// (0.00–0.13). Where the noise could not be measured (`None`: most points repeated, so
    /// that no patch spans a surface), the thickness decides alone: a cube's random points
    /// each written 4 times read 0.43 at every scale and no noise.
    pub fn fills_volume(&self, noise: Option<&Noise>) -> bool {
        self.thick_everywhere() && noise.is_none_or(Noise::is_noisy)
    }
}

/// The thickness of `positions` at each scale its distinct positions are enough for (see the
/// [module docs](self)). `None` for fewer than `POINTS_PER_SCALE · 32` = 256 distinct
/// positions, or a coordinate that is not finite.
///
/// ```
/// use zeroset_bases::noise::estimate_noise;
/// use zeroset_bases::thickness::measure_thickness;
///
/// // 4,096 points on the unit sphere, and 4,096 filling a cube (a jittered 16 × 16 × 16 grid).
/// let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
/// let sphere: Vec<[f64; 3]> = (0..4096)
///     .map(|i| {
///         let z = 1.0 - 2.0 * (i as f64 + 0.5) / 4096.0;
///         let r = (1.0 - z * z).sqrt();
///         [r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z]
///     })
///     .collect();
/// let jitter = |i: u32, axis: u32| f64::from((i * 7919 + axis * 104_729) % 1000) / 1000.0 - 0.5;
/// let cube: Vec<[f64; 3]> = (0..4096u32)
///     .map(|i| [i % 16, i / 16 % 16, i / 256].map(f64::from))
///     .enumerate()
///     .map(|(i, p)| std::array::from_fn(|a| p[a] + 0.8 * jitter(i as u32, a as u32)))
///     .collect();
/// let surface = measure_thickness(&sphere).unwrap();
/// assert!(!surface.thick_everywhere());
/// let volume = measure_thickness(&cube).unwrap();
/// assert!(volume.thick_everywhere());
/// assert!(volume.fills_volume(estimate_noise(&cube, None).as_ref()));
/// ```
pub fn measure_thickness(positions: &[Point<3>]) -> Option<Thickness> {
    read_scales(positions, false)
}

/// [`measure_thickness`] where the points are thick at every scale
/// ([`Thickness::thick_everywhere`]); `None` otherwise, and as there. The scales are read
/// smallest first and the reading stops at the first thin one: a surface's costs one or two
/// of them (the bunny's 32 neighbours, not the 2048 that take most of the time), so the
/// commands' warning costs a fit little.
pub fn thick_everywhere(positions: &[Point<3>]) -> Option<Thickness> {
    read_scales(positions, true)
}

/// The scales of [`measure_thickness`], ending at the first thin one (`None`) where
/// `stop_at_thin`.
fn read_scales(positions: &[Point<3>], stop_at_thin: bool) -> Option<Thickness> {
    let positions = distinct(positions)?;
    let n = positions.len();
    let tree = Tree::new_from_slice(&positions).ok()?;
    let mut scales = Vec::new();
    for &k in THICKNESS_SCALES
        .iter()
        .filter(|&&k| n >= POINTS_PER_SCALE * k)
    {
        let Some(thickness) = median_thickness(&tree, &positions, k) else {
            continue;
        };
        if stop_at_thin && thickness < VOLUME_THICKNESS {
            return None;
        }
        scales.push(ScaleThickness {
            neighbours: k,
            thickness,
        });
    }
    (!scales.is_empty()).then_some(Thickness { scales })
}

/// The median thickness of the neighbourhoods of `neighbours` points (each point and its
/// nearest, its distinct positions only; every `⌈n / 1000⌉`-th read), at one scale, for a
/// cloud of any size: how well planes fitted to that many points can stand for a surface's
/// (0 for a plane's points, 1 for a cube's 8 corners). `None` for fewer than 3 distinct
/// positions, a coordinate that is not finite, or `neighbours` under 3.
pub fn thickness_at(positions: &[Point<3>], neighbours: usize) -> Option<f64> {
    let positions = distinct(positions)?;
    if positions.len() < 3 || neighbours < 3 {
        return None;
    }
    let tree = Tree::new_from_slice(&positions).ok()?;
    median_thickness(&tree, &positions, neighbours.min(positions.len()))
}

/// The distinct positions of `positions`, each where it first occurs, in their order; `None`
/// where a coordinate is not finite. (A point written several times would fill its own
/// neighbourhood.)
fn distinct(positions: &[Point<3>]) -> Option<Vec<Point<3>>> {
    if !positions.iter().flatten().all(|x| x.is_finite()) {
        return None;
    }
    let key = |i: &usize| positions[*i].map(f64::to_bits);
    let mut order: Vec<usize> = (0..positions.len()).collect();
    order.par_sort_unstable_by_key(|i| (key(i), *i));
    order.dedup_by_key(|i| key(i));
    order.sort_unstable();
    Some(order.iter().map(|&i| positions[i]).collect())
}

/// The median over every `⌈n / 1000⌉`-th point of the thickness of its `k` nearest.
fn median_thickness(tree: &Tree, positions: &[Point<3>], k: usize) -> Option<f64> {
    let wanted = NonZero::new(k)?;
    let stride = positions.len().div_ceil(THICKNESS_SAMPLES).max(1);
    let samples: Vec<usize> = (0..positions.len()).step_by(stride).collect();
    let each: Vec<f64> = samples
        .par_iter()
        .filter_map(|&i| {
            let around = tree
                .query(&positions[i])
                .nearest_n::<SquaredEuclidean<f64>>(wanted)
                .execute();
            let points: Vec<Point<3>> = around.iter().map(|f| positions[f.item as usize]).collect();
            neighbourhood_thickness(&points)
        })
        .collect();
    median(each)
}

/// `λ₀ / λ₂` of the covariance of `points`; `None` where they all lie at one position.
fn neighbourhood_thickness(points: &[Point<3>]) -> Option<f64> {
    let m = points.len() as f64;
    let centroid = points
        .iter()
        .fold([0.0; 3], |s, p| geometry::add(&s, p))
        .map(|x| x / m);
    let covariance = Mat::<f64>::from_fn(3, 3, |r, c| {
        points
            .iter()
            .map(|p| (p[r] - centroid[r]) * (p[c] - centroid[c]))
            .sum::<f64>()
            / m
    });
    let eigen = covariance.self_adjoint_eigen(Side::Lower).ok()?;
    let values = eigen.S().column_vector();
    let (thinnest, widest) = (values[0].max(0.0), values[2]);
    (widest > 0.0).then(|| thinnest / widest)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::estimate_noise;

    /// `n` points on the unit sphere (a Fibonacci lattice).
    fn sphere(n: usize) -> Vec<Point<3>> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                [
                    r * (golden * i as f64).cos(),
                    r * (golden * i as f64).sin(),
                    z,
                ]
            })
            .collect()
    }

    /// `n` points of a low-discrepancy (R₃) sequence filling the cube `[0, size]³`.
    fn cube(n: usize, size: [f64; 3]) -> Vec<Point<3>> {
        // The plastic-number generalisation of the golden ratio to three dimensions.
        let phi: f64 = 1.220_744_084_605_759_5;
        let a = [1.0 / phi, 1.0 / (phi * phi), 1.0 / (phi * phi * phi)];
        (0..n)
            .map(|i| std::array::from_fn(|d| ((0.5 + a[d] * i as f64) % 1.0) * size[d]))
            .collect()
    }

    #[test]
    fn a_neighbourhoods_thickness_is_its_thinnest_spread_over_its_widest() {
        // A 2 × 1 × 0 rectangle's corners: flat.
        let flat = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 1.0, 0.0],
        ];
        assert_eq!(neighbourhood_thickness(&flat), Some(0.0));
        // A 2 × 1 × 1 box's corners: variances 1, ¼, ¼.
        let boxed: Vec<Point<3>> = (0..8)
            .map(|i| [2.0 * (i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64])
            .collect();
        assert!((neighbourhood_thickness(&boxed).unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(neighbourhood_thickness(&[[1.0, 2.0, 3.0]; 5]), None);
    }

    #[test]
    fn surfaces_are_thin_and_volumes_thick_at_every_scale() {
        let points = sphere(40_000);
        let surface = measure_thickness(&points).unwrap();
        assert_eq!(
            surface
                .scales()
                .iter()
                .map(|s| s.neighbours)
                .collect::<Vec<_>>(),
            THICKNESS_SCALES
        );
        assert!(surface.thinnest().thickness < 0.01, "{surface:?}");
        assert!(!surface.thick_everywhere());
        assert!(!surface.fills_volume(estimate_noise(&points, None).as_ref()));
        // The same sphere with uniform noise of ±0.06, twice its spacing: thick at 32 neighbours,
        // thin from 512 up, where the patches are wider than the noise.
        let mut state = 7u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let noisy: Vec<Point<3>> = points
            .into_iter()
            .map(|p| p.map(|x| x + 0.12 * (uniform() - 0.5)))
            .collect();
        let noise = estimate_noise(&noisy, None);
        assert!(noise.is_some_and(|n| n.is_noisy()));
        let noisy = measure_thickness(&noisy).unwrap();
        assert!(noisy.scales()[0].thickness > 0.3, "{noisy:?}");
        assert!(noisy.thinnest().thickness < 0.1, "{noisy:?}");
        assert!(!noisy.fills_volume(noise.as_ref()));
        // A filled cube, and a filled brick 4 × 2 × 1: thick at every scale read, and noisy.
        for size in [[1.0; 3], [4.0, 2.0, 1.0]] {
            let points = cube(20_000, size);
            let volume = measure_thickness(&points).unwrap();
            assert!(volume.thick_everywhere(), "{size:?}: {volume:?}");
            assert_eq!(thick_everywhere(&points).as_ref(), Some(&volume));
            assert!(volume.fills_volume(estimate_noise(&points, None).as_ref()));
            // Where the noise could not be measured, the thickness decides.
            assert!(volume.fills_volume(None));
        }
        // A slab 1/50 as thick as it is wide is a surface at the larger scales.
        let slab = measure_thickness(&cube(40_000, [1.0, 1.0, 0.02])).unwrap();
        assert!(!slab.thick_everywhere(), "{slab:?}");
        // The smallest cloud read, at its one scale.
        let small = measure_thickness(&cube(256, [1.0; 3])).unwrap();
        assert_eq!(small.scales().len(), 1);
        assert!(small.thick_everywhere());
        assert!(!measure_thickness(&sphere(256)).unwrap().thick_everywhere());
    }

    #[test]
    fn a_small_cloud_of_a_thin_tube_is_thick_but_clean_and_not_a_volume() {
        // 2,000 points on a tube of radius 0.05, 8 round it and as far apart along it (a
        // cylinder meshed with 8 segments): each 32-point neighbourhood spans the tube
        // (thick), the 256-point ones run along it (thin).
        let tube: Vec<Point<3>> = (0..2000)
            .map(|i| {
                let angle =
                    (i % 8) as f64 * std::f64::consts::TAU / 8.0 + (i / 8 % 2) as f64 * 0.39;
                [
                    0.05 * angle.cos(),
                    0.05 * angle.sin(),
                    (i / 8) as f64 * 0.039,
                ]
            })
            .collect();
        let t = measure_thickness(&tube).unwrap();
        assert!(t.scales()[0].thickness > VOLUME_THICKNESS, "{t:?}");
        assert!(!t.thick_everywhere(), "{t:?}");
        assert_eq!(thick_everywhere(&tube), None);
        assert!(!t.fills_volume(estimate_noise(&tube, None).as_ref()));
    }

    #[test]
    fn one_scale_reads_a_small_clouds_planes() {
        // The 8 corners of a cube: every plane through all of them, as thick as it is wide.
        let corners: Vec<Point<3>> = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64])
            .collect();
        assert!((thickness_at(&corners, 8).unwrap() - 1.0).abs() < 1e-9);
        // 40 points on a sphere, 17 at a time: caps of it, thin.
        assert!(thickness_at(&sphere(40), 17).unwrap() < VOLUME_THICKNESS);
        assert_eq!(thickness_at(&corners[..2], 8), None);
        assert_eq!(thickness_at(&corners, 2), None);
    }

    #[test]
    fn repeated_positions_are_read_once() {
        // 2,000 random points in a cube, each written 4 times: the copies would fill every
        // 32-point neighbourhood with 8 positions.
        let points = cube(2000, [1.0; 3]);
        let repeated: Vec<Point<3>> = points.iter().flat_map(|p| [*p; 4]).collect();
        assert_eq!(measure_thickness(&repeated), measure_thickness(&points));
        // The noise check reads nothing on them, and the thickness decides.
        let noise = estimate_noise(&repeated, None);
        assert!(noise.is_none(), "{noise:?}");
        assert!(
            measure_thickness(&repeated)
                .unwrap()
                .fills_volume(noise.as_ref())
        );
    }

    #[test]
    fn too_few_points_or_a_non_finite_one_read_nothing() {
        assert_eq!(measure_thickness(&cube(255, [1.0; 3])), None);
        assert!(measure_thickness(&cube(256, [1.0; 3])).is_some());
        let mut bad = cube(1000, [1.0; 3]);
        bad[10][2] = f64::NAN;
        assert_eq!(measure_thickness(&bad), None);
        assert_eq!(thick_everywhere(&bad), None);
        assert_eq!(thickness_at(&bad, 32), None);
        // One position written 600 times.
        assert_eq!(measure_thickness(&[[1.0, 2.0, 3.0]; 600]), None);
    }

    #[test]
    fn the_reading_is_the_same_on_one_thread_and_many() {
        let points = cube(30_000, [1.0, 2.0, 0.5]);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| measure_thickness(&points));
        assert_eq!(one, measure_thickness(&points));
    }
}
