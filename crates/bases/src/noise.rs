//! How noisy a scan is: the scatter of its points about the surface they sample, measured
//! against their spacing.
//!
//! Around each point `p_i`, its `k = 16` nearest other points and itself (`m = 17` points)
//! sample a small patch of surface. Where the cloud has normals, the patch takes the nearest
//! whose normal faces the same way as the point's (`n_i · n_j > 0`, among the 32 nearest), so
//! that a thin part's two sheets, or a sharp edge's two faces, are not mixed. The patch's
//! centroid and covariance give a frame: the eigenvector of the smallest eigenvalue is its
//! normal, the other two span its tangent plane (`u`, `v`). In that frame the patch is a height
//! field, and a quadric
//!
//! ```text
//! h(u, v) = a + b u + c v + d u² + e u v + f v²
//! ```
//!
//! fitted by least squares takes up its position, tilt and curvature, so what is left is
//! what no smooth surface explains: with independent Gaussian noise of standard deviation `σ`
//! along the normal, `RSS_i / σ²` follows a χ² law with `m − 6 = 11` degrees of freedom. The
//! estimate reads the lower quartile over the patches and scales it by that law's,
//!
//! ```text
//! σ̂² = Q₀.₂₅(RSS_i) / q₀.₂₅(χ²₁₁),    q₀.₂₅(χ²₁₁) = 7.5841…,
//! ```
//!
//! consistent for Gaussian noise and robust to the patches no quadric fits whatever the noise
//! (an edge, a fold, a stray point) even where they are half the cloud: on noisy clouds the
//! median gives the same figure within 1%, but it read a sparse cube's edges as noise (200
//! random points on its faces, no normals: 0.21 of the spacing, above the threshold; the lower
//! quartile 0.15; with the faces' normals 0).
//!
//! It is compared with the **spacing** `s` (the median over the points of the mean distance to
//! their 8 nearest others, as [`crate::outliers`] measures it): the **relative scatter**
//! `σ̂ / s` is scale-free.
//!
//! **Two sheets.** Without normals, a patch on a wall thinner than about two spacings (a cup,
//! a tube, sheet metal) takes points of both faces, and their distance reads as scatter: a
//! clean 1 mm tube sampled every 1.04 mm measures 0.52 of the spacing. Each patch is therefore
//! also fitted as two parallel sheets (one quadric and an offset; the points split between the
//! sheets by alternating a fit of two parallel planes, in the frame of the sheets' own
//! covariance, with moving each point to the sheet it lies nearer, from three first splits).
//! Where that leaves under a tenth of one quadric's residual, the patch is counted
//! ([`Noise::two_sheets`]) and its scatter about its sheets is kept
//! ([`Noise::sigma_within_sheets`]: the tube 0.0007 of the spacing; with Gaussian noise of
//! 0.1 mm, 0.11). Where most patches are two sheets and clean about them,
//! [`Noise::two_sheets_explain`] says so: such a cloud is a wall sampled more coarsely than it
//! is thick, or two scans of one surface out of register — positions cannot tell which, nor
//! which face of a wall a point lies on, so normals estimated from them are unreliable there.
//! `σ̂` itself still reads the distance as scatter: for a fit, two sheets a fraction of a
//! spacing apart are as hard to follow as noise.
//!
//! Why it matters: RBF interpolation (papers 002 and 003) makes every sample a zero of the
//! field, with off-surface points along its normal. Where neighbouring samples lie at different
//! heights by more than the off-surface offset allows, the interpolant folds between them and
//! the zero set grows bubbles: on the bunny scan (34,834 points) with Gaussian position noise,
//! `zeroset reconstruct --method rbf` gives one closed surface at σ = 0.15% of the diagonal
//! (relative scatter 0.24), 3 components at 0.2% (0.30), 23 at 0.25% (0.36), 418 at 0.5%
//! (0.52); on the kitten (5,210 points) one at 0.25% (0.15), 10 at 0.5% (0.29), 49 at 0.75%.
//! MRAS (paper 004) fits each cell by least squares and averages the noise instead: one closed
//! component at every one of these levels, its mesh closer to the clean scan than RBF's; so
//! does RBF's smoothing spline with `μ` from this estimate ([`Noise::rbf_smoothing`]). Clean
//! scans measure far below the threshold [`NOISY_SCATTER`] = 0.2: the bunny 0.025, the kitten
//! 0.009, the 2,000-point bunny sample 0.049, a 1 : 1 : 0.02 ellipsoid 0 (0.20 without its
//! normals: most patches straddle both sheets) — `benches/peers/noise_peers.py` has the runs.
//!
//! The estimate is deterministic (exact nearest neighbours, a per-point fit, quantiles of
//! all) and `O(n log n)`. Clouds of more than [`MAX_PATCHES`] points are measured at every
//! `⌈n / MAX_PATCHES⌉`-th point.
//!
//! ```
//! use zeroset_bases::noise::{estimate_noise, NOISY_SCATTER};
//!
//! // A 40 × 40 grid on the plane z = 0, spacing 0.01, then the same grid moved ±0.004 along z,
//! // the sign fixed pseudo-randomly by the top bit of a multiplicative hash of the index (a
//! // standard deviation of 0.004).
//! let grid = |height: &dyn Fn(usize) -> f64| -> Vec<[f64; 3]> {
//!     (0..1600).map(|i| [(i % 40) as f64 * 0.01, (i / 40) as f64 * 0.01, height(i)]).collect()
//! };
//! let clean = estimate_noise(&grid(&|_| 0.0), None).unwrap();
//! assert!(clean.sigma < 1e-12 && !clean.is_noisy());
//! let sign = |i: usize| if (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 63 == 1 { 1.0 } else { -1.0 };
//! let noisy = estimate_noise(&grid(&|i| 0.004 * sign(i)), None).unwrap();
//! assert!((0.002..0.006).contains(&noisy.sigma), "{noisy:?}");
//! assert!(noisy.relative() > NOISY_SCATTER && noisy.is_noisy(), "{noisy:?}");
//! ```

use std::num::NonZero;

