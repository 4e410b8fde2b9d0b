//! The dense 3-way tensor, its unfoldings and products (see the crate docs for the maths).

use faer::{Mat, MatRef};
use ndarray::Array3;

use crate::TensorError;

/// A dense `I₀ × I₁ × I₂` tensor of `f64`, row-major (`i₂` fastest), as an `ndarray::Array3` in
/// standard layout. Extents may be zero (an empty tensor); the algorithms that need entries say
/// so with [`TensorError::EmptyShape`].
#[derive(Debug, Clone, PartialEq)]
pub struct Tensor3 {
    shape: [usize; 3],
    data: Vec<f64>,
}

/// `I₀ I₁ I₂`, or `None` where it overflows `usize`.
fn entries(shape: [usize; 3]) -> Option<usize> {
    shape.iter().try_fold(1usize, |a, &n| a.checked_mul(n))
}

fn entries_or_panic(shape: [usize; 3]) -> usize {
    entries(shape)
        .unwrap_or_else(|| panic!("a tensor of shape {shape:?} has more entries than usize holds"))
}

impl Tensor3 {
    /// The tensor of `shape` whose row-major entries are `data`.
    ///
    /// # Errors
    /// [`TensorError::Length`] if `data` has not `I₀ I₁ I₂` entries (or that product overflows
    /// `usize`).
    pub fn new(shape: [usize; 3], data: Vec<f64>) -> Result<Self, TensorError> {
        if entries(shape) != Some(data.len()) {
            return Err(TensorError::Length {
                shape,
                len: data.len(),
            });
        }
        Ok(Self { shape, data })
    }

    /// The tensor of `shape` with row-major `data`, whose length the caller guarantees.
    pub(crate) fn from_row_major(shape: [usize; 3], data: Vec<f64>) -> Self {
        debug_assert_eq!(data.len(), shape.iter().product::<usize>());
        Self { shape, data }
    }

    /// The zero tensor of `shape`.
    ///
    /// # Panics
    /// If `I₀ I₁ I₂` overflows `usize` (as `vec!` does when memory runs out).
    pub fn zeros(shape: [usize; 3]) -> Self {
        Self {
            shape,
            data: vec![0.0; entries_or_panic(shape)],
        }
    }

    /// The tensor with entries `f(i₀, i₁, i₂)`.
    ///
    /// # Panics
    /// If `I₀ I₁ I₂` overflows `usize` (as `Vec::with_capacity` does when memory runs out).
    pub fn from_fn(shape: [usize; 3], mut f: impl FnMut(usize, usize, usize) -> f64) -> Self {
        let mut data = Vec::with_capacity(entries_or_panic(shape));
        for i in 0..shape[0] {
            for j in 0..shape[1] {
                for k in 0..shape[2] {
                    data.push(f(i, j, k));
                }
            }
        }
        Self { shape, data }
    }

    /// A copy of `a` (any memory layout).
    pub fn from_ndarray(a: &Array3<f64>) -> Self {
        let (i, j, k) = a.dim();
        Self {
            shape: [i, j, k],
            data: a.iter().copied().collect(),
        }
    }

    /// A copy as an `ndarray::Array3` in standard layout.
    pub fn to_ndarray(&self) -> Array3<f64> {
        let [i, j, k] = self.shape;
        Array3::from_shape_fn((i, j, k), |(a, b, c)| self[[a, b, c]])
    }

    /// The extents `[I₀, I₁, I₂]`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// The number of entries.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether some extent is zero.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// The entries in row-major order.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }

    /// The entries in row-major order, to modify.
    pub fn as_mut_slice(&mut self) -> &mut [f64] {
        &mut self.data
    }

