"""Ctrl-C and SIGTERM at random moments end a run at once, in one line, exit status 130, its completed
chunks kept in OUT.h5.partial and resumable bitwise (warp_ricochet.interrupts).

Three kinds of run, 30 trials each (SIGINT and SIGTERM in turn, at a random moment): a core run in
air (no collisions; chunks of a segment), a run of many small shots with collisions, and one large
collision shot (its dense phase is one native launch on the CPU, stopped by its flag). The trials
run `cli.main` in this process (no start-up cost, the kernels stay loaded) with the signal sent to
the process from a timer thread; a run that the signal reached after its end is told apart. Every
sixth trial's partial is resumed and compared bitwise with an uninterrupted run. Two trials run
the command in a subprocess, as a user would. Latency bounds here are generous (the figures are
measured by `python -m bench.interrupts`, bench/RESULTS.md).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.interrupts import quiet_main, trial

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
TRIALS = 30
RESUME_EVERY = 6
MAX_LATENCY = 5.0  # s, signal to return (a generous bound: the figures are in bench/RESULTS.md)
COLLISIONS = ["collisions.enabled=true", 'numerics.precision="float64"', 'output.fields=["landing.range", "collisions.count"]']
# kind: (--set overrides, the window of the signal's moment in s (None: 0.6 x an uninterrupted run's
# duration, then compared with it after --resume), its pellets)
KINDS = {
    # in air (chunks of one segment on the CPU): 4 chunks, about 1.5 s on one core
    "core": (["shot.count=200000", "air.density=1.225", 'output.fields=["landing.range"]'], None, 200_000),
    # 2,348 shots of 20 pellets: a whole chunk of 2,048 shots and a short one
    "shots": (
        [
            "shot.count=20",
            "shot.shots=2348",
            "shot.envelope_center=[0.0, 0.05, 0.0]",
            "surfaces.0.restitution=0.5",
            "numerics.chunk_size=40960",
            *COLLISIONS,
        ],
        None,
        46_960,
    ),
    # one shot of 1e5 pellets: its dense phase takes minutes (so no uninterrupted run to compare with;
    # signals in its first 1.5 s), in launches that only the stop flag ends; its launches not separated
    # (that is one launch too: test_a_large_shot_stops_from_the_command_line)
    "large": (["shot.count=100000", "shot.envelope_radius=0.3", "collisions.separate=false", *COLLISIONS], 1.5, 100_000),
}

WARM_UP = {"core": "shot.count=1000", "shots": "shot.shots=2"}


def argv(kind, out, *extra):
    sets = [a for s in KINDS[kind][0] for a in ("--set", s)]
    return ["run", SCENE, "--device", "cpu", *sets, "-o", str(out), *extra]


def same_results(a, b):
    """Every dataset of /pellets and /stats of two run files bitwise equal (NaN equal to NaN)."""
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        assert fa.attrs["status"] == fb.attrs["status"] == "complete"
        names = []
        for group in ("pellets", "stats"):
            fa[group].visititems(
                lambda name, obj, g=group: names.append(f"{g}/{name}") if isinstance(obj, h5py.Dataset) else None
            )
        assert names
        for name in names:
            x, y = fa[name][()], fb[name][()]
            assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name


@pytest.mark.parametrize("kind", list(KINDS))
def test_signals_at_random_moments(tmp_path, kind):
    """30 signals (SIGINT and SIGTERM in turn) at random moments: each ends the run at once in one line
    with status 130 and no "Exception ignored"; the partial holds whole chunks, and (every sixth
    trial) resumes to the uninterrupted result bitwise."""
    reference = None
    window = KINDS[kind][1]
    if window is None:  # the signal's moment: within the uninterrupted run's duration
        warm = argv(kind, tmp_path / "warm.h5", "--set", WARM_UP[kind])  # (the kernels loaded first)
        assert trial(warm, 1e6, signal.SIGINT)[0] == 0
        reference = tmp_path / "reference.h5"
        start = time.perf_counter()
        status, lines, _, _ = trial(argv(kind, reference), 1e6, signal.SIGINT)  # (a timer that never fires)
        assert status == 0, lines
        window = 0.6 * (time.perf_counter() - start)
    rng = random.Random(13)
    latencies, late = [], 0
    for k in range(TRIALS):
        out = tmp_path / f"t{k}.h5"
        partial = Path(str(out) + ".partial")
        signum = (signal.SIGINT, signal.SIGTERM)[k % 2]
        status, lines, unraisable, latency = trial(argv(kind, out), rng.uniform(0.0, window), signum)
        assert not unraisable and not any("Exception ignored" in line for line in lines), lines
        if latency is None:  # the run had ended before the signal (trial checks it): complete
            late += 1
            assert status == 0 and out.exists() and not partial.exists(), lines
            continue
        assert status == 130, lines
        assert len(lines) == 1 and lines[0].startswith("warp-ricochet: interrupted"), lines
        assert latency < MAX_LATENCY
        latencies.append(latency)
        if out.exists():  # the signal came after the last chunk: the run completed and says so
            assert lines[0] == f"warp-ricochet: interrupted; the run had completed: its result is in {out}"
            same_results(out, reference)
            continue
        if not partial.exists():  # the signal came before the run had made its file: nothing kept, nothing named
            assert lines == ["warp-ricochet: interrupted"], lines
            continue
        assert lines[0] == (
            f"warp-ricochet: interrupted; the chunks completed are in {partial} "
            "(warp-ricochet run ... --resume continues the run)"
        ), lines
        with h5py.File(partial, "r") as f:
            assert f.attrs["status"] == "interrupted"
            rows, chunk = int(f["progress/rows"][()]), int(f["progress/chunk_rows"][()])
            assert rows in (0, KINDS[kind][2]) or (chunk and rows % chunk == 0)  # whole chunks
        if reference is not None and k % RESUME_EVERY == 0:
            status, lines, _ = quiet_main(argv(kind, out, "--resume"))
            assert status == 0 and lines == [], lines
            same_results(out, reference)
        else:
            partial.unlink()
    print(
        f"{kind}: {len(latencies)} interrupted, {late} after the end; latency max {max(latencies):.3f} s, "
        f"median {float(np.median(latencies)):.3f} s"
    )
    assert len(latencies) >= TRIALS // 2  # (most signals land inside the run)


@pytest.mark.parametrize("signum, separate", [(signal.SIGTERM, "true"), (signal.SIGINT, "false")])
def test_a_large_shot_stops_from_the_command_line(tmp_path, signum, separate):
    """The command in a subprocess, one shot of 1e5 pellets with and without separated launches, in
    its dense phase (one native launch on the CPU; the separation takes ~20 ms and is stopped by its
    flag too: test_launch_overlaps): the signal ends it within MAX_LATENCY s, one line (after the
    scene's warning), status 130, its partial marked interrupted."""
    out = tmp_path / "large.h5"
    partial = Path(str(out) + ".partial")
    args = argv("large", out, "--set", f"collisions.separate={separate}")
    proc = subprocess.Popen(
        [sys.executable, "-m", "warp_ricochet.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    deadline = time.time() + 60
    while not partial.exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.02)
    time.sleep(1.0)  # into the dense phase
    sent = time.perf_counter()
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    latency = time.perf_counter() - sent
    assert proc.returncode == 130, err
    lines = [line for line in err.splitlines() if not line.startswith("warp-ricochet: warning: one shot")]
    assert lines == [
        f"warp-ricochet: interrupted; the chunks completed are in {partial} (warp-ricochet run ... --resume continues the run)"
    ], err  # (after the scene's warning)
    assert latency < MAX_LATENCY
    with h5py.File(partial, "r") as f:
        assert f.attrs["status"] == "interrupted" and f["progress/rows"][()] == 0


def test_the_api_raises_keyboard_interrupt(tmp_path):
    """warp_ricochet.run from Python: Ctrl-C raises KeyboardInterrupt to the caller, the partial kept,
    and the default SIGINT handler is back afterwards."""
    import warp_ricochet as wr
    from warp_ricochet.scene import load_scene

    out = tmp_path / "api.h5"
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as info:
            wr.run(load_scene(SCENE, KINDS["large"][0]), out, device="cpu")
    finally:
        timer.join()
    assert info.value.partial_path == str(out) + ".partial"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with h5py.File(info.value.partial_path, "r") as f:
        assert f.attrs["status"] == "interrupted"


def test_the_rename_of_a_finished_file_holds_signals(tmp_path, monkeypatch):
    """A signal during the move into place waits until the move is done (then reaches its handler)."""
    from warp_ricochet.io import runfile

    partial, path = tmp_path / "a.h5.partial", tmp_path / "a.h5"
    partial.write_bytes(b"x")
    moved = []

    def move(*args):
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)  # (the handler would run here, between the link and the unlink)
        moved.append(args)
        real_move(*args)

    real_move = runfile._move
    monkeypatch.setattr(runfile, "_move", move)
    with pytest.raises(KeyboardInterrupt):
        runfile.move_into_place(partial, path, overwrite=False)
    assert moved and path.read_bytes() == b"x" and not partial.exists()


# the steps of a run's end, in order: (module, attribute, object in it or None, signal before or after)
END_STEPS = [
    ("warp_ricochet.io.writer", "RunWriter", "write_stats", "after"),
    ("warp_ricochet.io.runfile", "OutputFile", "__exit__", "before"),
    ("warp_ricochet.io.runfile", None, "_move", "before"),
    ("warp_ricochet.io.runfile", None, "move_into_place", "after"),
    ("warp_ricochet.io.runfile", None, "write_xdmf", "before"),
    ("warp_ricochet.io.runfile", None, "publish_sidecar", "after"),
    ("warp_ricochet.progress", "ProgressBar", "__exit__", "before"),
    ("warp_ricochet.report", None, "format_run_summary", "after"),
    ("warp_ricochet.cli", None, "_run_command", "after"),
]


def signal_at(monkeypatch, step, signum):
    """Send `signum` to this process when the run reaches `step` (an END_STEPS entry)."""
    import importlib

    module, owner, name, when = step
    target = importlib.import_module(module)
    target = getattr(target, owner) if owner else target
    real = getattr(target, name)

    def hooked(*args, **kwargs):
        if when == "before":
            os.kill(os.getpid(), signum)
        result = real(*args, **kwargs)
        if when == "after":
            os.kill(os.getpid(), signum)
        return result

    monkeypatch.setattr(target, name, hooked)


@pytest.mark.parametrize("step", END_STEPS, ids=[f"{s[3]}-{s[2]}" for s in END_STEPS])
def test_a_signal_at_each_step_of_a_runs_end(tmp_path, monkeypatch, step):
    """A signal at every step of a run's end, from its statistics to the command's return (the
    result complete, or being moved into place): exit status 130 and the one line saying where the
    complete result is; the result and its sidecar in place, no partial left."""
    out = tmp_path / "end.h5"
    signum = (signal.SIGINT, signal.SIGTERM)[END_STEPS.index(step) % 2]
    signal_at(monkeypatch, step, signum)
    status, lines, unraisable = quiet_main(argv("core", out, "--set", "shot.count=1000"))
    assert status == 130 and not unraisable, lines
    assert lines == [f"warp-ricochet: interrupted; the run had completed: its result is in {out}"]
    assert out.exists() and out.with_suffix(".xmf").exists() and not Path(str(out) + ".partial").exists()


LATE = """
import atexit, os, signal, sys
from warp_ricochet import cli
signum, when = int(sys.argv[1]), sys.argv[2]
sys.argv = ["warp-ricochet", *sys.argv[3:]]
if when == "main returned":
    real = cli.main
    cli.main = lambda: (real(), os.kill(os.getpid(), signum))[0]
else:  # an exit function: registered before Warp's, so it runs after them
    atexit.register(os.kill, os.getpid(), signum)
cli.entry()
"""


@pytest.mark.parametrize("signum, when", [(signal.SIGTERM, "main returned"), (signal.SIGINT, "exit functions")])
def test_a_signal_after_the_command_returned_exits_130(tmp_path, signum, when):
    """The command line (`cli.entry`) after `main` returned: while Python's exit functions run, a
    signal still gives exit status 130 and the one line (the interpreter's teardown is skipped)."""
    out = tmp_path / "late.h5"
    proc = subprocess.run(
        [sys.executable, "-c", LATE, str(int(signum)), when, *argv("core", out, "--set", "shot.count=100")],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=120,
    )
    assert proc.returncode == 130, (proc.returncode, proc.stderr)
    assert proc.stderr.splitlines() == [f"warp-ricochet: interrupted; the run had completed: its result is in {out}"]
    assert out.exists() and "pellets" in proc.stdout  # (the summary was printed before)
