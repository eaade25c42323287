"""Streaming a render to a display: passes in pieces (bands of rows), the running sums of the
rows that changed, a render view that updates often without slowing the render, Esc that
returns at once, and the viewport's first image.

The pieces must not change the numbers: a pass cut into pieces is the same pass (each pixel
draws its own random numbers), so images are compared bit for bit.
"""
from __future__ import annotations

import math
import sys
import threading
import time
import types

import numpy as np
import pytest

import photic.render as render_mod
from photic.render import Renderer, render, row_bands

from test_adaptive_pixels import floor_scene


# ------------------------------------------------------------------------------------------
# The engine: pieces of passes
# ------------------------------------------------------------------------------------------

def test_row_bands_cover_the_active_rows_in_balanced_pieces():
    assert row_bands(None, 10, 4, 1) == [(0, 10)]
    assert row_bands(None, 10, 4, 3) == [(0, 4), (4, 7), (7, 10)] or sum(
        b - a for a, b in row_bands(None, 10, 4, 3)) == 10
    bands = row_bands(None, 100, 7, 8)
    assert bands[0][0] == 0 and bands[-1][1] == 100 and len(bands) == 8
    assert all(a < b for a, b in bands) and all(b == c for (_, b), (c, _) in zip(bands, bands[1:]))
    sizes = [b - a for a, b in bands]
    assert max(sizes) - min(sizes) <= 1
    assert row_bands(None, 5, 3, 100) == [(k, k + 1) for k in range(5)]  # at most one row each
    active = np.zeros((40, 6), np.uint8)
    active[10:12] = 1
    active[30] = 1
    bands = row_bands(active, 40, 6, 3)
    covered = np.zeros(40, bool)
    for a, b in bands:
        assert active[a:b].any()  # no piece without an active pixel
        covered[a:b] = True
    assert covered[active.any(axis=1)].all()
    assert row_bands(np.zeros((4, 4), np.uint8), 4, 4, 2) == []


def _render_pieces(monkeypatch, chunked: bool, **kw):
    if chunked:  # every pass in pieces of about 40 pixel-samples, a few rows each
        monkeypatch.setattr(render_mod, "CHUNK_PIXEL_SAMPLES", 40)
        monkeypatch.setattr(render_mod, "CHUNK_SECONDS", 1e-5)
    else:
        monkeypatch.setattr(render_mod, "CHUNK_PIXEL_SAMPLES", 1 << 40)
        monkeypatch.setattr(render_mod, "CHUNK_SECONDS", 1e9)
    sc = floor_scene(3, kw.pop("bands", 1))
    sc.settings.integrator = kw.pop("integrator", sc.settings.integrator)
    return render(sc, threads=2, **kw)


@pytest.mark.parametrize("kw", [
    dict(samples=8),                                                  # hybrid, one band group
    dict(samples=8, integrator="path"),
    dict(samples=6, bands=9),                                         # two band groups
    dict(samples=64, noise_threshold=0.05, adaptive_min_samples=8),  # adaptive sampling
], ids=["hybrid", "path", "band-groups", "adaptive"])
def test_a_pass_in_pieces_gives_the_same_image_bit_for_bit(monkeypatch, kw):
    whole = _render_pieces(monkeypatch, False, **dict(kw))
    pieces = _render_pieces(monkeypatch, True, **dict(kw))
    a, b = whole.images["floor"], pieces.images["floor"]
    assert a.samples == b.samples
    assert np.array_equal(a.mean, b.mean)
    assert np.array_equal(a.variance, b.variance)
    for c in a.components:
        assert np.array_equal(a.components[c], b.components[c]), c
    if a.pixel_samples is not None:
        assert np.array_equal(a.pixel_samples, b.pixel_samples)
        assert np.array_equal(a.converged, b.converged)
    assert whole.stats["segments"] == pieces.stats["segments"]


