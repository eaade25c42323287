"""A Photic scene description as Blender objects (File > Import > Photic Scene).

The inverse of ``export``: what it builds exports back to the same scene, up to Blender's
float32 storage of positions and angles (per-band coefficients and reflectances are kept
exactly, as text). The example .blend files are made with it.
"""
from __future__ import annotations

import math
import warnings

import bpy
import numpy as np
from mathutils import Matrix

from . import bands as bandmod
from .nodes import find_node

_ROLE_QUANTITY = {"radiance", "radiance_distribution"}


def _numbers(values) -> str:
    return ", ".join(repr(float(x)) for x in np.atleast_1d(values))


def _rgb(values, bands):
    """RGB for per-band values: (colour scaled to max 1, the max)."""
    values = np.atleast_1d(np.asarray(values, float))
    rgb = values[bandmod.display_indices(bands)] if len(values) > 1 else np.repeat(values, 3)
    top = float(rgb.max())
    return (tuple(rgb / top) if top > 0 else (1.0, 1.0, 1.0)), top


def _look_matrix(position, direction, up) -> Matrix:
    """World matrix of an object looking along ``direction`` (its -Z) with +Y towards ``up``."""
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    u = np.asarray(up, float)
    if np.linalg.norm(np.cross(d, u)) < 1e-9:
        u = np.array([0.0, 1.0, 0.0]) if abs(d[2]) > 0.9 else np.array([0.0, 0.0, 1.0])
    right = np.cross(d, u)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, d)
    m = np.identity(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, -d, position
    return Matrix(m.tolist())


def _mesh_object(name, vertices, triangles, collection):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(np.asarray(vertices, float).tolist(), [], np.asarray(triangles).tolist())
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(obj)
    return obj


# More copies than this are imported as the points of one object with a Geometry Nodes
# modifier (Instance on Points), not as that many objects: 10^5 objects take seconds to make
# and to evaluate, and swamp the Outliner.
POINTS_ABOVE = 100


def _copies(obj, instances, collection) -> None:
    """An instanced mesh's copies as linked duplicates of ``obj`` (one mesh data-block): ``obj``
    is the first, each stands where its transform [R | t] puts it (which exports back as the
    same instanced mesh). Blender keeps an object's transform as location, rotation and scale:
    a sheared transform loses its shear. Above POINTS_ABOVE copies: ``_copies_on_points``."""
    if len(instances) > POINTS_ABOVE:
        _copies_on_points(obj, np.asarray(instances, float), collection)
        return
    objects = [obj] + [obj.copy() for _ in range(len(instances) - 1)]
    for k, (target, rt) in enumerate(zip(objects, np.asarray(instances, float))):
        if k:
            collection.objects.link(target)
        target.matrix_world = Matrix([*rt.tolist(), [0.0, 0.0, 0.0, 1.0]])


def euler_and_scale(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) XYZ Euler angles (rad) and (N, 3) scales with R = Rz Ry Rx diag(scale) for the
    (N, 3, 3) linear parts of transforms, as Instance on Points composes them: the scales are
    the columns' lengths (the first negative where R mirrors), the rotation what is left (a
    shear is lost)."""
    scale = np.linalg.norm(r, axis=1)
    scale[:, 0] *= np.where(np.linalg.det(r) < 0, -1.0, 1.0)
    q = r / scale[:, None, :]
    x = np.arctan2(q[:, 2, 1], q[:, 2, 2])
    y = np.arcsin(np.clip(-q[:, 2, 0], -1.0, 1.0))
    z = np.arctan2(q[:, 1, 0], q[:, 0, 0])
    return np.stack([x, y, z], axis=1), scale


def _new_socket(tree, name: str, in_out: str) -> None:
    if hasattr(tree, "interface"):  # Blender 4+
        tree.interface.new_socket(name=name, in_out=in_out, socket_type="NodeSocketGeometry")
    else:
        (tree.inputs if in_out == "INPUT" else tree.outputs).new("NodeSocketGeometry", name)


def _copies_on_points(obj, instances, collection) -> None:
    """Many copies of ``obj``: a point per copy (at its translation, with its rotation and
    scale as the attributes photic_rotation and photic_scale) on an object named after it,
    whose Geometry Nodes modifier puts an instance of ``obj`` on each point; ``obj`` itself is
    hidden (drawn only through its copies). Exports back as the same instanced mesh."""
    rot, scale = euler_and_scale(instances[:, :, :3])
    points = bpy.data.meshes.new(f"{obj.name} copies")
    points.vertices.add(len(instances))
    points.vertices.foreach_set("co", np.ascontiguousarray(instances[:, :, 3], np.float32).ravel())
    for name, values in (("photic_rotation", rot), ("photic_scale", scale)):
        attribute = points.attributes.new(name, "FLOAT_VECTOR", "POINT")
        attribute.data.foreach_set("vector", np.ascontiguousarray(values, np.float32).ravel())
    carrier = bpy.data.objects.new(f"{obj.name} copies", points)
    collection.objects.link(carrier)
    tree = bpy.data.node_groups.new(f"{obj.name} copies", "GeometryNodeTree")
    _new_socket(tree, "Geometry", "INPUT")
    _new_socket(tree, "Geometry", "OUTPUT")
    n, link = tree.nodes, tree.links.new
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    info = n.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = obj
    info.inputs["As Instance"].default_value = True
    on_points = n.new("GeometryNodeInstanceOnPoints")
    link(next(x for x in gin.outputs if x.name == "Geometry"), on_points.inputs["Points"])
    link(info.outputs["Geometry"], on_points.inputs["Instance"])
    for name, socket in (("photic_rotation", "Rotation"), ("photic_scale", "Scale")):
        read = n.new("GeometryNodeInputNamedAttribute")
        read.data_type = "FLOAT_VECTOR"
        read.inputs["Name"].default_value = name
        link(next(x for x in read.outputs if x.name == "Attribute" and x.type == "VECTOR"),
             on_points.inputs[socket])
    link(on_points.outputs["Instances"], next(x for x in gout.inputs if x.name == "Geometry"))
    carrier.modifiers.new("Photic copies", "NODES").node_group = tree
    obj.hide_viewport = obj.hide_render = True


def _set_bands(props, bands) -> None:
    rgb = [(c, w) for _, c, w in bands]
    if len(bands) == 3 and rgb == [tuple(b) for b in bandmod.RGB_BANDS]:
        props.bands = "RGB"
    elif len(bands) == 1 and bands[0][0] == f"{bands[0][1]:g}":
        props.bands = "SINGLE"
        props.band_center_nm, props.band_width_nm = bands[0][1], bands[0][2]
    else:
        props.bands = "CUSTOM"
        props.custom_bands = ", ".join(f"{c!r}:{w!r}" for _, c, w in bands)
        if [b[0] for b in bands] != [f"{c:g}" for _, c, _ in bands]:
            raise ValueError("band names other than their centre wavelength cannot be kept")


def _material(m, bands):
    mat = bpy.data.materials.new(m.name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    node = find_node(mat, "BSDF_PRINCIPLED")
    colour, top = _rgb(m.reflectance, bands)
    node.inputs["Base Color"].default_value = (*[c * top for c in colour], 1.0)
    mat.diffuse_color = (*[c * top for c in colour], 1.0)
    mat.photic.use_override = True
    mat.photic.reflectance_bands = _numbers(m.reflectance)
    return mat


def _iops_props(p, owner: str, iops, what: str = "") -> None:
    """Coefficients and phase function of one set of IOPs (at most one scattering component)."""
    p.iop_source = "VALUES"
    p.absorption_bands = _numbers(iops.absorption)
    if len(iops.scattering) > 1:
        raise ValueError(f"{owner}: {what}{len(iops.scattering)} scattering components; a "
                         f"Blender water object holds one (give the water an IOP model in "
                         f"Blender instead)")
    if iops.scattering:
        comp = iops.scattering[0]
        p.scattering_bands = _numbers(comp.b)
        _phase_props(p, "", comp.phase)
    else:
        p.scattering_bands = _numbers(np.zeros_like(iops.absorption))


def _phase_props(p, prefix: str, phase) -> None:
    setattr(p, f"{prefix}phase_function", phase.type)
    if phase.type == "henyey_greenstein":
        setattr(p, f"{prefix}hg_g", phase.params["g"])
    elif phase.type == "fournier_forand":
        setattr(p, f"{prefix}ff_backscatter", phase.params["backscatter_fraction"])


def _profile_props(obj, w, profile, level: float, bands) -> None:
    """A profile of layers with one scattering component as a layer table (a Text)."""
    p = obj.photic
    _iops_props(p, f"water '{w.name}'", profile.layers[0], "its profile's layers have ")
    names = [name for name, _, _ in bands]
    lines = ["# Photic layer table: one row per layer top, depth in m below the water level",
             ",".join(["depth_m"] + [f"a_{n}" for n in names] + [f"b_{n}" for n in names])]
    for z, layer in zip(profile.z_top, profile.layers):
        b = layer.scattering[0].b if layer.scattering else np.zeros_like(layer.absorption)
        lines.append(",".join(repr(float(x)) for x in [level - z, *layer.absorption, *b]))
    text = bpy.data.texts.new(f"{w.name} layers")
    text.from_string("\n".join(lines) + "\n")
    p.iop_variation, p.profile_kind, p.profile_table_text = "PROFILE", "TABLE", text


def _grid_props(obj, w, collection, level: float, bands) -> None:
    """A grid with one scattering component and a density file (kept by its path; further
    fields are arrays of it); its box as an Empty; a depth profile as its base as a layer
    table (Depth Profile + 3-D Grid)."""
    g = w.iops
    p = obj.photic
    owner = f"water '{w.name}'"
    if g.file is None:
        raise ValueError(f"{owner}: the grid's densities are given inline; Blender reads them "
                         f"from a .npz: save them with numpy.savez(path, density=array) and "
                         f"give the grid's 'file'")
    layered = hasattr(g.iops, "z_top")  # a depth profile under the grid
    if layered:
        _profile_props(obj, w, g.iops, level, bands)
    else:
        _iops_props(p, owner, g.iops, "its grid's base IOPs have ")
    _unit_props(p, g.unit)
    _field_props(p, owner, g)
    box = bpy.data.objects.new(f"{w.name} grid box", None)
    box.empty_display_type, box.empty_display_size = "CUBE", 1.0
    box.location = tuple(np.asarray(g.origin) + 0.5 * np.asarray(g.size))
    box.scale = tuple(0.5 * np.asarray(g.size))
    collection.objects.link(box)
    p.grid_source, p.grid_file, p.grid_box = "NPZ", g.file, box
    p.iop_variation = "PROFILE_GRID" if layered else "GRID"


def _unit_props(q, unit) -> None:
    """Unit IOPs as coefficients on ``q`` (the object's Photic properties or a further field):
    a scene's unit IOPs are explicit per band (a unit given as a model is evaluated when the
    scene is read), which no IOP model describes; at most one scattering component (the
    base's, checked before)."""
    q.unit_source = "VALUES"
    q.unit_absorption_bands = _numbers(unit.absorption)
    if unit.scattering:
        q.unit_scattering_bands = _numbers(unit.scattering[0].b)
        _phase_props(q, "unit_", unit.scattering[0].phase)
    else:
        q.unit_scattering_bands = _numbers(np.zeros_like(unit.absorption))


def _field_props(p, owner: str, g) -> None:
    """The grid's further density fields as Further Density Fields: each named after its
    array in the grid's .npz (which the add-on reads by the field's name; the engine's own
    name of a field is a label only, and is replaced by its key where they differ), unit IOPs
    as coefficients."""
    p.grid_fields.clear()
    for f in g.extra_fields:
        if f.key is None:
            raise ValueError(f"{owner}: the grid's field '{f.name}' has its densities given "
                             f"inline; Blender reads every field from the grid's .npz by its "
                             f"name: save them in the same file (numpy.savez(path, density=..., "
                             f"{f.name}=...)) and give the field's 'key'")
        if f.key == "density":
            raise ValueError(f"{owner}: the grid's field '{f.name}' reads the array 'density', "
                             f"the first field's; Blender reads a further field from the array "
                             f"of its own name: save it under another name")
        item = p.grid_fields.add()
        item.name = f.key
        _unit_props(item, f.unit)


#: (settings prefix, WaterBody attribute and scene-file field, (property, field) of its values)
_FLUORESCENCE = (("chl", "fluorescence", "chlorophyll_fluorescence",
                  (("chl_quantum_yield", "quantum_yield"), ("chl_emission_peak_nm", "peak_nm"),
                   ("chl_emission_fwhm_nm", "fwhm_nm"))),
                 ("cdom", "cdom_fluorescence", "cdom_fluorescence",
                  (("cdom_efficiency_scale", "efficiency_scale"),)))


def _fluorescence_props(p, w, notes: list) -> None:
    """A water's fluorescence as its Inelastic Light settings. Every water imports with its
    IOPs as coefficients (above), so each absorption that fluoresces becomes a share per band of
    the water's own absorption (of a grid's base); what such a share, or a setting's range,
    cannot hold is added to ``notes``, naming the water and the field."""
    owner = f"water '{w.name}'"
    base = w.iops.iops if hasattr(w.iops, "density") else w.iops
    water_a = np.array([x.absorption for x in getattr(base, "layers", [base])], float)
    for key, attr, fld, values in _FLUORESCENCE:
        f = getattr(w, attr)
        if f is None:
            continue
        setattr(p, f"{key}_fluorescence", True)
        for prop, name in values:
            value = float(getattr(f, name))
            setattr(p, prop, value)
            if not math.isclose(getattr(p, prop), value, rel_tol=1e-6):  # (clamped to its range)
                notes.append(f"{owner}, {fld}.{name}: {value:g} is outside the range of "
                             f"Photic > {p.bl_rna.properties[prop].name}: imported as "
                             f"{getattr(p, prop):g}")
        share = _share(owner, fld, f.absorption, water_a, notes)
        setattr(p, f"{key}_fraction_bands", _numbers(share))


def _share(owner: str, fld: str, absorption, water_a: np.ndarray, notes: list) -> np.ndarray:
    """The share per band of the water's absorption ``water_a`` (one row per layer) that a
    fluorescence's ``absorption`` (one spectrum, or one per layer) is: of all layers' together
    where it differs from layer to layer."""
    a = np.broadcast_to(np.asarray(absorption, float), water_a.shape)
    total = water_a.sum(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(total > 0, a.sum(axis=0) / total, 0.0)
    problems = []
    if np.any((water_a == 0) & (a > 0)):
        problems.append("is above 0 in a band where the water absorbs nothing")
    elif not np.allclose(share * water_a, a, rtol=1e-12, atol=0.0):
        problems.append("is not the same share of the water's absorption in every layer")
    if np.any(share > 1):
        problems.append("is above the water's absorption")
        share = np.minimum(share, 1.0)
    if problems:
        notes.append(f"{owner}, {fld}.absorption: {'; '.join(problems)}, which a share of the "
                     f"water's absorption per band cannot hold: imported as the shares "
                     f"{_numbers(share)}")
    return share


def _water_props(obj, w, level: float, bands, collection) -> None:
    """The water's IOPs (homogeneous, a profile or a grid) and refractive index."""
    if hasattr(w.iops, "z_top"):
        _profile_props(obj, w, w.iops, level, bands)
    elif hasattr(w.iops, "density"):
        _grid_props(obj, w, collection, level, bands)
    else:
        _iops_props(obj.photic, f"water '{w.name}'", w.iops)
    obj.photic.ior = w.ior


def import_scene(scene, bscene=None, collection=None, notes: list | None = None) -> dict:
    """Create the objects of a ``photic.scene.Scene`` in ``bscene`` (default: the context's).

    Returns the created objects by the engine object's name (an instanced mesh's: the first of
    its copies, linked duplicates sharing its mesh data-block). What is imported other than the
    file has it (e.g. a fluorescence whose absorption no share of the water's holds) is added
    to ``notes`` as text naming the object and the field (without a list: Python warnings)."""
    told = [] if notes is None else notes
    bscene = bscene or bpy.context.scene
    collection = collection or bscene.collection
    bands = [(b.name, b.center_nm, b.width_nm) for b in scene.bands]
    props = bscene.photic
    _set_bands(props, bands)
    st = scene.settings
    props.integrator = st.integrator.upper()
    props.samples, props.radiometer_samples, props.seed = st.samples, st.radiometer_samples, st.seed
    props.max_depth, props.threads, props.beam_max_level = st.max_depth, st.threads, st.beam_max_level
    props.raman = "AUTO" if st.raman == "auto" else ("ON" if st.raman else "OFF")
    props.use_target_error = st.target_error is not None
    if st.target_error is not None:
        props.target_error = 100.0 * st.target_error
    props.use_noise_threshold = st.noise_threshold is not None
    if st.noise_threshold is not None:
        props.noise_threshold = 100.0 * st.noise_threshold
    props.adaptive_min_samples = st.adaptive_min_samples
    if st.forward_cone_deg == "auto":
        props.forward_cone = "AUTO"
    else:
        props.forward_cone, props.forward_cone_angle = "ANGLE", math.radians(st.forward_cone_deg)
    bscene.render.engine = "PHOTIC"
    bscene.name = scene.name
    created = {}
    materials = {name: _material(m, bands) for name, m in scene.materials.items()}
    for m in scene.meshes:
        obj = _mesh_object(m.name, m.mesh.vertices, m.mesh.triangles, collection)
        obj.data.materials.append(materials[m.material])
        created[m.name] = obj  # (an instanced mesh: its first copy, which shares the mesh)
        if m.instances is not None:
            _copies(obj, m.instances, collection)
    for w in scene.water:
        if w.type == "mesh":
            obj = _mesh_object(w.name, w.mesh.vertices, w.mesh.triangles, collection)
            obj.photic.role = "WATER_BODY"
        else:
            s = w.surface
            if s.kind == "flat":
                size = 200.0  # only drawn: a flat surface has no end
                v = [(-size, -size, 0), (size, -size, 0), (size, size, 0), (-size, size, 0)]
                obj = _mesh_object(w.name, v, [(0, 1, 2), (0, 2, 3)], collection)
                obj.location.z = s.z
                obj.photic.surface_shape = "FLAT"
            else:  # a patch, given or generated from a wave model
                mesh = s.patch()[0]
                obj = _mesh_object(w.name, mesh.vertices, mesh.triangles, collection)
                obj.photic.surface_shape = "MESH"
            obj.photic.role = "WATER_SURFACE"
            if w.bottom_depth is not None:
                obj.photic.use_bottom = True
                obj.photic.bottom_depth = w.bottom_depth
                obj.photic.bottom_material = materials.get(w.bottom_material)
        # Depths of a profile count from the mean sea level or the top of a body.
        level = float(np.max(w.mesh.vertices[:, 2])) if w.type == "mesh" else float(w.surface.z)
        _water_props(obj, w, level, bands, collection)
        _fluorescence_props(obj.photic, w, told)
        obj.display_type = "WIRE"
        created[w.name] = obj
    if scene.sun is not None:
        sun = scene.sun
        light = bpy.data.lights.new("Sun", "SUN")
        colour, top = _rgb(sun.irradiance, bands)
        light.color, light.energy = colour, top
        # A spectrum that Strength and Color cannot hold (other bands than RGB, or differing
        # within a primary) goes into the per-band irradiance, exactly.
        shown = top * bandmod.rgb_to_bands(colour, bands)
        if not np.allclose(shown, sun.irradiance, rtol=1e-6, atol=0.0):
            light.photic.irradiance_bands = _numbers(sun.irradiance)
        light.angle = math.radians(sun.angular_diameter_deg)
        obj = bpy.data.objects.new("Sun", light)
        obj.rotation_euler = (math.radians(sun.zenith_deg), 0.0, math.radians(sun.azimuth_deg + 90.0))
        obj.location = (0.0, 0.0, 5.0)
        collection.objects.link(obj)
        created["Sun"] = obj
    world = bscene.world or bpy.data.worlds.new("World")
    bscene.world = world
    sky = scene.sky
    if sky.type == "black":
        world.photic.sky_model = "BLACK"
        world.color = (0.0, 0.0, 0.0)
    else:
        colour, top = _rgb(sky.radiance_scale, bands)
        world.photic.sky_model = sky.type.upper()
        world.photic.radiance, world.photic.color = top, colour
        world.color = tuple(c * top for c in colour)
    for i, c in enumerate(scene.cameras):
        data = bpy.data.cameras.new(c.name)
        if c.type == "orthographic":
            data.type = "ORTHO"
            data.ortho_scale = c.ortho_width
        data.sensor_fit = "HORIZONTAL"
        data.sensor_width = 36.0
        data.lens = 18.0 / math.tan(math.radians(c.fov_deg) / 2.0)
        data.shift_x, data.shift_y = c.shift
        data.clip_start = max(c.clip_start, 1e-6)
        data.clip_end = 1e6
        obj = bpy.data.objects.new(c.name, data)
        obj.matrix_world = _look_matrix(c.position, c.direction, c.up)
        collection.objects.link(obj)
        created[c.name] = obj
        if i == 0:
            bscene.camera = obj
            bscene.render.resolution_x, bscene.render.resolution_y = c.resolution
            bscene.render.resolution_percentage = 100
    for r in scene.radiometers:
        obj = bpy.data.objects.new(r.name, None)
        obj.empty_display_type = "SINGLE_ARROW"
        obj.matrix_world = _look_matrix(r.position, r.direction, (0.0, 0.0, 1.0))
        obj.photic.role = "RADIOMETER"
        obj.photic.quantity = r.quantity
        obj.photic.half_angle = math.radians(r.half_angle_deg)
        obj.photic.polar_bins, obj.photic.azimuth_bins = r.polar_bins, r.azimuth_bins
        collection.objects.link(obj)
        created[r.name] = obj
    for a in scene.radiometer_arrays:
        direction = a.direction if a.direction is not None else (0.0, 0.0, -1.0)
        m = _look_matrix((0.0, 0.0, 0.0), direction, (0.0, 1.0, 0.0))
        local = np.asarray(a.positions, float) @ np.array(m.to_3x3().transposed())
        mesh = bpy.data.meshes.new(a.name)
        mesh.from_pydata(local.tolist(), [], [])
        obj = bpy.data.objects.new(a.name, mesh)
        obj.matrix_world = m
        obj.photic.role = "RADIOMETER_ARRAY"
        obj.photic.array_layout = "VERTICES"
        obj.photic.quantities = set(a.quantities)
        if a.half_angle_deg is not None:
            obj.photic.half_angle = math.radians(a.half_angle_deg)
        collection.objects.link(obj)
        created[a.name] = obj
    if notes is None:
        for text in told:
            warnings.warn(f"Photic import: {text}", stacklevel=2)
    return created
