#!/usr/bin/env bash
# One command on a fresh machine: set everything up in .venv/ and run the main job
# (render the example scene headless, writing an EXR image and radiometer tables).
set -euo pipefail
cd "$(dirname "$0")"
bash scripts/install.sh
echo "== rendering examples/coastal_shelf.json"
.venv/bin/photic render examples/coastal_shelf.json --out out
