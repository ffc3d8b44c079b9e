"""Ensemble comparison of the collision solvers: the paper's shot (450 pellets, collisions on) over
many shots, stepped solver in float64 and float32 against the event-driven float64 reference
(`warp_ricochet.reference.collisions`), and the chaos of one shot (its launch state moved by 1e-7).

    nice python -m bench.ensembles [--shots 200] [--reference-shots 200] [--out DIR] [--device cpu]

Per shot it computes the statistics below from the per-pellet outputs (the same function for the
solver's HDF5 and the reference's arrays). For each pair of settings and statistic: the means with
95% Student t intervals over shots, the difference with its Welch interval, a two-sample test per
statistic (Mann-Whitney U: ranks, so the heavy-tailed L+ needs no normality), Holm-corrected over
the statistics of the comparison; and the two-sample Kolmogorov-Smirnov D of the pooled ranges (its
p-value is not given: ranges within a shot are not independent). Chaos: the float64 run again from
its own launch states with each position moved by a relative 1e-7 (a pellet file): the per-shot
relative change of the mean range, beside float32's change against float64 on the same seeds.
Writes DIR/ensembles.txt and DIR/per-shot-*.csv.
"""

import argparse
import csv
import os
import time
import warnings

import numpy as np

from bench.collisions import paper_shots

FIELDS = (
    "initial",
    "impact.surface",
    "impact.velocity",
    "landing.range",
    "landing.surface",
    "landing.velocity",
    "collisions.count",
)
STATS = (
    "range_mean",
    "range_std",
    "range_max",
    "range_min",
    "range_p50",
    "range_p90",
    "landed_fraction",
    "collided_fraction",
    "pair_collisions",
    "post_mean_vt",
    "landing_mean_WT",
)


def per_shot(out, count, mass):
    """Per-shot statistics (rows: shots) from per-pellet arrays `out` (keys as in the HDF5 /pellets)."""
    shots = len(out["landing.range"]) // count
    rows = []
    for s in range(shots):
        sl = slice(s * count, (s + 1) * count)
        landed = out["landing.surface"][sl] >= 0
        r = out["landing.range"][sl][landed]
        hit = out["impact.surface"][sl][:, 0] >= 0
        v = out["impact.velocity"][sl][:, 0][hit]
        vl = out["landing.velocity"][sl][landed]
        rows.append(
            {
                "range_mean": r.mean(),
                "range_std": r.std(),
                "range_max": r.max(),
                "range_min": r.min(),
                "range_p50": np.median(r),
                "range_p90": np.quantile(r, 0.9),
                "landed_fraction": landed.mean(),
                "collided_fraction": np.mean(out["collisions.count"][sl] > 0),
                "pair_collisions": out["collisions.count"][sl].sum() / 2.0,
                "post_mean_vt": np.hypot(v[:, 0], v[:, 2]).mean(),  # the ground's normal is y
                "landing_mean_WT": 0.5 * mass * np.mean(np.einsum("ij,ij->i", vl, vl)),
            }
        )
    return {k: np.array([row[k] for row in rows]) for k in STATS}


def t_interval(x, level=0.95):
    """Mean and Student t interval of the mean of `x`."""
    from scipy import stats

    x = np.asarray(x, float)
    half = stats.t.ppf(0.5 + level / 2, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x))
    return x.mean(), x.mean() - half, x.mean() + half


def welch_interval(a, b, level=0.95):
    """Difference of means mean(a) - mean(b) with its Welch 95% interval."""
    from scipy import stats

    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    dof = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    half = stats.t.ppf(0.5 + level / 2, dof) * np.sqrt(va + vb)
    d = a.mean() - b.mean()
    return d, d - half, d + half


def holm(pvalues):
    """Holm-adjusted p-values (step-down, monotone)."""
    p = np.asarray(pvalues, float)
    order = np.argsort(p)
    adjusted, running = np.empty_like(p), 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(p) - rank) * p[i]))
        adjusted[i] = running
    return adjusted


def compare(name_a, a, name_b, b, ranges_a, ranges_b, lines):
    from scipy import stats

    pvals = [stats.mannwhitneyu(a[k], b[k]).pvalue for k in STATS]
    adjusted = holm(pvals)
    ks = stats.ks_2samp(ranges_a, ranges_b).statistic
    lines.append(
        f"\n## {name_a} ({len(a['range_mean'])} shots) vs {name_b} ({len(b['range_mean'])} shots): pooled ranges KS D = {ks:.4f}"
    )
    lines.append(
        f"| statistic | {name_a} mean [95% t CI] | {name_b} mean [95% t CI] | difference [Welch 95% CI] | "
        "Mann-Whitney p | Holm p |"
    )
    lines.append("|---|---|---|---|---|---|")
    for k, p, q in zip(STATS, pvals, adjusted):
        ma, mb, d = t_interval(a[k]), t_interval(b[k]), welch_interval(a[k], b[k])
        lines.append(
            f"| {k} | {ma[0]:.5g} [{ma[1]:.5g}, {ma[2]:.5g}] | {mb[0]:.5g} [{mb[1]:.5g}, {mb[2]:.5g}] | "
            f"{d[0]:+.4g} [{d[1]:+.4g}, {d[2]:+.4g}] | {p:.3g} | {q:.3g} |"
        )
    lines.append(f"smallest Holm p: {adjusted.min():.3g} ({STATS[int(np.argmin(adjusted))]})")


