"""Danger-area outlines and GIS files (issue 26, part 2; docs/hazard.md, "Outlines and GIS files"):
outlines against their definition on exact counts, the site's georeference against pyproj's geodesics,
and the files read back by GDAL's clients (geopandas, rasterio, ogrinfo, gdalinfo)."""

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from tests.helpers import cli

shapely = pytest.importorskip("shapely", reason="the gis extra (shapely) is not installed")
pyproj = pytest.importorskip("pyproj", reason="the gis extra (pyproj) is not installed")
rasterio = pytest.importorskip("rasterio", reason="the gis extra (rasterio) is not installed")

from warp_ricochet.gis.outline import chosen_cells, outline  # noqa: E402
from warp_ricochet.gis.site import LEVEL, Georeference, local_matrix  # noqa: E402

HAZARD_TOML = Path(__file__).resolve().parents[1] / "examples" / "hazard.toml"
UTM = {"crs": "EPSG:32630", "shooter": [620000.0, 5700000.0], "azimuth": 37.0}
# the hazard example, small, its map wide enough to hold nearly every landing
SMALL = ("shot.shots=20", "hazard.map_extent=[-10.0, 340.0, -40.0, 40.0]", "hazard.map_cell=1.0", "shot.seed=7")


def _centres(shape_vu, u0=0.0, v0=0.0, cell=1.0):
    j, i = np.indices(shape_vu)
    return u0 + (i + 0.5) * cell, v0 + (j + 0.5) * cell


def _left_out(geometry, counts, off_grid, u0=0.0, v0=0.0, cell=1.0, to=None):
    """Counts of the cells whose centres lie outside `geometry` (mapped by `to`), plus those off the grid."""
    u, v = _centres(counts.shape, u0, v0, cell)
    x, y = (u, v) if to is None else (np.reshape(c, u.shape) for c in to(u.ravel(), v.ravel()))
    inside = shapely.contains_xy(geometry, x, y) if geometry is not None else np.zeros(counts.shape, bool)
    return int(counts[~inside].sum()) + int(off_grid), inside


# ---------------------------------------------------------------------------------------------- outlines


@pytest.mark.parametrize("seed", range(12))
def test_an_outline_leaves_out_at_most_p_with_the_fewest_cells(seed):
    """Random sparse maps: the outline is a valid MultiPolygon without holes, what lies outside it is
    at most p of the total (integers), it is the fewest cells (dropping the lowest cut cell, without
    ties, leaves out more than p), and its area is that of the cells it holds."""
    rng = np.random.default_rng(seed)
    nv, nu = rng.integers(5, 40, size=2)
    counts = rng.poisson(rng.gamma(0.3, 4.0, size=(nv, nu))) * (rng.random((nv, nu)) < 0.6)
    p = float(rng.choice([0.3, 0.1, 0.01, 1e-3]))
    off = int(rng.integers(0, 3))
    u0, v0, cell = -5.0, 10.0, 0.5
    o = outline(counts, off, p, u0, v0, cell)
    total = int(counts.sum()) + off
    assert o.total == total
    if off > p * total:
        assert not o.contained and o.geometry is None
        return
    assert o.contained and o.geometry.is_valid and o.geometry.geom_type == "MultiPolygon"
    assert all(not part.interiors for part in o.geometry.geoms)
    left, inside = _left_out(o.geometry, counts, off, u0, v0, cell)
    assert left == o.left_out and left <= p * total
    mask, _ = chosen_cells(counts, off, p)
    assert inside[mask].all()  # every chosen cell is in, and holes filled only add cells
    assert math.isclose(o.geometry.area, inside.sum() * cell**2, rel_tol=1e-12)
    cut = counts[mask].min()
    if (counts == cut).sum() == 1:  # no tie at the cut: one cell fewer would leave out too much
        assert total - (counts[mask].sum() - cut) > p * total


