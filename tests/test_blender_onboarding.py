"""A newcomer's first steps in Blender: a plane made a Water Surface looks like water, water
types from measured natural waters, radiometer results with units that stay in the .blend."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from test_addon import add_camera, add_sea, add_sun, empty, export_current  # noqa: E402,F401

import photic  # noqa: E402
from photic_blender import final_render, ui, water_types  # noqa: E402

class Labels:
    """A panel layout that keeps the text of its labels."""

    def __init__(self, out):
        self.out = out
        self.use_property_split, self.active, self.alert = False, True, False

    def label(self, text="", **kw):
        self.out.append(text)

    def column(self, **kw):
        return Labels(self.out)

    row = box = column

    def prop(self, *a, **kw):
        pass

    operator = prop


STATIONS = Path(photic.__file__).parent / "data" / "petzold1972_stations.csv"


def _stations() -> dict:
    with open(STATIONS) as f:
        rows = [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]
    return {r["station"]: r for r in rows}


def test_water_types_are_petzolds_stations_at_530_nm(empty):
    """Each water type, exported in a single 530 nm band, has the absorption, scattering and
    backscatter fraction Petzold measured at its station (the data file, not the add-on's
    copy of the numbers); the Custom type keeps the IOPs given by hand."""
    add_camera()
    add_sun()
    sea = add_sea(depth=10.0)
    empty.photic.bands = "SINGLE"
    empty.photic.band_center_nm, empty.photic.band_width_nm = 530.0, 0.001
    stations = _stations()
    assert set(water_types.TYPES) == {"COASTAL", "CLEAR_OCEAN", "LAGOON", "TURBID"}
    for kind, (label, station, *_rest) in water_types.TYPES.items():
        sea.photic.water_type = kind
        iops = export_current()[0].water[0].iops
        ref = stations[station]
        assert iops.absorption[0] == pytest.approx(float(ref["a_per_m"]), rel=2e-3), kind
        assert iops.total_scattering[0] == pytest.approx(float(ref["b_per_m"]), rel=2e-3), kind
        bb = sum(c.b[0] * (c.phase.params.get("backscatter_fraction", 0.5 if c.phase.type == "pure_water" else 0))
                 for c in iops.scattering) / iops.total_scattering[0]
        assert bb == pytest.approx(float(ref["bb_over_b"]), abs=5e-4), kind
    sea.photic.water_type = "CUSTOM"  # chosen with no IOPs of its own: starts as the default
    assert sea.photic.iop_source == "MODEL"
    assert json.loads(sea.photic.iop_model) == water_types.model(water_types.DEFAULT)
    sea.photic.iop_source, sea.photic.absorption, sea.photic.scattering = "VALUES", 0.3, 0.4
    iops = export_current()[0].water[0].iops
    assert iops.absorption[0] == pytest.approx(0.3) and iops.total_scattering[0] == pytest.approx(0.4)


def test_editing_an_iop_makes_the_water_custom_and_old_files_keep_theirs(empty):
    add_camera()
    add_sun()
    sea = add_sea(depth=10.0)
    assert sea.photic.water_type == water_types.DEFAULT == "COASTAL"
    sea.photic.scattering = 0.5  # an edit (the panel or a script)
    assert sea.photic.water_type == "CUSTOM"
    b = export_current()[0].water[0].iops.total_scattering
    assert np.allclose(b, 0.5)
    # A file from before water types: IOPs stored, no water type: its own IOPs.
    bpy.data.objects.remove(sea)
    old = add_sea("Old", depth=10.0)
    old.photic["absorption"] = 0.7  # (as read from such a file: no update callback)
    assert old.photic.water_type == "COASTAL" and water_types.effective(old.photic) == "CUSTOM"
    assert np.allclose(export_current()[0].water[0].iops.absorption, 0.7)


def test_a_plane_made_a_water_surface_renders_as_water_not_grey(empty, tmp_path):
    """The issue's newcomer: a plane, Role: Water Surface, a sun and a camera looking down,
    nothing else set. The water renders blue-green (its red well below its green and blue),
    where the old default (one absorption in all bands) rendered it grey."""
    import OpenEXR
    add_camera((0, 0, 5), (0, 0, 0))
    add_sun(30)
    add_sea()  # (infinitely deep, the default IOPs)
    empty.render.resolution_x, empty.render.resolution_y = 24, 16
    empty.photic.samples = 8
    s = empty.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_depth = "OPEN_EXR", "32"
    means = {}
    for kind in ("default", "grey"):
        if kind == "grey":  # the old defaults
            sea = bpy.data.objects["Sea"]
            sea.photic.iop_source, sea.photic.absorption, sea.photic.scattering = "VALUES", 0.1, 0.2
        empty.render.filepath = str(tmp_path / f"{kind}_")
        bpy.ops.render.render(write_still=True)
        exr = next(tmp_path.glob(f"{kind}_*.exr"))
        with OpenEXR.File(str(exr)) as f:
            ch = f.parts[0].channels
            key = next(k for k in ch if k in ("RGBA", "RGB") or "Combined" in k)
            px = np.asarray(ch[key].pixels, float).reshape(-1, ch[key].pixels.shape[-1])
        means[kind] = px[:, :3].mean(axis=0)
    r, g, b = means["default"]
    assert g > 1.5 * r and b > 1.3 * r, means
    r0, g0, b0 = means["grey"]
    assert g0 < 1.3 * r0, means  # (the test can tell: the old default was grey)


def test_radiometer_results_have_units_and_stay_in_the_blend(empty, tmp_path):
    """After F12 the Radiometer Results panel shows each value with its unit; the results are
    written into the scene (photic.last_results), saved with the .blend and shown again after
    it is opened in a new session (this process's memory of them cleared)."""
    add_camera()
    add_sun()
    add_sea(depth=5.0)
    for name, z, q in (("Ed1", -1.0, "Ed"), ("Lu1", -1.0, "radiance")):
        obj = bpy.data.objects.new(name, None)
        obj.location = (0, 0, z)
        obj.photic.role, obj.photic.quantity = "RADIOMETER", q
        empty.collection.objects.link(obj)
    empty.photic.samples, empty.photic.radiometer_samples = 1, 2048
    empty.render.filepath = str(tmp_path / "r_")
    bpy.ops.render.render()
    saved = json.loads(empty.photic.last_results)
    assert {r["name"] for r in saved["rows"]} == {"Ed1", "Lu1"}

    def panel_text():
        shown = []
        ui.PHOTIC_PT_radiometer_results.draw(SimpleNamespace(layout=Labels(shown)),
                                             SimpleNamespace(scene=bpy.context.scene))
        return shown
    before = panel_text()
    path = tmp_path / "kept.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    final_render.LAST_RADIOMETERS.clear()
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    after = panel_text()
    assert after == before
    ed = next(t for t in after if t.startswith("Ed1"))
    lu = next(t for t in after if t.startswith("Lu1"))
    assert ed.rstrip().endswith("W m⁻²") and lu.rstrip().endswith("W m⁻² sr⁻¹"), (ed, lu)


#: The widest label a property keeps whole in Blender's default Properties editor (the factory
#: layout at 1920 x 1080: a 303 px region; labels are 40 % of a panel's width), in bpy's UI font
#: at 11 px: measured in Debian's Blender 3.4 under Xvfb, where "Absorption (m⁻¹)" (89 px here)
#: showed whole and "Wind Speed (m/s)" (95 px) was cut to "Wind Speed (...".
LABEL_BUDGET_PX = 90


def test_labels_keep_their_units_at_the_default_editor_width(empty):
    import re

    import blf
    blf.size(0, 11)
    groups = [(c.__name__, c.bl_rna.properties["photic"].fixed_type)
              for c in (bpy.types.Object, bpy.types.Scene, bpy.types.Material, bpy.types.Light,
                        bpy.types.World)]
    groups.append(("GridField", groups[0][1].properties["grid_fields"].fixed_type))
    assert blf.dimensions(0, "Absorption (m⁻¹)")[0] <= LABEL_BUDGET_PX < blf.dimensions(0, "Wind Speed (m/s)")[0]
    with_units, too_wide = 0, []
    for owner, grp in groups:
        for p in grp.properties:
            if p.identifier == "rna_type" or not re.search(r"\([^)]*\)$", p.name):
                continue
            with_units += 1
            w = blf.dimensions(0, p.name)[0]
            if w > LABEL_BUDGET_PX:
                too_wide.append((owner, p.identifier, p.name, w))
    assert with_units >= 20 and not too_wide, too_wide
