"""The water community's IOP models, turned into per-band IOPs the engine reads.

Every model is evaluated over each band ``[centre - width/2, centre + width/2]`` and averaged
(a band of width 0 is evaluated at its centre). The result is a ``photic.scene.IOPs``: the
absorption per band (m^-1; constituents add) and a list of ``ScatteringComponent``s, one per
scattering constituent (the engine samples a component with probability b_i / b).

Models (formulas, units and sources; see also ``docs/iop-models.md``)
--------------------------------------------------------------------
Pure water, ``pure_water``
    a_w: Pope & Fry 1997 (Appl. Opt. 36:8710), 380-727.5 nm every 2.5 nm, or Smith & Baker
    1981 (Appl. Opt. 20:177, Table 1, "clearest natural water"), 200-800 nm every 10 nm; both
    interpolated linearly and averaged exactly over the band. ``"pope_fry_smith_baker"`` uses
    Pope & Fry for bands inside 380-727.5 nm and Smith & Baker for the others.
    **A band reaching outside the chosen table raises ValueError naming the band; nothing is
    extrapolated.**
    b_w = 0.00288 (lambda / 500 nm)^-4.32 m^-1 (pure sea water; Morel 1974 as used by Smith &
    Baker 1981), phase function ``pure_water`` (1 + 0.835 cos^2 psi).
CDOM, ``cdom``
    a_g(lambda) = a_g(lambda0) exp(-S (lambda - lambda0)); lambda0 = 440 nm and
    S = 0.014 nm^-1 by default (HydroLight's value; typical range 0.010-0.020).
Particles, ``particles``
    b_p(lambda) = b_p(lambda0) (lambda0 / lambda)^n (lambda0 = 550 nm, n = 1 by default, the
    shape of the classic Case-1 model), with a Fournier-Forand phase function set by its
    backscatter fraction b_bp / b_p (Mobley et al. 2002, Appl. Opt. 41:1035; ``photic.phase``)
    or any scene phase function. Optional absorption of non-algal particles
    a_NAP(lambda) = a_NAP(443) exp(-0.0123 (lambda - 443)) (Babin et al. 2003; marked "not
    re-read in the paper" in PHYSICS-NOTES section 6).
Case 1, classic (``case1_classic``; Prieur & Sathyendranath 1981 / Morel 1988 absorption,
Gordon & Morel 1983 scattering, as in HydroLight's "Case 1" model)
    a_p(lambda) = 0.06 a*_c(lambda) C^0.65, a*_c normalised to 1 at 440 nm;
    a_CDOM(lambda) = 0.2 a_p(440) exp(-0.014 (lambda - 440)) = 0.012 C^0.65 exp(...);
    b_p(lambda) = 0.30 C^0.62 (550 / lambda); particle phase function Petzold by default.
    C is the chlorophyll concentration in mg m^-3.
Case 1, new (``case1_new``; Bricaud et al. 1998 absorption, Morel & Maritorena 2001 /
Loisel & Morel 1998 scattering, as in HydroLight's "new Case 1" model)
    a_p(lambda) = A_p(lambda) C^E_p(lambda);
    a_CDOM(lambda) = 0.2 a_p(440) exp(-0.014 (lambda - 440));
    b_p(lambda) = 0.416 C^0.766 (lambda / 550)^nu, nu = 0.5 (log10 C - 0.3) clamped to
    [-1, 0] (i.e. -1 below C = 0.02 and 0 above C = 2, HydroLight's rule);
    b_bp(lambda) = [0.002 + 0.01 (0.5 - 0.25 log10 C) (lambda / 550)^nu] 0.416 C^0.766
    (Morel & Maritorena 2001), used as the Fournier-Forand backscatter fraction b_bp / b_p
    of each band by default.

What is *not* bundled (read this)
---------------------------------
The spectral shape of chlorophyll absorption, a*_c(lambda) for the classic model and
Bricaud et al. 1998's A_p(lambda), E_p(lambda) for the new one, are published tables that the
project's verified reference data (``shared/data``) do not hold yet. Photic does not invent or
approximate them: both Case-1 models take the table as an input (``SpectralTable``, or the
``"chlorophyll_absorption"`` field of a model description, inline or as a CSV file) and raise
an error naming that field when it is missing. Everything else in the models above (the
co-varying CDOM of the classic model, all scattering and backscattering) needs no table.
Also left out: HydroLight's split of the new model's b_p into small and large particles with
their own phase functions (PHYSICS-NOTES 6 gives the split fraction but not the two phase
functions); here all particles share one phase function.

Declarative description (``iops_from_model``)
---------------------------------------------
A JSON-like dict; every model has ``"model"`` and ``"water"``::

    {"model": "pure_water" | "cdom" | "particles" | "case1" | "mixture",
     "water": "pope_fry" (default) | "smith_baker" | "pope_fry_smith_baker" | "none",
     ...model fields...}

``"cdom"``       ``"a_ref"`` (m^-1, required), ``"wavelength_ref_nm"`` (440), ``"slope"``
                 (nm^-1, 0.014).
``"particles"``  ``"b_ref"`` (m^-1, required), ``"wavelength_ref_nm"`` (550), ``"exponent"``
                 (1.0), ``"backscatter_fraction"`` (0.0183, Fournier-Forand) or ``"phase"``
                 (a scene phase function ``{"type": ..., ...params}``), ``"a_ref"`` (0),
                 ``"absorption_ref_nm"`` (443), ``"absorption_slope"`` (0.0123).
``"case1"``      ``"chlorophyll"`` (mg m^-3, required; > 0 for ``"new"``),
                 ``"variant"``: ``"classic"`` (default) or ``"new"``,
                 ``"chlorophyll_absorption"`` (required, see below),
                 ``"cdom"``: ``"covarying"`` (default), ``"none"``, ``{"slope": S}``
                 (co-varying with slope S) or ``{"a_ref": ..., "wavelength_ref_nm": ...,
                 "slope": ...}`` (independent CDOM instead of the co-varying one),
                 ``"particle_phase"``: a scene phase function; for ``fournier_forand`` the
                 ``backscatter_fraction`` may be ``"morel_maritorena_2001"`` (default of the
                 new variant; Petzold is the default of the classic one).
``"mixture"``    ``"components"``: a list of the model dicts above (not ``"mixture"``, and
                 without ``"water"``: pure water is added once, by the mixture).

``"chlorophyll_absorption"`` is ``{"wavelength_nm": [...], "a_star": [...]}`` (classic;
normalised here to 1 at 440 nm) or ``{"wavelength_nm": [...], "A": [...], "E": [...]}``
(new), or ``{"file": "table.csv"}`` with the same column names in a CSV header (lines
starting with ``#`` are comments; a relative path is taken from ``base_dir``); an optional
``"source"`` names the table in error messages. Example::

    iops_from_model({"model": "case1", "chlorophyll": 0.5, "variant": "new",
                     "chlorophyll_absorption": {"file": "bricaud1998.csv"},
                     "cdom": {"slope": 0.018}}, scene.bands)

Problems raise ``photic.scene.SceneError(obj, field, message)`` naming the field, e.g.
``iop model: field 'components[1].chlorophyll': must be a finite number >= 0, got -1``.
"""
from __future__ import annotations

