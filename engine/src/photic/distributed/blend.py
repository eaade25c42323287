""".blend inputs of a job: exported to Photic scenes by the add-on package (photic_blender,
which imports Blender as the bpy module), on the machine that plans the job, so that workers
need neither Blender nor the add-on (they receive plain scenes). The engine only hands the
file over, when the package is installed."""
from __future__ import annotations

import importlib.util
from pathlib import Path


def export_blend(path: Path, frames: list[int] | None) -> list[tuple[int, object]]:
    """[(frame, Scene)] of a .blend file, exported by the add-on as its final render does."""
    if importlib.util.find_spec("bpy") is None:
        raise RuntimeError(".blend inputs need the bpy module; install it with "
                           "'pip install bpy==5.0.*' (Python 3.11)")
    if importlib.util.find_spec("photic_blender") is None:
        raise RuntimeError(".blend inputs need the Blender add-on package: pip install -e "
                           "./blender_addon (scripts/install.sh does it)")
    from photic_blender.batch import export_frames
    return export_frames(path, frames)
