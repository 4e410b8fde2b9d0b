#!/usr/bin/env python3
"""Peer comparison, scan → mesh at full size: `zeroset reconstruct --method rbf` against scipy's
local RBF (`RBFInterpolator(neighbors=k)`) + scikit-image marching cubes, and Open3D's screened
Poisson, all on the same oriented point cloud in one run; every mesh measured the same way.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh --open3d        # once (Debian/Ubuntu: apt-get install libusb-1.0-0 first)
    cargo build --release -p zeroset-cli        # target/release/zeroset (built here if missing)
    benches/peers/.venv/bin/python benches/peers/scan_peers.py                       # data/bunny_points.ply
    benches/peers/.venv/bin/python benches/peers/scan_peers.py --sphere 100000       # Fibonacci sphere
    benches/peers/.venv/bin/python benches/peers/scan_peers.py --neighbors 20,50 --depths 8,9 --grid 96

Input: `--cloud` (default data/bunny_points.ply; any file `poisson_peers.read_points` reads, with
unit normals in columns 4-6 — normals are never estimated here, zeroset uses the file's) or
`--sphere N`: N Fibonacci points on the unit sphere (z = 1 − (2i+1)/N), outward normals, written
with 17 significant digits to OUT/<name>/sphere_N.xyzn, the file every side reads.

What is timed (every side at each `--threads` count, default 1 and the CPUs available):

  1. zeroset: the whole process `zeroset reconstruct CLOUD -o OUT/<name>/zeroset_rbf_t{t}.ply
     --method rbf --no-preview --force` with RAYON_NUM_THREADS=t (the rest of the environment as
     found): reading the cloud, the off-surface constraints, the RBF fit (FMM-accelerated GMRES),
     the signed marching cubes of the zero set, the mesh check and writing it. Wall time around
     the process; its peak memory is the child's own `ru_maxrss` (`os.wait4`), its CPU time
     user + system. Fit time, mesh time, GMRES steps, residual, grid and offset report are read
     from its summary. The binary target/release/zeroset (CARGO_TARGET_DIR honoured) is built
     with `cargo build --release -p zeroset-cli` only if it is missing (`--no-build`: never), and
     copied to OUT/<name>/zeroset, which every run executes and which is removed afterwards (a
     rebuild during the script's run cannot mix two builds; its build time and sha256 are
     recorded). One run without
     warm-up by default (`--zeroset-repeat R` > 1: one warm-up, then the upper median of R). Its
     FMM operators come from a disk cache (~/.cache/zeroset/fmm) once built; the plan line says
     whether they were cached (recorded).
  2. scipy: in a child process with BLAS at t threads (OMP/OPENBLAS/MKL_NUM_THREADS=t, set before
     numpy loads; the counts numpy's and scipy's OpenBLAS report are recorded), per `--neighbors`
     value k (default 50):
       constraints = the off-surface constraints built the way zeroset builds them by default
         (crates/bases/src/rbf/constraints.rs, `Offset::Auto`): each point p with value 0, and
         per side s = ±1 the point p + s·ε·n with value s·ε (n the unit normal), ε starting at 1%
         of the points' bounding-box diagonal; if the input point nearest to p + s·ε·n (a
         cKDTree query) is not p — and not as near as p within 0.1% — ε is halved for that side of
         that point and the test repeated, at most `--halvings` (8, zeroset's count) times; a
         side still failing is dropped (only that side, as zeroset does). Vectorised: all
         points tested at once, the failing ones again at half ε. The shrunk / dropped counts
         and the smallest ε are printed beside zeroset's own (a check that the two sets agree);
       fit = `RBFInterpolator(y, values, kernel='linear', degree=1, neighbors=k)` (φ = −r, with
         the degree-1 polynomial the same interpolant family as zeroset's `r` kernel; with
         `neighbors` the constructor only builds a KDTree: the local systems are solved during
         evaluation);
       grid = the field at every sample of zeroset's grid: the box, sample counts and voxel read
         from zeroset's mesh stage ("over min … max …", "grid A×B×C = … samples, voxel h"),
         laid out as zeroset lays it (cells = ceil(extent / h), centred on the box), i.e. the
         same samples up to the 7 printed digits; without those lines: the points' bounding box
         grown by 5% of its diagonal, 128 cells along its longest side. `--grid N` instead puts
         N cells along the longest side of that box (said in the report). The samples are
         evaluated in chunks of `--eval-chunk` (100,000) points, one `RBFInterpolator.__call__`
         per chunk (a single call on all 2.46M bunny samples made scipy's `_tree.query(x, k)`
         allocate ~2 GB of neighbour indices and distances at once: that peak was the harness's
         doing, not the method's): each call queries the k nearest constraints of
         every sample (cKDTree.query, default workers=1), groups samples with identical
         neighbourhoods, and in a Python loop builds and solves one (k+4)×(k+4) system per
         distinct neighbourhood (LAPACK dgesv) and evaluates it;
       marching cubes = `skimage.measure.marching_cubes(values, level=0, spacing=(h, h, h))`
         (scikit-image's defaults otherwise), vertices shifted to the grid's origin.
     wall s = the sum of the four stages (each also reported), one run without warm-up by
     default (`--scipy-repeat R` > 1: one warm-up, then the upper median of R). What is parallel
     there: nothing in RBFInterpolator takes a thread setting; the KDTree query runs with
     workers=1, the per-neighbourhood loop is Python, and dgesv on (k+4)² matrices is far below
     OpenBLAS's threading threshold; the BLAS-t child is timed anyway, so the report shows it.
     Peak memory = the child's own ru_maxrss (interpreter, numpy, scipy and scikit-image
     included; the resident size before the timed work is recorded as "baseline").
  3. Open3D screened Poisson, per `--depths` value (default 8): `poisson_peers.run_poisson` (the
     same call, settings — Open3D's defaults, `--scale` etc. — and timing: one warm-up, then the
     upper median of `--poisson-repeat` (3) runs of `create_from_point_cloud_poisson` alone,
     n_threads=t), in a child process per (depth, t) so that its peak memory (ru_maxrss, Open3D
     imported; the untimed distance measure of poisson_peers is inside it too) is its own.
     Reading the file and building the PointCloud are not timed.

What is measured on every mesh (here, untimed, the same functions for all):
  - points → mesh: `poisson_peers.Measure` (exact point-to-triangle distance of every input
    point, Open3D RaycastingScene, float32 on centred coordinates), max and mean / the points'
    bounding-box diagonal;
  - mesh → surface, mean / diagonal: for data/bunny_points.ply (1) "sampled", the method of
    mesh_distance.py (every mesh vertex to its nearest of `--scan-samples` area-weighted samples
    of data/bun_zipper.ply, / that scan's diagonal; `mesh_distance.scan_surface`) — it adds up to
    about half the sample spacing (printed; 3.9e-4 of the diagonal at 6,000,000 samples, as large
    as the distances measured), so (2) "exact" is given beside it: every vertex's exact distance
    to the scan's triangles (`poisson_peers.Measure` with the roles swapped); for `--sphere` the
    exact |‖v‖ − 1| over the vertices / the points' diagonal; otherwise not measured;
  - surface → scan (data/bunny_points.ply only): the mean distance of the mesh as a surface, not
    of its vertices: `--surface-samples` (2,000,000) area-weighted samples of the mesh, each
    sample's exact distance to the scan's triangles (RaycastingScene), mean and median / the
    scan's diagonal, and the mean away from the scan's holes (samples within 1% of the diagonal
    of a scan vertex; the rest lie on the caps over the 5 holes in its base, whose area share is
    given). The vertices' mean also weighs how a mesher spreads its vertices: Open3D's adaptive
    octree puts few of them on those caps, zeroset's uniform grid as many as anywhere;
  - vertices, triangles; watertight by edge counting (vertices at identical positions welded,
    triangles with a repeated vertex left out; watertight = every edge in exactly two
    triangles) and the connected components (through shared edges).

Output: the tables printed and written to OUT/<name>.md (markdown, with machine facts and load
averages at each stage) and OUT/<name>.csv; `--json OUT.json` writes every row, the settings
and the facts. <name> = `scan_peers` for the default cloud, `scan_peers_<stem>` for another
cloud, `scan_peers_sphere<N>` for `--sphere N`; meshes and logs go to OUT/<name>/. Ratios =
peer wall time / zeroset wall time (> 1: zeroset faster), one thread each and each at its
fastest. Run on an otherwise idle machine: the sides are timed one after the other.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import common
from common import fmt_e, fmt_ratio, ratio, render_md, render_text

BLAS_NOTE = common.pin_blas_threads(force=True)  # before numpy is imported

import numpy as np  # noqa: E402

DEFAULT_CLOUD = common.REPO / "data" / "bunny_points.ply"
HOLE_GAP = 0.01  # relative to the scan's diagonal: farther than this from every scan vertex = over a hole
SCAN = common.REPO / "data" / "bun_zipper.ply"  # the surface bunny_points.ply was taken from
OFFSET_FRACTION = 0.01  # zeroset's Offset::Auto default: 1% of the bounding-box diagonal
FALLBACK_MARGIN, FALLBACK_CELLS = 0.05, 128  # grid when zeroset's output does not give one


# ---------------------------------------------------------------------------------------------
# arguments


def parse_args() -> argparse.Namespace:
    import poisson_peers  # Open3D: imported only in the parent and the Poisson children

    p = argparse.ArgumentParser(
        description="zeroset reconstruct (RBF) vs scipy RBFInterpolator(neighbors) + marching cubes vs Open3D "
        "screened Poisson on the same oriented point cloud: time, memory, distance, watertightness.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--cloud", default=str(DEFAULT_CLOUD), help="oriented point cloud (x y z nx ny nz, unit normals)")
    src.add_argument("--sphere", type=int, metavar="N", help="N Fibonacci points on the unit sphere, outward normals")
    p.add_argument("--threads", default=f"1,{common.cpu_count()}", help="thread counts, comma-separated (every side)")
    p.add_argument("--neighbors", default="50", help="RBFInterpolator neighbors values, comma-separated")
    p.add_argument("--depths", default="8", help="Open3D Poisson depths, comma-separated ('' = no Poisson)")
    p.add_argument("--grid", type=int, metavar="N",
                   help="scipy's grid: N cells along the longest side of zeroset's box instead of zeroset's grid")  # fmt: skip
    p.add_argument("--eval-chunk", type=int, default=100_000, metavar="N",
                   help="scipy: evaluate the grid in chunks of N samples (one __call__ each)")
    p.add_argument("--halvings", type=int, default=8, help="off-surface offset halvings per side before dropping it")
    p.add_argument("--zeroset-repeat", type=int, default=1,
                   help="zeroset runs per thread count (1: one run, no warm-up; R > 1: warm-up + median of R)")  # fmt: skip
    p.add_argument("--scipy-repeat", type=int, default=1,
                   help="scipy pipeline runs (1: one run, no warm-up; R > 1: warm-up + median of R)")  # fmt: skip
    p.add_argument("--poisson-repeat", type=int, default=3, help="Poisson timed runs after one warm-up")
    p.add_argument("--scan-samples", type=int, default=6_000_000,
                   help="area-weighted samples of bun_zipper.ply for the mesh → scan distance")  # fmt: skip
    p.add_argument("--surface-samples", type=int, default=2_000_000,
                   help="area-weighted samples of each mesh for its surface's mean distance to the scan")  # fmt: skip
    p.add_argument("--no-scipy", action="store_true", help="skip the scipy side")
    p.add_argument("--no-build", action="store_true", help="never run cargo; fail if the zeroset binary is missing")
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the reports, meshes and logs")
    p.add_argument("--json", metavar="OUT.json", help="also write every row, the settings and the facts here")
    poisson_peers.add_poisson_settings(p)
    common.add_blas_arg(p)
    a = p.parse_args()

    a.thread_list = list(dict.fromkeys(common.int_list(p, a.threads, "--threads", 1)))
    a.neighbor_list = [] if a.no_scipy else list(dict.fromkeys(common.int_list(p, a.neighbors, "--neighbors", 5)))
    a.depth_list = list(dict.fromkeys(common.int_list(p, a.depths, "--depths", 2, "depth")))
    if not a.thread_list:
        p.error("--threads is empty")
    for name in ("zeroset_repeat", "scipy_repeat", "poisson_repeat"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if a.grid is not None and a.grid < 2:
        p.error("--grid must be at least 2")
    if a.sphere is not None and a.sphere < 100:
        p.error("--sphere: at least 100 points")
    if a.halvings < 0:
        p.error("--halvings must be >= 0")
    a.out = Path(a.out).resolve()
    if a.sphere is not None:
        a.name = f"scan_peers_sphere{a.sphere}"
    else:
        a.cloud = Path(a.cloud).resolve()
        if not a.cloud.is_file():
            p.error(f"--cloud {a.cloud}: no such file")
        a.name = "scan_peers" if a.cloud == DEFAULT_CLOUD.resolve() else f"scan_peers_{a.cloud.stem}"
    a.dir = a.out / a.name
    return a


# ---------------------------------------------------------------------------------------------
# input


def fibonacci_sphere(n: int) -> np.ndarray:
    """n points on the unit sphere, evenly spread (golden-angle spiral); they are their own normals."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    theta = math.pi * (3.0 - math.sqrt(5.0)) * i
    return np.column_stack([r * np.cos(theta), r * np.sin(theta), z])


