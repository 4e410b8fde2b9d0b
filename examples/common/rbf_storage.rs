//! The RBF side of the storage-versus-accuracy comparison with MRAS (paper 004): how many
//! numbers a zeroset RBF field needs to store to reach a given accuracy on a scanned cloud.
//!
//! For each subset size `N`, a seeded random subset of `N` points of the oriented cloud is
//! fitted exactly as `zeroset fit POINTS --method rbf` does by default for a point cloud:
//! off-surface constraints (Carr et al.: value 0 at every point, `±εᵢ` at `pᵢ ± εᵢ nᵢ`) with
//! [`Offset::Auto`]` { fraction: 0.01 }` (εᵢ starts at 1% of the *subset's* box diagonal and is
//! halved until the offset point's nearest input point is its own), kernel `r` (biharmonic) and
//! [`Solver::Auto`] (dense up to [`AUTO_DENSE_LIMIT`](zeroset_bases::rbf::AUTO_DENSE_LIMIT)
//! functionals, above that GMRES in the cardinal basis, falling back to the dense solve if it
//! does not converge).
//!
//! Accuracy is measured against **all** points of the cloud, not only the subset: for each
//! point `p`, the distance from `p` to the field's zero set, found by
//! [`distance_to_zero_set`] (Newton steps along the gradient, value tolerance
//! `1e-9 × diagonal`, at most 50 steps). Points where it finds no zero set are counted as
//! failed and left out of the max and mean, which are reported relative to the full cloud's
//! box diagonal — the paper's error measure.
//!
//! Storage counts the parameters of the representation, as the MRAS paper counts its own: the
//! centres (`D = 3` coordinates each), one weight per centre and the linear polynomial's
//! coefficients (4), all read from the fitted field. The constraint targets the field also
//! keeps are not counted: they are not needed to evaluate it.
//!
//! Subsets are drawn by a Fisher–Yates shuffle driven by SplitMix64 (the generator of
//! `examples/common/rng.rs`, inlined here because `rand`/`rand_chacha` are dependencies of the
//! library crates, not of the examples), then the first `N` indices are taken, so the subsets
//! of one seed are nested.
//!
//! **Memory.** The RBF system of `n = 3N − dropped` constraints is dense: a dense solve (the
//! default below 2,000 functionals, or the fallback when GMRES fails above) holds the
//! `(n + 4)²` matrix in f64 and a factor of the same size, about `16 (n + 4)²` bytes, ~2.3 GB
//! at 12,000 constraints (4,000 points) and ~9 GB at 24,000. [`rbf_rows`] therefore refuses
//! sizes above [`MAX_CONSTRAINTS`]` / 3` points, which keeps a run safe on a 24 GiB machine.

#![allow(dead_code)] // each example uses what it needs

use std::error::Error;
use std::time::Instant;

use rayon::prelude::*;
use zeroset_bases::rbf::{Biharmonic, Constraints, Fitted, Offset, RbfFit, Solver};
use zeroset_field_core::PointCloud3;
use zeroset_field_core::field::distance_to_zero_set;

/// The largest number of constraints (`3 ×` subset size, before dropped offset points) that
/// [`rbf_rows`] fits: the dense RBF solve needs about `16 (n + 4)²` bytes, ~2.3 GB here, safe
/// on a 24 GiB machine alongside the rest of the run.
pub const MAX_CONSTRAINTS: usize = 12_000;

/// Newton steps [`distance_to_zero_set`] may take per point.
const MAX_STEPS: usize = 50;

/// One fitted subset: its size, storage, accuracy on the whole cloud, and fit time.
#[derive(Debug, Clone, PartialEq)]
pub struct RbfRow {
    /// RBF centres (functionals) of the field: one per constraint.
    pub centres: usize,
    /// Constraints fitted: the subset's points plus the off-surface points kept.
    pub constraints: usize,
    /// Numbers stored: `3 × centres` coordinates + `centres` weights + the polynomial's 4.
    pub stored: usize,
    /// Largest distance from a cloud point to the zero set, divided by the diagonal.
    pub max_rel: f64,
    /// Mean distance from a cloud point to the zero set, divided by the diagonal.
    pub mean_rel: f64,
    /// Cloud points where [`distance_to_zero_set`] found no zero set (left out of max/mean).
    pub failed: usize,
    /// Wall-clock seconds to build the constraints and fit the field.
    pub fit_seconds: f64,
    /// What was fitted, e.g. `rbf r off-surface auto-1% (gmres-cardinal)`.
    pub method: String,
}

