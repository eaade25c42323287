"""Blender scenes as artists build them (issue 48): what Photic renders of the Ocean modifier,
Geometry Nodes instances, image textures, emission, the World's textures, and the notes that
name what it does not render. Through ``import bpy`` (Blender 5.0 as a module), rendering with
``bpy.ops.render.render`` as F12 and ``blender -b -f`` do.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import bpy  # noqa: E402

from photic.cli import load_addon  # noqa: E402

addon = load_addon()
from photic_blender import export, final_render, scene_notes  # noqa: E402
from photic_blender.batch import ensure_registered  # noqa: E402
from photic_blender.export_values import ExportError  # noqa: E402

from photic_blender.engine_loader import load_engine  # noqa: E402

photic = load_engine()


@pytest.fixture
def empty():
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    scene.render.resolution_x, scene.render.resolution_y = 24, 16
    scene.render.resolution_percentage = 100
    scene.photic.samples = 4
    scene.photic.threads = 2
    scene.photic.auto_exposure = False
    return scene


def add_mesh(name, vertices, faces, location=(0, 0, 0)):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([list(v) for v in vertices], [], [list(f) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_plane(name, size=2.0, location=(0, 0, 0), uv=True):
    s = size / 2
    obj = add_mesh(name, [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [(0, 1, 2, 3)], location)
    if uv:
        layer = obj.data.uv_layers.new(name="UVMap")
        for loop, (u, v) in zip(obj.data.loops, [(0, 0), (1, 0), (1, 1), (0, 1)]):
            layer.data[loop.index].uv = (u, v)
    return obj


def add_camera(location=(0, 0, 5), rotation=(0, 0, 0), ortho=None):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = location, rotation
    if ortho:
        cam.data.type, cam.data.ortho_scale = "ORTHO", ortho
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    return cam


def add_sun(zenith_deg=30.0):
    light = bpy.data.lights.new("Sun", "SUN")
    light.energy = 1.0
    obj = bpy.data.objects.new("Sun", light)
    obj.rotation_euler = (math.radians(zenith_deg), 0, 0)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def uniform_world(colour=(1, 1, 1), strength=1.0):
    world = bpy.data.worlds.new("World")
    bpy.context.scene.world = world
    if hasattr(world, "use_nodes"):
        world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (*colour, 1.0)
    bg.inputs["Strength"].default_value = strength
    return world


def node_material(name):
    mat = bpy.data.materials.new(name)
    if hasattr(mat, "use_nodes"):
        mat.use_nodes = True
    return mat, next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")


def export_current(**kw):
    return export.export_scene(bpy.context.evaluated_depsgraph_get(), photic, **kw)


def render():
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()
    summary = dict(final_render.LAST_RENDER)
    assert not summary.get("error"), summary.get("error")
    rr = bpy.data.images["Render Result"]
    # (the pixels of the Render Result image are not readable in bpy: read the pass)
    return summary


def combined(scene):
    """The last render's Combined pass (H, W, 4), top row first, from the render result."""
    import tempfile
    from pathlib import Path
    path = Path(tempfile.mkdtemp()) / "r.exr"
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "IMAGE"
    settings.file_format, settings.color_depth = "OPEN_EXR", "32"
    bpy.data.images["Render Result"].save_render(filepath=str(path), scene=scene)
    img = bpy.data.images.load(str(path))
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1]


# ------------------------------------------------------------------------------------------
# 1. The Ocean modifier
# ------------------------------------------------------------------------------------------

def ocean_sea(spatial=20.0, choppiness=1.0, size=1.0, shape="MESH"):
    bpy.ops.mesh.primitive_plane_add(size=2)
    sea = bpy.context.object
    sea.name = "Sea"
    mod = sea.modifiers.new("Ocean", "OCEAN")
    mod.spatial_size, mod.size, mod.choppiness = int(spatial), size, choppiness
    mod.resolution = mod.viewport_resolution = 7
    sea.photic.role = "WATER_SURFACE"
    sea.photic.surface_shape = shape
    sea.photic.use_bottom, sea.photic.bottom_depth = True, 6.0
    return sea, mod


def evaluated_vertices(obj):
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        v = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", v)
        return v.reshape(-1, 3).astype(float) @ np.array(obj.matrix_world)[:3, :3].T + np.array(obj.matrix_world)[:3, 3]
    finally:
        ev.to_mesh_clear()


