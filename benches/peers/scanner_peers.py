#!/usr/bin/env python3
"""Normals of a simulated multi-station laser scan, turned towards the scanners: `zeroset
normals SCENE.e57 --viewpoint scanners` against Open3D's per-scan
`orient_normals_towards_camera_location` and against orientation without the scanners (zeroset
outward; Open3D `orient_normals_consistent_tangent_plane`), on the same points, in the same run.

Run by hand, not by CI (see benches/peers/README.md), from the repository root:

    bash benches/peers/setup.sh --open3d        # once (Debian/Ubuntu: apt-get install libusb-1.0-0 first)
    cargo build --release -p zeroset-cli        # target/release/zeroset
    benches/peers/.venv/bin/python benches/peers/scanner_peers.py [--zeroset PATH] [--stations 4]

The scene: the Stanford bunny mesh (data/bun_zipper.ply, 69,451 triangles; its five holes in
the base left open) scanned by ray casting (Open3D's RaycastingScene) from `--stations`
tripod stations on a circle of radius 0.35 around it (heights alternating 0.03 above and 0.06
below its middle, so that some look up into the holes of the base), each sweeping a regular
azimuth × elevation grid over the bunny with a step of `--step` (3 mrad: about 1 mm between
neighbouring points at the bunny), Gaussian range noise of 1e-4 (0.04% of the bounding-box
diagonal) along each ray. Each station's hits are one E57 scan,
stored in the station's frame under its pose (a rotation about the z axis and the station's
position), written by libE57Format (pye57). The truth for each point is the normal of the
triangle its ray hit, turned towards the station: a scanner sees the side of a surface that
faces it (where it looks into a hole of the base and sees the inside of the far wall, that side
is the surface it measured, facing it).

Printed per method: the points whose normal points against the truth (count and %), and the
median angle error of the line. Open3D's normals are estimated from the same K + 1 = 17 points
(zeroset's 16 nearest others and the point) on the merged cloud; its per-scan orientation turns
each scan's points towards that scan's station. Times are each side's whole step (zeroset: the
process, reading the E57 file included; Open3D: its calls alone, reading excluded), on the
machine's default threads; they are context, not the claim — the claim is the counts.
"""

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import open3d as o3d
from pye57 import libe57
from pyquaternion import Quaternion

sys.path.insert(0, str(Path(__file__).resolve().parent))
from format_fixtures import e57_file, e57_scan, to_scan  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
RNG = np.random.default_rng(2026)


def stations(count: int, centre: np.ndarray) -> list:
    out = []
    for k in range(count):
        a = 2 * np.pi * k / count + 0.3
        h = 0.03 if k % 2 == 0 else -0.06
        out.append(centre + np.array([0.35 * np.cos(a), h, 0.35 * np.sin(a)]))
    return out


def scan(scene, mesh_normals, station, centre, radius, step):
    """Hits of a grid of rays from `station` over the bunny's bounding sphere."""
    axis = centre - station
    dist = np.linalg.norm(axis)
    half = np.arcsin(min(1.0, radius / dist))
    az0 = np.arctan2(axis[2], axis[0])
    el0 = np.arcsin(axis[1] / dist)
    az = np.arange(az0 - half, az0 + half, step)
    el = np.arange(el0 - half, el0 + half, step)
    A, E = np.meshgrid(az, el)
    d = np.stack([np.cos(E) * np.cos(A), np.sin(E), np.cos(E) * np.sin(A)], axis=-1).reshape(-1, 3)
    rays = np.hstack([np.broadcast_to(station, d.shape), d]).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays))
    t = hit["t_hit"].numpy()
    ok = np.isfinite(t)
    tri = hit["primitive_ids"].numpy()[ok]
    t = t[ok].astype(np.float64) + RNG.normal(0.0, 1e-4, ok.sum())
    p = station + d[ok] * t[:, None]
    n = mesh_normals[tri]
    # The side the scanner saw: towards it.
    facing = np.sign(np.einsum("ij,ij->i", n, station - p))
    facing[facing == 0] = 1
    back = np.einsum("ij,ij->i", n, station - p) < 0
    return p, n * facing[:, None], back


