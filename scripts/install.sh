#!/usr/bin/env bash
# Creates the development environment in .venv/ at the repository root:
# system packages (a C++ compiler, CMake, Python headers and venv, Debian's Blender and Xvfb for
# the add-on's tests), the Python dependencies (requirements.txt) and the engine built from
# source (engine/). No system Embree: the engine loads the one the embreex wheel ships.
# Safe to run again: it only installs what is missing and rebuilds the engine.
set -euo pipefail
cd "$(dirname "$0")/.."

PY=${PYTHON:-python3}
APT_PACKAGES="g++ cmake make python3-dev python3-venv blender xvfb xauth"

missing=()
for p in $APT_PACKAGES; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "== installing system packages: ${missing[*]}"
  $SUDO apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq ${missing[*]} >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  echo "== creating .venv with $($PY --version)"
  $PY -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
echo "== installing Python dependencies (bpy is large: this takes a few minutes the first time)"
.venv/bin/python -m pip install -q -r requirements.txt
echo "== building and installing the engine (C++ core) from source"
.venv/bin/python -m pip install -q -e ./engine
echo "== installing the Blender add-on as a package (photic_blender: photic-blend, .blend job inputs)"
.venv/bin/python -m pip install -q -e ./blender_addon
.venv/bin/python -c "import photic._core, photic; print('photic', photic.__version__, 'installed;', photic._core.EMBREE)"
