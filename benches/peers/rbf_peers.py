#!/usr/bin/env python3
"""Peer comparison: zeroset's RBF implicit-surface fit and evaluation vs scipy.interpolate.RBFInterpolator.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/rbf_peers.py [--n 1000,3000,6000] [--eval 100000]

Set-up: a sphere, centre (0.5, 0.5, 0.5), radius 0.35; per N, N − 2⌊N/3⌋ on-surface points
(value 0), ⌊N/3⌋ points 0.05 along the outward normal (value +0.05) and ⌊N/3⌋ at −0.05 (value
−0.05); M evaluation points uniform in [0, 1]³. Kernels: zeroset `r` (φ = r) against scipy
'linear' (φ = −r; with the degree-1 polynomial part this is the same interpolant, the RBF
coefficients just change sign) and zeroset `r3` against scipy 'cubic' (φ = r³), both degree=1.

Threads: both sides are timed at one thread and at all threads (N = --mt-threads, default the
CPUs available), and the report gives the ratios one thread each and each side at its fastest.

  1. `cargo build --release --example rbf_timing` (CARGO_TARGET_DIR honoured; --skip-build reuses
     the binary), then `rbf_timing --n … --kernels r,r3 --eval M --repeat R --csv …` twice: with
     RAYON_NUM_THREADS=1 (this run also writes the points: `--write-dir OUT`) and with
     RAYON_NUM_THREADS=N. Timed by the example (one warm-up, then the median of R; a single run
     without warm-up where the first run takes over 2 s, and the CSV says so):
       fit  = from the plain point and value arrays to a field ready to evaluate (building the
              constraints, validation, the kernel matrix, the factorisation and solve, the
              refinement step and the residual check, the field's construction);
       eval = the field's values at the M points into a new array.
     Points: OUT/rbf_sphere_n{N}.csv (`x,y,z,value`), OUT/rbf_eval_{M}.csv (`x,y,z`; 17
     significant digits, so both sides see bit-identical input); results
     OUT/rbf_zeroset_t1.csv and OUT/rbf_zeroset_tall.csv, one row per (n, kernel, solver).
     `--skip-zeroset` reuses those files instead of running cargo;
  2. on the same points (read back, not regenerated), times scipy with BLAS pinned to one thread
     in this process, and again with BLAS at N threads in a child process (OpenBLAS reads its
     thread count at import; numpy's and scipy's wheels each bundle one, both are pinned and the
     counts they report are recorded):
       fit  = `RBFInterpolator(points, values, kernel=K, degree=1)` — input checks, the
              polynomial's scaling, the kernel matrix (single-threaded compiled code) and the
              solve (LAPACK dgesv, LU);
       eval = its `__call__` at the M points (kernel matrix by compiled code, product by BLAS);
     each one warm-up + median of --scipy-repeat, a single run without warm-up for
     N > --scipy-once-above (marked next to the number). Accuracy as zeroset's: max |s(x) − sd(x)|
     over the evaluation points with |sd(x)| < 0.05, sd(x) = |x − c| − 0.35, and the constraint
     residual max |s(x_i) − v_i| (untimed).
     scipy's documented speed setting, its local mode, is timed too: at the N of --neighbors-n and
     each k of --neighbors, `RBFInterpolator(points, values, kernel=K, degree=1, neighbors=k)` and
     its `__call__` (each evaluation point interpolated from its k nearest fit points: a piecewise
     smooth, not a global, interpolant; the fit builds a KD-tree, the evaluation solves a small
     system per distinct neighbourhood), with the same band error; its fit + evaluation is compared
     with zeroset's fit + evaluation (and scipy's global fit + evaluation likewise);
  3. prints fit, evaluation and accuracy tables with ratios (scipy_ms / zeroset_ms, > 1 means
     zeroset is faster) one thread each and each side at its fastest, PASS/FAIL per bar, and
     writes OUT/rbf_peers.csv and OUT/rbf_peers.md.
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
from common import fmt_e, fmt_ratio, ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402
from scipy.interpolate import RBFInterpolator  # noqa: E402

EXAMPLE = "rbf_timing"
ZS_CSV = {"1": "rbf_zeroset_t1.csv", "all": "rbf_zeroset_tall.csv"}  # per zeroset configuration
SCIPY_KERNEL = {"r": "linear", "r3": "cubic"}  # zeroset kernel name -> scipy kernel name
DEGREE = 1
CENTRE = np.array([0.5, 0.5, 0.5])
RADIUS = 0.35
OFFSET = 0.05  # normal offset of the off-surface points, and half-width of the accuracy band
BAR_NS = (1000, 3000, 6000)  # N at which the accuracy bars are checked
SPEED_N = 6000  # N at which the speed bars are checked
FIT_BAR, EVAL_BAR = 3.0, 5.0  # scipy ms / zeroset ms, each at its fastest
ACC_SLACK = 1e-3  # "at least as accurate": zeroset ≤ scipy · (1 + ACC_SLACK)
RESIDUAL_TOL = 1e-10  # zeroset's constraint residual, every row


@dataclass
class ZsRow:
    """One row of the example's CSV; None where a field is empty."""

    n: int
    kernel: str
    solver: str
    fit_ms: float | None
    eval_ms: float | None
    max_err: float | None  # max |s − sd| over the band
    residual: float | None  # max |s(x_i) − v_i|
    runs: int | None  # timed fit runs
    threads: str | None
    fit_warmup: bool | None = None
    eval_runs: int | None = None
    eval_warmup: bool | None = None


