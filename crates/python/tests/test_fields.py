"""Fitting, evaluating, saving and loading fields, against analytic truth and the Rust
command's own results."""

import select
import signal
import subprocess
import sys
import threading
import time
import warnings

import numpy as np
import pytest

import zeroset
from conftest import sphere_cloud


def test_rbf_fit_interpolates_and_its_gradient_follows_the_normals(sphere, sphere_field):
    points, normals = sphere
    f = sphere_field
    assert f.kind == "rbf"
    assert np.abs(f(points)).max() < 1e-8
    g = f.gradient(points)
    cos = np.sum(g * normals, axis=1) / np.linalg.norm(g, axis=1)
    assert cos.min() > 0.99
    # negative inside, positive outside, close to the signed distance near the surface
    assert f(np.zeros(3)) < 0 and f(np.array([1.2, 0, 0])) > 0
    assert abs(f(np.array([1.05, 0.0, 0.0])) - 0.05) < 0.01
    r = f.report
    assert r.method == "rbf" and r.constraints == 3 * len(points)
    assert r.max_residual < 1e-8 and r.seconds > 0
    assert "iterations" in r.as_dict()
    lo, hi = f.bounds
    assert np.all(lo < -0.99) and np.all(hi > 0.99)
    assert f.centres.shape == (3 * len(points), 3)


def test_single_points_and_batches_agree(sphere_field):
    p = np.array([[0.3, -0.2, 0.9], [0.0, 0.0, 0.0]])
    batch = sphere_field(p)
    assert batch.shape == (2,)
    assert sphere_field(p[0]) == batch[0]
    assert np.array_equal(sphere_field.gradient(p[1]), sphere_field.gradient(p)[1])


@pytest.mark.parametrize(
    "convert",
    [
        lambda a: a.astype(np.float32).astype(np.float64),  # exact in float32 for the check
        lambda a: np.asfortranarray(a),
        lambda a: np.repeat(a, 2, axis=0)[::2],  # a strided view
        lambda a: a.tolist(),
        lambda a: _read_only(a),
    ],
    ids=["float32-exact", "fortran", "strided", "list", "read-only"],
)
def test_any_layout_gives_the_same_values(sphere_field, convert):
    rng = np.random.default_rng(1)
    p = rng.uniform(-1.2, 1.2, size=(50, 3)).astype(np.float32).astype(np.float64)
    want = sphere_field(p)
    assert np.array_equal(sphere_field(convert(p)), want)
    assert np.array_equal(sphere_field(p.astype(np.float32)), want)


def _read_only(a):
    b = a.copy()
    b.flags.writeable = False
    return b


def test_save_and_load_round_trip_bit_exactly(tmp_path, sphere_field):
    path = tmp_path / "sphere.zsf"
    sphere_field.save(path)
    loaded = zeroset.load(path)
    rng = np.random.default_rng(2)
    p = rng.uniform(-1.5, 1.5, size=(200, 3))
    assert np.array_equal(loaded(p), sphere_field(p))
    assert np.array_equal(loaded.gradient(p), sphere_field.gradient(p))
    assert loaded.report is None and "RBF field" in repr(loaded)


