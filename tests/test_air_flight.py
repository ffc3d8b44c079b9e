"""Flight in air (physics/air_flight.py) through the whole pipeline, against the float64 SciPy
reference (reference/air.py: DOP853, rtol 1e-12) and by its limits and invariants."""

import math

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from warp_ricochet.reference import air as ref
from warp_ricochet.scene import scene_from_dict

SURFACES = [
    {"point": [0.0, 0.0, 0.0], "normal": [0.05, 1.0, 0.02], "restitution": 0.4, "mu_s": 0.3, "mu_d": 0.25},
    {"point": [60.0, 0.0, 0.0], "normal": [-1.0, 0.1, 0.0], "restitution": 0.6, "mu_s": 0.2, "mu_d": 0.15},
]
DIAMETER, DENSITY, GRAVITY = 0.0025, 7800.0, (0.0, -9.81, 0.0)


def _launches(n, seed):
    """Speeds 30 to 450 m/s, angles -60 to 40 degrees, some sideways, spins up to ~1e4 rad/s."""
    rng = np.random.default_rng(seed)
    speed, angle, azimuth = rng.uniform(30, 450, n), np.radians(rng.uniform(-60, 40, n)), rng.uniform(-0.3, 0.3, n)
    velocity = np.stack(
        [speed * np.cos(angle) * np.cos(azimuth), speed * np.sin(angle), speed * np.cos(angle) * np.sin(azimuth)], 1
    )
    position = np.stack([np.zeros(n), rng.uniform(0.5, 3.0, n), np.zeros(n)], 1)
    return position, velocity, rng.normal(0.0, 3000.0, (n, 3))


def _run(tmp_path, position, velocity, spin, air, precision, name="air.h5", surfaces=SURFACES, device="cpu", **numerics):
    np.savez(tmp_path / "pellets.npz", position=position, velocity=velocity, angular_velocity=spin)
    raw = {
        "shot": {"file": str(tmp_path / "pellets.npz"), "diameter": DIAMETER, "density": DENSITY},
        "surfaces": surfaces,
        "physics": {"bounces": 1, "gravity": list(GRAVITY)},
        "numerics": {"precision": precision, **numerics},
        "output": {"fields": ["impact", "landing"]},
    }
    if air is not None:
        raw["air"] = air
    scene = scene_from_dict(raw)
    stats = wr.run(scene, tmp_path / name, device=device, overwrite=True)
    with h5py.File(tmp_path / name, "r") as f:
        out = {
            k: f["pellets/" + k][()].astype(np.float64)
            for k in (
                "impact/time",
                "impact/position",
                "impact/velocity",
                "impact/angular_velocity",
                "impact/angular_velocity_before",
                "impact/surface",
                "landing/time",
                "landing/position",
                "landing/velocity",
            )
        }
    return scene, out, stats


def _planes(surfaces=SURFACES):
    return [(np.array(s["point"], float), np.array(s["normal"], float)) for s in surfaces]


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize(
    "air",
    [
        {"wind": [4.0, 0.0, -3.0]},
        {"drag": "table", "drag_table": "gs", "lift": "sawicki2003", "spin_decay_law": "loth2008", "drag_factor": 1.1},
        {"drag": "constant", "drag_coefficient": 0.47, "lift": "linear", "lift_slope": 0.8, "spin_decay": False},
        {"magnus": False, "wind": [0.0, 0.0, 5.0]},
    ],
    ids=["loth-wind", "gs-sawicki", "constant-linear", "no-magnus"],
)
def test_landing_points_match_the_reference(tmp_path, device, precision, air):
    """Random launches: the first contact (from the launch) and the landing (from the kernel's own
    state after the impact, so the flight alone is compared) within 1e-4 of the distance flown
    at the default tolerance, on tilted planes."""
    position, velocity, spin = _launches(6, seed=len(str(air)))
    scene, out, _stats = _run(tmp_path, position, velocity, spin, air, precision, device=device)
    pellet = ref.Pellet(DIAMETER / 2, DENSITY)
    checked = 0
    for i in range(len(position)):
        first = ref.fly_to_planes(position[i], velocity[i], spin[i], pellet, scene.air, GRAVITY, _planes())
        if first is None:
            assert np.isnan(out["impact/time"][i, 0])
            continue
        assert out["impact/surface"][i, 0] == first.plane
        flown = np.linalg.norm(first.x - position[i])
        assert np.linalg.norm(out["impact/position"][i, 0] - first.x) <= 1e-4 * flown, i
        after = ref.fly_to_planes(
            out["impact/position"][i, 0],
            out["impact/velocity"][i, 0],
            out["impact/angular_velocity"][i, 0],
            pellet,
            scene.air,
            GRAVITY,
            _planes(),
            touching=first.plane,
        )
        if after is None:
            continue
        flown = np.linalg.norm(after.x - out["impact/position"][i, 0])
        assert np.linalg.norm(out["landing/position"][i] - after.x) <= 1e-4 * flown + 1e-7, i
        checked += 1
    assert checked >= 3


