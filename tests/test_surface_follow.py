"""A pellet followed along a surface (physics/surface_follow.py, docs/ground.md 9): the analytic cases,
against the float64 SciPy reference (reference/surface_motion.py) on seeded random planes in vacuum
and air with and without ploughing, lift-off, contact with a second plane, the step budget, and the
invariants; both precisions, CPU test kernels (bench/surface.py's `follow_pellets`)."""

import functools
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from bench.surface import follow_pellets
from warp_ricochet.physics.surface_follow import CONTACT, FLIGHT, FOREVER, REST, UNFINISHED
from warp_ricochet.reference import surface_motion as ref
from warp_ricochet.scene.schema import Air

G = 9.81
R = 0.00125
K = 0.4
FLOOR = [((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))]
PRECISIONS = ["float64", "float32"]
CLOSE = {"float64": 1e-9, "float32": 2e-5}  # closed forms against formulas, relative
AGREE = 1e-4  # the bound: rest positions within 1e-4 of the path length


def _frame(n):
    e1 = np.cross(np.eye(3)[np.argmin(np.abs(n))], n)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def _rolling(n, v):
    """The spin of a pellet rolling at v on the plane of normal n: omega_t = n x v / R."""
    return np.cross(n, v) / R


# --------------------------------------------------------------------------- analytic cases


@pytest.mark.parametrize("precision", PRECISIONS)
def test_level_slide_rolls_at_five_sevenths_then_stops(precision):
    """Level plane, vacuum, no spin: rolls after 12 v0^2 / (49 mu g) at 5/7 v0; with c = 0 it rolls on
    for ever from there (FOREVER, the state where the endless phase begins), with c > 0 it rests
    after 5 v0^2 / (14 c g) more, with rest_speed v_r (v^2 - v_r^2) / (2 * 5/7 c g) after rolling."""
    v0, mu, c = np.array([1.0, 30.0, 187.0]), 0.4, 0.05
    kw = dict(radius=R, mu_d=mu)
    on = follow_pellets(precision, FLOOR, [0, R, 0], np.outer(v0, [1, 0, 0]), 0, c=0.0, **kw)
    assert on["end"].tolist() == [FOREVER] * 3 and on["steps"].tolist() == [0] * 3
    np.testing.assert_allclose(on["x"][:, 0], 12 * v0**2 / (49 * mu * G), rtol=CLOSE[precision])
    np.testing.assert_allclose(on["v"][:, 0], 5 / 7 * v0, rtol=CLOSE[precision])
    np.testing.assert_allclose(on["elapsed"], 2 * v0 / (7 * mu * G), rtol=CLOSE[precision])
    rest = 0.13
    out = follow_pellets(precision, FLOOR, [0, R, 0], np.outer(v0, [1, 0, 0]), 0, c=c, rest=rest, **kw)
    assert out["end"].tolist() == [REST] * 3 and np.abs(out["v"]).max() == 0.0
    want = 12 * v0**2 / (49 * mu * G) + ((5 / 7 * v0) ** 2 - rest**2) / (2 * 5 / 7 * c * G)
    np.testing.assert_allclose(out["x"][:, 0], want, rtol=CLOSE[precision])
    np.testing.assert_allclose(out["path"], want, rtol=CLOSE[precision])


@pytest.mark.parametrize("precision", PRECISIONS)
def test_incline_rolls_at_five_sevenths_g_sin_theta_into_a_wall(precision):
    """c = 0, from rest on an incline: it rolls down at 5/7 g sin(theta) and meets a wall across the
    fall line L down the slope (CONTACT, k_next 1) after sqrt(2 L / (5/7 g sin theta)), at gap 0;
    without the wall it rolls for ever (FOREVER). With ploughing (integrated) it meets the wall slower."""
    theta, length = math.radians(20.0), 3.0
    n = np.array([-math.sin(theta), math.cos(theta), 0.0])
    down = np.array([-math.cos(theta), -math.sin(theta), 0.0])
    start = R * n
    wall = (tuple(start + (length + R) * down), tuple(-down))
    a = 5 / 7 * G * math.sin(theta)
    planes = [((0.0, 0.0, 0.0), tuple(n)), wall]
    out = follow_pellets(precision, planes, start, [[0, 0, 0]] * 3, 0, radius=R, mu_s=0.5, b=[0.0, 0.0, 0.2], static=True)
    assert out["end"].tolist() == [CONTACT] * 3 and out["k_next"].tolist() == [1] * 3
    t = math.sqrt(2 * length / a)
    assert out["elapsed"][0] == pytest.approx(t, rel=CLOSE[precision])
    np.testing.assert_allclose(out["v"][0], a * t * down, rtol=CLOSE[precision], atol=CLOSE[precision] * a * t)
    np.testing.assert_allclose(out["x"][:, :] @ down - start @ down, length, rtol=CLOSE[precision])  # at gap 0
    assert out["elapsed"][2] > t and out["steps"][2] > 0 and out["path"][2] == pytest.approx(length, rel=1e-5)
    alone = follow_pellets(precision, planes[:1], start, [0, 0, 0], 0, radius=R, mu_s=0.5)
    assert alone["end"].tolist() == [FOREVER] and alone["elapsed"][0] == 0.0


