"""The hazard's watch replayed after the core (docs/hazard.md, "The watch replayed by a kernel of its own").

In a run to rest on a GPU (`spec.RunSpec.replay`) the core kernel does not watch a pellet's path: each
call of the watch (`tallies.path`'s `segment`, `parabola`, `line`; a phase along a line's steps and its
end, `tallies.path_chord`) writes its arguments as a record into the pellet's column of the record log
(`Tally.steps`: word j of chunk row r at j * log_threads + r; word 0 counts the words written, or is
OVERFLOWED where the column filled). The replay kernel (`core.replay`, one thread a pellet) then makes
the same calls with the same values in the same order, so the results are the same bits; the core holds
none of the watch's code (bench/RESULTS.md, "The watch replayed by a kernel of its own": a fallback
compiled into the core costs although it never runs). A pellet whose column filled records no more
(its Track's `log_slot` < 0 from then on), and the core kernel follows those pellets again with the
watch in it and the statistics off (`core.replay.Replay.after_core`).

A phase along a line is recorded compactly, as `physics.line_log` logs it: where it begins (x, speed,
deceleration, direction), then each step's end (x1, dt, v1, d1; on rough ground also the direction at
its start); its start is the step before's end. `line_step` and `rough_step` turn a step into the watch's
call, for the core (`physics.line_log.watch_step`) and for the replay alike.
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.types import types_for
from .path_cells import NONE
from .path_chord import make_path_watch

SEGMENT, PARABOLA, LINE, OPEN, STEP, ROUGH_STEP, CLOSE = 1, 2, 3, 4, 5, 6, 7  # record tags
SIZE = {SEGMENT: 21, PARABOLA: 11, LINE: 11, OPEN: 9, STEP: 7, ROUGH_STEP: 10, CLOSE: 4}  # words, tag included
COLUMN_WORDS = 512  # a pellet's column of the record log: its count and its records (words)
OVERFLOWED = -2.0  # a column's count where the pellet's records did not fit
REPLAY = "cuda"  # where runs to rest that watch their path replay it: "cuda" (GPUs), "always", "never"


def replays_on(device) -> bool:
    """Whether a run on `device` (None: not known) records its watch for the replay (`REPLAY`)."""
    return REPLAY == "always" or (REPLAY == "cuda" and device is not None and bool(getattr(device, "is_cuda", False)))


def watch_for(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False, replay: bool = False):
    """The watch of `spec.RunSpec.watch`: `make_path_watch`'s, or its recording one (`replay`)."""
    if replay and thresholds > 0:
        return make_recording_watch(precision, thresholds, points, with_map, terrain)
    return make_path_watch(precision, thresholds, points, with_map, terrain)