use faer::linalg::solvers::SolveLstsq;
use faer::{Mat, Side};
use kiddo::SquaredEuclidean;
use kiddo::kd_tree::KdTree;
use kiddo::leaf_strategies::FlatVec;
use kiddo::stem_strategies::Eytzinger;
use rayon::prelude::*;
use zeroset_field_core::geometry::{self, Point};

/// The neighbours of each point in its patch (the point itself makes `m = 17`).
pub const NOISE_NEIGHBOURS: usize = 16;

/// The relative scatter `σ̂ / s` above which a scan counts as noisy (see the
/// [module docs](self) for the measurements behind 0.2).
pub const NOISY_SCATTER: f64 = 0.2;

/// The most patches fitted as two sheets ([`Noise::sheet_patches`]): a share and a quartile
/// need no more, and each costs about 17 times a patch's quadric fit (three first splits,
/// rounds of plane fits and eigenvectors). `zeroset info` on the clean 1 mm cup sampled as
/// 20,000 positions, 2 threads, the whole command: 0.29 s without two-sheet fits, 0.95 s with
/// this cap; one thread with every patch fitted as two sheets, 2.4 s.
pub const SHEET_PATCHES: usize = 10_000;

/// The share of a cloud's patches that must lie on two sheets for [`Noise::two_sheets_explain`]
/// (where fewer do, a lower quartile of the rest would still read the scatter).
pub const TWO_SHEETS_SHARE: f64 = 0.5;

/// The fewest points an estimate is made from.
pub const MIN_POINTS_FOR_NOISE: usize = 64;

/// The most patches fitted: larger clouds are measured at every `⌈n / MAX_PATCHES⌉`-th point
/// (their neighbours taken from the whole cloud).
pub const MAX_PATCHES: usize = 100_000;

/// A quadric whose least-squares matrix has a pivot below this fraction of its largest (points
/// on a conic, or on two or three scan lines) has a coefficient the patch does not determine,
/// which would soak up a residual: the patch is left out.
const RANK_TOLERANCE: f64 = 1e-8;

/// The neighbours the spacing averages over (as [`crate::outliers::OUTLIER_NEIGHBOURS`]).
const SPACING_NEIGHBOURS: usize = crate::outliers::OUTLIER_NEIGHBOURS;

/// The quadric's coefficients.
const QUADRIC_TERMS: usize = 6;

/// The quantile of the patches' residual sums of squares the estimate reads.
const QUANTILE: f64 = 0.25;

/// The same quantile of the χ² law with `NOISE_NEIGHBOURS + 1 − QUADRIC_TERMS = 11` degrees of
/// freedom (scipy.stats.chi2.ppf(0.25, 11)).
const CHI2_QUANTILE: f64 = 7.584_142_785_441_285;

/// A patch whose second tangent direction spreads less than this fraction of its first (in
/// variance) is a line of points, on which no quadric is determined: it is left out.
const FLAT_PATCH: f64 = 1e-4;

pub(crate) type Tree = KdTree<f64, u32, Eytzinger, FlatVec<f64, u32, 3, 32>, 3, 32>;

/// The constant of [`Noise::rbf_smoothing`]. Measured by sweeping `μ` over 0.003…3 on three
/// scans with Gaussian position noise (σ per axis, a fraction of the diagonal) and taking the
/// `μ` whose mesh lies nearest the clean surface (median vertex distance; the bunny's to
/// `bun_zipper.ply`, the kitten's to the mesh of its clean points): the best `μ` over
/// `(σ̂/s)² · diagonal` was 0.9 (bunny, 0.25%), 1.4 (bunny, 0.5%), 1.2–3.4 (bunny, 1%), 0.8–2.3
/// (its 2,000-point sample, 0.5%), 2.7 (kitten, 0.5%), 2.9 (kitten, 0.75%). The optimum is flat:
/// 2 puts every one of these within 10% of its best median distance, and one closed component
/// where interpolation made 10 to 904.
pub const RBF_SMOOTHING_SCALE: f64 = 2.0;

/// What [`estimate_noise`] measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// `σ̂`: the points' scatter about a smooth surface, in the cloud's units.
    pub sigma: f64,
    /// `s`: the median of the points' mean distance to their 8 nearest others.
    pub spacing: f64,
    /// The patches the quantile was taken over (those not degenerate).
    pub patches: usize,
    /// Of the [`sheet_patches`](Self::sheet_patches), those two parallel sheets explain far
    /// better than one surface: the two faces of a wall thinner than a patch is wide, or two
    /// scans of one surface out of register (see [`Noise::two_sheets_explain`]).
    pub two_sheets: usize,
    /// The patches fitted as two sheets: where `σ̂` reads noisy
    /// ([`is_noisy`](Self::is_noisy)), every `⌈patches / SHEET_PATCHES⌉`-th
    /// ([`SHEET_PATCHES`]); 0 otherwise.
    pub sheet_patches: usize,
    /// `σ̂` over the [`sheet_patches`](Self::sheet_patches), with each that
    /// [`two_sheets`](Self::two_sheets) counts measured about its two sheets: the scatter left
    /// if the sheets are surfaces in their own right (`σ̂` itself where the reading is not
    /// noisy).
    pub sigma_within_sheets: f64,
}

impl Noise {
    /// The relative scatter `σ̂ / s` (0 when the spacing is 0, which [`estimate_noise`] never
    /// returns).
    pub fn relative(&self) -> f64 {
        if self.spacing > 0.0 {
            self.sigma / self.spacing
        } else {
            0.0
        }
    }

    /// Whether the relative scatter exceeds [`NOISY_SCATTER`]: too noisy to interpolate.
    pub fn is_noisy(&self) -> bool {
        self.relative() > NOISY_SCATTER
    }

    /// The share of the [`sheet_patches`](Self::sheet_patches) that
    /// [`two_sheets`](Self::two_sheets) counts (0 where none were fitted as two sheets).
    pub fn two_sheet_share(&self) -> f64 {
        if self.sheet_patches > 0 {
            self.two_sheets as f64 / self.sheet_patches as f64
        } else {
            0.0
        }
    }

