"""Denoising: the camera's albedo and normal guides (Scene::camera_guides), OpenImageDenoise on
the engine's band images, and the Blender passes and option that use them."""
from __future__ import annotations

import math

import numpy as np
import pytest

from photic import denoise
from photic.render import render
from photic.scene import Scene

from test_adaptive_pixels import floor_scene


def _clear(scene, a=0.0, b=0.0):
    d = scene.to_dict()
    for w in d["water"]:
        w["iops"]["absorption"] = [a] * len(d["bands"])
        w["iops"]["scattering"][0]["b"] = [b] * len(d["bands"])
    return Scene.from_dict(d)


def test_guides_see_the_floor_through_the_water():
    """Clear water: the albedo is the sand's reflectance (0.3) and the normal the floor's,
    exactly; turbid water: between the sand's and the water's single-scattering albedo
    (b / c), deterministic, the normal shortened by the light that reaches the floor."""
    res = render(_clear(floor_scene(1)), samples=1, threads=1, guides=True)
    img = res.images["floor"]
    assert img.albedo.shape == img.mean.shape and img.normal.shape == img.mean.shape[:2] + (3,)
    np.testing.assert_allclose(img.albedo, 0.3, rtol=1e-6)
    np.testing.assert_allclose(img.normal, np.broadcast_to([0, 0, 1], img.normal.shape), atol=1e-6)
    a, b = 0.1, 0.2
    turbid = render(_clear(floor_scene(1), a, b), samples=1, threads=1, guides=True).images["floor"]
    again = render(_clear(floor_scene(2), a, b), samples=2, threads=2, guides=True).images["floor"]
    assert np.array_equal(turbid.albedo, again.albedo) and np.array_equal(turbid.normal, again.normal)
    assert np.all(turbid.albedo > 0.3) and np.all(turbid.albedo < b / (a + b))
    # The transmittance T from the normal's length; then albedo = 0.3 T + (1 - T) b / c.
    t = turbid.normal[:, :, 2]
    assert np.all((t > 0) & (t < 1))
    np.testing.assert_allclose(turbid.albedo[:, :, 0], 0.3 * t + (1 - t) * b / (a + b), rtol=1e-5)


def test_no_guides_unless_asked():
    img = render(floor_scene(1), samples=1, threads=1).images["floor"]
    assert img.albedo is None and img.normal is None


@pytest.mark.skipif(not denoise.available(), reason="pyoidn (OpenImageDenoise) is a requirement")
def test_denoising_brings_a_noisy_image_closer_to_the_converged_one():
    """The floor at 2 spp, three bands: denoised with its guides, its RMS error against a 512
    spp reference is well below the noisy image's (the reference's own noise removed)."""
    sc = floor_scene(1, bands=3)
    noisy = render(sc, samples=2, threads=2, guides=True).images["floor"]
    ref = render(floor_scene(7, bands=3), samples=512, threads=2).images["floor"]
    clean = denoise.denoise_bands(noisy.mean, noisy.albedo, noisy.normal)
    assert clean.shape == noisy.mean.shape and np.isfinite(clean).all()
    m = float(ref.mean.mean())
    ref_noise2 = float(np.mean(ref.variance))

    def err(x):
        return math.sqrt(max(float(np.mean((x - ref.mean) ** 2)) - ref_noise2, 0.0)) / m

    e_noisy, e_clean = err(noisy.mean), err(clean)
    print(f"2 spp: noisy {100 * e_noisy:.1f} %, denoised {100 * e_clean:.1f} %")
    assert e_clean < 0.5 * e_noisy, (e_noisy, e_clean)
    # Bands in threes: a 4-band image is denoised as bands (0, 1, 2) and (3, 3, 3).
    assert denoise._triples(4) == [[0, 1, 2], [3, 3, 3]]


def test_a_missing_denoiser_is_a_clear_error(monkeypatch):
    import builtins
    real = builtins.__import__

    def no_oidn(name, *a, **k):
        if name == "pyoidn":
            raise ImportError("No module named 'pyoidn'")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_oidn)
    assert not denoise.available()
    with pytest.raises(denoise.DenoiserMissing, match="pip install pyoidn"):
        denoise.denoise_rgb(np.zeros((4, 4, 3), np.float32))


def test_an_import_that_fails_otherwise_is_no_denoiser_either(monkeypatch):
    """Blender 3.4's Python finds the system's cffi backend first: importing pyoidn raises a
    plain Exception (version mismatch), which must read as 'unavailable', not end the render."""
    import builtins
    real = builtins.__import__

    def mismatch(name, *a, **k):
        if name == "pyoidn":
            raise Exception("Version mismatch: this is the 'cffi' package version 2.1.1")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", mismatch)
    assert not denoise.available()
    assert "Version mismatch" in denoise.unavailable_reason()


