//! Weighted CP by alternating least squares: a Kruskal tensor fitted where the entries matter.
//!
//! ## The maths
//!
//! Given non-negative entry weights `W`, minimise `Σ_{ijk} W_{ijk} (X_{ijk} − X̂_{ijk})²` over
//! the factors of `X̂ = Σ_r a_r ∘ b_r ∘ c_r` (Paatero 1997; Tomasi & Bro 2005 compare it with
//! imputation). With two factors fixed the objective separates by the rows of the third: row
//! `i` of `A` solves the `R × R` system
//!
//! `(Σ_{jk} W_{ijk} z_{jk} z_{jk}ᵀ + δI) a_i = Σ_{jk} W_{ijk} X_{ijk} z_{jk}`, `z_{jk} = b_j ∗ c_k`
//!
//! (`∗` the entrywise product), and likewise for the rows of `B` and `C`. Unlike plain CP-ALS
//! the normal matrix differs from row to row, so a sweep costs `O(I₀I₁I₂ R²)` instead of the
//! MTTKRP's `O(I₀I₁I₂ R)` — meant for small tensors. `δ = 10⁻¹² · trace / R` (the smallest
//! positive number where the trace is 0: a row that no weighted entry reaches, which then
//! comes out zero) keeps every system positive definite.
//!
//! MRAS (paper 004 §5.4) uses it to compress a cell's spline coefficients in the norm of the
//! data points' B-spline rows: the plain fit spends rank on coefficients no point reads.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

use crate::{CpStop, Kruskal, Tensor3, TensorError};

/// Settings of [`cp_als_weighted`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeightedOptions {
    /// Most sweeps.
    pub max_iter: usize,
    /// Stop when the weighted relative error `√(Σ W (X − X̂)² / Σ W X²)` changes by less than
    /// this between sweeps.
    pub tol: f64,
}

impl Default for WeightedOptions {
    fn default() -> Self {
        Self {
            max_iter: 100,
            tol: 1e-8,
        }
    }
}

/// What [`cp_als_weighted`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct WeightedResult {
    /// The fitted Kruskal tensor (weights 1, the scale in the factors).
    pub kruskal: Kruskal,
    /// Sweeps done.
    pub iterations: usize,
    /// The weighted relative error after the last sweep (of `start` if none ran).
    pub rel_error: f64,
    /// Why it stopped ([`CpStop::Cancelled`]: `progress` returned `false`).
    pub stop: CpStop,
}

/// The weighted CP fit of `x` (see the module docs) from the starting decomposition `start`,
/// whose rank it keeps; `weights` holds `W` in `x`'s row-major order. After every sweep
/// `progress` sees the sweep count and the current factors (weights 1) and stops the run when
/// it returns `false` — a caller with its own error bound stops as soon as it holds.
///
/// ```
/// use zeroset_tensor::{Tensor3, WeightedOptions, cp_als_weighted, planted};
///
/// // A rank-2 tensor with a corrupted corner: weighted 0 there, the fit ignores it.
/// let (_, clean) = planted([5, 6, 7], 2, 0.0, 3)?;
/// let mut x = clean.clone();
/// x.as_mut_slice()[0] += 100.0;
/// let mut w = vec![1.0; x.len()];
/// w[0] = 0.0;
/// let (start, _) = planted([5, 6, 7], 2, 0.0, 4)?;
/// let fit = cp_als_weighted(&x, &w, &start, &WeightedOptions::default(), |_, _| true)?;
/// let err = fit.kruskal.to_tensor().as_slice().iter().zip(clean.as_slice())
///     .map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
/// assert!(err < 1e-6, "{err}");
/// # Ok::<(), zeroset_tensor::TensorError>(())
/// ```
///
/// # Errors
/// [`TensorError::EmptyShape`] for an empty tensor, [`TensorError::Length`] if `weights` does
/// not match `x`, [`TensorError::NonFinite`] for a
/// NaN or infinite entry of `x`, [`TensorError::Weight`] for a negative, NaN or infinite
/// weight, [`TensorError::Dimensions`] if `start` is not of `x`'s shape, [`TensorError::Rank`]
/// for a start of rank 0, [`TensorError::Tolerance`] for a negative or NaN `tol`.
pub fn cp_als_weighted(
    x: &Tensor3,
    weights: &[f64],
    start: &Kruskal,
    options: &WeightedOptions,
    mut progress: impl FnMut(usize, &Kruskal) -> bool,
) -> Result<WeightedResult, TensorError> {
    let shape = x.shape();
    if x.is_empty() {
        return Err(TensorError::EmptyShape { shape });
    }
    x.check_finite()?;
    if weights.len() != x.len() {
        return Err(TensorError::Length {
            shape,
            len: weights.len(),
        });
    }
    if let Some(index) = weights.iter().position(|w| !w.is_finite() || *w < 0.0) {
        let value = weights[index];
        return Err(TensorError::Weight { index, value });
    }
    if start.rank() == 0 {
        let max = crate::cp::max_rank(shape);
        return Err(TensorError::Rank { rank: 0, max });
    }
    if let Some(mode) = (0..3).find(|&n| start.shape()[n] != shape[n]) {
        return Err(TensorError::Dimensions {
            what: "cp_als_weighted: the start's (extent, mode) in the first mode that differs",
            expected: (shape[mode], mode),
            got: (start.shape()[mode], mode),
        });
    }
    if options.tol.is_nan() || options.tol < 0.0 {
        return Err(TensorError::Tolerance { tol: options.tol });
    }
    let rank = start.rank();
    // Row-major copies of the factors (entry `(i, r)` at `i·R + r`), the first scaled by the
    // weights.
    let mut factors: [Vec<f64>; 3] = std::array::from_fn(|n| {
        let f = &start.factors()[n];
        let scale = |r: usize| if n == 0 { start.weights()[r] } else { 1.0 };
        (0..shape[n])
            .flat_map(|i| (0..rank).map(move |r| (i, r)))
            .map(|(i, r)| f[(i, r)] * scale(r))
            .collect()
    });
    let (xs, ws) = (x.as_slice(), weights);
    let norm2: f64 = xs.iter().zip(ws).map(|(v, w)| w * v * v).sum();
    let strides = [shape[1] * shape[2], shape[2], 1];
    let mut rel = weighted_error(xs, ws, &factors, shape, rank, norm2);
    let mut iterations = 0;
    let mut g = vec![0.0; rank * rank];
    let mut h = vec![0.0; rank];
    let mut z = vec![0.0; rank];
    let mut stop = CpStop::MaxIterations;
    while iterations < options.max_iter {
        for mode in 0..3 {
            let (pm, qm) = match mode {
                0 => (1, 2),
                1 => (0, 2),
                _ => (0, 1),
            };
            for i in 0..shape[mode] {
                g.fill(0.0);
                h.fill(0.0);
                for p in 0..shape[pm] {
                    let fp = &factors[pm][p * rank..(p + 1) * rank];
                    for q in 0..shape[qm] {
                        let flat = i * strides[mode] + p * strides[pm] + q * strides[qm];
                        let w = ws[flat];
                        if w == 0.0 {
                            continue;
                        }
                        let fq = &factors[qm][q * rank..(q + 1) * rank];
                        for ((zr, a), b) in z.iter_mut().zip(fp).zip(fq) {
                            *zr = a * b;
                        }
                        let wx = w * xs[flat];
                        for r in 0..rank {
                            let wz = w * z[r];
                            h[r] += wx * z[r];
                            let row = &mut g[r * rank..r * rank + r + 1];
                            for (gs, zs) in row.iter_mut().zip(&z) {
                                *gs += wz * zs;
                            }
                        }
                    }
                }
                let row = solve_row(&g, &h)?;
                factors[mode][i * rank..(i + 1) * rank].copy_from_slice(&row);
            }
        }
        let previous = rel;
        rel = weighted_error(xs, ws, &factors, shape, rank, norm2);
        iterations += 1;
        if !progress(iterations, &kruskal(&factors, shape, rank)?) {
            stop = CpStop::Cancelled;
            break;
        }
        if (previous - rel).abs() < options.tol {
            stop = CpStop::Converged;
            break;
        }
    }
    Ok(WeightedResult {
        kruskal: kruskal(&factors, shape, rank)?,
        iterations,
        rel_error: rel,
        stop,
    })
}

