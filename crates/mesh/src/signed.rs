//! Two-step **signed marching cubes** (SMC) and the **voxel-growing** (VG) baseline it improves
//! on: marching cubes that evaluates the expensive field only near the surface.
//!
//! Zhang, Zhong & Wang, *A Two-Step Surface Reconstruction Method Using Signed Marching Cubes*
//! (Appl. Sci. 12, 1792, 2022; paper 002), §2.3. Plain marching cubes evaluates the field at
//! every grid vertex (`N_MC` evaluations), although only the cells the surface crosses need
//! accurate values. The paper's fields are RBF interpolants evaluated by the fast multipole
//! method, whose expansion order trades accuracy for speed; SMC uses two orders:
//!
//! 1. **Coarse step.** A cheap approximation `s_p` (low expansion order) settles the side of
//!    every grid vertex: the paper evaluates it at every vertex (`N_SMC,p = N_MC` cheap
//!    evaluations, in large batches, since the FMM's per-call setup is not free;
//!    [`CoarseStep::EveryVertex`]); zeroset by default settles whole blocks of vertices at once
//!    where `s_p` can enclose itself ([`CoarseStep::Blocks`], below). The cells whose signs it
//!    cannot settle are the *candidates*.
//! 2. **Fine step.** The accurate field `s_P` (high order) is evaluated once at each distinct
//!    vertex of a candidate cell (`N_SMC,P` evaluations, in grid order), and marching cubes
//!    extracts the surface. The paper's Table 3 reports `γ = N_SMC,P / N_SMC,p` with
//!    `N_SMC,p = N_MC`; [`SmcReport::gamma`] is `N_SMC,P / N_MC` for both steps.
//!
//! [`voxel_growing`] is the paper's other baseline (§2.3, Figure 2b): it follows the surface from
//! seed cells through face-adjacent cells, so it evaluates little, but it only finds the
//! components it has a seed on (Figures 1 and 6f). SMC needs no seed and finds every component
//! plain marching cubes finds.
//!
//! ## The certainty rule
//!
//! The caller gives a `margin` with `|s_p(x) − s_P(x)| < margin` at every grid vertex (a bound
//! on the coarse field's error against the fine one, e.g. from the FMM's error estimate at the
//! lower order). A vertex is **certain** when `|s_p(x) − c| > margin` (`c` the level): then
//! `s_P(x) − c` has the sign of `s_p(x) − c`, so the coarse value sits on the correct side in
//! marching cubes' sense (inside iff `v < c`). A cell is a **candidate** when one of its eight
//! corners is uncertain, or when its corners' coarse values are not all on one side.
//!
//! ## The block step (beyond the paper)
//!
//! Evaluating the coarse field at every vertex still costs one evaluation per vertex, and the
//! near-field sums of a multipole field are the same work at any order, so the paper's step 1
//! cannot be much cheaper than plain marching cubes at the high order. Most vertices, though,
//! lie far from the surface, where the field is smooth at the scale of many cells. With
//! [`CoarseStep::Blocks`] the grid is tiled by blocks of [`TOP_BLOCK`]³ vertices; for each
//! block the coarse field is asked for an **enclosure** `[lo, hi]` of its values over the
//! block's box ([`ScalarField::value_range`]; a multipole field linearises its expansion and
//! kernel terms at the box's centre and bounds the remainders, about a few evaluations'
//! work). If `lo − c > margin` or `c − hi > margin`, every vertex of the block is certain, on
//! the side the enclosure gives, and none is evaluated: it stands in with the enclosure's end
//! nearer the level, a value on its side and farther than the margin. Otherwise the block is
//! split in eight, down to [`SMALLEST_BLOCK`] vertices, which are evaluated; a failed block
//! whose centre is very near the level for its width (its halves cannot plausibly settle) is
//! evaluated at once. Fields without enclosures are evaluated at every vertex.
//!
//! The statuses are exactly those of evaluating every vertex: a settled vertex's coarse value
//! lies in the enclosure, so it would have been certain on the same side. Hence the candidates,
//! the fine evaluations and the mesh are identical; only `N_SMC,p` falls (on a 256³ grid of a
//! 10,000-centre biharmonic RBF field of the bunny, 96% of the vertices are settled by about
//! 125,000 enclosures at order 5). The enclosures of a triharmonic (`r³`) field are loose, because its
//! large weights cancel: [`settled_fraction`] probes whether blocks pay, and
//! [`expected_evaluations`] tells a multipole field how many points to shape its tree for.
//!
//! ## Why the result is plain marching cubes on the fine field
//!
//! [`signed_marching_cubes`] runs the ordinary extractor of [`marching_cubes`] on a *composite*
//! array: the fine value at every vertex of a candidate cell, the coarse value elsewhere. The
//! mesh is identical — same vertex coordinates bit for bit, same triangles in the same order —
//! to [`mesh_field`]`(fine, …)` (and, without normals, to [`marching_cubes`] on the fine samples)
//! as long as the margin holds, because every input that extractor reads agrees:
//!
//! - **Sides.** A vertex left at its coarse value belongs to no candidate cell; every vertex
//!   belongs to some cell, which then has only certain corners, so the vertex is certain and its
//!   coarse value is on the fine value's side. Every inside bit is the fine one.
//! - **Crossings and the level-sample merge.** An edge whose ends are on different sides makes
//!   every cell around it mixed; with all corners certain, the coarse sides equal the fine ones
//!   and are mixed too, so each such cell is a candidate and both ends hold fine values. The
//!   crossing's position, and whether it rounds onto (merges with) an end sample, depend on
//!   these two values only.
//! - **Cells and ambiguous faces.** Only cells whose corners are not all on one side emit
//!   triangles, and only they consult the asymptotic decider on their faces; by the same
//!   argument they are candidates, and the decider reads fine values.
//! - **Border caps** ([`McOptions::close_boundary`]). The cap cells outside the grid read only
//!   inside bits (already the fine ones), their cap vertices sit *at* inside border samples (a
//!   position that reads no value), and any crossing or ambiguous face of theirs lies on the
//!   border face of a mixed real cell, a candidate. So a border cell needs no extra candidate
//!   rule: a fully inside border cell's coarse values already give the same caps.
//! - **Normals** come from the fine field's gradient at the final vertices, as in
//!   [`mesh_field`] (central differences of the composite samples would differ).
//!
//! If the margin is too small (the coarse field's error exceeds it somewhere) the result may
//! differ from plain marching cubes on the fine field: a surface piece in cells where the coarse
//! field sees no sign change is lost, or a spurious one appears. It is still a valid marching
//! cubes mesh of the composite samples. `margin = 0` only trusts coarse signs: it is exact when
//! the coarse field *is* the fine one.
//!
//! ## Costs
//!
//! `N_SMC,P` is roughly the number of vertices within `margin / ‖∇f‖ + h√3` of the surface, so
//! `γ` is about the volume of that band over the volume of the box: it falls like `1/n` on an
//! `n³` grid while the cell size `h` dominates the band, and tends to the fixed volume fraction
//! of the `margin` band when the margin does (a coarser field costs more fine evaluations).
//! Memory is that of plain marching cubes (one `f64` per vertex) plus a byte per vertex and per
//! cell; the block step adds an index and a value per evaluated coarse vertex (16 bytes, for the
//! few near the surface) and a record per settled block.

