"""Studies on Dask (issue 29; docs/cluster.md): a run's stretches computed on a real LocalCluster of
2 single-threaded worker processes and folded on the client give bitwise the serial run's /stats,
/progress partials, landing tallies and hazard map, for runs without and with pellet-pellet
collisions, a sweep, and a run whose worker is killed in the middle of a task."""

import dataclasses
import gc
import importlib.util
import logging
import os
import shutil
import socket
import threading

import h5py
import numpy as np
import pytest
from distributed import Client, LocalCluster
from helpers import assert_opens_in_xarray, assert_same_run, cli, interrupt_after, make_scene, paper_raw, stats_equal

import warp_ricochet as wr
from warp_ricochet import cluster, tasks
from warp_ricochet.errors import SceneError
from warp_ricochet.scene import scene_from_dict


@pytest.fixture(scope="module")
def client():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as local:
        with Client(local) as c:
            yield c


@pytest.fixture(autouse=True)
def few_tasks(monkeypatch):
    """A task a worker: tasks of several segments each, so a fold in any other grouping than the
    serial run's segment order would change the sums' bits."""
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 1)


def scene_of(count=450, shots=60, fields=(), **sections):
    raw = paper_raw(until="landing")
    raw["shot"].update(count=count, shots=shots)
    raw.update(sections)
    raw.setdefault("numerics", {})["chunk_size"] = 65536  # serial chunks of one segment: many chunks
    raw["output"] = {"fields": list(fields)}  # statistics, tallies and maps (per-pellet fields: shards)
    return scene_from_dict(raw)


SCENE_FILE = os.path.join(os.path.dirname(__file__), "..", "examples", "paper.toml")
SMALL_CPU = ["--set", "shot.count=200", "--device", "cpu", "-q"]
HAZARD = {"map_cell": 0.5, "map_extent": [-5.0, 140.0, -25.0, 25.0], "speed": {"skin": 60.0}}


@pytest.mark.parametrize(
    "sections",
    [
        {},
        {"hazard": HAZARD},
        {"collisions": {"enabled": True, "time_step": 5e-4, "rounds": 1}, "shot": "collisions"},
    ],
    ids=["plain", "hazard-map", "collisions"],
)
def test_a_run_on_a_cluster_is_bitwise_the_serial_run(tmp_path, client, sections):
    kw = dict(sections)
    if kw.pop("shot", None) == "collisions":
        scene = scene_of(count=30, shots=300, **kw)  # 9000 pellets: several tasks of whole granules of shots
    else:
        scene = scene_of(shots=600 if not kw else 300, **kw)  # 270,000 (135,000) pellets: 2 tasks of 3 (2) segments and 2 (1)
    serial, spread = tmp_path / "serial.h5", tmp_path / "cluster.h5"
    ref = wr.run(scene, serial, device="cpu")
    got = wr.run(scene, spread, device="cpu", client=client)
    assert stats_equal(dict(ref), dict(got))
    assert_same_run(spread, serial, fields=(), progress=("segment_results",))
    if ref.tally is not None:
        np.testing.assert_array_equal(ref.tally.flat(), got.tally.flat())
    if "hazard" in sections:
        with h5py.File(spread) as f:
            assert f["hazard/map/count"][()].sum() > 0  # the map was counted, not left empty


def test_a_sweep_on_a_cluster_is_bitwise_the_serial_sweep(tmp_path, client):
    scene = scene_of(shots=20)
    params = {"surfaces.0.mu_s": [0.2, 0.35, 0.5]}
    ties = [("surfaces.0.mu_d", 0.9, "surfaces.0.mu_s")]
    ref = wr.sweep(scene, params, ties, tmp_path / "serial.h5", device="cpu")
    seen = []  # one progress for the whole sweep, fed as tasks finish
    got = wr.sweep(scene, params, ties, tmp_path / "cluster.h5", device="cpu", client=client, progress=lambda *a: seen.append(a))
    assert seen[-1] == (3 * scene.shot.pellets,) * 2 and {total for _, total in seen} == {seen[-1][1]}
    assert [done for done, _ in seen] == sorted(done for done, _ in seen)
    for (p, a), (q, b) in zip(ref, got):
        assert p == q and stats_equal(dict(a), dict(b))
    with h5py.File(tmp_path / "serial.h5") as a, h5py.File(tmp_path / "cluster.h5") as b:
        names = []
        a["stats"].visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
        assert names and sorted(names) == sorted(n for n in b["stats"] if isinstance(b["stats"][n], h5py.Dataset))
        for name in names:  # every statistic of every point, and its interval's attributes (NaN equal to NaN)
            np.testing.assert_array_equal(b["stats"][name][()], a["stats"][name][()], err_msg=name)
            for key, value in a["stats"][name].attrs.items():
                if key in ("DIMENSION_LIST", "REFERENCE_LIST"):  # (HDF5 references: not values)
                    continue
                np.testing.assert_array_equal(b["stats"][name].attrs[key], value, err_msg=f"{name} {key}")