def load_cloud(args) -> tuple[Path, np.ndarray, np.ndarray, str]:
    """(the file every side reads, positions, unit normals, a description)."""
    import poisson_peers

    if args.sphere is not None:
        pts = fibonacci_sphere(args.sphere)
        path = args.dir / f"sphere_{args.sphere}.xyzn"
        np.savetxt(path, np.hstack([pts, pts]), fmt="%.17g")
        # read back, so that every side sees the same doubles
        pts, cols, _ = poisson_peers.read_points(path)
        return path, pts, cols, f"{args.sphere:,} Fibonacci points on the unit sphere, outward normals (generated)"
    pts, cols, how = poisson_peers.read_points(args.cloud)
    if cols is None:
        sys.exit(f"{args.cloud}: no normals (columns 4-6); this comparison uses the file's normals on every side")
    lens = np.linalg.norm(cols, axis=1)
    if not (np.all(np.isfinite(cols)) and np.all(np.abs(lens - 1.0) <= poisson_peers.UNIT_TOL)):
        sys.exit(f"{args.cloud}: columns 4-6 are not unit normals (lengths {lens.min():.6g} – {lens.max():.6g})")
    return args.cloud, pts, cols / lens[:, None], f"{pts.shape[0]:,} points ({how})"


# ---------------------------------------------------------------------------------------------
# step 1: zeroset