use std::time::Instant;

use rayon::prelude::*;
use zeroset_field_core::geometry::Point3;
use zeroset_field_core::{Aabb, Grid, ScalarField};

#[cfg(doc)]
use crate::cubes::mesh_field;
use crate::cubes::{
    CellMask, McOptions, SAMPLES, marching_cubes, marching_cubes_masked, with_gradient_normals,
};
use crate::error::{MeshError, Result};
use crate::samples;
use crate::trimesh::TriMesh;

/// Points per batched [`ScalarField::values`] call (the last batch of a step may be smaller).
pub const BATCH: usize = 1 << 20;

/// Vertices per axis of the blocks the block step starts from (the grid is tiled by them).
pub const TOP_BLOCK: usize = 32;

/// A block of at most this many vertices is evaluated vertex by vertex rather than enclosed.
pub const SMALLEST_BLOCK: usize = 4;

/// A failed enclosure whose centre lies nearer the level (plus margin) than this fraction of
/// its width is not split further: its vertices are evaluated.
const HOPELESS: f64 = 0.03125;

/// How step 1 settles the signs of the grid vertices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum CoarseStep {
    /// As the paper: the coarse field at every grid vertex (`N_SMC,p = N_MC`).
    EveryVertex,
    /// Blocks of vertices whose coarse enclosure ([`ScalarField::value_range`]) clears the
    /// margin are settled without evaluating them; the others are split in eight, down to
    /// [`SMALLEST_BLOCK`] vertices, which are evaluated (see the module docs). A coarse field
    /// that gives no enclosure for the probe boxes (a few 2 × 2 × 2 blocks along the grid's
    /// diagonal) is evaluated at every vertex as [`CoarseStep::EveryVertex`] does. The default.
    #[default]
    Blocks,
}