    /// Whether a noisy reading is explained by two sheets rather than scatter: the cloud
    /// [`is_noisy`](Self::is_noisy), at least [`TWO_SHEETS_SHARE`] of its patches lie on two
    /// parallel sheets, and about those sheets it is clean
    /// ([`sigma_within_sheets`](Self::sigma_within_sheets) at most [`NOISY_SCATTER`] of the
    /// spacing). Such a cloud is a thin wall sampled more coarsely than it is thick (a cup, a
    /// tube, sheet metal), or scans of one surface out of register; positions alone cannot
    /// tell which, nor which side of a thin wall a point lies on.
    pub fn two_sheets_explain(&self) -> bool {
        self.is_noisy()
            && self.two_sheet_share() >= TWO_SHEETS_SHARE
            && self.sigma_within_sheets <= NOISY_SCATTER * self.spacing
    }

    /// The smoothing `μ` of a biharmonic (`r`) RBF fit
    /// ([`RbfFit::with_smoothing`](crate::rbf::RbfFit::with_smoothing)) of a scan with this
    /// noise of an object of size `extent` ([`object_size`]; the box diagonal of a scan of one
    /// object):
    ///
    /// ```text
    /// μ = RBF_SMOOTHING_SCALE · (σ̂ / s)² · extent.
    /// ```
    ///
    /// `μ` is a length, so it scales with the scan; constant terms of the kernel matrix do not
    /// matter (the weights sum to 0), its spread does, and that is set by the object's size.
    /// The square of the relative scatter is the noise power against the sampling. See
    /// [`RBF_SMOOTHING_SCALE`] for the measurements behind it. With the whole scene's
    /// diagonal instead of the object's, two noisy kittens 20 apart (each 1.37 across) were
    /// smoothed 15× as hard as one: each lost its handle (Euler characteristic 0 → 2) and 9%
    /// of its area.
    pub fn rbf_smoothing(&self, extent: f64) -> f64 {
        RBF_SMOOTHING_SCALE * self.relative().powi(2) * extent
    }
}

/// The noise of a scan's positions (see the [module docs](self)), its patches made of the
/// neighbours whose normal faces the same way as the point's where `normals` are given (one per
/// point, finite, not all zero; otherwise they are not used; a zero normal, which some writers
/// put where a point has none, faces every way). `None` for fewer than
/// [`MIN_POINTS_FOR_NOISE`] points, a coordinate that is not finite, a cloud where fewer
/// than half the patches span a surface (points on a line, or all coincident), or a median
/// spacing of 0 (most points repeated 8 or more times).
pub fn estimate_noise(positions: &[Point<3>], normals: Option<&[Point<3>]>) -> Option<Noise> {
    estimate_noise_over(positions, normals, MAX_PATCHES)
}

/// [`estimate_noise`] fitting at most `max_patches` patches.
pub(crate) fn estimate_noise_over(
    positions: &[Point<3>],
    normals: Option<&[Point<3>]>,
    max_patches: usize,
) -> Option<Noise> {
    let n = positions.len();
    let finite = |v: &[Point<3>]| v.iter().flatten().all(|x| x.is_finite());
    if n < MIN_POINTS_FOR_NOISE || !finite(positions) {
        return None;
    }
    // Normals that are not one per point, or not finite, or all zero, are not used.
    let is_zero = |v: &Point<3>| v.iter().all(|&x| x == 0.0);
    let normals = normals.filter(|v| v.len() == n && finite(v) && !v.iter().all(is_zero));
    let tree = Tree::new_from_slice(positions).ok()?;
    // With normals, twice the neighbours to choose the patch's from.
    let wanted = if normals.is_some() { 2 } else { 1 } * NOISE_NEIGHBOURS + 1;
    let k = NonZero::new(wanted)?;
    // Every `stride`-th point's patch (all of them up to MAX_PATCHES points): a quantile needs
    // no more, and `zeroset info` stays quick on clouds of millions.
    let stride = n.div_ceil(max_patches.max(1));
    let queries: Vec<usize> = (0..n).step_by(stride).collect();
    let local: Vec<(f64, Option<Fitted>)> = queries
        .par_iter()
        .map(|&i| {
            let others: Vec<usize> = nearest_others(&tree, positions, i, k)
                .into_iter()
                .map(|j| j as usize)
                .collect();
            let spacing = others
                .iter()
                .take(SPACING_NEIGHBOURS)
                .map(|&j| geometry::distance(&positions[i], &positions[j]))
                .sum::<f64>()
                / others.len().clamp(1, SPACING_NEIGHBOURS) as f64;
            // The patch: the nearest that face the same way (the same sheet of a thin part).
            // (A zero normal, none there, faces every way.)
            let facing = |j: &usize| {
                normals.is_none_or(|v| {
                    geometry::dot(&v[i], &v[*j]) > 0.0 || is_zero(&v[i]) || is_zero(&v[*j])
                })
            };
            let mut patch = vec![i as u32];
            patch.extend(
                others
                    .iter()
                    .filter(|j| facing(j))
                    .take(NOISE_NEIGHBOURS)
                    .map(|&j| j as u32),
            );
            let fit = (patch.len() == NOISE_NEIGHBOURS + 1)
                .then(|| patch_fit(&points_of(positions, &patch), false))
                .flatten();
            (spacing, fit.map(|f| (f.rss, patch)))
        })
        .collect();
    let spacing = median(local.iter().map(|l| l.0).collect())?;
    let fitted: Vec<&Fitted> = local.iter().filter_map(|l| l.1.as_ref()).collect();
    // Half the points on 8 or more copies of themselves leave no spacing to compare with.
    if 2 * fitted.len() < local.len() || spacing <= 0.0 {
        return None;
    }
    let patches = fitted.len();
    let sigma_of = |sums: Vec<f64>| Some((quantile(sums, QUANTILE)? / CHI2_QUANTILE).sqrt());
    let sigma = sigma_of(fitted.iter().map(|f| f.0).collect())?;
    // Two sheets only where the reading is noisy: elsewhere they change nothing it says (and
    // each costs about 17 quadric fits), and on every `⌈patches / SHEET_PATCHES⌉`-th.
    let (two_sheets, sheet_patches, sigma_within_sheets) = if sigma > NOISY_SCATTER * spacing {
        let tried: Vec<&Fitted> = fitted
            .iter()
            .step_by(patches.div_ceil(SHEET_PATCHES))
            .copied()
            .collect();
        let sheets: Vec<Option<f64>> = tried
            .par_iter()
            .map(|(_, patch)| patch_fit(&points_of(positions, patch), true)?.two_sheets)
            .collect();
        // Two sheets fit one parameter more: scaled to the χ² law of one quadric's residual.
        let dof = (NOISE_NEIGHBOURS + 1 - QUADRIC_TERMS) as f64;
        let within = tried
            .iter()
            .zip(&sheets)
            .map(|(f, s)| s.map_or(f.0, |s| s * dof / (dof - 1.0)))
            .collect();
        let two = sheets.iter().flatten().count();
        (two, tried.len(), sigma_of(within)?)
    } else {
        (0, 0, sigma)
    };
    Some(Noise {
        sigma,
        spacing,
        patches,
        two_sheets,
        sheet_patches,
        sigma_within_sheets,
    })
}

