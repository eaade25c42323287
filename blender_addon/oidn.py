"""Blender's own OpenImageDenoise: found here (the engine never imports bpy) and handed to
``photic.denoise.use_library``, so that Denoise works without the ``pyoidn`` package (171 MB),
in the extension too. Blender links the library: the ``bpy`` module keeps it in ``bpy/lib``,
Blender 4.x beside its binary in ``lib/`` (macOS: ``Contents/Resources/lib``, Windows: beside
``blender.exe``). Blenders built without it (Debian's 3.4) leave pyoidn as the denoiser."""
from __future__ import annotations

import sys
from pathlib import Path

_NAMES = ("libOpenImageDenoise.so*", "libOpenImageDenoise*.dylib", "OpenImageDenoise.dll")


def _is_main_library(path: Path) -> bool:
    n = path.name
    return n.startswith(("libOpenImageDenoise.", "OpenImageDenoise.")) or (
        n.startswith("libOpenImageDenoise") and n.endswith(".dylib")
        and "_core" not in n and "_device" not in n)


def loaded_library() -> str | None:
    """The OpenImageDenoise library already mapped into this process (Linux), or None."""
    try:
        with open("/proc/self/maps") as f:
            for line in f:
                parts = line.rstrip("\n").split(None, 5)
                path = parts[5] if len(parts) == 6 else ""
                if "OpenImageDenoise" in path and _is_main_library(Path(path)):
                    return path
    except OSError:
        pass
    return None


def candidate_folders() -> list[Path]:
    import bpy
    out = []
    mod = getattr(bpy, "__file__", None)
    if mod:
        out.append(Path(mod).resolve().parent / "lib")
    binary = getattr(bpy.app, "binary_path", "") or ""
    if binary:
        b = Path(binary).resolve().parent
        out += [b / "lib", b, b.parent / "Resources" / "lib"]
    return out


def blender_library() -> str | None:
    """The path of Blender's OpenImageDenoise library, or None when this Blender has none."""
    path = loaded_library()
    if path is not None:
        return path
    for folder in candidate_folders():
        if not folder.is_dir():
            continue
        for pattern in _NAMES:
            for p in sorted(folder.glob(pattern)):
                if _is_main_library(p) and p.is_file():
                    return str(p)
    return None


def use_blender_library(photic) -> str | None:
    """Make the engine denoise with Blender's library when there is one (once it loads);
    returns its path, or None (the engine keeps pyoidn)."""
    path = blender_library()
    if path is None:
        return None
    why = photic.denoise.use_library(path)
    if why is not None:
        print(f"Photic: Blender's OpenImageDenoise not used: {why}", file=sys.stderr)
        return None
    return path
