//! The Rust side of `benches/peers/python_peers.py --overhead`: the library calls the Python
//! package makes, timed in Rust on the same inputs, so that the script can measure what a call
//! from Python costs over the library.
//!
//! ```text
//! cargo run --release --example python_overhead -- DIR [--repeat K] [--only OP]
//! ```
//!
//! `DIR` holds what the script wrote: `eval.npy` (`n × 3` evaluation points), `torus.npy`
//! (an `N³` volume sampled at the points `(i, j, k)`), `cp.npy` (an `I×J×K` tensor, with
//! `cp_rank.txt` and `cp_iters.txt`), and the CSR arrays `lsq_indptr.npy`, `lsq_indices.npy`,
//! `lsq_data.npy`, `lsq_b.npy`, `lsq_shape.txt`. The operations, each as the Python package
//! runs it (`crates/python/src`):
//!
//! - `fit`: the RBF fit of `samples/bunny_2k.xyzn` (off-surface constraints with the automatic
//!   offset, kernel `r`, solver auto) — `zeroset.fit(points, normals)`;
//! - `eval`: that field at the evaluation points — `field(points)`;
//! - `mc`: marching cubes of the volume at level 0, normals from the samples —
//!   `zeroset.marching_cubes(volume, 0.0)`;
//! - `cp`: CP-ALS from the SVD initialisation, a fixed number of sweeps (tol 0) —
//!   `zeroset.cp_als(x, rank, tol=0, n_iter_max=…)`;
//! - `lsqr`: LSQR at `atol = btol = 1e-10` on the CSR system — `zeroset.lstsq(A, b)`.
//!
//! One warm-up, then the median of `K` runs (default 5; the rule of `common/timing.rs`);
//! prints `op seconds` per line, for every operation or only `OP` (the script alternates Rust
//! and Python runs of one operation, so that the machine's drift falls on both sides).
//! Threads: rayon's default (`RAYON_NUM_THREADS`).

#[path = "common/npy.rs"]
mod npy;
#[path = "common/timing.rs"]
mod timing;

use std::path::{Path, PathBuf};

use faer::sparse::{SparseRowMatRef, SymbolicSparseRowMatRef};
use zeroset::bases::rbf::{Biharmonic, Constraints, Offset, RbfFit};
use zeroset::core::field::ScalarField;
use zeroset::core::geometry::Aabb;
use zeroset::core::grid::{Centering, Grid};
use zeroset::core::io::read_point_cloud;
use zeroset::core::lsq::{LeastSquaresSolver, LsqMatrix};
use zeroset::mesh::{McOptions, marching_cubes};
use zeroset::solvers::{IterativeParams, Lsqr};
use zeroset::tensor::{CpOptions, Tensor3, cp_als};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

const USAGE: &str = "usage: python_overhead DIR [--repeat K] [--only fit|eval|mc|cp|lsqr]";

fn main() -> Res<()> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().ok_or(USAGE)?);
    let (mut repeat, mut only) = (5, None);
    while let Some(flag) = args.next() {
        match (flag.as_str(), args.next()) {
            ("--repeat", Some(k)) => repeat = k.parse()?,
            ("--only", Some(op)) => only = Some(op),
            _ => return Err(USAGE.into()),
        }
    }
    let run = |op: &str| only.as_deref().is_none_or(|o| o == op);
    if run("fit") || run("eval") {
        fit_and_eval(&dir, repeat, run("fit"), run("eval"))?;
    }
    if run("mc") {
        mc(&dir, repeat)?;
    }
    if run("cp") {
        cp(&dir, repeat)?;
    }
    if run("lsqr") {
        lsqr(&dir, repeat)?;
    }
    Ok(())
}

fn fit_and_eval(dir: &Path, repeat: usize, time_fit: bool, time_eval: bool) -> Res<()> {
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/bunny_2k.xyzn");
    let cloud = read_point_cloud(&sample)?;
    let fit = || -> Res<_> {
        let (constraints, _) = Constraints::off_surface(&cloud, Offset::default())?;
        Ok(RbfFit::new(Biharmonic).fit(&constraints)?.field)
    };
    let field = if time_fit {
        let t = timing::measure(repeat, None, fit)?;
        println!("fit {}", t.median.as_secs_f64());
        t.last
    } else {
        fit()?
    };
    if !time_eval {
        return Ok(());
    }
    let (shape, flat) = npy::read_npy(&dir.join("eval.npy"))?;
    let points: Vec<[f64; 3]> = flat.as_chunks::<3>().0.to_vec();
    assert_eq!(shape, [points.len(), 3]);
    let t = timing::measure(repeat, None, || -> Res<Vec<f64>> {
        let mut out = vec![0.0; points.len()];
        field.values(&points, &mut out);
        Ok(out)
    })?;
    println!("eval {}", t.median.as_secs_f64());
    Ok(())
}

fn mc(dir: &Path, repeat: usize) -> Res<()> {
    let (shape, volume) = npy::read_npy(&dir.join("torus.npy"))?;
    let counts = [shape[0], shape[1], shape[2]];
    let hi = counts.map(|c| (c - 1) as f64);
    let t = timing::measure(repeat, None, || -> Res<_> {
        let grid = Grid::new(Aabb::new([0.0; 3], hi)?, counts, Centering::Vertex)?;
        Ok(marching_cubes(&grid, &volume, 0.0, &McOptions::default())?)
    })?;
    println!("mc {}", t.median.as_secs_f64());
    Ok(())
}

fn cp(dir: &Path, repeat: usize) -> Res<()> {
    let (shape, data) = npy::read_npy(&dir.join("cp.npy"))?;
    let x = Tensor3::new([shape[0], shape[1], shape[2]], data)?;
    let number =
        |name: &str| -> Res<usize> { Ok(std::fs::read_to_string(dir.join(name))?.trim().parse()?) };
    let options = CpOptions::new(number("cp_rank.txt")?)
        .with_tol(0.0)
        .with_max_iter(number("cp_iters.txt")?);
    let t = timing::measure(repeat, None, || cp_als(&x, &options, |_| true))?;
    println!("cp {}", t.median.as_secs_f64());
    Ok(())
}

fn lsqr(dir: &Path, repeat: usize) -> Res<()> {
    let indices = |name: &str| -> Res<Vec<usize>> {
        let (_, v) = npy::read_npy(&dir.join(name))?;
        Ok(v.into_iter().map(|x| x as usize).collect())
    };
    let row_ptr = indices("lsq_indptr.npy")?;
    let col_idx = indices("lsq_indices.npy")?;
    let (_, values) = npy::read_npy(&dir.join("lsq_data.npy"))?;
    let (_, b) = npy::read_npy(&dir.join("lsq_b.npy"))?;
    let shape = std::fs::read_to_string(dir.join("lsq_shape.txt"))?;
    let mut mn = shape.split_whitespace().map(str::parse::<usize>);
    let (m, n) = (
        mn.next().ok_or("lsq_shape")??,
        mn.next().ok_or("lsq_shape")??,
    );
    let t = timing::measure(repeat, None, || {
        let symbolic = SymbolicSparseRowMatRef::new_checked(m, n, &row_ptr, None, &col_idx);
        let a = SparseRowMatRef::new(symbolic, &values);
        Lsqr::new(IterativeParams::default()).solve(LsqMatrix::SparseRow(a), &b)
    })?;
    println!("lsqr {}", t.median.as_secs_f64());
    Ok(())
}
