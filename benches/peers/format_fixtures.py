"""Regenerates the point-format test fixtures in crates/field-core/tests/data/ with the peers'
own writers, so that zeroset's PCD and LAS readers are checked against files other software
wrote (not against zeroset's idea of the formats):

- bunny300_{ascii,binary,binary_compressed}.pcd: Open3D 0.20 `write_point_cloud` (ascii, the
  default binary, compressed=True) of the first 300 points of data/bunny_2k.xyzn with their
  normals and random colours (seed 7);
- bunny300.las (LAS 1.2, point format 0), bunny300_14.las (LAS 1.4, point format 6, one
  extended VLR), bunny300.laz (LAZ, point format 3) and bunny300_14.laz (LAZ 1.4, point
  format 6, layered chunks): laspy 2.5.4 with lazrs, scale 1e-7;
- bunny300.xyzn: those 300 points as printed to 9 significant digits (each value's f32 exact).

Usage (after `bash benches/peers/setup.sh --open3d`):
    benches/peers/.venv/bin/python benches/peers/format_fixtures.py
"""

from pathlib import Path

import laspy
import numpy as np
import open3d as o3d
from laspy.vlrs.vlrlist import VLRList

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "crates/field-core/tests/data"


def main() -> None:
    sub = np.loadtxt(ROOT / "data/bunny_2k.xyzn")[:300]
    np.savetxt(OUT / "bunny300.xyzn", sub[:, :6], fmt="%.9g")
    d = np.loadtxt(OUT / "bunny300.xyzn")

    pc = o3d.geometry.PointCloud()
    pc.points = o3d.utility.Vector3dVector(sub[:, :3])
    pc.normals = o3d.utility.Vector3dVector(sub[:, 3:6])
    pc.colors = o3d.utility.Vector3dVector(np.random.default_rng(7).random((300, 3)))
    for name, kw in [("ascii", dict(write_ascii=True)), ("binary", {}),
                     ("binary_compressed", dict(compressed=True))]:
        o3d.io.write_point_cloud(str(OUT / f"bunny300_{name}.pcd"), pc, **kw)

    def las(version: str, point_format: int) -> laspy.LasData:
        header = laspy.LasHeader(point_format=point_format, version=version)
        header.scales = np.array([1e-7] * 3)
        header.offsets = np.zeros(3)
        data = laspy.LasData(header)
        data.x, data.y, data.z = d[:, 0], d[:, 1], d[:, 2]
        return data

    plain = las("1.2", 0)
    plain.intensity = np.full(len(d), 7, dtype=np.uint16)
    plain.write(OUT / "bunny300.las")

    compressed = las("1.2", 3)
    compressed.intensity = np.full(len(d), 7, dtype=np.uint16)
    compressed.gps_time = np.arange(len(d), dtype=float)
    compressed.red = compressed.green = compressed.blue = np.full(len(d), 1000, dtype=np.uint16)
    compressed.write(OUT / "bunny300.laz")

    extended = las("1.4", 6)
    extended.gps_time = np.arange(len(d), dtype=float)
    evlrs = VLRList()
    evlrs.append(laspy.VLR(user_id="zeroset", record_id=1, description="test EVLR",
                           record_data=b"evlr payload 123"))
    extended.evlrs = evlrs
    extended.write(OUT / "bunny300_14.las")
    # LAS 1.4 point format 6 compressed: LASzip's layered chunks (compressor 3).
    layered = las("1.4", 6)
    layered.gps_time = np.arange(len(d), dtype=float)
    layered.write(OUT / "bunny300_14.laz")
    print(f"wrote the fixtures in {OUT}")


if __name__ == "__main__":
    main()
