"""Contacts with a mesh's convex edges and corners (docs/geometry.md, "Meshes and boxes"; issue 27,
sections 3-4): which edges are kept, and the flight against a box's edges and corners beside an
independent float64 reference (the distance of the parabola from the box, sampled and root-found)."""

import numpy as np
import pytest
from helpers import explicit_scene, first_contacts
from scipy.optimize import brentq

from bench.meshes import AHEAD, BOX, GRAVITY, aimed, inside_box
from warp_ricochet.physics.mesh_edges import convex_features, covering_faces, inner_depths
from warp_ricochet.scene.triangles import box_triangles

MATERIAL = {"restitution": 0.5, "mu_s": 0.3}
RADIUS = 0.00125  # m: the pellets' (diameter 2.5 mm)


def test_a_box_keeps_its_12_edges_and_8_corners_and_a_flat_square_its_border():
    box = box_triangles(BOX["point"], BOX["normal"], BOX["axis_u"], BOX["size"])
    found = convex_features(box.vertices, box.triangles)
    assert len(found["edges"]) == 12 and len(found["corners"]) == 8
    lengths = np.sort(np.linalg.norm(found["edges"][:, 1] - found["edges"][:, 0], axis=1))
    np.testing.assert_allclose(lengths, np.repeat(np.sort(BOX["size"]), 4))  # no face diagonal
    for name, total in (("face_edges", 12), ("face_corners", 8)):  # each owned by one triangle
        owned = found[name][found[name] >= 0]
        assert len(owned) == total and len(np.unique(owned)) == total
    unmerged = convex_features(box.vertices[box.triangles].reshape(-1, 3), np.arange(36).reshape(-1, 3))
    assert len(unmerged["edges"]) == 12 and len(unmerged["corners"]) == 8  # an STL's copies are one point
    inverted = convex_features(box.vertices, box.triangles[:, ::-1])  # a room seen from inside: all concave
    assert len(inverted["edges"]) == 0 and len(inverted["corners"]) == 0
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    flat = convex_features(square, [[0, 1, 2], [0, 2, 3]])
    assert len(flat["edges"]) == 4 and len(flat["corners"]) == 4  # its border, not its diagonal
    ridge = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1e-3], [1.0, 1.0, 1e-3], [0.0, 2.0, 0.0], [1.0, 2.0, 0.0]])
    roof = [[0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4]]
    assert len(convex_features(ridge, roof)["edges"]) == 7  # the border's 6 and the ridge
    ridge[2:4, 2] = -1e-3
    assert len(convex_features(ridge, roof)["edges"]) == 6  # a valley: the border only


def test_every_face_of_a_convex_or_flat_mesh_covers_its_edges_and_a_valley_s_do_not():
    """`covering_faces`: a face covers the mesh's kept edges and corners where all lie on or behind
    its plane (a box's faces, a flat square's, a convex roof's); not a valley's. `inner_depths`: how
    deep the nearest of those that project inside a face lies (none for a box; a frustum's side
    edges pass just under its top)."""
    box = box_triangles(BOX["point"], BOX["normal"], BOX["axis_u"], BOX["size"])
    assert covering_faces(box.vertices, box.triangles, convex_features(box.vertices, box.triangles)["corners"]).all()
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    assert covering_faces(square, [[0, 1, 2], [0, 2, 3]], convex_features(square, [[0, 1, 2], [0, 2, 3]])["corners"]).all()
    ridge = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1e-3], [1.0, 1.0, 1e-3], [0.0, 2.0, 0.0], [1.0, 2.0, 0.0]])
    roof = [[0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4]]
    assert covering_faces(ridge, roof, convex_features(ridge, roof)["corners"]).all()
    ridge[2:4, 2] = -1e-3  # a valley: each side's border rises above the other side's plane
    assert not covering_faces(ridge, roof, convex_features(ridge, roof)["corners"]).any()
    found = convex_features(box.vertices, box.triangles)  # nothing projects inside a box's face
    assert np.isinf(inner_depths(box.vertices, box.triangles, found["edges"], found["corners"])).all()
    top = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    frustum = np.r_[top, 0.5 * top - [0.0, 0.0, 1.0]]  # its sides' edges pass under its top
    sides = [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6], [0, 4, 5], [0, 5, 1], [1, 5, 6], [1, 6, 2], [2, 6, 7], [2, 7, 3]]
    sides += [[3, 7, 4], [3, 4, 0]]
    found = convex_features(frustum, sides)
    depths = inner_depths(frustum, sides, found["edges"], found["corners"])
    assert covering_faces(frustum, sides, found["corners"]).all() and (depths[:2] < 1e-6).all()
    assert np.isinf(depths[2:4]).all() and (depths[4:] > 1.0).all()  # (the bottom: nothing under it)
    lifted = box.vertices.copy()
    lifted[0] += 1e-3 * np.asarray(BOX["normal"]) / np.linalg.norm(BOX["normal"])  # one corner pulled out
    cover = covering_faces(lifted, box.triangles, convex_features(lifted, box.triangles)["corners"])
    assert 0 < cover.sum() < len(cover)


