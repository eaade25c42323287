"""Water types: a water object's IOPs from measured natural waters, chosen by name.

Each type is one of Petzold's (1972) stations, whose absorption a, scattering b and
backscatter fraction b_b/b were measured at 530 nm (Petzold 1972, SIO Ref. 72-78, as
transcribed in the PyPI package jerlov 0.22.0, ``jerlov/data/petzold1972_stations.csv``; the
project's reference copy: ``petzold1972_stations.csv``). Spread over wavelength as an IOP model
(``photic.iop_models``, docs/iop-models.md):

- pure water: absorption Pope & Fry 1997, scattering 0.00288 (lambda/500)^-4.32 (Morel 1974);
- the rest of the absorption, a(530) - a_w(530) (a_w(530) = 0.0434 m^-1, Pope & Fry), as
  CDOM and detritus, exp(-0.014 (lambda - 530)) (HydroLight's slope; an assumption: only the
  530 nm value is measured);
- the rest of the scattering, b(530) - b_w(530), as particles, (530/lambda)^1, with a
  Fournier-Forand phase function whose backscatter fraction makes the total b_b/b at 530 nm the
  station's.

At 530 nm the model gives the station's a, b and b_b/b (tests/test_blender_onboarding.py).
These are Jerlov-type waters from clear ocean to turbid coastal water, but Jerlov's classes are
defined by diffuse attenuation, not IOPs: no class is claimed. No lake station is in the
reference data: the turbid type is a harbour.
"""
from __future__ import annotations

import json

#: Pure water at 530 nm: absorption (Pope & Fry 1997) and scattering (Morel 1974), m^-1.
A_WATER_530 = 0.0434
B_WATER_530 = 0.00288 * (530.0 / 500.0) ** -4.32
CDOM_SLOPE = 0.014  # nm^-1

#: name -> (label, Petzold station, locale, a(530), b(530), b_b/b, description)
TYPES = {
    "COASTAL": ("Clear Coastal", "HAOCE 11", "Catalina Channel, offshore southern California",
                0.179, 0.219, 0.013, "clear coastal water, green-blue"),
    "CLEAR_OCEAN": ("Clear Ocean", "AUTEC 7", "Tongue of the Ocean, Bahamas",
                    0.082, 0.117, 0.025, "clear oceanic water, blue"),
    "LAGOON": ("Lagoon / Cove", "HAOCE 5", "Avalon Cove, Catalina Island",
               0.195, 0.275, 0.014, "a sheltered cove, green"),
    "TURBID": ("Turbid Harbour", "NUC 2200", "San Diego Harbor",
               0.337, 1.583, 0.019, "turbid harbour water, a few metres of visibility "
                                    "(no lake is in the reference data)"),
}
DEFAULT = "COASTAL"
CUSTOM = "CUSTOM"
SOURCE = "Petzold 1972 (SIO Ref. 72-78), stations measured at 530 nm"

#: The properties that describe a water's IOPs by hand: once one is set (in a file from before
#: water types, or edited), the water is 'Custom' unless a water type was chosen since.
IOP_FIELDS = ("iop_source", "iop_model", "absorption", "absorption_bands", "scattering",
              "scattering_bands", "phase_function", "hg_g", "ff_backscatter")


def enum_items():
    items = [(k, v[0], f"{v[6][0].upper()}{v[6][1:]}: Petzold's station {v[1]}, "
                                      f"{v[2]}: a = {v[3]} m^-1, b = {v[4]} m^-1 at 530 nm, "
                                      f"b_b/b = {v[5]}")
             for k, v in TYPES.items()]
    items.append((CUSTOM, "Custom", "The IOPs given below (coefficients, pure water plus "
                                    "additions, or an IOP model)"))
    return items


def model(name: str) -> dict:
    """The IOP model description (photic.iop_models) of a water type."""
    _, _, _, a, b, bb, _ = TYPES[name]
    return {"model": "mixture", "water": "pope_fry", "components": [
        {"model": "cdom", "a_ref": round(a - A_WATER_530, 6), "wavelength_ref_nm": 530.0,
         "slope": CDOM_SLOPE},
        {"model": "particles", "b_ref": round(b - B_WATER_530, 6), "wavelength_ref_nm": 530.0,
         "exponent": 1.0, "backscatter_fraction": particle_backscatter(b, bb)}]}


def particle_backscatter(b: float, bb: float) -> float:
    """The particles' b_bp/b_p that gives the station's total b_b/b at 530 nm (Petzold's VSFs
    include the water, which scatters half backwards)."""
    return round((bb * b - 0.5 * B_WATER_530) / (b - B_WATER_530), 4)


def model_json(name: str) -> str:
    return json.dumps(model(name))


def effective(p) -> str:
    """The water type a water object's IOPs come from: its Water Type, except in a file from
    before water types (the IOPs set by hand, no type chosen): there 'Custom'."""
    if p.water_type != CUSTOM and not p.is_property_set("water_type") \
            and any(p.is_property_set(k) for k in IOP_FIELDS):
        return CUSTOM
    return p.water_type


def describe(name: str) -> str:
    label, station, locale, a, b, bb, text = TYPES[name]
    return f"Petzold 1972, station {station} ({locale}): a {a}, b {b} m⁻¹ at 530 nm"
