"""Reproduce Tables 1-3 of Zohdi (2021) with our model and set them beside the paper's.

    python examples/paper_tables.py [--device cpu|cuda:0] [--out paper-sweep.h5] [--seeds 20]

Runs the paper's sweep (mu_s = 0 ... 0.5, mu_d = 0.9 mu_s) of examples/paper.toml, prints our tables,
then the paper's values beside ours with the relative differences, the checks of
docs/paper-reproduction.md, and, with --seeds, how much the statistics move from one draw of 450
pellets to another.
"""

import argparse
import math
from pathlib import Path

import numpy as np

import warp_ricochet as wr
from warp_ricochet.report import format_tables, read_results
from warp_ricochet.report.paper import paper_row

HERE = Path(__file__).resolve().parent
SWEEP = {"surfaces.0.mu_s": [round(0.05 * i, 2) for i in range(11)]}
TIE = [("surfaces.0.mu_d", 0.9, None)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default=None)
    ap.add_argument("--out", default="paper-sweep.h5")
    ap.add_argument("--seeds", type=int, default=0, help="also rerun the sweep with this many seeds")
    args = ap.parse_args()
    scene = wr.load_scene(HERE / "paper.toml")
    wr.sweep(scene, SWEEP, TIE, args.out, args.device, overwrite=True)
    print(format_tables(read_results(args.out), "text", paper=True))

    results = {p["surfaces.0.mu_s"]: s for p, s in wr.sweep(scene, SWEEP, TIE, device=args.device)}
    print("Checks (docs/paper-reproduction.md):")
    for mu, key, paper_key in (
        (0.0, "range_mean", "range_mean"),
        (0.0, "range_max", "range_max"),
        (0.0, "range_min", "range_min"),
        (0.05, "range_slip_max", "range_max"),
    ):
        ours, theirs = results[mu][key], paper_row(mu)[paper_key]
        print(f"  mu_s = {mu:4.2f} {key:15s} ours {ours:9.3f} m  paper {theirs:9.3f} m  {100 * (ours / theirs - 1):+.3f}%")
    stick = results[0.5]
    print(
        f"  all-stick: <v_t> after / before = {stick['post_mean_vt'] / stick['pre_mean_vt']:.6f} (5/7 = {5 / 7:.6f}, "
        f"eq. 29); the paper's 36.950 / 290.454 = {36.95 / 290.454:.3f}"
    )
    bound = 0.01 * 411.48**2 / 9.81
    a = 0.045 * 1.01
    print(
        f"  L+ bounds: E v^2/g = {bound:.2f} m (mu_s = 0); (E v^2/g)(sqrt(1+a^2)-a) = {bound * (math.sqrt(1 + a * a) - a):.2f} m "
        f"(mu_s = 0.05 slip)"
    )
    print(f"  stick threshold at 45 degrees: mu_s = 2/(7(1+E)) = {2 / (7 * 1.01):.3f}")

    if args.seeds:
        keys = ("range_mean", "range_max", "range_min", "pre_mean_vt", "post_norm_mean_omega")
        table = {mu: [] for mu in (0.0, 0.05, 0.5)}
        for seed in range(1, args.seeds + 1):
            sc = wr.load_scene(HERE / "paper.toml", [f"shot.seed={seed}", "output.fields=[]"])
            for p, s in wr.sweep(sc, {"surfaces.0.mu_s": list(table)}, TIE, device=args.device):
                table[p["surfaces.0.mu_s"]].append([s[k] for k in keys])
        print(f"\nOver {args.seeds} seeds (mean +- std):")
        for mu, rows in table.items():
            rows = np.array(rows)
            cells = ", ".join(f"{k} {m:.3f} +- {sd:.3f}" for k, m, sd in zip(keys, rows.mean(0), rows.std(0)))
            print(f"  mu_s = {mu:4.2f}: {cells}")


if __name__ == "__main__":
    main()
