"""Per-station statistics and landing counts of a run with `[[stations]]` (docs/output.md, "Stations").

Station k fires the contiguous pellets [ends[k-1], ends[k]) (`scene.stations.pellet_ends`). The
chunk loop ends a stretch at every station end (chunks never cross one) and starts each station's
statistics segments at its first pellet, so a chunk belongs to one station and every segment holds
the same pellets for any chunk size and on resume. A station's statistics fold its segments in
pellet order (`sums.combine`), as the run's fold all of them: both are chunk-invariant. Its landing
counts are the run's cumulative counts (int64) at its end less those at its start: exact. With
pair collisions a chunk's segments are of its shots' slots (`dense.schedule`), so a station's
stretch of n pellets holds `segments_of_shots(n / count, count)` of them (`stretch_segments`).
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from ..dense.schedule import segments_of_shots
from .reduce import SEGMENT
from .sums import combine, empty_totals, finalize


def stretch_segments(pellets: int, count: int, pair_collisions: bool) -> int:
    """Statistics segments of a stretch of `pellets` pellets that starts a chunk: of pellets, or with
    pair collisions of its whole shots' slots (`dense.schedule.segments_of_shots`)."""
    return segments_of_shots(pellets // count, count) if pair_collisions else math.ceil(pellets / SEGMENT)


class StationFold:
    """Statistics partials of each station and its landing counts (`counts`: station -> the nonzero
    elements (index, value) of its `TallyTotals.flat()`, the run's counts at its end less those at
    the previous station's end: a map of 1e6 cells x 31 thresholds is 248 MB dense, and each
    station's counts are held sparse, the run's last cumulative counts alone dense)."""

    def __init__(self, ends, count: int = 1, pair_collisions: bool = False):
        self.ends = list(ends)
        self.count, self.pair_collisions = count, pair_collisions
        self.totals = [empty_totals() for _ in self.ends]
        self.counts: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.previous = None  # the run's counts at the last station's end (dense)

    def station_of(self, start: int) -> int:
        """The station firing pellet `start`."""
        return bisect.bisect_right(self.ends, start)

    def resume(self, rows: int, segment_results, snapshots=None, width: int = 0):
        """Split a resumed run's segment results (each station's stretch starts its own segments)
        and take the counts of its complete stations from the run's counts at their ends
        (`snapshots`: station -> (index, value) of the nonzero elements, `io.station_out`; `width`:
        the length of `TallyTotals.flat()`)."""
        results, begin, used = np.asarray(segment_results), 0, 0
        for k, end in enumerate(self.ends):
            n = min(rows, end) - begin
            if n <= 0:
                break
            segments = stretch_segments(n, self.count, self.pair_collisions)
            self.totals[k] = combine(self.totals[k], results[used : used + segments])
            used, begin = used + segments, end
        for k in sorted(snapshots or {}):
            flat = np.zeros(width, np.int64)
            index, value = snapshots[k]
            flat[index] = value
            self._keep(k, flat)

    def _keep(self, k: int, flat):
        """Station k's counts: the run's at its end (`flat`, dense) less those at the previous end."""
        diff = flat if self.previous is None else flat - self.previous
        nonzero = np.flatnonzero(diff)
        self.counts[k] = (nonzero, diff[nonzero])
        self.previous = flat

    def add(self, start: int, segment_results):
        """A chunk starting at pellet `start`: its segments folded into its station's partials."""
        k = self.station_of(start)
        self.totals[k] = combine(self.totals[k], segment_results)

    def snapshot(self, done: int, tally) -> None:
        """At pellet `done`: when it ends a station, its counts from the run's so far (None: no tally)."""
        if tally is not None and done in self.ends and self.ends.index(done) not in self.counts:  # (resumed there: kept)
            self._keep(self.ends.index(done), tally.flat())

    def results(self, tally, done: int, **finalize_kw) -> list[tuple[dict, object]]:
        """[(statistics, landing counts or None)] of each station complete by pellet `done`."""
        out, begin = [], 0
        for k, end in enumerate(self.ends):
            if end > done:
                break
            stats = finalize(self.totals[k], pellets=end - begin, **finalize_kw)
            counts = None
            if tally is not None:
                counts = type(tally)(tally.setup)
                counts.scatter(*self.counts[k])
            out.append((stats, counts))
            begin = end
        return out


def segments_of(ends, rows: int, count: int = 1, pair_collisions: bool = False) -> int:
    """Statistics segments of the first `rows` pellets of a station run (each station its own;
    `count` pellets a shot, `stretch_segments`)."""
    total, begin = 0, 0
    for end in ends:
        n = min(rows, end) - begin
        if n <= 0:
            break
        total += stretch_segments(n, count, pair_collisions)
        begin = end
    return total
