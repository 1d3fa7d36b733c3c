#!/usr/bin/env bash
# Installs the test clients springbake's tests use into ignored folders of this checkout:
#   .venv/         Python venv with bpy (Blender as a module), usd-core, alembic3d, ray, maturin
#                  and springbake's own Python package (python/, scripts/build-python-package.sh)
#   node_modules/  the Khronos gltf-validator, three.js and playwright-core (the VAT player test)
#   and, from the distribution's packages, Xvfb, xdotool and xwd for the live-window test,
#   Chromium for the VAT player test, and Mesa's software Vulkan driver (lavapipe) with the
#   Vulkan loader where no Vulkan driver is installed (the GPU solver's tests run on it)
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
if ! .venv/bin/python -c 'import numpy' 2>/dev/null; then
  echo "setup: installing numpy into .venv (Python plug-ins)"
  .venv/bin/pip install --quiet --disable-pip-version-check numpy
fi
if ! .venv/bin/python -c 'import alembic3d' 2>/dev/null; then
  echo "setup: installing alembic3d (PyAlembic) into .venv (Alembic export)"
  .venv/bin/pip install --quiet --disable-pip-version-check "alembic3d==1.8.12.1"
fi
if ! .venv/bin/python -c 'import maturin' 2>/dev/null; then
  echo "setup: installing maturin into .venv (builds springbake's Python package)"
  .venv/bin/pip install --quiet --disable-pip-version-check "maturin==1.16.0"
fi
if ! .venv/bin/python -c 'import bpy' 2>/dev/null; then
  echo "setup: installing bpy==$BPY_VERSION into .venv (about 820 MB)"
  .venv/bin/pip install --quiet --disable-pip-version-check "bpy==$BPY_VERSION"
fi
if ! .venv/bin/python -c 'import ray' 2>/dev/null; then
  echo "setup: installing ray into .venv (springbake wedge --ray tests)"
  .venv/bin/pip install --quiet --disable-pip-version-check "ray==2.60.0"
fi
if ! command -v Xvfb >/dev/null || ! command -v xdotool >/dev/null || ! command -v xwd >/dev/null; then
  echo "setup: installing xvfb, xdotool and x11-apps (the live-window test)"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get install -y -qq xvfb xdotool x11-apps >/dev/null 2>&1 \
    || { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq xvfb xdotool x11-apps >/dev/null; }
fi
if { ! compgen -G '/usr/share/vulkan/icd.d/*.json' >/dev/null \
  && ! compgen -G '/etc/vulkan/icd.d/*.json' >/dev/null; } \
  || ! ldconfig -p | grep -q 'libvulkan\.so\.1'; then
  echo "setup: installing mesa-vulkan-drivers and libvulkan1 (lavapipe: the GPU solver's tests without a GPU)"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null 2>&1 \
    || { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null; }
fi
if ! command -v chromium >/dev/null; then
  echo "setup: installing chromium (the VAT player test's headless browser)"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get install -y -qq chromium >/dev/null 2>&1 \
    || { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq chromium >/dev/null; }
fi
if [ ! -f node_modules/gltf-validator/package.json ] || [ ! -f node_modules/three/package.json ] \
  || [ ! -f node_modules/playwright-core/package.json ]; then
  echo "setup: installing gltf-validator, three and playwright-core into node_modules"
  npm ci --no-audit --no-fund --silent >/dev/null
fi
scripts/build-python-package.sh
echo "setup: test clients ready (.venv, node_modules)"
