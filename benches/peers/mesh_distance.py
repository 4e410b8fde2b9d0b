#!/usr/bin/env python3
"""How close `zeroset fit` + `zeroset mesh` on bunny_2k.xyzn come to the scanned bunny.

Runs `zeroset fit data/bunny_2k.xyzn --method rbf -o OUT/bunny.zsf` and
`zeroset mesh OUT/bunny.zsf -o OUT/bunny_{detail}.ply --detail {detail}` for each `--detail`,
reads the meshes back, and measures each vertex's distance to the surface of the original scan
`bun_zipper.ply` (Stanford; 69,451 triangles, open at the bottom: 5 holes).

Distance to the scan's surface: the scan's triangles are sampled area-weighted (`--samples`
points, seeded) and each vertex takes its nearest sample (a k-d tree), so the figure is the
point-to-surface distance plus at most about half the sample spacing, which is printed. Figures
are relative to the scan's bounding-box diagonal. The maximum sits where the closed mesh caps the
scan's holes; the mean and median describe the fit.

    benches/peers/.venv/bin/python benches/peers/mesh_distance.py [--detail general,fine]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import common

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--data", default=str(common.REPO / "data"), help="the data folder (default: the repository's data/)")
    p.add_argument("--detail", default="general,fine", help="comma-separated --detail values for zeroset mesh")
    p.add_argument("--samples", type=int, default=6_000_000, help="area-weighted samples of the scan's surface")
    p.add_argument("--out", default=str(common.HERE / "out"), help="directory for the field, meshes and report")
    a = p.parse_args()
    a.details = [d.strip() for d in a.detail.split(",") if d.strip()]
    if not a.details or any(d not in ("coarse", "general", "fine") for d in a.details):
        p.error("--detail: comma-separated values among coarse, general, fine")
    if a.samples < 1000:
        p.error("--samples must be at least 1000")
    a.data, a.out = Path(a.data).resolve(), Path(a.out).resolve()
    return a


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (float) and triangles of a PLY with `x y z` first among float vertex properties
    and triangle faces `list uchar int`, ASCII or binary little-endian (what zeroset writes and
    what bun_zipper.ply is)."""
    data = path.read_bytes()
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii").splitlines()
    count = lambda name: int(next(l for l in header if l.startswith(f"element {name}")).split()[-1])  # noqa: E731
    nv, nf = count("vertex"), count("face")
    vprops = []
    in_vertex = False
    for line in header:
        if line.startswith("element"):
            in_vertex = line.startswith("element vertex")
        elif in_vertex and line.startswith("property"):
            vprops.append(line.split()[1])
    if any(l.startswith("format ascii") for l in header):
        rows = data[end:].decode("ascii").split("\n")
        verts = np.array([[float(x) for x in rows[i].split()[:3]] for i in range(nv)])
        faces = np.array([[int(x) for x in rows[nv + i].split()[1:4]] for i in range(nf)])
        return verts, faces
    if not any(l.startswith("format binary_little_endian") for l in header) or any(t not in ("float", "float32") for t in vprops):
        sys.exit(f"{path}: only ASCII or little-endian float32 PLY is read here")
    body = data[end:]
    verts = np.frombuffer(body[: 4 * len(vprops) * nv], dtype="<f4").reshape(nv, len(vprops))[:, :3].astype(float)
    rec = np.dtype([("n", "u1"), ("i", "<i4", (3,))])
    faces = np.frombuffer(body[4 * len(vprops) * nv : 4 * len(vprops) * nv + rec.itemsize * nf], dtype=rec)
    if np.any(faces["n"] != 3):
        sys.exit(f"{path}: only triangle faces are read here")
    return verts, faces["i"].astype(np.int64)


def surface_samples(verts: np.ndarray, faces: np.ndarray, m: int) -> tuple[np.ndarray, float]:
    """`m` area-weighted random points on the triangles (seed 1), and the sample spacing."""
    rng = np.random.default_rng(1)
    tri = verts[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    pick = rng.choice(len(faces), size=m, p=area / area.sum())
    u, v = rng.random(m), rng.random(m)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tri[pick]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0]), float(np.sqrt(area.sum() / m))


def scan_surface(scan: Path, m: int) -> tuple[cKDTree, float, float]:
    """A k-d tree of `m` area-weighted samples of the scan's surface, the bounding-box diagonal
    of the scan's triangle vertices and the sample spacing (also used by scan_peers.py)."""
    sv, sf = read_ply(scan)
    used = sv[np.unique(sf)]
    diag = float(np.linalg.norm(used.max(0) - used.min(0)))
    samples, spacing = surface_samples(sv, sf, m)
    return cKDTree(samples), diag, spacing


def main() -> None:
    args = parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    points, scan = args.data / "bunny_2k.xyzn", args.data / "bun_zipper.ply"
    for f in (points, scan):
        if not f.exists():
            sys.exit(f"missing {f} (set --data)")
    field = args.out / "bunny.zsf"
    common.run_logged(["cargo", "run", "--release", "-q", "-p", "zeroset-cli", "--", "fit", str(points),
                       "--method", "rbf", "--quiet", "--force", "-o", str(field)])  # fmt: skip
    meshes = {}
    for d in args.details:
        mesh = args.out / f"bunny_{d}.ply"
        common.run_logged(["cargo", "run", "--release", "-q", "-p", "zeroset-cli", "--", "mesh", str(field),
                           "--detail", d, "--quiet", "--force", "-o", str(mesh)])  # fmt: skip
        meshes[d] = mesh

    tree, diag, spacing = scan_surface(scan, args.samples)
    header = ["detail", "vertices", "triangles", "mean", "median", "p95", "max"]
    body, rows = [], []
    for d, path in meshes.items():
        v, f = read_ply(path)
        dist = tree.query(v)[0] / diag
        figs = [dist.mean(), np.median(dist), np.percentile(dist, 95), dist.max()]
        body.append([d, str(len(v)), str(len(f)), *[f"{x:.2e}" for x in figs]])
        rows.append([d, len(v), len(f), *figs])
    title = (f"distance of zeroset's bunny mesh to bun_zipper.ply's surface, / bbox diagonal {diag:.4f} "
             f"({args.samples:,} surface samples, spacing {spacing / diag:.1e} of the diagonal)")  # fmt: skip
    print(f"\n=== {title} ===\n" + common.render_text(header, body, left=1))
    csv_path, md_path = args.out / "mesh_distance.csv", args.out / "mesh_distance.md"
    with csv_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    common.write_report(md_path, csv_path, [f"## {title}", "", common.render_md(header, body, left=1), ""],
                        common.machine_facts([("load average", common.loadavg())]))  # fmt: skip


if __name__ == "__main__":
    main()
