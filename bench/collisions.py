"""Pellet-pellet collisions: run time against error of the time-stepped solver, measured against the
event-driven float64 reference (`warp_ricochet.collision_reference`), and dense-phase throughput.

    python -m bench.collisions tradeoff [--count 200] [--seeds 3] [--device cpu] [--out bench/results/...]
    python -m bench.collisions throughput [--count 450] [--shots 1] [--device cuda:0]

`tradeoff` runs the paper's shot (its envelope, so most pellets collide) with collisions on for a
grid of step fractions, rounds per step and precisions, and reports, against the reference on the
same launch states: the error in mean range, in L+ and L-, the Wasserstein-1 distance between the
range distributions, the difference in the fraction of pellets that collided, and the run time. It
writes a CSV and a PNG (error against time) beside it. Collisions are chaotic: per-pellet results
diverge from the reference as soon as one event is taken in another order, so the ensemble
metrics are what a study can rely on, and the reference itself is only one sample of that chaos;
the spread between seeds is printed with each figure.
"""

import argparse
import csv
import os
import time

import numpy as np


def _scene(count, seed, precision, **collisions):
    from tests.helpers import make_scene, paper_raw

    raw = paper_raw()
    raw["shot"].update(count=count, seed=seed)
    raw["collisions"] = {"enabled": True, **collisions}
    raw["output"] = {"fields": ["initial", "landing.range", "collisions.count"]}
    return make_scene(raw, precision=precision)


def _run(scene, device, path):
    import h5py

    from warp_ricochet import api

    api.run(scene, device=device)  # warm: kernels compiled, caches filled
    start = time.perf_counter()
    api.run(scene, output=path, device=device, overwrite=True)
    elapsed = time.perf_counter() - start
    with h5py.File(path, "r") as f:
        pellets = {k: f["pellets/" + k.replace(".", "/")][()] for k in ("initial.position", "initial.velocity",
                                                                         "initial.angular_velocity", "landing.range",
                                                                         "collisions.count")}
        stats = {k: float(f["stats"][k][()]) for k in f["stats"]}
    return elapsed, pellets, stats


def _metrics(ranges, ref_ranges, stats, ref_stats):
    a, b = np.sort(ranges[np.isfinite(ranges)]), np.sort(ref_ranges[np.isfinite(ref_ranges)])
    n = min(len(a), len(b))
    q = (np.arange(n) + 0.5) / n
    w1 = float(np.mean(np.abs(np.quantile(a, q) - np.quantile(b, q))))
    return {
        "mean_range_error": abs(stats["range_mean"] - ref_stats["range_mean"]) / ref_stats["range_mean"],
        "Lplus_error": abs(stats["range_max"] - ref_stats["range_max"]) / ref_stats["range_max"],
        "Lminus_error_m": abs(stats["range_min"] - ref_stats["range_min"]),
        "wasserstein_m": w1,
        "collided_error": abs(stats["collided_fraction"] - ref_stats["collided_fraction"]),
    }


