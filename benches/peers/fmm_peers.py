#!/usr/bin/env python3
"""Peer comparison: zeroset's fast multipole evaluation of an RBF field vs the exact sum in NumPy/SciPy.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/fmm_peers.py [--kernels r,r3] [--orders 6,8]
        [--targets 10000,100000,1000000] [--sources 10000] [--repeat 5]

The field is s(x) = Σ_j w_j φ(|x − y_j|) + c0 + c1 x + c2 y + c3 z with φ(r) = r (`r`) or r³ (`r3`).

  1. `cargo build --release --example fmm_timing`, then per (kernel, order, target count M)
     `target/release/examples/fmm_timing --kernel K --sources N --targets M --order P --dump DIR
     --repeat R` (`examples/fmm_timing.rs`), which times zeroset's FMM (build, evaluation) and its
     own parallel exact direct sum, and writes into DIR: `sources.npy` (N×3), `weights.npy` (N),
     `poly.npy` (4: c0, c1, c2, c3, absolute coordinates), `targets.npy` (M×3), `fmm_values.npy`
     (M), `direct_values.npy` (M) and `timing.json` (`kernel, order, sources, targets,
     fmm_build_ms, fmm_eval_ms, fmm_total_ms = build + evaluation, fmm_operators_ms, direct_ms,
     threads`, medians of R runs; the M2L operators depend on the kernel and order only, so the
     example builds them once, times them apart (`fmm_operators_ms`) and shares them).
     `--skip-zeroset` reuses the dumps of an earlier `--keep-data` run instead;
  2. on the same arrays, computes the exact field with `scipy.spatial.distance.cdist` over target
     chunks (each chunk's distance matrix ≈ 64 MB), then a BLAS matrix-vector product with the
     weights, plus the polynomial — timed (warm-up + median of `--numpy-repeat`) with BLAS pinned
     to one thread, and again with the chunks spread over `--numpy-procs` forked processes (cdist
     holds the GIL, so Python threads would not help) as the multi-core reference. Above
     `--numpy-max-targets` targets the sum is computed only on an evenly strided subset of that
     many targets: its time is scaled linearly to M and marked "extrapolated", and the errors
     against it are over that subset;
  3. prints and writes (OUT/fmm_peers.md, OUT/fmm_peers.csv): errors of the FMM and of zeroset's
     direct sum against the NumPy sum (max relative = max|err| / max|exact|, RMS relative =
     rms(err) / rms(exact)), times, ratios numpy_ms / fmm_total_ms and zeroset_direct_ms /
     fmm_total_ms (> 1 means the FMM is faster), and the FMM evaluation time per target count.
Always exits 0 once it has run; a failed check is reported, not raised.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import math
import multiprocessing
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import common
from common import fmt_e, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads()  # before numpy is imported

import numpy as np  # noqa: E402
from scipy.spatial.distance import cdist  # noqa: E402

EXAMPLE = "fmm_timing"
KERNELS = ("r", "r3")
TIMING_KEYS = ("kernel", "order", "sources", "targets", "fmm_build_ms", "fmm_eval_ms", "fmm_total_ms",
               "fmm_operators_ms", "direct_ms", "threads")  # fmt: skip
ARRAYS = ("sources", "weights", "poly", "targets", "fmm_values", "direct_values")
CHUNK_BYTES = 64 << 20  # one target chunk's distance matrix
# Sanity: zeroset's direct sum vs NumPy's, max relative error ≤ max(DIRECT_TOL, DIRECT_ULPS · ε · κ),
# κ = max_i Σ_j |w_j φ_ij| / max_i |s_i| the condition of the sum (two correct summation orders
# differ by about ε · κ: κ ≈ 1.6e3 for r and 4.6e6 for r3 on the bunny, whose weights cancel).
DIRECT_TOL = 1e-11
DIRECT_ULPS = 64
CONDITION_TARGETS = 2000  # κ is measured on an evenly strided subset of this many targets


@dataclass
class NpResult:
    """NumPy's exact sum on one set of targets (all of them, or a strided subset)."""

    exact: np.ndarray
    ms: float  # one thread, median
    times: list[float]
    mt_ms: float | None  # --numpy-procs processes, median; None if not measured