def test_holes_are_filled_and_known_points_are_inside():
    """A ring of cells (and a ring of cells meeting only at corners) holds its empty middle; a far
    cell with a few passes is outside at p = 0.1 and inside at p = 0.001."""
    counts = np.zeros((12, 12), np.int64)
    counts[1:6, 1:6] = 50
    counts[2:5, 2:5] = 0  # the hole
    for j, i in ((6, 9), (7, 8), (7, 10), (8, 7), (8, 11), (9, 8), (9, 10), (10, 9)):  # a diamond of corners
        counts[j, i] = 40
    counts[11, 0] = 3
    o = outline(counts, 0, 0.1, 0.0, 0.0, 1.0)
    assert o.geometry.is_valid and all(not part.interiors for part in o.geometry.geoms)
    contains = lambda u, v, g=o.geometry: bool(shapely.contains_xy(g, u, v))  # noqa: E731
    assert contains(3.5, 3.5) and contains(9.5, 8.5)  # the middles of the rings
    assert contains(1.5, 1.5) and not contains(0.5, 11.5) and not contains(11.5, 0.5)
    assert o.area == 25 + 13  # the square ring filled (16 + 9 cells), the diamond (8 + 5)
    assert bool(shapely.contains_xy(outline(counts, 0, 1e-3, 0.0, 0.0, 1.0).geometry, 0.5, 11.5))


def test_off_grid_beyond_p_is_not_drawn_and_no_passes_draw_nothing():
    counts = np.zeros((4, 4), np.int64)
    counts[1, 1] = 98
    assert outline(counts, 2, 0.01, 0, 0, 1).contained is False  # 2 of 100 off the grid
    counts[1, 1] = 99
    assert outline(counts, 1, 0.01, 0, 0, 1).contained is True  # 1 of 100: at most p
    empty = outline(np.zeros((3, 3), np.int64), 0, 0.01, 0, 0, 1)
    assert empty.contained and empty.geometry is None and empty.total == 0 and empty.area == 0.0


# ---------------------------------------------------------------------------------------------- site


@pytest.mark.parametrize(
    "crs, shooter, azimuth",
    [
        ("EPSG:32630", (620000.0, 5700000.0), 37.0),  # UTM 30N, 1.35 deg of grid convergence
        ("EPSG:27700", (530000.0, 180000.0), 300.0),  # British National Grid
        ("EPSG:4326", (-3.2, 51.5), 37.0),  # geographic: through the local azimuthal equidistant projection
        ("EPSG:4258", (10.75, 59.9), 181.0),
    ],
)
def test_the_crs_round_trip_returns_local_coordinates_to_1_mm(crs, shooter, azimuth):
    """Local -> CRS -> local within 1 mm over 3 km; the shooter lands on its coordinates; a point
    downrange lies at its distance from the shooter (geodesic, pyproj.Geod) and at the azimuth (true
    for a geographic CRS, grid for a projected one)."""
    geo = Georeference(crs, shooter, azimuth)
    rng = np.random.default_rng(3)
    u, v = rng.uniform(-500, 3000, 200), rng.uniform(-1500, 1500, 200)
    x, y = geo.to_crs(u, v)
    uu, vv = geo.to_local(x, y)
    assert np.max(np.hypot(uu - u, vv - v)) < 1e-3
    x0, y0 = geo.to_crs(0.0, 0.0)
    assert math.hypot(x0 - shooter[0], y0 - shooter[1]) < (1e-9 if geo.crs.is_geographic else 1e-4)
    geod = geo.crs.get_geod()
    lon_lat = pyproj.Transformer.from_crs(geo.crs, geo.crs.geodetic_crs, always_xy=True)
    x2, y2 = geo.to_crs(2000.0, 0.0)
    (lon0, lon2), (lat0, lat2) = lon_lat.transform([x0, x2], [y0, y2])
    forward, _, distance = geod.inv(lon0, lat0, lon2, lat2)
    assert abs(distance - 2000.0) < 1e-3
    if geo.crs.is_geographic:
        assert abs((forward - azimuth + 180) % 360 - 180) < 1e-7
    else:  # (the line's initial grid bearing: a geodesic is curved on the grid)
        x1, y1 = geo.to_crs(1.0, 0.0)
        assert abs((math.degrees(math.atan2(x1 - x0, y1 - y0)) - azimuth + 180) % 360 - 180) < 1e-6


