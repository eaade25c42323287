"""Natural waters on a Blender water object: IOPs that vary with depth or in 3-D.

``Object.photic.iop_variation`` chooses

- ``PROFILE``: horizontal layers (the engine's ``IOPProfile``), either a Gaussian chlorophyll
  maximum driving the Case-1 model (``photic.profiles``; the chlorophyll-specific absorption
  table comes from the user, none is bundled) or a CSV table of coefficients against depth;
- ``GRID``: the object's IOPs plus a density field times unit IOPs over a box (the engine's
  ``IOPGrid``), the density from a ``.npz`` file or from a Volume object's 'density' grid
  (read through geometry nodes, ``volume_grid``), and up to three further density fields
  (``photic.grid_fields``, the engine's ``GridField``), each with unit IOPs of its own, read
  by their names from the same file or Volume;
- ``PROFILE_GRID``: both, the profile as the grid's base (a plume in stratified water).

Depths count down from the water level: the mean sea level of a water surface, the top of a
water body's mesh. Every problem is an ``ExportError`` naming the object and the property.
"""
from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import export_iops
from .export_values import ExportError, _obj, blender_float, per_band
from .properties import MAX_FURTHER_FIELDS

MAX_LAYERS = 5000
# (path, mtime_ns, size) -> {array name: checked float32 array}: the arrays read of one .npz
# (the last one read); the viewport re-exports often
_DENSITY_CACHE: dict = {}

P_KIND = "Photic > Profile (photic.profile_kind)"
P_CHL_TEXT = "Photic > Chl Absorption Text (photic.chl_absorption_text)"
P_CHL_FILE = "Photic > Chl Absorption File (photic.chl_absorption_file)"
P_TABLE_TEXT = "Photic > Layer Table Text (photic.profile_table_text)"
P_TABLE_FILE = "Photic > Layer Table File (photic.profile_table_file)"
P_GRID_FILE = "Photic > Density File (photic.grid_file)"
P_GRID_SOURCE = "Photic > Density (photic.grid_source)"
P_GRID_BOX = "Photic > Grid Box (photic.grid_box)"
P_FIELDS = "Photic > Further Density Fields (photic.grid_fields)"
WATER_ROLES = ("WATER_BODY", "WATER_SURFACE")  # the objects that carry IOPs


def varying_iops(ex, obj, level: float, bounds):
    """The ``IOPProfile`` or ``IOPGrid`` of a water object (``ex``: the export's state,
    ``export_state.ExportState``)."""
    p = obj.original.photic
    profile = None
    if p.iop_variation in ("PROFILE", "PROFILE_GRID"):
        profile = (chlorophyll_profile(ex, obj, level) if p.profile_kind == "CHLOROPHYLL"
                   else table_profile(ex, obj, level))
        if p.iop_variation == "PROFILE":
            return profile
    return density_grid(ex, obj, bounds, profile)


# -- tables ----------------------------------------------------------------------------------

def _abspath(text: str) -> Path:
    """A file property as an absolute path ('//' is the .blend's folder)."""
    return Path(os.path.normpath(bpy.path.abspath(text.strip())))


def _table_source(owner: str, text_block, file_text: str, p_text: str, p_file: str,
                  what: str) -> tuple[str, str, str]:
    """(CSV text, where it came from, the property to name) of a Text data-block or a file."""
    if text_block is not None:
        return text_block.as_string(), f"Text '{text_block.name}'", p_text
    if not file_text.strip():
        raise ExportError(owner, p_text, f"and {p_file.split(' (')[0]} are both empty: the "
                                         f"{what} needs a CSV table")
    path = _abspath(file_text)
    try:
        return path.read_text(), str(path), p_file
    except OSError as exc:
        raise ExportError(owner, p_file, f"cannot read {path}: {exc.strerror or exc}") from None


def read_csv(owner: str, prop: str, text: str, where: str) -> tuple[list[str], np.ndarray]:
    """Header and rows (float64) of a CSV table; lines starting with '#' are comments."""
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    rows = list(csv.reader(lines))
    if len(rows) < 2:
        raise ExportError(owner, prop, f"{where} needs a header line and at least one row")
    header = [h.strip() for h in rows[0]]
    values = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ExportError(owner, prop, f"{where}, row {i + 1}: {len(row)} values but the "
                                           f"header has {len(header)} columns")
        for j, cell in enumerate(row):
            try:
                values[i, j] = float(cell)
            except ValueError:
                raise ExportError(owner, prop, f"{where}, row {i + 1}, column '{header[j]}': "
                                               f"{cell.strip()!r} is not a number") from None
    return header, values


# -- depth profiles --------------------------------------------------------------------------

