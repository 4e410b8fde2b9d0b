//! The matrix of protrusion removal on its box of unknowns, and its exact separable solve.
//!
//! After the fixed layers are taken out (the Neumann layer on the face `E`, the border layers),
//! the unknowns of protrusion removal fill a box `U` of `n₀ × … × n_{D−1}` cells, ordered last
//! axis fastest. With `w = 1/(2D)` the least-squares matrix is
//!
//! ```text
//!     A = [ L  ]   n rows:  (L x)_c = w·Σ_{neighbours c' of c in U} x_c' − x_c     (Laplace rows)
//!         [ wP ]   t rows:  (wP x)_j = w·x_{c_j}, c_j the cells of U's layer next to E (Neumann)
//! ```
//!
//! (neighbours outside `U` are fixed values and live in the right-hand side). `L` is the
//! Dirichlet Laplacian of the box, scaled by `w` — nonsingular, so `A` has full column rank:
//! that is Ren–Fujita–Nakata's uniqueness argument (§2.2: "A contains n rows identical to
//! Laplace's equation with the Dirichlet condition").
//!
//! ## The exact separable solve
//! Along every axis parallel to `E` the 1-D Dirichlet neighbour sum `T = tridiag(1, 0, 1)` is
//! diagonalised by the orthonormal DST-I, `S_a = √(2/(n_a+1)) sin(π(p+1)(q+1)/(n_a+1))`
//! (symmetric, `S_a² = I`), with eigenvalues `λ_p = 2 cos(π(p+1)/(n_a+1))`. Both row blocks
//! of `A` commute with `S = ⊗_{a ≠ axis(E)} S_a` acting across `E`'s layers, and `S` is
//! orthogonal, so `‖A x − b‖ = ‖(S A S) (S x) − S b‖` and the problem splits into one small
//! least-squares problem per lateral mode `m = (p, q)`, along `E`'s normal:
//!
//! ```text
//!     min ‖ [ tridiag(w, w(σ_m − 2D), w) ; w e_lastᵀ ] x̂_m − [ r̂_m ; ŝ_m ] ‖,   σ_m = Σ λ
//! ```
//!
//! a tridiagonal matrix with one extra row. Givens QR solves each in `O(n_axis)`, and is
//! backward stable (no normal equations, no squared condition number); the lines are laid out
//! position-major in blocks, so the sweeps run over contiguous rows of modes and vectorise.
//! The lateral transforms are the orthonormal DST-I of [`zeroset_solvers::dst`]: dense products
//! folded by parity, `n_a` flops per value and axis. The whole solve is exact up to rounding —
//! it agrees with dense QR to ~1e-14 (tested) and with an independent NumPy/SciPy port of the
//! method to ~4e-15 — and needs no iteration.
//!
//! Cost, measured on 2 cores (`examples/restoration_timing.rs`): 31,744 unknowns in ~1–2 ms,
//! 258,048 in ~20 ms, 2.1 M in ~0.25 s. The lateral products grow like `n_a` per value; an
//! FFT-based DST (`O(log n_a)`) would win from `n_a ≈ 64` on, and is the next step.

use std::time::Instant;

use faer::sparse::{SparseRowMat, SymbolicSparseRowMat};
use rayon::prelude::*;

use zeroset_field_core::lsq::{LinearOperator, Solution, SolveError, SolveInfo};
use zeroset_field_core::mask::{Face, Side};
use zeroset_solvers::dst::{Dst1, dst1_along_axis};

use crate::index::{multi_index, strides};

/// `A` of protrusion removal on a box of unknowns (see the module docs): `n` Laplace rows and,
/// with a Neumann face, `t = n / n_axis` rows on the layer next to it.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxLaplace<const D: usize> {
    dims: [usize; D],
    neumann: Option<Face>,
}

impl<const D: usize> BoxLaplace<D> {
    /// The matrix for a box of `dims` unknowns, with Neumann rows next to `neumann` if given.
    ///
    /// # Errors
    /// [`SolveError::ShapeMismatch`] for an empty axis or a face axis `≥ D`.
    pub fn new(dims: [usize; D], neumann: Option<Face>) -> Result<Self, SolveError> {
        if let Some(axis) = dims.iter().position(|&d| d == 0) {
            return Err(SolveError::ShapeMismatch {
                what: "box of unknowns",
                expected: 1,
                got: dims[axis],
            });
        }
        if let Some(face) = neumann
            && face.axis >= D
        {
            return Err(SolveError::ShapeMismatch {
                what: "Neumann face axis",
                expected: D - 1,
                got: face.axis,
            });
        }
        Ok(Self { dims, neumann })
    }

