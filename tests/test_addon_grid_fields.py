"""Several density fields on a water object's 3-D grid in Blender (``bpy`` 5.0 as a module):
further fields (``Object.photic.grid_fields``) read by their names from the grid's .npz or
from its Volume object's grids, with unit IOPs of their own, export to the engine's
``IOPGrid.extra_fields``; their errors name the object and the property; a Volume's grids are
read once per grid and cached with 'density'; scene files with further fields import and
export back; the panel draws them."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

import bpy  # noqa: E402  (a requirement, as in test_addon.py)

from test_addon_natural_waters import (FakeLayout, add_sea, empty, export,  # noqa: F401 (empty: a fixture)
                                       export_water, grid_sea, link, photic, ui)

CDOM = {"model": "cdom", "a_ref": 0.5}


def two_field_sea(tmp_path, cdom=None, **arrays):
    """The grid sea of test_addon_natural_waters with a further field 'cdom' (a CDOM model)
    whose densities are the array 'cdom' of the same '//plume.npz'."""
    density = np.arange(24, dtype=np.float32).reshape(4, 3, 2) / 24
    if cdom is None:
        cdom = np.linspace(0.0, 2.0, 24, dtype=np.float32).reshape(4, 3, 2)[::-1].copy()
    sea = grid_sea(tmp_path, density=density)
    np.savez(tmp_path / "plume.npz", density=density, cdom=cdom, **arrays)
    f = sea.photic.grid_fields.add()
    f.name, f.unit_source, f.unit_model = "cdom", "MODEL", json.dumps(CDOM)
    return sea


# ------------------------------------------------------------------------------------------
# .npz
# ------------------------------------------------------------------------------------------

def test_further_field_from_the_npz_exports_the_engine_field(empty, tmp_path):
    """(a) An .npz with 'density' and 'cdom', one further field 'cdom' with a CDOM model: the
    grid's extra field is named 'cdom', reads the array 'cdom' (its key in the saved scene),
    and its unit is the model at the scene's bands (no pure water), on the grid's components
    (b = 0 for both: CDOM does not scatter); the saved scene loads back the same."""
    from photic.iop_models import iops_from_model
    two_field_sea(tmp_path)
    scene, water = export_water()
    g = scene.water[0].iops
    (f,) = g.extra_fields
    z = np.load(tmp_path / "plume.npz")
    assert f.name == "cdom" and f.key == "cdom"
    np.testing.assert_array_equal(f.density, z["cdom"])
    np.testing.assert_array_equal(g.density, z["density"])
    expected = iops_from_model({**CDOM, "water": "none"}, scene.bands)
    np.testing.assert_allclose(f.unit.absorption, expected.absorption, rtol=1e-12)
    assert f.unit.absorption[2] > f.unit.absorption[1] > f.unit.absorption[0] > 0  # blue first
    assert [c.phase for c in f.unit.scattering] == [c.phase for c in g.unit.scattering]
    assert all(np.all(c.b == 0) for c in f.unit.scattering)
    assert water["iop_grid"]["fields"] == [{"name": "cdom", "unit": {"iops": {
        "absorption": list(f.unit.absorption),
        "scattering": [{"b": [0.0] * 3, "phase": c["phase"]}
                       for c in water["iop_grid"]["unit"]["iops"]["scattering"]]}}, "key": "cdom"}]
    photic.scene.save_scene(scene, tmp_path / "two.json")
    again = photic.scene.load_scene(tmp_path / "two.json")
    assert again.to_dict()["water"][0] == water


def test_further_fields_with_coefficients_over_a_profile(empty, tmp_path):
    """Two further fields, one with coefficients and its own phase function, over a depth
    profile (Depth Profile + 3-D Grid): every layer and every unit on one set of components,
    the coefficient field's scattering in its own."""
    sea = two_field_sea(tmp_path, sed=np.ones((4, 3, 2), np.float32))
    text = bpy.data.texts.new("layers")
    text.from_string("depth_m,a,b\n0,0.1,0.1\n2,0.2,0.3\n")
    p = sea.photic
    p.iop_variation, p.profile_kind, p.profile_table_text = "PROFILE_GRID", "TABLE", text
    f = p.grid_fields.add()
    f.name, f.unit_source, f.unit_absorption_bands = "sed", "VALUES", "0.01, 0.02, 0.03"
    f.unit_scattering, f.unit_phase_function, f.unit_hg_g = 3.0, "henyey_greenstein", 0.8
    scene, _ = export_water()
    g = scene.water[0].iops
    assert [x.name for x in g.extra_fields] == ["cdom", "sed"]
    phases = [c.phase.type for c in g.iops.layers[0].scattering]
    assert phases == ["petzold", "fournier_forand", "henyey_greenstein"]
    for unit in g.units():
        assert [c.phase.type for c in unit.scattering] == phases
    sed = g.extra_fields[1].unit
    np.testing.assert_array_equal(sed.absorption, [0.01, 0.02, 0.03])
    np.testing.assert_array_equal([c.b[0] for c in sed.scattering], [0.0, 0.0, 3.0])
    np.testing.assert_array_equal(g.extra_fields[1].density, 1.0)


