"""Helpers shared by the hand-run peer scripts in benches/peers (not run by CI).

Deliberately imports neither numpy nor scipy at module level, so that a script can call
`pin_blas_threads()` before its own `import numpy` (OpenBLAS reads its thread count once, at
load time).
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent  # benches/peers -> repo root
THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "RAYON_NUM_THREADS",
)
BLAS_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

# The environment as the script found it; cargo runs with this one, not with the BLAS pin.
ORIGINAL_ENV = dict(os.environ)


# ---------------------------------------------------------------------------------------------
# BLAS threads


def add_blas_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--blas-threads",
        type=int,
        default=None,
        metavar="N",
        help="set OMP/OPENBLAS/MKL_NUM_THREADS=N for the scipy side (not for cargo); 0 = leave the "
        "environment as it is; default: 1 (scripts with --mt-threads: always; the others: unless those "
        "variables are already set)",
    )


def pin_blas_threads(force: bool = False) -> str:
    """Reads --blas-threads from sys.argv and sets the BLAS thread variables accordingly.

    Must run before numpy is imported. Without --blas-threads the variables are set to 1 unless
    they are already set — or, with `force`, always (the one-thread configuration of the scripts
    that also time a multi-thread one, see `add_mt_arg`). Returns a one-line description for the
    report."""
    p = argparse.ArgumentParser(add_help=False)
    add_blas_arg(p)
    n = p.parse_known_args()[0].blas_threads
    if n == 0:
        return "left as found (--blas-threads 0)"
    if n is None:
        if not force and any(v in os.environ for v in BLAS_VARS):
            return "left as found (already set in the environment)"
        if force:
            for v in BLAS_VARS:
                os.environ[v] = "1"
            return "set to 1 for the Python side"
        n = 1
    for v in BLAS_VARS:
        os.environ[v] = str(n)
    return f"set to {n} for the scipy side (--blas-threads)"


def cpu_count() -> int:
    """The CPUs this process may run on (the affinity mask), else `os.cpu_count()`."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def add_mt_arg(p: argparse.ArgumentParser, peer: str | None) -> None:
    """`--mt-threads N`: the "all threads" configuration of both sides (default: every CPU);
    `peer` says what it sets on the Python side (None: nothing, the peer has no thread setting)."""
    side = f" and {peer} (in a child process: OpenBLAS reads its thread count at import)" if peer else ""
    p.add_argument(
        "--mt-threads",
        type=int,
        default=cpu_count(),
        metavar="N",
        help=f"the all-threads configuration: zeroset with RAYON_NUM_THREADS=N{side}; 0 or 1 = one-thread runs only",
    )


def blas_runtime() -> str:
    """The thread counts the loaded OpenBLAS libraries report now (numpy's and scipy's wheels
    each bundle one), e.g. "numpy 1, scipy 1"; "?" where it cannot be read. Imports numpy and
    scipy.linalg: call it after `pin_blas_threads`."""
    import ctypes
    import glob

    import numpy
    import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS)

    site = Path(numpy.__file__).resolve().parent.parent
    found = []
    for pkg in ("numpy", "scipy"):
        count = "?"
        for f in sorted(glob.glob(str(site / f"{pkg}.libs" / "*openblas*"))):
            try:
                lib = ctypes.CDLL(f)
            except OSError:
                continue
            for sym in ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads",
                        "openblas_get_num_threads64_", "openblas_get_num_threads"):  # fmt: skip
                fn = getattr(lib, sym, None)
                if fn is not None:
                    count = str(fn())
                    break
        found.append(f"{pkg} {count}")
    return ", ".join(found)


def run_child(script: Path, argv: list[str], blas_threads: int) -> int:
    """Runs `script argv --blas-threads N` with this interpreter and the original environment
    (so the child's OpenBLAS starts with N threads); returns its exit status."""
    cmd = [sys.executable, str(script), *argv, "--blas-threads", str(blas_threads)]
    print(f"$ {' '.join(cmd)}", flush=True)
    return subprocess.run(cmd, env=ORIGINAL_ENV).returncode


def how_timed(runs: int | None, warmup: bool | None) -> str:
    """The timing rule a number was measured under, for the note next to it."""
    if runs is None:
        return "?"
    if warmup is False:
        return "1 run, no warm-up" if runs == 1 else f"median of {runs}, no warm-up"
    return f"warm-up + median of {runs}"