def compare(estimated: np.ndarray, truth: np.ndarray, back: np.ndarray) -> str:
    dots = np.einsum("ij,ij->i", estimated, truth)
    wrong = int((dots < 0).sum())
    inside = int(((dots < 0) & back).sum())
    angle = np.degrees(np.arccos(np.clip(np.abs(dots), 0, 1)))
    return (f"{wrong:6d} against the truth ({100 * wrong / len(dots):.2f}%; {inside} of them seen "
            f"through a hole), median line error {np.median(angle):.2f}°")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--zeroset", default=str(ROOT / "target/release/zeroset"))
    ap.add_argument("--baseline", help="another zeroset binary to compare (e.g. an older build)")
    ap.add_argument("--stations", type=int, default=4)
    ap.add_argument("--step", type=float, default=3e-3, help="angular step of the rays (rad)")
    ap.add_argument("--out", default=str(ROOT / "benches/peers/out/scanner_peers"))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    mesh = o3d.io.read_triangle_mesh(str(ROOT / "data/bun_zipper.ply"))
    mesh.compute_triangle_normals()
    tnormals = np.asarray(mesh.triangle_normals)
    vertices = np.asarray(mesh.vertices)
    lo, hi = vertices.min(0), vertices.max(0)
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))

    path = out / "bunny_scene.e57"
    path.unlink(missing_ok=True)
    imf, data3d = e57_file(path, "{scanner-peers}", normals=False)
    points, truth, owners, backs = [], [], [], []
    for k, s in enumerate(stations(args.stations, centre)):
        p, n, back = scan(scene, tnormals, s, centre, radius, args.step)
        q = Quaternion(axis=[0.0, 0.0, 1.0], angle=0.4 * k)
        local = to_scan(q, s, p)
        cols = {"cartesianX": local[:, 0], "cartesianY": local[:, 1], "cartesianZ": local[:, 2]}
        proto = {c: libe57.FloatNode(imf, 0.0, libe57.E57_DOUBLE, -10.0, 10.0) for c in cols}
        e57_scan(imf, data3d, "{station %d}" % k, q, s, proto, cols)
        print(f"station {k} at {np.round(s, 3)}: {len(p)} points, {int(back.sum())} of them on the inside of the mesh (seen through a hole)")
        backs.append(back)
        points.append(p)
        truth.append(n)
        owners.append(np.repeat(s[None, :], len(p), axis=0))
    imf.close()
    points, truth, owners = np.vstack(points), np.vstack(truth), np.vstack(owners)
    back = np.concatenate(backs)
    print(f"{len(points)} points in {path}")

    rows = []
    runs = [("zeroset --viewpoint scanners", args.zeroset, ["--viewpoint", "scanners"]),
            ("zeroset (outward)", args.zeroset, [])]
    if args.baseline:
        runs.append(("baseline --viewpoint scanners", args.baseline, ["--viewpoint", "scanners"]))
    for how, binary, extra in runs:
        target = out / "zeroset.xyzn"
        t0 = time.perf_counter()
        subprocess.run([binary, "normals", str(path), "-o", str(target), "--force", "--quiet",
                        "--neighbours", "16", *extra],
                       check=True, stdout=subprocess.DEVNULL)
        elapsed = time.perf_counter() - t0
        got = np.loadtxt(target)
        # zeroset reads the scans in order, each in its records' order: the same order as here.
        assert np.abs(got[:, :3] - points).max() < 1e-9, "point order differs"
        rows.append((how, got[:, 3:6], elapsed))

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    t0 = time.perf_counter()
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(17))
    estimated = np.asarray(pc.normals).copy()
    t_est = time.perf_counter() - t0
    t0 = time.perf_counter()
    towards = estimated.copy()
    start = 0
    for s in stations(args.stations, centre):
        count = int((np.abs(owners - s).max(axis=1) == 0).sum())
        part = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points[start:start + count]))
        part.normals = o3d.utility.Vector3dVector(estimated[start:start + count])
        part.orient_normals_towards_camera_location(s)
        towards[start:start + count] = np.asarray(part.normals)
        start += count
    rows.append(("Open3D towards each scan's station", towards, t_est + time.perf_counter() - t0))
    t0 = time.perf_counter()
    pc.orient_normals_consistent_tangent_plane(17)
    rows.append(("Open3D consistent tangent plane", np.asarray(pc.normals), t_est + time.perf_counter() - t0))

    print(f"\n{'method':38s} {'normals':>6s}")
    for how, normals, elapsed in rows:
        print(f"{how:38s} {compare(normals, truth, back)}; {elapsed:.2f} s")
    print(f"(threads: zeroset and Open3D on their defaults, every CPU: {os.cpu_count()})")


if __name__ == "__main__":
    main()
