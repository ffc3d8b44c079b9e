"""The impact law (eqs. 1-25): analytic cases, the planar case (27-35), a float64 NumPy
reference on random inputs, and invariants as property-based tests."""

import numpy as np
import pytest
from conftest import DEVICES
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import warp_ricochet as wr
from warp_ricochet.reference import ballistic as reference

R = 0.00125
RHO = 7000.0
K = 0.4  # I / (m R^2)
G = (0.0, -9.81, 0.0)
UP = np.array([0.0, 1.0, 0.0])


def law(v, w, n=UP, *, device=DEVICES[0], precision="float64", E=0.01, mu_s=0.5, mu_d=0.45, gravity=G, duration=0.0):
    return wr.impact(
        np.atleast_2d(v),
        np.atleast_2d(w),
        n,
        radius=R,
        density=RHO,
        restitution=E,
        mu_s=mu_s,
        mu_d=mu_d,
        gravity=gravity,
        duration=duration,
        device=device,
        precision=precision,
    )


def energy(v, w):
    """Kinetic energy per unit mass: |v|^2/2 + k R^2 |w|^2/2."""
    return 0.5 * (v * v).sum(-1) + 0.5 * K * R * R * (w * w).sum(-1)


# ---------------------------------------------------------------- analytic cases


def test_normal_incidence_rebounds_with_minus_E_vn(device):
    v, w, s = law([0.0, -300.0, 0.0], [0.0, 0.0, 0.0], E=0.3, device=device)
    np.testing.assert_allclose(v[0], [0.0, 90.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(w[0], 0.0)
    assert not s[0]


def test_slip_reduces_tangential_speed_by_mu_d_1_plus_E_vn(device):
    vt, vn, E, mu_d = 290.0, -290.0, 0.01, 0.045
    v, w, s = law([vt, vn, 0.0], [0, 0, 0], E=E, mu_s=0.05, mu_d=mu_d, device=device)
    assert s[0]
    # eq. (25) with dt = 0: v_t' = v_t - mu_d (1 + E) |v_n|;  eq. (24): omega' = -(mu_d N* R / I) e_o
    np.testing.assert_allclose(v[0], [vt - mu_d * (1 + E) * -vn, -E * vn, 0.0], rtol=1e-13)
    e_o = np.cross([1.0, 0.0, 0.0], UP)
    np.testing.assert_allclose(w[0], -(mu_d * (1 + E) * -vn / (K * R)) * e_o, rtol=1e-13)


def test_slip_with_impact_duration_uses_m_g_dt(device):
    vt, vn, E, mu_d, dt = 100.0, -50.0, 0.2, 0.1, 1e-3
    v, _, s = law([vt, vn, 0.0], [0, 0, 0], E=E, mu_s=0.1, mu_d=mu_d, duration=dt, device=device)
    assert s[0]
    normal_impulse = (1 + E) * -vn + 9.81 * dt  # N* / m of eq. (10)
    np.testing.assert_allclose(v[0, 0], vt - mu_d * normal_impulse, rtol=1e-13)
    np.testing.assert_allclose(v[0, 1], -E * vn, rtol=1e-13)


def test_stick_without_spin_keeps_five_sevenths_and_rolls(device):
    vt = 200.0
    v, w, s = law([vt, -10.0, 30.0], [0, 0, 0], mu_s=10.0, mu_d=10.0, device=device)
    assert not s[0]
    tangential = np.array([vt, 0.0, 30.0])
    np.testing.assert_allclose(v[0] - v[0] @ UP * UP, 5.0 / 7.0 * tangential, rtol=1e-13)
    # rolling without slip afterwards: v_p,t = v_t + omega x (-R n) = 0
    contact = v[0] + np.cross(w[0], -R * UP)
    np.testing.assert_allclose(contact - contact @ UP * UP, 0.0, atol=1e-9)


def test_zero_slip_velocity_is_unchanged_tangentially_and_finite(device):
    # a pellet already rolling: v_t = -omega x (-R n)  ->  no friction needed, no NaN.
    # (The slip velocity is zero up to rounding: FMA on a GPU can leave ~1e-14 m/s.)
    w_in = np.array([0.0, 0.0, -200.0 / R])
    v_in = np.array([200.0, -5.0, 0.0])
    for mu_s in (0.5, 0.0):
        v, w, s = law(v_in, w_in, mu_s=mu_s, mu_d=mu_s, device=device)
        assert np.isfinite(v).all() and np.isfinite(w).all()
        np.testing.assert_allclose(v[0], [200.0, 0.05, 0.0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(w[0], w_in, rtol=1e-12)
        if mu_s > 0:
            assert not s[0]  # the (vanishing) sticking impulse is far inside the friction cone
        rv, rw, _ = reference.impact_law(v_in[None], w_in[None], UP, radius=R, restitution=0.01, mu_s=mu_s, mu_d=mu_s)
        np.testing.assert_allclose(v[0], rv[0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(w[0], rw[0], rtol=1e-12)


def test_grazing_impact_is_finite_and_slips(device):
    v, w, s = law([400.0, -1e-9, 0.0], [0, 0, 0], mu_s=0.5, device=device)
    assert np.isfinite(v).all() and np.isfinite(w).all()
    assert s[0]
    assert v[0, 0] == pytest.approx(400.0, rel=1e-9)


def test_pellet_moving_away_is_unchanged(device):
    v_in = np.array([[3.0, 0.0, 1.0], [3.0, 2.0, 1.0]])
    w_in = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    v, w, s = law(v_in, w_in, device=device)
    np.testing.assert_array_equal(v, v_in)
    np.testing.assert_array_equal(w, w_in)
    assert not s.any()


def test_incoming_spin_can_reverse_the_slip_direction(device):
    # back-spin larger than v/R makes the contact point slide backwards: friction pushes forwards
    v, w, s = law([10.0, -100.0, 0.0], [0.0, 0.0, -3.0 * 10.0 / R], mu_s=0.01, mu_d=0.01, device=device)
    assert s[0]
    assert v[0, 0] > 10.0


@pytest.mark.parametrize("E", [0.0, 0.5, 1.0])
def test_planar_case_eqs_27_to_34(E, device):
    """Planar impact with omega = omega e_o: stick (27-30) and slip (31-34) in the paper's scalars."""
    rng = np.random.default_rng(7)
    I_over_m = K * R * R
    for _ in range(20):
        vct, vcn, omega = rng.uniform(1, 300), -rng.uniform(10, 300), rng.uniform(-1e5, 1e5)
        # e_t = +x when v_p,t = v_ct + omega R > 0 (here e_o = e_t x e_n = +z)
        if vct + omega * R <= 0:
            continue
        v, w, s = law([vct, vcn, 0.0], [0.0, 0.0, omega], E=E, mu_s=100.0, mu_d=100.0, device=device)
        assert not s[0]
        slip = omega * R + vct
        np.testing.assert_allclose(w[0, 2], omega - R / (I_over_m + R * R) * slip, rtol=1e-12)  # eq. (28)
        np.testing.assert_allclose(v[0, 0], vct - I_over_m / (I_over_m + R * R) * slip, rtol=1e-12)  # eq. (29)
        np.testing.assert_allclose(v[0, 1], -E * vcn, rtol=1e-12, atol=1e-300)  # eq. (30)
        # eq. (35): the rebound angle from the plane, tan(theta) = v_n' / v_t'
        theta = np.arctan2(-E * vcn, vct - I_over_m / (I_over_m + R * R) * slip)
        assert np.arctan2(v[0, 1], v[0, 0]) == pytest.approx(theta, rel=1e-12, abs=1e-15)
        mu = 1e-3
        v, w, s = law([vct, vcn, 0.0], [0.0, 0.0, omega], E=E, mu_s=mu, mu_d=mu, device=device)
        assert s[0]
        np.testing.assert_allclose(w[0, 2], omega + mu * (1 + E) * vcn * R / I_over_m, rtol=1e-12)  # eq. (32)
        np.testing.assert_allclose(v[0, 0], vct + mu * (1 + E) * vcn, rtol=1e-12)  # eq. (33), v_cn < 0
        np.testing.assert_allclose(v[0, 1], -E * vcn, rtol=1e-12, atol=1e-300)  # eq. (34)


# ---------------------------------------------------------------- NumPy reference on random inputs


def random_states(rng, n):
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    v = rng.normal(scale=200.0, size=(n, 3))
    v -= (np.abs(v @ np.ones(3)) * 0 + np.abs(rng.normal(scale=100.0, size=n)))[:, None] * normals  # mostly approaching
    w = rng.normal(scale=2e4, size=(n, 3))
    return v, w, normals


@pytest.mark.parametrize("precision, rtol", [("float64", 1e-11), ("float32", 2e-5)])
def test_matches_float64_reference_on_random_inputs(device, precision, rtol):
    rng = np.random.default_rng(2021)
    v, w, n = random_states(rng, 4000)
    kwargs = dict(restitution=0.3, mu_s=0.3, mu_d=0.2, gravity=(1.0, -9.81, 2.0), duration=1e-4)
    v2, w2, s2 = wr.impact(v, w, n, radius=R, density=RHO, device=device, precision=precision, **kwargs)
    rv, rw, rs = reference.impact_law(v, w, n, radius=R, **kwargs)
    # the branch may differ only at the stick/slip threshold (float rounding)
    same = s2 == rs
    assert same.mean() > 0.999
    assert 0.05 < rs.mean() < 0.95  # both branches exercised
    scale_v = np.linalg.norm(v, axis=1)[:, None]
    scale_w = (np.linalg.norm(w, axis=1) + scale_v[:, 0] / R)[:, None]
    assert (np.abs(v2 - rv)[same] <= rtol * scale_v[same] * 10).all()
    assert (np.abs(w2 - rw)[same] <= rtol * scale_w[same] * 10).all()


# ---------------------------------------------------------------- invariants (hypothesis)

finite = dict(allow_nan=False, allow_infinity=False)
vec = st.tuples(*[st.floats(-1e4, 1e4, **finite)] * 3)
spin = st.tuples(*[st.floats(-1e6, 1e6, **finite)] * 3)
unit = st.tuples(*[st.floats(-1, 1, **finite)] * 3).filter(lambda t: np.linalg.norm(t) > 0.1)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    v=vec,
    w=spin,
    n=unit,
    E=st.floats(0, 1),
    mu_s=st.floats(0, 10),
    frac=st.floats(0, 1),
    duration=st.sampled_from([0.0, 1e-5, 1e-2]),
    precision=st.sampled_from(["float64", "float32"]),
)
def test_invariants(device, v, w, n, E, mu_s, frac, duration, precision):
    v, w = np.array([v]), np.array([w])
    n = np.array(n) / np.linalg.norm(n)
    v2, w2, s = law(v, w, n, E=E, mu_s=mu_s, mu_d=frac * mu_s, duration=duration, precision=precision, device=device)
    assert np.isfinite(v2).all() and np.isfinite(w2).all()
    eps = 1e-12 if precision == "float64" else 3e-6
    scale = np.linalg.norm(v) + R * np.linalg.norm(w) + 1e-30
    vn = v[0] @ n
    if vn >= 0:
        np.testing.assert_array_equal(v2, v.astype(precision))
        return
    # energy never rises
    assert energy(v2, w2)[0] <= energy(v, w)[0] * (1 + 4 * eps) + 1e-300
    # the normal rebound is -E v_n
    assert abs(v2[0] @ n + E * vn) <= 4 * eps * scale
    # the e_o component is unchanged (eq. 14)
    vp = v[0] + np.cross(w[0], -R * n)
    vpt = vp - (vp @ n) * n
    if np.linalg.norm(vpt) > 1e-6 * scale:
        e_o = np.cross(vpt / np.linalg.norm(vpt), n)
        assert abs(v2[0] @ e_o - v[0] @ e_o) <= 8 * eps * scale
    # a slipping impulse is mu_d N*: the tangential change equals it
    if s[0]:
        normal_impulse = max(-(1 + E) * vn - (np.array(G) @ n) * duration, 0.0)
        dv = v2[0] - v[0]
        dv_t = dv - (dv @ n) * n
        assert abs(np.linalg.norm(dv_t) - frac * mu_s * normal_impulse) <= 16 * eps * scale


def test_bad_arguments_name_the_key():
    with pytest.raises(wr.SceneError, match="restitution"):
        law([1.0, -1.0, 0.0], [0, 0, 0], E=1.5)
    with pytest.raises(wr.SceneError, match="mu_d"):
        law([1.0, -1.0, 0.0], [0, 0, 0], mu_s=0.1, mu_d=0.2)
    with pytest.raises(wr.SceneError, match="normal"):
        law([1.0, -1.0, 0.0], [0, 0, 0], n=[0.0, 0.0, 0.0])
    with pytest.raises(wr.SceneError, match="velocity"):
        law([[1.0, np.nan, 0.0]], [0, 0, 0])
    with pytest.raises(wr.SceneError, match="velocity"):
        law([["a", "b", "c"]], [0, 0, 0])
    with pytest.raises(wr.SceneError, match="angular_velocity"):
        wr.impact(
            np.zeros((2, 3)), np.zeros((3, 3)), UP, radius=R, density=RHO, restitution=0.1, mu_s=0.1, mu_d=0.1, device=DEVICES[0]
        )


@pytest.mark.parametrize(
    "kwargs, key",
    [
        (dict(v=[[1e39, -100.0, 0.0]]), "velocity"),
        (dict(w=[[0.0, 0.0, 1e12]]), "angular_velocity"),
        (dict(n="abc"), "normal"),
        (dict(n=[["a", 1, 0]]), "normal"),
        (dict(n=np.ones((5, 3))), "normal"),
        (dict(radius=1e-46), "radius"),
        (dict(gravity=(0.0, -9.81)), "gravity"),
        (dict(duration=-1.0), "duration"),
    ],
)
def test_out_of_domain_arguments_are_one_line_errors(kwargs, key):
    args = dict(v=[[10.0, -10.0, 0.0]], w=[[0.0, 0.0, 0.0]], n=UP, radius=R, gravity=G, duration=0.0)
    args.update(kwargs)
    with pytest.raises(wr.SceneError) as err:
        wr.impact(
            args["v"],
            args["w"],
            args["n"],
            radius=args["radius"],
            density=RHO,
            restitution=0.1,
            mu_s=0.1,
            mu_d=0.1,
            gravity=args["gravity"],
            duration=args["duration"],
            device=DEVICES[0],
        )
    assert str(err.value).startswith(key) and "\n" not in str(err.value)
