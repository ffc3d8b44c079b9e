"""What the paper's two neglects cost: its shot (450 steel pellets, 2.5 cm envelope, 411 m/s at 45
degrees) in vacuum and in sea-level air, with pellet-pellet collisions off and on, the Magnus lift at
both ends of the published bracket, over mu_s, as an ensemble of shots.

    python examples/air_study.py [--shots 200] [--device cuda:0] [--precision float64] [--out air-study]

Each configuration runs the same `--shots` shots (seeds shot by shot, so on/off and vacuum/air see
the same launch states). Per shot: the mean range <L>, the longest L+, the shortest L-, and the mean
translational energy at landing <W_T>; the table gives their means over shots with 95% confidence
intervals (Student t), and the costs of each neglect as paired differences over shots with theirs.
Writes table.md, shots.csv and ranges.png under --out. See docs/air.md.
"""

import argparse
import csv
import json
import math
import os
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

HERE = Path(__file__).resolve().parent
COUNT = 450
LIFTS = {
    "vacuum": None,
    "air, lift 0.5 S": {"lift": "linear", "lift_slope": 0.5},
    "air, loth2008 (default)": {},
    "air, lift min(0.09 + 0.6 S, 0.4)": {"lift": "sawicki2003", "lift_max": 0.4},
}
STATS = ("range_mean", "range_max", "range_min", "landing_WT")
LABELS = {"range_mean": "<L> (m)", "range_max": "L+ (m)", "range_min": "L- (m)", "landing_WT": "landing <W_T> (J)"}


def scene_for(mu_s, air, collisions, shots, precision):
    from warp_ricochet import load_scene

    sets = [
        f"surfaces.0.mu_s={mu_s}",
        f"surfaces.0.mu_d={0.9 * mu_s}",
        f"shot.shots={shots}",
        f"collisions.enabled={str(collisions).lower()}",
        f'numerics.precision="{precision}"',
        'output.fields=["landing.range", "landing.velocity"]',
    ]
    if air is not None:
        sets.append("air.density=1.225")
        sets += [f"air.{k}={json.dumps(v)}" for k, v in air.items()]
    return load_scene(HERE / "paper.toml", sets)


def per_shot(path, mass):
    """Per shot (rows of COUNT pellets): <L>, L+, L- over pellets that landed, mean W_T at landing."""
    import h5py

    with h5py.File(path, "r") as f:
        ranges = f["pellets/landing/range"][()].astype(np.float64).reshape(-1, COUNT)
        v = f["pellets/landing/velocity"][()].astype(np.float64).reshape(-1, COUNT, 3)
    energy = 0.5 * mass * np.einsum("spi,spi->sp", v, v)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a shot where no pellet landed: NaN
        return {
            "range_mean": np.nanmean(ranges, 1),
            "range_max": np.nanmax(ranges, 1),
            "range_min": np.nanmin(ranges, 1),
            "landing_WT": np.nanmean(energy, 1),
            "landed": np.isfinite(ranges).mean(1),
        }, ranges