def zeroset_binary(args) -> tuple[Path, str]:
    """target/release/zeroset (CARGO_TARGET_DIR honoured), built only if missing, then copied to
    OUT/<name>/zeroset, the copy every run uses: a rebuild during this script's run (cargo
    replaces the file) cannot mix two builds. Returns the copy and a description."""
    import hashlib
    import shutil

    target = common.ORIGINAL_ENV.get("CARGO_TARGET_DIR")
    binary = ((common.REPO / target) if target else common.REPO / "target") / "release" / "zeroset"
    if not binary.is_file():
        if args.no_build:
            sys.exit(f"{binary} not found (--no-build)")
        common.run_logged(["cargo", "build", "--release", "-p", "zeroset-cli"])
        if not binary.is_file():
            sys.exit(f"{binary} not found after cargo build (CARGO_TARGET_DIR elsewhere?)")
    copy = args.dir / "zeroset"
    shutil.copy2(binary, copy)
    digest = hashlib.sha256(copy.read_bytes()).hexdigest()[:12]
    built = time.strftime("%Y-%m-%d %H:%M", time.localtime(copy.stat().st_mtime))
    about = f"{binary} built {built}, sha256 {digest}…, run as its copy {copy} (removed afterwards)"
    print(f"zeroset binary: {about}", flush=True)
    return copy, about


def run_process(cmd: list[str], env: dict[str, str], log: Path) -> dict:
    """Runs `cmd` in the repository root, stdout and stderr to `log`; wall time, the child's own
    peak resident size (os.wait4) and CPU time. Exits on failure."""
    prefix = "".join(f"{k}={v} " for k, v in env.items())
    print(f"$ (cd {common.REPO} && {prefix}{' '.join(cmd)}) > {log}", flush=True)
    with log.open("w") as fh:
        t = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=common.REPO, env={**common.ORIGINAL_ENV, **env}, stdout=fh,
                                stderr=subprocess.STDOUT)  # fmt: skip
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        sys.exit(f"exit status {proc.returncode}: {' '.join(cmd)}\n{log.read_text()[-3000:]}")
    return {"wall_s": wall, "peak_mib": ru.ru_maxrss / 1024.0, "cpu_s": ru.ru_utime + ru.ru_stime}


FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_zeroset(text: str) -> dict:
    """The figures `zeroset reconstruct` prints (absent ones are left out)."""
    info: dict = {}

    def grab(key, pattern, conv=float, flags=re.M):
        m = re.search(pattern, text, flags)
        if m:
            info[key] = conv(m.group(1))

    grab("solver", r"^solver:\s+(\S+)", str)
    grab("gmres_steps", r"^iterations:\s+(\d+)", int)
    grab("unknowns", r"^unknowns:\s+(\d+)", int)
    grab("fit_solver_s", rf"^fit time:\s+({FLOAT}) s")
    grab("max_residual", rf"^max residual:\s+({FLOAT})")
    grab("constraints", r"^constraints:\s+(\d+)", int)
    grab("gamma_percent", rf"gamma = N_SMC,P / N_MC = ({FLOAT})%")
    grab("plan", r"^plan:\s+(.*)$", str)
    grab("report", r"^report:\s+(.*)$", str)
    grab("summary_fit_s", rf"^fit\s+({FLOAT}) s")
    grab("summary_mesh_s", rf"^mesh\s+({FLOAT}) s")
    grab("summary_total_s", rf"^total\s+({FLOAT}) s")
    m = re.search(rf"^offset:.*initial ({FLOAT}), smallest ({FLOAT}); (\d+) shrunk, (\d+) dropped", text, re.M)
    if m:
        info["offset"] = {"initial": float(m.group(1)), "smallest": float(m.group(2)),
                          "shrunk": int(m.group(3)), "dropped": int(m.group(4))}  # fmt: skip
    m = re.search(r"over min \(([^)]*)\) max \(([^)]*)\)", text)
    if m:
        info["box_min"] = [float(x) for x in m.group(1).split(",")]
        info["box_max"] = [float(x) for x in m.group(2).split(",")]
    m = re.search(rf"^grid (\d+)×(\d+)×(\d+) = (\d+) samples, voxel ({FLOAT})", text, re.M)
    if m:
        info["grid_counts"] = [int(m.group(i)) for i in (1, 2, 3)]
        info["voxel"] = float(m.group(5))
    m = re.search(r"^mesh:\s+(\d+) vertices, (\d+) triangles", text, re.M)
    if m:
        info["mesh_vertices"], info["mesh_triangles"] = int(m.group(1)), int(m.group(2))
    return info


