//! Outward normals for a scan that has none: local planes, oriented consistently over the
//! cloud (Hoppe, DeRose, Duchamp, McDonald & Stuetzle 1992, §3.2–3.3).
//!
//! Every fit in zeroset needs oriented normals; many scans (LiDAR, photogrammetry, an `x y z`
//! export) come without them. Two steps:
//!
//! **Tangent planes (§3.2).** Around each point `p_i`, its `k` nearest others and itself give a
//! centroid `o_i` and a covariance
//!
//! ```text
//! C_i = Σ_{y ∈ Nbhd(p_i)} (y − o_i)(y − o_i)ᵀ,
//! ```
//!
//! whose eigenvector of the smallest eigenvalue is the plane's normal `n_i`, up to its sign.
//! A patch whose middle eigenvalue is below [`LINE_PATCH`] of its largest (its points on a line
//! or one point repeated) spans no plane: the point is **undetermined** and takes the oriented
//! normal of its neighbour in the propagation below (a piece with no plane at all, such as
//! a heap of copies of one point, takes its nearest large piece's normals).
//!
//! **Orientation (§3.3).** Neighbouring planes of a smooth surface are nearly parallel, so the
//! signs are propagated along the edges where that holds best: the graph joining each point to
//! its `k` nearest (Hoppe's Riemannian graph without its Euclidean minimum spanning tree, see
//! below), each edge costing
//!
//! ```text
//! c_ij = 1 − |n_i · n_j| + ½ (|n_i · ê_ij| + |n_j · ê_ij|),    ê_ij = (p_j − p_i)/‖p_j − p_i‖,
//! ```
//!
//! its minimum spanning forest (Kruskal), walked breadth-first from a root, each point's sign
//! chosen so that `n_child · n_parent > 0`. Hoppe's cost is the first term. The second is
//! zeroset's: an edge along the surface runs in both tangent planes (`n · ê ≈ 0`), an edge
//! across a thin part — from one sheet to the other, whose planes are parallel too, so that
//! Hoppe's cost takes them for neighbours and makes both sheets face the same way — runs
//! along the normals (`|n · ê| ≈ 1`) and is avoided. On a closed box 1 × 1 × 0.04 sampled
//! about every 0.02 (its two large faces 2 spacings apart) Hoppe's cost alone turned one face
//! inward (half of their points); with the second term none of the points whose plane is
//! right (all but 1% whose patch straddles both sheets) is (a test). Thinner
//! still, the planes themselves fail (at 1.5 spacings a fifth of the patches straddle both
//! sheets and stand up) and no propagation can help.
//!
//! **Which way is out.** The walk fixes the signs within each connected piece of the graph up
//! to one sign per piece. By the divergence theorem `∮ (x − c) · n dA = 3V > 0` for the outward
//! normal of a closed surface, so a piece of at least [`MIN_PIECE`] points is flipped where
//! `Σ_i (p_i − c) · n_i < 0`, `c` its centroid (a sum over the samples standing in for the
//! integral; it also holds for a one-sided scan of a convex-ish object, whose normals point
//! away from its middle). Hoppe instead forces the topmost point's normal to `+z`: one noisy
//! sample can turn a whole piece inside out. A smaller piece (a stray clump, a few points
//! beyond a gap in the scan) is too small to read its inside from: it takes the sign that
//! agrees best with the normals of its points' nearest points in the large pieces. Separate
//! objects are separate pieces, each oriented on its own — this is why the pieces are not
//! joined by Hoppe's spanning tree, whose long edges would carry one object's sign to another.
//! A piece inside another — a hollow solid's inner wall — is the wall of a cavity: turned
//! outward it faced into the solid, and the fit filled the cavity (a shell of radii 1 and 0.7
//! came out a ball, its volume 5.63 for 2.75). A large piece whose box lies in another's,
//! whose points lie at least 90% behind that piece's nearest points (`(x − p)·n_p < 0`), and
//! around which that piece has points in every direction (64 directions, within 15° of each,
//! seen from 8 of its points) is inside it; nested an odd number of times it is turned to face
//! inward ([`EstimatedNormals::nested`]). A cavity with an opening wider than about 15° as
//! seen from inside it is left facing outward, as is any piece in a bowl.
//!
//! **Limits.** A scan of one side of a flat or nearly flat surface (a wall, terrain) has no
//! inside to read, its divergence about 0 (under [`FLAT_DIVERGENCE`] of `Σ ‖p − c‖`): such a
//! piece is turned by a convention instead, its mean normal's largest component positive
//! (terrain with `z` up faces up), and listed ([`EstimatedNormals::flat`]). A scan from inside
//! a closed space (a room) comes out facing away from the scanner, as the outside of that
//! space. For both, give where the scanner stood ([`NormalOptions::viewpoint`]): each large
//! piece then faces it.
//!
//! **Each point towards its own scanner.** A scanner records only surface that faces it, so
//! where it is known for every point (an E57 file's scan origins: a scene taken from several
//! stations), the sign needs no propagation: [`estimate_normals_from_scanners`] turns each
//! point's normal so that `n_i · (s_i − p_i) > 0`, `s_i` where the scanner that recorded `p_i`
//! stood. Only where the plane's line is nearly across the line of sight (`|cos| <`
//! [`GRAZING_COSINE`], incidence beyond 75.5°, where a few degrees of error in the plane would
//! turn the sign) do the signs come from the neighbours instead: propagated along the spanning
//! forest, breadth-first from the points signed by their scanner. A piece with no such point
//! keeps its sign by the pieces' rule above (its normals' mean cosine towards the scanners).
//! This is what makes two-sided thin parts come out right: a board 1.5 spacings thick scanned
//! from both faces, whose two sheets the forest joins, comes out with one face inward when
//! each piece is signed whole, with every point facing its scanner this way (a test).
//! Thin parts sampled more coarsely than their thickness mix the two sheets in their planes
//! (the 2,000-point bunny sample: one ear, 2.85% of its points, turned inward).
//!
//! Deterministic: exact nearest neighbours (the returned ones ordered by distance, then
//! index; kiddo picks which of the points tied at the last distance come back, the same every
//! run), per-point planes, edges sorted by cost then by index, so the same bits on any number
//! of threads. `O(n k log(n k))` time; memory about `40 + 20 k` bytes a point at most
//! (neighbours and edges; `zeroset normals` on 10⁶ torus points at `k = 16`: 0.44 GB peak in all,
//! 5 s on 2 threads).
//!
//! H. Hoppe, T. DeRose, T. Duchamp, J. McDonald, W. Stuetzle, "Surface reconstruction from
//! unorganized points", SIGGRAPH 1992.
//!
//! ```
//! use zeroset_bases::normals::{estimate_normals, NormalOptions};
//!
//! // 800 points on the unit sphere, no normals.
//! let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
//! let points: Vec<[f64; 3]> = (0..800)
//!     .map(|i| {
//!         let z = 1.0 - 2.0 * (i as f64 + 0.5) / 800.0;
//!         let r = (1.0 - z * z).sqrt();
//!         [r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z]
//!     })
//!     .collect();
//! let estimated = estimate_normals(&points, &NormalOptions::default())?;
//! // Outward everywhere: along the position, within 2°.
//! for (p, n) in points.iter().zip(&estimated.normals) {
//!     let cos = p[0] * n[0] + p[1] * n[1] + p[2] * n[2];
//!     assert!(cos > 2f64.to_radians().cos(), "{p:?} {n:?}");
//! }
//! assert_eq!(estimated.pieces, 1);
//! # Ok::<(), zeroset_bases::normals::NormalError>(())
//! ```

use std::collections::VecDeque;
use std::num::NonZero;

use faer::{Mat, Side};
use kiddo::SquaredEuclidean;
use rayon::prelude::*;
use zeroset_field_core::geometry::{self, Point};

use crate::noise::{Noise, Tree, estimate_noise_over, nearest_others, root};

mod rays;
pub use rays::{RAYS, RayVotes};

/// The neighbours each point's plane is fitted to by default (the point itself makes 17).
pub const NORMAL_NEIGHBOURS: usize = 16;

/// The neighbours each point's plane is fitted to by [`default_neighbours`] on a noisy scan
/// (its relative scatter above [`NOISY_SCATTER`](crate::noise::NOISY_SCATTER)). More points average the noise in each plane
/// where 16 let it tilt them past the propagation: normals turned the wrong way (against the
/// scan's own) from 16 / 32 neighbours on the bunny (34,834 points) with Gaussian noise of
/// σ = 0.25%, 0.5%, 0.75%, 1% of the diagonal (relative scatter about 0.26, 0.52, 0.8, 1.0):
/// 9 / 3, 508 / 91, 2,197 / 408, 6,387 / 1,658; the kitten (5,210 points) at the same σ
/// (0.15 to 0.58): 0 / 0, 0 / 0, 5 / 1, 12 / 5. (48 and 64 did no better over both.)
pub const NOISY_NORMAL_NEIGHBOURS: usize = 32;

