"""Progressive rendering of a scene: cameras and radiometers, with Monte Carlo errors.

Work is split into passes whose boundaries depend only on the sample counts, never on the
thread count, and the core sums each pass in a fixed order, so one seed gives the same numbers
bit for bit on any number of threads. Every pass reports progress; a cancel stops at the next
pass boundary (or sooner: the core checks its flag between rows and chunks) and the result
keeps only completed passes.
"""
from __future__ import annotations

import math
import os
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from .compile import compile_scene, inelastic_group_warnings, scene_band_groups
from .parameters import check_parameter
from .safe_io import machine_memory
from .estimates import (CameraSums, RadiometerSums, bin_counts, combine_round_sums,
                        image_variance, mean_stderr)
from .scene import IOPGrid, IOPProfile, Scene, SceneError, scene_warnings

RADIOMETER_PASS = 1 << 16  # samples per radiometer pass (a multiple of the core's chunk)
PAIRED_PASS = 1 << 12      # at most this many per pass in paired strata (more pairs, finer strata)
MIN_PAIRED_PASSES = 8      # paired strata: at least 4 pairs (photic.estimates.MIN_STRATA)
FIRST_ROUND = 4096         # target error: samples per radiometer of the first round
MIN_ROUND = 1024           # ... and at least this many in each further round
ROUND_MARGIN = 1.1         # ... which asks for this much more than the error's N^-1/2 predicts
ROUND_GROUPING = 1.5       # radiometers needing within this factor of a round's size join it
UNITS_RADIANCE = "W m^-2 sr^-1 (per unit of the band's source spectrum, e.g. nm^-1)"
UNITS_IRRADIANCE = "W m^-2 (per unit of the band's source spectrum, e.g. nm^-1)"
IRRADIANCE_QUANTITIES = {"Ed", "Eu", "Eo", "Eod", "Eou"}


COMPONENTS = ("beam_surface", "beam_volume", "path", "beam_direct", "raman", "chlorophyll", "cdom")
# A camera's component passes (beam_direct is a radiometer's own; raman with settings.raman,
# chlorophyll and cdom where a water's chlorophyll or CDOM fluoresces).
IMAGE_COMPONENTS = ("beam_surface", "beam_volume", "path", "raman", "chlorophyll", "cdom")


def image_components(scene) -> tuple[str, ...]:
    """The component passes of a scene's pixels."""
    from .inelastic import raman_active
    out = IMAGE_COMPONENTS[:3]
    if raman_active(scene):
        out += ("raman",)
    if any(getattr(w, "fluorescence", None) is not None for w in scene.water):
        out += ("chlorophyll",)
    if any(getattr(w, "cdom_fluorescence", None) is not None for w in scene.water):
        out += ("cdom",)
    return out


@dataclass
class ImageResult:
    name: str
    mean: np.ndarray          # (H, W, nbands) radiance
    variance: np.ndarray      # (H, W, nbands) variance of the per-pixel mean (standard error^2)
    samples: int              # samples per pixel (with adaptive sampling: the most any pixel took)
    components: dict = field(default_factory=dict)  # name -> (H, W, nbands) mean
    # Adaptive sampling (settings.noise_threshold): samples each pixel took (H, W), and whether
    # it stopped at the threshold; None otherwise.
    pixel_samples: np.ndarray | None = None
    converged: np.ndarray | None = None
    noise_threshold: float | None = None
    # Denoising guides (Renderer(guides=True)): albedo (H, W, nbands) in [0, 1] and normal
    # (H, W, 3), noise-free (photic.denoise); None otherwise.
    albedo: np.ndarray | None = None
    normal: np.ndarray | None = None

    @property
    def units(self) -> str:
        return UNITS_RADIANCE


@dataclass
class RadiometerResult:
    name: str
    quantity: str
    position: np.ndarray
    medium: str               # "air" or the water body's name
    mean: np.ndarray          # (nbins, nbands); nbins = 1 except radiance distributions
    stderr: np.ndarray        # (nbins, nbands)
    samples: int              # total samples (shared by the bins of a distribution)
    bins: tuple[int, int] | None = None  # (polar, azimuth) for radiance distributions
    components: dict = field(default_factory=dict)  # name -> (mean, stderr), each (nbins, nbands)
    # Whether each standard error can be trusted (nbins, nbands), and why not (photic.estimates:
    # "too few passes", "heavy tails", ...); vov: the relative variance of the variance.
    reliable: np.ndarray | None = None
    notes: list = field(default_factory=list)
    vov: np.ndarray | None = None
    # With a target relative error (settings.target_error): the worst relative standard error
    # over bins and bands, and whether the target was met with errors that can be trusted.
    target_error: float | None = None
    relative_error: float | None = None
    target_reached: bool | None = None

    @property
    def units(self) -> str:
        return UNITS_IRRADIANCE if self.quantity in IRRADIANCE_QUANTITIES else UNITS_RADIANCE


@dataclass
class RenderResult:
    scene_name: str
    bands: list
    images: dict[str, ImageResult] = field(default_factory=dict)
    radiometers: list[RadiometerResult] = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    cancelled: bool = False
    # Problems that did not stop the render but make some of its numbers useless (a sensor
    # inside an opaque object or below the sea floor, a sun without light; scene_warnings).
    warnings: list = field(default_factory=list)

    def radiometer(self, name: str) -> RadiometerResult:
        for r in self.radiometers:
            if r.name == name:
                return r
        raise KeyError(name)


def resolve_integrator(scene: Scene) -> str:
    """'hybrid' or 'path': the scene's choice, 'auto' meaning hybrid when there is a sun."""
    choice = scene.settings.integrator
    if choice == "auto":
        return "hybrid" if scene.sun is not None else "path"
    return choice



def optical_depth_scale(scene: Scene) -> float:
    """The largest attenuation depth c * D over the water bodies and bands (D: bottom depth,
    mesh height; infinite for a bottomless ocean)."""
    tau = 0.0
    for w in scene.water:
        if w.type == "ocean":
            depth = np.inf if w.bottom_depth is None else float(w.bottom_depth)
            top = float(w.surface.z)
        else:
            z = np.asarray(w.mesh.vertices)[:, 2]
            depth = float(z.max() - z.min())
            top = float(z.max())
        if isinstance(w.iops, IOPGrid):  # 3-D: bounded by the densest voxel everywhere
            g = w.iops
            unit = 0.0
            for rho, u in zip(g.densities(), g.units()):
                rmax = float(np.max(rho)) if np.size(rho) else 0.0
                unit = unit + rmax * (np.asarray(u.absorption) + np.asarray(u.total_scattering))
            for b in (g.iops.layers if isinstance(g.iops, IOPProfile) else [g.iops]):
                c = float(np.max(np.asarray(b.absorption) + np.asarray(b.total_scattering) + unit))
                tau = max(tau, c * depth if c > 0 else 0.0)
            continue
        if isinstance(w.iops, IOPProfile):  # stratified: the vertical column's optical depth
            tau = max(tau, _profile_optical_depth(w.iops, top, top - depth))
            continue
        c = float(np.max(np.asarray(w.iops.absorption) + np.asarray(w.iops.total_scattering)))
        tau = max(tau, c * depth if c > 0 else 0.0)
    return tau


def _profile_optical_depth(profile: IOPProfile, z_hi: float, z_lo: float) -> float:
    """Largest over bands of int (a + b) dz from z_lo to z_hi (m) through the layers."""
    tops = np.asarray(profile.z_top, dtype=np.float64)
    total = 0.0
    for i, layer in enumerate(profile.layers):
        hi = z_hi if i == 0 else min(z_hi, tops[i])
        lo = max(z_lo, tops[i + 1]) if i + 1 < len(tops) else z_lo
        if hi > lo:
            c = np.asarray(layer.absorption) + np.asarray(layer.total_scattering)
            total = total + np.array([ck * (hi - lo) if ck > 0 else 0.0 for ck in c])
    return float(np.max(total))


AUTO_CONE_TAU = 10.0       # optically deeper than this: use a forward cone
AUTO_CONE_DEG = 3.0        # its half-angle


