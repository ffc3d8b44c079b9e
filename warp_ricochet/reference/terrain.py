"""Float64 reference for the ground's height under a point of a terrain (the hazard along the path
above a terrain, docs/hazard.md section 11): the triangle whose horizontal projection holds the point,
found among the nearest triangle centroids (SciPy's KD-tree) by barycentric coordinates, and its
plane's height there; off every triangle, the base plane's (0). NumPy and SciPy only: no code of the
kernels, nor their grid."""

from __future__ import annotations

import numpy as np

NEAREST = 12  # triangles tried per point: a raster's right triangles hold a point within the 12 nearest centroids
SLACK = 1e-12  # barycentric coordinates down to -SLACK count as inside (a point on an edge)


class TerrainHeight:
    """height(x): m above the base plane (through `point`, perpendicular to the unit `up`) of the
    triangle mesh (vertices (n, 3) m, triangles (m, 3)) under each point x (k, 3), along up."""

    def __init__(self, vertices, triangles, point, up):
        from scipy.spatial import cKDTree

        up = np.asarray(up, dtype=np.float64)
        self.up, self.point = up / np.linalg.norm(up), np.asarray(point, dtype=np.float64)
        e1 = np.cross(self.up, [1.0, 0.0, 0.0] if abs(self.up[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        self.plane = np.stack([e1, np.cross(self.up, e1)], axis=1)  # (3, 2): horizontal coordinates
        v = np.asarray(vertices, dtype=np.float64) - self.point
        corners = v[np.asarray(triangles, dtype=np.int64)]  # (m, 3, 3)
        self.xy, self.z = corners @ self.plane, corners @ self.up  # (m, 3, 2), (m, 3)
        self.tree = cKDTree(self.xy.mean(axis=1))
        self.k = min(NEAREST, len(self.z))

    def __call__(self, x) -> np.ndarray:
        q = (np.atleast_2d(np.asarray(x, dtype=np.float64)) - self.point) @ self.plane
        _d, idx = self.tree.query(q, k=self.k)
        idx = idx.reshape(len(q), -1)
        a, b, c = (self.xy[idx, j] for j in range(3))  # (k, NEAREST, 2)
        p = q[:, None, :]

        def cross(u, w):
            return u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]

        area = cross(b - a, c - a)
        area = np.where(area == 0.0, np.nan, area)
        la, lb = cross(b - p, c - p) / area, cross(c - p, a - p) / area
        lc = 1.0 - la - lb
        inside = (la >= -SLACK) & (lb >= -SLACK) & (lc >= -SLACK)
        first = np.argmax(inside, axis=1)
        rows = np.arange(len(q))
        z = self.z[idx[rows, first]]
        h = la[rows, first] * z[:, 0] + lb[rows, first] * z[:, 1] + lc[rows, first] * z[:, 2]
        return np.where(inside[rows, first], h, 0.0)