/// About how many points each field of [`signed_marching_cubes`] will be evaluated at on
/// `grid`, `[coarse, fine]`, to shape fields whose cost depends on it (the multipole method's
/// `FmmOptions::with_expected_points`).
///
/// The fine field is evaluated in a band of cells around the surface, the coarse one everywhere
/// ([`CoarseStep::EveryVertex`]) or, with [`CoarseStep::Blocks`], about where the blocks near
/// the surface fail to settle (enclosures counted as a few evaluations each). A surface of
/// moderate complexity crosses the box a few times, so both bands scale with the box's mean
/// cross-section `S = (n₀n₁ + n₀n₂ + n₁n₂) / 3` in vertices: `8 S` fine and `32 S` coarse
/// evaluations, at most one per vertex. Only the cost depends on these estimates: a field
/// shaped for another count (a multipole field's tree) differs only within its accuracy, and
/// the mesh is always plain marching cubes on the fine field as built.
pub fn expected_evaluations(grid: &Grid<3>, step: CoarseStep) -> [usize; 2] {
    let [n0, n1, n2] = grid.counts();
    let section = (n0 * n1 + n0 * n2 + n1 * n2) / 3;
    let len = grid.len();
    let coarse = match step {
        CoarseStep::EveryVertex => len,
        CoarseStep::Blocks => (32 * section).min(len),
    };
    [coarse, (8 * section).min(len)]
}

/// The fraction of `samples` blocks of 4 × 4 × 4 grid vertices, spread over `grid` by a fixed
/// low-discrepancy sequence, whose coarse enclosure ([`ScalarField::value_range`]) settles
/// them (clears `level ± margin`): a cheap probe (one enclosure per sample) of whether
/// [`CoarseStep::Blocks`] pays for `coarse`. Enclosures are tight where the field is smooth
/// at the scale of a few cells and its terms do not cancel much: about 0.9 for a biharmonic
/// (`r`) RBF field of a scan on a 256³ grid, well under 0.5 for a triharmonic (`r³`) one, whose
/// large cancelling weights widen every bound. 0 if the field gives no enclosures.
pub fn settled_fraction<C: ScalarField<3> + ?Sized>(
    coarse: &C,
    grid: &Grid<3>,
    level: f64,
    margin: f64,
    samples: usize,
) -> f64 {
    let n = grid.counts();
    let span = n.map(|c| c.saturating_sub(4));
    // The R3 sequence (fractional parts of k·(1/φ₃, 1/φ₃², 1/φ₃³)).
    let alpha = [
        0.819_172_513_396_164_4,
        0.671_043_606_703_789_2,
        0.549_700_477_901_970_4,
    ];
    let settled = (0..samples)
        .into_par_iter()
        .filter(|&k| {
            let lo: [usize; 3] = std::array::from_fn(|a| {
                let u = (0.5 + k as f64 * alpha[a]).fract();
                ((u * (span[a] + 1) as f64) as usize).min(span[a])
            });
            let hi: [usize; 3] = std::array::from_fn(|a| (lo[a] + 3).min(n[a] - 1));
            enclose(coarse, grid, lo, hi)
                .is_some_and(|[lo, hi]| lo - level > margin || level - hi > margin)
        })
        .count();
    settled as f64 / samples.max(1) as f64
}

/// Options of [`signed_marching_cubes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub struct SmcOptions {
    /// The marching cubes' options (normals, closed boundary).
    pub mesh: McOptions,
    /// How step 1 settles the vertices (default [`CoarseStep::Blocks`]).
    pub coarse_step: CoarseStep,
}

impl SmcOptions {
    /// These options with [`coarse_step`](Self::coarse_step) set to `step`.
    pub fn with_coarse_step(mut self, step: CoarseStep) -> Self {
        self.coarse_step = step;
        self
    }
}

impl From<McOptions> for SmcOptions {
    fn from(mesh: McOptions) -> Self {
        Self {
            mesh,
            coarse_step: CoarseStep::default(),
        }
    }
}

/// What [`signed_marching_cubes`] did: the paper's evaluation counts (Table 3) and timings.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct SmcReport {
    /// Evaluations plain marching cubes makes: one per grid vertex (the paper's `N_MC`).
    pub n_mc: u64,
    /// Coarse-field evaluations of step 1 (`N_SMC,p`): one per grid vertex (`= n_mc`) with
    /// [`CoarseStep::EveryVertex`]; with [`CoarseStep::Blocks`] only the vertices of the blocks
    /// no enclosure settled.
    pub n_smc_low: u64,
    /// Fine-field evaluations of step 2: the distinct vertices of the candidate cells
    /// (`N_SMC,P`). The fine gradients taken for the normals (one per mesh vertex, as
    /// [`mesh_field`] takes them) are not counted.
    pub n_smc_high: u64,
    /// `n_smc_high / n_mc`: the paper's `γ = N_SMC,P / N_SMC,p`, whose step 1 evaluates every
    /// vertex (`N_SMC,p = N_MC`).
    pub gamma: f64,
    /// Coarse enclosures the block step asked for, the probe's and those the field could not
    /// give (`None`) included (each about four evaluations' work for a multipole field).
    pub enclosures: u64,
    /// Blocks the enclosures settled, and the grid vertices in them (never evaluated).
    pub settled_blocks: u64,
    /// Grid vertices settled by enclosures: `n_mc − n_smc_low` with [`CoarseStep::Blocks`].
    pub settled_vertices: u64,
    /// Vertices with `|coarse − level| ≤ margin`.
    pub uncertain_vertices: u64,
    /// Cells (of the `Π (nᵢ − 1)` inside the grid) with an uncertain corner or coarse corners on
    /// both sides.
    pub candidate_cells: u64,
    /// Cells inside the grid whose corners are not all on one side by the final (fine where it
    /// matters) values: those plain marching cubes triangulates, cap cells not counted.
    pub surface_cells: u64,
    /// Wall time of step 1 (coarse evaluation, certainty and candidates).
    pub coarse_seconds: f64,
    /// Wall time of step 2 (fine evaluation).
    pub fine_seconds: f64,
    /// Wall time of the extraction, fine-gradient normals included.
    pub extract_seconds: f64,
}

