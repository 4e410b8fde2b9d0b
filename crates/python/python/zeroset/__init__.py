"""zeroset: implicit surfaces from Python, numpy in and out.

Fit a scalar field to an oriented point cloud (RBF, neural, MRAS), restore it where it went
wrong (protrusion removal, de-noising), and mesh its zero set (marching cubes, or the signed
marching cubes of an RBF field by the fast multipole method); plus the least-squares, CP-ALS
and singular-value-thresholding solvers underneath. The work is done in Rust with the GIL
released; arrays come back as numpy arrays.

>>> import numpy as np, zeroset
>>> points, normals = zeroset.sample_points()          # 2,000 points of the Stanford bunny
>>> field = zeroset.fit(points, normals)               # RBF, kernel r, off-surface points
>>> bool(abs(field(points)).max() < 1e-6)              # it interpolates the points
True
>>> verts, faces, vnormals = zeroset.mesh(field)       # its zero set, marching cubes
>>> faces.shape[1]
3

A field is negative inside and positive outside; its gradient points out of the solid.
Errors are ``ValueError`` (bad input, with the reason), ``OSError`` (files), or
``KeyboardInterrupt`` (Ctrl-C stops long work).
"""

from __future__ import annotations

import math
import operator
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _zeroset as _native

__version__: str = _native.__version__

__all__ = [
    "Field",
    "Report",
    "cp_als",
    "demo",
    "estimate_normals",
    "fill_missing_normals",
    "fit",
    "load",
    "lstsq",
    "marching_cubes",
    "mesh",
    "orient_normals",
    "read_e57",
    "read_mesh",
    "read_points",
    "restore",
    "sample_points",
    "svt",
    "trim_mesh",
    "write_mesh",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Union[None, bool, Callable[[str, int, int], Any]]


class Report:
    """What a computation did: read-only attributes (``report.iterations``,
    ``report.max_residual``, ...) that also read as a mapping (``report["iterations"]``,
    ``"smoothing" in report``, ``dict(report)``), ``as_dict()`` for all of them. Reports copy
    and pickle."""

    __slots__ = ("_items",)

    def __init__(self, items: Dict[str, Any]):
        object.__setattr__(self, "_items", dict(items))

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            # copy and pickle probe for special methods on an instance without `_items`.
            raise AttributeError(name)
        try:
            return self._items[name]
        except KeyError:
            raise AttributeError(self._missing(name)) from None

    def __getitem__(self, name: str) -> Any:
        try:
            return self._items[name]
        except KeyError:
            raise KeyError(self._missing(name)) from None

    def _missing(self, name: str) -> str:
        return f"the report has no {name!r}; it has {sorted(self._items)}"

    def __contains__(self, name: object) -> bool:
        return name in self._items

    def __iter__(self):
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def keys(self):
        """The report's names."""
        return self._items.keys()

    def get(self, name: str, default: Any = None) -> Any:
        """The value of ``name``, or ``default``."""
        return self._items.get(name, default)

    def __reduce__(self):
        return (Report, (self._items,))

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("a report is read-only")

    def __dir__(self):
        return sorted(self._items)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Report) and self._items == other._items

    def __hash__(self) -> int:
        return hash(tuple(sorted((k, repr(v)) for k, v in self._items.items())))

    def as_dict(self) -> Dict[str, Any]:
        """The report as a new dict."""
        return dict(self._items)

    def __repr__(self) -> str:
        def short(v: Any) -> str:
            if isinstance(v, list) and len(v) > 4:
                return f"[... {len(v)} values]"
            if isinstance(v, float):
                return f"{v:.4g}"
            return repr(v)

        body = ", ".join(f"{k}={short(v)}" for k, v in self._items.items())
        return f"Report({body})"


class _TextBar:
    """``progress=True``: one line on stderr, redrawn at most ten times a second."""

    def __init__(self) -> None:
        self._last = 0.0
        self._shown = False

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = time.monotonic()
        if now - self._last < 0.1 and done != total:
            return
        self._last = now
        text = f"{stage}: {done}/{total}" if total else f"{stage}: {done}"
        sys.stderr.write("\r" + text.ljust(60))
        sys.stderr.flush()
        self._shown = True

    def close(self) -> None:
        if self._shown:
            sys.stderr.write("\n")
            sys.stderr.flush()


def _run(progress: Progress, call: Callable[[Any], Any]) -> Any:
    """Runs ``call(callback)`` with the native callback for ``progress``."""
    if progress is None or progress is False:
        return call(None)
    if progress is True:
        bar = _TextBar()
        try:
            return call(bar)
        finally:
            bar.close()
    if callable(progress):
        return call(progress)
    raise TypeError(
        f"progress must be None, True or a callable (stage, done, total), got {type(progress).__name__}"
    )


