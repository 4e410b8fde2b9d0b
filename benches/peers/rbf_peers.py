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

  1. `cargo run --release --example rbf_timing -- --n 1000,3000,6000 --kernels r,r3 --eval M
     --repeat R --write-dir OUT --csv OUT/rbf_zeroset.csv` times zeroset's fit and its evaluation
     at the M points and writes the fit points (OUT/rbf_sphere_n{N}.csv, `x,y,z,value`), the
     evaluation points (OUT/rbf_eval_{M}.csv, `x,y,z`; 17 significant digits, so both sides see
     bit-identical input) and its results, one row per (n, kernel, solver). `--skip-zeroset`
     reuses those files instead of running cargo;
  2. on the same points (read back, not regenerated), times `RBFInterpolator(points, values,
     kernel=K, degree=1)` (dense LU, LAPACK dgesv) and its evaluation at the M points, and computes
     the same accuracy figures as zeroset: max |s(x) − sd(x)| over the evaluation points with
     |sd(x)| < 0.05, sd(x) = |x − c| − 0.35, and the constraint residual max |s(x_i) − v_i|;
  3. prints a table with ratios (scipy_ms / zeroset_ms, > 1 means zeroset is faster), PASS/FAIL
     per bar, and writes OUT/rbf_peers.csv and OUT/rbf_peers.md.
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
from common import fmt_e, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads()  # before numpy is imported

import numpy as np  # noqa: E402
from scipy.interpolate import RBFInterpolator  # noqa: E402

EXAMPLE = "rbf_timing"
ZEROSET_CSV = "rbf_zeroset.csv"
SCIPY_KERNEL = {"r": "linear", "r3": "cubic"}  # zeroset kernel name -> scipy kernel name
DEGREE = 1
CENTRE = np.array([0.5, 0.5, 0.5])
RADIUS = 0.35
OFFSET = 0.05  # normal offset of the off-surface points, and half-width of the accuracy band
BAR_NS = (1000, 3000, 6000)  # N at which the accuracy bars are checked
SPEED_N = 6000  # N at which the speed bars are checked
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
    runs: int | None
    threads: str | None  # optional column; absent in the current example


