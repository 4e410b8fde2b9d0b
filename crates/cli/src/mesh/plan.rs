//! Whether the two-step signed marching cubes pay on a grid, decided before paying for them.
//!
//! Plain marching cubes of an RBF field evaluates the exact field (the direct sum over its `N`
//! centres, vectorised) at every one of the grid's `N_MC` vertices: `N_MC · N` kernel terms.
//! The signed marching cubes pay a fixed price first — the M2L operators of both orders unless
//! a cache holds them, both multipole fields' builds, and the error of each order sampled
//! against the direct sum at [`DEFAULT_ERROR_SAMPLES`] points — and then little per vertex.
//! So on a coarse grid or a small field plain marching cubes wins, on a fine grid of a large
//! field the signed ones win by far (a 256³ grid of a 10,000-centre field: about 60× less
//! work).
//!
//! The model counts everything in units of one exact kernel term, so it needs no machine
//! constants and its verdict does not depend on the machine; the term's time `c`, measured for
//! the field ([`calibrate`]: the direct sum at up to a few hundred grid points), only turns
//! both sides into the seconds the command prints:
//!
//! ```text
//!   plain MC   N_MC · N
//!   SMC        S N  +  B N  +  V N_MC  +  ops(p) + ops(P)
//! ```
//!
//! with `S` the error samples (the direct sum there serves both orders), `B` the two fields' builds per centre, `V` the
//! evaluations, enclosures and bookkeeping per grid vertex, and `ops(p) ≈ A p⁶` for operators
//! that must be built (0 in memory; a read of a few milliseconds on disk; per cell width, about
//! [`LEVELS`] widths, for a kernel that is not homogeneous). `B`, `V` and `A` were measured on
//! fields of scans (see the constants). The signed marching cubes
//! are chosen only when the model says they take at most [`WIN`] of plain marching cubes'
//! time, so a wrong guess near the break-even point costs little.

use std::time::Instant;

use zeroset_bases::rbf::fmm::cache::{self, Cached};
use zeroset_bases::rbf::fmm::{DEFAULT_ERROR_SAMPLES, FmmOptions};
use zeroset_bases::rbf::{Kernel, RbfField};
use zeroset_field_core::Grid;
use zeroset_field_core::field::ScalarField;

// The constants were fitted to `zeroset mesh --method smc --always-smc` against `--method mc`
// on the bunny fields of 6,000 and 10,002 centres and the kitten's 15,630, from the coarse
// detail (441 vertices) to 6.5 million vertices, on 2 cores (a busy machine, so the fixed part
// is on the high side; the model errs towards plain marching cubes).

/// Everything but the error samples' direct sum that does not grow with the grid — both
/// fields' builds, the probe, the bookkeeping — in exact kernel terms per centre (measured
/// 30,000–43,000).
const BUILD_PER_CENTRE: f64 = 40_000.0;
/// Step 1 (evaluations or enclosures), step 2 and the triangulation's extra work, in exact
/// kernel terms per grid vertex (measured 150–200).
const PER_VERTEX: f64 = 250.0;
/// Building the operators of order `p`, in exact kernel terms per `p⁶` (about 0.3 s at
/// `p = 10` on 2 cores, cross approximation; 0.8 s with this constant at 1.3 ns a term).
const OPERATORS_PER_P6: f64 = 600.0;
/// Reading one order's operators from the disk cache, in exact kernel terms per `p⁶` (tens of
/// milliseconds at `p = 10`).
const READ_PER_P6: f64 = 50.0;
/// Cell widths a kernel that is not homogeneous needs operators for (one per tree level).
pub const LEVELS: f64 = 4.0;
/// The signed marching cubes are chosen when the model gives them at most this fraction of
/// plain marching cubes' time.
pub const WIN: f64 = 0.8;
/// The most grid points the direct sum is timed at (fewer on small grids: at most 1/64 of the
/// grid, so that the timing never costs more than a few percent of plain marching cubes).
const CALIBRATION_POINTS: usize = 512;

/// The model's verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    /// Estimated seconds of plain marching cubes on the exact field.
    pub plain_seconds: f64,
    /// Estimated seconds of the signed marching cubes, operators included.
    pub signed_seconds: f64,
    /// Where each order's operators are (low, high).
    pub operators: [Cached; 2],
}

impl Plan {
    /// Whether the signed marching cubes should run.
    pub fn signed_wins(&self) -> bool {
        self.signed_seconds <= WIN * self.plain_seconds
    }
}

