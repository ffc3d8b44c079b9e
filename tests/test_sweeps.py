"""Sweeps (issue 13, item 2): points generated lazily and counted first, refused above the limit in
one line; every point validated before any work; each point committed as it finishes in the folder
OUT.h5.partial/, so a sweep killed (SIGKILL) or interrupted (SIGINT) at any moment is continued by
`sweep ... --resume` and ends bitwise identical to an uninterrupted sweep; a --resume of a
different sweep, or of a folder in use, is refused in one line without touching the folder."""

import hashlib
import os
import random
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import cli, held
from warp_ricochet.scene import MAX_SWEEP_POINTS, load_scene
from warp_ricochet.tallies.reduce import SEGMENT

# when and by which process a file was written: the only attributes a resumed sweep may differ in
PROVENANCE = ("created", "writer_pid", "writer_host")

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
SETS = [
    "--set",
    f"shot.count={12 * SEGMENT - 1000}",
    "--set",
    "numerics.chunk_size=65536",
    "--set",
    "numerics.precision='float64'",
    "--set",
    'output.fields=["landing.range", "initial.position"]',
]
SWEEP = ["--param", "surfaces.0.mu_s=0,0.05,0.1", "--tie", "surfaces.0.mu_d=0.9*"]
ARGS = [SCENE, "--device", "cpu", *SETS, *SWEEP]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
PREFIX = "warp-ricochet: error: "


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted sweep's file."""
    path = tmp_path_factory.mktemp("reference") / "ref.h5"
    rc, _, err = cli(["sweep", *ARGS, "-o", path])
    assert rc == 0, err
    return path


def _objects(f):
    found = {}
    f.visititems(lambda name, obj: found.__setitem__(name, obj))
    return found


def _named(f, value):
    """An attribute's value with object references (dimension scales) as the names they point to."""
    if isinstance(value, h5py.Reference):
        return f[value].name
    if isinstance(value, (tuple, list)) or (isinstance(value, np.ndarray) and value.dtype.kind in "OV"):
        return [_named(f, v) for v in (value.tolist() if isinstance(value, np.ndarray) else value)]
    return value


def assert_same_sweep(path, ref):
    """Every group, dataset (values, dtype, shape, chunks) and attribute equal, but `created`; object
    references (dimension scales) point to objects of the same name."""
    with h5py.File(path, "r") as a, h5py.File(ref, "r") as b:
        assert a.attrs["status"] == "complete" and a.attrs["kind"] == "sweep"
        objects_a, objects_b = _objects(a), _objects(b)
        assert sorted(objects_a) == sorted(objects_b)
        for name in ["/", *objects_b]:
            x, y = a[name], b[name]
            assert sorted(x.attrs) == sorted(y.attrs), name
            for attr in y.attrs:
                if attr in ("DIMENSION_LIST", "REFERENCE_LIST"):
                    assert _named(a, x.attrs[attr]) == _named(b, y.attrs[attr]), (name, attr)
                elif attr not in PROVENANCE:
                    np.testing.assert_array_equal(np.asarray(x.attrs[attr]), np.asarray(y.attrs[attr]), err_msg=name)
            if isinstance(y, h5py.Dataset):
                assert (x.dtype, x.shape, x.chunks, x.maxshape) == (y.dtype, y.shape, y.chunks, y.maxshape), name
                if y.dtype.kind == "f":  # bitwise, NaN included
                    assert x[()].tobytes() == y[()].tobytes(), name
                else:
                    np.testing.assert_array_equal(x[()], y[()], err_msg=name)


def start_sweep(out, *extra):
    return subprocess.Popen(
        [sys.executable, "-m", "warp_ricochet.cli", "sweep", *ARGS, "-o", str(out), *extra],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )


def folder_digest(folder):
    """Names and contents of every file in a folder."""
    h = hashlib.sha256()
    for p in sorted(Path(folder).iterdir()):
        h.update(p.name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


def finish_after_stop(out, reference):
    """After a kill or interrupt: the result, the folder resumed, or nothing at all, as found."""
    folder = Path(str(out) + ".partial")
    if out.exists():  # it finished first (or was killed while removing its folder)
        assert_same_sweep(out, reference)
        return "after the end"
    if not folder.exists():  # before the folder was made: nothing to resume, nothing lost
        rc, _, err = cli(["sweep", *ARGS, "-o", out, "--resume"])
        assert rc == 2 and "nothing to resume" in err and len(err.splitlines()) == 1
        assert cli(["sweep", *ARGS, "-o", out])[0] == 0
        assert_same_sweep(out, reference)
        return "before the folder"
    stage = sorted(p.name for p in folder.iterdir())
    rc, _, err = cli(["sweep", *ARGS, "-o", out, "--resume"])
    assert rc == 0, err
    assert not folder.exists()
    assert_same_sweep(out, reference)
    return stage


def wait_for(path, proc, timeout=60.0):
    deadline = time.time() + timeout
    while not path.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.01)


