"""The scene's data classes (bands, materials, meshes, water bodies and their IOPs, sun, sky,
cameras, radiometers, settings, ``Scene``). Validation, reading and writing live in their
own modules; ``photic.scene`` attaches ``Scene.validate``, ``from_dict`` and ``to_dict``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .checks import _ArrayEq, _as_floats, _unit


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
class MaterialTexture(_ArrayEq):
    """A reflectance texture: ``image`` (height, width, bands) in [0, 1], row 0 at texture
    coordinate v = 0 (the bottom), column 0 at u = 0; looked up bilinearly at the texture
    coordinates of the meshes that use the material (``MeshObject.uv``), repeating beyond
    [0, 1] (``wrap`` ``"repeat"``) or holding the edge texels (``"clamp"``); ``interpolation``
    ``"closest"`` takes the nearest texel instead."""

    image: np.ndarray
    wrap: str = "repeat"
    interpolation: str = "linear"

    def __post_init__(self):
        if not isinstance(self.image, np.ndarray) or self.image.dtype != np.float32:
            try:
                self.image = np.asarray(self.image, dtype=np.float32)
            except (TypeError, ValueError):
                pass


@dataclass(eq=False)
class Material(_ArrayEq):
    """A Lambertian material: reflectance per band in [0, 1]; with a ``texture`` the
    reflectance varies over the surface (``reflectance`` is then the texture's mean, used where
    a mesh has no texture coordinates). ``emission``: radiance the surface emits from both
    faces per band (W m^-2 sr^-1 per unit of the band's spectrum), or None."""

    name: str
    reflectance: np.ndarray
    emission: np.ndarray | None = None
    texture: MaterialTexture | None = None

    def __post_init__(self):
        self.reflectance = _as_floats(self.reflectance)
        if self.emission is not None:
            self.emission = _as_floats(self.emission)


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
    """An opaque object: a mesh and the name of its material; ``uv``: texture coordinates
    (triangles, 3, 2) at each triangle's corners, for a textured material (None: none).

    ``instances``: None (the mesh stands where its vertices are), or the copies of it that
    stand in the scene, as affine transforms (N, 3, 4) float64, rows [R | t]: a copy's vertex
    is R v + t (m). The mesh is stored once and traced as one Embree instance array (a
    two-level BVH), so N copies cost one mesh and N transforms, not N meshes. A transform with
    a negative determinant mirrors its copy, whose faces keep facing outwards (as ``transform``
    in a scene file does). A (N, 4, 4) array with last rows [0, 0, 0, 1] is taken too."""

    name: str
    mesh: TriangleMesh
    material: str
    uv: np.ndarray | None = None
    instances: np.ndarray | None = None

    def __post_init__(self):
        if self.uv is not None and not (isinstance(self.uv, np.ndarray) and self.uv.dtype == np.float32):
            try:
                self.uv = np.asarray(self.uv, dtype=np.float32)
            except (TypeError, ValueError):
                pass
        if self.instances is not None:
            try:
                m = np.asarray(self.instances, dtype=np.float64)
            except (TypeError, ValueError):
                return  # (validation names the field)
            if m.ndim == 3 and m.shape[1:] == (4, 4) and np.array_equal(
                    m[:, 3], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (len(m), 4))):
                m = m[:, :3]
            self.instances = np.ascontiguousarray(m)

    @property
    def copies(self) -> int:
        """How many times the mesh stands in the scene (1 without instances)."""
        return 1 if self.instances is None else len(self.instances)

    def flattened(self) -> MeshObject:
        """The same object with every instance's triangles in the world, as one mesh (what
        instancing saves; the reference the instanced renders are tested against)."""
        if self.instances is None:
            return self
        v = np.asarray(self.mesh.vertices, np.float64)
        t = np.asarray(self.mesh.triangles, np.int64)
        vs, ts, uvs = [], [], []
        for k, m in enumerate(self.instances):
            vs.append(v @ m[:, :3].T + m[:, 3])
            mirrored = np.linalg.det(m[:, :3]) < 0  # keep the faces outward, as transform does
            ts.append((t[:, ::-1] if mirrored else t) + k * len(v))
            if self.uv is not None:
                uvs.append(self.uv[:, ::-1] if mirrored else self.uv)
        uv = np.concatenate(uvs) if self.uv is not None else None
        return MeshObject(self.name, TriangleMesh(np.concatenate(vs), np.concatenate(ts)), self.material, uv)


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
        from ..surface import slope_variances
        r = self.roughness
        direction = r.wind_direction_deg
        if direction is None:
            direction = self.waves.wind_direction_deg if self.kind == "waves" else 0.0
        resolved = (0.0, 0.0)
        if self.kind == "waves":
            from ..waves import slope_variance_along
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
        from ..waves import surface_patch

        vertices, triangles, normals = surface_patch(self.waves, float(self.z))
        return TriangleMesh(vertices, triangles), tuple(self.waves.patch_size_m), normals


