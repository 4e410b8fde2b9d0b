//! The discrete sine transform DST-I, orthonormal, in place along one axis of an n-d array.
//!
//! `S_pq = √(2/(n+1)) sin(π(p+1)(q+1)/(n+1))` is symmetric and its own inverse; it diagonalises
//! the 1-D Dirichlet neighbour sum `tridiag(1, 0, 1)` with eigenvalues `2 cos(π(p+1)/(n+1))`,
//! which is what makes fast Poisson solves on boxes (and the separable restoration solve) work.
//!
//! ## Folding by parity, and the split order
//! `S_{p,n−1−q} = (−1)^p S_pq`, so even modes see only `x_q + x_{n−1−q}` and odd modes only
//! `x_q − x_{n−1−q}`: the transform is two dense products of half size (faer's gemm), `n` flops
//! per value. The two products naturally give the coefficients in **split order** — the even
//! modes `0, 2, 4, …` first, then the odd modes `1, 3, …` — and the inverse consumes exactly that
//! order (`x_q = E_q + O_q`, `x_{n−1−q} = E_q − O_q` with `E`, `O` the even and odd partial
//! sums). Solvers that only scale or solve per mode never need the natural order, so nothing
//! here spends a pass reordering: [`Dst1::mode`] says which mode sits at a split position.
//!
//! The transforms work in place with one scratch buffer of the same size. For the box sizes
//! of restoration (`n ≤ 256`) they run at gemm speed; an FFT-based DST of length `n` needs an
//! FFT of length `2(n+1)`, which for the common `n = 2ᵐ` is a poor size (`2·65 = 2·5·13`).
//!
//! ```
//! use zeroset_solvers::dst::{Direction, Dst1, dst1_split_along_axis};
//!
//! let shape = [3, 4];
//! let x: Vec<f64> = (0..12).map(|i| i as f64).collect();
//! let (mut y, mut scratch) = (x.clone(), vec![0.0; 12]);
//! let s = Dst1::new(4);
//! dst1_split_along_axis(&mut y, &mut scratch, &shape, 1, &s, Direction::Forward);
//! // Row 0 is (0, 1, 2, 3); its mode-0 coefficient (split position 0) is Σ_q S_0q x_q.
//! let mode0: f64 = (0..4).map(|q| s.entry(0, q) * q as f64).sum();
//! assert!((y[0] - mode0).abs() < 1e-12 && s.mode(2) == 1);
//! dst1_split_along_axis(&mut y, &mut scratch, &shape, 1, &s, Direction::Inverse); // S² = I
//! assert!(x.iter().zip(&y).all(|(a, b)| (a - b).abs() < 1e-12));
//! ```

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

/// How the lines to transform lie in a buffer of `lines × n` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Each line is `n` contiguous values (the last axis of an array): row-major `lines × n`.
    Rows,
    /// Position `q` of every line is a contiguous slab of `lines` values (a leading axis):
    /// column-major `lines × n`.
    Columns,
}

/// Forward (natural → split order) or inverse (split → natural order); the same matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Values in natural order in, coefficients in split order out.
    Forward,
    /// Coefficients in split order in, values in natural order out.
    Inverse,
}

/// The orthonormal DST-I matrix `S` of size `n`, stored folded by parity (see the module docs).
#[derive(Debug, Clone)]
pub struct Dst1 {
    n: usize,
    /// `even[(q, i)] = S_{2i, q}` for the folded columns `q < ⌈n/2⌉` (the middle one when `n`
    /// is odd): right-multiplying folded lines by it gives the even modes.
    even: Mat<f64>,
    /// `odd[(q, i)] = S_{2i+1, q}` for `q < ⌊n/2⌋`.
    odd: Mat<f64>,
}

impl Dst1 {
    /// The transform of length `n` (`n ≥ 1`).
    pub fn new(n: usize) -> Self {
        let (half, ceil) = (n / 2, n.div_ceil(2));
        let s = |p: usize, q: usize| entry(n, p, q);
        Self {
            n,
            even: Mat::from_fn(ceil, ceil, |q, i| s(2 * i, q)),
            odd: Mat::from_fn(half, half, |q, i| s(2 * i + 1, q)),
        }
    }

    /// The length `n` of the transform.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Never true: a transform has length at least 1.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// `S_pq`.
    pub fn entry(&self, p: usize, q: usize) -> f64 {
        entry(self.n, p, q)
    }

    /// The mode `p` whose coefficient sits at split position `j`: `2j` for `j < ⌈n/2⌉`, then
    /// the odd modes.
    pub fn mode(&self, j: usize) -> usize {
        let ceil = self.n.div_ceil(2);
        if j < ceil { 2 * j } else { 2 * (j - ceil) + 1 }
    }