/// The patches [`default_neighbours`] measures the noise on, at most: a quantile needs no more
/// (10,000 of them give the scatter within a few percent), and the measure stays a small part
/// of the estimate (without a cap it doubled `zeroset normals` on the 34,834-point bunny).
pub const NOISE_PATCHES: usize = 10_000;

/// The fewest neighbours [`NormalOptions::neighbours`] takes: a plane needs three points.
pub const MIN_NEIGHBOURS: usize = 2;

/// The most neighbours [`NormalOptions::neighbours`] takes (the graph holds `n·k` edges).
pub const MAX_NEIGHBOURS: usize = 256;

/// A patch whose middle eigenvalue is at most this fraction of its largest spans no plane.
pub const LINE_PATCH: f64 = 1e-6;

/// Pieces of the neighbour graph with at least this many points are signed by their own
/// divergence; smaller ones by their nearest points in the larger pieces.
pub const MIN_PIECE: usize = 64;

/// A large piece turned outward whose divergence `Σ (p − c)·n` is below this fraction of
/// `Σ ‖p − c‖` is flat: it has no inside to read its sign from, and is turned by convention
/// instead ([`FlatPiece`]). The fraction is 1 for a sphere, 0.88 for a one-sided scan of half
/// of one, 0.38 of a 30° cap, 0.13 of a 10° cap; for a sheet `z = a sin 3x cos 2y` over the
/// unit square (one hill) it is about `a`: 0.05 where its relief is 5% of its width, 0.19 at
/// 20%, where it reads as the hill it is.
pub const FLAT_DIVERGENCE: f64 = 0.1;

/// A flat piece's normals also agree: their mean has at least this length (1 for a plane; 0
/// for a closed surface, which a thin plate or a long rod, of divergence under
/// [`FLAT_DIVERGENCE`] of their spread, are; 0.64 for one side of a pipe, 0.90 for a quarter
/// of it; 0.98 for rolling terrain).
pub const FLAT_AGREEMENT: f64 = 0.9;

/// A flat piece's points also lie near a plane: the smallest eigenvalue of their covariance
/// is at most this fraction of the middle one (0.005–0.008 for terrain whose relief is 3–5% of
/// its width; 0.045 for a quarter of a pipe's side, 1 for a rod).
pub const FLAT_PLANARITY: f64 = 0.01;

/// How far `normals` point away from the middle of `positions`: `Σ (p − c)·n / Σ ‖p − c‖`, `c`
/// the points' centroid — by the divergence theorem about 1 for outward normals on a closed
/// surface sampled evenly, about −1 for inward ones, near 0 for a flat sheet
/// ([`FLAT_DIVERGENCE`]). 0 where the points are all at one position or the lengths differ.
///
/// ```
/// use zeroset_bases::normals::outwardness;
///
/// let points = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]];
/// assert_eq!(outwardness(&points, &points), 1.0);
/// let inward: Vec<[f64; 3]> = points.iter().map(|p| p.map(|x| -x)).collect();
/// assert_eq!(outwardness(&points, &inward), -1.0);
/// ```
#[must_use]
pub fn outwardness(positions: &[Point<3>], normals: &[Point<3>]) -> f64 {
    if positions.is_empty() || positions.len() != normals.len() {
        return 0.0;
    }
    let centroid = positions
        .iter()
        .fold([0.0; 3], |s, p| geometry::add(&s, p))
        .map(|x| x / positions.len() as f64);
    let (divergence, spread) = positions
        .iter()
        .zip(normals)
        .fold((0.0, 0.0), |(d, s), (p, n)| {
            let r = geometry::sub(p, &centroid);
            (d + geometry::dot(&r, n), s + geometry::norm(&r))
        });
    if spread > 0.0 {
        divergence / spread
    } else {
        0.0
    }
}

/// A large piece too flat to have an inside (a wall, terrain, a sheet scanned from one side:
/// divergence under [`FLAT_DIVERGENCE`] of its spread, normals agreeing to
/// [`FLAT_AGREEMENT`], points on a plane to [`FLAT_PLANARITY`]). Its sign is a convention: its mean normal's largest component is
/// made positive (a horizontal sheet faces `+z`, a wall facing along x faces `+x`). Give
/// [`NormalOptions::viewpoint`] to choose the side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatPiece {
    /// Its points.
    pub points: usize,
    /// Its normals' mean direction (unit), after the convention.
    pub facing: Point<3>,
}

/// [`estimate_normals_from_scanners`] signs a point by its own scanner where its plane's normal
/// makes at least this cosine (in absolute value) with the direction to the scanner (incidence
/// up to 75.5°); at more grazing incidence, by its neighbours.
pub const GRAZING_COSINE: f64 = 0.25;

/// How [`estimate_normals`] works.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalOptions {
    /// The neighbours of each point in its plane and in the orientation graph
    /// ([`NORMAL_NEIGHBOURS`] by default; [`MIN_NEIGHBOURS`] to [`MAX_NEIGHBOURS`]). More
    /// average out noise and bridge gaps; fewer follow fine detail and thin parts.
    pub neighbours: usize,
    /// Where the scanner stood, if known: each large piece is then turned to face it (its
    /// normals' mean cosine towards the viewpoint positive) instead of outward by its
    /// divergence — for one-sided scans of flat surfaces (a wall, terrain: no inside to read)
    /// and scans from inside a room. `None` by default.
    pub viewpoint: Option<Point<3>>,
}

impl Default for NormalOptions {
    fn default() -> Self {
        Self {
            neighbours: NORMAL_NEIGHBOURS,
            viewpoint: None,
        }
    }
}

impl NormalOptions {
    /// These options with `k` neighbours.
    #[must_use]
    pub fn neighbours(mut self, k: usize) -> Self {
        self.neighbours = k;
        self
    }

    /// These options, turning the pieces to face `viewpoint`.
    #[must_use]
    pub fn viewpoint(mut self, viewpoint: Point<3>) -> Self {
        self.viewpoint = Some(viewpoint);
        self
    }
}

/// What [`estimate_normals`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatedNormals {
    /// One unit normal per input point, in input order, oriented outward (or towards the
    /// viewpoint).
    pub normals: Vec<Point<3>>,
    /// Connected pieces of the neighbour graph signed on their own, by their divergence or
    /// the viewpoint (at least [`MIN_PIECE`] points with planes each, or every piece with a
    /// plane when none is that large).
    pub pieces: usize,
    /// Points in smaller pieces, signed by their nearest points in the large ones.
    pub attached: usize,
    /// Points whose neighbourhood spans no plane ([`LINE_PATCH`]); they took a neighbour's
    /// normal.
    pub undetermined: usize,
    /// Points signed by their own scanner ([`estimate_normals_from_scanners`]; 0 otherwise):
    /// the others took their neighbours' sign or their piece's.
    pub facing_scanner: usize,
    /// Of the [`pieces`](Self::pieces) turned outward, those lying inside another an odd
    /// number of times (a hollow solid's cavity, [`NESTED_SHARE`]), turned to face into it
    /// instead; 0 with a viewpoint or scanners.
    pub nested: usize,
    /// Of the [`pieces`](Self::pieces) turned outward, those too flat to have an inside, signed
    /// by convention ([`FlatPiece`]); none with a viewpoint or scanners.
    pub flat: Vec<FlatPiece>,
}

/// Why [`estimate_normals`] could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NormalError {
    /// Fewer points than a plane needs.
    #[error("estimating normals needs at least {needed} points, got {got}")]
    TooFewPoints {
        /// The minimum (3).
        needed: usize,
        /// Points given.
        got: usize,
    },
    /// More points than the neighbour graph indexes (`u32`).
    #[error("estimating normals takes at most {} points, got {got}", u32::MAX)]
    TooManyPoints {
        /// Points given.
        got: usize,
    },
    /// A coordinate that is NaN or infinite.
    #[error("point {index}: position {value:?} is not finite")]
    NonFinite {
        /// The record.
        index: usize,
        /// Its coordinates.
        value: Point<3>,
    },
    /// A normal with a NaN or infinite component.
    #[error("point {index}: normal {value:?} is not finite")]
    NonFiniteNormal {
        /// The record.
        index: usize,
        /// Its components.
        value: Point<3>,
    },
    /// A viewpoint with a NaN or infinite coordinate.
    #[error("viewpoint {value:?} is not finite")]
    Viewpoint {
        /// Its coordinates.
        value: Point<3>,
    },
    /// Scanner positions that are not one per point.
    #[error("{got} scanner positions for {points} points: give one per point")]
    Scanners {
        /// Positions given.
        got: usize,
        /// Points.
        points: usize,
    },
    /// A neighbour count outside its range.
    #[error(
        "neighbours = {got}: a plane is fitted to a point and its neighbours, from \
         {MIN_NEIGHBOURS} to {MAX_NEIGHBOURS}"
    )]
    Neighbours {
        /// The count given.
        got: usize,
    },
    /// [`fill_missing_normals`] was given normals that are all zero: none to sign the
    /// missing ones by.
    #[error(
        "every one of the {points} normals is zero (0 0 0: what some writers put where a point \
         has none): there are no normals to complete; estimate them all instead"
    )]
    NoneGiven {
        /// Points (and normals) given.
        points: usize,
    },
    /// Normals that are not one per point.
    #[error("{got} normals for {points} points: give one per point")]
    Normals {
        /// Normals given.
        got: usize,
        /// Points.
        points: usize,
    },
    /// Most points' neighbourhoods span no plane.
    #[error(
        "{undetermined} of {points} points have neighbourhoods that span no plane (their \
         {neighbours} nearest lie on a line or on one point): the cloud does not sample a \
         surface; more neighbours bridge scan lines, and repeated points can be merged first"
    )]
    Degenerate {
        /// Points without a plane.
        undetermined: usize,
        /// All points.
        points: usize,
        /// The neighbours used.
        neighbours: usize,
    },
}