# ---------------------------------------------------------------------------------------------- kills


def test_sigkill_at_random_moments_then_resume_is_bitwise_identical(tmp_path, reference):
    """SIGKILL at a random moment (making the folder, inside a point, between points, assembling,
    moving into place): --resume ends with a file equal to the uninterrupted sweep's."""
    seed = random.randrange(1 << 30)
    rng = random.Random(seed)
    stages = []
    for trial in range(3):
        out = tmp_path / f"k{trial}.h5"
        proc = start_sweep(out)
        wait_for(Path(str(out) + ".partial"), proc)
        time.sleep(rng.uniform(0.0, 1.5))
        proc.kill()
        proc.wait(timeout=60)
        stages.append(finish_after_stop(out, reference))
    print(f"seed {seed}: killed at {stages}")


def test_sigint_then_resume_is_bitwise_identical(tmp_path, reference):
    """Ctrl-C: exit 130, one line naming the folder and `sweep ... --resume`; then --resume."""
    seed = random.randrange(1 << 30)
    rng = random.Random(seed)
    for trial in range(2):
        out = tmp_path / f"i{trial}.h5"
        proc = start_sweep(out)
        wait_for(Path(str(out) + ".partial") / "0000.h5.partial", proc)
        time.sleep(rng.uniform(0.0, 1.5))
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        if proc.returncode == 130 and "the sweep had completed" in err:  # the signal came after its last point
            assert len(err.splitlines()) == 1 and f"its result is in {out}" in err, (seed, err)
        elif proc.returncode == 130:
            assert len(err.splitlines()) == 1, (seed, err)
            assert err.startswith("warp-ricochet: interrupted") and "warp-ricochet sweep ... --resume" in err, err
            assert f"{out}.partial" in err
        else:
            assert proc.returncode == 0, (seed, err)
        finish_after_stop(out, reference)


@pytest.fixture
def interrupted(tmp_path):
    """A sweep interrupted (Ctrl-C) in its second point: (out, folder)."""
    out = tmp_path / "s.h5"
    calls = []

    def progress(done, total):
        calls.append(done)
        if done > total // 2:
            raise KeyboardInterrupt

    scene = load_scene(SCENE, SETS[1::2])
    with pytest.raises(KeyboardInterrupt) as caught:
        wr.sweep(scene, {"surfaces.0.mu_s": [0, 0.05, 0.1]}, [("surfaces.0.mu_d", 0.9, None)], out, "cpu", progress=progress)
    folder = Path(str(out) + ".partial")
    assert caught.value.partial_path == str(folder) and caught.value.resume_command == "sweep"
    assert (folder / "0000.h5").exists() and (folder / "0001.h5.partial").exists()
    return out, folder


@pytest.mark.parametrize(
    "extra, start",
    [
        (["--set", "shot.seed=7"], "shot.seed = 7"),
        (["--param", "surfaces.0.restitution=0.1,0.2"], "--param = surfaces.0.mu_s, surfaces.0.restitution"),
        (["--tie", "surfaces.0.restitution=0.1*"], "--tie = "),
    ],
)
def test_resume_of_a_different_sweep_is_refused_and_touches_nothing(interrupted, extra, start):
    out, folder = interrupted
    before = folder_digest(folder)
    args = [a.replace("mu_d=0.9*", "mu_d=0.9*surfaces.0.mu_s") for a in ARGS]  # the same tie, named
    rc, stdout, err = cli(["sweep", *args, *extra, "-o", out, "--resume"])
    assert rc == 2 and stdout == "" and len(err.splitlines()) == 1 and err.startswith(PREFIX + start), err
    assert folder_digest(folder) == before and not out.exists()


