#!/usr/bin/env python3
"""Peer comparison: zeroset's quadratic B-spline prefilter and evaluation vs scipy.ndimage.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/spline_peers.py [--n 128,256] [--points 1000000]

Per case (n, mode) — by default mirror at n = 128 and 256, and reflect at n = 128:
  1. `cargo run --release --example spline_timing -- --n N --points P --repeat R --mode MODE
     --order 2 --write-dir DIR` times zeroset's prefilter and its evaluation at P points
     (continuous indices), and writes the grid, zeroset's coefficients, the points and the values
     as raw little-endian f64;
  2. on the same data, times `scipy.ndimage.spline_filter(grid, order=2, mode=MODE,
     output=np.float64)` and `map_coordinates(coeffs, points, order=2, prefilter=False,
     mode=MODE)` on zeroset's coefficients, and compares coefficients and values
     (max abs difference / max |grid|);
  3. prints tables with ratios (scipy_ms / zeroset_ms, > 1 means zeroset is faster),
     PASS/FAIL per bar, and writes OUT/spline_peers.csv and OUT/spline_peers.md.
Always exits 0 once it has run; a failed bar is reported, not raised.
"""

from __future__ import annotations

import argparse
import csv
import math
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import common
from common import fmt_e, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads()  # before numpy is imported

import numpy as np  # noqa: E402
from scipy import ndimage  # noqa: E402

EXAMPLE = "spline_timing"
ORDER = 2
AGREE_TOL = 1e-10  # relative to max |grid|
DATA_FILES = ("grid.f64", "coeffs.f64", "points.f64", "values.f64")


@dataclass
class Case:
    n: int
    mode: str
    points: int
    zs_prefilter_ms: float = math.nan
    zs_eval_ms: float = math.nan
    zs_threads: str = "?"
    sp_prefilter_ms: float = math.nan
    sp_eval_ms: float = math.nan
    coeff_diff: float = math.nan  # max |c_zeroset − c_scipy| / max |grid|
    value_diff: float = math.nan  # max |v_zeroset − map_coordinates(c_zeroset)| / max |grid|
    e2e_diff: float = math.nan  # max |v_zeroset − map_coordinates(c_scipy)| / max |grid|

    @property
    def prefilter_ratio(self) -> float:
        return self.sp_prefilter_ms / self.zs_prefilter_ms

    @property
    def eval_ratio(self) -> float:
        return self.sp_eval_ms / self.zs_eval_ms


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Time scipy.ndimage on the same B-spline data zeroset prefilters and evaluates.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--n", default="128,256", help="grid sizes (n³ samples), mode mirror")
    p.add_argument("--reflect-n", default="128", help="grid sizes also run with mode reflect; '' for none")
    p.add_argument("--points", type=int, default=1_000_000, help="evaluation points")
    p.add_argument("--repeat", type=int, default=5, help="zeroset timed runs after one warm-up")
    p.add_argument("--prefilter-repeat", type=int, default=5, help="scipy spline_filter timed runs after one warm-up")
    p.add_argument("--eval-repeat", type=int, default=3, help="scipy map_coordinates timed runs after one warm-up")
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the CSV, report and data")
    p.add_argument(
        "--keep-data",
        action="store_true",
        help="keep the raw .f64 files in OUT/spline_n{n}_{mode}/ (≈ 300 MB at n=256); removed otherwise",
    )
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
    a.out = Path(a.out).resolve()
    return a


def run_zeroset(case: Case, repeat: int, data: Path) -> None:
    data.mkdir(parents=True, exist_ok=True)
    stdout = common.run_logged(
        ["cargo", "run", "--release", "--example", EXAMPLE, "--",
         "--n", str(case.n), "--points", str(case.points), "--repeat", str(repeat),
         "--mode", case.mode, "--order", str(ORDER), "--write-dir", str(data)],
        capture=True,
    )  # fmt: skip
    fields = dict(re.findall(r"(\w+)=(\S+)", stdout))
    try:
        case.zs_prefilter_ms = float(fields["prefilter_ms"])
        case.zs_eval_ms = float(fields["eval_ms"])
    except (KeyError, ValueError):
        sys.exit(f"could not read prefilter_ms= / eval_ms= from the example's output:\n{stdout}")
    case.zs_threads = fields.get("threads", "?")


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
    print(
        f"  prefilter {case.sp_prefilter_ms:.1f} ms (zeroset {case.zs_prefilter_ms:.1f}), "
        f"eval {case.sp_eval_ms:.1f} ms (zeroset {case.zs_eval_ms:.1f}); "
        f"coeff diff {case.coeff_diff:.1e}, value diff {case.value_diff:.1e}",
        flush=True,
    )


