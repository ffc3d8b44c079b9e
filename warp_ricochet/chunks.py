"""How a run is cut into chunks: sizes within the device and host memory budgets (pellet rows
for the core; whole shots for runs with pair collisions), and the check, before any work, that an
explicit `numerics.chunk_size` fits in memory.
"""

from __future__ import annotations

import numpy as np

from .dense.schedule import dense_bytes_per_pellet, shot_granule, shot_stride
from .errors import SceneError
from .fields import bytes_per_pellet
from .io.space import free_bytes, host_memory_available, size_text
from .model import held_state_bytes
from .physics.line_log import INDEX_LIMIT, step_words
from .spec import RunSpec
from .tallies import path_replay
from .tallies.counts import TallySetup, pooled_bytes, tally_bytes
from .tallies.reduce import SEGMENT, partial_bytes_per_pellet

HOST_BUFFER_BYTES = 128 << 20  # per pinned host buffer (two are used): caps host memory
DEVICE_FRACTION = 0.5  # of the free device memory a chunk may use
MAX_CHUNK = 1 << 28  # pellets per chunk, statistics-only
CPU_STATS_CHUNK = 1 << 21  # CPU statistics-only chunk (~0.4 s on one core): progress, and interrupts between chunks
CPU_CHUNK_PELLETS = 1 << 20  # CPU: pellets per chunk of the dense phase
CPU_AIR_CHUNK = SEGMENT  # CPU, in air (~1e5 pellets/s a core): a chunk in well under a second, so
# Ctrl-C and SIGTERM, honoured between chunks (interrupts), end a run at once


def file_bytes_per_pellet(scene) -> int:
    """Device bytes per pellet of a pellet file's launch states (none when sampling)."""
    return 0 if scene.shot.file is None else 9 * np.dtype(scene.numerics.precision).itemsize


def device_bytes_per_pellet(scene, fields, device=None) -> float:
    """Device bytes per pellet of a core chunk on `device`: outputs, statistics partials, pellet-file
    states, the step log."""
    spec = RunSpec.of(scene, with_output=False, device=device)
    return (
        partial_bytes_per_pellet(spec.lanes)
        + bytes_per_pellet(fields, scene.numerics.precision, scene.physics.bounces)
        + file_bytes_per_pellet(scene)
        + log_words_per_pellet(spec) * np.dtype(scene.numerics.precision).itemsize
    )


def log_words(spec) -> int:
    """Words of the step log a core thread has (`physics.line_log`; a chunk row's column of the
    record log where the run replays its watch, `tallies.path_replay`): none without phases along a
    line watched (`spec.log_steps` = 0: each step watched at once)."""
    if spec.watch[4]:  # (a run to rest that watches its path and records it)
        return path_replay.COLUMN_WORDS  # (read at each call: tests shrink it)
    if not (spec.to_rest and spec.watch[0] > 0 and spec.log_steps > 0):
        return 0
    return spec.log_steps * step_words(spec.rough)


def log_words_per_pellet(spec) -> float:
    """Words of the step log a pellet (a slot) of a GPU chunk takes: its thread's, shared by its
    pellets (its own column of the record log where the run replays its watch)."""
    return log_words(spec) * (1 if spec.watch[4] else spec.lanes / SEGMENT)


