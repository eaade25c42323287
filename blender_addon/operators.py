"""Operators: export the Photic scene description of the current view layer; import a scene
file as Blender objects."""

import math

import bpy
from bpy.props import FloatProperty, IntProperty, StringProperty

from .engine_loader import engine_error, load_engine
from . import natural_waters, scene_notes
from .export import ExportCancelled, ExportError, export_scene
from .properties import MAX_FURTHER_FIELDS


class PHOTIC_OT_export_scene(bpy.types.Operator):
    """Write the scene as Photic sees it (JSON scene file for `photic render`)"""

    bl_idname = "photic.export_scene"
    bl_label = "Export Photic Scene (.json)"
    bl_options = {"REGISTER"}

    filepath: StringProperty(subtype="FILE_PATH", default="//photic_scene.json",
                             description="Where to write the scene file")

    def execute(self, context):
        photic = load_engine()
        if photic is None:
            self.report({"ERROR"}, engine_error())
            return {"CANCELLED"}
        natural_waters.read_volumes(context.scene)
        depsgraph = context.evaluated_depsgraph_get()
        try:
            scene, info = export_scene(depsgraph, photic)
        except (ExportError, ExportCancelled, photic.scene.SceneError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        scene_notes.remember(context.scene.name, info)
        for w in info.warnings:
            self.report({"WARNING"}, w)
        path = bpy.path.abspath(self.filepath)
        photic.scene.save_scene(scene, path)
        self.report({"INFO"}, f"Photic scene written to {path} ({info.describe()})")
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


class PHOTIC_OT_use_ocean_modifier(bpy.types.Operator):
    """Render this Water Surface's Ocean modifier as the sea surface (Surface Shape: Mesh
    Patch, repeated with the ocean's period)"""

    bl_idname = "photic.use_ocean_modifier"
    bl_label = "Render the Ocean Modifier"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.object is not None and hasattr(context.object, "photic")

    def execute(self, context):
        context.object.photic.surface_shape = "MESH"
        return {"FINISHED"}


class PHOTIC_OT_read_volume_grids(bpy.types.Operator):
    """Read the 'density' grids (and the grids of further density fields) of the Volume
    objects that water objects take their IOP grid from (at the current frame, or at every
    frame of the scene's range), for renders started with F12 or Ctrl+F12: Blender's main
    thread reads a Volume's voxels, not a render's"""

    bl_idname = "photic.read_volume_grids"
    bl_label = "Read Volume Grids"
    bl_options = {"REGISTER"}

    every_frame: bpy.props.BoolProperty(
        name="Every Frame", default=False,
        description="Read the grids at every frame of the scene's frame range (for animations "
                    "rendered with Ctrl+F12), not only at the current frame")

    def execute(self, context):
        scene = context.scene
        if self.every_frame:
            wm = context.window_manager
            frames = range(scene.frame_start, scene.frame_end + 1, max(1, scene.frame_step))
            wm.progress_begin(0, len(frames))
            try:
                done, problem = natural_waters.read_volumes_over_frames(
                    scene, frames, lambda i, n: wm.progress_update(i))
            finally:
                wm.progress_end()
            if problem:
                self.report({"ERROR"}, "Photic: " + problem)
                return {"CANCELLED"}
        else:
            done = natural_waters.read_volumes(scene)
        errors = sorted({str(got) for _, _, got in done if isinstance(got, ExportError)})
        for e in errors:
            self.report({"ERROR"}, e)
        if errors:
            return {"CANCELLED"}
        if not done:
            self.report({"WARNING"}, "Photic: no water object takes its IOP grid from a Volume")
            return {"CANCELLED"}
        def grids(water):  # the further fields' grids, if any
            names = list(natural_waters.volume_grid_names(scene.objects[water].photic))
            return f"grids {', '.join(names)}, " if len(names) > 1 else ""

        read = dict.fromkeys(f"Volume '{vol}' ({grids(water)}{' x '.join(map(str, shape))} "
                             f"voxels) for '{water}'" for water, vol, shape in done)
        where = (f" at frames {scene.frame_start}-{scene.frame_end}" if self.every_frame
                 else f" at frame {scene.frame_current}")
        self.report({"INFO"}, "Photic: read " + ", ".join(read) + where)
        return {"FINISHED"}


def _water_props(context):
    """The Photic properties of the context's water object, or None."""
    obj = getattr(context, "object", None)
    p = getattr(obj, "photic", None) if obj is not None else None
    return p if p is not None and p.role in natural_waters.WATER_ROLES else None


class PHOTIC_OT_grid_field_add(bpy.types.Operator):
    """Add a further density field to the water's 3-D grid (at most 3 beside 'density'): its
    densities, the array or Volume grid of its name, times its own unit IOPs"""

    bl_idname = "photic.grid_field_add"
    bl_label = "Add Density Field"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        p = _water_props(context)
        return p is not None and len(p.grid_fields) < MAX_FURTHER_FIELDS

    def execute(self, context):
        p = _water_props(context)
        taken = {f.name for f in p.grid_fields} | {"density"}
        name = next(n for n in ("cdom", *(f"field{i}" for i in range(2, 100))) if n not in taken)
        p.grid_fields.add().name = name
        return {"FINISHED"}


class PHOTIC_OT_grid_fields_from_source(bpy.types.Operator):
    """Add a further density field for each float array of the Density File (3-D, the
    density's shape) or each float grid of the Grid Box's Volume other than 'density', with
    the default unit IOPs; names already present are skipped, at most 3 fields in all"""

    bl_idname = "photic.grid_fields_from_source"
    bl_label = "Add Fields from Source"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        p = _water_props(context)
        return p is not None and p.iop_variation in {"GRID", "PROFILE_GRID"}

    def execute(self, context):
        p = _water_props(context)
        try:
            names, where = natural_waters.source_field_names(
                p, context.evaluated_depsgraph_get())
        except ValueError as exc:
            self.report({"WARNING"}, f"Photic: no fields added: {exc}")
            return {"CANCELLED"}
        present = {f.name for f in p.grid_fields}
        new = [n for n in names if n not in present]
        room = max(0, MAX_FURTHER_FIELDS - len(p.grid_fields))
        added, skipped = new[:room], new[room:]
        for name in added:
            p.grid_fields.add().name = name  # the other properties keep their defaults
        full = (f"at most {MAX_FURTHER_FIELDS} further fields: not added "
                f"{', '.join(skipped)}" if skipped else "")
        if added:
            self.report({"INFO"}, f"Photic: added density fields {', '.join(added)} from "
                                  f"{where}" + (f" ({full})" if full else ""))
            return {"FINISHED"}
        if full:
            why = full
        elif names:
            why = f"every field of {where} is present already ({', '.join(names)})"
        else:
            why = f"{where} holds no field but 'density'"
        self.report({"WARNING"}, f"Photic: no fields added: {why}")
        return {"CANCELLED"}


class PHOTIC_OT_grid_field_remove(bpy.types.Operator):
    """Remove this further density field from the water's 3-D grid"""

    bl_idname = "photic.grid_field_remove"
    bl_label = "Remove Density Field"
    bl_options = {"REGISTER", "UNDO"}

    index: bpy.props.IntProperty(name="Index", default=0, min=0,
                                 description="Which further field (0: the first listed)")

    @classmethod
    def poll(cls, context):
        p = _water_props(context)
        return p is not None and len(p.grid_fields) > 0

    def execute(self, context):
        p = _water_props(context)
        if self.index >= len(p.grid_fields):
            self.report({"ERROR"}, f"Photic: no further density field {self.index}")
            return {"CANCELLED"}
        p.grid_fields.remove(self.index)
        return {"FINISHED"}


class PHOTIC_OT_import_scene(bpy.types.Operator):
    """Create Blender objects from a Photic scene file (.json)"""

    bl_idname = "photic.import_scene"
    bl_label = "Import Photic Scene (.json)"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", description="Scene file to read")

    def execute(self, context):
        photic = load_engine()
        if photic is None:
            self.report({"ERROR"}, engine_error())
            return {"CANCELLED"}
        from .importer import import_scene
        notes = []
        try:
            scene = photic.scene.load_scene(bpy.path.abspath(self.filepath))
            created = import_scene(scene, context.scene, notes=notes)
        except (OSError, ValueError) as exc:  # SceneError is a ValueError
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for text in notes:  # (what the objects hold other than the file has it)
            self.report({"WARNING"}, text)
        self.report({"INFO"}, f"Photic scene '{scene.name}': {len(created)} objects created"
                              + (f", {len(notes)} warning(s)" if notes else ""))
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


def menu_import(self, context):
    self.layout.operator(PHOTIC_OT_import_scene.bl_idname, text="Photic Scene (.json)")


def menu_export(self, context):
    self.layout.operator(PHOTIC_OT_export_scene.bl_idname, text="Photic Scene (.json)")


class PHOTIC_OT_clear_sky_sun(bpy.types.Operator):
    """Point the active sun lamp at the sun of a place and time and give it the irradiance of
    a clear sky's direct beam in each band (photic.solar: approximate, within ~10 %); +Y is
    north, +X east"""

    bl_idname = "photic.clear_sky_sun"
    bl_label = "Clear-Sky Sun at a Place and Time"
    bl_options = {"REGISTER", "UNDO"}

    latitude: FloatProperty(name="Latitude (\u00b0N)", default=43.3, min=-90.0, max=90.0,
                            description="Degrees north (negative: south)")
    longitude: FloatProperty(name="Longitude (\u00b0E)", default=5.4, min=-180.0, max=180.0,
                             description="Degrees east (negative: west)")
    year: IntProperty(name="Year", default=2026, min=1900, max=2100)
    month: IntProperty(name="Month", default=6, min=1, max=12)
    day: IntProperty(name="Day", default=21, min=1, max=31)
    hour_utc: FloatProperty(name="Hour (UTC)", default=11.0, min=0.0, max=24.0,
                            description="Time of day in hours, UTC")
    aerosol_beta: FloatProperty(name="Turbidity \u03b2", default=0.05, min=0.0, max=1.0,
                                description="Angstrom turbidity: aerosol optical depth at 1 um "
                                            "(0.05 clear, 0.2 hazy; dimensionless)")

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.type == "LIGHT" and obj.data.type == "SUN"

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        import datetime

        import numpy as np

        from .bands import BandError, scene_bands
        photic = load_engine()
        if photic is None:
            self.report({"ERROR"}, engine_error())
            return {"CANCELLED"}
        from photic import solar
        try:
            hours = min(self.hour_utc, 23.9999)
            when = datetime.datetime(self.year, self.month, self.day, tzinfo=datetime.timezone.utc) \
                + datetime.timedelta(hours=hours)
        except ValueError as exc:
            self.report({"ERROR"}, f"Clear-Sky Sun: the date is not valid ({exc})")
            return {"CANCELLED"}
        zenith, azimuth = solar.solar_position(self.latitude, self.longitude, when)
        if zenith >= 89.0:
            self.report({"ERROR"}, f"Clear-Sky Sun: the sun is {zenith - 90.0:.1f} degrees below "
                                   f"the horizon (or too low) there and then")
            return {"CANCELLED"}
        try:
            bands = scene_bands(context.scene.photic)
        except BandError as exc:
            self.report({"ERROR"}, f"Render > Bands ({exc.prop}): {exc.message}")
            return {"CANCELLED"}
        doy = when.timetuple().tm_yday
        values = []
        for _, centre, width in bands:  # averaged over the band
            lam = np.linspace(max(280.0, centre - width / 2), min(4000.0, centre + width / 2), 9)
            values.append(float(np.mean(solar.clear_sky_direct(lam, zenith, self.aerosol_beta,
                                                                day_of_year=doy))))
        obj = context.object
        light = obj.data
        obj.rotation_mode = "XYZ"
        obj.rotation_euler = (math.radians(zenith), 0.0, math.radians(azimuth + 90.0))
        light.photic.irradiance_bands = ", ".join(f"{v:.4g}" for v in values)
        light.energy = max(values)
        light.color = (1.0, 1.0, 1.0)
        light.angle = math.radians(0.53)
        self.report({"INFO"}, f"Sun at zenith {zenith:.1f} deg, azimuth {azimuth:.1f} deg (from +X "
                              f"towards +Y); irradiance {', '.join(f'{v:.3g}' for v in values)} "
                              f"W m^-2 nm^-1")
        return {"FINISHED"}


classes = (PHOTIC_OT_export_scene, PHOTIC_OT_use_ocean_modifier, PHOTIC_OT_read_volume_grids, PHOTIC_OT_grid_field_add,
           PHOTIC_OT_grid_fields_from_source, PHOTIC_OT_grid_field_remove, PHOTIC_OT_import_scene,
           PHOTIC_OT_clear_sky_sun)


def register():
    bpy.types.TOPBAR_MT_file_export.append(menu_export)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
