"""Regenerates the point-format test fixtures in crates/field-core/tests/data/ with the peers'
own writers, so that zeroset's PCD and LAS readers are checked against files other software
wrote (not against zeroset's idea of the formats):

- bunny300_{ascii,binary,binary_compressed}.pcd: Open3D 0.20 `write_point_cloud` (ascii, the
  default binary, compressed=True) of the first 300 points of data/bunny_2k.xyzn with their
  normals and random colours (seed 7);
- bunny300.las (LAS 1.2, point format 0), bunny300_14.las (LAS 1.4, point format 6, one
  extended VLR), bunny300.laz (LAZ, point format 3) and bunny300_14.laz (LAZ 1.4, point
  format 6, layered chunks): laspy 2.5.4 with lazrs, scale 1e-7;
- bunny300_normals.las (LAS 1.4, point format 6) and bunny300_normals.laz (LAZ 1.2, point
  format 3): the same points with their normals in "extra bytes" described by the Extra Bytes
  VLR, as PDAL's `writers.las` (`extra_dims`) writes them: `Curvature NormalX NormalY NormalZ`
  as float32 in the first, `confidence` (uint8) then `nx ny nz` as int16 scaled by 1/30000 in
  the second;
- bunny300.xyzn: those 300 points as printed to 9 significant digits (each value's f32 exact);
- bunny300.e57 and bunny300_spherical.e57: libE57Format (pye57 0.4.19's binding) — see
  `write_e57` and `write_e57_spherical` for what each scan holds (poses, scaled integers,
  the surface-normals extension, invalid records, spherical coordinates).

Usage (after `bash benches/peers/setup.sh --open3d`):
    benches/peers/.venv/bin/python benches/peers/format_fixtures.py
"""

import datetime
from pathlib import Path

import laspy
import numpy as np
import open3d as o3d
from laspy.vlrs.vlrlist import VLRList
from pye57 import libe57
from pyquaternion import Quaternion

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
        # A fixed creation date (laspy writes today's), for files identical on every run.
        header.creation_date = datetime.date(2026, 12, 5)
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
    # Normals in extra bytes: after another extra field, so their offsets are not 0.
    pdal = las("1.4", 6)
    pdal.gps_time = np.arange(len(d), dtype=float)
    pdal.add_extra_dims([laspy.ExtraBytesParams(name, np.float32)
                         for name in ["Curvature", "NormalX", "NormalY", "NormalZ"]])
    pdal.Curvature = np.linspace(0.0, 1.0, len(d), dtype=np.float32)
    pdal.NormalX, pdal.NormalY, pdal.NormalZ = (d[:, k].astype(np.float32) for k in (3, 4, 5))
    pdal.write(OUT / "bunny300_normals.las")
    scaled = las("1.2", 3)
    scaled.add_extra_dims([laspy.ExtraBytesParams("confidence", np.uint8)]
                          + [laspy.ExtraBytesParams(name, np.int16, scales=np.array([1 / 30000]),
                                                    offsets=np.array([0.0]))
                             for name in ["nx", "ny", "nz"]])
    scaled.confidence = np.full(len(d), 200, dtype=np.uint8)
    scaled.nx, scaled.ny, scaled.nz = d[:, 3], d[:, 4], d[:, 5]
    scaled.write(OUT / "bunny300_normals.laz")
    write_e57(OUT / "bunny300.e57", d)
    write_e57_spherical(OUT / "bunny300_spherical.e57", d)
    print(f"wrote the fixtures in {OUT}")


# E57: the points are the file's; each scan stores them in its own frame, R^T (p - t), with the
# pose (R as a unit quaternion, t) that takes them back. Fixed GUIDs keep the files reproducible.
NORMALS_URI = "http://www.libe57.org/E57_EXT_surface_normals.txt"


def e57_file(path: Path, guid: str, normals: bool):
    imf = libe57.ImageFile(str(path), "w")
    imf.extensionsAdd("", libe57.E57_V1_0_URI)
    if normals:
        imf.extensionsAdd("nor", NORMALS_URI)
    root = imf.root()
    root.set("formatName", libe57.StringNode(imf, "ASTM E57 3D Imaging Data File"))
    root.set("guid", libe57.StringNode(imf, guid))
    root.set("versionMajor", libe57.IntegerNode(imf, libe57.E57_FORMAT_MAJOR))
    root.set("versionMinor", libe57.IntegerNode(imf, libe57.E57_FORMAT_MINOR))
    root.set("coordinateMetadata", libe57.StringNode(imf, ""))
    root.set("data3D", libe57.VectorNode(imf, True))
    root.set("images2D", libe57.VectorNode(imf, True))
    return imf, root["data3D"]


def e57_scan(imf, data3d, guid: str, q: Quaternion, t, prototype, columns: dict) -> None:
    """Appends a scan with pose (q, t) whose records have the fields of `prototype` (name ->
    node), filled from `columns` (name -> numpy array, in the scan's own frame)."""
    scan = libe57.StructureNode(imf)
    scan.set("guid", libe57.StringNode(imf, guid))
    pose = libe57.StructureNode(imf)
    rotation = libe57.StructureNode(imf)
    for k, v in zip("wxyz", q.elements):
        rotation.set(k, libe57.FloatNode(imf, float(v)))
    translation = libe57.StructureNode(imf)
    for k, v in zip("xyz", t):
        translation.set(k, libe57.FloatNode(imf, float(v)))
    pose.set("rotation", rotation)
    pose.set("translation", translation)
    scan.set("pose", pose)
    proto = libe57.StructureNode(imf)
    for name, node in prototype.items():
        proto.set(name, node)
    points = libe57.CompressedVectorNode(imf, proto, libe57.VectorNode(imf, True))
    scan.set("points", points)
    data3d.append(scan)
    n = len(next(iter(columns.values())))
    buffers = libe57.VectorSourceDestBuffer()
    arrays = {}
    for name in prototype:
        a = np.ascontiguousarray(columns[name])
        arrays[name] = a
        buffers.append(libe57.SourceDestBuffer(imf, name, a, n, True, True))
    writer = points.writer(buffers)
    writer.write(n)
    writer.close()


