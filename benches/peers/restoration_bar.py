#!/usr/bin/env python3
"""Bar check: zeroset's protrusion-removal solve vs scipy on the very same system.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/restoration_bar.py [--k 32,64] [--k-large 128]

Steps:
  1. `cargo run --release --example restoration_timing -- --k 32,64 --solvers separable,lsqr-poisson
     --write-dir OUT --csv …` times zeroset (assembly + solve) and writes, per k, the system
     A = [L; wP] (w = 1/6), b, zeroset's separable solution h and the box of unknowns; a second
     run times `--k 128 --solvers separable` without writing (too big for MatrixMarket);
  2. on the same A, b (scipy.io.mmread → CSR) times
       a. scipy `lsqr(A, b, atol=btol=1e-12)`;
       b. the same separable method as zeroset's, written in NumPy/SciPy (the like-for-like
          peer): DST-I across the two lateral axes, a Givens QR of the (tridiagonal + one row)
          line problem of every lateral mode, vectorised over the modes, inverse DST-I;
       c. LSQR on A·M⁻¹, right-preconditioned by the fast Poisson solve M = L (DST-I on all axes);
     and compares every solution with h (max |x − h| / max |h|);
  3. prints per-k tables, a summary with ratios (peer_ms / zeroset_ms: > 1 means zeroset is
     faster), PASS/FAIL per bar, and writes OUT/restoration_bar.csv and OUT/restoration_bar.md.
Always exits 0 once it has run; a failed bar is reported, not raised.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import common
from common import fmt_e, fmt_int, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads()  # before numpy is imported

import numpy as np  # noqa: E402
import scipy.io  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402
from scipy.fft import dstn  # noqa: E402

EXAMPLE = "restoration_timing"
W = 1.0 / 6.0  # neighbour weight of the Laplace rows and weight of the Neumann rows (D = 3)
AGREE_TOL = 1e-12  # like-for-like separable vs zeroset's h, relative to max |h|


@dataclass
class Row:
    """One method's result for one k."""

    k: int
    source: str  # "zeroset" | "scipy" | "numpy"
    method: str
    median_ms: float | None
    runs: int
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
    common.add_blas_arg(p)
    a = p.parse_args()

    def ks(s, flag):
        return common.int_list(p, s, flag, 3, name="k")

    a.ks, a.ks_large = ks(a.k, "--k"), ks(a.k_large, "--k-large")
    if not a.ks and not a.ks_large:
        p.error("nothing to do: --k and --k-large are both empty")
    for name in ("repeat", "repeat_large", "sep_repeat", "plsqr_repeat", "lsqr_repeat"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: zeroset


def run_zeroset(ks: list[int], solvers: str, repeat: int, out: Path, csv_name: str, write: bool) -> list[Row]:
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / csv_name
    cmd = ["cargo", "run", "--release", "--example", EXAMPLE, "--",
           "--k", ",".join(map(str, ks)), "--solvers", solvers, "--repeat", str(repeat),
           "--csv", str(csv_path)]  # fmt: skip
    if write:
        cmd += ["--write-dir", str(out)]
    common.run_logged(cmd)
    rows = []
    with csv_path.open(newline="") as f:
        for r in csv.DictReader(f):
            rows.append(
                Row(
                    k=int(r["k"]),
                    source="zeroset",
                    method=r["solver"],
                    median_ms=float(r["median_ms"]),
                    runs=repeat,
                    iterations=int(r["iterations"]),
                    rel_residual=float(r["rel_residual"] or "nan"),
                    # vs the default (separable) restoration of the example itself
                    max_rel_diff=float(r["max_rel_diff"] or "nan"),
                    note="solve alone, right-hand side ready (like NumPy's)"
                    if r["solver"] == "solve-only"
                    else "assembly + solve; rel_res, diff: from the example",
                )
            )
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


def separable_solve(b: np.ndarray, dims: tuple[int, int, int]) -> np.ndarray:
    """min ‖A x − b‖ for A = [L; wP] by zeroset's separable method, in NumPy/SciPy.

    DST-I (orthonormal, its own inverse) across axes 0 and 1 diagonalises both row blocks;
    per lateral mode (p, q) the line problem along axis 2 is
        min ‖[tridiag(w, w(σ−6), w); w e_lastᵀ] x − [r̂; ŝ]‖,  σ = λ_p + λ_q,
    solved by Givens QR: one rotation per position eliminates the subdiagonal, a last one the
    Neumann row; R has three diagonals. Every step is vectorised over all n0·n1 modes, with the
    lines stored position-major, (n2, modes), so each step touches contiguous rows.
    """
    n0, n1, n2 = dims
    n = n0 * n1 * n2
    w = W
    r = b[:n].reshape(n0, n1, n2).transpose(2, 0, 1)  # (n2, n0, n1), a view
    rhat = dstn(r, type=1, norm="ortho", axes=(1, 2)).reshape(n2, n0 * n1)
    shat = dstn(b[n:].reshape(n0, n1), type=1, norm="ortho").ravel()
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
    x = dstn(x.reshape(n2, n0, n1), type=1, norm="ortho", axes=(1, 2))
    return np.ascontiguousarray(x.transpose(1, 2, 0)).ravel()


def dst_lsqr(a, b: np.ndarray, dims: tuple[int, int, int], iter_lim: int):
    """LSQR on A·M⁻¹ with M = (1/6)Δ_h = L (the Laplace block), M⁻¹ by DST-I on all three axes;
    returns (x = M⁻¹y, istop, iterations)."""
    n0, n1, n2 = dims
    n = n0 * n1 * n2
    e = [dst_eigenvalues(m) for m in dims]
    eig = (e[0][:, None, None] + e[1][None, :, None] + e[2][None, None, :] - 6.0) / 6.0

    def minv(v):  # M symmetric, so this is also M⁻ᵀ
        return dstn(dstn(v.reshape(dims), type=1, norm="ortho") / eig, type=1, norm="ortho").ravel()

    op = spla.LinearOperator(
        (a.shape[0], n), matvec=lambda v: a @ minv(v), rmatvec=lambda u: minv(a.T @ u), dtype=np.float64
    )
    res = spla.lsqr(op, b, atol=1e-12, btol=1e-12, iter_lim=iter_lim)
    return minv(res[0]), int(res[1]), int(res[2])


def peer_rows(k: int, args, out: Path) -> list[Row]:
    t0 = time.perf_counter()
    a, b, h, dims = load_system(out, k)
    n = a.shape[1]
    print(f"\nk={k}: box {dims}, A {a.shape[0]}×{n}, nnz {a.nnz} (loaded in {time.perf_counter() - t0:.2f} s)", flush=True)
    hscale = float(np.max(np.abs(h)))
    bnorm = float(np.linalg.norm(b))
    diff = lambda x: float(np.max(np.abs(x - h))) / hscale  # noqa: E731
    rel = lambda x: float(np.linalg.norm(b - a @ x)) / bnorm  # noqa: E731
    rows = []

    print(f"  numpy separable (warm-up + {args.sep_repeat}) …", flush=True)
    x, ms, _ = common.timed(lambda: separable_solve(b, dims), args.sep_repeat)
    rows.append(Row(k, "numpy", "separable", ms, args.sep_repeat, 0, rel(x), diff(x), "dstn + vectorised Givens QR"))
    print(f"    {ms:.2f} ms, max rel diff to h {diff(x):.2e}", flush=True)

    print(f"  scipy dst-lsqr (warm-up + {args.plsqr_repeat}) …", flush=True)
    (x, istop, it), ms, _ = common.timed(lambda: dst_lsqr(a, b, dims, 10 * n), args.plsqr_repeat)
    rows.append(Row(k, "scipy", "dst-lsqr", ms, args.plsqr_repeat, it, rel(x), diff(x), f"istop={istop}"))
    print(f"    {ms:.2f} ms, {it} it, max rel diff to h {diff(x):.2e}", flush=True)

    once = k > args.lsqr_once_above
    runs = 1 if once else args.lsqr_repeat
    print(f"  scipy lsqr ({'1 run, no warm-up' if once else f'warm-up + {runs}'}) …", flush=True)
    res, ms, _ = common.timed(
        lambda: spla.lsqr(a, b, atol=1e-12, btol=1e-12, iter_lim=10 * n), runs, warmup=not once
    )
    x, istop, it = res[0], int(res[1]), int(res[2])
    rows.append(Row(k, "scipy", "lsqr", ms, runs, it, rel(x), diff(x), f"istop={istop}" + ("; single run" if once else "")))
    print(f"    {ms:.2f} ms, {it} it, max rel diff to h {diff(x):.2e}", flush=True)
    return rows


# ---------------------------------------------------------------------------------------------
# Step 3: tables and bars


def find(rows: list[Row], k: int, source: str, method: str) -> Row | None:
    return next((r for r in rows if r.k == k and r.source == source and r.method == method), None)


def ratio(num: Row | None, den: Row | None) -> float:
    if num is None or den is None or not num.median_ms or not den.median_ms:
        return math.nan
    return num.median_ms / den.median_ms


def per_k_table(rows: list[Row], k: int):
    zs = find(rows, k, "zeroset", "separable")
    header = ["source", "method", "median_ms", "runs", "iters", "rel_res", "max|x−h|/max|h|", "÷ zeroset sep", "note"]
    body = [
        [r.source, r.method, fmt_ms(r.median_ms), str(r.runs), fmt_int(r.iterations), fmt_e(r.rel_residual),
         fmt_e(r.max_rel_diff), fmt_ratio(ratio(r, zs)), r.note]
        for r in rows if r.k == k
    ]  # fmt: skip
    return header, body


def summary_table(rows: list[Row], ks: list[int]):
    header = ["k", "zeroset sep ms", "zeroset lsqr-poisson ms", "scipy lsqr ms (it)", "numpy sep ms",
              "scipy dst-lsqr ms (it)", "lsqr ÷ zs", "numpy sep ÷ zs", "dst-lsqr ÷ zs"]  # fmt: skip
    body = []
    for k in ks:
        zs, zl = find(rows, k, "zeroset", "separable"), find(rows, k, "zeroset", "lsqr-poisson")
        lq, ns, dl = find(rows, k, "scipy", "lsqr"), find(rows, k, "numpy", "separable"), find(rows, k, "scipy", "dst-lsqr")
        with_it = lambda r: "—" if r is None else f"{fmt_ms(r.median_ms)} ({r.iterations})"  # noqa: E731
        ms = lambda r: fmt_ms(None if r is None else r.median_ms)  # noqa: E731
        body.append([str(k), ms(zs), ms(zl), with_it(lq), ms(ns), with_it(dl),
                     fmt_ratio(ratio(lq, zs)), fmt_ratio(ratio(ns, zs)), fmt_ratio(ratio(dl, zs))])  # fmt: skip
    return header, body


def check_bars(rows: list[Row]) -> common.Bars:
    bars = common.Bars()
    z = lambda k: find(rows, k, "zeroset", "separable")  # noqa: E731

    zs, lq = z(32), find(rows, 32, "scipy", "lsqr")
    r = ratio(lq, zs)
    bars.check("k=32: zeroset ≥ 10× faster than scipy lsqr", None if math.isnan(r) else r >= 10,
               "not measured" if math.isnan(r) else f"{fmt_ms(lq.median_ms)} / {fmt_ms(zs.median_ms)} ms = {r:.1f}×")  # fmt: skip
    for k, limit in ((64, 100.0), (128, 1000.0)):
        zk = z(k)
        bars.check(f"k={k}: zeroset < {limit:.0f} ms", None if zk is None else zk.median_ms < limit,
                   "not measured" if zk is None else f"{fmt_ms(zk.median_ms)} ms")  # fmt: skip
    for k in (32, 64):
        # Like for like: both sides solve from a ready right-hand side.
        zk, ns = find(rows, k, "zeroset", "solve-only") or z(k), find(rows, k, "numpy", "separable")
        r = ratio(ns, zk)
        bars.check(f"k={k}: numpy separable (like-for-like) ≥ 3× slower than zeroset's solve",
                   None if math.isnan(r) else r >= 3,
                   "not measured" if math.isnan(r) else f"{fmt_ms(ns.median_ms)} / {fmt_ms(zk.median_ms)} ms = {r:.1f}×")  # fmt: skip
        zl, dl = find(rows, k, "zeroset", "lsqr-poisson"), find(rows, k, "scipy", "dst-lsqr")
        r = ratio(dl, zl)
        bars.check(f"k={k}: scipy dst-lsqr (like-for-like) ≥ 3× slower than zeroset lsqr-poisson",
                   None if math.isnan(r) else r >= 3,
                   "not measured" if math.isnan(r) else f"{fmt_ms(dl.median_ms)} / {fmt_ms(zl.median_ms)} ms = {r:.1f}×")  # fmt: skip
    for ns in (r for r in rows if r.source == "numpy"):
        bars.check(f"k={ns.k}: numpy separable = zeroset h (≤ {AGREE_TOL:g} rel.)", ns.max_rel_diff <= AGREE_TOL,
                   f"max|x−h|/max|h| = {ns.max_rel_diff:.2e}")  # fmt: skip
    return bars


def main() -> None:
    args = parse_args()
    out: Path = args.out
    load_start = common.loadavg()
    print(f"BLAS threads: {BLAS_NOTE}; load average {load_start}\n", flush=True)

    rows: list[Row] = []
    if args.ks:
        rows += run_zeroset(args.ks, "separable,lsqr-poisson", args.repeat, out, "restoration_bar_zeroset.csv", True)
    if args.ks_large:
        rows += run_zeroset(args.ks_large, "separable", args.repeat_large, out, "restoration_bar_zeroset_large.csv", False)
    load_after_cargo = common.loadavg()

    for k in args.ks:
        rows += peer_rows(k, args, out)
    load_after_scipy = common.loadavg()

    all_ks = sorted(set(args.ks) | set(args.ks_large))
    text, md = [], []
    for k in all_ks:
        h, body = per_k_table(rows, k)
        text.append(f"\n=== k={k} ===\n{render_text(h, body, left_last=True)}")
        md.append(f"### k={k}\n\n{render_md(h, body)}\n")
    sh, sbody = summary_table(rows, all_ks)
    bars = check_bars(rows)
    print("\n".join(text))
    print(f"\n=== summary (÷ zs = peer_ms / zeroset separable ms; > 1 means zeroset is faster) ===\n{render_text(sh, sbody, left=1)}")
    print(f"\n=== bars ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, before cargo", load_start),
         ("load average 1/5/15 min, after cargo", load_after_cargo),
         ("load average 1/5/15 min, after scipy", load_after_scipy)],
        [("BLAS threads (scipy side)", BLAS_NOTE)],
    )  # fmt: skip

    with (out / "restoration_bar.csv").open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["k", "source", "method", "median_ms", "runs", "iterations", "rel_residual",
                     "max_rel_diff_vs_h", "ratio_over_zeroset_separable", "note"])  # fmt: skip
        for r in rows:
            wr.writerow([r.k, r.source, r.method, common.num(r.median_ms), r.runs, common.num(r.iterations),
                         common.num(r.rel_residual), common.num(r.max_rel_diff),
                         common.num(ratio(r, find(rows, r.k, "zeroset", "separable"))), r.note])  # fmt: skip

    report = [
        "## Bar: protrusion-removal solve, zeroset vs scipy / NumPy",
        "",
        f"`benches/peers/restoration_bar.py {' '.join(sys.argv[1:])}`: same system in the same run. "
        f"zeroset: `examples/restoration_timing.rs`, median of {args.repeat} runs ({args.repeat_large} for "
        f"k = {args.k_large or '—'}) after one warm-up of "
        "`restore_in_place` (assembly of the system from the samples + solve). Peers, on the A, b that "
        "example wrote (solve only, loading excluded): scipy `lsqr(A, b, atol=btol=1e-12)`; "
        "`numpy separable` = zeroset's separable method in NumPy/SciPy (DST-I across the lateral axes, "
        "vectorised Givens QR per mode, inverse DST-I); `dst-lsqr` = LSQR on A·M⁻¹ with M = L solved by "
        "DST-I. `rel_res` = ‖b − Ax‖/‖b‖ (a least-squares residual, not small, the same for all); "
        "`max|x−h|/max|h|` against zeroset's separable solution h (for zeroset rows: the example's own "
        "comparison with its default restoration). Ratio = peer_ms / zeroset separable ms (> 1: zeroset faster). "
        f"scipy BLAS threads: {BLAS_NOTE}.",
        "",
        "### Summary",
        "",
        render_md(sh, sbody, left=1),
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
