//! Greedy centre reduction (Carr et al., *Reconstruction and representation of 3D objects with
//! radial basis functions*, SIGGRAPH 2001, §3.3): fit a subset of the constraints, evaluate
//! the field at all of them, add those whose residual exceeds the fitting tolerance, and fit
//! again, until every constraint is met to the tolerance. The field keeps only the centres it
//! chose — on a densely sampled scan far fewer than the points, for a field that is smaller to
//! store and faster to evaluate, at a stated accuracy.
//!
//! The start is `initial` constraints spread over the set (farthest-point order, the same
//! deterministic choice as the iterative fit's far centres); each round adds the constraints
//! over the tolerance, largest residual first, at most `growth` times the current count.
//!
//! ```
//! use zeroset_bases::rbf::{Biharmonic, Constraints, GreedyOptions, RbfFit};
//!
//! // Values of the plane x + y − z on a 12 × 12 grid of a curved sheet: a linear field, which
//! // the polynomial part of a few centres already reproduces.
//! let mut c = Constraints::new();
//! for i in 0..12 {
//!     for j in 0..12 {
//!         let (x, y) = (i as f64 / 11.0, j as f64 / 11.0);
//!         let z = 0.3 * (x * 3.0).sin() * y;
//!         c.push_value([x, y, z], x + y - z);
//!     }
//! }
//! let options = GreedyOptions { initial: 10, ..GreedyOptions::new(1e-6) };
//! let (fit, report) = RbfFit::new(Biharmonic).fit_greedy(&c, &options)?;
//! assert_eq!(fit.field.num_centres(), 10);
//! assert!(report.converged && report.max_residual <= 1e-6);
//! # Ok::<(), zeroset_bases::rbf::RbfError>(())
//! ```

use zeroset_field_core::field::ScalarField;

use super::constraints::{Constraints, Prescribed};
use super::iterative::spread;
use super::{Fitted, Kernel, RbfError, RbfFit};

/// How [`RbfFit::fit_greedy`] chooses its centres.
#[derive(Debug, Clone, PartialEq)]
pub struct GreedyOptions {
    /// The largest `|target − field|` allowed at any constraint (in the targets' units).
    pub tolerance: f64,
    /// Constraints in the first fit (default 1000, or all when there are fewer).
    pub initial: usize,
    /// A round adds at most this fraction of the current centres (default 1: the count at
    /// most doubles per round).
    pub growth: f64,
    /// Rounds at most (default 30); the last fit is returned with its residual reported.
    pub max_rounds: usize,
}

impl GreedyOptions {
    /// Reduction to `tolerance` with the default start, growth and round limit.
    pub fn new(tolerance: f64) -> Self {
        Self {
            tolerance,
            initial: 1000,
            growth: 1.0,
            max_rounds: 30,
        }
    }
}

/// One round of the reduction.
#[derive(Debug, Clone, PartialEq)]
pub struct GreedyRound {
    /// Centres fitted this round.
    pub centres: usize,
    /// Constraints over the tolerance after it.
    pub above: usize,
    /// The largest residual over all constraints after it.
    pub max_residual: f64,
}

/// What the reduction did.
#[derive(Debug, Clone, PartialEq)]
pub struct GreedyReport {
    /// Every round, in order.
    pub rounds: Vec<GreedyRound>,
    /// The largest `|target − field|` over all the constraints, for the field returned.
    pub max_residual: f64,
    /// Whether it met the tolerance everywhere (else the round limit stopped it).
    pub converged: bool,
}

impl<K: Kernel + Clone> RbfFit<K> {
    /// A field through a subset of `constraints` that meets all of them to
    /// `options.tolerance` (see the [module docs](super::greedy)). Value constraints only.
    ///
    /// # Errors
    /// As [`RbfFit::fit`]; [`RbfError::Degenerate`] for gradient constraints or a tolerance that
    /// is not finite and positive.
    pub fn fit_greedy<const D: usize>(
        &self,
        constraints: &Constraints<D>,
        options: &GreedyOptions,
    ) -> Result<(Fitted<K, D>, GreedyReport), RbfError> {
        if !(options.tolerance.is_finite() && options.tolerance > 0.0) {
            return Err(RbfError::Degenerate {
                detail: format!(
                    "the greedy fit's tolerance must be finite and > 0, got {}",
                    options.tolerance
                ),
            });
        }
        let all = constraints.as_slice();
        let mut points = Vec::with_capacity(all.len());
        let mut targets = Vec::with_capacity(all.len());
        for (index, c) in all.iter().enumerate() {
            match c.prescribed {
                Prescribed::Value(v) => {
                    points.push(c.point);
                    targets.push(v);
                }
                Prescribed::Gradient(_) => {
                    return Err(RbfError::Degenerate {
                        detail: format!(
                            "constraint {index} is a gradient: the greedy fit takes value constraints only"
                        ),
                    });
                }
            }
        }
        let n = all.len();
        let mut chosen = vec![false; n];
        for i in spread(&points, options.initial.clamp(1, n.max(1))) {
            chosen[i] = true;
        }
        let mut rounds = Vec::new();
        let mut values = vec![0.0; n];
        loop {
            let mut subset = Constraints::new();
            for (i, _) in chosen.iter().enumerate().filter(|(_, c)| **c) {
                subset.push_value(points[i], targets[i]);
            }
            let fitted = self.fit(&subset)?;
            fitted.field.values(&points, &mut values);
            let residuals: Vec<f64> = (0..n).map(|i| (targets[i] - values[i]).abs()).collect();
            let max_residual = residuals.iter().copied().fold(0.0, f64::max);
            let mut over: Vec<(f64, usize)> = residuals
                .iter()
                .enumerate()
                .filter(|&(_, &r)| r > options.tolerance)
                .map(|(i, &r)| (r, i))
                .collect();
            let count = subset.len();
            rounds.push(GreedyRound {
                centres: count,
                above: over.len(),
                max_residual,
            });
            // Chosen constraints over the tolerance (rounding in a badly conditioned fit) stay
            // chosen; only new ones can be added.
            over.retain(|&(_, i)| !chosen[i]);
            if over.is_empty() || rounds.len() >= options.max_rounds {
                let converged = rounds.last().is_some_and(|r| r.above == 0);
                return Ok((
                    fitted,
                    GreedyReport {
                        rounds,
                        max_residual,
                        converged,
                    },
                ));
            }
            over.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            let add = ((count as f64 * options.growth).ceil() as usize).max(1);
            for &(_, i) in over.iter().take(add) {
                chosen[i] = true;
            }
        }
    }
}
