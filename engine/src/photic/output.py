"""Files written by a render: multilayer OpenEXR images and radiometer tables (CSV, JSON)."""
from __future__ import annotations

import csv
import itertools
import json
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import __version__
from .render import COMPONENTS, IMAGE_COMPONENTS, RenderResult
from .safe_io import atomic_file, atomic_path, csv_text, json_safe  # noqa: F401  (photic.output.* too)

# What each component pass holds; the components sum to the total (radiance or value).
COMPONENT_DESCRIPTIONS = {
    "beam_surface": "refracted sun from beams on underwater surfaces",
    "beam_volume": "single scattering of beams along traced water segments",
    "path": "everything path tracing finds itself: sky, sun above water, multiple scattering of sky light",
    "beam_direct": "refracted sun reaching the radiometer directly, from the beams in closed form",
    "raman": "light Raman-scattered by water into this band, by the beams or along paths (settings.raman; else 0)",
    "chlorophyll": "light the phytoplankton's chlorophyll fluoresced into this band (a water's chlorophyll_fluorescence; else 0)",
    "cdom": "light the water's CDOM fluoresced into this band (a water's cdom_fluorescence; else 0)",
}


@dataclass
class WriteFailure:
    """An output that could not be written where it belonged: ``path``, why (``reason``), and
    where it was kept instead (``kept``, None when nowhere)."""

    path: Path
    reason: str
    kept: Path | None = None

    def __str__(self) -> str:
        where = (f"kept in {self.kept}" if self.kept is not None else
                 "not kept anywhere (the rescue folder failed too)")
        return f"could not write {self.path}: {self.reason}; {where}"


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return f"{type(exc).__name__}: {exc}"


def _safe(name: str, limit: int = 200) -> str:
    """A name as part of a file name: other characters as '_', at most ``limit`` of them (a
    file name has at most 255 bytes)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)[:limit]


def write_exr(path, result: RenderResult, camera: str) -> Path:
    """One camera as a multilayer EXR: radiance.<band>, variance.<band>, samples and, when the
    result has component passes, beam_surface.<band>, beam_volume.<band>, path.<band> (radiance
    units; they sum to radiance.<band>)."""
    import OpenEXR  # imported late: never needed inside Blender, where Blender writes EXR

    img = result.images[camera]
    channels = {}
    for k, band in enumerate(result.bands):
        channels[f"radiance.{band.name}"] = np.ascontiguousarray(img.mean[..., k], dtype=np.float32)
        channels[f"variance.{band.name}"] = np.ascontiguousarray(img.variance[..., k], dtype=np.float32)
    comps = [c for c in IMAGE_COMPONENTS if c in img.components]
    for c in comps:
        for k, band in enumerate(result.bands):
            channels[f"{c}.{band.name}"] = np.ascontiguousarray(img.components[c][..., k], dtype=np.float32)
    channels["samples"] = (np.full(img.mean.shape[:2], float(img.samples), dtype=np.float32)
                           if img.pixel_samples is None else np.asarray(img.pixel_samples, dtype=np.float32))
    header = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        "photic:version": __version__,
        "photic:scene": result.scene_name,
        "photic:camera": camera,
        "photic:units.radiance": img.units,
        "photic:units.variance": "square of radiance units; variance of the per-pixel mean",
        "photic:bands": json.dumps([{"name": b.name, "center_nm": b.center_nm, "width_nm": b.width_nm}
                                    for b in result.bands]),
        "photic:seed": str(result.stats.get("seed", "")),
    }
    if img.noise_threshold is not None:  # adaptive sampling: samples per pixel vary
        header["photic:noise_threshold"] = float(img.noise_threshold)
        header["photic:pixels_converged"] = float(np.mean(img.converged)) if img.converged is not None else 0.0
    if "integrator" in result.stats:
        header["photic:integrator"] = str(result.stats["integrator"])
    if "forward_cone_deg" in result.stats:
        header["photic:forward_cone_deg"] = float(result.stats["forward_cone_deg"])
    if comps:
        header["photic:components"] = " + ".join(comps) + " = radiance; same units as radiance"
        for c in comps:
            header[f"photic:component.{c}"] = COMPONENT_DESCRIPTIONS[c]
    if getattr(result, "cancelled", False):
        header["photic:cancelled"] = "1: a partial result (the passes finished before the render was stopped)"
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Written beside and renamed: a render killed while writing leaves no truncated file under
    # the final name.
    with atomic_path(path) as tmp:
        with OpenEXR.File(header, channels) as f:
            f.write(str(tmp))
    return path


def check_output_dir(out_dir) -> Path:
    """The output folder, created and tried with a file before a render starts, so that a bad
    ``--out`` (a file, a folder under a file, read-only, a name too long) fails in a second
    with the reason instead of after the render, losing it. OSError with a clear message."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OSError(f"--out {out}: is a file, not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".photic-write-test.{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise OSError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None
    return out


