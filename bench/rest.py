"""Following every pellet to its end (`physics.until = "rest"`, docs/ground.md): throughput beside
today's path (the landing) in one run, with impacts, integration steps and bytes per pellet.

    python -m bench.rest throughput [--device cuda:0] [--sizes 1e6,1e8] [--repeats 3] [--set KEY=VALUE] [--out DIR]
    python -m bench.rest collisions [--device cuda:0] [--shots 10000] [--count 450] [--out DIR]
    python -m bench.rest kernels [--device cuda:0] [--shots 10000] [--count 450]

`throughput`: statistics-only runs of the paper's scene (examples/paper.toml, mu_s 0.5, float32):
in vacuum and in sea-level air to the landing (today's path), and in air followed to rest on each
ground of GROUNDS (a rigid plane: the scene's own surface, c = 0; and catalogue materials). Each
row: seconds (median of --repeats after a warm-up), pellets/s, mean impacts and integration steps
per pellet (/stats), and the device bytes per pellet of a statistics-only run (the per-thread
partials: none per pellet). `collisions`: --shots shots of --count pellets with pellet-pellet
collisions in sea-level air, to the landing and to rest on turf. `kernels`: where the GPU's time
goes in runs of --shots shots of --count pellets in air on turf (with and without collisions, to the
landing and to rest; and the same pellets as one shot, without the per-shot pass of the ensemble):
each kernel's total time and launches, from Warp's CUDA activity timing (`wp.timing_begin`).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

from bench.__main__ import _timed, _wr, device_info
from bench.air import paper_scene
from bench.dask import _count

# (label, in air, physics.until, more settings)
CASES = (
    ("vacuum, landing", False, "landing", ()),
    ("air, landing", True, "landing", ()),
    ("air, rest, rigid plane (c = 0)", True, "rest", ()),
    ("air, rest, turf", True, "rest", ('surfaces.0.material="turf"',)),
    ("air, rest, packed soil", True, "rest", ('surfaces.0.material="packed_soil"',)),
    ("vacuum, rest, turf", False, "rest", ('surfaces.0.material="turf"',)),
)


def _row(label, n, stats, seconds, times):
    row = {"case": label, "N": n, "seconds": seconds, "runs": times, "pellets_per_s": n / seconds}
    for key in ("rest_impacts_mean", "rest_steps_mean", "flight_steps_mean", "rest_distance_mean", "rest_path_mean"):
        if key in stats:
            row[key] = float(stats[key])
    for key, value in stats.items():
        if key.startswith("ended_"):
            row[key] = int(value)
    return row


def _print(row):
    extra = ", ".join(f"{k} {v:.4g}" for k, v in row.items() if k not in ("case", "N", "seconds", "runs", "pellets_per_s"))
    print(
        f"{row['case']:34s} N {row['N']:.0e}: {row['seconds'] * 1e3:9.2f} ms, {row['pellets_per_s']:.3e} pellets/s; {extra}",
        flush=True,
    )


def throughput(device, sizes, repeats, only="", sets=()):
    wr, wp = _wr()
    rows = []
    for label, air, until, extra in CASES:
        if only not in label:
            continue
        settings = [f'physics.until="{until}"', *extra, *sets]
        wr.run(paper_scene(1000, air=air, mu_s=0.5, extra=settings), device=device)  # compile
        for n in sizes:
            scene = paper_scene(n, air=air, mu_s=0.5, extra=settings)
            stats = wr.run(scene, device=device)
            t, times = _timed(lambda scene=scene: (wr.run(scene, device=device), wp.synchronize_device(device)), repeats)
            row = _row(label, n, stats, t, times)
            rows.append(row)
            _print(row)
    return rows


def collisions(device, shots, count, repeats):
    wr, wp = _wr()
    rows = []
    for label, settings in (
        ("collisions, air, landing", ['physics.until="landing"']),
        ("collisions, air, rest, turf", ['physics.until="rest"', 'surfaces.0.material="turf"']),
    ):
        collided = [f"shot.shots={shots}", "collisions.enabled=true", "output.fields=[]"]
        scene = paper_scene(count, "float32", air=True, mu_s=0.5, extra=collided + settings)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            started = time.perf_counter()
            stats = wr.run(scene, device=device)
            print(f"{label}: the first run (compiling) took {time.perf_counter() - started:.1f} s", flush=True)
            t, times = _timed(lambda scene=scene: (wr.run(scene, device=device), wp.synchronize_device(device)), repeats)
        row = _row(label, shots * count, stats, t, times)
        rows.append(row)
        _print(row)
    return rows


def kernels(device, shots, count, only=""):
    wr, wp = _wr()
    rows = []
    cases = (
        ("collisions, air, rest, turf", shots, count, ["collisions.enabled=true", 'physics.until="rest"']),
        ("collisions, air, landing", shots, count, ["collisions.enabled=true", 'physics.until="landing"']),
        ("shots, air, rest, turf", shots, count, ['physics.until="rest"']),
        ("one shot, air, rest, turf", 1, shots * count, ['physics.until="rest"']),
    )
    for label, n_shots, n_count, settings in cases:
        if only not in label:
            continue
        extra = [f"shot.shots={n_shots}", "output.fields=[]", 'surfaces.0.material="turf"', *settings]
        scene = paper_scene(n_count, "float32", air=True, mu_s=0.5, extra=extra)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            started = time.perf_counter()
            wr.run(scene, device=device)
            compiled = time.perf_counter() - started
            print(f"{label}: the first run (compiling) took {compiled:.1f} s", flush=True)
            wp.synchronize_device(device)
            wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
            started = time.perf_counter()
            wr.run(scene, device=device)
            wp.synchronize_device(device)
            seconds = time.perf_counter() - started
            results = wp.timing_end()
        spent: dict = {}
        for r in results:
            total, launches = spent.get(r.name, (0.0, 0))
            spent[r.name] = (total + r.elapsed / 1e3, launches + 1)
        top = sorted(spent.items(), key=lambda kv: -kv[1][0])
        print(
            f"{label}: {n_shots:,} x {n_count:,} pellets, run {seconds:.2f} s (first run {compiled:.1f} s), kernels {sum(t for t, _ in spent.values()):.2f} s"
        )
        for name, (total, launches) in top[:8]:
            print(f"   {total:8.3f} s  {launches:6d} launches  {name[:110]}", flush=True)
        rows.append({"case": label, "seconds": seconds, "kernels": {k: v for k, v in top}})
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.rest", description=__doc__.split("\n")[0])
    parser.add_argument("what", choices=("throughput", "collisions", "kernels"))
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--sizes", default="1e5")
    parser.add_argument("--repeats", type=_count, default=3)
    parser.add_argument("--shots", type=_count, default=10_000)
    parser.add_argument("--count", type=_count, default=450)
    parser.add_argument("--only", default="", help="throughput, kernels: only the cases whose label holds this")
    parser.add_argument("--set", action="append", default=[], help="throughput: KEY=VALUE for every case (repeatable)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    _wr_mod, wp = _wr()
    info = device_info(wp, args.device)
    print(json.dumps(info), flush=True)
    if args.what == "throughput":
        rows = throughput(args.device, [int(float(s)) for s in args.sizes.split(",")], args.repeats, args.only, args.set)
    elif args.what == "kernels":
        rows = kernels(args.device, args.shots, args.count, args.only)
    else:
        rows = collisions(args.device, args.shots, args.count, args.repeats)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / f"rest-{args.what}.json").write_text(json.dumps({"device": info, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
