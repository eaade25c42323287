"""Instanced geometry from Blender (issue 43): the copies of one mesh (Geometry Nodes Instance
on Points, particle systems, collection instances, linked duplicates) are exported as one
engine mesh in its own coordinates with a transform per copy (``MeshObject.instances``), a
mesh met once stays flattened into the world; what is rendered is what the flattened copies
render, and File > Import makes linked duplicates that export back to the same instances.
Through ``import bpy`` (Blender 5.0 as a module).
"""
from __future__ import annotations

import copy
import math
import time

import numpy as np
import pytest

import bpy  # noqa: E402

from test_addon_blender_features import (add_camera, add_mesh, add_plane, add_sun, combined,  # noqa: E402,F401
                                         empty, export_current, node_material, photic, render,
                                         scatter_spheres, uniform_world)


def wedge(name="Wedge", location=(0, 0, 0)):
    """A small mesh with no mirror symmetry (a mirrored copy is a different solid)."""
    v = [(0, 0, 0), (1, 0, 0), (0, 0.6, 0), (0, 0, 0.8), (0.3, 0.2, 0.5)]
    f = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4)]
    return add_mesh(name, v, f, location)


def scatter(carrier, side, subdivisions=1, radius=0.2, transforms=True, material=None):
    """An ico sphere instanced on the side x side points of a grid on ``carrier`` (kept), each
    copy randomly rotated and scaled, about half mirrored (``scatter_spheres``)."""
    return scatter_spheres(carrier, count_side=side, radius=radius, material=material, size=0.5 * side,
                           subdivisions=subdivisions, transforms=transforms)


def world_triangles(select):
    """The world corners (T, 3, 3) of every depsgraph instance ``select(instance)`` takes, read
    straight from Blender (each instance's evaluated mesh, its loop triangles, its world
    matrix), winding reversed where the matrix mirrors: what flattening every copy gives."""
    out = []
    for inst in bpy.context.evaluated_depsgraph_get().object_instances:
        if not select(inst):
            continue
        obj = inst.object
        mesh = obj.to_mesh()
        mesh.calc_loop_triangles()
        local = np.array([v.co for v in mesh.vertices], np.float64)
        tris = np.array([t.vertices for t in mesh.loop_triangles], np.int64)
        obj.to_mesh_clear()
        m = np.array(inst.matrix_world, np.float64)
        if np.linalg.det(m[:3, :3]) < 0:
            tris = tris[:, ::-1]
        world = local @ m[:3, :3].T + m[:3, 3]
        out.append(world[tris])
    return np.concatenate(out)


def corners(mesh_object):
    """The world corners (T, 3, 3) of an engine mesh, flattened (every copy in the world)."""
    flat = mesh_object.flattened().mesh
    return flat.vertices[flat.triangles]


def test_geometry_nodes_instance_on_points_is_one_mesh_and_a_transform_per_point(empty):
    add_camera()
    seabed = add_plane("Seabed", size=10.0, location=(0, 0, -5))
    red, bsdf = node_material("Red")
    scatter(seabed, side=20, material=red)
    scene, info = export_current()
    assert sorted((m.material, m.copies) for m in scene.meshes) == [
        ("Red", 400), ("photic_default_grey", 1)], [(m.name, m.material, m.copies) for m in scene.meshes]
    spheres = next(m for m in scene.meshes if m.material == "Red")
    floor = next(m for m in scene.meshes if m.material != "Red")
    assert spheres.instances.shape == (400, 3, 4) and spheres.instances.dtype == np.float64
    assert len(spheres.mesh.triangles) == 20  # one ico sphere (1 subdivision), once
    dets = np.linalg.det(spheres.instances[:, :, :3])
    assert 100 < np.sum(dets < 0) < 300  # about half mirrored
    assert floor.instances is None and len(floor.mesh.triangles) == 2  # the carrier, flattened
    np.testing.assert_allclose(floor.mesh.vertices[:, 2], -5.0)
    assert info.triangles == 400 * 20 + 2
    assert (info.instanced_meshes, info.instanced_copies) == (1, 400)
    assert info.describe() == "8,002 triangles (400 copies of 1 mesh)"
    # Every copy where flattening it in the world puts it, with its faces outward.
    expected = world_triangles(lambda inst: inst.is_instance)
    got = corners(spheres)
    assert got.shape == expected.shape == (400 * 20, 3, 3)
    np.testing.assert_allclose(got, expected, rtol=0, atol=2e-6)


