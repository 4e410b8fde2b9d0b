#!/usr/bin/env python3
"""One-sided scans: `zeroset reconstruct --trim[=REACH]` against the common Open3D recipe, screened
Poisson followed by density trimming (remove the vertices whose Poisson density is below the
q-quantile). How much surface each mesh has that the scan does not support (excess), how much
of the scan it fails to cover (missed), its area against the true one, its pieces, and the time.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh --open3d        # once (Debian/Ubuntu: apt-get install libusb-1.0-0 first)
    cargo build --release -p zeroset-cli        # target/release/zeroset
    benches/peers/.venv/bin/python benches/peers/trim_peers.py                  # all three scans
    benches/peers/.venv/bin/python benches/peers/trim_peers.py --scans dome --runs 1 --depths 8

The scans (deterministic; written with 17 significant digits as x y z nx ny nz to
OUT/trim_peers/{scan}.xyzn, the file every side reads):
  front    the points of data/bunny_points.ply whose unit normal has nz > 0.2 (14,407 points): the
           bunny as one range scan from +z sees it. Its true area: the triangles of
           data/bun_zipper.ply (whose vertices the points are) with all three vertices in the scan.
  dome     20,000 points uniform on the unit upper half-sphere (z uniform in [0, 1], angle uniform:
           Archimedes), normals = positions; true area 2π.
  terrain  20,000 points with (x, y) uniform in [0, 2]², z = 0.1 sin(3x) cos(2y), unit normals from
           the gradient (pointing +z); true area = 4 · mean √(1 + |∇z|²) on a 2000² midpoint grid.
(numpy's default_rng(--seed) for dome and terrain.)

Each zeroset run is the whole process `zeroset reconstruct SCAN -o MESH.ply --no-preview --force
--quiet --threads T [--trim | --trim=1 | --trim=2]`, timed from outside (reading, fitting, meshing, trimming,
writing: everything), the median of --runs. Open3D: `create_from_point_cloud_poisson(pcd,
depth=d, n_threads=T)` then, for each q, `remove_vertices_by_mask(densities < quantile(densities,
q))` on a copy of its mesh (q = 0 removes nothing: the untrimmed Poisson mesh); the time is the
Poisson call plus that trimming, building the point cloud and copying the mesh excluded, median
over --runs (the Poisson call is made once per run and shared by every q of that run).

The measures, every mesh, with t = 3 × the scan's median nearest-neighbour spacing (scipy cKDTree):
  excess   the mesh's area farther than t from every scan point: --samples points drawn on the mesh
           by area (numpy, default_rng(--seed)); the fraction of them farther than t from the
           nearest scan point, as % of the mesh's area and as an area (that fraction × area); also
           the % farther than 2t, and the largest sample-to-scan distance in NN spacings (max / sp):
           how far the unsupported surface runs on.
  missed   the % of scan points farther than t from the mesh (exact point-to-triangle distance,
           Open3D RaycastingScene): holes cut into the surface the scan supports.
  area     the mesh's area, and its ratio to the true surface's area (the scan's region of it).
  comps    connected components (Open3D cluster_connected_triangles); bnd edges: edges on one
           triangle only.
The meshes measured are those of the last run (zeroset is deterministic; Open3D's threaded Poisson
may differ slightly run to run). Output: the tables printed and written to OUT/trim_peers.txt.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import common

try:
    import open3d as o3d
except ImportError as e:  # pragma: no cover - set-up message
    sys.exit(f"open3d is missing ({e}): bash benches/peers/setup.sh --open3d")

from scipy.spatial import cKDTree  # noqa: E402

REPO = common.REPO
SCANS = ("front", "dome", "terrain")
ZEROSET_SETTINGS = (("no trim", []), ("--trim (reach 1.5)", ["--trim"]), ("--trim=1", ["--trim=1"]),
                    ("--trim=2", ["--trim=2"]))


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scans", default=",".join(SCANS), help=f"comma-separated, of {', '.join(SCANS)}")
    p.add_argument("--runs", type=int, default=3, help="timed runs per setting; the median is reported")
    p.add_argument("--threads", type=int, default=common.cpu_count(),
                   help="threads on both sides: zeroset --threads, Open3D n_threads (default: the CPUs)")
    p.add_argument("--depths", default="8,9", help="Open3D Poisson octree depths, comma-separated")
    p.add_argument("--quantiles", default="0,0.01,0.05,0.1,0.2",
                   help="Open3D density-trimming quantiles q, comma-separated")
    p.add_argument("--samples", type=int, default=200_000, help="points drawn on each mesh for excess")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", type=Path, default=REPO / "benches" / "peers" / "out")
    target = common.ORIGINAL_ENV.get("CARGO_TARGET_DIR")
    p.add_argument("--zeroset", type=Path, default=((REPO / target) if target else REPO / "target")
                   / "release" / "zeroset", help="the zeroset binary (default: the release build)")
    a = p.parse_args()
    a.scan_list = [s.strip() for s in a.scans.split(",") if s.strip()]
    if not a.scan_list or any(s not in SCANS for s in a.scan_list):
        p.error(f"--scans: want some of {', '.join(SCANS)}")
    a.depth_list = [int(d) for d in a.depths.split(",") if d.strip()]
    a.q_list = [float(q) for q in a.quantiles.split(",") if q.strip()]
    if a.runs < 1 or a.threads < 1 or a.samples < 1000:
        p.error("--runs and --threads must be at least 1, --samples at least 1000")
    if not a.zeroset.exists():
        sys.exit(f"{a.zeroset} is missing: cargo build --release -p zeroset-cli (or --zeroset PATH)")
    return a


# ---------------------------------------------------------------------------------------------
# the scans


def make_scan(name: str, seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Points, unit normals and the true surface's area of the scan `name`."""
    rng = np.random.default_rng(seed)
    if name == "front":
        pcd = o3d.io.read_point_cloud(str(REPO / "data" / "bunny_points.ply"))
        p, n = np.asarray(pcd.points, dtype=np.float64), np.asarray(pcd.normals, dtype=np.float64)
        n = n / np.linalg.norm(n, axis=1)[:, None]
        keep = n[:, 2] > 0.2
        p, n = p[keep], n[keep]
        # The true region: bun_zipper's triangles with all three vertices among the scan's points.
        truth = o3d.io.read_triangle_mesh(str(REPO / "data" / "bun_zipper.ply"))
        v, f = np.asarray(truth.vertices), np.asarray(truth.triangles)
        d, _ = cKDTree(p).query(v)
        inside = d < 1e-6
        f = f[inside[f].all(axis=1)]
        return p, n, float(triangle_areas(v, f).sum())
    if name == "dome":
        k = 20_000
        z = rng.uniform(0.0, 1.0, k)
        phi = rng.uniform(0.0, 2.0 * np.pi, k)
        r = np.sqrt(1.0 - z * z)
        p = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
        return p, p.copy(), 2.0 * np.pi
    if name == "terrain":
        k = 20_000
        xy = rng.uniform(0.0, 2.0, (k, 2))
        x, y = xy[:, 0], xy[:, 1]
        z = 0.1 * np.sin(3 * x) * np.cos(2 * y)
        zx, zy = 0.3 * np.cos(3 * x) * np.cos(2 * y), -0.2 * np.sin(3 * x) * np.sin(2 * y)
        n = np.column_stack([-zx, -zy, np.ones(k)])
        n /= np.linalg.norm(n, axis=1)[:, None]
        g = (np.arange(2000) + 0.5) * (2.0 / 2000)
        gx, gy = np.meshgrid(g, g, indexing="ij")
        gzx, gzy = 0.3 * np.cos(3 * gx) * np.cos(2 * gy), -0.2 * np.sin(3 * gx) * np.sin(2 * gy)
        area = 4.0 * float(np.sqrt(1.0 + gzx**2 + gzy**2).mean())
        return np.column_stack([x, y, z]), n, area
    raise ValueError(name)


