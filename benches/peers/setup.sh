#!/usr/bin/env bash
# Creates benches/peers/.venv and installs the pinned scipy/numpy (idempotent).
# Usage: bash benches/peers/setup.sh [--torch] [--open3d] [--python] [--cholmod]   (from anywhere)
#   --torch   also installs requirements-torch.txt (PyTorch for neural_peers.py; a ~5 GB download)
#   --open3d  also installs requirements-open3d.txt (Open3D for poisson_peers.py; ~105 MB; needs the
#             system library libusb-1.0: apt-get install libusb-1.0-0)
#   --python  also builds the zeroset wheel from this checkout (maturin, pinned in
#             crates/python/requirements-test.txt) and installs it, for python_peers.py
#   --cholmod also installs requirements-cholmod.txt (scikit-sparse, CHOLMOD, for python_peers.py's
#             direct row; built from source: needs apt-get install libsuitesparse-dev, and
#             libopenblas0-pthread so that CHOLMOD runs on OpenBLAS, not the reference BLAS)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="$here/.venv"
python="${PYTHON:-python3}"
torch=0
open3d=0
python_pkg=0
cholmod=0
for arg in "$@"; do
    case "$arg" in
        --torch) torch=1 ;;
        --open3d) open3d=1 ;;
        --python) python_pkg=1 ;;
        --cholmod) cholmod=1 ;;
        *)
            echo "usage: bash benches/peers/setup.sh [--torch] [--open3d] [--python] [--cholmod]" >&2
            exit 2
            ;;
    esac
done
if [ ! -x "$venv/bin/python" ]; then
    echo "creating $venv with $("$python" --version 2>&1)"
    "$python" -m venv "$venv"
fi
# pip is a no-op when the pinned versions are already installed.
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements.txt"
if [ "$torch" = 1 ]; then
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements-torch.txt"
    "$venv/bin/python" -c 'import torch; print(f"ok: torch {torch.__version__}")'
fi
if [ "$open3d" = 1 ]; then
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements-open3d.txt"
    if ! "$venv/bin/python" -c 'import open3d; print(f"ok: open3d {open3d.__version__}")'; then
        echo "open3d is installed but does not import (if the error names libusb-1.0.so.0: apt-get install libusb-1.0-0)" >&2
        exit 1
    fi
fi
if [ "$cholmod" = 1 ]; then
    if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements-cholmod.txt"; then
        echo "scikit-sparse did not build (it needs the SuiteSparse headers: apt-get install libsuitesparse-dev libopenblas0-pthread)" >&2
        exit 1
    fi
    "$venv/bin/python" -c 'from sksparse.cholmod import cholesky; print("ok: scikit-sparse (CHOLMOD)")'
fi
if [ "$python_pkg" = 1 ]; then
    repo="$(cd "$here/../.." && pwd)"
    maturin=$(grep '^maturin==' "$repo/crates/python/requirements-test.txt")
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$maturin"
    rm -rf "$repo/target/peers-wheel"
    "$venv/bin/maturin" build --release --locked --quiet -m "$repo/crates/python/Cargo.toml" \
        -i "$venv/bin/python" -o "$repo/target/peers-wheel"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps \
        "$repo"/target/peers-wheel/zeroset-*.whl
    "$venv/bin/python" -c 'import zeroset; print(f"ok: zeroset {zeroset.__version__} (wheel)")'
fi
"$venv/bin/python" -c 'import sys, numpy, scipy; print(f"ok: python {sys.version.split()[0]}, numpy {numpy.__version__}, scipy {scipy.__version__}")'