@dataclass
class Case:
    kernel: str
    order: int
    m: int  # targets
    n: int  # sources
    timing: dict
    np_targets: int = 0  # targets NumPy summed over (m, or the subset size)
    np_ms: float = math.nan  # one thread, scaled to m if extrapolated
    np_mt_ms: float | None = None
    extrapolated: bool = False
    cached: bool = False  # NumPy result reused from an identical earlier case
    fmm_max: float = math.nan
    fmm_rms: float = math.nan
    dir_max: float = math.nan
    dir_rms: float = math.nan
    condition: float = math.nan  # κ of the sum, on a subset of the targets
    fmm_vs_dir_max: float = math.nan  # over all m targets
    fmm_vs_dir_rms: float = math.nan
    notes: list[str] = field(default_factory=list)

    def t(self, key: str) -> float:
        v = self.timing.get(key)
        return math.nan if v is None else float(v)


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Compare zeroset's FMM evaluation of an RBF field with the exact NumPy/SciPy sum.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--kernels", default="r,r3", help=f"kernels, from {list(KERNELS)}")
    p.add_argument("--orders", default="6,8", help="FMM expansion orders")
    p.add_argument("--targets", default="10000,100000,1000000", help="target counts M")
    p.add_argument("--sources", type=int, default=10_000, help="source count N")
    p.add_argument("--repeat", type=int, default=5, help="zeroset: timed runs per case (the example's --repeat)")
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
        "linearly (marked 'extrapolated') and the errors are over the subset",
    )
    default_procs = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    p.add_argument(
        "--numpy-procs",
        type=int,
        default=default_procs,
        metavar="P",
        help="also time the NumPy sum with the target chunks spread over P forked processes (BLAS one "
        "thread each; the fork is timed); 0 or 1 = only the one-process time",
    )
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the report; dumps go to OUT/fmm/")
    p.add_argument("--keep-data", action="store_true", help="keep the .npy dumps (≈ 40 MB per case at M = 10⁶)")
    p.add_argument(
        "--skip-zeroset",
        action="store_true",
        help="do not run cargo or the example; reuse the dumps of an earlier --keep-data run in OUT/fmm/",
    )
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
    if a.numpy_procs < 0:
        p.error("--numpy-procs must be >= 0")
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: zeroset


def example_binary() -> Path:
    target = common.ORIGINAL_ENV.get("CARGO_TARGET_DIR")
    target_dir = (common.REPO / target) if target else common.REPO / "target"
    return target_dir / "release" / "examples" / EXAMPLE


def case_dir(args, kernel: str, order: int, m: int) -> Path:
    return args.out / "fmm" / f"{kernel}_p{order}_n{args.sources}_m{m}"


def run_zeroset(binary: Path, dump: Path, kernel: str, order: int, m: int, args) -> None:
    if dump.exists():
        shutil.rmtree(dump)  # no stale arrays from an earlier run
    dump.mkdir(parents=True)
    common.run_logged(
        [str(binary), "--kernel", kernel, "--sources", str(args.sources), "--targets", str(m),
         "--order", str(order), "--dump", str(dump), "--repeat", str(args.repeat)]
        + ([] if args.tolerance is None else ["--tolerance", repr(args.tolerance)])
        + ([] if args.leaf is None else ["--leaf", str(args.leaf)])
        + ([] if args.compression is None else ["--compression", args.compression])
    )  # fmt: skip


