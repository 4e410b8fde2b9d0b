//! The trace norm and singular-value thresholding (see the crate docs for the maths).

use faer::{Mat, MatRef, Par};

use crate::TensorError;

/// A thin SVD `A = U Σ Vᵀ`.
#[derive(Debug, Clone, PartialEq)]
pub struct ThinSvd {
    /// `U`, `m × k`.
    pub u: Mat<f64>,
    /// The singular values, non-increasing, `k = min(m, n)` of them.
    pub s: Vec<f64>,
    /// `V`, `n × k`.
    pub v: Mat<f64>,
}

/// The thin SVD `A = U Σ Vᵀ` (`k = min(m, n)`), computed sequentially so that the bits never
/// depend on the thread count.
///
/// # Errors
/// [`TensorError::Svd`] if the SVD does not converge.
pub fn thin_svd(a: MatRef<'_, f64>) -> Result<ThinSvd, TensorError> {
    let (m, n) = (a.nrows(), a.ncols());
    let k = m.min(n);
    let mut u = Mat::<f64>::zeros(m, k);
    let mut v = Mat::<f64>::zeros(n, k);
    let mut s = faer::diag::Diag::<f64>::zeros(k);
    let par = Par::Seq;
    let compute = faer::linalg::svd::ComputeSvdVectors::Thin;
    let mut mem = faer::dyn_stack::MemBuffer::new(faer::linalg::svd::svd_scratch::<f64>(
        m,
        n,
        compute,
        compute,
        par,
        Default::default(),
    ));
    faer::linalg::svd::svd(
        a,
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        par,
        faer::dyn_stack::MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|_| TensorError::Svd)?;
    Ok(ThinSvd {
        u,
        s: (0..k).map(|i| s[i]).collect(),
        v,
    })
}

/// The trace (nuclear) norm `‖M‖_* = Σ σᵢ`.
///
/// # Errors
/// [`TensorError::NonFinite`] for a NaN or infinite entry (index in column-major order),
/// [`TensorError::Svd`] if the SVD does not converge.
pub fn trace_norm(m: MatRef<'_, f64>) -> Result<f64, TensorError> {
    check_finite(m)?;
    Ok(thin_svd(m)?.s.iter().sum())
}

/// Singular-value thresholding `D_τ(M) = U max(Σ − τ, 0) Vᵀ`, the minimiser of
/// `τ ‖Y‖_* + ½ ‖Y − M‖²_F`, and the rank it keeps. Computed sequentially (the same bits on
/// every thread count). A matrix at least 4 times longer than wide (an MRAS unfolding,
/// `m × m²`) is thresholded through the eigendecomposition of its small Gram matrix — 1.7 to
/// 2.5 times faster than through its SVD from `6 × 36` to `11 × 121` (measured, one thread) —
/// and within about `10⁻¹⁰ σ₁` of it (the SVD is used where that would not hold:
/// `τ < 10⁻⁶ σ₁`).
///
/// ```
/// use faer::Mat;
/// use zeroset_tensor::svt;
///
/// let m = Mat::from_fn(3, 3, |i, j| if i == j { [5.0, 2.0, 0.5][i] } else { 0.0 });
/// let (y, rank) = svt(m.as_ref(), 1.0)?;
/// assert_eq!(rank, 2);
/// assert!((y[(0, 0)] - 4.0).abs() < 1e-12 && (y[(1, 1)] - 1.0).abs() < 1e-12);
/// assert!(y[(2, 2)].abs() < 1e-12);
/// # Ok::<(), zeroset_tensor::TensorError>(())
/// ```
///
/// # Errors
/// [`TensorError::Threshold`] for a negative or non-finite `tau`, [`TensorError::NonFinite`]
/// for a NaN or infinite entry, [`TensorError::Svd`] if the SVD does not converge.
pub fn svt(m: MatRef<'_, f64>, tau: f64) -> Result<(Mat<f64>, usize), TensorError> {
    if !(tau.is_finite() && tau >= 0.0) {
        return Err(TensorError::Threshold { tau });
    }
    check_finite(m)?;
    if let Some(out) = svt_by_gram(m, tau)? {
        return Ok(out);
    }
    svt_by_svd(m, tau)
}

/// [`svt`] by the thin SVD.
fn svt_by_svd(m: MatRef<'_, f64>, tau: f64) -> Result<(Mat<f64>, usize), TensorError> {
    let ThinSvd { u, s, v } = thin_svd(m)?;
    let rank = s.iter().take_while(|&&x| x > tau).count();
    let us = Mat::from_fn(m.nrows(), rank, |i, r| u[(i, r)] * (s[r] - tau));
    Ok((product(us.as_ref(), v.subcols(0, rank).transpose()), rank))
}

