"""Motion along a surface (physics/surface_motion.py, docs/ground.md): the analytic cases, the Warp
laws and closed forms against the float64 SciPy reference (reference/surface_motion.py) on seeded
random cases in both precisions, and the invariants."""

import math

import numpy as np
import pytest
import warp as wp

from warp_ricochet.physics.surface_motion import FLIGHT, REST, ROLLING, SLIDING, make_surface_motion
from warp_ricochet.reference import surface_motion as ref

wp.config.log_level = wp.LOG_WARNING
G = 9.81
R = 0.00125
K = 0.4
PRECISIONS = ["float64", "float32"]
# closed forms and rates against the reference, relative: float32 rounding over a few phases
CLOSE = {"float64": 1e-9, "float32": 2e-5}
SCALARS = ("load", "slip", "needed", "mode", "slide_time", "slide_exact", "roll_time", "roll_rest", "roll_exact")
SCALARS += ("elapsed", "path", "end_mode", "end_exact", "separation", "separates")
VECTORS = ("slide_acc", "slide_spin", "roll_acc", "roll_spin", "end_x", "end_v", "end_w")


def _kernels(precision):
    scalar = wp.float64 if precision == "float64" else wp.float32
    vec3 = wp.types.vector(3, scalar)
    sm = make_surface_motion(precision)

    @wp.kernel(enable_backward=False, module="unique")
    def probe(
        x: wp.array(dtype=vec3),
        v: wp.array(dtype=vec3),
        w: wp.array(dtype=vec3),
        n: wp.array(dtype=vec3),
        applied: wp.array(dtype=vec3),
        alpha: wp.array(dtype=vec3),
        gravity: wp.array(dtype=vec3),
        p: wp.array2d(dtype=scalar),  # mu_s, mu_d, c, rest_speed, rebound normal speed, ploughing b
        s: wp.array2d(dtype=scalar),
        vecs: wp.array2d(dtype=vec3),
    ):
        i = wp.tid()
        mu_s = p[i, 0]
        mu_d = p[i, 1]
        c = p[i, 2]
        rest = p[i, 3]
        b = p[i, 5]
        radius, k = scalar(R), scalar(K)
        load = sm.normal_load(n[i], applied[i])
        s[i, 0] = load
        s[i, 1] = wp.length(sm.slip_velocity(v[i], w[i], n[i], radius))
        a, dw = sm.sliding_rates(v[i], w[i], n[i], applied[i], alpha[i], radius, k, mu_d, b)
        vecs[i, 0] = a
        vecs[i, 1] = dw
        a, dw, needed = sm.rolling_rates(v[i], n[i], applied[i], alpha[i], radius, k, c, b)
        vecs[i, 2] = a
        vecs[i, 3] = dw
        s[i, 2] = needed
        s[i, 3] = scalar(sm.surface_mode(v[i], w[i], n[i], applied[i], alpha[i], gravity[i], radius, k, mu_s, c, b, rest))
        t_slide, exact_slide = sm.slide_end(v[i], w[i], n[i], applied[i], radius, k, mu_d)
        s[i, 4] = t_slide
        s[i, 5] = exact_slide
        t_roll, at_rest, exact = sm.roll_end(v[i], n[i], applied[i], k, c, rest)
        s[i, 6] = t_roll
        s[i, 7] = scalar(at_rest)
        s[i, 8] = exact
        xe, ve, we, elapsed, path, mode, exact_end = sm.follow_on_plane(
            x[i], v[i], w[i], n[i], applied[i], radius, k, mu_s, mu_d, c, rest
        )
        vecs[i, 4] = xe
        vecs[i, 5] = ve
        vecs[i, 6] = we
        s[i, 9] = elapsed
        s[i, 10] = path
        s[i, 11] = scalar(mode)
        s[i, 12] = scalar(exact_end)
        s[i, 13] = sm.separation_speed(load, radius)
        s[i, 14] = scalar(sm.separates(p[i, 4], load, radius))

    @wp.kernel(enable_backward=False, module="unique")
    def arc(v: wp.array(dtype=vec3), a: wp.array(dtype=vec3), t: wp.array(dtype=scalar), out: wp.array(dtype=scalar)):
        i = wp.tid()
        out[i] = sm.arc_length(v[i], a[i], t[i])

    return scalar, vec3, probe, arc


