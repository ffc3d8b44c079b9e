"""Leaps in air (dense/leap.py): the bound on the air's acceleration covers every law, a leap lets
no pair touch and no pellet meet a plane (checked in float64 against the worst the bound allows),
leaping pellets land where the core lands them, and leaps change no statistic of a cloud (an
ensemble, leaps on against off). And the kicks' intervals (dense/air.py) keep the splitting's
accuracy: lone pellets and the convergence are in test_air_dense."""

import math

import h5py
import numpy as np
import pytest
import warp as wp
from hypothesis import given, settings
from hypothesis import strategies as st

import warp_ricochet as wr
from tests.helpers import busy_lattice
from warp_ricochet.model import air_struct
from warp_ricochet.reference import air as ref
from warp_ricochet.scene import load_scene
from warp_ricochet.scene.schema import Air
from warp_ricochet.spec import RunSpec

wp.config.log_level = wp.LOG_WARNING
PAPER = "examples/paper.toml"
RADIUS, DENSITY, GRAVITY = 0.00125, 7000.0, (0.0, -9.81, 0.0)
AIRS = {
    "loth2021": Air(),
    "loth2021-sawicki": Air(lift="sawicki2003"),
    "constant-linear": Air(drag="constant", drag_coefficient=0.47, lift="linear", lift_slope=0.8),
    "braun": Air(drag="table"),
    "gs-wind": Air(drag="table", drag_table="gs", wind=(5.0, 0.0, -3.0), spin_decay_law="loth2008"),
    "no-lift": Air(magnus=False),
}


def _spec(air, precision="float64"):
    return RunSpec(
        precision=precision,
        bounces=1,
        planes=1,
        collisions=True,
        flight="air",
        air_laws=(air.drag, air.lift if air.magnus else None, air.spin_decay_law if air.spin_decay else None),
    )


def _physics(air, precision, device):
    from warp_ricochet.physics.types import types_for

    mass = DENSITY * 4.0 / 3.0 * math.pi * RADIUS**3
    physics = types_for(precision).Physics()
    physics.radius = RADIUS
    physics.inertia_factor = 0.4
    physics.gravity = GRAVITY
    physics.impact_duration = 1e-5
    physics.air = air_struct(air, precision, device, RADIUS, mass, GRAVITY, 1e-6)
    return physics


@pytest.mark.parametrize("name", list(AIRS))
def test_the_air_bound_covers_every_law(name, device):
    """acceleration_bound(s) is at least the reference's |a_D + a_L| at any speed up to s and any
    spin (drag at s, lift at its cap), and the reference's drag force grows with speed (what the
    bound assumes), for speeds 0 to 2000 m/s."""
    from warp_ricochet.dense.air import make_dense_air
    from warp_ricochet.physics.types import types_for

    air = AIRS[name]
    bound = make_dense_air(_spec(air)).acceleration_bound
    Physics = types_for("float64").Physics

    @wp.kernel(enable_backward=False, module="unique")
    def bounds(speed: wp.array(dtype=wp.float64), physics: Physics, out: wp.array(dtype=wp.float64)):
        i = wp.tid()
        out[i] = bound(speed[i], physics)

    speeds = np.concatenate([[0.0], np.geomspace(1e-3, 2000.0, 400)])
    out = wp.zeros(len(speeds), dtype=wp.float64, device=device)
    wp.launch(
        bounds,
        dim=len(speeds),
        inputs=[wp.array(speeds, dtype=wp.float64, device=device), _physics(air, "float64", device), out],
        device=device,
    )
    got = out.numpy()
    pellet = ref.Pellet(RADIUS, DENSITY)
    drag = np.array([np.linalg.norm(ref.drag_force(np.array([s, 0.0, 0.0]), RADIUS, air)) for s in speeds])
    assert (np.diff(drag) >= -1e-12 * drag[1:]).all(), "the drag force must grow with speed"
    rng = np.random.default_rng(5)
    for _ in range(300):
        k = rng.integers(1, len(speeds))
        s = speeds[k] * rng.uniform(0.0, 1.0)  # any speed up to the bound's
        u = rng.normal(size=3)
        u *= s / np.linalg.norm(u)
        w = rng.normal(size=3) * 10.0 ** rng.uniform(0, 6)
        a = (ref.drag_force(u, RADIUS, air) + (ref.lift_force(u, w, RADIUS, air) if air.magnus else 0.0)) / pellet.mass
        assert np.linalg.norm(a) <= got[k] * (1 + 1e-9) + 1e-12, (s, speeds[k], np.linalg.norm(a), got[k])