def patch_height(surface, x, y):
    """Bilinear height of an exported periodic grid patch at (x, y), wrapped into its period."""
    v = surface.mesh.vertices
    lx, ly = surface.period
    xs, ys = np.unique(v[:, 0]), np.unique(v[:, 1])
    nx, ny = len(xs) - 1, len(ys) - 1
    z = v[:, 2].reshape(nx + 1, ny + 1)
    u = np.mod(x - xs[0], lx) / lx * nx
    w = np.mod(y - ys[0], ly) / ly * ny
    i, j = np.minimum(np.floor(u).astype(int), nx - 1), np.minimum(np.floor(w).astype(int), ny - 1)
    fu, fw = u - i, w - j
    return ((1 - fu) * (1 - fw) * z[i, j] + fu * (1 - fw) * z[i + 1, j]
            + (1 - fu) * fw * z[i, j + 1] + fu * fw * z[i + 1, j + 1])


def test_ocean_modifier_tiles_with_its_true_period_and_follows_blenders_surface(empty):
    add_camera(location=(0, -8, -2), rotation=(math.radians(80), 0, 0))
    add_sun()
    sea, mod = ocean_sea(spatial=20.0, choppiness=1.0)
    blender = evaluated_vertices(sea)
    ext = np.ptp(blender[:, :2], axis=0)
    assert np.all(ext > 20.4), ext  # the choppy mesh's extent is not the period (issue: 21.0 m)
    scene, info = export_current()
    surface = scene.water[0].surface
    assert surface.kind == "patch"
    assert surface.period == pytest.approx((20.0, 20.0), abs=1e-9)
    v = surface.mesh.vertices
    np.testing.assert_allclose(np.ptp(v[:, :2], axis=0), (20.0, 20.0), rtol=1e-9)
    # The tiles join: the last row and column are the first.
    xs, ys = np.unique(v[:, 0]), np.unique(v[:, 1])
    z = v[:, 2].reshape(len(xs), len(ys))
    np.testing.assert_array_equal(z[0], z[-1])
    np.testing.assert_array_equal(z[:, 0], z[:, -1])
    # The patch is Blender's displaced surface: its heights at the displaced vertices (away
    # from the folds) within 3 % of the waves' height range.
    h = patch_height(surface, blender[:, 0], blender[:, 1])
    err = np.abs(h - blender[:, 2])
    assert np.percentile(err, 95) < 0.03 * np.ptp(blender[:, 2]), np.percentile(err, 95)
    assert not any("Ocean" in w for w in info.warnings if "fold" not in w), info.warnings
    # Size scales the period; a second Repeat adds a second tile but not a longer period.
    mod.size = 1.5
    mod.repeat_x = 2
    scene, _ = export_current()
    assert scene.water[0].surface.period == pytest.approx((30.0, 30.0), abs=1e-9)
    summary = render()
    assert summary.get("samples") == 4


def test_ocean_modifier_is_animated_with_its_time(empty):
    add_camera()
    sea, mod = ocean_sea(choppiness=0.0)
    mod.time = 1.0
    mod.keyframe_insert("time", frame=1)
    mod.time = 5.0
    mod.keyframe_insert("time", frame=9)
    empty.frame_set(1)
    z1 = export_current()[0].water[0].surface.mesh.vertices[:, 2].copy()
    empty.frame_set(5)
    z5 = export_current()[0].water[0].surface.mesh.vertices[:, 2]
    assert z1.shape == z5.shape and not np.allclose(z1, z5)
    np.testing.assert_allclose(z5.reshape(-1).std(), evaluated_vertices(sea)[:, 2].std(), rtol=0.05)


def test_ocean_modifier_on_a_flat_surface_is_named_with_what_to_do(empty):
    add_camera()
    sea, _ = ocean_sea(shape="FLAT")
    scene, info = export_current()
    assert scene.water[0].surface.kind == "flat"
    note = next(w for w in info.warnings if "Ocean" in w)
    assert "Object 'Sea'" in note and "Flat" in note and "Mesh Patch" in note, note
    assert note in scene_notes.for_id(empty.name, "OBJECT", "Sea") or True  # (stored by renders)
    render()
    assert note in scene_notes.for_id(empty.name, "OBJECT", "Sea")
    sea.photic.surface_shape = "WAVES"
    _, info = export_current()
    assert any("Wave Model" in w and "'Ocean'" in w for w in info.warnings), info.warnings
    # The panel's button renders the modifier.
    bpy.context.view_layer.objects.active = sea
    with bpy.context.temp_override(object=sea):
        bpy.ops.photic.use_ocean_modifier()
    assert sea.photic.surface_shape == "MESH"


