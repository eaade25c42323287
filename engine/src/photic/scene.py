"""Photic scene description: data classes, JSON loader and validator (format version 1).

The format is specified in ``docs/scene-format.md``; its JSON Schema is
``photic/schema/scene.schema.json``. A scene is checked in two stages:

1. ``Scene.from_dict`` checks the JSON structure against the schema (types, ranges, unknown
   keys) and builds the objects, broadcasting single numbers to all bands;
2. ``Scene.validate`` runs every semantic check on the objects (per-band lengths, closed
   meshes, references, unique names, ...), so a scene built in Python is checked the same way.

Every problem is reported as a ``SceneError`` naming the object and the field.

Conventions: lengths in m, angles in degrees, coefficients in m^-1; right-handed coordinates
with z up.
"""

from __future__ import annotations

import difflib
import gc
import json
import math
import numbers
from dataclasses import dataclass, field, fields, is_dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "FORMAT_VERSION", "PHASE_FUNCTION_PARAMS", "QUANTITIES", "SceneError", "Band", "Material",
    "PhaseFunction", "ScatteringComponent", "IOPs", "IOPProfile", "IOPGrid", "GridField", "TriangleMesh", "MeshObject",
    "OceanSurface", "SurfaceRoughness", "WaterBody", "Sun", "Sky", "Camera", "Radiometer", "RadiometerArray",
    "Settings", "Scene", "check_closed_mesh", "load_scene", "save_scene", "scene_schema",
]

FORMAT_VERSION = 1

#: Phase function types and the names of their parameters.
PHASE_FUNCTION_PARAMS: dict[str, tuple[str, ...]] = {
    "petzold": (),
    "fournier_forand": ("backscatter_fraction",),
    "henyey_greenstein": ("g",),
    "pure_water": (),
    "isotropic": (),
}

#: Quantities a radiometer can measure.
QUANTITIES = ("Ed", "Eu", "Eo", "Eod", "Eou", "radiance", "radiance_distribution")

WATER_TYPES = ("mesh", "ocean")
MAX_COMPONENTS = 16  # scattering components per water body (the compiled core's limit)
SURFACE_KINDS = ("flat", "patch", "waves")  # scene files also take "plugin" (read as a patch)
SKY_TYPES = ("black", "uniform", "cardioidal", "harrison_coombes")
CAMERA_TYPES = ("perspective", "orthographic")
FILTER_TYPES = ("box", "gaussian")
INTEGRATORS = ("auto", "path", "hybrid")

# Default filter width per filter type (pixels).
_FILTER_DEFAULT_WIDTH = {"box": 1.0, "gaussian": 1.5}

# A triangle is degenerate when its area is below this times the squared bounding-box diagonal.
_DEGENERATE_AREA_FRACTION = 1e-12


class SceneError(ValueError):
    """An invalid scene: names the object (e.g. ``water 'sea'``) and the field.

    Parameters
    ----------
    obj : str
        The object, e.g. ``"water 'sea'"``, ``"settings"`` or ``"scene"``.
    field : str
        The field path inside the object, e.g. ``"iops.absorption[0]"``.
    message : str
        What is wrong.
    """

    def __init__(self, obj: str, field: str, message: str):
        # args are the constructor arguments so that the error survives pickling.
        super().__init__(obj, field, message)
        self.obj = obj
        self.field = field
        self.message = message

    def __str__(self) -> str:
        return f"{self.obj}: field '{self.field}': {self.message}"


# ----------------------------------------------------------------------------------------
# Small helpers shared by the data classes, the builder and the checks
# ----------------------------------------------------------------------------------------

def _values_equal(a: Any, b: Any) -> bool:
    """Compare nested scene values; numpy arrays compare by shape and value."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        try:
            a, b = np.asarray(a), np.asarray(b)
        except (TypeError, ValueError):
            return False
        return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"
                                                         and b.dtype.kind == "f"))
    if is_dataclass(a) or is_dataclass(b):
        return type(a) is type(b) and all(
            _values_equal(getattr(a, f.name), getattr(b, f.name)) for f in fields(a))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_values_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_values_equal(a[k], b[k]) for k in a)
    return bool(a == b)


class _ArrayEq:
    """Mixin: ``==`` that works for data classes holding numpy arrays."""

    def __eq__(self, other: object) -> bool:
        return _values_equal(self, other)

    __hash__ = None  # mutable, like the default data class


def _as_floats(x: Any) -> Any:
    """A float64 copy of ``x``, or ``x`` unchanged when it is not numeric (validate reports it)."""
    if x is None:
        return None
    try:
        return np.array(x, dtype=np.float64)
    except (TypeError, ValueError):
        return x


def _unit(v: Any) -> Any:
    """``v / |v|``; ``v`` itself if already unit length (keeps round trips bit-exact) or zero."""
    if not isinstance(v, np.ndarray) or v.shape != (3,):
        return v
    n = float(np.linalg.norm(v))
    if n == 0.0 or not math.isfinite(n) or abs(n - 1.0) <= 4 * np.finfo(np.float64).eps:
        return v
    return v / n


def _show(x: Any) -> str:
    """Short text for a value in an error message."""
    if isinstance(x, bool) or x is None:
        return repr(x)
    if isinstance(x, numbers.Integral):
        return str(int(x))
    if isinstance(x, numbers.Real):
        return repr(float(x))
    if isinstance(x, np.ndarray):
        x = x.tolist()
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


def _num(x: float) -> str:
    """A bound in an error message: integers without a decimal point."""
    if isinstance(x, numbers.Integral) or (float(x).is_integer() and abs(x) < 1e16):
        return str(int(x))
    return repr(float(x))


def _entries(n: int) -> str:
    return f"{n} entry" if n == 1 else f"{n} entries"


def _range_text(lo=None, hi=None, lo_open=False, hi_open=False, integer=False) -> str:
    """Describe an allowed range, e.g. ``a finite number in (-1, 1)``."""
    kind = "an integer" if integer else "a finite number"
    if lo is not None and hi is not None:
        return f"{kind} in {'(' if lo_open else '['}{_num(lo)}, {_num(hi)}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{kind} {'>' if lo_open else '>='} {_num(lo)}"
    if hi is not None:
        return f"{kind} {'<' if hi_open else '<='} {_num(hi)}"
    return kind


def _is_real(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def _check_real(obj, fld, x, lo=None, hi=None, *, lo_open=False, hi_open=False) -> None:
    """Require a finite real number in the given range."""
    ok = _is_real(x) and math.isfinite(x)
    if ok and lo is not None:
        ok = x > lo if lo_open else x >= lo
    if ok and hi is not None:
        ok = x < hi if hi_open else x <= hi
    if not ok:
        raise SceneError(obj, fld, f"must be {_range_text(lo, hi, lo_open, hi_open)}, "
                                   f"got {_show(x)}")


def _check_int(obj, fld, x, lo, hi) -> None:
    """Require an integer (an integral float is accepted) in ``[lo, hi]``."""
    ok = (isinstance(x, numbers.Integral) and not isinstance(x, bool)) or (
        _is_real(x) and math.isfinite(x) and float(x).is_integer())
    if not (ok and lo <= x <= hi):
        raise SceneError(obj, fld, f"must be {_range_text(lo, hi, integer=True)}, got {_show(x)}")


def _check_choice(obj, fld, x, choices) -> None:
    if not isinstance(x, str) or x not in choices:
        raise SceneError(obj, fld, f"must be one of {', '.join(map(repr, choices))}, "
                                   f"got {_show(x)}")


def _check_per_band(obj, fld, a, nbands, lo=0.0, hi=None) -> None:
    """Require a float array with one finite value in ``[lo, hi]`` per band."""
    if not isinstance(a, np.ndarray) or a.ndim != 1 or a.dtype.kind not in "fiu":
        raise SceneError(obj, fld, f"must be a list of {nbands} number(s), one per band, "
                                   f"got {_show(a)}")
    if a.shape[0] != nbands:
        raise SceneError(obj, fld, f"has {_entries(a.shape[0])} but the scene has "
                                   f"{nbands} band(s)")
    for i, x in enumerate(a.tolist()):
        _check_real(obj, f"{fld}[{i}]", x, lo, hi)


# Embree traces in single precision: beyond about a thousand kilometres from the origin a
# float32 coordinate is coarser than 6 cm and rays there fail its checks (it aborted the
# process). Positions and sizes are limited to this, in metres.
MAX_COORDINATE_M = 1e6
_COORD_TEXT = (f"within +-{MAX_COORDINATE_M:.0e} m of the origin (Embree traces in single "
               f"precision; move the scene nearer the origin)")


def _check_vec3(obj, fld, v, nonzero=False, position=False) -> None:
    """Require a finite 3-vector (not zero if ``nonzero``; within MAX_COORDINATE_M of the
    origin if it is a ``position``)."""
    if (not isinstance(v, np.ndarray) or v.shape != (3,) or v.dtype.kind not in "fiu"
            or not np.all(np.isfinite(v))):
        raise SceneError(obj, fld, f"must be 3 finite numbers [x, y, z], got {_show(v)}")
    if nonzero and not np.any(v):
        raise SceneError(obj, fld, "must not be the zero vector")
    if position and np.max(np.abs(v)) > MAX_COORDINATE_M:
        raise SceneError(obj, fld, f"must be {_COORD_TEXT}, got {_show(v)}")


MAX_DISTRIBUTION_BINS = 1_000_000  # polar x azimuth bins of a radiance distribution
MAX_ARRAY_RADIOMETERS = 1_000_000  # radiometers of one array
MAX_SOURCE = 1e20  # sun irradiance and sky radiance (per band): far beyond any sun, and the
                   # image (float32) stays finite
MAX_HG_G = 0.9999  # |g| of Henyey-Greenstein: nearer 1 its sampling loses all precision


def _check_name(kind: str, index: int, name: Any, seen: dict[str, str]) -> str:
    """Require a non-empty, unique name; return the object's label for error messages."""
    label = _label(kind, name, index)
    if not isinstance(name, str) or not name:
        raise SceneError(label, "name", f"must be a non-empty string, got {_show(name)}")
    if name in seen:
        raise SceneError(label, "name", f"duplicate name: also used by {seen[name]}")
    seen[name] = f"{kind}[{index}]"
    return label


def _label(kind: str, name: Any, index: int) -> str:
    """``water 'sea'``, or ``water[2]`` when the object has no usable name."""
    return f"{kind} '{name}'" if isinstance(name, str) and name else f"{kind}[{index}]"


# ----------------------------------------------------------------------------------------
# Data classes
# ----------------------------------------------------------------------------------------

@dataclass(eq=False)
class Band(_ArrayEq):
    """A spectral band: name, centre and width in nm."""

    name: str
    center_nm: float
    width_nm: float


@dataclass(eq=False)
class Material(_ArrayEq):
    """A Lambertian material: reflectance per band in [0, 1]."""

    name: str
    reflectance: np.ndarray

    def __post_init__(self):
        self.reflectance = _as_floats(self.reflectance)


@dataclass(eq=False)
class PhaseFunction(_ArrayEq):
    """A phase function: ``type`` (see ``PHASE_FUNCTION_PARAMS``) and its parameters.

    Examples
    --------
    >>> PhaseFunction("henyey_greenstein", {"g": 0.9})
    >>> PhaseFunction("fournier_forand", {"backscatter_fraction": 0.0183})
    """

    type: str
    params: dict = field(default_factory=dict)


@dataclass(eq=False)
class ScatteringComponent(_ArrayEq):
    """One scattering component: coefficient ``b`` per band (m^-1) and its phase function."""

    b: np.ndarray
    phase: PhaseFunction

    def __post_init__(self):
        self.b = _as_floats(self.b)


@dataclass(eq=False)
class IOPs(_ArrayEq):
    """Inherent optical properties: absorption per band (m^-1) and scattering components."""

    absorption: np.ndarray
    scattering: list[ScatteringComponent] = field(default_factory=list)

    def __post_init__(self):
        self.absorption = _as_floats(self.absorption)

    @property
    def total_scattering(self) -> np.ndarray:
        """Total scattering coefficient per band (m^-1): the sum of the components' ``b``."""
        total = np.zeros_like(np.asarray(self.absorption, dtype=np.float64))
        for component in self.scattering:
            total = total + component.b
        return total


