//! The last hidden layer as a learned [`Basis`], and the least-squares refit of the output
//! layer through it.

use std::time::Duration;

use zeroset_field_core::basis::{Basis, BasisRow, fit_values};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::lsq::{LeastSquaresSolver, SolveInfo};

use super::NeuralError;
use super::field::NeuralField;
use super::train::check_constraints;

/// The functions `bⱼ(x) = o · h_{L,j}(x)` (`j < w_L`, the last hidden layer's activations
/// times the output scale) and `b_{w_L}(x) = o`: the net is `f = Σⱼ cⱼ bⱼ` with
/// `c = (w_out, b_out)`, so for fixed hidden layers the output layer is a linear
/// least-squares problem. Dense rows, exact gradients.
#[derive(Debug, Clone, Copy)]
pub struct HiddenBasis<'a, const D: usize> {
    field: &'a NeuralField<D>,
}

impl<'a, const D: usize> HiddenBasis<'a, D> {
    /// The basis of `field`'s hidden layers.
    pub fn of(field: &'a NeuralField<D>) -> Self {
        Self { field }
    }
}

impl<const D: usize> Basis<D> for HiddenBasis<'_, D> {
    fn num_coefficients(&self) -> usize {
        self.field
            .layer(self.field.architecture().widths().len())
            .0
            .len()
            + 1
    }

    fn bounds(&self) -> Aabb<D> {
        self.field.domain()
    }

    fn max_row_nnz(&self) -> usize {
        self.num_coefficients()
    }

    fn eval_row(&self, p: &Point<D>, with_gradients: bool, row: &mut BasisRow<D>) {
        row.clear();
        let o = self.field.output_scale();
        let (h, g) = self.field.features(p, with_gradients);
        let n = h.len();
        row.indices.extend(0..=n);
        row.values.extend(h.iter().map(|v| o * v));
        row.values.push(o);
        if with_gradients {
            row.gradients.extend(g.iter().map(|gj| gj.map(|v| o * v)));
            row.gradients.push([0.0; D]);
        }
    }
}

/// What a last-layer refit did.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RefitReport {
    /// The data term `Σ (f(xᵢ) − zᵢ)²` before the refit.
    pub data_before: f64,
    /// The data term after it (at most `data_before`, up to the solver's tolerance).
    pub data_after: f64,
    /// `maxᵢ |f(xᵢ) − zᵢ|` after it.
    pub max_residual_after: f64,
    /// The solver's report.
    pub info: SolveInfo,
    /// Wall-clock time of the refit (design matrix, solve, evaluation).
    pub elapsed: Duration,
}

fn data_term<const D: usize>(
    field: &NeuralField<D>,
    points: &[Point<D>],
    targets: &[f64],
) -> (f64, f64) {
    let mut v = vec![0.0; points.len()];
    field.values(points, &mut v);
    v.iter().zip(targets).fold((0.0, 0.0), |(s, m), (f, z)| {
        let r = f - z;
        (s + r * r, f64::max(m, r.abs()))
    })
}

impl<const D: usize> NeuralField<D> {
    /// Refits the output layer `(w_out, b_out)` to the constraints by linear least squares
    /// with `solver`, keeping the hidden layers: `min_c ‖A c − z‖₂`, `A` the design matrix of
    /// [`HiddenBasis`] at the points. This minimises the data term over the output layer, so it
    /// never raises it (beyond the solver's tolerance); the curvature term is not part of the
    /// problem and may rise.
    ///
    /// # Errors
    /// The constraint errors of [`NeuralFit::fit`](super::NeuralFit::fit); the solver's
    /// error as [`NeuralError::Solve`] (e.g. rank deficient with fewer points than `w_L + 1`
    /// for a direct solver).
    pub fn refit_last_layer(
        &self,
        points: &[Point<D>],
        targets: &[f64],
        solver: &dyn LeastSquaresSolver,
    ) -> Result<(NeuralField<D>, RefitReport), NeuralError> {
        let start = std::time::Instant::now();
        check_constraints(points, targets)?;
        let (data_before, _) = data_term(self, points, targets);
        let (fitted, info) = fit_values(HiddenBasis::of(self), points, targets, solver)?;
        let c = fitted.coefficients();
        let (w, b) = c.split_at(c.len() - 1);
        let field = self.with_last_layer(w, b[0])?;
        let (data_after, max_residual_after) = data_term(&field, points, targets);
        Ok((
            field,
            RefitReport {
                data_before,
                data_after,
                max_residual_after,
                info,
                elapsed: start.elapsed(),
            },
        ))
    }
}
