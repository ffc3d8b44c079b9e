"""Which shots keep the dense phase stepping: per-shot end of the dense phase for many shots of
the paper's scene, and the launch states of the longest shot (to study it alone on the CPU).

    python -m bench.collision_tail --shots 2223 --device cuda:0 --out DIR
"""

import argparse
import os

import numpy as np


def main():
    import h5py
    import warp as wp

    from tests.helpers import make_scene, paper_raw
    from warp_ricochet import api

    parser = argparse.ArgumentParser(prog="python -m bench.collision_tail")
    parser.add_argument("--shots", type=int, default=2223)
    parser.add_argument("--count", type=int, default=450)
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--precision", default="float32")
    parser.add_argument("--out", default="bench/results/collisions")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    raw = paper_raw()
    raw["shot"].update(count=args.count, shots=args.shots)
    raw["collisions"] = {"enabled": True}
    raw["output"] = {"fields": ["initial", "release.time", "collisions.count"]}
    scene = make_scene(raw, precision=args.precision)
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "tail-run.h5")
    stats = api.run(scene, output=path, device=args.device, overwrite=True)
    with h5py.File(path, "r") as f:
        end = f["pellets/release/time"][()].reshape(args.shots, args.count).max(axis=1)
        initial = {k: f["pellets/initial/" + k][()] for k in ("position", "velocity", "angular_velocity")}
    os.remove(path)
    order = np.argsort(end)[::-1]
    q = np.quantile(end, [0.5, 0.9, 0.99, 0.999, 1.0])
    print(f"dense phase end per shot (ms): median {q[0]*1e3:.2f}, p90 {q[1]*1e3:.2f}, p99 {q[2]*1e3:.2f}, "
          f"p99.9 {q[3]*1e3:.2f}, max {q[4]*1e3:.2f}; steps mean {stats['dense_steps_mean']:.0f} max "
          f"{stats['dense_steps_max']:.0f}")
    print("longest shots:", ", ".join(f"{s} ({end[s]*1e3:.1f} ms)" for s in order[:8]))
    tail = order[0]
    sl = slice(tail * args.count, (tail + 1) * args.count)
    np.savez(os.path.join(args.out, "tail-shot.npz"), **{k: v[sl] for k, v in initial.items()})
    np.save(os.path.join(args.out, "shot-end.npy"), end)


if __name__ == "__main__":
    main()