def _rows(a: Any, name: str) -> np.ndarray:
    """``a`` as a C-contiguous float64 array of shape (n, 3) (copied only if needed)."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3), got {arr.shape}")
    return np.ascontiguousarray(arr)


def _count(v: Any, name: str, negative: bool = False) -> int:
    """``v`` as a whole number >= 0 (any whole number with ``negative``, for the native layer
    to name its range): ``ValueError`` for a negative one (not the ``OverflowError`` of the
    conversion to an unsigned integer), ``TypeError`` for one that is not whole (2.7 is not
    truncated to 2)."""
    try:
        n = operator.index(v)
    except TypeError:
        raise TypeError(f"{name} must be a whole number, got {v!r}") from None
    if n < 0 and not negative:
        raise ValueError(f"{name} must be >= 0, got {n}")
    return n


def _neighbours(v: Any) -> int:
    """A neighbour count, checked as :func:`_count` but for its range, which a negative one is
    told (the native layer names it for the others)."""
    k = _count(v, "neighbours", negative=True)
    if k < 0:
        raise ValueError(f"neighbours = {k}: from 2 to 256")
    return k


def _counts(v: Any, name: str) -> Tuple[int, int, int]:
    """Three whole numbers >= 0 (or one for all three axes), checked as :func:`_count`."""
    t = _triple(v, name, lambda x: x)
    return tuple(_count(x, name) for x in t)  # type: ignore[return-value]


def _is_default(v: Any, default: float) -> bool:
    """Whether ``v`` is the scalar ``default`` (an argument left as it was)."""
    return np.isscalar(v) and v == default


def _triple(v: Any, name: str, kind: type = float) -> Tuple[Any, Any, Any]:
    if np.isscalar(v):
        return (kind(v),) * 3  # type: ignore[return-value]
    t = tuple(kind(x) for x in v)
    if len(t) != 3:
        raise ValueError(f"{name} must be a number or 3 numbers, got {v!r}")
    return t  # type: ignore[return-value]


class Field:
    """A scalar field on a box of R³: fitted (:func:`fit`), restored (:func:`restore`) or
    loaded (:func:`load`). Negative inside, positive outside.

    ``field(points)`` evaluates it at the rows of an ``(n, 3)`` array (or at one point of
    shape ``(3,)``), ``field.gradient(points)`` gives ``(n, 3)`` gradients, ``field.bounds``
    the box ``(lo, hi)``, ``field.save(path)`` writes an exact ``.zsf`` field file that the
    ``zeroset`` command reads too. ``field.report`` is what made it (``None`` after
    :func:`load`).

    The sign tells inside from outside in the field's box and near it. Far outside, an RBF
    field is its kernel sum's far field, whose sign is not the surface's: on the bundled bunny
    none of the points within a quarter of the diagonal outside the box came out negative, but
    8% of those up to two diagonals away did (MRAS and B-spline fields stayed positive). Test
    points against ``field.bounds`` first.

    Fields pickle (and so go to ``multiprocessing`` workers and ``copy.deepcopy``) as the bytes
    of their ``.zsf`` file, exactly: the copy's values are the original's bit for bit.
    """

    __slots__ = ("_native", "report")

    def __init__(self, native: Any, report: Optional[Report] = None):
        self._native = native
        self.report = report

    def __call__(self, points: Any) -> np.ndarray:
        """The values at the rows of an ``(n, 3)`` array, ``(n,)`` (or at one point of shape
        ``(3,)``, a float): negative inside, positive outside (see the class docs for far from
        the box)."""
        arr = np.asarray(points, dtype=np.float64)
        if arr.shape == (3,):
            return self._native.values(np.ascontiguousarray(arr.reshape(1, 3)))[0]
        return self._native.values(_rows(arr, "points"))

    def gradient(self, points: Any) -> np.ndarray:
        """The gradient at the rows of an ``(n, 3)`` array (or at one point), ``(n, 3)``."""
        arr = np.asarray(points, dtype=np.float64)
        if arr.shape == (3,):
            return self._native.gradients(np.ascontiguousarray(arr.reshape(1, 3)))[0]
        return self._native.gradients(_rows(arr, "points"))

    @property
    def bounds(self) -> Optional[Tuple[np.ndarray, np.ndarray]]:
        """``(lo, hi)``: the box the field is defined on."""
        b = self._native.bounds
        return None if b is None else (np.array(b[0]), np.array(b[1]))

    @property
    def kind(self) -> str:
        """``"rbf"``, ``"bspline"``, ``"neural"`` or ``"mras"``."""
        return self._native.kind

    @property
    def centres(self) -> Optional[np.ndarray]:
        """The centres of an RBF field (the points it was fitted to), else ``None``."""
        return self._native.centres()

    def save(self, path: PathLike) -> None:
        """Writes the field to a ``.zsf`` field file (exact, atomic: an existing file is
        replaced only once the new one is complete)."""
        self._native.save(os.fspath(path))

    def __reduce__(self):
        return (_field_from_bytes, (self._native.to_bytes(), self.report))

    def __repr__(self) -> str:
        return f"<zeroset.Field: {self._native.describe()}>"


def _field_from_bytes(data: bytes, report: Optional[Report]) -> Field:
    """Unpickles a :class:`Field` (see ``Field.__reduce__``)."""
    return Field(_native.from_bytes(data), report)


FieldLike = Union[Field, Callable[[np.ndarray], Any], np.ndarray]


def _as_field(
    field: FieldLike,
    bounds: Optional[Tuple[Sequence[float], Sequence[float]]] = None,
    spacing: Any = 1.0,
    origin: Any = 0.0,
    resolution: int = 64,
) -> Field:
    """A :class:`Field` from a Field, a numpy grid of samples (sample ``[i, j, k]`` at
    ``origin + (i, j, k) * spacing``) or a Python callable ``f(points (n, 3)) -> (n,)``
    sampled on ``resolution`` cells along the longest axis of ``bounds``; both of the latter
    are interpolated by a quadratic B-spline."""
    if isinstance(field, Field):
        return field
    if isinstance(field, np.ndarray):
        if field.ndim != 3:
            raise ValueError(f"a grid of samples must be a 3-D array, got shape {field.shape}")
        values = np.ascontiguousarray(field, dtype=np.float64)
        return Field(
            _native.interpolate(values, _triple(origin, "origin"), _triple(spacing, "spacing"))
        )
    if callable(field):
        if bounds is None:
            raise ValueError("a callable field needs bounds=(lo, hi): the box to sample it on")
        lo = np.asarray(bounds[0], dtype=np.float64)
        hi = np.asarray(bounds[1], dtype=np.float64)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(hi > lo):
            raise ValueError(f"bounds must be (lo, hi) with lo < hi on every axis, got {bounds!r}")
        extent = hi - lo
        counts = np.maximum(3, np.round(extent / extent.max() * resolution)).astype(int)
        h = extent / counts
        axes = [lo[a] + (np.arange(counts[a]) + 0.5) * h[a] for a in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        values = np.asarray(field(grid), dtype=np.float64)
        if values.shape != (grid.shape[0],):
            raise ValueError(
                f"the callable must return one value per row of its (n, 3) argument: "
                f"got shape {values.shape} for {grid.shape[0]} points"
            )
        if not np.all(np.isfinite(values)):
            raise ValueError("the callable returned NaN or infinite values")
        return Field(
            _native.interpolate(
                np.ascontiguousarray(values.reshape(tuple(counts))),
                tuple(lo + 0.5 * h),
                tuple(h),
            )
        )
    raise TypeError(
        f"expected a zeroset.Field, a callable or a 3-D numpy array, got {type(field).__name__}"
    )


# ---------------------------------------------------------------------------------------
# Files


def read_points(
    path: PathLike, formation: Optional[str] = None
) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """Reads a point cloud: ``(points, normals)``, each ``(n, 3)``; normals ``None`` when the
    file has none. PLY (ascii or binary), PCD (PCL; ascii, binary or compressed), LAS / LAZ, E57, xyz /
    xyzn / pts / asc / pwn text (columns ``x y z [nx ny nz]`` or named by a first line), CSV
    with a header, GemPy tables; or a mesh (OBJ, STL, OFF, PLY with faces): the vertices its
    triangles use, with normals from the file or the triangles' winding (closed parts wound inward turned over), ``None``
    where the winding is inconsistent (``estimate_normals`` then).

    ``formation``: for a GemPy table, only the rows of this formation (or fault), by its exact
    name; read whole, every formation of a table is one cloud. Orientation tables give normals
    from dip, azimuth and polarity, or from GemPy 3's ``G_x, G_y, G_z``."""
    return _native.read_points(os.fspath(path), formation)