    /// The eigenvalues `2 cos(π(p+1)/(n+1))` of `tridiag(1, 0, 1)`, in split order.
    pub fn eigenvalues_split(&self) -> Vec<f64> {
        let pi = std::f64::consts::PI;
        (0..self.n)
            .map(|j| 2.0 * (pi * (self.mode(j) + 1) as f64 / (self.n + 1) as f64).cos())
            .collect()
    }

    /// Transforms the `lines` lines of `data` (laid out as `layout`) in place; `scratch` holds
    /// as many values as `data`. `parallel` spreads the work of this one call over rayon's
    /// threads. The lines are cut into groups of a fixed size whatever the thread count, so
    /// every value comes out bit-identical with or without `parallel`, on any number of threads.
    ///
    /// # Panics
    /// If `data` or `scratch` does not hold `lines · n` values.
    pub fn transform(
        &self,
        data: &mut [f64],
        scratch: &mut [f64],
        lines: usize,
        layout: Layout,
        direction: Direction,
        parallel: bool,
    ) {
        assert!(
            data.len() == lines * self.n && scratch.len() == data.len(),
            "DST-I buffers must hold lines · n values"
        );
        match direction {
            Direction::Forward => {
                fold(scratch, data, self.n, lines, layout, parallel);
                self.products(data, scratch, lines, layout, false, parallel);
            }
            Direction::Inverse => {
                self.products(scratch, data, lines, layout, true, parallel);
                unfold(data, scratch, self.n, lines, layout, parallel);
            }
        }
    }

    /// `out[:, ..⌈n/2⌉] ← x[:, ..⌈n/2⌉] · E`, `out[:, ⌈n/2⌉..] ← x[:, ⌈n/2⌉..] · O`, with
    /// `(E, O)` the even and odd blocks, transposed for the inverse; [`GROUP`] lines at a time.
    fn products(
        &self,
        out: &mut [f64],
        x: &[f64],
        lines: usize,
        layout: Layout,
        inverse: bool,
        parallel: bool,
    ) {
        let n = self.n;
        let (x, out) = match layout {
            Layout::Rows => (
                MatRef::from_row_major_slice(x, lines, n),
                MatMut::from_row_major_slice_mut(out, lines, n),
            ),
            Layout::Columns => (
                MatRef::from_column_major_slice(x, lines, n),
                MatMut::from_column_major_slice_mut(out, lines, n),
            ),
        };
        let mut groups = Vec::with_capacity(lines.div_ceil(GROUP));
        let mut rest = out;
        while rest.nrows() > GROUP {
            let (group, tail) = rest.split_at_row_mut(GROUP);
            groups.push(group);
            rest = tail;
        }
        groups.push(rest);
        let one = |(g, out): (usize, MatMut<'_, f64>)| {
            let x = x.subrows(g * GROUP, out.nrows());
            self.group_products(out, x, inverse);
        };
        if parallel {
            groups.into_par_iter().enumerate().for_each(one);
        } else {
            groups.into_iter().enumerate().for_each(one);
        }
    }

    fn group_products(&self, out: MatMut<'_, f64>, x: MatRef<'_, f64>, inverse: bool) {
        let ceil = self.n.div_ceil(2);
        let (even, odd) = if inverse {
            (self.even.transpose(), self.odd.transpose())
        } else {
            (self.even.as_ref(), self.odd.as_ref())
        };
        let (out_even, out_odd) = out.split_at_col_mut(ceil);
        let (x_even, x_odd) = x.split_at_col(ceil);
        matmul(out_even, Accum::Replace, x_even, even, 1.0, Par::Seq);
        if self.n > ceil {
            matmul(out_odd, Accum::Replace, x_odd, odd, 1.0, Par::Seq);
        }
    }
}

/// Lines per dense product: fixed, so that results never depend on the thread count.
const GROUP: usize = 128;

/// `S_pq` for length `n`.
fn entry(n: usize, p: usize, q: usize) -> f64 {
    let pi = std::f64::consts::PI;
    (2.0 / (n + 1) as f64).sqrt() * (pi * ((p + 1) * (q + 1)) as f64 / (n + 1) as f64).sin()
}