@dataclass(eq=False)
class IOPProfile(_ArrayEq):
    """Stratified water: IOPs in horizontal layers, each homogeneous (piecewise constant in z).

    ``z_top`` (m, world z, strictly descending) is the top of each layer: layer ``i`` holds
    ``z_top[i+1] < z <= z_top[i]``; the first layer's IOPs also apply above ``z_top[0]`` and
    the last layer extends downwards without limit. Every layer has the same scattering
    components (the same phase functions in the same order); only the absorption and each
    component's ``b`` differ between layers. A water body takes an ``IOPProfile`` in place of
    its ``IOPs``.

    Examples
    --------
    >>> water = PhaseFunction("pure_water")
    >>> IOPProfile([0.0, -5.0], [IOPs([0.1], [ScatteringComponent([0.2], water)]),
    ...                          IOPs([0.4], [ScatteringComponent([1.0], water)])])
    """

    z_top: np.ndarray
    layers: list[IOPs] = field(default_factory=list)

    def __post_init__(self):
        self.z_top = _as_floats(self.z_top)

    def layer_index(self, z: float) -> int:
        """Index of the layer holding height ``z`` (m)."""
        tops = np.asarray(self.z_top, dtype=np.float64)
        return int(np.count_nonzero(tops[1:] >= z))

    def at(self, z: float) -> IOPs:
        """The IOPs at height ``z`` (m)."""
        return self.layers[self.layer_index(z)]


@dataclass(eq=False)
class GridField(_ArrayEq):
    """A further density field of an ``IOPGrid`` on the grid's own voxels, for a constituent
    that does not follow the first one (CDOM beside sediment, a phytoplankton bloom): where
    its ``density`` (the same shape as the grid's) is ``rho_f``, ``rho_f * unit`` is added to
    the IOPs. ``unit`` has the grid's components, ``a`` and ``b >= 0``. ``key``: the name of the
    array in the grid's ``.npz`` file it was read from (a saved scene refers to it).

    Examples
    --------
    >>> water = PhaseFunction("pure_water")
    >>> GridField("cdom", IOPs([0.3], [ScatteringComponent([0.0], water)]), np.zeros((4, 4, 4)))  # doctest: +ELLIPSIS
    GridField(name='cdom', ...)
    """

    name: str
    unit: IOPs
    density: np.ndarray
    key: str | None = None

    def __post_init__(self):
        if not isinstance(self.density, np.ndarray):
            try:
                self.density = np.array(self.density, dtype=np.float32)
            except (TypeError, ValueError):
                pass


MAX_GRID_FIELDS = 4  # density fields per grid: the first and up to three more


@dataclass(eq=False)
class IOPGrid(_ArrayEq):
    """3-D IOPs: a regular grid of piecewise-constant voxels over the box ``origin`` to
    ``origin + size`` (m, world axes). Each voxel holds one density ``rho >= 0`` (float32;
    ``density[i, j, k]``, ``i`` along x, ``j`` along y, ``k`` along z), and the IOPs there are
    ``iops + rho * unit``: ``a = a_base + rho a_unit`` and, per scattering component,
    ``b_c = b_base,c + rho b_unit,c``. Outside the box ``rho = 0`` (the base ``iops``). The base
    is homogeneous ``IOPs`` or an ``IOPProfile`` (a depth profile: the base at each height is
    its layer there). ``unit`` has the same components (phase functions, in the same order) as
    the base, with ``a`` and
    ``b >= 0`` (b = 0 where a component is absent from the plume). Memory: 4 bytes per voxel
    (256^3: 64 MiB). ``file``: the ``.npz`` the density was read from (key ``density``), kept so
    that a saved scene refers to it instead of writing the voxels inline.

    ``extra_fields``: up to three further density fields (``GridField``) on the same voxels,
    each with unit IOPs of its own; the IOPs are then ``iops + rho * unit + sum_f rho_f
    unit_f``. One walk through the voxels integrates all fields, so each costs far less than a
    grid of its own (4 more bytes per voxel).

    Examples
    --------
    >>> water = PhaseFunction("pure_water")
    >>> base = IOPs([0.05], [ScatteringComponent([0.002], water)])
    >>> unit = IOPs([0.1], [ScatteringComponent([0.5], water)])
    >>> IOPGrid(base, unit, [0, 0, -10], [10, 10, 10], np.zeros((4, 4, 4)))  # doctest: +ELLIPSIS
    IOPGrid(...)
    """

    iops: IOPs | IOPProfile
    unit: IOPs
    origin: np.ndarray
    size: np.ndarray
    density: np.ndarray
    file: str | None = None
    extra_fields: list[GridField] = field(default_factory=list)

    def __post_init__(self):
        self.origin = _as_floats(self.origin)
        self.size = _as_floats(self.size)
        if not isinstance(self.density, np.ndarray):
            try:
                self.density = np.array(self.density, dtype=np.float32)
            except (TypeError, ValueError):
                pass

    def density_at(self, p, field: int = 0) -> float:
        """The density of field ``field`` (0: ``density``, f: ``extra_fields[f - 1]``) at point
        ``p`` (m; 0 outside the box)."""
        q = (np.asarray(p, dtype=np.float64) - self.origin) / self.size
        if np.any(q < 0) or np.any(q > 1):
            return 0.0
        rho = self.density if field == 0 else self.extra_fields[field - 1].density
        n = np.asarray(rho.shape)
        idx = np.minimum((q * n).astype(int), n - 1)
        return float(rho[tuple(idx)])

    def units(self) -> list[IOPs]:
        """Every field's unit IOPs, the first field's first."""
        return [self.unit] + [f.unit for f in self.extra_fields]

    def densities(self) -> list[np.ndarray]:
        """Every field's densities, the first field's first."""
        return [self.density] + [f.density for f in self.extra_fields]


@dataclass(eq=False)
class TriangleMesh(_ArrayEq):
    """A triangle mesh: ``vertices`` float64 (N, 3) in m, ``triangles`` int64 (M, 3).

    Triangles are counter-clockwise seen from outside: the normal
    ``(v1 - v0) x (v2 - v0)`` points outwards.
    """

    vertices: np.ndarray
    triangles: np.ndarray

    def __post_init__(self):
        self.vertices = _as_floats(self.vertices)
        if isinstance(self.vertices, np.ndarray) and self.vertices.size == 0:
            self.vertices = self.vertices.reshape(0, 3)
        try:
            t = np.array(self.triangles)
        except (TypeError, ValueError):
            return
        if t.size == 0:
            t = t.reshape(0, 3).astype(np.int64)
        # Integral floats (e.g. from a numeric library) are accepted as indices.
        if t.dtype.kind == "f" and np.all(np.isfinite(t)) and np.all(t == np.round(t)):
            t = t.astype(np.int64)
        if t.dtype.kind in "iu":
            t = t.astype(np.int64, copy=False)  # np.array above already copied
        self.triangles = t


@dataclass(eq=False)
class MeshObject(_ArrayEq):
    """An opaque object: a mesh and the name of its material."""

    name: str
    mesh: TriangleMesh
    material: str


@dataclass(eq=False)
class SurfaceRoughness(_ArrayEq):
    """Sub-pixel roughness of a sea surface: Cox-Munk facet slopes for the wind speed.

    ``wind_speed`` (m/s, the Cox-Munk wind at 12.5 m, within the 10 m wind for these purposes),
    ``anisotropic``: upwind/crosswind variances (Cox-Munk 1954) instead of the isotropic total;
    ``wind_direction_deg``: the direction the wind blows towards (degrees from +x towards +y);
    None: the wave model's, else 0. For a ``"waves"`` surface the slope variance its grid
    resolves is subtracted per axis (PHYSICS-NOTES 5.3), so roughness is not counted twice."""

    wind_speed: float
    anisotropic: bool = False
    wind_direction_deg: float | None = None


@dataclass(eq=False)
class OceanSurface(_ArrayEq):
    """The surface of an ocean.

    ``kind`` is ``"flat"`` (the plane ``z``), ``"patch"`` (the height-field ``mesh``
    repeated with ``period`` (Lx, Ly) in m; ``z`` is then the mean height of its vertices,
    computed here) or ``"waves"`` (a ``photic.waves.WaveModel`` in ``waves``, made into a
    patch over [0, Lx] x [0, Ly] at mean level ``z`` (m) by :meth:`patch`).
    """

    kind: str
    z: float = 0.0
    mesh: TriangleMesh | None = None
    period: tuple[float, float] | None = None
    waves: Any = None  # photic.waves.WaveModel for kind "waves"
    normals: np.ndarray | None = None  # kind "patch": vertex normals (a plugin's), else derived
    plugin: dict | None = None  # {"plugin": name, "params": {...}} of a patch a plugin made
    roughness: SurfaceRoughness | None = None  # sub-pixel Cox-Munk roughness (path tracing)

    def __post_init__(self):
        if self.period is not None and not isinstance(self.period, str):
            try:
                self.period = tuple(float(p) for p in self.period)
            except (TypeError, ValueError):
                pass
        # For a patch, z is derived so that the bottom depth has a well-defined reference.
        if self.kind == "patch" and isinstance(self.mesh, TriangleMesh):
            v = self.mesh.vertices
            if isinstance(v, np.ndarray) and v.ndim == 2 and v.shape[1] == 3 and len(v):
                self.z = float(np.mean(v[:, 2]))

    def slope_variances(self, ior: float) -> tuple[float, float, float]:
        """(upwind, crosswind) sub-pixel slope variances and the upwind azimuth (rad) of the
        roughness: Cox-Munk for the wind less what a wave model's grid resolves."""
        from .surface import slope_variances
        r = self.roughness
        direction = r.wind_direction_deg
        if direction is None:
            direction = self.waves.wind_direction_deg if self.kind == "waves" else 0.0
        resolved = (0.0, 0.0)
        if self.kind == "waves":
            from .waves import slope_variance_along
            resolved = (slope_variance_along(self.waves, direction),
                        slope_variance_along(self.waves, direction + 90.0))
        s2u, s2c = slope_variances(float(r.wind_speed), bool(r.anisotropic), resolved)
        return s2u, s2c, math.radians(direction)

    def patch(self) -> tuple[TriangleMesh, tuple[float, float], np.ndarray | None]:
        """(mesh, period, vertex normals or None) of a ``"patch"`` or ``"waves"`` surface.

        For ``"waves"`` the mesh is generated from the model (cached) and the normals are the
        model's exact ones; a ``"patch"`` has no normals (the core derives them from the mesh).
        """
        if self.kind != "waves":
            return self.mesh, self.period, self.normals
        from .waves import surface_patch

        vertices, triangles, normals = surface_patch(self.waves, float(self.z))
        return TriangleMesh(vertices, triangles), tuple(self.waves.patch_size_m), normals


@dataclass(eq=False)
class WaterBody(_ArrayEq):
    """A water body: type ``"mesh"`` (closed ``mesh``) or ``"ocean"`` (``surface``, optional
    flat bottom at ``surface.z - bottom_depth`` made of ``bottom_material``). ``iops`` is an
    ``IOPs`` (homogeneous water), an ``IOPProfile`` (stratified water) or an ``IOPGrid`` (3-D
    IOPs over a box)."""

    name: str
    type: str
    iops: IOPs | IOPProfile | IOPGrid
    ior: float = 1.34
    mesh: TriangleMesh | None = None
    surface: OceanSurface | None = None
    bottom_depth: float | None = None
    bottom_material: str | None = None


@dataclass(eq=False)
class Sun(_ArrayEq):
    """The sun: a disk of uniform radiance; ``irradiance`` per band normal to its direction."""

    zenith_deg: float
    azimuth_deg: float
    irradiance: np.ndarray
    angular_diameter_deg: float = 0.53

    def __post_init__(self):
        self.irradiance = _as_floats(self.irradiance)

    @property
    def direction(self) -> np.ndarray:
        """Unit vector pointing towards the sun (z up, azimuth from +x towards +y)."""
        theta, phi = math.radians(self.zenith_deg), math.radians(self.azimuth_deg)
        return np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi),
                         math.cos(theta)])


@dataclass(eq=False)
class Sky(_ArrayEq):
    """The sky over the upper hemisphere.

    ``radiance_scale`` is L0 per band: ``uniform`` has L = L0; ``cardioidal`` has
    L(theta) = L0 (1 + 2 cos theta), theta the zenith angle; ``black`` has None.
    """

    type: str
    radiance_scale: np.ndarray | None = None
    full_sphere: bool = False  # uniform only: radiance L0 below the horizon too (furnace tests)
    cloud_fraction: float = 0.0  # harrison_coombes only: 0 clear .. 1 overcast

    def __post_init__(self):
        self.radiance_scale = _as_floats(self.radiance_scale)


@dataclass(eq=False)
class Camera(_ArrayEq):
    """A camera; ``direction`` is normalised, ``up`` is kept as given."""

    name: str
    type: str
    position: np.ndarray
    direction: np.ndarray
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    fov_deg: float = 40.0
    ortho_width: float = 2.0
    resolution: tuple[int, int] = (64, 64)
    filter_type: str = "box"
    filter_width_px: float = 1.0
    shift: tuple[float, float] = (0.0, 0.0)  # image centre offset, in image widths (lens shift)
    clip_start: float = 0.0                  # m along the view axis before which nothing is seen

    def __post_init__(self):
        self.position = _as_floats(self.position)
        self.direction = _unit(_as_floats(self.direction))
        self.up = _as_floats(self.up)
        if isinstance(self.shift, (list, np.ndarray)):
            self.shift = tuple(float(x) for x in self.shift)
        if isinstance(self.resolution, (list, np.ndarray)):
            self.resolution = tuple(self.resolution.tolist() if isinstance(
                self.resolution, np.ndarray) else self.resolution)