/// The neighbour count to estimate `positions`' normals from where none is asked for:
/// [`NOISY_NORMAL_NEIGHBOURS`] where the positions measure noisy (their scatter about the
/// surface above [`NOISY_SCATTER`](crate::noise::NOISY_SCATTER) of their spacing,
/// [`estimate_noise_unoriented`], on at most [`NOISE_PATCHES`] patches spread over the cloud),
/// [`NORMAL_NEIGHBOURS`] otherwise; and the measure (`None` for a cloud too small to measure).
///
/// ```
/// use zeroset_bases::normals::{default_neighbours, NORMAL_NEIGHBOURS};
///
/// // A clean 40 × 40 grid on a plane.
/// let grid: Vec<[f64; 3]> = (0..1600).map(|i| [(i % 40) as f64, (i / 40) as f64, 0.0]).collect();
/// assert_eq!(default_neighbours(&grid).0, NORMAL_NEIGHBOURS);
/// ```
pub fn default_neighbours(positions: &[Point<3>]) -> (usize, Option<Noise>) {
    let noise = unoriented_noise(positions, NOISE_PATCHES);
    let k = if noise.is_some_and(|n| n.is_noisy()) {
        NOISY_NORMAL_NEIGHBOURS
    } else {
        NORMAL_NEIGHBOURS
    };
    (k, noise)
}

/// The noise of a cloud that has no normals ([`crate::noise`]): measured on the positions
/// alone, and where that reads noisy, measured again with the normals [`estimate_normals`]
/// gives from [`NORMAL_NEIGHBOURS`], so that each patch keeps to the points facing its way.
///
/// Without normals a patch takes its nearest points whatever sheet they lie on: where a thin
/// part's two sheets are a few spacings apart, its plane runs between them and their distance
/// reads as scatter. A clean closed 1 × 1 × 0.04 box sampled every 0.02 measured 0.54 of the
/// spacing from its positions (noisy), so its normals were estimated from 32 neighbours, which
/// mix the sheets more, and one face turned inward (half the points); measured with its
/// 16-neighbour normals, 0. On clouds that are noisy the second measure agrees with the first
/// (the bunny with Gaussian noise of 0.25% / 0.5% of the diagonal per axis: 0.360 / 0.524 from
/// the positions, 0.360 / 0.523 with the estimated normals and with the scan's own; the kitten
/// at 0.5%: 0.294 each), and costs one normal estimate more. Sheets closer than the spacing
/// are not told apart (a 2 × 2 × 0.04 plate sampled every 0.046: 0.63 either way). Clouds of
/// more than [`NOISE_FALLBACK_POINTS`] keep the first measure. `None` as
/// [`crate::noise::estimate_noise`].
///
/// ```
/// use zeroset_bases::noise::estimate_noise;
/// use zeroset_bases::normals::estimate_noise_unoriented;
///
/// // Both faces of a thin plate: two 40 × 40 grids of spacing 0.01, 0.02 apart.
/// let plate: Vec<[f64; 3]> = (0..3200)
///     .map(|i| [(i % 40) as f64 * 0.01, (i / 40 % 40) as f64 * 0.01, if i < 1600 { 0.0 } else { 0.02 }])
///     .collect();
/// assert!(estimate_noise(&plate, None).unwrap().is_noisy()); // the sheets' distance
/// assert!(!estimate_noise_unoriented(&plate).unwrap().is_noisy());
/// ```
pub fn estimate_noise_unoriented(positions: &[Point<3>]) -> Option<Noise> {
    unoriented_noise(positions, crate::noise::MAX_PATCHES)
}

/// The most points [`estimate_noise_unoriented`] estimates normals for: the second measure
/// costs a normal estimate of every point (a review: `zeroset info` on a noisy 400,000-point
/// cloud went from 1.6 s and 35 MB to 6.6 s and 172 MB), so larger clouds keep the measure from
/// their positions (a thin part's sheets can read as scatter there).
pub const NOISE_FALLBACK_POINTS: usize = 200_000;

/// [`estimate_noise_unoriented`] fitting at most `max_patches` patches per measure.
fn unoriented_noise(positions: &[Point<3>], max_patches: usize) -> Option<Noise> {
    let noise = estimate_noise_over(positions, None, max_patches)?;
    if !noise.is_noisy() || positions.len() > NOISE_FALLBACK_POINTS {
        return Some(noise);
    }
    let options = NormalOptions::default().neighbours(NORMAL_NEIGHBOURS);
    match estimate_normals(positions, &options) {
        Ok(estimated) => {
            estimate_noise_over(positions, Some(&estimated.normals), max_patches).or(Some(noise))
        }
        Err(_) => Some(noise),
    }
}

/// Unit normals for `positions`, oriented outward, or towards [`NormalOptions::viewpoint`]
/// where it is given (see the [module docs](self)).
///
/// # Errors
/// [`NormalError::TooFewPoints`] for fewer than 3 points ([`NormalError::TooManyPoints`] past
/// `u32::MAX`), [`NormalError::NonFinite`] for a NaN or infinite coordinate,
/// [`NormalError::Neighbours`] for a neighbour count outside
/// [`MIN_NEIGHBOURS`]..=[`MAX_NEIGHBOURS`], [`NormalError::Viewpoint`] for a viewpoint that is
/// not finite, [`NormalError::Degenerate`] where more than half the points' neighbourhoods
/// span no plane.
pub fn estimate_normals(
    positions: &[Point<3>],
    options: &NormalOptions,
) -> Result<EstimatedNormals, NormalError> {
    let facing = match options.viewpoint {
        Some(v) => Facing::Viewpoint(v),
        None => Facing::Outward,
    };
    estimate(positions, options.neighbours, &facing)
}

/// Unit normals for `positions`, each facing the scanner that recorded it: `scanners[i]` is
/// where the scanner stood that recorded point `i` (for a scene taken from several stations).
/// Points seen at grazing incidence take their neighbours' sign, and a piece with no point
/// seen otherwise is turned to face its scanners on average (see the [module docs](self)).
/// `options.viewpoint` is not used.
///
/// # Errors
/// As [`estimate_normals`]; [`NormalError::Scanners`] unless there is one scanner position per
/// point, [`NormalError::Viewpoint`] for one that is not finite.
pub fn estimate_normals_from_scanners(
    positions: &[Point<3>],
    scanners: &[Point<3>],
    options: &NormalOptions,
) -> Result<EstimatedNormals, NormalError> {
    if scanners.len() != positions.len() {
        return Err(NormalError::Scanners {
            got: scanners.len(),
            points: positions.len(),
        });
    }
    estimate(positions, options.neighbours, &Facing::Scanners(scanners))
}

/// The most rounds [`fill_missing_normals`] spreads signs from point to point before the
/// points still unsigned take the nearest given normal's.
pub const FILL_ROUNDS: usize = 64;