# ---------------------------------------------------------------------------------------------
# the measures


def triangle_areas(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)


def sample_by_area(v: np.ndarray, f: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    a = triangle_areas(v, f)
    tri = f[rng.choice(len(f), size=k, p=a / a.sum())]
    r1, r2 = np.sqrt(rng.random(k))[:, None], rng.random(k)[:, None]
    return (1 - r1) * v[tri[:, 0]] + r1 * (1 - r2) * v[tri[:, 1]] + r1 * r2 * v[tri[:, 2]]


def measure(mesh: o3d.geometry.TriangleMesh, scan: np.ndarray, tree: cKDTree, t: float,
            samples: int, seed: int) -> dict:
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    if len(f) == 0:
        return {"area": 0.0, "excess": float("nan"), "excess_area": 0.0, "excess2": float("nan"),
                "reach": float("nan"), "missed": 1.0, "components": 0, "boundary": 0}
    area = float(triangle_areas(v, f).sum())
    s = sample_by_area(v, f, samples, np.random.default_rng(seed))
    gap = tree.query(s)[0]
    far = float((gap > t).mean())
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    d = scene.compute_distance(o3d.core.Tensor(scan.astype(np.float32))).numpy()
    labels, _, _ = mesh.cluster_connected_triangles()
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return {"area": area, "excess": far, "excess_area": far * area, "excess2": float((gap > 2 * t).mean()),
            "reach": float(gap.max()) / (t / 3), "missed": float((d > t).mean()),
            "components": len(np.unique(np.asarray(labels))), "boundary": int((counts == 1).sum())}


# ---------------------------------------------------------------------------------------------
# the two sides


def zeroset_runs(binary: Path, cloud: Path, mesh: Path, extra: list[str], threads: int, runs: int) -> dict:
    cmd = [str(binary), "reconstruct", str(cloud), "-o", str(mesh), "--no-preview", "--force", "--quiet",
           "--threads", str(threads)] + extra
    times, out = [], ""
    for _ in range(runs):
        start = time.perf_counter()
        res = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
        times.append(time.perf_counter() - start)
        if res.returncode != 0:
            sys.exit(f"{' '.join(cmd)} failed:\n{res.stderr}")
        out = res.stdout
    trim = re.search(r"^trim: +(.*)$", out, re.M)
    method = re.search(r"reconstruct: .*?, (\w+) field", out)
    return {"seconds": statistics.median(times), "times": times, "trim": trim.group(1) if trim else None,
            "method": method.group(1) if method else "?"}


def open3d_runs(p: np.ndarray, n: np.ndarray, depth: int, qs: list[float], threads: int,
                runs: int) -> dict[float, dict]:
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    pcd.normals = o3d.utility.Vector3dVector(n)
    times = {q: [] for q in qs}
    meshes = {}
    for _ in range(runs):
        start = time.perf_counter()
        mesh, densities = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            pcd, depth=depth, n_threads=threads)
        poisson_s = time.perf_counter() - start
        for q in qs:
            m = o3d.geometry.TriangleMesh(mesh)  # a copy (not timed)
            start = time.perf_counter()
            dens = np.asarray(densities)
            m.remove_vertices_by_mask(dens < np.quantile(dens, q))
            times[q].append(poisson_s + time.perf_counter() - start)
            meshes[q] = m
    return {q: {"seconds": statistics.median(times[q]), "times": times[q], "mesh": meshes[q]} for q in qs}


