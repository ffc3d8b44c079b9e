"""The hazard along the path above a terrain (`tallies.terrain_walk`, docs/hazard.md section 11):
random vacuum flights watched over a raster of (a) a flat plane, the same reach, passes and places
as over the analytic plane; (b) a tilted plane, the same as over the tilted analytic plane; (c) a
hill, a berm and a nodata hole, against the float64 brute-force path sampler
(`reference.path_hazard` with `reference.terrain.TerrainHeight`: the triangle under each sample
point found among the mesh's triangles); and the grid the watch reads from a raster file is the
placed mesh's."""

import math

import numpy as np
import pytest
import warp as wp

from tests.test_path_hazard import _bounds
from tests.test_path_watch import _watch_kernel
from warp_ricochet.physics.types import types_for
from warp_ricochet.reference import path_hazard as ph
from warp_ricochet.reference.terrain import TerrainHeight
from warp_ricochet.scene.terrain import grid_triangles
from warp_ricochet.tallies.counts import DeviceTally, TallySetup
from warp_ricochet.tallies.terrain_ground import TerrainGrid

G = 9.81
H = 1.8  # m, body height
SPEEDS = (30.0, 60.0, 100.0)  # m/s, the thresholds
UP = np.array([0.0, 1.0, 0.0])
CELL, X0, Z0, NX, NZ = 2.0, -10.0, -40.0, 56, 41  # the raster: 2 m cells, x in [-10, 100], z in [-40, 40]
MAP = dict(cell=1.0, extent=(-10.0, 120.0, -30.0, 30.0))
PLACES = (("hilltop", (40.0, 0.0, 0.0), 4.0), ("berm", (70.0, 0.0, 5.0), 6.0), ("far", (95.0, 0.0, -3.0), 8.0))
CLOSE = {"float64": 1e-5, "float32": 1e-4}  # the reach against the sampler, of the path length (issue 26)
ROUNDING = {"float64": 1e-9, "float32": 1e-6}


def _grid(height, hole=False):
    """TerrainGrid of vertices (i, j) at (X0 + CELL j, height, Z0 + CELL i); `hole`: a nodata patch."""
    x = X0 + CELL * np.arange(NX)
    z = Z0 + CELL * np.arange(NZ)
    heights = height(x[None, :], z[:, None]) + np.zeros((NZ, NX))
    if hole:
        heights[18:22, 20:24] = np.nan  # x in [30, 36], z in [-4, 2]: no triangle there
    return TerrainGrid(np.array([X0, 0.0, Z0]), np.array([CELL, 0.0, 0.0]), np.array([0.0, 0.0, CELL]), UP, heights)


def _mesh(grid):
    """(vertices, triangles) of the grid's raster as `scene.terrain` triangulates it."""
    rows, cols = grid.z.shape
    i, j = np.divmod(np.arange(rows * cols), cols)
    vertices = grid.origin + np.outer(j, grid.col) + np.outer(i, grid.row) + np.outer(np.nan_to_num(grid.z.ravel()), UP)
    return vertices, grid_triangles(~np.isnan(grid.z), flip=False)


def _hill(x, z):
    return 3.0 * np.exp(-((x - 40.0) ** 2 + z**2) / 150.0) + 2.5 * np.clip(1.0 - np.abs(x - 70.0) / 4.0, 0.0, 1.0) - 0.02 * x


def _setup(grid=None, normal=(0.0, 1.0, 0.0), places=PLACES):
    nu = math.ceil((MAP["extent"][1] - MAP["extent"][0]) / MAP["cell"])
    nv = math.ceil((MAP["extent"][3] - MAP["extent"][2]) / MAP["cell"])
    n = np.asarray(normal, dtype=np.float64)
    return TallySetup(
        names=tuple(f"t{i}" for i in range(len(SPEEDS))),
        kinds=("speed",) * len(SPEEDS),
        values=SPEEDS,
        thresholds2=tuple(s * s for s in SPEEDS),
        shooter=(0.0, 0.0, 0.0),
        up=tuple(UP),
        half_mass=1e-4,
        area=1e-5,
        fractions=(1e-3,),
        map_surface=0,
        map_origin=(0.0, 0.0, 0.0),
        map_u=(1.0, 0.0, 0.0),
        map_v=(0.0, 0.0, 1.0),
        map_u0=MAP["extent"][0],
        map_v0=MAP["extent"][2],
        map_cell=MAP["cell"],
        map_nu=nu,
        map_nv=nv,
        body_height=H,
        ground_point=(0.0, 0.0, 0.0),
        ground_normal=tuple(n / (n @ UP)),
        places=places,
        terrain=grid,
    )