def beams_laterally_uniform(scene: Scene) -> bool:
    """Whether the sun's beams in the water are the same at every point of a depth: every
    ocean flat (sub-grid roughness only tilts each pass's one beam), no water meshes and no
    opaque objects. Only there is a forward cone exact: it keeps the light scattered within it
    inside its own beam, going straight on, where real small-angle scattering spreads it
    sideways. Wave patches' caustics and shadows, and objects' shadows, then stay too sharp:
    point by point 0.83-1.16x the exact mode's Ed 5 m below waves under a 30 deg sun, 0.77x 1 m
    down under an 80 deg one (docs/verification.md). (Gridded water's structure, metres across,
    is left out.)"""
    if scene.meshes:
        return False
    return all(w.type == "ocean" and w.surface.kind == "flat" for w in scene.water)


def resolve_forward_cone(scene: Scene) -> float:
    """Forward-scattering cone half-angle (degrees) for the hybrid integrator.

    The rule ('auto'): shallow or clear water (c * depth <= 10) keeps the full phase function,
    which is exact and cheap there; optically deeper water whose beams are the same across
    (beams_laterally_uniform: flat seas without objects) keeps the light scattered within 3
    degrees of the beam in the beam (c_beam = a + b (1 - f)), which removes the rare, very bright
    paths that head straight at the refracted sun. Below waves or with objects the cone would be
    biased, so the full phase function is kept there too. The error of each choice on the
    canonical problems is measured by `photic bench --error` (docs/benchmarks.md).
    """
    value = scene.settings.forward_cone_deg
    if value != "auto":
        return float(value)
    if not beams_laterally_uniform(scene):
        return 0.0
    return AUTO_CONE_DEG if optical_depth_scale(scene) > AUTO_CONE_TAU else 0.0


FORWARD_CONE_STRUCTURE = ("forward cone with waves or objects: light scattered within the cone stays in "
                          "its beam, so caustics and shadows stay too sharp (local errors of 10-20 % "
                          "measured; forward_cone_deg 0 is exact)")


def forward_cone_biased(scene: Scene, hybrid: bool, forward_cone_deg: float) -> bool:
    """Whether the hybrid's forward cone is in use where its beams are not uniform across."""
    return hybrid and forward_cone_deg > 0.0 and scene.sun is not None and not beams_laterally_uniform(scene)


def forward_cone_warning(scene: Scene, hybrid: bool, forward_cone_deg: float) -> list[str]:
    """The render log's warning for a forward cone whose beams are not uniform across."""
    if not forward_cone_biased(scene, hybrid, forward_cone_deg):
        return []
    return [f"settings.forward_cone_deg = {forward_cone_deg:g} deg: {FORWARD_CONE_STRUCTURE}"]


def concentric_disk(u1: float, u2: float) -> tuple[float, float]:
    """A point of the unit square mapped to the unit disk, preserving areas with little
    distortion (Shirley & Chiu 1997): strata of the square stay compact on the disk."""
    a, b = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r, phi = a, np.pi / 4 * (b / a)
    else:
        r, phi = b, np.pi / 2 - np.pi / 4 * (a / b)
    return r * np.cos(phi), r * np.sin(phi)


