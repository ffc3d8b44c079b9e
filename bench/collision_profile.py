"""Where the dense phase spends its time: wall time of the list rebuilds, the blocks of steps and
the checkpoints (survey, horizon, settle and the host's read of three flags), each timed with a
device synchronisation around it (so the total is a little above an unprofiled run).

    python -m bench.collision_profile [--shots 2223] [--count 450] [--device cuda:0] [--rounds 4]
"""

import argparse
import time
from collections import defaultdict

import numpy as np


def main():
    import warp as wp

    from tests.helpers import make_scene, paper_raw
    from warp_ricochet import api
    from warp_ricochet.collisions import DensePhase

    parser = argparse.ArgumentParser(prog="python -m bench.collision_profile")
    parser.add_argument("--shots", type=int, default=2223)
    parser.add_argument("--count", type=int, default=450)
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--precision", default="float32")
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--skin", type=float, default=2.0)
    parser.add_argument("--step-fraction", type=float, default=0.25)
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    raw = paper_raw()
    raw["shot"].update(count=args.count, shots=args.shots)
    raw["collisions"] = {"enabled": True, "rounds": args.rounds, "skin": args.skin,
                         "step_fraction": args.step_fraction}
    scene = make_scene(raw, precision=args.precision)
    api.run(scene, device=args.device)  # warm
    spent, calls = defaultdict(float), defaultdict(int)
    device = wp.get_device(args.device)

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

    originals = {name: getattr(DensePhase, name) for name in ("_rebuild", "_block", "_launch")}
    DensePhase._rebuild = timed("rebuild (grid points, HashGrid.build, neighbours)", originals["_rebuild"])
    DensePhase._block = timed("block of steps (graph or replay)", originals["_block"])
    other = timed("other launches (launch, drift, survey, horizon, settle, release, totals)", originals["_launch"])

    def launch(self, name, *a, **k):  # the rebuild's own launches are timed with it
        return (originals["_launch"] if name in ("grid_points", "neighbours") else other)(self, name, *a, **k)

    DensePhase._launch = launch
    start = time.perf_counter()
    stats = api.run(scene, device=args.device)
    total = time.perf_counter() - start
    for name in originals:
        setattr(DensePhase, name, originals[name])
    print(f"{args.device} {args.precision} {args.shots} x {args.count}, rounds {args.rounds}, skin {args.skin}, "
          f"step fraction {args.step_fraction}: "
          f"{total:.3f} s, steps {stats['dense_steps_max']:.0f} (mean {stats['dense_steps_mean']:.0f})")
    for name in spent:
        print(f"  {name:75s} {spent[name]:8.3f} s  {calls[name]:6d} calls  {spent[name] / calls[name] * 1e3:8.3f} ms each")
    print(f"  {'rest (sampling, flight kernel, statistics, host)':75s} {total - sum(spent.values()):8.3f} s")


if __name__ == "__main__":
    main()