def _leap_kernels(device):
    from warp_ricochet.dense.leap import make_leap
    from warp_ricochet.physics.types import types_for

    t = types_for("float64")
    leap = make_leap(_spec(Air()))
    vec3, Surfaces, Physics = t.vec3, t.Surfaces, t.Physics

    @wp.kernel(enable_backward=False, module="unique")
    def pairs(
        d: wp.array(dtype=vec3),
        u: wp.array(dtype=vec3),
        bound: wp.array(dtype=wp.float64),
        reach: wp.float64,
        margin: wp.float64,
        out: wp.array(dtype=wp.float64),
    ):
        i = wp.tid()
        out[i] = leap.pair_leap(d[i], u[i], reach, margin, bound[i], wp.length(u[i]))

    @wp.kernel(enable_backward=False, module="unique")
    def planes(
        x: wp.array(dtype=vec3),
        v: wp.array(dtype=vec3),
        bound: wp.array(dtype=wp.float64),
        surfaces: Surfaces,
        physics: Physics,
        out: wp.array(dtype=wp.float64),
    ):
        i = wp.tid()
        out[i] = leap.plane_leap(x[i], v[i], bound[i], surfaces, physics)

    return pairs, planes


vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3)


@settings(max_examples=60, deadline=None)
@given(
    direction=vectors,
    velocity=vectors,
    gap=st.floats(1e-6, 0.05),
    speed=st.floats(0.0, 300.0),
    bound=st.floats(0.0, 1e4),
    margin=st.floats(1e-4, 5e-3),
)
def test_a_leap_lets_no_pair_touch(direction, velocity, gap, speed, bound, margin):
    """However the air moves the pair off its straight line (up to bound t^2 / 2 towards each
    other), it stays apart for the whole leap: min over t of |d + u t| - bound t^2 / 2 >= 2R,
    checked in float64 on a fine grid of the leap, and the leap is positive while apart."""
    device = "cpu"
    pairs, _ = _leap_kernels(device)
    reach = 2 * RADIUS
    d = np.array(direction) / np.linalg.norm(direction) * (reach + gap)
    u = np.array(velocity) / np.linalg.norm(velocity) * speed
    out = wp.zeros(1, dtype=wp.float64, device=device)
    wp.launch(
        pairs,
        dim=1,
        inputs=[
            wp.array([d], dtype=wp.vec3d, device=device),
            wp.array([u], dtype=wp.vec3d, device=device),
            wp.array([bound], dtype=wp.float64, device=device),
            reach,
            margin,
            out,
        ],
        device=device,
    )
    leap = float(out.numpy()[0])
    assert leap > 0.0
    t = np.linspace(0.0, min(leap, 1e3), 20001)
    apart = np.linalg.norm(d[None, :] + u[None, :] * t[:, None], axis=1) - 0.5 * bound * t**2
    assert apart.min() >= reach - 1e-12 * (reach + gap + speed * t[-1]), (leap, apart.min() - reach)


@settings(max_examples=60, deadline=None)
@given(height=st.floats(0.0, 0.5), normal_speed=st.floats(-300.0, 300.0), bound=st.floats(0.0, 1e4), tilt=st.floats(-0.9, 0.9))
def test_a_leap_lets_no_pellet_meet_a_plane(height, normal_speed, bound, tilt):
    """With up to `bound` of air towards the plane besides gravity, the pellet's gap stays
    positive for the whole leap, and the leap ends where that worst gap closes (the earliest
    root of h + v_n t + (g.n - bound) t^2 / 2, np.roots in float64)."""
    device = "cpu"
    _, planes = _leap_kernels(device)
    from warp_ricochet.physics.types import surfaces_of

    normal = np.array([tilt, 1.0, 0.0]) / math.hypot(tilt, 1.0)
    surfaces = surfaces_of("float64", [[0.0, 0.0, 0.0]], [normal], [[0.5, 0.5, 0.5]], device)
    x = normal * (RADIUS + height)
    v = normal * normal_speed + np.array([5.0, 0.0, 1.0]) - normal * (np.array([5.0, 0.0, 1.0]) @ normal)
    out = wp.zeros(1, dtype=wp.float64, device=device)
    wp.launch(
        planes,
        dim=1,
        inputs=[
            wp.array([x], dtype=wp.vec3d, device=device),
            wp.array([v], dtype=wp.vec3d, device=device),
            wp.array([bound], dtype=wp.float64, device=device),
            surfaces,
            _physics(Air(), "float64", device),
            out,
        ],
        device=device,
    )
    leap = float(out.numpy()[0])
    pull = float(np.dot(GRAVITY, normal)) - bound  # the worst acceleration along the normal

    def closes(h):
        """The earliest t >= 0 where the worst gap from h closes to 0 (a root with gap' <= 0 there)."""
        if h <= 0.0:  # touching: now if closing, else when the pull brings it back
            if normal_speed <= 0:
                return 0.0
            return 2.0 * normal_speed / -pull if pull < 0 else math.inf
        roots = [
            r.real
            for r in np.roots([0.5 * pull, normal_speed, h])
            if abs(r.imag) < 1e-12 and r.real >= 0 and pull * r.real + normal_speed <= 0
        ]
        return min(roots) if roots else math.inf

    # where the worst gap closes, up to the rounding of the gap itself (a few ulp of R + height)
    rounding = 1e-18 * (1 + height / RADIUS)
    low, high = closes(max(height - rounding, 0.0)), closes(height + rounding)
    if math.isinf(low):
        assert leap >= 1e29
    else:
        assert low * (1 - 1e-9) - 1e-15 <= leap <= high * (1 + 1e-9) + 1e-15, (leap, low, high)