def test_a_worker_killed_mid_task_costs_a_retry_not_the_run(tmp_path, client, monkeypatch):
    scene = scene_of(shots=600)  # 270,000 pellets: 5 tasks of whole segments
    ref = wr.run(scene, device="cpu")
    marker = tmp_path / "killed"
    real = cluster.run_range

    def dying(scene, device, start, stop, options=None, shards=None, marker=str(marker)):
        if start > 0 and not os.path.exists(marker):  # the first task after the first: its worker dies (as OOM kills)
            open(marker, "w").close()
            os.kill(os.getpid(), 9)
        return real(scene, device, start, stop, options, shards)

    monkeypatch.setattr(cluster, "run_range", dying)
    got = wr.run(scene, device="cpu", client=client)
    assert marker.exists()  # a worker was killed
    assert stats_equal(dict(ref), dict(got))
    np.testing.assert_array_equal(ref.tally.flat(), got.tally.flat())


def test_a_run_is_cut_into_whole_chunks_whose_stages_its_workers_keep_and_free(client, monkeypatch):
    """Tasks of at least one serial chunk (not TASKS_PER_WORKER a worker, each a share of one), each
    worker's stage kept from task to task and freed at the end; the serial run's bits."""
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 4)
    scene = scene_of(shots=2000)  # 900,000 pellets
    scene = scene.replace(numerics=dataclasses.replace(scene.numerics, chunk_size=1 << 18))
    ref = wr.run(scene, device="cpu")
    real_range, real_result, parts = cluster.run_range, cluster.Study.result, []

    def noting(scene, device, start, stop, options=None, shards=None):
        from warp_ricochet.tasks import Kept

        before = Kept.entry
        part = real_range(scene, device, start, stop, options, shards)
        part.reused = before is not None and Kept.entry[2] is before[2]
        return part

    monkeypatch.setattr(cluster, "run_range", noting)
    monkeypatch.setattr(cluster.Study, "result", lambda self, f: parts.append(real_result(self, f)) or parts[-1])
    got = wr.run(scene, device="cpu", client=client)
    assert [(p.start, p.stop) for p in parts] == [(0, 262144), (262144, 524288), (524288, 786432), (786432, 900000)]
    assert sum(p.reused for p in parts) >= len(parts) - 2  # each of the 2 workers made one stage at most
    assert set(client.run(lambda: tasks.Kept.entry is None).values()) == {True}
    assert stats_equal(dict(ref), dict(got))
    np.testing.assert_array_equal(ref.tally.flat(), got.tally.flat())


@pytest.mark.parametrize("collisions", [False, True], ids=["plain", "collisions"])
def test_a_stage_kept_for_a_runs_next_task_gives_the_bits_of_a_new_one_and_no_other_run_gets_it(collisions):
    """A worker's tasks of one run, the last first (a retried task comes late), on the stage the
    first made: the bits of a stage each; a task of another scene makes its own."""
    if collisions:  # 63,000 pellets: 2 tasks, a granule of 2048 shots and 52 shots
        scene = scene_of(count=30, shots=2100, collisions={"enabled": True, "time_step": 5e-4, "rounds": 1})
    else:  # 135,000 pellets: 3 tasks of a segment, or less
        scene = scene_of(shots=300)
    other = scene.replace(surfaces=(dataclasses.replace(scene.surfaces[0], mu_s=0.3),))
    bounds = tasks.task_bounds(0, scene.shot.pellets, tasks.unit_of(scene), tasks.unit_of(scene))
    fresh = []
    for a, b in bounds:
        tasks.release()
        fresh.append(tasks.run_range(scene, "cpu", a, b))
    kept, stages = [], []
    for a, b in reversed(bounds):
        kept.insert(0, tasks.run_range(scene, "cpu", a, b))
        stages.append(tasks.Kept.entry[2])
    assert len(bounds) > 1 and all(stage is stages[0] for stage in stages)
    theirs = tasks.run_range(other, "cpu", *bounds[-1])
    assert tasks.Kept.entry[2] is not stages[0]
    tasks.release()
    assert tasks.Kept.entry is None
    pairs = [*zip(fresh, kept), (tasks.run_range(other, "cpu", *bounds[-1]), theirs)]
    for new, old in pairs:
        for name in ("segment_results", "shot_totals", "shot_partials"):
            a, b = getattr(new, name), getattr(old, name)
            assert (a is None) == (b is None) and (a is None or a.tobytes() == b.tobytes()), name
        assert all(x.tobytes() == y.tobytes() for x, y in zip(new.tally, old.tally))
    assert fresh[-1].tally[1].tobytes() != theirs.tally[1].tobytes()  # (another scene: other results)


def test_a_scheduler_that_cannot_be_reached_is_one_line_before_any_work(tmp_path, monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "1s")
    out = tmp_path / "run.h5"
    rc, stdout, stderr = cli(
        ["run", "examples/paper.toml", "--set", "output.fields=[]", "--scheduler", "tcp://127.0.0.1:9", "-o", out]
    )
    assert rc == 2, stderr
    assert len(stderr.strip().splitlines()) == 1, stderr
    assert "--scheduler = 'tcp://127.0.0.1:9': cannot be reached (Timed out trying to connect" in stderr
    assert not out.exists() and not os.path.exists(str(out) + ".partial")


