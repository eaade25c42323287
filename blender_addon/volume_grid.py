"""A Volume object's float grid as a numpy array, read through geometry nodes.

Blender's Python API gives a volume grid's name, type and index-to-object transform but not
its voxels, and Blender 5.0's Python has no ``openvdb`` module. Its geometry nodes do read
grids: a temporary object whose node tree makes one point per voxel of the grid's active
index box, samples the grid there by index (Sample Grid Index) and stores the value as an
attribute, which Python then reads in one call. The grid is the *evaluated* one (a ``.vdb``
sequence at the current frame, or a grid made by the Volume's own geometry nodes).

Objects and node groups are created and removed, so this runs only where Blender's data may
change (the main thread: batch export, operators), not during an F12 render.
"""
from __future__ import annotations

import threading

import bpy
import numpy as np

MAX_VOXELS = 1 << 25  # (32 M) one vertex per voxel in the temporary mesh: 16 bytes each, and more


class VolumeGridError(ValueError):
    """Why a grid could not be read (the caller adds the object and property)."""


def on_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def evaluated_grids(volume_obj, depsgraph):
    """The evaluated Volume object and its grids, loaded (a file's, a sequence's at the frame,
    or its geometry nodes' output)."""
    ev = volume_obj.evaluated_get(depsgraph)
    grids = ev.data.grids
    try:
        grids.load()  # a file-based volume's grids (the evaluated ones are loaded already)
    except RuntimeError:
        pass
    return ev, grids


def _grid_of(volume_obj, depsgraph, name: str):
    ev, grids = evaluated_grids(volume_obj, depsgraph)
    names = [g.name for g in grids]
    if name not in names:
        raise VolumeGridError(f"Volume '{volume_obj.name}' has no grid '{name}' (it has: "
                              f"{', '.join(names) or 'none'}{'' if names else '; is its file found?'})")
    grid = grids[names.index(name)]
    if grid.data_type != "FLOAT":  # (what the sampling nodes read as they are set up)
        raise VolumeGridError(f"grid '{name}' of Volume '{volume_obj.name}' holds "
                              f"{grid.data_type.lower()} values: a density is one float per voxel "
                              f"(save it as a float grid)")
    return ev, np.array(grid.matrix_object, dtype=np.float64)


