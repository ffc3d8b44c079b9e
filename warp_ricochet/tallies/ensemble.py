"""Ensembles of shots: per-shot statistics and 95% confidence intervals over shots.

A run of S >= 2 shots (`shot.shots`) reports each statistic as the ensemble value (the run's own
statistic, over all its pellets: `sums.finalize`) with a 95% interval over shots, made from that
statistic computed for each shot alone (one value per shot, kept in the file). The shots of a run
are independent and alike (the same scene, counter-based launch states), so the per-shot values
x_1..x_S are i.i.d. and the interval is Student's t over them (S - 1 degrees of freedom):

    mean(x) -+ t_{0.975, S-1} s(x) / sqrt(S)

read, by the kind of statistic (STAT_KIND):
- "mean" (means, ratios, spreads, fractions): the interval of the expected per-shot value. With
  shots of equal size this is the ensemble value's expectation up to O(1/n) terms of the ratio
  estimator (n pellets a shot);
- "total" (counts and sums over pellets: hits, landed, pair collisions, energy lost): S times the
  interval of the per-shot mean, the interval of the expected total of S shots;
- "extreme" (L+, L-, dense-phase maxima): the interval of the expected extreme of *one shot* (the
  mean over shots of each shot's maximum or minimum). The ensemble value, the extreme of all
  S shots, lies beyond it by design: no interval of a sample extreme is given (the bootstrap's
  is inconsistent for a maximum).
Shots where a statistic is undefined (NaN, e.g. no slip landing in a shot) are left out of its
interval; with fewer than two values it is NaN. Per-shot values are reduced in shot order, so the
intervals are bitwise the same for any chunk size and after --resume.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .collisions import SHOT_TOTALS, collision_statistics
from .sums import NUM_EXTREMES, NUM_SUMS, SPREADS, STAT_UNITS, SUM, finalize_rows

LEVEL = 0.95
PIECE = 256  # pellets of one shot a stored piece holds (= reduce.PER_THREAD, not imported: reduce imports Warp; `core.shots`)
MAX_ENSEMBLE_SHOTS = 100_000  # per-shot values are kept on the host and in the file up to this many shots
TOTALS = (
    "pellets",
    "hits",
    "missed",
    "stick",
    "slip",
    "landed",
    "escaped",
    "pair_collisions",
    "pair_energy_lost",
    "flights_unfinished",
    "rest_at_rest",
    "rest_embedded",
    "rest_escaped",
    "rest_not_finished",
)
EXTREMES = (
    "range_max",
    "range_min",
    "range_stick_max",
    "range_stick_min",
    "range_slip_max",
    "range_slip_min",
    "dense_steps_max",
    "dense_time_max",
    "skin_overrun_max",
    "flight_scale_max",
    "rest_distance_max",
    "rest_distance_min",
)
STAT_KIND = {name: "total" if name in TOTALS else "extreme" if name in EXTREMES else "mean" for name in STAT_UNITS}
CI_METHOD = {
    "mean": "Student t 95% interval of the mean over shots of the per-shot value",
    "total": "shots x the Student t 95% interval of the per-shot mean (expected total of the run's shots)",
    "extreme": "Student t 95% interval of the mean over shots of the per-shot extreme (one shot's expected "
    "extreme; the value is the extreme over all shots)",
}


def pieces_per_shot(count: int) -> int:
    """Pieces (rows of per-shot partials) of a shot of `count` pellets."""
    return -(-count // PIECE)


def has_ensemble(scene) -> bool:
    """Whether a run of `scene` reports intervals over shots: 2 to MAX_ENSEMBLE_SHOTS shots."""
    return 2 <= scene.shot.shots <= MAX_ENSEMBLE_SHOTS


@dataclass
class Ensemble:
    """Per-shot values (name -> (S,) float64, shot order) and the 95% interval of each statistic."""

    shots: int
    per_shot: dict = field(default_factory=dict)
    low: dict = field(default_factory=dict)
    high: dict = field(default_factory=dict)


def t_interval(values, level: float = LEVEL) -> tuple[float, float]:
    """Student t interval of the mean of the finite `values` (NaN, NaN with fewer than two)."""
    from scipy import stats

    x = np.asarray(values, np.float64)
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return math.nan, math.nan
    mean = math.fsum(x) / len(x)
    half = float(stats.t.ppf(0.5 + level / 2, len(x) - 1)) * math.sqrt(math.fsum((x - mean) ** 2) / (len(x) - 1) / len(x))
    return mean - half, mean + half


def per_shot_statistics(
    piece_rows, pieces: int, *, count: int, mass: float, inertia: float, air: bool = False, rest: bool = False, shot_totals=None
) -> dict:
    """name -> (S,) values of each shot alone, from its pieces' partial rows (`core.shots`; `pieces`
    rows a shot, in order: sums added left to right, spreads merged as `sums.merged_m2`) and, with
    pair collisions, its row of per-shot totals (`collisions.collision_statistics` of that row)."""
    shots = len(piece_rows) // pieces
    rows = np.asarray(piece_rows, np.float64)[: shots * pieces].reshape(shots, pieces, -1)
    sums = rows[:, 0, :NUM_SUMS].copy()
    for k in range(1, pieces):
        sums += rows[:, k, :NUM_SUMS]
    mins = rows[:, :, NUM_SUMS : NUM_SUMS + NUM_EXTREMES].min(axis=1)
    maxs = rows[:, :, NUM_SUMS + NUM_EXTREMES :].max(axis=1)
    spread, rest_spread = (_merged_spread(rows, keys) for keys in SPREADS)
    out = finalize_rows(
        sums, mins, maxs, spread, pellets=count, mass=mass, inertia=inertia, air=air, rest_m2=rest_spread if rest else None
    )
    if shot_totals is not None:
        out.update(_collision_rows(np.asarray(shot_totals, np.float64)[:shots], count))
    return out


def _merged_spread(rows, keys) -> np.ndarray:
    """(S,) squared deviations of each shot from its pieces' (count, sum, m2) rows `keys` (`sums.SPREADS`)."""
    n, total, m2 = (rows[:, :, SUM[key]] for key in keys)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = (total.sum(axis=1) / n.sum(axis=1))[:, None]
        return np.where(n > 0, m2, 0.0).sum(axis=1) + np.where(n > 0, n * (total / n - mean) ** 2, 0.0).sum(axis=1)


def _collision_rows(table, count: int) -> dict:
    """`collisions.collision_statistics` of each row of per-shot totals alone (a sum of one value is
    itself, the mean over one shot its value)."""
    col = {name: table[:, i] for i, name in enumerate(SHOT_TOTALS)}
    out = {
        "collided_fraction": col["collided"] / count,
        "pair_collisions": col["pair_collisions"] / 2.0,
        "pair_energy_lost": col["pair_energy_lost"],
        "pair_energy_lost_mean": col["pair_energy_lost"] / count,
        "dense_steps_max": col["dense_steps"],
        "dense_time_max": col["dense_end_time"],
        "dense_steps_mean": col["dense_steps"],
        "dense_time_mean": col["dense_end_time"],
        "skin_overrun_max": col["skin_overrun"],
    }
    assert not len(table) or set(out) == set(collision_statistics(table[:1], count))
    return out


def ensemble_of(per_shot: dict, shots: int) -> Ensemble:
    """The intervals of every statistic from its per-shot values (STAT_KIND decides the reading)."""
    out = Ensemble(shots=shots, per_shot=per_shot)
    for name, values in per_shot.items():
        low, high = t_interval(values)
        if STAT_KIND.get(name) == "total":
            low, high = low * shots, high * shots
        out.low[name], out.high[name] = low, high
    return out
