#!/usr/bin/env python3
"""Robustness to stray points: `zeroset reconstruct` (RBF and MRAS, with the stray points set
aside and with `--outlier-ratio 0`) against Open3D's screened Poisson, on a scan with points
added uniformly in its bounding box with random unit normals. Not a timing: what each mesh
looks like — its components, whether it is closed, its area against the clean scan's mesh, and
how far the scan's own points are from it.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh --open3d        # once (Debian/Ubuntu: apt-get install libusb-1.0-0 first)
    cargo build --release -p zeroset-cli        # target/release/zeroset
    benches/peers/.venv/bin/python benches/peers/stray_peers.py                  # 2% on the bunny
    benches/peers/.venv/bin/python benches/peers/stray_peers.py --fraction 0.05 --seed 3

The cloud: `--cloud` (default data/bunny_points.ply, unit normals in the file) plus
round(fraction · n) points drawn uniformly in its bounding box, each with a uniformly random
unit normal (numpy's default_rng(seed)); written with 17 significant digits to
OUT/stray_peers/stray.xyzn, the file every side reads. Each zeroset run is the whole process
`zeroset reconstruct stray.xyzn -o MESH.ply --method M [--outlier-ratio 0] --no-preview
--force --outliers-out ASIDE.xyzn`; its mesh report (closed/open, components, area) is read
from its output, and ASIDE.xyzn is matched against the scan's points (how many of the points
set aside were the scan's own). Open3D:
`create_from_point_cloud_poisson(depth)` on the same points and normals, no density trimming;
components by `cluster_connected_triangles`, closed = edge-manifold and watertight. Every mesh:
area / the area of the clean cloud's mesh by the same method, and the distance from the clean
scan's points to it (Open3D RaycastingScene; the mean and max over the diagonal).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

import common

try:
    import open3d as o3d
except ImportError as e:  # pragma: no cover - set-up message
    sys.exit(f"open3d is missing ({e}): bash benches/peers/setup.sh --open3d")

REPO = common.REPO


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cloud", type=Path, default=REPO / "data" / "bunny_points.ply")
    p.add_argument("--fraction", type=float, default=0.02, help="stray points per scan point")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--depth", type=int, default=8, help="Open3D Poisson octree depth")
    p.add_argument("--out", type=Path, default=REPO / "benches" / "peers" / "out")
    return p.parse_args()


def read_cloud(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Positions and unit normals: PLY through Open3D, text files as x y z nx ny nz columns."""
    if path.suffix.lower() == ".ply":
        pcd = o3d.io.read_point_cloud(str(path))
        if not pcd.has_normals():
            sys.exit(f"{path}: no normals")
        p, n = np.asarray(pcd.points, dtype=np.float64), np.asarray(pcd.normals, dtype=np.float64)
    else:
        a = np.loadtxt(path, ndmin=2)
        if a.shape[1] < 6:
            sys.exit(f"{path}: want x y z nx ny nz per line")
        p, n = a[:, :3], a[:, 3:6]
    return p, n / np.linalg.norm(n, axis=1)[:, None]


def zeroset_mesh(binary: Path, cloud: Path, mesh: Path, method: str, off: bool,
                 scan: np.ndarray) -> dict:
    aside = mesh.with_suffix(".aside.xyzn")
    cmd = [str(binary), "reconstruct", str(cloud), "-o", str(mesh), "--method", method,
           "--no-preview", "--force", "--quiet", "--outliers-out", str(aside)]
    if off:
        cmd += ["--outlier-ratio", "0"]
    out = common.run_logged(cmd, capture=True)
    report = re.search(r"report: (closed|open), .*?(\d+) component\(s\), .*?area ([0-9.eE+-]+)", out)
    stray = re.search(r"outliers: +(\d+) stray point", out)
    if report is None:
        sys.exit(f"no mesh report in the output of {' '.join(cmd)}")
    # The points set aside that belong to the scan (exact coordinates: both files round-trip).
    written = np.loadtxt(aside, ndmin=2).reshape(-1, 6)[:, :3]
    scan_set = {tuple(x) for x in scan.tolist()}
    return {
        "closed": report.group(1) == "closed",
        "components": int(report.group(2)),
        "area": float(report.group(3)),
        "set aside": int(stray.group(1)) if stray else 0,
        "scan points aside": sum(tuple(x) in scan_set for x in written.tolist()),
    }


