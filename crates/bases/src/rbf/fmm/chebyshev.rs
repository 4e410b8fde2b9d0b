//! Chebyshev interpolation on `[−1, 1]` (Fong & Darve 2009, §3.1).
//!
//! With the `p` Chebyshev nodes `x̄ₘ = cos((2m + 1)π / 2p)`, the interpolant of `g` is
//! `Σₘ g(x̄ₘ) Sₚ(x̄ₘ, x)` with
//!
//! ```text
//!     Sₚ(x̄ₘ, x) = 1/p + 2/p Σ_{k=1}^{p−1} T_k(x̄ₘ) T_k(x),
//! ```
//!
//! `T_k` the Chebyshev polynomials. A cell of centre `c` and half-width `h` maps `x ↦ (x − c)/h`.
//! The 3-D weights are products of three 1-D ones.

/// The nodes, the `T_k(x̄ₘ)` table and the 1-D transfer matrices of order `p`.
#[derive(Debug, Clone)]
pub(crate) struct Chebyshev {
    p: usize,
    nodes: Vec<f64>,
    /// `t[k * p + m] = 2 T_k(x̄ₘ) / p` (row `k = 0` unused): the weights are `1/p` plus these
    /// rows scaled by `T_k(x)`, a sum vectorised over the nodes `m`.
    t: Vec<f64>,
    /// `transfer[c][m * p + n] = Sₚ(x̄ₘ, (2c − 1)/2 + x̄ₙ/2)`: the weight of the parent's node
    /// `m` at node `n` of its lower (`c = 0`) or upper (`c = 1`) half.
    transfer: [Vec<f64>; 2],
}

impl Chebyshev {
    /// Order `p ≥ 1`.
    pub fn new(p: usize) -> Self {
        let nodes: Vec<f64> = (0..p)
            .map(|m| ((2 * m + 1) as f64 * std::f64::consts::PI / (2 * p) as f64).cos())
            .collect();
        let mut t = vec![0.0; p * p];
        let mut tm = vec![0.0; p];
        for (m, &x) in nodes.iter().enumerate() {
            chebyshev_t(x, &mut tm);
            for (k, &v) in tm.iter().enumerate() {
                t[k * p + m] = 2.0 * v / p as f64;
            }
        }
        let mut this = Self {
            p,
            nodes,
            t,
            transfer: [Vec::new(), Vec::new()],
        };
        let mut s = vec![0.0; p];
        for c in 0..2 {
            let mut mat = vec![0.0; p * p];
            for n in 0..p {
                let x = (2.0 * c as f64 - 1.0) * 0.5 + 0.5 * this.nodes[n];
                this.weights(x, &mut s);
                for m in 0..p {
                    mat[m * p + n] = s[m];
                }
            }
            this.transfer[c] = mat;
        }
        this
    }

    /// The order `p`.
    pub fn order(&self) -> usize {
        self.p
    }

    /// The nodes `x̄ₘ`.
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// `s[m] = Sₚ(x̄ₘ, x)`.
    #[inline(always)]
    pub fn weights(&self, x: f64, s: &mut [f64]) {
        let p = self.p;
        let mut tx = [0.0; MAX_ORDER];
        chebyshev_t(x, &mut tx[..p]);
        let s = &mut s[..p];
        s.fill(1.0 / p as f64);
        for (&w, row) in tx[1..p].iter().zip(self.t.chunks_exact(p).skip(1)) {
            for (sm, &t) in s.iter_mut().zip(row) {
                *sm += t * w;
            }
        }
    }

    /// `s[m] = Sₚ(x̄ₘ, x)` and `ds[m] = ∂Sₚ(x̄ₘ, x)/∂x`.
    #[inline]
    pub fn weights_with_derivative(&self, x: f64, s: &mut [f64], ds: &mut [f64]) {
        let p = self.p;
        let mut tx = [0.0; MAX_ORDER];
        let mut dtx = [0.0; MAX_ORDER];
        chebyshev_t(x, &mut tx[..p]);
        chebyshev_dt(x, &tx[..p], &mut dtx[..p]);
        let (s, ds) = (&mut s[..p], &mut ds[..p]);
        s.fill(1.0 / p as f64);
        ds.fill(0.0);
        let rows = self.t.chunks_exact(p).skip(1);
        for ((&w, &dw), row) in tx[1..p].iter().zip(&dtx[1..p]).zip(rows) {
            for ((sm, dsm), &t) in s.iter_mut().zip(ds.iter_mut()).zip(row) {
                *sm += t * w;
                *dsm += t * dw;
            }
        }
    }

    /// The transfer matrix to the lower (`half = 0`) or upper (`half = 1`) half, row-major
    /// `p × p`: entry `(m, n)` is the weight of parent node `m` at child node `n`.
    pub fn transfer(&self, half: usize) -> &[f64] {
        &self.transfer[half]
    }
}

/// The largest order the fixed-size work arrays allow.
pub(crate) const MAX_ORDER: usize = 16;