def planned_outputs(out_dir, scene) -> list[Path]:
    """The files ``photic render`` will write for ``scene`` into ``out_dir``."""
    out = Path(out_dir)
    paths = [out / n for n in output_names(scene.name, [c.name for c in scene.cameras]).values()]
    if scene.all_radiometers():
        stem = _safe(scene.name)
        paths += [out / f"{stem}_radiometers.csv", out / f"{stem}_radiometers.json",
                  out / f"{stem}_derived.csv"]
    return paths


def check_output_files(out_dir, scene) -> None:
    """Before a render: each output's destination must be free for a file (a folder of the
    same name made the EXR fail after the render, losing the tables). OSError naming it."""
    for path in planned_outputs(out_dir, scene):
        if path.is_dir():
            raise OSError(f"--out {out_dir}: {path.name} is a folder, but the render writes a "
                          f"file of that name; move or rename the folder")
        if path.exists() and not os.access(path, os.W_OK) and not os.access(path.parent, os.W_OK):
            raise OSError(f"--out {out_dir}: {path.name} exists and cannot be replaced")


def output_names(scene_name: str, cameras) -> dict[str, str]:
    """The EXR file name of each camera, distinct: names that differ only in characters a file
    name cannot keep ('cam€' and 'cam£' both give 'cam_') get a short hash of the name."""
    import hashlib
    base = {c: f"{_safe(scene_name, 100)}_{_safe(c, 100)}" for c in cameras}
    clash = {b for b in base.values() if list(base.values()).count(b) > 1}
    out = {}
    for c, b in base.items():
        if b in clash:
            b += "-" + hashlib.sha1(c.encode("utf-8")).hexdigest()[:8]
        out[c] = b + ".exr"
    return out


NOT_COMPUTED = "not computed: the value or its standard error is not a finite number"


def _computed(r, b: int, k: int) -> bool:
    """Whether bin b, band k has a finite value and standard error (tables never hold NaN or
    inf: a value that cannot be computed is written empty, with a note)."""
    return bool(np.isfinite(r.mean[b, k]) and np.isfinite(r.stderr[b, k]))


def _trusted(r, b: int, k: int) -> bool:
    """Whether the standard error of bin b, band k can be trusted (photic.estimates); never
    where the value is not computed."""
    return _computed(r, b, k) and (r.reliable is None or bool(r.reliable[b, k]))


def _note(r, b: int, k: int) -> str:
    """Why a standard error is not to be trusted ('' when it is)."""
    if not _computed(r, b, k):
        return NOT_COMPUTED
    return "" if _trusted(r, b, k) else "; ".join(r.notes)


def _finite(x) -> float | None:
    """A number for a table: None (empty, null) unless finite."""
    x = float(x)
    return x if np.isfinite(x) else None


def _finite_list(a) -> list:
    """A nested list of an array with None (null) where a value is not finite."""
    a = np.asarray(a, dtype=np.float64)
    if np.isfinite(a).all():
        return a.tolist()
    return np.where(np.isfinite(a), a, None).tolist()


_cell = csv_text


def radiometer_rows(result: RenderResult) -> list[dict]:
    """One row per radiometer, bin and band."""
    return list(iter_radiometer_rows(result))


