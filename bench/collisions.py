"""Pellet-pellet collisions: run time against error of the time-stepped solver, measured against the
event-driven float64 reference (`warp_ricochet.reference.collisions`), dense-phase throughput, where
its time goes, and which shots keep a run stepping. Every subcommand runs the paper's shot (its
envelope, so most pellets collide) with collisions on.

    python -m bench.collisions tradeoff [--count 120] [--seeds 2] [--knobs] [--device cpu] [--out DIR]
    python -m bench.collisions throughput [--count 450] [--shots 2223] [--rounds R] [--repeats 3] [--device cuda:0]
    python -m bench.collisions profile [--shots 2223] [--rounds R] [--skin K] [--step-fraction F] [--device cuda:0]
    python -m bench.collisions tail [--shots 2223] [--device cuda:0] [--out DIR]
    python -m bench.collisions reference [--count 450] [--seeds 2] [--device cpu]

`tradeoff` runs a grid of step fractions (or, with --knobs, skins with step_fraction = skin / 9),
rounds per step and precisions, and reports, against the reference on the same launch states: the
error in mean range, in L+ and L-, the Wasserstein-1 distance between the range distributions, the
difference in the fraction of pellets that collided, and the run time; it writes a CSV and a PNG
(error against time). Collisions are chaotic: per-pellet results diverge from the reference as soon
as one event is taken in another order, so the ensemble metrics are what a study can rely on; the
spread between seeds is printed with each figure.

`throughput`: the whole run (dense phase, flight, statistics), median of repeats after a warm-up;
pellet-steps *launched* (pellets x the longest shot's steps: every step launches over every pellet)
and *working* (pellets x the mean steps per shot). `profile`: wall time of the list rebuilds, the
blocks of steps and the checkpoints, each with a device synchronisation around it. `tail`: the end
of the dense phase per shot (quantiles), and the launch states of the longest shot (tail-shot.npz).
`reference`: one float64 shot per seed (2021 on) against the event-driven reference, ensemble and
pellet by pellet.
"""

import argparse
import csv
import os
import time
import warnings
from collections import defaultdict

import numpy as np


def paper_shots(count, shots=1, precision="float32", seed=2021, fields=None, air=False, **collisions):
    """The paper's scene (examples/paper.toml) as `shots` shots of `count` pellets, collisions on
    (`collisions`: the [collisions] keys given; the defaults otherwise); `air`: in sea-level air."""
    import tomllib

    from warp_ricochet.scene import scene_from_dict

    with open(os.path.join(os.path.dirname(__file__), "..", "examples", "paper.toml"), "rb") as f:
        raw = tomllib.load(f)
    raw["shot"].update(count=count, shots=shots, seed=seed)
    raw["collisions"] = {"enabled": True, **{k: v for k, v in collisions.items() if v is not None}}
    raw["numerics"]["precision"] = precision
    if air:
        raw["air"] = {"density": 1.225}  # sea level, every other key its default (docs/air.md)
        raw["surfaces"][0].update(mu_s=0.5, mu_d=0.45)
    raw.pop("output")  # the default fields
    if fields is not None:
        raw["output"] = {"fields": list(fields)}
    return scene_from_dict(raw)


