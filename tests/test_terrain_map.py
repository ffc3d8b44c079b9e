"""Landing maps on a terrain (issue 27 section 5; docs/hazard.md section 5): a horizontal grid in
the site's easting/northing (perpendicular to up = -g/|g|) counting each landing on the terrain by
its horizontal position. A flat raster gives the plane's map; a tilted one the counts of the
landings' horizontal projections; the GeoTIFF export lies where the raster's samples are in its CRS."""

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio", reason="the gis extra (rasterio) is not installed")
pytest.importorskip("pyproj", reason="the gis extra (pyproj) is not installed")

import h5py  # noqa: E402
from helpers import assert_opens_in_xarray, paper_raw  # noqa: E402
from test_terrain import SITE, one_line, write_tif  # noqa: E402

import warp_ricochet as wr  # noqa: E402
from warp_ricochet.scene import scene_from_dict  # noqa: E402
from warp_ricochet.scene.terrain import place_terrain, read_raster  # noqa: E402

GROUND = {k: v for k, v in paper_raw()["surfaces"][0].items() if k not in ("point", "normal")}  # its material
UNWATCHED = {"energy_density": [], "speed": []}  # (the hazard along the path above a terrain is refused)
MAP = {"map_cell": 0.5, "map_extent": [-5.0, 140.0, -25.0, 25.0], **UNWATCHED}


def grid_raster(tmp_path, name, slope_east=0.0, slope_north=0.0, west=0.0, north=60.0, rows=60, cols=160, cell=1.0, crs=None):
    """A raster of z = slope_east x + slope_north y (x east, y south from its north-west corner, at
    the pixels' centres)."""
    x = cell * (np.arange(cols) + 0.5)
    y = cell * (np.arange(rows) + 0.5)
    z = slope_east * x[None, :] + slope_north * y[:, None]
    return write_tif(tmp_path / name, z, west, north, cell, crs=crs)


def run_map(tmp_path, name, surface, hazard=MAP, count=300):
    """A float64 run of the paper's shot to the landing on `surface` alone, with `hazard`: its file."""
    raw = paper_raw(until="landing")
    raw["shot"]["count"] = count
    raw["surfaces"] = [surface]
    raw["hazard"] = dict(hazard)
    raw["numerics"] = {"precision": "float64"}
    scene = scene_from_dict(raw)
    wr.run(scene, tmp_path / name, device="cpu")
    return scene, tmp_path / name


def landings_and_map(path):
    with h5py.File(path) as f:
        m = f["hazard/map"]
        grid = {
            k: m[k][()] for k in ("count", "energy", "outside", "elsewhere", "origin", "u_axis", "v_axis", "u_edges", "v_edges")
        }
        return f["pellets/landing/position"][:], f["pellets/landing/surface"][:], grid


def test_a_flat_raster_s_map_is_the_plane_s(tmp_path):
    """To rounding: a landing on the raster's triangles is found where the plane has it to ~1e-14 m
    (the triangle's plane is computed from its vertices), so only a landing that close to a cell edge
    could change cell; none is within 1e-9 m of one here, and every cell is equal."""
    flat = grid_raster(tmp_path, "flat.tif")
    _, plane = run_map(tmp_path, "plane.h5", paper_raw()["surfaces"][0])
    _, terrain = run_map(tmp_path, "terrain.h5", {"kind": "terrain", "file": str(flat), "origin": [10.0, 30.0], **GROUND})
    on_plane, _, want = landings_and_map(plane)
    on_terrain, surface, got = landings_and_map(terrain)
    assert (surface == 0).all() and want["count"].sum() == len(on_plane) == 300  # all on the map
    np.testing.assert_allclose(on_terrain, on_plane, rtol=0, atol=1e-9)
    u = (on_plane - want["origin"]) @ want["u_axis"]
    v = (on_plane - want["origin"]) @ want["v_axis"]
    for edges, x in ((want["u_edges"], u), (want["v_edges"], v)):
        assert np.abs(x[:, None] - edges[None, :]).min() > 1e-9  # (so the maps must agree cell by cell)
    for key, value in want.items():
        np.testing.assert_array_equal(got[key], value, err_msg=key)
    assert "geometry/surface_0/triangles" in assert_opens_in_xarray(terrain)  # (xarray: the terrain's triangles, the map)


