"""Per-shot values of runs with pair collisions followed to rest come from the core kernel's own
threads (`RunSpec.thread_pieces`, `core.shots.ThreadPieces`), with no second pass over the pellets:
they equal the second pass's (`core.shots.ShotPass`) to the rounding of another grouping of the
sums, and are bitwise the same for any chunk size and after --resume."""

import h5py
import numpy as np
import pytest
from helpers import interrupt_after

import warp_ricochet as wr
import warp_ricochet.spec as spec_module
from warp_ricochet.dense.schedule import shot_granule
from warp_ricochet.scene import load_scene
from warp_ricochet.spec import RunSpec

SCENE = "examples/paper.toml"


def _overrides(count, shots, *extra):
    return [
        f"shot.count={count}",
        f"shot.shots={shots}",
        "collisions.enabled=true",
        'physics.until="rest"',
        'surfaces.0.material="turf"',
        'numerics.precision="float64"',
        "output.fields=[]",
        *extra,
    ]


@pytest.mark.parametrize("count", [40, 300])  # one piece a shot of 64 slots; two pieces of 512 slots
def test_per_shot_values_from_the_core_threads_equal_the_second_pass(monkeypatch, count, device):
    scene = load_scene(SCENE, _overrides(count, 5))
    assert RunSpec.of(scene).thread_pieces
    core = wr.run(scene, device=device)
    monkeypatch.setattr(spec_module, "_thread_pieces", lambda scene: False)
    second = wr.run(scene, device=device)
    assert core["rest_at_rest"] + core["rest_embedded"] > 0 and core.ensemble.shots == 5
    for name, values in second.ensemble.per_shot.items():
        np.testing.assert_allclose(core.ensemble.per_shot[name], values, rtol=1e-12, atol=1e-9, err_msg=name)


def test_only_collision_runs_to_rest_of_sixteen_slots_a_shot_take_them():
    rest = ['physics.until="rest"', "collisions.enabled=true"]
    assert not RunSpec.of(load_scene(SCENE, ["shot.count=8", *rest])).thread_pieces  # stride 8 < 16
    assert RunSpec.of(load_scene(SCENE, ["shot.count=9", *rest])).thread_pieces
    assert not RunSpec.of(load_scene(SCENE, ["shot.count=300", "collisions.enabled=true"])).thread_pieces
    assert not RunSpec.of(load_scene(SCENE, ["shot.count=300", 'physics.until="rest"'])).thread_pieces


def test_chunk_size_and_resume_leave_every_bit(tmp_path):
    count = 600  # 1,024 slots a shot: a chunk of whole segments holds 64 shots
    shots = shot_granule(count) + 2
    scene = load_scene(SCENE, _overrides(count, shots, f"numerics.chunk_size={count * shot_granule(count)}"))
    whole = wr.run(load_scene(SCENE, _overrides(count, shots, f"numerics.chunk_size={count * shots}")), device="cpu")
    out = tmp_path / "r.h5"
    interrupt_after(1, scene, out)
    resumed = wr.run(scene, out, device="cpu", resume=True)
    for name, values in whole.ensemble.per_shot.items():
        np.testing.assert_array_equal(resumed.ensemble.per_shot[name], values, err_msg=name)
    with h5py.File(out, "r") as f:
        assert f["stats/shots"].attrs["shots"] == shots
