"""Tests of the scene format: loading, round trips, the Python API and the validation errors."""

import copy
import json
import math
import pickle
from importlib import resources

import numpy as np
import pytest
import trimesh

from photic.scene import (
    Band, Camera, IOPs, Material, MeshObject, OceanSurface, PhaseFunction, Radiometer,
    RadiometerArray, ScatteringComponent, Scene, SceneError, Settings, Sky, Sun, TriangleMesh,
    WaterBody, load_scene, save_scene,
)

# A closed unit cube with outward normals, and a single triangle.
_BOX = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
BOX_VERTICES = (_BOX.vertices + [5.0, 0.0, -3.0]).tolist()
BOX_TRIANGLES = _BOX.faces.tolist()
ROCK_VERTICES = [[0.0, 0.0, -20.0], [1.0, 0.0, -20.0], [0.0, 1.0, -19.5]]
ROCK_TRIANGLES = [[0, 1, 2]]


def patch_surface(period=(2.0, 2.0), heights=(0.1, -0.1, 0.0, 0.2)):
    """A height-field patch of two upward-facing triangles over [0, Lx] x [0, Ly]."""
    lx, ly = period
    z0, z1, z2, z3 = heights
    return {"kind": "patch",
            "vertices": [[0, 0, z0], [lx, 0, z1], [lx, ly, z2], [0, ly, z3]],
            "triangles": [[0, 1, 2], [0, 2, 3]],
            "period": [lx, ly]}


def valid_dict():
    """A valid scene using every kind of object (2 bands); a fresh deep copy every call."""
    return copy.deepcopy({
        "photic_scene": 1,
        "name": "test",
        "bands": [{"name": "blue", "center_nm": 450, "width_nm": 20},
                  {"name": "green", "center_nm": 550, "width_nm": 20}],
        "materials": {"sand": {"type": "lambertian", "reflectance": [0.2, 0.3]},
                      "black": {"type": "lambertian", "reflectance": 0.0}},
        "meshes": [{"name": "rock", "material": "sand",
                    "vertices": ROCK_VERTICES, "triangles": ROCK_TRIANGLES}],
        "water": [
            {"name": "sea", "type": "ocean", "ior": 1.34,
             "iops": {"absorption": [0.1, 0.05],
                      "scattering": [
                          {"b": [0.2, 0.1], "phase": {"type": "petzold"}},
                          {"b": 0.01, "phase": {"type": "pure_water"}},
                          {"b": [0.0, 0.3], "phase": {"type": "henyey_greenstein", "g": 0.9}},
                          {"b": 0.05, "phase": {"type": "fournier_forand",
                                                "backscatter_fraction": 0.0183}}]},
             "surface": {"kind": "flat", "z": 0.0},
             "bottom": {"depth": 30.0, "material": "sand"}},
            {"name": "tank", "type": "mesh",
             "iops": {"absorption": 0.5, "b": [1.0, 2.0], "phase": {"type": "isotropic"}},
             "vertices": BOX_VERTICES, "triangles": BOX_TRIANGLES},
        ],
        "sun": {"zenith_deg": 30.0, "azimuth_deg": 90.0, "irradiance": [1.5, 1.8]},
        "sky": {"type": "uniform", "irradiance": [0.3, 0.2]},
        "cameras": [{"name": "cam", "type": "perspective", "position": [0, 0, 5],
                     "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 60,
                     "resolution": [32, 16], "filter": {"type": "gaussian"}}],
        "radiometers": [{"name": "Ed_1m", "quantity": "Ed", "position": [0, 0, -1]},
                        {"name": "Lu_1m", "quantity": "radiance", "position": [0, 0, -1],
                         "half_angle_deg": 25.8}],
        "radiometer_arrays": [{"name": "profile", "quantities": ["Ed", "Eu"],
                               "line": {"start": [0, 0, -1], "stop": [0, 0, -10],
                                        "count": 10}}],
        "settings": {"integrator": "path", "samples": 8, "radiometer_samples": 10000,
                     "seed": 7, "max_depth": 100, "threads": 2},
    })


