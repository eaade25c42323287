"""Photic's settings on Blender data: ``Object.photic``, ``Material.photic``, ``World.photic``
and ``Scene.photic``.

Every property carries its unit, range and meaning; the export (``export.py`` and its
``export_*`` modules) checks what a range cannot (per-band lists, NaN, closed water meshes) and
names the property when it fails.
Each group attaches itself to its ID type in ``register`` and removes itself in ``unregister``.
"""

import math

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, PointerProperty, StringProperty)

from . import water_types

ROLES = [
    ("NONE", "None", "An ordinary object: opaque, Lambertian with its material's base colour"),
    ("WATER_BODY", "Water Body", "A closed mesh filled with water (a pool, a tank, a lake's volume)"),
    ("WATER_SURFACE", "Water Surface", "The surface of an ocean: water below it to the bottom "
                                       "depth (or without end), air above"),
    ("RADIOMETER", "Radiometer", "A point instrument at the object's origin measuring one quantity"),
    ("RADIOMETER_ARRAY", "Radiometer Array", "Radiometers laid out along a line, on a grid or at "
                                             "the mesh's vertices, each measuring the chosen "
                                             "quantities"),
]

QUANTITIES = [
    ("Ed", "Ed", "Downwelling plane irradiance (W m^-2), collector facing up"),
    ("Eu", "Eu", "Upwelling plane irradiance (W m^-2), collector facing down"),
    ("Eo", "Eo", "Scalar irradiance (W m^-2), light from all directions"),
    ("Eod", "Eod", "Downwelling scalar irradiance (W m^-2)"),
    ("Eou", "Eou", "Upwelling scalar irradiance (W m^-2)"),
    ("radiance", "Radiance", "Radiance (W m^-2 sr^-1) seen in a cone along the object's -Z axis"),
    ("radiance_distribution", "Radiance Distribution",
     "Radiance (W m^-2 sr^-1) in polar x azimuth bins over the full sphere"),
]

PHASE_FUNCTIONS = [
    ("petzold", "Petzold (average particle)", "Petzold's average-particle phase function "
                                              "(San Diego harbour, tabulated), backscatter 1.83%"),
    ("fournier_forand", "Fournier-Forand", "Fournier-Forand particle phase function set by its "
                                           "backscatter fraction"),
    ("henyey_greenstein", "Henyey-Greenstein", "One-parameter analytic phase function with "
                                               "asymmetry g"),
    ("pure_water", "Pure water", "Rayleigh-like scattering of water molecules, "
                                 "1 + 0.835 cos^2"),
    ("isotropic", "Isotropic", "Equal scattering into every direction"),
]


# File paths may start with '//' (the .blend's folder); Blender 4.5+ asks properties to say so.
_BLEND_RELATIVE = ({"PATH_SUPPORTS_BLEND_RELATIVE"}
                   if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties
                   else set())


def _wave_update(self, context):
    # Regenerate the viewport preview of a wave-model surface (imported late: needs numpy).
    from . import waves_preview
    waves_preview.update_object(self.id_data)


# Density fields of a grid beside the first ('density'): the engine's MAX_GRID_FIELDS - 1
MAX_FURTHER_FIELDS = 3


def _unit_coefficients(per: str, scattering: str, b_default: float) -> dict:
    """The unit IOPs as coefficients (absorption, scattering, phase function), the same
    properties on a grid's first field (the object) and on each further field: ``per`` names
    the density ("per unit density"), ``scattering`` the scattering they add."""
    return {
        "unit_absorption": FloatProperty(
            name="Unit a (m⁻¹)", default=0.1, min=0.0, soft_max=10.0, precision=4,
            description=f"Absorption {per} (m^-1) in every band unless given per band"),
        "unit_absorption_bands": StringProperty(
            name="a per Band (m⁻¹)",
            description=f"Absorption {per} (m^-1), one per band separated by commas"),
        "unit_scattering": FloatProperty(
            name="Unit b (m⁻¹)", default=b_default, min=0.0, soft_max=100.0, precision=4,
            description=f"Scattering {per} (m^-1) in every band unless given per band"),
        "unit_scattering_bands": StringProperty(
            name="b per Band (m⁻¹)",
            description=f"Scattering {per} (m^-1), one per band separated by commas"),
        "unit_phase_function": EnumProperty(
            name="Unit Phase Function", items=PHASE_FUNCTIONS, default="fournier_forand",
            description=f"Phase function of {scattering}"),
        "unit_hg_g": FloatProperty(
            name="Unit Asymmetry g", default=0.9, min=-0.9999, max=0.9999, soft_min=-0.99,
            soft_max=0.99, precision=4,
            description=f"Henyey-Greenstein g of {scattering}, in [-0.9999, 0.9999]"),
        "unit_ff_backscatter": FloatProperty(
            name="Unit Backscatter Fraction", default=0.02, min=0.0001, max=0.15, precision=4,
            description=f"Fournier-Forand backscatter fraction of {scattering}, in [0.0001, 0.15]"),
    }


