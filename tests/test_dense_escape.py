"""The escape rule inside the dense phase (`dense.watch`, docs/hazard.md section 11, "Escapes"): a
pellet with no surface ahead is watched, as in the core, only until its centre is below the
hazard's ground plane and falling; there its watch ends for good.

- A hostile shot (tests of issue 26): 40 pellets packed in a 8 mm envelope, launched 1 m below the
  ground plane (the one surface, met only from above), falling, most of them colliding. Without
  the rule the dense phase watched their paths below the plane to their pair contacts: 249-276
  reaches and 423-531 map passes per run in vacuum, every reach (360) and 876-1,359 passes in air
  (measured), where the same shots without collisions have none. With it: none, as without.
- The same shot above a lower plane 3 m below the ground (a surface it meets): every pellet is
  watched to that plane and on, colliding or not, as the core watches a flight with a contact
  ahead: its reach above each threshold it exceeds at its first impact on the lower plane is at
  least as far as that impact, and every pellet has a reach above every threshold.
- In air, a leap (`dense.leap`): tests/test_air_leaps.py's lattice (its slow pair below the ground
  keeps the shot in the dense phase, which leaps) and one more pellet 0.5 m below the ground at
  100 m/s, rising at 0.5 m/s: the core watches it to its apex (51 ms, 5.0 m out); in the collision
  run it reaches its apex inside a leap, whose flight now ends its watch there, as the core's. Before:
  a reach of 9.05 m (watched to the release), 6.57 m with the rule in the kicks alone; passes 8,020
  against the core's 8,010 (the slow pair's 2 among them).
"""

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import busy_lattice
from warp_ricochet.scene import scene_from_dict

R = 0.00125  # m
SPEEDS = {"fast": 250.0, "mid": 150.0, "slow": 60.0}  # m/s
SHOOTER = np.array([0.0, 1.5, 0.0])  # m
LOWER = -3.0  # m: the lower plane's height (the ground plane is y = 0)
SEEDS = (1, 2, 3)


def _scene(collisions, seed, air=False, lower=False, precision="float32"):
    """3 shots of 40 pellets at 300 m/s, 3 degrees down from 1 m below the ground plane y = 0 (and,
    with `lower`, above a plane at y = LOWER): a map and a named place on the ground."""
    surface = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.4, "mu_s": 0.4, "mu_d": 0.35}
    raw = {
        "shot": {
            "count": 40,
            "shots": 3,
            "diameter": 2 * R,
            "density": 11340.0,
            "speed": 300.0,
            "direction": [1.0, -0.05, 0.0],
            "direction_jitter": [0.0, 0.03, 0.03],
            "envelope_radius": 0.008,
            "envelope_center": [0.0, -1.0, 0.0],
            "seed": seed,
        },
        "surfaces": [surface] + ([{**surface, "point": [0.0, LOWER, 0.0]}] if lower else []),
        "physics": {"bounces": 3},
        "collisions": {"enabled": collisions},
        "numerics": {"precision": precision},
        "hazard": {
            "speed": SPEEDS,
            "energy_density": {},
            "shooter": SHOOTER.tolist(),
            "map_cell": 0.5,
            "map_extent": [-20.0, 150.0, -10.0, 10.0],
            "points": [{"name": "near", "position": [5.0, 0.0, 0.0], "area": 1.0}],
        },
        "output": {
            "fields": ["hazard", "impact.position", "impact.velocity_before"] + (["collisions.count"] if collisions else [])
        },
    }
    if air:
        raw["air"] = {"density": 1.225}
    return scene_from_dict(raw)


MAPS = ("hazard/map/exposure", "hazard/map/exposure_outside", "hazard/map/passes", "hazard/points/pellets")


def _run(path, scene, device):
    """Run `scene` to `path`: its reaches, impact positions, pair counts and the maps."""
    wr.run(scene, path, device=device)
    with h5py.File(path, "r") as f:
        found = {name: f[name][()] for name in MAPS}
        found["reach"] = f["pellets/hazard/reach"][()]
        found["impacts"] = f["pellets/impact/position"][()]
        found["speeds"] = np.linalg.norm(f["pellets/impact/velocity_before"][()], axis=-1)
        found["count"] = f["pellets/collisions/count"][()] if "pellets/collisions/count" in f else None
    return found


