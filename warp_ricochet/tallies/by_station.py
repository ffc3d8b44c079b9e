"""Per-station statistics and landing counts of a run with `[[stations]]` (docs/output.md, "Stations").

Station k fires the contiguous pellets [ends[k-1], ends[k]) (`scene.stations.pellet_ends`). The
chunk loop ends a stretch at every station end (chunks never cross one) and starts each station's
statistics segments at its first pellet, so a chunk belongs to one station and every segment holds
the same pellets for any chunk size and on resume. A station's statistics fold its segments in
pellet order (`sums.combine`), as the run's fold all of them: both are chunk-invariant. Its landing
counts are the run's cumulative counts (int64) at its end less those at its start: exact.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from .reduce import SEGMENT
from .sums import combine, empty_totals, finalize


class StationFold:
    """Statistics partials of each station and the run's cumulative landing counts at each station's
    end (`snapshots`: station -> `TallyTotals.flat()`)."""

    def __init__(self, ends):
        self.ends = list(ends)
        self.totals = [empty_totals() for _ in self.ends]
        self.snapshots: dict[int, np.ndarray] = {}

    def station_of(self, start: int) -> int:
        """The station firing pellet `start`."""
        return bisect.bisect_right(self.ends, start)

    def resume(self, rows: int, segment_results, snapshots=None):
        """Split a resumed run's segment results (each station's stretch starts its own segments)
        and keep the snapshots of its complete stations."""
        results, begin, used = np.asarray(segment_results), 0, 0
        for k, end in enumerate(self.ends):
            n = min(rows, end) - begin
            if n <= 0:
                break
            segments = -(-n // SEGMENT)
            self.totals[k] = combine(self.totals[k], results[used : used + segments])
            used, begin = used + segments, end
        self.snapshots.update(snapshots or {})

    def add(self, start: int, segment_results):
        """A chunk starting at pellet `start`: its segments folded into its station's partials."""
        k = self.station_of(start)
        self.totals[k] = combine(self.totals[k], segment_results)

    def snapshot(self, done: int, tally) -> None:
        """At pellet `done`: when it ends a station, the run's counts so far (None: no tally)."""
        if tally is not None and done in self.ends:
            self.snapshots[self.ends.index(done)] = tally.flat().copy()

    def results(self, tally, done: int, **finalize_kw) -> list[tuple[dict, object]]:
        """[(statistics, landing counts or None)] of each station complete by pellet `done`."""
        out, begin = [], 0
        for k, end in enumerate(self.ends):
            if end > done:
                break
            stats = finalize(self.totals[k], pellets=end - begin, **finalize_kw)
            counts = None
            if tally is not None:
                before = self.snapshots[k - 1] if k else 0
                counts = type(tally)(tally.setup).load(self.snapshots[k] - before)
            out.append((stats, counts))
            begin = end
        return out


def segments_of(ends, rows: int) -> int:
    """Statistics segments of the first `rows` pellets of a station run (each station its own)."""
    total, begin = 0, 0
    for end in ends:
        n = min(rows, end) - begin
        if n <= 0:
            break
        total += math.ceil(n / SEGMENT)
        begin = end
    return total