def probe(
    precision, device, *, x, v, w, n, applied, alpha=None, gravity=None, mu_s=0.5, mu_d=0.4, c=0.0, rest=0.0, rebound=0.0, b=0.0
):
    """Every law and closed form of physics.surface_motion at m cases; {name: float64 array}."""
    scalar, vec3, kernel, _arc = _kernels(precision)
    v = np.atleast_2d(np.asarray(v, float))
    m = len(v)

    def rows(a):
        return np.broadcast_to(np.asarray(a, float), (m, 3)).copy()

    alpha = np.zeros((m, 3)) if alpha is None else alpha
    gravity = applied if gravity is None else gravity  # (the closed forms take `applied` as gravity)
    params = np.stack([np.broadcast_to(np.asarray(q, float), (m,)) for q in (mu_s, mu_d, c, rest, rebound, b)], axis=1)
    arrays = [wp.array(rows(a).astype(precision), dtype=vec3, device=device) for a in (x, v, w, n, applied, alpha, gravity)]
    s = wp.zeros((m, len(SCALARS)), dtype=scalar, device=device)
    vecs = wp.zeros((m, len(VECTORS)), dtype=vec3, device=device)
    wp.launch(
        kernel, dim=m, inputs=[*arrays, wp.array(params.astype(precision), device=device)], outputs=[s, vecs], device=device
    )
    out = {name: s.numpy()[:, j].astype(float) for j, name in enumerate(SCALARS)}
    out.update({name: vecs.numpy()[:, j].astype(float) for j, name in enumerate(VECTORS)})
    return out


def _frame(n):
    """Two unit vectors along the plane of unit normal n."""
    e1 = np.cross(np.eye(3)[np.argmin(np.abs(n))], n)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def _random_normals(rng, m):
    n = rng.normal(size=(m, 3))
    return n / np.linalg.norm(n, axis=1)[:, None]


# --------------------------------------------------------------------------- analytic cases


