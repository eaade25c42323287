"""Denoising a rendered image with Intel Open Image Denoise (OIDN), guided by the camera's
albedo and normal (``Scene::camera_guides``), the way Cycles users know it.

OIDN is the denoiser Blender itself ships. A host that has the library (Blender's add-on finds
Blender's own: ``bpy/lib`` in the ``bpy`` module, ``lib/`` beside a 4.x ``blender``) names it
with ``use_library`` and it is called through its C API (``oidn_library``), in the process;
otherwise the Python binding ``pyoidn`` (a requirement of the package) carries one. OIDN filters three channels at a time, so an image of
``n`` bands is denoised as ceil(n / 3) RGB images of consecutive bands (the last padded with
its own last band), each with the same bands of the albedo.

A denoised image is an estimate with a bias: it has no standard error, and it smooths detail
that the noise hides at the sample count given, caustic networks first (see
docs/benchmarks.md, "Denoising"). Keep the noisy image for numbers.
"""
from __future__ import annotations

import numpy as np

GUIDE_RAYS_PER_AXIS = 2  # 4 fixed sub-pixel rays per pixel: anti-aliased, noise-free guides


class DenoiserMissing(RuntimeError):
    """OpenImageDenoise (``pyoidn``) is not installed."""


#: The path of an OpenImageDenoise shared library to call (``use_library``), or None: pyoidn.
LIBRARY: str | None = None


def use_library(path: str | None) -> str | None:
    """Denoise with the OpenImageDenoise shared library at ``path`` (None: with pyoidn). The
    library is loaded now; returns None when it can be used, else why not (then pyoidn
    stays the denoiser)."""
    global LIBRARY
    if path is None:
        LIBRARY = None
        return None
    from .oidn_library import OIDNError, library
    try:
        library(path)
    except OIDNError as exc:
        LIBRARY = None
        return str(exc)
    LIBRARY = str(path)
    return None


def denoiser() -> str:
    """What denoises: the library's path, or 'pyoidn'."""
    return LIBRARY if LIBRARY is not None else "pyoidn"


def _import_pyoidn():
    """pyoidn, with cffi's compiled backend from the same folder as pyoidn and cffi: a Python
    whose own folders come first (Debian's Blender 3.4 runs the system Python, whose
    dist-packages hold an older ``_cffi_backend``) would otherwise pair the two versions and
    fail."""
    import importlib.util
    import sys
    from pathlib import Path
    spec = importlib.util.find_spec("pyoidn")
    if spec is None or spec.origin is None:
        raise ImportError("No module named 'pyoidn'")
    folder = str(Path(spec.origin).resolve().parent.parent)
    if "_cffi_backend" not in sys.modules and importlib.util.find_spec("cffi") is not None:
        sys.path.insert(0, folder)
        try:
            import _cffi_backend  # noqa: F401
        except ImportError:
            pass
        finally:
            sys.path.remove(folder)
    import pyoidn
    return pyoidn


def unavailable_reason() -> str | None:
    """Why OpenImageDenoise cannot be used here, or None when it can. Any failure of the
    import counts (a Blender whose Python has another cffi backend first on its path fails
    with a version mismatch, not an ImportError)."""
    if LIBRARY is not None:
        return None
    try:
        if _separate_process() is not None:  # denoised in a process of its own: not imported here
            import importlib.util
            if importlib.util.find_spec("pyoidn") is None:
                raise ImportError("No module named 'pyoidn'")
            return None
        _import_pyoidn()
    except Exception as exc:  # noqa: BLE001
        return (f"denoising needs OpenImageDenoise's Python binding, which could not be imported "
                f"({type(exc).__name__}: {str(exc)[:300]}); pip install pyoidn (scripts/install.sh "
                f"installs it)")
    return None


def available() -> bool:
    return unavailable_reason() is None


def _separate_process() -> str | None:
    """Why OIDN must run in a process of its own here, or None. Inside a Blender application
    (not the ``bpy`` module) the process has Blender's allocator (jemalloc in Debian's 3.4) and
    libraries, and pyoidn's OIDN 2.5 aborted it there ("munmap_chunk(): invalid pointer");
    in Python (``bpy``, the ``photic`` command, scripts) it runs in the process."""
    import os
    import sys
    try:
        exe = os.path.basename(os.readlink("/proc/self/exe"))
    except OSError:
        exe = os.path.basename(sys.executable or "")
    return f"inside the Blender application ({exe})" if exe.lower().startswith("blender") else None


