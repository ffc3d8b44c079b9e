"""Quantiles, tail fractions and danger distances from the landing histograms (`tallies.bins`).

Quantile at level q of n counted values: the sample quantile X_(k), k = ceil(q n) (NumPy's
"inverted_cdf"), located in its bin: the reported value is the bin's upper edge and `lower` its lower
edge, so X_(k) lies in [lower, value] and value / lower - 1 <= 2^-10 (docs/hazard.md).

Danger distance for a threshold and a fraction p: the distance from the shooter that contains all but
p of the landings above the threshold, i.e. their quantile at level 1 - p, with a distribution-free
95% confidence interval from the order statistics: the number E of landings beyond the true quantile
is binomial(n, p), so [X_(n+1-m_l), X_(n+1-m_u)] with m_u = the 2.5% point of E and m_l = its 97.5%
point + 1 covers it with probability >= 95% (e.g. Hahn & Meeker, Statistical Intervals, 1991,
sec. 5.2), widened to the bins' edges. When (1 - p)^n > 2.5% the upper end is unbounded: the run is
too small for p, and `needed` says how many landings above the threshold it would take.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .bins import ROW_DISTANCE, ROW_RANGE, ROW_SPEED, edges

LEVELS = (0.5, 0.75, 0.9, 0.99, 0.999, 0.999999)
QUANTITIES = {
    "range": ("m", "range (eq. 42): last ricochet point to landing point"),
    "distance": ("m", "horizontal distance from the shooter to the landing centre"),
    "speed": ("m/s", "speed |v| at landing"),
    "energy": ("J", "translational kinetic energy m |v|^2 / 2 at landing"),
}
# following pellets to rest (physics.until = "rest"): from the rest histogram (`counts.TallyTotals.rest`)
REST_QUANTITIES = {
    "rest_distance": ("m", "horizontal distance from the shooter to where the pellet ended, pellets at rest or embedded"),
}
CONFIDENCE = 0.95
Z_975 = 1.959963984540054  # the standard normal's 97.5% point
EXACT_VARIANCE = 1e4  # above this n p (1 - p), binomial points by the normal approximation


def rank(q: float, n: int) -> int:
    """k = ceil(q n), at least 1 (exact: q as its decimal)."""
    return max(1, math.ceil(Fraction(repr(float(q))) * n))


def bins_of_ranks(counts, ranks) -> np.ndarray:
    """The bin holding the k-th smallest value (1-based) for each k of `ranks` (1 <= k <= the
    total; the cumulative counts are taken over the span of nonzero bins only)."""
    counts = np.asarray(counts, dtype=np.int64)
    nonzero = np.flatnonzero(counts)
    if not nonzero.size:
        return np.full(len(ranks), counts.size)
    first = nonzero[0]
    cumulative = np.cumsum(counts[first : nonzero[-1] + 1])
    return first + np.searchsorted(cumulative, np.asarray(ranks, dtype=np.int64), side="left")


def quantiles(counts, levels=LEVELS) -> tuple[np.ndarray, np.ndarray]:
    """(upper, lower) edges of the bins holding the sample quantiles at `levels` (NaN when empty)."""
    n = int(np.sum(counts))
    if n == 0:
        return np.full(len(levels), math.nan), np.full(len(levels), math.nan)
    e = edges()
    b = bins_of_ranks(counts, [rank(q, n) for q in levels])
    return e[b + 1], e[b]


def tail(counts, distances) -> tuple[np.ndarray, np.ndarray]:
    """(edges used, counts at or beyond them): each distance moved up to the nearest bin edge e
    (e / d - 1 <= 2^-10), and the number of values >= e, exactly."""
    e = edges()
    j = np.searchsorted(e, np.asarray(distances, dtype=np.float64), side="left")
    beyond = np.concatenate([np.cumsum(np.asarray(counts, dtype=np.int64)[::-1])[::-1], [0]])
    return e[j], beyond[j]


def landing_quantiles(hist, half_mass: float, levels=LEVELS, hazard_levels: int | None = None) -> dict:
    """{quantity: (value, lower)} of QUANTITIES from the histogram rows (distance: its
    `hazard_levels` rows, all after ROW_DISTANCE when None)."""
    hist = np.asarray(hist)
    speed = quantiles(hist[ROW_SPEED], levels)
    return {
        "range": quantiles(hist[ROW_RANGE], levels),
        "distance": quantiles(distance_rows(hist, hazard_levels).sum(axis=0), levels),
        "speed": speed,
        "energy": (half_mass * speed[0] ** 2, half_mass * speed[1] ** 2),
    }


def binomial_point(n: int, p: float, alpha: float) -> int:
    """The smallest m with P(Binomial(n, p) <= m) >= alpha (exact summation; the normal
    approximation with continuity correction when n p (1 - p) > EXACT_VARIANCE)."""
    if n == 0:
        return 0
    variance = n * p * (1.0 - p)
    if variance > EXACT_VARIANCE:
        z = Z_975 if alpha > 0.5 else -Z_975
        return min(n, max(0, math.ceil(n * p + z * math.sqrt(variance) - 0.5)))
    top = min(n, int(n * p + 40.0 * math.sqrt(variance) + 50))
    m = np.arange(1, top + 1, dtype=np.float64)
    # log pmf(m) = log pmf(m - 1) + log((n - m + 1) / m) + log(p / (1 - p)), from pmf(0) = (1 - p)^n
    steps = np.log((n - m + 1.0) / m) + (math.log(p) - math.log1p(-p))
    log_pmf = n * math.log1p(-p) + np.concatenate([[0.0], np.cumsum(steps)])
    cdf = np.cumsum(np.exp(log_pmf))
    return int(min(np.searchsorted(cdf, alpha * (1.0 - 1e-12), side="left"), n))


def needed_landings(p: float, confidence: float = CONFIDENCE) -> int:
    """The fewest landings n whose 1 - p quantile has a bounded upper confidence limit:
    (1 - p)^n <= (1 - confidence) / 2."""
    return math.ceil(math.log((1.0 - confidence) / 2.0) / math.log1p(-p))


def danger_distance(counts, p: float) -> tuple[float, float, float, int]:
    """(distance, ci_low, ci_high, landings needed) of the 1 - p quantile of the distances counted
    in `counts` (NaN when empty; ci_high inf when the run is too small for p)."""
    n = int(np.sum(counts))
    needed = needed_landings(p)
    if n == 0:
        return math.nan, math.nan, math.nan, needed
    e = edges()
    m_upper = binomial_point(n, p, (1.0 - CONFIDENCE) / 2.0)  # landings beyond the upper limit
    m_lower = binomial_point(n, p, 1.0 - (1.0 - CONFIDENCE) / 2.0) + 1
    value_bin, low_bin, high_bin = bins_of_ranks(counts, [rank(1.0 - p, n), min(n + 1 - m_lower, n), max(n + 1 - m_upper, 1)])
    low = e[low_bin] if m_lower <= n else 0.0
    high = e[high_bin + 1] if m_upper >= 1 else math.inf
    return float(e[value_bin + 1]), float(low), float(high), needed


def distance_rows(hist, hazard_levels: int | None = None) -> np.ndarray:
    """The landing distance rows by hazard level (`hazard_levels` of them; None: all after
    ROW_DISTANCE), without the reach rows that follow them (`tallies.path`)."""
    end = None if hazard_levels is None else ROW_DISTANCE + hazard_levels
    return np.asarray(hist)[ROW_DISTANCE:end]


def hazard_distance_counts(hist, order) -> np.ndarray:
    """(thresholds, bins): the distance counts of the landings above each threshold (scene order),
    from the rows by level (a landing at level L exceeds the L lowest thresholds, `order`)."""
    by_level = distance_rows(hist, len(order) + 1)
    out = np.zeros((len(order), by_level.shape[1]), dtype=np.int64)
    above, span = levels_at_or_above(by_level)
    for position, index in enumerate(order):
        out[index, span] = above[position + 1]
    return out


def levels_at_or_above(by_level) -> tuple[np.ndarray, slice]:
    """(above, span): above[L] = the counts at level >= L (rows: levels) over `span`, the columns
    from the first to the last with a count (most are empty)."""
    used = np.flatnonzero(by_level.any(axis=0))
    span = slice(int(used[0]), int(used[-1]) + 1) if used.size else slice(0, 0)
    return np.cumsum(by_level[::-1, span], axis=0)[::-1], span


def summarize(tally, landed: int, with_map: bool = True) -> dict:
    """The results of a run's landing counts (`counts.TallyTotals`), as plain arrays: quantiles
    {name: (value, lower)} (following pellets to rest, "rest_distance" too, over the `stopped`
    pellets), tail (distance used, count, fraction), and with thresholds the danger
    distances (rows: thresholds in scene order, columns: fractions) and, `with_map`, the map's
    layers (cells x thresholds: the costly part for a large map)."""
    setup, hist = tally.setup, tally.hist
    used, beyond = tail(distance_rows(hist, setup.levels).sum(axis=0), setup.tail_distances)
    out = {
        "levels": np.asarray(LEVELS),
        "landed": landed,
        "quantiles": landing_quantiles(hist, setup.half_mass, hazard_levels=setup.levels),
        "tail": {"distance": used, "count": beyond, "fraction": beyond / landed if landed else np.full(len(used), np.nan)},
    }
    if setup.rest:
        out["quantiles"]["rest_distance"] = quantiles(tally.rest)
        out["stopped"] = int(tally.rest.sum())
    if setup.names:
        landing = _danger(setup, hazard_distance_counts(hist, setup.order))
        out["hazard"] = landing
        if setup.path:  # the danger distances from the reach along the path (`tallies.path`)
            out["landing_hazard"] = landing
            out["hazard"] = _danger(setup, np.asarray(hist)[setup.reach_row : setup.reach_row + len(setup.names)])
            out["points"] = {"counts": tally.points}
    if setup.has_map and with_map:
        shape, cells, counts = (setup.map_nv, setup.map_nu), setup.cells, tally.map_counts
        out["map"] = {
            "count": counts[:, :cells].sum(axis=0).reshape(shape),
            "outside": int(counts[:, cells].sum()),
            "elsewhere": int(counts[:, cells + 1].sum()),
            "energy": (tally.map_energy[:cells] * setup.quantum).reshape(shape),
            "quantum": setup.quantum,
            "above": threshold_layers(setup, counts),  # landings above each threshold per cell
        }
        if setup.path:
            out["map"].update(_exposure(setup, tally.exposure))
    return out


def threshold_layers(setup, by_level) -> np.ndarray:
    """(thresholds in scene order, nv, nu): per cell the counts above each threshold, from the
    counts by level (level, column; the first `cells` columns are the grid's)."""
    above, span = levels_at_or_above(by_level[:, : setup.cells])  # counts at level >= L per cell
    layers = np.zeros((len(setup.names), setup.cells), dtype=np.int64)
    for position, index in enumerate(setup.order):
        layers[index, span] = above[position + 1]
    return layers.reshape((len(setup.names), setup.map_nv, setup.map_nu))


def _danger(setup, by_threshold) -> dict:
    """The danger distances (thresholds x fractions) of distance counts by threshold (scene order)."""
    shape = (len(setup.names), len(setup.fractions))
    danger = {
        name: np.zeros(shape, dtype=np.int64 if name == "needed_landings" else np.float64)
        for name in ("distance", "ci_low", "ci_high", "needed_landings")
    }
    for i in range(shape[0]):
        for j, p in enumerate(setup.fractions):
            for name, x in zip(danger, danger_distance(by_threshold[i], p)):
                danger[name][i, j] = x
    return {
        "names": setup.names,
        "kinds": setup.kinds,
        "values": setup.values,
        "fractions": np.asarray(setup.fractions),
        "landings": by_threshold.sum(axis=1),
        **danger,
    }


def _exposure(setup, by_level) -> dict:
    """The passes map (all within body height) and per threshold (scene order) the passes above it,
    from the passes by level at entry (`tallies.path`), and the passes off the grid."""
    shape, cells = (setup.map_nv, setup.map_nu), setup.cells
    off = by_level[:, cells]
    off_above = np.cumsum(off[::-1])[::-1]
    outside = np.zeros(len(setup.names) + 1, dtype=np.int64)
    outside[0] = off.sum()
    for position, index in enumerate(setup.order):
        outside[index + 1] = off_above[position + 1]
    return {
        "passes": by_level[:, :cells].sum(axis=0).reshape(shape),
        "exposure": threshold_layers(setup, by_level),
        "exposure_outside": outside,
    }