def test_a_denoiser_that_fails_leaves_the_render_noisy(empty, monkeypatch):
    _scene(empty)
    empty.photic.denoise = True

    def broken(*a, **k):
        raise RuntimeError("OIDN device error (a stand-in)")

    monkeypatch.setattr(denoise, "denoise_rgb", broken)
    engine = _KeepPasses(break_after_s=1e9)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["error"] is None
    assert any("denoising failed" in m for _, m in engine.reports), engine.reports
    assert np.asarray(engine.passes["Combined"]).reshape(-1, 4)[:, :3].mean() > 0


# ------------------------------------------------------------------------------------------
# Blender: passes named as Cycles names them, and the Denoise option
# ------------------------------------------------------------------------------------------

import bpy  # noqa: E402  (a requirement, as in test_addon)
from test_addon import StandInEngine, add_box, add_camera, add_sea, add_sun, empty  # noqa: E402,F401

from photic_blender import final_render  # noqa: E402


class _KeepPasses(StandInEngine):
    def begin_result(self, x, y, w, h):
        result = super().begin_result(x, y, w, h)
        for name in (final_render.ALBEDO_PASS, final_render.NORMAL_PASS, final_render.NOISY_PASS):
            result.layers[0].passes[name] = type(result.layers[0].passes["Combined"])()
        return result

    def end_result(self, result):
        super().end_result(result)
        self.passes = {k: p.rect for k, p in result.layers[0].passes.items()}


def _scene(scene):
    scene.render.resolution_x, scene.render.resolution_y = 48, 32
    scene.photic.samples = 2
    add_sea(depth=4.0).photic.scattering = 0.5
    add_box("Rock", 1.0, (0, 0, -3.5))
    add_camera((0, -5, 1), (math.radians(80), 0, 0))
    add_sun(30)


@pytest.fixture(autouse=True)
def _pyoidn_unless_a_test_names_a_library(monkeypatch):
    """Every test starts with the engine's default denoiser (pyoidn); a render through the
    add-on may name Blender's library (photic.denoise.LIBRARY), undone after the test."""
    monkeypatch.setattr(denoise, "LIBRARY", None)


def _hide_pyoidn(monkeypatch):
    """pyoidn neither importable nor found, as in the extension (which does not bundle it)."""
    import builtins
    import importlib.util
    real_import, real_find = builtins.__import__, importlib.util.find_spec

    def no_oidn(name, *a, **k):
        if name == "pyoidn":
            raise ImportError("No module named 'pyoidn'")
        return real_import(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_oidn)
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a, **k: None if name == "pyoidn" else real_find(name, *a, **k))


def test_blenders_own_denoiser_is_found_and_denoises_as_pyoidn_does():
    """The OpenImageDenoise that Blender links (bpy 5.0: bpy/lib) is found by the add-on and,
    called through its C API, gives pyoidn's image (the same RT filter)."""
    from photic_blender import oidn
    path = oidn.blender_library()
    assert path is not None and "OpenImageDenoise" in path and "_core" not in path, path
    assert path == oidn.loaded_library()  # (the one Blender itself has loaded)
    rng = np.random.default_rng(0)
    c = (0.5 + 0.2 * rng.standard_normal((24, 32, 3))).astype(np.float32)
    a = np.full((24, 32, 3), 0.5, np.float32)
    n = np.zeros((24, 32, 3), np.float32)
    n[..., 2] = 1.0
    ours = denoise.denoise_rgb(c, a, n) if denoise.available() else None
    assert denoise.use_library(path) is None and denoise.denoiser() == path
    theirs = denoise.denoise_rgb(c, a, n)
    assert theirs.shape == c.shape and np.isfinite(theirs).all()
    assert theirs.std() < 0.5 * c.std()  # denoised: the noise (std 0.2) mostly gone
    if ours is not None:
        np.testing.assert_allclose(theirs, ours, atol=2e-3)
    assert denoise.use_library("/nonexistent/libOpenImageDenoise.so") is not None
    assert denoise.LIBRARY is None


def test_denoise_without_pyoidn_uses_blenders_own(empty, monkeypatch):
    """As in the extension (no pyoidn): F12 with Denoise denoises with Blender's library, no
    warning, the noisy image kept; through bpy.ops.render.render."""
    from photic_blender import oidn
    _hide_pyoidn(monkeypatch)
    assert not denoise.available()  # (pyoidn is really out of reach)
    _scene(empty)
    empty.photic.denoise = True
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()
    summary = final_render.LAST_RENDER
    assert summary["error"] is None and summary.get("denoise_s", 0) > 0, summary
    assert summary["denoiser"] == oidn.blender_library()
    engine = _KeepPasses(break_after_s=1e9)  # (the passes, as the render view gets them)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert not any("Denoise is off" in m for _, m in engine.reports), engine.reports
    img_c = np.asarray(engine.passes["Combined"]).reshape(32, 48, 4)[:, :, :3]
    img_n = np.asarray(engine.passes[final_render.NOISY_PASS]).reshape(32, 48, 3)
    assert np.isfinite(img_c).all() and not np.allclose(img_c, img_n)
    assert np.abs(np.diff(img_c, axis=1)).mean() < np.abs(np.diff(img_n, axis=1)).mean()