def _frame():
    """The box's unit axes (rows u, v, n), half sides and centre, from its keys alone."""
    n = np.asarray(BOX["normal"], float)
    n /= np.linalg.norm(n)
    u = np.asarray(BOX["axis_u"], float)
    u -= u @ n * n
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(n, u), n]), 0.5 * np.asarray(BOX["size"], float), np.asarray(BOX["point"], float)


def _offset(x):
    """The vector from the box's nearest point to x (zero inside)."""
    axes, half, centre = _frame()
    local = (x - centre) @ axes.T
    return (local - np.clip(local, -half, half)) @ axes


def _reference(x0, v0, until=1.2 * AHEAD):
    """(time, centre, unit normal) where the centre first comes within R of the box before `until`
    (s), or None: sampled every R / 10 of the path, the first crossing found by Brent's method."""
    times = np.arange(0.0, until, 0.1 * RADIUS / (np.linalg.norm(v0) + abs(GRAVITY[2]) * until))
    path = x0 + np.outer(times, v0) + 0.5 * np.outer(times**2, GRAVITY)
    gap = np.linalg.norm(_offset(path), axis=1) - RADIUS
    if not (gap <= 0).any():
        return None
    j = int(np.argmax(gap <= 0))
    if j == 0:
        return 0.0, x0, _offset(x0) / np.linalg.norm(_offset(x0))

    def f(t):
        return np.linalg.norm(_offset(x0 + v0 * t + 0.5 * GRAVITY * t * t)) - RADIUS

    t = brentq(f, times[j - 1], times[j], xtol=1e-16, rtol=1e-15)
    x = x0 + v0 * t + 0.5 * GRAVITY * t * t
    return t, x, _offset(x) / np.linalg.norm(_offset(x))


def _near_features(rng, count, reach):
    """(x0, v0) of pellets whose straight paths pass closest, AHEAD s after launch, at `reach`
    (a fraction of R: (low, high)) from a random edge or corner of the box, in its outer wedge
    (beside every face), moving across the direction to it."""
    axes, half, centre = _frame()
    signs = rng.choice([-1.0, 1.0], size=(count, 3))
    free = rng.integers(0, 4, count)  # 0-2: an edge along that axis; 3: a corner
    on = signs * half
    wedge = signs * rng.uniform(0.2, 1.0, (count, 3))
    for axis in range(3):
        pick = free == axis
        on[pick, axis] = rng.uniform(-0.9, 0.9, pick.sum()) * half[axis]
        wedge[pick, axis] = 0.0
    w = wedge / np.linalg.norm(wedge, axis=1, keepdims=True)
    targets = centre + (on + RADIUS * rng.uniform(*reach, (count, 1)) * w) @ axes
    across = rng.normal(size=(count, 3))
    across -= (across * w).sum(axis=1, keepdims=True) * w
    v = rng.uniform(30.0, 300.0, (count, 1)) * (across / np.linalg.norm(across, axis=1, keepdims=True)) @ axes
    v -= GRAVITY * AHEAD  # the velocity across it at the target, as `aimed` flies it
    return aimed(targets, v), v


