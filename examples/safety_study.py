"""The paper's shot as a safety analyst would run it: ensembles of shots with collisions off and on,
in vacuum and in sea-level air, and what each of the paper's two neglects costs, with intervals.

    python examples/safety_study.py [--shots 200] [--mu-s 0,0.25,0.5] [--device cuda:0]
                                    [--precision float64] [--out safety-study]

Every number comes from the run files the package writes (statistics only, no per-pellet data):
ensemble values with their 95% intervals over shots (`/stats/<name>` attributes `ci_low`, `ci_high`,
per-shot values in `/stats/shots`), landing-distance quantiles and tail fractions from the on-device
histograms (`/stats/quantiles`, `/stats/tail`) and the danger distances of the default hazard
thresholds (`/hazard/danger_distance`, docs/hazard.md). The cost of a neglect is the difference of
the ensemble means of two configurations with a Welch 95% interval over their per-shot values
(launch states differ slightly between them: with collisions on, shots are sampled without
overlaps). Writes table.md under --out and prints it.
"""

import argparse
import math
import sys
import warnings
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

HERE = Path(__file__).resolve().parent
MEDIA = {"vacuum": (), "air": ("air.density=1.225",)}
FRACTIONS = (1e-3, 1e-6)
TAILS = (10.0, 50.0, 100.0, 200.0, 500.0)
COSTS = ("range_mean", "range_max", "landing_mean_WT")


def scene_for(mu_s, medium, collisions, shots, precision):
    from warp_ricochet import load_scene

    sets = [
        f"surfaces.0.mu_s={mu_s}",
        f"surfaces.0.mu_d={0.9 * mu_s}",
        f"shot.shots={shots}",
        f"collisions.enabled={str(collisions).lower()}",
        f'numerics.precision="{precision}"',
        "output.fields=[]",
        f"hazard.fractions={list(FRACTIONS)}",
        f"output.tail_distances={list(TAILS)}",
    ]
    return load_scene(HERE / "paper.toml", sets + list(MEDIA[medium]))


def read(path):
    """What the table needs from one run file."""
    with h5py.File(path, "r") as f:
        stats = f["stats"]
        out = {
            name: (
                float(stats[name][()]),
                float(stats[name].attrs["ci_low"]),
                float(stats[name].attrs["ci_high"]),
                stats[f"shots/{name}"][()].astype(np.float64),
            )
            for name in COSTS
        }
        levels = list(stats["quantiles/distance"].attrs["levels"])
        quantiles = stats["quantiles/distance"][()]
        out["distance_p99"] = float(quantiles[levels.index(0.99)])
        out["distance_p999"] = float(quantiles[levels.index(0.999)])
        out["tail"] = dict(zip(stats["tail/distance"][()], stats["tail/fraction"][()]))
        danger = f["hazard/danger_distance"]
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in f["hazard/thresholds/name"][()]]
        above = f["hazard/thresholds/landings"][()]
        out["danger"] = {
            name: [
                (
                    float(danger["distance"][i, j]),
                    float(danger["ci_low"][i, j]),
                    float(danger["ci_high"][i, j]),
                    int(danger["needed_landings"][i, j]),
                    int(above[i]),
                )
                for j in range(len(FRACTIONS))
            ]
            for i, name in enumerate(names)
        }
        out["landed"] = int(stats["landed"][()])
    return out


def welch(a, b):
    """Difference of means mean(a) - mean(b) and its Welch 95% interval."""
    from scipy import stats

    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    diff = a.mean() - b.mean()
    if va + vb == 0:
        return diff, diff, diff
    df = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    half = stats.t.ppf(0.975, df) * math.sqrt(va + vb)
    return diff, diff - half, diff + half


def _ci(value, low, high, digits=1):
    return f"{value:,.{digits}f} [{low:,.{digits}f}, {high:,.{digits}f}]"


