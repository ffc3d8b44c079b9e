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