def run_zeroset(binary: Path, cloud: Path, args) -> list[dict]:
    rows = []
    for t in args.thread_list:
        mesh = args.dir / f"zeroset_rbf_t{t}.ply"
        cmd = [str(binary), "reconstruct", str(cloud), "-o", str(mesh), "--method", "rbf", "--no-preview", "--force"]
        runs = args.zeroset_repeat + (1 if args.zeroset_repeat > 1 else 0)
        res = []
        for i in range(runs):
            res.append(run_process(cmd, {"RAYON_NUM_THREADS": str(t)}, args.dir / f"zeroset_t{t}_run{i}.log"))
        timed = res[1:] if args.zeroset_repeat > 1 else res
        walls = [r["wall_s"] for r in timed]
        last_log = (args.dir / f"zeroset_t{t}_run{runs - 1}.log").read_text()
        info = parse_zeroset(last_log)
        row = {
            "method": "zeroset", "setting": "reconstruct --method rbf", "threads": t,
            "threads_label": f"RAYON_NUM_THREADS={t}", "mesh_path": str(mesh),
            "wall_s": sorted(walls)[len(walls) // 2], "times_s": walls, "runs": args.zeroset_repeat,
            "warmup": args.zeroset_repeat > 1, "peak_mib": max(r["peak_mib"] for r in res),
            "cpu_over_wall": sum(r["cpu_s"] for r in timed) / sum(walls), **info,
        }  # fmt: skip
        rows.append(row)
        print(f"  zeroset, RAYON_NUM_THREADS={t}: {row['wall_s']:.2f} s wall (fit {info.get('summary_fit_s', '?')} s, "
              f"mesh {info.get('summary_mesh_s', '?')} s, GMRES steps {info.get('gmres_steps', '?')}, "
              f"residual {info.get('max_residual', '?')}), peak {row['peak_mib']:.0f} MiB, "
              f"cpu/wall {row['cpu_over_wall']:.2f}", flush=True)  # fmt: skip
    return rows


def grid_spec(zs: dict | None, pts: np.ndarray, cells: int | None) -> dict:
    """The scipy side's sampling grid: zeroset's (box, counts, voxel as printed), or with `cells`
    that many cells along the box's longest side; laid out as zeroset's `voxel::grid_for` does
    (cells = ceil(extent / h), centred on the box, vertex-centred samples)."""
    if zs and "box_min" in zs and "box_max" in zs:
        lo, hi, src = np.array(zs["box_min"]), np.array(zs["box_max"]), "zeroset's field box"
    else:
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        m = FALLBACK_MARGIN * float(np.linalg.norm(hi - lo))
        lo, hi, src = lo - m, hi + m, f"the points' bounding box grown by {FALLBACK_MARGIN:.0%} of its diagonal"
        cells = cells or FALLBACK_CELLS
    extent = hi - lo
    if cells is None and zs and "grid_counts" in zs and "voxel" in zs:
        counts, h = np.array(zs["grid_counts"]), float(zs["voxel"])
        how = f"zeroset's grid ({src}, its sample counts and voxel)"
    else:
        h = float(extent.max()) / cells
        counts = np.ceil(extent / h * (1 - 1e-12)).astype(int) + 1
        how = f"{cells} cells along the longest side of {src}" + (" (--grid)" if zs and "grid_counts" in zs else "")
    centre = (lo + hi) / 2
    origin = centre - 0.5 * (counts - 1) * h
    return {"origin": origin.tolist(), "counts": [int(c) for c in counts], "voxel": h, "how": how,
            "samples": int(np.prod(counts))}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# step 2: scipy (child process)


def off_surface(pts: np.ndarray, nrm: np.ndarray, halvings: int):
    """zeroset's default off-surface constraints (see the module docs): (points, values, report)."""
    from scipy.spatial import cKDTree

    n = pts.shape[0]
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    eps0 = OFFSET_FRACTION * diag
    tree = cKDTree(pts)
    ys, vs = [pts], [np.zeros(n)]
    report = {"initial": eps0, "smallest": eps0, "shrunk": 0, "dropped": 0}
    for side in (1.0, -1.0):
        todo = np.arange(n)
        eps = eps0
        for attempt in range(halvings + 1):
            q = pts[todo] + (side * eps) * nrm[todo]
            dist, idx = tree.query(q)
            own = np.einsum("ij,ij->i", q - pts[todo], q - pts[todo])
            # As near within 0.1% (a near-duplicate sample) counts as the own point, as in zeroset.
            ok = (idx == todo) | (dist * dist >= own * (1.0 - 2e-3))
            if np.any(ok):
                ys.append(q[ok])
                vs.append(np.full(int(ok.sum()), side * eps))
                report["smallest"] = min(report["smallest"], eps)
                if attempt > 0:
                    report["shrunk"] += int(ok.sum())
            todo = todo[~ok]
            if todo.size == 0:
                break
            eps *= 0.5
        report["dropped"] += int(todo.size)
    return np.vstack(ys), np.concatenate(vs), report


def rss_now_mib() -> float:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return math.nan


def scipy_worker(spec: dict) -> dict:
    from scipy.interpolate import RBFInterpolator
    from skimage.measure import marching_cubes

    blas = common.blas_runtime()
    data = np.load(spec["cloud_npz"])
    pts, nrm = data["points"], data["normals"]
    g = spec["grid"]
    origin, counts, h = np.array(g["origin"]), g["counts"], g["voxel"]
    k = spec["neighbors"]
    baseline = rss_now_mib()
    stages: dict = {}

    def pipeline():
        t0 = time.perf_counter()
        y, v, report = off_surface(pts, nrm, spec["halvings"])
        t1 = time.perf_counter()
        interp = RBFInterpolator(y, v, kernel="linear", degree=1, neighbors=k)
        t2 = time.perf_counter()
        axes = [origin[a] + h * np.arange(counts[a]) for a in range(3)]
        xg = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        chunk = spec.get("eval_chunk") or xg.shape[0]
        vol = np.concatenate([interp(xg[i:i + chunk]) for i in range(0, xg.shape[0], chunk)]).reshape(counts)
        del xg
        t3 = time.perf_counter()
        if not (vol.min() < 0.0 < vol.max()):
            raise RuntimeError(f"the field does not change sign on the grid (min {vol.min()}, max {vol.max()})")
        verts, faces, _normals, _values = marching_cubes(vol, level=0.0, spacing=(h, h, h))
        t4 = time.perf_counter()
        stages.update(constraints_s=t1 - t0, fit_s=t2 - t1, grid_eval_s=t3 - t2, marching_cubes_s=t4 - t3,
                      constraints=int(y.shape[0]), offset=report,
                      field_min=float(vol.min()), field_max=float(vol.max()))  # fmt: skip
        return verts + origin, faces

    r = spec["repeat"]
    (verts, faces), ms, times = common.timed(pipeline, r, warmup=r > 1)
    np.savez(spec["mesh_npz"], vertices=verts, triangles=faces.astype(np.int64))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"wall_s": ms / 1e3, "times_s": [t / 1e3 for t in times], "runs": r, "warmup": r > 1, "blas": blas,
            "peak_mib": peak, "baseline_mib": baseline, **stages}  # fmt: skip


