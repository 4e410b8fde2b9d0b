//! Two-step **signed marching cubes** (SMC) and the **voxel-growing** (VG) baseline it improves
//! on: marching cubes that evaluates the expensive field only near the surface.
//!
//! Zhang, Zhong & Wang, *A Two-Step Surface Reconstruction Method Using Signed Marching Cubes*
//! (Appl. Sci. 12, 1792, 2022; paper 002), §2.3. Plain marching cubes evaluates the field at
//! every grid vertex (`N_MC` evaluations), although only the cells the surface crosses need
//! accurate values. The paper's fields are RBF interpolants evaluated by the fast multipole
//! method, whose expansion order trades accuracy for speed; SMC uses two orders:
//!
//! 1. **Coarse step.** A cheap approximation `s_p` (low expansion order) is evaluated at every
//!    grid vertex (`N_SMC,p = N_MC` cheap evaluations, in large batches, since the FMM's
//!    per-call setup is not free). The cells whose signs it cannot settle are the *candidates*.
//! 2. **Fine step.** The accurate field `s_P` (high order) is evaluated once at each distinct
//!    vertex of a candidate cell (`N_SMC,P` evaluations, in grid order), and marching cubes
//!    extracts the surface. The paper's Table 3 reports `γ = N_SMC,P / N_SMC,p`.
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
//! cell.

use std::time::Instant;

use rayon::prelude::*;
use zeroset_field_core::geometry::Point3;
use zeroset_field_core::{Grid, ScalarField};

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

/// What [`signed_marching_cubes`] did: the paper's evaluation counts (Table 3) and timings.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct SmcReport {
    /// Evaluations plain marching cubes makes: one per grid vertex (the paper's `N_MC`).
    pub n_mc: u64,
    /// Coarse-field evaluations of step 1: one per grid vertex, `= n_mc` (`N_SMC,p`).
    pub n_smc_low: u64,
    /// Fine-field evaluations of step 2: the distinct vertices of the candidate cells
    /// (`N_SMC,P`). The fine gradients taken for the normals (one per mesh vertex, as
    /// [`mesh_field`] takes them) are not counted.
    pub n_smc_high: u64,
    /// `n_smc_high / n_smc_low`, the paper's `γ`.
    pub gamma: f64,
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

/// The level surface `fine = level` on `grid`, by two-step signed marching cubes: `coarse` at
/// every vertex, `fine` only at the vertices of the cells the coarse values cannot settle (see
/// the [module docs](self)).
///
/// `margin` must bound the coarse field's error: `|coarse(x) − fine(x)| < margin` at every grid
/// vertex. Then the mesh is identical (vertices bit for bit, triangles and their order, normals)
/// to [`mesh_field`]`(fine, grid, level, options)`. `progress`, if given, is called at the start
/// of each stage.
///
/// Both fields are evaluated only through their batched [`ScalarField::values`], at most
/// [`BATCH`] points a call, in grid linear order; `fine.gradient` is called at the mesh vertices
/// when `options.normals`.
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
    options: &McOptions,
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
    let [n0, n1, n2] = n;
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
    let mut values = vec![0.0; len];
    evaluate(coarse, grid, &mut values, |chunk_start, k| chunk_start + k);
    if let Some(index) = values.par_iter().position_first(|v| !v.is_finite()) {
        return Err(samples::non_finite(grid, &values, index));
    }
    // Bit 0: possibly outside (v ≥ level); bit 1: possibly inside (v < level).
    let status: Vec<u8> = values
        .par_iter()
        .map(|&v| {
            if (v - level).abs() > margin {
                if v < level { 2 } else { 1 }
            } else {
                3
            }
        })
        .collect();
    report.uncertain_vertices = status.par_iter().filter(|&&s| s == 3).count() as u64;
    let cells = [n0 - 1, n1 - 1, n2 - 1];
    let candidate = mixed_cells(n, &status);
    report.candidate_cells = candidate.par_iter().filter(|&&c| c).count() as u64;
    drop(status);
    let refine: Vec<usize> = (0..len)
        .into_par_iter()
        .filter(|&l| {
            let idx = grid.multi_index(l);
            (0..8).any(|corner: usize| {
                let c: [usize; 3] = std::array::from_fn(|a| {
                    let d = (corner >> a) & 1;
                    // The cell whose corner `corner` is this vertex.
                    idx[a].wrapping_sub(d)
                });
                c.iter().zip(&cells).all(|(&x, &m)| x < m)
                    && candidate[(c[0] * cells[1] + c[1]) * cells[2] + c[2]]
            })
        })
        .collect();
    drop(candidate);
    report.n_smc_high = refine.len() as u64;
    report.gamma = report.n_smc_high as f64 / report.n_smc_low as f64;
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
    let mesh = marching_cubes(grid, &values, level, &options.with_normals(false))?;
    drop(values);
    let mesh = with_gradient_normals(mesh, fine, options)?;
    report.extract_seconds = start.elapsed().as_secs_f64();
    Ok((mesh, report))
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
    let mesh = with_gradient_normals(mesh, field, options)?;
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
/// its corners' status bits (1: possibly outside, 2: possibly inside) is 3.
fn mixed_cells(n: [usize; 3], status: &[u8]) -> Vec<bool> {
    let [_, n1, n2] = n;
    let cells = [n[0] - 1, n1 - 1, n2 - 1];
    let mut out = vec![false; cells[0] * cells[1] * cells[2]];
    out.par_chunks_mut(cells[1] * cells[2])
        .enumerate()
        .for_each(|(ci, slab)| {
            for cj in 0..cells[1] {
                for ck in 0..cells[2] {
                    let mut or = 0u8;
                    for corner in 0..8 {
                        let s = status[((ci + (corner & 1)) * n1 + cj + ((corner >> 1) & 1)) * n2
                            + ck
                            + (corner >> 2)];
                        or |= s;
                    }
                    slab[cj * cells[2] + ck] = or == 3;
                }
            }
        });
    out
}