/// The stage [`signed_marching_cubes`] is starting, passed to its progress callback.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SmcStage {
    /// Step 1 starts: the coarse field is about to be evaluated at `vertices` grid vertices.
    Coarse {
        /// Number of coarse evaluations to come.
        vertices: u64,
    },
    /// Step 2 starts: the fine field is about to be evaluated at `vertices` distinct vertices.
    Fine {
        /// Number of fine evaluations to come.
        vertices: u64,
    },
    /// Marching cubes on the composite samples starts.
    Extract,
}

/// What [`voxel_growing`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct VgReport {
    /// Field evaluations: the distinct grid vertices of the cells visited.
    pub evaluations: u64,
    /// Cells found whose corners are not all on one side (the cells triangulated; with
    /// `close_boundary` this includes cap cells outside the grid).
    pub surface_cells: u64,
    /// Distinct cells holding a seed point.
    pub seed_cells: u64,
    /// Seed points skipped: outside the grid's cells, or with a NaN or infinite coordinate.
    pub skipped_seeds: u64,
    /// Wall time of the whole call.
    pub seconds: f64,
}

/// The level surface `fine = level` on `grid`, by two-step signed marching cubes: `coarse`
/// settles the side of every vertex (evaluated at each, or by blocks through its enclosures:
/// [`SmcOptions::coarse_step`]), `fine` is evaluated only at the vertices of the cells the
/// coarse values cannot settle (see the [module docs](self)).
///
/// `margin` must bound the coarse field's error: `|coarse(x) − fine(x)| < margin` at every grid
/// vertex. Then the mesh is identical (vertices bit for bit, triangles and their order, normals)
/// to [`mesh_field`]`(fine, grid, level, options)`. `progress`, if given, is called at the start
/// of each stage.
///
/// Both fields are evaluated only through their batched [`ScalarField::values`], at most
/// [`BATCH`] points a call (the fine field in grid linear order, the coarse one block by block
/// with [`CoarseStep::Blocks`]), and `coarse.value_range` is asked for the blocks' enclosures;
/// `fine.gradient` is called at the mesh vertices when `options.mesh.normals`.
///
/// # Errors
/// - as [`mesh_field`] for the grid and the level (checked before any evaluation);
/// - [`MeshError::InvalidMargin`] if `margin` is negative, NaN or infinite;
/// - [`MeshError::NonFiniteSample`] naming the first grid sample where the coarse field is NaN
///   or infinite, or else the first where the fine field is;
/// - [`MeshError::InvalidMesh`] if the surface has too many vertices.
pub fn signed_marching_cubes<C, F>(
    coarse: &C,
    fine: &F,
    grid: &Grid<3>,
    level: f64,
    margin: f64,
    options: &SmcOptions,
    progress: Option<&(dyn Fn(SmcStage) + Sync)>,
) -> Result<(TriMesh, SmcReport)>
where
    C: ScalarField<3> + ?Sized,
    F: ScalarField<3> + ?Sized,
{
    samples::check(grid, None, level, SAMPLES)?;
    check_margin(margin)?;
    let notify = |stage| {
        if let Some(p) = progress {
            p(stage);
        }
    };
    let n = grid.counts();
    let len = grid.len();
    let mut report = SmcReport {
        n_mc: len as u64,
        n_smc_low: len as u64,
        ..SmcReport::default()
    };

    // Step 1: coarse values everywhere, certainty, candidate cells, vertices to refine.
    notify(SmcStage::Coarse {
        vertices: len as u64,
    });
    let start = Instant::now();
    let blocks = options.coarse_step == CoarseStep::Blocks && {
        let (encloses, probes) = encloses(coarse, grid);
        report.enclosures = probes;
        encloses
    };
    let mut values = if blocks {
        settle_blocks(coarse, grid, level, margin, &mut report)
    } else {
        let mut values = vec![0.0; len];
        evaluate(coarse, grid, &mut values, |chunk_start, k| chunk_start + k);
        report.n_smc_low = len as u64;
        values
    };
    if let Some(index) = samples::first_non_finite(&values) {
        return Err(samples::non_finite(grid, &values, index));
    }
    // Bit 0: possibly outside (v ≥ level); bit 1: possibly inside (v < level).
    let mut status = vec![0u8; len];
    status
        .par_chunks_mut(1 << 16)
        .zip(values.par_chunks(1 << 16))
        .for_each(|(s, v)| {
            for (s, &v) in s.iter_mut().zip(v) {
                let certain = (v - level).abs() > margin;
                *s = if !certain {
                    3
                } else if v < level {
                    2
                } else {
                    1
                };
            }
        });
    report.uncertain_vertices = status.par_iter().filter(|&&s| s == 3).count() as u64;
    let candidate = mixed_cells(n, &status);
    report.candidate_cells = candidate.par_iter().filter(|&&c| c).count() as u64;
    drop(status);
    let refine = cell_vertices(n, &candidate);
    drop(candidate);
    report.n_smc_high = refine.len() as u64;
    report.gamma = report.n_smc_high as f64 / report.n_mc as f64;
    report.coarse_seconds = start.elapsed().as_secs_f64();

    // Step 2: fine values at the vertices of the candidate cells.
    notify(SmcStage::Fine {
        vertices: report.n_smc_high,
    });
    let start = Instant::now();
    let mut fine_values = vec![0.0; refine.len()];
    evaluate(fine, grid, &mut fine_values, |chunk_start, k| {
        refine[chunk_start + k]
    });
    for (&l, &v) in refine.iter().zip(&fine_values) {
        values[l] = v;
    }
    if let Some(k) = fine_values.iter().position(|v| !v.is_finite()) {
        return Err(samples::non_finite(grid, &values, refine[k]));
    }
    drop(fine_values);
    drop(refine);
    report.fine_seconds = start.elapsed().as_secs_f64();

    // Extraction, as mesh_field does it.
    notify(SmcStage::Extract);
    let start = Instant::now();
    let inside: Vec<u8> = values
        .par_iter()
        .map(|&v| if v < level { 2 } else { 1 })
        .collect();
    report.surface_cells = mixed_cells(n, &inside).par_iter().filter(|&&c| c).count() as u64;
    drop(inside);
    let mesh = marching_cubes(grid, &values, level, &options.mesh.with_normals(false))?;
    drop(values);
    let mesh = with_gradient_normals(mesh, fine, grid, &options.mesh)?;
    report.extract_seconds = start.elapsed().as_secs_f64();
    Ok((mesh, report))
}