def read_e57(path: PathLike) -> Tuple[np.ndarray, Optional[np.ndarray], np.ndarray, list]:
    """Reads an E57 laser-scan file: ``(points, normals, origins, scans)``. Every scan is moved
    into the file's frame by its pose, records flagged invalid are left out, and normals (the
    surface-normals extension) are ``None`` unless every scan has them (:func:`read_points`
    refuses a file whose scans have them in part: a fit needs them everywhere). ``origins`` ``(n, 3)`` holds, for each point, its scan's origin in the file's
    frame — where a terrestrial scanner stood, for ``estimate_normals(points,
    scanners=origins)``. ``scans`` lists one dict per scan: ``name`` (or ``None``),
    ``records`` (announced), ``points`` (kept), ``coordinates`` (``"cartesian"`` or
    ``"spherical"``), ``normals``, ``posed`` and ``origin``."""
    points, normals, origins, rows = _native.read_e57(os.fspath(path))
    keys = ("name", "records", "points", "coordinates", "normals", "posed", "origin")
    scans = [dict(zip(keys, row)) for row in rows]
    for scan in scans:
        scan["origin"] = tuple(scan["origin"])
    return points, normals, origins, scans


def estimate_normals(
    points: Any,
    neighbours: Optional[int] = None,
    *,
    viewpoint: Optional[Sequence[float]] = None,
    scanners: Any = None,
) -> np.ndarray:
    """Outward unit normals ``(n, 3)`` for points ``(n, 3)`` that have none (a scan of
    positions only), in the points' order: each point's plane through its ``neighbours``
    nearest (2 to 256; by default 16, or 32 where the points measure noisy, as
    ``zeroset normals`` chooses), the signs propagated along a minimum spanning forest of the
    neighbour graph (Hoppe et al. 1992) and each connected piece turned outward. The result
    feeds :func:`fit` like a scan's own normals. With ``viewpoint=(x, y, z)``, where the
    scanner stood, each piece faces it instead (one-sided scans of flat surfaces, which have
    no inside to read, and scans from inside a room). With ``scanners`` ``(n, 3)``, where the
    scanner stood that recorded each point (a scene taken from several stations, such as an
    E57 file's scans), each point faces its own scanner (those seen at grazing incidence take
    their neighbours' sign).

    >>> import zeroset
    >>> points, normals = zeroset.sample_points()
    >>> estimated = zeroset.estimate_normals(points)
    >>> bool(((estimated * normals).sum(axis=1) > 0).mean() > 0.95)
    True

    Warns where the points fill a volume rather than sample a surface (see :func:`fit`): no
    surface's normals can be estimated from them.

    Raises ``ValueError`` for fewer than 3 points, a NaN or infinite coordinate, ``neighbours``
    out of range, a cloud whose neighbourhoods mostly span no plane (points on a line), both
    ``viewpoint`` and ``scanners``, or ``scanners`` not one finite position per point."""
    k = None if neighbours is None else _neighbours(neighbours)
    if viewpoint is not None and scanners is not None:
        raise ValueError("give viewpoint (one scanner) or scanners (one per point), not both")
    v = None if viewpoint is None else _triple(viewpoint, "viewpoint")
    s = None if scanners is None else _rows(scanners, "scanners")
    p = _rows(points, "points")
    estimated = _native.estimate_normals(p, k, v, s)
    _warn_of_a_volume(p, _native.thickness(p))
    return estimated


def _warn_of_a_volume(
    points: np.ndarray, thickness: Optional[Tuple[int, int, float, bool, float]]
) -> None:
    """Warns where ``thickness`` (``_native.thickness(points, ...)``) says the points fill a
    volume rather than sample a surface, as ``zeroset fit``, ``normals`` and ``reconstruct``
    warn (the warning names the caller of the caller)."""
    if thickness is None or not thickness[3]:
        return
    first, last, value, _, threshold = thickness
    reading = (
        f"at {first} neighbours a point's neighbourhood is"
        if first == last
        else f"at every scale from {first} to {last} neighbours a point's neighbourhood is at least"
    )
    warnings.warn(
        f"the {len(points)} points fill a volume rather than sample a surface: {reading} "
        f"{value:.2f} as thick as it is wide (the median; a surface's is under {threshold:g} at "
        "some scale, or lies on smooth sheets), and the points scatter about every local "
        "surface. zeroset fits a surface through points that lie on one: fitted as a very noisy "
        "scan, these give a crumpled sheet through the volume, not its boundary; give points "
        "sampled on the boundary",
        stacklevel=3,
    )


def fill_missing_normals(
    points: Any, normals: Any, neighbours: int = 16
) -> Tuple[np.ndarray, np.ndarray]:
    """Completes a scan's normals where some are missing: each normal that is the zero vector
    (``0 0 0``, what CGAL, PCL and others write where they could not estimate one) is replaced
    by the unit normal of the plane through its point and its ``neighbours`` nearest (2 to
    256), signed to agree with the normals around it (a neighbour across a thin wall counts
    less than one along the surface); a large gap is signed from its rim inward. Returns
    ``(completed, indices)``: a new ``(n, 3)`` array, the given normals unchanged in it, and
    the indices of the rows completed, increasing (empty where none was zero). The arrays
    given are not modified.

    >>> import numpy as np, zeroset
    >>> points, normals = zeroset.sample_points()
    >>> holed = normals.copy()
    >>> holed[::50] = 0.0
    >>> completed, filled = zeroset.fill_missing_normals(points, holed)
    >>> len(filled), bool((completed[filled] * normals[filled]).sum(axis=1).min() > 0.5)
    (40, True)

    Raises ``ValueError`` where every normal is zero (positions only: ``estimate_normals``),
    for a NaN or infinite coordinate or normal (naming the row), ``normals`` not one per
    point, or ``neighbours`` out of range."""
    k = _neighbours(neighbours)
    completed, filled = _native.fill_missing_normals(
        _rows(points, "points"), _rows(normals, "normals"), k
    )
    return completed, np.asarray(filled, dtype=np.intp)


