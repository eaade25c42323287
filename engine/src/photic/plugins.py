"""Plugins: new IOP models and new sea-surface (wave) models, found through Python entry points.

A plugin turns its model into data the compiled core reads (per-band constants, or a surface
patch with its normals), so no Python runs per ray. Two entry-point groups:

``photic.iop_models``
    ``name = module:function`` with ``function(params: dict, bands: list[tuple[str, float,
    float]]) -> photic.scene.IOPs`` (absorption per band and scattering components, each with
    a phase function the scene format knows). Used in scene files as
    ``"iop_model": {"model": "<name>", ...params}`` (also inside a ``"mixture"``).

``photic.wave_models``
    ``name = module:function`` with ``function(params: dict) -> (vertices (N, 3), triangles
    (M, 3), normals (N, 3) or None, (Lx, Ly))``: a height-field patch over one period, facing
    up, that tiles (border vertices equal to the opposite ones). Used in scene files as
    ``"surface": {"kind": "plugin", "plugin": "<name>", "params": {...}}``.

Raise ``ValueError`` for bad parameters: the message reaches the user with the object and the
field named. A plugin's name must not be a built-in model's. ``docs/plugin_example/`` holds a
complete example package. ``photic plugins`` lists what is installed.
"""
from __future__ import annotations

from functools import lru_cache
from importlib.metadata import entry_points

GROUPS = {"iop": "photic.iop_models", "wave": "photic.wave_models"}


@lru_cache(maxsize=None)
def available(kind: str) -> dict:
    """{name: entry point} of the installed plugins of a kind ('iop' or 'wave')."""
    return {ep.name: ep for ep in entry_points(group=GROUPS[kind])}


def load(kind: str, name: str):
    """The plugin's function, or None when no plugin of that name is installed."""
    ep = available(kind).get(name)
    return None if ep is None else ep.load()


def refresh() -> None:
    """Forget what was found (after installing a plugin in a running process)."""
    available.cache_clear()
