"""Each parameter is declared once (``photic/parameters.py``); the JSON Schema, the engine's
validation, the Blender add-on's property limits and the docs' tables must agree with that
declaration: this test fails when any of them drifts (issue 29 found the samples range in
five places, ior >= 1 in the engine but [1, 2] in the add-on, a band centre > 0 against
200-3000 nm, beam refinement 0-10 against 0-12, a Fournier-Forand backscatter fraction up to
0.5 in the add-on against 0.15 in the engine, Henyey-Greenstein g in (-1, 1) in the schema
against [-0.9999, 0.9999], and sizes, depths and bins the engine bounds but the schema and the
add-on did not)."""
from __future__ import annotations

import json
import re
from importlib import resources
from pathlib import Path

import pytest

from photic.parameters import PAIR, PARAMETERS, PER_BAND, Parameter
from photic.scene import SceneError

from test_scene import valid_dict

DOCS = Path(__file__).resolve().parents[1] / "docs" / "scene-format.md"


def schema() -> dict:
    return json.loads(resources.files("photic.schema").joinpath("scene.schema.json").read_text())


def _resolve(s: dict, prop: dict) -> dict:
    """A property with its ``$ref`` (to one of ``$defs``) merged in, its own keys winning."""
    if "$ref" in prop:
        target = s["$defs"][prop["$ref"].rsplit("/", 1)[1]]
        prop = {**target, **{k: v for k, v in prop.items() if k != "$ref"}}
    return prop


def schema_property(p: Parameter) -> dict:
    """The schema's number (or integer) for parameter ``p``: the property at ``p.key`` under
    ``$defs`` (``surface.roughness.wind_speed``: the surface's roughness' wind_speed), its
    items for a pair or a per-band list."""
    s = schema()
    prop = s["$defs"][p.object]
    for part in p.field.split("."):
        prop = _resolve(s, prop["properties"][part])
    if "oneOf" in prop:  # a number or "auto" / null: the number's branch
        prop = dict(next(b for b in prop["oneOf"] if b.get("type") in ("number", "integer")),
                    default=prop.get("default"))
    if p.shape == PER_BAND:  # a list of numbers, or one number for every band: both agree
        item = prop["items"]
        assert (prop.get("minimum"), prop.get("maximum")) == (item.get("minimum"), item.get("maximum")), prop
        return dict(item, default=prop.get("default"))
    if p.shape == PAIR:
        assert (prop["minItems"], prop["maxItems"]) == (2, 2), prop
        return dict(prop["items"], default=prop.get("default"))
    return prop


@pytest.mark.parametrize("key", sorted(PARAMETERS))
def test_the_schema_agrees_with_the_declaration(key):
    p = PARAMETERS[key]
    prop = schema_property(p)
    assert prop["type"] == ("integer" if p.integer else "number"), prop
    lo = prop.get("exclusiveMinimum" if p.lo_open else "minimum")
    hi = prop.get("exclusiveMaximum" if p.hi_open else "maximum")
    assert (lo, hi) == (p.lo, p.hi), (key, prop)
    other_ends = {"exclusiveMinimum" if not p.lo_open else "minimum",
                  "exclusiveMaximum" if not p.hi_open else "maximum"}
    assert not other_ends & prop.keys(), (key, prop)
    if prop.get("default") is not None and p.default is not None:
        assert prop["default"] == p.default, (key, prop)


def _patch_surface(period: float) -> dict:
    """A flat square patch of side ``period`` (m) at z = 0, centred on the origin."""
    h = period / 2
    v = [[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]]
    return {"kind": "patch", "vertices": v, "triangles": [[0, 1, 2], [0, 2, 3]],
            "period": [period, period]}


def _document_with(key: str, value):
    """The test scene (tests/test_scene.py) with parameter ``key`` set to ``value`` (every
    band's or both entries' for a per-band list or a pair) where the scene format has it."""
    p = PARAMETERS[key]
    value = [value, value] if p.shape in (PER_BAND, PAIR) else value
    d = valid_dict()
    sea = d["water"][0]
    scattering = sea["iops"]["scattering"]
    obj, field = p.object, p.field
    if obj == "settings":
        d["settings"][field] = value
    elif obj == "band":
        d["bands"][0][field] = value
    elif obj == "material":
        d["materials"]["sand"][field] = value
    elif obj == "water":
        sea[field] = value
    elif obj == "iops":
        sea["iops"][field] = value
    elif obj == "scattering_component":
        scattering[0][field] = value
    elif obj == "phase":  # the test scene's Henyey-Greenstein and Fournier-Forand components
        scattering[2 if field == "g" else 3]["phase"][field] = value
    elif obj == "bottom":
        sea["bottom"][field] = value
    elif key == "surface.period":
        sea["surface"] = _patch_surface(value[0])
    elif key == "surface.roughness.wind_speed":
        sea["surface"]["roughness"] = {"wind_speed": value}
    elif obj == "surface" and field == "z":
        sea["surface"]["z"] = value
    elif obj == "surface":  # a wave model; a calm one unless the field needs wind
        sea["surface"] = {"kind": "waves", "spectrum": "flat", field: value}
        if field == "fetch_m":
            sea["surface"].update(spectrum="jonswap", wind_speed=5.0)
    elif obj == "sun":
        d["sun"][field] = value
    elif obj == "sky":
        d["sky"] = {"type": "harrison_coombes", "irradiance": [0.3, 0.2], field: value} \
            if field == "cloud_fraction" else {"type": "uniform", field: value}
    elif obj == "camera":
        camera = d["cameras"][0]
        if field == "ortho_width":
            camera["type"] = "orthographic"
        if field == "filter.width_px":
            camera["filter"]["width_px"] = value
        else:
            camera[field] = value
    elif obj == "radiometer":  # a radiance distribution, whose other bins count is 1
        d["radiometers"].append({"name": "L", "quantity": "radiance_distribution",
                                 "position": [0, 0, -1], "polar_bins": 1, "azimuth_bins": 1,
                                 field: value})
    else:
        raise AssertionError(f"the test does not know where {key} goes in a scene")
    return d


