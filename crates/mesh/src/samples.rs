//! The checks marching squares and marching cubes share on a grid of samples.

use zeroset_field_core::{Error, Grid};

use crate::error::{MeshError, Result};

/// At least two samples per axis, one sample per grid point (`what` names them), and a finite
/// level.
pub(crate) fn check<const D: usize>(
    grid: &Grid<D>,
    values: Option<&[f64]>,
    level: f64,
    what: &'static str,
) -> Result<()> {
    for (axis, &got) in grid.counts().iter().enumerate() {
        if got < 2 {
            return Err(Error::GridTooSmall {
                axis,
                needed: 2,
                got,
            }
            .into());
        }
    }
    if !level.is_finite() {
        return Err(MeshError::NonFiniteLevel { level });
    }
    if let Some(values) = values
        && values.len() != grid.len()
    {
        return Err(Error::ShapeMismatch {
            what,
            expected: grid.len(),
            got: values.len(),
        }
        .into());
    }
    Ok(())
}

/// The error naming sample `index` of `values`, which is NaN or infinite.
pub(crate) fn non_finite<const D: usize>(
    grid: &Grid<D>,
    values: &[f64],
    index: usize,
) -> MeshError {
    let grid_index = grid.multi_index(index);
    MeshError::NonFiniteSample {
        index,
        grid_index: grid_index.to_vec(),
        position: grid.point(grid_index).to_vec(),
        value: values[index],
    }
}

/// The index of the first NaN or infinite value, scanning fixed chunks in parallel (cheaper
/// than a per-element parallel search on large grids).
pub(crate) fn first_non_finite(values: &[f64]) -> Option<usize> {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 16;
    let chunk = values
        .par_chunks(CHUNK)
        .position_first(|c| c.iter().fold(false, |bad, v| bad | !v.is_finite()))?;
    let start = chunk * CHUNK;
    values[start..]
        .iter()
        .position(|v| !v.is_finite())
        .map(|k| start + k)
}
