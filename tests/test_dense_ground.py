"""The ground's laws at the dense phase's impacts (`dense.events.meet_ground`): rough ground's draw
keyed by (seed, pellet, impact), entry into the ground and the skip apply there as at the core's
impacts, so a pellet that never meets another in the dense phase ends where the same pellet ends
in a run without collisions."""

import h5py
import numpy as np

import warp_ricochet as wr
from warp_ricochet.scene import load_scene

SCENE = "examples/paper.toml"


def _run(tmp_path, material, collisions, fields, device):
    overrides = [
        "shot.shots=3",
        "shot.count=40",
        f"collisions.enabled={collisions}",
        'physics.until="rest"',
        f'surfaces.0.material="{material}"',
        'numerics.precision="float64"',
        f"output.fields={fields}",
    ]
    path = tmp_path / f"{material}-{collisions}.h5"
    stats = wr.run(load_scene(SCENE, overrides), path, device=device)
    with h5py.File(path, "r") as f:
        arrays = {
            name: f[f"pellets/{name}"][()] for name in ("rest/position", "rest/state", "impact/velocity", "initial/position")
        }
        if collisions == "true":
            arrays["collisions/count"] = f["pellets/collisions/count"][()]
    return stats, arrays


def test_pellets_the_dense_phase_leaves_alone_end_as_without_collisions_on_rough_turf(tmp_path, device):
    fields = '["initial.position", "impact.velocity", "rest", "collisions.count"]'
    _, dense = _run(tmp_path, "turf", "true", fields, device)
    _, core = _run(tmp_path, "turf", "false", fields.replace(', "collisions.count"', ""), device)
    alone = dense["collisions/count"] == 0
    assert alone.sum() >= 60  # (most of the paper's 40 pellets a shot meet no other)
    np.testing.assert_array_equal(dense["rest/state"][alone], core["rest/state"][alone])
    # the dense phase flies the launch to the first impact its own way: 4e-5 m/s apart there (the
    # draws apart: 91 m/s and kilometres apart at rest)
    np.testing.assert_allclose(dense["impact/velocity"][alone], core["impact/velocity"][alone], atol=1e-3, equal_nan=True)
    travelled = np.linalg.norm(core["rest/position"][alone] - core["initial/position"][alone], axis=1)
    moved = np.linalg.norm(dense["rest/position"][alone] - core["rest/position"][alone], axis=1)
    assert (moved <= 1e-4 * travelled).all(), (moved.max(), travelled.min())


def test_a_steep_shot_enters_water_at_its_first_impact_in_the_dense_phase(tmp_path, device):
    with_dense, _ = _run(tmp_path, "water", "true", '["initial.position", "impact.velocity", "rest", "collisions.count"]', device)
    without, _ = _run(tmp_path, "water", "false", '["initial.position", "impact.velocity", "rest"]', device)
    assert with_dense["entered"] == without["entered"] == 120
    assert with_dense["rest_embedded"] == 120 and with_dense["hits"] == 0
