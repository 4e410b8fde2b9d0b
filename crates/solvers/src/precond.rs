//! Preconditioners.
//!
//! A preconditioner here is an invertible `M` with `MᵀM ≈ AᵀA` (for a least-squares problem)
//! or `MᵀM ≈ K` (for an SPD system `K x = b`). LSQR and CGLS use it on the right — they solve
//! `min ‖A M⁻¹ y − b‖` and return `x = M⁻¹ y` — and PCG applies `M⁻¹M⁻ᵀ` to its residual. The
//! same object therefore serves all three, and the equivalences hold exactly: column scaling
//! for LSQR is Jacobi for PCG on the normal equations.

use std::fmt::Debug;

use rayon::prelude::*;

use crate::dst::{Direction, Dst1, dst1_split_along_axis};
use zeroset_field_core::lsq::{LsqMatrix, SolveError};

use crate::operator::Prepared;

/// An invertible `M` applied through `M⁻¹` and `M⁻ᵀ`.
pub trait Preconditioner: Send + Sync + Debug {
    /// A short name for reports.
    fn name(&self) -> &'static str;
    /// The size `n` of `M`.
    fn dim(&self) -> usize;
    /// `out ← M⁻¹ v`.
    fn apply_inverse(&self, v: &[f64], out: &mut [f64]);
    /// `out ← M⁻ᵀ v` (default: `M` symmetric).
    fn apply_inverse_transpose(&self, v: &[f64], out: &mut [f64]) {
        self.apply_inverse(v, out)
    }
}

/// `M = diag(d)`: column scaling for least squares (`dⱼ = ‖A eⱼ‖`), Jacobi for SPD systems
/// (`dⱼ = √Kⱼⱼ`). Zero entries (empty columns) are treated as 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagonal {
    inv: Vec<f64>,
}

impl Diagonal {
    /// `M = diag(d)`.
    pub fn new(d: &[f64]) -> Self {
        Self {
            inv: d
                .iter()
                .map(|&x| if x != 0.0 { 1.0 / x } else { 1.0 })
                .collect(),
        }
    }

    /// Column scaling for `A`: `M = diag(‖A e₁‖, …, ‖A eₙ‖)`.
    ///
    /// # Errors
    /// [`SolveError::Unsupported`] for a matrix-free operator (its columns are not known), and
    /// [`SolveError::NonFinite`] for a NaN or infinite entry.
    pub fn column_scaling(a: LsqMatrix<'_>) -> Result<Self, SolveError> {
        let prepared = Prepared::new(a)?;
        let norms = prepared.column_norms().ok_or(SolveError::Unsupported {
            solver: "column scaling",
            reason: "a matrix-free operator".into(),
        })?;
        Ok(Self::new(&norms))
    }

    /// Jacobi for an SPD matrix given by its diagonal: `M = diag(√Kⱼⱼ)`.
    pub fn jacobi(diagonal: &[f64]) -> Self {
        let d: Vec<f64> = diagonal.iter().map(|x| x.abs().sqrt()).collect();
        Self::new(&d)
    }
}

impl Preconditioner for Diagonal {
    fn name(&self) -> &'static str {
        "diagonal"
    }
    fn dim(&self) -> usize {
        self.inv.len()
    }
    fn apply_inverse(&self, v: &[f64], out: &mut [f64]) {
        out.par_iter_mut()
            .zip(v.par_iter().zip(&self.inv))
            .for_each(|(o, (x, s))| *o = x * s);
    }
}