class PhoticGridField(bpy.types.PropertyGroup):
    """A further density field of a water object's 3-D grid: its densities (the array or
    Volume grid of its name) times its own unit IOPs are added to the IOPs, on the voxels of
    the first field ('density')."""

    name: StringProperty(
        name="Name", default="cdom",
        description="The field's name, which is also where its densities are: the array of "
                    "this name in the Density File (.npz), or the float grid of this name in "
                    "the Grid Box's Volume object; on the same voxels as 'density' (the same "
                    "shape), >= 0. Not 'density' (the first field's)")
    unit_source: EnumProperty(
        name="Unit IOPs", default="MODEL",
        items=[("MODEL", "IOP Model", "A model description in JSON (docs/iop-models.md); pure "
                                      "water is not added unless it names \"water\""),
               ("VALUES", "Coefficients", "Absorption and scattering per unit density as "
                                          "given below (File > Import makes a scene's explicit "
                                          "unit IOPs these)")],
        description="IOPs added per unit of this field's density")
    unit_model: StringProperty(
        name="Unit IOP Model", default='{"model": "cdom", "a_ref": 0.5}',
        description="IOPs per unit of this field's density as a model description in JSON "
                    "(docs/iop-models.md), e.g. {\"model\": \"cdom\", \"a_ref\": 0.5} (CDOM "
                    "absorbing 0.5 m^-1 at 440 nm per unit density); pure water is not added "
                    "unless it names \"water\"")
    __annotations__.update(_unit_coefficients("per unit of this field's density",
                                              "this field's scattering", 0.0))


def _iops_edited(self, context):
    """An IOP edited by hand: the water is 'Custom' from now on (its Water Type gives way)."""
    if self.water_type != water_types.CUSTOM:
        self.water_type = water_types.CUSTOM


def _water_type_update(self, context):
    """'Custom' chosen for a water whose IOPs were never set: they start as the default water
    type's model (editable), not as the grey coefficients below it."""
    if self.water_type == water_types.CUSTOM and \
            not any(self.is_property_set(k) for k in water_types.IOP_FIELDS):
        self.iop_source = "MODEL"
        self.iop_model = water_types.model_json(water_types.DEFAULT)


