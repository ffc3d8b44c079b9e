"""Terrain from raster elevation models (issue 27, parts 2 and 4; docs/geometry.md, "Terrain"): the
raster's triangles equal the analytic surface they sample, the same wherever the raster lies on the
map (the local origin), with holes at nodata; placed through a site's CRS to 1 mm; scene keys
checked in one line; runs on the triangles of the mesh kind give the analytic plane's impacts."""

import sys
from pathlib import Path

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio", reason="the gis extra (rasterio) is not installed")
pytest.importorskip("pyproj", reason="the gis extra (pyproj) is not installed")

from helpers import paper_raw  # noqa: E402
from rasterio.transform import Affine  # noqa: E402

from warp_ricochet.errors import SceneError  # noqa: E402
from warp_ricochet.scene import scene_from_dict  # noqa: E402
from warp_ricochet.scene.terrain import load_terrain, place_terrain, read_raster  # noqa: E402

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


SITE = {"crs": "EPSG:32630", "shooter": [500_100.0, 4_200_050.0], "azimuth": 30.0}


def terrain_scene(path, site=False, **keys):
    """The paper's scene, to the landing (triangles are met until landing only), with a terrain
    (surface 1) from `path`; with `site`, a map placed by SITE."""
    raw = paper_raw(until="landing")
    raw["surfaces"].append({"kind": "terrain", "file": str(path), "material": "turf", **keys})
    if site:
        raw["hazard"] = {"map_cell": 1.0, "map_extent": [-50.0, 200.0, -100.0, 100.0], "site": dict(SITE)}
    return raw