/// Completes an oriented cloud whose normals are missing at some points: a normal that is the
/// zero vector (exactly `0 0 0`, what CGAL, PCL exports and others write where they could not
/// estimate one) is replaced by the unit normal of the plane through the point and its `k`
/// nearest others (as [`estimate_normals`] fits it), signed to agree with the normals its
/// neighbours have, each unit and weighted by `1 − |n · ê|` (`ê` the direction to the
/// neighbour: one across a thin wall, on the far face, counts less than one along the
/// surface). Signs spread in rounds: the first from the given normals, each next one also from
/// the normals completed before it, so a large gap is signed from its rim inward; after
/// [`FILL_ROUNDS`] rounds, or where no neighbour has a normal, a point takes the sign of the
/// nearest given normal. A point whose neighbourhood spans no plane ([`LINE_PATCH`]) takes its
/// reference direction itself. The given normals are not touched. Returns the indices of the
/// points completed, increasing (empty where no normal is zero).
///
/// Deterministic: exact nearest neighbours (ordered by distance, then index; which of the
/// points tied at the `k`-th distance are returned is the tree's choice, the same every run),
/// and each round reads only the normals known before it, so the same bits on any number of
/// threads.
///
/// ```
/// use zeroset_bases::normals::fill_missing_normals;
///
/// // A 20 × 20 grid on the plane z = 0 facing +z; two points lost their normals.
/// let positions: Vec<[f64; 3]> =
///     (0..400).map(|i| [(i % 20) as f64 * 0.1, (i / 20) as f64 * 0.1, 0.0]).collect();
/// let mut normals = vec![[0.0, 0.0, 1.0]; 400];
/// normals[7] = [0.0; 3];
/// normals[210] = [0.0; 3];
/// let filled = fill_missing_normals(&positions, &mut normals, 16)?;
/// assert_eq!(filled, vec![7, 210]);
/// assert!(normals.iter().all(|n| n[2] > 0.999));
/// # Ok::<(), zeroset_bases::normals::NormalError>(())
/// ```
///
/// # Errors
/// [`NormalError::Normals`] unless there is one normal per point, [`NormalError::NoneGiven`]
/// where every normal is zero (use [`estimate_normals`]), [`NormalError::NonFinite`] for a
/// position or [`NormalError::NonFiniteNormal`] for a normal that is not finite,
/// [`NormalError::Neighbours`] for `k` outside [`MIN_NEIGHBOURS`]..=[`MAX_NEIGHBOURS`],
/// [`NormalError::TooManyPoints`] past `u32::MAX`.
pub fn fill_missing_normals(
    positions: &[Point<3>],
    normals: &mut [Point<3>],
    k: usize,
) -> Result<Vec<usize>, NormalError> {
    let n = positions.len();
    if normals.len() != n {
        return Err(NormalError::Normals {
            got: normals.len(),
            points: n,
        });
    }
    if !(MIN_NEIGHBOURS..=MAX_NEIGHBOURS).contains(&k) {
        return Err(NormalError::Neighbours { got: k });
    }
    if let Some(index) = first_non_finite(normals) {
        return Err(NormalError::NonFiniteNormal {
            index,
            value: normals[index],
        });
    }
    if let Some(index) = first_non_finite(positions) {
        return Err(NormalError::NonFinite {
            index,
            value: positions[index],
        });
    }
    let is_missing = |v: &Point<3>| v.iter().all(|&x| x == 0.0);
    let missing: Vec<usize> = (0..n).filter(|&i| is_missing(&normals[i])).collect();
    if missing.is_empty() {
        return Ok(missing);
    }
    if missing.len() == n {
        return Err(NormalError::NoneGiven { points: n });
    }
    if n > u32::MAX as usize {
        return Err(NormalError::TooManyPoints { got: n });
    }
    let k = k.min(n - 1);
    let tree = Tree::new_from_slice(positions).expect("at most u32::MAX finite points");
    let wanted = NonZero::new(k + 1).expect("k + 1 > 0");
    // Each missing point's neighbours and plane.
    let patches: Vec<(Vec<usize>, Option<Point<3>>)> = missing
        .par_iter()
        .map(|&i| {
            let others: Vec<usize> = nearest_others(&tree, positions, i, wanted)
                .into_iter()
                .take(k)
                .map(|j| j as usize)
                .collect();
            let plane = plane_normal(&positions[i], others.iter().map(|&j| &positions[j]));
            (others, plane)
        })
        .collect();
    // The unit normals known so far: the given ones, then the completed ones round by round.
    let mut known: Vec<Option<Point<3>>> = normals
        .iter()
        .map(|v| (!is_missing(v)).then(|| v.map(|x| x / geometry::norm(v))))
        .collect();
    let mut pending: Vec<usize> = (0..missing.len()).collect();
    for _ in 0..FILL_ROUNDS {
        let signed: Vec<(usize, Point<3>)> = pending
            .par_iter()
            .filter_map(|&m| {
                let (others, plane) = &patches[m];
                let p = &positions[missing[m]];
                let reference = others.iter().fold([0.0; 3], |sum, &j| {
                    let Some(normal) = known[j] else { return sum };
                    let weight = plane.map_or(1.0, |plane| {
                        let e = geometry::sub(&positions[j], p);
                        let length = geometry::norm(&e);
                        if length > 0.0 {
                            1.0 - geometry::dot(&plane, &e).abs() / length
                        } else {
                            1.0
                        }
                    });
                    geometry::add(&sum, &normal.map(|x| weight * x))
                });
                let length = geometry::norm(&reference);
                (length > 0.0).then(|| (m, agreeing(*plane, &reference.map(|x| x / length))))
            })
            .collect();
        if signed.is_empty() {
            break;
        }
        for (m, normal) in signed {
            known[missing[m]] = Some(normal);
        }
        pending.retain(|&m| known[missing[m]].is_none());
        if pending.is_empty() {
            break;
        }
    }
    if !pending.is_empty() {
        // Out of reach of every sign: the nearest given normal signs them.
        let given: Vec<u32> = (0..n as u32)
            .filter(|&i| !is_missing(&normals[i as usize]))
            .collect();
        let given_positions: Vec<Point<3>> = given.iter().map(|&i| positions[i as usize]).collect();
        let given_tree =
            Tree::new_from_slice(&given_positions).expect("fewer points than the cloud");
        for &m in &pending {
            let nearest = given_tree
                .query(&positions[missing[m]])
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute();
            let reference = known[given[nearest.item as usize] as usize].expect("a given normal");
            known[missing[m]] = Some(agreeing(patches[m].1, &reference));
        }
    }
    for &i in &missing {
        normals[i] = known[i].expect("every missing normal completed");
    }
    Ok(missing)
}

/// Signs for normals that have a line but no consistent sign — principal-component normals
/// written unoriented (CGAL's `cube.pwn`: every face's normal along `+x`, `+y` or `+z`, half of
/// them inward): the orientation of [`estimate_normals`] run on `lines` instead of the planes it
/// would fit, each large piece turned outward (or towards [`NormalOptions::viewpoint`]). Each
/// returned normal is `±` its line, scaled to unit length; a zero line counts as a point
/// without a plane and takes its neighbour's normal. Compare the result's signs with the
/// lines' own to see whether they were oriented ([`Orientation::unoriented`]).
///
/// Where the lines' signs disagree with the orientation on a part of the cloud only (from
/// [`FACING_IN_SHARE`] up to [`UNORIENTED_SHARE`]), the part may be wrong — a closed object's
/// underside whose normals a program turned to face up — or the walk may be, across sharp
/// creases of a correct scan. Rays cast from those points along their lines tell which
/// ([`Orientation::rays`], [`Orientation::facing_in`]): a normal facing into its object
/// meets the surface from inside.
///
/// ```
/// use zeroset_bases::normals::{orient_normals, NormalOptions};
///
/// // 800 points on the unit sphere, their normals all turned to point up (z ≥ 0).
/// let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
/// let points: Vec<[f64; 3]> = (0..800)
///     .map(|i| {
///         let z = 1.0 - 2.0 * (i as f64 + 0.5) / 800.0;
///         let r = (1.0 - z * z).sqrt();
///         [r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z]
///     })
///     .collect();
/// let up: Vec<[f64; 3]> = points.iter().map(|p| if p[2] < 0.0 { p.map(|x| -x) } else { *p }).collect();
/// let oriented = orient_normals(&points, &up, &NormalOptions::default())?;
/// assert_eq!(oriented.turned, 400); // the lower half
/// assert!(oriented.inconsistent > 300);
/// assert!(points.iter().zip(&oriented.estimated.normals).all(|(p, n)| p.iter().zip(n).all(|(a, b)| (a - b).abs() < 1e-12)));
/// # Ok::<(), zeroset_bases::normals::NormalError>(())
/// ```
///
/// # Errors
/// As [`estimate_normals`]; [`NormalError::Normals`] unless there is one line per point,
/// [`NormalError::NonFiniteNormal`] for a line with a NaN or infinite component (a zero line is
/// a point without one).
pub fn orient_normals(
    positions: &[Point<3>],
    lines: &[Point<3>],
    options: &NormalOptions,
) -> Result<Orientation, NormalError> {
    if lines.len() != positions.len() {
        return Err(NormalError::Normals {
            got: lines.len(),
            points: positions.len(),
        });
    }
    if let Some(index) = first_non_finite(lines) {
        return Err(NormalError::NonFiniteNormal {
            index,
            value: lines[index],
        });
    }
    let facing = match options.viewpoint {
        Some(v) => Facing::Viewpoint(v),
        None => Facing::Outward,
    };
    let (estimated, walk) = estimate_from(positions, options.neighbours, &facing, Some(lines))?;
    let inconsistent = walk.inconsistent;
    let turned = lines
        .iter()
        .zip(&estimated.normals)
        .filter(|(l, n)| geometry::dot(l, n) < 0.0)
        .count();
    let share = inconsistent.len() as f64 / positions.len() as f64;
    let (rays, rays_consistent) = if (FACING_IN_SHARE..UNORIENTED_SHARE).contains(&share) {
        let mut is_inconsistent = vec![false; positions.len()];
        for &i in &inconsistent {
            is_inconsistent[i as usize] = true;
        }
        let consistent: Vec<u32> = (0..positions.len() as u32)
            .filter(|&i| !is_inconsistent[i as usize])
            .collect();
        rays::scene(positions, lines, &walk.piece_of).map_or_else(
            || (RayVotes::default(), RayVotes::default()),
            |scene| (scene.votes(&inconsistent), scene.votes(&consistent)),
        )
    } else {
        (RayVotes::default(), RayVotes::default())
    };
    Ok(Orientation {
        estimated,
        inconsistent: inconsistent.len(),
        turned,
        rays,
        rays_consistent,
    })
}