def _missing_array(tmp_path):
    two_field_sea(tmp_path).photic.grid_fields[0].name = "sed"


def _wrong_shape(tmp_path):
    two_field_sea(tmp_path, cdom=np.ones((4, 3, 3), np.float32))


def _negative_field(tmp_path):
    cdom = np.ones((4, 3, 2), np.float32)
    cdom[3, 1, 0] = -2.0
    two_field_sea(tmp_path, cdom=cdom)


def _named_density(tmp_path):
    two_field_sea(tmp_path).photic.grid_fields[0].name = "density"


def _unnamed(tmp_path):
    two_field_sea(tmp_path).photic.grid_fields[0].name = ""


def _twice(tmp_path):
    sea = two_field_sea(tmp_path)
    sea.photic.grid_fields.add().name = "cdom"


def _too_many(tmp_path):
    sea = two_field_sea(tmp_path)
    for name in ("a", "b", "c"):
        sea.photic.grid_fields.add().name = name


def _bad_model(tmp_path):
    two_field_sea(tmp_path).photic.grid_fields[0].unit_model = '{"model": "cdom", "a_ref": -1}'


def _bad_json(tmp_path):
    two_field_sea(tmp_path).photic.grid_fields[0].unit_model = '{"model": "cdom", '


def _bad_coefficients(tmp_path):
    f = two_field_sea(tmp_path).photic.grid_fields[0]
    f.unit_source, f.unit_absorption_bands = "VALUES", "0.1, 0.2"


F = "Further Density Field 'cdom' > "
BAD = [
    (_missing_array, ["Further Density Field 'sed' > Name (photic.grid_fields[0].name)",
                      "plume.npz has no array 'sed'", "(it has: density, cdom)"]),
    (_wrong_shape, [F + "Name (photic.grid_fields[0].name)", "'cdom' has shape (4, 3, 3)",
                    "'density' has (4, 3, 2)"]),
    (_negative_field, [F + "Name (photic.grid_fields[0].name)", "'cdom' at voxel [3, 1, 0]",
                       "-2", ">= 0"]),
    (_named_density, ["(photic.grid_fields[0].name)", "is 'density', the first field's"]),
    (_unnamed, ["Further Density Field 1 > Name (photic.grid_fields[0].name)", "needs a name"]),
    (_twice, ["(photic.grid_fields[1].name)", "'cdom' names two further fields"]),
    (_too_many, ["Further Density Fields (photic.grid_fields)", "has 4 fields", "at most 3"]),
    (_bad_model, [F + "Unit IOP Model (photic.grid_fields[0].unit_model)", "a_ref"]),
    (_bad_json, [F + "Unit IOP Model (photic.grid_fields[0].unit_model)", "not valid JSON"]),
    (_bad_coefficients, [F + "Unit Absorption per Band (photic.grid_fields[0].unit_absorption_bands)",
                         "2 values", "3 bands"]),
]


@pytest.mark.parametrize("build, expected", BAD, ids=[b.__name__[1:] for b, _ in BAD])
def test_bad_further_field_names_object_and_property(empty, tmp_path, build, expected):
    """(b) A missing array, another shape, a negative voxel, a bad name, too many fields or a
    bad unit: an ExportError naming the water object and the field's property."""
    build(tmp_path)
    with pytest.raises(export.ExportError) as info:
        export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    message = str(info.value)
    assert message.startswith("Object 'Sea', Photic > "), message
    for text in expected:
        assert text in message, message


