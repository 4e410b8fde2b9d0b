//! [`fit_mras`]: the adaptive octree fit of paper 004 §5.1 (see the module docs).

use std::collections::BTreeMap;
use std::num::NonZero;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use faer::Mat;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;
use zeroset_field_core::geometry::{self, Aabb, Point};
use zeroset_tensor::thin_svd;

use super::MrasError;
use super::field::CellSpline;
use super::field::{LevelGeometry, MAX_LEVEL, MrasCell, MrasField, MrasLevel};
use super::local::{
    CellSolve, CpBound, LAMBDA_SCALE_CAP, LocalSettings, Target, ThinPlate, compress_cell,
    solve_cell,
};
use crate::meeting::{Meeting, meeting};
use crate::outliers::Tree as NeighbourTree;
use crate::rbf::NORMAL_NEIGHBOURS;

/// Options of [`fit_mras`]. The paper's values where it gives one; the others measured on
/// `bunny_points.ply` and `kitten.xyz` (the issue note has the runs), in the normalised energy of
/// the module docs (so the paper's λ and ω₂ ranges do not carry over):
///
/// | option | default | paper | why |
/// |---|---|---|---|
/// | `tolerance` | 1e-3 of the box diagonal | `ε₀`, user's | the split threshold; also scales λ |
/// | `max_level` | 8 | 4–5 (Table 2) | N_min stops the bunny at 7 |
/// | `lambda` | 0.3 | `[0.01, 0.05]` (unnormalised) | bunny storage 1.9× → 3.6× smaller than λ = 0.02 for a 2% larger max error |
/// | `omega1` | 5e-5 | `[5e-5, 1e-3]` | 1e-3 leaves the kitten at 4.5e-3 (normals fight positions), 5e-5 at 2.7e-3 |
/// | `omega2` | 1e-8 | not given | 1e-6 doubles the bunny's max error |
/// | `omega2_root` | 3e-6 | (ω₂) | the root level decides the field far from the points: 1e-8 there leaves a spurious sheet (bunny_2k: 2 components), 3e-6 none; single-level sphere rank 10 at 7.0e-4, torus 10 at 2.1e-3 (1e-5 smooths the torus to 7e-3; Fig. 5's ranks with 1e-8 and λ = 20: `mras_tables -- shapes`) |
/// | `omega2_decay` | 10 | — | per level, from `omega2_root` to `omega2` (3e-7 at level 2, 3e-8 at 3, then 1e-8). 100 (3e-8 at level 2, then 1e-8) left the coarse levels' cells free where their support has no points: on the bunny with Gaussian position noise of 0.5% of the diagonal, a sheet at the cube's corner (2 components, open), on the kitten with 0.75% two components; 10 removes both and changes no clean fit's outcome at the default depth (bunny numbers / max / mean 294k, 4.498e-3, 3.497e-4 → 290k, 4.504e-3, 3.513e-4; kitten 104k → 101k, max 4.14e-3 → 4.10e-3; the sweep of `benches/peers/noise_peers.py` and the synthetic shapes of the stray-point sweep: never more components). Shallow fits follow their points less closely: 2 levels on a 2,000-point sphere left 10 unfiltered stray points within 0.055 of zero (below 0.05 before) |
/// | `m0`, `beta` | 12, 1 | `m_k = m₀ − ⌊βk⌋`, `β ∈ [1, 3]` | 13 costs 1.6× the time for the same error; `β` = 0.5 (12, 11, 11, 10, …, 9 B-splines) on the bunny: 229k numbers, max / mean 4.35e-3 / 3.07e-4, 5.4× the time (42.8 s) |
/// | `min_knots` | 6 | — | the coarsest deep-level spline. Bunny, numbers / fitted cells uncompressed / max / mean / fit time (2 threads): **6 → 223k, 7.7×, 4.79e-3, 3.51e-4, 8.2 s** (max first quoted as 4.50e-3; 4.79e-3 re-measured 2026-12-06 on this commit and on the one that set the default); 7 → 233k, 9.7×, 4.86e-3, 3.39e-4, 11.7 s; 8 → 230k, 12.6×, 4.44e-3, 3.26e-4, 17.8 s. Finer splines at the deep levels raise the ratio to the uncompressed count (their cells are mostly rank 1, and `m³/3m` grows with `m`) but not what is stored, and cost time |
/// | `alpha` | 0.75 | 0.75 | |
/// | `n_min` | 16 | 16 | |
/// | `eta`, `relaxation` | 0.3 (× the c-step's mean diagonal), 1.6 | η = 1, no relaxation | ADMM warm-started at η = 1 stops after 1–3 iterations at levels 3–4 (its residuals are small against the start's); over-relaxed at η = 0.3 it runs 7–36 and lowers the ranks: bunny 385k → 326k numbers, kitten 124k → 102k, max distance within 2–3%, mean 2% lower; η from 0.2 to 0.5 stores within 4% |
/// | `admm_max_iter`, `admm_tol` | 50, 1e-3 | "c barely changes" | warm-started, more iterations change nothing measurable |
/// | `cp_scale`, `cp_points` | 0, 0.5 | `ε_cp^k = 10^{−k−1}` | the bound at the data points (see [`MrasOptions::cp_points`]): bunny 3.3× → 3.8× smaller than uncompressed, same error. With rank 0 and `cp_refined` = 1, bunny numbers / max / mean distance: 0.4 → 333k, 4.47e-3, 3.29e-4; **0.5 → 294k, 4.50e-3, 3.50e-4**; 0.75 → 222k, 5.12e-3, 4.09e-4; 1 → 174k, 5.78e-3, 4.74e-4 (measured with `omega2_decay` 100; with 10 the default gives 290k, 4.50e-3, 3.51e-4, kitten 101k) |
/// | `outlier_ratio` | 3 | — (the paper's scans are clean) | see [`crate::outliers`]: the bunny with 2% stray points in its box (random normals) broke into 23 components with open sheets; with the outliers this finds set aside, one closed bunny (`benches/peers/stray_peers.py`). None found on the bunny, kitten and `bunny_2k` samples; 2 would cut a flattened ellipsoid's rim |
/// | `cp_weighted` | true | — (plain CP-ALS) | each rank fitted in the points' weights where plain CP-ALS misses the bound at the points (module docs): bunny numbers / max / mean distance 290k, 4.50e-3, 3.51e-4 → **218k**, 4.58e-3, 3.52e-4 (7.9× fewer than its fitted cells uncompressed, was 5.8×); kitten 101k → 68k (max 4.10e-3 → 4.16e-3); `bunny_2k` 129k → 85k; the noisy bunny and kitten copies of `benches/peers/noise_peers.py` 25–40% fewer; one component on each; fit time +0.7 s on the bunny (8.6 → 9.3 s). The `cp_points` and `cp_refined` rows were measured with plain CP-ALS |
/// | `cp_refined` | 1 | (`10^{−k−1}` loosens the coarse levels) | bunny numbers / max / mean: 0 → 318k, 4.50e-3, 3.48e-4; 0.5 → 312k, 4.49e-3, 3.49e-4; **1 → 294k, 4.50e-3, 3.50e-4**; kitten 0.5 → 107k, 1 → 104k at the same errors. The bound it replaced (`cp_points · max(ε₀, e/16)` at every point, `e` the previous level's largest Sampson distance) stored 3–8% less where it worked, and dropped whole levels where it did not (bunny with `m₀` 10 or 11: 0.18 / 0.33 of the diagonal; now 4.5e-3 / 4.7e-3) (measured with `omega2_decay` 100; with 10 the default gives 290k, 4.50e-3, 3.51e-4, kitten 101k) |
#[derive(Debug, Clone, PartialEq)]
pub struct MrasOptions {
    /// The target largest distance from the points to the surface, as a fraction of the points'
    /// bounding-box diagonal: the split threshold `ε₀` on the Sampson distance.
    pub tolerance: f64,
    /// The deepest level (the root is level 1).
    pub max_level: u32,
    /// The trace-norm weight `λ` (dimensionless; see the module docs).
    pub lambda: f64,
    /// The normal weight `ω₁`.
    pub omega1: f64,
    /// The thin-plate weight `ω₂` of levels 2, 3, ….
    pub omega2: f64,
    /// The thin-plate weight of the root level, which alone decides the field far from the
    /// points: stronger, so that no spurious sheet appears there.
    pub omega2_root: f64,
    /// The factor the thin-plate weight falls by from one level to the next, from `omega2_root`
    /// down to `omega2` ([`MrasOptions::omega2_at`]); at least 1.
    pub omega2_decay: f64,
    /// `m₀` of `m_k = m₀ − ⌊βk⌋`.
    pub m0: usize,
    /// `β` of `m_k = m₀ − ⌊βk⌋`.
    pub beta: f64,
    /// The fewest B-splines per axis at any level.
    pub min_knots: usize,
    /// The partition-of-unity factor `α` (support radius `α` × the cell's diagonal).
    pub alpha: f64,
    /// A cell is split only when it holds more than this many points (`N_min`).
    pub n_min: usize,
    /// ADMM's penalty, in units of the c-step matrix's mean diagonal.
    pub eta: f64,
    /// ADMM's over-relaxation `ρ ∈ (0, 2)` ([`zeroset_solvers::admm::AdmmOptions::relaxation`]).
    pub relaxation: f64,
    /// ADMM's iteration limit per cell.
    pub admm_max_iter: usize,
    /// ADMM's relative tolerance.
    pub admm_tol: f64,
    /// Compress each cell by CP (false: keep the full tensors, the uncompressed MRAS).
    pub compress: bool,
    /// Scale of Algorithm 2's bound as the paper words it, `‖C − Ĉ‖ ≤ cp_scale · 10^{−k−1}`;
    /// 0: bound the error at the data points instead (`cp_points`).
    pub cp_scale: f64,
    /// Algorithm 2's bound at the data points, `|φ̂ − φ| ≤ cp_points · ε₀ · slack` (`slack`
    /// 1 except where [`MrasOptions::cp_refined`] loosens it).
    pub cp_points: f64,
    /// Where the next level refines a cell (decided on the level before compression), its
    /// points' `slack` is `max(1, cp_refined · r/ε₀)`, `r` the largest residual `|f^k|` the
    /// cell's own points keep: the next level fits those points again, so only the points the
    /// field ends on need the tight bound. 0: the same bound everywhere.
    pub cp_refined: f64,
    /// Under the bound at the data points (`cp_scale` 0), fit each CP rank in the norm the
    /// points read the coefficients in (weighted CP-ALS, [`zeroset_tensor::weighted`]) where
    /// plain CP-ALS misses the bound; false: plain CP-ALS only.
    pub cp_weighted: bool,
    /// The cube's margin around the bounding box, as a fraction of its largest side (each side).
    pub margin: f64,
    /// Points whose spacing (mean distance to their 8 nearest) exceeds this many times the
    /// median, and that do not lie on a surface with their neighbours, are outliers, as are
    /// points off a clean patch of surface with a normal of their own: set aside before fitting
    /// ([`crate::outliers`]; [`MrasFit::outliers`] lists them). 0: fit every point.
    pub outlier_ratio: f64,
}