def iter_radiometer_rows(result: RenderResult):
    """The rows of ``radiometer_rows`` one at a time (a radiance distribution of 10^6 bins
    made a list of dicts of more than 8 GB before the CSV was written)."""
    for r in result.radiometers:
        nbins = r.mean.shape[0]
        for b in range(nbins):
            for k, band in enumerate(result.bands):
                row = {"name": r.name, "quantity": r.quantity,
                       "x_m": r.position[0], "y_m": r.position[1], "z_m": r.position[2],
                       "medium": r.medium, "band": band.name, "center_nm": band.center_nm,
                       "bin": b, "value": _finite(r.mean[b, k]), "stderr": _finite(r.stderr[b, k]),
                       "stderr_trusted": _trusted(r, b, k), "stderr_note": _note(r, b, k),
                       "samples": r.samples, "units": r.units}
                for c in COMPONENTS:
                    if c in r.components:
                        cm, ce = r.components[c]
                        row[f"value_{c}"] = _finite(cm[b, k])
                        row[f"stderr_{c}"] = _finite(ce[b, k])
                if r.bins:
                    ip, ia = divmod(b, r.bins[1])
                    row["polar_deg"] = (ip + 0.5) * 180.0 / r.bins[0]
                    row["azimuth_deg"] = (ia + 0.5) * 360.0 / r.bins[1]
                yield row


def write_radiometer_tables(out_dir, result: RenderResult, stem: str | None = None) -> tuple[Path, Path]:
    """Radiometer values and standard errors as CSV and JSON; returns both paths."""
    return (write_radiometer_csv(out_dir, result, stem),
            write_radiometer_json(out_dir, result, stem))