import csv
import math
import numbers
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .parameters import PARAMETERS
from .scene.checks import PHASE_FUNCTION_PARAMS, SceneError
from .scene.model import IOPs, PhaseFunction, ScatteringComponent

__all__ = [
    "WATER_ABSORPTION_SOURCES", "SpectralTable", "pope_fry_1997", "smith_baker_1981",
    "load_table_csv", "pure_water_absorption", "pure_seawater_scattering", "pure_water",
    "cdom_absorption", "cdom", "particles", "case1_classic", "case1_new",
    "morel_maritorena_backscatter_ratio", "mix", "iops_from_model",
]

#: Pure-water absorption tables a model may name.
WATER_ABSORPTION_SOURCES = ("pope_fry", "smith_baker", "pope_fry_smith_baker")
#: The range of backscatter fractions the Fournier-Forand fit (and the scene format) accepts.
FF_BACKSCATTER_RANGE = (PARAMETERS["phase.backscatter_fraction"].lo,
                        PARAMETERS["phase.backscatter_fraction"].hi)
#: The special value of a Fournier-Forand ``backscatter_fraction`` in a Case-1 model.
MM01 = "morel_maritorena_2001"

# Coefficients, with their sources in the module docstring.
BW500, BW_EXPONENT = 0.00288, -4.32           # pure sea water, Morel 1974 / Smith & Baker 1981
CDOM_SLOPE, CDOM_REF_NM = 0.014, 440.0         # HydroLight's CDOM slope and reference
NAP_SLOPE, NAP_REF_NM = 0.0123, 443.0          # Babin et al. 2003
PETZOLD_BACKSCATTER = 0.0183                   # Petzold average particle, b_b / b


# --------------------------------------------------------------------------------------------
# Bands and band averages
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Band:
    label: str
    center: float
    width: float

    @property
    def lo(self) -> float:
        return self.center - 0.5 * self.width

    @property
    def hi(self) -> float:
        return self.center + 0.5 * self.width


def _as_bands(bands: Sequence[Any]) -> list[_Band]:
    """Bands as ``photic.scene.Band``s, (centre, width) or (name, centre, width) tuples."""
    out = []
    for i, band in enumerate(bands):
        if isinstance(band, _Band):
            out.append(band)
            continue
        if hasattr(band, "center_nm"):
            name, c, w = getattr(band, "name", None), band.center_nm, band.width_nm
        elif isinstance(band, (tuple, list)) and len(band) in (2, 3):
            name, c, w = (None, *band) if len(band) == 2 else band
        else:
            raise ValueError(f"band {i}: expected a Band or (centre_nm, width_nm), got {band!r}")
        c, w = float(c), float(w)
        if not (math.isfinite(c) and math.isfinite(w) and w >= 0 and c - 0.5 * w > 0):
            raise ValueError(f"band {i}: centre {c:g} nm and width {w:g} nm must be finite, "
                             f"the width >= 0 and the band above 0 nm")
        label = f"band {i}" + (f" '{name}'" if name else "") + f" ({c:g} +- {0.5 * w:g} nm)"
        out.append(_Band(label, c, w))
    if not out:
        raise ValueError("at least one band is required")
    return out


def _trapezoid(v: np.ndarray, x: np.ndarray) -> float:
    return float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(x)))


def _band_mean(f, band: _Band, nodes: np.ndarray | None = None, step_nm: float = 0.5) -> float:
    """Mean of f(lambda) over the band: trapezoids on a grid of at most ``step_nm`` that holds
    every table node inside the band (exact for a linearly interpolated table)."""
    if band.width <= 0.0:
        return float(f(np.array([band.center]))[0])
    grid = np.linspace(band.lo, band.hi, max(2, int(np.ceil(band.width / step_nm)) + 1))
    if nodes is not None:
        grid = np.union1d(grid, nodes[(nodes > band.lo) & (nodes < band.hi)])
    return _trapezoid(f(grid), grid) / (band.hi - band.lo)


