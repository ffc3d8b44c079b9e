"""The hazard along the path above a terrain (`tallies.terrain_walk`, docs/hazard.md section 11):
random vacuum flights watched over a raster of (a) a flat plane, the same reach, passes and places
as over the analytic plane; (b) a tilted plane, the same as over the tilted analytic plane; (c) a
hill, a berm and a nodata hole, against the float64 brute-force path sampler
(`reference.path_hazard` with `reference.terrain.TerrainHeight`: the triangle under each sample
point found among the mesh's triangles); and the grid the watch reads from a raster file is the
placed mesh's."""

import functools
import math
from pathlib import Path

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
from warp_ricochet.tallies.path_chord import make_path_watch
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
TRAP_FIELD = Path(__file__).resolve().parents[1] / "warp_ricochet" / "examples" / "terrain" / "trap_field.asc"


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


def _watch(precision, setup, x0, v0, dt, curve=None):
    """Per flight its reach (n, K) and the chunk's counts: passes by level and column, places. The
    flights: vacuum parabolas from x0 with v0 for dt s, or with `curve` (c, (n, 3) m/s^3) the cubics
    x0 + v0 t + g t^2 / 2 + c t^3 given as one Hermite segment each (`_segment_kernel`)."""
    t = types_for(precision)
    n = len(x0)
    if curve is None:
        watch, _lines, _hermite = _watch_kernel(precision, len(setup.places), setup.terrain is not None)
        inputs = [
            wp.array(x0, dtype=t.vec3, device="cpu"),
            wp.array(v0, dtype=t.vec3, device="cpu"),
            t.vec3(0.0, -G, 0.0),
            wp.array(np.asarray(dt, dtype=np.float64), dtype=t.scalar, device="cpu"),
        ]
    else:
        watch = _segment_kernel(precision, len(setup.places))
        h = np.asarray(dt, dtype=np.float64)[:, None]
        x1, v1 = _cubic(x0, v0, curve, h)
        g = np.array([0.0, -G, 0.0])
        data = [x0, h * v0, h * h * np.broadcast_to(g, x0.shape), x1, h * v1, h * h * (g + 6.0 * curve * h)]
        inputs = [wp.array(a, dtype=t.vec3, device="cpu") for a in data] + [wp.array(h[:, 0], dtype=t.scalar, device="cpu")]
    tally = DeviceTally(setup, precision, wp.get_device("cpu"), active=True)
    tally.start(None)
    reach = wp.zeros((n, len(SPEEDS)), dtype=t.scalar, device="cpu")
    wp.launch(watch, dim=n, inputs=[tally.struct, *inputs], outputs=[reach], device="cpu")
    tally.resolve()
    passes = tally.counts["exposure"].numpy().reshape(setup.levels, setup.cells + 2).astype(np.int64)
    places = tally.counts["places"].numpy().reshape(setup.levels, len(setup.places)).astype(np.int64)
    return reach.numpy().astype(np.float64), passes, places


def _cubic(x0, v0, c, t):
    """Position and velocity at t of x0 + v0 t + g t^2 / 2 + c t^3 (g along -y)."""
    g = np.array([0.0, -G, 0.0])
    return x0 + v0 * t + 0.5 * g * t * t + c * t**3, v0 + g * t + 3.0 * c * t * t


