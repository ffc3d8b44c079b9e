"""Run time against error of the phases along surfaces (`numerics.surface_tolerance`, docs/ground.md 9):
the paper's scene (mu_s 0.5) followed to rest, per ground, the surface tolerance varied alone (the
flight's stays at its default).

    python -m bench.surface_tolerance [--device cpu] [--n 2000] [--timed 20000] [--out DIR]

For each case and tolerance: the mean integration steps a pellet along surfaces, the seconds of a
statistics-only run of --timed pellets in float32 (median of 3 after a warm-up; process CPU time on
the CPU, which leaves out waits for a shared core), and each pellet's rest-position error against a
float64 run at a surface tolerance of 1e-10, over its path along surfaces (`rest.path_length`,
at least the pellet's radius): median, 99th percentile, largest, and the share above 1e-4 (the
accuracy issue 25 asks of the default); and the 99th percentile and largest over the larger of that
path and the distance from launch to rest (a lower bound of the whole path, whose flights add their
own error: float32 resolves 0.1 mm at 2 km). A pellet whose end differs in kind (its `rest.state` or its
impact count) is counted apart: its path has branched (an impact's outcome near a threshold).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.__main__ import _wr, device_info
from bench.air import paper_scene
from bench.dask import _count

CASES = (
    ("air, rest, turf", True, ('surfaces.0.material="turf"',)),
    ("air, rest, packed soil", True, ('surfaces.0.material="packed_soil"',)),
    ("air, rest, rigid plane (c = 0)", True, ()),
    ("vacuum, rest, turf", False, ('surfaces.0.material="turf"',)),
)
TOLERANCES = (1e-8, 1e-6, 3e-6, 1e-5, 3e-5, 1e-4, 3e-4, 1e-3)
REFERENCE = 1e-10
FIELDS = ("rest.position", "rest.path_length", "rest.state", "rest.impacts", "initial.position")
RADIUS = 1.2e-3  # m: the floor of the path in the error's denominator (about the paper's pellet radius)


def _scene(n, air, extra, precision, tolerance):
    sets = ['physics.until="rest"', f"numerics.surface_tolerance={tolerance}", *extra]
    return paper_scene(n, precision, air=air, mu_s=0.5, extra=sets)


def _pellets(wr, scene, device, folder: Path, name: str):
    import h5py

    path = folder / f"{name}.h5"
    scene = _scene_with_path(scene, path)
    stats = wr.run(scene, device=device, overwrite=True)
    with h5py.File(path, "r") as f:
        out = {k: f[f"pellets/{k.replace('.', '/')}"][()] for k in FIELDS}
    return stats, out


def _scene_with_path(scene, path):
    import dataclasses

    return dataclasses.replace(scene, output=dataclasses.replace(scene.output, path=str(path), fields=FIELDS))


def _errors(out, ref) -> dict:
    same = (out["rest.state"] == ref["rest.state"]) & (out["rest.impacts"] == ref["rest.impacts"])
    moved = np.linalg.norm(out["rest.position"].astype(np.float64) - ref["rest.position"], axis=1)
    rel = moved[same] / np.maximum(ref["rest.path_length"][same], RADIUS)
    travel = np.linalg.norm(ref["rest.position"] - ref["initial.position"], axis=1)
    whole = moved[same] / np.maximum(np.maximum(ref["rest.path_length"], travel)[same], RADIUS)
    return {
        "branched": int((~same).sum()),
        "travel_p99": float(np.quantile(whole, 0.99)),
        "travel_max": float(whole.max()),
        "median": float(np.median(rel)),
        "p99": float(np.quantile(rel, 0.99)),
        "max": float(rel.max()),
        "above_1e-4": float((rel > 1e-4).mean()),
    }


def _timed(wr, wp, scene, device, repeats=3):
    wr.run(scene, device=device)
    times = []
    clock = time.process_time if device == "cpu" else time.perf_counter
    for _ in range(repeats):
        t0 = clock()
        wr.run(scene, device=device)
        wp.synchronize_device(device)
        times.append(clock() - t0)
    return float(np.median(times))


def study(device, n, timed, only=""):
    wr, wp = _wr()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for label, air, extra in CASES:
            if only not in label:
                continue
            _stats, ref = _pellets(wr, _scene(n, air, extra, "float64", REFERENCE), device, folder, "ref")
            for precision in ("float64", "float32"):
                for tol in TOLERANCES:
                    if precision == "float32" and tol < 1e-6:
                        continue
                    stats, out = _pellets(wr, _scene(n, air, extra, precision, tol), device, folder, "run")
                    row = {"case": label, "precision": precision, "tolerance": tol, "steps": float(stats["rest_steps_mean"])}
                    row |= _errors(out, ref)
                    if precision == "float32" and timed:
                        seconds = _timed(wr, wp, _scene(timed, air, extra, precision, tol), device)
                        row |= {"seconds": seconds, "pellets_per_s": timed / seconds}
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.surface_tolerance", description=__doc__.split("\n")[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--n", type=_count, default=2000)
    parser.add_argument("--timed", type=int, default=20_000, help="pellets of the timed runs (0: none)")
    parser.add_argument("--only", default="")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    _wr_mod, wp = _wr()
    info = device_info(wp, args.device)
    print(json.dumps(info), flush=True)
    rows = study(args.device, args.n, args.timed, args.only)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "surface-tolerance.json").write_text(json.dumps({"device": info, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
