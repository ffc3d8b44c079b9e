"""Studies on Dask (`distributed`): a run's or a sweep's pellets as tasks on a cluster's workers,
folded on the client in the serial run's order (docs/cluster.md).

`session` starts a `LocalCluster` (a `LocalCUDACluster` from dask-cuda, one worker a GPU, when the
device is CUDA) or reaches an existing scheduler, before this process touches Warp: a CUDA context
made first would put every worker on GPU 0. `Study` submits each run's stretches (`tasks.run_range`)
and folds what they return as the chunk loop folds its chunks (`pipeline._loop`): the segments'
statistics partials in segment order, the shots' tables and per-shot partials in shot order, the
landing counts (int64) summed, a station run's pieces and a bounded run's checks at their ends;
so `/stats`, tallies and maps are bitwise those of the serial run on the same kind of device, for
any number of workers. The writer receives each task's results in order, as a chunk's; per-pellet
fields go from the workers to shards the run file reads as virtual datasets (`io.shards`)."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import os
import re

import numpy as np

from . import interrupts
from .errors import RicochetError, SceneError
from .tasks import Partial, chunk_of, describe_device, release, run_range, task_bounds, task_size, unit_of

log = logging.getLogger(__name__)

TASKS_PER_WORKER = 4  # stretches a run is cut into, per worker (a killed worker's task is redone), each a chunk at least
CONNECT_TIMEOUT = "10s"  # how long a scheduler is given to answer
QUIET = logging.CRITICAL  # a local cluster's own logs: a task's error reaches the user as one line, not the worker's traceback
NO_DASK_CUDA = "one worker a GPU needs dask-cuda (pip install 'warp-ricochet[dask-cuda]')"


@dataclasses.dataclass(frozen=True)
class RemoteDevice:
    """A worker's device as the client's checks and files need it (`tasks.describe_device`):
    str() its alias, as a Warp device's."""

    alias: str
    name: str
    is_cuda: bool
    free_memory: int  # (with the buffers the worker keeps from its last run: `chunks.free_device_bytes`)
    remote = True  # (its kept buffers are the worker's, counted in free_memory)

    def __str__(self) -> str:
        return self.alias


def refuse(scene, output=None) -> None:
    """Refuse in one line what a cluster does not run yet: H5MD frames written to `output` (without
    an output none is computed)."""
    if output is not None and scene.pair_collisions and scene.collisions.frame_every:
        raise SceneError("collisions.frame_every", scene.collisions.frame_every, "must be 0 on a cluster (H5MD frames)")


def parse_cluster(value: str) -> int:
    """Workers of `--cluster local:N` (1 <= N <= this machine's cores: each worker is a
    single-threaded process, and a huge N would exhaust the memory); else one line (SceneError)."""
    found = re.fullmatch(r"local:(\d+)", str(value).strip())
    cores = os.cpu_count() or 1
    if found is None or not 1 <= int(found.group(1)) <= cores:
        raise SceneError("--cluster", value, f"must be local:N, 1 <= N <= {cores} workers (this machine's cores)")
    return int(found.group(1))


def check_device(device) -> None:
    """Refuse (SceneError) a `--device` no worker can have, before a cluster starts: Warp's
    devices are cpu, cuda and cuda:N (whether the workers have it, only they can say)."""
    if device is not None and re.fullmatch(r"cpu|cuda(:\d+)?", str(device)) is None:
        raise SceneError("--device", device, "must be cpu, cuda or cuda:N (N: a GPU's number)")


def _probe(address: str, seconds: float) -> None:
    """Refuse (SceneError) an address that does not answer Dask's `identity` as a scheduler within
    `seconds`: `distributed.Client` waits forever on a port that accepts but never answers (an
    HTTP server), past its own timeout and deaf to Ctrl-C."""

    async def identity():
        from distributed.comm import connect

        comm = await connect(address, timeout=seconds)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(identity(), seconds + 1))  # (connect times out first)
    except Exception as exc:  # (whatever the peer sends: msgpack's errors, a closed stream)
        why = " ".join(str(exc).split())[:160] or f"no Dask scheduler answered within {seconds:g} s"
        raise SceneError("--scheduler", address, f"cannot be reached ({why})") from None
    kind = reply.get("type") if isinstance(reply, dict) else None
    if kind != "Scheduler":
        raise SceneError("--scheduler", address, f"is not a Dask scheduler (it answers as {kind or 'something else'})")