def _watch(precision, setup, x0, v0, dt):
    """Per flight its reach (n, K) and the chunk's counts: passes by level and column, places."""
    t = types_for(precision)
    watch, _lines = _watch_kernel(precision, len(setup.places), setup.terrain is not None)
    n = len(x0)
    tally = DeviceTally(setup, precision, wp.get_device("cpu"), active=True)
    tally.start(None)
    reach = wp.zeros((n, len(SPEEDS)), dtype=t.scalar, device="cpu")
    inputs = [
        wp.array(x0, dtype=t.vec3, device="cpu"),
        wp.array(v0, dtype=t.vec3, device="cpu"),
        t.vec3(0.0, -G, 0.0),
        wp.array(np.asarray(dt, dtype=np.float64), dtype=t.scalar, device="cpu"),
    ]
    wp.launch(watch, dim=n, inputs=[tally.struct, *inputs], outputs=[reach], device="cpu")
    tally.resolve()
    passes = tally.counts["exposure"].numpy().reshape(setup.levels, setup.cells + 2).astype(np.int64)
    places = tally.counts["places"].numpy().reshape(setup.levels, len(setup.places)).astype(np.int64)
    return reach.numpy().astype(np.float64), passes, places


def _flights(rng, n, ground):
    """Launches 0.05-3 m above the ground under them, 20-120 m/s, 10 deg down to 25 up, within 8
    deg of +x, flown 0.2-1 s: over the hill, the berm, the hole and past the raster's end."""
    x0 = np.column_stack([rng.uniform(-5.0, 60.0, n), np.zeros(n), rng.uniform(-8.0, 8.0, n)])
    x0[:, 1] = ground(x0) + rng.uniform(0.05, 3.0, n)
    speed = rng.uniform(20.0, 120.0, n)
    angle, side = np.radians(rng.uniform(-10.0, 25.0, n)), np.radians(rng.uniform(-8.0, 8.0, n))
    v0 = speed[:, None] * np.column_stack([np.cos(angle) * np.cos(side), np.sin(angle), np.cos(angle) * np.sin(side)])
    return x0, v0, rng.uniform(0.2, 1.0, n)


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("slope", [(0.0, 0.0), (0.05, -0.03)])
def test_a_raster_of_a_plane_watches_as_the_plane(precision, slope):
    """(a) A flat raster and (b) a tilted one (heights a x + b z, exact at the vertices) over their
    whole extent: the reach per threshold within rounding of the analytic plane's (1e-12 of the
    path length in float64, 2e-6 in float32), the passes cell by cell and level by level and the
    named places the same (float32: passes within 0.1%, moved across an edge by rounding)."""
    a, b = slope
    grid = _grid(lambda x, z: a * x + b * z)
    rng = np.random.default_rng(27)
    n = 200
    x0, v0, dt = _flights(rng, n, lambda x: a * x[:, 0] + b * x[:, 2])
    x0[:, 0] = np.clip(x0[:, 0], 0.0, 30.0)  # (the flights stay over the raster: off it the ground is the base plane)
    x0[:, 1] = a * x0[:, 0] + b * x0[:, 2] + rng.uniform(0.05, 3.0, n)
    dt = np.minimum(dt, 60.0 / np.linalg.norm(v0, axis=1))
    on, passes, places = _watch(precision, _setup(grid), x0, v0, dt)
    want, want_passes, want_places = _watch(precision, _setup(None, normal=(-a, 1.0, -b)), x0, v0, dt)
    length = np.linalg.norm(v0, axis=1) * dt
    np.testing.assert_array_equal(np.isnan(on), np.isnan(want))
    close = 1e-12 if precision == "float64" else 2e-6
    assert np.nanmax(np.abs(on - want) / length[:, None]) <= close
    assert np.isfinite(want).sum() > n  # (most flights reach within body height above some threshold)
    np.testing.assert_array_equal(places, want_places)
    if precision == "float64":
        np.testing.assert_array_equal(passes, want_passes)
    else:
        assert np.abs(passes - want_passes).sum() <= 1e-3 * want_passes.sum()
    assert want_passes[:, :-2].sum() > 1000 and want_places.sum() > 5