def python_scene():
    """The scene of ``valid_dict`` built with the Python API."""
    nb = 2
    return Scene(
        name="test",
        bands=[Band("blue", 450.0, 20.0), Band("green", 550.0, 20.0)],
        materials={"sand": Material("sand", np.array([0.2, 0.3])),
                   "black": Material("black", np.zeros(nb))},
        meshes=[MeshObject("rock", TriangleMesh(np.array(ROCK_VERTICES),
                                                np.array(ROCK_TRIANGLES)), "sand")],
        water=[
            WaterBody("sea", "ocean", IOPs(np.array([0.1, 0.05]), [
                ScatteringComponent(np.array([0.2, 0.1]), PhaseFunction("petzold", {})),
                ScatteringComponent(np.full(nb, 0.01), PhaseFunction("pure_water", {})),
                ScatteringComponent(np.array([0.0, 0.3]),
                                    PhaseFunction("henyey_greenstein", {"g": 0.9})),
                ScatteringComponent(np.full(nb, 0.05), PhaseFunction(
                    "fournier_forand", {"backscatter_fraction": 0.0183}))]),
                surface=OceanSurface("flat", 0.0), bottom_depth=30.0, bottom_material="sand"),
            WaterBody("tank", "mesh", IOPs(np.full(nb, 0.5), [
                ScatteringComponent(np.array([1.0, 2.0]), PhaseFunction("isotropic", {}))]),
                mesh=TriangleMesh(np.array(BOX_VERTICES), np.array(BOX_TRIANGLES))),
        ],
        sun=Sun(30.0, 90.0, np.array([1.5, 1.8])),
        sky=Sky("uniform", np.array([0.3, 0.2]) / np.pi),
        cameras=[Camera("cam", "perspective", np.array([0.0, 0.0, 5.0]),
                        np.array([0.0, 0.0, -1.0]), up=np.array([0.0, 1.0, 0.0]), fov_deg=60.0,
                        resolution=(32, 16), filter_type="gaussian", filter_width_px=1.5)],
        radiometers=[Radiometer("Ed_1m", "Ed", np.array([0.0, 0.0, -1.0])),
                     Radiometer("Lu_1m", "radiance", np.array([0.0, 0.0, -1.0]),
                                half_angle_deg=25.8)],
        radiometer_arrays=[RadiometerArray("profile", ["Ed", "Eu"],
                                           np.linspace([0, 0, -1], [0, 0, -10], 10))],
        settings=Settings("path", 8, 10000, 7, 100, 2),
    )


# --------------------------------------------------------------------------------------
# Valid scenes
# --------------------------------------------------------------------------------------

def test_valid_scene_round_trips():
    scene = Scene.from_dict(valid_dict())
    d = scene.to_dict()
    json.dumps(d, allow_nan=False)  # JSON-serialisable as it is
    again = Scene.from_dict(json.loads(json.dumps(d)))
    assert again == scene
    assert again.to_dict() == d


def test_python_api_builds_the_same_scene_as_json():
    built = python_scene()
    built.validate()
    assert built == Scene.from_dict(valid_dict())


def test_equality_notices_differences():
    a, b = python_scene(), python_scene()
    b.water[0].iops.absorption[1] = 0.06
    assert a != b


def test_save_and_load_file(tmp_path):
    scene = Scene.from_dict(valid_dict())
    path = tmp_path / "scene.json"
    save_scene(scene, path)
    assert load_scene(path) == scene


def test_single_numbers_are_broadcast_to_all_bands():
    d = valid_dict()
    d["water"][0]["iops"]["absorption"] = 0.25
    d["sun"]["irradiance"] = 2.0
    scene = Scene.from_dict(d)
    sea, tank = scene.water
    np.testing.assert_array_equal(sea.iops.absorption, [0.25, 0.25])
    np.testing.assert_array_equal(sea.iops.scattering[1].b, [0.01, 0.01])
    np.testing.assert_array_equal(tank.iops.absorption, [0.5, 0.5])
    np.testing.assert_array_equal(scene.materials["black"].reflectance, [0.0, 0.0])
    np.testing.assert_array_equal(scene.sun.irradiance, [2.0, 2.0])
    for array in (sea.iops.absorption, scene.sun.irradiance, tank.iops.scattering[0].b):
        assert array.dtype == np.float64 and array.shape == (2,)


def test_iops_shorthand_and_total_scattering():
    scene = Scene.from_dict(valid_dict())
    sea, tank = scene.water
    assert len(tank.iops.scattering) == 1
    assert tank.iops.scattering[0].phase == PhaseFunction("isotropic", {})
    np.testing.assert_allclose(sea.iops.total_scattering, [0.26, 0.46])


def test_radiometer_array_expansion():
    scene = Scene.from_dict(valid_dict())
    expanded = scene.radiometer_arrays[0].radiometers()
    assert len(expanded) == 20
    assert [r.name for r in expanded[:3]] == ["profile[0].Ed", "profile[0].Eu", "profile[1].Ed"]
    assert expanded[-1].name == "profile[9].Eu"
    np.testing.assert_allclose(expanded[-1].position, [0, 0, -10])
    np.testing.assert_allclose(expanded[2].position, [0, 0, -2])
    np.testing.assert_array_equal(expanded[0].direction, [0, 0, -1])
    assert expanded[0].half_angle_deg == 12.9
    names = [r.name for r in scene.all_radiometers()]
    assert names[:2] == ["Ed_1m", "Lu_1m"] and len(names) == 22