/// Normals whose [`Orientation::inconsistent`] share is at least this are unoriented: their
/// signs about as often against their neighbours' as with them. Measured (2026-12-07,
/// [`orient_normals`] at 16 neighbours): scans with oriented normals 0% (the bunny, the kitten,
/// `bunny_2k`, CGAL's `hippo1`, `oni`, `point_set_3`; closed boxes 1 × 1 × 0.01–0.05 sampled
/// every 0.01, walls thinner than their sampling), 0.04–0.3% (CGAL's noisy
/// `sphere_20k_normal`, `ball`), 30.0% (CGAL's `building`, an open façade: 9.9% while every
/// edge between normals pointing apart cost 3, 28–34% for wall weights 3–10), 25% where the
/// orientation itself errs (CGAL's `spheres`: overlapping spheres, one taken for a cavity);
/// unoriented normals 47% (the bunny's turned to face up; 49% its 2,000-point sample), 49.9% (CGAL's `cube.pwn`, a CAD
/// part whose every face's normal points along `+x`, `+y` or `+z`; the bunny's with a random
/// half turned), 50% (a sphere's turned to face up).
pub const UNORIENTED_SHARE: f64 = 0.4;

/// [`orient_normals`] casts rays ([`RayVotes`]) from the [inconsistent](Orientation::inconsistent)
/// points where they are at least this share of the cloud and under [`UNORIENTED_SHARE`]: below it,
/// a few flipped normals, which the fits themselves set aside
/// ([`OffsetReport::opposed_normals`](crate::rbf::OffsetReport::opposed_normals)).
pub const FACING_IN_SHARE: f64 = 0.05;

/// Normals face into their object ([`Orientation::facing_in`]) where at least this share of the
/// rays cast from the inconsistent points read inward, and at least twice as many as read outward.
/// Measured (2026-12-07, rays from up to 256 points): normals turned to face up on closed objects
/// read 238 of 240 inward (an egg; 225 and 159 with position noise σ of 0.27 and about 0.4 of its
/// spacing), 126 of 239 (CGAL's `oni`), 103 of 251 (`point_set_3`), 205 of 232 (`fandisk`), 86 of
/// 185 (`helmet`); every 10th normal of a sphere flipped, 150 of 150. Correct normals the walk
/// disagrees with across sharp creases read outward or meet nothing: 0 inward on a regular
/// tetrahedron (closed, standing without its base, or its three upper faces), asymmetric ridges,
/// open prisms and wedges; 13 of 244 on pointed terrain (`z = 0.15 √|sin 8x| √|sin 8y|`), 1 of 251
/// on CGAL's overlapping `spheres`, 48 of 254 (against 63 outward) on CGAL's `building`, an open
/// façade. Of 212 clouds with their own normals (a reviewer's synthetic set, CGAL's `points_3` and
/// the vertices of 125 of its meshes, zeroset's samples) none faces in.
pub const FACING_IN_VOTES: f64 = 1.0 / 3.0;

/// The fewest rays [`Orientation::facing_in`] reads a verdict from.
pub const FACING_IN_MIN_RAYS: usize = 8;

/// What [`orient_normals`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Orientation {
    /// The oriented normals (each `±` its line, unit) and how they were signed.
    pub estimated: EstimatedNormals,
    /// Points whose line's own sign disagrees with the orientation up to one sign per connected
    /// piece: of each piece, the smaller of the points that agree and those that disagree. 0
    /// where the lines were oriented consistently (outward or not); about half of a piece whose
    /// signs are arbitrary.
    pub inconsistent: usize,
    /// Points whose returned normal is the opposite of their line.
    pub turned: usize,
    /// Rays cast from the [inconsistent](Self::inconsistent) points along their lines, where
    /// they are from [`FACING_IN_SHARE`] up to [`UNORIENTED_SHARE`] of the points; zero
    /// otherwise.
    pub rays: RayVotes,
    /// Rays cast likewise from the other points, where [`rays`](Self::rays) are cast.
    pub rays_consistent: RayVotes,
}

impl Orientation {
    /// Whether the lines were unoriented: [`inconsistent`](Self::inconsistent) at least
    /// [`UNORIENTED_SHARE`] of the points, or the ones turned [face into the
    /// object](Self::facing_in).
    #[must_use]
    pub fn unoriented(&self) -> bool {
        self.unoriented_by_share() || self.facing_in()
    }

    /// Whether [`inconsistent`](Self::inconsistent) is at least [`UNORIENTED_SHARE`] of the
    /// points: signs set arbitrarily.
    #[must_use]
    pub fn unoriented_by_share(&self) -> bool {
        let n = self.estimated.normals.len();
        n > 0 && self.inconsistent as f64 >= UNORIENTED_SHARE * n as f64
    }

    /// Whether the [inconsistent](Self::inconsistent) lines faced into the object: at least
    /// [`FACING_IN_VOTES`] of the [rays](Self::rays) cast from them read inward, twice as
    /// many as read outward, at least [`FACING_IN_MIN_RAYS`] were cast, and the [rays from
    /// the other points](Self::rays_consistent) read inward at most a quarter as often. So
    /// read the normals a program turned to face one direction (Open3D's
    /// `orient_normals_to_align_with_direction`, `+z` by default) on a closed object: only its
    /// underside disagrees with the rest, a third of the points or less, and the rest face
    /// out. The last condition holds back where the walk itself errs, so that turning the
    /// normals as it gives would not help: a closed regular tetrahedron with its base's
    /// normals turned up reads 111 of 248 inward, but the other points 42 of 248 (the walk
    /// disagrees across its creases with correct normals too); on the normals turned up
    /// listed at [`FACING_IN_VOTES`], the other points read 0–6%. (Open sheets stacked facing
    /// one way — terraces, geological horizons — read like a closed object's two sides ray by
    /// ray, but are separate pieces of the walk, and a sheet of another piece says nothing
    /// of a ray's side: see [`RayVotes`].)
    #[must_use]
    pub fn facing_in(&self) -> bool {
        let share = |v: RayVotes| v.inward as f64 / v.cast.max(1) as f64;
        let RayVotes {
            cast,
            inward,
            outward,
        } = self.rays;
        cast >= FACING_IN_MIN_RAYS
            && inward as f64 >= FACING_IN_VOTES * cast as f64
            && inward >= 2 * outward
            && 4.0 * share(self.rays_consistent) <= share(self.rays)
    }
}

/// The first of `points` with a NaN or infinite coordinate.
fn first_non_finite(points: &[Point<3>]) -> Option<usize> {
    points.iter().position(|p| !p.iter().all(|x| x.is_finite()))
}

/// Which way each large piece is turned.
enum Facing<'a> {
    /// Outward, by its divergence.
    Outward,
    /// Towards one viewpoint.
    Viewpoint(Point<3>),
    /// Each point towards its own scanner.
    Scanners(&'a [Point<3>]),
}

/// [`estimate_normals`] with `k` neighbours, each large piece turned as `facing` says.
fn estimate(
    positions: &[Point<3>],
    k: usize,
    facing: &Facing<'_>,
) -> Result<EstimatedNormals, NormalError> {
    estimate_from(positions, k, facing, None).map(|(estimated, _)| estimated)
}

/// Where `lines` are given to [`estimate_from`]: the points inconsistent with them
/// ([`Orientation::inconsistent`]) and each point's piece of the walk (its tree in the
/// spanning forest).
struct Walk {
    inconsistent: Vec<u32>,
    piece_of: Vec<u32>,
}

/// [`estimate`], with the planes' normals given as `lines` (unit or not; zero for none) where
/// they are known; and how the walk read them ([`Walk`]: empty without `lines`).
fn estimate_from(
    positions: &[Point<3>],
    k: usize,
    facing: &Facing<'_>,
    lines: Option<&[Point<3>]>,
) -> Result<(EstimatedNormals, Walk), NormalError> {
    let n = positions.len();
    if !(MIN_NEIGHBOURS..=MAX_NEIGHBOURS).contains(&k) {
        return Err(NormalError::Neighbours { got: k });
    }
    let viewpoints: &[Point<3>] = match facing {
        Facing::Outward => &[],
        Facing::Viewpoint(v) => std::slice::from_ref(v),
        Facing::Scanners(all) => all,
    };
    if let Some(v) = viewpoints.iter().find(|v| !v.iter().all(|x| x.is_finite())) {
        return Err(NormalError::Viewpoint { value: *v });
    }
    if n < 3 {
        return Err(NormalError::TooFewPoints { needed: 3, got: n });
    }
    if let Some(index) = first_non_finite(positions) {
        return Err(NormalError::NonFinite {
            index,
            value: positions[index],
        });
    }
    if n > u32::MAX as usize {
        return Err(NormalError::TooManyPoints { got: n });
    }
    let k = k.min(n - 1);
    let (neighbours, planes) = tangent_planes(positions, k, lines);
    let undetermined = planes.iter().filter(|p| p.is_none()).count();
    if 2 * undetermined > n {
        return Err(NormalError::Degenerate {
            undetermined,
            points: n,
            neighbours: k,
        });
    }
    let forest = spanning_forest(positions, &neighbours, k, &planes, lines.is_some());
    drop(neighbours);
    let mut normals = vec![[0.0; 3]; n];
    let pieces = orient_pieces(&forest, &planes, &mut normals);
    let signed = sign_pieces(positions, &pieces, facing, &planes, &forest, &mut normals);
    // Of each piece, the points on the smaller side of its split by agreement with the lines'
    // own signs: 0 for lines oriented consistently, whichever way the piece faces.
    let mut piece_of = vec![0; if lines.is_some() { n } else { 0 }];
    if lines.is_some() {
        for (label, piece) in pieces.iter().enumerate() {
            for &i in piece {
                piece_of[i as usize] = label as u32;
            }
        }
    }
    let inconsistent = lines.map_or_else(Vec::new, |lines| {
        pieces
            .iter()
            .flat_map(|piece| {
                let (against, with): (Vec<u32>, Vec<u32>) = piece
                    .iter()
                    .partition(|&&i| geometry::dot(&lines[i as usize], &normals[i as usize]) < 0.0);
                if against.len() <= with.len() {
                    against
                } else {
                    with
                }
            })
            .collect()
    });
    Ok((
        EstimatedNormals {
            normals,
            pieces: signed.large,
            attached: signed.attached,
            undetermined,
            facing_scanner: signed.facing_scanner,
            nested: signed.nested,
            flat: signed.flat,
        },
        Walk {
            inconsistent,
            piece_of,
        },
    ))
}

