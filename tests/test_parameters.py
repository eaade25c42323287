"""Each parameter is declared once (``photic/parameters.py``); the JSON Schema, the engine's
validation, the Blender add-on's property limits and the docs' settings table must agree with
that declaration: this test fails when any of them drifts (issue 29 found the samples range in
five places, ior >= 1 in the engine but [1, 2] in the add-on, a band centre > 0 against
200-3000 nm, beam refinement 0-10 against 0-12)."""
from __future__ import annotations

import json
import re
from importlib import resources
from pathlib import Path

import pytest

from photic.parameters import PARAMETERS, Parameter
from photic.scene import SceneError

from test_scene import valid_dict

DOCS = Path(__file__).resolve().parents[1] / "docs" / "scene-format.md"
SCHEMA_DEFS = {"settings": "settings", "water": "water", "band": "band"}


def schema() -> dict:
    return json.loads(resources.files("photic.schema").joinpath("scene.schema.json").read_text())


def schema_property(p: Parameter) -> dict:
    obj, field = p.key.split(".", 1)
    prop = schema()["$defs"][SCHEMA_DEFS[obj]]["properties"][field]
    if "oneOf" in prop:  # a number or "auto" / null: the number's branch
        prop = dict(next(b for b in prop["oneOf"] if b.get("type") in ("number", "integer")),
                    default=prop.get("default"))
    return prop


@pytest.mark.parametrize("key", sorted(PARAMETERS))
def test_the_schema_agrees_with_the_declaration(key):
    p = PARAMETERS[key]
    prop = schema_property(p)
    assert prop["type"] == ("integer" if p.integer else "number"), prop
    lo = prop.get("exclusiveMinimum" if p.lo_open else "minimum")
    hi = prop.get("exclusiveMaximum" if p.hi_open else "maximum")
    assert (lo, hi) == (p.lo, p.hi), (key, prop)
    if "default" in prop and p.default is not None:
        assert prop["default"] == p.default, (key, prop)


def _document_with(key: str, value):
    d = valid_dict()
    obj, field = key.split(".", 1)
    if obj == "settings":
        d["settings"][field] = value
    elif obj == "water":
        d["water"][0][field] = value
    else:
        d["bands"][0][field] = value
    return d


def _edges(p: Parameter):
    """Values just inside and just outside each finite end of the range."""
    step = 1 if p.integer else None
    out = []
    for end, open_, sign in ((p.lo, p.lo_open, -1), (p.hi, p.hi_open, +1)):
        if end is None:
            continue
        if step is not None:
            inside, outside = end - sign * step, end + sign * step
            inside = end if not open_ else inside
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
    for value, ok in _edges(p):
        if p.integer:
            value = int(value)
        d = _document_with(key, value)
        if ok:
            Scene.from_dict(d)
        else:
            with pytest.raises(SceneError) as e:
                Scene.from_dict(d)
            assert p.field in str(e.value), (key, value, str(e.value))


def test_the_docs_settings_table_gives_the_declared_defaults():
    text = DOCS.read_text()
    rows = dict(re.findall(r"^\| `(\w+)` \| ([^|]+) \|", text, flags=re.M))
    for key, p in PARAMETERS.items():
        if not key.startswith("settings."):
            continue
        shown = rows[p.field].strip().strip("`").strip('"')
        want = "none" if p.default is None else str(p.default)
        assert shown == want, (key, shown, want)