def _mean_power(band: _Band, p: float) -> float:
    """Exact mean of lambda^p over the band (written to keep precision for narrow bands)."""
    c = band.center
    h = 0.5 * band.width / c
    if h == 0.0:
        return c ** p
    q = p + 1.0
    if abs(q) < 1e-12:
        return (math.log1p(h) - math.log1p(-h)) / (2 * h) / c
    return c ** p * (math.expm1(q * math.log1p(h)) - math.expm1(q * math.log1p(-h))) / (2 * h * q)


def _mean_exp(band: _Band, slope: float, ref_nm: float) -> float:
    """Exact mean of exp(-slope (lambda - ref_nm)) over the band."""
    x = 0.5 * slope * band.width
    return math.exp(-slope * (band.center - ref_nm)) * (math.sinh(x) / x if x != 0.0 else 1.0)


# --------------------------------------------------------------------------------------------
# Spectral tables
# --------------------------------------------------------------------------------------------

class SpectralTable:
    """Columns tabulated against wavelength (nm), interpolated linearly, never extrapolated.

    Parameters
    ----------
    name : str
        The table's name and source, used in error messages (e.g. ``"Pope & Fry 1997"``).
    wavelength_nm : array
        Strictly increasing wavelengths, at least 2.
    **columns : array
        One array per column, as long as ``wavelength_nm``.
    """

    def __init__(self, name: str, wavelength_nm, **columns):
        wl = np.asarray(wavelength_nm, dtype=np.float64)
        if wl.ndim != 1 or wl.size < 2 or not np.all(np.isfinite(wl)) or np.any(np.diff(wl) <= 0):
            raise ValueError(f"{name}: wavelength_nm must be at least 2 finite, strictly "
                             f"increasing numbers")
        self.name = name
        self.wavelength_nm = wl
        self.columns: dict[str, np.ndarray] = {}
        for key, col in columns.items():
            v = np.asarray(col, dtype=np.float64)
            if v.shape != wl.shape or not np.all(np.isfinite(v)):
                raise ValueError(f"{name}: column {key!r} must hold {wl.size} finite numbers, "
                                 f"one per wavelength")
            self.columns[key] = v

    @property
    def range_nm(self) -> tuple[float, float]:
        return float(self.wavelength_nm[0]), float(self.wavelength_nm[-1])

    def covers(self, band: _Band) -> bool:
        lo, hi = self.range_nm
        return band.lo >= lo - 1e-9 and band.hi <= hi + 1e-9

    def check(self, band: _Band) -> None:
        """Raise ValueError naming the band if it reaches outside the table."""
        if not self.covers(band):
            lo, hi = self.range_nm
            raise ValueError(f"{band.label} reaches outside the {self.name} table "
                             f"({lo:g}-{hi:g} nm); tables are not extrapolated")

    def __call__(self, column: str, wavelength_nm) -> np.ndarray:
        """Linear interpolation of a column (callers check the range first)."""
        return np.interp(wavelength_nm, self.wavelength_nm, self.columns[column])

    def band_mean(self, column: str, band: _Band) -> float:
        self.check(band)
        return _band_mean(lambda wl: self(column, wl), band, self.wavelength_nm)


def _parse_csv(text: str, name: str) -> SpectralTable:
    rows = list(csv.DictReader(line for line in text.splitlines()
                               if line.strip() and not line.lstrip().startswith("#")))
    if not rows or "wavelength_nm" not in rows[0]:
        raise ValueError(f"{name}: a CSV header with a 'wavelength_nm' column is required")
    try:
        cols = {k.strip(): [float(r[k]) for r in rows] for k in rows[0] if k is not None}
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: every cell must be a number ({exc})") from None
    return SpectralTable(name, cols.pop("wavelength_nm"), **cols)


def load_table_csv(path: str | Path, name: str | None = None) -> SpectralTable:
    """A SpectralTable from a CSV file: ``#`` comment lines, a header with ``wavelength_nm``
    and the other columns, one row per wavelength."""
    path = Path(path)
    return _parse_csv(path.read_text(), name or str(path))


@lru_cache(maxsize=None)
def _bundled(filename: str, name: str) -> SpectralTable:
    return _parse_csv(resources.files("photic.data").joinpath(filename).read_text(), name)


def pope_fry_1997() -> SpectralTable:
    """Pure water absorption ``aw_per_m`` (1/m), 380-727.5 nm (Pope & Fry 1997)."""
    return _bundled("pope_fry_1997_pure_water_absorption.csv", "Pope & Fry 1997")


def smith_baker_1981() -> SpectralTable:
    """Clearest natural water ``aw_per_m`` and sea-water ``bw_seawater_per_m`` (1/m),
    200-800 nm (Smith & Baker 1981, Table 1)."""
    return _bundled("smith_baker_1981_clearest_water.csv", "Smith & Baker 1981")


# --------------------------------------------------------------------------------------------
# Pure water
# --------------------------------------------------------------------------------------------

