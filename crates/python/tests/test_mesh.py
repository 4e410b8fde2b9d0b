"""Marching cubes against scikit-image on the same volume, meshes of fields against their
analytic truth (Euler characteristic, distance to the sphere), and mesh files."""

import subprocess
import warnings

import numpy as np
import pytest

import zeroset
from conftest import sphere_cloud

measure = pytest.importorskip("skimage.measure")


def ball_volume(n=40, radius=0.7):
    """A bright ball: 1 − |x|² over [−1, 1]³ sampled on n³ points (positive inside)."""
    t = np.linspace(-1, 1, n)
    x, y, z = np.meshgrid(t, t, t, indexing="ij")
    return radius**2 - (x * x + y * y + z * z), t[1] - t[0]


def face_normals(verts, faces):
    a, b, c = (verts[faces[:, i]] for i in range(3))
    return np.cross(b - a, c - a)


def test_marching_cubes_matches_scikit_image():
    vol, h = ball_volume()
    spacing = (h, h, 2 * h)
    ours = zeroset.marching_cubes(vol, 0.0, spacing=spacing)
    theirs = measure.marching_cubes(vol, 0.0, spacing=spacing)
    v, f, n, values = ours
    sv, sf, sn, _ = theirs
    # every marching-cubes variant puts one vertex on each crossed edge, linearly interpolated
    assert v.shape == sv.shape and f.shape == sf.shape
    assert f.dtype == sf.dtype == np.int32  # scikit-image's face dtype
    key = lambda a: a[np.lexsort(np.round(a, 9).T[::-1])]  # noqa: E731
    assert np.allclose(key(v), key(sv.astype(np.float64)), atol=1e-5)
    # orientation as scikit-image's: normals down the gradient (out of the bright ball),
    # faces' right-hand normals up it (in); 'ascent' flips the faces only
    centre = np.array([(len(vol) - 1) * s / 2 for s in spacing])
    for direction, sign in (("descent", -1), ("ascent", 1)):
        v, f, n, _ = zeroset.marching_cubes(vol, 0.0, spacing=spacing, gradient_direction=direction)
        sv, sf, sn, _ = measure.marching_cubes(vol, 0.0, spacing=spacing, gradient_direction=direction)
        assert np.all(np.sum(n * (v - centre), axis=1) > 0)
        assert np.all(np.sum(sn * (sv - centre), axis=1) > 0)
        ours_f = np.sign(np.sum(face_normals(v, f) * (v[f[:, 0]] - centre), axis=1))
        theirs_f = np.sign(np.sum(face_normals(sv, sf) * (sv[sf[:, 0]] - centre), axis=1))
        assert np.all(ours_f == sign) and np.all(theirs_f == sign), direction
    # values: the largest sample of the grid cell each vertex lies in (the cell above on a
    # cell face, moved inside the grid)
    cell = np.floor(v / np.array(spacing) + 1e-9).astype(int)
    cell = np.clip(cell, 0, np.array(vol.shape) - 2)
    corners = [vol[cell[:, 0] + i, cell[:, 1] + j, cell[:, 2] + k]
               for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    assert np.array_equal(values, np.max(corners, axis=0))
    assert np.all(values >= 0.0)  # each cell has a sample above the level


def test_ascent_flips_the_faces_and_default_level_is_the_middle():
    vol, h = ball_volume(24)
    v, f, n, _ = zeroset.marching_cubes(vol, 0.0, gradient_direction="ascent")
    vd, fd, nd, _ = zeroset.marching_cubes(vol, 0.0)
    assert np.array_equal(v, vd) and np.array_equal(n, nd)
    assert np.array_equal(f[:, [0, 2, 1]], fd)
    mid = (vol.min() + vol.max()) / 2
    a = zeroset.marching_cubes(vol)[0]
    b = measure.marching_cubes(vol)[0]
    assert a.shape == b.shape and np.allclose(np.sort(a[:, 0]), np.sort(b[:, 0]), atol=1e-5)
    assert np.array_equal(a, zeroset.marching_cubes(vol, mid)[0])


def test_marching_cubes_takes_any_layout_and_step_size():
    vol, _ = ball_volume(30)
    base = zeroset.marching_cubes(vol, 0.0)
    for variant in (np.asfortranarray(vol), vol.astype(np.float32), vol[:, :, :]):
        out = zeroset.marching_cubes(variant, 0.0)
        assert out[0].shape == base[0].shape
    coarse = zeroset.marching_cubes(vol, 0.0, step_size=2)
    sk = measure.marching_cubes(vol, 0.0, step_size=2)
    assert len(coarse[0]) < len(base[0]) and len(sk[0]) < len(base[0])


@pytest.mark.parametrize(
    "volume, kwargs, message",
    [
        (np.zeros((4, 4)), {}, "3-D"),
        (np.zeros((1, 4, 4)), {"level": 0.0}, "at least 2 samples"),
        (np.zeros((4, 4, 4)), {"level": 1.0}, "outside the volume's range"),
        (np.full((4, 4, 4), np.nan), {"level": 0.0}, "NaN|non-finite|outside"),
        (np.zeros((4, 4, 4)), {"level": 0.0, "spacing": (1, 0, 1)}, "spacing"),
        (np.zeros((4, 4, 4)), {"level": 0.0, "mask": np.ones((4, 4, 4), bool)}, "mask"),
        (np.zeros((4, 4, 4)), {"level": 0.0, "method": "dual"}, "method"),
    ],
)
def test_bad_volumes_are_value_errors(volume, kwargs, message):
    with pytest.raises(ValueError, match=message):
        zeroset.marching_cubes(volume, **kwargs)


def test_the_mesh_of_a_fitted_sphere_is_a_closed_sphere(sphere_field):
    v, f, n = zeroset.mesh(sphere_field, resolution=48)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)  # closed and manifold
    euler = len(v) - len(counts) + len(f)
    assert euler == 2
    r = np.linalg.norm(v, axis=1)
    assert np.abs(r - 1).max() < 0.01
    assert np.all(np.sum(n * v, axis=1) > 0)  # outward normals