/// Fits zeroset RBF fields to seeded random subsets (sizes `sizes`) of the oriented cloud and
/// measures, against ALL `points`, the distance to the field's zero set relative to `diagonal`.
///
/// Sizes larger than the cloud are skipped. One progress line per size goes to stderr.
///
/// # Errors
/// Mismatched `points`/`normals`, a `diagonal` that is not finite and positive, a size above
/// [`MAX_CONSTRAINTS`]` / 3` (checked before anything is fitted), or a failed constraint
/// build or fit (named by size).
pub fn rbf_rows(
    points: &[[f64; 3]],
    normals: &[[f64; 3]],
    diagonal: f64,
    sizes: &[usize],
    seed: u64,
) -> Result<Vec<RbfRow>, Box<dyn Error>> {
    if points.len() != normals.len() {
        return Err(format!(
            "rbf_rows: {} points but {} normals",
            points.len(),
            normals.len()
        )
        .into());
    }
    if !(diagonal.is_finite() && diagonal > 0.0) {
        return Err(
            format!("rbf_rows: the diagonal must be finite and > 0, got {diagonal}").into(),
        );
    }
    let sizes: Vec<usize> = sizes
        .iter()
        .copied()
        .filter(|&n| n <= points.len())
        .collect();
    if let Some(&n) = sizes.iter().find(|&&n| 3 * n > MAX_CONSTRAINTS) {
        return Err(format!(
            "rbf_rows: {n} points make up to {} constraints, above the limit of \
             {MAX_CONSTRAINTS} (the dense RBF solve needs O(n²) memory)",
            3 * n
        )
        .into());
    }
    let order = shuffled(points.len(), seed);
    let mut rows = Vec::with_capacity(sizes.len());
    for n in sizes {
        eprintln!("rbf_storage: fitting {n} points ...");
        let start = Instant::now();
        let take = &order[..n];
        let cloud = PointCloud3::with_normals(
            take.iter().map(|&i| points[i]).collect(),
            take.iter().map(|&i| normals[i]).collect(),
        )
        .map_err(|e| format!("rbf_rows: subset of {n}: {e}"))?;
        let (c, _offset) = Constraints::off_surface(&cloud, Offset::Auto { fraction: 0.01 })
            .map_err(|e| format!("rbf_rows: subset of {n}: off-surface constraints: {e}"))?;
        let Fitted { field, report } = RbfFit::new(Biharmonic)
            .with_solver(Solver::Auto)
            .fit(&c)
            .map_err(|e| format!("rbf_rows: subset of {n}: RBF fit: {e}"))?;
        let fit_seconds = start.elapsed().as_secs_f64();

        let tol = 1e-9 * diagonal;
        let (count, max, sum) = points
            .par_iter()
            .map(|p| distance_to_zero_set(&field, p, tol, MAX_STEPS))
            .fold(
                || (0usize, 0.0f64, 0.0f64),
                |(k, m, s), d| match d {
                    Some(d) => (k + 1, m.max(d), s + d),
                    None => (k, m, s),
                },
            )
            .reduce(
                || (0, 0.0, 0.0),
                |(k1, m1, s1), (k2, m2, s2)| (k1 + k2, m1.max(m2), s1 + s2),
            );
        let failed = points.len() - count;
        let (max_rel, mean_rel) = if count == 0 {
            (f64::NAN, f64::NAN)
        } else {
            (max / diagonal, sum / count as f64 / diagonal)
        };
        let centres = field.num_centres();
        let coordinates = field.centres().iter().map(|p| p.len()).sum::<usize>();
        let stored = coordinates + field.weights().len() + field.polynomial_coefficients().len();
        eprintln!(
            "rbf_storage: {n} points: {} constraints, {} solver, fit {fit_seconds:.2} s, max \
             {max_rel:.3e}, mean {mean_rel:.3e}, {failed} failed ({:.1} s in all)",
            c.len(),
            report.solver,
            start.elapsed().as_secs_f64()
        );
        rows.push(RbfRow {
            centres,
            constraints: c.len(),
            stored,
            max_rel,
            mean_rel,
            failed,
            fit_seconds,
            method: format!("rbf r off-surface auto-1% ({})", report.solver),
        });
    }
    Ok(rows)
}

/// `0..len` in a seeded random order: Fisher–Yates with SplitMix64.
fn shuffled(len: usize, seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..len).collect();
    zeroset::core::rng::SplitMix64::new(seed).shuffle(&mut order);
    order
}
