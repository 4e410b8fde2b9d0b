//! The exact dense solve of `[Φ P; Pᵀ 0]`, by Cholesky on the null space of `Pᵀ`.
//!
//! With `P = Q [R; 0]` (Householder QR, `m = D + 1` reflections) write `w = Q y`. Then
//! `Pᵀ w = Rᵀ y₁`, and `Q̃ = Qᵀ Φ Q` splits the system into
//!
//! ```text
//!     y₁ = R⁻ᵀ g,     Φ̃₂₂ y₂ = f̃₂ − Φ̃₂₁ y₁,     c = R⁻¹ (f̃₁ − Φ̃₁₁ y₁ − Φ̃₁₂ y₂),    f̃ = Qᵀ f
//! ```
//!
//! for a right-hand side `[f; g]`. `σ Φ̃₂₂` is positive definite for a kernel `σφ` that is
//! conditionally positive definite of order ≤ 2 and distinct points (see [`super::kernel`]),
//! so it factors by Cholesky: `(n−m)³/3` flops against LU's `2(n+m)³/3` on the whole
//! indefinite matrix. Forming `Q̃` costs `O(n² m)` (rank-2 updates, one per reflection). A solve
//! afterwards is `O(n²)`, which is what the incremental constraints build on.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

use super::RbfError;

/// A factorised RBF system (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct DenseFactor {
    n: usize,
    m: usize,
    /// Householder vectors (zero before their index) and their `τ`.
    reflectors: Vec<(Vec<f64>, f64)>,
    /// `R`, `m × m` upper triangular, row-major.
    r: Vec<f64>,
    /// The first `m` rows of `Q̃`, `m × n` row-major.
    top: Vec<f64>,
    llt: Cholesky,
    sign: f64,
    /// `(max Lᵢᵢ / min Lᵢᵢ)²`, a lower bound on the condition number of `σ Φ̃₂₂`.
    condition: f64,
}

impl DenseFactor {
    /// Factors the column-major `(n+m)²` matrix `a` (overwritten), `sign` the kernel's `σ`;
    /// the Cholesky factor in `precision`.
    pub fn new(
        a: Vec<f64>,
        n: usize,
        m: usize,
        sign: f64,
        precision: Precision,
    ) -> Result<Self, RbfError> {
        let size = n + m;
        if n <= m {
            return Err(RbfError::Degenerate {
                detail: format!("{n} constraints; a linear polynomial needs more than {m}"),
            });
        }
        // Householder QR of P (rows 0..n of columns n..n+m).
        let mut p: Vec<f64> = (0..m)
            .flat_map(|k| a[(n + k) * size..(n + k) * size + n].to_vec())
            .collect();
        let mut reflectors = Vec::with_capacity(m);
        let mut r = vec![0.0; m * m];
        let scale_p = p.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        for k in 0..m {
            let col = &p[k * n..(k + 1) * n];
            let alpha_norm = col[k..].iter().map(|v| v * v).sum::<f64>().sqrt();
            if alpha_norm <= 1e-10 * scale_p * (n as f64).sqrt() {
                return Err(RbfError::Degenerate {
                    detail: degenerate_detail(k, m),
                });
            }
            let alpha = if col[k] > 0.0 {
                -alpha_norm
            } else {
                alpha_norm
            };
            let mut v = vec![0.0; n];
            v[k..].copy_from_slice(&col[k..]);
            v[k] -= alpha;
            let vv: f64 = v.iter().map(|x| x * x).sum();
            let tau = 2.0 / vv;
            // Apply H = I − τvvᵀ to the columns k.. of P.
            for j in k..m {
                let cj = &mut p[j * n..(j + 1) * n];
                let s = tau * v.iter().zip(cj.iter()).map(|(a, b)| a * b).sum::<f64>();
                cj.iter_mut().zip(&v).for_each(|(c, vi)| *c -= s * vi);
            }
            for j in k..m {
                r[k * m + j] = p[j * n + k];
            }
            reflectors.push((v, tau));
        }
        let (llt, top, (lo, hi)) = match precision {
            Precision::Double => {
                let (a, top) = project(a, size, n, m, &reflectors, sign);
                let (l, range) = factor(a, size, m * size + m, n - m)?;
                (Cholesky::Double(l), top, range)
            }
            Precision::Single => {
                // The projection stays in f64 (its cancellation would cost f32 the definiteness);
                // the trailing block is converted once and factored 8 lanes wide.
                let (a, top) = project(a, size, n, m, &reflectors, sign);
                let len = n - m;
                let mut k32 = vec![0.0f32; len * len];
                k32.par_chunks_mut(len).enumerate().for_each(|(j, dst)| {
                    let src = &a[(m + j) * size + m..(m + j) * size + m + len];
                    dst.iter_mut().zip(src).for_each(|(d, s)| *d = *s as f32);
                });
                drop(a);
                let (l, range) = factor(k32, len, 0, len)?;
                (Cholesky::Single(l), top, range)
            }
        };
        Ok(Self {
            n,
            m,
            reflectors,
            r,
            top,
            llt,
            sign,
            condition: (hi / lo).powi(2),
        })
    }