@pytest.mark.parametrize("precision", PRECISIONS)
def test_sliding_without_spin_rolls_at_five_sevenths(precision, device):
    """Level plane, vacuum, no spin: rolls after 2 v0 / (7 mu g), 12 v0^2 / (49 mu g) on, at 5/7 v0;
    with c > 0 it then stops (5/7 v0)^2 / (2 * 5/7 c g) later: the closed forms and the reference."""
    v0, mu, c = np.array([1.0, 30.0, 187.0]), 0.4, 0.05
    m = len(v0)
    n = np.array([0.0, 1.0, 0.0])
    got = probe(precision, device, x=[0, R, 0], v=np.outer(v0, [1, 0, 0]), w=0, n=n, applied=[0, -G, 0], mu_d=mu, c=c)
    t_roll = 2 * v0 / (7 * mu * G)
    assert got["mode"].tolist() == [SLIDING] * m
    np.testing.assert_allclose(got["slide_time"], t_roll, rtol=CLOSE[precision])
    np.testing.assert_allclose(got["slide_acc"], np.outer(np.ones(m), [-mu * G, 0, 0]), rtol=CLOSE[precision], atol=1e-12)
    roll_distance = (5 / 7 * v0) ** 2 / (2 * 5 / 7 * c * G)
    np.testing.assert_allclose(got["end_x"][:, 0], 12 * v0**2 / (49 * mu * G) + roll_distance, rtol=CLOSE[precision])
    np.testing.assert_allclose(got["elapsed"], t_roll + v0 / (c * G), rtol=CLOSE[precision])
    np.testing.assert_allclose(got["path"], got["end_x"][:, 0], rtol=CLOSE[precision])
    assert got["end_mode"].tolist() == [REST] * m and got["end_exact"].tolist() == [1] * m
    for speed in v0:  # (187 m/s: the reference's slip once chattered about zero below its stop)
        r = ref.follow([0, R, 0], [speed, 0, 0], [0, 0, 0], radius=R, ground=ref.Ground(0.0, mu, mu, c))
        sliding, rolling = r.phases
        assert (sliding.mode, rolling.mode, r.state) == ("sliding", "rolling", "rest")
        t = 2 * speed / (7 * mu * G)
        assert rolling.t == pytest.approx(t, rel=1e-9)
        y = sliding.sols[0](t)
        assert y[0] == pytest.approx(12 * speed**2 / (49 * mu * G), rel=1e-9)
        assert y[3] == pytest.approx(5 / 7 * speed, rel=1e-9)
        assert r.x[0] == pytest.approx(12 * speed**2 / (49 * mu * G) + (5 / 7 * speed) ** 2 / (2 * 5 / 7 * c * G), rel=1e-9)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_rolling_down_an_incline_at_five_sevenths_g_sin_theta(precision, device):
    """c = 0: a rolling sphere accelerates at 5/7 g sin(theta) down the fall line, needing the static
    friction 2/7 g sin(theta); it slides instead where tan(theta) > 7/2 mu_s."""
    theta = np.radians([5.0, 20.0, 45.0, 70.0])
    n = np.stack([-np.sin(theta), np.cos(theta), 0 * theta], axis=1)
    down = np.stack([-np.cos(theta), -np.sin(theta), 0 * theta], axis=1)
    mu_s = 0.5
    v = 2.0 * down
    w = np.cross(n, v) / R  # rolling: omega_t = n x v / R
    got = probe(precision, device, x=R * n, v=v, w=w, n=n, applied=[0, -G, 0], mu_s=mu_s, mu_d=0.4)
    np.testing.assert_allclose(got["roll_acc"], 5 / 7 * G * np.sin(theta)[:, None] * down, rtol=CLOSE[precision], atol=1e-6)
    np.testing.assert_allclose(got["needed"], 2 / 7 * G * np.sin(theta), rtol=CLOSE[precision])
    expect = np.where(np.tan(theta) > 3.5 * mu_s, SLIDING, ROLLING)
    assert got["mode"].tolist() == expect.tolist()
    assert got["end_mode"].tolist() == expect.tolist() and got["end_exact"].tolist() == [1] * 4  # never stops
    # the reference, from rest on the 20 degree slope: s = 5/14 g sin(theta) t^2 after t
    r = ref.follow(R * n[1], [0, 0, 0], [0, 0, 0], radius=R, normal=n[1], ground=ref.Ground(0.0, mu_s, 0.4, 0.0), t_max=2.0)
    assert r.state == "moving" and [p.mode for p in r.phases] == ["rolling"]
    assert (r.x - R * n[1]) @ down[1] == pytest.approx(5 / 14 * G * np.sin(theta[1]) * 4.0, rel=1e-10)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_rolling_resistance_stops_where_the_closed_form_says(precision, device):
    """Level plane: v^2 / (2 * 5/7 c g) to a stop, (v^2 - v_rest^2) / (2 * 5/7 c g) to the rest speed;
    up a slope tan(theta) < c: v^2 / (2 * 5/7 g (sin + c cos)); one too steep to rest on rolls back."""
    v, c, rest = 3.0, 0.1, 0.2
    theta = np.radians([0.0, 0.0, 4.0, 8.0])
    n = np.stack([-np.sin(theta), np.cos(theta), 0 * theta], axis=1)
    up = np.stack([np.cos(theta), np.sin(theta), 0 * theta], axis=1)
    rests = np.array([0.0, rest, 0.0, 0.0])
    got = probe(precision, device, x=R * n, v=v * up, w=np.cross(n, v * up) / R, n=n, applied=[0, -G, 0], c=c, rest=rests)
    deceleration = 5 / 7 * G * (np.sin(theta) + c * np.cos(theta))
    distance = (v**2 - rests**2) / (2 * deceleration)
    moved = np.einsum("ij,ij->i", got["end_x"] - R * n, up)
    np.testing.assert_allclose(moved[:3], distance[:3], rtol=CLOSE[precision])
    assert got["end_mode"].tolist() == [REST, REST, REST, ROLLING]  # tan(8 deg) = 0.14 > c: rolls back for ever
    assert moved[3] == pytest.approx(distance[3], rel=CLOSE[precision]) and got["end_exact"][3] == 1
    assert np.abs(got["end_v"][3]).max() == 0.0  # returned where it turns back
    for k in range(3):
        r = ref.follow(
            R * n[k],
            v * up[k],
            np.cross(n[k], v * up[k]) / R,
            radius=R,
            normal=n[k],
            ground=ref.Ground(0, 0.5, 0.4, c),
            rest_speed=rests[k],
        )
        assert r.state == "rest" and (r.x - R * n[k]) @ up[k] == pytest.approx(distance[k], rel=1e-8)


