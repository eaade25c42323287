"""Every input the loader accepts gives finite numbers (issue 49, kind 3): each declared
parameter at the ends of its range (and at 1e30 and 1e300 where it has no upper end) renders
with the hybrid integrator to finite images (in float32, as the EXR holds them) and finite
radiometer values; the JSON tables are strict JSON and no table holds 'nan' or 'inf'. A
value that cannot be computed (Kd where Ed is 0) is written empty, with a note, and never
marked trusted. Ranges that could not give finite numbers were narrowed (sun irradiance and
sky radiance to 1e8, the sun's disk to >= 0.001 degrees, a radiance meter's cap to >= 0.01
degrees)."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photic.output import write_outputs
from photic.parameters import MAX_SOURCE, PARAMETERS
from photic.render import RadiometerResult, RenderResult, render
from photic.scene import Band, Scene, SceneError

from test_parameters import _document_with, _edges

# Too slow or too large for the default suite: 10^6 radiance-distribution bins (kind 6 of the
# issue: its tables) and a 4096 x 4096 wave patch.
SLOW = {("radiometer.azimuth_bins", 1_000_000), ("radiometer.polar_bins", 1_000_000),
        ("surface.resolution", 4096)}


def _accepted_values():
    for key, p in sorted(PARAMETERS.items()):
        values = [v for v, ok in _edges(p) if ok]
        if p.lo == 0.0 and p.lo_open:
            values.append(1e-300)
        if p.hi is None:
            values += [1e30, 1e300]
        for v in values:
            v = int(v) if p.integer else v
            marks = [pytest.mark.slow] if (key, v) in SLOW else []
            yield pytest.param(key, v, marks=marks, id=f"{key}={v!r}")


def _small(d: dict) -> dict:
    d["water"] = d["water"][:1]
    d["settings"].update(integrator="hybrid", threads=1)
    d["cameras"][0]["resolution"] = [8, 6]
    return d


def _strict_json(text: str):
    def refuse(constant):
        raise ValueError(f"{constant} is not JSON")
    return json.loads(text, parse_constant=refuse)


def assert_finite_outputs(res: RenderResult, out_dir) -> None:
    for name, img in res.images.items():
        for what, a in (("mean", img.mean), ("variance", img.variance)):
            a32 = np.asarray(a, np.float32)
            if img.samples < 2 and what == "variance":  # inf: not estimated from one sample
                continue
            assert np.isfinite(a32).all(), (name, what, int((~np.isfinite(a32)).sum()))
    for r in res.radiometers:
        assert np.isfinite(r.mean).all() and np.isfinite(r.stderr).all(), (r.name, r.mean, r.stderr)
    written = write_outputs(out_dir, res)
    for path in written["tables"]:
        text = path.read_text()
        if path.suffix == ".json":
            _strict_json(text)
        low = text.lower()
        assert "nan" not in low.replace("nanomet", "") and "inf" not in low.replace("info", ""), path


@pytest.mark.parametrize("key, value", list(_accepted_values()))
def test_every_accepted_end_of_every_parameter_renders_finite(key, value, tmp_path):
    d = _small(_document_with(key, value))
    res = render(Scene.from_dict(d), samples=2, radiometer_samples=256)
    assert_finite_outputs(res, tmp_path)


def _inside(p, u: float) -> float:
    """A value of parameter ``p`` at fraction ``u`` of its range (log-spaced over wide ranges;
    up to 1e300 where it has no upper end)."""
    lo = p.lo if p.lo is not None else -1e300
    hi = p.hi if p.hi is not None else 1e300
    if lo > 0 and hi / lo > 1e3:
        x = math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo)))
    elif lo == 0 and hi > 1e3:
        x = 0.0 if u == 0 else math.exp(math.log(1e-300) + u * (math.log(hi) - math.log(1e-300)))
    else:
        x = lo + u * (hi - lo)
    x = min(max(x, lo), hi)
    if p.integer:
        x = int(round(x))
    if not p.contains(x):
        return None
    return x


KEYS = sorted(k for k in PARAMETERS if k not in ("radiometer.azimuth_bins", "radiometer.polar_bins",
                                                 "surface.resolution"))


@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
@given(key=st.sampled_from(KEYS), u=st.floats(0.0, 1.0))
def test_any_accepted_value_renders_finite(key, u, tmp_path_factory):
    value = _inside(PARAMETERS[key], u)
    if value is None:
        return
    d = _small(_document_with(key, value))
    try:
        scene = Scene.from_dict(d)
    except SceneError as e:  # a value may clash with another field (the sun's disk with ...)
        pytest.fail(f"{key}={value!r} is in the declared range but refused: {e}")
    res = render(scene, samples=2, radiometer_samples=256)
    assert_finite_outputs(res, tmp_path_factory.mktemp("out"))


def _sun_scene(**sun) -> dict:
    d = _small(_document_with("sun.zenith_deg", 30.0))
    d["sun"].update(sun)
    return d


def test_a_narrow_radiance_meter_gives_finite_values_marked_as_they_are(tmp_path):
    """half_angle_deg 1e-9 gave NaN marked stderr_trusted: now refused below 0.01, and 0.01
    looking down and up (at the sky and the refracted sun) renders finite."""
    d = _sun_scene()
    d["radiometers"].append({"name": "L", "quantity": "radiance", "position": [0, 0, -1],
                             "half_angle_deg": 1e-9})
    with pytest.raises(SceneError, match=r"half_angle_deg.*\[0\.01, 90\]"):
        Scene.from_dict(d)
    d["radiometers"][-1]["half_angle_deg"] = 0.01
    d["radiometers"].append({"name": "L_up", "quantity": "radiance", "position": [0, 0, -1],
                             "direction": [0, 0, 1], "half_angle_deg": 0.01})
    res = render(Scene.from_dict(d), samples=2, radiometer_samples=4096)
    assert_finite_outputs(res, tmp_path)


def test_the_smallest_brightest_sun_in_view_stays_finite_in_the_image(tmp_path):
    """A sun of the largest irradiance and the smallest disk, seen by the camera from above the
    water: its disk's radiance and its square (the variance) fit float32; below the smallest
    disk the loader refuses it (1e-300 made every pixel NaN)."""
    d = _sun_scene(zenith_deg=0.0, angular_diameter_deg=1e-300, irradiance=[MAX_SOURCE] * 2)
    with pytest.raises(SceneError, match="angular_diameter_deg"):
        Scene.from_dict(d)
    d["sun"]["angular_diameter_deg"] = 0.001
    cam = d["cameras"][0]
    cam.update(position=[0, 0, 1], look_at=[0, 0, 2], up=[0, 1, 0], fov_deg=1e-3)
    res = render(Scene.from_dict(d), samples=4, radiometer_samples=256)
    assert res.images["cam"].mean.max() > 1e15  # it does see the disk
    assert_finite_outputs(res, tmp_path)


def test_sky_irradiance_beyond_the_radiance_limit_names_the_field():
    for kind, factor in (("uniform", math.pi), ("cardioidal", 7 * math.pi / 3)):
        d = _small(_document_with("sun.zenith_deg", 30.0))
        d["sky"] = {"type": kind, "irradiance": [1.0, MAX_SOURCE * factor * 1.001]}
        with pytest.raises(SceneError) as e:
            Scene.from_dict(d)
        assert "irradiance[1]" in str(e.value) and "radiance L0 at most" in str(e.value), str(e.value)
        d["sky"]["irradiance"][1] = MAX_SOURCE * factor
        Scene.from_dict(d)


def test_kd_where_ed_is_zero_is_empty_with_a_note(tmp_path):
    """A bottom 0.5 m deep: the profile's Ed below it reads 0 (exactly), so Kd between
    those depths cannot be computed: empty in the CSV, with a note naming the radiometer."""
    d = _small(_document_with("bottom.depth", 0.5))
    res = render(Scene.from_dict(d), samples=1, radiometer_samples=256)
    written = write_outputs(tmp_path, res)
    derived = [p for p in written["tables"] if p.name.endswith("_derived.csv")][0]
    rows = list(csv.DictReader(line for line in derived.read_text().splitlines()
                               if not line.startswith("#")))
    empty = [r for r in rows if r["value"] == ""]
    assert empty, rows
    for r in empty:
        assert r["stderr"] == "" and r["note"].startswith("not computed:") and " is 0 in this band" in r["note"], r
    assert all(r["value"] != "" for r in rows if r["note"] == ""), rows


def test_a_value_that_is_not_finite_is_null_untrusted_and_noted(tmp_path):
    """The writer's last line of defence: a NaN or inf that reached a result is written as
    null (JSON) and empty (CSV), marked not trusted, with a note; the JSON stays strict."""
    mean = np.array([[1.0, np.nan]])
    stderr = np.array([[0.1, 0.2]])
    r = RadiometerResult("E", "Ed", np.zeros(3), "sea", mean, stderr, 64,
                         reliable=np.array([[True, True]]))
    r2 = RadiometerResult("F", "Ed", np.ones(3), "sea", np.array([[2.0, 3.0]]),
                          np.array([[np.inf, 0.1]]), 64)
    res = RenderResult("s", [Band("a", 450.0, 10.0), Band("b", 550.0, 10.0)], radiometers=[r, r2],
                       stats={"seed": 0, "odd": float("nan")})
    csv_path, json_path = write_outputs(tmp_path, res)["tables"][:2]
    doc = _strict_json(json_path.read_text())
    e, f = doc["radiometers"]
    assert e["value"] == [[1.0, None]] and e["stderr_trusted"] == [[True, False]]
    assert any(n.startswith("not computed") for n in e["stderr_notes"])
    assert f["stderr"] == [[None, 0.1]] and f["stderr_trusted"] == [[False, True]]
    assert doc["stats"]["odd"] is None
    rows = list(csv.DictReader(line for line in csv_path.read_text().splitlines()
                               if not line.startswith("#")))
    bad = [row for row in rows if row["stderr_trusted"] == "False"]
    assert len(bad) == 2 and all(row["stderr_note"].startswith("not computed") for row in bad), rows
    assert "nan" not in csv_path.read_text().lower() and "inf" not in csv_path.read_text().lower()