def test_a_port_that_accepts_but_is_no_scheduler_is_one_line_not_a_hang(tmp_path, monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "1s")
    listener = socket.create_server(("127.0.0.1", 0))  # accepts (the backlog) and never answers
    address = f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    out, ended = tmp_path / "run.h5", []
    argv = ["run", "examples/paper.toml", "--set", "output.fields=[]", "--scheduler", address, "-o", out]
    thread = threading.Thread(target=lambda: ended.append(cli(argv)), daemon=True)  # (a hang: left behind)
    thread.start()
    thread.join(30)
    listener.close()
    assert ended, "the command still waits on a port that never answers"
    rc, _stdout, stderr = ended[0]
    assert rc == 2 and stderr.strip().splitlines() == [
        f"warp-ricochet: error: --scheduler = '{address}': cannot be reached (no Dask scheduler answered within 1 s)"
    ]
    assert not out.exists() and not os.path.exists(str(out) + ".partial")


def test_a_worker_address_is_refused_as_no_scheduler(monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "5s")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as local:
        address = next(iter(local.scheduler_info["workers"]))
        with pytest.raises(SceneError, match="is not a Dask scheduler [(]it answers as Worker[)]"):
            with cluster.session(scheduler=address):
                pass


@pytest.mark.parametrize("value", ["local:0", "local:-1", "local:abc", f"local:{(os.cpu_count() or 1) + 1}", "local:99999999999"])
def test_a_local_cluster_of_no_workers_or_more_than_the_cores_is_one_line(value):
    with pytest.raises(SceneError, match=f"must be local:N, 1 <= N <= {os.cpu_count() or 1} workers"):
        cluster.parse_cluster(value)  # (local:99999999999 once built its worker specs until the OOM killer came)
    assert cluster.parse_cluster(f"local:{os.cpu_count() or 1}") == (os.cpu_count() or 1)


@pytest.mark.parametrize("where", [{"cluster": "local:1"}, {"scheduler": "tcp://127.0.0.1:1"}])
def test_a_device_no_worker_can_have_is_one_line_before_the_cluster_starts(where, monkeypatch):
    """`--device bogus` with --cluster was refused by the workers after the cluster's start (2-3 s)."""
    import distributed

    def started(*args, **kwargs):
        raise AssertionError("a cluster was started or reached before the device's name was checked")

    monkeypatch.setattr(distributed, "LocalCluster", started)
    monkeypatch.setattr(cluster, "_probe", started)
    for device in ("bogus", "cuda:x", "cpu ", "CPU"):
        with pytest.raises(SceneError, match=r"--device = .*: must be cpu, cuda or cuda:N"):
            with cluster.session(device=device, **where):
                pass


def test_ctrl_c_while_the_local_cluster_starts_ends_the_command_before_any_work(tmp_path, monkeypatch):
    """A request (Ctrl-C, SIGTERM) that came while the cluster started was acted on at the first
    fold, after the run's file was made and every task submitted (a 2e7-pellet run on 2 workers
    kept two finished tasks' shards); it ends the command as soon as the cluster is up."""
    import signal

    import distributed

    from warp_ricochet import interrupts

    real = distributed.LocalCluster

    def started(*args, **kwargs):
        local = real(*args, **kwargs)
        interrupts._record(signal.SIGINT, None)  # (as the handler does for a Ctrl-C meanwhile)
        return local

    monkeypatch.setattr(distributed, "LocalCluster", started)
    monkeypatch.setattr(interrupts, "_requested", [])  # (the request left to no later test)
    monkeypatch.setattr(interrupts, "_raised", False)
    out = tmp_path / "out.h5"
    rc, _, err = cli(["run", SCENE_FILE, *SMALL_CPU, "--cluster", "local:1", "-o", out])
    assert rc == 130 and err == "warp-ricochet: interrupted\n", err
    assert os.listdir(tmp_path) == []


def test_a_device_the_workers_lack_is_one_line_with_no_worker_traceback(client):
    """Once the worker's "Compute Failed" log and traceback came on stderr above the line (-q too)."""
    with pytest.raises(wr.RicochetError, match="^device = 'tpu': not available here; available: cpu"):
        cluster.remote_device(client, "tpu")
    logs = [(level, msg) for records in client.get_worker_logs().values() for level, msg in records]
    assert not [msg for level, msg in logs if "describe_device" in msg and level != "INFO"], logs  # ("Run out-of-band ...")


def test_a_local_cluster_s_workers_log_nothing_of_their_own():
    """Once each task cancelled by Ctrl-C wrote "distributed.worker.state_machine - WARNING - Async
    instruction ... ended with CancelledError" above the command's line, -q too, and a failed task
    its "Compute Failed" record and traceback above the one-line error the client prints."""
    with cluster.session(cluster="local:1") as client:
        levels = client.run(lambda: [h.level for h in logging.getLogger("distributed").handlers])  # (where records print)
    assert list(levels.values()) == [[logging.CRITICAL]]


