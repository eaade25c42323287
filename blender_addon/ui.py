"""Panels in the Render, Object, Material and World properties."""
from __future__ import annotations

import bpy

import textwrap

from . import final_render, scene_notes, water_types
from .natural_waters import WATER_ROLES
from .properties import MAX_FURTHER_FIELDS
from .engine_loader import engine_error, load_engine
from .nodes import find_node


class PhoticPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {"PHOTIC"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


def _engine_status(layout) -> None:
    if load_engine() is None:
        box = layout.box()
        box.alert = True
        box.label(text="Photic engine unavailable", icon="ERROR")
        msg = engine_error() or ""
        for i in range(0, min(len(msg), 600), 60):
            box.label(text=msg[i:i + 60])


def _draw_notes(layout, context, kind: str, name: str) -> None:
    """What the last render or viewport export could not render of this data-block (a box of
    wrapped lines under a warning icon), if anything."""
    notes = scene_notes.for_id(context.scene.name, kind, name)
    if not notes:
        return
    box = layout.box()
    width = max(30, int((getattr(context.region, "width", 400) or 400) / 7.5))
    box.label(text=f"Not rendered as in Blender ({len(notes)}), from the last render:", icon="ERROR")
    for note in notes[:12]:
        for i, line in enumerate(textwrap.wrap(note, width)):
            box.label(text=("   " if i else "- ") + line)
    if len(notes) > 12:
        box.label(text=f"... {len(notes) - 12} more in the render's log")


class PHOTIC_PT_render(PhoticPanel, bpy.types.Panel):
    bl_label = "Photic"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        p = context.scene.photic
        _engine_status(layout)
        layout.prop(p, "integrator")
        col = layout.column(align=True)
        col.prop(p, "samples")
        col.prop(p, "viewport_samples")
        col.prop(p, "viewport_scale")
        row = layout.row(heading="Noise Threshold")
        row.prop(p, "use_noise_threshold", text="")
        sub = row.row()
        sub.active = p.use_noise_threshold
        sub.prop(p, "noise_threshold", text="")
        sub = layout.row()
        sub.active = p.use_noise_threshold
        sub.prop(p, "adaptive_min_samples")
        layout.prop(p, "radiometer_samples")
        row = layout.row(heading="Target Error")
        row.prop(p, "use_target_error", text="")
        sub = row.row()
        sub.active = p.use_target_error
        sub.prop(p, "target_error", text="")
        layout.prop(p, "auto_exposure")
        col = layout.column(heading="Denoising", align=True)
        col.prop(p, "denoise")
        col.prop(p, "denoising_data")
        col = layout.column(align=True)
        col.prop(p, "seed")
        col.prop(p, "threads")
        col.prop(p, "max_depth")
        layout.prop(p, "dask_scheduler")
        if p.dask_scheduler.strip():
            layout.prop(p, "dask_allow_remote")


class PHOTIC_PT_bands(PhoticPanel, bpy.types.Panel):
    bl_label = "Spectral Bands"
    bl_context = "render"
    bl_parent_id = "PHOTIC_PT_render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        p = context.scene.photic
        layout.prop(p, "bands")
        if p.bands == "SINGLE":
            layout.prop(p, "band_center_nm")
            layout.prop(p, "band_width_nm")
        elif p.bands == "CUSTOM":
            layout.prop(p, "custom_bands")


class PHOTIC_PT_beams(PhoticPanel, bpy.types.Panel):
    bl_label = "Beams and Forward Scattering"
    bl_context = "render"
    bl_parent_id = "PHOTIC_PT_render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        p = context.scene.photic
        layout.prop(p, "forward_cone")
        row = layout.row()
        row.active = p.forward_cone == "ANGLE"
        row.prop(p, "forward_cone_angle")
        layout.prop(p, "beam_max_level")
        layout.prop(p, "raman")
        layout.prop(p, "write_tables")


class PHOTIC_PT_radiometer_results(PhoticPanel, bpy.types.Panel):
    bl_label = "Radiometer Results"
    bl_context = "render"
    bl_parent_id = "PHOTIC_PT_render"

