"""Pellets followed to rest on triangles (`physics.until = "rest"`, docs/geometry.md "Rest on
triangles"): meshes, boxes and terrain give the rest positions of the planes they lie on, a pellet
rolls over a box's edge onto the ground, and none ends inside a box or below a terrain."""

from pathlib import Path

import numpy as np
import pytest
from helpers import paper_raw

from warp_ricochet.scene import scene_from_dict

trimesh = pytest.importorskip("trimesh")

R = 0.00125  # m, the paper's pellet
GROUND = paper_raw()["surfaces"][0]  # the paper's plane y = 0 (y up), rolling resistance 0.05
SLOW = {"speed": 30.0, "count": 40}  # the paper's shot at 30 m/s: 45 to 63 m along the ground


def _run(tmp_path, name, surfaces, shot=None, air=None, fields=("rest", "landing")):
    """{rest.position, rest.state, rest.path_length, landing.position, landing.velocity} of the
    paper's shot (float64, until rest) on `surfaces`."""
    import h5py

    import warp_ricochet as wr

    raw = paper_raw(until="rest")
    raw["shot"] |= shot or {"count": 30}
    raw["surfaces"] = surfaces
    raw["numerics"] = {"precision": "float64"}
    raw["output"] = {"fields": list(fields)}
    if air:
        raw["air"] = air
    wr.run(scene_from_dict(raw), tmp_path / f"{name}.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / f"{name}.h5") as f:
        return {f"{g}.{k}": f[f"pellets/{g}/{k}"][()] for g in ("rest", "landing") for k in f[f"pellets/{g}"]}


def _grid(path, half, cells, height=lambda x, z: 0.0 * x):
    """An STL of the square |x|, |z| <= half cut into cells x cells squares of two triangles each,
    at y = height(x, z), counter-clockwise seen from +y."""
    s = np.linspace(-half, half, cells + 1)
    x, z = np.meshgrid(s, s, indexing="ij")
    vertices = np.c_[x.ravel(), height(x, z).ravel(), z.ravel()]
    i, j = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
    a, b = (i * (cells + 1) + j).ravel(), ((i + 1) * (cells + 1) + j).ravel()
    faces = np.r_[np.c_[a, a + 1, b + 1], np.c_[a, b + 1, b]]
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    assert (mesh.face_normals[:, 1] > 0).all()
    mesh.export(path)
    return str(path)


def _same_rest(on_mesh, on_plane, tolerance=1e-6):
    """The rest states are the plane's and the positions within `tolerance` of the path."""
    np.testing.assert_array_equal(on_mesh["rest.state"], on_plane["rest.state"])
    stopped = on_plane["rest.state"] == 0
    error = np.linalg.norm(on_mesh["rest.position"] - on_plane["rest.position"], axis=1)[stopped]
    assert stopped.any() and (error <= tolerance * on_plane["rest.path_length"][stopped]).all(), error.max()


@pytest.mark.parametrize("air", [None, {"density": 1.225}], ids=["vacuum", "air"])
def test_a_two_triangle_mesh_of_the_papers_plane_rests_where_the_plane_does(tmp_path, air):
    """Issue 27: the paper's shot (411 m/s; its pellets roll 60 to 70 km in vacuum) followed to
    rest on two triangles of the paper's plane: the plane's rest positions within 1e-6 of the path."""
    mesh = {**GROUND, "kind": "mesh", "file": _grid(tmp_path / "two.stl", 2.0e5, 1)}
    shot = {"count": 20} if air is None else {"count": 8, "speed": 60.0}
    _same_rest(_run(tmp_path, "mesh", [mesh], shot, air), _run(tmp_path, "plane", [GROUND], shot, air))


def test_a_finely_triangulated_plane_rests_where_the_plane_does(tmp_path):
    """320,000 triangles of 0.5 m cells: each pellet crosses hundreds of their edges on its way
    (counted from its straight path) and rests where it does on the plane."""
    ground = {**GROUND, "rolling_resistance": 0.3}
    mesh = {**ground, "kind": "mesh", "file": _grid(tmp_path / "fine.stl", 100.0, 400)}
    on_mesh, on_plane = _run(tmp_path, "mesh", [mesh], SLOW), _run(tmp_path, "plane", [ground], SLOW)
    _same_rest(on_mesh, on_plane)
    start, end = on_plane["landing.position"][:, [0, 2]], on_plane["rest.position"][:, [0, 2]]
    lines = np.abs(np.floor(end / 0.5) - np.floor(start / 0.5)).sum(axis=1)  # grid lines crossed
    diagonals = np.abs(np.floor((end[:, 0] - end[:, 1]) / 0.5) - np.floor((start[:, 0] - start[:, 1]) / 0.5))
    assert (lines + diagonals > 150).all(), (lines + diagonals).min()


def _raster(path, slope_x, slope_y, bumps=0.0):
    """An ESRI ASCII grid of 0.5 m cells over x in [-5, 95], y in [-30, 30]: heights slope_x x +
    slope_y y (+ uniform noise of +-bumps m)."""
    cell, cols, rows = 0.5, 200, 120
    x = -5.0 + cell * (np.arange(cols) + 0.5)
    y = (-30.0 + cell * (np.arange(rows) + 0.5))[::-1]  # the first row the northernmost
    z = slope_x * x[None, :] + slope_y * y[:, None] + np.random.default_rng(5).uniform(-bumps, bumps, (rows, cols))
    header = f"ncols {cols}\nnrows {rows}\nxllcorner -5.0\nyllcorner -30.0\ncellsize {cell}\nNODATA_value -9999\n"
    path.write_text(header + "\n".join(" ".join(repr(float(h)) for h in row) for row in z) + "\n")
    return str(path)


def _terrain(tmp_path, slope_x, slope_y, bumps=0.0, **material):
    pytest.importorskip("rasterio")
    path = _raster(tmp_path / "ground.asc", slope_x, slope_y, bumps)
    return {**GROUND, "kind": "terrain", "file": path, "origin": [0.0, 0.0], "normal": [0.0, 1.0, 0.0], **material}


@pytest.mark.parametrize("slope", [0.02, 0.6], ids=["held", "too_steep"])
def test_a_tilted_raster_rests_where_its_analytic_plane_does(tmp_path, slope):
    """A terrain of the plane y = s x + 0.01 z (raster north is -z): the analytic plane's rest
    positions; on a slope steeper than the rolling resistance allows they roll back down and off
    the raster's edge (escaped), and on the plane none rests either."""
    terrain = _terrain(tmp_path, slope, -0.01, rolling_resistance=0.3)
    normal = np.array([-slope, 1.0, -0.01]) / np.linalg.norm([-slope, 1.0, -0.01])
    plane = {**GROUND, "rolling_resistance": 0.3, "normal": list(normal)}
    on_terrain, on_plane = _run(tmp_path, "terrain", [terrain], SLOW), _run(tmp_path, "plane", [plane], SLOW)
    if slope > 0.3:
        assert (on_plane["rest.state"] != 0).all() and (on_terrain["rest.state"] == 2).all()
    else:
        _same_rest(on_terrain, on_plane)


BOX = {"kind": "box", "point": [10.0, 0.5, 0.0], "normal": [0.0, 1.0, 0.0], "axis_u": [1.0, 0.0, 0.0]}


def _onto_box(tmp_path, name, top, extra=()):
    """Pellets dropped onto y = 1 between x = 8.6 and 9.4, moving on at 3 m/s along x."""
    from helpers import explicit_scene

    import warp_ricochet as wr

    n = 12
    rng = np.random.default_rng(2)
    x0 = np.c_[rng.uniform(8.6, 9.4, n), np.full(n, 1.3), rng.uniform(-1.0, 1.0, n)]
    v0 = np.c_[np.full(n, 3.0), np.full(n, -0.5), rng.uniform(-0.3, 0.3, n)]
    physics = {"gravity": [0.0, -9.81, 0.0], "until": "rest"}
    ground = {**GROUND, "rolling_resistance": 0.3}
    scene = explicit_scene(tmp_path, x0, v0, surfaces=[top, ground, *extra], physics=physics, name=f"{name}.npz")
    scene = scene_from_dict({**scene.to_dict(), "output": {"fields": ["rest"]}})
    wr.run(scene, tmp_path / f"{name}.h5", device="cpu", overwrite=True)
    import h5py

    with h5py.File(tmp_path / f"{name}.h5") as f:
        return {f"rest.{k}": f[f"pellets/rest/{k}"][()] for k in f["pellets/rest"]}


TOP = {"restitution": 0.1, "mu_s": 0.3, "mu_d": 0.27, "rolling_resistance": 0.1}


def test_pellets_rest_on_a_box_top_where_they_do_on_its_plane(tmp_path):
    """A box 20 m long, its top at y = 1: the rest positions on a plane y = 1."""
    box = _onto_box(tmp_path, "box", {**BOX, "size": [20.0, 10.0, 1.0], **TOP})
    plane = _onto_box(tmp_path, "plane", {"point": [0.0, 1.0, 0.0], "normal": [0.0, 1.0, 0.0], **TOP})
    assert (plane["rest.state"] == 0).all() and np.allclose(plane["rest.position"][:, 1], 1.0 + R)
    _same_rest(box, plane)


def test_a_pellet_rolling_off_a_box_lifts_off_and_rests_on_the_ground_beyond(tmp_path):
    """A box 4 m long (its top x in [8, 12]): the pellets roll off its edge at x = 12, fly and
    rest on the ground beyond it, none inside the box."""
    from bench.meshes import inside_box

    box = {**BOX, "size": [4.0, 10.0, 1.0], **TOP}
    end = _onto_box(tmp_path, "off", box)
    where = end["rest.position"]
    assert (end["rest.state"] == 0).all() and np.allclose(where[:, 1], R, atol=1e-9), where
    assert (where[:, 0] > 12.0 + R).all() and not inside_box(where, box | {"size": [4.0, 10.0, 1.0]}, -R).any()


def _surface_height(corners, points):
    """The height (y) of the triangles `corners` (m, 3, 3) over points (x, z): of the triangle whose
    projection on y = 0 holds each point (barycentric)."""
    out = np.full(len(points), np.nan)
    a, b, c = (corners[:, i][:, [0, 2]] for i in range(3))
    d = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    for i, p in enumerate(points):
        wb = ((p[0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (p[1] - a[:, 1])) / d
        wc = ((b[:, 0] - a[:, 0]) * (p[1] - a[:, 1]) - (p[0] - a[:, 0]) * (b[:, 1] - a[:, 1])) / d
        holds = np.flatnonzero((wb >= 0) & (wc >= 0) & (wb + wc <= 1))[0]
        out[i] = (
            (1 - wb[holds] - wc[holds]) * corners[holds, 0, 1]
            + wb[holds] * corners[holds, 1, 1]
            + wc[holds] * corners[holds, 2, 1]
        )
    return out


def test_no_pellet_rests_below_a_bumpy_terrain_nor_gains_energy(tmp_path):
    """A raster of 0.5 m cells with heights scattered by +-0.03 m (slopes to 0.12; its edges convex
    and concave, where pellets hop): the pellets that stay on it rest with their centres at least
    0.9 R above it, with potential energy no more than their energy at their landing."""
    from warp_ricochet.scene.terrain import place_terrain

    terrain = _terrain(tmp_path, 0.0, 0.0, bumps=0.03, rolling_resistance=0.3)
    end = _run(tmp_path, "bumpy", [terrain], {"speed": 20.0, "count": 40})
    stopped = end["rest.state"] == 0
    assert stopped.sum() >= 30 and (stopped | (end["rest.state"] == 2)).all(), end["rest.state"]
    end = {key: value[stopped] for key, value in end.items()}
    raw = paper_raw(until="rest")
    raw["surfaces"] = [terrain]
    vertices, triangles = place_terrain(scene_from_dict(raw), 0)
    where = end["rest.position"]
    height = where[:, 1] - _surface_height(vertices[triangles], where[:, [0, 2]])
    assert (height >= 0.9 * R).all(), height.min() / R  # (on a slope: R / cos; a crease: R cos)
    g = 9.81
    landing = 0.5 * (end["landing.velocity"] ** 2).sum(axis=1) + g * end["landing.position"][:, 1]
    assert (g * where[:, 1] <= landing).all()


@pytest.mark.filterwarnings("ignore:no pellet hit any surface")  # (they start on it, rolling)
def test_pellets_rolling_through_vertices_and_along_edges_rest_where_the_plane_rests_them(tmp_path):
    """Pellets rolling from a vertex of a grid of 0.5 m cells along its lines, its diagonals and
    through its vertices (directions (1, 0), (1, 1), (2, 1), (1, 2), ...): at each vertex the path
    goes on into the triangle ahead, not one it touches behind; the plane's rest positions."""
    import h5py
    from helpers import explicit_scene

    import warp_ricochet as wr

    angles = np.arctan2([0, 1, 1, 2, 1, -1, 3, 0], [1, 1, 2, 1, 0, 1, 1, -1])
    n = len(angles)
    x0 = np.c_[np.zeros(n), np.full(n, R), np.zeros(n)]
    v0 = 4.0 * np.c_[np.cos(angles), np.zeros(n), np.sin(angles)]
    w0 = np.cross([0.0, 1.0, 0.0], v0) / R  # rolling
    ground = {**GROUND, "rolling_resistance": 0.1}
    mesh = {**ground, "kind": "mesh", "file": _grid(tmp_path / "grid.stl", 20.0, 80)}
    ends = {}
    for name, surface in (("mesh", mesh), ("plane", ground)):
        scene = explicit_scene(tmp_path, x0, v0, w0, surfaces=[surface], physics={"until": "rest"}, name=f"{name}.npz")
        scene = scene_from_dict({**scene.to_dict(), "output": {"fields": ["rest"]}})
        wr.run(scene, tmp_path / f"{name}.h5", device="cpu", overwrite=True)
        with h5py.File(tmp_path / f"{name}.h5") as f:
            ends[name] = {f"rest.{k}": f[f"pellets/rest/{k}"][()] for k in f["pellets/rest"]}
    assert (ends["plane"]["rest.path_length"] > 8.0).all()
    _same_rest(ends["mesh"], ends["plane"])


def test_the_trap_field_followed_to_rest_ends_every_pellet(tmp_path):
    """The trap-field study's low shot (4 of 300, -3 to 3 deg, in air) to rest on the shipped
    terrain: every pellet ends at rest; some of them in the pocket where the ditch's V meets its
    west end (without the POCKET rule 5 of 1,200 crossed its faces until max_steps)."""
    import sys

    import h5py

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    from trap_field_study import scene as trap_scene

    import warp_ricochet as wr

    raw = trap_scene(4, (-3.0, 3.0)).to_dict()
    raw["physics"] = {**raw["physics"], "until": "rest"}
    raw["output"] = {"fields": ["rest"]}
    wr.run(scene_from_dict(raw), tmp_path / "trap.h5", device="cpu")
    with h5py.File(tmp_path / "trap.h5") as f:
        state, where = f["pellets/rest/state"][()], f["pellets/rest/position"][()]
    assert (state == 0).all(), np.flatnonzero(state)
    assert 0.1 < np.mean(where[:, 0] < 142.5) < 0.4  # short of the berm's crest