def test_a_turned_ocean_and_one_narrower_than_its_period_are_refused_clearly(empty):
    add_camera()
    sea, mod = ocean_sea()
    sea.rotation_euler[2] = math.radians(30)
    with pytest.raises(ExportError) as e:
        export_current()
    assert "Rotation" in e.value.prop and "30.0 degrees" in e.value.message
    sea.rotation_euler[2] = math.radians(90)
    assert export_current()[0].water[0].surface.period == pytest.approx((20.0, 20.0), abs=1e-6)
    sea.rotation_euler[2] = 0
    mod.geometry_mode = "DISPLACE"  # on the 2 m plane: a tenth of one period
    with pytest.raises(ExportError) as e:
        export_current()
    assert "period" in e.value.message and "Generate" in e.value.message


def test_a_mesh_patch_that_does_not_tile_is_named(empty):
    add_camera()
    sea = add_mesh("Sea", [(-1, -1, 0), (1, -1, 0.3), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)])
    sea.photic.role, sea.photic.surface_shape = "WATER_SURFACE", "MESH"
    _, info = export_current()
    assert any("does not tile" in w and "Object 'Sea'" in w for w in info.warnings), info.warnings
    sea.data.vertices[1].co.z = 0.0
    _, info = export_current()
    assert not any("does not tile" in w for w in info.warnings)


# ------------------------------------------------------------------------------------------
# Geometry Nodes instances
# ------------------------------------------------------------------------------------------

def scatter_spheres(carrier, count_side=10, radius=0.2, material=None, keep_carrier=True, size=8.0,
                    subdivisions=None, transforms=False):
    """A Geometry Nodes modifier on ``carrier``: an ico sphere instanced on the count_side^2
    points of a size x size grid (Instance on Points), the carrier kept or not; with
    ``transforms``, each copy randomly rotated and scaled, about half of them mirrored (scale
    -1 on x)."""
    mod = carrier.modifiers.new("Scatter", "NODES")
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n, link = tree.nodes, tree.links.new
    gi, go = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    grid = n.new("GeometryNodeMeshGrid")
    grid.inputs["Vertices X"].default_value = count_side
    grid.inputs["Vertices Y"].default_value = count_side
    grid.inputs["Size X"].default_value = grid.inputs["Size Y"].default_value = size
    ico = n.new("GeometryNodeMeshIcoSphere")
    ico.inputs["Radius"].default_value = radius
    if subdivisions is not None:
        ico.inputs["Subdivisions"].default_value = subdivisions
    iop = n.new("GeometryNodeInstanceOnPoints")
    join = n.new("GeometryNodeJoinGeometry")
    src = ico.outputs["Mesh"]
    if material is not None:
        sm = n.new("GeometryNodeSetMaterial")
        sm.inputs["Material"].default_value = material
        link(src, sm.inputs["Geometry"])
        src = sm.outputs["Geometry"]
    link(grid.outputs["Mesh"], iop.inputs["Points"])
    link(src, iop.inputs["Instance"])
    if transforms:
        rot = n.new("FunctionNodeRandomValue")
        rot.data_type = "FLOAT_VECTOR"
        rot.inputs["Min"].default_value, rot.inputs["Max"].default_value = (0, 0, 0), (3, 3, 3)
        scale = n.new("FunctionNodeRandomValue")
        scale.data_type = "FLOAT_VECTOR"
        scale.inputs["Min"].default_value, scale.inputs["Max"].default_value = (0.5,) * 3, (1.5,) * 3
        scale.inputs["Seed"].default_value = 7
        coin = n.new("FunctionNodeRandomValue")
        coin.data_type = "BOOLEAN"
        coin.inputs["Seed"].default_value = 11
        mirror = n.new("GeometryNodeSwitch")
        mirror.input_type = "VECTOR"
        mirror.inputs["False"].default_value, mirror.inputs["True"].default_value = (1, 1, 1), (-1, 1, 1)
        mul = n.new("ShaderNodeVectorMath")
        mul.operation = "MULTIPLY"
        link(coin.outputs[3], mirror.inputs["Switch"])
        link(scale.outputs[0], mul.inputs[0])
        link(mirror.outputs[0], mul.inputs[1])
        link(rot.outputs[0], iop.inputs["Rotation"])
        link(mul.outputs[0], iop.inputs["Scale"])
    link(iop.outputs["Instances"], join.inputs["Geometry"])
    if keep_carrier:
        link(gi.outputs[0], join.inputs["Geometry"])
    link(join.outputs[0], go.inputs[0])
    mod.node_group = tree
    return mod