/// A patch fitted by one quadric: its residual sum of squares and its points' indices.
type Fitted = (f64, Vec<u32>);

/// The points of `positions` that `indices` name.
fn points_of(positions: &[Point<3>], indices: &[u32]) -> Vec<Point<3>> {
    indices.iter().map(|&j| positions[j as usize]).collect()
}

/// Neighbours closer than this many times the spacing join one piece in [`object_size`]: far
/// enough to bridge a scan's sparse stretches and small holes, near enough that objects a
/// few spacings apart stay apart.
pub const OBJECT_LINK: f64 = 6.0;

/// The most neighbours [`object_size`] links each point to (the nearest within its reach):
/// enough to reach the next scan line where lines lie 10 times closer along than across.
pub const OBJECT_NEIGHBOURS: usize = 32;

/// Points whose links [`object_size`] finds in parallel at a time (bounded work space).
const OBJECT_BLOCK: usize = 1 << 16;

/// The size of the object a scan mostly samples: the bounding-box diagonal of the connected
/// piece that holds the median point, the pieces ordered by their diagonals. A point is linked
/// to its [`OBJECT_NEIGHBOURS`] nearest others within [`OBJECT_LINK`] times `spacing` (the
/// scan's, [`Noise::spacing`]); linked points are one piece. For a scan of one object it is
/// the object's box diagonal (stray pieces hold few points); for several objects apart, the
/// median point's object's, not the scene's: [`Noise::rbf_smoothing`]'s length scale. Where
/// two pieces of different sizes hold about half the points each, the answer follows the one
/// that holds the median point, so a few points can switch it. `None` for fewer than 2
/// points, a coordinate that is not finite, or a spacing that is not positive and finite.
///
/// Deterministic: the neighbours are found in parallel, the pieces joined in index order.
///
/// ```
/// use zeroset_bases::noise::object_size;
///
/// // Two 10 × 10 grids of spacing 0.1 (diagonal ≈ 1.27), 100 apart.
/// let grid = |x0: f64| (0..100).map(move |i| [x0 + (i % 10) as f64 * 0.1, (i / 10) as f64 * 0.1, 0.0]);
/// let points: Vec<[f64; 3]> = grid(0.0).chain(grid(100.0)).collect();
/// let size = object_size(&points, 0.1).unwrap();
/// assert!((size - 0.9 * 2f64.sqrt()).abs() < 1e-12, "{size}");
/// ```
pub fn object_size(positions: &[Point<3>], spacing: f64) -> Option<f64> {
    let n = positions.len();
    if n < 2 || !(spacing.is_finite() && spacing > 0.0) {
        return None;
    }
    if !positions.iter().flatten().all(|x| x.is_finite()) {
        return None;
    }
    let tree = Tree::new_from_slice(positions).ok()?;
    let k = NonZero::new(OBJECT_NEIGHBOURS + 1)?;
    let reach = (OBJECT_LINK * spacing).powi(2);
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut links = vec![u32::MAX; OBJECT_BLOCK.min(n) * OBJECT_NEIGHBOURS];
    for start in (0..n).step_by(OBJECT_BLOCK) {
        let block = OBJECT_BLOCK.min(n - start);
        links[..block * OBJECT_NEIGHBOURS]
            .par_chunks_mut(OBJECT_NEIGHBOURS)
            .enumerate()
            .for_each(|(b, out)| {
                let i = start + b;
                out.fill(u32::MAX);
                let found = tree
                    .query(&positions[i])
                    .nearest_n::<SquaredEuclidean<f64>>(k)
                    .within(reach)
                    .execute();
                let near = found
                    .into_iter()
                    .map(|f| f.item)
                    .filter(|&j| j as usize != i);
                for (slot, j) in out.iter_mut().zip(near) {
                    *slot = j;
                }
            });
        for (b, near) in links[..block * OBJECT_NEIGHBOURS]
            .chunks(OBJECT_NEIGHBOURS)
            .enumerate()
        {
            for &j in near.iter().take_while(|&&j| j != u32::MAX) {
                let (a, c) = (root(&mut parent, (start + b) as u32), root(&mut parent, j));
                if a != c {
                    parent[a.max(c) as usize] = a.min(c);
                }
            }
        }
    }
    // Each piece's box and point count, then the piece of the median point by diagonal.
    let mut pieces: std::collections::BTreeMap<u32, (Point<3>, Point<3>, usize)> =
        std::collections::BTreeMap::new();
    for (i, p) in positions.iter().enumerate() {
        let r = root(&mut parent, i as u32);
        let (lo, hi, count) = pieces.entry(r).or_insert((*p, *p, 0));
        *lo = std::array::from_fn(|a| lo[a].min(p[a]));
        *hi = std::array::from_fn(|a| hi[a].max(p[a]));
        *count += 1;
    }
    let mut sized: Vec<(f64, usize)> = pieces
        .values()
        .map(|(lo, hi, count)| (geometry::distance(lo, hi), *count))
        .collect();
    sized.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut seen = 0;
    for (diagonal, count) in sized {
        seen += count;
        if 2 * seen >= n {
            return Some(diagonal);
        }
    }
    None
}