def linked_duplicates():
    """A floor and five linked duplicates of a wedge: rotated, scaled, one mirrored."""
    uniform_world(strength=0.5)
    add_sun(35)
    add_plane("Floor", size=12.0)
    original = wedge(location=(-3, 0, 0))
    rock, bsdf = node_material("Rock")
    bsdf.inputs["Base Color"].default_value = (0.6, 0.5, 0.4, 1)
    original.data.materials.append(rock)
    for loc, rot, scale in [((-1, 1, 0), (0, 0, 0.7), (1, 1, 1)),
                            ((1, -1, 0.2), (0.3, 0, 2.0), (1.5, 1, 0.7)),
                            ((2, 1.5, 0), (0, 0, 0), (-1, 1, 1)),  # mirrored
                            ((0, -2.5, 0), (0, 0, -1.2), (2, 2, 2))]:
        dup = original.copy()  # (sharing the mesh data)
        dup.location, dup.rotation_euler, dup.scale = loc, rot, scale
        bpy.context.scene.collection.objects.link(dup)
    add_camera(location=(0, -9, 7), rotation=(math.radians(52), 0, 0))


def z_scores(a, b):
    """Per pixel and band (a - b) / sqrt(var_a + var_b) of two independent renders; pixels
    whose two variances are both zero must agree exactly (they are returned separately)."""
    var = a.variance + b.variance
    ok = var > 0
    return (a.mean - b.mean)[ok] / np.sqrt(var[ok]), (a.mean - b.mean)[~ok]


def test_linked_duplicates_render_as_their_flattened_copies(empty):
    empty.render.resolution_x, empty.render.resolution_y = 48, 32
    linked_duplicates()
    scene, info = export_current()
    floor, rocks = scene.meshes
    assert floor.instances is None and rocks.material == "Rock"
    assert rocks.copies == 5 and len(rocks.mesh.triangles) == 6 and info.meshes_evaluated == 2
    assert np.sum(np.linalg.det(rocks.instances[:, :, :3]) < 0) == 1
    np.testing.assert_allclose(rocks.mesh.vertices.max(axis=0), [1, 0.6, 0.8], atol=1e-6)  # local
    np.testing.assert_allclose(corners(rocks), world_triangles(
        lambda inst: inst.object.data is not None and inst.object.data.original.name == "Wedge"), atol=2e-6)
    flat = copy.copy(scene)
    flat.meshes = [m.flattened() for m in scene.meshes]
    assert flat.meshes[1].instances is None and len(flat.meshes[1].mesh.triangles) == 30
    cam = scene.cameras[0].name
    t0 = time.perf_counter()
    a = photic.render.render(scene, samples=64, seed=1, threads=2).images[cam]
    b = photic.render.render(flat, samples=64, seed=2, threads=2).images[cam]
    z, exact = z_scores(a, b)
    print(f"instanced vs flattened: mean z^2 {np.mean(z ** 2):.3f}, max |z| {np.abs(z).max():.2f} "
          f"over {z.size} pixel-bands ({time.perf_counter() - t0:.2f} s)")
    assert z.size > 0.9 * a.mean.size and np.all(exact == 0)
    assert 0.7 < np.mean(z ** 2) < 1.4 and np.abs(z).max() < 6
    # (the test sees a copy less: leaving out the mirrored one is far outside those bounds)
    rocks_less = copy.copy(scene)
    rocks_less.meshes = [floor, photic.scene.MeshObject("w", rocks.mesh, rocks.material,
                                                         instances=rocks.instances[[0, 1, 2, 4]])]
    c = photic.render.render(rocks_less, samples=64, seed=2, threads=2).images[cam]
    z, _ = z_scores(a, c)
    assert np.mean(z ** 2) > 1.4 or np.abs(z).max() > 6


def test_f12_renders_instances_and_says_how_many(empty):
    linked_duplicates()
    summary = render()  # (bpy.ops.render.render, as F12)
    assert (summary["instanced_meshes"], summary["instanced_copies"]) == (1, 5)
    assert summary["triangles"] == 2 + 5 * 6
    px = combined(empty)
    assert px.shape == (16, 24, 4) and np.all(np.isfinite(px)) and px[..., :3].mean() > 0