/// `A B`, sequential like the SVD: the same bits on every thread count.
fn product(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(out.as_mut(), faer::Accum::Replace, a, b, 1.0, Par::Seq);
    out
}

/// [`svt`] takes the Gram path for matrices at least this many times longer than wide.
const GRAM_ASPECT: usize = 4;
/// … and only while `τ ≥ GRAM_FLOOR · σ₁` (see [`svt_by_gram`]).
const GRAM_FLOOR: f64 = 1e-6;

/// [`svt`] of an elongated matrix through the eigendecomposition of its small Gram matrix:
/// with `A` the matrix or its transpose, whichever is wide (`s × l`, `s ≤ l`),
/// `AAᵀ = U Λ Uᵀ` gives `σᵢ = √λᵢ` and `D_τ(A) = U diag(max(σᵢ − τ, 0)/σᵢ) Uᵀ A` — an
/// `s × s` eigenproblem and two `s × s × l` products instead of the SVD's QR and
/// bidiagonalisation (the unfoldings of an MRAS coefficient tensor are `m × m²`).
///
/// Squaring costs accuracy in the small singular values: `λᵢ` carries an absolute error of
/// about `ε_mach σ₁²`, so `σᵢ` near `τ` is off by about `ε_mach σ₁²/τ` and the output by about
/// `ε_mach σ₁ · σ₁/τ` (a component with `σᵢ` far below or above `τ` is removed or kept with
/// its factor barely changed, whatever its direction's error). Returns `None` — use the SVD —
/// for matrices that are not elongated or when `τ < 10⁻⁶ σ₁`, so that the output stays within
/// about `10⁻¹⁰ σ₁` of the SVD's.
fn svt_by_gram(m: MatRef<'_, f64>, tau: f64) -> Result<Option<(Mat<f64>, usize)>, TensorError> {
    let wide = m.nrows() <= m.ncols();
    let a = if wide { m } else { m.transpose() };
    let (s, l) = (a.nrows(), a.ncols());
    if s == 0 || l < GRAM_ASPECT * s {
        return Ok(None);
    }
    let par = Par::Seq;
    let gram = product(a, a.transpose());
    let mut lambda = faer::diag::Diag::<f64>::zeros(s);
    let mut u = Mat::<f64>::zeros(s, s);
    let mut mem =
        faer::dyn_stack::MemBuffer::new(faer::linalg::evd::self_adjoint_evd_scratch::<f64>(
            s,
            faer::linalg::evd::ComputeEigenvectors::Yes,
            par,
            Default::default(),
        ));
    faer::linalg::evd::self_adjoint_evd(
        gram.as_ref(),
        lambda.as_mut(),
        Some(u.as_mut()),
        par,
        faer::dyn_stack::MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|_| TensorError::Svd)?;
    let sigma: Vec<f64> = (0..s).map(|i| lambda[i].max(0.0).sqrt()).collect();
    let largest = sigma.iter().copied().fold(0.0, f64::max);
    if tau < GRAM_FLOOR * largest {
        return Ok(None);
    }
    let kept: Vec<usize> = (0..s).filter(|&i| sigma[i] > tau).collect();
    let rank = kept.len();
    // W = U_k diag(d), d = (σ − τ)/σ; Y = W (U_kᵀ A).
    let uk = Mat::from_fn(s, rank, |i, r| u[(i, kept[r])]);
    let w = Mat::from_fn(s, rank, |i, r| {
        uk[(i, r)] * (sigma[kept[r]] - tau) / sigma[kept[r]]
    });
    let y = product(w.as_ref(), product(uk.transpose(), a).as_ref());
    Ok(Some((
        if wide { y } else { y.transpose().to_owned() },
        rank,
    )))
}