def solver_run(scene, device, path):
    import h5py

    from warp_ricochet import api

    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        api.run(scene, output=path, device=device, overwrite=True)
    cpu = time.process_time() - start
    with h5py.File(path, "r") as f:
        out = {}
        for group in ("initial", "impact", "landing", "collisions"):
            for k, ds in f["pellets"][group].items():
                out[f"{group}.{k}"] = ds[()]
        mass = float(f["constants/mass"][()])
    return out, mass, cpu


def write_csv(path, per):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(STATS)
        w.writerows(zip(*(per[k] for k in STATS)))


def main():
    import warp as wp

    from warp_ricochet.reference.collisions import simulate_collisions

    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    parser = argparse.ArgumentParser()
    parser.add_argument("--shots", type=int, default=200)
    parser.add_argument("--reference-shots", type=int, default=200)
    parser.add_argument("--count", type=int, default=450)
    parser.add_argument("--seed", type=int, default=2021)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", default="bench/results/ensembles")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    count = args.count
    runs, lines = {}, [f"# paper's shot, collisions on: {args.shots} shots of {count} pellets, seed {args.seed}"]
    for precision in ("float64", "float32"):
        scene = paper_shots(count, args.shots, precision, args.seed, FIELDS)
        out, mass, cpu = solver_run(scene, args.device, os.path.join(args.out, f"stepped-{precision}.h5"))
        runs[precision] = out
        lines.append(f"stepped {precision}: {cpu:.1f} s CPU")
    # chaos: the float64 run's own launch states, positions moved by a relative 1e-7
    base = runs["float64"]
    rng = np.random.default_rng(7)
    moved = base["initial.position"] * (1 + 1e-7 * rng.choice([-1.0, 1.0], size=base["initial.position"].shape))
    pellet_file = os.path.join(args.out, "moved.npz")
    np.savez(pellet_file, position=moved, velocity=base["initial.velocity"], angular_velocity=base["initial.angular_velocity"])
    scene = paper_shots(count, args.shots, "float64", args.seed, FIELDS)
    import dataclasses

    scene = dataclasses.replace(scene, shot=dataclasses.replace(scene.shot, file=pellet_file))
    runs["float64 moved 1e-7"], _, cpu = solver_run(scene, args.device, os.path.join(args.out, "moved.h5"))
    lines.append(f"stepped float64, launch positions moved by 1e-7: {cpu:.1f} s CPU")
    # the event-driven reference on the float64 run's launch states, shot by shot
    ref, start = {}, time.process_time()
    for s in range(args.reference_shots):
        sl = slice(s * count, (s + 1) * count)
        out, _ = simulate_collisions(
            scene,
            base["initial.position"][sl],
            base["initial.velocity"][sl],
            base["initial.angular_velocity"][sl],
            np.zeros(count, int),
        )
        for k, v in out.items():
            ref.setdefault(k, []).append(v)
    runs["reference"] = {k: np.concatenate(v) for k, v in ref.items()}
    lines.append(f"reference (event-driven, float64): {time.process_time() - start:.1f} s CPU for {args.reference_shots} shots")
    per = {name: per_shot(out, count, mass) for name, out in runs.items()}
    for name, p in per.items():
        write_csv(os.path.join(args.out, f"per-shot-{name.replace(' ', '-')}.csv"), p)

    def ranges(name):
        out = runs[name]
        return out["landing.range"][out["landing.surface"] >= 0]

    for a, b in (("float64", "reference"), ("float32", "reference"), ("float32", "float64")):
        compare(a, per[a], b, per[b], ranges(a), ranges(b), lines)
    # chaos: per-shot relative change of the mean range, on the same seeds
    lines.append("\n## chaos: per-shot |relative change| of the mean range (same launch seeds)")
    n = min(args.reference_shots, args.shots)
    for label, a, b in (
        ("float64, positions moved by 1e-7", "float64 moved 1e-7", "float64"),
        ("float32 against float64", "float32", "float64"),
        ("reference against float64 stepped", "reference", "float64"),
    ):
        rel = np.abs(per[a]["range_mean"][:n] / per[b]["range_mean"][:n] - 1)
        lines.append(f"- {label}: median {np.median(rel):.3f}, P90 {np.quantile(rel, 0.9):.3f}, max {rel.max():.3f}")
    from scipy import stats

    rel64 = np.abs(per["float64 moved 1e-7"]["range_mean"] / per["float64"]["range_mean"] - 1)
    rel32 = np.abs(per["float32"]["range_mean"] / per["float64"]["range_mean"] - 1)
    lines.append(f"- the two spreads (moved 1e-7 vs float32), Mann-Whitney p = {stats.mannwhitneyu(rel64, rel32).pvalue:.3g}")
    # how many shots pin each statistic to 1% (95% t half-width / mean)
    lines.append("\n## shots for a 95% interval of +-1% of the ensemble mean (float64 stepped)")
    for k in STATS:
        x = per["float64"][k]
        if x.mean() != 0:
            need = (1.96 * x.std(ddof=1) / (0.01 * abs(x.mean()))) ** 2
            lines.append(f"- {k}: {need:,.0f}")
    text = "\n".join(lines)
    print(text)
    with open(os.path.join(args.out, "ensembles.txt"), "w") as fh:
        fh.write(text + "\n")


if __name__ == "__main__":
    main()