impl Default for MrasOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-3,
            max_level: 8,
            lambda: 0.3,
            omega1: 5e-5,
            omega2: 1e-8,
            omega2_root: 3e-6,
            omega2_decay: 10.0,
            m0: 12,
            beta: 1.0,
            min_knots: 6,
            alpha: 0.75,
            n_min: 16,
            eta: 0.3,
            relaxation: 1.6,
            admm_max_iter: 50,
            admm_tol: 1e-3,
            compress: true,
            cp_scale: 0.0,
            cp_points: 0.5,
            cp_refined: 1.0,
            cp_weighted: true,
            margin: 0.05,
            outlier_ratio: crate::outliers::DEFAULT_OUTLIER_RATIO,
        }
    }
}

macro_rules! setter {
    ($(#[$doc:meta] $name:ident: $ty:ty),* $(,)?) => {
        impl MrasOptions {
            $(#[$doc] pub fn $name(mut self, $name: $ty) -> Self {
                self.$name = $name;
                self
            })*
        }
    };
}

setter! {
    /// With target tolerance `tolerance` (fraction of the box diagonal).
    tolerance: f64,
    /// With at most `max_level` levels.
    max_level: u32,
    /// With trace-norm weight `lambda`.
    lambda: f64,
    /// With normal weight `omega1`.
    omega1: f64,
    /// With thin-plate weight `omega2` (levels 2, 3, …).
    omega2: f64,
    /// With root-level thin-plate weight `omega2_root`.
    omega2_root: f64,
    /// With the thin-plate weight falling by `omega2_decay` per level.
    omega2_decay: f64,
    /// With `m₀ = m0` B-splines per axis at level 0.
    m0: usize,
    /// With `β = beta`.
    beta: f64,
    /// With CP compression on or off.
    compress: bool,
    /// With the weighted CP fit at the data points on or off.
    cp_weighted: bool,
    /// With ADMM iteration limit `admm_max_iter`.
    admm_max_iter: usize,
    /// With outlier ratio `outlier_ratio` (0: no points set aside).
    outlier_ratio: f64,
}

