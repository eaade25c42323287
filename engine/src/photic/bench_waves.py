"""``photic bench --error --cases waves``: radiometers under a family of wave patches, each
against the same scene over a flat sea.

Every member is one ocean scene (a 0.1, b 0.2 Petzold, sand 5 m down, the real 0.53 deg sun)
with 64 Ed radiometers 2 m deep on an 8 x 8 grid over one period of its JONSWAP patch; the
members differ in the patch's size, the wind, the patch's grid points per side and the sun's
zenith angle. Per member, the CPU time (all threads) of whole renders, the beam builds
included, under the waves over the same over a flat sea:

- ``total``: at ``samples`` (1,000) samples per radiometer, user and system time;
- ``margin``: of the extra cost of ``samples_hi`` samples over ``samples`` (the same number of
  beam builds in both: the cost per sample alone), in user CPU time. The system time is left
  out of the margin: it is nearly all the build's page faults, whose cost is the same at any
  number of samples but varies 10-fold from one render to the next (transparent huge pages
  faulted in for the first time: 0.06 to 0.7 s for the same 53 pages on the 2-core machine),
  which made the margin of a fine patch read too low whenever the run with fewer samples drew
  the slow build.

Runs are paired (waves and flat with the same seed, one after the other) and interleaved over
members and repeats (the machine's load drifts over both alike); the ratios are medians over
the repeats of each repeat's ratio.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import dataclass

import numpy as np

from .scene import Scene


@dataclass(frozen=True)
class WaveMember:
    name: str
    patch_m: float        # the patch's side
    wind: float           # m/s
    grid: int             # the patch's grid points per side
    sun_zenith: float     # deg


# Patches 10-50 m, winds 3-12 m/s, 32-128 points per side, the sun 0-60 deg from the zenith;
# "issue" is the configuration of issue 46.
WAVE_FAMILY = (
    WaveMember("issue", 20.0, 6.0, 64, 30.0),
    WaveMember("small calm", 10.0, 3.0, 32, 0.0),
    WaveMember("small rough fine", 10.0, 12.0, 128, 45.0),
    WaveMember("large rough fine", 50.0, 12.0, 128, 60.0),
    WaveMember("large calm", 50.0, 3.0, 32, 15.0),
    WaveMember("medium", 30.0, 9.0, 96, 60.0),
)


def wave_member_scene(member: WaveMember, surface: str, samples: int, radiometers_per_side: int = 8) -> Scene:
    """The member's scene under its waves (surface "waves") or over a flat sea ("flat")."""
    L = member.patch_m
    g = (np.arange(radiometers_per_side) + 0.5) * L / radiometers_per_side
    waves = {"kind": "waves", "spectrum": "jonswap", "wind_speed": member.wind, "fetch_m": 50000.0,
             "patch_size_m": [L, L], "resolution": [member.grid, member.grid], "seed": 0}
    d = {"photic_scene": 1, "name": f"radiometers_{surface}",
         "materials": {"sand": {"type": "lambertian", "reflectance": [0.3]}},
         "water": [{"name": "sea", "type": "ocean",
                    "surface": {"kind": "flat", "z": 0.0} if surface == "flat" else waves,
                    "bottom": {"depth": 5.0, "material": "sand"},
                    "iops": {"absorption": [0.1], "b": [0.2], "phase": {"type": "petzold"}}}],
         "sun": {"zenith_deg": member.sun_zenith, "azimuth_deg": 290.0, "irradiance": [1.0],
                 "angular_diameter_deg": 0.53},
         "radiometers": [{"name": f"r{i}", "quantity": "Ed", "position": [float(x), float(y), -2.0]}
                         for i, (x, y) in enumerate((x, y) for x in g for y in g)],
         "settings": {"integrator": "hybrid", "radiometer_samples": samples}}
    return Scene.from_dict(d)


def _cpu_times() -> tuple[float, float]:
    """This process's (user, system) CPU seconds, all threads; (process time, 0) where the
    platform does not split them."""
    try:
        import resource
    except ImportError:  # (Windows)
        return time.process_time(), 0.0
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime, r.ru_stime


def _cpu_render(scene: Scene, seed: int, threads: int) -> tuple[float, float, dict]:
    """A render's user and system CPU seconds and its stats."""
    from .render import render
    from .waves import surface_patch

    surface_patch.cache_clear()  # every render synthesises its waves, as a fresh one does
    u0, s0 = _cpu_times()
    res = render(scene, seed=seed, threads=threads)
    u1, s1 = _cpu_times()
    return u1 - u0, s1 - s0, res.stats