def _cuda_wanted(device) -> bool:
    """Whether a local cluster's workers are to hold GPUs: a CUDA device named, or none named and
    dask-cuda finds GPUs (through NVML: no CUDA context here)."""
    if device is not None:
        return str(device).startswith("cuda")
    try:
        from dask_cuda.utils import get_n_gpus
    except ImportError:
        return False
    try:
        return get_n_gpus() > 0
    except Exception:
        return False


@contextlib.contextmanager
def session(cluster=None, scheduler=None, device=None, announce=None):
    """A `distributed.Client`: on a new local cluster of `cluster` ("local:N"), or on the scheduler
    at `scheduler`; a scheduler that does not answer: one line (SceneError), before any work. The
    dashboard's address is written to `announce` (a stream) when given. Both closed at the end."""
    try:
        from dask.utils import parse_timedelta
        from distributed import Client, LocalCluster
    except ImportError:
        raise SceneError(
            "--cluster" if cluster is not None else "--scheduler",
            cluster or scheduler,
            "needs Dask's distributed (pip install 'warp-ricochet[dask]')",
        ) from None
    check_device(device)
    with contextlib.ExitStack() as stack:
        if cluster is not None:
            workers = parse_cluster(cluster)
            local = None
            if _cuda_wanted(device):
                try:
                    from dask_cuda import LocalCUDACluster  # (imported only here: CI has no GPU)
                except ImportError:
                    if workers > 1:  # (one plain worker process computes on cuda:0, as a direct run does)
                        raise SceneError("--cluster", cluster, f"{NO_DASK_CUDA}, or --device cpu") from None
                else:
                    local = LocalCUDACluster(n_workers=workers, threads_per_worker=1, dashboard_address=":0", silence_logs=QUIET)
            if local is None:
                local = LocalCluster(
                    n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=QUIET
                )
            client = stack.enter_context(Client(stack.enter_context(local)))
            if device is None and workers > 1 and remote_device(client, None).is_cuda:  # (no dask-cuda here)
                raise SceneError("--cluster", cluster, f"the workers' device is CUDA: {NO_DASK_CUDA}, or --device cpu")
        else:
            _probe(str(scheduler), parse_timedelta(CONNECT_TIMEOUT))
            try:
                client = stack.enter_context(Client(str(scheduler), timeout=CONNECT_TIMEOUT))
            except (OSError, TimeoutError, ValueError) as exc:
                why = " ".join(str(exc).split())[:160] or type(exc).__name__
                raise SceneError("--scheduler", scheduler, f"cannot be reached ({why})") from None
            try:  # (a scheduler without workers: the first task would wait forever, deaf to Ctrl-C)
                client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
            except TimeoutError:
                raise SceneError(
                    "--scheduler", scheduler, f"has no worker (none joined within {CONNECT_TIMEOUT}): start `dask worker ADDRESS`"
                ) from None
        if announce is not None:
            print(f"Dask dashboard: {client.dashboard_link}", file=announce)
        if interrupts.pending():  # a Ctrl-C while the cluster started: before any work, nothing written
            interrupts.check()  # (not an earlier command's request, acted on already)
        yield client


def describe_workers(client, device=None) -> tuple[RemoteDevice, int]:
    """`device` as the client's workers resolve it (`tasks.describe_device` on every worker, the
    least free memory of them) and how many workers there are; one a worker lacks: its one line
    (RicochetError). Asked through `client.run`, a direct call to the workers rather than a task:
    a task's submission would hold the run's own tasks in the client's batched stream for up to
    its 10 ms interval. With no worker yet, a task waits for one."""
    found = list(client.run(describe_device, device).values())
    if not found:
        found = [client.submit(describe_device, device, pure=False).result()]
    lacking = [f for f in found if f[0] is None]
    if lacking:
        raise RicochetError(lacking[0][1])
    alias, name, is_cuda, _ = found[0]
    return RemoteDevice(alias, name, is_cuda, min(f[3] for f in found)), len(found)


def remote_device(client, device=None) -> RemoteDevice:
    """`device` as the client's workers resolve it (`describe_workers`)."""
    return describe_workers(client, device)[0]


