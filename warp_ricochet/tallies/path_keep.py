"""A pellet's hazard watch (`tallies.path`'s `Track`) kept in arrays between kernels: the dense
phase of a collision run keeps each pellet's watch from step to step and hands it to the core
kernel with the release (docs/hazard.md section 11). A pellet row holds `reach` (m, one a
threshold) and `ints` (the map cell of the pass under way, or ESCAPED once its watch has ended,
the pending run's row, first and last cell and level, then 1 + its level at each named place):
every member of the Track, as it is (columns of members a Track lacks are left as they are)."""

import functools

import warp as wp

from ..physics.types import types_for
from .path_cells import make_path_cells

KEPT_INTS = 5  # cell, run_row, run_lo, run_hi, run_level; then one a named place


def kept_shapes(rows: int, thresholds: int, points: int) -> tuple[tuple[int, int], tuple[int, int]]:
    """The shapes of `reach` and `ints` for `rows` pellets (none without thresholds: nothing watched)."""
    rows = rows if thresholds > 0 else 0
    return (rows, max(thresholds, 1)), (rows, KEPT_INTS + max(points, 1))


@functools.cache
def make_path_keep(precision: str, thresholds: int, points: int, with_map: bool):
    """`load(reach, ints, row)` -> Track and `store(track, reach, ints, row)`."""
    scalar = types_for(precision).scalar
    Track = make_path_cells(precision, thresholds, points, with_map).Track
    K, P, ON = max(thresholds, 1), max(points, 1), thresholds > 0

    @wp.func
    def load(reach: wp.array2d(dtype=scalar), ints: wp.array2d(dtype=wp.int32), row: wp.int32):
        track = Track()
        if wp.static(ON):
            for i in range(wp.static(K)):
                track.reach[i] = reach[row, i]
        track.cell = ints[row, 0]
        if wp.static(ON and with_map):
            track.run_row = ints[row, 1]
            track.run_lo = ints[row, 2]
            track.run_hi = ints[row, 3]
            track.run_level = ints[row, 4]
        if wp.static(ON and points > 0):
            for p in range(wp.static(P)):
                track.places[p] = ints[row, wp.static(KEPT_INTS) + p]
        return track

    @wp.func
    def store(track: Track, reach: wp.array2d(dtype=scalar), ints: wp.array2d(dtype=wp.int32), row: wp.int32):
        if wp.static(ON):
            for i in range(wp.static(K)):
                reach[row, i] = track.reach[i]
        ints[row, 0] = track.cell
        if wp.static(ON and with_map):
            ints[row, 1] = track.run_row
            ints[row, 2] = track.run_lo
            ints[row, 3] = track.run_hi
            ints[row, 4] = track.run_level
        if wp.static(ON and points > 0):
            for p in range(wp.static(P)):
                ints[row, wp.static(KEPT_INTS) + p] = track.places[p]

    return load, store
