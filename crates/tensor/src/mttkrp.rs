//! The matricised-tensor times Khatri–Rao products (MTTKRPs) of CP-ALS, by two passes over the
//! row-major data per sweep.
//!
//! For `X ∈ ℝ^{I₀×I₁×I₂}` (row-major, `i₂` fastest) and factors `A, B, C` of rank `R`:
//!
//! - `T = X ×₂ Cᵀ`, `T[i₀I₁ + i₁, r] = Σ_k X[i₀, i₁, k] C[k, r]`: the data as an
//!   `(I₀I₁) × I₂` matrix times `C`. It serves the MTTKRPs of modes 0 and 1 (`C` does not change
//!   while `A` and `B` are updated): `M₀[i₀, r] = Σ_{i₁} T[i₀I₁ + i₁, r] B[i₁, r]` and
//!   `M₁[i₁, r] = Σ_{i₀} T[i₀I₁ + i₁, r] A[i₀, r]`;
//! - `U = X₍₀₎ᵀ A`, `U[i₁I₂ + k, r] = Σ_{i₀} X[i₀, i₁, k] A[i₀, r]`: the transposed data as an
//!   `(I₁I₂) × I₀` matrix times `A`; then `M₂[k, r] = Σ_{i₁} U[i₁I₂ + k, r] B[i₁, r]`.
//!
//! Each product is `2 I₀I₁I₂R` flops and streams `X` once; there is no unfolding and no
//! Khatri–Rao product in the loop. The products (faer's dense kernels) are cut into a fixed
//! number of row blocks that depends on the work alone and run in parallel; every output
//! entry is computed by one block in one fixed order, so the results are the same bits on 1 and
//! N threads.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

/// Multiply-adds per row block of a product, at least: a product with less than twice this
/// runs as one block (30³ × 10: 0.27M), larger ones in a power of two of blocks (60³ × 20,
/// 4.3M: 4 blocks), so that they share out evenly over 2 or 4 threads.
const BLOCK_WORK: usize = 1 << 20;

/// The most row blocks of one product.
const MAX_BLOCKS: usize = 16;

/// The work space of the MTTKRPs of one tensor shape and rank, reused every sweep.
#[derive(Debug, Clone)]
pub(crate) struct Mttkrp {
    shape: [usize; 3],
    /// `T`, `(I₀I₁) × R`.
    t: Mat<f64>,
    /// `U`, `(I₁I₂) × R`.
    u: Mat<f64>,
}

impl Mttkrp {
    pub fn new(shape: [usize; 3], rank: usize) -> Self {
        Self {
            shape,
            t: Mat::zeros(shape[0] * shape[1], rank),
            u: Mat::zeros(shape[1] * shape[2], rank),
        }
    }

    /// `T = X ×₂ Cᵀ` (see the module docs).
    pub fn times_last(&mut self, x: &[f64], c: &Mat<f64>) {
        let [i, j, k] = self.shape;
        let xm = MatRef::from_row_major_slice(x, i * j, k);
        blocked_product(self.t.as_mut(), xm, c.as_ref());
    }

    /// `M₀` (`mode = 0`, `f = B`) or `M₁` (`mode = 1`, `f = A`) from `T`.
    pub fn contract_t(&self, mode: usize, f: &Mat<f64>) -> Mat<f64> {
        let j = self.shape[1];
        let rank = self.t.ncols();
        let mut m = Mat::<f64>::zeros(self.shape[mode], rank);
        for r in 0..rank {
            let (tc, fc, out) = (
                self.t.col_as_slice(r),
                f.col_as_slice(r),
                m.col_as_slice_mut(r),
            );
            for (a, row) in tc.chunks_exact(j).enumerate() {
                if mode == 0 {
                    out[a] = dot4(row, fc);
                } else {
                    let w = fc[a];
                    for (o, v) in out.iter_mut().zip(row) {
                        *o += w * v;
                    }
                }
            }
        }
        m
    }

    /// `M₂ = X₍₂₎ (B ⊙ A)` by `U = X₍₀₎ᵀ A` (see the module docs).
    pub fn last(&mut self, x: &[f64], a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
        let [i, j, k] = self.shape;
        let xm = MatRef::from_row_major_slice(x, i, j * k);
        blocked_product(self.u.as_mut(), xm.transpose(), a.as_ref());
        let rank = a.ncols();
        let mut m = Mat::<f64>::zeros(k, rank);
        for r in 0..rank {
            let (uc, bc, out) = (
                self.u.col_as_slice(r),
                b.col_as_slice(r),
                m.col_as_slice_mut(r),
            );
            for (row, &w) in uc.chunks_exact(k).zip(bc) {
                for (o, v) in out.iter_mut().zip(row) {
                    *o += w * v;
                }
            }
        }
        m
    }
}