@dataclass(eq=False)
class ChlorophyllFluorescence(_ArrayEq):
    """Fluorescence of a water body's phytoplankton (photic.inelastic): of the light its
    chlorophyll absorbs between 370 and 690 nm (``absorption``: the phytoplankton's
    absorption coefficient per band, m^-1, part of the water's own absorption; one spectrum,
    or one per layer of an ``iop_profile``), the ``quantum_yield`` share of photons is
    re-emitted isotropically in a Gaussian around ``peak_nm`` of full width ``fwhm_nm``."""

    absorption: np.ndarray
    quantum_yield: float = 0.02
    peak_nm: float = 685.0
    fwhm_nm: float = 25.0

    def __post_init__(self):
        self.absorption = np.asarray(self.absorption, dtype=np.float64)


@dataclass(eq=False)
class CDOMFluorescence(_ArrayEq):
    """Fluorescence of a water body's CDOM (photic.inelastic): of the light the CDOM absorbs
    (``absorption``: a_CDOM per band, m^-1, part of the water's own absorption; one spectrum,
    or one per layer of an ``iop_profile``), photons are re-emitted isotropically with Hawes'
    (1992) spectral fluorescence quantum efficiency of fulvic acid FA7 (HydroLight's default),
    times ``efficiency_scale`` (1: Hawes' values)."""

    absorption: np.ndarray
    efficiency_scale: float = 1.0

    def __post_init__(self):
        self.absorption = np.asarray(self.absorption, dtype=np.float64)


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
    fluorescence: ChlorophyllFluorescence | None = None  # chlorophyll fluorescence, or none
    cdom_fluorescence: CDOMFluorescence | None = None  # CDOM fluorescence, or none


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
    L(theta) = L0 (1 + 2 cos theta), theta the zenith angle; ``environment`` has
    L = L0 table(theta, phi) per band, ``table`` (n_theta, n_phi, bands) on the nodes
    theta_i = i / (n_theta - 1) 90 deg and phi_j = j / n_phi 360 deg (azimuth from +x towards
    +y), interpolated bilinearly (an environment map's upper half); ``black`` has None.
    """

    type: str
    radiance_scale: np.ndarray | None = None
    full_sphere: bool = False  # uniform only: radiance L0 below the horizon too (furnace tests)
    cloud_fraction: float = 0.0  # harrison_coombes only: 0 clear .. 1 overcast
    table: np.ndarray | None = None  # environment only: (n_theta, n_phi, bands) relative radiance

    def __post_init__(self):
        self.radiance_scale = _as_floats(self.radiance_scale)
        if self.table is not None:
            self.table = _as_floats(self.table)


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
    # beams spread over the sun's disk, built once for its centre (False: a direction drawn
    # in the disk per pass, the average doing the spreading)
    sun_disk_blur: bool = True
    # Raman scattering by water into longer-wavelength bands (photic.inelastic): true, false,
    # or "auto": on where the scene's bands can receive it (inelastic.raman_auto)
    raman: bool | str = "auto"
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


