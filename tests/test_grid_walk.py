"""The terrain's raster walk (issue 27; physics/grid_walk.py, docs/geometry.md "Terrain"): its cells
and maximum mipmap on the host, and on the device the same contacts, bit for bit, as the chords' BVH
search it replaces, for shots from every side at a rough raster with holes."""

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio", reason="the gis extra (rasterio) is not installed")

import h5py  # noqa: E402
import warp as wp  # noqa: E402
from rasterio.transform import Affine  # noqa: E402

import warp_ricochet as wr  # noqa: E402
from warp_ricochet import model as model_module  # noqa: E402
from warp_ricochet.model import Model  # noqa: E402
from warp_ricochet.physics.mipmap import LOWEST_TOP, grid_deviation, max_pyramid  # noqa: E402
from warp_ricochet.scene import scene_from_dict  # noqa: E402
from warp_ricochet.scene import terrain as terrain_module  # noqa: E402
from warp_ricochet.scene.terrain import cell_triangles, grid_triangles  # noqa: E402

CELL = 0.7  # m


def rough_raster(path, rng, rows=25, cols=32, holes=6):
    """A GeoTIFF of rough relief (+-1.5 m, slopes up to ~2) with `holes` nodata samples."""
    x = np.arange(cols)[None, :]
    y = np.arange(rows)[:, None]
    z = 1.5 * np.sin(0.5 * x + 0.3 * y) * np.cos(0.2 * x - 0.45 * y) + 0.4 * rng.standard_normal((rows, cols))
    z[rng.integers(0, rows, holes), rng.integers(0, cols, holes)] = -9999.0
    with rasterio.open(
        path, "w", driver="GTiff", width=cols, height=rows, count=1, dtype="float64",
        transform=Affine(CELL, 0.0, 100.0, 0.0, -CELL, 200.0), nodata=-9999.0,
    ) as out:  # fmt: skip
        out.write(z, 1)
    return path