def _busy_lattice(tmp_path, collisions, device, leaps=True):
    """20 pellets 10 cm apart, fired as the paper's at the surface with topspin (none meets
    another), and below the surface (never meeting it) a slow pair that meets 97 ms later: it
    keeps the shot in the dense phase, which leaps past its arrival window while the 20 land."""
    raw = {
        **busy_lattice(tmp_path / "busy.npz"),
        "output": {"fields": ["initial", "landing"]},
        "collisions": {"enabled": collisions, "air_leaps": leaps},
    }
    from warp_ricochet.scene import scene_from_dict

    stats = wr.run(scene_from_dict(raw), tmp_path / "busy.h5", device=device, overwrite=True, sidecar=False)
    with h5py.File(tmp_path / "busy.h5", "r") as f:
        return {k: f["pellets/" + k][()].astype(float)[:20] for k in ("initial/position", "landing/position")}, stats


def test_leaping_pellets_land_where_the_core_lands_them(tmp_path, device):
    """Pellets that land inside leaps (`_busy_lattice`) land within 1e-5 of the distance they
    flew from where the core alone lands them, and the leaps take the place of the steps there."""
    off, _ = _busy_lattice(tmp_path, False, device)
    on, stats = _busy_lattice(tmp_path, True, device)
    _, stepped = _busy_lattice(tmp_path, True, device, leaps=False)
    assert stats["pair_collisions"] == 1 and stats["dense_time_max"] > 0.09  # (the far pair)
    # (stepping, the 20 take 2,400 steps of 1.8 us from the end of the arrival window to their landing)
    assert stats["dense_steps_mean"] < 0.8 * stepped["dense_steps_mean"], (stats["dense_steps_mean"], stepped["dense_steps_mean"])
    flown = np.linalg.norm(off["landing/position"] - off["initial/position"], axis=1)
    assert np.isfinite(flown).all()
    error = np.linalg.norm(on["landing/position"] - off["landing/position"], axis=1) / flown
    assert error.max() < 1e-5, error.max()


def test_leaps_change_no_statistic_of_a_cloud(tmp_path):
    """The same 160 shots (the paper's, 120 pellets in a 17 mm envelope) with leaps and without:
    the ensemble's collided fraction, pair collisions and mean range agree within their
    confidence intervals (4 standard errors of the difference), and the leaps save most steps."""
    sets = [
        "shot.count=120",
        "shot.envelope_radius=0.017",
        "shot.shots=160",
        "air.density=1.225",
        "collisions.enabled=true",
        "surfaces.0.mu_s=0.5",
        "surfaces.0.mu_d=0.45",
        "output.fields=[]",
    ]
    runs = {}
    for leaps in ("true", "false"):
        wr.run(load_scene(PAPER, sets + [f"collisions.air_leaps={leaps}"]), tmp_path / f"{leaps}.h5", device="cpu", sidecar=False)
        with h5py.File(tmp_path / f"{leaps}.h5", "r") as f:
            runs[leaps] = {
                k: f["stats/shots/" + k][()] for k in ("collided_fraction", "pair_collisions", "range_mean", "dense_steps_mean")
            }
    for name in ("collided_fraction", "pair_collisions", "range_mean"):
        on, off = runs["true"][name], runs["false"][name]
        error = math.sqrt((on.var(ddof=1) + off.var(ddof=1)) / len(on))
        assert abs(on.mean() - off.mean()) <= 4 * error + 1e-12, (name, on.mean(), off.mean(), error)
    assert runs["true"]["dense_steps_mean"].mean() < 0.7 * runs["false"]["dense_steps_mean"].mean()
