"""Photic's Raman Rrs against quasi-single-scattering (QSS) models of ocean-colour work, on the
waters of ``scripts/raman_rrs.py`` (pure water, a little CDOM, particles; a flat deep sea, the
sun at 30 deg, a black sky, 16 bands of 20 nm from 400 to 700 nm).

The models, each evaluated with the scene's own IOPs per band (a, b_b) and Photic's own
band coupling (``inelastic.raman_coupling``: what the refracted sun's irradiance E_d(0-, i) in
excitation band i gives emission band k, S_k = sum_i m[k, i] E_d(0-, i)), so that they differ
from Photic only in the transport:

- Westberry, Boss and Lee (2013), Appl. Opt. 52, 5552, their Eq. 7 (after Sathyendranath and
  Platt 1998 and Mobley's HydroLight technical note 10):
  Rrs_R = S / (4 pi n^2 (K_d,ex + K_Lu) E_d(0+)) (1 + b_b,ex / (mu_u (K_d,ex + kappa_ex)) + b_b / kappa),
  K_d = (a + b_b) / mu_d, kappa = (a + b_b) / mu_u, K_Lu = (a + b_b) 1.03 (1 + 2.4 u)^0.5 (nadir
  view; u = b_b / (a + b_b)), mu_u = 0.5; mu_d here the refracted sun's cosine; the excitation
  side's K_d, kappa and b_b weighted over the excitation bands by their share of S.
- Lee, Carder, Hawes, Steward, Peacock and Davis (1994), Appl. Opt. 33, 5721:
  Rrs_R = 0.072 S / ((2 a + a_ex) E_d(0+)).
- The single scattering of the direct beam alone, exact (as the closed form in
  tests/test_raman.py: the Raman phase function at the scattering angle, attenuation c = a + b
  + b_R along both legs, out through the surface): a floor, which light scattered elastically
  on either leg adds to (much of it where the particles' forward peak keeps the light going).

Expected differences, before any measurement: the QSS model takes Raman emission as isotropic
(1 / 4 pi), where towards the nadir from a sun refracted to 22 deg the Raman phase function is
1.245 / 4 pi (1 + 0.55 cos^2 psi, normalised); its source is b_R times the downward irradiance
E_d(0-), where the direct beam's scalar irradiance, which Raman scattering takes, is E_d / mu_w
(1.079 E_d); and it leaves out the surface's transmittance of Lu (0.98). The column "W. exact"
is Westberry's with these three put back (x 1.245 x 1.079 x 0.98 = 1.316).

    .venv/bin/python scripts/raman_qss.py [--particles 0 0.02 0.3] [--samples 400000]
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from photic import inelastic
from photic._core import fresnel
from photic.render import render
from raman_rrs import CENTERS, ZENITH, scene

N_WATER = 1.34
MU_U = 0.5


def backscattering(iops) -> np.ndarray:
    bb = np.zeros(len(CENTERS))
    for c in iops.scattering:
        frac = 0.5 if c.phase.type == "pure_water" else float(c.phase.params["backscatter_fraction"])
        bb += frac * np.asarray(c.b)
    return bb


def models(sc) -> dict:
    sc.validate()
    w = sc.water[0]
    a = np.asarray(w.iops.absorption, float)
    b = sum(np.asarray(c.b, float) for c in w.iops.scattering)
    bb = backscattering(w.iops)
    mu0 = math.cos(math.radians(ZENITH))
    mu_w = math.sqrt(1.0 - (math.sin(math.radians(ZENITH)) / N_WATER) ** 2)
    ed_air = mu0                                        # E_d(0+): the sun's 1 normal to it
    ed_w = mu0 * (1.0 - fresnel(mu0, 1.0, N_WATER))     # E_d(0-) of the direct sun
    m = inelastic.raman_coupling(sc.bands)
    src = m * ed_w                                      # [k, i]: band i's part of S_k
    S = src.sum(axis=1)
    share = np.divide(src, S[:, None], out=np.zeros_like(src), where=S[:, None] > 0)
    kd = (a + bb) / mu_w
    kappa = (a + bb) / MU_U
    kd_ex, kappa_ex, bb_ex, a_ex = share @ kd, share @ kappa, share @ bb, share @ a
    u = bb / (a + bb)
    klu = (a + bb) * 1.03 * np.sqrt(1.0 + 2.4 * u)
    with np.errstate(invalid="ignore", divide="ignore"):
        westberry = S / (4 * math.pi * N_WATER ** 2 * (kd_ex + klu) * ed_air) * \
            (1.0 + bb_ex / (MU_U * (kd_ex + kappa_ex)) + bb / kappa)
        lee = 0.072 * S / ((2.0 * a + a_ex) * ed_air)
        # exact single scattering of the direct beam into the nadir, out through the surface
        c = a + b + inelastic.raman_b(CENTERS)
        cos_psi = -mu_w                                 # beam down at mu_w, view straight up
        p = float(inelastic.raman_phase(cos_psi))
        t_out = 1.0 - fresnel(1.0, N_WATER, 1.0)
        single = p * (m * (ed_w / mu_w) / (c[None, :] / mu_w + c[:, None])).sum(axis=1) * t_out / N_WATER ** 2 / ed_air
    # the three simplifications put back: emission's phase function, scalar irradiance, t
    exact = westberry * 4 * math.pi * p / mu_w * t_out
    return {"westberry": westberry, "exact": exact, "lee": lee, "single": single, "S": S}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=float, nargs="+", default=[0.0, 0.02, 0.3])
    ap.add_argument("--samples", type=int, default=400_000)
    a = ap.parse_args(argv)
    ed = math.cos(math.radians(ZENITH))
    for bp in a.particles:
        sc = scene(bp, True)
        r = render(sc, radiometer_samples=a.samples, threads=2).radiometers[0]
        raman, se = r.components["raman"][0][0] / ed, r.components["raman"][1][0] / ed
        mod = models(scene(bp, True))
        print(f"particles b(550) = {bp:g} m^-1: Raman Rrs (1e-4 sr^-1), Photic +- SE, and the models "
              f"(ratio Photic / model)")
        print(f"{'band':>5} {'Photic':>9} {'+-':>6} {'Westberry':>9} {'ratio':>6} {'W. exact':>9} {'ratio':>6} "
              f"{'Lee 94':>9} {'ratio':>6} {'1st order':>9} {'ratio':>6}")
        for k, lam in enumerate(CENTERS):
            if mod["S"][k] <= 0 or raman[k] <= 0:
                continue
            row = f"{lam:>5.0f} {1e4 * raman[k]:>9.4f} {1e4 * se[k]:>6.4f}"
            for key in ("westberry", "exact", "lee", "single"):
                row += f" {1e4 * mod[key][k]:>9.4f} {raman[k] / mod[key][k]:>6.2f}"
            print(row)


if __name__ == "__main__":
    main()