def pure_water_absorption(bands, source: str = "pope_fry") -> np.ndarray:
    """Band-averaged pure-water absorption (1/m) from the table ``source``.

    ``source`` is ``"pope_fry"``, ``"smith_baker"`` or ``"pope_fry_smith_baker"`` (Pope & Fry
    for bands inside 380-727.5 nm, Smith & Baker for the others).

    Raises
    ------
    ValueError
        If a band reaches outside the table used for it (the message names the band).
    """
    if source not in WATER_ABSORPTION_SOURCES:
        raise ValueError(f"unknown pure-water absorption {source!r}; one of "
                         f"{', '.join(WATER_ABSORPTION_SOURCES)}")
    out = []
    for band in _as_bands(bands):
        table = smith_baker_1981() if source == "smith_baker" else pope_fry_1997()
        if source == "pope_fry_smith_baker" and not table.covers(band):
            table = smith_baker_1981()
        try:
            out.append(table.band_mean("aw_per_m", band))
        except ValueError as exc:
            hint = "" if source != "pope_fry" else (
                "; 'smith_baker' covers 200-800 nm, 'pope_fry_smith_baker' combines the two")
            raise ValueError(f"{exc}{hint}") from None
    return np.array(out)


def pure_seawater_scattering(bands) -> np.ndarray:
    """Band-averaged pure sea-water scattering (1/m): 0.00288 (lambda / 500)^-4.32."""
    return np.array([BW500 * 500.0 ** -BW_EXPONENT * _mean_power(b, BW_EXPONENT)
                     for b in _as_bands(bands)])


def pure_water(bands, absorption: str = "pope_fry") -> IOPs:
    """Pure (sea) water: absorption from ``absorption``'s table, scattering with the
    ``pure_water`` phase function."""
    return IOPs(pure_water_absorption(bands, absorption),
                [ScatteringComponent(pure_seawater_scattering(bands), PhaseFunction("pure_water"))])


# --------------------------------------------------------------------------------------------
# CDOM and particles
# --------------------------------------------------------------------------------------------

def cdom_absorption(bands, a_ref: float, wavelength_ref_nm: float = CDOM_REF_NM,
                    slope: float = CDOM_SLOPE) -> np.ndarray:
    """Band-averaged a_g(lambda) = a_ref exp(-slope (lambda - wavelength_ref_nm)) (1/m)."""
    return np.array([a_ref * _mean_exp(b, slope, wavelength_ref_nm) for b in _as_bands(bands)])


def cdom(bands, a_ref: float, wavelength_ref_nm: float = CDOM_REF_NM,
         slope: float = CDOM_SLOPE) -> IOPs:
    """CDOM alone: absorption only."""
    return IOPs(cdom_absorption(bands, a_ref, wavelength_ref_nm, slope), [])


def _check_backscatter(ratio: float, label: str) -> None:
    lo, hi = FF_BACKSCATTER_RANGE
    if not (lo <= ratio <= hi):
        raise ValueError(f"{label}: backscatter fraction {ratio:.4g} is outside the "
                         f"Fournier-Forand range [{lo:g}, {hi:g}]")


def _components(b: np.ndarray, phase, labels: Sequence[str]) -> list[ScatteringComponent]:
    """Scattering components for per-band ``b`` and either one PhaseFunction or, per band, a
    Fournier-Forand backscatter fraction (rounded to 4 significant digits; bands that share a
    fraction share a component, each component's b is zero in the other bands)."""
    if not np.any(b > 0):
        return []
    if isinstance(phase, PhaseFunction):
        return [ScatteringComponent(b, phase)]
    groups: dict[float, np.ndarray] = {}
    for i, ratio in enumerate(phase):
        if b[i] <= 0:
            continue
        _check_backscatter(ratio, labels[i])
        key = float(f"{ratio:.4g}")
        groups.setdefault(key, np.zeros_like(b))[i] = b[i]
    return [ScatteringComponent(bi, PhaseFunction("fournier_forand", {"backscatter_fraction": k}))
            for k, bi in groups.items()]


def _phase(phase) -> PhaseFunction:
    """A PhaseFunction, or a number: a Fournier-Forand backscatter fraction."""
    if isinstance(phase, PhaseFunction):
        return phase
    ratio = float(phase)
    _check_backscatter(ratio, "particles")
    return PhaseFunction("fournier_forand", {"backscatter_fraction": ratio})


def particles(bands, b_ref: float, *, wavelength_ref_nm: float = 550.0, exponent: float = 1.0,
              phase: PhaseFunction | float = PETZOLD_BACKSCATTER, a_ref: float = 0.0,
              absorption_ref_nm: float = NAP_REF_NM,
              absorption_slope: float = NAP_SLOPE) -> IOPs:
    """Particles: b_p = b_ref (wavelength_ref_nm / lambda)^exponent with ``phase`` (a
    PhaseFunction, or a number: the Fournier-Forand backscatter fraction), and absorption
    a_ref exp(-absorption_slope (lambda - absorption_ref_nm)) (non-algal particles)."""
    bs = _as_bands(bands)
    b = np.array([b_ref * wavelength_ref_nm ** exponent * _mean_power(x, -exponent) for x in bs])
    a = np.array([a_ref * _mean_exp(x, absorption_slope, absorption_ref_nm) for x in bs])
    return IOPs(a, _components(b, _phase(phase), [x.label for x in bs]))


# --------------------------------------------------------------------------------------------
# Case 1
# --------------------------------------------------------------------------------------------

def _require_columns(table: SpectralTable, names: tuple[str, ...], model: str) -> None:
    if not isinstance(table, SpectralTable):
        raise ValueError(f"{model}: a SpectralTable of chlorophyll absorption is required "
                         f"(none is bundled with Photic)")
    missing = [n for n in names if n not in table.columns]
    if missing:
        raise ValueError(f"{model}: the table {table.name} needs column(s) "
                         f"{', '.join(names)}; missing {', '.join(missing)}")


