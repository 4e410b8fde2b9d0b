#!/usr/bin/env bash
# Creates benches/peers/.venv and installs the pinned scipy/numpy (idempotent).
# Usage: bash benches/peers/setup.sh [--torch]   (from anywhere)
#   --torch  also installs requirements-torch.txt (PyTorch for neural_peers.py; a ~5 GB download)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="$here/.venv"
python="${PYTHON:-python3}"
if [ ! -x "$venv/bin/python" ]; then
    echo "creating $venv with $("$python" --version 2>&1)"
    "$python" -m venv "$venv"
fi
# pip is a no-op when the pinned versions are already installed.
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements.txt"
if [ "${1:-}" = "--torch" ]; then
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements-torch.txt"
    "$venv/bin/python" -c 'import torch; print(f"ok: torch {torch.__version__}")'
elif [ -n "${1:-}" ]; then
    echo "usage: bash benches/peers/setup.sh [--torch]" >&2
    exit 2
fi
"$venv/bin/python" -c 'import sys, numpy, scipy; print(f"ok: python {sys.version.split()[0]}, numpy {numpy.__version__}, scipy {scipy.__version__}")'