def test_the_air_to_zero_is_the_vacuum(tmp_path, device):
    """density 0 is the vacuum's exact parabola (bitwise). Air thinned to 1e-12 of sea level
    (density and viscosity: the viscous spin decay depends on the viscosity alone, as in any
    continuum law) lands within 1e-8 of the distance flown of it, long flights (km) included."""
    position, velocity, spin = _launches(8, seed=5)
    _s, vacuum, _ = _run(tmp_path, position, velocity, spin, None, "float64", "vacuum.h5", device=device)
    _s, zero, _ = _run(tmp_path, position, velocity, spin, {"density": 0.0}, "float64", "zero.h5", device=device)
    thin_air = {"density": 1.225e-12, "viscosity": 1.789e-17}
    _s, thin, stats = _run(tmp_path, position, velocity, spin, thin_air, "float64", "thin.h5", device=device)
    for name in vacuum:
        np.testing.assert_array_equal(zero[name], vacuum[name], err_msg=name)
    landed = np.isfinite(vacuum["landing/time"])
    flown = np.linalg.norm(vacuum["landing/position"][landed] - position[landed], axis=1)
    assert landed.sum() >= 4 and flown.max() > 1000
    assert (np.linalg.norm(thin["landing/position"][landed] - vacuum["landing/position"][landed], axis=1) < 1e-8 * flown).all()
    assert "flight_steps_mean" in stats