    /// The box of unknowns.
    pub fn dims(&self) -> [usize; D] {
        self.dims
    }

    /// The Neumann face, if any.
    pub fn neumann(&self) -> Option<Face> {
        self.neumann
    }

    /// `w = 1/(2D)`, the neighbour weight of the Laplace rows and the weight of Neumann rows.
    pub fn weight() -> f64 {
        1.0 / (2 * D) as f64
    }

    /// `n`, the number of unknowns.
    pub fn unknowns(&self) -> usize {
        self.dims.iter().product()
    }

    /// `t`, the number of Neumann rows (0 without a face).
    pub fn neumann_rows(&self) -> usize {
        self.neumann
            .map_or(0, |f| self.unknowns() / self.dims[f.axis])
    }

    /// The linear indices (into the box) of the cells next to the Neumann face, in row order.
    pub fn layer_cells(&self) -> Vec<usize> {
        let Some(face) = self.neumann else {
            return Vec::new();
        };
        let fixed = match face.side {
            Side::Lower => 0,
            Side::Upper => self.dims[face.axis] - 1,
        };
        let strides = strides(&self.dims);
        let mut layer = self.dims;
        layer[face.axis] = 1;
        (0..self.neumann_rows())
            .map(|j| {
                let mut index = multi_index(j, &layer);
                index[face.axis] = fixed;
                index.iter().zip(&strides).map(|(i, s)| i * s).sum()
            })
            .collect()
    }

    /// `A` assembled as a sparse row matrix (columns sorted in each row).
    pub fn to_sparse(&self) -> SparseRowMat<usize, f64> {
        let n = self.unknowns();
        let w = Self::weight();
        let strides = strides(&self.dims);
        let mut row_ptr = Vec::with_capacity(n + self.neumann_rows() + 1);
        let mut col_idx = Vec::with_capacity((2 * D + 1) * n);
        let mut val = Vec::with_capacity((2 * D + 1) * n);
        row_ptr.push(0);
        let mut entries: Vec<(usize, f64)> = Vec::with_capacity(2 * D + 1);
        for l in 0..n {
            let index = multi_index(l, &self.dims);
            entries.clear();
            entries.push((l, -1.0));
            for a in 0..D {
                if index[a] > 0 {
                    entries.push((l - strides[a], w));
                }
                if index[a] + 1 < self.dims[a] {
                    entries.push((l + strides[a], w));
                }
            }
            entries.sort_unstable_by_key(|e| e.0);
            for &(c, v) in &entries {
                col_idx.push(c);
                val.push(v);
            }
            row_ptr.push(col_idx.len());
        }
        for c in self.layer_cells() {
            col_idx.push(c);
            val.push(w);
            row_ptr.push(col_idx.len());
        }
        let m = row_ptr.len() - 1;
        let symbolic = SymbolicSparseRowMat::new_checked(m, n, row_ptr, None, col_idx);
        SparseRowMat::new(symbolic, val)
    }

    /// `‖A‖_F`, exactly.
    pub fn frobenius_norm(&self) -> f64 {
        let n = self.unknowns();
        let w = Self::weight();
        // Each neighbour pair inside the box appears twice (once in each row).
        let links: usize = (0..D)
            .map(|a| 2 * (self.dims[a] - 1) * n / self.dims[a])
            .sum();
        (n as f64 + (links + self.neumann_rows()) as f64 * w * w).sqrt()
    }

    /// `y ← L x` over the box (the Laplace rows only; `L` is symmetric).
    fn apply_laplace(&self, x: &[f64], y: &mut [f64]) {
        let w = Self::weight();
        let last = self.dims[D - 1];
        let strides = strides(&self.dims);
        y.par_chunks_mut(last).enumerate().for_each(|(line, out)| {
            let start = line * last;
            let index = multi_index(start, &self.dims);
            let xs = &x[start..start + last];
            for (k, o) in out.iter_mut().enumerate() {
                let mut s = 0.0;
                if k > 0 {
                    s += xs[k - 1];
                }
                if k + 1 < last {
                    s += xs[k + 1];
                }
                *o = s;
            }
            for a in 0..D - 1 {
                if index[a] > 0 {
                    let nb = &x[start - strides[a]..start - strides[a] + last];
                    out.iter_mut().zip(nb).for_each(|(o, v)| *o += v);
                }
                if index[a] + 1 < self.dims[a] {
                    let nb = &x[start + strides[a]..start + strides[a] + last];
                    out.iter_mut().zip(nb).for_each(|(o, v)| *o += v);
                }
            }
            out.iter_mut().zip(xs).for_each(|(o, v)| *o = w * *o - v);
        });
    }