def _danger(entry):
    distance, low, high, needed, above = entry
    if above == 0:
        return "no landing above it"
    if math.isinf(high):
        return f"{distance:,.1f} (needs {needed:,} landings)"
    return _ci(distance, low, high)


def tables(results, mu_values, shots):
    lines = [
        f"{shots} shots of 450 pellets per row; 95% intervals over shots in brackets.",
        "",
        "| mu_s | medium | collisions | <L> (m) | one shot's L+ (m) | L+ of all (m) | <W_T> landing (J) "
        "| P99 / P99.9 distance (m) | landed beyond 50 / 100 / 200 m | corneal abrasion, p = 1e-3 (m) "
        "| skin perforation, p = 1e-3 (m) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (mu_s, medium, collisions), r in results.items():
        tails = r["tail"]
        beyond = " / ".join(f"{tails[min(tails, key=lambda d, t=t: abs(d - t))]:.2e}" for t in (50.0, 100.0, 200.0))
        rmax = r["range_max"]
        lines.append(
            f"| {mu_s} | {medium} | {'on' if collisions else 'off'} | {_ci(*r['range_mean'][:3])} "
            f"| {_ci(rmax[3].mean(), rmax[1], rmax[2])} | {rmax[0]:,.1f} | {_ci(*r['landing_mean_WT'][:3], digits=3)} "
            f"| {r['distance_p99']:,.1f} / {r['distance_p999']:,.1f} | {beyond} "
            f"| {_danger(r['danger']['corneal_abrasion'][0])} | {_danger(r['danger']['skin_perforation'][0])} |"
        )
    lines += [
        "",
        "What each neglect costs: the paper's answer minus the fuller model's (difference of ensemble "
        "means, Welch 95% interval).",
        "",
        "| mu_s | neglect | in | <L> (m) | one shot's L+ (m) | <W_T> landing (J) |",
        "|---|---|---|---|---|---|",
    ]
    for mu_s in mu_values:
        for neglect, a_key, b_key, within in (
            ("collisions", (mu_s, "vacuum", False), (mu_s, "vacuum", True), "vacuum"),
            ("collisions", (mu_s, "air", False), (mu_s, "air", True), "air"),
            ("air", (mu_s, "vacuum", False), (mu_s, "air", False), "collisions off"),
            ("air", (mu_s, "vacuum", True), (mu_s, "air", True), "collisions on"),
            ("both", (mu_s, "vacuum", False), (mu_s, "air", True), "the paper vs air + collisions"),
        ):
            cells = [
                _ci(*welch(results[a_key][n][3], results[b_key][n][3]), digits=3 if n == "landing_mean_WT" else 1) for n in COSTS
            ]
            lines.append(f"| {mu_s} | {neglect} | {within} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--shots", type=int, default=200)
    parser.add_argument("--mu-s", default="0,0.25,0.5", help="comma-separated mu_s values (mu_d = 0.9 mu_s)")
    parser.add_argument("--device", default=None)
    parser.add_argument("--precision", default="float64")
    parser.add_argument("--out", default="safety-study")
    args = parser.parse_args(argv)
    import warp_ricochet as wr

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    mu_values = [float(m) for m in args.mu_s.split(",")]
    results = {}
    for mu_s in mu_values:
        for medium in MEDIA:
            for collisions in (False, True):
                path = out / f"mu{mu_s:g}-{medium}-{'on' if collisions else 'off'}.h5"
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    wr.run(
                        scene_for(mu_s, medium, collisions, args.shots, args.precision),
                        output=str(path),
                        device=args.device,
                        overwrite=True,
                    )
                results[(mu_s, medium, collisions)] = read(path)
                print(
                    f"mu_s {mu_s} {medium} collisions {'on' if collisions else 'off'}: <L> "
                    f"{results[(mu_s, medium, collisions)]['range_mean'][0]:.2f} m",
                    file=sys.stderr,
                    flush=True,
                )
    text = tables(results, mu_values, args.shots)
    (out / "table.md").write_text(text)
    sys.stdout.write(text)


if __name__ == "__main__":
    main()