    /// `n + m`, the size of the system.
    pub fn size(&self) -> usize {
        self.n + self.m
    }

    /// The condition estimate (a lower bound on `κ(σ Φ̃₂₂)`).
    pub fn condition(&self) -> f64 {
        self.condition
    }

    /// `[w; c]` solving the system for the right-hand side `[f; g]` (`n + m` values).
    pub fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        let (n, m) = (self.n, self.m);
        let (f, g) = rhs.split_at(n);
        // f̃ = Qᵀ f = H_{m−1} … H₀ f.
        let mut ft = f.to_vec();
        for (v, tau) in &self.reflectors {
            reflect(&mut ft, v, *tau);
        }
        // y₁ = R⁻ᵀ g (forward substitution with Rᵀ).
        let mut y = vec![0.0; n];
        for i in 0..m {
            let s: f64 = (0..i).map(|k| self.r[k * m + i] * y[k]).sum();
            y[i] = (g[i] - s) / self.r[i * m + i];
        }
        // Φ̃₂₂ y₂ = f̃₂ − Φ̃₂₁ y₁ (Φ̃₂₁ = Φ̃₁₂ᵀ, the top rows' tail).
        let b2: Vec<f64> = (0..n - m)
            .map(|i| ft[m + i] - (0..m).map(|k| self.top[k * n + m + i] * y[k]).sum::<f64>())
            .collect();
        let y2 = match &self.llt {
            Cholesky::Double(l) => l.solve(&b2),
            Cholesky::Single(l) => l.solve(&b2),
        };
        for (yi, v) in y[m..].iter_mut().zip(y2) {
            *yi = self.sign * v;
        }
        // c = R⁻¹ (f̃₁ − Φ̃₁₁ y₁ − Φ̃₁₂ y₂): the top rows times y.
        let mut c = vec![0.0; m];
        for i in 0..m {
            let row = &self.top[i * n..(i + 1) * n];
            c[i] = ft[i] - row.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>();
        }
        for i in (0..m).rev() {
            let s: f64 = (i + 1..m).map(|k| self.r[i * m + k] * c[k]).sum();
            c[i] = (c[i] - s) / self.r[i * m + i];
        }
        // w = Q y = H₀ … H_{m−1} y.
        for (v, tau) in self.reflectors.iter().rev() {
            reflect(&mut y, v, *tau);
        }
        y.extend_from_slice(&c);
        y
    }
}

/// The precision of the Cholesky factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Precision {
    /// f64: an exact solve (up to rounding).
    Double,
    /// f32: twice the speed and half the memory; solves to about `κ · 6e-8`, so it serves as
    /// the preconditioner of an f64 iteration (mixed-precision refinement).
    Single,
}

/// The Cholesky factor `L` of `σ Φ̃₂₂`, the lower triangle of the trailing block of the
/// (column-major, `stride`) buffer it was computed in.
#[derive(Debug, Clone)]
struct Factor<T> {
    buffer: Vec<T>,
    stride: usize,
    offset: usize,
    len: usize,
}

