"""Speed against error in gridded water (a benchmark command, not a test): the sediment-plume
example's scene (``example_blends/make_examples.py``: shore, 10 bands, Case-2 IOP models, the
plume on its own grid of 128 x 128 x 32 voxels, or ``--shape``) without its camera, the
radiance above the plume and above clear water (``Lu_plume``, ``Lu_clear``, the water-leaving
light behind Rrs) in every band, rendered with pure path tracing and the hybrid integrator
(cone 0 and 'auto') at doubling sample budgets. Errors: RMS over the 20 values of
(x - ref) / ref, the reference the hybrid at a large budget with its own noise removed (as
``photic bench --error``, whose machinery this uses). Prints the table and the time to 5 %
error; writes the log-log plot of error against time.

    .venv/bin/python scripts/grid_error.py [--shape 128 128 32] [--threads 2] [--quick]
                                           [--plot docs/images/bench_error_plume.png]
"""
from __future__ import annotations

import argparse
import functools
import tempfile
from pathlib import Path

import numpy as np

from photic.bench import ErrorCase, run_error_bench
from photic.scene import Scene

from grid_cost import _examples

NAMES = ("Lu_plume", "Lu_clear")


_TEMP_DIRS = []  # removed when the interpreter exits


@functools.lru_cache(maxsize=None)
def density_file(shape: tuple) -> Path:
    """The example's plume on a grid of ``shape``, in a .npz (as users give grids)."""
    _TEMP_DIRS.append(tempfile.TemporaryDirectory(prefix="photic_grid_error_"))
    path = Path(_TEMP_DIRS[-1].name) / "plume.npz"
    np.savez(path, density=_examples().plume_density(shape))
    return path


def plume_scene(integrator: str, cone, shape) -> Scene:
    ex = _examples()
    d = ex.plume_scene_dict()
    d["cameras"] = []
    water = d["water"][0]
    del water["iops"]
    water["iop_grid"] = {"base": {"iop_model": ex.clear_water_model()},
                         "unit": {"iop_model": ex.plume_unit_model()},
                         "origin": list(ex.PLUME_BOX_ORIGIN), "size": list(ex.PLUME_BOX_SIZE),
                         "file": density_file(tuple(shape)).name}
    d["settings"].update(integrator=integrator, forward_cone_deg=cone)
    return Scene.from_dict(d, base_dir=density_file(tuple(shape)).parent)


def pick(result):
    """Lu above the plume and above clear water, every band: values and their variances."""
    rs = [result.radiometer(n) for n in NAMES]
    return (np.concatenate([r.mean[0] for r in rs]),          # (nbins = 1, nbands)
            np.concatenate([r.stderr[0] ** 2 for r in rs]))


def main(argv=None) -> list:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shape", type=int, nargs=3, default=None, help="the plume's grid (default: the example's)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="small budgets (a smoke run)")
    ap.add_argument("--plot", default=str(Path(__file__).resolve().parents[1] / "docs" / "images"
                                          / "bench_error_plume.png"))
    args = ap.parse_args(argv)
    shape = args.shape or _examples().PLUME_GRID_SHAPE
    doubling = lambda first, n: [first << i for i in range(n)]
    if args.quick:
        budgets = {"path": doubling(4096, 2), "hybrid cone 0": doubling(1024, 2), "hybrid auto": doubling(1024, 2)}
        ref = 1 << 14
    else:  # path samples are cheaper: larger budgets, to span similar times
        budgets = {"path": doubling(1 << 14, 6), "hybrid cone 0": doubling(1 << 12, 6),
                   "hybrid auto": doubling(1 << 12, 6)}
        ref = 1 << 21
    case = ErrorCase(f"sediment_plume_{'x'.join(map(str, shape))}",
                     f"Sediment plume {' x '.join(map(str, shape))}: Lu",
                     "radiometers", lambda integrator, cone: plume_scene(integrator, cone, shape),
                     budgets, ref, "samples", pick)
    return run_error_bench(threads=args.threads, plot=args.plot, cases=[case],
                           progress=lambda msg: print(msg, flush=True))


if __name__ == "__main__":
    main()
