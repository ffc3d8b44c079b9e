"""--resume of runs with pellet-pellet collisions.

A collision run computes chunks of whole shots, each but the last a multiple of
`dense.schedule.shot_granule` shots (whole statistics segments of slots): here 5 pellets a shot, so a
chunk is 8,192 shots (40,960 pellets). The scene is the paper's shot lowered to 5 cm above a
livelier ground, with a fixed 0.5 ms step and one event round per step, so a chunk takes about 0.6 s
on the CPU and a few percent of the pellets collide. Each case compares every per-pellet dataset,
every statistic and the stored partials bitwise with one uninterrupted run (`reference`).
"""

import math
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import (
    assert_resume_refused,
    assert_same_run,
    cli,
    interrupt_after,
    stats_equal,
    wait_for_a_chunk,
)
from warp_ricochet.dense.schedule import segments_of_shots, shot_granule
from warp_ricochet.io.writer import RunWriter
from warp_ricochet.scene import load_scene
from warp_ricochet.tallies.collisions import SHOT_TOTALS

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
COUNT = 5
GRANULE = shot_granule(COUNT)  # shots per chunk
CHUNK = COUNT * GRANULE  # pellets per chunk
SHOTS = 2 * GRANULE + 3  # two whole chunks and a short last one
CHUNK_ENDS = [CHUNK, 2 * CHUNK, SHOTS * COUNT]  # /progress/rows after each chunk
OVERRIDES = [
    f"shot.count={COUNT}",
    f"shot.shots={SHOTS}",
    "shot.envelope_center=[0.0, 0.05, 0.0]",
    "surfaces.0.restitution=0.5",
    "collisions.enabled=true",
    "collisions.time_step=5e-4",
    "collisions.rounds=1",
    f"numerics.chunk_size={CHUNK}",
    'output.fields=["initial.position", "impact.velocity", "landing.range", "landing.time", '
    '"collisions.count", "collisions.last_time", "release.velocity"]',
]
ARGS = ["--device", "cpu"] + [a for o in OVERRIDES for a in ("--set", o)]
FIELDS = (
    "initial/position",
    "impact/velocity",
    "landing/range",
    "landing/time",
    "collisions/count",
    "collisions/last_time",
    "release/velocity",
)
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def scene():
    return load_scene(SCENE, OVERRIDES)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted run: (path, stats)."""
    path = tmp_path_factory.mktemp("reference") / "ref.h5"
    stats = wr.run(scene(), path, device="cpu")
    with h5py.File(path, "r") as f:  # the case the tests are about: whole chunks with collisions
        assert f["progress/chunk_rows"][()] == CHUNK and f["progress/rows"][()] == SHOTS * COUNT
        counts = f["pellets/collisions/count"][()]
        assert counts[:CHUNK].sum() > 0 and counts[CHUNK : 2 * CHUNK].sum() > 0
    assert stats["pair_energy_lost"] > 0 and stats["landed"] > 0
    return path, stats


def assert_same_as_reference(path, reference):
    """Every per-pellet dataset, every statistic and the stored partials (statistics and per-shot
    totals) bitwise equal; status complete."""
    assert_same_run(path, reference[0], FIELDS, progress=("segment_results", "shot_totals", "shot_partials"))


def check_partial(partial, reference, *, swmr):
    """The partial opens; its complete rows are whole chunks of whole shots, equal to the
    reference's with their partials and per-shot totals: returns them."""
    with h5py.File(partial, "r", swmr=swmr) as f, h5py.File(reference[0], "r") as b:
        rows = int(f["progress/rows"][()])
        assert rows in (0, *CHUNK_ENDS)
        shots, segments = rows // COUNT, segments_of_shots(rows // COUNT, COUNT)
        for name in FIELDS:
            np.testing.assert_array_equal(f[f"pellets/{name}"][:rows], b[f"pellets/{name}"][:rows], err_msg=name)
        np.testing.assert_array_equal(f["progress/segment_results"][:segments], b["progress/segment_results"][:segments])
        np.testing.assert_array_equal(f["progress/shot_totals"][:shots], b["progress/shot_totals"][:shots])
    return rows