def test_a_display_sees_rows_change_piece_by_piece_and_the_sums_agree(monkeypatch):
    """changed_rows / total_sums while a render runs: versions grow, the rows reported are
    those that changed, and the sums at the end divided by the samples are the image."""
    monkeypatch.setattr(render_mod, "CHUNK_PIXEL_SAMPLES", 64)
    monkeypatch.setattr(render_mod, "CHUNK_SECONDS", 1e-5)
    r = Renderer(floor_scene(4), samples=4, threads=1)
    seen, done = [], threading.Event()
    version = -1

    def watch():
        nonlocal version
        while not done.is_set():
            ch = r.changed_rows("floor", version)
            if ch is not None:
                seen.append(ch)
                version = ch[2]
            time.sleep(0.001)

    t = threading.Thread(target=watch)
    assert r.changed_rows("floor") is None and r.total_sums("floor") is None  # before the run
    t.start()
    last = {}

    def progress(fraction, message):
        got = r.total_sums("floor")
        if got is not None:
            last["sums"] = got

    res = r.run(progress)
    done.set()
    t.join()
    assert len(seen) >= 2
    assert all(b[2] > a[2] for a, b in zip(seen, seen[1:]))
    assert all(0 <= f < e <= 16 for f, e, _ in seen)
    assert any(e - f < 16 for f, e, _ in seen[1:])  # some updates are a few rows only
    # After the run the sums became the result: nothing for a display any more.
    assert r.total_sums("floor") is None and r.changed_rows("floor") is None
    got = last["sums"]
    img = res.images["floor"]
    np.testing.assert_allclose(got.total / got.n[:, :, None], img.mean, rtol=1e-12)


def test_cancel_without_images_returns_at_once_and_keeps_the_sums(monkeypatch):
    sc = floor_scene(5)
    r = Renderer(sc, samples=1 << 19, threads=1)
    out = {}
    t = threading.Thread(target=lambda: out.setdefault("res", r.run()))
    t.start()
    while r.total_sums("floor") is None:
        time.sleep(0.01)
    t0 = time.perf_counter()
    r.cancel(images=False)
    t.join()
    assert time.perf_counter() - t0 < 2.0
    res = out["res"]
    assert res.cancelled and res.images == {}
    got = r.total_sums("floor")  # still there for the display
    assert got is not None and got.total.shape[:2] == (16, 24) and float(got.total.sum()) > 0
    # A plain cancel (the command line's Ctrl-C) keeps the images.
    r2 = Renderer(floor_scene(5), samples=1 << 19, threads=1)
    t = threading.Thread(target=lambda: out.__setitem__("res2", r2.run()))
    t.start()
    while r2.total_sums("floor") is None:
        time.sleep(0.01)
    r2.cancel()
    t.join()
    assert out["res2"].cancelled and "floor" in out["res2"].images


def test_denoising_guides_come_after_the_first_pixels_in_pieces_that_a_cancel_stops(monkeypatch):
    """The guides (Renderer(guides=True)) no longer delay the first pixels: they follow the
    passes, in bands of rows like a pass, and a cancel during them returns within a piece;
    in pieces they are the guides of the whole image bit for bit."""
    from photic import denoise
    sc = floor_scene(5)
    sc.cameras[0].resolution = (320, 240)
    whole = render(sc, samples=1, threads=2, guides=True).images["floor"]
    calls = []
    real = denoise.guides

    def spy(core, ci, threads=0, rows=None):
        calls.append((time.perf_counter(), rows))
        return real(core, ci, threads, rows)
    monkeypatch.setattr(denoise, "guides", spy)
    monkeypatch.setattr(render_mod, "GUIDE_FIRST_PIXELS", 320 * 16)
    monkeypatch.setattr(render_mod, "CHUNK_SECONDS", 0.002)
    r = Renderer(sc, samples=1, threads=2, guides=True)
    first_pixels = []
    res = r.run(progress=lambda f, text: first_pixels.append(time.perf_counter()))
    assert len(calls) > 2 and all(c[1] is not None for c in calls)
    assert calls[0][0] > first_pixels[0]  # after the first pass
    rows = sorted(c[1] for c in calls)
    assert rows[0][0] == 0 and rows[-1][1] == 240 and all(a[1] == b[0] for a, b in zip(rows, rows[1:]))
    np.testing.assert_array_equal(res.images["floor"].albedo, whole.albedo)
    np.testing.assert_array_equal(res.images["floor"].normal, whole.normal)
    # Cancelled while the guides run: back after the piece running then.
    calls.clear()
    r = Renderer(sc, samples=1, threads=2, guides=True)
    out = {}
    t = threading.Thread(target=lambda: out.setdefault("res", r.run()))
    t.start()
    while not calls:
        time.sleep(0.001)
    t0 = time.perf_counter()
    r.cancel()
    t.join()
    assert time.perf_counter() - t0 < 0.5
    assert out["res"].cancelled and out["res"].images["floor"].albedo is None
    assert len(calls) < 240 // 16


# ------------------------------------------------------------------------------------------
# Blender: the render view and the viewport
# ------------------------------------------------------------------------------------------

