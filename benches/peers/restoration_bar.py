#!/usr/bin/env python3
"""Bar check: zeroset's protrusion-removal solve vs scipy on the very same system.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/restoration_bar.py [--k 32,64] [--k-large 128]

Threads: both sides are timed at one thread and at all threads (N = --mt-threads, default the
CPUs available), and the report gives the ratios one thread each and each side at its fastest.

Steps:
  1. `cargo build --release --example restoration_timing` (CARGO_TARGET_DIR honoured; --skip-build
     reuses the binary), then `restoration_timing --k 32,64 --solvers separable,lsqr-poisson
     --repeat R --csv …` with RAYON_NUM_THREADS=1 (this run also writes, per k, the system
     A = [L; wP] (w = 1/6), b, zeroset's separable solution h and the box of unknowns:
     `--write-dir OUT`) and again with RAYON_NUM_THREADS=N; likewise `--k 128 --solvers separable`
     (no matrix written: too big for MatrixMarket). Timed by the example (one warm-up, then the
     median of R): `solve-only` = the separable solve on the ready right-hand side (the
     like-for-like figure for the NumPy port); `separable` and `lsqr-poisson` =
     `restore_in_place`: the assembly of the system from the samples + the solve + writing the
     solution back;
  2. on the same A, b (scipy.io.mmread → CSR; loading excluded) times, with BLAS pinned to one
     thread and scipy.fft `workers=1` in this process, and again in a child process with BLAS at
     N threads and `workers=N` (OpenBLAS reads its thread count at import):
       a. scipy `lsqr(A, b, atol=btol=1e-12)` (no FFT; BLAS for its vector operations);
       b. the same separable method as zeroset's, written in NumPy/SciPy (the like-for-like
          peer): DST-I across the two lateral axes, a Givens QR of the (tridiagonal + one row)
          line problem of every lateral mode, vectorised over the modes, inverse DST-I;
       c. LSQR on A·M⁻¹, right-preconditioned by the fast Poisson solve M = L (DST-I on all axes);
     each one warm-up + median of its repeat count (scipy lsqr: a single run without warm-up for
     k > --lsqr-once-above, marked next to the number), and compares every solution with h
     (max |x − h| / max |h|);
  3. cold (a one-shot program's cost: `zeroset restore` is one): for k in --cold-k, each side's
     first solve in a fresh process, --cold-runs processes per side and thread setting, the
     median reported (each process also times --cold-warm further calls: the warm figure in it).
     zeroset through its Python binding (`zeroset.restore` on the same sphere samples, the
     report's solve seconds; needs `setup.sh --python`, else skipped), whose first call pays
     the page faults of fresh work buffers that later calls of one size reuse (laplace.rs);
     the NumPy port's first `separable_solve` on the loaded b (its scipy.fft plans made then);
  4. prints per-k tables, a summary with ratios (peer_ms / zeroset_ms: > 1 means zeroset is
     faster) one thread each and each side at its fastest, PASS/FAIL per bar, and writes
     OUT/restoration_bar.csv and OUT/restoration_bar.md.
Always exits 0 once it has run; a failed bar is reported, not raised.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import common
from common import fmt_e, fmt_int, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402
import scipy.io  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402
from scipy.fft import dstn  # noqa: E402

EXAMPLE = "restoration_timing"
W = 1.0 / 6.0  # neighbour weight of the Laplace rows and weight of the Neumann rows (D = 3)
AGREE_TOL = 1e-12  # like-for-like separable vs zeroset's h, relative to max |h|
CONFIGS = ("1", "all")  # one thread each; all threads (N = --mt-threads)

# (label, zeroset method, peer source, peer method): the comparisons of the summary and bars.
PAIRS = (
    ("scipy lsqr ÷ zeroset separable", "separable", "scipy", "lsqr"),
    ("numpy separable ÷ zeroset solve-only (like-for-like)", "solve-only", "numpy", "separable"),
    ("scipy dst-lsqr ÷ zeroset lsqr-poisson", "lsqr-poisson", "scipy", "dst-lsqr"),
)


@dataclass
class Row:
    """One method's result for one k at one thread configuration."""

    k: int
    source: str  # "zeroset" | "scipy" | "numpy"
    method: str
    config: str  # "1" | "all"
    threads: str  # what ran: "rayon 1", "rayon 2", "BLAS 1, fft workers 1", …
    median_ms: float | None
    runs: int
    warmup: bool = True
    iterations: int | None = None
    rel_residual: float = math.nan  # ‖b − Ax‖/‖b‖
    max_rel_diff: float = math.nan  # max |x − h| / max |h|
    note: str = ""


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Time scipy and a NumPy separable solve on the protrusion-removal system zeroset solves.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--k", default="32,64", help="mask sizes whose system is written and solved by scipy too")
    p.add_argument(
        "--k-large",
        default="128",
        help="mask sizes timed in zeroset only (separable, no matrix written); '' for none",
    )
    p.add_argument("--repeat", type=int, default=5, help="zeroset timed runs (after one warm-up) for --k")
    p.add_argument("--repeat-large", type=int, default=3, help="zeroset timed runs for --k-large")
    p.add_argument("--sep-repeat", type=int, default=5, help="NumPy separable: timed runs after one warm-up")
    p.add_argument("--plsqr-repeat", type=int, default=3, help="DST-preconditioned LSQR: timed runs after one warm-up")
    p.add_argument("--lsqr-repeat", type=int, default=3, help="scipy lsqr: timed runs after one warm-up")
    p.add_argument(
        "--lsqr-once-above",
        type=int,
        default=32,
        metavar="K",
        help="for k > K run scipy lsqr once, without warm-up (it takes seconds)",
    )
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the mtx files, CSV and report")
    p.add_argument("--skip-build", action="store_true", help="do not run cargo build; reuse the example binary")
    p.add_argument("--worker", metavar="JSON", help=argparse.SUPPRESS)  # child: time the peers, write JSON
    p.add_argument("--workers", type=int, default=1, help=argparse.SUPPRESS)  # scipy.fft workers (child)
    p.add_argument("--cold-k", default=None, help="k at which the first call of a fresh process is timed "
                   "(default: the largest of --k; '' for none)")
    p.add_argument("--cold-runs", type=int, default=5, help="fresh processes per side and thread setting")
    p.add_argument("--cold-warm", type=int, default=5, help="warm calls after the first, in each fresh process")
    p.add_argument("--cold-worker", choices=["zeroset", "numpy"], help=argparse.SUPPRESS)  # child: one fresh process
    p.add_argument("--cold-json", help=argparse.SUPPRESS)
    common.add_mt_arg(p, "the peers with BLAS at N threads and scipy.fft workers=N")
    common.add_blas_arg(p)
    a = p.parse_args()

    def ks(s, flag):
        return common.int_list(p, s, flag, 3, name="k")

    a.ks, a.ks_large = ks(a.k, "--k"), ks(a.k_large, "--k-large")
    if a.cold_k is None:
        a.cold_ks = [max(a.ks)] if a.ks else []
    else:
        a.cold_ks = ks(a.cold_k, "--cold-k") if a.cold_k.strip() else []
    if not a.ks and not a.ks_large:
        p.error("nothing to do: --k and --k-large are both empty")
    for name in ("repeat", "repeat_large", "sep_repeat", "plsqr_repeat", "lsqr_repeat"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if a.mt_threads < 0:
        p.error("--mt-threads must be >= 0")
    a.mt = a.mt_threads if a.mt_threads > 1 else 0  # 0: one-thread runs only
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: zeroset


def run_zeroset(binary: Path, ks: list[int], solvers: str, repeat: int, out: Path, csv_name: str, write: bool,
                config: str, mt: int) -> list[Row]:  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / csv_name
    csv_path.unlink(missing_ok=True)
    cmd = [str(binary), "--k", ",".join(map(str, ks)), "--solvers", solvers, "--repeat", str(repeat),
           "--csv", str(csv_path)]  # fmt: skip
    if write:
        cmd += ["--write-dir", str(out)]
    common.run_logged(cmd, env={"RAYON_NUM_THREADS": "1" if config == "1" else str(mt)})
    rows = []
    with csv_path.open(newline="") as f:
        for r in csv.DictReader(f):
            threads = (r.get("threads") or "").strip() or "?"
            rows.append(
                Row(
                    k=int(r["k"]),
                    source="zeroset",
                    method=r["solver"],
                    config=config,
                    threads=f"rayon {threads}",
                    median_ms=float(r["median_ms"]),
                    runs=int(r.get("runs") or repeat),
                    warmup=(r.get("warmup") or "1").strip() != "0",
                    iterations=int(r["iterations"]),
                    rel_residual=float(r["rel_residual"] or "nan"),
                    # vs the default (separable) restoration of the example itself
                    max_rel_diff=float(r["max_rel_diff"] or "nan"),
                    note="solve alone, right-hand side ready (like NumPy's)"
                    if r["solver"] == "solve-only"
                    else "assembly + solve; rel_res, diff: from the example",
                )
            )
            if config == "1" and threads not in ("1", "?"):
                print(f"warning: the RAYON_NUM_THREADS=1 run reports threads={threads}", flush=True)
    return rows


# ---------------------------------------------------------------------------------------------
# Step 2: the peers


def load_system(out: Path, k: int):
    stem = out / f"restoration_bar_k{k}"
    files = {s: Path(f"{stem}.{s}") for s in ("A.mtx", "b.mtx", "h.mtx", "dims.txt")}
    for f in files.values():
        if not f.is_file():
            sys.exit(f"{f} not found (the example did not write it)")
    dims = tuple(int(v) for v in files["dims.txt"].read_text().split())
    a = sp.csr_array(scipy.io.mmread(files["A.mtx"]))
    vec = lambda f: np.asarray(scipy.io.mmread(f), dtype=np.float64).ravel()  # noqa: E731
    b, h = vec(files["b.mtx"]), vec(files["h.mtx"])
    n0, n1, n2 = dims
    n = n0 * n1 * n2
    if a.shape != (n + n0 * n1, n) or b.shape != (a.shape[0],) or h.shape != (n,):
        sys.exit(f"k={k}: unexpected shapes A {a.shape}, b {b.shape}, h {h.shape} for box {dims}")
    return a, b, h, dims


def dst_eigenvalues(m: int) -> np.ndarray:
    """Eigenvalues 2cos(π(j+1)/(m+1)) of tridiag(1, 0, 1) (m×m), in DST-I mode order."""
    return 2.0 * np.cos(np.pi * np.arange(1, m + 1) / (m + 1))


def separable_solve(b: np.ndarray, dims: tuple[int, int, int], workers: int = 1) -> np.ndarray:
    """min ‖A x − b‖ for A = [L; wP] by zeroset's separable method, in NumPy/SciPy.

    DST-I (orthonormal, its own inverse) across axes 0 and 1 diagonalises both row blocks;
    per lateral mode (p, q) the line problem along axis 2 is
        min ‖[tridiag(w, w(σ−6), w); w e_lastᵀ] x − [r̂; ŝ]‖,  σ = λ_p + λ_q,
    solved by Givens QR: one rotation per position eliminates the subdiagonal, a last one the
    Neumann row; R has three diagonals. Every step is vectorised over all n0·n1 modes, with the
    lines stored position-major, (n2, modes), so each step touches contiguous rows. The DSTs run
    on `workers` threads (scipy.fft); the NumPy element-wise steps are single-threaded.
    """
    n0, n1, n2 = dims
    n = n0 * n1 * n2
    w = W
    r = b[:n].reshape(n0, n1, n2).transpose(2, 0, 1)  # (n2, n0, n1), a view
    rhat = dstn(r, type=1, norm="ortho", axes=(1, 2), workers=workers).reshape(n2, n0 * n1)
    shat = dstn(b[n:].reshape(n0, n1), type=1, norm="ortho", workers=workers).ravel()
    d = (w * (dst_eigenvalues(n0)[:, None] + dst_eigenvalues(n1)[None, :] - 6.0)).ravel()

    r0 = np.empty_like(rhat)  # R[j, j]
    r1 = np.empty_like(rhat)  # R[j, j+1]
    r2 = np.empty_like(rhat)  # R[j, j+2] (= s·w)
    y = np.empty_like(rhat)  # Qᵀ b
    a, off, g = d.copy(), np.full_like(d, w), rhat[0].copy()  # working row j: (a, off) at (j, j+1)
    for j in range(n2 - 1):
        rho = np.hypot(a, w)
        c, s = a / rho, w / rho
        f = rhat[j + 1]
        r0[j], r1[j], r2[j] = rho, c * off + s * d, s * w
        y[j] = c * g + s * f
        a, off, g = c * d - s * off, c * w, c * f - s * g
    # the Neumann row w·e_lastᵀ
    rho = np.hypot(a, w)
    c, s = a / rho, w / rho
    r0[-1], y[-1] = rho, c * g + s * shat

    x = np.empty_like(rhat)
    x[-1] = y[-1] / r0[-1]
    if n2 > 1:
        x[-2] = (y[-2] - r1[-2] * x[-1]) / r0[-2]
    for j in range(n2 - 3, -1, -1):
        x[j] = (y[j] - r1[j] * x[j + 1] - r2[j] * x[j + 2]) / r0[j]
    x = dstn(x.reshape(n2, n0, n1), type=1, norm="ortho", axes=(1, 2), workers=workers)
    return np.ascontiguousarray(x.transpose(1, 2, 0)).ravel()


def dst_lsqr(a, b: np.ndarray, dims: tuple[int, int, int], iter_lim: int, workers: int = 1):
    """LSQR on A·M⁻¹ with M = (1/6)Δ_h = L (the Laplace block), M⁻¹ by DST-I on all three axes
    (scipy.fft with `workers` threads); returns (x = M⁻¹y, istop, iterations)."""
    n0, n1, n2 = dims
    n = n0 * n1 * n2
    e = [dst_eigenvalues(m) for m in dims]
    eig = (e[0][:, None, None] + e[1][None, :, None] + e[2][None, None, :] - 6.0) / 6.0

    def minv(v):  # M symmetric, so this is also M⁻ᵀ
        t = dstn(v.reshape(dims), type=1, norm="ortho", workers=workers) / eig
        return dstn(t, type=1, norm="ortho", workers=workers).ravel()

    op = spla.LinearOperator(
        (a.shape[0], n), matvec=lambda v: a @ minv(v), rmatvec=lambda u: minv(a.T @ u), dtype=np.float64
    )
    res = spla.lsqr(op, b, atol=1e-12, btol=1e-12, iter_lim=iter_lim)
    return minv(res[0]), int(res[1]), int(res[2])


def peer_rows(k: int, args, config: str, threads: str, workers: int) -> list[Row]:
    t0 = time.perf_counter()
    a, b, h, dims = load_system(args.out, k)
    n = a.shape[1]
    print(f"\nk={k} ({threads}): box {dims}, A {a.shape[0]}×{n}, nnz {a.nnz} (loaded in {time.perf_counter() - t0:.2f} s)",
          flush=True)  # fmt: skip
    hscale = float(np.max(np.abs(h)))
    bnorm = float(np.linalg.norm(b))
    diff = lambda x: float(np.max(np.abs(x - h))) / hscale  # noqa: E731
    rel = lambda x: float(np.linalg.norm(b - a @ x)) / bnorm  # noqa: E731
    rows = []

    print(f"  numpy separable (warm-up + {args.sep_repeat}) …", flush=True)
    x, ms, _ = common.timed(lambda: separable_solve(b, dims, workers), args.sep_repeat)
    rows.append(Row(k, "numpy", "separable", config, threads, ms, args.sep_repeat, True, 0, rel(x), diff(x),
                    "dstn + vectorised Givens QR"))  # fmt: skip
    print(f"    {ms:.2f} ms, max rel diff to h {diff(x):.2e}", flush=True)

    print(f"  scipy dst-lsqr (warm-up + {args.plsqr_repeat}) …", flush=True)
    (x, istop, it), ms, _ = common.timed(lambda: dst_lsqr(a, b, dims, 10 * n, workers), args.plsqr_repeat)
    rows.append(Row(k, "scipy", "dst-lsqr", config, threads, ms, args.plsqr_repeat, True, it, rel(x), diff(x),
                    f"istop={istop}"))  # fmt: skip
    print(f"    {ms:.2f} ms, {it} it, max rel diff to h {diff(x):.2e}", flush=True)

    once = k > args.lsqr_once_above
    runs = 1 if once else args.lsqr_repeat
    print(f"  scipy lsqr ({'1 run, no warm-up' if once else f'warm-up + {runs}'}) …", flush=True)
    res, ms, _ = common.timed(
        lambda: spla.lsqr(a, b, atol=1e-12, btol=1e-12, iter_lim=10 * n), runs, warmup=not once
    )
    x, istop, it = res[0], int(res[1]), int(res[2])
    rows.append(Row(k, "scipy", "lsqr", config, threads, ms, runs, not once, it, rel(x), diff(x), f"istop={istop}"))
    print(f"    {ms:.2f} ms, {it} it, max rel diff to h {diff(x):.2e}", flush=True)
    return rows


def peers_here(args, config: str, workers: int) -> list[Row]:
    """Every peer on every k, with the BLAS threads this process started with."""
    threads = f"BLAS {common.blas_runtime()}; fft workers {workers}"
    rows = []
    for k in args.ks:
        rows += peer_rows(k, args, config, threads, workers)
    return rows


def worker_main(args) -> None:
    """`--worker JSON`: time the peers (BLAS as --blas-threads set it, fft --workers) and write the rows."""
    rows = peers_here(args, "all", args.workers)
    Path(args.worker).write_text(json.dumps([asdict(r) for r in rows]))


def peers_child(args, threads: int) -> list[Row]:
    out = args.out / f"restoration_bar_peers_t{threads}.json"
    out.unlink(missing_ok=True)
    argv = ["--worker", str(out), "--workers", str(threads), "--out", str(args.out), "--k", ",".join(map(str, args.ks)),
            "--k-large", "", "--sep-repeat", str(args.sep_repeat), "--plsqr-repeat", str(args.plsqr_repeat),
            "--lsqr-repeat", str(args.lsqr_repeat), "--lsqr-once-above", str(args.lsqr_once_above)]  # fmt: skip
    rc = common.run_child(Path(__file__).resolve(), argv, threads)
    if rc != 0 or not out.is_file():
        print(f"warning: the peer child with {threads} threads failed (exit {rc}); its rows are missing", flush=True)
        return []
    return [Row(**r) for r in json.loads(out.read_text())]


# ---------------------------------------------------------------------------------------------
# Step 3: cold — the first call of a fresh process


def cold_worker(args) -> None:
    """One fresh process: the first solve and `--cold-warm` more, written to --cold-json.

    zeroset: the protrusion restoration of the example's set-up through the Python binding
    (`zeroset.interpolate` of the sphere's samples on the 2k-cell grid, then `zeroset.restore`
    with face +z, α = 1 over the central k³ cells; its report's `seconds` is the solve alone);
    numpy: `separable_solve` on the b the example wrote (loading outside the timing)."""
    k = args.cold_ks[0]
    res = {"side": args.cold_worker, "k": k}
    if args.cold_worker == "zeroset":
        import zeroset

        h = 1.0 / k
        c = -1.0 + (np.arange(2 * k) + 0.5) * h
        x, y, z = np.meshgrid(c, c, c, indexing="ij")
        f = np.sqrt(x * x + y * y + z * z) - 0.6
        # The samples' quadratic B-spline, built once outside the timing (what `zeroset.restore`
        # does with a grid of samples; `_as_field` is that step alone).
        field = zeroset._as_field(f, spacing=(h,) * 3, origin=(c[0],) * 3)
        lo_i = k // 2
        lo, hi = (c[lo_i] - 0.25 * h,) * 3, (c[lo_i + k - 1] + 0.25 * h,) * 3

        def call():
            t0 = time.perf_counter()
            rep = zeroset.restore(field, (lo, hi), "protrusion", face="+z", alpha=1.0).report.as_dict()
            wall = (time.perf_counter() - t0) * 1e3
            return rep["seconds"] * 1e3, wall, rep

        first, first_wall, rep = call()
        warm = [call() for _ in range(args.cold_warm)]
        res.update(first_ms=first, first_call_ms=first_wall, warm_ms=sorted(w[0] for w in warm)[len(warm) // 2],
                   warm_call_ms=sorted(w[1] for w in warm)[len(warm) // 2], unknowns=int(rep["unknowns"]),
                   mask_cells=int(rep["mask_cells"]), solver=str(rep["solver"]))  # fmt: skip
    else:
        _, b, _, dims = load_system(args.out, k)
        t0 = time.perf_counter()
        separable_solve(b, dims, args.workers)
        res["first_ms"] = (time.perf_counter() - t0) * 1e3
        _, res["warm_ms"], _ = common.timed(lambda: separable_solve(b, dims, args.workers), args.cold_warm, False)
        res["unknowns"] = int(np.prod(dims))
    Path(args.cold_json).write_text(json.dumps(res))


def cold_runs(args) -> list[dict]:
    """--cold-runs fresh processes per side, k and thread setting; the upper medians of their
    first and warm figures."""
    import subprocess

    try:
        subprocess.run([sys.executable, "-c", "import zeroset"], check=True, capture_output=True)
        sides = ["zeroset", "numpy"]
    except subprocess.CalledProcessError:
        print("warning: the zeroset Python package is not installed (bash benches/peers/setup.sh --python); "
              "the cold zeroset figures are skipped", flush=True)  # fmt: skip
        sides = ["numpy"]
    out = []
    for k in args.cold_ks:
        for threads in [1] + ([args.mt] if args.mt else []):
            for side in sides:
                results = []
                for _ in range(args.cold_runs):  # alternate nothing: each run is its own fresh process
                    path = args.out / f"restoration_bar_cold_{side}_k{k}_t{threads}.json"
                    path.unlink(missing_ok=True)
                    env = dict(common.ORIGINAL_ENV)
                    env.update({v: str(threads) for v in common.THREAD_VARS})
                    cmd = [sys.executable, str(Path(__file__).resolve()), "--cold-worker", side, "--cold-json", str(path),
                           "--cold-k", str(k), "--cold-warm", str(args.cold_warm), "--out", str(args.out),
                           "--workers", str(threads), "--blas-threads", str(threads), "--k", str(k), "--k-large", ""]  # fmt: skip
                    subprocess.run(cmd, check=True, env=env)
                    results.append(json.loads(path.read_text()))
                med = lambda key: sorted(r[key] for r in results)[len(results) // 2]  # noqa: E731
                row = {"k": k, "side": side, "threads": threads, "runs": len(results), "first_ms": med("first_ms"),
                       "warm_ms": med("warm_ms"), "first_all": [round(r["first_ms"], 3) for r in results],
                       "unknowns": results[0]["unknowns"]}  # fmt: skip
                if side == "zeroset":
                    row.update(first_call_ms=med("first_call_ms"), warm_call_ms=med("warm_call_ms"),
                               mask_cells=results[0]["mask_cells"], solver=results[0]["solver"])  # fmt: skip
                print(f"  cold k={k} {side} {threads} thread(s): first {row['first_ms']:.2f} ms "
                      f"(runs {row['first_all']}), warm {row['warm_ms']:.2f} ms, unknowns {row['unknowns']:,}"
                      + (f", mask cells {row['mask_cells']:,}, solver {row['solver']}; whole restore call first "
                         f"{row['first_call_ms']:.1f} ms, warm {row['warm_call_ms']:.1f} ms" if side == "zeroset" else ""),
                      flush=True)  # fmt: skip
                out.append(row)
    return out


def cold_table(cold: list[dict], mt: int):
    header = ["k", "side", "threads", "first call ms (median of fresh processes)", "warm ms (same processes)",
              "first ÷ warm", "fresh-process first calls ms"]  # fmt: skip
    body = [[str(r["k"]), r["side"] + (" solve (Python binding; report's seconds)" if r["side"] == "zeroset" else
                                       " separable_solve"), str(r["threads"]), common.fmt_ms(r["first_ms"]),
             common.fmt_ms(r["warm_ms"]), fmt_ratio(common.ratio(r["first_ms"], r["warm_ms"])),
             ", ".join(f"{v:.2f}" for v in r["first_all"])] for r in cold]  # fmt: skip
    # ratios numpy ÷ zeroset on the first calls
    ratios = []
    for k in sorted({r["k"] for r in cold}):
        g = {(r["side"], r["threads"]): r["first_ms"] for r in cold if r["k"] == k}
        if ("zeroset", 1) in g and ("numpy", 1) in g:
            one = common.ratio(g[("numpy", 1)], g[("zeroset", 1)])
            zf = min(v for (sd, _), v in g.items() if sd == "zeroset")
            nf = min(v for (sd, _), v in g.items() if sd == "numpy")
            ratios.append(f"k={k}: numpy ÷ zeroset on first calls, one thread each {fmt_ratio(one)}, each at its "
                          f"fastest {fmt_ratio(common.ratio(nf, zf))}")  # fmt: skip
    return header, body, ratios


# ---------------------------------------------------------------------------------------------
# Step 4: tables and bars


def find(rows: list[Row], k: int, source: str, method: str, config: str) -> Row | None:
    return next((r for r in rows if r.k == k and r.source == source and r.method == method and r.config == config),
                None)  # fmt: skip


def ms_of(r: Row | None) -> float | None:
    return None if r is None else r.median_ms


def ms_text(r: Row | None) -> str:
    return "—" if r is None else common.with_how(r.median_ms, r.runs, r.warmup)


def compare(rows: list[Row], k: int, zs_method: str, source: str, method: str):
    """(one thread each, each at its fastest, which configurations) for peer ms ÷ zeroset ms."""
    z = {c: find(rows, k, "zeroset", zs_method, c) for c in CONFIGS}
    p = {c: find(rows, k, source, method, c) for c in CONFIGS}
    one = common.ratio(ms_of(p["1"]), ms_of(z["1"]))
    zl, zm = common.fastest({(z[c].threads if z[c] else c): ms_of(z[c]) for c in CONFIGS})
    pl, pm = common.fastest({(p[c].threads if p[c] else c): ms_of(p[c]) for c in CONFIGS})
    fast = common.ratio(pm, zm)
    return one, fast, "—" if math.isnan(fast) else f"{pl} ÷ {zl}"


def per_k_table(rows: list[Row], k: int):
    header = ["source", "method", "threads", "median_ms", "runs", "iters", "rel_res", "max|x−h|/max|h|", "note"]
    body = [
        [r.source, r.method, r.threads, common.fmt_ms(r.median_ms),
         f"{r.runs}" + ("" if r.warmup else " (no warm-up)"), fmt_int(r.iterations), fmt_e(r.rel_residual),
         fmt_e(r.max_rel_diff), r.note]
        for r in sorted((r for r in rows if r.k == k), key=lambda r: (r.source != "zeroset", r.source, r.method, r.config))
    ]  # fmt: skip
    return header, body


def summary_table(rows: list[Row], ks: list[int], mt: int):
    header = ["k", "comparison", "zeroset 1 thread ms", f"zeroset {mt or 'all'} threads ms", "peer 1 thread ms",
              f"peer {mt or 'all'} threads ms", "ratio, 1 thread each", "ratio, each at its fastest",
              "fastest configurations"]  # fmt: skip
    body = []
    for k in ks:
        for label, zm, src, meth in PAIRS:
            z = [find(rows, k, "zeroset", zm, c) for c in CONFIGS]
            p = [find(rows, k, src, meth, c) for c in CONFIGS]
            if not any(z) and not any(p):
                continue
            one, fast, which = compare(rows, k, zm, src, meth)
            body.append([str(k), label, ms_text(z[0]), ms_text(z[1]), ms_text(p[0]), ms_text(p[1]), fmt_ratio(one),
                         fmt_ratio(fast), which])  # fmt: skip
    return header, body


def check_bars(rows: list[Row]) -> common.Bars:
    bars = common.Bars()

    def speed(k: int, target: float, label: str, zm: str, src: str, meth: str) -> None:
        one, fast, which = compare(rows, k, zm, src, meth)
        bars.check(f"k={k}: {label} ≥ {target:g}×, each at its fastest", None if math.isnan(fast) else fast >= target,
                   "not measured" if math.isnan(fast) else f"{fast:.1f}× ({which})")  # fmt: skip
        bars.check(f"k={k}: {label} ≥ {target:g}×, one thread each (reported)",
                   None if math.isnan(one) else one >= target,
                   "not measured" if math.isnan(one) else f"{one:.1f}×")  # fmt: skip

    speed(32, 10, "scipy lsqr ÷ zeroset separable (assembly + solve)", "separable", "scipy", "lsqr")
    for k, limit in ((64, 100.0), (128, 1000.0)):
        zs = {c: find(rows, k, "zeroset", "separable", c) for c in CONFIGS}
        label, ms = common.fastest({(zs[c].threads if zs[c] else c): ms_of(zs[c]) for c in CONFIGS})
        bars.check(f"k={k}: zeroset separable < {limit:.0f} ms, at its fastest",
                   None if math.isnan(ms) else ms < limit,
                   "not measured" if math.isnan(ms) else f"{common.fmt_ms(ms)} ms ({label})")  # fmt: skip
        z1 = ms_of(zs["1"])
        bars.check(f"k={k}: zeroset separable < {limit:.0f} ms, one thread (reported)",
                   None if z1 is None else z1 < limit, "not measured" if z1 is None else f"{common.fmt_ms(z1)} ms")  # fmt: skip
    for k in (32, 64):
        # Like for like: both sides solve from a ready right-hand side.
        speed(k, 3, "numpy separable ÷ zeroset solve-only (like-for-like)", "solve-only", "numpy", "separable")
        speed(k, 3, "scipy dst-lsqr ÷ zeroset lsqr-poisson", "lsqr-poisson", "scipy", "dst-lsqr")
    for ns in (r for r in rows if r.source == "numpy"):
        bars.check(f"k={ns.k}: numpy separable ({ns.threads}) = zeroset h (≤ {AGREE_TOL:g} rel.)",
                   ns.max_rel_diff <= AGREE_TOL, f"max|x−h|/max|h| = {ns.max_rel_diff:.2e}")  # fmt: skip
    return bars


def main() -> None:
    args = parse_args()
    if args.worker:
        worker_main(args)
        return
    if args.cold_worker:
        cold_worker(args)
        return
    out: Path = args.out
    load_start = common.loadavg()
    print(f"BLAS threads: {BLAS_NOTE} ({common.blas_runtime()}); all-threads configuration: {args.mt or 'not run'}; "
          f"load average {load_start}\n", flush=True)  # fmt: skip

    binary = common.built_example(EXAMPLE, args.skip_build)
    rows: list[Row] = []
    for config in CONFIGS if args.mt else CONFIGS[:1]:
        if args.ks:
            rows += run_zeroset(binary, args.ks, "separable,lsqr-poisson", args.repeat, out,
                                f"restoration_bar_zeroset_t{config}.csv", config == "1", config, args.mt)  # fmt: skip
        if args.ks_large:
            rows += run_zeroset(binary, args.ks_large, "separable", args.repeat_large, out,
                                f"restoration_bar_zeroset_large_t{config}.csv", False, config, args.mt)  # fmt: skip
    load_after_cargo = common.loadavg()

    t0 = time.perf_counter()
    if args.ks:
        rows += peers_here(args, "1", 1)
        if args.mt:
            rows += peers_child(args, args.mt)
    peers_s = time.perf_counter() - t0
    load_after_scipy = common.loadavg()
    cold = cold_runs(args) if args.cold_ks and args.cold_runs > 0 else []
    ch, cbody, cratios = cold_table(cold, args.mt)
    load_after_cold = common.loadavg()

    all_ks = sorted(set(args.ks) | set(args.ks_large))
    text, md = [], []
    for k in all_ks:
        h, body = per_k_table(rows, k)
        text.append(f"\n=== k={k} ===\n{render_text(h, body, left=3, left_last=True)}")
        md.append(f"### k={k}\n\n{render_md(h, body, left=3)}\n")
    sh, sbody = summary_table(rows, all_ks, args.mt)
    bars = check_bars(rows)
    print("\n".join(text))
    print("\n=== summary (ratio = peer_ms / zeroset_ms; > 1 means zeroset is faster; one thread each: BLAS 1 + fft "
          "workers 1 vs RAYON_NUM_THREADS=1; each at its fastest: the faster configuration of each side) ===\n"
          f"{render_text(sh, sbody, left=2, left_last=True)}")  # fmt: skip
    if cold:
        print("\n=== cold: the first solve of a fresh process (what a one-shot command pays) ===\n"
              f"{render_text(ch, cbody, left=2, left_last=True)}\n" + "\n".join(cratios))
    print(f"\n=== bars ===\n{bars.text()}")

    peer_threads = sorted({r.threads for r in rows if r.source != "zeroset"})
    zs_threads = sorted({r.threads for r in rows if r.source == "zeroset"})
    facts = common.machine_facts(
        [("load average 1/5/15 min, before cargo", load_start),
         ("load average 1/5/15 min, after cargo", load_after_cargo),
         ("load average 1/5/15 min, after the peers", load_after_scipy),
         ("load average 1/5/15 min, after the cold runs", load_after_cold)],
        [("BLAS threads (Python side, one-thread run)", BLAS_NOTE),
         ("Python side configurations (OpenBLAS-reported threads)", " | ".join(peer_threads) or "not run"),
         ("zeroset configurations (from the example's CSV)", ", ".join(zs_threads) or "not run"),
         ("Python side wall time", f"{peers_s:.1f} s")],
    )  # fmt: skip

    with (out / "restoration_bar.csv").open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["k", "source", "method", "config", "threads", "median_ms", "runs", "warmup", "iterations",
                     "rel_residual", "max_rel_diff_vs_h", "note"])  # fmt: skip
        for r in rows:
            wr.writerow([r.k, r.source, r.method, r.config, r.threads, common.num(r.median_ms), r.runs, int(r.warmup),
                         common.num(r.iterations), common.num(r.rel_residual), common.num(r.max_rel_diff), r.note])  # fmt: skip

    report = [
        "## Bar: protrusion-removal solve, zeroset vs scipy / NumPy",
        "",
        f"`benches/peers/restoration_bar.py {' '.join(sys.argv[1:])}`: same system in the same run, each side at one "
        f"thread and at {args.mt or '—'} threads.",
        "",
        f"**zeroset**: `examples/restoration_timing.rs` with RAYON_NUM_THREADS=1 and RAYON_NUM_THREADS={args.mt or '—'} "
        f"(threads reported: {', '.join(zs_threads) or '—'}), median of {args.repeat} runs ({args.repeat_large} for "
        f"k = {args.k_large or '—'}) after one warm-up. `separable` and `lsqr-poisson` time `restore_in_place`: "
        "the assembly of the system from the samples + the solve + writing the solution back; `solve-only` times "
        "the separable solve alone on the ready right-hand side (the like-for-like figure for the NumPy port).",
        "",
        "**Peers**, on the A, b that example wrote (solve only, loading excluded), with BLAS pinned to one thread "
        "and scipy.fft `workers=1`, and again in a child process with BLAS at N threads and `workers=N` "
        f"({' | '.join(peer_threads) or '—'}): scipy `lsqr(A, b, atol=btol=1e-12)` (no FFT; BLAS vector "
        "operations); `numpy separable` = zeroset's separable method in NumPy/SciPy (DST-I across the lateral axes, "
        "vectorised Givens QR per mode, inverse DST-I); `dst-lsqr` = LSQR on A·M⁻¹ with M = L solved by DST-I; one "
        f"warm-up, then the median of {args.sep_repeat} / {args.plsqr_repeat} / {args.lsqr_repeat} runs (scipy lsqr: "
        f"a single run without warm-up for k > {args.lsqr_once_above}, marked next to the number).",
        "",
        "`rel_res` = ‖b − Ax‖/‖b‖ (a least-squares residual, not small, the same for all); `max|x−h|/max|h|` against "
        "zeroset's separable solution h (for zeroset rows: the example's own comparison with its default "
        "restoration). Ratios = peer_ms / zeroset_ms (> 1: zeroset faster): one thread each, and each side at its "
        "fastest (the configurations named). zeroset's `separable` and `lsqr-poisson` include the assembly, the "
        "peers do not.",
        "",
        "### Summary",
        "",
        render_md(sh, sbody, left=2),
        "",
        "### Cold: the first solve of a fresh process",
        "",
        "The medians above are warm: zeroset's solve reuses its work buffers across calls of one size, and the "
        "NumPy port reuses the heap the previous call freed. A one-shot program (`zeroset restore`) pays the "
        f"first call: here each of {args.cold_runs} fresh processes per row times its first solve and then "
        f"{args.cold_warm} more (their median is the warm figure). zeroset: `zeroset.restore` through the Python "
        "binding on the same set-up (the report's solve seconds; unknowns and mask cells checked against the "
        "example's), numpy: `separable_solve` on the loaded b (scipy.fft plans made in the first call).",
        "",
        render_md(ch, cbody, left=2) if cold else "not run",
        "",
        *[f"- {r}" for r in cratios],
        "",
        "### Bars",
        "",
        bars.md(),
        "",
        *md,
    ]
    common.write_report(out / "restoration_bar.md", out / "restoration_bar.csv", report, facts)


if __name__ == "__main__":
    main()
