#!/usr/bin/env python3
"""Peer comparison: zeroset's marching-cubes extraction vs skimage.measure.marching_cubes.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/pip install scikit-image==0.26.0
    benches/peers/.venv/bin/python benches/peers/mc_peers.py [--n 128,256] [--repeat 5]

Set-up: the torus R = 0.3, r = 0.1, centred at (0.5, 0.5, 0.5), axis z,
sdf(x, y, z) = sqrt((sqrt((x − .5)² + (y − .5)²) − 0.3)² + (z − .5)²) − 0.1, sampled on an n³ grid
with coordinates `numpy.linspace(0, 1, n)` on each axis (h = 1/(n − 1)).

Threads: skimage's marching_cubes is single-threaded compiled code (no BLAS, no thread option),
so its one configuration is both its one-thread and its best setting; zeroset is timed at one
thread (RAYON_NUM_THREADS=1) and at all threads (RAYON_NUM_THREADS=N, N = --mt-threads, default
the CPUs available), and the report gives both ratios and the one with zeroset at its fastest.

  1. `cargo build --release --example mc_timing` (CARGO_TARGET_DIR honoured; --skip-build reuses
     the binary), then `mc_timing --n 128,256 --shape torus --repeat R --csv …` twice: with
     RAYON_NUM_THREADS=1 (this run also writes the samples: `--write-dir OUT`) and with
     RAYON_NUM_THREADS=N. Timed by the example (one warm-up, then the median of R): one call of
     `marching_cubes` on the ready samples — the samples' check, the cell walk, welding the
     vertices into an indexed mesh and the normals by central differences of the samples (what
     skimage returns: vertices, faces, normals). Sampling the field is outside. It writes the
     samples (OUT/mc_torus_{n}.f64: raw little-endian f64, n³ values, C order, values[(i·n + j)·n + k] =
     sdf(x_i, y_j, z_k)) and one row per n in OUT/mc_zeroset_t1.csv / mc_zeroset_tall.csv
     (`n,shape,extract_ms,vertices,triangles,euler,watertight,max_abs_sdf_over_h,runs,threads,…`).
     `--skip-zeroset` reuses those files instead of running cargo;
  2. on the same samples (read back, not regenerated), times `skimage.measure.marching_cubes(volume,
     level=0.0, spacing=(h, h, h), method='lewiner')` (extraction only; loading excluded; one warm-up,
     then the median of --skimage-repeat) twice: on the float64 samples (what zeroset is given;
     skimage converts them to float32 inside the call, `_marching_cubes_lewiner.py`, and that
     conversion is timed) and on a float32 copy (skimage's native dtype; the copy made before the
     timing), and computes the same figures as zeroset from its vertices
     and faces: vertex and triangle counts, the Euler characteristic V − E + F (E = distinct
     undirected edges), watertightness (every edge in exactly two triangles) and max |sdf(v)| / h
     with the analytic torus sdf at the vertices;
  3. prints a table with ratios (skimage_ms / zeroset_ms, > 1 means zeroset is faster) against
     zeroset on one thread, on all threads and at its fastest, PASS/FAIL per bar, and writes
     OUT/mc_peers.csv and OUT/mc_peers.md.
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
from common import fmt_e, fmt_int, fmt_ms, fmt_ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402

try:
    import skimage  # noqa: E402
    from skimage.measure import marching_cubes  # noqa: E402
except ImportError:
    sys.exit(
        "scikit-image is not installed in this interpreter; run\n"
        f"    {sys.executable} -m pip install scikit-image==0.26.0"
    )

EXAMPLE = "mc_timing"
ZS_CSV = {"1": "mc_zeroset_t1.csv", "all": "mc_zeroset_tall.csv"}  # per zeroset configuration
SHAPE = "torus"
METHOD = "lewiner"  # skimage's default
CENTRE = (0.5, 0.5, 0.5)
MAJOR, MINOR = 0.3, 0.1
BAR_NS = (128, 256)  # n at which the bars are checked
SPEED_TARGET = 4.0  # extraction: skimage_ms / zeroset_ms (zeroset at its fastest) ≥ this
SDF_SLACK = 1.05  # zeroset max |sdf|/h ≤ skimage's · SDF_SLACK
SAMPLE_TOL = 1e-12  # warn if the file differs from the analytic sdf on the grid by more than this


@dataclass
class ZsRow:
    """One row of the example's CSV; None where a field is empty."""

    n: int
    shape: str
    extract_ms: float | None
    vertices: int | None
    triangles: int | None
    euler: int | None
    watertight: bool | None
    max_sdf_h: float | None  # max |sdf(v)| / h over the vertices
    runs: int | None
    threads: str | None  # optional column
    warmup: bool | None = None  # optional column