def test_terrain_is_placed_at_its_point_in_the_scene_s_axes(tmp_path):
    path = plane_raster(tmp_path, west=500_000.0, north=4_200_024.0)
    keys = dict(point=[3.0, -1.0, 2.0], origin=[500_000.0, 4_200_000.0], elevation=40.0, axis_u=[0.0, 0.0, 2.0])
    scene = scene_from_dict(terrain_scene(path, **keys))
    terrain = scene.surfaces[1]
    assert terrain.kind == "terrain" and terrain.normal == (0.0, 1.0, 0.0)  # up = -gravity by default
    assert terrain.file == str(path) and terrain.axis_u == (0.0, 0.0, 1.0)
    assert scene_from_dict(scene.to_dict()) == scene  # round trip
    vertices, triangles = place_terrain(scene, 1)
    local, same = load_terrain(path, origin=(500_000.0, 4_200_000.0), elevation=40.0)
    np.testing.assert_array_equal(triangles, same)
    east, north, up = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])  # north = up x east
    np.testing.assert_allclose(
        vertices,
        [3.0, -1.0, 2.0] + np.outer(local[:, 0], east) + np.outer(local[:, 1], north) + np.outer(local[:, 2], up),
        rtol=0,
        atol=1e-12,
    )
    corners = vertices[triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert (normals @ up > 0).all()  # outward: up, the side pellets meet
    assert vertices[np.argmin(np.linalg.norm(local[:, :2], axis=1)), 1] == pytest.approx(
        -1.0 + tilted(1.0, 1.0) - 40.0, abs=1e-12
    )


def test_terrain_through_the_site_s_crs_round_trips_to_a_millimetre(tmp_path):
    from warp_ricochet.gis.site import Georeference, local_matrix
    from warp_ricochet.tallies.counts import TallySetup

    path = plane_raster(tmp_path, west=500_080.0, north=4_200_070.0, rows=20, cols=30, cell=5.0)
    with rasterio.open(path, "r+") as dst:
        dst.crs = rasterio.crs.CRS.from_epsg(32630)
    scene = scene_from_dict(terrain_scene(path, site=True, point=[0.0, 2.0, 0.0], elevation=40.0))
    vertices, _ = place_terrain(scene, 1)
    xyz, _ = load_terrain(path, origin=(0.0, 0.0))  # the raster's own (x, y, z), same order
    setup = TallySetup.of(scene, 1.0, 1.0, 1.0)
    geo = Georeference(SITE["crs"], SITE["shooter"], SITE["azimuth"], local_matrix(setup))
    offset = vertices - np.asarray(setup.map_origin)
    x, y = geo.to_crs(offset @ np.asarray(setup.map_u), offset @ np.asarray(setup.map_v))  # as the GIS outputs
    assert np.hypot(x - xyz[:, 0], y - xyz[:, 1]).max() < 1e-6  # (measured 4e-9 m; the issue asks 1 mm)
    np.testing.assert_allclose(vertices[:, 1], 2.0 + xyz[:, 2] - 40.0, rtol=0, atol=1e-9)  # heights along up


def one_line(raw, key, match):
    with pytest.raises(SceneError, match=match) as info:
        scene_from_dict(raw)
    assert "\n" not in str(info.value) and str(info.value).startswith(key)


def test_terrain_keys_are_checked_in_one_line(tmp_path):
    good = plane_raster(tmp_path)
    text = tmp_path / "not.tif"
    text.write_text("not a raster\n")
    one_line(terrain_scene(text), "surfaces.1.file", "is not a raster")
    one_line(terrain_scene(tmp_path / "absent.tif"), "surfaces.1.file", "is not a file")
    nodata = write_tif(tmp_path / "none.tif", np.full((3, 3), -1.0), 0.0, 3.0, 1.0, nodata=-1.0)
    one_line(terrain_scene(nodata), "surfaces.1.file", "no valid sample")
    flat = write_tif(tmp_path / "flat.tif", [[5.0, 5.0, 7.0], [5.0, 6.0, 5.0]], 0.0, 2.0, 1.0)
    one_line(terrain_scene(flat, nodata=5.0), "surfaces.1.file", "has no cell of four valid samples")  # the key's nodata
    unflagged = write_tif(
        tmp_path / "unflagged.tif", [[5.0, 5.0, 5.0], [5.0, 5.0, -3.4028234663852886e38], [5.0] * 3], 0.0, 3.0, 1.0
    )
    one_line(  # (once a terrain of one triangle fan 3e38 m high: every pellet "missed", no error)
        terrain_scene(unflagged),
        "surfaces.1.file",
        "has a sample of -3.40282e[+]38 m [(]row 1, column 2[)]; elevations are within [+]-1e[+]06 m: a nodata value the "
        "raster does not flag[?] give nodata = -3.4028234663852886e[+]38$",
    )
    scene_from_dict(terrain_scene(unflagged, nodata=-3.4028234663852886e38))  # (the hint's value: accepted)
    raw = terrain_scene(good)
    del raw["surfaces"][1]["file"]
    one_line(raw, "surfaces.1.file", "is required for kind = 'terrain'")
    one_line(terrain_scene(good, size=[1.0, 1.0]), "surfaces.1.size", "is a key of kind = 'rectangle' or 'box' only")
    one_line(terrain_scene(good, origin=[1.0]), "surfaces.1.origin", "list of 2 numbers")
    one_line(terrain_scene(good, axis_u=[1.0, 1.0, 0.0]), "surfaces.1.axis_u", "perpendicular to the terrain's up")
    plane = paper_raw()
    plane["surfaces"][0]["file"] = str(good)
    one_line(plane, "surfaces.0.file", "is a key of kind = 'terrain' or 'mesh' only")
    one_line(terrain_scene(good, site=True), "surfaces.1.file", "has no CRS")
    with rasterio.open(good, "r+") as dst:
        dst.crs = rasterio.crs.CRS.from_epsg(32631)
    one_line(terrain_scene(good, site=True), "surfaces.1.file", "is in EPSG:32631, not in the site's crs")
    one_line(terrain_scene(good, site=True, origin=[0.0, 0.0]), "surfaces.1.origin", "not allowed with")
    one_line(terrain_scene(good, site=True, normal=[1.0, 0.0, 0.0], axis_u=None), "surfaces.1.normal", "must be the scene's up")
    raw = terrain_scene(good)
    raw["physics"]["gravity"] = [0.0, 0.0, 0.0]
    one_line(raw, "surfaces.1.normal", "is required for a terrain with zero gravity")


def _first_impacts(raw, tmp_path, name):
    """Per pellet of a run of `raw` (float64, to the landing): its first impact's position and velocity."""
    import h5py

    import warp_ricochet as wr

    raw = {**raw, "physics": {**raw["physics"], "until": "landing", "bounces": 1}, "output": {"fields": ["impact"]}}
    raw["numerics"] = {"precision": "float64"}
    wr.run(scene_from_dict(raw), tmp_path / name, device="cpu")
    with h5py.File(tmp_path / name) as f:
        return f["pellets/impact/position"][:, 0], f["pellets/impact/velocity"][:, 0]


RIGID = {"restitution": 0.3, "mu_s": 0.4}


def test_a_run_on_a_heightfield_of_a_tilted_plane_is_the_run_on_the_plane(tmp_path):
    """The shot's first impacts on the raster of a tilted plane (its triangles on the device) are
    those on the analytic plane through three of its vertices, to 1e-9 of their size (float64)."""
    keys = dict(point=[-5.0, -1.5, -12.0], elevation=39.82, **RIGID)
    raw = paper_raw(until="landing")
    raw["shot"]["count"] = 200
    raw["surfaces"] = [{"kind": "terrain", "file": str(plane_raster(tmp_path)), **keys}]
    vertices, triangles = place_terrain(scene_from_dict(raw), 0)
    a, b, c = vertices[triangles[0]]
    normal = np.cross(b - a, c - a)
    plane = {**paper_raw(), "surfaces": [{"point": list(a), "normal": list(normal / np.linalg.norm(normal)), **RIGID}]}
    plane["shot"]["count"] = 200
    on_terrain, v_terrain = _first_impacts(raw, tmp_path, "terrain.h5")
    on_plane, v_plane = _first_impacts(plane, tmp_path, "plane.h5")
    assert np.isfinite(on_plane).all() and (on_plane[:, 0] > -3.0).all()  # all on the raster's extent
    np.testing.assert_allclose(on_terrain, on_plane, rtol=0, atol=1e-9 * np.abs(on_plane).max())
    np.testing.assert_allclose(v_terrain, v_plane, rtol=0, atol=1e-9 * np.abs(v_plane).max())


def test_a_raster_at_utm_scale_runs_as_the_same_raster_at_the_origin(tmp_path):
    """The same heights stored at (5e5, 4.2e6) with that origin, and at 0: the same impacts, bit for bit."""
    raw = paper_raw()
    raw["shot"]["count"] = 100
    far = plane_raster(tmp_path, west=500_000.0, north=4_200_024.0, name="far.tif")
    near = plane_raster(tmp_path, name="near.tif")
    keys = dict(point=[-5.0, -1.5, -12.0], elevation=39.82, **RIGID)
    raw["surfaces"] = [{"kind": "terrain", "file": str(far), "origin": [500_000.0, 4_200_024.0], **keys}]
    got = _first_impacts(raw, tmp_path, "far.h5")
    raw["surfaces"] = [{"kind": "terrain", "file": str(near), **keys}]
    want = _first_impacts(raw, tmp_path, "near.h5")
    for x, y in zip(got, want):
        assert np.isfinite(y).all()
        np.testing.assert_array_equal(x, y)


def test_a_rectangle_still_needs_its_axis(tmp_path):
    raw = paper_raw()
    raw["surfaces"].append(
        {"kind": "rectangle", "point": [5.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "size": [1.0, 1.0], "material": "steel_plate"}
    )
    one_line(raw, "surfaces.1.axis_u", "is required for kind = 'rectangle'")  # (terrain's axis_u is optional, not a rectangle's)


def test_a_terrain_without_the_gis_extra_is_one_line(tmp_path, monkeypatch):
    good = plane_raster(tmp_path)
    monkeypatch.setitem(sys.modules, "rasterio", None)  # (import rasterio raises ImportError)
    one_line(terrain_scene(good), "surfaces.1.file", "needs rasterio to be read .* pip install 'warp-ricochet\\[gis\\]'")


def test_a_terrain_s_model_is_reused_until_its_raster_changes(tmp_path):
    """A run over a terrain (without a site) reuses the model of the run before (its triangles and
    BVH built once), with the same impacts; a raster rewritten with other heights is read again."""
    import os

    from warp_ricochet.model import _cached_model

    keys = dict(point=[-5.0, -1.5, -12.0], elevation=39.82, **RIGID)
    raw = paper_raw(until="landing")
    raw["shot"]["count"] = 50
    path = plane_raster(tmp_path)
    raw["surfaces"] = [{"kind": "terrain", "file": str(path), **keys}]
    first = _first_impacts(raw, tmp_path, "a.h5")
    built = _cached_model.cache_info().misses
    again = _first_impacts(raw, tmp_path, "b.h5")
    assert _cached_model.cache_info().misses == built  # (not built again)
    for x, y in zip(first, again):
        np.testing.assert_array_equal(x, y)
    x = 2.0 * (np.arange(17) + 0.5)
    y = 2.0 * (np.arange(12) + 0.5)[::-1]
    write_tif(path, tilted(x[None, :], y[:, None]) + 0.25, 0.0, 24.0, 2.0)  # 0.25 m higher
    os.utime(path, ns=(1, 1))  # (a new stamp even within the file system's time resolution)
    higher = _first_impacts(raw, tmp_path, "c.h5")
    assert _cached_model.cache_info().misses == built + 1
    assert not np.array_equal(higher[0], first[0])