def test_a_scheduler_without_workers_is_one_line_not_a_hang(monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "1s")
    ended = []

    def reach(address):
        try:
            with cluster.session(scheduler=address) as client:
                cluster.remote_device(client)  # (once: waited for a worker forever)
        except SceneError as exc:
            ended.append(str(exc))

    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as local:
        thread = threading.Thread(target=reach, args=(local.scheduler_address,), daemon=True)  # (a hang: left behind)
        thread.start()
        thread.join(30)
        assert ended == [
            f"--scheduler = {local.scheduler_address!r}: has no worker (none joined within 1s): start `dask worker ADDRESS`"
        ]


def test_a_bounded_station_run_on_a_cluster_stops_at_the_serial_check_with_its_bits(client):
    """Tasks a check at a time, cut at every station's piece: the outcome, each station's results
    and the counts are the serial run's."""
    from test_station_bound import bounded_raw

    raw = bounded_raw()
    raw["output"] = {"fields": []}
    scene = make_scene(raw, precision="float64")
    ref = wr.run(scene, device="cpu")
    got = wr.run(scene, device="cpu", client=client)
    assert got.bound == ref.bound and got.bound.met and stats_equal(dict(ref), dict(got))
    np.testing.assert_array_equal(ref.tally.flat(), got.tally.flat())
    for name, part in ref.stations.items():
        assert stats_equal(dict(part), dict(got.stations[name]))
        np.testing.assert_array_equal(part.tally.flat(), got.stations[name].tally.flat())


def interrupt_at_task(monkeypatch, number, start) -> list:
    """Call `start`, Ctrl-C when the `number`th task's results reach a writer (before they are
    written); returns the rows of every task that reached one."""
    from warp_ricochet.io.writer import RunWriter

    real, calls = RunWriter.append, []

    def append(self, *args, **kw):
        calls.append(args[1])
        if len(calls) == number:
            raise KeyboardInterrupt
        return real(self, *args, **kw)

    monkeypatch.setattr(RunWriter, "append", append)
    with pytest.raises(KeyboardInterrupt):
        start()
    monkeypatch.setattr(RunWriter, "append", real)
    return calls


def interrupt_at_the_second_task(monkeypatch, scene, out, client) -> int:
    """Run `scene` to `out` on the cluster, Ctrl-C when the second task's results reach the writer
    (before they are written); returns the rows of the first, committed."""
    return interrupt_at_task(monkeypatch, 2, lambda: wr.run(scene, out, device="cpu", client=client))[0]


def test_an_interrupted_run_on_a_cluster_resumes_bitwise(tmp_path, client, monkeypatch):
    """Ctrl-C after the first task is committed: the others cancelled, the file resumable; --resume
    on the cluster gives the serial run's file."""
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 2)  # 270,000 pellets: 3 tasks
    scene = scene_of(shots=600)
    serial, out = tmp_path / "serial.h5", tmp_path / "out.h5"
    wr.run(scene, serial, device="cpu")
    rows = interrupt_at_the_second_task(monkeypatch, scene, out, client)
    with h5py.File(str(out) + ".partial") as f:
        assert f["progress/rows"][()] == rows < scene.shot.pellets
    wr.run(scene, out, device="cpu", client=client, resume=True)
    assert_same_run(out, serial, fields=(), progress=("segment_results",))


FIELDS = ("initial", "landing")
FIELD_PATHS = ("initial/position", "initial/velocity", "landing/position", "landing/velocity", "landing/surface")


def fields_scene():
    return scene_of(shots=600, fields=FIELDS)  # 270,000 pellets: 3 tasks of 131,072, 131,072 and 7,856 rows


def test_per_pellet_fields_on_a_cluster_are_shards_read_as_one_dataset(tmp_path, client, monkeypatch):
    """Each task writes its shard; the run file's virtual datasets over them read as the serial
    run's rows through h5py, open_run and the XDMF sidecar; a missing shard is an error, not zeros."""
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 2)
    scene = fields_scene()
    serial, out = tmp_path / "serial.h5", tmp_path / "out.h5"
    wr.run(scene, serial, device="cpu")
    wr.run(scene, out, device="cpu", client=client)
    assert_same_run(out, serial, fields=FIELD_PATHS)
    shards = tmp_path / "out.h5.shards"
    with h5py.File(out) as f:
        ds = f["pellets/landing/position"]
        assert ds.is_virtual and [m.file_name for m in ds.virtual_sources()] == [
            str(shards / f"rows-{a:012d}-{b:012d}.h5") for a, b in ((0, 131072), (131072, 262144), (262144, 270000))
        ]
    del ds
    with wr.open_run(out) as run, h5py.File(serial) as f:
        np.testing.assert_array_equal(run.landing.position.values, f["pellets/landing/position"][()])
    gc.collect()  # (an open dataset keeps its sources open, and a moved shard would still be read)
    shards.rename(tmp_path / "moved")
    with h5py.File(out) as f:  # h5py alone: the fill value, never a zero that reads as a result
        assert np.isnan(f["pellets/landing/position"][0]).all() and (f["pellets/landing/surface"][:5] == -1).all()
    with pytest.raises(wr.OutputError, match="over a shard that is missing, .*rows-000000000000-000000131072.h5 .moved"):
        wr.open_run(out)
    (tmp_path / "moved").rename(shards)
    assert_opens_in_xarray(out)  # (xarray's reader: every group, the shards' values)
    pytest.importorskip("vtk")  # (last: VTK's reader keeps the shards open)
    from test_xdmf import _check_clouds, _read

    blocks, _steps = _read(tmp_path / "out.xmf")
    with h5py.File(out) as f:
        _check_clouds(blocks, f)


