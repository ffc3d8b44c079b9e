"""Air in the dense phase (dense/air.py: Strang splitting) and in whole runs: pellets far apart land
where the collisions-off run lands them, the splitting converges with the step, and runs in air
keep the pipeline's guarantees (same bits for any chunk size and after a resume)."""

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import assert_same_run, interrupt_after
from warp_ricochet.scene import load_scene, scene_from_dict

PAPER = "examples/paper.toml"
FIELDS = 'output.fields=["initial", "impact", "landing"]'


def _landings(tmp_path, sets, name, device="cpu"):
    scene = load_scene(PAPER, sets)
    stats = wr.run(scene, tmp_path / f"{name}.h5", device=device, overwrite=True)
    with h5py.File(tmp_path / f"{name}.h5", "r") as f:
        return {k: f["pellets/" + k][()].astype(float) for k in ("initial/position", "landing/position")}, stats


FAR_APART = [
    "shot.count=120",
    "shot.envelope_radius=15.0",
    "air.density=1.225",
    "shot.spin=[0.0, 0.0, 2000.0]",
    "physics.bounces=2",
    FIELDS,
]


def _far_apart_errors(tmp_path, device, precision, reference_precision, sets=()):
    """Pellets metres apart (none meets another), spinning, two ricochets, in `precision` through
    the dense phase (exact flight, the air as kicks) and then the core: each one's landing error
    against the core alone (integrated flight) in `reference_precision`, over the distance flown."""
    sets = FAR_APART + list(sets)
    off, _ = _landings(tmp_path, sets + [f'numerics.precision="{reference_precision}"'], "off", device)
    on, stats = _landings(tmp_path, sets + [f'numerics.precision="{precision}"', "collisions.enabled=true"], "on", device)
    assert stats["pair_collisions"] == 0 and stats["dense_steps_mean"] > 100
    flown = np.linalg.norm(off["landing/position"] - off["initial/position"], axis=1)
    landed = np.isfinite(flown)
    assert landed.sum() >= 50
    return np.linalg.norm(on["landing/position"] - off["landing/position"], axis=1)[landed] / flown[landed]


@pytest.mark.parametrize(("precision", "bound"), [("float64", 1e-5), ("float32", 1e-4)])
def test_pellets_far_apart_land_where_the_collisions_off_run_lands_them(tmp_path, device, precision, bound):
    """Each lands within `bound` of the distance it flew from where the collisions-off run of its
    precision lands it: 1e-5 in float64, 1e-4 in float32 (the float32 flight's own error;
    docs/air.md, section 3.2). Until 2026-11-28 float32 was off by up to 1e-2: a kick that put a
    pellet within 64 float32 epsilons of its distance from the plane's point (0.1 mm at 20 m)
    met the plane at once."""
    error = _far_apart_errors(tmp_path, device, precision, precision)
    assert error.max() < bound, error.max()


def test_over_a_tilted_plane_float32_lands_as_the_float64_flight(tmp_path, device):
    """Ground tilted 11 degrees (second hops leave it at a few cm/s: grazing landings, where a
    position error is multiplied by the slope): float32 through the dense phase lands within a
    median 1e-4 of the distance flown of the float64 core (measured 5e-5; the float32 core's own
    median is 7e-5), its worst within 3e-3 (the float32 core's own worst: 1.8e-3). Without the
    compensated kicks (dense.air.drifted) the median was 3.6e-4: each kick rounded the position."""
    error = _far_apart_errors(tmp_path, device, "float32", "float64", ["surfaces.0.normal=[0.2, 1.0, 0.0]"])
    assert np.median(error) < 1e-4 and error.max() < 3e-3, (np.median(error), error.max())


def _lattice(tmp_path, collisions, device):
    """Identical pellets 1 m apart across the shot: no relative motion, so the air alone sizes the
    dense phase's step. The second rebound is a slip that leaves at 2.6 cm/s under 660 m/s^2 of
    Magnus lift (topspin of 1.5e5 rad/s from the first, sticking, impact): it lands 79 us later."""
    z = np.arange(4.0)
    one = np.ones_like(z)
    np.savez(
        tmp_path / "lattice.npz",
        position=np.stack([0 * z, one, z], 1),
        velocity=np.stack([290.96 * one, -290.96 * one, 0 * z], 1),
        angular_velocity=np.stack([0 * z, 0 * z, -3e3 * one], 1),
    )
    raw = {
        "shot": {"file": str(tmp_path / "lattice.npz"), "diameter": 0.0025, "density": 7000.0},
        "surfaces": [{"point": [0, 0, 0], "normal": [0, 1, 0], "restitution": 0.01, "mu_s": 0.28, "mu_d": 0.252}],
        "physics": {"bounces": 2},
        "air": {},
        "numerics": {"precision": "float64", "flight_tolerance": 1e-12},
        "output": {"fields": ["initial", "impact", "landing"]},
        "collisions": {"enabled": collisions},
    }
    stats = wr.run(scene_from_dict(raw), tmp_path / "lattice.h5", device=device, overwrite=True)
    with h5py.File(tmp_path / "lattice.h5", "r") as f:
        return {k: f["pellets/" + k][()].astype(float) for k in ("initial/position", "impact/slipped", "landing/position")}, stats


def test_a_rigid_lattice_lands_where_the_core_lands_it(tmp_path, device):
    """With no relative motion the step is bounded by the air alone (air_step_fraction): near a
    plane by the air's share of the normal motion, and cut at each rebound, so the slow hop
    after the second impact is resolved: within 1e-5 of the distance flown."""
    off, _ = _lattice(tmp_path, False, device)
    on, stats = _lattice(tmp_path, True, device)
    assert stats["pair_collisions"] == 0 and (off["impact/slipped"] == [0, 1]).all()
    flown = np.linalg.norm(off["landing/position"] - off["initial/position"], axis=1)
    error = np.linalg.norm(on["landing/position"] - off["landing/position"], axis=1) / flown
    assert error.max() < 1e-5, error