    /// Solves `min ‖A x − b‖` exactly by the separable method of the module docs.
    ///
    /// # Errors
    /// [`SolveError::ShapeMismatch`] when `b.len() != nrows()`, [`SolveError::NonFinite`] for a
    /// NaN or infinite entry of `b`.
    pub fn solve(&self, b: &[f64]) -> Result<Solution, SolveError> {
        let start = Instant::now();
        let (n, t) = (self.unknowns(), self.neumann_rows());
        if b.len() != n + t {
            return Err(SolveError::ShapeMismatch {
                what: "b",
                expected: n + t,
                got: b.len(),
            });
        }
        if let Some(index) = b.iter().position(|v| !v.is_finite()) {
            return Err(SolveError::NonFinite {
                what: "b",
                index,
                value: b[index],
            });
        }
        let lines = Lines::new(&self.dims, self.neumann);
        let mut r = lines.gather(&b[..n]);
        let mut s = b[n..].to_vec();
        let mut tmp = vec![0.0; n];
        lines.lateral_transform(&mut r, &mut tmp, lines.len);
        if t > 0 {
            let mut tmp = vec![0.0; t];
            lines.lateral_transform(&mut s, &mut tmp, 1);
        }
        // One block per outer lateral index: a (len × inner) matrix, one mode per column, so
        // the Givens sweeps run over contiguous rows of modes (vectorised).
        let (len, inner) = (lines.len, lines.inner);
        let w = Self::weight();
        let residuals: Vec<f64> = r
            .par_chunks_mut(len * inner)
            .enumerate()
            .map_init(
                || BlockQr::new(len, inner),
                |qr, (outer, block)| {
                    let sigma_outer = lines.outer_eigenvalue(outer);
                    let diag: Vec<f64> = lines
                        .inner_eigen()
                        .iter()
                        .map(|e| w * (sigma_outer + e - (2 * D) as f64))
                        .collect();
                    let extra = (t > 0).then(|| &s[outer * inner..(outer + 1) * inner]);
                    qr.solve(&diag, w, extra, block)
                },
            )
            .collect();
        lines.lateral_transform(&mut r, &mut tmp, lines.len);
        let x = lines.scatter(&r);

        let residual = residuals.iter().map(|q| q * q).sum::<f64>().sqrt();
        let b_norm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        let rel_residual = if b_norm > 0.0 { residual / b_norm } else { 0.0 };
        let rel_normal_residual = self.normal_residual(&x, b);
        let mut info = SolveInfo::new(
            "separable-dst",
            0,
            rel_residual,
            rel_normal_residual,
            start.elapsed(),
        );
        info.details.push(("lateral_modes", (n / len) as f64));
        info.details.push(("line_length", len as f64));
        Ok(Solution { x, info })
    }

    /// `‖Aᵀ(b − A x)‖ / (‖A‖_F ‖b − A x‖)`, 0 for a zero residual.
    fn normal_residual(&self, x: &[f64], b: &[f64]) -> f64 {
        let mut r = vec![0.0; b.len()];
        self.apply(x, &mut r);
        r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
        let r_norm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        if r_norm == 0.0 {
            return 0.0;
        }
        let mut g = vec![0.0; x.len()];
        self.apply_transpose(&r, &mut g);
        g.iter().map(|v| v * v).sum::<f64>().sqrt() / (self.frobenius_norm() * r_norm)
    }
}