@dataclass(eq=False)
class Radiometer(_ArrayEq):
    """A point radiometer measuring ``quantity`` (see ``QUANTITIES``) at ``position``."""

    name: str
    quantity: str
    position: np.ndarray
    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -1.0]))
    half_angle_deg: float = 12.9
    polar_bins: int = 18
    azimuth_bins: int = 24

    def __post_init__(self):
        self.position = _as_floats(self.position)
        self.direction = _unit(_as_floats(self.direction))


@dataclass(eq=False)
class RadiometerArray(_ArrayEq):
    """Radiometers at ``positions`` (N, 3), one per position and quantity.

    ``direction`` and ``half_angle_deg`` default (None) to the Radiometer defaults.
    """

    name: str
    quantities: list[str]
    positions: np.ndarray
    direction: np.ndarray | None = None
    half_angle_deg: float | None = None

    def __post_init__(self):
        self.positions = _as_floats(self.positions)
        self.direction = _unit(_as_floats(self.direction))

    def radiometers(self) -> list[Radiometer]:
        """The radiometers, named ``f"{name}[{i}].{q}"``, position-major.

        Returns
        -------
        list of Radiometer
            For each position i, one radiometer per quantity, in the order of ``quantities``.
        """
        extra = {}
        if self.direction is not None:
            extra["direction"] = self.direction
        if self.half_angle_deg is not None:
            extra["half_angle_deg"] = self.half_angle_deg
        return [Radiometer(name=f"{self.name}[{i}].{q}", quantity=q, position=p, **extra)
                for i, p in enumerate(self.positions) for q in self.quantities]


@dataclass(eq=False)
class Settings(_ArrayEq):
    """Rendering settings (see docs/scene-format.md for the limits)."""

    integrator: str = "auto"   # "auto": hybrid when there is a sun, else path
    samples: int = 16
    radiometer_samples: int = 65536
    seed: int = 0
    max_depth: int = 256
    threads: int = 0
    forward_cone_deg: float | str = "auto"  # half-angle kept in the beams, or "auto"
    beam_max_level: int = 5    # adaptive subdivision levels of a water-surface triangle
    target_error: float | None = None  # relative standard error at which radiometers stop
    noise_threshold: float | None = None  # relative standard error at which pixels stop
    adaptive_min_samples: int = 16     # samples per pixel before a pixel may stop


def _default_bands() -> list[Band]:
    return [Band("550", 550.0, 10.0)]


@dataclass(eq=False)
class Scene(_ArrayEq):
    """A complete Photic scene. Build it in Python or with ``Scene.from_dict`` /
    ``load_scene``; check it with ``validate``."""

    name: str = "scene"
    bands: list[Band] = field(default_factory=_default_bands)
    materials: dict[str, Material] = field(default_factory=dict)
    meshes: list[MeshObject] = field(default_factory=list)
    water: list[WaterBody] = field(default_factory=list)
    sun: Sun | None = None
    sky: Sky = field(default_factory=lambda: Sky("black"))
    cameras: list[Camera] = field(default_factory=list)
    radiometers: list[Radiometer] = field(default_factory=list)
    radiometer_arrays: list[RadiometerArray] = field(default_factory=list)
    settings: Settings = field(default_factory=Settings)

    def all_radiometers(self) -> list[Radiometer]:
        """The radiometers followed by those of the expanded radiometer arrays."""
        result = list(self.radiometers)
        for array in self.radiometer_arrays:
            result.extend(array.radiometers())
        return result

    def validate(self) -> None:
        """Run every semantic check on the scene.

        Raises
        ------
        SceneError
            For the first problem found, naming the object and the field.
        """
        _validate_scene(self)

    @classmethod
    def from_dict(cls, d: dict, base_dir: str | Path | None = None) -> "Scene":
        """Build and validate a scene from its JSON structure.

        Parameters
        ----------
        d : dict
            The parsed JSON document.
        base_dir : str or Path, optional
            Directory that relative mesh ``file`` paths are relative to (default: the
            current directory).

        Raises
        ------
        SceneError
            If the document does not follow the schema or the scene is invalid.
        """
        if not isinstance(d, dict):
            raise SceneError("scene", "(document)", f"must be a JSON object, got {_show(d)}")
        version = d.get("photic_scene")
        if version is None:
            raise SceneError("scene", "photic_scene",
                             f"required field is missing (format version, must be "
                             f"{FORMAT_VERSION})")
        if isinstance(version, bool) or version != FORMAT_VERSION:
            raise SceneError("scene", "photic_scene",
                             f"unsupported format version {_show(version)}: this Photic reads "
                             f"version {FORMAT_VERSION}")
        _check_schema(d)
        scene = _build_scene(d, Path(base_dir) if base_dir is not None else Path.cwd())
        scene.validate()
        return scene

    def to_dict(self) -> dict:
        """The scene as a JSON-serialisable dict (meshes inline, per-band values as lists)."""
        return _scene_to_dict(self)


# ----------------------------------------------------------------------------------------
# Semantic checks: one function per kind of object
# ----------------------------------------------------------------------------------------

def _validate_scene(s: Scene) -> None:
    if not isinstance(s.name, str):
        raise SceneError("scene", "name", f"must be a string, got {_show(s.name)}")
    if not isinstance(s.bands, list) or not s.bands:
        raise SceneError("scene", "bands", "at least one band is required")
    seen: dict[str, str] = {}
    for i, band in enumerate(s.bands):
        _validate_band(_check_name("band", i, band.name, seen), band)
    nbands = len(s.bands)

    for key, material in s.materials.items():
        _validate_material(key, material, nbands)

    seen = {}
    for i, obj in enumerate(s.meshes):
        label = _check_name("mesh", i, obj.name, seen)
        _check_mesh(label, "", obj.mesh)
        _check_material_ref(label, "material", obj.material, s.materials)

    seen = {}
    ocean = None
    for i, water in enumerate(s.water):
        label = _check_name("water", i, water.name, seen)
        _validate_water(label, water, nbands, s.materials)
        if water.type == "ocean":
            if ocean is not None:
                raise SceneError(label, "type", f"at most one ocean is allowed, {ocean} is "
                                                f"already one")
            ocean = label

    if s.sun is not None:
        _validate_sun(s.sun, nbands)
    _validate_sky(s.sky, nbands)
    if isinstance(s.sky, Sky) and s.sky.type == "harrison_coombes" and s.sun is None:
        raise SceneError("sky", "type", "a 'harrison_coombes' sky is shaped by the sun: the "
                                        "scene needs a sun")

    seen = {}
    for i, camera in enumerate(s.cameras):
        _validate_camera(_check_name("camera", i, camera.name, seen), camera)

    seen = {}
    for i, radiometer in enumerate(s.radiometers):
        _validate_radiometer(_check_name("radiometer", i, radiometer.name, seen), radiometer)
    arrays_seen: dict[str, str] = {}
    for i, array in enumerate(s.radiometer_arrays):
        label = _check_name("radiometer_array", i, array.name, arrays_seen)
        _validate_radiometer_array(label, array)
        # Expanded names share the radiometers' namespace (outputs are keyed by them).
        for radiometer in array.radiometers():
            if radiometer.name in seen:
                raise SceneError(label, "name", f"expands to radiometer '{radiometer.name}', "
                                                f"which is also {seen[radiometer.name]}")
            seen[radiometer.name] = f"{label} (expanded)"

    _validate_settings(s.settings)

    if not s.cameras and not seen:
        raise SceneError("scene", "cameras", "missing sensor: the scene needs at least one "
                                             "camera or radiometer")
    _check_water_overlap(s)


_OVERLAP_SAMPLE = 2000  # vertices of a water mesh tested against each other one


def _check_water_overlap(s: Scene) -> None:
    """Water meshes must not overlap (a point lies in one water body at most; the medium of
    the overlap would depend on the order of the list). A body whose boxes meet another's is
    tested by its vertices, moved a millionth of its size towards its own centre (so that bodies
    that only touch pass), being inside the other (ray parity, trimesh)."""
    meshes = [(i, w) for i, w in enumerate(s.water) if w.type == "mesh" and w.mesh is not None]
    if len(meshes) < 2:
        return
    boxes = {i: (np.asarray(w.mesh.vertices).min(0), np.asarray(w.mesh.vertices).max(0)) for i, w in meshes}
    built: dict = {}

    def solid(i, w):
        if i not in built:
            import trimesh
            built[i] = trimesh.Trimesh(np.asarray(w.mesh.vertices, float), np.asarray(w.mesh.triangles),
                                       process=False)
        return built[i]

    for a, wa in meshes:
        for b, wb in meshes:
            if a == b:
                continue
            (alo, ahi), (blo, bhi) = boxes[a], boxes[b]
            if np.any(alo > bhi) or np.any(blo > ahi):
                continue
            v = np.asarray(wa.mesh.vertices, float)
            if len(v) > _OVERLAP_SAMPLE:
                v = v[np.linspace(0, len(v) - 1, _OVERLAP_SAMPLE).astype(np.int64)]
            centre = 0.5 * (alo + ahi)
            v = v + (centre - v) * 1e-6
            inside = solid(b, wb).contains(v)
            if np.any(inside):
                raise SceneError(_label("water", wb.name, b), "vertices",
                                 f"overlaps water '{wa.name}' ({int(np.count_nonzero(inside))} of its "
                                 f"{len(v)} tested vertices lie inside it): a point can be in one "
                                 f"water body only; separate them, or join them into one body")


def scene_warnings(s: Scene) -> list[str]:
    """Problems that do not stop a render but make its numbers useless where the user may not
    expect it (the renderer adds those it needs geometry for: sensors inside opaque objects)."""
    out = []
    if s.sun is not None and not np.any(np.asarray(s.sun.irradiance, float) > 0):
        out.append("sun: its irradiance is 0 in every band: it adds no light")
    ocean = next((w for w in s.water if w.type == "ocean"), None)
    if ocean is not None and ocean.bottom_depth is not None:
        floor = float(ocean.surface.z) - float(ocean.bottom_depth)
        for r in s.all_radiometers():
            if float(r.position[2]) < floor:
                out.append(f"radiometer '{r.name}': position z = {float(r.position[2]):g} m is below "
                           f"the sea floor (z = {floor:g} m): no light reaches it, it reads 0")
        for c in s.cameras:
            if float(c.position[2]) < floor:
                out.append(f"camera '{c.name}': position z = {float(c.position[2]):g} m is below the "
                           f"sea floor (z = {floor:g} m): it sees nothing")
    return out


def _validate_band(label: str, band: Band) -> None:
    _check_real(label, "center_nm", band.center_nm, 0, 1e6, lo_open=True)
    _check_real(label, "width_nm", band.width_nm, 1e-3, 1e6)


def _validate_material(key: Any, material: Material, nbands: int) -> None:
    label = f"material '{key}'"
    if not isinstance(key, str) or not key:
        raise SceneError(label, "name", "must be a non-empty string")
    if not isinstance(material, Material):
        raise SceneError(label, "type", "must be a Material")
    if material.name != key:
        raise SceneError(label, "name", f"is {_show(material.name)} but the material is stored "
                                        f"under the key '{key}'")
    _check_per_band(label, "reflectance", material.reflectance, nbands, 0.0, 1.0)


def _check_material_ref(label: str, fld: str, name: Any, materials: dict) -> None:
    if name not in materials:
        known = ", ".join(repr(k) for k in materials) or "none"
        raise SceneError(label, fld, f"unknown material {_show(name)} (defined: {known})")


