"""Example Photic plugins (see README.md): bubble-cloud IOPs and Gerstner waves.

Each function turns parameters into the data Photic's compiled core reads: per-band IOPs, or a
surface patch with its normals. Bad parameters raise ValueError; Photic reports the message with
the water body and the field.
"""
from __future__ import annotations

import math

import numpy as np


def bubble_cloud(params: dict, bands: list) -> "photic.scene.IOPs":  # noqa: F821
    """IOPs of a bubble cloud: {"b": scattering coefficient (1/m, >= 0), "g": HG asymmetry
    (default 0.85)}; geometric-optics bubbles scatter independently of wavelength and absorb
    nothing."""
    from photic.scene import IOPs, PhaseFunction, ScatteringComponent
    unknown = set(params) - {"b", "g"}
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)}; this model takes 'b' and 'g'")
    b = float(params.get("b", 0.0))
    g = float(params.get("g", 0.85))
    if not (math.isfinite(b) and b >= 0):
        raise ValueError(f"'b' must be a finite scattering coefficient >= 0 (1/m), got {b}")
    if not -0.99 <= g <= 0.99:
        raise ValueError(f"'g' must be in [-0.99, 0.99], got {g}")
    n = len(bands)
    return IOPs(np.zeros(n), [ScatteringComponent(np.full(n, b),
                                                   PhaseFunction("henyey_greenstein", {"g": g}))])


def gerstner_waves(params: dict):
    """A Gerstner wave travelling along +x over a square patch: {"amplitude_m", "wavelength_m",
    "waves_per_patch" (whole number, default 1), "resolution" (grid points per side, 64)}.
    The surface points are x = x0 - A sin(k x0), z = A cos(k x0) (steepness k A < 1); returns
    (vertices, triangles, normals, (Lx, Ly))."""
    a = float(params.get("amplitude_m", 0.1))
    lam = float(params.get("wavelength_m", 2.0))
    m = int(params.get("waves_per_patch", 1))
    n = int(params.get("resolution", 64))
    if not (lam > 0 and m >= 1 and n >= 4):
        raise ValueError("need wavelength_m > 0, waves_per_patch >= 1 and resolution >= 4")
    k = 2 * math.pi / lam
    if not 0 <= k * a < 1:
        raise ValueError(f"steepness k A = {k * a:.3g} must be below 1 (the wave would fold)")
    size = m * lam
    g = np.linspace(0.0, size, n + 1)
    x0, y = np.meshgrid(g, g, indexing="ij")
    x = x0 - a * np.sin(k * x0)
    z = a * np.cos(k * x0)
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    normals = np.stack([(k * a * np.sin(k * x0)).ravel(), np.zeros(x0.size),
                        (1 - k * a * np.cos(k * x0)).ravel()], 1)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    v00 = (i * (n + 1) + j).ravel()
    v10, v01 = v00 + n + 1, v00 + 1
    triangles = np.concatenate([np.stack([v00, v10, v10 + 1], 1), np.stack([v00, v10 + 1, v01], 1)])
    return vertices, triangles, normals, (size, size)