@pytest.mark.parametrize("precision", PRECISIONS)
def test_ploughing_stops_where_the_closed_form_says(precision):
    """Rolling on a level plane with ploughing b: v' = -5/7 (c g + b v^2), so it rests after
    7/(10 b) ln((c g + b v0^2) / (c g + b v_r^2)) (c = 0: 7/(5 b) ln(v0 / v_r)), in closed form (no
    steps); a wall on the way is met at the speed v^2 = ((c g + b v0^2) exp(-10 b s / 7) - c g) / b."""
    v0, b = np.array([3.0, 5.0, 20.0, 20.0]), np.array([0.5, 0.5, 0.02, 0.02])  # b v^2 < (7/2 mu_s - c) g: grips
    c, rest = np.array([0.05, 0.05, 0.05, 0.0]), 0.13
    vel = np.outer(v0, [1, 0, 0])
    out = follow_pellets(precision, FLOOR, [0, R, 0], vel, _rolling([0, 1, 0], vel), radius=R, c=c, b=b, rest=rest)
    want = np.where(c > 0, 7 / (10 * b) * np.log((c * G + b * v0**2) / (c * G + b * rest**2)), 7 / (5 * b) * np.log(v0 / rest))
    assert out["end"].tolist() == [REST] * 4 and out["steps"].tolist() == [0] * 4
    np.testing.assert_allclose(out["x"][:, 0], want, rtol=CLOSE[precision])
    np.testing.assert_allclose(out["path"], want, rtol=CLOSE[precision])
    r = ref.follow(
        [0, R, 0], vel[1], _rolling([0, 1, 0], vel[1]), radius=R, ground=ref.Ground(0, 0.5, 0.4, c[1], b[1]), rest_speed=rest
    )
    assert r.state == "rest" and r.x[0] == pytest.approx(want[1], rel=1e-8)
    assert out["elapsed"][1] == pytest.approx(r.t, rel=CLOSE[precision])
    wall = ((2.0 + R, 0.0, 0.0), (-1.0, 0.0, 0.0))
    met = follow_pellets(precision, [*FLOOR, wall], [0, R, 0], vel, _rolling([0, 1, 0], vel), radius=R, c=c, b=b, rest=rest)
    assert met["end"].tolist() == [CONTACT] * 4 and met["k_next"].tolist() == [1] * 4
    np.testing.assert_allclose(met["x"][:, 0], 2.0, rtol=CLOSE[precision])
    speed = np.sqrt(((c * G + b * v0**2) * np.exp(-10 * b * 2.0 / 7) - c * G) / b)
    np.testing.assert_allclose(met["v"][:, 0], speed, rtol=10 * CLOSE[precision])


# --------------------------------------------------------------------------- against the reference