/// Each point's `k` nearest others (row `i` of an `n × k` table, nearest first, ties by
/// index) and its plane's unit normal (`None` where the patch spans no plane), or its line of
/// `lines` scaled to unit length where they are given (`None` for a zero line).
fn tangent_planes(
    positions: &[Point<3>],
    k: usize,
    lines: Option<&[Point<3>]>,
) -> (Vec<u32>, Vec<Option<Point<3>>>) {
    let tree = Tree::new_from_slice(positions).expect("at most u32::MAX finite points");
    let wanted = NonZero::new(k + 1).expect("k + 1 > 0");
    let rows: Vec<(Vec<u32>, Option<Point<3>>)> = positions
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let mut others = nearest_others(&tree, positions, i, wanted);
            others.truncate(k);
            let plane = match lines {
                Some(lines) => {
                    let length = geometry::norm(&lines[i]);
                    (length > 0.0 && length.is_finite()).then(|| lines[i].map(|x| x / length))
                }
                None => plane_normal(p, others.iter().map(|&j| &positions[j as usize])),
            };
            (others, plane)
        })
        .collect();
    let mut table = Vec::with_capacity(positions.len() * k);
    let mut planes = Vec::with_capacity(positions.len());
    for (others, plane) in rows {
        // k + 1 found and the point itself dropped at most once.
        debug_assert_eq!(others.len(), k);
        table.extend(others);
        planes.push(plane);
    }
    (table, planes)
}

/// The unit normal (unsigned) of the plane through `p` and `others` by their covariance's
/// smallest eigenvector; `None` where the middle eigenvalue is at most [`LINE_PATCH`] of the
/// largest.
fn plane_normal<'a>(p: &Point<3>, others: impl Iterator<Item = &'a Point<3>>) -> Option<Point<3>> {
    let patch: Vec<Point<3>> = std::iter::once(*p).chain(others.copied()).collect();
    let m = patch.len() as f64;
    let centroid = patch
        .iter()
        .fold([0.0; 3], |s, q| geometry::add(&s, q))
        .map(|x| x / m);
    let covariance = Mat::<f64>::from_fn(3, 3, |r, c| {
        patch
            .iter()
            .map(|q| (q[r] - centroid[r]) * (q[c] - centroid[c]))
            .sum::<f64>()
    });
    let eigen = covariance.self_adjoint_eigen(Side::Lower).ok()?;
    let (values, frame) = (eigen.S().column_vector(), eigen.U());
    // Ascending: the normal first, the widest tangent direction last.
    if !(values[2] > 0.0 && values[1] > LINE_PATCH * values[2]) {
        return None;
    }
    let normal = [frame[(0, 0)], frame[(1, 0)], frame[(2, 0)]];
    let length = geometry::norm(&normal);
    (length > 0.0 && length.is_finite()).then(|| normal.map(|x| x / length))
}

/// The cost of propagating a sign along the edge `i`–`j`: `1 − |n_i · n_j|` plus how far
/// the edge runs along the two normals, `½ (|n_i · ê| + |n_j · ê|)` (see the
/// [module docs](self)); 3 where either plane is missing. With `signed` planes (given
/// normals, [`orient_normals`]), an edge between normals that point apart (`n_i · n_j < −½`)
/// counts how far it runs along them [`WALL_WEIGHT`] times: across a thin wall (its two
/// faces) it costs more than the rim, which would cost about 1 or less against the rim's 1.7
/// and let the walk carry one face's sign onto the other (a closed box 1 × 1 × 0.02 sampled
/// every 0.01 with its own normals read 47% against the orientation — as unoriented normals
/// do); along the surface, where unoriented normals change sign, it costs what it would
/// unsigned (costing 3 there too, the walk crossed the sparse bunny's ears instead: 2,000
/// points signed to face up read 1.7% inconsistent). An edge between given normals that
/// point apart *and* either face each other or face away from each other along it
/// (`(n_i · ê)(n_j · ê) < 0`: a gap between two objects, a wall's two faces) and run along
/// them by at least [`GAP_REACH`] is not walked at all ([`f64::INFINITY`]): see there.
fn edge_cost(
    positions: &[Point<3>],
    planes: &[Option<Point<3>>],
    signed: bool,
    i: usize,
    j: usize,
) -> f64 {
    let (Some(a), Some(b)) = (&planes[i], &planes[j]) else {
        return 3.0;
    };
    let e = geometry::sub(&positions[j], &positions[i]);
    let length = geometry::norm(&e);
    let across = if length > 0.0 {
        0.5 * (geometry::dot(a, &e).abs() + geometry::dot(b, &e).abs()) / length
    } else {
        0.0
    };
    let cos = geometry::dot(a, b);
    let apart = signed && cos < -0.5;
    if apart && across >= GAP_REACH && geometry::dot(a, &e) * geometry::dot(b, &e) < 0.0 {
        return f64::INFINITY;
    }
    let across_weight = if apart { WALL_WEIGHT } else { 1.0 };
    1.0 - cos.abs() + across_weight * across
}

/// How much more an edge between given normals that point apart costs per unit of how far it
/// runs along them ([`edge_cost`]): such an edge across a thin wall (running along its
/// normals, `½ (|n_i · ê| + |n_j · ê|)` from 0.45 for a wall as thick as its sampling to 1)
/// costs from 2.25 up, above a rim's 1.7; along the surface (where unoriented normals change
/// sign) it costs what it would unsigned, so the walk crosses there.
const WALL_WEIGHT: f64 = 5.0;

/// How far, at least, an edge between given normals that point apart and face each other (or
/// away from each other) along it must run along them, `½ (|n_i · ê| + |n_j · ê|)`, to be
/// left out of the walk ([`edge_cost`]). Costly as it is, such an edge was walked wherever no
/// other joined two parts, and the walk carried one part's sign onto the other: two unit
/// spheres 0.1 apart sampled every 0.15 with their own outward normals read 50%
/// inconsistent — as unoriented — and `reconstruct` turned one inside out (the edge the walk
/// took across the gap ran along the normals by 0.19). Left out, each is a piece of its own
/// and turned outward by itself. Where unoriented normals change sign on a curved surface,
/// the edge between them runs along them by the curvature, but the pair faces the same way
/// along it (`(n_i · ê)(n_j · ê) > 0`), so it stays in the walk whatever its reach.
/// Measured (2026-12-07, [`orient_normals`] at 16 neighbours, the share inconsistent of
/// each scan's own normals, of them turned to face up, and of a hashed half turned): every
/// reach from 0.03 to 0.1 gave two unit spheres 0.02–0.2 apart (sampled every 0.05–0.15)
/// 0% with their own normals (50% before) and 50% turned; on the bunny, the kitten,
/// `bunny_2k` and CGAL's `hippo1`, `oni`, `point_set_3`, `sphere926`, `sphere_20k_normal`,
/// `ball`, `building`, `spheres` and `cube.pwn` no share moved by more than 0.06 points at
/// 0.1 (0.9 at 0.03). Without the facing condition, reaches of 0.05 and below read the
/// turned spheres and `sphere926` as oriented (0%). Not enough under position noise: the
/// spheres with their points moved by 0.2–0.3 of their spacing still read 50%.
const GAP_REACH: f64 = 0.1;

