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
   fit + evaluation, `scipy.sparse.linalg.lsqr`, the normal equations by a direct solver on
   both sides (scipy's `spsolve`, SuperLU, at two orderings; CHOLMOD through scikit-sparse
   where installed; zeroset's sparse Cholesky), `skimage.measure.marching_cubes`, TensorLy
   `parafac` (same SVD initialisation, 50 sweeps, tol 0). Run once with one thread each
   (`RAYON_NUM_THREADS=1`, BLAS pinned to 1) and once with two (`--threads 2`, BLAS at 2);
   `--threads-both 2` runs both in child processes and prints them side by side with the
   ratios one thread each and each at its fastest (the faster of each side's two settings).
   The RBF rows also time scipy's local mode (`neighbors=20` and `50`, its documented speed
   setting: a different, piecewise smooth interpolant), with its distance to the global
   interpolant; marching cubes is timed on float64 samples (skimage converts them to float32
   inside its call; zeroset takes them as they are) and on float32 samples (skimage's native
   dtype; zeroset's binding converts them to float64 inside its call).

Timing rule of `common.py`: one warm-up, then the median of 5 runs (`--repeat`); the RBF rows
the median of 3 (`--rbf-repeat`). The report ends with the machine facts (commit, CPU, load).

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
    p.add_argument("--rbf-repeat", type=int, default=3, help="timed runs of the RBF rows (seconds each)")
    p.add_argument("--neighbors", default="20,50", help="scipy RBFInterpolator local mode: these k ('' for none)")
    p.add_argument("--threads-both", type=int, default=None, metavar="N",
                   help="run the migration table at 1 and at N threads (child processes) and merge them")
    p.add_argument("--json", default=None, help=argparse.SUPPRESS)  # child: write the migration rows here
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


def migration() -> list:
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

    s_global = scipy_rbf()
    z_rbf = zeroset_rbf()
    diff = np.abs(s_global - z_rbf).max()
    t_zeroset_rbf = timed(zeroset_rbf, ARGS.rbf_repeat)
    rows.append(("`RBFInterpolator(c, v, kernel='linear')(x)`", "`zeroset.fit(p, n, offset=1e-3)(x)`",
                 "6,000 constraints, 10⁵ evaluations", timed(scipy_rbf, ARGS.rbf_repeat), t_zeroset_rbf,
                 f"max |difference| {diff:.1e}", ARGS.rbf_repeat))
    for k in [int(v) for v in ARGS.neighbors.split(",") if v.strip()]:
        def scipy_local(k=k):
            return RBFInterpolator(centres, values, kernel="linear", degree=1, neighbors=k)(evals)

        s_local = scipy_local()
        rows.append((f"`RBFInterpolator(c, v, kernel='linear', neighbors={k})(x)` (local: piecewise smooth)",
                     "`zeroset.fit(p, n, offset=1e-3)(x)` (global)", "6,000 constraints, 10⁵ evaluations",
                     timed(scipy_local, ARGS.rbf_repeat), t_zeroset_rbf,
                     f"max |local − global| {np.abs(s_local - s_global).max():.1e} "
                     f"(zeroset − global {diff:.1e})", ARGS.rbf_repeat))
    a, b = laplacian_system()
    scipy_lsqr = lsqr(a, b, atol=1e-10, btol=1e-10, iter_lim=100_000)
    want = scipy_lsqr[0]
    got = zeroset.lstsq(a, b, tol=1e-10, max_iter=100_000)
    rows.append(("`scipy.sparse.linalg.lsqr(A, b, atol=1e-10, btol=1e-10)`", "`zeroset.lstsq(A, b)`",
                 f"{a.shape[0]}×{a.shape[1]}, nnz {a.nnz}",
                 timed(lambda: lsqr(a, b, atol=1e-10, btol=1e-10, iter_lim=100_000)),
                 timed(lambda: zeroset.lstsq(a, b, tol=1e-10, max_iter=100_000)),
                 f"max |difference| {np.abs(want - got).max():.1e}; {scipy_lsqr[2]} "
                 "scipy iterations", ARGS.repeat))
    # Direct against direct: the normal equations AᵀA x = Aᵀb, formed and factored on each side
    # (the product counted: the user pays it). zeroset's sparse Cholesky (faer, AMD ordering);
    # scipy's SuperLU at its default column ordering and at the one for symmetric matrices;
    # CHOLMOD where scikit-sparse is installed (`setup.sh --cholmod`).
    from scipy.sparse.linalg import spsolve

    def zs_cholesky():
        return zeroset.lstsq(a, b, solver="cholesky")

    x_chol = zs_cholesky()
    t_chol = timed(zs_cholesky)
    shape = f"{a.shape[0]}×{a.shape[1]}, nnz {a.nnz}"
    for permc, why in (("COLAMD", "its default ordering"), ("MMD_AT_PLUS_A", "its ordering for symmetric A")):
        def superlu(permc=permc):
            return spsolve((a.T @ a).tocsc(), a.T @ b, permc_spec=permc)

        rows.append((f"`spsolve(A.T @ A, A.T @ b, permc_spec='{permc}')` (SuperLU, {why})",
                     "`zeroset.lstsq(A, b, solver='cholesky')`", shape, timed(superlu), t_chol,
                     f"max |difference| {np.abs(superlu() - x_chol).max():.1e}", ARGS.repeat))
    try:
        from sksparse.cholmod import cholesky as cholmod
    except ImportError:
        cholmod = None
        print("(CHOLMOD row skipped: scikit-sparse is not installed; setup.sh --cholmod)", file=sys.stderr)
    if cholmod is not None:
        def chol():
            return cholmod((a.T @ a).tocsc())(a.T @ b)

        rows.append(("`sksparse.cholmod.cholesky(A.T @ A)(A.T @ b)` (CHOLMOD)",
                     "`zeroset.lstsq(A, b, solver='cholesky')`", shape, timed(chol), t_chol,
                     f"max |difference| {np.abs(chol() - x_chol).max():.1e}", ARGS.repeat))
    volume = torus_volume()
    for vol, dtype in ((volume, "float64"), (volume.astype(np.float32), "float32")):
        sv = sk_mc(vol, 0.0)[0]
        zv = zeroset.marching_cubes(vol, 0.0)[0]
        rows.append(("`skimage.measure.marching_cubes(v, 0)`", "`zeroset.marching_cubes(v, 0)`",
                     f"torus, 256³, {dtype} samples",
                     timed(lambda: sk_mc(vol, 0.0)), timed(lambda: zeroset.marching_cubes(vol, 0.0)),
                     f"{len(sv)} vs {len(zv)} vertices", ARGS.repeat))
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
                     f"relative error {e1:.2e} vs {e2:.2e}", ARGS.repeat))
    threads = os.environ.get("RAYON_NUM_THREADS", f"default ({os.cpu_count()} CPUs)")
    print(f"\n## Peer call against the zeroset call (threads: {threads}, BLAS the same)\n")
    print("| peer call | zeroset call | input | peer | zeroset | speed-up | agreement | median of |")
    print("|---|---|---|---|---|---|---|---|")
    for peer, ours, what, tp, tz, note, reps in rows:
        print(f"| {peer} | {ours} | {what} | {tp*1e3:.1f} ms | {tz*1e3:.1f} ms | {tp/tz:.2f}× | {note} | {reps} |")
    return rows


