"""OpenImageDenoise through its C API from a shared library given by path (``ctypes``): the
library a host application already ships, such as Blender's own (``bpy/lib`` in the ``bpy``
module, ``lib/`` beside the ``blender`` binary of 4.x), so that no extra package is needed.

Only what the RT filter needs is bound: a CPU device, shared (host) images of three floats
per pixel, the ``hdr`` and ``cleanAux`` flags. The calls are the same in OIDN 1.4+ and 2.x
(2.x renamed ``oidnSetFilter1b`` to ``oidnSetFilterBool``; either is taken).
"""
from __future__ import annotations

import ctypes
import threading

import numpy as np

OIDN_DEVICE_TYPE_CPU = 1
OIDN_FORMAT_FLOAT3 = 3


class OIDNError(RuntimeError):
    """The library could not be loaded, or OIDN reported an error."""


class Library:
    """One OIDN shared library and a CPU device of it (created at the first use, kept)."""

    def __init__(self, path: str):
        self.path = str(path)
        try:
            lib = ctypes.CDLL(self.path)
        except OSError as exc:
            raise OIDNError(f"OpenImageDenoise library {self.path} could not be loaded: {exc}") from exc
        vp, cp, sz = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t
        try:
            lib.oidnNewDevice.restype, lib.oidnNewDevice.argtypes = vp, [ctypes.c_int]
            lib.oidnCommitDevice.argtypes = [vp]
            lib.oidnGetDeviceError.restype = ctypes.c_int
            lib.oidnGetDeviceError.argtypes = [vp, ctypes.POINTER(cp)]
            lib.oidnNewFilter.restype, lib.oidnNewFilter.argtypes = vp, [vp, cp]
            lib.oidnSetSharedFilterImage.argtypes = [vp, cp, vp, ctypes.c_int, sz, sz, sz, sz, sz]
            lib.oidnCommitFilter.argtypes = [vp]
            lib.oidnExecuteFilter.argtypes = [vp]
            lib.oidnReleaseFilter.argtypes = [vp]
            self._set_bool = getattr(lib, "oidnSetFilterBool", None) or lib.oidnSetFilter1b
            self._set_bool.argtypes = [vp, cp, ctypes.c_bool]
        except AttributeError as exc:
            raise OIDNError(f"{self.path} is not an OpenImageDenoise 1.4+ library: {exc}") from exc
        self.lib = lib
        self._device = None
        self._lock = threading.Lock()

    def _check(self) -> None:
        msg = ctypes.c_char_p()
        code = self.lib.oidnGetDeviceError(self._device, ctypes.byref(msg))
        if code != 0:
            text = msg.value.decode("utf-8", "replace") if msg.value else ""
            raise OIDNError(f"OpenImageDenoise error {code}: {text} ({self.path})")

    def device(self):
        if self._device is None:
            dev = self.lib.oidnNewDevice(OIDN_DEVICE_TYPE_CPU)
            if not dev:
                raise OIDNError(f"OpenImageDenoise made no CPU device ({self.path})")
            self._device = dev
            self.lib.oidnCommitDevice(dev)
            self._check()
        return self._device

    def denoise(self, color: np.ndarray, albedo: np.ndarray | None = None,
                normal: np.ndarray | None = None, hdr: bool = True) -> np.ndarray:
        """An (H, W, 3) float32 image denoised by the RT filter, with optional (H, W, 3)
        albedo and normal (a normal only with an albedo; both taken as noise-free)."""
        c = np.ascontiguousarray(color, np.float32)
        h, w = c.shape[:2]
        if c.shape != (h, w, 3):
            raise ValueError(f"colour must be (H, W, 3), not {c.shape}")
        imgs = {"color": c}
        if albedo is not None:
            imgs["albedo"] = np.ascontiguousarray(albedo, np.float32)
            if normal is not None:
                imgs["normal"] = np.ascontiguousarray(normal, np.float32)
        for k, v in imgs.items():
            if v.shape != (h, w, 3):
                raise ValueError(f"{k} must be {(h, w, 3)}, not {v.shape}")
        out = np.empty_like(c)
        imgs["output"] = out
        with self._lock:
            lib = self.lib
            flt = lib.oidnNewFilter(self.device(), b"RT")
            if not flt:
                self._check()
                raise OIDNError(f"OpenImageDenoise has no RT filter ({self.path})")
            try:
                for name, arr in imgs.items():
                    lib.oidnSetSharedFilterImage(flt, name.encode(), arr.ctypes.data, OIDN_FORMAT_FLOAT3,
                                                 w, h, 0, 0, 0)
                self._set_bool(flt, b"hdr", bool(hdr))
                if "albedo" in imgs:
                    self._set_bool(flt, b"cleanAux", True)
                lib.oidnCommitFilter(flt)
                self._check()
                lib.oidnExecuteFilter(flt)
                self._check()
            finally:
                lib.oidnReleaseFilter(flt)
        return out


_LIBRARIES: dict[str, Library] = {}


def library(path: str) -> Library:
    """The Library of a path (loaded once per process)."""
    lib = _LIBRARIES.get(str(path))
    if lib is None:
        lib = _LIBRARIES[str(path)] = Library(path)
    return lib