def _random_cases(seed, m):
    """Seeded random planes of any orientation, shallow enough to rest on (tan theta < c); sliding or
    rolling any way along them at 1-40 m/s with any spin; vacuum and air; ploughing in half."""
    rng = np.random.default_rng(seed)
    cases = []
    for i in range(m):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        e1, e2 = _frame(n)
        c = rng.uniform(0.05, 0.3)
        theta = rng.uniform(0, 0.8) * math.atan(c)
        g = G * (-math.cos(theta) * n + math.sin(theta) * e1)
        phi = rng.uniform(0, 2 * math.pi)
        v = rng.uniform(1, 40) * (math.cos(phi) * e1 + math.sin(phi) * e2)
        w = _rolling(n, v) if i % 4 == 0 else rng.normal(0, 3e3, 3) + _rolling(n, v) * rng.uniform(-0.5, 1.5)
        b = rng.uniform(0.05, 1.0) if i % 2 else 0.0
        air = Air() if (i // 2) % 2 else None
        mu_d = rng.uniform(0.2, 0.5)
        cases.append(dict(n=n, g=g, v=v, w=w, c=c, b=b, air=air, mu_s=mu_d + 0.1, mu_d=mu_d, rest=rng.choice([0.05, 0.13])))
    return cases


@functools.cache
def _reference(seed, m):
    """The reference's end of each case: (state, x, path, t); 'flight' where it lifts off first."""
    out = []
    for case in _random_cases(seed, m):
        ground = ref.Ground(0.3, case["mu_s"], case["mu_d"], case["c"], case["b"])
        r = ref.follow(R * case["n"], case["v"], case["w"], radius=R, normal=case["n"], gravity=case["g"], ground=ground,
                       rest_speed=case["rest"], air=case["air"], density=7000.0)  # fmt: skip
        flights = [p for p in r.phases if p.mode == "flight"]
        first = r.phases.index(flights[0]) if flights else None
        if first == 0:  # lifted off at once
            out.append(("flight", R * case["n"], 0.0, 0.0))
        elif flights:  # lifted off: the state where the surface phase before the first flight ends
            sol = r.phases[first - 1].sols[-1]
            y = sol(sol.t_max)
            out.append(("flight", y[0:3], y[9], sol.t_max))
        else:
            out.append((r.state, r.x, r.path_length, r.t))
    return out


def _follow_cases(precision, cases, **kw):
    """follow_pellets of each case on its own plane: a list of dicts of its outputs."""
    got = []
    for case in cases:
        plane = [((0.0, 0.0, 0.0), tuple(case["n"]))]
        keys = dict(mu_s=case["mu_s"], mu_d=case["mu_d"], c=case["c"], b=case["b"], rest=case["rest"], air=case["air"])
        out = follow_pellets(
            precision, plane, R * case["n"], case["v"], case["w"], radius=R, gravity=tuple(case["g"]), **keys, **kw
        )
        got.append({key: value[0] for key, value in out.items()})
    return got


@pytest.mark.parametrize("precision", PRECISIONS)
def test_rest_positions_match_the_reference(precision):
    """Seeded random cases (any plane, vacuum and air, with and without ploughing): the same end
    (rest, or lift-off), the end position within 1e-4 of the path length of the reference's, the path
    and the time within 1e-4."""
    m = 24
    cases, want = _random_cases(8, m), _reference(8, m)
    names = {REST: "rest", FLIGHT: "flight"}
    got = _follow_cases(precision, cases)
    assert sum(state == "rest" for state, *_ in want) >= m - 4  # mostly rests
    worst = 0.0
    for i, (out, (state, x, path, t)) in enumerate(zip(got, want)):
        assert names.get(int(out["end"]), int(out["end"])) == state, (i, out["end"], state)
        error = np.linalg.norm(out["x"] - x) / path
        worst = max(worst, error)
        assert error <= AGREE, (i, out["x"], x, path)
        assert out["path"] == pytest.approx(path, rel=AGREE) and out["elapsed"] == pytest.approx(t, rel=AGREE)
    print(f"{precision}: worst rest position error {worst:.2g} of the path length")


def test_backspin_in_air_lifts_off_where_the_reference_does():
    """Sliding down a 60 degree slope in air with backspin: the Magnus lift grows with the speed
    until it outweighs g cos(60) and the pellet lifts off (FLIGHT) mid-slide, where the reference's
    normal load crosses 0; a plane facing down lets go at once."""
    theta = math.radians(60.0)
    n = np.array([math.sin(theta), math.cos(theta), 0.0])
    down = np.array([math.cos(theta), -math.sin(theta), 0.0])
    v, w = 12.0 * down, np.array([0.0, 0.0, 4e4])  # omega x v along +n: lift away from the plane
    ground = ref.Ground(0.3, 0.5, 0.4, 0.05)
    r = ref.follow(R * n, v, w, radius=R, normal=n, ground=ground, air=Air(), density=7000.0, rest_speed=0.13, t_max=5.0)
    sliding, flight = r.phases[:2]
    lift_off = sliding.sols[-1].t_max
    assert (sliding.mode, flight.mode) == ("sliding", "flight") and lift_off > 0.5
    y = sliding.sols[-1](lift_off)
    for precision in PRECISIONS:
        out = follow_pellets(
            precision, [((0.0, 0.0, 0.0), tuple(n))], R * n, v, w, radius=R, mu_d=0.4, c=0.05, rest=0.13, air=Air()
        )
        assert out["end"][0] == FLIGHT and out["steps"][0] > 0
        assert np.linalg.norm(out["x"][0] - y[0:3]) <= AGREE * y[9] and out["elapsed"][0] == pytest.approx(lift_off, rel=AGREE)
        np.testing.assert_allclose(out["v"][0], y[3:6], rtol=AGREE, atol=AGREE * np.linalg.norm(y[3:6]))
    ceiling = [((0.0, 1.0, 0.0), (0.0, -1.0, 0.0))]
    out = follow_pellets("float64", ceiling, [0, 1 - R, 0], [5.0, 0, 0], 0, radius=R)
    assert out["end"].tolist() == [FLIGHT] and out["elapsed"][0] == 0.0


@pytest.mark.parametrize("precision", PRECISIONS)
def test_contact_with_a_wall_in_air(precision):
    """Rolling in air with ploughing towards a wall 2 m ahead: CONTACT with it, at gap 0, at the
    reference's speed where its path (on the floor alone) reaches the wall."""
    v = np.array([40.0, 0.0, 0.0])
    wall = ((2.0 + R, 0.0, 0.0), (-1.0, 0.0, 0.0))
    out = follow_pellets(
        precision, [*FLOOR, wall], [0, R, 0], v, _rolling([0, 1, 0], v), radius=R, c=0.05, b=0.2, rest=0.13, air=Air()
    )
    r = ref.follow([0, R, 0], v, _rolling([0, 1, 0], v), radius=R, ground=ref.Ground(0.3, 0.5, 0.4, 0.05, 0.2), air=Air(),
                   density=7000.0, rest_speed=0.13)  # fmt: skip
    sol = r.phases[0].sols[0]
    t = brentq(lambda s: sol(s)[0] - 2.0, sol.t_min, sol.t_max, xtol=1e-14)
    assert (out["end"][0], out["k_next"][0]) == (CONTACT, 1)
    assert out["x"][0][0] == pytest.approx(2.0, rel=CLOSE[precision]) and out["elapsed"][0] == pytest.approx(t, rel=AGREE)
    assert out["v"][0][0] == pytest.approx(sol(t)[3], rel=AGREE)


def test_the_step_budget_ends_unfinished():
    """max_steps integration steps spent: UNFINISHED, with exactly that many steps, the state moving."""
    v = np.array([100.0, 0.0, 0.0])
    out = follow_pellets(
        "float64", FLOOR, [0, R, 0], v, _rolling([0, 1, 0], v), radius=R, c=0.05, b=0.2, air=Air(), max_steps=[0, 3]
    )
    assert out["end"].tolist() == [UNFINISHED] * 2 and out["steps"].tolist() == [0, 3]
    assert 0 < out["x"][1][0] and np.linalg.norm(out["v"][1]) > 1.0


# --------------------------------------------------------------------------- invariants


@pytest.mark.parametrize("precision", PRECISIONS)
def test_energy_never_rises_and_the_pellet_stays_on_the_plane(precision):
    """The random cases stopped after 1, 2, 4, ... steps (UNFINISHED) and at their end: the energy
    (kinetic, spin, height) never rises from one to the next (no wind); the centre is at height R."""
    cases = [case for case in _random_cases(8, 24) if case["air"] is not None or case["b"] > 0][:8]
    budgets = [1, 2, 4, 8, 16, 32, 64, 100000]
    runs = [_follow_cases(precision, cases, max_steps=budget) for budget in budgets]
    for i, case in enumerate(cases):
        n, g = case["n"], case["g"]
        energies = [0.5 * case["v"] @ case["v"] + 0.5 * K * R**2 * case["w"] @ case["w"] - g @ (R * n)]
        for run in runs:
            x, v, w = run[i]["x"], run[i]["v"], run[i]["w"]
            energies.append(0.5 * v @ v + 0.5 * K * R**2 * w @ w - g @ x)
            assert abs(x @ n - R) <= 64 * np.finfo(precision).eps * (np.abs(x).max() + R), (i, x @ n - R)
        e = np.array(energies)
        assert (np.diff(e) <= CLOSE[precision] * np.abs(e).max()).all(), (i, e)
