"""Derived quantities from radiometer values: K (diffuse attenuation), R, Rrs and mean cosines,
each with a first-order (linear) propagated standard error.

Sources are a ``RenderResult`` or the radiometer JSON table that ``photic render`` writes
(``<scene>_radiometers.json``, see ``output.write_radiometer_tables``). See
docs/derived-quantities.md for the definitions, the conventions and the assumptions.

Conventions
-----------
- Depth is ``d = -z`` in metres (the engine's z points up; positive depth is below z = 0).
- ``K = -d ln E / d d``: positive when E decreases downwards, for every quantity (Kd, Ku, Ko,
  ...), as in Mobley (1994). Between two depths ``d1 < d2``:
  ``K = -ln(E(d2) / E(d1)) / (d2 - d1)``.
- Errors: every radiometer is an independent estimate (Photic draws each radiometer's random
  numbers from its own stream). Quantities that share samples, such as two components of one
  radiometer or two bands of one radiometer, are correlated and are not combined here.
"""
from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

UNITS_K = "m^-1"
UNITS_RATIO = "1 (dimensionless)"
UNITS_RRS = "sr^-1"
K_NAMES = {"Ed": "Kd", "Eu": "Ku", "Eo": "Ko", "Eod": "Kod", "Eou": "Kou", "radiance": "KL"}
POSITION_DECIMALS = 6  # positions equal to 1 micrometre match
_ARRAY_NAME = re.compile(r"^(?P<array>.*)\[(?P<index>\d+)\]\.(?P<quantity>\w+)$")


class DerivedError(ValueError):
    """A table that cannot be read, or radiometers that do not fit a formula."""


@dataclass(eq=False)
class Reading:
    """One radiometer's values: ``value`` and ``stderr`` per band (radiance distributions,
    which have several bins, are left out of the tables derived here)."""

    name: str
    quantity: str
    position: np.ndarray       # (3,) m, z up
    medium: str                # "air" or the water body's name
    value: np.ndarray          # (nbands,)
    stderr: np.ndarray         # (nbands,)
    units: str = ""

    @property
    def depth(self) -> float:
        """-z in metres (positive below z = 0)."""
        return -float(self.position[2])


@dataclass(eq=False)
class Derived:
    """A derived quantity per band with its standard error, units and the radiometers used."""

    name: str
    quantity: str              # Kd, Ku, Ko, Kod, Kou, KL (+ "_fit"), R, Rrs, Rrs_uncorrected, mu_d, mu_u, mu
    value: np.ndarray          # (nbands,)
    stderr: np.ndarray         # (nbands,)
    units: str
    sources: tuple[str, ...]
    medium: str
    position: np.ndarray       # (3,): the radiometer's; for K the top of the depth range
    depths: tuple[float, float] | None = None   # (top, bottom) depth range in m, for K
    note: str = ""
    extra: dict = field(default_factory=dict)   # name -> (nbands,) array, e.g. chi2_dof of a fit
    # Why the value of a band is not computed (NaN inside, empty in the tables): band -> text.
    missing: dict = field(default_factory=dict)

    def why_missing(self, k: int) -> str:
        """The note of a band whose value (or standard error) is not a finite number."""
        return self.missing.get(k) or "not computed: not a finite number"


def _not_positive(readings, role: str = "") -> dict:
    """{band: note} where any of ``readings`` is not > 0 (K takes their logarithm; a ratio
    divides by them)."""
    out = {}
    for r in readings:
        for k, v in enumerate(np.asarray(r.value, float).tolist()):
            if not v > 0 and k not in out:
                out[k] = (f"not computed: {r.name} ({r.quantity}{role}) is {v:g} in this band"
                          + (" (no light reaches it)" if v == 0 else ""))
    return out