# --------------------------------------------------------------------------- laws against the reference


@pytest.mark.parametrize("precision", PRECISIONS)
def test_rates_match_the_reference_on_any_plane_in_air(precision, device):
    """Sliding and rolling rates at random states on random planes, with a random air acceleration,
    air torque and ploughing (a third without): the Warp vector form against the reference's
    component form in the plane's frame."""
    rng = np.random.default_rng(25)
    m = 200
    n = _random_normals(rng, m)
    applied = -15.0 * n + rng.normal(0, 5, (m, 3))  # pressing on, with a drive along the plane
    alpha = rng.normal(0, 1e4, (m, 3))
    v = rng.normal(0, 50, (m, 3))
    v -= np.einsum("ij,ij->i", v, n)[:, None] * n
    w = rng.normal(0, 1e4, (m, 3))
    mu_d, c, b = 0.4, rng.uniform(0, 0.5, m), rng.uniform(0, 0.02, m) * (np.arange(m) % 3 != 0)
    got = probe(precision, device, x=R * n, v=v, w=w, n=n, applied=applied, alpha=alpha, mu_d=mu_d, c=c, b=b)
    for i in range(m):
        plane = ref.Plane((0, 0, 0), n[i])
        model = ref.Model(R, 7000.0, (0, -G, 0), None)
        model.applied = lambda _v, _w, i=i: (applied[i], alpha[i])
        y = np.concatenate([R * n[i], v[i], w[i], [0.0]])
        ground = ref.Ground(0.0, 0.5, mu_d, c[i], b[i])
        slide, load, _ = ref.surface_rates(y, plane, model, ground, False)
        roll, _, needed = ref.surface_rates(y, plane, model, ground, True)
        scale = np.abs(applied[i]).max() + R * np.abs(alpha[i]).max() + load + b[i] * (v[i] @ v[i])
        assert got["load"][i] == pytest.approx(load, rel=CLOSE[precision])
        np.testing.assert_allclose(got["slide_acc"][i], slide[3:6], atol=CLOSE[precision] * scale)
        np.testing.assert_allclose(got["slide_spin"][i], slide[6:9], atol=CLOSE[precision] * scale / R)
        np.testing.assert_allclose(got["roll_acc"][i], roll[3:6], atol=CLOSE[precision] * scale)
        np.testing.assert_allclose(got["roll_spin"][i], roll[6:9], atol=CLOSE[precision] * scale / R)
        assert got["needed"][i] == pytest.approx(needed, rel=CLOSE[precision], abs=CLOSE[precision] * scale)