def test_overwrite_replaces_a_file_or_a_link_where_the_shards_folder_goes(tmp_path, client):
    """Once "Not a directory" (a file there) and "Cannot call rmtree on a symbolic link", no key named."""
    scene, out, shards = scene_of(shots=2, fields=("landing",)), tmp_path / "out.h5", tmp_path / "out.h5.shards"
    shards.write_text("not a folder")
    wr.run(scene, out, device="cpu", client=client, overwrite=True)
    assert shards.is_dir() and [p.name for p in shards.iterdir()] == ["rows-000000000000-000000000900.h5"]
    elsewhere = tmp_path / "elsewhere"
    shards.rename(elsewhere)
    shards.symlink_to(elsewhere)
    wr.run(scene, out, device="cpu", client=client, overwrite=True)
    assert shards.is_dir() and not shards.is_symlink() and (elsewhere / "rows-000000000000-000000000900.h5").exists()
    sweep, sweep_shards, mu = tmp_path / "sweep.h5", tmp_path / "sweep.h5.shards", {"surfaces.0.mu_s": [0.5, 0.6]}
    for make in (lambda: sweep_shards.write_text("not a folder"), lambda: sweep_shards.symlink_to(elsewhere)):
        make()
        wr.sweep(scene, mu, (), sweep, device="cpu", client=client, overwrite=True)  # (a sweep's too)
        assert sorted(p.name for p in sweep_shards.iterdir()) == ["0000", "0001"] and not sweep_shards.is_symlink()
        shutil.rmtree(sweep_shards)
    assert (elsewhere / "rows-000000000000-000000000900.h5").exists()


def test_overwrite_by_a_run_without_shards_removes_the_replaced_files_shards_and_nothing_else(tmp_path, client):
    """A serial `run`/`sweep --overwrite` onto a file whose fields were in OUT.h5.shards removes that
    folder once the new file is in place (once left behind); without --overwrite, or a folder of
    that name the replaced file does not read, is kept."""
    scene = scene_of(shots=2, fields=("landing",))
    out, shards = tmp_path / "out.h5", tmp_path / "out.h5.shards"
    wr.run(scene, out, device="cpu", client=client)
    assert (shards / "rows-000000000000-000000000900.h5").exists()
    rc, _, err = cli(["run", SCENE_FILE, *SMALL_CPU, "-o", out])  # refused: nothing changes
    assert rc == 2 and "exists" in err and shards.is_dir()
    rc, _, err = cli(["run", SCENE_FILE, *SMALL_CPU, "-o", out, "--overwrite"])
    assert rc == 0 and not shards.exists() and not os.path.lexists(shards), err
    with wr.open_run(out) as run:  # the new file, its fields in it
        assert run.landing.position.values.shape == (200, 3)
    (shards).mkdir()  # a folder of that name the file does not read: never removed
    (shards / "mine.txt").write_text("kept")
    assert cli(["run", SCENE_FILE, *SMALL_CPU, "-o", out, "--overwrite"])[0] == 0
    assert (shards / "mine.txt").read_text() == "kept"
    sweep, sweep_shards, mu = tmp_path / "sweep.h5", tmp_path / "sweep.h5.shards", {"surfaces.0.mu_s": [0.5, 0.6]}
    wr.sweep(scene, mu, (), sweep, device="cpu", client=client)
    assert sorted(p.name for p in sweep_shards.iterdir()) == ["0000", "0001"]
    wr.sweep(scene, mu, (), sweep, device="cpu", overwrite=True)
    assert not sweep_shards.exists()
    with h5py.File(sweep) as f:
        assert not f["runs/0001/pellets/landing/position"].is_virtual


def interrupt_sweep(scene, out):
    """A serial sweep of mu_s = 0.5, 0.6 to `out`, Ctrl-C after its first chunk (point 0 resumable)."""
    seen = []

    def progress(done, total):
        seen.append(done)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        wr.sweep(scene, {"surfaces.0.mu_s": [0.5, 0.6]}, (), out, device="cpu", progress=progress)