def chlorophyll_model(obj, level: float):
    """(model, tops, where, prop) of a Gaussian chlorophyll maximum: ``model(z)`` the Case-1
    model description at height z, ``tops`` the layer tops, and where the chlorophyll-specific
    absorption table came from and the property naming it."""
    from photic.profiles import gaussian_chlorophyll
    p = obj.original.photic
    owner = _obj(obj.name)
    columns = ("a_star",) if p.case1_variant == "classic" else ("A", "E")
    text, where, prop = _table_source(owner, p.chl_absorption_text, p.chl_absorption_file,
                                      P_CHL_TEXT, P_CHL_FILE, "chlorophyll profile's Case-1 "
                                      "model (chlorophyll-specific absorption)")
    header, rows = read_csv(owner, prop, text, where)
    # Only the columns the model reads: a table may carry both variants' columns.
    table = {"source": where, **{h: rows[:, j].tolist() for j, h in enumerate(header)
                                 if h in ("wavelength_nm",) + columns}}
    values = {}
    for name, label in (("chl_background", "Background Chl"), ("chl_peak", "Peak Chl"),
                        ("chl_peak_depth", "Depth of Peak"), ("chl_width", "Width"),
                        ("profile_layer_thickness", "Layer Thickness"),
                        ("profile_max_depth", "Profile Depth")):
        x = blender_float(getattr(p, name))
        if not (math.isfinite(x) and x >= 0):
            raise ExportError(owner, f"Photic > {label} (photic.{name})", f"is {x}, must be a "
                                                                           f"finite number >= 0")
        values[name] = x
    thickness, depth = values["profile_layer_thickness"], values["profile_max_depth"]
    if not (thickness > 0 and depth / thickness <= MAX_LAYERS):
        raise ExportError(owner, "Photic > Layer Thickness (photic.profile_layer_thickness)",
                          f"gives {depth / thickness if thickness > 0 else math.inf:.0f} layers "
                          f"down to {depth:g} m; at most {MAX_LAYERS}")
    if not values["chl_width"] > 0:
        raise ExportError(owner, "Photic > Width (photic.chl_width)", "must be > 0 m")
    tops = level - thickness * np.arange(max(1, math.ceil(depth / thickness - 1e-9)))
    chl = gaussian_chlorophyll(values["chl_background"], values["chl_peak"],
                               level - values["chl_peak_depth"], values["chl_width"])

    def model(z):
        return {"model": "case1", "variant": p.case1_variant, "chlorophyll": chl(z),
                "chlorophyll_absorption": table}

    return model, tops, where, prop


def chlorophyll_profile(ex, obj, level: float):
    """A Gaussian chlorophyll maximum through the Case-1 model, averaged into layers."""
    S = ex.photic.scene
    from photic.profiles import profile_from_function
    p = obj.original.photic
    owner = _obj(obj.name)
    model, tops, where, prop = chlorophyll_model(obj, level)
    try:
        profile = profile_from_function(model, tops, [S.Band(*b) for b in ex.bands])
    except S.SceneError as exc:
        if "chlorophyll_absorption" in exc.field:
            raise ExportError(owner, prop, f"{where}: field '{exc.field}': {exc.message}") from None
        if exc.field == "chlorophyll":  # e.g. the 'new' model at C = 0 far from the peak
            raise ExportError(owner, "Photic > Background Chl (photic.chl_background)",
                              f"the Case-1 model's chlorophyll away from the peak: "
                              f"{exc.message}") from None
        raise ExportError(owner, "Photic > Case-1 Model (photic.case1_variant)",
                          f"field '{exc.field}': {exc.message}") from None
    components = len(profile.layers[0].scattering)
    if components > S.MAX_COMPONENTS:  # the 'new' model: one phase function per fraction
        raise ExportError(owner, "Photic > Case-1 Model (photic.case1_variant)",
                          f"the '{p.case1_variant}' model's particle backscatter fraction "
                          f"changes with band and chlorophyll: the profile has {components} "
                          f"different phase functions, the engine holds at most "
                          f"{S.MAX_COMPONENTS}; use the classic model, or fewer layers and "
                          f"bands")
    return profile