/// `folded[:, q] ← x_q + x_{n−1−q}`, `folded[:, ⌈n/2⌉ + q] ← x_q − x_{n−1−q}` (`q < ⌊n/2⌋`), and
/// the middle value at `⌊n/2⌋` when `n` is odd.
fn fold(folded: &mut [f64], x: &[f64], n: usize, lines: usize, layout: Layout, parallel: bool) {
    let (half, ceil) = (n / 2, n.div_ceil(2));
    match layout {
        Layout::Rows => {
            let rows = |(f, x): (&mut [f64], &[f64])| {
                for (f, x) in f.chunks_exact_mut(n).zip(x.chunks_exact(n)) {
                    let (plus, minus) = f.split_at_mut(ceil);
                    for q in 0..half {
                        plus[q] = x[q] + x[n - 1 - q];
                        minus[q] = x[q] - x[n - 1 - q];
                    }
                    if ceil > half {
                        plus[half] = x[half];
                    }
                }
            };
            if parallel {
                let chunk = GROUP * n;
                folded
                    .par_chunks_mut(chunk)
                    .zip(x.par_chunks(chunk))
                    .for_each(rows);
            } else {
                rows((folded, x));
            }
        }
        Layout::Columns => {
            let slab = |q: usize| &x[q * lines..(q + 1) * lines];
            let (plus, minus) = folded.split_at_mut(ceil * lines);
            let pair = |(q, (p, m)): (usize, (&mut [f64], &mut [f64]))| {
                let (a, b) = (slab(q), slab(n - 1 - q));
                for j in 0..lines {
                    p[j] = a[j] + b[j];
                    m[j] = a[j] - b[j];
                }
            };
            if parallel {
                plus.par_chunks_mut(lines)
                    .zip(minus.par_chunks_mut(lines))
                    .enumerate()
                    .for_each(pair);
            } else {
                plus.chunks_mut(lines)
                    .zip(minus.chunks_mut(lines))
                    .enumerate()
                    .for_each(pair);
            }
            if ceil > half {
                plus[half * lines..].copy_from_slice(slab(half));
            }
        }
    }
}

/// The inverse of [`fold`]'s pairing: `x_q ← E_q + O_q`, `x_{n−1−q} ← E_q − O_q`, and the middle
/// value `E_{⌊n/2⌋}` when `n` is odd, from `sums = [E | O]`.
fn unfold(x: &mut [f64], sums: &[f64], n: usize, lines: usize, layout: Layout, parallel: bool) {
    let (half, ceil) = (n / 2, n.div_ceil(2));
    match layout {
        Layout::Rows => {
            let rows = |(x, s): (&mut [f64], &[f64])| {
                for (x, s) in x.chunks_exact_mut(n).zip(s.chunks_exact(n)) {
                    let (e, o) = s.split_at(ceil);
                    for q in 0..half {
                        x[q] = e[q] + o[q];
                        x[n - 1 - q] = e[q] - o[q];
                    }
                    if ceil > half {
                        x[half] = e[half];
                    }
                }
            };
            if parallel {
                let chunk = GROUP * n;
                x.par_chunks_mut(chunk)
                    .zip(sums.par_chunks(chunk))
                    .for_each(rows);
            } else {
                rows((x, sums));
            }
        }
        Layout::Columns => {
            let (e, o) = sums.split_at(ceil * lines);
            let (low, high) = x.split_at_mut(ceil * lines);
            if ceil > half {
                low[half * lines..].copy_from_slice(&e[half * lines..]);
            }
            // Position n−1−q is slab `half − 1 − q` of `high` (positions ceil..n).
            let pair = |(q, (lo, hi)): (usize, (&mut [f64], &mut [f64]))| {
                let (e, o) = (
                    &e[q * lines..(q + 1) * lines],
                    &o[q * lines..(q + 1) * lines],
                );
                for j in 0..lines {
                    lo[j] = e[j] + o[j];
                    hi[j] = e[j] - o[j];
                }
            };
            let low = &mut low[..half * lines];
            if parallel {
                low.par_chunks_mut(lines)
                    .zip(high.par_chunks_mut(lines).rev())
                    .enumerate()
                    .for_each(pair);
            } else {
                low.chunks_mut(lines)
                    .zip(high.chunks_mut(lines).rev())
                    .enumerate()
                    .for_each(pair);
            }
        }
    }
}

