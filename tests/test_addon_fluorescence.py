"""Inelastic light on Blender water objects (issue 42): the Inelastic Light settings of a water
(chlorophyll and CDOM fluorescence) export to the engine's ``fluorescence`` and
``cdom_fluorescence``, their absorption from the water's natural-water model (as
``photic.iop_models.fluorescent_absorption`` gives it) or from a share of its coefficients';
off by default; a scene file's fluorescence imports onto them and exports back, and what they
cannot hold is named; the Photic Chlorophyll pass is declared and filled (and written to the
EXR) where the render has chlorophyll light. Through ``import bpy`` (Blender 5.0 as a module).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import bpy  # noqa: E402

from photic.cli import load_addon  # noqa: E402

addon = load_addon()
from photic_blender import export, final_render, water_types  # noqa: E402
from photic_blender.batch import ensure_registered  # noqa: E402
from photic_blender.export_values import ExportError  # noqa: E402
from photic_blender.engine_loader import load_engine  # noqa: E402

photic = load_engine()
from photic.iop_models import fluorescent_absorption  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
CHL_TABLE = {"wavelength_nm": [400.0, 440.0, 500.0, 550.0, 600.0, 650.0, 700.0],
             "a_star": [0.69, 1.0, 0.62, 0.33, 0.26, 0.35, 0.1]}
CASE1 = {"model": "case1", "variant": "classic", "chlorophyll": 2.0,
         "chlorophyll_absorption": CHL_TABLE}


@pytest.fixture
def empty():
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    scene.render.resolution_x, scene.render.resolution_y = 4, 3
    scene.render.resolution_percentage = 100
    scene.photic.samples, scene.photic.threads = 2, 2
    scene.photic.auto_exposure = False
    return scene


def add_sea(name="Sea"):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [], [(0, 1, 2, 3)])
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.photic.role = "WATER_SURFACE"
    return obj


def add_camera(location=(0.0, 0.0, 3.0)):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = location  # (looking straight down)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    return cam


def add_sun(zenith_deg=20.0):
    obj = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    obj.data.energy = 1.0
    obj.rotation_euler = (math.radians(zenith_deg), 0.0, 0.0)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def export_current():
    return export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)


def custom_values(p, a="0.1, 0.2, 0.4", b="0.2"):
    p.water_type = water_types.CUSTOM
    p.iop_source, p.absorption_bands, p.scattering_bands = "VALUES", a, b


def bands_of(scene):
    return [photic.scene.Band(b.name, b.center_nm, b.width_nm) for b in scene.bands]


# ------------------------------------------------------------------------------------------
# Export
# ------------------------------------------------------------------------------------------

def test_fluorescence_is_off_by_default_with_the_documented_defaults(empty):
    add_camera()
    sea = add_sea()
    p = sea.photic
    assert not p.chl_fluorescence and not p.cdom_fluorescence
    assert (p.chl_quantum_yield, p.chl_emission_peak_nm, p.chl_emission_fwhm_nm) == \
        (pytest.approx(0.02), 685.0, 25.0)
    assert p.cdom_efficiency_scale == 1.0
    scene, _ = export_current()
    assert scene.water[0].fluorescence is None and scene.water[0].cdom_fluorescence is None
    assert "chlorophyll_fluorescence" not in scene.to_dict()["water"][0]
    passes = [n for n, _, _ in final_render.render_passes(empty)]
    assert final_render.CHLOROPHYLL_PASS not in passes and final_render.CDOM_PASS not in passes


def test_coefficients_fluoresce_with_their_shares_of_the_absorption(empty):
    add_camera()
    p = add_sea().photic
    custom_values(p)
    p.chl_fluorescence, p.chl_fraction_bands = True, "0.1, 0.25, 0.5"
    p.chl_quantum_yield, p.chl_emission_peak_nm, p.chl_emission_fwhm_nm = 0.035, 682.0, 20.0
    p.cdom_fluorescence, p.cdom_fraction, p.cdom_efficiency_scale = True, 0.3, 1.5
    scene, info = export_current()
    w = scene.water[0]
    np.testing.assert_allclose(w.fluorescence.absorption, [0.01, 0.05, 0.2], rtol=1e-15)
    assert (w.fluorescence.quantum_yield, w.fluorescence.peak_nm, w.fluorescence.fwhm_nm) == \
        (0.035, 682.0, 20.0)
    np.testing.assert_allclose(w.cdom_fluorescence.absorption, [0.03, 0.06, 0.12], rtol=1e-15)
    assert w.cdom_fluorescence.efficiency_scale == 1.5
    d = scene.to_dict()["water"][0]
    assert d["chlorophyll_fluorescence"]["quantum_yield"] == 0.035
    assert d["cdom_fluorescence"]["efficiency_scale"] == 1.5
    assert not info.warnings
    # Shares that add up to more than the absorption are named.
    p.cdom_fraction = 0.6
    with pytest.raises(ExportError) as err:
        export_current()
    assert str(err.value) == (
        "Object 'Sea', Photic > Phytoplankton Share of a per Band (photic.chl_fraction_bands) + "
        "CDOM Share of a (photic.cdom_fraction): add up to more than 1 in band 460 nm: both are "
        "parts of the water's absorption, together at most all of it")


def test_pure_water_plus_additions_takes_the_share_of_the_total_absorption(empty):
    add_camera()
    p = add_sea().photic
    custom_values(p)
    p.iop_source = "PURE_WATER"
    p.chl_fluorescence, p.chl_fraction = True, 0.5
    scene, _ = export_current()
    w = scene.water[0]
    np.testing.assert_allclose(w.fluorescence.absorption, 0.5 * w.iops.absorption, rtol=1e-15)


@pytest.mark.parametrize("spec", [CASE1, {"model": "cdom", "a_ref": 0.3},
                                  {"model": "mixture", "components": [CASE1, {"model": "cdom",
                                                                              "a_ref": 0.1}]}])
def test_an_iop_model_gives_the_absorption_that_fluoresces(empty, spec):
    add_camera()
    p = add_sea().photic
    p.water_type, p.iop_source, p.iop_model = water_types.CUSTOM, "MODEL", json.dumps(spec)
    p.chl_fluorescence = p.cdom_fluorescence = True
    scene, info = export_current()
    expected = fluorescent_absorption(spec, bands_of(scene))
    w = scene.water[0]
    np.testing.assert_array_equal(w.fluorescence.absorption, expected["phytoplankton"])
    np.testing.assert_array_equal(w.cdom_fluorescence.absorption, expected["cdom"])
    assert np.all(expected["cdom"] > 0)
    # A model without phytoplankton (CDOM alone): on, but dark, and the object's note says why.
    dark = [t for t in info.warnings if "Chlorophyll Fluorescence is on" in t]
    assert bool(dark) == (spec["model"] == "cdom")
    if dark:
        assert "Object 'Sea'" in dark[0] and "Case-1" in dark[0]


def test_a_water_type_fluoresces_with_its_cdom(empty):
    add_camera()
    p = add_sea().photic
    p.water_type = "TURBID"
    p.cdom_fluorescence = True
    scene, info = export_current()
    expected = fluorescent_absorption(water_types.model("TURBID"), bands_of(scene))["cdom"]
    np.testing.assert_array_equal(scene.water[0].cdom_fluorescence.absorption, expected)
    assert np.all(expected > 0) and not info.warnings


def test_a_chlorophyll_profile_fluoresces_layer_by_layer(empty):
    from photic.profiles import gaussian_chlorophyll, profile_from_function
    add_camera()
    p = add_sea().photic
    text = bpy.data.texts.new("chl")
    text.from_string("wavelength_nm,a_star\n" + "".join(
        f"{w},{a}\n" for w, a in zip(CHL_TABLE["wavelength_nm"], CHL_TABLE["a_star"])))
    p.iop_variation, p.profile_kind, p.chl_absorption_text = "PROFILE", "CHLOROPHYLL", text
    p.chl_background, p.chl_peak, p.chl_peak_depth, p.chl_width = 0.2, 1.5, 7.0, 2.0
    p.profile_layer_thickness, p.profile_max_depth = 2.0, 10.0
    p.chl_fluorescence = True
    scene, _ = export_current()
    table = {"source": "Text 'chl'", **CHL_TABLE}
    chl = gaussian_chlorophyll(0.2, 1.5, -7.0, 2.0)
    bands = bands_of(scene)
    expected = profile_from_function(  # (a_ph as an "absorption", depth-averaged as the IOPs)
        lambda z: photic.scene.IOPs(fluorescent_absorption(
            {"model": "case1", "variant": "classic", "chlorophyll": chl(z),
             "chlorophyll_absorption": table}, bands)["phytoplankton"], []),
        -2.0 * np.arange(5))
    a = scene.water[0].fluorescence.absorption
    assert a.shape == (5, 3)
    np.testing.assert_allclose(a, [x.absorption for x in expected.layers], rtol=1e-12)
    assert int(np.argmax(a[:, 2])) == 3  # the layer of the maximum (6-8 m) in the blue


def test_a_layer_table_fluoresces_with_its_share_of_each_layer(empty):
    add_camera()
    p = add_sea().photic
    custom_values(p)
    text = bpy.data.texts.new("layers")
    text.from_string("depth_m,a,b\n0,0.1,0.2\n3,0.4,0.2\n")
    p.iop_variation, p.profile_kind, p.profile_table_text = "PROFILE", "TABLE", text
    p.cdom_fluorescence, p.cdom_fraction = True, 0.5
    scene, _ = export_current()
    np.testing.assert_allclose(scene.water[0].cdom_fluorescence.absorption,
                               [[0.05] * 3, [0.2] * 3], rtol=1e-15)


@pytest.mark.parametrize("text, prop, message", [
    ("0.1, 0.2", "Phytoplankton Share of a per Band (photic.chl_fraction_bands)", "has 2 values"),
    ("0.1, 1.2, 0.3", "Phytoplankton Share of a per Band (photic.chl_fraction_bands)",
     "share 1.2 is above 1"),
    ("0.1, x, 0.3", "Phytoplankton Share of a per Band (photic.chl_fraction_bands)", "x")])
def test_a_bad_share_is_named(empty, text, prop, message):
    add_camera()
    p = add_sea().photic
    custom_values(p)
    p.chl_fluorescence, p.chl_fraction_bands = True, text
    with pytest.raises(ExportError) as err:
        export_current()
    assert err.value.owner == "Object 'Sea'"
    assert err.value.prop == f"Photic > {prop}"
    assert message in err.value.message


def test_a_blend_saved_before_these_settings_renders_without_fluorescence(empty):
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "example_blends" / "canonical_problem2.blend"))
    waters = [o for o in bpy.data.objects if o.photic.role in ("WATER_BODY", "WATER_SURFACE")]
    assert waters and not any(o.photic.is_property_set("chl_fluorescence") for o in waters)
    scene, _ = export_current()
    assert all(w.fluorescence is None and w.cdom_fluorescence is None for w in scene.water)


class FakeLayout:
    """Records the properties a panel draws (each must exist on its data) and its labels."""

    def __init__(self, shown):
        self.shown, self.use_property_split, self.active, self.alert = shown, False, True, False
        self.alignment = ""

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, (data, name)
        self.shown.append(name)

    def column(self, **kw):
        return FakeLayout(self.shown)

    row = box = column

    def label(self, text="", **kw):
        self.shown.append(text)


def test_the_inelastic_light_panel_shows_the_shares_only_for_coefficients(empty):
    from types import SimpleNamespace
    from photic_blender import ui
    sea = add_sea()
    context = SimpleNamespace(engine="PHOTIC", scene=empty, object=sea)
    assert ui.PHOTIC_PT_inelastic.poll(context)
    for custom in (False, True):
        if custom:
            custom_values(sea.photic)
        shown = []
        ui.PHOTIC_PT_inelastic.draw(SimpleNamespace(layout=FakeLayout(shown)), context)
        for name in ("chl_fluorescence", "chl_quantum_yield", "chl_emission_peak_nm",
                     "chl_emission_fwhm_nm", "cdom_fluorescence", "cdom_efficiency_scale"):
            assert name in shown
        assert ("chl_fraction_bands" in shown and "cdom_fraction_bands" in shown) == custom
        assert any("IOP model's phytoplankton" in t for t in shown) != custom
    sea.photic.role = "RADIOMETER"
    assert not ui.PHOTIC_PT_inelastic.poll(context)


# ------------------------------------------------------------------------------------------
# Import
# ------------------------------------------------------------------------------------------

def fluorescent_scene_dict(layered=False, chl_absorption=(0.01, 0.05, 0.2)):
    iops = {"absorption": [0.1, 0.2, 0.4], "b": [0.2] * 3, "phase": {"type": "petzold"}}
    water = {"name": "Sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0},
             "chlorophyll_fluorescence": {"absorption": list(chl_absorption), "quantum_yield": 0.03,
                                          "peak_nm": 683.0, "fwhm_nm": 22.0},
             "cdom_fluorescence": {"absorption": [0.03, 0.06, 0.12], "efficiency_scale": 0.8}}
    if layered:
        water["iop_profile"] = {"z_top": [0.0, -3.0], "layers": [
            {"iops": iops}, {"iops": dict(iops, absorption=[0.3, 0.3, 0.5])}]}
    else:
        water["iops"] = iops
    bands = [{"name": n, "center_nm": float(n), "width_nm": 10.0} for n in ("620", "550", "460")]
    return {"photic_scene": 1, "name": "fluorescent", "bands": bands, "water": [water],
            "sky": {"type": "uniform", "radiance": 1.0},
            "cameras": [{"name": "Camera", "type": "perspective", "position": [0, -5, 3],
                         "look_at": [0, 0, 0], "fov_deg": 40, "resolution": [4, 3]}]}


def test_a_scene_files_fluorescence_imports_and_exports_back(empty):
    from photic_blender.importer import import_scene
    src = photic.scene.Scene.from_dict(fluorescent_scene_dict())
    notes = []
    created = import_scene(src, empty, notes=notes)
    assert notes == []
    p = created["Sea"].photic
    assert p.chl_fluorescence and p.cdom_fluorescence
    assert p.chl_quantum_yield == pytest.approx(0.03) and p.chl_emission_fwhm_nm == 22.0
    scene, _ = export_current()
    mine, theirs = scene.water[0], src.water[0]
    for f in ("fluorescence", "cdom_fluorescence"):
        np.testing.assert_allclose(getattr(mine, f).absorption, getattr(theirs, f).absorption,
                                   rtol=1e-15)
    assert (mine.fluorescence.quantum_yield, mine.fluorescence.peak_nm,
            mine.fluorescence.fwhm_nm) == (0.03, 683.0, 22.0)
    assert mine.cdom_fluorescence.efficiency_scale == 0.8


def test_a_fluorescence_taken_from_the_files_iop_model_imports_and_exports_back(empty, tmp_path):
    # (no "absorption": the CDOM of the water's model; pure water beside it does not fluoresce)
    d = fluorescent_scene_dict()
    water = d["water"][0]
    del water["iops"], water["chlorophyll_fluorescence"]
    water["iop_model"] = {"model": "cdom", "a_ref": 0.3}
    water["cdom_fluorescence"] = {"efficiency_scale": 2.0}
    path = tmp_path / "cdom.json"
    path.write_text(json.dumps(d))
    src = photic.scene.load_scene(path)
    assert bpy.ops.photic.import_scene(filepath=str(path)) == {"FINISHED"}
    p = bpy.data.objects["Sea"].photic
    assert p.cdom_fluorescence and not p.chl_fluorescence and p.cdom_efficiency_scale == 2.0
    scene, _ = export_current()
    np.testing.assert_allclose(scene.water[0].cdom_fluorescence.absorption,
                               src.water[0].cdom_fluorescence.absorption, rtol=1e-15)
    assert scene.water[0].fluorescence is None


def test_what_a_share_cannot_hold_is_named_when_importing(empty, tmp_path):
    from photic_blender.importer import import_scene
    # One spectrum for two layers that absorb differently: a different share in each layer.
    d = fluorescent_scene_dict(layered=True)
    d["water"][0]["chlorophyll_fluorescence"]["fwhm_nm"] = 0.05  # (below the property's range)
    notes = []
    created = import_scene(photic.scene.Scene.from_dict(d), empty, notes=notes)
    assert len(notes) == 3, notes
    assert notes[0].startswith("water 'Sea', chlorophyll_fluorescence.fwhm_nm: 0.05 is outside "
                               "the range of Photic > FWHM (nm): imported as 0.1")
    for text, fld in zip(notes[1:], ("chlorophyll_fluorescence", "cdom_fluorescence")):
        assert text.startswith(f"water 'Sea', {fld}.absorption: is not the same share of the "
                               f"water's absorption in every layer"), text
        assert "imported as the shares" in text
    p = created["Sea"].photic
    assert p.chl_fluorescence and p.cdom_fluorescence  # (imported, as near as they can be)
    # (each band's share of both layers' absorption together)
    np.testing.assert_allclose([float(x) for x in p.chl_fraction_bands.split(",")],
                               np.array([0.02, 0.1, 0.4]) / [0.4, 0.5, 0.9], rtol=1e-15)
    # Without a list, they are Python warnings; the operator reports them.
    bpy.ops.wm.read_homefile(use_empty=True)
    with pytest.warns(UserWarning) as caught:
        import_scene(photic.scene.Scene.from_dict(d), bpy.context.scene)
    assert [str(w.message) for w in caught] == [f"Photic import: {t}" for t in notes]
    path = tmp_path / "fluorescent.json"
    path.write_text(json.dumps(d))
    assert bpy.ops.photic.import_scene(filepath=str(path)) == {"FINISHED"}


# ------------------------------------------------------------------------------------------
# Passes
# ------------------------------------------------------------------------------------------

def chlorophyll_sea(empty):
    """A sea whose phytoplankton absorb at 440 nm and fluoresce into the 685 nm band, seen from
    above under the sun."""
    p = empty.photic
    p.bands, p.custom_bands, p.raman = "CUSTOM", "440:20, 685:30", "OFF"
    add_camera()
    add_sun()
    sea = add_sea().photic
    custom_values(sea, a="0.2, 0.5", b="0.1")
    sea.chl_fluorescence, sea.chl_fraction_bands, sea.chl_quantum_yield = True, "0.8, 0", 0.2
    return sea


def test_the_chlorophyll_pass_is_declared_and_filled_where_the_render_has_chlorophyll_light(empty):
    from photic.render import render as engine_render
    chlorophyll_sea(empty)
    declared = [n for n, _, _ in final_render.render_passes(empty)]
    assert final_render.CHLOROPHYLL_PASS in declared and final_render.CDOM_PASS not in declared
    scene, _ = export_current()
    img = next(iter(engine_render(scene, samples=4, threads=2).images.values()))
    assert "chlorophyll" in img.components and "cdom" not in img.components
    bands = [(b.name, b.center_nm, b.width_nm) for b in scene.bands]
    passes = final_render.image_passes(img, bands)
    assert final_render.CHLOROPHYLL_PASS in passes and final_render.CDOM_PASS not in passes
    assert passes[final_render.CHLOROPHYLL_PASS].max() > 0
    # The CDOM pass is declared as soon as a water's CDOM fluoresces; a water disabled in
    # renders declares nothing.
    bpy.data.objects["Sea"].photic.cdom_fluorescence = True
    assert final_render.CDOM_PASS in [n for n, _, _ in final_render.render_passes(empty)]
    bpy.data.objects["Sea"].hide_render = True
    declared = [n for n, _, _ in final_render.render_passes(empty)]
    assert final_render.CHLOROPHYLL_PASS not in declared and final_render.CDOM_PASS not in declared


def test_the_chlorophyll_pass_is_written_to_the_exr_and_the_passes_sum_to_combined(empty, tmp_path):
    import OpenEXR
    from photic_blender.batch import render_blend
    chlorophyll_sea(empty)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "fluorescent.blend"))
    summary = render_blend(tmp_path / "fluorescent.blend", out_dir=tmp_path, samples=4, threads=2)
    with OpenEXR.File(str(summary["image"]), separate_channels=True) as f:
        channels = {name: ch.pixels for part in f.parts for name, ch in part.channels.items()}
    layer = "ViewLayer."

    def rgb(name):
        return np.stack([channels[f"{layer}{name}.{c}"] for c in "RGB"], -1)

    chl = rgb(final_render.CHLOROPHYLL_PASS)
    assert chl.max() > 0 and f"{layer}{final_render.CDOM_PASS}.R" not in channels
    parts = sum(rgb(n) for n in final_render.PASS_NAMES[:3]) + chl
    np.testing.assert_allclose(parts, rgb("Combined"), rtol=1e-4, atol=1e-6)
