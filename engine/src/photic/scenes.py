"""Example scenes built in Python.

:func:`stepped_pool` is the talk's example: a tiled pool whose floor steps down in three steps,
filled with clear water under a wavy (static) surface, lit by the real 0.53 degree sun. Its
caustics on the steps are what the hybrid integrator's beams are for.
"""
from __future__ import annotations

import math

import numpy as np

from .scene import Scene

# Geometry of the stepped pool (metres): interior x in [-3, 3], y in [-1.5, 1.5]; the floor
# steps down along +x: depth 0.6 for x < -1, 1.2 for -1 < x < 1, 1.8 for x > 1.
POOL_X = (-3.0, 3.0)
POOL_Y = (-1.5, 1.5)
STEP_DEPTHS = (0.6, 1.2, 1.8)
DECK_Z = 0.2          # coping / deck height above the mean water level
DECK_WIDTH = 3.0      # width of the deck around the pool
OVERLAP = 1e-3        # the water mesh reaches this far into the walls and the floor
# Beam subdivision levels: 2 splits a 5 cm source triangle down to ~1.2 cm where its vertex
# rays end on different planes (step edges, wall corners, the deck's shadow). Deeper levels
# multiply the prisms along those lines and the beam build time (on two cores, about 0.6 s
# per pass at level 2, 1.5 s at 3, 2.3 s at 4, 4.7 s at 5).
BEAM_MAX_LEVEL = 2
# Waves: (amplitude m, wavelength m, direction deg from +x, phase rad): crests up to ~4 cm,
# curvatures up to ~2 m^-1, so the refracted sun focuses ~1.5-2 m down: caustics on the steps.
WAVES = ((0.020, 1.30, 20.0, 0.0), (0.012, 0.80, -55.0, 1.3), (0.008, 0.55, 100.0, 2.1))


def _box(lo, hi) -> tuple[list, list]:
    """An axis-aligned box: 8 vertices, 12 triangles with outward normals."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
         [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]]
    t = [[0, 2, 1], [0, 3, 2],      # bottom (-z)
         [4, 5, 6], [4, 6, 7],      # top (+z)
         [0, 1, 5], [0, 5, 4],      # -y
         [1, 2, 6], [1, 6, 5],      # +x
         [2, 3, 7], [2, 7, 6],      # +y
         [3, 0, 4], [3, 4, 7]]      # -x
    return v, t


def _merge(boxes) -> tuple[list, list]:
    vertices, triangles = [], []
    for v, t in boxes:
        base = len(vertices)
        vertices += v
        triangles += [[i + base for i in tri] for tri in t]
    return vertices, triangles


def wave_height(x, y, waves=WAVES) -> np.ndarray:
    """Height of the static wave surface (sum of sinusoids) at (x, y)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    z = np.zeros(np.broadcast(x, y).shape)
    for amp, lam, deg, phase in waves:
        k = 2 * math.pi / lam
        kx, ky = k * math.cos(math.radians(deg)), k * math.sin(math.radians(deg))
        z = z + amp * np.sin(kx * x + ky * y + phase)
    return z