def orient_normals(
    points: Any,
    normals: Any,
    neighbours: Optional[int] = None,
    *,
    viewpoint: Optional[Sequence[float]] = None,
) -> Tuple[np.ndarray, Report]:
    """Signs normals consistently over the scan: for normals whose lines are right but whose
    signs are not (principal-component normals written unoriented, half of them inward, as
    CGAL's ``cube.pwn``). The lines' signs are propagated as :func:`estimate_normals`
    propagates its planes' (``neighbours`` as there), each connected piece turned outward, or
    towards ``viewpoint``; a ``0 0 0`` row takes its nearest neighbour's normal, as a point
    without a plane does. Returns ``(oriented, report)``: unit normals, each ``±`` its line,
    and a :class:`Report` with ``inconsistent`` (of each piece, the smaller of the points
    that agree with the orientation and those that disagree: 0 for oriented normals, about
    half the points for unoriented ones), ``turned`` (the normals reversed),
    ``facing_in`` (the inconsistent points' normals, 5–40% of the points, face into the
    object: rays cast along them meet the surface as from inside, as on a closed object's
    underside whose normals were turned to face up: at least a third of the rays cast,
    ``rays_cast``, read inward, ``rays_inward``, twice as many as outward, ``rays_outward``,
    and the rays cast likewise from the other points, ``consistent_rays_cast``, read inward,
    ``consistent_rays_inward``, at most a quarter as often) and ``unoriented``
    (``inconsistent`` at least 40% of the points, or
    ``facing_in``: where ``zeroset reconstruct`` turns them; oriented scans measure
    0–0.3%).

    >>> import zeroset
    >>> points, normals = zeroset.sample_points()
    >>> up = normals * np.sign(normals[:, 2:3] + 1e-300)    # every normal turned to face up
    >>> oriented, report = zeroset.orient_normals(points, up)
    >>> bool(report.unoriented), bool((oriented * normals).sum(axis=1).mean() > 0.9)
    (True, True)

    Raises ``ValueError`` as :func:`estimate_normals`, and for ``normals`` not one finite row
    per point."""
    k = None if neighbours is None else _neighbours(neighbours)
    v = None if viewpoint is None else _triple(viewpoint, "viewpoint")
    oriented, report = _native.orient_normals(
        _rows(points, "points"), _rows(normals, "normals"), k, v
    )
    return oriented, Report(report)


def read_mesh(path: PathLike) -> Tuple[np.ndarray, np.ndarray, Optional[np.ndarray]]:
    """Reads a triangle mesh from a PLY, OBJ, STL or OFF file (told by the extension):
    ``(vertices (n, 3), faces (m, 3), normals or None)``. An STL file's corners are welded
    into shared vertices (equal coordinates), so its topology can be checked."""
    return _native.read_mesh(os.fspath(path))


def write_mesh(
    path: PathLike,
    vertices: Any,
    faces: Any,
    normals: Any = None,
    *,
    ascii: bool = False,
) -> None:
    """Writes a triangle mesh atomically, in the format the extension names: PLY or STL
    (binary, or ASCII with ``ascii=True``) for ``.ply`` and ``.stl``, Wavefront OBJ for
    ``.obj``, OFF for ``.off`` (an existing file is replaced). STL keeps the triangles only (no
    vertex normals, no unused vertices) in 32-bit floats: a mesh far from the origin for its
    size (UTM coordinates) loses precision there, and a warning says how much; PLY switches to
    doubles, OBJ and OFF write them exactly."""
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must be integers of shape (m, 3), got {f.dtype} {f.shape}")
    n = None if normals is None else _rows(normals, "normals")
    moved = _native.write_mesh(
        os.fspath(path),
        _rows(vertices, "vertices"),
        np.ascontiguousarray(f, dtype=np.int64),
        n,
        bool(ascii),
    )
    if moved is not None:
        warnings.warn(
            f"STL stores 32-bit floats, which moved these vertices by up to {moved:.3g} of the "
            "mesh's diagonal (it lies far from the origin for its size): .ply, .obj or .off "
            "keep them exactly",
            stacklevel=2,
        )


def trim_mesh(
    vertices: Any,
    faces: Any,
    scan: Any,
    *,
    normals: Any = None,
    reach: float = 1.5,
) -> Tuple[np.ndarray, np.ndarray, Optional[np.ndarray]]:
    """The mesh cut where it leaves the reach of the points ``scan`` (``(k, 3)``, at least 9):
    each point reaches ``reach`` times its local spacing (the mean distance to its 8
    nearest), and triangles partly within reach are cut along the edge of it, so the result
    stays welded. As ``zeroset mesh --trim``: for one-sided scans (a face, a façade,
    terrain), whose zero set otherwise runs on to the field's box, and to reopen holes the
    scan left. Returns ``(vertices, faces, normals or None)``; normals, if given, are
    interpolated to the new vertices.

    >>> import numpy as np, zeroset
    >>> g = np.linspace(0, 1, 21)                  # the unit square, 20 x 20 cells
    >>> v = np.array([[x, y, 0] for x in g for y in g])
    >>> c = [(i, j) for i in range(20) for j in range(20)]
    >>> k = lambda i, j: 21 * i + j
    >>> f = np.array([t for i, j in c for t in ([k(i, j), k(i + 1, j), k(i + 1, j + 1)],
    ...                                         [k(i, j), k(i + 1, j + 1), k(i, j + 1)])])
    >>> scan = np.array([[0.025 * i, 0.025 * j, 0] for i in range(11) for j in range(41)])
    >>> tv, tf, _ = zeroset.trim_mesh(v, f, scan)  # cut a little beyond x = 0.25
    >>> bool(0.25 < tv[:, 0].max() < 0.4)
    True
    """
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must be integers of shape (m, 3), got {f.dtype} {f.shape}")
    n = None if normals is None else _rows(normals, "normals")
    tv, tf, tn, _, _ = _native.trim_mesh(
        _rows(vertices, "vertices"),
        np.ascontiguousarray(f, dtype=np.int64),
        n,
        _rows(scan, "scan"),
        float(reach),
    )
    return tv, tf, tn


def load(path: PathLike) -> Field:
    """Reads a 3-D field from a ``.zsf`` field file (written by :meth:`Field.save` or the
    ``zeroset`` command)."""
    return Field(_native.load(os.fspath(path)))


def sample_points() -> Tuple[np.ndarray, np.ndarray]:
    """The bundled sample: 2,000 points of the Stanford bunny with outward normals (see the
    repository's ``samples/README.md`` for its provenance)."""
    with tempfile.TemporaryDirectory(prefix="zeroset-") as d:
        path = Path(d) / "bunny_2k.xyzn"
        path.write_text(_native.sample_xyzn())
        points, normals = read_points(path)
    assert normals is not None
    return points, normals


# ---------------------------------------------------------------------------------------
# Fitting


