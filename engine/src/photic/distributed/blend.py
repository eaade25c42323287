""".blend inputs of a job: exported to Photic scenes here, on the machine that plans the job,
so that workers need neither Blender nor the add-on (they receive plain scenes)."""
from __future__ import annotations

from pathlib import Path


def export_blend(path: Path, frames: list[int] | None) -> list[tuple[int, object]]:
    """[(frame, Scene)] of a .blend file, exported by the add-on as its final render does."""
    try:
        import bpy  # noqa: F401  (Blender as a Python module)
    except ImportError as exc:
        raise RuntimeError(f".blend inputs need the bpy module ({exc}); install it with "
                           f"'pip install bpy==5.0.*' (Python 3.11)") from None
    from importlib import import_module

    from ..cli import load_addon
    load_addon()
    return import_module("photic_blender.batch").export_frames(path, frames)
