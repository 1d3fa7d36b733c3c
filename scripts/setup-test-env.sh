#!/usr/bin/env bash
# Installs the test clients springbake's tests use into ignored folders of this checkout:
#   .venv/         Python venv with bpy (Blender as a module), usd-core and ray
#   node_modules/  the Khronos gltf-validator
# Idempotent: a second run only checks. Needs network access to PyPI and npm.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
BPY_VERSION=${BPY_VERSION:-5.0.1}

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $($PYTHON --version)"
  "$PYTHON" -m venv .venv
fi
if ! .venv/bin/python -c 'import pxr.Usd' 2>/dev/null; then
  echo "setup: installing usd-core into .venv"
  .venv/bin/pip install --quiet --disable-pip-version-check usd-core
fi
if ! .venv/bin/python -c 'import bpy' 2>/dev/null; then
  echo "setup: installing bpy==$BPY_VERSION into .venv (about 820 MB)"
  .venv/bin/pip install --quiet --disable-pip-version-check "bpy==$BPY_VERSION"
fi
if ! .venv/bin/python -c 'import ray' 2>/dev/null; then
  echo "setup: installing ray into .venv (springbake wedge --ray tests)"
  .venv/bin/pip install --quiet --disable-pip-version-check "ray==2.60.0"
fi
if [ ! -f node_modules/gltf-validator/package.json ]; then
  echo "setup: installing gltf-validator into node_modules"
  npm ci --no-audit --no-fund --silent >/dev/null
fi
echo "setup: test clients ready (.venv, node_modules)"