def log_rows(spec) -> int:
    """The most rows (slots) of a GPU chunk whose step log a 32-bit index reaches (whole segments);
    a record log (`spec.watch`[4]) is indexed in 64 bits: only memory bounds it (`plan_rows`)."""
    words = log_words_per_pellet(spec)
    return MAX_CHUNK if not words or spec.watch[4] else max(SEGMENT, int(INDEX_LIMIT / words) // SEGMENT * SEGMENT)


def free_device_bytes(device) -> int:
    """The device memory a run may plan with: the free memory and the buffers kept from the last run
    (`tallies.counts.pooled_bytes`, `model.held_state_bytes`), which a run frees before it allocates
    unless it repeats the last one's chunks (`pipeline.release_kept`). Counting them keeps a run's
    chunks the same size as the last one's, so that it reuses them. A worker's device
    (`cluster.RemoteDevice`) reports its own."""
    if getattr(device, "remote", False):
        return device.free_memory
    return device.free_memory + pooled_bytes(device) + held_state_bytes(device)


def balanced(rows: int, pellets: int) -> int:
    """The fewest chunks of at most `rows` (a multiple of SEGMENT) made as equal as whole segments
    allow: no small last chunk (on a GPU, a launch's last wave and each chunk's reduction cost the
    same for a few rows as for many)."""
    chunks = max(-(-pellets // rows), 1)
    each = -(-pellets // chunks)
    return min(rows, -(-each // SEGMENT) * SEGMENT)


def plan_rows(scene, device, pellets: int, fields) -> int:
    """Pellets per core chunk: a multiple of SEGMENT that fits device and host memory budgets; on a
    GPU without `numerics.chunk_size`, `balanced`."""
    if scene.numerics.chunk_size:
        rows = scene.numerics.chunk_size
    else:
        if device.is_cuda:
            rows = min(
                int(DEVICE_FRACTION * free_device_bytes(device) / device_bytes_per_pellet(scene, fields, device)), MAX_CHUNK
            )
        else:
            rows = CPU_AIR_CHUNK if scene.in_air else CPU_STATS_CHUNK
        if fields:
            rows = min(rows, int(HOST_BUFFER_BYTES / bytes_per_pellet(fields, scene.numerics.precision, scene.physics.bounces)))
    rows = max(SEGMENT, -(-rows // SEGMENT) * SEGMENT)  # whole segments: chunk-size invariance
    if device.is_cuda:  # (the same bits for any chunk size)
        rows = min(rows, log_rows(RunSpec.of(scene, with_output=False, device=device)))
        if not scene.numerics.chunk_size:
            rows = balanced(rows, pellets)
    return min(rows, max(pellets, 1))


def plan_shots(scene, device, shots: int) -> int:
    """Shots per chunk of a run with pair collisions: whole statistics segments of slots (so
    statistics do not depend on it), within the device memory budget (or numerics.chunk_size
    pellets)."""
    count = scene.shot.count
    granule = shot_granule(count)
    spec = RunSpec.of(scene, with_output=False, device=device)
    if scene.numerics.chunk_size:
        pellets = scene.numerics.chunk_size
    elif device.is_cuda:
        log = log_words_per_pellet(spec) * np.dtype(scene.numerics.precision).itemsize * shot_stride(count) / count
        pellets = int(
            DEVICE_FRACTION
            * free_device_bytes(device)
            / (dense_bytes_per_pellet(scene.numerics.precision, scene.collisions.max_neighbours) + 64 + log)
        )
    else:
        pellets = CPU_AIR_CHUNK if scene.in_air else CPU_CHUNK_PELLETS
    per_chunk = max(granule, (max(pellets // count, 1) // granule) * granule)
    if device.is_cuda:  # (the step log's slots within a 32-bit index; the same bits for any chunk)
        per_chunk = min(per_chunk, max(granule, log_rows(spec) // shot_stride(count) // granule * granule))
    return min(per_chunk, shots)


def check_chunk_memory(scene, dev, with_output: bool) -> None:
    """An explicit `numerics.chunk_size` must fit in memory: refuse it in one line before any work
    (a chunk of 2e8 pellets with every output field needs 40 GB; the automatic size always fits)."""
    chunk = scene.numerics.chunk_size
    if not chunk:
        return
    pellets = scene.shot.pellets
    rows = min(max(SEGMENT, -(-chunk // SEGMENT) * SEGMENT), max(pellets, 1))
    if dev.is_cuda:  # (as `plan_rows` caps it)
        rows = min(rows, log_rows(RunSpec.of(scene, with_output=False, device=dev)))
    fields = scene.output.fields if with_output else ()
    on_device = device_bytes_per_pellet(scene, fields, dev)
    on_host = bytes_per_pellet(fields, scene.numerics.precision, scene.physics.bounces) * (2 if dev.is_cuda else 1)
    if not dev.is_cuda:
        on_host, on_device = on_host + on_device, 0
    host_free = host_memory_available()
    for need, free, where in (
        (rows * on_device, free_device_bytes(dev) if dev.is_cuda else None, f"on {dev.alias}"),
        (rows * on_host, host_free, "in host memory"),
    ):
        if free is not None and need > free:
            fits = int(free / max(need / rows, 1e-9)) // SEGMENT * SEGMENT
            raise SceneError(
                "numerics.chunk_size",
                chunk,
                f"a chunk of {rows} pellets needs {need / 2**30:.3g} GiB, {free / 2**30:.3g} GiB is free "
                f"{where}: give at most {fits} or leave it out (automatic)",
            )


def check_tallies(scene, dev, output) -> int:
    """Before any work: the landing tallies (`tallies.counts.tally_bytes`: histograms and hazard map)
    must fit in host and device memory, and their datasets on the output's disk; else one line naming
    the map's keys and the estimate. Returns the bytes they add to the output file."""
    if not scene.output.quantiles:
        return 0
    setup = TallySetup.of(scene, 1.0, 1.0, 1.0)  # (the shapes do not depend on the pellets)
    host, device, file = tally_bytes(setup, dev, output is not None, scene.shot.pellets)
    if setup.has_map:
        hazard = scene.hazard
        key, value = "hazard.map_cell", hazard.map_cell
        what = (
            f"the hazard map of {setup.cells:,} cells ({setup.map_nu:,} x {setup.map_nv:,} cells of hazard.map_cell "
            f"over hazard.map_extent {list(hazard.map_extent)}) x {setup.levels - 1} thresholds needs"
        )
        fix = "a larger map_cell, a smaller map_extent or fewer thresholds"
    else:
        key, value, what, fix = "output.quantiles", True, "the landing histograms need", "output.quantiles = false"
    for need, free, where in (
        (host, host_memory_available(), "of host memory"),
        (device, free_device_bytes(dev) if dev.is_cuda else None, f"on {dev.alias}"),
        (file, None if output is None else free_bytes(output), "on the output's disk"),
    ):
        if free is not None and need > free:
            raise SceneError(key, value, f"{what} up to {size_text(need)} {where}, {size_text(free)} is free: {fix}")
    return file
