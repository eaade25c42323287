"""The evaluated depsgraph as a Photic scene description (``photic.scene.Scene``).

Geometry comes from ``depsgraph.object_instances``: each distinct mesh is evaluated once
(modifiers applied) and read in bulk, its instances only add a matrix, and all instances of a
mesh that share a material become one engine mesh. The camera, the sun lamp, the world and the
objects' Photic properties become the engine's camera, sun, sky, water bodies and radiometers.

Every problem is an ``ExportError`` naming the Blender data-block and the property, checked
here where Blender's names are known; what the engine's own validation finds later is
translated back to the object it came from (``engine_error``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from . import bands as bandmod
from .export_values import (  # noqa: F401  (export.ExportError ... as before)
    ExportCancelled, ExportError, _finite_non_negative, _obj, blender_float, per_band,
)
from .mesh_export import drop_degenerate, evaluated_mesh, mesh_arrays, transform
from .nodes import find_node

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD"}
DEFAULT_MATERIAL = "photic_default_grey"
DEFAULT_REFLECTANCE = 0.5
CHECK_EVERY = 1000  # instances between cancel checks and progress reports


@dataclass
class ExportInfo:
    """What the export did: counts, warnings for the user and time taken."""

    triangles: int = 0
    instances: int = 0
    meshes_evaluated: int = 0
    warnings: list = field(default_factory=list)
    time_s: float = 0.0
    radiometer_objects: dict = field(default_factory=dict)  # engine radiometer -> object


@dataclass
class ViewCamera:
    """A camera given directly (the 3D viewport's view) instead of a camera object."""

    orthographic: bool
    matrix_world: np.ndarray   # camera-to-world, looking down -Z with +Y up
    tan_half_fov: float        # horizontal
    ortho_width: float
    shift: tuple
    clip_start: float


class _Exporter:
    def __init__(self, depsgraph, photic, view_camera, resolution, progress, test_break):
        self.dg = depsgraph
        self.bscene = depsgraph.scene_eval
        self.photic = photic
        self.view_camera = view_camera
        self.resolution = resolution
        self.progress = progress or (lambda f, text: None)
        self.test_break = test_break or (lambda: False)
        self.info = ExportInfo()
        # Photic settings are read from the original data-blocks: Blender does not always
        # re-evaluate the depsgraph when only an add-on property changed.
        self.props = self.bscene.original.photic
        try:
            self.bands = bandmod.scene_bands(self.props)
        except bandmod.BandError as exc:
            raise ExportError(f"Scene '{self.bscene.name}'", f"Photic > Bands ({exc.prop})",
                              exc.message) from None
        self.materials: dict = {}
        # (key, material name) -> [list of world vertex arrays, list of triangle arrays]
        self.groups: dict = {}
        self.group_names: dict = {}
        self.mesh_cache: dict = {}
        self.water = []
        self.suns = []
        self.radiometers = []
        self.arrays = []

    # -- materials --------------------------------------------------------------------------
    def material(self, mat) -> str:
        """Engine material name of a Blender material (None: the default grey)."""
        S = self.photic.scene
        if mat is None:
            if DEFAULT_MATERIAL not in self.materials:
                self.materials[DEFAULT_MATERIAL] = S.Material(
                    DEFAULT_MATERIAL, np.full(len(self.bands), DEFAULT_REFLECTANCE))
            return DEFAULT_MATERIAL
        name = mat.name_full if hasattr(mat, "name_full") else mat.name
        if name in self.materials:
            return name
        owner = f"Material '{mat.name}'"
        p = getattr(getattr(mat, "original", mat), "photic", None)
        if p is not None and p.use_override:
            refl = per_band(owner, p.reflectance, p.reflectance_bands, "Reflectance",
                            "photic.reflectance", self.bands, "reflectance", hi=1.0)
        else:
            rgb = self._base_colour(mat)
            refl = bandmod.rgb_to_bands(rgb, self.bands)
            if not np.all(np.isfinite(refl)):
                raise ExportError(owner, "Base Color", f"is not finite: {list(rgb)}")
            refl = np.clip(refl, 0.0, 1.0)
        self.materials[name] = S.Material(name, refl)
        return name

    @staticmethod
    def _base_colour(mat):
        """Base colour of the material's Principled BSDF, else its viewport colour."""
        node = find_node(mat, "BSDF_PRINCIPLED")
        if node is not None:
            return tuple(node.inputs["Base Color"].default_value)[:3]
        node = find_node(mat, "BSDF_DIFFUSE")
        if node is not None:
            return tuple(node.inputs["Color"].default_value)[:3]
        return tuple(mat.diffuse_color)[:3]

    # -- geometry ----------------------------------------------------------------------------
    def mesh_data(self, obj, key):
        """Local arrays and slot materials (Blender materials or None) of an object's evaluated
        mesh, read once per key."""
        if key in self.mesh_cache:
            return self.mesh_cache[key]
        with evaluated_mesh(obj) as mesh:
            if mesh is None:
                data = None
            else:
                v, t, m = mesh_arrays(mesh)
                slots = [s.material for s in obj.material_slots] if obj.material_slots else []
                if not slots and len(mesh.materials):
                    slots = list(mesh.materials)
                data = (v, t, m, slots or [None])
        self.info.meshes_evaluated += 1
        self.mesh_cache[key] = data
        return data

    def add_opaque(self, obj, key, matrix):
        data = self.mesh_data(obj, key)
        if data is None or len(data[1]) == 0:
            return
        v, t, m, slots = data
        slot_materials = [self.material(s) for s in slots]
        world = transform(v, matrix)
        if np.linalg.det(np.asarray(matrix)[:3, :3]) < 0:  # mirrored: keep normals outward
            t = t[:, ::-1]
        m = np.clip(m, 0, len(slot_materials) - 1)
        for slot in np.unique(m):
            tris = t[m == slot] if len(slot_materials) > 1 else t
            gkey = (key, slot_materials[slot])
            group = self.groups.setdefault(gkey, [[], []])
            group[0].append(world)
            group[1].append(tris)
            self.group_names.setdefault(gkey, obj.name)
        self.info.triangles += len(t)

    def build_meshes(self):
        S = self.photic.scene
        meshes = []
        names_used = {}
        for (key, mat), (vlist, tlist) in self.groups.items():
            offsets = np.cumsum([0] + [len(v) for v in vlist[:-1]])
            vertices = np.concatenate(vlist)
            triangles = np.concatenate([t.astype(np.int64) + o for t, o in zip(tlist, offsets)])
            triangles, _, dropped = drop_degenerate(vertices, triangles)
            base = self.group_names[(key, mat)]
            if dropped:
                self.info.warnings.append(f"{_obj(base)}: {dropped} zero-area triangle(s) "
                                          f"skipped")
            if len(triangles) == 0:
                continue
            name = base if mat in (DEFAULT_MATERIAL,) or len(
                [k for k in self.groups if k[0] == key]) == 1 else f"{base} [{mat}]"
            n = names_used.get(name, 0)
            names_used[name] = n + 1
            if n:
                name = f"{name} #{n + 1}"
            meshes.append(S.MeshObject(name, S.TriangleMesh(vertices, triangles), mat))
        return meshes

    # -- water -------------------------------------------------------------------------------
    def iops(self, obj):
        """The water's IOPs from its IOP source (the base IOPs of a grid)."""
        p = obj.original.photic
        owner = _obj(obj.name)
        if p.iop_source == "MODEL":
            return self.model_iops(owner, p.iop_model, "Photic > IOP Model (photic.iop_model)")
        a = per_band(owner, p.absorption, p.absorption_bands, "Photic > Absorption",
                     "photic.absorption", self.bands, "absorption coefficient")
        b = per_band(owner, p.scattering, p.scattering_bands, "Photic > Scattering",
                     "photic.scattering", self.bands, "scattering coefficient")
        return self.coefficient_iops(owner, p, a, b)

    def model_iops(self, owner: str, text: str, prop: str, defaults: dict | None = None):
        """IOPs from a model description in JSON (``defaults`` fill top-level fields it lacks)."""
        import json
        S = self.photic.scene
        try:
            spec = json.loads(text)
        except ValueError as exc:
            raise ExportError(owner, prop, f"is not valid JSON: {exc}") from None
        if not isinstance(spec, dict):
            raise ExportError(owner, prop, "must be a JSON object such as "
                                           "{\"model\": \"cdom\", \"a_ref\": 0.1}")
        spec = {**(defaults or {}), **spec}
        from photic.iop_models import iops_from_model
        try:
            return iops_from_model(spec, [S.Band(*b) for b in self.bands], obj=owner)
        except S.SceneError as exc:
            raise ExportError(owner, prop, f"field '{exc.field}': {exc.message}") from None

    def phase_function(self, owner: str, kind: str, g: float, backscatter: float,
                       prefix: str = "Photic > "):
        """A phase function from the enum and its parameter properties."""
        S = self.photic.scene
        params = {}
        if kind == "henyey_greenstein":
            params = {"g": blender_float(g)}
        elif kind == "fournier_forand":
            params = {"backscatter_fraction": blender_float(backscatter)}
        for pname, value in params.items():
            if not math.isfinite(value):
                raise ExportError(owner, f"{prefix}phase function parameter {pname}",
                                  f"is {value}")
        return S.PhaseFunction(kind, params)

    def coefficient_iops(self, owner: str, p, a, b):
        """IOPs from coefficients per band with the object's phase function; pure water added
        for the source 'Pure Water + Additions'."""
        S = self.photic.scene
        phase = self.phase_function(owner, p.phase_function, p.hg_g, p.ff_backscatter)
        scattering = [S.ScatteringComponent(b, phase)] if np.any(b > 0) else []
        if p.iop_source == "PURE_WATER":
            models = self.photic.iop_models
            bands = [(c, w) for _, c, w in self.bands]
            try:
                a = a + models.pure_water_absorption(bands)
            except ValueError as exc:
                raise ExportError(owner, "Photic > IOPs (photic.iop_source)",
                                  f"pure water: {exc}; choose bands within it or give the "
                                  f"coefficients") from None
            b_w = models.pure_seawater_scattering(bands)
            scattering.insert(0, S.ScatteringComponent(b_w, S.PhaseFunction("pure_water")))
        return S.IOPs(a, scattering)

    def water_iops(self, obj, level: float, bounds=None):
        """Homogeneous IOPs, a depth profile or a 3-D grid (``natural_waters``). ``level``:
        the height depths are measured from (m); ``bounds``: (lo, hi) of a water body."""
        if obj.original.photic.iop_variation == "NONE":
            return self.iops(obj)
        from . import natural_waters
        return natural_waters.varying_iops(self, obj, level, bounds)

    def add_water_body(self, obj, key, matrix, index):
        S = self.photic.scene
        owner = _obj(obj.name)
        data = self.mesh_data(obj, key)
        if data is None or len(data[1]) == 0:
            raise ExportError(owner, "Photic > Role (photic.role)",
                              "is 'Water Body' but the object has no faces: a water body must "
                              "be a closed mesh")
        v, t, _, _ = data
        world = transform(v, matrix)
        t = t.astype(np.int64)
        if np.linalg.det(np.asarray(matrix)[:3, :3]) < 0:
            t = t[:, ::-1]
        t, _, dropped = drop_degenerate(world, t)
        if dropped:
            self.info.warnings.append(f"{owner}: {dropped} zero-area triangle(s) skipped")
        mesh = S.TriangleMesh(world, t)
        try:
            self.photic.scene.check_closed_mesh(owner, mesh)
        except self.photic.scene.SceneError as exc:
            raise ExportError(owner, "mesh (a water body must be a closed mesh with outward "
                                     "normals)", exc.message) from None
        name = obj.name if index == 0 else f"{obj.name} #{index + 1}"
        # Depths of a profile count from the top of the body; a grid defaults to its bounds.
        iops = self.water_iops(obj, float(world[:, 2].max()),
                               bounds=(world.min(axis=0), world.max(axis=0)))
        self.water.append(S.WaterBody(name, "mesh", iops, ior=self._ior(obj), mesh=mesh))
        self.info.triangles += len(t)

    def _ior(self, obj) -> float:
        ior = blender_float(obj.original.photic.ior)
        p = self.photic.parameters.PARAMETERS["water.ior"]
        if not (math.isfinite(ior) and p.contains(ior)):
            raise ExportError(_obj(obj.name), "Photic > Refractive Index (photic.ior)",
                              f"is {ior}, must be in {p.range_text()}")
        return ior

    def add_water_surface(self, obj, key, matrix):
        S = self.photic.scene
        p = obj.original.photic
        owner = _obj(obj.name)
        m = np.asarray(matrix, float)
        if p.surface_shape == "FLAT":
            surface = S.OceanSurface("flat", z=float(m[2, 3]))
        elif p.surface_shape == "WAVES":
            from .waves_preview import frame_time, wave_model
            try:
                model = wave_model(self.photic, obj.original, frame_time(self.bscene))
            except ValueError as exc:
                raise ExportError(owner, "Photic > Sinusoids (photic.wave_sinusoids)",
                                  str(exc)) from None
            surface = S.OceanSurface("waves", z=float(m[2, 3]), waves=model)
        else:
            data = self.mesh_data(obj, key)
            if data is None or len(data[1]) == 0:
                raise ExportError(owner, "Photic > Surface Shape (photic.surface_shape)",
                                  "is 'Mesh Patch' but the object has no faces")
            v, t, _, _ = data
            world = transform(v, matrix)
            extent = world[:, :2].max(axis=0) - world[:, :2].min(axis=0)
            if np.any(extent <= 0):
                raise ExportError(owner, "mesh", "a water surface patch must span an area in "
                                                 "x and y")
            surface = S.OceanSurface("patch", mesh=S.TriangleMesh(world, t.astype(np.int64)),
                                     period=(float(extent[0]), float(extent[1])))
        if p.use_roughness:
            surface.roughness = S.SurfaceRoughness(
                blender_float(p.wind_speed), bool(p.roughness_anisotropic),
                blender_float(math.degrees(p.wind_direction)))
        bottom_depth = bottom_material = None
        if p.use_bottom:
            depth = blender_float(p.bottom_depth)
            if not (math.isfinite(depth) and depth > 0):
                raise ExportError(owner, "Photic > Bottom Depth (photic.bottom_depth)",
                                  f"is {depth}, must be > 0")
            bottom_depth = depth
            bottom_material = self.material(p.bottom_material)
        # Depths of a profile count from the mean sea level (a patch's mean height).
        self.water.append(S.WaterBody(obj.name, "ocean", self.water_iops(obj, float(surface.z)),
                                      ior=self._ior(obj),
                                      surface=surface, bottom_depth=bottom_depth,
                                      bottom_material=bottom_material))

    # -- radiometers -------------------------------------------------------------------------
    def add_radiometer(self, obj, matrix):
        S = self.photic.scene
        p = obj.original.photic
        m = np.asarray(matrix, float)
        direction = -m[:3, 2]
        if not np.linalg.norm(direction) > 0:
            raise ExportError(_obj(obj.name), "Scale", "is zero: the radiometer has no direction")
        self.radiometers.append(S.Radiometer(
            obj.name, p.quantity, m[:3, 3].copy(), direction / np.linalg.norm(direction),
            half_angle_deg=blender_float(math.degrees(p.half_angle)), polar_bins=int(p.polar_bins),
            azimuth_bins=int(p.azimuth_bins)))

    def add_radiometer_array(self, obj, key, matrix):
        S = self.photic.scene
        p = obj.original.photic
        owner = _obj(obj.name)
        m = np.asarray(matrix, float)
        quantities = [q for q in self.photic.scene.QUANTITIES if q in p.quantities]
        if not quantities:
            raise ExportError(owner, "Photic > Quantities (photic.quantities)",
                              "none chosen: a radiometer array needs at least one quantity")
        if p.array_layout == "VERTICES":
            data = self.mesh_data(obj, key) if obj.type in GEOMETRY_TYPES else None
            local = data[0] if data is not None else np.zeros((0, 3), np.float32)
            where = "the object has no mesh vertices"
        else:
            n = int(p.array_count)
            s = float(p.array_spacing)
            k = np.arange(n, dtype=float) * s
            if p.array_layout == "LINE":
                local = np.stack([np.zeros(n), np.zeros(n), -k], axis=1)
            else:
                c = k - k.mean() if n else k
                gx, gy = np.meshgrid(c, c, indexing="ij")
                local = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
            where = "Photic > Count (photic.array_count) is 0"
        if len(local) == 0:
            raise ExportError(owner, "Photic > Layout (photic.array_layout)",
                              f"the radiometer array has no elements: {where}")
        positions = transform(np.asarray(local, np.float64), m)
        if len(np.unique(np.round(positions, 9), axis=0)) < len(positions):
            raise ExportError(owner, "Photic > Spacing (photic.array_spacing)",
                              "two radiometers of the array are at the same place")
        direction = -m[:3, 2]
        direction = direction / np.linalg.norm(direction) if np.linalg.norm(direction) > 0 \
            else np.array([0.0, 0.0, -1.0])
        self.arrays.append(S.RadiometerArray(obj.name, quantities, positions, direction=direction,
                                             half_angle_deg=blender_float(math.degrees(p.half_angle))))

    # -- lights, world, camera ---------------------------------------------------------------
    def add_light(self, obj, matrix):
        light = obj.data
        if light.type != "SUN":
            self.info.warnings.append(f"Light '{obj.name}': {light.type.lower()} lights are not "
                                      f"used by Photic (only sun lamps)")
            return
        self.suns.append((obj, np.asarray(matrix, float)))

    def sun(self):
        S = self.photic.scene
        if not self.suns:
            return None
        if len(self.suns) > 1:
            names = " and ".join(f"'{o.name}'" for o, _ in self.suns)
            raise ExportError(f"Light '{self.suns[1][0].name}'", "type",
                              f"Photic uses one sun lamp; the scene has {names} (hide or delete "
                              f"all but one from the render)")
        obj, m = self.suns[0]
        owner = f"Light '{obj.name}'"
        towards = m[:3, 2]
        norm = np.linalg.norm(towards)
        if not norm > 0:
            raise ExportError(owner, "Scale", "is zero: the sun has no direction")
        towards = towards / norm
        # Blender keeps rotations in float32 (about 1e-5 degrees): angles are rounded to 1e-4
        # degrees so that a sun set to 30 degrees exports as exactly 30.
        zenith = round(math.degrees(math.acos(max(-1.0, min(1.0, towards[2])))), 4)
        if zenith >= 90.0:
            raise ExportError(owner, "Rotation", f"puts the sun below the horizon (zenith angle "
                                                 f"{zenith:.1f} degrees; the lamp shines along "
                                                 f"its -Z axis and must point downwards)")
        azimuth = round(math.degrees(math.atan2(towards[1], towards[0])), 4) % 360.0 + 0.0
        light = obj.data
        # (the original ID's: editing a custom property does not always re-evaluate the lamp)
        lp = getattr(getattr(light, "original", None) or light, "photic", None)
        if lp is not None and lp.irradiance_bands.strip():
            irradiance = per_band(owner, 0.0, lp.irradiance_bands, "Irradiance",
                                  "data.photic.irradiance", self.bands, "sun irradiance")
        else:
            strength = blender_float(light.energy)
            if not (math.isfinite(strength) and strength >= 0):
                raise ExportError(owner, "Strength (data.energy)",
                                  f"is {strength}, must be a finite irradiance >= 0 W m^-2")
            colour = tuple(blender_float(c) for c in light.color)
            irradiance = strength * bandmod.rgb_to_bands(colour, self.bands)
            _finite_non_negative(owner, "Color (data.color)", irradiance, "sun irradiance")
        diameter = blender_float(math.degrees(light.angle))
        p = self.photic.parameters.PARAMETERS["sun.angular_diameter_deg"]
        if not p.contains(diameter):
            raise ExportError(owner, "Angle (data.angle)", f"is {diameter:.3g} degrees; "
                                                           f"Photic's sun disk must be in "
                                                           f"{p.range_text()} degrees (the real "
                                                           f"sun: 0.53)")
        return S.Sun(zenith, azimuth, irradiance, angular_diameter_deg=diameter)

    def sky(self):
        S = self.photic.scene
        world = self.bscene.world
        if world is None:
            return S.Sky("black")
        p = world.original.photic
        owner = f"World '{world.name}'"
        if p.sky_model == "BLACK":
            return S.Sky("black")
        if p.sky_model == "FROM_WORLD":
            colour, strength = tuple(world.color)[:3], 1.0
            node = find_node(world, "BACKGROUND")
            if node is not None:
                colour = tuple(node.inputs["Color"].default_value)[:3]
                strength = float(node.inputs["Strength"].default_value)
            l0 = strength * bandmod.rgb_to_bands(colour, self.bands)
            _finite_non_negative(owner, "Surface > Color x Strength", l0, "sky radiance")
            return S.Sky("uniform", l0) if np.any(l0 > 0) else S.Sky("black")
        l0 = blender_float(p.radiance) * bandmod.rgb_to_bands(
            tuple(blender_float(c) for c in p.color), self.bands)
        _finite_non_negative(owner, "Photic > Radiance L0 (photic.radiance)", l0, "sky radiance")
        return S.Sky("uniform" if p.sky_model == "UNIFORM" else "cardioidal", l0)

    def camera(self):
        S = self.photic.scene
        width, height = self.resolution
        vc = self.view_camera
        if vc is not None:
            m = np.asarray(vc.matrix_world, float)
            return S.Camera("viewport", "orthographic" if vc.orthographic else "perspective",
                            m[:3, 3].copy(), -m[:3, 2], up=m[:3, 1].copy(),
                            fov_deg=math.degrees(2 * math.atan(vc.tan_half_fov)),
                            ortho_width=vc.ortho_width, resolution=(width, height),
                            shift=tuple(vc.shift), clip_start=vc.clip_start)
        cam = self.bscene.camera
        if cam is None:
            return None
        r = self.bscene.render
        if abs(r.pixel_aspect_x - r.pixel_aspect_y) > 1e-6 * r.pixel_aspect_x:
            raise ExportError(f"Scene '{self.bscene.name}'", "Output > Format > Aspect "
                              "(render.pixel_aspect_x/y)", f"non-square pixels "
                              f"({r.pixel_aspect_x:g}:{r.pixel_aspect_y:g}) are not supported")
        owner = _obj(cam.name)
        data = cam.data
        m = np.asarray(cam.matrix_world, float)
        fwd, up = -m[:3, 2], m[:3, 1]
        if not (np.linalg.norm(fwd) > 0 and np.linalg.norm(up) > 0):
            raise ExportError(owner, "Scale", "is zero: the camera has no viewing direction")
        fit = data.sensor_fit
        if fit == "AUTO":
            ref = max(width, height)
            sensor = data.sensor_width
        elif fit == "HORIZONTAL":
            ref, sensor = width, data.sensor_width
        else:
            ref, sensor = height, data.sensor_height
        if data.type == "PANO":
            raise ExportError(owner, "Type (data.type)", "panoramic cameras are not supported "
                                                         "by Photic; use perspective or "
                                                         "orthographic")
        if data.type == "ORTHO":
            half_ref = 0.5 * float(data.ortho_scale)
        else:
            if not data.lens > 0:
                raise ExportError(owner, "Focal Length (data.lens)", f"is {data.lens}, must be > 0")
            half_ref = 0.5 * float(sensor) / float(data.lens)  # tan of the half angle
        half_width = half_ref * width / ref
        # Blender's smallest clip start (1e-6 m) means none.
        clip = blender_float(data.clip_start)
        clip = 0.0 if clip <= 1e-6 else clip
        shift = (float(data.shift_x) * ref / width, float(data.shift_y) * ref / width)
        if data.type == "ORTHO":
            return S.Camera(cam.name, "orthographic", m[:3, 3].copy(), fwd, up=up.copy(),
                            ortho_width=2 * half_width, resolution=(width, height), shift=shift,
                            clip_start=clip)
        fov = math.degrees(2 * math.atan(half_width))
        if not 0 < fov < 180:
            raise ExportError(owner, "Focal Length (data.lens)", f"gives a field of view of "
                                                                 f"{fov:.3g} degrees")
        return S.Camera(cam.name, "perspective", m[:3, 3].copy(), fwd, up=up.copy(),
                        fov_deg=fov, resolution=(width, height), shift=shift, clip_start=clip)

    def settings(self):
        S = self.photic.scene
        p = self.props
        cone = "auto" if p.forward_cone == "AUTO" else blender_float(math.degrees(p.forward_cone_angle))
        return S.Settings(integrator=p.integrator.lower(), samples=int(p.samples),
                          radiometer_samples=int(p.radiometer_samples), seed=int(p.seed),
                          max_depth=int(p.max_depth), threads=int(p.threads),
                          forward_cone_deg=cone, beam_max_level=int(p.beam_max_level),
                          target_error=(blender_float(p.target_error) / 100.0
                                        if p.use_target_error else None),
                          noise_threshold=(blender_float(p.noise_threshold) / 100.0
                                           if p.use_noise_threshold else None),
                          adaptive_min_samples=int(p.adaptive_min_samples))

    # -- the walk ----------------------------------------------------------------------------
    def walk(self):
        water_index: dict = {}
        estimate = max(1, len(self.dg.objects))
        for i, inst in enumerate(self.dg.object_instances):
            if i % CHECK_EVERY == CHECK_EVERY - 1:
                if self.test_break():
                    raise ExportCancelled()
                self.progress(min(0.99, i / max(estimate, i + 1)), f"exporting: {i + 1} instances")
            obj = inst.object
            matrix = np.array(inst.matrix_world, dtype=np.float64)
            original = obj.original
            role = original.photic.role if hasattr(original, "photic") else "NONE"
            self.info.instances += 1
            if obj.type == "LIGHT":
                self.add_light(obj, matrix)
                continue
            if obj.type == "CAMERA":
                continue
            # Geometry is keyed by the mesh data when the object has no modifiers, so linked
            # duplicates share one evaluated mesh; otherwise by the object.
            data = getattr(original, "data", None)
            if data is not None and not getattr(original, "modifiers", None) and obj.type == "MESH":
                key = ("mesh", data.name_full)
            else:
                key = ("object", original.name_full)
            if role == "RADIOMETER":
                self.add_radiometer(original, matrix)
            elif role == "RADIOMETER_ARRAY":
                self.add_radiometer_array(obj, key, matrix)
            elif role == "WATER_BODY":
                n = water_index.get(original.name_full, 0)
                water_index[original.name_full] = n + 1
                self.add_water_body(obj, key, matrix, n)
            elif role == "WATER_SURFACE":
                if original.name_full in water_index:
                    raise ExportError(_obj(original.name), "Photic > Role (photic.role)",
                                      "a water surface cannot be instanced")
                water_index[original.name_full] = 1
                self.add_water_surface(obj, key, matrix)
            elif obj.type in GEOMETRY_TYPES:
                self.add_opaque(obj, key, matrix)


def export_scene(depsgraph, photic, *, view_camera: ViewCamera | None = None,
                 resolution: tuple[int, int] | None = None, progress=None, test_break=None):
    """The Photic scene of an evaluated depsgraph.

    Parameters
    ----------
    depsgraph : bpy.types.Depsgraph
        Evaluated for render (final renders) or for the viewport.
    photic : module
        The ``photic`` engine package (see ``engine_loader``).
    view_camera : ViewCamera, optional
        Render this view instead of the scene's camera (the viewport).
    resolution : (width, height), optional
        Image size; default the scene's render resolution times its percentage.
    progress : callable(fraction, text), optional
    test_break : callable() -> bool, optional
        Polled every thousand instances; True stops the export with ``ExportCancelled``.

    Returns
    -------
    (photic.scene.Scene, ExportInfo)

    Raises
    ------
    ExportError
        Naming the data-block and the property.
    ExportCancelled
    """
    t0 = time.perf_counter()
    S = photic.scene
    bscene = depsgraph.scene_eval
    if resolution is None:
        r = bscene.render
        resolution = (max(1, r.resolution_x * r.resolution_percentage // 100),
                      max(1, r.resolution_y * r.resolution_percentage // 100))
    ex = _Exporter(depsgraph, photic, view_camera, resolution, progress, test_break)
    ex.walk()
    scene_owner = f"Scene '{bscene.name}'"
    camera = ex.camera()
    radiometer_count = len(ex.radiometers) + len(ex.arrays)
    if camera is None and radiometer_count == 0:
        raise ExportError(scene_owner, "Camera (scene.camera)",
                          "the scene has no camera and no Photic radiometer: nothing to render")
    meshes = ex.build_meshes()
    sun = ex.sun()
    sky = ex.sky()
    if not ex.water and not meshes and sun is None and sky.type == "black":
        raise ExportError(scene_owner, "objects", "the scene is empty for Photic: no water, no "
                                                  "objects, no sun lamp and a black sky")
    scene = S.Scene(name=bscene.name, bands=[S.Band(*b) for b in ex.bands],
                    materials=ex.materials, meshes=meshes, water=ex.water, sun=sun, sky=sky,
                    cameras=[camera] if camera is not None else [],
                    radiometers=ex.radiometers, radiometer_arrays=ex.arrays,
                    settings=ex.settings())
    try:
        scene.validate()
    except S.SceneError as exc:
        raise engine_error(exc, scene_owner) from None
    ex.info.time_s = time.perf_counter() - t0
    ex.progress(1.0, "exported")
    return scene, ex.info


_ENGINE_KINDS = {"water": "Object", "mesh": "Object", "camera": "Object", "radiometer": "Object",
                 "radiometer array": "Object", "sun": "Light (sun)", "sky": "World",
                 "settings": "Scene", "scene": "Scene"}


def engine_error(exc, scene_owner: str) -> ExportError:
    """An engine ``SceneError`` as an ``ExportError`` on the Blender object it came from."""
    label = getattr(exc, "obj", "") or ""
    fld = getattr(exc, "field", "") or ""
    message = getattr(exc, "message", None) or str(exc)
    kind, _, name = label.partition(" '")
    name = name.rstrip("'").split(" [")[0].split(" #")[0]
    owner = f"{_ENGINE_KINDS.get(kind, kind.title())} '{name}'" if name else \
        (scene_owner if kind in ("settings", "scene", "") else _ENGINE_KINDS.get(kind, kind))
    return ExportError(owner, f"Photic field '{fld}'", message)
