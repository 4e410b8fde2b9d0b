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
/// every thread count).
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
    let ThinSvd { u, s, v } = thin_svd(m)?;
    let rank = s.iter().take_while(|&&x| x > tau).count();
    let us = Mat::from_fn(m.nrows(), rank, |i, r| u[(i, r)] * (s[r] - tau));
    let mut y = Mat::zeros(m.nrows(), m.ncols());
    // Sequential, like the SVD: the same bits on every thread count.
    faer::linalg::matmul::matmul(
        y.as_mut(),
        faer::Accum::Replace,
        us.as_ref(),
        v.subcols(0, rank).transpose(),
        1.0,
        Par::Seq,
    );
    Ok((y, rank))
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
