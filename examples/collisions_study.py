"""What the paper's no-collision assumption costs: its scene (450 pellets, 2.5 cm envelope) with
pellet-pellet collisions off and on, over mu_s, as ensembles of shots (default 200), with a
histogram of ranges.

    python examples/collisions_study.py [--device cpu] [--shots 200] [--out collisions-study]

Prints a Markdown table (SI units): each statistic of the ensemble with its 95% interval over shots
(`tallies.ensemble`: for L+ and L- the interval of one shot's extreme), and writes
collisions-study/ranges.png. See docs/collisions.md.
"""

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main():
    import h5py
    import warp as wp

    from warp_ricochet import api, load_scene

    wp.config.log_level = wp.LOG_WARNING
    parser = argparse.ArgumentParser()
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", default="collisions-study")
    parser.add_argument("--precision", default="float64")
    parser.add_argument("--shots", type=int, default=200)
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    here = Path(__file__).resolve().parent
    rows, ranges = [], {}
    for mu_s in (0.0, 0.25, 0.5):
        for enabled in (False, True):
            scene = load_scene(
                here / "paper.toml",
                [
                    f"surfaces.0.mu_s={mu_s}",
                    f"surfaces.0.mu_d={0.9 * mu_s}",
                    f"collisions.enabled={str(enabled).lower()}",
                    f'numerics.precision="{args.precision}"',
                    f"shot.shots={args.shots}",
                    'output.fields=["landing.range"]',
                ],
            )
            path = os.path.join(args.out, f"mu{mu_s}-{'on' if enabled else 'off'}.h5")
            stats = api.run(scene, output=path, device=args.device, overwrite=True)
            with h5py.File(path, "r") as f:
                ranges[mu_s, enabled] = f["pellets/landing/range"][()]
            rows.append((mu_s, enabled, stats))
    keys = (
        "range_mean",
        "range_std",
        "range_max",
        "range_min",
        "post_mean_vt",
        "landing_mean_WT",
        "collided_fraction",
        "pair_energy_lost_mean",
    )

    def cell(stats, key):
        if key not in stats:
            return "0"
        e = stats.ensemble
        if e is None:
            return f"{stats[key]:.4g}"
        return f"{stats[key]:.4g} [{e.low[key]:.4g}, {e.high[key]:.4g}]"

    print(f"{args.shots} shots a row; value [95% interval over shots; for range_max/min one shot's extreme]")
    print("| mu_s | collisions | " + " | ".join(keys) + " |")
    print("|---|---|" + "---|" * len(keys))
    for mu_s, enabled, s in rows:
        print(f"| {mu_s:g} | {'on' if enabled else 'off (paper)'} | " + " | ".join(cell(s, k) for k in keys) + " |")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed (pip install 'warp-ricochet[plot]'): no histogram")
        return
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
    for ax, mu_s in zip(axes, (0.0, 0.25, 0.5)):
        off, on = ranges[mu_s, False], ranges[mu_s, True]
        top = np.nanpercentile(np.concatenate([off, on]), 99)
        bins = np.linspace(0, top, 50)
        ax.hist(off[np.isfinite(off)], bins=bins, alpha=0.6, label="collisions off (paper)")
        ax.hist(on[np.isfinite(on)], bins=bins, alpha=0.6, label="collisions on")
        ax.set_title(f"mu_s = {mu_s}")
        ax.set_xlabel("range L (m)")
    axes[0].set_ylabel("pellets")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "ranges.png"), dpi=120)
    print("wrote", os.path.join(args.out, "ranges.png"))


if __name__ == "__main__":
    main()
