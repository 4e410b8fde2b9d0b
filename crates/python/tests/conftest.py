"""Shared fixtures: analytic clouds with known truth, and the `zeroset` command for the
round-trip tests (``$ZEROSET_BIN``, else ``target/{release,debug}/zeroset`` of this checkout)."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]


def sphere_cloud(n=400, radius=1.0, centre=(0.0, 0.0, 0.0)):
    """``n`` Fibonacci points on a sphere and their outward normals."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5**0.5) * i
    normals = np.stack(
        [np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1
    )
    return np.asarray(centre) + radius * normals, normals


@pytest.fixture(scope="session")
def sphere():
    return sphere_cloud()


@pytest.fixture(scope="session")
def sphere_field(sphere):
    import zeroset

    return zeroset.fit(*sphere)


@pytest.fixture(scope="session")
def zeroset_bin():
    explicit = os.environ.get("ZEROSET_BIN")
    if explicit:
        if not Path(explicit).is_file():
            pytest.fail(f"ZEROSET_BIN={explicit} is not a file")
        return explicit
    for profile in ("release", "debug"):
        candidate = REPO / "target" / profile / "zeroset"
        if candidate.is_file():
            return str(candidate)
    found = shutil.which("zeroset")
    if found:
        return found
    pytest.skip("no zeroset command: build it (cargo build -p zeroset-cli) or set ZEROSET_BIN")