/// `out = lhs · rhs`, in row blocks of `out` and `lhs` (fixed by the work, see [`BLOCK_WORK`]),
/// each a sequential product, run in parallel.
fn blocked_product(out: MatMut<'_, f64>, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>) {
    let rows = out.nrows();
    let work = rows * lhs.ncols() * rhs.ncols();
    let blocks = work
        .div_ceil(BLOCK_WORK)
        .clamp(1, MAX_BLOCKS)
        .min(rows.max(1));
    if blocks == 1 {
        matmul(out, Accum::Replace, lhs, rhs, 1.0, Par::Seq);
        return;
    }
    // Block heights: a multiple of 12 (the kernel's row tile) where the rows allow it.
    let height = rows.div_ceil(blocks).div_ceil(12) * 12;
    let mut parts = Vec::with_capacity(blocks);
    let mut rest = out;
    let mut first = 0;
    while rest.nrows() > height {
        let (head, tail) = rest.split_at_row_mut(height);
        parts.push((first, head));
        first += height;
        rest = tail;
    }
    parts.push((first, rest));
    parts.into_par_iter().for_each(|(first, part)| {
        let n = part.nrows();
        matmul(
            part,
            Accum::Replace,
            lhs.subrows(first, n),
            rhs,
            1.0,
            Par::Seq,
        );
    });
}

/// `Σ xᵢ yᵢ` with four running partial sums (vectorised; a fixed order).
fn dot4(x: &[f64], y: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (xc, xt) = x.as_chunks::<4>();
    let (yc, yt) = y.as_chunks::<4>();
    for (a, b) in xc.iter().zip(yc) {
        for l in 0..4 {
            acc[l] += a[l] * b[l];
        }
    }
    let tail: f64 = xt.iter().zip(yt).map(|(a, b)| a * b).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(x: &[f64], shape: [usize; 3], f: &[Mat<f64>; 3], mode: usize) -> Mat<f64> {
        let [i0, i1, i2] = shape;
        let rank = f[0].ncols();
        let mut m = Mat::<f64>::zeros(shape[mode], rank);
        for a in 0..i0 {
            for b in 0..i1 {
                for c in 0..i2 {
                    let v = x[(a * i1 + b) * i2 + c];
                    for r in 0..rank {
                        let (row, w) = match mode {
                            0 => (a, f[1][(b, r)] * f[2][(c, r)]),
                            1 => (b, f[0][(a, r)] * f[2][(c, r)]),
                            _ => (c, f[0][(a, r)] * f[1][(b, r)]),
                        };
                        m[(row, r)] += v * w;
                    }
                }
            }
        }
        m
    }

    /// The three MTTKRPs equal the sums written out, for shapes small enough for one block and
    /// large enough for several.
    #[test]
    fn mttkrps_match_the_definition() {
        for (shape, rank) in [
            ([5, 7, 13], 3),
            ([9, 4, 25], 8),
            ([3, 3, 3], 1),
            ([40, 45, 50], 30),
        ] {
            let n = shape.iter().product::<usize>();
            let x: Vec<f64> = (0..n)
                .map(|v| ((v * 7919) % 1001) as f64 / 1001.0 - 0.5)
                .collect();
            let f: [Mat<f64>; 3] = std::array::from_fn(|m| {
                Mat::from_fn(shape[m], rank, |i, r| {
                    ((i * 31 + r * 17 + m) % 13) as f64 / 13.0 - 0.4
                })
            });
            let mut w = Mttkrp::new(shape, rank);
            w.times_last(&x, &f[2]);
            let got = [
                w.contract_t(0, &f[1]),
                w.contract_t(1, &f[0]),
                w.last(&x, &f[0], &f[1]),
            ];
            for (mode, got) in got.iter().enumerate() {
                let want = naive(&x, shape, &f, mode);
                for i in 0..shape[mode] {
                    for r in 0..rank {
                        let (a, b) = (got[(i, r)], want[(i, r)]);
                        assert!(
                            (a - b).abs() <= 1e-11 * (1.0 + b.abs()),
                            "{shape:?} r{rank} mode {mode}: {a} vs {b}"
                        );
                    }
                }
            }
        }
    }
}