def test_every_check_of_the_outputs_comes_before_the_cluster_starts(tmp_path, monkeypatch):
    """With --cluster, an existing file, XDMF sidecar or shards' folder, a --resume with nothing to
    resume or of a run or sweep begun without a cluster, and a sweep's bad point are one line
    (exit 2) before the cluster starts (they came after its seconds of start-up), nothing made."""

    def no_cluster(*args, **kwargs):
        raise AssertionError("the cluster was started before the checks")

    monkeypatch.setattr(cluster, "session", no_cluster)
    scene = scene_of(shots=600, fields=("landing",))  # 270,000 pellets, chunks of 65,536
    toml, out = tmp_path / "scene.toml", tmp_path / "out.h5"
    toml.write_text(scene.to_toml())
    run = ["run", toml, "--device", "cpu", "--cluster", "local:1", "-o", out]
    sweep = ["sweep", toml, "--device", "cpu", "--cluster", "local:1", "-o", out, "--param", "surfaces.0.mu_s=0.5,0.6"]
    sidecar, shards = tmp_path / "out.xmf", tmp_path / "out.h5.shards"
    cases = [
        (lambda: out.write_bytes(b""), run, "output path = '{out}': exists; give --overwrite"),
        (lambda: sidecar.write_text(""), run, "output path = '{out}': out.xmf (its XDMF sidecar) exists"),
        (lambda: sidecar.write_text(""), sweep, "output path = '{out}': out.xmf (its XDMF sidecar) exists"),
        (shards.mkdir, run, "its shards' folder '{out}.shards' exists; --overwrite replaces it"),
        (shards.mkdir, sweep, "its shards' folder '{out}.shards' exists; --overwrite replaces it"),
        (None, [*run, "--resume"], "nothing to resume: out.h5.partial does not exist"),
        (None, [*sweep, "--resume"], "nothing to resume: out.h5.partial does not exist"),
        (None, [*sweep[:-1], "surfaces.0.mu_s=0.5,0.1"], "surfaces.0.mu_d = 0.45: must be a number in [0, mu_s = 0.1]"),
        (lambda: interrupt_after(2, scene, out), [*run, "--resume"], "--resume = 'on a cluster': the run was begun without one"),
        (lambda: interrupt_sweep(scene, out), [*sweep, "--resume"], "--resume = 'on a cluster': the run was begun without one"),
    ]
    for make, argv, want in cases:
        for path in tmp_path.iterdir():
            if path != toml:
                shutil.rmtree(path) if path.is_dir() else path.unlink()
        if make is not None:
            make()
        before = sorted(os.listdir(tmp_path))
        rc, _, err = cli(argv)
        assert rc == 2 and err.count("\n") == 1 and want.format(out=out) in err, (argv, err)
        assert sorted(os.listdir(tmp_path)) == before, argv


@pytest.mark.parametrize(
    "argv, want",
    [
        (["--workers", "0"], "argument --workers: '0': must be a whole number in [1, 2147483647]"),
        (["--workers", "1,,2"], "argument --workers: '': must be a whole number"),
        (["--workers", "1,99999"], "--cluster = 'local:99999': must be local:N"),
        (["--repeats", "0"], "argument --repeats: '0': must be a whole number"),
        (["--pellets", "nan"], "argument --pellets: 'nan': must be a whole number"),
        (["--shots", "1e8"], "argument --shots: '1e8': must be a whole number in [1, 4772185]"),
        (["--study", "sweep-rest", "--points", "10"], "--points = 10: must be a square number"),
        (["--study", "statistics", "--points", "20000"], "--points = 20000: must be at most 10,000"),
        (["--study", "statistics", "--rest"], "--rest = True: is for --study collisions"),
    ],
)
def test_bench_dask_scaling_refuses_odd_options_in_one_line_before_any_cluster(argv, want, monkeypatch, capsys):
    """`python -m bench.dask scaling` with options it cannot run: one line, exit 2, no cluster
    started (once tracebacks, or a refusal after the first worker count's whole study)."""
    from bench import dask as bench_dask

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started before the checks")

    monkeypatch.setattr(cluster, "session", no_cluster)
    with pytest.raises(SystemExit) as exc:
        bench_dask.main(["scaling", "--device", "cpu", *argv])
    err = capsys.readouterr().err
    assert (
        exc.value.code == 2 and err.count("\n") == 1 and err.startswith("python -m bench.dask scaling: error: ") and want in err
    ), err


def test_a_fifo_where_the_shards_folder_goes_is_refused_before_the_cluster_and_never_opened(tmp_path, monkeypatch):
    """A FIFO at OUT.h5.shards: `run --cluster ... --overwrite` once started the cluster, then hung
    for good in rmtree (which opens it), deaf to SIGTERM; now one line before the cluster starts
    (as a FIFO at the output path), and `io.shards.remove` unlinks whatever is not a folder."""
    from test_faults import watchdog

    from warp_ricochet.io import shards as io_shards

    def no_cluster(*args, **kwargs):
        raise AssertionError("the cluster was started before the checks")

    monkeypatch.setattr(cluster, "session", no_cluster)
    out, fifo = tmp_path / "o.h5", tmp_path / "o.h5.shards"
    os.mkfifo(fifo)
    with watchdog(fifo) as fired:
        rc, _, err = cli(["run", SCENE_FILE, *SMALL_CPU, "--cluster", "local:1", "-o", out, "--overwrite"])
    assert not fired and rc == 2, err
    assert (
        err
        == f"warp-ricochet: error: output path = '{out}': its shards' folder '{fifo}' is a FIFO (named pipe), not a regular file; remove it\n"
    )
    with watchdog(fifo) as fired:
        io_shards.remove(fifo)
    assert not fired and not os.path.lexists(fifo)


