"""The hazard along the path inside the dense phase (`dense.watch`, docs/hazard.md section 11): each
pellet's watch is kept from its launch through the dense phase's steps and handed to the core with
the release, its passes counted into the run's tally once per cell entry.

- Pellets spread apart so that none meets another (pair count 0) get, in a collision run, the
  reaches, exposure maps and named places of the same scene without collisions: in vacuum bitwise
  (the dense phase flies the same parabolas from the same reference states), in air within the
  dense phase's own flight (its kicks against the core's integrated flight: 5 mm apart in reach
  here) and, for the maps and places, equal. Before this, the maps missed every pass from the
  muzzle to the release (64-67 m out in vacuum here): 4,437 of the 14,598 exposure counts and 48 of
  the 54 place counts in vacuum, 3,482 of 4,865 and all 34 in air, where 32 of the 48 reaches
  were none (the pellets below those thresholds at the release).
- Pellets leaping in air (past the arrival window) are watched on their integrated flight.
- A pellet thrown back by a wall near the muzzle inside the dense phase gets the reach of its
  farthest point above the threshold (at the wall), not its release's (NaN before: its speed at the
  release is below the threshold).
- Bitwise the same for two chunk sizes, after an interrupted run is resumed, and from the per-step
  kernels (the CUDA path's) as from the CPU's one-launch phase.
"""

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import assert_same_run, busy_lattice, interrupt_after, stats_equal
from tests.test_resume_collisions import CHUNK
from tests.test_resume_collisions import OVERRIDES as RESUME_OVERRIDES
from warp_ricochet.dense.phase import DenseOptions
from warp_ricochet.scene import load_scene, scene_from_dict

R = 0.00125  # m
SPEEDS = {"fast": 250.0, "mid": 150.0, "slow": 60.0}  # m/s
WALL = 8.0  # m downrange


def _scene(collisions, air=False, wall=False):
    """Pellets at 300 m/s from 1.5 m up, 2 degrees down, 0.4 m apart in their envelope (none meets
    another), onto a grass-like plane (and a wall facing the shooter): a map and two places."""
    raw = {
        "shot": {
            "count": 8,
            "shots": 2,
            "diameter": 2 * R,
            "density": 11340.0,
            "speed": 300.0,
            "direction": [1.0, -0.035, 0.0],
            "direction_jitter": [0.0, 0.02, 0.02],
            "envelope_radius": 0.4,
            "envelope_center": [0.0, 1.5, 0.0],
            "seed": 3,
        },
        "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.4, "mu_s": 0.4, "mu_d": 0.35}],
        "physics": {"bounces": 3},
        "collisions": {"enabled": collisions},
        "numerics": {"precision": "float64"},
        "hazard": {
            "speed": SPEEDS,
            "energy_density": {},
            "shooter": [0.0, 1.5, 0.0],
            "map_cell": 0.5,
            "map_extent": [-20.0, 150.0, -10.0, 10.0],
            "points": [
                {"name": "near", "position": [15.0, 0.0, 0.0], "area": 1.0},
                {"name": "mid", "position": [40.0, 0.0, 0.3], "area": 1.0},
            ],
        },
        "output": {"fields": ["hazard", "impact.position"] + (["collisions.count", "release.position"] if collisions else [])},
    }
    if air:
        raw["air"] = {"density": 1.225}
    if wall:
        wall = {"point": [WALL, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0], "restitution": 0.6, "mu_s": 0.2, "mu_d": 0.15}
        raw["surfaces"].append(wall)
    return scene_from_dict(raw)


def _run(tmp_path, name, scene, options=None, device="cpu"):
    """Run `scene` to tmp_path/name.h5 on `device`: {dataset path: its values} of the pellets and the hazard."""
    path = tmp_path / f"{name}.h5"
    wr.run(scene, path, device=device, dense_options=options)
    found = {}
    with h5py.File(path, "r") as f:
        for group in ("pellets", "hazard"):
            f[group].visititems(
                lambda n, obj, g=group: found.update({f"{g}/{n}": obj[()]}) if isinstance(obj, h5py.Dataset) else None
            )
    return found


