"""A cluster's task: one stretch [start, stop) of a run's pellets, computed on a worker (`cluster`).

A task runs the chunk loop (`pipeline._loop`) over its stretch, exactly as a serial run's chunks
starting at `start` would, and returns what the client folds (`Partial`): the per-segment
statistics partials in segment order, the shots' totals and per-shot partials in shot order and
the landing counts of its pellets (int64, as nonzero (index, value) pairs). A stretch starts on a
chunk boundary of the serial run (`task_bounds`: whole segments of pellets, or whole granules of
shots with pair collisions, counted from each station piece's or bound check's start), so its
segments hold the same pellets as the serial run's and the client's fold in segment order gives
the serial run's bits. Nothing here imports Dask: a task is a plain function of plain values.

A worker keeps the stage of its last task (`Kept`: model, device buffers, kernels) for the next
task of the same run (the same scene, device, spec and options): the chunk loop continues from any
chunk boundary on a stage whatever it computed before, as the serial loop does from chunk to
chunk, so a task gives the bits of a fresh stage. A task of another run drops it first (one stage
a worker: its device memory), as does `release` (the study's end: `cluster.Study.fold`).
"""

from __future__ import annotations

import contextlib
import threading
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


def chunk_of(scene, device, fields=()) -> int:
    """Pellets of one chunk of `scene`'s serial run on `device` (a worker's, `cluster.RemoteDevice`:
    its kind and free memory), writing `fields` (`chunks.plan_rows`, `chunks.plan_shots`)."""
    from .chunks import plan_rows, plan_shots

    if scene.pair_collisions:
        return plan_shots(scene, device, scene.shot.shots) * scene.shot.count
    return plan_rows(scene, device, scene.shot.pellets, fields)


def task_size(pellets: int, workers: int, per_worker: int, chunk: int) -> int:
    """Pellets a task of a run of `pellets` on `workers`: `per_worker` tasks a worker, but none
    smaller than one `chunk` of the serial run's unless a worker's share is (a stretch shorter than
    a chunk pays a chunk's fixed costs for less of its work)."""
    pellets = max(pellets, 1)
    return max(-(-pellets // (per_worker * workers)), min(chunk, -(-pellets // workers)))


def task_bounds(begin: int, end: int, unit: int, size: int) -> list[tuple[int, int]]:
    """[start, stop) stretches of at most `size` pellets (rounded up to whole `unit`s) from `begin`
    (a stretch's start) to `end`: every start is `begin` plus whole units."""
    size = max(unit, -(-size // unit) * unit)
    return [(a, min(a + size, end)) for a in range(begin, end, size)]


class Kept:
    """The stage a worker keeps between the tasks of one run (one at a time: `take`, `keep`)."""

    lock = threading.Lock()
    entry: tuple | None = None  # (key, model, stage): the last task's, complete
    generation = 0  # `release`s so far: a task begun before one keeps nothing

    @classmethod
    def take(cls, key) -> tuple:
        """(model, stage, generation): the stage kept for `key` (a task's run), taken out while the
        task uses it, else (None, None); one of another key is dropped (its memory freed before a
        new stage is planned)."""
        with cls.lock:
            entry, cls.entry = cls.entry, None
            if entry is None or entry[0] != key:
                return None, None, cls.generation
            return entry[1], entry[2], cls.generation

    @classmethod
    def keep(cls, key, model, stage, generation: int) -> None:
        """Keep the stage of a task complete (none kept if `release`d since it began)."""
        with cls.lock:
            if generation == cls.generation:
                cls.entry = (key, model, stage)


def release() -> None:
    """Drop the stage kept on this worker (`Kept`): a study's end (`cluster.Study.fold`)."""
    with Kept.lock:
        Kept.entry, Kept.generation = None, Kept.generation + 1


def run_range(scene, device, start: int, stop: int, options=None, shards=None) -> Partial:
    """Pellets [start, stop) of `scene` (a bounded run's budget scene, `bound.planned`) on `device`
    (a name, resolved here on the worker); `options`: the dense phase's `DenseOptions`; `shards`:
    the folder its per-pellet fields are written to, a shard of its own (`io.shards`). The stage
    of the worker's last task is used again when it ran the same scene (`Kept`)."""
    from .device import resolve_device
    from .model import Model
    from .pipeline import _DEVICE_LOCK, Resumed, _loop, make_stage
    from .scene import load_pellet_file
    from .spec import RunSpec

    dev = resolve_device(device)
    spec = RunSpec.of(scene, with_output=shards is not None, device=dev)
    key = (scene.to_toml(), str(dev), spec, options)
    model, stage, generation = Kept.take(key)
    if model is None:
        model = Model.from_scene(scene, dev)
    kept: list = []
    sink = None
    if shards is not None:
        from .io.shards import ShardSink, shard_path

        sink = ShardSink(shard_path(shards, start, stop), spec.fields, model, stop - start, scene.output.compression)
    with _DEVICE_LOCK if dev.is_cuda else contextlib.nullcontext():
        if stage is None:
            arrays = load_pellet_file(scene.shot.file) if scene.shot.file is not None else None
            stage = make_stage(scene, model, spec, arrays, scene.shot.pellets, options)
        resumed = Resumed(start, np.zeros((0, SEGMENT_WIDTH)))
        try:
            _totals, tables, tally, pieces, done, _ = _loop(stage, stop, sink, resumed, None, kept=kept)
        except BaseException:  # (the stage, mid-chunk, is not kept)
            if sink is not None:
                sink.close(complete=False)
            raise
    if sink is not None:
        sink.close(complete=True)
    assert done == stop, (done, stop)
    Kept.keep(key, model, stage, generation)
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
    """(alias, name, is_cuda, free bytes) of `device` resolved on a worker (`cluster.RemoteDevice`);
    (None, the one-line error) for a device it does not have, raised by the client (a task that
    raises has the worker log "Compute Failed" and a traceback above the command's line)."""
    from .chunks import free_device_bytes
    from .device import resolve_device
    from .errors import RicochetError

    try:
        dev = resolve_device(device)
    except RicochetError as exc:
        return None, str(exc)
    return str(dev), dev.name, bool(dev.is_cuda), int(free_device_bytes(dev)) if dev.is_cuda else 0
