//! The interpolation prefilter: samples → B-spline coefficients, one tridiagonal solve per line.
//!
//! Along an axis of `n ≥ 2` samples the samples are `s = M c` with `M` the tridiagonal Toeplitz
//! matrix of the sampled kernel `(a, b, a)` — `(⅛, ¾, ⅛)` quadratic, `(⅙, ⅔, ⅙)` cubic — whose
//! first and last rows absorb the mirrored coefficients:
//!
//! ```text
//! half-sample (c₋₁ = c₀):   row 0 = (a + b, a),   row n−1 = (a, a + b)
//! whole-sample (c₋₁ = c₁):  row 0 = (b, 2a),      row n−1 = (2a, b)
//! ```
//!
//! `M` is strictly diagonally dominant, so its LU (Thomas) factors need no pivoting. They are
//! computed once per axis length and applied to every line: forward `yᵢ = (sᵢ − lᵢ yᵢ₋₁)/mᵢ`,
//! back `cᵢ = yᵢ − uᵢ cᵢ₊₁`. The factors depend only on `n`, so every line goes through exactly
//! the same floating-point operations whichever way the lines are batched or scheduled: the
//! result is bit-identical for any number of threads.
//!
//! Memory order (C order, last axis fastest) decides how lines are batched:
//! - the **last axis** (contiguous lines): [`LANES`] lines are transposed into a small buffer and
//!   solved side by side, so the recurrence runs over `LANES` independent lanes (SIMD, no
//!   latency stall);
//! - **other axes** (stride `s > 1`): the solve runs over whole rows of `s` contiguous values at
//!   once (`rowᵢ ← (rowᵢ − lᵢ rowᵢ₋₁)/mᵢ`), in column blocks of about [`COLUMN_BLOCK_VALUES`]
//!   values in all, so that a block's `n` row pieces stay in cache between the forward and the
//!   back sweep.
//!
//! Axes `1 … D−1` are filtered slab by slab (one slab = fixed index on axis 0; the last axis
//! first, which streams the slab into cache for the others), in parallel over slabs; then axis 0
//! in parallel over column blocks. Two passes over memory in all.

use rayon::prelude::*;
use zeroset_field_core::Error;

use super::stencil::strides;
use super::{Boundary, Degree};

/// Lines of the last axis solved side by side.
const LANES: usize = 8;
/// Values per column block of a strided axis (256 KiB, half a typical L2 cache): a block of
/// `n` rows is `COLUMN_BLOCK_VALUES / n` values wide (128 for `n` = 256), within 16 … 1024.
const COLUMN_BLOCK_VALUES: usize = 1 << 15;
/// Smallest number of values per parallel task of the slab stage.
const MIN_TASK: usize = 1 << 14;

/// The width of the column blocks along an axis of `n` rows.
fn column_block(n: usize) -> usize {
    (COLUMN_BLOCK_VALUES / n).clamp(16, 1024)
}

/// The Thomas factors of the `n × n` prefilter matrix (`n ≥ 2`).
#[derive(Debug, Clone)]
struct Factors {
    /// Sub-diagonal `lᵢ` (`l₀` unused).
    lower: Vec<f64>,
    /// `1/mᵢ`, the reciprocal pivots.
    inv_pivot: Vec<f64>,
    /// `uᵢ/mᵢ`, the scaled super-diagonal (`u_{n−1}` unused).
    upper: Vec<f64>,
}

/// The sampled kernel `(a, b)` of `degree`: `(⅛, ¾)` quadratic, `(⅙, ⅔)` cubic.
fn taps(degree: Degree) -> (f64, f64) {
    match degree {
        Degree::Quadratic => (1.0 / 8.0, 6.0 / 8.0),
        Degree::Cubic => (1.0 / 6.0, 4.0 / 6.0),
    }
}

