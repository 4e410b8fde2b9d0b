//! Stray samples of an oriented scan: points off the surface the rest of the cloud samples,
//! found before a fit so that they do not become surface.
//!
//! A point's *spacing* `s_i` is the mean distance to its `k = 8` nearest other points; on a
//! scanned surface it is about the sampling step there. Its neighbours describe the surface
//! around it: their unit normals' resultant `L = |Σ n_j| / k` (near 1 where they agree), their
//! mean direction `n̄`, their centroid `c`; the point's own normal agrees with them when
//! `n_i · n̄ ≥ 0.8`, and it lies on their plane when `|(p_i − c) · n̄| ≤ s_i / 2`. A point is an
//! **outlier** when
//!
//! - it is **isolated**, `s_i > ratio · median_j s_j` (`ratio` 3 by default: a neighbourhood
//!   at least 9× sparser, per unit area, than the typical one), unless it looks like a sparsely
//!   scanned patch of surface: `L ≥ 0.8`, its normal agrees and it lies on their plane; or
//! - it **floats off** a clean patch: `L ≥ 0.8`, yet its normal does not agree and it does not
//!   lie on their plane — a stray sample near the surface, whose spacing looks like the scan's.
//!
//! Where the neighbours' normals disagree (edges, thin shells seen from both sides, noisy
//! normals) only the first rule applies, and only to isolated points.
//!
//! Why a fit needs this: a method that makes every sample a zero of the field with the sample's
//! normal as its gradient (MRAS, paper 004; RBF interpolation) grows a sheet or a blob around
//! each stray sample, the size of the cell that fits it. On the bunny scan with 2% of points
//! added uniformly in its box with random normals, `zeroset reconstruct` made 117 components
//! with open sheets (RBF; MRAS 23); Open3D's screened Poisson, which integrates the normals,
//! kept the bunny. With the outliers this module finds set aside (none of the scan's points),
//! both keep the bunny (`benches/peers/stray_peers.py` has the figures). On the clean bunny,
//! kitten and `bunny_2k` samples it finds none; on thin or noisy synthetic shapes the second
//! rule takes a handful of real points where the surface folds within a spacing (at most 15 of
//! 30,000 on a 1 : 1 : 0.005 ellipsoid), which the fit does not miss among their neighbours.
//!
//! The rule is local and scale-free (no distance in the cloud's units), deterministic (exact
//! k-nearest neighbours, a per-point rule, the median of all spacings), and `O(n log n)`.
//!
//! ```
//! use zeroset_bases::outliers::{find_outliers, DEFAULT_OUTLIER_RATIO};
//!
//! // A 20 × 20 grid on the plane z = 0 with normals +z, one point far above it and one just
//! // above it with a normal of its own.
//! let mut positions: Vec<[f64; 3]> = (0..400)
//!     .map(|i| [(i % 20) as f64 * 0.01, (i / 20) as f64 * 0.01, 0.0])
//!     .collect();
//! let mut normals = vec![[0.0, 0.0, 1.0]; 400];
//! positions.extend([[0.1, 0.1, 0.08], [0.055, 0.155, 0.012]]);
//! normals.extend([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
//! let found = find_outliers(&positions, &normals, DEFAULT_OUTLIER_RATIO);
//! assert_eq!(found.indices, vec![400, 401]);
//! assert_eq!((found.isolated, found.floating), (1, 1));
//! ```

use std::num::NonZero;

use kiddo::SquaredEuclidean;
use kiddo::kd_tree::KdTree;
use kiddo::leaf_strategies::FlatVec;
use kiddo::stem_strategies::Eytzinger;
use rayon::prelude::*;
use zeroset_field_core::geometry::{self, Point, add, dot, norm, scale, sub};
use zeroset_field_core::{PointCloud, Result};