def test_shot_totals_are_stored_per_shot(reference):
    """/progress/shot_totals holds one row per shot, whose sums and maxima are the collision statistics."""
    path, stats = reference
    with h5py.File(path, "r") as f:
        table = f["progress/shot_totals"]
        assert table.shape == (SHOTS, len(SHOT_TOTALS)) and list(table.attrs["columns"]) == list(SHOT_TOTALS)
        table = table[()]
        counts = f["pellets/collisions/count"][()].reshape(SHOTS, COUNT)
    assert np.array_equal(table[:, 0], (counts > 0).sum(axis=1))
    assert np.array_equal(table[:, 1], counts.sum(axis=1))
    assert stats["pair_energy_lost"] == math.fsum(table[:, 2]) and stats["dense_steps_max"] == table[:, 3].max()


def test_the_run_in_one_chunk_is_bitwise_the_same(tmp_path, reference):
    """What resuming on whole chunks relies on: a shot's results, the statistics partials and the
    per-shot totals do not depend on the chunks (here three against one; the chunk-size test of
    test_collisions.py has too few shots to make two chunks)."""
    one = load_scene(SCENE, [*OVERRIDES, f"numerics.chunk_size={3 * CHUNK}"])
    calls = []
    wr.run(one, tmp_path / "one.h5", device="cpu", progress=lambda done, total: calls.append(done))
    assert calls == [SHOTS * COUNT]
    assert_same_as_reference(tmp_path / "one.h5", reference)


@pytest.mark.parametrize("at_chunk", [0, 1, 2, 3])
def test_ctrl_c_after_any_chunk_then_resume_is_bitwise_identical(tmp_path, monkeypatch, reference, at_chunk):
    """Ctrl-C right after chunk k is written (k = 0: before any; k = 3: after the last, before
    /stats): k chunks complete, and the resumed run computes only the missing chunks."""
    out = tmp_path / "c.h5"
    if at_chunk == 0:

        def interrupted(self, *args, **kwargs):
            raise KeyboardInterrupt

        monkeypatch.setattr(RunWriter, "append", interrupted)
        with pytest.raises(KeyboardInterrupt):
            wr.run(scene(), out, device="cpu")
        monkeypatch.undo()
    else:
        interrupt_after(at_chunk, scene(), out)
    partial = Path(str(out) + ".partial")
    with h5py.File(partial, "r") as f:
        assert f.attrs["status"] == "interrupted"
    assert check_partial(partial, reference, swmr=False) == ([0] + CHUNK_ENDS)[at_chunk]
    resumed = []
    stats = wr.run(scene(), out, device="cpu", resume=True, progress=lambda done, total: resumed.append(done))
    assert resumed == CHUNK_ENDS[at_chunk:]
    assert_same_as_reference(out, reference)
    assert stats_equal(stats, reference[1])


def test_a_chunk_written_but_not_committed_is_computed_again(tmp_path, monkeypatch, reference):
    """Interrupted between flushing chunk 2 (rows, partials, per-shot totals) and counting its rows:
    the file holds rows and totals past /progress/rows, which the resumed run cuts off and computes
    again (folding them in as well would count those shots twice)."""
    real = h5py.Dataset.__setitem__

    def commit(self, key, value):
        if self.name == "/progress/rows" and value == 2 * CHUNK:
            raise KeyboardInterrupt
        return real(self, key, value)

    monkeypatch.setattr(h5py.Dataset, "__setitem__", commit)
    out = tmp_path / "u.h5"
    with pytest.raises(KeyboardInterrupt):
        wr.run(scene(), out, device="cpu")
    monkeypatch.undo()
    partial = Path(str(out) + ".partial")
    with h5py.File(partial, "r") as f:
        assert f["progress/rows"][()] == CHUNK
        assert len(f["progress/shot_totals"]) == 2 * GRANULE and len(f["pellets/landing/range"]) == 2 * CHUNK
    check_partial(partial, reference, swmr=False)
    resumed = []
    wr.run(scene(), out, device="cpu", resume=True, progress=lambda done, total: resumed.append(done))
    assert resumed == CHUNK_ENDS[1:]
    assert_same_as_reference(out, reference)


