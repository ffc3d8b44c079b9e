"""The layout of the statistics reduction and its segment kernel.

Threads and segments: thread t works on LANES consecutive-lane pellets at a time, so a warp
touches consecutive pellets (coalesced), and handles PER_THREAD of them. A segment is the
SEGMENT = LANES * PER_THREAD pellets of one group of LANES threads. Chunks start on segment
boundaries, so segment k always holds the same pellets and the reduction order (pellet order
within a thread, lane order within a segment, segment order on the host, `sums.combine`) is
independent of the chunk size. Costly pellets (followed to rest, tens of integration steps each;
against a terrain or a large mesh: `spec.RunSpec.lanes`) are spread wider, to keep a GPU's
multiprocessors busy from fewer pellets: REST_LANES threads a segment of the same SEGMENT pellets,
SEGMENT // REST_LANES a thread (`lanes_for`); their partials take 24 bytes a pellet (1.5 with LANES).
"""

import functools
import math

import warp as wp

from .sums import NUM_EXTREMES, NUM_SUMS, SUM

LANES = 256
PER_THREAD = 256
SEGMENT = LANES * PER_THREAD
REST_LANES = 4096  # threads a segment of a run followed to rest
REST_PER_THREAD = SEGMENT // REST_LANES  # (16 pellets a thread)
SEGMENT_WIDTH = NUM_SUMS + 2 * NUM_EXTREMES  # a segment's results: sums, minima, maxima
BATCH = 8  # partials a reduction thread loads together (their loads overlap; added in lane order all the same)
Batch = wp.types.vector(length=BATCH, dtype=wp.float64)


def lanes_for(costly: bool) -> int:
    """Threads a segment: REST_LANES for costly pellets (`spec.RunSpec.lanes`), else LANES."""
    return REST_LANES if costly else LANES


def threads_for(rows: int, lanes: int = LANES) -> int:
    """Threads (a whole number of groups of `lanes`) that cover `rows` pellets."""
    segments = -(-rows // SEGMENT)
    return max(segments, 1) * lanes


def partial_bytes_per_pellet(lanes: int = LANES) -> float:
    """Device bytes per pellet of the per-thread partials (float64 sums, minima and maxima)."""
    return SEGMENT_WIDTH * 8 * lanes / SEGMENT


@functools.cache
def reduce_kernel(lanes: int = LANES):
    """One thread per (segment, row): the segment's `lanes` per-thread partials added in lane order,
    loaded BATCH at a time (a statistics segment's LANES; `core.shots`: a piece's sub-pieces or threads). Segment k's
    partials start at column (k // pieces) * shot_cols + (k % pieces) * piece_cols (a statistics
    segment: pieces 1, shot_cols lanes)."""
    num_sums, num_extremes = NUM_SUMS, NUM_EXTREMES
    ROW_LANDED, ROW_RANGE, ROW_M2 = SUM["landed"], SUM["range"], SUM["range_m2"]
    ROW_STOPPED, ROW_REST, ROW_REST_M2 = SUM["end_stopped"], SUM["end_distance"], SUM["end_distance_m2"]
    inf64 = wp.float64(math.inf)

    FULL = lanes // BATCH * BATCH  # lanes in whole batches (the rest one by one)

    @wp.func
    def lane_sum(partial_sums: wp.array2d(dtype=wp.float64), row: wp.int32, base: wp.int32):
        """Row `row`'s partials of the segment's lanes added in lane order."""
        total = wp.float64(0.0)
        for first in range(0, FULL, BATCH):
            v = Batch()
            for k in range(BATCH):
                v[k] = partial_sums[row, base + first + k]
            for k in range(BATCH):
                total += v[k]
        for lane in range(FULL, lanes):
            total += partial_sums[row, base + lane]
        return total

    @wp.func
    def deviations(n: wp.float64, total: wp.float64, m2: wp.float64, mean: wp.float64):
        """A lane's squared deviations about `mean` from its count n, sum and own m2."""
        result = wp.float64(0.0)
        if n > wp.float64(0.0):
            delta = total / n - mean
            result = m2 + n * delta * delta
        return result

    @wp.func
    def merged_m2(partial_sums: wp.array2d(dtype=wp.float64), base: wp.int32, rows: wp.vec3i):
        """Squared deviations about the segment mean of rows (count, sum, m2): the lanes' own,
        plus n (mean_lane - mean)^2 (Chan et al.)."""
        count = lane_sum(partial_sums, rows[0], base)
        total = lane_sum(partial_sums, rows[1], base)
        m2 = wp.float64(0.0)
        if count > wp.float64(0.0):
            mean = total / count
            for first in range(0, FULL, BATCH):
                n, t, q = Batch(), Batch(), Batch()
                for k in range(BATCH):
                    n[k] = partial_sums[rows[0], base + first + k]
                    t[k] = partial_sums[rows[1], base + first + k]
                    q[k] = partial_sums[rows[2], base + first + k]
                for k in range(BATCH):
                    m2 += deviations(n[k], t[k], q[k], mean)
            for lane in range(FULL, lanes):
                m2 += deviations(
                    partial_sums[rows[0], base + lane],
                    partial_sums[rows[1], base + lane],
                    partial_sums[rows[2], base + lane],
                    mean,
                )
        return m2

    @wp.kernel(module="unique", enable_backward=False)
    def reduce_segments(
        partial_sums: wp.array2d(dtype=wp.float64),
        partial_min: wp.array2d(dtype=wp.float64),
        partial_max: wp.array2d(dtype=wp.float64),
        pieces: wp.int32,
        shot_cols: wp.int32,
        piece_cols: wp.int32,
        segments: wp.array2d(dtype=wp.float64),  # (segments, SEGMENT_WIDTH): sums, minima, maxima
    ):
        seg, row = wp.tid()
        shot = seg // pieces
        base = shot * shot_cols + (seg - shot * pieces) * piece_cols
        if row == ROW_M2:
            segments[seg, row] = merged_m2(partial_sums, base, wp.vec3i(ROW_LANDED, ROW_RANGE, ROW_M2))
        elif row == ROW_REST_M2:
            segments[seg, row] = merged_m2(partial_sums, base, wp.vec3i(ROW_STOPPED, ROW_REST, ROW_REST_M2))
        elif row < num_sums:
            segments[seg, row] = lane_sum(partial_sums, row, base)
        else:
            e = row - num_sums
            low = inf64
            high = -inf64
            for first in range(0, FULL, BATCH):
                lo, hi = Batch(), Batch()
                for k in range(BATCH):
                    lo[k] = partial_min[e, base + first + k]
                    hi[k] = partial_max[e, base + first + k]
                for k in range(BATCH):
                    low = wp.min(low, lo[k])
                    high = wp.max(high, hi[k])
            for lane in range(FULL, lanes):
                low = wp.min(low, partial_min[e, base + lane])
                high = wp.max(high, partial_max[e, base + lane])
            segments[seg, num_sums + e] = low
            segments[seg, num_sums + num_extremes + e] = high

    return reduce_segments


def launch_reduce(state, rows: int, device, lanes: int = LANES) -> int:
    """Reduce the per-thread partials (`lanes` a segment) of a chunk of `rows` pellets into
    `state.segments`; returns the number of segments."""
    segments = threads_for(rows, lanes) // lanes
    wp.launch(
        reduce_kernel(lanes),
        dim=(segments, NUM_SUMS + NUM_EXTREMES),
        inputs=[state.partial_sums, state.partial_min, state.partial_max, 1, lanes, 0],
        outputs=[state.segments],
        device=device,
    )
    return segments
