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
//! So the cloud is read at the scales `k ∈ {32, 128, 512, 2048}` that hold at most a
//! sixteenth of its points ([`THICKNESS_SCALES`], [`POINTS_PER_SCALE`]), on every
//! `⌈n / 1000⌉`-th point ([`THICKNESS_SAMPLES`]), and each scale's median thickness kept; the
//! **thinnest** scale decides. A surface is thin at some scale — above its noise, below its
//! curvature — and a volume at none: [`Thickness::fills_volume`] where even the thinnest reads
//! at least [`VOLUME_THICKNESS`].
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

use crate::noise::{Tree, median};

/// The neighbourhood sizes the thickness is read at (those a cloud has points for:
/// [`POINTS_PER_SCALE`]).
pub const THICKNESS_SCALES: [usize; 4] = [32, 128, 512, 2048];

/// A scale of `k` neighbours is read only on a cloud of at least `POINTS_PER_SCALE · k` points:
/// a neighbourhood holding more than a sixteenth of a volume's points reaches its boundary from
/// most of them (a uniform ball of 20,000 points read 0.68 at 512 neighbours, 0.55 at 2048).
/// So the smallest cloud judged has `16 × 32 = 512` points.
pub const POINTS_PER_SCALE: usize = 16;

/// The most points whose neighbourhoods are read per scale (every `⌈n / 1000⌉`-th): a median
/// needs no more, and a million-point cloud is read in a fraction of a second.
pub const THICKNESS_SAMPLES: usize = 1000;

/// A cloud fills a volume ([`Thickness::fills_volume`]) where its median thickness is at least
/// this at every scale read. Measured (2026-12-07, the thinnest scale's median): surfaces 0.001–0.02 (clean
/// scans: the bunny, the kitten, CGAL's `hippo1`, `ball`, `spheres`, `cube.pwn`, `building`),
/// 0.07 (CGAL's noisy `sphere_20k`), 0.12 (CGAL's sparse `oni`, 1,435 points), 0.19 (the
/// bunny with Gaussian noise of 2% of its diagonal, twice its spacing; 0.10–0.14 at 0.25–1%),
/// 0.27 (a sparse thin torus, 1,000 points on a tube of 1/20 its radius: the neighbourhoods
/// span the tube); volumes 0.42 (CGAL's `oneK`: 1,000 random points in a cube), 0.46 (5,000
/// in a cube), 0.51 (CGAL's `blobby`, 3,288 points filling a blob), 0.55–0.68 (50,000 in a
/// cube, 20,000 in a ball). A slab 1/20 as thick as it is wide, filled with 50,000 points, reads
/// 0.06 at 2048 neighbours: at that scale it is a surface, and meshing it as one is right.
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
    /// The scales read, `neighbours` ascending (at least one).
    pub scales: Vec<ScaleThickness>,
}

impl Thickness {
    /// The scale whose median neighbourhood is thinnest (the first of equals).
    pub fn thinnest(&self) -> ScaleThickness {
        self.scales
            .iter()
            .copied()
            .reduce(|a, b| if b.thickness < a.thickness { b } else { a })
            .expect("at least one scale is read")
    }

    /// Whether the points fill a volume: thick ([`VOLUME_THICKNESS`]) at every scale read.
    pub fn fills_volume(&self) -> bool {
        self.thinnest().thickness >= VOLUME_THICKNESS
    }
}