impl MrasOptions {
    /// The thin-plate weight at level `k`: `max(ω₂_root / decay^{k−1}, ω₂)` — strong at the
    /// coarse levels, whose large cells decide the field far from the points, weak at the fine
    /// ones, which must follow the points.
    pub fn omega2_at(&self, level: u32) -> f64 {
        (self.omega2_root / self.omega2_decay.powi(level as i32 - 1)).max(self.omega2)
    }

    /// B-splines per axis at level `k`: `max(m₀ − ⌊βk⌋, min_knots)`.
    pub fn knots(&self, level: u32) -> usize {
        let drop = (self.beta * f64::from(level)).floor() as usize;
        self.m0.saturating_sub(drop).max(self.min_knots)
    }

    /// Checks every option's range ([`fit_mras`] does so too, before it looks at the points).
    ///
    /// # Errors
    /// [`MrasError::Option`], naming the first option out of its range.
    pub fn validate(&self) -> Result<(), MrasError> {
        let check = |name, value: f64, ok: bool, reason| {
            if ok {
                Ok(())
            } else {
                Err(MrasError::Option {
                    name,
                    value,
                    reason,
                })
            }
        };
        let t = self.tolerance;
        check(
            "tolerance",
            t,
            t.is_finite() && t > 0.0 && t < 1.0,
            "must be in (0, 1)",
        )?;
        let l = f64::from(self.max_level);
        check(
            "max_level",
            l,
            (1..=MAX_LEVEL).contains(&self.max_level),
            "must be 1 to 20",
        )?;
        for (name, v) in [
            ("lambda", self.lambda),
            ("omega1", self.omega1),
            ("omega2", self.omega2),
            ("omega2_root", self.omega2_root),
        ] {
            check(name, v, v.is_finite() && v >= 0.0, "must be finite and ≥ 0")?;
        }
        check(
            "omega1",
            self.omega1,
            self.omega1 > 0.0,
            "must be > 0 (the normals fix the scale)",
        )?;
        check(
            "omega2_decay",
            self.omega2_decay,
            self.omega2_decay.is_finite() && self.omega2_decay >= 1.0,
            "must be finite and ≥ 1",
        )?;
        check(
            "beta",
            self.beta,
            self.beta.is_finite() && self.beta >= 0.0,
            "must be ≥ 0",
        )?;
        let mk = self.min_knots as f64;
        check(
            "min_knots",
            mk,
            (4..=24).contains(&self.min_knots),
            "must be 4 to 24",
        )?;
        let m0 = self.m0 as f64;
        check("m0", m0, (4..=24).contains(&self.m0), "must be 4 to 24")?;
        let a = self.alpha;
        check(
            "alpha",
            a,
            a.is_finite() && a > 0.5 && a <= 2.0,
            "must be in (0.5, 2]",
        )?;
        let rho = self.relaxation;
        check(
            "relaxation",
            rho,
            rho > 0.0 && rho < 2.0,
            "must be in (0, 2)",
        )?;
        check(
            "eta",
            self.eta,
            self.eta.is_finite() && self.eta > 0.0,
            "must be > 0",
        )?;
        let it = self.admm_max_iter as f64;
        check("admm_max_iter", it, self.admm_max_iter > 0, "must be > 0")?;
        let tol = self.admm_tol;
        check("admm_tol", tol, tol.is_finite() && tol > 0.0, "must be > 0")?;
        let cr = self.cp_refined;
        check(
            "cp_refined",
            cr,
            cr.is_finite() && cr >= 0.0,
            "must be finite and ≥ 0",
        )?;
        let or = self.outlier_ratio;
        check(
            "outlier_ratio",
            or,
            crate::outliers::valid_ratio(or),
            "must be 0 (off) or ≥ 1.5 (below, most of a surface's points would be isolated)",
        )?;
        let mg = self.margin;
        check(
            "margin",
            mg,
            mg.is_finite() && (0.0..=1.0).contains(&mg),
            "must be in [0, 1]",
        )?;
        Ok(())
    }
}

/// Progress of [`fit_mras`], reported after every cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MrasProgress {
    /// The level being fitted (from 1).
    pub level: u32,
    /// `false` while the level's cells are fitted (ADMM), `true` while they are compressed
    /// (CP): each cell passes both stages, the second after every cell finished the first.
    pub compressing: bool,
    /// Cells of this level through the current stage so far.
    pub cells_done: usize,
    /// Cells of this level to fit.
    pub cells_total: usize,
    /// The largest Sampson distance after the previous level, relative to the box diagonal
    /// (`None` at level 1).
    pub error: Option<f64>,
}

/// What one level of a fit did.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelReport {
    /// The level (from 1).
    pub level: u32,
    /// B-splines per axis.
    pub knots: usize,
    /// Cells stored.
    pub cells: usize,
    /// Cells fitted but not stored: their offset `φ = 0` met the CP bound (rank 0), and the
    /// blend counts a cell that is not stored as `φ = 0`.
    pub dropped: usize,
    /// Cells stored as full tensors (CP would not save storage).
    pub full_cells: usize,
    /// Smallest, mean and largest CP rank.
    pub ranks: (usize, f64, usize),
    /// Numbers stored (splines and blending functions).
    pub stored: usize,
    /// Numbers the fitted cells (stored and dropped) take uncompressed: `m³ + 4` each.
    pub uncompressed: usize,
    /// Mean data points per cell (inside the support).
    pub mean_points: f64,
    /// Mean ADMM iterations per cell (0 for a cell whose offset without the trace norm already
    /// met the CP bound at rank 0: ADMM does not run there).
    pub mean_admm_iterations: f64,
    /// The largest error Algorithm 2 stopped at in a cell, in the bound's units (unit-cube
    /// field values at the data points, each divided by its slack, or the tensor's Frobenius
    /// norm with `cp_scale`).
    pub max_cp_error: f64,
    /// The largest Sampson distance `|f^k|/|∇f^k|` over all points after this level, relative to
    /// the box diagonal.
    pub max_error: f64,
    /// The mean Sampson distance, relative to the box diagonal.
    pub mean_error: f64,
    /// Cells split for the next level.
    pub split: usize,
    /// Wall-clock seconds for the level.
    pub seconds: f64,
}