/// Neighbours a point's spacing is measured over (`k`).
pub const OUTLIER_NEIGHBOURS: usize = 8;
/// The default `ratio`: isolated means a spacing more than 3× the median (a neighbourhood at
/// least 9× sparser). On the samples shipped with zeroset the largest spacing is 1.9× the
/// median (bunny), 1.1× (kitten); a flattened ellipsoid's rim (1 : 1 : 0.02, 8,000 points)
/// reached 2×, where its curvature also defeats the surface test, so 2 would cut its rim.
pub const DEFAULT_OUTLIER_RATIO: f64 = 3.0;
/// Clouds with fewer distinct points than this are not filtered: too few for a median spacing
/// to mean a sampling step.
pub const MIN_POINTS_FOR_OUTLIERS: usize = 64;
/// The agreement (cosine) the surface test asks of the neighbours' normals and the point's.
const AGREEMENT: f64 = 0.8;
/// The largest offset from the neighbours' plane, in units of the point's spacing.
const PLANE_OFFSET: f64 = 0.5;
/// [`find_isolated`] keeps an isolated point whose neighbours' covariance has its smallest
/// eigenvalue at most this fraction of the middle one (a plane) and that lies on that plane. Of
/// the 296 isolated strays (spacing above 3× the median) among 348 added uniformly to the
/// bunny's box (1% of its points), 3 pass at
/// 0.01, 18 at 0.05, 35 at 0.1.
pub const SPARSE_PLANE: f64 = 0.01;

/// A k-d tree over 3-D points, items their indices.
pub(crate) type Tree = KdTree<f64, u32, Eytzinger, FlatVec<f64, u32, 3, 32>, 3, 32>;

/// Whether `ratio` is a ratio [`find_outliers`] takes as an option: 0 (off) or finite and at
/// least 1.5 (below, most of a surface's points would be isolated).
pub fn valid_ratio(ratio: f64) -> bool {
    ratio == 0.0 || (ratio.is_finite() && ratio >= 1.5)
}

/// What [`find_outliers`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Outliers {
    /// The outliers' indices into the positions given, increasing.
    pub indices: Vec<usize>,
    /// Of them, the isolated ones (the first rule of the [module docs](self)).
    pub isolated: usize,
    /// Of them, those floating off a clean patch of surface (the second rule).
    pub floating: usize,
    /// Points isolated by the spacing rule but kept as a sparse patch of surface.
    pub kept_sparse: usize,
    /// The median spacing (mean distance to the `k` nearest points), in the cloud's units;
    /// 0 for a cloud too small to filter.
    pub median_spacing: f64,
}

/// The outliers of an oriented cloud (see the [module docs](self)): points whose spacing exceeds
/// `ratio` times the median and that do not lie on a surface with their neighbours, and points
/// off a clean patch of surface with a normal of their own.
///
/// `positions` must be finite, `normals` finite and non-zero (any length), one per point.
/// Exact duplicates count as neighbours at distance 0 (merge them first for the spacing of
/// distinct samples). `ratio ≤ 0`, fewer than [`MIN_POINTS_FOR_OUTLIERS`] points, or normals of
/// another length: nothing is found.
pub fn find_outliers(positions: &[Point<3>], normals: &[Point<3>], ratio: f64) -> Outliers {
    let n = positions.len();
    let Some(tree) = index(positions, ratio).filter(|_| normals.len() == n) else {
        return Outliers::none(0.0);
    };
    let local: Vec<Neighbourhood> = (0..n)
        .into_par_iter()
        .map(|i| {
            let others =
                nearest_others(&tree, positions, i).map(|j| (&positions[j], unit(&normals[j])));
            Neighbourhood::new(&positions[i], &unit(&normals[i]), others)
        })
        .collect();
    let median = median(local.iter().map(|l| l.spacing).collect());
    let limit = ratio * median;
    let mut found = Outliers::none(median);
    for (i, l) in local.iter().enumerate() {
        let agree = l.agreement >= AGREEMENT;
        let on_patch = l.resultant >= AGREEMENT && agree && l.on_plane;
        if l.spacing > limit {
            if on_patch {
                found.kept_sparse += 1;
            } else {
                found.indices.push(i);
                found.isolated += 1;
            }
        } else if l.resultant >= AGREEMENT && !agree && !l.on_plane {
            found.indices.push(i);
            found.floating += 1;
        }
    }
    found
}