def test_fields_pickle_bit_exactly_and_go_to_other_processes(tmp_path, sphere_field):
    import copy
    import multiprocessing
    import pickle

    rng = np.random.default_rng(3)
    p = rng.uniform(-1.5, 1.5, size=(200, 3))
    for copied in (copy.deepcopy(sphere_field), pickle.loads(pickle.dumps(sphere_field))):
        assert copied is not sphere_field and copied.kind == "rbf"
        assert np.array_equal(copied(p), sphere_field(p))
        assert np.array_equal(copied.gradient(p), sphere_field.gradient(p))
        assert copied.report == sphere_field.report
    # the pickle is the .zsf file's bytes: another process (spawned, sharing nothing) gets the
    # same values
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        assert np.array_equal(pool.apply(sphere_field, (p,)), sphere_field(p))
    # damaged bytes are the file reader's error, not a crash
    data = bytearray(sphere_field._native.to_bytes())
    data[len(data) // 2] ^= 0xFF
    with pytest.raises(ValueError, match="checksum"):
        zeroset._native.from_bytes(bytes(data))


def test_the_rust_command_and_python_fit_the_same_field(tmp_path, zeroset_bin, sphere):
    points, normals = sphere
    cloud = tmp_path / "sphere.xyzn"
    np.savetxt(cloud, np.hstack([points, normals]), fmt="%.17g")
    rust = tmp_path / "rust.zsf"
    subprocess.run(
        [zeroset_bin, "fit", str(cloud), "--method", "rbf", "-o", str(rust), "--quiet"],
        check=True,
        capture_output=True,
    )
    read_p, read_n = zeroset.read_points(cloud)
    assert np.array_equal(read_p, points) and np.array_equal(read_n, normals)
    ours = zeroset.fit(read_p, read_n)
    theirs = zeroset.load(rust)
    rng = np.random.default_rng(3)
    p = rng.uniform(-1.3, 1.3, size=(300, 3))
    assert np.allclose(ours(p), theirs(p), rtol=0, atol=1e-12)
    # and `zeroset mesh` of the Rust field is the mesh of the Python field
    ply = tmp_path / "rust.ply"
    subprocess.run(
        [zeroset_bin, "mesh", str(rust), "-o", str(ply), "--quiet"], check=True, capture_output=True
    )
    v_rust, f_rust, _ = zeroset.read_mesh(ply)
    v, f, _ = zeroset.mesh(ours)
    assert f.shape == f_rust.shape
    assert np.allclose(v, v_rust, atol=1e-9)


def test_greedy_tolerance_keeps_fewer_centres_and_meets_it(sphere):
    points, normals = sphere
    f = zeroset.fit(points, normals, tolerance=1e-3)
    r = f.report
    assert r.centres < r.constraints and r.greedy_converged
    assert r.greedy_max_residual <= 1e-3 * 2 * np.sqrt(3)


def test_hermite_and_other_kernels(sphere):
    points, normals = sphere_cloud(150)
    for kernel in ("r3", "tps"):
        f = zeroset.fit(points, normals, kernel=kernel)
        assert np.abs(f(points)).max() < 1e-7, kernel
    f = zeroset.fit(points, normals, kernel="wendland", radius=1.0)
    assert f.report.radius == 1.0 and np.abs(f(points)).max() < 1e-7
    h = zeroset.fit(points, normals, kernel="r3", hermite=True)
    g = h.gradient(points)
    assert np.allclose(g, normals, atol=1e-6)


def test_neural_fit_learns_the_sphere_and_is_seeded():
    points, normals = sphere_cloud(200)
    f = zeroset.fit(points, normals, method="neural", steps=300, seed=7)
    g = zeroset.fit(points, normals, method="neural", steps=300, seed=7)
    p = np.random.default_rng(4).uniform(-1, 1, size=(20, 3))
    assert np.array_equal(f(p), g(p))
    assert f.kind == "neural" and len(f.report.loss_history) == 300
    assert f.report.loss < f.report.loss_history[0]
    assert f(np.zeros(3)) < 0 < f(np.array([1.5, 0, 0]))


def test_mras_fit_reaches_its_tolerance_and_round_trips(tmp_path):
    points, normals = sphere_cloud(2000)
    f = zeroset.fit(points, normals, method="mras", tolerance=2e-3)
    r = f.report
    assert r.method == "mras" and r.levels >= 1 and r.storage > 0
    assert r.max_error <= 2e-3
    assert r.tolerance_met and r.points_over_tolerance == 0 and r.capped_cells == 0
    # the report's error is the field's largest Sampson distance |f|/|∇f| at the points,
    # relative to the box diagonal: recompute it from the field
    v, g = f(points), f.gradient(points)
    sampson = np.abs(v) / np.linalg.norm(g, axis=1)
    diagonal = np.linalg.norm(points.max(axis=0) - points.min(axis=0))
    assert sampson.max() / diagonal == pytest.approx(r.max_error, rel=1e-6)
    path = tmp_path / "m.zsf"
    f.save(path)
    assert np.array_equal(zeroset.load(path)(points), v)
    # an MRAS field is meshed at fine detail by default, as `zeroset mesh` does
    default, fine = zeroset.mesh(f)[0], zeroset.mesh(f, detail="fine")[0]
    assert np.array_equal(default, fine)
    assert len(zeroset.mesh(f, detail="general")[0]) < len(fine) / 4


def test_a_loose_mras_tolerance_keeps_the_surface_and_a_flat_field_is_warned_of():
    points, normals = sphere_cloud(2000)
    # The trace norm's weight stops growing with the tolerance past 1%: at 10% the offsets
    # used to shrink to nothing (an empty field, and no warning).
    loose = zeroset.fit(points, normals, method="mras", tolerance=0.1)
    assert loose.report.flat_points == 0 and loose.report.storage > 0
    assert loose(np.zeros(3)) < -0.2
    for axis in np.eye(3):
        assert loose(0.92 * axis) < 0 < loose(1.08 * axis)
    with pytest.warns(UserWarning, match="nearly flat"):
        flat = zeroset.fit(points, normals, method="mras", lam=1e6, max_level=2)
    assert flat.report.flat_points > flat.report.fitted_points / 100
    assert flat.report.lam == 1e6
    with pytest.raises(ValueError, match="lam= applies to method='neural' and 'mras'"):
        zeroset.fit(points, normals, lam=0.1)


def test_two_spheres_touching_at_a_shared_sample_fit_by_rbf_and_mras():
    # Unit spheres centred at z = ±1, both sampled at the origin where they touch (normal
    # down on the upper one, up on the lower): one place, normals pointing apart, two sheets.
    points, normals = sphere_cloud(800)
    parts = []
    for dz in (1.0, -1.0):
        parts.append((points + [0.0, 0.0, dz], normals))
        parts.append((np.zeros((1, 3)), np.array([[0.0, 0.0, -dz]])))
    p = np.vstack([q for q, _ in parts])
    n = np.vstack([m for _, m in parts])
    for method in ("rbf", "mras"):
        f = zeroset.fit(p, n, method=method)
        assert f.report["touching"] == 1, method
        assert f(np.array([0.0, 0.0, 0.5])) < 0 and f(np.array([0.0, 0.0, -0.5])) < 0, method
        assert f(np.array([0.5, 0.0, 0.0])) > 0, method
        if method == "mras":
            # the gradient fitted there is the two normals' mean: a saddle, flat (keeping
            # one normal of the two gives about 0.1)
            assert np.linalg.norm(f.gradient(np.zeros(3))) < 0.03


def test_rbf_and_mras_set_stray_points_aside():
    # 2,000 points on the unit sphere and 10 scattered well off it with random normals: the
    # MRAS report lists exactly those 10 and the field keeps them off its zero set;
    # outlier_ratio=0 fits them (they become surface)
    points, normals = sphere_cloud(2000)
    rng = np.random.default_rng(3)
    stray = []
    while len(stray) < 10:
        q = rng.uniform(-1.25, 1.25, 3)
        if abs(np.linalg.norm(q) - 1) > 0.35:
            stray.append(q)
    p = np.vstack([points, stray])
    n = np.vstack([normals, rng.uniform(-1, 1, (10, 3))])
    f = zeroset.fit(p, n, method="mras", max_level=2)
    assert f.report.outliers == list(range(2000, 2010))
    assert np.abs(f(np.array(stray))).min() > 0.1
    # (three levels: the cells of the second alone leave the strays within 0.06 of zero)
    g = zeroset.fit(p, n, method="mras", max_level=3, outlier_ratio=0)
    assert g.report.outliers == []
    assert np.abs(g(np.array(stray))).max() < 0.05
    with pytest.raises(ValueError, match="outlier_ratio"):
        zeroset.fit(p, n, method="mras", outlier_ratio=1.0)
    # RBF sets the same points aside
    r = zeroset.fit(p, n, outlier_ratio=None)
    assert r.report.outliers == list(range(2000, 2010))
    assert len(r.centres) == 3 * 2000
    with pytest.raises(ValueError, match="outlier_ratio"):
        zeroset.fit(p, n, outlier_ratio=0.5)
    with pytest.raises(ValueError, match="applies to method='rbf' and 'mras'"):
        zeroset.fit(p, n, method="neural", outlier_ratio=3)


def test_rbf_measures_noise_and_warns_of_it():
    # The unit sphere's 2,000 points (spacing about 0.1) moved +-0.03 along their normals (random
    # signs): noisy. The clean sphere: scatter near 0, no warning
    points, normals = sphere_cloud(2000)
    import warnings as w

    with w.catch_warnings():
        w.simplefilter("error")
        clean = zeroset.fit(points, normals)
    assert clean.report.noisy is False and clean.report.scatter < 0.05
    h = np.where(np.random.default_rng(5).random(2000) < 0.5, 0.03, -0.03)
    with pytest.warns(UserWarning, match="smoothing='auto' approximates them"):
        noisy = zeroset.fit(points + h[:, None] * normals, normals)
    assert noisy.report.noisy is True and noisy.report.scatter > 0.2
    assert noisy.report.smoothing == 0 and noisy.report.misfit_rms == 0
    # Smoothed: no warning, mu = 2 scatter^2 diagonal, and the field's zero set nearer the
    # true sphere than the interpolant's (its values on the sphere ~ the distance to it).
    with w.catch_warnings():
        w.simplefilter("error")
        smoothed = zeroset.fit(points + h[:, None] * normals, normals, smoothing="auto")
    r = smoothed.report
    diagonal = np.linalg.norm(np.ptp(points + h[:, None] * normals, axis=0))
    assert r.smoothing == pytest.approx(2 * r.scatter**2 * diagonal, rel=1e-12)
    assert 0 < r.misfit_rms < 0.03
    probes, _ = sphere_cloud(500)
    assert np.sqrt(np.mean(smoothed(probes) ** 2)) < 0.5 * np.sqrt(np.mean(noisy(probes) ** 2))


def test_rbf_smoothing_agrees_with_scipy():
    # The same off-surface constraints (fixed offset, every point kept) through SciPy's
    # RBFInterpolator with the kernel -r and the same smoothing: the same function.
    from scipy.interpolate import RBFInterpolator

    points, normals = sphere_cloud(300)
    h = np.random.default_rng(3).normal(0.0, 0.02, 300)
    points = points + h[:, None] * normals
    eps, mu = 0.05, 0.02
    probes = np.random.default_rng(4).uniform(-1.2, 1.2, (200, 3))
    x = np.vstack([points, points + eps * normals, points - eps * normals])
    y = np.concatenate([np.zeros(300), np.full(300, eps), np.full(300, -eps)])
    want = RBFInterpolator(x, y, kernel="linear", degree=1, smoothing=mu)(probes)
    for solver in ("dense", "iterative"):
        got = zeroset.fit(
            points, normals, offset=eps, smoothing=mu, outlier_ratio=0, solver=solver
        )
        assert got.report.smoothing == mu
        np.testing.assert_allclose(got(probes), want, rtol=0, atol=1e-8 * np.abs(want).max())


def test_rbf_smoothing_options_are_checked(sphere):
    points, normals = sphere
    for bad, message in [
        ("some", "'auto' or a number"),
        (-1.0, "finite number >= 0"),
        (float("nan"), "finite number >= 0"),
    ]:
        with pytest.raises(ValueError, match=message):
            zeroset.fit(points, normals, smoothing=bad)
    with pytest.raises(ValueError, match="drop hermite"):
        zeroset.fit(points, normals, smoothing=0.1, hermite=True)
    with pytest.raises(ValueError, match="give one or the other"):
        zeroset.fit(points, normals, smoothing=0.1, tolerance=1e-3)
    with pytest.raises(ValueError, match="calibrated for kernel='r'"):
        zeroset.fit(points, normals, smoothing="auto", kernel="r3")
    with pytest.raises(ValueError, match="applies to method='rbf'"):
        zeroset.fit(points, normals, method="mras", smoothing=0.1)


@pytest.mark.parametrize(
    "points, normals, message",
    [
        (np.zeros((5, 2)), np.zeros((5, 3)), r"points must have shape \(n, 3\)"),
        (np.ones((5, 3)), np.ones((4, 3)), "same length"),
        (np.array([[0, 0, np.nan]] * 3), np.ones((3, 3)), r"points\[0\].*not finite"),
        (np.ones((3, 3)), np.array([[0, np.inf, 0]] * 3), r"normals\[0\].*not finite"),
        (np.zeros((0, 3)), np.zeros((0, 3)), "no constraints"),
    ],
    ids=["shape", "lengths", "nan", "inf", "empty"],
)
def test_bad_clouds_are_value_errors(points, normals, message):
    with pytest.raises(ValueError, match=message):
        zeroset.fit(points, normals)


def test_bad_options_are_value_errors(sphere):
    points, normals = sphere
    with pytest.raises(ValueError, match="method must be"):
        zeroset.fit(points, normals, method="poisson")
    with pytest.raises(ValueError, match="kernel must be"):
        zeroset.fit(points, normals, kernel="gauss")
    with pytest.raises(ValueError, match="solver must be"):
        zeroset.fit(points, normals, solver="magic")
    with pytest.raises(ValueError, match="apply to method='rbf'"):
        zeroset.fit(points, normals, method="neural", kernel="r")
    with pytest.raises(ValueError, match="activation"):
        zeroset.fit(points, normals, method="neural", activation="relu", steps=1)


def test_files_errors_are_os_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        zeroset.load(tmp_path / "missing.zsf")
    with pytest.raises(FileNotFoundError):
        zeroset.read_points(tmp_path / "missing.ply")
    bad = tmp_path / "bad.zsf"
    bad.write_bytes(b"ZSF\x00 not really")
    with pytest.raises(ValueError):
        zeroset.load(bad)
    truncated = tmp_path / "cloud.xyzn"
    truncated.write_text("0 0 0 0 0 1\n1 1 1 0 0 nan\n")
    with pytest.raises(ValueError, match="record 1 has a non-finite nz"):
        zeroset.read_points(truncated)


def test_progress_is_called_and_its_exception_stops_the_fit(sphere):
    points, normals = sphere
    seen = []
    zeroset.fit(
        points,
        normals,
        solver="iterative",
        progress=lambda stage, done, total: seen.append((stage, done)),
    )
    assert seen and seen[0] == ("rbf", 1)

    class Stop(Exception):
        pass

    def stop(stage, done, total):
        raise Stop("enough")

    with pytest.raises(Stop, match="enough"):
        zeroset.fit(points, normals, method="neural", steps=500, progress=stop)
    with pytest.raises(TypeError, match="progress must be"):
        zeroset.fit(points, normals, progress=3)


def test_a_progress_callback_stops_an_mras_fit():
    points, normals = zeroset.sample_points()
    start = time.perf_counter()
    zeroset.fit(points, normals, method="mras")
    whole = time.perf_counter() - start

    class Stop(Exception):
        pass

    calls = []

    def stop(stage, done, total):
        calls.append(stage)
        raise Stop("enough")

    start = time.perf_counter()
    with pytest.raises(Stop):
        zeroset.fit(points, normals, method="mras", progress=stop)
    stopped = time.perf_counter() - start
    assert calls == ["mras level 1 fitting"]
    # Stopped after the root cell, not after every level (before, the fit ran to its end).
    assert stopped < 0.5 * whole, (stopped, whole)


# The child installs Python's own SIGINT handler: a process started with SIGINT ignored (a job
# a shell runs in the background, as some CI runners do) passes that on, and Python then
# installs none — Ctrl-C would be ignored, whatever zeroset does.
CHILD = """
import signal, sys, zeroset
signal.signal(signal.SIGINT, signal.default_int_handler)
p, n = zeroset.sample_points()
def started(stage, done, total):
    if done == 1:
        print("started", flush=True)
try:
    zeroset.fit(p, n, method="neural", steps=10**7, progress=started)
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process")
def test_ctrl_c_stops_a_fit_whose_reports_come_from_worker_threads():
    # The neural fit reports from a worker thread, where Python cannot see signals: the
    # calling thread watches for them.
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdout=subprocess.PIPE, text=True
    )
    ready, _, _ = select.select([child.stdout], [], [], 60)
    if not ready:
        child.kill()
        pytest.fail("the neural fit never reported")
    assert child.stdout.readline().strip() == "started"
    start = time.monotonic()
    child.send_signal(signal.SIGINT)
    try:
        out, _ = child.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        child.kill()
        child.communicate()
        pytest.fail("the fit did not stop within 60 s of Ctrl-C")
    assert out.strip() == "KeyboardInterrupt"
    assert time.monotonic() - start < 10


def test_reports_read_as_mappings_and_copy(sphere_field):
    import copy
    import pickle

    r = sphere_field.report
    assert r["method"] == r.method == "rbf"
    assert "iterations" in r and "nothing" not in r
    assert dict(r) == r.as_dict() and list(r) == list(r.keys())
    assert r.get("nothing", 7) == 7
    with pytest.raises(KeyError, match="has no 'nothing'"):
        r["nothing"]
    # GMRES reached its target: None (was NaN, which made a report unequal to its copy)
    assert r.gmres_stalled_at is None
    for copied in (copy.copy(r), copy.deepcopy(r), pickle.loads(pickle.dumps(r))):
        assert isinstance(copied, zeroset.Report) and copied == r


def test_the_gil_is_released_while_fitting():
    points, normals = sphere_cloud(200)
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    start = time.perf_counter()
    try:
        zeroset.fit(points, normals, method="neural", steps=1500)
    finally:
        done.set()
        t.join()
    during = [x for x in ticks if x >= start]
    # the counting thread kept running (a held GIL would leave it one tick or none)
    assert len(during) > 20, len(during)


def test_the_rbf_fit_agrees_with_scipy_rbf_interpolator(sphere):
    interpolate = pytest.importorskip("scipy.interpolate")
    points, normals = sphere_cloud(300)
    eps = 0.05
    centres = np.vstack([points, points + eps * normals, points - eps * normals])
    values = np.concatenate([np.zeros(300), np.full(300, eps), np.full(300, -eps)])
    theirs = interpolate.RBFInterpolator(centres, values, kernel="linear", degree=1)
    ours = zeroset.fit(points, normals, offset=eps)
    assert ours.report.smallest_offset == eps
    p = np.random.default_rng(10).uniform(-1.3, 1.3, size=(500, 3))
    assert np.abs(ours(p) - theirs(p)).max() < 1e-9


def test_estimated_normals_are_outward_and_the_commands(tmp_path, zeroset_bin):
    points, normals = sphere_cloud(800)
    estimated = zeroset.estimate_normals(points)
    assert estimated.shape == (800, 3)
    assert np.all((estimated * normals).sum(axis=1) > np.cos(np.radians(3)))
    # `zeroset normals` on the same positions writes the same bits (xyzn keeps every digit).
    xyz = tmp_path / "sphere.xyz"
    np.savetxt(xyz, points, fmt="%.17g")
    out = tmp_path / "sphere.xyzn"
    subprocess.run([zeroset_bin, "normals", str(xyz), "-o", str(out), "--quiet"], check=True)
    written = np.loadtxt(out)
    np.testing.assert_array_equal(written[:, :3], points)
    np.testing.assert_array_equal(written[:, 3:], estimated)
    # Seen from the centre (a room scanned from inside): every normal faces it.
    inward = zeroset.estimate_normals(points, viewpoint=(0.0, 0.0, 0.0))
    np.testing.assert_array_equal(inward, -estimated)
    # The same scanner given for every point is that viewpoint.
    scanners = np.zeros_like(points)
    np.testing.assert_array_equal(zeroset.estimate_normals(points, scanners=scanners), inward)
    # The estimate fits like a scan's own normals.
    field = zeroset.fit(points, estimated)
    assert field(np.zeros(3)) < -0.5 and field(np.array([1.2, 0, 0])) > 0


def test_estimate_normals_rejects_bad_input():
    points, _ = sphere_cloud(100)
    bad = points.copy()
    bad[7, 2] = np.nan
    with pytest.raises(ValueError, match=r"points\[7\]"):
        zeroset.estimate_normals(bad)
    with pytest.raises(ValueError, match="at least 3 points"):
        zeroset.estimate_normals(points[:2])
    for k in (1, -3, 257):
        with pytest.raises(ValueError, match=f"neighbours = {k}"):
            zeroset.estimate_normals(points, neighbours=k)
    line = np.stack([np.arange(50.0), 2 * np.arange(50.0), np.zeros(50)], axis=1)
    with pytest.raises(ValueError, match="span no plane"):
        zeroset.estimate_normals(line)
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        zeroset.estimate_normals(points[:, :2])
    with pytest.raises(ValueError, match="viewpoint"):
        zeroset.estimate_normals(points, viewpoint=(0.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match="99 scanner positions for 100 points"):
        zeroset.estimate_normals(points, scanners=np.zeros((99, 3)))
    with pytest.raises(ValueError, match="not both"):
        zeroset.estimate_normals(points, viewpoint=(0, 0, 0), scanners=np.zeros((100, 3)))


def test_points_that_fill_a_volume_are_warned_of():
    # 600 random points filling a 2 x 1 x 1 brick, with made-up normals away from its centre.
    brick = np.random.default_rng(3).random((600, 3)) * [2.0, 1.0, 1.0]
    away = brick - brick.mean(axis=0)
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    said = "600 points fill a volume rather than sample a surface: at every scale from 32 to 64 neighbours"
    with pytest.warns(UserWarning, match=said):
        zeroset.estimate_normals(brick)
    with pytest.warns(UserWarning, match=said):
        field = zeroset.fit(brick, away, smoothing="auto")
    assert field.report["thickness"] > 0.35
    # A sphere's points: thin, and nothing said.
    points, normals = sphere_cloud(600)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        zeroset.estimate_normals(points)
        field = zeroset.fit(points, normals)
    assert field.report["thickness"] < 0.05
    # Under 256 distinct positions nothing is read.
    assert "thickness" not in zeroset.fit(*sphere_cloud(200)).report


def test_missing_normals_are_completed_and_fit_like_the_command(tmp_path, zeroset_bin):
    points, truth = sphere_cloud(1200)
    holed = truth.copy()
    lost = np.flatnonzero((np.arange(1200) % 9 == 0) | (points[:, 2] > 0.9))
    holed[lost] = 0.0
    before = holed.copy()
    completed, filled = zeroset.fill_missing_normals(points, holed)
    np.testing.assert_array_equal(holed, before)  # the input is not modified
    np.testing.assert_array_equal(filled, lost)
    assert filled.dtype == np.intp
    np.testing.assert_array_equal(np.delete(completed, lost, 0), np.delete(truth, lost, 0))
    cos = (completed[lost] * truth[lost]).sum(axis=1)
    assert cos.min() > np.cos(np.radians(5)), cos.min()
    np.testing.assert_allclose(np.linalg.norm(completed, axis=1), 1.0, atol=1e-12)
    # Nothing missing: the normals back, nothing filled.
    same, none = zeroset.fill_missing_normals(points, truth)
    np.testing.assert_array_equal(same, truth)
    assert none.size == 0
    # `fit` refuses the zeros and names the cure; `zeroset fit` completes them itself, and
    # fits the field Python fits to the completed normals, bit for bit.
    with pytest.raises(ValueError, match=rf"{lost.size} of the 1200 normals are 0 0 0 \(row 0 "
                       r"first\).*fill_missing_normals"):
        zeroset.fit(points, holed)
    with pytest.raises(ValueError, match="every normal is 0 0 0.*estimate_normals"):
        zeroset.fit(points, np.zeros_like(points))
    cloud = tmp_path / "holed.xyzn"
    np.savetxt(cloud, np.hstack([points, holed]), fmt="%.17g")
    rust = tmp_path / "holed.zsf"
    subprocess.run(
        [zeroset_bin, "fit", str(cloud), "--method", "rbf", "-o", str(rust), "--quiet"],
        check=True, capture_output=True,
    )
    ours = zeroset.fit(points, completed)
    probes = np.random.default_rng(3).uniform(-1.3, 1.3, (500, 3))
    np.testing.assert_array_equal(zeroset.load(rust)(probes), ours(probes))


def test_fill_missing_normals_rejects_bad_input():
    points, normals = sphere_cloud(100)
    with pytest.raises(ValueError, match="every one of the 100 normals is zero"):
        zeroset.fill_missing_normals(points, np.zeros_like(points))
    bad = normals.copy()
    bad[4] = (np.nan, 0.0, 1.0)
    with pytest.raises(ValueError, match=r"point 4: normal .* is not finite"):
        zeroset.fill_missing_normals(points, bad)
    bad = points.copy()
    bad[6, 0] = np.inf
    with pytest.raises(ValueError, match=r"point 6: position .* is not finite"):
        zeroset.fill_missing_normals(bad, normals)
    with pytest.raises(ValueError, match="99 normals for 100 points"):
        zeroset.fill_missing_normals(points, normals[:99])
    for k in (1, -3, 257):
        with pytest.raises(ValueError, match=f"neighbours = {k}"):
            zeroset.fill_missing_normals(points, normals, neighbours=k)
    with pytest.raises(TypeError, match="whole number"):
        zeroset.fill_missing_normals(points, normals, neighbours=2.5)


def test_unoriented_normals_are_told_and_turned():
    points, truth = sphere_cloud(1000)
    up = np.where(points[:, 2:3] < 0, -truth, truth)  # each line right, the lower half inward
    oriented, report = zeroset.orient_normals(points, up)
    assert report.unoriented and report.turned == int((points[:, 2] < 0).sum())
    assert report.inconsistent > 0.4 * len(points) and report.points == 1000
    assert not report.facing_in and report.rays_cast == 0  # told by the share
    np.testing.assert_allclose(oriented, truth, atol=1e-12)
    # A cap of a fifth of the normals facing in: told by rays cast along them.
    cap = np.where(points[:, 2:3] > 0.6, -truth, truth)
    capped, cap_report = zeroset.orient_normals(points, cap)
    assert cap_report.facing_in and cap_report.unoriented, cap_report
    assert cap_report.rays_inward * 10 >= cap_report.rays_cast * 9 > 0, cap_report
    assert cap_report.rays_outward * 10 <= cap_report.rays_cast, cap_report
    assert cap_report.consistent_rays_cast > 0, cap_report
    assert cap_report.consistent_rays_inward * 10 <= cap_report.consistent_rays_cast, cap_report
    np.testing.assert_allclose(capped, truth, atol=1e-12)
    # Oriented normals: consistent, none turned, returned as they were.
    again, clean = zeroset.orient_normals(points, truth)
    assert not clean.unoriented and clean.inconsistent == 0 and clean.turned == 0
    np.testing.assert_allclose(again, truth, atol=1e-12)
    # Towards a viewpoint inside: every one turned inward.
    inward, seen = zeroset.orient_normals(points, truth, viewpoint=(0, 0, 0))
    np.testing.assert_allclose(inward, -truth, atol=1e-12)
    assert seen.turned == 1000 and seen.inconsistent == 0
    with pytest.raises(ValueError, match="99 normals for 100 points"):
        zeroset.orient_normals(points[:100], truth[:99])
    with pytest.raises(ValueError, match=r"normals\[2\].*not finite"):
        bad = truth.copy()
        bad[2, 1] = np.nan
        zeroset.orient_normals(points, bad)


def test_read_points_takes_pcd_and_named_text_columns(tmp_path):
    rng = np.random.default_rng(3)
    points = rng.normal(size=(50, 3)).astype(np.float32)
    normals = points / np.linalg.norm(points, axis=1, keepdims=True)
    # A binary PCD as PCL writes it: x y z, then an rgb field, then PCL's normal names.
    record = np.dtype(
        [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4"),
         ("normal_x", "<f4"), ("normal_y", "<f4"), ("normal_z", "<f4")]
    )
    rows = np.zeros(len(points), dtype=record)
    for i, axis in enumerate("xyz"):
        rows[axis] = points[:, i]
        rows[f"normal_{axis}"] = normals[:, i]
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        "FIELDS x y z rgb normal_x normal_y normal_z\nSIZE 4 4 4 4 4 4 4\n"
        "TYPE F F F U F F F\nCOUNT 1 1 1 1 1 1 1\n"
        f"WIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(points)}\n"
        "DATA binary\n"
    )
    path = tmp_path / "scan.pcd"
    path.write_bytes(header.encode() + rows.tobytes())
    read_p, read_n = zeroset.read_points(path)
    assert np.array_equal(read_p, points.astype(np.float64))
    assert np.array_equal(read_n, normals.astype(np.float64))
    # CloudCompare's text export, colours before the normal, names on the first line.
    text = tmp_path / "scan.txt"
    lines = ["//X,Y,Z,R,G,B,Nx,Ny,Nz"] + [
        ",".join(f"{v!r}" for v in (*p.tolist(), 10, 20, 30, *n.tolist()))
        for p, n in zip(points.astype(np.float64), normals.astype(np.float64))
    ]
    text.write_text("\n".join(lines) + "\n")
    read_p, read_n = zeroset.read_points(text)
    assert np.array_equal(read_p, points.astype(np.float64))
    assert np.array_equal(read_n, normals.astype(np.float64))


def test_read_points_takes_one_formation_of_a_gempy_table(tmp_path):
    table = tmp_path / "orientations.csv"
    table.write_text(
        "X,Y,Z,G_x,G_y,G_z,surface\n"
        "0,0,0,0,0,2,Shale\n1,0,0,1,0,0,Sand\n2,0,0,0,-1,0,Shale\n"
    )
    points, normals = zeroset.read_points(table)
    assert points.shape == (3, 3) and normals.shape == (3, 3)
    points, normals = zeroset.read_points(table, formation="Shale")
    assert np.array_equal(points, [[0, 0, 0], [2, 0, 0]])
    assert np.allclose(normals, [[0, 0, 1], [0, -1, 0]], atol=1e-15)
    with pytest.raises(ValueError, match="no row of formation 'Clay'.*Sand, Shale"):
        zeroset.read_points(table, formation="Clay")


def test_read_points_takes_e57_laser_scans():
    # Written by libE57Format (benches/peers/format_fixtures.py): two scans, the second under a
    # pose, as integers scaled by 1e-7, with four records flagged invalid; normals rotated with
    # the scan. Read back into the file's frame, they are the text file's points.
    from conftest import REPO

    data = REPO / "crates/field-core/tests/data"
    want = np.loadtxt(data / "bunny300.xyzn")
    points, normals = zeroset.read_points(data / "bunny300.e57")
    assert points.shape == (300, 3)
    assert np.abs(points - want[:, :3]).max() < 2e-7
    assert np.abs(normals - want[:, 3:6]).max() < 1e-6
    points, normals = zeroset.read_points(data / "bunny300_spherical.e57")
    assert normals is None
    assert np.abs(points - want[:, :3]).max() < 1e-12
    # With each scan's summary and each point's scan origin (its pose's translation).
    points, normals, origins, scans = zeroset.read_e57(data / "bunny300.e57")
    assert points.shape == normals.shape == origins.shape == (300, 3)
    assert [(s["records"], s["points"], s["coordinates"], s["normals"]) for s in scans] == [
        (150, 150, "cartesian", True),
        (154, 150, "cartesian", True),
    ]
    np.testing.assert_array_equal(origins[:150], 0.0)
    np.testing.assert_array_equal(origins[150:], [[0.5, -0.25, 1.75]] * 150)
    assert scans[1]["origin"] == (0.5, -0.25, 1.75)
    inward = zeroset.estimate_normals(points, scanners=origins)
    assert inward.shape == (300, 3)


def test_counts_are_checked_before_they_reach_the_native_layer(sphere):
    points, normals = sphere
    # Negative counts were OverflowError from the conversion to an unsigned integer.
    for kwargs, name in (
        (dict(method="mras", max_level=-1), "max_level"),
        (dict(method="neural", steps=-1), "steps"),
        (dict(method="neural", seed=-1), "seed"),
    ):
        with pytest.raises(ValueError, match=f"{name} must be >= 0"):
            zeroset.fit(points, normals, **kwargs)
    with pytest.raises(ValueError, match="max_iter must be >= 0"):
        zeroset.lstsq(np.eye(3), np.ones(3), max_iter=-1)
    with pytest.raises(ValueError, match="rank must be >= 0"):
        zeroset.cp_als(np.ones((3, 3, 3)), rank=-1)
    # A count that is not whole is refused, not truncated.
    with pytest.raises(TypeError, match="neighbours must be a whole number"):
        zeroset.estimate_normals(points, 2.7)
    with pytest.raises(TypeError, match="resolution must be a whole number"):
        zeroset.mesh(zeroset.fit(points, normals), resolution=64.0)