def run_scipy(args, cloud_npz: Path, grid: dict) -> list[dict]:
    rows = []
    for k in args.neighbor_list:
        for t in args.thread_list:
            stem = f"scipy_k{k}_t{t}"
            spec = {"kind": "scipy", "cloud_npz": str(cloud_npz), "neighbors": k, "grid": grid,
                    "halvings": args.halvings, "repeat": args.scipy_repeat, "eval_chunk": args.eval_chunk,
                    "mesh_npz": str(args.dir / f"{stem}.npz"), "result": str(args.dir / f"{stem}.json")}  # fmt: skip
            res = child(spec, args.dir / f"{stem}_spec.json", t)
            if res is None:
                continue
            row = {"method": "scipy", "setting": f"RBFInterpolator linear, degree 1, neighbors={k}", "neighbors": k,
                   "threads": t, "threads_label": f"BLAS {t} ({res['blas']})", "mesh_path": spec["mesh_npz"], **res}  # fmt: skip
            rows.append(row)
            print(f"  scipy neighbors={k}, BLAS {t} ({res['blas']}): {row['wall_s']:.2f} s = constraints "
                  f"{res['constraints_s']:.2f} + fit {res['fit_s']:.2f} + grid {res['grid_eval_s']:.2f} + marching "
                  f"cubes {res['marching_cubes_s']:.2f} s; peak {res['peak_mib']:.0f} MiB", flush=True)  # fmt: skip
    return rows


# ---------------------------------------------------------------------------------------------
# step 3: Open3D Poisson (child process)