def test_v_is_to_the_left_and_the_local_frame_follows_the_map_axes():
    """v lies 90 deg anticlockwise of u seen from above; a map whose v axis points the other way
    (its surface's normal down) is mirrored by `local`."""
    geo = Georeference("EPSG:27700", (400000.0, 300000.0), 0.0)  # u due grid north at the central meridian
    x, y = geo.to_crs(0.0, 100.0)
    assert x < 400000.0 - 99.0 and abs(y - 300000.0) < 0.1  # left of north is west
    level = SimpleNamespace(map_u=(1, 0, 0), map_v=(0, 0, -1), up=(0, 1, 0), map_origin=(0, 0, 0), shooter=(0, 1.5, 0))
    np.testing.assert_allclose(local_matrix(level), LEVEL, atol=1e-15)
    mirrored = SimpleNamespace(**{**vars(level), "map_v": (0, 0, 1)})
    np.testing.assert_allclose(local_matrix(mirrored), [[1, 0, 0], [0, -1, 0]], atol=1e-15)
    moved = SimpleNamespace(**{**vars(level), "map_origin": (2.0, 0, 3.0)})  # origin 2 m downrange, 3 m right
    np.testing.assert_allclose(local_matrix(moved), [[1, 0, 2], [0, 1, -3]], atol=1e-15)


# ---------------------------------------------------------------------------------------------- scene


def test_a_site_round_trips_through_the_scene_and_bad_sites_are_refused():
    import warp_ricochet as wr
    from warp_ricochet.scene import load_scene, scene_from_dict

    scene = load_scene(HAZARD_TOML, [f"hazard.site={_toml(UTM)}"])
    assert scene.hazard.site.crs == "EPSG:32630" and scene.hazard.site.azimuth == 37.0
    assert scene_from_dict(scene.to_dict()) == scene and "[hazard.site]" in scene.to_toml()
    for site, match in (
        ({**UTM, "crs": "EPSG:99999"}, r"^hazard\.site\.crs = 'EPSG:99999': is not a CRS pyproj knows"),
        ({**UTM, "crs": "EPSG:4978"}, r"^hazard\.site\.crs = 'EPSG:4978': is a Geocentric CRS"),
        ({**UTM, "shooter": [1.0]}, r"^hazard\.site\.shooter = \[1\.0\]: must be a list of 2 numbers"),
        ({**UTM, "shooter": [1e12, 0.0]}, r"^hazard\.site\.shooter = .*is outside the domain of EPSG:32630"),
        ({**UTM, "azimuth": 360.0}, r"^hazard\.site\.azimuth = 360\.0: must be a number in \[0, 360\)"),
        ({"crs": "EPSG:4326", "shooter": [10.0, 95.0]}, r"^hazard\.site\.shooter = .*lat in \(-90, 90\)"),
        ({"shooter": [0.0, 0.0]}, r"^hazard\.site\.crs = \(missing\): is required"),
        ({**UTM, "north": 1.0}, r"^hazard\.site\.north = 1\.0: unknown key"),
    ):
        with pytest.raises(wr.SceneError, match=match):
            load_scene(HAZARD_TOML, [f"hazard.site={_toml(site)}"])
    with pytest.raises(wr.SceneError, match=r"^hazard\.site = .*needs a map"):
        scene_from_dict({**scene.to_dict(), "hazard": {"site": UTM}})


def _toml(d: dict) -> str:
    from warp_ricochet.scene.toml_out import toml_value

    return toml_value(d)


