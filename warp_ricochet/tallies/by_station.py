"""Per-station statistics and landing counts of a run with `[[stations]]` (docs/output.md, "Stations").

A station fires pieces, contiguous pellets [ends[p-1], ends[p]) (`bound.station_pieces`: one a
station, or a bounded run's cut at its checks). The chunk loop ends a stretch at every piece's end
(chunks never cross one) and starts statistics segments at every piece's first pellet, so a chunk
belongs to one station and every segment holds the same pellets for any chunk size and on resume.
A station's statistics fold its segments in pellet order (`sums.combine`), as the run's fold all of
them: both are chunk-invariant. Its landing counts are the sums over its pieces of the run's
cumulative counts (int64) at the piece's end less those at its start: exact. With
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
    """Statistics partials of each station and its landing counts over the run's pieces
    (`pieces`: [(first shot, end shot, station)], `bound.station_pieces`; `count` pellets a shot).
    `counts`: station -> the nonzero elements (index, value) of its `TallyTotals.flat()`, the sum
    over its pieces of the run's counts at the piece's end less those at the previous piece's end:
    a map of 1e6 cells x 31 thresholds is 248 MB dense, and each station's counts are held sparse,
    the run's counts at the last piece end alone dense."""

    def __init__(self, pieces, stations: int, count: int = 1, pair_collisions: bool = False):
        self.ends = [end * count for _first, end, _k in pieces]
        self.owner = [k for _first, _end, k in pieces]
        self.count, self.pair_collisions = count, pair_collisions
        self.totals = [empty_totals() for _ in range(stations)]
        self.counts: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.kept: set[int] = set()  # the pieces whose counts are in
        self.previous = None  # the run's counts at the last piece's end (dense)

    def station_of(self, start: int) -> int:
        """The station firing pellet `start`."""
        return self.owner[bisect.bisect_right(self.ends, start)]

    def resume(self, rows: int, segment_results, snapshots=None, width: int = 0):
        """Split a resumed run's segment results (each piece starts its own segments) and take
        the counts of its complete pieces from the run's counts at their ends (`snapshots`: piece
        -> (index, value) of the nonzero elements, `io.station_out`; `width`: the length of
        `TallyTotals.flat()`)."""
        results, begin, used = np.asarray(segment_results), 0, 0
        for p, end in enumerate(self.ends):
            n = min(rows, end) - begin
            if n <= 0:
                break
            segments = stretch_segments(n, self.count, self.pair_collisions)
            k = self.owner[p]
            self.totals[k] = combine(self.totals[k], results[used : used + segments])
            used, begin = used + segments, end
        for p in sorted(snapshots or {}):
            flat = np.zeros(width, np.int64)
            index, value = snapshots[p]
            flat[index] = value
            self._keep(p, flat)

    def _keep(self, p: int, flat):
        """Piece p's counts, the run's at its end (`flat`, dense) less those at the previous
        piece's end, added to its station's."""
        diff = flat.copy() if self.previous is None else flat - self.previous
        k = self.owner[p]
        if k in self.counts:
            index, value = self.counts[k]
            diff[index] += value
        nonzero = np.flatnonzero(diff)
        self.counts[k] = (nonzero, diff[nonzero])
        self.previous = flat
        self.kept.add(p)

    def add(self, start: int, segment_results):
        """A chunk starting at pellet `start`: its segments folded into its station's partials."""
        k = self.station_of(start)
        self.totals[k] = combine(self.totals[k], segment_results)

    def snapshot(self, done: int, tally) -> None:
        """At pellet `done`: when it ends a piece, its counts from the run's so far (None: no tally)."""
        if tally is not None and done in self.ends and self.ends.index(done) not in self.kept:  # (resumed there: kept)
            self._keep(self.ends.index(done), tally.flat())

    def results(self, tally, done: int, **finalize_kw) -> list[tuple[int, dict, object]]:
        """[(station, statistics, landing counts or None)] of each station that fired a piece
        complete by pellet `done` (all of them at a run's end and at a bounded run's checks)."""
        pellets, begin = [0] * len(self.totals), 0
        for end, k in zip(self.ends, self.owner):
            if end > done:
                break
            pellets[k] += end - begin
            begin = end
        out = []
        for k, n in enumerate(pellets):
            if n == 0:
                continue
            counts = None
            if tally is not None:
                counts = type(tally)(tally.setup)
                counts.scatter(*self.counts[k])
            out.append((k, finalize(self.totals[k], pellets=n, **finalize_kw), counts))
        return out


def segments_of(ends, rows: int, count: int = 1, pair_collisions: bool = False) -> int:
    """Statistics segments of the first `rows` pellets of a station run (each piece its own: `ends`,
    `bound.piece_ends`; `count` pellets a shot, `stretch_segments`)."""
    total, begin = 0, 0
    for end in ends:
        n = min(rows, end) - begin
        if n <= 0:
            break
        total += stretch_segments(n, count, pair_collisions)
        begin = end
    return total