impl<const D: usize> LinearOperator for BoxLaplace<D> {
    fn nrows(&self) -> usize {
        self.unknowns() + self.neumann_rows()
    }
    fn ncols(&self) -> usize {
        self.unknowns()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let n = self.unknowns();
        let (lap, extra) = y.split_at_mut(n);
        self.apply_laplace(x, lap);
        let w = Self::weight();
        for (e, c) in extra.iter_mut().zip(self.layer_cells()) {
            *e = w * x[c];
        }
    }
    fn apply_transpose(&self, y: &[f64], x: &mut [f64]) {
        let n = self.unknowns();
        self.apply_laplace(&y[..n], x);
        let w = Self::weight();
        for (e, c) in y[n..].iter().zip(self.layer_cells()) {
            x[c] += w * e;
        }
    }
}

/// The box re-laid out for the separable solve: `(outer lateral axes…, normal, last lateral
/// axis)`, the normal axis oriented so that the Neumann layer is each line's end. A block (one
/// outer index) is a `len × inner` matrix whose columns are lines: the Givens sweeps along the
/// lines run over contiguous rows, and the DST along the last lateral axis is one product with
/// row-major blocks.
struct Lines {
    /// Extents and natural strides of the lateral axes but the last, in order.
    outer_dims: Vec<usize>,
    outer_strides: Vec<usize>,
    /// Extent and natural stride of the last lateral axis (1 and 0 in 1-D).
    inner: usize,
    inner_stride: usize,
    /// Orthonormal DST-I of each lateral axis (outer…, inner), folded by parity.
    sine: Vec<Dst1>,
    /// Eigenvalues `2 cos(π(p+1)/(n+1))` of each lateral axis (outer…, inner).
    eigen: Vec<Vec<f64>>,
    /// Natural stride of the normal axis.
    stride: usize,
    /// Line length (extent of the normal axis).
    len: usize,
    /// Whether lines run against the natural order (Neumann face on the lower side).
    reversed: bool,
}

impl Lines {
    fn new<const D: usize>(dims: &[usize; D], neumann: Option<Face>) -> Self {
        let axis = neumann.map_or(D - 1, |f| f.axis);
        let natural = strides(dims);
        let lateral: Vec<usize> = (0..D).filter(|&a| a != axis).collect();
        let pi = std::f64::consts::PI;
        let (outer, inner) = match lateral.split_last() {
            Some((&last, outer)) => (outer.to_vec(), Some(last)),
            None => (Vec::new(), None),
        };
        Self {
            outer_dims: outer.iter().map(|&a| dims[a]).collect(),
            outer_strides: outer.iter().map(|&a| natural[a]).collect(),
            inner: inner.map_or(1, |a| dims[a]),
            inner_stride: inner.map_or(0, |a| natural[a]),
            sine: lateral.iter().map(|&a| Dst1::new(dims[a])).collect(),
            eigen: lateral
                .iter()
                .map(|&a| {
                    let n = dims[a];
                    (0..n)
                        .map(|p| 2.0 * (pi * (p + 1) as f64 / (n + 1) as f64).cos())
                        .collect()
                })
                .collect(),
            stride: natural[axis],
            len: dims[axis],
            reversed: matches!(
                neumann,
                Some(Face {
                    side: Side::Lower,
                    ..
                })
            ),
        }
    }

    /// The natural offset of the first cell of block `outer` (inner index 0, position 0).
    fn block_start(&self, mut outer: usize) -> usize {
        let mut offset = 0;
        for (&d, &s) in self.outer_dims.iter().zip(&self.outer_strides).rev() {
            offset += (outer % d) * s;
            outer /= d;
        }
        offset
    }

    /// `Σ` of the outer axes' eigenvalues of block `outer`.
    fn outer_eigenvalue(&self, mut outer: usize) -> f64 {
        let mut sigma = 0.0;
        for (d, eig) in self.outer_dims.iter().zip(&self.eigen).rev() {
            sigma += eig[outer % d];
            outer /= d;
        }
        sigma
    }

    /// The eigenvalues of the inner (last lateral) axis; zeros in 1-D.
    fn inner_eigen(&self) -> &[f64] {
        if self.eigen.len() > self.outer_dims.len() {
            &self.eigen[self.outer_dims.len()]
        } else {
            &[0.0]
        }
    }

    /// The natural offset of position `k` along the line of block `start`, inner index `i`.
    fn at(&self, start: usize, k: usize, i: usize) -> usize {
        let k = if self.reversed { self.len - 1 - k } else { k };
        start + k * self.stride + i * self.inner_stride
    }

