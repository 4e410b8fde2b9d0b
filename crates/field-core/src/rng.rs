//! Seeded random numbers: the one generator zeroset's library code, tests, examples and
//! benches draw from, so that every "random" choice (initial CP factors, randomised SVD
//! sketches, error samples, test data, fuzz mutations) is reproducible from its seed.
//!
//! [`SplitMix64`] (Steele, Lea and Flood, "Fast splittable pseudorandom number generators",
//! OOPSLA 2014) passes BigCrush, has a 2⁶⁴ period, one `u64` of state and no
//! dependencies; it is not cryptographic. Floating-point values take the top 53 bits, so
//! [`SplitMix64::unit`] is exactly uniform on the multiples of 2⁻⁵³ in `[0, 1)`.
//!
//! ```
//! use zeroset_field_core::rng::SplitMix64;
//!
//! let mut a = SplitMix64::new(7);
//! let mut b = SplitMix64::new(7);
//! let x: Vec<f64> = (0..3).map(|_| a.unit()).collect();
//! assert_eq!(x, (0..3).map(|_| b.unit()).collect::<Vec<_>>());
//! assert!(x.iter().all(|v| (0.0..1.0).contains(v)));
//! let mut order = [0, 1, 2, 3, 4];
//! a.shuffle(&mut order);
//! order.sort();
//! assert_eq!(order, [0, 1, 2, 3, 4]);
//! ```

/// SplitMix64: a seeded stream of 64-bit values, and uniform, normal and index draws from it.
/// The state is public so that a generator can be written as `SplitMix64(seed)`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The stream with this seed.
    pub const fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Standard normal: Box–Muller on a uniform in `(0, 1)` and one in `[0, 1)`.
    pub fn normal(&mut self) -> f64 {
        let u = ((self.next_u64() >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64);
        let v = self.unit();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// Uniform in `0..n` (multiply-shift, bias below `n / 2⁶⁴`); 0 when `n` is 0.
    pub fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.next_u64()) * n as u128) >> 64) as usize
    }

    /// Shuffles `items` in place (Fisher–Yates).
    pub fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            let j = self.below(i + 1);
            items.swap(i, j);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reference_stream() {
        // The first outputs for seed 1234567 of the authors' C reference (splitmix64.c).
        let mut g = SplitMix64::new(1_234_567);
        assert_eq!(g.next_u64(), 6_457_827_717_110_365_317);
        assert_eq!(g.next_u64(), 3_203_168_211_198_807_973);
        assert_eq!(g.next_u64(), 9_817_491_932_198_370_423);
    }

    #[test]
    fn draws_are_in_range_and_moments_are_right() {
        let mut g = SplitMix64::new(3);
        let n = 200_000;
        let (mut sum, mut sq) = (0.0, 0.0);
        for _ in 0..n {
            let u = g.unit();
            assert!((0.0..1.0).contains(&u));
            let z = g.normal();
            assert!(z.is_finite());
            sum += z;
            sq += z * z;
            assert!(g.below(7) < 7);
            let x = g.uniform(-2.0, 3.0);
            assert!((-2.0..3.0).contains(&x));
        }
        let mean = sum / f64::from(n);
        let var = sq / f64::from(n) - mean * mean;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.02, "{var}");
        assert_eq!(g.below(0), 0);
    }

    #[test]
    fn shuffle_is_a_seeded_permutation() {
        let mut a: Vec<usize> = (0..100).collect();
        let mut b = a.clone();
        SplitMix64::new(9).shuffle(&mut a);
        SplitMix64::new(9).shuffle(&mut b);
        assert_eq!(a, b);
        assert_ne!(a, (0..100).collect::<Vec<_>>());
        a.sort_unstable();
        assert_eq!(a, (0..100).collect::<Vec<_>>());
    }
}
