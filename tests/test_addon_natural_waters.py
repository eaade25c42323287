"""Natural waters in Blender (``bpy`` 5.0 as a module): depth profiles and 3-D grids on water
objects, exported to the engine's ``iop_profile`` and ``iop_grid``; their errors name the
object and the property; scene files with profiles and grids import and export back; a grid
scene renders through the RenderEngine; the sediment-plume example builds and renders."""
from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import bpy  # noqa: E402  (a requirement, as in test_addon.py)

from photic.cli import load_addon  # noqa: E402
from photic.scene import Scene, save_scene  # noqa: E402

addon = load_addon()
from photic_blender import export, final_render, ui  # noqa: E402
from photic_blender.batch import ensure_registered, render_blend  # noqa: E402

import photic  # noqa: E402
import photic.render  # noqa: E402,F401  (the exporter uses photic.scene and photic.iop_models)
import photic.iop_models  # noqa: E402,F401

REPO = Path(__file__).resolve().parents[1]
RGB = ["620", "550", "460"]  # the default bands, red first
PETZOLD = {"type": "petzold"}


@pytest.fixture
def empty(tmp_path):
    """An empty Blender file saved in tmp_path (so '//' paths resolve there), add-on on."""
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    scene.render.resolution_x, scene.render.resolution_y = 24, 16
    scene.render.resolution_percentage = 100
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    return bpy.context.scene


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_mesh(name, vertices, faces):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([list(v) for v in vertices], [], [list(f) for f in faces])
    mesh.update()
    return link(bpy.data.objects.new(name, mesh))


