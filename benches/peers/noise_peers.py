#!/usr/bin/env python3
"""Robustness to position noise: `zeroset reconstruct` (its automatic choice, RBF interpolating,
RBF smoothed by `--smoothing auto`, and MRAS) against Open3D's screened Poisson on a scan whose points are moved by Gaussian noise. What each
mesh looks like — components, whether it is closed, how far it is from the clean scan — and
the whole command's wall time.

Run by hand, not by CI (see benches/peers/README.md):

    bash benches/peers/setup.sh --open3d        # once (Debian/Ubuntu: apt-get install libusb-1.0-0 first)
    cargo build --release -p zeroset-cli        # target/release/zeroset
    benches/peers/.venv/bin/python benches/peers/noise_peers.py                   # the bunny
    benches/peers/.venv/bin/python benches/peers/noise_peers.py --cloud data/kitten.xyz \\
        --sigmas 0,0.0025,0.005,0.0075

The noisy clouds: `--cloud`'s positions plus independent Gaussian noise of standard deviation
σ · (its bounding-box diagonal) on each axis (numpy's default_rng(seed), seeded afresh for each
σ: the same pattern, scaled), normals left exact; written with 17 significant digits to
OUT/noise_peers/{cloud}_{σ}.xyzn, the file every side
reads. `zeroset info` gives the scatter it measures (`zeroset_bases::noise`: σ̂ and its ratio to
the point spacing; noisy above 0.2). Each zeroset run is the whole process
`zeroset reconstruct noisy.xyzn -o MESH.ply [--method M [--smoothing auto]] --no-preview --force
--quiet`, timed
from outside; the method `auto` chose is read from its output. Open3D:
`create_from_point_cloud_poisson(depth)` on the same points and normals, no density trimming,
its default threads, timed around that call alone (reading the cloud excluded). Distances, over
the clean cloud's bounding-box diagonal: the clean points → the mesh (mean and max; Open3D
RaycastingScene), and the mesh's vertices → the clean scan's surface (`--truth`, a mesh:
the median and 90th percentile; with `--truth none`, to the nearest clean point instead, which
adds about half the point spacing). The scan's own holes (the bunny's base) are capped by every
closed mesh: those vertices raise the 90th percentile alike for all.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import common
from stray_peers import binary_and_out, distances, o3d, poisson_mesh, read_cloud  # exits without open3d

from scipy.spatial import cKDTree  # noqa: E402

REPO = common.REPO


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cloud", type=Path, default=REPO / "data" / "bunny_points.ply")
    p.add_argument("--truth", default="auto",
                   help="the clean scan's mesh for the vertices' distance, or 'none' (auto: "
                        "data/bun_zipper.ply for data/bunny_points.ply, none otherwise)")
    p.add_argument("--sigmas", default="0,0.001,0.0025,0.005",
                   help="noise standard deviations as fractions of the diagonal, comma-separated")
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--depth", type=int, default=8, help="Open3D Poisson octree depth")
    p.add_argument("--out", type=Path, default=REPO / "benches" / "peers" / "out")
    a = p.parse_args()
    a.sigma_list = [float(s) for s in a.sigmas.split(",") if s.strip()]
    if a.truth == "auto":
        bunny = a.cloud.resolve() == (REPO / "data" / "bunny_points.ply").resolve()
        a.truth = str(REPO / "data" / "bun_zipper.ply") if bunny else "none"
    return a


def zeroset_run(binary: Path, cloud: Path, mesh: Path, method: str | None, extra: list[str]) -> dict:
    cmd = [str(binary), "reconstruct", str(cloud), "-o", str(mesh), "--no-preview", "--force", "--quiet"]
    if method:
        cmd += ["--method", method]
    cmd += extra
    t = time.perf_counter()
    run = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if run.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{run.stderr}")
    out = run.stdout
    report = re.search(r"report: (closed|open), .*?(\d+) component\(s\)", out)
    chosen = re.search(r"reconstruct: .*?, (\w+) field", out)
    if report is None or chosen is None:
        sys.exit(f"no mesh report in the output of {' '.join(cmd)}")
    return {"closed": report.group(1) == "closed", "components": int(report.group(2)),
            "seconds": seconds, "method": chosen.group(1)}


def scatter(binary: Path, cloud: Path) -> str:
    out = subprocess.run([str(binary), "info", str(cloud)], capture_output=True, text=True, check=True).stdout
    m = re.search(r"σ ≈ \S+ \((\S+) of the diagonal\), ([0-9.]+) of the point spacing: (\w+)", out)
    return f"{float(m.group(1)):.2e} / {m.group(2)} ({m.group(3)})" if m else "?"


class Truth:
    """The vertices' distance to the clean scan: its mesh, or its points."""

    def __init__(self, truth: str, clean: np.ndarray):
        self.scene = None
        if truth != "none":
            mesh = o3d.t.geometry.TriangleMesh.from_legacy(o3d.io.read_triangle_mesh(truth))
            self.scene = o3d.t.geometry.RaycastingScene()
            self.scene.add_triangles(mesh)
        self.tree = cKDTree(clean)

    def of(self, vertices: np.ndarray) -> np.ndarray:
        if self.scene is not None:
            return self.scene.compute_distance(o3d.core.Tensor(vertices.astype(np.float32))).numpy()
        return self.tree.query(vertices)[0]