impl<T: Real> Factor<T> {
    fn l(&self) -> MatRef<'_, T> {
        MatRef::from_column_major_slice_with_stride(
            &self.buffer[self.offset..],
            self.len,
            self.len,
            self.stride,
        )
    }

    /// `(L Lᵀ)⁻¹ b`, sequentially: with one right-hand side faer's parallel triangular solve
    /// splits the sums of its matrix–vector products into one part per thread, so its bits
    /// depended on the thread count (`zeroset fit --solver dense` wrote other weights on 1 and
    /// 3 threads, and on the 2,000-point sample the iterative fit, whose coarse level is solved
    /// here every step, took 14 GMRES steps against 12). The solve is `O(n²)` against the
    /// factorisation's `O(n³)`; that one and the projection stay parallel (blocked products
    /// that split no sum: the same bits on 1, 2 and 3 threads, see the test below).
    fn solve(&self, b: &[f64]) -> Vec<f64> {
        let mut x = Mat::<T>::from_fn(self.len, 1, |i, _| T::of(b[i]));
        let l = self.l();
        solve_lower_triangular_in_place(l, x.as_mut(), Par::Seq);
        solve_upper_triangular_in_place(l.transpose(), x.as_mut(), Par::Seq);
        (0..self.len).map(|i| x[(i, 0)].to()).collect()
    }
}

#[derive(Debug, Clone)]
enum Cholesky {
    Double(Factor<f64>),
    Single(Factor<f32>),
}

/// The float types a factor can be computed in.
trait Real: faer::traits::RealField + Copy + Send + Sync + 'static {
    fn of(x: f64) -> Self;
    fn to(self) -> f64;
}

impl Real for f64 {
    fn of(x: f64) -> Self {
        x
    }
    fn to(self) -> f64 {
        self
    }
}

impl Real for f32 {
    fn of(x: f64) -> Self {
        x as f32
    }
    fn to(self) -> f64 {
        f64::from(self)
    }
}

/// `Q̃ = Qᵀ Φ Q` in two passes over `Φ` (the leading `n × n` block of the column-major buffer
/// `a` with column stride `stride`), and `σ Φ̃₂₂` in its place. With
/// `Q = H₀⋯H_{m−1} = I − V T Vᵀ` (compact WY, `T` upper triangular): `Y = Φ V`, `Z = Y T`,
/// `W = Z − ½ V (Tᵀ Vᵀ Y T)`, and `Qᵀ Φ Q = Φ − W Vᵀ − V Wᵀ`. Returns the buffer and the
/// first `m` rows of `Q̃` (`m × n`, row-major).
fn project(
    mut a: Vec<f64>,
    stride: usize,
    n: usize,
    m: usize,
    reflectors: &[(Vec<f64>, f64)],
    sign: f64,
) -> (Vec<f64>, Vec<f64>) {
    let v = Mat::<f64>::from_fn(n, m, |i, k| reflectors[k].0[i]);
    let mut t = Mat::<f64>::zeros(m, m);
    for k in 0..m {
        let tau = reflectors[k].1;
        t[(k, k)] = tau;
        // T[..k, k] = −τ_k T[..k, ..k] V[:, ..k]ᵀ v_k.
        let vtv: Vec<f64> = (0..k)
            .map(|i| (0..n).map(|r| v[(r, i)] * v[(r, k)]).sum())
            .collect();
        for i in 0..k {
            t[(i, k)] = -tau * (i..k).map(|l| t[(i, l)] * vtv[l]).sum::<f64>();
        }
    }
    let mut phi = MatMut::from_column_major_slice_with_stride_mut(&mut a, n, n, stride);
    let mut y = Mat::<f64>::zeros(n, m);
    matmul(
        y.as_mut(),
        Accum::Replace,
        phi.as_ref(),
        v.as_ref(),
        1.0,
        Par::rayon(0),
    );
    let z = &y * &t;
    let middle = t.transpose() * (v.transpose() * &z);
    let w = &z - (&v * &middle) * faer::Scale(0.5);
    let left = Mat::from_fn(
        n,
        2 * m,
        |i, k| if k < m { w[(i, k)] } else { v[(i, k - m)] },
    );
    let right = Mat::from_fn(
        2 * m,
        n,
        |k, i| if k < m { v[(i, k)] } else { w[(i, k - m)] },
    );
    matmul(
        phi.as_mut(),
        Accum::Add,
        left.as_ref(),
        right.as_ref(),
        -1.0,
        Par::rayon(0),
    );
    let top: Vec<f64> = (0..m)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| phi[(i, j)])
        .collect();
    if sign < 0.0 {
        let mut k = phi.submatrix_mut(m, m, n - m, n - m);
        for j in 0..n - m {
            for i in j..n - m {
                k[(i, j)] = -k[(i, j)];
            }
        }
    }
    (a, top)
}