def add_camera(location=(0.0, -6.0, 2.0), rotation=(math.radians(75), 0.0, 0.0)):
    cam = link(bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera")))
    cam.location, cam.rotation_euler = location, rotation
    bpy.context.scene.camera = cam
    return cam


def add_sea(name="Sea"):
    obj = add_mesh(name, [(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [(0, 1, 2, 3)])
    obj.photic.role = "WATER_SURFACE"
    return obj


def add_box(name="Box", location=(0.0, 0.0, -2.0), scale=(4.0, 4.0, 2.0)):
    """An Empty whose cube (+-1 times its scale) is the grid's box."""
    box = link(bpy.data.objects.new(name, None))
    box.empty_display_type = "CUBE"
    box.location, box.scale = location, scale
    return box


def export_water(index=0):
    scene, _ = export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    return scene, scene.to_dict()["water"][index]


def iops_dict(a, components):
    return {"absorption": list(a), "scattering": [{"b": list(b), "phase": ph} for b, ph in components]}


def grid_sea(tmp_path, density=None):
    """A sea with a grid: base a = 0.05, b = 0.1 (Petzold); unit a = (0.3, 0.2, 0.1) and
    b = 2 with Fournier-Forand 0.02; the density from '//plume.npz' over an Empty box."""
    add_camera()
    sea = add_sea()
    if density is None:
        density = np.arange(24, dtype=np.float32).reshape(4, 3, 2) / 24
    np.savez(tmp_path / "plume.npz", density=density)
    p = sea.photic
    p.absorption, p.scattering = 0.05, 0.1
    p.iop_variation, p.grid_file, p.grid_box = "GRID", "//plume.npz", add_box()
    p.unit_absorption_bands, p.unit_scattering = "0.3, 0.2, 0.1", 2.0
    p.unit_phase_function, p.unit_ff_backscatter = "fournier_forand", 0.02
    return sea


# ------------------------------------------------------------------------------------------
# Export: the engine's iop_grid and iop_profile
# ------------------------------------------------------------------------------------------

def test_grid_properties_export_the_engine_grid(empty, tmp_path):
    grid_sea(tmp_path)
    scene, water = export_water()
    ff = {"type": "fournier_forand", "backscatter_fraction": 0.02}
    assert water["iop_grid"] == {
        "base": {"iops": iops_dict([0.05] * 3, [([0.1] * 3, PETZOLD), ([0.0] * 3, ff)])},
        "unit": {"iops": iops_dict([0.3, 0.2, 0.1], [([0.0] * 3, PETZOLD), ([2.0] * 3, ff)])},
        "origin": [-4.0, -4.0, -4.0], "size": [8.0, 8.0, 4.0],
        "file": str(tmp_path / "plume.npz")}
    np.testing.assert_array_equal(scene.water[0].iops.density,
                                  np.load(tmp_path / "plume.npz")["density"])
    # The saved scene refers to the .npz and loads back to the same grid.
    save_scene(scene, tmp_path / "grid.json")
    again = photic.scene.load_scene(tmp_path / "grid.json")
    assert again.to_dict()["water"][0] == water


def test_grid_unit_model_and_water_body_bounds(empty, tmp_path):
    """Unit IOPs from a model (no pure water added); without a box object a water body's
    bounds are the grid's box, and its profiles count depths from its top."""
    from photic.iop_models import iops_from_model
    from photic.profiles import align_components
    add_camera()
    v = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    tank = add_mesh("Tank", v, f)
    np.savez(tmp_path / "d.npz", density=np.ones((2, 2, 2)))
    p = tank.photic
    p.role, p.iop_source = "WATER_BODY", "PURE_WATER"
    p.absorption, p.scattering = 0.0, 0.0
    model = {"model": "particles", "b_ref": 1.5, "backscatter_fraction": 0.02, "a_ref": 0.2}
    p.iop_variation, p.grid_file = "GRID", str(tmp_path / "d.npz")
    p.unit_source, p.unit_model = "MODEL", json.dumps(model)
    scene, water = export_water()
    grid = scene.water[0].iops
    assert water["iop_grid"]["origin"] == [-1.0, -1.0, -1.0] and water["iop_grid"]["size"] == [2.0, 2.0, 1.0]
    expected = iops_from_model({**model, "water": "none"}, scene.bands)
    _, unit = align_components([scene.water[0].iops.iops, expected])
    np.testing.assert_array_equal(grid.unit.absorption, unit.absorption)
    assert [c.phase.type for c in grid.iops.scattering] == ["pure_water", "fournier_forand"]
    np.testing.assert_array_equal(grid.unit.scattering[0].b, 0.0)  # no pure water per density
    np.testing.assert_array_equal(grid.unit.scattering[1].b, unit.scattering[1].b)
    # A profile in a water body counts its depths from the top of the mesh.
    tank.location.z = 3.0
    text = bpy.data.texts.new("layers")
    text.from_string("depth_m,a,b\n0,0.1,0.1\n0.25,0.2,0.2\n")
    p.iop_variation, p.profile_kind, p.profile_table_text = "PROFILE", "TABLE", text
    _, water = export_water()
    assert water["iop_profile"]["z_top"] == [3.0, 2.75]


def test_layer_table_profile_exports_the_engine_profile(empty):
    """Rows of depth below the water level; per-band columns; the object's phase function;
    'Pure Water + Additions' adds pure water to every layer."""
    add_camera()
    sea = add_sea()
    sea.location.z = 0.5
    text = bpy.data.texts.new("layers")
    text.from_string("# depth below the sea level\n"
                     "depth_m, a_620, a_550, a_460, b_620, b_550, b_460\n"
                     "0, 0.3, 0.1, 0.05, 0.2, 0.2, 0.2\n"
                     "5, 0.35, 0.15, 0.1, 0.6, 0.7, 0.8\n"
                     "12.5, 0.4, 0.2, 0.2, 0.1, 0.1, 0.1\n")
    p = sea.photic
    p.iop_variation, p.profile_kind, p.profile_table_text = "PROFILE", "TABLE", text
    p.phase_function, p.hg_g = "henyey_greenstein", 0.9
    _, water = export_water()
    hg = {"type": "henyey_greenstein", "g": 0.9}
    assert water["iop_profile"] == {"z_top": [0.5, -4.5, -12.0], "layers": [
        {"iops": iops_dict([0.3, 0.1, 0.05], [([0.2] * 3, hg)])},
        {"iops": iops_dict([0.35, 0.15, 0.1], [([0.6, 0.7, 0.8], hg)])},
        {"iops": iops_dict([0.4, 0.2, 0.2], [([0.1] * 3, hg)])}]}
    # Single columns a and b for every band, pure water added, from a file.
    p.iop_source = "PURE_WATER"
    path = Path(bpy.path.abspath("//layers.csv"))
    path.write_text("depth_m,a,b\n0,0.01,0.1\n3,0.02,0.3\n")
    p.profile_table_text, p.profile_table_file = None, "//layers.csv"
    scene, water = export_water()
    from photic.iop_models import pure_water_absorption, pure_seawater_scattering
    bands = [(b.center_nm, b.width_nm) for b in scene.bands]
    layer = scene.water[0].iops.layers[1]
    np.testing.assert_allclose(layer.absorption, 0.02 + pure_water_absorption(bands))
    assert [c.phase.type for c in layer.scattering] == ["pure_water", "henyey_greenstein"]
    np.testing.assert_allclose(layer.scattering[0].b, pure_seawater_scattering(bands))
    assert water["iop_profile"]["z_top"] == [0.5, -2.5]


def test_chlorophyll_profile_is_the_case1_model_through_photic_profiles(empty):
    from photic.profiles import gaussian_chlorophyll, profile_from_function
    add_camera()
    sea = add_sea()
    rows = [(400, 0.69), (440, 1.0), (500, 0.62), (550, 0.33), (600, 0.26), (650, 0.35), (700, 0.1)]
    text = bpy.data.texts.new("chl")
    text.from_string("wavelength_nm,a_star\n" + "".join(f"{w},{a}\n" for w, a in rows))
    p = sea.photic
    p.iop_variation, p.profile_kind, p.chl_absorption_text = "PROFILE", "CHLOROPHYLL", text
    p.chl_background, p.chl_peak, p.chl_peak_depth, p.chl_width = 0.2, 1.5, 13.0, 4.0
    p.profile_layer_thickness, p.profile_max_depth = 2.0, 30.0
    scene, water = export_water()
    table = {"source": "Text 'chl'", "wavelength_nm": [float(w) for w, _ in rows],
             "a_star": [a for _, a in rows]}
    chl = gaussian_chlorophyll(0.2, 1.5, -13.0, 4.0)
    expected = profile_from_function(
        lambda z: {"model": "case1", "variant": "classic", "chlorophyll": chl(z),
                   "chlorophyll_absorption": table}, -2.0 * np.arange(15), scene.bands)
    profile = scene.water[0].iops
    np.testing.assert_array_equal(profile.z_top, expected.z_top)
    for mine, ref in zip(profile.layers, expected.layers, strict=True):
        np.testing.assert_array_equal(mine.absorption, ref.absorption)
        assert [c.phase for c in mine.scattering] == [c.phase for c in ref.scattering]
        for c, r in zip(mine.scattering, ref.scattering):
            np.testing.assert_array_equal(c.b, r.b)
    assert len(water["iop_profile"]["layers"]) == 15
    # The layer at the maximum absorbs most in the blue.
    a_blue = [layer.absorption[2] for layer in scene.water[0].iops.layers]
    assert int(np.argmax(a_blue)) == 6  # the layer from 12 to 14 m


# ------------------------------------------------------------------------------------------
# Bad input: ExportError naming the object and the property
# ------------------------------------------------------------------------------------------

def _missing_npz(tmp_path):
    grid_sea(tmp_path).photic.grid_file = "//nowhere.npz"


def _no_density_key(tmp_path):
    grid_sea(tmp_path)
    np.savez(tmp_path / "plume.npz", rho=np.ones((2, 2, 2)))


def _wrong_shape(tmp_path):
    grid_sea(tmp_path, density=np.ones((4, 4), np.float32))


def _negative(tmp_path):
    d = np.ones((3, 3, 3), np.float32)
    d[1, 2, 0] = -0.5
    grid_sea(tmp_path, density=d)


def _nan(tmp_path):
    d = np.ones((3, 3, 3), np.float32)
    d[2, 0, 1] = np.nan
    grid_sea(tmp_path, density=d)


def _not_npz(tmp_path):
    grid_sea(tmp_path)
    (tmp_path / "plume.npz").write_text("not numpy")


def _rotated_box(tmp_path):
    grid_sea(tmp_path).photic.grid_box.rotation_euler.z = 0.3


def _ocean_without_box(tmp_path):
    grid_sea(tmp_path).photic.grid_box = None


def _flat_box(tmp_path):
    grid_sea(tmp_path).photic.grid_box.scale.z = 0.0


def _volume_not_read(tmp_path):
    sea = grid_sea(tmp_path)
    vol = link(bpy.data.objects.new("Plume", bpy.data.volumes.new("Plume")))
    sea.photic.grid_source, sea.photic.grid_box = "VOLUME", vol


def _negative_unit(tmp_path):
    grid_sea(tmp_path).photic.unit_absorption_bands = "0.1, -0.2, 0.1"


def _bad_unit_model(tmp_path):
    sea = grid_sea(tmp_path)
    sea.photic.unit_source, sea.photic.unit_model = "MODEL", '{"model": "cdom", "a_ref": -1}'


def _table_sea(text):
    add_camera()
    sea = add_sea()
    block = bpy.data.texts.new("layers")
    block.from_string(text)
    sea.photic.iop_variation, sea.photic.profile_kind = "PROFILE", "TABLE"
    sea.photic.profile_table_text = block
    return sea


def _table_missing_band(tmp_path):
    _table_sea("depth_m,a_620,a_550,b\n0,0.1,0.1,0.2\n")


def _table_depth_order(tmp_path):
    _table_sea("depth_m,a,b\n0,0.1,0.2\n5,0.1,0.2\n3,0.1,0.2\n")


def _table_nan(tmp_path):
    _table_sea("depth_m,a,b\n0,0.1,0.2\n5,nan,0.2\n")


def _table_with_model(tmp_path):
    _table_sea("depth_m,a,b\n0,0.1,0.2\n").photic.iop_source = "MODEL"


def _chl_without_table(tmp_path):
    add_camera()
    sea = add_sea()
    sea.photic.iop_variation, sea.photic.profile_kind = "PROFILE", "CHLOROPHYLL"


def _chl_table_column(tmp_path):
    add_camera()
    sea = add_sea()
    text = bpy.data.texts.new("chl")
    text.from_string("wavelength_nm,a\n400,0.7\n700,0.1\n")
    sea.photic.iop_variation, sea.photic.profile_kind = "PROFILE", "CHLOROPHYLL"
    sea.photic.chl_absorption_text = text


def _chl_new_variant(tmp_path):
    add_camera()
    sea = add_sea()
    text = bpy.data.texts.new("chl")
    text.from_string("wavelength_nm,A,E\n400,0.03,0.7\n440,0.06,0.68\n560,0.01,0.8\n700,0.005,0.9\n")
    sea.photic.iop_variation, sea.photic.profile_kind = "PROFILE", "CHLOROPHYLL"
    sea.photic.chl_absorption_text, sea.photic.case1_variant = text, "new"


BAD = [
    (_missing_npz, ["Object 'Sea'", "Density File (photic.grid_file)", "nowhere.npz", "does not exist"]),
    (_no_density_key, ["Density File", "no array 'density'", "rho"]),
    (_wrong_shape, ["Density File", "3-D", "(4, 4)"]),
    (_negative, ["Density File", "voxel [1, 2, 0]", "-0.5", ">= 0"]),
    (_nan, ["Density File", "voxel [2, 0, 1]", "nan", "finite"]),
    (_not_npz, ["Density File", "cannot read"]),
    (_rotated_box, ["Grid Box (photic.grid_box)", "Object 'Box' is rotated"]),
    (_ocean_without_box, ["Grid Box", "is empty", "water surface"]),
    (_flat_box, ["Grid Box", "no extent along z"]),
    (_volume_not_read, ["Density (photic.grid_source)", "Volume 'Plume'", "not been read",
                        "Read Volume Grids"]),
    (_negative_unit, ["Unit Absorption per Band (photic.unit_absorption_bands)", "band 2", ">= 0"]),
    (_bad_unit_model, ["Unit IOP Model (photic.unit_model)", "a_ref"]),
    (_table_missing_band, ["Layer Table Text (photic.profile_table_text)", "a_460", "one column 'a'"]),
    (_table_depth_order, ["Layer Table Text", "row 3", "below the row before"]),
    (_table_nan, ["Layer Table Text", "row 2", "band 620", "nan"]),
    (_table_with_model, ["IOPs (photic.iop_source)", "layer table"]),
    (_chl_without_table, ["Chl Absorption Text (photic.chl_absorption_text)", "both empty"]),
    (_chl_table_column, ["Chl Absorption Text", "a_star"]),
    (_chl_new_variant, ["Case-1 Model (photic.case1_variant)", "at most 16", "classic"]),
]


@pytest.mark.parametrize("build, expected", BAD, ids=[b.__name__[1:] for b, _ in BAD])
def test_bad_natural_water_input_names_object_and_property(empty, tmp_path, build, expected):
    build(tmp_path)
    with pytest.raises(export.ExportError) as info:
        export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    message = str(info.value)
    assert message.startswith("Object '"), message
    for text in expected:
        assert text in message, message


def volume_with_cube_grid(name="Plume", size=(2.0, 1.0, 1.0), voxel=0.25, density=2.0,
                          offset=(0.0, 0.0, 0.0)):
    """A Volume object whose own geometry nodes make its 'density' grid: ``density`` in the
    voxels whose centres lie inside a cube of ``size`` (m, object space) centred at
    ``offset``, 0 elsewhere (Mesh to Density Grid, no gradient band), voxels of ``voxel`` m."""
    vol = link(bpy.data.objects.new(name, bpy.data.volumes.new(name)))
    tree = bpy.data.node_groups.new(name + " grid", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    cube = nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = size
    grid = nodes.new("GeometryNodeMeshToDensityGrid")
    grid.inputs["Density"].default_value = density
    grid.inputs["Voxel Size"].default_value = voxel
    grid.inputs["Gradient Width"].default_value = 0.0
    store = nodes.new("GeometryNodeStoreNamedGrid")
    store.data_type = "FLOAT"
    store.inputs["Name"].default_value = "density"
    move = nodes.new("GeometryNodeTransform")
    move.inputs["Translation"].default_value = offset
    links.new(cube.outputs["Mesh"], move.inputs["Geometry"])
    links.new(move.outputs["Geometry"], grid.inputs["Mesh"])
    links.new(nodes.new("NodeGroupInput").outputs[0], store.inputs["Volume"])
    links.new(grid.outputs[0], store.inputs["Grid"])
    links.new(store.outputs[0], nodes.new("NodeGroupOutput").inputs[0])
    vol.modifiers.new("grid", "NODES").node_group = tree
    return vol


@pytest.mark.parametrize("sx", [2.0, -2.0], ids=["scaled", "mirrored"])
def test_volume_object_grid_is_read_through_geometry_nodes(empty, tmp_path, sx):
    """A water's grid from a Volume object (its 'density' grid made by its own geometry nodes,
    the object moved, scaled and mirrored): read_volumes (main thread) then the export give
    the voxels where the grid has them, exactly: density 2 in the 7 x 3 x 3 voxels whose
    centres lie strictly inside a 2 x 1 x 1 cube at voxel 0.25 m (object space, centred 0.5 m
    off the origin along x), times the scale, 0 around, placed where they sit in the world.
    Moving the Volume afterwards without reading it again is refused (the last read no longer
    matches), and no temporary object or node group is left behind."""
    from photic_blender import natural_waters
    sea = grid_sea(tmp_path)
    vol = volume_with_cube_grid(offset=(0.5, 0.0, 0.0))
    vol.location, vol.scale = (1.0, 2.0, -3.0), (sx, 1.0, 1.0)
    sea.photic.grid_source, sea.photic.grid_box = "VOLUME", vol
    objects, groups = set(bpy.data.objects.keys()), set(bpy.data.node_groups.keys())
    done = natural_waters.read_volumes(bpy.context.scene)
    assert [d[:2] for d in done] == [("Sea", "Plume")]
    assert set(bpy.data.objects.keys()) == objects and set(bpy.data.node_groups.keys()) == groups
    scene, _ = export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    g = scene.water[0].iops
    rho = np.asarray(g.density)
    assert set(np.unique(rho[rho > 1e-3]).tolist()) == {2.0}
    inside = np.argwhere(rho > 1.0)
    assert len(inside) == 7 * 3 * 3
    cell = np.asarray(g.size) / rho.shape
    assert np.allclose(cell, [0.5, 0.25, 0.25])
    centres = np.asarray(g.origin) + (inside + 0.5) * cell
    # the voxel centres strictly inside: x = 1 + sx (0.5 + (-0.75 .. 0.75)), y 2 +- 0.25, z -3 +- 0.25
    x = sorted(1.0 + sx * (0.5 + np.array([-0.75, 0.75])))
    assert np.allclose(centres.min(axis=0), [x[0], 1.75, -3.25])
    assert np.allclose(centres.max(axis=0), [x[1], 2.25, -2.75])
    assert np.allclose(centres.mean(axis=0), [1.0 + 0.5 * sx, 2.0, -3.0])
    vol.location.x += 1.0
    with pytest.raises(export.ExportError, match="not been read"):
        export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)


def sunlit_volume_slab(tmp_path, radiometers):
    """A sunlit sea whose grid is a Volume's 4 x 8 x 4 m slab of density 1 (unit b = 5 per
    metre), radiometers looking down at x = +2 m and x = -2 m (named ``radiometers``); returns
    the Volume, at the origin."""
    sea = grid_sea(tmp_path)
    sea.photic.unit_absorption_bands, sea.photic.unit_scattering = "0.05", 5.0
    vol = volume_with_cube_grid(size=(4.0, 8.0, 4.0), voxel=0.5, density=1.0)
    sea.photic.grid_source, sea.photic.grid_box = "VOLUME", vol
    sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
    sun.rotation_euler = (math.radians(30), 0.0, 0.0)
    for name, x in zip(radiometers, (2.0, -2.0)):
        r = link(bpy.data.objects.new(name, None))
        r.location = (x, 0.0, 0.5)
        r.photic.role, r.photic.quantity = "RADIOMETER", "radiance"
    return vol


def test_volume_grid_scene_renders_through_the_command_line_path(empty, tmp_path):
    """The turbid slab of the F12 test below as a Volume object's grid, rendered by
    ``render_blend`` (``photic blend``), which reads the Volume before the render: a radiometer
    looking down on the slab sees more upwelling light than one over clear water."""
    vol = sunlit_volume_slab(tmp_path, ("Lu_turbid", "Lu_clear"))
    vol.location = (2.0, 0.0, -2.0)  # x from 0 to 4 m, 0 to 4 m deep
    empty.photic.samples, empty.photic.radiometer_samples = 2, 4000
    bpy.ops.wm.save_mainfile()
    summary = render_blend(tmp_path / "scene.blend", out_dir=tmp_path / "out")
    assert Path(summary["image"]).is_file()
    rows = {r["name"]: r for r in final_render.LAST_RADIOMETERS[bpy.context.scene.name]["rows"]}
    turbid, clear = (np.array(rows[n]["value"]) for n in ("Lu_turbid", "Lu_clear"))
    assert np.all(np.isfinite(turbid)) and np.all(turbid > 3 * clear), (turbid, clear)


def test_volume_grids_are_read_when_a_file_is_opened(empty, tmp_path):
    """Opening a .blend reads its water objects' Volume grids (a load_post handler), so an
    F12 render right away finds them: the export needs no further read."""
    from photic_blender import natural_waters
    sea = grid_sea(tmp_path)
    vol = volume_with_cube_grid()
    sea.photic.grid_source, sea.photic.grid_box = "VOLUME", vol
    bpy.ops.wm.save_mainfile()
    natural_waters._VOLUME_CACHE.clear()
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "scene.blend"))
    assert natural_waters._VOLUME_CACHE
    scene, _ = export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    assert int((np.asarray(scene.water[0].iops.density) > 1.0).sum()) == 7 * 3 * 3


def moving_slab(empty, tmp_path, frames=2):
    """A turbid slab (a Volume's grid) keyframed under the radiometer Lu_east at frame 1 and
    under Lu_west from frame 2 on; the scene's range is frames 1 to ``frames``."""
    vol = sunlit_volume_slab(tmp_path, ("Lu_east", "Lu_west"))
    for frame, x in ((1, 2.0), (2, -2.0)):  # x from 0 to 4 m, then from -4 to 0 m; 0 to 4 m deep
        vol.location = (x, 0.0, -2.0)
        vol.keyframe_insert("location", frame=frame)
    empty.frame_set(1)  # (the animation's place, not the last one set)
    empty.photic.samples, empty.photic.radiometer_samples = 1, 4000
    empty.frame_start, empty.frame_end = 1, frames
    empty.render.filepath = str(tmp_path / "frame_")


def render_animation() -> dict:
    """bpy.ops.render.render(animation=True): per frame its radiometers' values, or the error."""
    seen = {}

    def keep(scene, *_args):  # each frame's radiometers, after its render
        err = final_render.LAST_RENDER.get("error")
        rows = final_render.LAST_RADIOMETERS[scene.name]["rows"]
        seen[scene.frame_current] = err or {r["name"]: np.array(r["value"]) for r in rows}

    final_render.LAST_RENDER.clear()
    bpy.app.handlers.render_post.append(keep)
    try:
        bpy.ops.render.render(animation=True)
    finally:
        bpy.app.handlers.render_post.remove(keep)
    return seen


def assert_slab_followed(seen):
    assert sorted(seen) == [1, 2], seen
    (east1, west1), (east2, west2) = ((seen[f]["Lu_east"], seen[f]["Lu_west"]) for f in (1, 2))
    assert np.all(east1 > 3 * west1) and np.all(west2 > 3 * east2), seen


def test_volume_grids_are_read_for_every_frame_of_an_animation(empty, tmp_path):
    """An animation rendered on Blender's main thread (``bpy.ops.render.render(animation=True)``,
    as ``blender -b file.blend -a`` renders): a render_pre handler reads the Volume at each
    frame. Each frame's radiometers see the keyframed slab where it is then (nothing was read
    before)."""
    from photic_blender import natural_waters
    moving_slab(empty, tmp_path)
    natural_waters._VOLUME_CACHE.clear()
    assert_slab_followed(render_animation())


def test_batch_exports_each_frame_of_a_moving_volume_grid(empty, tmp_path):
    """``photic batch`` with a .blend and several frames (``batch.export_frames``, a final
    render's export per frame): the saved file opened again, each frame's grid read where the
    keyframed Volume is at that frame (its box 4 m further west at frame 2)."""
    from photic_blender import natural_waters
    from photic_blender.batch import export_frames
    moving_slab(empty, tmp_path)
    bpy.ops.wm.save_mainfile()
    natural_waters._VOLUME_CACHE.clear()
    (f1, s1), (f2, s2) = export_frames(tmp_path / "scene.blend", frames=[1, 2])
    o1, o2 = (np.asarray(s.water[0].iops.origin) for s in (s1, s2))
    assert (f1, f2) == (1, 2)
    np.testing.assert_allclose(o2 - o1, [-4.0, 0.0, 0.0], atol=1e-6)


def test_every_frame_read_serves_an_animation_rendered_off_the_main_thread(empty, tmp_path,
                                                                         monkeypatch):
    """Ctrl+F12 in Blender's interface renders in a thread of its own, where a Volume cannot be
    read: 'Read Volume Grids' > 'Every Frame' reads every frame of the range beforehand (the
    scene back at its frame after; the slab's densities, the same at every frame, kept once),
    and the animation rendered with reading switched off, as in that thread, follows the slab.
    Without that read it stops at the first frame with the error naming the button; frames
    that do not fit in the cache's budget are refused."""
    from photic_blender import natural_waters, volume_grid
    moving_slab(empty, tmp_path, frames=2)
    natural_waters._VOLUME_CACHE.clear()
    with monkeypatch.context() as m:
        m.setattr(volume_grid, "on_main_thread", lambda: False)
        with pytest.raises(RuntimeError, match="frame 1 has not been read.*Read Volume Grids"):
            bpy.ops.render.render(animation=True)
    assert bpy.ops.photic.read_volume_grids(every_frame=True) == {"FINISHED"}
    assert empty.frame_current == 1 and len(natural_waters._VOLUME_CACHE) == 2
    assert len({id(v["density"][0]) for v in natural_waters._VOLUME_CACHE.values()}) == 1
    with monkeypatch.context() as m:
        m.setattr(volume_grid, "on_main_thread", lambda: False)
        assert_slab_followed(render_animation())
    empty.frame_end = 6
    monkeypatch.setattr(natural_waters, "VOLUME_CACHE_BYTES", 1)  # 4 reads kept, not 6
    with pytest.raises(RuntimeError, match="frames 1-6 need more than"):
        bpy.ops.photic.read_volume_grids(every_frame=True)
    assert empty.frame_current == 1


def bake_grids(vol, directory: Path, mode: str = "STILL") -> list[Path]:
    """Bakes a Volume's geometry-node grids to disk (a Bake node before the group's output;
    ``mode`` 'STILL' or 'ANIMATION' over the scene's frame range): Blender writes them as
    .vdb files (one per frame), whose paths are returned in order."""
    mod = vol.modifiers[0]
    tree = mod.node_group
    out = next(n for n in tree.nodes if n.bl_idname == "NodeGroupOutput")
    made = out.inputs[0].links[0].from_socket
    bake = tree.nodes.new("GeometryNodeBake")
    bake.bake_items.new("GEOMETRY", "Geometry")
    tree.links.new(made, bake.inputs[0])
    tree.links.new(bake.outputs[0], out.inputs[0])
    mod.bake_target, mod.bake_directory = "DISK", str(directory)
    mod.bakes[0].bake_mode = mode
    with bpy.context.temp_override(object=vol, active_object=vol):
        assert bpy.ops.object.geometry_node_bake_single(
            session_uid=vol.session_uid, modifier_name=mod.name,
            bake_id=mod.bakes[0].bake_id) == {"FINISHED"}
    return sorted(directory.rglob("*.vdb"))


def bake_to_vdb(vol, directory: Path) -> Path:
    """A Volume's geometry-node grids baked to one .vdb file, its path."""
    vdb, = bake_grids(vol, directory)
    return vdb


def test_volume_reading_a_vdb_file_gives_the_grid_written(empty, tmp_path):
    """A Volume object that reads a .vdb file (Blender's bake of the cube grid above, moved)
    exports the same densities, box and voxels as the Volume whose geometry nodes made it."""
    from photic_blender import natural_waters
    sea = grid_sea(tmp_path)
    made = volume_with_cube_grid(offset=(0.5, 0.0, 0.0))
    vdb = bake_to_vdb(made, tmp_path / "bake")
    filed = link(bpy.data.objects.new("From File", bpy.data.volumes.new("From File")))
    filed.data.filepath = str(vdb)
    grids = []
    for box in (made, filed):
        box.location = (1.0, 2.0, -3.0)
        sea.photic.grid_source, sea.photic.grid_box = "VOLUME", box
        (water, volume, shape), = natural_waters.read_volumes(bpy.context.scene)
        assert volume == box.name and isinstance(shape, tuple), shape
        g = export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)[0].water[0].iops
        grids.append((np.asarray(g.density), np.asarray(g.origin), np.asarray(g.size)))
    (d0, o0, s0), (d1, o1, s1) = grids
    assert int((d0 > 1.0).sum()) == 7 * 3 * 3
    np.testing.assert_array_equal(d1, d0)
    np.testing.assert_allclose(o1, o0, atol=1e-6)
    np.testing.assert_allclose(s1, s0, atol=1e-6)


