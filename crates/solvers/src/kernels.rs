//! Deterministic parallel kernels: the same bits for 1 or N threads.
//!
//! Reductions split vectors into fixed blocks of [`BLOCK`] elements, sum each block
//! sequentially (in parallel across blocks), then add the block sums in order. The grouping
//! depends only on the length, never on the thread count. Matrix products are gathers (each
//! output element summed sequentially in storage order), so they need no reduction at all.

use rayon::prelude::*;

/// Elements per reduction block.
pub const BLOCK: usize = 4096;

/// `Σ aᵢ bᵢ`, deterministic.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    if a.len() <= BLOCK {
        return a.iter().zip(b).map(|(x, y)| x * y).sum();
    }
    let partial: Vec<f64> = a
        .par_chunks(BLOCK)
        .zip(b.par_chunks(BLOCK))
        .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p * q).sum())
        .collect();
    partial.iter().sum()
}

/// `‖a‖₂`, deterministic. Scaled against overflow only where it matters (values beyond 1e150).
pub fn norm2(a: &[f64]) -> f64 {
    let s = dot(a, a);
    if s.is_finite() && s > 1e-290 {
        return s.sqrt();
    }
    let scale = a.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return scale;
    }
    let scaled: Vec<f64> = a.iter().map(|x| x / scale).collect();
    scale * dot(&scaled, &scaled).sqrt()
}

/// `max_i |aᵢ − bᵢ|`: how far two solutions are apart (0 for empty slices).
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// `y ← y + α x`.
pub fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    y.par_chunks_mut(BLOCK)
        .zip(x.par_chunks(BLOCK))
        .for_each(|(ys, xs)| ys.iter_mut().zip(xs).for_each(|(y, x)| *y += alpha * x));
}

/// `y ← x + β y`.
pub fn xpby(x: &[f64], beta: f64, y: &mut [f64]) {
    y.par_chunks_mut(BLOCK)
        .zip(x.par_chunks(BLOCK))
        .for_each(|(ys, xs)| ys.iter_mut().zip(xs).for_each(|(y, x)| *y = x + beta * *y));
}

/// `x ← α x`.
pub fn scale(alpha: f64, x: &mut [f64]) {
    x.par_chunks_mut(BLOCK)
        .for_each(|xs| xs.iter_mut().for_each(|v| *v *= alpha));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reductions_do_not_depend_on_the_thread_count() {
        let a: Vec<f64> = (0..100_003)
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-3 - 0.5)
            .collect();
        let many = dot(&a, &a);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| dot(&a, &a));
        assert_eq!(many.to_bits(), one.to_bits());
        assert!((norm2(&a) - many.sqrt()).abs() < 1e-12 * many.sqrt());
        assert!((norm2(&[3e-200, 4e-200]) / 5e-200 - 1.0).abs() < 1e-15);
        assert!((norm2(&[3e200, 4e200]) / 5e200 - 1.0).abs() < 1e-15);
    }
}
