"""The World as Photic's sky (radiance over the upper hemisphere, in both integrators).

World > Photic Sky chooses: *From World* reads the World's nodes -- a Background's colour x
strength (a uniform sky), an **Environment Texture** (an HDRI, equirectangular: its upper half
becomes the sky's radiance per band, turned by a Mapping node's rotation about Z), or a **Sky
Texture**, approximated by Photic's own clear sky (Harrison & Coombes 1988) for the node's sun
position with the level of World > Photic Sky > Radiance L0; anything else is named in a note
and the Background's own colour is used. Uniform, cardioidal and black skies are the panel's own.
"""
from __future__ import annotations

import math

import numpy as np

from . import bands as bandmod
from .export_textures import ImageProblem, linear_rgb, to_bands
from .export_values import _finite_non_negative, blender_float
from .material_nodes import _label, linked
from .nodes import node_tree

N_THETA, N_PHI = 91, 360  # the sky table's nodes: every degree of zenith angle and azimuth
SUN_SHARE = 0.05   # a sky whose brightest 0.1 % of solid angle holds more than this share ...
SUN_CONTRAST = 50  # ... at this many times its median radiance holds a sun


def sky(ex):
    """The engine's sky from the scene's world (black without one)."""
    S = ex.photic.scene
    world = ex.bscene.world
    if world is None:
        return S.Sky("black")
    p = world.original.photic
    owner = f"World '{world.name}'"
    wid = ("WORLD", world.name)
    if p.sky_model == "BLACK":
        return S.Sky("black")
    if p.sky_model == "FROM_WORLD":
        return _from_world(ex, world, owner, wid)
    l0 = blender_float(p.radiance) * bandmod.rgb_to_bands(
        tuple(blender_float(c) for c in p.color), ex.bands)
    _finite_non_negative(owner, "Photic > Radiance L0 (photic.radiance)", l0, "sky radiance")
    _note_unused_nodes(ex, world, owner, wid, f"World > Photic Sky is '{p.sky_model.title()}'")
    return S.Sky("uniform" if p.sky_model == "UNIFORM" else "cardioidal", l0)


def _output_background(world):
    """The Background node the World's active output shows, or None."""
    tree = node_tree(world)
    if tree is None:
        return None, None
    outs = [n for n in tree.nodes if n.type == "OUTPUT_WORLD"]
    out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
    if out is None:
        return tree, None
    src = linked(out.inputs["Surface"])
    return tree, (src[0] if src is not None else None)


def _note_unused_nodes(ex, world, owner, wid, why):
    _, shader = _output_background(world)
    if shader is None:
        return
    tex = shader if shader.type in ("TEX_SKY", "TEX_ENVIRONMENT") else None
    if shader.type == "BACKGROUND":
        src = linked(shader.inputs["Color"])
        tex = src[0] if src is not None else None
    if tex is not None:
        ex.warn(f"{owner}, {_label(tex)}: is not used because {why} (choose From World to render "
                f"it)", wid)


def _from_world(ex, world, owner, wid):
    S = ex.photic.scene
    tree, shader = _output_background(world)
    colour, strength = tuple(world.color)[:3], 1.0
    if tree is not None and shader is None:
        return S.Sky("black")  # nothing connected to the World Output: black, as in Cycles
    if shader is not None and shader.type != "BACKGROUND":
        ex.warn(f"{owner}, {_label(shader)} into World Output > Surface: is not rendered; the sky is "
                f"black (connect a Background node)", wid)
        return S.Sky("black")
    src = None
    if shader is not None:
        colour = tuple(shader.inputs["Color"].default_value)[:3]
        strength = float(shader.inputs["Strength"].default_value)
        if linked(shader.inputs["Strength"]) is not None:
            ex.warn(f"{owner}, {_label(shader)}: its linked Strength is not rendered (its own value "
                    f"{strength:.3g} is used)", wid)
        src = linked(shader.inputs["Color"])
    if src is not None:
        node = src[0]
        if node.type not in ("TEX_ENVIRONMENT", "TEX_SKY"):
            from .material_nodes import _path_upstream
            path = _path_upstream(node, {"TEX_ENVIRONMENT", "TEX_SKY"})
            if path:
                names = ", ".join(f"'{n.name}'" for n in [node] + path[:-1])
                ex.warn(f"{owner}: node(s) {names} between {_label(path[-1])} and the Background are "
                        f"not applied (approximated: the texture is used as it is)", wid)
                node = path[-1]
        if node.type == "TEX_ENVIRONMENT":
            got = _environment(ex, owner, wid, node, strength)
            if got is not None:
                return got
        elif node.type == "TEX_SKY":
            return _sky_texture(ex, world, owner, wid, node, strength)
        else:
            ex.warn(f"{owner}, {_label(node)} into Background > Color: is not rendered; the sky is "
                    f"uniform with the Background's own colour {tuple(round(c, 3) for c in colour)}",
                    wid)
    l0 = strength * bandmod.rgb_to_bands(colour, ex.bands)
    _finite_non_negative(owner, "Surface > Color x Strength", l0, "sky radiance")
    return S.Sky("uniform", l0) if np.any(l0 > 0) else S.Sky("black")


