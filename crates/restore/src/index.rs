//! Last-axis-fastest index arithmetic on boxes of cells.

/// Strides of a last-axis-fastest array of `dims`.
pub(crate) fn strides<const D: usize>(dims: &[usize; D]) -> [usize; D] {
    let mut s = [1; D];
    for a in (0..D.saturating_sub(1)).rev() {
        s[a] = s[a + 1] * dims[a + 1];
    }
    s
}

/// The multi-index of linear index `l` in a last-axis-fastest box of `dims`.
pub(crate) fn multi_index<const D: usize>(mut l: usize, dims: &[usize; D]) -> [usize; D] {
    let mut index = [0; D];
    for a in (0..D).rev() {
        index[a] = l % dims[a];
        l /= dims[a];
    }
    index
}

/// The linear index of `index` under `strides`.
pub(crate) fn linear<const D: usize>(index: [usize; D], strides: &[usize; D]) -> usize {
    index.iter().zip(strides).map(|(i, s)| i * s).sum()
}