@dataclass(eq=False)
class RadiometerTable:
    """The single-valued radiometers of one render, and its bands (name, centre nm)."""

    scene: str
    bands: list[tuple[str, float]]
    readings: list[Reading]
    cancelled: bool = False

    def reading(self, name: str) -> Reading:
        for r in self.readings:
            if r.name == name:
                return r
        raise DerivedError(f"no radiometer named {name!r} in the table of scene {self.scene!r} "
                           f"(radiance distributions are left out)")


# --- reading the sources ------------------------------------------------------------------

def load_table(source) -> RadiometerTable:
    """A ``RadiometerTable`` from a ``RenderResult``, a radiometer JSON document (dict) or the
    path of one (``<scene>_radiometers.json``)."""
    if isinstance(source, RadiometerTable):
        return source
    if isinstance(source, (str, Path)):
        path = Path(source)
        try:
            doc = json.loads(path.read_text())
        except json.JSONDecodeError as e:
            raise DerivedError(f"{path} is not JSON: {e}") from None
        return _from_json(doc, str(path))
    if isinstance(source, dict):
        return _from_json(source, "the radiometer table")
    if hasattr(source, "radiometers") and hasattr(source, "bands"):
        return _from_result(source)
    raise DerivedError(f"cannot read radiometers from a {type(source).__name__}")


def _from_result(result) -> RadiometerTable:
    readings = [Reading(r.name, r.quantity, np.asarray(r.position, float), r.medium,
                        np.asarray(r.mean, float)[0].copy(), np.asarray(r.stderr, float)[0].copy(), r.units)
                for r in result.radiometers if not r.bins and np.asarray(r.mean).shape[0] == 1]
    bands = [(b.name, float(b.center_nm)) for b in result.bands]
    return RadiometerTable(result.scene_name, bands, readings, bool(getattr(result, "cancelled", False)))


def _from_json(doc: dict, what: str) -> RadiometerTable:
    if not isinstance(doc, dict) or "radiometers" not in doc or "bands" not in doc:
        raise DerivedError(f"{what} is not a Photic radiometer table (it needs 'bands' and "
                           f"'radiometers', as in <scene>_radiometers.json)")
    try:
        bands = [(str(b["name"]), float(b["center_nm"])) for b in doc["bands"]]
        readings = []
        for r in doc["radiometers"]:
            value, stderr = np.asarray(r["value"], float), np.asarray(r["stderr"], float)
            if r.get("bins") or value.shape[0] != 1:
                continue
            if value.shape != (1, len(bands)) or stderr.shape != value.shape:
                raise DerivedError(f"{what}: radiometer {r['name']!r} has values of shape "
                                   f"{value.shape} for {len(bands)} bands")
            readings.append(Reading(str(r["name"]), str(r["quantity"]), np.asarray(r["position_m"], float),
                                    str(r["medium"]), value[0], stderr[0], str(r.get("units", ""))))
    except (KeyError, TypeError, ValueError) as e:
        if isinstance(e, DerivedError):
            raise
        raise DerivedError(f"{what}: malformed radiometer entry ({type(e).__name__}: {e})") from None
    return RadiometerTable(str(doc.get("scene", "")), bands, readings, bool(doc.get("cancelled", False)))


def _resolve(table: RadiometerTable | None, r) -> Reading:
    if isinstance(r, Reading):
        return r
    if table is None:
        raise DerivedError(f"radiometer {r!r} named without a table")
    return table.reading(str(r))


def _pos_key(p) -> tuple:
    return tuple(round(float(c), POSITION_DECIMALS) + 0.0 for c in p)


# --- formulas -----------------------------------------------------------------------------