def test_denoising_data_passes_are_registered_and_written(empty):
    _scene(empty)
    names = [n for n, _, _ in final_render.render_passes(empty)]
    assert final_render.ALBEDO_PASS not in names
    empty.photic.denoising_data = True
    passes = {n: (c, k) for n, c, k in final_render.render_passes(empty)}
    assert passes[final_render.ALBEDO_PASS] == ("RGB", "COLOR")
    assert passes[final_render.NORMAL_PASS] == ("XYZ", "VECTOR")
    assert final_render.NOISY_PASS not in passes
    engine = _KeepPasses(break_after_s=1e9)
    final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    albedo = np.asarray(engine.passes[final_render.ALBEDO_PASS]).reshape(-1, 3)
    normal = np.asarray(engine.passes[final_render.NORMAL_PASS]).reshape(-1, 3)
    assert albedo.shape == (48 * 32, 3) and albedo.min() >= 0 and albedo.max() <= 1 and albedo.max() > 0
    assert np.abs(normal).max() <= 1.0 + 1e-6 and np.abs(normal).max() > 0
    assert engine.passes[final_render.NOISY_PASS] is None  # not asked for: not written


@pytest.mark.skipif(not denoise.available(), reason="pyoidn (OpenImageDenoise) is a requirement")
def test_denoise_option_denoises_combined_and_keeps_the_noisy_image(empty):
    _scene(empty)
    empty.photic.denoise = True
    engine = _KeepPasses(break_after_s=1e9)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["error"] is None and summary["denoise_s"] > 0
    combined = np.asarray(engine.passes["Combined"]).reshape(-1, 4)
    noisy = np.asarray(engine.passes[final_render.NOISY_PASS]).reshape(-1, 3)
    assert np.isfinite(combined).all() and not np.allclose(combined[:, :3], noisy)
    assert np.all(combined[:, 3] == 1.0)
    # Denoising smooths: neighbouring pixels differ less than in the noisy image.
    img_c = combined[:, :3].reshape(32, 48, 3)
    img_n = noisy.reshape(32, 48, 3)
    assert np.abs(np.diff(img_c, axis=1)).mean() < np.abs(np.diff(img_n, axis=1)).mean()


def test_denoise_without_the_denoiser_warns_and_keeps_the_image(empty, monkeypatch):
    _scene(empty)
    empty.photic.denoise = True
    monkeypatch.setattr(denoise, "unavailable_reason", lambda: "cffi version mismatch (a stand-in)")
    engine = _KeepPasses(break_after_s=1e9)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["error"] is None
    assert any("Denoise is off: cffi version mismatch" in m for _, m in engine.reports), engine.reports
    assert engine.passes[final_render.NOISY_PASS] is None
    assert np.asarray(engine.passes["Combined"]).reshape(-1, 4)[:, :3].mean() > 0


@pytest.mark.skipif(not denoise.available(), reason="pyoidn (OpenImageDenoise) is a requirement")
def test_f12_with_denoise_through_blender(empty, tmp_path):
    """Through bpy.ops.render.render (the real render result: add_pass with the XYZ normal)
    and a multilayer EXR with the denoising passes."""
    _scene(empty)
    empty.photic.denoise = True
    settings = empty.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: multilayer is a media type
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()
    bpy.data.images["Render Result"].save_render(filepath=str(tmp_path / "frame.exr"), scene=empty)
    summary = final_render.LAST_RENDER
    assert summary["error"] is None and summary.get("denoise_s", 0) > 0
    from test_addon import exr_channels
    channels = exr_channels(tmp_path / "frame.exr")
    for name in (final_render.ALBEDO_PASS, final_render.NORMAL_PASS, final_render.NOISY_PASS):
        assert any(name in c for c in channels), (name, sorted(channels))


@pytest.mark.skipif(not denoise.available(), reason="pyoidn (OpenImageDenoise) is a requirement")
def test_inside_blender_the_denoiser_runs_in_a_child_process(monkeypatch):
    """Inside a Blender application (Debian's 3.4: its jemalloc and libraries) OIDN 2.5
    aborted the process: there the denoiser runs in a process of its own, with the same
    result (Blender 3.4 itself: docs/blender.md, checked by hand)."""
    rng = np.random.default_rng(0)
    c = (0.5 + 0.2 * rng.standard_normal((24, 32, 3))).astype(np.float32)
    a = np.full((24, 32, 3), 0.5, np.float32)
    n = np.zeros((24, 32, 3), np.float32)
    n[..., 2] = 1.0
    here = denoise.denoise_rgb(c, a, n)
    calls = []
    real = denoise._denoise_in_child
    assert denoise._separate_process() is None  # (pytest: a Python process)
    monkeypatch.setattr(denoise, "_separate_process", lambda: "inside the Blender application (blender)")
    monkeypatch.setattr(denoise, "_denoise_in_child", lambda *x: calls.append(1) or real(*x))
    assert denoise.available()
    child = denoise.denoise_rgb(c, a, n)
    assert calls and np.array_equal(here, child)