def sun_direction(scene: Scene, u1: float, u2: float) -> np.ndarray:
    """The direction of the sun's disk at the square's point (u1, u2): uniform in solid angle
    for uniform (u1, u2)."""
    s = np.asarray(scene.sun.direction, float)
    alpha = np.radians(scene.sun.angular_diameter_deg) / 2
    x, y = concentric_disk(u1, u2)
    rho2 = x * x + y * y
    cos_t = 1.0 - rho2 * (1.0 - np.cos(alpha))
    phi = np.arctan2(y, x)
    a = np.array([1.0, 0.0, 0.0]) if abs(s[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(s, a); u /= np.linalg.norm(u)
    v = np.cross(s, u)
    sin_t = np.sqrt(max(0.0, 1 - cos_t * cos_t))
    d = cos_t * s + sin_t * (np.cos(phi) * u + np.sin(phi) * v)
    return d / np.linalg.norm(d)


def strata_grid(k: int) -> tuple[int, int]:
    """k equal strata of the unit square as an a x b grid (a <= b, a as large as divides k)."""
    a = int(np.sqrt(k))
    while k % a:
        a -= 1
    return a, k // a


def pass_draw(seed: int, key: tuple, i: int, n: int, paired: bool,
              rough: bool = False) -> tuple[float, float, float, float]:
    """The random numbers of pass ``i`` of ``n``: (u1, u2) for its sun direction and (f1, f2)
    for a rough sea's facet. Paired passes (radiometers): passes 2k and 2k + 1 draw
    independently in stratum k of n // 2 strata (photic.estimates) of the square of the sun's
    direction, or with a ``rough`` sea of its facet's (whose spread, over slopes of several
    degrees, is the larger one by far); otherwise every pass draws independently (cameras).
    Deterministic per seed, sensor ``key`` and pass, and the same for every band group, so
    spectra share their directions."""
    r = np.random.default_rng([seed, 0x5D15C, *key, i]).random(4)
    if paired and n >= 2:
        a, b = strata_grid(n // 2)
        k = min(i // 2, n // 2 - 1)
        j = 2 if rough else 0
        r[j], r[j + 1] = (k % a + r[j]) / a, (k // a + r[j + 1]) / b
    return r[0], r[1], r[2], r[3]


# --- pieces shared with photic.distributed, whose work units must reproduce these passes -----

# Kept under their old names for photic.distributed and the tests.
_bin_counts = bin_counts
_mean_stderr = mean_stderr


def camera_passes(samples: int) -> list[tuple[int, int]]:
    """(first sample, count) of each camera pass: 1, 2, 4, 8, then 16 samples per pixel."""
    passes, start, size = [], 0, 1
    while start < samples:
        n = min(size, samples - start)
        passes.append((start, n))
        start += n
        size = min(size * 2, 16)
    return passes


def radiometer_passes(samples: int, paired: bool) -> list[tuple[int, int]]:
    """(first sample, count) of each radiometer pass.

    paired (the hybrid integrator with a sun): an even number of passes, at least 8 (4 pairs
    of strata of the sun's disk: photic.estimates) and more for large counts (at most
    PAIRED_PASS samples each: 1M samples are 256 passes), whose sizes differ by one at most;
    otherwise passes of
    RADIOMETER_PASS samples."""
    if not paired:
        return [(s, min(RADIOMETER_PASS, samples - s)) for s in range(0, samples, RADIOMETER_PASS)]
    if samples < 2:
        return [(0, samples)]
    npass = MIN_PAIRED_PASSES
    while samples > npass * PAIRED_PASS:
        npass *= 2
    npass = min(npass, samples - samples % 2)
    base, extra = divmod(samples, npass)
    passes, start = [], 0
    for p in range(npass):
        n = base + (1 if p < extra else 0)
        passes.append((start, n))
        start += n
    return passes


MEMORY_SHARE = 0.8  # of the machine's memory a render may plan to use


def render_memory(scene: Scene) -> dict:
    """Bytes the largest buffers of a render will take, per item: each camera's running sums
    (components + total, squares, between-pass sums, samples: float64 per pixel and band) and
    the pass buffers; a generated wave patch's triangles (about 1 KiB each with beams: the
    prisms, their grid and Embree's BVH; 200 bytes without); the radiometers' per-bin sums."""
    nb = len(scene.bands)
    nc = len(COMPONENTS) + 1
    out = {}
    for c in scene.cameras:
        px = int(c.resolution[0]) * int(c.resolution[1])
        out[f"camera '{c.name}' ({c.resolution[0]} x {c.resolution[1]}, {nb} bands)"] = \
            px * 8 * (nb * (2 * nc + 3) + 4)
    beams = resolve_integrator(scene) == "hybrid" and scene.sun is not None
    for w in scene.water:
        waves = getattr(getattr(w, "surface", None), "waves", None)
        if waves is not None:  # the generated patch: its mesh, BVH and (hybrid) beam prisms
            tris = 2 * int(waves.resolution[0]) * int(waves.resolution[1])
            out[f"water '{w.name}' wave patch ({waves.resolution[0]} x {waves.resolution[1]}: "
                f"{tris:,} triangles)"] = tris * (1024 if beams else 200)
    bins = sum(r.polar_bins * r.azimuth_bins if r.quantity == "radiance_distribution" else 1
               for r in scene.all_radiometers())
    if bins:
        out[f"radiometers ({bins:,} bins)"] = bins * 8 * nb * (4 * nc + 8)
    return out


def check_memory(scene: Scene) -> None:
    """Refuse a render whose buffers would not fit the machine (SceneError naming the largest
    item, with the estimate), before anything is allocated."""
    total = machine_memory()
    need = render_memory(scene)
    if total is None or not need:
        return
    if sum(need.values()) > MEMORY_SHARE * total:
        what = max(need, key=need.get)
        raise SceneError(what, "memory", f"the render needs about {sum(need.values()) / 2**30:.1f} GiB "
                                         f"({need[what] / 2**30:.1f} GiB for this) but this machine has "
                                         f"{total / 2**30:.1f} GiB: lower the resolution, the bands or "
                                         f"the bins")


def uses_beams(scene: Scene, hybrid: bool) -> bool:
    """Whether a render builds beams (per pass): the hybrid integrator with a sun."""
    return hybrid and scene.sun is not None


def build_pass_beams(core, scene: Scene, seed: int, key: tuple, i: int, n: int, threads: int,
                     paired: bool, keep: bool = False) -> None:
    """Before pass ``i`` of ``n`` of the hybrid integrator: beams for the sun direction (and a
    rough sea's facet) that pass_draw gives it. Without a sun there are no beams. ``keep``:
    the core's beams were built by an earlier pass of this render; with the sun-disk blur
    (the prisms are then the sun centre's in every pass) they are kept, and only the shadow
    rays and a flat sea's beams take this pass's direction."""
    if scene.sun is None:
        return
    u1, u2, f1, f2 = pass_draw(seed, key, i, n, paired, core.ocean_rough)
    direction = tuple(sun_direction(scene, u1, u2))
    if core.ocean_rough:
        core.build_beams(direction, threads, (f1, f2))
    else:
        core.build_beams(direction, threads, keep_prisms=keep)
    check_beam_patch_copies(core, scene)


# Beam lookups under a periodic wave patch visit every copy of the patch whose beams reach the
# point; beyond this many copies (16 x 16) a lookup costs over ~60x the usual and a render's
# chunks stop answering Ctrl-C promptly (a 1 mm patch: 500,000 copies, no progress in minutes).
MAX_BEAM_PATCH_COPIES = 256


def check_beam_patch_copies(core, scene: Scene) -> None:
    """Refuse beams that spread over more copies of the ocean's patch than a lookup can visit
    in bounded time, naming the patch's size and what to do instead."""
    copies = float(core.beam_patch_copies())
    if copies <= MAX_BEAM_PATCH_COPIES:
        return
    w = next(w for w in scene.water if w.type == "ocean" and w.surface.kind != "flat")
    field = "surface.patch_size_m" if w.surface.kind == "waves" else "surface.period"
    period = w.surface.waves.patch_size_m if w.surface.kind == "waves" else w.surface.period
    side = max(float(p) for p in period)
    larger = side * math.sqrt(copies / MAX_BEAM_PATCH_COPIES)
    raise SceneError(f"water '{w.name}'", field,
                     f"the sun's refracted beams under this {side:.3g} m patch spread over about "
                     f"{copies:,.0f} copies of the patch on their way down, more than the "
                     f"{MAX_BEAM_PATCH_COPIES} a beam lookup visits in bounded time: use a patch of "
                     f"at least about {larger:.2g} m, or, for waves this much smaller than the "
                     f"beams' spread, a flat surface with their slopes as its roughness "
                     f"(surface.kind 'flat', surface.roughness.wind_speed)")


def check_sensors_off_boundaries(core, scene: Scene) -> None:
    """Refuse a radiometer on the boundary between two media (a water mesh's face, the sea
    surface): which side it measures would be decided by rounding (a tank-top sensor read
    5.40 against 1.17 just below or above). Tested by the medium 10 micrometres (plus the
    core's ray offset at that distance from the origin, 4e-6 of it) away along each axis: a
    sensor a tenth of a millimetre below the surface is fine."""
    for r in scene.all_radiometers():
        p = np.asarray(r.position, float)
        eps = 1e-5 + 4e-6 * float(np.max(np.abs(p)))
        media = set()
        for axis in range(3):
            for sign in (-1.0, 1.0):
                q = p.copy()
                q[axis] += sign * eps
                media.add(core.medium_at(tuple(map(float, q))))
        if len(media) > 1:
            names = sorted("air" if m < 0 else scene.water[m].name for m in media)
            raise SceneError(f"radiometer '{r.name}'", "position",
                             f"{p.tolist()} lies on the boundary between {' and '.join(names)} "
                             f"(within {eps:g} m): move it into one of them")


def sensor_warnings(core, scene: Scene) -> list[str]:
    """Cameras and radiometers that stand inside a closed opaque object: they see nothing."""
    out = []
    for c in scene.cameras:
        start = np.asarray(c.position, float) + np.asarray(c.direction, float) * float(c.clip_start)
        if core.inside_opaque(tuple(map(float, start))):
            out.append(f"camera '{c.name}': it is inside an opaque object, which hides everything "
                       f"(move it out or raise its clip start)")
    for r in scene.all_radiometers():
        if core.inside_opaque(tuple(map(float, r.position))):
            out.append(f"radiometer '{r.name}': it is inside an opaque object: no light reaches it, "
                       f"it reads 0")
    return out


@dataclass
class DisplaySums:
    """Rows [first, first + len(total)) of a camera's running sums of the total (rows, W,
    bands) with each pixel's samples (rows, W)."""
    total: np.ndarray
    n: np.ndarray
    first: int


IMAGE_BLOCK_ROWS = 32  # image_result works on bands of rows: its temporaries stay in cache


def image_result(name: str, sums: CameraSums, n: int, in_place: bool = False,
                 components: tuple[str, ...] = IMAGE_COMPONENTS[:3]) -> ImageResult:
    """A camera's result from its sums over ``n`` samples per pixel (adaptive sampling, or a
    pass under way: each pixel's own, from the sums). Done by bands of rows, so that a large
    image (1920 x 1080 x 10 bands) makes no large temporaries; ``in_place``: the result takes
    the sums' memory (they are spent), which spares allocating (and the system zeroing) as much
    again: most of the time this step takes at that size. ``components``: the passes kept
    (``image_components``)."""
    per_pixel = sums.adaptive or sums.partial
    height = sums.s.shape[0]
    mean = sums.s if in_place else np.empty(sums.s.shape)
    var = sums.s2[:, :, 0, :] if in_place else np.empty(sums.s.shape[:2] + sums.s.shape[3:])
    for r0 in range(0, height, IMAGE_BLOCK_ROWS):
        r = slice(r0, min(height, r0 + IMAGE_BLOCK_ROWS))
        b = None if sums.b is None else sums.b[r]
        if per_pixel:
            v = image_variance(sums.s[r, :, 0, :], sums.s2[r, :, 0, :], sums.n[r], b,
                               passes=sums.passes[r], sum_n2=sums.sum_n2[r])
            np.divide(sums.s[r], np.maximum(sums.n[r], 1.0)[:, :, None, None], out=mean[r])
        else:
            v = image_variance(sums.s[r, :, 0, :], sums.s2[r, :, 0, :], n, b, sums.sizes)
            np.divide(sums.s[r], max(float(n), 1.0), out=mean[r])
        var[r] = v
    comps = {c: mean[:, :, COMPONENTS.index(c) + 1, :] for c in components}
    if not per_pixel:
        return ImageResult(name, mean[:, :, 0, :], var, n, comps)
    return ImageResult(name, mean[:, :, 0, :], var, int(sums.n.max()), comps,
                       pixel_samples=sums.n.copy())


ADAPTIVE_FLOOR = 0.05  # pixel values below this fraction of the image's mean count as that
CHUNK_SECONDS = 0.5             # a camera pass longer than this runs in pieces (bands of rows)
CHUNK_PIXEL_SAMPLES = 1 << 13   # ... the first piece, whose speed is unknown, this many
                                #     (about a tenth of a second on two cores: the first pixels)
GUIDE_FIRST_PIXELS = 1 << 15    # denoising guides: the first piece, then pieces of CHUNK_SECONDS
GUIDE_WORK = 1                  # their cost counted as this many samples per pixel (progress)


def row_bands(active, height: int, width: int, k: int) -> list[tuple[int, int]]:
    """A pass over ``active`` pixels (None: all) as at most ``k`` pieces of consecutive rows
    (first, end) with about equal numbers of active pixels, none without one."""
    per_row = (np.full(height, width) if active is None
               else np.count_nonzero(active, axis=1))
    total = int(per_row.sum())
    if total == 0:
        return []
    k = max(1, min(int(k), height))
    cuts = np.searchsorted(np.cumsum(per_row), np.linspace(0, total, k + 1)[1:-1], side="left") + 1
    edges = [0, *sorted(set(int(c) for c in cuts if 0 < c < height)), height]
    return [(r0, r1) for r0, r1 in zip(edges[:-1], edges[1:]) if per_row[r0:r1].any()]


def pixels_converged(img: ImageResult, threshold: float) -> np.ndarray:
    """(H, W) bool: pixels whose standard error is at most ``threshold`` times their value in
    every band, values below ADAPTIVE_FLOOR times the band's image mean counting as that (so
    black and nearly black pixels stop on an absolute error, not on a relative one that would
    never be reached); pixels without an error estimate (fewer than 2 samples) are not."""
    mean = np.maximum(img.mean, 0.0)
    floor = ADAPTIVE_FLOOR * np.mean(mean, axis=(0, 1))
    scale = np.maximum(mean, floor[None, None, :])
    se = np.sqrt(img.variance)
    ok = np.isfinite(se) & (se <= threshold * scale)
    return np.all(ok, axis=-1)


EXACT_BELOW_WAVES = ("exact mode below waves: light passed from wave to wave arrives along rare paths "
                     "(the error may be too small: more samples)")

# The share of the refracted sunlight that may be left to rare paths before the exact mode's
# error bars are flagged (sun_rehit_fraction). Measured (scripts/se_calibration.py --surfaces
# waves --cones 0, 16 seeds of 16,384 samples, the 20 m patch at 6 m/s): 0 at sun zeniths of
# 0-35 deg and 7.4e-4 at 60 deg, with honest error bars (spread / reported 0.58-1.31); 1.2e-2 at
# 70 deg, 3.6e-2 at 75 deg and 8.0e-2 at 80 deg, with Eo 5 m down 24x, 58x and 76x. Set about
# 7x below the largest honest case (docs/verification.md).
REHIT_LIMIT = 1e-4


def sun_rehit_fraction(scene: Scene, water_index: int, core=None) -> float:
    """The sunlight entering water ``water_index`` that the beams do not carry, over what they
    carry (``_core.Scene.sun_rehit_fraction``): what the ocean's wave patch reflects onto
    itself and what it refracts back into itself from below, for the sun's centre. 0 for a
    flat sea, a water mesh, or no sun; inf where sub-grid roughness spreads the reflections
    (not counted: the flag then stays on). ``core``: the scene's compiled core (a render's),
    else a small one of the patch alone is made."""
    w = scene.water[water_index]
    if scene.sun is None or w.type != "ocean" or w.surface.kind == "flat":
        return 0.0
    surf = w.surface
    if surf.roughness is not None:
        return math.inf
    if core is None:
        from . import _core
        from .compile import set_ocean_patch
        core = _core.Scene()
        core.nbands = 1
        core.add_water(float(w.ior), np.zeros(1), [])
        set_ocean_patch(core, 0, w)
        if w.bottom_depth is not None:
            core.add_material(np.zeros(1))
            core.set_bottom(float(surf.z) - float(w.bottom_depth), 0)
        core.commit()
    return float(core.sun_rehit_fraction(tuple(float(c) for c in scene.sun.direction), float(w.ior),
                                         int(scene.settings.threads)))


def exact_mode_below_waves(scene: Scene, hybrid: bool, forward_cone_deg: float, water_index: int,
                           rehit: float | None = None) -> bool:
    """Whether a radiometer in water body ``water_index`` (-1: air) has an error that cannot be
    trusted because it is the hybrid's exact mode (forward cone 0) below a wavy sea that sends
    a share of the sunlight past the beams (``rehit``: sun_rehit_fraction, computed here when
    not given).

    Sunlight that one wave reflects onto the next, or that a steep facet refracts into the
    next wave from below, reaches a point only along paths that path tracing rarely finds (the
    beams do not carry it): over 16 seeds of 16,384 samples the spread of Eo's means 5 m down
    was 24-76x the reported error under 70-80 deg suns (1-8 % of the refracted light), though
    honest under 0-60 deg ones (at most 7.4e-4; docs/verification.md). A forward cone is no
    remedy there: its errors look honest, but under the 80 deg sun its Ed 1 m down is 23 % below
    pure path tracing's, where the exact mode's agrees (docs/verification.md)."""
    if not (hybrid and scene.sun is not None and forward_cone_deg == 0.0 and water_index >= 0):
        return False
    w = scene.water[water_index]
    if not (w.type == "ocean" and w.surface.kind != "flat"):
        return False
    if rehit is None:
        rehit = sun_rehit_fraction(scene, water_index)
    return not (rehit <= REHIT_LIMIT)


# A radiometer below a wave model's patch is flagged where refining the patch's mesh 2x moves
# its value (the direct sun's share of it) by more than this, or twice its standard error.
MESH_LIMIT = 0.02
# (the patch refined 2x for the estimate: at most this many triangles, else no estimate)
MESH_CHECK_TRIANGLES = 1 << 20
WAVE_MESH_NOTE = "wave mesh"


def _wave_mesh_checked(w) -> bool | None:
    """Whether the wave-mesh check covers water body ``w``: None where it does not apply (no
    wave model, or sub-grid roughness), False where its patch refined 2x would exceed
    MESH_CHECK_TRIANGLES (or the refinement's limit), True otherwise."""
    if w.type != "ocean" or w.surface.kind != "waves" or w.surface.roughness is not None:
        return None
    r = int(w.surface.waves.mesh_refinement)
    nx, ny = (int(n) for n in w.surface.waves.resolution)
    return not (2 * (2 * r * nx) * (2 * r * ny) > MESH_CHECK_TRIANGLES or 2 * r > 16)


def _beam_source_region(scene: Scene, w, positions: list) -> list[float]:
    """(x, y, radius) triples over the ocean patch from which the refracted sun can reach the
    given points in its water: around where the level surface's refracted sun ray through each
    point comes up, half the point's depth across (a refracted ray leans at most ~27 deg from
    that ray there) plus three grid cells and the waves' height; [] where they cover the patch."""
    lx, ly = (float(x) for x in w.surface.waves.patch_size_m)
    nx, ny = (int(n) for n in w.surface.waves.resolution)
    mesh = w.surface.patch()[0]
    z = np.asarray(mesh.vertices)[:, 2]
    level, hmax = float(np.mean(z)), float(np.max(np.abs(z - np.mean(z))))
    s = np.asarray(scene.sun.direction, float)
    ior = float(w.ior)
    sin_t = math.sqrt(max(0.0, 1.0 - s[2] ** 2)) / ior
    cos_t = math.sqrt(max(0.0, 1.0 - sin_t ** 2))
    sh = math.hypot(s[0], s[1])
    back = np.array([s[0] / sh * sin_t, s[1] / sh * sin_t, cos_t]) if sh > 0 else np.array([0.0, 0.0, 1.0])
    out, area = [], 0.0
    for p in positions:
        depth = max(0.0, level - float(p[2]))
        t = depth / back[2]
        r = 0.5 * depth + 3.0 * max(lx / nx, ly / ny) + 2.0 * hmax * (1.0 + sin_t / max(cos_t, 1e-3))
        out += [float(p[0]) + back[0] * t, float(p[1]) + back[1] * t, r]
        area += math.pi * r * r
    return [] if area >= lx * ly else out


def wave_mesh_sensitivity(scene: Scene, water_index: int, threads: int = 0, cancel=None,
                          hold=None, restrict: bool = True) -> dict | None:
    """Per radiometer in water ``water_index`` (by name): how much the refracted sun's direct
    light there (summed over its beams, the first band) changes when the ocean's wave patch is
    meshed 2x finer (``mesh_refinement`` doubled: the same waves), relative to the scene's own
    mesh: an estimate of the mesh's error at that point (docs/physics.md, "Wave patches and
    caustics": it reads about half to all of the error against a 16x mesh). Computed on cores of
    the water alone (no objects, the sun's centre, the disk's blur). None where it does not
    apply (no sun, no wave model) or the refined patch would exceed MESH_CHECK_TRIANGLES, or
    when ``cancel`` (a threading.Event) is set: ``hold(core)`` is told each core it builds, for
    a caller's cancel to stop its build at once. ``restrict``: the builds take only the faces
    whose beams can reach the radiometers (_beam_source_region), which gives the same beams
    there at a fraction of the cost for a few radiometers."""
    import copy
    w = scene.water[water_index]
    if scene.sun is None or not _wave_mesh_checked(w):
        return None
    model = w.surface.waves
    r = int(model.mesh_refinement)
    radiometers = scene.all_radiometers()
    values, region = [], None
    for refinement in (r, 2 * r):
        sc = copy.copy(scene)
        sc.meshes, sc.cameras = [], []
        sc.water = list(scene.water)
        wc = copy.copy(w)
        wc.surface = copy.copy(w.surface)
        wc.surface.waves = model.replace(mesh_refinement=refinement)
        sc.water[water_index] = wc
        core = compile_scene(sc, slice(0, 1), hybrid=True, threads=threads)
        if hold is not None:
            hold(core)
        if cancel is not None and cancel.is_set():
            return None
        if restrict:
            if region is None:  # (the same for both meshes: the coarser one's cells)
                inside = [rad.position for ri, rad in enumerate(radiometers)
                          if core.radiometer_medium(ri) == water_index]
                region = _beam_source_region(scene, wc, inside)
            core.beam_source_region = region
        core.build_beams(tuple(float(c) for c in scene.sun.direction), threads)
        if cancel is not None and cancel.is_set():
            return None
        e = {}
        for ri, rad in enumerate(radiometers):
            if core.radiometer_medium(ri) == water_index:
                e[rad.name] = sum(b[1][0] for b in core.beams_at(tuple(float(c) for c in rad.position), water_index))
        values.append(e)
    out = {}
    for name, a in values[0].items():
        b = values[1][name]
        out[name] = abs(b - a) / max(abs(a), abs(b)) if max(abs(a), abs(b)) > 0 else 0.0
    return out


def wave_mesh_warnings(scene: Scene, hybrid: bool) -> list[str]:
    """The render log's warning for wave patches whose mesh error at the radiometers is not
    estimated (wave_mesh_sensitivity: the patch refined 2x would be too large)."""
    if not (hybrid and scene.sun is not None and scene.all_radiometers()):
        return []
    out = []
    for w in scene.water:
        if _wave_mesh_checked(w) is False:
            out.append(f"water '{w.name}': the wave mesh's error at the radiometers is not estimated (its "
                       f"patch refined 2x would exceed {MESH_CHECK_TRIANGLES:,} triangles); see docs/physics.md, "
                       f"'Wave patches and caustics'")
    return out


def flag_wave_mesh(res: "RadiometerResult", sensitivity: float | None) -> None:
    """Mark ``res`` untrusted where the wave mesh's estimated error (``sensitivity`` times its
    direct-sun component) exceeds MESH_LIMIT of its value and twice its standard error."""
    if sensitivity is None or not sensitivity > 0:
        return
    direct = res.components.get("beam_direct")
    if direct is None:
        return
    est = sensitivity * np.abs(np.asarray(direct[0], float))
    limit = np.maximum(MESH_LIMIT * np.abs(res.mean), 2.0 * res.stderr)
    if np.any(est > limit):
        share = float(np.max(est / np.maximum(np.abs(res.mean), 1e-300)))
        res.notes.append(f"{WAVE_MESH_NOTE}: the value changes by about {100 * share:.0f} % when the wave patch's "
                         f"mesh is refined 2x (set surface.mesh_refinement; docs/physics.md)")
        res.reliable[:] = False


def sampling_untrusted(res: "RadiometerResult") -> bool:
    """Whether ``res``'s error bar is flagged for a reason of the sampling (heavy tails, too
    few passes, light left to rare paths, a biased cone), not only for the wave mesh's error
    (flag_wave_mesh), which more samples do not change: what the error bars' calibration
    counts."""
    if np.all(res.reliable):
        return False
    return not res.notes or any(not n.startswith(WAVE_MESH_NOTE) for n in res.notes)


def flag_beam_modes(res: "RadiometerResult", scene: Scene, hybrid: bool,
                    forward_cone_deg: float, water_index: int,
                    rehits: dict | None = None, meshes: dict | None = None,
                    check_meshes: bool = True) -> None:
    """Mark ``res`` untrusted where the hybrid's mode makes its error bar too small: a forward
    cone whose beams are not uniform across (every radiometer: the bias reaches the light that
    leaves the water too; 1.6 % in the mean of 64 points 5 m down), exact_mode_below_waves, or
    a wave mesh too coarse for the caustics at its point (flag_wave_mesh). ``rehits``,
    ``meshes``: dicts kept by the caller across radiometers (water index ->
    sun_rehit_fraction, wave_mesh_sensitivity), filled here; ``check_meshes`` False: no new
    wave-mesh check (a cancelled render does not wait for one)."""
    if hybrid and water_index >= 0 and meshes is not None and (check_meshes or water_index in meshes):
        if water_index not in meshes:
            meshes[water_index] = wave_mesh_sensitivity(scene, water_index, int(scene.settings.threads))
        if meshes[water_index] is not None:
            flag_wave_mesh(res, meshes[water_index].get(res.name))
    if forward_cone_biased(scene, hybrid, forward_cone_deg):
        res.notes.append(FORWARD_CONE_STRUCTURE)
        res.reliable[:] = False
        return
    if not (hybrid and forward_cone_deg == 0.0 and water_index >= 0 and scene.sun is not None):
        return
    rehits = {} if rehits is None else rehits
    if water_index not in rehits:
        rehits[water_index] = sun_rehit_fraction(scene, water_index)
    if exact_mode_below_waves(scene, hybrid, forward_cone_deg, water_index, rehits[water_index]):
        res.notes.append(EXACT_BELOW_WAVES)
        res.reliable[:] = False


def round_seed(seed: int, rnd: int) -> int:
    """The seed of round ``rnd`` of a render (round 0 keeps the render's seed, so a render of
    one round equals a plain one)."""
    if rnd == 0:
        return seed
    state = np.random.SeedSequence([seed, 0x5EED, rnd]).generate_state(2, np.uint32)
    return int((int(state[0]) << 32 | int(state[1])) & ((1 << 63) - 1))


def worst_relative_error(mean: np.ndarray, stderr: np.ndarray) -> float:
    """The largest stderr / |mean| over the entries (a total's bins and bands); entries that
    are exactly 0 +- 0 (a bin no light reaches) do not count, a 0 with an error is infinite."""
    zero = (mean == 0) & (stderr == 0)
    if np.all(zero):
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(zero, 0.0, stderr / np.abs(mean))
    return float(np.max(np.nan_to_num(rel, nan=np.inf, posinf=np.inf)))


def next_round_samples(done: int, rel: float, target: float, trusted: bool, left: int) -> int:
    """Samples per radiometer of an adaptive render's next round (0: stop).

    The error falls as N^-1/2, so reaching ``target`` from ``rel`` after ``done`` samples takes
    done ((rel / target)^2 - 1) more (with a margin); an error that cannot be trusted yet
    (too few passes, heavy tails) is not extrapolated: the samples are doubled instead."""
    if left <= 0 or (trusted and rel <= target):
        return 0
    if trusted and np.isfinite(rel):
        need = done * ((rel / target) ** 2 - 1.0) * ROUND_MARGIN
    else:
        need = done
    return int(min(left, max(MIN_ROUND, np.ceil(need))))


def radiometer_result(r, medium: str, rounds: list[RadiometerSums]) -> RadiometerResult:
    """A radiometer's result from the sums of its rounds (one for a plain render)."""
    est = combine_round_sums(rounds)
    mean, err = est["mean"], est["stderr"]
    bins = (r.polar_bins, r.azimuth_bins) if r.quantity == "radiance_distribution" else None
    comps = {c: (mean[:, i + 1, :], err[:, i + 1, :]) for i, c in enumerate(COMPONENTS)}
    return RadiometerResult(r.name, r.quantity, np.asarray(r.position, float), medium,
                            mean[:, 0, :], err[:, 0, :], est["samples"], bins, comps,
                            reliable=est["reliable"], notes=list(est["notes"]), vov=est["vov"])


def _check_target(owner: str, field: str, value) -> float | None:
    if value is None:
        return None
    try:
        te = float(value)
    except (TypeError, ValueError):
        te = float("nan")
    if isinstance(value, bool) or not 0.0 < te < 1.0:
        raise SceneError(owner, field, f"must be a relative error between 0 and 1 (0.01 = 1 %), "
                                       f"got {value!r}")
    return te


class Renderer:
    """Renders a validated scene progressively.

    Parameters override the scene's settings: ``samples`` per pixel, ``radiometer_samples`` per
    radiometer, ``seed``, ``threads`` (0 = all cores), ``target_error`` (a relative standard
    error at which each radiometer stops, ``radiometer_samples`` then being the most it may
    take; None: every radiometer takes all its samples), ``radiometer_targets`` (radiometer
    name -> its own target error, over ``target_error``) and ``noise_threshold`` (a relative
    standard error at which each pixel stops after ``adaptive_min_samples``, ``samples`` then
    being the most it may take; None: every pixel takes all its samples).
    """

    _UNSET = object()

    def __init__(self, scene: Scene, samples: int | None = None, radiometer_samples: int | None = None,
                 seed: int | None = None, threads: int | None = None, target_error=_UNSET,
                 radiometer_targets: dict | None = None, noise_threshold=_UNSET,
                 adaptive_min_samples: int | None = None, guides: bool = False):
        scene.validate()
        self.guides = bool(guides)
        st = scene.settings
        self.integrator = resolve_integrator(scene)
        self.forward_cone_deg = resolve_forward_cone(scene) if self.integrator == "hybrid" else 0.0
        self.scene = scene
        self._rehits: dict[int, float] = {}  # (flag_beam_modes' per water body)
        self._meshes: dict[int, dict | None] = {}
        self.samples = int(st.samples if samples is None else samples)
        self.radiometer_samples = int(st.radiometer_samples if radiometer_samples is None else radiometer_samples)
        self.seed = int(st.seed if seed is None else seed)
        self.threads = int(st.threads if threads is None else threads)
        for key in ("samples", "radiometer_samples", "threads", "seed"):  # (overrides too)
            check_parameter("settings", f"settings.{key}", getattr(self, key))
        check_memory(scene)
        self.target_error = _check_target(
            "settings", "target_error", st.target_error if target_error is Renderer._UNSET else target_error)
        self.noise_threshold = _check_target(
            "settings", "noise_threshold",
            st.noise_threshold if noise_threshold is Renderer._UNSET else noise_threshold)
        self.adaptive_min_samples = int(st.adaptive_min_samples if adaptive_min_samples is None
                                        else adaptive_min_samples)
        check_parameter("settings", "settings.adaptive_min_samples", self.adaptive_min_samples)
        names = {r.name for r in scene.all_radiometers()}
        self.radiometer_targets = {}
        for name, value in (radiometer_targets or {}).items():
            if name not in names:
                raise SceneError("radiometers", name, "has a target error but is no radiometer "
                                                     f"of the scene (there are {len(names)})")
            self.radiometer_targets[name] = _check_target("radiometers", name, value)
        self._cancel = threading.Event()
        self._core = None
        # Running sums of the cameras, readable while rendering (snapshot) under the lock.
        self._lock = threading.Lock()
        self._cam_sums: dict = {}
        self._cam_done: dict = {}
        self._cam_version: dict = {}   # camera -> a count of the pieces of passes added
        self._cam_rows: dict = {}      # camera -> per row, the version that last changed it
        self._spent: set = set()       # cameras whose sums became their result
        self._skip_images = False
        self.progress = 0.0
        self.counters = {"segments": 0, "shadow_rays": 0, "paths": 0}
        self.t_start = None

    def cancel(self, images: bool = True) -> None:
        """Stop as soon as possible (safe to call from another thread). ``images=False``: the
        result then has no camera images (their assembly takes about a second at 1920 x 1080
        with 10 bands), for a caller that shows what ``total_sums`` gave it instead."""
        self._skip_images = not images
        self._cancel.set()
        core = self._core
        if core is not None:
            core.cancel()

    def snapshot(self, camera: str, stride: int = 1) -> ImageResult | None:
        """The current estimate of a camera while it renders (None before its first pass);
        ``stride`` > 1: of every stride-th row and column only (a cheap sample of the image,
        e.g. for its noise figure).

        Safe to call from another thread: passes are added under a lock, so the sums and the
        sample count always belong together."""
        with self._lock:
            if self._live(camera) is None:
                return None
            n = self._cam_done[camera]
            sums = self._cam_sums[camera].copy(stride)
        return image_result(camera, sums, n, components=image_components(self.scene))

    def _live(self, camera: str) -> CameraSums | None:
        """A camera's sums while they are a display's to read (under the lock): after its
        first piece, before they became its result."""
        if camera in self._spent or not self._cam_done.get(camera):
            return None
        return self._cam_sums.get(camera)

    def changed_rows(self, camera: str, since: int = -1) -> tuple[int, int, int] | None:
        """(first, end, version): the rows of a camera that changed after version ``since``
        (for -1: the rows rendered so far, which may be a few: a display need not convert the
        rest, still black), and the version they are at; None before its first pass or when
        nothing changed."""
        with self._lock:
            if self._live(camera) is None:
                return None
            version = self._cam_version.get(camera, 0)
            if version <= since:
                return None
            changed = np.flatnonzero(self._cam_rows[camera] > max(since, 0))
            return int(changed[0]), int(changed[-1]) + 1, version

    def total_sums(self, camera: str, rows: tuple[int, int] | None = None) -> DisplaySums | None:
        """What a display needs of a camera while it renders, copied under the lock: the sums
        of the total and the samples of ``rows`` (first, end; all by default); None before its
        first pass. Which rows changed: ``changed_rows``."""
        with self._lock:
            sums = self._live(camera)
            if sums is None:
                return None
            r = slice(*rows) if rows is not None else slice(None)
            return DisplaySums(np.ascontiguousarray(sums.s[r, :, 0, :]), sums.n[r].copy(),
                               rows[0] if rows is not None else 0)

    def _guides(self, core, ci: int, cam, g: slice, nb: int, guide_maps: dict) -> bool:
        """The denoising guides of a camera for one band group, in bands of rows (the first
        GUIDE_FIRST_PIXELS pixels, then pieces of about CHUNK_SECONDS at the speed measured);
        False when cancelled (then the guides are incomplete and not kept)."""
        from .denoise import guides as camera_guides
        width, height = cam.resolution
        maps = guide_maps.get(cam.name)
        if maps is None:
            maps = guide_maps[cam.name] = [np.zeros((height, width, nb), np.float32),
                                           np.zeros((height, width, 3), np.float32)]
        r0, rate = 0, None
        while r0 < height:
            if self._cancel.is_set():
                guide_maps.pop(cam.name, None)
                return False
            rows = (max(1, GUIDE_FIRST_PIXELS // width) if rate is None
                    else max(1, int(CHUNK_SECONDS / max(rate * width, 1e-12))))
            r1 = min(height, r0 + rows)
            t = time.perf_counter()
            a, nrm = camera_guides(core, ci, self.threads, rows=(r0, r1))
            rate = (time.perf_counter() - t) / (r1 - r0) / width
            maps[0][r0:r1, :, g] = a
            maps[1][r0:r1] = nrm
            r0 = r1
        return True

    def _camera_passes(self) -> list[tuple[int, int]]:
        return camera_passes(self.samples)

    def run(self, progress=None) -> RenderResult:
        """Render everything; ``progress(fraction, message)`` is called after every pass."""
        scene = self.scene
        radiometers = scene.all_radiometers()
        nb = len(scene.bands)
        nc = len(COMPONENTS) + 1  # the core's layout: total, then the components
        groups = scene_band_groups(scene)
        threads = self.threads or (os.cpu_count() or 1)
        hybrid = self.integrator == "hybrid"
        beams = uses_beams(scene, hybrid)
        result = RenderResult(scene.name, list(scene.bands))
        # A pixel's error from its samples as independent draws (no between-pass term: see
        # photic.estimates, "Cameras").
        cam_sums = self._cam_sums = {c.name: CameraSums((c.resolution[1], c.resolution[0], nc, nb), False)
                                     for c in scene.cameras}
        cam_done = self._cam_done = {c.name: 0 for c in scene.cameras}
        self._cam_rows = {c.name: np.zeros(c.resolution[1], np.int64) for c in scene.cameras}
        self._spent = set()
        cam_passes = self._camera_passes()
        camera_steps: dict = {}  # camera -> [(pass index, active mask or None)] of group 0
        stopped: dict = {}       # camera -> pixels that stopped at the noise threshold
        # per radiometer, its sums per (band group, round); without a target error one round
        # whose sums all band groups fill, keyed (0, 0)
        rad_rounds: list[dict] = [{} for _ in radiometers]
        nbins_of = [0] * len(radiometers)
        rounds_run = 0
        targets = [self.radiometer_targets.get(r.name, self.target_error) for r in radiometers]
        adaptive = any(t is not None for t in targets)
        total_work = len(groups) * (sum(c.resolution[0] * c.resolution[1] * (self.samples + self.guides * GUIDE_WORK)
                                        for c in scene.cameras)
                                    + len(radiometers) * self.radiometer_samples)
        done_work = 0
        counters = self.counters = {"segments": 0, "shadow_rays": 0, "paths": 0}
        media = [None] * len(radiometers)
        media_index = [-1] * len(radiometers)
        beam_stats = {"passes": 0, "prisms": 0, "build_s": 0.0}
        t0 = self.t_start = time.perf_counter()
        buffers: dict = {}  # per shape, the passes' output arrays (reused: fresh ones fault per page)

        def out(shape):
            if shape not in buffers:
                buffers[shape] = (np.empty(shape), np.empty(shape))
            return buffers[shape]

        def add_counts(c):
            for k in counters:
                counters[k] += int(c[k])

        last_core = [None]  # (held, so that its identity stays its own)

        def new_pass(core, seed, key, i, n, paired):
            """Before a pass of the hybrid integrator: beams for its sun direction."""
            if not beams:
                return
            tb = time.perf_counter()
            build_pass_beams(core, scene, seed, key, i, n, self.threads, paired, keep=last_core[0] is core)
            last_core[0] = core
            beam_stats["build_s"] += time.perf_counter() - tb
            beam_stats["passes"] += 1
            beam_stats["prisms"] = max(beam_stats["prisms"], core.beam_count)

        def report(label):
            self.progress = done_work / total_work
            if progress:
                progress(done_work / total_work, label)

        cancelled = False
        guide_maps: dict = {}  # camera -> [albedo (H, W, nb), normal (H, W, 3)]
        for gi, g in enumerate(groups):
            core = compile_scene(scene, g, seed=self.seed, hybrid=hybrid,
                                 forward_cone_deg=self.forward_cone_deg, threads=self.threads)
            self._core = core
            if self._cancel.is_set():
                core.cancel()
            if gi == 0:
                if hybrid and self.forward_cone_deg == 0.0 and radiometers:  # (the flag's share)
                    for wi in range(len(scene.water)):
                        self._rehits[wi] = sun_rehit_fraction(scene, wi, core)
                check_sensors_off_boundaries(core, scene)
                result.warnings = (scene_warnings(scene) + inelastic_group_warnings(scene) + sensor_warnings(core, scene)
                                   + forward_cone_warning(scene, hybrid, self.forward_cone_deg)
                                   + (wave_mesh_warnings(scene, hybrid) if radiometers else []))
            for ri in range(len(radiometers)):
                m = core.radiometer_medium(ri)
                media[ri] = "air" if m < 0 else scene.water[m].name
                media_index[ri] = m
                if gi == 0:
                    nbins_of[ri] = core.radiometer_bins(ri)
            # Cameras: every pass with beams of its own (an independent draw). With a noise
            # threshold, the pixels that reached it take no further passes. A pass that would
            # take long runs in pieces, bands of rows, so that a display sees pixels within
            # about CHUNK_SECONDS (the first pass: CHUNK_PIXEL_SAMPLES at a time, its speed
            # unknown); the pieces are added as they come (each pixel's own passes: the same
            # numbers). All is decided on the first band group and replayed in the others.
            for ci, cam in enumerate(scene.cameras):
                height, width = cam.resolution[1], cam.resolution[0]
                shape = (height, width, nc, g.stop - g.start)
                npix = width * height
                sums = cam_sums[cam.name]
                plan = camera_steps.setdefault(cam.name, [])  # (pass index, active mask, rows)
                rate = None  # seconds per pixel-sample, measured
                for pi, (start, n) in enumerate(cam_passes):
                    if gi > 0:
                        pieces = [(m, rows) for p, m, rows in plan if p == pi]
                        if not pieces:  # every pixel stopped here in the first group
                            done_work += npix * (self.samples - start)
                            break
                    else:
                        active = None
                        if self.noise_threshold is not None and start >= self.adaptive_min_samples:
                            with self._lock:
                                img = image_result(cam.name, sums, cam_done[cam.name],
                                                   components=image_components(scene))
                            done_px = pixels_converged(img, self.noise_threshold)
                            if stopped.get(cam.name) is not None:
                                done_px |= stopped[cam.name]  # a pixel that stopped stays stopped
                            if np.all(done_px):
                                done_work += npix * (self.samples - start)
                                break
                            active = np.ascontiguousarray(~done_px, dtype=np.uint8)
                            stopped[cam.name] = done_px
                        taking = npix if active is None else int(np.count_nonzero(active))
                        work = taking * n
                        if active is None:
                            pieces = None  # decided piece by piece, at the speed measured
                        else:
                            k = (math.ceil(work / CHUNK_PIXEL_SAMPLES) if rate is None
                                 else math.ceil(work * rate / CHUNK_SECONDS))
                            pieces = [(active, rows) for rows in row_bands(active, height, width, k)]
                            plan.extend((pi, m, rows) for m, rows in pieces)
                    new_pass(core, self.seed, (0, ci), pi, len(cam_passes), False)
                    taken = 0
                    piece, next_row = 0, 0
                    while True:
                        if pieces is not None:
                            if piece >= len(pieces):
                                break
                            m, (r0, r1) = pieces[piece]
                            last_piece = piece == len(pieces) - 1
                        else:  # the first piece small (the first pixels), then about
                            if next_row >= height:  # CHUNK_SECONDS each, growing at most 2x a
                                break               # piece (rows differ: sky, then the sea floor)
                            rows = max(1, int(CHUNK_PIXEL_SAMPLES / (width * n) if rate is None
                                              else CHUNK_SECONDS / max(rate * width * n, 1e-12)))
                            if piece:
                                rows = min(rows, 2 * (plan[-1][2][1] - plan[-1][2][0]))
                            m, r0 = None, next_row
                            r1 = next_row = min(height, r0 + rows)
                            last_piece = r1 == height
                            plan.append((pi, None, (r0, r1)))
                        t_piece = time.perf_counter()
                        bufs = tuple(b[:r1 - r0] for b in out(shape))  # (a view: no new pages)
                        s, s2, c = core.render_camera(ci, start, n, self.threads, bufs, m, (r0, r1))
                        if core.cancelled:
                            cancelled = True
                            break
                        dt = time.perf_counter() - t_piece
                        px = (r1 - r0) * width if m is None else int(np.count_nonzero(m[r0:r1]))
                        if px > 0 and dt > 0:
                            rate = dt / (px * n)
                        with self._lock:
                            sums.add_pass(g, s, s2, n, gi == 0, m, rows=(r0, r1),
                                          new_pass=piece == 0, last_piece=last_piece)
                            if gi == 0:
                                cam_done[cam.name] = start + n
                            self._cam_version[cam.name] = version = self._cam_version.get(cam.name, 0) + 1
                            self._cam_rows[cam.name][r0:r1] = version
                            add_counts(c)
                            done_work += px * n
                        taken += px
                        piece += 1
                    if cancelled:
                        break
                    done_work += max(0, npix - taken) * n  # (a stopped pixel's share is done too)
                    report(f"camera {cam.name}: {start + n}/{self.samples} samples"
                           + (f" ({taken / npix:.0%} of pixels)" if taken < npix else ""))
                if cancelled:
                    break
            # Denoising guides: a few fixed rays per pixel, after the passes (the first pixels
            # do not wait for them) and in bands of rows like a pass, so that a cancel stops
            # them within about CHUNK_SECONDS too.
            if self.guides and not cancelled:
                for ci, cam in enumerate(scene.cameras):
                    if not self._guides(core, ci, cam, g, nb, guide_maps):
                        cancelled = True
                        break
                    done_work += cam.resolution[0] * cam.resolution[1] * GUIDE_WORK
                    report(f"camera {cam.name}: denoising guides")
            # Radiometers: in rounds (one without a target error), each pass after pass for
            # all radiometers of the round with the same beams (one build per pass serves them
            # all); the passes of a round are paired strata of the sun's disk. With targets,
            # a radiometer that needs more samples joins the next round of those needing about
            # as many (at most ROUND_GROUPING times its need), so one slow radiometer does not
            # drag the others along.
            done = [0] * len(radiometers)
            pending = {ri: (min(self.radiometer_samples, FIRST_ROUND) if adaptive
                            else self.radiometer_samples) for ri in range(len(radiometers))}
            rnd = 0
            while pending and not cancelled:
                size = max(pending.values())
                active = [ri for ri in sorted(pending) if pending[ri] * ROUND_GROUPING >= size]
                for ri in active:
                    del pending[ri]
                seed = round_seed(self.seed, rnd)
                core.seed = seed
                passes = radiometer_passes(size, beams)
                key = (gi if adaptive else 0, rnd)
                for ri in active:
                    rad_rounds[ri].setdefault(key, RadiometerSums(
                        (nbins_of[ri], nc, nb), beams, len(passes) // 2))
                for pi, (start, n) in enumerate(passes):
                    new_pass(core, seed, (1,), pi, len(passes), True)
                    for ri in active:
                        sums = rad_rounds[ri][key]
                        shape = sums.s.shape[:-1] + (g.stop - g.start,)
                        mom = np.empty((shape[0], 3, shape[2]))
                        s, s2, c = core.render_radiometer(ri, start, n, self.threads, out(shape), mom)
                        if core.cancelled:
                            cancelled = True
                            break
                        with self._lock:
                            sums.add_pass(g, pi, start, n, s, s2, mom)
                            add_counts(c)
                            done_work += n
                    if cancelled:
                        break
                    report(f"radiometers: {done[active[0]] + start + n}/{self.radiometer_samples} "
                           "samples" + (f" (round {rnd + 1})" if adaptive else ""))
                rnd += 1
                if not adaptive or cancelled:
                    break
                # Who goes on: those whose worst relative error in this group is above the
                # target (or not yet to be trusted), for the samples each needs.
                for ri in active:
                    done[ri] += size
                    est = combine_round_sums(list(rad_rounds[ri].values()))
                    rel = worst_relative_error(est["mean"][:, 0, g], est["stderr"][:, 0, g])
                    trusted = bool(np.all(est["reliable"][:, g]))
                    left = self.radiometer_samples - done[ri]
                    need = (left if targets[ri] is None else
                            next_round_samples(done[ri], rel, targets[ri], trusted, left))
                    if need > 0:
                        pending[ri] = need
            rounds_run = max(rounds_run, rnd)
            if cancelled:
                break
        self._core = None
        elapsed = time.perf_counter() - t0

        for cam in scene.cameras:
            if cancelled and self._skip_images:
                break
            with self._lock:  # the sums are spent: a display asking now gets nothing
                self._spent.add(cam.name)
            img = result.images[cam.name] = image_result(cam.name, cam_sums[cam.name], cam_done[cam.name],
                                                         in_place=True, components=image_components(scene))
            if cam.name in guide_maps:
                img.albedo, img.normal = guide_maps[cam.name]
            if self.noise_threshold is not None and cam_done[cam.name]:
                img.noise_threshold = self.noise_threshold
                if img.pixel_samples is None:
                    img.pixel_samples = np.full(img.mean.shape[:2], img.samples, np.int64)
                done_px = stopped.get(cam.name)
                if done_px is None:
                    done_px = np.zeros(img.mean.shape[:2], bool)
                img.converged = done_px | pixels_converged(img, self.noise_threshold)
        # The wave-mesh check (flag_wave_mesh) before the radiometers' results: cancellable,
        # and a render cancelled before or during it does not wait for it.
        if hybrid and not cancelled:
            for wi in sorted({m for m in media_index if m >= 0}):
                if wi not in self._meshes:
                    w = scene.water[wi]
                    if _wave_mesh_checked(w):
                        report(f"radiometers: checking the wave mesh of water '{w.name}'")
                    self._meshes[wi] = wave_mesh_sensitivity(scene, wi, self.threads, self._cancel,
                                                             lambda c: setattr(self, "_core", c))
            self._core = None
            cancelled = self._cancel.is_set()
        reached = 0
        for ri, r in enumerate(radiometers):
            if not rad_rounds[ri]:
                break
            res = radiometer_result(r, media[ri] or "air", [rad_rounds[ri][k] for k in sorted(rad_rounds[ri])])
            if res.samples == 0:  # cancelled before its first pass ended: no result, not 0 +- 0
                break
            flag_beam_modes(res, scene, hybrid, self.forward_cone_deg, media_index[ri], self._rehits, self._meshes,
                            check_meshes=False)  # (made above, unless cancelled)
            if targets[ri] is not None:
                res.target_error = targets[ri]
                res.relative_error = worst_relative_error(res.mean, res.stderr)
                res.target_reached = bool(res.relative_error <= targets[ri]
                                          and np.all(res.reliable) and not cancelled)
                reached += res.target_reached
            result.radiometers.append(res)
        result.cancelled = cancelled
        result.stats = dict(counters, time_s=elapsed, threads=threads, seed=self.seed,
                            samples=self.samples, radiometer_samples=self.radiometer_samples,
                            segments_per_s=counters["segments"] / elapsed if elapsed > 0 else 0.0,
                            band_groups=len(groups), integrator=self.integrator,
                            forward_cone_deg=self.forward_cone_deg,
                            beam_passes=beam_stats["passes"], beam_prisms=beam_stats["prisms"],
                            beam_build_s=beam_stats["build_s"])
        if adaptive:
            result.stats.update(target_error=self.target_error, rounds=rounds_run,
                                target_reached=reached)
        if self.noise_threshold is not None:
            result.stats.update(noise_threshold=self.noise_threshold,
                                adaptive_min_samples=self.adaptive_min_samples,
                                pixel_samples_mean={k: float(np.mean(v.pixel_samples))
                                                    for k, v in result.images.items()
                                                    if v.pixel_samples is not None},
                                pixels_converged={k: float(np.mean(v.converged))
                                                  for k, v in result.images.items()
                                                  if v.converged is not None})
        return result


def render(scene: Scene, progress=None, **overrides) -> RenderResult:
    """Render a scene (see Renderer for the overrides)."""
    return Renderer(scene, **overrides).run(progress)