def test_sigkill_then_resume_is_bitwise_identical(tmp_path, reference):
    """A real SIGKILL once a chunk is complete (HDF5's flags of a killed writer set), then --resume.
    The kill must land in the half second the rest of the run takes after its first chunk: a run
    that ended first is tried again (up to 3 times) before the test gives up."""
    for attempt in range(3):
        out = tmp_path / f"k{attempt}.h5"
        proc = subprocess.Popen(
            [sys.executable, "-m", "warp_ricochet.cli", "run", SCENE, *ARGS, "-o", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=ENV,
        )
        partial = Path(str(out) + ".partial")
        wait_for_a_chunk(proc, partial, timeout=120)
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=60)
        if not out.exists():
            break
    else:
        pytest.skip("the run ended before SIGKILL, 3 times")
    with h5py.File(partial, "r", swmr=True) as f:
        assert f.attrs["status"] == "running"  # never closed
    assert check_partial(partial, reference, swmr=True) > 0
    rc, _, err = cli(["run", SCENE, *ARGS, "-o", out, "--resume"])
    assert rc == 0, err
    assert_same_as_reference(out, reference)


@pytest.fixture(scope="module")
def interrupted_once(tmp_path_factory):
    """A collision run interrupted after its first chunk: its partial file."""
    out = tmp_path_factory.mktemp("interrupted") / "i.h5"
    interrupt_after(1, scene(), out)
    return Path(str(out) + ".partial")


@pytest.fixture
def interrupted(tmp_path, interrupted_once):
    """A copy of `interrupted_once` to resume: (output path, partial path)."""
    out = tmp_path / "i.h5"
    partial = Path(str(out) + ".partial")
    shutil.copy(interrupted_once, partial)
    return out, partial


@pytest.mark.parametrize(
    "extra, edit, start",
    [
        (
            ["--set", f"numerics.chunk_size={2 * CHUNK}"],
            None,
            f"numerics.chunk_size = {2 * CHUNK}: the interrupted run had {CHUNK}",
        ),
        (["--set", "collisions.restitution=0.5"], None, "collisions.restitution = 0.5: the interrupted run had 0.9"),
        (["--set", f"shot.shots={SHOTS + 1}"], None, f"shot.shots = {SHOTS + 1}: the interrupted run had {SHOTS}"),
        (["--set", "collisions.frame_every=8"], None, "collisions.frame_every = 8: must be 0 for --resume"),
        (
            [],
            lambda f: f["progress/shot_totals"].resize(GRANULE - 1, axis=0),
            f"output path = PARTIAL: is inconsistent ({GRANULE - 1} per-shot collision totals for {GRANULE} shots)",
        ),
        (
            [],
            lambda f: f["progress/chunk_rows"].__setitem__((), CHUNK // 2),
            f"output path = PARTIAL: is inconsistent (chunk plan of {CHUNK // 2} pellets per chunk",
        ),
        (
            [],
            lambda f: f.__delitem__("progress/shot_totals"),
            "output path = PARTIAL: holds no per-shot collision totals (written by an older version)",
        ),
    ],
)
def test_resume_refuses_a_different_collision_run_in_one_line_and_changes_nothing(interrupted, extra, edit, start):
    """A different chunk size is refused like any other change of the scene (the chunk plan of the
    interrupted run is kept), as are trajectory frames and a partial whose records do not agree."""
    out, partial = interrupted
    assert_resume_refused(
        ["run", SCENE, *ARGS, *extra, "-o", out, "--resume"], out, edit, start.replace("PARTIAL", repr(str(partial)))
    )


def test_a_run_with_trajectory_frames_is_not_resumed(tmp_path):
    """Frames are written during a chunk's dense phase, before its commit: such a run is refused in
    one line (key, value, what is allowed), the file unchanged, and --overwrite runs it again."""
    raw = ["shot.count=30", "collisions.enabled=true", "collisions.frame_every=8"]
    frames = load_scene(SCENE, raw)
    out = tmp_path / "f.h5"
    interrupt_after(1, frames, out)  # its only chunk complete, /stats not written
    assert_resume_refused(
        ["run", SCENE, "--device", "cpu", *(a for o in raw for a in ("--set", o)), "-o", out, "--resume"],
        out,
        None,
        "collisions.frame_every = 8: must be 0 for --resume (H5MD trajectory frames are "
        "not resumed); --overwrite starts a run with frames again\n",
    )
    wr.run(frames, out, device="cpu", overwrite=True)
    with h5py.File(out, "r") as f:
        assert f["particles/pellets/position/value"].shape[0] > 1