@pytest.mark.parametrize("problem", ["no density grid", "rotated", "too many voxels"])
def test_volume_that_cannot_be_a_grid_is_named(empty, tmp_path, monkeypatch, problem):
    """A Volume without a 'density' grid, one whose voxels are rotated against the world axes
    (the grid's box is aligned with them), or one with more voxels than the read allows: the
    read keeps the error, and the export names the water object, the Grid Box property, the
    Volume and what is wrong or to do."""
    from photic_blender import natural_waters, volume_grid
    sea = grid_sea(tmp_path)
    if problem == "no density grid":
        vol = link(bpy.data.objects.new("Plume", bpy.data.volumes.new("Plume")))
        expected = ["no grid 'density'"]
    elif problem == "rotated":
        vol = volume_with_cube_grid()
        vol.rotation_euler = (0.0, 0.0, math.radians(30))
        expected = ["rotated against the world axes", "clear the rotation"]
    else:
        vol = volume_with_cube_grid()
        monkeypatch.setattr(volume_grid, "MAX_VOXELS", 100)
        expected = ["more than 100", "coarser voxel size"]
    sea.photic.grid_source, sea.photic.grid_box = "VOLUME", vol
    (water, volume, got), = natural_waters.read_volumes(bpy.context.scene)
    assert isinstance(got, export.ExportError)
    with pytest.raises(export.ExportError) as info:
        export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    message = str(info.value)
    for text in ["Object 'Sea'", "Grid Box (photic.grid_box)", "Volume 'Plume'"] + expected:
        assert text in message, message