@pytest.mark.parametrize("keep_carrier", [True, False])
def test_geometry_nodes_instances_are_what_blender_shows(empty, keep_carrier):
    add_camera()
    floor = add_plane("Seabed", size=10.0, location=(0, 0, -5))
    red, bsdf = node_material("Red")
    bsdf.inputs["Base Color"].default_value = (0.8, 0.1, 0.1, 1)
    scatter_spheres(floor, count_side=10, material=red, keep_carrier=keep_carrier)
    scene, info = export_current()
    ico_tris = 20  # an icosphere of 1 subdivision
    sphere_meshes = [m for m in scene.meshes if m.material == "Red"]
    assert len(sphere_meshes) == 1, [(m.name, m.material) for m in scene.meshes]
    # one sphere and a transform per point (tests/test_addon_instancing.py)
    assert sphere_meshes[0].copies == 100 and len(sphere_meshes[0].mesh.triangles) == ico_tris
    spheres = sphere_meshes[0].flattened().mesh
    assert len(spheres.triangles) == 100 * ico_tris
    # 100 spheres at the grid's points on the seabed, each of radius 0.2
    centres = spheres.vertices.reshape(100, -1, 3).mean(axis=1)
    assert np.allclose(centres[:, 2], -5.0, atol=1e-6)
    assert np.ptp(centres[:, 0]) == pytest.approx(8.0, abs=1e-5)
    r = np.linalg.norm(spheres.vertices.reshape(100, -1, 3) - centres[:, None], axis=2)
    assert np.allclose(r, 0.2, rtol=1e-4)
    floors = [m for m in scene.meshes if m.material != "Red"]
    if keep_carrier:  # the seabed once, not once per sphere
        assert len(floors) == 1 and len(floors[0].mesh.triangles) == 2
    else:
        assert floors == []
    assert info.triangles == 100 * ico_tris + (2 if keep_carrier else 0)


# ------------------------------------------------------------------------------------------
# 2. Materials: image textures, emission and notes
# ------------------------------------------------------------------------------------------

def checker_image(name="Checker", colourspace="sRGB", value=0.5):
    """A 2 x 2 byte image: bottom-left and top-right ``value`` grey (encoded), the others black."""
    img = bpy.data.images.new(name, 2, 2, alpha=False)
    img.colorspace_settings.name = colourspace  # (before the pixels: a new space regenerates them)
    px = np.zeros((2, 2, 4), np.float32)
    px[..., 3] = 1
    px[0, 0, :3] = value
    px[1, 1, :3] = value
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def textured_floor(image, mapping_scale=None, uv_map_node=False):
    mat, bsdf = node_material("Tiles")
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Closest"
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    src = None
    if uv_map_node:
        uvn = tree.nodes.new("ShaderNodeUVMap")
        uvn.uv_map = "UVMap"
        src = uvn.outputs["UV"]
    if mapping_scale is not None:
        mp = tree.nodes.new("ShaderNodeMapping")
        mp.inputs["Scale"].default_value = (mapping_scale, mapping_scale, 1)
        if src is None:
            tc = tree.nodes.new("ShaderNodeTexCoord")
            src = tc.outputs["UV"]
        tree.links.new(src, mp.inputs["Vector"])
        src = mp.outputs["Vector"]
    if src is not None:
        tree.links.new(src, tex.inputs["Vector"])
    floor = add_plane("Floor", size=2.0)
    floor.data.materials.append(mat)
    return floor, mat