def poisson_worker(spec: dict) -> dict:
    import open3d as o3d
    import poisson_peers

    data = np.load(spec["cloud_npz"])
    pts = data["points"]
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pcd.normals = o3d.utility.Vector3dVector(data["normals"])
    baseline = rss_now_mib()
    ns = argparse.Namespace(depth_list=[spec["depth"]], thread_list=[spec["threads"]], repeat=spec["repeat"],
                            no_octree_log=True, save_meshes=spec["save_dir"], points=Path(spec["points"]),
                            **spec["settings"])  # fmt: skip
    (row,) = poisson_peers.run_poisson(pcd, poisson_peers.Measure(pts), ns)
    row["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    row["baseline_mib"] = baseline
    return row


def run_poisson(args, cloud: Path, cloud_npz: Path) -> list[dict]:
    settings = {k: getattr(args, k) for k in ("scale", "linear_fit", "full_depth", "samples_per_node", "point_weight")}
    rows = []
    for d in args.depth_list:
        for t in args.thread_list:
            stem = f"poisson_d{d}_t{t}"
            save = args.dir / stem
            spec = {"kind": "poisson", "cloud_npz": str(cloud_npz), "points": str(cloud), "depth": d, "threads": t,
                    "repeat": args.poisson_repeat, "settings": settings, "save_dir": str(save),
                    "result": str(args.dir / f"{stem}.json")}  # fmt: skip
            res = child(spec, args.dir / f"{stem}_spec.json", 1)
            if res is None:
                continue
            rows.append({"method": "Open3D Poisson", "setting": f"depth {d}", "depth": d, "threads": t,
                         "threads_label": f"n_threads={t}", "wall_s": res["median_ms"] / 1e3,
                         "times_s": [x / 1e3 for x in res["times_ms"]], "runs": res["runs"], "warmup": True,
                         "mesh_path": res.get("saved_as"), "peak_mib": res["peak_mib"],
                         "baseline_mib": res["baseline_mib"], "cpu_over_wall": res["cpu_over_wall"],
                         "poisson_row": res})  # fmt: skip
    return rows


# ---------------------------------------------------------------------------------------------
# children


def child(spec: dict, spec_path: Path, blas_threads: int) -> dict | None:
    """Runs this script as `--worker SPEC` with BLAS at `blas_threads`; its result or None."""
    out = Path(spec["result"])
    out.unlink(missing_ok=True)
    spec_path.write_text(json.dumps(spec))
    rc = common.run_child(Path(__file__).resolve(), ["--worker", str(spec_path)], blas_threads)
    if rc != 0 or not out.is_file():
        print(f"warning: the {spec['kind']} child failed (exit {rc}); its row is missing", flush=True)
        return None
    return json.loads(out.read_text())


def worker_main(spec_path: str) -> None:
    spec = json.loads(Path(spec_path).read_text())
    res = scipy_worker(spec) if spec["kind"] == "scipy" else poisson_worker(spec)
    Path(spec["result"]).write_text(json.dumps(common.jsonable(res)))


# ---------------------------------------------------------------------------------------------
# measuring


def read_mesh(path: str) -> tuple[np.ndarray, np.ndarray]:
    if path.endswith(".npz"):
        d = np.load(path)
        return d["vertices"].astype(np.float64), d["triangles"].astype(np.int64)
    import open3d as o3d
    import poisson_peers

    return poisson_peers.mesh_arrays(o3d.io.read_triangle_mesh(path))


def topology(verts: np.ndarray, tris: np.ndarray) -> dict:
    """Edge counts after welding identical positions and leaving out triangles with a repeated
    vertex: watertight = every edge in exactly two triangles; components through shared edges."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if tris.shape[0] == 0:
        return {"watertight": False, "boundary_edges": 0, "nonmanifold_edges": 0, "components": 0,
                "degenerate_triangles": 0, "welded_vertices": 0}  # fmt: skip
    uniq, inv = np.unique(verts, axis=0, return_inverse=True)
    t = inv.reshape(-1)[tris]
    keep = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])
    t = t[keep]
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    keys, counts = np.unique(e[:, 0] * len(uniq) + e[:, 1], return_counts=True)
    nv = len(uniq)
    a, b = keys // nv, keys % nv
    graph = coo_matrix((np.ones(len(keys)), (a, b)), shape=(nv, nv))
    _, labels = connected_components(graph, directed=False)
    used = np.unique(t)
    boundary, nonmanifold = int(np.sum(counts == 1)), int(np.sum(counts > 2))
    return {
        "watertight": boundary == 0 and nonmanifold == 0 and len(t) > 0,
        "boundary_edges": boundary, "nonmanifold_edges": nonmanifold,
        "components": int(len(np.unique(labels[used]))), "degenerate_triangles": int(np.sum(~keep)),
        "welded_vertices": int(verts.shape[0] - nv),
        "euler_characteristic": int(len(used) - len(keys) + len(t)),
    }  # fmt: skip


class Measurer:
    def __init__(self, pts: np.ndarray, args, cloud: Path) -> None:
        import poisson_peers

        self.points = poisson_peers.Measure(pts)
        self.diag = self.points.diag
        self.surface = None
        self.surface_note = "not measured (no reference surface for this cloud)"
        if args.sphere is not None:
            self.surface = "sphere"
            self.surface_note = ("mesh vertices → the unit sphere, exact: mean |‖v‖ − 1| / the points' diagonal "
                                 "(no sampled figure)")  # fmt: skip
        elif cloud.resolve() == DEFAULT_CLOUD.resolve() and SCAN.is_file():
            import mesh_distance
            import open3d as o3d
            from scipy.spatial import cKDTree

            t = time.perf_counter()
            self.tree, self.scan_diag, spacing = mesh_distance.scan_surface(SCAN, args.scan_samples)
            self.scan_v, self.scan_f = mesh_distance.read_ply(SCAN)
            # The surface's mean distance: each mesh sampled uniformly by area, each sample's exact
            # distance to the scan's triangles (centred float32, as poisson_peers.Measure). A mesh
            # is a surface; its vertices' mean also weighs how a mesher spreads its vertices (an
            # adaptive octree puts few where the scan has no points: on the caps of its holes).
            used = self.scan_v[np.unique(self.scan_f)]
            self.scan_centre = (used.min(axis=0) + used.max(axis=0)) / 2
            self.scan_scene = o3d.t.geometry.RaycastingScene()
            self.scan_scene.add_triangles(o3d.core.Tensor((self.scan_v - self.scan_centre).astype(np.float32)),
                                          o3d.core.Tensor(np.ascontiguousarray(self.scan_f, dtype=np.uint32)))  # fmt: skip
            self.scan_vertices = cKDTree(used)
            self.surface_samples = args.surface_samples
            self.mesh_distance = mesh_distance
            self.o3d = o3d
            self.surface = "scan"
            self.surface_note = (
                f"mesh vertices → {SCAN.name}'s surface, mean / the scan's diagonal {self.scan_diag:.6g} (the points' "
                f"diagonal: {self.diag:.6g}); sampled = mesh_distance.py's method (each vertex to the nearest of "
                f"{args.scan_samples:,} area-weighted samples of the scan, seed 1; sample spacing "
                f"{spacing / self.scan_diag:.1e} of the diagonal, so the figure is the distance plus up to about half "
                f"that; k-d tree built in {time.perf_counter() - t:.1f} s); exact = each vertex's exact distance to the "
                f"scan's triangles (poisson_peers.Measure with the roles swapped: RaycastingScene of the scan, float32); "
                f"surface = the mesh's surface: {args.surface_samples:,} area-weighted samples of the mesh (seed 1), each "
                f"sample's exact distance to the scan's triangles, mean / the scan's diagonal; 'away from holes' leaves "
                f"out the samples farther than {HOLE_GAP:g} of the diagonal from every scan vertex (the caps over the "
                f"scan's 5 holes, where no surface was scanned), whose share of the area is given"
            )

    def __call__(self, verts: np.ndarray, tris: np.ndarray) -> dict:
        acc = self.points(verts, tris)
        res = {"vertices": int(verts.shape[0]), "triangles": int(tris.shape[0]),
               "max_rel": acc["max_rel"], "mean_rel": acc["mean_rel"], "p99_rel": acc["p99_rel"],
               "max_at_point": acc["max_at_point"], **topology(verts, tris)}  # fmt: skip
        res["surface_mean_rel"] = res["surface_exact_mean_rel"] = math.nan
        if self.surface == "scan" and verts.shape[0]:
            import poisson_peers

            d = self.tree.query(verts)[0] / self.scan_diag
            exact = poisson_peers.Measure(verts)(self.scan_v, self.scan_f)
            res.update(surface_mean_rel=float(d.mean()), surface_max_rel=float(d.max()),
                       surface_exact_mean_rel=exact["mean_abs"] / self.scan_diag,
                       surface_exact_max_rel=exact["max_abs"] / self.scan_diag)  # fmt: skip
            samples, _ = self.mesh_distance.surface_samples(verts, tris, self.surface_samples)
            q = self.o3d.core.Tensor((samples - self.scan_centre).astype(np.float32))
            ds = self.scan_scene.compute_distance(q).numpy().astype(np.float64) / self.scan_diag
            holes = self.scan_vertices.query(samples)[0] > HOLE_GAP * self.scan_diag
            res.update(area_mean_rel=float(ds.mean()), area_median_rel=float(np.median(ds)),
                       area_away_mean_rel=float(ds[~holes].mean()), hole_area_share=float(holes.mean()))  # fmt: skip
        elif self.surface == "sphere" and verts.shape[0]:
            d = np.abs(np.linalg.norm(verts, axis=1) - 1.0) / self.diag
            res.update(surface_exact_mean_rel=float(d.mean()), surface_exact_max_rel=float(d.max()))
        return res


# ---------------------------------------------------------------------------------------------
# tables


def fmt_s(row: dict) -> str:
    return f"{common.fmt_ms(row['wall_s'])} ({common.how_timed(row['runs'], row['warmup'])})"


def fmt_mib(v) -> str:
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.0f}"


MAIN_HEADER = ["method", "setting", "threads", "wall s", "peak MiB", "points→mesh max/diag", "mean/diag",
               "vertices→scan mean/diag (sampled)", "vertices→scan mean/diag (exact)",
               "surface→scan mean/diag (area samples, exact)", "median", "away from holes (hole area share)",
               "vertices", "triangles", "watertight", "components"]  # fmt: skip


def main_table(rows: list[dict]) -> list[list[str]]:
    body = []
    for r in rows:
        body.append([r["method"], r["setting"], r["threads_label"], fmt_s(r), fmt_mib(r.get("peak_mib")),
                     fmt_e(r.get("max_rel")), fmt_e(r.get("mean_rel")), fmt_e(r.get("surface_mean_rel")),
                     fmt_e(r.get("surface_exact_mean_rel")), fmt_e(r.get("area_mean_rel")),
                     fmt_e(r.get("area_median_rel")),
                     f"{fmt_e(r.get('area_away_mean_rel'))} ({r['hole_area_share']:.2%})" if "hole_area_share" in r else "—",
                     f"{r['vertices']:,}" if "vertices" in r else "—",
                     f"{r['triangles']:,}" if "triangles" in r else "—",
                     ("yes" if r["watertight"] else f"no ({r['boundary_edges']} boundary, "
                      f"{r['nonmanifold_edges']} non-manifold edges)") if "watertight" in r else "—",
                     str(r.get("components", "—"))])  # fmt: skip
    return body


def ratio_table(zs: list[dict], peers: list[dict]):
    header = ["peer", "setting", "one thread each", "each at its fastest", "peer config (fastest)",
              "zeroset config (fastest)"]  # fmt: skip
    body = []
    zs_by_t = {r["threads"]: r["wall_s"] for r in zs}
    zbest_label, zbest = common.fastest({r["threads_label"]: r["wall_s"] for r in zs})
    groups: dict = {}
    for r in peers:
        groups.setdefault((r["method"], r["setting"]), []).append(r)
    for (method, setting), rs in groups.items():
        one = next((r["wall_s"] for r in rs if r["threads"] == 1), None)
        plabel, pbest = common.fastest({r["threads_label"]: r["wall_s"] for r in rs})
        body.append([method, setting, fmt_ratio(ratio(one, zs_by_t.get(1))), fmt_ratio(ratio(pbest, zbest)),
                     plabel or "—", zbest_label or "—"])  # fmt: skip
    return header, body


def zeroset_table(zs: list[dict]):
    header = ["threads", "wall s", "cpu/wall", "fit s", "(solver s)", "mesh s", "solver", "GMRES steps",
              "max residual", "constraints", "offsets shrunk / dropped / smallest", "grid", "γ = SMC evals / MC",
              "FMM operators"]  # fmt: skip
    body = []
    for r in zs:
        off = r.get("offset")
        plan = r.get("plan", "")
        body.append([
            r["threads_label"], fmt_s(r), f"{r['cpu_over_wall']:.2f}", common.fmt_ms(r.get("summary_fit_s")),
            common.fmt_ms(r.get("fit_solver_s")), common.fmt_ms(r.get("summary_mesh_s")), r.get("solver", "—"),
            str(r.get("gmres_steps", "—")), fmt_e(r.get("max_residual")), f"{r.get('constraints', 0):,}",
            f"{off['shrunk']} / {off['dropped']} / {off['smallest']:.4g}" if off else "—",
            ("×".join(map(str, r["grid_counts"])) + f", voxel {r['voxel']:.4g}") if "grid_counts" in r else "—",
            f"{r['gamma_percent']:.2f}%" if "gamma_percent" in r else "—",
            "disk cache" if "disk cache" in plan else ("built" if plan else "?"),
        ])  # fmt: skip
    return header, body


def scipy_table(sp: list[dict]):
    header = ["neighbors", "threads", "wall s", "constraints s", "fit s", "grid eval s", "marching cubes s",
              "constraints", "offsets shrunk / dropped / smallest", "baseline MiB", "peak MiB"]  # fmt: skip
    body = []
    for r in sp:
        off = r["offset"]
        body.append([str(r["neighbors"]), r["threads_label"], fmt_s(r), f"{r['constraints_s']:.2f}",
                     f"{r['fit_s']:.2f}", f"{r['grid_eval_s']:.2f}", f"{r['marching_cubes_s']:.2f}",
                     f"{r['constraints']:,}", f"{off['shrunk']} / {off['dropped']} / {off['smallest']:.4g}",
                     fmt_mib(r["baseline_mib"]), fmt_mib(r["peak_mib"])])  # fmt: skip
    return header, body


def poisson_table(po: list[dict]):
    header = ["depth", "threads", "Poisson call s", "runs (ms)", "cpu/wall", "baseline MiB", "peak MiB"]
    body = [[str(r["depth"]), r["threads_label"], fmt_s(r), ", ".join(f"{x * 1e3:.0f}" for x in r["times_s"]),
             f"{r['cpu_over_wall']:.2f}", fmt_mib(r["baseline_mib"]), fmt_mib(r["peak_mib"])] for r in po]  # fmt: skip
    return header, body


def write_csv(path: Path, rows: list[dict]) -> None:
    cols = ["method", "setting", "threads", "threads_label", "wall_s", "runs", "warmup", "peak_mib", "max_rel",
            "mean_rel", "surface_mean_rel", "surface_exact_mean_rel", "area_mean_rel", "area_median_rel",
            "area_away_mean_rel", "hole_area_share", "vertices", "triangles", "watertight", "boundary_edges",
            "nonmanifold_edges", "components", "mesh_path"]  # fmt: skip
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([common.num(r.get(c)) if isinstance(r.get(c), float) else r.get(c, "") for c in cols])


# ---------------------------------------------------------------------------------------------


def main() -> None:
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--worker")
    known, _ = pre.parse_known_args()
    if known.worker:
        worker_main(known.worker)
        return

    args = parse_args()
    import open3d as o3d
    import skimage

    args.dir.mkdir(parents=True, exist_ok=True)
    loads = [("load average 1/5/15 min, at start", common.loadavg())]
    print(f"BLAS threads: {BLAS_NOTE} ({common.blas_runtime()}); threads {args.thread_list}; CPUs "
          f"{common.cpu_count()}; load average {loads[0][1]}", flush=True)  # fmt: skip
    cloud, pts, nrm, described = load_cloud(args)
    cloud_npz = args.dir / "cloud.npz"
    np.savez(cloud_npz, points=pts, normals=nrm)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    print(f"cloud {cloud}: {described}; bbox diagonal {diag:.6g}", flush=True)

    print("\n== 1. zeroset reconstruct --method rbf (whole process)", flush=True)
    binary, binary_about = zeroset_binary(args)
    try:
        zs = run_zeroset(binary, cloud, args)
    finally:
        binary.unlink(missing_ok=True)  # the copy (77 MB); its sha256 is recorded
    loads.append(("load average 1/5/15 min, after zeroset", common.loadavg()))

    grid = grid_spec(zs[0] if zs else None, pts, args.grid)
    sp: list[dict] = []
    if args.neighbor_list:
        print(f"\n== 2. scipy RBFInterpolator(neighbors) + skimage marching_cubes; grid {grid['how']}: "
              f"{'×'.join(map(str, grid['counts']))} = {grid['samples']:,} samples, voxel {grid['voxel']:.6g}",
              flush=True)  # fmt: skip
        sp = run_scipy(args, cloud_npz, grid)
        loads.append(("load average 1/5/15 min, after scipy", common.loadavg()))
    po: list[dict] = []
    if args.depth_list:
        print("\n== 3. Open3D screened Poisson (poisson_peers.run_poisson)", flush=True)
        po = run_poisson(args, cloud, cloud_npz)
        loads.append(("load average 1/5/15 min, after Poisson", common.loadavg()))

    print("\n== measuring every mesh (untimed)", flush=True)
    measure = Measurer(pts, args, cloud)
    rows = zs + sp + po
    for r in rows:
        if not r.get("mesh_path"):
            continue
        verts, tris = read_mesh(r["mesh_path"])
        r.update(measure(verts, tris))
        print(f"  {r['method']} {r['setting']} {r['threads_label']}: {r['vertices']:,} vertices, max/diag "
              f"{r['max_rel']:.3e}, mean/diag {r['mean_rel']:.3e}, vertices→scan mean {fmt_e(r['surface_mean_rel'])} sampled, {fmt_e(r['surface_exact_mean_rel'])} exact, "
              f"surface→scan mean {fmt_e(r.get('area_mean_rel'))}, "
              f"watertight {r['watertight']}, {r['components']} component(s)", flush=True)  # fmt: skip
    if args.neighbor_list:  # a viewable copy of scipy's meshes
        for r in sp:
            v, t = read_mesh(r["mesh_path"])
            m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v), o3d.utility.Vector3iVector(t.astype(np.int32)))
            o3d.io.write_triangle_mesh(r["mesh_path"].replace(".npz", ".ply"), m, write_ascii=False)

    title = f"{cloud.name if args.sphere is None else f'sphere, {args.sphere:,} points'}: scan → mesh"
    notes = [
        f"Input: `{cloud.relative_to(common.REPO) if cloud.is_relative_to(common.REPO) else cloud}`, {described}; "
        f"bounding-box diagonal {diag:.6g}.",
        "wall s: zeroset = the whole `zeroset reconstruct … --method rbf --no-preview --force` process; scipy = "
        "constraints + RBFInterpolator + evaluation on the grid + marching cubes (in-process, file reading "
        "excluded); Open3D = the `create_from_point_cloud_poisson` call alone (poisson_peers.py's rule).",
        f"Different amounts of work: the scipy pipeline evaluates its local interpolant at every sample of the grid "
        f"({grid['samples']:,}; in chunks of {args.eval_chunk:,}), while zeroset's signed marching cubes evaluate "
        "the field near the surface only (a coarse pass, then the cells the zero set crosses); the meshes are "
        "compared below, the work is not the same.",
        "peak MiB: each configuration's own process (ru_maxrss): zeroset's process; the scipy / Open3D child "
        "(interpreter and imports included; the resident size before the work is the baseline below).",
        f"scipy grid: {grid['how']}, {'×'.join(map(str, grid['counts']))} = {grid['samples']:,} samples, voxel "
        f"{grid['voxel']:.6g}" + (" — LOWER than zeroset's (--grid)." if args.grid else "."),
        f"points→mesh: every input point to the mesh (exact, Open3D RaycastingScene), / the points' diagonal. "
        f"mesh→surface: {measure.surface_note}.",
        "watertight: by edge counting (identical positions welded, triangles with a repeated vertex left out); "
        "components through shared edges.",
    ]
    zsh, zsb = zeroset_table(zs)
    rh, rb = ratio_table(zs, sp + po)
    body = main_table(rows)
    print(f"\n=== {title} ===\n" + render_text(MAIN_HEADER, body, left=3))
    print(f"\n=== peer wall time ÷ zeroset wall time (> 1: zeroset faster) ===\n{render_text(rh, rb, left=2)}")
    print(f"\n=== zeroset stages (from its summary) ===\n{render_text(zsh, zsb, left=1)}")
    lines = [f"## {title}", "", *[f"- {n}" for n in notes], "", render_md(MAIN_HEADER, body, left=3), "",
             "### Ratios: peer wall time ÷ zeroset wall time (> 1: zeroset faster)", "", render_md(rh, rb, left=2), "",
             "### zeroset stages (from its summary)", "", render_md(zsh, zsb, left=1), ""]  # fmt: skip
    if zs and sp:
        z_off = zs[0].get("offset")
        s_off = sp[0]["offset"]
        same = z_off and all(z_off[k] == s_off[k] for k in ("shrunk", "dropped"))
        lines += [f"Off-surface constraints: zeroset {z_off['shrunk']} shrunk / {z_off['dropped']} dropped, smallest "
                  f"{z_off['smallest']:.7g}; the scipy side's {s_off['shrunk']} / {s_off['dropped']}, smallest "
                  f"{s_off['smallest']:.7g}" + (" (the same)." if same else " (they differ).") if z_off else
                  "zeroset printed no offset report.", ""]  # fmt: skip
    if sp:
        h, b = scipy_table(sp)
        print(f"\n=== scipy stages ===\n{render_text(h, b, left=2)}")
        lines += ["### scipy stages", "", render_md(h, b, left=2), ""]
    if po:
        h, b = poisson_table(po)
        print(f"\n=== Open3D Poisson ===\n{render_text(h, b, left=2)}")
        lines += ["### Open3D screened Poisson (Open3D's default settings, no density trimming)", "",
                  render_md(h, b, left=2), ""]  # fmt: skip
    for n in notes:
        print(f"note: {n}")

    loads.append(("load average 1/5/15 min, at end", common.loadavg()))
    facts = common.machine_facts(loads, [
        ("open3d", o3d.__version__), ("scikit-image", skimage.__version__),
        ("zeroset binary", binary_about),
        ("BLAS (parent)", f"{BLAS_NOTE} ({common.blas_runtime()})"),
    ])  # fmt: skip
    csv_path, md_path = args.out / f"{args.name}.csv", args.out / f"{args.name}.md"
    write_csv(csv_path, rows)
    common.write_report(md_path, csv_path, lines, facts)
    if args.json:
        doc = {"script": "benches/peers/scan_peers.py", "argv": sys.argv[1:], "cloud": str(cloud), "points": int(len(pts)),
               "bbox_diagonal": diag, "grid": grid, "notes": notes, "rows": rows, "machine": dict(facts)}  # fmt: skip
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(common.jsonable(doc), indent=1) + "\n")
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