# ------------------------------------------------------------------------------------------
# Import, panels, rendering
# ------------------------------------------------------------------------------------------

def test_profile_and_grid_scenes_import_and_export_back(empty, tmp_path):
    """File > Import of a scene with a profile, one with a grid and one with a grid over a
    profile: the objects export back to the same water (the grid's box becomes an Empty;
    values with exact float32 forms)."""
    np.savez(tmp_path / "g.npz", density=np.random.default_rng(1).random((5, 4, 3)))
    hg = {"type": "henyey_greenstein", "g": 0.8}
    base = {"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0}}
    waters = {
        "profile": {**base, "iop_profile": {"z_top": [0.0, -2.5, -10.0], "layers": [
            {"iops": {"absorption": [0.3, 0.1, 0.05], "b": [0.2, 0.25, 0.3], "phase": hg}},
            {"iops": {"absorption": [0.4, 0.2, 0.1], "b": [1.0, 1.1, 1.2], "phase": hg}},
            {"iops": {"absorption": [0.35, 0.1, 0.02], "b": [0.1, 0.1, 0.1], "phase": hg}}]}},
        "grid": {**base, "iop_grid": {
            "base": {"iops": {"absorption": [0.3, 0.06, 0.02], "b": [0.05, 0.05, 0.05], "phase": PETZOLD}},
            "unit": {"iops": {"absorption": [0.1, 0.2, 0.4], "b": [2.0, 2.0, 2.0], "phase": PETZOLD}},
            "origin": [-8.0, -4.0, -2.0], "size": [16.0, 8.0, 2.0], "file": str(tmp_path / "g.npz")}}}
    # a grid over a depth profile: Depth Profile + 3-D Grid (a layer table and the grid)
    waters["profile grid"] = {**base, "iop_grid": {
        "base": {"iop_profile": waters["profile"]["iop_profile"]},
        "unit": {"iops": {"absorption": [0.1, 0.2, 0.4], "b": [2.0, 2.0, 2.0], "phase": hg}},
        "origin": [-8.0, -4.0, -2.0], "size": [16.0, 8.0, 2.0], "file": str(tmp_path / "g.npz")}}
    for kind, water in waters.items():
        bpy.ops.wm.read_homefile(use_empty=True)
        d = {"photic_scene": 1, "name": kind, "water": [water], "bands": [
                {"name": "620", "center_nm": 620.0, "width_nm": 80.0},
                {"name": "550", "center_nm": 550.0, "width_nm": 60.0},
                {"name": "460", "center_nm": 460.0, "width_nm": 80.0}],
             "sky": {"type": "uniform", "radiance": [0.1, 0.1, 0.1]},
             "cameras": [{"name": "cam", "type": "perspective", "position": [0, -5, 3], "look_at": [0, 0, 0], "fov_deg": 40,
                          "resolution": [8, 8]}]}
        src = tmp_path / f"{kind.replace(' ', '_')}.json"
        src.write_text(json.dumps(d))
        assert bpy.ops.photic.import_scene(filepath=str(src)) == {"FINISHED"}
        _, exported = export_water()
        assert exported == photic.scene.load_scene(src).to_dict()["water"][0], kind


def test_refused_import_says_why(empty, tmp_path):
    d = {"photic_scene": 1, "name": "inline", "sky": {"type": "uniform", "radiance": [0.1]},
         "bands": [{"name": "550", "center_nm": 550, "width_nm": 10}],
         "cameras": [{"name": "cam", "type": "perspective", "position": [0, -5, 3], "look_at": [0, 0, 0]}],
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat"}, "iop_grid": {
             "base": {"iops": {"absorption": [0.1]}}, "unit": {"iops": {"absorption": [0.1]}},
             "origin": [0, 0, -1], "size": [1, 1, 1], "density": [[[1.0]]]}}]}
    from photic_blender.importer import import_scene
    with pytest.raises(ValueError, match="water 'sea'.*inline.*numpy.savez"):
        import_scene(Scene.from_dict(d), empty)


