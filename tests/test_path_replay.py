"""The watch replayed by a kernel of its own (`tallies.path_replay`, `core.replay`): the core kernel
records each call of the hazard's watch into its pellet's column, the replay kernel makes the same calls
after it, so the hazard's outputs are the same bits as with the watch in the core (on the CPU: a GPU
compiles the watch's roots in another kernel, within rounding). Pellets whose records do not fit are
followed again by the core kernel with the watch in it and nothing else counted: the same bits too.
Each column is replayed in order. Runs replay on GPUs by default; here on the CPU (`REPLAY = "always"`)."""

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.test_line_log import PAPER, _scene
from warp_ricochet import pipeline
from warp_ricochet.chunks import (
    DEVICE_FRACTION,
    INDEX_LIMIT,
    MAX_CHUNK,
    device_bytes_per_pellet,
    log_rows,
    log_words,
    log_words_per_pellet,
    plan_rows,
)
from warp_ricochet.core import replay
from warp_ricochet.scene import load_scene
from warp_ricochet.spec import RunSpec
from warp_ricochet.tallies import counts, path_replay
from warp_ricochet.tallies.counts import log_buffer
from warp_ricochet.tallies.reduce import SEGMENT

AIR = ("air.density=1.225",)
REST = ('physics.until="rest"', "surfaces.0.rolling_resistance=0.05", "surfaces.0.mu_s=0.5", "surfaces.0.mu_d=0.45")
MAP = ("hazard.map_cell=0.5", "hazard.map_extent=[0.0, 400.0, -50.0, 50.0]")
PLACE = ('hazard.points=[{name="path", position=[100.0, 0.0, 0.0], area=0.7}]',)
CASES = {
    "reach": (*AIR, *REST, "hazard.fractions=[1e-3]"),
    "map-places": (*AIR, *REST, *MAP, *PLACE, "hazard.fractions=[1e-3]"),
    "rough": (*AIR, *REST, "surfaces.0.roughness=0.3", "hazard.fractions=[1e-3]"),
    "collisions": (*AIR, *REST, *MAP, "collisions.enabled=true", "shot.shots=3", "hazard.fractions=[1e-3]"),
    "vacuum": (*REST, "hazard.fractions=[1e-3]"),
}


class _H200:
    """A stand-in for a GPU of 140 GB free (the chunk planners and `replays_on` read these)."""

    is_cuda = True
    free_memory = 140e9


def _outputs(tmp_path, name, scene):
    """Every hazard and per-pellet dataset of a run of `scene` on the CPU."""
    path = tmp_path / f"{name}.h5"
    wr.run(scene, path, device="cpu", overwrite=True)
    found = {}
    with h5py.File(path) as f:
        f.visititems(
            lambda key, obj: (
                found.__setitem__(key, obj[()])
                if isinstance(obj, h5py.Dataset) and key.split("/")[0] in ("hazard", "pellets") and obj.dtype.kind in "fiu"
                else None
            )
        )
    return found


def _same(a, b, label):
    assert a.keys() == b.keys(), label
    for key, value in a.items():
        np.testing.assert_array_equal(b[key], value, err_msg=f"{label}: {key}")


def _runs(tmp_path, monkeypatch, scene, words=None):
    """The outputs with the watch in the core and replayed (columns of `words` words), and the
    pellets followed again."""
    reruns = []
    after = replay.Replay.after_core

    def spy(self, *args):
        after(self, *args)
        reruns.append(self.reruns)

    at_once = _outputs(tmp_path, "core", scene)
    with monkeypatch.context() as m:
        m.setattr(path_replay, "REPLAY", "always")
        m.setattr(replay.Replay, "after_core", spy)
        if words:
            m.setattr(path_replay, "COLUMN_WORDS", words)
        replayed = _outputs(tmp_path, "replayed", scene)
    assert reruns, "the run did not replay"
    return at_once, replayed, reruns[-1]


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_replayed_watch_gives_the_same_bits_as_the_watch_in_the_core(tmp_path, monkeypatch, case):
    scene = _scene(CASES[case])
    at_once, replayed, reruns = _runs(tmp_path, monkeypatch, scene)
    assert np.isfinite(at_once["pellets/hazard/reach"]).any()  # (something reached: the comparison bites)
    assert reruns < scene.shot.pellets  # (most pellets replayed; after pair collisions some need >512 words)
    _same(at_once, replayed, case)


