#!/usr/bin/env python3
"""Peer comparison: zeroset's CP-ALS vs TensorLy's `parafac` (NumPy backend), same tensor, same start.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/python benches/peers/tensor_peers.py [--cases 30x10,60x20,100x30]
        [--tol 1e-10] [--max-iter 1000] [--repeat 5]

Threads: both sides are timed at one thread and at N threads (N = --mt-threads, default the CPUs
available), each set explicitly: TensorLy with BLAS pinned to one thread in this process and with
BLAS at N threads in a child process (OpenBLAS reads its thread count at import; the counts the
loaded OpenBLAS libraries report are recorded); zeroset with RAYON_NUM_THREADS=1 and
RAYON_NUM_THREADS=N (whatever the environment says). The report gives the ratios one thread each
and each side at its fastest.

Per case `NxR` (an N×N×N tensor, CP rank R; `NxR:NOISE` sets that case's noise level):

  1. a planted tensor X = Σ_r a_r ∘ b_r ∘ c_r, the factors i.i.d. standard normal from
     `numpy.random.default_rng([seed, N, R])`, plus Gaussian noise scaled so that
     ‖noise‖_F = NOISE · ‖X_planted‖_F; saved as DIR/x.npy (float64, C order);
  2. the initial factors, computed once here and shared by both sides: TensorLy's SVD
     initialisation `tensorly.decomposition._cp.initialize_cp(X, R, init='svd',
     svd='truncated_svd', random_state=seed)` (mode n: the R leading left singular vectors of the
     mode-n unfolding; mode 0 scaled by the singular values), saved as DIR/a0.npy, b0.npy, c0.npy
     (N×R, float64, C order). TensorLy gets them as `init=CPTensor((ones(R), [A0, B0, C0]))`;
     with all-one weights `initialize_cp` only copies them, so both sides start from the same
     point and the SVD is outside both timings;
  3. TensorLy: `parafac(X, R, init=…, tol=TOL, n_iter_max=MAX_ITER, linesearch=False,
     normalize_factors=False, return_errors=True)` — one warm-up, then the median of `--repeat`
     runs — with BLAS pinned to one thread (`--blas-threads`, default 1) and again, in a child
     process of this script, with BLAS at `--mt-threads` threads (default: the CPUs available;
     0 or 1 skips it). Recorded: iterations = len(errors), ms, ms per iteration, and
     the final relative error ‖X − X̂‖_F / ‖X‖_F computed exactly here (`tl.cp_to_tensor`);
  4. zeroset: `cargo build --release --example cp_timing` (`--skip-build` reuses the binary;
     `CARGO_TARGET_DIR` is honoured), then `cp_timing --input DIR --rank R --tol TOL --max-iter
     MAX_ITER --repeat REPEAT` twice, with RAYON_NUM_THREADS=1 and RAYON_NUM_THREADS=N (one
     warm-up, then the median of REPEAT, as TensorLy); each writes DIR/zeroset.json (`ms,
     times_ms, runs, warmup, iterations, rel_error, threads, converged`), kept as
     zeroset_t1.json / zeroset_tall.json. `--skip-zeroset` times TensorLy only;
  5. prints and writes OUT/tensor_peers.md and OUT/tensor_peers.csv: per case and side the
     iterations, ms, ms/iteration, final relative error, the ratios TensorLy ms ÷ zeroset ms and
     (ms/iteration) ÷ (ms/iteration), and the checks (PASS / FAIL / SKIP; exits 0 regardless).

TensorLy 0.10.0 `parafac` (tensorly/decomposition/_cp.py), as pinned in requirements.txt:

  * one iteration = one sweep over the modes 0, 1, 2 in order (Gauss-Seidel: each update uses
    the factors just updated). Mode n: V = ∗_{m≠n} F_mᵀF_m (Hadamard product of the Gram
    matrices; the weights are all ones), M = unfold(X, n) · khatri_rao(F_m, m≠n) (the MTTKRP with
    an explicitly formed Khatri-Rao product, one BLAS GEMM), F_n = solve(Vᵀ, Mᵀ)ᵀ
    (`numpy.linalg.solve`, LU with partial pivoting; no pseudo-inverse, no regularisation);
  * after each sweep, the "cheap" error: rel_err = sqrt(|‖X‖² + ‖X̂‖² − 2⟨X, X̂⟩|) / ‖X‖ with
    ‖X̂‖² = Σ (∗_m F_mᵀF_m) (`cp_norm`) and ⟨X, X̂⟩ = Σ M ∗ F_last from the last mode's MTTKRP;
    ‖X‖ is computed once per call (inside the timed call here). It is appended to `errors`;
  * stopping (`cvg_criterion='abs_rec_error'`): from the second iteration on (0-based iteration
    ≥ 1), stop when |errors[-2] − errors[-1]| < tol; otherwise after n_iter_max iterations. So
    len(errors) is the number of sweeps done (≥ 2 unless n_iter_max < 2), and "converged" here
    means the test fired (not merely len(errors) < n_iter_max);
  * `normalize_factors=False`: the factors are never rescaled, the weights stay ones.

Caveat, measured: at the default noise 1e-6 the cheap error's rounding resolution is about
ε / (2 · rel_err) ≈ 1e-10 — the size of the default tol. TensorLy's stopping test then fires when
two successive cheap errors round to the same value, not when the true decrease drops below tol,
so the iteration count at which either side stops is partly decided by rounding (it can differ
between BLAS thread counts, and between TensorLy and zeroset). The ms/iteration ratio is the
comparison that does not depend on it; the report shows both. `--tol 0` switches the test off
(TensorLy skips it when tol is falsy; zeroset's |Δ| < 0 never holds): both sides then do exactly
--max-iter iterations, a fixed-work comparison in which the final errors are directly comparable.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import common
from common import fmt_e, fmt_int, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402
import tensorly as tl  # noqa: E402
from tensorly.cp_tensor import CPTensor  # noqa: E402
from tensorly.decomposition import parafac  # noqa: E402
from tensorly.decomposition._cp import initialize_cp  # noqa: E402

EXAMPLE = "cp_timing"
FACTOR_FILES = ("a0.npy", "b0.npy", "c0.npy")
ZS_KEYS = ("ms", "times_ms", "iterations", "rel_error", "threads", "converged")
SPEED_BAR = 3.0  # TensorLy ms ÷ zeroset ms, for the BAR_CASES
BAR_CASES = ((30, 10), (60, 20))
ERR_RTOL, ERR_ATOL = 1e-6, 1e-12  # zeroset error ≤ TensorLy's · (1 + ERR_RTOL) + ERR_ATOL
NOISE_FACTOR = 10.0  # sanity: final error ≤ NOISE_FACTOR · noise


@dataclass
class Run:
    """One timed configuration of one side on one case."""

    side: str  # "TensorLy" or "zeroset"
    threads: str  # "BLAS 1", "BLAS 2", "rayon 1", "rayon 2", …
    ms: float = math.nan
    times: list[float] = field(default_factory=list)
    iterations: int | None = None
    rel_error: float = math.nan  # exact, at the end
    converged: bool | None = None
    cheap_error: float = math.nan  # TensorLy's last errors[] entry
    blas: str = ""  # TensorLy: the thread counts the loaded OpenBLAS libraries report
    runs: int | None = None  # timed runs
    warmup: bool | None = None  # whether one warm-up preceded them

    @property
    def ms_per_iter(self) -> float:
        return self.ms / self.iterations if self.iterations else math.nan


@dataclass
class Case:
    n: int
    rank: int
    noise: float
    dir: Path
    tl1: Run | None = None  # TensorLy, BLAS one thread (or as --blas-threads says)
    tlmt: Run | None = None  # TensorLy, BLAS --mt-threads
    zs1: Run | None = None  # zeroset, RAYON_NUM_THREADS=1
    zsmt: Run | None = None  # zeroset, all threads
    noise_actual: float = math.nan  # ‖noise‖ / ‖X_planted‖, as generated
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return f"{self.n}³ r{self.rank}"

    def runs(self) -> list[Run]:
        return [r for r in (self.tl1, self.tlmt, self.zs1, self.zsmt) if r is not None]


def parse_cases(p: argparse.ArgumentParser, value: str, noise: float) -> list[tuple[int, int, float]]:
    out = []
    for item in (x.strip() for x in value.split(",")):
        if not item:
            continue
        try:
            shape, _, nz = item.partition(":")
            n, r = (int(v) for v in shape.lower().split("x"))
            nz = float(nz) if nz else noise
        except ValueError:
            p.error(f"--cases: expected NxR or NxR:NOISE items (e.g. 30x10,60x20:1e-4), got {item!r}")
        if n < 2 or r < 1 or nz < 0:
            p.error(f"--cases: {item!r}: need N ≥ 2, R ≥ 1, NOISE ≥ 0")
        out.append((n, r, nz))
    if not out:
        p.error("--cases: nothing to do")
    return out


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Compare zeroset's CP-ALS with TensorLy's parafac on the same tensor and initial factors.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--cases", default="30x10,60x20,100x30",
                   help="NxR (N×N×N tensor, CP rank R) or NxR:NOISE, comma-separated")  # fmt: skip
    p.add_argument("--noise", type=float, default=1e-6, help="‖noise‖_F / ‖X‖_F for cases without :NOISE")
    p.add_argument("--seed", type=int, default=3,
                   help="data seed; case NxR uses numpy.random.default_rng([seed, N, R])")  # fmt: skip
    p.add_argument("--tol", type=float, default=1e-10,
                   help="stop when |Δ rel_err| < tol (both sides); 0 = no test, exactly --max-iter iterations")  # fmt: skip
    p.add_argument("--max-iter", type=int, default=1000, help="iteration limit (sweeps over the 3 modes)")
    p.add_argument("--repeat", type=int, default=5, help="timed runs per configuration (after one warm-up)")
    p.add_argument("--line-search", action="store_true",
                   help="both sides with their line search (TensorLy linesearch=True, zeroset --line-search)")
    common.add_mt_arg(p, "TensorLy with BLAS at N threads")
    p.add_argument("--mt-blas-threads", type=int, dest="mt_threads", default=argparse.SUPPRESS, metavar="N",
                   help="the same as --mt-threads (its former name)")  # fmt: skip
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the report; data in OUT/tensor/")
    p.add_argument("--keep-data", action="store_true", help="keep x.npy and the initial factors of each case")
    p.add_argument("--skip-zeroset", action="store_true", help="time TensorLy only (no cargo, no example)")
    p.add_argument("--skip-build", action="store_true", help="do not run cargo build; reuse the example binary")
    common.add_blas_arg(p)
    a = p.parse_args()
    a.case_list = parse_cases(p, a.cases, a.noise)
    for name in ("repeat", "max_iter"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if not a.tol >= 0:
        p.error("--tol must be >= 0 (0: no stopping test, exactly --max-iter iterations)")
    if a.mt_threads < 0:
        p.error("--mt-threads must be >= 0")
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Steps 1–2: data and initial factors


def make_case(n: int, rank: int, noise: float, seed: int, d: Path) -> float:
    """Writes x.npy and the SVD initial factors into d; returns the realised noise ratio."""
    rng = np.random.default_rng([seed, n, rank])
    a, b, c = (rng.standard_normal((n, rank)) for _ in range(3))
    x = np.einsum("ir,jr,kr->ijk", a, b, c, optimize=True)
    e = rng.standard_normal(x.shape)
    nx, ne = np.linalg.norm(x), np.linalg.norm(e)
    if noise > 0:
        e *= noise * nx / ne
        x += e
    init = initialize_cp(x, rank, init="svd", svd="truncated_svd", random_state=seed)
    np.save(d / "x.npy", np.ascontiguousarray(x, dtype=np.float64))
    for name, f in zip(FACTOR_FILES, init.factors):
        np.save(d / name, np.ascontiguousarray(f, dtype=np.float64))
    return float(np.linalg.norm(e) / nx) if noise > 0 else 0.0


def load_case(d: Path, rank: int) -> tuple[np.ndarray, list[np.ndarray]]:
    x = np.load(d / "x.npy")
    factors = [np.load(d / name) for name in FACTOR_FILES]
    for i, f in enumerate(factors):
        if f.shape != (x.shape[i], rank) or f.dtype != np.float64:
            sys.exit(f"{d / FACTOR_FILES[i]}: {f.dtype} {f.shape}, expected float64 {(x.shape[i], rank)}")
    return x, factors


# ---------------------------------------------------------------------------------------------
# Step 3: TensorLy


def time_tensorly(d: Path, rank: int, tol: float, max_iter: int, repeat: int, line_search: bool = False) -> dict:
    """Times parafac on DIR's tensor from DIR's factors (warm-up + median of `repeat`)."""
    x, factors = load_case(d, rank)
    init = CPTensor((np.ones(rank), factors))  # initialize_cp copies the factors; init is not modified

    def fit():
        return parafac(x, rank, n_iter_max=max_iter, init=init, tol=tol, linesearch=line_search,
                       normalize_factors=False, return_errors=True)  # fmt: skip

    (cp, errors), ms, times = common.timed(fit, repeat)
    errors = [float(e) for e in errors]
    rel = float(np.linalg.norm(x - tl.cp_to_tensor(cp)) / np.linalg.norm(x))
    converged = len(errors) >= 2 and abs(errors[-2] - errors[-1]) < tol
    return {"ms": ms, "times_ms": times, "iterations": len(errors), "rel_error": rel,
            "converged": converged, "cheap_error": errors[-1] if errors else math.nan,
            "blas": common.blas_runtime(), "runs": repeat, "warmup": True}  # fmt: skip


def tensorly_run(res: dict, threads: str) -> Run:
    return Run("TensorLy", threads, ms=res["ms"], times=res["times_ms"], iterations=res["iterations"],
               rel_error=res["rel_error"], converged=res["converged"], cheap_error=res["cheap_error"],
               blas=res.get("blas", "?"), runs=res.get("runs"), warmup=res.get("warmup"))  # fmt: skip


def tensorly_child(d: Path, case: Case, args, threads: int) -> Run | None:
    """time_tensorly in a child process with BLAS at `threads` threads (read at numpy import)."""
    out = d / f"tensorly_blas{threads}.json"
    out.unlink(missing_ok=True)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", str(d), "--worker-rank", str(case.rank),
           "--tol", repr(args.tol), "--max-iter", str(args.max_iter), "--repeat", str(args.repeat),
           "--blas-threads", str(threads)] + (["--line-search"] if args.line_search else [])  # fmt: skip
    res = subprocess.run(cmd, env=common.ORIGINAL_ENV)
    if res.returncode != 0 or not out.is_file():
        case.notes.append(f"TensorLy BLAS {threads}: child failed (exit {res.returncode})")
        return None
    return tensorly_run(json.loads(out.read_text()), f"BLAS {threads}")


def worker_main() -> None:
    """`--worker DIR`: time TensorLy on DIR and write DIR/tensorly_blas{N}.json (used by tensor_peers.py)."""
    p = argparse.ArgumentParser()
    p.add_argument("--worker", required=True)
    p.add_argument("--worker-rank", type=int, required=True)
    p.add_argument("--tol", type=float, required=True)
    p.add_argument("--max-iter", type=int, required=True)
    p.add_argument("--repeat", type=int, required=True)
    p.add_argument("--line-search", action="store_true")
    common.add_blas_arg(p)
    a = p.parse_args()
    d = Path(a.worker)
    res = time_tensorly(d, a.worker_rank, a.tol, a.max_iter, a.repeat, a.line_search)
    (d / f"tensorly_blas{a.blas_threads}.json").write_text(json.dumps(res))


# ---------------------------------------------------------------------------------------------
# Step 4: zeroset


def example_binary() -> Path:
    target = common.ORIGINAL_ENV.get("CARGO_TARGET_DIR")
    target_dir = (common.REPO / target) if target else common.REPO / "target"
    return target_dir / "release" / "examples" / EXAMPLE


def run_zeroset(binary: Path, case: Case, args, one_thread: bool) -> Run | None:
    d = case.dir
    result = d / "zeroset.json"
    result.unlink(missing_ok=True)  # no stale result from an earlier run
    common.run_logged(
        [str(binary), "--input", str(d), "--rank", str(case.rank), "--tol", repr(args.tol),
         "--max-iter", str(args.max_iter), "--repeat", str(args.repeat)]
        + (["--line-search"] if args.line_search else []),
        env={"RAYON_NUM_THREADS": "1" if one_thread else str(args.mt)},
    )  # fmt: skip
    if not result.is_file():
        case.notes.append(f"zeroset ({'1 thread' if one_thread else 'all threads'}): no zeroset.json")
        return None
    kept = d / ("zeroset_t1.json" if one_thread else "zeroset_tall.json")
    result.replace(kept)
    z = json.loads(kept.read_text())
    missing = [k for k in ZS_KEYS if k not in z]
    if missing:
        case.notes.append(f"{kept.name}: missing keys {missing}")
    threads = z.get("threads")
    if one_thread and threads not in (None, 1):
        case.notes.append(f"zeroset with RAYON_NUM_THREADS=1 reports threads={threads}")
    it = z.get("iterations")
    return Run("zeroset", f"rayon {threads if threads is not None else '?'}",
               ms=float(z.get("ms", math.nan)), times=[float(t) for t in z.get("times_ms", [])],
               iterations=None if it is None else int(it), rel_error=float(z.get("rel_error", math.nan)),
               converged=z.get("converged"), runs=z.get("runs"), warmup=z.get("warmup"))  # fmt: skip


# ---------------------------------------------------------------------------------------------
# Step 5: tables and checks


def ratio(a: float | None, b: float | None) -> float:
    if a is None or b is None or math.isnan(a) or math.isnan(b) or b <= 0:
        return math.nan
    return a / b


def fmt_err(v: float | None) -> str:
    """Relative errors with 7 significant digits: the error check works at the 1e-12 level."""
    return "—" if v is None or math.isnan(v) else f"{v:.6e}"


def fmt_bool(v: bool | None) -> str:
    return "—" if v is None else ("yes" if v else "no")


def slots(c: Case, mt: int) -> list[tuple[str, str, Run | None]]:
    """The four configurations, present or not (missing ones are shown as —)."""
    return [("TensorLy", BLAS_COL, c.tl1), ("TensorLy", f"BLAS {mt}", c.tlmt) if mt > 1 else None,
            ("zeroset", "rayon 1", c.zs1), ("zeroset", "rayon all", c.zsmt) if mt > 1 else None]  # fmt: skip


def fastest(*runs: Run | None) -> Run | None:
    """The run with the smallest median ms (None if there is none)."""
    ok = [r for r in runs if r is not None and not math.isnan(r.ms)]
    return min(ok, key=lambda r: r.ms) if ok else None


BLAS_COL = "BLAS 1"  # the label of the main TensorLy run; set in main() from --blas-threads


def results_table(cases: list[Case], mt: int):
    header = ["case", "side", "threads", "noise", "iterations", "converged", "ms", "ms / iter", "rel error (exact)",
              "TensorLy cheap err", "TensorLy ms ÷ ms", "note"]  # fmt: skip
    body = []
    for c in cases:
        first = True
        for slot in slots(c, mt):
            if slot is None:
                continue
            side, label, r = slot
            # like-for-like ratio: one-thread zeroset vs one-thread TensorLy, all vs all
            ref = c.tl1 if label in (BLAS_COL, "rayon 1") or c.tlmt is None else c.tlmt
            threads = r.threads if r is not None and side == "zeroset" else label
            if r is not None and side == "TensorLy" and r.blas:
                threads += f" ({r.blas})"
            note = "missing" if r is None else ""
            if first and c.notes:
                note = "; ".join([note] * bool(note) + c.notes)
            body.append([c.name if first else "", side, threads, f"{c.noise:g}" if first else "",
                         fmt_int(None if r is None else r.iterations),
                         fmt_bool(None if r is None else r.converged),
                         fmt_ms(None if r is None else r.ms), f"{r.ms_per_iter:.3f}" if r and r.iterations else "—",
                         fmt_err(None if r is None else r.rel_error),
                         fmt_err(r.cheap_error) if r is not None and side == "TensorLy" else "",
                         "" if side == "TensorLy" or r is None else fmt_ratio(ratio(ref.ms if ref else None, r.ms)),
                         note])  # fmt: skip
            first = False
    return header, body


def ratio_table(cases: list[Case], mt: int):
    """TensorLy ÷ zeroset, total time and time per iteration, like-for-like and mixed."""
    tl_mt = f"TL BLAS {mt}" if mt > 1 else None
    pairs = [(f"TL {BLAS_COL} ÷ zs 1", lambda c: (c.tl1, c.zs1)),
             (f"TL {BLAS_COL} ÷ zs all", lambda c: (c.tl1, c.zsmt))]
    if tl_mt:
        pairs.append((f"{tl_mt} ÷ zs all", lambda c: (c.tlmt, c.zsmt)))
    pairs.append(("each at its fastest", lambda c: (fastest(c.tl1, c.tlmt), fastest(c.zs1, c.zsmt))))
    header = ["case", "rank"] + [f"{n} (ms)" for n, _ in pairs] + [f"{n} (ms/iter)" for n, _ in pairs]
    body = []
    for c in cases:
        row = [c.name, str(c.rank)]
        for attr in ("ms", "ms_per_iter"):
            for _, get in pairs:
                a, b = get(c)
                row.append(fmt_ratio(ratio(getattr(a, attr) if a else None, getattr(b, attr) if b else None)))
        body.append(row)
    return header, body


def check_bars(cases: list[Case], mt: int) -> common.Bars:
    bars = common.Bars()
    for c in cases:
        if (c.n, c.rank) not in BAR_CASES:
            continue
        tl1, tlmt, zs1, zsmt = c.tl1, c.tlmt, c.zs1, c.zsmt
        # The bar: each side at its fastest thread setting (TensorLy is usually fastest on
        # one BLAS thread at these sizes; zeroset on all its threads).
        tl_best, zs_best = fastest(tl1, tlmt), fastest(zs1, zsmt)
        rb = ratio(tl_best.ms if tl_best else None, zs_best.ms if zs_best else None)
        which = f"TensorLy {tl_best.threads} ÷ zeroset {zs_best.threads}" if tl_best and zs_best else "—"
        bars.check(f"{c.name}: TensorLy ÷ zeroset ≥ {SPEED_BAR:g}, each at its fastest",
                   None if math.isnan(rb) else rb >= SPEED_BAR, f"{fmt_ratio(rb)} ({which})")  # fmt: skip
        r1 = ratio(tl1.ms if tl1 else None, zs1.ms if zs1 else None)
        bars.check(f"{c.name}: one thread each, TensorLy ({BLAS_COL}) ÷ zeroset (rayon 1) ≥ {SPEED_BAR:g} (reported)",
                   None if math.isnan(r1) else r1 >= SPEED_BAR, fmt_ratio(r1))  # fmt: skip
        ref_mt, label_mt = (tlmt, f"BLAS {mt}") if tlmt is not None else (tl1, BLAS_COL)
        rmt = ratio(ref_mt.ms if ref_mt else None, zsmt.ms if zsmt else None)
        if zsmt is not None:
            bars.check(f"{c.name}: TensorLy ({label_mt}) ÷ zeroset (all threads) ≥ {SPEED_BAR:g} (reported)",
                       None if math.isnan(rmt) else rmt >= SPEED_BAR, fmt_ratio(rmt))  # fmt: skip
        ri = ratio(tl1.ms_per_iter if tl1 else None, zs1.ms_per_iter if zs1 else None)
        bars.check(f"{c.name}: per iteration, TensorLy ({BLAS_COL}) ÷ zeroset (rayon 1) ≥ {SPEED_BAR:g} (informational)",
                   None if math.isnan(ri) else ri >= SPEED_BAR, fmt_ratio(ri))  # fmt: skip
        for zs, label in ((zs1, "rayon 1"), (zsmt, "all threads")):
            ok, detail = None, "zeroset missing"
            if tl1 is not None and zs is not None and not math.isnan(zs.rel_error):
                limit = tl1.rel_error * (1 + ERR_RTOL) + ERR_ATOL
                ok = zs.rel_error <= limit
                detail = f"{fmt_err(zs.rel_error)} vs TensorLy {fmt_err(tl1.rel_error)} (limit {limit:.6e})"
            bars.check(f"{c.name}: zeroset ({label}) final rel error ≤ TensorLy's ({BLAS_COL}) "
                       f"× (1 + {ERR_RTOL:g}) + {ERR_ATOL:g}", ok, detail)  # fmt: skip
    for c in cases:
        limit = NOISE_FACTOR * c.noise
        for r in c.runs():
            bars.check(f"{c.name}: {r.side} ({r.threads}) final rel error ≤ {NOISE_FACTOR:g} × noise "
                       "(informational)", None if math.isnan(r.rel_error) else r.rel_error <= limit,
                       f"{fmt_e(r.rel_error)} vs {limit:.1e}")  # fmt: skip
    return bars


def write_csv(path: Path, cases: list[Case], mt: int) -> None:
    with path.open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["n", "rank", "noise", "noise_actual", "seed_dir", "side", "threads", "iterations", "converged",
                     "ms", "ms_per_iter", "rel_error", "tensorly_cheap_error", "ratio_tensorly_ms_over_ms",
                     "ratio_tensorly_ms_per_iter_over_ms_per_iter", "ratio_each_fastest", "openblas_reported", "runs",
                     "warmup", "times_ms"])  # fmt: skip
        for c in cases:
            for slot in slots(c, mt):
                if slot is None or slot[2] is None:
                    continue
                side, label, r = slot
                ref = c.tl1 if label in (BLAS_COL, "rayon 1") or c.tlmt is None else c.tlmt
                rr = side == "zeroset" and ref is not None
                tb, zb = fastest(c.tl1, c.tlmt), fastest(c.zs1, c.zsmt)
                wr.writerow([c.n, c.rank, c.noise, common.num(c.noise_actual), c.dir.name, side, r.threads,
                             "" if r.iterations is None else r.iterations,
                             "" if r.converged is None else int(bool(r.converged))]
                            + [common.num(v) for v in (r.ms, r.ms_per_iter, r.rel_error,
                                                       r.cheap_error if side == "TensorLy" else None,
                                                       ratio(ref.ms, r.ms) if rr else None,
                                                       ratio(ref.ms_per_iter, r.ms_per_iter) if rr else None,
                                                       ratio(tb.ms if tb else None, zb.ms if zb else None))]
                            + [r.blas, common.num(r.runs), "" if r.warmup is None else int(bool(r.warmup))]
                            + [" ".join(f"{t:.3f}" for t in r.times)])  # fmt: skip


def main() -> None:
    global BLAS_COL
    args = parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    blas1 = os.environ.get("OPENBLAS_NUM_THREADS") or os.environ.get("OMP_NUM_THREADS")
    BLAS_COL = f"BLAS {blas1}" if blas1 else "BLAS default"
    mt = args.mt_threads if args.mt_threads > 1 else 1
    args.mt = mt
    load_start = common.loadavg()
    blas_rt = common.blas_runtime()
    print(f"BLAS threads: {BLAS_NOTE} ({blas_rt}); all-threads configuration: {mt if mt > 1 else 'not run'}; "
          f"TensorLy {tl.__version__} (backend {tl.get_backend()}); load average {load_start}\n", flush=True)  # fmt: skip

    binary = example_binary()
    if args.skip_zeroset:
        print("--skip-zeroset: timing TensorLy only", flush=True)
    elif args.skip_build:
        print(f"--skip-build: using {binary}", flush=True)
    else:
        common.run_logged(["cargo", "build", "--release", "--example", EXAMPLE])
    if not args.skip_zeroset and not binary.is_file():
        sys.exit(f"{binary} not found (cargo build failed, or CARGO_TARGET_DIR elsewhere?)")

    cases: list[Case] = []
    tl_s = 0.0
    for n, rank, noise in args.case_list:
        d = out / "tensor" / f"n{n}_r{rank}_noise{noise:g}_seed{args.seed}"
        if d.exists():
            shutil.rmtree(d)  # no stale arrays or results from an earlier run
        d.mkdir(parents=True)
        case = Case(n, rank, noise, d)
        print(f"\n--- {n}×{n}×{n}, rank {rank}, noise {noise:g}, seed {args.seed} ---", flush=True)
        case.noise_actual = make_case(n, rank, noise, args.seed, d)

        t0 = time.perf_counter()
        print(f"  TensorLy parafac, {BLAS_COL} (warm-up + {args.repeat}) …", flush=True)
        case.tl1 = tensorly_run(time_tensorly(d, rank, args.tol, args.max_iter, args.repeat, args.line_search),
                                BLAS_COL)  # fmt: skip
        print(f"    {case.tl1.iterations} iterations, {case.tl1.ms:.1f} ms ({case.tl1.ms_per_iter:.3f} ms/iter), "
              f"rel error {case.tl1.rel_error:.6e}, converged {fmt_bool(case.tl1.converged)}", flush=True)  # fmt: skip
        if mt > 1:
            print(f"  TensorLy parafac, BLAS {mt} (child process) …", flush=True)
            case.tlmt = tensorly_child(d, case, args, mt)
            if case.tlmt:
                print(f"    {case.tlmt.iterations} iterations, {case.tlmt.ms:.1f} ms, "
                      f"rel error {case.tlmt.rel_error:.6e}", flush=True)  # fmt: skip
        tl_s += time.perf_counter() - t0

        if not args.skip_zeroset:
            for one in (True, False) if mt > 1 else (True,):
                r = run_zeroset(binary, case, args, one)
                if r is not None:
                    print(f"  zeroset {r.threads}: {r.iterations} iterations, {r.ms:.1f} ms, "
                          f"rel error {r.rel_error:.6e}, converged {fmt_bool(r.converged)}", flush=True)  # fmt: skip
                if one:
                    case.zs1 = r
                else:
                    case.zsmt = r
        cases.append(case)
        if not args.keep_data:
            for name in ("x.npy", *FACTOR_FILES):
                (d / name).unlink(missing_ok=True)
    load_end = common.loadavg()

    rh, rb = results_table(cases, mt)
    qh, qb = ratio_table(cases, mt)
    bars = check_bars(cases, mt)
    zs_threads = ", ".join(sorted({r.threads for c in cases for r in (c.zs1, c.zsmt) if r})) or "not run"
    tl_blas = " | ".join(sorted({f"{r.threads}: {r.blas}" for c in cases for r in (c.tl1, c.tlmt) if r})) or "?"
    each = f"1 thread each or {mt} each" if mt > 1 else "1 thread each"
    print(f"\n=== results (ratio = like-for-like TensorLy ms ÷ zeroset ms, {each}; > 1: zeroset is faster) ===\n"
          f"{render_text(rh, rb, left=3, left_last=True)}")  # fmt: skip
    print(f"\n=== TensorLy ÷ zeroset ===\n{render_text(qh, qb, left=2)}")
    print(f"\n=== checks ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start), ("load average 1/5/15 min, at end", load_end)],
        [("tensorly", f"{tl.__version__} (backend {tl.get_backend()})"),
         ("BLAS threads (TensorLy side, one-thread run)", f"{BLAS_NOTE}; OpenBLAS reports {blas_rt}"),
         ("TensorLy multi-thread variant", f"BLAS {mt} threads (child process)" if mt > 1 else "not run"),
         ("TensorLy runs (OpenBLAS-reported threads)", tl_blas),
         ("zeroset threads (zeroset.json)", zs_threads), ("TensorLy side wall time", f"{tl_s:.1f} s")],
    )  # fmt: skip
    write_csv(out / "tensor_peers.csv", cases, mt)

    zs_text = (
        "not run (`--skip-zeroset`): its columns are marked — and its checks SKIP"
        if args.skip_zeroset
        else f"`examples/cp_timing.rs`, one warm-up then the median of {args.repeat} runs (its `--repeat`), with "
        f"RAYON_NUM_THREADS=1" + (f" and RAYON_NUM_THREADS={mt}" if mt > 1 else "") + f" (threads reported: {zs_threads})"
    )
    report = [
        "## Peer comparison: CP-ALS (zeroset vs TensorLy parafac)",
        "",
        f"`benches/peers/tensor_peers.py {' '.join(sys.argv[1:])}`: same tensor, same initial factors, same "
        f"stopping rule, in the same run. Per case: N×N×N tensor with a planted rank-R CP model (i.i.d. standard "
        f"normal factors, `default_rng([{args.seed}, N, R])`) plus Gaussian noise with ‖noise‖_F = noise · ‖X‖_F; "
        "initial factors = TensorLy's SVD initialisation (`initialize_cp(init='svd')`), computed once and given to "
        f"both sides. Stop when |Δ rel err| < {args.tol:g} (TensorLy's `abs_rec_error` test, from the second "
        f"iteration on) or after {args.max_iter} iterations (one iteration = one sweep over the three modes). "
        f"TensorLy {tl.__version__}: `parafac(…, linesearch={args.line_search}, normalize_factors=False, "
        "return_errors=True)`, "
        f"median of {args.repeat} runs after one warm-up, with BLAS pinned to one thread ({BLAS_NOTE})"
        + (f" and again, in a child process, with BLAS at {mt} threads" if mt > 1 else "")
        + f" (OpenBLAS reports: {tl_blas})"
        + f". zeroset: {zs_text}. `rel error (exact)` = ‖X − X̂‖_F / ‖X‖_F computed exactly at the end "
        "(TensorLy: here, from its factors; zeroset: by the example); `TensorLy cheap err` is the last value of "
        "TensorLy's own `errors` list (the inexpensive formula its stopping test uses). Ratios: TensorLy ms ÷ zeroset "
        "ms (> 1: zeroset is faster), like-for-like (1 BLAS thread vs 1 rayon thread, N vs N), mixed, and each at its "
        "fastest (the faster run of each side); the speed bar is judged each at its fastest. At noise "
        "1e-6 the cheap error's rounding resolution (≈ 1e-10) is the size of the default tol, so where each side "
        "stops is partly decided by rounding: compare ms / iteration as well.",
        "",
        "### Results",
        "",
        render_md(rh, rb, left=3),
        "",
        "### TensorLy ÷ zeroset",
        "",
        render_md(qh, qb, left=2),
        "",
        "### Checks",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "tensor_peers.md", out / "tensor_peers.csv", report, facts)


if __name__ == "__main__":
    if "--worker" in sys.argv:
        worker_main()
    else:
        main()