class PhoticObjectProperties(bpy.types.PropertyGroup):
    """Photic role and parameters of an object."""

    role: EnumProperty(name="Role", items=ROLES, default="NONE",
                       description="What the object is to Photic")

    # Water (bodies and surfaces)
    water_type: EnumProperty(
        name="Water Type", items=water_types.enum_items(), default=water_types.DEFAULT,
        update=_water_type_update,
        description="The water's absorption and scattering from a measured natural water "
                    f"({water_types.SOURCE}; docs/blender.md), or Custom: the IOPs below. "
                    "Editing an IOP makes the water Custom")

    iop_source: EnumProperty(
        name="IOPs", default="VALUES",
        items=[("VALUES", "Coefficients", "Absorption and scattering as given below"),
               ("PURE_WATER", "Pure Water + Additions",
                "Pure water (absorption: Pope & Fry 1997, averaged over each band; scattering: "
                "0.00288 (wavelength/500 nm)^-4.32 per m with the pure-water phase function) "
                "plus the absorption and scattering given below (e.g. of particles)"),
               ("MODEL", "IOP Model", "The water community's models (CDOM, particles, Case 1, "
                                      "mixtures, installed plugins) as described in 'IOP Model' "
                                      "(the scene format's iop_model, docs/iop-models.md)")],
        description="Where the water's absorption and scattering come from", update=_iops_edited)
    iop_model: StringProperty(
        name="IOP Model",
        default='{"model": "mixture", "components": [{"model": "cdom", "a_ref": 0.05}, '
                '{"model": "particles", "b_ref": 0.2}]}',
        description="IOP model description in JSON (docs/iop-models.md), evaluated per band; "
                    "pure water is included unless \"water\": \"none\"", update=_iops_edited)
    absorption: FloatProperty(
        name="Absorption (m⁻¹)", default=0.1, min=0.0, soft_max=10.0, precision=4,
        description="Absorption coefficient a (m^-1), the same in every band unless "
                    "'Absorption per band' is given", update=_iops_edited)
    absorption_bands: StringProperty(
        name="a per Band (m⁻¹)",
        description="Absorption coefficients a (m^-1), one per band in the scene's band order, "
                    "separated by commas; empty: use 'Absorption a' in every band",
        update=_iops_edited)
    scattering: FloatProperty(
        name="Scattering (m⁻¹)", default=0.2, min=0.0, soft_max=10.0, precision=4,
        description="Scattering coefficient b (m^-1), the same in every band unless "
                    "'Scattering per band' is given", update=_iops_edited)
    scattering_bands: StringProperty(
        name="b per Band (m⁻¹)",
        description="Scattering coefficients b (m^-1), one per band, separated by commas; "
                    "empty: use 'Scattering b' in every band", update=_iops_edited)
    phase_function: EnumProperty(name="Phase Function", items=PHASE_FUNCTIONS,
                                 default="petzold", update=_iops_edited,
                                 description="Angular distribution of scattered light")
    # (the engine's range, photic.parameters; dragging stops at +-0.99)
    hg_g: FloatProperty(name="Asymmetry g", default=0.9, min=-0.9999, max=0.9999, soft_min=-0.99,
                        soft_max=0.99, precision=4, update=_iops_edited,
                        description="Henyey-Greenstein mean cosine of scattering "
                                    "(dimensionless), in [-0.9999, 0.9999]")
    # (at most 0.15: the range of the Fournier-Forand parameterisation the engine uses)
    ff_backscatter: FloatProperty(
        name="Backscatter Fraction", default=0.0183, min=0.0001, max=0.15, precision=4,
        description="Fournier-Forand backscatter fraction b_b/b (dimensionless), "
                    "in [0.0001, 0.15]", update=_iops_edited)
    ior: FloatProperty(name="Refractive Index", default=1.34, min=1.0, max=2.0, precision=3,
                       description="Refractive index of the water relative to air "
                                   "(dimensionless), in [1, 2]")
    surface_shape: EnumProperty(
        name="Surface Shape", default="FLAT",
        items=[("FLAT", "Flat", "A flat sea at the height of the object's origin, without end"),
               ("MESH", "Mesh Patch", "The evaluated mesh as a height field, repeated without "
                                      "end with its x and y extent as the period (the patch "
                                      "must tile seamlessly)"),
               ("WAVES", "Wave Model", "A wave patch generated from an ocean spectrum at the "
                                       "frame's time, repeated without end; the object's mesh "
                                       "shows it (regenerated when a wave setting or the frame "
                                       "changes)")],
        description="How the water surface is shaped", update=_wave_update)
    flat_mesh: PointerProperty(
        type=bpy.types.Mesh, name="Mesh Before Waves", options={"HIDDEN"},
        description="The object's own mesh while a Wave Model preview stands in for it "
                    "(given back when Surface Shape leaves Wave Model)")
    wave_spectrum: EnumProperty(
        name="Spectrum", default="pierson_moskowitz", update=_wave_update,
        items=[("pierson_moskowitz", "Pierson-Moskowitz", "Fully developed wind sea"),
               ("jonswap", "JONSWAP", "Fetch-limited wind sea (peak enhancement 3.3)"),
               ("phillips", "Phillips", "Tessendorf's Phillips spectrum"),
               ("sinusoids", "Sinusoids", "A sum of the sinusoidal waves listed in "
                                          "'Sinusoids'")],
        description="Ocean wave spectrum of the wave model")
    wave_sinusoids: StringProperty(
        name="Sinusoids", default="0.05:10:0:0, 0.02:5:60:1",
        update=_wave_update,
        description="Waves as 'amplitude_m:wavelength_m:direction_deg:phase_rad' separated by "
                    "commas; each must repeat a whole number of times over the patch")
    wind_speed: FloatProperty(name="Wind (m/s)", default=5.0, min=0.0, max=50.0, precision=2,
                              update=_wave_update,
                              description="Wind speed at 10 m above the sea (m/s): the wave "
                                          "spectrum's and the Cox-Munk roughness's wind")
    wind_direction: FloatProperty(name="Wind Direction", subtype="ANGLE", default=0.0,
                                  update=_wave_update,
                                  description="Direction the wind blows towards, from +X "
                                              "towards +Y (degrees)")
    # (at most 2e6 m: the engine's limit, Embree traces in single precision)
    wave_patch_size: FloatProperty(name="Patch Size", default=50.0, min=0.1, max=2e6,
                                   soft_max=1000.0, unit="LENGTH", update=_wave_update,
                                   description="Side of the square wave patch, its period (m)")
    wave_resolution: IntProperty(name="Resolution", default=64, min=4, max=1024,
                                 update=_wave_update,
                                 description="Grid points per side of the wave patch")
    wave_mesh_refinement: IntProperty(name="Mesh Refinement", default=1, min=1, max=16,
                                      description="Triangles this many times finer than the grid: "
                                                  "the same waves, sampled finer, so that caustics "
                                                  "deep down follow the shortest waves (costs its "
                                                  "square in triangles; the viewport shows the grid)")
    wave_seed: IntProperty(name="Seed", default=0, min=0, update=_wave_update,
                           description="Seed of the random wave amplitudes")
    choppiness: FloatProperty(name="Choppiness", default=0.0, min=0.0, max=3.0,
                              update=_wave_update,
                              description="Horizontal (choppy) displacement factor "
                                          "(dimensionless); 0: none. The surface must not fold")
    fetch: FloatProperty(name="Fetch", default=50000.0, min=1.0, unit="LENGTH",
                         update=_wave_update,
                         description="JONSWAP: distance over which the wind has blown (m)")
    wave_depth: FloatProperty(name="Water Depth", default=0.0, min=0.0, unit="LENGTH",
                              update=_wave_update,
                              description="Depth in the waves' dispersion relation (m); 0: "
                                          "deep water")
    use_roughness: BoolProperty(name="Sub-pixel Roughness", default=False,
                                description="Cox-Munk facet slopes for the wind speed below "
                                            "the resolved waves: sun glint, sky reflection and "
                                            "the spread of the transmitted sun")
    roughness_anisotropic: BoolProperty(name="Anisotropic", default=False,
                                        description="Upwind and crosswind slope variances "
                                                    "instead of the isotropic total")
    use_bottom: BoolProperty(name="Bottom", default=False,
                             description="A flat, opaque sea floor below the water surface")
    # (at most 1e6 m: the engine's limit, Embree traces in single precision)
    bottom_depth: FloatProperty(name="Bottom Depth", default=10.0, min=0.001, max=1e6,
                                soft_max=1000.0, unit="LENGTH",
                                description="Depth of the sea floor below the mean water "
                                            "surface (m), > 0")
    bottom_material: PointerProperty(type=bpy.types.Material, name="Bottom Material",
                                     description="Material of the sea floor (its base colour "
                                                 "or Photic reflectance); none: grey 0.18")

    # Natural waters: IOPs that vary with depth (a profile) or in 3-D (a density grid)
    iop_variation: EnumProperty(
        name="IOP Variation", default="NONE",
        items=[("NONE", "Homogeneous", "The same IOPs everywhere in the water"),
               ("PROFILE", "Depth Profile", "Horizontal layers: a Gaussian chlorophyll maximum "
                                            "through the Case-1 model, or a table of "
                                            "coefficients against depth"),
               ("GRID", "3-D Grid", "The IOPs above plus a density field times the unit IOPs "
                                    "below, over a box (a sediment plume, a bloom)"),
               ("PROFILE_GRID", "Depth Profile + 3-D Grid",
                "A depth profile as above plus a density field times the unit IOPs over a box "
                "(a plume in stratified water)")],
        description="How the water's IOPs vary in space (docs/blender.md, 'Natural waters')")
    profile_kind: EnumProperty(
        name="Profile", default="CHLOROPHYLL",
        items=[("CHLOROPHYLL", "Chlorophyll Maximum",
                "C(d) = background + peak exp(-(d - depth of peak)^2 / (2 width^2)) driving "
                "the Case-1 model; replaces the IOPs above"),
               ("TABLE", "Layer Table", "Absorption and scattering per band at each depth from "
                                        "a CSV table (Text or file), with the phase function "
                                        "above (and pure water with 'Pure Water + Additions')")],
        description="Where the depth profile comes from")
    chl_background: FloatProperty(name="Base (mg m⁻³)", default=0.1, min=0.0, soft_max=50.0,
                                  precision=3, description="Chlorophyll concentration far from "
                                                           "the maximum (mg m^-3), >= 0")
    chl_peak: FloatProperty(name="Peak (mg m⁻³)", default=1.0, min=0.0, soft_max=50.0, precision=3,
                            description="Chlorophyll added at the depth of the maximum "
                                        "(mg m^-3), >= 0")
    chl_peak_depth: FloatProperty(name="Depth of Peak", default=20.0, min=0.0, soft_max=200.0,
                                  unit="LENGTH", description="Depth of the chlorophyll maximum "
                                                             "below the water level (m)")
    chl_width: FloatProperty(name="Width", default=5.0, min=0.001, soft_max=100.0,
                             unit="LENGTH", description="Standard deviation of the Gaussian "
                                                        "maximum (m), > 0")
    case1_variant: EnumProperty(
        name="Case-1 Model", default="classic",
        items=[("classic", "Classic", "Prieur & Sathyendranath / Gordon & Morel (table "
                                      "columns wavelength_nm, a_star)"),
               ("new", "New", "Bricaud et al. 1998 / Morel & Maritorena 2001 (table columns "
                              "wavelength_nm, A, E)")],
        description="Case-1 IOP model driven by the chlorophyll profile (docs/iop-models.md)")
    chl_absorption_text: PointerProperty(
        type=bpy.types.Text, name="Chl Absorption Text",
        description="Chlorophyll-specific absorption as CSV in a Text data-block (header "
                    "wavelength_nm,a_star or wavelength_nm,A,E); none is bundled with Photic")
    chl_absorption_file: StringProperty(
        options=_BLEND_RELATIVE,
        name="Chl Absorption File", subtype="FILE_PATH",
        description="The same table as a CSV file (used when no Text is chosen; '//' is the "
                    ".blend's folder)")
    profile_table_text: PointerProperty(
        type=bpy.types.Text, name="Layer Table Text",
        description="Layer table as CSV in a Text data-block: columns depth_m, then a_<band> "
                    "and b_<band> for every band (e.g. a_450, b_450), or single columns a and "
                    "b for all bands; one row per layer top (m below the water level)")
    profile_table_file: StringProperty(
        options=_BLEND_RELATIVE,
        name="Layer Table File", subtype="FILE_PATH",
        description="The same table as a CSV file (used when no Text is chosen; '//' is the "
                    ".blend's folder)")
    profile_layer_thickness: FloatProperty(
        name="Layer Thickness", default=1.0, min=0.01, soft_max=20.0, unit="LENGTH",
        description="Thickness of the layers the chlorophyll profile is averaged into (m)")
    profile_max_depth: FloatProperty(
        name="Profile Depth", default=60.0, min=0.01, soft_max=1000.0, unit="LENGTH",
        description="Depth below the water level down to which layers are made (m); the "
                    "deepest layer goes on below it")
    grid_source: EnumProperty(
        name="Density", default="NPZ",
        items=[("NPZ", "Density File (.npz)", "A numpy .npz holding a float array 'density' "
                                              "(nx, ny, nz), x first, over the grid box"),
               ("VOLUME", "Volume Object", "The 'density' grid of the Grid Box's Volume "
                                           "object (a .vdb or its geometry nodes, at the "
                                           "current frame) over its voxels' box; read through "
                                           "geometry nodes before command-line renders and "
                                           "each frame they render, and by 'Read Volume Grids' "
                                           "for F12 renders ('Every Frame': Ctrl+F12)")],
        description="Where the density field comes from")
    grid_file: StringProperty(
        options=_BLEND_RELATIVE, name="Density File", subtype="FILE_PATH",
        description="The .npz with the array 'density' (dimensionless, >= 0); '//' is the "
                    ".blend's folder")
    grid_box: PointerProperty(
        type=bpy.types.Object, name="Grid Box",
        description="Object whose world bounds are the grid's box (an Empty: +-Display Size "
                    "times its scale; a Volume or mesh: its bounding box); not rotated. "
                    "None: the water body's bounds")
    unit_source: EnumProperty(
        name="Unit IOPs", default="VALUES",
        items=[("VALUES", "Coefficients", "Absorption and scattering per unit density as "
                                          "given below"),
               ("MODEL", "IOP Model", "A model description in JSON (docs/iop-models.md); pure "
                                      "water is not added unless it names \"water\"")],
        description="IOPs added per unit of density")
    unit_model: StringProperty(
        name="Unit IOP Model",
        default='{"model": "mixture", "components": [{"model": "cdom", "a_ref": 0.3}, '
                '{"model": "particles", "b_ref": 2.0, "backscatter_fraction": 0.02, '
                '"a_ref": 0.1}]}',
        description="IOPs per unit density as a model description in JSON, e.g. sediment "
                    "particles and CDOM")
    __annotations__.update(_unit_coefficients("per unit density", "the added scattering", 1.0))
    grid_fields: CollectionProperty(
        type=PhoticGridField, name="Further Density Fields",
        description="Up to 3 more density fields on the grid's voxels, each with unit IOPs of "
                    "its own (e.g. CDOM beside sediment): IOPs = base + density x unit IOPs + "
                    "the sum of each further field's density x its unit IOPs. Each is read "
                    "like the first, by its name: an array of the Density File or a grid of "
                    "the Volume object")

    # Inelastic light: the water's fluorescence (photic.inelastic); off in files from before it.
    # The absorption that fluoresces comes from the water's IOP model where it has one, else
    # from the shares below (export_fluorescence).
    chl_fluorescence: BoolProperty(
        name="Chlorophyll Fluorescence", default=False,
        description="The phytoplankton re-emit the quantum yield's share of the photons their "
                    "chlorophyll absorbs (370-690 nm), isotropically around the emission peak: "
                    "the Photic Chlorophyll pass and the tables' component 'chlorophyll'. Their "
                    "absorption: the IOP model's phytoplankton (Case 1, a Chlorophyll Maximum "
                    "profile), or the Phytoplankton Share of the coefficients' absorption")
    chl_quantum_yield: FloatProperty(
        name="Quantum Yield", default=0.02, min=0.0, max=1.0, precision=3,
        description="Photons emitted per photon the chlorophyll absorbs (dimensionless), in "
                    "[0, 1]; natural waters about 0.01-0.05")
    chl_emission_peak_nm: FloatProperty(
        name="Peak (nm)", default=685.0, min=300.0, max=1000.0, precision=1,
        description="Centre of the fluorescence's Gaussian emission (nm); chlorophyll a in "
                    "vivo: 685 nm")
    chl_emission_fwhm_nm: FloatProperty(
        name="FWHM (nm)", default=25.0, min=0.1, max=200.0, precision=1,
        description="Full width at half maximum of the emission (nm), in (0, 200]")
    chl_fraction: FloatProperty(
        name="Phytoplankton Share of a", default=0.0, min=0.0, max=1.0, precision=3,
        description="For IOPs given as coefficients (or a layer table): the share of the "
                    "water's total absorption a (dimensionless, 0-1, pure water included) that "
                    "is the phytoplankton's, in every band unless given per band")
    chl_fraction_bands: StringProperty(
        name="Share per Band",
        description="The phytoplankton's share of the water's absorption, one per band in "
                    "[0, 1], separated by commas; empty: 'Phytoplankton Share of a' in every "
                    "band")
    cdom_fluorescence: BoolProperty(
        name="CDOM Fluorescence", default=False,
        description="Coloured dissolved organic matter re-emits some of the light it absorbs "
                    "(310-550 nm), broadly and red of the excitation, with Hawes' (1992) "
                    "quantum efficiency of fulvic acid: the Photic CDOM pass and the tables' "
                    "component 'cdom'. Its absorption: the IOP model's CDOM (CDOM and Case-1 "
                    "models, the water types' CDOM), or the CDOM Share of the coefficients' "
                    "absorption")
    cdom_efficiency_scale: FloatProperty(
        name="Efficiency Scale", default=1.0, min=0.0, max=50.0, soft_max=5.0,
        precision=3,
        description="Factor on Hawes' (1992) spectral fluorescence quantum efficiency "
                    "(dimensionless, in [0, 50]; 1: Hawes' values, a quantum yield of about "
                    "1-2 %)")
    cdom_fraction: FloatProperty(
        name="CDOM Share of a", default=0.0, min=0.0, max=1.0, precision=3,
        description="For IOPs given as coefficients (or a layer table): the share of the "
                    "water's total absorption a (dimensionless, 0-1, pure water included) that "
                    "is CDOM's, in every band unless given per band")
    cdom_fraction_bands: StringProperty(
        name="Share per Band",
        description="CDOM's share of the water's absorption, one per band in [0, 1], "
                    "separated by commas; empty: 'CDOM Share of a' in every band")

    # Radiometers
    quantity: EnumProperty(name="Quantity", items=QUANTITIES, default="Ed",
                           description="What the radiometer measures")
    quantities: EnumProperty(name="Quantities", items=QUANTITIES, options={"ENUM_FLAG"},
                             default={"Ed", "Eu", "Eo"},
                             description="What each radiometer of the array measures")
    half_angle: FloatProperty(name="Cap Half-Angle", subtype="ANGLE", default=math.radians(12.9),
                              min=math.radians(0.01), max=math.radians(90.0),
                              description="Half-angle of a radiance meter's field of view "
                                          "(degrees), in [0.01, 90]")
    polar_bins: IntProperty(name="Polar Bins", default=18, min=1, max=180,
                            description="Radiance distribution: bins in zenith angle over 180 "
                                        "degrees")
    azimuth_bins: IntProperty(name="Azimuth Bins", default=24, min=1, max=360,
                              description="Radiance distribution: bins in azimuth over 360 "
                                          "degrees")
    array_layout: EnumProperty(
        name="Layout", default="LINE",
        items=[("LINE", "Line", "Along the object's local -Z axis from its origin (a profile)"),
               ("GRID", "Grid", "A grid in the object's local XY plane centred on its origin"),
               ("VERTICES", "Mesh Vertices", "At the vertices of the object's evaluated mesh")],
        description="Where the radiometers of the array are")
    array_count: IntProperty(name="Count", default=10, min=0, max=100000,
                             description="Line: number of radiometers; grid: per side")
    array_spacing: FloatProperty(name="Spacing", default=1.0, min=0.0, soft_max=100.0,
                                 unit="LENGTH", description="Distance between neighbouring "
                                                            "radiometers (m), in the object's "
                                                            "scale")

    @classmethod
    def register(cls):
        bpy.types.Object.photic = PointerProperty(type=cls, name="Photic",
                                                  description="Photic settings of the object")

    @classmethod
    def unregister(cls):
        del bpy.types.Object.photic


