"""Building the objects from a (schema-valid) document: ``scene_from_dict`` (``Scene.from_dict``),
with per-band broadcasting, mesh files, IOP models, profiles, grids and wave models.
"""
from __future__ import annotations

import gc
import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from .checks import (
    FORMAT_VERSION, MAX_ARRAY_RADIOMETERS, SceneError, _FILTER_DEFAULT_WIDTH, _entries,
    _label, _show,
)
from .model import (
    Band, Camera, GridField, IOPGrid, IOPProfile, IOPs, Material, MaterialTexture, MeshObject, OceanSurface,
    PhaseFunction, Radiometer, RadiometerArray, ScatteringComponent, Scene, Settings, Sky,
    Sun, SurfaceRoughness, TriangleMesh, WaterBody, _default_bands, ChlorophyllFluorescence, CDOMFluorescence,
)
from .schema_errors import _check_schema


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
            from ..iop_models import iops_from_model
            modelled = True
            layers.append(iops_from_model(layer["iop_model"], bands, obj=label,
                                          prefix=f"{prefix}.layers[{i}].iop_model.",
                                          base_dir=base_dir))
        else:
            layers.append(_read_iops(label, layer["iops"], len(bands),
                                     f"{prefix}.layers[{i}].iops"))
    if modelled:
        from ..profiles import align_components
        layers = align_components(layers)
    return IOPProfile(z_top, layers)


def _read_grid(label: str, d: dict, bands: list, base_dir: Path) -> IOPGrid:
    """Base and unit IOPs (explicit or from a model), the box, and the density: inline nested
    lists or the key 'density' of a numpy .npz 'file' (relative to the scene file). Further
    density fields in 'fields': each a 'name', its 'unit' IOPs and its densities, inline
    ('density') or the array 'key' of the grid's .npz file."""
    def iops(spec, where):
        if "iop_model" in spec:
            from ..iop_models import iops_from_model
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
            from ..profiles import align_components
            aligned = align_components(list(base.layers) + units)
            base, units = IOPProfile(base.z_top, aligned[:len(base.layers)]), aligned[len(base.layers):]
    elif modelled or "iop_model" in d["base"]:  # one set of components for all
        from ..profiles import align_components
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
            if path.is_file() and _starts_with(path, b"PK\x03\x04"):  # a .npz: headers first
                from ..safe_io import machine_memory
                from ..safe_io import check_npz
                memory = machine_memory()
                try:
                    check_npz(path, set(wanted), None if memory is None else int(0.5 * memory))
                except ValueError as e:
                    raise SceneError(label, "iop_grid.file", f"{path}: {e}") from None
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
        except SceneError:
            raise
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
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
    w = _read_water_body(label, d, bands, base_dir)
    f = d.get("chlorophyll_fluorescence")
    if f is not None:
        w.fluorescence = ChlorophyllFluorescence(
            _fluorescent_absorption(label, d, "chlorophyll_fluorescence", "phytoplankton", bands, base_dir),
            float(f.get("quantum_yield", 0.02)), float(f.get("peak_nm", 685.0)), float(f.get("fwhm_nm", 25.0)))
    f = d.get("cdom_fluorescence")
    if f is not None:
        w.cdom_fluorescence = CDOMFluorescence(
            _fluorescent_absorption(label, d, "cdom_fluorescence", "cdom", bands, base_dir),
            float(f.get("efficiency_scale", 1.0)))
    return w


def _fluorescent_absorption(label: str, d: dict, fld: str, part: str, bands: list, base_dir: Path) -> np.ndarray:
    """A fluorescence's absorption: given, or (absent) its part of the water's iop_model."""
    f = d[fld]
    if not isinstance(f, dict):
        raise SceneError(label, fld, f"must be an object, got {f!r}")
    if "absorption" in f:
        return np.asarray(f["absorption"], dtype=np.float64)
    if "iop_model" not in d:
        raise SceneError(label, f"{fld}.absorption", "is required unless the water has an 'iop_model' "
                                                    f"(whose {part} absorption it then takes)")
    from ..iop_models import fluorescent_absorption
    return fluorescent_absorption(d["iop_model"], bands, obj=label, prefix="iop_model.",
                                  base_dir=base_dir)[part]


def _read_water_body(label: str, d: dict, bands: list, base_dir: Path) -> WaterBody:
    nbands = len(bands)
    if "iop_model" in d:
        from ..iop_models import iops_from_model
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
    from .. import plugins
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
              "spreading_s", "sinusoids", "mesh_refinement")