def write_radiometer_csv(out_dir, result: RenderResult, stem: str | None = None) -> Path:
    """The radiometer table as CSV, one row per radiometer, bin and band; returns its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = stem or _safe(result.scene_name)
    csv_path = out_dir / f"{stem}_radiometers.csv"
    with atomic_file(csv_path, "w", newline="", encoding="utf-8") as f:
        if result.cancelled:
            f.write("# CANCELLED: a partial result (the passes finished before the render was "
                    "stopped; see samples)\n")
        f.write(f"# photic {__version__}; scene {result.scene_name}; seed {result.stats.get('seed')}; "
                f"integrator {result.stats.get('integrator')}; "
                f"forward cone {result.stats.get('forward_cone_deg')} deg; "
                "value = Monte Carlo mean, stderr = its standard error (stderr_trusted False: not to be "
                "trusted, stderr_note says why: too few passes, heavy tails of the samples); "
                "value = " + " + ".join(f"value_{c}" for c in COMPONENTS) + " (" +
                "; ".join(f"{c}: {COMPONENT_DESCRIPTIONS[c]}" for c in COMPONENTS) + ")\n")
        w = csv.writer(f)
        w.writerow(CSV_FIELDS)
        for r in result.radiometers:
            w.writerows(_csv_rows(r, result.bands))
    return csv_path


CSV_FIELDS = ["name", "quantity", "x_m", "y_m", "z_m", "medium", "band", "center_nm", "bin",
              "polar_deg", "azimuth_deg", "value", "stderr", "stderr_trusted", "stderr_note",
              *(f"value_{c}" for c in COMPONENTS), *(f"stderr_{c}" for c in COMPONENTS),
              "samples", "units"]


def _csv_rows(r, bands, chunk: int = 2048):
    """The CSV rows of one radiometer (bins, then bands within a bin), as iter_radiometer_rows
    gives them, built a column at a time for ``chunk`` bins at once: one dict per row took
    ~150 s for 10^6 bins, whole columns of them hold gigabytes."""
    nbins, nb = r.mean.shape

    def numbers(a):  # a column of finite values, '' where not finite
        a = np.asarray(a, dtype=np.float64).ravel()
        out = a.tolist()
        if not np.isfinite(a).all():
            for i in np.flatnonzero(~np.isfinite(a)):
                out[i] = ""
        return out

    computed = np.isfinite(r.mean) & np.isfinite(r.stderr)
    trusted = computed if r.reliable is None else computed & np.asarray(r.reliable, bool)
    note_untrusted, note_missing = _cell("; ".join(r.notes)), _cell(NOT_COMPUTED)
    names, centres = [_cell(band.name) for band in bands], [band.center_nm for band in bands]
    fixed = [_cell(x) for x in (r.name, r.quantity, r.position[0], r.position[1], r.position[2], r.medium)]
    tail = [_cell(r.samples), _cell(r.units)]
    for b0 in range(0, nbins, chunk):
        sl = slice(b0, min(nbins, b0 + chunk))
        k = sl.stop - sl.start
        n = k * nb

        def same(x):
            return itertools.repeat(x, n)

        notes = np.where(trusted[sl], "", np.where(computed[sl], note_untrusted, note_missing))
        b = np.repeat(np.arange(sl.start, sl.stop), nb)
        if r.bins:
            ip, ia = np.divmod(b, r.bins[1])
            polar = ((ip + 0.5) * 180.0 / r.bins[0]).tolist()
            azimuth = ((ia + 0.5) * 360.0 / r.bins[1]).tolist()
        else:
            polar, azimuth = same(""), same("")  # (two: zip draws from each)
        values, errors = [], []
        for c in COMPONENTS:
            if c in r.components:
                cm, ce = r.components[c]
                values.append(numbers(cm[sl]))
                errors.append(numbers(ce[sl]))
            else:
                values.append(same(""))
                errors.append(same(""))
        columns = [*(same(x) for x in fixed), names * k, centres * k, b.tolist(), polar, azimuth,
                   numbers(r.mean[sl]), numbers(r.stderr[sl]), trusted[sl].ravel().tolist(),
                   notes.ravel().tolist(), *values, *errors, *(same(x) for x in tail)]
        yield from zip(*columns)


def write_radiometer_json(out_dir, result: RenderResult, stem: str | None = None) -> Path:
    """The radiometer table as JSON (what photic.derived reads); returns its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = stem or _safe(result.scene_name)
    json_path = out_dir / f"{stem}_radiometers.json"
    doc = {"photic_version": __version__, "scene": result.scene_name,
           "bands": [{"name": b.name, "center_nm": b.center_nm, "width_nm": b.width_nm} for b in result.bands],
           "stats": result.stats, "cancelled": result.cancelled,
           "radiometers": [{"name": r.name, "quantity": r.quantity, "position_m": r.position.tolist(),
                            "medium": r.medium, "units": r.units, "samples": r.samples,
                            "bins": list(r.bins) if r.bins else None,
                            "value": _Array(r.mean), "stderr": _Array(r.stderr),
                            "stderr_trusted": _Array(_trusted_list(r)),
                            "stderr_notes": list(r.notes) + ([NOT_COMPUTED + " (null)"] if not
                                                             np.isfinite(r.mean).all() or not
                                                             np.isfinite(r.stderr).all() else []),
                            **({} if r.target_error is None else
                               {"target_error": r.target_error, "relative_error": r.relative_error,
                                "target_reached": r.target_reached}),
                            "components": {c: {"value": _Array(r.components[c][0]),
                                               "stderr": _Array(r.components[c][1])}
                                           for c in COMPONENTS if c in r.components}}
                           for r in result.radiometers],
           "components": {c: COMPONENT_DESCRIPTIONS[c] for c in COMPONENTS}}
    with atomic_file(json_path, "w", encoding="utf-8") as f:
        _write_json_arrays(f, doc)
    return json_path


class _Array:
    """An array of a JSON table, written one row per line by ``_write_json_arrays`` (a table
    of 10^6 bins as one json.dumps of nested lists took 6 GB and 150 s)."""

    def __init__(self, a):
        self.a = a