    fn gather(&self, natural: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; natural.len()];
        out.par_chunks_mut(self.len * self.inner)
            .enumerate()
            .for_each(|(outer, block)| {
                let start = self.block_start(outer);
                for (k, row) in block.chunks_mut(self.inner).enumerate() {
                    for (i, v) in row.iter_mut().enumerate() {
                        *v = natural[self.at(start, k, i)];
                    }
                }
            });
        out
    }

    fn scatter(&self, blocks: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; blocks.len()];
        for (outer, block) in blocks.chunks(self.len * self.inner).enumerate() {
            let start = self.block_start(outer);
            for (k, row) in block.chunks(self.inner).enumerate() {
                for (i, &v) in row.iter().enumerate() {
                    out[self.at(start, k, i)] = v;
                }
            }
        }
        out
    }

    /// Applies `S` along every lateral axis of `data`, laid out as (outer…, `len`, inner).
    fn lateral_transform(&self, data: &mut [f64], tmp: &mut [f64], len: usize) {
        let mut shape = self.outer_dims.clone();
        shape.push(len);
        shape.push(self.inner);
        let last = shape.len() - 1;
        for (k, s) in self.sine.iter().enumerate() {
            let axis = if k < self.outer_dims.len() { k } else { last };
            dst1_along_axis(data, tmp, &shape, axis, s);
            data.copy_from_slice(tmp);
        }
    }
}

/// Givens QR of the line problems `min ‖[tridiag(e, d_m, e); w e_lastᵀ] x_m − [r_m; s_m]‖` of
/// one block, all modes `m` (columns) at once.
struct BlockQr {
    r0: Vec<f64>,
    r1: Vec<f64>,
    r2: Vec<f64>,
    a0: Vec<f64>,
    a1: Vec<f64>,
    ra: Vec<f64>,
}

impl BlockQr {
    fn new(len: usize, inner: usize) -> Self {
        Self {
            r0: vec![0.0; len * inner],
            r1: vec![0.0; len * inner],
            r2: vec![0.0; len * inner],
            a0: vec![0.0; inner],
            a1: vec![0.0; inner],
            ra: vec![0.0; inner],
        }
    }

