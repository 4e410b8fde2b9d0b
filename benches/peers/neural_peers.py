#!/usr/bin/env python3
"""Peer comparison: zeroset's neural curve fit vs the same model in PyTorch (CPU).

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh --torch
    benches/peers/.venv/bin/python benches/peers/neural_peers.py [--repeat 5] [--seeds 0,1,2,3,4]

The set-up is the "neural curve" line of PEERS.md (Jiang–Turk, paper 003 §4.2): the curve
r(t) = 0.6 + 0.15 cos 3t, 30 on-curve points (0), 15 inside at 0.5 r, 15 outside at 1.4 r (zeroset's
signs: −1 inside, +1 outside); an MLP 2 → 32 → 32 → 1 with tanh; the loss
Σ (f(x_i) − z_i)² + (λ |Ω| / P) Σ_j (f_xx² + 2 f_xy² + f_yy²)(y_j) with λ = 0.05, P = 250 auxiliary
points in Ω = [−1, 1]² (|Ω| = 4); Adam (lr 1e-2, β = (0.9, 0.999), ε = 1e-8) for 3000 full-batch
steps.

Threads: both sides are timed at one thread and at N threads (N = --mt-threads, default the CPUs
available; 0 or 1: one-thread runs only), and the report gives the ratios one thread each and each
side at its fastest (the configurations named). One timing rule for both sides: one warm-up
training, then the median of R (the upper median sorted[R // 2]).

  1. zeroset: `cargo build --release --example neural_curve` (CARGO_TARGET_DIR honoured;
     `--skip-build` reuses the binary), then, per seed, `neural_curve --only paper --seed S
     --export DIR --json DIR/zeroset.json`: it writes the constraints, the initial weights (Glorot
     uniform from the seed; PyTorch's `out × in` layout) and the auxiliary points (uniform in Ω
     from the seed, one fixed set) as .npy, trains, and reports the max constraint residual. For
     the timed seed (the first of --seeds) it runs with `--repeat R` twice, with
     RAYON_NUM_THREADS=1 and with RAYON_NUM_THREADS=N (set explicitly): one warm-up training, then
     the median of R; the JSON records `rayon::current_num_threads()`.
  2. PyTorch, on exactly those arrays (the same data, initial weights and auxiliary points — the
     same seed scheme): `nn.Sequential(Linear, Tanh, Linear, Tanh, Linear)` in float32
     (`--dtype`), the Hessian by double backward — the gradient g = ∂f/∂y with
     `torch.autograd.grad(f.sum(), y, create_graph=True)`, then one more
     `autograd.grad(g[:, k].sum(), y, create_graph=True)` per row (the fastest of the
     formulations tried: `is_grads_batched` and `torch.func.vmap(hessian)` were 1.2× and 3×
     slower here) — `loss.backward()`, `torch.optim.Adam`. Timed: one warm-up training, then the
     median of R (each a fresh model from the exported weights and a fresh optimiser). Only the
     training loop is timed (no imports, data loading or model set-up), on both sides. Two
     configurations:
       - one thread, in this process: OMP/MKL/OPENBLAS_NUM_THREADS=1 before torch is imported,
         then `torch.set_num_threads(1)` and `torch.set_num_interop_threads(1)`;
       - N threads, in a child process (the inter-op pool can be sized only once, before any
         parallel work, and OpenMP reads its variables at load): the variables at N,
         `torch.set_num_threads(N)`, `torch.set_num_interop_threads(N)` (PyTorch's own default
         on an N-CPU machine; eager autograd on the CPU runs in the calling thread, so the
         intra-op pool is the one that works).
     The counts `torch.get_num_threads()` / `torch.get_num_interop_threads()` report inside
     each configuration are recorded next to its timing. OMP_WAIT_POLICY is left as found and
     recorded: with the other cores busy, OpenMP's spin-waiting makes the N-thread run many
     times slower (seen on a 2-vCPU VM at load 3: 90 ms/step at 2 threads vs 3.2 at one;
     4.5 ms/step with OMP_WAIT_POLICY=PASSIVE).
  3. Prints and writes out/neural_peers.md / .csv: times, ms/step and the thread counts of every
     configuration, the ratios PyTorch ms ÷ zeroset ms (> 1: zeroset is faster) one thread each,
     each at its fastest and N threads each, the max constraint residual per seed on both sides —
     zeroset after Adam alone (the same model and arithmetic as PyTorch's) and after its
     least-squares refit of the output layer (`--refit-last-layer` in the CLI; dense QR, ~1 ms) —
     and the bars (PASS / FAIL, exit 0):
       - speed: PyTorch ms ÷ zeroset ms ≥ 5, each at its fastest (the bar), one thread each
         (reported beside it);
       - accuracy: zeroset's max constraint residual ≤ PyTorch's, on the timed seed and as the
         median over --seeds, for Adam alone and with the refit (PyTorch at one thread).

Why both: zeroset follows PyTorch in float64 step for step (the agreement bar: after
--agree-steps = 100 steps the residuals agree to ~1e-13), but from a few hundred steps on the
optimisation amplifies rounding — even between two float64 implementations that sum in another
order — until the 3000-step residual is a draw from the same distribution on both sides; against
PyTorch float32 either side wins on a given seed. The median over seeds is the fair comparison of
Adam alone; the refit lowers the data term for certain (and raises the curvature).

The machine is shared in CI-like set-ups: run it when nothing else runs, and look at the load
averages in the report.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import common
from common import fmt_ratio, ratio

# Before numpy and torch are imported: OMP/MKL/OPENBLAS_NUM_THREADS=1 in this process (the
# one-thread configuration); the N-thread child gets `--blas-threads N`, so N there.
BLAS_NOTE = common.pin_blas_threads(force=True)

EXAMPLE = "neural_curve"
LAMBDA = 0.05
DOMAIN_MEASURE = 4.0  # |Ω| of Ω = [−1, 1]²
LEARNING_RATE = 1e-2
BETAS = (0.9, 0.999)
EPS = 1e-8
BAR_SPEED = 5.0


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repeat", type=int, default=5, help="timed runs after one warm-up (default 5)")
    p.add_argument("--seeds", default="0,1,2,3,4,5,6,7,8,9",
                   help="seeds for the residual comparison; the first is timed (default 0 to 9)")
    p.add_argument("--steps", type=int, default=3000, help="Adam steps (default 3000)")
    p.add_argument("--dtype", choices=["float32", "float64"], default="float32",
                   help="PyTorch's precision for the bar (default float32, as in PEERS.md)")
    p.add_argument("--float64", action="store_true", help="also time PyTorch in float64 (informational)")
    p.add_argument("--agree-steps", type=int, default=100,
                   help="steps of the float64 agreement check (default 100; 0 skips it)")
    p.add_argument("--out", type=Path, default=common.HERE / "out")
    p.add_argument("--skip-build", action="store_true", help="reuse the built example")
    common.add_mt_arg(p, "PyTorch with set_num_threads(N) and set_num_interop_threads(N)")
    # Internal: the child that times PyTorch at N threads (N = --blas-threads, which common.run_child
    # passes and pin_blas_threads has already applied to the OMP/MKL/OpenBLAS variables).
    p.add_argument("--worker", metavar="JSON", type=Path, help=argparse.SUPPRESS)
    p.add_argument("--blas-threads", type=int, default=None, help=argparse.SUPPRESS)
    a = p.parse_args()
    a.seed_list = common.int_list(p, a.seeds, "--seeds", 0, "a seed")
    if not a.seed_list:
        p.error("--seeds: give at least one seed")
    if a.repeat < 1 or a.steps < 1:
        p.error("--repeat and --steps must be at least 1")
    if a.mt_threads < 0:
        p.error("--mt-threads must be >= 0")
    a.mt = a.mt_threads if a.mt_threads > 1 else 0  # 0: one-thread runs only
    a.dtypes = [a.dtype] + (["float64"] if a.float64 and a.dtype != "float64" else [])
    return a


def run_zeroset(binary: Path, d: Path, seed: int, steps: int, repeat: int | None, threads: int | None) -> dict:
    """One `neural_curve --only paper` run with RAYON_NUM_THREADS=threads; `repeat` None: no timing
    repeats (residual only, the environment's thread setting)."""
    result = d / "zeroset.json"
    result.unlink(missing_ok=True)
    cmd = [str(binary), "--only", "paper", "--seed", str(seed), "--steps", str(steps),
           "--export", str(d), "--json", str(result)]  # fmt: skip
    if repeat is not None:
        cmd += ["--repeat", str(repeat)]
    env = {"RAYON_NUM_THREADS": str(threads)} if threads else None
    common.run_logged(cmd, capture=True, env=env)
    if not result.is_file():
        sys.exit(f"{binary} wrote no {result}")
    z = json.loads(result.read_text())
    # `--repeat R`: the first training is the warm-up, `times_ms` holds the R timed ones.
    z["runs"] = len(z.get("times_ms", []))
    z["warmup"] = repeat is not None and repeat > 0
    return z


# ---------------------------------------------------------------------------------------------
# PyTorch


def import_torch(threads: int):
    """Imports torch and sets its intra-op and inter-op thread counts to `threads` (the inter-op
    pool can be sized only before any parallel work: call this first thing); returns the module."""
    try:
        import torch
    except ImportError:
        sys.exit("torch is not installed: run `bash benches/peers/setup.sh --torch`")
    torch.set_num_threads(threads)
    try:
        torch.set_num_interop_threads(threads)
    except RuntimeError as e:  # already started: the count is recorded as it is
        print(f"warning: torch.set_num_interop_threads({threads}): {e}", flush=True)
    return torch


def torch_threads(torch) -> dict:
    """The thread counts torch reports now, and its parallel back-end."""
    backend = "?"
    for line in torch.__config__.parallel_info().splitlines():
        if line.startswith("ATen parallel backend:"):
            backend = line.split(":", 1)[1].strip()
    return {"threads": torch.get_num_threads(), "interop": torch.get_num_interop_threads(), "backend": backend}


def load_case(d: Path, np):
    arrays = {name: np.load(d / f"{name}.npy") for name in ("points", "targets", "aux")}
    layers = []
    l = 0
    while (d / f"w{l}.npy").is_file():
        layers.append((np.load(d / f"w{l}.npy"), np.load(d / f"b{l}.npy")))
        l += 1
    return arrays, layers


def torch_trainer(torch, arrays, layers, dtype_name: str, steps: int):
    """A function that trains a fresh copy of the exported net and returns (seconds, net)."""
    dtype = getattr(torch, dtype_name)
    x = torch.tensor(arrays["points"], dtype=dtype)
    z = torch.tensor(arrays["targets"], dtype=dtype)
    aux = torch.tensor(arrays["aux"], dtype=dtype)
    p = aux.shape[0]
    weight = LAMBDA * DOMAIN_MEASURE / p

    def make():
        mods = []
        for i, (w, b) in enumerate(layers):
            lin = torch.nn.Linear(w.shape[1], w.shape[0]).to(dtype)
            with torch.no_grad():
                lin.weight.copy_(torch.tensor(w, dtype=dtype))
                lin.bias.copy_(torch.tensor(b, dtype=dtype))
            mods.append(lin)
            if i + 1 < len(layers):
                mods.append(torch.nn.Tanh())
        return torch.nn.Sequential(*mods)

    def train():
        net = make()
        opt = torch.optim.Adam(net.parameters(), lr=LEARNING_RATE, betas=BETAS, eps=EPS)
        t = time.perf_counter()
        for _ in range(steps):
            opt.zero_grad()
            y = aux.detach().requires_grad_(True)
            g = torch.autograd.grad(net(y).sum(), y, create_graph=True)[0]
            hx = torch.autograd.grad(g[:, 0].sum(), y, create_graph=True)[0]
            hy = torch.autograd.grad(g[:, 1].sum(), y, create_graph=True)[0]
            curvature = (hx[:, 0] ** 2 + 2 * hx[:, 1] ** 2 + hy[:, 1] ** 2).sum()
            data = ((net(x).squeeze(1) - z) ** 2).sum()
            loss = data + weight * curvature
            loss.backward()
            opt.step()
        return time.perf_counter() - t, net

    def residual(net) -> float:
        with torch.no_grad():
            return float((net(x).squeeze(1) - z).abs().max().to(torch.float64))

    return train, residual


def time_torch(torch, d: Path, dtype: str, steps: int, repeat: int, np) -> dict:
    """One warm-up training, then the upper median of `repeat` (common.timed's rule; only the
    training loop is timed, not building the model)."""
    arrays, layers = load_case(d, np)
    train, residual = torch_trainer(torch, arrays, layers, dtype, steps)
    _, net = train()  # warm-up
    times = []
    for _ in range(repeat):
        s, net = train()
        times.append(s * 1e3)
    ms = sorted(times)[len(times) // 2]
    return {"dtype": dtype, "ms": ms, "times_ms": times, "ms_per_step": ms / steps, "runs": repeat, "warmup": True,
            "max_residual": residual(net), **torch_threads(torch)}  # fmt: skip


def torch_residual(torch, d: Path, dtype: str, steps: int, np) -> float:
    arrays, layers = load_case(d, np)
    train, residual = torch_trainer(torch, arrays, layers, dtype, steps)
    _, net = train()
    return residual(net)


def worker_main(args) -> None:
    """`--worker JSON`: time PyTorch at --blas-threads threads on the timed seed's exported arrays
    (written by the parent) and write the results."""
    n = args.blas_threads or 1
    torch = import_torch(n)
    import numpy as np

    d = args.out / "neural" / f"seed{args.seed_list[0]}"
    print(f"  [child] torch {torch.__version__}: {torch_threads(torch)}", flush=True)
    rows = []
    for dtype in args.dtypes:
        r = time_torch(torch, d, dtype, args.steps, args.repeat, np)
        print(f"  [child] PyTorch {dtype}, {r['threads']} threads: {r['ms']:.1f} ms ({r['ms_per_step']:.3f} ms/step), "
              f"residual {r['max_residual']:.4f}", flush=True)  # fmt: skip
        rows.append(r)
    args.worker.write_text(json.dumps(rows))


def torch_child(args) -> list[dict]:
    """The PyTorch timings at N = args.mt threads, from a child process; [] if it failed."""
    out = args.out / f"neural_torch_t{args.mt}.json"
    out.unlink(missing_ok=True)
    argv = ["--worker", str(out), "--out", str(args.out), "--seeds", str(args.seed_list[0]),
            "--steps", str(args.steps), "--repeat", str(args.repeat), "--dtype", args.dtype]  # fmt: skip
    if args.float64:
        argv.append("--float64")
    rc = common.run_child(Path(__file__).resolve(), argv, args.mt)
    if rc != 0 or not out.is_file():
        print(f"warning: the PyTorch child at {args.mt} threads failed (exit {rc}); its rows are missing", flush=True)
        return []
    return json.loads(out.read_text())


# ---------------------------------------------------------------------------------------------
# Report


def how(r: dict | None) -> str:
    return "—" if r is None else common.how_timed(r.get("runs"), r.get("warmup"))


def zs_label(threads: int) -> str:
    return f"zeroset RAYON_NUM_THREADS={threads}"


def torch_label(threads: int, dtype: str) -> str:
    return f"PyTorch {dtype} set_num_threads({threads})"


def main() -> None:
    args = parse_args()
    out: Path = args.out
    if args.worker:
        worker_main(args)
        return
    torch = import_torch(1)  # the one-thread configuration, in this process
    import numpy as np

    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    t1_info = torch_threads(torch)
    print(f"torch {torch.__version__}: one-thread configuration {t1_info}; N-thread configuration: "
          f"{args.mt or 'not run'}; load average {load_start}\n", flush=True)  # fmt: skip
    binary = common.built_example(EXAMPLE, args.skip_build)

    timed_seed = args.seed_list[0]
    d0 = out / "neural" / f"seed{timed_seed}"
    d0.mkdir(parents=True, exist_ok=True)
    configs = "1 and " + str(args.mt) if args.mt else "1"
    print(f"\n--- timing, seed {timed_seed}: zeroset and PyTorch {', '.join(args.dtypes)} at {configs} thread(s) ---",
          flush=True)  # fmt: skip
    zs1 = run_zeroset(binary, d0, timed_seed, args.steps, args.repeat, 1)
    zsn = run_zeroset(binary, d0, timed_seed, args.steps, args.repeat, args.mt) if args.mt else None
    for z in (zs1, zsn):
        if z:
            print(f"  zeroset rayon {z['threads']}: {z['ms']:.1f} ms ({z['ms_per_step']:.3f} ms/step), "
                  f"residual {z['max_residual']:.4f}", flush=True)  # fmt: skip
    if zs1["threads"] != 1:
        print(f"warning: the RAYON_NUM_THREADS=1 run reports {zs1['threads']} threads", flush=True)
    if zsn and zsn["threads"] != args.mt:
        print(f"warning: the RAYON_NUM_THREADS={args.mt} run reports {zsn['threads']} threads", flush=True)
    load_after_zeroset = common.loadavg()

    th1 = {}  # dtype -> result, one thread
    for dtype in args.dtypes:
        print(f"  PyTorch {dtype}, 1 thread (warm-up + {args.repeat}) …", flush=True)
        th1[dtype] = time_torch(torch, d0, dtype, args.steps, args.repeat, np)
        r = th1[dtype]
        print(f"    {r['ms']:.1f} ms ({r['ms_per_step']:.3f} ms/step), residual {r['max_residual']:.4f}; "
              f"threads {r['threads']}, inter-op {r['interop']}", flush=True)  # fmt: skip
    thn = {}  # dtype -> result, N threads (child process)
    if args.mt:
        print(f"  PyTorch {', '.join(args.dtypes)}, {args.mt} threads, child process (warm-up + {args.repeat}) …",
              flush=True)  # fmt: skip
        thn = {r["dtype"]: r for r in torch_child(args)}
        for r in thn.values():
            if r["threads"] != args.mt:
                print(f"warning: PyTorch's {args.mt}-thread run reports {r['threads']} threads", flush=True)
    load_after_torch = common.loadavg()

    th = th1[args.dtype]
    seeds = [(timed_seed, zs1["max_residual"], zs1["refit_max_residual"], th["max_residual"])]
    for s in args.seed_list[1:]:
        d = out / "neural" / f"seed{s}"
        d.mkdir(parents=True, exist_ok=True)
        print(f"\n--- residuals, seed {s} ---", flush=True)
        zj = run_zeroset(binary, d, s, args.steps, None, None)
        t = torch_residual(torch, d, args.dtype, args.steps, np)
        print(f"  zeroset {zj['max_residual']:.4f} (refit {zj['refit_max_residual']:.4f}), PyTorch {t:.4f}",
              flush=True)  # fmt: skip
        seeds.append((s, zj["max_residual"], zj["refit_max_residual"], t))
    agree = None
    if args.agree_steps > 0:
        d = out / "neural" / f"agree_seed{timed_seed}"
        d.mkdir(parents=True, exist_ok=True)
        print(f"\n--- agreement: {args.agree_steps} steps in float64 on both sides, seed {timed_seed} ---", flush=True)
        zj = run_zeroset(binary, d, timed_seed, args.agree_steps, None, None)
        arrays, layers = load_case(d, np)
        train, residual = torch_trainer(torch, arrays, layers, "float64", args.agree_steps)
        _, net = train()
        agree = (zj["max_residual"], residual(net))
        print(f"  zeroset {agree[0]!r}, PyTorch float64 {agree[1]!r}", flush=True)
    load_end = common.loadavg()

    # --- the runs
    # (label, side, configuration, threads text, precision, result)
    runs = [(zs_label(1), "zeroset", "RAYON_NUM_THREADS=1", f"rayon {zs1['threads']}", "float64", zs1)]
    if zsn:
        runs.append((zs_label(args.mt), "zeroset", f"RAYON_NUM_THREADS={args.mt}", f"rayon {zsn['threads']}",
                     "float64", zsn))  # fmt: skip
    for dtype in args.dtypes:
        for n, r in ((1, th1.get(dtype)), (args.mt, thn.get(dtype))):
            if r is None or not n:
                continue
            where = "" if n == 1 else ", child process"
            runs.append((torch_label(n, dtype), "PyTorch", f"set_num_threads({n}){where}",
                         f"intra-op {r['threads']}, inter-op {r['interop']}", dtype, r))  # fmt: skip
    header = ["side", "configuration", "threads (reported)", "precision", "timed as", "median ms", "ms / step",
              "max residual"]  # fmt: skip
    body = [[side, conf, thr, prec, how(r), f"{r['ms']:.1f}", f"{r['ms_per_step']:.4f}", f"{r['max_residual']:.4f}"]
            for _, side, conf, thr, prec, r in runs]  # fmt: skip

    # --- the ratios, PyTorch ms ÷ zeroset ms, per PyTorch precision
    zs_runs = {zs_label(1): zs1["ms"], **({zs_label(args.mt): zsn["ms"]} if zsn else {})}
    zl, zm = common.fastest(zs_runs)
    ratio_rows = []  # (comparison, precision, PyTorch label, zeroset label, ratio)
    for dtype in args.dtypes:
        t1, tn = th1.get(dtype), thn.get(dtype)
        ratio_rows.append(("one thread each", dtype, torch_label(1, dtype), zs_label(1), ratio(t1["ms"], zs1["ms"])))
        t_runs = {torch_label(1, dtype): t1["ms"], **({torch_label(args.mt, dtype): tn["ms"]} if tn else {})}
        tl, tm = common.fastest(t_runs)
        ratio_rows.append(("each at its fastest", dtype, tl, zl, ratio(tm, zm)))
        if tn and zsn:
            ratio_rows.append((f"{args.mt} threads each", dtype, torch_label(args.mt, dtype), zs_label(args.mt),
                               ratio(tn["ms"], zsn["ms"])))  # fmt: skip
    ratio_header = ["comparison", "PyTorch precision", "PyTorch", "zeroset", "PyTorch ÷ zeroset"]
    ratio_body = [[c, p, a, b, fmt_ratio(v)] for c, p, a, b, v in ratio_rows]
    one = next(v for c, p, _, _, v in ratio_rows if c == "one thread each" and p == args.dtype)
    best_row = next(r for r in ratio_rows if r[0] == "each at its fastest" and r[1] == args.dtype)

    # --- the residuals per seed
    seed_header = ["seed", "zeroset (Adam)", "zeroset + refit", f"PyTorch {args.dtype}", "Adam ≤ PyTorch",
                   "refit ≤ PyTorch"]  # fmt: skip
    yes = lambda ok: "yes" if ok else "no"  # noqa: E731
    seed_body = [[str(s), f"{z:.4f}", f"{zr:.4f}", f"{t:.4f}", yes(z <= t), yes(zr <= t)] for s, z, zr, t in seeds]
    med_z = statistics.median(z for _, z, _, _ in seeds)
    med_zr = statistics.median(zr for _, _, zr, _ in seeds)
    med_t = statistics.median(t for _, _, _, t in seeds)
    seed_body.append(["median", f"{med_z:.4f}", f"{med_zr:.4f}", f"{med_t:.4f}", yes(med_z <= med_t),
                      yes(med_zr <= med_t)])  # fmt: skip

    # --- the bars
    bars = common.Bars()
    fast = best_row[4]
    t_best = next(r for lab, *_, r in runs if lab == best_row[2])
    z_best = next(r for lab, *_, r in runs if lab == best_row[3])
    bars.check(f"speed: PyTorch ({args.dtype}) ÷ zeroset ≥ {BAR_SPEED:g}, each at its fastest",
               None if math.isnan(fast) else fast >= BAR_SPEED,
               f"{fmt_ratio(fast)} ({best_row[2]}: {t_best['ms']:.0f} ms ÷ {best_row[3]}: "
               f"{z_best['ms']:.0f} ms)")  # fmt: skip
    bars.check(f"speed: PyTorch ({args.dtype}) ÷ zeroset ≥ {BAR_SPEED:g}, one thread each (reported)",
               None if math.isnan(one) else one >= BAR_SPEED,
               f"{fmt_ratio(one)} ({th['ms']:.0f} ms ÷ {zs1['ms']:.0f} ms)")  # fmt: skip
    s0 = seeds[0]
    bars.check("accuracy, Adam alone: zeroset max residual ≤ PyTorch's (timed seed)", s0[1] <= s0[3],
               f"{s0[1]:.4f} vs {s0[3]:.4f}")  # fmt: skip
    bars.check(f"accuracy, Adam alone: median over seeds {args.seeds}", med_z <= med_t, f"{med_z:.4f} vs {med_t:.4f}")
    bars.check("accuracy, with the refit: zeroset ≤ PyTorch (timed seed)", s0[2] <= s0[3],
               f"{s0[2]:.4f} vs {s0[3]:.4f}")  # fmt: skip
    bars.check(f"accuracy, with the refit: median over seeds {args.seeds}", med_zr <= med_t,
               f"{med_zr:.4f} vs {med_t:.4f}")  # fmt: skip
    if agree:
        bars.check(f"same model: |zeroset − PyTorch float64| max residual ≤ 1e-9 after {args.agree_steps} steps",
                   abs(agree[0] - agree[1]) <= 1e-9, f"{agree[0]:.15f} vs {agree[1]:.15f}")  # fmt: skip

    legend = ("ratio = PyTorch ms ÷ zeroset ms (> 1: zeroset is faster); one thread each = PyTorch "
              "set_num_threads(1) ÷ zeroset RAYON_NUM_THREADS=1; each at its fastest = PyTorch's faster "
              "configuration ÷ zeroset's faster one (named)")  # fmt: skip
    print(f"\n=== timings, seed {timed_seed} ===\n" + common.render_text(header, body, left=5))
    print(f"\n=== ratios ({legend}) ===\n" + common.render_text(ratio_header, ratio_body, left=4))
    print("\n=== max constraint residual per seed ===\n" + common.render_text(seed_header, seed_body, left=1))
    print("\n=== bars ===\n" + bars.text())

    csv_path = out / "neural_peers.csv"
    with csv_path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["kind", "label", "side", "threads", "interop_threads", "precision", "ms", "ms_per_step", "runs",
                    "warmup", "max_residual", "refit_max_residual", "ratio", "times_ms"])  # fmt: skip
        for label, side, _, _, prec, r in runs:
            w.writerow(["run", label, side, r["threads"], r.get("interop", ""), prec, common.num(r["ms"]),
                        common.num(r["ms_per_step"]), r["runs"], int(r["warmup"]), common.num(r["max_residual"]),
                        common.num(r.get("refit_max_residual")), "",
                        " ".join(f"{t:.3f}" for t in r["times_ms"])])  # fmt: skip
        for c, p, a, b, v in ratio_rows:
            w.writerow(["ratio", f"{c}: {a} ÷ {b}", "", "", "", p, "", "", "", "", "", "", common.num(v), ""])
        for s, z, zr, t in seeds:
            w.writerow(["seed", f"seed {s}", "zeroset", "", "", "float64", "", "", "", "", repr(z), repr(zr), "", ""])
            w.writerow(["seed", f"seed {s}", "PyTorch", 1, "", args.dtype, "", "", "", "", repr(t), "", "", ""])
    mt_text = "only (--mt-threads 0 or 1)"
    if args.mt:
        mt_text = (f"and at N = {args.mt} (zeroset RAYON_NUM_THREADS={args.mt}; PyTorch set_num_threads({args.mt}) "
                   f"and set_num_interop_threads({args.mt}) in a child process)")  # fmt: skip
    lines = [
        "## Neural curve: zeroset vs PyTorch (CPU)",
        "",
        f"`benches/peers/neural_peers.py {' '.join(sys.argv[1:])}`: {args.steps} Adam steps, P = 250, λ = 0.05, "
        "the same data, initial weights and auxiliary points on both sides; only the training loop timed, one "
        f"warm-up then the median of {args.repeat} (`timed as` per row). Both sides at one thread (zeroset "
        "RAYON_NUM_THREADS=1; PyTorch set_num_threads(1) and set_num_interop_threads(1), OMP/MKL/OpenBLAS "
        f"variables at 1) {mt_text}; the thread counts are as each side reports them "
        "(`rayon::current_num_threads()`, `torch.get_num_threads()` / `get_num_interop_threads()`). zeroset "
        f"trains in float64, PyTorch in {' and '.join(args.dtypes)}.",
        "",
        f"### Timings (seed {timed_seed})",
        "",
        common.render_md(header, body, left=5),
        "",
        f"### Ratios ({legend})",
        "",
        common.render_md(ratio_header, ratio_body, left=4),
        "",
        "### Max constraint residual per seed (PyTorch at one thread)",
        "",
        common.render_md(seed_header, seed_body, left=1),
        "",
        "### Bars",
        "",
        bars.md(),
        "",
    ]
    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start),
         ("load average 1/5/15 min, after zeroset's timing", load_after_zeroset),
         ("load average 1/5/15 min, after PyTorch's timing", load_after_torch),
         ("load average 1/5/15 min, at the end", load_end)],
        [("torch", torch.__version__),
         ("OMP/MKL/OpenBLAS variables (this process)", BLAS_NOTE),
         ("OMP_WAIT_POLICY (both PyTorch processes)", os.environ.get("OMP_WAIT_POLICY", "unset")),
         ("torch threads, one-thread configuration", f"intra-op {t1_info['threads']}, inter-op "
          f"{t1_info['interop']} (ATen parallel backend: {t1_info['backend']})"),
         ("torch threads, N-thread configuration (child)",
          "; ".join(f"{d}: intra-op {r['threads']}, inter-op {r['interop']}" for d, r in thn.items())
          or ("child failed" if args.mt else "not run")),
         ("zeroset threads (from the example's JSON)", ", ".join(f"rayon {z['threads']}" for z in (zs1, zsn) if z))],
    )  # fmt: skip
    common.write_report(out / "neural_peers.md", csv_path, lines, facts)


if __name__ == "__main__":
    main()