class FakeLayout:
    def __init__(self, shown):
        self.shown, self.use_property_split, self.active, self.alert = shown, False, True, False

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, (data, name)
        self.shown.append(name)

    def column(self, **kw):
        return FakeLayout(self.shown)

    row = box = column

    def label(self, **kw):
        pass

    def operator(self, idname, **kw):
        self.shown.append(idname)
        return SimpleNamespace()


def test_iop_variation_panel_draws_every_property_it_names(empty):
    sea = add_sea()
    p = sea.photic
    shown = []
    context = SimpleNamespace(engine="PHOTIC", scene=empty, object=sea)
    cases = [("PROFILE", "CHLOROPHYLL", "VALUES", "petzold"), ("PROFILE", "TABLE", "VALUES", "petzold"),
             ("GRID", "CHLOROPHYLL", "MODEL", "petzold"), ("GRID", "TABLE", "VALUES", "henyey_greenstein"),
             ("GRID", "TABLE", "VALUES", "fournier_forand"), ("NONE", "TABLE", "VALUES", "petzold"),
             ("PROFILE_GRID", "CHLOROPHYLL", "VALUES", "petzold")]
    for i, (variation, kind, unit, phase) in enumerate(cases):
        p.iop_variation, p.profile_kind, p.unit_source, p.unit_phase_function = variation, kind, unit, phase
        p.grid_source = "VOLUME" if i == 2 else "NPZ"
        assert ui.PHOTIC_PT_iop_variation.poll(context)
        ui.PHOTIC_PT_iop_variation.draw(SimpleNamespace(layout=FakeLayout(shown)), context)
    for name in ("chl_peak", "chl_absorption_file", "profile_table_text", "grid_file", "grid_box",
                 "unit_model", "unit_hg_g", "unit_ff_backscatter", "photic.read_volume_grids"):
        assert name in shown, name
    both = []  # a profile under a grid: both sections
    p.iop_variation, p.profile_kind = "PROFILE_GRID", "TABLE"
    ui.PHOTIC_PT_iop_variation.draw(SimpleNamespace(layout=FakeLayout(both)), context)
    assert "profile_table_text" in both and "grid_box" in both and "unit_source" in both
    p.role = "RADIOMETER"
    assert not ui.PHOTIC_PT_iop_variation.poll(context)


