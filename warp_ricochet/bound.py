"""Runs that go on until an answer is bounded: `[hazard.bound]` (docs/hazard.md, "Running until the
answer is bounded").

A bounded run is planned as the run of its budget (`planned`): shot.count pellets a shot and
floor(max_pellets / shot.count) shots. Its chunk plan, its memory and disk checks before any work,
its file's datasets and its intervals over shots are that run's; it stops early. Pellets are keyed
by their global index (counter-based launch states), so shot k is always pellets [k count,
(k + 1) count), with or without pair collisions (whose chunks are whole shots), and adding shots
appends pellets.

The run is checked after whole shots, at pellet counts that depend on shot.shots, shot.count and the
budget alone (`BoundPlan.checks`): first after shot.shots shots, then each check a quarter more
shots (at least one), the last at the budget. After a check's chunk the danger distance of the
threshold at p and its 95% interval are made from the run's tally totals (`interval`, through
`tallies.quantiles.summarize`'s "hazard", so it follows the distances that gives); the run stops at
the first check where ci_high is finite and ci_high - ci_low < width, else at the budget, not
bounded. The interval's width falls as 1/sqrt(n), so a quarter more shots a check stops the run
within about 25% more pellets than the first check that meets the width would need, with about
log(budget / first) / log(1.25) checks (52 from one shot to 1e5); each check waits for the device
once.

Chunks never cross a check, and between two checks they start at multiples of the chunk size (whole
statistics segments) from the stretch's start, so every statistics segment holds the same pellets
for any chunk size and after --resume (`segments`): the same bits for any chunk size on one device.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from . import display
from .scene.stations import shot_pieces
from .tallies.quantiles import summarize

GROWTH = 4  # a check adds shots // GROWTH shots (at least one): a quarter more


@dataclass(frozen=True)
class BoundPlan:
    """The checks of a bounded run: `bound` (scene.schema.Bound), `count` pellets a shot, the first
    check after `first` shots (shot.shots), at most `budget` shots."""

    bound: object
    count: int
    first: int
    budget: int

    @classmethod
    def of(cls, scene) -> BoundPlan | None:
        """The plan of `scene`'s [hazard.bound] (None without one)."""
        bound = None if scene.hazard is None else scene.hazard.bound
        if bound is None:
            return None
        count, first = scene.shot.count, scene.bound_first or scene.shot.shots  # (the same for `planned(scene)`)
        return cls(bound, count, first, max(first, bound.max_pellets // count))

    def checks(self) -> list[int]:
        """The pellets complete at each check, increasing; the last is the budget's."""
        shots, out = self.first, []
        while True:
            out.append(shots * self.count)
            if shots >= self.budget:
                return out
            shots = min(self.budget, shots + max(1, shots // GROWTH))

    def segments(self, rows: int, pair_collisions: bool) -> int:
        """Statistics segments of the first `rows` pellets (a check or a chunk's end): each stretch
        between checks starts its own segments (of pellets; with pair collisions, of shots' slots)."""
        from .dense.schedule import segments_of_shots  # (imports Warp: `report` reads a bound without it)
        from .tallies.reduce import SEGMENT

        total, start = 0, 0
        for stop in self.checks():
            n = min(rows, stop) - start
            if n <= 0:
                break
            total += segments_of_shots(n // self.count, self.count) if pair_collisions else -(-n // SEGMENT)
            start = stop
        return total

    def chunk_end(self, rows: int, pair_collisions: bool, ends=None) -> bool:
        """Whether `rows` pellets can end a chunk of this run: at a check, or whole statistics
        segments (with pair collisions whole shots of them, `dense.schedule.shot_granule`) past one
        (`ends`: where chunks restart instead of the checks: a station run's pieces, `station_pieces`)."""
        from .dense.schedule import shot_granule
        from .tallies.reduce import SEGMENT

        checks = self.checks() if ends is None else list(ends)
        if rows in checks or not 0 < rows < checks[-1]:
            return rows in checks or rows == 0
        past = rows - max([0, *(n for n in checks if n < rows)])
        if pair_collisions:
            return past % self.count == 0 and (past // self.count) % shot_granule(self.count) == 0
        return past % SEGMENT == 0

    def result(self, tally, pellets: int, checks: int) -> BoundResult:
        """The outcome of the check after `pellets` pellets, from the run's tally totals."""
        b = self.bound
        distance, low, high = interval(tally, b.threshold, b.fraction)
        met = math.isfinite(high) and math.isfinite(low) and high - low < b.width
        return BoundResult(
            b.threshold, b.fraction, b.width, b.max_pellets, pellets, pellets // self.count, met, distance, low, high, checks
        )


def planned(scene):
    """The scene a bounded run is planned as (its budget's shots, remembering its own in
    `bound_first`); `scene` itself without a bound."""
    plan = BoundPlan.of(scene)
    if plan is None or plan.budget == scene.shot.shots:
        return scene
    return scene.replace(shot=dataclasses.replace(scene.shot, shots=plan.budget), bound_first=plan.first)


def station_pieces(scene) -> list[tuple[int, int, int]]:
    """[(first shot, end shot, station)] of a station run (`scene.stations.shot_pieces`): a bounded
    run's are cut at its checks (the same for `scene` and `planned(scene)`), others one a station."""
    plan = BoundPlan.of(scene)
    return shot_pieces(planned(scene), None if plan is None else [n // plan.count for n in plan.checks()])


def piece_ends(scene) -> list[int]:
    """The pellets complete at the end of each of a station run's pieces (`station_pieces`)."""
    return [end * scene.shot.count for _first, end, _k in station_pieces(scene)]


class _WithFractions:
    """A tally's totals seen with other danger-distance fractions (the rest as the tally's)."""

    def __init__(self, tally, fractions):
        self._tally = tally
        self.setup = dataclasses.replace(tally.setup, fractions=tuple(fractions))

    def __getattr__(self, name):
        return getattr(self._tally, name)


def interval(tally, threshold: str, p: float) -> tuple[float, float, float]:
    """(distance, ci_low, ci_high) in m of the danger distance of `threshold` at fraction `p` from a
    run's tally totals (`tallies.counts.TallyTotals`): `summarize(...)["hazard"]`'s values."""
    hazard = summarize(_WithFractions(tally, (p,)), 0, with_map=False)["hazard"]
    i = list(hazard["names"]).index(threshold)
    return tuple(float(hazard[name][i, 0]) for name in ("distance", "ci_low", "ci_high"))


@dataclass
class BoundResult:
    """A bounded run's outcome: the bound asked (threshold, fraction, width m, max_pellets), the
    pellets and shots run, whether the bound was `met`, the danger distance and its 95% interval
    (m) at the last check, and the checks made."""

    threshold: str
    fraction: float
    width: float
    max_pellets: int
    pellets: int
    shots: int
    met: bool
    distance: float
    ci_low: float
    ci_high: float
    checks: int

    @classmethod
    def of(cls, values: dict) -> BoundResult:
        """The outcome from /hazard/bound's values (`io.bound_out.read`)."""
        kw = {f.name: values[f.name] for f in dataclasses.fields(cls)}
        for name in ("max_pellets", "pellets", "shots", "checks"):
            kw[name] = int(kw[name])
        for name in ("fraction", "width", "distance", "ci_low", "ci_high"):
            kw[name] = float(kw[name])
        return cls(**{**kw, "met": bool(kw["met"])})

    @property
    def final_width(self) -> float:
        """ci_high - ci_low (m; inf while unbounded, NaN with no pellet above the threshold)."""
        return self.ci_high - self.ci_low

    def interval_text(self) -> str:
        """The danger distance and its interval, in words."""
        m = display.unit("m")  # (m, or yd with --units imperial: `display`)
        if math.isnan(self.distance):
            return f"no pellet above {self.threshold}: no danger distance, width nan {m}"
        low, high = (display.value(x, "m") for x in (self.ci_low, self.ci_high))
        return (
            f"danger distance of {self.threshold} at p = {self.fraction:g}: {display.text(self.distance, 'm', '.6g')}, "
            f"95% interval [{low:.6g}, {high:.6g}] {m}, width {display.text(self.final_width, 'm')}"
        )

    def summary(self) -> str:
        """One line: how many pellets it took, and the final interval (or that it is not bounded)."""
        what = self.interval_text()
        run = f"{self.pellets:,} pellets ({self.shots:,} shot{'s' * (self.shots != 1)}, {self.checks} check{'s' * (self.checks != 1)})"
        if self.met:
            return f"bounded after {run}: {what} < {display.text(self.width, 'm')}"
        return (
            f"NOT BOUNDED: the budget of {run} is spent (hazard.bound.max_pellets = {self.max_pellets:,}): {what}, "
            f"not below {display.text(self.width, 'm')}; raise max_pellets or the width"
        )