class PhoticMaterialProperties(bpy.types.PropertyGroup):
    """Optional Photic reflectance overriding the Principled BSDF base colour."""

    use_override: BoolProperty(name="Photic Reflectance", default=False,
                               description="Use the reflectance below instead of the base "
                                           "colour of the Principled BSDF")
    reflectance: FloatProperty(name="Reflectance", default=0.2, min=0.0, max=1.0,
                               description="Lambertian reflectance (dimensionless) in every "
                                           "band, unless given per band")
    reflectance_bands: StringProperty(name="Reflectance per Band",
                                      description="Lambertian reflectances in [0, 1], one per "
                                                  "band, separated by commas")

    @classmethod
    def register(cls):
        bpy.types.Material.photic = PointerProperty(type=cls, name="Photic")

    @classmethod
    def unregister(cls):
        del bpy.types.Material.photic


class PhoticLightProperties(bpy.types.PropertyGroup):
    """A sun lamp's irradiance per band, overriding its Strength and Color."""

    irradiance_bands: StringProperty(
        name="E Bands (W m⁻²)",
        description="Sun irradiance normal to the sun (W m^-2 per unit of the band's spectrum, "
                    "e.g. W m^-2 nm^-1), one per band in the scene's band order, separated by "
                    "commas; when given, Strength and Color are not used")

    @classmethod
    def register(cls):
        bpy.types.Light.photic = PointerProperty(type=cls, name="Photic")

    @classmethod
    def unregister(cls):
        del bpy.types.Light.photic