def _fall_line_cases(rng, m):
    """Random planes and gravity, the pellet on the plane moving and slipping along the fall line
    (or anywhere on a level plane): the cases whose accelerations are constant in vacuum."""
    cases = []
    for i in range(m):
        n = _random_normals(rng, 1)[0]
        e1, e2 = _frame(n)
        c = rng.uniform(0.02, 0.3)
        level = i % 2 == 0
        theta = 0.0 if level else rng.uniform(0, 0.9) * math.atan(c)  # shallow enough to rest on
        phi = rng.uniform(0, 2 * math.pi)
        down = e1 if not level else math.cos(phi) * e1 + math.sin(phi) * e2
        g = G * (-math.cos(theta) * n + math.sin(theta) * down)
        across = np.cross(n, down)
        if level:  # any speed and spin: the slip keeps its direction
            v = rng.normal(0, 30, 2) @ np.stack([e1, e2])
            w = rng.normal(0, 2e4, 3)
        else:  # along the fall line, spun about the axis across it
            v = rng.normal(0, 30) * down
            w = rng.normal(0, 2e4) * across + rng.normal(0, 1e3) * n
        cases.append(dict(n=n, g=g, v=v, w=w, c=c, mu_d=rng.uniform(0.1, 0.6), rest=rng.choice([0.0, 0.1])))
    return cases


def _probe_cases(precision, device, cases):
    """(the cases' fields stacked, `probe` of them), mu_s = 0.7."""
    stack = {key: np.array([case[key] for case in cases]) for key in cases[0]}
    n = stack["n"]
    got = probe(
        precision,
        device,
        x=R * n,
        v=stack["v"],
        w=stack["w"],
        n=n,
        applied=stack["g"],
        mu_s=0.7,
        mu_d=stack["mu_d"],
        c=stack["c"],
        rest=stack["rest"],
    )
    return stack, got


@pytest.mark.parametrize("precision", PRECISIONS)
def test_closed_forms_rest_where_the_reference_does(precision, device):
    """follow_on_plane against reference.follow on seeded random planes of any orientation: the rest
    position within 2e-5 (float32) and 1e-9 (float64) of the path length (the issue asks 1e-4), the
    path and the time alike; v = 0 and omega = (omega . n) n there, though rest_speed > 0 in half."""
    cases = _fall_line_cases(np.random.default_rng(7), 24)
    stack, got = _probe_cases(precision, device, cases)
    n = stack["n"]
    assert got["end_mode"].tolist() == [REST] * len(cases) and got["end_exact"].tolist() == [1] * len(cases)
    for i, case in enumerate(cases):
        r = ref.follow(
            R * n[i],
            case["v"],
            case["w"],
            radius=R,
            normal=n[i],
            gravity=case["g"],
            ground=ref.Ground(0.0, 0.7, case["mu_d"], case["c"]),
            rest_speed=case["rest"],
        )
        assert r.state == "rest"
        # at rest nothing moves (docs/ground.md 4), though it stopped at rest_speed: both zero v, omega_t
        assert np.abs(got["end_v"][i]).max() == 0.0 and np.abs(r.v).max() == 0.0, (got["end_v"][i], r.v)
        for spin, rounding in ((got["end_w"][i], CLOSE[precision]), (r.omega, 1e-15)):
            assert np.abs(spin - (spin @ n[i]) * n[i]).max() <= rounding * np.abs(spin).max(), spin
        assert np.linalg.norm(got["end_x"][i] - r.x) <= CLOSE[precision] * r.path_length, (i, got["end_x"][i], r.x)
        assert got["path"][i] == pytest.approx(r.path_length, rel=CLOSE[precision])
        assert got["elapsed"][i] == pytest.approx(r.t, rel=CLOSE[precision])