@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
def test_pellets_that_meet_none_watch_as_without_collisions(tmp_path, air, device):
    dense = _run(tmp_path, "dense", _scene(True, air), device=device)
    core = _run(tmp_path, "core", _scene(False, air), device=device)
    assert dense["pellets/collisions/count"].sum() == 0
    # the dense phase flies them far: its release is past the first impact (about 43 m out)
    release = np.linalg.norm(dense["pellets/release/position"][:, [0, 2]], axis=1)
    assert release.min() > 50.0, release.min()
    reach, expected = dense["pellets/hazard/reach"], core["pellets/hazard/reach"]
    np.testing.assert_array_equal(np.isnan(reach), np.isnan(expected))
    assert np.isfinite(expected).sum() >= 40  # most pellets exceed most thresholds at body height
    # vacuum: the same parabolas, bitwise; air: the dense phase's kicks against the core's
    # integrated flight move a threshold's crossing by up to 5 mm here (1 cm: the bound)
    np.testing.assert_allclose(reach, expected, rtol=0.0, atol=1e-2 if air else 0.0, equal_nan=True)
    for name in ("hazard/map/exposure", "hazard/map/exposure_outside", "hazard/map/passes", "hazard/points/pellets"):
        np.testing.assert_array_equal(dense[name], core[name], err_msg=name)
    assert dense["hazard/map/exposure"].sum() > (3_000 if air else 10_000)


def test_a_pellet_thrown_back_inside_the_dense_phase_gets_the_reach_of_its_farthest_point(tmp_path, device):
    dense = _run(tmp_path, "dense", _scene(True, wall=True), device=device)
    core = _run(tmp_path, "core", _scene(False, wall=True), device=device)
    assert dense["pellets/collisions/count"].sum() == 0
    # every pellet meets the wall first (it is within body height, at 280-300 m/s) and leaves it
    # below 250 m/s, towards the shooter: its "fast" reach is the wall's contact, not the release's
    first = dense["pellets/impact/position"][:, 0]
    np.testing.assert_allclose(first[:, 0], WALL - R, atol=1e-9)
    wall_distance = np.hypot(first[:, 0], first[:, 2])
    release = np.linalg.norm(dense["pellets/release/position"][:, [0, 2]], axis=1)
    assert (release < wall_distance - 0.5).all(), release.max()
    fast = list(SPEEDS).index("fast")
    np.testing.assert_allclose(dense["pellets/hazard/reach"][:, fast], wall_distance, rtol=1e-12)
    # bitwise on the CPU; on CUDA the two kernels' fused multiply-adds differ by an ulp (measured)
    reach, expected = dense["pellets/hazard/reach"], core["pellets/hazard/reach"]
    np.testing.assert_allclose(reach, expected, rtol=0 if device == "cpu" else 1e-15, atol=0, equal_nan=True)
    for name in ("hazard/map/exposure", "hazard/map/exposure_outside", "hazard/points/pellets"):
        np.testing.assert_array_equal(dense[name], core[name], err_msg=name)


def _busy_lattice(tmp_path, collisions):
    """tests/test_air_leaps.py's lattice in air: 20 pellets 10 cm apart fired at the ground (none
    meets another) and, below the ground, a slow pair that meets 97 ms later and keeps the shot in
    the dense phase, which leaps past its arrival window while the 20 fly on: their leaps are flown
    by the integrated flight, watched."""
    raw = {
        **busy_lattice(tmp_path / "busy.npz"),
        "hazard": {
            "speed": {"fast": 150.0, "slow": 50.0},
            "energy_density": {},
            "shooter": [0.0, 1.0, 0.0],
            "map_cell": 0.5,
            "map_extent": [-5.0, 200.0, -10.0, 10.0],
            "points": [{"name": "near", "position": [1.5, 0.0, 0.2], "area": 1.0}],
        },
        "output": {"fields": ["hazard"]},
        "collisions": {"enabled": collisions},
    }
    path = tmp_path / f"busy-{collisions}.h5"
    stats = wr.run(scene_from_dict(raw), path, device="cpu")
    with h5py.File(path, "r") as f:
        names = ("pellets/hazard/reach", "hazard/map/exposure", "hazard/map/exposure_outside", "hazard/points/pellets")
        return stats, {name: f[name][()] for name in names}


