"""Phases along a plane over the distance (`physics.surface_line`) in scenes that also hold plates,
meshes or posts: each step stays within their clearance less R (`free_of`) and a phase that comes
near one goes on in 3-D, where the contact is found (docs/ground.md 9).

A plate, a box or a post far from every path changes nothing; a wall met by a pellet rolling in air
is met where the same wall as an infinite plane (the line's exact distance to it) is met."""

import h5py
import numpy as np
import pytest
from helpers import explicit_scene

from warp_ricochet.api import run
from warp_ricochet.ends import AT_REST
from warp_ricochet.scene import scene_from_dict

R = 0.00125  # m
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.2, "mu_s": 0.4}
GROUND |= {"mu_d": 0.35, "rolling_resistance": 0.05}
AIR = {"density": 1.225}
PHYSICS = {"gravity": [0.0, 0.0, -9.81], "until": "rest", "rest_speed": 0.01, "bounces": 1}
FAR_POST = {"kind": "cylinder", "point": [3000.0, 40.0, 0.0], "normal": [0.0, 0.0, 1.0], "radius": 0.1, "length": 1.0}
FAR_PLATE = {"kind": "rectangle", "point": [-500.0, 0.0, 1.0], "normal": [1.0, 0.0, 0.0], "axis_u": [0.0, 1.0, 0.0]}
FAR_PLATE |= {"size": [2.0, 2.0]}
FAR_BOX = {"kind": "box", "point": [0.0, -800.0, 0.5], "normal": [0.0, 0.0, 1.0], "axis_u": [1.0, 0.0, 0.0]}
FAR_BOX |= {"size": [1.0, 1.0, 1.0]}
WALL_X = 6.0  # m: the wall's face down range


def _rest(tmp_path, name, x, v, surfaces, precision):
    """(rest state, rest position, steps a pellet) of pellets from x with v over `surfaces`, in air."""
    scene = explicit_scene(tmp_path, x, v, surfaces=surfaces, physics=PHYSICS, precision=precision, name=f"{name}.npz")
    scene = scene_from_dict({**scene.to_dict(), "air": AIR, "output": {"fields": ["rest"]}})
    stats = run(scene, tmp_path / f"{name}.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / f"{name}.h5") as f:
        return f["pellets/rest/state"][()], f["pellets/rest/position"][()], stats["rest_steps_mean"]


def _skims(count, seed):
    """Pellets launched low over the ground at 40-120 m/s, 1-4 degrees down, spread across y."""
    rng = np.random.default_rng(seed)
    speed, down = rng.uniform(40.0, 120.0, count), np.radians(rng.uniform(1.0, 4.0, count))
    side = rng.uniform(-0.05, 0.05, count)
    v = np.c_[speed * np.cos(down) * np.cos(side), speed * np.cos(down) * np.sin(side), -speed * np.sin(down)]
    x = np.c_[np.zeros(count), rng.uniform(-1.0, 1.0, count), np.full(count, 0.3)]
    return x, v


@pytest.mark.parametrize("far", ["post", "plate", "box"])
def test_a_solid_far_from_every_path_changes_no_rest(tmp_path, far):
    """The same rest positions and steps with a post, a plate or a box far from every path as without."""
    x, v = _skims(24, 5)
    solid = {"post": FAR_POST, "plate": FAR_PLATE, "box": FAR_BOX}[far] | {"restitution": 0.5, "mu_s": 0.3}
    state0, where0, steps0 = _rest(tmp_path, "plane", x, v, [GROUND], "float32")
    state1, where1, steps1 = _rest(tmp_path, far, x, v, [GROUND, solid], "float32")
    assert (state0 == AT_REST).all() and (state1 == AT_REST).all()
    assert steps1 == steps0
    np.testing.assert_array_equal(where1, where0)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_rolling_pellet_meets_a_wall_plate_where_it_meets_the_walls_plane(tmp_path, precision):
    """Pellets rolling in air towards a wall (restitution 0.5) rest, thrown back, where they rest when
    the wall is an infinite plane, to the integration's tolerance (1e-4 of the path)."""
    count = 8
    rng = np.random.default_rng(11)
    speed = rng.uniform(8.0, 20.0, count)
    x = np.c_[np.zeros(count), rng.uniform(-0.5, 0.5, count), np.full(count, R)]
    v = np.c_[speed, np.zeros(count), np.zeros(count)]
    w = np.c_[np.zeros(count), speed / R, np.zeros(count)]  # rolling: omega = n x v / R
    scene = explicit_scene(tmp_path, x, v, w, surfaces=[GROUND], physics=PHYSICS, precision=precision)
    wall = {"point": [WALL_X, 0.0, 1.0], "normal": [-1.0, 0.0, 0.0], "restitution": 0.5, "mu_s": 0.3}
    plate = wall | {"kind": "rectangle", "axis_u": [0.0, 1.0, 0.0], "size": [4.0, 2.0]}
    ends = {}
    for name, surfaces in (("plane", [GROUND, wall]), ("plate", [GROUND, plate])):
        raw = {**scene.to_dict(), "surfaces": surfaces, "air": AIR, "output": {"fields": ["rest", "impact"]}}
        stats = run(scene_from_dict(raw), tmp_path / f"{name}.h5", device="cpu", overwrite=True)
        with h5py.File(tmp_path / f"{name}.h5") as f:
            ends[name] = f["pellets/rest/state"][()], f["pellets/rest/position"][()], f["pellets/rest/path_length"][()]
        assert stats["rest_impacts_mean"] >= 1.0
    (s0, p0, l0), (s1, p1, l1) = ends["plane"], ends["plate"]
    assert (s0 == AT_REST).all() and (s1 == AT_REST).all()
    assert (p0[:, 0] < WALL_X - R).all()  # thrown back from the wall
    assert (np.linalg.norm(p1 - p0, axis=1) <= 1e-4 * l0).all(), np.linalg.norm(p1 - p0, axis=1) / l0
    np.testing.assert_allclose(l1, l0, rtol=1e-4)