/// The root of `i`'s piece in the union–find forest `parent` (halving the path on the way).
/// The `wanted` points of `tree` nearest to `positions[i]`, nearest first, ties by index, less
/// `i` itself. (Which of the points tied at the last distance come back is kiddo's choice; a
/// tree built serially makes it the same every run.)
pub(crate) fn nearest_others(
    tree: &Tree,
    positions: &[Point<3>],
    i: usize,
    wanted: NonZero<usize>,
) -> Vec<u32> {
    let mut found = tree
        .query(&positions[i])
        .nearest_n::<SquaredEuclidean<f64>>(wanted)
        .execute();
    found.sort_by(|a, b| a.distance.total_cmp(&b.distance).then(a.item.cmp(&b.item)));
    found
        .iter()
        .map(|f| f.item)
        .filter(|&j| j as usize != i)
        .collect()
}

pub(crate) fn root(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        parent[i as usize] = parent[parent[i as usize] as usize];
        i = parent[i as usize];
    }
    i
}

/// The quadric height field fitted to `patch` in its principal frame, and where `sheets` asks,
/// two parallel sheets ([`PatchFit`]); `None` for a patch that does not span a surface.
fn patch_fit(patch: &[Point<3>], sheets: bool) -> Option<PatchFit> {
    let m = patch.len();
    let centroid = patch
        .iter()
        .fold([0.0; 3], |s, p| geometry::add(&s, p))
        .map(|x| x / m as f64);
    let centred: Vec<Point<3>> = patch.iter().map(|p| geometry::sub(p, &centroid)).collect();
    let covariance = Mat::<f64>::from_fn(3, 3, |r, c| {
        centred.iter().map(|p| p[r] * p[c]).sum::<f64>() / m as f64
    });
    let eigen = covariance.self_adjoint_eigen(Side::Lower).ok()?;
    let (values, frame) = (eigen.S().column_vector(), eigen.U());
    // Ascending: the normal, then the tangent directions (the widest last).
    let (narrow, wide) = (values[1], values[2]);
    if !(wide > 0.0 && narrow > FLAT_PATCH * wide) {
        return None;
    }
    // Coordinates scaled by the patch's size, for a well-conditioned fit.
    let unit = wide.sqrt();
    let axis = |p: &Point<3>, j: usize| (0..3).map(|r| p[r] * frame[(r, j)]).sum::<f64>() / unit;
    let design = Mat::<f64>::from_fn(m, QUADRIC_TERMS, |r, c| {
        let (u, v) = (axis(&centred[r], 2), axis(&centred[r], 1));
        [1.0, u, v, u * u, u * v, v * v][c]
    });
    let heights = Mat::<f64>::from_fn(m, 1, |r, _| axis(&centred[r], 0));
    let coefficients = determined_lstsq(&design, &heights)?;
    let residual = &heights - &design * &coefficients;
    let residual: Vec<f64> = residual.col(0).iter().copied().collect();
    let rss = residual.iter().map(|r| r * r).sum::<f64>();
    if !rss.is_finite() {
        return None;
    }
    let two = sheets
        .then(|| two_sheets(&centred, unit, &heights, &residual))
        .flatten()
        .filter(|&(sheets, offset)| {
            sheets <= SHEETS_RATIO * rss && offset.abs() >= SHEETS_MIN_OFFSET
        })
        .map(|(sheets, _)| sheets * wide);
    Some(PatchFit {
        rss: rss * wide,
        two_sheets: two,
    })
}

/// The least-squares solution of `design · x ≈ heights` by column-pivoted QR, or `None` where
/// a pivot is at most [`RANK_TOLERANCE`] of the largest (a coefficient the points do not
/// determine, which would soak up a residual).
fn determined_lstsq(design: &Mat<f64>, heights: &Mat<f64>) -> Option<Mat<f64>> {
    let qr = design.col_piv_qr();
    let pivots: Vec<f64> = (0..design.ncols()).map(|j| qr.R()[(j, j)].abs()).collect();
    let largest = pivots.iter().copied().fold(0.0, f64::max);
    if pivots
        .iter()
        .any(|&p| p.is_nan() || p <= RANK_TOLERANCE * largest)
    {
        return None;
    }
    Some(qr.solve_lstsq(heights))
}

/// A patch's quadric fit ([`patch_fit`]).
#[derive(Debug, Clone, Copy)]
struct PatchFit {
    /// The residual sum of squares of one quadric.
    rss: f64,
    /// Where two parallel sheets were asked for and explain the patch (one quadric and an
    /// offset between the sheets, leaving at most [`SHEETS_RATIO`] of `rss`, the sheets at
    /// least [`SHEETS_MIN_OFFSET`] apart): their residual sum of squares.
    two_sheets: Option<f64>,
}

/// The fewest points of a patch on either of two sheets.
const MIN_SHEET: usize = 4;

/// Two sheets explain a patch where they leave at most this fraction of one quadric's residual
/// sum of squares. Gaussian noise split at its best into two groups keeps about a third
/// (`1 − 2/π` for a large patch), and under a tenth in 2–4% of patches of 17 (the bunny, its
/// 2,000-point sample, the kitten with Gaussian noise of 0.25% or 0.5% of the diagonal per
/// axis, 2.3–3.6%; at 0.05, 0.05–0.2%); the faces of a 1 mm tube or cup sampled every 1.04 mm
/// leave 10⁻⁶ of it, and with Gaussian noise of 0.1 mm 0.7–0.76 of their patches are under a
/// tenth (0.53–0.58 under 0.05), at 0.2 mm 0.26.
const SHEETS_RATIO: f64 = 0.1;

/// Two sheets explain a patch only where they lie at least this far apart, in units of the
/// patch's standard deviation along its widest tangent direction (about a point spacing):
/// a clean patch's tiny residuals split any way.
const SHEETS_MIN_OFFSET: f64 = 0.1;

