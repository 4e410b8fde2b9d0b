//! Times zeroset's CP-ALS (`zeroset::tensor::cp_als`) for `benches/peers/tensor_peers.py`, which
//! runs TensorLy's `parafac` on the same tensor from the same initial factors.
//!
//! ```text
//! cargo run --release --example cp_timing -- --input DIR --rank R [--tol T] [--max-iter N]
//!     [--repeat K] [--line-search] [--threads N]
//! cargo run --release --example cp_timing -- --shape 30,30,30 --rank 10 [--noise 1e-6] …
//! ```
//!
//! With `--input DIR` it reads `DIR/x.npy` (`I×J×K`) and the initial factors `DIR/a0.npy`,
//! `DIR/b0.npy`, `DIR/c0.npy` (`I×R`, `J×R`, `K×R`), runs CP-ALS from them once as a warm-up,
//! then `K` timed times (the timing rule of `common/timing.rs` and `benches/peers/common.py`;
//! the stopping rule is TensorLy's: the relative error changes by less than `T` between
//! iterations), and writes `DIR/zeroset.json`: `ms` (median wall time of the `K` timed runs),
//! `times_ms`, `runs`, `warmup`, `iterations`, `rel_error` (exact, `‖X − X̂‖/‖X‖`), `threads`,
//! `converged`. Without it, a planted rank-`R` tensor with standard normal factors plus
//! relative noise `--noise` is made (seeded) and decomposed from the SVD initialisation.
//!
//! Threads: rayon's default (`RAYON_NUM_THREADS`, else one per CPU) or `--threads N` (a global
//! rayon pool of `N` threads); the count in effect (`rayon::current_num_threads()`, which also
//! drives faer) is printed and written as `threads`.

#[path = "common/npy.rs"]
mod npy;
#[path = "common/rng.rs"]
mod rng;
#[path = "common/timing.rs"]
mod timing;

use std::path::PathBuf;
use std::time::Duration;

use faer::Mat;
use zeroset::tensor::{CpInit, CpOptions, CpStop, Kruskal, Tensor3, cp_als};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

struct Args {
    input: Option<PathBuf>,
    shape: [usize; 3],
    rank: usize,
    noise: f64,
    tol: f64,
    max_iter: usize,
    repeat: usize,
    line_search: bool,
    threads: Option<usize>,
}

fn parse() -> Res<Args> {
    let mut a = Args {
        input: None,
        shape: [30, 30, 30],
        rank: 10,
        noise: 1e-6,
        tol: 1e-10,
        max_iter: 1000,
        repeat: 5,
        line_search: false,
        threads: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        if flag == "--line-search" {
            a.line_search = true;
            continue;
        }
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--input" => a.input = Some(value.into()),
            "--shape" => {
                let v = timing::parse_list("--shape", &value)?;
                a.shape = v
                    .try_into()
                    .map_err(|_| "--shape takes three extents, e.g. 30,30,30")?;
            }
            "--rank" => a.rank = value.parse()?,
            "--noise" => a.noise = value.parse()?,
            "--tol" => a.tol = value.parse()?,
            "--max-iter" => a.max_iter = value.parse()?,
            "--repeat" => a.repeat = value.parse::<usize>()?.max(1),
            "--threads" => a.threads = Some(value.parse()?),
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    Ok(a)
}

fn matrix(path: PathBuf, rows: usize, rank: usize) -> Res<Mat<f64>> {
    let (shape, data) = npy::read_npy(&path)?;
    if shape != [rows, rank] {
        return Err(format!(
            "{}: shape {shape:?}, expected [{rows}, {rank}]",
            path.display()
        )
        .into());
    }
    Ok(Mat::from_fn(rows, rank, |i, r| data[i * rank + r]))
}

fn main() -> Res<()> {
    let args = parse()?;
    let threads = timing::set_threads(args.threads)?;
    let (x, init) = match &args.input {
        Some(dir) => {
            let (shape, data) = npy::read_npy(&dir.join("x.npy"))?;
            let shape: [usize; 3] = shape
                .try_into()
                .map_err(|s| format!("x.npy: shape {s:?} is not 3-way"))?;
            let x = Tensor3::new(shape, data)?;
            let factors = [
                matrix(dir.join("a0.npy"), shape[0], args.rank)?,
                matrix(dir.join("b0.npy"), shape[1], args.rank)?,
                matrix(dir.join("c0.npy"), shape[2], args.rank)?,
            ];
            let init = CpInit::Given(Kruskal::new(vec![1.0; args.rank], factors)?);
            (x, init)
        }
        None => (
            rng::planted_tensor(args.shape, args.rank, args.noise, 42)?,
            CpInit::Svd,
        ),
    };
    let options = CpOptions::new(args.rank)
        .with_tol(args.tol)
        .with_max_iter(args.max_iter)
        .with_init(init)
        .with_line_search(args.line_search);
    // One warm-up, then the median of `repeat` runs.
    let timed = timing::measure(args.repeat, None, || cp_als(&x, &options, |_| true))?;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let median = timed.ms();
    let times = &timed.times;
    let fit = &timed.last;
    println!(
        "cp_timing: {:?} rank {}, {threads} threads, {}: {} iterations, median {:.2} ms \
         ({:.3} ms/iteration), rel error {:.3e}, {:?}",
        x.shape(),
        args.rank,
        timed.how(),
        fit.iterations,
        median,
        median / fit.iterations.max(1) as f64,
        fit.rel_error,
        fit.stop
    );
    if let Some(dir) = &args.input {
        let list: Vec<String> = times.iter().map(|d| format!("{:.4}", ms(*d))).collect();
        let json = format!(
            "{{\"ms\": {median:.4}, \"times_ms\": [{}], \"runs\": {}, \"warmup\": {}, \
             \"iterations\": {}, \"rel_error\": {:e}, \"threads\": {threads}, \"converged\": {}}}\n",
            list.join(", "),
            timed.runs(),
            timed.warmup,
            fit.iterations,
            fit.rel_error,
            fit.stop == CpStop::Converged
        );
        std::fs::write(dir.join("zeroset.json"), json)?;
    }
    Ok(())
}
