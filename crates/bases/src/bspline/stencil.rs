//! Per-axis B-spline weights and the mirror folding of coefficient indices — the one place where
//! the kernels `β²` and `β³` are written down; evaluation, the sparse basis rows and the tests'
//! finite-difference checks all go through [`weights`].

use super::Boundary;

/// The `K` B-splines that may be non-zero at a continuous index `x` (`K` = 3 quadratic, 4 cubic):
/// B-spline `first + k` has value `w[k]`, first derivative `d1[k]` and second derivative
/// `d2[k]`, all with respect to the index (divide by the spacing for world units).
#[derive(Debug, Clone, Copy)]
pub(crate) struct AxisWeights<const K: usize> {
    /// Index of the first B-spline (may be negative or `≥ n`: fold it with [`fold`]).
    pub first: isize,
    /// `β(x − first − k)`.
    pub w: [f64; K],
    /// `β′(x − first − k)`.
    pub d1: [f64; K],
    /// `β″(x − first − k)`.
    pub d2: [f64; K],
}

/// The weights at the continuous index `x` for `K` = 3 (quadratic) or `K` = 4 (cubic).
///
/// Quadratic: `i = ⌊x + ½⌋`, `t = x − i ∈ [−½, ½)`, B-splines `i−1, i, i+1` with
/// `((½ − t)²/2, ¾ − t², (½ + t)²/2)`; at a half-integer (a knot) the right-hand piece is used,
/// which matters only for the (discontinuous) second derivative.
/// Cubic: `i = ⌊x⌋`, `t = x − i ∈ [0, 1)`, `s = 1 − t`, B-splines `i−1 … i+2` with
/// `(s³/6, ⅔ − t² + t³/2, ⅔ − s² + s³/2, t³/6)`.
///
/// Requires `x ≥ −1` (callers clamp indices to the grid's box, `x ≥ −½`), so that `⌊·⌋` is a
/// truncation; NaN gives NaN weights.
#[inline(always)]
pub(crate) fn weights<const K: usize>(x: f64) -> AxisWeights<K> {
    debug_assert!(x.is_nan() || x >= -1.0, "weights: index {x} below −1");
    let mut out = AxisWeights {
        first: 0,
        w: [0.0; K],
        d1: [0.0; K],
        d2: [0.0; K],
    };
    if K == 3 {
        // ⌊x + ½⌋ = trunc(x + 3/2) − 1 for x ≥ −3/2 (one float-to-int conversion).
        let i = (x + 1.5) as isize - 1;
        let t = x - i as f64;
        let (l, r) = (0.5 - t, 0.5 + t);
        out.first = i - 1;
        out.w
            .copy_from_slice(&[0.5 * l * l, 0.75 - t * t, 0.5 * r * r]);
        out.d1.copy_from_slice(&[-l, -2.0 * t, r]);
        out.d2.copy_from_slice(&[1.0, -2.0, 1.0]);
    } else {
        debug_assert_eq!(K, 4, "only quadratic (K = 3) and cubic (K = 4) B-splines");
        // ⌊x⌋ = trunc(x + 1) − 1 for x ≥ −1.
        let i = (x + 1.0) as isize - 1;
        let t = x - i as f64;
        let s = 1.0 - t;
        out.first = i - 1;
        out.w.copy_from_slice(&[
            s * s * s / 6.0,
            2.0 / 3.0 - t * t * (1.0 - 0.5 * t),
            2.0 / 3.0 - s * s * (1.0 - 0.5 * s),
            t * t * t / 6.0,
        ]);
        out.d1.copy_from_slice(&[
            -0.5 * s * s,
            t * (1.5 * t - 2.0),
            s * (2.0 - 1.5 * s),
            0.5 * t * t,
        ]);
        out.d2
            .copy_from_slice(&[s, 3.0 * t - 2.0, 3.0 * s - 2.0, t]);
    }
    out
}

