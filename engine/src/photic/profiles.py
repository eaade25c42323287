"""Stratified water: IOP profiles (``photic.scene.IOPProfile``) built from functions of depth.

The engine treats a profile of horizontal, homogeneous layers exactly: optical depths are
integrated in closed form layer by layer, collisions are accepted with the local scattering
(docs/physics.md, "Stratified water"). A continuous profile ``c(z)`` becomes layers whose
coefficients are the averages of ``c`` over each layer's depth range. The optical depth of any
straight path that crosses a layer whole is then exact, ``int c dl = mean(c) dz / |mu|`` for
every direction ``mu``; only the distribution of the coefficients inside a layer is
smoothed, and that error shrinks with the layer thickness.

Example: a Gaussian subsurface chlorophyll maximum through the classic Case-1 model (which
needs a chlorophyll-specific absorption table from the user, see ``photic.iop_models``)::

    chl = gaussian_chlorophyll(background=0.2, peak=1.5, z_max=-25.0, width=5.0)
    tops = np.arange(0.0, -60.0, -2.5)
    profile = profile_from_function(
        lambda z: {"model": "case1", "chlorophyll": chl(z), "chlorophyll_absorption": table},
        tops, bands)
    water = WaterBody("sea", "ocean", profile, surface=OceanSurface("flat", 0.0))

Heights are world z in m (up positive; below a sea surface at z = 0 they are negative).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .scene.model import IOPProfile, IOPs, PhaseFunction, ScatteringComponent

__all__ = ["align_components", "gaussian_chlorophyll", "profile_from_function"]


def align_components(layers: Sequence[IOPs]) -> list[IOPs]:
    """The same layers, each with the same scattering components, as a profile needs.

    The components are the union of the layers' phase functions in the order first seen; a
    layer without one gets ``b = 0`` for it, and components of one layer with equal phase
    functions are summed (the mixture's phase function is weighted by ``b``, so it does not
    change).
    """
    phases: list[PhaseFunction] = []
    for layer in layers:
        for c in layer.scattering:
            if not any(c.phase == p for p in phases):
                phases.append(c.phase)
    out = []
    for layer in layers:
        a = np.array(layer.absorption, dtype=np.float64)
        bs = [np.zeros_like(a) for _ in phases]
        for c in layer.scattering:
            j = next(i for i, p in enumerate(phases) if c.phase == p)
            bs[j] = bs[j] + np.asarray(c.b, dtype=np.float64)
        out.append(IOPs(a, [ScatteringComponent(b, p) for b, p in zip(bs, phases)]))
    return out


def gaussian_chlorophyll(background: float, peak: float, z_max: float,
                         width: float) -> Callable[[float], float]:
    """``C(z) = background + peak exp(-(z - z_max)^2 / (2 width^2))`` in mg m^-3.

    A subsurface chlorophyll maximum (Lewis et al. 1983 form, PHYSICS-NOTES section 6):
    ``z_max`` is the height of the maximum (m, world z) and ``width`` its standard deviation
    (m, > 0); ``peak`` is the value above the background at the maximum.
    """
    if not width > 0:
        raise ValueError(f"width must be > 0 m, got {width!r}")

    def chlorophyll(z: float) -> float:
        return float(background + peak * np.exp(-(z - z_max) ** 2 / (2.0 * width ** 2)))

    return chlorophyll


def _evaluate(value: Any, bands, base_dir) -> IOPs:
    if isinstance(value, IOPs):
        return value
    if isinstance(value, Mapping):
        from .iop_models import iops_from_model
        return iops_from_model(value, bands, base_dir=base_dir)
    raise TypeError(f"the profile function must return IOPs or a model description (dict), "
                    f"got {type(value).__name__}")


def profile_from_function(iops_at: Callable[[float], IOPs | Mapping], z_top: Sequence[float],
                          bands=None, *, nodes: int = 4, base_dir=None) -> IOPProfile:
    """Layers from a function of height: each layer's coefficients are their depth average.

    Parameters
    ----------
    iops_at : callable
        ``iops_at(z)`` gives the IOPs at height ``z`` (m): a ``photic.scene.IOPs``, or a model
        description for ``photic.iop_models.iops_from_model`` (then ``bands`` is required).
    z_top : sequence of float
        The layer tops (m, world z), strictly descending. Layer ``i`` spans
        ``z_top[i+1] < z <= z_top[i]``; the last layer extends downwards without limit and
        takes the function's value at its top.
    bands : sequence, optional
        The scene's bands (``photic.scene.Band`` or (centre, width) tuples), for models.
    nodes : int
        Gauss-Legendre nodes per layer for the depth average (exact for polynomials of degree
        ``2 nodes - 1`` in z).

    Returns
    -------
    IOPProfile
        With the layers' components aligned (``align_components``).
    """
    tops = np.asarray(z_top, dtype=np.float64)
    if tops.ndim != 1 or tops.size == 0 or not np.all(np.isfinite(tops)):
        raise ValueError("z_top must be a non-empty list of finite heights (m)")
    if np.any(np.diff(tops) >= 0):
        raise ValueError("z_top must be strictly descending (layer tops from the top down)")
    if isinstance(iops_at, (IOPs, Mapping)) or not callable(iops_at):
        raise TypeError("iops_at must be a function of the height z (m)")
    x, w = np.polynomial.legendre.leggauss(int(nodes))
    samples, weights = [], []
    for i, top in enumerate(tops):
        if i + 1 < tops.size:
            bottom = tops[i + 1]
            zs = 0.5 * (top + bottom) + 0.5 * (top - bottom) * x
            ws = 0.5 * w
        else:
            zs, ws = np.array([top]), np.array([1.0])
        samples.append([_evaluate(iops_at(float(z)), bands, base_dir) for z in zs])
        weights.append(ws)
    flat = align_components([iops for layer in samples for iops in layer])
    layers, k = [], 0
    for ws in weights:
        group, k = flat[k:k + len(ws)], k + len(ws)
        a = sum(wi * g.absorption for wi, g in zip(ws, group))
        comps = [ScatteringComponent(sum(wi * g.scattering[j].b for wi, g in zip(ws, group)),
                                     group[0].scattering[j].phase)
                 for j in range(len(group[0].scattering))]
        layers.append(IOPs(np.asarray(a, dtype=np.float64), comps))
    return IOPProfile(tops, layers)