def _contacts(tmp_path, precision, x, v, solid=None, cover=True):
    """(time, normal) of each pellet's first contact with the box (or the surface `solid`), by the
    kernels (time < 0: none); `cover` False: every edge and corner searched, no face covering them."""
    from warp_ricochet.physics.geometry import MESHES

    solid = solid or {"kind": "box", **BOX, **MATERIAL}
    return first_contacts(tmp_path, precision, x, v, solid, MESHES, GRAVITY, cover)[:2]


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_paths_beside_a_box_edge_or_corner_meet_it_where_the_reference_does(tmp_path, precision):
    """Paths passing 0.2 R to 0.9 R from an edge or a corner, beside every face (where the faces'
    R-offsets leave a gap), meet it where the float64 reference does, with its radial normal;
    paths passing 1.05 R to 2 R from it meet nothing."""
    rng = np.random.default_rng(27)
    x, v = _near_features(rng, 400, (0.2, 0.9))
    far_x, far_v = _near_features(rng, 400, (1.05, 2.0))
    times, normals = _contacts(tmp_path, precision, np.r_[x, far_x], np.r_[v, far_v])
    want = [_reference(*pair) for pair in zip(x, v)]
    assert all(w is not None for w in want)
    tolerance = {"float64": (1e-9, 1e-6), "float32": (2e-5, 2e-2)}[precision]  # m, normal
    beside = 0
    for i, (_t, centre, n) in enumerate(want):
        assert times[i] >= 0, i
        got = x[i] + v[i] * times[i] + 0.5 * GRAVITY * times[i] ** 2
        assert np.linalg.norm(got - centre) <= tolerance[0], (i, got - centre)
        assert np.linalg.norm(normals[i] - n) <= tolerance[1], (i, normals[i], n)
        beside += np.abs(n @ _frame()[0].T).max() < 0.999  # a radial normal, not a face's
    assert beside > 100  # (the rest meet a face first: 148 of 400)
    assert all(_reference(*pair) is None for pair in zip(far_x, far_v))
    assert (times[len(x) :] < 0).all(), np.flatnonzero(times[len(x) :] >= 0)


