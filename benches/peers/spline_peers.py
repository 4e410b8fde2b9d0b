#!/usr/bin/env python3
"""Peer comparison: zeroset's quadratic B-spline prefilter and evaluation vs scipy.ndimage.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/spline_peers.py [--n 128,256] [--points 1000000]

Threads: scipy.ndimage's `spline_filter` and `map_coordinates` are single-threaded compiled code
with no thread setting (no `workers` argument, no BLAS), so scipy's one configuration is both its
one-thread and its best; zeroset is timed at one thread (RAYON_NUM_THREADS=1) and at all threads
(RAYON_NUM_THREADS=N, N = --mt-threads, default the CPUs available), and the report gives the
ratios with zeroset on one thread (one thread each) and at its fastest.

Per case (n, mode) — by default mirror at n = 128 and 256, and reflect at n = 128:
  1. `cargo build --release --example spline_timing` (CARGO_TARGET_DIR honoured; --skip-build
     reuses the binary), then `spline_timing --n N --points P --repeat R --mode MODE --order 2`
     twice: with RAYON_NUM_THREADS=1 (this run also writes the grid, zeroset's coefficients, the
     points and the values as raw little-endian f64: `--write-dir DIR`) and with
     RAYON_NUM_THREADS=N. Timed by the example (one warm-up, then the median of R): the prefilter
     in place on a fresh copy of the grid (the copy not timed: `BSplineField::interpolate` takes
     the samples by value) and the evaluation at P points (continuous indices) into a ready array;
  2. on the same data, times `scipy.ndimage.spline_filter(grid, order=2, mode=MODE,
     output=np.float64)` (allocates its output) and `map_coordinates(coeffs, points, order=2,
     prefilter=False, mode=MODE)` on zeroset's coefficients (allocates its output), one warm-up
     then the median, and compares coefficients and values (max abs difference / max |grid|);
  3. prints tables with ratios (scipy_ms / zeroset_ms, > 1 means zeroset is faster) with zeroset
     on one thread and at its fastest, PASS/FAIL per bar (judged with zeroset at its fastest; one
     thread reported), and writes OUT/spline_peers.csv and OUT/spline_peers.md.
Always exits 0 once it has run; a failed bar is reported, not raised.
"""

from __future__ import annotations

import argparse
import csv
import math
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import common
from common import fmt_e, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402
from scipy import ndimage  # noqa: E402

EXAMPLE = "spline_timing"
ORDER = 2
AGREE_TOL = 1e-10  # relative to max |grid|
DATA_FILES = ("grid.f64", "coeffs.f64", "points.f64", "values.f64")
CONFIGS = ("1", "all")  # zeroset: RAYON_NUM_THREADS=1, RAYON_NUM_THREADS=N


@dataclass
class ZsRun:
    """One zeroset run (one thread configuration) of one case."""

    prefilter_ms: float = math.nan
    eval_ms: float = math.nan
    threads: str = "?"  # as the example reports it
    runs: int | None = None  # timed runs after one warm-up