@pytest.mark.parametrize("how", ["particles", "collection"])
def test_instances_of_a_mesh_with_two_material_slots_are_one_instanced_mesh_per_slot(empty, how):
    add_camera()
    v = [(-.2, -.2, 0), (.2, -.2, 0), (.2, .2, 0), (-.2, .2, 0), (0, 0, .3)]
    f = [(0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)]
    rock = add_mesh("Rock", v, f)
    a, bsdf = node_material("Base")
    bsdf.inputs["Base Color"].default_value = (0.2, 0.2, 0.2, 1)
    b, bsdf = node_material("Cap")
    bsdf.inputs["Base Color"].default_value = (0.9, 0.1, 0.1, 1)
    rock.data.materials.append(a)
    rock.data.materials.append(b)
    for p in rock.data.polygons:
        p.material_index = 0 if p.index == 0 else 1  # the base quad, the four sides
    if how == "particles":  # hair particles rendered as the rock
        rock.location = (0, 0, 20)  # (the rock itself is one more, separate object)
        emitter = add_plane("Emitter", size=4.0)
        settings = emitter.modifiers.new("Rocks", "PARTICLE_SYSTEM").particle_system.settings
        settings.type, settings.count = "HAIR", 50
        settings.render_type, settings.instance_object = "OBJECT", rock
        n = 50
    else:  # collection instances of a collection holding the rock
        for c in rock.users_collection:
            c.objects.unlink(rock)
        coll = bpy.data.collections.new("Rocks")
        coll.objects.link(rock)
        for k in range(7):
            inst = bpy.data.objects.new(f"Rocks {k}", None)
            inst.instance_type, inst.instance_collection = "COLLECTION", coll
            inst.location = (k, 0.5 * k, 0)
            inst.rotation_euler.z = 0.4 * k
            bpy.context.scene.collection.objects.link(inst)
        n = 7
    scene, info = export_current()
    instanced = [m for m in scene.meshes if m.instances is not None]
    assert [(m.material, m.copies, len(m.mesh.triangles)) for m in instanced] == [
        ("Base", n, 2), ("Cap", n, 4)]
    # (named after the rock, the slot's material; '#2' where the rock itself is one more mesh)
    assert [m.name.split(" #")[0] for m in instanced] == ["Rock [Base]", "Rock [Cap]"]
    np.testing.assert_array_equal(instanced[0].instances, instanced[1].instances)
    assert scene.materials["Cap"].reflectance[0] > scene.materials["Base"].reflectance[0]
    assert info.instanced_meshes == 1 and info.instanced_copies == n
    # The base quad's triangles where the rock's base is, in each copy.
    base = corners(instanced[0]).reshape(n, 2, 3, 3)
    transforms = instanced[0].instances
    np.testing.assert_allclose(base.reshape(n, -1, 3).mean(axis=1), transforms[:, :, 3], atol=1e-5)
    if how == "particles":  # the rock object itself: one copy, flattened
        alone = [m for m in scene.meshes if m.instances is None and m.material in ("Base", "Cap")]
        assert sorted(len(m.mesh.triangles) for m in alone) == [2, 4]
        assert all(np.allclose(m.mesh.vertices[:, 2].min(), 20.0) for m in alone)


def test_a_mesh_met_once_stays_flattened(empty):
    add_camera()
    obj = wedge(location=(1, 2, 3))
    obj.rotation_euler = (0.3, -0.2, 1.0)
    obj.scale = (-1.5, 1, 2)  # mirrored: its winding is reversed in the world, as ever
    scene, info = export_current()
    (m,) = scene.meshes
    assert m.instances is None and m.copies == 1
    assert (info.instanced_meshes, info.instanced_copies) == (0, 0)
    assert info.describe() == "6 triangles"
    np.testing.assert_allclose(m.mesh.vertices[m.mesh.triangles],
                               world_triangles(lambda inst: inst.object.name == "Wedge"), atol=1e-6)