import bpy  # noqa: E402  (a requirement, as in test_addon)
from test_addon import StandInEngine, add_box, add_camera, add_sea, add_sun, empty  # noqa: E402,F401

from photic_blender import final_render, viewport  # noqa: E402


def _plume_like(scene, size, samples, bands=10):
    """A hybrid scene with 10 bands (the Natural-waters default band set is 10)."""
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.photic.samples = samples
    scene.photic.threads = 2
    sea = add_sea(depth=4.0)
    sea.photic.scattering = 0.5
    add_box("Rock", 1.0, (0, 0, -3.5))
    add_camera((0, -5, 1), (math.radians(80), 0, 0))
    add_sun(30)
    return sea


def test_render_view_gets_pixels_early_and_often_and_esc_returns_at_once(empty):
    """480 x 270, hybrid: the first pixels come within 2 s of the render's start (the first
    pass is rendered in pieces), then at least every 2 s; Esc returns within 0.5 s and keeps
    the streamed image in the Combined pass."""
    _plume_like(empty, (480, 270), 1 << 16)
    engine = StandInEngine(break_after_s=8.0)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    pressed = engine.t0 + engine.break_after_s
    returned = time.perf_counter() - pressed
    assert summary["cancelled"] and summary["error"] is None
    times = summary["update_times"]
    assert times and times[0] <= 2.0 + summary.get("export_s", 0.0), times[:3]
    gaps = np.diff(times)
    assert gaps.size >= 2 and gaps.max() <= 2.0, gaps
    assert returned <= 0.5 + final_render.POLL_S, returned
    pixels = np.asarray(engine.final_pixels).reshape(-1, 4)
    assert pixels.shape[0] == 480 * 270 and np.isfinite(pixels).all() and pixels[:, :3].mean() > 0
    print(f"first pixels {times[0]:.2f} s, largest gap {gaps.max():.2f} s, Esc returned in "
          f"{1000 * returned:.0f} ms; display prep median "
          f"{1000 * float(np.median(summary['display_prep_s'])):.0f} ms")


def test_a_finished_render_writes_every_pass(empty):
    """A render that finishes writes all passes from the engine's result (the streamed image
    is the Combined pass only)."""
    _plume_like(empty, (64, 48), 8)

    class Keep(StandInEngine):
        def end_result(self, result):
            super().end_result(result)
            self.passes = {k: p.rect for k, p in result.layers[0].passes.items()}

    engine = Keep(break_after_s=1e9)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert not summary["cancelled"] and summary["samples"] == 8
    for name in ("Combined", *final_render.PASS_NAMES):
        px = np.asarray(engine.passes[name]).reshape(64 * 48, -1)
        assert px.shape[1] in (3, 4) and np.isfinite(px).all(), name
    assert np.asarray(engine.passes["Combined"]).reshape(-1, 4)[:, :3].mean() > 0


class _Matrix:
    """What viewport.view_camera reads of a mathutils Matrix (numpy does the rest)."""

    def __init__(self, m):
        self.m = np.asarray(m, float)

    def inverted(self):
        return _Matrix(np.linalg.inv(self.m))

    def __array__(self, dtype=None, copy=None):
        return self.m if dtype is None else self.m.astype(dtype)

    def __iter__(self):
        return iter(self.m.tolist())

    def __getitem__(self, k):
        return self.m[k]


def _stub_gpu(monkeypatch):
    """gpu and gpu_extras as the viewport uses them (no GPU in background mode): textures are
    kept so the test sees what would be drawn."""
    made = []

    class Texture:
        def __init__(self, size, format, data):
            self.size, self.data = size, np.asarray(data.values, np.float32)
            made.append(self)

    class Buffer:
        def __init__(self, kind, n, values):
            self.values = np.array(values, np.float32).reshape(n)

    gpu = types.ModuleType("gpu")
    gpu.types = types.SimpleNamespace(Buffer=Buffer, GPUTexture=Texture)
    gpu.state = types.SimpleNamespace(blend_set=lambda mode: None)
    extras = types.ModuleType("gpu_extras")
    presets = types.ModuleType("gpu_extras.presets")
    presets.draw_texture_2d = lambda tex, pos, w, h: None
    extras.presets = presets
    monkeypatch.setitem(sys.modules, "gpu", gpu)
    monkeypatch.setitem(sys.modules, "gpu_extras", extras)
    monkeypatch.setitem(sys.modules, "gpu_extras.presets", presets)
    return made