fn check_finite(m: MatRef<'_, f64>) -> Result<(), TensorError> {
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            if !m[(i, j)].is_finite() {
                return Err(TensorError::NonFinite {
                    index: j * m.nrows() + i,
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Tensor3;

    /// On a diagonal matrix SVT is the closed form: each diagonal entry shrunk towards zero.
    #[test]
    fn svt_matches_the_closed_form_on_diagonal_input() {
        let d = [3.0, -2.5, 1.2, 0.4, 0.0];
        let m = Mat::from_fn(5, 7, |i, j| if i == j { d[i] } else { 0.0 });
        for tau in [0.0, 0.3, 1.0, 2.6, 10.0] {
            let (y, rank) = svt(m.as_ref(), tau).unwrap();
            let expected = Mat::from_fn(5, 7, |i, j| {
                if i == j {
                    d[i].signum() * (d[i].abs() - tau).max(0.0)
                } else {
                    0.0
                }
            });
            assert!((&y - &expected).norm_max() < 1e-12, "tau {tau}");
            assert_eq!(rank, d.iter().filter(|v| v.abs() > tau).count());
        }
    }

    /// SVT satisfies the optimality condition of its problem: `M − Y = τ G` with `G` in the
    /// subdifferential of the trace norm at `Y` (`G = U₁V₁ᵀ + W`, `‖W‖₂ ≤ 1`).
    #[test]
    fn svt_is_the_proximal_operator() {
        let m = Mat::from_fn(6, 9, |i, j| {
            ((i * 5 + j * 3) % 7) as f64 - 3.0 + 0.1 * j as f64
        });
        let sm = thin_svd(m.as_ref()).unwrap().s;
        let tau = 0.5 * (sm[2] + sm[3]);
        let (y, rank) = svt(m.as_ref(), tau).unwrap();
        assert_eq!(rank, 3);
        let g = (&m - &y) * (1.0 / tau);
        let s = thin_svd(g.as_ref()).unwrap().s;
        assert!(
            s[0] <= 1.0 + 1e-10,
            "spectral norm of the subgradient {}",
            s[0]
        );
        // And the trace norm objective is lower than at nearby points.
        let objective =
            |z: &Mat<f64>| tau * trace_norm(z.as_ref()).unwrap() + 0.5 * (z - &m).squared_norm_l2();
        let best = objective(&y);
        for k in 0..5 {
            let e = Mat::from_fn(6, 9, |i, j| 1e-3 * (((i + 2 * j + k) % 5) as f64 - 2.0));
            assert!(objective(&(&y + &e)) >= best - 1e-12);
        }
    }

    /// The Gram path agrees with the SVD on wide and tall matrices of several ranks, for
    /// thresholds between, above and below their singular values; it declines square matrices
    /// and thresholds too small for it.
    #[test]
    fn gram_path_agrees_with_the_svd() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for (rows, cols, rank) in [
            (6, 36, 6),
            (7, 49, 3),
            (11, 121, 11),
            (40, 8, 2),
            (5, 20, 1),
        ] {
            // A rank-`rank` product plus a small full-rank part.
            let p = Mat::from_fn(rows, rank, |_, _| next());
            let q = Mat::from_fn(rank, cols, |_, _| next());
            let noise = Mat::from_fn(rows, cols, |_, _| 1e-3 * next());
            let m = &p * &q + &noise;
            let sv = thin_svd(m.as_ref()).unwrap().s;
            let mut taus = vec![2.0 * sv[0], 1e-5 * sv[0]];
            taus.extend(sv.windows(2).map(|w| 0.5 * (w[0] + w[1])));
            for tau in taus {
                let (want, want_rank) = svt_by_svd(m.as_ref(), tau).unwrap();
                let (got, got_rank) = svt_by_gram(m.as_ref(), tau)
                    .unwrap()
                    .expect("an elongated matrix");
                assert_eq!(got_rank, want_rank, "{rows}×{cols}, τ {tau}");
                let err = (&got - &want).norm_max();
                assert!(err <= 1e-10 * sv[0], "{rows}×{cols}, τ {tau}: {err}");
            }
            assert!(svt_by_gram(m.as_ref(), 1e-9 * sv[0]).unwrap().is_none());
        }
        let square = Mat::from_fn(5, 5, |i, j| (i * 5 + j) as f64);
        assert!(svt_by_gram(square.as_ref(), 1.0).unwrap().is_none());
        let zero = Mat::<f64>::zeros(3, 30);
        let (y, rank) = svt(zero.as_ref(), 0.5).unwrap();
        assert_eq!((rank, y.norm_max()), (0, 0.0));
    }

    #[test]
    fn trace_norm_of_a_rank_one_unfolding_is_its_frobenius_norm() {
        let x = Tensor3::from_fn([3, 4, 5], |i, j, k| {
            (i as f64 + 1.0) * (j as f64 - 1.5) * (k as f64 + 0.5)
        });
        for mode in 0..3 {
            let t = trace_norm(x.unfold(mode).unwrap().as_ref()).unwrap();
            assert!((t - x.frobenius_norm()).abs() < 1e-10 * t);
        }
    }

    #[test]
    fn bad_thresholds_and_entries_are_specific_errors() {
        let mut m = Mat::<f64>::zeros(2, 3);
        assert_eq!(
            svt(m.as_ref(), -1.0).unwrap_err(),
            TensorError::Threshold { tau: -1.0 }
        );
        assert!(matches!(
            svt(m.as_ref(), f64::NAN),
            Err(TensorError::Threshold { .. })
        ));
        m[(1, 2)] = f64::INFINITY;
        assert_eq!(
            trace_norm(m.as_ref()),
            Err(TensorError::NonFinite { index: 5 })
        );
        assert_eq!(
            svt(m.as_ref(), 1.0).unwrap_err(),
            TensorError::NonFinite { index: 5 }
        );
    }
}