def with_how(ms, runs: int | None, warmup: bool | None, repeat: int | None = None) -> str:
    """`fmt_ms(ms)`, followed by "(1 run, no warm-up)" or "(median of R)" where the run count
    differs from the default `repeat` or no warm-up preceded it."""
    text = fmt_ms(ms)
    if text == "—" or runs is None:
        return text
    if warmup is False:
        return f"{text} ({how_timed(runs, warmup)})"
    if repeat is not None and runs != repeat:
        return f"{text} ({runs} runs)"
    return text


def int_list(p: argparse.ArgumentParser, value: str, flag: str, minimum: int, name: str = "n") -> list[int]:
    """A comma-separated list of integers for `flag`, each at least `minimum` (`name` in the
    message); exits through `p.error` otherwise. An empty string gives an empty list."""
    try:
        v = [int(x) for x in value.split(",") if x.strip()]
    except ValueError:
        p.error(f"{flag}: expected comma-separated integers, got {value!r}")
    if any(x < minimum for x in v):
        p.error(f"{flag}: {name} must be at least {minimum}")
    return v


# ---------------------------------------------------------------------------------------------
# running and timing


def run_logged(cmd: list[str], capture: bool = False, env: dict[str, str] | None = None) -> str:
    """Runs `cmd` in the repository root with the original environment (plus the overrides in
    `env`, if any); exits on failure.

    With `capture`, stdout is captured (and echoed) and returned."""
    prefix = "".join(f"{k}={v} " for k, v in (env or {}).items())
    print(f"$ (cd {REPO} && {prefix}{' '.join(cmd)})", flush=True)
    t = time.perf_counter()
    res = subprocess.run(
        cmd,
        cwd=REPO,
        env={**ORIGINAL_ENV, **(env or {})},
        stdout=subprocess.PIPE if capture else None,
        text=True,
    )
    if capture and res.stdout:
        print(res.stdout, end="", flush=True)
    if res.returncode != 0:
        sys.exit(f"command failed with exit status {res.returncode}: {' '.join(cmd)}")
    print(f"(took {time.perf_counter() - t:.1f} s)", flush=True)
    return res.stdout or ""


def built_example(name: str, skip_build: bool) -> Path:
    """The release binary of the zeroset example `name` (`CARGO_TARGET_DIR` honoured), built
    first with cargo unless `skip_build`; exits if it is missing."""
    target = ORIGINAL_ENV.get("CARGO_TARGET_DIR")
    binary = ((REPO / target) if target else REPO / "target") / "release" / "examples" / name
    if skip_build:
        print(f"--skip-build: using {binary}", flush=True)
    else:
        run_logged(["cargo", "build", "--release", "--example", name])
    if not binary.is_file():
        sys.exit(f"{binary} not found (cargo build failed, or CARGO_TARGET_DIR elsewhere?)")
    return binary


def run_and_read_zeroset(args, example: str, csv_names: dict, run, read, reused: str):
    """The zeroset side of a peer script: unless `--skip-zeroset`, builds `example` (or reuses it
    with `--skip-build`) and calls `run(args, binary, config)` for the one-thread configuration
    "1" and, with `args.mt`, for "all"; then reads both CSVs (`csv_names[config]` in `args.out`)
    with `read`. Returns (rows at one thread, rows at all threads or [])."""
    out = args.out
    if args.skip_zeroset:
        print(f"--skip-zeroset: reusing {reused} and {', '.join(csv_names.values())} in {out}", flush=True)
    else:
        binary = built_example(example, args.skip_build)
        run(args, binary, "1")
        if args.mt:
            run(args, binary, "all")
    zs1 = read(out / csv_names["1"])
    zsn = read(out / csv_names["all"]) if args.mt and (out / csv_names["all"]).is_file() else []
    return zs1, zsn


def timed(fn, repeat: int, warmup: bool = True):
    """Optionally one warm-up, then `repeat` timed runs; returns (last result, upper median ms,
    all times in ms). The upper median `sorted[n // 2]` is the rule of the Rust examples
    (`examples/common/timing.rs`)."""
    out = fn() if warmup else None
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append((time.perf_counter() - t) * 1e3)
    return out, sorted(times)[len(times) // 2], times


def fastest(runs: dict):
    """(label, ms) of the smallest ms among `runs` ({label: ms or None}); (None, nan) if none."""
    ok = [(k, v) for k, v in runs.items() if v is not None and not (isinstance(v, float) and math.isnan(v))]
    return min(ok, key=lambda kv: kv[1]) if ok else (None, math.nan)


def ratio(a, b) -> float:
    """a / b; NaN where either is missing or b ≤ 0."""
    if a is None or b is None or (isinstance(a, float) and math.isnan(a)) or (isinstance(b, float) and math.isnan(b)):
        return math.nan
    return a / b if b > 0 else math.nan


# ---------------------------------------------------------------------------------------------
# formatting


def fmt_ms(v):
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.2f}"