/// `Σ_{a,b,c} s[0][a] s[1][b] s[2][c] e[(a p + b) p + c]`: an expansion `e` of order `p`
/// (`2 ≤ p ≤ MAX_ORDER`) at a point with 1-D weights `s`, the order a compile-time constant
/// inside (so that the partial sums stay in registers). The sums run in a fixed order: along
/// `y` for each `x`, then along `x`, then along `z`.
#[inline(always)]
pub(crate) fn contract(p: usize, s: &[[f64; MAX_ORDER]; 3], e: &[f64]) -> f64 {
    macro_rules! orders {
        ($($p:literal)*) => {
            match p {
                $($p => contract_fixed::<$p>(s, e),)*
                _ => contract_any(p, s, e),
            }
        };
    }
    orders!(2 3 4 5 6 7 8 9 10 11 12 13 14 15 16)
}

/// [`contract`] for an order not known at compile time (order 1).
fn contract_any(p: usize, s: &[[f64; MAX_ORDER]; 3], e: &[f64]) -> f64 {
    let mut v = 0.0;
    for a in 0..p.min(MAX_ORDER) {
        for b in 0..p.min(MAX_ORDER) {
            for c in 0..p.min(MAX_ORDER) {
                v += s[0][a] * s[1][b] * s[2][c] * e[(a * p + b) * p + c];
            }
        }
    }
    v
}

#[inline(always)]
fn contract_fixed<const P: usize>(s: &[[f64; MAX_ORDER]; 3], e: &[f64]) -> f64 {
    let e = &e[..P * P * P];
    let mut row = [0.0; P];
    for a in 0..P {
        let mut inner = [0.0; P];
        for b in 0..P {
            let w = s[1][b];
            let line = &e[(a * P + b) * P..][..P];
            for c in 0..P {
                inner[c] += w * line[c];
            }
        }
        let w = s[0][a];
        for c in 0..P {
            row[c] += w * inner[c];
        }
    }
    let mut v = 0.0;
    for c in 0..P {
        v += row[c] * s[2][c];
    }
    v
}

/// `t[k] = T_k(x)` for `k < t.len()`, by the three-term recurrence (valid for every `x`).
#[inline(always)]
fn chebyshev_t(x: f64, t: &mut [f64]) {
    if let Some(t0) = t.first_mut() {
        *t0 = 1.0;
    }
    if t.len() > 1 {
        t[1] = x;
    }
    for k in 2..t.len() {
        t[k] = 2.0 * x * t[k - 1] - t[k - 2];
    }
}

/// `dt[k] = T_k'(x)` from `t[k] = T_k(x)`: `T'_{k+1} = 2 T_k + 2x T'_k − T'_{k−1}`.
#[inline]
fn chebyshev_dt(x: f64, t: &[f64], dt: &mut [f64]) {
    if let Some(d0) = dt.first_mut() {
        *d0 = 0.0;
    }
    if dt.len() > 1 {
        dt[1] = 1.0;
    }
    for k in 2..dt.len() {
        dt[k] = 2.0 * t[k - 1] + 2.0 * x * dt[k - 1] - dt[k - 2];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The interpolant reproduces polynomials of degree `< p` exactly, and the derivative of the
    /// weights differentiates them.
    #[test]
    fn interpolation_reproduces_polynomials_and_their_derivatives() {
        for p in [2, 5, 9, 12] {
            let c = Chebyshev::new(p);
            let g = |x: f64| {
                (0..p)
                    .map(|k| (k as f64 + 1.0) * x.powi(k as i32))
                    .sum::<f64>()
            };
            let dg = |x: f64| {
                (1..p)
                    .map(|k| (k as f64 + 1.0) * k as f64 * x.powi(k as i32 - 1))
                    .sum::<f64>()
            };
            let (mut s, mut ds) = (vec![0.0; p], vec![0.0; p]);
            for &x in &[-1.0, -0.37, 0.0, 0.81, 1.0] {
                c.weights_with_derivative(x, &mut s, &mut ds);
                let v: f64 = (0..p).map(|m| g(c.nodes()[m]) * s[m]).sum();
                let d: f64 = (0..p).map(|m| g(c.nodes()[m]) * ds[m]).sum();
                assert!((v - g(x)).abs() <= 1e-12 * g(1.0).abs(), "p={p} x={x}");
                assert!((d - dg(x)).abs() <= 1e-10 * dg(1.0).abs(), "p={p} x={x}");
            }
        }
    }

    /// Transferring to a half and interpolating there equals interpolating on the whole.
    #[test]
    #[allow(clippy::needless_range_loop)]
    fn transfer_matrices_are_interpolation_on_the_halves() {
        let p = 6;
        let c = Chebyshev::new(p);
        let mut s = vec![0.0; p];
        for half in 0..2 {
            for n in 0..p {
                let x = (2.0 * half as f64 - 1.0) * 0.5 + 0.5 * c.nodes()[n];
                c.weights(x, &mut s);
                for m in 0..p {
                    assert_eq!(c.transfer(half)[m * p + n], s[m]);
                }
            }
        }
    }
}