/// What [`fit_mras`] returns.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct MrasFit {
    /// The field.
    pub field: MrasField<3>,
    /// One report per level.
    pub levels: Vec<LevelReport>,
    /// The points' bounding-box diagonal (world units), the unit of the relative errors.
    pub diagonal: f64,
    /// Exact duplicate positions merged before fitting.
    pub duplicates: usize,
    /// Of the places where [`MrasFit::duplicates`] were merged, those where normals pointing
    /// apart meet as two sheets (a mesh touching itself, two solids touching, a crease's split
    /// normals), judged by the normals around: fitted with value 0 and the two unit normals'
    /// mean as the gradient (short where they point nearly opposite ways: the field is flat
    /// there by design and not counted in [`MrasFit::flat_points`]). They are not measured
    /// (not in the levels' errors nor [`MrasFit::points_over_tolerance`], and they do not make
    /// a cell split): no smooth field follows two sheets into the place where they touch (a
    /// neck or a gap forms around it, about as wide as without the place's sample), and
    /// neither `|f|` nor the Sampson distance `|f|/|∇f|` is a distance there. Where the points
    /// around all face one of the two ways, the place is one sheet with a flipped normal,
    /// fitted with that side (not counted here). Copies whose normals differ without pointing
    /// apart (a crease's split normals) are fitted with the mean of their unit normals.
    pub touching: usize,
    /// The input points set aside as outliers ([`MrasOptions::outlier_ratio`]), by index,
    /// increasing; the field is not fitted to them.
    pub outliers: Vec<usize>,
    /// Points isolated by their spacing but kept as a sparse patch of surface.
    pub kept_sparse: usize,
    /// The tolerance fitted to ([`MrasOptions::tolerance`], a fraction of `diagonal`).
    pub tolerance: f64,
    /// The fitted points whose Sampson distance `|f|/|∇f|` to the final field exceeds the
    /// tolerance: 0 where it is met ([`MrasFit::tolerance_met`]). The subdivision stops short
    /// of it where a cell holds `N_min` points or fewer ([`MrasOptions::n_min`]: too few to fit
    /// an offset to), at the level cap, and where a cell's points were within the tolerance
    /// when its level was fitted (a finer level beside it, blended in by the partition of
    /// unity, can move them again; such a cell is not fitted again).
    pub points_over_tolerance: usize,
    /// Cells of the last level that would have been split further but for the level cap
    /// ([`MrasOptions::max_level`]).
    pub capped_cells: usize,
    /// The fitted points where the final field is nearly flat, `|∇f| <` [`FLAT_GRADIENT`]
    /// (a fit wants `|∇f| ≈ 1` there): its zero set need not pass near them whatever their
    /// Sampson distance says. A trace-norm weight far too large for the data (`λ`) shrinks the
    /// offsets to this.
    pub flat_points: usize,
    /// The points fitted: distinct (duplicates merged) and not set aside as outliers, what
    /// [`MrasFit::flat_points`] and [`MrasFit::points_over_tolerance`] count among.
    pub fitted_points: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl MrasFit {
    /// Whether every fitted point's Sampson distance is within the tolerance.
    pub fn tolerance_met(&self) -> bool {
        self.points_over_tolerance == 0
    }

    /// The largest Sampson distance over the fitted points after the last level, as a
    /// fraction of the diagonal (0 for a fit with no level).
    pub fn max_error(&self) -> f64 {
        self.levels.last().map_or(0.0, |l| l.max_error)
    }
}