def _at_440(table: SpectralTable, column: str) -> float:
    lo, hi = table.range_nm
    if not lo <= 440.0 <= hi:
        raise ValueError(f"the table {table.name} ({lo:g}-{hi:g} nm) must cover 440 nm")
    return float(table(column, 440.0))


def case1_classic(bands, chlorophyll: float, astar_c: SpectralTable, *,
                  covarying_cdom: bool = True, cdom_slope: float = CDOM_SLOPE,
                  particle_phase: PhaseFunction | float = PhaseFunction("petzold")) -> IOPs:
    """Classic Case-1 constituents (no pure water): particles and co-varying CDOM.

    ``astar_c`` is a table with column ``a_star`` (a*_c(lambda); divided here by its value at
    440 nm). ``particle_phase`` is a PhaseFunction or a Fournier-Forand backscatter fraction.
    """
    if not (math.isfinite(chlorophyll) and chlorophyll >= 0):
        raise ValueError(f"chlorophyll must be a finite number >= 0, got {chlorophyll!r}")
    _require_columns(astar_c, ("a_star",), "classic Case 1")
    bs = _as_bands(bands)
    norm = _at_440(astar_c, "a_star")
    if not norm > 0:
        raise ValueError(f"the table {astar_c.name} must be > 0 at 440 nm to normalise a*_c")
    chl65 = chlorophyll ** 0.65
    a = np.array([0.06 * chl65 * astar_c.band_mean("a_star", x) / norm for x in bs])
    if covarying_cdom:
        a = a + cdom_absorption(bands, 0.2 * 0.06 * chl65, 440.0, cdom_slope)
    b = np.array([0.30 * chlorophyll ** 0.62 * 550.0 * _mean_power(x, -1.0) for x in bs])
    return IOPs(a, _components(b, _phase(particle_phase), [x.label for x in bs]))


def _mm01_nu(chlorophyll: float) -> float:
    return min(0.0, max(-1.0, 0.5 * (math.log10(chlorophyll) - 0.3)))


def morel_maritorena_backscatter_ratio(chlorophyll: float, bands) -> np.ndarray:
    """b_bp / b_p per band of the new Case-1 model: band mean of b_bp (Morel & Maritorena
    2001) over band mean of b_p = 0.416 C^0.766 (lambda / 550)^nu."""
    nu = _mm01_nu(chlorophyll)
    out = []
    for x in _as_bands(bands):
        spectral = 550.0 ** -nu * _mean_power(x, nu)  # mean of (lambda / 550)^nu
        out.append((0.002 + 0.01 * (0.5 - 0.25 * math.log10(chlorophyll)) * spectral) / spectral)
    return np.array(out)


def case1_new(bands, chlorophyll: float, coefficients: SpectralTable, *,
              covarying_cdom: bool = True, cdom_slope: float = CDOM_SLOPE,
              particle_phase: PhaseFunction | float | str = MM01) -> IOPs:
    """New Case-1 constituents (no pure water): particles and co-varying CDOM.

    ``coefficients`` is a table with columns ``A`` and ``E`` (Bricaud et al. 1998's A_p, E_p
    for total particulate absorption). ``particle_phase`` is ``"morel_maritorena_2001"``
    (Fournier-Forand with each band's b_bp / b_p), a PhaseFunction or a backscatter fraction.
    """
    if not (math.isfinite(chlorophyll) and chlorophyll > 0):
        raise ValueError(f"chlorophyll must be a finite number > 0, got {chlorophyll!r}")
    _require_columns(coefficients, ("A", "E"), "new Case 1")
    bs = _as_bands(bands)
    t = coefficients
    a_p = lambda wl: t("A", wl) * chlorophyll ** t("E", wl)
    a = []
    for x in bs:
        t.check(x)
        a.append(_band_mean(a_p, x, t.wavelength_nm))
    a = np.array(a)
    if covarying_cdom:
        a440 = _at_440(t, "A") * chlorophyll ** _at_440(t, "E")
        a = a + cdom_absorption(bands, 0.2 * a440, 440.0, cdom_slope)
    nu = _mm01_nu(chlorophyll)
    b = np.array([0.416 * chlorophyll ** 0.766 * 550.0 ** -nu * _mean_power(x, nu) for x in bs])
    if isinstance(particle_phase, str):
        if particle_phase != MM01:
            raise ValueError(f"particle_phase: unknown {particle_phase!r}; use {MM01!r}, a "
                             f"PhaseFunction or a backscatter fraction")
        phase = morel_maritorena_backscatter_ratio(chlorophyll, bands)
    else:
        phase = _phase(particle_phase)
    return IOPs(a, _components(b, phase, [x.label for x in bs]))


# --------------------------------------------------------------------------------------------
# Mixtures
# --------------------------------------------------------------------------------------------

def mix(*parts: IOPs) -> IOPs:
    """Sum of constituents: absorptions add, scattering components are kept side by side."""
    if not parts:
        raise ValueError("mix needs at least one IOPs")
    n = np.asarray(parts[0].absorption).shape
    a = np.zeros(n)
    scattering: list[ScatteringComponent] = []
    for i, p in enumerate(parts):
        if np.asarray(p.absorption).shape != n:
            raise ValueError(f"part {i} has {np.asarray(p.absorption).size} band(s), part 0 "
                             f"has {int(np.prod(n))}")
        a = a + p.absorption
        scattering.extend(p.scattering)
    return IOPs(a, scattering)