/// The Kruskal tensor (weights 1) of row-major factors.
fn kruskal(
    factors: &[Vec<f64>; 3],
    shape: [usize; 3],
    rank: usize,
) -> Result<Kruskal, TensorError> {
    Kruskal::new(
        vec![1.0; rank],
        std::array::from_fn(|n| Mat::from_fn(shape[n], rank, |i, r| factors[n][i * rank + r])),
    )
}

/// Solves one row's system from the lower triangle of `g` (row-major `R × R`), ridged by
/// `10⁻¹² · trace / R` (the smallest positive number where the trace is 0).
fn solve_row(g: &[f64], h: &[f64]) -> Result<Vec<f64>, TensorError> {
    let rank = h.len();
    let trace: f64 = (0..rank).map(|r| g[r * rank + r]).sum();
    let ridge = (1e-12 * trace / rank as f64).max(f64::MIN_POSITIVE);
    let a = Mat::from_fn(rank, rank, |r, s| {
        let v = g[r.max(s) * rank + r.min(s)];
        if r == s { v + ridge } else { v }
    });
    let b = Mat::from_fn(rank, 1, |r, _| h[r]);
    // Positive definite by the ridge unless rounding says otherwise: then the pseudo-inverse.
    let solved = a
        .llt(Side::Lower)
        .ok()
        .map(|llt| llt.solve(&b))
        .filter(|x| x.col(0).iter().all(|v| v.is_finite()));
    let solved = match solved {
        Some(x) => x,
        None => crate::cp::solve_gram(&a, &b.transpose().to_owned())?
            .transpose()
            .to_owned(),
    };
    Ok((0..rank).map(|r| solved[(r, 0)]).collect())
}

/// `√(Σ W (X − X̂)² / Σ W X²)` (the absolute error where `Σ W X² = 0`), row-major factors.
fn weighted_error(
    xs: &[f64],
    ws: &[f64],
    factors: &[Vec<f64>; 3],
    shape: [usize; 3],
    rank: usize,
    norm2: f64,
) -> f64 {
    let mut e2 = 0.0;
    let mut ab = vec![0.0; rank];
    for i in 0..shape[0] {
        let a = &factors[0][i * rank..(i + 1) * rank];
        for j in 0..shape[1] {
            let b = &factors[1][j * rank..(j + 1) * rank];
            for ((v, x), y) in ab.iter_mut().zip(a).zip(b) {
                *v = x * y;
            }
            for k in 0..shape[2] {
                let flat = (i * shape[1] + j) * shape[2] + k;
                let w = ws[flat];
                if w == 0.0 {
                    continue;
                }
                let c = &factors[2][k * rank..(k + 1) * rank];
                let fit: f64 = ab.iter().zip(c).map(|(v, z)| v * z).sum();
                e2 += w * (xs[flat] - fit) * (xs[flat] - fit);
            }
        }
    }
    if norm2 > 0.0 {
        (e2 / norm2).sqrt()
    } else {
        e2.sqrt()
    }
}
