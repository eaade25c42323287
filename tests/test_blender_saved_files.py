"""What a render writes to disk from Blender, as a user gets it: ``bpy.ops.render.render`` with
``write_still`` (``blender -b ... -f``) and ``animation`` (``-a``), 8-bit PNGs read back."""
from __future__ import annotations


import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from test_addon import add_camera, add_mesh, add_sun, empty  # noqa: E402,F401


def _png_mean(path) -> float:
    """Mean of an 8-bit PNG's RGB, 0-255 (Blender reads it back; no colour management)."""
    img = bpy.data.images.load(str(path))
    try:
        img.colorspace_settings.name = "Non-Color"  # (the stored bytes, not linearised)
        px = np.empty(img.size[0] * img.size[1] * img.channels, np.float32)
        img.pixels.foreach_get(px)
        return float(px.reshape(-1, img.channels)[:, :3].mean() * 255.0)
    finally:
        bpy.data.images.remove(img)


def _dim_scene(scene):
    """A lit ground under a very dim sun: near black at exposure 0."""
    add_camera()
    add_mesh("Ground", [(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [(0, 1, 2, 3)])
    sun = add_sun()
    sun.data.energy = 0.01
    scene.photic.samples = 2
    scene.view_settings.view_transform = "Standard"
    s = scene.render.image_settings
    if hasattr(s, "media_type"):  # Blender 5
        s.media_type = "IMAGE"
    s.file_format, s.color_depth, s.color_mode = "PNG", "8", "RGB"
    return sun


def test_a_still_is_saved_with_the_auto_exposure_blender_shows(empty, tmp_path):
    """``-f``: the PNG of a render with Auto Exposure shows the image's key as mid-grey (the
    issue: mean 8/255 for a dim sun, the exposure before the render); with it off the same
    render is near black, and the display exposure is the one the file was written with."""
    _dim_scene(empty)
    means = {}
    for auto in (True, False):
        empty.photic.auto_exposure = auto
        empty.view_settings.exposure = 0.0
        empty.render.filepath = str(tmp_path / f"still_{auto}_")
        bpy.ops.render.render(write_still=True)
        png = next(tmp_path.glob(f"still_{auto}_*.png"))
        means[auto] = _png_mean(png)
        if auto:
            assert empty.view_settings.exposure > 5.0
    assert means[False] < 20.0, means
    assert 60.0 < means[True] < 200.0, means


def test_every_frame_of_an_animation_is_saved_with_its_own_exposure(empty, tmp_path):
    """``-a``: frames 1 and 2, the sun 100 x brighter on frame 2: each PNG is exposed as
    Blender shows that frame (mid-grey), not with the exposure of the frame before."""
    sun = _dim_scene(empty)
    sun.data.energy = 0.01
    sun.data.keyframe_insert("energy", frame=1)
    sun.data.energy = 1.0
    sun.data.keyframe_insert("energy", frame=2)
    empty.frame_start, empty.frame_end = 1, 2
    empty.photic.auto_exposure = True
    empty.view_settings.exposure = 0.0
    empty.render.filepath = str(tmp_path / "anim_")
    bpy.ops.render.render(animation=True)
    pngs = sorted(tmp_path.glob("anim_*.png"))
    assert len(pngs) == 2, pngs
    means = [_png_mean(p) for p in pngs]
    assert all(60.0 < m < 200.0 for m in means), means
    assert abs(means[0] - means[1]) < 15.0, means