def _moving_cases(rng, m):
    """Rolling on slopes it cannot rest on, where the closed forms end moving for ever: even i, c > 0
    steeper than atan(c), rolling up the fall line (stops, rolls back down); odd i, c = 0, rolling
    any way along the plane (a parabola: the part across the fall line stays)."""
    cases = []
    for i in range(m):
        n = _random_normals(rng, 1)[0]
        e1, e2 = _frame(n)
        c = rng.uniform(0.02, 0.3) if i % 2 == 0 else 0.0
        theta = rng.uniform(1.2, 2.0) * math.atan(c) if c > 0 else rng.uniform(0.05, 0.5)
        g = G * (-math.cos(theta) * n + math.sin(theta) * e1)
        phi = rng.uniform(0, 2 * math.pi)
        v = -rng.uniform(1, 30) * e1 if c > 0 else rng.uniform(1, 30) * (math.cos(phi) * e1 + math.sin(phi) * e2)
        w = np.cross(n, v) / R + rng.normal(0, 1e3) * n
        cases.append(dict(n=n, g=g, v=v, w=w, c=c, mu_d=0.4, rest=rng.choice([0.0, 0.1])))
    return cases


@pytest.mark.parametrize("precision", PRECISIONS)
def test_closed_forms_roll_on_where_the_reference_does(precision, device):
    """follow_on_plane where the pellet never rests: it ends ROLLING, exact, at the start of a phase
    of constant acceleration (docs/ground.md 3, 6), which carried on to t_max matches reference.follow
    there. Before the fix, c = 0 with v across the fall line 'stopped' and dropped the part across."""
    cases = _moving_cases(np.random.default_rng(11), 12)
    stack, got = _probe_cases(precision, device, cases)
    n = stack["n"]
    assert got["end_mode"].tolist() == [ROLLING] * len(cases) and got["end_exact"].tolist() == [1] * len(cases)
    for i, case in enumerate(cases):
        g_t = case["g"] - (case["g"] @ n[i]) * n[i]
        t_max = got["elapsed"][i] + 0.5
        r = ref.follow(
            R * n[i],
            case["v"],
            case["w"],
            radius=R,
            normal=n[i],
            gravity=case["g"],
            ground=ref.Ground(0.0, 0.7, case["mu_d"], case["c"]),
            rest_speed=case["rest"],
            t_max=t_max,
        )
        assert r.state == "moving"
        v_end = got["end_v"][i]
        ahead = v_end if np.linalg.norm(v_end) > 0 else g_t  # from rest it rolls down the fall line
        a = (g_t - case["c"] * (-case["g"] @ n[i]) * ahead / np.linalg.norm(ahead)) / (1 + K)
        tau = t_max - got["elapsed"][i]
        x = got["end_x"][i] + v_end * tau + 0.5 * a * tau**2
        scale = r.path_length + np.linalg.norm(case["v"]) * t_max
        assert np.linalg.norm(x - r.x) <= CLOSE[precision] * scale, (i, x, r.x)
        assert np.linalg.norm(v_end + a * tau - r.v) <= CLOSE[precision] * (np.linalg.norm(case["v"]) + G * t_max)


def test_a_drive_across_the_slip_is_left_to_integration(device):
    """On a slope, a slip across the fall line turns as it goes: no closed form, exact = 0, the
    state returned is the phase's start."""
    n = np.array([0.0, 1.0, 0.0])
    g = G * np.array([0.3, -1.0, 0.0]) / math.hypot(0.3, 1.0)
    got = probe("float64", device, x=[0, R, 0], v=[0, 0, 5.0], w=0, n=n, applied=g, c=0.5)
    assert (got["end_mode"][0], got["end_exact"][0], got["elapsed"][0]) == (SLIDING, 0, 0)
    np.testing.assert_array_equal(got["end_v"][0], [0, 0, 5.0])


# --------------------------------------------------------------------------- criteria