/// The thickness of `positions` at each scale it has points for (see the
/// [module docs](self)). `None` for fewer than `POINTS_PER_SCALE · 32` = 512 points, a
/// coordinate that is not finite, or a cloud whose sampled neighbourhoods are all single
/// positions (points repeated more often than the scale).
///
/// ```
/// use zeroset_bases::thickness::measure_thickness;
///
/// // 4,096 points on the unit sphere, and 4,096 filling a cube (a 16 × 16 × 16 grid).
/// let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
/// let sphere: Vec<[f64; 3]> = (0..4096)
///     .map(|i| {
///         let z = 1.0 - 2.0 * (i as f64 + 0.5) / 4096.0;
///         let r = (1.0 - z * z).sqrt();
///         [r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z]
///     })
///     .collect();
/// let cube: Vec<[f64; 3]> = (0..4096).map(|i| [i % 16, i / 16 % 16, i / 256].map(f64::from)).collect();
/// assert!(!measure_thickness(&sphere).unwrap().fills_volume());
/// assert!(measure_thickness(&cube).unwrap().fills_volume());
/// ```
pub fn measure_thickness(positions: &[Point<3>]) -> Option<Thickness> {
    let n = positions.len();
    if !positions.iter().flatten().all(|x| x.is_finite()) {
        return None;
    }
    let tree = Tree::new_from_slice(positions).ok()?;
    let stride = n.div_ceil(THICKNESS_SAMPLES).max(1);
    let samples: Vec<usize> = (0..n).step_by(stride).collect();
    let scales: Vec<ScaleThickness> = THICKNESS_SCALES
        .iter()
        .filter(|&&k| n >= POINTS_PER_SCALE * k)
        .filter_map(|&k| {
            let wanted = NonZero::new(k)?;
            let each: Vec<f64> = samples
                .par_iter()
                .filter_map(|&i| {
                    let around = tree
                        .query(&positions[i])
                        .nearest_n::<SquaredEuclidean<f64>>(wanted)
                        .execute();
                    let points: Vec<Point<3>> =
                        around.iter().map(|f| positions[f.item as usize]).collect();
                    neighbourhood_thickness(&points)
                })
                .collect();
            median(each).map(|thickness| ScaleThickness {
                neighbours: k,
                thickness,
            })
        })
        .collect();
    (!scales.is_empty()).then_some(Thickness { scales })
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
        let surface = measure_thickness(&sphere(40_000)).unwrap();
        assert_eq!(
            surface
                .scales
                .iter()
                .map(|s| s.neighbours)
                .collect::<Vec<_>>(),
            [32, 128, 512, 2048]
        );
        assert!(surface.thinnest().thickness < 0.01, "{surface:?}");
        assert!(!surface.fills_volume());
        // The same sphere with uniform noise of ±0.06, twice its spacing: thick at 32 neighbours,
        // thin from 512 up, where the patches are wider than the noise.
        let mut state = 7u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let noisy: Vec<Point<3>> = sphere(40_000)
            .into_iter()
            .map(|p| p.map(|x| x + 0.12 * (uniform() - 0.5)))
            .collect();
        let noisy = measure_thickness(&noisy).unwrap();
        assert!(noisy.scales[0].thickness > 0.3, "{noisy:?}");
        assert!(noisy.thinnest().thickness < 0.1, "{noisy:?}");
        assert!(!noisy.fills_volume());
        // A filled cube, and a filled brick 4 × 2 × 1: thick at every scale read.
        for size in [[1.0; 3], [4.0, 2.0, 1.0]] {
            let volume = measure_thickness(&cube(20_000, size)).unwrap();
            assert!(volume.fills_volume(), "{size:?}: {volume:?}");
        }
        // A slab 1/50 as thick as it is wide is a surface at the larger scales.
        let slab = measure_thickness(&cube(40_000, [1.0, 1.0, 0.02])).unwrap();
        assert!(!slab.fills_volume(), "{slab:?}");
        // The smallest cloud read, at its one scale.
        let small = measure_thickness(&cube(512, [1.0; 3])).unwrap();
        assert_eq!(small.scales.len(), 1);
        assert!(small.fills_volume());
        assert!(!measure_thickness(&sphere(512)).unwrap().fills_volume());
    }

    #[test]
    fn too_few_points_or_a_non_finite_one_read_nothing() {
        assert_eq!(measure_thickness(&cube(511, [1.0; 3])), None);
        let mut bad = cube(1000, [1.0; 3]);
        bad[10][2] = f64::NAN;
        assert_eq!(measure_thickness(&bad), None);
        // Every point repeated past the scale: each neighbourhood is one position.
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