/// The minimum spanning forest of the `k`-nearest-neighbour graph under [`edge_cost`]
/// (Kruskal; edges in order of cost, then of their ends), as adjacency lists.
fn spanning_forest(
    positions: &[Point<3>],
    neighbours: &[u32],
    k: usize,
    planes: &[Option<Point<3>>],
    signed: bool,
) -> Vec<Vec<u32>> {
    let n = positions.len();
    // Each pair once: from its lower end, or from its upper end where the lower one's row does
    // not hold it (so a pair found from both ends is not stored twice).
    let row = |i: usize| &neighbours[i * k..(i + 1) * k];
    let mut edges: Vec<(f64, u32, u32)> = (0..n)
        .into_par_iter()
        .flat_map_iter(|i| {
            row(i)
                .iter()
                .map(|&j| j as usize)
                .filter(move |&j| j > i || (j < i && !row(j).contains(&(i as u32))))
                .map(move |j| {
                    let (a, b) = (i.min(j), i.max(j));
                    (
                        edge_cost(positions, planes, signed, a, b),
                        a as u32,
                        b as u32,
                    )
                })
        })
        .collect();
    // The pairs are unique, so the order is total: the same on any number of threads.
    edges.par_sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut adjacent = vec![Vec::new(); n];
    for (cost, a, b) in edges {
        if cost == f64::INFINITY {
            break;
        }
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
            adjacent[a as usize].push(b);
            adjacent[b as usize].push(a);
        }
    }
    adjacent
}

/// Walks each tree of `forest` breadth-first from its first point with a plane, giving every
/// point the sign that agrees with its parent's normal (undetermined points take the parent's
/// normal). Returns the trees' points, each tree in walk order.
fn orient_pieces(
    forest: &[Vec<u32>],
    planes: &[Option<Point<3>>],
    normals: &mut [Point<3>],
) -> Vec<Vec<u32>> {
    let n = forest.len();
    let mut seen = vec![false; n];
    let mut pieces = Vec::new();
    // Roots: points with a plane first, so that a piece starts from one where it has any.
    let order = (0..n)
        .filter(|&i| planes[i].is_some())
        .chain((0..n).filter(|&i| planes[i].is_none()));
    for start in order {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        // A piece without any plane keeps the zero vector until it is attached.
        normals[start] = planes[start].unwrap_or([0.0; 3]);
        let mut piece = vec![start as u32];
        let mut queue = VecDeque::from([start]);
        while let Some(i) = queue.pop_front() {
            for &j in &forest[i] {
                let j = j as usize;
                if seen[j] {
                    continue;
                }
                seen[j] = true;
                normals[j] = agreeing(planes[j], &normals[i]);
                piece.push(j as u32);
                queue.push_back(j);
            }
        }
        pieces.push(piece);
    }
    pieces
}

/// The sign of `plane` that agrees with `reference` (`plane` itself where they are square),
/// or `reference` where there is no plane: how a sign crosses an edge of the forest.
fn agreeing(plane: Option<Point<3>>, reference: &Point<3>) -> Point<3> {
    match plane {
        Some(p) if geometry::dot(&p, reference) < 0.0 => p.map(|x| -x),
        Some(p) => p,
        None => *reference,
    }
}

/// Whether a large piece turned outward is flat ([`FlatPiece`]): its divergence small against
/// its spread, its normals agreeing, its points on a plane — a closed thin plate or rod, or
/// one side of a pipe, has the first without the others, and its divergence's sign is right.
fn is_flat(
    piece: &[u32],
    positions: &[Point<3>],
    normals: &[Point<3>],
    centroid: &Point<3>,
    divergence: f64,
) -> bool {
    let spread: f64 = piece
        .iter()
        .map(|&i| geometry::norm(&geometry::sub(&positions[i as usize], centroid)))
        .sum();
    let sum = piece
        .iter()
        .fold([0.0; 3], |s, &i| geometry::add(&s, &normals[i as usize]));
    if !(divergence.abs() < FLAT_DIVERGENCE * spread
        && geometry::norm(&sum) >= FLAT_AGREEMENT * piece.len() as f64)
    {
        return false;
    }
    let covariance = Mat::<f64>::from_fn(3, 3, |r, c| {
        piece
            .iter()
            .map(|&i| {
                let q = &positions[i as usize];
                (q[r] - centroid[r]) * (q[c] - centroid[c])
            })
            .sum::<f64>()
    });
    covariance
        .self_adjoint_eigen(Side::Lower)
        .ok()
        .is_some_and(|e| {
            let values = e.S().column_vector();
            values[0] <= FLAT_PLANARITY * values[1]
        })
}

/// Turns a flat piece so that its normals' mean direction has its largest component positive
/// ([`FlatPiece`]), and says so.
fn flat_convention(piece: &[u32], normals: &mut [Point<3>]) -> FlatPiece {
    let sum = piece
        .iter()
        .fold([0.0; 3], |s, &i| geometry::add(&s, &normals[i as usize]));
    let largest = (0..3)
        .max_by(|&a, &b| sum[a].abs().total_cmp(&sum[b].abs()))
        .unwrap_or(2);
    let sign = if sum[largest] < 0.0 { -1.0 } else { 1.0 };
    if sign < 0.0 {
        for &i in piece {
            normals[i as usize] = normals[i as usize].map(|x| -x);
        }
    }
    let length = geometry::norm(&sum);
    FlatPiece {
        points: piece.len(),
        facing: if length > 0.0 {
            sum.map(|x| sign * x / length)
        } else {
            [0.0; 3]
        },
    }
}

/// Signs every point whose plane is seen at an incidence of at most `acos(`[`GRAZING_COSINE`]`)`
/// from its scanner towards that scanner, then the others from them along `forest`,
/// breadth-first (sources in index order); points of trees without such a point keep their
/// normals. Returns the points signed by their scanner, and which points were signed (whole
/// trees).
fn face_scanners(
    positions: &[Point<3>],
    scanners: &[Point<3>],
    planes: &[Option<Point<3>>],
    forest: &[Vec<u32>],
    normals: &mut [Point<3>],
) -> (usize, Vec<bool>) {
    let mut seen = vec![false; positions.len()];
    let mut queue = VecDeque::new();
    for (i, plane) in planes.iter().enumerate() {
        let Some(plane) = plane else { continue };
        let towards = geometry::sub(&scanners[i], &positions[i]);
        let length = geometry::norm(&towards);
        let cosine = geometry::dot(plane, &towards) / length;
        // A point at its scanner (length 0) gives a NaN cosine and is not a source.
        if cosine.abs() >= GRAZING_COSINE {
            normals[i] = agreeing(Some(*plane), &towards);
            seen[i] = true;
            queue.push_back(i);
        }
    }
    let sources = queue.len();
    while let Some(i) = queue.pop_front() {
        for &j in &forest[i] {
            let j = j as usize;
            if !seen[j] {
                seen[j] = true;
                normals[j] = agreeing(planes[j], &normals[i]);
                queue.push_back(j);
            }
        }
    }
    (sources, seen)
}

/// What [`sign_pieces`] did.
struct Signed {
    /// Large pieces, each signed on its own.
    large: usize,
    /// Points of small pieces attached to the large ones.
    attached: usize,
    /// Points signed by their own scanner.
    facing_scanner: usize,
    /// Large pieces turned to face a cavity they lie in ([`nesting_depths`]).
    nested: usize,
    /// Large pieces too flat to read an inside from, signed by convention.
    flat: Vec<FlatPiece>,
}

