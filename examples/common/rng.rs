//! The seeded generator the examples and benches draw from: the library's one
//! ([`zeroset::core::rng::SplitMix64`]), and planted tensors ([`zeroset::tensor::planted`]).

#[allow(unused_imports)] // not every example draws from it directly
pub use zeroset::core::rng::SplitMix64;

/// A planted rank-`rank` tensor: standard normal factors (weights 1) plus Gaussian noise with
/// `‖noise‖ = noise · ‖X‖`, seeded.
#[allow(dead_code)]
pub fn planted_tensor(
    shape: [usize; 3],
    rank: usize,
    noise: f64,
    seed: u64,
) -> Result<zeroset::tensor::Tensor3, zeroset::tensor::TensorError> {
    Ok(zeroset::tensor::planted(shape, rank, noise, seed)?.1)
}
