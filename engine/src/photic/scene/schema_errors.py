"""The JSON Schema check of a scene document, its errors translated to SceneErrors naming the
object and the field the way the semantic checks do.
"""
from __future__ import annotations

import difflib
import json
from functools import lru_cache
from importlib import resources
from typing import Any

from .checks import SceneError, _entries, _label, _range_text, _show


# ----------------------------------------------------------------------------------------
# JSON Schema check, with errors translated to SceneError
# ----------------------------------------------------------------------------------------

# Top-level lists whose items are named objects, and the word used for them in messages.
_LIST_KINDS = {"bands": "band", "meshes": "mesh", "water": "water", "cameras": "camera",
               "radiometers": "radiometer", "radiometer_arrays": "radiometer_array"}

_TYPE_WORDS = {"number": "a number", "integer": "an integer", "string": "a string",
               "array": "a list", "object": "an object", "null": "null", "boolean": "true/false"}


@lru_cache(maxsize=1)
def scene_schema() -> dict:
    """The JSON Schema of the scene format (draft 2020-12), as a dict."""
    text = resources.files("photic.schema").joinpath("scene.schema.json").read_text("utf-8")
    return json.loads(text)


@lru_cache(maxsize=1)
def _schema_validator():
    import jsonschema

    return jsonschema.Draft202012Validator(scene_schema())


def _field_text(parts) -> str:
    """``["iops", "absorption", 0]`` -> ``"iops.absorption[0]"``."""
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _locate(doc: dict, parts: list) -> tuple[str, str]:
    """The object label and field for a path in the document."""
    if parts and parts[0] in _LIST_KINDS and len(parts) >= 3 and isinstance(parts[1], int):
        item = doc[parts[0]][parts[1]]
        name = item.get("name") if isinstance(item, dict) else None
        return _label(_LIST_KINDS[parts[0]], name, parts[1]), _field_text(parts[2:])
    if parts and parts[0] == "materials" and len(parts) >= 3:
        return f"material '{parts[1]}'", _field_text(parts[2:])
    if parts and parts[0] in ("sun", "sky", "settings") and len(parts) >= 2:
        return parts[0], _field_text(parts[1:])
    return "scene", _field_text(parts) or "(document)"


def _schema_message(error) -> tuple[list, str]:
    """Path (possibly extended by a key) and message for a jsonschema error."""
    parts = list(error.absolute_path)
    kind, schema, value = error.validator, error.schema, error.instance
    if kind == "required":
        missing = [k for k in error.validator_value if k not in value]
        return parts + missing[:1], "required field is missing"
    if kind == "dependentRequired":
        for key, needed in error.validator_value.items():
            missing = [k for k in needed if key in value and k not in value]
            if missing:
                return parts + missing[:1], f"required together with '{key}'"
    if kind == "additionalProperties" and error.validator_value is False:
        known = list(schema.get("properties", {}))
        unknown = [k for k in value if k not in known]
        hint = difflib.get_close_matches(unknown[0], known, n=1)
        suggestion = f"; did you mean '{hint[0]}'?" if hint else f"; allowed: {', '.join(known)}"
        return parts + unknown[:1], f"unknown key{suggestion}"
    if kind in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        lo = schema.get("minimum", schema.get("exclusiveMinimum"))
        hi = schema.get("maximum", schema.get("exclusiveMaximum"))
        allowed = _range_text(lo, hi, "exclusiveMinimum" in schema,
                              "exclusiveMaximum" in schema, schema.get("type") == "integer")
        return parts, f"must be {allowed}, got {_show(value)}"
    if kind == "type":
        wanted = error.validator_value
        wanted = [wanted] if isinstance(wanted, str) else wanted
        return parts, (f"must be {' or '.join(_TYPE_WORDS.get(w, w) for w in wanted)}, "
                       f"got {_show(value)}")
    if kind == "enum":
        return parts, (f"must be one of {', '.join(map(repr, error.validator_value))}, "
                       f"got {_show(value)}")
    if kind == "const":
        return parts, f"must be {error.validator_value!r}, got {_show(value)}"
    if kind in ("minItems", "maxItems"):
        lo, hi = schema.get("minItems"), schema.get("maxItems")
        if lo == hi:
            count = f"exactly {_entries(lo)}"
        else:
            count = f"at least {_entries(lo)}" if kind == "minItems" else f"at most {_entries(hi)}"
        return parts, f"must have {count}, got {len(value)}"
    if kind == "minLength":
        return parts, "must not be empty"
    if kind == "oneOf" and all(set(sub) == {"required"} for sub in error.validator_value):
        # exactly one of several alternative keys (e.g. 'iops', 'iop_model', 'iop_profile')
        keys = [sub["required"][0] for sub in error.validator_value]
        given = [k for k in keys if isinstance(value, dict) and k in value]
        choice = ", ".join(f"'{k}'" for k in keys)
        if not given:
            return parts + keys[:1], f"required field is missing: give one of {choice}"
        return parts + given[1:2], f"give only one of {choice}, not {' and '.join(map(repr, given))}"
    if kind == "oneOf":
        words = [_alternative_text(sub) for sub in error.validator_value]
        if all(words):  # simple alternatives (a type, a range, a constant): say them all
            return parts, f"must be {', or '.join(words)}, got {_show(value)}"
    return parts, error.message