# ---------------------------------------------------------------------------------------------


def main() -> None:
    args = parse_args()
    out = args.out / "trim_peers"
    out.mkdir(parents=True, exist_ok=True)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    lines = [
        f"zeroset: {args.zeroset}, whole `reconstruct` command timed (read, fit, mesh, trim, write), "
        f"--threads {args.threads}",
        f"Open3D {o3d.__version__}: create_from_point_cloud_poisson(depth, n_threads={args.threads}) + "
        "density trimming timed; reading and building the point cloud excluded",
        f"time: median of {args.runs} run(s); excess: {args.samples:,} area samples on each mesh, "
        "farther than t = 3 × median NN spacing from every scan point; missed: scan points farther "
        "than t from the mesh; excess % (2t): the same beyond 2t; max / sp: the farthest mesh sample "
        "from the scan, in median NN spacings",
        "",
    ]
    print("\n".join(lines), flush=True)
    header = ["method", "setting", "time s", "area", "area / true", "excess %", "excess area",
              "excess % (2t)", "max / sp", "missed %", "comps", "bnd edges"]
    for name in args.scan_list:
        p, n, true_area = make_scan(name, args.seed)
        cloud = out / f"{name}.xyzn"
        np.savetxt(cloud, np.hstack([p, n]), fmt="%.17g")
        a = np.loadtxt(cloud)  # the coordinates as every side reads them
        p, n = a[:, :3], a[:, 3:6]
        tree = cKDTree(p)
        spacing = float(np.median(tree.query(p, k=2)[0][:, 1]))
        t = 3.0 * spacing
        title = (f"=== {name}: {len(p):,} points, median NN spacing {spacing:.4g}, t = {t:.4g}; "
                 f"true area {true_area:.5g} ===")
        print(title, flush=True)
        rows, notes = [], []
        for label, extra in ZEROSET_SETTINGS:
            tag = extra[0].lstrip("-").replace("=", "") if extra else "notrim"
            mesh_path = out / f"{name}_zeroset_{tag}.ply"
            r = zeroset_runs(args.zeroset, cloud, mesh_path, extra, args.threads, args.runs)
            m = measure(o3d.io.read_triangle_mesh(str(mesh_path)), p, tree, t, args.samples, args.seed)
            rows.append((f"zeroset ({r['method']})", label, r, m))
            if r["trim"]:
                notes.append(f"zeroset {label}: trim: {r['trim']}")
            print(f"  zeroset {label}: {', '.join(f'{x:.2f}' for x in r['times'])} s", flush=True)
        for depth in args.depth_list:
            res = open3d_runs(p, n, depth, args.q_list, args.threads, args.runs)
            for q in args.q_list:
                r = res[q]
                o3d.io.write_triangle_mesh(str(out / f"{name}_poisson{depth}_q{q:g}.ply"), r["mesh"])
                m = measure(r["mesh"], p, tree, t, args.samples, args.seed)
                setting = f"depth {depth}, " + ("no trim (q = 0)" if q == 0 else f"q = {q:g}")
                rows.append(("Open3D Poisson", setting, r, m))
            print(f"  Open3D depth {depth}: Poisson + trim "
                  f"{', '.join(f'{x:.2f}' for x in res[args.q_list[0]]['times'])} s", flush=True)
        body = [[method, setting, f"{r['seconds']:.2f}", f"{m['area']:.5g}", f"{m['area'] / true_area:.3f}",
                 f"{100 * m['excess']:.2f}", f"{m['excess_area']:.4g}", f"{100 * m['excess2']:.2f}",
                 f"{m['reach']:.1f}", f"{100 * m['missed']:.2f}", str(m["components"]), str(m["boundary"])] for method, setting, r, m in rows]
        table = common.render_text(header, body, left=2)
        block = [title, table] + notes + [""]
        print("\n" + "\n".join(block), flush=True)
        lines += block
    facts = common.machine_facts([("load", common.loadavg())],
                                 [("open3d", o3d.__version__), ("threads (both sides)", str(args.threads))])
    fact_lines = [f"{k}: {v}" for k, v in facts]
    print("\n".join(fact_lines))
    (args.out / "trim_peers.txt").write_text("\n".join(lines + fact_lines) + "\n")
    print(f"\nwrote {args.out / 'trim_peers.txt'}")


if __name__ == "__main__":
    main()