def test_signed_marching_cubes_agrees_with_plain_ones(sphere_field):
    plain = zeroset.mesh(sphere_field, resolution=40)
    signed = zeroset.mesh(sphere_field, resolution=40, method="smc")
    assert plain[1].shape == signed[1].shape
    assert np.allclose(np.sort(plain[0], axis=0), np.sort(signed[0], axis=0), atol=1e-6)


def test_fields_callables_and_grids_mesh_alike(sphere_field):
    lo, hi = np.full(3, -1.2), np.full(3, 1.2)
    sphere = lambda p: np.linalg.norm(p, axis=1) - 1.0  # noqa: E731
    v, f, n, _ = zeroset.marching_cubes(sphere, 0.0, bounds=(lo, hi), resolution=41)
    assert np.abs(np.linalg.norm(v, axis=1) - 1).max() < 0.01
    assert np.all(np.sum(n * v, axis=1) < 0)  # down the gradient: in, for a signed distance
    vf, ff, _, _ = zeroset.marching_cubes(sphere_field, 0.0, resolution=41)
    assert np.abs(np.linalg.norm(vf, axis=1) - 1).max() < 0.01
    # a callable through zeroset.mesh is interpolated by a quadratic B-spline first
    vm, fm, _ = zeroset.mesh(sphere, bounds=(lo, hi), resolution=40)
    assert np.abs(np.linalg.norm(vm, axis=1) - 1).max() < 0.01
    with pytest.raises(ValueError, match="bounds"):
        zeroset.mesh(sphere)
    with pytest.raises(ValueError, match="smc"):
        zeroset.mesh(sphere, bounds=(lo, hi), method="smc")
    # a Field is meshed in its own box: arguments describing another are refused, not ignored
    with pytest.raises(ValueError, match="own box"):
        zeroset.mesh(sphere_field, bounds=(lo, hi))
    with pytest.raises(ValueError, match="own box"):
        zeroset.mesh(sphere_field, spacing=0.5)


@pytest.mark.parametrize("method", ["mc", "smc"])
def test_a_grid_larger_than_memory_is_refused_before_allocating(sphere_field, monkeypatch, method):
    # signed marching cubes aborted the process (a 64 GB allocation) at resolution 2000
    monkeypatch.setenv("ZEROSET_MEMORY_LIMIT", "256MiB")
    with pytest.raises(ValueError, match="needs about .* GiB of memory"):
        zeroset.mesh(sphere_field, resolution=2000, method=method)


