"""Rendering .blend files without the Blender application: ``photic blend`` and scripts.

Works in ``bpy`` (the Python module) and inside a Blender started with ``--background``.
The add-on is registered when it is not yet, the file is opened, the Photic engine selected,
and the frame rendered through ``bpy.ops.render.render`` (so through the RenderEngine, exactly
as F12 renders it) into a multilayer EXR with the Photic passes, with the radiometer tables
beside it.
"""
from __future__ import annotations

import sys
from pathlib import Path

import bpy

from . import final_render


def ensure_registered() -> None:
    """Register the add-on unless Blender already has it (as an extension or add-on)."""
    if not hasattr(bpy.types.Scene, "photic"):
        sys.modules[__package__].register()


def open_blend(path) -> tuple[Path, "bpy.types.Scene"]:
    """Open a .blend file with the add-on registered; (its absolute path, its scene set to
    render with Photic)."""
    path = Path(path).resolve()
    if not path.is_file():
        raise FileNotFoundError(f"no such .blend file: {path}")
    ensure_registered()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    return path, scene


def export_frames(path, frames=None) -> list:
    """[(frame, photic Scene)] of a .blend file, each exported through the Photic render engine
    exactly as a final render of that frame would be (render depsgraph, resolution), without
    rendering it: the scenes of a ``photic batch`` job's .blend input."""
    path, scene = open_blend(path)
    out = []
    for frame in frames or [scene.frame_current]:
        scene.frame_set(int(frame))
        captured: list = []
        final_render.EXPORT_HOOK = captured.append
        final_render.LAST_RENDER.clear()
        try:
            bpy.ops.render.render()
        finally:
            final_render.EXPORT_HOOK = None
        if not captured:
            raise RuntimeError(f"{path.name}, frame {frame}: " + (final_render.LAST_RENDER.get("error") or
                               "the scene was not exported (is there a camera or a radiometer?)"))
        out.append((int(frame), captured[0]))
    return out


def render_blend(path, frame: int | None = None, out_dir=None, samples: int | None = None,
                 radiometer_samples: int | None = None, seed: int | None = None,
                 threads: int | None = None, resolution_percentage: int | None = None,
                 progress=None, target_error: float | None = None,
                 noise_threshold: float | None = None, radiometers_only: bool = False,
                 png: bool = False) -> dict:
    """Render one frame of a .blend file with Photic.

    ``progress(fraction, text)``, when given, is called as the render goes on (a background
    Blender shows nothing). Returns the render summary (``final_render.LAST_RENDER``) with
    ``"image"``: the EXR path. ``target_error`` (a fraction, e.g. 0.01) turns on the scene's
    Target Error for the radiometers at that value, ``noise_threshold`` (a fraction) its Noise
    Threshold for the pixels. ``radiometers_only`` (or a file without a camera) renders the
    radiometers alone, as Render > Render Radiometers does: tables beside the output, no image
    (``"image"`` is None). ``png``: also a PNG beside the EXR as Blender displays the image
    (its view transform and exposure; ``"png"``: its path). Raises RuntimeError with the add-on's message when the render
    failed.
    """
    path, scene = open_blend(path)
    p = scene.photic
    for name, value in (("samples", samples), ("radiometer_samples", radiometer_samples),
                        ("seed", seed), ("threads", threads)):
        if value is not None:
            setattr(p, name, int(value))
    if target_error is not None:
        p.use_target_error, p.target_error = True, 100.0 * float(target_error)
    if noise_threshold is not None:
        p.use_noise_threshold, p.noise_threshold = True, 100.0 * float(noise_threshold)
    if resolution_percentage is not None:
        scene.render.resolution_percentage = int(resolution_percentage)
    if frame is not None:
        scene.frame_set(int(frame))
    out_dir = Path(out_dir if out_dir is not None else path.parent / "out").resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: multilayer is a media type
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    scene.render.use_file_extension = True
    scene.render.filepath = str(out_dir / f"{path.stem}_####")
    if radiometers_only or scene.camera is None:
        from . import natural_waters
        from .radiometers import render_radiometers
        natural_waters.read_volumes(scene)
        summary = render_radiometers(bpy.context.evaluated_depsgraph_get(), progress=progress,
                                     should_stop=final_render.CANCEL.is_set)
        summary["image"] = None
        return summary
    # (Volume grids: read before the frame by natural_waters' render_pre handler)
    final_render.LAST_RENDER.clear()
    final_render.PROGRESS_HOOK = progress
    try:
        bpy.ops.render.render()
    finally:
        final_render.PROGRESS_HOOK = None
    summary = dict(final_render.LAST_RENDER)
    if summary.get("cancelled") and not summary.get("samples"):  # stopped before a sample
        summary.update(image=None, nothing_done=True)
        return summary
    if not summary or summary.get("error"):
        raise RuntimeError(summary.get("error") or "the render did not run (is the scene's "
                                                   "render engine Photic and is there a camera?)")
    # Saved here rather than with write_still, which does not number still frames in 5.0;
    # under a temporary name renamed when complete, so that a full disk or a second Ctrl-C
    # never leaves a truncated image under the frame's name.
    image = scene.render.frame_path(frame=scene.frame_current)
    _save_render(image, scene)
    summary["image"] = image
    if png:
        final_render.apply_auto_exposure(scene)  # (as the render_complete handler does)
        if hasattr(settings, "media_type"):  # Blender 5: a single image is a media type
            settings.media_type = "IMAGE"
        settings.file_format = "PNG"
        settings.color_depth = "8"
        summary["png"] = str(Path(image).with_suffix(".png"))
        _save_render(summary["png"], scene)
    return summary


def _save_render(path: str, scene) -> None:
    """The render result saved to ``path`` with the scene's output settings, atomically."""
    from photic.safe_io import atomic_path

    with atomic_path(path) as tmp:
        bpy.data.images["Render Result"].save_render(filepath=str(tmp), scene=scene)