/// Applies `S` in place along `axis` of the last-axis-fastest array `data` of `shape`:
/// [`Direction::Forward`] leaves that axis in split order, [`Direction::Inverse`] expects it
/// there. `scratch` holds as many values as `data`. Parallel; the result does not depend on
/// the thread count.
///
/// # Panics
/// If `data` and `scratch` do not both hold `Π shape` values or `shape[axis] != s.len()`.
pub fn dst1_split_along_axis(
    data: &mut [f64],
    scratch: &mut [f64],
    shape: &[usize],
    axis: usize,
    s: &Dst1,
    direction: Direction,
) {
    let n = shape[axis];
    assert_eq!(n, s.n, "transform length does not match the axis");
    assert!(data.len() == shape.iter().product::<usize>() && scratch.len() == data.len());
    let post: usize = shape[axis + 1..].iter().product();
    let pre: usize = shape[..axis].iter().product();
    if post == 1 {
        s.transform(data, scratch, pre, Layout::Rows, direction, true);
        return;
    }
    // Each of the `pre` blocks is `post` lines in the column layout.
    let block = n * post;
    let blocks = data.chunks_mut(block).zip(scratch.chunks_mut(block));
    if pre < 2 * rayon::current_num_threads() {
        blocks.for_each(|(d, t)| s.transform(d, t, post, Layout::Columns, direction, true));
    } else {
        data.par_chunks_mut(block)
            .zip(scratch.par_chunks_mut(block))
            .for_each(|(d, t)| s.transform(d, t, post, Layout::Columns, direction, false));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `S x` by the definition, in natural order.
    fn naive(x: &[f64]) -> Vec<f64> {
        let n = x.len();
        (0..n)
            .map(|p| (0..n).map(|q| entry(n, p, q) * x[q]).sum())
            .collect()
    }

    #[test]
    fn matches_the_definition_along_every_axis_for_odd_and_even_lengths() {
        for shape in [[5, 4, 7], [6, 3, 2], [1, 9, 8]] {
            let len: usize = shape.iter().product();
            let x: Vec<f64> = (0..len).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
            for axis in 0..3 {
                let n = shape[axis];
                let s = Dst1::new(n);
                let (mut y, mut scratch) = (x.clone(), vec![0.0; len]);
                dst1_split_along_axis(&mut y, &mut scratch, &shape, axis, &s, Direction::Forward);
                let post: usize = shape[axis + 1..].iter().product();
                let pre: usize = shape[..axis].iter().product();
                for a in 0..pre {
                    for b in 0..post {
                        let at = |q: usize| (a * n + q) * post + b;
                        let line: Vec<f64> = (0..n).map(|q| x[at(q)]).collect();
                        let want = naive(&line);
                        for j in 0..n {
                            let (got, want) = (y[at(j)], want[s.mode(j)]);
                            assert!((got - want).abs() < 1e-12, "{shape:?} axis {axis}");
                        }
                    }
                }
                dst1_split_along_axis(&mut y, &mut scratch, &shape, axis, &s, Direction::Inverse);
                assert!(x.iter().zip(&y).all(|(a, b)| (a - b).abs() < 1e-12));
            }
        }
    }

    #[test]
    fn both_layouts_and_thread_counts_give_identical_bits() {
        let (n, lines) = (11, 37);
        let s = Dst1::new(n);
        let rows: Vec<f64> = (0..n * lines).map(|i| (i as f64 * 0.37).sin()).collect();
        // The same lines stored column-wise.
        let mut cols = vec![0.0; n * lines];
        for l in 0..lines {
            for q in 0..n {
                cols[q * lines + l] = rows[l * n + q];
            }
        }
        let run = |data: &[f64], layout: Layout, parallel: bool| {
            let (mut d, mut t) = (data.to_vec(), vec![0.0; data.len()]);
            s.transform(&mut d, &mut t, lines, layout, Direction::Forward, parallel);
            d
        };
        let (r_seq, r_par) = (
            run(&rows, Layout::Rows, false),
            run(&rows, Layout::Rows, true),
        );
        let (c_seq, c_par) = (
            run(&cols, Layout::Columns, false),
            run(&cols, Layout::Columns, true),
        );
        assert_eq!(r_seq, r_par);
        assert_eq!(c_seq, c_par);
        for l in 0..lines {
            for q in 0..n {
                assert!((r_seq[l * n + q] - c_seq[q * lines + l]).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn split_order_lists_even_then_odd_modes_with_their_eigenvalues() {
        let s = Dst1::new(5);
        assert_eq!(
            (0..5).map(|j| s.mode(j)).collect::<Vec<_>>(),
            [0, 2, 4, 1, 3]
        );
        let e = s.eigenvalues_split();
        assert!((e[0] - 2.0 * (std::f64::consts::PI / 6.0).cos()).abs() < 1e-15);
        assert!((e[3] - 2.0 * (std::f64::consts::PI * 2.0 / 6.0).cos()).abs() < 1e-15);
        let one = Dst1::new(1);
        let (mut d, mut t) = (vec![1.0, 2.0, 3.0], vec![0.0; 3]);
        dst1_split_along_axis(&mut d, &mut t, &[3, 1], 1, &one, Direction::Forward);
        assert_eq!(d, [1.0, 2.0, 3.0]);
    }
}