def test_grid_scene_renders_through_the_render_engine(empty, tmp_path):
    """A turbid slab under part of the sea: F12 renders it, and a radiometer looking down on
    the slab sees more upwelling light than one over clear water."""
    d = np.zeros((8, 8, 4), np.float32)
    d[4:] = 1.0  # x > 0: the turbid half of the box
    sea = grid_sea(tmp_path, density=d)
    sea.photic.unit_absorption_bands, sea.photic.unit_scattering = "0.05", 5.0
    light = bpy.data.lights.new("Sun", "SUN")
    sun = link(bpy.data.objects.new("Sun", light))
    sun.rotation_euler = (math.radians(30), 0.0, 0.0)
    for name, x in (("Lu_turbid", 2.0), ("Lu_clear", -2.0)):
        r = link(bpy.data.objects.new(name, None))
        r.location = (x, 0.0, 0.5)
        r.photic.role, r.photic.quantity = "RADIOMETER", "radiance"
    p = empty.photic
    p.samples, p.radiometer_samples = 2, 4000
    empty.render.filepath = str(tmp_path / "frame_")
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()
    summary = final_render.LAST_RENDER
    assert not summary.get("error"), summary
    rows = {r["name"]: r for r in final_render.LAST_RADIOMETERS[empty.name]["rows"]}
    turbid, clear = (np.array(rows[n]["value"]) for n in ("Lu_turbid", "Lu_clear"))
    assert np.all(np.isfinite(turbid)) and np.all(turbid > 3 * clear), (turbid, clear)