def test_the_logs_are_read_only_where_written(tmp_path, monkeypatch):
    """The step and record logs are not zeroed (`counts.log_buffer`): filled with NaN first, both the
    watch in the core and its replay give the same bits as ever."""
    import warp as wp

    scene = _scene(CASES["map-places"])
    clean, _, _ = _runs(tmp_path, monkeypatch, scene)
    filled = []

    def nan_filled(shape, dtype, device):
        filled.append(shape)
        return wp.full(shape, value=dtype(float("nan")), dtype=dtype, device=device)

    monkeypatch.setattr(counts, "_unset", nan_filled)
    at_once, replayed, _ = _runs(tmp_path, monkeypatch, scene)
    assert sum(1 for shape in filled if np.prod(shape) > 0) >= 2  # (both runs' logs made by `_unset`, not empty)
    _same(clean, at_once, "the watch in the core, its step log filled with NaN")
    _same(clean, replayed, "the replay, its record log filled with NaN")


@pytest.mark.parametrize(("case", "words"), [("reach", 64), ("map-places", 225), ("collisions", 1500)])
def test_pellets_whose_records_do_not_fit_are_followed_again_to_the_same_bits(tmp_path, monkeypatch, case, words):
    scene = _scene(CASES[case])
    at_once, replayed, reruns = _runs(tmp_path, monkeypatch, scene, words)
    assert 0 < reruns
    if words > 64:
        assert reruns < scene.shot.pellets  # (some fit, some not: both paths in one chunk)
    _same(at_once, replayed, f"{case}, columns of {words} words")


def test_a_run_to_rest_that_watches_its_path_replays_on_a_gpu_only():
    scene = _scene(CASES["reach"])
    on_gpu = RunSpec.of(scene, with_output=False, device=_H200())
    assert on_gpu.replay and on_gpu.watch == (4, 0, False, False, True)  # (the four default thresholds)
    assert not RunSpec.of(scene, with_output=False).replay  # (the CPU, or no device known)
    assert not RunSpec.of(scene, with_output=False, device=type("Cpu", (), {"is_cuda": False})()).replay
    landing = _scene(("hazard.fractions=[1e-3]",), fields=())  # (not followed to rest)
    assert not RunSpec.of(landing, with_output=False, device=_H200()).watch[4]
    quiet = _scene(REST, fields=())  # (no hazard: nothing watched, nothing recorded)
    assert RunSpec.of(quiet, with_output=False, device=_H200()).watch == (0, 0, False, False, False)


def test_a_gpu_chunk_of_a_run_that_records_is_bounded_by_memory_not_by_a_32_bit_index():
    scene = _scene(CASES["reach"])
    spec = RunSpec.of(scene, with_output=False, device=_H200())
    assert log_words(spec) == path_replay.COLUMN_WORDS == log_words_per_pellet(spec)
    assert log_rows(spec) == MAX_CHUNK  # (the record log is indexed in 64 bits)
    big = load_scene(PAPER, [*(f"{k}" for k in CASES["reach"]), "shot.count=1000000000"])
    rows = plan_rows(big, _H200(), big.shot.pellets, ())
    assert rows * path_replay.COLUMN_WORDS > INDEX_LIMIT  # (33 M rows of 512 words: 8x past a 32-bit index)
    assert (rows - SEGMENT) * device_bytes_per_pellet(big, (), _H200()) <= DEVICE_FRACTION * _H200.free_memory  # (whole segments)
    assert pipeline.log_threads(spec, _H200(), 12_345) == 12_345  # (a column a chunk row)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_a_log_past_a_32_bit_index_is_held_in_rows_and_reached_by_its_64_bit_index(precision):
    """`counts.log_buffer` past its limit: a view of `limit` words over rows that hold them all; the
    replay's raw accessors write and read every word (here a limit of 1,000 words, 7 columns of 300)."""
    import warp as wp

    scalar = wp.float64 if precision == "float64" else wp.float32
    load, store = path_replay.raw_access(precision)

    @wp.kernel(module="unique")
    def fill(steps: wp.array(dtype=scalar), threads: wp.int32, words: wp.int32, back: wp.array(dtype=scalar)):
        slot = wp.tid()
        for j in range(words):
            store(steps, j, threads, slot, scalar(j * threads + slot))
        for j in range(words):
            back[j * threads + slot] = load(steps, j, threads, slot)

    device = wp.get_device("cpu")
    view, rows = log_buffer(device, 7 * 300, scalar, 1000)
    assert view.shape == (1000,) and rows.shape == (3, 1000)
    back = wp.zeros(7 * 300, dtype=scalar, device=device)
    wp.launch(fill, dim=7, inputs=[view, 7, 300, back], device=device)
    np.testing.assert_array_equal(rows.numpy().ravel()[: 7 * 300], np.arange(7 * 300))
    np.testing.assert_array_equal(back.numpy(), np.arange(7 * 300))
    flat, none = log_buffer(device, 1000, scalar, 1000)
    assert flat.shape == (1000,) and none is None