def test_pellets_leaping_in_air_are_watched_on_their_flight(tmp_path):
    stats, dense = _busy_lattice(tmp_path, True)
    _, core = _busy_lattice(tmp_path, False)
    assert stats["pair_collisions"] == 1 and stats["dense_time_max"] > 0.09  # (the far pair: the 20 leap)
    reach = dense["pellets/hazard/reach"][:20]
    assert np.isfinite(reach).all()
    np.testing.assert_allclose(reach, core["pellets/hazard/reach"][:20], rtol=0.0, atol=1e-2)
    # (the slow pair, below every threshold, counts in no exposure map nor place)
    for name in ("hazard/map/exposure", "hazard/map/exposure_outside", "hazard/points/pellets"):
        np.testing.assert_array_equal(dense[name], core[name], err_msg=name)


def test_the_per_step_kernels_watch_the_bits_of_the_one_launch_phase(tmp_path):
    """In air (kicks, leaps): the host loop of per-step kernels on HashGrid lists, as on CUDA, with
    the watch's struct recorded in its commands, gives the one-launch phase's bits."""
    phase = _run(tmp_path, "phase", _scene(True, air=True))
    kernels = _run(tmp_path, "kernels", _scene(True, air=True), DenseOptions(cpu_steps="kernels", cpu_lists="hashgrid"))
    assert phase.keys() == kernels.keys()
    for name, values in phase.items():
        np.testing.assert_array_equal(kernels[name], values, err_msg=name)


# tests/test_resume_collisions.py's scene in chunks of CHUNK pellets (the paper's shot 5 cm above a livelier ground, a fixed
# step: a few percent of the pellets collide), watched at body height on a map with a place
OVERRIDES = [
    *RESUME_OVERRIDES,
    "hazard.speed={fast = 300.0, slow = 100.0}",
    "hazard.energy_density={}",
    "hazard.shooter=[0.0, 0.05, 0.0]",
    "hazard.map_cell=0.05",
    "hazard.map_extent=[-1.0, 4.0, -1.0, 1.0]",
    'hazard.points=[{name = "a", position = [0.5, 0.0, 0.0], area = 0.2}]',
    'output.fields=["hazard", "collisions.count"]',
]
FIELDS = ("hazard/reach", "hazard/exceeds", "collisions/count")


def _chunked(chunks):
    return load_scene("examples/paper.toml", [*OVERRIDES, f"numerics.chunk_size={chunks * CHUNK}"])


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The run in chunks of CHUNK pellets: (path, stats)."""
    path = tmp_path_factory.mktemp("reference") / "ref.h5"
    stats = wr.run(_chunked(1), path, device="cpu")
    with h5py.File(path, "r") as f:
        assert f["progress/chunk_rows"][()] == CHUNK
        assert f["pellets/collisions/count"][()].sum() > 1000  # pellets that meet others are watched too
        assert f["hazard/map/exposure"][()].sum() > 0 and f["hazard/points/pellets"][()].sum() > 0
    return path, stats


def test_two_chunk_sizes_give_the_same_bits(tmp_path, reference):
    stats = wr.run(_chunked(2), tmp_path / "two.h5", device="cpu")
    assert_same_run(tmp_path / "two.h5", reference[0], FIELDS)
    assert stats_equal(stats, reference[1])


def test_resume_after_a_chunk_gives_the_same_bits(tmp_path, reference):
    out = tmp_path / "resumed.h5"
    interrupt_after(1, _chunked(1), out)
    stats = wr.run(_chunked(1), out, device="cpu", resume=True)
    assert_same_run(out, reference[0], FIELDS)
    assert stats_equal(stats, reference[1])
