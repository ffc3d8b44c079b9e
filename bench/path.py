"""The hazard watched along the path (docs/hazard.md, "The hazard along the path"): its cost beside
the same statistics-only run followed to rest without it, in one run, and a device's per-pellet
reach and maps for a comparison with the CPU's, and the ways the watch can be given its steps compared.

    python -m bench.path cost [--device cuda:0] [--sizes 1e8,1e9] [--repeats 2] [--out DIR]
    python -m bench.path check [--device cuda:0] [--count 20000] [--out DIR]
    python -m bench.path logs [--device cuda:0] [--count 20000]

`cost`: the paper's scene in sea-level air (examples/paper.toml, mu_s 0.5, float32) followed to
rest on a plane with rolling resistance 0.05, statistics only: without a [hazard] table (no
thresholds: the watch compiled away), with the four default thresholds (reach and its histograms),
and with them and a map of 0.5 m cells over 0-400 m downrange and 50 m either side (passes by level,
160,000 cells). Each row: seconds (median of --repeats after a warm-up), pellets/s and the cost
over the run without the hazard. `check`: `count` pellets of that scene in float64 with per-pellet
reach and the maps, written to DIR/check-DEVICE.npz. `logs`: the step log (`physics.line_log`;
logs of 3 and 32 steps) and the watch replayed after the core (`tallies.path_replay`; with columns of
COLUMN_WORDS and of 64 words, where pellets overflow and are followed again) against each step watched at once (log size 0, no
replay), on one device, float32: that scene with the map, on rough ground (the reach alone) and with
pair collisions (shots of 200): per-pellet reach and rest positions and the maps, bit for bit or the
differences (on a GPU, where threads sharing a column would race; a CPU runs a kernel's threads one
after another).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from bench.__main__ import _timed, _wr, device_info
from bench.air import paper_scene

BASE = ('physics.until="rest"', "surfaces.0.rolling_resistance=0.05")
HAZARD = ("hazard.fractions=[1e-3, 1e-6]",)
MAP = ("hazard.map_cell=0.5", "hazard.map_extent=[0.0, 400.0, -50.0, 50.0]")
CASES = (("to rest, no hazard", ()), ("to rest, reach", HAZARD), ("to rest, reach + map", HAZARD + MAP))


def cost(device, sizes, repeats):
    wr, wp = _wr()
    rows = []
    for n in sizes:
        base = None
        for label, extra in CASES:
            settings = [*BASE, *extra]
            started = time.perf_counter()
            wr.run(paper_scene(1000, air=True, mu_s=0.5, extra=settings), device=device)  # compile
            print(f"{label:24s} compiled and ran 1000 pellets in {time.perf_counter() - started:.1f} s", flush=True)
            scene = paper_scene(n, air=True, mu_s=0.5, extra=settings)
            t, times = _timed(lambda scene=scene: (wr.run(scene, device=device), wp.synchronize_device(device)), repeats)
            base = t if base is None else base
            row = {"case": label, "N": n, "seconds": t, "runs": times, "pellets_per_s": n / t, "over_base": t / base - 1.0}
            rows.append(row)
            print(
                f"{label:24s} N {n:.0e}: {t:8.3f} s, {n / t:.3e} pellets/s, {100 * row['over_base']:+.1f}% over no hazard",
                flush=True,
            )
    return rows


def check(device, count, out):
    wr, _wp = _wr()
    import h5py

    scene = paper_scene(count, "float64", air=True, mu_s=0.5, fields=("hazard", "rest"), extra=[*BASE, *HAZARD, *MAP])
    path = Path(out or ".") / f"check-{device.replace(':', '')}.h5"
    wr.run(scene, path, device=device, overwrite=True)
    with h5py.File(path, "r") as f:
        arrays = {
            "reach": f["pellets/hazard/reach"][()],
            "rest": f["pellets/rest/position"][()],
            "passes": f["hazard/map/passes"][()],
            "exposure": f["hazard/map/exposure"][()],
            "danger": f["hazard/danger_distance/distance"][()],
        }
    path.unlink()
    np.savez_compressed(Path(out or ".") / f"check-{device.replace(':', '')}.npz", **arrays)
    print(f"{device}: {count} pellets, passes {arrays['passes'].sum():,}, danger distances {arrays['danger'].ravel()}")


LOG_CASES = {  # (settings, pellets of each shot: `count` in all)
    "map": ((*BASE, *HAZARD, *MAP), None),
    "rough, reach": ((*BASE, *HAZARD, "surfaces.0.roughness=0.3"), None),
    "collisions, map": ((*BASE, *HAZARD, *MAP, "collisions.enabled=true"), 200),
}
LOG_KEYS = ("pellets/hazard/reach", "pellets/rest/position", "hazard/map/passes", "hazard/map/exposure")


def logs(device, count, out):
    """Each LOG_CASES scene watched at once (log size 0, no replay), with logs of 3 and the default
    size, and replayed (columns of the default and of 64 words): the same bits, or the differences.
    Returns {case: {way: 'bitwise' or the differences}}."""
    wr, _wp = _wr()
    import tempfile

    import h5py

    from warp_ricochet.physics import line_log
    from warp_ricochet.tallies import path_replay

    default, found = line_log.LOG_STEPS, {}
    ways = {"at once": (0, "never", None), "log 3": (3, "never", None), f"log {default}": (default, "never", None)}
    ways |= {"replay": (default, "always", None), "replay, rerun": (default, "always", 64)}
    saved = (path_replay.REPLAY, path_replay.COLUMN_WORDS)
    folder = Path(out or tempfile.mkdtemp())
    for case, (settings, shot) in LOG_CASES.items():
        extra = [*settings] + ([f"shot.shots={count // shot}"] if shot else [])
        outputs = {}
        for way, (size, replay, words) in ways.items():
            line_log.LOG_STEPS, path_replay.REPLAY = size, replay
            path_replay.COLUMN_WORDS = words or saved[1]
            try:
                scene = paper_scene(shot or count, air=True, mu_s=0.5, fields=("hazard", "rest"), extra=extra)
                path = folder / "logs.h5"
                wr.run(scene, path, device=device, overwrite=True)
            finally:
                line_log.LOG_STEPS = default
                path_replay.REPLAY, path_replay.COLUMN_WORDS = saved
            with h5py.File(path, "r") as f:
                outputs[way] = {key: f[key][()] for key in LOG_KEYS if key in f}
            path.unlink()
        found[case] = {way: _differences(outputs["at once"], outputs[way]) for way in list(ways)[1:]}
        for way, verdict in found[case].items():
            print(f"{case:16s} {way:16s} against each step at once: {verdict}", flush=True)
    return found


def _differences(a, b) -> str:
    """'bitwise', or per array the elements that differ and the largest difference."""
    out = []
    for key, x in a.items():
        y = b[key]
        if not np.array_equal(x, y, equal_nan=True):
            both = np.isfinite(x) & np.isfinite(y)
            worst = np.abs(x[both].astype(np.float64) - y[both]).max(initial=0.0)
            out.append(f"{key}: {int((x != y).sum() - (np.isnan(x) & np.isnan(y)).sum())} differ (max {worst:.3g})")
    return "bitwise" if not out else "; ".join(out)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.path", description=__doc__.split("\n")[0])
    parser.add_argument("what", choices=("cost", "check", "logs"))
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--sizes", default="1e6")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--count", type=int, default=20_000)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    _wr_mod, wp = _wr()
    info = device_info(wp, args.device)
    print(json.dumps(info), flush=True)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
    if args.what == "check":
        check(args.device, args.count, args.out)
        return
    if args.what == "logs":
        logs(args.device, args.count, args.out)
        return
    rows = cost(args.device, [int(float(s)) for s in args.sizes.split(",")], args.repeats)
    if args.out:
        (args.out / "path-cost.json").write_text(json.dumps({"device": info, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