def test_npz_arrays_are_read_once_while_the_file_is_unchanged(empty, tmp_path, monkeypatch):
    """The viewport re-exports often: the arrays read of the .npz are kept while it is
    unchanged, one added later (a field added) is read then, and a changed file is read
    again."""
    from photic_blender import natural_waters
    sea = two_field_sea(tmp_path, sed=np.full((4, 3, 2), 3.0, np.float32))
    natural_waters._DENSITY_CACHE.clear()
    loads = []
    real_load = np.load
    monkeypatch.setattr(np, "load", lambda *a, **k: loads.append(a[0]) or real_load(*a, **k))
    export_water()
    export_water()
    assert len(loads) == 1
    sea.photic.grid_fields.add().name = "sed"
    scene, _ = export_water()
    assert len(loads) == 2 and scene.water[0].iops.extra_fields[1].density[0, 0, 0] == 3.0
    (kept,) = natural_waters._DENSITY_CACHE.values()
    assert sorted(kept) == ["cdom", "density", "sed"]


# ------------------------------------------------------------------------------------------
# Volume objects
# ------------------------------------------------------------------------------------------

def volume_with_two_grids(name="Plume", voxel=0.25, grids=None):
    """A Volume object whose geometry nodes store float grids made from cubes (Mesh to
    Density Grid, no gradient band): ``grids`` maps a grid name to (value, cube size, cube
    centre, voxel size) in object space; default 'density' 2 in a 2 x 1 x 1 cube at x = 0.5
    and 'cdom' 0.5 in a 1 x 1 x 1 cube at x = -0.5, voxels of ``voxel`` m."""
    if grids is None:
        grids = {"density": (2.0, (2.0, 1.0, 1.0), (0.5, 0.0, 0.0), voxel),
                 "cdom": (0.5, (1.0, 1.0, 1.0), (-0.5, 0.0, 0.0), voxel)}
    vol = link(bpy.data.objects.new(name, bpy.data.volumes.new(name)))
    tree = bpy.data.node_groups.new(name + " grids", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    geometry = nodes.new("NodeGroupInput").outputs[0]
    for grid_name, (value, size, centre, vox) in grids.items():
        cube = nodes.new("GeometryNodeMeshCube")
        cube.inputs["Size"].default_value = size
        move = nodes.new("GeometryNodeTransform")
        move.inputs["Translation"].default_value = centre
        grid = nodes.new("GeometryNodeMeshToDensityGrid")
        grid.inputs["Density"].default_value = value
        grid.inputs["Voxel Size"].default_value = vox
        grid.inputs["Gradient Width"].default_value = 0.0
        store = nodes.new("GeometryNodeStoreNamedGrid")
        store.data_type = "FLOAT"
        store.inputs["Name"].default_value = grid_name
        links.new(cube.outputs["Mesh"], move.inputs["Geometry"])
        links.new(move.outputs["Geometry"], grid.inputs["Mesh"])
        links.new(geometry, store.inputs["Volume"])
        links.new(grid.outputs[0], store.inputs["Grid"])
        geometry = store.outputs[0]
    links.new(geometry, nodes.new("NodeGroupOutput").inputs[0])
    vol.modifiers.new("grids", "NODES").node_group = tree
    return vol


def volume_sea(tmp_path, vol):
    sea = grid_sea(tmp_path)
    sea.photic.grid_source, sea.photic.grid_box = "VOLUME", vol
    f = sea.photic.grid_fields.add()
    f.name, f.unit_model = "cdom", json.dumps(CDOM)
    return sea


def counting_reads(monkeypatch):
    """The grid names read_volume_grid is asked for, in order."""
    from photic_blender import volume_grid
    asked = []
    real = volume_grid.read_volume_grid

    def read(volume_obj, name="density"):
        asked.append((volume_obj.name, name))
        return real(volume_obj, name)

    monkeypatch.setattr(volume_grid, "read_volume_grid", read)
    return asked


def test_volume_with_two_grids_exports_both_fields(empty, tmp_path, monkeypatch):
    """(c) A Volume whose geometry nodes make two float grids, 'density' (2 in a 2 x 1 x 1
    cube) and 'cdom' (0.5 in a 1 x 1 x 1 cube beside it), moved: each grid read once, cached
    in one entry with 'density', and exported as the grid's two fields on the same voxels,
    each where its cube is (voxel centres strictly inside), 0 elsewhere; no key (the
    densities are written inline in a saved scene)."""
    from photic_blender import natural_waters
    vol = volume_with_two_grids()
    vol.location = (1.0, 2.0, -3.0)
    volume_sea(tmp_path, vol)
    natural_waters._VOLUME_CACHE.clear()
    asked = counting_reads(monkeypatch)
    done = natural_waters.read_volumes(bpy.context.scene)
    assert asked == [("Plume", "density"), ("Plume", "cdom")]
    assert [d[:2] for d in done] == [("Sea", "Plume")] and isinstance(done[0][2], tuple)
    (entry,) = natural_waters._VOLUME_CACHE.values()
    assert list(entry) == ["density", "cdom"]
    scene, water = export_water()
    g = scene.water[0].iops
    (f,) = g.extra_fields
    assert f.name == "cdom" and f.key is None and "density" in water["iop_grid"]["fields"][0]
    rho, cdom = np.asarray(g.density), np.asarray(f.density)
    assert rho.shape == cdom.shape
    cell = np.asarray(g.size) / rho.shape
    np.testing.assert_allclose(cell, 0.25)
    for values, value, count, lo, hi in (
            (rho, 2.0, 7 * 3 * 3, [1.5 - 0.75, 1.75, -3.25], [1.5 + 0.75, 2.25, -2.75]),
            (cdom, 0.5, 3 * 3 * 3, [0.5 - 0.25, 1.75, -3.25], [0.5 + 0.25, 2.25, -2.75])):
        assert set(np.unique(values[values > 1e-3]).tolist()) == {value}
        inside = np.argwhere(values > 1e-3)
        assert len(inside) == count
        centres = np.asarray(g.origin) + (inside + 0.5) * cell
        np.testing.assert_allclose(centres.min(axis=0), lo, atol=1e-6)
        np.testing.assert_allclose(centres.max(axis=0), hi, atol=1e-6)
    from photic.iop_models import iops_from_model
    np.testing.assert_allclose(f.unit.absorption,
                               iops_from_model({**CDOM, "water": "none"}, scene.bands).absorption)


def test_volume_grids_are_read_once_per_grid(empty, tmp_path, monkeypatch):
    """Two water objects sharing the Volume, one with the further field 'cdom' and one with
    'cdom' and 'sed': one read of each grid per call; a second call that keeps current reads
    (force=False, as the render_pre handler) reads nothing, nor after a field is added that
    the entry has; a field added that it lacks is read alone; the 'Read Volume Grids' operator
    and the render_pre handler read the further grids too."""
    from photic_blender import natural_waters
    vol = volume_with_two_grids(grids={
        "density": (2.0, (2.0, 1.0, 1.0), (0.5, 0.0, 0.0), 0.25),
        "cdom": (0.5, (1.0, 1.0, 1.0), (-0.5, 0.0, 0.0), 0.25),
        "sed": (1.0, (0.75, 0.75, 0.75), (0.0, 0.0, 0.0), 0.25)})
    sea = volume_sea(tmp_path, vol)
    v = [(-1, -1, -5), (1, -1, -5), (1, 1, -5), (-1, 1, -5), (-1, -1, -4), (1, -1, -4), (1, 1, -4), (-1, 1, -4)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    mesh = bpy.data.meshes.new("Tank")
    mesh.from_pydata(v, [], faces)
    tank = link(bpy.data.objects.new("Tank", mesh))
    t = tank.photic
    t.role, t.iop_variation, t.grid_source, t.grid_box = "WATER_BODY", "GRID", "VOLUME", vol
    for name in ("sed", "cdom"):
        t.grid_fields.add().name = name
    natural_waters._VOLUME_CACHE.clear()
    asked = counting_reads(monkeypatch)
    natural_waters.read_volumes(bpy.context.scene)
    assert sorted(asked) == [("Plume", "cdom"), ("Plume", "density"), ("Plume", "sed")]
    asked.clear()
    natural_waters.read_volumes(bpy.context.scene, force=False)
    assert asked == []
    natural_waters._read_volumes_before_render(bpy.context.scene)  # render_pre: keeps them
    assert asked == []
    natural_waters._VOLUME_CACHE.clear()
    natural_waters._read_volumes_before_render(bpy.context.scene)
    assert sorted(asked) == [("Plume", "cdom"), ("Plume", "density"), ("Plume", "sed")]
    (entry,) = natural_waters._VOLUME_CACHE.values()
    assert sorted(entry) == ["cdom", "density", "sed"]
    asked.clear()
    sea.photic.grid_fields.add().name = "sed"
    natural_waters.read_volumes(bpy.context.scene, force=False)
    assert asked == []
    # Only the water surface reads the Volume now: 'cdom' kept, 'sed' read alone.
    tank.photic.role = "NONE"
    natural_waters._VOLUME_CACHE.clear()
    sea.photic.grid_fields.remove(1)
    natural_waters.read_volumes(bpy.context.scene)
    asked.clear()
    sea.photic.grid_fields.add().name = "sed"
    natural_waters.read_volumes(bpy.context.scene, force=False)
    assert asked == [("Plume", "sed")]
    natural_waters._VOLUME_CACHE.clear()
    asked.clear()
    assert bpy.ops.photic.read_volume_grids() == {"FINISHED"}
    assert asked == [("Plume", "density"), ("Plume", "cdom"), ("Plume", "sed")]
    scene, _ = export_water()
    assert [f.name for f in scene.water[0].iops.extra_fields] == ["cdom", "sed"]
    assert int((scene.water[0].iops.extra_fields[1].density > 0.5).sum()) == 3 * 3 * 3


def test_every_frame_read_keeps_each_unchanged_grid_once(empty, tmp_path):
    """'Read Volume Grids' > 'Every Frame' over a Volume whose two grids do not change from
    frame to frame: one cache entry per frame, each holding both grids, each grid's densities
    stored once; the scene back at its frame."""
    from photic_blender import natural_waters
    volume_sea(tmp_path, volume_with_two_grids())
    empty.frame_start, empty.frame_end = 1, 3
    empty.frame_set(2)
    natural_waters._VOLUME_CACHE.clear()
    assert bpy.ops.photic.read_volume_grids(every_frame=True) == {"FINISHED"}
    assert empty.frame_current == 2 and len(natural_waters._VOLUME_CACHE) == 3
    for name in ("density", "cdom"):
        assert len({id(e[name][0]) for e in natural_waters._VOLUME_CACHE.values()}) == 1


def test_volume_field_problems_name_the_field(empty, tmp_path, monkeypatch):
    """A grid the Volume lacks (the error lists the grids it has), a grid on other voxels
    than 'density', and a field added since the last read: each names the water object and
    the property to look at."""
    from photic_blender import natural_waters, volume_grid
    vol = volume_with_two_grids()
    sea = volume_sea(tmp_path, vol)
    sea.photic.grid_fields[0].name = "sed"
    done = natural_waters.read_volumes(bpy.context.scene)
    assert isinstance(done[0][2], export.ExportError)
    with pytest.raises(export.ExportError) as info:
        export_water()
    message = str(info.value)
    for text in ["Object 'Sea'", "Further Density Field 'sed' > Name (photic.grid_fields[0].name)",
                 "Volume 'Plume' has no grid 'sed'", "(it has: density, cdom)"]:
        assert text in message, message
    # The operator reports it and stops.
    with pytest.raises(RuntimeError, match="no grid 'sed'"):
        bpy.ops.photic.read_volume_grids()
    # A field added since the read: not read yet, the button named.
    sea.photic.grid_fields[0].name = "cdom"
    natural_waters.read_volumes(bpy.context.scene)
    sea.photic.grid_fields.add().name = "other"
    monkeypatch.setattr(volume_grid, "on_main_thread", lambda: False)  # as in an F12 render
    with pytest.raises(export.ExportError) as info:
        export_water()
    message = str(info.value)
    for text in ["Density (photic.grid_source)", "grid 'other' of Volume 'Plume'",
                 "has not been read", "Read Volume Grids"]:
        assert text in message, message
    monkeypatch.undo()
    # A 'cdom' grid of coarser voxels is not on the density's voxels.
    sea.photic.grid_fields.remove(1)
    coarse = volume_with_two_grids("Coarse", grids={
        "density": (2.0, (2.0, 1.0, 1.0), (0.5, 0.0, 0.0), 0.25),
        "cdom": (0.5, (1.0, 1.0, 1.0), (-0.5, 0.0, 0.0), 0.5)})
    sea.photic.grid_box = coarse
    natural_waters.read_volumes(bpy.context.scene)
    with pytest.raises(export.ExportError) as info:
        export_water()
    message = str(info.value)
    for text in ["Object 'Sea'", "(photic.grid_fields[0].name)", "Volume 'Coarse': grid 'cdom' spans",
                 "grid 'density' spans", "every field is on the grid's voxels"]:
        assert text in message, message


def test_further_field_renders_through_the_render_engine(empty, tmp_path):
    """A turbid slab that only a further field holds (the first field's density is 0): F12
    renders it, and a radiometer looking down on the slab sees more upwelling light than one
    over clear water."""
    from photic_blender import final_render
    sed = np.zeros((8, 8, 4), np.float32)
    sed[4:] = 1.0  # x > 0: the turbid half of the box
    sea = two_field_sea(tmp_path, sed=sed)
    np.savez(tmp_path / "plume.npz", density=np.zeros((8, 8, 4), np.float32),
             cdom=np.zeros((8, 8, 4), np.float32), sed=sed)
    f = sea.photic.grid_fields.add()
    f.name, f.unit_source, f.unit_absorption_bands, f.unit_scattering = "sed", "VALUES", "0.05", 5.0
    sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
    sun.rotation_euler = (0.5236, 0.0, 0.0)
    for name, x in (("Lu_turbid", 2.0), ("Lu_clear", -2.0)):
        r = link(bpy.data.objects.new(name, None))
        r.location = (x, 0.0, 0.5)
        r.photic.role, r.photic.quantity = "RADIOMETER", "radiance"
    empty.photic.samples, empty.photic.radiometer_samples = 2, 4000
    empty.render.filepath = str(tmp_path / "frame_")
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()
    assert not final_render.LAST_RENDER.get("error"), final_render.LAST_RENDER
    rows = {r["name"]: r for r in final_render.LAST_RADIOMETERS[empty.name]["rows"]}
    turbid, clear = (np.array(rows[n]["value"]) for n in ("Lu_turbid", "Lu_clear"))
    assert np.all(np.isfinite(turbid)) and np.all(turbid > 3 * clear), (turbid, clear)


# ------------------------------------------------------------------------------------------
# Import, panel, operators
# ------------------------------------------------------------------------------------------

def test_grid_with_further_fields_imports_and_exports_back(empty, tmp_path):
    """(d) File > Import of a scene whose grid has further fields read from its .npz by key:
    the water object gets them as Further Density Fields named after their arrays with their
    unit IOPs as coefficients (no IOP model describes explicit coefficients), the first
    field's file path kept, and exports back to the same water."""
    rng = np.random.default_rng(3)
    np.savez(tmp_path / "g.npz", density=rng.random((5, 4, 3)), cdom=rng.random((5, 4, 3)),
             sed=rng.random((5, 4, 3)))
    petzold = {"type": "petzold"}
    water = {"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0}, "iop_grid": {
        "base": {"iops": {"absorption": [0.3, 0.06, 0.02], "b": [0.05, 0.05, 0.05], "phase": petzold}},
        "unit": {"iops": {"absorption": [0.1, 0.2, 0.4], "b": [2.0, 2.0, 2.0], "phase": petzold}},
        "origin": [-8.0, -4.0, -2.0], "size": [16.0, 8.0, 2.0], "file": str(tmp_path / "g.npz"),
        "fields": [
            {"name": "cdom", "key": "cdom",
             "unit": {"iops": {"absorption": [0.05, 0.125, 0.5], "b": [0.0, 0.0, 0.0], "phase": petzold}}},
            {"name": "sed", "key": "sed",
             "unit": {"iops": {"absorption": [0.01, 0.02, 0.03], "b": [1.5, 1.25, 1.0], "phase": petzold}}}]}}
    d = {"photic_scene": 1, "name": "fields", "water": [water], "bands": [
            {"name": "620", "center_nm": 620.0, "width_nm": 80.0},
            {"name": "550", "center_nm": 550.0, "width_nm": 60.0},
            {"name": "460", "center_nm": 460.0, "width_nm": 80.0}],
         "sky": {"type": "uniform", "radiance": [0.1, 0.1, 0.1]},
         "cameras": [{"name": "cam", "type": "perspective", "position": [0, -5, 3], "look_at": [0, 0, 0],
                      "fov_deg": 40, "resolution": [8, 8]}]}
    src = tmp_path / "fields.json"
    src.write_text(json.dumps(d))
    assert bpy.ops.photic.import_scene(filepath=str(src)) == {"FINISHED"}
    p = bpy.data.objects["sea"].photic
    assert p.grid_file == str(tmp_path / "g.npz")
    assert [(f.name, f.unit_source) for f in p.grid_fields] == [("cdom", "VALUES"), ("sed", "VALUES")]
    assert p.grid_fields[1].unit_scattering_bands == "1.5, 1.25, 1.0"
    _, exported = export_water()
    assert exported == photic.scene.load_scene(src).to_dict()["water"][0]


def test_import_of_an_inline_further_field_says_why(empty, tmp_path):
    from photic_blender.importer import import_scene
    np.savez(tmp_path / "g.npz", density=np.ones((1, 1, 1)))
    d = {"photic_scene": 1, "name": "inline", "sky": {"type": "uniform", "radiance": [0.1]},
         "bands": [{"name": "550", "center_nm": 550, "width_nm": 10}],
         "cameras": [{"name": "cam", "type": "perspective", "position": [0, -5, 3], "look_at": [0, 0, 0]}],
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat"}, "iop_grid": {
             "base": {"iops": {"absorption": [0.1]}}, "unit": {"iops": {"absorption": [0.1]}},
             "origin": [0, 0, -1], "size": [1, 1, 1], "file": str(tmp_path / "g.npz"),
             "fields": [{"name": "cdom", "unit": {"iops": {"absorption": [0.2]}}, "density": [[[1.0]]]}]}}]}
    src = tmp_path / "inline.json"
    src.write_text(json.dumps(d))
    with pytest.raises(ValueError, match="water 'sea'.*field 'cdom'.*inline.*numpy.savez"):
        import_scene(photic.scene.load_scene(src), empty)


