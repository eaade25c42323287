"""Modifier stacks on a Water Surface, and Blender's Ocean modifier as a wave source.

Photic's sea surface is a height field that repeats without end, so what a Water Surface's
modifiers do is rendered or named, never dropped:

- *Mesh Patch* with an **Ocean modifier**: the evaluated (displaced, animated by the modifier's
  Time) surface is resampled as a height field over exactly one period of the ocean -- its
  Spatial Size x Size, in the object's scale -- so the tiles join; the horizontal displacement
  of Choppiness is kept (the grid's heights are the displaced surface's). Other modifiers in the
  same stack are rendered as evaluated (and must keep the ocean's period: a note says so).
- *Mesh Patch* without one: the evaluated mesh repeats with its x and y extent as the period;
  a note says when its opposite edges do not match (the sea then shows seams).
- *Flat* and *Wave Model*: the object's mesh is not rendered; a note names any modifier that
  would change it, and a mesh that is not flat, and says to choose Mesh Patch.
"""
from __future__ import annotations

import math

import numpy as np

# Modifiers that never change a flat plane's heights (no note on a Flat surface).
FLAT_SAFE = {"SUBSURF", "TRIANGULATE", "EDGE_SPLIT", "WEIGHTED_NORMAL", "MIRROR", "ARRAY",
             "DECIMATE", "REMESH", "MULTIRES"}
MAX_CELLS = 2048  # a resampled patch's cells per period at most


def render_modifiers(obj) -> list:
    """The modifiers of an object enabled for rendering (of its original object)."""
    return [m for m in getattr(obj.original, "modifiers", ()) if m.show_render]


def ocean_modifier(obj):
    """The first Ocean modifier enabled for rendering, or None."""
    return next((m for m in render_modifiers(obj) if m.type == "OCEAN"), None)


def ocean_period(mod, matrix) -> tuple[float, float]:
    """The world period (Lx, Ly) in m of an Ocean modifier under the object's matrix: its
    Spatial Size x Size along the object's x and y axes, which must lie along the world's.

    Raises ValueError when they do not (a rotation about Z other than a multiple of 90
    degrees, or a tilt): a periodic sea's tiles are aligned with the world's axes."""
    size = float(mod.spatial_size) * float(mod.size)
    m = np.asarray(matrix, float)[:3, :3]
    ex, ey = m[:, 0] * size, m[:, 1] * size
    if abs(ex[2]) > 1e-6 * size or abs(ey[2]) > 1e-6 * size:
        raise ValueError("the object is tilted: the ocean must lie in the world's XY plane")
    # (matrices are float32: a turn of 90 degrees leaves about 1e-7 of the other axis)
    if min(abs(ex[0]), abs(ex[1])) > 1e-5 * np.linalg.norm(ex) or \
            min(abs(ey[0]), abs(ey[1])) > 1e-5 * np.linalg.norm(ey):
        angle = math.degrees(math.atan2(ex[1], ex[0]))
        raise ValueError(f"the object is turned {angle:.1f} degrees about Z: the ocean's tiles "
                         f"repeat along the world's axes, so turn it by a multiple of 90 degrees "
                         f"(turn the waves with the modifier's Wave Alignment and Direction)")
    lx = max(abs(ex[0]), abs(ey[0]))
    ly = max(abs(ex[1]), abs(ey[1]))
    return float(lx), float(ly)


def cells_per_period(vertices: np.ndarray, ntri: int, period) -> tuple[int, int]:
    """Grid cells per period that keep about the mesh's own density of vertices."""
    lo, hi = vertices[:, :2].min(axis=0), vertices[:, :2].max(axis=0)
    area = max(float(np.prod(hi - lo)), 1e-12)
    per_area = 0.5 * ntri / area  # grid cells (two triangles each) per m^2
    out = []
    for p in period:
        n = int(round(p * math.sqrt(per_area)))
        out.append(int(np.clip(n, 8, MAX_CELLS)))
    return out[0], out[1]