def fmt_e(v):
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.2e}"


def fmt_ratio(v):
    return "—" if v is None or math.isnan(v) else f"{v:.2f}×"


def fmt_int(v):
    return "—" if v is None else str(v)


def num(v) -> str:
    """A CSV cell: empty for missing values, full precision otherwise."""
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else repr(v)


def render_text(header: list[str], body: list[list[str]], left: int = 2, left_last: bool = False) -> str:
    """Plain-text table: the first `left` columns (and the last one with `left_last`) left-aligned."""
    w = [max(len(h), *(len(r[i]) for r in body)) if body else len(h) for i, h in enumerate(header)]
    is_left = lambda i: i < left or (left_last and i == len(header) - 1)  # noqa: E731
    line = lambda cells: "  ".join(  # noqa: E731
        c.ljust(w[i]) if is_left(i) else c.rjust(w[i]) for i, c in enumerate(cells)
    ).rstrip()
    return "\n".join([line(header), line(["-" * x for x in w])] + [line(r) for r in body])


def render_md(header: list[str], body: list[list[str]], left: int = 2) -> str:
    esc = lambda c: c.replace("|", "\\|")  # noqa: E731
    out = ["| " + " | ".join(esc(c) for c in header) + " |"]
    out.append("|" + "|".join(":---" if i < left else "---:" for i in range(len(header))) + "|")
    out += ["| " + " | ".join(esc(c) for c in r) + " |" for r in body]
    return "\n".join(out)


class Bars:
    """PASS / FAIL / SKIP lines for the targets a script checks (never changes the exit code)."""

    def __init__(self) -> None:
        self.rows: list[list[str]] = []

    def check(self, name: str, ok: bool | None, detail: str) -> None:
        verdict = "SKIP" if ok is None else ("PASS" if ok else "FAIL")
        self.rows.append([verdict, name, detail])

    def header(self) -> list[str]:
        return ["result", "bar", "measured"]

    def text(self) -> str:
        return render_text(self.header(), self.rows, left=3)

    def md(self) -> str:
        return render_md(self.header(), self.rows, left=3)


# ---------------------------------------------------------------------------------------------
# machine facts


def loadavg() -> str:
    try:
        return " / ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "?"


def machine_facts(loads: list[tuple[str, str]], extra: list[tuple[str, str]] = ()) -> list[tuple[str, str]]:
    """Date, CPU, versions, zeroset commit, thread variables (as this process sees them),
    then `extra` and the `loads` (label, loadavg()) pairs."""
    import numpy as np
    import scipy

    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        affinity = str(len(os.sched_getaffinity(0)))
    except AttributeError:
        affinity = "?"

    def cmd(*c):
        try:
            return subprocess.run(c, cwd=REPO, capture_output=True, text=True, timeout=30).stdout.strip() or "?"
        except (OSError, subprocess.SubprocessError):
            return "?"

    commit = cmd("git", "rev-parse", "--short", "HEAD")
    dirty = cmd("git", "status", "--porcelain", "--untracked-files=no")
    facts = [
        ("date", datetime.datetime.now().astimezone().isoformat(timespec="seconds")),
        ("host", f"{platform.node()} ({platform.platform()})"),
        ("cpu", cpu),
        ("cpu count (os / affinity)", f"{os.cpu_count()} / {affinity}"),
        ("python", sys.version.split()[0]),
        ("numpy", np.__version__),
        ("scipy", scipy.__version__),
        ("rustc", cmd("rustc", "--version")),
        ("zeroset commit", commit + (" (working tree modified)" if dirty not in ("", "?") else "")),
    ]
    facts += [(v, os.environ.get(v, "unset")) for v in THREAD_VARS]
    facts += list(extra)
    facts += list(loads)
    return facts


def write_report(md_path: Path, csv_path: Path, lines: list[str], facts: list[tuple[str, str]]) -> None:
    """Writes `lines` plus a Machine section to `md_path` and prints the facts and both paths."""
    lines = [*lines, "### Machine", "", render_md(["fact", "value"], [[a, b] for a, b in facts]), ""]
    md_path.write_text("\n".join(lines))
    print("\nmachine: " + "; ".join(f"{a}={b}" for a, b in facts))
    print(f"\nwrote {csv_path} and {md_path}")


def jsonable(v):
    """`v` with non-finite floats as None and numpy scalars as Python numbers, for json.dumps."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if getattr(v, "ndim", None) == 0 and hasattr(v, "item"):  # a numpy scalar
        return jsonable(v.item())
    return v
