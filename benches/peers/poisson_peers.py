#!/usr/bin/env python3
"""Peer comparison: Open3D's screened Poisson reconstruction on an oriented point cloud, measured
the same way as any other mesh (e.g. one written by `zeroset mesh` after zeroset's MRAS fit).

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh --open3d
    benches/peers/.venv/bin/python benches/peers/poisson_peers.py data/bunny_points.ply --depths 6,7,8,9,10
    benches/peers/.venv/bin/python benches/peers/poisson_peers.py data/kitten.xyz --depths 6,7,8,9
    benches/peers/.venv/bin/python benches/peers/poisson_peers.py data/bunny_points.ply --depths '' \\
        --measure out/bunny_mras.ply           # measure other meshes only

Input: an oriented point cloud, PLY with `x y z nx ny nz` (ascii or binary, read by Open3D) or
whitespace text with 6 columns `x y z nx ny nz` (.xyz/.xyzn/.txt/.pts; 3 columns = positions
only). Columns 4-6 are used as normals only if every row has a finite length within 1e-3 of 1
(Open3D normalises them anyway); otherwise, or with `--estimate-normals`, the script says so and
estimates them with Open3D (`estimate_normals`, k nearest neighbours, then
`orient_normals_consistent_tangent_plane(k)`, then flipped as a whole if most point towards the
centroid) and reports it.

For each `--depths` value d: `open3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd,
depth=d, width=0, scale=1.1, linear_fit=False, n_threads=t, full_depth=5, samples_per_node=1.5,
point_weight=2.0)` (Open3D's defaults; `--scale`, `--linear-fit`, ... change them), for each t in
`--threads` (default 1 and the CPUs available): one warm-up, then the median of `--repeat` runs
(the upper median, `common.timed`). Only that call is timed (building the PointCloud and reading
the file are not). Open3D passes `n_threads` to Kazhdan's ThreadPool, which runs the parallel
loops of the reconstruction. The process CPU time of each run is recorded too: its median
("process CPU ms") and CPU ÷ wall over the timed runs ("cpu/wall") check the threads actually
used, and on a busy machine a one-thread run's CPU time (cpu/wall well below 1 means it waited
for a core) is the better guide to its idle-machine time. No density trimming: the mesh is
Poisson's closed surface as returned.

Storage: Open3D returns only the mesh, so the mesh is what is stored: 3·vertices + 3·triangles
numbers. Open3D's API does not expose the octree node count that the screened-Poisson papers
count; its debug log prints it, and unless `--no-octree-log` one extra, untimed 1-thread run per
depth at Debug verbosity is captured to read "Leaf Nodes / Active Nodes" and the per-level
"Nodes:" counts of the solver (their sum = the unknowns solved for; the deepest level with any =
"solved to": the octree adapts to the sampling density, so a depth is only an upper bound);
shown for reference only.

Accuracy: the distance from every input point to the mesh (exact point-to-triangle distance,
`open3d.t.geometry.RaycastingScene.compute_distance`, float32, on coordinates centred on the
points' bounding-box centre), reported as max and mean over the points divided by the input
points' bounding-box diagonal. One-sided (points → mesh): surface far from every point (e.g.
Poisson closing a scan's holes) is not penalised. `--measure MESH.ply ...` measures any other
mesh (read with `open3d.io.read_triangle_mesh`) against the same points with the same function.

`--json OUT.json` writes every row (each thread configuration separately) with the settings and
the machine facts; a readable table is always printed. `--target-max E` reports the smallest
depth whose max relative distance is ≤ E (and its mean), and which measured meshes reach E.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import common
from common import fmt_e, fmt_int, fmt_ms, render_text

import numpy as np  # noqa: E402

try:
    import open3d as o3d  # noqa: E402
except ImportError as e:
    hint = (
        "\n(the wheel needs the system library libusb-1.0: apt-get install libusb-1.0-0)"
        if "libusb" in str(e)
        else ""
    )
    sys.exit(
        f"cannot import open3d: {e}{hint}\n"
        f"install it with: bash {common.HERE / 'setup.sh'} --open3d  (requirements-open3d.txt)"
    )

TEXT_SUFFIXES = {".xyz", ".xyzn", ".txt", ".pts"}
UNIT_TOL = 1e-3  # normals are used as given if every length is within this of 1
DEFAULT_POINTS = common.REPO / "data" / "bunny_points.ply"


def add_poisson_settings(p: argparse.ArgumentParser) -> None:
    """The Poisson settings `poisson` reads (`--scale`, `--linear-fit`, `--full-depth`,
    `--samples-per-node`, `--point-weight`; defaults = Open3D's); also used by scan_peers.py."""
    g = p.add_argument_group("Poisson settings (defaults = Open3D's)")
    g.add_argument("--scale", type=float, default=1.1, help="reconstruction cube diameter / samples' bounding cube")
    g.add_argument("--linear-fit", action="store_true", help="linear interpolation for the iso-vertices")
    g.add_argument("--full-depth", type=int, default=5, help="depth up to which the octree is complete")
    g.add_argument("--samples-per-node", type=float, default=1.5, help="minimum samples per octree node")
    g.add_argument("--point-weight", type=float, default=2.0, help="screening weight (0 = unscreened Poisson)")


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Open3D screened Poisson vs any mesh: time, mesh size and point-to-mesh distance.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("points", nargs="?", default=str(DEFAULT_POINTS),
                   help="oriented point cloud: .ply with x y z nx ny nz, or text x y z nx ny nz (.xyz/.xyzn/.txt/.pts)")  # fmt: skip
    p.add_argument("--depths", default="6,7,8,9,10", help="Poisson octree depths, comma-separated ('' = none)")
    p.add_argument("--threads", default=f"1,{common.cpu_count()}",
                   help="n_threads values to time, comma-separated (1 and the CPUs available)")  # fmt: skip
    p.add_argument("--repeat", type=int, default=3, help="timed runs after one warm-up (median reported)")
    p.add_argument("--measure", nargs="+", default=[], metavar="MESH",
                   help="other meshes (e.g. from `zeroset mesh`) to measure against the same points")  # fmt: skip
    p.add_argument("--json", metavar="OUT.json", help="write every row, the settings and the machine facts here")
    p.add_argument("--target-max", type=float, metavar="E",
                   help="report the smallest depth whose max distance / diagonal is <= E")  # fmt: skip
    p.add_argument("--save-meshes", metavar="DIR",
                   help="write each depth's 1-thread Poisson mesh to DIR/poisson_{stem}_d{depth}.ply")  # fmt: skip
    p.add_argument("--no-octree-log", action="store_true",
                   help="skip the extra untimed Debug-verbosity run per depth that reads the octree node count")  # fmt: skip
    p.add_argument("--estimate-normals", action="store_true",
                   help="estimate and orient normals with Open3D even if the file has unit normals")  # fmt: skip
    p.add_argument("--normal-knn", type=int, default=30, help="k nearest neighbours for estimated normals")
    add_poisson_settings(p)
    a = p.parse_args()

    a.depth_list = common.int_list(p, a.depths, "--depths", 2, "depth")
    a.thread_list = list(dict.fromkeys(common.int_list(p, a.threads, "--threads", 1)))
    if not a.depth_list and not a.measure:
        p.error("nothing to do: --depths is empty and no --measure")
    if a.depth_list and not a.thread_list:
        p.error("--threads is empty")
    if a.repeat < 1:
        p.error("--repeat must be >= 1")
    if a.normal_knn < 3:
        p.error("--normal-knn must be >= 3")
    a.points = Path(a.points)
    if not a.points.is_file():
        p.error(f"{a.points}: no such file")
    for m in a.measure:
        if not Path(m).is_file():
            p.error(f"--measure {m}: no such file")
    return a


# ---------------------------------------------------------------------------------------------
# input


def read_points(path: Path) -> tuple[np.ndarray, np.ndarray | None, str]:
    """(positions (n, 3) float64, columns 4-6 or None, a description)."""
    if path.suffix.lower() in TEXT_SUFFIXES:
        try:
            a = np.loadtxt(path, dtype=np.float64, ndmin=2)
        except ValueError as e:
            sys.exit(f"{path}: cannot read as whitespace-separated numbers: {e}")
        if a.shape[1] not in (3, 6):
            sys.exit(f"{path}: {a.shape[1]} columns; expected 3 (x y z) or 6 (x y z nx ny nz)")
        cols = a[:, 3:6] if a.shape[1] == 6 else None
        return a[:, :3].copy(), None if cols is None else cols.copy(), f"text, {a.shape[1]} columns"
    pcd = o3d.io.read_point_cloud(str(path))
    pts = np.asarray(pcd.points, dtype=np.float64)
    if pts.shape[0] == 0:
        sys.exit(f"{path}: Open3D read no points")
    nrm = np.asarray(pcd.normals, dtype=np.float64).copy() if pcd.has_normals() else None
    return pts.copy(), nrm, f"{path.suffix.lstrip('.') or '?'} read by Open3D" + ("" if nrm is not None else ", no normals")


def outward_fraction(pts: np.ndarray, nrm: np.ndarray) -> float:
    """Share of normals pointing away from the centroid (a rough orientation check)."""
    return float(np.mean(np.einsum("ij,ij->i", pts - pts.mean(axis=0), nrm) > 0))


def oriented_cloud(pts: np.ndarray, cols: np.ndarray | None, args) -> tuple[o3d.geometry.PointCloud, dict]:
    """The Open3D point cloud Poisson runs on, and a record of where its normals came from."""
    info: dict = {"points": int(pts.shape[0])}
    use_given = False
    if cols is None:
        info["columns_4_6"] = "absent"
    else:
        lens = np.linalg.norm(cols, axis=1)
        finite = bool(np.all(np.isfinite(cols)))
        info["columns_4_6"] = {
            "finite": finite,
            "min_length": float(np.nanmin(lens)),
            "max_length": float(np.nanmax(lens)),
            "unit_within": UNIT_TOL,
        }
        unit = finite and bool(np.all(np.abs(lens - 1.0) <= UNIT_TOL))
        info["columns_4_6"]["unit"] = unit
        use_given = unit and not args.estimate_normals
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    if use_given:
        pcd.normals = o3d.utility.Vector3dVector(cols)
        info["normals"] = "from the file (unit length)"
    else:
        why = ("--estimate-normals" if cols is not None and info["columns_4_6"]["unit"]
               else "the file has no normals" if cols is None
               else "columns 4-6 are not unit normals")  # fmt: skip
        t = time.perf_counter()
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=args.normal_knn))
        pcd.orient_normals_consistent_tangent_plane(args.normal_knn)
        nrm = np.asarray(pcd.normals)
        flipped = outward_fraction(pts, nrm) < 0.5
        if flipped:
            pcd.normals = o3d.utility.Vector3dVector(-nrm)
        info["normals"] = (
            f"ESTIMATED with Open3D ({why}): estimate_normals(KNN {args.normal_knn}), "
            f"orient_normals_consistent_tangent_plane({args.normal_knn})"
            + (", then all flipped (most pointed towards the centroid)" if flipped else "")
            + f"; {time.perf_counter() - t:.1f} s"
        )
    info["outward_from_centroid"] = outward_fraction(pts, np.asarray(pcd.normals))
    return pcd, info


