//! A tiny seeded generator shared by the examples, so that data is reproducible without extra
//! crates.

/// SplitMix64: a tiny seeded generator, so that the data is reproducible without extra crates.
pub struct SplitMix64(pub u64);

impl SplitMix64 {
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
}

impl SplitMix64 {
    /// Standard normal (Box–Muller on two uniforms in `(0, 1)`).
    #[allow(dead_code)] // not every example draws normals
    pub fn normal(&mut self) -> f64 {
        let u = (self.next_u64() >> 11) as f64 + 0.5;
        let v = self.unit();
        (-2.0 * (u / (1u64 << 53) as f64).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// A planted rank-`rank` tensor: standard normal factors (weights 1) plus Gaussian noise with
/// `‖noise‖ = noise · ‖X‖`, seeded.
#[allow(dead_code)]
pub fn planted_tensor(
    shape: [usize; 3],
    rank: usize,
    noise: f64,
    seed: u64,
) -> Result<zeroset::tensor::Tensor3, zeroset::tensor::TensorError> {
    let mut g = SplitMix64(seed);
    let factors = std::array::from_fn(|n| faer::Mat::from_fn(shape[n], rank, |_, _| g.normal()));
    let mut x = zeroset::tensor::Kruskal::new(vec![1.0; rank], factors)?.to_tensor();
    let e: Vec<f64> = (0..x.len()).map(|_| g.normal()).collect();
    let scale = noise * x.frobenius_norm() / e.iter().map(|v| v * v).sum::<f64>().sqrt();
    for (v, e) in x.as_mut_slice().iter_mut().zip(&e) {
        *v += scale * e;
    }
    Ok(x)
}
