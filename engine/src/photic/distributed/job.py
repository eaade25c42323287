"""Job files of ``photic batch``: what to render, expanded into items (one scene each).

A job (JSON, docs/distributed.md) names inputs (scene files, inline scenes or .blend files
with frames), overrides applied to every scene (``set``), swept parameters (``sweep``: their
cartesian product; ``cases``: explicit lists of overrides), sample counts or a target
standard error, and how renders are cut into work units. ``load_job`` checks it and expands
it into :class:`Item` objects: one validated scene per input x frame x case, each with a
fingerprint of everything that decides its numbers (resume trusts a stored unit only when
its fingerprint matches).
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import __version__
from ..render import Renderer
from ..scene import Scene, SceneError

JOB_VERSION = 1
JOB_KEYS = {"photic_job", "name", "inputs", "frames", "set", "sweep", "cases", "samples",
            "radiometer_samples", "seed", "target_rel_stderr", "max_rounds", "units", "threads",
            "retries", "out"}
UNIT_KEYS = {"camera_passes", "radiometer_passes", "tile"}


class JobError(ValueError):
    """An invalid job file: says which entry and why."""


#: Items of one job at most (inputs x frames x cases): each is a render; a sweep or a frame
#: range of 1e9 grew to the memory limit before anything was checked (issue 49).
MAX_ITEMS = 100_000


def _too_many(count: int, what: str) -> None:
    if count > MAX_ITEMS:
        raise JobError(f"{what} gives {count:,} items; a job has at most {MAX_ITEMS:,} (each item "
                       f"is a render): split it into several jobs")


@dataclass
class Item:
    """One scene to render: an input at one frame with one case of the swept parameters."""

    name: str                 # unique within the job, safe as a file name
    scene: Scene              # validated, overrides applied
    source: str               # the input (file path or "inline")
    frame: int | None
    params: dict              # the swept values of this case, {path: value}
    samples: int              # camera samples per pixel
    radiometer_samples: int   # samples per radiometer and round
    seed: int
    integrator: str           # resolved: "hybrid" or "path"
    forward_cone_deg: float   # resolved
    fingerprint: str = ""     # sha256 of the scene and everything that decides the numbers


@dataclass
class Job:
    name: str
    items: list[Item]
    camera_passes: int = 1        # camera passes per unit (1: cameras equal `photic render` bit for bit)
    radiometer_passes: int = 8    # radiometer passes per unit
    tile: int = 0                 # tile size in pixels (0: whole images)
    target_rel_stderr: float | None = None
    max_rounds: int = 16
    threads: int = 0              # core threads per unit (0: decided by the runner)
    retries: int = 2              # Dask retries of a unit that raised
    out: Path | None = None       # default output folder
    path: Path | None = None
    doc: dict = field(default_factory=dict)


# --- overrides: dotted paths into a scene document ---------------------------------------

def _step(container: Any, key: str, path: str, create: bool):
    """The child of ``container`` named by one path segment: a dict key, a list index or
    the ``name`` of a list entry (``water.sea.iops.b``)."""
    if isinstance(container, dict):
        if key not in container and not create:
            raise JobError(f"override '{path}': no '{key}' here (keys: {', '.join(map(str, container))})")
        return key
    if isinstance(container, list):
        if re.fullmatch(r"-?\d+", key):
            i = int(key)
            if not -len(container) <= i < len(container):
                raise JobError(f"override '{path}': index {i} out of range (length {len(container)})")
            return i
        for i, entry in enumerate(container):
            if isinstance(entry, dict) and entry.get("name") == key:
                return i
        raise JobError(f"override '{path}': no entry named '{key}'")
    raise JobError(f"override '{path}': '{key}' goes into a {type(container).__name__}")


def apply_override(doc: dict, path: str, value: Any) -> None:
    """Set ``doc[a][b]...`` for the dotted ``path`` (the last key may be new)."""
    parts = path.split(".")
    node = doc
    for k, key in enumerate(parts):
        last = k == len(parts) - 1
        idx = _step(node, key, path, create=last)
        if last:
            node[idx] = copy.deepcopy(value)
        else:
            node = node[idx]


# --- cases and names ---------------------------------------------------------------------

def _cases(doc: dict) -> list[dict]:
    """The parameter cases: the product of ``sweep`` times each of ``cases`` (default one
    empty case)."""
    sweep = doc.get("sweep") or {}
    if not isinstance(sweep, dict) or not all(isinstance(v, list) and v for v in sweep.values()):
        raise JobError("'sweep' must map override paths to non-empty lists of values")
    keys = list(sweep)
    extra_n = len(doc.get("cases") or [{}]) if isinstance(doc.get("cases") or [{}], list) else 1
    count = extra_n
    for k in keys:
        count *= len(sweep[k])
    _too_many(count, "'sweep' x 'cases' (" + " x ".join(f"{len(sweep[k]):,}" for k in keys) +
              (f" x {extra_n:,}" if extra_n != 1 else "") + ")")
    product = [dict(zip(keys, values)) for values in itertools.product(*(sweep[k] for k in keys))]
    extra = doc.get("cases") or [{}]
    if not isinstance(extra, list) or not all(isinstance(c, dict) for c in extra):
        raise JobError("'cases' must be a list of objects mapping override paths to values")
    return [{**p, **c} for p in product for c in extra]


def _short(value: Any, index: int) -> str:
    if isinstance(value, bool) or value is None:
        return str(value).lower()
    if isinstance(value, (int, float)):
        return f"{value:g}"
    if isinstance(value, str) and len(value) <= 24:
        return value
    return f"#{index}"


def safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=-]+", "_", text).strip("_") or "item"


def _item_name(stem: str, frame: int | None, case: dict, case_values: dict) -> str:
    parts = [stem]
    if frame is not None:
        parts.append(f"f{frame:04d}")
    for key, value in case.items():
        parts.append(f"{key.split('.')[-1]}={_short(value, case_values[key].index(value) if value in case_values[key] else 0)}")
    return safe_name("_".join(parts))


# --- inputs --------------------------------------------------------------------------------

def _frames(spec: Any, where: str) -> list[int] | None:
    if spec is None:
        return None
    if isinstance(spec, list) and spec and all(isinstance(f, int) and not isinstance(f, bool) for f in spec):
        return list(spec)
    if isinstance(spec, dict) and set(spec) <= {"start", "end", "step"} and "start" in spec and "end" in spec:
        if not all(isinstance(spec.get(k, 1), int) and not isinstance(spec.get(k, 1), bool)
                   for k in ("start", "end", "step")):
            raise JobError(f"{where}: 'frames' start, end and step must be integers")
        step = int(spec.get("step", 1))
        if step < 1:
            raise JobError(f"{where}: frame step must be >= 1")
        frames = range(int(spec["start"]), int(spec["end"]) + 1, step)
        _too_many(len(frames), f"{where}: 'frames' {spec['start']}..{spec['end']}")
        return list(frames)
    raise JobError(f"{where}: 'frames' must be a list of integers or {{\"start\", \"end\", \"step\"}}")


def _input_docs(entry: Any, base: Path, job_frames, index: int, export_blend) -> list[tuple]:
    """[(stem, source, frame, scene document, base dir)] of one input entry."""
    where = f"inputs[{index}]"
    if isinstance(entry, str):
        entry = {"blend" if entry.lower().endswith(".blend") else "scene": entry}
    if not isinstance(entry, dict) or len({"scene", "blend"} & set(entry)) != 1:
        raise JobError(f"{where}: must be a path or an object with 'scene' (file or inline "
                       f"scene) or 'blend' (file)")
    unknown = set(entry) - {"scene", "blend", "frames", "name"}
    if unknown:
        raise JobError(f"{where}: unknown keys {sorted(unknown)}")
    if "scene" in entry:
        if "frames" in entry:
            raise JobError(f"{where}: frames apply to .blend inputs only")
        spec = entry["scene"]
        if isinstance(spec, dict):
            return [(entry.get("name") or spec.get("name") or f"scene{index}", "inline", None,
                     copy.deepcopy(spec), base)]
        path = (base / spec).resolve()
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise JobError(f"{where}: cannot read scene {path}: {exc}") from None
        return [(entry.get("name") or path.stem, str(path), None, doc, path.parent)]
    frames = _frames(entry.get("frames", job_frames), where)
    path = (base / entry["blend"]).resolve()
    if not path.is_file():
        raise JobError(f"{where}: no such .blend file: {path}")
    if export_blend is None:
        from .blend import export_blend  # needs bpy: imported only for .blend inputs
    out = []
    for frame, scene in export_blend(path, frames):
        out.append((entry.get("name") or path.stem, str(path), frame if frames is not None else None,
                    scene.to_dict(), path.parent))
    return out


def _positive_int(doc: dict, key: str, default, lo: int = 1):
    value = doc.get(key, default)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise JobError(f"'{key}' must be an integer >= {lo}, got {value!r}")
    return value


def scene_fingerprint(scene: Scene, **extra) -> str:
    """sha256 of the scene's document and the render parameters that decide its numbers."""
    from ..render import COMPONENTS  # (the unit files' layout: units of another one are redone)
    body = json.dumps({"scene": scene.to_dict(), "photic": __version__, "components": COMPONENTS, **extra},
                      sort_keys=True,
                      default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
    return hashlib.sha256(body.encode()).hexdigest()


def make_item(job: Job, name: str, scene: Scene, source: str = "inline", frame: int | None = None,
              params: dict | None = None, samples: int | None = None,
              radiometer_samples: int | None = None, seed: int | None = None) -> Item:
    """An item of ``job`` rendering ``scene`` (sample counts and seed: the scene's unless
    given); raises SceneError for an invalid scene."""
    r = Renderer(scene, samples=samples, radiometer_samples=radiometer_samples, seed=seed)
    item = Item(name, scene, source, frame, dict(params or {}), r.samples, r.radiometer_samples,
                r.seed, r.integrator, r.forward_cone_deg)
    item.fingerprint = scene_fingerprint(
        scene, samples=item.samples, radiometer_samples=item.radiometer_samples, seed=item.seed,
        integrator=item.integrator, cone=item.forward_cone_deg, camera_passes=job.camera_passes,
        radiometer_passes=job.radiometer_passes, tile=job.tile)
    return item


def scene_job(scene: Scene, name: str | None = None, **options) -> Job:
    """A job of one scene, built in Python (the Blender add-on's renders on a scheduler);
    ``options``: Job fields (``tile``, ``camera_passes``, ...)."""
    job = Job(name=safe_name(name or scene.name), items=[], **options)
    job.items.append(make_item(job, job.name, scene))
    return job


def parse_job(doc: dict, base: Path | str = ".", path: Path | None = None, export_blend=None) -> Job:
    """Check a job document and expand its items (``base``: folder of relative paths)."""
    base = Path(base)
    if not isinstance(doc, dict):
        raise JobError("a job must be a JSON object")
    if doc.get("photic_job") != JOB_VERSION:
        raise JobError(f"'photic_job' must be {JOB_VERSION} (the job format version)")
    unknown = set(doc) - JOB_KEYS
    if unknown:
        raise JobError(f"unknown keys {sorted(unknown)} (known: {sorted(JOB_KEYS)})")
    inputs = doc.get("inputs")
    if not isinstance(inputs, list) or not inputs:
        raise JobError("'inputs' must be a non-empty list of scene files, inline scenes or .blend files")
    units = doc.get("units") or {}
    if not isinstance(units, dict) or set(units) - UNIT_KEYS:
        raise JobError(f"'units' takes {sorted(UNIT_KEYS)}")
    target = doc.get("target_rel_stderr")
    if target is not None and (isinstance(target, bool) or not isinstance(target, (int, float))
                               or not 0 < target < 1):
        raise JobError("'target_rel_stderr' must be a number in (0, 1), e.g. 0.01 for 1%")
    overrides = doc.get("set") or {}
    if not isinstance(overrides, dict):
        raise JobError("'set' must map override paths to values")
    cases = _cases(doc)
    case_values = {k: list(v) for k, v in (doc.get("sweep") or {}).items()}
    for c in doc.get("cases") or []:
        for k, v in c.items():
            case_values.setdefault(k, []).append(v)
    samples = _positive_int(doc, "samples", None)
    rad_samples = _positive_int(doc, "radiometer_samples", None)
    seed = _positive_int(doc, "seed", None, lo=0)
    job = Job(name=safe_name(str(doc.get("name") or (path.stem if path else "job"))), items=[],
              camera_passes=_positive_int(units, "camera_passes", 1),
              radiometer_passes=_positive_int(units, "radiometer_passes", 8),
              tile=_positive_int(units, "tile", 0, lo=0),
              target_rel_stderr=None if target is None else float(target),
              max_rounds=_positive_int(doc, "max_rounds", 16),
              threads=_positive_int(doc, "threads", 0, lo=0),
              retries=_positive_int(doc, "retries", 2, lo=0),
              out=(base / doc["out"]) if doc.get("out") else None, path=path, doc=doc)
    names: dict[str, int] = {}
    if isinstance(inputs, list):
        _too_many(len(inputs) * len(cases), f"{len(inputs):,} inputs x {len(cases):,} cases")
    for i, entry in enumerate(inputs):
        for stem, source, frame, scene_doc, scene_base in _input_docs(entry, base, doc.get("frames"), i,
                                                                     export_blend):
            _too_many(len(job.items) + len(cases), "the inputs, frames and cases together")
            for case in cases:
                d = copy.deepcopy(scene_doc)
                for key, value in {**overrides, **case}.items():
                    apply_override(d, key, value)
                name = _item_name(stem, frame, case, case_values)
                if name in names:  # two inputs with one stem: number the later ones
                    names[name] += 1
                    name = f"{name}-{names[name]}"
                else:
                    names[name] = 1
                try:
                    scene = Scene.from_dict(d, base_dir=scene_base)
                    job.items.append(make_item(job, name, scene, source, frame, case, samples,
                                               rad_samples, seed))
                except SceneError as exc:
                    raise JobError(f"item {name}: invalid scene: {exc}") from None
    if job.target_rel_stderr is not None and not any(it.scene.all_radiometers() for it in job.items):
        raise JobError("'target_rel_stderr' applies to radiometers, and no scene has one")
    return job


def load_job(path, export_blend=None) -> Job:
    """Read, check and expand a job file (relative paths are relative to its folder)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise JobError(f"cannot read job {path}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise JobError(f"job {path}: invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    return parse_job(doc, path.resolve().parent, path, export_blend)


def item_target(job: Job, item: Item) -> float | None:
    """The relative standard error an item's rounds aim at: the job's ``target_rel_stderr``,
    else the item's scene's ``settings.target_error`` (a scene rendered from Blender or a scene
    file with its own target); None: one round."""
    if job.target_rel_stderr is not None:
        return job.target_rel_stderr
    return item.scene.settings.target_error if item.scene.all_radiometers() else None


def rounds_needed(done_rounds: int, worst_rel_stderr: float, target: float, max_rounds: int) -> int:
    """Rounds to add so that the worst relative standard error reaches ``target`` (it falls
    as 1/sqrt(rounds)); 0 when it has or ``max_rounds`` is reached."""
    if worst_rel_stderr <= target or done_rounds >= max_rounds:
        return 0
    total = math.ceil(done_rounds * (worst_rel_stderr / target) ** 2)
    return max(1, min(total, max_rounds) - done_rounds)
