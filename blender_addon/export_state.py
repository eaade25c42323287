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

    triangles: int = 0           # rendered: an instanced mesh's triangles times its copies
    instances: int = 0           # depsgraph instances walked (objects and their instances)
    instanced_meshes: int = 0    # meshes exported once with a transform per copy
    instanced_copies: int = 0    # the copies of those meshes
    meshes_evaluated: int = 0
    warnings: list = field(default_factory=list)
    # What Photic does not render, or renders approximately, per data-block the panels show
    # it on: ("OBJECT" | "MATERIAL" | "WORLD" | "LIGHT" | "SCENE", name) -> [text]
    notes: dict = field(default_factory=dict)
    time_s: float = 0.0
    radiometer_objects: dict = field(default_factory=dict)  # engine radiometer -> object

    def describe(self) -> str:
        """The exported geometry in a few words: '3,200,000 triangles (10,000 copies of 1
        mesh)'."""
        text = f"{self.triangles:,} triangles"
        if self.instanced_meshes:
            s = "" if self.instanced_meshes == 1 else "es"
            text += f" ({self.instanced_copies:,} copies of {self.instanced_meshes} mesh{s})"
        return text


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
        # mesh key -> export_geometry.Opaque: the mesh read once and each copy's matrix
        self.opaque: dict = {}
        # (key, material name) -> [world vertex arrays, triangle arrays, uv arrays] (a mesh
        # met once, flattened) or export_geometry.Instanced (export_geometry.build_meshes)
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