def tradeoff(args):
    import warp as wp

    from warp_ricochet.collision_reference import simulate_collisions

    wp.config.log_level = wp.LOG_WARNING
    os.makedirs(args.out, exist_ok=True)
    rows = []
    if args.knobs:  # skin and step fraction together (fraction = skin / 8: neither bound of the step binds alone)
        grid = [(p, k, k / 8.0, r) for p in ("float64", "float32") for k in (2.0, 4.0, 6.0) for r in (1, 2, 4)]
    else:
        grid = [(p, 2.0, f, r) for p in ("float64", "float32") for f in (1.0, 0.5, 0.25, 0.1) for r in (1, 4)]
        grid += [("float64", 2.0, 0.25, 16), ("float64", 2.0, 0.05, 4)]
    name = "collisions-knobs" if args.knobs else "collisions-tradeoff"
    for precision, skin, fraction, rounds in grid:
        per_seed = []
        for seed in range(args.seeds):
            scene = _scene(args.count, 2021 + seed, precision, step_fraction=fraction, rounds=rounds, skin=skin)
            elapsed, pellets, stats = _run(scene, args.device, os.path.join(args.out, "tradeoff-run.h5"))
            ref, ref_stats = simulate_collisions(scene, pellets["initial.position"].astype(float),
                                                 pellets["initial.velocity"].astype(float),
                                                 pellets["initial.angular_velocity"].astype(float))
            m = _metrics(pellets["landing.range"].astype(float), ref["landing.range"], stats, ref_stats)
            m.update(time_s=elapsed, steps=stats["dense_steps_max"],
                     same_collision_count=float(np.mean(pellets["collisions.count"] == ref["collisions.count"])))
            per_seed.append(m)
        row = {"precision": precision, "skin": skin, "step_fraction": fraction, "rounds": rounds}
        for key in per_seed[0]:
            values = [m[key] for m in per_seed]
            row[key] = float(np.mean(values))
            row[key + "_spread"] = float(np.std(values))
        rows.append(row)
        print(f"{precision} skin {skin:3.1f} fraction {fraction:5.2f} rounds {rounds:2d}: {row['time_s']:7.3f} s  steps {row['steps']:7.0f}  "
              f"mean range {row['mean_range_error']:.2e}  L+ {row['Lplus_error']:.2e}  W1 {row['wasserstein_m']:.3g} m  "
              f"collided {row['collided_error']:.3f}  same counts {row['same_collision_count']:.2f}", flush=True)
    path = os.path.join(args.out, name + ".csv")
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no plot")
        return
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for precision, marker in (("float64", "o"), ("float32", "s")):
        for rounds, colour in ((1, "tab:red"), (2, "tab:orange"), (4, "tab:blue"), (16, "tab:green")):
            sel = [r for r in rows if r["precision"] == precision and r["rounds"] == rounds]
            if not sel:
                continue
            t = [r["time_s"] for r in sel]
            axes[0].loglog(t, [max(r["mean_range_error"], 1e-6) for r in sel], marker=marker, color=colour, ls="-",
                           label=f"{precision}, {rounds} rounds")
            axes[1].loglog(t, [max(r["wasserstein_m"], 1e-6) for r in sel], marker=marker, color=colour, ls="-")
            for r in sel:
                label = f"{r['skin']:g}/{r['step_fraction']:g}" if args.knobs else f"{r['step_fraction']:g}"
                axes[0].annotate(label, (r["time_s"], max(r["mean_range_error"], 1e-6)), fontsize=7)
    axes[0].set_xlabel("run time (s)")
    axes[0].set_ylabel("|mean range - reference| / reference")
    axes[1].set_xlabel("run time (s)")
    axes[1].set_ylabel("Wasserstein-1 distance of ranges (m)")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"Collisions, paper shot of {args.count} pellets, {args.seeds} seeds, {args.device} (labels: " + ("skin/step_fraction" if args.knobs else "step_fraction") + ")")
    fig.tight_layout()
    png = os.path.join(args.out, name + ".png")
    fig.savefig(png, dpi=120)
    print("wrote", path, "and", png)


def throughput(args):
    import warp as wp

    from warp_ricochet import api

    wp.config.log_level = wp.LOG_WARNING
    from tests.helpers import make_scene, paper_raw

    raw = paper_raw()
    raw["shot"].update(count=args.count, shots=args.shots)
    raw["collisions"] = {"enabled": True, **({"rounds": args.rounds} if args.rounds else {})}
    raw["numerics"] = {"precision": args.precision}
    scene = make_scene(raw, precision=args.precision)
    api.run(scene, device=args.device)  # warm: kernels compiled, graphs captured, buffers sized
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        stats = api.run(scene, device=args.device)
        times.append(time.perf_counter() - start)
    elapsed = float(np.median(times))
    # every step launches over every pellet of the run (pellets and shots that are done return at once);
    # the pellet-steps that do work are those of each shot's own steps
    pellets = args.count * args.shots
    launched = stats["dense_steps_max"] * pellets
    working = stats["dense_steps_mean"] * pellets
    print(f"{args.device} {args.precision} rounds={scene.collisions.rounds}: {args.shots} shots x {args.count} pellets = {pellets:.3g} "
          f"in {elapsed:.3f} s (median of {args.repeats}: {', '.join(f'{t:.3f}' for t in times)}; whole run: dense "
          f"phase, flight, statistics); steps: {stats['dense_steps_max']:.0f} launched, {stats['dense_steps_mean']:.0f} "
          f"per shot on average; dense phase up to {stats['dense_time_max'] * 1e3:.2f} ms of flight (mean "
          f"{stats['dense_time_mean'] * 1e3:.2f}); {launched / elapsed:.3g} pellet-steps/s launched, "
          f"{working / elapsed:.3g} working; collided {stats['collided_fraction']:.3f}")


def main():
    parser = argparse.ArgumentParser(prog="python -m bench.collisions")
    parser.add_argument("what", choices=("tradeoff", "throughput"))
    parser.add_argument("--count", type=int, default=200)
    parser.add_argument("--shots", type=int, default=1)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--knobs", action="store_true", help="tradeoff over skin (with step_fraction = skin / 8) and rounds")
    parser.add_argument("--rounds", type=int, default=0, help="collisions.rounds (0: the default)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--precision", default="float32")
    parser.add_argument("--out", default="bench/results/collisions")
    args = parser.parse_args()
    {"tradeoff": tradeoff, "throughput": throughput}[args.what](args)


if __name__ == "__main__":
    main()