/// `M = Σ_a s_a T_a`: the 7-point (3-D) Dirichlet Laplacian on a box of `n₀ × n₁ × n₂`
/// unknowns, ordered last axis fastest, `T = tridiag(1, −2, 1)` along each axis `a` and a scale
/// `s_a` per axis (no `1/d²`: fold the spacings into the scales; one `s` for all axes is
/// `s·Δ_h`, [`new`](Self::new)). Applied by the fast Poisson solver:
///
/// ```text
/// M⁻¹ v = S (Λ⁻¹ ∘ S v),   Λ_ijk = −4 Σ_a s_a sin²(π (i_a + 1) / (2(n_a + 1)))
/// ```
///
/// where `S = S₀ ⊗ S₁ ⊗ S₂` is the orthonormal 3-D DST-I ([`crate::dst`]), the eigenvector
/// matrix of `T` and its own inverse.
///
/// This is the preconditioner of restoration (Ren–Fujita–Nakata): its Laplace rows *are*
/// `M` (with `s_a = 1/6` on cubic cells, the rows' neighbour weights `w_a` on others), so LSQR on `A M⁻¹ = [I; T M⁻¹]` sees the identity plus a term of rank
/// at most the number of Neumann rows and converges in tens of iterations instead of
/// thousands (see `DESIGN.md`, "Two fast routes").
#[derive(Clone, Debug)]
pub struct DirichletLaplacian {
    dims: [usize; 3],
    inv_eigen: Vec<f64>,
    sine: [Dst1; 3],
}

impl DirichletLaplacian {
    /// The preconditioner for a box of `dims` unknowns and scale `s` (`s = 1/6` for rows
    /// `(Σ₆ neighbours − 6h)/6`).
    ///
    /// # Errors
    /// [`SolveError::ShapeMismatch`] for an empty axis, [`SolveError::NonFinite`] for a zero or
    /// non-finite scale.
    pub fn new(dims: [usize; 3], scale: f64) -> Result<Self, SolveError> {
        Self::with_axis_scales(dims, [scale; 3])
    }

    /// `M = Σ_a s_a T_a`, a scale per axis (`s_a = w_a`, the neighbour weights of the Laplace
    /// rows on cells that are not cubes: `Σ_a w_a (x_{c−e_a} − 2x_c + x_{c+e_a})`).
    ///
    /// # Errors
    /// As [`new`](Self::new), for any axis's scale, or for scales of different signs.
    pub fn with_axis_scales(dims: [usize; 3], scales: [f64; 3]) -> Result<Self, SolveError> {
        if let Some(axis) = dims.iter().position(|&d| d == 0) {
            return Err(SolveError::ShapeMismatch {
                what: "Laplacian box axis",
                expected: 1,
                got: dims[axis],
            });
        }
        // One sign for all (else `Σ_a s_a sin²` can vanish: a singular `M`).
        let sign = scales[0].signum();
        if let Some(a) = scales
            .iter()
            .position(|s| !(s.is_finite() && *s != 0.0 && s.signum() == sign))
        {
            return Err(SolveError::NonFinite {
                what: "Laplacian scale",
                index: a,
                value: scales[a],
            });
        }
        let pi = std::f64::consts::PI;
        let sin2 = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| (pi * (i + 1) as f64 / (2 * (n + 1)) as f64).sin().powi(2))
                .collect()
        };
        // In the split order of the transforms (even modes first), so no pass reorders.
        let sine = dims.map(Dst1::new);
        let [s0, s1, s2] = [0, 1, 2].map(|a| {
            let modes: Vec<usize> = (0..dims[a]).map(|j| sine[a].mode(j)).collect();
            let sin2 = sin2(dims[a]);
            modes
                .into_iter()
                .map(|p| scales[a] * sin2[p])
                .collect::<Vec<f64>>()
        });
        let mut inv_eigen = Vec::with_capacity(dims.iter().product());
        for a in &s0 {
            for b in &s1 {
                for c in &s2 {
                    inv_eigen.push(1.0 / (-4.0 * (a + b + c)));
                }
            }
        }
        Ok(Self {
            dims,
            inv_eigen,
            sine,
        })
    }

    /// The orthonormal 3-D DST-I of `data` in place, one axis at a time, `scratch` as scratch.
    fn dst3(&self, data: &mut [f64], scratch: &mut [f64], direction: Direction) {
        for axis in [2, 0, 1] {
            dst1_split_along_axis(data, scratch, &self.dims, axis, &self.sine[axis], direction);
        }
    }
}

