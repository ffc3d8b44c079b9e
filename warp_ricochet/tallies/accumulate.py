"""Per-thread accumulation of the statistics (`tallies.sums`) inside the core kernel.

A thread's partials are `counts` (int32: hits, slip, landed, landed_slip), `acc` (the float sums
in the working precision: at most PER_THREAD = 256 terms, a relative rounding error of order
1e-6 in float32), `lo`/`hi` (range extremes: all, stick, slip; then `hi` the largest flight scale;
then, following pellets to rest, the rest distances) and `range_shift` (the thread's first range:
ranges are summed as deviations from it; the rest distances likewise from the sum END_SHIFT). `store_partials` widens them to float64
once per thread; from there on everything is float64 (`tallies.reduce`). Each helper returns one
vector (see `core.pellet` on why).
"""

import functools
import math
from types import SimpleNamespace

import warp as wp

from ..ends import AT_REST, EMBEDDED, NOT_FINISHED
from ..physics.air_flight import GAVE_UP
from ..physics.types import types_for
from .sums import FLIGHT_SCALE, NUM_COUNTS, NUM_EXTREMES, NUM_FLOATS, REST, SUM

# offsets into the float accumulator (counts are separate)
OFFSETS = SimpleNamespace(
    PRE=SUM["vt_pre"] - NUM_COUNTS,
    POST=SUM["vt_post"] - NUM_COUNTS,  # vt, vn, wx, wy, wz, v2, w2 each
    V2_LAUNCH=SUM["v2_launch"] - NUM_COUNTS,
    W2_LAUNCH=SUM["w2_launch"] - NUM_COUNTS,
    RANGE=SUM["range"] - NUM_COUNTS,
    RANGE2=SUM["range_m2"] - NUM_COUNTS,  # deviations from the thread's first range
    RANGE_STICK=SUM["range_stick"] - NUM_COUNTS,
    RANGE_SLIP=SUM["range_slip"] - NUM_COUNTS,
    TIME_ALOFT=SUM["time_aloft"] - NUM_COUNTS,
    V2_LANDING=SUM["v2_landing"] - NUM_COUNTS,
    FLIGHT_STEPS=SUM["flight_steps"] - NUM_COUNTS,
    FLIGHT_UNFINISHED=SUM["flight_unfinished"] - NUM_COUNTS,
    ENTERED=SUM["entered"] - NUM_COUNTS,
    END_STOPPED=SUM["end_stopped"] - NUM_COUNTS,  # physics.until = "rest": counts (exact: < 2^24 a thread)
    END_AT_REST=SUM["end_at_rest"] - NUM_COUNTS,
    END_NOT_FINISHED=SUM["end_not_finished"] - NUM_COUNTS,
    END_DISTANCE=SUM["end_distance"] - NUM_COUNTS,  # deviations from END_SHIFT, the thread's first rest distance
    END_DISTANCE2=SUM["end_distance_m2"] - NUM_COUNTS,
    END_SHIFT=SUM["end_shift"] - NUM_COUNTS,
    END_PATH=SUM["end_path"] - NUM_COUNTS,
    END_IMPACTS=SUM["end_impacts"] - NUM_COUNTS,
    END_STEPS=SUM["end_steps"] - NUM_COUNTS,
)


# the rest sums and extreme are the last ones: a run that does not follow pellets to rest leaves them
# out of its vectors (its registers and copies), and stores zeros and empty extremes for them
assert SUM["end_stopped"] - NUM_COUNTS == NUM_FLOATS - 9 and REST == NUM_EXTREMES - 1


