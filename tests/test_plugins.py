"""Plugins through entry points: the example package in docs/plugin_example, made discoverable
by a temporary .dist-info (what pip would write), without installing it."""
import math
import shutil
import sys

import numpy as np
import pytest

from photic import plugins
from photic.cli import main
from photic.render import Renderer
from photic.scene import Scene, SceneError

EXAMPLE = __import__("pathlib").Path(__file__).resolve().parents[1] / "docs" / "plugin_example"


@pytest.fixture
def example_plugins(tmp_path, monkeypatch):
    shutil.copytree(EXAMPLE / "photic_example_plugins", tmp_path / "photic_example_plugins")
    info = tmp_path / "photic_example_plugins-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: photic-example-plugins\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(
        "[photic.iop_models]\nbubbles = photic_example_plugins:bubble_cloud\n\n"
        "[photic.wave_models]\ngerstner = photic_example_plugins:gerstner_waves\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    plugins.refresh()
    yield
    sys.modules.pop("photic_example_plugins", None)
    plugins.refresh()


def scene_dict():
    return {"photic_scene": 1, "name": "plugins",
            "water": [{"name": "sea", "type": "ocean",
                       "surface": {"kind": "plugin", "plugin": "gerstner",
                                   "params": {"amplitude_m": 0.2, "wavelength_m": 4.0,
                                              "waves_per_patch": 2, "resolution": 32}},
                       "iop_model": {"model": "mixture", "components": [
                           {"model": "bubbles", "b": 0.5},
                           {"model": "cdom", "a_ref": 0.05}]}}],
            "sun": {"zenith_deg": 30.0, "azimuth_deg": 0.0, "irradiance": [1.0]},
            "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [0.0, 0.0, -2.0]}],
            "settings": {"radiometer_samples": 8192, "seed": 1}}


def test_plugins_are_found_and_listed(example_plugins, capsys):
    assert set(plugins.available("iop")) == {"bubbles"}
    assert set(plugins.available("wave")) == {"gerstner"}
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert "bubbles (photic_example_plugins:bubble_cloud)" in out and "gerstner" in out


def test_plugin_models_build_a_scene_the_core_renders(example_plugins):
    scene = Scene.from_dict(scene_dict())
    w = scene.water[0]
    hg = [c for c in w.iops.scattering if c.phase.type == "henyey_greenstein"]
    assert len(hg) == 1 and hg[0].b[0] == 0.5 and hg[0].phase.params["g"] == 0.85
    assert w.surface.kind == "patch" and w.surface.period == (8.0, 8.0)
    mesh, period, normals = w.surface.patch()
    assert normals is not None and np.all(normals[:, 2] > 0)
    res = Renderer(scene).run()
    ed = res.radiometer("Ed")
    assert 0 < ed.mean[0, 0] < math.cos(math.radians(30)) and ed.stderr[0, 0] > 0
    again = Scene.from_dict(scene.to_dict())  # written back as the plugin call
    assert again.water[0].surface.plugin == w.surface.plugin


def test_plugin_errors_name_the_field(example_plugins):
    d = scene_dict()
    d["water"][0]["surface"]["params"]["amplitude_m"] = 1.0  # k A > 1: folds
    with pytest.raises(SceneError, match=r"water 'sea'.*surface\.params.*gerstner.*steepness"):
        Scene.from_dict(d)
    d = scene_dict()
    d["water"][0]["iop_model"]["components"][0]["g"] = 2.0
    with pytest.raises(SceneError, match=r"iop_model\.components\[0\]\.model.*bubbles"):
        Scene.from_dict(d)


def test_a_missing_plugin_is_named():
    d = scene_dict()
    with pytest.raises(SceneError, match=r"components\[0\]\.model.*unknown model 'bubbles'.*plugin"):
        Scene.from_dict(d)
    d["water"][0]["iop_model"] = {"model": "cdom", "a_ref": 0.05}
    with pytest.raises(SceneError, match=r"surface\.plugin.*no wave-model plugin 'gerstner'"):
        Scene.from_dict(d)
