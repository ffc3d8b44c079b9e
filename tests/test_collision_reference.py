"""The event-driven collision reference: the pair law (invariants on random inputs, closed forms,
the plane-law limit), pair contact times, and the solver (agreement with reference.simulate when
nothing touches, analytic pair collisions, conservation in a free cloud, the TC model, the event
cap, determinism). Everything is float64 NumPy; the whole file runs in a few seconds."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from warp_ricochet.reference import ballistic as reference
from warp_ricochet.reference.collisions import (
    pair_contact_time,
    pair_law,
    simulate_collisions,
)
from warp_ricochet.scene import scene_from_dict

D = 0.0025  # m
R = D / 2
RHO = 7000.0  # kg/m^3
K = 0.4
MASS = RHO * 4.0 / 3.0 * math.pi * R**3  # kg, as reference.simulate computes it
INERTIA = K * MASS * R * R
GRAVITY = np.array([0.0, -9.81, 0.0])
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.4, "mu_s": 0.5, "mu_d": 0.4}
PAIR = {"restitution": 0.5, "mu_s": 0.3, "mu_d": 0.2, "contact_duration": 1e-6}


def make_scene(surfaces=(), gravity=GRAVITY, bounces=1, duration=0.0, **collisions):
    raw = {
        "shot": {"count": 1, "diameter": D, "density": RHO, "speed": 1.0},
        "surfaces": list(surfaces),
        "physics": {"gravity": list(map(float, gravity)), "bounces": bounces, "impact_duration": duration},
    }
    if collisions:
        raw["collisions"] = collisions
    return scene_from_dict(raw)


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def law(xa, va, wa, xb, vb, wb, *, ma=MASS, mb=MASS, Ra=R, Rb=R, E=0.5, mu_s=0.3, mu_d=0.2):
    return pair_law(
        xa,
        va,
        wa,
        xb,
        vb,
        wb,
        mass_a=ma,
        mass_b=mb,
        radius_a=Ra,
        radius_b=Rb,
        restitution=E,
        mu_s=mu_s,
        mu_d=mu_d,
        inertia_factor=K,
    )


# ---------------------------------------------------------------- the pair law: invariants

finite = {"allow_nan": False, "allow_infinity": False}
TINY = 1e-300  # absolute floor of the rounding tolerances


def component(lo, hi):
    """0 or lo <= |x| <= hi: no magnitudes whose squares underflow (1e-200 m/s is not physics)."""
    return st.one_of(st.just(0.0), st.floats(lo, hi), st.floats(-hi, -lo))


vec = st.tuples(*[component(1e-6, 100.0)] * 3).map(np.array)
spin = st.tuples(*[component(1e-3, 1e4)] * 3).map(np.array)
direction = st.tuples(*[st.floats(-1.0, 1.0, **finite)] * 3).filter(lambda t: np.linalg.norm(t) > 0.1).map(unit)


@st.composite
def impacts(draw, overlap=True):
    """Two spheres in contact (or overlapping: s in [0.5, 1]) whose centres approach."""
    Ra, Rb = draw(st.floats(1e-4, 1e-2)), draw(st.floats(1e-4, 1e-2))
    ma, mb = draw(st.floats(1e-6, 1.0)), draw(st.floats(1e-6, 1.0))
    n = draw(direction)
    s = draw(st.floats(0.5, 1.0)) if overlap else 1.0
    xa = draw(vec) / 100.0  # within 1 m of the origin: angular momentum about it is not trivial
    xb = xa + s * (Ra + Rb) * n
    # the normal and arm scale as the law sees them (x_b - x_a carries the rounding of the positions)
    d = np.linalg.norm(xb - xa)
    n, s = (xb - xa) / d, d / (Ra + Rb)
    va, vb = draw(vec), draw(vec)
    closing = np.dot(vb - va, n)
    if closing > 0:  # mirror the normal relative velocity so the spheres approach
        vb = vb - 2.0 * closing * n
    mu_s = draw(st.floats(0.0, 2.0))
    return {
        "xa": xa,
        "va": va,
        "wa": draw(spin),
        "xb": xb,
        "vb": vb,
        "wb": draw(spin),
        "ma": ma,
        "mb": mb,
        "Ra": Ra,
        "Rb": Rb,
        "E": draw(st.floats(0.0, 1.0)),
        "mu_s": mu_s,
        "mu_d": mu_s * draw(st.floats(0.0, 1.0)),
        "n": n,
        "s": s,
    }


def apply(c):
    return law(
        c["xa"],
        c["va"],
        c["wa"],
        c["xb"],
        c["vb"],
        c["wb"],
        ma=c["ma"],
        mb=c["mb"],
        Ra=c["Ra"],
        Rb=c["Rb"],
        E=c["E"],
        mu_s=c["mu_s"],
        mu_d=c["mu_d"],
    )


def energy(c, va, wa, vb, wb):
    return (
        0.5 * c["ma"] * va @ va
        + 0.5 * c["mb"] * vb @ vb
        + 0.5 * K * c["ma"] * c["Ra"] ** 2 * wa @ wa
        + 0.5 * K * c["mb"] * c["Rb"] ** 2 * wb @ wb
    )


def contact_velocity(c, va, wa, vb, wb):
    """u = v_b - v_a - s R_b (w_b x n) - s R_a (w_a x n)."""
    n, s = c["n"], c["s"]
    return vb - va - s * c["Rb"] * np.cross(wb, n) - s * c["Ra"] * np.cross(wa, n)


@settings(max_examples=300, deadline=None)
@given(c=impacts())
def test_pair_law_conserves_momenta_and_never_adds_energy(c):
    r = apply(c)
    assume(r.collided)
    ma, mb, Ia, Ib = c["ma"], c["mb"], K * c["ma"] * c["Ra"] ** 2, K * c["mb"] * c["Rb"] ** 2
    impulse = mb * (r.velocity_b - c["vb"])  # P on b
    # linear momentum, to rounding of its terms
    p0, p1 = ma * c["va"] + mb * c["vb"], ma * r.velocity_a + mb * r.velocity_b
    scale = ma * np.abs(c["va"]).sum() + mb * np.abs(c["vb"]).sum() + np.abs(impulse).sum()
    assert np.abs(p1 - p0).max() <= 1e-13 * scale + TINY
    # angular momentum about the origin, exactly also when overlapping (s < 1): the arms sum to d
    L0 = ma * np.cross(c["xa"], c["va"]) + mb * np.cross(c["xb"], c["vb"]) + Ia * c["wa"] + Ib * c["wb"]
    L1 = (
        ma * np.cross(c["xa"], r.velocity_a)
        + mb * np.cross(c["xb"], r.velocity_b)
        + Ia * r.angular_velocity_a
        + Ib * r.angular_velocity_b
    )
    lscale = (
        (np.abs(c["xa"]).sum() + np.abs(c["xb"]).sum()) * scale
        + Ia * np.abs(c["wa"]).sum()
        + Ib * np.abs(c["wb"]).sum()
        + (c["Ra"] + c["Rb"]) * np.abs(impulse).sum()
    )
    assert np.abs(L1 - L0).max() <= 1e-13 * lscale + TINY
    # kinetic energy never rises; the closed-form loss is the drop, to rounding of the energies
    e0 = energy(c, c["va"], c["wa"], c["vb"], c["wb"])
    e1 = energy(c, r.velocity_a, r.angular_velocity_a, r.velocity_b, r.angular_velocity_b)
    assert r.energy_lost >= 0.0
    assert e1 <= e0 * (1 + 1e-13) + TINY
    assert abs((e0 - e1) - r.energy_lost) <= 1e-12 * e0 + TINY


@settings(max_examples=300, deadline=None)
@given(c=impacts())
def test_pair_law_normal_restitution_and_stick_slip(c):
    r = apply(c)
    assume(r.collided)
    n = c["n"]
    un0 = np.dot(c["vb"] - c["va"], n)
    un1 = np.dot(r.velocity_b - r.velocity_a, n)
    vscale = np.abs(c["va"]).sum() + np.abs(c["vb"]).sum()
    assert abs(un1 + c["E"] * un0) <= 1e-13 * vscale + TINY  # u_n' = -E u_n
    u0 = contact_velocity(c, c["va"], c["wa"], c["vb"], c["wb"])
    u1 = contact_velocity(c, r.velocity_a, r.angular_velocity_a, r.velocity_b, r.angular_velocity_b)
    ut0, ut1 = u0 - (u0 @ n) * n, u1 - (u1 @ n) * n
    uscale = vscale + c["s"] * (c["Ra"] * np.abs(c["wa"]).sum() + c["Rb"] * np.abs(c["wb"]).sum())
    stick = K / (K + c["s"] ** 2)
    if not r.slipped:  # the contact points stop sliding; the sticking impulse was within mu_s P_n
        assert np.abs(ut1).max() <= 1e-12 * uscale + TINY
        assert stick * np.linalg.norm(ut0) <= c["mu_s"] * (1 + c["E"]) * -un0 * (1 + 1e-12) + 1e-12 * uscale + TINY
    else:  # kinetic friction mu_d P_n along -e_t: the slip slows along its own direction, never reverses
        drop = (1.0 / stick) * c["mu_d"] * (1 + c["E"]) * -un0
        np.testing.assert_allclose(ut1, ut0 * (1.0 - drop / np.linalg.norm(ut0)), rtol=0, atol=1e-12 * uscale + TINY)
        assert drop <= np.linalg.norm(ut0) * (1 + 1e-12) + TINY


def test_pair_law_leaves_separating_and_coincident_spheres_alone():
    xa, xb = np.zeros(3), np.array([D, 0.0, 0.0])
    r = law(xa, [-1.0, 5.0, 0.0], [0, 0, 100.0], xb, [1.0, 0, 0], [0, 0, 0])
    assert not r.collided and not r.slipped and r.energy_lost == 0.0
    np.testing.assert_array_equal(r.velocity_a, [-1.0, 5.0, 0.0])
    np.testing.assert_array_equal(r.angular_velocity_a, [0, 0, 100.0])
    r = law(xa, [1.0, 0, 0], [0, 0, 0], xa, [-1.0, 0, 0], [0, 0, 0])  # d = 0: no normal
    assert not r.collided
    np.testing.assert_array_equal(r.velocity_b, [-1.0, 0, 0])


# ---------------------------------------------------------------- the pair law: closed forms


@pytest.mark.parametrize("vb", [[0.0, 0.0, 0.0], [-3.0, 0.0, 0.0]])
def test_head_on_equal_spheres_elastic_exchange_velocities(vb):
    va = np.array([7.0, 0.0, 0.0])
    r = law(np.zeros(3), va, np.zeros(3), [D, 0, 0], vb, np.zeros(3), E=1.0)
    np.testing.assert_allclose(r.velocity_a, vb, atol=1e-14)
    np.testing.assert_allclose(r.velocity_b, va, atol=1e-14)
    assert r.energy_lost == pytest.approx(0.0, abs=1e-18)
    np.testing.assert_array_equal(r.angular_velocity_a, 0.0)


def oblique(theta, **kw):
    """a at the origin moving +x at V hits b at rest, centre at angle theta: n = (cos, sin, 0)."""
    V = 10.0
    n = np.array([math.cos(theta), math.sin(theta), 0.0])
    return V, n, law(np.zeros(3), [V, 0, 0], np.zeros(3), D * n, np.zeros(3), np.zeros(3), **kw)


def test_oblique_equal_spheres_without_spin_sticking():
    # u = -V x, u_n = -V cos, u_t = -V sin t with t = (sin, -cos, 0); stick: P/m* = (1+E)V cos n + 2/7 V sin t,
    # v_b' = P/m_b = P/(2 m*); w_a' = w_b' = -(n x P)/(k m R) = 5/14 V sin / R z  (n x t = -z)
    theta, E = 0.6, 0.3
    V, n, r = oblique(theta, E=E, mu_s=10.0, mu_d=10.0)
    t = np.array([math.sin(theta), -math.cos(theta), 0.0])
    p = (1 + E) * V * math.cos(theta) * n + 2.0 / 7.0 * V * math.sin(theta) * t
    assert not r.slipped
    np.testing.assert_allclose(r.velocity_b, p / 2, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(r.velocity_a, [V, 0, 0] - p / 2, rtol=1e-13, atol=1e-13)
    w = 5.0 / 14.0 * V * math.sin(theta) / R * np.array([0, 0, 1.0])
    np.testing.assert_allclose(r.angular_velocity_a, w, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(r.angular_velocity_b, w, rtol=1e-13, atol=1e-9)
    u = r.velocity_b - r.velocity_a - R * np.cross(r.angular_velocity_b, n) - R * np.cross(r.angular_velocity_a, n)
    assert abs(u @ t) <= 1e-13 * V  # the contact points no longer slide
    # energy: m*/2 [(1-E^2) u_n^2 + 2/7 |u_t|^2], m* = m/2
    lost = MASS / 4 * ((1 - E * E) * (V * math.cos(theta)) ** 2 + 2.0 / 7.0 * (V * math.sin(theta)) ** 2)
    assert r.energy_lost == pytest.approx(lost, rel=1e-13)


def test_oblique_equal_spheres_without_spin_slipping():
    # slip: the tangential change of the relative contact velocity's impulse is mu_d (1+E) |u_n|
    theta, E, mu_d = 1.1, 0.5, 0.1
    V, n, r = oblique(theta, E=E, mu_s=0.15, mu_d=mu_d)
    t = np.array([math.sin(theta), -math.cos(theta), 0.0])
    un = V * math.cos(theta)
    p = (1 + E) * un * n + mu_d * (1 + E) * un * t
    assert r.slipped
    np.testing.assert_allclose(r.velocity_b, p / 2, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(r.velocity_a, [V, 0, 0] - p / 2, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(
        r.angular_velocity_b, 5.0 / 4.0 * mu_d * (1 + E) * un / R * np.array([0, 0, 1.0]), rtol=1e-13, atol=1e-9
    )
    u = r.velocity_b - r.velocity_a - R * np.cross(r.angular_velocity_b, n) - R * np.cross(r.angular_velocity_a, n)
    # u_t' = u_t + (k+1)/k * mu_d (1+E) u_n t  (along t, towards zero, not past it)
    assert u @ t == pytest.approx(-V * math.sin(theta) + 3.5 * mu_d * (1 + E) * un, rel=1e-12)


@pytest.mark.parametrize("mu_s, slips", [(10.0, False), (0.01, True)])
def test_head_on_with_spin(mu_s, slips):
    # a spins about z at W, head-on along x: u = -V x - R W y; stick: P_t/m* = 2/7 R W y,
    # v_b' = ((1+E) V/2, R W/7, 0), w_a' = 9/14 W z, w_b' = -5/14 W z.
    # slip: P_t/m* = mu_d (1+E) V y.
    V, W, E, mu_d = 5.0, 2000.0, 0.5, 0.01
    r = law(np.zeros(3), [V, 0, 0], [0, 0, W], [D, 0, 0], np.zeros(3), np.zeros(3), E=E, mu_s=mu_s, mu_d=mu_d)
    assert bool(r.slipped) == slips
    pt = mu_d * (1 + E) * V if slips else 2.0 / 7.0 * R * W
    np.testing.assert_allclose(r.velocity_b, [(1 + E) * V / 2, pt / 2, 0], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(r.velocity_a, [V - (1 + E) * V / 2, -pt / 2, 0], rtol=1e-13, atol=1e-13)
    dw = -5.0 / 4.0 * pt / R  # -(n x P)/(k m R) with P = m/2 pt y
    np.testing.assert_allclose(r.angular_velocity_a, [0, 0, W + dw], rtol=1e-13)
    np.testing.assert_allclose(r.angular_velocity_b, [0, 0, dw], rtol=1e-13)
    if not slips:
        assert W + dw == pytest.approx(9.0 / 14.0 * W, rel=1e-13)


@settings(max_examples=200, deadline=None)
@given(c=impacts(overlap=False), mb=st.sampled_from([math.inf, 1e30]))
def test_infinite_mass_b_is_the_plane_law(c, mb):
    # b fixed (no motion, no spin, infinite mass): a hits a plane with normal -n (towards a)
    c = {**c, "mb": mb, "vb": np.zeros(3), "wb": np.zeros(3)}
    if np.dot(c["va"], c["n"]) < 0:  # a must move towards b (into the plane)
        c["va"] = c["va"] - 2.0 * np.dot(c["va"], c["n"]) * c["n"]
    r = apply(c)
    assume(r.collided)
    v, w, slipped = reference.impact_law(
        c["va"][None],
        c["wa"][None],
        -c["n"],
        radius=c["Ra"],
        restitution=c["E"],
        mu_s=c["mu_s"],
        mu_d=c["mu_d"],
        gravity=(0.0, 0.0, 0.0),
        duration=0.0,
    )
    # the stick/slip choice may differ only on its boundary, by rounding; elsewhere it must agree
    u = contact_velocity(c, c["va"], c["wa"], np.zeros(3), np.zeros(3))
    closing = -np.dot(u, c["n"])
    sliding = np.linalg.norm(u + closing * c["n"])
    margin = K / (1 + K) * sliding - c["mu_s"] * (1 + c["E"]) * closing
    assume(abs(margin) > 1e-9 * (sliding + closing) or bool(r.slipped) == bool(slipped[0]))
    assert bool(r.slipped) == bool(slipped[0])
    # the plane law projects v on its frame (e_t from v_t): ill-conditioned when |v_t| << |v|, so the
    # tolerance grows as eps |v|^2 / |v_t| there
    vscale = np.abs(c["va"]).sum() + c["Ra"] * np.abs(c["wa"]).sum()
    tol = 1e-13 * vscale + (1e-15 * vscale**2 / sliding if sliding > 0 else 0.0) + TINY
    np.testing.assert_allclose(r.velocity_a, v[0], rtol=0, atol=tol)
    np.testing.assert_allclose(r.angular_velocity_a, w[0], rtol=0, atol=tol / c["Ra"])
    np.testing.assert_allclose(r.velocity_b, 0.0, rtol=0, atol=1e-25 * vscale)  # exactly 0 for m_b = inf
    np.testing.assert_allclose(r.angular_velocity_b, 0.0, rtol=0, atol=1e-25 * vscale / c["Rb"])


# ---------------------------------------------------------------- pair contact times


def test_pair_contact_time_closed_forms():
    kw = {"diameter": D, "position_scale": 1.0, "speed_scale": 20.0}
    # head-on from L apart at closing speed 10: (L - D) / 10
    assert pair_contact_time(np.array([0.1, 0, 0]), np.array([-10.0, 0, 0]), **kw) == pytest.approx((0.1 - D) / 10, rel=1e-14)
    # offset b: |(L - u t, b)| = D  ->  t = (L - sqrt(D^2 - b^2)) / u
    b = 0.6 * D
    t = pair_contact_time(np.array([0.1, b, 0]), np.array([-10.0, 0, 0]), **kw)
    assert t == pytest.approx((0.1 - math.sqrt(D * D - b * b)) / 10, rel=1e-13)
    # misses, separating, parallel: never
    assert pair_contact_time(np.array([0.1, 1.01 * D, 0]), np.array([-10.0, 0, 0]), **kw) == math.inf
    assert pair_contact_time(np.array([0.1, 0, 0]), np.array([10.0, 0, 0]), **kw) == math.inf
    assert pair_contact_time(np.array([0.1, 0, 0]), np.zeros(3), **kw) == math.inf
    # touching or overlapping: at once if approaching, never if separating
    assert pair_contact_time(np.array([0.7 * D, 0, 0]), np.array([-1.0, 0, 0]), **kw) == 0.0
    assert pair_contact_time(np.array([0.7 * D, 0, 0]), np.array([1.0, 0, 0]), **kw) == math.inf
    assert pair_contact_time(np.array([D, 0, 0]), np.array([-1.0, 0.5, 0]), **kw) == 0.0


# ---------------------------------------------------------------- the solver: no contacts = reference.simulate


def assert_matches_reference(scene, position, velocity, spin):
    position, velocity = np.asarray(position, float), np.asarray(velocity, float)
    spin = np.zeros_like(position) if spin is None else spin
    out, stats = simulate_collisions(scene, position, velocity, spin, **PAIR, check_caches=True)
    ref, ref_stats = reference.simulate(scene, position, velocity, spin)
    assert (out["collisions.count"] == 0).all() and np.isnan(out["collisions.last_time"]).all()
    assert stats["pair_collisions"] == 0 and stats["collided_fraction"] == 0 and stats["pair_energy_lost"] == 0
    for key, value in ref.items():
        assert out[key].dtype == value.dtype and out[key].shape == value.shape, key
        if value.dtype.kind == "f":
            scale = np.nanmax(np.abs(np.where(np.isfinite(value), value, np.nan)), initial=1.0)
            np.testing.assert_allclose(out[key], value, rtol=1e-12, atol=1e-12 * scale, err_msg=key)
        else:
            np.testing.assert_array_equal(out[key], value, err_msg=key)
    for key, value in ref_stats.items():
        assert stats[key] == pytest.approx(value, rel=1e-12, abs=1e-300, nan_ok=True), key
    return out, stats


def test_sparse_cloud_matches_reference_simulate():
    # 25 pellets 1 m apart flying radially apart (their paths never cross), onto the ground and a
    # wall with E = 0 (some rest on it), 3 bounces, spin, impact duration: every plane branch
    rng = np.random.default_rng(7)
    gx, gz = np.meshgrid(np.arange(-2.0, 3.0), np.arange(-2.0, 3.0))
    position = np.stack([gx.ravel(), 1.0 + rng.uniform(0, 1, gx.size), gz.ravel()], axis=1)
    velocity = np.stack([3.0 * gx.ravel(), rng.uniform(-5, 2, gx.size), 3.0 * gz.ravel()], axis=1)
    spin = rng.normal(0, 100, (gx.size, 3))
    wall = {"point": [3.0, 0, 0], "normal": [-1.0, 0, 0], "restitution": 0.0, "mu_s": 0.3, "mu_d": 0.3}
    scene = make_scene([GROUND, wall], bounces=3, duration=1e-5)
    out, stats = assert_matches_reference(scene, position, velocity, spin)
    assert stats["landed"] > 0 and (out["landing.surface"] == 1).any()  # some rest on the wall


def test_sparse_cloud_without_gravity_escapes_and_misses_as_reference():
    position = [[0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [2.0, 1.0, 0.0]]
    velocity = [[0.0, 1.0, 0.0], [0.5, -1.0, 0.0], [1.0, -2.0, 0.0]]  # misses, escapes, escapes
    _, stats = assert_matches_reference(make_scene([GROUND], gravity=(0, 0, 0), bounces=2), position, velocity, None)
    assert stats["missed"] == 1 and stats["escaped"] == 2


# ---------------------------------------------------------------- the solver: pair collisions


def test_head_on_pair_in_free_space_collides_at_the_analytic_time():
    L, V, E = 0.1, 10.0, 0.5
    out, stats = simulate_collisions(make_scene(), [[0, 1, 0], [L, 1, 0]], [[V, 0, 0], [-V, 0, 0]], **{**PAIR, "restitution": E})
    tc = (L - D) / (2 * V)
    np.testing.assert_allclose(out["collisions.last_time"], tc, rtol=1e-14)
    assert stats["last_collision_time"] == pytest.approx(tc, rel=1e-14) and stats["end_time"] == stats["last_collision_time"]
    np.testing.assert_array_equal(out["collisions.count"], [1, 1])
    np.testing.assert_allclose(out["final.time"], tc, rtol=1e-14)
    np.testing.assert_allclose(out["final.velocity"], [[-E * V, -9.81 * tc, 0], [E * V, -9.81 * tc, 0]], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(np.diff(out["final.position"][:, 0]), D, rtol=1e-12)
    assert stats["pair_energy_lost"] == pytest.approx(0.5 * (MASS / 2) * (1 - E * E) * (2 * V) ** 2, rel=1e-13)
    assert stats["collided_fraction"] == 1.0 and stats["pair_collisions"] == 1
    assert np.isinf(out["landing.time"]).all() and stats["hits"] == 0


def test_head_on_pair_collides_in_mid_air_then_lands_where_the_rebound_takes_it():
    # both fall from h (no vertical speed): they meet at tc, rebound along x, hit the ground at the
    # time of a drop from h; a's impact point is x_a(tc) - E V (t_hit - tc)
    L, V, E, h = 0.1, 10.0, 0.5, 1.0
    scene = make_scene([{**GROUND, "restitution": 0.0, "mu_s": 0.0, "mu_d": 0.0}], bounces=1)
    out, stats = simulate_collisions(scene, [[0, h, 0], [L, h, 0]], [[V, 0, 0], [-V, 0, 0]], **{**PAIR, "restitution": E})
    tc = (L - D) / (2 * V)
    t_hit = math.sqrt(2 * (h - R) / 9.81)
    np.testing.assert_allclose(out["impact.time"][:, 0], t_hit, rtol=1e-13)
    x_hit = V * tc - E * V * (t_hit - tc)
    np.testing.assert_allclose(out["impact.position"][:, 0, 0], [x_hit, L - x_hit], rtol=1e-12)
    np.testing.assert_allclose(
        out["impact.velocity_before"][:, 0], [[-E * V, -9.81 * t_hit, 0], [E * V, -9.81 * t_hit, 0]], rtol=1e-12
    )
    # E = 0 on the ground: they stay there (rest), landing with zero range at the impact point
    np.testing.assert_array_equal(out["landing.surface"], [0, 0])
    np.testing.assert_allclose(out["landing.range"], 0.0, atol=1e-15)
    assert stats["landed"] == 2


def test_pellet_hit_after_its_bounce_returns_on_its_new_parabola():
    # a drops onto the ground, bounces up; b meets it side-on at tc (after the bounce), frictionless:
    # a's vertical motion is unchanged, so it is back on the ground at t1 + 2 v_up / g exactly as
    # without b (the plane it left is no longer 'touching': its gap is computed afresh), and its
    # horizontal velocity is -(1 + E) V / 2.
    g, E_plane, E, V, h = 9.81, 0.5, 0.3, 2.0, 0.05
    scene = make_scene([{**GROUND, "restitution": E_plane, "mu_s": 0.0, "mu_d": 0.0}], bounces=2)
    t1 = math.sqrt(2 * (h - R) / g)
    v_up = E_plane * g * t1
    tc = t1 + 0.3 * v_up / g
    ya = R + v_up * (tc - t1) - 0.5 * g * (tc - t1) ** 2
    # b at tc: at (D, ya), velocity (-V, -1 m/s); back to t = 0 on its parabola (above the ground throughout)
    vb_y = -1.0
    yb0 = ya - vb_y * tc - 0.5 * g * tc**2
    assert yb0 > 2 * D
    pos = [[0.0, h, 0.0], [D + V * tc, yb0, 0.0]]
    vel = [[0.0, 0.0, 0.0], [-V, vb_y + g * tc, 0.0]]
    out, stats = simulate_collisions(scene, pos, vel, restitution=E, mu_s=0.0, contact_duration=0.0, check_caches=True)
    assert stats["pair_collisions"] == 1
    assert out["collisions.last_time"][0] == pytest.approx(tc, rel=1e-9)
    t2 = t1 + 2 * v_up / g
    assert out["impact.time"][0, 1] == pytest.approx(t2, rel=1e-9)
    assert out["impact.velocity_before"][0, 1, 0] == pytest.approx(-(1 + E) * V / 2, rel=1e-9)
    assert out["impact.position"][0, 1, 0] == pytest.approx(-(1 + E) * V / 2 * (t2 - tc), rel=1e-8)


def test_overlapping_pairs_collide_at_once_only_when_approaching():
    scene = make_scene(gravity=(0, 0, 0))
    out, stats = simulate_collisions(scene, [[0, 0, 0], [0.8 * D, 0, 0]], [[1.0, 0, 0], [0, 0, 0]], **PAIR)
    np.testing.assert_array_equal(out["collisions.last_time"], [0.0, 0.0])
    out, stats = simulate_collisions(scene, [[0, 0, 0], [0.8 * D, 0, 0]], [[-1.0, 0, 0], [0, 0, 0]], **PAIR)
    assert stats["pair_collisions"] == 0


def test_pellets_of_different_shots_pass_through_each_other():
    scene = make_scene([GROUND], bounces=2)
    pos, vel = [[0, 1, 0], [0.1, 1, 0]], [[10.0, 0, 0], [-10.0, 0, 0]]
    out, stats = simulate_collisions(scene, pos, vel, shot_index=[0, 1], **PAIR)
    ref, _ = reference.simulate(scene, np.array(pos, float), np.array(vel, float), np.zeros((2, 3)))
    assert stats["pair_collisions"] == 0
    np.testing.assert_allclose(out["landing.position"], ref["landing.position"], rtol=1e-12)
    _, stats = simulate_collisions(scene, pos, vel, shot_index=[1, 1], **PAIR)
    assert stats["pair_collisions"] == 1


def dense_cloud(side=5, spacing=1.15, seed=0):
    """side^3 pellets on a jittered cubic lattice (gaps ~0.05 D), converging, drifting, spinning."""
    rng = np.random.default_rng(seed)
    g = np.arange(side) - (side - 1) / 2
    position = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) * spacing * D
    position += rng.uniform(-0.05, 0.05, position.shape) * D
    velocity = np.array([30.0, 5.0, 0.0]) - 40.0 * position / (spacing * D * side) + rng.normal(0, 1.0, position.shape)
    return position, velocity, rng.normal(0, 500.0, position.shape)


def test_free_cloud_conserves_momenta_and_loses_energy_only_in_pair_collisions():
    position, velocity, spin = dense_cloud()
    n = len(position)
    out, stats = simulate_collisions(make_scene(), position, velocity, spin, **PAIR)
    assert stats["pair_collisions"] > n and stats["collided_fraction"] > 0.9
    T = out["final.time"][0]
    assert (out["final.time"] == T).all() and T == stats["end_time"] == stats["last_collision_time"]
    x, v, w = out["final.position"], out["final.velocity"], out["final.angular_velocity"]
    M = n * MASS
    # momentum: dP/dt = M g
    p0 = MASS * velocity.sum(0)
    np.testing.assert_allclose(MASS * v.sum(0) - M * GRAVITY * T, p0, rtol=0, atol=1e-13 * MASS * np.abs(velocity).sum())
    # angular momentum about the origin: dL/dt = M x_cm(t) x g
    xc, vc = position.mean(0), velocity.mean(0)
    L0 = MASS * np.cross(position, velocity).sum(0) + INERTIA * spin.sum(0)
    L1 = MASS * np.cross(x, v).sum(0) + INERTIA * w.sum(0)
    lscale = MASS * (np.abs(position).sum(1) * np.abs(velocity).sum(1)).sum() + INERTIA * np.abs(spin).sum()
    np.testing.assert_allclose(L1 - L0, M * np.cross(xc * T + vc * T * T / 2, GRAVITY), rtol=0, atol=1e-12 * lscale)

    # energy: kinetic + potential drops by exactly the pair losses
    def total(x, v, w):
        return 0.5 * MASS * (v * v).sum() + 0.5 * INERTIA * (w * w).sum() - MASS * (x @ GRAVITY).sum()

    e0 = total(position, velocity, spin)
    assert stats["pair_energy_lost"] > 0.05 * e0
    assert total(x, v, w) == pytest.approx(e0 - stats["pair_energy_lost"], rel=1e-12)
    # no overlaps
    gaps = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(n) * D
    assert gaps.min() >= D - 1e-9
    # each pellet's count and last time; every collision counted twice
    assert out["collisions.count"].sum() == 2 * stats["pair_collisions"]
    assert np.nanmax(out["collisions.last_time"]) == T


def test_cloud_onto_the_ground_keeps_exact_caches_and_ends():
    # pairs, impacts, resting and landings interleaved; the event caches are checked after every event
    position, velocity, spin = dense_cloud(side=3, seed=1)
    position = position + [0.0, 0.02, 0.0]
    velocity = velocity - [30.0, 20.0, 0.0]
    out, stats = simulate_collisions(make_scene([GROUND], bounces=3), position, velocity, spin, **PAIR, check_caches=True)
    assert stats["pair_collisions"] > 0 and stats["landed"] + stats["escaped"] + stats["missed"] == len(position)
    hit = out["impact.surface"] >= 0
    assert out["impact.position"][hit][:, 1] == pytest.approx(R, rel=1e-9)


# ---------------------------------------------------------------- TC model, event cap, determinism


@pytest.mark.parametrize("contact_duration", [0.0, 1e-3])
def test_zero_restitution_pellet_pressed_against_the_ground_ends(contact_duration):
    # a falls onto the ground with b right on top of it, faster: E = 0 between them, so a is squeezed
    # between b and the ground again and again (at the same instant); the TC model makes the repeat
    # collisions elastic, and every impact uses up a bounce, so it ends
    scene = make_scene([GROUND], bounces=16)
    pos, vel = [[0.0, R + 1e-4, 0.0], [0.0, 3 * R + 3e-4, 0.0]], [[0.0, -1.0, 0.0], [0.0, -3.0, 0.0]]
    out, stats = simulate_collisions(
        scene, pos, vel, restitution=0.0, mu_s=0.5, contact_duration=contact_duration, max_events=1000, check_caches=True
    )
    assert stats["pair_collisions"] >= 2 and stats["landed"] == 2
    assert (out["impact.surface"] == 0).all()  # all 16 bounces of both used up
    assert stats["pair_energy_lost"] > 0


@pytest.mark.parametrize("long_contact", [True, False])
def test_tc_model_makes_repeat_collisions_within_contact_duration_elastic(long_contact):
    # a (V) hits b (at rest, E = 0: a and b move on together at V/2); b reaches c (at rest, gap delta) after
    # delta / (V/2). Within contact_duration of its collision with a, that collision is elastic: b stops,
    # c takes V/2, a catches b at once (elastic again, a's last collision is within t_c too): (0, V/2, V/2).
    # Past it, b and c stick (E = 0) at V/4, then a (V/2) and b, b and c collide at once, elastic (same
    # instant): (V/4, V/4, V/2).
    V, delta = 1.0, 1e-4
    t_bc = delta / (V / 2)
    tc = 10 * t_bc if long_contact else 0.1 * t_bc
    pos = [[-0.01, 0, 0], [D, 0, 0], [2 * D + delta, 0, 0]]
    vel = [[V, 0, 0], [0, 0, 0], [0, 0, 0]]
    out, stats = simulate_collisions(make_scene(gravity=(0, 0, 0)), pos, vel, restitution=0.0, mu_s=0.0, contact_duration=tc)
    expected = [0, V / 2, V / 2] if long_contact else [V / 4, V / 4, V / 2]
    np.testing.assert_allclose(out["final.velocity"][:, 0], expected, atol=1e-12)
    assert stats["pair_collisions"] == (3 if long_contact else 4)
    first = (0.01 + D - D) / V  # a meets b
    assert stats["pair_energy_lost"] == pytest.approx(0.25 * MASS * V**2 * (1.0 if long_contact else 1.0 + 0.25), rel=1e-9)
    assert np.nanmin(out["collisions.last_time"]) == pytest.approx(first + t_bc, rel=1e-6)


def test_event_cap_raises_instead_of_hanging():
    position, velocity, spin = dense_cloud(side=3)
    with pytest.raises(RuntimeError, match="inelastic collapse"):
        simulate_collisions(make_scene(), position, velocity, spin, **PAIR, max_events=5)


def test_two_runs_are_identical():
    position, velocity, spin = dense_cloud(side=4, seed=3)
    scene = make_scene([GROUND], bounces=2)
    a, sa = simulate_collisions(scene, position, velocity, spin, **PAIR)
    b, sb = simulate_collisions(scene, position, velocity, spin, **PAIR)
    assert sa["pair_collisions"] > 0
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(a[key], b[key], equal_nan=True), key
    assert all(sa[k] == sb[k] or (math.isnan(sa[k]) and math.isnan(sb[k])) for k in sa)


# ---------------------------------------------------------------- parameters


def head_on_loss(**kw):
    _, stats = simulate_collisions(
        kw.pop("scene", make_scene(gravity=(0, 0, 0))), [[0, 0, 0], [0.1, 0, 0]], [[1.0, 0, 0], [-1.0, 0, 0]], **kw
    )
    return stats["pair_energy_lost"] / (0.5 * (MASS / 2) * 4.0)  # = 1 - E^2


def test_pair_parameters_from_keywords_collisions_or_scene():
    scene = make_scene(gravity=(0, 0, 0), restitution=0.8, mu_s=0.5, enabled=True)
    assert head_on_loss(scene=scene) == pytest.approx(1 - 0.8**2)
    section = SimpleNamespace(restitution=0.6, mu_s=0.2, mu_d=None, contact_duration=0.0)
    assert head_on_loss(scene=scene, collisions=section) == pytest.approx(1 - 0.6**2)
    assert head_on_loss(scene=scene, collisions=section, restitution=0.1) == pytest.approx(1 - 0.1**2)
    assert head_on_loss(restitution=0.0, mu_s=0.1) == pytest.approx(1.0)  # explicit mu_s: mu_d = mu_s
    bare = SimpleNamespace(
        shot=SimpleNamespace(diameter=D, density=RHO),
        surfaces=(),
        physics=SimpleNamespace(gravity=(0, 0, 0), impact_duration=0.0, bounces=1),
    )
    with pytest.raises(ValueError, match="restitution and mu_s"):
        head_on_loss(scene=bare)
    assert head_on_loss(scene=bare, restitution=1.0, mu_s=0.0) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError, match="mu_d"):
        head_on_loss(restitution=0.5, mu_s=0.1, mu_d=0.2)
    with pytest.raises(ValueError, match="restitution"):
        head_on_loss(restitution=1.5, mu_s=0.1)


def test_default_shot_index_is_the_scene_shots():
    raw = {"shot": {"count": 1, "shots": 2, "diameter": D, "density": RHO, "speed": 1.0}, "physics": {"gravity": [0, 0, 0]}}
    scene = scene_from_dict(raw)
    pos, vel = [[0, 0, 0], [0.1, 0, 0]], [[1.0, 0, 0], [-1.0, 0, 0]]
    assert simulate_collisions(scene, pos, vel, **PAIR)[1]["pair_collisions"] == 0  # one pellet per shot
    assert simulate_collisions(scene, pos, vel, shot_index=[0, 0], **PAIR)[1]["pair_collisions"] == 1