# --------------------------------------------------------------------------------------------
# Declarative description
# --------------------------------------------------------------------------------------------

_FIELDS = {
    "pure_water": ("model", "water"),
    "cdom": ("model", "water", "a_ref", "wavelength_ref_nm", "slope"),
    "particles": ("model", "water", "b_ref", "wavelength_ref_nm", "exponent",
                  "backscatter_fraction", "phase", "a_ref", "absorption_ref_nm",
                  "absorption_slope"),
    "case1": ("model", "water", "chlorophyll", "variant", "chlorophyll_absorption", "cdom",
              "particle_phase"),
    "mixture": ("model", "water", "components"),
}
CASE1_VARIANTS = ("classic", "new")


def _show(x: Any) -> str:
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


class _Spec:
    """Field access with errors naming the field (obj, prefix + field)."""

    def __init__(self, d: Any, obj: str, prefix: str, allowed: tuple[str, ...] | None = None):
        self.obj, self.prefix = obj, prefix
        if not isinstance(d, Mapping):
            raise SceneError(obj, prefix.rstrip(".") or "(model)",
                             f"must be an object (dict), got {_show(d)}")
        self.d = d
        if allowed is not None:
            for key in d:
                if key not in allowed:
                    raise SceneError(obj, prefix + str(key),
                                     f"unknown field (allowed: {', '.join(allowed)})")

    def error(self, fld: str, message: str) -> SceneError:
        return SceneError(self.obj, self.prefix + fld, message)

    def number(self, fld: str, default=None, *, lo=None, lo_open=False) -> float:
        x = self.d.get(fld, default)
        if x is None:
            raise self.error(fld, "required")
        ok = isinstance(x, numbers.Real) and not isinstance(x, bool) and math.isfinite(x)
        if ok and lo is not None:
            ok = x > lo if lo_open else x >= lo
        if not ok:
            rng = "" if lo is None else (f" > {lo:g}" if lo_open else f" >= {lo:g}")
            raise self.error(fld, f"must be a finite number{rng}, got {_show(x)}")
        return float(x)

    def choice(self, fld: str, default: str | None, choices: tuple[str, ...]) -> str:
        x = self.d.get(fld, default)
        if x is None:
            raise self.error(fld, f"required: one of {', '.join(map(repr, choices))}")
        if x not in choices:
            raise self.error(fld, f"must be one of {', '.join(map(repr, choices))}, got {_show(x)}")
        return x


def _phase_from_spec(spec: _Spec, fld: str, allow_mm01: bool):
    d = spec.d[fld]
    sub = _Spec(d, spec.obj, f"{spec.prefix}{fld}.")
    ptype = sub.choice("type", None, tuple(PHASE_FUNCTION_PARAMS))
    expected = PHASE_FUNCTION_PARAMS[ptype]
    sub = _Spec(d, spec.obj, sub.prefix, ("type",) + expected)
    params = {}
    for key in expected:
        if key not in d:
            raise sub.error(key, f"required by phase function '{ptype}'")
    if ptype == "henyey_greenstein":
        g = sub.number("g")
        if not PARAMETERS["phase.g"].contains(g):
            raise sub.error("g", f"must be in {PARAMETERS['phase.g'].range_text()}, got {_show(g)}")
        params["g"] = g
    elif ptype == "fournier_forand":
        if d["backscatter_fraction"] == MM01:
            if allow_mm01:
                return MM01
            raise sub.error("backscatter_fraction", f"{MM01!r} is only defined for the Case-1 "
                                                    f"variant 'new'")
        params["backscatter_fraction"] = _backscatter(sub, "backscatter_fraction")
    return PhaseFunction(ptype, params)


def _backscatter(spec: _Spec, fld: str) -> float:
    ratio = spec.number(fld)
    lo, hi = FF_BACKSCATTER_RANGE
    if not lo <= ratio <= hi:
        raise spec.error(fld, f"must be in [{lo:g}, {hi:g}] (Fournier-Forand), got {_show(ratio)}")
    return ratio


def _table_from_spec(spec: _Spec, fld: str, columns: tuple[str, ...],
                     base_dir: Path | None) -> SpectralTable:
    if fld not in spec.d:
        raise spec.error(fld, f"required: a table with columns wavelength_nm, "
                              f"{', '.join(columns)} (no such table is bundled with Photic; "
                              f"see docs/iop-models.md)")
    d = spec.d[fld]
    sub = _Spec(d, spec.obj, f"{spec.prefix}{fld}.",
                ("file", "source") if isinstance(d, Mapping) and "file" in d
                else ("wavelength_nm", "source") + columns)
    name = str(d.get("source", f"'{spec.prefix}{fld}'"))
    try:
        if "file" in d:
            path = Path(d["file"])
            if not path.is_absolute() and base_dir is not None:
                path = Path(base_dir) / path
            try:
                table = load_table_csv(path, name if "source" in d else str(path))
            except OSError as exc:
                reason = exc.strerror or exc
                raise sub.error("file", f"cannot read {str(path)!r}: {reason}") from None
        else:
            for key in ("wavelength_nm",) + columns:
                if key not in d:
                    raise sub.error(key, "required")
            table = SpectralTable(name, d["wavelength_nm"], **{k: d[k] for k in columns})
    except (TypeError, ValueError) as exc:
        if isinstance(exc, SceneError):
            raise
        raise spec.error(fld, str(exc)) from None
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise spec.error(fld, f"the table {table.name} lacks column(s) {', '.join(missing)}")
    return table