/// The isolated points of a cloud without normals: those whose spacing exceeds `ratio` times
/// the median (the first rule of the [module docs](self)) unless their neighbours lie on a
/// plane and they lie on it too — the positions' own version of that rule's exception for
/// sparse patches of surface (a far wall of a terrestrial scan, sampled more coarsely with
/// range): the neighbours' smallest covariance eigenvalue at most [`SPARSE_PLANE`] of the
/// middle one, the point within half its spacing of their plane. For normals that will be
/// *estimated* from the positions: an isolated point's estimated normal is the plane of other
/// stray points, which agrees with theirs by construction, so a group of stray points would
/// pass for a sparse patch. On the bunny scan with 1% of points added uniformly in its box and
/// no normals, `zeroset reconstruct` kept 11 of them that way (an open mesh of 12
/// components, one a sheet out to the box); with this filter first (293 of the 348 found, none
/// of the scan's points; 3 more isolated ones pass for a plane here and the fit's own test sets
/// them aside), the bunny closed (Euler characteristic 2) and 7 small closed blobs around
/// strays near the surface, whose spacing looks like the scan's.
///
/// Same input conditions as [`find_outliers`]; `isolated`, `kept_sparse` and `indices` are
/// set. A median spacing of 0 (most points repeated) finds nothing.
///
/// ```
/// use zeroset_bases::outliers::{find_isolated, DEFAULT_OUTLIER_RATIO};
///
/// let mut positions: Vec<[f64; 3]> = (0..400)
///     .map(|i| [(i % 20) as f64 * 0.01, (i / 20) as f64 * 0.01, 0.0])
///     .collect();
/// positions.push([0.1, 0.1, 0.5]);
/// assert_eq!(find_isolated(&positions, DEFAULT_OUTLIER_RATIO).indices, vec![400]);
/// ```
pub fn find_isolated(positions: &[Point<3>], ratio: f64) -> Outliers {
    let n = positions.len();
    let Some(tree) = index(positions, ratio) else {
        return Outliers::none(0.0);
    };
    let spacing: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            let others: Vec<f64> = nearest_others(&tree, positions, i)
                .map(|j| geometry::distance(&positions[i], &positions[j]))
                .collect();
            others.iter().sum::<f64>() / others.len().max(1) as f64
        })
        .collect();
    let median = median(spacing.clone());
    let mut found = Outliers::none(median);
    if median <= 0.0 {
        return found;
    }
    let on_plane = |i: usize| {
        let others: Vec<Point<3>> = nearest_others(&tree, positions, i)
            .map(|j| positions[j])
            .collect();
        sparse_plane(&positions[i], &others, spacing[i])
    };
    for i in (0..n).filter(|&i| spacing[i] > ratio * median) {
        if on_plane(i) {
            found.kept_sparse += 1;
        } else {
            found.indices.push(i);
        }
    }
    found.isolated = found.indices.len();
    found
}

/// Whether `others` lie on a plane (their covariance's smallest eigenvalue at most
/// [`SPARSE_PLANE`] of the middle one) and `p` within half of `spacing` of it.
fn sparse_plane(p: &Point<3>, others: &[Point<3>], spacing: f64) -> bool {
    let m = others.len() as f64;
    if m < 3.0 {
        return false;
    }
    let c = others
        .iter()
        .fold([0.0; 3], |s, q| add(&s, q))
        .map(|x| x / m);
    let covariance = faer::Mat::<f64>::from_fn(3, 3, |r, k| {
        others
            .iter()
            .map(|q| (q[r] - c[r]) * (q[k] - c[k]))
            .sum::<f64>()
    });
    let Ok(eigen) = covariance.self_adjoint_eigen(faer::Side::Lower) else {
        return false;
    };
    let (values, frame) = (eigen.S().column_vector(), eigen.U());
    // Ascending: the plane's normal first.
    if !(values[1] > 0.0 && values[0] <= SPARSE_PLANE * values[1]) {
        return false;
    }
    let normal = [frame[(0, 0)], frame[(1, 0)], frame[(2, 0)]];
    dot(&sub(p, &c), &normal).abs() <= PLANE_OFFSET * spacing
}