def _run(scene, device, path):
    import h5py

    from warp_ricochet import api

    api.run(scene, device=device)  # warm: kernels compiled, caches filled
    start = time.perf_counter()
    api.run(scene, output=path, device=device, overwrite=True)
    elapsed = time.perf_counter() - start
    with h5py.File(path, "r") as f:
        pellets = {
            k: f["pellets/" + k.replace(".", "/")][()]
            for k in ("initial.position", "initial.velocity", "initial.angular_velocity", "landing.range", "collisions.count")
        }
        stats = {k: float(ds[()]) for k, ds in f["stats"].items() if isinstance(ds, h5py.Dataset)}
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
    from warp_ricochet.reference.collisions import simulate_collisions

    os.makedirs(args.out, exist_ok=True)
    rows = []
    from warp_ricochet.dense.constants import SKIN_STEPS

    if args.knobs:  # skin and step fraction together (fraction = skin / SKIN_STEPS: neither bound of the step binds alone)
        grid = [(p, k, k / SKIN_STEPS, r) for p in ("float64", "float32") for k in (2.25, 4.5, 6.75) for r in (1, 2, 4)]
    else:
        # (at skin 2.25 the step is capped at skin / SKIN_STEPS = 0.25 diameters: larger fractions give the same steps)
        grid = [(p, 2.25, f, r) for p in ("float64", "float32") for f in (0.25, 0.1, 0.05) for r in (1, 4)]
        grid += [("float64", 2.25, 0.25, 16)]
    name = "collisions-knobs" if args.knobs else "collisions-tradeoff"
    for precision, skin, fraction, rounds in grid:
        per_seed = []
        for seed in range(args.seeds):
            scene = paper_shots(
                args.count,
                1,
                precision,
                2021 + seed,
                ("initial", "landing.range", "collisions.count"),
                step_fraction=fraction,
                rounds=rounds,
                skin=skin,
            )
            elapsed, pellets, stats = _run(scene, args.device, os.path.join(args.out, "tradeoff-run.h5"))
            ref, ref_stats = simulate_collisions(
                scene,
                pellets["initial.position"].astype(float),
                pellets["initial.velocity"].astype(float),
                pellets["initial.angular_velocity"].astype(float),
            )
            m = _metrics(pellets["landing.range"].astype(float), ref["landing.range"], stats, ref_stats)
            m.update(
                time_s=elapsed,
                steps=stats["dense_steps_max"],
                same_collision_count=float(np.mean(pellets["collisions.count"] == ref["collisions.count"])),
            )
            per_seed.append(m)
        row = {"precision": precision, "skin": skin, "step_fraction": fraction, "rounds": rounds}
        for key in per_seed[0]:
            values = [m[key] for m in per_seed]
            row[key] = float(np.mean(values))
            row[key + "_spread"] = float(np.std(values))
        rows.append(row)
        print(
            f"{precision} skin {skin:4.2f} fraction {fraction:5.2f} rounds {rounds:2d}: {row['time_s']:7.3f} s  steps {row['steps']:7.0f}  "
            f"mean range {row['mean_range_error']:.2e}  L+ {row['Lplus_error']:.2e}  W1 {row['wasserstein_m']:.3g} m  "
            f"collided {row['collided_error']:.3f}  same counts {row['same_collision_count']:.2f}",
            flush=True,
        )
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
            axes[0].loglog(
                t,
                [max(r["mean_range_error"], 1e-6) for r in sel],
                marker=marker,
                color=colour,
                ls="-",
                label=f"{precision}, {rounds} rounds",
            )
            axes[1].loglog(t, [max(r["wasserstein_m"], 1e-6) for r in sel], marker=marker, color=colour, ls="-")
            for r in sel:
                label = f"{r['skin']:g}/{r['step_fraction']:g}" if args.knobs else f"{r['step_fraction']:g}"
                axes[0].annotate(label, (r["time_s"], max(r["mean_range_error"], 1e-6)), fontsize=7)
    axes[0].set_xlabel("run time (s)")
    axes[0].set_ylabel("|mean range - reference| / reference")
    axes[1].set_xlabel("run time (s)")
    axes[1].set_ylabel("Wasserstein-1 distance of ranges (m)")
    axes[0].legend(fontsize=7)
    fig.suptitle(
        f"Collisions, paper shot of {args.count} pellets, {args.seeds} seeds, {args.device} (labels: "
        + ("skin/step_fraction" if args.knobs else "step_fraction")
        + ")"
    )
    fig.tight_layout()
    png = os.path.join(args.out, name + ".png")
    fig.savefig(png, dpi=120)
    print("wrote", path, "and", png)


def _timed_runs(scene, device, repeats):
    """Run times (s) of `repeats` runs after a warm-up (kernels compiled, graphs captured), and
    the last run's statistics."""
    from warp_ricochet import api

    api.run(scene, device=device)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        stats = api.run(scene, device=device)
        times.append(time.perf_counter() - start)
    return times, stats


def throughput(args):
    scene = paper_shots(args.count, args.shots, args.precision, rounds=args.rounds)
    times, stats = _timed_runs(scene, args.device, args.repeats)
    elapsed = float(np.median(times))
    pellets = args.count * args.shots
    launched = stats["dense_steps_max"] * pellets
    working = stats["dense_steps_mean"] * pellets
    print(
        f"{args.device} {args.precision} rounds={scene.collisions.rounds}: {args.shots} shots x {args.count} pellets = {pellets:.3g} "
        f"in {elapsed:.3f} s (median of {args.repeats}: {', '.join(f'{t:.3f}' for t in times)}; whole run: dense "
        f"phase, flight, statistics); steps: {stats['dense_steps_max']:.0f} launched, {stats['dense_steps_mean']:.0f} "
        f"per shot on average; dense phase up to {stats['dense_time_max'] * 1e3:.2f} ms of flight (mean "
        f"{stats['dense_time_mean'] * 1e3:.2f}); {launched / elapsed:.3g} pellet-steps/s launched, "
        f"{working / elapsed:.3g} working; collided {stats['collided_fraction']:.3f}"
    )