    /// The Frobenius norm `√Σ x²`.
    pub fn frobenius_norm(&self) -> f64 {
        self.data.iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// [`TensorError::NonFinite`] for the first NaN or infinite entry.
    ///
    /// # Errors
    /// As said.
    pub fn check_finite(&self) -> Result<(), TensorError> {
        match self.data.iter().position(|v| !v.is_finite()) {
            Some(index) => Err(TensorError::NonFinite { index }),
            None => Ok(()),
        }
    }

    /// The row and column of entry `(i₀, i₁, i₂)` in the mode-`mode` unfolding.
    fn unfolded_index(shape: [usize; 3], mode: usize, idx: [usize; 3]) -> (usize, usize) {
        let [a, b] = others(mode);
        (idx[mode], idx[a] + shape[a] * idx[b])
    }

    /// The mode-`mode` unfolding `X₍ₙ₎` (`Iₙ × ∏_{m≠n} I_m`, Kolda–Bader column order).
    ///
    /// # Errors
    /// [`TensorError::Mode`] for `mode > 2`.
    pub fn unfold(&self, mode: usize) -> Result<Mat<f64>, TensorError> {
        check_mode(mode)?;
        let [a, b] = others(mode);
        let s = self.shape;
        let mut m = Mat::zeros(s[mode], s[a] * s[b]);
        let mut values = self.data.iter();
        for i in 0..s[0] {
            for j in 0..s[1] {
                for k in 0..s[2] {
                    let (r, c) = Self::unfolded_index(s, mode, [i, j, k]);
                    if let Some(&v) = values.next() {
                        m[(r, c)] = v;
                    }
                }
            }
        }
        Ok(m)
    }

    /// The tensor of `shape` whose mode-`mode` unfolding is `m`: the inverse of
    /// [`Tensor3::unfold`].
    ///
    /// # Errors
    /// [`TensorError::Mode`] for `mode > 2`, [`TensorError::Dimensions`] if `m` is not
    /// `Iₙ × ∏_{m≠n} I_m`.
    pub fn fold(mode: usize, m: &Mat<f64>, shape: [usize; 3]) -> Result<Self, TensorError> {
        check_mode(mode)?;
        let [a, b] = others(mode);
        let expected = (shape[mode], shape[a] * shape[b]);
        if (m.nrows(), m.ncols()) != expected {
            return Err(TensorError::Dimensions {
                what: "fold: the unfolding",
                expected,
                got: (m.nrows(), m.ncols()),
            });
        }
        Ok(Self::from_fn(shape, |i, j, k| {
            let (r, c) = Self::unfolded_index(shape, mode, [i, j, k]);
            m[(r, c)]
        }))
    }

    /// The n-mode product `X ×ₙ U` (`U`: `J × Iₙ`), the tensor with `Iₙ` replaced by `J` and
    /// `(X ×ₙ U)₍ₙ₎ = U X₍ₙ₎`.
    ///
    /// # Errors
    /// [`TensorError::Mode`] for `mode > 2`, [`TensorError::Dimensions`] if `U` has not `Iₙ`
    /// columns.
    pub fn mode_product(&self, mode: usize, u: MatRef<'_, f64>) -> Result<Self, TensorError> {
        check_mode(mode)?;
        if u.ncols() != self.shape[mode] {
            return Err(TensorError::Dimensions {
                what: "mode_product: the matrix",
                expected: (usize::MAX, self.shape[mode]),
                got: (u.nrows(), u.ncols()),
            });
        }
        let unfolded = self.unfold(mode)?;
        let product = u * &unfolded;
        let mut shape = self.shape;
        shape[mode] = u.nrows();
        Self::fold(mode, &product, shape)
    }
}

impl std::ops::Index<[usize; 3]> for Tensor3 {
    type Output = f64;