def main() -> None:
    args = parse_args()
    binary, out = binary_and_out(args, "noise_peers")
    p, n = read_cloud(args.cloud)
    diagonal = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
    truth = Truth(args.truth, p)
    print(f"{args.cloud.name}: {len(p)} points, diagonal {diagonal:.6g}; noise seed {args.seed}; "
          f"vertices measured against {'the clean points' if args.truth == 'none' else Path(args.truth).name}")

    header = ["σ / diag", "σ̂ / diag, / spacing", "mesh", "components", "closed", "s",
              "points→mesh mean", "max", "mesh→scan median", "p90"]
    body = []
    for sigma in args.sigma_list:
        rng = np.random.default_rng(args.seed)
        q = p + rng.normal(size=p.shape) * sigma * diagonal
        cloud = out / f"{args.cloud.stem}_{sigma:g}.xyzn"
        np.savetxt(cloud, np.hstack([q, n]), fmt="%.17g")
        q = np.loadtxt(cloud)[:, :3]  # the coordinates as every side reads them
        measured = scatter(binary, cloud)
        rows = []
        for method, extra, label in ((None, [], ""), ("rbf", [], ""),
                                     ("rbf", ["--smoothing", "auto"], " --smoothing auto"),
                                     ("mras", [], "")):
            name = f"{method or 'auto'}{'_smoothed' if extra else ''}"
            mesh = out / f"{args.cloud.stem}_{sigma:g}_{name}.ply"
            r = zeroset_run(binary, cloud, mesh, method, extra)
            rows.append((f"zeroset {method or 'auto → ' + r['method']}{label}", r, mesh))
        mesh = out / f"{args.cloud.stem}_{sigma:g}_poisson.ply"
        r = poisson_mesh(q, n, args.depth, mesh)
        rows.append((f"Open3D Poisson depth {args.depth}", r, mesh))
        for name, r, mesh in rows:
            mean, mx = distances(mesh, p, diagonal)
            vertices = np.asarray(o3d.io.read_triangle_mesh(str(mesh)).vertices)
            d = truth.of(vertices) / diagonal
            body.append([f"{sigma:g}", measured, name, str(r["components"]), "yes" if r["closed"] else "no",
                         f"{r['seconds']:.1f}", f"{mean:.2e}", f"{mx:.2e}", f"{np.median(d):.2e}",
                         f"{np.quantile(d, 0.9):.2e}"])
            measured = ""
        print(f"  σ = {sigma:g} done", flush=True)
    print()
    print(f"=== position noise: {args.cloud.name} + N(0, σ·diag) per axis; distances / the diagonal ===")
    print(common.render_text(header, body, left=3))
    print()
    for key, value in common.machine_facts([("load", common.loadavg())]):
        print(f"{key}: {value}")


if __name__ == "__main__":
    main()
