"""Least squares against numpy and scipy on manufactured problems; CP-ALS on planted
low-rank tensors; singular-value thresholding against its definition."""

import numpy as np
import pytest

import zeroset

sparse = pytest.importorskip("scipy.sparse")
splinalg = pytest.importorskip("scipy.sparse.linalg")


def laplacian_problem(n=30, seed=0):
    """A 2-D Laplacian stacked over a scaled identity (full column rank), and b."""
    rng = np.random.default_rng(seed)
    d = sparse.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    lap = sparse.kronsum(d, d).tocsr()
    a = sparse.vstack([lap, 0.1 * sparse.identity(n * n)]).tocsr()
    b = rng.standard_normal(a.shape[0])
    return a, b


@pytest.mark.parametrize("solver", ["lsqr", "cgls", "pcg", "qr", "lu", "sparse_qr", "cholesky"])
def test_every_solver_agrees_with_scipy(solver):
    a, b = laplacian_problem()
    want = splinalg.lsqr(a, b, atol=1e-14, btol=1e-14, iter_lim=20000)[0]
    x, info = zeroset.lstsq(a, b, solver=solver, return_info=True)
    assert np.abs(x - want).max() < 1e-7 * np.abs(want).max()
    assert info.rel_residual < 1
    dense = zeroset.lstsq(a.toarray(), b, solver=solver)
    assert np.abs(dense - want).max() < 1e-7 * np.abs(want).max()


def test_dense_least_squares_matches_numpy():
    rng = np.random.default_rng(5)
    a = rng.standard_normal((80, 12))
    b = rng.standard_normal(80)
    want = np.linalg.lstsq(a, b, rcond=None)[0]
    for solver in ("qr", "lsqr"):
        assert np.allclose(zeroset.lstsq(a, b, solver=solver), want, atol=1e-9)
    # Fortran order, float32, and lists give the same answer
    assert np.allclose(zeroset.lstsq(np.asfortranarray(a), b, solver="qr"), want, atol=1e-9)
    assert np.allclose(zeroset.lstsq(a.tolist(), b.tolist(), solver="qr"), want, atol=1e-9)


def test_sparse_formats_with_duplicates_and_unsorted_indices():
    a, b = laplacian_problem(12)
    want = zeroset.lstsq(a, b, solver="sparse_qr")
    coo = a.tocoo()
    # every entry split in two halves: duplicates that scipy sums
    dup = sparse.coo_matrix(
        (np.concatenate([coo.data / 2, coo.data / 2]),
         (np.concatenate([coo.row, coo.row]), np.concatenate([coo.col, coo.col]))),
        shape=a.shape,
    )
    for m in (a.tocsc(), coo, dup, sparse.csr_array(a)):
        assert np.allclose(zeroset.lstsq(m, b, solver="sparse_qr"), want, atol=1e-10)
    unsorted = a.copy()
    unsorted.has_sorted_indices = False
    for i in range(unsorted.shape[0]):
        s, e = unsorted.indptr[i], unsorted.indptr[i + 1]
        unsorted.indices[s:e] = unsorted.indices[s:e][::-1]
        unsorted.data[s:e] = unsorted.data[s:e][::-1]
    assert np.allclose(zeroset.lstsq(unsorted, b, solver="sparse_qr"), want, atol=1e-10)


def test_bad_systems_are_value_errors():
    a, b = laplacian_problem(5)
    with pytest.raises(ValueError, match="rows"):
        zeroset.lstsq(a, b[:-1])
    with pytest.raises(ValueError, match="solver must be"):
        zeroset.lstsq(a, b, solver="magic")
    bad = a.toarray()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        zeroset.lstsq(bad, b, solver="qr")
    with pytest.raises(ValueError):
        zeroset.lstsq(a, b, solver="lsqr", max_iter=2, tol=1e-14)


def test_cp_als_recovers_a_planted_low_rank_tensor():
    rng = np.random.default_rng(6)
    factors = [rng.standard_normal((d, 3)) for d in (7, 8, 9)]
    x = np.einsum("ir,jr,kr->ijk", *factors)
    (weights, (a, b, c)), errors = zeroset.cp_als(x, 3, tol=1e-14, n_iter_max=2000,
                                                  return_errors=True)
    back = np.einsum("r,ir,jr,kr->ijk", weights, a, b, c)
    assert np.linalg.norm(back - x) / np.linalg.norm(x) < 1e-8
    assert errors[-1] < 1e-6 and len(errors) >= 2  # the tracked error
    w2, f2 = zeroset.cp_als(x, 3, tol=1e-14, n_iter_max=2000)
    assert np.array_equal(w2, weights) and all(np.array_equal(p, q) for p, q in zip(f2, (a, b, c)))
    w3, _ = zeroset.cp_als(x, 3, init="random", random_state=3, n_iter_max=50)
    assert w3.shape == (3,)
    with pytest.raises(ValueError, match="3-way"):
        zeroset.cp_als(x[0], 2)
    with pytest.raises(ValueError):
        zeroset.cp_als(x, 0)


def test_svt_is_the_shrunk_svd():
    rng = np.random.default_rng(7)
    m = rng.standard_normal((9, 6))
    u, s, vt = np.linalg.svd(m, full_matrices=False)
    tau = s[2] * 0.999
    want = (u * np.maximum(s - tau, 0)) @ vt
    got, rank = zeroset.svt(m, tau, return_rank=True)
    assert rank == 3 and np.allclose(got, want, atol=1e-12)
    assert np.allclose(zeroset.svt(m, 0.0), m, atol=1e-12)