def test_an_edge_impact_leaves_the_edge_and_never_gains_energy(tmp_path):
    """The pellets of the test above, flown with the impact law: each rebound moves away from the
    box's nearest point and the energy (translational and rotational) never rises."""
    import h5py

    from warp_ricochet.api import run

    x, v = _near_features(np.random.default_rng(28), 1000, (0.2, 0.9))
    physics = {"gravity": list(GRAVITY), "until": "landing", "bounces": 1}
    scene = explicit_scene(tmp_path, x, v, surfaces=[{"kind": "box", **BOX, **MATERIAL}], physics=physics)
    run(scene, tmp_path / "edges.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "edges.h5") as f:
        group = f["pellets/impact"]
        centre, before, after, spin = (
            group[name][()].reshape(len(x), 3) for name in ("position", "velocity_before", "velocity", "angular_velocity")
        )
    inertia = 0.4 * RADIUS**2  # I / m of a solid sphere
    assert ((after**2).sum(axis=1) + inertia * (spin**2).sum(axis=1) <= (before**2).sum(axis=1) * (1 + 1e-12)).all()
    out = _offset(centre)
    assert ((after * out).sum(axis=1) > 0).all()
    assert not inside_box(centre, BOX, 1e-9).any()


@pytest.mark.parametrize("jitter", [1e-5, 1e-4])
def test_pellets_aimed_near_a_box_edge_all_meet_it_in_float32(tmp_path, jitter):
    """`bench.meshes box` at a small size: launch positions moved by up to `jitter` of their
    coordinates, so that those aimed at an edge or a corner pass within a fraction of a millimetre
    of it; all meet the box and no centre is inside it (without the edges' contacts, of these
    100,000 at jitter 1e-4, some pass by)."""
    import io
    from contextlib import redirect_stdout

    from bench.meshes import box

    out = io.StringIO()
    with redirect_stdout(out):
        box(100_000, 100_000, "float32", "cpu", seed=29, jitter=jitter)
    assert "100,000 pellets, 100,000 meet it" in out.getvalue() and " 0 centres inside" in out.getvalue(), out.getvalue()


def test_in_thin_air_the_edges_are_met_where_the_vacuum_reference_meets_them(tmp_path):
    """The integrated flight (air of 1e-6 kg/m^3: its path within nanometres of the parabola)
    meets paths beside a box's edges and corners on its steps' interpolants where the float64
    vacuum reference does; none passes by."""
    import h5py

    from warp_ricochet.api import run
    from warp_ricochet.scene import scene_from_dict

    x, v = _near_features(np.random.default_rng(30), 200, (0.2, 0.9))
    physics = {"gravity": list(GRAVITY), "until": "landing", "bounces": 1}
    scene = explicit_scene(tmp_path, x, v, surfaces=[{"kind": "box", **BOX, **MATERIAL}], physics=physics)
    scene = scene_from_dict({**scene.to_dict(), "air": {"density": 1e-6}})
    assert scene.in_air
    run(scene, tmp_path / "air.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "air.h5") as f:
        surface = f["pellets/impact/surface"][()].reshape(len(x))
        centre = f["pellets/impact/position"][()].reshape(len(x), 3)
    assert (surface == 0).all()
    want = np.array([_reference(*pair)[1] for pair in zip(x, v)])
    assert np.abs(centre - want).max() <= 1e-6, np.abs(centre - want).max()


SLOPE = 0.5  # the valley's sides: z = SLOPE |y| (m), for |x| <= 1 and |y| <= 1


def _valley(path):
    """A V-shaped valley of 8 triangles (a 3 x 3 grid of vertices, normals up) as an STL: its floor
    along the x axis is a concave edge, its grid lines across the sides and the cells' diagonals
    flat ones, its centre a vertex where six triangles meet; only its border is kept."""
    import trimesh

    grid = np.array([[x, y, SLOPE * abs(y)] for y in (-1.0, 0.0, 1.0) for x in (-1.0, 0.0, 1.0)])
    cells = [(3 * row + col, 3 * row + col + 1, 3 * row + col + 4, 3 * row + col + 3) for row in range(2) for col in range(2)]
    faces = np.array([tri for a, b, c, d in cells for tri in ((a, b, c), (a, c, d))])
    assert len(convex_features(grid, faces)["edges"]) == 8  # the border's 8, not the floor
    trimesh.Trimesh(vertices=grid, faces=faces, process=False).export(path)
    return str(path)


SIDES = [np.array([0.0, s * SLOPE, 1.0]) / np.hypot(SLOPE, 1.0) for s in (1.0, -1.0)]  # unit normals, y < 0 first


def _valley_reference(x0, v0):
    """Each side's time (s) of the first contact with the valley, in float64: the room R above
    both sides is the intersection of two half-spaces (each side's plane through the floor, offset
    by R), so the centre leaves it at the first time either side's height comes down to R."""
    times = []
    for n in SIDES:
        c, b, a = n @ x0 - RADIUS, n @ v0, 0.5 * (n @ GRAVITY)  # height - R = c + b t + a t^2
        roots = np.roots([a, b, c])
        roots = roots[np.isreal(roots)].real
        times.append(roots[roots >= 0].min())
    return np.array(times)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_pellets_aimed_exactly_at_flat_and_concave_edges_meet_the_faces(tmp_path, precision):
    """400 pellets from above, aimed exactly at a valley's floor (a concave edge, not kept), at its
    centre vertex and at its flat interior edges (grid lines and diagonals, not kept): each meets
    the valley where the float64 reference does, with the normal of a face it touches, its centre
    then R above both sides' planes (no pass-through between the faces)."""
    rng = np.random.default_rng(44)
    u = rng.uniform(-0.8, 0.8, 400)
    targets = np.stack([u, np.zeros(400), np.zeros(400)], axis=1)  # the floor
    targets[100:150] = 0.0  # the centre vertex
    w = rng.uniform(0.05, 0.8, 100) * rng.choice([-1.0, 1.0], 100)
    targets[150:250] = np.stack([np.zeros(100), w, SLOPE * np.abs(w)], axis=1)  # the grid lines x = 0
    corner, along = rng.choice([-1.0, 0.0], (150, 2)), rng.uniform(0.05, 0.95, (150, 1))  # a cell's diagonal
    targets[250:] = np.c_[corner + along, SLOPE * np.abs(corner[:, 1:] + along)]
    down = np.c_[rng.normal(scale=0.5, size=(400, 2)), -np.ones(400)]
    v = rng.uniform(30.0, 300.0, (400, 1)) * down / np.linalg.norm(down, axis=1, keepdims=True) - GRAVITY * AHEAD
    x = aimed(targets, v)
    times, normals = _contacts(tmp_path, precision, x, v, {"kind": "mesh", "file": _valley(tmp_path / "valley.stl"), **MATERIAL})
    tolerance = {"float64": (1e-9, 1e-9), "float32": (2e-5, 1e-4)}[precision]  # m, normal
    for i in range(len(x)):
        sides = _valley_reference(x[i], v[i])
        want = sides.min()
        assert times[i] >= 0, i
        got = x[i] + v[i] * times[i] + 0.5 * GRAVITY * times[i] ** 2
        centre = x[i] + v[i] * want + 0.5 * GRAVITY * want**2
        assert np.linalg.norm(got - centre) <= tolerance[0], (i, got - centre)
        met = [j for j in range(2) if SIDES[j] @ got <= RADIUS + 1e-5]  # touched (the normal: the steeper's)
        assert min(np.linalg.norm(normals[i] - SIDES[j]) for j in met) <= tolerance[1], (i, normals[i], sides)
        assert min(side @ got for side in SIDES) >= RADIUS - tolerance[0], (i, [side @ got for side in SIDES])


def _square(path):
    """A flat 2 m square of two triangles, normal up, as an STL: its border kept, not its diagonal."""
    import trimesh

    square = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    trimesh.Trimesh(vertices=square, faces=[[0, 1, 2], [0, 2, 3]], process=False).export(path)
    return str(path)


def _at_border(rng, count, height):
    """(x0, v0) of pellets from all directions whose unhindered centres pass, AHEAD s after launch,
    within 1.2 R of the lines x, y = +-1 at `height(y)` (m) (a square's or the valley's border)."""
    targets = rng.uniform(-1.1, 1.1, (count, 3))
    side = rng.integers(0, 2, count)
    targets[np.arange(count), side] = rng.choice([-1.0, 1.0], count) * (1.0 + rng.uniform(-1.2, 1.2, count) * RADIUS)
    targets[:, 2] = height(targets[:, 1]) + rng.uniform(-1.2, 1.2, count) * RADIUS
    way = rng.normal(size=(count, 3))
    v = rng.uniform(30.0, 300.0, (count, 1)) * way / np.linalg.norm(way, axis=1, keepdims=True) - GRAVITY * AHEAD
    return aimed(targets, v), v


def _leaving_top(rng, count):
    """(x0, v0) of centres 0 to 0.3 R inside R of the box's top face, over it within 2 R of its
    edges and corners or beside them, leaving it (up to 30 m/s) and moving over or along its edges."""
    axes, half, centre = _frame()
    local = rng.uniform(-1.0, 1.0, (count, 3)) * half
    near = np.stack([rng.integers(0, 3, count) != j for j in (0, 1)], axis=1)  # by an edge or at a corner
    edge = np.sign(local[:, :2]) * (half[:2] + rng.uniform(-2.0, 0.5, (count, 2)) * RADIUS)
    local[:, :2] = np.where(near, edge, local[:, :2])
    local[:, 2] = half[2] + RADIUS * (1.0 - rng.uniform(0.0, 0.3, count))
    way = rng.normal(size=(count, 3))
    way[:, 2] = np.abs(way[:, 2]) * rng.uniform(0.01, 1.0, count)
    v = rng.uniform(1.0, 30.0, (count, 1)) * way / np.linalg.norm(way, axis=1, keepdims=True)
    return centre + local @ axes, v @ axes


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_edges_searched_only_before_the_covering_faces_give_the_same_contacts(tmp_path, precision):
    """A box's and a flat square's faces cover their edges and corners (`covering_faces`), so a
    small mesh's search looks for those only while the centre is within R of every face plane:
    the same contacts, to the bit, as searching them all, for paths from all sides near their
    edges and corners (within and beyond R) and at them, and paths leaving the box's top from
    within R of it near its edges; a valley's (not covered) too.
    In float32 a face met at an edge may be met an ulp later than the edge was."""
    from bench.meshes import box_shots

    rng = np.random.default_rng(55)
    near, beyond, shots = _near_features(rng, 300, (0.2, 0.9)), _near_features(rng, 300, (1.0, 1.2)), box_shots(rng, 400)
    at_box = np.r_[near[0], beyond[0], shots[0]], np.r_[near[1], beyond[1], shots[1]]
    square = {"kind": "mesh", "file": _square(tmp_path / "square.stl"), **MATERIAL}
    valley = {"kind": "mesh", "file": _valley(tmp_path / "valley.stl"), **MATERIAL}
    cases = [(None, at_box), (None, _leaving_top(rng, 600)), (square, _at_border(rng, 600, np.zeros_like))]
    cases.append((valley, _at_border(rng, 600, lambda y: SLOPE * np.abs(y))))
    for solid, (x, v) in cases:
        with_cover = _contacts(tmp_path, precision, x, v, solid)
        without = _contacts(tmp_path, precision, x, v, solid, cover=False)
        assert (with_cover[0] >= 0).sum() > len(x) // 6, solid  # (many meet it)
        same = with_cover[0] == without[0]  # float32: where a face is met at an edge, within an ulp
        assert same.mean() >= {"float64": 1.0, "float32": 0.99}[precision], np.flatnonzero(~same)
        np.testing.assert_allclose(with_cover[0], without[0], rtol=3e-7)
        np.testing.assert_array_equal(with_cover[1][same], without[1][same])
        np.testing.assert_allclose(with_cover[1], without[1], atol=2e-2)
