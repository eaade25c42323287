"""The tiled ocean to the horizon: an image and the memory used for two visible distances.

A camera 10 m above a wind sea (a JONSWAP wave patch of 64 m repeated without copies, with
the sub-pixel Cox-Munk roughness for the same wind) looks towards the horizon with the sun
ahead: sun glint, reflected sky and the water's colour. The same sea is then rendered by a
camera looking steeply down at about 20 m of sea; each render runs in its own process and its
peak resident memory is printed, showing that memory does not grow with the visible distance.

    .venv/bin/python scripts/ocean_horizon.py [--out docs/images/ocean_horizon.png] [--samples N]
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path


REPO = Path(__file__).resolve().parents[1]


def scene_dict(view: str, resolution, samples: int) -> dict:
    direction = [0.0, 1.0, -0.06] if view == "horizon" else [0.0, 0.35, -1.0]
    return {
        "photic_scene": 1, "name": f"ocean_{view}",
        "bands": [{"name": "620", "center_nm": 620.0, "width_nm": 80.0},
                  {"name": "550", "center_nm": 550.0, "width_nm": 60.0},
                  {"name": "460", "center_nm": 460.0, "width_nm": 80.0}],
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34,
                   "surface": {"kind": "waves", "spectrum": "jonswap", "wind_speed": 7.0,
                               "fetch_m": 50000.0, "wind_direction_deg": 80.0,
                               "patch_size_m": [64.0, 64.0], "resolution": [128, 128], "seed": 4,
                               "roughness": {"wind_speed": 7.0}},
                   "iops": {"absorption": [0.3, 0.065, 0.02], "b": [0.05, 0.05, 0.05],
                            "phase": {"type": "petzold"}}}],
        "sun": {"zenith_deg": 70.0, "azimuth_deg": 90.0, "irradiance": [1.5, 1.8, 1.9]},
        "sky": {"type": "cardioidal", "radiance": [0.05, 0.07, 0.12]},
        "cameras": [{"name": "view", "type": "perspective", "position": [0.0, 0.0, 10.0],
                     "direction": direction, "up": [0.0, 0.0, 1.0], "fov_deg": 60.0,
                     "resolution": list(resolution)}],
        "settings": {"integrator": "path", "samples": samples, "seed": 5},
    }


def render_one(view: str, resolution, samples: int, png: str | None) -> dict:
    from photic.images import write_preview
    from photic.render import render
    from photic.scene import Scene
    t0 = time.perf_counter()
    result = render(Scene.from_dict(scene_dict(view, resolution, samples)))
    seconds = time.perf_counter() - t0
    if png:
        write_preview(png, result.images["view"].mean[:, :, ::-1])  # bands R, G, B
    return {"view": view, "seconds": seconds,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(REPO / "docs" / "images" / "ocean_horizon.png"))
    p.add_argument("--samples", type=int, default=32)
    p.add_argument("--resolution", type=int, nargs=2, default=[320, 180])
    p.add_argument("--one", choices=["horizon", "down"], help=argparse.SUPPRESS)
    p.add_argument("--png", default=None, help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.one:
        print(json.dumps(render_one(a.one, a.resolution, a.samples, a.png)))
        return 0
    rows = []
    for view in ("horizon", "down"):
        cmd = [sys.executable, __file__, "--one", view, "--samples", str(a.samples),
               "--resolution", *map(str, a.resolution)]
        if view == "horizon":
            cmd += ["--png", a.out]
        rows.append(json.loads(subprocess.run(cmd, check=True, capture_output=True,
                                              text=True).stdout.strip().splitlines()[-1]))
    print(f"{'view':<8} {'visible distance':<18} {'time (s)':>9} {'peak RSS (MB)':>14}")
    for r, dist in zip(rows, ("to the horizon", "about 20 m")):
        print(f"{r['view']:<8} {dist:<18} {r['seconds']:>9.1f} {r['peak_rss_mb']:>14.0f}")
    print(f"image: {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
