"""A terrain as the hazard's ground (docs/hazard.md section 11, "Above a terrain"), on the host: the
raster's grid of placed vertices as the path's watch reads it (`tallies.terrain_walk`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from .terrain_walk import HEADER


@dataclasses.dataclass(frozen=True)
class TerrainGrid:
    """A raster's vertices: vertex (i, j) (row, column) at origin + j col + i row + z[i, j] up (m;
    origin on the base plane, col and row horizontal; z NaN where no triangle uses the vertex);
    `deviation` (m): the largest horizontal distance of a placed vertex from that affine grid (0 to
    rounding unless a [hazard.site] placed the raster through its projection)."""

    origin: np.ndarray
    col: np.ndarray
    row: np.ndarray
    up: np.ndarray
    z: np.ndarray
    deviation: float = 0.0

    def duals(self) -> tuple[np.ndarray, np.ndarray]:
        """(A*, B*): horizontal, with A*.col = B*.row = 1 and A*.row = B*.col = 0 (fc = (x - origin).A*)."""
        a, b = self.col, self.row
        aa, ab, bb = a @ a, a @ b, b @ b
        det = aa * bb - ab * ab
        return (bb * a - ab * b) / det, (aa * b - ab * a) / det

    def packed(self) -> np.ndarray:
        """`Tally.terrain`: origin, A*, B*, col, row (3 each), rows, cols, the highest z (at least 0,
        the base plane's), then z row by row (float64)."""
        rows, cols = self.z.shape
        col_dual, row_dual = self.duals()
        top = max(0.0, float(np.nanmax(self.z)))
        head = np.concatenate([self.origin, col_dual, row_dual, self.col, self.row, [rows, cols, top]])
        assert head.size == HEADER
        return np.concatenate([head, self.z.ravel()])

    def height(self, x) -> np.ndarray:
        """m: the ground's height above the base plane under points x (n, 3), float64: the triangle's
        plane, the base plane (0) off the raster (`tallies.terrain_walk`'s rule, for tests)."""
        x = np.atleast_2d(np.asarray(x, dtype=np.float64)) - self.origin
        col_dual, row_dual = self.duals()
        fc, fr = x @ col_dual, x @ row_dual
        rows, cols = self.z.shape
        i, j = np.floor(fr).astype(np.int64), np.floor(fc).astype(np.int64)
        inside = (i >= 0) & (j >= 0) & (i < rows - 1) & (j < cols - 1)
        i, j = np.where(inside, i, 0), np.where(inside, j, 0)
        s, t = fc - j, fr - i
        z = self.z
        a_side = s >= t
        h = np.where(
            a_side,
            z[i, j] + s * (z[i, j + 1] - z[i, j]) + t * (z[i + 1, j + 1] - z[i, j + 1]),
            z[i, j] + t * (z[i + 1, j] - z[i, j]) + s * (z[i + 1, j + 1] - z[i + 1, j]),
        )
        return np.where(inside & np.isfinite(h), h, 0.0)


def terrain_grid(surface, vertices, base_point, up) -> TerrainGrid:
    """The TerrainGrid of terrain `surface` (parsed: its file and nodata) from its placed vertices
    (`scene.terrain.place_terrain`'s, float64 (n, 3): the raster's samples used by a triangle, in
    raster order), its base plane's point and the unit up: heights (v - point).up, the horizontal
    feet fitted by least squares to origin + j col + i row."""
    from ..scene.terrain import grid_triangles, read_raster

    raster = read_raster(surface.file, surface.nodata)
    rows, cols = raster.z.shape
    used = np.zeros(rows * cols, dtype=bool)
    used[grid_triangles(~np.isnan(raster.z), flip=False).ravel()] = True
    flat = np.flatnonzero(used)
    i, j = np.divmod(flat, cols)
    up, point = np.asarray(up, dtype=np.float64), np.asarray(base_point, dtype=np.float64)
    v = np.asarray(vertices, dtype=np.float64)
    height = (v - point) @ up
    foot = v - np.outer(height, up)
    design = np.column_stack([np.ones(len(flat)), j, i]).astype(np.float64)
    centre = foot.mean(axis=0)  # (fitted about the mean: the fit's rounding is that of the grid's size)
    coef, *_ = np.linalg.lstsq(design, foot - centre, rcond=None)
    origin, col, row = coef[0] + centre, coef[1], coef[2]
    origin = origin - ((origin - point) @ up) * up
    col, row = col - (col @ up) * up, row - (row @ up) * up
    deviation = float(np.max(np.linalg.norm(design @ np.stack([origin, col, row]) - foot, axis=1)))
    z = np.full(rows * cols, np.nan)
    z[flat] = height
    return TerrainGrid(origin, col, row, up, z.reshape(rows, cols), deviation)


def with_terrain(setup, scene, model):
    """`setup` (a `counts.TallySetup`) with the TerrainGrid of the hazard's ground when that is a
    terrain watched along the path (`model.meshes`: its placed triangles), else `setup`."""
    hazard = scene.hazard
    if not (setup.path and scene.terrain_ground):
        return setup
    grid = terrain_grid(
        scene.surfaces[hazard.map_surface], model.meshes[hazard.map_surface].vertices, setup.ground_point, setup.up
    )
    return dataclasses.replace(setup, terrain=grid)
