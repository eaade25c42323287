"""Photic for Blender: a render engine for light in natural waters.

Loads as a Blender 4.2+ extension (``blender_manifest.toml``) and as a legacy add-on
(``bl_info``) for distribution Blenders such as Debian's 3.4. Registration never imports the
engine's compiled core (``engine_loader`` does that when first needed), so the add-on always
registers and the panels say why the engine is missing if it is.
"""

bl_info = {
    "name": "Photic",
    "author": "Photic developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Render Properties > Render Engine > Photic",
    "description": "Physically based light in natural waters: caustics, sun shafts, water "
                   "colour and radiometers with error bars",
    "category": "Render",
}

import bpy  # noqa: E402

from . import engine_loader  # noqa: E402

try:
    import numpy  # noqa: F401
except ImportError:  # a distribution Blender without numpy: use the engine's environment
    engine_loader.add_search_paths()

from . import engine, natural_waters, operators, properties, radiometers, ui, waves_preview  # noqa: E402

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(
    properties.classes + operators.classes + radiometers.classes + (engine.PhoticRenderEngine,)
    + ui.classes)


def register():
    _register_classes()
    operators.register()
    radiometers.register()
    engine.register()
    waves_preview.register()
    natural_waters.register()


def unregister():
    natural_waters.unregister()
    waves_preview.unregister()
    engine.unregister()
    radiometers.unregister()
    operators.unregister()
    _unregister_classes()