/// `coarse`'s enclosure over the box of the grid vertices `lo..=hi`.
fn enclose<C: ScalarField<3> + ?Sized>(
    coarse: &C,
    grid: &Grid<3>,
    lo: [usize; 3],
    hi: [usize; 3],
) -> Option<[f64; 2]> {
    let region = Aabb::new(grid.point(lo), grid.point(hi)).ok()?;
    coarse.value_range(&region)
}

/// Whether `coarse` encloses itself over any of a few 2 × 2 × 2 blocks of vertices along the
/// grid's diagonal (a field without enclosures is then evaluated vertex by vertex, sparing the
/// block step's bookkeeping), and how many enclosures that asked for.
fn encloses<C: ScalarField<3> + ?Sized>(coarse: &C, grid: &Grid<3>) -> (bool, u64) {
    let n = grid.counts();
    let mut asked = 0;
    let found = (1..8).any(|k| {
        asked += 1;
        let lo: [usize; 3] = std::array::from_fn(|a| (k * (n[a] - 2)) / 8);
        enclose(coarse, grid, lo, lo.map(|i| i + 1)).is_some()
    });
    (found, asked)
}

/// A box of grid vertices: indices `lo[a]..hi[a]` per axis.
#[derive(Debug, Clone, Copy)]
struct Block {
    lo: [usize; 3],
    hi: [usize; 3],
}

impl Block {
    fn vertices(&self) -> usize {
        (0..3).map(|a| self.hi[a] - self.lo[a]).product()
    }
}

/// What the block step did in one top block.
#[derive(Default)]
struct BlockWork {
    /// Settled blocks, each with the value its vertices stand in with (the enclosure's end
    /// nearer the level: on the right side, farther than the margin).
    settled: Vec<(Block, f64)>,
    /// Vertices (linear indices) to evaluate.
    vertices: Vec<usize>,
    enclosures: u64,
}