def table_profile(ex, obj, level: float):
    """Layers from a CSV table: depth_m, then a_<band> and b_<band> (or a and b)."""
    S = ex.photic.scene
    from photic.profiles import align_components
    p = obj.original.photic
    owner = _obj(obj.name)
    if p.iop_source == "MODEL":
        raise ExportError(owner, "Photic > IOPs (photic.iop_source)",
                          "is 'IOP Model', which a layer table cannot use: choose "
                          "'Coefficients' (the table's a and b) or 'Pure Water + Additions' "
                          "(pure water plus the table's a and b)")
    text, where, prop = _table_source(owner, p.profile_table_text, p.profile_table_file,
                                      P_TABLE_TEXT, P_TABLE_FILE, "layer table")
    header, rows = read_csv(owner, prop, text, where)
    names = [b[0] for b in ex.bands]
    index = {h: j for j, h in enumerate(header)}
    if "depth_m" not in index:
        raise ExportError(owner, prop, f"{where} has no column 'depth_m' (columns: "
                                       f"{', '.join(header)})")
    used = {"depth_m"}
    per_band = {}
    for q in ("a", "b"):
        if q in index:
            per_band[q] = np.repeat(rows[:, [index[q]]], len(names), axis=1)
            used.add(q)
            continue
        wanted = [f"{q}_{n}" for n in names]
        missing = [w for w in wanted if w not in index]
        if missing:
            raise ExportError(owner, prop, f"{where} lacks column(s) {', '.join(missing)}: give "
                                           f"{q}_<band> for every band ({', '.join(names)} nm) "
                                           f"or one column '{q}' for all bands")
        per_band[q] = rows[:, [index[w] for w in wanted]]
        used.update(wanted)
    unknown = [h for h in header if h not in used]
    if unknown:
        raise ExportError(owner, prop, f"{where}: unknown column(s) {', '.join(unknown)} "
                                       f"(expected depth_m, a_<band>, b_<band>; bands "
                                       f"{', '.join(names)})")
    depth = rows[:, index["depth_m"]]
    for i, d in enumerate(depth):
        if not (math.isfinite(d) and d >= 0):
            raise ExportError(owner, prop, f"{where}, row {i + 1}: depth_m {d:g} must be a "
                                           f"finite depth >= 0 m below the water level")
        if i and not d > depth[i - 1]:
            raise ExportError(owner, prop, f"{where}, row {i + 1}: depth_m {d:g} must be below "
                                           f"the row before ({depth[i - 1]:g} m): one row per "
                                           f"layer top, from the top down")
    layers = []
    for i in range(len(depth)):
        for q, what in (("a", "absorption"), ("b", "scattering")):
            for k, x in enumerate(per_band[q][i]):
                if not (math.isfinite(x) and x >= 0):
                    raise ExportError(owner, prop, f"{where}, row {i + 1}: {what} {q} in band "
                                                   f"{names[k]} is {x:g}, must be a finite "
                                                   f"number >= 0 (m^-1)")
        layers.append(export_iops.coefficient_iops(ex, owner, p, per_band["a"][i].copy(),
                                                   per_band["b"][i].copy()))
    return S.IOPProfile(level - depth, align_components(layers))


# -- 3-D grids -------------------------------------------------------------------------------

def unit_iops(ex, obj):
    """IOPs per unit density of the first field (no pure water unless the model names it)."""
    return _unit_iops(ex, _obj(obj.name), obj.original.photic, "photic", "Photic > ")


def _field_label(f, i: int) -> str:
    """The UI path of further field ``i`` (``photic.grid_fields[i]``), for error messages."""
    return (f"Photic > Further Density Field '{f.name}' > " if f.name.strip()
            else f"Photic > Further Density Field {i + 1} > ")


def field_prop(f, i: int) -> str:
    """The name of further field ``i`` as errors name that property."""
    return f"{_field_label(f, i)}Name (photic.grid_fields[{i}].name)"


def field_unit_iops(ex, owner: str, f, i: int):
    """IOPs per unit density of further field ``i``, as ``unit_iops``."""
    return _unit_iops(ex, owner, f, f"photic.grid_fields[{i}]", _field_label(f, i))


def _unit_iops(ex, owner: str, q, path: str, label: str):
    """Unit IOPs from the properties ``unit_*`` of ``q`` (the object's Photic properties or a
    further field), errors naming ``label`` + the property's name and ``path`` + its name."""
    S = ex.photic.scene
    if q.unit_source == "MODEL":
        return export_iops.model_iops(ex, owner, q.unit_model,
                                      f"{label}Unit IOP Model ({path}.unit_model)",
                                      defaults={"water": "none"})
    a = per_band(owner, q.unit_absorption, q.unit_absorption_bands, f"{label}Unit Absorption",
                 f"{path}.unit_absorption", ex.bands, "absorption per unit density")
    b = per_band(owner, q.unit_scattering, q.unit_scattering_bands, f"{label}Unit Scattering",
                 f"{path}.unit_scattering", ex.bands, "scattering per unit density")
    phase = export_iops.phase_function(ex, owner, q.unit_phase_function, q.unit_hg_g,
                                       q.unit_ff_backscatter, prefix=f"{label}Unit ")
    return S.IOPs(a, [S.ScatteringComponent(b, phase)])


