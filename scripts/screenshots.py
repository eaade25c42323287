"""Screenshots of the Photic panels and of a viewport render, in Blender with its UI.

Run inside Blender (not ``-b``) by ``scripts/screenshots.sh``, which starts Xvfb, installs the
add-on into a temporary scripts directory and calls:

    blender --addons photic_blender -p 0 0 1600 1000 example_blends/stepped_pool.blend \\
        --python scripts/screenshots.py

Everything happens in ``bpy.app.timers`` callbacks, after the window exists: each step changes
the UI, returns, and the next step (after a redraw) saves the screenshot. Writes, into
``$PHOTIC_SCREENSHOT_DIR`` (default ``docs/images``):

- ``blender_render_panel.png``: Render properties with the Photic panels;
- ``blender_object_panel.png``: Object properties of the water body 'pool';
- ``blender_viewport.png``: the 3D viewport in rendered shading through the camera, once the
  progressive Photic render reached ``$PHOTIC_SCREENSHOT_SAMPLES`` samples (or after
  ``$PHOTIC_SCREENSHOT_WAIT`` seconds).

Then Blender quits (exit status 0 only when all three were written).
"""
import gc
import os
import sys
import time
import traceback
from pathlib import Path

import bpy

ROOT = Path(__file__).resolve().parents[1]
OUT = Path(os.environ.get("PHOTIC_SCREENSHOT_DIR", ROOT / "docs" / "images"))
SAMPLES = int(os.environ.get("PHOTIC_SCREENSHOT_SAMPLES", "32"))
WAIT_S = float(os.environ.get("PHOTIC_SCREENSHOT_WAIT", "300"))
WATER = "pool"
PROPS_WIDTH = 560
NAMES = ("blender_render_panel.png", "blender_object_panel.png", "blender_viewport.png")


def log(msg):
    print(f"screenshots: {msg}", flush=True)


def window_and_screen():
    window = bpy.context.window_manager.windows[0]
    return window, window.screen


def area_of(kind):
    _, screen = window_and_screen()
    areas = [a for a in screen.areas if a.type == kind]
    return max(areas, key=lambda a: a.width * a.height) if areas else None


def region_of(area, kind="WINDOW"):
    return next(r for r in area.regions if r.type == kind)


def override(area=None):
    window, screen = window_and_screen()
    kw = {"window": window, "screen": screen}
    if area is not None:
        kw.update(area=area, region=region_of(area))
    return bpy.context.temp_override(**kw)


def redraw():
    for area in window_and_screen()[1].areas:
        area.tag_redraw()


def screenshot(name, area=None):
    """The whole window, or only ``area``."""
    path = OUT / name
    if area is None:
        with override(area_of("VIEW_3D")):
            bpy.ops.screen.screenshot(filepath=str(path), check_existing=False)
    else:
        with override(area):
            bpy.ops.screen.screenshot_area(filepath=str(path), check_existing=False)
    log(f"wrote {path}")


def cursor_to_edge():
    """Put the mouse pointer on the edge left of the Properties editor: ``area_move`` only
    runs while the pointer is over no region."""
    props = area_of("PROPERTIES")
    window_and_screen()[0].cursor_warp(props.x - 1, props.y + props.height // 2)


def enlarge_properties(width=PROPS_WIDTH):
    """Widen the Properties editor (labels unabridged) and give it the outliner's height."""
    props = area_of("PROPERTIES")
    with override(props):
        bpy.ops.screen.area_move(x=props.x, y=props.y + props.height // 2,
                                 delta=props.width - width)
    props = area_of("PROPERTIES")
    outliner = area_of("OUTLINER")
    with override(props):
        bpy.ops.screen.area_move(x=props.x + props.width // 2, y=props.y + props.height,
                                 delta=outliner.height - 120)


def viewport_samples():
    """Samples of the texture the Photic viewport shows now (-1: none yet)."""
    vp = sys.modules.get("photic_blender.viewport")
    if vp is None:
        return -1
    renders = [o for o in gc.get_objects() if isinstance(o, vp.ViewportRender)]
    return max((r.texture_samples for r in renders if r.texture is not None), default=-1)


# -- the steps ---------------------------------------------------------------------------------
def setup():
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    prefs = bpy.context.preferences
    prefs.use_preferences_save = False  # never write preferences (not even the temporary ones)
    prefs.view.use_save_prompt = False  # quit without the "save changes?" dialog
    water = bpy.data.objects[WATER]
    for o in bpy.context.view_layer.objects:
        o.select_set(o == water)
    bpy.context.view_layer.objects.active = water
    enlarge_properties()
    props = area_of("PROPERTIES")
    props.spaces.active.context = "RENDER"
    view = area_of("VIEW_3D")
    view.spaces.active.shading.type = "SOLID"
    view.spaces.active.region_3d.view_perspective = "CAMERA"
    with override(view):
        bpy.ops.view3d.view_center_camera()
    redraw()


def shot_render_panel():
    screenshot(NAMES[0], area_of("PROPERTIES"))
    area_of("PROPERTIES").spaces.active.context = "OBJECT"
    redraw()


def shot_object_panel():
    screenshot(NAMES[1], area_of("PROPERTIES"))
    area_of("PROPERTIES").spaces.active.context = "RENDER"
    scene = bpy.context.scene
    scene.photic.viewport_samples = SAMPLES
    scene.update_tag()  # a script's edit of an add-on property does not tag the depsgraph
    view = area_of("VIEW_3D")
    space = view.spaces.active
    space.overlay.show_overlays = False
    space.shading.type = "RENDERED"
    with override(view):
        bpy.ops.view3d.view_center_camera()
    redraw()


STEPS = [(cursor_to_edge, 1.0), (setup, 3.0), (shot_render_panel, 2.0), (shot_object_panel, 2.0)]
state = {"step": 0, "t_render": None}


def tick():
    try:
        if state["step"] < len(STEPS):
            fn, delay = STEPS[state["step"]]
            log(fn.__name__)
            fn()
            state["step"] += 1
            return delay
        if state["t_render"] is None:
            state["t_render"] = time.monotonic()
        samples = viewport_samples()
        elapsed = time.monotonic() - state["t_render"]
        if samples < SAMPLES and elapsed < WAIT_S:
            log(f"viewport at {samples} samples after {elapsed:.0f} s")
            redraw()
            return 5.0
        log(f"viewport render: {samples} samples after {elapsed:.0f} s")
        redraw()
        state["step"] = "final"
        bpy.app.timers.register(final_shot, first_interval=1.0)
        return None
    except Exception:
        traceback.print_exc()
        quit_blender(1)
        return None


def final_shot():
    try:
        screenshot(NAMES[2])
    except Exception:
        traceback.print_exc()
    quit_blender(0 if all((OUT / n).is_file() for n in NAMES) else 1)
    return None


def quit_blender(status):
    log(f"quitting with status {status}")
    sys.stdout.flush()
    if status == 0:
        bpy.ops.wm.quit_blender()
    else:
        os._exit(status)


OUT.mkdir(parents=True, exist_ok=True)
for n in NAMES:
    (OUT / n).unlink(missing_ok=True)
bpy.app.timers.register(tick, first_interval=2.0, persistent=True)