def test_image_texture_on_base_color_is_rendered_with_its_uv_and_colour_space(empty):
    uniform_world(strength=1.0)
    add_camera(location=(0, 0, 5), ortho=2.0)
    empty.render.resolution_x = empty.render.resolution_y = 16
    floor, mat = textured_floor(checker_image(value=0.5), uv_map_node=True)
    scene, info = export_current()
    m = scene.materials["Tiles"]
    assert m.texture is not None and m.texture.image.shape == (2, 2, 3)
    lin = ((0.5 + 0.055) / 1.055) ** 2.4  # sRGB 0.5 (128/255: 0.2158) decoded
    assert m.texture.image[0, 0, 0] == pytest.approx(((128 / 255 + 0.055) / 1.055) ** 2.4, rel=1e-5)
    assert scene.meshes[0].uv.shape == (2, 3, 2)
    assert not info.warnings, info.warnings
    render()
    px = combined(empty)[..., 0]
    # A uniform sky of radiance 1 on a matte floor: radiance = reflectance. The image's
    # bottom-left texel is the floor's -x -y quarter (the camera looks down, +y up).
    q = {"bl": px[10:15, 1:6], "tr": px[1:6, 10:15], "tl": px[1:6, 1:6], "br": px[10:15, 10:15]}
    assert q["bl"].mean() == pytest.approx(lin, rel=0.1) and q["tr"].mean() == pytest.approx(lin, rel=0.1)
    assert q["tl"].mean() < 0.02 and q["br"].mean() < 0.02


def test_a_mapping_node_tiles_the_texture(empty):
    uniform_world()
    add_camera(location=(0, 0, 5), ortho=2.0)
    floor, mat = textured_floor(checker_image(colourspace="Non-Color", value=1.0), mapping_scale=2.0)
    scene, info = export_current()
    uv = scene.meshes[0].uv
    assert uv.max() == pytest.approx(2.0) and uv.min() == pytest.approx(0.0)
    assert not info.warnings, info.warnings
    assert scene.materials["Tiles"].texture.image.max() == pytest.approx(1.0)


def test_emission_is_rendered_and_what_a_matte_surface_leaves_out_is_named(empty):
    add_camera(location=(0, 0, 5), ortho=2.0)
    lamp = add_plane("Lamp", size=4.0)
    mat, bsdf = node_material("Glow")
    bsdf.inputs["Base Color"].default_value = (0, 0, 0, 1)
    bsdf.inputs["Emission Color"].default_value = (1.0, 0.5, 0.25, 1)
    bsdf.inputs["Emission Strength"].default_value = 3.0
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.05
    lamp.data.materials.append(mat)
    scene, info = export_current()
    np.testing.assert_allclose(scene.materials["Glow"].emission, [3.0, 1.5, 0.75])
    metal = [w for w in info.warnings if "Metallic" in w]
    assert len(metal) == 1 and "Material 'Glow'" in metal[0] and "Principled BSDF" in metal[0]
    assert any("Roughness 0.05" in w for w in info.warnings)
    summary = render()
    px = combined(empty)
    np.testing.assert_allclose(px[4:12, 4:20, :3].reshape(-1, 3).mean(axis=0), [3.0, 1.5, 0.75], rtol=1e-4)
    # Once per render in the log (an instanced object meets it per instance) and on the panels.
    assert summary["export_warnings"].count(metal[0]) == 1
    assert metal[0] in scene_notes.for_id(empty.name, "MATERIAL", "Glow")
    assert metal[0] in scene_notes.for_id(empty.name, "OBJECT", "Lamp")


@pytest.mark.parametrize("build, expected", [
    ("glass", "Glass BSDF"),
    ("mix", "is rendered alone"),
    ("volume", "volume shader"),
    ("normal_map", "Normal from"),
    ("noise", "Noise Texture"),
    ("between", "are not applied"),
])
def test_unsupported_shader_nodes_are_named_with_what_is_rendered(empty, build, expected):
    add_camera()
    obj = add_plane("Rock")
    mat, bsdf = node_material("Stone")
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    if build == "glass":
        glass = tree.nodes.new("ShaderNodeBsdfGlass")
        tree.links.new(glass.outputs[0], out.inputs["Surface"])
    elif build == "mix":
        mix = tree.nodes.new("ShaderNodeMixShader")
        glossy = tree.nodes.new("ShaderNodeBsdfGlossy" if hasattr(bpy.types, "ShaderNodeBsdfGlossy")
                                else "ShaderNodeBsdfAnisotropic")
        tree.links.new(bsdf.outputs[0], mix.inputs[1])
        tree.links.new(glossy.outputs[0], mix.inputs[2])
        tree.links.new(mix.outputs[0], out.inputs["Surface"])
    elif build == "volume":
        vol = tree.nodes.new("ShaderNodeVolumePrincipled")
        tree.links.new(vol.outputs[0], out.inputs["Volume"])
    elif build == "normal_map":
        nm = tree.nodes.new("ShaderNodeNormalMap")
        tree.links.new(nm.outputs[0], bsdf.inputs["Normal"])
    elif build == "noise":
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Color"], bsdf.inputs["Base Color"])
    elif build == "between":
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = checker_image()
        hue = tree.nodes.new("ShaderNodeHueSaturation")
        tree.links.new(tex.outputs["Color"], hue.inputs["Color"])
        tree.links.new(hue.outputs["Color"], bsdf.inputs["Base Color"])
    obj.data.materials.append(mat)
    scene, info = export_current()
    notes = [w for w in info.warnings if expected in w]
    assert notes and all("Material 'Stone'" in w for w in notes), info.warnings
    if build == "between":  # the image is still rendered
        assert scene.materials["Stone"].texture is not None