@functools.cache
def _segment_kernel(precision, places):
    """A kernel watching one Hermite segment (x, h v, h^2 a at its ends; h s) a pellet, over the terrain."""
    t = types_for(precision)
    w = make_path_watch(precision, len(SPEEDS), places, True, True)

    @wp.kernel
    def watch_segments(
        tally: w.Tally,
        x0: wp.array(dtype=t.vec3),
        d0: wp.array(dtype=t.vec3),
        e0: wp.array(dtype=t.vec3),
        x1: wp.array(dtype=t.vec3),
        d1: wp.array(dtype=t.vec3),
        e1: wp.array(dtype=t.vec3),
        h: wp.array(dtype=t.scalar),
        reach_out: wp.array2d(dtype=t.scalar),
    ):
        i = wp.tid()
        track = w.start()
        track = w.segment(track, tally, x0[i], d0[i], e0[i], x1[i], d1[i], e1[i], h[i], t.scalar(1.0))
        w.write(track, reach_out, i)
        w.finish(track, tally, i)

    return watch_segments


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
@pytest.mark.parametrize("flight", ["parabola", "curve"])
def test_a_hill_and_a_berm_match_the_brute_force_sampler(precision, flight):
    """(c) A hill, a berm and a nodata hole: every reach within CLOSE of the path length of the
    sampler's, every cell of the passes and exposure maps within the sampler's bounds (equal but
    for passes it flags within a rounding of an edge, of body height or of a threshold), and the
    named places' counts the sampler's. Vacuum parabolas, and cubics bent along and across the line
    of fire given as one Hermite segment each (as an integration step's interpolant: their grid
    coordinates, not linear in time, cross the triangles' edges at the quintic's roots)."""
    grid = _grid(_hill, hole=True)
    vertices, triangles = _mesh(grid)
    terrain = TerrainHeight(vertices, triangles, (0.0, 0.0, 0.0), UP)
    rng = np.random.default_rng(28)
    n = 24
    x0, v0, dt = _flights(rng, n, terrain)
    curve = None
    if flight == "curve":  # slowing down by up to a quarter of the speed along x, bent by up to 5 m/s^3 across
        curve = np.column_stack(
            [-rng.uniform(0.0, 0.08, n) * v0[:, 0] / dt**2, rng.uniform(-3.0, 3.0, n), rng.uniform(-5.0, 5.0, n)]
        )
    setup = _setup(grid)
    reach, passes, places = _watch(precision, setup, x0, v0, dt, curve)
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
        if curve is not None:
            path = ph.Path([(0.0, float(dt[i]), lambda t, i=i: tuple(a.T for a in _cubic(x0[i], v0[i], curve[i], t[:, None])))])
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


def test_the_grid_read_from_a_raster_is_its_placed_mesh():
    """The trap field's raster, placed at its station: the watch's grid holds every mesh vertex (an
    affine grid to 1e-9 m, heights (v - point).up), and its height between vertices is the
    sampler's triangle's (`reference.terrain`, another implementation) to 1e-9 m."""
    from warp_ricochet.model import terrain_triangles
    from warp_ricochet.scene import scene_from_dict
    from warp_ricochet.tallies.terrain_ground import terrain_grid

    raw = {
        "shot": {"count": 1, "diameter": 0.0024, "density": 11340.0, "speed": 100.0, "direction": [1.0, 0.0, 0.0]},
        "surfaces": [
            {
                "kind": "terrain",
                "file": str(TRAP_FIELD),
                "origin": [500_010.0, 4_200_050.0],
                "elevation": 119.8,
                "material": "turf",
            }
        ],
        "hazard": {"speed": {"fast": 50.0}},
    }
    scene = scene_from_dict(raw)
    mesh = terrain_triangles(scene, 0)
    grid = terrain_grid(scene.surfaces[0], mesh.vertices, (0.0, 0.0, 0.0), UP)
    assert grid.deviation <= 1e-9 and grid.z.shape == (21, 61)
    np.testing.assert_allclose(np.sort(grid.z[np.isfinite(grid.z)]), np.sort(mesh.vertices[:, 1]), rtol=0, atol=1e-12)
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.uniform(-20.0, 300.0, 2000), np.zeros(2000), rng.uniform(-60.0, 60.0, 2000)])
    want = TerrainHeight(mesh.vertices, mesh.triangles, (0.0, 0.0, 0.0), UP)(x)
    np.testing.assert_allclose(grid.height(x), want, rtol=0, atol=1e-9)
    assert (want != 0.0).sum() > 1000 and (want == 0.0).sum() > 100  # (on the raster and off it)