    /// Overwrites `block` (row `k` = position `k` of every line) with the solutions; returns
    /// the norm of the residual of the block (the rotated right-hand side left over).
    fn solve(&mut self, d: &[f64], e: f64, extra: Option<&[f64]>, block: &mut [f64]) -> f64 {
        let inner = d.len();
        let len = block.len() / inner;
        let w = if extra.is_some() { e } else { 0.0 };
        // Working row k over columns (k, k+1, k+2); its third entry is always 0 on entry.
        self.a0.copy_from_slice(d);
        self.a1.fill(if len > 1 { e } else { 0.0 });
        self.ra.copy_from_slice(&block[..inner]);
        for k in 0..len {
            let row = k * inner..(k + 1) * inner;
            let last = k + 1 == len;
            // The next row: (e, d, e) at columns (k, k+1, k+2), or the Neumann row (w, 0, 0).
            let (b0, b2) = if last {
                (w, 0.0)
            } else {
                (e, if k + 2 < len { e } else { 0.0 })
            };
            let (r0, r1, r2) = (
                &mut self.r0[row.clone()],
                &mut self.r1[row.clone()],
                &mut self.r2[row.clone()],
            );
            let (a0, a1, ra) = (&mut self.a0, &mut self.a1, &mut self.ra);
            if last {
                let s = extra.unwrap_or(&[]);
                let (head, _) = block.split_at_mut((k + 1) * inner);
                let out = &mut head[k * inner..];
                for m in 0..inner {
                    let rho = (a0[m] * a0[m] + b0 * b0).sqrt();
                    let (c, sn) = (a0[m] / rho, b0 / rho);
                    let rb = if b0 != 0.0 { s[m] } else { 0.0 };
                    r0[m] = rho;
                    r1[m] = c * a1[m];
                    r2[m] = 0.0;
                    out[m] = c * ra[m] + sn * rb;
                    ra[m] = -sn * ra[m] + c * rb;
                }
            } else {
                let (head, tail) = block.split_at_mut((k + 1) * inner);
                let out = &mut head[k * inner..];
                let next = &tail[..inner];
                for m in 0..inner {
                    // Entries are O(1) (|d| ≤ 2, e ≤ ½): no overflow to guard against.
                    let rho = (a0[m] * a0[m] + b0 * b0).sqrt();
                    let (c, sn) = (a0[m] / rho, b0 / rho);
                    let b1 = d[m];
                    r0[m] = rho;
                    r1[m] = c * a1[m] + sn * b1;
                    r2[m] = sn * b2;
                    out[m] = c * ra[m] + sn * next[m];
                    let na0 = -sn * a1[m] + c * b1;
                    a1[m] = c * b2;
                    a0[m] = na0;
                    ra[m] = -sn * ra[m] + c * next[m];
                }
            }
        }
        let residual = self.ra.iter().map(|v| v * v).sum::<f64>();
        // Back substitution, row by row from the end.
        for k in (0..len).rev() {
            let (head, tail) = block.split_at_mut((k + 1) * inner);
            let x = &mut head[k * inner..];
            let row = k * inner..(k + 1) * inner;
            let (r0, r1, r2) = (&self.r0[row.clone()], &self.r1[row.clone()], &self.r2[row]);
            if k + 1 < len {
                let x1 = &tail[..inner];
                for m in 0..inner {
                    x[m] -= r1[m] * x1[m];
                }
            }
            if k + 2 < len {
                let x2 = &tail[inner..2 * inner];
                for m in 0..inner {
                    x[m] -= r2[m] * x2[m];
                }
            }
            for m in 0..inner {
                x[m] /= r0[m];
            }
        }
        residual.sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use zeroset_field_core::lsq::{LeastSquaresSolverExt, LsqMatrix};
    use zeroset_solvers::DenseQr;

    fn rhs(m: usize) -> Vec<f64> {
        (0..m)
            .map(|i| ((i * 7919) % 13) as f64 * 0.3 - 1.7)
            .collect()
    }

    fn check<const D: usize>(dims: [usize; D], face: Option<Face>) {
        let a = BoxLaplace::new(dims, face).unwrap();
        let b = rhs(a.nrows());
        let sparse = a.to_sparse();
        let dense = DenseQr::default().solve_with(&sparse, &b).unwrap();
        let fast = a.solve(&b).unwrap();
        let scale = dense.x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (p, q) in fast.x.iter().zip(&dense.x) {
            assert!(
                (p - q).abs() <= 1e-12 * scale,
                "{dims:?} {face:?}: {p} vs {q}"
            );
        }
        let rel = (fast.info.rel_residual - dense.info.rel_residual).abs();
        assert!(
            rel < 1e-10,
            "residuals {} {}",
            fast.info.rel_residual,
            dense.info.rel_residual
        );
        assert!(
            fast.info.rel_normal_residual < 1e-12 || fast.info.rel_residual < 1e-14,
            "{dims:?} {face:?}: {:?}",
            fast.info
        );
    }

    #[test]
    fn separable_solve_matches_dense_qr_for_every_face() {
        for face in Face::all::<3>() {
            check([4, 5, 3], Some(face));
        }
        check([4, 5, 3], None);
        for face in Face::all::<2>() {
            check([6, 4], Some(face));
        }
        check([1, 1, 1], Some(Face::new(2, Side::Upper)));
        check([1, 3, 1], Some(Face::new(0, Side::Lower)));
    }

    #[test]
    fn operator_and_assembled_matrix_agree() {
        let a = BoxLaplace::new([3, 4, 5], Some(Face::new(1, Side::Upper))).unwrap();
        let sparse = a.to_sparse();
        let x: Vec<f64> = (0..a.ncols()).map(|i| (i as f64 * 0.7).sin()).collect();
        let y: Vec<f64> = (0..a.nrows()).map(|i| (i as f64 * 0.3).cos()).collect();
        let (mut p, mut q) = (vec![0.0; a.nrows()], vec![0.0; a.nrows()]);
        a.apply(&x, &mut p);
        LsqMatrix::SparseRow(sparse.as_ref()).apply(&x, &mut q);
        assert!(p.iter().zip(&q).all(|(u, v)| (u - v).abs() < 1e-15));
        let (mut p, mut q) = (vec![0.0; a.ncols()], vec![0.0; a.ncols()]);
        a.apply_transpose(&y, &mut p);
        LsqMatrix::SparseRow(sparse.as_ref()).apply_transpose(&y, &mut q);
        assert!(p.iter().zip(&q).all(|(u, v)| (u - v).abs() < 1e-15));
        let frob: f64 = sparse.val().iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((frob - a.frobenius_norm()).abs() < 1e-12);
    }
}