def load_dump(dump: Path, n: int, m: int) -> tuple[dict, dict[str, np.ndarray]]:
    """timing.json and the six arrays, shape-checked; exits with a message if anything is off."""
    tpath = dump / "timing.json"
    if not tpath.is_file():
        sys.exit(f"{tpath} not found (the example did not write it; with --skip-zeroset, same arguments and --keep-data?)")
    timing = json.loads(tpath.read_text())
    missing = [k for k in TIMING_KEYS if k not in timing]
    if missing:
        sys.exit(f"{tpath}: missing keys {missing} (has {sorted(timing)})")
    arrays = {}
    # The example fits ~n centres (3 per scan point, so n rounded up to a multiple of 3) and
    # reports the count it used in timing.json.
    n = int(timing.get("sources", n))
    expected = {"sources": (n, 3), "weights": (n,), "poly": (4,), "targets": (m, 3), "fmm_values": (m,),
                "direct_values": (m,)}  # fmt: skip
    for name in ARRAYS:
        path = dump / f"{name}.npy"
        if not path.is_file():
            sys.exit(f"{path} not found (the example did not write it)")
        a = np.load(path)
        if a.dtype != np.float64 or a.shape != expected[name]:
            sys.exit(f"{path}: {a.dtype} {a.shape}, expected float64 {expected[name]}")
        arrays[name] = np.ascontiguousarray(a)
    return timing, arrays


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
    threads would not help); the fork is inside the timed call."""
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
          f"(warm-up + {args.numpy_repeat}, 1 thread) …", flush=True)  # fmt: skip
    exact, ms, times = common.timed(lambda: exact_sum(x, y, w, poly, kernel), args.numpy_repeat)
    mt_ms = None
    if args.numpy_procs > 1:
        print(f"    {ms:.1f} ms; again with {args.numpy_procs} processes …", flush=True)
        mt, mt_ms, _ = common.timed(lambda: exact_sum_procs(x, y, w, poly, kernel, args.numpy_procs), args.numpy_repeat)
        diff = float(np.max(np.abs(mt - exact))) if exact.size else 0.0
        if diff != 0.0:
            print(f"    warning: the multi-process sum differs from the one-process sum by {diff:.2e}", flush=True)
        print(f"    {mt_ms:.1f} ms", flush=True)
    else:
        print(f"    {ms:.1f} ms", flush=True)
    res = NpResult(exact, ms, times, mt_ms)
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


def direct_tol(case: "Case") -> float:
    if math.isnan(case.condition):
        return DIRECT_TOL
    return max(DIRECT_TOL, DIRECT_ULPS * float(np.finfo(float).eps) * case.condition)


def process_case(case: Case, arrays, args, cache: dict) -> None:
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
    case.np_mt_ms = None if res.mt_ms is None else res.mt_ms * scale
    case.fmm_max, case.fmm_rms = rel_errors(arrays["fmm_values"][idx], res.exact)
    case.dir_max, case.dir_rms = rel_errors(arrays["direct_values"][idx], res.exact)
    case.fmm_vs_dir_max, case.fmm_vs_dir_rms = rel_errors(arrays["fmm_values"], arrays["direct_values"])
    case.condition = sum_condition(x, arrays["sources"], arrays["weights"], case.kernel)
    for key, want in (("kernel", case.kernel), ("order", case.order), ("sources", case.n), ("targets", m)):
        if str(case.timing.get(key)) != str(want):
            case.notes.append(f"timing.json {key}={case.timing.get(key)!r}, expected {want!r}")
    print(f"  FMM vs NumPy: max rel {case.fmm_max:.2e}, RMS rel {case.fmm_rms:.2e}; zeroset direct vs NumPy: "
          f"max rel {case.dir_max:.2e}, RMS rel {case.dir_rms:.2e}", flush=True)  # fmt: skip


# ---------------------------------------------------------------------------------------------
# Step 3: tables


def ratio(a: float | None, b: float | None) -> float:
    if a is None or b is None or math.isnan(a) or math.isnan(b) or b <= 0:
        return math.nan
    return a / b


def np_cell(v: float | None, c: Case) -> str:
    return fmt_ms(v) + (" (extrap.)" if c.extrapolated and v is not None else "")


def speed_table(cases: list[Case], mt: int):
    """Times and ratios; the multi-process NumPy columns only when mt > 1."""
    header = ["kernel", "order", "targets", "fmm operators ms (once)", "fmm build ms", "fmm eval ms", "fmm total ms",
              "zeroset direct ms",
              "numpy 1 proc ms"] + ([f"numpy {mt} proc ms"] if mt > 1 else []) + ["numpy 1 proc ÷ fmm"] + (
              [f"numpy {mt} proc ÷ fmm"] if mt > 1 else []) + ["zeroset direct ÷ fmm", "note"]  # fmt: skip
    body = []
    for c in cases:
        tot = c.t("fmm_total_ms")
        body.append([c.kernel, str(c.order), f"{c.m:,}", fmt_ms(c.t("fmm_operators_ms")),
                     fmt_ms(c.t("fmm_build_ms")), fmt_ms(c.t("fmm_eval_ms")),
                     fmt_ms(tot), fmt_ms(c.t("direct_ms")), np_cell(c.np_ms, c)]
                    + ([np_cell(c.np_mt_ms, c)] if mt > 1 else []) + [fmt_ratio(ratio(c.np_ms, tot))]
                    + ([fmt_ratio(ratio(c.np_mt_ms, tot))] if mt > 1 else [])
                    + [fmt_ratio(ratio(c.t("direct_ms"), tot)), "; ".join(c.notes)])  # fmt: skip
    return header, body


def accuracy_table(cases: list[Case]):
    header = ["kernel", "order", "targets", "compared on", "fmm max rel", "fmm rms rel", "direct max rel",
              "direct rms rel", "sum condition κ", "fmm vs direct max rel (all)", "fmm vs direct rms rel (all)"]  # fmt: skip
    body = []
    for c in cases:
        on = f"{c.np_targets:,}" + (" (subset)" if c.extrapolated else "")
        body.append([c.kernel, str(c.order), f"{c.m:,}", on, fmt_e(c.fmm_max), fmt_e(c.fmm_rms), fmt_e(c.dir_max),
                     fmt_e(c.dir_rms), fmt_e(c.condition), fmt_e(c.fmm_vs_dir_max), fmt_e(c.fmm_vs_dir_rms)])  # fmt: skip
    return header, body


def growth_table(cases: list[Case]):
    """FMM evaluation time against the target count, per (kernel, order), relative to the smallest M."""
    header = ["kernel", "order", "targets", "× targets", "fmm eval ms", "× eval ms", "eval ns / target",
              "fmm build ms"]  # fmt: skip
    body = []
    groups: dict[tuple[str, int], list[Case]] = {}
    for c in cases:
        groups.setdefault((c.kernel, c.order), []).append(c)
    for (k, p), cs in groups.items():
        cs = sorted(cs, key=lambda c: c.m)
        m0, e0 = cs[0].m, cs[0].t("fmm_eval_ms")
        for c in cs:
            e = c.t("fmm_eval_ms")
            body.append([k, str(p), f"{c.m:,}", f"{c.m / m0:g}×", fmt_ms(e), fmt_ratio(ratio(e, e0)),
                         f"{e * 1e6 / c.m:.1f}" if not math.isnan(e) else "—", fmt_ms(c.t("fmm_build_ms"))])  # fmt: skip
    return header, body


def check_bars(cases: list[Case]) -> common.Bars:
    bars = common.Bars()
    for c in cases:
        tol = direct_tol(c)
        bars.check(f"{c.kernel} p={c.order} M={c.m:,}: zeroset direct sum = NumPy's (max rel ≤ "
                   f"max({DIRECT_TOL:g}, {DIRECT_ULPS} ε κ) = {tol:.2g}, κ = {c.condition:.3g})",
                   None if math.isnan(c.dir_max) else c.dir_max <= tol, fmt_e(c.dir_max))  # fmt: skip
        if c.n != 10_000 or c.m != 100_000 or math.isnan(c.fmm_max) or c.fmm_max > 1e-5:
            continue  # the speed bars: 10⁴ sources × 10⁵ targets at max rel ≤ 1e-5
        tot = c.t("fmm_total_ms")
        r_np, r_dir = ratio(c.np_ms, tot), ratio(c.t("direct_ms"), tot)
        bars.check(f"{c.kernel} p={c.order}: NumPy 1 proc ÷ fmm ≥ 20 (max rel {fmt_e(c.fmm_max)})",
                   None if math.isnan(r_np) else r_np >= 20, fmt_ratio(r_np))  # fmt: skip
        bars.check(f"{c.kernel} p={c.order}: zeroset direct ÷ fmm ≥ 5",
                   None if math.isnan(r_dir) else r_dir >= 5, fmt_ratio(r_dir))  # fmt: skip
    return bars


def write_csv(path: Path, cases: list[Case]) -> None:
    with path.open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["kernel", "order", "sources", "targets", "zeroset_threads", "fmm_build_ms", "fmm_eval_ms",
                     "fmm_total_ms", "zeroset_direct_ms", "numpy_ms", "numpy_mt_ms", "numpy_extrapolated",
                     "numpy_targets", "ratio_numpy_over_fmm", "ratio_numpy_mt_over_fmm",
                     "ratio_zeroset_direct_over_fmm", "fmm_max_rel", "fmm_rms_rel", "direct_max_rel",
                     "direct_rms_rel", "sum_condition", "fmm_vs_direct_max_rel", "fmm_vs_direct_rms_rel"])  # fmt: skip
        for c in cases:
            tot = c.t("fmm_total_ms")
            wr.writerow([c.kernel, c.order, c.n, c.m, c.timing.get("threads", "")] + [common.num(v) for v in (
                c.t("fmm_build_ms"), c.t("fmm_eval_ms"), tot, c.t("direct_ms"), c.np_ms, c.np_mt_ms)]
                + [int(c.extrapolated), c.np_targets] + [common.num(v) for v in (
                ratio(c.np_ms, tot), ratio(c.np_mt_ms, tot), ratio(c.t("direct_ms"), tot), c.fmm_max, c.fmm_rms,
                c.dir_max, c.dir_rms, c.condition, c.fmm_vs_dir_max, c.fmm_vs_dir_rms)])  # fmt: skip


def main() -> None:
    args = parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    print(f"BLAS threads: {BLAS_NOTE}; load average {load_start}\n", flush=True)

    binary = example_binary()
    if args.skip_zeroset:
        print(f"--skip-zeroset: reusing the dumps in {out / 'fmm'}", flush=True)
    else:
        common.run_logged(["cargo", "build", "--release", "--example", EXAMPLE])
        if not binary.is_file():
            sys.exit(f"{binary} not found after cargo build (CARGO_TARGET_DIR elsewhere?)")

    cases: list[Case] = []
    cache: dict = {}
    numpy_s = 0.0
    for kernel in args.kernel_list:
        for order in args.order_list:
            for m in args.target_list:
                print(f"\n--- kernel {kernel}, order {order}, {args.sources:,} sources, {m:,} targets ---", flush=True)
                dump = case_dir(args, kernel, order, m)
                if not args.skip_zeroset:
                    run_zeroset(binary, dump, kernel, order, m, args)
                timing, arrays = load_dump(dump, args.sources, m)
                case = Case(kernel, order, m, args.sources, timing)
                print(f"  zeroset: fmm build {case.t('fmm_build_ms'):.1f} ms, eval {case.t('fmm_eval_ms'):.1f} ms, "
                      f"total {case.t('fmm_total_ms'):.1f} ms; direct {case.t('direct_ms'):.1f} ms; "
                      f"threads {timing.get('threads')}", flush=True)  # fmt: skip
                t0 = time.perf_counter()
                process_case(case, arrays, args, cache)
                numpy_s += time.perf_counter() - t0
                cases.append(case)
                del arrays
                if not args.keep_data and not args.skip_zeroset:
                    for name in ARRAYS:
                        (dump / f"{name}.npy").unlink(missing_ok=True)
    load_end = common.loadavg()

    mt = args.numpy_procs if args.numpy_procs > 1 else 1
    sh, sb = speed_table(cases, mt)
    ah, ab = accuracy_table(cases)
    gh, gb = growth_table(cases)
    bars = check_bars(cases)
    threads = ", ".join(sorted({str(c.timing.get("threads")) for c in cases})) or "?"
    print(f"\n=== times (ms; ratio > 1 means the FMM is faster; numpy time 'extrap.' = scaled from a subset) ===\n"
          f"{render_text(sh, sb, left=3, left_last=True)}")  # fmt: skip
    print(f"\n=== errors vs the NumPy sum (max rel = max|err| / max|exact|, rms rel = rms(err) / rms(exact)) ===\n"
          f"{render_text(ah, ab, left=4)}")  # fmt: skip
    print(f"\n=== FMM evaluation time vs target count ===\n{render_text(gh, gb, left=3)}")
    print(f"\n=== checks ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start), ("load average 1/5/15 min, at end", load_end)],
        [("BLAS threads (NumPy side)", BLAS_NOTE), ("NumPy multi-process variant", f"{mt} processes" if mt > 1 else "not run"),
         ("zeroset threads (timing.json)", threads), ("NumPy side wall time", f"{numpy_s:.1f} s")],
    )  # fmt: skip
    write_csv(out / "fmm_peers.csv", cases)

    zs_source = (
        "timings read from an earlier run's dumps (`--skip-zeroset`; only NumPy was timed now)"
        if args.skip_zeroset
        else f"median of {args.repeat} runs, the example's `--repeat`"
    )
    mt_text = (
        f"and again with the chunks spread over {mt} forked processes (BLAS one thread each, fork included in "
        "the time) "
        if mt > 1
        else ""
    )
    report = [
        "## Peer comparison: fast multipole evaluation (zeroset FMM vs the exact NumPy/SciPy sum)",
        "",
        f"`benches/peers/fmm_peers.py {' '.join(sys.argv[1:])}`: same arrays in the same run. Field "
        "s(x) = Σ_j w_j φ(|x − y_j|) + c0 + c1 x + c2 y + c3 z, φ = r (`r`) or r³ (`r3`), "
        f"{args.sources:,} sources. zeroset: `examples/fmm_timing.rs`, FMM build + evaluation and its own "
        f"parallel exact direct sum ({zs_source}); zeroset threads: {threads}. NumPy: "
        f"`scipy.spatial.distance.cdist` over target chunks of ≈ {CHUNK_BYTES >> 20} MB, then a BLAS "
        f"matrix-vector product with the weights plus the polynomial, median of {args.numpy_repeat} runs after "
        f"one warm-up, with BLAS threads {BLAS_NOTE} {mt_text}(identical results). Above "
        f"{args.numpy_max_targets:,} targets NumPy sums over an evenly strided subset of "
        f"{args.numpy_max_targets:,} targets: the time is scaled linearly to all targets (\"extrap.\") and the "
        "errors are over the subset; `fmm vs direct (all)` compares the FMM with zeroset's direct sum over all "
        "targets. Ratios: time ÷ fmm total = build + evaluation (> 1: the FMM is faster); the operators are "
        "built once per kernel and order and shared between fields, so they are listed apart. Relative errors: max = max|err| / "
        "max|exact|, rms = rms(err) / rms(exact).",
        "",
        "### Times",
        "",
        render_md(sh, sb, left=3),
        "",
        "### Errors against the NumPy sum",
        "",
        render_md(ah, ab, left=4),
        "",
        "### FMM evaluation time against the target count",
        "",
        render_md(gh, gb, left=3),
        "",
        "### Checks",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "fmm_peers.md", out / "fmm_peers.csv", report, facts)


if __name__ == "__main__":
    main()