/// Folds a coefficient index into `[0, n)` by the mirror rule of `boundary`:
/// half-sample `c₋₁ = c₀, c_n = c_{n−1}` (period `2n`), whole-sample `c₋₁ = c₁,
/// c_n = c_{n−2}` (period `2n − 2`; everything folds to 0 when `n = 1`).
#[inline(always)]
pub(crate) fn fold(k: isize, n: usize, boundary: Boundary) -> usize {
    let ni = n as isize;
    if k >= 0 && k < ni {
        return k as usize;
    }
    match boundary {
        Boundary::HalfSample => {
            let m = k.rem_euclid(2 * ni);
            (if m >= ni { 2 * ni - 1 - m } else { m }) as usize
        }
        Boundary::WholeSample => {
            if n == 1 {
                return 0;
            }
            let period = 2 * ni - 2;
            let m = k.rem_euclid(period);
            (if m >= ni { period - m } else { m }) as usize
        }
    }
}

/// Row-major (last axis fastest) strides of a shape.
pub(crate) fn strides<const D: usize>(shape: [usize; D]) -> [usize; D] {
    let mut s = [1; D];
    for a in (0..D.saturating_sub(1)).rev() {
        s[a] = s[a + 1] * shape[a + 1];
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quadratic and cubic B-splines, straight from their piecewise definitions.
    fn beta(k: usize, t: f64) -> f64 {
        let a = t.abs();
        match k {
            3 => {
                if a <= 0.5 {
                    0.75 - a * a
                } else if a < 1.5 {
                    0.5 * (1.5 - a) * (1.5 - a)
                } else {
                    0.0
                }
            }
            _ => {
                if a <= 1.0 {
                    2.0 / 3.0 - a * a + 0.5 * a * a * a
                } else if a < 2.0 {
                    (2.0 - a).powi(3) / 6.0
                } else {
                    0.0
                }
            }
        }
    }

    fn check<const K: usize>() {
        for step in 0..=400 {
            let x = -1.0 + step as f64 * 0.01 + 1e-3;
            let aw = weights::<K>(x);
            assert!((aw.w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
            assert!(aw.d1.iter().sum::<f64>().abs() < 1e-14);
            assert!(aw.d2.iter().sum::<f64>().abs() < 1e-14);
            for k in 0..K {
                let t = x - (aw.first + k as isize) as f64;
                assert!((aw.w[k] - beta(K, t)).abs() < 1e-15, "K={K} x={x} k={k}");
                let h = 1e-6;
                let fd = (beta(K, t + h) - beta(K, t - h)) / (2.0 * h);
                assert!((aw.d1[k] - fd).abs() < 1e-8, "K={K} x={x} k={k}");
                let fd1 = (weights::<K>(x + h).d1[k] - weights::<K>(x - h).d1[k]) / (2.0 * h);
                if weights::<K>(x + h).first == aw.first && weights::<K>(x - h).first == aw.first {
                    assert!((aw.d2[k] - fd1).abs() < 1e-7, "K={K} x={x} k={k}");
                }
            }
        }
    }

    #[test]
    fn weights_match_the_piecewise_kernels_and_their_derivatives() {
        check::<3>();
        check::<4>();
    }

    #[test]
    fn sampled_kernels_are_one_eighth_and_one_sixth() {
        let q = weights::<3>(5.0);
        assert_eq!((q.first, q.w), (4, [0.125, 0.75, 0.125]));
        let c = weights::<4>(5.0);
        assert_eq!(c.first, 4);
        assert!((c.w[0] - 1.0 / 6.0).abs() < 1e-16 && (c.w[1] - 4.0 / 6.0).abs() < 1e-16);
        assert!((c.w[2] - 1.0 / 6.0).abs() < 1e-16 && c.w[3] == 0.0);
    }

    #[test]
    fn folding_mirrors_about_the_half_or_the_end_sample() {
        let half: Vec<usize> = (-4..8).map(|k| fold(k, 3, Boundary::HalfSample)).collect();
        assert_eq!(half, [2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0, 1]);
        let whole: Vec<usize> = (-4..8).map(|k| fold(k, 3, Boundary::WholeSample)).collect();
        assert_eq!(whole, [0, 1, 2, 1, 0, 1, 2, 1, 0, 1, 2, 1]);
        for k in -5..5 {
            assert_eq!(fold(k, 1, Boundary::HalfSample), 0);
            assert_eq!(fold(k, 1, Boundary::WholeSample), 0);
        }
    }

    #[test]
    fn strides_are_c_order() {
        assert_eq!(strides([5, 7, 3]), [21, 3, 1]);
        assert_eq!(strides([4]), [1]);
    }
}
