//! Linear function spaces: `f(x) = Σⱼ cⱼ bⱼ(x)`.
//!
//! A [`Basis`] turns fitting into linear least squares. For points `pᵢ` with target values `yᵢ`
//! the **design matrix** `A[i, j] = bⱼ(pᵢ)` gives `min_c ‖A c − y‖₂`; gradient constraints
//! `∇f(pᵢ) ≈ nᵢ` add the rows `∂bⱼ/∂x_a(pᵢ)`. Compactly supported bases (B-splines, MRAS) give
//! sparse rows; global ones (RBF, polynomials, a neural net's last hidden layer) dense rows —
//! the same [`BasisRow`] carries both.
//!
//! ```
//! use zeroset_field_core::basis::{Basis, PolynomialBasis, design_matrix};
//! use zeroset_field_core::geometry::Aabb;
//!
//! // 1, u, v, u², uv, v² on the unit square (u, v scaled to [-1, 1]).
//! let basis = PolynomialBasis::<2>::new(Aabb::new([0.0, 0.0], [1.0, 1.0])?, 2);
//! assert_eq!(basis.num_coefficients(), 6);
//! let a = design_matrix(&basis, &[[0.5, 0.5], [1.0, 0.0]]);
//! assert_eq!((a.nrows(), a.ncols()), (2, 6));
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```

use faer::sparse::{SparseRowMat, SymbolicSparseRowMat};
use rayon::prelude::*;

use crate::field::ScalarField;
use crate::geometry::{Aabb, Point};
use crate::lsq::{LeastSquaresSolver, LsqMatrix, SolveError, SolveInfo};

/// The non-zero basis functions at one point: `values[k] = b_{indices[k]}(p)` and, when asked
/// for, `gradients[k] = ∇b_{indices[k]}(p)`. Indices are strictly increasing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BasisRow<const D: usize> {
    /// Coefficient indices, strictly increasing.
    pub indices: Vec<usize>,
    /// Basis values at the point.
    pub values: Vec<f64>,
    /// Basis gradients at the point (empty unless requested).
    pub gradients: Vec<Point<D>>,
}

impl<const D: usize> BasisRow<D> {
    /// An empty row.
    pub fn new() -> Self {
        Self::default()
    }

    /// Empties the row, keeping its allocations.
    pub fn clear(&mut self) {
        self.indices.clear();
        self.values.clear();
        self.gradients.clear();
    }
}

/// A finite-dimensional linear function space on `Rᴰ`.
pub trait Basis<const D: usize>: Send + Sync {
    /// The number of basis functions (coefficients), `n`.
    fn num_coefficients(&self) -> usize;

    /// The box the basis is built on.
    fn bounds(&self) -> Aabb<D>;

    /// An upper bound on the non-zeros of one row (`n` for a dense basis).
    fn max_row_nnz(&self) -> usize;

    /// Writes the basis functions that may be non-zero at `p` into `row` (cleared first), with
    /// their gradients when `with_gradients`. Indices must be strictly increasing.
    fn eval_row(&self, p: &Point<D>, with_gradients: bool, row: &mut BasisRow<D>);
}

/// Rows computed per rayon task in the assembly functions.
const ROW_CHUNK: usize = 256;

/// Assembles a CSR matrix from per-point rows, in parallel, with a deterministic layout.
fn assemble<const D: usize, B: Basis<D> + ?Sized>(
    basis: &B,
    points: &[Point<D>],
    rows_per_point: usize,
    with_gradients: bool,
    emit: impl Fn(&BasisRow<D>, usize, &mut Vec<(usize, f64)>) + Sync,
) -> SparseRowMat<usize, f64> {
    let chunks: Vec<Vec<Vec<(usize, f64)>>> = points
        .par_chunks(ROW_CHUNK)
        .map(|ps| {
            let mut row = BasisRow::new();
            let mut out = Vec::with_capacity(ps.len() * rows_per_point);
            for p in ps {
                basis.eval_row(p, with_gradients, &mut row);
                for r in 0..rows_per_point {
                    let mut entries = Vec::with_capacity(row.indices.len());
                    emit(&row, r, &mut entries);
                    if !entries.windows(2).all(|w| w[0].0 < w[1].0) {
                        entries.sort_by_key(|e| e.0);
                        entries.dedup_by(|b, a| {
                            let same = a.0 == b.0;
                            if same {
                                a.1 += b.1;
                            }
                            same
                        });
                    }
                    out.push(entries);
                }
            }
            out
        })
        .collect();
    let nrows = points.len() * rows_per_point;
    let mut row_ptr = Vec::with_capacity(nrows + 1);
    let mut col_idx = Vec::new();
    let mut val = Vec::new();
    row_ptr.push(0);
    for entries in chunks.iter().flatten() {
        for &(j, v) in entries {
            col_idx.push(j);
            val.push(v);
        }
        row_ptr.push(col_idx.len());
    }
    let n = basis.num_coefficients();
    let symbolic = SymbolicSparseRowMat::new_checked(nrows, n, row_ptr, None, col_idx);
    SparseRowMat::new(symbolic, val)
}

/// The design matrix `A[i, j] = bⱼ(pᵢ)`, one row per point, as compressed sparse rows.
pub fn design_matrix<const D: usize, B: Basis<D> + ?Sized>(
    basis: &B,
    points: &[Point<D>],
) -> SparseRowMat<usize, f64> {
    assemble(basis, points, 1, false, |row, _, out| {
        out.extend(row.indices.iter().copied().zip(row.values.iter().copied()));
    })
}

/// The gradient design matrix: `D` rows per point, row `D·i + a` holding `∂bⱼ/∂x_a(pᵢ)`.
pub fn gradient_design_matrix<const D: usize, B: Basis<D> + ?Sized>(
    basis: &B,
    points: &[Point<D>],
) -> SparseRowMat<usize, f64> {
    assemble(basis, points, D, true, |row, a, out| {
        out.extend(
            row.indices
                .iter()
                .copied()
                .zip(row.gradients.iter().map(|g| g[a])),
        );
    })
}

/// A field `f(x) = Σⱼ cⱼ bⱼ(x)` from a basis and its coefficients, with exact gradients.
#[derive(Debug, Clone)]
pub struct BasisField<B> {
    basis: B,
    coefficients: Vec<f64>,
}

impl<B> BasisField<B> {
    /// The field with these coefficients.
    ///
    /// # Errors
    /// [`crate::Error::ShapeMismatch`] if the coefficient count is not the basis's.
    pub fn new<const D: usize>(basis: B, coefficients: Vec<f64>) -> crate::Result<Self>
    where
        B: Basis<D>,
    {
        if coefficients.len() != basis.num_coefficients() {
            return Err(crate::Error::ShapeMismatch {
                what: "basis coefficients",
                expected: basis.num_coefficients(),
                got: coefficients.len(),
            });
        }
        Ok(Self {
            basis,
            coefficients,
        })
    }

    /// The basis.
    pub fn basis(&self) -> &B {
        &self.basis
    }

    /// The coefficients.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }
}

impl<const D: usize, B: Basis<D>> ScalarField<D> for BasisField<B> {
    fn value(&self, p: &Point<D>) -> f64 {
        let mut row = BasisRow::new();
        self.basis.eval_row(p, false, &mut row);
        row.indices
            .iter()
            .zip(&row.values)
            .map(|(&j, v)| self.coefficients[j] * v)
            .sum()
    }
    fn gradient(&self, p: &Point<D>) -> Point<D> {
        let mut row = BasisRow::new();
        self.basis.eval_row(p, true, &mut row);
        let mut g = [0.0; D];
        for (&j, gj) in row.indices.iter().zip(&row.gradients) {
            for a in 0..D {
                g[a] += self.coefficients[j] * gj[a];
            }
        }
        g
    }
    fn bounds(&self) -> Option<Aabb<D>> {
        Some(self.basis.bounds())
    }
}

/// Fits `f = Σ cⱼ bⱼ` to values: `min_c Σᵢ (f(pᵢ) − yᵢ)²` with the given solver.
///
/// # Errors
/// [`SolveError::ShapeMismatch`] when `values` and `points` differ in length, otherwise
/// whatever the solver reports (e.g. [`SolveError::RankDeficient`] when the points do not
/// determine the coefficients).
pub fn fit_values<const D: usize, B: Basis<D>>(
    basis: B,
    points: &[Point<D>],
    values: &[f64],
    solver: &dyn LeastSquaresSolver,
) -> Result<(BasisField<B>, SolveInfo), SolveError> {
    if values.len() != points.len() {
        return Err(SolveError::ShapeMismatch {
            what: "values",
            expected: points.len(),
            got: values.len(),
        });
    }
    let a = design_matrix(&basis, points);
    let solution = solver.solve(LsqMatrix::SparseRow(a.as_ref()), values)?;
    let field = BasisField {
        basis,
        coefficients: solution.x,
    };
    Ok((field, solution.info))
}

/// Polynomials of total degree `≤ degree` in the scaled coordinates `u = (x − c)/r` (`c` the
/// box centre, `r` its half-extent), so that `u ∈ [−1, 1]ᴰ` on the box and the design matrix
/// stays well conditioned. Dense rows. Useful on its own (a global quadric fit) and as the
/// polynomial part of an RBF.
#[derive(Debug, Clone, PartialEq)]
pub struct PolynomialBasis<const D: usize> {
    bounds: Aabb<D>,
    center: Point<D>,
    inv_half: Point<D>,
    exponents: Vec<[u32; D]>,
}

impl<const D: usize> PolynomialBasis<D> {
    /// All monomials `u^α` with `|α| ≤ degree`, ordered by degree and then lexicographically.
    /// A flat axis of the box is scaled by 1.
    pub fn new(bounds: Aabb<D>, degree: u32) -> Self {
        let mut exponents = Vec::new();
        for total in 0..=degree {
            let mut alpha = [0u32; D];
            Self::push_exponents(&mut alpha, 0, total, &mut exponents);
        }
        let half = bounds.extent().map(|e| if e > 0.0 { e / 2.0 } else { 1.0 });
        Self {
            bounds,
            center: bounds.center(),
            inv_half: half.map(|h| 1.0 / h),
            exponents,
        }
    }

    fn push_exponents(alpha: &mut [u32; D], axis: usize, left: u32, out: &mut Vec<[u32; D]>) {
        if D == 0 {
            return;
        }
        if axis == D - 1 {
            alpha[axis] = left;
            out.push(*alpha);
            return;
        }
        for e in (0..=left).rev() {
            alpha[axis] = e;
            Self::push_exponents(alpha, axis + 1, left - e, out);
        }
    }

    /// The exponents `α` of the monomials, in coefficient order.
    pub fn exponents(&self) -> &[[u32; D]] {
        &self.exponents
    }
}

impl<const D: usize> Basis<D> for PolynomialBasis<D> {
    fn num_coefficients(&self) -> usize {
        self.exponents.len()
    }
    fn bounds(&self) -> Aabb<D> {
        self.bounds
    }
    fn max_row_nnz(&self) -> usize {
        self.exponents.len()
    }
    fn eval_row(&self, p: &Point<D>, with_gradients: bool, row: &mut BasisRow<D>) {
        row.clear();
        let u: Point<D> = std::array::from_fn(|a| (p[a] - self.center[a]) * self.inv_half[a]);
        for (j, alpha) in self.exponents.iter().enumerate() {
            row.indices.push(j);
            row.values
                .push((0..D).map(|a| u[a].powi(alpha[a] as i32)).product());
            if with_gradients {
                row.gradients.push(std::array::from_fn(|b| {
                    if alpha[b] == 0 {
                        return 0.0;
                    }
                    let d = alpha[b] as f64 * u[b].powi(alpha[b] as i32 - 1) * self.inv_half[b];
                    (0..D)
                        .filter(|&a| a != b)
                        .map(|a| u[a].powi(alpha[a] as i32))
                        .product::<f64>()
                        * d
                }));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::central_difference_gradient;

    #[test]
    fn polynomial_counts_match_binomials() {
        let b = Aabb::centered_cube(1.0).unwrap();
        // C(d + D, D): 1, 4, 10, 20 in 3-D.
        for (deg, n) in [(0, 1), (1, 4), (2, 10), (3, 20)] {
            assert_eq!(PolynomialBasis::<3>::new(b, deg).num_coefficients(), n);
        }
        assert_eq!(
            PolynomialBasis::<2>::new(Aabb::centered_cube(1.0).unwrap(), 3).num_coefficients(),
            10
        );
    }

    #[test]
    fn basis_field_gradient_is_exact() {
        let basis =
            PolynomialBasis::<3>::new(Aabb::new([0.0, -1.0, 2.0], [2.0, 3.0, 3.0]).unwrap(), 3);
        let c: Vec<f64> = (0..basis.num_coefficients())
            .map(|j| (j as f64 * 0.7).sin())
            .collect();
        let f = BasisField::new(basis, c).unwrap();
        for p in [[0.3, 0.2, 2.5], [1.9, -0.8, 2.1], [1.0, 1.0, 2.9]] {
            let g = f.gradient(&p);
            let fd = central_difference_gradient(&f, &p);
            for a in 0..3 {
                assert!(
                    (g[a] - fd[a]).abs() < 1e-7 * (1.0 + g[a].abs()),
                    "{g:?} vs {fd:?}"
                );
            }
        }
    }

    #[test]
    fn design_matrices_hold_values_and_gradients() {
        let basis = PolynomialBasis::<2>::new(Aabb::centered_cube(2.0).unwrap(), 2);
        let pts = [[0.5, -1.0], [2.0, 2.0], [0.0, 0.0]];
        let a = design_matrix(&basis, &pts);
        let g = gradient_design_matrix(&basis, &pts);
        assert_eq!((a.nrows(), a.ncols()), (3, 6));
        assert_eq!((g.nrows(), g.ncols()), (6, 6));
        let mut row = BasisRow::new();
        basis.eval_row(&pts[0], true, &mut row);
        let dense_a = a.to_dense();
        let dense_g = g.to_dense();
        for j in 0..6 {
            assert_eq!(dense_a[(0, j)], row.values[j]);
            assert_eq!(dense_g[(1, j)], row.gradients[j][1]);
        }
        // u = x/2: at (0.5, -1): 1, u, v, u², uv, v²  with (u, v) = (0.25, -0.5).
        assert_eq!(row.values, vec![1.0, 0.25, -0.5, 0.0625, -0.125, 0.25]);
    }
}