def test_panel_and_operators_add_draw_and_remove_fields(empty):
    """'Add Density Field' adds fields with names of their own up to three; the IOP
    Variation panel draws each (name, remove button, its unit IOPs either way); 'Remove'
    takes the one it is pressed on."""
    sea = add_sea()
    bpy.context.view_layer.objects.active = sea
    p = sea.photic
    p.iop_variation = "GRID"
    for _ in range(3):
        assert bpy.ops.photic.grid_field_add() == {"FINISHED"}
    assert [f.name for f in p.grid_fields] == ["cdom", "field2", "field3"]
    assert not bpy.ops.photic.grid_field_add.poll()  # at most three
    assert json.loads(p.grid_fields[0].unit_model) == CDOM and p.grid_fields[0].unit_source == "MODEL"
    p.grid_fields[1].unit_source, p.grid_fields[1].unit_phase_function = "VALUES", "henyey_greenstein"
    shown = []
    context = SimpleNamespace(engine="PHOTIC", scene=empty, object=sea)
    ui.PHOTIC_PT_iop_variation.draw(SimpleNamespace(layout=FakeLayout(shown)), context)
    assert shown.count("name") == 3 and shown.count("photic.grid_field_remove") == 3
    assert shown.count("unit_model") == 2  # two further fields (the first has coefficients)
    assert "unit_hg_g" in shown and "photic.grid_field_add" in shown
    assert "photic.grid_fields_from_source" in shown
    assert bpy.ops.photic.grid_field_remove(index=1) == {"FINISHED"}
    assert [f.name for f in p.grid_fields] == ["cdom", "field3"]
    assert bpy.ops.photic.grid_field_add() == {"FINISHED"}
    assert [f.name for f in p.grid_fields] == ["cdom", "field3", "field2"]
    p.role = "RADIOMETER"
    assert not bpy.ops.photic.grid_field_add.poll()