def test_a_tilted_raster_counts_the_landings_horizontal_projections(tmp_path):
    """A raster falling 5% downrange (east) and rising 3% to the right (south): the map's cells are the NumPy counts
    of each landing's (easting, northing) from the shooter, its position projected along up."""
    tilted = grid_raster(tmp_path, "tilted.tif", slope_east=-0.05, slope_north=0.03)
    keys = dict(origin=[10.0, 30.0], elevation=-0.5 + 0.03 * 30.0, **GROUND)  # (the raster's height at the shooter: -0.5 m)
    scene, path = run_map(tmp_path, "tilted.h5", {"kind": "terrain", "file": str(tilted), **keys})
    position, surface, got = landings_and_map(path)
    assert (surface == 0).all()
    up = np.array([0.0, 1.0, 0.0])  # -g/|g| of the paper's scene
    assert np.ptp(position @ up) > 0.5  # (their heights differ: 0.8 m; 6 m below the shooter)
    assert abs(got["u_axis"] @ up) < 1e-15 and abs(got["v_axis"] @ up) < 1e-15  # a horizontal grid
    shooter = np.array(scene.shot.envelope_center)
    horizontal = position - np.outer(position @ up, up)
    east, left = ((horizontal - (shooter - (shooter @ up) * up)) @ np.array([[1.0, 0.0], [0.0, 0.0], [0.0, -1.0]])).T
    np.testing.assert_array_equal(got["u_axis"], [1.0, 0.0, 0.0])  # downrange: east; v = up x u: north (-z)
    counts, _, _ = np.histogram2d(left, east, bins=[got["v_edges"], got["u_edges"]])
    assert counts.sum() == len(position) == 300
    np.testing.assert_array_equal(got["count"], counts.astype(np.int64))
    assert got["outside"] == 0 and got["elsewhere"] == 0


def test_a_terrain_ground_s_refusals_are_one_line(tmp_path):
    flat = str(grid_raster(tmp_path, "flat.tif"))

    def scene(hazard, **keys):
        raw = paper_raw(until="landing")
        raw["surfaces"] = [{"kind": "terrain", "file": flat, **GROUND, **keys}]
        raw["hazard"] = hazard
        return raw

    watched = scene_from_dict(scene({"map_surface": 0}))  # (thresholds: the hazard along the path above it)
    assert watched.hazard.thresholds and watched.surfaces[0].kind == "terrain"
    places = {**MAP, "points": [{"name": "path", "position": [500.0, 0.0, 0.0], "area": 1.0}]}
    one_line(scene(places), "hazard.points.0.position", "outside hazard.map_extent")
    one_line(scene(MAP, normal=[0.0, 0.6, 0.8], axis_u=[1.0, 0.0, 0.0]), "surfaces.0.normal", "must be the scene's up")
    one_line(scene({**MAP, "map_axis": [0.0, 1.0, 0.0]}), "hazard.map_axis", "is along the normal")


def test_the_geotiff_of_a_terrain_map_lies_on_the_raster_s_crs(tmp_path):
    """With a site, the map's GeoTIFF is in the raster's CRS, and each landing's pixel there (its
    easting/northing found from the raster's own samples, as placed in the scene) holds it."""
    from warp_ricochet.gis.export import export

    west, north = 500_000.0, 4_200_250.0
    tif = grid_raster(
        tmp_path, "site.tif", slope_east=-0.02, west=west, north=north, rows=60, cols=60, cell=5.0, crs="EPSG:32630"
    )
    hazard = {"map_cell": 2.0, "map_extent": [-10.0, 140.0, -30.0, 30.0], "site": dict(SITE), **UNWATCHED}
    ground = {"kind": "terrain", "file": str(tif), "elevation": -0.02 * 100.0, **GROUND}  # (0 m under the shooter)
    scene, path = run_map(tmp_path, "site.h5", ground, hazard)
    position, surface, _ = landings_and_map(path)
    assert (surface == 0).all()
    vertices, _ = place_terrain(scene, 0)
    x, y = read_raster(tif).centres()  # the samples' (easting, northing), the vertices' order (no nodata)
    fit, residual, *_ = np.linalg.lstsq(np.c_[vertices[:, [0, 2]], np.ones(len(vertices))], np.c_[x.ravel(), y.ravel()])
    assert np.sqrt(residual.max() / len(vertices)) < 1e-6  # (the site's transform is affine here to 1e-6 m)
    crs_xy = np.c_[position[:, [0, 2]], np.ones(len(position))] @ fit
    out = tmp_path / "map.tif"
    export(path, geotiff=out)
    with rasterio.open(out) as src:
        assert src.crs.to_epsg() == 32630
        count = src.read(list(src.descriptions).index("landings per cell") + 1)
        rows, cols = zip(*(src.index(px, py) for px, py in crs_xy))
    assert count.sum() == len(position) == 300
    assert (count[rows, cols] > 0).all()
    cells = np.unique(np.c_[rows, cols], axis=0)
    assert count[cells[:, 0], cells[:, 1]].sum() == len(position)  # (no landing counted elsewhere)
