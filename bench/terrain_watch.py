"""The cost of the hazard along the path above a terrain (docs/hazard.md section 11, "Above a
terrain"), figures, not tests: the trap-field study's shot (examples/trap_field_study.py: #7.5 lead
at 400 m/s in sea-level air, turf, float64) followed to rest, statistics only, on the shipped raster
and on a level plane of turf, each without the watch (no threshold) and with it (the study's two
thresholds and its 5 m map: `trap_field_study.HAZARD`): pellets/s (the fastest of --repeats runs,
the four interleaved, after a warm-up) and the watch's cost over the run without it.

    python -m bench.terrain_watch [--n 1200] [--elevation 5 15] [--precision float64] [--device cpu] [--repeats 3]

Figures: bench/RESULTS.md, "The hazard along the path above a terrain".
"""

import argparse
import platform
import sys
import time
from pathlib import Path

import warp_ricochet as wr

ROOT = Path(__file__).resolve().parent.parent


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.terrain_watch", description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=1200)
    parser.add_argument("--elevation", type=float, nargs=2, default=(5.0, 15.0))
    parser.add_argument("--precision", default="float64", choices=("float32", "float64"))
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT / "examples"))
    from trap_field_study import scene as trap_scene

    from warp_ricochet.scene import scene_from_dict

    print(f"{args.n} pellets, elevation {args.elevation[0]:g}-{args.elevation[1]:g} deg, {args.precision}, [{args.device}]")
    print(f"  ({platform.processor() or platform.machine()}, one Warp CPU thread when on the CPU)")
    scenes = {}
    for level in (False, True):
        for watched in (False, True):
            raw = trap_scene(max(1, args.n // 300), tuple(args.elevation), hazard=True, level=level).to_dict()
            raw["numerics"] = {**raw.get("numerics", {}), "precision": args.precision}
            raw["output"] = {"fields": []}
            if not watched:  # (the landing map stays: it is counted either way)
                raw["hazard"] = {**raw["hazard"], "energy_density": [], "speed": []}
            scenes[level, watched] = scene_from_dict(raw)
            wr.run(scenes[level, watched], None, device=args.device)  # (warm-up: compilation)
    times = {key: [] for key in scenes}
    for _ in range(args.repeats):  # interleaved, the fastest of each kept: the machine is shared
        for key, scene in scenes.items():
            start = time.perf_counter()
            wr.run(scene, None, device=args.device)
            times[key].append(time.perf_counter() - start)
    for level in (False, True):
        name = "level plane" if level else "terrain"
        best = {watched: min(times[level, watched]) for watched in (False, True)}
        for watched in (False, True):
            label = "with the watch" if watched else "no watch"
            print(f"  {name}, {label}: {best[watched]:.3f} s, {args.n / best[watched]:.3g} pellets/s (fastest of {args.repeats})")
        print(f"  {name}: the watch costs {100 * (best[True] / best[False] - 1):+.0f}%")


if __name__ == "__main__":
    main()