/// Fits an MRAS field to points with outward normals (paper 004; see the module docs).
/// `progress` is called from worker threads after each cell; when it answers `false` the fit
/// stops ([`MrasError::Cancelled`]) as soon as the cells in progress are done.
///
/// Points at exactly one position are fitted as one ([`MrasFit::duplicates`]); where their
/// normals point apart, as two sheets meeting there or as one with a flipped normal, as the
/// points around say ([`MrasFit::touching`]).
///
/// # Errors
/// Bad input: [`MrasError::Normals`], [`MrasError::NonFinite`], [`MrasError::ZeroNormal`],
/// [`MrasError::TooFewPoints`] (fewer than `N_min`
/// distinct points), [`MrasError::Degenerate`] (all points on a plane or line),
/// [`MrasError::Option`]; numerical breakdowns as [`MrasError::Admm`] or [`MrasError::Tensor`];
/// [`MrasError::Cancelled`] when `progress` answers `false`.
pub fn fit_mras(
    positions: &[Point<3>],
    normals: &[Point<3>],
    options: &MrasOptions,
    progress: &(dyn Fn(&MrasProgress) -> bool + Sync),
) -> Result<MrasFit, MrasError> {
    let start = Instant::now();
    options.validate()?;
    let cloud = Cloud::new(positions, normals, options)?;
    let diagonal = cloud.diagonal;
    let eps0 = options.tolerance * diagonal / cloud.side;
    let u = &cloud.u;
    let np = u.len();
    let mut f = vec![0.0; np];
    let mut grad = vec![[0.0; 3]; np];
    let mut field = MrasField::new(cloud.origin, cloud.side, options.alpha, Vec::new())
        .map_err(MrasError::Field)?;
    let mut reports = Vec::new();
    let mut to_fit: Vec<[u64; 3]> = vec![[0, 0, 0]];
    let mut last_error = None;
    // After the last level: the points beyond ε₀, and the cells the level cap kept unsplit.
    let (mut points_over, mut capped, mut flat) = (positions.len(), 0, 0);
    // No slack: the screen before ADMM and the levels that nothing refines.
    let tight = vec![1.0; np];
    for level in 1..=options.max_level {
        if to_fit.is_empty() {
            break;
        }
        let t0 = Instant::now();
        let m = options.knots(level);
        let g = LevelGeometry::new(3, level, m, options.alpha);
        let buckets = Buckets::new(u, g.lattice);
        let plate = ThinPlate::new(m);
        let settings = LocalSettings {
            omega1: options.omega1,
            omega2: options.omega2_at(level),
            lambda: options.lambda,
            value_scale: eps0,
            lambda_scale: eps0.min(LAMBDA_SCALE_CAP * diagonal / cloud.side),
            zero_allowed: level > 1,
            eta: options.eta,
            relaxation: options.relaxation,
            admm_max_iter: options.admm_max_iter,
            admm_tol: options.admm_tol,
            cp_bound: options.compress.then(|| {
                if options.cp_scale > 0.0 {
                    CpBound::Tensor(options.cp_scale * 10f64.powi(-(level as i32) - 1))
                } else if options.cp_weighted {
                    CpBound::PointsWeighted(options.cp_points * eps0)
                } else {
                    CpBound::Points(options.cp_points * eps0)
                }
            }),
        };
        // The targets of one cell; `slack` per point (see `MrasOptions::cp_refined`).
        let targets_of = |index: [u64; 3], slack: &[f64]| {
            let mut targets = gather(&buckets, &g, index, &cloud, &f, &grad, slack, level > 1);
            if level == 1 {
                targets.extend(far_field(&cloud.u));
            }
            targets
        };
        let total = to_fit.len();
        let done = AtomicUsize::new(0);
        let report = |compressing: bool| {
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            let go_on = progress(&MrasProgress {
                level,
                compressing,
                cells_done: d,
                cells_total: total,
                error: last_error,
            });
            if go_on {
                Ok(())
            } else {
                Err(MrasError::Cancelled)
            }
        };
        // 1. Every cell's minimiser of eq. 14 (ADMM), the screen holding every point to the CP
        //    bound itself: its index, solution and number of targets.
        let solved: Vec<Option<([u64; 3], CellSolve, usize)>> = to_fit
            .par_iter()
            .map(|&index| {
                let targets = targets_of(index, &tight);
                let out = if targets.is_empty() {
                    None
                } else {
                    let solution = solve_cell(&g, index, &targets, &plate, &settings)?;
                    Some((index, solution, targets.len()))
                };
                report(false)?;
                Ok(out)
            })
            .collect::<Result<_, MrasError>>()?;
        let solved: Vec<_> = solved.into_iter().flatten().collect();
        if solved.is_empty() {
            break;
        }
        let mean_points = solved.iter().map(|c| c.2 as f64).sum::<f64>() / solved.len() as f64;
        let mean_iters = solved
            .iter()
            .map(|c| c.1.admm_iterations as f64)
            .sum::<f64>()
            / solved.len() as f64;
        let fitted_indices: Vec<[u64; 3]> = solved.iter().map(|c| c.0).collect();
        let may_refine = level < options.max_level;
        // 2. The cells the next level refines, judged on the uncompressed level: the next level
        //    fits their points again, so there the CP error may reach `cp_refined` times the
        //    largest residual `|f^k|` the cell's own points keep (not less than the bound).
        let mut refined_early = vec![false; solved.len()];
        let slack = if settings.cp_bound.is_some_and(CpBound::at_points)
            && may_refine
            && options.cp_refined > 0.0
        {
            let cells = solved
                .iter()
                .filter_map(|(index, solution, _)| {
                    let c = solution.coefficients.clone()?;
                    Some(MrasCell {
                        index: index.map(|i| i as u32),
                        spline: CellSpline::Full { coefficients: c },
                    })
                })
                .collect();
            let full = MrasLevel::new(level, m, cells).map_err(MrasError::Field)?;
            // Only the own points of the cells fitted here decide (at the deep levels most
            // points lie in none of them): their residual |f^k| and Sampson distance.
            let own: Vec<u32> = fitted_indices
                .iter()
                .flat_map(|&index| buckets.points(index))
                .copied()
                .collect();
            let at: Vec<(f64, f64)> = own
                .par_iter()
                .map(|&i| {
                    let i = i as usize;
                    let (o, og) = field.level_offset(&full, &u[i], true);
                    let v = f[i] + o;
                    let g: Point<3> = std::array::from_fn(|a| grad[i][a] + og[a]);
                    (v.abs(), cloud.distance(i, v, &g))
                })
                .collect();
            let (mut residual, mut distance) = (vec![0.0; np], vec![0.0; np]);
            for (&i, &(r, d)) in own.iter().zip(&at) {
                (residual[i as usize], distance[i as usize]) = (r, d);
            }
            refined_early = refined(&buckets, &fitted_indices, &distance, eps0, options);
            let mut slack = tight.clone();
            for (index, _) in fitted_indices.iter().zip(&refined_early).filter(|r| *r.1) {
                let own = buckets.points(*index);
                let residual = own.iter().fold(0.0f64, |a, &i| a.max(residual[i as usize]));
                let cell_slack = (options.cp_refined * residual / eps0).max(1.0);
                for &i in own {
                    slack[i as usize] = cell_slack;
                }
            }
            Some(slack)
        } else {
            None
        };
        let slack = slack.as_deref().unwrap_or(&tight);
        // 3. Each cell's CP factors within the bound (times its points' slack).
        done.store(0, Ordering::Relaxed);
        let compressed: Vec<(Option<MrasCell<3>>, f64)> = solved
            .into_par_iter()
            .map(|(index, solution, _)| {
                let (spline, error) = match solution.coefficients {
                    None => (None, solution.screen_error),
                    Some(c) => {
                        let targets = targets_of(index, slack);
                        compress_cell(
                            &g,
                            index,
                            &targets,
                            c,
                            settings.cp_bound,
                            settings.zero_allowed,
                        )?
                    }
                };
                report(true)?;
                let cell = spline.map(|spline| MrasCell {
                    index: index.map(|i| i as u32),
                    spline,
                });
                Ok((cell, error))
            })
            .collect::<Result<_, MrasError>>()?;
        let cp_error = compressed.iter().map(|c| c.1).fold(0.0, f64::max);
        let cells: Vec<MrasCell<3>> = compressed.into_iter().filter_map(|c| c.0).collect();
        let dropped = fitted_indices.len() - cells.len();
        let lvl = MrasLevel::new(level, m, cells).map_err(MrasError::Field)?;
        // f^k and ∇f^k at every point (unit-cube units), and the Sampson distances.
        add_level(&field, &lvl, u, &mut f, &mut grad);
        let sampson = cloud.distances(&f, &grad);
        let max_error = sampson.iter().fold(0.0f64, |a, &b| a.max(b));
        let measured = cloud.touching.iter().filter(|&&t| !t).count();
        let mean_error = sampson.iter().sum::<f64>() / measured.max(1) as f64;
        // A cell splits where its own points need it after compression, or where step 2
        // promised the next level to its points (a cell not stored splits too).
        let mut next = Vec::new();
        points_over = sampson.iter().filter(|&&d| d > eps0).count();
        flat = grad
            .iter()
            .zip(&cloud.touching)
            .filter(|(g, touching)| {
                !**touching && g.iter().map(|v| v * v).sum::<f64>() < FLAT_GRADIENT * FLAT_GRADIENT
            })
            .count();
        // The cells whose own points need a finer level; at the level cap, those it stops.
        let late = refined(&buckets, &fitted_indices, &sampson, eps0, options);
        if may_refine {
            for ((index, early), late) in fitted_indices.iter().zip(refined_early).zip(late) {
                if early || late {
                    for child in 0..8u64 {
                        next.push([
                            2 * index[0] + (child >> 2),
                            2 * index[1] + ((child >> 1) & 1),
                            2 * index[2] + (child & 1),
                        ]);
                    }
                }
            }
        } else {
            capped = late.iter().filter(|r| **r).count();
        }
        let to_rel = cloud.side / diagonal;
        let ranks: Vec<usize> = lvl.cells().iter().filter_map(|c| c.spline.rank()).collect();
        let full_cells = lvl.cells().len() - ranks.len();
        reports.push(LevelReport {
            level,
            knots: m,
            cells: lvl.cells().len(),
            dropped,
            full_cells,
            ranks: (
                ranks.iter().copied().min().unwrap_or(0),
                ranks.iter().sum::<usize>() as f64 / ranks.len().max(1) as f64,
                ranks.iter().copied().max().unwrap_or(0),
            ),
            stored: lvl.stored_numbers() + lvl.cells().len() * 4,
            uncompressed: (m.pow(3) + 4) * fitted_indices.len(),
            mean_points,
            mean_admm_iterations: mean_iters,
            max_cp_error: cp_error,
            max_error: max_error * to_rel,
            mean_error: mean_error * to_rel,
            split: next.len() / 8,
            seconds: t0.elapsed().as_secs_f64(),
        });
        last_error = Some(max_error * to_rel);
        field.push_level(lvl).map_err(MrasError::Field)?;
        to_fit = next;
    }
    // The distinct input points, recorded for the mesh's spurious-component check.
    let unit = u.iter().map(|p| p.map(|v| v as f32)).collect();
    Ok(MrasFit {
        field: field.with_unit_points(unit),
        levels: reports,
        diagonal,
        duplicates: cloud.duplicates,
        touching: cloud.touching.iter().filter(|&&t| t).count(),
        outliers: cloud.outliers,
        kept_sparse: cloud.kept_sparse,
        tolerance: options.tolerance,
        points_over_tolerance: points_over,
        capped_cells: capped,
        flat_points: flat,
        fitted_points: np,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The gradient magnitude below which [`MrasFit::flat_points`] counts a point (a fit wants 1).
pub const FLAT_GRADIENT: f64 = 0.1;

/// Adds level `lvl`'s offset and its gradient to `f` and `grad` at the points `u`.
fn add_level(
    field: &MrasField<3>,
    lvl: &MrasLevel<3>,
    u: &[Point<3>],
    f: &mut [f64],
    grad: &mut [Point<3>],
) {
    u.par_iter()
        .zip(f.par_iter_mut())
        .zip(grad.par_iter_mut())
        .for_each(|((p, fv), gv)| {
            let (o, og) = field.level_offset(lvl, p, true);
            *fv += o;
            for a in 0..3 {
                gv[a] += og[a];
            }
        });
}

/// The Sampson distance `|f| / |∇f|` of value `f` and gradient `g` (infinite where `∇f = 0`).
fn sampson_distance(f: f64, g: &Point<3>) -> f64 {
    let n = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if n > 0.0 { f.abs() / n } else { f64::INFINITY }
}

/// §5.1's rule per fitted cell: split where it holds more than `N_min` points of its own and
/// the largest Sampson distance among them exceeds `ε₀`.
fn refined(
    buckets: &Buckets,
    cells: &[[u64; 3]],
    sampson: &[f64],
    eps0: f64,
    options: &MrasOptions,
) -> Vec<bool> {
    cells
        .iter()
        .map(|&index| {
            let own = buckets.points(index);
            own.len() > options.n_min
                && own.iter().fold(0.0f64, |a, &i| a.max(sampson[i as usize])) > eps0
        })
        .collect()
}

/// The checked, de-duplicated cloud in unit-cube coordinates.
struct Cloud {
    u: Vec<Point<3>>,
    /// The gradient each point is fitted to: its unit normal, or where copies of it differ
    /// (two sheets meeting, a crease's split normals) the mean of theirs.
    normals: Vec<Point<3>>,
    /// Per point, whether two sheets meet there ([`sheets_meeting`]): the field is flat
    /// there by design, and the point is not measured ([`Cloud::distance`]).
    touching: Vec<bool>,
    origin: Point<3>,
    side: f64,
    diagonal: f64,
    duplicates: usize,
    /// Input indices set aside as outliers.
    outliers: Vec<usize>,
    kept_sparse: usize,
}

impl Cloud {
    /// The Sampson distance `|f| / |∇f|` of fitted point `i` to the zero set of a field of
    /// value `f` and gradient `g` there — 0 where two sheets meet, which is not measured: no
    /// smooth field follows two sheets into the place where they touch (a neck or a gap forms
    /// around it), and its gradient vanishes there by design. Neither `|f|` (which understated
    /// such a place's distance to the mesh 10–80 times) nor the Sampson distance (which
    /// overstated it 6 times) is a distance there.
    fn distance(&self, i: usize, f: f64, g: &Point<3>) -> f64 {
        if self.touching[i] {
            0.0
        } else {
            sampson_distance(f, g)
        }
    }

    /// [`Cloud::distance`] at every point (unit-cube units).
    fn distances(&self, f: &[f64], grad: &[Point<3>]) -> Vec<f64> {
        (f, grad)
            .into_par_iter()
            .enumerate()
            .map(|(i, (&v, g))| self.distance(i, v, g))
            .collect()
    }

    /// The distinct, finite points with unit normals, outliers set aside, in the unit cube.
    fn new(
        positions: &[Point<3>],
        normals_in: &[Point<3>],
        options: &MrasOptions,
    ) -> Result<Self, MrasError> {
        let normals = normals_in;
        let (n_min, margin) = (options.n_min, options.margin);
        if normals.len() != positions.len() {
            return Err(MrasError::Normals {
                points: positions.len(),
                normals: normals.len(),
            });
        }
        for (index, (p, n)) in positions.iter().zip(normals).enumerate() {
            if p.iter().any(|v| !v.is_finite()) {
                return Err(MrasError::NonFinite {
                    index,
                    what: "position",
                    value: *p,
                });
            }
            if n.iter().any(|v| !v.is_finite()) {
                return Err(MrasError::NonFinite {
                    index,
                    what: "normal",
                    value: *n,
                });
            }
            let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if length < 1e-6 {
                return Err(MrasError::ZeroNormal {
                    index,
                    normal: *n,
                    length,
                });
            }
        }
        // Exact duplicates: one point each, the first. Where a repeat's normal points against
        // the first's, the points around say which (`crate::meeting`); where the normals differ
        // less (a crease's split normals), their mean is fitted.
        let mut order: Vec<usize> = (0..positions.len()).collect();
        let key = |i: usize| positions[i].map(f64::to_bits);
        order.sort_by_key(|&i| (key(i), i));
        let mut keep = vec![true; positions.len()];
        let mut duplicates = 0;
        let unit = |n: &Point<3>| {
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            n.map(|v| v / l)
        };
        // The first of each place, and the first repeat whose normal points against its own.
        let mut apart: Vec<(usize, usize)> = Vec::new();
        // The places whose copies' normals differ without pointing apart: their mean.
        let mut creases: BTreeMap<usize, Point<3>> = BTreeMap::new();
        let mut start = 0;
        while start < order.len() {
            let a = order[start];
            let end = start + order[start..].partition_point(|&i| key(i) == key(a));
            let repeats = &order[start + 1..end];
            for &b in repeats {
                keep[b] = false;
            }
            duplicates += repeats.len();
            let na = unit(&normals[a]);
            if let Some(&b) = repeats
                .iter()
                .find(|&&b| geometry::dot(&na, &unit(&normals[b])) < 0.0)
            {
                apart.push((a, b));
            } else if repeats.iter().any(|&b| unit(&normals[b]) != na) {
                let sum = order[start..end]
                    .iter()
                    .fold([0.0; 3], |sum, &c| geometry::add(&sum, &unit(&normals[c])));
                creases.insert(a, geometry::scale(1.0 / (end - start) as f64, &sum));
            }
            start = end;
        }
        let (normals, touching) = sheets_meeting(positions, normals, &keep, &apart);
        let normals = normals.as_deref().unwrap_or(normals_in);
        let mut idx: Vec<usize> = (0..positions.len()).filter(|&i| keep[i]).collect();
        // Outliers: before the box, which they would stretch.
        let found = {
            let p: Vec<Point<3>> = idx.iter().map(|&i| positions[i]).collect();
            let n: Vec<Point<3>> = idx.iter().map(|&i| normals[i]).collect();
            crate::outliers::find_outliers(&p, &n, options.outlier_ratio)
        };
        let outliers: Vec<usize> = found.indices.iter().map(|&k| idx[k]).collect();
        for &i in &outliers {
            keep[i] = false;
        }
        idx.retain(|&i| keep[i]);
        if idx.len() < n_min.max(1) {
            return Err(MrasError::TooFewPoints {
                needed: n_min.max(1),
                got: idx.len(),
                duplicates,
                outliers: outliers.len(),
            });
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &i in &idx {
            for a in 0..3 {
                lo[a] = lo[a].min(positions[i][a]);
                hi[a] = hi[a].max(positions[i][a]);
            }
        }
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let diagonal = Aabb::new(lo, hi).map_or(f64::NAN, |b| b.diagonal());
        if !(extent.is_finite() && diagonal.is_finite()) {
            return Err(MrasError::Overflow { extent });
        }
        check_spread(positions, &idx, extent)?;
        let side = extent * (1.0 + 2.0 * margin);
        let origin: Point<3> = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]) - 0.5 * side);
        let u = idx
            .iter()
            .map(|&i| std::array::from_fn(|a| (positions[i][a] - origin[a]) / side))
            .collect();
        let normals = idx
            .iter()
            .map(|i| {
                let mean = touching.get(i).or_else(|| creases.get(i));
                mean.copied().unwrap_or_else(|| unit(&normals[*i]))
            })
            .collect();
        let touching: Vec<bool> = idx.iter().map(|i| touching.contains_key(i)).collect();
        Ok(Self {
            u,
            normals,
            touching,
            origin,
            side,
            diagonal,
            duplicates,
            outliers,
            kept_sparse: found.kept_sparse,
        })
    }
}

/// The places where a repeat's normal points against the first point's (`apart`: the two
/// input indices; `keep`: the distinct points), judged by the [`NORMAL_NEIGHBOURS`] nearest
/// distinct points ([`crate::meeting`]). Returns the normals to fit with where one place is one
/// sheet with its first normal flipped (the repeat's taken; `None` where none is), and by kept
/// index the places where two sheets meet, with the mean of their unit normals: the gradient
/// fitted there, short where they point nearly opposite ways (the field's gradient vanishes
/// where two solids touch or a wall is pinched to nothing), a crease's mean where they meet at
/// an angle.
fn sheets_meeting(
    positions: &[Point<3>],
    normals: &[Point<3>],
    keep: &[bool],
    apart: &[(usize, usize)],
) -> (Option<Vec<Point<3>>>, BTreeMap<usize, Point<3>>) {
    let mut touching = BTreeMap::new();
    if apart.is_empty() {
        return (None, touching);
    }
    let unit = |n: &Point<3>| geometry::scale(1.0 / geometry::norm(n), n);
    let distinct: Vec<usize> = (0..positions.len()).filter(|&i| keep[i]).collect();
    let at: Vec<Point<3>> = distinct.iter().map(|&i| positions[i]).collect();
    let tree = NeighbourTree::new_from_slice(&at).ok();
    let mut flipped: Vec<(usize, usize)> = Vec::new();
    for &(a, b) in apart {
        let (na, nb) = (unit(&normals[a]), unit(&normals[b]));
        let wanted = NonZero::new((NORMAL_NEIGHBOURS + 1).min(at.len())).expect("a is kept");
        let around = tree.iter().flat_map(|tree| {
            tree.query(&positions[a])
                .nearest_n::<SquaredEuclidean<f64>>(wanted)
                .execute()
        });
        let around = around
            .map(|found| distinct[found.item as usize])
            .filter(|&m| m != a)
            .map(|m| (positions[m], unit(&normals[m])));
        match meeting(&positions[a], &na, &nb, around) {
            Meeting::OneSheet { first: true } => {}
            Meeting::OneSheet { first: false } => flipped.push((a, b)),
            Meeting::Sheets { .. } => {
                touching.insert(a, std::array::from_fn(|x| 0.5 * (na[x] + nb[x])));
            }
        }
    }
    let chosen = (!flipped.is_empty()).then(|| {
        let mut chosen = normals.to_vec();
        for (a, b) in flipped {
            chosen[a] = normals[b];
        }
        chosen
    });
    (chosen, touching)
}

/// Rejects clouds on a plane, a line or a point: their covariance has a (near) zero eigenvalue.
fn check_spread(positions: &[Point<3>], idx: &[usize], extent: f64) -> Result<(), MrasError> {
    let n = idx.len() as f64;
    let mut mean = [0.0; 3];
    for &i in idx {
        for a in 0..3 {
            mean[a] += positions[i][a] / n;
        }
    }
    // In units of the extent, so that coordinates of 1e155 or 1e-200 neither overflow nor
    // underflow the squares.
    let mut cov = [[0.0; 3]; 3];
    let scale = if extent > 0.0 { 1.0 / extent } else { 1.0 };
    for &i in idx {
        let d: [f64; 3] = std::array::from_fn(|a| (positions[i][a] - mean[a]) * scale);
        for a in 0..3 {
            for b in 0..3 {
                cov[a][b] += d[a] * d[b] / n;
            }
        }
    }
    let shape = ["point", "line", "plane"];
    if extent <= 0.0 {
        return Err(MrasError::Degenerate {
            shape: shape[0],
            thickness: 0.0,
            extent,
        });
    }
    let svd = thin_svd(Mat::from_fn(3, 3, |a, b| cov[a][b]).as_ref()).map_err(MrasError::Tensor)?;
    // The largest distance of a point from the mean along the covariance's column `col`.
    let thickness = |col: usize| {
        idx.iter()
            .map(|&i| {
                (0..3)
                    .map(|a| (positions[i][a] - mean[a]) * svd.u[(a, col)])
                    .sum::<f64>()
                    .abs()
            })
            .fold(0.0, f64::max)
    };
    let (thinnest, next) = (thickness(2), thickness(1));
    if thinnest <= 1e-6 * extent {
        return Err(MrasError::Degenerate {
            shape: if next <= 1e-6 * extent {
                shape[1]
            } else {
                shape[2]
            },
            thickness: thinnest,
            extent,
        });
    }
    Ok(())
}

/// Point indices sorted by their cell in one level's lattice.
struct Buckets {
    lattice: u64,
    /// Sorted occupied cell keys and where their points start in `order`.
    keys: Vec<u64>,
    starts: Vec<u32>,
    order: Vec<u32>,
}

impl Buckets {
    fn new(u: &[Point<3>], lattice: u64) -> Self {
        let key = |p: &Point<3>| {
            p.iter().fold(0u64, |acc, &v| {
                acc * lattice + ((v * lattice as f64) as u64).min(lattice - 1)
            })
        };
        let mut order: Vec<(u64, u32)> = u
            .iter()
            .enumerate()
            .map(|(i, p)| (key(p), i as u32))
            .collect();
        order.sort_unstable();
        let mut keys = Vec::new();
        let mut starts = Vec::new();
        for (pos, &(k, _)) in order.iter().enumerate() {
            if keys.last() != Some(&k) {
                keys.push(k);
                starts.push(pos as u32);
            }
        }
        starts.push(order.len() as u32);
        Self {
            lattice,
            keys,
            starts,
            order: order.into_iter().map(|(_, i)| i).collect(),
        }
    }

    /// The points in lattice cell `index`.
    fn points(&self, index: [u64; 3]) -> &[u32] {
        let n = self.lattice;
        let key = (index[0] * n + index[1]) * n + index[2];
        match self.keys.binary_search(&key) {
            Ok(at) => &self.order[self.starts[at] as usize..self.starts[at + 1] as usize],
            Err(_) => &[],
        }
    }
}

/// Outside constraints for the root level: on a 5 × 5 × 5 lattice's points on the cube's
/// boundary, the distance to the nearest data point (positive: outside) with the direction away
/// from that point as the gradient — the values a signed distance would take there, which is
/// what the normal term (`|∇f| = 1` at the points) makes the field resemble near the surface.
/// The root level alone decides the field far from the points, where nothing else holds its
/// sign.
fn far_field(u: &[Point<3>]) -> Vec<Target> {
    let mut out = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            for k in 0..5 {
                let idx = [i, j, k];
                if !idx.iter().any(|&v| v == 0 || v == 4) {
                    continue;
                }
                let p: Point<3> = idx.map(|v| v as f64 / 4.0);
                let mut best = (f64::INFINITY, [0.0; 3]);
                for q in u {
                    let d: Point<3> = std::array::from_fn(|a| p[a] - q[a]);
                    let l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    if l2 < best.0 {
                        best = (l2, d);
                    }
                }
                let len = best.0.sqrt();
                if len > 0.0 {
                    out.push(Target {
                        u: p,
                        value: len,
                        gradient: best.1.map(|v| v / len),
                        slack: 1.0,
                    });
                }
            }
        }
    }
    out
}