def fields_from_source(sea):
    """Runs 'Add Fields from Source' on ``sea`` as the panel's button does: its result and
    its reports ((type, message) each)."""
    from photic_blender.operators import PHOTIC_OT_grid_fields_from_source as op
    bpy.context.view_layer.objects.active = sea
    assert op.poll(bpy.context)
    reports = []
    me = SimpleNamespace(report=lambda kind, text: reports.append((kind, text)))
    return op.execute(me, bpy.context), reports


def test_fields_from_the_npz_add_its_other_3d_arrays(empty, tmp_path):
    """'Add Fields from Source' over an .npz with 'density', 'cdom', 'chl' and a 2-D 'meta':
    adds 'cdom' and 'chl' (not 'meta') with the default unit IOPs; a second press adds
    nothing and says why; the limit of 3 further fields is kept, naming what it left out."""
    sea = grid_sea(tmp_path)
    cube = np.ones((4, 3, 2), np.float32)
    np.savez(tmp_path / "plume.npz", density=cube, cdom=cube, chl=2 * cube, meta=np.ones((4, 3)))
    p = sea.photic
    bpy.context.view_layer.objects.active = sea
    assert bpy.ops.photic.grid_fields_from_source() == {"FINISHED"}
    assert [f.name for f in p.grid_fields] == ["cdom", "chl"]
    default = type(p.grid_fields[0]).bl_rna.properties
    for f in p.grid_fields:
        assert f.unit_source == "MODEL" and f.unit_model == default["unit_model"].default
    done, reports = fields_from_source(sea)
    assert done == {"CANCELLED"} and [k for k, _ in reports] == [{"WARNING"}]
    assert "present already (cdom, chl)" in reports[0][1], reports
    scene, _ = export_water()  # the fields read their arrays
    assert [f.name for f in scene.water[0].iops.extra_fields] == ["cdom", "chl"]
    # The limit: one place left for 'sed' and 'tss' after 'cdom', 'chl'.
    np.savez(tmp_path / "plume.npz", density=cube, cdom=cube, chl=cube, sed=cube, tss=cube)
    done, reports = fields_from_source(sea)
    assert done == {"FINISHED"} and [f.name for f in p.grid_fields] == ["cdom", "chl", "sed"]
    assert reports[0][0] == {"INFO"} and "added density fields sed" in reports[0][1]
    assert "not added tss" in reports[0][1], reports
    done, reports = fields_from_source(sea)
    assert done == {"CANCELLED"} and reports[0][0] == {"WARNING"}
    assert "at most 3" in reports[0][1] and "not added tss" in reports[0][1], reports
    # No file, and no grid variation (the button is not offered).
    p.grid_fields.clear()
    p.grid_file = ""
    done, reports = fields_from_source(sea)
    assert done == {"CANCELLED"} and "no Density File" in reports[0][1] and not p.grid_fields
    p.iop_variation = "PROFILE"
    assert not bpy.ops.photic.grid_fields_from_source.poll()


def test_fields_from_the_volume_add_its_other_float_grids(empty, tmp_path):
    """Over a Volume with the float grids 'density' and 'cdom': adds 'cdom'; without a Volume
    as the Grid Box it adds nothing and says so."""
    sea = grid_sea(tmp_path)
    p = sea.photic
    p.grid_source, p.grid_box = "VOLUME", volume_with_two_grids()
    done, reports = fields_from_source(sea)
    assert done == {"FINISHED"} and [f.name for f in p.grid_fields] == ["cdom"]
    assert "added density fields cdom from Volume 'Plume'" in reports[0][1], reports
    done, reports = fields_from_source(sea)
    assert done == {"CANCELLED"} and "present already (cdom)" in reports[0][1]
    p.grid_box = None
    done, reports = fields_from_source(sea)
    assert done == {"CANCELLED"} and reports == [({"WARNING"}, "Photic: no fields added: no "
                                                               "Volume object as the Grid Box")]