# ---------------------------------------------------------------------------------------------
# measuring


class Measure:
    """Distance from the input points to a triangle mesh, relative to the points' bbox diagonal."""

    def __init__(self, pts: np.ndarray) -> None:
        self.pts = pts
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self.centre = (lo + hi) / 2
        self.diag = float(np.linalg.norm(hi - lo))
        q = (pts - self.centre).astype(np.float32)
        self.query = o3d.core.Tensor(q)
        # float32 spacing of the largest centred coordinate, relative to the diagonal
        self.f32_resolution = float(np.abs(q).max()) * 2.0**-23 / self.diag

    def __call__(self, verts: np.ndarray, tris: np.ndarray) -> dict:
        if tris.shape[0] == 0:
            return {"max_rel": math.nan, "mean_rel": math.nan, "median_rel": math.nan, "p99_rel": math.nan,
                    "rms_rel": math.nan, "max_abs": math.nan, "mean_abs": math.nan, "max_at_point": None}  # fmt: skip
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor((verts - self.centre).astype(np.float32)),
                            o3d.core.Tensor(np.ascontiguousarray(tris, dtype=np.uint32)))  # fmt: skip
        d = scene.compute_distance(self.query).numpy().astype(np.float64)
        return {
            "max_rel": float(d.max()) / self.diag,
            "mean_rel": float(d.mean()) / self.diag,
            "median_rel": float(np.median(d)) / self.diag,
            "p99_rel": float(np.percentile(d, 99)) / self.diag,
            "rms_rel": float(np.sqrt(np.mean(d * d))) / self.diag,
            "max_abs": float(d.max()),
            "mean_abs": float(d.mean()),
            "max_at_point": self.pts[int(np.argmax(d))].tolist(),
        }


