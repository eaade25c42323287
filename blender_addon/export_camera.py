"""The engine's camera: the scene's camera object (perspective or orthographic, its sensor
fit, shift and clip start in the render's resolution), or the 3D viewport's view given as a
``ViewCamera``."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .export_values import ExportError, _obj, blender_float


@dataclass
class ViewCamera:
    """A camera given directly (the 3D viewport's view) instead of a camera object."""

    orthographic: bool
    matrix_world: np.ndarray   # camera-to-world, looking down -Z with +Y up
    tan_half_fov: float        # horizontal
    ortho_width: float
    shift: tuple
    clip_start: float


def camera(ex, view_camera: ViewCamera | None, resolution: tuple[int, int]):
    """The engine camera of ``view_camera``, else of the scene's camera (None without one)."""
    S = ex.photic.scene
    width, height = resolution
    vc = view_camera
    if vc is not None:
        m = np.asarray(vc.matrix_world, float)
        return S.Camera("viewport", "orthographic" if vc.orthographic else "perspective",
                        m[:3, 3].copy(), -m[:3, 2], up=m[:3, 1].copy(),
                        fov_deg=math.degrees(2 * math.atan(vc.tan_half_fov)),
                        ortho_width=vc.ortho_width, resolution=(width, height),
                        shift=tuple(vc.shift), clip_start=vc.clip_start)
    cam = ex.bscene.camera
    if cam is None:
        return None
    r = ex.bscene.render
    if abs(r.pixel_aspect_x - r.pixel_aspect_y) > 1e-6 * r.pixel_aspect_x:
        raise ExportError(f"Scene '{ex.bscene.name}'", "Output > Format > Aspect "
                          "(render.pixel_aspect_x/y)", f"non-square pixels "
                          f"({r.pixel_aspect_x:g}:{r.pixel_aspect_y:g}) are not supported")
    owner = _obj(cam.name)
    data = cam.data
    m = np.asarray(cam.matrix_world, float)
    if not np.isfinite(m).all():
        from .export_values import non_finite_transform
        raise non_finite_transform(cam)
    fwd, up = -m[:3, 2], m[:3, 1]
    if not (np.linalg.norm(fwd) > 0 and np.linalg.norm(up) > 0):
        raise ExportError(owner, "Scale", "is zero: the camera has no viewing direction")
    fit = data.sensor_fit
    if fit == "AUTO":
        ref = max(width, height)
        sensor = data.sensor_width
    elif fit == "HORIZONTAL":
        ref, sensor = width, data.sensor_width
    else:
        ref, sensor = height, data.sensor_height
    if data.type == "PANO":
        raise ExportError(owner, "Type (data.type)", "panoramic cameras are not supported "
                                                     "by Photic; use perspective or "
                                                     "orthographic")
    if data.type == "ORTHO":
        half_ref = 0.5 * float(data.ortho_scale)
    else:
        if not data.lens > 0:
            raise ExportError(owner, "Focal Length (data.lens)", f"is {data.lens}, must be > 0")
        half_ref = 0.5 * float(sensor) / float(data.lens)  # tan of the half angle
    half_width = half_ref * width / ref
    # Blender's smallest clip start (1e-6 m) means none.
    clip = blender_float(data.clip_start)
    clip = 0.0 if clip <= 1e-6 else clip
    shift = (float(data.shift_x) * ref / width, float(data.shift_y) * ref / width)
    if data.type == "ORTHO":
        return S.Camera(cam.name, "orthographic", m[:3, 3].copy(), fwd, up=up.copy(),
                        ortho_width=2 * half_width, resolution=(width, height), shift=shift,
                        clip_start=clip)
    fov = math.degrees(2 * math.atan(half_width))
    if not 0 < fov < 180:
        raise ExportError(owner, "Focal Length (data.lens)", f"gives a field of view of "
                                                             f"{fov:.3g} degrees")
    return S.Camera(cam.name, "perspective", m[:3, 3].copy(), fwd, up=up.copy(),
                    fov_deg=fov, resolution=(width, height), shift=shift, clip_start=clip)