/// Seconds per exact kernel term of `field`, from the direct sum at up to a few hundred
/// vertices spread over `grid` (after a warm-up of a few). Only the seconds the plan prints
/// depend on it: both sides of the model are multiples of it, so the verdict does not.
pub fn calibrate<K: Kernel + Clone>(field: &RbfField<K, 3>, grid: &Grid<3>) -> f64 {
    let n = grid.len().max(1);
    let count = (n / 64).clamp(8, CALIBRATION_POINTS);
    let points: Vec<[f64; 3]> = (0..count)
        .map(|i| grid.point(grid.multi_index(i * (n - 1) / count)))
        .collect();
    let mut out = vec![0.0; points.len()];
    field.values(&points[..8], &mut out[..8]);
    let t = Instant::now();
    field.values(&points, &mut out);
    let seconds = t.elapsed().as_secs_f64();
    seconds / (points.len() as f64 * field.num_centres().max(1) as f64)
}

/// The plan for meshing `field` on `grid` with orders `low` and `high`, `term` seconds per exact
/// kernel term ([`calibrate`]).
pub fn plan<K: Kernel + Clone>(
    field: &RbfField<K, 3>,
    grid: &Grid<3>,
    low: &FmmOptions,
    high: &FmmOptions,
    term: f64,
) -> Plan {
    let centres = field.num_centres() as f64;
    let vertices = grid.len() as f64;
    let kernel = field.kernel();
    let operators = [cache::cached(kernel, low), cache::cached(kernel, high)];
    let ops: f64 = [low.order, high.order]
        .iter()
        .zip(operators)
        .map(|(&p, where_)| {
            let p6 = (p as f64).powi(6);
            let levels = if kernel.homogeneity().is_some() {
                1.0
            } else {
                LEVELS
            };
            match where_ {
                Cached::InMemory => 0.0,
                Cached::OnDisk => READ_PER_P6 * p6,
                Cached::NotYet => levels * OPERATORS_PER_P6 * p6,
            }
        })
        .sum();
    // The direct sum at the error samples (once for both orders).
    let sampling = DEFAULT_ERROR_SAMPLES as f64 * centres;
    let signed = sampling + BUILD_PER_CENTRE * centres + PER_VERTEX * vertices + ops;
    Plan {
        plain_seconds: term * vertices * centres,
        signed_seconds: term * signed,
        operators,
    }
}

/// The folder the `zeroset` command keeps M2L operators in: `$ZEROSET_CACHE_DIR` (empty: no
/// disk cache), else `$XDG_CACHE_HOME/zeroset`, else `$HOME/.cache/zeroset`; `None` if none of
/// them is set.
pub fn cache_dir() -> Option<std::path::PathBuf> {
    use std::path::PathBuf;
    if let Some(dir) = std::env::var_os("ZEROSET_CACHE_DIR") {
        return (!dir.is_empty()).then(|| PathBuf::from(dir));
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME")
                .filter(|d| !d.is_empty())
                .map(|h| PathBuf::from(h).join(".cache"))
        })?;
    Some(base.join("zeroset"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use zeroset_bases::rbf::{Biharmonic, Constraints, RbfFit};
    use zeroset_field_core::Aabb;

    /// 300 points on the unit sphere with values 0 and ±0.1 off it: 900 centres.
    fn sphere() -> RbfField<Biharmonic, 3> {
        let mut c = Constraints::<3>::new();
        for i in 0..300 {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 300.0;
            let t = i as f64 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            let p = [r * t.cos(), r * t.sin(), z];
            c.push_value(p, 0.0);
            c.push_value(p.map(|v| 1.1 * v), 0.1);
            c.push_value(p.map(|v| 0.9 * v), -0.1);
        }
        RbfFit::new(Biharmonic).fit(&c).expect("fit").field
    }

    fn grid(n: usize) -> Grid<3> {
        let b = Aabb::new([-1.2; 3], [1.2; 3]).expect("box");
        Grid::vertex_centered(b, [n; 3]).expect("grid")
    }

    /// Plain marching cubes on a coarse grid, the signed ones on a fine grid; the verdict does
    /// not depend on the machine's speed (the term's time scales both sides).
    #[test]
    fn coarse_grids_go_plain_and_fine_grids_signed() {
        let field = sphere();
        let (low, high) = (FmmOptions::new(5), FmmOptions::new(10));
        for term in [1e-9, 5e-9] {
            let coarse = plan(&field, &grid(12), &low, &high, term);
            assert!(!coarse.signed_wins(), "{coarse:?}");
            assert!(coarse.plain_seconds < coarse.signed_seconds);
            let fine = plan(&field, &grid(300), &low, &high, term);
            assert!(fine.signed_wins(), "{fine:?}");
            assert!(fine.signed_seconds < 0.5 * fine.plain_seconds, "{fine:?}");
        }
    }

    /// The calibration measures a positive, finite time per kernel term.
    #[test]
    fn calibration_gives_a_time_per_term() {
        let term = calibrate(&sphere(), &grid(40));
        assert!(term.is_finite() && term > 0.0 && term < 1e-5, "{term}");
    }
}