def test_an_unknown_crs_stops_a_run_before_any_work(tmp_path):
    out = tmp_path / "run.h5"
    rc, _, err = cli(["run", HAZARD_TOML, "-o", out, "--set", f"hazard.site={_toml({**UTM, 'crs': 'EPSG:99999'})}"])
    assert rc == 2 and err.count("\n") == 1 and "hazard.site.crs = 'EPSG:99999': is not a CRS pyproj knows" in err
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------------- files


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A small CPU run of the hazard example with a UTM site, the same without a site, and a copy
    of the first given exposure layers (the lead's layout; their values made up here)."""
    folder = tmp_path_factory.mktemp("gis")
    site = folder / "site.h5"
    rc, _, err = cli(
        ["-q", "run", HAZARD_TOML, "--device", "cpu", "-o", site, *_sets(SMALL), "--set", f"hazard.site={_toml(UTM)}"]
    )
    assert rc == 0, err
    local = folder / "local.h5"
    shutil.copy(site, local)
    with h5py.File(local, "a") as f:
        del f["hazard/site"]
    exposure = folder / "exposure.h5"
    shutil.copy(site, exposure)
    with h5py.File(exposure, "a") as f:
        m = f["hazard/map"]
        k, nv, nu = m["above"].shape
        made = np.zeros((k, nv, nu), np.int64)
        made[:, 5:9, 100:110] = 7 * np.arange(k, 0, -1)[:, None, None]  # a block downrange, off the landings' peak
        for name in ("exposure", "exposure_outside", "passes"):  # (a run's own: replaced by these)
            if name in m:
                del m[name]
        m.create_dataset("exposure", data=made)
        m.create_dataset("exposure_outside", data=np.array([60, 50, 1, 0, 0], np.int64)[: k + 1])
        m.create_dataset("passes", data=made[0] + 1)
    return SimpleNamespace(site=site, local=local, exposure=exposure, folder=folder)


def _sets(keys):
    return [x for key in keys for x in ("--set", key)]


def _export(run, tmp_path, *extra, name="out"):
    gj, tif = tmp_path / f"{name}.geojson", tmp_path / f"{name}.tif"
    rc, out, err = cli(["export", run, "--geojson", gj, "--geotiff", tif, *extra])
    assert rc == 0, err
    assert out.splitlines() == [f"wrote {gj}", f"wrote {tif}"]
    return gj, tif


def _map(path):
    with h5py.File(path, "r") as f:
        m = f["hazard/map"]
        return {
            k: m[k][()] for k in m if k in ("count", "above", "u_edges", "v_edges", "exposure", "exposure_outside", "passes")
        }, {
            "landings": f["hazard/thresholds/landings"][()],
            "fractions": f["hazard/danger_distance/fraction"][()],
            "names": [x.decode() for x in f["hazard/thresholds/name"][()]],
            "site": None if "hazard/site" not in f else {k: f[f"hazard/site/{k}"][()] for k in f["hazard/site"]},
            "attrs": None if "hazard/site" not in f else {k: dict(f[f"hazard/site/{k}"].attrs) for k in f["hazard/site"]},
        }


def _exposed(layers, i):
    """(counts per cell, total) of the passes above threshold i: a run's own exposure layers
    (issue 26), the outlines' basis."""
    counts = layers["exposure"][i]
    return counts, int(counts.sum() + layers["exposure_outside"][1 + i])


def test_the_site_is_written_into_the_run_file(runs):
    _, info = _map(runs.site)
    assert info["site"]["crs"].decode() == "EPSG:32630" and info["site"]["azimuth"] == 37.0
    np.testing.assert_array_equal(info["site"]["shooter"], UTM["shooter"])
    np.testing.assert_allclose(info["site"]["local"], [[1, 0, 0], [0, 1, 0]], atol=1e-12)  # level ground, v = left
    assert pyproj.CRS.from_wkt(info["site"]["crs_wkt"].decode()).to_epsg() == 32630
    assert all({"units", "description"} <= set(attrs) for attrs in info["attrs"].values())


def test_geojson_and_geotiff_of_a_run_with_a_site_open_in_geopandas_and_rasterio(runs, tmp_path):
    """Real GDAL readers: the CRS is the site's, one valid feature per (threshold, p), the landings
    outside each outline (cell centres taken to the CRS) at most p of those above the threshold, the
    landings' busiest cell inside; the GeoTIFF's CRS, its rotated transform and its bands."""
    gpd = pytest.importorskip("geopandas", reason="geopandas is not installed (the test extra)")
    gj, tif = _export(runs.site, tmp_path)
    layers, info = _map(runs.site)
    geo = Georeference(UTM["crs"], UTM["shooter"], UTM["azimuth"])
    frame = gpd.read_file(gj)
    assert frame.crs.to_epsg() == 32630 and len(frame) == len(info["names"]) * len(info["fractions"])
    u0, v0, cell = layers["u_edges"][0], layers["v_edges"][0], layers["u_edges"][1] - layers["u_edges"][0]
    for _, row in frame.iterrows():
        i = info["names"].index(row["threshold"])
        assert row["basis"] == "exposure" and row["pellets"] == 20 * 280
        counts, total = _exposed(layers, i)
        assert row["total"] == total and row["contained"]
        assert row.geometry.is_valid and row.geometry.geom_type == "MultiPolygon"
        left, inside = _left_out(row.geometry, counts, total - counts.sum(), u0, v0, cell, geo.to_crs)
        assert left == row["outside"] and left <= row["p"] * total
        assert inside.flat[np.argmax(counts)]
        assert math.isclose(row["area_m2"], inside.sum() * cell**2)
    with rasterio.open(tif) as r:
        bands = list(r.descriptions)
        assert r.crs.to_epsg() == 32630 and r.count == 2 + 2 * len(info["names"]) and r.nodata is None
        assert bands[0] == "landings per cell" and f"landings above {info['names'][0]}" in bands
        np.testing.assert_array_equal(r.read(1)[::-1], layers["count"])
        np.testing.assert_array_equal(r.read(bands.index(f"landings above {info['names'][0]}") + 1)[::-1], layers["above"][0])
        np.testing.assert_array_equal(r.read(bands.index(f"passes above {info['names'][0]}") + 1)[::-1], layers["exposure"][0])
        # the centre of cell (row j, column i) of the map, through the raster's affine and through pyproj
        j, i = np.unravel_index(np.argmax(layers["count"]), layers["count"].shape)
        x, y = r.xy(r.height - 1 - j, i)
        assert math.hypot(*(np.subtract((x, y), geo.to_crs(u0 + (i + 0.5) * cell, v0 + (j + 0.5) * cell)))) < 1e-3
        a = r.transform
        assert abs(a.b) > 0.1 and abs(a.d) > 0.1  # rotated: the line of fire is along no grid axis
        assert math.isclose(math.degrees(math.atan2(a.a, a.d)), 37.0, abs_tol=1e-4)  # u (columns) at the azimuth
        assert float(r.tags()["AFFINE_MAX_ERROR"]) < 1e-3


def test_a_file_with_exposure_layers_is_outlined_by_them(runs, tmp_path):
    gj, tif = _export(runs.exposure, tmp_path, "--p", "0.01")
    layers, info = _map(runs.exposure)
    collection = json.loads(gj.read_text())
    geo = Georeference(UTM["crs"], UTM["shooter"], UTM["azimuth"])
    u0, v0 = layers["u_edges"][0], layers["v_edges"][0]
    for feature in collection["features"]:
        props = feature["properties"]
        i = info["names"].index(props["threshold"])
        assert props["basis"] == "exposure" and props["p"] == 0.01
        total = int(layers["exposure"][i].sum() + layers["exposure_outside"][1 + i])
        assert props["total"] == total and props["contained"] == (layers["exposure_outside"][1 + i] <= 0.01 * total)
        if props["contained"]:
            g = shapely.geometry.shape(feature["geometry"])
            assert g.is_valid and shapely.contains_xy(g, *geo.to_crs(u0 + 105.5, v0 + 6.5))  # the block
            assert not shapely.contains_xy(g, *geo.to_crs(u0 + 50.5, v0 + 30.5))
        else:
            assert feature["geometry"] is None
    assert [f["properties"]["contained"] for f in collection["features"]] == [False, True, True, True]
    with rasterio.open(tif) as r:
        assert "passes per cell (within body height)" in r.descriptions
        assert f"passes above {info['names'][0]}" in r.descriptions
        np.testing.assert_array_equal(
            r.read(r.descriptions.index(f"passes above {info['names'][1]}") + 1)[::-1], layers["exposure"][1]
        )


def test_a_run_without_a_site_is_written_in_local_metres(runs, tmp_path):
    gpd = pytest.importorskip("geopandas", reason="geopandas is not installed (the test extra)")
    gj, tif = _export(runs.local, tmp_path)
    layers, info = _map(runs.local)
    frame = gpd.read_file(gj)
    assert frame.crs is not None and not frame.crs.is_geographic and not frame.crs.is_projected
    assert "local" in frame.crs.name and "local engineering coordinates" in frame["crs_note"][0]
    u0, v0, cell = layers["u_edges"][0], layers["v_edges"][0], 1.0
    for _, row in frame.iterrows():
        i = info["names"].index(row["threshold"])
        counts, total = _exposed(layers, i)
        left, inside = _left_out(row.geometry, counts, total - counts.sum(), u0, v0, cell)
        assert left == row["outside"] <= row["p"] * total and inside.flat[np.argmax(counts)]
    with rasterio.open(tif) as r:
        assert tuple(r.transform)[:6] == (cell, 0.0, u0, 0.0, -cell, layers["v_edges"][-1])
        assert "local engineering coordinates" in r.tags()["CRS_NOTE"] and "local map" in r.crs.to_wkt()


def test_a_geographic_site_writes_lon_lat_outlines_and_a_local_projection_raster(runs, tmp_path):
    """The run file's site replaced by one in EPSG:4326: the outlines come in lon/lat (GeoJSON's
    CRS84), the raster on the shooter's azimuthal equidistant projection, exactly a rotated grid."""
    gpd = pytest.importorskip("geopandas", reason="geopandas is not installed (the test extra)")
    run = tmp_path / "geographic.h5"
    shutil.copy(runs.site, run)
    with h5py.File(run, "a") as f:
        s = f["hazard/site"]
        for name in ("crs", "crs_wkt", "shooter"):
            del s[name]
        s["crs"], s["crs_wkt"] = np.bytes_("EPSG:4326"), np.bytes_(pyproj.CRS("EPSG:4326").to_wkt())
        s["shooter"] = np.array([-3.2, 51.5])
    gj, tif = _export(run, tmp_path)
    layers, info = _map(run)
    geo = Georeference("EPSG:4326", (-3.2, 51.5), 37.0)
    frame = gpd.read_file(gj)
    assert frame.crs.to_epsg() == 4326
    (x0, x1), (y0, y1) = frame.total_bounds.reshape(2, 2).T
    assert -3.21 < x0 < x1 < -3.18 and 51.49 < y0 < y1 < 51.51  # lon first
    row = frame.iloc[0]
    counts, total = _exposed(layers, info["names"].index(row["threshold"]))
    left, inside = _left_out(
        row.geometry, counts, total - counts.sum(), layers["u_edges"][0], layers["v_edges"][0], 1.0, geo.to_crs
    )
    assert left == row["outside"] and inside.flat[np.argmax(counts)]
    with rasterio.open(tif) as r:
        assert pyproj.CRS(r.crs.to_wkt()).coordinate_operation.method_name.startswith("Azimuthal Equidistant")
        assert math.isclose(math.degrees(math.atan2(r.transform.a, r.transform.d)), 37.0, abs_tol=1e-9)
        assert math.isclose(math.hypot(r.transform.a, r.transform.d), 1.0, rel_tol=1e-12)  # metres, unscaled


@pytest.mark.skipif(
    shutil.which("ogrinfo") is None or shutil.which("gdalinfo") is None, reason="gdal-bin (ogrinfo, gdalinfo) is not installed"
)
def test_ogrinfo_and_gdalinfo_read_the_files(runs, tmp_path):
    gj, tif = _export(runs.site, tmp_path)
    og = subprocess.run(["ogrinfo", "-ro", "-al", "-so", gj], capture_output=True, text=True, check=True).stdout
    assert "Geometry: Multi Polygon" in og and 'ID["EPSG",32630]' in og and "Feature Count: 8" in og
    assert "area_m2: Real" in og and "contained: Integer(Boolean)" in og
    gi = subprocess.run(["gdalinfo", "-json", tif], capture_output=True, text=True, check=True).stdout
    info = json.loads(gi)
    assert info["coordinateSystem"]["wkt"].rstrip().endswith('ID["EPSG",32630]]')
    with rasterio.open(tif) as r:
        np.testing.assert_allclose(info["geoTransform"], r.transform.to_gdal(), rtol=0, atol=1e-9)
    assert [b["description"] for b in info["bands"]][0] == "landings per cell"


# ---------------------------------------------------------------------------------------------- refusals


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--p", "0"], "--p = 0.0: must be a number in (0, 1)"),
        (["--p", "1.5"], "--p = 1.5: must be a number in (0, 1)"),
        (["--p", "nan"], "--p = nan: must be a number in (0, 1)"),
    ],
)
def test_bad_containment_is_refused_before_writing(runs, tmp_path, extra, match):
    rc, _, err = cli(["export", runs.site, "--geojson", tmp_path / "o.geojson", "--geotiff", tmp_path / "o.tif", *extra])
    assert rc == 2 and err == f"warp-ricochet: error: {match}, the share of the exposure left outside an outline\n"
    assert list(tmp_path.iterdir()) == []