def _flat_raster(path):
    """A GeoTIFF of a level plane at 10 m: 300 m x 80 m of 5 m cells, its north-west corner at (0, 80)."""
    from test_terrain import write_tif

    return write_tif(path, np.full((17, 61), 10.0), 0.0, 80.0, 5.0)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_run_over_a_flat_raster_is_watched_as_over_its_plane(tmp_path, monkeypatch, precision):
    """A shot in air followed to rest (flights, bounces, slides and rolls on the triangles) over a
    raster of a level plane, watched over the raster's triangles and, the same run, over the plane
    itself (the plane code, `RunSpec.terrain_ground` off): the same reach per pellet to 1e-9 of the
    path (float32: 1e-5), the same exposure maps and places. (Against a run on the analytic plane
    the paths themselves differ: the triangles' contacts move a sliding pellet's speed by ~1e-4.)"""
    import dataclasses

    import h5py

    import warp_ricochet as wr
    from warp_ricochet import spec
    from warp_ricochet.scene import scene_from_dict

    pytest.importorskip("rasterio", reason="the gis extra (rasterio) is not installed")
    raster = str(_flat_raster(tmp_path / "flat.tif"))
    ground = {"restitution": 0.3, "mu_s": 0.5, "mu_d": 0.45, "rolling_resistance": 0.3}
    raw = {
        "shot": {
            "count": 60,
            "diameter": 0.0024,
            "density": 11340.0,
            "speed": 150.0,
            "direction": [1.0, -0.02, 0.0],
            "direction_jitter": [0.0, 0.05, 0.05],
            "envelope_center": [0.0, 1.5, 0.0],
            "seed": 5,
        },
        "surfaces": [
            {"kind": "terrain", "file": raster, "origin": [0.0, 40.0], "elevation": 10.0, "point": [-10.0, 0.0, 0.0], **ground}
        ],
        "physics": {"until": "rest", "bounces": 3, "impact_duration": 1e-5},
        "air": {},
        "hazard": {
            "speed": {"fast": 100.0, "slow": 20.0},
            "map_cell": 1.0,
            "map_extent": [-5.0, 250.0, -30.0, 30.0],
            "shooter": [0.0, 0.0, 0.0],
            "points": [{"name": "p", "position": [60.0, 0.0, 0.0], "area": 20.0}],
        },
        "numerics": {"precision": precision},
        "output": {"fields": ["hazard", "rest"]},
    }
    names = ("pellets/hazard/reach", "hazard/map/exposure", "hazard/map/exposure_outside", "hazard/points/pellets")
    out = {}
    of = spec.RunSpec.of.__func__

    def plane_watch(cls, scene, **kw):
        return dataclasses.replace(of(cls, scene, **kw), terrain_ground=False)

    for name in ("terrain", "plane"):
        if name == "plane":
            monkeypatch.setattr(spec.RunSpec, "of", classmethod(plane_watch))
        wr.run(scene_from_dict(raw), tmp_path / f"{name}.h5", device="cpu")
        with h5py.File(tmp_path / f"{name}.h5") as f:
            out[name] = {k: f[k][()] for k in (*names, "pellets/rest/position")}
    got, want = out["terrain"], out["plane"]
    np.testing.assert_array_equal(got["pellets/rest/position"], want["pellets/rest/position"])  # (the same paths)
    assert np.abs(want["pellets/rest/position"][:, 0]).max() < 280.0  # (all at rest on the raster)
    reach = want["pellets/hazard/reach"]
    assert np.isfinite(reach).sum() > 200  # (every pellet within body height above most thresholds)
    close = (1e-9 if precision == "float64" else 1e-5) * 250.0
    np.testing.assert_allclose(got["pellets/hazard/reach"], reach, rtol=0, atol=close)
    for name in names[1:]:
        np.testing.assert_array_equal(got[name], want[name])
    assert want["hazard/map/exposure"].sum() > 5000 and want["hazard/points/pellets"].sum() > 20


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_rolling_stretch_is_judged_over_the_terrain_below_it(precision):
    """A straight stretch of rolling with ploughing (`line`) 2.5 m above the base plane: over a
    raster 1 m high it is within body height (1.5 m above the ground) and reaches where its speed
    falls to each threshold; over the base plane alone (2.5 m > 1.8 m) it reaches nowhere."""
    t = types_for(precision)
    a, b = 0.35, 0.02  # m/s^2, 1/m: v' = -(a + b v^2) along the line
    x0 = np.array([[5.0, 2.5, 0.0]])
    v0 = np.array([120.0])
    reach = {}
    for name, grid in (("raised", _grid(lambda x, z: 1.0 + 0.0 * x * z)), ("base", None)):
        setup = _setup(grid, places=())
        _parabolas, lines, _hermite = _watch_kernel(precision, 0, grid is not None)
        tally = DeviceTally(setup, precision, wp.get_device("cpu"), active=True)
        tally.start(None)
        out = wp.zeros((1, len(SPEEDS)), dtype=t.scalar, device="cpu")
        inputs = [wp.array(x0, dtype=t.vec3, device="cpu"), t.vec3(1.0, 0.0, 0.0), wp.array([40.0], dtype=t.scalar, device="cpu")]
        inputs += [wp.array(v0, dtype=t.scalar, device="cpu"), t.scalar(a), t.scalar(b)]
        wp.launch(lines, dim=1, inputs=[tally.struct, *inputs], outputs=[out], device="cpu")
        reach[name] = out.numpy()[0].astype(np.float64)
    assert np.isnan(reach["base"]).all()
    for k, s in enumerate(SPEEDS):
        d = min(math.log((a + b * 120.0**2) / (a + b * s * s)) / (2 * b), 40.0)
        assert reach["raised"][k] == pytest.approx(5.0 + d, rel=1e-5 if precision == "float32" else 1e-12)