def check_bars(cases: list[Case]) -> common.Bars:
    bars = common.Bars()
    mirror = {c.n: c for c in cases if c.mode == "mirror"}
    c = mirror.get(256)
    bars.check("prefilter 256³ (mirror): zeroset ≥ 3× faster than scipy", None if c is None else c.prefilter_ratio >= 3,
               "not measured" if c is None else
               f"{fmt_ms(c.sp_prefilter_ms)} / {fmt_ms(c.zs_prefilter_ms)} ms = {c.prefilter_ratio:.1f}×")  # fmt: skip
    for c in sorted(mirror.values(), key=lambda c: c.n):
        bars.check(f"eval {c.points:,} pts, n={c.n} (mirror): zeroset ≥ 5× faster", c.eval_ratio >= 5,
                   f"{fmt_ms(c.sp_eval_ms)} / {fmt_ms(c.zs_eval_ms)} ms = {c.eval_ratio:.1f}×")  # fmt: skip
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
    print(f"BLAS threads: {BLAS_NOTE}; load average {load_start}", flush=True)

    cases = []
    for n, mode in args.cases:
        case = Case(n, mode, args.points)
        data = out / f"spline_n{n}_{mode}"
        print(f"\n--- n={n} ({n**3:,} samples), {args.points:,} points, mode {mode} ---", flush=True)
        run_zeroset(case, args.repeat, data)
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

    header = ["n", "mode", "zeroset prefilter ms", "scipy spline_filter ms", "ratio",
              "zeroset eval ms", "scipy map_coordinates ms", "ratio",
              "coeff diff", "value diff", "e2e diff"]  # fmt: skip
    body = [
        [str(c.n), c.mode, fmt_ms(c.zs_prefilter_ms), fmt_ms(c.sp_prefilter_ms), fmt_ratio(c.prefilter_ratio),
         fmt_ms(c.zs_eval_ms), fmt_ms(c.sp_eval_ms), fmt_ratio(c.eval_ratio),
         fmt_e(c.coeff_diff), fmt_e(c.value_diff), fmt_e(c.e2e_diff)]
        for c in cases
    ]  # fmt: skip
    bars = check_bars(cases)
    threads = ", ".join(sorted({c.zs_threads for c in cases}))
    print(f"\n=== spline order {ORDER}: ratio = scipy_ms / zeroset_ms (> 1 means zeroset is faster); "
          f"zeroset threads {threads}, scipy.ndimage single-threaded ===\n{render_text(header, body)}")  # fmt: skip
    print(f"\n=== bars ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start), ("load average 1/5/15 min, at end", load_end)],
        [("BLAS threads (scipy side)", BLAS_NOTE), ("zeroset threads (from the example)", threads)],
    )
    with (out / "spline_peers.csv").open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["n", "mode", "points", "zeroset_threads", "zeroset_prefilter_ms", "scipy_prefilter_ms",
                     "ratio_prefilter", "zeroset_eval_ms", "scipy_eval_ms", "ratio_eval",
                     "max_coeff_diff_rel", "max_value_diff_rel", "max_e2e_diff_rel"])  # fmt: skip
        for c in cases:
            wr.writerow([c.n, c.mode, c.points, c.zs_threads] + [common.num(v) for v in (
                c.zs_prefilter_ms, c.sp_prefilter_ms, c.prefilter_ratio, c.zs_eval_ms, c.sp_eval_ms,
                c.eval_ratio, c.coeff_diff, c.value_diff, c.e2e_diff)])  # fmt: skip

    report = [
        "## Peer comparison: quadratic B-spline prefilter and evaluation (zeroset vs scipy.ndimage)",
        "",
        f"`benches/peers/spline_peers.py {' '.join(sys.argv[1:])}`: same data in the same run. "
        f"zeroset: `examples/spline_timing.rs` (median of {args.repeat} runs after one warm-up; "
        f"{threads} rayon threads). scipy (single-threaded): `spline_filter(grid, order=2, mode, "
        f"output=float64)` (median of {args.prefilter_repeat}) and `map_coordinates(coeffs, points, "
        f"order=2, prefilter=False, mode)` on zeroset's coefficients (median of {args.eval_repeat}), after "
        f"one warm-up each; {args.points:,} points uniform in [0, n−1]³. Ratio = scipy_ms / zeroset_ms "
        "(> 1: zeroset faster). Differences are max abs / max |grid|: `coeff diff` zeroset vs scipy "
        "coefficients, `value diff` zeroset's values vs scipy evaluating zeroset's coefficients, `e2e diff` "
        f"vs scipy evaluating its own coefficients. scipy BLAS threads: {BLAS_NOTE}.",
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
