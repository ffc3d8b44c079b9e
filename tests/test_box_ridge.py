"""Pellets on a box's top edges and corners, followed to rest (issue 27; docs/geometry.md, "Rest on
triangles", "On an edge or a corner"): a pellet staying on an edge or a corner with its centre over
no face rolls off it to one side, as a sphere on a ridge, instead of hopping on the edge until its
impacts run out (NOT_FINISHED: pellet 63 of a lost hostile scene, float32)."""

import functools
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import explicit_scene
from scipy import stats

import warp_ricochet as wr
from bench.meshes import inside_box
from warp_ricochet.ends import AT_REST
from warp_ricochet.scene import scene_from_dict

R = 0.00125  # m: the pellets' radius
BOX = {"kind": "box", "point": [0.0, 0.5, 0.0], "normal": [0.0, 1.0, 0.0], "axis_u": [1.0, 0.0, 0.0]}
BOX |= {"size": [1.0, 1.0, 1.0]}  # its top y = 1, |x|, |z| <= 0.5
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.01, "mu_s": 0.5, "mu_d": 0.45}
GROUND |= {"rolling_resistance": 0.05}
SMOOTH = {"restitution": 0.3, "mu_s": 0.2, "mu_d": 0.18, "rolling_resistance": 0.02}  # no rough draws
TOLERANCE = {"float32": 2e-5, "float64": 1e-9}  # m: rest heights and sides, the coordinates' rounding


def _rest(folder, name, x0, v0, box, precision="float64", air=None, w0=None, **physics):
    """{state, position, impacts} at rest of pellets from x0, v0 (spin w0) over `box` on GROUND."""
    physics = {"gravity": [0.0, -9.81, 0.0], "until": "rest", **physics}
    scene = explicit_scene(folder, x0, v0, w0, surfaces=[box, GROUND], physics=physics, precision=precision, name=f"{name}.npz")
    raw = {**scene.to_dict(), "output": {"fields": ["rest"]}}
    if air:
        raw["air"] = {"density": 1.225}
    wr.run(scene_from_dict(raw), folder / f"{name}.h5", device="cpu", overwrite=True)
    with h5py.File(folder / f"{name}.h5") as f:
        return {key: f[f"pellets/rest/{key}"][()] for key in ("state", "position", "impacts")}


def _dropped(n, seed=27):
    """The rebuilt scene: n pellets dropped 1 mm to 0.3 m onto the box's top edges (half of them)
    and corners, within a few R of them, falling at up to 1 m/s and moving at about 0.1 m/s."""
    rng = np.random.default_rng(seed)
    along, side = rng.uniform(-0.5, 0.5, n), rng.integers(0, 4, n)
    edge_x = np.where(side < 2, np.where(side == 0, -0.5, 0.5), along)
    edge_z = np.where(side < 2, along, np.where(side == 2, -0.5, 0.5))
    corner = rng.integers(0, 2, n) == 1
    x = np.where(corner, rng.choice([-0.5, 0.5], n), edge_x) + rng.normal(0.0, 1.5 * R, n)
    z = np.where(corner, rng.choice([-0.5, 0.5], n), edge_z) + rng.normal(0.0, 1.5 * R, n)
    x0 = np.c_[x, 1.0 + R + rng.uniform(0.001, 0.3, n), z]
    v0 = np.c_[rng.normal(0.0, 0.1, n), -rng.uniform(0.0, 1.0, n), rng.normal(0.0, 0.1, n)]
    return x0, v0


@functools.cache
def _scene_rests(precision, air, n):
    """The rebuilt scene (a concrete box: rough, its coefficients scattered) at rest (cached per session)."""
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="box-ridge-"))
    x0, v0 = _dropped(n)
    return _rest(folder, "dropped", x0, v0, {**BOX, "material": "concrete"}, precision, {"density": 1.225} if air else None)


def _on_top_or_ground(where, precision):
    """Whether each centre lies R above the box's top over it, or R above the ground beside it."""
    tol = TOLERANCE[precision]
    over = (np.abs(where[:, [0, 2]]) <= 0.5 + tol).all(axis=1)
    on_top = over & (np.abs(where[:, 1] - (1.0 + R)) <= tol)
    beside = (np.abs(where[:, [0, 2]]) >= 0.5 + R - tol).any(axis=1)
    return on_top | (beside & (np.abs(where[:, 1] - R) <= tol))


@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_pellets_dropped_on_a_boxs_top_edges_and_corners_all_rest_on_its_top_or_the_ground(precision, air):
    """300 pellets of the rebuilt scene: every one at rest (before the ridge rule 14 of 3,000 in
    float32 and 10 in float64 hopped on an edge until max_impacts), on the top or the ground,
    none inside the box, none after more than a few impacts."""
    end = _scene_rests(precision, air, 300)
    where = end["position"]
    assert (end["state"] == AT_REST).all(), np.flatnonzero(end["state"] != AT_REST)
    assert _on_top_or_ground(where, precision).all(), where[~_on_top_or_ground(where, precision)]
    assert not inside_box(where, BOX, -R * (1.0 - 1e-3)).any()  # no sphere overlaps the box
    assert end["impacts"].max() <= 20
    assert 0.1 < np.mean(where[:, 1] > 0.5) < 0.5  # some rest on the top, most fall off it


