#!/usr/bin/env python3
"""Peer comparison: zeroset's fast multipole evaluation of an RBF field vs the exact sum in NumPy/SciPy.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/fmm_peers.py [--kernels r,r3] [--orders 6,8]
        [--targets 10000,100000,1000000] [--sources 10000] [--repeat 5] [--mt-threads N]

The field is s(x) = Σ_j w_j φ(|x − y_j|) + c0 + c1 x + c2 y + c3 z with φ(r) = r (`r`) or r³ (`r3`).

Threads: both sides are timed at one thread and at N (--mt-threads, default the CPUs available):
zeroset with RAYON_NUM_THREADS=1 and =N, NumPy in this process with BLAS pinned to one thread and
with the target chunks spread over N forked processes (BLAS one thread each; cdist holds the GIL,
so Python threads would not help). The report gives the ratios one thread each and each side at
its fastest.

  1. `cargo build --release --example fmm_timing` (CARGO_TARGET_DIR honoured; --skip-build reuses
     the binary), then per (kernel, order, target count M), twice (RAYON_NUM_THREADS=1 and =N):
     `fmm_timing --kernel K --sources N --targets M --order P --dump DIR --repeat R
     --disk-cache OUT/fmm/opcache` (`examples/fmm_timing.rs`; OUT/fmm/opcache is emptied at the
     start of the run, so the operators are written to disk in this run). Per run it writes into
     DIR (OUT/fmm/K_pP_nN_mM_t1 or …_tall): `sources.npy` (N×3), `weights.npy` (N), `poly.npy`
     (c0, c1, c2, c3), `targets.npy` (M×3), `fmm_values.npy` (M), `direct_values.npy` (M) and
     `timing.json`. Counted there:
       fmm_operators_ms       the M2L operators built from an empty cache (1 run);
       fmm_operators_disk_ms  the same operators read back from the on-disk cache (1 run);
       fmm_first_ms           the first call: operator cache emptied, `FmmField::new` (operators,
                              tree, expansions) and one evaluation at the M targets — what a
                              one-shot program pays (1 run: a first call happens once);
       fmm_build_ms, fmm_eval_ms, fmm_total_ms = build + eval
                              a second field of the same kernel and order (operators reused from
                              the in-process cache) and its evaluation: one warm-up, then the
                              median of R;
       direct_ms              zeroset's exact parallel direct sum, same rule;
       near_max_distance, near_rms_distance
                              the FMM error as a distance, |s_fmm − s| / |∇s|, at 20,000 points
                              within one voxel of the zero set.
     `--skip-zeroset` reuses the dumps of an earlier `--keep-data` run instead;
  2. on the same arrays, computes the exact field with `scipy.spatial.distance.cdist` over target
     chunks (each chunk's distance matrix ≈ 64 MB), then a BLAS matrix-vector product with the
     weights, plus the polynomial — one warm-up, then the median of --numpy-repeat — in this
     process (BLAS one thread) and with the chunks spread over N forked processes (pool start-up
     and fork inside the timed call). Above --numpy-max-targets targets the sum is computed only
     on an evenly strided subset of that many targets: its time is scaled linearly to M and
     marked "extrap.", and the errors against it are over that subset;
  3. prints and writes (OUT/fmm_peers.md, OUT/fmm_peers.csv): times per zeroset thread count,
     ratios NumPy ÷ FMM with the operators counted (first call) and reused, one thread each and
     each at its fastest, zeroset direct ÷ FMM (first call and reused, same thread count), errors
     of the FMM and of zeroset's direct sum against the NumPy sum, the error near the zero set,
     the FMM evaluation time per target count, and the checks (PASS / FAIL / SKIP).
Always exits 0 once it has run; a failed check is reported, not raised.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import math
import multiprocessing
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import common
from common import fmt_e, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402
from scipy.spatial.distance import cdist  # noqa: E402

EXAMPLE = "fmm_timing"
KERNELS = ("r", "r3")
CONFIGS = ("1", "all")  # zeroset: RAYON_NUM_THREADS=1, RAYON_NUM_THREADS=N
TIMING_KEYS = ("kernel", "order", "sources", "targets", "fmm_build_ms", "fmm_eval_ms", "fmm_total_ms",
               "fmm_operators_ms", "fmm_operators_disk_ms", "fmm_first_ms", "direct_ms", "near_max_distance",
               "near_rms_distance", "voxel", "diagonal", "threads", "repeat")  # fmt: skip
ARRAYS = ("sources", "weights", "poly", "targets", "fmm_values", "direct_values")
CHUNK_BYTES = 64 << 20  # one target chunk's distance matrix
# Sanity: zeroset's direct sum vs NumPy's, max relative error ≤ max(DIRECT_TOL, DIRECT_ULPS · ε · κ),
# κ = max_i Σ_j |w_j φ_ij| / max_i |s_i| the condition of the sum (two correct summation orders
# differ by about ε · κ: κ ≈ 1.6e3 for r and 4.6e6 for r3 on the bunny, whose weights cancel).
DIRECT_TOL = 1e-11
DIRECT_ULPS = 64
CONDITION_TARGETS = 2000  # κ is measured on an evenly strided subset of this many targets
# The speed bars, at BAR_SOURCES sources × BAR_TARGETS targets and FMM max rel ≤ BAR_MAX_REL,
# judged with the operators counted (first call), each side at its fastest.
BAR_SOURCES, BAR_TARGETS, BAR_MAX_REL = 10_000, 100_000, 1e-5
NUMPY_BAR, DIRECT_BAR = 20.0, 5.0


@dataclass
class NpResult:
    """NumPy's exact sum on one set of targets (all of them, or a strided subset)."""

    exact: np.ndarray
    ms: float  # one process, BLAS one thread: median after one warm-up
    first_ms: float  # that configuration's warm-up run (the first call)
    runs: int
    mt_ms: float | None  # N processes, median; None if not measured


