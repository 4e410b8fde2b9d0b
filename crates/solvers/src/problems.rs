//! Test and benchmark problems with known structure.
//!
//! [`protrusion_problem`] is the least-squares system of protrusion removal
//! (Ren–Fujita–Nakata §2.2) in the set-up `PEERS.md` times scipy on, so that zeroset's solvers
//! and scipy's can be compared on the same matrices:
//!
//! - a cell-centred grid of `2k` cells per axis on `[−1, 1]³` (spacing `d = 1/k`);
//! - `f` = the signed distance to the sphere of radius 0.6 about the origin (negative inside);
//! - the mask = the central `k³` block of cells; the unknowns `h` = all `k³` mask cells, ordered
//!   last axis fastest;
//! - one row per mask cell: the 7-point Laplacian `(Σ₆ neighbours − 6h)/6 = 0`, neighbours
//!   outside the mask moved to the right-hand side with their value of `f` (Dirichlet);
//! - one row per cell of the mask's top layer (`z` = last axis, upper face):
//!   `h = f(cell above) + α·d` (the Neumann condition `∂h/∂n = α` in zeroset's negative-inside
//!   convention; the paper, positive inside, writes `− α·d`).
//!
//! That is `k³ + k²` rows, `k³` columns and full column rank (the Laplacian rows alone are the
//! square Dirichlet problem), so every solver must return the same `h`.

use faer::sparse::{SparseRowMat, SymbolicSparseRowMat};

use zeroset_field_core::analytic::Sphere;
use zeroset_field_core::field::ScalarField;

/// A least-squares problem `min ‖A x − b‖` with its provenance.
#[derive(Debug, Clone)]
pub struct Problem {
    /// What it is, for reports.
    pub name: String,
    /// The matrix, `m × n`.
    pub a: SparseRowMat<usize, f64>,
    /// The right-hand side, length `m`.
    pub b: Vec<f64>,
}

/// The protrusion-removal system described in the module docs, for a `k³` mask and slope `α`.
///
/// # Panics
/// If `k == 0`.
pub fn protrusion_problem(k: usize, alpha: f64) -> Problem {
    assert!(k > 0, "protrusion_problem needs k >= 1");
    let cells = 2 * k;
    let d = 2.0 / cells as f64;
    let lo = k / 2;
    let centre = |i: usize| -1.0 + (i as f64 + 0.5) * d;
    let sphere = Sphere::new([0.0; 3], 0.6);
    let f = |i: usize, j: usize, l: usize| sphere.value(&[centre(i), centre(j), centre(l)]);
    let unknown = |i: usize, j: usize, l: usize| ((i - lo) * k + (j - lo)) * k + (l - lo);
    let inside = |c: usize| (lo..lo + k).contains(&c);

    let n = k * k * k;
    let mut row_ptr = Vec::with_capacity(n + k * k + 1);
    let mut col_idx = Vec::with_capacity(7 * n + k * k);
    let mut val = Vec::with_capacity(7 * n + k * k);
    let mut b = Vec::with_capacity(n + k * k);
    row_ptr.push(0);
    for i in lo..lo + k {
        for j in lo..lo + k {
            for l in lo..lo + k {
                let mut entries: Vec<(usize, f64)> = vec![(unknown(i, j, l), -1.0)];
                let mut rhs = 0.0;
                let neighbours = [
                    (i - 1, j, l),
                    (i + 1, j, l),
                    (i, j - 1, l),
                    (i, j + 1, l),
                    (i, j, l - 1),
                    (i, j, l + 1),
                ];
                for (p, q, r) in neighbours {
                    if inside(p) && inside(q) && inside(r) {
                        entries.push((unknown(p, q, r), 1.0 / 6.0));
                    } else {
                        rhs -= f(p, q, r) / 6.0;
                    }
                }
                entries.sort_by_key(|e| e.0);
                for (c, v) in entries {
                    col_idx.push(c);
                    val.push(v);
                }
                row_ptr.push(col_idx.len());
                b.push(rhs);
            }
        }
    }
    let top = lo + k - 1;
    for i in lo..lo + k {
        for j in lo..lo + k {
            col_idx.push(unknown(i, j, top));
            val.push(1.0);
            row_ptr.push(col_idx.len());
            b.push(f(i, j, top + 1) + alpha * d);
        }
    }
    let m = b.len();
    let symbolic = SymbolicSparseRowMat::new_checked(m, n, row_ptr, None, col_idx);
    Problem {
        name: format!("protrusion k={k} ({m}×{n})"),
        a: SparseRowMat::new(symbolic, val),
        b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn protrusion_problem_has_the_documented_shape() {
        let p = protrusion_problem(4, 1.0);
        assert_eq!((p.a.nrows(), p.a.ncols()), (64 + 16, 64));
        // Interior cells see 7 entries; corners 4; top rows 1.
        let nnz = p.a.symbolic().row_ptr()[p.a.nrows()];
        // 7·64 minus the outside neighbours (6 faces × 16 cells), plus 16 top rows.
        assert_eq!(nnz, 7 * 64 - 6 * 16 + 16);
        assert!(p.b.iter().all(|v| v.is_finite()));
    }
}