def test_resume_with_other_values_is_refused_naming_the_first_that_differs(interrupted):
    out, folder = interrupted
    before = folder_digest(folder)
    args = [a.replace("0,0.05,0.1", "0,0.06,0.1") for a in ARGS]
    rc, _, err = cli(["sweep", *args, "-o", out, "--resume"])
    assert rc == 2 and len(err.splitlines()) == 1
    assert err.startswith(
        PREFIX + "surfaces.0.mu_s = 3 values, value 1 = 0.06: the interrupted sweep had 3 values, value 1 = 0.05"
    ), err
    assert folder_digest(folder) == before


def test_a_folder_in_use_is_refused_with_resume_overwrite_or_neither(interrupted):
    out, folder = interrupted
    before = folder_digest(folder)
    with held(folder, exclusive=True):
        for extra in (["--resume"], ["--overwrite"], []):
            rc, _, err = cli(["sweep", *ARGS, "-o", out, *extra])
            assert rc == 2 and len(err.splitlines()) == 1 and "in use by another process" in err, (extra, err)
    assert folder_digest(folder) == before
    rc, _, err = cli(["sweep", *ARGS, "-o", out])  # not in use: an earlier sweep, which --resume continues
    assert rc == 2 and "earlier interrupted sweep" in err and "--resume" in err


def test_resume_refusals_without_a_folder(tmp_path, interrupted):
    out, folder = interrupted
    rc, _, err = cli(["sweep", *ARGS, "-o", tmp_path / "none.h5", "--resume"])
    assert rc == 2 and "nothing to resume" in err
    before = folder_digest(folder)
    rc, _, err = cli(["run", SCENE, "--device", "cpu", *SETS, "-o", out, "--resume"])
    assert rc == 2 and "is a sweep's folder; warp-ricochet sweep ... --resume continues it" in err
    rc, _, err = cli(["run", SCENE, "--device", "cpu", *SETS, "-o", out, "--overwrite"])  # never over a sweep's folder
    assert rc == 2 and len(err.splitlines()) == 1 and "is a sweep's folder" in err, err
    assert folder_digest(folder) == before and not Path(str(folder) + ".new").exists()
    rc, stdout, err = cli(["report", folder])
    assert rc == 2 and "unfinished sweep: 1 of 3 points complete" in err, err


def test_interrupted_sweep_resumed_in_process_equals_reference(interrupted, reference):
    out, folder = interrupted
    scene = load_scene(SCENE, SETS[1::2])
    results = wr.sweep(scene, {"surfaces.0.mu_s": [0, 0.05, 0.1]}, [("surfaces.0.mu_d", 0.9, None)], out, "cpu", resume=True)
    assert [p["surfaces.0.mu_s"] for p, _ in results] == [0, 0.05, 0.1] and not folder.exists()
    assert_same_sweep(out, reference)
    with h5py.File(out) as f:  # the copied points' dimensions are their own group's (io.dimensions)
        assert f["runs/0001/pellets/landing/range"].dims[0][0].name == "/runs/0001/pellet"
        assert f["runs/0002/pellets/initial/position"].dims[1][0].name == "/runs/0002/xyz"
        assert f["stats/range_mean"].dims[0][0].name == "/point"
    with h5py.File(reference) as f:
        for i, (_, stats) in enumerate(results):
            assert set(stats) == set(f["stats"])  # points read back from their files too
            assert all(stats[k] == f[f"stats/{k}"][i] or (np.isnan(stats[k]) and np.isnan(f[f"stats/{k}"][i])) for k in stats)


# ---------------------------------------------------------------------------------------------- limits


def test_huge_products_are_refused_in_one_line_before_any_memory_is_spent(tmp_path):
    values = list(range(100_000))
    scene = load_scene(SCENE, SETS[1::2])
    tracemalloc.start()
    try:
        with pytest.raises(wr.SceneError) as caught:
            wr.sweep(scene, {"surfaces.0.mu_s": values, "surfaces.0.restitution": values}, output=tmp_path / "x.h5")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6, peak
    text = str(caught.value)
    assert text == (
        f"--param = 2 keys: surfaces.0.mu_s (100,000 values) x surfaces.0.restitution (100,000 values) give "
        f"10,000,000,000 points; a sweep may have at most {MAX_SWEEP_POINTS:,} (MAX_SWEEP_POINTS)"
    )
    assert list(tmp_path.iterdir()) == []
    # on the command line: one parameter over the limit, and a product over it
    for params, start in (
        (
            ["surfaces.0.mu_s=0:99999:1"],
            "surfaces.0.mu_s = 'surfaces.0.mu_s=0:99999:1': gives 100,000 points; a sweep may have at most 10,000",
        ),
        (
            ["surfaces.0.mu_s=0:0.9999:0.0001", "surfaces.0.restitution=0:0.9999:0.0001"],
            "--param = 2 keys: surfaces.0.mu_s (10,000 values) x surfaces.0.restitution (10,000 values) give 100,000,000 points",
        ),
    ):
        argv = ["sweep", SCENE, "--device", "cpu", "-o", tmp_path / "y.h5"]
        for p in params:
            argv += ["--param", p]
        rc, _, err = cli(argv)
        assert rc == 2 and len(err.splitlines()) == 1 and err.startswith(PREFIX + start), err
    assert list(tmp_path.iterdir()) == []