class _ViewEngine:
    def __init__(self):
        self.stats, self.redraws = [], 0

    def update_stats(self, a, b):
        self.stats.append(b)

    def tag_redraw(self):
        self.redraws += 1

    def bind_display_space_shader(self, scene):
        pass

    def unbind_display_space_shader(self):
        pass


def _view_context(width, height, distance=6.0):
    look = np.eye(4)
    look[:3, 3] = (0.0, -distance, 1.0)
    rot = np.array([[1, 0, 0], [0, math.cos(math.radians(80)), -math.sin(math.radians(80))],
                    [0, math.sin(math.radians(80)), math.cos(math.radians(80))]])
    look[:3, :3] = rot
    view = np.linalg.inv(look)
    f = 1.0 / math.tan(math.radians(25))
    proj = np.array([[f * height / width, 0, 0, 0], [0, f, 0, 0], [0, 0, -1.0002, -0.02], [0, 0, -1, 0]])
    rv3d = types.SimpleNamespace(view_matrix=_Matrix(view), window_matrix=_Matrix(proj),
                                 is_perspective=True, view_distance=distance)
    region = types.SimpleNamespace(width=width, height=height)
    return types.SimpleNamespace(region=region, region_data=rv3d)


def test_viewport_draws_a_first_image_within_two_seconds_and_restarts_on_edits(empty, monkeypatch):
    """view_update / view_draw as Blender calls them (the RenderEngine forwards both to
    ViewportRender): a 3D view of 400 x 300 at 50 % scale shows an image within 2 s, its
    pixels finite and lit; an edit restarts the render; stop() ends the thread."""
    made = _stub_gpu(monkeypatch)
    _plume_like(empty, (32, 24), 1)
    empty.photic.viewport_samples = 1 << 12
    empty.photic.viewport_scale = 50
    vp = viewport.ViewportRender()
    eng = _ViewEngine()
    ctx = _view_context(400, 300)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    try:
        vp.update(ctx, depsgraph)
        t0 = time.perf_counter()
        while not made and time.perf_counter() - t0 < 10.0:
            vp.draw(eng, ctx, depsgraph)
            time.sleep(0.02)
        first = time.perf_counter() - t0
        assert made, eng.stats[-3:]
        assert first <= 2.0, first
        tex = made[-1]
        assert tex.size == (200, 150) and tex.data.size == 200 * 150 * 4
        assert np.isfinite(tex.data).all() and tex.data.reshape(-1, 4)[:, :3].mean() > 0
        assert eng.redraws >= 1 and any("sample" in s for s in eng.stats)
        old = vp.thread
        bpy.data.objects["Rock"].location.z = -3.0  # an edit: view_update, then a redraw
        vp.update(ctx, bpy.context.evaluated_depsgraph_get())
        vp.draw(eng, ctx, bpy.context.evaluated_depsgraph_get())
        assert vp.thread is not old and not old.is_alive()
    finally:
        vp.stop()
    assert vp.thread is None
    print(f"viewport: first image after {first:.2f} s")


def test_viewport_shows_the_finished_render_with_all_its_samples(empty, monkeypatch):
    """When the viewport's render ends, the texture is its final image (all samples), although
    the last pieces' sums are spent by then; once shown, no more redraws are asked for."""
    made = _stub_gpu(monkeypatch)
    _plume_like(empty, (32, 24), 1)
    empty.photic.viewport_samples = 8
    empty.photic.viewport_scale = 25
    vp = viewport.ViewportRender()
    eng = _ViewEngine()
    ctx = _view_context(240, 160)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    try:
        vp.update(ctx, depsgraph)
        vp.draw(eng, ctx, depsgraph)
        vp.thread.join()
        vp.draw(eng, ctx, depsgraph)
        assert vp.texture_samples == 8 and made, vp.texture_samples
        last = eng.redraws
        vp.draw(eng, ctx, depsgraph)
        assert eng.redraws == last  # nothing more to show: no more redraws
    finally:
        vp.stop()