def _run(spec: _Spec, fld: str, fn, *args, **kwargs):
    """Call a model function; its ValueErrors (a band outside a table, ...) name ``fld``."""
    try:
        return fn(*args, **kwargs)
    except SceneError:
        raise
    except ValueError as exc:
        raise spec.error(fld, str(exc)) from None


def _plugin(d: Any, bands, obj: str, prefix: str, in_mixture: bool) -> IOPs | None:
    """IOPs from an installed plugin model (photic.plugins), or None if there is none."""
    from . import plugins
    name = d.get("model") if isinstance(d, Mapping) else None
    if not isinstance(name, str) or name in _FIELDS:
        return None
    fn = plugins.load("iop", name)
    if fn is None:
        return None
    params = {k: v for k, v in d.items() if k not in ("model", "water")}
    if in_mixture and "water" in d:
        raise SceneError(obj, f"{prefix}water", "inside a mixture pure water is added once, by "
                                               "the mixture")
    try:
        iops = fn(params, [(b.label, b.center, b.width) for b in bands])
    except ValueError as exc:
        raise SceneError(obj, f"{prefix}model", f"plugin '{name}': {exc}") from None
    if not isinstance(iops, IOPs) or np.shape(iops.absorption) != (len(bands),):
        raise SceneError(obj, f"{prefix}model", f"plugin '{name}' must return photic.scene.IOPs "
                                                f"with one absorption value per band")
    return iops


def _constituent(d: Any, bands, obj: str, prefix: str, base_dir, in_mixture: bool) -> IOPs:
    from_plugin = _plugin(d, bands, obj, prefix, in_mixture)
    if from_plugin is not None:
        return from_plugin
    spec = _Spec(d, obj, prefix)
    name = d.get("model") if isinstance(d, Mapping) else None
    if isinstance(name, str) and name not in _FIELDS:
        from . import plugins
        installed = ", ".join(sorted(plugins.available("iop"))) or "none"
        raise spec.error("model", f"unknown model {name!r}: one of {', '.join(map(repr, _FIELDS))} "
                                  f"or an installed IOP-model plugin (installed: {installed})")
    model = spec.choice("model", None, tuple(_FIELDS))
    allowed = _FIELDS[model]
    if in_mixture:
        if model == "mixture":
            raise spec.error("model", "a mixture cannot hold another mixture")
        allowed = tuple(f for f in allowed if f != "water")
    spec = _Spec(d, obj, prefix, allowed)
    zero = IOPs(np.zeros(len(bands)), [])

    if model == "pure_water":
        return zero
    if model == "cdom":
        return _run(spec, "a_ref", cdom, bands, spec.number("a_ref", lo=0),
                    spec.number("wavelength_ref_nm", CDOM_REF_NM, lo=0, lo_open=True),
                    spec.number("slope", CDOM_SLOPE, lo=0))
    if model == "particles":
        if "phase" in d and "backscatter_fraction" in d:
            raise spec.error("phase", "give either 'phase' or 'backscatter_fraction', not both")
        phase = (_phase_from_spec(spec, "phase", False) if "phase" in d else
                 _backscatter(spec, "backscatter_fraction") if "backscatter_fraction" in d
                 else PETZOLD_BACKSCATTER)
        return _run(spec, "b_ref", particles, bands, spec.number("b_ref", lo=0),
                    wavelength_ref_nm=spec.number("wavelength_ref_nm", 550.0, lo=0, lo_open=True),
                    exponent=spec.number("exponent", 1.0), phase=phase,
                    a_ref=spec.number("a_ref", 0.0, lo=0),
                    absorption_ref_nm=spec.number("absorption_ref_nm", NAP_REF_NM, lo=0,
                                                  lo_open=True),
                    absorption_slope=spec.number("absorption_slope", NAP_SLOPE, lo=0))
    if model == "case1":
        variant = spec.choice("variant", "classic", CASE1_VARIANTS)
        chl = spec.number("chlorophyll", lo=0, lo_open=(variant == "new"))
        columns = ("a_star",) if variant == "classic" else ("A", "E")
        table = _table_from_spec(spec, "chlorophyll_absorption", columns, base_dir)
        phase: Any = PhaseFunction("petzold") if variant == "classic" else MM01
        if "particle_phase" in d:
            phase = _phase_from_spec(spec, "particle_phase", variant == "new")
        covarying, slope, extra = True, CDOM_SLOPE, []
        c = d.get("cdom", "covarying")
        if c == "none":
            covarying = False
        elif isinstance(c, Mapping) and "a_ref" in c:
            covarying = False
            _Spec(c, obj, f"{prefix}cdom.", ("a_ref", "wavelength_ref_nm", "slope"))
            extra.append(_constituent({**c, "model": "cdom"}, bands, obj, f"{prefix}cdom.",
                                      base_dir, True))
        elif isinstance(c, Mapping):
            slope = _Spec(c, obj, f"{prefix}cdom.", ("slope",)).number("slope", lo=0)
        elif c != "covarying":
            raise spec.error("cdom", f"must be 'covarying', 'none', {{'slope': S}} or "
                                     f"{{'a_ref': ..., 'wavelength_ref_nm': ..., 'slope': ...}}, "
                                     f"got {_show(c)}")
        fn = case1_classic if variant == "classic" else case1_new
        if variant == "new" and isinstance(phase, str) and phase == MM01:
            # (the particles' backscatter fraction follows the chlorophyll: far outside the
            # model's range it leaves the Fournier-Forand range, the chlorophyll's problem)
            ratio = morel_maritorena_backscatter_ratio(chl, bands)
            lo, hi = FF_BACKSCATTER_RANGE
            bad = np.flatnonzero(~((ratio >= lo) & (ratio <= hi)))
            if bad.size:
                k = int(bad[0])
                raise spec.error("chlorophyll", f"{chl:g} mg m^-3 gives the particles a backscatter fraction "
                                                f"b_bp/b_p of {ratio[k]:.4g} in {_as_bands(bands)[k].label}, outside the "
                                                f"Fournier-Forand range [{lo:g}, {hi:g}] (Morel and "
                                                f"Maritorena 2001's b_bp is fitted for about 0.02-30 mg m^-3)")
        # a band outside the table is the table's field's problem
        out = _run(spec, "chlorophyll_absorption", fn, bands, chl, table,
                   covarying_cdom=covarying, cdom_slope=slope, particle_phase=phase)
        return mix(out, *extra)
    # mixture
    comps = d.get("components")
    if not isinstance(comps, (list, tuple)) or not comps:
        raise spec.error("components", f"must be a non-empty list of models, got {_show(comps)}")
    return mix(zero, *(_constituent(c, bands, obj, f"{prefix}components[{i}].", base_dir, True)
                       for i, c in enumerate(comps)))