    def draw(self, context):
        layout = self.layout
        layout.operator("photic.render_radiometers", icon="LIGHT_SUN")
        last = final_render.shown_results(context.scene)
        if not last:
            layout.label(text="No radiometer results yet (F12, or Render Radiometers)")
            return
        if last["cancelled"]:
            layout.label(text="Render was cancelled: partial results", icon="INFO")
        layout.label(text="Bands (nm): " + ", ".join(last["bands"]))
        layout.label(text="Value ± standard error, per unit of the sun's spectrum (e.g. nm⁻¹)")
        for row in last["rows"][:40]:
            # '?': a standard error not to be trusted (too few passes, heavy tails)
            trusted = row.get("trusted", [True] * len(row["value"]))
            values = ", ".join(f"{v:.4g}±{e:.2g}{'' if t else '?'}"
                               for v, e, t in zip(row["value"], row["stderr"], trusted))
            extra = f" ({row['bins']} bins, first shown)" if row["bins"] > 1 else ""
            units = final_render.short_units(row.get("units", ""))
            layout.label(text=f"{row['name']} {row['quantity']} [{row['medium']}]: {values} {units}{extra}")
            if row.get("target_error") is not None and not row.get("target_reached"):
                layout.label(text=f"    target error {100 * row['target_error']:.3g} % not reached "
                                  f"in {row['samples']} samples (raise Radiometer Samples)",
                             icon="INFO")
            if not all(trusted):
                layout.label(text="    ? error not to be trusted: " + ", ".join(row.get("notes", [])),
                             icon="ERROR")
        if len(last["rows"]) > 40:
            layout.label(text=f"... {len(last['rows']) - 40} more in the radiometer tables")


class PHOTIC_PT_object(PhoticPanel, bpy.types.Panel):
    bl_label = "Photic"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.object is not None and \
            context.object.type in {"MESH", "EMPTY", "CURVE", "SURFACE", "META", "FONT"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        obj = context.object
        p = obj.photic
        _draw_notes(layout, context, "OBJECT", obj.name)
        layout.prop(p, "role")
        if p.role in WATER_ROLES:
            kind = water_types.effective(p)
            layout.prop(p, "water_type")
            if kind != water_types.CUSTOM:
                for i, line in enumerate(textwrap.wrap(water_types.describe(kind), 34)):
                    layout.label(text=line, icon="INFO" if i == 0 else "BLANK1")
            else:
                if p.water_type != water_types.CUSTOM:  # (a file from before water types)
                    layout.label(text="Custom: this file's own IOPs", icon="INFO")
                _draw_iops(layout, p, "iop_source", "iop_model", "")
            layout.prop(p, "ior")
        if p.role == "WATER_SURFACE":
            layout.prop(p, "surface_shape")
            ocean = next((m for m in obj.modifiers if m.type == "OCEAN" and m.show_render), None)
            if ocean is not None and p.surface_shape != "MESH":
                col = layout.column()
                col.alert = True
                col.label(text=f"Ocean modifier '{ocean.name}' is not rendered", icon="ERROR")
                col.operator("photic.use_ocean_modifier", icon="MOD_OCEAN")
            elif ocean is not None:
                layout.label(text=f"Waves: Ocean modifier '{ocean.name}', period "
                                  f"{ocean.spatial_size * ocean.size:g} m", icon="MOD_OCEAN")
            if p.surface_shape == "WAVES":
                col = layout.column(align=True)
                col.prop(p, "wave_spectrum")
                if p.wave_spectrum == "jonswap":
                    col.prop(p, "fetch")
                elif p.wave_spectrum == "sinusoids":
                    col.prop(p, "wave_sinusoids")
                col.prop(p, "wave_patch_size")
                col.prop(p, "wave_resolution")
                col.prop(p, "wave_mesh_refinement")
                col.prop(p, "wave_seed")
                col.prop(p, "choppiness")
                col.prop(p, "wave_depth")
            col = layout.column(align=True)
            col.prop(p, "wind_speed")
            col.prop(p, "wind_direction")
            col.prop(p, "use_roughness")
            sub = col.row()
            sub.active = p.use_roughness
            sub.prop(p, "roughness_anisotropic")
            layout.prop(p, "use_bottom")
            col = layout.column()
            col.active = p.use_bottom
            col.prop(p, "bottom_depth")
            col.prop(p, "bottom_material")
        elif p.role == "RADIOMETER":
            layout.prop(p, "quantity")
            if p.quantity == "radiance":
                layout.prop(p, "half_angle")
            elif p.quantity == "radiance_distribution":
                layout.prop(p, "polar_bins")
                layout.prop(p, "azimuth_bins")
        elif p.role == "RADIOMETER_ARRAY":
            layout.prop(p, "quantities")
            layout.prop(p, "array_layout")
            if p.array_layout != "VERTICES":
                layout.prop(p, "array_count")
                layout.prop(p, "array_spacing")
            if "radiance" in p.quantities:
                layout.prop(p, "half_angle")


class PHOTIC_PT_iop_variation(PhoticPanel, bpy.types.Panel):
    """Natural waters: a depth profile or a 3-D grid of IOPs on a water object."""

    bl_label = "IOP Variation"
    bl_context = "object"
    bl_parent_id = "PHOTIC_PT_object"

    @classmethod
    def poll(cls, context):
        return PHOTIC_PT_object.poll(context) and \
            context.object.photic.role in WATER_ROLES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        p = context.object.photic
        layout.prop(p, "iop_variation")
        if p.iop_variation in ("PROFILE", "PROFILE_GRID"):
            layout.prop(p, "profile_kind")
            if p.profile_kind == "CHLOROPHYLL":
                col = layout.column(align=True)
                col.prop(p, "chl_background")
                col.prop(p, "chl_peak")
                col.prop(p, "chl_peak_depth")
                col.prop(p, "chl_width")
                layout.prop(p, "case1_variant")
                col = layout.column(align=True)
                col.prop(p, "chl_absorption_text")
                sub = col.row()
                sub.active = p.chl_absorption_text is None
                sub.prop(p, "chl_absorption_file")
                col = layout.column(align=True)
                col.prop(p, "profile_layer_thickness")
                col.prop(p, "profile_max_depth")
            else:
                col = layout.column(align=True)
                col.prop(p, "profile_table_text")
                sub = col.row()
                sub.active = p.profile_table_text is None
                sub.prop(p, "profile_table_file")
        if p.iop_variation in ("GRID", "PROFILE_GRID"):
            base = "the IOPs above" if p.iop_variation == "GRID" else "the profile's layer"
            more = " + further fields" if len(p.grid_fields) else ""
            layout.label(text=f"IOPs = {base} + density x unit IOPs{more}")
            layout.prop(p, "grid_source")
            if p.grid_source == "NPZ":
                layout.prop(p, "grid_file")
            layout.prop(p, "grid_box")
            if p.grid_source == "VOLUME":
                row = layout.row(align=True)
                row.operator("photic.read_volume_grids", icon="FILE_REFRESH")
                row.operator("photic.read_volume_grids", text="Every Frame").every_frame = True
            _draw_unit_iops(layout, p)
            _draw_further_fields(layout, p)


class PHOTIC_PT_inelastic(PhoticPanel, bpy.types.Panel):
    """A water's fluorescence: chlorophyll's and CDOM's (export_fluorescence)."""

    bl_label = "Inelastic Light"
    bl_context = "object"
    bl_parent_id = "PHOTIC_PT_object"

    @classmethod
    def poll(cls, context):
        return PHOTIC_PT_object.poll(context) and \
            context.object.photic.role in WATER_ROLES

    def draw(self, context):
        from .export_fluorescence import from_model
        layout = self.layout
        layout.use_property_split = True
        p = context.object.photic
        modelled = from_model(p)
        layout.prop(context.scene.photic, "raman")  # (Raman scattering by water: one setting per scene)
        for key, fields, what in (
                ("chl", ("chl_quantum_yield", "chl_emission_peak_nm", "chl_emission_fwhm_nm"),
                 "the IOP model's phytoplankton (a_ph, m⁻¹)"),
                ("cdom", ("cdom_efficiency_scale",), "the IOP model's CDOM (a_CDOM, m⁻¹)")):
            layout.prop(p, f"{key}_fluorescence")
            col = layout.column()
            col.active = getattr(p, f"{key}_fluorescence")
            for name in fields:
                col.prop(p, name)
            if modelled:
                col.label(text=f"Absorption: {what}", icon="INFO")
            else:
                _value_or_bands(col, p, f"{key}_fraction", f"{key}_fraction_bands")
        layout.label(text="Passes: Photic Raman, Photic Chlorophyll, Photic CDOM")


def _draw_iops(layout, q, source: str, model: str, prefix: str) -> None:
    """IOPs as chosen by the property ``source``: the model description ``model``, or the
    coefficients and phase function named ``prefix`` + absorption, scattering, ... (the
    water's own IOPs: no prefix; a grid field's unit IOPs: "unit_")."""
    layout.prop(q, source)
    if getattr(q, source) == "MODEL":
        layout.prop(q, model)
        return
    _value_or_bands(layout, q, prefix + "absorption", prefix + "absorption_bands")
    _value_or_bands(layout, q, prefix + "scattering", prefix + "scattering_bands")
    layout.prop(q, prefix + "phase_function")
    phase = getattr(q, prefix + "phase_function")
    if phase == "henyey_greenstein":
        layout.prop(q, prefix + "hg_g")
    elif phase == "fournier_forand":
        layout.prop(q, prefix + "ff_backscatter")


def _value_or_bands(layout, q, single: str, bands: str) -> None:
    """A value for every band and its per-band list: the value greyed out while the list
    overrides it, and the scene's band order under the list."""
    col = layout.column(align=True)
    row = col.row()
    row.active = not getattr(q, bands).strip()
    row.prop(q, single)
    col.prop(q, bands)
    row = col.row()
    row.alignment = "RIGHT"
    row.label(text=f"band order: {_band_order(bpy.context)}")


def _draw_unit_iops(layout, q) -> None:
    """The unit IOPs of a grid's first field (``q``: the object's Photic properties) or of a
    further field (``q``: the field): the same property names on both."""
    _draw_iops(layout, q, "unit_source", "unit_model", "unit_")


def _draw_further_fields(layout, p) -> None:
    """The grid's further density fields, one box each (name, remove button, unit IOPs), and
    the buttons that add one or one per array or grid of the source (at most
    MAX_FURTHER_FIELDS)."""
    layout.label(text=f"Further Density Fields ({len(p.grid_fields)} of {MAX_FURTHER_FIELDS})")
    if len(p.grid_fields):
        where = "array in the Density File" if p.grid_source == "NPZ" else "grid in the Volume"
        layout.label(text=f"Each reads the {where} of its name")
    for i, f in enumerate(p.grid_fields):
        box = layout.box()
        row = box.row(align=True)
        row.prop(f, "name", text=f"Field {i + 1}")
        row.operator("photic.grid_field_remove", text="", icon="X").index = i
        _draw_unit_iops(box, f)
    row = layout.row(align=True)
    add = row.row(align=True)
    add.enabled = len(p.grid_fields) < MAX_FURTHER_FIELDS
    add.operator("photic.grid_field_add", icon="ADD")
    row.operator("photic.grid_fields_from_source", icon="IMPORT")


class PHOTIC_PT_material(PhoticPanel, bpy.types.Panel):
    bl_label = "Photic Surface"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.material is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        mat = context.material
        p = mat.photic
        _draw_notes(layout, context, "MATERIAL", mat.name)
        layout.prop(p, "use_override")
        if p.use_override:
            _value_or_bands(layout, p, "reflectance", "reflectance_bands")
        else:
            layout.label(text="Matte (Lambertian): Base Color, an Image Texture on it, Emission")
            node = find_node(mat, "BSDF_PRINCIPLED")
            if node is not None:
                layout.prop(node.inputs["Base Color"], "default_value", text="Base Color")
            else:
                layout.prop(mat, "diffuse_color", text="Color")


def _band_order(context) -> str:
    """The scene's bands in order, for per-band text fields."""
    from .bands import BandError, scene_bands
    try:
        return ", ".join(b[0] for b in scene_bands(context.scene.photic)) + " nm"
    except BandError as exc:
        return f"(bands: {exc.message})"


class PHOTIC_PT_light(PhoticPanel, bpy.types.Panel):
    bl_label = "Photic Sun"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and getattr(context, "light", None) is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        light = context.light
        _draw_notes(layout, context, "LIGHT", light.name)
        if light.type != "SUN":
            layout.label(text="Photic renders sun lamps only: this light is not used", icon="INFO")
            return
        p = light.photic
        col = layout.column()
        col.active = not p.irradiance_bands.strip()  # overridden by the per-band list
        col.prop(light, "energy", text="Irradiance (W m\u207b\u00b2 nm\u207b\u00b9)")
        col.prop(light, "color")
        layout.prop(p, "irradiance_bands", text="Per Band (W m⁻² nm⁻¹)")
        row = layout.row()
        row.alignment = "RIGHT"
        row.label(text=f"band order: {_band_order(context)}")
        layout.prop(light, "angle", text="Angular Diameter (\u00b0)")
        layout.operator("photic.clear_sky_sun", icon="LIGHT_SUN")


class PHOTIC_PT_world(PhoticPanel, bpy.types.Panel):
    bl_label = "Photic Sky"
    bl_context = "world"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.world is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        world = context.world
        p = world.photic
        _draw_notes(layout, context, "WORLD", world.name)
        layout.prop(p, "sky_model")
        if p.sky_model in {"UNIFORM", "CARDIOIDAL"}:
            layout.prop(p, "radiance")
            layout.prop(p, "color")
        elif p.sky_model == "FROM_WORLD":
            layout.label(text="Background colour, Environment Texture; Sky Texture approximated")
            node = find_node(world, "BACKGROUND")
            if node is not None:
                layout.prop(node.inputs["Color"], "default_value", text="Color")
                layout.prop(node.inputs["Strength"], "default_value", text="Radiance Scale")
            else:
                layout.prop(world, "color")


classes = (PHOTIC_PT_render, PHOTIC_PT_bands, PHOTIC_PT_beams, PHOTIC_PT_radiometer_results,
           PHOTIC_PT_object, PHOTIC_PT_iop_variation, PHOTIC_PT_inelastic, PHOTIC_PT_material,
           PHOTIC_PT_light, PHOTIC_PT_world)
