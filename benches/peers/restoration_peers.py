#!/usr/bin/env python3
"""Peer comparison: scipy vs zeroset on the protrusion-removal least-squares system.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/restoration_peers.py [--k 16,24,32] [--repeat 5]

Threads: both sides are timed at one thread and at all threads (N = --mt-threads, default the
CPUs available), and the report gives the ratios one thread each and each side at its fastest.

Steps:
  1. `cargo build --release --example restoration_solvers` (CARGO_TARGET_DIR honoured;
     --skip-build reuses the binary), then `restoration_solvers --k … --repeat R --csv …` with
     RAYON_NUM_THREADS=1 (this run also writes the matrices A, b and each zeroset solution x:
     `--write-mtx OUT`) and again with RAYON_NUM_THREADS=N; results OUT/zeroset_t1.csv and
     OUT/zeroset_tall.csv. Every zeroset run builds its solver afresh (preconditioner, symbolic
     analysis) and solves: every cost counted; one warm-up, then the median of R. One more row,
     `sparse-cholesky-reused`, keeps the symbolic analysis between solves (the interactive
     re-solve; the analysis is not counted there, and the row is never "best");
  2. loads the very same A and b and times scipy's lsqr, lsmr and the normal-equations solve
     spsolve(AᵀA, Aᵀb) (one warm-up, then the median of --repeat runs, the same rule as the
     Rust example: the upper median, sorted[n // 2]) with BLAS pinned to one thread in this
     process, and again in a child process with BLAS at N threads (OpenBLAS reads its thread
     count at import; lsqr / lsmr use BLAS for their vector operations, spsolve's SuperLU for
     its dense kernels; scipy has no other thread setting for these);
  3. prints per-k tables, ratio tables (scipy_ms / zeroset_ms, >1 means zeroset is faster) one
     thread each and each side at its fastest, and writes OUT/peers.csv and OUT/report.md.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import common
from common import HERE, fmt_e, fmt_int, fmt_ms, fmt_ratio, loadavg, render_md, render_text, timed

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.io  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

EXAMPLE = "restoration_solvers"
SCIPY_SOLVERS = ("lsqr", "lsmr", "spsolve")
CONFIGS = ("1", "all")  # one thread each; all threads (N = --mt-threads)
ZS_CSV = {"1": "zeroset_t1.csv", "all": "zeroset_tall.csv"}


@dataclass
class Row:
    """One solver's result for one k at one thread configuration (zeroset or scipy)."""

    k: int
    source: str  # "zeroset" | "scipy"
    solver: str
    config: str  # "1" | "all"
    threads: str  # what ran: "rayon 1", "BLAS numpy 1, scipy 1", …
    median_ms: float | None
    iterations: int | None
    runs: int | None = None
    first_ms: float | None = None  # zeroset: the warm-up run (that solver's first solve)
    setup: str = "counted"  # zeroset: "counted" (solver built in each run) or "reused"
    rel_residual: float = math.nan
    rel_normal_residual: float = math.nan
    x: np.ndarray | None = None
    note: str = ""
    dx: dict[str, float] = field(default_factory=dict)  # vs scipy solver name (the BLAS-1 run)


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Time scipy on the same restoration least-squares matrices zeroset solves.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--k", default="16,24,32", help="comma-separated mask sizes (k³ unknowns)")
    p.add_argument("--repeat", type=int, default=5, help="timed runs after one warm-up (both sides)")
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
        help=f"do not run the cargo example; reuse the mtx files and {', '.join(ZS_CSV.values())} already in --out",
    )
    p.add_argument("--skip-build", action="store_true", help="do not run cargo build; reuse the example binary")
    p.add_argument(
        "--agree-tol",
        type=float,
        default=1e-6,
        help="a zeroset solver counts as agreeing when max|x − x_scipy_lsqr| <= tol·max(1, max|x_scipy_lsqr|); "
        "only agreeing solvers can be 'best'",
    )
    p.add_argument("--worker", metavar="JSON", help=argparse.SUPPRESS)  # child: time scipy, write JSON
    common.add_mt_arg(p, "scipy's BLAS at N threads")
    common.add_blas_arg(p)
    a = p.parse_args()
    a.ks = common.int_list(p, a.k, "--k", 1, "k")
    if not a.ks:
        p.error("--k: need at least one k >= 1")
    if a.repeat < 1:
        p.error("--repeat must be >= 1")
    if a.mt_threads < 0:
        p.error("--mt-threads must be >= 0")
    a.mt = a.mt_threads if a.mt_threads > 1 else 0  # 0: one-thread runs only
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: the Rust side