def resample_periodic(vertices: np.ndarray, triangles: np.ndarray, period, cells,
                      centre=None) -> tuple[np.ndarray, np.ndarray, dict]:
    """A periodic height field from a surface that repeats with ``period``: the heights of the
    triangle mesh (world coordinates, seen from above) at the nodes of a regular grid over one
    period, ``cells`` (nx, ny) cells, centred on ``centre`` (default: the mesh's), the last row
    and column repeating the first so the patch tiles. The mesh is taken as repeating too, so
    nodes beyond its edges (choppy displacement pulls them in) are found on its neighbours.

    Returns (vertices (N, 3), triangles (M, 3) int64 facing up, stats): stats holds
    ``uncovered`` (nodes no triangle covers, filled from their nearest covered neighbour along
    the grid) and ``folded`` (triangles facing down: a surface folding over)."""
    lx, ly = (float(p) for p in period)
    nx, ny = (int(c) for c in cells)
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64)
    if centre is None:
        centre = 0.5 * (v[:, :2].min(axis=0) + v[:, :2].max(axis=0))
    x0, y0 = float(centre[0]) - 0.5 * lx, float(centre[1]) - 0.5 * ly
    hx, hy = lx / nx, ly / ny
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    folded = int(min(np.count_nonzero(cross < 0), np.count_nonzero(cross > 0)))  # the minority faces
    keep = np.abs(cross) > 1e-18
    a, b, c, cross = a[keep], b[keep], c[keep], cross[keep]
    z = np.full((nx, ny), np.nan)
    for sx in (-lx, 0.0, lx):
        for sy in (-ly, 0.0, ly):
            _rasterise(a, b, c, cross, sx, sy, x0, y0, hx, hy, nx, ny, z)
    uncovered = int(np.count_nonzero(np.isnan(z)))
    if uncovered:
        z = _fill(z)
    zz = np.empty((nx + 1, ny + 1))
    zz[:nx, :ny] = z
    zz[nx, :ny] = z[0]
    zz[:nx, ny] = z[:, 0]
    zz[nx, ny] = z[0, 0]
    gx = x0 + np.arange(nx + 1) * hx
    gy = y0 + np.arange(ny + 1) * hy
    gx[-1], gy[-1] = x0 + lx, y0 + ly
    xx, yy = np.meshgrid(gx, gy, indexing="ij")
    out_v = np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    v00 = (i * (ny + 1) + j).ravel()
    v10, v01 = v00 + (ny + 1), v00 + 1
    v11 = v10 + 1
    tri = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    return out_v, tri.astype(np.int64), {"uncovered": uncovered, "nodes": nx * ny, "folded": folded}


def _rasterise(a, b, c, cross, sx, sy, x0, y0, hx, hy, nx, ny, z) -> None:
    """Heights of the triangles (shifted by sx, sy) at the grid nodes they cover, into z."""
    ax, ay = a[:, 0] + sx, a[:, 1] + sy
    bx, by = b[:, 0] + sx, b[:, 1] + sy
    cx, cy = c[:, 0] + sx, c[:, 1] + sy
    i0 = np.ceil((np.minimum(np.minimum(ax, bx), cx) - x0) / hx - 1e-9).astype(np.int64)
    i1 = np.floor((np.maximum(np.maximum(ax, bx), cx) - x0) / hx + 1e-9).astype(np.int64)
    j0 = np.ceil((np.minimum(np.minimum(ay, by), cy) - y0) / hy - 1e-9).astype(np.int64)
    j1 = np.floor((np.maximum(np.maximum(ay, by), cy) - y0) / hy + 1e-9).astype(np.int64)
    sel = (i1 >= 0) & (i0 < nx) & (j1 >= 0) & (j0 < ny) & (i1 >= i0) & (j1 >= j0)
    if not np.any(sel):
        return
    idx = np.flatnonzero(sel)
    span_i = i1[idx] - i0[idx] + 1
    span_j = j1[idx] - j0[idx] + 1
    # Triangles a few cells across (a mesh about as fine as the grid) in one vectorised sweep
    # per offset; larger ones (a coarse mesh) node by node in blocks.
    small = idx[(span_i <= 4) & (span_j <= 4)]
    for di in range(4):
        for dj in range(4):
            k = small[(i0[small] + di <= i1[small]) & (j0[small] + dj <= j1[small])]
            if len(k):
                _fill_nodes(k, i0[k] + di, j0[k] + dj, ax, ay, bx, by, cx, cy, a, b, c, cross,
                            x0, y0, hx, hy, nx, ny, z)
    for k in idx[(span_i > 4) | (span_j > 4)]:
        ii, jj = np.meshgrid(np.arange(max(0, i0[k]), min(nx - 1, i1[k]) + 1),
                             np.arange(max(0, j0[k]), min(ny - 1, j1[k]) + 1), indexing="ij")
        kk = np.full(ii.size, k)
        _fill_nodes(kk, ii.ravel(), jj.ravel(), ax, ay, bx, by, cx, cy, a, b, c, cross,
                    x0, y0, hx, hy, nx, ny, z)