def test_radiometer_array_positions_direction_and_half_angle():
    d = valid_dict()
    d["radiometer_arrays"] = [{"name": "grid", "quantities": ["radiance"],
                               "positions": [[0, 0, -1], [1, 0, -1]],
                               "direction": [0, 0, 2], "half_angle_deg": 5.0},
                              {"name": "line", "quantities": ["Eo"],
                               "positions": {"start": [0, 0, -3], "stop": [0, 0, -4],
                                             "count": 1}}]
    scene = Scene.from_dict(d)
    grid, line = (a.radiometers() for a in scene.radiometer_arrays)
    assert [r.name for r in grid] == ["grid[0].radiance", "grid[1].radiance"]
    np.testing.assert_array_equal(grid[1].direction, [0, 0, 1])  # normalised
    assert grid[1].half_angle_deg == 5.0
    assert [r.name for r in line] == ["line[0].Eo"]
    np.testing.assert_array_equal(line[0].position, [0, 0, -3])


def test_defaults():
    scene = Scene.from_dict({"photic_scene": 1, "radiometers": [
        {"name": "Ed", "quantity": "Ed", "position": [0, 0, -1]}]})
    assert scene.name == "scene"
    assert scene.bands == [Band("550", 550.0, 10.0)]
    assert scene.sun is None and scene.sky == Sky("black") and scene.sky.radiance_scale is None
    assert scene.settings == Settings()
    assert scene.materials == {} and scene.water == [] and scene.cameras == []
    assert Scene().bands == [Band("550", 550.0, 10.0)]


def test_camera_defaults_and_direction():
    d = valid_dict()
    d["cameras"] = [{"name": "c", "type": "orthographic", "position": [1, 2, 3],
                     "direction": [0, 3, 4]}]
    camera = Scene.from_dict(d).cameras[0]
    np.testing.assert_allclose(camera.direction, [0, 0.6, 0.8])
    np.testing.assert_array_equal(camera.up, [0, 0, 1])
    assert (camera.fov_deg, camera.ortho_width, camera.resolution) == (40.0, 2.0, (64, 64))
    assert (camera.filter_type, camera.filter_width_px) == ("box", 1.0)


def test_sun_direction_points_towards_the_sun():
    sun = Sun(60.0, 90.0, np.ones(1))
    np.testing.assert_allclose(sun.direction, [0, math.sin(math.radians(60)), 0.5], atol=1e-15)
    np.testing.assert_allclose(Sun(0.0, 0.0, np.ones(1)).direction, [0, 0, 1])


def test_sky_radiance_scale():
    d = valid_dict()
    np.testing.assert_allclose(Scene.from_dict(d).sky.radiance_scale,
                               np.array([0.3, 0.2]) / np.pi)
    d["sky"] = {"type": "cardioidal", "irradiance": 7.0}
    scene = Scene.from_dict(d)
    np.testing.assert_allclose(scene.sky.radiance_scale, [3 / np.pi] * 2)
    assert Scene.from_dict(scene.to_dict()) == scene
    d["sky"] = {"type": "uniform", "radiance": [1.0, 2.0]}
    np.testing.assert_array_equal(Scene.from_dict(d).sky.radiance_scale, [1.0, 2.0])


def test_ocean_patch_surface():
    d = valid_dict()
    d["water"][0]["surface"] = patch_surface()
    scene = Scene.from_dict(d)
    surface = scene.water[0].surface
    assert surface.kind == "patch" and surface.period == (2.0, 2.0)
    assert surface.z == pytest.approx(0.05)  # mean height of the vertices
    assert Scene.from_dict(scene.to_dict()) == scene


def test_hybrid_integrator_is_accepted():
    d = valid_dict()
    d["settings"]["integrator"] = "hybrid"
    assert Scene.from_dict(d).settings.integrator == "hybrid"


def test_radiometer_samples_may_be_written_as_float():
    d = valid_dict()
    d["settings"]["radiometer_samples"] = 1e10
    settings = Scene.from_dict(d).settings
    assert settings.radiometer_samples == 10**10 and isinstance(settings.radiometer_samples, int)


@pytest.mark.parametrize("suffix", ["stl", "obj", "ply"])
def test_mesh_file_relative_to_scene_file_with_transform(tmp_path, suffix):
    (tmp_path / "meshes").mkdir()
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(tmp_path / "meshes" / f"box.{suffix}")
    d = valid_dict()
    tank = d["water"][1]
    del tank["vertices"], tank["triangles"]
    tank["file"] = f"meshes/box.{suffix}"
    tank["transform"] = [[2, 0, 0, 10], [0, 1, 0, 0], [0, 0, 1, -5], [0, 0, 0, 1]]
    (tmp_path / "scene.json").write_text(json.dumps(d))
    mesh = load_scene(tmp_path / "scene.json").water[1].mesh
    assert mesh.vertices.dtype == np.float64 and mesh.triangles.dtype == np.int64
    np.testing.assert_allclose(mesh.vertices.min(axis=0), [9, -0.5, -5.5])
    np.testing.assert_allclose(mesh.vertices.max(axis=0), [11, 0.5, -4.5])


