#!/usr/bin/env python3
"""Peer comparison: scipy vs zeroset on the protrusion-removal least-squares system.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/restoration_peers.py [--k 16,24,32] [--repeat 5]

Steps:
  1. runs `cargo run --release --example restoration_solvers` (repo root), which times every
     zeroset solver and writes the matrices A, b, each zeroset solution x and a CSV into --out;
  2. loads the very same A and b and times scipy's lsqr, lsmr and the normal-equations solve
     spsolve(AᵀA, Aᵀb) (one warm-up, then the median of --repeat runs, the same rule as the
     Rust example: the upper median, sorted[n // 2]);
  3. prints per-k tables, a ratio table (scipy_ms / zeroset_ms, >1 means zeroset is faster) and
     writes OUT/peers.csv and OUT/report.md.
"""

from __future__ import annotations

import argparse
import csv
import math
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy
import scipy.io
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from common import (
    HERE,
    REPO,
    fmt_e,
    fmt_int,
    fmt_ms,
    fmt_ratio,
    loadavg,
    machine_facts,
    render_md,
    render_text,
    timed,
)

EXAMPLE = "restoration_solvers"
SCIPY_SOLVERS = ("lsqr", "lsmr", "spsolve")


@dataclass
class Row:
    """One solver's result for one k (zeroset or scipy)."""

    k: int
    source: str  # "zeroset" | "scipy"
    solver: str
    median_ms: float | None
    iterations: int | None
    rel_residual: float = math.nan
    rel_normal_residual: float = math.nan
    x: np.ndarray | None = None
    note: str = ""
    dx: dict[str, float] = field(default_factory=dict)  # vs scipy solver name
    ratio: dict[str, float] = field(default_factory=dict)  # scipy_ms / this_ms


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Time scipy on the same restoration least-squares matrices zeroset solves.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--k", default="16,24,32", help="comma-separated mask sizes (k³ unknowns)")
    p.add_argument("--repeat", type=int, default=5, help="timed runs after one warm-up")
    p.add_argument("--out", default=str(HERE / "out"), help="directory for mtx files, CSVs, report")
    p.add_argument(
        "--skip-spsolve-above",
        type=int,
        default=24,
        metavar="K",
        help="skip the normal-equations spsolve for k > K (about 24 s per solve at k=32); "
        "pass a large value to always run it",
    )
    p.add_argument(
        "--no-build",
        action="store_true",
        help="do not run the cargo example; reuse the mtx files and zeroset.csv already in --out",
    )
    p.add_argument(
        "--agree-tol",
        type=float,
        default=1e-6,
        help="a zeroset solver counts as agreeing when max|x − x_scipy_lsqr| <= tol·max(1, max|x_scipy_lsqr|); "
        "only agreeing solvers can be 'best'",
    )
    a = p.parse_args()
    try:
        a.ks = [int(s) for s in a.k.split(",") if s.strip()]
    except ValueError:
        p.error(f"--k: expected comma-separated integers, got {a.k!r}")
    if not a.ks or any(k < 1 for k in a.ks):
        p.error("--k: need at least one k >= 1")
    if a.repeat < 1:
        p.error("--repeat must be >= 1")
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: the Rust side


