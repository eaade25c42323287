"""What a Blender material's shader nodes mean to Photic, whose surfaces are matte (Lambertian),
optionally textured and emitting.

``analyse(mat)`` follows the material's active Material Output to its surface shader and reads
what Photic renders: the diffuse colour (a value, or an Image Texture on UV coordinates, through
a UV Map and a Mapping node), and emission (colour x strength). Everything else that changes how
the material looks in Cycles or EEVEE -- metallic, transmission, alpha, coat, sheen, subsurface,
glossy roughness, bump and normal maps, displacement, volume shaders, other shader nodes and
nodes between a texture and the colour -- becomes a note that names the material, the node and
what is rendered instead. Nothing here reads pixels (``export_textures``) or knows the engine.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .nodes import node_tree

# Shader nodes rendered as a colour: (node type, colour input).
DIFFUSE_SHADERS = {"BSDF_PRINCIPLED": ("Base Color",), "BSDF_DIFFUSE": ("Color",)}
GLOSSY_ROUGHNESS = 0.2  # below this a Principled BSDF looks glossy: say that its gloss is not rendered


@dataclass
class Shading:
    """A material as Photic renders it."""

    colour: tuple = (0.8, 0.8, 0.8)   # diffuse reflectance RGB (where there is no texture)
    image: object = None              # bpy Image of the diffuse colour, or None
    image_node: str = ""              # the Image Texture node's name
    uv_map: str = ""                  # its UV map ("": the mesh's active render UV map)
    uv_affine: np.ndarray | None = None  # (2, 3): uv' = A [u, v, 1] (a Mapping node), or None
    clamp: bool = False               # the texture's Extension holds its edges (Extend, Clip)
    closest: bool = False             # its Interpolation is Closest (else bilinear)
    emission: tuple | None = None     # emitted radiance RGB (colour x strength), or None
    notes: list = field(default_factory=list)


def _label(node) -> str:
    return f"node '{node.name}' ({node.bl_label})"


def linked(socket):
    """(node, output socket) feeding an input socket, through reroutes; None when unlinked."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        node = link.from_node
        if node.type != "REROUTE":
            return node, link.from_socket
        socket = node.inputs[0] if len(node.inputs) else None
        seen += 1
    return None


def _input(node, *names):
    for n in names:
        s = node.inputs.get(n)
        if s is not None:
            return s
    return None


def _value(socket) -> float:
    try:
        return float(socket.default_value)
    except (TypeError, ValueError):
        return 0.0


def active_output(tree):
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    for targets in (("ALL", "CYCLES"), ("ALL", "CYCLES", "EEVEE")):
        active = [n for n in outputs if n.is_active_output and getattr(n, "target", "ALL") in targets]
        if active:
            return active[0]
    return outputs[0] if outputs else None


def analyse(mat) -> Shading:
    """The Shading of a Blender material (see the module's docstring)."""
    sh = Shading()
    owner = f"Material '{mat.name}'"
    viewport = tuple(float(c) for c in mat.diffuse_color[:3])
    tree = node_tree(mat)
    if tree is None:  # a material without nodes: its viewport colour
        sh.colour = viewport
        return sh
    out = active_output(tree)
    if out is None:
        sh.colour = viewport
        sh.notes.append(f"{owner}: has no Material Output node: rendered as a matte surface of its "
                        f"Viewport Display colour {_rgb(viewport)}")
        return sh
    for socket_name, what in (("Volume", "a volume shader"), ("Displacement", "displacement")):
        src = linked(out.inputs.get(socket_name)) if out.inputs.get(socket_name) is not None else None
        if src is not None:
            sh.notes.append(f"{owner}, {_label(src[0])} into Material Output > {socket_name}: {what} "
                            f"is not rendered by Photic" + (" (apply it with a Displace modifier to render "
                                                              "it)" if socket_name == "Displacement" else ""))
    src = linked(out.inputs.get("Surface"))
    if src is None:
        sh.colour = (0.0, 0.0, 0.0)
        sh.notes.append(f"{owner}: nothing is connected to Material Output > Surface: black, as in Cycles")
        return sh
    shader = src[0]
    if shader.type in ("MIX_SHADER", "ADD_SHADER"):
        inner = _find_upstream(shader, set(DIFFUSE_SHADERS) | {"EMISSION"}, shaders_only=True)
        if inner is not None:
            sh.notes.append(f"{owner}, {_label(shader)}: is not rendered; its input {_label(inner)} is "
                            f"rendered alone")
            shader = inner
    if shader.type in DIFFUSE_SHADERS:
        _diffuse(sh, owner, shader, _input(shader, *DIFFUSE_SHADERS[shader.type]))
        if shader.type == "BSDF_PRINCIPLED":
            _principled_notes(sh, owner, shader)
    elif shader.type == "EMISSION":
        sh.colour = (0.0, 0.0, 0.0)
        _emission(sh, owner, shader, _input(shader, "Color"), _input(shader, "Strength"))
    else:
        sh.colour = viewport
        sh.notes.append(f"{owner}, {_label(shader)}: is not rendered (Photic's surfaces are matte, "
                        f"Lambertian): rendered as a matte surface of the material's Viewport Display "
                        f"colour {_rgb(viewport)}")
    return sh


