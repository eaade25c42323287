#!/usr/bin/env python3
"""F12 and the viewport timed in Blender with its UI, as a user meets them: Debian's Blender
(3.4) under Xvfb, the add-on installed into a temporary scripts folder, keys pressed through
the X server (``scripts/ui_timing.py`` runs inside Blender).

    .venv/bin/python scripts/ui_timing_run.py f12 --esc 1.5,3 --repeat 3
    .venv/bin/python scripts/ui_timing_run.py viewport --repeat 3
    .venv/bin/python scripts/ui_timing_run.py f12 --addon-src /tmp/base/blender_addon   # another add-on

Prints the JSON of every run and the medians. Defaults: the main example
(``example_blends/underwater_objects.blend``) at 1920 x 1080, Denoise on, 2 threads, opened
without its screen layout (Blender's default one); the Xvfb screen is 1920 x 1080 for F12 and
1600 x 1027 for the viewport, where that layout's 3D view is 1321 x 877 pixels. Nothing of the user's Blender configuration is read or written.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import site
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
INSIDE = ROOT / "scripts" / "ui_timing.py"
MAIN_EXAMPLE = ROOT / "example_blends" / "underwater_objects.blend"


def free_display() -> int:
    for n in range(120, 200):
        if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists():
            return n
    raise RuntimeError("no free X display number")


def install(scripts: Path, source: Path | None) -> None:
    """The add-on into ``scripts`` (the repository's unless ``source`` is given)."""
    if source is None:
        subprocess.run([sys.executable, str(ROOT / "scripts" / "install_blender_addon.py"),
                        "--scripts", str(scripts)], check=True, capture_output=True)
        return
    dest = scripts / "addons" / "photic_blender"
    shutil.copytree(source, dest, ignore=shutil.ignore_patterns("__pycache__", "site_packages.txt"))
    (dest / "site_packages.txt").write_text("\n".join(site.getsitepackages()) + "\n")


def run(mode: str, blend: Path = MAIN_EXAMPLE, esc: str = "", repeat: int = 1,
        resolution: str = "1920x1080", denoise: bool = True, threads: int = 2,
        samples: int | None = None, addon_src: Path | None = None, timeout: float = 900,
        screen: str | None = None, blender: str = "blender") -> dict:
    """Results of ``scripts/ui_timing.py`` in one Blender session (see its docstring)."""
    # F12: a full-HD screen; the viewport: the screen on which Blender's default layout gives
    # the 3D view of the measurement, 1321 x 877 pixels.
    screen = screen or ("1920x1080" if mode == "f12" else "1600x1027")
    tmp = Path(tempfile.mkdtemp(prefix="photic_ui_"))
    xvfb = None
    try:
        (tmp / "home").mkdir()
        install(tmp / "scripts", addon_src)
        n = free_display()
        xvfb = subprocess.Popen(["Xvfb", f":{n}", "-screen", "0", f"{screen}x24", "-nolisten", "tcp"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for _ in range(100):
            if Path(f"/tmp/.X11-unix/X{n}").exists():
                break
            time.sleep(0.05)
        out = tmp / "results.json"
        env = dict(os.environ, DISPLAY=f":{n}", LIBGL_ALWAYS_SOFTWARE="1", HOME=str(tmp / "home"),
                   XDG_CONFIG_HOME=str(tmp / "home" / ".config"), XDG_CACHE_HOME=str(tmp / "home" / ".cache"),
                   BLENDER_USER_CONFIG=str(tmp / "config"), BLENDER_USER_SCRIPTS=str(tmp / "scripts"),
                   BLENDER_USER_DATAFILES=str(tmp / "datafiles"), BLENDER_USER_RESOURCES=str(tmp / "resources"),
                   PHOTIC_UI_OUT=str(out), PHOTIC_UI_MODE=mode, PHOTIC_UI_ESC_AFTER=esc,
                   PHOTIC_UI_REPEAT=str(repeat), PHOTIC_UI_RESOLUTION=resolution,
                   PHOTIC_UI_DENOISE="1" if denoise else "0", PHOTIC_UI_THREADS=str(threads),
                   PHOTIC_UI_SAMPLES="" if samples is None else str(samples))
        env.pop("PHOTIC_SITE_PACKAGES", None)
        env.setdefault("PHOTIC_UI_WATCHDOG", "0")
        w, h = screen.split("x")
        # The file without its own screen layout: Blender's default one at this window size
        # (a 3D view of about 1321 x 879 pixels at 1920 x 1080), as a new user has it.
        proc = subprocess.run([blender, "--addons", "photic_blender", "--factory-startup", "-p", "0", "0", w, h,
                               "--python-expr", "import bpy; bpy.context.preferences.filepaths.use_load_ui = False",
                               str(blend), "--python", str(INSIDE)],
                              env=env, capture_output=True, text=True, timeout=timeout)
        if not out.exists():
            raise RuntimeError(f"Blender wrote no results (exit {proc.returncode}):\n"
                               f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
        res = json.loads(out.read_text())
        res["log"] = proc.stdout[-6000:]
        return res
    finally:
        if xvfb is not None:
            xvfb.terminate()
            xvfb.wait()
        shutil.rmtree(tmp, ignore_errors=True)


def medians(res: dict) -> dict:
    keys = sorted({k for r in res["runs"] for k, v in r.items() if isinstance(v, (int, float)) and v is not None})
    out = {}
    for k in keys:
        vals = [r[k] for r in res["runs"] if isinstance(r.get(k), (int, float))]
        if vals:
            out[k] = {"median": statistics.median(vals), "min": min(vals), "max": max(vals), "n": len(vals)}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["f12", "viewport"])
    ap.add_argument("--blend", type=Path, default=MAIN_EXAMPLE)
    ap.add_argument("--esc", default="", help="seconds after F12 to press Esc, comma-separated (one F12 each)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--resolution", default="1920x1080")
    ap.add_argument("--no-denoise", action="store_true")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--samples", type=int, default=None)
    ap.add_argument("--addon-src", type=Path, default=None)
    a = ap.parse_args(argv)
    res = run(a.mode, a.blend, a.esc, a.repeat, a.resolution, not a.no_denoise, a.threads, a.samples, a.addon_src)
    log = res.pop("log", "")
    print(json.dumps(res, indent=1))
    print(json.dumps(medians(res), indent=1))
    if res.get("error"):
        print(log[-3000:], file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