def _check_mesh(label: str, prefix: str, mesh: Any) -> None:
    """Check a mesh: shapes, finite vertices, indices in range, no zero-area triangles.

    ``prefix`` is prepended to the field names (``"surface."`` for an ocean patch).
    """
    if not isinstance(mesh, TriangleMesh):
        raise SceneError(label, f"{prefix}mesh", f"a TriangleMesh is required, got "
                                                 f"{_show(mesh)}")
    v, t = mesh.vertices, mesh.triangles
    if not isinstance(v, np.ndarray) or v.ndim != 2 or v.shape[1] != 3 or v.dtype.kind not in "fiu":
        raise SceneError(label, f"{prefix}vertices", "must be an (N, 3) array of numbers")
    if not isinstance(t, np.ndarray) or t.ndim != 2 or t.shape[1] != 3 or t.dtype.kind not in "iu":
        raise SceneError(label, f"{prefix}triangles", "must be an (M, 3) array of integer "
                                                      "vertex indices")
    if len(t) == 0 or len(v) == 0:
        raise SceneError(label, f"{prefix}triangles", "empty mesh: at least one triangle is "
                                                      "required")
    # Large meshes (millions of triangles) are checked in blocks, so the temporaries stay a
    # few tens of MB whatever the size; the whole-array reductions come first as fast paths.
    if not np.isfinite(v).all():
        bad = np.flatnonzero(~np.all(np.isfinite(v), axis=1))
        raise SceneError(label, f"{prefix}vertices[{bad[0]}]", f"must be finite, got "
                                                              f"{v[bad[0]].tolist()}")
    far = np.max(np.abs(v), axis=1) > MAX_COORDINATE_M
    if far.any():
        bad = int(np.flatnonzero(far)[0])
        raise SceneError(label, f"{prefix}vertices[{bad}]", f"must be {_COORD_TEXT}, got "
                                                            f"{v[bad].tolist()}")
    if t.min() < 0 or t.max() >= len(v):
        bad = np.flatnonzero(np.any((t < 0) | (t >= len(v)), axis=1))
        raise SceneError(label, f"{prefix}triangles[{bad[0]}]",
                         f"vertex index out of range 0..{len(v) - 1}: {t[bad[0]].tolist()}")
    diagonal2 = float(np.sum((v.max(axis=0) - v.min(axis=0)) ** 2))
    limit = _DEGENERATE_AREA_FRACTION * diagonal2
    for start in range(0, len(t), _MESH_CHECK_BLOCK):
        area = _triangle_areas(v, t[start:start + _MESH_CHECK_BLOCK])
        bad = np.flatnonzero((area < limit) | (area == 0.0))
        if len(bad):
            i = start + int(bad[0])
            raise SceneError(label, f"{prefix}triangles[{i}]",
                             f"zero-area (degenerate) triangle {t[i].tolist()}: area "
                             f"{area[bad[0]]:.3g} m^2 < 1e-12 x (bounding-box diagonal)^2")


_MESH_CHECK_BLOCK = 1 << 18  # triangles per block of the mesh checks