def poisson_mesh(points: np.ndarray, normals: np.ndarray, depth: int, path: Path) -> dict:
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd.normals = o3d.utility.Vector3dVector(normals)
    start = time.perf_counter()
    mesh, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=depth)
    seconds = time.perf_counter() - start
    o3d.io.write_triangle_mesh(str(path), mesh)
    labels, _, _ = mesh.cluster_connected_triangles()
    return {
        "closed": mesh.is_edge_manifold() and mesh.is_watertight(),
        "components": len(set(np.asarray(labels).tolist())),
        "area": mesh.get_surface_area(),
        "set aside": 0,
        "scan points aside": 0,
        "seconds": seconds,
    }


def distances(mesh_path: Path, points: np.ndarray, diagonal: float) -> tuple[float, float]:
    mesh = o3d.t.geometry.TriangleMesh.from_legacy(o3d.io.read_triangle_mesh(str(mesh_path)))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(mesh)
    d = scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
    return float(d.mean() / diagonal), float(d.max() / diagonal)


def binary_and_out(args: argparse.Namespace, name: str) -> tuple[Path, Path]:
    """The release `zeroset` binary (exits if it is not built) and the folder OUT/`name`."""
    binary = REPO / "target" / "release" / "zeroset"
    if not binary.exists():
        sys.exit(f"{binary} is missing: cargo build --release -p zeroset-cli")
    out = args.out / name
    out.mkdir(parents=True, exist_ok=True)
    return binary, out


def main() -> None:
    args = parse_args()
    binary, out = binary_and_out(args, "stray_peers")
    p, n = read_cloud(args.cloud)
    rng = np.random.default_rng(args.seed)
    k = int(round(args.fraction * len(p)))
    lo, hi = p.min(axis=0), p.max(axis=0)
    q = rng.uniform(lo, hi, size=(k, 3))
    m = rng.normal(size=(k, 3))
    m /= np.linalg.norm(m, axis=1)[:, None]
    clean = out / "clean.xyzn"
    stray = out / "stray.xyzn"
    np.savetxt(clean, np.hstack([p, n]), fmt="%.17g")
    np.savetxt(stray, np.vstack([np.hstack([p, n]), np.hstack([q, m])]), fmt="%.17g")
    p = np.loadtxt(clean)[:, :3]  # the coordinates as every side reads them
    diagonal = float(np.linalg.norm(hi - lo))
    print(f"{args.cloud.name}: {len(p)} points; {k} stray points added (seed {args.seed}); "
          f"diagonal {diagonal:.6g}")

    rows = []
    for method in ("rbf", "mras"):
        base = zeroset_mesh(binary, clean, out / f"clean_{method}.ply", method, False, p)
        for off in (False, True):
            name = f"zeroset {method}" + (" --outlier-ratio 0" if off else "")
            mesh = out / f"stray_{method}{'_all' if off else ''}.ply"
            r = zeroset_mesh(binary, stray, mesh, method, off, p)
            rows.append((name, r, base["area"], mesh))
    base = poisson_mesh(p, n, args.depth, out / "clean_poisson.ply")
    mesh = out / "stray_poisson.ply"
    r = poisson_mesh(np.vstack([p, q]), np.vstack([n, m]), args.depth, mesh)
    rows.append((f"Open3D Poisson depth {args.depth}", r, base["area"], mesh))

    header = ["mesh", "set aside", "of the scan", "components", "closed", "area / clean",
              "mean / diag", "max / diag"]
    body = []
    for name, r, clean_area, mesh in rows:
        mean, mx = distances(mesh, p, diagonal)
        body.append([name, str(r["set aside"]), str(r["scan points aside"]), str(r["components"]),
                     "yes" if r["closed"] else "no",
                     f"{r['area'] / clean_area:.3f}", f"{mean:.3e}", f"{mx:.3e}"])
    print()
    print(f"=== stray points: {args.cloud.name} + {k} uniform in its box, random normals; distances "
          "from the scan's own points ===")
    print(common.render_text(header, body, left=1))
    print()
    for key, value in common.machine_facts([("load", common.loadavg())]):
        print(f"{key}: {value}")


if __name__ == "__main__":
    main()
