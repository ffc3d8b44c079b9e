"""Studies on Dask (issue 29, docs/cluster.md): what going through a cluster costs and gains.

    python -m bench.dask sweep [--points 16] [--shots 40] [--workers 2] [--device cpu] [--repeats 3]
    python -m bench.dask overhead [--study statistics|collisions] [--pellets N] [--shots N] [--split 4] [--device cuda:0]
    python -m bench.dask trace [--pellets 1e9] [--device cuda:0]
    python -m bench.dask scaling --study collisions|sweep-rest|statistics|exposure [--workers 1,2] [--device cuda:0]

`sweep`: a sweep of `--points` values of mu_s (the paper's scene, `--shots` shots of 450 pellets a
point, statistics only) run serially, then on a local cluster of `--workers` single-threaded
workers (a `LocalCUDACluster` on CUDA), median wall time of `--repeats` after a warm-up of each; the
results checked bitwise equal; and the scheduler's overhead per task: the round trip of `--tasks`
empty tasks, and the sweep's time against its tasks' own (each task times itself on its worker).

`overhead`: one run on a cluster of one worker against the same run direct in this process (the
issue's 5% goal on one GPU): `statistics`, `--pellets` pellets statistics-only (1e9 on a GPU), or
`collisions`, `--shots` shots of 450 pellets with pair collisions (10,000 on a GPU); the tasks the
cluster's run was cut into; and the direct run in the chunks of `--split` tasks' stretches (the
cost of cutting a run, without Dask). Each timed run follows a `--pause` (a run on its own: the
client's batched stream holds a submission for up to 10 ms after its last message), and the
cluster's runs are also timed back to back. The cluster runs first and is closed before this process
touches Warp's device (a CUDA context made before it would put its worker on GPU 0).

`scaling` (issue 30, several GPUs of one host): one study on local clusters of each of `--workers`
workers in turn (`warp_ricochet.cluster.session`: a `LocalCUDACluster`, one worker a GPU, on CUDA),
then (`--direct`) the same study direct in this process: median wall time of `--repeats` after a
warm-up (the cluster's start not counted), the speed-up and scaling efficiency against the first
worker count, and the results checked bitwise equal. Studies: `collisions`, `--shots` shots of 450
in sea-level air with pair collisions (`--rest`: followed to rest on turf); `sweep-rest`, the
paper's scene in air followed to rest on turf at `--points` (a square number) points of mu_s x
muzzle speed, `--pellets` a point; `statistics`, `--points` runs of `--pellets` in vacuum (a sweep
of mu_s); `exposure`, the same in air to rest with the hazard along the path and its exposure map
(`bench.path`'s map of 0.5 m cells).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
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


def _timed(fn, repeats: int, warm: bool = True, pause: float = 0.0):
    """(median seconds, last result) of `repeats` calls of `fn`, each after `pause` seconds (not
    timed), after a warm-up call."""
    if warm:
        fn()  # warm-up: kernels compiled or loaded, models built
    times, result = [], None
    for _ in range(repeats):
        time.sleep(pause)
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def _visible():
    import os

    return os.environ.get("CUDA_VISIBLE_DEVICES", "(all)")


def _nothing(i):
    return i


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
    same = _same_study(ref, got)
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
        run = lambda: (seen.clear(), wr.run(scene, device=args.device, client=client))[1]  # noqa: E731
        on_cluster, got = _timed(run, args.repeats, pause=args.pause)
        back_to_back, _ = _timed(run, args.repeats, warm=False)
        cl.Study.result = real
    direct, ref = _timed(lambda: wr.run(scene, device=args.device), args.repeats, pause=args.pause)
    print(f"device {args.device}; {args.study}: {scene.shot.pellets:,} pellets ({scene.shot.shots:,} shots)")
    print(f"direct           {direct:8.3f} s")
    print(f"1-worker cluster {on_cluster:8.3f} s  overhead {100 * (on_cluster / direct - 1):+.1f}%, {len(seen)} task(s) {seen}")
    print(f"  back to back   {back_to_back:8.3f} s  overhead {100 * (back_to_back / direct - 1):+.1f}% (no pause between runs)")
    print(f"bitwise equal    {_equal(ref, got)}")
    if args.split > 1:  # the serial run in the chunks of `split` tasks: what cutting a run costs without Dask
        unit = tasks.unit_of(scene)
        size = tasks.task_bounds(0, scene.shot.pellets, unit, -(-scene.shot.pellets // args.split))[0][1]
        cut = scene.replace(numerics=dataclasses.replace(scene.numerics, chunk_size=size))
        split, _ = _timed(lambda: wr.run(cut, device=args.device), args.repeats)
        print(f"direct, chunks of {size:,} ({args.split} tasks' stretches) {split:8.3f} s  {100 * (split / direct - 1):+.1f}%")


def _equal(a, b) -> bool:
    """Bitwise equal statistics (dicts of numbers or arrays; NaN equal to NaN)."""
    a, b = dict(a), dict(b)
    if a.keys() != b.keys():
        return False
    for k in a:
        x, y = np.asarray(a[k]), np.asarray(b[k])
        if x.shape != y.shape or x.dtype.kind != y.dtype.kind:
            return False
        if x.dtype.kind == "f":
            if not np.array_equal(x, y, equal_nan=True):  # (NaN == NaN; otherwise == on floats is bitwise but for 0.0 and -0.0)
                return False
        elif not np.array_equal(x, y):
            return False
    return True


def _same_study(a, b) -> bool:
    if isinstance(a, list):  # a sweep: [(point, stats)]
        return len(a) == len(b) and all(pa == pb and _equal(sa, sb) for (pa, sa), (pb, sb) in zip(a, b))
    return _equal(a, b)


def scaling_study(args):
    """(what, pellets, fn(client=None)): the study `bench.dask scaling` times."""
    import warp_ricochet as wr
    from bench.air import paper_scene as scene_of

    rest = ['physics.until="rest"', 'surfaces.0.material="turf"']
    if args.study == "collisions":
        extra = [f"shot.shots={args.shots}", "collisions.enabled=true", *(rest if args.rest else [])]
        scene = scene_of(450, air=True, mu_s=0.5, extra=extra)
        what = f"{args.shots:,} shots of 450 in air with collisions" + (", to rest on turf" if args.rest else "")
        return what, scene.shot.pellets, lambda client=None: wr.run(scene, device=args.device, client=client)
    side = max(1, round(args.points**0.5))
    if args.study == "sweep-rest":
        scene = scene_of(args.pellets, air=True, mu_s=0.5, extra=rest)
        params = {"surfaces.0.mu_s": list(np.linspace(0.1, 0.5, side)), "shot.speed": list(np.linspace(300.0, 450.0, side))}
        what = f"{side * side}-point sweep (mu_s x speed) in air to rest on turf, {args.pellets:,} pellets a point"
    else:
        from bench.path import BASE, HAZARD, MAP

        map_ = [*BASE, *HAZARD, *MAP] if args.study == "exposure" else []
        scene = scene_of(args.pellets, air=args.study == "exposure", mu_s=0.5, extra=map_)
        params = {"surfaces.0.mu_s": list(np.linspace(0.1, 0.5, args.points))}
        what = f"{args.points} runs of {args.pellets:,} pellets, " + (
            "in air to rest with the exposure map" if map_ else "statistics only in vacuum"
        )
        side = args.points
    ties = [("surfaces.0.mu_d", 0.9, "surfaces.0.mu_s")]
    points = side * side if args.study == "sweep-rest" else side
    return what, points * args.pellets, lambda client=None: wr.sweep(scene, params, ties, device=args.device, client=client)


def cmd_scaling(args) -> None:
    import warnings

    from warp_ricochet.cluster import session

    warnings.simplefilter("ignore")
    what, pellets, study = scaling_study(args)
    print(f"device {args.device}; {what} ({pellets:,} pellets)", flush=True)
    rows, first = [], None
    for n in args.workers:
        with session(cluster=f"local:{n}", device=args.device) as client:
            seen = client.run(_visible)
            print(f"{n} worker(s), CUDA_VISIBLE_DEVICES: {sorted(seen.values())}", flush=True)
            started = time.perf_counter()
            study(client)
            warm = time.perf_counter() - started
            seconds, got = _timed(lambda client=client: study(client), args.repeats, warm=False)
        first = got if first is None else first
        rows.append((f"{n} worker(s)", n, seconds, got))
        print(f"{n} worker(s): warm-up {warm:.2f} s, then {seconds:.3f} s", flush=True)
    if args.direct:
        seconds, got = _timed(lambda: study(None), args.repeats)
        rows.append(("direct", 1, seconds, got))
    base_n, base_t = rows[0][1], rows[0][2]
    for label, n, seconds, got in rows:
        speedup = base_t / seconds
        print(
            f"{label:14s} {seconds:9.3f} s  {pellets / seconds:.3e} pellets/s  speed-up {speedup:5.2f}x  "
            f"efficiency {100 * speedup * base_n / n:5.1f}%  bitwise equal to {rows[0][0]}: {_same_study(first, got)}"
        )


_PHASES: dict = {}


def _traced_range(*args, **kwargs):
    """`tasks.run_range` on a worker, with the seconds of its phases (`bench.dask trace`)."""
    from warp_ricochet import pipeline, tasks

    if not _PHASES.get("patched"):
        for name in ("make_stage", "_loop"):
            real = getattr(pipeline, name)

            def timed(*a, _real=real, _name=name, **kw):
                start = time.perf_counter()
                try:
                    return _real(*a, **kw)
                finally:
                    _PHASES[_name] = _PHASES.get(_name, 0.0) + time.perf_counter() - start

            setattr(pipeline, name, timed)
        _PHASES["patched"] = True
    for name in ("make_stage", "_loop"):
        _PHASES[name] = 0.0
    started = time.time()
    part = tasks.run_range(*args, **kwargs)
    part.trace = {"start": started, "end": time.time(), **{k: _PHASES[k] for k in ("make_stage", "_loop")}}
    return part


def cmd_trace(args) -> None:
    """Where a statistics-only run's time goes through a one-worker cluster: per task, when the
    worker began and ended it (from the client's submission), its stage's build and its chunk loop,
    and when the client had its result; then the study's end."""
    import warnings

    import warp_ricochet as wr
    from warp_ricochet import cluster as cl
    from warp_ricochet.cluster import session

    warnings.simplefilter("ignore")
    scene = paper_scene(0, pellets=args.pellets)
    got: list = []
    real_result = cl.Study.result

    def result(self, future):
        part = real_result(self, future)
        got.append((part, time.time()))
        return part

    with session(cluster="local:1", device=args.device) as client:
        cl.run_range, cl.Study.result = _traced_range, result
        for repeat in range(args.repeats + 1):
            got.clear()
            time.sleep(0.05)
            t0 = time.time()
            wr.run(scene, device=args.device, client=client)
            t1 = time.time()
            ms = lambda t: 1e3 * (t - t0)  # noqa: E731
            print(f"run {repeat} ({'warm-up' if repeat == 0 else 'timed'}): {ms(t1):.1f} ms")
            for part, arrived in got:
                tr = part.trace
                print(
                    f"  task [{part.start:,}, {part.stop:,}): worker {ms(tr['start']):7.1f} -> {ms(tr['end']):7.1f} ms "
                    f"(stage {1e3 * tr['make_stage']:.1f} ms, loop {1e3 * tr['_loop']:.1f} ms), "
                    f"result at the client {ms(arrived):7.1f} ms"
                )
    for repeat in range(args.repeats + 1):
        time.sleep(0.05)
        t0 = time.perf_counter()
        part = _traced_range(scene, args.device, 0, scene.shot.pellets)
        print(
            f"direct range {repeat}: {1e3 * (time.perf_counter() - t0):.1f} ms (stage {1e3 * part.trace['make_stage']:.1f} ms, "
            f"loop {1e3 * part.trace['_loop']:.1f} ms)"
        )
        t0 = time.perf_counter()
        wr.run(scene, device=args.device)
        print(f"direct run {repeat}: {1e3 * (time.perf_counter() - t0):.1f} ms")


class _Parser(argparse.ArgumentParser):
    """argparse, its usage errors as one line (`python -m bench.dask ...: error: ...`), exit 2."""

    def error(self, message):
        print(f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)", file=sys.stderr)
        raise SystemExit(2)


MAX_COUNT = 2**31 - 1  # (a scene's shot.count and shot.shots: int32)


def _count(text: str, top: int = MAX_COUNT) -> int:
    """A whole number in [1, top], also written as a float (1e5)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and 1 <= value <= top and value == int(value)):
        raise argparse.ArgumentTypeError(f"{text!r}: must be a whole number in [1, {top}]")
    return int(value)


def _shots(text: str) -> int:
    """Shots of 450 pellets: at most MAX_COUNT pellets in all."""
    return _count(text, MAX_COUNT // 450)


def _counts(text: str) -> list[int]:
    """Comma-separated whole numbers >= 1 (worker counts)."""
    return [_count(part) for part in text.split(",")]


def check_scaling(args) -> None:
    """Refuse in one line (SceneError), before any cluster starts, what `scaling` cannot run: a
    worker count no local cluster takes (`cluster.parse_cluster`), a sweep of more points than a
    sweep takes or (sweep-rest) of a non-square number, --rest without the collisions study."""
    from warp_ricochet.cluster import parse_cluster
    from warp_ricochet.errors import SceneError
    from warp_ricochet.scene.sweep import MAX_SWEEP_POINTS

    for n in args.workers:
        parse_cluster(f"local:{n}")
    if args.study != "collisions" and args.points > MAX_SWEEP_POINTS:
        raise SceneError("--points", args.points, f"must be at most {MAX_SWEEP_POINTS:,} (a sweep's points)")
    if args.study == "sweep-rest" and math.isqrt(args.points) ** 2 != args.points:
        raise SceneError("--points", args.points, "must be a square number for --study sweep-rest (mu_s x speed), e.g. 64")
    if args.rest and args.study != "collisions":
        raise SceneError("--rest", True, f"is for --study collisions; --study {args.study} does not take it")


def main(argv=None) -> None:
    p = _Parser(prog="python -m bench.dask", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
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
    o.add_argument("--pause", type=float, default=0.05, help="seconds between timed runs (a run alone; also timed without)")
    o.add_argument("--split", type=int, default=4, help="also time the direct run in the chunks of this many tasks (0: not)")
    o.set_defaults(func=cmd_overhead)
    c = sub.add_parser("scaling")
    c.add_argument("--study", choices=("collisions", "sweep-rest", "statistics", "exposure"), default="collisions")
    c.add_argument("--workers", type=_counts, default=[1, 2])
    c.add_argument("--shots", type=_shots, default=10000)
    c.add_argument("--rest", action="store_true", help="collisions: followed to rest on turf")
    c.add_argument("--points", type=_count, default=64)
    c.add_argument("--pellets", type=_count, default=100_000)
    c.add_argument("--direct", action="store_true", help="also the study direct in this process (last)")
    c.add_argument("--device", default="cuda:0")
    c.add_argument("--repeats", type=_count, default=2)
    c.set_defaults(func=cmd_scaling, check=check_scaling)
    t = sub.add_parser("trace")
    t.add_argument("--pellets", type=float, default=1e9)
    t.add_argument("--device", default="cuda:0")
    t.add_argument("--repeats", type=int, default=2)
    t.set_defaults(func=cmd_trace)
    args = p.parse_args(argv)
    if getattr(args, "pellets", None) is not None:
        args.pellets = int(args.pellets)
    from warp_ricochet.errors import RicochetError

    try:
        if getattr(args, "check", None) is not None:
            args.check(args)
        args.func(args)
    except RicochetError as exc:  # (a scene the options make that is not valid: its one line)
        print(f"{p.prog} {args.command}: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