def test_mesh_files_round_trip(tmp_path, sphere_field):
    v, f, n = zeroset.mesh(sphere_field, resolution=20)
    for name, ascii in (("m.ply", False), ("a.ply", True)):
        zeroset.write_mesh(tmp_path / name, v, f, n, ascii=ascii)
        rv, rf, rn = zeroset.read_mesh(tmp_path / name)
        assert np.array_equal(rf, f)
        assert np.allclose(rv, v, atol=0 if not ascii else 1e-6)
        assert rn is not None and np.allclose(rn, n, atol=1e-6)
    zeroset.write_mesh(tmp_path / "m.obj", v, f)
    assert (tmp_path / "m.obj").read_text().count("\nf ") == len(f)
    with pytest.raises(ValueError, match="index outside"):
        zeroset.write_mesh(tmp_path / "x.ply", v, f + len(v))
    with pytest.raises(ValueError, match="integers"):
        zeroset.write_mesh(tmp_path / "x.ply", v, f.astype(float))
    # STL: the corners are welded back into the same vertices, the triangles keep their
    # order and winding; OBJ keeps everything (full precision, one normal per vertex).
    for name, ascii in (("m.stl", False), ("a.stl", True)):
        zeroset.write_mesh(tmp_path / name, v, f, n, ascii=ascii)
        assert (tmp_path / name).read_bytes().startswith(b"solid") == ascii
        rv, rf, rn = zeroset.read_mesh(tmp_path / name)
        assert rn is None and len(rv) == len(v)
        assert np.array_equal(rv[rf], v[f].astype(np.float32).astype(np.float64))
    # A mesh at UTM coordinates: STL's 32-bit floats move its vertices, and a warning says so;
    # near the origin, no warning.
    with pytest.warns(UserWarning, match="STL stores 32-bit floats"):
        zeroset.write_mesh(tmp_path / "utm.stl", v + [512345.0, 5412345.0, 312.0], f)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        zeroset.write_mesh(tmp_path / "near.stl", v, f)
    rv, rf, rn = zeroset.read_mesh(tmp_path / "m.obj")
    assert np.array_equal(rv, v) and np.array_equal(rf, f) and rn is None
    zeroset.write_mesh(tmp_path / "n.obj", v, f, n)
    rv, rf, rn = zeroset.read_mesh(tmp_path / "n.obj")
    assert np.array_equal(rn, n)
    zeroset.write_mesh(tmp_path / "n.off", v, f, n)
    rv, rf, rn = zeroset.read_mesh(tmp_path / "n.off")
    assert np.array_equal(rv, v) and np.array_equal(rf, f) and np.array_equal(rn, n)
    with pytest.raises(ValueError, match=r"\.ply, \.obj, \.stl or \.off"):
        zeroset.write_mesh(tmp_path / "x.3mf", v, f)
    with pytest.raises(ValueError, match=r"\.ply, \.obj, \.stl or \.off"):
        zeroset.read_mesh(tmp_path / "x.3mf")
    # A mesh file read as points: its vertices, with the file's normals (PLY), or normals from
    # the triangles' winding (STL), then — a mesh of fewer than 10,000 vertices — points
    # sampled inside its triangles; every normal outward on the sphere.
    centre = v.mean(axis=0)
    p_ply, n_ply = zeroset.read_points(tmp_path / "m.ply")
    assert len(v) < len(p_ply)  # fewer than 10,000 vertices: some points sampled inside
    # The vertices come in the order the triangles use them: compare sorted.
    v32 = v.astype(np.float32).astype(np.float64)
    mine, theirs = np.lexsort(p_ply[: len(v)].T), np.lexsort(v32.T)
    assert np.array_equal(p_ply[: len(v)][mine], v32[theirs])
    unit = n / np.linalg.norm(n, axis=1)[:, None]
    assert np.allclose(n_ply[: len(v)][mine], unit[theirs], atol=1e-6)
    p_stl, n_stl = zeroset.read_points(tmp_path / "m.stl")
    assert len(p_stl) == len(p_ply) and n_stl is not None
    for p, q in ((p_ply, n_ply), (p_stl, n_stl)):
        assert (np.einsum("ij,ij->i", p - centre, q) > 0).all()
    (tmp_path / "cut.stl").write_bytes((tmp_path / "m.stl").read_bytes()[:200])
    with pytest.raises(ValueError, match="truncated"):
        zeroset.read_mesh(tmp_path / "cut.stl")
    with pytest.raises(OSError):
        zeroset.write_mesh(tmp_path / "no" / "such" / "dir.ply", v, f)