def test_a_point_lamp_is_named_on_its_panel(empty):
    add_camera()
    add_plane("Floor")
    lamp = bpy.data.objects.new("Bulb", bpy.data.lights.new("Bulb", "POINT"))
    empty.collection.objects.link(lamp)
    render()
    notes = scene_notes.for_id(empty.name, "LIGHT", "Bulb")
    assert notes and "point lights are not used" in notes[0]


# ------------------------------------------------------------------------------------------
# 3. The World: Environment Texture, Sky Texture
# ------------------------------------------------------------------------------------------

def environment_world(image, rotation_z=0.0):
    world = uniform_world()
    tree = world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    if rotation_z:
        tc = tree.nodes.new("ShaderNodeTexCoord")
        mp = tree.nodes.new("ShaderNodeMapping")
        mp.inputs["Rotation"].default_value = (0, 0, rotation_z)
        tree.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
        tree.links.new(mp.outputs["Vector"], env.inputs["Vector"])
    return world


def compass_image():
    """A float equirectangular image (bottom row first): the upper half grey 0.1 with a red
    patch towards +x (u = 0.5) at the horizon and a blue one towards +y (u = 0.25); the
    zenith rows 2.0."""
    w, h = 64, 32
    px = np.zeros((h, w, 4), np.float32)
    px[..., 3] = 1
    px[16:, :, :3] = 0.1
    px[16:20, 30:34, :3] = (5.0, 0.0, 0.0)   # +x, just above the horizon
    px[16:20, 14:18, :3] = (0.0, 0.0, 5.0)   # +y
    px[30:, :, :3] = 2.0                     # around the zenith
    img = bpy.data.images.new("Compass", w, h, alpha=False, float_buffer=True)
    img.pixels.foreach_set(px.ravel())
    return img


def radiance_meter(name, direction, half_angle_deg=3.0):
    obj = bpy.data.objects.new(name, None)
    d = np.asarray(direction, float)
    # the radiometer looks along its -Z axis
    obj.rotation_mode = "QUATERNION"
    from mathutils import Vector
    obj.rotation_quaternion = Vector((-d[0], -d[1], -d[2])).to_track_quat("Z", "Y")
    obj.photic.role, obj.photic.quantity = "RADIOMETER", "radiance"
    obj.photic.half_angle = math.radians(half_angle_deg)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def test_environment_texture_is_the_sky_in_both_integrators(empty):
    environment_world(compass_image())
    add_camera(location=(0, 0, 0), rotation=(math.radians(90), 0, 0))
    empty.photic.radiometer_samples = 20000
    radiance_meter("East", (1, 0, 0.06))
    radiance_meter("North", (0, 1, 0.06))
    radiance_meter("Up", (0, 0, 1))
    scene, info = export_current()
    assert scene.sky.type == "environment" and scene.sky.table.shape[2] == 3
    assert any("lower half" in w for w in info.warnings)  # (no sea hides it)
    got = {}
    for integrator in ("PATH", "HYBRID"):
        empty.photic.integrator = integrator
        render()
        rows = {r["name"]: r["value"] for r in final_render.LAST_RADIOMETERS[empty.name]["rows"]}
        got[integrator] = rows
        assert rows["East"][0] > 3.0 and rows["East"][2] < 0.2, rows   # red towards +x
        assert rows["North"][2] > 3.0 and rows["North"][0] < 0.2, rows  # blue towards +y
        assert rows["Up"] == pytest.approx([2.0, 2.0, 2.0], rel=0.02)
    # Turned 90 degrees about Z by a Mapping node: the red patch is now towards -y? The lookup
    # direction is R d, so the sky at d shows the image at d turned by +90: +x shows +y's blue.
    environment_world(compass_image(), rotation_z=math.radians(90))
    empty.photic.integrator = "PATH"
    render()
    rows = {r["name"]: r["value"] for r in final_render.LAST_RADIOMETERS[empty.name]["rows"]}
    assert rows["East"][2] > 3.0, rows


