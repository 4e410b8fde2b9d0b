//! The shape of a net and where each parameter lives in the flat parameter vector.

use super::{Activation, NeuralError};

/// Hidden widths above this are refused: the dense layer products grow with the square of the
/// width, and a typo (`--widths 32000`) should be an error rather than an allocation failure.
pub const MAX_WIDTH: usize = 4096;

/// The shape of a multilayer perceptron `Rᴰ → R`: `D` inputs, the hidden widths, one linear
/// output, and the activation of every hidden layer.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Architecture {
    widths: Vec<usize>,
    activation: Activation,
}

impl Architecture {
    /// Hidden layers of `widths` (at least one, each between 1 and [`MAX_WIDTH`]).
    ///
    /// # Errors
    /// [`NeuralError::InvalidWidths`] for no hidden layer, a width of 0, or one above
    /// [`MAX_WIDTH`].
    pub fn new(widths: Vec<usize>, activation: Activation) -> Result<Self, NeuralError> {
        let reason = if widths.is_empty() {
            Some("at least one hidden layer is needed")
        } else if widths.contains(&0) {
            Some("every hidden layer needs at least one neuron")
        } else if widths.iter().any(|&w| w > MAX_WIDTH) {
            Some("a hidden layer is wider than 4096 neurons")
        } else {
            None
        };
        match reason {
            Some(reason) => Err(NeuralError::InvalidWidths { widths, reason }),
            None => Ok(Self { widths, activation }),
        }
    }

    /// The paper's net: two hidden layers of 32 neurons, `tanh`.
    pub fn paper() -> Self {
        Self {
            widths: vec![32, 32],
            activation: Activation::Tanh,
        }
    }

    /// The hidden widths.
    pub fn widths(&self) -> &[usize] {
        &self.widths
    }

    /// The activation of the hidden layers.
    pub fn activation(&self) -> Activation {
        self.activation
    }

    /// The number of trainable parameters of the net with `inputs` inputs.
    pub fn num_parameters(&self, inputs: usize) -> usize {
        Layout::new(inputs, &self.widths).total
    }
}

impl Default for Architecture {
    fn default() -> Self {
        Self::paper()
    }
}

/// Offsets of the layers in the flat parameter vector. Layer `l` (0-based, the last one the
/// output) maps `dims[l]` inputs to `dims[l + 1]` outputs; its weight matrix is stored column
/// by column (`W[j, k]` at `weight[l] + j + dims[l+1]·k`), followed by its bias.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Layout {
    /// `[D, w₁, …, w_L, 1]`.
    pub dims: Vec<usize>,
    /// Where each layer's weights start.
    pub weight: Vec<usize>,
    /// Where each layer's biases start.
    pub bias: Vec<usize>,
    /// The parameter count.
    pub total: usize,
}

impl Layout {
    pub fn new(inputs: usize, widths: &[usize]) -> Self {
        let mut dims = Vec::with_capacity(widths.len() + 2);
        dims.push(inputs);
        dims.extend_from_slice(widths);
        dims.push(1);
        let mut weight = Vec::with_capacity(dims.len() - 1);
        let mut bias = Vec::with_capacity(dims.len() - 1);
        let mut at = 0;
        for l in 0..dims.len() - 1 {
            weight.push(at);
            at += dims[l] * dims[l + 1];
            bias.push(at);
            at += dims[l + 1];
        }
        Self {
            dims,
            weight,
            bias,
            total: at,
        }
    }

    /// The number of layers with parameters (hidden layers + the output).
    pub fn layers(&self) -> usize {
        self.dims.len() - 1
    }

    /// The number of hidden layers.
    pub fn hidden(&self) -> usize {
        self.dims.len() - 2
    }

    /// Layer `l`'s weight matrix (`dims[l+1] × dims[l]`, column-major) in `params`.
    pub fn weight<'a>(&self, params: &'a [f64], l: usize) -> &'a [f64] {
        &params[self.weight[l]..self.bias[l]]
    }

    /// Layer `l`'s bias in `params`.
    pub fn bias<'a>(&self, params: &'a [f64], l: usize) -> &'a [f64] {
        &params[self.bias[l]..self.bias[l] + self.dims[l + 1]]
    }

    /// The widest layer (inputs excluded).
    pub fn max_width(&self) -> usize {
        self.dims[1..].iter().copied().max().unwrap_or(1)
    }
}

/// The packed second derivatives `(k, l)`, `k ≤ l`, in the order every Hessian is stored:
/// `(0,0), (0,1), …, (0,D−1), (1,1), …, (D−1,D−1)`.
pub(crate) fn pairs(d: usize) -> Vec<(usize, usize)> {
    (0..d).flat_map(|k| (k..d).map(move |l| (k, l))).collect()
}

/// The packed index of `(k, l)` (either order) in [`pairs`].
pub(crate) fn pair_index(d: usize, k: usize, l: usize) -> usize {
    let (k, l) = if k <= l { (k, l) } else { (l, k) };
    // Pairs before row k: d + (d−1) + … + (d−k+1) = k·d − k(k−1)/2.
    k * d - k * k.saturating_sub(1) / 2 + (l - k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_of_the_paper_net() {
        let l = Layout::new(2, &[32, 32]);
        assert_eq!(l.dims, vec![2, 32, 32, 1]);
        assert_eq!(l.total, 2 * 32 + 32 + 32 * 32 + 32 + 32 + 1);
        assert_eq!(Architecture::paper().num_parameters(2), 1185);
        assert_eq!(l.weight, vec![0, 96, 1152]);
        assert_eq!(l.bias, vec![64, 1120, 1184]);
        assert_eq!((l.layers(), l.hidden(), l.max_width()), (3, 2, 32));
    }

    #[test]
    fn pairs_are_indexed_consistently() {
        for d in 1..=4 {
            for (q, &(k, l)) in pairs(d).iter().enumerate() {
                assert_eq!(pair_index(d, k, l), q, "d={d} ({k},{l})");
                assert_eq!(pair_index(d, l, k), q);
            }
            assert_eq!(pairs(d).len(), d * (d + 1) / 2);
        }
    }

    #[test]
    fn bad_widths_are_refused() {
        for w in [vec![], vec![32, 0], vec![5000]] {
            let e = Architecture::new(w, Activation::Tanh).unwrap_err();
            assert!(matches!(e, NeuralError::InvalidWidths { .. }), "{e}");
        }
        assert!(Architecture::new(vec![1], Activation::Softplus).is_ok());
    }
}