def test_trim_mesh_cuts_a_sphere_to_the_half_a_scan_covers(sphere_field):
    # The fitted sphere's mesh, trimmed to points on its upper half: a disc-like cap (one
    # boundary loop) a little larger than the half, the cut welded, normals carried along.
    verts, faces, normals = zeroset.mesh(sphere_field, detail="fine")
    centre = verts.mean(axis=0)
    radius = np.linalg.norm(verts - centre, axis=1).mean()
    rng = np.random.default_rng(1)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = np.abs(d[:, 2])
    scan = centre + radius * d
    tv, tf, tn = zeroset.trim_mesh(verts, faces, scan, normals=normals)
    assert tn is not None and tn.shape == tv.shape
    assert np.allclose(np.linalg.norm(tn, axis=1), 1.0)
    assert tv[:, 2].min() > centre[2] - 0.3 * radius
    edges = np.sort(tf[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert counts.max() == 2  # welded: no edge has three triangles
    area = lambda v, f: 0.5 * np.linalg.norm(
        np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1
    ).sum()
    half = area(verts, faces) / 2
    assert half < area(tv, tf) < 1.15 * half
    # A smaller reach cuts closer; a scan covering everything leaves the mesh as it was.
    sv, sf, _ = zeroset.trim_mesh(verts, faces, scan, reach=1.0)
    assert area(sv, sf) < area(tv, tf)
    same_v, same_f, none = zeroset.trim_mesh(verts, faces, verts)
    assert none is None and np.array_equal(same_v, verts) and np.array_equal(same_f, faces)


@pytest.mark.parametrize(
    "scan, kwargs, message",
    [
        (np.zeros((5, 3)), {}, "at least 9"),
        (np.zeros((20, 3)), {}, "repeated"),
        (np.random.default_rng(0).random((20, 3)), {"reach": 0.0}, "finite and positive"),
        (np.random.default_rng(0).random((20, 2)), {}, "scan"),
    ],
)
def test_trim_mesh_refuses_bad_scans(scan, kwargs, message):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(ValueError, match=message):
        zeroset.trim_mesh(v, np.array([[0, 1, 2]]), scan, **kwargs)


def test_a_dense_scans_mras_field_is_meshed_as_the_command_meshes_it(tmp_path, zeroset_bin):
    # Two balls of radius 0.05 at opposite corners of a box, 10,000 points each (spaced about
    # 0.002), fitted to 2e-5 of the diagonal: the scan is denser than the fine voxels (0.009),
    # so `zeroset mesh` samples at twice its median spacing, and so does the default here.
    parts = [sphere_cloud(10_000, 0.05, c) for c in [(0.0, 0.0, 0.0), (1.0, 1.0, 0.5)]]
    points = np.vstack([p for p, _ in parts])
    normals = np.vstack([n for _, n in parts])
    field = zeroset.fit(points, normals, method="mras", tolerance=2e-5)
    path = tmp_path / "balls.zsf"
    field.save(path)
    ply = tmp_path / "balls.ply"
    out = subprocess.run(
        [zeroset_bin, "mesh", str(path), "-o", str(ply), "--quiet"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    grid = next(line for line in out.splitlines() if line.startswith("grid "))
    assert "(2 × the scan's median spacing" in grid, grid
    v_cli, f_cli, _ = zeroset.read_mesh(ply)
    v, f, _ = zeroset.mesh(field)
    assert f.shape == f_cli.shape
    assert np.allclose(v, v_cli, atol=1e-9)
    # the fine voxel the l0 rule gives is coarser: fewer triangles
    _, fine, _ = zeroset.mesh(field, detail="fine")
    assert len(fine) < len(f) / 2, (len(fine), len(f))
