"""Fuzzing the other inputs (issue 49): ``photic batch`` job files with one to three values
replaced by anything JSON holds load or fail with a JobError, never another exception; and a
Blender scene whose objects' transforms and Photic properties are set to extreme or
non-numbers exports or fails with an ExportError or SceneError naming the object, never
another exception."""
from __future__ import annotations

import copy
import json
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photic.distributed import JobError, load_job

from test_fuzz import VALUES, _mutate, _paths
from test_robustness import small

JOB = {"photic_job": 1, "name": "fuzz", "inputs": ["scene.json"],
       "set": {"sun.irradiance": 1.0, "water.sea.iops.absorption": 0.1},
       "sweep": {"sun.zenith_deg": [0.0, 30.0]}, "cases": [{"settings.seed": 1}],
       "samples": 2, "radiometer_samples": 256, "units": {"radiometer_passes": 2},
       "max_rounds": 2, "threads": 1, "retries": 0}


@st.composite
def mutated_jobs(draw):
    doc = copy.deepcopy(JOB)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(_paths(doc)))
        try:
            _mutate(doc, path, draw(VALUES))
        except (KeyError, IndexError, TypeError):
            pass
    return doc


@pytest.fixture(scope="module")
def job_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("jobs")
    scene = small()
    scene["water"] = scene["water"][:1]
    (d / "scene.json").write_text(json.dumps(scene))
    return d


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck))
@given(doc=mutated_jobs())
def test_a_job_file_loads_or_raises_a_job_error(job_dir, doc):
    try:
        text = json.dumps(doc, allow_nan=False)
    except ValueError:
        return
    path = job_dir / "job.json"
    path.write_text(text)
    try:
        load_job(path)
    except JobError:
        pass


bpy = pytest.importorskip("bpy")

NUMBERS = st.one_of(st.floats(allow_infinity=True, allow_nan=True, width=32),
                    st.sampled_from([0.0, -0.0, 1e-38, 3.4e38, -3.4e38, float("nan")]))


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
@given(target=st.sampled_from(["sea", "rock", "sun", "camera"]),
       attr=st.sampled_from(["location", "rotation_euler", "scale", "delta_scale"]),
       values=st.lists(NUMBERS, min_size=3, max_size=3),
       props=st.dictionaries(st.sampled_from(["absorption", "scattering", "ior", "bottom_depth",
                                              "wind_speed", "hg_g"]), NUMBERS, max_size=2))
def test_a_blender_scene_exports_or_names_the_problem(target, attr, values, props):
    import photic
    from photic_blender import export
    from test_addon import add_box, add_camera, add_sea, add_sun, empty  # noqa: F401
    from photic_blender.batch import ensure_registered
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.render.engine = "PHOTIC"
    objects = {"camera": add_camera(), "sea": add_sea(depth=10.0), "sun": add_sun(),
               "rock": add_box("Rock", location=(0, 0, -3))}
    setattr(objects[target], attr, values)
    for name, value in props.items():
        try:
            setattr(objects["sea"].photic, name, value)
        except (TypeError, ValueError, AttributeError):
            pass
    try:
        scene, _ = export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    except export.ExportError as e:
        assert "'" in str(e), str(e)  # names an object, light or scene
        return
    except photic.scene.SceneError:
        return
    try:
        scene.validate()
    except photic.scene.SceneError:
        pass