@dataclass
class SpRow:
    """scipy's result for one (n, kernel) at one BLAS setting."""

    n: int
    kernel: str  # zeroset's name
    runs: int
    single: bool  # one run without warm-up (n > --scipy-once-above)
    blas: str = ""  # the thread counts numpy's and scipy's OpenBLAS report
    fit_ms: float = math.nan
    eval_ms: float = math.nan
    max_err: float = math.nan
    residual: float = math.nan


@dataclass
class LocalRow:
    """scipy's local mode (`neighbors=k`) for one (n, kernel, k) at one BLAS setting."""

    n: int
    kernel: str  # zeroset's name
    k: int
    runs: int
    single: bool  # one run without warm-up (the first fit + evaluation took over --local-once-above-s)
    blas: str = ""
    fit_ms: float = math.nan
    eval_ms: float = math.nan
    total_ms: float = math.nan  # fit + evaluation, timed together
    max_err: float = math.nan
    residual: float = math.nan


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Time scipy's RBFInterpolator on the same sphere data zeroset fits and evaluates.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--n", default="1000,3000,6000", help="numbers of fit points")
    p.add_argument("--kernels", default="r,r3", help=f"zeroset kernels, from {sorted(SCIPY_KERNEL)}")
    p.add_argument("--eval", type=int, default=100_000, help="evaluation points, uniform in [0, 1]³")
    p.add_argument("--repeat", type=int, default=5, help="zeroset timed runs after one warm-up")
    p.add_argument("--scipy-repeat", type=int, default=3, help="scipy fit and evaluation: timed runs after one warm-up")
    p.add_argument(
        "--scipy-once-above",
        type=int,
        default=3000,
        metavar="N",
        help="for n > N time scipy's fit and evaluation once each, without warm-up (seconds each)",
    )
    p.add_argument("--neighbors", default="20,50",
                   help="scipy local mode: RBFInterpolator(..., neighbors=k) for these k ('' for none)")
    p.add_argument("--neighbors-n", default=str(SPEED_N), help="the n at which the local mode is timed")
    p.add_argument("--local-once-above-s", type=float, default=8.0, metavar="S",
                   help="local mode: where the first fit + evaluation takes over S seconds, it is the one run "
                   "(no warm-up, no repeats)")
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the point files, CSV and report")
    p.add_argument(
        "--skip-zeroset",
        action="store_true",
        help=f"do not run cargo; reuse the point files and {', '.join(ZS_CSV.values())} already in --out "
        "(only scipy is timed now)",
    )
    p.add_argument("--skip-build", action="store_true", help="do not run cargo build; reuse the example binary")
    p.add_argument("--worker", metavar="JSON", help=argparse.SUPPRESS)  # child: time scipy, write JSON
    common.add_mt_arg(p, "scipy's BLAS at N threads")
    common.add_blas_arg(p)
    a = p.parse_args()

    a.ns = common.int_list(p, a.n, "--n", 12)
    a.neighbor_ks = common.int_list(p, a.neighbors, "--neighbors", 1, "k") if a.neighbors.strip() else []
    a.neighbor_ns = common.int_list(p, a.neighbors_n, "--neighbors-n", 12) if a.neighbors_n.strip() else []
    a.neighbor_ns = [n for n in a.neighbor_ns if n in a.ns]
    if not a.ns:
        p.error("nothing to do: --n is empty")
    a.kernel_list = [k.strip() for k in a.kernels.split(",") if k.strip()]
    if not a.kernel_list or any(k not in SCIPY_KERNEL for k in a.kernel_list):
        p.error(f"--kernels: expected a comma-separated subset of {sorted(SCIPY_KERNEL)}, got {a.kernels!r}")
    for name in ("eval", "repeat", "scipy_repeat"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if a.mt_threads < 0:
        p.error("--mt-threads must be >= 0")
    a.mt = a.mt_threads if a.mt_threads > 1 else 0  # 0: one-thread runs only
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: zeroset


def run_zeroset(args, binary: Path, config: str) -> None:
    """`config` "1": RAYON_NUM_THREADS=1 (and writes the point files); "all": RAYON_NUM_THREADS=N."""
    args.out.mkdir(parents=True, exist_ok=True)
    cmd = [str(binary), "--n", ",".join(map(str, args.ns)), "--kernels", ",".join(args.kernel_list),
           "--eval", str(args.eval), "--repeat", str(args.repeat), "--csv", str(args.out / ZS_CSV[config])]  # fmt: skip
    if config == "1":
        cmd += ["--write-dir", str(args.out)]
    threads = "1" if config == "1" else str(args.mt)
    common.run_logged(cmd, env={"RAYON_NUM_THREADS": threads})


def read_zeroset(path: Path) -> list[ZsRow]:
    """Reads the example's CSV: empty cells are missing values, unknown columns are ignored."""
    if not path.is_file():
        sys.exit(f"{path} not found (the example did not write it)")
    required = ("n", "kernel", "solver", "fit_ms", "eval_ms", "max_err_band", "max_constraint_residual", "runs")

    def cell(r: dict, key: str, conv):
        v = (r.get(key) or "").strip()
        return conv(v) if v else None

    flag = lambda v: v not in ("0", "false")  # noqa: E731
    rows = []
    with path.open(newline="") as f:
        rd = csv.DictReader(f)
        missing = [c for c in required if c not in (rd.fieldnames or [])]
        if missing:
            sys.exit(f"{path}: missing columns {missing} (header: {rd.fieldnames})")
        for r in rd:
            rows.append(
                ZsRow(
                    n=int(r["n"]),
                    kernel=r["kernel"].strip(),
                    solver=r["solver"].strip(),
                    fit_ms=cell(r, "fit_ms", float),
                    eval_ms=cell(r, "eval_ms", float),
                    max_err=cell(r, "max_err_band", float),
                    residual=cell(r, "max_constraint_residual", float),
                    runs=cell(r, "runs", int),
                    threads=cell(r, "threads", str),
                    fit_warmup=cell(r, "fit_warmup", flag),
                    eval_runs=cell(r, "eval_runs", int),
                    eval_warmup=cell(r, "eval_warmup", flag),
                )
            )
    return rows


# ---------------------------------------------------------------------------------------------
# Step 2: scipy


def read_points(path: Path, columns: list[str]) -> np.ndarray:
    """A numeric CSV with exactly the header `columns`, as an (rows, len(columns)) float64 array.

    numpy's parser rounds correctly, so the 17-digit decimals give back zeroset's doubles exactly."""
    if not path.is_file():
        sys.exit(f"{path} not found (the example did not write it; with --skip-zeroset, same --n / --eval?)")
    with path.open() as f:
        header = [c.strip() for c in f.readline().split(",")]
    if header != columns:
        sys.exit(f"{path}: header {header}, expected {columns}")
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=np.float64)