def water_volume(x0, x1, y0, y1, z_bottom, nx, ny, height=None) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-wound triangle mesh: a box whose top is an (nx x ny)-quad height
    field ``height(x, y)`` (flat z = 0 if None), bottom flat at ``z_bottom``.

    The four sides are stitched to the border vertices of the top grid (one quad per border
    edge) and the bottom is a fan around its centre over the same border, so the mesh is
    watertight with no T-junctions.
    """
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")             # (nx+1, ny+1), vertex (i, j)
    Z = np.zeros_like(X) if height is None else np.asarray(height(X, Y), float)
    if np.any(Z <= z_bottom):
        raise ValueError("the top surface must stay above the bottom")
    top = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    idx = lambda i, j: i * (ny + 1) + j
    tris = []
    for i in range(nx):                                  # top, counter-clockwise from above
        for j in range(ny):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            tris += [[a, b, c], [a, c, d]] if (i + j) % 2 == 0 else [[a, b, d], [b, c, d]]
    # The border loop, counter-clockwise seen from above.
    loop = ([idx(i, 0) for i in range(nx)] + [idx(nx, j) for j in range(ny)]
            + [idx(i, ny) for i in range(nx, 0, -1)] + [idx(0, j) for j in range(ny, 0, -1)])
    nt = len(top)
    bottom = top[loop].copy()
    bottom[:, 2] = z_bottom
    centre = nt + len(loop)
    n = len(loop)
    for k in range(n):
        t0, t1 = loop[k], loop[(k + 1) % n]
        b0, b1 = nt + k, nt + (k + 1) % n
        tris += [[b0, b1, t1], [b0, t1, t0]]              # sides, outward
        tris.append([centre, b1, b0])                    # bottom fan, facing down
    vertices = np.vstack([top, bottom, [[(x0 + x1) / 2, (y0 + y1) / 2, z_bottom]]])
    return vertices, np.asarray(tris, np.int64)


def stepped_pool(resolution=(96, 64), waves: bool = True, samples: int = 16,
                 integrator: str = "hybrid", sun_diameter_deg: float = 0.53,
                 grid=(120, 60)) -> Scene:
    """The talk's example: a 6 m x 3 m tiled pool stepping down 0.6 / 1.2 / 1.8 m along +x.

    - Tiles (walls, steps, floor): Lambertian, reflectance ~0.7 (slightly blue); a darker
      stone deck (0.4) 0.2 m above the water around the pool.
    - Water: one closed mesh filling the pool up to z = 0 whose top is a static wave field
      (three sinusoids, 0.8-2 cm each, wavelengths 0.55-1.3 m; ``grid`` quads, 5 cm by
      default) or flat when ``waves`` is False; its sides and bottom reach 1 mm into the
      walls and the floor so that the opaque tiles, not the water boundary, are met there.
      Clear pool water: a = 0.02 / 0.05 / 0.30 per m (450 / 550 / 650 nm), b = 0.05 per m
      (Henyey-Greenstein, g = 0.9).
    - Sun at 35 deg zenith, irradiance 1 per band; uniform sky radiance 0.02 / pi.
    - Cameras (``resolution`` each): "above" looks down at the pool from 4 m above its side;
      "under" is in the water near the deep end's wall, looking back along the steps.
    """
    nx, ny = grid
    (x0, x1), (y0, y1) = POOL_X, POOL_Y
    deep = max(STEP_DEPTHS)
    z_floor = -deep - 0.25
    wv, wt = water_volume(x0 - OVERLAP, x1 + OVERLAP, y0 - OVERLAP, y1 + OVERLAP, -deep - OVERLAP,
                          nx, ny, (lambda x, y: wave_height(x, y)) if waves else None)
    dw = DECK_WIDTH
    # Walls (tiles) up to the deck's underside, then the deck slabs on the same footprints.
    footprints = [((x0 - dw, y0 - dw), (x0, y1 + dw)), ((x1, y0 - dw), (x1 + dw, y1 + dw)),
                  ((x0, y0 - dw), (x1, y0)), ((x0, y1), (x1, y1 + dw))]
    z_deck = DECK_Z - 0.05
    walls = [_box((a[0], a[1], z_floor), (b[0], b[1], z_deck)) for a, b in footprints]
    decks = [_box((a[0], a[1], z_deck), (b[0], b[1], DECK_Z)) for a, b in footprints]
    # Floor slab and two steps; the steps reach into the walls and the slab (hidden faces).
    floor = [_box((x0 - 0.1, y0 - 0.1, z_floor), (x1 + 0.1, y1 + 0.1, -deep))]
    edges = np.linspace(x0, x1, len(STEP_DEPTHS) + 1)
    steps = [_box((x0 - 0.1 if k == 0 else edges[k], y0 - 0.1, -deep - 0.05), (edges[k + 1], y1 + 0.1, -d))
             for k, d in enumerate(STEP_DEPTHS[:-1])]
    mv, mt = _merge(walls + floor + steps)
    dv, dt = _merge(decks)
    sun_e = [1.0, 1.0, 1.0]
    res = [int(resolution[0]), int(resolution[1])]
    d = {
        "photic_scene": 1,
        "name": "stepped_pool",
        "bands": [{"name": str(c), "center_nm": float(c), "width_nm": 100.0} for c in (450, 550, 650)],
        "materials": {"tile": {"type": "lambertian", "reflectance": [0.72, 0.72, 0.66]},
                      "deck": {"type": "lambertian", "reflectance": [0.45, 0.42, 0.38]}},
        "meshes": [{"name": "walls_floor_steps", "material": "tile", "vertices": mv, "triangles": mt},
                   {"name": "deck", "material": "deck", "vertices": dv, "triangles": dt}],
        "water": [{"name": "pool", "type": "mesh", "ior": 1.34,
                   "vertices": np.round(wv, 6).tolist(), "triangles": wt.tolist(),
                   "iops": {"absorption": [0.02, 0.05, 0.30], "b": [0.05, 0.05, 0.05],
                            "phase": {"type": "henyey_greenstein", "g": 0.9}}}],
        "sun": {"zenith_deg": 35.0, "azimuth_deg": 30.0, "irradiance": sun_e,
                "angular_diameter_deg": float(sun_diameter_deg)},
        "sky": {"type": "uniform", "radiance": [0.02 * e / math.pi for e in sun_e]},
        "cameras": [
            {"name": "above", "type": "perspective", "position": [0.0, -3.6, 3.8],
             "look_at": [0.0, 0.0, -0.2], "up": [0, 0, 1], "fov_deg": 70.0, "resolution": res},
            {"name": "under", "type": "perspective", "position": [2.8, -1.1, -0.9],
             "look_at": [-2.0, 0.4, -1.05], "up": [0, 0, 1], "fov_deg": 75.0, "resolution": res},
        ],
        "settings": {"integrator": integrator, "samples": int(samples), "seed": 7,
                     "forward_cone_deg": "auto", "beam_max_level": BEAM_MAX_LEVEL},
    }
    return Scene.from_dict(d)