def profile(args):
    import warp as wp

    from warp_ricochet import api
    from warp_ricochet.dense.phase import DenseOptions, DensePhase

    scene = paper_shots(
        args.count, args.shots, args.precision, rounds=args.rounds, skin=args.skin, step_fraction=args.step_fraction, air=args.air
    )
    # (on the CPU the dense phase is one launch; its parts are timed in the host loop, which
    # launches the same per-shot work: the one launch saves the host round trips between them)
    host_loop = DenseOptions(cpu_steps="block")
    api.run(scene, device=args.device, dense_options=host_loop)  # warm
    device = wp.get_device(args.device)
    spent, calls = defaultdict(float), defaultdict(int)

    def timed(name, fn):
        def wrapper(self, *a, **k):
            wp.synchronize_device(device)
            start = time.perf_counter()
            result = fn(self, *a, **k)
            wp.synchronize_device(device)
            spent[name] += time.perf_counter() - start
            calls[name] += 1
            return result

        return wrapper

    originals = {name: getattr(DensePhase, name) for name in ("_rebuild", "_block", "_checkpoint", "_launch")}
    DensePhase._rebuild = timed("rebuild (CPU: cell lists; CUDA: grid points, HashGrid.build, neighbours)", originals["_rebuild"])
    DensePhase._block = timed("block of steps (graph or replay)", originals["_block"])
    DensePhase._checkpoint = timed("checkpoint (now, horizon, settle, leaps; flags to the host)", originals["_checkpoint"])
    if args.per_kernel:  # each launch of a block and a checkpoint alone, synchronised (no graphs: slower in all)

        def each(commands, repeat=1):
            for _ in range(repeat):
                for command in commands:
                    wp.synchronize_device(device)
                    start = time.perf_counter()
                    command.launch()
                    wp.synchronize_device(device)
                    name = "  kernel " + command.kernel.key
                    spent[name] += time.perf_counter() - start
                    calls[name] += 1

        def block(self, commands):
            each(commands, self.block_steps)

        def checkpoint(self):
            each([self.now_command, *self.horizon_commands, *self.checkpoint_commands])
            return self.cloud.flags.numpy().copy()

        DensePhase._block = timed("block of steps (kernels one at a time)", block)
        DensePhase._checkpoint = timed("checkpoint (kernels one at a time)", checkpoint)
    DensePhase._launch = timed("other launches (launch, drift, release, totals; recording)", originals["_launch"])
    try:
        start = time.perf_counter()
        stats = api.run(scene, device=args.device, dense_options=host_loop)
        total = time.perf_counter() - start
    finally:
        for name, fn in originals.items():
            setattr(DensePhase, name, fn)
    c = scene.collisions
    print(
        f"{args.device} {args.precision} {args.shots} x {args.count}, rounds {c.rounds}, skin {c.skin}, step fraction "
        f"{c.step_fraction}: {total:.3f} s, steps {stats['dense_steps_max']:.0f} (mean {stats['dense_steps_mean']:.0f})"
        + ("; the host loop (by default the CPU's dense phase is one launch of the same work)" if not device.is_cuda else "")
    )
    for name in spent:
        print(f"  {name:75s} {spent[name]:8.3f} s  {calls[name]:6d} calls  {spent[name] / calls[name] * 1e3:8.3f} ms each")
    parts = sum(t for name, t in spent.items() if not name.startswith("  kernel"))  # (kernels are inside their parts)
    print(f"  {'rest (sampling, flight kernel, statistics, host)':75s} {total - parts:8.3f} s")