impl Preconditioner for DirichletLaplacian {
    fn name(&self) -> &'static str {
        "dirichlet-laplacian"
    }
    fn dim(&self) -> usize {
        self.inv_eigen.len()
    }
    fn apply_inverse(&self, v: &[f64], out: &mut [f64]) {
        let mut scratch = crate::scratch::take(v.len());
        out.copy_from_slice(v);
        self.dst3(out, &mut scratch, Direction::Forward);
        out.par_iter_mut()
            .zip(self.inv_eigen.par_iter())
            .for_each(|(x, l)| *x *= l);
        self.dst3(out, &mut scratch, Direction::Inverse);
        crate::scratch::give_back(scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use zeroset_field_core::lsq::LinearOperator;

    #[test]
    fn fast_poisson_inverts_the_laplace_rows_of_the_protrusion_problem() {
        // The first k³ rows of the protrusion problem are (Σ₆ − 6h)/6: M with s = 1/6.
        let k = 5;
        let p = crate::problems::protrusion_problem(k, 1.0);
        let n = k * k * k;
        let m = DirichletLaplacian::new([k, k, k], 1.0 / 6.0).unwrap();
        let x: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let mut ax = vec![0.0; p.a.nrows()];
        LsqMatrix::SparseRow(p.a.as_ref()).apply(&x, &mut ax);
        let mut back = vec![0.0; n];
        m.apply_inverse(&ax[..n], &mut back);
        for (a, b) in x.iter().zip(&back) {
            assert!((a - b).abs() < 1e-11, "{a} vs {b}");
        }
    }

    #[test]
    fn non_cubic_boxes_invert_too() {
        let dims = [3, 4, 6];
        let m = DirichletLaplacian::new(dims, 2.0).unwrap();
        let n = 72;
        let idx = |i: usize, j: usize, l: usize| (i * 4 + j) * 6 + l;
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        // y = 2·Δ_h x with zero Dirichlet boundary.
        let mut y = vec![0.0; n];
        for i in 0..3 {
            for j in 0..4 {
                for l in 0..6 {
                    let mut s = -6.0 * x[idx(i, j, l)];
                    if i > 0 {
                        s += x[idx(i - 1, j, l)];
                    }
                    if i < 2 {
                        s += x[idx(i + 1, j, l)];
                    }
                    if j > 0 {
                        s += x[idx(i, j - 1, l)];
                    }
                    if j < 3 {
                        s += x[idx(i, j + 1, l)];
                    }
                    if l > 0 {
                        s += x[idx(i, j, l - 1)];
                    }
                    if l < 5 {
                        s += x[idx(i, j, l + 1)];
                    }
                    y[idx(i, j, l)] = 2.0 * s;
                }
            }
        }
        let mut back = vec![0.0; n];
        m.apply_inverse(&y, &mut back);
        for (a, b) in x.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        assert!(DirichletLaplacian::new([3, 0, 2], 1.0).is_err());
    }

    #[test]
    fn a_scale_per_axis_inverts_the_weighted_laplacian() {
        let dims = [3, 4, 6];
        let s = [0.05, 0.3, 0.15];
        let m = DirichletLaplacian::with_axis_scales(dims, s).unwrap();
        let n = 72;
        let idx = |i: [usize; 3]| (i[0] * 4 + i[1]) * 6 + i[2];
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        // y = Σ_a s_a (x_{c−e_a} − 2 x_c + x_{c+e_a}), zero Dirichlet boundary.
        let mut y = vec![0.0; n];
        for c in 0..n {
            let i = [c / 24, (c / 6) % 4, c % 6];
            for a in 0..3 {
                let mut t = -2.0 * x[c];
                if i[a] > 0 {
                    let mut j = i;
                    j[a] -= 1;
                    t += x[idx(j)];
                }
                if i[a] + 1 < dims[a] {
                    let mut j = i;
                    j[a] += 1;
                    t += x[idx(j)];
                }
                y[c] += s[a] * t;
            }
        }
        let mut back = vec![0.0; n];
        m.apply_inverse(&y, &mut back);
        for (a, b) in x.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        // Scales of mixed signs could make an eigenvalue 0.
        assert!(DirichletLaplacian::with_axis_scales(dims, [1.0, -1.0, 1.0]).is_err());
    }
}
