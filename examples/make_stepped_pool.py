"""Write examples/stepped_pool.json (the talk's example scene) and PNG previews of its cameras.

    .venv/bin/python examples/make_stepped_pool.py [--resolution 192 128] [--samples 32]

The scene is built by ``photic.scenes.stepped_pool`` (96 x 64 pixels per camera in the file);
the previews are rendered with the hybrid integrator at a small budget, tone-mapped (the 99th
percentile of the luminance maps to 1, sRGB curve) and written to docs/images/.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from photic.images import write_preview
from photic.render import render
from photic.scene import load_scene, save_scene
from photic.scenes import stepped_pool

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolution", type=int, nargs=2, default=(192, 128), metavar=("W", "H"),
                   help="preview resolution (default 192 128; the JSON file keeps 96 x 64)")
    p.add_argument("--samples", type=int, default=32, help="samples per pixel of the previews")
    p.add_argument("--threads", type=int, default=0, help="threads, 0 = all cores")
    p.add_argument("--scene", type=Path, default=ROOT / "examples" / "stepped_pool.json")
    p.add_argument("--images", type=Path, default=ROOT / "docs" / "images")
    args = p.parse_args(argv)

    scene = stepped_pool()
    save_scene(scene, args.scene)
    size = args.scene.stat().st_size
    loaded = load_scene(args.scene)  # the file reads back and validates
    print(f"wrote {args.scene} ({size / 1e6:.2f} MB, {len(loaded.water[0].mesh.triangles)} water "
          f"triangles, {sum(len(m.mesh.triangles) for m in loaded.meshes)} opaque triangles)")

    preview = stepped_pool(resolution=tuple(args.resolution), samples=args.samples, integrator="hybrid")
    t0 = time.perf_counter()
    result = render(preview, samples=args.samples, threads=args.threads)
    st = result.stats
    print(f"rendered {len(result.images)} cameras at {args.resolution[0]}x{args.resolution[1]}, "
          f"{args.samples} spp, {st['integrator']} (forward cone {st['forward_cone_deg']:g} deg) in "
          f"{time.perf_counter() - t0:.1f} s ({st['beam_passes']} beam passes, "
          f"{st['beam_build_s']:.1f} s building up to {st['beam_prisms']} prisms)")
    for name, image in result.images.items():
        path = write_preview(args.images / f"stepped_pool_{name}.png", image.mean)
        share = {k: float(v.mean() / max(image.mean.mean(), 1e-30)) for k, v in image.components.items()}
        rel = float(np.sqrt(image.variance.mean()) / max(image.mean.mean(), 1e-30))
        print(f"  {path}: mean radiance {image.mean.mean():.4g}, rel. pixel noise {rel:.3f}, shares "
              + ", ".join(f"{k} {v:.2f}" for k, v in share.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
