"""The scipy / scikit-image / TensorLy calls of an implicit-surface workflow and their zeroset
equivalents, side by side on the same input, each checked to agree (timed by
`benches/peers/python_peers.py`, not here).

    python crates/python/examples/from_scipy.py

Needs scipy and scikit-image (and TensorLy for the last step, skipped without it).
"""

import numpy as np

import zeroset

points, normals = zeroset.sample_points()
eps = 1e-3  # the off-surface offset, fixed so that both sides fit the same constraints

# 1. RBF implicit surface: scipy needs the off-surface points spelled out; zeroset builds them.
from scipy.interpolate import RBFInterpolator

centres = np.vstack([points, points + eps * normals, points - eps * normals])
values = np.concatenate([np.zeros(len(points)), np.full(len(points), eps), np.full(len(points), -eps)])
scipy_field = RBFInterpolator(centres, values, kernel="linear", degree=1)
field = zeroset.fit(points, normals, kernel="r", offset=eps)
probe = np.random.default_rng(0).uniform(points.min(0), points.max(0), size=(1000, 3))
print("RBF: max |scipy - zeroset| =", np.abs(scipy_field(probe) - field(probe)).max())

# 2. Marching cubes on a volume: the same arguments and results as scikit-image.
from skimage.measure import marching_cubes

lo, hi = field.bounds
n = 64
axes = [np.linspace(lo[a], hi[a], n) for a in range(3)]
volume = field(np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)).reshape(n, n, n)
spacing = tuple((hi - lo) / (n - 1))
sk = marching_cubes(volume, 0.0, spacing=spacing)
zs = zeroset.marching_cubes(volume, 0.0, spacing=spacing)
print("marching cubes: vertices", len(sk[0]), "(skimage)", len(zs[0]), "(zeroset)")
# or straight from the field, normals pointing out:
verts, faces, vnormals = zeroset.mesh(field, resolution=n)

# 3. Sparse least squares: lsqr with the same tolerances.
import scipy.sparse as sp
from scipy.sparse.linalg import lsqr

d = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(40, 40))
A = sp.vstack([sp.kronsum(d, d), 0.1 * sp.identity(1600)]).tocsr()
b = np.random.default_rng(1).standard_normal(A.shape[0])
x_scipy = lsqr(A, b, atol=1e-10, btol=1e-10)[0]
x, info = zeroset.lstsq(A, b, solver="lsqr", tol=1e-10, return_info=True)
print("lsqr: max |difference| =", np.abs(x - x_scipy).max(), "|", info)
print("      sparse QR (direct):", np.abs(zeroset.lstsq(A, b, solver="sparse_qr") - x_scipy).max())

# 4. CP decomposition: TensorLy's parafac arguments, (weights, factors) back.
rng = np.random.default_rng(2)
X = np.einsum("ir,jr,kr->ijk", *[rng.standard_normal((20, 4)) for _ in range(3)])
weights, factors = zeroset.cp_als(X, 4, init="svd", tol=1e-12, n_iter_max=1000)
err = np.linalg.norm(np.einsum("r,ir,jr,kr->ijk", weights, *factors) - X) / np.linalg.norm(X)
print("cp_als: relative error", err)
try:
    import tensorly as tl
    from tensorly.decomposition import parafac

    cp = parafac(X, 4, init="svd", tol=1e-12, n_iter_max=1000)
    print("parafac: relative error", np.linalg.norm(tl.cp_to_tensor(cp) - X) / np.linalg.norm(X))
except ImportError:
    print("(TensorLy not installed: parafac skipped)")