def fit(
    points: Any,
    normals: Any,
    method: str = "rbf",
    *,
    kernel: Optional[str] = None,
    tolerance: Optional[float] = None,
    offset: Optional[float] = None,
    hermite: bool = False,
    solver: str = "auto",
    radius: Optional[float] = None,
    steps: int = 3000,
    lam: Optional[float] = None,
    widths: Sequence[int] = (32, 32),
    activation: str = "tanh",
    seed: int = 0,
    max_level: Optional[int] = None,
    compress: bool = True,
    outlier_ratio: Optional[float] = None,
    smoothing: Union[None, float, str] = None,
    progress: Progress = None,
) -> Field:
    """Fits a field to an oriented point cloud (normals point out of the solid).

    ``method="rbf"`` (default): a radial basis function interpolant through Carr et al.'s
    off-surface points (value 0 at each point, ±ε along its normal; ``offset`` fixes ε,
    by default 1% of the diagonal, shrunk per point where it would cross the surface) or,
    with ``hermite=True``, the normals as gradients. ``kernel`` is ``"r"`` (biharmonic,
    default; ``"r3"`` with ``hermite=True``, which needs a twice-differentiable kernel),
    ``"r3"``, ``"tps"`` or ``"wendland"`` (support ``radius``, default half the
    diagonal); ``solver`` ``"auto"``, ``"dense"``, ``"mixed"`` or ``"iterative"`` (GMRES with
    the fast multipole method: large clouds). ``tolerance`` (a fraction of the diagonal)
    keeps only the centres needed to meet it at every constraint (Carr's greedy fit).
    ``smoothing`` approximates the values instead of interpolating them, for noisy scans:
    ``"auto"`` (kernel ``"r"``) takes μ from the measured noise, ``2 × scatter² × D`` (``D``
    the box diagonal of the connected piece of the cloud holding its median point: the
    object's size, not a scene's);
    a number μ ≥ 0 is added to the kernel matrix's diagonal, as SciPy's ``RBFInterpolator``
    ``smoothing`` (``report["smoothing"]`` is the μ used, ``report["misfit_rms"]`` how far the
    field misses the values on purpose).

    ``method="neural"``: a small MLP (``widths``, ``activation``) trained by Adam for
    ``steps`` steps on the off-surface points with the thin-plate curvature weight ``lam``
    (Jiang–Turk §3; 0.005 by default, as ``zeroset fit --method neural`` on a point cloud);
    ``seed`` fixes the initial weights.

    ``method="mras"``: multilevel rational algebraic spline offsets, stored at low rank (Pan–Tong–Chen): ``tolerance`` is
    the target max distance as a fraction of the diagonal, ``max_level`` the deepest level,
    ``lam`` the trace-norm weight (0.3 by default, as ``--lambda``: larger stores less and
    smooths more), ``compress=False`` keeps full coefficient tensors. ``report["tolerance_met"]`` says whether
    every point's Sampson distance is within it; ``report["points_over_tolerance"]`` counts
    those that are not (the subdivision stops at cells of 16 points or fewer, at the level
    cap, and at cells whose points were within it when their level was fitted), and
    ``report["capped_cells"]`` the cells the level cap kept from splitting;
    ``report["flat_points"]`` counts the points where the field is nearly flat
    (``|∇f| < 0.1``), warned of above 1% of ``report["fitted_points"]``.

    Points repeated at one position are fitted once (``report["merged"]`` for ``"rbf"``,
    ``report["duplicates"]`` for ``"mras"``). Where their normals point apart — a mesh
    touching itself, two solids touching — the points around say whether two sheets meet
    there (counted in ``report["touching"]``: RBF offsets on the side they say, MRAS the two
    normals' mean as the gradient) or one sheet carries a flipped normal (fitted with the
    sheet's side).

    Every method reads how thick the points' neighbourhoods are against how wide, from 32
    neighbours up to 2048 (``report["thickness"]``, the median at the thinnest scale: about
    0.01 on a clean scan, under 0.35 on most surfaces' points; absent under 256 distinct
    positions), and warns before fitting where the points fill a volume rather than sample a
    surface: thick at every scale and scattered about every local surface (as
    :func:`estimate_normals` does).

    ``"rbf"`` and ``"mras"`` set stray points aside before fitting (each would become a
    blob or a sheet of surface): those whose mean distance to their 8 nearest exceeds
    ``outlier_ratio`` times the median (default 3) and that do not lie on a surface with
    them, and those off a clean patch of surface with a normal of their own.
    ``report["outliers"]`` lists their indices; ``outlier_ratio=0`` fits every point.
    ``"rbf"`` also measures how noisy the points are, ``report["scatter"]`` (their scatter
    about a local quadric over their spacing), and warns when it exceeds 0.2
    (``report["noisy"]``) unless smoothed: interpolating noise grows bubbles,
    ``smoothing="auto"`` or ``"mras"`` averages it. Both
    keys are absent below 64 points or where the points span no surface.

    Normals ``0 0 0`` are refused (:func:`fill_missing_normals` completes them); normals
    written without a consistent sign (half inward) fit a wrong surface without an error
    (:func:`orient_normals` tells and turns them, as ``zeroset fit`` warns).

    ``progress``: ``True`` for a line on stderr, or a callable ``(stage, done, total)``;
    raising in it stops the fit. Returns a :class:`Field` whose ``report`` says what the fit
    did (iterations, residuals, time).
    """
    p = _rows(points, "points")
    n = _rows(normals, "normals")
    zero = np.flatnonzero(~n.any(axis=1))
    if len(zero):
        what = "every normal is" if len(zero) == len(n) else f"{len(zero)} of the {len(n)} normals are"
        cure = (
            "estimate them with zeroset.estimate_normals(points)"
            if len(zero) == len(n)
            else "complete them with zeroset.fill_missing_normals(points, normals)"
        )
        raise ValueError(
            f"{what} 0 0 0 (row {zero[0]} first), which marks a normal missing: {cure}"
        )
    thickness = _native.thickness(p, n)
    _warn_of_a_volume(p, thickness)
    neural_given = [
        name
        for name, value, default in (
            ("steps", steps, 3000),
            ("widths", tuple(widths), (32, 32)),
            ("activation", activation, "tanh"),
            ("seed", seed, 0),
        )
        if value != default
    ]
    if method != "neural" and neural_given:
        verb = "applies" if len(neural_given) == 1 else "apply"
        raise ValueError(f"{'=, '.join(neural_given)}= {verb} to method='neural'")
    if method == "rbf" and lam is not None:
        raise ValueError("lam= applies to method='neural' and 'mras'")
    if method != "rbf" and solver != "auto":
        raise ValueError("solver= applies to method='rbf'")
    if method == "rbf":
        if any(x is not None for x in (max_level,)) or not compress:
            raise ValueError("max_level= and compress= apply to method='mras'")
        auto = isinstance(smoothing, str)
        if auto and smoothing != "auto":
            raise ValueError(f"smoothing must be 'auto' or a number >= 0, got {smoothing!r}")
        mu = None if smoothing is None or auto else float(smoothing)
        native, report = _run(
            progress,
            lambda cb: _native.fit_rbf(
                p, n, kernel or ("r3" if hermite else "r"), offset, bool(hermite), solver,
                tolerance, radius, outlier_ratio, mu, auto, cb,
            ),
        )
        if auto and "scatter" not in report:
            warnings.warn(
                "smoothing='auto': the noise cannot be measured (fewer than 64 points, or they "
                "span no surface), so the points are interpolated; give smoothing as a number",
                stacklevel=2,
            )
        if report.get("noisy") and not report.get("smoothing"):
            warnings.warn(
                f"the points scatter {report['scatter']:.2f} of their spacing about their local "
                "surface (noisy above 0.2): RBF interpolates every point and folds between noisy "
                "ones, so the surface grows bubbles; smoothing='auto' approximates them instead, "
                "or method='mras' fits them by least squares",
                stacklevel=2,
            )
    elif method == "neural":
        if kernel is not None or tolerance is not None or hermite or radius is not None:
            raise ValueError("kernel=, tolerance=, hermite= and radius= apply to method='rbf'")
        if smoothing is not None:
            raise ValueError("smoothing= applies to method='rbf'")
        if outlier_ratio is not None:
            raise ValueError("outlier_ratio= applies to method='rbf' and 'mras'")
        native, report = _run(
            progress,
            lambda cb: _native.fit_neural(
                p, n, _count(steps, "steps"), 0.005 if lam is None else float(lam),
                [_count(w, "widths") for w in widths],
                activation, _count(seed, "seed"),
                offset, cb,
            ),
        )
    elif method == "mras":
        if smoothing is not None:
            raise ValueError("smoothing= applies to method='rbf' (MRAS fits by least squares)")
        if kernel is not None or hermite or radius is not None or offset is not None:
            raise ValueError(
                "kernel=, hermite=, radius= and offset= apply to method='rbf' (and offset= "
                "to 'neural')"
            )
        native, report = _run(
            progress,
            lambda cb: _native.fit_mras_cloud(
                p, n, tolerance, None if lam is None else float(lam),
                None if max_level is None else _count(max_level, "max_level"),
                bool(compress), outlier_ratio, cb,
            ),
        )
        # Over 1% of the points on a nearly flat field is a field that misses the surface
        # (as `zeroset fit --method mras` warns).
        if report["flat_points"] * 100 > report["fitted_points"]:
            warnings.warn(
                f"the field is nearly flat (|∇f| < 0.1, where a fit has about 1) at "
                f"{report['flat_points']} of the {report['fitted_points']} fitted points: its "
                "surface need not pass near them, whatever report['max_error'] says. Levels too "
                f"coarse for them (max_level) or a trace norm that shrank the offsets "
                f"(lam={report['lam']:g}) leave a field this flat",
                stacklevel=2,
            )
    else:
        raise ValueError(f"method must be 'rbf', 'neural' or 'mras', got {method!r}")
    if thickness is not None:
        report["thickness"] = thickness[2]
    return Field(native, Report(report))