def interval(x):
    """Mean and half-width of its 95% confidence interval (Student t; without SciPy the normal
    quantile, within 1% of it from 200 shots), over finite values."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return (float(x.mean()) if len(x) else math.nan), math.nan
    try:
        from scipy import stats

        quantile = stats.t.ppf(0.975, len(x) - 1)
    except ImportError:
        quantile = 1.959964
    return float(x.mean()), float(quantile * x.std(ddof=1) / math.sqrt(len(x)))


def fmt(mean, half):
    digits = 3 if abs(mean) < 10 else 1
    return f"{mean:,.{digits}f} ± {half:,.{digits}f}" if math.isfinite(half) else f"{mean:,.{digits}f}"


def run_all(args):
    from warp_ricochet import api

    shots, pooled = {}, {}
    for mu_s in args.mu_s:
        for name, air in LIFTS.items():
            for collisions in (False, True):
                scene = scene_for(mu_s, air, collisions, args.shots, args.precision)
                path = Path(args.out) / "run.h5"
                api.run(scene, output=path, device=args.device, overwrite=True)
                mass = scene.shot.density * math.pi * scene.shot.diameter**3 / 6.0
                shots[mu_s, name, collisions], pooled[mu_s, name, collisions] = per_shot(path, mass)
                path.unlink()
                m = shots[mu_s, name, collisions]
                print(
                    f"mu_s {mu_s:4.2f} {name:34s} collisions {'on ' if collisions else 'off'}: <L> "
                    f"{fmt(*interval(m['range_mean']))} m, L+ {fmt(*interval(m['range_max']))} m",
                    flush=True,
                )
    return shots, pooled


def table(shots, args):
    lines = [
        f"Shots of {COUNT} pellets: {args.shots} per row, {args.precision}, device {args.device}; mean over shots ± 95% CI.",
        "",
        "| μ_s | air | collisions | " + " | ".join(LABELS[s] for s in STATS) + " | landed |",
        "|---|---|---|" + "---:|" * (len(STATS) + 1),
    ]
    for (mu_s, name, collisions), m in shots.items():
        cells = [fmt(*interval(m[s])) for s in STATS] + [f"{np.mean(m['landed']):.3f}"]
        lines.append(f"| {mu_s:g} | {name} | {'on' if collisions else 'off'} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "What each neglect costs (paired differences over the same shots, ± 95% CI):",
        "",
        "| μ_s | neglect | from → to | " + " | ".join("Δ" + LABELS[s] for s in STATS) + " |",
        "|---|---|---|" + "---:|" * len(STATS),
    ]
    for mu_s in args.mu_s:
        pairs = [
            ("the air", ("vacuum", False), ("air, loth2008 (default)", False)),
            ("collisions (vacuum)", ("vacuum", False), ("vacuum", True)),
            ("collisions (in air)", ("air, loth2008 (default)", False), ("air, loth2008 (default)", True)),
            ("both", ("vacuum", False), ("air, loth2008 (default)", True)),
        ]
        for label, a, b in pairs:
            ma, mb = shots[(mu_s, *a)], shots[(mu_s, *b)]
            cells = [fmt(*interval(mb[s] - ma[s])) for s in STATS]
            lines.append(
                f"| {mu_s:g} | {label} | {a[0]}, {'on' if a[1] else 'off'} → {b[0]}, "
                f"{'on' if b[1] else 'off'} | " + " | ".join(cells) + " |"
            )
    return "\n".join(lines) + "\n"


def plot(pooled, args):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no plot")
        return
    fig, axes = plt.subplots(1, len(args.mu_s), figsize=(5 * len(args.mu_s), 3.8), squeeze=False)
    for ax, mu_s in zip(axes[0], args.mu_s):
        for (m, name, collisions), ranges in pooled.items():
            if m != mu_s or name not in ("vacuum", "air, loth2008 (default)"):
                continue
            r = ranges[np.isfinite(ranges) & (ranges > 0)]
            ax.hist(
                r,
                bins=np.logspace(-3, 4, 70),
                histtype="step",
                label=f"{name.split(',')[0]}, collisions {'on' if collisions else 'off'}",
            )
        ax.set(xscale="log", yscale="log", xlabel="range L (m)", title=f"mu_s = {mu_s}")
    axes[0][0].set_ylabel("pellets")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(Path(args.out) / "ranges.png", dpi=120)


def main():
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--shots", type=int, default=20)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--precision", default="float64")
    parser.add_argument("--mu-s", dest="mu_s", type=float, nargs="+", default=[0.0, 0.25, 0.5])
    parser.add_argument("--out", default="air-study")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    shots, pooled = run_all(args)
    text = table(shots, args)
    (Path(args.out) / "table.md").write_text(text)
    print(text)
    with open(Path(args.out) / "shots.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["mu_s", "air", "collisions", "shot", *STATS, "landed"])
        for (mu_s, name, collisions), m in shots.items():
            for i in range(len(m["range_mean"])):
                writer.writerow([mu_s, name, int(collisions), i, *(m[s][i] for s in (*STATS, "landed"))])
    plot(pooled, args)


if __name__ == "__main__":
    main()
