"""Per-pellet fields of a bounded run ([hazard.bound]) on a cluster (issue 29; docs/cluster.md): its
tasks, submitted a check at a time on a real LocalCluster of 2 single-threaded workers, write their
shards, and the run file presents the pellets of the checks run as one dataset per field, bitwise
the serial bounded run's (h5py, open_run, xarray, the XDMF sidecar), also after Ctrl-C or a SIGKILL
and --resume, for a sweep of bounded points, with stations and with the budget spent; the last step,
cutting the file's datasets to the checks run, leaves the closed file as it was if it fails."""

import errno
import gc
import os
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import test_cluster
from helpers import assert_opens_in_xarray, assert_same_run, make_scene, paper_raw, stats_equal

import warp_ricochet as wr
from warp_ricochet import cluster
from warp_ricochet.io import shards
from warp_ricochet.io.shards import BOUNDS, shard_path

FIELDS = ("initial", "landing")
FIELD_PATHS = ("initial/position", "initial/velocity", "landing/position", "landing/range", "landing/surface")
SHOT = 70_000  # pellets a shot: a check's stretch is 2 tasks (65,536 and 4,464 rows) of 4 a worker
RAN = [(0, 65_536), (65_536, 70_000), (70_000, 135_536), (135_536, 140_000)]  # the tasks of the 2 checks run
ROOT = Path(__file__).resolve().parents[1]
client = test_cluster.client  # (the fixture: a LocalCluster of 2 single-threaded worker processes)
interrupt_at_task = test_cluster.interrupt_at_task


@pytest.fixture(autouse=True)
def tasks_of_a_segment(monkeypatch):
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 4)


def bounded_scene():
    """A shot of 70,000 pellets in vacuum, checks at 1, 2, 3 and 4 shots (the budget): 3e-5 of the
    pellets above `low` need about 123,000 of them for a finite interval, so the first check is
    unbounded and the second (140,000 pellets) meets the width, half the budget."""
    raw = paper_raw(until="landing")
    raw["shot"].update(count=SHOT, shots=1)
    hazard = {
        "energy_density": {"low": 237_000.0},
        "fractions": [3e-5],
        "bound": {"threshold": "low", "fraction": 3e-5, "width": 1.0, "max_pellets": 4 * SHOT},
    }
    return make_scene(raw, hazard=hazard, output={"fields": list(FIELDS)}, numerics={"chunk_size": 65_536})


