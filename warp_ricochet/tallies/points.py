"""The probability of a hit at named places (`[[hazard.points]]`, docs/hazard.md section 9), from
the point passages a run counts: `counts[L, p]` pellets whose highest hazard level while within
body height of place p's cylinder was L (`TallyTotals.points`, levels = thresholds + 1).

Per place p and threshold i (scene order), with n pellets simulated and N pellets per shot:

- m: pellets that passed there above threshold i (level > the rank of i in `setup.order`);
- q = m / n, the chance that one pellet does, with its 95% Clopper-Pearson interval (Clopper &
  Pearson, Biometrika 26(4):404, 1934): [B(a/2; m, n - m + 1), B(1 - a/2; m + 1, n - m)], B the
  beta quantile, a = 0.05 (0 below m = 0, 1 above m = n); it assumes m binomial, pellets independent;
- E = N q = m / shots, the pellets per shot passing there above it: an unbiased estimate of their
  expected number, N times a pellet's chance by linearity of expectation whether the pellets of a
  shot are independent or not (no assumption beyond q's); its interval N [q_low, q_high];
- P = 1 - (1 - q)^N, the probability that a shot sends at least one: exact for pellets independent
  of one another (runs without pellet-pellet collisions), an estimate with them; always P <= E
  (P(X >= 1) <= E[X]); its interval the same monotone function of q's ends.
"""

from __future__ import annotations

import numpy as np

CONFIDENCE = 0.95
# the statistics a run file keeps (/hazard/points, io.tally_out), each (places, thresholds)
COLUMNS = ("pellets", "expected_per_shot", "expected_ci_low", "expected_ci_high", "probability", "ci_low", "ci_high")


def above_thresholds(counts, order) -> np.ndarray:
    """(places, thresholds) int64: the pellets above each threshold (scene order) at each place, from
    `counts` (levels, places) by highest level (a level-L pellet exceeds the thresholds order[:L])."""
    counts = np.asarray(counts, dtype=np.int64)
    at_or_above = np.cumsum(counts[::-1], axis=0)[::-1]  # [L, p]: pellets at level >= L
    out = np.zeros((counts.shape[1], len(order)), dtype=np.int64)
    for position, index in enumerate(order):
        out[:, index] = at_or_above[position + 1]
    return out


def clopper_pearson(m, n: int, confidence: float = CONFIDENCE) -> tuple[np.ndarray, np.ndarray]:
    """(low, high): the two-sided Clopper-Pearson interval of a binomial proportion for each count in
    `m` of `n` trials (NaN for n = 0). At m = 0: [0, 1 - (a/2)^(1/n)]; at m = n: [(a/2)^(1/n), 1]."""
    from scipy.stats import beta

    m = np.asarray(m, dtype=np.float64)
    if n <= 0:
        return np.full(m.shape, np.nan), np.full(m.shape, np.nan)
    tail = (1.0 - confidence) / 2.0
    low = np.where(m > 0, beta.ppf(tail, np.maximum(m, 1.0), n - m + 1.0), 0.0)
    high = np.where(m < n, beta.ppf(1.0 - tail, m + 1.0, np.maximum(n - m, 1.0)), 1.0)
    return low, high


def at_least_one(q, per_shot: int) -> np.ndarray:
    """1 - (1 - q)^N for N = `per_shot` independent pellets, without cancellation for small q."""
    q = np.asarray(q, dtype=np.float64)
    with np.errstate(divide="ignore"):  # (q = 1: log1p(-1) = -inf, and the probability 1)
        return -np.expm1(per_shot * np.log1p(-q))


def place_statistics(counts, order, pellets: int, per_shot: int, confidence: float = CONFIDENCE) -> dict:
    """The statistics of the module's docstring, each (places, thresholds) (NaN when `pellets` is 0):
    pellets (m), fraction (q) with fraction_low/high, expected_per_shot (E) with expected_ci_low/high,
    probability (P) with ci_low/high; and pellets_simulated (n), pellets_per_shot (N), confidence."""
    m = above_thresholds(counts, order)
    q = m / pellets if pellets > 0 else np.full(m.shape, np.nan)
    low, high = clopper_pearson(m, pellets, confidence)
    return {
        "pellets": m,
        "fraction": q,
        "fraction_low": low,
        "fraction_high": high,
        "expected_per_shot": per_shot * q,
        "expected_ci_low": per_shot * low,
        "expected_ci_high": per_shot * high,
        "probability": at_least_one(q, per_shot),
        "ci_low": at_least_one(low, per_shot),
        "ci_high": at_least_one(high, per_shot),
        "pellets_simulated": int(pellets),
        "pellets_per_shot": int(per_shot),
        "confidence": confidence,
    }