def test_a_replayed_run_whose_record_log_is_past_the_index_limit_gives_the_same_bits(tmp_path, monkeypatch):
    """A record log held in rows (`counts.log_buffer`, its limit lowered to 10,000 words: a column's
    words from the 50th on lie past the first row) replays as one flat array does."""
    from warp_ricochet.physics import line_log
    from warp_ricochet.tallies import counts

    held_rows = []
    real = counts.log_buffer

    def spy(*args):
        view, rows = real(*args)
        held_rows.append(rows)
        return view, rows

    scene = _scene(CASES["map-places"])
    with monkeypatch.context() as m:
        m.setattr(path_replay, "REPLAY", "always")
        flat = _outputs(tmp_path, "flat", scene)
        m.setattr(line_log, "INDEX_LIMIT", 10_000)
        m.setattr(counts, "log_buffer", spy)
        held = _outputs(tmp_path, "rows", scene)
    rows = next(r for r in held_rows if r is not None).numpy()
    assert rows.shape[0] > 1 and np.any(rows[1:] != 0)  # (records written past the view's shape)
    _same(flat, held, "a record log in rows")


@pytest.mark.parametrize("words", [None, 16])
def test_a_replayed_run_in_chunks_and_resumed_is_the_same_bits_as_the_watch_in_the_core(tmp_path, monkeypatch, words):
    """tests/test_dense_watch.py's scene followed to rest (pair collisions, a map and a place, chunks of whole shots):
    replayed in chunks of two sizes, and stopped after a chunk then resumed, the same bits as the
    watch in the core in chunks of one size; with columns of 16 words pellets are followed again."""
    from tests.helpers import assert_same_run, interrupt_after
    from tests.test_dense_watch import CHUNK, FIELDS, OVERRIDES

    def _chunked(chunks):
        return load_scene(PAPER, [*OVERRIDES, *REST, f"numerics.chunk_size={chunks * CHUNK}"])

    reference = tmp_path / "core.h5"
    wr.run(_chunked(1), reference, device="cpu")  # (REPLAY "cuda": the CPU watches in the core)
    seen = []
    after = replay.Replay.after_core
    monkeypatch.setattr(replay.Replay, "after_core", lambda self, *args: (after(self, *args), seen.append(self.reruns)))
    monkeypatch.setattr(path_replay, "REPLAY", "always")
    if words:
        monkeypatch.setattr(path_replay, "COLUMN_WORDS", words)
    wr.run(_chunked(2), tmp_path / "two.h5", device="cpu")
    assert seen and (seen[-1] > 0) == bool(words)
    assert_same_run(tmp_path / "two.h5", reference, FIELDS, progress=())
    interrupt_after(1, _chunked(1), tmp_path / "resumed.h5")
    wr.run(_chunked(1), tmp_path / "resumed.h5", device="cpu", resume=True)
    assert_same_run(tmp_path / "resumed.h5", reference, FIELDS)
