"""Precision guards (issue 13): tiny direction vectors launch at the scene's speed, exactly as their
scaled-up selves; the flight scale statistic bounds how far rounding moves a pellet, and the rule
built on it (docs/stability.md, "Precision") warns in one line where float32 cannot follow and not
on the examples."""

import math
import sys
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import cli, make_scene, paper_raw
from hypothesis import given, settings
from hypothesis import strategies as st

import warp_ricochet as wr
from warp_ricochet.errors import PrecisionWarning
from warp_ricochet.physics.limits import POSITION_RESOLUTION, UNIT_ROUNDOFF
from warp_ricochet.reference.ballistic import sample_launch, simulate
from warp_ricochet.scene import load_scene
from warp_ricochet.scene.vectors import HIGHEST, LOWEST, scale_exponent, scaled, unit_vector

TINY = {"float32": 1e-30, "float64": 1e-165}  # |d|^2 underflows to 0 in this precision
SCALE = {"float32": -100, "float64": -600}  # 2^k: exact, far below the square root of the smallest number


def _pellets(path):
    out = {}
    with h5py.File(path, "r") as f:
        f["pellets"].visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def _paper(precision, count=300, **shot):
    raw = paper_raw()
    raw["shot"].update(count=count, **shot)
    raw["output"] = {"fields": ["initial", "impact", "landing"]}
    return make_scene(raw, precision=precision)


# ---------------------------------------------------------------------------------------------- directions


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_a_tiny_direction_launches_every_pellet_at_the_scenes_speed(tmp_path, device, precision):
    tiny = TINY[precision]
    assert np.dtype(precision).type(tiny) ** 2 == 0  # the case: |d|^2 underflows in the kernel's precision
    scene = _paper(precision, direction=[tiny, -tiny, 0.0], direction_jitter=[0.1 * tiny] * 3)
    wr.run(scene, tmp_path / "t.h5", device=device)
    speeds = np.linalg.norm(_pellets(tmp_path / "t.h5")["initial/velocity"].astype(float), axis=1)
    np.testing.assert_allclose(speeds, scene.shot.speed, rtol=4 * np.finfo(precision).eps)
    # the NumPy reference samples the same way
    _, velocity, _ = sample_launch(scene.shot, np.random.default_rng(0))
    np.testing.assert_allclose(np.linalg.norm(velocity, axis=1), scene.shot.speed, rtol=1e-15)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_a_direction_scaled_by_a_power_of_two_gives_bitwise_the_same_pellets(tmp_path, device, precision):
    k = SCALE[precision]
    direction, jitter = [1.0, -1.0, 0.0], [0.1, 0.1, 0.1]
    wr.run(_paper(precision, direction=direction, direction_jitter=jitter), tmp_path / "a.h5", device=device)
    wr.run(
        _paper(precision, direction=list(scaled(direction, k)), direction_jitter=list(scaled(jitter, k))),
        tmp_path / "b.h5",
        device=device,
    )
    a, b = _pellets(tmp_path / "a.h5"), _pellets(tmp_path / "b.h5")
    assert sorted(a) == sorted(b) and len(a) > 10
    for name in a:
        assert a[name].tobytes() == b[name].tobytes(), name


def test_a_tiny_surface_normal_is_the_unit_normal_of_its_direction():
    for normal in ([0.0, 1e-300, 0.0], [0.0, 5e-324, 0.0], [0.0, 1e-165, 0.0]):
        raw = paper_raw()
        raw["surfaces"][0]["normal"] = normal
        assert make_scene(raw).surfaces[0].normal == (0.0, 1.0, 0.0), normal
    raw = paper_raw()
    raw["surfaces"][0]["normal"] = list(scaled([0.3, 1.0, -0.2], -1000))
    assert make_scene(raw).surfaces[0].normal == unit_vector([0.3, 1.0, -0.2])


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_the_impact_api_takes_a_tiny_normal(precision):
    rng = np.random.default_rng(5)
    v, w = rng.normal(0, 50, (64, 3)) - [0, 100, 0], rng.normal(0, 500, (64, 3))
    law = dict(radius=0.00125, density=7000.0, restitution=0.5, mu_s=0.3, mu_d=0.2, device="cpu", precision=precision)
    want = wr.impact(v, w, [0.0, 1.0, 0.0], **law)
    got = wr.impact(v, w, [0.0, TINY[precision], 0.0], **law)
    for a, b in zip(want, got):
        assert a.tobytes() == b.tobytes()


vectors = st.lists(st.one_of(st.just(0.0), st.floats(1e-6, 1e6), st.floats(-1e6, -1e-6)), min_size=3, max_size=3).filter(any)