@dataclass
class SkRow:
    """skimage's result for one n."""

    n: int
    runs: int
    extract_ms: float = math.nan
    vertices: int = 0
    triangles: int = 0
    euler: int = 0
    watertight: bool = False
    max_sdf_h: float = math.nan
    degenerate: int = 0  # triangles with a repeated vertex index
    unreferenced: int = 0  # vertices used by no triangle
    extract_ms_f32: float = math.nan  # the same call on a float32 copy of the samples (skimage's native dtype)
    vertices_f32: int = 0
    max_sdf_h_f32: float = math.nan


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Time skimage.measure.marching_cubes on the same torus samples zeroset extracts from.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--n", default="128,256", help="grid sizes (n³ samples)")
    p.add_argument("--repeat", type=int, default=5, help="zeroset timed runs after one warm-up")
    p.add_argument("--skimage-repeat", type=int, default=5, help="skimage marching_cubes timed runs after one warm-up")
    p.add_argument(
        "--out", default=str(common.HERE / "out"), help="directory for the sample files (134 MB at n=256), CSV and report"
    )
    p.add_argument(
        "--skip-zeroset",
        action="store_true",
        help=f"do not run cargo; reuse the .f64 files and {', '.join(ZS_CSV.values())} already in --out "
        "(only skimage is timed now)",
    )
    p.add_argument("--skip-build", action="store_true", help="do not run cargo build; reuse the example binary")
    common.add_mt_arg(p, None)  # skimage has no thread setting
    common.add_blas_arg(p)
    a = p.parse_args()

    a.ns = common.int_list(p, a.n, "--n", 4)
    if not a.ns:
        p.error("nothing to do: --n is empty")
    for name in ("repeat", "skimage_repeat"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if a.mt_threads < 0:
        p.error("--mt-threads must be >= 0")
    a.mt = a.mt_threads if a.mt_threads > 1 else 0  # 0: one-thread run only
    a.out = Path(a.out).resolve()
    return a


# ---------------------------------------------------------------------------------------------
# Step 1: zeroset


def run_zeroset(args, binary: Path, config: str) -> None:
    """`config` "1": RAYON_NUM_THREADS=1 (and writes the samples); "all": RAYON_NUM_THREADS=N."""
    args.out.mkdir(parents=True, exist_ok=True)
    cmd = [str(binary), "--n", ",".join(map(str, args.ns)), "--shape", SHAPE, "--repeat", str(args.repeat),
           "--csv", str(args.out / ZS_CSV[config])]  # fmt: skip
    if config == "1":
        cmd += ["--write-dir", str(args.out)]
    common.run_logged(cmd, env={"RAYON_NUM_THREADS": "1" if config == "1" else str(args.mt)})


def parse_bool(v: str) -> bool:
    s = v.strip().lower()
    if s in ("true", "1", "yes", "y"):
        return True
    if s in ("false", "0", "no", "n"):
        return False
    raise ValueError(f"not a boolean: {v!r}")


def read_zeroset(path: Path) -> list[ZsRow]:
    """Reads the example's CSV: empty cells are missing values, unknown columns are ignored."""
    if not path.is_file():
        sys.exit(f"{path} not found (the example did not write it)")
    required = ("n", "shape", "extract_ms", "vertices", "triangles", "euler", "watertight",
                "max_abs_sdf_over_h", "runs")  # fmt: skip

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
            try:
                rows.append(
                    ZsRow(
                        n=int(r["n"]),
                        shape=r["shape"].strip(),
                        extract_ms=cell(r, "extract_ms", float),
                        vertices=cell(r, "vertices", int),
                        triangles=cell(r, "triangles", int),
                        euler=cell(r, "euler", int),
                        watertight=cell(r, "watertight", parse_bool),
                        max_sdf_h=cell(r, "max_abs_sdf_over_h", float),
                        runs=cell(r, "runs", int),
                        threads=cell(r, "threads", str),
                        warmup=cell(r, "warmup", parse_bool),
                    )
                )
            except ValueError as e:
                sys.exit(f"{path}: cannot parse row {r}: {e}")
    return rows


# ---------------------------------------------------------------------------------------------
# Step 2: skimage


def torus_sdf(x, y, z):
    cx, cy, cz = CENTRE
    return np.sqrt((np.sqrt((x - cx) ** 2 + (y - cy) ** 2) - MAJOR) ** 2 + (z - cz) ** 2) - MINOR


def load_volume(out: Path, n: int) -> np.ndarray:
    f = out / f"mc_{SHAPE}_{n}.f64"
    if not f.is_file():
        sys.exit(f"{f} not found (the example did not write it; with --skip-zeroset, same --n?)")
    t0 = time.perf_counter()
    v = np.fromfile(f, dtype="<f8")
    if v.size != n**3:
        sys.exit(f"{f}: {v.size} values, expected {n}³ = {n**3}")
    vol = v.reshape(n, n, n)
    # Sanity check of the layout (printed, not enforced): the file against the analytic sdf.
    c = np.linspace(0.0, 1.0, n)
    diff = float(np.max(np.abs(vol - torus_sdf(c[:, None, None], c[None, :, None], c[None, None, :]))))
    print(f"  {f.name}: loaded in {time.perf_counter() - t0:.2f} s; max |file − sdf(grid)| = {diff:.1e}", flush=True)
    if not diff <= SAMPLE_TOL:
        print(f"  warning: the samples differ from the analytic torus sdf by {diff:.1e} (> {SAMPLE_TOL:g}); "
              "wrong layout or shape?", flush=True)  # fmt: skip
    return vol


def mesh_stats(verts: np.ndarray, faces: np.ndarray, h: float, row: SkRow) -> None:
    """Counts, Euler characteristic V − E + F, watertightness and max |sdf(v)|/h of an indexed mesh."""
    faces = np.asarray(faces, dtype=np.int64)
    row.vertices, row.triangles = int(verts.shape[0]), int(faces.shape[0])
    row.degenerate = int(np.count_nonzero(
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    ))  # fmt: skip
    used = np.unique(faces)
    row.unreferenced = row.vertices - int(used.size)
    # Undirected edges, self-loops of degenerate triangles dropped; watertight: each edge in exactly two faces.
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.sort(e[e[:, 0] != e[:, 1]], axis=1)
    _, counts = np.unique(e[:, 0] * np.int64(row.vertices) + e[:, 1], return_counts=True)
    row.euler = int(used.size) - int(counts.size) + row.triangles
    row.watertight = bool(counts.size > 0 and np.all(counts == 2))
    # skimage's vertices are (axis 0, axis 1, axis 2) · h = (x, y, z) with spacing (h, h, h) and origin 0.
    row.max_sdf_h = float(np.max(np.abs(torus_sdf(verts[:, 0], verts[:, 1], verts[:, 2])))) / h


def run_skimage(n: int, vol: np.ndarray, args) -> SkRow:
    h = 1.0 / (n - 1)
    row = SkRow(n, args.skimage_repeat)
    print(f"  skimage marching_cubes(level=0, spacing=(h,h,h), method={METHOD!r}) (warm-up + {row.runs}) …",
          flush=True)  # fmt: skip
    (verts, faces, _normals, _values), row.extract_ms, _ = common.timed(
        lambda: marching_cubes(vol, level=0.0, spacing=(h, h, h), method=METHOD), row.runs
    )
    mesh_stats(verts, faces, h, row)
    vol32 = vol.astype(np.float32)  # skimage's native dtype; the conversion is not timed
    print(f"  the same on a float32 copy (warm-up + {row.runs}) …", flush=True)
    (v32, f32, _n32, _v32), row.extract_ms_f32, _ = common.timed(
        lambda: marching_cubes(vol32, level=0.0, spacing=(h, h, h), method=METHOD), row.runs
    )
    row.vertices_f32 = int(v32.shape[0])
    row.max_sdf_h_f32 = float(np.max(np.abs(torus_sdf(v32[:, 0], v32[:, 1], v32[:, 2])))) / h
    print(f"    float32: {row.extract_ms_f32:.1f} ms; {row.vertices_f32:,} vertices, max |sdf|/h {row.max_sdf_h_f32:.3e}",
          flush=True)  # fmt: skip
    del vol32
    extra = "".join([f", {row.degenerate} degenerate triangles" if row.degenerate else "",
                     f", {row.unreferenced} unreferenced vertices" if row.unreferenced else ""])  # fmt: skip
    print(f"    {row.extract_ms:.1f} ms; {row.vertices:,} vertices, {row.triangles:,} triangles, Euler {row.euler}, "
          f"watertight {row.watertight}, max |sdf|/h {row.max_sdf_h:.3e}{extra}", flush=True)  # fmt: skip
    return row


# ---------------------------------------------------------------------------------------------
# Step 3: tables and bars


def ratio(sk: float | None, zs: float | None) -> float:
    """skimage_ms / zeroset_ms; NaN where either is missing."""
    return common.ratio(sk, zs)


def fmt_bool(v) -> str:
    return "—" if v is None else ("yes" if v else "NO")


@dataclass
class Case:
    """One n: zeroset at one and at all threads, skimage."""

    n: int
    zs1: ZsRow | None
    zsn: ZsRow | None
    sk: SkRow | None

    def zs_runs(self) -> list[ZsRow]:
        return [z for z in (self.zs1, self.zsn) if z is not None]

    def zs_fastest(self) -> tuple[str | None, float]:
        g = lambda z: None if z is None else z.extract_ms  # noqa: E731
        return common.fastest({"1 thread": g(self.zs1), "all threads": g(self.zsn)})

    def ratios(self, f32: bool = False) -> tuple[float, float, float]:
        """skimage ÷ zeroset: one thread, all threads, zeroset at its fastest (skimage on the
        float64 samples, or with `f32` on its float32 copy)."""
        sk = None if self.sk is None else (self.sk.extract_ms_f32 if f32 else self.sk.extract_ms)
        g = lambda z: None if z is None else z.extract_ms  # noqa: E731
        return ratio(sk, g(self.zs1)), ratio(sk, g(self.zsn)), ratio(sk, self.zs_fastest()[1])


def cases(zs1: list[ZsRow], zsn: list[ZsRow], sk_rows: list[SkRow]) -> list[Case]:
    z1 = {r.n: r for r in zs1 if r.shape == SHAPE}
    zn = {r.n: r for r in zsn if r.shape == SHAPE}
    sk = {r.n: r for r in sk_rows}
    return [Case(n, z1.get(n), zn.get(n), sk.get(n)) for n in sorted(set(z1) | set(zn) | set(sk))]


def zs_ms(z: ZsRow | None, repeat: int) -> str:
    return "—" if z is None else common.with_how(z.extract_ms, z.runs, z.warmup, repeat)


def speed_table(cs: list[Case], args):
    header = ["n", "zeroset 1 thread ms", f"zeroset {args.mt or 'all'} threads ms", "skimage float64 ms (1 thread)",
              "skimage float32 ms (1 thread)", "skimage ÷ zeroset, 1 thread each (float64 / float32)",
              f"skimage ÷ zeroset, {args.mt or 'all'} threads (float64 / float32)",
              "skimage ÷ zeroset, each at its fastest (float64 / float32)", "note"]  # fmt: skip
    body = []
    for c in cs:
        one, alln, fast = c.ratios()
        one32, alln32, fast32 = c.ratios(f32=True)
        notes = []
        if c.zs1 is None and c.zsn is None:
            notes.append("not in zeroset's CSV")
        if c.sk is None:
            notes.append("zeroset only")
        for label, z in (("1 thread", c.zs1), ("all threads", c.zsn)):
            if z is not None and z.threads is not None and label == "1 thread" and z.threads != "1":
                notes.append(f"the 1-thread run reports threads={z.threads}")
        body.append([str(c.n), zs_ms(c.zs1, args.repeat), zs_ms(c.zsn, args.repeat),
                     "—" if c.sk is None else common.with_how(c.sk.extract_ms, c.sk.runs, True, args.skimage_repeat),
                     "—" if c.sk is None else common.with_how(c.sk.extract_ms_f32, c.sk.runs, True, args.skimage_repeat),
                     f"{fmt_ratio(one)} / {fmt_ratio(one32)}", f"{fmt_ratio(alln)} / {fmt_ratio(alln32)}",
                     f"{fmt_ratio(fast)} / {fmt_ratio(fast32)}" + (f" (zeroset {c.zs_fastest()[0]})"
                                                                  if c.zs_fastest()[0] else ""),
                     "; ".join(notes)])  # fmt: skip
    return header, body


def mesh_table(cs: list[Case]):
    header = ["n", "zeroset verts", "skimage verts", "zeroset tris", "skimage tris", "zeroset Euler", "skimage Euler",
              "zeroset watertight", "skimage watertight", "zeroset max|sdf|/h", "skimage max|sdf|/h", "note"]  # fmt: skip
    body = []
    for c in cs:
        z = c.zs1 or c.zsn
        g = lambda attr: None if z is None else getattr(z, attr)  # noqa: E731
        h = lambda attr: None if c.sk is None else getattr(c.sk, attr)  # noqa: E731
        notes = []
        if c.zs1 is not None and c.zsn is not None:
            key = lambda r: (r.vertices, r.triangles, r.euler, r.watertight, r.max_sdf_h)  # noqa: E731
            if key(c.zs1) != key(c.zsn):
                notes.append("zeroset's 1-thread and all-threads meshes differ!")
        if c.sk is not None:
            if c.sk.degenerate:
                notes.append(f"skimage {c.sk.degenerate} degenerate tris")
            if c.sk.unreferenced:
                notes.append(f"skimage {c.sk.unreferenced} unreferenced verts")
            notes.append(f"skimage on float32: {c.sk.vertices_f32:,} verts, max|sdf|/h {fmt_e(c.sk.max_sdf_h_f32)}")
        body.append([str(c.n), fmt_int(g("vertices")), fmt_int(h("vertices")), fmt_int(g("triangles")),
                     fmt_int(h("triangles")), fmt_int(g("euler")), fmt_int(h("euler")), fmt_bool(g("watertight")),
                     fmt_bool(h("watertight")), fmt_e(g("max_sdf_h")), fmt_e(h("max_sdf_h")), "; ".join(notes)])  # fmt: skip
    return header, body


def check_bars(cs: list[Case]) -> common.Bars:
    bars = common.Bars()
    by_n = {c.n: c for c in cs}
    for n in BAR_NS:
        c = by_n.get(n, Case(n, None, None, None))
        zs = c.zs_runs()  # every zeroset run must pass the mesh bars
        eulers = [z.euler for z in zs if z.euler is not None]
        bars.check(f"n={n}: zeroset Euler characteristic 0 (torus)", all(e == 0 for e in eulers) if eulers else None,
                   "not measured" if not eulers else "V − E + F = " + " / ".join(map(str, eulers)))  # fmt: skip
        wts = [z.watertight for z in zs if z.watertight is not None]
        bars.check(f"n={n}: zeroset mesh watertight", all(wts) if wts else None,
                   "not measured" if not wts else ("every edge in exactly 2 triangles" if all(wts) else "open or non-manifold edges"))  # fmt: skip
        zms = [z.max_sdf_h for z in zs if z.max_sdf_h is not None]
        zm, sm = (max(zms) if zms else None), (None if c.sk is None else c.sk.max_sdf_h)
        ok = None if zm is None or sm is None else zm <= sm * SDF_SLACK
        bars.check(f"n={n}: zeroset max|sdf|/h ≤ skimage's × {SDF_SLACK:g}", ok,
                   "not measured" if ok is None else f"{zm:.3e} vs {sm:.3e} (ratio {zm / sm:.3f})")  # fmt: skip
        f32_faster = c.sk is not None and c.sk.extract_ms_f32 < c.sk.extract_ms
        one, _, fast = c.ratios(f32=f32_faster)
        st = None if c.sk is None else min(c.sk.extract_ms, c.sk.extract_ms_f32)
        label, zt = c.zs_fastest()
        label = f"{label}; skimage on {'float32' if f32_faster else 'float64'}"
        bars.check(f"n={n}: extraction ≥ {SPEED_TARGET:g}× faster than skimage at its fastest dtype, zeroset at its fastest",
                   None if math.isnan(fast) else fast >= SPEED_TARGET,
                   "not measured" if math.isnan(fast) else f"{fmt_ms(st)} / {fmt_ms(zt)} ms = {fast:.1f}× (zeroset {label})")  # fmt: skip
        z1 = None if c.zs1 is None else c.zs1.extract_ms
        bars.check(f"n={n}: extraction ≥ {SPEED_TARGET:g}× faster than skimage at its fastest dtype, one thread each (reported)",
                   None if math.isnan(one) else one >= SPEED_TARGET,
                   "not measured" if math.isnan(one) else f"{fmt_ms(st)} / {fmt_ms(z1)} ms = {one:.1f}×")  # fmt: skip
    return bars


def main() -> None:
    args = parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    print(f"BLAS threads: {BLAS_NOTE}; all-threads configuration (zeroset): {args.mt or 'not run'}; "
          f"load average {load_start}; scikit-image {skimage.__version__}\n", flush=True)  # fmt: skip

    zs1, zsn = common.run_and_read_zeroset(args, EXAMPLE, ZS_CSV, run_zeroset, read_zeroset, "the .f64 files")
    for rows, label in [(zs1, "1 thread")] + ([(zsn, "all threads")] if args.mt else []):
        for n in args.ns:
            if not any(r.n == n and r.shape == SHAPE for r in rows):
                print(f"warning: no zeroset row ({label}) for n={n}, shape {SHAPE}", flush=True)
    load_after_cargo = common.loadavg()

    sk_rows = []
    for n in args.ns:
        print(f"\n--- n={n} ({n**3:,} samples, h = 1/{n - 1}) ---", flush=True)
        vol = load_volume(out, n)
        sk_rows.append(run_skimage(n, vol, args))
        del vol
    load_after_skimage = common.loadavg()

    cs = cases([r for r in zs1 if r.n in args.ns], [r for r in zsn if r.n in args.ns], sk_rows)
    sh, sb = speed_table(cs, args)
    mh, mb = mesh_table(cs)
    bars = check_bars(cs)
    threads = ", ".join(sorted({z.threads for z in zs1 + zsn if z.threads})) or "not reported by the example"
    print(f"\n=== marching cubes, {SHAPE} (R={MAJOR}, r={MINOR}), extraction only (ms): ratio = skimage_ms / "
          f"zeroset_ms (> 1 means zeroset is faster); skimage is single-threaded ===\n"
          f"{render_text(sh, sb, left=1, left_last=True)}")  # fmt: skip
    print(f"\n=== meshes: max|sdf|/h = max over vertices of |analytic sdf| / h ===\n"
          f"{render_text(mh, mb, left=1, left_last=True)}")  # fmt: skip
    print(f"\n=== bars ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start),
         ("load average 1/5/15 min, after cargo", load_after_cargo),
         ("load average 1/5/15 min, after skimage", load_after_skimage)],
        [("scikit-image", skimage.__version__),
         ("BLAS threads (Python side; skimage's marching_cubes uses none)",
          f"{BLAS_NOTE}; OpenBLAS reports {common.blas_runtime()}"),
         ("zeroset threads (from the example's CSV)", threads)],
    )  # fmt: skip

    with (out / "mc_peers.csv").open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["n", "shape", "side", "threads", "runs", "warmup", "extract_ms", "ratio_skimage_f64_over_this",
                     "vertices", "triangles", "euler", "watertight", "max_abs_sdf_over_h", "degenerate_triangles",
                     "unreferenced_vertices"])  # fmt: skip
        for c in cs:
            sk = None if c.sk is None else c.sk.extract_ms
            for label, z in (("rayon 1", c.zs1), ("rayon all", c.zsn)):
                if z is not None:
                    wr.writerow([c.n, SHAPE, "zeroset", z.threads or label] + [common.num(v) for v in (
                        z.runs, None if z.warmup is None else int(z.warmup), z.extract_ms, ratio(sk, z.extract_ms),
                        z.vertices, z.triangles, z.euler, z.watertight, z.max_sdf_h, None, None)])  # fmt: skip
            if c.sk is not None:
                s_ = c.sk
                wr.writerow([c.n, SHAPE, "skimage float64", "1"] + [common.num(v) for v in (
                    s_.runs, 1, s_.extract_ms, 1.0, s_.vertices, s_.triangles, s_.euler, s_.watertight, s_.max_sdf_h,
                    s_.degenerate, s_.unreferenced)])  # fmt: skip
                wr.writerow([c.n, SHAPE, "skimage float32", "1"] + [common.num(v) for v in (
                    s_.runs, 1, s_.extract_ms_f32, ratio(s_.extract_ms, s_.extract_ms_f32), s_.vertices_f32, None,
                    None, None, s_.max_sdf_h_f32, None, None)])  # fmt: skip

    zs_source = (
        f"timings and mesh figures read from an earlier run's {' and '.join(f'`{v}`' for v in ZS_CSV.values())} "
        "(`--skip-zeroset`; only skimage was timed now)"
        if args.skip_zeroset
        else f"median of {args.repeat} runs after one warm-up, with RAYON_NUM_THREADS=1 and with "
        f"RAYON_NUM_THREADS={args.mt or '—'}"
    )
    report = [
        "## Peer comparison: marching cubes (zeroset vs skimage.measure.marching_cubes)",
        "",
        f"`benches/peers/mc_peers.py {' '.join(sys.argv[1:])}`: same samples in the same run. Torus R = {MAJOR}, "
        f"r = {MINOR}, centre (0.5, 0.5, 0.5), axis z, its exact sdf sampled on n³ points `linspace(0, 1, n)` per "
        f"axis (h = 1/(n − 1)), written by zeroset and read back by Python. Extraction only on both sides (sampling "
        "and loading excluded): zeroset times one `marching_cubes` call on the ready samples (the samples' check, "
        "the cell walk, the welded indexed mesh, normals by central differences), skimage one `marching_cubes` "
        "call (vertices, faces, normals, values). zeroset: `examples/mc_timing.rs` "
        f"({zs_source}); zeroset threads reported: {threads}. skimage {skimage.__version__}: `marching_cubes(volume, "
        f"level=0.0, spacing=(h, h, h), method='{METHOD}')`, median of {args.skimage_repeat} runs after one "
        "warm-up, on the float64 samples (skimage converts them to float32 inside the call: timed) and on a "
        "float32 copy made beforehand (its native dtype: the peer at its best); it is single-threaded compiled code with no thread setting, so its one run is both its "
        "one-thread and its best configuration. Ratios = skimage ms ÷ zeroset ms (> 1: zeroset faster) against "
        "zeroset on one thread (like for like), on all threads, and at its fastest. Euler = V − E + F "
        "(V = referenced vertices, E = distinct undirected edges; 0 for a torus); watertight = every edge in "
        "exactly two triangles; max|sdf|/h = max over the vertices of the analytic sdf's absolute value, divided "
        "by h (the mesh bars must hold for both zeroset runs).",
        "",
        "### Extraction time (ms)",
        "",
        render_md(sh, sb, left=1),
        "",
        "### Meshes",
        "",
        render_md(mh, mb, left=1),
        "",
        "### Bars",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "mc_peers.md", out / "mc_peers.csv", report, facts)


if __name__ == "__main__":
    main()