def small_scene(width=1.0, max_pellets=20_000):
    """Shots of 100 pellets, checks at 200, 300, 400, ... pellets (a task each): the third meets
    the width of 1 m (test_bound.py), of a budget of 20,000 pellets."""
    raw = paper_raw(until="landing")
    raw["shot"].update(count=100, shots=2)
    hazard = {
        "energy_density": {"low": 237_000.0},
        "fractions": [0.01],
        "bound": {"threshold": "low", "fraction": 0.01, "width": width, "max_pellets": max_pellets},
    }
    return make_scene(raw, hazard=hazard, output={"fields": ["landing"]})


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The serial bounded run: (path, stats)."""
    path = tmp_path_factory.mktemp("serial") / "serial.h5"
    stats = wr.run(bounded_scene(), path, device="cpu")
    assert stats.bound.met and stats.bound.pellets == 2 * SHOT and stats.bound.checks == 2
    return path, stats


def assert_same_bounded_run(out, serial, stats=None):
    """`out` is the serial bounded run bitwise (fields, /stats, /hazard with /hazard/bound, the
    progress partials), its fields virtual datasets over the shards of the tasks run only."""
    path, ref = serial
    if stats is not None:
        assert stats.bound == ref.bound and stats_equal(dict(ref), dict(stats))
    assert_same_run(out, path, fields=FIELD_PATHS)
    shards = Path(str(out) + ".shards")
    names = [shard_path(shards, a, b) for a, b in RAN]
    with h5py.File(out) as f, h5py.File(path) as g:
        for name in FIELD_PATHS:
            ds = f[f"pellets/{name}"]
            assert ds.is_virtual and ds.shape == g[f"pellets/{name}"].shape == (2 * SHOT,) + ds.shape[1:], name
            assert [m.file_name for m in ds.virtual_sources()] == names, name
            assert dict(ds.attrs).keys() == dict(g[f"pellets/{name}"].attrs).keys(), name
        assert f["progress"].attrs[BOUNDS].tolist() == [list(b) for b in RAN]
    assert sorted(str(p) for p in shards.iterdir()) == names  # (no shard of a check not run)


def test_per_pellet_fields_of_a_bounded_run_on_a_cluster_are_the_serial_runs(tmp_path, client, serial):
    """The run stops at the serial run's check; its fields read as the serial run's through h5py,
    open_run, xarray (its named dimensions) and the XDMF sidecar; a missing shard is an error."""
    out = tmp_path / "out.h5"
    stats = wr.run(bounded_scene(), out, device="cpu", client=client)
    assert_same_bounded_run(out, serial, stats)
    with wr.open_run(out) as run, h5py.File(serial[0]) as f:
        assert run.rows == 2 * SHOT
        np.testing.assert_array_equal(run.landing.position.values, f["pellets/landing/position"][()])
    gc.collect()  # (an open dataset keeps its sources open)
    gone = Path(shard_path(Path(str(out) + ".shards"), *RAN[2]))
    gone.rename(tmp_path / "moved.h5")
    with pytest.raises(wr.OutputError, match="over a shard that is missing, .*rows-000000070000-000000135536.h5"):
        wr.open_run(out)
    (tmp_path / "moved.h5").rename(gone)
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    for group in ("pellets/initial", "pellets/landing"):  # netCDF's view: the dimension `pellet` is the rows run
        with (
            xr.open_dataset(out, engine="h5netcdf", group=group) as a,
            xr.open_dataset(serial[0], engine="h5netcdf", group=group) as b,
        ):
            assert dict(a.sizes) == dict(b.sizes) == {"pellet": 2 * SHOT, "xyz": 3}
            assert {k: v.dims for k, v in a.items()} == {k: v.dims for k, v in b.items()}
            np.testing.assert_array_equal(a["position"].values, b["position"].values)
    assert_opens_in_xarray(out)  # every group, /hazard/bound too
    pytest.importorskip("vtk")  # (last: VTK's reader keeps the shards open)
    from test_xdmf import _check_clouds, _read

    blocks, _steps = _read(tmp_path / "out.xmf")
    with h5py.File(out) as f:
        _check_clouds(blocks, f)


@pytest.mark.parametrize(("task", "rows"), [(2, 65_536), (3, 70_000)], ids=["inside-a-check", "at-a-check"])
def test_an_interrupted_bounded_run_with_shards_resumes_bitwise(tmp_path, client, serial, monkeypatch, task, rows):
    """Ctrl-C as a task's results reach the writer, inside the first check's stretch or at the
    first check: --resume on the cluster, with other task sizes now, continues from the committed
    shards, with the interrupted run's task bounds, to the serial run's bits."""
    out = tmp_path / "out.h5"
    interrupt_at_task(monkeypatch, task, lambda: wr.run(bounded_scene(), out, device="cpu", client=client))
    with h5py.File(str(out) + ".partial") as f:
        assert f["progress/rows"][()] == rows
    monkeypatch.setattr(cluster, "TASKS_PER_WORKER", 1)  # (the shards' bounds are the interrupted run's)
    stats = wr.run(bounded_scene(), out, device="cpu", client=client, resume=True)
    assert_same_bounded_run(out, serial, stats)


KILLER = """
import os, signal, sys
from warp_ricochet.io.writer import RunWriter
real, seen = RunWriter.append, []
def append(self, *args, **kw):
    seen.append(1)
    if len(seen) == 3:  # the third task's results, before they are written: SIGKILL, no clean-up
        os.kill(os.getpid(), signal.SIGKILL)
    return real(self, *args, **kw)
