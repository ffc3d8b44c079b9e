"""How a GPU run is cut into chunks (`chunks.plan_rows`): as equal as whole segments allow, and the
same size for a run after another, whose kept buffers (`tallies.counts.pooled_bytes`,
`model.held_state_bytes`) count as free memory, so the run reuses them instead of making smaller ones."""

import warp as wp
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.test_line_log import _scene
from warp_ricochet import chunks
from warp_ricochet.chunks import balanced, device_bytes_per_pellet, free_device_bytes, plan_rows
from warp_ricochet.tallies import counts
from warp_ricochet.tallies.reduce import SEGMENT

REACH = ("air.density=1.225", 'physics.until="rest"', "surfaces.0.rolling_resistance=0.05", "hazard.fractions=[1e-3]")


class _Gpu:
    """A stand-in for a GPU with `free` bytes free (what the planners read)."""

    is_cuda = True

    def __init__(self, free):
        self.free_memory = free
        self.alias = "cuda:test"

    def __str__(self):
        return self.alias


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 10**10), st.integers(1, 1 << 16))
def test_balanced_chunks_are_as_few_and_as_equal_as_whole_segments_allow(pellets, segments):
    rows = segments * SEGMENT
    even = balanced(rows, pellets)
    chunks_needed = -(-pellets // rows)
    assert even % SEGMENT == 0 and SEGMENT <= even <= rows
    assert -(-pellets // even) == chunks_needed  # (no more chunks than the cap gives)
    last = pellets - (chunks_needed - 1) * even
    assert 0 < last <= even and (chunks_needed == 1 or even - last < chunks_needed * SEGMENT)


def test_a_gpu_run_of_1e8_pellets_has_no_small_last_chunk():
    scene = _scene(REACH, pellets=100_000_000, fields=())
    rows = plan_rows(scene, _Gpu(140e9), scene.shot.pellets, ())
    full = chunks.DEVICE_FRACTION * 140e9 / device_bytes_per_pellet(scene, (), _Gpu(140e9))
    assert rows < full  # (below the memory's bound: balanced)
    count = -(-scene.shot.pellets // rows)
    assert count == -(-scene.shot.pellets // (int(full) // SEGMENT * SEGMENT))
    assert scene.shot.pellets - (count - 1) * rows > rows - count * SEGMENT


def test_a_run_after_another_plans_the_same_chunks_with_the_buffers_it_kept(monkeypatch):
    """The first run takes half the free memory for its chunk's buffers; they are kept, so the GPU
    reports that much less free. Counted as free again, the next run plans the same chunks and reuses
    them (before, its chunks were half the size, and each run made its buffers anew)."""
    scene = _scene(REACH, pellets=100_000_000, fields=())
    total = 4e9
    first = plan_rows(scene, _Gpu(total), scene.shot.pellets, ())
    held = int(first * device_bytes_per_pellet(scene, (), _Gpu(total)))
    kept = wp.empty(held, dtype=wp.uint8, device="cpu")  # (what the first run's log holds)
    monkeypatch.setitem(counts._POOL, ("cuda:test", "step log"), kept)
    after = _Gpu(total - held)
    assert free_device_bytes(after) == total - held + kept.capacity
    assert plan_rows(scene, after, scene.shot.pellets, ()) == first
    monkeypatch.delitem(counts._POOL, ("cuda:test", "step log"))
    assert plan_rows(scene, after, scene.shot.pellets, ()) < first  # (without the kept buffers counted)


def test_a_workers_device_reports_its_own_kept_buffers(monkeypatch):
    """A worker's device, described to the client (`cluster.RemoteDevice`), has its kept buffers in
    its free memory already (`tasks.describe_device`): the client's own are not added."""
    from warp_ricochet.cluster import RemoteDevice

    kept = wp.empty(1 << 20, dtype=wp.uint8, device="cpu")
    monkeypatch.setitem(counts._POOL, ("cuda:test", "step log"), kept)
    assert free_device_bytes(_Gpu(1e9)) == 1e9 + kept.capacity
    assert free_device_bytes(RemoteDevice("cuda:test", "H200", True, 10**9)) == 10**9


def test_a_run_frees_the_kept_buffers_it_counted_as_free_unless_it_repeats_the_last_chunks(monkeypatch):
    """`pipeline.release_kept`: a run whose plan counted the kept buffers as free frees them before
    it allocates, unless its chunk buffers are the kept ones (a repeat, which reuses them all); a
    collision run (None) always frees them. Pinned host buffers stay."""
    from warp_ricochet import model, pipeline

    def keep():
        monkeypatch.setitem(model._LAST_STATE, "key", ("cuda:test", "float32", 1))
        monkeypatch.setitem(model._LAST_STATE, "state", object())
        monkeypatch.setitem(counts._POOL, ("cuda:test", "step log"), wp.empty(16, dtype=wp.uint8, device="cpu"))
        monkeypatch.setitem(counts._POOL, ("cuda:test", ("pinned",)), {"host": None})

    gpu = _Gpu(1e9)
    keep()
    pipeline.release_kept(gpu, ("cuda:test", "float32", 1))
    assert model._LAST_STATE and ("cuda:test", "step log") in counts._POOL  # (a repeat: all reused)
    for other in (("cuda:test", "float32", 2), None):
        keep()
        pipeline.release_kept(gpu, other)
        assert not model._LAST_STATE and ("cuda:test", "step log") not in counts._POOL
        assert ("cuda:test", ("pinned",)) in counts._POOL
        assert free_device_bytes(gpu) == 1e9
