"""A water's grid from a Volume object that reads a .vdb *sequence* (one file per frame, as a
CFD run or a bake of an animated simulation writes), in Blender (``bpy`` 5.0 as a module):
each frame exports the grid of that frame's file, read on the main thread by
``natural_waters.read_volumes`` and by the render_pre handler of an animation's render.

The sequence is made here by Blender itself: a Volume whose geometry nodes make a 'density'
grid that moves and changes its value from frame to frame, baked to disk as an animation (one
.vdb per frame), the files renamed as a sequence (``plume_0001.vdb``, ...: Blender takes the
frame number from the last digits of the file name, which in its bake's names ``00001_00000
_file_1.vdb`` are the item's, not the frame's)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import bpy  # noqa: E402  (a requirement, as in test_addon.py)

from test_addon_natural_waters import (assert_slab_followed, bake_grids, empty, export,  # noqa: F401
                                       grid_sea, link, photic, render_animation, sunlit_volume_slab,
                                       volume_with_cube_grid)


def keyframe_grid(vol, keys: dict) -> None:
    """Keyframes the cube grid of ``volume_with_cube_grid``: {frame: (cube centre offset,
    density)} on its Transform and Mesh to Density Grid nodes."""
    tree = vol.modifiers[0].node_group
    move = next(n for n in tree.nodes if n.bl_idname == "GeometryNodeTransform")
    grid = next(n for n in tree.nodes if n.bl_idname == "GeometryNodeMeshToDensityGrid")
    for frame, (offset, density) in keys.items():
        move.inputs["Translation"].default_value = offset
        grid.inputs["Density"].default_value = density
        move.inputs["Translation"].keyframe_insert("default_value", frame=frame)
        grid.inputs["Density"].keyframe_insert("default_value", frame=frame)


def bake_sequence(vol, directory: Path, frames: range) -> list[Path]:
    """Bakes a Volume's geometry-node grids over ``frames`` (the scene's range; a Bake node
    before the group's output, bake mode 'ANIMATION'): one .vdb per frame, copied to
    ``directory``/plume_NNNN.vdb with NNNN the frame. Returns those files, by frame."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = frames[0], frames[-1]
    baked = bake_grids(vol, directory / "bake", "ANIMATION")  # blobs/FFFFF_00000_file_1.vdb
    assert [int(p.name.split("_")[0]) for p in baked] == list(frames), baked
    files = []
    for frame, vdb in zip(frames, baked):
        files.append(directory / f"plume_{frame:04d}.vdb")
        shutil.copy(vdb, files[-1])
    return files


def sequence_volume(first: Path, frames: int, name: str = "From Files"):
    """A Volume object reading the .vdb sequence whose first file is ``first``: scene frame N
    reads file N (Blender reads file number frame - frame_start + 1 + frame_offset, and with
    sequence_mode 'CLIP' nothing outside frame_start .. frame_start + frame_duration - 1)."""
    obj = link(bpy.data.objects.new(name, bpy.data.volumes.new(name)))
    v = obj.data
    v.filepath = str(first)
    v.is_sequence = True
    v.frame_start, v.frame_duration, v.frame_offset = 1, frames, 0
    v.sequence_mode = "CLIP"
    return obj


def exported_grid(sea, box):
    """(densities, origin, size) of the sea's grid taken from the Volume ``box`` at the scene's
    frame: read_volumes (main thread) then the export."""
    from photic_blender import natural_waters
    sea.photic.grid_source, sea.photic.grid_box = "VOLUME", box
    (_, volume, shape), = natural_waters.read_volumes(bpy.context.scene)
    assert volume == box.name and isinstance(shape, tuple), shape
    g = export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)[0].water[0].iops
    return np.asarray(g.density), np.asarray(g.origin), np.asarray(g.size)


def dense_centre(density, origin, size, threshold=0.5):
    """The mean world position of the voxel centres whose density exceeds ``threshold``."""
    cell = size / np.array(density.shape)
    return origin + (np.argwhere(density > threshold).mean(axis=0) + 0.5) * cell


# Per frame: the cube's centre (object space) and its density. Moves of whole voxels (0.25 m).
KEYS = {1: ((0.5, 0.0, 0.0), 2.0), 2: ((1.5, 0.0, 0.0), 3.0), 3: ((1.5, 0.0, -0.5), 1.0)}


def test_volume_reading_a_vdb_sequence_gives_each_frames_grid(empty, tmp_path):
    """A Volume reading a .vdb sequence (``filepath`` its first file, ``is_sequence``,
    frame_start 1, frame_duration 3): at each frame, read_volumes and the export give exactly
    the densities, box and voxels that the Volume whose animated geometry nodes wrote the files
    gives at that frame; the frames differ as the animation says (the cube 1 m further along x
    at frame 2 with density 3, 0.5 m lower at frame 3 with density 1; 7 x 3 x 3 voxels inside
    each time). Past the sequence's end (sequence mode 'CLIP') the Volume has no grid, and the
    read says so."""
    from photic_blender import natural_waters
    sea = grid_sea(tmp_path)
    made = volume_with_cube_grid()
    keyframe_grid(made, KEYS)
    files = bake_sequence(made, tmp_path, range(1, 4))
    filed = sequence_volume(files[0], 3)
    for box in (made, filed):
        box.location = (1.0, 2.0, -3.0)
    for frame, (offset, value) in KEYS.items():
        empty.frame_set(frame)
        (d0, o0, s0), (d1, o1, s1) = (exported_grid(sea, box) for box in (made, filed))
        assert set(np.unique(d0[d0 > 1e-3]).tolist()) == {value}, frame
        assert int((d0 > 0.5).sum()) == 7 * 3 * 3, frame
        np.testing.assert_allclose(dense_centre(d0, o0, s0),
                                   np.add((1.0, 2.0, -3.0), offset), atol=1e-6)
        np.testing.assert_array_equal(d1, d0, err_msg=f"frame {frame}")
        np.testing.assert_allclose(o1, o0, atol=1e-6, err_msg=f"frame {frame}")
        np.testing.assert_allclose(s1, s0, atol=1e-6, err_msg=f"frame {frame}")
        ev = filed.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.grids
        assert (ev.frame, Path(ev.frame_filepath)) == (frame, files[frame - 1])
    keys = {k[2] for k in natural_waters._VOLUME_CACHE if k[0] == filed.session_uid}
    assert keys == {1, 2, 3}, keys  # (a read kept per frame)
    empty.frame_set(4)  # past the 3 files
    sea.photic.grid_box = filed
    (_, _, got), = natural_waters.read_volumes(empty)
    assert isinstance(got, export.ExportError) and "no grid 'density'" in got.message, got