def test_viewport_shows_a_coarse_first_image_then_the_full_resolution(empty, monkeypatch):
    """A view larger than PREVIEW_MIN_PIXELS: the first texture is the coarse image (a quarter
    of the render's size in each direction, lit and finite), then the full-resolution render
    replaces it once its first pass covers the whole view; the coarse one is never shown again."""
    made = _stub_gpu(monkeypatch)
    _plume_like(empty, (32, 24), 1)
    empty.photic.viewport_samples = 4
    empty.photic.viewport_scale = 50
    vp = viewport.ViewportRender()
    eng = _ViewEngine()
    ctx = _view_context(640, 480)  # 320 x 240 rendered: more than PREVIEW_MIN_PIXELS
    assert 320 * 240 > viewport.ViewportRender.PREVIEW_MIN_PIXELS
    assert viewport.ViewportRender.preview_factor(320, 240) == 4  # (80 x 60: the least factor)
    assert viewport.ViewportRender.preview_factor(660, 438) == 7  # (Blender's 3D view at 50 %)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    try:
        vp.update(ctx, depsgraph)
        t0 = time.perf_counter()
        while (not made or made[-1].size != (320, 240)) and time.perf_counter() - t0 < 60.0:
            vp.draw(eng, ctx, depsgraph)
            time.sleep(0.01)
        sizes = [t.size for t in made]
        assert sizes[0] == (80, 60), sizes
        assert (320, 240) in sizes, sizes
        first_full = sizes.index((320, 240))
        assert all(s == (80, 60) for s in sizes[:first_full])
        coarse = made[0].data.reshape(-1, 4)
        assert np.isfinite(coarse).all() and coarse[:, :3].mean() > 0
        assert any("coarse" in s for s in eng.stats)
        vp.thread.join()
        for _ in range(3):
            vp.draw(eng, ctx, depsgraph)
        assert all(t.size == (320, 240) for t in made[first_full:])
        assert vp.texture_samples == 4
    finally:
        vp.stop()


def test_a_few_changed_rows_stream_as_a_tile_and_blender_takes_it(empty, tmp_path):
    """Rows that changed since the last update (the first pixels, a piece of a pass) go to the
    render view as a tile of those rows: a result of their own, not a merge of every pass of
    the whole image (0.05-0.4 s with the interpreter lock held at 1080p). Through the stand-in
    (what was begun), then through bpy.ops.render.render (Blender's own results)."""
    _plume_like(empty, (480, 270), 1 << 10)

    class Tiles(StandInEngine):
        def begin_result(self, x, y, w, h):
            self.begun = getattr(self, "begun", []) + [(x, y, w, h)]
            return super().begin_result(x, y, w, h)

    engine = Tiles(break_after_s=4.0)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["cancelled"] and summary["error"] is None
    assert engine.begun[0] == (0, 0, 480, 270)  # the render's own result
    tiles = engine.begun[1:]
    assert tiles, summary["update_times"]
    assert all(w == 480 and x == 0 and 0 <= y and 0 < h < 270 and y + h <= 270 for x, y, w, h in tiles)
    pixels = np.asarray(engine.final_pixels).reshape(-1, 4)  # the whole image at the end
    assert pixels.shape[0] == 480 * 270 and np.isfinite(pixels).all() and pixels[:, :3].mean() > 0
    # Blender: tiles begun and ended while the render's own result is open, then that one.
    empty.photic.samples = 2
    empty.render.image_settings.file_format = "OPEN_EXR"
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()
    assert final_render.LAST_RENDER["error"] is None and final_render.LAST_RENDER["updates"] >= 1
    bpy.data.images["Render Result"].save_render(filepath=str(tmp_path / "tiles.exr"), scene=empty)
    assert (tmp_path / "tiles.exr").stat().st_size > 0


def test_the_worker_is_lowered_in_priority_only_after_the_first_pixels(empty, monkeypatch):
    """The render's worker runs at the interface's priority until the first pixels reach the
    render view, then final_render.lower_priority gets its thread id (in Blender with a window
    that is nice +4 for it and the threads it starts; nothing in background renders)."""
    _plume_like(empty, (160, 90), 1 << 10)
    calls = []

    class Watch(StandInEngine):  # (a streamed update: update_result, or a tile's end_result)
        def update_result(self, result):
            calls.append(("shown", None))
            super().update_result(result)

        def end_result(self, result):
            calls.append(("shown", None))
            super().end_result(result)

    monkeypatch.setattr(final_render, "lower_priority",
                        lambda tid=None: calls.append(("lower", tid)))
    engine = Watch(break_after_s=3.0)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["updates"] >= 1
    lowered = [i for i, c in enumerate(calls) if c[0] == "lower"]
    assert len(lowered) == 1 and isinstance(calls[lowered[0]][1], int) and calls[lowered[0]][1] > 0
    assert calls[lowered[0]][1] != threading.get_native_id()  # the worker's, not this thread's
    assert lowered[0] > calls.index(("shown", None))  # after the first streamed update
