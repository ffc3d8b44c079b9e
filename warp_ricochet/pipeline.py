"""The run: one chunk loop for every scene.

A stage computes a chunk on the device: `CoreStage` launches its pellets in the fused core
kernel; `CollisionStage` (scenes with pair collisions) runs whole shots through the dense phase,
then continues every pellet in the core kernel. Each chunk ends with the segment reduction of its
statistics partials. The loop copies a chunk's results into host buffers (on CUDA two pinned sets,
used in turn, copied asynchronously: the host hands one chunk to the sink while the device
computes the next; no sync inside a chunk), folds its statistics in pellet order and hands its
rows to the sink (a writer): the sink receives results and decides nothing about what is
computed. A resumed run starts after the rows already complete, with their partials.

Ctrl-C (and, from the command line, SIGTERM) is honoured between chunks (`interrupts`): the loop
raises KeyboardInterrupt before it computes the next chunk, so the sink holds whole chunks only.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import warnings
from dataclasses import dataclass

import numpy as np
import warp as wp

from . import interrupts
from .bound import station_pieces
from .chunks import log_words, plan_rows, plan_shots
from .core.kernel import block_dim_for, ricochet_kernel_for
from .core.release import empty_release
from .core.replay import Replay
from .core.shots import ShotPass, ThreadPieces
from .dense.phase import DensePhase
from .dense.schedule import shot_stride
from .errors import ChaosWarning, PrecisionWarning
from .launch.source import PelletSource
from .model import State, release_kept_state, reused_state, state_key
from .physics.air_flight import MAX_FLIGHT_STEPS
from .physics.limits import POSITION_RESOLUTION, UNIT_ROUNDOFF
from .scene.stations import station_shots
from .tallies.by_station import StationFold
from .tallies.collisions import (
    OVERRUN_TOLERANCE,
    SHOT_TOTALS,
    SKIN_OVERRUN,
    collision_statistics,
)
from .tallies.counts import DeviceTally, TallySetup, TallyTotals, release_pool
from .tallies.ensemble import ensemble_of, has_ensemble, per_shot_statistics
from .tallies.reduce import SEGMENT_WIDTH, launch_reduce, threads_for
from .tallies.sums import combine, empty_totals, finalize
from .tallies.terrain_ground import with_terrain

log = logging.getLogger(__name__)  # `warp-ricochet -vv`: a line per chunk

ONE_SHOT_COLLISIONS = (
    "one shot with pellet-pellet collisions is one sample of a chaotic cloud: on the paper's shot its "
    "mean range moves by a median 5% (up to 23%) when its launch moves by 1e-7, in float64 as in "
    "float32; set shot.shots = 200 or more for 95% intervals (docs/collisions.md)"
)

UNFINISHED_FLIGHTS = (
    "{:,} flights in air took more than {:,} integration steps and were given up (counted as "
    "escaped, in flights_unfinished): raise numerics.flight_tolerance or check the scene"
)

COARSE_POSITIONS = (
    "{precision} resolves a flight's coordinates to {eps} of its scale: flight_scale_max = {scale:.3g} m "
    "gives {error:.3g} m, more than 1/{parts:g} of the pellet radius ({radius:.3g} m), so contacts and "
    'ranges are decided by rounding (docs/stability.md, "Precision"); {fix}'
)
FIX = {
    "float32": 'set numerics.precision = "float64"',
    "float64": "even float64 cannot: shorten the flights or move the scene nearer the origin",
}

_PINNED_POOL: dict = {}  # (name, shape, dtype, slot) -> pinned host array, reused: cudaHostAlloc is slow
_DEVICE_LOCK = threading.Lock()  # one CUDA run at a time uses the pool and the reused state


@dataclass
class Resumed:
    """What a resumed run already has: `rows` pellets complete, their statistics partials (one row
    per segment), with pair collisions their shots' totals, and in a run of several shots the
    per-shot partials of its complete shots (`core.shots`)."""

    rows: int
    segment_results: np.ndarray
    shot_totals: np.ndarray | None = None
    tally: np.ndarray | None = None  # the landing counts of those rows (`TallyTotals.flat`)
    shot_partials: np.ndarray | None = None
    station_tally: dict | None = None  # station runs: piece -> the landing counts at its end (`by_station`)


class RunStats(dict):
    """The statistics of a run ({name: float}, `tallies.sums.STAT_UNITS`) and, in `tally`, its
    landing counts (`TallyTotals`; None when the scene counts none: output.quantiles = false) and, in
    `ensemble`, its intervals over shots (`tallies.ensemble.Ensemble`; None for one shot). A sweep's
    points keep no `tally`; without a sweep file, `summary` holds its results (`api.sweep`)."""

    tally = None
    ensemble = None
    summary = None
    bound = None  # a bounded run's outcome (`bound.BoundResult`)
    stations = None  # [[stations]]: {name: RunStats of that station's pellets alone} (`tallies.by_station`)


def landing_setup(scene, model, arrays) -> TallySetup:
    """The landing tallies' setup of a run (`arrays`: a pellet file's launch states, or None)."""
    if arrays is not None:
        launch_speed = float(np.sqrt((np.asarray(arrays["velocity"], dtype=np.float64) ** 2).sum(axis=1)).max(initial=0.0))
    else:
        launch_speed = scene.shot.speed
    return with_terrain(TallySetup.of(scene, model.mass, model.radius, launch_speed), scene, model)


def landing_tally(scene, model, spec, arrays, rows: int) -> DeviceTally:
    """The device tally of a run (active with spec.tally; its struct is passed either way), with the
    step log of a run to rest that watches its path for a core launch over `rows` rows (`log_threads`)."""
    log = (log_threads(spec, model.device, rows), log_words(spec))
    return DeviceTally(
        landing_setup(scene, model, arrays), model.precision, model.device, spec.tally, log, wide=bool(spec.watch[4])
    )


def log_threads(spec, device, rows: int) -> int:
    """Threads the step log has a column for (`physics.line_log`): a core launch's over `rows` rows
    on a GPU, one on a CPU (its threads run one after another); none without surface phases watched
    or with `spec.log_steps` = 0 (each step watched at once)."""
    if not log_words(spec):
        return 0
    if spec.watch[4]:  # (a record log: a column a chunk row, `tallies.path_replay`)
        return rows
    return threads_for(rows, spec.lanes) if device.is_cuda else 1


def check_log(tally: DeviceTally, spec, device, rows: int) -> None:
    """A core launch over `rows` rows has a column of the step log a thread (`log_threads`): raise
    before it where it would not (threads sharing a column would race on a GPU)."""
    need = log_threads(spec, device, rows)
    if need > tally.struct.log_threads:
        raise RuntimeError(f"step log of {tally.struct.log_threads} threads for a launch of {need}")


def launch_core(kernel, inputs, state, rows: int, device, block_dim: int, scratch: bool = False) -> None:
    """Launch a core kernel over `rows` rows (or slots) with `inputs` in CUDA blocks of `block_dim`
    threads, its statistics partials into `state`'s (`scratch`: into its scratch set, thrown away:
    the rerun of `core.replay.Replay`)."""
    partials = [state.partial_sums, state.partial_min, state.partial_max]
    if scratch:
        if state.scratch_partials is None:  # (one set, reused by the chunks)
            state.scratch_partials = [wp.empty_like(a) for a in partials]
        partials = state.scratch_partials
    wp.launch(kernel, dim=threads_for(rows, state.lanes), inputs=inputs, outputs=partials, device=device, block_dim=block_dim)


def release_kept(device, key=None) -> None:
    """Before a CUDA run allocates: the buffers kept from the last run, which its plan counted as
    free (`chunks.free_device_bytes`), freed unless its chunk buffers are kept by `key` (the same
    state: a repeat of the last run's chunks, which reuses them). None: always freed."""
    if not release_kept_state(unless=key):
        release_pool(device)


class CoreStage:
    """Chunks of pellet rows, launched in the core kernel."""

    def __init__(self, scene, model, spec, arrays, pellets):
        dev = model.device
        self.model, self.pellets, self.stop = model, pellets, pellets
        self.capacity = plan_rows(scene, dev, pellets, spec.fields)
        if dev.is_cuda:
            release_kept(dev, state_key(model, self.capacity, spec.core_fields, spec.lanes))
        self.state = (reused_state if dev.is_cuda else State)(model, self.capacity, spec.core_fields, spec.lanes)
        self.source = PelletSource(scene, model.precision, dev, self.capacity, arrays)
        self.kernel = ricochet_kernel_for(spec)
        self.release = empty_release(model.precision, dev.alias)
        self.arrays, self.totals = self.state.arrays, None
        self.tally, self.spec = landing_tally(scene, model, spec, arrays, self.capacity), spec
        self.replay = Replay(spec, dev)
        self.count = scene.shot.count
        self.shot_pass = ShotPass(scene, model, spec, self.capacity // self.count + 1, arrays) if has_ensemble(scene) else None

    def chunks(self, done: int):
        """(start, rows) of the chunks from `done` to `stop` (the run's end, or its next check)."""
        for start in range(done, self.stop, self.capacity):
            yield start, min(self.capacity, self.stop - start)

    def compute(self, start: int, rows: int):
        """Launch the chunk's kernels; returns (segments, shots) of results to copy."""
        m = self.model
        self.source.load(start, rows)
        self.tally.before_chunk()
        check_log(self.tally, self.spec, m.device, rows)
        inputs = [start, rows, self.source.struct, m.surfaces, m.physics, self.state.outputs, self.release, self.tally.struct]
        block_dim = block_dim_for(self.spec)
        launch_core(self.kernel, inputs, self.state, rows, m.device, block_dim)
        self.replay.after_core(
            rows,
            self.state.outputs,
            self.release,
            self.tally.struct,
            lambda k: launch_core(k, inputs, self.state, rows, m.device, block_dim, True),
        )
        self.tally.fold(rows, last=start + rows >= self.stop)
        return launch_reduce(self.state, rows, m.device, self.state.lanes), 0

    def shot_rows(self, start: int, rows: int):
        """Launch the per-piece partials of the shots this chunk completes; returns their pieces
        (rows of `shot_pass.rows`; None: no ensemble)."""
        if self.shot_pass is None:
            return None
        first = start // self.count
        return self.shot_pass.launch(
            first,
            (start + rows) // self.count - first,
            self.source.struct,
            self.state.outputs,
            self.release,
            self.tally.struct,
            start,
        )


class CollisionStage:
    """Chunks of whole shots: the dense phase, then the core kernel from each pellet's release."""

    def __init__(self, scene, model, spec, arrays, pellets, options=None, frames=None):
        dev = model.device
        self.model, self.pellets, self.stop, self.frames = model, pellets, pellets, frames
        self.count = scene.shot.count
        self.shots = pellets // self.count
        self.per_chunk = plan_shots(scene, dev, self.shots)
        if dev.is_cuda:
            release_kept(dev)  # (its state is its own: nothing kept is reused)
        self.stride = shot_stride(self.count)
        self.state = State(model, self.per_chunk * self.stride, spec.core_fields, spec.lanes)
        self.dense = DensePhase(model, scene, spec, self.per_chunk * self.count, options)
        self.source = PelletSource(scene, model.precision, dev, self.per_chunk * self.count, arrays)
        self.kernel = ricochet_kernel_for(spec)
        self.arrays = {**self.state.arrays, **self.dense.field_arrays}
        self.totals = self.dense.totals
        self.tally, self.spec = landing_tally(scene, model, spec, arrays, self.per_chunk * self.stride), spec
        self.replay = Replay(spec, dev)
        self.shot_pass = None
        if has_ensemble(scene):
            self.shot_pass = (
                ThreadPieces(scene, model, self.state, self.stride, self.per_chunk)
                if spec.thread_pieces
                else ShotPass(scene, model, spec, self.per_chunk)
            )

    def chunks(self, done: int):
        """(start, rows) of the chunks of whole shots from `done` to `stop` (the run's end, or its next check)."""
        shots = self.stop // self.count
        for first in range(done // self.count, shots, self.per_chunk):
            yield first * self.count, min(self.per_chunk, shots - first) * self.count

    def compute(self, start: int, rows: int):
        m = self.model
        shots = rows // self.count
        self.source.load(start, rows)
        self.tally.before_chunk()  # (the dense phase counts into it too: the hazard along the path)
        self.dense.run(start, shots, self.source.struct, self.state.outputs, frames=self.frames, tally=self.tally.struct)
        interrupts.check()  # (before the core kernel's pass over the chunk)
        slots = shots * self.stride
        check_log(self.tally, self.spec, m.device, slots)
        inputs = [0, slots, self.source.struct, m.surfaces, m.physics, self.state.outputs, self.dense.release, self.tally.struct]
        block_dim = block_dim_for(self.spec)
        launch_core(self.kernel, inputs, self.state, slots, m.device, block_dim)
        self.replay.after_core(
            shots * self.count,
            self.state.outputs,
            self.dense.release,
            self.tally.struct,
            lambda k: launch_core(k, inputs, self.state, slots, m.device, block_dim, True),
        )
        self.tally.fold(slots, last=start + rows >= self.stop)
        return launch_reduce(self.state, slots, m.device, self.state.lanes), shots

    def shot_rows(self, start: int, rows: int):
        """Launch the per-piece partials of the chunk's shots, continued from their release; returns
        their pieces (rows of `shot_pass.rows`; None: no ensemble)."""
        if self.shot_pass is None:
            return None
        return self.shot_pass.launch(
            start // self.count,
            rows // self.count,
            self.source.struct,
            self.state.outputs,
            self.dense.release,
            self.tally.struct,
            start,
        )


class HostSlot:
    """One set of host buffers receiving a chunk (pinned on CUDA, so copies run async)."""

    def __init__(self, stage, pinned: bool, index: int):
        self.pinned, self.index = pinned, index
        self.arrays = {name: self._like(arr, name) for name, arr in stage.arrays.items()}
        self.segments = self._like(stage.state.segments, "segments")
        self.totals = None if stage.totals is None else self._like(stage.totals, "shot_totals")
        self.tally = None  # the landing counts' buffers, made by the first `fill` that copies them
        self.piece_rows = None if stage.shot_pass is None else self._like(stage.shot_pass.rows, "shot_rows")
        self.rows = self.segment_count = self.shots = 0
        self.event, self.shot_pieces, self.with_tally = None, None, False

    def _like(self, arr, name):
        """A host array like `arr`: pinned ones kept between runs (by name, shape, dtype and slot)."""
        if not self.pinned:
            return wp.empty(arr.shape, dtype=arr.dtype, device="cpu")
        key = (name, arr.shape, arr.dtype, self.index)
        if key not in _PINNED_POOL:
            if len(_PINNED_POOL) > 64:
                _PINNED_POOL.clear()
            _PINNED_POOL[key] = wp.empty(arr.shape, dtype=arr.dtype, device="cpu", pinned=True)
        return _PINNED_POOL[key]

    def fill(self, stage, rows: int, segments: int, shots: int, with_tally: bool, shot_pieces=None):
        """Enqueue the copies of a computed chunk's results (element counts: contiguous rows),
        `with_tally` of the landing counts so far, and of its shots' `shot_pieces` rows of
        per-piece partials (None: no ensemble)."""
        for name, arr in stage.arrays.items():
            wp.copy(self.arrays[name], arr, count=rows * (arr.size // arr.shape[0]))
        wp.copy(self.segments, stage.state.segments, count=segments * stage.state.segments.shape[1])
        if shots:
            wp.copy(self.totals, stage.totals, count=shots * stage.totals.shape[1])
        if with_tally:
            if self.tally is None:
                self.tally = {name: self._like(arr, "tally_" + name) for name, arr in stage.tally.totals.items()}
            for name, arr in stage.tally.totals.items():
                if arr.size:
                    wp.copy(self.tally[name], arr)
        if shot_pieces:
            wp.copy(self.piece_rows, stage.shot_pass.rows, count=shot_pieces * SEGMENT_WIDTH)
        self.rows, self.segment_count, self.shots, self.with_tally = rows, segments, shots, with_tally
        self.shot_pieces = shot_pieces
        device = stage.model.device
        self.event = device.stream.record_event() if device.is_cuda else None

    def results(self):
        """(per-pellet arrays, segment results, shot totals, landing counts so far or None, per-piece
        partials of the chunk's shots or None) once the copies are done."""
        if self.event is not None:
            wp.synchronize_event(self.event)
        totals = self.totals.numpy()[: self.shots].copy() if self.shots else None
        pieces = None if self.shot_pieces is None else self.piece_rows.numpy()[: self.shot_pieces].copy()
        return (
            {name: arr.numpy() for name, arr in self.arrays.items()},
            self.segments.numpy()[: self.segment_count],
            totals,
            {name: arr.numpy() for name, arr in self.tally.items()} if self.with_tally else None,
            pieces,
        )


def run(scene, model, spec, *, arrays=None, sink=None, resumed=None, progress=None, options=None, frames=None, plan=None) -> dict:
    """Every pellet of `scene` through `model`'s device as `spec` compiles it; returns the statistics.
    arrays: a pellet file's launch states; sink: receives each chunk (`append(arrays, rows,
    segment_results, shot_totals, tally, shot_partials)`); resumed: a `Resumed`; progress(done, total); options: the
    dense phase's `DenseOptions`; frames(step, time, positions): trajectory frames; plan: a bounded
    run's checks (`bound.BoundPlan`; `scene` is then its budget's, `bound.planned`): the run stops at
    the first check that meets the bound, its outcome in the statistics' `bound`."""
    with interrupts.honoured(), _DEVICE_LOCK if model.device.is_cuda else contextlib.nullcontext():
        pellets = scene.shot.pellets
        warn_one_shot(scene, spec)
        stage = make_stage(scene, model, spec, arrays, pellets, options, frames)
        layout, fold = station_fold(scene, spec)
        totals, tables, tally, pieces, pellets, outcome = _loop(stage, pellets, sink, resumed, progress, plan, fold)
    shot_pieces = None if stage.shot_pass is None else stage.shot_pass.pieces
    return results(scene, model, spec, (totals, tables, tally, pieces, pellets, outcome), fold, layout, shot_pieces)


def warn_one_shot(scene, spec) -> None:
    """ONE_SHOT_COLLISIONS, for a run of one shot with pair collisions."""
    if spec.collisions and scene.shot.shots == 1:
        warnings.warn(ONE_SHOT_COLLISIONS, ChaosWarning, stacklevel=4)


def make_stage(scene, model, spec, arrays, pellets, options=None, frames=None):
    """The stage computing `scene`'s chunks: whole shots with pair collisions, else pellet rows."""
    if spec.collisions:
        return CollisionStage(scene, model, spec, arrays, pellets, options, frames)
    return CoreStage(scene, model, spec, arrays, pellets)


def station_fold(scene, spec):
    """(layout, fold) of a run with [[stations]] (`bound.station_pieces`, `StationFold`); ([], None) without."""
    if not scene.stations:
        return [], None
    layout = station_pieces(scene)
    return layout, StationFold(layout, len(scene.stations), scene.shot.count, spec.collisions)


def results(scene, model, spec, folded, fold, layout, shot_pieces) -> RunStats:
    """The statistics of a run from what its chunks folded to (`_loop`'s results: totals, shot
    totals tables, landing counts, per-shot partials, pellets complete, a bound's outcome), its
    stations' `fold` and `layout`, and `shot_pieces` (pieces a shot, `core.shots`; None: one shot)."""
    totals, tables, tally, pieces, pellets, outcome = folded
    kw = dict(mass=model.mass, inertia=model.inertia, air=spec.in_air, rest=spec.to_rest)
    stats = RunStats(finalize(totals, pellets=pellets, **kw))
    stats.tally, stats.bound = tally, outcome
    if fold is not None:
        stats.stations = {}
        for k, values, counts in fold.results(tally, pellets, **kw):
            stats.stations[scene.stations[k].name] = RunStats(values)
            stats.stations[scene.stations[k].name].tally = counts
    warn_coarse_positions(stats["flight_scale_max"], model.precision, model.radius)
    if spec.in_air and stats["flights_unfinished"] > 0:
        warnings.warn(
            UNFINISHED_FLIGHTS.format(int(stats["flights_unfinished"]), MAX_FLIGHT_STEPS), PrecisionWarning, stacklevel=4
        )
    if spec.collisions:
        table = np.concatenate(tables) if tables else np.zeros((0, len(SHOT_TOTALS)))
        stats.update(collision_statistics(table, pellets))
        for k, part in _station_parts(scene, stats):  # each station's shots
            part.update(collision_statistics(table[station_shots(layout, k, len(table))], int(part["pellets"])))
        if stats["skin_overrun_max"] > OVERRUN_TOLERANCE:
            warnings.warn(SKIN_OVERRUN.format(stats["skin_overrun_max"]), PrecisionWarning, stacklevel=4)
    if shot_pieces is not None:
        per_shot = per_shot_statistics(
            np.concatenate(pieces),
            shot_pieces,
            count=scene.shot.count,
            mass=model.mass,
            inertia=model.inertia,
            air=spec.in_air,
            rest=spec.to_rest,
            shot_totals=table if spec.collisions else None,
        )
        stats.ensemble = ensemble_of(per_shot, pellets // scene.shot.count)
        for k, part in _station_parts(scene, stats):  # each station's shots
            shots = station_shots(layout, k, stats.ensemble.shots)
            if len(shots) > 1:
                part.ensemble = ensemble_of({name: v[shots] for name, v in per_shot.items()}, len(shots))
    return stats


def _station_parts(scene, stats):
    """(station index, its RunStats) of each station with results (`RunStats.stations`)."""
    index = {s.name: k for k, s in enumerate(scene.stations)}
    return [(index[name], part) for name, part in (stats.stations or {}).items()]


def warn_coarse_positions(scale: float, precision: str, radius: float) -> bool:
    """The precision rule: warn (one line) when the unit roundoff of `precision` times the largest
    flight scale (m) exceeds POSITION_RESOLUTION of the pellet radius (m); returns whether it did."""
    error = UNIT_ROUNDOFF[precision] * scale
    if not error > POSITION_RESOLUTION * radius:  # (NaN: no flight met a surface)
        return False
    warnings.warn(
        COARSE_POSITIONS.format(
            precision=precision,
            eps="2^-24" if precision == "float32" else "2^-53",
            scale=scale,
            error=error,
            parts=1 / POSITION_RESOLUTION,
            radius=radius,
            fix=FIX[precision],
        ),
        PrecisionWarning,
        stacklevel=5,
    )
    return True


def stretch_end(fold, plan, tally, done: int, number: int):
    """At a stretch's end (`done` pellets): a station piece's counts kept (`fold`), and check
    `number` of a bounded run's `plan` made: its outcome (None: not a check)."""
    if fold is not None:
        fold.snapshot(done, tally)
    if not number:
        return None
    outcome = plan.result(tally, done, number)
    log.info("check %d after %s pellets: %s", number, f"{done:,}", outcome.interval_text())
    return outcome


def _loop(stage, pellets, sink, resumed, progress, plan=None, fold=None, kept=None):
    """The chunk loop; returns the folded statistics totals, the shots' totals tables and the
    landing counts (None when not counted), the per-shot partials (`core.shots`), in shot order,
    the pellets complete and, with a `plan` (`bound.BoundPlan`), the outcome of its last check.
    With a `fold` (`tallies.by_station.StationFold`) each piece of a station's shots is a stretch of
    its own, the fold given each chunk's partials and the counts at each piece's end. `kept`: a list
    given each chunk's segment results, copied (a cluster's task returns them: `tasks`)."""
    totals, tables, pieces, done = empty_totals(), [], [], 0
    tally = TallyTotals(stage.tally.setup) if stage.tally.active else None
    loaded = None  # the resumed run's landing counts
    if resumed is not None and resumed.rows:
        totals, done = combine(totals, resumed.segment_results), resumed.rows
        if resumed.shot_totals is not None:
            tables.append(resumed.shot_totals)
        if tally is not None and resumed.tally is not None:
            loaded = tally.load(resumed.tally)
        if resumed.shot_partials is not None:
            pieces.append(resumed.shot_partials)
        if fold is not None:
            width = 0 if tally is None else sum(int(np.prod(shape)) for shape in tally.shapes.values())
            fold.resume(resumed.rows, resumed.segment_results, resumed.station_tally, width)
    if tally is not None:
        stage.tally.start(loaded, every_chunk=sink is not None)
    cuda = stage.model.device.is_cuda
    slots = [HostSlot(stage, pinned=cuda, index=i) for i in range(2 if cuda else 1)]

    def consume(slot):
        nonlocal totals, done
        arrays, segment_results, shot_totals, counts, shot_rows = slot.results()
        totals = combine(totals, segment_results)
        if kept is not None:
            kept.append(segment_results.copy())
        if fold is not None:
            fold.add(done, segment_results)
        if shot_totals is not None:
            tables.append(shot_totals)
        if tally is not None and counts is not None:
            tally.set(counts)
        if shot_rows is not None:
            pieces.append(shot_rows)
        if sink is not None:
            sink.append(arrays, slot.rows, segment_results, shot_totals, tally, shot_rows)
        done += slot.rows
        log.debug("%d of %d pellets complete", done, pellets)
        if progress is not None:
            progress(done, pellets)

    def finish(pending):
        """Consume the last chunk queued, the tally totals fetched with it (a sink had them chunk by chunk)."""
        fetch = tally is not None and sink is None
        if fetch:
            stage.tally.request()  # queued behind the last chunk: one wait for both
        if pending is not None:
            consume(pending)
        if fetch:
            stage.tally.receive(tally)

    pending, outcome, chunks = None, None, 0
    checks = plan.checks() if plan is not None else []
    every = fold.ends if fold is not None else (checks or [pellets])  # (a station run's pieces end at its checks too)
    for stop in every:
        number = checks.index(stop) + 1 if stop in checks else 0  # a check of the bound
        if stop < done:  # (a resumed run's checks passed)
            continue
        if number and stop == done:  # resumed at a check: its outcome again, from the counts kept
            outcome = plan.result(tally, done, number)
            if outcome.met:
                break
            continue
        stage.stop, begin = stop, done
        for start, rows in stage.chunks(begin):
            interrupts.check()
            segments, shots = stage.compute(start, rows)
            shot_pieces = stage.shot_rows(start, rows)
            slot = slots[chunks % len(slots)]
            chunks += 1
            if pending is slot:  # CPU: one slot, consume before reuse
                consume(pending)
                pending = None
            slot.fill(stage, rows, segments, shots, with_tally=sink is not None, shot_pieces=shot_pieces)
            if pending is not None:
                consume(pending)  # host work on the previous chunk while the device runs this one
            pending = slot
        if fold is not None or number:  # a piece's end or a check: every chunk before it consumed, the counts read
            finish(pending)
            pending = None
        outcome = stretch_end(fold, plan, tally, done, number) or outcome
        if number and outcome.met:
            break
    if plan is None and fold is None:
        finish(pending)
    interrupts.check()
    return totals, tables, tally, pieces, done, outcome
