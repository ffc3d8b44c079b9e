"""A flat mesh searched as its plane (docs/geometry.md, "Flat meshes"; issue 27, section 5): which
meshes are flat, and the same contacts as its triangles searched one by one (`geometry.FLAT`
against the general small-mesh search), in vacuum at the kernels' level and in air through a run."""

import numpy as np
import pytest
from helpers import first_contacts, make_scene

from bench.meshes import AHEAD, GRAVITY, aimed
from warp_ricochet.physics.geometry import FLAT
from warp_ricochet.physics.mesh_edges import flat_mesh

MATERIAL = {"restitution": 0.5, "mu_s": 0.3}
RADIUS = 0.00125  # m: the pellets' (diameter 2.5 mm)
# an L of six triangles (not convex: one border corner points inwards), in its own frame (m)
L_POINTS = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 2.0, 0.0]])
L_POINTS = np.r_[L_POINTS, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]
L_FACES = np.array([[0, 6, 3], [0, 3, 7], [6, 1, 2], [6, 2, 3], [7, 3, 4], [7, 4, 5]])


def _tilted(points, origin):
    """`points` turned about x by 0.3 rad and about z by 0.7 rad, then moved to `origin` (m)."""
    a, b = 0.3, 0.7
    rx = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    rz = np.array([[np.cos(b), -np.sin(b), 0.0], [np.sin(b), np.cos(b), 0.0], [0.0, 0.0, 1.0]])
    return points @ (rz @ rx).T + origin


def test_flat_meshes_are_told_from_bent_ones():
    """`flat_mesh`: a square, an L turned and moved 1 km away (float64), the same L rounded to float32
    as an STL holds it, yes; a box, a square bent by 1e-9 m, the float32 L bent by 1e-5 m, one with
    a triangle wound the other way or of no area, no."""
    from bench.meshes import BOX
    from warp_ricochet.scene.triangles import box_triangles

    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    assert flat_mesh(square, [[0, 1, 2], [0, 2, 3]])
    turned = _tilted(L_POINTS, [1000.0, -300.0, 20.0])
    assert flat_mesh(turned, L_FACES)
    single = _tilted(L_POINTS, [3.0, 0.5, -1.0]).astype(np.float32).astype(np.float64)
    assert flat_mesh(single, L_FACES)
    bent = single.copy()
    bent[4] += 1e-5 * np.cross(single[1] - single[0], single[5] - single[0]) / 2.0
    assert not flat_mesh(bent, L_FACES)
    box = box_triangles(BOX["point"], BOX["normal"], BOX["axis_u"], BOX["size"])
    assert not flat_mesh(box.vertices, box.triangles)
    bent = square.copy()
    bent[2, 2] = 1e-9
    assert not flat_mesh(bent, [[0, 1, 2], [0, 2, 3]])
    assert not flat_mesh(square, [[0, 1, 2], [0, 3, 2]])  # wound the other way
    assert not flat_mesh(np.r_[square, [[2.0, 0.0, 0.0]]], [[0, 1, 2], [0, 2, 3], [0, 1, 4]])  # no area
    assert not flat_mesh(square, np.zeros((0, 3), int))


def test_a_flat_mesh_s_edge_lines_give_each_triangle_s_edge_distances():
    """`flat_edges`: w.(y - origin) - offset equals the edge function n.((q - p) x (y - p)) / |q - p|
    of every edge of every triangle (float64, random points of the plane), positive inside; the
    slack covers the float32 vertices' distance from the plane."""
    from warp_ricochet.physics.mesh_edges import flat_edges, flat_plane

    points = _tilted(L_POINTS, [30.0, -5.0, 12.0]).astype(np.float32).astype(np.float64)
    plane = flat_plane(points, L_FACES)
    origin = 0.5 * (points.min(axis=0) + points.max(axis=0))
    w, offsets, slack = flat_edges(points, L_FACES, plane, origin)
    a, n = plane
    rng = np.random.default_rng(5)
    y = rng.uniform(points.min(axis=0) - 1.0, points.max(axis=0) + 1.0, (200, 3))
    y -= ((y - a) @ n)[:, None] * n
    for f, face in enumerate(L_FACES):
        for j in range(3):
            p, q = points[face[j]], points[face[(j + 1) % 3]]
            want = np.cross(q - p, y - p) @ n / np.linalg.norm(q - p)
            np.testing.assert_allclose((y - origin) @ w[f, j] - offsets[f, j], want, atol=1e-9)
        centre = points[face].mean(axis=0)
        assert ((centre - origin) @ w[f].T - offsets[f] > 0).all()  # (inside every edge)
    assert slack >= np.abs((points - a) @ n).max() > 0


