"""Coverage of the reach danger distance's 95% interval (issue 26 part 4, docs/hazard.md section 4).

    python -m bench.coverage [--seeds 200] [--count 20000] [--truth 4000000] [--out DIR]

A cheap scene: pellets fired from 1 m at 120 m/s, from about 3 deg below level to 9 deg above (the
direction jitter's 0.1), onto a rigid plane in vacuum, followed to rest (closed forms on the CPU),
thresholds at 110, 100 and 50 m/s: the first two end on the flights (whose ranges spread over
hundreds of metres, far wider than a bin), the third while rolling. Each of --seeds runs of --count pellets (seeds 1, 2, ...) gives,
per threshold and p in (1e-2, 1e-3), the reach danger distance and its 95% interval
(`summarize(...)["hazard"]`, from the reach histograms). The true quantile is that of one run of
--truth pellets (seed 0; its own error is sqrt(count / truth) of the seeds' intervals). An interval
covers when it meets the true quantile's bin. Printed and written to DIR/coverage.json: per
threshold and p, the seeds with a bounded interval, the coverage and its Clopper-Pearson 95%
interval.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

FRACTIONS = (1e-2, 1e-3)
SPEEDS = {"fast": 110.0, "mid": 100.0, "slow": 50.0}


def scene(count: int, seed: int, fractions=FRACTIONS):
    """The cheap scene of the module docstring, `count` pellets drawn with `seed`."""
    from warp_ricochet.scene import scene_from_dict

    raw = {
        "shot": {
            "count": count,
            "diameter": 0.0025,
            "density": 7000.0,
            "speed": 120.0,
            "direction": [1.0, 0.05, 0.0],
            "direction_jitter": [0.02, 0.1, 0.05],
            "envelope_radius": 0.02,
            "envelope_center": [0.0, 1.0, 0.0],
            "seed": seed,
        },
        "surfaces": [
            {
                "point": [0.0, 0.0, 0.0],
                "normal": [0.0, 1.0, 0.0],
                "restitution": 0.3,
                "mu_s": 0.5,
                "mu_d": 0.45,
                "rolling_resistance": 0.3,
            }
        ],
        "physics": {"until": "rest", "impact_duration": 0.0, "rest_speed": 0.2},
        "hazard": {"speed": dict(SPEEDS), "energy_density": {}, "fractions": list(fractions)},
        "output": {"fields": []},
    }
    return scene_from_dict(raw)


def danger(count: int, seed: int, fractions=FRACTIONS) -> dict:
    """The reach danger distances of one run (contract: summarize's "hazard", rows thresholds)."""
    import warp_ricochet as wr
    from warp_ricochet.tallies.quantiles import summarize

    stats = wr.run(scene(count, seed, fractions), device="cpu")
    return summarize(stats.tally, int(stats["landed"]), with_map=False)["hazard"]


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact binomial interval of k successes in n."""
    from scipy.stats import beta

    a = (1.0 - level) / 2.0
    low = beta.ppf(a, k, n - k + 1) if k > 0 else 0.0
    high = beta.ppf(1.0 - a, k + 1, n - k) if k < n else 1.0
    return float(low), float(high)


def coverage(seeds: int, count: int, truth: int, fractions=FRACTIONS) -> dict:
    """Per threshold and fraction: seeds bounded, covered, coverage and its interval, the true
    quantile's bin."""
    from warp_ricochet.tallies.bins import bin_index, edges

    true = danger(truth, 0, fractions)
    e = edges()
    rows = [danger(count, seed, fractions) for seed in range(1, seeds + 1)]
    out = {"seeds": seeds, "count": count, "truth": truth, "rows": []}
    for i, name in enumerate(true["names"]):
        for j, p in enumerate(fractions):
            value = float(true["distance"][i, j])  # the upper edge of its bin
            b = int(bin_index([value * (1 - 1e-7)])[0])
            lo, hi = float(e[b]), float(e[b + 1])
            bounded = [r for r in rows if math.isfinite(r["ci_high"][i, j])]
            covered = int(sum(r["ci_low"][i, j] <= hi and r["ci_high"][i, j] >= lo for r in bounded))
            row = {
                "threshold": name,
                "p": p,
                "true": value,
                "true_landings": int(true["landings"][i]),
                "bounded": len(bounded),
                "covered": covered,
                "coverage": covered / len(bounded) if bounded else math.nan,
                "interval": clopper_pearson(covered, len(bounded)) if bounded else (math.nan, math.nan),
                "width_median": float(np.median([r["ci_high"][i, j] - r["ci_low"][i, j] for r in bounded]))
                if bounded
                else math.nan,
            }
            out["rows"].append(row)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.coverage", description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=200)
    parser.add_argument("--count", type=int, default=20000)
    parser.add_argument("--truth", type=int, default=4_000_000)
    parser.add_argument("--out", type=Path, default=None)
    a = parser.parse_args(argv)
    result = coverage(a.seeds, a.count, a.truth)
    print(f"{a.seeds} seeds of {a.count} pellets; true quantiles from {a.truth}")
    print("| threshold | p | true (m) | bounded | covered | coverage | 95% interval | median width (m) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | --- | ---: |")
    for r in result["rows"]:
        lo, hi = r["interval"]
        print(
            f"| {r['threshold']} | {r['p']:g} | {r['true']:.3f} | {r['bounded']} | {r['covered']} | "
            f"{r['coverage']:.3f} | [{lo:.3f}, {hi:.3f}] | {r['width_median']:.3f} |"
        )
    if a.out is not None:
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / "coverage.json").write_text(json.dumps(result, indent=1, default=float))


if __name__ == "__main__":
    main()
