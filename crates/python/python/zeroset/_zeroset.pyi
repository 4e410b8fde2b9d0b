"""Type stubs of the native module ``zeroset._zeroset`` (Rust, PyO3). The public API is
``zeroset`` itself, which normalises arguments and calls these with C-contiguous float64
arrays; they are not meant to be called directly."""

from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

__version__: str

_F64 = npt.NDArray[np.float64]
_I64 = npt.NDArray[np.int64]
_I32 = npt.NDArray[np.int32]
_Progress = Optional[Callable[[str, int, int], Any]]
_Triple = Tuple[float, float, float]

class NativeField:
    def values(self, at: _F64) -> _F64: ...
    def gradients(self, at: _F64) -> _F64: ...
    @property
    def bounds(self) -> Optional[Tuple[List[float], List[float]]]: ...
    @property
    def kind(self) -> str: ...
    def describe(self) -> str: ...
    def centres(self) -> Optional[_F64]: ...
    def save(self, path: str) -> None: ...
    def to_bytes(self) -> bytes: ...

def load(path: str) -> NativeField: ...
def from_bytes(data: bytes) -> NativeField: ...
def interpolate(samples: _F64, origin: _Triple, spacing: _Triple) -> NativeField: ...
def fit_rbf(
    points: _F64,
    normals: _F64,
    kernel: str,
    offset: Optional[float],
    hermite: bool,
    solver: str,
    tolerance: Optional[float],
    radius: Optional[float],
    outlier_ratio: Optional[float],
    smoothing: Optional[float],
    smoothing_auto: bool,
    progress: _Progress,
) -> Tuple[NativeField, Dict[str, Any]]: ...
def fit_neural(
    points: _F64,
    normals: _F64,
    steps: int,
    lam: float,
    widths: Sequence[int],
    activation: str,
    seed: int,
    offset: Optional[float],
    progress: _Progress,
) -> Tuple[NativeField, Dict[str, Any]]: ...
def fit_mras_cloud(
    points: _F64,
    normals: _F64,
    tolerance: Optional[float],
    max_level: Optional[int],
    compress: bool,
    outlier_ratio: Optional[float],
    progress: _Progress,
) -> Tuple[NativeField, Dict[str, Any]]: ...
def read_points(path: str, formation: Optional[str] = None) -> Tuple[_F64, Optional[_F64]]: ...
def estimate_normals(
    points: _F64,
    neighbours: Optional[int],
    viewpoint: Optional[Tuple[float, float, float]] = None,
    scanners: Optional[_F64] = None,
) -> _F64: ...
def fill_missing_normals(
    points: _F64, normals: _F64, neighbours: int
) -> Tuple[_F64, List[int]]: ...
def thickness(
    points: _F64, normals: Optional[_F64] = None
) -> Optional[Tuple[int, int, float, bool, float]]: ...
def orient_normals(
    points: _F64,
    normals: _F64,
    neighbours: Optional[int],
    viewpoint: Optional[Tuple[float, float, float]] = None,
) -> Tuple[_F64, Dict[str, Any]]: ...
def sample_xyzn() -> str: ...
def lstsq_native(
    b: _F64,
    solver_name: str,
    tol: Optional[float],
    max_iter: Optional[int],
    dense: Optional[_F64] = None,
    csr: Optional[Tuple[Tuple[int, int], _I64, _I64, _F64]] = None,
    progress: _Progress = None,
) -> Tuple[_F64, Dict[str, Any]]: ...
def cp_als(
    tensor: _F64,
    rank: int,
    max_iter: int,
    tol: float,
    init: str,
    seed: int,
    line_search: bool,
    progress: _Progress,
) -> Tuple[_F64, List[_F64], Dict[str, Any]]: ...
def svt(matrix: _F64, tau: float) -> Tuple[_F64, int]: ...
def marching_cubes_volume(
    volume: _F64, level: float, spacing: _Triple, descent: bool, close: bool
) -> Tuple[_F64, _I32, _F64, _F64]: ...
def mesh_native(
    field: NativeField,
    level: float,
    detail: Optional[str],
    resolution: Optional[int],
    voxel: Optional[float],
    method: str,
    close: bool,
    progress: _Progress,
) -> Tuple[_F64, _I64, _F64]: ...
def read_mesh(path: str) -> Tuple[_F64, _I64, Optional[_F64]]: ...
def write_mesh(
    path: str, vertices: _F64, faces: _I64, normals: Optional[_F64], ascii: bool
) -> None: ...
def trim_mesh(
    vertices: _F64, faces: _I64, normals: Optional[_F64], scan: _F64, reach: float
) -> Tuple[_F64, _I64, Optional[_F64], int, int]: ...
def restore(
    field: NativeField,
    lo: _Triple,
    hi: _Triple,
    mode: str,
    face: Optional[str],
    alpha: Optional[float],
    coarse: Optional[Tuple[int, int, int]],
    grid: Optional[Tuple[int, int, int]],
    positive_inside: bool,
    point_resampling: bool,
) -> Tuple[NativeField, Dict[str, Any]]: ...