def _exposure(passes, setup, order):
    """The kernel's counts by level as the run file lays them out: passes (nv, nu), exposure (K, nv,
    nu) at or above each threshold, exposure_outside (all, then per threshold)."""
    k, cells = len(SPEEDS), setup.cells
    rank = np.empty(k, dtype=int)
    rank[order] = np.arange(k)
    shape = (setup.map_nv, setup.map_nu)
    exposure = np.stack([passes[rank[i] + 1 :, :cells].sum(axis=0).reshape(shape) for i in range(k)])
    outside = np.array([passes[:, cells].sum()] + [passes[rank[i] + 1 :, cells].sum() for i in range(k)])
    return {"passes": passes[:, :cells].sum(axis=0).reshape(shape), "exposure": exposure, "outside": outside}


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_hill_and_a_berm_match_the_brute_force_sampler(precision):
    """(c) A hill, a berm and a nodata hole: every reach within CLOSE of the path length of the
    sampler's, every cell of the passes and exposure maps within the sampler's bounds (equal but
    for passes it flags within a rounding of an edge, of body height or of a threshold), and the
    named places' counts the sampler's."""
    grid = _grid(_hill, hole=True)
    vertices, triangles = _mesh(grid)
    terrain = TerrainHeight(vertices, triangles, (0.0, 0.0, 0.0), UP)
    rng = np.random.default_rng(28)
    n = 24
    x0, v0, dt = _flights(rng, n, terrain)
    setup = _setup(grid)
    reach, passes, places = _watch(precision, setup, x0, v0, dt)
    g = ph.Grid(
        (0.0, 0.0, 0.0),
        (1.0, 0.0, 0.0),
        (0.0, 0.0, 1.0),
        MAP["extent"][0],
        MAP["extent"][2],
        MAP["cell"],
        setup.map_nu,
        setup.map_nv,
    )
    hazard = ph.Hazard(
        (0.0, 0.0, 0.0), tuple(UP), (0.0, 0.0, 0.0), tuple(UP), H, SPEEDS, g, tuple((p, r) for _n, p, r in PLACES), terrain
    )
    order = np.argsort(np.asarray(SPEEDS), kind="stable")
    found, all_passes, levels = 0, [], []
    for i in range(n):
        path = ph.parabola(x0[i], v0[i], dt[i], (0.0, -G, 0.0))
        length = path.length(0)
        tolerance = (CLOSE[precision] * length, CLOSE[precision] * np.linalg.norm(v0[i]))
        rounding = (ROUNDING[precision] * length, ROUNDING[precision] * np.linalg.norm(v0[i]))
        h = ph.hazard_of(path, hazard, tolerance, rounding)
        for j in range(len(SPEEDS)):
            if math.isnan(h.reach[j]):
                assert math.isnan(reach[i, j]) or reach[i, j] <= h.reach_high[j] + tolerance[0], (i, j, reach[i, j])
            elif h.reach_high[j] - h.reach_low[j] > tolerance[0]:  # a graze: within the spread a rounding makes
                assert h.reach_low[j] - tolerance[0] <= reach[i, j] <= h.reach_high[j] + tolerance[0], (i, j)
            else:
                found += 1
                assert abs(reach[i, j] - h.reach[j]) <= tolerance[0], (i, j, reach[i, j], h.reach[j], length)
        all_passes += h.passes
        levels.append(h.points)
    assert found >= n  # (most flights reach within body height above some threshold)
    lower, upper = _bounds(all_passes, hazard, order)
    got = _exposure(passes, setup, order)
    for name in ("passes", "exposure", "outside"):
        bad = np.argwhere((got[name] < lower[name]) | (got[name] > upper[name]))
        assert not bad.size, (
            name,
            [(tuple(c), got[name][tuple(c)], lower[name][tuple(c)], upper[name][tuple(c)]) for c in bad[:10]],
        )
    assert sum(p.certain for p in all_passes) >= 0.8 * len(all_passes)
    want = [
        [sum(1 for pellet in levels if pellet[k] is not None and pellet[k] >= level) for k in range(len(PLACES))]
        for level in range(1, len(SPEEDS) + 1)
    ]
    got_places = [places[level:].sum(axis=0) for level in range(1, len(SPEEDS) + 1)]
    np.testing.assert_array_equal(got_places, want)