    fn index(&self, [i, j, k]: [usize; 3]) -> &f64 {
        &self.data[(i * self.shape[1] + j) * self.shape[2] + k]
    }
}

impl std::ops::IndexMut<[usize; 3]> for Tensor3 {
    fn index_mut(&mut self, [i, j, k]: [usize; 3]) -> &mut f64 {
        &mut self.data[(i * self.shape[1] + j) * self.shape[2] + k]
    }
}

/// The two modes other than `mode`, in increasing order.
fn others(mode: usize) -> [usize; 2] {
    match mode {
        0 => [1, 2],
        1 => [0, 2],
        _ => [0, 1],
    }
}

fn check_mode(mode: usize) -> Result<(), TensorError> {
    if mode > 2 {
        return Err(TensorError::Mode { mode });
    }
    Ok(())
}

/// The Khatri–Rao product `C ⊙ B` (columnwise Kronecker): `(K J) × R` with entry
/// `(k J + j, r) = C[k, r] B[j, r]`, the second factor's index running fastest, matching the
/// unfoldings ([`Tensor3::unfold`]).
///
/// # Errors
/// [`TensorError::Dimensions`] if the factors have different column counts.
pub fn khatri_rao(c: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Result<Mat<f64>, TensorError> {
    if c.ncols() != b.ncols() {
        return Err(TensorError::Dimensions {
            what: "khatri_rao: the second factor",
            expected: (usize::MAX, c.ncols()),
            got: (b.nrows(), b.ncols()),
        });
    }
    Ok(khatri_rao_unchecked(c, b))
}

/// [`khatri_rao`] for factors known to have the same column count.
pub(crate) fn khatri_rao_unchecked(c: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let (j, k) = (b.nrows(), c.nrows());
    let mut out = Mat::<f64>::zeros(k * j, c.ncols());
    for r in 0..c.ncols() {
        let (bc, cc) = (b.col(r), c.col(r));
        let col = out.col_as_slice_mut(r);
        for kk in 0..k {
            let ck = cc[kk];
            for jj in 0..j {
                col[kk * j + jj] = ck * bc[jj];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn shape_and_data() -> impl Strategy<Value = ([usize; 3], Vec<f64>)> {
        (1usize..5, 1usize..5, 1usize..5).prop_flat_map(|(i, j, k)| {
            (
                Just([i, j, k]),
                proptest::collection::vec(-10.0..10.0f64, i * j * k),
            )
        })
    }

    proptest! {
        #[test]
        fn fold_after_unfold_is_the_identity((shape, data) in shape_and_data(), mode in 0usize..3) {
            let x = Tensor3::new(shape, data).unwrap();
            let m = x.unfold(mode).unwrap();
            prop_assert_eq!(Tensor3::fold(mode, &m, shape).unwrap(), x.clone());
            prop_assert_eq!(Tensor3::from_ndarray(&x.to_ndarray()), x);
        }

        #[test]
        fn kruskal_unfoldings_are_khatri_rao_products(
            (shape, _) in shape_and_data(),
            rank in 1usize..4,
            seed in 0u64..1000,
        ) {
            let f = |rows: usize, salt: u64| {
                Mat::from_fn(rows, rank, |i, r| {
                    (((i * 7 + r * 13) as u64 + seed * salt) % 17) as f64 / 8.0 - 1.0
                })
            };
            let (a, b, c) = (f(shape[0], 3), f(shape[1], 5), f(shape[2], 11));
            let x = Tensor3::from_fn(shape, |i, j, k| {
                (0..rank).map(|r| a[(i, r)] * b[(j, r)] * c[(k, r)]).sum()
            });
            let checks = [
                (0, &a, khatri_rao(c.as_ref(), b.as_ref()).unwrap()),
                (1, &b, khatri_rao(c.as_ref(), a.as_ref()).unwrap()),
                (2, &c, khatri_rao(b.as_ref(), a.as_ref()).unwrap()),
            ];
            for (mode, factor, kr) in checks {
                let expected = factor * kr.transpose();
                let got = x.unfold(mode).unwrap();
                prop_assert!((&got - &expected).norm_max() < 1e-12);
            }
        }
    }

    #[test]
    fn mode_product_multiplies_every_fibre() {
        let x = Tensor3::from_fn([2, 3, 4], |i, j, k| (i + 2 * j) as f64 - 0.5 * k as f64);
        let u = Mat::from_fn(5, 3, |r, c| (r * 3 + c) as f64 * 0.1);
        let y = x.mode_product(1, u.as_ref()).unwrap();
        assert_eq!(y.shape(), [2, 5, 4]);
        for i in 0..2 {
            for r in 0..5 {
                for k in 0..4 {
                    let expected: f64 = (0..3).map(|j| u[(r, j)] * x[[i, j, k]]).sum();
                    assert!((y[[i, r, k]] - expected).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn bad_shapes_and_modes_are_specific_errors() {
        assert_eq!(
            Tensor3::new([2, 2, 2], vec![0.0; 7]),
            Err(TensorError::Length {
                shape: [2, 2, 2],
                len: 7
            })
        );
        let x = Tensor3::zeros([2, 3, 4]);
        assert_eq!(x.unfold(3), Err(TensorError::Mode { mode: 3 }));
        let m = x.unfold(0).unwrap();
        assert!(matches!(
            Tensor3::fold(1, &m, [2, 3, 4]),
            Err(TensorError::Dimensions { .. })
        ));
        let u = Mat::<f64>::zeros(2, 2);
        assert!(matches!(
            x.mode_product(2, u.as_ref()),
            Err(TensorError::Dimensions { .. })
        ));
        assert!(matches!(
            khatri_rao(u.as_ref(), Mat::<f64>::zeros(3, 3).as_ref()),
            Err(TensorError::Dimensions { .. })
        ));
        let mut y = Tensor3::zeros([1, 2, 2]);
        y[[0, 1, 0]] = f64::NAN;
        assert_eq!(y.check_finite(), Err(TensorError::NonFinite { index: 2 }));
        assert!(Tensor3::zeros([0, 3, 3]).is_empty());
    }
}
