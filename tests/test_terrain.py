"""Terrain from raster elevation models (issue 27, parts 2 and 4; docs/geometry.md, "Terrain"): the
raster's triangles equal the analytic surface they sample, the same wherever the raster lies on the
map (the local origin), with holes at nodata; placed through a site's CRS to 1 mm; scene keys
checked in one line, and a terrain refused at run time until the mesh kind carries it."""

from pathlib import Path

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio", reason="the gis extra (rasterio) is not installed")
pytest.importorskip("pyproj", reason="the gis extra (pyproj) is not installed")

from rasterio.transform import Affine  # noqa: E402

from warp_ricochet.scene.terrain import load_terrain, read_raster  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TRAP_FIELD = ROOT / "warp_ricochet" / "examples" / "terrain" / "trap_field.asc"


def write_tif(path, z, west, north, cell, crs=None, nodata=None):
    """A float64 GeoTIFF of `z` (its first row the northernmost), north-up, square cells."""
    z = np.asarray(z, dtype=np.float64)
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=z.shape[1],
        height=z.shape[0],
        count=1,
        dtype="float64",
        transform=Affine(cell, 0.0, west, 0.0, -cell, north),
        crs=crs,
        nodata=nodata,
    ) as dst:
        dst.write(z, 1)
    return path


def tilted(x, y):
    """An analytic tilted plane (m): 0.13 m/m east, -0.07 m/m north, 41.5 m at the origin."""
    return 41.5 + 0.13 * x - 0.07 * y


def plane_raster(tmp_path, west=0.0, north=24.0, name="plane.tif", rows=12, cols=17, cell=2.0):
    """A raster of the tilted plane in local coordinates (x from west, y from north - rows cell), its
    north-west corner at (west, north)."""
    x = cell * (np.arange(cols) + 0.5)
    y = cell * (np.arange(rows) + 0.5)[::-1]
    z = tilted(x[None, :], y[:, None])
    return write_tif(tmp_path / name, z, west, north, cell)


def heights_at(vertices, triangles, points):
    """The triangulated surface's height at (x, y) points: barycentric in the triangle holding each."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    out = np.full(len(points), np.nan)
    for i, (px, py) in enumerate(points):
        d = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
        wb = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (py - a[:, 1])) / d
        wc = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (px - a[:, 0]) * (b[:, 1] - a[:, 1])) / d
        wa = 1.0 - wb - wc
        j = np.flatnonzero((wa >= -1e-12) & (wb >= -1e-12) & (wc >= -1e-12))[0]
        out[i] = wa[j] * a[j, 2] + wb[j] * b[j, 2] + wc[j] * c[j, 2]
    return out


def test_a_heightfield_of_a_tilted_plane_is_the_plane(tmp_path):
    vertices, triangles = load_terrain(plane_raster(tmp_path), origin=(0.0, 0.0))
    assert vertices.dtype == np.float64 and triangles.dtype == np.int32
    assert triangles.shape == (2 * 11 * 16, 3) and vertices.shape == (12 * 17, 3)
    corners = vertices[triangles]  # every triangle's vertices on the plane
    np.testing.assert_allclose(corners[..., 2], tilted(corners[..., 0], corners[..., 1]), rtol=1e-12, atol=0)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert (normals[:, 2] > 0).all()  # counter-clockwise seen from above
    np.testing.assert_allclose(
        normals / np.linalg.norm(normals, axis=1)[:, None],
        [[-0.13, 0.07, 1.0] / np.sqrt(1.0218)] * len(normals),
        rtol=1e-12,
        atol=1e-15,
    )
    rng = np.random.default_rng(27)
    points = rng.uniform([1.0, 1.0], [33.0, 23.0], size=(200, 2))  # inside the centres' hull
    np.testing.assert_allclose(heights_at(vertices, triangles, points), tilted(points[:, 0], points[:, 1]), rtol=1e-12, atol=0)


def test_a_raster_at_utm_coordinates_gives_the_triangles_at_the_origin(tmp_path):
    cell = 0.3  # (not a binary fraction: the pixel centres at map coordinates round, 1e-10 m apart)
    near = plane_raster(tmp_path, north=0.0, name="near.tif", cell=cell)
    far = plane_raster(tmp_path, west=500_000.0, north=4_200_000.0, name="far.tif", cell=cell)
    v0, t0 = load_terrain(near)  # (the default origin: each raster's corner, as stored)
    v1, t1 = load_terrain(far)
    np.testing.assert_array_equal(t0, t1)
    assert v0.tobytes() == v1.tobytes()  # bitwise in float64 after the subtraction
    assert v0.astype(np.float32).tobytes() == v1.astype(np.float32).tobytes()
    w0, _ = load_terrain(near, origin=(1.0, -2.0), elevation=40.0)  # an origin inside, an elevation
    w1, _ = load_terrain(far, origin=(500_001.0, 4_199_998.0), elevation=40.0)
    assert w0.tobytes() == w1.tobytes()
    np.testing.assert_allclose(w0, v0 - [1.0, -2.0, 40.0], rtol=0, atol=1e-14)


def test_nodata_leaves_holes_and_a_raster_of_nodata_is_refused(tmp_path):
    z = tilted(np.arange(8)[None, :] + 0.5, np.arange(6)[::-1, None] + 0.5)
    z[2, 3] = -9999.0  # an inner sample: the four cells around it go
    z[0, 0] = -9999.0  # a corner sample: its one cell goes
    path = write_tif(tmp_path / "holes.tif", z, 0.0, 6.0, 1.0, nodata=-9999.0)
    vertices, triangles = load_terrain(path)
    assert len(triangles) == 2 * (7 * 5 - 4 - 1)
    assert len(vertices) == 8 * 6 - 2
    hole = np.array([3.5, 6.0 - 2.5])
    assert not np.any(np.all(vertices[:, :2] == hole, axis=1))
    assert len(load_terrain(path, nodata=float(z[5, 7]))[1]) == 2 * (7 * 5 - 4 - 1 - 1)  # and the key's value
    none = write_tif(tmp_path / "none.tif", np.full((4, 5), -9999.0), 0.0, 4.0, 1.0, nodata=-9999.0)
    with pytest.raises(ValueError, match="no valid sample"):
        load_terrain(none)
    scattered = z.copy()
    scattered[1::2, :] = -9999.0  # valid samples on every other row: no cell of four
    with pytest.raises(ValueError, match="no triangle"):
        load_terrain(write_tif(tmp_path / "rows.tif", scattered, 0.0, 6.0, 1.0, nodata=-9999.0))


def test_the_trap_field_raster_is_the_script_s():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_trap_field", ROOT / "examples" / "make_trap_field.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert TRAP_FIELD.read_text() == module.grid_text()
    assert TRAP_FIELD.stat().st_size < 16_000
    raster = read_raster(TRAP_FIELD)
    assert raster.corner == (500_000.0, 4_200_105.0) and raster.z.shape == (21, 61)  # (north-west)
    vertices, triangles = load_terrain(TRAP_FIELD)
    assert len(triangles) == 2 * 60 * 20
    crest = vertices[np.isclose(vertices[:, 0], 152.5)]
    np.testing.assert_allclose(crest[:, 2] - (120.0 - 0.02 * 152.5), 4.0, atol=1e-9)  # the berm