def test_bad_output_paths_and_inputs_are_refused_in_one_line(runs, tmp_path):
    folder = tmp_path / "folder.geojson"
    folder.mkdir()
    rc, _, err = cli(["export", runs.site, "--geojson", folder])
    assert rc == 2 and err == f"warp-ricochet: error: --geojson {str(folder)!r}: is a directory; give a file path\n"
    old = tmp_path / "old.tif"
    old.write_bytes(b"keep")
    rc, _, err = cli(["export", runs.site, "--geojson", tmp_path / "new.geojson", "--geotiff", old])
    assert rc == 2 and err.endswith("exists; give --overwrite to replace it\n") and err.count("\n") == 1
    assert old.read_bytes() == b"keep" and not (tmp_path / "new.geojson").exists()
    rc, _, _ = cli(["export", runs.site, "--geojson", tmp_path / "new.geojson", "--geotiff", old, "--overwrite"])
    assert rc == 0 and old.read_bytes()[:2] in (b"II", b"MM")
    rc, _, err = cli(["export", runs.site])
    assert rc == 2 and "give --geojson" in err
    no_map = tmp_path / "no-map.h5"
    shutil.copy(runs.local, no_map)
    with h5py.File(no_map, "a") as f:
        del f["hazard/map"]
    rc, _, err = cli(["export", no_map, "--geojson", tmp_path / "x.geojson"])
    assert rc == 2 and err.endswith("has no hazard map; run the scene with hazard.map_cell and hazard.map_extent\n")
    sweep = tmp_path / "sweep.h5"
    sets = _sets(("shot.shots=1", "shot.count=20"))
    assert cli(["-q", "sweep", HAZARD_TOML, *sets, "--param", "physics.bounces=1,2", "--device", "cpu", "-o", sweep])[0] == 0
    rc, _, err = cli(["export", sweep, "--geojson", tmp_path / "x.geojson"])
    assert rc == 2 and err.endswith("is a sweep file; export takes a run file (run the point's scene on its own)\n")
    assert not (tmp_path / "x.geojson").exists()
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_without_the_gis_extra_export_says_what_to_install(runs, tmp_path, monkeypatch):
    for name in [m for m in sys.modules if m.startswith("warp_ricochet.gis")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "shapely", None)
    rc, _, err = cli(["export", runs.site, "--geojson", tmp_path / "o.geojson"])
    assert (
        rc == 2
        and err == "warp-ricochet: error: export needs the gis extra (shapely is missing): pip install 'warp-ricochet[gis]'\n"
    )


def test_without_pyproj_a_site_is_refused_with_what_to_install(monkeypatch):
    import warp_ricochet as wr
    from warp_ricochet.scene import load_scene

    for name in [m for m in sys.modules if m.startswith("warp_ricochet.gis")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "pyproj", None)
    with pytest.raises(
        wr.SceneError, match=r"^hazard\.site\.crs = 'EPSG:32630': needs pyproj to be checked \(pyproj is missing\)"
    ):
        load_scene(HAZARD_TOML, [f"hazard.site={_toml(UTM)}"])


def test_open_run_reads_the_site(runs):
    xr = pytest.importorskip("xarray", reason="xarray is not installed (the test extra)")
    import warp_ricochet as wr

    run = wr.open_run(runs.site)
    site = run.hazard_results
    assert isinstance(site, xr.Dataset) and str(site["site_crs"].values) == "EPSG:32630"
    assert site["site_local"].dims == ("site_dl", "site_uv1") and site["site_shooter"].dims == ("site_xy",)