def test_copies_scaled_to_nothing_are_left_out_with_a_warning(empty):
    add_camera()
    obj = wedge()
    for k, scale in enumerate([(1, 1, 1), (0, 0, 0), (2, 2, 2)]):
        dup = obj.copy()
        dup.location, dup.scale = (2 * k + 2, 0, 0), scale
        bpy.context.scene.collection.objects.link(dup)
    scene, info = export_current()
    (m,) = scene.meshes
    assert m.copies == 3 and info.instanced_copies == 3
    assert any("1 instance(s) of zero size skipped" in w for w in info.warnings), info.warnings


def test_a_copy_with_a_non_finite_transform_is_named(empty):
    from photic_blender.export_values import ExportError
    add_camera()
    obj = wedge()
    for k in range(3):
        dup = obj.copy()
        dup.name = f"Bad {k}" if k == 1 else f"Good {k}"
        dup.location = (2 * k + 2, 0, 0)
        bpy.context.scene.collection.objects.link(dup)
    bpy.data.objects["Bad 1"].location.x = float("nan")
    with pytest.raises(ExportError) as err:
        export_current()
    assert "Object 'Bad 1'" in str(err.value) and "Location" in str(err.value)


def test_ten_thousand_geometry_nodes_instances_export_as_one_mesh(empty):
    """10,000 ico spheres of 320 triangles (3.2 M triangles flattened): one mesh of 320
    triangles and 10,000 transforms. The time is printed, not asserted (a loaded machine is
    slow; scripts/instancing_export_time.py compares it with flattening)."""
    add_camera()
    carrier = add_plane("Seabed", size=1.0)
    scatter(carrier, side=100, subdivisions=3, transforms=False)
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        scene, info = export_current()
        times.append(time.perf_counter() - t0)
    spheres = next(m for m in scene.meshes if m.instances is not None)
    assert len(scene.meshes) == 2 and len(spheres.mesh.triangles) == 320
    assert spheres.instances.shape == (10_000, 3, 4)
    assert info.triangles == 10_000 * 320 + 2 and info.meshes_evaluated == 2
    assert info.describe() == "3,200,002 triangles (10,000 copies of 1 mesh)"
    # the grid's points (50 m across), each sphere unrotated
    np.testing.assert_allclose(np.ptp(spheres.instances[:, :2, 3], axis=0), [50.0, 50.0], atol=1e-4)
    np.testing.assert_allclose(spheres.instances[:, :, :3], np.broadcast_to(np.eye(3), (10_000, 3, 3)), atol=1e-6)
    print(f"export of 10,000 instances ({info.triangles:,} triangles): {min(times):.3f} s "
          f"(best of 2: {', '.join(f'{t:.3f}' for t in times)})")