/// Rounds of moving each point to the sheet it lies nearer in [`two_sheets`].
const SHEET_ROUNDS: usize = 6;

/// The best fit found of two parallel sheets to the `centred` patch, in units of `unit`: its
/// residual sum of squares and the offset between the sheets, or `None` where no split leaves
/// [`MIN_SHEET`] points on each sheet. From each of three first splits — at the largest gap
/// between the one quadric's sorted `residual`s, by their sign, and by the sign of the
/// `heights` above the patch's plane (its centroid lies between its sheets) — it alternates:
/// the frame from the covariance of each sheet's points about their own centroid (the
/// patch's own covariance mixes in the distance between the sheets and can tilt its plane
/// towards it), one quadric and an offset fitted in that frame, each point moved to the sheet
/// it lies nearer; for up to [`SHEET_ROUNDS`] rounds.
fn two_sheets(
    centred: &[Point<3>],
    unit: f64,
    heights: &Mat<f64>,
    residual: &[f64],
) -> Option<(f64, f64)> {
    let m = residual.len();
    if m < 2 * MIN_SHEET {
        return None;
    }
    let mut sorted = residual.to_vec();
    sorted.sort_by(f64::total_cmp);
    let cut = (MIN_SHEET..=m - MIN_SHEET)
        .max_by(|&a, &b| (sorted[a] - sorted[a - 1]).total_cmp(&(sorted[b] - sorted[b - 1])))?;
    let threshold = 0.5 * (sorted[cut] + sorted[cut - 1]);
    let starts: [Vec<bool>; 3] = [
        residual.iter().map(|&r| r > threshold).collect(),
        residual.iter().map(|&r| r > 0.0).collect(),
        (0..m).map(|r| heights[(r, 0)] > 0.0).collect(),
    ];
    let mut best: Option<(f64, f64)> = None;
    for start in starts {
        if let Some((rss, offset)) = refine_sheets(centred, unit, start)
            && best.is_none_or(|(b, _)| rss < b)
        {
            best = Some((rss, offset));
        }
    }
    best
}

/// [`two_sheets`] from one first split `upper`: the split refined with two parallel planes
/// (stiff enough that a point put on the wrong sheet lies off it), then one quadric and an
/// offset fitted to the last split.
fn refine_sheets(centred: &[Point<3>], unit: f64, mut upper: Vec<bool>) -> Option<(f64, f64)> {
    for _ in 0..SHEET_ROUNDS {
        let (_, offset, heights, fitted) = fit_sheets(centred, unit, &upper, PLANE_TERMS)?;
        // Each point to the sheet it lies nearer: its height above the lower sheet against
        // half the offset.
        let moved: Vec<bool> = (0..upper.len())
            .map(|r| {
                let lower = fitted[r] - if upper[r] { offset } else { 0.0 };
                (heights[r] - lower - 0.5 * offset) * offset.signum() > 0.0
            })
            .collect();
        if moved == upper {
            break;
        }
        upper = moved;
    }
    let (rss, offset, ..) = fit_sheets(centred, unit, &upper, QUADRIC_TERMS)?;
    Some((rss, offset))
}

/// The terms of a plane `a + b u + c v`: the first of the quadric's.
const PLANE_TERMS: usize = 3;

/// Two parallel sheets fitted to the `centred` patch split by `upper`: the frame from the
/// covariance of each sheet's points about their own centroid, the first `terms` of the
/// quadric and an offset for the upper sheet fitted to the heights in it (coordinates in units
/// of `unit`). Returns the residual sum of squares, the offset, the heights and the fitted
/// heights; `None` where a sheet has fewer than [`MIN_SHEET`] points or the fit is not
/// determined.
fn fit_sheets(
    centred: &[Point<3>],
    unit: f64,
    upper: &[bool],
    terms: usize,
) -> Option<(f64, f64, Vec<f64>, Vec<f64>)> {
    let m = upper.len();
    let on_upper = upper.iter().filter(|&&u| u).count();
    if on_upper < MIN_SHEET || m - on_upper < MIN_SHEET {
        return None;
    }
    let mut sums = [[0.0; 3]; 2];
    for (p, &u) in centred.iter().zip(upper) {
        sums[usize::from(u)] = geometry::add(&sums[usize::from(u)], p);
    }
    let counts = [(m - on_upper) as f64, on_upper as f64];
    let centres = [0, 1].map(|s| sums[s].map(|x| x / counts[s]));
    let within = Mat::<f64>::from_fn(3, 3, |r, c| {
        centred
            .iter()
            .zip(upper)
            .map(|(p, &u)| {
                let q = geometry::sub(p, &centres[usize::from(u)]);
                q[r] * q[c]
            })
            .sum::<f64>()
    });
    let eigen = within.self_adjoint_eigen(Side::Lower).ok()?;
    let frame = eigen.U();
    let axis = |p: &Point<3>, j: usize| (0..3).map(|r| p[r] * frame[(r, j)]).sum::<f64>() / unit;
    let design = Mat::<f64>::from_fn(m, terms + 1, |r, c| {
        let (u, v) = (axis(&centred[r], 2), axis(&centred[r], 1));
        if c == terms {
            if upper[r] { 1.0 } else { 0.0 }
        } else {
            [1.0, u, v, u * u, u * v, v * v][c]
        }
    });
    let heights = Mat::<f64>::from_fn(m, 1, |r, _| axis(&centred[r], 0));
    let coefficients = determined_lstsq(&design, &heights)?;
    let fitted = &design * &coefficients;
    let heights: Vec<f64> = heights.col(0).iter().copied().collect();
    let fitted: Vec<f64> = fitted.col(0).iter().copied().collect();
    let rss = heights
        .iter()
        .zip(&fitted)
        .map(|(h, f)| (h - f).powi(2))
        .sum::<f64>();
    rss.is_finite()
        .then_some((rss, coefficients[(terms, 0)], heights, fitted))
}

/// The median (the mean of the two middle values for an even count); `None` when empty.
pub(crate) fn median(values: Vec<f64>) -> Option<f64> {
    quantile(values, 0.5)
}