/// Turns each large piece outward by its divergence (a flat one by [`FlatPiece`]'s convention)
/// or as `facing` says, then — facing the scanners — every point it can by its own scanner
/// ([`face_scanners`]), then each small piece not signed so to agree with its points' nearest
/// points in the large pieces.
fn sign_pieces(
    positions: &[Point<3>],
    pieces: &[Vec<u32>],
    facing: &Facing<'_>,
    planes: &[Option<Point<3>>],
    forest: &[Vec<u32>],
    normals: &mut [Point<3>],
) -> Signed {
    // A piece whose root has no plane has none at all (roots are taken from the points with
    // planes first): its normals are zero until it takes its nearest large piece's.
    let planar = |piece: &Vec<u32>| normals[piece[0] as usize] != [0.0; 3];
    let largest = pieces
        .iter()
        .filter(|p| planar(p))
        .map(Vec::len)
        .max()
        .unwrap_or(0);
    // Where no piece is large, every piece with a plane reads its own inside.
    let threshold = MIN_PIECE.min(largest);
    let is_large: Vec<bool> = pieces
        .iter()
        .map(|p| planar(p) && p.len() >= threshold)
        .collect();
    let flip = |normals: &mut [Point<3>], piece: &[u32]| {
        for &i in piece {
            normals[i as usize] = normals[i as usize].map(|x| -x);
        }
    };
    let mut large = 0;
    let mut flat = Vec::new();
    // Which pieces are flat: the cavity rule leaves them be.
    let mut is_flat_piece = vec![false; pieces.len()];
    for (index, piece) in pieces
        .iter()
        .enumerate()
        .zip(&is_large)
        .filter(|(_, l)| **l)
        .map(|(p, _)| p)
    {
        large += 1;
        let centroid = piece
            .iter()
            .fold([0.0; 3], |s, &i| geometry::add(&s, &positions[i as usize]))
            .map(|x| x / piece.len() as f64);
        // Outward: Σ (p − c)·n > 0; towards the viewpoints v_i: Σ n·(v_i − p)/‖v_i − p‖ > 0.
        let cosine_towards = |v: &Point<3>, i: usize| {
            let towards = geometry::sub(v, &positions[i]);
            let length = geometry::norm(&towards);
            if length > 0.0 {
                geometry::dot(&towards, &normals[i]) / length
            } else {
                0.0
            }
        };
        let divergence: f64 = piece
            .iter()
            .map(|&i| {
                let i = i as usize;
                match facing {
                    Facing::Outward => {
                        geometry::dot(&geometry::sub(&positions[i], &centroid), &normals[i])
                    }
                    Facing::Viewpoint(v) => cosine_towards(v, i),
                    Facing::Scanners(all) => cosine_towards(&all[i], i),
                }
            })
            .sum();
        if divergence < 0.0 {
            flip(normals, piece);
        }
        if let Facing::Outward = facing
            && is_flat(piece, positions, normals, &centroid, divergence)
        {
            flat.push(flat_convention(piece, normals));
            is_flat_piece[index] = true;
        }
    }
    // A piece inside another (a hollow solid's cavity) faces into its cavity, away from the
    // solid, which the divergence turned the other way: flipped where nested an odd number of
    // times.
    let mut nested = 0;
    if matches!(facing, Facing::Outward) {
        let large_pieces: Vec<&Vec<u32>> = pieces
            .iter()
            .zip(is_large.iter().zip(&is_flat_piece))
            .filter(|(_, (l, f))| **l && !**f)
            .map(|(p, _)| p)
            .collect();
        for (piece, depth) in
            large_pieces
                .iter()
                .zip(nesting_depths(positions, &large_pieces, normals))
        {
            if depth % 2 == 1 {
                flip(normals, piece);
                nested += 1;
            }
        }
    }
    // Before the small pieces are attached: they take the large pieces' final signs.
    let (facing_scanner, signed) = match facing {
        Facing::Scanners(scanners) => face_scanners(positions, scanners, planes, forest, normals),
        Facing::Outward | Facing::Viewpoint(_) => (0, vec![false; positions.len()]),
    };
    // A tree the scanners reached is signed whole.
    let small: Vec<&Vec<u32>> = pieces
        .iter()
        .zip(&is_large)
        .filter(|(p, l)| !**l && !signed[p[0] as usize])
        .map(|(p, _)| p)
        .collect();
    let mut signed = Signed {
        large,
        attached: 0,
        facing_scanner,
        nested,
        flat,
    };
    if small.is_empty() {
        return signed;
    }
    let anchors: Vec<u32> = pieces
        .iter()
        .zip(&is_large)
        .filter(|(_, l)| **l)
        .flat_map(|(p, _)| p)
        .copied()
        .collect();
    let anchor_positions: Vec<Point<3>> = anchors.iter().map(|&i| positions[i as usize]).collect();
    let tree = Tree::new_from_slice(&anchor_positions).expect("finite points");
    let mut attached = 0;
    for piece in small {
        attached += piece.len();
        let mut agreement = 0.0;
        for &i in piece {
            let i = i as usize;
            let nearest = tree
                .query(&positions[i])
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute();
            let anchor = anchors[nearest.item as usize] as usize;
            agreement += geometry::dot(&normals[i], &normals[anchor]);
        }
        // A piece with no plane of its own takes its nearest anchor's normals.
        if piece.iter().all(|&i| normals[i as usize] == [0.0; 3]) {
            for &i in piece {
                let nearest = tree
                    .query(&positions[i as usize])
                    .nearest_one::<SquaredEuclidean<f64>>()
                    .execute();
                normals[i as usize] = normals[anchors[nearest.item as usize] as usize];
            }
        } else if agreement < 0.0 {
            flip(normals, piece);
        }
    }
    signed.attached = attached;
    signed
}

/// How many of the other `pieces` (turned outward) each piece lies inside: `A` lies inside `B`
/// where `A`'s box lies in `B`'s, at least [`NESTED_SHARE`] of `A`'s points (at most
/// [`NESTING_SAMPLES`] of them, evenly spread) are behind `B`'s nearest point, `(x − p)·n_p < 0`,
/// and `B` surrounds `A` on every side ([`encloses`]).
/// All 0 beyond [`MAX_NESTING_PIECES`] pieces.
fn nesting_depths(
    positions: &[Point<3>],
    pieces: &[&Vec<u32>],
    normals: &[Point<3>],
) -> Vec<usize> {
    let mut depths = vec![0; pieces.len()];
    if pieces.len() < 2 || pieces.len() > MAX_NESTING_PIECES {
        return depths;
    }
    let boxes: Vec<(Point<3>, Point<3>)> = pieces
        .iter()
        .map(|piece| {
            piece.iter().fold(
                ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
                |(lo, hi), &i| {
                    let p = positions[i as usize];
                    (
                        std::array::from_fn(|a| lo[a].min(p[a])),
                        std::array::from_fn(|a| hi[a].max(p[a])),
                    )
                },
            )
        })
        .collect();
    let within = |a: usize, b: usize| {
        (0..3).all(|k| boxes[b].0[k] <= boxes[a].0[k] && boxes[a].1[k] <= boxes[b].1[k])
    };
    for (b, outer) in pieces.iter().enumerate() {
        let inner: Vec<usize> = (0..pieces.len())
            .filter(|&a| a != b && within(a, b))
            .collect();
        if inner.is_empty() {
            continue;
        }
        let points: Vec<Point<3>> = outer.iter().map(|&i| positions[i as usize]).collect();
        let tree = Tree::new_from_slice(&points).expect("finite points");
        for a in inner {
            let piece = pieces[a];
            let stride = piece.len().div_ceil(NESTING_SAMPLES).max(1);
            let (mut behind, mut tried) = (0usize, 0usize);
            for &i in piece.iter().step_by(stride) {
                let x = positions[i as usize];
                let nearest = tree
                    .query(&x)
                    .nearest_one::<SquaredEuclidean<f64>>()
                    .execute();
                let j = outer[nearest.item as usize] as usize;
                tried += 1;
                if geometry::dot(&geometry::sub(&x, &positions[j]), &normals[j]) < 0.0 {
                    behind += 1;
                }
            }
            if behind as f64 >= NESTED_SHARE * tried as f64 && encloses(positions, outer, piece) {
                depths[a] += 1;
            }
        }
    }
    depths
}

/// Whether `outer`'s points surround `inner`: seen from each of [`ENCLOSURE_VIEWS`] of
/// `inner`'s points (evenly spread), every one of [`ENCLOSURE_DIRECTIONS`] directions (a
/// Fibonacci lattice on the sphere) has a point of `outer` within [`ENCLOSURE_CONE`] degrees
/// of it, at all but one view. Lying behind the nearest points is not enough: every chord of a
/// convex surface lies behind it, so a cap cut off a sphere by a gap, or a ball resting in a
/// bowl or an open crate, passed that test and was turned inward (a review's cases); the open
/// side leaves directions empty.
fn encloses(positions: &[Point<3>], outer: &[u32], inner: &[u32]) -> bool {
    let directions: Vec<Point<3>> = (0..ENCLOSURE_DIRECTIONS)
        .map(|k| {
            let z = 1.0 - (2 * k + 1) as f64 / ENCLOSURE_DIRECTIONS as f64;
            let r = (1.0 - z * z).sqrt();
            let t = k as f64 * 2.399_963_229_728_653;
            [r * t.cos(), r * t.sin(), z]
        })
        .collect();
    let cone = ENCLOSURE_CONE.to_radians().cos();
    let stride = inner.len().div_ceil(ENCLOSURE_VIEWS).max(1);
    let views: Vec<usize> = inner.iter().step_by(stride).map(|&i| i as usize).collect();
    let open = views
        .iter()
        .filter(|&&v| {
            let mut seen = vec![false; directions.len()];
            for &j in outer {
                let d = geometry::sub(&positions[j as usize], &positions[v]);
                let length = geometry::norm(&d);
                if length == 0.0 {
                    continue;
                }
                for (k, dir) in directions.iter().enumerate() {
                    if !seen[k] && geometry::dot(&d, dir) >= cone * length {
                        seen[k] = true;
                    }
                }
            }
            !seen.iter().all(|s| *s)
        })
        .count();
    open <= 1
}

/// The points of a piece [`encloses`] looks out from.
const ENCLOSURE_VIEWS: usize = 8;

/// The directions [`encloses`] looks along from each view.
const ENCLOSURE_DIRECTIONS: usize = 64;

/// The half-angle, in degrees, of the cone about each direction in which [`encloses`] wants a
/// point of the outer piece (64 directions lie about 14.5° apart).
const ENCLOSURE_CONE: f64 = 15.0;

/// The share of a piece's points that must lie behind another piece's surface for it to count
/// as inside that piece ([`EstimatedNormals::nested`]): all but a few, so that a piece beside
/// an open or concave one is not taken for a cavity.
pub const NESTED_SHARE: f64 = 0.9;

/// The points of a piece [`EstimatedNormals::nested`]'s test reads, at most.
const NESTING_SAMPLES: usize = 2000;

/// The most large pieces whose nesting is looked for (each pair is tested).
pub const MAX_NESTING_PIECES: usize = 32;