def _mesh(path, points):
    """The L of `points` as an STL; its scene surface."""
    import trimesh

    trimesh.Trimesh(vertices=points, faces=L_FACES, process=False).export(path)
    return {"kind": "mesh", "file": str(path), **MATERIAL}


def _shots(rng, points, count):
    """(x0, v0): pellets from all directions (both sides) whose unhindered centres pass, AHEAD s after
    launch, within 1.2 R of the L's plane at its vertices, on its border and inner edges, or
    anywhere over its box."""
    n = np.cross(points[1] - points[0], points[5] - points[0])
    n /= np.linalg.norm(n)
    ends = points[np.r_[L_FACES[:, [0, 1]], L_FACES[:, [1, 2]], L_FACES[:, [2, 0]]]]  # every edge
    pick = rng.integers(0, len(ends), count)
    along = rng.uniform(0.0, 1.0, (count, 1))
    targets = ends[pick, 0] + along * (ends[pick, 1] - ends[pick, 0])
    at_vertex = rng.uniform(size=count) < 0.2
    targets[at_vertex] = points[rng.integers(0, len(points), at_vertex.sum())]
    anywhere = rng.uniform(size=count) < 0.3
    low, high = points.min(axis=0), points.max(axis=0)
    targets[anywhere] = rng.uniform(low, high, (anywhere.sum(), 3))
    targets[anywhere] -= ((targets[anywhere] - points[0]) @ n)[:, None] * n  # onto its plane
    targets += (rng.uniform(-1.2, 1.2, count) * RADIUS)[:, None] * n
    targets += rng.normal(scale=RADIUS, size=(count, 3)) * (rng.uniform(size=count) < 0.5)[:, None]
    way = rng.normal(size=(count, 3))
    v = rng.uniform(30.0, 300.0, (count, 1)) * way / np.linalg.norm(way, axis=1, keepdims=True) - GRAVITY * AHEAD
    return aimed(targets, v), v


def _contacts(tmp_path, precision, solid, x, v, flat, device):
    """(time, normal) of each pellet's first contact with `solid`, by a kernel on `device` compiled
    with the flat search (`flat`) or the triangles one by one (time < 0: none)."""
    from warp_ricochet.physics.geometry import MESHES, NO_POSTS, SMALL

    plates = MESHES | NO_POSTS | SMALL | (FLAT if flat else 0)
    times, normals, model = first_contacts(tmp_path, precision, x, v, solid, plates, GRAVITY, device=device)
    assert np.linalg.norm(model.surfaces.flat_normal.numpy()[0]) > 0.5  # (the host found it flat)
    return times, normals


