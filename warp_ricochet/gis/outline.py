"""Danger-area outlines from a map's counts (docs/hazard.md, "Outlines and GIS files"): the fewest
highest cells holding at least 1 - p of a threshold's passes (ties at the cut included), their squares'
union with its holes filled (the cells its squares enclose), as a valid shapely MultiPolygon in local map coordinates (u, v), m."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from rasterio.features import shapes
from rasterio.transform import Affine
from scipy.ndimage import binary_fill_holes
from shapely.geometry import MultiPolygon, Polygon, shape


@dataclass(frozen=True)
class Outline:
    """One threshold's outline at containment p. `geometry` None when nothing is outlined: no passes
    (`total` 0), or more than p of them off the grid (`contained` False)."""

    p: float
    total: int  # passes (or landings) above the threshold: on the grid and off it
    off_grid: int  # those off the grid
    left_out: int  # those outside the outline (off the grid included): at most p * total when contained
    contained: bool
    cells: int  # cells chosen (before holes are filled)
    geometry: MultiPolygon | None
    area: float  # m^2 of `geometry` (0 without one)


def chosen_cells(counts: np.ndarray, off_grid: int, p: float) -> tuple[np.ndarray | None, int]:
    """(mask of the chosen cells, or None when more than p of the total is off the grid; total).
    The cells ranked by count, the fewest highest holding at least (1 - p) of the total, every cell
    tied with the last one taken too. Exact on the integer counts: what is left out is at most
    p * total (the comparison is of integers against that one product)."""
    counts = np.asarray(counts, dtype=np.int64)
    total = int(counts.sum()) + int(off_grid)
    allowed = p * total  # the passes that may lie outside
    if off_grid > allowed:
        return None, total
    if total == 0:
        return np.zeros(counts.shape, dtype=bool), 0
    ranked = np.sort(counts, axis=None)[::-1]
    left = total - np.cumsum(ranked)  # left out after taking the k + 1 highest cells
    k = int(np.argmax(left <= allowed))  # (exists: taking every nonzero cell leaves off_grid <= allowed)
    return counts >= max(int(ranked[k]), 1), total


def outline(counts: np.ndarray, off_grid: int, p: float, u0: float, v0: float, cell: float) -> Outline:
    """The outline of `counts` (nv, nu; row j spans v0 + j cell ... , column i u0 + i cell ...) at p."""
    counts = np.asarray(counts, dtype=np.int64)
    mask, total = chosen_cells(counts, off_grid, p)
    if mask is None:
        return Outline(p, total, int(off_grid), total, False, 0, None, 0.0)
    kept = int(counts[mask].sum())
    if not mask.any():
        return Outline(p, total, int(off_grid), total - kept, True, 0, None, 0.0)
    transform = Affine(cell, 0.0, u0, 0.0, cell, v0)
    solid = binary_fill_holes(mask)  # (the cells no path along cell edges joins to the border)
    pieces = shapes(solid.astype(np.uint8), mask=solid, connectivity=4, transform=transform)
    # the regions of a hole-free mask: disjoint, meeting at most at corners, so no union is needed
    geometry = filled(MultiPolygon([shape(geom) for geom, _ in pieces]))
    return Outline(p, total, int(off_grid), total - kept, True, int(mask.sum()), geometry, float(geometry.area))


def filled(geometry) -> MultiPolygon:
    """`geometry`'s polygons with their holes filled, merged (a hole may hold other polygons, and
    polygons meeting at corners may enclose one), until none has a hole."""
    geometry = to_multipolygon(geometry)
    while any(part.interiors for part in geometry.geoms):
        geometry = to_multipolygon(shapely.union_all([Polygon(part.exterior) for part in geometry.geoms]))
    return geometry


def to_multipolygon(geometry) -> MultiPolygon:
    """A valid MultiPolygon of `geometry`'s polygons (shapely.make_valid where it is not valid)."""
    if not geometry.is_valid:
        geometry = shapely.make_valid(geometry)
    parts = [g for g in shapely.get_parts(geometry) if isinstance(g, Polygon) and not g.is_empty]
    if not parts:  # (a collection of polygons within it)
        parts = [g for g in shapely.get_parts(shapely.get_parts(geometry)) if isinstance(g, Polygon)]
    return MultiPolygon(parts)
