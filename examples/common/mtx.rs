//! MatrixMarket writers shared by the examples that hand systems to the scipy peer scripts.

use std::io::Write;
use std::path::Path;

use faer::sparse::SparseRowMatRef;

/// Writes `v` as a dense `n × 1` MatrixMarket array, full precision.
pub fn write_vector(path: &Path, v: &[f64]) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(out, "%%MatrixMarket matrix array real general")?;
    writeln!(out, "{} 1", v.len())?;
    for x in v {
        writeln!(out, "{x:.17e}")?;
    }
    out.flush()
}

/// Writes `a` as a MatrixMarket coordinate matrix with a comment line.
pub fn write_sparse(
    path: &Path,
    a: SparseRowMatRef<'_, usize, f64>,
    comment: &str,
) -> std::io::Result<()> {
    let (m, n) = (a.nrows(), a.ncols());
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    let nnz = a.symbolic().row_ptr()[m];
    writeln!(out, "%%MatrixMarket matrix coordinate real general")?;
    writeln!(out, "% {comment}")?;
    writeln!(out, "{m} {n} {nnz}")?;
    for i in 0..m {
        for (j, v) in a.col_idx_of_row(i).zip(a.val_of_row(i)) {
            writeln!(out, "{} {} {:.17e}", i + 1, j + 1, v)?;
        }
    }
    out.flush()
}
