"""Posts followed to rest (`physics.until = "rest"`, docs/geometry.md "Posts (cylinders)").

A pellet dropped onto a post's top cap slides, rolls and rests on it, or rolls off its rim and rests
on the ground beyond, where docs/ground.md's closed forms in vacuum put it; shots fired at a post
all end, none inside it, the pellets it hits resting on the ground on the side it threw them to,
with the same first impact and landing as when followed until landing only."""

import math

import h5py
import numpy as np
import pytest
from helpers import explicit_scene

from warp_ricochet.api import run
from warp_ricochet.core.rest import LIFT_OFF
from warp_ricochet.ends import AT_REST, NOT_FINISHED
from warp_ricochet.scene import scene_from_dict

R = 0.00125  # m, the pellets' radius (diameter 2.5 mm)
G = 9.81
K = 0.4  # I = K m R^2, a solid sphere
REST_SPEED = 0.01  # m/s
R_POST, L_POST = 0.1, 1.0  # m, the post's radius and length
CAP = {"restitution": 0.0, "mu_s": 0.3, "mu_d": 0.27, "rolling_resistance": 0.1}
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.0, "mu_s": 0.5, "mu_d": 0.45}
GROUND_C = 0.2  # the ground's rolling resistance
POST = {"kind": "cylinder", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "radius": R_POST, "length": L_POST}
PHYSICS = {"gravity": [0.0, 0.0, -G], "until": "rest", "rest_speed": REST_SPEED, "bounces": 1}