/// The search tree of `positions`, or `None` where nothing is to be found: `ratio` off (≤ 0 or
/// NaN), fewer than [`MIN_POINTS_FOR_OUTLIERS`] points, or more than `u32::MAX` (the only
/// clouds that fail to index).
fn index(positions: &[Point<3>], ratio: f64) -> Option<Tree> {
    if ratio.is_nan() || ratio <= 0.0 || positions.len() < MIN_POINTS_FOR_OUTLIERS {
        return None;
    }
    Tree::new_from_slice(positions).ok()
}

/// The median of `values` (not empty), the mean of the middle two for an even count.
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    0.5 * (values[(n - 1) / 2] + values[n / 2])
}

/// The (at most) [`OUTLIER_NEIGHBOURS`] nearest other points of point `i`.
fn nearest_others<'a>(
    tree: &Tree,
    positions: &'a [Point<3>],
    i: usize,
) -> impl Iterator<Item = usize> + 'a {
    let k = NonZero::new(OUTLIER_NEIGHBOURS + 1).unwrap_or(NonZero::<usize>::MIN);
    tree.query(&positions[i])
        .nearest_n::<SquaredEuclidean<f64>>(k)
        .execute()
        .into_iter()
        .map(|f| f.item as usize)
        .filter(move |&j| j != i)
        .take(OUTLIER_NEIGHBOURS)
}

impl Outliers {
    /// Nothing found, at median spacing `median_spacing`.
    fn none(median_spacing: f64) -> Self {
        Self {
            indices: Vec::new(),
            isolated: 0,
            floating: 0,
            kept_sparse: 0,
            median_spacing,
        }
    }
}

/// What a point's `k` nearest neighbours say of it (see the [module docs](self)).
struct Neighbourhood {
    /// `s_i`: the mean distance to them.
    spacing: f64,
    /// `L = |Σ n_j| / k`: 1 where their normals agree (0 without neighbours).
    resultant: f64,
    /// `n_i · n̄`.
    agreement: f64,
    /// `|(p_i − c) · n̄| ≤ s_i / 2`.
    on_plane: bool,
}

impl Neighbourhood {
    /// Of point `p` with unit normal `normal`, from its neighbours' positions and unit
    /// normals.
    fn new<'a>(
        p: &Point<3>,
        normal: &Point<3>,
        neighbours: impl Iterator<Item = (&'a Point<3>, Point<3>)>,
    ) -> Self {
        let (mut sum, mut centroid, mut distance, mut count) = ([0.0; 3], [0.0; 3], 0.0, 0usize);
        for (q, nq) in neighbours {
            sum = add(&sum, &nq);
            centroid = add(&centroid, q);
            distance += geometry::distance(p, q);
            count += 1;
        }
        let spacing = distance / count.max(1) as f64;
        let length = norm(&sum);
        if length == 0.0 {
            // No neighbours, or normals that cancel: nothing agrees, nothing is on a plane.
            return Self {
                spacing,
                resultant: 0.0,
                agreement: 0.0,
                on_plane: false,
            };
        }
        let mean = scale(1.0 / length, &sum);
        let offset = dot(&sub(p, &scale(1.0 / count as f64, &centroid)), &mean);
        Self {
            spacing,
            resultant: length / count as f64,
            agreement: dot(normal, &mean),
            on_plane: offset.abs() <= PLANE_OFFSET * spacing,
        }
    }
}

/// `cloud` without the outliers [`find_outliers`] finds in it at `ratio`, and what it found
/// (indices into `cloud`). A cloud without normals, or with a coordinate or normal that is
/// not finite (for the fit's own checks to report), is returned whole.
///
/// # Errors
/// Only those of [`PointCloud::from_raw`] for the points kept, which cannot arise for a cloud
/// whose normals match its positions.
pub fn remove_outliers(cloud: &PointCloud<3>, ratio: f64) -> Result<(PointCloud<3>, Outliers)> {
    let whole = || Outliers::none(0.0);
    let Some(normals) = cloud.normals() else {
        return Ok((cloud.clone(), whole()));
    };
    let finite = |v: &[Point<3>]| v.iter().flatten().all(|x| x.is_finite());
    if !(finite(cloud.positions()) && finite(normals)) {
        return Ok((cloud.clone(), whole()));
    }
    let found = find_outliers(cloud.positions(), normals, ratio);
    Ok((without(cloud, &found.indices)?, found))
}