def run_zeroset(binary: Path, args, config: str) -> None:
    """`config` "1": RAYON_NUM_THREADS=1, writes the matrices and solutions; "all": =N."""
    args.out.mkdir(parents=True, exist_ok=True)
    csv_path = args.out / ZS_CSV[config]
    csv_path.unlink(missing_ok=True)
    cmd = [str(binary), "--k", ",".join(map(str, args.ks)), "--repeat", str(args.repeat), "--csv", str(csv_path)]
    if config == "1":
        cmd += ["--write-mtx", str(args.out)]
    common.run_logged(cmd, env={"RAYON_NUM_THREADS": "1" if config == "1" else str(args.mt)})


def read_zeroset_csv(path: Path, ks: list[int], config: str) -> dict[int, list[Row]]:
    if not path.is_file():
        sys.exit(f"{path} not found: run without --no-build first")
    rows: dict[int, list[Row]] = {k: [] for k in ks}

    def cell(r: dict, key: str, conv):
        v = (r.get(key) or "").strip()
        return conv(v) if v else None

    with path.open(newline="") as f:
        for r in csv.DictReader(f):
            k = int(r["k"])
            if k not in rows:
                continue
            threads = cell(r, "threads", str) or "?"
            if config == "1" and threads not in ("1", "?"):
                print(f"warning: the RAYON_NUM_THREADS=1 run reports threads={threads}", flush=True)
            rows[k].append(
                Row(
                    k=k,
                    source="zeroset",
                    solver=r["solver"],
                    config=config,
                    threads=f"rayon {threads}",
                    median_ms=float(r["median_ms"]),
                    iterations=int(r["iterations"]),
                    runs=cell(r, "runs", int),
                    first_ms=cell(r, "first_ms", float),
                    setup=cell(r, "setup", str) or "?",
                    # zeroset's own claims; replaced below (one-thread rows) by values recomputed
                    # here on the same A, b (same definitions), and flagged if they disagree
                    rel_residual=float(r["rel_residual"]),
                    rel_normal_residual=float(r["rel_normal_residual"]),
                    note="" if cell(r, "setup", str) != "reused" else "symbolic analysis reused (not counted)",
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


def scipy_rows(k: int, a, b: np.ndarray, args, config: str, threads: str) -> list[Row]:
    n = a.shape[1]
    a_fro = float(np.sqrt(np.sum(a.data**2)))
    rows = []

    def lsqr():
        return spla.lsqr(a, b, atol=1e-12, btol=1e-12, iter_lim=10 * n)

    res, ms, _ = timed(lsqr, args.repeat)
    rows.append(Row(k, "scipy", "lsqr", config, threads, ms, int(res[2]), args.repeat, x=res[0], note=f"istop={res[1]}"))

    def lsmr():
        return spla.lsmr(a, b, atol=1e-12, btol=1e-12, maxiter=10 * n)

    res, ms, _ = timed(lsmr, args.repeat)
    rows.append(Row(k, "scipy", "lsmr", config, threads, ms, int(res[2]), args.repeat, x=res[0], note=f"istop={res[1]}"))

    if k <= args.skip_spsolve_above:

        def normal():
            # forming AᵀA and Aᵀb is part of the timed solve
            ata = (a.T @ a).tocsc()
            return spla.spsolve(ata, a.T @ b)

        x, ms, _ = timed(normal, args.repeat)
        rows.append(Row(k, "scipy", "spsolve", config, threads, ms, None, args.repeat, x=np.asarray(x).ravel(),
                        note="AᵀA x = Aᵀb, SuperLU"))  # fmt: skip
    else:
        rows.append(Row(k, "scipy", "spsolve", config, threads, None, None,
                        note=f"skipped (k > --skip-spsolve-above {args.skip_spsolve_above})"))  # fmt: skip
    for r in rows:
        if r.x is not None:
            r.rel_residual, r.rel_normal_residual = residuals(a, a_fro, r.x, b)
    return rows


def scipy_all(args, config: str) -> dict[int, list[Row]]:
    """Every scipy solver on every k, with the BLAS threads this process started with."""
    threads = f"BLAS {common.blas_runtime()}"
    out = {}
    for k in args.ks:
        t0 = time.perf_counter()
        a, b = load_problem(args.out, k)
        print(f"k={k}: A {a.shape[0]}×{a.shape[1]}, nnz {a.nnz} (loaded in {time.perf_counter() - t0:.2f} s); "
              f"timing scipy ({threads}) …", flush=True)  # fmt: skip
        out[k] = scipy_rows(k, a, b, args, config, threads)
    return out


def worker_main(args) -> None:
    """`--worker JSON`: time scipy (BLAS threads as --blas-threads set them) and write the rows (no x)."""
    rows = [r for rs in scipy_all(args, "all").values() for r in rs]
    for r in rows:
        r.x = None
    Path(args.worker).write_text(json.dumps([{k: v for k, v in asdict(r).items() if k != "x"} for r in rows]))


def scipy_child(args, threads: int) -> dict[int, list[Row]]:
    out = args.out / f"restoration_peers_scipy_blas{threads}.json"
    out.unlink(missing_ok=True)
    argv = ["--worker", str(out), "--out", str(args.out), "--k", ",".join(map(str, args.ks)), "--repeat",
            str(args.repeat), "--skip-spsolve-above", str(args.skip_spsolve_above)]  # fmt: skip
    rc = common.run_child(Path(__file__).resolve(), argv, threads)
    if rc != 0 or not out.is_file():
        print(f"warning: the scipy child with BLAS {threads} failed (exit {rc}); its rows are missing", flush=True)
        return {}
    rows: dict[int, list[Row]] = {}
    for r in json.loads(out.read_text()):
        rows.setdefault(r["k"], []).append(Row(**r))
    return rows


# ---------------------------------------------------------------------------------------------
# Step 3: tables


def find(rows: list[Row], source: str, solver: str, config: str) -> Row | None:
    return next((r for r in rows if r.source == source and r.solver == solver and r.config == config), None)


def ms_of(r: Row | None) -> float | None:
    return None if r is None else r.median_ms


def ms_text(r: Row | None) -> str:
    if r is None:
        return "—"
    if r.median_ms is None:
        return "— (skipped)" if r.note.startswith("skipped") else "—"
    return fmt_ms(r.median_ms)


def compare(rows: list[Row], zs_solver: str, sc_solver: str) -> tuple[float, float, str]:
    """scipy ms ÷ zeroset ms: (one thread each, each at its fastest, which configurations)."""
    z = {c: find(rows, "zeroset", zs_solver, c) for c in CONFIGS}
    s = {c: find(rows, "scipy", sc_solver, c) for c in CONFIGS}
    one = common.ratio(ms_of(s["1"]), ms_of(z["1"]))
    zl, zm = common.fastest({(z[c].threads if z[c] else c): ms_of(z[c]) for c in CONFIGS})
    sl, sm = common.fastest({(s[c].threads if s[c] else c): ms_of(s[c]) for c in CONFIGS})
    fast = common.ratio(sm, zm)
    return one, fast, "—" if math.isnan(fast) else f"scipy {sl} ÷ zeroset {zl}"


def zs_fastest(rows: list[Row], solver: str) -> float:
    return common.fastest({c: ms_of(find(rows, "zeroset", solver, c)) for c in CONFIGS})[1]


def results_table(rows: list[Row], best: str | None, agree_bad: set[str]):
    header = ["source", "solver", "threads", "median_ms", "first_ms (1 run)", "iters", "rel_res", "rel_normal",
              "max|x−lsqr|", "max|x−lsmr|", "max|x−spsolve|", "note"]  # fmt: skip
    body = []
    for r in rows:
        name = r.solver
        if r.source == "zeroset" and r.solver == best:
            name += " *"
        if r.solver in agree_bad and r.source == "zeroset":
            name += " !"
        body.append([r.source, name, r.threads, ms_text(r), fmt_ms(r.first_ms), fmt_int(r.iterations),
                     fmt_e(r.rel_residual), fmt_e(r.rel_normal_residual), *(fmt_e(r.dx.get(s)) for s in SCIPY_SOLVERS),
                     r.note])  # fmt: skip
    return header, body


def ratio_table(rows: list[Row], best: str | None, mt: int):
    header = ["solver", "zeroset 1 thread ms", f"zeroset {mt or 'all'} threads ms"]
    for s in SCIPY_SOLVERS:
        header += [f"vs scipy {s}, 1 thread each", f"vs scipy {s}, each at its fastest"]
    body = []
    for solver in dict.fromkeys(r.solver for r in rows if r.source == "zeroset"):
        name = solver + (" *" if solver == best else "")
        row = [name, ms_text(find(rows, "zeroset", solver, "1")), ms_text(find(rows, "zeroset", solver, "all"))]
        for s in SCIPY_SOLVERS:
            one, fast, _ = compare(rows, solver, s)
            row += [fmt_ratio(one), fmt_ratio(fast)]
        body.append(row)
    return header, body


def scipy_table(rows: list[Row], mt: int):
    header = ["scipy solver", "BLAS 1 ms", f"BLAS {mt or 'N'} ms", "iters (BLAS 1)", "threads (OpenBLAS-reported)"]
    body = []
    for s in SCIPY_SOLVERS:
        r1, rn = find(rows, "scipy", s, "1"), find(rows, "scipy", s, "all")
        body.append([s, ms_text(r1), ms_text(rn), fmt_int(r1.iterations if r1 else None),
                     " | ".join(r.threads for r in (r1, rn) if r is not None)])  # fmt: skip
    return header, body


# ---------------------------------------------------------------------------------------------


def main() -> None:
    args = parse_args()
    if args.worker:
        worker_main(args)
        return
    load_at_start = loadavg()
    out: Path = args.out
    blas_rt = common.blas_runtime()
    print(f"BLAS threads: {BLAS_NOTE} ({blas_rt}); all-threads configuration: {args.mt or 'not run'}; "
          f"load average {load_at_start}\n", flush=True)  # fmt: skip
    configs = CONFIGS if args.mt else CONFIGS[:1]
    if args.no_build:
        print(f"--no-build: reusing {out}\n")
    else:
        binary = common.built_example(EXAMPLE, args.skip_build)
        for config in configs:
            run_zeroset(binary, args, config)
    zs = {c: read_zeroset_csv(out / ZS_CSV[c], args.ks, c) for c in configs if (out / ZS_CSV[c]).is_file()}
    if "1" not in zs:
        sys.exit(f"{out / ZS_CSV['1']} not found: run without --no-build first")
    load_after_cargo = loadavg()

    t0 = time.perf_counter()
    sc1 = scipy_all(args, "1")
    scn = scipy_child(args, args.mt) if args.mt else {}
    scipy_s = time.perf_counter() - t0
    load_after_scipy = loadavg()

    all_rows: list[Row] = []
    md_parts: list[str] = []
    text_parts: list[str] = []
    summary: list[list[str]] = []
    warnings: list[str] = []

    for k in args.ks:
        a, b = load_problem(out, k)
        a_fro = float(np.sqrt(np.sum(a.data**2)))
        ref = {r.solver: r for r in sc1[k]}

        for r in zs["1"][k]:
            path = out / f"restoration_k{k}_x_{r.solver}.mtx"
            r.x = load_vector(path)
            if r.x is None or r.x.shape != (a.shape[1],):
                warnings.append(f"k={k} {r.solver}: solution file {path.name} missing or wrong length")
                r.x = None
                r.note = "; ".join(filter(None, [r.note, "no solution file"]))
                continue
            claimed = (r.rel_residual, r.rel_normal_residual)
            r.rel_residual, r.rel_normal_residual = residuals(a, a_fro, r.x, b)
            # zeroset may estimate ‖A‖ differently; the plain residual must match closely
            if not math.isclose(claimed[0], r.rel_residual, rel_tol=1e-6, abs_tol=1e-14):
                warnings.append(
                    f"k={k} {r.solver}: zeroset reported rel_residual {claimed[0]:.6e}, recomputed here {r.rel_residual:.6e}"
                )
        for r in zs.get("all", {}).get(k, []):
            r.note = "; ".join(filter(None, [r.note, "residuals from the example"]))

        rows = zs["1"][k] + zs.get("all", {}).get(k, []) + sc1[k] + scn.get(k, [])
        for r in rows:
            for s, ref_row in ref.items():
                if r.x is not None and ref_row.x is not None:
                    r.dx[s] = float(np.max(np.abs(r.x - ref_row.x)))

        lsqr_x = ref["lsqr"].x
        scale = max(1.0, float(np.max(np.abs(lsqr_x))))
        agree_bad = {r.solver for r in zs["1"][k] if r.x is None or r.dx.get("lsqr", math.inf) > args.agree_tol * scale}
        for s in sorted(agree_bad):
            warnings.append(
                f"k={k} {s}: max|x − x_scipy_lsqr| = {fmt_e(next(r for r in zs['1'][k] if r.solver == s).dx.get('lsqr'))} "
                f"> {args.agree_tol:g}·{scale:g}; excluded from 'best'"
            )
        for r in sc1[k]:
            if r.x is not None and r.solver != "lsqr" and r.dx["lsqr"] > args.agree_tol * scale:
                warnings.append(f"k={k} scipy {r.solver}: max|x − x_scipy_lsqr| = {r.dx['lsqr']:.2e} (scipy solvers disagree)")
        # Best: agreeing, every cost counted (not the re-solve with a reused analysis), by its faster configuration.
        candidates = [r.solver for r in zs["1"][k] if r.solver not in agree_bad and r.setup != "reused"]
        best = min(candidates, key=lambda s: zs_fastest(rows, s)) if candidates else None

        title = f"k={k}: A {a.shape[0]}×{a.shape[1]}, nnz {a.nnz}"
        h, body = results_table(rows, best, agree_bad)
        rh, rbody = ratio_table(rows, best, args.mt)
        sh_, sbody_ = scipy_table(rows, args.mt)
        legend = ("ratio = scipy_ms / zeroset_ms (>1 means zeroset faster); 1 thread each = scipy BLAS 1 ÷ zeroset "
                  "RAYON_NUM_THREADS=1; each at its fastest = the faster configuration of each side")  # fmt: skip
        block = (f"\n=== {title} ===\n{render_text(h, body, left=3, left_last=True)}\n\n"
                 f"{render_text(sh_, sbody_, left=1, left_last=True)}\n\n{legend}\n{render_text(rh, rbody, left=1)}")  # fmt: skip
        md_parts.append(f"### {title}\n\n{render_md(h, body, left=3)}\n\n{render_md(sh_, sbody_, left=1)}\n\n"
                        f"{legend}\n\n{render_md(rh, rbody, left=1)}")  # fmt: skip
        lq1, lqn = find(rows, "scipy", "lsqr", "1"), find(rows, "scipy", "lsqr", "all")
        if best:
            one, fast, which = compare(rows, best, "lsqr")
            summary.append([str(k), best, ms_text(find(rows, "zeroset", best, "1")),
                            ms_text(find(rows, "zeroset", best, "all")),
                            f"{ms_text(lq1)} ({lq1.iterations} it)", ms_text(lqn), fmt_ratio(one), fmt_ratio(fast),
                            fmt_ratio(compare(rows, best, "lsmr")[1]), fmt_ratio(compare(rows, best, "spsolve")[1]),
                            which])  # fmt: skip
            block += f"\n\n>>> best zeroset solver at k={k}: {best}; vs scipy lsqr {fmt_ratio(one)} one thread each, " \
                     f"{fmt_ratio(fast)} each at its fastest ({which})"  # fmt: skip
        else:
            summary.append([str(k), "— (none agrees)", "—", "—", f"{ms_text(lq1)} ({lq1.iterations} it)", ms_text(lqn),
                            "—", "—", "—", "—", "—"])  # fmt: skip
        all_rows += rows
        text_parts.append(block)
        print(block, flush=True)

    sh = ["k", "best zeroset", "zeroset 1 thread ms", f"zeroset {args.mt or 'all'} threads ms", "scipy lsqr BLAS 1 ms",
          f"scipy lsqr BLAS {args.mt or 'N'} ms", "vs lsqr, 1 thread each", "vs lsqr, each at its fastest",
          "vs lsmr, each at its fastest", "vs spsolve, each at its fastest", "fastest configurations (lsqr)"]  # fmt: skip
    print(f"\n=== summary: fastest agreeing zeroset solver per k (every cost counted) ===\n"
          f"{render_text(sh, summary, left=2, left_last=True)}")  # fmt: skip
    if warnings:
        print("\nwarnings:\n" + "\n".join("  " + w for w in warnings))

    zs_threads = sorted({r.threads for r in all_rows if r.source == "zeroset"})
    sc_threads = sorted({r.threads for r in all_rows if r.source == "scipy"})
    facts = common.machine_facts(
        [("load average 1/5/15 min, before cargo", load_at_start),
         ("load average 1/5/15 min, after cargo", load_after_cargo),
         ("load average 1/5/15 min, after scipy", load_after_scipy)],
        [("BLAS threads (scipy, one-thread run)", f"{BLAS_NOTE}; OpenBLAS reports {blas_rt}"),
         ("scipy configurations (OpenBLAS-reported threads)", " | ".join(sc_threads) or "not run"),
         ("zeroset configurations (from the example's CSV)", ", ".join(zs_threads) or "not run"),
         ("scipy side wall time", f"{scipy_s:.1f} s")],
    )  # fmt: skip

    with (out / "peers.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["k", "source", "solver", "config", "threads", "median_ms", "runs", "first_ms", "setup",
                    "iterations", "rel_residual", "rel_normal_residual"]
                   + [f"max_abs_dx_vs_scipy_{s}" for s in SCIPY_SOLVERS]
                   + [f"ratio_scipy_{s}_over_zeroset_one_thread_each" for s in SCIPY_SOLVERS]
                   + [f"ratio_scipy_{s}_over_zeroset_each_fastest" for s in SCIPY_SOLVERS] + ["note"])  # fmt: skip
        num = common.num
        for r in all_rows:
            rows_k = [x for x in all_rows if x.k == r.k]
            cmp = {s: compare(rows_k, r.solver, s) for s in SCIPY_SOLVERS} if r.source == "zeroset" else {}
            w.writerow([r.k, r.source, r.solver, r.config, r.threads, num(r.median_ms), num(r.runs), num(r.first_ms),
                        r.setup if r.source == "zeroset" else "", num(r.iterations), num(r.rel_residual),
                        num(r.rel_normal_residual)]
                       + [num(r.dx.get(s)) for s in SCIPY_SOLVERS]
                       + [num(cmp[s][0]) if cmp else "" for s in SCIPY_SOLVERS]
                       + [num(cmp[s][1]) if cmp else "" for s in SCIPY_SOLVERS] + [r.note])  # fmt: skip

    md = [
        "## Peer comparison: restoration least squares (zeroset vs scipy)",
        "",
        "Same matrices in the same run: `benches/peers/restoration_peers.py " + " ".join(sys.argv[1:]) + "`. Each side "
        f"at one thread and at {args.mt or '—'} threads; one warm-up, then the median of {args.repeat} runs on both "
        "sides.",
        "",
        "**zeroset**: `examples/restoration_solvers.rs` with RAYON_NUM_THREADS=1 and RAYON_NUM_THREADS="
        f"{args.mt or '—'} (threads reported: {', '.join(zs_threads) or '—'}); each run builds its solver afresh "
        "(the Poisson preconditioner of `lsqr-poisson`, the symbolic analysis of `sparse-cholesky`) and solves "
        "from the matrix and the right-hand side: every cost counted. `first_ms` = the warm-up run alone (1 run: "
        "that solver's first solve). `sparse-cholesky-reused` keeps its symbolic analysis between runs (the "
        "interactive re-solve; the analysis is **not** counted) and is never `*`.",
        "",
        "**scipy** " + scipy.__version__ + ": `lsqr`/`lsmr` with atol=btol=1e-12, iteration limit 10·n; `spsolve` = "
        "normal equations `spsolve((AᵀA).tocsc(), Aᵀb)` (SuperLU), forming AᵀA included; with BLAS pinned to one "
        f"thread ({BLAS_NOTE}; OpenBLAS reports {blas_rt}) and again in a child process with BLAS at "
        f"{args.mt or '—'} threads ({' | '.join(sc_threads) or '—'}); scipy has no other thread setting for these "
        f"solvers. `spsolve` is skipped for k > {args.skip_spsolve_above} (marked \"— (skipped)\"). Loading A and b "
        "is outside both sides.",
        "",
        "Residuals are recomputed here for the one-thread zeroset rows and every scipy row on the same A, b: "
        "rel_res = ‖b−Ax‖/‖b‖, rel_normal = ‖Aᵀ(b−Ax)‖/(‖A‖_F‖b−Ax‖) (the all-threads zeroset rows: the example's "
        "own figures). Ratio = scipy_ms / zeroset_ms (>1 means zeroset faster): *1 thread each* (scipy BLAS 1 ÷ "
        "zeroset RAYON_NUM_THREADS=1) and *each at its fastest* (the faster configuration of each side). "
        f"`*` = fastest zeroset solver (at its faster configuration) whose solution agrees with scipy lsqr (max abs "
        f"diff ≤ {args.agree_tol:g}·max(1, max|x|)); `!` = does not agree."
        + (" **--no-build: the zeroset rows come from an earlier run's CSVs, only scipy was timed now.**"
           if args.no_build else ""),  # fmt: skip
        "",
        "### Summary",
        "",
        render_md(sh, summary),
        "",
        *("\n".join([p, ""]) for p in md_parts),
    ]
    if warnings:
        md += ["### Warnings", "", *(f"- {w}" for w in warnings), ""]
    common.write_report(out / "report.md", out / "peers.csv", md, facts)


if __name__ == "__main__":
    main()