def test_switch_criteria(device):
    """Lift-off when the net normal force pulls away; rest below the rest speed where the slope
    cannot restart the pellet; separation above sqrt(2 R N/m)."""
    n = np.array([0.0, 1.0, 0.0])
    rolling = dict(x=[0, R, 0], v=[[0.05, 0, 0]] * 6, w=np.cross(n, [0.05, 0, 0]) / R, n=n)
    slopes = [[0, -G, 0], [0, 0.1, 0], [0, -G, 0], [2, -G, 0], [0.9, -G, 0], [0, -G, 0]]
    applied = slopes[:5] + [[-3, -G, 0]]  # the last: drag against the motion on a level plane
    got = probe("float64", device, **rolling, applied=applied, gravity=slopes, c=0.1, rest=[0.1, 0.1, 0.01, 0.1, 0.1, 0.1])
    # drive 2 > c N/m = 0.98 > 0.9; drag, which vanishes at rest, cannot restart a pellet
    assert got["mode"].tolist() == [REST, FLIGHT, ROLLING, ROLLING, REST, REST]
    speed = math.sqrt(2 * R * G)
    got = probe(
        "float64", device, x=[0, R, 0], v=[[1, 0, 0]] * 2, w=0, n=n, applied=[0, -G, 0], rebound=[0.99 * speed, 1.01 * speed]
    )
    np.testing.assert_allclose(got["separation"], speed, rtol=1e-12)
    assert got["separates"].tolist() == [0, 1]


# --------------------------------------------------------------------------- invariants


@pytest.mark.parametrize("precision", PRECISIONS)
def test_arc_length_matches_quadrature(precision, device):
    """The closed-form path length of x = v t + a t^2 / 2, through a turn-back (v against a) too."""
    from scipy.integrate import quad

    rng = np.random.default_rng(3)
    m = 60
    v, a = rng.normal(0, 10, (m, 3)), rng.normal(0, 5, (m, 3))
    v[::3] = -rng.uniform(0.5, 2, (len(v[::3]), 1)) * a[::3]  # straight back through zero speed
    v[1::6] *= 1e-6
    t = rng.uniform(0.01, 8, m)
    scalar, vec3, _probe, arc = _kernels(precision)
    out = wp.zeros(m, dtype=scalar, device=device)
    arrays = [wp.array(q.astype(precision), dtype=vec3, device=device) for q in (v, a)]
    wp.launch(arc, dim=m, inputs=[*arrays, wp.array(t.astype(precision), device=device)], outputs=[out], device=device)
    for i in range(m):
        turn = -(v[i] @ a[i]) / (a[i] @ a[i])
        points = [turn] if 0 < turn < t[i] else None
        want = quad(lambda s, i=i: np.linalg.norm(v[i] + a[i] * s), 0, t[i], points=points, epsabs=0, epsrel=1e-13)[0]
        assert out.numpy()[i] == pytest.approx(want, rel=CLOSE[precision]), i


@pytest.mark.parametrize("precision", PRECISIONS)
def test_closed_forms_never_gain_energy_nor_leave_the_plane(precision, device):
    """follow_on_plane: the end state's energy (kinetic, spin and height) never above the start's;
    the centre stays at height R; the slip ends zero, never reversed."""
    cases = _fall_line_cases(np.random.default_rng(11), 40)
    stack, got = _probe_cases(precision, device, cases)
    n, g = stack["n"], stack["g"]

    def energy(x, v, w):
        return 0.5 * np.einsum("ij,ij->i", v, v) + 0.5 * K * R**2 * np.einsum("ij,ij->i", w, w) - np.einsum("ij,ij->i", g, x)

    before, after = energy(R * n, stack["v"], stack["w"]), energy(got["end_x"], got["end_v"], got["end_w"])
    assert (after <= before + CLOSE[precision] * np.abs(before)).all()
    rounding = 256 * np.finfo(precision).eps * (np.abs(got["end_x"]).max(axis=1) + got["path"])  # a few phases' steps
    assert (np.abs(np.einsum("ij,ij->i", got["end_x"], n) - R) <= rounding).all()
    slip = got["end_v"] - R * np.cross(got["end_w"], n)
    assert np.abs(slip).max() <= CLOSE[precision] * (np.abs(stack["v"]).max() + R * np.abs(stack["w"]).max())