def test_mirroring_transform_keeps_normals_outward():
    d = valid_dict()
    d["water"][1]["transform"] = [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    mesh = Scene.from_dict(d).water[1].mesh
    assert trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False).volume > 0


def test_scene_error_message_and_pickling():
    error = SceneError("water 'sea'", "iops.absorption[0]",
                       "must be a finite number >= 0, got -0.1")
    assert isinstance(error, ValueError)
    assert (error.obj, error.field) == ("water 'sea'", "iops.absorption[0]")
    assert str(error) == ("water 'sea': field 'iops.absorption[0]': must be a finite number "
                          ">= 0, got -0.1")
    assert str(pickle.loads(pickle.dumps(error))) == str(error)


def test_error_message_of_the_format_specification():
    d = valid_dict()
    d["water"][0]["iops"]["absorption"] = [-0.1, 0.05]
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d)
    assert str(info.value) == ("water 'sea': field 'iops.absorption[0]': must be a finite "
                               "number >= 0, got -0.1")


@pytest.mark.parametrize("field, value, text", [
    ("raman", "yes", "must be true/false, or 'auto', got 'yes'"),
    ("target_error", "1%", "must be a finite number in (0, 1), or null, got '1%'"),
    ("forward_cone_deg", "wide", "must be a finite number in [0, 30], or 'auto', got 'wide'"),
])
def test_settings_with_alternatives_say_what_they_accept(field, value, text):
    """A value none of a field's alternatives accepts (oneOf) is answered with the list of
    them, not the schema library's 'is not valid under any of the given schemas'."""
    d = valid_dict()
    d["settings"][field] = value
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d)
    assert info.value.field == field and info.value.message == text, str(info.value)


def _walk_properties(schema, node, where):
    """Yield (where, property schema) for every property in the schema, following $ref."""
    if isinstance(node, dict):
        for name, prop in node.get("properties", {}).items():
            target = prop
            if "$ref" in prop and "description" not in prop:
                target = schema["$defs"][prop["$ref"].split("/")[-1]]
            yield f"{where}.{name}", target
        for key, value in node.items():
            if key != "if":  # conditions name properties without defining them
                yield from _walk_properties(schema, value, f"{where}.{key}")
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _walk_properties(schema, value, f"{where}[{i}]")


def test_schema_is_valid_and_describes_every_property():
    import jsonschema

    text = resources.files("photic.schema").joinpath("scene.schema.json").read_text("utf-8")
    schema = json.loads(text)
    jsonschema.Draft202012Validator.check_schema(schema)
    props = list(_walk_properties(schema, schema, "#"))
    assert len(props) > 60
    missing = [where for where, prop in props if not prop.get("description")]
    assert not missing, missing
    jsonschema.validate(Scene.from_dict(valid_dict()).to_dict(), schema)


def test_petzold_data_is_packaged():
    text = resources.files("photic").joinpath(
        "data/petzold_average_particle_phase_function.csv").read_text("utf-8")
    lines = text.splitlines()
    assert lines[0].startswith("# Petzold \"average-particle\" phase function")
    rows = [line for line in lines if line and not line.startswith(("#", "psi"))]
    assert len(rows) == 55


# --------------------------------------------------------------------------------------
# Invalid scenes: each must raise SceneError naming the object and the field
# --------------------------------------------------------------------------------------

def _set(path, value):
    """A mutation setting the item at a dotted path ("water.0.ior") to ``value``."""
    def mutate(d):
        *head, last = path.split(".")
        node = d
        for key in head:
            node = node[int(key)] if isinstance(node, list) else node[key]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
    return mutate


def _delete(path):
    def mutate(d):
        *head, last = path.split(".")
        node = d
        for key in head:
            node = node[int(key)] if isinstance(node, list) else node[key]
        del node[int(last) if isinstance(node, list) else last]
    return mutate


def _both(*mutations):
    def mutate(d):
        for m in mutations:
            m(d)
    return mutate


def _append(path, value):
    def mutate(d):
        node = d
        for key in path.split("."):
            node = node[int(key)] if isinstance(node, list) else node[key]
        node.append(copy.deepcopy(value))
    return mutate


_OCEAN2 = {"name": "sea2", "type": "ocean", "iops": {"absorption": 0.1},
           "surface": {"kind": "flat"}}
_INWARD = [t[::-1] for t in BOX_TRIANGLES]