/// The Cholesky factor, in place, of the `len × len` block at `offset` of the column-major
/// buffer `a` (column stride `stride`); returns it and the range of its diagonal.
fn factor<T: Real>(
    mut a: Vec<T>,
    stride: usize,
    offset: usize,
    len: usize,
) -> Result<(Factor<T>, (f64, f64)), RbfError> {
    let mut k = MatMut::from_column_major_slice_with_stride_mut(&mut a[offset..], len, len, stride);
    let par = Par::rayon(0);
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<T>(len, par, Default::default()));
    cholesky_in_place(
        k.as_mut(),
        Default::default(),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|e| {
        RbfError::Singular(if std::mem::size_of::<T>() < 8 {
            format!(
                "the projected kernel matrix is not positive definite in single precision \
                 ({e:?}): its condition number is beyond what f32 resolves (the dense f64 solve \
                 takes it)"
            )
        } else {
            format!(
                "the projected kernel matrix is not positive definite ({e:?}): duplicate or \
                 nearly coincident points, or a kernel that is not conditionally positive \
                 definite"
            )
        })
    })?;
    let range = diagonal_range(len, |i| k[(i, i)].to());
    let factor = Factor {
        buffer: a,
        stride,
        offset,
        len,
    };
    Ok((factor, range))
}

/// `(min, max)` of `|d(i)|` over `i < len`.
fn diagonal_range(len: usize, d: impl Fn(usize) -> f64) -> (f64, f64) {
    (0..len).fold((f64::INFINITY, 0.0f64), |(lo, hi), i| {
        let v = d(i).abs();
        (lo.min(v), hi.max(v))
    })
}

/// `x ← (I − τ v vᵀ) x`.
fn reflect(x: &mut [f64], v: &[f64], tau: f64) {
    let s = tau * x.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
    x.iter_mut().zip(v).for_each(|(xi, vi)| *xi -= s * vi);
}

fn degenerate_detail(k: usize, m: usize) -> String {
    let d = m - 1;
    match k {
        0 => "no value constraint".into(),
        _ if k + 1 == m && d == 3 => "all value and gradient constraints lie on one plane".into(),
        _ if k + 1 == m && d == 2 => "all value and gradient constraints lie on one line".into(),
        _ => format!("the constraints span fewer than {d} dimensions"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbf::system::{self, Functionals, Polynomial};
    use crate::rbf::{Biharmonic, Kernel};

    /// The value system of `n` points spread over three shells of a sphere (values `z`).
    fn system(n: usize) -> (Vec<f64>, usize) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut constraints = crate::rbf::Constraints::new();
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let s = 1.0 + 0.05 * (i % 3) as f64;
            let t = golden * i as f64;
            constraints.push_value([s * r * t.cos(), s * r * t.sin(), s * z], z);
        }
        let f = Functionals::new(&Biharmonic, constraints.as_slice()).unwrap();
        let poly = Polynomial::fit(&f.points);
        (system::assemble(&Biharmonic, &f, &poly), n)
    }

    fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }

    /// The factor and its solves give the same bits on any number of threads (the triangular
    /// solves once split their sums by the thread count).
    #[test]
    fn the_same_bits_on_one_and_several_threads() {
        let (a, n) = system(1500);
        let m = Polynomial::<3>::len();
        let rhs: Vec<f64> = (0..n + m)
            .map(|i| ((i * 37 % 101) as f64 - 50.0) / 50.0)
            .collect();
        for precision in [Precision::Double, Precision::Single] {
            let run = |threads: usize| {
                in_pool(threads, || {
                    let f =
                        DenseFactor::new(a.clone(), n, m, Biharmonic.sign(), precision).unwrap();
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    let l = match &f.llt {
                        Cholesky::Double(l) => bits(&l.buffer),
                        Cholesky::Single(l) => {
                            l.buffer.iter().map(|x| u64::from(x.to_bits())).collect()
                        }
                    };
                    (bits(&f.top), l, bits(&f.solve(&rhs)))
                })
            };
            let one = run(1);
            for threads in [2, 3] {
                let other = run(threads);
                assert!(
                    one.0 == other.0,
                    "{precision:?}: the projection differs on {threads} threads"
                );
                assert!(
                    one.1 == other.1,
                    "{precision:?}: the factor differs on {threads} threads"
                );
                assert!(
                    one.2 == other.2,
                    "{precision:?}: the solve differs on {threads} threads"
                );
            }
        }
    }
}