def _fill_nodes(k, i, j, ax, ay, bx, by, cx, cy, a, b, c, cross, x0, y0, hx, hy, nx, ny, z):
    ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    k, i, j = k[ok], i[ok], j[ok]
    px, py = x0 + i * hx, y0 + j * hy
    w1 = ((px - ax[k]) * (cy[k] - ay[k]) - (py - ay[k]) * (cx[k] - ax[k])) / cross[k]
    w2 = ((bx[k] - ax[k]) * (py - ay[k]) - (by[k] - ay[k]) * (px - ax[k])) / cross[k]
    w0 = 1.0 - w1 - w2
    eps = -1e-9
    inside = (w0 >= eps) & (w1 >= eps) & (w2 >= eps)
    k, i, j, w0, w1, w2 = k[inside], i[inside], j[inside], w0[inside], w1[inside], w2[inside]
    z[i, j] = w0 * a[k, 2] + w1 * b[k, 2] + w2 * c[k, 2]


def _fill(z: np.ndarray) -> np.ndarray:
    """NaN nodes from their nearest non-NaN neighbour along the (periodic) grid, by rings."""
    z = z.copy()
    for _ in range(max(z.shape)):
        bad = np.isnan(z)
        if not bad.any():
            break
        acc = np.zeros_like(z)
        cnt = np.zeros_like(z)
        for axis in (0, 1):
            for shift in (-1, 1):
                n = np.roll(z, shift, axis=axis)
                good = ~np.isnan(n)
                acc[good] += n[good]
                cnt[good] += 1
        fill = bad & (cnt > 0)
        z[fill] = acc[fill] / cnt[fill]
    return np.nan_to_num(z, nan=0.0)


def edge_mismatch(vertices: np.ndarray) -> float | None:
    """How far a mesh patch's heights on opposite edges differ (m, the largest over the vertices
    whose counterpart across the period exists), or None when its edge vertices do not pair up
    (then it cannot tile either)."""
    v = np.asarray(vertices, float)
    lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)
    ext = hi - lo
    worst = 0.0
    for axis in (0, 1):
        other = 1 - axis
        tol = 1e-6 * max(ext[axis], 1e-9)
        first = v[np.abs(v[:, axis] - lo[axis]) <= tol]
        last = v[np.abs(v[:, axis] - hi[axis]) <= tol]
        if len(first) == 0 or len(last) == 0:
            return None
        order = np.argsort(last[:, other])
        pos = np.searchsorted(last[order, other], first[:, other])
        pos = np.clip(pos, 0, len(last) - 1)
        match = last[order][pos]
        close = np.abs(match[:, other] - first[:, other]) <= 1e-6 * max(ext[other], 1e-9)
        if not np.any(close):
            return None
        worst = max(worst, float(np.max(np.abs(match[close, 2] - first[close, 2]))))
    return worst