def test_float32_rests_agree_with_float64_statistically():
    """The rebuilt scene's 300 pellets (vacuum): the share resting on the top and the distance of
    the rest positions from the box's vertical axis, float32 against float64 (the paths may part at
    the edges, so pellet by pellet only most agree)."""
    single, double = _scene_rests("float32", False, 300), _scene_rests("float64", False, 300)
    top32, top64 = single["position"][:, 1] > 0.5, double["position"][:, 1] > 0.5
    table = [[top32.sum(), (~top32).sum()], [top64.sum(), (~top64).sum()]]
    assert stats.fisher_exact(table).pvalue > 1e-3, table
    far32, far64 = (np.linalg.norm(end["position"][:, [0, 2]], axis=1) for end in (single, double))
    assert stats.ks_2samp(far32, far64, method="asymp").pvalue > 1e-3
    apart = np.linalg.norm(single["position"] - double["position"], axis=1)
    assert np.mean(apart < 1e-4) > 0.9  # most pellet by pellet too (measured: 97%)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_a_pellet_dropped_onto_an_edge_goes_to_the_side_its_centre_is_on(tmp_path, precision):
    """Pellets dropped 1 cm straight down with their centres 0.01 R to 0.9 R either side of the top
    edge x = 0.5 or beside a corner (a smooth box: no draws): those over the top rest where they
    fell; those beyond the edge, whose first contact is the edge itself, roll off it and rest on
    the ground beside the box's side, none on the edge."""
    rng = np.random.default_rng(3)
    n = 40
    offset = rng.choice([-1.0, 1.0], n) * rng.uniform(0.01, 0.9, n) * R
    z = np.where(np.arange(n) % 4 == 0, 0.5 - 0.3 * R, rng.uniform(-0.45, 0.45, n))  # every 4th by a corner
    x0 = np.c_[0.5 + offset, np.full(n, 1.01 + R), z]
    end = _rest(tmp_path, "edge", x0, np.zeros((n, 3)), {**BOX, **SMOOTH}, precision)
    where, tol = end["position"], TOLERANCE[precision]
    assert (end["state"] == AT_REST).all() and end["impacts"].max() <= 6, end["impacts"]
    top = offset < 0
    np.testing.assert_allclose(where[top], np.c_[x0[top, 0], np.full(top.sum(), 1.0 + R), z[top]], atol=tol)
    assert (np.abs(where[~top, 1] - R) <= tol).all() and (where[~top, 0] >= 0.5 + R - tol).all(), where[~top]


@pytest.mark.filterwarnings("ignore:no pellet hit any surface")  # (they start on it, rolling)
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_pellets_rolling_slowly_off_a_box_top_edge_rest_on_the_ground_beyond(tmp_path, precision):
    """Pellets rolling at 0.02 to 0.1 m/s (a rest speed of 0.01 m/s) towards the top edge x = 0.5:
    slower than sqrt(g R), they meet the edge as they leave the top; each rolls off it and rests on
    the ground beyond the side."""
    rng = np.random.default_rng(5)
    n = 24
    speed = rng.uniform(0.02, 0.1, n)
    heading = rng.uniform(-0.5, 0.5, n)  # rad from +x
    v0 = speed[:, None] * np.c_[np.cos(heading), np.zeros(n), np.sin(heading)]
    x0 = np.c_[np.full(n, 0.49), np.full(n, 1.0 + R), rng.uniform(-0.3, 0.3, n)]
    w0 = np.cross([0.0, 1.0, 0.0], v0) / R  # rolling
    box = {**BOX, **SMOOTH, "rolling_resistance": 0.001}
    end = _rest(tmp_path, "roll", x0, v0, box, precision, w0=w0, rest_speed=0.01)
    where, tol = end["position"], TOLERANCE[precision]
    assert (end["state"] == AT_REST).all(), end["state"]
    assert (np.abs(where[:, 1] - R) <= tol).all() and (where[:, 0] >= 0.5 + R - tol).all(), where


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_pellets_dropped_on_a_raised_squares_border_rest_on_it_or_the_ground(tmp_path, precision):
    """A one-sided square of two triangles at y = 1 (an open mesh: its border edges have one face
    each), 200 pellets dropped onto its border as onto the box's edges: those that roll off the
    border (gravity pulls them off its only face) pivot to level with it and fall; every one rests
    on the square or on the ground, after a few impacts (before the rule for a border,
    float64 pellets hopped on it up to 20 impacts, or until max_impacts)."""
    trimesh = pytest.importorskip("trimesh")
    square = np.array([[-0.5, 1.0, -0.5], [0.5, 1.0, -0.5], [0.5, 1.0, 0.5], [-0.5, 1.0, 0.5]])
    trimesh.Trimesh(vertices=square, faces=[[0, 2, 1], [0, 3, 2]], process=False).export(tmp_path / "square.stl")
    rng = np.random.default_rng(1)
    n = 200
    across, along = rng.choice([-0.5, 0.5], n) + rng.normal(0.0, 1.5 * R, n), rng.uniform(-0.5, 0.5, n)
    swap = rng.integers(0, 2, n) == 1
    x0 = np.c_[np.where(swap, along, across), 1.0 + R + rng.uniform(0.001, 0.3, n), np.where(swap, across, along)]
    v0 = np.c_[rng.normal(0.0, 0.1, n), -rng.uniform(0.0, 1.0, n), rng.normal(0.0, 0.1, n)]
    mesh = {"kind": "mesh", "file": str(tmp_path / "square.stl"), **SMOOTH}
    end = _rest(tmp_path, "square", x0, v0, mesh, precision)
    where, tol = end["position"], TOLERANCE[precision]
    on = (np.abs(where[:, [0, 2]]) <= 0.5 + tol).all(axis=1) & (np.abs(where[:, 1] - (1.0 + R)) <= tol)
    off = np.abs(where[:, 1] - R) <= tol  # (some roll on under the square)
    assert (end["state"] == AT_REST).all() and end["impacts"].max() <= 8, end["impacts"].max()
    assert (on | off).all() and 0.2 < on.mean() < 0.8, where[~(on | off)]
