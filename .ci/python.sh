#!/usr/bin/env bash
# CI: the Python package. Creates a venv, installs maturin and pytest from PyPI, builds and
# installs ./python (PyO3, through maturin), then runs its pytest suite. Any failure fails CI.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
venv="${SCANATLAS_PY_VENV:-$root/target/python-venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet "maturin>=1.7,<2" pytest
# The package's own target folder, kept between runs (it is not part of the workspace's).
# maturin runs as a subprocess of pip, found on PATH.
export PATH="$venv/bin:$PATH"
export CARGO_TARGET_DIR="${SCANATLAS_PY_TARGET:-$root/target/python}"
echo "== pip install ./python"
start=$(date +%s)
"$venv/bin/pip" install --no-build-isolation --force-reinstall --no-deps ./python
echo "installed in $(( $(date +%s) - start )) s"
echo "== pytest python/tests"
"$venv/bin/python" -m pytest -q python/tests
echo "== python package passed"