def test_an_interrupted_run_with_shards_resumes_from_its_committed_shards(tmp_path, client, monkeypatch):
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 2)
    scene = fields_scene()
    serial, out = tmp_path / "serial.h5", tmp_path / "out.h5"
    wr.run(scene, serial, device="cpu")
    interrupt_at_the_second_task(monkeypatch, scene, out, client)
    with pytest.raises(wr.SceneError, match="--resume = 'without a cluster': the run was begun on one"):
        wr.run(scene, out, device="cpu", resume=True)
    first = tmp_path / "out.h5.shards" / "rows-000000000000-000000131072.h5"  # (its committed rows)
    first.rename(tmp_path / "moved.h5")  # once resumed to a file whose rows 0-131071 read as NaN
    with pytest.raises(wr.OutputError, match=f"--resume = '{first}': a shard of the interrupted run's committed rows is missing"):
        wr.run(scene, out, device="cpu", client=client, resume=True)
    (tmp_path / "moved.h5").rename(first)
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 8)  # (the shards' bounds are the interrupted run's)
    wr.run(scene, out, device="cpu", client=client, resume=True)
    assert_same_run(out, serial, fields=FIELD_PATHS)


def test_a_local_cluster_of_gpus_without_dask_cuda_is_one_line(tmp_path):
    try:  # (CI has no dask-cuda: the refusal is what a GPU host without it sees)
        import dask_cuda  # noqa: F401
    except ImportError:
        pass
    else:
        pytest.skip("dask-cuda is installed here")
    rc, _stdout, stderr = cli(
        ["run", "examples/paper.toml", "--set", "output.fields=[]", "--cluster", "local:2", "--device", "cuda"]
    )
    assert rc == 2 and stderr.strip().splitlines() == [
        "warp-ricochet: error: --cluster = 'local:2': one worker a GPU needs dask-cuda "
        "(pip install 'warp-ricochet[dask-cuda]'), or --device cpu"
    ]


def test_one_local_worker_on_cuda_needs_no_dask_cuda_and_a_workers_error_is_one_line(tmp_path):
    """`--cluster local:1 --device cuda` is one plain worker process (it computes on cuda:0, as a
    direct run does); where there is no GPU, the worker's error reaches the user as the one line a
    direct run prints, without the worker's log and traceback."""
    try:
        import dask_cuda  # noqa: F401
    except ImportError:
        pass
    else:
        pytest.skip("dask-cuda is installed here")
    import warp as wp

    if wp.is_cuda_available():
        pytest.skip("a GPU is here")
    rc, _stdout, stderr = cli(
        ["run", "examples/paper.toml", "--set", "output.fields=[]", "--cluster", "local:1", "--device", "cuda"]
    )
    lines = [line for line in stderr.strip().splitlines() if not line.startswith("Dask dashboard: ")]
    assert rc == 2 and len(lines) == 1, stderr
    assert lines[0].startswith("warp-ricochet: error: device = 'cuda': not available here"), stderr


def sweep_with_fields(out, client=None, **kw):
    """A 2-point sweep of 67,500 pellets a point with per-pellet fields: on a cluster 2 tasks a
    point, of 65,536 and 1,964 rows (a shard each)."""
    scene = scene_of(shots=150, fields=FIELDS)
    ties = [("surfaces.0.mu_d", 0.9, "surfaces.0.mu_s")]
    return wr.sweep(scene, {"surfaces.0.mu_s": [0.2, 0.5]}, ties, out, device="cpu", client=client, **kw)


def assert_same_sweep_fields(out, serial):
    with h5py.File(out) as a, h5py.File(serial) as b:
        for i in range(2):
            for name in FIELD_PATHS:
                x, y = a[f"runs/{i:04d}/pellets/{name}"], b[f"runs/{i:04d}/pellets/{name}"]
                assert x.is_virtual and not y.is_virtual and x.dtype == y.dtype
                np.testing.assert_array_equal(x[()], y[()], err_msg=f"{i} {name}")


