"""Terrain from raster elevation models as triangles (docs/geometry.md, "Terrain"): a north-up
GeoTIFF or ESRI ASCII grid read by rasterio (the gis extra), one vertex per sample at its pixel's
centre, two triangles per cell of four valid samples (a nodata sample leaves a hole), counter-
clockwise seen from above. Coordinates are taken relative to a local origin in float64 before
anything else (x - x0 = (c - x0) + a (col + 1/2), with c the raster's corner), so a raster at map
coordinates of 1e6 m gives the same local triangles, bitwise, as the same raster at 0, and float32
keeps its accuracy."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

MAX_SAMPLES = 1 << 24  # a raster's samples (rows x cols): 2^25 triangles at most, ~1.5 GB of them in float64


@dataclass(frozen=True)
class Raster:
    """A raster's elevations `z` (m, float64 (rows, cols), NaN where nodata), its pixel size and
    corner (x = x_corner + dx col, y = y_corner + dy row at a pixel's corner: dy < 0 when north-up)
    and its CRS (an authority string such as "EPSG:32630", or None)."""

    z: np.ndarray
    dx: float
    dy: float
    x_corner: float
    y_corner: float
    crs: str | None

    @property
    def corner(self) -> tuple[float, float]:
        """(x, y) of the raster's corner as stored (its transform's origin: north-west when north-up)."""
        return self.x_corner, self.y_corner

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of every pixel's centre, float64 (rows, cols)."""
        rows, cols = self.z.shape
        return self._axes(0.0, 0.0, rows, cols)

    def _axes(self, x0: float, y0: float, rows: int, cols: int):
        x = (self.x_corner - x0) + self.dx * (np.arange(cols, dtype=np.float64) + 0.5)
        y = (self.y_corner - y0) + self.dy * (np.arange(rows, dtype=np.float64) + 0.5)
        return np.broadcast_to(x, (rows, cols)), np.broadcast_to(y[:, None], (rows, cols))


MAX_ELEVATION = 1e6  # m: a valid sample's |z| (the scene's coordinates: schema.MAX_COORDINATE)


def read_raster(path, nodata: float | None = None) -> Raster:
    """The first band of the raster at `path`, its nodata (and `nodata`, when given) as NaN. Raises
    ValueError with a one-line reason for a file that is not a raster, an empty or rotated raster,
    one of more than MAX_SAMPLES samples, one with no valid sample or with one beyond MAX_ELEVATION."""
    try:
        import rasterio
        from rasterio.errors import RasterioError
    except ImportError as exc:
        raise ValueError(f"needs rasterio to be read ({exc.name} is missing): pip install 'warp-ricochet[gis]'") from None
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError("is not a file")
    try:
        with rasterio.Env(AAIGRID_DATATYPE="Float64"), rasterio.open(path) as src:  # (an .asc's decimals as written)
            if src.count < 1 or src.width < 1 or src.height < 1:
                raise ValueError("is an empty raster (no band or no pixel)")
            if src.width * src.height > MAX_SAMPLES:
                raise ValueError(f"has {src.width * src.height:,} samples; at most {MAX_SAMPLES:,}")
            t = src.transform
            if t.b != 0.0 or t.d != 0.0:
                raise ValueError("is rotated or sheared; give a north-up raster (e.g. through gdalwarp)")
            band = src.read(1, masked=True)
            crs = src.crs.to_string() if src.crs is not None else None
    except RasterioError as exc:
        raise ValueError(f"is not a raster rasterio can read ({' '.join(str(exc).split())})") from None
    z = np.ma.filled(band.astype(np.float64), np.nan)
    z[~np.isfinite(z)] = np.nan
    if nodata is not None:
        z[z == nodata] = np.nan
    if np.isnan(z).all():
        raise ValueError(f"has no valid sample (all {z.size:,} are nodata)")
    far = np.nanargmax(np.abs(z))
    if abs(z.flat[far]) > MAX_ELEVATION:  # (float32 GeoTIFFs often mark nodata -3.4e38 without the tag)
        value = float(z.flat[far])
        raise ValueError(
            f"has a sample of {value:g} m (row {far // z.shape[1]}, column {far % z.shape[1]}); elevations are within "
            f"+-{MAX_ELEVATION:g} m: a nodata value the raster does not flag? give nodata = {value!r}"
        )
    return Raster(z, float(t.a), float(t.e), float(t.c), float(t.f), crs)