def test_animation_render_reads_each_frame_of_a_vdb_sequence(empty, tmp_path):
    """``bpy.ops.render.render(animation=True)`` (as ``blender -b file.blend -a`` renders) of a
    water whose grid is a Volume reading a .vdb sequence, nothing read before: the render_pre
    handler reads each frame's file, and each frame's radiometers see the turbid slab where
    that frame's file has it (under Lu_east at frame 1, under Lu_west at frame 2)."""
    from photic_blender import natural_waters
    made = sunlit_volume_slab(tmp_path, ("Lu_east", "Lu_west"))
    sea = next(o for o in empty.objects if o.photic.role == "WATER_SURFACE")
    # x from 0 to 4 m, then from -4 to 0 m; 0 to 4 m deep (the slab is 4 x 8 x 4 m)
    keyframe_grid(made, {1: ((2.0, 0.0, -2.0), 1.0), 2: ((-2.0, 0.0, -2.0), 1.0)})
    files = bake_sequence(made, tmp_path, range(1, 3))
    bpy.data.objects.remove(made)
    filed = sequence_volume(files[0], 2)
    sea.photic.grid_box = filed
    empty.frame_set(1)
    empty.photic.samples, empty.photic.radiometer_samples = 1, 4000
    empty.render.filepath = str(tmp_path / "frame_")
    natural_waters._VOLUME_CACHE.clear()
    assert_slab_followed(render_animation())
    frames = sorted(k[2] for k in natural_waters._VOLUME_CACHE if k[0] == filed.session_uid)
    assert frames == [1, 2], frames


# The read cache's key (natural_waters._volume_key) holds what picks a sequence's file at a
# frame: the file the evaluated Volume reads and the sequence settings. Changing is_sequence,
# frame_start or frame_offset makes the frame read another file, and the last read of that
# frame must not be taken for it (it was, before the key held them).

# (Volume data property, new value, the file then read at frame 2, its density)
CHANGES = [("frame_offset", 1, 3, 1.0), ("frame_start", 0, 3, 1.0), ("is_sequence", False, 1, 2.0)]


def sequence_read_at_frame_2(empty, tmp_path):
    """The cube grid sequence of KEYS as a water's grid, read at frame 2 (density 3);
    returns the sea, the Volume reading the files and the files."""
    sea = grid_sea(tmp_path)
    made = volume_with_cube_grid()
    keyframe_grid(made, KEYS)
    files = bake_sequence(made, tmp_path, range(1, 4))
    filed = sequence_volume(files[0], 3)
    empty.frame_set(2)
    d, _, _ = exported_grid(sea, filed)
    assert set(np.unique(d[d > 1e-3]).tolist()) == {3.0}
    return sea, filed, files


def exported_values(sea) -> set:
    g = export.export_scene(bpy.context.evaluated_depsgraph_get(), photic)[0].water[0].iops
    d = np.asarray(g.density)
    return set(np.unique(d[d > 1e-3]).tolist())


@pytest.mark.parametrize("prop, value, file, density", CHANGES, ids=[c[0] for c in CHANGES])
def test_changed_sequence_settings_refuse_the_last_read(empty, tmp_path, prop, value, file,
                                                        density):
    """After a change of the Volume's sequence settings that makes the frame read another file
    (Blender's evaluated Volume then has that file), an export without a new read is refused
    ('has not been read'), as it is after the Volume is moved: the last read is of another
    file."""
    sea, filed, files = sequence_read_at_frame_2(empty, tmp_path)
    setattr(filed.data, prop, value)
    ev = filed.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.grids
    assert Path(ev.frame_filepath) == files[file - 1]
    with pytest.raises(export.ExportError, match="not been read"):
        exported_values(sea)


@pytest.mark.parametrize("prop, value, file, density", CHANGES, ids=[c[0] for c in CHANGES])
def test_render_after_changed_sequence_settings_reads_the_new_file(empty, tmp_path, prop, value,
                                                                   file, density):
    """After such a change, a render of the frame (``bpy.ops.render.render()``: its render_pre
    handler reads the Volumes, keeping reads still current) uses the file the frame now reads:
    the export after it (the same read, looked up the same way) has that file's density."""
    sea, filed, files = sequence_read_at_frame_2(empty, tmp_path)
    setattr(filed.data, prop, value)
    empty.photic.samples = 1
    empty.render.filepath = str(tmp_path / "frame_")
    bpy.ops.render.render()
    assert exported_values(sea) == {density}