def _triangle_areas(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Areas (float64) of the triangles ``t`` (M, 3) over the vertices ``v``."""
    p0 = v[t[:, 0]].astype(np.float64, copy=False)
    e1 = v[t[:, 1]] - p0
    e2 = v[t[:, 2]] - p0
    cx = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    cy = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    cz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    return 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)


def check_closed_mesh(label: str, mesh: TriangleMesh) -> None:
    """Check a water mesh on its own (as ``Scene.validate`` does): valid, closed, outward.

    Raises
    ------
    SceneError
        Naming ``label`` and the field."""
    _check_mesh(label, "", mesh)
    _check_closed(label, mesh)


def _check_closed(label: str, mesh: TriangleMesh) -> None:
    """Require a watertight, consistently wound mesh with outward normals.

    The same rules as trimesh's ``merge_vertices``, ``is_watertight``, ``is_winding_consistent``
    and ``volume`` (tests/test_large_scenes.py compares them), in O(M log M) time and about
    40 bytes per triangle of temporaries (trimesh needs ~470), so that meshes of millions of
    triangles are checked in seconds:

    - closedness is geometric: vertices at the same position (to 1e-8 m) are joined first;
    - every edge must belong to exactly two triangles, which traverse it in opposite
      directions (consistent winding);
    - the enclosed volume (divergence theorem) must be positive (outward normals).
    """
    v = np.asarray(mesh.vertices, dtype=np.float64)
    ids, n = _merged_vertex_ids(v)
    tri = mesh.triangles
    m = len(tri)
    if n >= 1 << 31:  # edge keys would overflow int64: not reachable in memory anyway
        raise SceneError(label, "triangles", f"water mesh has too many vertices ({n})")
    # One int64 key per directed edge: 2 (lo n + hi) + (a > b); sorted, the two uses of an
    # edge are then neighbours, the lower key traversing it from lo to hi.
    keys = np.empty(3 * m, np.int64)
    for j in range(3):
        a, b = ids[tri[:, j]], ids[tri[:, (j + 1) % 3]]
        k = keys[j * m:(j + 1) * m]
        np.minimum(a, b, out=k)
        k *= n
        k += np.maximum(a, b)
        k *= 2
        k += a > b
        del a, b
    keys.sort()
    edge = keys >> 1
    first, second = edge[0::2], edge[1::2]
    closed = len(keys) % 2 == 0 and bool(np.array_equal(first, second)) and bool(
        np.all(first[1:] != second[:-1]))
    if not closed:
        _, counts = np.unique(edge, return_counts=True)
        open_edges, shared = int(np.count_nonzero(counts == 1)), int(np.count_nonzero(counts > 2))
        if open_edges == 0 and shared > 0:  # closed, but parts touch along edges
            raise SceneError(label, "triangles", f"water mesh is not a single closed surface: "
                                                 f"{shared} edge(s) belong to more than two "
                                                 f"triangles (parts touching along an edge, e.g. "
                                                 f"two boxes sharing one: join them into one "
                                                 f"body or move them apart)")
        raise SceneError(label, "triangles", f"water mesh is not closed (watertight): "
                                             f"{open_edges} edge(s) belong to only one triangle"
                                             + (f" and {shared} to more than two" if shared else ""))
    del edge, first, second
    # Opposite directions: flags 0 then 1 in each pair (an edge from a vertex to itself, in
    # a triangle whose corners were joined, counts as consistent, as in trimesh).
    k0, k1 = keys[0::2], keys[1::2]
    ok = ((k0 & 1) == 0) & ((k1 & 1) == 1)
    if not ok.all():
        lo_hi = k0[~ok] >> 1
        if not np.all(lo_hi // n == lo_hi % n):
            raise SceneError(label, "triangles", "water mesh winding is inconsistent: "
                                                 "neighbouring triangles have opposite "
                                                 "orientations")
    del keys, k0, k1, ok
    volume = 0.0
    for start in range(0, m, _MESH_CHECK_BLOCK):
        t = tri[start:start + _MESH_CHECK_BLOCK]
        p0, p1, p2 = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        cx = (p1[:, 1] - p0[:, 1]) * (p2[:, 2] - p0[:, 2]) - (p1[:, 2] - p0[:, 2]) * (p2[:, 1] - p0[:, 1])
        volume += float(np.dot(cx, p0[:, 0] + p1[:, 0] + p2[:, 0]))
    volume /= 6.0
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float(np.max(hi - lo))
    if abs(volume) <= 1e-9 * max(size, 1e-300) ** 3:  # flat: no height, width or depth
        thin = "xyz"[int(np.argmin(hi - lo))]
        raise SceneError(label, "triangles", f"water mesh encloses no volume ({volume:.3g} m^3): "
                                             f"it is flat (extent {float(np.min(hi - lo)):.3g} m "
                                             f"in {thin}); a water body needs a height")
    if not volume > 0:
        raise SceneError(label, "triangles", f"water mesh normals point inwards (enclosed volume "
                                             f"{volume:.6g} m^3 <= 0); reverse the winding "
                                             f"of every triangle")


def _merged_vertex_ids(v: np.ndarray) -> tuple[np.ndarray, int]:
    """(id per vertex, number of ids): vertices whose coordinates agree when rounded to 1e-8
    (trimesh's ``tol.merge``) share an id."""
    q = np.round(v * 1e8).astype(np.int64)
    order = np.lexsort((q[:, 2], q[:, 1], q[:, 0]))
    qs = q[order]
    del q
    new = np.empty(len(v), bool)
    new[:1] = True
    np.any(qs[1:] != qs[:-1], axis=1, out=new[1:])
    del qs
    ids = np.empty(len(v), np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids, int(np.count_nonzero(new))


def _validate_phase(label: str, prefix: str, phase: Any) -> None:
    if not isinstance(phase, PhaseFunction):
        raise SceneError(label, f"{prefix}type", "a PhaseFunction is required")
    _check_choice(label, f"{prefix}type", phase.type, tuple(PHASE_FUNCTION_PARAMS))
    expected = PHASE_FUNCTION_PARAMS[phase.type]
    for key in phase.params:
        if key not in expected:
            raise SceneError(label, f"{prefix}{key}", f"is not a parameter of phase function "
                                                      f"'{phase.type}'")
    for key in expected:
        if key not in phase.params:
            raise SceneError(label, f"{prefix}{key}", f"required by phase function "
                                                      f"'{phase.type}'")
    if phase.type == "henyey_greenstein":
        _check_real(label, f"{prefix}g", phase.params["g"], -MAX_HG_G, MAX_HG_G)
    elif phase.type == "fournier_forand":
        _check_real(label, f"{prefix}backscatter_fraction",
                    phase.params["backscatter_fraction"], 1e-4, 0.15)


def _validate_iops(label: str, iops: Any, nbands: int, fld: str = "iops") -> None:
    if not isinstance(iops, IOPs):
        raise SceneError(label, fld, "an IOPs or an IOPProfile is required" if fld == "iops"
                         else "an IOPs is required")
    _check_per_band(label, f"{fld}.absorption", iops.absorption, nbands)
    if not isinstance(iops.scattering, list):
        raise SceneError(label, f"{fld}.scattering", f"must be a list of ScatteringComponent, "
                                                     f"got {_show(iops.scattering)}")
    if len(iops.scattering) > MAX_COMPONENTS:
        raise SceneError(label, f"{fld}.scattering", f"has {len(iops.scattering)} components; "
                                                     f"at most {MAX_COMPONENTS} are supported")
    for i, component in enumerate(iops.scattering):
        prefix = f"{fld}.scattering[{i}]"
        if not isinstance(component, ScatteringComponent):
            raise SceneError(label, prefix, f"must be a ScatteringComponent, got {_show(component)}")
        _check_per_band(label, f"{prefix}.b", component.b, nbands)
        _validate_phase(label, f"{prefix}.phase.", component.phase)


def _validate_profile(label: str, profile: IOPProfile, nbands: int,
                      prefix: str = "iop_profile") -> None:
    """Layer tops finite and strictly descending, one valid IOPs per layer, and the same
    phase functions (in the same order) in every layer."""
    z = profile.z_top
    if not isinstance(z, np.ndarray) or z.ndim != 1 or z.dtype.kind not in "fiu" or z.size == 0:
        raise SceneError(label, f"{prefix}.z_top", f"must be a non-empty list of layer tops "
                                                     f"(m), got {_show(z)}")
    for i, x in enumerate(z.tolist()):
        _check_real(label, f"{prefix}.z_top[{i}]", x)
        if i > 0 and not x < z[i - 1]:
            raise SceneError(label, f"{prefix}.z_top[{i}]",
                             f"must be below z_top[{i - 1}] = {_num(z[i - 1])} m (layer tops "
                             f"run strictly downwards), got {_show(x)}")
    layers = profile.layers
    if not isinstance(layers, list) or len(layers) != z.size:
        count = _entries(len(layers)) if isinstance(layers, list) else _show(layers)
        raise SceneError(label, f"{prefix}.layers", f"needs one IOPs per layer top: z_top has "
                                                      f"{_entries(z.size)}, layers has {count}")
    for i, layer in enumerate(layers):
        _validate_iops(label, layer, nbands, f"{prefix}.layers[{i}].iops")
    first = layers[0].scattering
    for i, layer in enumerate(layers[1:], start=1):
        fld = f"{prefix}.layers[{i}].iops.scattering"
        if len(layer.scattering) != len(first):
            raise SceneError(label, fld, f"has {len(layer.scattering)} component(s) but layer 0 "
                                         f"has {len(first)}: every layer needs the same "
                                         f"components (phase functions), with b = 0 where absent")
        for j, (mine, ref) in enumerate(zip(layer.scattering, first)):
            if mine.phase != ref.phase:
                raise SceneError(label, f"{fld}[{j}].phase",
                                 f"is {_phase_text(mine.phase)} but layer 0's component {j} is "
                                 f"{_phase_text(ref.phase)}: layers may differ only in a and b")


def _validate_grid(label: str, grid: IOPGrid, nbands: int) -> None:
    """Base and unit IOPs with the same components, unit coefficients >= 0, a finite box of
    positive size, and 3-D arrays of finite densities >= 0 (every field's of one shape)."""
    if isinstance(grid.iops, IOPProfile):  # a depth profile under the grid
        _validate_profile(label, grid.iops, nbands, "iop_grid.base.iop_profile")
        ref_iops, ref_name = grid.iops.layers[0], "iop_grid.base.iop_profile.layers[0].iops"
    else:
        _validate_iops(label, grid.iops, nbands, "iop_grid.base.iops")
        ref_iops, ref_name = grid.iops, "iop_grid.base.iops"
    extra = grid.extra_fields
    if not isinstance(extra, list) or not all(isinstance(f, GridField) for f in extra):
        raise SceneError(label, "iop_grid.fields", f"must be a list of GridField, got {_show(extra)}")
    if len(extra) > MAX_GRID_FIELDS - 1:
        raise SceneError(label, "iop_grid.fields", f"has {len(extra)} fields: a grid holds at most "
                                                   f"{MAX_GRID_FIELDS - 1} beside its 'density'")
    names = [f.name for f in extra]
    for i, f in enumerate(extra):
        if not isinstance(f.name, str) or not f.name or f.name in names[:i]:
            raise SceneError(label, f"iop_grid.fields[{i}].name",
                             f"must be a non-empty name of its own, got {f.name!r}")
    units = [("iop_grid.unit.iops", grid.unit)] + [(f"iop_grid.fields[{i}].unit.iops", f.unit)
                                                   for i, f in enumerate(extra)]
    for prefix, unit in units:
        _validate_iops(label, unit, nbands, prefix)
        fld = f"{prefix}.scattering"
        if len(unit.scattering) != len(ref_iops.scattering):
            raise SceneError(label, fld, f"has {len(unit.scattering)} component(s) but "
                                         f"{ref_name} has {len(ref_iops.scattering)}: the unit "
                                         f"IOPs need the same components (phase functions), with "
                                         f"b = 0 where absent")
        for j, (mine, ref) in enumerate(zip(unit.scattering, ref_iops.scattering)):
            if mine.phase != ref.phase:
                raise SceneError(label, f"{fld}[{j}].phase",
                                 f"is {_phase_text(mine.phase)} but {ref_name} component {j} is "
                                 f"{_phase_text(ref.phase)}")
            if np.any(np.asarray(mine.b) < 0):
                raise SceneError(label, f"{fld}[{j}].b", f"must be >= 0 in every band, got "
                                                         f"{_show(mine.b)}")
        if np.any(np.asarray(unit.absorption) < 0):
            raise SceneError(label, f"{prefix}.absorption", f"must be >= 0 in every band, got "
                                                            f"{_show(unit.absorption)}")
    for fld, v in (("origin", grid.origin), ("size", grid.size)):
        if (not isinstance(v, np.ndarray) or v.shape != (3,) or v.dtype.kind not in "fiu"
                or not np.all(np.isfinite(v))):
            raise SceneError(label, f"iop_grid.{fld}", f"must be 3 finite numbers [x, y, z] "
                                                      f"(m), got {_show(v)}")
    if not np.all(grid.size > 0):
        raise SceneError(label, "iop_grid.size", f"must be > 0 along every axis, got "
                                                 f"{_show(grid.size)}")
    for fld, d in [("iop_grid.density", grid.density)] + [(f"iop_grid.fields[{i}].density", f.density)
                                                          for i, f in enumerate(extra)]:
        if not isinstance(d, np.ndarray) or d.ndim != 3 or d.dtype.kind not in "fiu" or 0 in d.shape:
            shape = f"shape {d.shape}" if isinstance(d, np.ndarray) else _show(d)
            raise SceneError(label, fld, f"must be a non-empty 3-D array of numbers "
                                         f"(nx, ny, nz), got {shape}")
        if d.shape != grid.density.shape:
            raise SceneError(label, fld, f"has shape {d.shape} but iop_grid.density has "
                                         f"{grid.density.shape}: the fields share the grid's voxels")
        # min and max pass over the array without temporaries (a NaN makes both NaN); only a
        # bad array is searched for its first bad voxel
        if d.size and not (d.min() >= 0 and np.isfinite(d.max())):
            i = tuple(int(x) for x in np.argwhere(~(np.isfinite(d) & (d >= 0)))[0])
            raise SceneError(label, f"{fld}{list(i)}", f"must be finite and >= 0, got "
                                                       f"{_num(float(d[i]))}")


def _phase_text(p: PhaseFunction) -> str:
    params = ", ".join(f"{k}={_num(v)}" for k, v in p.params.items())
    return f"{p.type!r}" + (f" ({params})" if params else "")


def _validate_water(label: str, w: WaterBody, nbands: int, materials: dict) -> None:
    _check_choice(label, "type", w.type, WATER_TYPES)
    _check_real(label, "ior", w.ior, 1.0)
    if isinstance(w.iops, IOPProfile):
        _validate_profile(label, w.iops, nbands)
    elif isinstance(w.iops, IOPGrid):
        _validate_grid(label, w.iops, nbands)
    else:
        _validate_iops(label, w.iops, nbands)
    if w.type == "mesh":
        for attr in ("surface", "bottom_depth", "bottom_material"):
            if getattr(w, attr) is not None:
                raise SceneError(label, attr, "only allowed for water of type 'ocean'")
        _check_mesh(label, "", w.mesh)
        _check_closed(label, w.mesh)
        return
    if w.mesh is not None:
        raise SceneError(label, "mesh", "only allowed for water of type 'mesh'")
    _validate_surface(label, w.surface)
    if w.bottom_depth is not None or w.bottom_material is not None:
        _check_real(label, "bottom_depth", w.bottom_depth, 0, MAX_COORDINATE_M, lo_open=True)
        _check_material_ref(label, "bottom_material", w.bottom_material, materials)


def _validate_surface(label: str, surface: Any) -> None:
    if not isinstance(surface, OceanSurface):
        raise SceneError(label, "surface", "an ocean needs a surface (OceanSurface)")
    _check_choice(label, "surface.kind", surface.kind, SURFACE_KINDS)
    _check_real(label, "surface.z", surface.z)
    if surface.kind != "waves" and surface.waves is not None:
        raise SceneError(label, "surface.waves", "only allowed for surface kind 'waves'")
    r = surface.roughness
    if r is not None:
        if not isinstance(r, SurfaceRoughness):
            raise SceneError(label, "surface.roughness", f"must be a SurfaceRoughness, got {_show(r)}")
        _check_real(label, "surface.roughness.wind_speed", r.wind_speed, 0, 50)
        if not isinstance(r.anisotropic, bool):
            raise SceneError(label, "surface.roughness.anisotropic", f"must be true or false, got {_show(r.anisotropic)}")
        if r.wind_direction_deg is not None:
            _check_real(label, "surface.roughness.wind_direction_deg", r.wind_direction_deg)
    if surface.kind in ("flat", "waves"):
        for attr in ("mesh", "period"):
            if getattr(surface, attr) is not None:
                raise SceneError(label, f"surface.{attr}", "only allowed for surface kind "
                                                           "'patch'")
    if surface.kind == "waves":
        from .waves import SurfaceFoldsError, WaveModel

        if not isinstance(surface.waves, WaveModel):
            raise SceneError(label, "surface.waves", f"a photic.waves.WaveModel is required, "
                                                     f"got {_show(surface.waves)}")
        surface.waves.validate(label, "surface.")
        if surface.waves.choppiness > 0:  # only a choppy surface can fold over: generated now
            try:                          # (22 s at 4096 x 4096; a render builds it anyway)
                surface.patch()
            except SurfaceFoldsError as exc:
                raise SceneError(label, "surface.choppiness", str(exc)) from None
        return
    if surface.kind == "flat":
        return
    _check_mesh(label, "surface.", surface.mesh)
    if surface.normals is not None:
        nrm = surface.normals
        if not isinstance(nrm, np.ndarray) or nrm.shape != surface.mesh.vertices.shape or \
                not np.all(np.isfinite(nrm)) or np.any(nrm[:, 2] <= 0):
            raise SceneError(label, "surface.normals", "must be finite (N, 3) vertex normals "
                                                       "pointing up, one per vertex")
    period = surface.period
    if not isinstance(period, tuple) or len(period) != 2:
        raise SceneError(label, "surface.period", f"must be [Lx, Ly], got {_show(period)}")
    for i, p in enumerate(period):
        _check_real(label, f"surface.period[{i}]", p, 1e-3, 2 * MAX_COORDINATE_M)
    v, t = surface.mesh.vertices, surface.mesh.triangles
    # The patch tiles the plane, so its xy extent must be exactly one period.
    extent = v[:, :2].max(axis=0) - v[:, :2].min(axis=0)
    for i, axis in enumerate("xy"):
        if abs(extent[i] - period[i]) > 1e-6 * period[i]:
            raise SceneError(label, f"surface.period[{i}]",
                             f"is {_num(period[i])} but the patch vertices span "
                             f"{extent[i]:.9g} m in {axis}")
    # A height field with water below: every triangle must face upwards.
    normal_z = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2]
    bad = np.flatnonzero(normal_z <= 0)
    if len(bad):
        raise SceneError(label, f"surface.triangles[{bad[0]}]",
                         "must face upwards (normal z > 0): the patch is a height field with "
                         "the water below it")
    mean_z = float(np.mean(v[:, 2]))
    if abs(surface.z - mean_z) > 1e-9 * max(1.0, abs(mean_z)):
        raise SceneError(label, "surface.z", f"is {surface.z!r} but must equal the mean height "
                                             f"of the patch vertices, {mean_z!r}")


def _validate_sun(sun: Sun, nbands: int) -> None:
    _check_real("sun", "zenith_deg", sun.zenith_deg, 0, 90, hi_open=True)
    _check_real("sun", "azimuth_deg", sun.azimuth_deg)
    _check_per_band("sun", "irradiance", sun.irradiance, nbands, 0.0, MAX_SOURCE)
    _check_real("sun", "angular_diameter_deg", sun.angular_diameter_deg, 0, 20, lo_open=True)


def _validate_sky(sky: Any, nbands: int) -> None:
    if not isinstance(sky, Sky):
        raise SceneError("sky", "type", "a Sky is required (Sky('black') for none)")
    _check_choice("sky", "type", sky.type, SKY_TYPES)
    if sky.type == "black":
        if sky.radiance_scale is not None:
            raise SceneError("sky", "radiance_scale", "must be None for a black sky")
        return
    _check_per_band("sky", "radiance_scale", sky.radiance_scale, nbands, 0.0, MAX_SOURCE)
    _check_real("sky", "cloud_fraction", sky.cloud_fraction, 0, 1)
    if sky.cloud_fraction and sky.type != "harrison_coombes":
        raise SceneError("sky", "cloud_fraction", "only for sky type 'harrison_coombes'")
    if sky.full_sphere and sky.type != "uniform":
        raise SceneError("sky", "full_sphere", f"only a uniform sky can cover the full sphere, not '{sky.type}'")


def _validate_camera(label: str, c: Camera) -> None:
    _check_choice(label, "type", c.type, CAMERA_TYPES)
    _check_vec3(label, "position", c.position, position=True)
    _check_vec3(label, "direction", c.direction, nonzero=True)
    _check_vec3(label, "up", c.up, nonzero=True)
    d = c.direction / np.linalg.norm(c.direction)
    u = c.up / np.linalg.norm(c.up)
    if np.linalg.norm(np.cross(d, u)) < 1e-6:
        raise SceneError(label, "up", f"is parallel to the viewing direction {d.tolist()}")
    _check_real(label, "fov_deg", c.fov_deg, 0, 180, lo_open=True, hi_open=True)
    _check_real(label, "ortho_width", c.ortho_width, 0, 2 * MAX_COORDINATE_M, lo_open=True)
    if not isinstance(c.resolution, tuple) or len(c.resolution) != 2:
        raise SceneError(label, "resolution", f"must be [width, height], got "
                                              f"{_show(c.resolution)}")
    for i, n in enumerate(c.resolution):
        _check_int(label, f"resolution[{i}]", n, 1, 16384)
    _check_choice(label, "filter.type", c.filter_type, FILTER_TYPES)
    _check_real(label, "filter.width_px", c.filter_width_px, 0, lo_open=True)
    if not isinstance(c.shift, tuple) or len(c.shift) != 2:
        raise SceneError(label, "shift", f"must be [x, y], got {_show(c.shift)}")
    for i, x in enumerate(c.shift):
        _check_real(label, f"shift[{i}]", x, -10, 10)
    _check_real(label, "clip_start", c.clip_start, 0, MAX_COORDINATE_M)


def _validate_radiometer(label: str, r: Radiometer) -> None:
    _check_choice(label, "quantity", r.quantity, QUANTITIES)
    _check_vec3(label, "position", r.position, position=True)
    _check_vec3(label, "direction", r.direction, nonzero=True)
    _check_real(label, "half_angle_deg", r.half_angle_deg, 0, 90, lo_open=True)
    _check_int(label, "polar_bins", r.polar_bins, 1, 1_000_000)
    _check_int(label, "azimuth_bins", r.azimuth_bins, 1, 1_000_000)
    if r.quantity == "radiance_distribution" and r.polar_bins * r.azimuth_bins > MAX_DISTRIBUTION_BINS:
        raise SceneError(label, "azimuth_bins", f"polar_bins x azimuth_bins must be at most "
                                                f"{MAX_DISTRIBUTION_BINS:,}, got {r.polar_bins:,} x "
                                                f"{r.azimuth_bins:,} = {r.polar_bins * r.azimuth_bins:,}")


def _validate_radiometer_array(label: str, a: RadiometerArray) -> None:
    if not isinstance(a.quantities, (list, tuple)) or not a.quantities:
        raise SceneError(label, "quantities", "at least one quantity is required")
    for i, q in enumerate(a.quantities):
        _check_choice(label, f"quantities[{i}]", q, QUANTITIES)
    p = a.positions
    if not isinstance(p, np.ndarray) or p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise SceneError(label, "positions", "must be a non-empty (N, 3) array of points")
    if len(p) > MAX_ARRAY_RADIOMETERS:
        raise SceneError(label, "positions", f"at most {MAX_ARRAY_RADIOMETERS:,} radiometers per "
                                             f"array, got {len(p):,}")
    for i, point in enumerate(p):
        _check_vec3(label, f"positions[{i}]", point, position=True)
    if a.direction is not None:
        _check_vec3(label, "direction", a.direction, nonzero=True)
    if a.half_angle_deg is not None:
        _check_real(label, "half_angle_deg", a.half_angle_deg, 0, 90, lo_open=True)


def _validate_settings(s: Settings) -> None:
    _check_choice("settings", "integrator", s.integrator, INTEGRATORS)
    _check_int("settings", "samples", s.samples, 1, 1_000_000)
    _check_int("settings", "radiometer_samples", s.radiometer_samples, 1, 10**10)
    _check_int("settings", "seed", s.seed, 0, 2**63 - 1)
    _check_int("settings", "max_depth", s.max_depth, 1, 100_000)
    _check_int("settings", "threads", s.threads, 0, 1024)
    _check_int("settings", "beam_max_level", s.beam_max_level, 0, 10)
    if s.forward_cone_deg != "auto":
        _check_real("settings", "forward_cone_deg", s.forward_cone_deg, 0.0, 30.0)
    if s.target_error is not None:
        _check_real("settings", "target_error", s.target_error, 0.0, 1.0, lo_open=True, hi_open=True)
    if s.noise_threshold is not None:
        _check_real("settings", "noise_threshold", s.noise_threshold, 0.0, 1.0, lo_open=True, hi_open=True)
    _check_int("settings", "adaptive_min_samples", s.adaptive_min_samples, 1, 1_000_000)


# ----------------------------------------------------------------------------------------
# JSON Schema check, with errors translated to SceneError
# ----------------------------------------------------------------------------------------

# Top-level lists whose items are named objects, and the word used for them in messages.
_LIST_KINDS = {"bands": "band", "meshes": "mesh", "water": "water", "cameras": "camera",
               "radiometers": "radiometer", "radiometer_arrays": "radiometer_array"}

_TYPE_WORDS = {"number": "a number", "integer": "an integer", "string": "a string",
               "array": "a list", "object": "an object", "null": "null", "boolean": "true/false"}


@lru_cache(maxsize=1)
def scene_schema() -> dict:
    """The JSON Schema of the scene format (draft 2020-12), as a dict."""
    text = resources.files("photic.schema").joinpath("scene.schema.json").read_text("utf-8")
    return json.loads(text)


@lru_cache(maxsize=1)
def _schema_validator():
    import jsonschema

    return jsonschema.Draft202012Validator(scene_schema())


def _field_text(parts) -> str:
    """``["iops", "absorption", 0]`` -> ``"iops.absorption[0]"``."""
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _locate(doc: dict, parts: list) -> tuple[str, str]:
    """The object label and field for a path in the document."""
    if parts and parts[0] in _LIST_KINDS and len(parts) >= 3 and isinstance(parts[1], int):
        item = doc[parts[0]][parts[1]]
        name = item.get("name") if isinstance(item, dict) else None
        return _label(_LIST_KINDS[parts[0]], name, parts[1]), _field_text(parts[2:])
    if parts and parts[0] == "materials" and len(parts) >= 3:
        return f"material '{parts[1]}'", _field_text(parts[2:])
    if parts and parts[0] in ("sun", "sky", "settings") and len(parts) >= 2:
        return parts[0], _field_text(parts[1:])
    return "scene", _field_text(parts) or "(document)"


def _schema_message(error) -> tuple[list, str]:
    """Path (possibly extended by a key) and message for a jsonschema error."""
    parts = list(error.absolute_path)
    kind, schema, value = error.validator, error.schema, error.instance
    if kind == "required":
        missing = [k for k in error.validator_value if k not in value]
        return parts + missing[:1], "required field is missing"
    if kind == "dependentRequired":
        for key, needed in error.validator_value.items():
            missing = [k for k in needed if key in value and k not in value]
            if missing:
                return parts + missing[:1], f"required together with '{key}'"
    if kind == "additionalProperties" and error.validator_value is False:
        known = list(schema.get("properties", {}))
        unknown = [k for k in value if k not in known]
        hint = difflib.get_close_matches(unknown[0], known, n=1)
        suggestion = f"; did you mean '{hint[0]}'?" if hint else f"; allowed: {', '.join(known)}"
        return parts + unknown[:1], f"unknown key{suggestion}"
    if kind in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        lo = schema.get("minimum", schema.get("exclusiveMinimum"))
        hi = schema.get("maximum", schema.get("exclusiveMaximum"))
        allowed = _range_text(lo, hi, "exclusiveMinimum" in schema,
                              "exclusiveMaximum" in schema, schema.get("type") == "integer")
        return parts, f"must be {allowed}, got {_show(value)}"
    if kind == "type":
        wanted = error.validator_value
        wanted = [wanted] if isinstance(wanted, str) else wanted
        return parts, (f"must be {' or '.join(_TYPE_WORDS.get(w, w) for w in wanted)}, "
                       f"got {_show(value)}")
    if kind == "enum":
        return parts, (f"must be one of {', '.join(map(repr, error.validator_value))}, "
                       f"got {_show(value)}")
    if kind == "const":
        return parts, f"must be {error.validator_value!r}, got {_show(value)}"
    if kind in ("minItems", "maxItems"):
        lo, hi = schema.get("minItems"), schema.get("maxItems")
        if lo == hi:
            count = f"exactly {_entries(lo)}"
        else:
            count = f"at least {_entries(lo)}" if kind == "minItems" else f"at most {_entries(hi)}"
        return parts, f"must have {count}, got {len(value)}"
    if kind == "minLength":
        return parts, "must not be empty"
    if kind == "oneOf" and all(set(sub) == {"required"} for sub in error.validator_value):
        # exactly one of several alternative keys (e.g. 'iops', 'iop_model', 'iop_profile')
        keys = [sub["required"][0] for sub in error.validator_value]
        given = [k for k in keys if isinstance(value, dict) and k in value]
        choice = ", ".join(f"'{k}'" for k in keys)
        if not given:
            return parts + keys[:1], f"required field is missing: give one of {choice}"
        return parts + given[1:2], f"give only one of {choice}, not {' and '.join(map(repr, given))}"
    return parts, error.message


def _is_index_rows(rows: Any, number_types: tuple) -> bool:
    """True when ``rows`` is a list of 3-lists of the given number types (no bools)."""
    return (isinstance(rows, list)
            and all(type(row) is list and len(row) == 3 for row in rows)
            and {type(x) for row in rows for x in row} <= set(number_types))


def _shorten_mesh_lists(d: dict) -> dict:
    """A copy of ``d`` whose well-formed mesh lists are cut to one row.

    jsonschema takes seconds per 100,000 triangles; well-formed rows are recognised here much
    faster, and anything unusual is left whole for the schema to report precisely.
    """
    def shorten(obj: Any) -> Any:
        if not isinstance(obj, dict):
            return obj
        obj = dict(obj)
        if _is_index_rows(obj.get("vertices"), (int, float)):
            obj["vertices"] = obj["vertices"][:1]
        if _is_index_rows(obj.get("triangles"), (int,)):
            if all(x >= 0 for row in obj["triangles"] for x in row):
                obj["triangles"] = obj["triangles"][:1]
        if "surface" in obj:
            obj["surface"] = shorten(obj["surface"])
        return obj

    d = dict(d)
    for key in ("meshes", "water"):
        if isinstance(d.get(key), list):
            d[key] = [shorten(item) for item in d[key]]
    return d


def _check_schema(d: dict) -> None:
    """Check ``d`` against the JSON Schema; raise the most relevant error as SceneError."""
    import jsonschema

    error = jsonschema.exceptions.best_match(
        _schema_validator().iter_errors(_shorten_mesh_lists(d)))
    if error is not None:
        parts, message = _schema_message(error)
        raise SceneError(*_locate(d, parts), message)


# ----------------------------------------------------------------------------------------
# Building the objects from a (schema-valid) document
# ----------------------------------------------------------------------------------------

def _per_band(label: str, fld: str, value: Any, nbands: int) -> np.ndarray:
    """A per-band value as float64 (nbands,): a single number is broadcast to all bands."""
    if isinstance(value, list):
        if len(value) != nbands:
            raise SceneError(label, fld, f"has {_entries(len(value))} but the scene "
                                         f"has {nbands} band(s)")
        return np.array(value, dtype=np.float64)
    return np.full(nbands, float(value))


def _only_for(label: str, d: dict, keys, what: str, prefix: str = "") -> None:
    """Reject keys that do not belong to this type of object."""
    for key in keys:
        if key in d:
            raise SceneError(label, f"{prefix}{key}", f"only allowed for {what}")


def _read_mesh(label: str, d: dict, base_dir: Path, prefix: str = "") -> TriangleMesh:
    """The mesh of an object: inline ``vertices``/``triangles`` or a ``file``, transformed."""
    if "file" in d:
        if "vertices" in d:
            raise SceneError(label, f"{prefix}file", "give either 'file' or 'vertices' and "
                                                     "'triangles', not both")
        vertices, triangles = _read_mesh_file(label, f"{prefix}file", base_dir / d["file"])
    elif "vertices" in d:
        try:
            vertices = np.array(d["vertices"], dtype=np.float64).reshape(-1, 3)
        except (ValueError, TypeError, OverflowError) as exc:
            raise SceneError(label, f"{prefix}vertices", f"must be a list of [x, y, z] numbers ({exc})") from exc
        try:
            triangles = np.array(d["triangles"], dtype=np.int64).reshape(-1, 3)
        except OverflowError as exc:
            raise SceneError(label, f"{prefix}triangles", "a vertex index is beyond 2^63 - 1: "
                                                          "indices run from 0 to the number of "
                                                          "vertices - 1") from exc
        except (ValueError, TypeError) as exc:
            raise SceneError(label, f"{prefix}triangles", f"must be a list of [i, j, k] vertex "
                                                          f"indices ({exc})") from exc
    else:
        raise SceneError(label, f"{prefix}vertices", "a mesh needs 'vertices' and 'triangles', "
                                                     "or 'file'")
    if "transform" in d:
        vertices, triangles = _apply_transform(label, f"{prefix}transform", d["transform"],
                                               vertices, triangles)
    return TriangleMesh(vertices, triangles)


def _read_mesh_file(label: str, fld: str, path: Path) -> tuple[np.ndarray, np.ndarray]:
    import trimesh  # imported here: loading trimesh is slow and only mesh files need it

    if path.is_dir():
        raise SceneError(label, fld, f"is a folder, not a mesh file: {path}")
    if not path.exists():
        raise SceneError(label, fld, f"mesh file not found: {path}")
    if not path.is_file():
        raise SceneError(label, fld, f"is not a regular file (a device or a pipe): {path}")
    try:
        tm = trimesh.load(str(path), force="mesh")
        vertices = np.array(tm.vertices, dtype=np.float64).reshape(-1, 3)
        triangles = np.array(tm.faces, dtype=np.int64).reshape(-1, 3)
    except Exception as exc:  # trimesh raises many kinds of errors for bad files
        raise SceneError(label, fld, f"cannot read mesh file {path}: {exc}") from exc
    # A trimesh object holds reference cycles: without a collection its caches (over 100
    # bytes per triangle) would stay resident until the garbage collector happens to run.
    del tm
    gc.collect()
    if len(triangles) == 0:
        raise SceneError(label, fld, f"mesh file {path} contains no triangles")
    return vertices, triangles


def _apply_transform(label, fld, matrix, vertices, triangles):
    """Apply a 4x4 row-major affine matrix to column-vector vertices."""
    m = np.array(matrix, dtype=np.float64)
    if not np.all(np.isfinite(m)):
        raise SceneError(label, fld, "must contain only finite numbers")
    if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise SceneError(label, fld, f"must be affine (last row [0, 0, 0, 1]), got last row "
                                     f"{m[3].tolist()}")
    det = np.linalg.det(m[:3, :3])
    if det == 0.0:
        raise SceneError(label, fld, "is singular (determinant 0)")
    vertices = vertices @ m[:3, :3].T + m[:3, 3]
    # A mirroring transform would turn outward normals inward: reverse the winding.
    if det < 0:
        triangles = triangles[:, ::-1].copy()
    return vertices, triangles


def _read_phase(d: dict) -> PhaseFunction:
    params = {k: float(v) for k, v in d.items() if k != "type"}
    return PhaseFunction(d["type"], params)


def _read_iops(label: str, d: dict, nbands: int, fld: str = "iops") -> IOPs:
    absorption = _per_band(label, f"{fld}.absorption", d["absorption"], nbands)
    if "b" in d:
        if "scattering" in d:
            raise SceneError(label, f"{fld}.b", "give either 'scattering' or the shorthand 'b' "
                                                "and 'phase', not both")
        components = [ScatteringComponent(_per_band(label, f"{fld}.b", d["b"], nbands),
                                          _read_phase(d["phase"]))]
    else:
        components = [
            ScatteringComponent(_per_band(label, f"{fld}.scattering[{i}].b", c["b"], nbands),
                                _read_phase(c["phase"]))
            for i, c in enumerate(d.get("scattering", []))]
    return IOPs(absorption, components)


def _read_profile(label: str, d: dict, bands: list, base_dir: Path,
                  prefix: str = "iop_profile") -> IOPProfile:
    """Layers from explicit 'iops' or from an 'iop_model' each; layers from models are aligned
    on the union of the phase functions (photic.profiles.align_components)."""
    z_top = [float(z) for z in d["z_top"]]
    layers, modelled = [], False
    for i, layer in enumerate(d["layers"]):
        if "iop_model" in layer:
            from .iop_models import iops_from_model
            modelled = True
            layers.append(iops_from_model(layer["iop_model"], bands, obj=label,
                                          prefix=f"{prefix}.layers[{i}].iop_model.",
                                          base_dir=base_dir))
        else:
            layers.append(_read_iops(label, layer["iops"], len(bands),
                                     f"{prefix}.layers[{i}].iops"))
    if modelled:
        from .profiles import align_components
        layers = align_components(layers)
    return IOPProfile(z_top, layers)


def _read_grid(label: str, d: dict, bands: list, base_dir: Path) -> IOPGrid:
    """Base and unit IOPs (explicit or from a model), the box, and the density: inline nested
    lists or the key 'density' of a numpy .npz 'file' (relative to the scene file). Further
    density fields in 'fields': each a 'name', its 'unit' IOPs and its densities, inline
    ('density') or the array 'key' of the grid's .npz file."""
    def iops(spec, where):
        if "iop_model" in spec:
            from .iop_models import iops_from_model
            return iops_from_model(spec["iop_model"], bands, obj=label,
                                   prefix=f"{where}.iop_model.", base_dir=base_dir)
        return _read_iops(label, spec["iops"], len(bands), f"{where}.iops")
    extra = d.get("fields", [])
    if not isinstance(extra, list) or not all(isinstance(f, dict) for f in extra):
        raise SceneError(label, "iop_grid.fields", "must be a list of objects {name, unit, "
                                                   "density or key}")
    if "iop_profile" in d["base"]:
        base = _read_profile(label, d["base"]["iop_profile"], bands, base_dir, "iop_grid.base.iop_profile")
    else:
        base = iops(d["base"], "iop_grid.base")
    units = [iops(d["unit"], "iop_grid.unit")] + [iops(f["unit"], f"iop_grid.fields[{i}].unit")
                                                  for i, f in enumerate(extra)]
    modelled = any("iop_model" in u for u in [d["unit"]] + [f["unit"] for f in extra])
    if isinstance(base, IOPProfile):
        modelled = modelled or any("iop_model" in x for x in d["base"]["iop_profile"].get("layers", []))
        if modelled:  # every layer and unit on one set of components
            from .profiles import align_components
            aligned = align_components(list(base.layers) + units)
            base, units = IOPProfile(base.z_top, aligned[:len(base.layers)]), aligned[len(base.layers):]
    elif modelled or "iop_model" in d["base"]:  # one set of components for all
        from .profiles import align_components
        base, *units = align_components([base] + units)
    if ("file" in d) == ("density" in d):
        raise SceneError(label, "iop_grid", "give either 'density' (nested lists) or 'file' "
                                            "(a .npz holding 'density')")
    file = None
    arrays = {}  # the .npz file's arrays that the fields name
    if "file" in d:
        path = base_dir / d["file"]
        wanted = ["density"] + [f["key"] for f in extra if "key" in f]
        try:
            z = np.load(path, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise SceneError(label, "iop_grid.file", f"{path} holds one array (a .npy): a .npz "
                                                         f"with an array 'density' is needed "
                                                         f"(numpy.savez(file, density=array))")
            with z:
                for i, key in enumerate(wanted):
                    if key not in z:
                        fld = "iop_grid.file" if i == 0 else f"iop_grid.fields[{i - 1}].key"
                        raise SceneError(label, fld, f"{path} has no array {key!r} "
                                                     f"(has: {', '.join(z.files) or 'none'})")
                    arrays[key] = np.asarray(z[key])
        except (OSError, ValueError, EOFError) as e:
            raise SceneError(label, "iop_grid.file", f"cannot read {path}: {e}") from None
        density = arrays["density"]
        file = str(path.resolve())
    else:
        density = _read_density(label, d["density"], "iop_grid.density")
    fields = []
    for i, (f, unit) in enumerate(zip(extra, units[1:])):
        where = f"iop_grid.fields[{i}]"
        if ("key" in f) == ("density" in f):
            raise SceneError(label, where, "give either 'density' (nested lists) or 'key' (an "
                                           "array of the grid's .npz 'file')")
        if "key" in f and file is None:
            raise SceneError(label, f"{where}.key", "names an array of the grid's .npz 'file', "
                                                     "but the grid has no 'file'")
        rho = arrays[f["key"]] if "key" in f else _read_density(label, f["density"], f"{where}.density")
        fields.append(GridField(f["name"], unit, rho, f.get("key")))
    return IOPGrid(base, units[0], d["origin"], d["size"], density, file, fields)


def _read_density(label: str, value: Any, fld: str) -> np.ndarray:
    try:
        return np.array(value, dtype=np.float32)
    except (TypeError, ValueError):
        raise SceneError(label, fld, "must be nested lists of numbers [x][y][z] with equal "
                                     "lengths") from None


def _read_water(label: str, d: dict, bands: list, base_dir: Path) -> WaterBody:
    nbands = len(bands)
    if "iop_model" in d:
        from .iop_models import iops_from_model
        iops = iops_from_model(d["iop_model"], bands, obj=label, prefix="iop_model.",
                               base_dir=base_dir)
    elif "iop_profile" in d:
        iops = _read_profile(label, d["iop_profile"], bands, base_dir)
    elif "iop_grid" in d:
        iops = _read_grid(label, d["iop_grid"], bands, base_dir)
    else:
        iops = _read_iops(label, d["iops"], nbands)
    ior = float(d.get("ior", 1.34))
    if d["type"] == "mesh":
        _only_for(label, d, ("surface", "bottom"), "water of type 'ocean'")
        return WaterBody(d["name"], "mesh", iops, ior, mesh=_read_mesh(label, d, base_dir))
    _only_for(label, d, ("vertices", "triangles", "file", "transform"), "water of type 'mesh'")
    s = d["surface"]
    if s["kind"] != "waves":
        _only_for(label, s, _WAVE_KEYS, "surface kind 'waves'", "surface.")
    if s["kind"] != "plugin":
        _only_for(label, s, ("plugin", "params"), "surface kind 'plugin'", "surface.")
    else:
        _only_for(label, s, ("vertices", "triangles", "file", "transform", "period", "z"),
                  "surface kind 'patch' (a plugin's patch carries its own heights)", "surface.")
        return _finish_ocean(label, d, iops, ior, _plugin_surface(label, s))
    if s["kind"] in ("flat", "waves"):
        _only_for(label, s, ("vertices", "triangles", "file", "transform", "period"),
                  "surface kind 'patch'", "surface.")
    if s["kind"] == "flat":
        surface = OceanSurface("flat", float(s.get("z", 0.0)))
    elif s["kind"] == "waves":
        surface = OceanSurface("waves", float(s.get("z", 0.0)), waves=_read_wave_model(s))
    else:
        _only_for(label, s, ("z",), "surface kind 'flat' (a patch's z is the mean height of "
                                    "its vertices)", "surface.")
        surface = OceanSurface("patch", mesh=_read_mesh(label, s, base_dir, "surface."),
                               period=tuple(float(p) for p in s["period"]))
    return _finish_ocean(label, d, iops, ior, surface)


def _plugin_surface(label: str, s: dict) -> OceanSurface:
    """A surface patch made by a wave-model plugin (photic.plugins)."""
    from . import plugins
    name = s.get("plugin")
    fn = plugins.load("wave", name) if isinstance(name, str) else None
    if fn is None:
        installed = ", ".join(sorted(plugins.available("wave"))) or "none"
        raise SceneError(label, "surface.plugin", f"no wave-model plugin {_show(name)} is "
                                                  f"installed (installed: {installed})")
    params = dict(s.get("params", {}))
    try:
        vertices, triangles, normals, period = fn(params)
    except ValueError as exc:
        raise SceneError(label, "surface.params", f"plugin '{name}': {exc}") from None
    return OceanSurface("patch", mesh=TriangleMesh(np.asarray(vertices, float), triangles),
                        period=tuple(float(p) for p in period),
                        normals=None if normals is None else np.asarray(normals, float),
                        plugin={"plugin": name, "params": params})


def _finish_ocean(label: str, d: dict, iops, ior: float, surface: OceanSurface) -> WaterBody:
    s = d["surface"]
    if s.get("roughness") is not None:
        r = s["roughness"]
        surface.roughness = SurfaceRoughness(float(r["wind_speed"]), bool(r.get("anisotropic", False)),
                                             None if r.get("wind_direction_deg") is None
                                             else float(r["wind_direction_deg"]))
    bottom = d.get("bottom")
    return WaterBody(d["name"], "ocean", iops, ior, surface=surface,
                     bottom_depth=float(bottom["depth"]) if bottom else None,
                     bottom_material=bottom["material"] if bottom else None)


# Keys of a "waves" surface: the fields of photic.waves.WaveModel.
_WAVE_KEYS = ("spectrum", "wind_speed", "wind_direction_deg", "patch_size_m", "resolution",
              "seed", "time_s", "choppiness", "water_depth_m", "fetch_m", "gamma", "spreading",
              "spreading_s", "sinusoids")
_SINUSOID_KEYS = ("amplitude_m", "wavelength_m", "direction_deg", "phase_rad")


def _read_wave_model(s: dict) -> Any:
    from .waves import WaveModel

    values = {key: s[key] for key in _WAVE_KEYS if key in s}
    if "sinusoids" in values:
        values["sinusoids"] = tuple(
            (float(c["amplitude_m"]), float(c["wavelength_m"]),
             float(c.get("direction_deg", 0.0)), float(c.get("phase_rad", 0.0)))
            for c in values["sinusoids"])
    for key in ("patch_size_m", "resolution"):
        if key in values:
            values[key] = tuple(values[key])
    return WaveModel(**values)


def _wave_model_to_dict(model: Any) -> dict:
    d: dict[str, Any] = {}
    for key in _WAVE_KEYS:
        value = getattr(model, key)
        if key == "sinusoids":
            if model.spectrum != "sinusoids":
                continue
            value = [dict(zip(_SINUSOID_KEYS, map(float, c))) for c in value]
        elif key in ("patch_size_m",):
            value = [float(x) for x in value]
        elif key == "resolution":
            value = [int(x) for x in value]
        elif key == "seed":
            value = int(value)
        elif key in ("fetch_m", "water_depth_m") and value is None:
            continue
        elif isinstance(value, numbers.Real) and not isinstance(value, bool):
            value = float(value)
        d[key] = value
    return d


def _read_sky(d: dict, nbands: int) -> Sky:
    kind = d["type"]
    if kind == "black":
        _only_for("sky", d, ("radiance", "irradiance", "full_sphere"), "sky types 'uniform' and 'cardioidal'")
        return Sky("black")
    full = bool(d.get("full_sphere", False))
    if ("radiance" in d) == ("irradiance" in d):
        raise SceneError("sky", "radiance", f"a '{kind}' sky needs exactly one of 'radiance' "
                                            f"and 'irradiance'")
    if kind != "harrison_coombes":
        _only_for("sky", d, ("cloud_fraction",), "sky type 'harrison_coombes'")
    cloud = float(d.get("cloud_fraction", 0.0))
    if "radiance" in d:
        return Sky(kind, _per_band("sky", "radiance", d["radiance"], nbands), full, cloud)
    irradiance = _per_band("sky", "irradiance", d["irradiance"], nbands)
    if kind in ("uniform", "harrison_coombes"):
        return Sky(kind, irradiance / math.pi, full, cloud)  # E = pi L0 (the table is normalised)
    return Sky(kind, 3.0 * irradiance / (7.0 * math.pi))  # E = 7 pi L0 / 3


def _read_camera(label: str, d: dict) -> Camera:
    position = np.array(d["position"], dtype=np.float64)
    if ("look_at" in d) == ("direction" in d):
        raise SceneError(label, "direction", "give exactly one of 'look_at' and 'direction'")
    if "look_at" in d:
        direction = np.array(d["look_at"], dtype=np.float64) - position
        if not np.any(direction):
            raise SceneError(label, "look_at", "must differ from 'position'")
    else:
        direction = np.array(d["direction"], dtype=np.float64)
    flt = d.get("filter", {"type": "box"})
    return Camera(
        d["name"], d["type"], position, direction, up=np.array(d.get("up", [0, 0, 1]), float),
        fov_deg=float(d.get("fov_deg", 40.0)), ortho_width=float(d.get("ortho_width", 2.0)),
        resolution=tuple(int(n) for n in d.get("resolution", (64, 64))),
        filter_type=flt["type"],
        filter_width_px=float(flt.get("width_px", _FILTER_DEFAULT_WIDTH[flt["type"]])),
        shift=tuple(float(x) for x in d.get("shift", (0.0, 0.0))),
        clip_start=float(d.get("clip_start", 0.0)))


def _read_radiometer(d: dict) -> Radiometer:
    return Radiometer(d["name"], d["quantity"], np.array(d["position"], dtype=np.float64),
                      direction=np.array(d.get("direction", [0, 0, -1]), dtype=np.float64),
                      half_angle_deg=float(d.get("half_angle_deg", 12.9)),
                      polar_bins=int(d.get("polar_bins", 18)),
                      azimuth_bins=int(d.get("azimuth_bins", 24)))


def _read_radiometer_array(label: str, d: dict) -> RadiometerArray:
    if ("positions" in d) == ("line" in d):
        raise SceneError(label, "positions", "give exactly one of 'positions' and 'line'")
    spec = d["positions"] if "positions" in d else d["line"]
    if isinstance(spec, dict):
        count = int(spec["count"])
        if not 1 <= count <= MAX_ARRAY_RADIOMETERS:  # (before the points are made)
            raise SceneError(label, "line.count", f"must be in 1..{MAX_ARRAY_RADIOMETERS:,}, got {count:,}")
        positions = np.linspace(spec["start"], spec["stop"], count)
    else:
        positions = np.array(spec, dtype=np.float64)
    return RadiometerArray(
        d["name"], list(d["quantities"]), positions,
        direction=np.array(d["direction"], dtype=np.float64) if "direction" in d else None,
        half_angle_deg=float(d["half_angle_deg"]) if "half_angle_deg" in d else None)


def _build_scene(d: dict, base_dir: Path) -> Scene:
    bands = [Band(b["name"], float(b["center_nm"]), float(b["width_nm"]))
             for b in d.get("bands", [])] or _default_bands()
    nb = len(bands)
    materials = {name: Material(name, _per_band(f"material '{name}'", "reflectance",
                                                m["reflectance"], nb))
                 for name, m in d.get("materials", {}).items()}
    meshes = []
    for i, m in enumerate(d.get("meshes", [])):
        label = _label("mesh", m["name"], i)
        meshes.append(MeshObject(m["name"], _read_mesh(label, m, base_dir), m["material"]))
    water = [_read_water(_label("water", w["name"], i), w, bands, base_dir)
             for i, w in enumerate(d.get("water", []))]
    sun = None
    if d.get("sun") is not None:
        s = d["sun"]
        sun = Sun(float(s["zenith_deg"]), float(s["azimuth_deg"]),
                  _per_band("sun", "irradiance", s["irradiance"], nb),
                  float(s.get("angular_diameter_deg", 0.53)))
    settings = Settings(**{k: (v if k in ("integrator", "forward_cone_deg") else
                               None if (k in ("target_error", "noise_threshold") and v is None) else
                               float(v) if k in ("target_error", "noise_threshold") else int(v))
                           for k, v in d.get("settings", {}).items()})
    return Scene(
        name=d.get("name", "scene"), bands=bands, materials=materials, meshes=meshes,
        water=water, sun=sun, sky=_read_sky(d.get("sky", {"type": "black"}), nb),
        cameras=[_read_camera(_label("camera", c["name"], i), c)
                 for i, c in enumerate(d.get("cameras", []))],
        radiometers=[_read_radiometer(r) for r in d.get("radiometers", [])],
        radiometer_arrays=[_read_radiometer_array(_label("radiometer_array", a["name"], i), a)
                           for i, a in enumerate(d.get("radiometer_arrays", []))],
        settings=settings)


# ----------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------

def _list(a: Any) -> list:
    return np.asarray(a).tolist()


def _mesh_to_dict(mesh: TriangleMesh) -> dict:
    return {"vertices": _list(mesh.vertices), "triangles": _list(mesh.triangles)}


def _phase_to_dict(p: PhaseFunction) -> dict:
    return {"type": p.type, **{k: float(v) for k, v in p.params.items()}}


def _profile_to_dict(p: IOPProfile) -> dict:
    return {"z_top": _list(p.z_top), "layers": [{"iops": _iops_to_dict(x)} for x in p.layers]}


def _iops_to_dict(iops: IOPs) -> dict:
    return {"absorption": _list(iops.absorption),
            "scattering": [{"b": _list(c.b), "phase": _phase_to_dict(c.phase)}
                           for c in iops.scattering]}


def _water_to_dict(w: WaterBody) -> dict:
    d: dict[str, Any] = {"name": w.name, "type": w.type, "ior": float(w.ior)}
    if isinstance(w.iops, IOPProfile):
        d["iop_profile"] = _profile_to_dict(w.iops)
    elif isinstance(w.iops, IOPGrid):
        g = w.iops
        base = ({"iop_profile": _profile_to_dict(g.iops)} if isinstance(g.iops, IOPProfile)
                else {"iops": _iops_to_dict(g.iops)})
        d["iop_grid"] = {"base": base,
                         "unit": {"iops": _iops_to_dict(g.unit)},
                         "origin": _list(g.origin), "size": _list(g.size)}
        if g.file is not None:
            d["iop_grid"]["file"] = g.file
        else:
            d["iop_grid"]["density"] = np.asarray(g.density, dtype=np.float64).tolist()
        if g.extra_fields:
            d["iop_grid"]["fields"] = [
                {"name": f.name, "unit": {"iops": _iops_to_dict(f.unit)},
                 **({"key": f.key} if f.key is not None and g.file is not None
                    else {"density": np.asarray(f.density, dtype=np.float64).tolist()})}
                for f in g.extra_fields]
    else:
        d["iops"] = _iops_to_dict(w.iops)
    if w.type == "mesh":
        d.update(_mesh_to_dict(w.mesh))
        return d
    s = w.surface
    if s.kind == "flat":
        d["surface"] = {"kind": "flat", "z": float(s.z)}
    elif s.kind == "waves":
        d["surface"] = {"kind": "waves", "z": float(s.z), **_wave_model_to_dict(s.waves)}
    elif s.plugin is not None:
        d["surface"] = {"kind": "plugin", **s.plugin}
    else:
        d["surface"] = {"kind": "patch", **_mesh_to_dict(s.mesh),
                        "period": [float(p) for p in s.period]}
    if s.roughness is not None:
        d["surface"]["roughness"] = {"wind_speed": float(s.roughness.wind_speed),
                                     "anisotropic": bool(s.roughness.anisotropic)}
        if s.roughness.wind_direction_deg is not None:
            d["surface"]["roughness"]["wind_direction_deg"] = float(s.roughness.wind_direction_deg)
    d["bottom"] = None if w.bottom_depth is None else {"depth": float(w.bottom_depth),
                                                       "material": w.bottom_material}
    return d


def _scene_to_dict(s: Scene) -> dict:
    sky: dict[str, Any] = {"type": s.sky.type}
    if s.sky.radiance_scale is not None:
        # L0 itself is written (not an irradiance) so that reading it back is bit-exact.
        sky["radiance"] = _list(s.sky.radiance_scale)
    if s.sky.full_sphere:
        sky["full_sphere"] = True
    if s.sky.cloud_fraction:
        sky["cloud_fraction"] = float(s.sky.cloud_fraction)
    arrays = []
    for a in s.radiometer_arrays:
        item: dict[str, Any] = {"name": a.name, "quantities": list(a.quantities),
                                "positions": _list(a.positions)}
        if a.direction is not None:
            item["direction"] = _list(a.direction)
        if a.half_angle_deg is not None:
            item["half_angle_deg"] = float(a.half_angle_deg)
        arrays.append(item)
    return {
        "photic_scene": FORMAT_VERSION,
        "name": s.name,
        "bands": [{"name": b.name, "center_nm": float(b.center_nm), "width_nm": float(b.width_nm)}
                  for b in s.bands],
        "materials": {k: {"type": "lambertian", "reflectance": _list(m.reflectance)}
                      for k, m in s.materials.items()},
        "meshes": [{"name": m.name, "material": m.material, **_mesh_to_dict(m.mesh)}
                   for m in s.meshes],
        "water": [_water_to_dict(w) for w in s.water],
        "sun": None if s.sun is None else {
            "zenith_deg": float(s.sun.zenith_deg), "azimuth_deg": float(s.sun.azimuth_deg),
            "irradiance": _list(s.sun.irradiance),
            "angular_diameter_deg": float(s.sun.angular_diameter_deg)},
        "sky": sky,
        "cameras": [{"name": c.name, "type": c.type, "position": _list(c.position),
                     "direction": _list(c.direction), "up": _list(c.up),
                     "fov_deg": float(c.fov_deg), "ortho_width": float(c.ortho_width),
                     "resolution": [int(n) for n in c.resolution],
                     "filter": {"type": c.filter_type, "width_px": float(c.filter_width_px)},
                     "shift": [float(x) for x in c.shift], "clip_start": float(c.clip_start)}
                    for c in s.cameras],
        "radiometers": [{"name": r.name, "quantity": r.quantity, "position": _list(r.position),
                         "direction": _list(r.direction),
                         "half_angle_deg": float(r.half_angle_deg),
                         "polar_bins": int(r.polar_bins), "azimuth_bins": int(r.azimuth_bins)}
                        for r in s.radiometers],
        "radiometer_arrays": arrays,
        "settings": {"integrator": s.settings.integrator, "samples": int(s.settings.samples),
                     "radiometer_samples": int(s.settings.radiometer_samples),
                     "seed": int(s.settings.seed), "max_depth": int(s.settings.max_depth),
                     "threads": int(s.settings.threads),
                     "forward_cone_deg": s.settings.forward_cone_deg,
                     "beam_max_level": int(s.settings.beam_max_level),
                     **({} if s.settings.target_error is None else
                        {"target_error": float(s.settings.target_error)}),
                     **({} if s.settings.noise_threshold is None else
                        {"noise_threshold": float(s.settings.noise_threshold),
                         "adaptive_min_samples": int(s.settings.adaptive_min_samples)})},
    }


def _dumps(obj: Any, level: int = 0) -> str:
    """JSON text with lists of numbers on one line (so meshes stay one vertex per line)."""
    inner = "  " * (level + 1)
    if isinstance(obj, dict) and obj:
        items = [f"{inner}{json.dumps(k)}: {_dumps(v, level + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + "  " * level + "}"
    if isinstance(obj, list) and any(isinstance(x, (dict, list)) for x in obj):
        return "[\n" + ",\n".join(inner + _dumps(x, level + 1) for x in obj) + "\n" + \
            "  " * level + "]"
    return json.dumps(obj)


# ----------------------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------------------

def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file; relative mesh paths are relative to its directory.

    Raises
    ------
    SceneError
        If the file cannot be read, is not valid JSON, or the scene is invalid.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError("scene", str(path), f"cannot read scene file: {exc}") from exc
    try:
        d = json.loads(text, object_pairs_hook=_no_duplicate_keys)
    except json.JSONDecodeError as exc:
        raise SceneError("scene", str(path), f"invalid JSON at line {exc.lineno} column "
                                             f"{exc.colno}: {exc.msg}") from exc
    except _DuplicateKey as exc:
        raise SceneError("scene", str(path), f"the key {exc.args[0]!r} appears twice in one "
                                             f"object (which value is meant?)") from exc
    except RecursionError as exc:
        raise SceneError("scene", str(path), "JSON nested too deeply (a scene needs a few "
                                             "levels)") from exc
    return Scene.from_dict(d, base_dir=path.resolve().parent)


class _DuplicateKey(ValueError):
    pass


def _no_duplicate_keys(pairs: list) -> dict:
    """A JSON object as a dict, refusing a key given twice (json keeps the last silently)."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write a scene as JSON (meshes inline)."""
    Path(path).write_text(_dumps(scene.to_dict()) + "\n", encoding="utf-8")