impl Factors {
    fn with_taps(n: usize, (a, b): (f64, f64), boundary: Boundary) -> Self {
        debug_assert!(n >= 2);
        let (end_diag, end_off) = match boundary {
            Boundary::HalfSample => (a + b, a),
            Boundary::WholeSample => (b, 2.0 * a),
        };
        let mut lower = vec![a; n];
        let mut diag = vec![b; n];
        let mut upper = vec![a; n];
        diag[0] = end_diag;
        diag[n - 1] = end_diag;
        upper[0] = end_off;
        lower[n - 1] = end_off;
        lower[0] = 0.0;
        upper[n - 1] = 0.0;
        let mut inv_pivot = vec![0.0; n];
        let mut scaled_upper = vec![0.0; n];
        for i in 0..n {
            let m = if i == 0 {
                diag[0]
            } else {
                diag[i] - lower[i] * scaled_upper[i - 1]
            };
            inv_pivot[i] = 1.0 / m;
            scaled_upper[i] = upper[i] / m;
        }
        Self {
            lower,
            inv_pivot,
            upper: scaled_upper,
        }
    }

    fn len(&self) -> usize {
        self.lower.len()
    }

    /// Solves one contiguous line in place (the scalar form of the lane and row solves below,
    /// with the same operations in the same order).
    fn solve_line(&self, line: &mut [f64]) {
        let n = self.len();
        debug_assert_eq!(line.len(), n);
        line[0] *= self.inv_pivot[0];
        for i in 1..n {
            line[i] = (line[i] - self.lower[i] * line[i - 1]) * self.inv_pivot[i];
        }
        for i in (0..n - 1).rev() {
            line[i] -= self.upper[i] * line[i + 1];
        }
    }

    /// Solves every contiguous line of `block` (a whole number of lines of length `n`).
    fn solve_lines(&self, block: &mut [f64]) {
        let n = self.len();
        let mut groups = block.chunks_exact_mut(n * LANES);
        let mut buf = vec![[0.0; LANES]; n];
        for group in &mut groups {
            for (lane, line) in group.chunks_exact(n).enumerate() {
                for (b, &v) in buf.iter_mut().zip(line) {
                    b[lane] = v;
                }
            }
            let inv0 = self.inv_pivot[0];
            buf[0].iter_mut().for_each(|v| *v *= inv0);
            for i in 1..n {
                let (l, m) = (self.lower[i], self.inv_pivot[i]);
                let prev = buf[i - 1];
                for (v, p) in buf[i].iter_mut().zip(prev) {
                    *v = (*v - l * p) * m;
                }
            }
            for i in (0..n - 1).rev() {
                let u = self.upper[i];
                let next = buf[i + 1];
                for (v, x) in buf[i].iter_mut().zip(next) {
                    *v -= u * x;
                }
            }
            for (lane, line) in group.chunks_exact_mut(n).enumerate() {
                for (v, b) in line.iter_mut().zip(&buf) {
                    *v = b[lane];
                }
            }
        }
        for line in groups.into_remainder().chunks_exact_mut(n) {
            self.solve_line(line);
        }
    }

    /// Solves along the row index for every column of `rows` (`n` equal-width row pieces).
    fn solve_rows(&self, rows: &mut [&mut [f64]]) {
        let n = self.len();
        debug_assert_eq!(rows.len(), n);
        let inv0 = self.inv_pivot[0];
        rows[0].iter_mut().for_each(|v| *v *= inv0);
        for i in 1..n {
            let (l, m) = (self.lower[i], self.inv_pivot[i]);
            let (done, rest) = rows.split_at_mut(i);
            for (v, p) in rest[0].iter_mut().zip(done[i - 1].iter()) {
                *v = (*v - l * p) * m;
            }
        }
        for i in (0..n - 1).rev() {
            let u = self.upper[i];
            let (head, tail) = rows.split_at_mut(i + 1);
            for (v, x) in head[i].iter_mut().zip(tail[0].iter()) {
                *v -= u * x;
            }
        }
    }

    /// Solves along the rows of a contiguous block of `n` rows of `row_len` values, column
    /// block by column block.
    fn solve_block(&self, block: &mut [f64], row_len: usize) {
        let width = column_block(self.len());
        let mut pieces: Vec<_> = block
            .chunks_exact_mut(row_len)
            .map(|row| row.chunks_mut(width))
            .collect();
        let mut rows = Vec::with_capacity(pieces.len());
        loop {
            rows.clear();
            rows.extend(pieces.iter_mut().filter_map(|it| it.next()));
            if rows.is_empty() {
                break;
            }
            self.solve_rows(&mut rows);
        }
    }
}

