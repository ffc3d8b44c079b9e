"""Studies on Dask (issue 29, docs/cluster.md): what going through a cluster costs and gains.

    python -m bench.dask sweep [--points 16] [--shots 40] [--workers 2] [--device cpu] [--repeats 3]
    python -m bench.dask overhead [--study statistics|collisions] [--pellets N] [--shots N] [--split 4] [--device cuda:0]

`sweep`: a sweep of `--points` values of mu_s (the paper's scene, `--shots` shots of 450 pellets a
point, statistics only) run serially, then on a local cluster of `--workers` single-threaded
workers (a `LocalCUDACluster` on CUDA), median wall time of `--repeats` after a warm-up of each; the
results checked bitwise equal; and the scheduler's overhead per task: the round trip of `--tasks`
empty tasks, and the sweep's time against its tasks' own (each task times itself on its worker).

`overhead`: one run on a cluster of one worker against the same run direct in this process (the
issue's 5% goal on one GPU): `statistics`, `--pellets` pellets statistics-only (1e9 on a GPU), or
`collisions`, `--shots` shots of 450 pellets with pair collisions (10,000 on a GPU); the tasks the
cluster's run was cut into; and the direct run in the chunks of `--split` tasks' stretches (the
cost of cutting a run, without Dask). The cluster runs first and is closed before this process
touches Warp's device (a CUDA context made before it would put its worker on GPU 0).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def paper_scene(shots: int, count: int = 450, collisions: bool = False, pellets: int = 0, seed: int = 2021, air=False):
    """The paper's scene, statistics only: `shots` shots of `count` pellets (or `pellets` in one
    shot); `air`: in sea-level air."""
    import tomllib
    from pathlib import Path

    from warp_ricochet.scene import scene_from_dict

    raw = tomllib.loads((Path(__file__).resolve().parent.parent / "examples" / "paper.toml").read_text())
    if pellets:
        raw["shot"].update(count=int(pellets), shots=1, seed=seed)
    else:
        raw["shot"].update(count=count, shots=shots, seed=seed)
    raw["output"] = {"fields": []}
    if collisions:
        raw["collisions"] = {"enabled": True}
    if air:
        raw["air"] = {"density": 1.225}  # sea level, every other key its default (docs/air.md)
    return scene_from_dict(raw)


def _cluster(workers: int, device: str):
    from distributed import Client, LocalCluster

    if device.startswith("cuda"):
        try:
            from dask_cuda import LocalCUDACluster
        except ImportError:
            if workers != 1:
                raise
            print("dask-cuda is not installed: one worker process on the one GPU (a LocalCluster)")
            cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0")
            return cluster, Client(cluster)
        cluster = LocalCUDACluster(n_workers=workers, threads_per_worker=1, dashboard_address=":0")
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0")
    return cluster, Client(cluster)


def _timed(fn, repeats: int):
    fn()  # warm-up: kernels compiled or loaded, models built
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def _nothing(i):
    return i


def _same(a, b) -> bool:
    return all(a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]) for k in b)


def cmd_sweep(args) -> None:
    import warnings

    import warp_ricochet as wr
    from warp_ricochet import cluster as cl
    from warp_ricochet import tasks

    scene = paper_scene(args.shots, air=args.air)
    params = {"surfaces.0.mu_s": list(np.linspace(0.05, 0.5, args.points))}
    ties = [("surfaces.0.mu_d", 0.9, None)]
    warnings.simplefilter("ignore")
    spent: list[float] = []  # each task's own time on its worker
    real = tasks.run_range

    def timed_task(*a, **kw):
        start = time.perf_counter()
        out = real(*a, **kw)
        out.seconds = time.perf_counter() - start
        return out

    local, client = _cluster(args.workers, args.device)
    with local, client:
        cl.run_range = timed_task
        count = client.submit(_nothing, 0, pure=False).result()  # (workers up)
        start = time.perf_counter()
        count = sum(client.gather([client.submit(_nothing, i, pure=False) for i in range(args.tasks)]))
        empty = (time.perf_counter() - start) / args.tasks
        original_fold = cl.Study.result

        def result(self, future):
            part = original_fold(self, future)
            spent.append(part.seconds)
            return part

        cl.Study.result = result
        on_cluster, got = _timed(
            lambda: (spent.clear(), wr.sweep(scene, params, ties, device=args.device, client=client))[1], args.repeats
        )
        cl.Study.result, cl.run_range = original_fold, real
        ntasks = len(spent)
        task_time = sum(spent)
    serial, ref = _timed(lambda: wr.sweep(scene, params, ties, device=args.device), args.repeats)
    same = all(_same(dict(a), dict(b)) for (_, a), (_, b) in zip(ref, got))
    pellets = args.points * scene.shot.pellets
    where = "in air" if args.air else "in vacuum"
    print(
        f"device {args.device}; {args.points}-point sweep {where} of {scene.shot.pellets:,} pellets a point ({pellets:,} in all)"
    )
    print(f"serial           {serial:8.3f} s")
    print(f"{args.workers} workers        {on_cluster:8.3f} s  ({serial / on_cluster:.2f}x), bitwise equal: {same}")
    print(f"tasks            {ntasks} ({ntasks / args.points:g} a point), their own time {task_time:.3f} s in all")
    print(f"empty task       {1e3 * empty:8.3f} ms round trip ({args.tasks} tasks, {count} summed)")
    print(
        f"overhead a task  {1e3 * (on_cluster * args.workers - task_time) / ntasks:8.3f} ms "
        "(workers x wall time less the tasks' own, per task)"
    )


def cmd_overhead(args) -> None:
    import dataclasses
    import warnings

    import warp_ricochet as wr
    from warp_ricochet import cluster as cl
    from warp_ricochet import tasks

    warnings.simplefilter("ignore")
    if args.study == "collisions":
        scene = paper_scene(args.shots, collisions=True, air=args.air)
    else:
        scene = paper_scene(0, pellets=args.pellets, air=args.air)
    seen: list[tuple] = []  # the last run's tasks (start, stop)
    real = cl.Study.result

    def result(self, future):
        part = real(self, future)
        seen.append((part.start, part.stop))
        return part

    local, client = _cluster(1, args.device)
    with local, client:
        cl.Study.result = result
        on_cluster, got = _timed(lambda: (seen.clear(), wr.run(scene, device=args.device, client=client))[1], args.repeats)
        cl.Study.result = real
    direct, ref = _timed(lambda: wr.run(scene, device=args.device), args.repeats)
    print(f"device {args.device}; {args.study}: {scene.shot.pellets:,} pellets ({scene.shot.shots:,} shots)")
    print(f"direct           {direct:8.3f} s")
    print(f"1-worker cluster {on_cluster:8.3f} s  overhead {100 * (on_cluster / direct - 1):+.1f}%, {len(seen)} task(s) {seen}")
    print(f"bitwise equal    {_same(dict(ref), dict(got))}")
    if args.split > 1:  # the serial run in the chunks of `split` tasks: what cutting a run costs without Dask
        unit = tasks.unit_of(scene)
        size = tasks.task_bounds(0, scene.shot.pellets, unit, -(-scene.shot.pellets // args.split))[0][1]
        cut = scene.replace(numerics=dataclasses.replace(scene.numerics, chunk_size=size))
        split, _ = _timed(lambda: wr.run(cut, device=args.device), args.repeats)
        print(f"direct, chunks of {size:,} ({args.split} tasks' stretches) {split:8.3f} s  {100 * (split / direct - 1):+.1f}%")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(
        prog="python -m bench.dask", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("sweep")
    s.add_argument("--points", type=int, default=16)
    s.add_argument("--shots", type=int, default=40)
    s.add_argument("--workers", type=int, default=2)
    s.add_argument("--tasks", type=int, default=200, help="empty tasks timed")
    s.add_argument("--air", action="store_true", help="in sea-level air (about 1e5 pellets/s a CPU core)")
    s.add_argument("--device", default="cpu")
    s.add_argument("--repeats", type=int, default=3)
    s.set_defaults(func=cmd_sweep)
    o = sub.add_parser("overhead")
    o.add_argument("--study", choices=("statistics", "collisions"), default="statistics")
    o.add_argument("--pellets", type=float, default=1e7)
    o.add_argument("--shots", type=int, default=100)
    o.add_argument("--air", action="store_true", help="in sea-level air")
    o.add_argument("--device", default="cpu")
    o.add_argument("--repeats", type=int, default=3)
    o.add_argument("--split", type=int, default=4, help="also time the direct run in the chunks of this many tasks (0: not)")
    o.set_defaults(func=cmd_overhead)
    args = p.parse_args(argv)
    if getattr(args, "pellets", None) is not None:
        args.pellets = int(args.pellets)
    args.func(args)


if __name__ == "__main__":
    main()