@dataclass
class Case:
    n: int
    mode: str
    points: int
    zs: dict = field(default_factory=dict)  # config "1" / "all" -> ZsRun
    sp_prefilter_ms: float = math.nan
    sp_eval_ms: float = math.nan
    coeff_diff: float = math.nan  # max |c_zeroset − c_scipy| / max |grid|
    value_diff: float = math.nan  # max |v_zeroset − map_coordinates(c_zeroset)| / max |grid|
    e2e_diff: float = math.nan  # max |v_zeroset − map_coordinates(c_scipy)| / max |grid|

    def zs_ms(self, config: str, what: str) -> float:
        z = self.zs.get(config)
        return math.nan if z is None else getattr(z, f"{what}_ms")

    def zs_fastest(self, what: str) -> tuple[str | None, float]:
        return common.fastest({f"zeroset {z.threads} thr": getattr(z, f"{what}_ms") for z in self.zs.values()})

    def ratios(self, what: str) -> tuple[float, float, str]:
        """scipy ÷ zeroset: (zeroset on one thread, zeroset at its fastest, which zeroset run)."""
        sp = getattr(self, f"sp_{what}_ms")
        label, ms = self.zs_fastest(what)
        return common.ratio(sp, self.zs_ms("1", what)), common.ratio(sp, ms), label or "—"


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Time scipy.ndimage on the same B-spline data zeroset prefilters and evaluates.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--n", default="128,256", help="grid sizes (n³ samples), mode mirror")
    p.add_argument("--reflect-n", default="128", help="grid sizes also run with mode reflect; '' for none")
    p.add_argument("--points", type=int, default=1_000_000, help="evaluation points")
    p.add_argument("--repeat", type=int, default=5, help="zeroset timed runs after one warm-up (each thread setting)")
    p.add_argument("--prefilter-repeat", type=int, default=5, help="scipy spline_filter timed runs after one warm-up")
    p.add_argument("--eval-repeat", type=int, default=3, help="scipy map_coordinates timed runs after one warm-up")
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the CSV, report and data")
    p.add_argument(
        "--keep-data",
        action="store_true",
        help="keep the raw .f64 files in OUT/spline_n{n}_{mode}/ (≈ 300 MB at n=256); removed otherwise",
    )
    p.add_argument("--skip-build", action="store_true", help="do not run cargo build; reuse the example binary")
    common.add_mt_arg(p, None)  # scipy.ndimage's spline_filter / map_coordinates have no thread setting
    common.add_blas_arg(p)
    a = p.parse_args()

    def ints(s, flag):
        return common.int_list(p, s, flag, 2)

    a.cases = [(n, "mirror") for n in ints(a.n, "--n")] + [(n, "reflect") for n in ints(a.reflect_n, "--reflect-n")]
    if not a.cases:
        p.error("nothing to do: --n and --reflect-n are both empty")
    for name in ("points", "repeat", "prefilter_repeat", "eval_repeat"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if a.mt_threads < 0:
        p.error("--mt-threads must be >= 0")
    a.mt = a.mt_threads if a.mt_threads > 1 else 0  # 0: one-thread run only
    a.out = Path(a.out).resolve()
    return a


def run_zeroset(binary: Path, case: Case, args, data: Path, config: str) -> None:
    """`config` "1": RAYON_NUM_THREADS=1, writes the data files; "all": RAYON_NUM_THREADS=N."""
    cmd = [str(binary), "--n", str(case.n), "--points", str(case.points), "--repeat", str(args.repeat),
           "--mode", case.mode, "--order", str(ORDER)]  # fmt: skip
    if config == "1":
        data.mkdir(parents=True, exist_ok=True)
        cmd += ["--write-dir", str(data)]
    stdout = common.run_logged(cmd, capture=True, env={"RAYON_NUM_THREADS": "1" if config == "1" else str(args.mt)})
    fields = dict(re.findall(r"(\w+)=(\S+)", stdout))
    z = ZsRun()
    try:
        z.prefilter_ms = float(fields["prefilter_ms"])
        z.eval_ms = float(fields["eval_ms"])
    except (KeyError, ValueError):
        sys.exit(f"could not read prefilter_ms= / eval_ms= from the example's output:\n{stdout}")
    z.threads = fields.get("threads", "?")
    z.runs = int(fields["runs"]) if fields.get("runs", "").isdigit() else None
    if config == "1" and z.threads not in ("1", "?"):
        print(f"warning: the RAYON_NUM_THREADS=1 run reports threads={z.threads}", flush=True)
    case.zs[config] = z


def load(data: Path, name: str, count: int) -> np.ndarray:
    f = data / name
    if not f.is_file():
        sys.exit(f"{f} not found (the example did not write it)")
    v = np.fromfile(f, dtype="<f8")
    if v.size != count:
        sys.exit(f"{f}: {v.size} values, expected {count}")
    return v


def run_scipy(case: Case, args, data: Path) -> None:
    n, p, mode = case.n, case.points, case.mode
    t0 = time.perf_counter()
    grid = load(data, "grid.f64", n**3).reshape(n, n, n)
    coeffs = load(data, "coeffs.f64", n**3).reshape(n, n, n)
    points = load(data, "points.f64", 3 * p).reshape(3, p)
    values = load(data, "values.f64", p)
    print(f"  loaded in {time.perf_counter() - t0:.2f} s", flush=True)
    scale = float(np.max(np.abs(grid)))

    print(f"  scipy spline_filter (warm-up + {args.prefilter_repeat}) …", flush=True)
    c_sp, case.sp_prefilter_ms, _ = common.timed(
        lambda: ndimage.spline_filter(grid, order=ORDER, output=np.float64, mode=mode), args.prefilter_repeat
    )
    case.coeff_diff = float(np.max(np.abs(coeffs - c_sp))) / scale

    print(f"  scipy map_coordinates (warm-up + {args.eval_repeat}) …", flush=True)
    v_sp, case.sp_eval_ms, _ = common.timed(
        lambda: ndimage.map_coordinates(coeffs, points, order=ORDER, prefilter=False, mode=mode), args.eval_repeat
    )
    case.value_diff = float(np.max(np.abs(values - v_sp))) / scale
    # end to end, scipy's own coefficients (not timed)
    v_e2e = ndimage.map_coordinates(c_sp, points, order=ORDER, prefilter=False, mode=mode)
    case.e2e_diff = float(np.max(np.abs(values - v_e2e))) / scale
    zs = lambda what: " / ".join(f"{getattr(z, what + '_ms'):.1f} ({z.threads} thr)" for z in case.zs.values())  # noqa: E731
    print(
        f"  prefilter {case.sp_prefilter_ms:.1f} ms (zeroset {zs('prefilter')}), "
        f"eval {case.sp_eval_ms:.1f} ms (zeroset {zs('eval')}); "
        f"coeff diff {case.coeff_diff:.1e}, value diff {case.value_diff:.1e}",
        flush=True,
    )


def speed_bars(bars: common.Bars, c: Case, what: str, target: float, label: str) -> None:
    """The bar with zeroset at its fastest, and the one-thread ratio reported beside it."""
    one, fast, which = c.ratios(what)
    sp = getattr(c, f"sp_{what}_ms")
    verdict = lambda v: None if math.isnan(v) else v >= target  # noqa: E731
    bars.check(f"{label}: zeroset ≥ {target:g}× faster than scipy, zeroset at its fastest", verdict(fast),
               f"{fmt_ms(sp)} / {fmt_ms(c.zs_fastest(what)[1])} ms = {fmt_ratio(fast)} ({which})")  # fmt: skip
    bars.check(f"{label}: zeroset ≥ {target:g}× faster than scipy, one thread each (reported)", verdict(one),
               f"{fmt_ms(sp)} / {fmt_ms(c.zs_ms('1', what))} ms = {fmt_ratio(one)}")  # fmt: skip


def check_bars(cases: list[Case]) -> common.Bars:
    bars = common.Bars()
    mirror = {c.n: c for c in cases if c.mode == "mirror"}
    c = mirror.get(256)
    if c is None:
        bars.check("prefilter 256³ (mirror): zeroset ≥ 3× faster than scipy", None, "not measured")
    else:
        speed_bars(bars, c, "prefilter", 3, "prefilter 256³ (mirror)")
    for c in sorted(mirror.values(), key=lambda c: c.n):
        speed_bars(bars, c, "eval", 5, f"eval {c.points:,} pts, n={c.n} (mirror)")
    if not mirror:
        bars.check("eval 1M points (mirror): zeroset ≥ 5× faster", None, "not measured")
    for c in cases:
        worst = max(c.coeff_diff, c.value_diff)
        bars.check(f"n={c.n} {c.mode}: coefficients and values agree (≤ {AGREE_TOL:g}·max|grid|)", worst <= AGREE_TOL,
                   f"coeffs {c.coeff_diff:.1e}, values {c.value_diff:.1e}")  # fmt: skip
    return bars


def main() -> None:
    args = parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    blas_rt = common.blas_runtime()
    print(f"BLAS threads: {BLAS_NOTE} ({blas_rt}; scipy.ndimage uses none); all-threads configuration (zeroset): "
          f"{args.mt or 'not run'}; load average {load_start}", flush=True)  # fmt: skip

    binary = common.built_example(EXAMPLE, args.skip_build)
    cases = []
    for n, mode in args.cases:
        case = Case(n, mode, args.points)
        data = out / f"spline_n{n}_{mode}"
        print(f"\n--- n={n} ({n**3:,} samples), {args.points:,} points, mode {mode} ---", flush=True)
        for config in CONFIGS if args.mt else CONFIGS[:1]:
            run_zeroset(binary, case, args, data, config)
        run_scipy(case, args, data)
        if not args.keep_data:
            for f in DATA_FILES:
                (data / f).unlink(missing_ok=True)
            try:
                data.rmdir()
            except OSError:
                pass
        cases.append(case)
    load_end = common.loadavg()

    mt = args.mt or "all"
    zs_cell = lambda c, cfg, what: "—" if cfg not in c.zs else common.with_how(  # noqa: E731
        c.zs_ms(cfg, what), c.zs[cfg].runs, True, args.repeat)
    header = ["n", "mode", "zeroset prefilter ms, 1 thread", f"zeroset prefilter ms, {mt} threads",
              "scipy spline_filter ms (1 thread)", "ratio, 1 thread each", "ratio, zeroset at its fastest",
              "zeroset eval ms, 1 thread", f"zeroset eval ms, {mt} threads", "scipy map_coordinates ms (1 thread)",
              "ratio, 1 thread each", "ratio, zeroset at its fastest", "coeff diff", "value diff", "e2e diff"]  # fmt: skip
    body = []
    for c in cases:
        pf, ev = c.ratios("prefilter"), c.ratios("eval")
        body.append([str(c.n), c.mode, zs_cell(c, "1", "prefilter"), zs_cell(c, "all", "prefilter"),
                     common.with_how(c.sp_prefilter_ms, args.prefilter_repeat, True), fmt_ratio(pf[0]),
                     f"{fmt_ratio(pf[1])} ({pf[2]})", zs_cell(c, "1", "eval"), zs_cell(c, "all", "eval"),
                     common.with_how(c.sp_eval_ms, args.eval_repeat, True), fmt_ratio(ev[0]),
                     f"{fmt_ratio(ev[1])} ({ev[2]})", fmt_e(c.coeff_diff), fmt_e(c.value_diff), fmt_e(c.e2e_diff)])  # fmt: skip
    bars = check_bars(cases)
    threads = ", ".join(sorted({z.threads for c in cases for z in c.zs.values()}))
    print(f"\n=== spline order {ORDER}: ratio = scipy_ms / zeroset_ms (> 1 means zeroset is faster); "
          f"zeroset threads {threads}; scipy.ndimage single-threaded, no thread setting ===\n"
          f"{render_text(header, body)}")  # fmt: skip
    print(f"\n=== bars ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start), ("load average 1/5/15 min, at end", load_end)],
        [("BLAS threads (Python side; spline_filter / map_coordinates use none)",
          f"{BLAS_NOTE}; OpenBLAS reports {blas_rt}"),
         ("zeroset threads (from the example)", threads)],
    )  # fmt: skip
    with (out / "spline_peers.csv").open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["n", "mode", "points", "side", "threads", "runs", "prefilter_ms", "eval_ms",
                     "ratio_prefilter_scipy_over_this", "ratio_eval_scipy_over_this",
                     "ratio_prefilter_one_thread_each", "ratio_prefilter_zeroset_fastest",
                     "ratio_eval_one_thread_each", "ratio_eval_zeroset_fastest",
                     "max_coeff_diff_rel", "max_value_diff_rel", "max_e2e_diff_rel"])  # fmt: skip
        for c in cases:
            pf, ev = c.ratios("prefilter"), c.ratios("eval")
            tail = [common.num(v) for v in (pf[0], pf[1], ev[0], ev[1], c.coeff_diff, c.value_diff, c.e2e_diff)]
            for z in c.zs.values():
                wr.writerow([c.n, c.mode, c.points, "zeroset", z.threads, common.num(z.runs)] + [common.num(v) for v in (
                    z.prefilter_ms, z.eval_ms, common.ratio(c.sp_prefilter_ms, z.prefilter_ms),
                    common.ratio(c.sp_eval_ms, z.eval_ms))] + tail)  # fmt: skip
            wr.writerow([c.n, c.mode, c.points, "scipy", "1", f"{args.prefilter_repeat}/{args.eval_repeat}"]
                        + [common.num(v) for v in (c.sp_prefilter_ms, c.sp_eval_ms, 1.0, 1.0)] + tail)  # fmt: skip

    report = [
        "## Peer comparison: quadratic B-spline prefilter and evaluation (zeroset vs scipy.ndimage)",
        "",
        f"`benches/peers/spline_peers.py {' '.join(sys.argv[1:])}`: same data in the same run; "
        f"{args.points:,} points uniform in [0, n−1]³.",
        "",
        "**zeroset**: `examples/spline_timing.rs` with RAYON_NUM_THREADS=1 and with "
        f"RAYON_NUM_THREADS={args.mt or '—'} (threads reported: {threads}); one warm-up, then the median of "
        f"{args.repeat} runs. *prefilter* = the in-place prefilter of a fresh copy of the grid (the copy is not "
        "timed: `BSplineField::interpolate` takes the samples by value); *eval* = the values at the points "
        "(continuous indices) into a ready array.",
        "",
        f"**scipy** {__import__('scipy').__version__}: `spline_filter(grid, order=2, mode, output=float64)` "
        f"(median of {args.prefilter_repeat}; allocates its output) and `map_coordinates(coeffs, points, order=2, "
        f"prefilter=False, mode)` on zeroset's coefficients (median of {args.eval_repeat}; allocates its output), "
        "after one warm-up each. Both are single-threaded compiled code with **no thread setting** (no `workers` "
        "argument; no BLAS), so scipy's one configuration is both its one-thread and its best; the BLAS threads "
        f"are pinned anyway ({BLAS_NOTE}; OpenBLAS reports {blas_rt}). Loading the files is outside both.",
        "",
        "**Ratios** = scipy ms ÷ zeroset ms (> 1: zeroset faster): *1 thread each* (zeroset with "
        "RAYON_NUM_THREADS=1) and *zeroset at its fastest* (the faster of its two runs, named). The speed bars are "
        "judged with zeroset at its fastest; the one-thread ratio is reported beside them. Differences are max abs "
        "/ max |grid|: `coeff diff` zeroset vs scipy coefficients, `value diff` zeroset's values (one-thread run) "
        "vs scipy evaluating zeroset's coefficients, `e2e diff` vs scipy evaluating its own coefficients.",
        "",
        render_md(header, body),
        "",
        "### Bars",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "spline_peers.md", out / "spline_peers.csv", report, facts)


if __name__ == "__main__":
    main()