def signed_distance(x: np.ndarray) -> np.ndarray:
    return np.linalg.norm(x - CENTRE, axis=1) - RADIUS


def load_fit_points(out: Path, n: int, verbose: bool = True) -> tuple[np.ndarray, np.ndarray]:
    data = read_points(out / f"rbf_sphere_n{n}.csv", ["x", "y", "z", "value"])
    if data.shape[0] != n:
        sys.exit(f"rbf_sphere_n{n}.csv: {data.shape[0]} points, expected {n}")
    pts, vals = np.ascontiguousarray(data[:, :3]), data[:, 3].copy()
    # Sanity check of the set-up (printed, not enforced): value counts, and value = sd(point).
    third = n // 3
    counts = [int(np.sum(vals == v)) for v in (0.0, OFFSET, -OFFSET)]
    if counts != [n - 2 * third, third, third]:
        print(f"  warning: value counts (0, +{OFFSET}, −{OFFSET}) = {counts}, expected "
              f"{[n - 2 * third, third, third]}", flush=True)  # fmt: skip
    if verbose:
        print(f"  {n} fit points; max |sd(x_i) − v_i| = {np.max(np.abs(signed_distance(pts) - vals)):.1e}", flush=True)
    return pts, vals


def load_eval_points(out: Path, m: int) -> np.ndarray:
    xe = read_points(out / f"rbf_eval_{m}.csv", ["x", "y", "z"])
    if xe.shape[0] != m:
        sys.exit(f"rbf_eval_{m}.csv: {xe.shape[0]} points, expected {m}")
    return np.ascontiguousarray(xe)


def run_scipy(n: int, kernel: str, pts, vals, xe, band, sd_band, args, blas: str) -> SpRow:
    single = n > args.scipy_once_above
    row = SpRow(n, kernel, 1 if single else args.scipy_repeat, single, blas)
    how = "1 run, no warm-up" if single else f"warm-up + {row.runs}"
    sk = SCIPY_KERNEL[kernel]
    print(f"  scipy RBFInterpolator kernel={sk!r}, degree={DEGREE}, BLAS threads {blas}: fit and eval ({how} each) …",
          flush=True)  # fmt: skip
    interp, row.fit_ms, _ = common.timed(
        lambda: RBFInterpolator(pts, vals, kernel=sk, degree=DEGREE), row.runs, warmup=not single
    )
    s, row.eval_ms, _ = common.timed(lambda: interp(xe), row.runs, warmup=not single)
    row.max_err = float(np.max(np.abs(s[band] - sd_band)))
    row.residual = float(np.max(np.abs(interp(pts) - vals)))  # untimed
    print(f"    fit {row.fit_ms:.1f} ms, eval {row.eval_ms:.1f} ms; max err in band {row.max_err:.3e}, "
          f"residual {row.residual:.1e}", flush=True)  # fmt: skip
    return row