@dataclass
class SpRow:
    """scipy's result for one (n, kernel)."""

    n: int
    kernel: str  # zeroset's name
    runs: int
    single: bool  # one run without warm-up (n > --scipy-once-above)
    fit_ms: float = math.nan
    eval_ms: float = math.nan
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
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the point files, CSV and report")
    p.add_argument(
        "--skip-zeroset",
        action="store_true",
        help=f"do not run cargo; reuse the point files and {ZEROSET_CSV} already in --out (only scipy is timed now)",
    )
    common.add_blas_arg(p)
    a = p.parse_args()

    a.ns = common.int_list(p, a.n, "--n", 12)
    if not a.ns:
        p.error("nothing to do: --n is empty")
    a.kernel_list = [k.strip() for k in a.kernels.split(",") if k.strip()]
    if not a.kernel_list or any(k not in SCIPY_KERNEL for k in a.kernel_list):
        p.error(f"--kernels: expected a comma-separated subset of {sorted(SCIPY_KERNEL)}, got {a.kernels!r}")
    for name in ("eval", "repeat", "scipy_repeat"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: zeroset


def run_zeroset(args) -> None:
    args.out.mkdir(parents=True, exist_ok=True)
    common.run_logged(
        ["cargo", "run", "--release", "--example", EXAMPLE, "--",
         "--n", ",".join(map(str, args.ns)), "--kernels", ",".join(args.kernel_list),
         "--eval", str(args.eval), "--repeat", str(args.repeat),
         "--write-dir", str(args.out), "--csv", str(args.out / ZEROSET_CSV)]
    )  # fmt: skip


def read_zeroset(path: Path) -> list[ZsRow]:
    """Reads the example's CSV: empty cells are missing values, unknown columns are ignored."""
    if not path.is_file():
        sys.exit(f"{path} not found (the example did not write it)")
    required = ("n", "kernel", "solver", "fit_ms", "eval_ms", "max_err_band", "max_constraint_residual", "runs")

    def cell(r: dict, key: str, conv):
        v = (r.get(key) or "").strip()
        return conv(v) if v else None

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


def load_fit_points(out: Path, n: int) -> tuple[np.ndarray, np.ndarray]:
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
    print(f"  {n} fit points; max |sd(x_i) − v_i| = {np.max(np.abs(signed_distance(pts) - vals)):.1e}", flush=True)
    return pts, vals


def run_scipy(n: int, kernel: str, pts, vals, xe, band, sd_band, args) -> SpRow:
    single = n > args.scipy_once_above
    row = SpRow(n, kernel, 1 if single else args.scipy_repeat, single)
    how = "1 run, no warm-up" if single else f"warm-up + {row.runs}"
    sk = SCIPY_KERNEL[kernel]
    print(f"  scipy RBFInterpolator kernel={sk!r}, degree={DEGREE}: fit and eval ({how} each) …", flush=True)
    interp, row.fit_ms, _ = common.timed(
        lambda: RBFInterpolator(pts, vals, kernel=sk, degree=DEGREE), row.runs, warmup=not single
    )
    s, row.eval_ms, _ = common.timed(lambda: interp(xe), row.runs, warmup=not single)
    row.max_err = float(np.max(np.abs(s[band] - sd_band)))
    row.residual = float(np.max(np.abs(interp(pts) - vals)))  # untimed
    print(f"    fit {row.fit_ms:.1f} ms, eval {row.eval_ms:.1f} ms; max err in band {row.max_err:.3e}, "
          f"residual {row.residual:.1e}", flush=True)  # fmt: skip
    return row


# ---------------------------------------------------------------------------------------------
# Step 3: tables and bars


def kernel_order(k: str) -> int:
    return list(SCIPY_KERNEL).index(k) if k in SCIPY_KERNEL else len(SCIPY_KERNEL)


def ratio(sp: float | None, zs: float | None) -> float:
    """scipy_ms / zeroset_ms; NaN where either is missing."""
    if sp is None or zs is None or math.isnan(sp) or math.isnan(zs) or zs <= 0:
        return math.nan
    return sp / zs


def paired(zs_rows: list[ZsRow], sp_rows: list[SpRow]) -> list[tuple[int, str, ZsRow | None, SpRow | None]]:
    """(n, kernel, zeroset row, scipy row) — one entry per zeroset row (several solvers per (n, kernel)
    are possible), plus the scipy rows zeroset did not report."""
    sp = {(r.n, r.kernel): r for r in sp_rows}
    keys = sorted({(r.n, r.kernel) for r in zs_rows} | set(sp), key=lambda k: (k[0], kernel_order(k[1]), k[1]))
    out = []
    for n, k in keys:
        zs = [r for r in zs_rows if r.n == n and r.kernel == k] or [None]
        out += [(n, k, z, sp.get((n, k))) for z in zs]
    return out


def table(pairs, args):
    header = ["n", "kernel", "zeroset solver", "zeroset fit ms", "scipy fit ms", "fit ratio",
              "zeroset eval ms", "scipy eval ms", "eval ratio", "zeroset max err", "scipy max err",
              "zeroset residual", "scipy residual", "note"]  # fmt: skip
    body = []
    for n, k, z, s in pairs:
        g = lambda attr: None if z is None else getattr(z, attr)  # noqa: E731
        h = lambda attr: None if s is None else getattr(s, attr)  # noqa: E731
        notes = []
        if z is None:
            notes.append("not in zeroset's CSV")
        elif z.runs is not None and z.runs != args.repeat:
            notes.append(f"zeroset runs {z.runs}")
        if s is None:
            notes.append("zeroset only")
        elif s.single:
            notes.append("scipy single run")
        body.append([str(n), f"{k} / {SCIPY_KERNEL.get(k, '?')}", "—" if z is None else z.solver,
                     fmt_ms(g("fit_ms")), fmt_ms(h("fit_ms")), fmt_ratio(ratio(h("fit_ms"), g("fit_ms"))),
                     fmt_ms(g("eval_ms")), fmt_ms(h("eval_ms")), fmt_ratio(ratio(h("eval_ms"), g("eval_ms"))),
                     fmt_e(g("max_err")), fmt_e(h("max_err")), fmt_e(g("residual")), fmt_e(h("residual")),
                     "; ".join(notes)])  # fmt: skip
    return header, body


def check_bars(pairs, args) -> common.Bars:
    bars = common.Bars()
    find = lambda n, k: [(z, s) for pn, pk, z, s in pairs if pn == n and pk == k and z is not None]  # noqa: E731
    sp_of = lambda n, k: next((s for pn, pk, _, s in pairs if pn == n and pk == k and s is not None), None)  # noqa: E731
    where = lambda z: "" if z is None else f" ({z.solver})"  # noqa: E731

    # Accuracy: zeroset at least as accurate as scipy in the band (the same interpolant for `r`).
    for k in SCIPY_KERNEL:
        for n in BAR_NS:
            label = lambda z: f"n={n} {k}{where(z)}: zeroset max err in band ≤ scipy's (× {1 + ACC_SLACK:g})"  # noqa: E731
            found = [(z, s) for z, s in find(n, k) if s is not None and z.max_err is not None]
            if not found:
                bars.check(label(None), None, "not measured")
            for z, s in found:
                bars.check(label(z), z.max_err <= s.max_err * (1 + ACC_SLACK),
                           f"{z.max_err:.3e} vs {s.max_err:.3e} (ratio {z.max_err / s.max_err:.3f})")  # fmt: skip

    # Constraint residual, every zeroset row (also the zeroset-only ones).
    for z in (z for _, _, z, _ in pairs if z is not None):
        bars.check(f"n={z.n} {z.kernel}{where(z)}: constraint residual ≤ {RESIDUAL_TOL:g}",
                   None if z.residual is None else z.residual <= RESIDUAL_TOL,
                   "not reported" if z.residual is None else f"{z.residual:.2e}")  # fmt: skip

    # Speed at n = SPEED_N, per kernel (and per zeroset solver, if several).
    for k in SCIPY_KERNEL:
        for what, attr, target in (("fit", "fit_ms", 3.0), (f"eval {args.eval:,} pts", "eval_ms", 5.0)):
            label = lambda z: f"n={SPEED_N} {k}{where(z)}: {what} ≥ {target:g}× faster than scipy"  # noqa: E731
            s = sp_of(SPEED_N, k)
            found = [z for z, _ in find(SPEED_N, k) if getattr(z, attr) is not None] if s else []
            if not found:
                bars.check(label(None), None, "not measured")
            for z in found:
                zm, sm = getattr(z, attr), getattr(s, attr)
                r = ratio(sm, zm)
                bars.check(label(z), r >= target,
                           f"{fmt_ms(sm)} / {fmt_ms(zm)} ms = {r:.1f}×")  # fmt: skip
    return bars


def main() -> None:
    args = parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    print(f"BLAS threads: {BLAS_NOTE}; load average {load_start}\n", flush=True)

    if args.skip_zeroset:
        print(f"--skip-zeroset: reusing the point files and {ZEROSET_CSV} in {out}", flush=True)
    else:
        run_zeroset(args)
    zs_rows = read_zeroset(out / ZEROSET_CSV)
    for n in args.ns:
        for k in args.kernel_list:
            if not any(r.n == n and r.kernel == k for r in zs_rows):
                print(f"warning: no zeroset row for n={n}, kernel {k} in {ZEROSET_CSV}", flush=True)
    load_after_cargo = common.loadavg()

    t0 = time.perf_counter()
    xe = read_points(out / f"rbf_eval_{args.eval}.csv", ["x", "y", "z"])
    if xe.shape[0] != args.eval:
        sys.exit(f"rbf_eval_{args.eval}.csv: {xe.shape[0]} points, expected {args.eval}")
    xe = np.ascontiguousarray(xe)
    sd = signed_distance(xe)
    band = np.abs(sd) < OFFSET
    n_band = int(np.count_nonzero(band))
    print(f"\n{args.eval:,} evaluation points, {n_band:,} in the band |sd| < {OFFSET} "
          f"(loaded in {time.perf_counter() - t0:.2f} s)", flush=True)  # fmt: skip

    sp_rows = []
    for n in args.ns:
        print(f"\n--- n={n} ---", flush=True)
        pts, vals = load_fit_points(out, n)
        for k in args.kernel_list:
            sp_rows.append(run_scipy(n, k, pts, vals, xe, band, sd[band], args))
    load_after_scipy = common.loadavg()

    pairs = paired(zs_rows, sp_rows)
    header, body = table(pairs, args)
    bars = check_bars(pairs, args)
    threads = ", ".join(sorted({z.threads for z in zs_rows if z.threads})) or "not reported by the example"
    print(f"\n=== RBF fit + eval of {args.eval:,} points: ratio = scipy_ms / zeroset_ms (> 1 means zeroset is "
          f"faster); max err = max |s − sd| over the {n_band:,} points with |sd| < {OFFSET} ===\n"
          f"{render_text(header, body, left=3, left_last=True)}")  # fmt: skip
    print(f"\n=== bars ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start),
         ("load average 1/5/15 min, after cargo", load_after_cargo),
         ("load average 1/5/15 min, after scipy", load_after_scipy)],
        [("BLAS threads (scipy side)", BLAS_NOTE), ("zeroset threads (from the example)", threads)],
    )  # fmt: skip

    with (out / "rbf_peers.csv").open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["n", "kernel", "scipy_kernel", "zeroset_solver", "zeroset_runs", "scipy_runs", "eval_points",
                     "band_points", "zeroset_fit_ms", "scipy_fit_ms", "ratio_fit", "zeroset_eval_ms",
                     "scipy_eval_ms", "ratio_eval", "zeroset_max_err_band", "scipy_max_err_band",
                     "zeroset_max_constraint_residual", "scipy_max_constraint_residual"])  # fmt: skip
        for n, k, z, s in pairs:
            g = lambda attr: None if z is None else getattr(z, attr)  # noqa: E731
            h = lambda attr: None if s is None else getattr(s, attr)  # noqa: E731
            wr.writerow([n, k, SCIPY_KERNEL.get(k, ""), g("solver") or "", common.num(g("runs")),
                         common.num(h("runs")), args.eval, n_band] + [common.num(v) for v in (
                g("fit_ms"), h("fit_ms"), ratio(h("fit_ms"), g("fit_ms")),
                g("eval_ms"), h("eval_ms"), ratio(h("eval_ms"), g("eval_ms")),
                g("max_err"), h("max_err"), g("residual"), h("residual"))])  # fmt: skip

    zs_source = (
        f"timings and errors read from an earlier run's `{ZEROSET_CSV}` (`--skip-zeroset`; only scipy was timed now)"
        if args.skip_zeroset
        else f"median of {args.repeat} runs after one warm-up"
    )
    report = [
        "## Peer comparison: RBF implicit-surface fit and evaluation (zeroset vs scipy RBFInterpolator)",
        "",
        f"`benches/peers/rbf_peers.py {' '.join(sys.argv[1:])}`: same points in the same run. Sphere centre "
        f"(0.5, 0.5, 0.5), radius {RADIUS}; N − 2⌊N/3⌋ on-surface points (value 0) and ⌊N/3⌋ each at ±{OFFSET} "
        f"along the normal (value ±{OFFSET}); {args.eval:,} evaluation points uniform in [0, 1]³, {n_band:,} of "
        f"them in the band |sd| < {OFFSET}. zeroset: `examples/rbf_timing.rs` ({zs_source}); zeroset threads: "
        f"{threads}. scipy: `RBFInterpolator(points, values, kernel=K, degree={DEGREE})` (dense LU, LAPACK "
        "dgesv) and its `__call__` at the evaluation points (kernel matrix built by single-threaded compiled "
        f"code, products by BLAS), median of {args.scipy_repeat} runs after one warm-up, a single run without "
        f"warm-up for N > {args.scipy_once_above}. Kernels: zeroset `r` (φ = r) vs scipy `linear` (φ = −r; with "
        "the degree-1 polynomial part the same interpolant) and `r3` vs `cubic` (φ = r³). Ratio = scipy_ms / "
        "zeroset_ms (> 1: zeroset faster). `max err` = max |s(x) − sd(x)| over the band, sd(x) = |x − c| − "
        f"{RADIUS}; `residual` = max |s(x_i) − v_i| over the fit points. scipy BLAS threads: {BLAS_NOTE}.",
        "",
        render_md(header, body, left=3),
        "",
        "### Bars",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "rbf_peers.md", out / "rbf_peers.csv", report, facts)


if __name__ == "__main__":
    main()