def _rgb(c) -> str:
    return "(" + ", ".join(f"{x:.3g}" for x in c[:3]) + ")"


def _path_upstream(node, types, shaders_only=False, limit=64) -> list:
    """The nodes from ``node``'s inputs up to the first node of one of ``types`` (breadth first),
    that node last; [] when there is none."""
    queue, seen = [(node, [])], set()
    while queue and len(seen) < limit:
        n, path = queue.pop(0)
        if n.as_pointer() in seen:
            continue
        seen.add(n.as_pointer())
        for s in n.inputs:
            if shaders_only and s.type != "SHADER":
                continue
            src = linked(s)
            if src is None:
                continue
            if src[0].type in types:
                return path + [src[0]]
            queue.append((src[0], path + [src[0]]))
    return []


def _find_upstream(node, types, shaders_only=False):
    """The first node of one of ``types`` upstream of ``node``, or None."""
    path = _path_upstream(node, types, shaders_only)
    return path[-1] if path else None


def _diffuse(sh: Shading, owner: str, shader, socket) -> None:
    """The diffuse colour from a shader's colour input: its value, an Image Texture, an RGB node."""
    sh.colour = tuple(float(c) for c in socket.default_value[:3])
    src = linked(socket)
    if src is None:
        return
    node, out_socket = src
    where = f"{shader.name} > {socket.name}"
    if node.type == "RGB":
        sh.colour = tuple(float(c) for c in out_socket.default_value[:3])
        return
    path = [node] if node.type == "TEX_IMAGE" else [node] + _path_upstream(node, {"TEX_IMAGE"})
    image_node = path[-1] if path[-1].type == "TEX_IMAGE" else None
    if image_node is None:
        sh.notes.append(f"{owner}, {_label(node)} into {where}: is not rendered; the colour is "
                        f"{socket.name}'s own value {_rgb(sh.colour)}")
        return
    if image_node is not node:
        skipped = path[:-1]
        names = ", ".join(f"'{n.name}'" for n in skipped)
        sh.notes.append(f"{owner}, {_label(node)} into {where}: node(s) {names} between Image Texture "
                        f"'{image_node.name}' and {socket.name} are not applied (approximated: the "
                        f"image is used as it is)")
    elif out_socket.name != "Color":
        sh.notes.append(f"{owner}, {_label(node)}: its {out_socket.name} output into {where} is "
                        f"approximated by its Color")
    _image(sh, owner, image_node)


def _image(sh: Shading, owner: str, node) -> None:
    if node.image is None:
        sh.notes.append(f"{owner}, {_label(node)}: has no image: the colour is the Base Color's own "
                        f"value {_rgb(sh.colour)}")
        return
    sh.image, sh.image_node = node.image, node.name
    sh.closest = node.interpolation == "Closest"
    if node.projection != "FLAT":
        sh.notes.append(f"{owner}, {_label(node)}: projection '{node.projection.title()}' is "
                        f"approximated by Flat (UV coordinates)")
    ext = getattr(node, "extension", "REPEAT")
    sh.clamp = ext in ("EXTEND", "CLIP")
    if ext in ("CLIP", "MIRROR"):
        sh.notes.append(f"{owner}, {_label(node)}: Extension '{ext.title()}' is approximated by "
                        f"{'Extend' if ext == 'CLIP' else 'Repeat'}")
    if node.image.source in ("TILED", "SEQUENCE", "MOVIE"):
        sh.notes.append(f"{owner}, {_label(node)}: a {node.image.source.lower()} image: only the "
                        f"pixels Blender holds now (its first tile or current frame) are used")
    vec = node.inputs.get("Vector")
    _uv_source(sh, owner, linked(vec) if vec is not None else None, node)


def _uv_source(sh: Shading, owner: str, src, image_node) -> None:
    """UV map and Mapping transform of an image's Vector input."""
    affine = None
    for _ in range(8):
        if src is None:
            break
        node, out = src
        if node.type == "UVMAP":
            sh.uv_map = node.uv_map
            break
        if node.type == "TEX_COORD":
            if out.name != "UV":
                sh.notes.append(f"{owner}, {_label(node)}: '{out.name}' coordinates into Image Texture "
                                f"'{image_node.name}' are not rendered: the UV map is used instead")
            break
        if node.type == "MAPPING":
            a = _mapping_affine(sh, owner, node)
            affine = a if affine is None else _compose(affine, a)
            src = linked(node.inputs["Vector"])
            continue
        sh.notes.append(f"{owner}, {_label(node)} into Image Texture '{image_node.name}' > Vector: is "
                        f"not rendered: the UV map is used instead")
        break
    sh.uv_affine = affine