def run_scipy_local(n: int, kernel: str, k: int, pts, vals, xe, band, sd_band, args, blas: str) -> LocalRow:
    """scipy's local mode: fit (KD-tree) and evaluation (a small solve per neighbourhood), timed
    separately and together; one warm-up + median of --scipy-repeat, or one run where the first
    fit + evaluation takes over --local-once-above-s."""
    sk = SCIPY_KERNEL[kernel]
    print(f"  scipy RBFInterpolator kernel={sk!r}, degree={DEGREE}, neighbors={k}, BLAS threads {blas} …", flush=True)

    def once():
        t0 = time.perf_counter()
        interp = RBFInterpolator(pts, vals, kernel=sk, degree=DEGREE, neighbors=k)
        t1 = time.perf_counter()
        s = interp(xe)
        t2 = time.perf_counter()
        return interp, s, (t1 - t0) * 1e3, (t2 - t1) * 1e3, (t2 - t0) * 1e3

    first = once()
    single = first[4] > args.local_once_above_s * 1e3
    runs = [first] if single else [once() for _ in range(args.scipy_repeat)]
    med = lambda i: sorted(r[i] for r in runs)[len(runs) // 2]  # noqa: E731  (upper median, common.timed's rule)
    interp, s = runs[-1][0], runs[-1][1]
    row = LocalRow(n, kernel, k, len(runs), single, blas, med(2), med(3), med(4))
    row.max_err = float(np.max(np.abs(s[band] - sd_band)))
    row.residual = float(np.max(np.abs(interp(pts) - vals)))  # untimed
    how = "1 run, no warm-up" if single else f"warm-up + median of {len(runs)}"
    print(f"    fit {row.fit_ms:.1f} ms, eval {row.eval_ms:.1f} ms, together {row.total_ms:.1f} ms ({how}); "
          f"max err in band {row.max_err:.3e}, residual {row.residual:.1e}", flush=True)  # fmt: skip
    return row


def scipy_all(args) -> tuple[list[SpRow], list[LocalRow]]:
    """Times scipy on every (n, kernel) with the BLAS threads this process started with, and its
    local mode at --neighbors-n."""
    blas = common.blas_runtime()
    t0 = time.perf_counter()
    xe = load_eval_points(args.out, args.eval)
    sd = signed_distance(xe)
    band = np.abs(sd) < OFFSET
    print(f"\n{args.eval:,} evaluation points, {int(np.count_nonzero(band)):,} in the band |sd| < {OFFSET} "
          f"(loaded in {time.perf_counter() - t0:.2f} s); BLAS threads {blas}", flush=True)  # fmt: skip
    rows, local = [], []
    for n in args.ns:
        print(f"\n--- n={n} ---", flush=True)
        pts, vals = load_fit_points(args.out, n)
        for k in args.kernel_list:
            rows.append(run_scipy(n, k, pts, vals, xe, band, sd[band], args, blas))
            if n in args.neighbor_ns:
                for nb in args.neighbor_ks:
                    local.append(run_scipy_local(n, k, nb, pts, vals, xe, band, sd[band], args, blas))
    return rows, local


def worker_main(args) -> None:
    """`--worker JSON`: time scipy (BLAS threads as --blas-threads set them) and write the rows."""
    rows, local = scipy_all(args)
    Path(args.worker).write_text(json.dumps({"global": [asdict(r) for r in rows], "local": [asdict(r) for r in local]}))


def scipy_child(args, threads: int) -> tuple[list[SpRow], list[LocalRow], str]:
    """scipy_all in a child process whose BLAS starts with `threads` threads."""
    out = args.out / f"rbf_scipy_blas{threads}.json"
    out.unlink(missing_ok=True)
    argv = ["--worker", str(out), "--out", str(args.out), "--n", ",".join(map(str, args.ns)),
            "--kernels", ",".join(args.kernel_list), "--eval", str(args.eval),
            "--scipy-repeat", str(args.scipy_repeat), "--scipy-once-above", str(args.scipy_once_above),
            "--neighbors", args.neighbors, "--neighbors-n", args.neighbors_n,
            "--local-once-above-s", str(args.local_once_above_s)]  # fmt: skip
    rc = common.run_child(Path(__file__).resolve(), argv, threads)
    if rc != 0 or not out.is_file():
        print(f"warning: the scipy child with BLAS {threads} failed (exit {rc}); its columns are missing", flush=True)
        return [], [], f"child failed (exit {rc})"
    data = json.loads(out.read_text())
    rows = [SpRow(**r) for r in data["global"]]
    local = [LocalRow(**r) for r in data["local"]]
    return rows, local, rows[0].blas if rows else "?"


# ---------------------------------------------------------------------------------------------
# Step 3: tables and bars


def kernel_order(k: str) -> int:
    return list(SCIPY_KERNEL).index(k) if k in SCIPY_KERNEL else len(SCIPY_KERNEL)


@dataclass
class Case:
    """One (n, kernel, zeroset solver): zeroset at 1 and all threads, scipy at BLAS 1 and N."""

    n: int
    kernel: str
    solver: str
    zs1: ZsRow | None
    zsn: ZsRow | None
    sp1: SpRow | None
    spn: SpRow | None

    def zs(self) -> dict:
        return {"zeroset 1 thread": self.zs1, "zeroset all threads": self.zsn}

    def sp(self) -> dict:
        return {"scipy BLAS 1": self.sp1, "scipy BLAS N": self.spn}


def cases(zs1: list[ZsRow], zsn: list[ZsRow], sp1: list[SpRow], spn: list[SpRow]) -> list[Case]:
    """One entry per (n, kernel, zeroset solver) — several solvers per (n, kernel) are possible —
    plus the (n, kernel) scipy measured and zeroset did not report."""
    z1 = {(r.n, r.kernel, r.solver): r for r in zs1}
    zn = {(r.n, r.kernel, r.solver): r for r in zsn}
    s1 = {(r.n, r.kernel): r for r in sp1}
    sn = {(r.n, r.kernel): r for r in spn}
    keys = set(z1) | set(zn)
    keys |= {(n, k, "—") for n, k in set(s1) | set(sn) if not any(kk[:2] == (n, k) for kk in keys)}
    out = []
    for n, k, s in sorted(keys, key=lambda t: (t[0], kernel_order(t[1]), t[1], t[2])):
        out.append(Case(n, k, s, z1.get((n, k, s)), zn.get((n, k, s)), s1.get((n, k)), sn.get((n, k))))
    return out


def zs_ms(z: ZsRow | None, what: str, repeat: int) -> str:
    if z is None:
        return "—"
    if what == "fit":
        return common.with_how(z.fit_ms, z.runs, z.fit_warmup, repeat)
    return common.with_how(z.eval_ms, z.eval_runs, z.eval_warmup, repeat)


def sp_ms(s: SpRow | None, what: str, repeat: int) -> str:
    if s is None:
        return "—"
    return common.with_how(getattr(s, f"{what}_ms"), s.runs, not s.single, repeat)


def ratios(c: Case, what: str) -> tuple[float, float, str]:
    """(one thread each, each at its fastest, which configurations were fastest)."""
    attr = f"{what}_ms"
    get = lambda r: None if r is None else getattr(r, attr)  # noqa: E731
    one = ratio(get(c.sp1), get(c.zs1))
    zl, zm = common.fastest({k: get(v) for k, v in c.zs().items()})
    sl, sm = common.fastest({k: get(v) for k, v in c.sp().items()})
    fast = ratio(sm, zm)
    return one, fast, "—" if math.isnan(fast) else f"{sl} ÷ {zl}"


def time_table(cs: list[Case], what: str, args, mt: int):
    header = ["n", "kernel", "zeroset solver", "zeroset 1 thread", f"zeroset {mt or 'all'} threads", "scipy BLAS 1",
              f"scipy BLAS {mt or 'N'}", "scipy ÷ zeroset, 1 thread each", "scipy ÷ zeroset, each at its fastest",
              "fastest configurations"]  # fmt: skip
    body = []
    for c in cs:
        one, best, which = ratios(c, what)
        body.append([str(c.n), f"{c.kernel} / {SCIPY_KERNEL.get(c.kernel, '?')}", c.solver,
                     zs_ms(c.zs1, what, args.repeat), zs_ms(c.zsn, what, args.repeat),
                     sp_ms(c.sp1, what, args.scipy_repeat), sp_ms(c.spn, what, args.scipy_repeat),
                     fmt_ratio(one), fmt_ratio(best), which])  # fmt: skip
    return header, body


def worst(*vals) -> float | None:
    v = [x for x in vals if x is not None and not math.isnan(x)]
    return max(v) if v else None


def best(*vals) -> float | None:
    v = [x for x in vals if x is not None and not math.isnan(x)]
    return min(v) if v else None


def accuracy_table(cs: list[Case]):
    header = ["n", "kernel", "zeroset solver", "zeroset max err (1 thread)", "zeroset max err (all)",
              "scipy max err (BLAS 1)", "scipy max err (BLAS N)", "zeroset residual (worst)", "scipy residual (BLAS 1)"]  # fmt: skip
    g = lambda r, a: None if r is None else getattr(r, a)  # noqa: E731
    body = [[str(c.n), f"{c.kernel} / {SCIPY_KERNEL.get(c.kernel, '?')}", c.solver,
             fmt_e(g(c.zs1, "max_err")), fmt_e(g(c.zsn, "max_err")), fmt_e(g(c.sp1, "max_err")),
             fmt_e(g(c.spn, "max_err")), fmt_e(worst(g(c.zs1, "residual"), g(c.zsn, "residual"))),
             fmt_e(g(c.sp1, "residual"))] for c in cs]  # fmt: skip
    return header, body


def total_table(cs: list[Case], loc1: list[LocalRow], locn: list[LocalRow], args, mt: int):
    """Fit + evaluation, what a user of `RBFInterpolator(...)(x)` pays: zeroset's fit + eval
    against scipy's global interpolant and its local mode (neighbors=k), with the band error."""
    header = ["n", "kernel", "scipy mode", f"zeroset 1 / {mt or 'all'} threads ms", f"scipy BLAS 1 / {mt or 'N'} ms",
              "scipy ÷ zeroset, 1 thread each", "scipy ÷ zeroset, each at its fastest", "zeroset max err",
              "scipy max err", "scipy residual"]  # fmt: skip
    g = lambda r, a: None if r is None else getattr(r, a)  # noqa: E731
    add = lambda r: None if r is None or r.fit_ms is None or r.eval_ms is None else r.fit_ms + r.eval_ms  # noqa: E731
    body = []
    for c in cs:
        if c.zs1 is None and c.zsn is None:
            continue
        z1, zn = add(c.zs1), add(c.zsn)
        zf = common.fastest({"1": z1, "N": zn})[1]
        zerr = worst(g(c.zs1, "max_err"), g(c.zsn, "max_err"))
        modes = [("global (LU)", add(c.sp1), add(c.spn),
                  best(g(c.sp1, "max_err"), g(c.spn, "max_err")), g(c.sp1, "residual"), "")]
        for k in args.neighbor_ks:
            l1 = next((r for r in loc1 if (r.n, r.kernel, r.k) == (c.n, c.kernel, k)), None)
            ln = next((r for r in locn if (r.n, r.kernel, r.k) == (c.n, c.kernel, k)), None)
            if l1 is None and ln is None:
                continue
            note = " (1 run, no warm-up)" if any(r is not None and r.single for r in (l1, ln)) else ""
            modes.append((f"neighbors={k}", g(l1, "total_ms"), g(ln, "total_ms"),
                          best(g(l1, "max_err"), g(ln, "max_err")), g(l1, "residual"), note))
        for label, s1, sn, serr, sres, note in modes:
            sf = common.fastest({"1": s1, "N": sn})[1]
            body.append([str(c.n), f"{c.kernel} / {SCIPY_KERNEL.get(c.kernel, '?')}", label,
                         f"{common.fmt_ms(z1)} / {common.fmt_ms(zn)}", f"{common.fmt_ms(s1)} / {common.fmt_ms(sn)}{note}",
                         fmt_ratio(ratio(s1, z1)), fmt_ratio(ratio(sf, zf)), fmt_e(zerr), fmt_e(serr),
                         fmt_e(sres)])  # fmt: skip
    return header, body


def check_bars(cs: list[Case], args) -> common.Bars:
    bars = common.Bars()
    g = lambda r, a: None if r is None else getattr(r, a)  # noqa: E731
    where = lambda c: "" if c.solver == "—" else f" ({c.solver})"  # noqa: E731

    # Accuracy: zeroset's worse run at least as accurate as scipy's better one, in the band.
    for k in SCIPY_KERNEL:
        for n in BAR_NS:
            found = [c for c in cs if c.n == n and c.kernel == k]
            label = lambda c: f"n={n} {k}{where(c) if c else ''}: zeroset max err in band ≤ scipy's (× {1 + ACC_SLACK:g})"  # noqa: E731
            if not found:
                bars.check(label(None), None, "not measured")
            for c in found:
                zm = worst(g(c.zs1, "max_err"), g(c.zsn, "max_err"))
                sm = best(g(c.sp1, "max_err"), g(c.spn, "max_err"))
                if zm is None or sm is None:
                    bars.check(label(c), None, "not measured")
                    continue
                bars.check(label(c), zm <= sm * (1 + ACC_SLACK),
                           f"{zm:.3e} vs {sm:.3e} (ratio {zm / sm:.3f}; zeroset's worse run, scipy's better)")  # fmt: skip

    # Constraint residual, every zeroset row (also the zeroset-only ones), both thread settings.
    for c in cs:
        for label, z in (("1 thread", c.zs1), ("all threads", c.zsn)):
            if z is None:
                continue
            bars.check(f"n={c.n} {c.kernel}{where(c)} ({label}): constraint residual ≤ {RESIDUAL_TOL:g}",
                       None if z.residual is None else z.residual <= RESIDUAL_TOL,
                       "not reported" if z.residual is None else f"{z.residual:.2e}")  # fmt: skip

    # Speed at n = SPEED_N, per kernel (and per zeroset solver, if several): the bar each side at
    # its fastest; one thread each reported beside it.
    for k in SCIPY_KERNEL:
        for what, target, label_what in (("fit", FIT_BAR, "fit"), ("eval", EVAL_BAR, f"eval {args.eval:,} pts")):
            found = [c for c in cs if c.n == SPEED_N and c.kernel == k]
            if not found:
                bars.check(f"n={SPEED_N} {k}: {label_what} ≥ {target:g}× faster than scipy (each at its fastest)",
                           None, "not measured")  # fmt: skip
            for c in found:
                one, fast, which = ratios(c, what)
                bars.check(f"n={SPEED_N} {k}{where(c)}: {label_what} ≥ {target:g}× faster than scipy, each at its "
                           "fastest", None if math.isnan(fast) else fast >= target, f"{fmt_ratio(fast)} ({which})")  # fmt: skip
                bars.check(f"n={SPEED_N} {k}{where(c)}: {label_what} ≥ {target:g}× faster than scipy, one thread "
                           "each (reported)", None if math.isnan(one) else one >= target,
                           f"{fmt_ratio(one)} (scipy BLAS 1 ÷ zeroset RAYON_NUM_THREADS=1)")  # fmt: skip
    return bars


def write_csv(path: Path, cs: list[Case], args, n_band: int) -> None:
    cols = ["n", "kernel", "scipy_kernel", "zeroset_solver", "side", "threads", "fit_ms", "fit_runs", "fit_warmup",
            "eval_ms", "eval_runs", "eval_warmup", "max_err_band", "max_constraint_residual", "eval_points",
            "band_points", "ratio_fit_one_thread_each", "ratio_fit_each_fastest", "ratio_eval_one_thread_each",
            "ratio_eval_each_fastest"]  # fmt: skip
    with path.open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(cols)
        for c in cs:
            rf = ratios(c, "fit")
            re_ = ratios(c, "eval")
            tail = [common.num(v) for v in (rf[0], rf[1], re_[0], re_[1])]
            head = [c.n, c.kernel, SCIPY_KERNEL.get(c.kernel, ""), c.solver]
            for label, z in (("rayon 1", c.zs1), ("rayon all", c.zsn)):
                if z is not None:
                    wr.writerow(head + ["zeroset", z.threads or label] + [common.num(v) for v in (
                        z.fit_ms, z.runs, None if z.fit_warmup is None else int(z.fit_warmup), z.eval_ms, z.eval_runs,
                        None if z.eval_warmup is None else int(z.eval_warmup), z.max_err, z.residual)]
                        + [args.eval, n_band] + tail)  # fmt: skip
            for s in (c.sp1, c.spn):
                if s is not None:
                    wr.writerow(head + ["scipy", f"BLAS {s.blas}"] + [common.num(v) for v in (
                        s.fit_ms, s.runs, int(not s.single), s.eval_ms, s.runs, int(not s.single), s.max_err,
                        s.residual)] + [args.eval, n_band] + tail)  # fmt: skip


def main() -> None:
    args = parse_args()
    if args.worker:
        worker_main(args)
        return
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    print(f"BLAS threads: {BLAS_NOTE} ({common.blas_runtime()}); all-threads configuration: "
          f"{args.mt or 'not run'}; load average {load_start}\n", flush=True)  # fmt: skip

    zs1, zsn = common.run_and_read_zeroset(args, EXAMPLE, ZS_CSV, run_zeroset, read_zeroset, "the point files")
    for rows, label in [(zs1, "1 thread")] + ([(zsn, "all threads")] if args.mt else []):
        for n in args.ns:
            for k in args.kernel_list:
                if not any(r.n == n and r.kernel == k for r in rows):
                    print(f"warning: no zeroset row ({label}) for n={n}, kernel {k}", flush=True)
    bad = [r for r in zs1 if r.threads not in (None, "1")]
    if bad:
        print(f"warning: the RAYON_NUM_THREADS=1 run reports threads={bad[0].threads}", flush=True)
    zs1 = [r for r in zs1 if r.n in args.ns and r.kernel in args.kernel_list]
    zsn = [r for r in zsn if r.n in args.ns and r.kernel in args.kernel_list]
    load_after_cargo = common.loadavg()

    t0 = time.perf_counter()
    sp1, loc1 = scipy_all(args)
    blas1 = sp1[0].blas if sp1 else common.blas_runtime()
    spn, locn, blasn = scipy_child(args, args.mt) if args.mt else ([], [], "not run")
    scipy_s = time.perf_counter() - t0
    load_after_scipy = common.loadavg()

    n_band = int(np.count_nonzero(np.abs(signed_distance(load_eval_points(out, args.eval))) < OFFSET))
    cs = cases(zs1, zsn, sp1, spn)
    fh, fb = time_table(cs, "fit", args, args.mt)
    eh, eb = time_table(cs, "eval", args, args.mt)
    ah, ab = accuracy_table(cs)
    th, tb = total_table(cs, loc1, locn, args, args.mt)
    bars = check_bars(cs, args)
    zs_threads = ", ".join(sorted({z.threads for z in zs1 + zsn if z.threads})) or "not reported by the example"
    legend = ("ratio = scipy ms ÷ zeroset ms (> 1: zeroset is faster); one thread each = scipy BLAS 1 ÷ zeroset "
              "RAYON_NUM_THREADS=1; each at its fastest = scipy's faster BLAS setting ÷ zeroset's faster thread "
              "setting")  # fmt: skip
    print(f"\n=== fit (ms; {legend}) ===\n{render_text(fh, fb, left=3, left_last=True)}")
    print(f"\n=== evaluation at {args.eval:,} points (ms) ===\n{render_text(eh, eb, left=3, left_last=True)}")
    print(f"\n=== accuracy: max err = max |s − sd| over the {n_band:,} points with |sd| < {OFFSET}; residual = "
          f"max |s(x_i) − v_i| ===\n{render_text(ah, ab, left=3)}")  # fmt: skip
    print(f"\n=== fit + evaluation at {args.eval:,} points (ms): zeroset against scipy's global interpolant and its "
          f"local mode (neighbors=k) ===\n{render_text(th, tb, left=3)}")  # fmt: skip
    print(f"\n=== bars ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start),
         ("load average 1/5/15 min, after cargo", load_after_cargo),
         ("load average 1/5/15 min, after scipy", load_after_scipy)],
        [("BLAS threads (scipy, one-thread run)", f"{BLAS_NOTE}; OpenBLAS reports {blas1}"),
         ("BLAS threads (scipy, all-threads run, child process)", blasn if args.mt else "not run"),
         ("zeroset threads (from the example's CSV)", zs_threads),
         ("scipy side wall time", f"{scipy_s:.1f} s")],
    )  # fmt: skip
    write_csv(out / "rbf_peers.csv", cs, args, n_band)
    with (out / "rbf_peers_local.csv").open("w", newline="") as f:  # scipy's local mode, one row per BLAS setting
        wr = csv.writer(f)
        wr.writerow(["n", "kernel", "scipy_kernel", "neighbors", "blas", "runs", "warmup", "fit_ms", "eval_ms",
                     "fit_plus_eval_ms", "max_err_band", "max_constraint_residual"])  # fmt: skip
        for r in loc1 + locn:
            wr.writerow([r.n, r.kernel, SCIPY_KERNEL[r.kernel], r.k, r.blas, r.runs, int(not r.single)]
                        + [common.num(v) for v in (r.fit_ms, r.eval_ms, r.total_ms, r.max_err, r.residual)])

    zs_source = (
        f"timings and errors read from an earlier run's {' and '.join(f'`{v}`' for v in ZS_CSV.values())} "
        "(`--skip-zeroset`; only scipy was timed now)"
        if args.skip_zeroset
        else f"one warm-up, then the median of {args.repeat} runs (a single run without warm-up where the first "
        "took over 2 s: marked next to the number)"
    )
    report = [
        "## Peer comparison: RBF implicit-surface fit and evaluation (zeroset vs scipy RBFInterpolator)",
        "",
        f"`benches/peers/rbf_peers.py {' '.join(sys.argv[1:])}`: same points in the same run. Sphere centre "
        f"(0.5, 0.5, 0.5), radius {RADIUS}; N − 2⌊N/3⌋ on-surface points (value 0) and ⌊N/3⌋ each at ±{OFFSET} "
        f"along the normal (value ±{OFFSET}); {args.eval:,} evaluation points uniform in [0, 1]³, {n_band:,} of "
        f"them in the band |sd| < {OFFSET}. Kernels: zeroset `r` (φ = r) vs scipy `linear` (φ = −r; with the "
        "degree-1 polynomial part the same interpolant) and `r3` vs `cubic` (φ = r³).",
        "",
        "**Timed.** zeroset (`examples/rbf_timing.rs`, run with RAYON_NUM_THREADS=1 and with "
        f"RAYON_NUM_THREADS={args.mt or '—'}; threads reported: {zs_threads}; {zs_source}): *fit* = from the plain "
        "point and value arrays to a field ready to evaluate — building the constraints, validation and duplicate "
        "check, the polynomial's scaling, the kernel matrix, the factorisation and solve (or GMRES), the "
        "refinement step and the residual check, the field; *eval* = the field's values at the evaluation points "
        f"into a new array. scipy {__import__('scipy').__version__}: *fit* = `RBFInterpolator(points, values, "
        f"kernel=K, degree={DEGREE})` (input checks, scaling, the kernel matrix by single-threaded compiled code, "
        "LAPACK dgesv); *eval* = its `__call__` at the evaluation points (compiled kernel matrix, BLAS product); "
        f"median of {args.scipy_repeat} runs after one warm-up, a single run without warm-up for N > "
        f"{args.scipy_once_above} (marked next to the number); with BLAS at one thread ({blas1}) and, in a child "
        f"process, at {args.mt or '—'} threads ({blasn}). Loading the points is outside both.",
        "",
        f"**Ratios** = scipy ms ÷ zeroset ms (> 1: zeroset is faster): one thread each (scipy BLAS 1 ÷ zeroset "
        "RAYON_NUM_THREADS=1), and each at its fastest (the faster of scipy's two BLAS settings ÷ the faster of "
        "zeroset's two thread settings; the configurations are named). `max err` = max |s(x) − sd(x)| over the "
        f"band, sd(x) = |x − c| − {RADIUS}; `residual` = max |s(x_i) − v_i| over the fit points.",
        "",
        "### Fit (ms)",
        "",
        render_md(fh, fb, left=3),
        "",
        f"### Evaluation at {args.eval:,} points (ms)",
        "",
        render_md(eh, eb, left=3),
        "",
        "### Accuracy",
        "",
        render_md(ah, ab, left=3),
        "",
        f"### Fit + evaluation at {args.eval:,} points (ms): scipy's global interpolant and its local mode",
        "",
        "What a user of `RBFInterpolator(...)(x)` pays, fit and evaluation together, against zeroset's fit + "
        "evaluation (the sums of the medians above). scipy's documented speed setting is `neighbors=k`: each "
        "evaluation point is interpolated from its k nearest fit points only — a different, piecewise smooth "
        "interpolant (it jumps where the neighbourhood changes), not the global one zeroset and scipy's default "
        f"build; it is timed at n = {', '.join(map(str, args.neighbor_ns)) or '—'} (fit and evaluation in one timed "
        f"block: one warm-up and the median of {args.scipy_repeat}, or one run without warm-up where the first took "
        f"over {args.local_once_above_s:g} s). Max err as above (zeroset's worse thread setting, scipy's better); "
        "residual = max |s(x_i) − v_i| at the fit points.",
        "",
        render_md(th, tb, left=3),
        "",
        "### Bars",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "rbf_peers.md", out / "rbf_peers.csv", report, facts)


if __name__ == "__main__":
    main()