def _run(tmp_path, name, x, v, surfaces, precision="float64", physics=PHYSICS, fields=("rest", "impact", "landing")):
    """The per-pellet outputs {group.field: array} of pellets from x with v."""
    scene = explicit_scene(tmp_path, x, v, surfaces=surfaces, physics=physics, precision=precision, name=f"{name}.npz")
    scene = scene_from_dict({**scene.to_dict(), "output": {"fields": list(fields)}})
    run(scene, tmp_path / f"{name}.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / f"{name}.h5") as f:
        return {
            f"{g}.{k}": f[f"pellets/{g}/{k}"][()]
            for g in ("rest", "impact", "landing")
            if g in f["pellets"]
            for k in f[f"pellets/{g}"]
        }


def _on_level(x, v, w, mu_d, c):
    """docs/ground.md 6 on a level plane (normal +z) in vacuum from centre x, velocity v, spin w:
    sliding (the slip s = v - R w x n decays at (1 + 1/K) mu_d g along a fixed line, v at mu_d g)
    then rolling at (c g / (1 + K)) to REST_SPEED. Returns the points where sliding ends and where
    it rests, and the rolling speed (m/s) after sliding."""
    n = np.array([0.0, 0.0, 1.0])
    slip = v - R * np.cross(w, n)
    s = np.linalg.norm(slip)
    t1 = s / ((1.0 + 1.0 / K) * mu_d * G)
    along = slip / s if s > 0 else np.zeros(3)
    x1 = x + v * t1 - 0.5 * mu_d * G * t1 * t1 * along
    v1 = v - mu_d * G * t1 * along
    speed = np.linalg.norm(v1)
    x2 = x1 + v1 / speed * (speed**2 - REST_SPEED**2) / (2.0 * c * G / (1.0 + K))
    return x1, x2, speed, v1 / speed


def _drops(tmp_path, speeds, precision):
    """Pellets dropped 1 mm onto the middle of the top cap, moving along x at `speeds`."""
    x0 = np.c_[np.zeros(len(speeds)), np.zeros(len(speeds)), np.full(len(speeds), L_POST + R + 1e-3)]
    v0 = np.c_[speeds, np.zeros(len(speeds)), np.zeros(len(speeds))]
    surfaces = [POST | CAP, GROUND | {"rolling_resistance": GROUND_C}]
    return _run(tmp_path, f"drop-{precision}", x0, v0, surfaces, precision)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_pellet_dropped_on_a_cap_rests_on_it_or_rolls_off_its_rim_where_the_closed_forms_say(tmp_path, precision):
    """Slow pellets slide, roll and rest on the cap (centre R above it); fast ones roll over its rim,
    fly down the post's length L (lifting off its rim with core.rest's LIFT_OFF) and, rolling on the
    ground (restitution 0, no slip: no friction impulse), rest at r + u t + (u^2 - v_rest^2) / (2 (5/7)
    c g) from the axis, t the fall's time."""
    speeds = np.array([0.06, 0.12, 0.2, 0.6, 0.75, 0.9])
    out = _drops(tmp_path, speeds, precision)
    tolerance = 1e-12 if precision == "float64" else 1e-6
    assert (out["rest.state"] == AT_REST).all(), out["rest.state"]
    assert (out["impact.surface"][:, 0] == 0).all()  # the first impact: on the post's cap
    assert (out["rest.position"][:, 2] > L_POST).sum() == 3  # 3 rest on the cap, 3 on the ground
    for i in range(len(speeds)):
        x, v, w = out["impact.position"][i, 0], out["impact.velocity"][i, 0], out["impact.angular_velocity"][i, 0]
        assert abs(v[2]) <= tolerance and x[2] == pytest.approx(L_POST + R, abs=tolerance)
        rolls_from, on_cap, speed, direction = _on_level(x, v, w, CAP["mu_d"], CAP["rolling_resistance"])
        at = out["rest.position"][i]
        if np.hypot(on_cap[0], on_cap[1]) <= R_POST:  # it rests on the cap
            np.testing.assert_allclose(at, on_cap, atol=tolerance)
            continue
        assert speeds[i] > 0.5 and rolls_from[0] < R_POST  # rolling before it reaches the rim
        rim = (R_POST - rolls_from[0]) / direction[0]  # along its line, to where its centre crosses the rim
        decel = CAP["rolling_resistance"] * G / (1.0 + K)
        u = math.sqrt(speed**2 - 2.0 * decel * rim)  # rolling (not sliding) at the rim
        up = LIFT_OFF * (u + math.sqrt(G * R))  # the lift-off's normal speed (core.rest)
        down = R_POST + u * (up + math.sqrt(up * up + 2.0 * G * L_POST)) / G
        beyond = down + (u * u - REST_SPEED**2) / (2.0 * GROUND_C * G / (1.0 + K))
        np.testing.assert_allclose(at, [beyond, 0.0, R], atol=10 * tolerance)


def _shot(n=60, seed=3):
    """n pellets from (0, 0, 1) m at 120 m/s towards a post 10 m away, spread +-0.02 rad across it."""
    rng = np.random.default_rng(seed)
    x0 = np.tile([0.0, 0.0, 1.0], (n, 1))
    direction = np.c_[np.ones(n), rng.uniform(-0.02, 0.02, n), rng.uniform(-0.015, 0.01, n)]
    return x0, 120.0 * direction / np.linalg.norm(direction, axis=1)[:, None]


SHOT_POST = POST | {"point": [10.0, 0.0, 0.0], "length": 1.2, "restitution": 0.5, "mu_s": 0.3, "mu_d": 0.27}
SHOT_GROUND = GROUND | {"restitution": 0.3, "rolling_resistance": 0.3}


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_shots_at_a_post_all_end_outside_it_on_the_side_it_threw_them_to(tmp_path, precision):
    """Every pellet ends (none NOT_FINISHED), its centre never inside the post; those whose first
    impact is on the post's side rest on the ground, beyond the post from where it hit them, along
    the way the post threw them (their horizontal rebound)."""
    x0, v0 = _shot()
    out = _run(tmp_path, f"shot-{precision}", x0, v0, [SHOT_GROUND, SHOT_POST], precision)
    state, at = out["rest.state"], out["rest.position"]
    assert (state != NOT_FINISHED).all() and (state == AT_REST).sum() > 50, np.bincount(state)
    hit = out["impact.surface"][:, 0] == 1
    assert 15 < hit.sum() < len(hit) - 15
    for where in (at[state == AT_REST], out["landing.position"], out["impact.position"][:, 0]):
        where = where[np.isfinite(where[:, 0])]
        rho = np.hypot(where[:, 0] - 10.0, where[:, 1])
        assert not ((rho < R_POST) & (where[:, 2] > 0.0) & (where[:, 2] < 1.2)).any()
    contact, thrown = out["impact.position"][hit, 0], out["impact.velocity"][hit, 0]
    resting = at[hit]
    np.testing.assert_allclose(resting[:, 2], R, atol=1e-6)
    back = thrown[:, 0] < 0.0  # thrown back by the side facing the shot (the rest glance off it)
    assert back.sum() > 10 and (resting[back, 0] < 10.0 - R_POST).all()
    away = (resting - contact)[:, :2]
    along = np.einsum("ij,ij->i", away, thrown[:, :2]) / np.linalg.norm(away, axis=1) / np.linalg.norm(thrown[:, :2], axis=1)
    assert (along > 0.9).all(), along.min()


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_the_first_impact_and_landing_are_those_until_landing(tmp_path, precision):
    """The same pellets followed until landing only: the same impacts and landings, bitwise."""
    x0, v0 = _shot()
    fields = ("impact", "landing")
    to_rest = _run(tmp_path, f"rest-{precision}", x0, v0, [SHOT_GROUND, SHOT_POST], precision, fields=("rest", *fields))
    landing = _run(
        tmp_path, f"landing-{precision}", x0, v0, [SHOT_GROUND, SHOT_POST], precision, PHYSICS | {"until": "landing"}, fields
    )
    assert (to_rest["impact.surface"][:, 0] == 1).sum() > 15
    for key, value in landing.items():
        np.testing.assert_array_equal(to_rest[key], value, err_msg=key)


AIR = {"density": 1.225, "drag": "constant", "drag_coefficient": 0.47}


@pytest.mark.parametrize(
    ("precision", "air", "upside_down"),
    [("float64", False, False), ("float32", False, True), ("float64", True, True), ("float32", True, False)],
)
def test_pellets_dropped_on_the_rims_and_along_the_side_all_end_outside_the_post(tmp_path, precision, air, upside_down):
    """400 pellets dropped from above a post's rim: at rest on the rim (centre at rho = r, and
    r +- R/2 with 1 cm/s outwards), R/2 and R beyond it, and across it: all end at rest, on the cap
    (the top, or the bottom of a post hung upside down) or on the ground, none with its centre
    inside the post, none with more energy at its landing than at its start. Without the cap's
    slack (`geometry.on_face`), pellets resting at the rim bounced there until their impacts ran out."""
    n = 400
    angle = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    rho = np.r_[np.full(100, R_POST), np.full(100, R_POST + R / 2), np.full(100, R_POST + R), np.linspace(0.09, 0.1 + 2 * R, 100)]
    x0 = np.c_[rho * np.cos(angle), rho * np.sin(angle), np.full(n, 1.3)]
    v0 = np.c_[0.01 * np.cos(angle), 0.01 * np.sin(angle), np.zeros(n)] * (np.arange(n) >= 200)[:, None]
    post = POST | {"restitution": 0.5, "mu_s": 0.3, "mu_d": 0.27, "rolling_resistance": 0.1}
    if upside_down:
        post |= {"point": [0.0, 0.0, L_POST], "normal": [0.0, 0.0, -1.0]}
    surfaces = [GROUND | {"restitution": 0.3, "rolling_resistance": 0.3}, post]
    scene = explicit_scene(tmp_path, x0, v0, surfaces=surfaces, physics=PHYSICS, precision=precision)
    scene = scene_from_dict({**scene.to_dict(), "output": {"fields": ["rest", "landing"]}} | ({"air": AIR} if air else {}))
    run(scene, tmp_path / "rim.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "rim.h5") as f:
        state, at = f["pellets/rest/state"][()], f["pellets/rest/position"][()]
        landed, speed = f["pellets/landing/position"][()], np.linalg.norm(f["pellets/landing/velocity"][()], axis=1)
    assert (state == AT_REST).all(), np.bincount(state)
    across = np.hypot(at[:, 0], at[:, 1])
    on_cap = (across <= R_POST + 1e-6) & (np.abs(at[:, 2] - L_POST - R) <= 1e-5)
    on_ground = np.abs(at[:, 2] - R) <= 1e-5
    assert (on_cap | on_ground).all() and on_cap.sum() > 100 and on_ground.sum() > 200
    assert not ((across < R_POST) & (at[:, 2] < L_POST)).any()
    energy = 0.5 * speed**2 + G * landed[:, 2]
    assert (energy <= 0.5 * 0.01**2 + G * 1.3 + 1e-5).all()


@pytest.mark.parametrize(("ground", "air"), [({}, False), ({"ploughing": 100.0, "ploughing_area": 0.5}, False), ({}, True)])
def test_pellets_rolling_into_a_posts_foot_bounce_off_its_side(tmp_path, ground, air):
    """50 pellets rolling at 2 m/s along the ground into a post, across its width (closed forms; the
    rolling with ploughing in closed form; the integrated phase in air) meet its side: all rest,
    none inside it, those aimed within r/2 of its axis thrown back to the near side."""
    n = 50
    y = np.linspace(-0.1, 0.1, n)
    x0 = np.c_[np.full(n, -0.5), y, np.full(n, R + 1e-4)]
    v0 = np.c_[np.full(n, 2.0), np.zeros(n), np.zeros(n)]
    w0 = np.c_[np.zeros(n), np.full(n, 2.0 / R), np.zeros(n)]
    post = POST | {"restitution": 0.5, "mu_s": 0.3, "mu_d": 0.27}
    surfaces = [GROUND | {"restitution": 0.3, "rolling_resistance": 0.05} | ground, post]
    scene = explicit_scene(tmp_path, x0, v0, w0, surfaces=surfaces, physics=PHYSICS)
    scene = scene_from_dict({**scene.to_dict(), "output": {"fields": ["rest"]}} | ({"air": AIR} if air else {}))
    run(scene, tmp_path / "foot.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "foot.h5") as f:
        state, at = f["pellets/rest/state"][()], f["pellets/rest/position"][()]
    assert (state == AT_REST).all() and np.allclose(at[:, 2], R, atol=1e-9)
    assert (np.hypot(at[:, 0], at[:, 1]) > R_POST).all()
    assert (at[np.abs(y) < R_POST / 2, 0] < 0.0).all()  # on the near side of its axis


@pytest.mark.parametrize("air", [False, True])
def test_pellets_rolling_up_a_slope_into_a_post_bounce_off_it(tmp_path, air):
    """A post standing on a 10-degree slope (c = 0.5 holds a pellet on it), its base 5 cm under the
    slope: 30 pellets rolling up at 4 m/s from 0.5 m below it, aimed within r/2 of its axis, start
    below its base's plane, meet its side (in air: the integrated phase watches the post from the
    start) and rest below it, none inside it; through it they would rest 1.1 m up the slope."""
    slope = math.radians(10.0)
    uphill, normal = np.array([math.cos(slope), 0.0, math.sin(slope)]), np.array([-math.sin(slope), 0.0, math.cos(slope)])
    n = 30
    x0 = -0.5 * uphill + np.c_[np.zeros(n), np.linspace(-0.05, 0.05, n), np.zeros(n)] + (R + 1e-5) * normal
    v0 = np.tile(4.0 * uphill, (n, 1))
    w0 = np.tile(np.cross(normal, 4.0 * uphill) / R, (n, 1))
    ground = GROUND | {"normal": normal.tolist(), "restitution": 0.3, "rolling_resistance": 0.5}
    post = POST | {"point": [0.0, 0.0, -0.05], "restitution": 0.5, "mu_s": 0.3, "mu_d": 0.27}
    scene = explicit_scene(tmp_path, x0, v0, w0, surfaces=[ground, post], physics=PHYSICS)
    scene = scene_from_dict({**scene.to_dict(), "output": {"fields": ["rest"]}} | ({"air": AIR} if air else {}))
    run(scene, tmp_path / "slope.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "slope.h5") as f:
        state, at = f["pellets/rest/state"][()], f["pellets/rest/position"][()]
    assert (state == AT_REST).all() and (at[:, 0] < 0.0).all()
    assert (np.hypot(at[:, 0], at[:, 1]) > R_POST).all()


@pytest.mark.parametrize("air", [False, True])
def test_a_pellet_stopped_at_a_posts_side_falls_along_it_and_rests_at_its_foot(tmp_path, air):
    """Pellets fired at 20 m/s straight at a post's axis (heights 0.05, 0.5 and 1.1 m) whose side
    has restitution 0 and no friction: the impact leaves them no speed from the side, they leave
    it (no load: its axis is along gravity) with the lift-off speed, fall along it (in the time a
    fall takes) without meeting it again, and rest on the ground touching its foot (rho = r + R, to
    the lift-off's drift)."""
    x0 = np.c_[np.full(3, 9.0), np.zeros(3), [0.05, 0.5, 1.1]]
    v0 = np.tile([20.0, 0.0, 0.0], (3, 1))
    post = SHOT_POST | {"restitution": 0.0, "mu_s": 0.0, "mu_d": 0.0}
    scene = explicit_scene(tmp_path, x0, v0, surfaces=[SHOT_GROUND, post], physics=PHYSICS)
    scene = scene_from_dict({**scene.to_dict(), "output": {"fields": ["rest", "landing"]}} | ({"air": AIR} if air else {}))
    run(scene, tmp_path / "foot.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "foot.h5") as f:
        state, at, impacts = f["pellets/rest/state"][()], f["pellets/rest/position"][()], f["pellets/rest/impacts"][()]
        time = f["pellets/rest/time"][()]
    assert (state == AT_REST).all() and (impacts <= 5).all(), impacts
    fall = (10.0 - R_POST - R - 9.0) / 20.0 + np.sqrt(2.0 * (x0[:, 2] - R) / G)  # s: to the side, then down
    assert (time >= fall).all(), time - fall  # (moved down at once, they would rest ~0.1 to 0.5 s early)
    np.testing.assert_allclose(at[:, 2], R, atol=1e-12)
    gap = np.hypot(at[:, 0] - 10.0, at[:, 1]) - R_POST - R
    assert (gap >= -1e-12).all() and (gap <= 1e-5).all(), gap
