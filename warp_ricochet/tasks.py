"""A cluster's task: one stretch [start, stop) of a run's pellets, computed on a worker (`cluster`).

A task runs the chunk loop (`pipeline._loop`) over its stretch, exactly as a serial run's chunks
starting at `start` would, and returns what the client folds (`Partial`): the per-segment
statistics partials in segment order, the shots' totals and per-shot partials in shot order and
the landing counts of its pellets (int64, as nonzero (index, value) pairs). A stretch starts on a
chunk boundary of the serial run (`task_bounds`: whole segments of pellets, or whole granules of
shots with pair collisions, counted from each station piece's or bound check's start), so its
segments hold the same pellets as the serial run's and the client's fold in segment order gives
the serial run's bits. Nothing here imports Dask: a task is a plain function of plain values.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np

from .tallies.reduce import SEGMENT, SEGMENT_WIDTH


@dataclass
class Partial:
    """What a task returns: its stretch, segment results (rows, SEGMENT_WIDTH), shots' totals and
    per-shot partials (None: none), landing counts (index, value) of `TallyTotals.flat()` (None:
    not counted), and the worker's device (alias, name)."""

    start: int
    stop: int
    segment_results: np.ndarray
    shot_totals: np.ndarray | None
    shot_partials: np.ndarray | None
    tally: tuple | None
    device: tuple


def unit_of(scene) -> int:
    """Pellets of the smallest stretch a task may start or end on: a statistics segment, or with
    pair collisions a granule of whole shots (`dense.schedule.shot_granule`)."""
    if scene.pair_collisions:
        from .dense.schedule import shot_granule

        return shot_granule(scene.shot.count) * scene.shot.count
    return SEGMENT


def task_bounds(begin: int, end: int, unit: int, size: int) -> list[tuple[int, int]]:
    """[start, stop) stretches of at most `size` pellets (rounded up to whole `unit`s) from `begin`
    (a stretch's start) to `end`: every start is `begin` plus whole units."""
    size = max(unit, -(-size // unit) * unit)
    return [(a, min(a + size, end)) for a in range(begin, end, size)]


def run_range(scene, device, start: int, stop: int, options=None, shards=None) -> Partial:
    """Pellets [start, stop) of `scene` (a bounded run's budget scene, `bound.planned`) on `device`
    (a name, resolved here on the worker); `options`: the dense phase's `DenseOptions`; `shards`:
    the folder its per-pellet fields are written to, a shard of its own (`io.shards`)."""
    from .device import resolve_device
    from .model import Model
    from .pipeline import _DEVICE_LOCK, Resumed, _loop, make_stage
    from .scene import load_pellet_file
    from .spec import RunSpec

    dev = resolve_device(device)
    model = Model.from_scene(scene, dev)
    spec = RunSpec.of(scene, with_output=shards is not None)
    arrays = load_pellet_file(scene.shot.file) if scene.shot.file is not None else None
    kept: list = []
    sink = None
    if shards is not None:
        from .io.shards import ShardSink, shard_path

        sink = ShardSink(shard_path(shards, start, stop), spec.fields, model, stop - start, scene.output.compression)
    with _DEVICE_LOCK if dev.is_cuda else contextlib.nullcontext():
        stage = make_stage(scene, model, spec, arrays, scene.shot.pellets, options)
        resumed = Resumed(start, np.zeros((0, SEGMENT_WIDTH)))
        try:
            _totals, tables, tally, pieces, done, _ = _loop(stage, stop, sink, resumed, None, kept=kept)
        except BaseException:
            if sink is not None:
                sink.close(complete=False)
            raise
    if sink is not None:
        sink.close(complete=True)
    assert done == stop, (done, stop)
    counts = None
    if tally is not None:
        flat = tally.flat()
        index = np.flatnonzero(flat)
        counts = (index, flat[index])
    return Partial(
        start,
        stop,
        np.concatenate(kept) if kept else np.zeros((0, SEGMENT_WIDTH)),
        np.concatenate(tables) if tables else None,
        np.concatenate(pieces) if pieces else None,
        counts,
        (str(dev), dev.name),
    )


def describe_device(device) -> tuple:
    """(alias, name, is_cuda, free bytes) of `device` resolved on a worker (`cluster.RemoteDevice`)."""
    from .device import resolve_device

    dev = resolve_device(device)
    return str(dev), dev.name, bool(dev.is_cuda), int(dev.free_memory) if dev.is_cuda else 0