def run_wave_family(members=WAVE_FAMILY, threads: int = 2, repeats: int = 5, samples: int = 1000,
                    samples_hi: int = 4000, progress=None) -> list[dict]:
    """Per member: the medians of the paired ratios waves / flat ("total" at ``samples``,
    "margin" between ``samples`` and ``samples_hi``), the median CPU seconds of each run and
    the waves' beam build time (wall, inside the render)."""
    say = progress or (lambda msg: None)
    cpu = {(m.name, s, n): [] for m in members for s in ("waves", "flat") for n in (samples, samples_hi)}
    user = {k: [] for k in cpu}
    build = {m.name: [] for m in members}
    for rep in range(repeats):
        for mi, m in enumerate(members):
            runs = [(s, n) for n in (samples, samples_hi) for s in ("waves", "flat")]
            if (rep + mi) % 2:  # alternate which surface goes first
                runs = [(s, n) for n in (samples, samples_hi) for s in ("flat", "waves")]
            for s, n in runs:
                tu, ts, stats = _cpu_render(wave_member_scene(m, s, n), 1 + rep, threads)
                cpu[(m.name, s, n)].append(tu + ts)
                user[(m.name, s, n)].append(tu)
                if s == "waves" and n == samples:
                    build[m.name].append(stats["beam_build_s"])
            say(f"waves family, repeat {rep + 1}/{repeats}, {m.name}: "
                f"{cpu[(m.name, 'waves', samples)][-1]:.2f} / {cpu[(m.name, 'flat', samples)][-1]:.2f} CPU-s")
    out = []
    for m in members:
        w1, f1 = cpu[(m.name, "waves", samples)], cpu[(m.name, "flat", samples)]
        total = [a / b for a, b in zip(w1, f1)]
        uw1, uf1 = user[(m.name, "waves", samples)], user[(m.name, "flat", samples)]
        uw2, uf2 = user[(m.name, "waves", samples_hi)], user[(m.name, "flat", samples_hi)]
        margin = [(a2 - a1) / (b2 - b1) for a1, b1, a2, b2 in zip(uw1, uf1, uw2, uf2)]
        out.append({"member": m.name, "patch_m": m.patch_m, "wind": m.wind, "grid": m.grid,
                    "sun_zenith": m.sun_zenith, "samples": samples, "samples_hi": samples_hi,
                    "cpu_s": {f"{s}_{n}": float(statistics.median(cpu[(m.name, s, n)]))
                              for s in ("waves", "flat") for n in (samples, samples_hi)},
                    "beam_build_s": float(statistics.median(build[m.name])),
                    "beam_build_s_range": [float(min(build[m.name])), float(max(build[m.name]))],
                    "ratio_total": float(statistics.median(total)), "ratio_margin": float(statistics.median(margin)),
                    "ratios_total": total, "ratios_margin": margin})
    return out


def format_wave_family(records: list[dict]) -> str:
    r0 = records[0]
    lines = [f"64 Ed radiometers 2 m deep over one period, waves / flat sea (CPU time, medians of paired runs): "
             f"total at {r0['samples']:,} samples each, margin (user time) from {r0['samples']:,} to "
             f"{r0['samples_hi']:,}",
             "  member               patch  wind  grid  sun   waves CPU-s  flat CPU-s  build s   total  margin",
             "                          m   m/s        deg   at {:>6,}  at {:>6,}   (wall)".format(
                 r0["samples"], r0["samples"])]
    for r in records:
        w, f = r["cpu_s"][f"waves_{r['samples']}"], r["cpu_s"][f"flat_{r['samples']}"]
        lines.append(f"  {r['member']:<18} {r['patch_m']:6.0f} {r['wind']:5.0f} {r['grid']:5d} {r['sun_zenith']:4.0f} "
                     f"{w:12.2f} {f:11.2f} "
                     f"{r['beam_build_s']:8.2f} {r['ratio_total']:6.2f}x {r['ratio_margin']:6.2f}x"
                     + (f"   (builds {r['beam_build_s_range'][0]:.2f}-{r['beam_build_s_range'][1]:.2f} s)"
                        if "beam_build_s_range" in r else ""))
    return "\n".join(lines)
