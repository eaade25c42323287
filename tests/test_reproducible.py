"""Same scene and seed give bit-identical numbers whatever the thread count."""
from pathlib import Path

import numpy as np

from photic.render import render
from photic.scene import load_scene

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "coastal_shelf.json"


def test_bit_identical_on_one_and_two_threads():
    scene = load_scene(EXAMPLE)
    kw = dict(samples=3, radiometer_samples=5000, seed=99)
    one = render(scene, threads=1, **kw)
    two = render(scene, threads=2, **kw)
    for name, img in one.images.items():
        assert img.mean.any()
        assert np.array_equal(img.mean, two.images[name].mean)
        assert np.array_equal(img.variance, two.images[name].variance)
    for r1, r2 in zip(one.radiometers, two.radiometers):
        assert np.array_equal(r1.mean, r2.mean) and np.array_equal(r1.stderr, r2.stderr)
    # A different seed changes the numbers (the test can fail).
    other = render(scene, threads=2, samples=3, radiometer_samples=5000, seed=100)
    assert not np.array_equal(other.images["diver"].mean, one.images["diver"].mean)


def test_pass_output_arrays_are_reused_and_checked():
    """render_camera / render_radiometer fill the caller's arrays (out=) with exactly what
    new ones would hold, zeroing what an earlier pass left; a wrong shape or type is refused."""
    import pytest

    from photic.compile import compile_scene

    scene = load_scene(EXAMPLE)
    core = compile_scene(scene, slice(0, len(scene.bands)), seed=7)
    cam = scene.cameras[0]
    shape = (cam.resolution[1], cam.resolution[0]) + core.render_camera(0, 0, 1, 1)[0].shape[2:]
    bufs = (np.full(shape, 5.0), np.full(shape, 5.0))  # garbage from an "earlier pass"
    s, s2, c = core.render_camera(0, 0, 2, 1, bufs)
    assert s is bufs[0] and s2 is bufs[1]
    t, t2, ct = core.render_camera(0, 0, 2, 1)
    assert s.any() and np.array_equal(s, t) and np.array_equal(s2, t2) and c == ct
    r = core.render_radiometer(0, 0, 200, 1)
    rb = tuple(np.full(r[0].shape, -1.0) for _ in range(2))
    assert np.array_equal(core.render_radiometer(0, 0, 200, 1, rb)[0], r[0])
    for bad in ((np.zeros(shape[:-1] + (shape[-1] + 1,)), bufs[1]),       # shape
                (bufs[0], np.zeros(shape, dtype=np.float32)),              # type
                (bufs[0], np.zeros(shape[::-1]).T),                        # not C-contiguous
                (bufs[0],)):                                               # not a pair
        with pytest.raises(ValueError, match="out"):
            core.render_camera(0, 0, 1, 1, bad)
