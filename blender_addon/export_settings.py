"""The scene's Photic render settings (integrator, samples, seed, depth, threads, forward
cone, adaptive sampling, Raman scattering) as the engine's ``Settings``."""
from __future__ import annotations

import math

from .export_values import blender_float

#: Scene.photic.raman -> the engine's settings.raman
RAMAN_SETTING = {"AUTO": "auto", "ON": True, "OFF": False}


def settings(ex):
    """The engine's settings from the scene's Photic properties."""
    S = ex.photic.scene
    p = ex.props
    cone = "auto" if p.forward_cone == "AUTO" else blender_float(math.degrees(p.forward_cone_angle))
    return S.Settings(integrator=p.integrator.lower(), samples=int(p.samples),
                      radiometer_samples=int(p.radiometer_samples), seed=int(p.seed),
                      max_depth=int(p.max_depth), threads=int(p.threads),
                      forward_cone_deg=cone, beam_max_level=int(p.beam_max_level),
                      target_error=(blender_float(p.target_error) / 100.0
                                    if p.use_target_error else None),
                      noise_threshold=(blender_float(p.noise_threshold) / 100.0
                                       if p.use_noise_threshold else None),
                      adaptive_min_samples=int(p.adaptive_min_samples),
                      raman=RAMAN_SETTING[p.raman])