/// Turns samples into B-spline coefficients in place, so that the spline with these
/// coefficients (and the same `degree` and `boundary`) interpolates the samples.
///
/// `data` holds `shape[0] × … × shape[D−1]` values in C order (last axis fastest: the linear
/// index of `[i, j, k]` is `(i·shape[1] + j)·shape[2] + k`, as in
/// [`Grid`](zeroset_field_core::grid::Grid)). Each axis of length `n ≥ 2` is one tridiagonal
/// solve per line (see the [module docs](super#interpolation-the-prefilter)); an axis of length 1 is
/// the identity. The LU factors of each axis's matrix are computed once and applied to whole
/// contiguous rows at a time (lines of the last axis in groups of 8), so the inner loops run over
/// contiguous memory.
/// Parallel (rayon) and bit-identical for any number of threads. Non-finite values are not
/// checked here (they spread along their lines); [`BSplineField`](super::BSplineField)'s
/// constructors reject them.
///
/// With [`Boundary::WholeSample`] this is scipy's `ndimage.spline_filter(data, order, mode='mirror')`,
/// with [`Boundary::HalfSample`] `mode='reflect'` (`'grid-mirror'`), `order` 2 or 3.
///
/// # Errors
/// [`Error::ShapeMismatch`] if `data.len()` is not the product of `shape`.
///
/// ```
/// use zeroset_bases::bspline::{Boundary, Degree, prefilter};
///
/// // A constant is its own coefficient vector (the kernel sums to 1).
/// let mut data = vec![2.5; 4 * 5];
/// prefilter(&mut data, [4, 5], Degree::Quadratic, Boundary::HalfSample)?;
/// assert!(data.iter().all(|c| (c - 2.5).abs() < 1e-14));
/// # Ok::<(), zeroset_field_core::Error>(())
/// ```
pub fn prefilter<const D: usize>(
    data: &mut [f64],
    shape: [usize; D],
    degree: Degree,
    boundary: Boundary,
) -> Result<(), Error> {
    prefilter_taps(data, shape, [taps(degree); D], boundary)
}

/// [`prefilter`] for a quadratic spline from its means rather than its values: along axis `a`
/// each datum is the spline's mean over `points[a]` equally spaced points across its cell (as
/// when a coarse cell takes the mean of the fine samples it covers), which is
/// `α·c_{i−1} + (1 − 2α)·c_i + α·c_{i+1}` with `α = 1/6 − 1/(24k²)`, `k = points[a]`: the
/// values (`k = 1`, `α = ⅛`: [`prefilter`]'s quadratic kernel) through the cell means
/// (`k → ∞`, `α = ⅙`). Interpolating means as values biases the spline by `h²/24 · Δf`;
/// taking a few samples' mean for a cell mean (the cubic kernel at `k = 1`) amplifies the
/// finest oscillation threefold per axis. A `k` below 1 (or NaN) is taken as 1. For a `k`
/// that is not whole (an overlap-weighted mean of fine cells that straddle coarse ones) the
/// true kernel varies from cell to cell; `α(k)` interpolates between the whole cases.
///
/// # Errors
/// As [`prefilter`].
pub fn prefilter_means<const D: usize>(
    data: &mut [f64],
    shape: [usize; D],
    points: [f64; D],
    boundary: Boundary,
) -> Result<(), Error> {
    let taps = points.map(|k| {
        let k = if k >= 1.0 { k } else { 1.0 };
        let a = 1.0 / 6.0 - 1.0 / (24.0 * k * k);
        (a, 1.0 - 2.0 * a)
    });
    prefilter_taps(data, shape, taps, boundary)
}