def tail(args):
    import h5py

    from warp_ricochet import api

    scene = paper_shots(args.count, args.shots, args.precision, fields=("initial", "release.time", "collisions.count"))
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "tail-run.h5")
    stats = api.run(scene, output=path, device=args.device, overwrite=True)
    with h5py.File(path, "r") as f:
        end = f["pellets/release/time"][()].reshape(args.shots, args.count).max(axis=1)
        initial = {k: f["pellets/initial/" + k][()] for k in ("position", "velocity", "angular_velocity")}
    os.remove(path)
    order = np.argsort(end)[::-1]
    q = np.quantile(end, [0.5, 0.9, 0.99, 0.999, 1.0])
    print(
        f"dense phase end per shot (ms): median {q[0] * 1e3:.2f}, p90 {q[1] * 1e3:.2f}, p99 {q[2] * 1e3:.2f}, "
        f"p99.9 {q[3] * 1e3:.2f}, max {q[4] * 1e3:.2f}; steps mean {stats['dense_steps_mean']:.0f} max "
        f"{stats['dense_steps_max']:.0f}"
    )
    print("longest shots:", ", ".join(f"{s} ({end[s] * 1e3:.1f} ms)" for s in order[:8]))
    rows = slice(order[0] * args.count, (order[0] + 1) * args.count)
    np.savez(os.path.join(args.out, "tail-shot.npz"), **{k: v[rows] for k, v in initial.items()})
    np.save(os.path.join(args.out, "shot-end.npy"), end)


def reference(args):
    from warp_ricochet.reference.collisions import simulate_collisions

    for seed in range(2021, 2021 + args.seeds):
        scene = paper_shots(args.count, 1, "float64", seed, ("initial", "landing.range", "collisions.count"))
        elapsed, p, st = _run(scene, args.device, "/tmp/bench-collisions-reference.h5")
        start = time.perf_counter()
        ref, rs = simulate_collisions(scene, p["initial.position"], p["initial.velocity"], p["initial.angular_velocity"])
        ref_time = time.perf_counter() - start
        same = np.mean(ref["collisions.count"] == p["collisions.count"])
        print(
            f"seed {seed}: solver {elapsed:.2f} s, reference {ref_time:.2f} s; collided {st['collided_fraction']:.3f} vs "
            f"{rs['collided_fraction']:.3f}; pair collisions {st['pair_collisions']:.0f} vs {rs['pair_collisions']:.0f}; "
            f"lost {st['pair_energy_lost']:.2f} vs {rs['pair_energy_lost']:.2f} J; mean range {st['range_mean']:.2f} vs "
            f"{rs['range_mean']:.2f}; L+ {st['range_max']:.1f} vs {rs['range_max']:.1f}; same counts {same:.3f}; "
            f"max range diff {np.nanmax(np.abs(ref['landing.range'] - p['landing.range'])):.3g} m"
        )


def main():
    import warp as wp

    commands = {"tradeoff": tradeoff, "throughput": throughput, "profile": profile, "tail": tail, "reference": reference}
    parser = argparse.ArgumentParser(
        prog="python -m bench.collisions", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("what", choices=tuple(commands))
    parser.add_argument("--count", type=int, default=None, help="pellets per shot (tradeoff 120, else 450)")
    parser.add_argument("--shots", type=int, default=2223, help="shots in one run (throughput, profile, tail)")
    parser.add_argument("--seeds", type=int, default=2, help="tradeoff: seeds per setting")
    parser.add_argument("--repeats", type=int, default=3, help="throughput: timed runs after a warm-up")
    parser.add_argument("--knobs", action="store_true", help="tradeoff over skin (with step_fraction = skin / 9) and rounds")
    parser.add_argument("--rounds", type=int, default=None, help="collisions.rounds (default: the scene default)")
    parser.add_argument("--skin", type=float, default=None, help="profile: collisions.skin")
    parser.add_argument("--step-fraction", type=float, default=None, help="profile: collisions.step_fraction")
    parser.add_argument("--air", action="store_true", help="profile: in sea-level air (mu_s 0.5, as bench.air)")
    parser.add_argument(
        "--per-kernel", dest="per_kernel", action="store_true", help="profile: time each launch of a block and a checkpoint alone"
    )
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--precision", default="float32")
    parser.add_argument("--out", default=None, help="tradeoff, tail: folder for the CSV/PNG or the tail files")
    args = parser.parse_args()
    args.count = args.count or (120 if args.what == "tradeoff" else 450)
    if args.out is None and args.what in ("tradeoff", "tail"):
        parser.error(f"{args.what} needs --out (a dated folder under bench/results/)")
    wp.config.log_level = wp.LOG_WARNING
    from warp_ricochet.errors import PrecisionWarning

    warnings.simplefilter("ignore", PrecisionWarning)  # float32 runs here are on purpose
    commands[args.what](args)


if __name__ == "__main__":
    main()