def _alternative_text(sub: dict) -> str | None:
    """One simple alternative of a oneOf in words ('a finite number in (0, 1)', 'null',
    "'auto'"); None for anything more involved (lists of lists, objects)."""
    if set(sub) == {"const"}:
        c = sub["const"]
        return json.dumps(c) if c is None or isinstance(c, bool) else repr(c)
    t = sub.get("type")
    if t in ("number", "integer") and set(sub) <= {"type", "minimum", "maximum", "exclusiveMinimum",
                                                  "exclusiveMaximum"}:
        lo = sub.get("minimum", sub.get("exclusiveMinimum"))
        hi = sub.get("maximum", sub.get("exclusiveMaximum"))
        return _range_text(lo, hi, "exclusiveMinimum" in sub, "exclusiveMaximum" in sub, t == "integer")
    if isinstance(t, str) and set(sub) == {"type"}:
        return _TYPE_WORDS.get(t, t)
    return None


def _is_index_rows(rows: Any, number_types: tuple) -> bool:
    """True when ``rows`` is a list of 3-lists of the given number types (no bools)."""
    return (isinstance(rows, list)
            and all(type(row) is list and len(row) == 3 for row in rows)
            and {type(x) for row in rows for x in row} <= set(number_types))


def _shorten_mesh_lists(d: dict) -> dict:
    """A copy of ``d`` whose well-formed mesh lists are cut to one row.

    jsonschema takes seconds per 100,000 triangles; well-formed rows are recognised here much
    faster, and anything unusual is left whole for the schema to report precisely.
    """
    def shorten(obj: Any) -> Any:
        if not isinstance(obj, dict):
            return obj
        obj = dict(obj)
        if _is_index_rows(obj.get("vertices"), (int, float)):
            obj["vertices"] = obj["vertices"][:1]
        if _is_index_rows(obj.get("triangles"), (int,)):
            if all(x >= 0 for row in obj["triangles"] for x in row):
                obj["triangles"] = obj["triangles"][:1]
        if "surface" in obj:
            obj["surface"] = shorten(obj["surface"])
        return obj

    d = dict(d)
    for key in ("meshes", "water"):
        if isinstance(d.get(key), list):
            d[key] = [shorten(item) for item in d[key]]
    return d


def _check_schema(d: dict) -> None:
    """Check ``d`` against the JSON Schema; raise the most relevant error as SceneError."""
    import jsonschema

    error = jsonschema.exceptions.best_match(
        _schema_validator().iter_errors(_shorten_mesh_lists(d)))
    if error is not None:
        parts, message = _schema_message(error)
        raise SceneError(*_locate(d, parts), message)


