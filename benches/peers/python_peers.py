"""The Python package `zeroset` (crates/python) against the library and against the peers its
users would otherwise call (hand-run, not by CI).

Two tables, on the same inputs in the same run:

1. **Overhead** — each operation called from Python (`zeroset.fit`, `field(points)`,
   `zeroset.marching_cubes`, `zeroset.cp_als`, `zeroset.lstsq`) against the same library
   calls timed in Rust by `examples/python_overhead.rs`, at the README's benchmark sizes: the
   2,000-point bunny fit (6,000 constraints), 10⁵ evaluation points, a 256³ torus volume,
   CP-ALS of a 60³ rank-20 tensor (50 sweeps), LSQR on a 2-D Laplacian least-squares system
   (128² unknowns). Both sides use rayon's default threads (`RAYON_NUM_THREADS`, else one per
   CPU); the Python side counts everything the call does (argument conversion, copies, the
   GIL release, progress hooks, results handed to numpy). Rust and Python alternate per
   operation (`--rounds`, default 5), and the overhead is the median of the rounds' ratios.
2. **Migration** — the scipy / scikit-image / TensorLy call a user replaces, on the same input:
   `RBFInterpolator` (kernel `linear` = zeroset's `r`, degree 1, the same off-surface points)
   fit + evaluation, `scipy.sparse.linalg.lsqr`, `skimage.measure.marching_cubes`, TensorLy
   `parafac` (same SVD initialisation, 50 sweeps, tol 0). Run once with one thread each
   (`RAYON_NUM_THREADS=1`, BLAS pinned to 1) and once with two (`--threads 2`, BLAS at 2).

Timing rule of `common.py`: one warm-up, then the median of 5 runs.

Set-up: `bash benches/peers/setup.sh --python` (the pinned peers plus the zeroset wheel built by
maturin from this checkout). Run: `benches/peers/.venv/bin/python benches/peers/python_peers.py
[--threads 1|2] [--rounds R] [--only fit,eval,mc,cp,lsqr] [--skip-overhead] [--skip-migration]`.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent


def parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--threads", type=int, default=None, help="RAYON and BLAS threads (default: leave)")
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--rounds", type=int, default=5, help="alternations of Rust and Python per operation")
    p.add_argument("--only", default=None,
                   help="overhead of these operations only (comma-separated: fit,eval,mc,cp,lsqr)")
    p.add_argument("--skip-overhead", action="store_true")
    p.add_argument("--skip-migration", action="store_true")
    return p.parse_args()


ARGS = parse()
if ARGS.threads is not None:
    for var in ("RAYON_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.threads)

import numpy as np  # noqa: E402  (after the thread variables)

import zeroset  # noqa: E402


def timed(f, repeat: int = ARGS.repeat) -> float:
    """One warm-up, then the median of `repeat` runs, in seconds."""
    f()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return sorted(times)[len(times) // 2]


def torus_volume(n: int = 256) -> np.ndarray:
    t = np.arange(n, dtype=np.float64)
    c = (n - 1) / 2
    x, y, z = np.meshgrid(t - c, t - c, t - c, indexing="ij")
    major, minor = 0.3 * n, 0.12 * n
    return np.sqrt((np.sqrt(x * x + y * y) - major) ** 2 + z * z) - minor


def laplacian_system(k: int = 128):
    import scipy.sparse as sp

    d = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(k, k))
    a = sp.vstack([sp.kronsum(d, d), 0.05 * sp.identity(k * k)]).tocsr()
    b = np.random.default_rng(1).standard_normal(a.shape[0])
    return a, b


def cp_tensor(n: int = 60, rank: int = 20) -> np.ndarray:
    rng = np.random.default_rng(2)
    f = [rng.standard_normal((n, rank)) for _ in range(3)]
    x = np.einsum("ir,jr,kr->ijk", *f)
    return x + 1e-3 * np.linalg.norm(x) / x.size**0.5 * rng.standard_normal(x.shape)


CP_RANK, CP_ITERS = 20, 50


def overhead() -> None:
    points, normals = zeroset.sample_points()
    evals = np.random.default_rng(3).uniform(-0.12, 0.21, size=(100_000, 3))
    volume = torus_volume()
    x = cp_tensor()
    a, b = laplacian_system()
    with tempfile.TemporaryDirectory(prefix="zeroset-overhead-") as d:
        d = Path(d)
        np.save(d / "eval.npy", evals)
        np.save(d / "torus.npy", volume)
        np.save(d / "cp.npy", x)
        (d / "cp_rank.txt").write_text(str(CP_RANK))
        (d / "cp_iters.txt").write_text(str(CP_ITERS))
        np.save(d / "lsq_indptr.npy", a.indptr.astype(np.float64))
        np.save(d / "lsq_indices.npy", a.indices.astype(np.float64))
        np.save(d / "lsq_data.npy", a.data)
        np.save(d / "lsq_b.npy", b)
        (d / "lsq_shape.txt").write_text(f"{a.shape[0]} {a.shape[1]}")
        subprocess.run(
            ["cargo", "build", "--release", "--quiet", "--example", "python_overhead"],
            cwd=REPO, check=True,
        )
        field = zeroset.fit(points, normals)
        python = {
            "fit": lambda: zeroset.fit(points, normals),
            "eval": lambda: field(evals),
            "mc": lambda: zeroset.marching_cubes(volume, 0.0),
            "cp": lambda: zeroset.cp_als(x, CP_RANK, tol=0.0, n_iter_max=CP_ITERS),
            "lsqr": lambda: zeroset.lstsq(a, b),
        }
        # Rust and Python alternate, operation by operation, ROUNDS times: the machine's
        # drift falls on both sides; the overhead is the median of the rounds' ratios.
        rust, py, ratio = {}, {}, {}
        if ARGS.only:
            wanted = ARGS.only.split(",")
            unknown = set(wanted) - set(python)
            if unknown:
                sys.exit(f"--only: unknown operations {sorted(unknown)}; they are {list(python)}")
            python = {op: python[op] for op in wanted}
        for op, call in python.items():
            pairs = []
            for _ in range(ARGS.rounds):
                out = subprocess.run(
                    [str(REPO / "target/release/examples/python_overhead"), str(d),
                     "--repeat", str(ARGS.repeat), "--only", op],
                    check=True, capture_output=True, text=True,
                ).stdout.split()
                pairs.append((float(out[1]), timed(call)))
            rust[op] = sorted(p[0] for p in pairs)[len(pairs) // 2]
            py[op] = sorted(p[1] for p in pairs)[len(pairs) // 2]
            ratios = sorted(p[1] / p[0] for p in pairs)
            ratio[op] = (ratios[len(ratios) // 2], ratios[0], ratios[-1])
    what = {
        "fit": "RBF fit, bunny_2k (6,000 constraints, r)",
        "eval": "field at 10⁵ points",
        "mc": "marching cubes, torus 256³",
        "cp": f"CP-ALS 60³ rank {CP_RANK}, {CP_ITERS} sweeps",
        "lsqr": f"LSQR, {a.shape[0]}×{a.shape[1]} sparse (nnz {a.nnz})",
    }
    threads = os.environ.get("RAYON_NUM_THREADS", f"default ({os.cpu_count()} CPUs)")
    print(f"\n## Overhead of the Python call over the Rust library (threads: {threads})\n")
    print(f"{ARGS.rounds} rounds of Rust then Python, each a warm-up and the median of {ARGS.repeat} runs\n")
    print("| operation | Rust | Python | overhead (median of the rounds' ratios) | range |")
    print("|---|---|---|---|---|")
    for k in ratio:
        mid, lo, hi = ratio[k]
        print(f"| {what[k]} | {rust[k]*1e3:.2f} ms | {py[k]*1e3:.2f} ms | {100*(mid-1):+.1f}% "
              f"| {100*(lo-1):+.1f}% … {100*(hi-1):+.1f}% |")


def migration() -> None:
    from scipy.interpolate import RBFInterpolator
    from scipy.sparse.linalg import lsqr
    from skimage.measure import marching_cubes as sk_mc

    rows = []
    # RBF: the same off-surface points on both sides (a fixed offset that crosses nothing)
    points, normals = zeroset.sample_points()
    eps = 1e-3
    centres = np.vstack([points, points + eps * normals, points - eps * normals])
    values = np.concatenate([np.zeros(len(points)), np.full(len(points), eps), np.full(len(points), -eps)])
    evals = np.random.default_rng(3).uniform(-0.12, 0.21, size=(100_000, 3))

    def scipy_rbf():
        f = RBFInterpolator(centres, values, kernel="linear", degree=1)
        return f(evals)

    def zeroset_rbf():
        return zeroset.fit(points, normals, offset=eps)(evals)

    diff = np.abs(scipy_rbf() - zeroset_rbf()).max()
    rows.append(("`RBFInterpolator(c, v, kernel='linear')(x)`", "`zeroset.fit(p, n)(x)`",
                 "6,000 constraints, 10⁵ evaluations", timed(scipy_rbf, 3), timed(zeroset_rbf, 3),
                 f"max |difference| {diff:.1e}"))
    a, b = laplacian_system()
    want = lsqr(a, b, atol=1e-10, btol=1e-10, iter_lim=100_000)[0]
    got = zeroset.lstsq(a, b, tol=1e-10, max_iter=100_000)
    rows.append(("`scipy.sparse.linalg.lsqr(A, b, atol=1e-10, btol=1e-10)`", "`zeroset.lstsq(A, b)`",
                 f"{a.shape[0]}×{a.shape[1]}, nnz {a.nnz}",
                 timed(lambda: lsqr(a, b, atol=1e-10, btol=1e-10, iter_lim=100_000)),
                 timed(lambda: zeroset.lstsq(a, b, tol=1e-10, max_iter=100_000)),
                 f"max |difference| {np.abs(want - got).max():.1e}"))
    volume = torus_volume()
    sv = sk_mc(volume, 0.0)[0]
    zv = zeroset.marching_cubes(volume, 0.0)[0]
    rows.append(("`skimage.measure.marching_cubes(v, 0)`", "`zeroset.marching_cubes(v, 0)`", "torus, 256³",
                 timed(lambda: sk_mc(volume, 0.0)), timed(lambda: zeroset.marching_cubes(volume, 0.0)),
                 f"{len(sv)} vs {len(zv)} vertices"))
    try:
        import tensorly as tl
        from tensorly.decomposition import parafac
    except ImportError:
        tl = None
    if tl is not None:
        x = cp_tensor()

        def tly():
            return parafac(x, CP_RANK, n_iter_max=CP_ITERS, init="svd", tol=0.0)

        def zs():
            return zeroset.cp_als(x, CP_RANK, n_iter_max=CP_ITERS, init="svd", tol=0.0)

        e1 = np.linalg.norm(tl.cp_to_tensor(tly()) - x) / np.linalg.norm(x)
        w, fs = zs()
        e2 = np.linalg.norm(np.einsum("r,ir,jr,kr->ijk", w, *fs) - x) / np.linalg.norm(x)
        rows.append(("`tensorly.decomposition.parafac(x, 20, init='svd')`", "`zeroset.cp_als(x, 20)`",
                     f"60³ rank 20, {CP_ITERS} sweeps", timed(tly), timed(zs),
                     f"relative error {e1:.2e} vs {e2:.2e}"))
    threads = os.environ.get("RAYON_NUM_THREADS", f"default ({os.cpu_count()} CPUs)")
    print(f"\n## Peer call against the zeroset call (threads: {threads}, BLAS the same)\n")
    print("| peer call | zeroset call | input | peer | zeroset | speed-up | agreement |")
    print("|---|---|---|---|---|---|---|")
    for peer, ours, what, tp, tz, note in rows:
        print(f"| {peer} | {ours} | {what} | {tp*1e3:.1f} ms | {tz*1e3:.1f} ms | {tp/tz:.1f}× | {note} |")


if __name__ == "__main__":
    print(f"zeroset {zeroset.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}, "
          f"load {os.getloadavg()}")
    if not ARGS.skip_overhead:
        overhead()
    if not ARGS.skip_migration:
        migration()