def test_per_pellet_fields_of_a_sweep_on_a_cluster_are_its_points_shards_read_as_the_serial_sweeps(tmp_path, client, monkeypatch):
    """Each point's run file, and its /runs/NNNN in the sweep file, presents its fields as virtual
    datasets over its shards (OUT.h5.shards/NNNN/), bitwise the serial sweep's through h5py,
    open_run and the XDMF sidecar; a missing shard of one point is refused in one line by the
    readers; an OUT.h5.shards there already, before any work."""
    serial, out = tmp_path / "serial.h5", tmp_path / "out.h5"
    ref = sweep_with_fields(serial)
    real, cut = cluster.Study._submit, []
    monkeypatch.setattr(
        cluster.Study, "_submit", lambda self, sc, bounds, shards=None: cut.extend(bounds) or real(self, sc, bounds, shards)
    )
    got = sweep_with_fields(out, client)
    assert cut == [(0, 65536), (65536, 67500)] * 2  # every point's tasks, submitted once (ahead)
    assert all(stats_equal(dict(a), dict(b)) for (_, a), (_, b) in zip(ref, got))
    assert_same_sweep_fields(out, serial)
    shards = tmp_path / "out.h5.shards"
    with h5py.File(out) as f:
        assert [m.file_name for m in f["runs/0001/pellets/landing/position"].virtual_sources()] == [
            str(shards / "0001" / f"rows-{a:012d}-{b:012d}.h5") for a, b in ((0, 65536), (65536, 67500))
        ]
    for i in range(2):
        with wr.open_run(out, point=i) as run, h5py.File(serial) as f:
            np.testing.assert_array_equal(run.landing.position.values, f[f"runs/{i:04d}/pellets/landing/position"][()])
    gc.collect()  # (an open dataset keeps its sources open)
    gone = shards / "0001" / "rows-000000065536-000000067500.h5"
    gone.rename(tmp_path / "moved.h5")
    with pytest.raises(wr.OutputError, match="runs/0001/pellets/initial/position over a shard that is missing, .*0001/rows-0"):
        wr.open_run(out, point=0)  # (the file is checked whole: any point's missing shard)
    rc, _stdout, stderr = cli(["report", out])
    assert rc == 2 and len(stderr.strip().splitlines()) == 1 and str(gone) in stderr, stderr
    (tmp_path / "moved.h5").rename(gone)
    assert_opens_in_xarray(out)  # (xarray's reader: every point's group, the shards' values)
    if importlib.util.find_spec("vtk") is not None:  # the sweep's XDMF sidecar reads them too
        from test_xdmf import _check_clouds, _read

        blocks, _steps = _read(tmp_path / "out.xmf")
        with h5py.File(out) as f:
            for point in ("0000", "0001"):
                _check_clouds(blocks, f[f"runs/{point}"], suffix=f" point_{point}")
    (tmp_path / "new.h5.shards").mkdir()
    with pytest.raises(wr.OutputError, match="new.h5.shards' exists; --overwrite replaces it"):  # (before any work)
        sweep_with_fields(tmp_path / "new.h5", client)
    assert not os.path.exists(tmp_path / "new.h5.partial")


def test_a_sweep_whose_complete_points_shards_are_gone_is_not_resumed(tmp_path, client, monkeypatch):
    """Ctrl-C at point 1's first task, point 0 complete: with point 0's shards gone, --resume once
    assembled a sweep file whose /runs/0000 rows read as NaN; it is refused before any work."""
    out = tmp_path / "out.h5"
    assert interrupt_at_task(monkeypatch, 3, lambda: sweep_with_fields(out, client)) == [65536, 1964, 65536]
    assert (tmp_path / "out.h5.partial" / "0000.h5").is_file()
    (tmp_path / "out.h5.shards" / "0000").rename(tmp_path / "moved")
    gone = tmp_path / "out.h5.shards" / "0000" / "rows-000000000000-000000065536.h5"
    with pytest.raises(wr.OutputError, match=f"--resume = '{gone}': a shard of the interrupted sweep's complete point 0"):
        sweep_with_fields(out, client, resume=True)
    assert not out.exists() and (tmp_path / "out.h5.partial" / "0001.h5.partial").exists()


def test_an_interrupted_sweep_with_shards_resumes_from_its_committed_shards(tmp_path, client, monkeypatch):
    """Ctrl-C at point 0's second task: --resume on the cluster keeps point 0's first shard (not
    computed again), runs point 1 again (the shards its tasks wrote ahead removed first) and gives
    the serial sweep's fields; without a cluster it is refused before any work."""
    serial, out = tmp_path / "serial.h5", tmp_path / "out.h5"
    sweep_with_fields(serial)
    assert interrupt_at_task(monkeypatch, 2, lambda: sweep_with_fields(out, client)) == [65536, 1964]
    first = out.parent / "out.h5.shards" / "0000" / "rows-000000000000-000000065536.h5"
    written = first.stat().st_mtime_ns
    (out.parent / "out.h5.shards" / "0001").mkdir(exist_ok=True)
    (out.parent / "out.h5.shards" / "0001" / "stale.h5").touch()
    with pytest.raises(wr.SceneError, match="--resume = 'without a cluster': the run was begun on one"):
        sweep_with_fields(out, resume=True)  # (before any work)
    sweep_with_fields(out, client, resume=True)
    assert first.stat().st_mtime_ns == written and not (out.parent / "out.h5.shards" / "0001" / "stale.h5").exists()
    assert_same_sweep_fields(out, serial)