def test_reference_invariants_with_impacts_and_air():
    """The reference from random flights in vacuum and in air, any plane: energy (with gravity's
    potential) never rises along the surface, and in vacuum not in flight either; the centre never
    below R; on a level plane in vacuum the slip keeps its direction while it falls to zero."""
    from warp_ricochet.scene.schema import Air

    rng = np.random.default_rng(5)
    for i in range(8):
        n = _random_normals(rng, 1)[0]
        g = G * (-0.95 * n + 0.05 * _frame(n)[0]) if i % 2 else -G * n
        x0 = (R + rng.uniform(0, 0.5)) * n
        v0 = rng.normal(0, 20, 3) - 10 * n
        w0 = rng.normal(0, 3e3, 3)
        air = Air(wind=(0.0, 0.0, 0.0)) if i >= 4 else None
        r = ref.follow(
            x0, v0, w0, radius=R, normal=n, gravity=g, ground=ref.Ground(0.4, 0.5, 0.4, 0.2), rest_speed=0.05, air=air, t_max=60.0
        )
        assert r.state == "rest", (i, r.state)
        for phase in r.phases:
            for sol in phase.sols:
                ts = np.linspace(sol.t_min, sol.t_max, 200)
                y = sol(ts)
                e = 0.5 * (y[3:6] ** 2).sum(0) + 0.5 * K * R**2 * (y[6:9] ** 2).sum(0) - g @ y[0:3]
                if phase.mode != "flight" or air is None:
                    assert (np.diff(e) <= 1e-9 * np.abs(e).max()).all(), (i, phase.mode)
                assert (n @ y[0:3] >= R * (1 - 1e-9)).all()
                if phase.mode == "sliding" and air is None and i % 2 == 0:
                    slip = y[3:6] - R * np.cross(y[6:9].T, n).T
                    assert (np.einsum("ij,i->j", slip, slip[:, 0]) >= -1e-9 * (slip[:, 0] @ slip[:, 0])).all()
                    assert (np.diff(np.linalg.norm(slip, axis=0)) <= 1e-9).all()


def test_reference_applies_the_criteria():
    """The reference: a drop separates while v_n' > sqrt(2 R g) (E = 0.2: 1 -> 0.2 -> 0.04 m/s, two
    impacts; E = 0.1: one); a rolling pellet on a slope steeper than atan(7/2 mu_s) slides, at
    g (sin - mu_d cos); strong backspin in air lifts a pellet off the plane (Magnus lift above g)."""
    from warp_ricochet.scene.schema import Air

    for restitution, impacts in ((0.2, 2), (0.1, 1)):
        r = ref.follow([0, R, 0], [0, -1.0, 0], [0, 0, 0], radius=R, ground=ref.Ground(restitution, 0.5, 0.4, 0.1))
        assert (r.state, r.impacts, r.x[1]) == ("rest", impacts, R)
    theta = math.radians(70)
    n = np.array([-math.sin(theta), math.cos(theta), 0.0])
    down = np.array([-math.cos(theta), -math.sin(theta), 0.0])
    v = 1.0 * down
    r = ref.follow(R * n, v, np.cross(n, v) / R, radius=R, normal=n, ground=ref.Ground(0.0, 0.5, 0.4, 0.0), t_max=1.0)
    assert r.state == "moving" and [p.mode for p in r.phases] == ["sliding"]
    assert (r.v - v) @ down == pytest.approx(G * (math.sin(theta) - 0.4 * math.cos(theta)), rel=1e-10)
    r = ref.follow(
        [0, R, 0],
        [187, 0, 0],
        [0, 0, 1.5e5],
        radius=R,
        density=7000.0,
        air=Air(),
        ground=ref.Ground(0.3, 0.5, 0.4, 0.05),
        rest_speed=0.13,
    )
    assert r.phases[0].mode == "flight" and r.impacts >= 1 and r.state == "rest"