RunWriter.append = append
from warp_ricochet.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_bounded_run_with_shards_killed_resumes_bitwise(tmp_path, client, serial):
    """`run --cluster local:2` killed (SIGKILL) after the first check's tasks are committed:
    --resume on a cluster gives the serial run's bits."""
    scene, out = tmp_path / "scene.toml", tmp_path / "out.h5"
    scene.write_text(bounded_scene().to_toml())
    argv = ["run", str(scene), "-o", str(out), "--device", "cpu", "--cluster", "local:2", "-q"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", KILLER, *argv], env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    with h5py.File(str(out) + ".partial", "r", swmr=True) as f:  # (the flags of a writer killed: a SWMR reader's open)
        assert f["progress/rows"][()] == SHOT and f.attrs["status"] == "running"
    stats = wr.run(bounded_scene(), out, device="cpu", client=client, resume=True)
    assert_same_bounded_run(out, serial, stats)


def test_per_pellet_fields_of_a_bounded_sweep_on_a_cluster_are_the_serial_sweeps(tmp_path, client):
    """Each bounded point stops at the serial point's check (the third, 400 of a budget of 20,000
    pellets); its /runs/NNNN reads its fields over its shards, bitwise the serial sweep's."""
    scene, params = small_scene(), {"shot.seed": [1, 2]}
    ref = wr.sweep(scene, params, output=tmp_path / "serial.h5", device="cpu")
    got = wr.sweep(scene, params, output=tmp_path / "out.h5", device="cpu", client=client)
    for (_, a), (_, b) in zip(ref, got):
        assert stats_equal(dict(a), dict(b))
    with h5py.File(tmp_path / "out.h5") as f, h5py.File(tmp_path / "serial.h5") as g:
        for i in range(2):
            run, shards = f"runs/{i:04d}", tmp_path / "out.h5.shards" / f"{i:04d}"
            assert g[f"{run}/hazard/bound/met"][()] and g[f"{run}/hazard/bound/pellets"][()] == 400
            np.testing.assert_array_equal(f[f"{run}/hazard/bound/checks"][()], g[f"{run}/hazard/bound/checks"][()])
            for name in ("landing/position", "landing/range"):
                x, y = f[f"{run}/pellets/{name}"], g[f"{run}/pellets/{name}"]
                assert x.is_virtual and x.shape == y.shape == (400,) + y.shape[1:]
                assert [m.file_name for m in x.virtual_sources()] == [
                    shard_path(shards, a, b) for a, b in ((0, 200), (200, 300), (300, 400))
                ]
                np.testing.assert_array_equal(x[()], y[()], err_msg=f"{i} {name}")
            assert len(list(shards.iterdir())) == 3
    assert_opens_in_xarray(tmp_path / "out.h5")  # (each point's /runs/NNNN/hazard/bound too)


def test_a_cut_that_fails_leaves_the_closed_run_file_as_it_was(tmp_path, client, monkeypatch):
    """The fields are cut to the checks run in a copy moved onto the closed file: an error there
    (a full disk) halfway leaves OUT.h5.partial complete as it was closed and no copy behind."""
    real, calls = shards._recut, []

    def failing(*args):
        calls.append(args[1])
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(*args)

    monkeypatch.setattr(shards, "_recut", failing)
    out = tmp_path / "out.h5"
    with pytest.raises(OSError, match="No space left on device"):
        wr.run(small_scene(), out, device="cpu", client=client)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5.partial", "out.h5.shards"]
    with h5py.File(str(out) + ".partial") as f:
        assert f.attrs["status"] == "complete" and f["progress/rows"][()] == 400
        assert calls and {len(ds) for ds in f["pellets/landing"].values()} == {20_000}  # (the budget's tasks: not cut)
        assert f["progress"].attrs[BOUNDS][-1].tolist() == [18_800, 20_000]  # (the last check)


@pytest.mark.parametrize("stop", ["cut", "move"])
def test_a_complete_bounded_run_stopped_before_its_move_resumes_to_its_end(tmp_path, client, monkeypatch, stop):
    """Stopped after its file was closed: its fields' cut failed (a full disk), or it was killed after
    the cut, before the move into place. --resume on the cluster meets the bound again at once, runs
    no task, cuts what is not cut and moves the file into place: the serial run's bits, 3 shards."""
    from warp_ricochet.io import runfile

    def fails(*args):
        raise OSError(errno.ENOSPC, "No space left on device") if stop == "cut" else KeyboardInterrupt

    serial, out = tmp_path / "serial.h5", tmp_path / "out.h5"
    wr.run(small_scene(), serial, device="cpu")
    with monkeypatch.context() as m:
        m.setattr(*((shards, "_recut") if stop == "cut" else (runfile, "move_into_place")), fails)
        with pytest.raises(OSError if stop == "cut" else KeyboardInterrupt):
            wr.run(small_scene(), out, device="cpu", client=client)
    with h5py.File(str(out) + ".partial") as f:
        assert f.attrs["status"] == "complete" and len(f["pellets/landing/range"]) == (20_000 if stop == "cut" else 400)
    stats = wr.run(small_scene(), out, device="cpu", client=client, resume=True)
    assert stats.bound.met and stats.bound.pellets == 400
    assert_same_run(out, serial, fields=("landing/position", "landing/range"))
    with h5py.File(out) as f:
        assert f["progress"].attrs[BOUNDS].tolist() == [[0, 200], [200, 300], [300, 400]]
    assert len(os.listdir(str(out) + ".shards")) == 3


def test_a_bounded_station_run_with_fields_on_a_cluster_is_the_serial_runs(tmp_path, client):
    """Stations: tasks cut at every station's piece and check; the fields of the pieces run."""
    from test_station_bound import bounded_raw

    raw = bounded_raw()
    raw["output"] = {"fields": ["landing"]}
    scene, serial, out = make_scene(raw, precision="float64"), tmp_path / "serial.h5", tmp_path / "out.h5"
    ref = wr.run(scene, serial, device="cpu")
    got = wr.run(scene, out, device="cpu", client=client)
    assert got.bound == ref.bound and got.bound.met and ref.bound.pellets < ref.bound.max_pellets
    assert_same_run(out, serial, fields=("landing/position", "landing/range"))
    with h5py.File(out) as f:
        bounds = f["progress"].attrs[BOUNDS].tolist()
        assert bounds[-1][1] == ref.bound.pellets and len(bounds) > ref.bound.checks  # (pieces within checks)
        assert len(f["pellets/landing/range"].virtual_sources()) == len(bounds)


def test_a_bounded_run_that_spends_its_budget_keeps_every_task_s_shard(tmp_path, client):
    """Not bounded: the run goes to its budget (1,000 pellets, 8 checks), its datasets as made."""
    scene = small_scene(width=0.01, max_pellets=1_050)  # (below one bin's width: never met)
    serial, out = tmp_path / "serial.h5", tmp_path / "out.h5"
    with pytest.warns(wr.PrecisionWarning, match="NOT BOUNDED"):
        ref = wr.run(scene, serial, device="cpu")
    with pytest.warns(wr.PrecisionWarning, match="NOT BOUNDED"):
        got = wr.run(scene, out, device="cpu", client=client)
    assert got.bound == ref.bound and not got.bound.met and got.bound.pellets == 1_000
    assert_same_run(out, serial, fields=("landing/position", "landing/range"))
    with h5py.File(out) as f:
        assert len(f["pellets/landing/range"].virtual_sources()) == 8 == len(os.listdir(str(out) + ".shards"))