def fluorescent_absorption(spec: Mapping, bands, *, obj: str = "iop model", prefix: str = "",
                           base_dir: str | Path | None = None) -> dict[str, np.ndarray]:
    """The parts of a model's absorption that fluoresce (photic.inelastic), per band (m^-1):
    ``"phytoplankton"`` (the Case-1 models' particulate absorption a_p, all of it taken as
    phytoplankton's; for the new variant, A_ph C^E_ph where its table file has the columns
    ``A_ph`` and ``E_ph``, Bricaud et al. 1998's phytoplankton coefficients) and ``"cdom"``
    (the ``cdom`` models' and the Case-1 models' CDOM).
    Pure water, other particles and plugin models add nothing. Errors as ``iops_from_model``."""
    band_list = _as_bands(bands)
    zero = np.zeros(len(band_list))

    def parts(d: Any, pre: str) -> tuple[np.ndarray, np.ndarray]:
        name = d.get("model") if isinstance(d, Mapping) else None
        if name == "cdom":
            return zero, _constituent(d, band_list, obj, pre, base_dir, True).absorption
        if name == "case1":
            total = _constituent(d, band_list, obj, pre, base_dir, True).absorption
            a_p = _constituent({**d, "cdom": "none"}, band_list, obj, pre, base_dir, True).absorption
            return phytoplankton(d, pre, a_p), total - a_p
        return parts_of_mixture(d, pre) if name == "mixture" else (zero, zero)

    def phytoplankton(d: Mapping, pre: str, a_p: np.ndarray) -> np.ndarray:
        # (the new variant's table may hold Bricaud et al.'s phytoplankton columns too)
        if d.get("variant") != "new":
            return a_p
        table = _table_from_spec(_Spec(d, obj, pre), "chlorophyll_absorption", ("A", "E"), base_dir)
        if not {"A_ph", "E_ph"} <= set(table.columns):
            return a_p
        chl = float(d["chlorophyll"])
        return np.array([_band_mean(lambda wl: table("A_ph", wl) * chl ** table("E_ph", wl), x, table.wavelength_nm)
                         for x in band_list])

    def parts_of_mixture(d: Mapping, pre: str) -> tuple[np.ndarray, np.ndarray]:
        got = [parts(c, f"{pre}components[{i}].") for i, c in enumerate(d.get("components") or [])]
        return sum((g[0] for g in got), zero), sum((g[1] for g in got), zero)

    iops_from_model(spec, bands, obj=obj, prefix=prefix, base_dir=base_dir)  # (errors first, named)
    a_ph, a_cdom = parts({k: v for k, v in spec.items() if k != "water"}, prefix)
    return {"phytoplankton": np.asarray(a_ph, float), "cdom": np.maximum(np.asarray(a_cdom, float), 0.0)}


def iops_from_model(spec: Mapping, bands, *, obj: str = "iop model", prefix: str = "",
                    base_dir: str | Path | None = None) -> IOPs:
    """Per-band IOPs from a model description (format in the module docstring).

    Parameters
    ----------
    spec : dict
        The model description.
    bands : sequence
        ``photic.scene.Band``s, or (centre_nm, width_nm) or (name, centre_nm, width_nm) tuples.
    obj, prefix : str
        Name the object and the field path in errors, e.g. ``obj="water 'sea'"`` and
        ``prefix="iop_model."``.
    base_dir : path, optional
        Directory for relative table files.

    Raises
    ------
    photic.scene.SceneError
        Naming the field: unknown model or field, bad numbers, a band outside a table.
    """
    try:
        band_list = _as_bands(bands)
    except ValueError as exc:
        raise SceneError(obj, "bands", str(exc)) from None
    top = _Spec(spec, obj, prefix)
    water = top.choice("water", "pope_fry", WATER_ABSORPTION_SOURCES + ("none",))
    constituents = _constituent(spec, band_list, obj, prefix, base_dir, False)
    if water == "none":
        return constituents
    return mix(_run(top, "water", pure_water, band_list, water), constituents)