def further_fields(owner: str, p) -> list[tuple[str, str]]:
    """(name, property naming it) of each further density field, checked: at most three,
    names non-empty, their own and not 'density' (the first field's array or grid)."""
    fields = list(p.grid_fields)
    if len(fields) > MAX_FURTHER_FIELDS:
        raise ExportError(owner, P_FIELDS, f"has {len(fields)} fields: a grid holds at most "
                                           f"{MAX_FURTHER_FIELDS} beside its 'density' (remove "
                                           f"{len(fields) - MAX_FURTHER_FIELDS})")
    out = []
    for i, f in enumerate(fields):
        name, prop = f.name, field_prop(f, i)
        if not name.strip() or name != name.strip():
            raise ExportError(owner, prop, f"is {name!r}: a further field needs a name, without "
                                           f"spaces around it: the name of its array in the "
                                           f"Density File or of its grid in the Volume")
        if name == "density":
            raise ExportError(owner, prop, "is 'density', the first field's array or grid: "
                                           "name a further field after its own array or grid")
        if name in [n for n, _ in out]:
            raise ExportError(owner, prop, f"'{name}' names two further fields: each reads its "
                                           f"own array or grid")
        out.append((name, prop))
    return out


def density_grid(ex, obj, bounds, profile=None):
    """The base IOPs (the object's IOP source, or the depth ``profile``) plus density x unit
    IOPs over the box, and each further field's density x its unit IOPs; every layer and unit
    on one set of components."""
    S = ex.photic.scene
    from photic.profiles import align_components
    p = obj.original.photic
    owner = _obj(obj.name)
    fields = further_fields(owner, p)
    units = [unit_iops(ex, obj)] + [field_unit_iops(ex, owner, f, i)
                                    for i, f in enumerate(p.grid_fields)]
    if profile is not None:
        aligned = align_components(list(profile.layers) + units)
        n = len(profile.layers)
        base, units = S.IOPProfile(profile.z_top, aligned[:n]), aligned[n:]
    else:
        base, *units = align_components([export_iops.iops(ex, obj)] + units)
    if p.grid_source == "VOLUME":
        density, lo, hi, extra = volume_density(ex, owner, p.grid_box, fields)
        file = None
    else:
        (density, *extra), file = npz_arrays(owner, p.grid_file, fields)
        lo, hi = grid_box(ex, owner, p.grid_box, bounds)
        where = f"{file}: array"
        for (name, prop), rho in zip(fields, extra):
            if rho.shape != density.shape:
                raise ExportError(owner, prop, f"{where} '{name}' has shape {rho.shape} but "
                                               f"'density' has {density.shape}: every field is "
                                               f"on the grid's voxels (the same shape)")
    extra_fields = [S.GridField(name, unit, rho, name if file is not None else None)
                    for (name, _), unit, rho in zip(fields, units[1:], extra)]
    return S.IOPGrid(base, units[0], lo, hi - lo, density, file, extra_fields)


def check_density(owner: str, prop: str, density, where: str,
                  name: str = "density") -> np.ndarray:
    """The densities of field ``name`` as float32 (nx, ny, nz), every voxel finite and >= 0."""
    d = np.asarray(density)
    what = "density" if name == "density" else f"'{name}'"
    if d.ndim != 3 or 0 in d.shape or d.dtype.kind not in "fiu":
        raise ExportError(owner, prop, f"{where}: '{name}' must be a non-empty 3-D array of "
                                       f"numbers (nx, ny, nz), x first; it has shape "
                                       f"{d.shape} and type {d.dtype}")
    d = np.ascontiguousarray(d, dtype=np.float32)
    bad = ~np.isfinite(d)
    if bad.any():
        i = tuple(int(x) for x in np.argwhere(bad)[0])
        raise ExportError(owner, prop, f"{where}: {what} at voxel {list(i)} is {d[i]} "
                                       f"({int(bad.sum())} voxel(s) not finite); densities "
                                       f"must be finite numbers >= 0")
    neg = d < 0
    if neg.any():
        i = tuple(int(x) for x in np.argwhere(neg)[0])
        raise ExportError(owner, prop, f"{where}: {what} at voxel {list(i)} is {d[i]:g} "
                                       f"({int(neg.sum())} voxel(s) negative); densities "
                                       f"must be >= 0")
    return d