@functools.cache
def make_accumulators(precision: str, rest: bool = False) -> SimpleNamespace:
    """The vector types of the partials and the functions that add to them and store them; `rest`:
    with the sums of where pellets end (physics.until = "rest", `add_rest_sums`)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    n_floats, n_extremes = (NUM_FLOATS, NUM_EXTREMES) if rest else (OFFSETS.END_STOPPED, REST)
    floats_t = wp.types.vector(n_floats, scalar)
    extremes_t = wp.types.vector(n_extremes, scalar)
    REST_ON, inf64 = rest, wp.float64(math.inf)
    F_PRE, F_POST, F_V2_LAUNCH, F_W2_LAUNCH = OFFSETS.PRE, OFFSETS.POST, OFFSETS.V2_LAUNCH, OFFSETS.W2_LAUNCH
    F_RANGE, F_RANGE2, F_TIME_ALOFT, F_V2_LANDING = OFFSETS.RANGE, OFFSETS.RANGE2, OFFSETS.TIME_ALOFT, OFFSETS.V2_LANDING
    F_FLIGHT_STEPS, F_FLIGHT_UNFINISHED = OFFSETS.FLIGHT_STEPS, OFFSETS.FLIGHT_UNFINISHED
    F_END_STOPPED, F_END_AT_REST, F_END_NOT_FINISHED = OFFSETS.END_STOPPED, OFFSETS.END_AT_REST, OFFSETS.END_NOT_FINISHED
    F_END_DISTANCE, F_END_DISTANCE2, F_END_SHIFT = OFFSETS.END_DISTANCE, OFFSETS.END_DISTANCE2, OFFSETS.END_SHIFT
    F_END_PATH, F_END_IMPACTS, F_END_STEPS = OFFSETS.END_PATH, OFFSETS.END_IMPACTS, OFFSETS.END_STEPS
    S_AT_REST, S_EMBEDDED, S_NOT_FINISHED = AT_REST, EMBEDDED, NOT_FINISHED
    num_counts, num_floats, num_extremes = NUM_COUNTS, NUM_FLOATS, NUM_EXTREMES

    @wp.func
    def add_impact_sums(acc: floats_t, base: wp.int32, velocity: vec3, angular_velocity: vec3, normal: vec3):
        """Accumulate vt, vn, omega, |v|^2, |omega|^2 of one pellet at `base` (a constant)."""
        vn = wp.dot(velocity, normal)
        acc[base + 0] += wp.length(velocity - vn * normal)
        acc[base + 1] += vn
        acc[base + 2] += angular_velocity[0]
        acc[base + 3] += angular_velocity[1]
        acc[base + 4] += angular_velocity[2]
        acc[base + 5] += wp.dot(velocity, velocity)
        acc[base + 6] += wp.dot(angular_velocity, angular_velocity)
        return acc

    @wp.func
    def add_first_impact_sums(
        acc: floats_t,
        velocity_before: vec3,
        spin_before: vec3,
        velocity_after: vec3,
        spin_after: vec3,
        normal: vec3,
        launch_v2: scalar,
        launch_w2: scalar,
    ):
        """The float sums of a pellet's first impact: the states before and after, its launch
        |v|^2 and |omega|^2 (its counts are the caller's)."""
        acc = add_impact_sums(acc, F_PRE, velocity_before, spin_before, normal)
        acc = add_impact_sums(acc, F_POST, velocity_after, spin_after, normal)
        acc[F_V2_LAUNCH] += launch_v2
        acc[F_W2_LAUNCH] += launch_w2
        return acc

    @wp.func
    def add_landing_sums(acc: floats_t, deviation: scalar, time_aloft: scalar, landing_velocity: vec3):
        """The float sums of a landing: its range as a deviation from the thread's first, its time
        aloft, its |v|^2 (the range by branch, counts and extremes are the caller's)."""
        acc[F_RANGE] += deviation
        acc[F_RANGE2] += deviation * deviation
        acc[F_TIME_ALOFT] += time_aloft
        acc[F_V2_LANDING] += wp.dot(landing_velocity, landing_velocity)
        return acc

    @wp.func
    def add_flight_sums(acc: floats_t, steps: wp.int32, plane: wp.int32):
        """A flight in air: its integration steps, and whether it was given up (plane GAVE_UP)."""
        acc[F_FLIGHT_STEPS] += scalar(steps)
        if plane == GAVE_UP:
            acc[F_FLIGHT_UNFINISHED] += scalar(1.0)
        return acc

    def add_rest_sums(acc: floats_t, state: wp.int32, distance: scalar, path_length: scalar, impacts: wp.int32, steps: wp.int32):
        """Where a pellet ends (`ends`): its impacts and integration steps after its landing; stopped (at rest or embedded), its rest
        distance as a deviation from the thread's first (kept in END_SHIFT) and its path along
        surfaces; its end state's count (extremes are the caller's)."""
        acc[F_END_IMPACTS] += scalar(impacts)
        acc[F_END_STEPS] += scalar(steps)
        if state == S_AT_REST or state == S_EMBEDDED:
            if acc[F_END_STOPPED] == scalar(0.0):
                acc[F_END_SHIFT] = distance
            deviation = distance - acc[F_END_SHIFT]
            acc[F_END_STOPPED] += scalar(1.0)
            acc[F_END_DISTANCE] += deviation
            acc[F_END_DISTANCE2] += deviation * deviation
            acc[F_END_PATH] += path_length
            if state == S_AT_REST:
                acc[F_END_AT_REST] += scalar(1.0)
        elif state == S_NOT_FINISHED:
            acc[F_END_NOT_FINISHED] += scalar(1.0)
        return acc

    add_rest_sums = wp.func(add_rest_sums) if rest else None  # (only with the rest sums in the vector)

    @wp.func
    def flight_scale(position: vec3, velocity: vec3, dt: scalar, gravity: vec3):
        """M = |x0| + |v0| t + |g| t^2 / 2 (m) of a flight from `position` at `velocity` lasting `dt`
        (s), |.| the largest absolute component: no coordinate along the flight exceeds it
        (`tallies.sums`; the precision rule of docs/stability.md)."""
        return wp.max(wp.abs(position)) + dt * (wp.max(wp.abs(velocity)) + scalar(0.5) * dt * wp.max(wp.abs(gravity)))

    @wp.func
    def store_partials(
        tid: wp.int32,
        counts: wp.vec4i,
        acc: floats_t,
        lo: extremes_t,
        hi: extremes_t,
        range_shift: scalar,
        partial_sums: wp.array2d(dtype=wp.float64),
        partial_min: wp.array2d(dtype=wp.float64),
        partial_max: wp.array2d(dtype=wp.float64),
    ):
        """Widen once per thread: float64 from here on. Ranges were summed as deviations from the
        thread's first range: the range row gets the plain sum back, the m2 row the squared
        deviations about the thread's mean (no cancellation; merged across threads by Chan)."""
        for c in range(num_counts):
            partial_sums[c, tid] = wp.float64(counts[c])
        for f in range(wp.static(n_floats)):
            partial_sums[num_counts + f, tid] = wp.float64(acc[f])
        landed = wp.float64(counts[2])
        deviations = wp.float64(acc[F_RANGE])
        partial_sums[num_counts + F_RANGE, tid] = landed * wp.float64(range_shift) + deviations
        m2 = wp.float64(0.0)
        if counts[2] > 0:
            m2 = wp.max(wp.float64(acc[F_RANGE2]) - deviations * deviations / landed, wp.float64(0.0))
        partial_sums[num_counts + F_RANGE2, tid] = m2
        if wp.static(REST_ON):  # the rest distances likewise (from END_SHIFT; 0 kept there)
            stopped = wp.float64(acc[F_END_STOPPED])
            deviations = wp.float64(acc[F_END_DISTANCE])
            partial_sums[num_counts + F_END_DISTANCE, tid] = stopped * wp.float64(acc[F_END_SHIFT]) + deviations
            m2 = wp.float64(0.0)
            if stopped > wp.float64(0.0):
                m2 = wp.max(wp.float64(acc[F_END_DISTANCE2]) - deviations * deviations / stopped, wp.float64(0.0))
            partial_sums[num_counts + F_END_DISTANCE2, tid] = m2
            partial_sums[num_counts + F_END_SHIFT, tid] = wp.float64(0.0)
        for f in range(wp.static(n_floats), num_floats):  # (none following pellets to rest)
            partial_sums[num_counts + f, tid] = wp.float64(0.0)
        for e in range(wp.static(n_extremes)):
            partial_min[e, tid] = wp.float64(lo[e])
            partial_max[e, tid] = wp.float64(hi[e])
        for e in range(wp.static(n_extremes), num_extremes):
            partial_min[e, tid] = inf64
            partial_max[e, tid] = -inf64

    return SimpleNamespace(
        floats_t=floats_t,
        extremes_t=extremes_t,
        inf=scalar(math.inf),
        offsets=OFFSETS,
        flight_scale_index=FLIGHT_SCALE,
        flight_scale=flight_scale,
        add_first_impact_sums=add_first_impact_sums,
        add_landing_sums=add_landing_sums,
        add_flight_sums=add_flight_sums,
        add_rest_sums=add_rest_sums,
        store_partials=store_partials,
    )