/// The `p`-quantile, linear between the sorted values at positions `p (n − 1)` (the median's
/// rule for `p = ½`); `None` when empty.
fn quantile(mut values: Vec<f64>, p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let at = p * (values.len() - 1) as f64;
    let (low, high) = (at.floor() as usize, at.ceil() as usize);
    Some(values[low] + (at - low as f64) * (values[high] - values[low]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `n` points of a Fibonacci lattice on the sphere of radius `r`.
    fn sphere(n: usize, r: f64) -> Vec<Point<3>> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let s = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                [r * s * t.cos(), r * s * t.sin(), r * z]
            })
            .collect()
    }

    /// `points` moved by independent Gaussian noise of standard deviation `sigma` per axis.
    fn jitter(points: &[Point<3>], sigma: f64, seed: u64) -> Vec<Point<3>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Box–Muller: one standard normal per uniform pair.
        let mut gaussian = || {
            let (a, b): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        points
            .iter()
            .map(|p| p.map(|x| x + sigma * gaussian()))
            .collect()
    }

    /// The diagonal of the bounding box of `points`.
    fn box_diagonal(points: &[Point<3>]) -> f64 {
        let (mut lo, mut hi) = (points[0], points[0]);
        for p in points {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        geometry::distance(&lo, &hi)
    }

    #[test]
    fn the_object_size_is_the_median_points_objects_not_the_scenes() {
        // One noisy sphere: its own box diagonal.
        let one = jitter(&sphere(3000, 1.0), 0.01, 1);
        let spacing = estimate_noise(&one, None).unwrap().spacing;
        let size = object_size(&one, spacing).unwrap();
        assert_eq!(size, box_diagonal(&one));
        // With a smaller sphere of fewer points 50 away, and two stray points between: still
        // the big sphere's (it holds the median point); the scene's diagonal is 14× larger.
        let mut scene = one.clone();
        scene.extend(sphere(1000, 0.3).iter().map(|p| [p[0] + 50.0, p[1], p[2]]));
        scene.extend([[20.0, 0.0, 0.0], [30.0, 1.0, 0.0]]);
        let spacing = estimate_noise(&scene, None).unwrap().spacing;
        assert_eq!(object_size(&scene, spacing), Some(size));
        assert!(box_diagonal(&scene) > 14.0 * size);
        // Most points on the small sphere: the small sphere's.
        let mut small_first: Vec<Point<3>> = sphere(5000, 0.3);
        small_first.extend(one.iter().map(|p| [p[0] + 50.0, p[1], p[2]]));
        let spacing = estimate_noise(&small_first, None).unwrap().spacing;
        let small = box_diagonal(&sphere(5000, 0.3));
        assert!((object_size(&small_first, spacing).unwrap() - small).abs() < 1e-12);
        // A plane scanned in lines 10 times closer along than across: one piece.
        let lines: Vec<Point<3>> = (0..40 * 400)
            .map(|i| [(i % 400) as f64 * 0.001, (i / 400) as f64 * 0.01, 0.0])
            .collect();
        // (The spacing, the mean distance to the 8 nearest, is 0.0025: ±1…4 along a line; the
        // patches span no surface, so the noise estimate is None.)
        assert_eq!(object_size(&lines, 0.0025), Some(box_diagonal(&lines)));
        // The same on one thread as on three.
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| object_size(&scene, 0.05))
        };
        assert_eq!(on(1), on(3));
        // Nothing to measure.
        assert_eq!(object_size(&one[..1], spacing), None);
        assert_eq!(object_size(&one, 0.0), None);
        assert_eq!(object_size(&one, f64::NAN), None);
        let mut bad = one.clone();
        bad[7][1] = f64::INFINITY;
        assert_eq!(object_size(&bad, spacing), None);
    }

    #[test]
    fn a_clean_curved_surface_measures_almost_no_scatter() {
        // The quadric takes up the sphere's curvature: what is left is its quartic term.
        let noise = estimate_noise(&sphere(4000, 1.0), None).unwrap();
        assert!(noise.relative() < 0.01, "{noise:?}");
        assert_eq!(noise.patches, 4000);
        // The lattice's step √(4π/n) ≈ 0.056; 8 neighbours' mean lies a little beyond it.
        assert!((0.05..0.09).contains(&noise.spacing), "{noise:?}");
    }

    #[test]
    fn the_noise_of_a_jittered_sphere_is_recovered() {
        // Noise along the normal has the standard deviation of one axis; the tangential part
        // hardly moves the heights.
        for sigma in [0.002, 0.005, 0.01] {
            let noise = estimate_noise(&jitter(&sphere(8000, 1.0), sigma, 3), None).unwrap();
            let error = (noise.sigma - sigma).abs() / sigma;
            assert!(error < 0.15, "σ = {sigma}: {noise:?}");
        }
    }

    #[test]
    fn the_estimate_is_scale_free_and_the_threshold_separates_clean_from_noisy() {
        let clean = sphere(6000, 1.0);
        let noisy = jitter(&clean, 0.02, 5);
        for scale in [1e-4, 1.0, 1e5] {
            let shrink = |p: &[Point<3>]| -> Vec<Point<3>> {
                p.iter()
                    .map(|q| q.map(|x| x * scale + 3.0 * scale))
                    .collect()
            };
            let (a, b) = (
                estimate_noise(&shrink(&clean), None).unwrap(),
                estimate_noise(&shrink(&noisy), None).unwrap(),
            );
            assert!(!a.is_noisy() && b.is_noisy(), "scale {scale}: {a:?} {b:?}");
            assert!(
                (b.sigma / scale - 0.02).abs() < 0.004,
                "scale {scale}: {b:?}"
            );
        }
    }

    #[test]
    fn with_normals_a_thin_part_is_measured_one_sheet_at_a_time() {
        // A 1 : 1 : 0.02 ellipsoid (8,000 points): its two sheets lie closer than a patch is
        // wide, so patches of the nearest points straddle both and look like noise; patches of
        // the neighbours facing the same way see one smooth sheet.
        let c = 0.02;
        let points: Vec<Point<3>> = sphere(8000, 1.0)
            .iter()
            .map(|p| [p[0], p[1], c * p[2]])
            .collect();
        let normals: Vec<Point<3>> = points
            .iter()
            .map(|p| [p[0], p[1], p[2] / (c * c)])
            .collect();
        let blind = estimate_noise(&points, None).unwrap();
        let facing = estimate_noise(&points, Some(&normals)).unwrap();
        assert!(blind.relative() > 0.1, "{blind:?}");
        assert!(facing.relative() < 0.01, "{facing:?}");
        // Normals of another length, or not finite, are not used.
        assert_eq!(estimate_noise(&points, Some(&normals[1..])), Some(blind));
    }

    /// `n` points spread over a tube of radius `r` and height 2 (a Fibonacci-like lattice in
    /// angle and height), without its ends.
    fn tube(n: usize, r: f64) -> Vec<Point<3>> {
        let golden = (5f64.sqrt() - 1.0) / 2.0;
        (0..n)
            .map(|i| {
                let t = std::f64::consts::TAU * (i as f64 * golden).fract();
                let z = 2.0 * (i as f64 + 0.5) / n as f64 - 1.0;
                [r * t.cos(), r * t.sin(), z]
            })
            .collect()
    }

    #[test]
    fn a_wall_thinner_than_the_sampling_is_read_as_two_sheets_not_noise() {
        // Both faces of a tube wall 0.02 thick (radii 1 and 1.02), each face 6,000 points: a
        // spacing of about 0.04, twice the wall. Without normals the patches straddle both
        // faces and the distance reads as scatter; two sheets explain it.
        let mut wall = tube(6000, 1.0);
        wall.extend(tube(6000, 1.02).iter().map(|p| [p[0], p[1], p[2] + 0.013]));
        let clean = estimate_noise(&wall, None).unwrap();
        assert!(clean.is_noisy(), "{clean:?}");
        assert!(clean.two_sheet_share() > 0.6, "{clean:?}");
        assert!(
            clean.sigma_within_sheets < 0.01 * clean.spacing,
            "{clean:?}"
        );
        assert!(clean.two_sheets_explain(), "{clean:?}");
        // With Gaussian noise of 0.002 per axis (0.1 of the wall): still two sheets, and the
        // scatter about them is the noise's.
        let noisy = estimate_noise(&jitter(&wall, 0.002, 21), None).unwrap();
        assert!(noisy.two_sheets_explain(), "{noisy:?}");
        let error = noisy.sigma_within_sheets / 0.002 - 1.0;
        assert!(error.abs() < 0.2, "{noisy:?}");
        // One face alone is one clean sheet.
        let face = estimate_noise(&tube(6000, 1.0), None).unwrap();
        assert!(!face.is_noisy() && !face.two_sheets_explain(), "{face:?}");
    }

    #[test]
    fn gaussian_noise_is_not_read_as_two_sheets() {
        // A sphere with noise of 0.3 to 0.6 of its spacing: a few patches split well by
        // chance, far from the half that two_sheets_explain asks for, and the scatter about
        // them is the noise's.
        for (sigma, seed) in [(0.015, 1), (0.03, 2)] {
            let noise = estimate_noise(&jitter(&sphere(8000, 1.0), sigma, seed), None).unwrap();
            assert!(noise.is_noisy(), "{noise:?}");
            assert!(noise.two_sheet_share() < 0.06, "{noise:?}");
            assert!(!noise.two_sheets_explain(), "{noise:?}");
            assert!(noise.sigma_within_sheets > 0.9 * noise.sigma, "{noise:?}");
        }
    }

    #[test]
    fn degenerate_clouds_have_no_estimate() {
        // Too few points, a point that is not finite, all on a line, all the same.
        assert!(estimate_noise(&sphere(40, 1.0), None).is_none());
        let mut bad = sphere(200, 1.0);
        bad[7][1] = f64::NAN;
        assert!(estimate_noise(&bad, None).is_none());
        let line: Vec<Point<3>> = (0..200).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        assert!(estimate_noise(&line, None).is_none());
        assert!(estimate_noise(&vec![[1.0, 2.0, 3.0]; 100], None).is_none());
    }

    #[test]
    fn a_large_cloud_measured_at_every_kth_point_agrees_with_all_of_it() {
        let points = jitter(&sphere(12_000, 1.0), 0.01, 4);
        let all = estimate_noise_over(&points, None, usize::MAX).unwrap();
        let some = estimate_noise_over(&points, None, 1_500).unwrap();
        assert_eq!((all.patches, some.patches), (12_000, 1_500));
        assert!(
            (some.sigma / all.sigma - 1.0).abs() < 0.1,
            "{all:?} {some:?}"
        );
        assert!(
            (some.spacing / all.spacing - 1.0).abs() < 0.05,
            "{all:?} {some:?}"
        );
    }

    #[test]
    fn patches_across_two_scan_lines_still_measure_the_noise() {
        // Two parallel rows of 100 points, 0.001 apart along x, 0.004 apart in y, with Gaussian
        // heights of standard deviation 0.0005: every patch holds points of both rows only, on
        // which the v² column nearly repeats 1 and v. The estimate is still the heights'.
        let rows: Vec<Point<3>> = (0..200)
            .map(|i| [(i % 100) as f64 * 0.001, (i / 100) as f64 * 0.004, 0.0])
            .collect();
        let noisy: Vec<Point<3>> = jitter(&rows, 0.0005, 11)
            .iter()
            .zip(&rows)
            .map(|(j, p)| [p[0], p[1], j[2]])
            .collect();
        let noise = estimate_noise(&noisy, None).unwrap();
        assert!((noise.sigma / 0.0005 - 1.0).abs() < 0.25, "{noise:?}");
    }

    #[test]
    fn one_and_several_threads_agree_bit_for_bit() {
        let points = jitter(&sphere(3000, 1.0), 0.01, 9);
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| estimate_noise(&points, None))
        };
        assert_eq!(on(1), on(3));
    }
}