class PhoticWorldProperties(bpy.types.PropertyGroup):
    """The sky."""

    sky_model: EnumProperty(
        name="Sky", default="FROM_WORLD",
        items=[("FROM_WORLD", "From World Colour", "Uniform sky with the radiance of the world's "
                                                    "background colour times its strength"),
               ("UNIFORM", "Uniform", "The same radiance L0 from every direction above the "
                                      "horizon"),
               ("CARDIOIDAL", "Cardioidal", "Overcast sky, L = L0 (1 + 2 cos zenith angle)"),
               ("BLACK", "Black", "No sky light (sun only)")],
        description="Radiance of the sky over the upper hemisphere")
    # (at most 1e8: the engine's limit, the float32 image's variances stay finite)
    radiance: FloatProperty(name="L (W m⁻² sr⁻¹)", default=0.1, min=0.0, max=1e8,
                            soft_max=100.0,
                            description="Sky radiance scale L0 (W m^-2 sr^-1 per unit of the "
                                        "band's spectrum)")
    color: FloatVectorProperty(name="Colour", subtype="COLOR", size=3, min=0.0, max=1.0,
                               default=(1.0, 1.0, 1.0),
                               description="Relative sky radiance per colour (dimensionless)")

    @classmethod
    def register(cls):
        bpy.types.World.photic = PointerProperty(type=cls, name="Photic")

    @classmethod
    def unregister(cls):
        del bpy.types.World.photic