def mesh_arrays(mesh: o3d.geometry.TriangleMesh) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.triangles, dtype=np.int64)


# ---------------------------------------------------------------------------------------------
# Open3D Poisson


def poisson(pcd, depth: int, threads: int, args):
    return o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        pcd, depth=depth, width=0, scale=args.scale, linear_fit=args.linear_fit, n_threads=threads,
        full_depth=args.full_depth, samples_per_node=args.samples_per_node, point_weight=args.point_weight,
    )  # fmt: skip


def captured_stdout(fn):
    """Runs fn() with file descriptor 1 redirected to a temporary file (Open3D's C++ log writes
    there); returns (fn's result, the captured text)."""
    libc = ctypes.CDLL(None)
    sys.stdout.flush()
    libc.fflush(None)
    saved = os.dup(1)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 1)
        try:
            out = fn()
        finally:
            libc.fflush(None)
            os.dup2(saved, 1)
            os.close(saved)
        tmp.seek(0)
        return out, tmp.read().decode(errors="replace")


def octree_counts(pcd, depth: int, args) -> tuple[dict, tuple[int, int]]:
    """Leaf / active octree nodes and the solver's unknowns per depth, from one untimed 1-thread
    run at Debug verbosity; plus that run's (vertices, triangles) for a consistency check."""
    old = o3d.utility.get_verbosity_level()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Debug)
    try:
        (mesh, _dens), log = captured_stdout(lambda: poisson(pcd, depth, 1, args))
    finally:
        o3d.utility.set_verbosity_level(old)
    counts: dict = {}
    m = re.search(r"Leaf Nodes / Active Nodes / Ghost Nodes:\s*(\d+)\s*/\s*(\d+)\s*/\s*(\d+)", log)
    if m:
        counts["octree_leaf_nodes"], counts["octree_active_nodes"], counts["octree_ghost_nodes"] = map(int, m.groups())
    per_depth = {int(a): int(n) for a, n in re.findall(r"Depth\[\s*(\d+)\s*/\s*\d+\]:.*?Nodes:\s*(\d+)", log)}
    if per_depth:
        counts["solver_unknowns_per_depth"] = [per_depth[k] for k in sorted(per_depth)]
        counts["solver_unknowns"] = sum(per_depth.values())
        counts["solver_deepest_depth"] = max((k for k, n in per_depth.items() if n > 0), default=None)
    return counts, (len(mesh.vertices), len(mesh.triangles))