def grid_triangles(valid: np.ndarray, flip: bool) -> np.ndarray:
    """int32 (m, 3): two triangles per cell of four valid samples of a (rows, cols) grid, indices
    row * cols + col; (00, 01, 11) and (00, 11, 10), reversed when `flip`."""
    rows, cols = valid.shape
    quad = valid[:-1, :-1] & valid[:-1, 1:] & valid[1:, :-1] & valid[1:, 1:]
    r, c = np.nonzero(quad)
    p00 = (r * cols + c).astype(np.int64)
    p01, p10, p11 = p00 + 1, p00 + cols, p00 + cols + 1
    tris = np.stack([np.stack([p00, p01, p11], 1), np.stack([p00, p11, p10], 1)], 1).reshape(-1, 3)
    return (tris[:, ::-1] if flip else tris).astype(np.int32)


def load_terrain(path, origin=None, elevation: float = 0.0, nodata: float | None = None):
    """(vertices float64 (n, 3), triangles int32 (m, 3)) of the raster at `path` in local (east,
    north, up) metres: (x - x0, y - y0, z - elevation) with origin = (x0, y0) (default: the raster's
    stored corner, north-west when north-up: then x - x0 = a (col + 1/2) exactly). Only the vertices of some triangle are kept; the triangles are counter-
    clockwise seen from above (their normals up). ValueError (one line) as `read_raster`, or for a
    raster whose valid samples make no triangle."""
    raster = read_raster(path, nodata)
    return raster_triangles(raster, raster.corner if origin is None else origin, elevation)


def raster_triangles(raster: Raster, origin, elevation: float = 0.0):
    """`load_terrain` of a read raster."""
    rows, cols = raster.z.shape
    x0, y0 = map(float, origin)
    x, y = raster._axes(x0, y0, rows, cols)
    valid = ~np.isnan(raster.z)
    tris = grid_triangles(valid, flip=raster.dx * raster.dy < 0.0)
    if len(tris) == 0:
        raise ValueError("has no cell of four valid samples (no triangle)")
    used = np.zeros(rows * cols, dtype=bool)
    used[tris.ravel()] = True
    index = np.cumsum(used) - 1
    vertices = np.stack([x.ravel()[used], y.ravel()[used], raster.z.ravel()[used] - float(elevation)], 1)
    return vertices, index[tris].astype(np.int32)


def same_crs(raster_crs: str | None, site_crs: str) -> str | None:
    """None, or why a raster's CRS disagrees with the site's (pyproj's equality, axis order aside)."""
    import pyproj

    if raster_crs is None:
        return f"has no CRS; with [hazard.site] it must be in the site's crs {site_crs!r}"
    if not pyproj.CRS.from_user_input(raster_crs).equals(pyproj.CRS.from_user_input(site_crs), ignore_axis_order=True):
        return f"is in {raster_crs}, not in the site's crs {site_crs!r} (hazard.site.crs): reproject it (gdalwarp -t_srs)"
    return None


def up_of(gravity) -> tuple[float, float, float] | None:
    """The scene's up, -g made unit; None for zero gravity."""
    g = math.hypot(*gravity)
    return None if g == 0.0 else tuple(0.0 - x / g for x in gravity)  # (0.0 -: no negative zeros)


@dataclass(frozen=True, eq=False)
class TerrainGrid:
    """Where a terrain's triangles lie in its raster (`physics.grid_walk`): sample (row r, col c) at
    `origin` + c dx `east` + r dy `north` + z `up` in scene coordinates (m), so a point q lies in
    cell (floor((q - origin).per_col), floor((q - origin).per_row)) (per_col = east / dx, per_row =
    north / dy, 1/m); `cells` int32 (rows - 1, cols - 1): the first of the cell's two triangles
    (`grid_triangles`' order), -1 for a hole."""

    origin: np.ndarray
    per_col: np.ndarray
    per_row: np.ndarray
    up: np.ndarray
    cells: np.ndarray


def cell_triangles(valid: np.ndarray) -> np.ndarray:
    """int32 (rows - 1, cols - 1): the first triangle of each cell as `grid_triangles` numbers them
    (2 per cell of four valid samples, row by row), -1 for a cell with a nodata sample."""
    quad = valid[:-1, :-1] & valid[:-1, 1:] & valid[1:, :-1] & valid[1:, 1:]
    return np.where(quad, 2 * (np.cumsum(quad.ravel()) - 1).reshape(quad.shape), -1).astype(np.int32)


