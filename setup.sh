#!/usr/bin/env bash
# One command on a fresh machine: set everything up in .venv/ and run the main job
# (render the example .blend headless through the Blender add-on, writing a multilayer EXR
# image and radiometer tables).
set -euo pipefail
cd "$(dirname "$0")"
bash scripts/install.sh
echo "== rendering example_blends/underwater_objects.blend (bpy + the Photic add-on)"
.venv/bin/photic blend example_blends/underwater_objects.blend --out out --png