/// The targets of one cell: the points inside its support, with `−f^{k−1}`, `n − ∇f^{k−1}`
/// and their `slack`, in a fixed order (lattice cells in order, points by index inside each).
/// The tolerance bounds the Sampson distance `|f|/|∇f|`; the CP bound and the rank-0 screen
/// bound changes of the value. Where the field so far is much flatter than a distance function
/// a change `δ` of its value moves the surface by `δ/|∇f|`, far more than `δ`: there each
/// point's bound is scaled by `|∇f^{k−1}|/STEEP_FLOOR`. Without it a loose tolerance let the
/// cells of a flat coarse field pass at `φ = 0` level after level: the bunny at
/// `--tolerance 0.02` kept 8,029 points beyond 2% of the diagonal, the farthest at 10.4%
/// (now 45, the farthest at 2.6%; at 0.01: 1,718 up to 9.0% → 94 up to 3.2%).
///
/// Why 0.5 and not 1 (a bound on the distance wherever `|∇f| < 1`): 1 met both loose
/// tolerances, but stored 11% more at the default tolerance (bunny 243k numbers) and 19–45%
/// more on noisy copies of the bunny (Gaussian noise of 0.25% and 0.5% of the diagonal), whose
/// meshes came no closer to the scanned surface (mean 5.71e-4 of the diagonal either way); 0.5
/// stores 2% more on the clean bunny and kitten (bunny 218k → 223k numbers, its largest and
/// mean distance to the points 4.58e-3, 3.52e-4 → 4.79e-3, 3.51e-4 — the max first quoted as
/// 4.50e-3, which no build of this rule gives) and 1–7% more on the
/// noisy copies.
const STEEP_FLOOR: f64 = 0.5;