def test_import_makes_linked_duplicates_that_export_back_to_the_instances(empty, tmp_path):
    from photic_blender.importer import import_scene
    S = photic.scene
    v = np.array([(0, 0, 0), (1, 0, 0), (0, 0.6, 0), (0, 0, 0.8)], float)
    t = np.array([(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
    rng = np.random.default_rng(5)
    transforms = []
    for k in range(6):
        angle = rng.uniform(0, 2 * np.pi)
        c, s = np.cos(angle), np.sin(angle)
        r = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) * rng.uniform(0.5, 2.0)
        if k == 3:
            r[:, 0] *= -1  # mirrored
        transforms.append(np.column_stack([r, [k, -k, 0.5]]))
    transforms = np.array(transforms)
    src = S.Scene(name="Copies", bands=[S.Band("550", 550.0, 10.0)],
                  materials={"stone": S.Material("stone", [0.3])},
                  meshes=[S.MeshObject("Stone", S.TriangleMesh(v, t), "stone", instances=transforms)],
                  sun=S.Sun(zenith_deg=30.0, azimuth_deg=0.0, irradiance=[1.0]),
                  cameras=[S.Camera("cam", "perspective", position=[0, 0, 10], direction=[0, 0, -1], up=[0, 1, 0],
                                    resolution=(8, 8), fov_deg=40.0)])
    src.validate()
    created = import_scene(src, empty)
    first = created["Stone"]
    copies = [o for o in bpy.data.objects if o.data is first.data]
    assert len(copies) == 6 and first.data.users == 6
    scene, info = export_current()
    (m,) = scene.meshes
    assert m.material == "stone" and m.copies == 6
    np.testing.assert_allclose(m.mesh.vertices, v, atol=1e-6)
    np.testing.assert_array_equal(m.mesh.triangles, t)
    np.testing.assert_allclose(m.instances, transforms, atol=1e-5)


def test_the_meadow_example_exports_its_blades_as_instances():
    """example_blends/seagrass_meadow.blend: about 10,000 Geometry Nodes copies of one blade
    and a rock three times (linked duplicates) export as two meshes with their transforms."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "example_blends" / "seagrass_meadow.blend"
    from photic_blender.batch import ensure_registered

    bpy.ops.wm.open_mainfile(filepath=str(path))
    ensure_registered()
    scene, info = export_current()
    copies = {m.name: m.copies for m in scene.meshes}
    assert copies["rock"] == 3 and 9000 < copies["seagrass blade"] < 11500, copies
    blade = next(m for m in scene.meshes if m.name == "seagrass blade")
    assert len(blade.mesh.triangles) == 80 and blade.material == "seagrass"
    assert info.instanced_copies == copies["rock"] + copies["seagrass blade"]


def test_import_of_many_copies_makes_points_with_a_geometry_nodes_modifier(empty, tmp_path):
    """More than importer.POINTS_ABOVE copies: one object whose points carry the copies'
    rotations and scales and a Geometry Nodes modifier that instances the (hidden) mesh on
    them, not an object per copy; it exports back to the same transforms, in the viewport and
    in a final render's depsgraph, mirrored and unevenly scaled copies included."""
    from photic_blender.batch import export_frames
    from photic_blender.importer import POINTS_ABOVE, import_scene
    S = photic.scene
    n = POINTS_ABOVE + 50
    rng = np.random.default_rng(8)
    x = np.zeros((n, 3, 4))
    for k in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))  # rotations, about half of them mirrored
        x[k, :, :3] = q * rng.uniform(0.5, 1.5, 3)
        x[k, :, 3] = rng.uniform(-5.0, 5.0, 3)
    v = np.array([(0, 0, 0), (1, 0, 0), (0, 0.6, 0), (0, 0, 0.8)], float)
    t = np.array([(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
    src = S.Scene(name="Many", bands=[S.Band("550", 550.0, 10.0)],
                  materials={"stone": S.Material("stone", [0.3])},
                  meshes=[S.MeshObject("Stone", S.TriangleMesh(v, t), "stone", instances=x)],
                  sun=S.Sun(zenith_deg=30.0, azimuth_deg=0.0, irradiance=[1.0]),
                  cameras=[S.Camera("cam", "perspective", position=[0, 0, 10], direction=[0, 0, -1],
                                    up=[0, 1, 0], resolution=(8, 8), fov_deg=40.0)])
    src.validate()
    created = import_scene(src, empty)
    assert len([o for o in bpy.data.objects if o.data is created["Stone"].data]) == 1
    assert created["Stone"].hide_render and "Stone copies" in bpy.data.objects
    scene, info = export_current()
    (m,) = scene.meshes
    assert m.copies == n and info.instanced_copies == n
    np.testing.assert_allclose(m.instances, x, atol=2e-5)
    np.testing.assert_allclose(m.mesh.vertices, v, atol=1e-6)
    path = tmp_path / "many.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    (_, rendered), = export_frames(path)
    np.testing.assert_allclose(rendered.meshes[0].instances, x, atol=2e-5)


def test_euler_and_scale_rebuild_the_transforms():
    from photic_blender.importer import euler_and_scale
    rng = np.random.default_rng(2)
    q = np.array([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(200)])
    r = q * rng.uniform(0.2, 3.0, (200, 1, 3))
    euler, scale = euler_and_scale(r)

    def rot(axis, a):
        c, s = np.cos(a), np.sin(a)
        m = np.zeros((len(a), 3, 3))
        i, j = [(1, 2), (0, 2), (0, 1)][axis]
        m[:, axis, axis] = 1.0
        m[:, i, i] = m[:, j, j] = c
        m[:, i, j], m[:, j, i] = (-s, s) if axis != 1 else (s, -s)
        return m

    back = rot(2, euler[:, 2]) @ rot(1, euler[:, 1]) @ rot(0, euler[:, 0]) * scale[:, None, :]
    np.testing.assert_allclose(back, r, atol=1e-9)