def _denoise_in_child(c, a, n) -> np.ndarray:
    """OIDN in a Python process of its own, the arrays through a temporary .npz: for a
    process OIDN cannot run in (_separate_process)."""
    import importlib.util
    import os
    import shutil
    import subprocess
    import sys
    import tempfile
    from pathlib import Path
    folder = Path(importlib.util.find_spec("pyoidn").origin).resolve().parent.parent
    venv_python = folder.parents[2] / "bin" / "python"
    python = str(venv_python) if venv_python.exists() else shutil.which("python3") or sys.executable
    code = ("import sys, numpy as np\n"
            "sys.path.insert(0, sys.argv[2])\n"
            "import pyoidn\n"
            "d = np.load(sys.argv[1])\n"
            "a = d['a'] if 'a' in d.files else None\n"
            "n = d['n'] if 'n' in d.files else None\n"
            "out = pyoidn.denoise(d['c'], a, n, hdr=True, clean_aux=a is not None, quality='high')\n"
            "np.save(sys.argv[1] + '.out.npy', np.asarray(out, np.float32))\n")
    with tempfile.TemporaryDirectory(prefix="photic_oidn_") as tmp:
        path = os.path.join(tmp, "in.npz")
        arrays = {"c": c} | ({} if a is None else {"a": a}) | ({} if n is None else {"n": n})
        np.savez(path, **arrays)
        env = dict(os.environ, PYTHONNOUSERSITE="1")
        res = subprocess.run([python, "-c", code, path, str(folder)], capture_output=True, text=True,
                             env=env, timeout=600)
        if res.returncode != 0:
            raise RuntimeError(f"the denoiser's process failed ({python}): {res.stderr.strip()[-500:]}")
        return np.load(path + ".out.npy")


def denoise_rgb(color: np.ndarray, albedo: np.ndarray | None = None,
                normal: np.ndarray | None = None) -> np.ndarray:
    """An (H, W, 3) HDR image denoised, with optional (H, W, 3) albedo in [0, 1] and normal
    guides (noise-free: no prefiltering). Non-finite values in the colour are taken as 0.
    With a library named by ``use_library`` it runs in this process; with pyoidn, inside a
    Blender application, in a process of its own (_separate_process)."""
    reason = unavailable_reason()
    if reason is not None:
        raise DenoiserMissing(reason)
    c = np.ascontiguousarray(np.nan_to_num(np.asarray(color, np.float32), nan=0.0, posinf=0.0, neginf=0.0))
    c = np.maximum(c, 0.0)
    a = None if albedo is None else np.ascontiguousarray(np.clip(albedo, 0.0, 1.0), np.float32)
    n = None if normal is None else np.ascontiguousarray(np.clip(normal, -1.0, 1.0), np.float32)
    if a is None and n is not None:
        n = None  # OIDN takes a normal only together with an albedo
    if LIBRARY is not None:
        from .oidn_library import library
        return library(LIBRARY).denoise(c, a, n)
    if _separate_process() is not None:
        return _denoise_in_child(c, a, n)
    out = _import_pyoidn().denoise(c, a, n, hdr=True, clean_aux=a is not None, quality="high")
    return np.asarray(out, np.float32)


def _triples(nbands: int) -> list[list[int]]:
    return [[min(i + k, nbands - 1) for k in range(3)] for i in range(0, nbands, 3)]


def denoise_bands(mean: np.ndarray, albedo: np.ndarray | None = None,
                  normal: np.ndarray | None = None) -> np.ndarray:
    """An (H, W, bands) image denoised three bands at a time (float64 out, as the engine's
    images), each triple with the same bands of an (H, W, bands) albedo and the (H, W, 3)
    normal."""
    mean = np.asarray(mean)
    out = np.empty(mean.shape, np.float64)
    for idx in _triples(mean.shape[2]):
        d = denoise_rgb(mean[:, :, idx], None if albedo is None else albedo[:, :, idx], normal)
        for k, b in enumerate(idx):
            out[:, :, b] = d[:, :, k]
    return out


def guides(core, camera_index: int, threads: int = 0, rows: tuple[int, int] | None = None
           ) -> tuple[np.ndarray, np.ndarray]:
    """(albedo (H, W, bands), normal (H, W, 3)) of a compiled scene's camera; ``rows``
    (first, end): of those rows only."""
    a, n = core.camera_guides(camera_index, GUIDE_RAYS_PER_AXIS, threads, rows)
    return np.asarray(a), np.asarray(n)