def _two_pellets(tmp_path, time_step, device):
    np.savez(
        tmp_path / "two.npz", position=[[0.0, 1.0, 0.0], [0.0, 1.0, 5.0]], velocity=[[300.0, -300.0, 0.0], [300.0, -290.0, 0.0]]
    )
    raw = {
        "shot": {"file": str(tmp_path / "two.npz"), "diameter": 0.0025, "density": 7000.0},
        "surfaces": [{"point": [0, 0, 0], "normal": [0, 1, 0], "restitution": 0.5, "mu_s": 0.3}],
        "physics": {"bounces": 1},
        "air": {},
        "numerics": {"precision": "float64"},
        "output": {"fields": ["landing"]},
        "collisions": {"enabled": time_step is not None},
    }
    if time_step:
        raw["collisions"]["time_step"] = time_step
    wr.run(scene_from_dict(raw), tmp_path / "two.h5", device=device, overwrite=True)
    with h5py.File(tmp_path / "two.h5", "r") as f:
        return f["pellets/landing/position"][()]


def test_the_splitting_converges_with_the_step(tmp_path, device):
    """Fixed dense steps h, h/4, h/16: the landing error against the core alone falls at least
    ~h^2 until the integrator's own tolerance (about 1e-9 of 135 m) is reached."""
    reference = _two_pellets(tmp_path, None, device)
    errors = [np.abs(_two_pellets(tmp_path, h, device) - reference).max() for h in (4e-4, 1e-4, 2.5e-5)]
    assert errors[0] > 1e-6
    assert errors[1] < errors[0] / 12 and errors[2] < max(errors[1] / 12, 2e-6), errors


@pytest.mark.parametrize("collisions", [False, True])
def test_runs_in_air_are_the_same_bits_for_any_chunk_size(tmp_path, device, collisions):
    """Statistics and pellets of a run in air do not depend on the chunk size (nor on how many
    shots share a chunk)."""
    sets = [
        "air.density=1.225",
        FIELDS,
        "shot.count=40",
        "shot.shots=6",
        f"collisions.enabled={str(collisions).lower()}",
        "shot.envelope_radius=0.01",
    ]
    small = wr.run(load_scene(PAPER, sets + ["numerics.chunk_size=1"]), tmp_path / "small.h5", device=device)
    big = wr.run(load_scene(PAPER, sets), tmp_path / "big.h5", device=device)
    assert small.keys() == big.keys() and "flight_steps_mean" in big
    assert_same_run(tmp_path / "small.h5", tmp_path / "big.h5", ["landing/position", "impact/velocity"], progress=())
    for k in big:
        assert small[k] == big[k] or (np.isnan(small[k]) and np.isnan(big[k])), k


def test_a_run_in_air_resumes_bitwise(tmp_path, device):
    """Interrupted after a chunk, resumed: the same file as an uninterrupted run."""
    sets = ["air.density=1.225", FIELDS, "shot.count=200000", "numerics.chunk_size=65536"]
    scene = load_scene(PAPER, sets)
    wr.run(scene, tmp_path / "whole.h5", device=device)
    interrupt_after(1, scene, tmp_path / "part.h5", device)
    wr.run(scene, tmp_path / "part.h5", device=device, resume=True)
    assert_same_run(tmp_path / "part.h5", tmp_path / "whole.h5", ["landing/position", "impact/time"])


def test_in_air_every_cpu_schedule_gives_the_same_bits(tmp_path):
    """The CPU's one-launch phase, its host loop of blocks and the per-step kernels (CUDA's path,
    the kick kernel included) give the same file in air."""
    from tests.conftest import DEVICES
    from warp_ricochet import api

    if "cpu" not in DEVICES:
        pytest.skip("the CPU's schedules (this run's devices exclude the CPU)")
    from warp_ricochet.dense import phase
    from warp_ricochet.dense.phase import DenseOptions

    sets = [
        "air.density=1.225",
        FIELDS,
        "shot.count=60",
        "shot.shots=2",
        "collisions.enabled=true",
        'numerics.precision="float64"',
    ]
    scene = load_scene(PAPER, sets)
    for name, options in (
        ("one", DenseOptions()),
        ("block", DenseOptions(cpu_steps="block")),
        ("kernels", DenseOptions(cpu_steps="kernels")),
    ):
        stats = api.run(scene, output=tmp_path / f"{name}.h5", device="cpu", dense_options=options)
        assert stats["pair_collisions"] > 10
    launched = []
    with pytest.MonkeyPatch.context() as patch:  # the horizon (leap bounds) and the separation in pieces
        patch.setattr(phase, "HORIZON_PAIRS_PER_LAUNCH", 4 * 120)
        patch.setattr(phase, "SEPARATION_PELLETS_PER_LAUNCH", 7)
        launch = phase.DensePhase._launch
        patch.setattr(
            phase.DensePhase, "_launch", lambda self, name, *a, **k: launched.append(name) or launch(self, name, *a, **k)
        )
        api.run(scene, output=tmp_path / "pieces.h5", device="cpu", dense_options=DenseOptions(cpu_steps="kernels"))
    assert launched.count("horizon_kernel") >= 8 and launched.count("separate_kernel") == 9  # (60 pellets: 30 partners)
    for name in ("block", "kernels", "pieces"):
        assert_same_run(tmp_path / f"{name}.h5", tmp_path / "one.h5", ["landing/position", "impact/velocity"], progress=())