def test_each_cell_names_its_own_two_triangles():
    rng = np.random.default_rng(3)
    valid = rng.random((9, 13)) > 0.15
    tris, first = grid_triangles(valid, flip=False), cell_triangles(valid)
    cols = valid.shape[1]
    for (r, c), f in np.ndenumerate(first):
        corners = {r * cols + c, r * cols + c + 1, (r + 1) * cols + c, (r + 1) * cols + c + 1}
        if f < 0:
            assert not valid[r : r + 2, c : c + 2].all()
        else:
            assert set(tris[f]) | set(tris[f + 1]) == corners and set(tris[f]) <= corners
    assert (first >= 0).sum() * 2 == len(tris)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_mipmap_covers_each_block_and_its_neighbours(dtype):
    """Level 0: each cell's highest vertex (a hole: LOWEST_TOP); level L: no lower than any cell
    within one cell of its block; the last level one block; float32 tops rounded up."""
    rng = np.random.default_rng(5)
    rows, cols = 11, 19
    valid = rng.random((rows + 1, cols + 1)) > 0.1
    tris = grid_triangles(valid, flip=False)
    heights = 1e3 + rng.standard_normal((rows + 1) * (cols + 1))
    vertices = np.stack([rng.random(heights.size), rng.random(heights.size), heights], 1).astype(dtype)
    grid = terrain_module.TerrainGrid(np.zeros(3), np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 1.0]), cell_triangles(valid))
    first, tops = max_pyramid(grid, vertices, tris, np.dtype(dtype))
    z = vertices[:, 2].astype(np.float64)
    cell = np.full((rows, cols), LOWEST_TOP)
    for (r, c), f in np.ndenumerate(grid.cells):
        if f >= 0:
            cell[r, c] = z[np.r_[tris[f], tris[f + 1]]].max()
    assert (tops[: rows * cols].astype(np.float64) >= cell.ravel()).all()
    assert (tops[: rows * cols].astype(np.float64) - cell.ravel() <= np.abs(cell.ravel()) * np.finfo(dtype).eps).all()
    for level in range(1, len(first)):
        size, across = 1 << level, -(-cols // (1 << level))
        end = first[level + 1] if level + 1 < len(first) else len(tops)
        assert end - first[level] == across * -(-rows // size)
        for j in range(-(-rows // size)):
            for i in range(across):
                near = cell[max(j * size - 1, 0) : (j + 1) * size + 1, max(i * size - 1, 0) : (i + 1) * size + 1]
                assert tops[first[level] + j * across + i] >= near.max()
    assert len(tops) - first[-1] == 1


def test_the_vertices_offset_from_their_cell_corners_is_measured():
    """`grid_deviation`: 0 for vertices on the grid (float64); the largest offset across the raster
    (m) of a vertex moved off its corner, in either direction."""
    valid = np.ones((4, 6), dtype=bool)
    tris = grid_triangles(valid, flip=False)
    r, c = np.mgrid[0:4, 0:6]
    frame = np.array([[0.5, 0.0, 0.0], [0.0, -0.25, 0.0], [0.0, 0.0, 1.0]])  # per_col, per_row (1/m), up
    points = np.stack([c.ravel() / 0.5, r.ravel() / -0.25, np.zeros(24)], 1)
    grid = terrain_module.TerrainGrid(np.zeros(3), frame[0], frame[1], frame[2], cell_triangles(valid))
    assert grid_deviation(grid, points, tris, np.dtype(np.float64)) == 0.0
    points[7] += [3e-4, 0.0, 5.0]  # 3e-4 m east (and any height)
    points[16] += [0.0, 1e-3, 0.0]  # 1e-3 m north
    assert grid_deviation(grid, points, tris, np.dtype(np.float64)) == pytest.approx(1e-3, rel=1e-9)


def _shots(rng, count, low, high):
    """(x0, v0): pellets from all around the raster's box (low, high) and through it: above, below,
    beside, straight down, level, fast and slow."""
    centre, size = 0.5 * (low + high), high - low
    start = centre + (rng.random((count, 3)) - 0.5) * size * np.array([1.6, 1.6, 3.0])
    aim = centre + (rng.random((count, 3)) - 0.5) * size * np.array([1.0, 1.0, 0.5])
    v = (aim - start) / rng.uniform(0.05, 0.6, (count, 1))
    v[: count // 10, :2] = 0.0  # straight down or up
    v[count // 10 : count // 5, 2] = 0.0  # level
    return start, v


def _run(tmp_path, raw, walk, device, monkeypatch):
    """Per-pellet outputs of `raw`, its terrain walked or (its grid dropped) searched by the chords."""

    def placed(scene, index, grid=False):
        out = place(scene, index, grid)
        return out if walk or not grid else out[:2] + (None,)

    place = terrain_module.place_terrain
    monkeypatch.setattr(terrain_module, "place_terrain", placed)
    model_module._cached_model.cache_clear()
    scene = scene_from_dict(raw)
    walked = Model.from_scene(scene, wp.get_device(device))
    levels = walked.surfaces.grid_dims.numpy()[0][2]
    out = {}
    path = tmp_path / f"{'walk' if walk else 'chords'}.h5"
    wr.run(scene, path, device=device, overwrite=True)
    with h5py.File(path) as f:
        f["pellets"].visititems(lambda k, d: out.__setitem__(k, d[()]) if isinstance(d, h5py.Dataset) else None)
    monkeypatch.setattr(terrain_module, "place_terrain", place)
    model_module._cached_model.cache_clear()
    return out, levels


@pytest.mark.parametrize("precision", ["float32", "float64"])
@pytest.mark.parametrize("case", ["level", "air", "tilted", "weightless"])
def test_the_walk_meets_what_the_chords_meet(tmp_path, monkeypatch, device, precision, case):
    """Shots from every side at a rough raster with holes (`_shots`), two bounces, to the landing:
    the same per-pellet outputs, bit for bit, with the raster's cells (the walk in vacuum; the
    contact normal's and the air steps' candidates) and with its BVH only (the chords). "air":
    sea-level air; "tilted": the raster's up 0.3 rad off gravity, whose part along it drifts the line
    past a third of a cell (the walk gives way to the chords); "weightless": straight lines."""
    rng = np.random.default_rng({"level": 1, "air": 4, "tilted": 2, "weightless": 3}[case])
    raster = rough_raster(tmp_path / "rough.tif", rng)
    normal, east = [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]
    if case == "tilted":
        normal, east = [np.sin(0.3), 0.0, np.cos(0.3)], [np.cos(0.3), 0.0, -np.sin(0.3)]
    gravity = [0.0, 0.0, 0.0] if case == "weightless" else [0.0, 0.0, -9.81]
    low, high = np.array([0.0, -25 * CELL, -1.5]), np.array([32 * CELL, 0.0, 1.5])
    x, v = _shots(rng, 3000, low, high)
    np.savez(tmp_path / "shots.npz", position=x, velocity=v)
    raw = {
        "shot": {"file": str(tmp_path / "shots.npz"), "diameter": 0.0025, "density": 11340.0},
        "surfaces": [
            {
                "kind": "terrain",
                "file": str(raster),
                "point": [0.0, 0.0, 0.0],
                "normal": normal,
                "axis_u": east,
                "origin": [100.0, 200.0],
                "restitution": 0.4,
                "mu_s": 0.3,
            },
            {"point": [0.0, 0.0, -40.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.0, "mu_s": 0.5},
        ],  # fmt: skip
        "physics": {"gravity": gravity, "until": "landing", "bounces": 2},
        "numerics": {"precision": precision},
        "output": {"fields": ["impact", "landing"]},
    }
    if case == "air":
        raw["air"] = {}
    walked, levels = _run(tmp_path, raw, True, device, monkeypatch)
    chords, none = _run(tmp_path, raw, False, device, monkeypatch)
    assert levels == 6 and none == 0  # (31 x 24 cells: blocks of 1 to 32 cells)
    hit = walked["impact/surface"].reshape(len(x), -1)
    assert 0.3 * len(hit) < (hit[:, 0] == 0).sum() < len(hit)  # many meet the terrain, not all
    assert (hit[:, 1] == 0).sum() > 0.05 * len(hit)  # some twice
    for name, values in chords.items():
        np.testing.assert_array_equal(walked[name], values, err_msg=name)


def edge_raster(path):
    """4 x 40 cells of 1 m: level to row 12, then rising 2 m a row; its east column 1 m lower, so the
    cells along its east edge face east (a pellet just outside that edge meets them)."""
    z = np.zeros((41, 5))
    z[13:, :] = 2.0 * (np.arange(13, 41) - 12.0)[:, None]
    z[:, -1] -= 1.0
    with rasterio.open(
        path, "w", driver="GTiff", width=5, height=41, count=1, dtype="float64",
        transform=Affine(1.0, 0.0, 1000.0, 0.0, -1.0, 2000.0),
    ) as out:  # fmt: skip
        out.write(z, 1)
    return path


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_the_walk_meets_cells_along_the_raster_s_edge_beyond_its_block(tmp_path, monkeypatch, device, precision):
    """A centre just outside the raster's east edge, flying nearly along it, meets the east-facing
    cells of a rise 12 rows on: beyond the block it left the raster from (a review's case, found
    missed by the walk as first written). The same contacts walked and by the chords, and that one
    met at t = 0.1347 s."""
    rng = np.random.default_rng(8)
    x = np.array([[4.4, -1.0, 0.55]]) + np.r_[np.zeros((1, 3)), rng.uniform(-0.05, 0.05, (199, 3))]
    v = np.array([[1.0, -90.0, 0.0]]) * np.r_[np.ones((1, 1)), rng.uniform(0.5, 1.5, (199, 1))]
    v[100:, 0] = rng.uniform(-0.5, 3.0, 100)
    x[150:, 0], v[150:, 1] = 1.0 - x[150:, 0], -v[150:, 1] / 3.0  # along the west edge too
    np.savez(tmp_path / "shots.npz", position=x, velocity=v)
    raw = {
        "shot": {"file": str(tmp_path / "shots.npz"), "diameter": 0.2, "density": 11340.0},
        "surfaces": [
            {
                "kind": "terrain",
                "file": str(edge_raster(tmp_path / "edge.tif")),
                "normal": [0.0, 0.0, 1.0],
                "restitution": 0.4,
                "mu_s": 0.3,
            },
            {"point": [0.0, 0.0, -40.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.0, "mu_s": 0.5},
        ],  # fmt: skip
        "physics": {"gravity": [0.0, 0.0, -9.81], "until": "landing", "bounces": 1},
        "numerics": {"precision": precision},
        "output": {"fields": ["impact"]},
    }
    walked, levels = _run(tmp_path, raw, True, device, monkeypatch)
    chords, _ = _run(tmp_path, raw, False, device, monkeypatch)
    assert levels > 2
    surface = walked["impact/surface"].reshape(len(x), -1)[:, 0]
    assert surface[0] == 0 and (surface == 0).sum() > 50
    np.testing.assert_allclose(walked["impact/time"].reshape(len(x), -1)[0, 0], 0.1347, atol=5e-4)
    for name, values in chords.items():
        np.testing.assert_array_equal(walked[name], values, err_msg=name)


def test_a_terrain_placed_through_a_site_is_not_walked(tmp_path):
    """A site's map projection does not keep the raster's cells a regular grid: no `TerrainGrid`."""
    pytest.importorskip("pyproj", reason="the gis extra (pyproj) is not installed")
    from helpers import paper_raw

    raster = rough_raster(tmp_path / "rough.tif", np.random.default_rng(0))
    with rasterio.open(raster, "r+") as f:
        f.crs = "EPSG:32630"
    raw = paper_raw(until="landing")
    raw["surfaces"].append({"kind": "terrain", "file": str(raster), "material": "turf"})
    raw["hazard"] = {"map_cell": 1.0, "map_extent": [-50.0, 200.0, -100.0, 100.0]}
    raw["hazard"]["site"] = {"crs": "EPSG:32630", "shooter": [100.0, 190.0], "azimuth": 30.0}
    scene = scene_from_dict(raw)
    assert terrain_module.place_terrain(scene, 1, grid=True)[2] is None
    without = {key: value for key, value in raw.items() if key != "hazard"}
    assert terrain_module.place_terrain(scene_from_dict(without), 1, grid=True)[2] is not None