# ---------------------------------------------------------------------------------------
# Restoration


def restore(
    field: FieldLike,
    mask: Tuple[Sequence[float], Sequence[float]],
    mode: str = "protrusion",
    *,
    face: Optional[str] = None,
    alpha: Optional[float] = None,
    coarse: Optional[Sequence[int]] = None,
    grid: Optional[Sequence[int]] = None,
    positive_inside: bool = False,
    point_resampling: bool = False,
    bounds: Optional[Tuple[Sequence[float], Sequence[float]]] = None,
    spacing: Any = 1.0,
    origin: Any = 0.0,
) -> Field:
    """Restores a field inside the box ``mask=(lo, hi)`` (Ren–Fujita–Nakata 2022), as
    ``zeroset restore`` does.

    ``mode="protrusion"`` removes what sticks out through the mask: ``face`` (``"+x"``,
    ``"-x"``, ..., ``"-z"``) is the face the protrusion's base crosses, where the field keeps
    the slope ``alpha`` (default: its mean slope there, which counts the protrusion's own
    cross-section; for a distance-like field ``alpha=1`` continues the body, larger values
    flatten it); without ``face`` the mask is filled harmonically from its boundary.
    ``mode="denoise"`` smooths the field inside the mask by its fit on ``coarse=(m, n, l)``
    coarse cells (fewer: smoother; as many as the mask has: unchanged), each the mean of the
    samples it covers, or the sample at its centre with ``point_resampling=True`` (the
    paper's rule). A B-spline field is restored on its own grid; other fields are sampled on
    the grid ``zeroset restore`` uses (64 cells along the longest axis of their box, 3 of
    them beyond it on each side), or on ``grid=(nx, ny, nz)`` cells over that box. ``field`` may also be a
    callable, sampled on 64 cells along the longest axis of ``bounds`` exactly, or a numpy
    grid of samples (with ``spacing`` and ``origin``). A mask reaching beyond that grid's box
    is cut to it (with a warning; ``report.mask_cut_axes`` names the axes).
    Returns a quadratic B-spline :class:`Field` with the ``report``.
    """
    f = _as_field(field, bounds=bounds, spacing=spacing, origin=origin)
    try:
        lo, hi = mask
    except (TypeError, ValueError):
        raise ValueError(f"mask must be (lo, hi), two corners of a box, got {mask!r}") from None
    native, report = _native.restore(
        f._native,
        _triple(lo, "mask lo"),
        _triple(hi, "mask hi"),
        mode,
        face,
        None if alpha is None else float(alpha),
        None if coarse is None else _counts(coarse, "coarse"),
        None if grid is None else _counts(grid, "grid"),
        bool(positive_inside),
        bool(point_resampling),
    )
    if report["mask_cut_axes"]:
        axes = ", ".join("xyz"[a] for a in report["mask_cut_axes"])
        warnings.warn(
            f"the mask reaches beyond the sampling grid's box on {axes}: cut to it",
            stacklevel=2,
        )
    return Field(native, Report(report))


# ---------------------------------------------------------------------------------------
# Meshing