def test_thinning_the_density_alone_leaves_the_stokes_spin_decay(tmp_path, device):
    """The vacuum limit needs the viscous torque gone too. With the density thinned to 1e-12 of sea
    level at sea-level viscosity, drag and lift vanish (both scale with the density: the free-
    molecular drag, rho C_L) but the spin decay does not: its Reynolds number rho d^2 |omega| / mu
    goes to 0 and the torque to the Stokes one, -8 pi mu R^3 omega, which has no density in it. So
    the flight to the first impact is the vacuum's (within 1e-8 of the distance flown), its spin
    there the vacuum's times exp(-15 mu t / (rho_p R^2)) (I = 2/5 m R^2; 2.2% a second here), and
    the ricochet, which depends on the spin through friction, lands elsewhere. With spin_decay =
    false as well it lands within 1e-8 of the vacuum's landing."""
    position, velocity, spin = _launches(8, seed=5)
    _s, vacuum, _ = _run(tmp_path, position, velocity, spin, None, "float64", "vacuum.h5", device=device)
    _s, thin, _ = _run(tmp_path, position, velocity, spin, {"density": 1.225e-12}, "float64", "thin.h5", device=device)
    _s, still, _ = _run(
        tmp_path,
        position,
        velocity,
        spin,
        {"density": 1.225e-12, "spin_decay": False},
        "float64",
        "still.h5",
        device=device,
    )
    hit = np.isfinite(vacuum["impact/time"][:, 0])
    landed = np.isfinite(vacuum["landing/time"])
    assert hit.sum() >= 6 and landed.sum() >= 4
    to_impact = np.linalg.norm(vacuum["impact/position"][hit, 0] - position[hit], axis=1)
    assert (np.linalg.norm(thin["impact/position"][hit, 0] - vacuum["impact/position"][hit, 0], axis=1) < 1e-8 * to_impact).all()
    mu, radius = 1.789e-5, DIAMETER / 2
    stokes = np.exp(-15 * mu * vacuum["impact/time"][hit, 0] / (DENSITY * radius**2))[:, None]
    np.testing.assert_allclose(thin["impact/angular_velocity_before"][hit, 0], spin[hit] * stokes, rtol=1e-6)
    flown = np.linalg.norm(vacuum["landing/position"][landed] - position[landed], axis=1)
    off = np.linalg.norm(thin["landing/position"][landed] - vacuum["landing/position"][landed], axis=1) / flown
    assert off.max() > 1e-4, off
    off = np.linalg.norm(still["landing/position"][landed] - vacuum["landing/position"][landed], axis=1) / flown
    assert (off < 1e-8).all(), off


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_dropped_pellet_lands_at_the_terminal_speed(tmp_path, device, precision):
    """Drag only, dropped from 3 km: it lands at the speed where drag balances its weight (root
    found by the reference) for each drag law."""
    ground = [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.5, "mu_s": 0.2}]
    pellet = ref.Pellet(DIAMETER / 2, DENSITY)
    for air in (
        {"magnus": False},
        {"drag": "table", "magnus": False},
        {"drag": "constant", "drag_coefficient": 0.47, "magnus": False},
    ):
        scene, out, _ = _run(
            tmp_path,
            [[0.0, 3000.0, 0.0]],
            [[0.0, 0.0, 0.0]],
            [[0.0, 0.0, 0.0]],
            air,
            precision,
            surfaces=ground,
            device=device,
        )
        terminal = ref.terminal_speed(pellet, scene.air)
        assert np.linalg.norm(out["impact/velocity"][0, 0] / 0.5) == pytest.approx(terminal, rel=2e-5), air


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_the_air_never_adds_energy_without_wind(tmp_path, device, precision):
    """Kinetic (translation and rotation) plus potential energy at the first contact is at most
    that at the launch, whatever the spin and lift law."""
    position, velocity, spin = _launches(40, seed=9)
    spin *= 5.0
    for lift in ("loth2008", "sawicki2003"):
        _s, out, _ = _run(tmp_path, position, velocity, spin, {"lift": lift}, precision, device=device)
        hit = np.isfinite(out["impact/time"][:, 0])
        mass = DENSITY * 4 / 3 * math.pi * (DIAMETER / 2) ** 3
        inertia = 0.4 * mass * (DIAMETER / 2) ** 2

        def energy(x, v, w, mass=mass, inertia=inertia):
            return 0.5 * mass * (v * v).sum(1) + 0.5 * inertia * (w * w).sum(1) + mass * 9.81 * x[:, 1]

        with h5py.File(tmp_path / "air.h5", "r") as f:
            before_v = f["pellets/impact/velocity_before"][:, 0].astype(float)
            before_w = f["pellets/impact/angular_velocity_before"][:, 0].astype(float)
        start = energy(position, velocity, spin)[hit]
        end = energy(out["impact/position"][:, 0], before_v, before_w)[hit]
        rounding = 1e-12 if precision == "float64" else 2e-6
        assert (end <= start * (1 + rounding)).all()
        assert (end < 0.999 * start).any()


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_pellet_leaving_a_plane_under_topspin_lift_comes_back_when_it_should(tmp_path, device, precision):
    """A pellet leaving the ground with a little normal speed and topspin (the lift pushes it down)
    meets the ground again after the reference's time, not at once and not at the vacuum's 2 v_n / g."""
    ground = [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.02, "mu_s": 0.5}]
    r = DIAMETER / 2
    # launched onto the ground at a grazing angle: E = 0.02 leaves it 0.05 m/s of normal speed, rolling
    position, velocity = [[0.0, r + 1e-3, 0.0]], [[200.0, -2.5, 0.0]]
    scene, out, _ = _run(tmp_path, position, velocity, [[0.0, 0.0, 0.0]], {}, precision, surfaces=ground, device=device)
    pellet = ref.Pellet(r, DENSITY)
    after = ref.fly_to_planes(
        out["impact/position"][0, 0],
        out["impact/velocity"][0, 0],
        out["impact/angular_velocity"][0, 0],
        pellet,
        scene.air,
        GRAVITY,
        _planes(ground),
        touching=0,
    )
    took = out["landing/time"][0] - out["impact/time"][0, 0]
    vacuum = 2 * out["impact/velocity"][0, 0, 1] / 9.81
    assert 0 < after.t < 0.5 * vacuum
    assert took == pytest.approx(after.t, rel=1e-4)


def test_a_flight_given_up_is_counted_and_warned(tmp_path, device):
    """A 0.25 mm pellet dropped from 1000 km falls at its terminal speed for days, in steps bounded
    by the stepper's stability (its drag time scale): more than MAX_FLIGHT_STEPS steps, so it is
    given up, counted in flights_unfinished, and the run warns in one line. (In float32 the fall
    reaches a speed where the drag rounds to exactly the weight, and steps grow without bound.)"""
    np.savez(tmp_path / "p.npz", position=[[0.0, 1e6, 0.0]], velocity=[[0.0, 0.0, 0.0]], angular_velocity=[[0.0, 0.0, 0.0]])
    raw = {
        "shot": {"file": str(tmp_path / "p.npz"), "diameter": 2.5e-4, "density": DENSITY},
        "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.5, "mu_s": 0.2}],
        "air": {"magnus": False},
        "output": {"fields": []},
        "numerics": {"precision": "float64"},
    }
    with pytest.warns(wr.PrecisionWarning, match="given up"):
        stats = wr.run(scene_from_dict(raw), tmp_path / "o.h5", device=device, overwrite=True)
    assert stats["flights_unfinished"] == 1 and stats["hits"] == 0
