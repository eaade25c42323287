"""Shader-node lookups shared by the export and the panels."""
from __future__ import annotations

import bpy


def node_tree(idblock):
    """The node tree a material or world renders with, or None.

    Blender 5 always uses nodes (``use_nodes`` is deprecated there); older versions only when
    ``use_nodes`` is set."""
    tree = getattr(idblock, "node_tree", None)
    if tree is None:
        return None
    if bpy.app.version < (5, 0, 0) and not idblock.use_nodes:
        return None
    return tree


def find_node(idblock, node_type: str):
    """The first node of a type (e.g. ``"BSDF_PRINCIPLED"``, ``"BACKGROUND"``), or None."""
    tree = node_tree(idblock)
    if tree is None:
        return None
    return next((n for n in tree.nodes if n.type == node_type), None)