def remote_name(client, device=None) -> str:
    """The alias of `device` on the client's workers."""
    return remote_device(client, device).alias


class Study:
    """A study's runs on a client's workers, with one progress(done, total) for them all: runs are
    `submit`ted (every stretch at once, but a bounded run's, submitted a check at a time) and then
    `fold`ed in turn; the progress counts the pellets of every finished task."""

    def __init__(self, client, device=None, progress=None, options=None):
        self.client, self.device, self.progress, self.options = client, device, progress, options
        self.remote, self.workers = describe_workers(client, device)  # (workers: the tasks' sizes only)
        self.futures: dict = {}  # key -> (future, pellets) of every task submitted and not folded yet
        self.total = self.folded = 0  # pellets submitted, folded
        self.pending: dict = {}  # scene TOML -> a job submitted ahead (`take`)

    def model(self, scene):
        """`scene`'s model for the client's files and statistics: its constants, built on the CPU
        (Warp's CPU device: no CUDA context here), the workers' device named."""
        from .device import resolve_device
        from .model import Model

        return dataclasses.replace(Model.from_scene(scene, resolve_device("cpu")), device=self.remote)

    def take(self, scene, done: int = 0, shards=None, bounds=None) -> dict:
        """The job of `scene` (and shards' folder) submitted ahead (a sweep's points), else
        `submit`ted now."""
        job = self.pending.pop(_ahead(scene, shards), None) if not done and bounds is None else None
        return job if job is not None else self.submit(scene, done, shards=shards, bounds=bounds)

    def _submit(self, scene, bounds, shards=None) -> list:
        futures = [
            self.client.submit(run_range, scene, self.device, a, b, self.options, shards, pure=False, retries=0)
            for a, b in bounds
        ]
        self.futures.update((f.key, (f, b - a)) for f, (a, b) in zip(futures, bounds))
        return futures

    def submit(self, scene, done: int = 0, ahead: bool = False, shards=None, bounds=None) -> dict:
        """Submit `scene`'s tasks (a bounded run's: `bound.planned`'s scene) from pellet `done`;
        returns the job `fold` takes (`ahead`: kept for `take` too). `shards`: the folder the
        tasks write their per-pellet fields to; `bounds`: the tasks' [start, stop) (a resumed
        sharded run's, its shards' names), else cut here: a bounded run's up to its budget, each
        check's submitted by `fold` once the check before is not met."""
        from .bound import BoundPlan, planned

        plan, work = BoundPlan.of(scene), planned(scene)
        chunk = chunk_of(work, self.remote, work.output.fields if shards is not None else ())
        size = task_size(work.shot.pellets - done, self.workers, TASKS_PER_WORKER, chunk)
        job = {"scene": work, "plan": plan, "unit": unit_of(work), "submitted": {}, "bounds": [], "shards": shards}
        self.total += work.shot.pellets - done
        for begin, stop in _stretches(work, done):
            cut = task_bounds(begin, stop, job["unit"], size) if bounds is None else [b for b in bounds if begin <= b[0] < stop]
            job["bounds"] += cut
            if plan is None:
                job["submitted"][stop] = self._submit(work, cut, shards)
        if ahead:
            self.pending[_ahead(scene, shards)] = job
        return job

    def result(self, future) -> Partial:
        """The task's result, the progress fed by every task finished meanwhile (in any order)."""
        from distributed import wait

        while not future.done():
            self._report()
            interrupts.check()
            with contextlib.suppress(TimeoutError):
                wait([f for f, _ in self.futures.values() if not f.done()], timeout=0.2, return_when="FIRST_COMPLETED")
        part = future.result()
        self.folded += self.futures.pop(future.key)[1]  # (its result no longer held on the cluster)
        self._report()
        return part

    def _report(self):
        if self.progress is not None:
            done = self.folded + sum(n for f, n in self.futures.values() if f.done())
            self.progress(done, max(self.total, 1))

    def cancel(self):
        """Cancel every task not finished (an interruption or a failure)."""
        self.client.cancel([f for f, _ in self.futures.values() if not f.done()])

    def fold(self, job, model, spec, sink=None, resumed=None):
        """The run's statistics (`pipeline.results`) from its tasks, each handed in order to
        `sink` as a chunk; resumed: a `pipeline.Resumed`."""
        from .pipeline import results, station_fold, warn_one_shot

        scene = job["scene"]
        warn_one_shot(scene, spec)
        layout, fold = station_fold(scene, spec)
        try:
            folded = _fold(self, job, model, spec, sink, resumed, fold)
        except BaseException:
            self.cancel()
            raise
        if not self.futures:  # the study's last run: the workers' kept stages freed (`tasks.Kept`)
            self.client.run(release, on_error="ignore")  # (a worker gone meanwhile frees its own)
        from .tallies.ensemble import has_ensemble, pieces_per_shot

        shot_pieces = pieces_per_shot(scene.shot.count) if has_ensemble(scene) else None
        return results(scene, model, spec, folded, fold, layout, shot_pieces)