/// [`prefilter`] with the kernel `(a, b)` of each axis (diagonally dominant: `b > 2a > 0`).
fn prefilter_taps<const D: usize>(
    data: &mut [f64],
    shape: [usize; D],
    taps: [(f64, f64); D],
    boundary: Boundary,
) -> Result<(), Error> {
    let expected = shape
        .iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .unwrap_or(usize::MAX);
    if data.len() != expected {
        return Err(Error::ShapeMismatch {
            what: "prefilter data (product of shape)",
            expected,
            got: data.len(),
        });
    }
    if D == 0 || data.is_empty() {
        return Ok(());
    }
    let factors: [Option<Factors>; D] = std::array::from_fn(|a| {
        (shape[a] >= 2).then(|| Factors::with_taps(shape[a], taps[a], boundary))
    });
    let stride = strides(shape);

    // Axes 1 … D−1, slab by slab (a slab = fixed index on axis 0, `stride[0]` values).
    let slab = stride[0];
    if D >= 2 && factors[1..].iter().any(Option::is_some) {
        let per_task = slab * MIN_TASK.div_ceil(slab);
        data.par_chunks_mut(per_task).for_each(|task| {
            // The last axis first: it streams through memory, and leaves the slab in cache.
            if let Some(f) = &factors[D - 1] {
                f.solve_lines(task);
            }
            for slab in task.chunks_exact_mut(stride[0]) {
                for a in 1..D - 1 {
                    if let Some(f) = &factors[a] {
                        for block in slab.chunks_exact_mut(shape[a] * stride[a]) {
                            f.solve_block(block, stride[a]);
                        }
                    }
                }
            }
        });
    }

    // Axis 0.
    if let Some(f) = &factors[0] {
        if D == 1 {
            f.solve_line(data);
        } else {
            let width = column_block(f.len());
            let mut pieces: Vec<_> = data
                .chunks_exact_mut(slab)
                .map(|row| row.chunks_mut(width))
                .collect();
            let mut columns: Vec<Vec<&mut [f64]>> = Vec::with_capacity(slab.div_ceil(width));
            loop {
                let rows: Vec<&mut [f64]> = pieces.iter_mut().filter_map(|it| it.next()).collect();
                if rows.is_empty() {
                    break;
                }
                columns.push(rows);
            }
            columns
                .into_par_iter()
                .for_each(|mut rows| f.solve_rows(&mut rows));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense `M` for a line of `n`, applied to `c`.
    fn apply(c: &[f64], degree: Degree, boundary: Boundary) -> Vec<f64> {
        let n = c.len();
        let (a, b) = match degree {
            Degree::Quadratic => (0.125, 0.75),
            Degree::Cubic => (1.0 / 6.0, 4.0 / 6.0),
        };
        let at = |k: isize| c[super::super::stencil::fold(k, n, boundary)];
        (0..n as isize)
            .map(|i| a * at(i - 1) + b * at(i) + a * at(i + 1))
            .collect()
    }

    #[test]
    fn lines_lanes_and_rows_solve_the_same_systems_bit_for_bit() {
        for degree in [Degree::Quadratic, Degree::Cubic] {
            for boundary in [Boundary::HalfSample, Boundary::WholeSample] {
                for n in [2, 3, 5, 17] {
                    let f = Factors::with_taps(n, taps(degree), boundary);
                    let lines = 11; // one lane group and a remainder of 3
                    let data: Vec<f64> = (0..n * lines).map(|i| (i as f64 * 0.37).sin()).collect();
                    let mut by_line = data.clone();
                    by_line.chunks_exact_mut(n).for_each(|l| f.solve_line(l));
                    let mut by_lanes = data.clone();
                    f.solve_lines(&mut by_lanes);
                    assert_eq!(by_line, by_lanes);
                    // The transpose, solved along rows.
                    let mut t: Vec<f64> = (0..n * lines)
                        .map(|k| data[(k % lines) * n + k / lines])
                        .collect();
                    f.solve_block(&mut t, lines);
                    for (k, v) in t.iter().enumerate() {
                        assert_eq!(*v, by_line[(k % lines) * n + k / lines]);
                    }
                    for line in data.chunks_exact(n).zip(by_line.chunks_exact(n)) {
                        let back = apply(line.1, degree, boundary);
                        for (x, y) in back.iter().zip(line.0) {
                            assert!((x - y).abs() < 1e-14, "{degree:?} {boundary:?} n={n}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn shape_mismatch_is_reported() {
        let mut d = vec![0.0; 10];
        let e = prefilter(&mut d, [3, 3], Degree::Quadratic, Boundary::HalfSample).unwrap_err();
        assert!(matches!(
            e,
            Error::ShapeMismatch {
                expected: 9,
                got: 10,
                ..
            }
        ));
    }
}