@dataclass
class Case:
    kernel: str
    order: int
    m: int  # targets
    n: int  # sources (requested)
    zs: dict = field(default_factory=dict)  # config "1" / "all" -> timing.json (missing: not run)
    same_bits: bool | None = None  # the all-threads run's values equal the one-thread run's, bit for bit
    np_targets: int = 0  # targets NumPy summed over (m, or the subset size)
    np_ms: float = math.nan  # one process, scaled to m if extrapolated
    np_first_ms: float = math.nan
    np_runs: int = 0
    np_mt_ms: float | None = None
    extrapolated: bool = False
    cached: bool = False  # NumPy result reused from an identical earlier case
    fmm_max: float = math.nan
    fmm_rms: float = math.nan
    dir_max: dict = field(default_factory=dict)  # config -> zeroset direct vs NumPy, max rel
    dir_rms: dict = field(default_factory=dict)
    condition: float = math.nan  # κ of the sum, on a subset of the targets
    fmm_vs_dir_max: float = math.nan  # over all m targets
    fmm_vs_dir_rms: float = math.nan
    notes: list[str] = field(default_factory=list)

    def t(self, config: str, key: str) -> float:
        v = self.zs.get(config, {}).get(key)
        return math.nan if v is None else float(v)

    def threads(self, config: str) -> str:
        v = self.zs.get(config, {}).get("threads")
        return "?" if v is None else str(v)

    def configs(self) -> list[str]:
        return [c for c in CONFIGS if c in self.zs]

    def zs_fastest(self, key: str) -> tuple[str | None, float]:
        """(label, ms) of zeroset's faster configuration for `key`."""
        return common.fastest({f"zeroset {self.threads(c)} thr": self.t(c, key) for c in self.configs()})

    def np_fastest(self, procs: int) -> tuple[str | None, float]:
        runs = {"NumPy 1 proc": self.np_ms}
        if self.np_mt_ms is not None:
            runs[f"NumPy {procs} procs"] = self.np_mt_ms
        return common.fastest(runs)


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Compare zeroset's FMM evaluation of an RBF field with the exact NumPy/SciPy sum.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--kernels", default="r,r3", help=f"kernels, from {list(KERNELS)}")
    p.add_argument("--orders", default="6,8", help="FMM expansion orders")
    p.add_argument("--targets", default="10000,100000,1000000", help="target counts M")
    p.add_argument("--sources", type=int, default=10_000, help="source count N")
    p.add_argument("--repeat", type=int, default=5,
                   help="zeroset: timed runs after one warm-up (the example's --repeat)")  # fmt: skip
    p.add_argument("--numpy-repeat", type=int, default=3, help="NumPy sum: timed runs after one warm-up")
    p.add_argument("--tolerance", type=float, default=None,
                   help="zeroset: the M2L compression tolerance (the example's --tolerance; default 10^-(p+1))")
    p.add_argument("--leaf", type=int, default=None,
                   help="zeroset: the most sources per leaf (the example's --leaf; default by order and targets)")
    p.add_argument("--compression", choices=["shared", "per-operator"], default=None,
                   help="zeroset: the M2L compression (the example's --compression; default by order)")
    p.add_argument(
        "--numpy-max-targets",
        type=int,
        default=100_000,
        metavar="M",
        help="above M targets, NumPy sums over an evenly strided subset of M targets; its time is scaled "
        "linearly (marked 'extrap.') and the errors are over the subset",
    )
    p.add_argument(
        "--mt-threads",
        type=int,
        default=common.cpu_count(),
        metavar="N",
        help="the all-threads configuration: zeroset with RAYON_NUM_THREADS=N, NumPy with the target chunks "
        "over N forked processes (BLAS one thread each); 0 or 1 = one-thread runs only",
    )
    p.add_argument("--numpy-procs", type=int, default=None, metavar="P",
                   help="NumPy's multi-process run with P processes instead of --mt-threads (0 or 1: not run)")  # fmt: skip
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the report; dumps go to OUT/fmm/")
    p.add_argument("--keep-data", action="store_true", help="keep the .npy dumps (≈ 40 MB per case and run at M = 10⁶)")
    p.add_argument(
        "--skip-zeroset",
        action="store_true",
        help="do not run cargo or the example; reuse the dumps of an earlier --keep-data run in OUT/fmm/",
    )
    p.add_argument("--skip-build", action="store_true", help="do not run cargo build; reuse the example binary")
    common.add_blas_arg(p)
    a = p.parse_args()

    a.kernel_list = [k.strip() for k in a.kernels.split(",") if k.strip()]
    if not a.kernel_list or any(k not in KERNELS for k in a.kernel_list):
        p.error(f"--kernels: expected a comma-separated subset of {list(KERNELS)}, got {a.kernels!r}")
    a.order_list = common.int_list(p, a.orders, "--orders", 1, "order")
    a.target_list = sorted(set(common.int_list(p, a.targets, "--targets", 1, "M")))
    if not a.order_list or not a.target_list:
        p.error("nothing to do: --orders or --targets is empty")
    for name in ("sources", "repeat", "numpy_repeat", "numpy_max_targets"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if a.mt_threads < 0 or (a.numpy_procs is not None and a.numpy_procs < 0):
        p.error("--mt-threads and --numpy-procs must be >= 0")
    a.mt = a.mt_threads if a.mt_threads > 1 else 0  # 0: one-thread runs only
    procs = a.mt if a.numpy_procs is None else a.numpy_procs
    a.procs = procs if procs > 1 else 0
    a.out = Path(a.out).resolve()
    a.opcache = a.out / "fmm" / "opcache"
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: zeroset


def case_dir(args, kernel: str, order: int, m: int, config: str) -> Path:
    return args.out / "fmm" / f"{kernel}_p{order}_n{args.sources}_m{m}_t{config}"


def run_zeroset(binary: Path, dump: Path, kernel: str, order: int, m: int, args, config: str) -> None:
    if dump.exists():
        shutil.rmtree(dump)  # no stale arrays from an earlier run
    dump.mkdir(parents=True)
    common.run_logged(
        [str(binary), "--kernel", kernel, "--sources", str(args.sources), "--targets", str(m),
         "--order", str(order), "--dump", str(dump), "--repeat", str(args.repeat),
         "--disk-cache", str(args.opcache)]
        + ([] if args.tolerance is None else ["--tolerance", repr(args.tolerance)])
        + ([] if args.leaf is None else ["--leaf", str(args.leaf)])
        + ([] if args.compression is None else ["--compression", args.compression]),
        env={"RAYON_NUM_THREADS": "1" if config == "1" else str(args.mt)},
    )  # fmt: skip


def load_timing(dump: Path) -> dict:
    tpath = dump / "timing.json"
    if not tpath.is_file():
        sys.exit(f"{tpath} not found (the example did not write it; with --skip-zeroset, same arguments?)")
    timing = json.loads(tpath.read_text())
    missing = [k for k in TIMING_KEYS if k not in timing]
    if missing:
        sys.exit(f"{tpath}: missing keys {missing} (has {sorted(timing)}; an older example? rerun without "
                 "--skip-zeroset)")  # fmt: skip
    return timing


def load_arrays(dump: Path, timing: dict, m: int, names=ARRAYS, required: bool = True) -> dict[str, np.ndarray] | None:
    """The dumped arrays, shape-checked; exits if one is missing or off (or returns None if not `required`)."""
    # The example fits ~n centres (3 per scan point) and reports the count it used in timing.json.
    n = int(timing["sources"])
    expected = {"sources": (n, 3), "weights": (n,), "poly": (4,), "targets": (m, 3), "fmm_values": (m,),
                "direct_values": (m,)}  # fmt: skip
    arrays = {}
    for name in names:
        path = dump / f"{name}.npy"
        if not path.is_file():
            if not required:
                return None
            sys.exit(f"{path} not found (the example did not write it; with --skip-zeroset, --keep-data before?)")
        a = np.load(path)
        if a.dtype != np.float64 or a.shape != expected[name]:
            sys.exit(f"{path}: {a.dtype} {a.shape}, expected float64 {expected[name]}")
        arrays[name] = np.ascontiguousarray(a)
    return arrays


# ---------------------------------------------------------------------------------------------
# Step 2: NumPy / SciPy exact sum


def chunk_rows(n: int) -> int:
    return max(1, CHUNK_BYTES // (8 * n))


def sum_chunk(x, y, w, poly, kernel, out, bufs) -> None:
    """out[:] = s(x) for one chunk of targets; bufs = (D, T) scratch of chunk_rows × N."""
    k = x.shape[0]
    d = bufs[0][:k]
    cdist(x, y, "euclidean", out=d)
    if kernel == "r3":
        t = bufs[1][:k]
        np.multiply(d, d, out=t)
        t *= d
        d = t
    np.matmul(d, w, out=out)
    out += poly[0] + x @ poly[1:]


def exact_sum(x, y, w, poly, kernel) -> np.ndarray:
    """The exact field at the targets x, chunk by chunk, in this process."""
    m, n = x.shape[0], y.shape[0]
    rows = chunk_rows(n)
    s = np.empty(m)
    bufs = (np.empty((rows, n)), np.empty((rows, n)) if kernel == "r3" else None)
    for i in range(0, m, rows):
        sum_chunk(x[i : i + rows], y, w, poly, kernel, s[i : i + rows], bufs)
    return s


# The inputs and scratch of the forked workers of exact_sum_procs (inherited, not pickled).
_WORK: dict = {}


def _proc_chunk(i: int) -> tuple[int, np.ndarray]:
    x, y, w, poly, kernel, rows = _WORK["args"]
    if "bufs" not in _WORK:
        n = y.shape[0]
        _WORK["bufs"] = (np.empty((rows, n)), np.empty((rows, n)) if kernel == "r3" else None)
    xc = x[i : i + rows]
    out = np.empty(xc.shape[0])
    sum_chunk(xc, y, w, poly, kernel, out, _WORK["bufs"])
    return i, out


def exact_sum_procs(x, y, w, poly, kernel, procs: int) -> np.ndarray:
    """exact_sum with the chunks spread over `procs` forked processes (cdist holds the GIL, so
    threads would not help); the pool start-up and the fork are inside the timed call."""
    m, n = x.shape[0], y.shape[0]
    rows = chunk_rows(n)
    s = np.empty(m)
    _WORK.clear()
    _WORK["args"] = (x, y, w, poly, kernel, rows)
    try:
        with multiprocessing.get_context("fork").Pool(procs) as pool:
            for i, v in pool.imap_unordered(_proc_chunk, range(0, m, rows)):
                s[i : i + v.shape[0]] = v
    finally:
        _WORK.clear()
    return s


def timed_with_first(fn, repeat: int):
    """common.timed's rule (one warm-up, then the upper median of `repeat`), also returning the
    warm-up's own time (the first call)."""
    t = time.perf_counter()
    fn()
    first = (time.perf_counter() - t) * 1e3
    out, ms, _ = common.timed(fn, repeat, warmup=False)
    return out, ms, first


def digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha1()
    for a in arrays:
        h.update(repr(a.shape).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def run_numpy(kernel: str, x, arrays, args, cache: dict) -> tuple[NpResult, bool]:
    """NumPy's sum at the targets x (timed); reused when the same inputs were summed before."""
    y, w, poly = arrays["sources"], arrays["weights"], arrays["poly"]
    key = (kernel, digest(y, w, poly, x))
    if key in cache:
        print("  NumPy sum: same sources, weights, polynomial and targets as an earlier case; reused", flush=True)
        return cache[key], True
    rows = chunk_rows(y.shape[0])
    print(f"  NumPy sum over {x.shape[0]:,} targets × {y.shape[0]:,} sources, chunks of {rows} targets "
          f"(warm-up + {args.numpy_repeat}, 1 process, BLAS 1 thread) …", flush=True)  # fmt: skip
    exact, ms, first = timed_with_first(lambda: exact_sum(x, y, w, poly, kernel), args.numpy_repeat)
    mt_ms = None
    print(f"    {ms:.1f} ms (first run {first:.1f} ms)", flush=True)
    if args.procs:
        print(f"    again with {args.procs} processes (warm-up + {args.numpy_repeat}) …", flush=True)
        mt, mt_ms, _ = common.timed(lambda: exact_sum_procs(x, y, w, poly, kernel, args.procs), args.numpy_repeat)
        diff = float(np.max(np.abs(mt - exact))) if exact.size else 0.0
        if diff != 0.0:
            print(f"    warning: the multi-process sum differs from the one-process sum by {diff:.2e}", flush=True)
        print(f"    {mt_ms:.1f} ms", flush=True)
    res = NpResult(exact, ms, first, args.numpy_repeat, mt_ms)
    cache[key] = res
    return res, False


def rel_errors(approx: np.ndarray, exact: np.ndarray) -> tuple[float, float]:
    """(max|err| / max|exact|, rms(err) / rms(exact))."""
    err = approx - exact
    scale_max = float(np.max(np.abs(exact)))
    scale_rms = math.sqrt(float(np.mean(exact * exact)))
    max_rel = float(np.max(np.abs(err))) / scale_max if scale_max > 0 else math.nan
    rms_rel = math.sqrt(float(np.mean(err * err))) / scale_rms if scale_rms > 0 else math.nan
    return max_rel, rms_rel


def sum_condition(x, y, w, kernel) -> float:
    """κ = max_i Σ_j |w_j φ(|x_i − y_j|)| / max_i |Σ_j w_j φ(|x_i − y_j|)| over ≤ CONDITION_TARGETS of x
    (the polynomial left out: it is added exactly on both sides)."""
    if x.shape[0] == 0:
        return math.nan
    k = min(CONDITION_TARGETS, x.shape[0])
    idx = np.arange(k, dtype=np.int64) * x.shape[0] // k
    d = cdist(x[idx], y)
    if kernel == "r3":
        d = d * d * d
    top = float(np.max(np.abs(d @ w)))
    return float(np.max(d @ np.abs(w))) / top if top > 0 else math.inf


def direct_tol(case: Case) -> float:
    if math.isnan(case.condition):
        return DIRECT_TOL
    return max(DIRECT_TOL, DIRECT_ULPS * float(np.finfo(float).eps) * case.condition)


def process_case(case: Case, arrays: dict, other: dict | None, args, cache: dict) -> None:
    """NumPy's sum and the errors; `arrays` from the one-thread run, `other` (values only) from the
    all-threads run, if kept."""
    m = case.m
    if m > args.numpy_max_targets:
        idx = np.arange(args.numpy_max_targets, dtype=np.int64) * m // args.numpy_max_targets
        case.extrapolated = True
        case.notes.append(f"NumPy on {len(idx):,} strided targets, time × {m / len(idx):g}")
    else:
        idx = slice(None)
    x = np.ascontiguousarray(arrays["targets"][idx])
    res, case.cached = run_numpy(case.kernel, x, arrays, args, cache)
    if case.cached:
        case.notes.append("NumPy result reused (identical input)")
    scale = m / x.shape[0]
    case.np_targets = x.shape[0]
    case.np_ms = res.ms * scale
    case.np_first_ms = res.first_ms * scale
    case.np_runs = res.runs
    case.np_mt_ms = None if res.mt_ms is None else res.mt_ms * scale
    case.fmm_max, case.fmm_rms = rel_errors(arrays["fmm_values"][idx], res.exact)
    first = case.configs()[0]
    case.dir_max[first], case.dir_rms[first] = rel_errors(arrays["direct_values"][idx], res.exact)
    if other is not None:
        case.dir_max["all"], case.dir_rms["all"] = rel_errors(other["direct_values"][idx], res.exact)
        case.same_bits = bool(np.array_equal(arrays["fmm_values"], other["fmm_values"])
                              and np.array_equal(arrays["direct_values"], other["direct_values"]))  # fmt: skip
        if not case.same_bits:
            case.notes.append("the one- and all-thread runs' values differ")
    case.fmm_vs_dir_max, case.fmm_vs_dir_rms = rel_errors(arrays["fmm_values"], arrays["direct_values"])
    case.condition = sum_condition(x, arrays["sources"], arrays["weights"], case.kernel)
    for c in case.configs():
        for key, want in (("kernel", case.kernel), ("order", case.order), ("targets", m)):
            if str(case.zs[c].get(key)) != str(want):
                case.notes.append(f"timing.json ({c}) {key}={case.zs[c].get(key)!r}, expected {want!r}")
    if "1" in case.zs and case.threads("1") != "1":
        case.notes.append(f"the RAYON_NUM_THREADS=1 run reports threads={case.threads('1')}")
    dirs = ", ".join(f"{fmt_e(v)} ({c})" for c, v in case.dir_max.items())
    print(f"  FMM vs NumPy: max rel {case.fmm_max:.2e}, RMS rel {case.fmm_rms:.2e}; zeroset direct vs NumPy: "
          f"max rel {dirs}", flush=True)  # fmt: skip


# ---------------------------------------------------------------------------------------------
# Step 3: tables


ratio = common.ratio


def np_cell(v: float | None, c: Case) -> str:
    return fmt_ms(v) + (" (extrap.)" if c.extrapolated and v is not None and not math.isnan(v) else "")


def once(v: float) -> str:
    """A figure measured once (a first call, an operator build, a disk read)."""
    return fmt_ms(v) + (" (1 run)" if not math.isnan(v) else "")


def speed_table(cases: list[Case], procs: int):
    """One row per case and zeroset thread count."""
    header = ["kernel", "order", "targets", "zeroset threads", "operators built ms", "operators from disk ms",
              "build ms", "eval ms", "total ms (operators reused)", "first call ms (operators built)",
              "zeroset direct ms", "direct ÷ FMM first call", "direct ÷ FMM reused", "NumPy 1 proc ms"] + (
              [f"NumPy {procs} procs ms"] if procs else []) + ["note"]  # fmt: skip
    body = []
    for c in cases:
        for cfg in c.configs():
            first, tot, direct = c.t(cfg, "fmm_first_ms"), c.t(cfg, "fmm_total_ms"), c.t(cfg, "direct_ms")
            body.append([c.kernel, str(c.order), f"{c.m:,}", c.threads(cfg), once(c.t(cfg, "fmm_operators_ms")),
                         once(c.t(cfg, "fmm_operators_disk_ms")), fmt_ms(c.t(cfg, "fmm_build_ms")),
                         fmt_ms(c.t(cfg, "fmm_eval_ms")), fmt_ms(tot), once(first), fmt_ms(direct),
                         fmt_ratio(ratio(direct, first)), fmt_ratio(ratio(direct, tot)), np_cell(c.np_ms, c)]
                        + ([np_cell(c.np_mt_ms, c)] if procs else [])
                        + ["; ".join(c.notes) if cfg == c.configs()[0] else ""])  # fmt: skip
    return header, body


def numpy_ratios(c: Case, procs: int) -> dict:
    """NumPy ÷ FMM: first call and reused, one thread each and each at its fastest."""
    out = {}
    for what, key in (("first", "fmm_first_ms"), ("reused", "fmm_total_ms")):
        out[f"{what} one"] = ratio(c.np_ms, c.t("1", key))
        zl, zm = c.zs_fastest(key)
        nl, nm = c.np_fastest(procs)
        out[f"{what} fast"] = ratio(nm, zm)
        out[f"{what} which"] = "—" if math.isnan(out[f"{what} fast"]) else f"{nl} ÷ {zl}"
    return out


def direct_ratios(c: Case) -> dict:
    """zeroset direct ÷ FMM (first call, reused), each at its fastest."""
    out = {}
    dl, dm = c.zs_fastest("direct_ms")
    for what, key in (("first", "fmm_first_ms"), ("reused", "fmm_total_ms")):
        zl, zm = c.zs_fastest(key)
        out[f"{what} fast"] = ratio(dm, zm)
        out[f"{what} which"] = "—" if math.isnan(out[f"{what} fast"]) else f"direct {dl} ÷ FMM {zl}"
    return out


def ratio_table(cases: list[Case], procs: int):
    header = ["kernel", "order", "targets", "NumPy ÷ FMM first call, 1 thread each", "NumPy ÷ FMM reused, 1 thread each",
              "NumPy ÷ FMM first call, each at its fastest", "NumPy ÷ FMM reused, each at its fastest",
              "fastest configurations (first call)", "direct ÷ FMM first call, each at its fastest",
              "direct ÷ FMM reused, each at its fastest"]  # fmt: skip
    body = []
    for c in cases:
        r, d = numpy_ratios(c, procs), direct_ratios(c)
        ext = " (extrap.)" if c.extrapolated else ""
        body.append([c.kernel, str(c.order), f"{c.m:,}", fmt_ratio(r["first one"]) + ext,
                     fmt_ratio(r["reused one"]) + ext, fmt_ratio(r["first fast"]) + ext,
                     fmt_ratio(r["reused fast"]) + ext, r["first which"], fmt_ratio(d["first fast"]),
                     fmt_ratio(d["reused fast"])])  # fmt: skip
    return header, body


def accuracy_table(cases: list[Case]):
    header = ["kernel", "order", "targets", "compared on", "fmm max rel", "fmm rms rel", "direct max rel (worse run)",
              "sum condition κ", "fmm vs direct max rel (all)", "fmm vs direct rms rel (all)",
              "near zero set: max distance error (voxels)", "max distance error / diagonal",
              "rms distance error (voxels)", "same bits on 1 and N threads"]  # fmt: skip
    body = []
    for c in cases:
        on = f"{c.np_targets:,}" + (" (subset)" if c.extrapolated else "")
        cfg = c.configs()[0]
        near, rms = c.t(cfg, "near_max_distance"), c.t(cfg, "near_rms_distance")
        vox, diag = c.t(cfg, "voxel"), c.t(cfg, "diagonal")
        dmax = max(c.dir_max.values()) if c.dir_max else math.nan
        body.append([c.kernel, str(c.order), f"{c.m:,}", on, fmt_e(c.fmm_max), fmt_e(c.fmm_rms), fmt_e(dmax),
                     fmt_e(c.condition), fmt_e(c.fmm_vs_dir_max), fmt_e(c.fmm_vs_dir_rms),
                     fmt_e(ratio(near, vox)), fmt_e(ratio(near, diag)), fmt_e(ratio(rms, vox)),
                     "—" if c.same_bits is None else ("yes" if c.same_bits else "NO")])  # fmt: skip
    return header, body


def growth_table(cases: list[Case]):
    """FMM evaluation time against the target count, per (kernel, order, zeroset threads), relative
    to the smallest M."""
    header = ["kernel", "order", "zeroset threads", "targets", "× targets", "fmm eval ms", "× eval ms",
              "eval ns / target", "fmm build ms"]  # fmt: skip
    body = []
    groups: dict[tuple[str, int, str], list[Case]] = {}
    for c in cases:
        for cfg in c.configs():
            groups.setdefault((c.kernel, c.order, cfg), []).append(c)
    for (k, p, cfg), cs in groups.items():
        cs = sorted(cs, key=lambda c: c.m)
        m0, e0 = cs[0].m, cs[0].t(cfg, "fmm_eval_ms")
        for c in cs:
            e = c.t(cfg, "fmm_eval_ms")
            body.append([k, str(p), c.threads(cfg), f"{c.m:,}", f"{c.m / m0:g}×", fmt_ms(e), fmt_ratio(ratio(e, e0)),
                         f"{e * 1e6 / c.m:.1f}" if not math.isnan(e) else "—", fmt_ms(c.t(cfg, "fmm_build_ms"))])  # fmt: skip
    return header, body


def check_bars(cases: list[Case], args) -> common.Bars:
    bars = common.Bars()
    for c in cases:
        tol = direct_tol(c)
        for cfg, v in c.dir_max.items():
            bars.check(f"{c.kernel} p={c.order} M={c.m:,}: zeroset direct sum ({c.threads(cfg)} thr) = NumPy's "
                       f"(max rel ≤ max({DIRECT_TOL:g}, {DIRECT_ULPS} ε κ) = {tol:.2g}, κ = {c.condition:.3g})",
                       None if math.isnan(v) else v <= tol, fmt_e(v))  # fmt: skip
    for c in cases:
        if args.sources != BAR_SOURCES or c.m != BAR_TARGETS:
            continue
        where = f"{c.kernel} p={c.order} {BAR_SOURCES:,} × {BAR_TARGETS:,}"
        if math.isnan(c.fmm_max) or c.fmm_max > BAR_MAX_REL:
            bars.check(f"{where}: speed bars (need FMM max rel ≤ {BAR_MAX_REL:g})", None,
                       f"not judged: FMM max rel {fmt_e(c.fmm_max)}")  # fmt: skip
            continue
        r, d = numpy_ratios(c, args.procs), direct_ratios(c)
        first1, tot1 = c.t("1", "fmm_first_ms"), c.t("1", "fmm_total_ms")
        verdict = lambda v, bar: None if math.isnan(v) else v >= bar  # noqa: E731
        bars.check(f"{where}: NumPy ÷ FMM first call (operators built) ≥ {NUMPY_BAR:g}, each at its fastest",
                   verdict(r["first fast"], NUMPY_BAR), f"{fmt_ratio(r['first fast'])} ({r['first which']})")  # fmt: skip
        bars.check(f"{where}: NumPy ÷ FMM first call ≥ {NUMPY_BAR:g}, one thread each (reported)",
                   verdict(r["first one"], NUMPY_BAR),
                   f"{fmt_ratio(r['first one'])} ({fmt_ms(c.np_ms)} / {fmt_ms(first1)} ms)")  # fmt: skip
        bars.check(f"{where}: NumPy ÷ FMM operators reused ≥ {NUMPY_BAR:g}, each at its fastest (reported)",
                   verdict(r["reused fast"], NUMPY_BAR), f"{fmt_ratio(r['reused fast'])} ({r['reused which']})")  # fmt: skip
        bars.check(f"{where}: NumPy ÷ FMM operators reused ≥ {NUMPY_BAR:g}, one thread each (reported)",
                   verdict(r["reused one"], NUMPY_BAR),
                   f"{fmt_ratio(r['reused one'])} ({fmt_ms(c.np_ms)} / {fmt_ms(tot1)} ms)")  # fmt: skip
        bars.check(f"{where}: zeroset direct ÷ FMM first call ≥ {DIRECT_BAR:g}, each at its fastest",
                   verdict(d["first fast"], DIRECT_BAR), f"{fmt_ratio(d['first fast'])} ({d['first which']})")  # fmt: skip
        for cfg in c.configs():
            v = ratio(c.t(cfg, "direct_ms"), c.t(cfg, "fmm_first_ms"))
            bars.check(f"{where}: zeroset direct ÷ FMM first call ≥ {DIRECT_BAR:g}, both {c.threads(cfg)} thr "
                       "(reported)", verdict(v, DIRECT_BAR), fmt_ratio(v))  # fmt: skip
        bars.check(f"{where}: zeroset direct ÷ FMM operators reused ≥ {DIRECT_BAR:g}, each at its fastest (reported)",
                   verdict(d["reused fast"], DIRECT_BAR), f"{fmt_ratio(d['reused fast'])} ({d['reused which']})")  # fmt: skip
    return bars


def write_csv(path: Path, cases: list[Case], procs: int) -> None:
    cols = ["kernel", "order", "sources", "targets", "zeroset_threads", "zeroset_repeat", "fmm_operators_ms",
            "fmm_operators_disk_ms", "fmm_build_ms", "fmm_eval_ms", "fmm_total_ms", "fmm_first_ms",
            "zeroset_direct_ms", "numpy_ms", "numpy_first_ms", "numpy_runs", "numpy_mt_ms", "numpy_procs",
            "numpy_extrapolated", "numpy_targets", "ratio_direct_over_fmm_first", "ratio_direct_over_fmm_reused",
            "ratio_numpy_over_fmm_first", "ratio_numpy_over_fmm_reused", "ratio_numpy_mt_over_fmm_first",
            "ratio_numpy_mt_over_fmm_reused", "ratio_numpy_over_fmm_first_one_thread_each",
            "ratio_numpy_over_fmm_reused_one_thread_each", "ratio_numpy_over_fmm_first_each_fastest",
            "ratio_numpy_over_fmm_reused_each_fastest", "fmm_max_rel", "fmm_rms_rel", "direct_max_rel",
            "direct_rms_rel", "sum_condition", "fmm_vs_direct_max_rel", "fmm_vs_direct_rms_rel",
            "near_max_distance", "near_rms_distance", "voxel", "diagonal", "same_bits_1_and_n_threads"]  # fmt: skip
    with path.open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(cols)
        for c in cases:
            r = numpy_ratios(c, procs)
            for cfg in c.configs():
                t = lambda k: c.t(cfg, k)  # noqa: E731
                first, tot, direct = t("fmm_first_ms"), t("fmm_total_ms"), t("direct_ms")
                wr.writerow([c.kernel, c.order, int(c.zs[cfg]["sources"]), c.m, c.threads(cfg), c.zs[cfg].get("repeat")]
                            + [common.num(v) for v in (
                                t("fmm_operators_ms"), t("fmm_operators_disk_ms"), t("fmm_build_ms"), t("fmm_eval_ms"),
                                tot, first, direct, c.np_ms, c.np_first_ms, c.np_runs, c.np_mt_ms, procs or None)]
                            + [int(c.extrapolated), c.np_targets]
                            + [common.num(v) for v in (
                                ratio(direct, first), ratio(direct, tot), ratio(c.np_ms, first), ratio(c.np_ms, tot),
                                ratio(c.np_mt_ms, first), ratio(c.np_mt_ms, tot), r["first one"], r["reused one"],
                                r["first fast"], r["reused fast"], c.fmm_max, c.fmm_rms, c.dir_max.get(cfg),
                                c.dir_rms.get(cfg), c.condition, c.fmm_vs_dir_max, c.fmm_vs_dir_rms,
                                t("near_max_distance"), t("near_rms_distance"), t("voxel"), t("diagonal"))]
                            + ["" if c.same_bits is None else int(c.same_bits)])  # fmt: skip


def main() -> None:
    args = parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    blas_rt = common.blas_runtime()
    print(f"BLAS threads: {BLAS_NOTE} ({blas_rt}); all-threads configuration: zeroset {args.mt or 'not run'}, "
          f"NumPy {args.procs or 'not run'} processes; load average {load_start}\n", flush=True)  # fmt: skip

    configs = CONFIGS if args.mt else CONFIGS[:1]
    binary = None
    if args.skip_zeroset:
        print(f"--skip-zeroset: reusing the dumps in {out / 'fmm'}", flush=True)
    else:
        binary = common.built_example(EXAMPLE, args.skip_build)
        if args.opcache.exists():
            shutil.rmtree(args.opcache)  # the operators are written to disk in this run
        args.opcache.mkdir(parents=True)

    cases: list[Case] = []
    cache: dict = {}
    numpy_s = 0.0
    for kernel in args.kernel_list:
        for order in args.order_list:
            for m in args.target_list:
                print(f"\n--- kernel {kernel}, order {order}, {args.sources:,} sources, {m:,} targets ---", flush=True)
                case = Case(kernel, order, m, args.sources)
                dumps = {cfg: case_dir(args, kernel, order, m, cfg) for cfg in configs}
                for cfg in configs:
                    if binary is not None:
                        run_zeroset(binary, dumps[cfg], kernel, order, m, args, cfg)
                    if args.skip_zeroset and not (dumps[cfg] / "timing.json").is_file() and cfg != "1":
                        print(f"  no {dumps[cfg]}: the all-threads run is missing", flush=True)
                        continue
                    case.zs[cfg] = load_timing(dumps[cfg])
                    z = case.zs[cfg]
                    print(f"  zeroset ({z.get('threads')} threads): operators {z['fmm_operators_ms']:.1f} ms built, "
                          f"{fmt_ms(z['fmm_operators_disk_ms'])} ms from disk; first call {z['fmm_first_ms']:.1f} ms; "
                          f"reused: build {z['fmm_build_ms']:.1f} + eval {z['fmm_eval_ms']:.1f} = "
                          f"{z['fmm_total_ms']:.1f} ms; direct {z['direct_ms']:.1f} ms", flush=True)  # fmt: skip
                arrays = load_arrays(dumps["1"], case.zs["1"], m)
                other = None
                if "all" in case.zs:
                    other = load_arrays(dumps["all"], case.zs["all"], m, ("fmm_values", "direct_values"), required=False)
                t0 = time.perf_counter()
                process_case(case, arrays, other, args, cache)
                numpy_s += time.perf_counter() - t0
                cases.append(case)
                del arrays, other
                if not args.keep_data and not args.skip_zeroset:
                    for d in dumps.values():
                        for name in ARRAYS:
                            (d / f"{name}.npy").unlink(missing_ok=True)
    load_end = common.loadavg()

    procs = args.procs
    sh, sb = speed_table(cases, procs)
    qh, qb = ratio_table(cases, procs)
    ah, ab = accuracy_table(cases)
    gh, gb = growth_table(cases)
    bars = check_bars(cases, args)
    threads = ", ".join(sorted({c.threads(cfg) for c in cases for cfg in c.configs()})) or "?"
    print(f"\n=== times (ms) per zeroset thread count; '(1 run)' = measured once (a first call happens once); "
          f"NumPy 'extrap.' = scaled from a subset ===\n{render_text(sh, sb, left=4, left_last=True)}")  # fmt: skip
    print(f"\n=== NumPy ÷ FMM (> 1: the FMM is faster); first call = operators built + build + one evaluation; "
          f"reused = build + evaluation with the operators in memory ===\n{render_text(qh, qb, left=3)}")  # fmt: skip
    print(f"\n=== errors vs the NumPy sum (max rel = max|err| / max|exact|, rms rel = rms(err) / rms(exact)); near "
          f"the zero set: |s_fmm − s| / |∇s| ===\n{render_text(ah, ab, left=4)}")  # fmt: skip
    print(f"\n=== FMM evaluation time vs target count ===\n{render_text(gh, gb, left=4)}")
    print(f"\n=== checks ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start), ("load average 1/5/15 min, at end", load_end)],
        [("BLAS threads (NumPy side)", f"{BLAS_NOTE}; OpenBLAS reports {blas_rt}"),
         ("NumPy multi-process variant", f"{procs} forked processes, BLAS one thread each" if procs else "not run"),
         ("zeroset threads (timing.json)", threads), ("NumPy side wall time", f"{numpy_s:.1f} s")],
    )  # fmt: skip
    write_csv(out / "fmm_peers.csv", cases, procs)

    zs_source = (
        "timings read from an earlier run's dumps (`--skip-zeroset`; only NumPy was timed now)"
        if args.skip_zeroset
        else f"run with RAYON_NUM_THREADS=1 and RAYON_NUM_THREADS={args.mt or '—'}"
    )
    mt_text = (
        f", and again with the chunks spread over {procs} forked processes (BLAS one thread each; the pool's "
        "start-up and the fork inside the timed call)"
        if procs
        else ""
    )
    report = [
        "## Peer comparison: fast multipole evaluation (zeroset FMM vs the exact NumPy/SciPy sum)",
        "",
        f"`benches/peers/fmm_peers.py {' '.join(sys.argv[1:])}`: same arrays in the same run. Field "
        "s(x) = Σ_j w_j φ(|x − y_j|) + c0 + c1 x + c2 y + c3 z, φ = r (`r`) or r³ (`r3`), fitted by zeroset to "
        f"{args.sources:,} bunny centres (the fit is outside every figure: both sides are given the same weights); "
        "targets uniform in the field's bounds.",
        "",
        f"**zeroset** (`examples/fmm_timing.rs`, {zs_source}; threads reported: {threads}). Counted: "
        "*operators built* = the M2L operators computed from an empty cache; *operators from disk* = the same "
        "read back from the on-disk cache (`OUT/fmm/opcache`, "
        "emptied at the start of this run and written in it; what a later process pays instead); *first call* = "
        "the operator cache emptied, `FmmField::new` (operators, octree, upward pass, M2L, downward pass) and "
        "one evaluation at all targets — what a one-shot program pays; these three are measured **once** "
        "(\"(1 run)\": a first call happens once), the first call being the process's first FMM. *build*, "
        "*eval*, *total* = a second field of the same kernel and order with the operators reused from the "
        "in-process cache, and its evaluation; *zeroset direct* = zeroset's exact parallel direct sum; these "
        f"three: one warm-up, then the median of {args.repeat} runs.",
        "",
        f"**NumPy** {np.__version__} / SciPy: `scipy.spatial.distance.cdist` over target chunks of ≈ "
        f"{CHUNK_BYTES >> 20} MB, cubed in place for `r3`, a BLAS matrix-vector product with the weights, plus "
        f"the polynomial: one warm-up, then the median of {args.numpy_repeat} runs, in one process with BLAS "
        f"pinned to one thread ({BLAS_NOTE}; OpenBLAS reports {blas_rt}){mt_text}. Its first (warm-up) run is in "
        f"the CSV (`numpy_first_ms`). Above {args.numpy_max_targets:,} targets NumPy sums over an evenly strided "
        f"subset of {args.numpy_max_targets:,}: the time is scaled linearly to all targets (\"extrap.\") and the "
        "errors are over the subset. Loading the arrays is outside every figure.",
        "",
        "**Ratios** (> 1: the FMM is faster): NumPy ÷ FMM *first call* (operators counted) and ÷ FMM *reused* "
        "(build + evaluation, operators in memory); *one thread each* = NumPy in one process (BLAS one thread) ÷ "
        "zeroset with RAYON_NUM_THREADS=1; *each at its fastest* = the faster of NumPy's configurations ÷ the "
        "faster of zeroset's (named). zeroset direct ÷ FMM at the same thread count, and each at its fastest. The "
        f"speed bars ({BAR_SOURCES:,} sources × {BAR_TARGETS:,} targets, FMM max rel ≤ {BAR_MAX_REL:g}: NumPy ÷ "
        f"FMM ≥ {NUMPY_BAR:g}, zeroset direct ÷ FMM ≥ {DIRECT_BAR:g}) are judged on the **first call**, each at "
        "its fastest; the other ratios are reported beside them. Relative errors: max = max|err| / max|exact|, "
        "rms = rms(err) / rms(exact); near the zero set: |s_fmm − s| / |∇s| at 20,000 points within one voxel of "
        "on-surface points, in voxels (`zeroset mesh`'s general detail) and relative to the bounds' diagonal.",
        "",
        "### Times (ms)",
        "",
        render_md(sh, sb, left=4),
        "",
        "### NumPy ÷ FMM",
        "",
        render_md(qh, qb, left=3),
        "",
        "### Errors",
        "",
        render_md(ah, ab, left=4),
        "",
        "### FMM evaluation time against the target count",
        "",
        render_md(gh, gb, left=4),
        "",
        "### Checks",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "fmm_peers.md", out / "fmm_peers.csv", report, facts)


if __name__ == "__main__":
    main()