/// Step 1 by blocks ([`CoarseStep::Blocks`]): the grid is tiled by blocks of [`TOP_BLOCK`]
/// vertices per axis; a block whose coarse enclosure lies farther than `margin` from the level
/// is settled (its vertices take the enclosure's nearer end, which has their side and is
/// certain), any other is split in eight, and a block of at most [`SMALLEST_BLOCK`] vertices is
/// evaluated. The statuses are those of evaluating every vertex: a settled vertex's coarse
/// value would have been certain, on the same side.
fn settle_blocks<C: ScalarField<3> + ?Sized>(
    coarse: &C,
    grid: &Grid<3>,
    level: f64,
    margin: f64,
    report: &mut SmcReport,
) -> Vec<f64> {
    let n = grid.counts();
    let tiles = n.map(|c| c.div_ceil(TOP_BLOCK));
    let tile_block = |t: usize| {
        let ti = [
            t / (tiles[1] * tiles[2]),
            (t / tiles[2]) % tiles[1],
            t % tiles[2],
        ];
        let lo = ti.map(|i| i * TOP_BLOCK);
        Block {
            lo,
            hi: std::array::from_fn(|a| (lo[a] + TOP_BLOCK).min(n[a])),
        }
    };
    let work: Vec<BlockWork> = (0..tiles.iter().product::<usize>())
        .into_par_iter()
        .map(|t| {
            let mut work = BlockWork::default();
            let mut stack = vec![tile_block(t)];
            while let Some(b) = stack.pop() {
                if b.vertices() > SMALLEST_BLOCK {
                    work.enclosures += 1;
                    match enclose(coarse, grid, b.lo, b.hi.map(|i| i - 1)) {
                        Some([lo, _]) if lo - level > margin => work.settled.push((b, lo)),
                        Some([_, hi]) if level - hi > margin => work.settled.push((b, hi)),
                        // Halves have at least a quarter of the spread (the remainders are
                        // quadratic in the size): hopeless when the centre is nearer the
                        // level than that.
                        Some([lo, hi])
                            if (0.5 * (lo + hi) - level).abs() - margin <= HOPELESS * (hi - lo) =>
                        {
                            push_vertices(&b, grid, &mut work.vertices)
                        }
                        _ => stack.extend(split(&b)),
                    }
                    continue;
                }
                push_vertices(&b, grid, &mut work.vertices);
            }
            work
        })
        .collect();

    // Settled values, slab by slab (the slab's tiles are one row of `work`).
    let mut values = vec![f64::NAN; grid.len()];
    let row_tiles = tiles[1] * tiles[2];
    values
        .par_chunks_mut(n[1] * n[2])
        .enumerate()
        .for_each(|(i, slab)| {
            let row = i / TOP_BLOCK;
            for w in &work[row * row_tiles..][..row_tiles] {
                for (b, v) in &w.settled {
                    if b.lo[0] <= i && i < b.hi[0] {
                        for j in b.lo[1]..b.hi[1] {
                            slab[j * n[2] + b.lo[2]..j * n[2] + b.hi[2]].fill(*v);
                        }
                    }
                }
            }
        });
    let vertices: Vec<usize> = work
        .iter()
        .flat_map(|w| w.vertices.iter().copied())
        .collect();
    let mut evaluated = vec![0.0; vertices.len()];
    evaluate(coarse, grid, &mut evaluated, |chunk_start, k| {
        vertices[chunk_start + k]
    });
    for (&l, &v) in vertices.iter().zip(&evaluated) {
        values[l] = v;
    }
    report.n_smc_low = vertices.len() as u64;
    report.enclosures += work.iter().map(|w| w.enclosures).sum::<u64>();
    report.settled_blocks = work.iter().map(|w| w.settled.len() as u64).sum();
    report.settled_vertices = (grid.len() - vertices.len()) as u64;
    values
}

/// Appends the linear indices of the vertices of `b`.
fn push_vertices(b: &Block, grid: &Grid<3>, vertices: &mut Vec<usize>) {
    for i in b.lo[0]..b.hi[0] {
        for j in b.lo[1]..b.hi[1] {
            let row = grid.linear_index([i, j, 0]);
            vertices.extend((b.lo[2]..b.hi[2]).map(|k| row + k));
        }
    }
}

/// The (up to) eight halves of a block: each axis with two or more vertices is halved.
fn split(b: &Block) -> impl Iterator<Item = Block> + use<> {
    let b = *b;
    let mid: [usize; 3] = std::array::from_fn(|a| b.lo[a] + (b.hi[a] - b.lo[a]).div_ceil(2));
    (0..8).filter_map(move |k| {
        let mut part = b;
        for (a, &m) in mid.iter().enumerate() {
            let upper = (k >> (2 - a)) & 1 == 1;
            if b.hi[a] - b.lo[a] < 2 {
                if upper {
                    return None;
                }
            } else if upper {
                part.lo[a] = m;
            } else {
                part.hi[a] = m;
            }
        }
        Some(part)
    })
}