@settings(max_examples=300, deadline=None)
@given(vectors, st.integers(-960, 0))
def test_scaling_by_a_power_of_two_changes_no_unit_vector(v, k):
    u = scaled(v, k)
    assert unit_vector(u) == unit_vector(v)
    e = scale_exponent(u)
    largest = max(map(abs, scaled(u, e)))
    assert 2.0**LOWEST <= largest < 2.0**HIGHEST
    if 2.0**LOWEST <= max(map(abs, u)) < 2.0**HIGHEST:
        assert e == 0  # ordinary vectors are left as they are
    assert abs(math.hypot(*unit_vector(v)) - 1.0) <= 4e-16


# ---------------------------------------------------------------------------------------------- the float32 range


def far_scene(precision, count=200):
    """The issue's kind of scene: launched 1e6 m out, upwards, flights of about 6e5 s that end 1.6e8 m
    away, inside the documented domain."""
    raw = paper_raw(gravity=[0.0, -1e-3, 0.0], bounces=2)
    raw["shot"].update(count=count, speed=400.0, direction=[1.0, 1.0, 0.0], envelope_center=[1e6, 1e6, 0.0], envelope_radius=10.0)
    raw["output"] = {"fields": ["impact", "landing"]}
    return make_scene(raw, precision=precision)


def _behind(path, radius):
    """The largest distance (m) of a pellet's centre from R in front of the plane y = 0 at an impact or landing."""
    p = _pellets(path)
    y = np.concatenate([p["impact/position"][..., 1].ravel(), p["landing/position"][:, 1]]).astype(float)
    return np.nanmax(np.abs(y - radius))


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_the_flight_scale_bounds_where_rounding_puts_a_pellet(tmp_path, precision):
    scene = far_scene(precision)
    radius = 0.5 * scene.shot.diameter
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stats = wr.run(scene, tmp_path / "f.h5", device="cpu")
    scale, eps = stats["flight_scale_max"], UNIT_ROUNDOFF[precision]
    assert 3e8 < scale < 5e8  # |x0| 1e6 + |v0| t 2.5e8 + |g| t^2 / 2 2e8
    error = _behind(tmp_path / "f.h5", radius)
    assert error <= 4 * eps * scale  # the rule's premise: rounding moves a centre by a few eps M at most
    messages = [str(w.message) for w in caught if issubclass(w.category, PrecisionWarning)]
    if precision == "float32":
        assert error > radius  # the centres are metres behind the plane: the warning is due
        assert len(messages) == 1 and 'numerics.precision = "float64"' in messages[0]
        assert "flight_scale_max" in messages[0] and "\n" not in messages[0]
    else:
        assert error < POSITION_RESOLUTION * radius and messages == []


def test_the_flight_scale_is_that_of_the_float64_reference(tmp_path):
    scene = far_scene("float64", count=50)
    scene = scene.replace(
        output=scene.output.__class__(fields=("initial.position", "initial.velocity", "initial.angular_velocity"))
    )
    stats = wr.run(scene, tmp_path / "f.h5", device="cpu")
    p = _pellets(tmp_path / "f.h5")
    _, ref_stats = simulate(scene, p["initial/position"], p["initial/velocity"], p["initial/angular_velocity"])
    assert ref_stats["flight_scale_max"] == pytest.approx(stats["flight_scale_max"], rel=1e-9)


def test_the_cli_warns_in_one_line_naming_float64(tmp_path):
    path = tmp_path / "far.toml"
    path.write_text(far_scene("float32", count=20).to_toml())
    with warnings.catch_warnings():  # as outside pytest, which records warnings and ignores this one
        warnings.simplefilter("always", PrecisionWarning)
        warnings.showwarning = lambda message, category, filename, lineno, file=None, line=None: sys.stderr.write(
            warnings.formatwarning(message, category, filename, lineno, line)
        )
        rc, stdout, err = cli(["run", path, "-o", tmp_path / "far.h5"])
    assert rc == 0 and "mean range" in stdout
    lines = [line for line in err.splitlines() if "flight_scale_max" in line]
    assert len(lines) == 1 and lines[0].startswith("warp-ricochet: warning: float32 resolves")
    assert 'numerics.precision = "float64"' in lines[0]


@pytest.mark.parametrize("example", ["paper.toml", "steel_plate.toml", "field.toml", "steel_plate_air.toml"])
def test_the_examples_do_not_warn(example):
    overrides = ["output.fields=[]"] + (["shot.shots=20"] if example == "field.toml" else [])
    scene = load_scene(Path(__file__).resolve().parents[1] / "examples" / example, overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PrecisionWarning)
        stats = wr.run(scene, None, device="cpu")
    # with room to spare: a quarter of the allowance at most
    assert (
        UNIT_ROUNDOFF[scene.numerics.precision] * stats["flight_scale_max"] < POSITION_RESOLUTION / 4 * 0.5 * scene.shot.diameter
    )
