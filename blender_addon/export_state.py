"""What one export shares between its parts: the depsgraph, the scene's Photic settings and
bands, the ``photic`` package, progress and cancel, and the lists the parts fill.

Every ``export_*`` module (materials, geometry, water, radiometers, light, camera, settings)
is a set of functions taking this state as ``ex``; ``export.export_scene`` makes one state,
walks the depsgraph and assembles the scene from what the parts collected. Natural waters'
varying IOPs (``natural_waters.varying_iops``) get the same state.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from . import bands as bandmod
from .export_values import ExportError


@dataclass
class ExportInfo:
    """What the export did: counts, warnings for the user and time taken."""

    triangles: int = 0
    instances: int = 0
    meshes_evaluated: int = 0
    warnings: list = field(default_factory=list)
    # What Photic does not render, or renders approximately, per data-block the panels show
    # it on: ("OBJECT" | "MATERIAL" | "WORLD" | "LIGHT" | "SCENE", name) -> [text]
    notes: dict = field(default_factory=dict)
    time_s: float = 0.0
    radiometer_objects: dict = field(default_factory=dict)  # engine radiometer -> object


class ExportState:
    """One export in progress (``ex`` in the ``export_*`` modules)."""

    def __init__(self, depsgraph, photic, progress=None, test_break=None):
        self.dg = depsgraph
        self.bscene = depsgraph.scene_eval
        self.photic = photic
        self.progress = progress or (lambda f, text: None)
        self.test_break = test_break or (lambda: False)
        self.info = ExportInfo()
        # Photic settings are read from the original data-blocks: Blender does not always
        # re-evaluate the depsgraph when only an add-on property changed.
        self.props = self.bscene.original.photic
        try:
            self.bands = bandmod.scene_bands(self.props)
        except bandmod.BandError as exc:
            raise ExportError(f"Scene '{self.bscene.name}'", f"Photic > Bands ({exc.prop})",
                              exc.message) from None
        # engine material name -> photic Material (export_materials)
        self.materials: dict = {}
        # (key, material name) -> [list of world vertex arrays, list of triangle arrays]
        # (export_geometry)
        self.groups: dict = {}
        self.group_names: dict = {}  # (key, material name) -> the first object's name
        self.mesh_cache: dict = {}   # key -> evaluated mesh arrays (export_geometry.mesh_data)
        self.uv_cache: dict = {}     # key -> {UV map name: (triangles, 3, 2)} (mesh_data)
        self.water = []              # photic WaterBody (export_water)
        self.suns = []               # (sun lamp object, matrix) (export_light)
        self.radiometers = []        # photic Radiometer (export_radiometers)
        self.arrays = []             # photic RadiometerArray (export_radiometers)
        self.material_notes: dict = {}  # engine material name -> its notes (export_materials)
        self.textured: dict = {}     # engine material name -> (UV map name or "", 2x3 affine or None)
        self.has_ocean = False       # a water surface (which hides the sky below the horizon)

    def warn(self, text: str, *ids) -> None:
        """A warning for the user: once in the render's log however often it is met (an
        instanced object's is met per instance), and on the panels of the data-blocks ``ids``
        ((kind, name) pairs, see ``ExportInfo.notes``)."""
        if text not in self.info.warnings:
            self.info.warnings.append(text)
        for key in ids:
            lst = self.info.notes.setdefault(key, [])
            if text not in lst:
                lst.append(text)
