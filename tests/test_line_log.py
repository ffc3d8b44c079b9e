"""The step log (`physics.line_log`): a phase's steps along a line are watched after, in their order
with their values, so the hazard's outputs and the rest positions are the same bits for any log size
as without a log (0: each step watched at once; 1: after the next is taken; 2 and 3: logs filled and
emptied inside a phase) and with a column of the log a thread (a GPU's layout) as with the one
column a CPU shares. On plain ground (the steps gathered along their chord, with a map), on rough
ground (each step watched at once, its chord turning) and after pair collisions (the pellets from the
dense phase's release). A CPU runs a kernel's threads one after another, so only a GPU can show two
threads racing on a column: the host refuses a launch with more threads than the log has columns,
and a chunk whose log a 32-bit index would not reach."""

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from warp_ricochet import pipeline
from warp_ricochet.chunks import INDEX_LIMIT, MAX_CHUNK, log_rows, log_words, log_words_per_pellet, plan_rows, plan_shots
from warp_ricochet.dense.schedule import shot_stride
from warp_ricochet.physics import line_log
from warp_ricochet.physics.line_log import LOG_WORDS, ROUGH_WORDS
from warp_ricochet.scene import load_scene
from warp_ricochet.spec import RunSpec
from warp_ricochet.tallies.reduce import SEGMENT, threads_for

PAPER = Path(__file__).resolve().parents[1] / "examples" / "paper.toml"
AIR = ("air.density=1.225",)
REST = ('physics.until="rest"', "surfaces.0.rolling_resistance=0.05", "surfaces.0.mu_s=0.5", "surfaces.0.mu_d=0.45")
MAP = ("hazard.map_cell=0.5", "hazard.map_extent=[0.0, 400.0, -50.0, 50.0]")
CASES = {  # (settings, log sizes against the default)
    "plain-map": ((*AIR, *REST, *MAP, "hazard.fractions=[1e-3]"), (0, 1, 3)),
    "rough-reach": ((*AIR, *REST, "surfaces.0.roughness=0.3", "hazard.fractions=[1e-3]"), (0, 2)),
    "collisions": ((*AIR, *REST, "collisions.enabled=true", "shot.shots=3", "hazard.fractions=[1e-3]"), (0,)),
}
KEYS = ("pellets/hazard/reach", "pellets/rest/position", "hazard/map/exposure", "hazard/map/passes")


def _scene(settings, pellets=200, fields=("hazard", "rest")):
    sets = [f"shot.count={pellets}", 'numerics.precision="float32"', "output.fields=" + json.dumps(list(fields))]
    return load_scene(PAPER, sets + list(settings))


def _outputs(tmp_path, name, scene):
    path = tmp_path / f"{name}.h5"
    wr.run(scene, path, device="cpu", overwrite=True)
    with h5py.File(path) as f:
        return {key: f[key][()] for key in KEYS if key in f}


def _columns(spec, device, rows):
    """A column of the step log a thread on the CPU too (a GPU's layout)."""
    return threads_for(rows, spec.lanes) if spec.to_rest and spec.watch[0] > 0 else 0


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_hazard_is_the_same_bits_for_any_log_size_and_layout(tmp_path, monkeypatch, case):
    settings, sizes = CASES[case]
    scene = _scene(settings)
    assert RunSpec.of(scene).to_rest and RunSpec.of(scene).watch[0] > 0
    default = _outputs(tmp_path, "default", scene)
    assert np.isfinite(default["pellets/hazard/reach"]).any()  # (something reached: the comparison bites)
    runs = {}
    with monkeypatch.context() as m:
        m.setattr(pipeline, "log_threads", _columns)
        runs["a column a thread"] = _outputs(tmp_path, "columns", scene)
    for size in sizes:
        with monkeypatch.context() as m:
            m.setattr(line_log, "LOG_STEPS", size)
            assert RunSpec.of(scene).log_steps == size
            runs[f"{size} steps"] = _outputs(tmp_path, f"steps{size}", scene)
    for name, outputs in runs.items():
        assert outputs.keys() == default.keys()
        for key, value in default.items():
            np.testing.assert_array_equal(outputs[key], value, err_msg=f"{name}: {key}")


def test_a_spec_logs_the_package_s_log_size_by_default():
    assert RunSpec("float32", 0, 0).log_steps == line_log.LOG_STEPS


class _H200:
    """A stand-in for a GPU of 140 GB free (the chunk planners read these two)."""

    is_cuda = True
    free_memory = 140e9


@pytest.mark.parametrize("rough", [False, True])
def test_a_gpu_chunk_keeps_the_step_log_within_a_32_bit_index(rough):
    settings = (*AIR, *REST, "hazard.fractions=[1e-3]", *(("surfaces.0.roughness=0.3",) if rough else ()))
    scene = _scene(settings)
    spec = RunSpec.of(scene, with_output=False)
    assert log_words(spec) == spec.log_steps * (ROUGH_WORDS if rough else LOG_WORDS)
    assert log_words_per_pellet(spec) == log_words(spec) * spec.lanes / SEGMENT
    rows = log_rows(spec)
    assert rows % SEGMENT == 0 and rows < MAX_CHUNK
    assert threads_for(rows, spec.lanes) * log_words(spec) <= INDEX_LIMIT
    assert threads_for(rows + SEGMENT, spec.lanes) * log_words(spec) > INDEX_LIMIT
    big = load_scene(PAPER, [*settings, "shot.count=1000000000"])
    assert plan_rows(big, _H200(), big.shot.pellets, ()) <= log_rows(spec)
    landing = RunSpec.of(_scene(("hazard.fractions=[1e-3]",), fields=()), with_output=False)  # (no phase along a line)
    assert log_words_per_pellet(landing) == 0 and log_rows(landing) == MAX_CHUNK


@pytest.mark.parametrize(("count", "chunk"), [(600, 0), (460, 0), (1000, 0), (600, 300_000_000), (450, 300_000_000)])
def test_a_gpu_chunk_of_collision_shots_keeps_the_step_log_within_a_32_bit_index(monkeypatch, count, chunk):
    """With the watch in the core (`path_replay.REPLAY` "never"; a replay's record log is indexed in 64
    bits: tests/test_path_replay.py)."""
    from warp_ricochet.tallies import path_replay

    monkeypatch.setattr(path_replay, "REPLAY", "never")
    sets = [*AIR, *REST, "collisions.enabled=true", "hazard.fractions=[1e-3]", f"shot.count={count}", "shot.shots=1000000"]
    scene = load_scene(PAPER, sets + ([f"numerics.chunk_size={chunk}"] if chunk else []))
    spec = RunSpec.of(scene, with_output=False)
    slots = plan_shots(scene, _H200(), scene.shot.shots) * shot_stride(count)
    assert slots <= log_rows(spec) and threads_for(slots, spec.lanes) * log_words(spec) <= INDEX_LIMIT


def test_a_launch_with_more_threads_than_the_log_has_columns_is_refused():
    scene = _scene((*AIR, *REST, "hazard.fractions=[1e-3]"))
    spec = RunSpec.of(scene, with_output=False)
    tally = type("Tally", (), {"struct": type("Struct", (), {"log_threads": 4096})()})()
    pipeline.check_log(tally, spec, _H200(), 4096 * SEGMENT // spec.lanes)  # (fits: no error)
    with pytest.raises(RuntimeError, match="step log of 4096 threads for a launch of 8192"):
        pipeline.check_log(tally, spec, _H200(), 2 * 4096 * SEGMENT // spec.lanes)