def _compose(outer: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """outer(inner(x)) of two (2, 3) affine maps."""
    m = np.eye(3)
    m[:2] = inner
    return outer @ m


def _mapping_affine(sh: Shading, owner: str, node) -> np.ndarray:
    """A Mapping node's transform of (u, v) as a (2, 3) affine map (rotation about Z only)."""
    kind = node.vector_type
    def vec(name, default):
        s = node.inputs.get(name)
        if s is None:
            return np.array(default, float)
        if s.is_linked:
            sh.notes.append(f"{owner}, {_label(node)}: its linked {name} is not rendered (the "
                            f"socket's own value is used)")
        return np.array(s.default_value[:], float)
    loc = vec("Location", (0, 0, 0))
    rot = vec("Rotation", (0, 0, 0))
    scale = vec("Scale", (1, 1, 1))
    if kind == "NORMAL" or abs(rot[0]) > 1e-6 or abs(rot[1]) > 1e-6:
        sh.notes.append(f"{owner}, {_label(node)}: only its rotation about Z is rendered on UV "
                        f"coordinates" if kind != "NORMAL" else
                        f"{owner}, {_label(node)}: type Normal is not rendered on UV coordinates")
    c, s = math.cos(rot[2]), math.sin(rot[2])
    r = np.array([[c, -s], [s, c]])
    sc = np.diag(scale[:2])
    m = np.zeros((2, 3))
    if kind == "TEXTURE":  # the inverse of Point: S^-1 R^-1 (x - L)
        with np.errstate(divide="ignore"):
            inv_s = np.diag([1.0 / x if x != 0 else 0.0 for x in scale[:2]])
        a = inv_s @ r.T
        m[:, :2] = a
        m[:, 2] = -a @ loc[:2]
    else:  # Point: L + R S x; Vector: R S x
        m[:, :2] = r @ sc
        m[:, 2] = loc[:2] if kind == "POINT" else 0.0
    return m


def _principled_notes(sh: Shading, owner: str, node) -> None:
    """Emission, and what of a Principled BSDF a matte surface leaves out."""
    _emission(sh, owner, node, _input(node, "Emission Color", "Emission"), _input(node, "Emission Strength"))
    checks = ((("Metallic",), 0.0, "the metal's reflections are left out; Base Color is used as a "
                                   "matte colour"),
              (("Transmission Weight", "Transmission"), 0.0, "the surface is opaque"),
              (("Coat Weight", "Clearcoat"), 0.0, "the coat's reflections are left out"),
              (("Sheen Weight", "Sheen"), 0.0, "sheen is left out"),
              (("Subsurface Weight", "Subsurface"), 0.0, "light does not enter the surface"))
    for names, default, what in checks:
        s = _input(node, *names)
        if s is None:
            continue
        src = linked(s)
        if src is not None or _value(s) > default + 1e-6:
            v = f"from {_label(src[0])}" if src is not None else f"{_value(s):.3g}"
            sh.notes.append(f"{owner}, {_label(node)}: {s.name} {v} is not rendered ({what})")
    alpha = _input(node, "Alpha")
    if alpha is not None and (linked(alpha) is not None or _value(alpha) < 1.0 - 1e-6):
        sh.notes.append(f"{owner}, {_label(node)}: Alpha is not rendered (the surface is opaque)")
    rough = _input(node, "Roughness")
    if rough is not None:
        src = linked(rough)
        if src is not None or _value(rough) < GLOSSY_ROUGHNESS:
            v = f"from {_label(src[0])}" if src is not None else f"{_value(rough):.3g}"
            sh.notes.append(f"{owner}, {_label(node)}: Roughness {v}: glossy reflections are not "
                            f"rendered (a matte surface of the Base Color)")
    normal = _input(node, "Normal")
    if normal is not None and linked(normal) is not None:
        sh.notes.append(f"{owner}, {_label(node)}: Normal from {_label(linked(normal)[0])} (a bump or "
                        f"normal map) is not rendered: the mesh's own normals are used")


def _emission(sh: Shading, owner: str, node, colour, strength) -> None:
    if colour is None or strength is None:
        return
    k = _value(strength)
    rgb = tuple(float(c) for c in colour.default_value[:3])
    src = linked(colour)
    if linked(strength) is not None:
        sh.notes.append(f"{owner}, {_label(node)}: its linked {strength.name} is not rendered "
                        f"(its own value {k:.3g} is used)")
    if src is not None and k > 0:
        sh.notes.append(f"{owner}, {_label(node)}: {colour.name} from {_label(src[0])} is not "
                        f"rendered: it emits its own value {_rgb(rgb)} x {k:.3g}")
    if k > 0 and max(rgb) > 0:
        sh.emission = tuple(k * c for c in rgb)