def run_poisson(pcd, measure: Measure, args) -> list[dict]:
    rows = []
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Warning)
    for d in args.depth_list:
        counts, debug_vt = ({}, None) if args.no_octree_log else octree_counts(pcd, d, args)
        for t in args.thread_list:
            print(f"  depth {d}, n_threads {t}: warm-up + {args.repeat} …", end="", flush=True)
            cpu: list[float] = []

            def call():
                c = time.process_time()
                r = poisson(pcd, d, t, args)
                cpu.append(time.process_time() - c)
                return r

            (mesh, _dens), ms, times = common.timed(call, args.repeat)
            cpu_runs = [c * 1e3 for c in cpu[1:]]  # the warm-up is cpu[0]
            verts, tris = mesh_arrays(mesh)
            acc = measure(verts, tris)
            row = {
                "kind": "open3d_poisson", "label": f"Open3D Poisson depth {d}", "depth": d, "threads": t,
                "median_ms": ms, "times_ms": times, "runs": args.repeat, "warmup": True,
                "cpu_over_wall": sum(cpu_runs) / sum(times) if sum(times) > 0 else math.nan,
                "cpu_ms": cpu_runs, "median_cpu_ms": sorted(cpu_runs)[len(cpu_runs) // 2],
                "vertices": int(verts.shape[0]), "triangles": int(tris.shape[0]),
                "storage_numbers": 3 * int(verts.shape[0]) + 3 * int(tris.shape[0]),
                **acc, **counts,
            }  # fmt: skip
            if debug_vt is not None and t == 1 and debug_vt != (row["vertices"], row["triangles"]):
                row["note"] = f"the Debug-log run gave {debug_vt[0]} vertices, {debug_vt[1]} triangles"
            rows.append(row)
            print(f" {ms:.1f} ms (process CPU {row['median_cpu_ms']:.1f} ms, cpu/wall {row['cpu_over_wall']:.2f}); "
                  f"{row['vertices']:,} vertices, "
                  f"{row['triangles']:,} triangles; max/diag {acc['max_rel']:.3e}, mean/diag {acc['mean_rel']:.3e}",
                  flush=True)  # fmt: skip
            if args.save_meshes and t == args.thread_list[0]:
                out = Path(args.save_meshes)
                out.mkdir(parents=True, exist_ok=True)
                f = out / f"poisson_{args.points.stem}_d{d}.ply"
                o3d.io.write_triangle_mesh(str(f), mesh, write_ascii=False)
                row["saved_as"] = str(f)
    return rows


def run_measure(measure: Measure, args) -> list[dict]:
    rows = []
    for path in args.measure:
        mesh = o3d.io.read_triangle_mesh(str(path))
        verts, tris = mesh_arrays(mesh)
        row = {"kind": "mesh", "label": str(path), "path": str(Path(path).resolve()),
               "vertices": int(verts.shape[0]), "triangles": int(tris.shape[0]),
               "storage_numbers": 3 * int(verts.shape[0]) + 3 * int(tris.shape[0]), **measure(verts, tris)}  # fmt: skip
        if tris.shape[0] == 0:
            row["note"] = "no triangles read"
        rows.append(row)
        print(f"  {path}: {row['vertices']:,} vertices, {row['triangles']:,} triangles; "
              f"max/diag {row['max_rel']:.3e}, mean/diag {row['mean_rel']:.3e}", flush=True)  # fmt: skip
    return rows


# ---------------------------------------------------------------------------------------------
# tables


def poisson_table(rows: list[dict], args):
    ts = args.thread_list
    header = (["depth"] + [f"{t} thr ms" for t in ts] + ["fastest", "process CPU ms", "cpu/wall"]
              + ["vertices", "triangles", "storage 3V+3T", "octree nodes*", "solved to*", "max/diag", "p99/diag",
                 "mean/diag", "note"])  # fmt: skip
    body = []
    for d in args.depth_list:
        by_t = {r["threads"]: r for r in rows if r["depth"] == d}
        first = by_t[ts[0]]
        label, _ = common.fastest({f"{t} thr": by_t[t]["median_ms"] for t in ts})
        notes = [r["note"] for r in by_t.values() if r.get("note")]
        key = lambda r: (r["vertices"], r["triangles"])  # noqa: E731
        if any(key(r) != key(first) for r in by_t.values()):
            notes.append("mesh sizes differ between thread counts: " +
                         ", ".join(f"{t} thr {r['vertices']}/{r['triangles']}" for t, r in by_t.items()))  # fmt: skip
        ref = first["max_rel"]
        if any(not abs(r["max_rel"] - ref) <= 1e-3 * abs(ref) for r in by_t.values()):
            notes.append("max/diag by threads: " + ", ".join(f"{t} thr {r['max_rel']:.3e}" for t, r in by_t.items()))
        body.append([str(d)] + [fmt_ms(by_t[t]["median_ms"]) for t in ts] + [label or "—"]
                    + [" / ".join(f"{by_t[t]['median_cpu_ms']:.0f}" for t in ts)]
                    + ["/".join(f"{by_t[t]['cpu_over_wall']:.2f}" for t in ts)]
                    + [f"{first['vertices']:,}", f"{first['triangles']:,}", f"{first['storage_numbers']:,}",
                       "—" if first.get("octree_active_nodes") is None else f"{first['octree_active_nodes']:,}",
                       fmt_int(first.get("solver_deepest_depth")), fmt_e(first["max_rel"]), fmt_e(first["p99_rel"]),
                       fmt_e(first["mean_rel"]),
                       "; ".join(notes)])  # fmt: skip
    return header, body


def mesh_table(rows: list[dict]):
    header = ["mesh", "vertices", "triangles", "storage 3V+3T", "max/diag", "p99/diag", "mean/diag", "note"]
    body = [[r["label"], f"{r['vertices']:,}", f"{r['triangles']:,}", f"{r['storage_numbers']:,}",
             fmt_e(r["max_rel"]), fmt_e(r["p99_rel"]), fmt_e(r["mean_rel"]), r.get("note", "")] for r in rows]  # fmt: skip
    return header, body


def target_report(e: float, prows: list[dict], mrows: list[dict], args) -> dict:
    t0 = args.thread_list[0] if args.thread_list else None
    ok = sorted((r for r in prows if r["threads"] == t0 and r["max_rel"] <= e), key=lambda r: r["depth"])
    res: dict = {"target_max_rel": e, "poisson_depths_tried": args.depth_list}
    if ok:
        r = ok[0]
        res["poisson"] = {k: r[k] for k in ("depth", "max_rel", "mean_rel", "vertices", "triangles",
                                            "storage_numbers")}  # fmt: skip
        res["poisson"]["median_ms"] = {str(x["threads"]): x["median_ms"] for x in prows if x["depth"] == r["depth"]}
        print(f"\ntarget max/diag ≤ {e:g}: smallest Open3D depth {r['depth']} (max/diag {r['max_rel']:.3e}, "
              f"mean/diag {r['mean_rel']:.3e}, {r['vertices']:,} vertices, {r['triangles']:,} triangles, "
              f"storage {r['storage_numbers']:,}; "
              + ", ".join(f"{t} thr {v:.1f} ms" for t, v in res["poisson"]["median_ms"].items()) + ")")  # fmt: skip
    elif prows:
        res["poisson"] = None
        print(f"\ntarget max/diag ≤ {e:g}: no Open3D depth among {args.depth_list} reaches it "
              f"(best max/diag {min(r['max_rel'] for r in prows):.3e})")  # fmt: skip
    res["meshes_meeting_target"] = [r["label"] for r in mrows if r["max_rel"] <= e]
    if mrows:
        print(f"  measured meshes reaching it: {', '.join(res['meshes_meeting_target']) or 'none'}")
    return res


def main() -> None:
    args = parse_args()
    load_start = common.loadavg()
    o3d_version = o3d.__version__
    device_api = getattr(o3d, "__DEVICE_API__", "?")
    print(f"open3d {o3d_version} (device API {device_api}); numpy {np.__version__}; CPUs {common.cpu_count()}; "
          f"load average {load_start}", flush=True)  # fmt: skip

    pts, cols, how_read = read_points(args.points)
    pcd, normals = oriented_cloud(pts, cols, args)
    measure = Measure(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c46 = normals["columns_4_6"]
    c46_text = c46 if isinstance(c46, str) else (
        f"lengths {c46['min_length']:.7f} – {c46['max_length']:.7f}, "
        + ("unit" if c46["unit"] else f"NOT unit (tolerance {UNIT_TOL:g})")
        + ("" if c46["finite"] else ", non-finite values"))  # fmt: skip
    print(f"input {args.points} ({how_read}): {pts.shape[0]:,} points; bbox min {np.array2string(lo, precision=6)}, "
          f"max {np.array2string(hi, precision=6)}, diagonal {measure.diag:.6g}\n"
          f"  columns 4-6: {c46_text}\n  normals: {normals['normals']}; "
          f"{100 * normals['outward_from_centroid']:.1f}% point away from the centroid\n"
          f"  distances: float32 RaycastingScene on centred coordinates (resolution ≈ {measure.f32_resolution:.1e} "
          f"of the diagonal)", flush=True)  # fmt: skip
    settings = {
        "function": "open3d.geometry.TriangleMesh.create_from_point_cloud_poisson",
        "depths": args.depth_list, "threads": args.thread_list, "width": 0, "scale": args.scale,
        "linear_fit": args.linear_fit, "full_depth": args.full_depth, "samples_per_node": args.samples_per_node,
        "point_weight": args.point_weight, "density_trimming": None,
        "timing": f"one warm-up, then the upper median of {args.repeat} runs; the Poisson call only",
        "storage": "3*vertices + 3*triangles numbers (Open3D returns only the mesh; the octree node count "
                   "is not exposed by its API, only printed in its Debug log)",
        "distance": "every input point to the mesh, open3d.t.geometry.RaycastingScene.compute_distance "
                    "(float32, coordinates centred on the points' bbox centre), / points' bbox diagonal",
    }  # fmt: skip
    if args.depth_list:
        print(f"\nOpen3D screened Poisson: create_from_point_cloud_poisson(depth=d, width=0, scale={args.scale:g}, "
              f"linear_fit={args.linear_fit}, n_threads=t, full_depth={args.full_depth}, "
              f"samples_per_node={args.samples_per_node:g}, point_weight={args.point_weight:g}); no density trimming; "
              f"d in {args.depth_list}, t in {args.thread_list}; {settings['timing']}", flush=True)  # fmt: skip
    prows = run_poisson(pcd, measure, args) if args.depth_list else []
    load_after_poisson = common.loadavg()
    if args.measure:
        print("\nmeasuring meshes against the same points:", flush=True)
    mrows = run_measure(measure, args)

    title = (f"{args.points.name}: {pts.shape[0]:,} points, bbox diagonal {measure.diag:.6g}; "
             f"distance = input point → mesh, / diagonal")  # fmt: skip
    if prows:
        h, b = poisson_table(prows, args)
        print(f"\n=== Open3D screened Poisson ({title}); time = warm-up + median of {args.repeat}, ms ===\n"
              f"{render_text(h, b, left=1, left_last=True)}")  # fmt: skip
        if not args.no_octree_log:
            print("* from Open3D's Debug log (one extra untimed 1-thread run per depth; its API returns only the mesh, "
                  "so the storage column counts the mesh): octree nodes = its 'Active Nodes'; solved to = the deepest "
                  "level with unknowns in its solver (the octree adapts to the sampling density, so --depths is only "
                  "an upper bound).")  # fmt: skip
    if mrows:
        h, b = mesh_table(mrows)
        print(f"\n=== measured meshes ({title}) ===\n{render_text(h, b, left=1, left_last=True)}")
    target = target_report(args.target_max, prows, mrows, args) if args.target_max is not None else None

    facts = common.machine_facts(
        [("load average 1/5/15 min, at start", load_start),
         ("load average 1/5/15 min, after Poisson", load_after_poisson),
         ("load average 1/5/15 min, at end", common.loadavg())],
        [("open3d", f"{o3d_version} (device API {device_api})")],
    )  # fmt: skip
    print("\nmachine: " + "; ".join(f"{a}={b}" for a, b in facts))
    if args.json:
        doc = {
            "script": "benches/peers/poisson_peers.py", "argv": sys.argv[1:],
            "input": {"path": str(args.points), "read": how_read, "bbox_min": lo.tolist(), "bbox_max": hi.tolist(),
                      "bbox_diagonal": measure.diag, "float32_resolution_rel": measure.f32_resolution, **normals},
            "settings": settings, "rows": prows + mrows, "target": target, "machine": dict(facts),
        }  # fmt: skip
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(common.jsonable(doc), indent=1) + "\n")
        print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