def index_box(corners_object: np.ndarray, index_to_object: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last voxel index (inclusive, per axis) of the voxels within the object-space
    box ``corners_object`` (8 x 3), padded by one voxel (sampled outside the active voxels a
    grid holds its background, 0 for a density: the padding only adds empty voxels). Voxel
    centres sit at integer index coordinates, a voxel spans +-0.5 around its centre."""
    inv = np.linalg.inv(index_to_object)
    c = np.c_[corners_object, np.ones(len(corners_object))] @ inv.T
    lo, hi = c[:, :3].min(axis=0), c[:, :3].max(axis=0)
    i0 = np.floor(lo + 0.5 + 1e-6).astype(np.int64) - 1
    i1 = np.ceil(hi - 0.5 - 1e-6).astype(np.int64) + 1
    return i0, np.maximum(i1, i0)


def _node(tree, kind, **props):
    n = tree.nodes.new(kind)
    for k, v in props.items():
        setattr(n, k, v)
    return n


def _sampler_tree(volume_obj, name: str, i0, shape) -> bpy.types.NodeTree:
    """Points, one per voxel of the index box (point p: voxel i0 + (p // (ny nz), p // nz mod
    ny, p mod nz)), with the grid's value there as the point attribute 'photic_density',
    as mesh vertices."""
    tree = bpy.data.node_groups.new("Photic Volume Sampler", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = _node(tree, "NodeGroupOutput")
    nx, ny, nz = shape
    link = tree.links.new
    points = _node(tree, "GeometryNodePoints")
    points.inputs["Count"].default_value = nx * ny * nz
    index = _node(tree, "GeometryNodeInputIndex")

    def imath(op, a, b):
        n = _node(tree, "FunctionNodeIntegerMath", operation=op)
        for sock, v in zip(n.inputs[:2], (a, b)):
            if isinstance(v, int):
                sock.default_value = v
            else:
                link(v, sock)
        return n.outputs[0]

    idx = index.outputs["Index"]
    ix = imath("ADD", imath("DIVIDE_FLOOR", idx, ny * nz), int(i0[0]))
    iy = imath("ADD", imath("FLOORED_MODULO", imath("DIVIDE_FLOOR", idx, nz), ny), int(i0[1]))
    iz = imath("ADD", imath("FLOORED_MODULO", idx, nz), int(i0[2]))
    info = _node(tree, "GeometryNodeObjectInfo", transform_space="ORIGINAL")
    info.inputs["Object"].default_value = volume_obj
    get = _node(tree, "GeometryNodeGetNamedGrid", data_type="FLOAT")
    get.inputs["Name"].default_value = name
    link(info.outputs["Geometry"], get.inputs["Volume"])
    sample = _node(tree, "GeometryNodeSampleGridIndex", data_type="FLOAT")
    link(get.outputs["Grid"], sample.inputs["Grid"])
    for sock, v in zip(("X", "Y", "Z"), (ix, iy, iz)):
        link(v, sample.inputs[sock])
    store = _node(tree, "GeometryNodeStoreNamedAttribute", data_type="FLOAT", domain="POINT")
    store.inputs["Name"].default_value = "photic_density"
    link(points.outputs["Points"], store.inputs["Geometry"])
    link(sample.outputs["Value"], store.inputs["Value"])
    verts = _node(tree, "GeometryNodePointsToVertices")
    link(store.outputs["Geometry"], verts.inputs["Points"])
    link(verts.outputs["Mesh"], out.inputs[0])
    return tree


def read_volume_grid(volume_obj, name: str = "density"):
    """(values float32 (nx, ny, nz) with x first, index_to_world 4 x 4, i0): the evaluated
    grid ``name`` of ``volume_obj`` over its active voxels' index box (padded by one voxel);
    voxel (i, j, k) of the array is grid voxel i0 + (i, j, k), centred at
    ``index_to_world @ (i0 + (i, j, k), 1)``. Main thread only."""
    if not on_main_thread():
        raise VolumeGridError("a Volume's voxels are read through geometry nodes, which only "
                              "Blender's main thread may set up")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev, to_object = _grid_of(volume_obj, depsgraph, name)
    corners = np.array([tuple(c) for c in ev.bound_box], dtype=np.float64)
    i0, i1 = index_box(corners, to_object)
    shape = tuple(int(s) for s in i1 - i0 + 1)
    n = int(np.prod(shape))
    if n > MAX_VOXELS:
        raise VolumeGridError(f"grid '{name}' of Volume '{volume_obj.name}' spans "
                              f"{' x '.join(map(str, shape))} voxels, more than "
                              f"{MAX_VOXELS:,} (save it at a coarser voxel size)")
    tree = _sampler_tree(volume_obj, name, i0, shape)
    mesh = bpy.data.meshes.new("Photic Volume Sampler")
    obj = bpy.data.objects.new("Photic Volume Sampler", mesh)
    scene = depsgraph.scene_eval.original
    try:
        scene.collection.objects.link(obj)
        mod = obj.modifiers.new("Photic Volume Sampler", "NODES")
        mod.node_group = tree
        depsgraph = bpy.context.evaluated_depsgraph_get()
        depsgraph.update()
        ev_mesh = obj.evaluated_get(depsgraph).data
        attr = ev_mesh.attributes.get("photic_density")
        if attr is None or len(ev_mesh.vertices) != n:
            raise VolumeGridError(f"geometry nodes did not sample grid '{name}' of Volume "
                                  f"'{volume_obj.name}' ({len(ev_mesh.vertices)} of {n} voxels)")
        values = np.empty(n, dtype=np.float32)
        attr.data.foreach_get("value", values)
    finally:
        bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(mesh)
        bpy.data.node_groups.remove(tree)
    index_to_world = np.array(volume_obj.matrix_world, dtype=np.float64) @ to_object
    return values.reshape(shape), index_to_world, i0