class PhoticSceneProperties(bpy.types.PropertyGroup):
    """Render settings."""

    integrator: EnumProperty(
        name="Integrator", default="AUTO",
        items=[("AUTO", "Automatic", "Hybrid when there is a sun, else path tracing"),
               ("HYBRID", "Hybrid (beams + paths)", "The refracted sun as beams (caustics, "
                                                     "sun shafts), path tracing for sky light "
                                                     "and multiple scattering"),
               ("PATH", "Path Tracing", "Pure volumetric path tracing (the unbiased baseline)")],
        description="How light is transported")
    samples: IntProperty(name="Samples", default=16, min=1, max=1000000, soft_max=4096,
                         description="Samples per pixel of the final render")
    viewport_samples: IntProperty(name="Viewport Samples", default=32, min=1, max=100000,
                                  description="Samples per pixel in the viewport")
    viewport_scale: IntProperty(name="Viewport Resolution", default=50, min=5, max=100,
                                subtype="PERCENTAGE",
                                description="Viewport render resolution (percent of the region)")
    radiometer_samples: IntProperty(name="Radiometer Samples", default=65536, min=1,
                                    max=2_000_000_000,
                                    description="Samples per radiometer (the standard error "
                                                "falls as 1/sqrt of this)")
    use_target_error: BoolProperty(
        name="Target Error", default=False,
        description="Stop each radiometer when its worst relative standard error (over its "
                    "bands and bins) reaches the target and can be trusted; Radiometer Samples "
                    "is then the most it may take")
    target_error: FloatProperty(name="Target Error", default=1.0, min=0.001, max=50.0,
                                soft_min=0.1, soft_max=10.0, precision=2, subtype="PERCENTAGE",
                                description="Relative standard error (1 sigma, percent of the "
                                            "value) at which a radiometer stops")
    use_noise_threshold: BoolProperty(
        name="Noise Threshold", default=False,
        description="Adaptive sampling: stop each pixel when its relative standard error is at "
                    "most the threshold in every band (after Min Samples); Samples is then the "
                    "most a pixel takes")
    noise_threshold: FloatProperty(name="Noise Threshold", default=2.0, min=0.01, max=50.0,
                                   soft_min=0.5, soft_max=20.0, precision=2, subtype="PERCENTAGE",
                                   description="Relative standard error (1 sigma, percent of the "
                                               "pixel's value; dark pixels count as a twentieth "
                                               "of the image's mean) at which a pixel stops")
    adaptive_min_samples: IntProperty(name="Min Samples", default=16, min=1, max=1_000_000,
                                      description="Samples per pixel before a pixel may stop at "
                                                  "the noise threshold")
    seed: IntProperty(name="Seed", default=0, min=0, max=2**31 - 1,
                      description="Random seed: the same seed gives the same result bit for "
                                  "bit on any number of threads")
    threads: IntProperty(name="Threads", default=0, min=0, max=1024,
                         description="CPU threads (0: all cores)")
    dask_scheduler: StringProperty(
        name="Dask Scheduler", default="",
        description="Address of a Dask scheduler (e.g. tcp://10.0.0.5:8786) whose workers "
                    "render final renders and animations as work units, streamed back into the "
                    "render view; the same numbers bit for bit as rendering here. Empty: "
                    "render on this computer")
    dask_allow_remote: BoolProperty(
        name="Allow Unencrypted Remote Scheduler", default=False,
        description="Send renders to a scheduler on another machine over plain tcp:// (no "
                    "encryption, no authentication: whoever reaches that scheduler runs code on "
                    "its workers). Off: only a scheduler on this machine (or reached through an "
                    "SSH tunnel to 127.0.0.1) or a tls:// address is used")
    max_depth: IntProperty(name="Max Depth", default=256, min=1, max=100000,
                           description="Largest number of scattering or reflection events of "
                                       "a path")
    bands: EnumProperty(
        name="Bands", default="RGB",
        items=[("RGB", "RGB (620, 550, 460 nm)", "Three bands shown as red, green and blue"),
               ("SINGLE", "Single Band", "One band, shown as grey"),
               ("CUSTOM", "Custom", "A list of bands 'centre:width' in nm")],
        description="Spectral bands rendered (per-band values in radiometer tables)")
    band_center_nm: FloatProperty(name="Centre (nm)", default=550.0, min=200.0, max=3000.0,
                                  description="Centre wavelength of the single band (nm)")
    band_width_nm: FloatProperty(name="Width (nm)", default=10.0, min=0.001, max=1000.0,
                                 description="Width of the single band (nm)")
    custom_bands: StringProperty(name="Band List (nm)", default="450:20, 500:20, 550:20, 600:20",
                                 description="Bands as 'centre_nm:width_nm' separated by "
                                             "commas, e.g. '412:10, 443:10, 490:10'")
    forward_cone: EnumProperty(
        name="Forward Cone", default="AUTO",
        items=[("AUTO", "Automatic", "3 degrees in optically deep water (c x depth > 10), "
                                     "else none"),
               ("ANGLE", "Angle", "Scattering within the given half-angle stays in the beams")],
        description="Forward scattering kept within a narrow cone around the beams")
    forward_cone_angle: FloatProperty(name="Cone Half-Angle", subtype="ANGLE", default=0.0,
                                      min=0.0, max=math.radians(30.0),
                                      description="Half-angle of the forward-scattering cone "
                                                  "(degrees), in [0, 30]; 0: none")
    beam_max_level: IntProperty(name="Beam Refinement", default=5, min=0, max=10,
                                description="Levels of adaptive subdivision of a surface "
                                            "triangle's beam where its rays disagree (each "
                                            "level halves the beam cell size)")
    raman: EnumProperty(
        name="Raman Scattering", default="AUTO",
        # (numbered so that a .blend saved with the former checkbox reads False as OFF and
        # True as ON)
        items=[("AUTO", "Auto", "On where the scene's bands can receive Raman light: where a "
                                "band's excitation, about 60-100 nm bluer than it, lies among "
                                "the bands (else purely elastic)", "NONE", 2),
               ("ON", "On", "Raman scattering by water in any scene", "NONE", 1),
               ("OFF", "Off", "Purely elastic: no Raman scattering", "NONE", 0)],
        description="Raman scattering by water: light shifted by about 3,400 cm^-1 into the scene's "
                    "longer-wavelength bands (b_R 2.7e-4 m^-1 at 488 nm excitation), in both "
                    "integrators; the component 'raman' of the radiometer tables and the "
                    "Photic Raman pass")
    auto_exposure: BoolProperty(
        name="Auto Exposure", default=True,
        description="After a render (and in the viewport), set the scene's display exposure "
                    "(Color Management > Exposure) so that the image's average brightness shows "
                    "as mid-grey. Only the display changes: the passes, the EXR and the "
                    "radiometer tables keep their radiometric values")
    denoise: BoolProperty(
        name="Denoise", default=False,
        description="After a final render, denoise the Combined pass with OpenImageDenoise, "
                    "guided by the Denoising Albedo and Normal passes; the noisy image stays in "
                    "the Noisy Image pass. A denoised image has no standard error and smooths "
                    "caustics at low sample counts: keep the passes and tables for numbers")
    denoising_data: BoolProperty(
        name="Denoising Data", default=False,
        description="Write the Denoising Albedo and Denoising Normal passes, for the "
                    "compositor's Denoise node (as Cycles' Denoising Data)")
    write_tables: BoolProperty(name="Radiometer Tables", default=True,
                               description="Write radiometer values and standard errors as CSV "
                                           "and JSON next to the render output")
    last_results: StringProperty(name="Last Radiometer Results", options={"HIDDEN"},
                                 description="Radiometer results of the last render (JSON)")

    @classmethod
    def register(cls):
        bpy.types.Scene.photic = PointerProperty(type=cls, name="Photic")

    @classmethod
    def unregister(cls):
        del bpy.types.Scene.photic


classes = (PhoticGridField, PhoticObjectProperties, PhoticMaterialProperties,
           PhoticLightProperties, PhoticWorldProperties, PhoticSceneProperties)