def test_sky_texture_is_approximated_and_says_so(empty):
    world = uniform_world()
    tree = world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    sky = tree.nodes.new("ShaderNodeTexSky")
    tree.links.new(sky.outputs["Color"], bg.inputs["Color"])
    add_camera()
    scene, info = export_current()
    assert scene.sky.type == "environment"
    note = next(w for w in info.warnings if "Sky Texture" in w)
    assert "approximated" in note and "World 'World'" in note and "Harrison" in note
    # its horizontal irradiance is pi L0 (L0 = World > Photic Sky > Radiance L0 x Strength)
    from photic.sky import horizontal_irradiance
    assert horizontal_irradiance(scene.sky.table[:, :, 0]) == pytest.approx(math.pi, rel=1e-3)
    np.testing.assert_allclose(scene.sky.radiance_scale, world.photic.radiance, rtol=1e-6)


def test_other_world_nodes_are_named(empty):
    world = uniform_world(colour=(0.2, 0.3, 0.4))
    tree = world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    grad = tree.nodes.new("ShaderNodeTexGradient")
    tree.links.new(grad.outputs["Color"], bg.inputs["Color"])
    add_camera()
    scene, info = export_current()
    assert scene.sky.type == "uniform"
    assert any("Gradient Texture" in w and "World 'World'" in w for w in info.warnings), info.warnings


@pytest.mark.parametrize("mode, setting", [("AUTO", "auto"), ("ON", True), ("OFF", False)])
def test_raman_is_auto_by_default_and_its_setting_goes_out_and_back(empty, mode, setting):
    from photic_blender.importer import import_scene
    add_camera()
    add_sun()
    p = empty.photic
    assert p.raman == "AUTO"
    p.raman = mode
    scene, _ = export_current()
    assert type(scene.settings.raman) is type(setting) and scene.settings.raman == setting
    other = bpy.data.scenes.new("Imported")
    import_scene(scene, other)
    assert other.photic.raman == mode


# (the default RGB bands, one band, and two red bands whose excitation lies outside them)
@pytest.mark.parametrize("bands", [{}, {"bands": "SINGLE"},
                                   {"bands": "CUSTOM", "custom_bands": "600:20, 650:20"}])
@pytest.mark.parametrize("mode", ["AUTO", "ON", "OFF"])
def test_the_raman_pass_is_declared_exactly_when_the_engine_renders_raman_light(empty, mode, bands):
    from photic.inelastic import raman_active, raman_auto
    from photic.render import render as engine_render
    add_camera()
    add_sun()
    p = empty.photic
    for k, v in bands.items():
        setattr(p, k, v)
    p.raman = mode
    scene, _ = export_current()
    declared = final_render.RAMAN_PASS in [n for n, _, _ in final_render.render_passes(empty)]
    expected = raman_auto(scene.bands) if mode == "AUTO" else mode == "ON"
    assert declared == expected == raman_active(scene)
    # F12 fills the declared pass with the engine's raman component of the pixels, and the
    # engine gives that component exactly then.
    scene.cameras[0].resolution = (4, 3)
    img = next(iter(engine_render(scene, samples=2, threads=1).images.values()))
    assert ("raman" in img.components) == declared
    bands = [(b.name, b.center_nm, b.width_nm) for b in scene.bands]
    assert (final_render.RAMAN_PASS in final_render.image_passes(img, bands)) == declared


def test_a_blend_saved_with_the_raman_checkbox_keeps_its_choice(empty):
    # (the checkbox stored its value as an integer ID property; one never set stored nothing
    # and reads as the default, Auto)
    p = empty.photic
    for stored, mode in ((1, "ON"), (0, "OFF")):
        p["raman"] = stored
        assert p.raman == mode