/// `cloud` without the points at `indices` (its normals, if any, follow their points).
///
/// # Errors
/// Only those of [`PointCloud::from_raw`], which cannot arise for a cloud whose normals match
/// its positions.
pub fn without<const D: usize>(cloud: &PointCloud<D>, indices: &[usize]) -> Result<PointCloud<D>> {
    if indices.is_empty() {
        return Ok(cloud.clone());
    }
    let mut keep = vec![true; cloud.len()];
    for &i in indices {
        if let Some(k) = keep.get_mut(i) {
            *k = false;
        }
    }
    let kept = |v: &[Point<D>]| -> Vec<Point<D>> {
        v.iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(p, _)| *p)
            .collect()
    };
    PointCloud::from_raw(kept(cloud.positions()), cloud.normals().map(kept))
}

/// `v / |v|` (`v` itself where it is zero).
fn unit(v: &Point<3>) -> Point<3> {
    let l = norm(v);
    if l > 0.0 { v.map(|x| x / l) } else { *v }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn isolated_points_without_normals_spare_a_sparse_plane() {
        // A dense sphere (3,000 points, spacing about 0.06), a far wall sampled 5× as coarsely
        // (a 12 × 12 grid of step 0.3 at x = 4, gently curved), and 20 strays scattered
        // between them.
        let (mut positions, _) = sphere(3000);
        let wall: Vec<Point<3>> = (0..144)
            .map(|i| {
                let (y, z) = ((i % 12) as f64 * 0.3 - 1.65, (i / 12) as f64 * 0.3 - 1.65);
                [4.0 + 0.01 * (y * y + z * z), y, z]
            })
            .collect();
        positions.extend(&wall);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let strays: Vec<Point<3>> = (0..20)
            .map(|_| {
                let r: [f64; 3] = [rng.random(), rng.random(), rng.random()];
                [1.5 + 2.0 * r[0], 3.0 * r[1] - 1.5, 3.0 * r[2] - 1.5]
            })
            .collect();
        positions.extend(&strays);
        let found = find_isolated(&positions, DEFAULT_OUTLIER_RATIO);
        assert!(found.indices.iter().all(|&i| i >= 3144), "{found:?}");
        assert!(found.indices.len() >= 18, "{found:?}");
        assert!(found.kept_sparse >= 140, "{found:?}");
        // Most points repeated: the median spacing is 0 and nothing is found.
        let mut repeated = vec![[0.0, 0.0, 0.0]; 100];
        repeated.push([5.0, 5.0, 5.0]);
        assert!(
            find_isolated(&repeated, DEFAULT_OUTLIER_RATIO)
                .indices
                .is_empty()
        );
    }

    /// Points on the unit sphere with their outward normals, a Fibonacci lattice.
    fn sphere(n: usize) -> (Vec<Point<3>>, Vec<Point<3>>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let p: Vec<Point<3>> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                [r * t.cos(), r * t.sin(), z]
            })
            .collect();
        (p.clone(), p)
    }

    #[test]
    fn a_clean_sphere_has_no_outliers() {
        let (p, n) = sphere(4000);
        let found = find_outliers(&p, &n, DEFAULT_OUTLIER_RATIO);
        assert!(found.indices.is_empty(), "{found:?}");
        // The Fibonacci sphere's step is √(4π/n) ≈ 0.056; the mean of 8 neighbours lies a
        // little beyond it.
        assert!(
            (0.05..0.09).contains(&found.median_spacing),
            "{}",
            found.median_spacing
        );
    }

    #[test]
    fn points_scattered_in_the_box_are_found_and_the_surface_is_kept() {
        let (mut p, mut n) = sphere(4000);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        // 80 points (2%) uniform in the box [−1.2, 1.2]³ farther than 0.3 from the sphere,
        // with random normals.
        let mut added = Vec::new();
        while added.len() < 80 {
            let q: Point<3> = std::array::from_fn(|_| rng.random_range(-1.2..1.2));
            if (norm(&q) - 1.0).abs() > 0.3 {
                added.push(p.len());
                p.push(q);
                n.push(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            }
        }
        let found = find_outliers(&p, &n, DEFAULT_OUTLIER_RATIO);
        assert_eq!(found.indices, added, "{found:?}");
        // The rule off: nothing.
        assert!(find_outliers(&p, &n, 0.0).indices.is_empty());
    }

    #[test]
    fn points_floating_just_off_the_surface_with_normals_of_their_own_are_found() {
        // 4,000 sphere points (step ≈ 0.056) and 40 more 0.08–0.15 outside it, above sphere
        // points spread over it: not isolated (their spacing is below 3× the median). With
        // normals at right angles to the sphere's they float off it: outliers. With the
        // sphere's own normal there (a point displaced by position noise) they are kept.
        let (p, n) = sphere(4000);
        let (mut crossed, mut crossed_n) = (p.clone(), n.clone());
        let (mut along, mut along_n) = (p.clone(), n.clone());
        for k in 0..40 {
            let d = p[k * 100 + 50];
            let r = 1.08 + 0.01 * (k % 8) as f64;
            let side = unit(&[d[1], -d[0], 0.0]);
            crossed.push(d.map(|v| v * r));
            crossed_n.push(side);
            along.push(d.map(|v| v * r));
            along_n.push(d);
        }
        let found = find_outliers(&crossed, &crossed_n, DEFAULT_OUTLIER_RATIO);
        assert_eq!(found.indices, (4000..4040).collect::<Vec<_>>(), "{found:?}");
        assert_eq!((found.isolated, found.floating), (0, 40));
        let kept = find_outliers(&along, &along_n, DEFAULT_OUTLIER_RATIO);
        assert!(kept.indices.is_empty(), "{kept:?}");
    }

    #[test]
    fn a_sparsely_sampled_patch_of_surface_is_kept() {
        // A sphere sampled 25× more sparsely (5× the step) on its upper cap: the cap's points
        // are isolated by spacing, but their neighbours' normals agree and they lie on their
        // plane, so none is an outlier.
        let (p, n) = sphere(16_000);
        let keep: Vec<usize> = (0..p.len())
            .filter(|&i| p[i][2] < 0.5 || i % 25 == 0)
            .collect();
        let (p, n): (Vec<_>, Vec<_>) = keep.iter().map(|&i| (p[i], n[i])).unzip();
        let found = find_outliers(&p, &n, DEFAULT_OUTLIER_RATIO);
        assert!(found.kept_sparse > 80, "{found:?}");
        // At most the odd point on the border between the densities.
        assert!(found.indices.len() <= 5, "{found:?}");
        // The same cap with random normals: outliers.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let scrambled: Vec<Point<3>> = p
            .iter()
            .zip(&n)
            .map(|(q, m)| {
                if q[2] > 0.55 {
                    std::array::from_fn(|_| rng.random_range(-1.0..1.0))
                } else {
                    *m
                }
            })
            .collect();
        let found = find_outliers(&p, &scrambled, DEFAULT_OUTLIER_RATIO);
        assert!(found.indices.len() > 80, "{}", found.indices.len());
    }

    #[test]
    fn small_or_mismatched_input_is_left_alone() {
        let (p, n) = sphere(MIN_POINTS_FOR_OUTLIERS - 1);
        assert!(find_outliers(&p, &n, 3.0).indices.is_empty());
        let (p, n) = sphere(100);
        assert!(find_outliers(&p, &n[..99], 3.0).indices.is_empty());
        assert!(find_outliers(&p, &n, f64::NAN).indices.is_empty());
    }

    #[test]
    fn the_result_does_not_depend_on_the_thread_count() {
        let (mut p, mut n) = sphere(3000);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..60 {
            p.push(std::array::from_fn(|_| rng.random_range(-1.5..1.5)));
            n.push(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
        }
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| find_outliers(&p, &n, DEFAULT_OUTLIER_RATIO))
        };
        assert_eq!(run(1), run(3));
    }
}