def _write_json_arrays(f, doc) -> None:
    """``doc`` as indented JSON into ``f``, its _Array values streamed row by row (null for
    values that are not finite; strict JSON)."""
    arrays: list = []

    def mark(x):
        if isinstance(x, _Array):
            arrays.append(x.a)
            return f"\x00ARRAY{len(arrays) - 1}\x00"
        if isinstance(x, dict):
            return {k: mark(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [mark(v) for v in x]
        return x

    text = json.dumps(json_safe(mark(doc)), indent=1, allow_nan=False)
    parts = re.split(r'"\\u0000ARRAY(\d+)\\u0000"', text)
    f.write(parts[0])
    for i in range(1, len(parts), 2):
        a = arrays[int(parts[i])]
        if a is None:
            f.write("null")
        else:
            a = np.asarray(a)
            f.write("[")
            if a.ndim == 2 and a.dtype.kind == "f" and np.isfinite(a).all():
                # (finite floats: each row as json.dumps writes it, its floats by repr, 4,096 rows
                # at a time, without a json_safe and a dumps per row: 10^6 rows took a minute)
                for j0 in range(0, len(a), 4096):
                    text = ",".join("\n  [" + ", ".join(map(repr, row)) + "]" for row in a[j0:j0 + 4096].tolist())
                    f.write(text if j0 == 0 else "," + text)
            else:
                for j in range(len(a)):
                    f.write(("," if j else "") + "\n  " + json.dumps(json_safe(a[j].tolist()), allow_nan=False))
            f.write("]")
        f.write(parts[i + 1])


def _trusted_list(r):
    """stderr_trusted of the JSON table: None without reliability flags unless a value is not
    computed, False wherever it is not."""
    computed = np.isfinite(r.mean) & np.isfinite(r.stderr)
    if r.reliable is None:
        return None if computed.all() else computed.tolist()
    return (np.asarray(r.reliable, bool) & computed).tolist()


_WRITE_ERRORS = (OSError, ValueError, UnicodeError)  # a full disk, a folder in the way, a name


def write_outputs(out_dir, result: RenderResult, stem: str | None = None,
                  images: bool = True) -> dict[str, list]:
    """Every camera as EXR (unless not ``images``) and the radiometer tables (named after
    ``stem``, default the scene's name); returns the written paths ("images", "tables") and
    the failures ("failed": WriteFailure).

    Each file is written atomically and on its own: one that fails (a full disk, a folder in
    the way) does not stop the others, and is written instead into a private rescue folder in
    the system's temporary folder, which its WriteFailure names (so a finished render is never
    lost to a write)."""
    out_dir = Path(out_dir)
    written: dict[str, list] = {"images": [], "tables": [], "failed": []}
    rescue: list[Path] = []

    def rescue_dir() -> Path:
        if not rescue:
            rescue.append(Path(tempfile.mkdtemp(prefix=f"photic-rescue-{_safe(result.scene_name, 60)}-")))
        return rescue[0]

    def attempt(kind: str, path: Path, write) -> None:
        try:
            got = write(path.parent)
        except _WRITE_ERRORS as exc:
            kept = None
            try:
                kept = write(rescue_dir())
            except _WRITE_ERRORS:
                pass
            for p in (got_paths(kept) if kept is not None else [None]):
                written["failed"].append(WriteFailure(path if p is None else path.parent / p.name,
                                                      _reason(exc), p))
            return
        written[kind].extend(got_paths(got))

    def got_paths(got) -> list[Path]:
        if got is None:
            return []
        return list(got) if isinstance(got, (list, tuple)) else [got]

    names = output_names(result.scene_name, list(result.images)) if images else {}
    for cam in names:
        attempt("images", out_dir / names[cam], lambda d, c=cam: write_exr(d / names[c], result, c))
    if result.radiometers:
        stem = stem or _safe(result.scene_name)
        attempt("tables", out_dir / f"{stem}_radiometers.csv",
                lambda d: write_radiometer_csv(d, result, stem))
        attempt("tables", out_dir / f"{stem}_radiometers.json",
                lambda d: write_radiometer_json(d, result, stem))
        attempt("tables", out_dir / f"{stem}_derived.csv",
                lambda d: write_derived_table(d / f"{stem}_derived.csv", result))
    return written


def write_derived_table(path, result: RenderResult) -> Path | None:
    """Kd, R, mean cosines, Rrs ... that the radiometers allow (photic.derived), as CSV; None
    when there are none."""
    from .derived import DerivedError, derive, write_derived_csv
    try:
        derived = derive(result)
    except DerivedError:
        return None
    if not derived:
        return None
    return write_derived_csv(path, derived, result.bands, f"scene {result.scene_name}")