@pytest.mark.parametrize(
    ("precision", "origin"), [("float64", (0.0, 0.0, 0.0)), ("float64", (90.0, 4.0, -70.0)), ("float32", (0.0, 0.0, 0.0))]
)
def test_a_flat_mesh_is_met_where_its_triangles_are(tmp_path, precision, origin, device):
    """An L of six triangles, turned and moved (an STL: float32 vertices, off its first triangle's
    plane by their rounding): pellets from both sides at its vertices, on its border and inner edges
    (within 1.2 R of its plane) and over it meet it as its triangles searched one by one: the same
    pellets (but for 0.5% at most, a rounding from its border) at the same times, within the time
    the vertices' rounding takes to cross at the speed along the normal, with the same normals
    (its plane's, or radial from a border edge or corner) within the tilt of its faces' own normals
    from that rounding."""
    points = _tilted(L_POINTS, origin)
    solid = _mesh(tmp_path / "l.stl", points)
    x, v = _shots(np.random.default_rng(27), points, 1500)
    flat = _contacts(tmp_path, precision, solid, x, v, True, device)
    each = _contacts(tmp_path, precision, solid, x, v, False, device)
    met = each[0] >= 0
    assert met.sum() > 600 and (~met).sum() > 50  # (most meet it; some pass by its border)
    both = met & (flat[0] >= 0)
    assert ((flat[0] >= 0) != met).mean() <= 0.005
    n = np.cross(points[1] - points[0], points[5] - points[0])
    n /= np.linalg.norm(n)
    off = 2.0**-23 * 3.0 * (np.abs(points).sum(axis=1).max() + 3.0)  # (m) `flat_mesh`'s FLAT_SINGLE
    if precision == "float32":
        off += 2.0**-22 * (np.abs(x).sum(axis=1).max() + 3.0)  # (the flight's own rounding)
    speed = np.abs(v @ n)[both]
    gap = np.abs(flat[0][both] - each[0][both])
    assert (gap <= off / np.maximum(speed - 10.0, 1.0) + 1e-9 * each[0][both]).all(), gap.max()
    tilt = 2.0**-21 * (np.abs(points).sum(axis=1).max() + 3.0)  # (the faces' normals from float32 vertices, 1 m edges)
    np.testing.assert_allclose(flat[1][both], each[1][both], atol={"float64": tilt, "float32": 2e-2}[precision])


@pytest.mark.parametrize("air", [False, True])
def test_a_run_over_a_flat_mesh_lands_where_its_triangles_send_it(tmp_path, monkeypatch, air, device):
    """A run (float64, three bounces, to the landing) off the turned L (an STL) over a ground plane,
    in vacuum and in sea-level air: the same impacts and landings with the flat search as with the
    L's triangles one by one (`spec` told the L is not flat), but for the vertices' float32
    rounding: 99% of the pellets within 1e-5 relative, the others where that rounding decides an
    edge's contact."""
    import h5py

    import warp_ricochet as wr
    from warp_ricochet.physics import mesh_edges
    from warp_ricochet.spec import RunSpec

    points = _tilted(L_POINTS, (3.0, 0.5, -1.0))
    x, v = _shots(np.random.default_rng(28), points, 400)
    np.savez(tmp_path / "pellets.npz", position=x, velocity=v)
    ground = {"point": [0.0, -2.0, 0.0], "normal": [0.0, 1.0, 0.0], **MATERIAL}
    raw = {
        "shot": {"file": str(tmp_path / "pellets.npz"), "diameter": 2 * RADIUS, "density": 7000.0},
        "surfaces": [_mesh(tmp_path / "l.stl", points), ground],
        "physics": {"bounces": 3, "until": "landing"},
        "output": {"fields": ["impact", "landing"]},
    }
    if air:
        raw["air"] = {}
    scene = make_scene(raw, precision="float64")
    outputs = {}
    for label in ("flat", "each"):
        if label == "each":
            monkeypatch.setattr(mesh_edges, "flat_mesh", lambda *_: False)
        assert bool(RunSpec.of(scene).plates & FLAT) == (label == "flat")
        path = tmp_path / f"{label}.h5"
        wr.run(scene, path, device=device)
        with h5py.File(path) as f:
            group = f["pellets"]
            outputs[label] = {k: group[k][()] for k in ("impact/position", "landing/position")}
    for key, got in outputs["flat"].items():
        want = outputs["each"][key]
        close = np.isclose(got, want, rtol=1e-5, atol=1e-6) | (np.isnan(got) & np.isnan(want))
        assert close.reshape(len(x), -1).all(axis=1).mean() >= 0.99, key
    assert np.isfinite(outputs["flat"]["landing/position"]).all(axis=1).sum() > 100