_SINUSOID_KEYS = ("amplitude_m", "wavelength_m", "direction_deg", "phase_rad")


def _read_wave_model(s: dict) -> Any:
    from ..waves import WaveModel

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




def _array(label: str, fld: str, value: Any, dtype) -> np.ndarray:
    try:
        return np.array(value, dtype=dtype)
    except (TypeError, ValueError, OverflowError) as exc:
        raise SceneError(label, fld, f"must be a nested list of numbers ({exc})") from None


def _read_instances(label: str, value: Any, base_dir: Path) -> np.ndarray:
    """A mesh's instances: inline transforms (N x 3 x 4 or N x 4 x 4) or the path of a .npy
    file holding such an array (compact for 10^5 copies and more)."""
    if not isinstance(value, str):
        return _array(label, "instances", value, np.float64)
    path = base_dir / value
    if not path.is_file():
        raise SceneError(label, "instances", f"instance file not found (or not a file): {path}")
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise SceneError(label, "instances", f"cannot read {path} as a .npy array of transforms "
                                             f"(N, 3, 4): {exc}") from None


def _read_material(name: str, m: dict, nbands: int) -> Material:
    label = f"material '{name}'"
    emission = _per_band(label, "emission", m["emission"], nbands) if "emission" in m else None
    texture = None
    if "texture" in m:
        t = m["texture"]
        texture = MaterialTexture(_array(label, "texture.image", t["image"], np.float32),
                                  t.get("wrap", "repeat"), t.get("interpolation", "linear"))
    return Material(name, _per_band(label, "reflectance", m["reflectance"], nbands), emission, texture)


def _read_sky(d: dict, nbands: int) -> Sky:
    kind = d["type"]
    if kind == "environment":
        _only_for("sky", d, ("irradiance", "full_sphere", "cloud_fraction"), "other sky types")
        scale = (_per_band("sky", "radiance", d["radiance"], nbands) if "radiance" in d
                 else np.ones(nbands))
        return Sky(kind, scale, table=_array("sky", "table", d["table"], np.float64))
    if "table" in d:
        raise SceneError("sky", "table", "only for sky type 'environment'")
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
    # E = pi L0 (uniform; harrison_coombes' table is normalised), or E = 7 pi L0 / 3 (cardioidal)
    per_radiance = math.pi if kind in ("uniform", "harrison_coombes") else 7.0 * math.pi / 3.0
    from ..parameters import MAX_SOURCE
    for i, e in enumerate(np.atleast_1d(np.asarray(irradiance, float)).tolist()):
        if math.isfinite(e) and e > MAX_SOURCE * per_radiance:  # the radiance it gives is bounded
            raise SceneError("sky", f"irradiance[{i}]",
                             f"must be at most {MAX_SOURCE * per_radiance:.6g} for a '{kind}' sky "
                             f"(its radiance L0 at most {MAX_SOURCE:g}: the image, float32, stays "
                             f"finite), got {e!r}")
    return Sky(kind, irradiance / per_radiance, full, cloud)


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
    materials = {name: _read_material(name, m, nb) for name, m in d.get("materials", {}).items()}
    meshes = []
    for i, m in enumerate(d.get("meshes", [])):
        label = _label("mesh", m["name"], i)
        uv = _array(label, "uv", m["uv"], np.float32) if "uv" in m else None
        instances = _read_instances(label, m["instances"], base_dir) if "instances" in m else None
        meshes.append(MeshObject(m["name"], _read_mesh(label, m, base_dir), m["material"], uv, instances))
    water = [_read_water(_label("water", w["name"], i), w, bands, base_dir)
             for i, w in enumerate(d.get("water", []))]
    sun = None
    if d.get("sun") is not None:
        s = d["sun"]
        sun = Sun(float(s["zenith_deg"]), float(s["azimuth_deg"]),
                  _per_band("sun", "irradiance", s["irradiance"], nb),
                  float(s.get("angular_diameter_deg", 0.53)))
    settings = Settings(**{k: (v if k in ("integrator", "forward_cone_deg", "sun_disk_blur", "raman") else
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


def scene_from_dict(cls, d: dict, base_dir: str | Path | None = None) -> "Scene":
    """Build and validate a scene from its JSON structure (``Scene.from_dict``).

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


def _starts_with(path: Path, magic: bytes) -> bool:
    with open(path, "rb") as f:
        return f.read(len(magic)) == magic