def npz_arrays(owner: str, file_text: str, fields=()) -> tuple[list[np.ndarray], str]:
    """The checked arrays 'density' and those of the further ``fields`` ((name, property)
    each) of a .npz, and its absolute path. The arrays read of the last file read are kept
    while it is unchanged; an array asked for later is read then."""
    if not file_text.strip():
        raise ExportError(owner, P_GRID_FILE, "is empty: choose the .npz holding the array "
                                              "'density'")
    path = _abspath(file_text)
    try:
        st = path.stat()
    except OSError:
        raise ExportError(owner, P_GRID_FILE, f"{path} does not exist") from None
    key = (str(path), st.st_mtime_ns, st.st_size)
    if key not in _DENSITY_CACHE:
        _DENSITY_CACHE.clear()  # keep one file's arrays: they can be large
    kept = _DENSITY_CACHE.get(key, {})
    wanted = [("density", P_GRID_FILE)] + list(fields)
    missing = [(name, prop) for name, prop in wanted if name not in kept]
    if missing:
        got = {}
        try:
            from photic.safe_io import machine_memory
            from photic.safe_io import check_npz
            memory = machine_memory()
            try:  # headers first: a cut-short file, or one claiming 256 GiB, says so
                check_npz(path, {name for name, _ in missing},
                          None if memory is None else int(0.5 * memory))
            except ValueError as exc:
                if "not a whole .npz" not in str(exc) or path.suffix == ".npz":
                    raise ExportError(owner, P_GRID_FILE, f"cannot read {path}: {exc}") from None
            with np.load(path, allow_pickle=False) as z:
                if not hasattr(z, "files"):
                    raise ValueError("not a .npz archive (save it with "
                                     "numpy.savez(path, density=array))")
                for name, prop in missing:
                    if name not in z.files:
                        has = ", ".join(z.files) or "none"
                        if name == "density":
                            raise ExportError(owner, P_GRID_FILE, f"{path} has no array "
                                                                  f"'density' (it has: {has})")
                        raise ExportError(owner, prop, f"the Density File {path} has no array "
                                                       f"'{name}' (it has: {has}): a further "
                                                       f"field reads the array of its name")
                    got[name] = (z[name], prop)
        except ExportError:
            raise
        except Exception as exc:  # zip, pickle and format errors alike
            raise ExportError(owner, P_GRID_FILE, f"cannot read {path}: {exc}") from None
        for name, (raw, prop) in got.items():
            got[name] = check_density(owner, prop, raw, str(path), name)
        kept = _DENSITY_CACHE.setdefault(key, {})
        kept.update(got)
    return [kept[name] for name, _ in wanted], str(path)


def _world_box(owner: str, box, corners) -> tuple[np.ndarray, np.ndarray]:
    """World bounds of local ``corners`` under the box object's matrix, which must not rotate."""
    m = np.asarray(box.matrix_world, float)
    r = m[:3, :3]
    off = r - np.diag(np.diag(r))
    if np.abs(off).max() > 1e-6 * max(np.abs(r).max(), 1e-30):
        raise ExportError(owner, P_GRID_BOX, f"Object '{box.name}' is rotated: the grid's box "
                                             f"is aligned with the world axes (clear the "
                                             f"rotation and size the box with its scale)")
    world = np.asarray(corners, float) @ r.T + m[:3, 3]
    return world.min(axis=0), world.max(axis=0)


