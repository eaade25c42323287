"""What the last export of each scene could not render, per data-block, for the panels.

An export (a final render, the viewport, File > Export) collects its warnings in
``ExportInfo.notes``; ``remember`` keeps them per scene, and the Photic panels of an object, a
material, a light or the world show those that name it (``for_id``), so the artist finds the
note where the setting is. The render log has the same texts, once each.
"""
from __future__ import annotations

_LAST: dict = {}  # scene name -> {(kind, name): [text]}


def remember(scene_name: str, info) -> None:
    """The notes of an export of ``scene_name`` replace those of the one before."""
    _LAST[scene_name] = {k: list(v) for k, v in getattr(info, "notes", {}).items()}


def for_id(scene_name: str, kind: str, name: str) -> list[str]:
    """The notes of the last export of the scene about one data-block."""
    return list(_LAST.get(scene_name, {}).get((kind, name), ()))


def clear() -> None:
    _LAST.clear()