BAD_INPUTS = [
    # (mutation, object named in the message, field named in the message)
    pytest.param(_set("photic_scene", 2), "scene", "photic_scene", id="version-2"),
    pytest.param(_delete("photic_scene"), "scene", "photic_scene", id="version-missing"),
    pytest.param(_set("water.0.iops.absorption.0", -0.1), "water 'sea'", "iops.absorption[0]",
                 id="absorption-negative"),
    pytest.param(_set("water.0.iops.absorption.1", math.nan), "water 'sea'",
                 "iops.absorption[1]", id="absorption-nan"),
    pytest.param(_set("water.0.iops.scattering.0.b.1", math.inf), "water 'sea'",
                 "iops.scattering[0].b[1]", id="b-inf"),
    pytest.param(_set("water.1.iops.b", -1.0), "water 'tank'", "iops.b", id="b-negative"),
    pytest.param(_set("water.0.iops.absorption", [0.1]), "water 'sea'", "iops.absorption",
                 id="per-band-list-too-short"),
    pytest.param(_set("sun.irradiance", [1, 2, 3]), "sun", "irradiance",
                 id="per-band-list-too-long"),
    pytest.param(_set("water.0.iops.scattering.0.phase.type", "rayleigh"), "water 'sea'",
                 "phase.type", id="phase-unknown"),
    pytest.param(_set("water.0.iops.scattering.2.phase.g", 1.0), "water 'sea'", "phase.g",
                 id="hg-g-1"),
    pytest.param(_set("water.0.iops.scattering.2.phase.g", -1.5), "water 'sea'", "phase.g",
                 id="hg-g-below-minus-1"),
    pytest.param(_delete("water.0.iops.scattering.2.phase.g"), "water 'sea'", "phase.g",
                 id="hg-g-missing"),
    pytest.param(_set("water.0.iops.scattering.0.phase.g", 0.5), "water 'sea'", "phase.g",
                 id="petzold-with-g"),
    pytest.param(_set("water.0.iops.scattering.3.phase.backscatter_fraction", 0.2),
                 "water 'sea'", "backscatter_fraction", id="ff-bb-too-large"),
    pytest.param(_set("water.0.iops.scattering.3.phase.backscatter_fraction", 1e-5),
                 "water 'sea'", "backscatter_fraction", id="ff-bb-too-small"),
    pytest.param(_set("sun.zenith_deg", 95.0), "sun", "zenith_deg", id="sun-below-horizon"),
    pytest.param(_set("sun.zenith_deg", 90.0), "sun", "zenith_deg", id="sun-on-horizon"),
    pytest.param(_set("sun.irradiance", [-1.0, 1.0]), "sun", "irradiance[0]",
                 id="sun-irradiance-negative"),
    pytest.param(_set("sun.angular_diameter_deg", 0.0), "sun", "angular_diameter_deg",
                 id="sun-diameter-zero"),
    pytest.param(_set("sun.angular_diameter_deg", 25.0), "sun", "angular_diameter_deg",
                 id="sun-diameter-too-large"),
    pytest.param(_set("water.1.triangles", BOX_TRIANGLES[:-1]), "water 'tank'", "triangles",
                 id="water-mesh-open"),
    pytest.param(_set("water.1.triangles", _INWARD), "water 'tank'", "triangles",
                 id="water-mesh-inward"),
    pytest.param(_set("water.1.triangles", _INWARD[:1] + BOX_TRIANGLES[1:]), "water 'tank'",
                 "triangles", id="water-mesh-inconsistent-winding"),
    pytest.param(_both(_set("meshes.0.vertices", ROCK_VERTICES + [[2.0, 0.0, -20.0]]),
                       _set("meshes.0.triangles", [[0, 1, 2], [0, 1, 3]])),
                 "mesh 'rock'", "triangles[1]", id="zero-area-triangle"),
    pytest.param(_set("meshes.0.triangles", [[0, 1, 3]]), "mesh 'rock'", "triangles[0]",
                 id="index-out-of-range"),
    pytest.param(_set("meshes.0.triangles", [[0, 1, -1]]), "mesh 'rock'", "triangles[0][2]",
                 id="index-negative"),
    pytest.param(_set("meshes.0.vertices.1", [1.0, math.nan, 0.0]), "mesh 'rock'",
                 "vertices[1]", id="vertex-nan"),
    pytest.param(_set("meshes.0.triangles", []), "mesh 'rock'", "triangles", id="mesh-empty"),
    pytest.param(_set("meshes.0.triangles", [[0, 1, 1.5]]), "mesh 'rock'", "triangles[0][2]",
                 id="index-fractional"),
    pytest.param(_set("water.1.vertices.3", [1, True, 0]), "water 'tank'", "vertices[3][1]",
                 id="vertex-bool"),
    pytest.param(_both(_delete("meshes.0.vertices"), _delete("meshes.0.triangles")),
                 "mesh 'rock'", "vertices", id="mesh-without-geometry"),
    pytest.param(_delete("meshes.0.triangles"), "mesh 'rock'", "triangles",
                 id="mesh-vertices-without-triangles"),
    pytest.param(_set("meshes.0.file", "missing.ply"), "mesh 'rock'", "file",
                 id="mesh-file-and-vertices"),
    pytest.param(_both(_delete("meshes.0.vertices"), _delete("meshes.0.triangles"),
                       _set("meshes.0.file", "no/such/file.ply")),
                 "mesh 'rock'", "file", id="mesh-file-not-found"),
    pytest.param(_set("meshes.0.transform", [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0],
                                             [0, 0, 1, 1]]),
                 "mesh 'rock'", "transform", id="transform-not-affine"),
    pytest.param(_both(_set("cameras", []), _set("radiometers", []),
                       _set("radiometer_arrays", [])), "scene", "cameras", id="no-sensor"),
    pytest.param(_set("settings.samples", 0), "settings", "samples", id="samples-0"),
    pytest.param(_set("settings.samples", 2_000_000), "settings", "samples",
                 id="samples-too-many"),
    pytest.param(_set("settings.radiometer_samples", 10**11), "settings", "radiometer_samples",
                 id="radiometer-samples-too-many"),
    pytest.param(_set("settings.max_depth", 0), "settings", "max_depth", id="max-depth-0"),
    pytest.param(_set("settings.max_depth", 10**6), "settings", "max_depth",
                 id="max-depth-too-large"),
    pytest.param(_set("settings.threads", 2000), "settings", "threads", id="threads-too-many"),
    pytest.param(_set("settings.seed", -1), "settings", "seed", id="seed-negative"),
    pytest.param(_set("settings.samples", 1.5), "settings", "samples", id="samples-fractional"),
    pytest.param(_set("settings.integrator", "bdpt"), "settings", "integrator",
                 id="integrator-unknown"),
    pytest.param(_set("meshes.0.material", "granite"), "mesh 'rock'", "material",
                 id="mesh-material-unknown"),
    pytest.param(_set("water.0.bottom.material", "mud"), "water 'sea'", "bottom_material",
                 id="bottom-material-unknown"),
    pytest.param(_set("materials.sand.reflectance", [1.5, 0.3]), "material 'sand'",
                 "reflectance[0]", id="reflectance-above-1"),
    pytest.param(_set("materials.sand.reflectance", -0.1), "material 'sand'", "reflectance",
                 id="reflectance-negative"),
    pytest.param(_set("materials.sand.type", "mirror"), "material 'sand'", "type",
                 id="material-type-unknown"),
    pytest.param(_set("water.0.ior", 0.9), "water 'sea'", "ior", id="ior-below-1"),
    pytest.param(_set("water.0.ior", math.nan), "water 'sea'", "ior", id="ior-nan"),
    pytest.param(_set("cameras.0.resolution", [0, 16]), "camera 'cam'", "resolution[0]",
                 id="resolution-0"),
    pytest.param(_set("cameras.0.resolution", [32, 20000]), "camera 'cam'", "resolution[1]",
                 id="resolution-too-large"),
    pytest.param(_set("cameras.0.fov_deg", 180), "camera 'cam'", "fov_deg", id="fov-180"),
    pytest.param(_set("cameras.0.fov_deg", 0), "camera 'cam'", "fov_deg", id="fov-0"),
    pytest.param(_both(_delete("cameras.0.look_at"), _set("cameras.0.direction", [0, 0, 0])),
                 "camera 'cam'", "direction", id="camera-direction-zero"),
    pytest.param(_set("cameras.0.look_at", [0, 0, 5]), "camera 'cam'", "look_at",
                 id="camera-look-at-position"),
    pytest.param(_set("cameras.0.direction", [0, 0, -1]), "camera 'cam'", "direction",
                 id="camera-look-at-and-direction"),
    pytest.param(_set("cameras.0.up", [0, 0, 2]), "camera 'cam'", "up", id="camera-up-parallel"),
    pytest.param(_set("cameras.0.ortho_width", 0.0), "camera 'cam'", "ortho_width",
                 id="ortho-width-0"),
    pytest.param(_set("cameras.0.filter", {"type": "mitchell"}), "camera 'cam'", "filter.type",
                 id="filter-unknown"),
    pytest.param(_set("radiometers.0.quantity", "PAR"), "radiometer 'Ed_1m'", "quantity",
                 id="radiometer-quantity-unknown"),
    pytest.param(_set("radiometers.1.half_angle_deg", 0.0), "radiometer 'Lu_1m'",
                 "half_angle_deg", id="half-angle-0"),
    pytest.param(_set("radiometers.1.half_angle_deg", 91.0), "radiometer 'Lu_1m'",
                 "half_angle_deg", id="half-angle-91"),
    pytest.param(_set("radiometers.1.polar_bins", 0), "radiometer 'Lu_1m'", "polar_bins",
                 id="polar-bins-0"),
    pytest.param(_set("radiometers.1.azimuth_bins", -3), "radiometer 'Lu_1m'", "azimuth_bins",
                 id="azimuth-bins-negative"),
    pytest.param(_set("radiometers.1.direction", [0, 0, 0]), "radiometer 'Lu_1m'", "direction",
                 id="radiometer-direction-zero"),
    pytest.param(_set("radiometer_arrays.0.quantities", ["Ed", "Lw"]),
                 "radiometer_array 'profile'", "quantities[1]", id="array-quantity-unknown"),
    pytest.param(_set("radiometer_arrays.0.line.count", 0), "radiometer_array 'profile'",
                 "line.count", id="array-count-0"),
    pytest.param(_set("radiometer_arrays.0.positions", [[0, 0, 0]]),
                 "radiometer_array 'profile'", "positions", id="array-positions-and-line"),
    pytest.param(_set("bands.1.name", "blue"), "band 'blue'", "name", id="duplicate-band"),
    pytest.param(_append("meshes", {"name": "rock", "material": "sand",
                                    "vertices": ROCK_VERTICES, "triangles": ROCK_TRIANGLES}),
                 "mesh 'rock'", "name", id="duplicate-mesh"),
    pytest.param(_set("water.1.name", "sea"), "water 'sea'", "name", id="duplicate-water"),
    pytest.param(_append("cameras", {"name": "cam", "type": "orthographic",
                                     "position": [0, 0, 1], "direction": [0, 0, -1]}),
                 "camera 'cam'", "name", id="duplicate-camera"),
    pytest.param(_set("radiometers.1.name", "Ed_1m"), "radiometer 'Ed_1m'", "name",
                 id="duplicate-radiometer"),
    pytest.param(_set("radiometers.1.name", "profile[3].Eu"), "radiometer_array 'profile'",
                 "name", id="radiometer-clashes-with-array"),
    pytest.param(_append("water", _OCEAN2), "water 'sea2'", "type", id="two-oceans"),
    pytest.param(_set("water.0.bottom.depth", 0.0), "water 'sea'", "bottom.depth",
                 id="bottom-depth-0"),
    pytest.param(_set("water.0.bottom.depth", -5.0), "water 'sea'", "bottom.depth",
                 id="bottom-depth-negative"),
    pytest.param(_set("water.0.surface", {**patch_surface(), "period": [-2.0, 2.0]}),
                 "water 'sea'", "surface.period[0]", id="patch-period-negative"),
    pytest.param(_set("water.0.surface", {**patch_surface(), "period": [2.0, 0.0]}),
                 "water 'sea'", "surface.period[1]", id="patch-period-zero"),
    pytest.param(_set("water.0.surface", {**patch_surface(), "period": [3.0, 2.0]}),
                 "water 'sea'", "surface.period[0]", id="patch-period-not-extent"),
    pytest.param(_set("water.0.surface", {**patch_surface(), "triangles": [[0, 2, 1],
                                                                           [0, 3, 2]]}),
                 "water 'sea'", "surface.triangles[0]", id="patch-facing-down"),
    pytest.param(_set("water.0.surface", {"kind": "flat", "period": [1, 1]}), "water 'sea'",
                 "surface.period", id="flat-surface-with-period"),
    pytest.param(_delete("water.0.surface"), "water 'sea'", "surface", id="ocean-no-surface"),
    pytest.param(_set("water.1.surface", {"kind": "flat"}), "water 'tank'", "surface",
                 id="mesh-water-with-surface"),
    pytest.param(_set("camera", []), "scene", "camera", id="typo-top-level"),
    pytest.param(_set("radiometers.0.postion", [0, 0, -1]), "radiometer 'Ed_1m'", "postion",
                 id="typo-radiometer"),
    pytest.param(_set("settings.sample", 4), "settings", "sample", id="typo-settings"),
    pytest.param(_set("water.0.iops.absorbtion", 0.1), "water 'sea'", "absorbtion",
                 id="typo-iops"),
    pytest.param(_set("sky", {"type": "uniform", "radiance": [-0.1, 0.2]}), "sky", "radiance",
                 id="sky-negative-radiance"),
    pytest.param(_set("sky", {"type": "cardioidal", "irradiance": -1.0}), "sky", "irradiance",
                 id="sky-negative-irradiance"),
    pytest.param(_set("sky", {"type": "uniform", "radiance": 1.0, "irradiance": 1.0}), "sky",
                 "radiance", id="sky-radiance-and-irradiance"),
    pytest.param(_set("sky", {"type": "black", "radiance": 1.0}), "sky", "radiance",
                 id="black-sky-with-radiance"),
    pytest.param(_delete("water.0.name"), "water[0]", "name", id="water-name-missing"),
    pytest.param(_set("water.0.type", "lake"), "water 'sea'", "type", id="water-type-unknown"),
    pytest.param(_set("cameras.0.position", [0, 0]), "camera 'cam'", "position",
                 id="position-two-numbers"),
    pytest.param(_set("sun.zenith_deg", "high"), "sun", "zenith_deg", id="zenith-not-a-number"),
]