def _rel2(r: Reading) -> np.ndarray:
    """(stderr / value)^2, NaN where the value is not positive."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r.value > 0, (r.stderr / r.value) ** 2, np.nan)


def _check_quantity(r: Reading, allowed, role: str) -> None:
    if r.quantity not in allowed:
        raise DerivedError(f"{role}: radiometer {r.name!r} measures {r.quantity}, expected "
                           + " or ".join(sorted(allowed)))


def attenuation(r1, r2, table: RadiometerTable | None = None) -> Derived:
    """K = -ln(E(d2) / E(d1)) / (d2 - d1) between two radiometers of one quantity (depth
    d = -z, d1 < d2 after ordering), with
    stderr^2 = ((s1 / E1)^2 + (s2 / E2)^2) / (d2 - d1)^2 (independent radiometers).
    NaN in bands where either value is not positive."""
    a, b = _resolve(table, r1), _resolve(table, r2)
    if a.quantity != b.quantity:
        raise DerivedError(f"K: {a.name!r} measures {a.quantity} but {b.name!r} measures {b.quantity}")
    _check_quantity(a, K_NAMES, "K")
    if a.depth > b.depth:
        a, b = b, a
    dz = b.depth - a.depth
    if not dz > 0:
        raise DerivedError(f"K: {a.name!r} and {b.name!r} are at the same depth ({a.depth:g} m)")
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = (a.value > 0) & (b.value > 0)
        value = np.where(ok, -np.log(b.value / a.value) / dz, np.nan)
        err = np.sqrt(_rel2(a) + _rel2(b)) / dz
    q = K_NAMES[a.quantity]
    return Derived(f"{q}({a.name}, {b.name})", q, value, err, UNITS_K, (a.name, b.name), a.medium,
                   a.position.copy(), (a.depth, b.depth), missing=_not_positive((a, b)))


def attenuation_fit(readings, table: RadiometerTable | None = None) -> Derived:
    """K from a least-squares line through ln E against depth over a profile (three or more
    radiometers of one quantity): ln E_i = c - K d_i.

    Each band is weighted by 1 / var(ln E_i) = (E_i / s_i)^2; when any s_i is 0 the fit is
    unweighted. K is a linear combination sum c_i ln E_i, so stderr^2 = sum c_i^2 (s_i / E_i)^2
    (the weights taken as exact). ``extra['chi2_dof']``: sum of squared residuals in units of
    their standard errors over n - 2 (weighted fits, n > 2): much more than 1 means ln E is
    not a straight line within the Monte Carlo noise (K varies with depth), which stderr does
    not include."""
    rs = sorted((_resolve(table, r) for r in readings), key=lambda r: r.depth)
    if len(rs) < 2:
        raise DerivedError("K fit: needs at least two radiometers")
    qs = {r.quantity for r in rs}
    if len(qs) != 1:
        raise DerivedError(f"K fit: radiometers of different quantities {sorted(qs)}")
    _check_quantity(rs[0], K_NAMES, "K fit")
    d = np.array([r.depth for r in rs])
    if np.ptp(d) <= 0:
        raise DerivedError("K fit: all radiometers are at the same depth")
    nb = rs[0].value.shape[0]
    value, err, chi2 = np.full(nb, np.nan), np.full(nb, np.nan), np.full(nb, np.nan)
    for k in range(nb):
        e = np.array([r.value[k] for r in rs])
        s = np.array([r.stderr[k] for r in rs])
        if not np.all(e > 0):
            continue
        y, var = np.log(e), (s / e) ** 2
        weighted = bool(np.all(var > 0))
        w = 1.0 / var if weighted else np.ones_like(var)
        dm = np.sum(w * d) / np.sum(w)
        c = w * (d - dm) / np.sum(w * (d - dm) ** 2)   # slope = sum c_i y_i
        slope = float(np.sum(c * y))
        value[k] = -slope
        err[k] = float(np.sqrt(np.sum(c * c * var)))
        if weighted and len(rs) > 2:
            intercept = np.sum(w * y) / np.sum(w) - slope * dm
            chi2[k] = float(np.sum(w * (y - intercept - slope * d) ** 2) / (len(rs) - 2))
    q = K_NAMES[rs[0].quantity] + "_fit"
    return Derived(f"{q}({rs[0].name} .. {rs[-1].name}, {len(rs)} depths)", q, value, err, UNITS_K,
                   tuple(r.name for r in rs), rs[0].medium, rs[0].position.copy(), (d[0], d[-1]),
                   extra={"chi2_dof": chi2}, missing=_not_positive(rs))


def _ratio(num: Reading, den: Reading):
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.where(den.value != 0, num.value / np.where(den.value != 0, den.value, 1.0), np.nan)
        err = np.sqrt((num.stderr / den.value) ** 2 + (value * den.stderr / den.value) ** 2)
    return value, err


def _ratio_quantity(quantity: str, num, den, num_q: str, den_q: str, table, at_num: bool) -> Derived:
    """num / den with a first-order error, both radiometers checked for their quantity; the
    position and medium reported are the numerator's (``at_num``) or the denominator's."""
    n, d = _resolve(table, num), _resolve(table, den)
    _check_quantity(n, {num_q}, f"{quantity} numerator")
    _check_quantity(d, {den_q}, f"{quantity} denominator")
    value, err = _ratio(n, d)
    at = n if at_num else d
    missing = {k: f"not computed: the denominator {d.name} ({d.quantity}) is 0 in this band"
               for k, v in enumerate(np.asarray(d.value, float).tolist()) if v == 0}
    return Derived(f"{quantity}({n.name}, {d.name})", quantity, value, err, UNITS_RATIO,
                   (n.name, d.name), at.medium, at.position.copy(), missing=missing)


def irradiance_reflectance(eu, ed, table: RadiometerTable | None = None) -> Derived:
    """R = Eu / Ed; stderr^2 = (s_u / Ed)^2 + (R s_d / Ed)^2."""
    return _ratio_quantity("R", eu, ed, "Eu", "Ed", table, at_num=False)


def mean_cosine_down(ed, eod, table: RadiometerTable | None = None) -> Derived:
    """mu_d = Ed / Eod (first-order error as for a ratio)."""
    return _ratio_quantity("mu_d", ed, eod, "Ed", "Eod", table, at_num=True)


def mean_cosine_up(eu, eou, table: RadiometerTable | None = None) -> Derived:
    """mu_u = Eu / Eou (positive, as Ed / Eod)."""
    return _ratio_quantity("mu_u", eu, eou, "Eu", "Eou", table, at_num=True)


def mean_cosine(ed, eu, eo=None, eod=None, eou=None, table: RadiometerTable | None = None) -> Derived:
    """mu = (Ed - Eu) / Eo, with Eo from an Eo radiometer or else Eod + Eou.

    stderr^2 = (s_d^2 + s_u^2) / Eo^2 + (mu s_o / Eo)^2."""
    d, u = _resolve(table, ed), _resolve(table, eu)
    _check_quantity(d, {"Ed"}, "mu (Ed)")
    _check_quantity(u, {"Eu"}, "mu (Eu)")
    if eo is not None:
        o = _resolve(table, eo)
        _check_quantity(o, {"Eo"}, "mu (Eo)")
        eo_v, eo_s, names = o.value, o.stderr, (o.name,)
    elif eod is not None and eou is not None:
        od, ou = _resolve(table, eod), _resolve(table, eou)
        _check_quantity(od, {"Eod"}, "mu (Eod)")
        _check_quantity(ou, {"Eou"}, "mu (Eou)")
        eo_v, eo_s, names = od.value + ou.value, np.hypot(od.stderr, ou.stderr), (od.name, ou.name)
    else:
        raise DerivedError("mu: needs Eo, or Eod and Eou")
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.where(eo_v != 0, (d.value - u.value) / np.where(eo_v != 0, eo_v, 1.0), np.nan)
        err = np.sqrt((d.stderr ** 2 + u.stderr ** 2) / eo_v ** 2 + (value * eo_s / eo_v) ** 2)
    sources = (d.name, u.name, *names)
    missing = {k: f"not computed: Eo ({' + '.join(names)}) is 0 in this band"
               for k, v in enumerate(np.asarray(eo_v, float).tolist()) if v == 0}
    return Derived(f"mu({', '.join(sources)})", "mu", value, err, UNITS_RATIO, sources, d.medium,
                   d.position.copy(), missing=missing)


def remote_sensing_reflectance(lu, ed, sky=None, rho: float | None = None, reflected=None,
                               table: RadiometerTable | None = None) -> Derived:
    """Rrs = Lw / Ed(0+) in sr^-1, from a radiance radiometer above the water looking down
    (``lu``, i.e. L_u(0+)) and a downwelling irradiance radiometer above the water (``ed``).

    Lw, the water-leaving radiance, is L_u(0+) less the radiance reflected by the surface:
    - ``reflected``: a radiance radiometer whose value is that reflected radiance (for example
      the same L_u(0+) radiometer in a render of the scene with black, fully absorbing water):
      Lw = Lu - L_reflected;
    - ``sky`` and ``rho``: a radiance radiometer looking at the sky in the direction that the
      surface reflects into the sensor, and the surface reflectance factor (Fresnel
      reflectance of a flat surface, or an empirical rho such as Mobley's 0.028):
      Lw = Lu - rho L_sky;
    - neither: Lw = Lu(0+), quantity ``Rrs_uncorrected``, which equals Rrs only when no sky
      or sun light is reflected into the sensor (black sky, and no sun glint in view).
    stderr^2 = (s_u^2 + rho^2 s_sky^2) / Ed^2 + (Rrs s_d / Ed)^2 (rho exact).
    """
    u, d = _resolve(table, lu), _resolve(table, ed)
    _check_quantity(u, {"radiance"}, "Rrs (Lu)")
    _check_quantity(d, {"Ed"}, "Rrs (Ed)")
    for r, role in ((u, "Lu(0+)"), (d, "Ed(0+)")):
        if r.medium != "air":
            raise DerivedError(f"Rrs: {role} radiometer {r.name!r} is in {r.medium}, not above the water")
    lw, lw_var, sources, note = u.value, u.stderr ** 2, [u.name, d.name], ""
    if reflected is not None and sky is not None:
        raise DerivedError("Rrs: give either a reflected-radiance radiometer or a sky radiometer and rho, not both")
    if reflected is not None:
        f = _resolve(table, reflected)
        _check_quantity(f, {"radiance"}, "Rrs (reflected radiance)")
        lw, lw_var = u.value - f.value, lw_var + f.stderr ** 2
        sources.append(f.name)
        note = f"Lw = {u.name} - {f.name}"
    elif sky is not None:
        if rho is None:
            raise DerivedError("Rrs: a sky radiometer needs the surface reflectance factor rho")
        s = _resolve(table, sky)
        _check_quantity(s, {"radiance"}, "Rrs (sky radiance)")
        rho = float(rho)
        lw, lw_var = u.value - rho * s.value, lw_var + (rho * s.stderr) ** 2
        sources.append(s.name)
        note = f"Lw = {u.name} - {rho:g} {s.name}"
    elif rho is not None:
        raise DerivedError("Rrs: rho needs a sky radiometer")
    else:
        note = f"Lw = {u.name}: surface-reflected sky and sun not removed"
    q = "Rrs" if len(sources) > 2 else "Rrs_uncorrected"
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.where(d.value != 0, lw / np.where(d.value != 0, d.value, 1.0), np.nan)
        err = np.sqrt(lw_var / d.value ** 2 + (value * d.stderr / d.value) ** 2)
    missing = {k: f"not computed: Ed(0+) {d.name} is 0 in this band"
               for k, v in enumerate(np.asarray(d.value, float).tolist()) if v == 0}
    return Derived(f"{q}({', '.join(sources)})", q, value, err, UNITS_RRS, tuple(sources), "air",
                   u.position.copy(), note=note, missing=missing)


# --- matching radiometers -----------------------------------------------------------------

def profiles(table: RadiometerTable) -> list[list[Reading]]:
    """Vertical profiles in water, each sorted by depth: irradiance radiometers of one quantity
    and medium at the same x, y; radiance radiometers only within one radiometer array
    (``NAME[i].radiance``: an array shares one viewing direction, which the tables do not
    record). Radiometers at a depth already in the profile are left out."""
    groups: dict[tuple, list[Reading]] = {}
    for r in table.readings:
        if r.medium == "air" or r.quantity not in K_NAMES:
            continue
        xy = _pos_key(r.position)[:2]
        if r.quantity == "radiance":
            m = _ARRAY_NAME.match(r.name)
            if not m:
                continue
            key = ("array", m["array"], r.medium, xy)
        else:
            key = ("position", r.quantity, r.medium, xy)
        groups.setdefault(key, []).append(r)
    out = []
    for rs in groups.values():
        rs = sorted(rs, key=lambda r: r.depth)
        kept = [rs[0]]
        for r in rs[1:]:
            if round(r.depth - kept[-1].depth, POSITION_DECIMALS) > 0:
                kept.append(r)
        if len(kept) >= 2:
            out.append(kept)
    return out


def _same_place(table: RadiometerTable) -> dict[tuple, dict[str, list[Reading]]]:
    places: dict[tuple, dict[str, list[Reading]]] = {}
    for r in table.readings:
        places.setdefault((r.medium, _pos_key(r.position)), {}).setdefault(r.quantity, []).append(r)
    return places


def auto_rrs_pairs(table: RadiometerTable) -> list[tuple[Reading, Reading]]:
    """(Lu, Ed) pairs for Rrs: every radiance radiometer in air with the lowest Ed radiometer
    in air at the same x, y. The tables do not record viewing directions: a radiance radiometer
    in air is taken to look down (the engine's default direction); name the radiometers
    explicitly when it does not."""
    eds: dict[tuple, Reading] = {}
    for r in table.readings:
        if r.medium == "air" and r.quantity == "Ed":
            xy = _pos_key(r.position)[:2]
            if xy not in eds or r.position[2] < eds[xy].position[2]:
                eds[xy] = r
    return [(r, eds[_pos_key(r.position)[:2]]) for r in table.readings
            if r.medium == "air" and r.quantity == "radiance" and _pos_key(r.position)[:2] in eds]


def derive(source, rrs: list[dict] | None = None, fit: bool = True) -> list[Derived]:
    """Every derived quantity the radiometers allow, matched by position, medium and quantity:

    - K between consecutive depths of each profile (``profiles``) and, for three or more
      depths, the least-squares K over the profile (``fit``);
    - R = Eu / Ed, mu_d = Ed / Eod, mu_u = Eu / Eou and mu = (Ed - Eu) / Eo (Eo or Eod + Eou)
      from radiometers at the same position and medium;
    - Rrs: from ``rrs``, a list of dicts with keys lu, ed and optionally sky and rho, or
      reflected (radiometer names; see ``remote_sensing_reflectance``); without it, every
      pair of ``auto_rrs_pairs`` as Rrs_uncorrected.
    """
    table = load_table(source)
    out: list[Derived] = []
    for prof in profiles(table):
        out += [attenuation(a, b) for a, b in zip(prof[:-1], prof[1:])]
        if fit and len(prof) > 2:
            out.append(attenuation_fit(prof))
    for (medium, _), qs in _same_place(table).items():
        get = lambda q: qs.get(q, [])
        out += [irradiance_reflectance(u, d) for d in get("Ed") for u in get("Eu")]
        out += [mean_cosine_down(d, o) for d in get("Ed") for o in get("Eod")]
        out += [mean_cosine_up(u, o) for u in get("Eu") for o in get("Eou")]
        if get("Eo"):
            out += [mean_cosine(d, u, eo=o) for d in get("Ed") for u in get("Eu") for o in get("Eo")]
        else:
            out += [mean_cosine(d, u, eod=od, eou=ou) for d in get("Ed") for u in get("Eu")
                    for od in get("Eod") for ou in get("Eou")]
    if rrs is None:
        out += [remote_sensing_reflectance(u, d) for u, d in auto_rrs_pairs(table)]
    else:
        for spec in rrs:
            unknown = set(spec) - {"lu", "ed", "sky", "rho", "reflected"}
            if unknown or "lu" not in spec or "ed" not in spec:
                raise DerivedError(f"Rrs: expected keys lu, ed and optionally sky, rho or reflected, got {sorted(spec)}")
            out.append(remote_sensing_reflectance(spec["lu"], spec["ed"], spec.get("sky"), spec.get("rho"),
                                                  spec.get("reflected"), table=table))
    return out


# --- tables -------------------------------------------------------------------------------

CSV_FIELDS = ["name", "quantity", "band", "center_nm", "value", "stderr", "units", "medium", "x_m", "y_m",
              "z_m", "depth_top_m", "depth_bottom_m", "chi2_dof", "sources", "note"]


def derived_rows(derived: list[Derived], bands) -> list[dict]:
    """One row per derived quantity and band (``bands``: (name, centre nm) pairs or Band
    objects); ``sources`` joined with ';'."""
    bands = [(b.name, float(b.center_nm)) if hasattr(b, "name") else (b[0], float(b[1])) for b in bands]
    rows = []
    for q in derived:
        for k, (band, center) in enumerate(bands):
            value, err = float(q.value[k]), float(q.stderr[k])
            note = q.note
            if not (np.isfinite(value) and np.isfinite(err)):  # empty with a note, never NaN
                value = err = None
                note = "; ".join(x for x in (q.why_missing(k), note) if x)
            row = {"name": q.name, "quantity": q.quantity, "band": band, "center_nm": center,
                   "value": value, "stderr": err, "units": q.units,
                   "medium": q.medium, "x_m": float(q.position[0]), "y_m": float(q.position[1]),
                   "z_m": float(q.position[2]), "sources": ";".join(q.sources), "note": note}
            if q.depths is not None:
                row["depth_top_m"], row["depth_bottom_m"] = float(q.depths[0]), float(q.depths[1])
            if "chi2_dof" in q.extra and np.isfinite(q.extra["chi2_dof"][k]):
                row["chi2_dof"] = float(q.extra["chi2_dof"][k])
            rows.append(row)
    return rows


def write_derived_csv(path, derived: list[Derived], bands, header: str = "") -> Path:
    """The rows of ``derived_rows`` as CSV, after a '#' comment line."""
    from .safe_io import atomic_file, csv_text
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path, "w", newline="", encoding="utf-8") as f:
        f.write("# photic derived quantities" + (f"; {header}" if header else "") +
                "; value +- stderr (first-order propagation, radiometers independent); depth = -z (m); "
                "K = -d ln E / d depth\n")
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for row in derived_rows(derived, bands):
            w.writerow({k: csv_text(row.get(k, "")) for k in CSV_FIELDS})
    return path


def format_table(derived: list[Derived], bands) -> str:
    """A fixed-width table: name, quantity, band, value +- stderr, units."""
    rows = derived_rows(derived, bands)
    width = max([len("name")] + [len(r["name"]) for r in rows])
    lines = [f"{'name':<{width}} {'quantity':<16} {'band':<8} {'value +- stderr':<28} units"]
    for r in rows:
        ve = ("not computed" if r["value"] is None else f"{r['value']:.6g} +- {r['stderr']:.2g}")
        lines.append(f"{r['name']:<{width}} {r['quantity']:<16} {r['band']:<8} {ve:<28} {r['units']}")
    return "\n".join(lines)