def _ahead(scene, shards) -> tuple:
    """What a job submitted ahead is kept under: its scene and its shards' folder."""
    return scene.to_toml(), None if shards is None else str(shards)


def _stretches(scene, done: int):
    """(begin, stop) of the stretches every chunk boundary restarts from: each station piece (or
    bound check) from `done` on."""
    from .bound import BoundPlan, piece_ends

    plan = BoundPlan.of(scene)
    ends = piece_ends(scene) if scene.stations else (plan.checks() if plan is not None else [scene.shot.pellets])
    begin, out = 0, []
    for stop in ends:
        if stop > done:
            out.append((max(begin, done), stop))
        begin = stop
    return out


def _fold(study, job, model, spec, sink, resumed, fold):
    """`pipeline._loop`'s fold of the tasks' results: (totals, tables, tally, pieces, done, outcome)."""
    from .pipeline import landing_setup, stretch_end
    from .scene import load_pellet_file
    from .tallies.counts import TallyTotals
    from .tallies.sums import combine, empty_totals

    scene, plan = job["scene"], job["plan"]
    pellets = scene.shot.pellets
    arrays = load_pellet_file(scene.shot.file) if scene.shot.file is not None and spec.tally else None
    totals, tables, pieces, done = empty_totals(), [], [], 0
    tally = TallyTotals(landing_setup(scene, model, arrays)) if spec.tally else None
    counts = None if tally is None else np.zeros(tally.flat().size, np.int64)
    if resumed is not None and resumed.rows:
        totals, done = combine(totals, resumed.segment_results), resumed.rows
        tables += [resumed.shot_totals] if resumed.shot_totals is not None else []
        pieces += [resumed.shot_partials] if resumed.shot_partials is not None else []
        if tally is not None and resumed.tally is not None:
            counts = np.array(resumed.tally, np.int64)
            tally.load(counts)
        if fold is not None:
            width = 0 if tally is None else counts.size
            fold.resume(resumed.rows, resumed.segment_results, resumed.station_tally, width)
    checks = plan.checks() if plan is not None else []
    outcome = None
    if done in checks:  # resumed at a check: its outcome again, from the counts kept
        outcome = plan.result(tally, done, checks.index(done) + 1)
        if outcome.met:
            return totals, tables, tally, pieces, done, outcome
    for begin, stop in _stretches(scene, done):
        number = checks.index(stop) + 1 if stop in checks else 0
        futures = job["submitted"].get(stop)
        if futures is None:  # a bounded run: its tasks a check at a time
            futures = study._submit(scene, [b for b in job["bounds"] if begin <= b[0] < stop], job["shards"])
        while futures:  # (each dropped once folded: its result leaves the cluster's memory)
            part = study.result(futures.pop(0))
            assert part.start == done, (part.start, done)
            totals = combine(totals, part.segment_results)
            if fold is not None:
                fold.add(done, part.segment_results)
            if part.shot_totals is not None:
                tables.append(part.shot_totals)
            if part.shot_partials is not None:
                pieces.append(part.shot_partials)
            if tally is not None:
                np.add.at(counts, part.tally[0], part.tally[1])
                tally.load(counts)
            if sink is not None:
                sink.append({}, part.stop - part.start, part.segment_results, part.shot_totals, tally, part.shot_partials)
            done = part.stop
            log.debug("%d of %d pellets complete", done, pellets)
        outcome = stretch_end(fold, plan, tally, done, number) or outcome
        if number and outcome.met:
            break
    return totals, tables, tally, pieces, done, outcome
