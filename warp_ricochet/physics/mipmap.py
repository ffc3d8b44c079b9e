"""A terrain's maximum mipmap, on the host (`physics.grid_walk` walks it; `physics.types` stores it)."""

import numpy as np

LOWEST_TOP = -1.0e30  # m: a hole's top (no triangle), finite in float32


def max_pyramid(grid, vertices: np.ndarray, triangles: np.ndarray, dtype) -> tuple[np.ndarray, np.ndarray]:
    """(first, tops) of the maximum mipmap (Tevs, Ihrke & Seidel 2008) of `grid` (a
    `scene.terrain.TerrainGrid`: its cells, origin and up) for `physics.grid_walk`:
    `tops` holds, level after level (level L starts at first[L]; blocks of 2^L x 2^L cells row by row,
    ceil(cols / 2^L) a row), the height (m along `grid.up` above `grid.origin`, both as rounded to
    `dtype`) of the highest vertex of each cell's triangles (level 0, LOWEST_TOP for a hole), and from
    level 1 on of every cell within one cell of the block; the last level is one block. `vertices`:
    the kernel's (already in `dtype`); the heights are rounded up to `dtype`."""
    rows, cols = grid.cells.shape
    origin = np.asarray(grid.origin, dtype=dtype).astype(np.float64)
    up = np.asarray(grid.up, dtype=dtype).astype(np.float64)
    height = (np.asarray(vertices, dtype=np.float64) - origin) @ up
    first = grid.cells.ravel()
    top = np.full(rows * cols, LOWEST_TOP)
    held = first >= 0
    corners = np.concatenate([triangles[first[held]], triangles[first[held] + 1]], axis=1)
    top[held] = height[corners].max(axis=1)
    level = top.reshape(rows, cols)
    padded = np.pad(level, 1, constant_values=LOWEST_TOP)
    near = np.max([padded[i : i + rows, j : j + cols] for i in range(3) for j in range(3)], axis=0)
    levels, block = [level], near
    while len(levels) == 1 or levels[-1].shape != (1, 1):
        r, c = block.shape
        block = np.pad(block, ((0, r % 2), (0, c % 2)), constant_values=LOWEST_TOP)
        block = block.reshape(block.shape[0] // 2, 2, block.shape[1] // 2, 2).max(axis=(1, 3))
        levels.append(block)
    tops = np.concatenate([lv.ravel() for lv in levels])
    rounded = tops.astype(dtype)
    rounded = np.where(rounded.astype(np.float64) < tops, np.nextafter(rounded, dtype.type(np.inf)), rounded)
    return np.cumsum([0] + [lv.size for lv in levels[:-1]]).astype(np.int32), rounded


def grid_deviation(grid, vertices: np.ndarray, triangles: np.ndarray, dtype) -> float:
    """How far (m, across the raster) any vertex of a cell's triangles lies from that cell's corner
    it stands for, with `grid`'s frame as rounded to `dtype` (the kernel's; `vertices` the kernel's):
    float32 rounding, or an axis_u not quite perpendicular to up. The walk adds it to its margin."""
    origin, per_col, per_row = (np.asarray(a, dtype=dtype).astype(np.float64) for a in (grid.origin, grid.per_col, grid.per_row))
    rows, cols = grid.cells.shape
    r, c = np.nonzero(grid.cells >= 0)
    first = grid.cells[r, c]
    corners = np.concatenate([triangles[first], triangles[first + 1]], axis=1)  # (cells, 6)
    points = np.asarray(vertices, dtype=np.float64)[corners] - origin
    u, w = points @ per_col, points @ per_row
    off_u = np.minimum(np.abs(u - c[:, None]), np.abs(u - c[:, None] - 1.0)).max(initial=0.0)
    off_w = np.minimum(np.abs(w - r[:, None]), np.abs(w - r[:, None] - 1.0)).max(initial=0.0)
    return float(max(off_u / np.linalg.norm(per_col), off_w / np.linalg.norm(per_row)))