def to_scan(q: Quaternion, t, p: np.ndarray) -> np.ndarray:
    return (q.inverse.rotation_matrix @ (p - t).T).T


def write_e57(path: Path, d: np.ndarray) -> None:
    """Two scans of the 300 points with the surface-normals extension. Scan 0: points 0-149,
    identity pose, double coordinates, single-precision normals. Scan 1: points 150-299 under a
    pose (a rotation of 1.2 rad and a translation), coordinates as integers scaled by 1e-7,
    with four records flagged cartesianInvalidState 1 (a direction, no range) or 2 (invalid)
    between them, which the reader leaves out."""
    imf, data3d = e57_file(path, "{zeroset-fixture-bunny300-e57}", normals=True)
    identity = Quaternion(1, 0, 0, 0)
    p, n = d[:150, :3], d[:150, 3:6]
    double = lambda v: libe57.FloatNode(imf, 0.0, libe57.E57_DOUBLE, -1e3, 1e3)
    single = lambda: libe57.FloatNode(imf, 0.0, libe57.E57_SINGLE, -1.0, 1.0)
    e57_scan(imf, data3d, "{zeroset-fixture-scan-0}", identity, np.zeros(3),
             {"cartesianX": double(0), "cartesianY": double(0), "cartesianZ": double(0),
              "nor:normalX": single(), "nor:normalY": single(), "nor:normalZ": single()},
             {"cartesianX": p[:, 0].copy(), "cartesianY": p[:, 1].copy(),
              "cartesianZ": p[:, 2].copy(), "nor:normalX": n[:, 0].astype(np.float32),
              "nor:normalY": n[:, 1].astype(np.float32),
              "nor:normalZ": n[:, 2].astype(np.float32)})
    q = Quaternion(axis=[1.0, -2.0, 2.0], angle=1.2)
    t = np.array([0.5, -0.25, 1.75])
    p = to_scan(q, t, d[150:, :3])
    n = to_scan(q, np.zeros(3), d[150:, 3:6])
    state = np.zeros(len(p), dtype=np.int8)
    for at, flag in [(0, 2), (37, 1), (90, 2), (149, 1)]:
        p = np.insert(p, at, [9.0, 9.0, 9.0], axis=0)
        n = np.insert(n, at, [0.0, 0.0, 1.0], axis=0)
        state = np.insert(state, at, flag)
    scaled = lambda: libe57.ScaledIntegerNode(imf, 0, -(2**31), 2**31 - 1, 1e-7, 0.0)
    e57_scan(imf, data3d, "{zeroset-fixture-scan-1}", q, t,
             {"cartesianX": scaled(), "cartesianY": scaled(), "cartesianZ": scaled(),
              "cartesianInvalidState": libe57.IntegerNode(imf, 0, 0, 2),
              "nor:normalX": single(), "nor:normalY": single(), "nor:normalZ": single()},
             {"cartesianX": p[:, 0].copy(), "cartesianY": p[:, 1].copy(),
              "cartesianZ": p[:, 2].copy(), "cartesianInvalidState": state,
              "nor:normalX": n[:, 0].astype(np.float32),
              "nor:normalY": n[:, 1].astype(np.float32),
              "nor:normalZ": n[:, 2].astype(np.float32)})
    imf.close()


def write_e57_spherical(path: Path, d: np.ndarray) -> None:
    """One scan of the 300 points in spherical coordinates (range, azimuth, elevation, doubles)
    as a scanner at t sees them (pose: a rotation of 0.7 rad about z and t), no normals, with
    three records flagged sphericalInvalidState 1 or 2 between them."""
    imf, data3d = e57_file(path, "{zeroset-fixture-bunny300-spherical-e57}", normals=False)
    q = Quaternion(axis=[0.0, 0.0, 1.0], angle=0.7)
    t = np.array([-0.3, 0.1, -0.05])
    p = to_scan(q, t, d[:, :3])
    r = np.linalg.norm(p, axis=1)
    azimuth = np.arctan2(p[:, 1], p[:, 0])
    elevation = np.arcsin(p[:, 2] / r)
    state = np.zeros(len(p), dtype=np.int8)
    for at, flag in [(5, 1), (150, 2), (300, 1)]:
        r, azimuth, elevation = (np.insert(v, at, x) for v, x in
                                 [(r, 0.0), (azimuth, 0.5), (elevation, 0.25)])
        state = np.insert(state, at, flag)
    double = lambda lo, hi: libe57.FloatNode(imf, 0.0, libe57.E57_DOUBLE, lo, hi)
    e57_scan(imf, data3d, "{zeroset-fixture-spherical-scan-0}", q, t,
             {"sphericalRange": double(0.0, 10.0), "sphericalAzimuth": double(-np.pi, np.pi),
              "sphericalElevation": double(-np.pi / 2, np.pi / 2),
              "sphericalInvalidState": libe57.IntegerNode(imf, 0, 0, 2)},
             {"sphericalRange": r, "sphericalAzimuth": azimuth,
              "sphericalElevation": elevation, "sphericalInvalidState": state})
    imf.close()


if __name__ == "__main__":
    main()