/// The level surface `field = level` on `grid`, found by **voxel growing** from the cells
/// holding the `seeds` (the paper's VG baseline, §2.3).
///
/// The cells containing the seed points are visited first; then, wave after wave (breadth
/// first), the six face neighbours of every visited *surface* cell (corners not all on one side)
/// are visited. A visited cell's corners are evaluated with one batched [`ScalarField::values`]
/// call per wave (at most [`BATCH`] points a call), each grid vertex at most once. Exactly the
/// surface cells found are triangulated, as plain marching cubes triangulates them: every
/// connected component of the surface (through face-adjacent surface cells) that holds a seed
/// cell is identical, as a set of triangles with their vertex coordinates, to its part of
/// [`mesh_field`]`(field, …)`; when the seeds reach every component the mesh is
/// [`mesh_field`]'s, vertex order included. With `close_boundary` the cap cells outside the
/// grid (corners outside counted as outside, never evaluated) take part in the growth.
///
/// **A component without a seed is missed** (the paper's Figures 1 and 6f): this is what
/// [`signed_marching_cubes`] avoids.
///
/// Seeds outside the cells of the grid, or with a NaN or infinite coordinate, are skipped and
/// counted in [`VgReport::skipped_seeds`]; no seed (or none inside) gives an empty mesh.
///
/// # Errors
/// - as [`mesh_field`] for the grid and the level (checked before any evaluation);
/// - [`MeshError::NonFiniteSample`] naming a visited grid sample where the field is NaN or
///   infinite (the first in linear order of the wave that found it);
/// - [`MeshError::InvalidMesh`] if the surface has too many vertices.
pub fn voxel_growing<F: ScalarField<3> + ?Sized>(
    field: &F,
    grid: &Grid<3>,
    level: f64,
    seeds: &[Point3],
    options: &McOptions,
) -> Result<(TriMesh, VgReport)> {
    samples::check(grid, None, level, SAMPLES)?;
    let start = Instant::now();
    let n = grid.counts();
    let close = options.close_boundary;
    // Cell index range per axis: lo..hi (cap cells at −1 and n − 1 with close_boundary).
    let (lo, hi): (isize, [isize; 3]) = if close {
        (-1, n.map(|x| x as isize))
    } else {
        (0, n.map(|x| x as isize - 1))
    };
    let mut report = VgReport::default();
    let mut visited = CellMask::new(n);
    let mut surface = CellMask::new(n);
    let mut wave: Vec<[isize; 3]> = Vec::new();
    for p in seeds {
        let c = grid.continuous_index(p);
        let mut cell = [0isize; 3];
        let mut ok = true;
        for a in 0..3 {
            // Inside the cells' span [lo, hi] (NaN fails both comparisons).
            if c[a] >= lo as f64 && c[a] <= hi[a] as f64 {
                cell[a] = (c[a].floor() as isize).min(hi[a] - 1);
            } else {
                ok = false;
            }
        }
        if !ok {
            report.skipped_seeds += 1;
        } else if visited.insert(cell) {
            wave.push(cell);
        }
    }
    report.seed_cells = wave.len() as u64;

    // Unevaluated samples hold `level`: outside, so they carry no cap vertex; the masked
    // extractor places no crossing next to them.
    let mut values = vec![level; grid.len()];
    let mut known = vec![false; grid.len()];
    let real = |c: [isize; 3], corner: usize| -> Option<usize> {
        let mut idx = [0usize; 3];
        for a in 0..3 {
            let x = c[a] + ((corner >> a) & 1) as isize;
            if x < 0 || x >= n[a] as isize {
                return None;
            }
            idx[a] = x as usize;
        }
        Some(grid.linear_index(idx))
    };
    while !wave.is_empty() {
        let mut todo: Vec<usize> = Vec::new();
        for &c in &wave {
            for corner in 0..8 {
                if let Some(l) = real(c, corner)
                    && !known[l]
                {
                    known[l] = true;
                    todo.push(l);
                }
            }
        }
        todo.sort_unstable();
        let mut out = vec![0.0; todo.len()];
        evaluate(field, grid, &mut out, |chunk_start, k| {
            todo[chunk_start + k]
        });
        for (&l, &v) in todo.iter().zip(&out) {
            values[l] = v;
        }
        if let Some(k) = out.iter().position(|v| !v.is_finite()) {
            return Err(samples::non_finite(grid, &values, todo[k]));
        }
        report.evaluations += todo.len() as u64;
        let mut next = Vec::new();
        for &c in &wave {
            let (mut any_in, mut any_out) = (false, false);
            for corner in 0..8 {
                match real(c, corner) {
                    Some(l) if values[l] < level => any_in = true,
                    _ => any_out = true,
                }
            }
            if !(any_in && any_out) {
                continue;
            }
            surface.insert(c);
            report.surface_cells += 1;
            for a in 0..3 {
                for d in [-1, 1] {
                    let mut m = c;
                    m[a] += d;
                    if m[a] >= lo && m[a] < hi[a] && visited.insert(m) {
                        next.push(m);
                    }
                }
            }
        }
        wave = next;
    }
    let mesh = marching_cubes_masked(grid, &values, level, &known, &surface, close)?;
    drop(values);
    let mesh = with_gradient_normals(mesh, field, grid, options)?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok((mesh, report))
}

