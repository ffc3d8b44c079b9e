"""How the dense phase is put together (issue 27, part 1): every stage starts from one namespace
(`dense.kit`), the physics factories are keyed by the precision string alone, and the precision has
one owner per layer. Its results are held bitwise by tests/test_golden.py and tests/test_collisions.py."""

import dataclasses
import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import numpy as np
import pytest
import warp as wp

import warp_ricochet.dense as dense
import warp_ricochet.launch.sampling as sampling
import warp_ricochet.physics as physics
from warp_ricochet.dense.constants import FLYING
from warp_ricochet.dense.kit import dense_kit
from warp_ricochet.model import Model
from warp_ricochet.physics.ballistic import make_ballistic
from warp_ricochet.spec import RunSpec

DENSE = Path(dense.__file__).parent


def _factories(package):
    """Every `make_*` function of a package's modules."""
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        for name, f in vars(module).items():
            f = inspect.unwrap(f) if callable(f) else f
            if name.startswith("make_") and inspect.isfunction(f) and f.__module__ == module.__name__:
                yield module.__name__, name, f


def test_dense_stages_take_their_types_and_physics_from_the_kit():
    shared = re.compile(r"\b(dense_types|dense_flight|make_ballistic|make_geometry|make_flight|make_outputs)\(")
    copied = {p.name: shared.findall(p.read_text()) for p in DENSE.glob("*.py") if p.name != "kit.py"}
    assert not {name: calls for name, calls in copied.items() if calls}
    for path in DENSE.glob("*.py"):
        factories = re.findall(r"^def make_\w+\(spec\)", path.read_text(), flags=re.M)
        assert len(re.findall(r"^    kit = dense_kit\(spec\)$", path.read_text(), flags=re.M)) == len(factories), path.name


def test_physics_factories_are_keyed_by_the_precision_string():
    found = list(_factories(physics)) + [
        (sampling.__name__, n, inspect.unwrap(getattr(sampling, n))) for n in ("make_sampler", "make_redraw")
    ]
    assert len(found) > 20
    for module, name, f in found:
        first = next(iter(inspect.signature(f).parameters))
        assert first == "precision", f"{module}.{name} is keyed by {first!r}"
    assert make_ballistic("float64") is make_ballistic("float64")


def test_the_kit_is_built_once_per_spec_and_holds_its_precisions_physics():
    spec = RunSpec(precision="float64", bounces=1, planes=1, collisions=True)
    kit = dense_kit(spec)
    assert kit is dense_kit(dataclasses.replace(spec))
    assert kit.ballistic is make_ballistic("float64") and kit.precision == "float64"
    assert dense_kit(dataclasses.replace(spec, precision="float32")).scalar.__name__ == "float32"


def test_a_model_reads_its_precision_from_its_types():
    assert "precision" not in {f.name for f in dataclasses.fields(Model)}
    assert isinstance(inspect.getattr_static(Model, "precision"), property)


def test_the_clouds_arrays_are_grouped_by_stage_and_sized_by_pellet_shot_or_block():
    from warp_ricochet.core.release import RELEASE_ARRAYS
    from warp_ricochet.dense.state import allocate_cloud, make_state, release_struct

    Cloud = make_state("float64")[0]
    groups = {name for name, var in Cloud.vars.items() if isinstance(var.type, type(Cloud))}
    assert groups == {"state", "collisions", "event", "air", "now", "lists", "written", "frame", "clock", "watch"}
    assert set(Cloud.vars) - groups == {"shot_flags", "flags", "stop", "keys"}
    assert list(Cloud.vars["state"].type.vars) == list(RELEASE_ARRAYS)
    clock = Cloud.vars["clock"].type.vars
    assert len(clock) == 13 and all(var.type.ndim == 1 for var in clock.values())  # named, one a shot
    cloud, arrays = allocate_cloud("float64", "cpu", 50, 2, 25, 3, 7, ("release.position", "collisions.count"))
    assert cloud.state.position.shape == (50,) and cloud.lists.neighbours.shape == (50, 7)
    assert cloud.clock.time.shape == (2,) and cloud.frame.drift_origin.shape == (2,) and cloud.lists.half_skin.shape == (2,)
    assert cloud.frame.position.shape == (2,) and cloud.event.round_applied.shape == (3,)  # one frame block a shot
    assert cloud.written.release_position.shape == (50,) and cloud.written.release_time.shape == (0,)
    assert arrays == {"release.position": cloud.written.release_position, "collisions.count": cloud.collisions.count}
    assert release_struct("float64", cloud, 25).position.ptr == cloud.state.position.ptr
    assert cloud.watch.reach.shape == (0, 1) and cloud.watch.ints.shape == (0, 6)  # (no hazard watched)
    watched, _ = allocate_cloud("float64", "cpu", 50, 2, 25, 3, 7, (), (4, 2))  # (4 thresholds, 2 places)
    assert watched.watch.reach.shape == (50, 4) and watched.watch.ints.shape == (50, 7)
    assert release_struct("float64", watched, 25).watch_ints.ptr == watched.watch.ints.ptr


def _host_frame(x, v, t, phase, now, g):
    """The trajectory frame as the host computed it before it was taken on the device (NumPy)."""
    age = np.where(phase == FLYING, now - t, 0.0)[:, None]
    return x + v * age + 0.5 * np.asarray(g, np.float64) * age**2


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_trajectory_frames_on_the_device_are_the_host_formulas_bits(precision):
    from warp_ricochet.dense.kernels import make_setup_kernels
    from warp_ricochet.dense.state import allocate_cloud
    from warp_ricochet.physics.types import types_for

    n, dtype, t = 4000, np.dtype(precision), types_for(precision)
    rng = np.random.default_rng(27)
    spec = RunSpec(precision=precision, bounces=1, planes=1, collisions=True)
    cloud, _ = allocate_cloud(precision, "cpu", n, 2, n // 2, 1, 4, ())
    scale = 10.0 ** rng.uniform(-3, 4, (n, 1))  # positions of every magnitude, ages up to 30 s
    x, v = (rng.standard_normal((n, 3)) * scale).astype(dtype), (rng.standard_normal((n, 3)) * 300.0).astype(dtype)
    times, phase = rng.uniform(0.0, 30.0, n).astype(dtype), rng.integers(0, 2, n).astype(np.int32)
    now = dtype.type(rng.uniform(0.0, 30.0))
    for array, value in (
        (cloud.state.position, x),
        (cloud.state.velocity, v),
        (cloud.state.time, times),
        (cloud.state.phase, phase),
    ):
        array.assign(value)
    cloud.clock.time.assign(np.array([now, now + 1], dtype))  # (the first shot's clock is the frame's)
    physics = t.Physics()
    physics.gravity = t.vec3(0.3, -9.81, 0.07)
    points = wp.empty(n, dtype=wp.vec3d, device="cpu")
    wp.launch(make_setup_kernels(spec).trajectory_frame_kernel, n, [physics, cloud, points], device="cpu")
    want = _host_frame(x, v, times, phase, float(now), physics.gravity)
    assert want.dtype == np.float64
    np.testing.assert_array_equal(points.numpy(), want)