def both(n: int) -> None:
    """The migration table at 1 and at n threads (child processes: BLAS reads its thread count at
    import), side by side with the ratios one thread each and each at its fastest."""
    import json

    runs = {}
    with tempfile.TemporaryDirectory(prefix="zeroset-migration-") as d:
        for t in (1, n):
            out = Path(d) / f"t{t}.json"
            cmd = [sys.executable, __file__, "--threads", str(t), "--skip-overhead", "--json", str(out),
                   "--repeat", str(ARGS.repeat), "--rbf-repeat", str(ARGS.rbf_repeat), "--neighbors", ARGS.neighbors]
            print("$ " + " ".join(cmd), flush=True)
            subprocess.run(cmd, check=True)
            runs[t] = json.loads(out.read_text())
    print(f"\n## Migration, 1 thread each and each at its fastest (1 and {n} threads; BLAS the same as RAYON)\n")
    print(f"| peer call | zeroset call | input | 1 thread each: peer / zeroset | {n} threads each: peer / zeroset "
          "| each at its fastest: peer / zeroset | agreement | median of |")
    print("|---|---|---|---|---|---|---|---|")
    fmt = lambda v: f"{v:.2f} s" if v >= 1 else f"{v * 1e3:.1f} ms"  # noqa: E731
    for r1, rn in zip(runs[1], runs[n]):
        peer, ours, what, p1, z1, note, reps = r1
        pn, zn = rn[3], rn[4]
        pb, pt = min((p1, 1), (pn, n))
        zb, zt = min((z1, 1), (zn, n))
        print(f"| {peer} | {ours} | {what} | {fmt(p1)} / {fmt(z1)}: **{p1 / z1:.2f}×** | {fmt(pn)} / {fmt(zn)}: "
              f"**{pn / zn:.2f}×** | {fmt(pb)} ({pt} thr.) / {fmt(zb)} ({zt} thr.): **{pb / zb:.2f}×** | {note} | "
              f"{reps} |")


if __name__ == "__main__":
    import common

    load_start = common.loadavg()
    print(f"zeroset {zeroset.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}, "
          f"load {load_start}", flush=True)
    if ARGS.threads_both:
        both(ARGS.threads_both)
    else:
        if not ARGS.skip_overhead:
            overhead()
        if not ARGS.skip_migration:
            rows = migration()
            if ARGS.json:
                import json

                Path(ARGS.json).write_text(json.dumps(rows))
    if not ARGS.json:
        facts = common.machine_facts([("load average 1/5/15 min, at start", load_start),
                                      ("load average 1/5/15 min, at the end", common.loadavg())],
                                     [("zeroset wheel", zeroset.__version__ + " (built by setup.sh --python from "
                                       "this checkout)")])
        print("\n### Machine\n")
        print("| fact | value |\n|---|---|")
        for a, b in facts:
            print(f"| {a} | {b} |")