/// `MeshError::InvalidMargin` unless `margin` is finite and `≥ 0`.
fn check_margin(margin: f64) -> Result<()> {
    if margin.is_finite() && margin >= 0.0 {
        Ok(())
    } else {
        Err(MeshError::InvalidMargin { margin })
    }
}

/// `out[k] = field(grid point at linear index sample(chunk start, k within chunk))`, with one
/// batched call per chunk of [`BATCH`] points.
fn evaluate<F, S>(field: &F, grid: &Grid<3>, out: &mut [f64], sample: S)
where
    F: ScalarField<3> + ?Sized,
    S: Fn(usize, usize) -> usize + Sync,
{
    let mut points: Vec<Point3> = Vec::with_capacity(BATCH.min(out.len()));
    for (c, chunk) in out.chunks_mut(BATCH).enumerate() {
        let chunk_start = c * BATCH;
        (0..chunk.len())
            .into_par_iter()
            .map(|k| grid.point(grid.multi_index(sample(chunk_start, k))))
            .collect_into_vec(&mut points);
        field.values(&points, chunk);
    }
}

/// For each cell inside the grid (linear order over `nᵢ − 1` cells per axis): whether the OR of
/// its corners' status bits (1: possibly outside, 2: possibly inside) is 3. Separable: the OR of
/// four vertex rows, then of neighbours along the row (byte operations the compiler
/// vectorises).
fn mixed_cells(n: [usize; 3], status: &[u8]) -> Vec<bool> {
    let [_, n1, n2] = n;
    let cells = [n[0] - 1, n1 - 1, n2 - 1];
    let mut out = vec![false; cells[0] * cells[1] * cells[2]];
    out.par_chunks_mut(cells[1] * cells[2])
        .enumerate()
        .for_each(|(ci, slab)| {
            let mut rows = vec![0u8; n2];
            for cj in 0..cells[1] {
                let row = |i: usize, j: usize| &status[(i * n1 + j) * n2..][..n2];
                let (a, b) = (row(ci, cj), row(ci, cj + 1));
                let (c, d) = (row(ci + 1, cj), row(ci + 1, cj + 1));
                for k in 0..n2 {
                    rows[k] = a[k] | b[k] | c[k] | d[k];
                }
                let dst = &mut slab[cj * cells[2]..][..cells[2]];
                for (k, m) in dst.iter_mut().enumerate() {
                    *m = rows[k] | rows[k + 1] == 3;
                }
            }
        });
    out
}

/// The linear indices, in order, of the grid vertices that are a corner of some cell marked in
/// `cells` (linear order over `nᵢ − 1` cells per axis): for each vertex slab, the OR of the
/// two cell slabs beside it, of the two cell rows beside each vertex row, and of the two cells
/// beside each vertex.
fn cell_vertices(n: [usize; 3], cells: &[bool]) -> Vec<usize> {
    let [n0, n1, n2] = n;
    let (m1, m2) = (n1 - 1, n2 - 1);
    let slabs: Vec<Vec<usize>> = (0..n0)
        .into_par_iter()
        .map(|i| {
            let mut found = Vec::new();
            // The cell slabs i − 1 and i, where they exist.
            let slab = |ci: usize| &cells[ci * m1 * m2..][..m1 * m2];
            let mut both = vec![false; m1 * m2];
            for ci in [i.wrapping_sub(1), i] {
                if ci < n0 - 1 {
                    for (o, &c) in both.iter_mut().zip(slab(ci)) {
                        *o |= c;
                    }
                }
            }
            let mut row = vec![false; m2];
            for j in 0..n1 {
                row.fill(false);
                for cj in [j.wrapping_sub(1), j] {
                    if cj < m1 {
                        for (o, &c) in row.iter_mut().zip(&both[cj * m2..][..m2]) {
                            *o |= c;
                        }
                    }
                }
                let base = (i * n1 + j) * n2;
                for k in 0..n2 {
                    let left = k > 0 && row[k - 1];
                    let right = k < m2 && row[k];
                    if left || right {
                        found.push(base + k);
                    }
                }
            }
            found
        })
        .collect();
    slabs.concat()
}