@pytest.mark.parametrize("mutate, obj, field", BAD_INPUTS)
def test_bad_input_is_rejected(mutate, obj, field):
    d = valid_dict()
    mutate(d)
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d)
    message = str(info.value)
    assert obj in message and field in message, message
    assert info.value.obj == obj and field in info.value.field, message


def test_number_of_bad_input_tests():
    assert len(BAD_INPUTS) >= 20


# The same kinds of checks on scenes built in Python (no JSON schema involved).

def _py_mutations():
    def set_attr(getter, attr, value):
        def mutate(s):
            setattr(getter(s), attr, value)
        return mutate

    sea = lambda s: s.water[0]  # noqa: E731
    return [
        pytest.param(set_attr(lambda s: s.water[0].iops, "absorption", np.array([-0.1, 0.1])),
                     "water 'sea'", "iops.absorption[0]", id="py-absorption-negative"),
        pytest.param(set_attr(lambda s: s.water[0].iops, "absorption", np.array([0.1])),
                     "water 'sea'", "iops.absorption", id="py-per-band-length"),
        pytest.param(set_attr(lambda s: s.water[0].iops.scattering[2].phase, "params",
                              {"g": 1.2}), "water 'sea'", "phase.g", id="py-hg-g"),
        pytest.param(set_attr(sea, "ior", float("nan")), "water 'sea'", "ior", id="py-ior-nan"),
        pytest.param(set_attr(sea, "bottom_depth", 0.0), "water 'sea'", "bottom_depth",
                     id="py-bottom-depth"),
        pytest.param(set_attr(lambda s: s.water[1], "mesh", TriangleMesh(
            np.array(BOX_VERTICES), np.array(_INWARD))), "water 'tank'", "triangles",
            id="py-inward-normals"),
        pytest.param(set_attr(lambda s: s.meshes[0].mesh, "triangles", np.array([[0, 1, 1]])),
                     "mesh 'rock'", "triangles[0]", id="py-degenerate"),
        pytest.param(set_attr(lambda s: s.sun, "zenith_deg", 120.0), "sun", "zenith_deg",
                     id="py-sun-below-horizon"),
        pytest.param(set_attr(lambda s: s.sky, "radiance_scale", np.array([-1.0, 0.0])), "sky",
                     "radiance_scale[0]", id="py-sky-negative"),
        pytest.param(set_attr(lambda s: s.cameras[0], "up", np.array([0.0, 0.0, 1.0])),
                     "camera 'cam'", "up", id="py-up-parallel"),
        pytest.param(set_attr(lambda s: s.cameras[0], "resolution", (0, 10)), "camera 'cam'",
                     "resolution[0]", id="py-resolution"),
        pytest.param(set_attr(lambda s: s.radiometers[0], "quantity", "Lw"),
                     "radiometer 'Ed_1m'", "quantity", id="py-quantity"),
        pytest.param(set_attr(lambda s: s.settings, "threads", -1), "settings", "threads",
                     id="py-threads"),
        pytest.param(set_attr(lambda s: s.settings, "samples", True), "settings", "samples",
                     id="py-samples-bool"),
        pytest.param(set_attr(lambda s: s.materials["sand"], "name", "dune"), "material 'sand'",
                     "name", id="py-material-key-mismatch"),
        pytest.param(set_attr(lambda s: s.water[0], "surface", OceanSurface(
            "patch", mesh=TriangleMesh(np.array(patch_surface()["vertices"], float),
                                       np.array(patch_surface()["triangles"])),
            period=(2.0, -2.0))), "water 'sea'", "surface.period[1]", id="py-patch-period"),
    ]


@pytest.mark.parametrize("mutate, obj, field", _py_mutations())
def test_bad_python_scene_is_rejected_by_validate(mutate, obj, field):
    scene = python_scene()
    mutate(scene)
    with pytest.raises(SceneError) as info:
        scene.validate()
    message = str(info.value)
    assert obj in message and field in message, message
    assert info.value.obj == obj and field in info.value.field, message


@pytest.mark.parametrize("content", ["this is not a mesh\n", ""], ids=["garbage", "empty"])
def test_unreadable_mesh_file(tmp_path, content):
    (tmp_path / "rock.ply").write_text(content)
    d = valid_dict()
    rock = d["meshes"][0]
    del rock["vertices"], rock["triangles"]
    rock["file"] = "rock.ply"
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d, base_dir=tmp_path)
    assert info.value.obj == "mesh 'rock'" and info.value.field == "file", str(info.value)


def test_invalid_json_file(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"photic_scene": 1,, }')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.obj == "scene" and str(path) in str(info.value)
    assert "line 1" in str(info.value)


def test_missing_scene_file(tmp_path):
    with pytest.raises(SceneError) as info:
        load_scene(tmp_path / "nope.json")
    assert "nope.json" in str(info.value)