@pytest.mark.filterwarnings("ignore::warp_ricochet.SceneWarning")  # (no pellet hits a surface)
@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
def test_a_shot_below_the_ground_escapes_with_collisions_as_without(tmp_path, air, device):
    collided = 0
    for seed in SEEDS:
        dense = _run(tmp_path / f"dense{seed}.h5", _scene(True, seed, air), device)
        core = _run(tmp_path / f"core{seed}.h5", _scene(False, seed, air), device)
        collided += (dense["count"] > 0).sum()
        assert np.isnan(core["reach"]).all()
        assert np.isnan(dense["reach"]).all(), np.isfinite(dense["reach"]).sum()
        for name in MAPS:
            assert core[name].sum() == 0, name
            np.testing.assert_array_equal(dense[name], core[name], err_msg=name)
    assert collided >= len(SEEDS) * 120 // 2, collided  # (hostile: most pellets meet another below the plane)


@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
def test_pellets_below_the_ground_with_a_lower_plane_ahead_are_watched(tmp_path, air, device):
    for seed in SEEDS[:2]:
        dense = _run(tmp_path / f"dense{seed}.h5", _scene(True, seed, air, lower=True), device)
        assert (dense["count"] > 0).sum() >= 60, (dense["count"] > 0).sum()
        first = dense["impacts"][:, 0]
        np.testing.assert_allclose(first[:, 1], LOWER + R, atol=1e-4)  # (every pellet meets the lower plane first)
        distance = np.hypot(first[:, 0] - SHOOTER[0], first[:, 2] - SHOOTER[2])
        reach = dense["reach"]
        assert np.isfinite(reach).all(), np.isnan(reach).sum()  # (every pellet: all of its path is within body height)
        # watched at least up to its first impact, for each threshold it exceeds there (float32
        # rounding of the distances: 1e-3 m)
        exceeded = dense["speeds"][:, 0, None] >= np.array(list(SPEEDS.values()))
        assert exceeded[:, -1].all() and exceeded.sum() >= (120 if air else 360), exceeded.sum(0)
        short = np.where(exceeded, distance[:, None] - reach, -np.inf)
        assert (short <= 1e-3).all(), short.max()
        assert dense["hazard/map/exposure"].sum() > 10_000


def _lattice_and_a_riser(tmp_path, collisions):
    """`busy_lattice` in air and a pellet 0.5 m below the ground rising at 0.5 m/s, flying 100 m/s
    along x 2 m aside: its reach and the maps."""
    raw = busy_lattice(tmp_path / "busy.npz")
    pellets = dict(np.load(tmp_path / "busy.npz"))
    for name, row in (("position", [0.0, -0.5, 2.0]), ("velocity", [100.0, 0.5, 0.0]), ("angular_velocity", [0.0, 0.0, 0.0])):
        pellets[name] = np.concatenate([pellets[name], [row]])
    np.savez(tmp_path / "busy.npz", **pellets)
    raw["hazard"] = {
        "speed": {"fast": 150.0, "slow": 50.0},
        "energy_density": {},
        "shooter": [0.0, 1.0, 0.0],
        "map_cell": 0.5,
        "map_extent": [-5.0, 200.0, -10.0, 10.0],
        "points": [{"name": "near", "position": [1.5, 0.0, 0.2], "area": 1.0}],
    }
    raw.update(output={"fields": ["hazard"]}, collisions={"enabled": collisions})
    path = tmp_path / f"riser-{collisions}.h5"
    stats = wr.run(scene_from_dict(raw), path, device="cpu")
    with h5py.File(path, "r") as f:
        found = {name: f[name][()] for name in MAPS}
        found["reach"] = f["pellets/hazard/reach"][()]
    return stats, found


def test_a_pellet_below_the_ground_that_falls_in_a_leap_stops_being_watched_there(tmp_path):
    stats, dense = _lattice_and_a_riser(tmp_path, True)
    _, core = _lattice_and_a_riser(tmp_path, False)
    assert stats["pair_collisions"] == 1 and stats["dense_time_max"] > 0.09  # (the slow pair: the shot leaps)
    riser, apex = dense["reach"][-1], 100.0 * 0.5 / 9.81  # m: its apex's distance in vacuum (air: a little less)
    assert np.isnan(riser[0]) and 0.95 * apex < core["reach"][-1, 1] <= apex
    np.testing.assert_allclose(riser, core["reach"][-1], rtol=0.0, atol=1e-2, equal_nan=True)
    for name in MAPS:  # (the slow pair counts none: it escapes at once, as in the core)
        np.testing.assert_array_equal(dense[name], core[name], err_msg=name)
