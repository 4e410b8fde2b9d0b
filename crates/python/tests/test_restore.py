"""Restoration: a protrusion removed from an analytic shape, de-noising, fields given as
callables and grids, and the bundled demo."""

import numpy as np
import pytest

import zeroset


def bumpy_sphere(p):
    """A unit sphere with a thin spike along +z up to z = 1.6 (negative inside)."""
    p = np.atleast_2d(p)
    sphere = np.linalg.norm(p, axis=1) - 1.0
    spike = np.maximum(np.hypot(p[:, 0], p[:, 1]) - 0.12, np.abs(p[:, 2] - 1.1) - 0.5)
    return np.minimum(sphere, spike)


BOX = (np.full(3, -1.8), np.full(3, 1.8))
MASK = ((-0.4, -0.4, 1.0), (0.4, 0.4, 1.75))


def test_protrusion_removal_takes_the_spike_off():
    restored = zeroset.restore(bumpy_sphere, MASK, face="-z", bounds=BOX)
    assert restored.kind == "bspline" and restored.report.unknowns > 0
    top = np.array([[0.0, 0.0, 1.3], [0.0, 0.0, 1.5]])
    assert np.all(bumpy_sphere(top) < 0)  # inside the spike before
    assert np.all(restored(top) > 0)  # outside after
    # outside the mask the field is the original one, up to the spline's interpolation
    far = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    assert np.abs(restored(far)).max() < 0.02


def test_a_grid_of_samples_restores_like_the_callable():
    n = 64
    h = 3.6 / n
    axes = -1.8 + (np.arange(n) + 0.5) * h
    g = np.stack(np.meshgrid(axes, axes, axes, indexing="ij"), axis=-1).reshape(-1, 3)
    volume = bumpy_sphere(g).reshape(n, n, n)
    from_grid = zeroset.restore(volume, MASK, face="-z", spacing=h, origin=axes[0])
    from_callable = zeroset.restore(bumpy_sphere, MASK, face="-z", bounds=BOX)
    p = np.random.default_rng(8).uniform(-1.5, 1.5, size=(100, 3))
    assert np.allclose(from_grid(p), from_callable(p), atol=1e-12)


def test_denoise_smooths_inside_the_mask():
    rng = np.random.default_rng(9)
    noise = rng.standard_normal((48, 48, 48)) * 0.02
    h = 3.6 / 48
    axes = -1.8 + (np.arange(48) + 0.5) * h
    g = np.stack(np.meshgrid(axes, axes, axes, indexing="ij"), axis=-1).reshape(-1, 3)
    clean = (np.linalg.norm(g, axis=1) - 1.0).reshape(48, 48, 48)
    noisy = zeroset.restore(clean + noise, ((-1, -1, -1), (1, 1, 1)), mode="denoise",
                            coarse=(6, 6, 6), spacing=h, origin=axes[0])
    inside = g[np.all(np.abs(g) < 0.9, axis=1)]
    err_after = np.abs(noisy(inside) - (np.linalg.norm(inside, axis=1) - 1)).mean()
    assert err_after < 0.5 * 0.02 * np.sqrt(2 / np.pi)  # below the noise's mean deviation


def test_denoise_takes_the_papers_point_rule_and_reports_whole_numbers(sphere_field):
    mask = ((-0.5, -0.5, 0.4), (0.5, 0.5, 1.2))
    area = zeroset.restore(sphere_field, mask, mode="denoise", coarse=4)
    point = zeroset.restore(sphere_field, mask, mode="denoise", coarse=4, point_resampling=True)
    p = np.random.default_rng(4).uniform(-0.4, 0.4, size=(50, 3)) + [0, 0, 0.8]
    assert not np.array_equal(area(p), point(p))
    assert np.abs(area(p) - point(p)).max() < 0.05
    assert all(type(c) is int for c in area.report.grid) and len(area.report.grid) == 3
    with pytest.raises(ValueError, match="apply to mode='denoise'"):
        zeroset.restore(sphere_field, mask, point_resampling=True)


def test_bad_counts_are_named_before_the_native_layer(sphere_field):
    mask = ((-0.5, -0.5, 0.4), (0.5, 0.5, 1.2))
    with pytest.raises(TypeError, match="coarse must be a whole number"):
        zeroset.restore(sphere_field, mask, mode="denoise", coarse=(2.5, 3, 3))
    with pytest.raises(ValueError, match="coarse must be >= 0"):
        zeroset.restore(sphere_field, mask, mode="denoise", coarse=(-1, 3, 3))
    with pytest.raises(ValueError, match="at least 3 cells per axis"):
        zeroset.restore(sphere_field, mask, grid=(0, 40, 40))


def test_a_mask_reaching_beyond_the_grid_is_cut_to_it(sphere_field):
    lo, hi = sphere_field.bounds
    inside = ((-0.3, -0.3, 0.4), (0.3, 0.3, hi[2] - 0.05))
    beyond = ((-0.3, -0.3, 0.4), (0.3, 0.3, hi[2] + 5.0))
    plain = zeroset.restore(sphere_field, inside, face="-z")
    assert plain.report.mask_cut_axes == []
    with pytest.warns(UserWarning, match="beyond the sampling grid's box on z"):
        cut = zeroset.restore(sphere_field, beyond, face="-z")
    assert cut.report.mask_cut_axes == [2] and cut.report.mask_cells > plain.report.mask_cells


def test_bad_masks_and_modes_are_value_errors(sphere_field):
    with pytest.raises(ValueError, match="mask must lie"):
        zeroset.restore(sphere_field, ((5, 5, 5), (6, 6, 6)))
    with pytest.raises(ValueError, match="face"):
        zeroset.restore(sphere_field, ((-0.2, -0.2, 0.5), (0.2, 0.2, 1.0)), face="up")
    with pytest.raises(ValueError, match="coarse"):
        zeroset.restore(sphere_field, ((-0.2, -0.2, 0.5), (0.2, 0.2, 1.0)), mode="denoise")
    with pytest.raises(ValueError, match="mode must be"):
        zeroset.restore(sphere_field, ((-0.2, -0.2, 0.5), (0.2, 0.2, 1.0)), mode="smooth")
    with pytest.raises(ValueError, match="mask must be"):
        zeroset.restore(sphere_field, (1, 2, 3))
    with pytest.raises(ValueError, match="bounds"):
        zeroset.restore(bumpy_sphere, MASK)


def test_demo_runs_the_pipeline_on_the_bundled_sample(tmp_path):
    out = zeroset.demo(tmp_path, quiet=True)
    assert out["points"] == 2000
    assert out["top_restored"] < out["top"] - 0.02  # the ears are gone
    v, f, _ = zeroset.read_mesh(out["mesh"])
    assert len(f) > 1000 and (tmp_path / "bunny_no_ears.ply").is_file()
