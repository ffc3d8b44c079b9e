"""The steps of a phase along a line, logged and given to the hazard's watch after (docs/hazard.md,
"The steps along a line, watched after"): `surface_line.integrate_line` writes each accepted step's
end into its thread's column of the step log (`Tally.steps`: `log_steps` steps of LOG_WORDS words,
ROUGH_WORDS on rough ground, interleaved by thread so that a warp's writes of one step meet) and
gives the logged steps to the watch (`watch_step`) in their order when the log is full and where the
phase ends. The watch gets the same values in the same order as when each step was watched at once,
so its results are the same bits for any `log_steps`; the step loop holds none of the watch's code
(on a GPU the watch's branches, its roots and its state slowed every step: bench/RESULTS.md, "The
steps along a line watched after").

A logged step is (x1, dt, v1, d1): where it ends (m), its time (s), its speed and its deceleration
there (m/s, m/s^2); on rough ground also `line.direction` at its start (the watch's direction of a
step too short to have one of its own). Its start (x0, v0 and the deceleration `line.decel` there)
is the step before's end, or where the phase began (`log_open`). The log exists where the watch is
on (`watch[0] > 0`); without it, or with `log_steps` = 0, `log_step` watches each step at once. The
host sizes it (`pipeline.log_threads`, `chunks.log_words`) and keeps its index within INDEX_LIMIT.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .inlining import out_of_line_on_cuda
from .line_laws import make_line_laws
from .types import types_for

LOG_STEPS = 32  # steps of a phase along a line a thread logs before they are watched
LOG_WORDS = 6  # a logged step's words: where it ends (3), its time, its speed and deceleration there
ROUGH_WORDS = 9  # on rough ground, and its direction at its start (3: the line turns every step)
INDEX_LIMIT = (1 << 31) - 1  # elements of one array a kernel indexes (int32: Warp's shapes and indices)


def step_words(rough: bool) -> int:
    """Words a logged step takes (`RunSpec.rough`: a scene with rough ground)."""
    return ROUGH_WORDS if rough else LOG_WORDS


@functools.cache
def make_line_log(
    precision: str,
    model: str = "ballistic",
    laws=None,
    watch: tuple = (0, 0, False),
    noise: tuple = (0.0, 0.0),
    rough=True,
    log_steps: int = LOG_STEPS,
) -> SimpleNamespace:
    """`StepLog` (where the logged steps begin, and how many), `log_open`, `log_step`, `log_close`
    and `watch_step` for `surface_line.integrate_line` of the same arguments (`make_line_integrator`'s)."""
    from ..tallies.path_replay import make_line_steps, watch_for  # (tallies imports physics: not at the top)

    if log_steps < 0:
        raise ValueError(f"log_steps must be at least 0: {log_steps}")
    watcher = watch_for(precision, *watch)
    steps = make_line_steps(precision, *watch[:4])
    RECORDING = getattr(watcher, "RECORDING", False)
    Track, Tally, Straight = watcher.Track, watcher.Tally, watcher.Straight
    Line = make_line_laws(precision, model, laws, noise, rough).Line
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    LOGGED, ROUGH, STEPS, WORDS = watch[0] > 0 and log_steps > 0 and not RECORDING, rough, log_steps, step_words(rough)

    @wp.func
    def watch_step(track: Track, tally: Tally, pending: Straight, x0: vec3, x1: vec3, line: Line, dt: scalar, v0: scalar, v1: scalar, d1: scalar):  # fmt: skip
        """Give the step (from x0 to x1, dt s; speeds v0, v1 and decelerations `line.decel`,
        d1 at its ends) to the watch (`tallies.path_replay.make_line_steps`; recorded for the replay
        where the watch is `RECORDING`). Returns (track, pending)."""
        if wp.static(RECORDING):
            return watcher.step(track, tally, pending, x0, x1, line.direction, line.decel, dt, v0, v1, d1, ROUGH)
        if wp.static(ROUGH and not RECORDING):
            return steps.rough_step(track, tally, x0, x1, line.direction, line.decel, dt, v0, v1, d1), pending
        if wp.static(not ROUGH and not RECORDING):
            return steps.line_step(track, tally, pending, x0, x1, line.direction, line.decel, dt, v0, v1, d1)

    @wp.struct
    class StepLog:
        """The logged steps of a phase: how many, and where the first begins."""

        count: wp.int32
        x: vec3  # m
        v: scalar  # m/s, the speed there
        decel: scalar  # m/s^2, the deceleration there

    @wp.func
    def log_open(track: Track, tally: Tally, pending: Straight, line: Line, x: vec3, v: scalar, decel: scalar):
        """No step logged; the next begins at x, at speed v and deceleration `decel` (recorded for the
        replay where the watch is `RECORDING`). Returns (log, track, pending)."""
        log = StepLog()
        log.x = x
        log.v = v
        log.decel = decel
        if wp.static(RECORDING):
            track, pending = watcher.line_open(track, tally, pending, x, v, decel, line.direction)
        return log, track, pending

    @wp.func
    def log_watch(track: Track, tally: Tally, pending: Straight, log: StepLog, line: Line):
        """The logged steps given to the watch in order (`watch_step`, `line.decel` each step's own);
        then none logged, the next beginning where the last ends. Returns (track, pending, log)."""
        threads = tally.log_threads
        for i in range(log.count):
            word = i * WORDS * threads + track.log_slot
            x1 = vec3(tally.steps[word], tally.steps[word + threads], tally.steps[word + 2 * threads])
            dt = tally.steps[word + 3 * threads]
            v1 = tally.steps[word + 4 * threads]
            d1 = tally.steps[word + 5 * threads]
            if wp.static(ROUGH):
                line.direction = vec3(
                    tally.steps[word + 6 * threads], tally.steps[word + 7 * threads], tally.steps[word + 8 * threads]
                )
            line.decel = log.decel
            track, pending = watch_step(track, tally, pending, log.x, x1, line, dt, log.v, v1, d1)
            log.x = x1
            log.v = v1
            log.decel = d1
        log.count = wp.int32(0)
        return track, pending, log

    @wp.func
    def log_step(
        track: Track,
        tally: Tally,
        pending: Straight,
        log: StepLog,
        line: Line,
        x0: vec3,
        x1: vec3,
        dt: scalar,
        v0: scalar,
        v1: scalar,
        d1: scalar,
    ):
        """A step from x0 (speed v0, deceleration `line.decel`) to x1 (dt s; v1, d1 at its end): logged
        (x0 and v0 are the log's: the step before's end), watched with the others when the log is
        full; without a log, watched at once. Returns (track, pending, log)."""
        if wp.static(LOGGED):
            threads = tally.log_threads
            word = log.count * WORDS * threads + track.log_slot
            tally.steps[word] = x1[0]
            tally.steps[word + threads] = x1[1]
            tally.steps[word + 2 * threads] = x1[2]
            tally.steps[word + 3 * threads] = dt
            tally.steps[word + 4 * threads] = v1
            tally.steps[word + 5 * threads] = d1
            if wp.static(ROUGH):
                for j in range(3):
                    tally.steps[word + (6 + j) * threads] = line.direction[j]
            log.count += 1
            if log.count == STEPS:
                track, pending, log = log_watch(track, tally, pending, log, line)
        if wp.static(not LOGGED):
            track, pending = watch_step(track, tally, pending, x0, x1, line, dt, v0, v1, d1)
        return track, pending, log

    @wp.func
    def log_close(track: Track, tally: Tally, pending: Straight, log: StepLog, line: Line):
        """Where the phase ends: the steps still logged given to the watch. Returns (track, pending)."""
        if wp.static(LOGGED):
            if log.count > 0:
                track, pending, log = log_watch(track, tally, pending, log, line)
        return track, pending

    if LOGGED:
        out_of_line_on_cuda(log_watch)
    return SimpleNamespace(StepLog=StepLog, log_open=log_open, log_step=log_step, log_close=log_close, watch_step=watch_step)