def test_sediment_plume_example_builds_and_renders(tmp_path):
    """The example's builder in bpy: the .blend with its .npz beside it renders through
    'photic blend' (tiny image, few samples) and its tables give Rrs for both radiometers."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("make_examples", REPO / "example_blends" / "make_examples.py")
    make_examples = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_examples)
    path = make_examples.build_sediment_plume(tmp_path, grid_shape=(32, 32, 8))
    assert path.is_file() and (tmp_path / "sediment_plume.npz").is_file()
    summary = render_blend(path, out_dir=tmp_path / "out", samples=1, radiometer_samples=3000,
                           resolution_percentage=10)
    table = next(Path(t) for t in summary["tables"] if t.endswith("_radiometers.json"))
    rrs = make_examples.plume_rrs(table)
    assert set(rrs) == {"plume", "clear"}
    for d in rrs.values():
        assert np.all(np.isfinite(d.value)) and d.quantity == "Rrs"


def test_committed_sediment_plume_blend_renders(tmp_path):
    """The saved example (Blender 3.4's file, its .npz beside it) renders here; Rrs is higher
    above the plume than above clear water in the green."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("make_examples", REPO / "example_blends" / "make_examples.py")
    make_examples = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_examples)
    seen = []  # photic blend's progress bar is fed this way
    summary = render_blend(REPO / "example_blends" / "sediment_plume.blend", out_dir=tmp_path,
                           samples=1, radiometer_samples=4000, resolution_percentage=10,
                           progress=lambda f, text: seen.append((f, text)))
    fractions = [f for f, _ in seen]
    assert len(seen) > 3 and fractions == sorted(fractions) and fractions[-1] == 1.0, seen
    assert any("samples" in text or "sample" in text for _, text in seen)
    table = next(Path(t) for t in summary["tables"] if t.endswith("_radiometers.json"))
    rrs = make_examples.plume_rrs(table)
    green = [i for i, (c, _) in enumerate(make_examples.PLUME_BANDS) if 530 < c < 570]
    assert np.all(rrs["plume"].value[green] > 3 * rrs["clear"].value[green])
