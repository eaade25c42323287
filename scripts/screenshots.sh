#!/usr/bin/env bash
# Screenshots of the Photic panels and of a viewport render, taken in the distribution Blender
# (Debian's `blender` 3.4, with its UI) under Xvfb with Mesa's software OpenGL (llvmpipe).
#
#   bash scripts/screenshots.sh            # writes docs/images/blender_{render_panel,object_panel,viewport}.png
#
# Needs: apt packages blender, xvfb, xauth (scripts/install.sh installs them) and .venv with the
# engine. The add-on is installed into a temporary scripts directory and Blender's user config
# is redirected there as well, so ~/.config/blender is not touched. Environment knobs, read by
# scripts/screenshots.py: PHOTIC_SCREENSHOT_DIR (output directory), PHOTIC_SCREENSHOT_SAMPLES
# (viewport samples to wait for, default 32), PHOTIC_SCREENSHOT_WAIT (seconds at most, 300),
# DISPLAY_NUM (Xvfb display number, default 99).
set -euo pipefail
cd "$(dirname "$0")/.."

DISPLAY_NUM=${DISPLAY_NUM:-99}
TMP=$(mktemp -d)
XVFB_PID=""
cleanup() {
  if [ -n "$XVFB_PID" ]; then kill "$XVFB_PID" 2>/dev/null || true; fi
  rm -rf "$TMP"
}
trap cleanup EXIT

# Everything Blender could write for a user goes under $TMP: its config, scripts, data files
# and resources, and HOME itself (recent files, caches); the user's own Blender folder is
# fingerprinted before and after, and a change fails the script.
fingerprint() {
  local dir="${REAL_HOME}/.config/blender"
  if [ -d "$dir" ]; then find "$dir" -type f -printf '%p %s %T@\n' | sort | sha256sum; else echo none; fi
}
REAL_HOME="$HOME"
BEFORE=$(fingerprint)
mkdir -p "$TMP/home"
export HOME="$TMP/home" XDG_CONFIG_HOME="$TMP/home/.config" XDG_CACHE_HOME="$TMP/home/.cache"
export BLENDER_USER_CONFIG="$TMP/config" BLENDER_USER_SCRIPTS="$TMP/scripts"
export BLENDER_USER_DATAFILES="$TMP/datafiles" BLENDER_USER_RESOURCES="$TMP/resources"
.venv/bin/python scripts/install_blender_addon.py --scripts "$TMP/scripts"

Xvfb ":$DISPLAY_NUM" -screen 0 1600x1000x24 -nolisten tcp >"$TMP/xvfb.log" 2>&1 &
XVFB_PID=$!
for _ in $(seq 50); do
  [ -e "/tmp/.X11-unix/X$DISPLAY_NUM" ] && break
  sleep 0.1
done

DISPLAY=":$DISPLAY_NUM" LIBGL_ALWAYS_SOFTWARE=1 \
  blender --addons photic_blender -p 0 0 1600 1000 example_blends/stepped_pool.blend \
  --python scripts/screenshots.py

if [ "$(fingerprint)" != "$BEFORE" ]; then
  echo "screenshots.sh: the user's Blender configuration (${REAL_HOME}/.config/blender) changed" >&2
  exit 1
fi