def _azimuth_offset(ex, owner, wid, node) -> float:
    """Radians the Environment Texture is turned by a Mapping node (rotation about Z) on its
    Vector input (its lookup direction is R d)."""
    vec = node.inputs.get("Vector")
    src = linked(vec) if vec is not None else None
    angle = 0.0
    while src is not None:
        n = src[0]
        if n.type == "MAPPING":
            rot = n.inputs.get("Rotation")
            r = rot.default_value if rot is not None else (0, 0, 0)
            if abs(r[0]) > 1e-6 or abs(r[1]) > 1e-6 or n.vector_type == "NORMAL":
                ex.warn(f"{owner}, {_label(n)}: only its rotation about Z turns the sky", wid)
            angle += -r[2] if n.vector_type == "TEXTURE" else r[2]
            src = linked(n.inputs["Vector"])
            continue
        if n.type == "TEX_COORD" and src[1].name in ("Generated", "Object"):
            break
        ex.warn(f"{owner}, {_label(n)} into {_label(node)} > Vector: is not rendered (the view "
                f"direction is used)", wid)
        break
    return angle


def _environment(ex, owner, wid, node, strength):
    """An Environment Texture's upper half as an 'environment' sky; None (with a note) when its
    image cannot be used."""
    S = ex.photic.scene
    if node.image is None:
        ex.warn(f"{owner}, {_label(node)}: has no image; the sky is uniform with the Background's "
                f"own colour", wid)
        return None
    try:
        rgb, note = linear_rgb(node.image, max_side=4 * N_PHI)
    except ImageProblem as exc:
        ex.warn(f"{owner}, {_label(node)}: {exc}; the sky is uniform with the Background's own "
                f"colour", wid)
        return None
    if note:
        ex.warn(f"{owner}, {_label(node)}: {note}", wid)
    if node.projection != "EQUIRECTANGULAR":
        ex.warn(f"{owner}, {_label(node)}: projection '{node.projection.title()}' is read as "
                f"equirectangular", wid)
    offset = _azimuth_offset(ex, owner, wid, node)
    table = equirect_table(to_bands(rgb, ex.bands), offset)
    table = np.nan_to_num(np.maximum(table, 0.0), nan=0.0, posinf=0.0)
    if not ex.has_ocean:
        ex.warn(f"{owner}, {_label(node)}: its lower half (below the horizon) is not rendered: "
                f"Photic's sky covers the upper hemisphere", wid)
    _sun_in_sky(ex, owner, wid, node, table)
    scale = np.full(len(ex.bands), strength)
    _finite_non_negative(owner, "Background > Strength", scale, "sky radiance")
    return S.Sky("environment", scale, table=table)