def marching_cubes(
    volume: Union[np.ndarray, Field, Callable[[np.ndarray], Any]],
    level: Optional[float] = None,
    *,
    spacing: Sequence[float] = (1.0, 1.0, 1.0),
    gradient_direction: str = "descent",
    step_size: int = 1,
    allow_degenerate: bool = True,
    method: str = "lewiner",
    mask: Optional[np.ndarray] = None,
    bounds: Optional[Tuple[Sequence[float], Sequence[float]]] = None,
    resolution: int = 128,
) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Marching cubes with the arguments and results of ``skimage.measure.marching_cubes``.

    ``volume[i, j, k]`` is the sample at ``(i, j, k) * spacing``; returns ``(verts, faces,
    normals, values)`` with verts in those coordinates and ``values`` the largest sample of
    the grid cell each vertex lies in (on a cell face, the cell above it), for colour maps as
    scikit-image's; its own measure of the data's maximum near each vertex gives other
    numbers. Orientation as scikit-image's: the normals point down the
    gradient (out of a bright object) whatever ``gradient_direction`` says, and the faces are
    wound so that their right-hand normal points up the gradient with ``"descent"`` (the
    default; scikit-image's "left-hand rule" around its normals) and down it with
    ``"ascent"``. For a zeroset field (negative inside) :func:`mesh` gives normals and faces
    that both point out. ``level`` defaults to the middle of the volume's range, as in
    scikit-image. The mesh is topologically consistent (no cracks or holes between cubes),
    which is what ``method="lewiner"`` asks of scikit-image; ``method="lorensen"`` is
    accepted and gives the same mesh. ``step_size`` samples every ``step_size``-th voxel.
    Differences: verts, normals and values are float64 (scikit-image returns float32; faces
    are int32 on both sides), and ``mask`` is not supported (``ValueError``).

    ``volume`` may also be a :class:`Field` or a callable ``f(points (n, 3)) -> (n,)``: it is
    sampled at ``resolution`` samples along the longest axis of its box (``bounds=(lo, hi)``,
    required for a callable), and the vertices are returned in the field's coordinates.
    """

    if mask is not None:
        raise ValueError("mask= is not supported: set the volume outside the mask above level")
    if method not in ("lewiner", "lorensen"):
        raise ValueError(f"method must be 'lewiner' or 'lorensen', got {method!r}")
    if gradient_direction not in ("descent", "ascent"):
        raise ValueError(
            f"gradient_direction must be 'descent' or 'ascent', got {gradient_direction!r}"
        )
    if int(step_size) < 1:
        raise ValueError(f"step_size must be at least 1, got {step_size}")
    step = int(step_size)
    h = np.asarray(_triple(spacing, "spacing"), dtype=np.float64)
    offset = np.zeros(3)
    if isinstance(volume, np.ndarray):
        vol = volume
    else:
        if isinstance(volume, Field):
            if bounds is None:
                bounds = volume.bounds
            evaluate: Callable[[np.ndarray], Any] = volume
        elif callable(volume):
            if bounds is None:
                raise ValueError("a callable needs bounds=(lo, hi): the box to sample it on")
            evaluate = volume
        else:
            raise TypeError(
                f"expected a 3-D numpy array, a zeroset.Field or a callable, got {type(volume).__name__}"
            )
        lo = np.asarray(bounds[0], dtype=np.float64)  # type: ignore[index]
        hi = np.asarray(bounds[1], dtype=np.float64)  # type: ignore[index]
        extent = hi - lo
        d = extent.max() / max(int(resolution) - 1, 1)
        counts = np.maximum(2, np.round(extent / d).astype(int) + 1)
        h = extent / (counts - 1)
        axes = [lo[a] + np.arange(counts[a]) * h[a] for a in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        vol = np.asarray(evaluate(grid), dtype=np.float64).reshape(tuple(counts))
        offset = lo
    vol = np.asarray(vol)
    if vol.ndim != 3:
        raise ValueError(f"the volume must be 3-D, got shape {vol.shape}")
    if step > 1:
        vol = vol[::step, ::step, ::step]
        h = h * step
    vol = np.ascontiguousarray(vol, dtype=np.float64)
    if level is None:
        level = float(vol.min() + vol.max()) / 2.0
    verts, faces, normals, values = _native.marching_cubes_volume(
        vol, float(level), tuple(h), gradient_direction == "descent", False
    )
    # As scikit-image, a level outside the data is an error; checked only when nothing was
    # found, so that a mesh costs no extra pass over the volume.
    if len(faces) == 0 and not (vol.min() <= level <= vol.max()):
        raise ValueError(f"level {level} is outside the volume's range [{vol.min()}, {vol.max()}]")
    if not allow_degenerate and len(faces):
        a, b, c = (verts[faces[:, i]] for i in range(3))
        area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
        faces = faces[area > 0]
    if offset.any():
        verts += offset
    return verts, faces, normals, values


def mesh(
    field: FieldLike,
    level: float = 0.0,
    *,
    detail: Optional[str] = None,
    resolution: Optional[int] = None,
    voxel: Optional[float] = None,
    method: str = "mc",
    close: bool = False,
    bounds: Optional[Tuple[Sequence[float], Sequence[float]]] = None,
    spacing: Any = 1.0,
    origin: Any = 0.0,
    progress: Progress = None,
) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The level set ``field = level`` as a triangle mesh ``(vertices, faces, normals)``,
    normals ``∇f/‖∇f‖`` (outward for a zeroset field), as ``zeroset mesh`` makes it.

    The voxel edge follows the ``detail`` class (``"coarse"``, ``"general"``, ``"fine"``:
    5, 1 or 0.3 times the box's reference length; by default ``"fine"`` for MRAS fields,
    fitted to scans within 1e-3 of their diagonal, or twice the median spacing of the scan
    the field records where that is finer, but no finer than half the knot spacing of its
    finest splines nor 512 voxels along the longest axis; and
    ``"general"`` for the others), or
    ``resolution`` voxels along the
    longest axis, or the edge ``voxel``. ``method="mc"`` samples the field on the grid and
    runs marching cubes; ``method="smc"`` (RBF fields) runs the two-step signed marching
    cubes with fast multipole expansions of orders 5 and 10, which evaluates the exact
    field only near the surface. ``close=True`` caps the surface where it leaves the grid.
    ``field`` may also be a callable (with ``bounds``), sampled on ``resolution`` cells along
    the longest axis of ``bounds`` (64 without one) and interpolated by a quadratic B-spline,
    or a numpy grid of samples (interpolated likewise); :func:`marching_cubes` meshes samples
    as they are. The spline's boundary condition flattens its slope at the box's faces: where
    the surface leaves the box its vertices there are off by about a tenth of a cell (and
    their normals by degrees), so give ``bounds`` a few cells beyond the part you need, or
    use :func:`marching_cubes`. ``bounds``, ``spacing`` and ``origin`` describe a callable or
    grid; with a :class:`Field` they are refused (it is meshed in its own box).

    A grid whose memory is more than the machine has is refused (``ValueError``, with the
    amount) before anything is allocated.
    """
    if resolution is not None:
        resolution = _count(resolution, "resolution")
    if isinstance(field, Field) and (
        bounds is not None or not _is_default(spacing, 1.0) or not _is_default(origin, 0.0)
    ):
        raise ValueError(
            "bounds=, spacing= and origin= describe a callable or a grid of samples; a Field "
            "is meshed in its own box (field.bounds)"
        )
    f = _as_field(
        field, bounds=bounds, spacing=spacing, origin=origin, resolution=resolution or 64
    )
    return _run(
        progress,
        lambda cb: _native.mesh_native(
            f._native, float(level), detail, resolution, voxel, method, bool(close), cb
        ),
    )


# ---------------------------------------------------------------------------------------
# Solvers


def lstsq(
    A: Any,
    b: Any,
    solver: str = "lsqr",
    *,
    tol: Optional[float] = None,
    max_iter: Optional[int] = None,
    return_info: bool = False,
    progress: Progress = None,
) -> Union[np.ndarray, Tuple[np.ndarray, Report]]:
    """Solves ``min ‖A x − b‖₂`` with one of zeroset's solvers and returns ``x`` (and the
    solver's :class:`Report` with ``return_info=True``).

    ``A`` is a dense 2-D array or a ``scipy.sparse`` matrix (any format; converted to CSR).
    ``solver``: ``"lsqr"`` (default) and ``"cgls"`` (iterative, ``tol`` is scipy's
    ``atol = btol``, default 1e-10), ``"pcg"`` (conjugate gradients on the normal equations),
    ``"qr"`` (dense Householder QR), ``"lu"`` (dense LU of the normal equations),
    ``"sparse_qr"`` and ``"cholesky"`` (sparse direct). An iterative solver that does not
    reach ``tol`` in ``max_iter`` steps raises ``ValueError`` with the residual it reached.
    """
    max_iter = None if max_iter is None else _count(max_iter, "max_iter")
    bb = np.ascontiguousarray(np.asarray(b, dtype=np.float64))
    if bb.ndim != 1:
        raise ValueError(f"b must be 1-D, got shape {bb.shape}")
    if hasattr(A, "tocsr") and hasattr(A, "nnz"):
        csr = A.tocsr()
        if not csr.has_canonical_format:
            csr = csr.copy()
            csr.sum_duplicates()
        m, n = csr.shape
        if m != bb.shape[0]:
            raise ValueError(f"A has {m} rows but b has {bb.shape[0]} entries")
        arrays = (
            (int(m), int(n)),
            np.ascontiguousarray(csr.indptr, dtype=np.int64),
            np.ascontiguousarray(csr.indices, dtype=np.int64),
            np.ascontiguousarray(csr.data, dtype=np.float64),
        )
        x, info = _run(
            progress,
            lambda cb: _native.lstsq_native(bb, solver, tol, max_iter, None, arrays, cb),
        )
    else:
        dense = np.asarray(A, dtype=np.float64)
        if dense.ndim != 2:
            raise ValueError(f"A must be 2-D, got shape {dense.shape}")
        if dense.shape[0] != bb.shape[0]:
            raise ValueError(f"A has {dense.shape[0]} rows but b has {bb.shape[0]} entries")
        dense = np.ascontiguousarray(dense)
        x, info = _run(
            progress,
            lambda cb: _native.lstsq_native(bb, solver, tol, max_iter, dense, None, cb),
        )
    return (x, Report(info)) if return_info else x


def cp_als(
    tensor: Any,
    rank: int,
    *,
    n_iter_max: int = 500,
    tol: float = 1e-10,
    init: str = "svd",
    random_state: int = 0,
    line_search: bool = False,
    return_errors: bool = False,
    progress: Progress = None,
) -> Any:
    """CP decomposition of a 3-way array by alternating least squares, with TensorLy's
    ``parafac`` argument names: returns ``(weights, [A, B, C])`` with
    ``tensor[i, j, k] ≈ Σ_r weights[r] A[i, r] B[j, r] C[k, r]`` (and the relative error
    per iteration with ``return_errors=True``). ``init`` is ``"svd"`` or ``"random"``
    (seeded by ``random_state``); it stops when the relative error changes by less than
    ``tol``. The same bits on any thread count.
    """
    t = np.ascontiguousarray(np.asarray(tensor, dtype=np.float64))
    if t.ndim != 3:
        raise ValueError(f"cp_als takes a 3-way array, got shape {t.shape}")
    weights, factors, report = _run(
        progress,
        lambda cb: _native.cp_als(
            t, _count(rank, "rank"), _count(n_iter_max, "n_iter_max"), float(tol), init,
            _count(random_state, "random_state"),
            bool(line_search), cb,
        ),
    )
    if return_errors:
        return (weights, factors), report["errors"]
    return weights, factors


def svt(matrix: Any, tau: float, *, return_rank: bool = False) -> Any:
    """Singular-value thresholding ``U max(Σ − τ, 0) Vᵀ``: the proximal map of ``τ‖·‖_*``
    (and the rank kept with ``return_rank=True``)."""
    m = np.ascontiguousarray(np.asarray(matrix, dtype=np.float64))
    if m.ndim != 2:
        raise ValueError(f"svt takes a 2-D array, got shape {m.shape}")
    out, rank = _native.svt(m, float(tau))
    return (out, rank) if return_rank else out


# ---------------------------------------------------------------------------------------
# The demo

#: The bunny's ears in the bundled sample: the box above the head, its bottom face (-y)
#: where they join it (as ``zeroset demo``).
EAR_MASK = ((-0.1, 0.145, -0.07), (0.005, 0.2, 0.05))


def demo(directory: Optional[PathLike] = None, *, quiet: bool = False) -> Dict[str, Any]:
    """The pipeline on the bundled bunny sample: read, RBF fit, mesh, the ears removed by
    protrusion removal, mesh again; the meshes are written as PLY under ``directory``
    (default ``./zeroset-demo-python``). Prints one line per step; returns the figures."""
    out = Path(directory if directory is not None else "zeroset-demo-python")
    out.mkdir(parents=True, exist_ok=True)
    say = (lambda *a: None) if quiet else print
    start = time.perf_counter()
    sample = out / "bunny_2k.xyzn"
    sample.write_text(_native.sample_xyzn())
    points, normals = read_points(sample)
    assert normals is not None
    say(f"zeroset {__version__}: {len(points)} points of the Stanford bunny ({sample})")
    field = fit(points, normals)
    r = field.report
    say(
        f"fit: RBF (kernel r), {r.constraints} constraints, solver {r.solver}, "
        f"max residual {r.max_residual:.2e}, {r.seconds:.2f} s"
    )
    verts, faces, _ = mesh(field)
    fitted = out / "bunny.ply"
    write_mesh(fitted, verts, faces)
    say(f"mesh: {len(verts)} vertices, {len(faces)} triangles -> {fitted}")
    restored = restore(field, EAR_MASK, face="-y", alpha=1.0, grid=_demo_grid(field))
    rv, rf, _ = mesh(restored)
    no_ears = out / "bunny_no_ears.ply"
    write_mesh(no_ears, rv, rf)
    top, top_after = float(verts[:, 1].max()), float(rv[:, 1].max())
    say(
        f"restore: ears removed ({restored.report.unknowns} unknowns, solver "
        f"{restored.report.solver}); top of the surface y {top:.4f} -> {top_after:.4f}; "
        f"{len(rv)} vertices -> {no_ears}"
    )
    seconds = time.perf_counter() - start
    say(f"done in {seconds:.2f} s")
    return {
        "points": len(points),
        "fit": r,
        "mesh": str(fitted),
        "vertices": len(verts),
        "restored_mesh": str(no_ears),
        "top": top,
        "top_restored": top_after,
        "seconds": seconds,
    }


def _demo_grid(field: Field) -> Tuple[int, int, int]:
    """96 cells along the longest axis of the field's box, as ``zeroset demo``."""
    b = field.bounds
    assert b is not None
    extent = b[1] - b[0]
    return tuple(int(max(3, round(e / extent.max() * 96))) for e in extent)  # type: ignore[return-value]