@functools.cache
def make_line_steps(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """`line_step` and `rough_step`: a step of a phase along a line given to the watch as the time
    Hermite of its ends along its chord (quintic: the integrated path to O(dt^6))."""
    watcher = make_path_watch(precision, thresholds, points, with_map, terrain)
    Track, Tally, Straight = watcher.Track, watcher.Tally, watcher.Straight
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def line_step(track: Track, tally: Tally, pending: Straight, x0: vec3, x1: vec3, e: vec3, decel0: scalar, dt: scalar, v0: scalar, v1: scalar, d1: scalar):  # fmt: skip
        """The step from x0 (speed v0, deceleration decel0) to x1 (dt s; v1, d1 there) along e, added
        to the phase's steps `pending`. Returns (track, pending)."""
        d0 = (dt * v0) * e
        e0 = (-dt * dt * decel0) * e
        e1 = (-dt * dt * d1) * e
        return watcher.straight_segment(track, tally, pending, x0, d0, e0, x1, (dt * v1) * e, e1, dt, v0, v1)

    @wp.func
    def rough_step(track: Track, tally: Tally, x0: vec3, x1: vec3, e: vec3, decel0: scalar, dt: scalar, v0: scalar, v1: scalar, d1: scalar):  # fmt: skip
        """The same on rough ground, watched at once along its own chord (e: the direction at its
        start, taken where the step is too short to have one)."""
        if wp.length(x1 - x0) > ZERO:
            e = x1 - x0
            e = e * (ONE / wp.length(e))
        d0 = (dt * v0) * e
        e0 = (-dt * dt * decel0) * e
        e1 = (-dt * dt * d1) * e
        return watcher.segment(track, tally, x0, d0, e0, x1, (dt * v1) * e, e1, dt, ONE)

    return SimpleNamespace(line_step=line_step, rough_step=rough_step)


_AT = "(size_t)(unsigned int)j * (size_t)(unsigned int)threads + (size_t)(unsigned int)slot"
_LOAD = f"return steps.data[{_AT}];"
_STORE = f"steps.data[{_AT}] = value;"


@wp.func_native(_LOAD)
def load32(steps: wp.array(dtype=wp.float32), j: wp.int32, threads: wp.int32, slot: wp.int32) -> wp.float32:
    """Word j of column `slot` of a contiguous log of `threads` columns (word j * threads + slot, in 64
    bits: the log may hold more words than its shape says, `tallies.counts.log_buffer`; no negative
    wrap, no stride)."""
    ...


@wp.func_native(_STORE)
def store32(steps: wp.array(dtype=wp.float32), j: wp.int32, threads: wp.int32, slot: wp.int32, value: wp.float32):
    """Word j of column `slot` of a contiguous log of `threads` columns set to `value` (`load32`)."""
    ...


@wp.func_native(_LOAD)
def load64(steps: wp.array(dtype=wp.float64), j: wp.int32, threads: wp.int32, slot: wp.int32) -> wp.float64:
    """`load32` in float64."""
    ...


@wp.func_native(_STORE)
def store64(steps: wp.array(dtype=wp.float64), j: wp.int32, threads: wp.int32, slot: wp.int32, value: wp.float64):
    """`store32` in float64."""
    ...


def raw_access(precision: str):
    """(load, store) of a contiguous record log's words in `precision`."""
    return (load64, store64) if precision == "float64" else (load32, store32)


@functools.cache
def make_path_replay(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """`replay` (a column's records given to the watch) and the log's `get` and `put` (`put3`: a
    vector's three words) of `make_path_watch`'s arguments."""
    real = make_path_watch(precision, thresholds, points, with_map, terrain)
    steps = make_line_steps(precision, thresholds, points, with_map, terrain)
    Track, Tally, Straight = real.Track, real.Tally, real.Straight
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    load, store = raw_access(precision)

    @wp.func
    def get(tally: Tally, slot: wp.int32, j: wp.int32):
        return load(tally.steps, j, tally.log_threads, slot)

    @wp.func
    def get3(tally: Tally, slot: wp.int32, j: wp.int32):
        return vec3(get(tally, slot, j), get(tally, slot, j + 1), get(tally, slot, j + 2))

    @wp.func
    def put(tally: Tally, slot: wp.int32, j: wp.int32, value: scalar):
        store(tally.steps, j, tally.log_threads, slot, value)

    @wp.func
    def put3(tally: Tally, slot: wp.int32, j: wp.int32, value: vec3):
        for i in range(3):
            put(tally, slot, j + i, value[i])

    @wp.func
    def size(tag: wp.int32):
        """Words of a record of `tag` (`SIZE`)."""
        n = wp.where(tag == ROUGH_STEP, wp.static(SIZE[ROUGH_STEP]), wp.static(SIZE[CLOSE]))
        n = wp.where(tag == STEP, wp.static(SIZE[STEP]), wp.where(tag == OPEN, wp.static(SIZE[OPEN]), n))
        n = wp.where(tag == PARABOLA or tag == LINE, wp.static(SIZE[PARABOLA]), n)
        return wp.where(tag == SEGMENT, wp.static(SIZE[SEGMENT]), n)

    @wp.func
    def flight(track: Track, tally: Tally, slot: wp.int32, j: wp.int32, tag: wp.int32):
        """A SEGMENT, PARABOLA or LINE record at word j given to the watch."""
        if tag == SEGMENT:
            track = real.segment(
                track, tally, get3(tally, slot, j + 1), get3(tally, slot, j + 4), get3(tally, slot, j + 7),
                get3(tally, slot, j + 10), get3(tally, slot, j + 13), get3(tally, slot, j + 16),
                get(tally, slot, j + 19), get(tally, slot, j + 20),
            )  # fmt: skip
        elif tag == PARABOLA:
            track = real.parabola(
                track, tally, get3(tally, slot, j + 1), get3(tally, slot, j + 4), get3(tally, slot, j + 7), get(tally, slot, j + 10)
            )  # fmt: skip
        else:
            track = real.line(
                track, tally, get3(tally, slot, j + 1), get3(tally, slot, j + 4), get(tally, slot, j + 7),
                get(tally, slot, j + 8), get(tally, slot, j + 9), get(tally, slot, j + 10),
            )  # fmt: skip
        return track

    @wp.struct
    class Phase:
        """A phase along a line under replay: its steps pending, where the next step begins (m; its
        speed m/s and deceleration m/s^2 there) and its direction."""

        pending: Straight
        x0: vec3
        e: vec3
        v0: scalar
        decel0: scalar

    @wp.func
    def open_phase():
        phase = Phase()
        phase.pending = real.straight_open()
        return phase

    @wp.func
    def along(track: Track, tally: Tally, slot: wp.int32, j: wp.int32, tag: wp.int32, phase: Phase):
        """An OPEN or CLOSE record at word j given to the watch (a step's is `replay`'s). Returns
        (track, phase)."""
        if tag == OPEN:
            phase = open_phase()
            phase.x0 = get3(tally, slot, j + 1)
            phase.v0 = get(tally, slot, j + 4)
            phase.decel0 = get(tally, slot, j + 5)
            phase.e = get3(tally, slot, j + 6)
        else:
            pending = phase.pending
            track, pending = real.straight_close(track, tally, pending, get3(tally, slot, j + 1))
            phase.pending = pending
        return track, phase

    @wp.func
    def replay(track: Track, tally: Tally, slot: wp.int32, count: wp.int32):
        """The column's `count` words of records given to the watch in order. Returns track. A step's
        first words (the commonest record) are read with its tag, their addresses known before it
        (within the column), so that a step waits for one round of reads, not two."""
        phase = open_phase()
        last = tally.log_words - 1  # the column's last word
        j = wp.int32(1)
        while j <= count:
            tag = wp.int32(get(tally, slot, j))
            x1 = vec3(get(tally, slot, wp.min(j + 1, last)), get(tally, slot, wp.min(j + 2, last)), get(tally, slot, wp.min(j + 3, last)))  # fmt: skip
            dt = get(tally, slot, wp.min(j + 4, last))
            v1 = get(tally, slot, wp.min(j + 5, last))
            d1 = get(tally, slot, wp.min(j + 6, last))
            if tag == STEP or tag == ROUGH_STEP:  # a step from the one before's end
                if tag == STEP:
                    pending = phase.pending
                    track, pending = steps.line_step(track, tally, pending, phase.x0, x1, phase.e, phase.decel0, dt, phase.v0, v1, d1)  # fmt: skip
                    phase.pending = pending
                else:  # (on rough ground, with the line's direction at its start)
                    e = get3(tally, slot, j + 7)
                    track = steps.rough_step(track, tally, phase.x0, x1, e, phase.decel0, dt, phase.v0, v1, d1)
                phase.x0 = x1
                phase.v0 = v1
                phase.decel0 = d1
            elif tag <= LINE:
                track = flight(track, tally, slot, j, tag)
            else:
                track, phase = along(track, tally, slot, j, tag, phase)
            j += size(tag)
        return track

    return SimpleNamespace(replay=replay, get=get, put=put, put3=put3)


@functools.cache
def recording_structs(scalar):
    """The recording core's `Track` (its column of the record log, and the pass's `cell` that a dense
    phase's leap marks) and `Straight` (nothing pending: the replay gathers a phase's steps): the
    watch's own would be carried through the core for nothing (bench/RESULTS.md, "A slim track")."""
    Track = wp.struct(
        type(
            "Track",
            (),
            {
                "__annotations__": {"cell": wp.int32, "log_slot": wp.int32},
                "__module__": __name__,
                "__qualname__": "recording_structs.<locals>.Track",
            },
        )
    )
    Straight = wp.struct(
        type(
            "Straight",
            (),
            {
                "__annotations__": {"length": scalar},
                "__module__": __name__,
                "__qualname__": "recording_structs.<locals>.Straight",
            },
        )
    )
    return Track, Straight


@functools.cache
def make_recording_watch(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """The watch's namespace (`make_path_watch`) whose calls write records for the replay (module
    docstring), with the recorded phase along a line's `line_open` and `step`; its `Track` and
    `Straight` are `recording_structs`' (`claim`: where a record goes in the pellet's column)."""
    real = make_path_watch(precision, thresholds, points, with_map, terrain)
    rp = make_path_replay(precision, thresholds, points, with_map, terrain)
    get, put, put3 = rp.get, rp.put, rp.put3
    Tally = real.Tally
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    Track, Straight = recording_structs(scalar)

    @wp.func
    def start():
        """No column yet (`seat`), no pass under way."""
        track = Track()
        track.cell = wp.int32(NONE)
        track.log_slot = wp.int32(-1)
        return track

    @wp.func
    def seat(track: Track, tally: Tally, row: wp.int32):
        """The pellet's column of the record log: its chunk row's, no record in it yet."""
        track.log_slot = row
        put(tally, row, 0, scalar(0.0))
        return track

    @wp.func
    def straight_open():
        """Nothing pending (the replay gathers the phase's steps)."""
        pending = Straight()
        pending.length = scalar(-1.0)
        return pending

    @wp.func
    def claim(track: Track, tally: Tally, words: wp.int32):
        """Where a record of `words` words begins in the pellet's column (its count raised), or -1
        where the column is full (OVERFLOWED: no more records). Returns (track, first word)."""
        if track.log_slot < 0:
            return track, wp.int32(-1)
        used = wp.int32(get(tally, track.log_slot, 0))
        if used + words >= tally.log_words:  # (the column's words: `COLUMN_WORDS`)
            put(tally, track.log_slot, 0, scalar(OVERFLOWED))
            track.log_slot = -1 - track.log_slot
            return track, wp.int32(-1)
        put(tally, track.log_slot, 0, scalar(used + words))
        return track, used + 1

    @wp.func
    def segment(track: Track, tally: Tally, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, h: scalar, theta_end: scalar):  # fmt: skip
        track, j = claim(track, tally, wp.static(SIZE[SEGMENT]))
        if j < 0:
            return track
        slot = track.log_slot
        put(tally, slot, j, scalar(SEGMENT))
        put3(tally, slot, j + 1, x0)
        put3(tally, slot, j + 4, d0)
        put3(tally, slot, j + 7, e0)
        put3(tally, slot, j + 10, x1)
        put3(tally, slot, j + 13, d1)
        put3(tally, slot, j + 16, e1)
        put(tally, slot, j + 19, h)
        put(tally, slot, j + 20, theta_end)
        return track

    @wp.func
    def parabola(track: Track, tally: Tally, x0: vec3, v0: vec3, g: vec3, dt: scalar):
        track, j = claim(track, tally, wp.static(SIZE[PARABOLA]))
        if j < 0:
            return track
        slot = track.log_slot
        put(tally, slot, j, scalar(PARABOLA))
        put3(tally, slot, j + 1, x0)
        put3(tally, slot, j + 4, v0)
        put3(tally, slot, j + 7, g)
        put(tally, slot, j + 10, dt)
        return track

    @wp.func
    def line(track: Track, tally: Tally, x0: vec3, direction: vec3, length: scalar, v0: scalar, a: scalar, b: scalar):  # fmt: skip
        track, j = claim(track, tally, wp.static(SIZE[LINE]))
        if j < 0:
            return track
        slot = track.log_slot
        put(tally, slot, j, scalar(LINE))
        put3(tally, slot, j + 1, x0)
        put3(tally, slot, j + 4, direction)
        put(tally, slot, j + 7, length)
        put(tally, slot, j + 8, v0)
        put(tally, slot, j + 9, a)
        put(tally, slot, j + 10, b)
        return track

    @wp.func
    def line_open(track: Track, tally: Tally, pending: Straight, x: vec3, v: scalar, decel: scalar, e: vec3):
        """A phase along a line begins at x (speed v, deceleration `decel`, direction e). Returns
        (track, pending)."""
        track, j = claim(track, tally, wp.static(SIZE[OPEN]))
        if j >= 0:
            slot = track.log_slot
            put(tally, slot, j, scalar(OPEN))
            put3(tally, slot, j + 1, x)
            put(tally, slot, j + 4, v)
            put(tally, slot, j + 5, decel)
            put3(tally, slot, j + 6, e)
        return track, pending

    @wp.func
    def step(track: Track, tally: Tally, pending: Straight, x0: vec3, x1: vec3, e: vec3, decel0: scalar, dt: scalar, v0: scalar, v1: scalar, d1: scalar, rough: wp.bool):  # fmt: skip
        """A step of a phase along a line (`make_line_steps`; its start the step before's end).
        Returns (track, pending)."""
        track, j = claim(track, tally, wp.where(rough, wp.static(SIZE[ROUGH_STEP]), wp.static(SIZE[STEP])))
        if j < 0:
            return track, pending
        slot = track.log_slot
        put(tally, slot, j, wp.where(rough, scalar(ROUGH_STEP), scalar(STEP)))
        put3(tally, slot, j + 1, x1)
        put(tally, slot, j + 4, dt)
        put(tally, slot, j + 5, v1)
        put(tally, slot, j + 6, d1)
        if rough:
            put3(tally, slot, j + 7, e)
        return track, pending

    @wp.func
    def straight_close(track: Track, tally: Tally, pending: Straight, x: vec3):
        track, j = claim(track, tally, wp.static(SIZE[CLOSE]))
        if j >= 0:
            put(tally, track.log_slot, j, scalar(CLOSE))
            put3(tally, track.log_slot, j + 1, x)
        return track, pending

    @wp.func
    def finish(track: Track, tally: Tally, row: wp.int32):
        """Nothing: the replay kernel (or the rerun of an OVERFLOWED pellet) counts the pellet."""
        pass

    @wp.func
    def write(track: Track, reach_out: wp.array2d(dtype=scalar), row: wp.int32):
        """Nothing: the replay kernel (or the rerun) writes the pellet's reach."""
        pass

    return SimpleNamespace(
        **{
            **vars(real),
            "Track": Track,
            "Straight": Straight,
            "start": start,
            "seat": seat,
            "straight_open": straight_open,
            "segment": segment,
            "parabola": parabola,
            "line": line,
            "straight_close": straight_close,
            "finish": finish,
            "write": write,
            "line_open": line_open,
            "step": step,
            "RECORDING": True,
        }
    )