def place_terrain(scene, index: int, grid: bool = False):
    """(vertices float64 (n, 3) in scene coordinates, triangles int32 (m, 3)) of terrain surface
    `index` of `scene`. Without [hazard.site]: point + e axis_u + n (normal x axis_u) + h normal,
    (e, n, h) from `load_terrain` (the raster's (origin, elevation) at `point`). With a site: the
    raster's (x, y) through the site's transform (gis.site.Georeference, as the GIS outputs) onto
    the hazard's map, then at height point.up + z - elevation along up (-gravity). `grid`: a third
    item, its `TerrainGrid` (None with a site, whose map projection does not keep the raster's cells
    a regular grid)."""
    s = scene.surfaces[index]
    raster = read_raster(s.file, s.nodata)
    up = np.asarray(s.normal, dtype=np.float64)
    site = None if scene.hazard is None else scene.hazard.site
    if site is None:
        x0, y0 = map(float, s.origin or raster.corner)
        local, tris = raster_triangles(raster, (x0, y0), s.elevation or 0.0)
        east = np.asarray(s.axis_u or (1.0, 0.0, 0.0), dtype=np.float64)
        frame = np.stack([east, np.cross(up, east), up])
        point = np.asarray(s.point, dtype=np.float64)
        if not grid:
            return point + local @ frame, tris
        first = np.array([(raster.x_corner - x0) + 0.5 * raster.dx, (raster.y_corner - y0) + 0.5 * raster.dy, 0.0])
        cells = cell_triangles(~np.isnan(raster.z))
        found = TerrainGrid(point + first @ frame, frame[0] / raster.dx, frame[1] / raster.dy, frame[2], cells)
        return point + local @ frame, tris, found
    from ..gis.site import Georeference, local_matrix
    from ..tallies.counts import TallySetup

    setup = TallySetup.of(scene, 1.0, 1.0, 1.0)  # (the map's frame does not depend on the pellet)
    geo = Georeference(site.crs, site.shooter, site.azimuth, local_matrix(setup))
    local, tris = raster_triangles(raster, (0.0, 0.0), s.elevation or 0.0)  # (CRS coordinates in full)
    u, v = geo.to_local(local[:, 0], local[:, 1])
    foot = np.asarray(setup.map_origin) + np.outer(u, setup.map_u) + np.outer(v, setup.map_v)
    height = np.dot(s.point, up) + local[:, 2] - foot @ up
    return (foot + np.outer(height, up), tris) + ((None,) if grid else ())


TERRAIN_OPTIONAL = ("axis_u", "origin", "elevation", "nodata")  # terrain's keys beside `file` (and point, normal)


def check_terrain(surface, path: str, physics, hazard, base_dir):
    """A parsed surface, a terrain one completed and checked (one SceneError line each): its file
    resolved against `base_dir` and read (a raster with valid cells, in the site's CRS when
    [hazard.site] places it); `normal` (its up) -g unit by default (required with zero gravity),
    along -g with a site; `axis_u` (its east, [1, 0, 0] by default) perpendicular to the normal, and
    with `origin` not allowed with a site (the site places the raster's x, y)."""
    from dataclasses import replace

    from .keys import MISSING, err
    from .schema import PERPENDICULAR
    from .vectors import unit_vector

    if surface.kind != "terrain":
        return surface
    site = None if hazard is None else hazard.site
    up, normal = up_of(physics.gravity), surface.normal
    if not any(normal):
        if up is None:
            raise err(f"{path}.normal", MISSING, "is required for a terrain with zero gravity (its up: a list of 3 numbers)")
        normal = up
    if site is not None:
        for key in ("axis_u", "origin"):
            if getattr(surface, key) is not None:
                raise err(
                    f"{path}.{key}", list(getattr(surface, key)), "not allowed with [hazard.site]: the site places the raster"
                )
        if up is None or abs(sum(a * b for a, b in zip(normal, up)) - 1.0) > PERPENDICULAR:
            raise err(f"{path}.normal", list(normal), f"must be the scene's up (-gravity: {up}) with [hazard.site]")
    east = unit_vector(surface.axis_u) if surface.axis_u is not None else None
    if abs(sum(a * b for a, b in zip(east or (1.0, 0.0, 0.0), normal))) > PERPENDICULAR:
        shown = MISSING if east is None else list(surface.axis_u)
        raise err(
            f"{path}.axis_u", shown, f"must be perpendicular to the terrain's up {list(normal)} (its east; default [1, 0, 0])"
        )
    file = os.path.abspath(os.path.join(os.fspath(base_dir), surface.file))
    try:
        raster = read_raster(file, surface.nodata)
        raster_triangles(raster, surface.origin or raster.corner)
        why = None if site is None else same_crs(raster.crs, site.crs)
    except ValueError as exc:
        why = str(exc)
    if why is not None:
        raise err(f"{path}.file", surface.file, why)
    return replace(surface, file=file, normal=normal, axis_u=east)