def equirect_table(img: np.ndarray, azimuth_offset: float = 0.0) -> np.ndarray:
    """(N_THETA, N_PHI, bands) radiance of an equirectangular image (bottom row first, as
    Blender's pixels) on the sky table's nodes: zenith angle theta_i = i / (N_THETA - 1) 90 deg,
    azimuth phi_j = j / N_PHI 360 deg from +x towards +y. Cycles' mapping: u = 0.5 - phi / 2 pi
    (+x at the image's centre, +y a quarter to the left), v = 1 - theta / pi (the top row is the
    zenith). The image is box-filtered to about the table's resolution, then read bilinearly."""
    h, w = img.shape[:2]
    f = max(1, min(h // (2 * N_THETA), w // N_PHI))
    if f > 1:
        h2, w2 = h // f, w // f
        img = img[:h2 * f, :w2 * f].reshape(h2, f, w2, f, -1).mean(axis=(1, 3))
        h, w = h2, w2
    theta = np.radians(np.linspace(0.0, 90.0, N_THETA))[:, None]
    phi = (np.arange(N_PHI) * (2 * math.pi / N_PHI))[None, :] + azimuth_offset
    u = np.mod(0.5 - phi / (2 * math.pi), 1.0) * w - 0.5
    v = np.clip((1.0 - theta / math.pi) * h - 0.5, 0.0, h - 1.0)
    u, v = np.broadcast_arrays(u, v)
    x0 = np.floor(u).astype(int)
    y0 = np.floor(v).astype(int)
    fx, fy = (u - x0)[..., None], (v - y0)[..., None]
    x0m, x1m = x0 % w, (x0 + 1) % w
    y1 = np.minimum(y0 + 1, h - 1)
    return ((1 - fy) * ((1 - fx) * img[y0, x0m] + fx * img[y0, x1m])
            + fy * ((1 - fx) * img[y1, x0m] + fx * img[y1, x1m])).astype(np.float64)


def _sun_in_sky(ex, owner, wid, node, table):
    """A note when the environment holds a sun: Photic finds sky light only by chance."""
    theta = np.radians(np.linspace(0.0, 90.0, N_THETA))
    weight = np.sin(np.maximum(theta, 1e-3))[:, None] * np.ones((1, N_PHI))
    lum = table.mean(axis=2) * weight
    total = float(lum.sum())
    if not total > 0:
        return
    flat = np.sort(lum.ravel())[::-1]
    top = flat[:max(1, int(0.001 * flat.size))]
    median = float(np.median(table.mean(axis=2)))
    peak = float(table.mean(axis=2).max())
    if float(top.sum()) / total > SUN_SHARE and peak > SUN_CONTRAST * max(median, 1e-30):
        ex.warn(f"{owner}, {_label(node)}: the image holds a sun ({100 * float(top.sum()) / total:.0f} % "
                f"of its light from 0.1 % of the sky): Photic finds sky light only by chance, so it "
                f"renders noisy and makes no caustics; paint the sun out of the image and add a Sun "
                f"lamp in its direction", wid)


def _sky_texture(ex, world, owner, wid, node, strength):
    """A Sky Texture, approximated: Harrison & Coombes' clear sky for the node's sun, with the
    level of World > Photic Sky > Radiance L0 x the Background's Strength."""
    S = ex.photic.scene
    from photic.sky import harrison_coombes, horizontal_irradiance
    kind = node.sky_type
    if kind in ("PREETHAM", "HOSEK_WILKIE"):
        d = np.array(node.sun_direction[:], float)
        d = d / max(np.linalg.norm(d), 1e-12)
        zenith, azimuth = math.degrees(math.acos(np.clip(d[2], -1, 1))), math.degrees(math.atan2(d[1], d[0]))
    else:  # Nishita and the newer scattering skies: elevation and rotation (Cycles: rotation + 90 deg)
        zenith = 90.0 - math.degrees(node.sun_elevation)
        azimuth = math.degrees(node.sun_rotation) + 90.0
    p = world.original.photic
    l0 = blender_float(p.radiance) * strength
    ex.warn(f"{owner}, {_label(node)} ({kind.replace('_', ' ').title()}): approximated by Photic's "
            f"clear sky (Harrison & Coombes 1988) for the node's sun ({zenith:.1f} deg from the "
            f"zenith, azimuth {azimuth % 360:.1f} deg), grey, with radiance L0 = World > Photic Sky > "
            f"Radiance L0 x Strength = {l0:.3g} W m^-2 sr^-1; its colours, sun disc and air, dust "
            f"and ozone settings are not rendered (an Environment Texture renders a sky's own "
            f"radiances)", wid)
    t = np.radians(np.linspace(0.0, 90.0, N_THETA))
    ph = np.arange(N_PHI) * (2 * math.pi / N_PHI)
    tt, pp = np.meshgrid(t, ph, indexing="ij")
    table = harrison_coombes(tt, pp, max(0.0, zenith), azimuth)
    table = table * (math.pi / horizontal_irradiance(table))
    if zenith >= 90.0:
        ex.warn(f"{owner}, {_label(node)}: its sun is below the horizon; the sky's shape is that of "
                f"a sun at the horizon", wid)
    table = np.repeat(table[:, :, None], len(ex.bands), axis=2)
    return S.Sky("environment", np.full(len(ex.bands), l0), table=table)