def test_points_are_lazy_and_in_product_order():
    points = wr.api.sweep_points({"a": [1, 2, 3], "b": [10.0, 20.0]}, [("c", 0.5, "b")])
    assert len(points) == 6
    assert list(points) == [{"a": a, "b": b, "c": 0.5 * b} for a in (1, 2, 3) for b in (10.0, 20.0)]
    assert points[-1] == {"a": 3, "b": 20.0, "c": 10.0}


def test_a_bad_point_is_found_before_the_first_point_runs(tmp_path):
    out = tmp_path / "bad.h5"
    rc, _, err = cli(["sweep", *ARGS[:-4], "--param", "surfaces.0.mu_s=0.1,0.2,-1", "--tie", "surfaces.0.mu_d=0.9*", "-o", out])
    assert rc == 2 and len(err.splitlines()) == 1 and "surfaces.0.mu_s" in err and "-1" in err, err
    assert list(tmp_path.iterdir()) == []


def test_trajectory_frames_are_refused_in_a_sweep_file(tmp_path):
    rc, _, err = cli(
        [
            "sweep",
            SCENE,
            "--device",
            "cpu",
            "--set",
            "collisions.enabled=true",
            "--set",
            "collisions.frame_every=10",
            "--param",
            "surfaces.0.restitution=0,0.1",
            "-o",
            tmp_path / "f.h5",
        ]
    )
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith(PREFIX + "collisions.frame_every = 10"), err
    assert list(tmp_path.iterdir()) == []


def test_a_point_interrupted_while_its_file_was_set_up_is_run_again(interrupted, reference):
    """Its NNNN.h5.partial holds no /progress (and no chunk): --resume runs that point again."""
    out, folder = interrupted
    with h5py.File(folder / "0001.h5.partial", "r+") as f:
        del f["progress"]
    rc, _, err = cli(["sweep", *ARGS, "-o", out, "--resume"])
    assert rc == 0, err
    assert_same_sweep(out, reference)


# ---------------------------------------------------------------------------------------------- memory


def test_a_sweep_keeps_no_point_s_landing_counts(tmp_path):
    """Issue 24, item 5: each point's landing counts (3.7 MB with the four hazard thresholds of
    examples/hazard.toml) stayed in the list a sweep returns, so its memory grew with every point.
    Python's allocations (tracemalloc sees NumPy's arrays) from point 2 to point 6 of a sweep file:
    16 MB before, now about 0.1 MB (bench/sweep_memory.py measures 1,000 points). Without a file each
    point keeps the results of its counts instead (less the map)."""
    from warp_ricochet.tallies.quantiles import summarize

    hazard, sets = ROOT / "examples" / "hazard.toml", ["shot.shots=1", "shot.count=20"]
    scene, values, traced = load_scene(hazard, sets), [0.04 * i for i in range(6)], []

    def progress(done, total):
        if done * len(values) % total == 0:  # a point done
            traced.append(tracemalloc.get_traced_memory()[0])

    tracemalloc.start()
    try:
        results = wr.sweep(scene, {"surfaces.0.restitution": values}, output=tmp_path / "s.h5", device="cpu", progress=progress)
    finally:
        tracemalloc.stop()
    assert len(traced) == len(values) and traced[-1] - traced[1] < 1e6, traced
    assert all(stats.tally is None for _, stats in results)
    [(_, stats)] = wr.sweep(scene, {"surfaces.0.restitution": [0.04]}, device="cpu")
    alone = wr.run(load_scene(hazard, [*sets, "surfaces.0.restitution=0.04"]), device="cpu")
    expected = summarize(alone.tally, int(alone["landed"]))
    assert stats.tally is None and expected.pop("map") is not None and sorted(stats.summary) == sorted(expected)
    np.testing.assert_equal(stats.summary, expected)