def run_cargo(ks: list[int], repeat: int, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    cmd = [
        "cargo", "run", "--release", "--example", EXAMPLE, "--",
        "--k", ",".join(map(str, ks)),
        "--repeat", str(repeat),
        "--write-mtx", str(out),
        "--csv", str(out / "zeroset.csv"),
    ]  # fmt: skip
    print(f"$ (cd {REPO} && {' '.join(cmd)})", flush=True)
    t = time.perf_counter()
    res = subprocess.run(cmd, cwd=REPO)
    if res.returncode != 0:
        sys.exit(f"cargo example failed with exit status {res.returncode}")
    print(f"(cargo step took {time.perf_counter() - t:.1f} s)\n", flush=True)


def read_zeroset_csv(path: Path, ks: list[int]) -> dict[int, list[Row]]:
    if not path.is_file():
        sys.exit(f"{path} not found: run without --no-build first")
    rows: dict[int, list[Row]] = {k: [] for k in ks}
    with path.open(newline="") as f:
        for r in csv.DictReader(f):
            k = int(r["k"])
            if k not in rows:
                continue
            rows[k].append(
                Row(
                    k=k,
                    source="zeroset",
                    solver=r["solver"],
                    median_ms=float(r["median_ms"]),
                    iterations=int(r["iterations"]),
                    # zeroset's own claims; replaced below by values recomputed here on the
                    # same A, b (same definitions), and flagged if they disagree
                    rel_residual=float(r["rel_residual"]),
                    rel_normal_residual=float(r["rel_normal_residual"]),
                )
            )
    missing = [k for k, v in rows.items() if not v]
    if missing:
        sys.exit(f"{path} has no rows for k={missing}: run without --no-build (or with those k)")
    return rows


# ---------------------------------------------------------------------------------------------
# Step 2: scipy


def load_problem(out: Path, k: int) -> tuple[sp.csr_array, np.ndarray]:
    fa, fb = out / f"restoration_k{k}_A.mtx", out / f"restoration_k{k}_b.mtx"
    for f in (fa, fb):
        if not f.is_file():
            sys.exit(f"{f} not found: run without --no-build (or with k={k})")
    a = sp.csr_array(scipy.io.mmread(fa))
    b = np.asarray(scipy.io.mmread(fb), dtype=np.float64).ravel()
    n = k**3
    if a.shape != (n + k * k, n) or b.shape != (a.shape[0],):
        sys.exit(f"k={k}: unexpected shapes A {a.shape}, b {b.shape}")
    return a, b


def load_vector(path: Path) -> np.ndarray | None:
    if not path.is_file():
        return None
    return np.asarray(scipy.io.mmread(path), dtype=np.float64).ravel()


def residuals(a, a_fro: float, x: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """zeroset's definitions (crates/field-core/src/lsq.rs):
    rel_residual = ‖b − Ax‖/‖b‖, rel_normal_residual = ‖Aᵀ(b − Ax)‖/(‖A‖_F‖b − Ax‖)."""
    r = b - a @ x
    rn = float(np.linalg.norm(r))
    bn = float(np.linalg.norm(b))
    rel = rn / bn if bn > 0 else rn
    nrm = float(np.linalg.norm(a.T @ r))
    rel_n = nrm / (a_fro * rn) if rn > 0 else nrm
    return rel, rel_n


def scipy_rows(k: int, a, b: np.ndarray, repeat: int, skip_spsolve_above: int) -> list[Row]:
    n = a.shape[1]
    rows = []

    def lsqr():
        return spla.lsqr(a, b, atol=1e-12, btol=1e-12, iter_lim=10 * n)

    res, ms, _ = timed(lsqr, repeat)
    x, istop, itn = res[0], res[1], res[2]
    rows.append(Row(k, "scipy", "lsqr", ms, int(itn), x=x, note=f"istop={istop}"))

    def lsmr():
        return spla.lsmr(a, b, atol=1e-12, btol=1e-12, maxiter=10 * n)

    res, ms, _ = timed(lsmr, repeat)
    x, istop, itn = res[0], res[1], res[2]
    rows.append(Row(k, "scipy", "lsmr", ms, int(itn), x=x, note=f"istop={istop}"))

    if k <= skip_spsolve_above:

        def normal():
            # forming AᵀA and Aᵀb is part of the timed solve
            ata = (a.T @ a).tocsc()
            return spla.spsolve(ata, a.T @ b)

        x, ms, _ = timed(normal, repeat)
        rows.append(Row(k, "scipy", "spsolve", ms, None, x=np.asarray(x).ravel(), note="AᵀA x = Aᵀb, SuperLU"))
    else:
        rows.append(
            Row(k, "scipy", "spsolve", None, None, note=f"skipped (k > --skip-spsolve-above {skip_spsolve_above})")
        )
    return rows


# ---------------------------------------------------------------------------------------------
# Step 3: tables


def results_table(rows: list[Row], best: str | None, agree_bad: set[str]):
    header = [
        "source", "solver", "median_ms", "iters", "rel_res", "rel_normal",
        "max|x−lsqr|", "max|x−lsmr|", "max|x−spsolve|", "note",
    ]  # fmt: skip
    body = []
    for r in rows:
        name = r.solver
        if r.source == "zeroset" and r.solver == best:
            name += " *"
        if r.solver in agree_bad and r.source == "zeroset":
            name += " !"
        body.append(
            [
                r.source,
                name,
                fmt_ms(r.median_ms),
                fmt_int(r.iterations),
                fmt_e(r.rel_residual),
                fmt_e(r.rel_normal_residual),
                *(fmt_e(r.dx.get(s)) for s in SCIPY_SOLVERS),
                r.note,
            ]
        )
    return header, body


def ratio_table(rows: list[Row], best: str | None):
    header = ["solver", "zeroset_ms", "vs scipy lsqr", "vs scipy lsmr", "vs scipy spsolve"]
    body = []
    for r in rows:
        if r.source != "zeroset":
            continue
        name = r.solver + (" *" if r.solver == best else "")
        body.append([name, fmt_ms(r.median_ms), *(fmt_ratio(r.ratio.get(s, math.nan)) for s in SCIPY_SOLVERS)])
    return header, body


# ---------------------------------------------------------------------------------------------


def main() -> None:
    args = parse_args()
    load_at_start = loadavg()
    out: Path = args.out
    if args.no_build:
        print(f"--no-build: reusing {out}\n")
    else:
        run_cargo(args.ks, args.repeat, out)
    zs = read_zeroset_csv(out / "zeroset.csv", args.ks)

    all_rows: list[Row] = []
    md_parts: list[str] = []
    summary: list[list[str]] = []
    warnings: list[str] = []

    for k in args.ks:
        t0 = time.perf_counter()
        a, b = load_problem(out, k)
        a_fro = float(np.sqrt(np.sum(a.data**2)))
        print(f"k={k}: A {a.shape[0]}×{a.shape[1]}, nnz {a.nnz} (loaded in {time.perf_counter() - t0:.2f} s); timing scipy …", flush=True)

        sc = scipy_rows(k, a, b, args.repeat, args.skip_spsolve_above)
        for r in sc:
            if r.x is not None:
                r.rel_residual, r.rel_normal_residual = residuals(a, a_fro, r.x, b)
        ref = {r.solver: r for r in sc}

        for r in zs[k]:
            path = out / f"restoration_k{k}_x_{r.solver}.mtx"
            r.x = load_vector(path)
            if r.x is None or r.x.shape != (a.shape[1],):
                warnings.append(f"k={k} {r.solver}: solution file {path.name} missing or wrong length")
                r.x = None
                r.note = "no solution file"
                continue
            claimed = (r.rel_residual, r.rel_normal_residual)
            r.rel_residual, r.rel_normal_residual = residuals(a, a_fro, r.x, b)
            # zeroset may estimate ‖A‖ differently; the plain residual must match closely
            if not math.isclose(claimed[0], r.rel_residual, rel_tol=1e-6, abs_tol=1e-14):
                warnings.append(
                    f"k={k} {r.solver}: zeroset reported rel_residual {claimed[0]:.6e}, recomputed here {r.rel_residual:.6e}"
                )

        rows = zs[k] + sc
        for r in rows:
            for s, ref_row in ref.items():
                if r.x is not None and ref_row.x is not None:
                    r.dx[s] = float(np.max(np.abs(r.x - ref_row.x)))
            if r.source == "zeroset" and r.median_ms:
                for s, ref_row in ref.items():
                    if ref_row.median_ms is not None:
                        r.ratio[s] = ref_row.median_ms / r.median_ms

        lsqr_x = ref["lsqr"].x
        scale = max(1.0, float(np.max(np.abs(lsqr_x))))
        agree_bad = {
            r.solver for r in zs[k] if r.x is None or r.dx.get("lsqr", math.inf) > args.agree_tol * scale
        }
        for s in sorted(agree_bad):
            warnings.append(
                f"k={k} {s}: max|x − x_scipy_lsqr| = {fmt_e(next(r for r in zs[k] if r.solver == s).dx.get('lsqr'))} "
                f"> {args.agree_tol:g}·{scale:g}; excluded from 'best'"
            )
        for r in sc:
            if r.x is not None and r.solver != "lsqr" and r.dx["lsqr"] > args.agree_tol * scale:
                warnings.append(f"k={k} scipy {r.solver}: max|x − x_scipy_lsqr| = {r.dx['lsqr']:.2e} (scipy solvers disagree)")
        candidates = [r for r in zs[k] if r.solver not in agree_bad]
        best = min(candidates, key=lambda r: r.median_ms) if candidates else None
        best_name = best.solver if best else None

        title = f"k={k}: A {a.shape[0]}×{a.shape[1]}, nnz {a.nnz}"
        h, body = results_table(rows, best_name, agree_bad)
        rh, rbody = ratio_table(rows, best_name)
        block = (
            f"\n=== {title} ===\n{render_text(h, body)}\n\n"
            f"ratio = scipy_ms / zeroset_ms (>1 means zeroset faster)\n{render_text(rh, rbody, left=1)}"
        )
        md_parts.append(f"### {title}\n\n{render_md(h, body)}\n\nratio = scipy_ms / zeroset_ms (>1 means zeroset faster)\n\n{render_md(rh, rbody, left=1)}")
        lq = ref["lsqr"]
        if best:
            summary.append(
                [
                    str(k),
                    best.solver,
                    fmt_ms(best.median_ms),
                    f"{fmt_ms(lq.median_ms)} ({lq.iterations} it)",
                    fmt_ratio(best.ratio.get("lsqr", math.nan)),
                    fmt_ratio(best.ratio.get("lsmr", math.nan)),
                    fmt_ratio(best.ratio.get("spsolve", math.nan)),
                ]
            )
            block += (
                f"\n\n>>> best zeroset solver at k={k}: {best.solver} {fmt_ms(best.median_ms)} ms = "
                f"{fmt_ratio(best.ratio.get('lsqr', math.nan))} vs scipy lsqr {fmt_ms(lq.median_ms)} ms"
            )
        else:
            summary.append([str(k), "— (none agrees)", "—", f"{fmt_ms(lq.median_ms)} ({lq.iterations} it)", "—", "—", "—"])
        all_rows += rows
        print(block, flush=True)

    sh = ["k", "best zeroset", "ms", "scipy lsqr ms", "vs lsqr", "vs lsmr", "vs spsolve"]
    print(f"\n=== summary: fastest agreeing zeroset solver per k ===\n{render_text(sh, summary)}")
    if warnings:
        print("\nwarnings:\n" + "\n".join("  " + w for w in warnings))

    facts = machine_facts(
        [
            ("load average 1/5/15 min, before cargo", load_at_start),
            ("load average 1/5/15 min, after scipy", loadavg()),
        ]
    )

    # peers.csv
    with (out / "peers.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            ["k", "source", "solver", "median_ms", "iterations", "rel_residual", "rel_normal_residual"]
            + [f"max_abs_dx_vs_scipy_{s}" for s in SCIPY_SOLVERS]
            + [f"ratio_scipy_{s}_over_zeroset" for s in SCIPY_SOLVERS]
            + ["note"]
        )
        for r in all_rows:
            num = lambda v: "" if v is None or (isinstance(v, float) and math.isnan(v)) else repr(v)  # noqa: E731
            w.writerow(
                [r.k, r.source, r.solver, num(r.median_ms), num(r.iterations), num(r.rel_residual), num(r.rel_normal_residual)]
                + [num(r.dx.get(s)) for s in SCIPY_SOLVERS]
                + [num(r.ratio.get(s)) for s in SCIPY_SOLVERS]
                + [r.note]
            )

    # report.md
    md = [
        "## Peer comparison: restoration least squares (zeroset vs scipy)",
        "",
        "Same matrices in the same run: `benches/peers/restoration_peers.py "
        + " ".join(sys.argv[1:])
        + "`. Times are the median of "
        + f"{args.repeat} runs after one warm-up. scipy: `lsqr`/`lsmr` with atol=btol=1e-12, iteration limit 10·n; "
        "`spsolve` = normal equations `spsolve((AᵀA).tocsc(), Aᵀb)` (SuperLU), forming AᵀA included. "
        "Residuals are recomputed here for every row on the same A, b: rel_res = ‖b−Ax‖/‖b‖, "
        "rel_normal = ‖Aᵀ(b−Ax)‖/(‖A‖_F‖b−Ax‖). Ratio = scipy_ms / zeroset_ms (>1 means zeroset faster). "
        f"`*` = fastest zeroset solver whose solution agrees with scipy lsqr (max abs diff ≤ {args.agree_tol:g}·max(1, max|x|)); "
        "`!` = does not agree."
        + (
            " **--no-build: the zeroset rows come from an earlier run's zeroset.csv, only scipy was timed now.**"
            if args.no_build
            else ""
        ),
        "",
        "### Summary",
        "",
        render_md(sh, summary),
        "",
        *("\n".join([p, ""]) for p in md_parts),
        "### Machine",
        "",
        render_md(["fact", "value"], [[k, v] for k, v in facts], left=2),
        "",
    ]
    if warnings:
        md += ["### Warnings", "", *(f"- {w}" for w in warnings), ""]
    (out / "report.md").write_text("\n".join(md))

    print("\nmachine: " + "; ".join(f"{k}={v}" for k, v in facts))
    print(f"\nwrote {out / 'peers.csv'} and {out / 'report.md'}")


if __name__ == "__main__":
    main()
