"""A scan to a mesh: read an oriented point cloud, fit a field, mesh its zero set, and show
the mesh with trimesh (or write it as PLY when trimesh or a display is missing).

    python crates/python/examples/scan_to_mesh.py [CLOUD.ply] [--method rbf|mras|neural]
        [--detail coarse|general|fine] [-o OUT.ply] [--no-show]

Without a cloud it uses the bundled 2,000-point bunny. Needs `pip install zeroset` (or the
wheel built by `maturin build --release` in crates/python); `pip install trimesh` to see the
mesh (pyglet for the window; without it the mesh is still written).
"""

import argparse
import time

import numpy as np

import zeroset


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("cloud", nargs="?", help="oriented point cloud (PLY, xyzn, CSV, ...)")
    p.add_argument("--method", default="rbf", choices=["rbf", "mras", "neural"])
    p.add_argument("--detail", default="general", choices=["coarse", "general", "fine"])
    p.add_argument("-o", "--output", default="scan_mesh.ply")
    p.add_argument("--no-show", action="store_true", help="write the mesh only")
    args = p.parse_args()

    if args.cloud:
        points, normals = zeroset.read_points(args.cloud)
        if normals is None:
            raise SystemExit(f"{args.cloud} has no normals: the fit needs an oriented cloud")
    else:
        points, normals = zeroset.sample_points()
    print(f"{len(points)} points, box {points.min(axis=0)} .. {points.max(axis=0)}")

    start = time.perf_counter()
    field = zeroset.fit(points, normals, method=args.method, progress=True)
    print(f"fit ({args.method}) in {time.perf_counter() - start:.2f} s: {field.report}")

    start = time.perf_counter()
    method = "smc" if field.kind == "rbf" and args.detail == "fine" else "mc"
    verts, faces, vnormals = zeroset.mesh(field, detail=args.detail, method=method)
    print(f"mesh ({method}) in {time.perf_counter() - start:.2f} s: "
          f"{len(verts)} vertices, {len(faces)} triangles")
    # How far the input points are from the mesh's zero set, in the field's units.
    print(f"|field| at the input points: max {np.abs(field(points)).max():.2e}")
    zeroset.write_mesh(args.output, verts, faces, vnormals)
    print(f"wrote {args.output}")

    try:
        import trimesh
    except ImportError:
        print("trimesh is not installed (pip install trimesh): open the PLY in any viewer")
        return
    mesh = trimesh.Trimesh(vertices=verts, faces=faces, vertex_normals=vnormals, process=False)
    print(f"trimesh: watertight {mesh.is_watertight}, volume {mesh.volume:.4g}, "
          f"Euler characteristic {mesh.euler_number}")
    if not args.no_show:
        try:
            mesh.show()
        except Exception as e:  # no display, or no pyglet
            print(f"cannot open a window ({e}); the mesh is in {args.output}")


if __name__ == "__main__":
    main()