def grid_box(ex, owner: str, box, bounds) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of the grid: the box object's world bounds, else the water body's."""
    if box is None:
        if bounds is None:
            raise ExportError(owner, P_GRID_BOX, "is empty: a water surface has no bounds of "
                                                 "its own; choose an Empty, Volume or mesh "
                                                 "object whose bounds are the grid's box")
        lo, hi = (np.asarray(b, float) for b in bounds)
    elif box.type == "EMPTY":
        s = float(box.empty_display_size)
        lo, hi = _world_box(owner, box, [[x, y, z] for x in (-s, s) for y in (-s, s)
                                         for z in (-s, s)])
    else:
        try:  # modifiers applied; a box hidden from the render is not in the depsgraph
            corners = box.evaluated_get(ex.dg).bound_box
        except (ReferenceError, RuntimeError):
            corners = box.bound_box
        lo, hi = _world_box(owner, box, [tuple(c) for c in corners])
    size = hi - lo
    if not np.all(size > 0):
        axis = "xyz"[int(np.argmin(size))]
        what = f"Object '{box.name}'" if box is not None else "the water body"
        raise ExportError(owner, P_GRID_BOX, f"{what} has no extent along {axis}: the grid's "
                                             f"box needs a size > 0 along every axis")
    return lo, hi


def _volume_key(box, frame: int, depsgraph) -> tuple:
    """What a cached read of a Volume's grid depends on, as far as can be seen without reading
    it: the object and its data, the file the frame reads (path, size, time: of a .vdb
    sequence the frame's own file, as the evaluated Volume chooses it from the sequence
    settings, which are part of the key too), the frame, the object's transform (as
    ``depsgraph`` evaluates it: a render's own depsgraph has it at the frame rendered) and
    modifiers (not their inputs)."""
    volume = box.data
    ev = box.evaluated_get(depsgraph)
    matrix = ev.matrix_world
    path = ""
    if volume.filepath:
        path = ev.data.grids.frame_filepath or bpy.path.abspath(volume.filepath, library=volume.library)
    try:
        st = os.stat(path) if path else None
    except OSError:
        st = None
    file = (path, st.st_size, st.st_mtime_ns) if st else (path,)
    sequence = (volume.is_sequence, volume.frame_start, volume.frame_duration, volume.frame_offset,
                volume.sequence_mode)
    # (session_uid: the same data-blocks, not others of the same names in a file opened since)
    return (box.session_uid, volume.session_uid, frame, file, sequence, tuple(map(tuple, matrix)),
            tuple(box.modifiers.keys()))


# key -> {grid name: (densities, lo, hi) or ExportError}: the reads made on the main thread,
# one entry per Volume and frame holding each grid read of it ('density' and the further
# fields' grids), the newest last. Kept: the last 4, and older ones while all together hold at
# most VOLUME_CACHE_BYTES of densities (an animation read frame by frame); equal densities of
# a grid are stored once.
_VOLUME_CACHE: dict = {}
VOLUME_CACHE_BYTES = 2 << 30


def _cache_bytes() -> int:
    arrays = {id(g[0]): g[0].nbytes for entry in _VOLUME_CACHE.values()
              for g in entry.values() if isinstance(g, tuple)}
    return sum(arrays.values())


def _cache_put(key, entry: dict, fresh) -> None:
    """Keeps ``entry`` (the grids read of one Volume at one frame) as the newest read.
    A grid of ``fresh`` (the names just read) with the same densities as the newest read of
    that grid and shape (a Volume still in time, read frame by frame) is kept once: one
    comparison per grid read, not one per read kept."""
    for name in fresh:
        got = entry[name]
        if not isinstance(got, tuple):
            continue
        d = got[0]
        for other in reversed(list(_VOLUME_CACHE.values())):
            o = other.get(name)
            if isinstance(o, tuple) and o[0].shape == d.shape:
                if np.array_equal(o[0], d):
                    entry[name] = (o[0],) + tuple(got[1:])
                break
    _VOLUME_CACHE.pop(key, None)
    _VOLUME_CACHE[key] = entry
    while len(_VOLUME_CACHE) > 4 and _cache_bytes() > VOLUME_CACHE_BYTES:
        _VOLUME_CACHE.pop(next(iter(_VOLUME_CACHE)))


def volume_grid_names(p) -> dict:
    """{grid name: the property an error about it names} of the grids a water object reads
    from its Volume: 'density' (the Grid Box) and each further field's (its name), in order;
    names ``further_fields`` would refuse are left to the export to name."""
    names = {"density": P_GRID_BOX}
    for i, f in enumerate(p.grid_fields):
        if f.name.strip() and f.name not in names:
            names[f.name] = field_prop(f, i)
    return names


def _npz_headers(path: Path) -> dict:
    """{array name: (shape, dtype)} of a .npz's arrays, from the arrays' headers (no voxels
    read; an array whose header cannot be parsed alone is loaded)."""
    import zipfile
    fmt = np.lib.format
    out = {}
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            if not info.filename.endswith(".npy"):
                continue
            name = info.filename[:-4]
            try:
                with zf.open(info) as f:
                    version = fmt.read_magic(f)
                    read = {(1, 0): fmt.read_array_header_1_0,
                            (2, 0): fmt.read_array_header_2_0}[version]
                    shape, _, dtype = read(f)
            except Exception:  # another format version: load that array
                with np.load(path, allow_pickle=False) as z:
                    a = z[name]
                shape, dtype = a.shape, a.dtype
            out[name] = (tuple(shape), np.dtype(dtype))
    return out


def source_field_names(p, depsgraph) -> tuple[list[str], str]:
    """The names a further density field could read from a water object's grid source, other
    than 'density', in the source's order: the 3-D numeric arrays of the Density File with the
    density's shape, or the float grids of the Grid Box's Volume (its evaluated grids, no voxel
    read); and the source in words. A ValueError says why there is no source to list."""
    if p.grid_source == "NPZ":
        if not p.grid_file.strip():
            raise ValueError("no Density File (.npz) chosen")
        path = _abspath(p.grid_file)
        if not path.is_file():
            raise ValueError(f"the Density File {path} does not exist")
        try:
            headers = _npz_headers(path)
        except Exception as exc:  # not a zip, a damaged archive
            raise ValueError(f"cannot read the Density File {path}: {exc}") from None
        if "density" not in headers:
            raise ValueError(f"the Density File {path} has no array 'density' (it has: "
                             f"{', '.join(headers) or 'none'})")
        shape = headers["density"][0]
        names = [n for n, (s, dt) in headers.items()
                 if n != "density" and s == shape and dt.kind in "iuf"]
        return names, f"the Density File {path.name}"
    box = p.grid_box
    if box is None or box.type != "VOLUME":
        raise ValueError("no Volume object as the Grid Box")
    from . import volume_grid
    _, grids = volume_grid.evaluated_grids(box, depsgraph)
    names = [g.name for g in grids if g.data_type == "FLOAT" and g.name != "density"]
    return list(dict.fromkeys(names)), f"Volume '{box.name}'"


def read_volumes(scene, force: bool = True, keys: list | None = None) -> list:
    """Reads, on Blender's main thread, the 'density' grid and the further density fields'
    grids of every Volume that a water object of ``scene`` (original) takes its grid from,
    into the cache that ``volume_density`` answers from. Before the export walks the
    depsgraph: the read adds and removes a temporary object and re-evaluates. Elsewhere (an F12
    render's thread) it does nothing: the last read stands. A Volume shared by several water
    objects is read once per grid; ``force=False`` keeps the grids of a read whose key (data,
    file, frame, transform, modifiers) still matches (right after loading a file) and reads
    only the grids it lacks. Returns what was read: per water object (water object, Volume,
    the density's voxel counts or the first ExportError among its grids); ``keys`` gets the
    cache keys of the reads made or kept."""
    from . import volume_grid
    done = []
    if not volume_grid.on_main_thread():
        return done
    depsgraph = bpy.context.evaluated_depsgraph_get()  # (evaluated: transforms are current)
    this_call: dict = {}
    for obj in scene.objects:
        p = getattr(obj, "photic", None)
        if (p is None or p.role not in WATER_ROLES or p.iop_variation not in ("GRID", "PROFILE_GRID")
                or p.grid_source != "VOLUME"):
            continue
        box = p.grid_box
        if box is None or box.type != "VOLUME":
            continue  # volume_density names the problem
        owner = _obj(obj.name)
        names = volume_grid_names(p)
        key = _volume_key(box, scene.frame_current, depsgraph)
        entry = this_call.get(key, None if force else _VOLUME_CACHE.get(key))
        if entry is not None and key in _VOLUME_CACHE:
            _VOLUME_CACHE[key] = _VOLUME_CACHE.pop(key)  # (used again: kept longest)
        missing = [name for name in names if entry is None or name not in entry]
        if missing:
            entry = dict(entry or {})
            for name in missing:
                try:
                    raw, index_to_world, i0 = volume_grid.read_volume_grid(box, name)
                    entry[name] = _volume_field(owner, names[name], box, raw, index_to_world,
                                                i0, name)
                except volume_grid.VolumeGridError as exc:
                    entry[name] = ExportError(owner, names[name], str(exc))
            _cache_put(key, entry, missing)
            this_call[key] = entry
        problems = [ExportError(owner, prop, entry[name].message) for name, prop in names.items()
                    if isinstance(entry[name], ExportError)]
        done.append((obj.name, box.name, problems[0] if problems else entry["density"][0].shape))
        if keys is not None:
            keys.append(key)
    return done


def read_volumes_over_frames(scene, frames, progress=None) -> tuple[list, str | None]:
    """``read_volumes`` at each of ``frames`` (main thread; the scene goes back to its frame
    after), so that a render in Blender's interface of those frames (Ctrl+F12), which cannot
    read, finds each frame's grids. Returns what was read and None, or an error message when
    the frames' densities do not fit in what the cache keeps (VOLUME_CACHE_BYTES; a Volume
    unchanged from frame to frame is kept once). ``progress(done, total)`` after each frame."""
    start, keys, done = scene.frame_current, [], []
    frames = list(frames)
    full = False
    try:
        for i, frame in enumerate(frames):
            scene.frame_set(frame)
            done += read_volumes(scene, force=False, keys=keys)
            if progress is not None:
                progress(i + 1, len(frames))
            full = any(k not in _VOLUME_CACHE for k in keys)  # (a frame read is forgotten)
            if full:
                break
    finally:
        scene.frame_set(start)
    if full:
        gb = VOLUME_CACHE_BYTES / 2 ** 30
        return done, (f"the Volume grids of frames {frames[0]}-{frames[-1]} need more than the "
                      f"{gb:g} GB kept for them: render the animation from the command line "
                      f"(blender -b FILE -a, or photic blend per frame), which reads each frame "
                      f"as it renders it")
    return done, None


def _volume_field(owner: str, prop: str, box, raw, index_to_world, i0, name: str = "density"):
    """(densities, lo, hi) of grid ``name`` read from a Volume, or the ExportError saying why
    not (naming ``prop``)."""
    grid = "its grid's voxels are" if name == "density" else f"its grid '{name}' has voxels"
    r = index_to_world[:3, :3]
    if np.abs(r - np.diag(np.diag(r))).max() > 1e-6 * np.abs(r).max():
        return ExportError(owner, prop, f"Volume '{box.name}': {grid} rotated against the "
                                        f"world axes (the grid's box is aligned with them: "
                                        f"clear the rotation)")
    # Voxel centres sit at integer index coordinates: the voxels span +-0.5 around them.
    ends = np.array([i0 - 0.5, i0 + np.array(raw.shape) - 0.5])
    world = np.c_[ends, np.ones(2)] @ index_to_world.T
    lo, hi = world[:, :3].min(axis=0), world[:, :3].max(axis=0)
    # A negative scale runs the voxels backwards along its axis.
    flip = tuple(a for a in range(3) if r[a, a] < 0)
    where = f"Volume '{box.name}'" if name == "density" else f"Volume '{box.name}', grid '{name}'"
    try:
        density = check_density(owner, prop, np.flip(raw, axis=flip) if flip else raw, where,
                                name)
    except ExportError as exc:
        return exc
    return density, lo, hi


def _span(d, lo, hi) -> str:
    xyz = [", ".join(f"{x:g}" for x in v) for v in (lo, hi)]
    return f"{' x '.join(map(str, d.shape))} voxels from ({xyz[0]}) to ({xyz[1]}) m"


def volume_density(ex, owner: str, box, fields=()):
    """Density and world bounds of a Volume object's evaluated 'density' grid, and the
    densities of the grids of the further ``fields`` ((name, property) each) on the same
    voxels: (density, lo, hi, [densities of each field]), as ``read_volumes`` read them before
    the export (geometry nodes, main thread); an F12 render (its own thread) uses the last
    read of the same Volume and frame."""
    if box is None or box.type != "VOLUME":
        name = f"Object '{box.name}' is a {box.type.lower()}" if box is not None else "it is empty"
        raise ExportError(owner, P_GRID_BOX, f"'Volume Object' reads a Volume object's grid, "
                                             f"but {name}: choose a Volume object")
    frame = ex.bscene.frame_current
    entry = _VOLUME_CACHE.get(_volume_key(box, frame, ex.dg))
    if entry is None or "density" not in entry:
        raise ExportError(owner, P_GRID_SOURCE, f"is 'Volume Object': Volume '{box.name}' at "
                                                f"frame {frame} has not been read. Its "
                                                f"voxels are read through geometry nodes on "
                                                f"Blender's main thread, not in an F12 render's: "
                                                f"press 'Read Volume Grids' in the water's "
                                                f"Photic panel (again after changing the Volume "
                                                f"or the frame), or render from the command "
                                                f"line (blender -b FILE -f N or -a, photic "
                                                f"blend), which reads every frame")
    got = []
    for name, prop in [("density", P_GRID_BOX)] + list(fields):
        grid = entry.get(name)
        if grid is None:
            raise ExportError(owner, P_GRID_SOURCE, f"is 'Volume Object': grid '{name}' of "
                                                    f"Volume '{box.name}' at frame {frame} has "
                                                    f"not been read (its field was added or "
                                                    f"renamed since the last read): press 'Read "
                                                    f"Volume Grids' in the water's Photic panel, "
                                                    f"or render from the command line")
        if isinstance(grid, ExportError):
            raise ExportError(owner, prop, grid.message)
        got.append(grid)
    (density, lo, hi), *extra = got
    tol = 1e-6 * float(np.max(hi - lo))
    for (name, prop), (rho, lo_f, hi_f) in zip(fields, extra):
        if rho.shape != density.shape or not (np.allclose(lo_f, lo, rtol=0, atol=tol)
                                              and np.allclose(hi_f, hi, rtol=0, atol=tol)):
            raise ExportError(owner, prop, f"Volume '{box.name}': grid '{name}' spans "
                                           f"{_span(rho, lo_f, hi_f)} but grid 'density' spans "
                                           f"{_span(density, lo, hi)}: every field is on the "
                                           f"grid's voxels (give the grids one voxel size and "
                                           f"transform)")
    return density, lo, hi, [e[0] for e in extra]


@persistent
def _read_volumes_on_load(*_args):
    """After a file is opened (main thread): its water objects' Volume grids, so that an F12
    render right away finds them read. Never raises: what failed is kept and reported by the
    export, naming the object."""
    try:
        read_volumes(bpy.context.scene)
    except Exception as exc:  # noqa: BLE001  (a handler must not break file loading)
        print(f"Photic: reading Volume grids after loading failed: {exc}")


@persistent
def _read_volumes_before_render(scene, *_args):
    """Before each frame a render draws (render_pre): the water objects' Volume grids at that
    frame, where the handler runs on the main thread -- renders from the command line
    (``blender -b file.blend -f N`` or ``-a``) and ``bpy.ops.render.render`` in scripts -- so
    that every frame of an animation finds its grids (a read still current is kept). An F12
    render in the interface calls it from its own thread, where reading does nothing. Never
    raises: the export names what failed."""
    if scene.render.engine != "PHOTIC":
        return
    try:
        read_volumes(scene, force=False)
    except Exception as exc:  # noqa: BLE001  (a handler must not break the render)
        print(f"Photic: reading Volume grids before rendering frame {scene.frame_current} "
              f"failed: {exc}")


_HANDLERS = (("load_post", _read_volumes_on_load), ("render_pre", _read_volumes_before_render))


def register():
    for event, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, event)
        if handler not in handlers:
            handlers.append(handler)


def unregister():
    for event, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, event)
        if handler in handlers:
            handlers.remove(handler)
