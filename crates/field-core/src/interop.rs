//! Zero-copy bridges to ndarray, faer and sprs.
//!
//! | from | to | copy? |
//! |---|---|---|
//! | grid samples `&[f64]` | `ndarray::ArrayView3` / `ArrayViewD` indexed `[i, j, k]` | no (C order = last axis fastest) |
//! | `ndarray::ArrayView2<f64>` | [`LsqMatrix::Dense`] | no (strides carried over) |
//! | `faer::Mat`, `SparseColMat`, `SparseRowMat` | [`LsqMatrix`] | no |
//! | `&sprs::CsMatI<f64, usize>` (CSR or CSC) | [`LsqMatrix`] | no; checked |
//!
//! ```
//! use zeroset_field_core::geometry::Aabb;
//! use zeroset_field_core::grid::Grid;
//! use zeroset_field_core::interop::view3;
//!
//! let g = Grid::cell_centered(Aabb::centered_cube(1.0)?, [2, 3, 4])?;
//! let values: Vec<f64> = (0..g.len()).map(|l| l as f64).collect();
//! let a = view3(&g, &values)?;
//! assert_eq!(a[[1, 2, 3]], values[g.linear_index([1, 2, 3])]);
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```

use faer::sparse::{
    SparseColMatRef, SparseRowMatRef, SymbolicSparseColMatRef, SymbolicSparseRowMatRef,
};
use faer_ext::IntoFaer;
use ndarray::{Array3, ArrayView2, ArrayView3, ArrayViewD, IxDyn};

use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::lsq::LsqMatrix;

fn check_len<const D: usize>(grid: &Grid<D>, len: usize) -> Result<()> {
    if len != grid.len() {
        return Err(Error::ShapeMismatch {
            what: "grid samples",
            expected: grid.len(),
            got: len,
        });
    }
    Ok(())
}

/// Views a 3-D grid's samples as an array indexed `[i, j, k]`.
///
/// # Errors
/// [`Error::ShapeMismatch`] if `values.len()` is not the grid's sample count.
pub fn view3<'a>(grid: &Grid<3>, values: &'a [f64]) -> Result<ArrayView3<'a, f64>> {
    check_len(grid, values.len())?;
    let [l, m, n] = grid.counts();
    Ok(ArrayView3::from_shape((l, m, n), values).expect("length checked"))
}

/// Moves a 3-D grid's samples into an owned array indexed `[i, j, k]` (no copy).
///
/// # Errors
/// [`Error::ShapeMismatch`] if `values.len()` is not the grid's sample count.
pub fn into_array3(grid: &Grid<3>, values: Vec<f64>) -> Result<Array3<f64>> {
    check_len(grid, values.len())?;
    let [l, m, n] = grid.counts();
    Ok(Array3::from_shape_vec((l, m, n), values).expect("length checked"))
}

/// Views a grid of any dimension as an `ndarray` with one axis per grid axis.
///
/// # Errors
/// [`Error::ShapeMismatch`] if `values.len()` is not the grid's sample count.
pub fn view_dyn<'a, const D: usize>(
    grid: &Grid<D>,
    values: &'a [f64],
) -> Result<ArrayViewD<'a, f64>> {
    check_len(grid, values.len())?;
    Ok(ArrayViewD::from_shape(IxDyn(&grid.counts()), values).expect("length checked"))
}

impl<'a> From<ArrayView2<'a, f64>> for LsqMatrix<'a> {
    fn from(a: ArrayView2<'a, f64>) -> Self {
        LsqMatrix::Dense(a.into_faer())
    }
}

fn malformed(reason: String) -> Error {
    Error::Malformed {
        path: "sprs matrix".into(),
        line: None,
        reason,
    }
}

/// Checks a compressed structure: pointers start at 0, never decrease, end at `nnz`; inner
/// indices strictly increase within each outer slice and stay below `inner_len`.
fn check_compressed(ptr: &[usize], idx: &[usize], inner_len: usize) -> Result<()> {
    if ptr.first() != Some(&0) || ptr.last() != Some(&idx.len()) {
        return Err(malformed(
            "index pointer must start at 0 and end at nnz".into(),
        ));
    }
    for (outer, w) in ptr.windows(2).enumerate() {
        if w[0] > w[1] {
            return Err(malformed(format!("index pointer decreases at {outer}")));
        }
        let slice = &idx[w[0]..w[1]];
        if slice.windows(2).any(|p| p[0] >= p[1]) || slice.last().is_some_and(|&i| i >= inner_len) {
            return Err(malformed(format!(
                "indices of outer slice {outer} are unsorted, repeated or out of range"
            )));
        }
    }
    Ok(())
}

impl<'a> TryFrom<&'a sprs::CsMatI<f64, usize>> for LsqMatrix<'a> {
    type Error = Error;

    /// Borrows a sprs matrix, CSR or CSC, without copying.
    ///
    /// # Errors
    /// [`Error::Malformed`] for a matrix whose index pointer does not start at 0 (a slice of a
    /// larger matrix: call `.to_owned()` first) or whose indices are unsorted.
    fn try_from(m: &'a sprs::CsMatI<f64, usize>) -> Result<Self> {
        let ptr: &'a [usize] = match m.proper_indptr() {
            std::borrow::Cow::Borrowed(p) => p,
            std::borrow::Cow::Owned(_) => {
                return Err(malformed(
                    "index pointer does not start at 0 (a sliced matrix): call .to_owned() first"
                        .into(),
                ));
            }
        };
        let (rows, cols) = (m.rows(), m.cols());
        if m.is_csc() {
            check_compressed(ptr, m.indices(), rows)?;
            let s = SymbolicSparseColMatRef::new_checked(rows, cols, ptr, None, m.indices());
            Ok(LsqMatrix::SparseCol(SparseColMatRef::new(s, m.data())))
        } else {
            check_compressed(ptr, m.indices(), cols)?;
            let s = SymbolicSparseRowMatRef::new_checked(rows, cols, ptr, None, m.indices());
            Ok(LsqMatrix::SparseRow(SparseRowMatRef::new(s, m.data())))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;
    use crate::lsq::LinearOperator;

    #[test]
    fn sprs_and_ndarray_views_apply_like_the_dense_matrix() {
        let dense = ndarray::array![
            [1.0, 0.0, 2.0],
            [0.0, 3.0, 0.0],
            [4.0, 0.0, 5.0],
            [0.0, 6.0, 0.0]
        ];
        let csr: sprs::CsMatI<f64, usize> = sprs::CsMatI::csr_from_dense(dense.view(), 0.0);
        let csc = csr.to_csc();
        let x = [1.0, 2.0, 3.0];
        let mut expected = vec![0.0; 4];
        LsqMatrix::from(dense.view()).apply(&x, &mut expected);
        assert_eq!(expected, vec![7.0, 6.0, 19.0, 12.0]);
        for m in [&csr, &csc] {
            let view = LsqMatrix::try_from(m).unwrap();
            let mut y = vec![0.0; 4];
            view.apply(&x, &mut y);
            assert_eq!(y, expected);
        }
        // A transposed ndarray view has non-unit strides and still works.
        let t = dense.t();
        let mut z = vec![0.0; 3];
        LsqMatrix::from(t).apply(&[1.0, 0.0, 0.0, 1.0], &mut z);
        assert_eq!(z, vec![1.0, 6.0, 2.0]);
    }

    #[test]
    fn grid_views_are_c_order() {
        let g = Grid::vertex_centered(Aabb::centered_cube(1.0).unwrap(), [2, 3, 4]).unwrap();
        let v: Vec<f64> = (0..24).map(f64::from).collect();
        let a = into_array3(&g, v.clone()).unwrap();
        assert_eq!(a[[1, 0, 2]], v[g.linear_index([1, 0, 2])]);
        assert_eq!(view_dyn(&g, &v).unwrap().shape(), &[2, 3, 4]);
        assert!(matches!(
            view3(&g, &v[1..]),
            Err(Error::ShapeMismatch { .. })
        ));
    }
}
