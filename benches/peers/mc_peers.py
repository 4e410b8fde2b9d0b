#!/usr/bin/env python3
"""Peer comparison: zeroset's marching-cubes extraction vs skimage.measure.marching_cubes.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh
    benches/peers/.venv/bin/pip install scikit-image==0.26.0
    benches/peers/.venv/bin/python benches/peers/mc_peers.py [--n 128,256] [--repeat 5]

Set-up: the torus R = 0.3, r = 0.1, centred at (0.5, 0.5, 0.5), axis z,
sdf(x, y, z) = sqrt((sqrt((x − .5)² + (y − .5)²) − 0.3)² + (z − .5)²) − 0.1, sampled on an n³ grid
with coordinates `numpy.linspace(0, 1, n)` on each axis (h = 1/(n − 1)).

  1. `cargo run --release --example mc_timing -- --n 128,256 --shape torus --repeat R --write-dir OUT
     --csv OUT/mc_zeroset.csv` times zeroset's extraction (sampling excluded) and writes the samples
     (OUT/mc_torus_{n}.f64: raw little-endian f64, n³ values, C order, values[(i·n + j)·n + k] =
     sdf(x_i, y_j, z_k)) and one row per n in mc_zeroset.csv (`n,shape,extract_ms,vertices,
     triangles,euler,watertight,max_abs_sdf_over_h,runs`). `--skip-zeroset` reuses those files
     instead of running cargo;
  2. on the same samples (read back, not regenerated), times `skimage.measure.marching_cubes(volume,
     level=0.0, spacing=(h, h, h), method='lewiner')` (extraction only; loading excluded) and computes
     the same figures as zeroset from its vertices and faces: vertex and triangle counts, the Euler
     characteristic V − E + F (E = distinct undirected edges), watertightness (every edge in exactly
     two triangles) and max |sdf(v)| / h with the analytic torus sdf at the vertices;
  3. prints a table with ratios (skimage_ms / zeroset_ms, > 1 means zeroset is faster), PASS/FAIL
     per bar, and writes OUT/mc_peers.csv and OUT/mc_peers.md.
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

BLAS_NOTE = common.pin_blas_threads()  # before numpy is imported

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
ZEROSET_CSV = "mc_zeroset.csv"
SHAPE = "torus"
METHOD = "lewiner"  # skimage's default
CENTRE = (0.5, 0.5, 0.5)
MAJOR, MINOR = 0.3, 0.1
BAR_NS = (128, 256)  # n at which the bars are checked
SPEED_TARGET = 4.0  # extraction: skimage_ms / zeroset_ms ≥ this
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
        help=f"do not run cargo; reuse the .f64 files and {ZEROSET_CSV} already in --out (only skimage is timed now)",
    )
    common.add_blas_arg(p)
    a = p.parse_args()

    a.ns = common.int_list(p, a.n, "--n", 4)
    if not a.ns:
        p.error("nothing to do: --n is empty")
    for name in ("repeat", "skimage_repeat"):
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
         "--n", ",".join(map(str, args.ns)), "--shape", SHAPE, "--repeat", str(args.repeat),
         "--write-dir", str(args.out), "--csv", str(args.out / ZEROSET_CSV)]
    )  # fmt: skip


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
    extra = "".join([f", {row.degenerate} degenerate triangles" if row.degenerate else "",
                     f", {row.unreferenced} unreferenced vertices" if row.unreferenced else ""])  # fmt: skip
    print(f"    {row.extract_ms:.1f} ms; {row.vertices:,} vertices, {row.triangles:,} triangles, Euler {row.euler}, "
          f"watertight {row.watertight}, max |sdf|/h {row.max_sdf_h:.3e}{extra}", flush=True)  # fmt: skip
    return row


# ---------------------------------------------------------------------------------------------
# Step 3: tables and bars


def ratio(sk: float | None, zs: float | None) -> float:
    """skimage_ms / zeroset_ms; NaN where either is missing."""
    if sk is None or zs is None or math.isnan(sk) or math.isnan(zs) or zs <= 0:
        return math.nan
    return sk / zs


def fmt_bool(v) -> str:
    return "—" if v is None else ("yes" if v else "NO")


def paired(zs_rows: list[ZsRow], sk_rows: list[SkRow]) -> list[tuple[int, ZsRow | None, SkRow | None]]:
    zs = {r.n: r for r in zs_rows if r.shape == SHAPE}
    sk = {r.n: r for r in sk_rows}
    return [(n, zs.get(n), sk.get(n)) for n in sorted(set(zs) | set(sk))]


def table(pairs, args):
    header = ["n", "zeroset ms", "skimage ms", "ratio", "zeroset verts", "skimage verts", "zeroset tris",
              "skimage tris", "zeroset Euler", "skimage Euler", "zeroset watertight", "skimage watertight",
              "zeroset max|sdf|/h", "skimage max|sdf|/h", "note"]  # fmt: skip
    body = []
    for n, z, s in pairs:
        g = lambda attr: None if z is None else getattr(z, attr)  # noqa: E731
        h = lambda attr: None if s is None else getattr(s, attr)  # noqa: E731
        notes = []
        if z is None:
            notes.append("not in zeroset's CSV")
        elif z.runs is not None and z.runs != args.repeat:
            notes.append(f"zeroset runs {z.runs}")
        if s is None:
            notes.append("zeroset only")
        else:
            if s.degenerate:
                notes.append(f"skimage {s.degenerate} degenerate tris")
            if s.unreferenced:
                notes.append(f"skimage {s.unreferenced} unreferenced verts")
        body.append([str(n), fmt_ms(g("extract_ms")), fmt_ms(h("extract_ms")),
                     fmt_ratio(ratio(h("extract_ms"), g("extract_ms"))),
                     fmt_int(g("vertices")), fmt_int(h("vertices")), fmt_int(g("triangles")), fmt_int(h("triangles")),
                     fmt_int(g("euler")), fmt_int(h("euler")), fmt_bool(g("watertight")), fmt_bool(h("watertight")),
                     fmt_e(g("max_sdf_h")), fmt_e(h("max_sdf_h")), "; ".join(notes)])  # fmt: skip
    return header, body


def check_bars(pairs) -> common.Bars:
    bars = common.Bars()
    by_n = {n: (z, s) for n, z, s in pairs}
    for n in BAR_NS:
        z, s = by_n.get(n, (None, None))
        zv = lambda attr: None if z is None else getattr(z, attr)  # noqa: E731
        euler, wt = zv("euler"), zv("watertight")
        bars.check(f"n={n}: zeroset Euler characteristic 0 (torus)", None if euler is None else euler == 0,
                   "not measured" if euler is None else f"V − E + F = {euler}")  # fmt: skip
        bars.check(f"n={n}: zeroset mesh watertight", wt,
                   "not measured" if wt is None else ("every edge in exactly 2 triangles" if wt else "open or non-manifold edges"))  # fmt: skip
        zm, sm = zv("max_sdf_h"), None if s is None else s.max_sdf_h
        ok = None if zm is None or sm is None else zm <= sm * SDF_SLACK
        bars.check(f"n={n}: zeroset max|sdf|/h ≤ skimage's × {SDF_SLACK:g}", ok,
                   "not measured" if ok is None else f"{zm:.3e} vs {sm:.3e} (ratio {zm / sm:.3f})")  # fmt: skip
        zt, st = zv("extract_ms"), None if s is None else s.extract_ms
        r = ratio(st, zt)
        bars.check(f"n={n}: extraction ≥ {SPEED_TARGET:g}× faster than skimage", None if math.isnan(r) else r >= SPEED_TARGET,
                   "not measured" if math.isnan(r) else f"{fmt_ms(st)} / {fmt_ms(zt)} ms = {r:.1f}×")  # fmt: skip
    return bars


def main() -> None:
    args = parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    load_start = common.loadavg()
    print(f"BLAS threads: {BLAS_NOTE}; load average {load_start}; scikit-image {skimage.__version__}\n", flush=True)

    if args.skip_zeroset:
        print(f"--skip-zeroset: reusing the .f64 files and {ZEROSET_CSV} in {out}", flush=True)
    else:
        run_zeroset(args)
    zs_rows = read_zeroset(out / ZEROSET_CSV)
    for n in args.ns:
        if not any(r.n == n and r.shape == SHAPE for r in zs_rows):
            print(f"warning: no zeroset row for n={n}, shape {SHAPE} in {ZEROSET_CSV}", flush=True)
    load_after_cargo = common.loadavg()

    sk_rows = []
    for n in args.ns:
        print(f"\n--- n={n} ({n**3:,} samples, h = 1/{n - 1}) ---", flush=True)
        vol = load_volume(out, n)
        sk_rows.append(run_skimage(n, vol, args))
        del vol
    load_after_skimage = common.loadavg()

    pairs = paired([r for r in zs_rows if r.n in args.ns], sk_rows)
    header, body = table(pairs, args)
    bars = check_bars(pairs)
    threads = ", ".join(sorted({z.threads for z in zs_rows if z.threads})) or "not reported by the example"
    print(f"\n=== marching cubes, {SHAPE} (R={MAJOR}, r={MINOR}), extraction only: ratio = skimage_ms / zeroset_ms "
          f"(> 1 means zeroset is faster); max|sdf|/h = max over vertices of |analytic sdf| / h ===\n"
          f"{render_text(header, body, left=1, left_last=True)}")  # fmt: skip
    print(f"\n=== bars ===\n{bars.text()}")

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start),
         ("load average 1/5/15 min, after cargo", load_after_cargo),
         ("load average 1/5/15 min, after skimage", load_after_skimage)],
        [("scikit-image", skimage.__version__), ("BLAS threads (Python side)", BLAS_NOTE),
         ("zeroset threads (from the example)", threads)],
    )  # fmt: skip

    with (out / "mc_peers.csv").open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["n", "shape", "zeroset_runs", "skimage_runs", "zeroset_extract_ms", "skimage_extract_ms",
                     "ratio_extract", "zeroset_vertices", "skimage_vertices", "zeroset_triangles",
                     "skimage_triangles", "zeroset_euler", "skimage_euler", "zeroset_watertight",
                     "skimage_watertight", "zeroset_max_abs_sdf_over_h", "skimage_max_abs_sdf_over_h",
                     "skimage_degenerate_triangles", "skimage_unreferenced_vertices"])  # fmt: skip
        for n, z, s in pairs:
            g = lambda attr: None if z is None else getattr(z, attr)  # noqa: E731
            h = lambda attr: None if s is None else getattr(s, attr)  # noqa: E731
            wr.writerow([n, SHAPE] + [common.num(v) for v in (
                g("runs"), h("runs"), g("extract_ms"), h("extract_ms"), ratio(h("extract_ms"), g("extract_ms")),
                g("vertices"), h("vertices"), g("triangles"), h("triangles"), g("euler"), h("euler"),
                g("watertight"), h("watertight"), g("max_sdf_h"), h("max_sdf_h"),
                h("degenerate"), h("unreferenced"))])  # fmt: skip

    zs_source = (
        f"timings and mesh figures read from an earlier run's `{ZEROSET_CSV}` (`--skip-zeroset`; only skimage "
        "was timed now)"
        if args.skip_zeroset
        else f"median of {args.repeat} runs after one warm-up"
    )
    report = [
        "## Peer comparison: marching cubes (zeroset vs skimage.measure.marching_cubes)",
        "",
        f"`benches/peers/mc_peers.py {' '.join(sys.argv[1:])}`: same samples in the same run. Torus R = {MAJOR}, "
        f"r = {MINOR}, centre (0.5, 0.5, 0.5), axis z, its exact sdf sampled on n³ points `linspace(0, 1, n)` per "
        f"axis (h = 1/(n − 1)), written by zeroset and read back by Python. Extraction only on both sides (sampling "
        f"and loading excluded). zeroset: `examples/mc_timing.rs` ({zs_source}); zeroset threads: {threads}. "
        f"skimage {skimage.__version__} (single-threaded): `marching_cubes(volume, level=0.0, spacing=(h, h, h), "
        f"method='{METHOD}')`, median of {args.skimage_repeat} runs after one warm-up. Ratio = skimage_ms / "
        "zeroset_ms (> 1: zeroset faster). Euler = V − E + F (V = referenced vertices, E = distinct undirected "
        "edges; 0 for a torus); watertight = every edge in exactly two triangles; max|sdf|/h = max over the "
        "vertices of the analytic sdf's absolute value, divided by h.",
        "",
        render_md(header, body, left=1),
        "",
        "### Bars",
        "",
        bars.md(),
        "",
    ]
    common.write_report(out / "mc_peers.md", out / "mc_peers.csv", report, facts)


if __name__ == "__main__":
    main()
