"""Small meshes shared by the tests."""
import numpy as np


def box(lo, hi):
    """A closed box with outward normals: (vertices, triangles) as lists."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
         [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]]
    t = [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
         [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]
    return v, t


def height_field(period, n, height=lambda x, y: 0.0 * x):
    """A periodic height-field patch over [0, period]^2 with n x n quads, z = height(x, y)."""
    g = np.linspace(0.0, period, n + 1)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    v = np.stack([xx.ravel(), yy.ravel(), height(xx, yy).ravel()], 1)
    idx = lambda i, j: i * (n + 1) + j
    t = []
    for i in range(n):
        for j in range(n):
            t += [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)], [idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]]
    return v.tolist(), t