def _edges(p: Parameter):
    """Values just inside and just outside each finite end of the range."""
    out = []
    for end, open_, sign in ((p.lo, p.lo_open, -1), (p.hi, p.hi_open, +1)):
        if end is None:
            continue
        if p.integer:
            inside, outside = (end - sign if open_ else end), end + sign
        else:
            d = max(abs(end) * 1e-9, 1e-12)
            inside = end - sign * d if open_ else end
            outside = end if open_ else end + sign * max(abs(end) * 1e-6, 1e-9)
        out.append((inside, True))
        out.append((outside, False))
    return out


@pytest.mark.parametrize("key", sorted(PARAMETERS))
def test_the_loader_accepts_the_range_and_refuses_beyond_it(key):
    """Through the whole loader (schema and validation): the ends of the declared range are
    accepted, values just beyond them refused with a SceneError naming the field."""
    from photic.scene import Scene
    p = PARAMETERS[key]
    assert _edges(p), f"{key} declares no range to check"
    for value, ok in _edges(p):
        if p.integer:
            value = int(value)
        d = _document_with(key, value)
        if ok:
            Scene.from_dict(d)
        else:
            with pytest.raises(SceneError) as e:
                Scene.from_dict(d)
            assert p.name in str(e.value), (key, value, str(e.value))


def _optional(p: Parameter) -> bool:
    """Whether the schema lets the field out (a band's centre is required: its 550 nm is
    the default band's)."""
    return p.name not in schema()["$defs"][p.object].get("required", ())


@pytest.mark.parametrize("key", sorted(k for k, p in PARAMETERS.items()
                                       if p.default is not None and _optional(p)))
def test_the_loader_fills_in_the_declared_default(key):
    """A scene without the field gets the declared default."""
    from photic.scene import Scene
    p = PARAMETERS[key]
    d = _document_with(key, p.default[0] if p.shape == PAIR else p.default)
    _holder(d, key).pop(p.name)  # the field absent: the scene holds the reader's default
    got = _scene_value(Scene.from_dict(d), key)
    assert got == (tuple(p.default) if p.shape == PAIR else p.default), (key, got)


def _holder(d: dict, key: str) -> dict:
    """The dict of ``_document_with``'s document that holds ``key``'s field."""
    p = PARAMETERS[key]
    return {"settings": lambda: d["settings"], "band": lambda: d["bands"][0],
            "water": lambda: d["water"][0], "surface": lambda: d["water"][0]["surface"],
            "sun": lambda: d["sun"], "sky": lambda: d["sky"], "camera": lambda: d["cameras"][0],
            "radiometer": lambda: d["radiometers"][-1]}[p.object]()


def _scene_value(scene, key: str):
    p = PARAMETERS[key]
    if p.object == "settings":
        return getattr(scene.settings, p.field)
    if p.object == "band":
        return getattr(scene.bands[0], p.field)
    if p.object == "water":
        return getattr(scene.water[0], p.field)
    if p.object == "surface":
        surface = scene.water[0].surface
        return getattr(surface, p.field) if p.field == "z" else getattr(surface.waves, p.field)
    if p.object == "sun":
        return getattr(scene.sun, p.field)
    if p.object == "sky":
        return getattr(scene.sky, p.field)
    if p.object == "camera":
        return getattr(scene.cameras[0], p.field)
    return getattr(scene.radiometers[-1], p.field)


def _docs_rows(heading: str) -> dict[str, str]:
    """``{key: second column}`` of the first table after the markdown ``heading``."""
    text = DOCS.read_text()
    start = text.index(heading)
    table = re.search(r"((?:^\|.*\n)+)", text[start:], flags=re.M).group(1)
    return dict(re.findall(r"^\| `(\w+)` \| ([^|]+) \|", table, flags=re.M))


def _shown(p: Parameter) -> str:
    if p.default is None:
        return "none"
    if isinstance(p.default, list):
        return "[" + ", ".join(f"{x:g}" for x in p.default) + "]"
    return p.default if isinstance(p.default, str) else f"{p.default:g}"


def test_the_docs_settings_table_gives_the_declared_defaults():
    rows = _docs_rows("## settings")
    for key, p in PARAMETERS.items():
        if key.startswith("settings."):
            assert rows[p.field].strip().strip("`").strip('"') == _shown(p), (key, rows[p.field])


def test_the_docs_waves_table_gives_the_declared_defaults():
    rows = _docs_rows('### surface kind "waves"')
    checked = 0
    for key, p in PARAMETERS.items():
        if p.object == "surface" and p.field in rows and p.default is not None:
            assert rows[p.field].strip() == _shown(p), (key, rows[p.field])
            checked += 1
    assert checked >= 7, checked


def test_the_docs_phase_table_gives_the_declared_ranges():
    """The phase functions' table shows each parameter as `name` in RANGE."""
    text = DOCS.read_text()
    for key in ("phase.g", "phase.backscatter_fraction"):
        p = PARAMETERS[key]
        assert f"`{p.name}` in {p.range_text()} |" in text, (key, p.range_text())


def test_the_coordinate_limit_is_the_positions_one():
    from photic import parameters
    from photic.scene import checks
    assert parameters.MAX_COORDINATE_M == checks.MAX_COORDINATE_M
