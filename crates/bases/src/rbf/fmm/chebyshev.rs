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

    /// The map from values at the nodes to Chebyshev coefficients, row-major `p × p`: the
    /// interpolant of values `gₘ` is `Σ_k c_k T_k` with `c_k = Σₘ C[k][m] gₘ`
    /// (`C[0][m] = 1/p`, `C[k][m] = 2 T_k(x̄ₘ)/p`).
    pub fn coefficient_map(&self) -> Vec<f64> {
        let p = self.p;
        let mut c = self.t.clone();
        c[..p].fill(1.0 / p as f64);
        c
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

/// [`contract`] and its gradient in one pass: `[value, ∂₀, ∂₁, ∂₂]` with the 1-D weights `s`
/// and their derivatives `ds`.
#[inline(always)]
pub(crate) fn contract_with_gradient(
    p: usize,
    s: &[[f64; MAX_ORDER]; 3],
    ds: &[[f64; MAX_ORDER]; 3],
    e: &[f64],
) -> [f64; 4] {
    macro_rules! orders {
        ($($p:literal)*) => {
            match p {
                $($p => contract_gradient_fixed::<$p>(s, ds, e),)*
                _ => contract_gradient_any(p, s, ds, e),
            }
        };
    }
    orders!(2 3 4 5 6 7 8 9 10 11 12 13 14 15 16)
}

fn contract_gradient_any(
    p: usize,
    s: &[[f64; MAX_ORDER]; 3],
    ds: &[[f64; MAX_ORDER]; 3],
    e: &[f64],
) -> [f64; 4] {
    let mut out = [0.0; 4];
    let p = p.min(MAX_ORDER);
    for a in 0..p {
        for b in 0..p {
            for c in 0..p {
                let v = e[(a * p + b) * p + c];
                out[0] += v * s[0][a] * s[1][b] * s[2][c];
                out[1] += v * ds[0][a] * s[1][b] * s[2][c];
                out[2] += v * s[0][a] * ds[1][b] * s[2][c];
                out[3] += v * s[0][a] * s[1][b] * ds[2][c];
            }
        }
    }
    out
}

#[inline(always)]
fn contract_gradient_fixed<const P: usize>(
    s: &[[f64; MAX_ORDER]; 3],
    ds: &[[f64; MAX_ORDER]; 3],
    e: &[f64],
) -> [f64; 4] {
    let e = &e[..P * P * P];
    // row: Σ_a s0 Σ_b s1 e; dx: Σ_a ds0 Σ_b s1 e; dy: Σ_a s0 Σ_b ds1 e (each along z).
    let (mut row, mut dx, mut dy) = ([0.0; P], [0.0; P], [0.0; P]);
    for a in 0..P {
        let (mut inner, mut dinner) = ([0.0; P], [0.0; P]);
        for b in 0..P {
            let (w, dw) = (s[1][b], ds[1][b]);
            let line = &e[(a * P + b) * P..][..P];
            for c in 0..P {
                inner[c] += w * line[c];
                dinner[c] += dw * line[c];
            }
        }
        let (w, dw) = (s[0][a], ds[0][a]);
        for c in 0..P {
            row[c] += w * inner[c];
            dx[c] += dw * inner[c];
            dy[c] += w * dinner[c];
        }
    }
    let mut out = [0.0; 4];
    for c in 0..P {
        out[0] += row[c] * s[2][c];
        out[1] += dx[c] * s[2][c];
        out[2] += dy[c] * s[2][c];
        out[3] += row[c] * ds[2][c];
    }
    out
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

    /// The fused value-and-gradient contraction equals the plain sums, for compile-time and
    /// other orders.
    #[test]
    fn contraction_with_gradient_matches_the_plain_sums() {
        for p in [2, 5, 9, 16] {
            let c = Chebyshev::new(p);
            let e: Vec<f64> = (0..p * p * p)
                .map(|i| ((i * 7919) % 1013) as f64 / 1013.0 - 0.5)
                .collect();
            let mut s = [[0.0; MAX_ORDER]; 3];
            let mut ds = [[0.0; MAX_ORDER]; 3];
            for (a, x) in [0.3, -0.71, 0.94].into_iter().enumerate() {
                c.weights_with_derivative(x, &mut s[a][..p], &mut ds[a][..p]);
            }
            let fused = contract_with_gradient(p, &s, &ds, &e);
            let plain = contract_gradient_any(p, &s, &ds, &e);
            assert!((fused[0] - contract(p, &s, &e)).abs() < 1e-13, "p={p}");
            for k in 0..4 {
                assert!((fused[k] - plain[k]).abs() < 1e-12, "p={p} k={k}");
            }
        }
    }

    /// The coefficient map gives the interpolant in the Chebyshev basis.
    #[test]
    fn coefficient_map_expands_the_interpolant() {
        let p = 7;
        let c = Chebyshev::new(p);
        let g: Vec<f64> = c.nodes().iter().map(|x| (1.3 * x).sin() + x * x).collect();
        let map = c.coefficient_map();
        let coeffs: Vec<f64> = (0..p)
            .map(|k| (0..p).map(|m| map[k * p + m] * g[m]).sum())
            .collect();
        let (mut s, mut t) = (vec![0.0; p], vec![0.0; p]);
        for &x in &[-1.0, -0.2, 0.45, 1.0] {
            c.weights(x, &mut s);
            chebyshev_t(x, &mut t);
            let lagrange: f64 = (0..p).map(|m| g[m] * s[m]).sum();
            let chebyshev: f64 = (0..p).map(|k| coeffs[k] * t[k]).sum();
            assert!((lagrange - chebyshev).abs() < 1e-14, "x={x}");
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
