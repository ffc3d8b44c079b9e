"""The reach danger distance's 95% interval covers the true quantile at the nominal rate (issue 26
part 4; bench/coverage.py measures it over more seeds and pellets): 100 seeded runs of the cheap
scene (vacuum to rest on a rigid plane), p = 1e-2, against one run of 200,000 pellets (the truth
of 24,000 moved by its own error covered 90 of 100)."""

import math

from bench.coverage import clopper_pearson, coverage

SEEDS = 100


def test_the_danger_distance_interval_covers_at_95_percent():
    """Per threshold: the bounded intervals that meet the true quantile's bin number at least
    95% of them less twice the binomial error (sqrt(0.95 0.05 / n)), and the exact interval of the
    coverage reaches 0.95."""
    result = coverage(SEEDS, 600, 200_000, fractions=(1e-2,))
    for row in result["rows"]:
        n, k = row["bounded"], row["covered"]
        assert n >= 0.9 * SEEDS, row  # 600 pellets: most runs have the 367 reaches p = 1e-2 needs
        assert k >= n * (0.95 - 2 * math.sqrt(0.95 * 0.05 / n)), row
        assert clopper_pearson(k, n)[1] >= 0.95, row