/// The smallest [`steepness_factor`]: a point where `∇f^{k−1}` vanishes still gets a bound
/// (a factor of 0 would make its slack 0 and the bound at it infinite or NaN downstream).
const MIN_STEEPNESS: f64 = 1e-3;

fn steepness_factor(gradient: &Point<3>) -> f64 {
    (geometry::norm(gradient) / STEEP_FLOOR).clamp(MIN_STEEPNESS, 1.0)
}

/// `steepness`: scale each point's slack by [`steepness_factor`] (not at the root, before which
/// there is no field).
#[allow(clippy::too_many_arguments)]
fn gather(
    buckets: &Buckets,
    g: &LevelGeometry,
    index: [u64; 3],
    cloud: &Cloud,
    f: &[f64],
    grad: &[Point<3>],
    slack: &[f64],
    steepness: bool,
) -> Vec<Target> {
    let centre = index.map(|i| g.centre(i));
    let r2 = g.radius * g.radius;
    let mut out = Vec::new();
    let n = g.lattice as i64;
    for dx in -1..=1i64 {
        for dy in -1..=1i64 {
            for dz in -1..=1i64 {
                let j = [
                    index[0] as i64 + dx,
                    index[1] as i64 + dy,
                    index[2] as i64 + dz,
                ];
                if j.iter().any(|&v| v < 0 || v >= n) {
                    continue;
                }
                for &i in buckets.points(j.map(|v| v as u64)) {
                    let i = i as usize;
                    let p = cloud.u[i];
                    let d2: f64 = (0..3).map(|a| (p[a] - centre[a]).powi(2)).sum();
                    if d2 < r2 {
                        out.push(Target {
                            u: p,
                            value: -f[i],
                            gradient: std::array::from_fn(|a| cloud.normals[i][a] - grad[i][a]),
                            slack: if steepness {
                                slack[i] * steepness_factor(&grad[i])
                            } else {
                                slack[i]
                            },
                        });
                    }
                }
            }
        }
    }
    out
}
