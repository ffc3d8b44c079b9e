"""Faults during long runs: kills at random moments, Ctrl-C, --resume, a full disk, permissions, and
readers watching a run (HDF5 SWMR).

The promises: an interrupted run leaves NAME.partial that opens with h5py (`swmr=True` after a
SIGKILL, plainly after Ctrl-C or SIGTERM), with every chunk counted in /progress/rows intact;
`run --resume` ends with per-pellet datasets and /stats bitwise equal to an uninterrupted run's; a
resume that does not match is refused in one line without changing the file; a full disk or a
permission problem ends with one line, not a corrupt file; a second process can read the rows
complete while the run writes. Each case compares against one uninterrupted run (`reference`).
"""

import contextlib
import errno
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import (
    assert_resume_refused,
    assert_same_run,
    cli,
    digest,
    held,
    interrupt_after,
    stats_equal,
    wait_for_a_chunk,
)
from warp_ricochet.cli import main
from warp_ricochet.io import space, writer
from warp_ricochet.scene import load_scene
from warp_ricochet.tallies.reduce import SEGMENT

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
CHUNKS = 24  # of 65,536 pellets (the smallest chunk): every kill lands between or inside chunks
SETS = [
    "--set",
    f"shot.count={CHUNKS * SEGMENT - 1000}",
    "--set",
    "numerics.chunk_size=65536",
    "--set",
    "numerics.precision='float64'",
    "--set",
    "surfaces.0.mu_s=0.05",
    "--set",
    "surfaces.0.mu_d=0.045",
    "--set",
    'output.fields=["landing.range", "impact.velocity", "initial.position"]',
]
ARGS = ["--device", "cpu", *SETS]
FIELDS = ("landing/range", "impact/velocity", "initial/position")
PREFIX = "warp-ricochet: error: "
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted run: (path, stats)."""
    path = tmp_path_factory.mktemp("reference") / "ref.h5"
    stats = wr.run(load_scene(SCENE, SETS[1::2]), path, device="cpu")
    return path, stats


def assert_same_as_reference(path, reference):
    """Every per-pellet dataset, every statistic and the statistics partials bitwise equal; status complete."""
    assert_same_run(path, reference[0], FIELDS)


def check_partial(partial, reference, *, swmr):
    """The partial opens; its complete rows are whole chunks equal to the reference's: returns them."""
    ref, _ = reference
    with h5py.File(partial, "r", swmr=swmr) as f, h5py.File(ref, "r") as b:
        rows = int(f["progress/rows"][()])
        assert f.attrs["status"] in ("running", "interrupted", "failed")
        pellets = b["constants/pellets"][()]
        assert (rows % SEGMENT == 0 or rows == pellets) and 0 <= rows <= pellets
        assert len(f["progress/segment_results"]) >= rows // SEGMENT
        for name in FIELDS:
            assert f[f"pellets/{name}"].shape[0] >= rows
            np.testing.assert_array_equal(f[f"pellets/{name}"][:rows], b[f"pellets/{name}"][:rows], err_msg=name)
        np.testing.assert_array_equal(
            f["progress/segment_results"][: rows // SEGMENT], b["progress/segment_results"][: rows // SEGMENT]
        )
    return rows


def start_run(out, *extra):
    return subprocess.Popen(
        [sys.executable, "-m", "warp_ricochet.cli", "run", SCENE, *ARGS, "-o", str(out), *extra],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )


# ---------------------------------------------------------------------------------------------- kills


def test_sigkill_at_random_moments_then_resume_is_bitwise_identical(tmp_path, reference):
    """SIGKILL at a random moment (during start-up, set-up, a chunk or a flush): NAME.partial opens
    (HDF5 refuses a plain open of a file whose writer died, so readers use swmr=True), holds whole
    chunks equal to the uninterrupted run's, and --resume ends bitwise identical to it."""
    seed = random.randrange(1 << 30)
    rng = random.Random(seed)
    kills = []
    for trial in range(3):
        out = tmp_path / f"k{trial}.h5"
        proc = start_run(out)
        partial = Path(str(out) + ".partial")
        if trial == 0:  # early: while Python, Warp and the file start (no partial, or no rows yet)
            time.sleep(rng.uniform(0.0, 1.0))
        else:  # once chunks are being written
            deadline = time.time() + 60
            while not partial.exists() and proc.poll() is None and time.time() < deadline:
                time.sleep(0.01)
            time.sleep(rng.uniform(0.0, 0.6))
        proc.kill()
        proc.wait(timeout=60)
        if out.exists():  # it finished first
            assert_same_as_reference(out, reference)
            kills.append("after the end")
            continue
        if not partial.exists():  # killed before the file was published: nothing to resume, nothing lost
            rc, _, err = cli(["run", SCENE, *ARGS, "-o", out, "--resume"])
            assert rc == 2 and "nothing to resume" in err and len(err.splitlines()) == 1
            kills.append("before the file")
            assert cli(["run", SCENE, *ARGS, "-o", out])[0] == 0  # a set-up file left behind is no obstacle
            assert_same_as_reference(out, reference)
            continue
        rows = check_partial(partial, reference, swmr=True)
        kills.append(f"{rows} rows")
        rc, _, err = cli(["run", SCENE, *ARGS, "-o", out, "--resume"])
        assert rc == 0, err
        assert not partial.exists()
        assert_same_as_reference(out, reference)
    print(f"seed {seed}: killed at {kills}")


@pytest.mark.parametrize("at_chunk", [0, 1, 7, CHUNKS - 1, CHUNKS])
def test_ctrl_c_after_any_chunk_then_resume_is_bitwise_identical(tmp_path, monkeypatch, reference, at_chunk):
    """Ctrl-C (KeyboardInterrupt) right after chunk k is written: status "interrupted", k chunks
    complete, and the resumed run computes only the missing chunks and ends bitwise equal to the
    uninterrupted one (k = 0: before any chunk; k = CHUNKS: after the last chunk, before /stats)."""
    out = tmp_path / "c.h5"
    scene = load_scene(SCENE, SETS[1::2])
    pellets = scene.shot.count
    calls = []

    def progress(done, total):
        calls.append(done)
        if len(calls) == at_chunk:
            raise KeyboardInterrupt

    if at_chunk == 0:

        def interrupted(self, *args, **kwargs):
            raise KeyboardInterrupt

        monkeypatch.setattr(writer.RunWriter, "append", interrupted)
    with pytest.raises(KeyboardInterrupt):
        wr.run(scene, out, device="cpu", progress=progress)
    monkeypatch.undo()
    partial = Path(str(out) + ".partial")
    with h5py.File(partial, "r") as f:  # closed cleanly: a plain open works
        assert f.attrs["status"] == "interrupted"
        assert f["progress/rows"][()] == min(at_chunk * SEGMENT, pellets)
    check_partial(partial, reference, swmr=False)
    resumed = []
    stats = wr.run(scene, out, device="cpu", resume=True, progress=lambda done, total: resumed.append(done))
    assert resumed == [min(k * SEGMENT, pellets) for k in range(at_chunk + 1, CHUNKS + 1)]
    assert_same_as_reference(out, reference)
    assert stats_equal(stats, reference[1])


def test_sigterm_then_resume_from_the_command_line(tmp_path, reference):
    out = tmp_path / "t.h5"
    proc = start_run(out)
    partial = Path(str(out) + ".partial")
    wait_for_a_chunk(proc, partial)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the run ended before SIGTERM")
    assert proc.returncode == 130
    assert err.strip().splitlines()[-1] == (
        f"warp-ricochet: interrupted; the chunks completed are in {partial} (warp-ricochet run ... --resume continues the run)"
    )
    with h5py.File(partial, "r") as f:
        assert f.attrs["status"] == "interrupted"
    check_partial(partial, reference, swmr=False)
    rc, stdout, err = cli(["run", SCENE, *ARGS, "-o", out, "--resume"])
    assert rc == 0 and err == "" and "mean range" in stdout
    assert_same_as_reference(out, reference)


# ---------------------------------------------------------------------------------------------- resume refusals


@pytest.fixture
def interrupted(tmp_path):
    """An interrupted run (3 chunks complete): (output path, partial path)."""
    out = tmp_path / "i.h5"
    interrupt_after(3, load_scene(SCENE, SETS[1::2]), out)
    return out, Path(str(out) + ".partial")


def _older_partials(f):
    """The statistics partials of an older layout (before flight_scale: two columns fewer)."""
    old = f["progress/segment_results"][()][:, :-2]
    del f["progress/segment_results"]
    f["progress"].create_dataset("segment_results", data=old, maxshape=(None, old.shape[1]))


@pytest.mark.parametrize(
    "extra, edit, key",
    [
        (["--set", "surfaces.0.mu_s=0.06"], None, "surfaces.0.mu_s = 0.06"),
        (["--set", "shot.seed=7"], None, "shot.seed = 7"),
        (["--set", "numerics.precision='float32'"], None, "numerics.precision = 'float32'"),
        (["--set", "numerics.chunk_size=131072"], None, "numerics.chunk_size = 131072"),
        (["--set", 'output.fields=["landing.range"]'], None, "output.fields = "),
        ([], lambda f: f.attrs.__setitem__("device", "cuda:0"), "device = 'cpu'"),
        ([], lambda f: f.attrs.__setitem__("warp_version", "1.18.0"), "warp_version = "),
        ([], lambda f: f["progress/rows"].__setitem__((), 3 * SEGMENT + 5), "output path = "),
        ([], lambda f: f["progress/segment_results"].resize(1, axis=0), "output path = "),
        ([], lambda f: f["pellets/landing/range"].resize(10, axis=0), "output path = "),
        ([], _older_partials, "output path = "),
        ([], lambda f: f.attrs.__setitem__("kind", "sweep"), "output path = "),
        ([], lambda f: f.__delitem__("progress"), "output path = "),
    ],
)
def test_resume_refuses_a_different_run_in_one_line_and_changes_nothing(interrupted, extra, edit, key):
    out, _ = interrupted
    assert_resume_refused(["run", SCENE, *ARGS, *extra, "-o", out, "--resume"], out, edit, key)


def test_resume_refusals_without_a_usable_partial(tmp_path, interrupted):
    out, partial = interrupted
    cases = [
        (tmp_path / "none.h5", "nothing to resume"),
        (out, "in use by another process"),
    ]
    junk = tmp_path / "junk.h5"
    Path(str(junk) + ".partial").write_bytes(b"not hdf5 at all")
    cases.append((junk, "is not an HDF5 file"))
    done = tmp_path / "done.h5"
    done.write_bytes(b"a finished result")
    shutil.copy(partial, str(done) + ".partial")
    cases.append((done, "exists; give --overwrite"))
    for path, words in cases:
        # a writer or reader holds the file
        with held(partial) if words.startswith("in use") else contextlib.nullcontext():
            rc, _, err = cli(["run", SCENE, *ARGS, "-o", path, "--resume"])
        assert rc == 2 and len(err.splitlines()) == 1 and words in err, (path, err)
    assert done.read_bytes() == b"a finished result"
    rc, _, err = cli(["run", SCENE, *ARGS, "-o", out, "--resume", "--device", "cuda:9"])
    assert rc == 2 and err.startswith(PREFIX + "device = 'cuda:9'")


def test_a_new_run_does_not_clobber_an_interrupted_one(interrupted):
    out, partial = interrupted
    before = digest(partial)
    rc, _, err = cli(["run", SCENE, *ARGS, "-o", out])
    assert rc == 2 and "--resume" in err and digest(partial) == before


def test_resume_of_a_pellet_file_run_checks_the_file(tmp_path):
    """Pellets from a file: resuming needs the same file (size and modification time), and then ends
    bitwise equal to the uninterrupted run."""
    rng = np.random.default_rng(5)
    n = 3 * SEGMENT - 7
    pellets = tmp_path / "p.npz"
    np.savez(
        pellets,
        position=rng.uniform([-1.0, 0.5, -1.0], [1.0, 3.0, 1.0], (n, 3)),
        velocity=rng.normal([20.0, -10.0, 0.0], 5.0, (n, 3)),
        angular_velocity=rng.normal(0.0, 100.0, (n, 3)),
    )
    scene = load_scene(
        SCENE,
        [
            f"shot={{file='{pellets}', diameter=0.0025, density=7000.0}}",
            "numerics.chunk_size=65536",
            'output.fields=["landing.range", "impact.angular_velocity"]',
        ],
    )
    full = wr.run(scene, tmp_path / "full.h5", device="cpu")
    out = tmp_path / "f.h5"
    interrupt_after(2, scene, out)
    st = os.stat(pellets)
    os.utime(pellets, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # touched: it may have changed
    with pytest.raises(wr.SceneError, match="shot.file = .*: changed since the interrupted run"):
        wr.run(scene, out, device="cpu", resume=True)
    os.utime(pellets, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert stats_equal(wr.run(scene, out, device="cpu", resume=True), full)
    with h5py.File(out, "r") as a, h5py.File(tmp_path / "full.h5", "r") as b:
        for name in ("landing/range", "impact/angular_velocity"):
            np.testing.assert_array_equal(a[f"pellets/{name}"][()], b[f"pellets/{name}"][()])


def test_a_multi_shot_run_without_collisions_resumes(tmp_path, monkeypatch):
    """shot.shots > 1 with collisions off: the pellets are count x shots (not count), for the check of
    the partial and for the disk space of the rest (two chunks of 4-byte ranges, 512 kB, refused
    where only a quarter of that is free)."""
    overrides = [f"shot.count={SEGMENT}", "shot.shots=3", f"numerics.chunk_size={SEGMENT}", 'output.fields=["landing.range"]']
    multi = load_scene(SCENE, overrides)
    full = wr.run(multi, tmp_path / "full.h5", device="cpu")
    out = tmp_path / "m.h5"
    interrupt_after(1, multi, out)
    monkeypatch.setattr(space, "free_bytes", lambda path: space.SPACE_MARGIN + 2 * SEGMENT)
    with pytest.raises(OSError, match="the output needs"):
        wr.run(multi, out, device="cpu", resume=True)
    monkeypatch.undo()
    stats = wr.run(multi, out, device="cpu", resume=True)
    assert stats_equal(stats, full)
    with h5py.File(out, "r") as a, h5py.File(tmp_path / "full.h5", "r") as b:
        assert a["progress/rows"][()] == 3 * SEGMENT
        np.testing.assert_array_equal(a["pellets/landing/range"][()], b["pellets/landing/range"][()])


# ---------------------------------------------------------------------------------------------- full disk


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_no_room_for_the_output_is_refused_before_any_file(tmp_path, monkeypatch, capsys, command):
    """An output that cannot fit is bad input, found before any work: one line, exit status 2."""
    monkeypatch.setattr(space, "free_bytes", lambda path: 10_000_000)
    out = tmp_path / "o.h5"
    sweep = ["--param", "physics.impact_duration=0,1e-5"] if command == "sweep" else []  # (mu_s is --set)
    assert main([command, SCENE, *ARGS, *sweep, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        PREFIX + f"output path = '{out}': cannot fit: No space left on device (the output needs"
    ), err
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("how", ["reserve", "free space"])
def test_disk_full_during_the_run_ends_in_one_line_with_a_readable_file(tmp_path, monkeypatch, capsys, reference, how):
    """The disk fills after 5 chunks: the run stops before writing the 6th, the file is closed
    cleanly (status "failed", 5 chunks), and --resume finishes it once there is room. `reserve`: the
    space reservation fails (fallocate: ENOSPC); `free space`: no reservation on this file system,
    the free-space check fails."""
    import ctypes

    chunks_written = []
    real_append = writer.RunWriter.append

    def append(self, arrays, rows, *results):
        chunks_written.append(rows)
        return real_append(self, arrays, rows, *results)

    def fallocate(fd, mode, offset, length):
        if len(chunks_written) <= 5:
            return 0
        ctypes.set_errno(errno.ENOSPC)
        return -1

    monkeypatch.setattr(writer.RunWriter, "append", append)
    if how == "reserve":
        monkeypatch.setattr(space, "_fallocate", lambda: fallocate)
    else:
        monkeypatch.setattr(space, "_fallocate", lambda: None)
        monkeypatch.setattr(space, "free_bytes", lambda path: 10**12 if len(chunks_written) <= 5 else 2_000_000)
    out = tmp_path / "o.h5"
    assert main(["run", SCENE, *ARGS, "-o", str(out)]) == 1
    err = capsys.readouterr().err
    partial = Path(str(out) + ".partial")
    assert err.count("\n") == 1, err
    assert err.startswith(PREFIX + "No space left on device (the next chunk needs") and f"'{partial}'" in err
    assert "--resume continues the run" in err
    with h5py.File(partial, "r") as f:
        assert f.attrs["status"] == "failed" and f["progress/rows"][()] == 5 * SEGMENT
    check_partial(partial, reference, swmr=False)
    monkeypatch.undo()
    assert main(["run", SCENE, *ARGS, "-o", str(out), "--resume"]) == 0
    assert_same_as_reference(out, reference)


def test_a_write_error_inside_hdf5_leaves_the_file_as_of_its_last_chunk(tmp_path, monkeypatch, capsys, reference):
    """Should the library itself hit ENOSPC (another process filled the disk between the check and
    the write), the file is detached and closed: one line, the chunks before the failure readable."""
    real = h5py.Dataset.__setitem__
    count = []

    def failing(self, key, value):
        if self.name == "/pellets/impact/velocity":
            count.append(1)
            if len(count) == 4:
                raise RuntimeError(
                    "Can't write data (file write failed: time = now, filename = 'x', file descriptor "
                    "= 5, errno = 28, error message = 'No space left on device', buf = 0x0)"
                )
        return real(self, key, value)

    monkeypatch.setattr(h5py.Dataset, "__setitem__", failing)
    out = tmp_path / "w.h5"
    assert main(["run", SCENE, *ARGS, "-o", str(out)]) == 1
    err = capsys.readouterr().err
    partial = Path(str(out) + ".partial")
    assert err.count("\n") == 1 and err.startswith(PREFIX + f"No space left on device: '{partial}'"), err
    monkeypatch.setattr(h5py.Dataset, "__setitem__", real)
    assert check_partial(partial, reference, swmr=True) == 3 * SEGMENT
    assert main(["run", SCENE, *ARGS, "-o", str(out), "--resume"]) == 0
    assert_same_as_reference(out, reference)


TMPFS_SCRIPT = r"""
set -u
mount -t tmpfs -o size={size} tmpfs {mnt} || exit 77
cd {mnt} || exit 78
{python} -m warp_ricochet.cli run {scene} {args} -o {mnt}/o.h5 2> err1.txt &
run=$!
while [ ! -e o.h5.partial ] && kill -0 $run 2>/dev/null; do sleep 0.01; done
dd if=/dev/zero of={mnt}/filler bs=64k 2>/dev/null   # another writer fills the disk while the run writes
wait $run; echo "rc1=$?"; cat err1.txt
{python} -c 'import h5py; f = h5py.File("o.h5.partial", "r"); print("status", f.attrs["status"], "rows", f["progress/rows"][()])'
rm {mnt}/filler
{python} -m warp_ricochet.cli run {scene} {args} -o {mnt}/o.h5 --resume > /dev/null 2> err2.txt; echo "rc2=$?"; cat err2.txt
cp {mnt}/o.h5 {result}
"""


def test_a_real_full_disk_on_a_small_tmpfs(tmp_path, reference):
    """A 100 MB tmpfs (in a private mount namespace) that another writer fills while the run writes
    (the output needs 88 MB): the run stops before a chunk it has no room for, in one line (exit 1),
    and its file is closed cleanly in the space it had reserved (status "failed", a plain open works);
    after freeing the space --resume ends bitwise equal to the uninterrupted run."""
    if shutil.which("unshare") is None or shutil.which("mount") is None:
        pytest.skip("needs unshare and mount")
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    script = TMPFS_SCRIPT.format(
        size="100m",
        mnt=mnt,
        python=sys.executable,
        scene=SCENE,
        result=tmp_path / "result.h5",
        args=" ".join(f"'{a}'" for a in ARGS),
    )
    namespace = ["unshare", "-m"] if os.geteuid() == 0 else ["unshare", "-Urm"]  # unprivileged: a user namespace
    proc = subprocess.run([*namespace, "sh", "-c", script], capture_output=True, text=True, env=ENV, timeout=300)
    if proc.returncode in (77, 78) or proc.stderr.startswith("unshare"):
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.strip()[:200]}")
    lines = proc.stdout.splitlines()
    assert "rc1=1" in lines, proc.stdout + proc.stderr
    err = lines[lines.index("rc1=1") + 1]
    assert err.startswith(PREFIX + "No space left on device (the next chunk needs"), proc.stdout
    status = [line for line in lines if line.startswith("status")][0].split()  # closed cleanly: a plain open
    assert status[1] == "failed" and int(status[3]) % SEGMENT == 0, status
    assert "rc2=0" in lines, proc.stdout + proc.stderr
    assert_same_as_reference(tmp_path / "result.h5", reference)


# ---------------------------------------------------------------------------------------------- permissions


def test_a_read_only_folder_is_refused_in_one_line(tmp_path):
    """Root may write anywhere: as root the command runs without the capabilities that allow it."""
    folder = tmp_path / "ro"
    folder.mkdir()
    scene = folder / "scene.toml"
    shutil.copy(SCENE, scene)
    os.chmod(folder, 0o555)
    argv = ["run", str(scene), "--device", "cpu", "--set", "shot.count=100", "-o", str(folder / "o.h5")]
    try:
        if os.geteuid() != 0:
            rc, out, err = cli(argv)
        else:
            if shutil.which("setpriv") is None:
                pytest.skip("root without setpriv: cannot drop the capability to write anywhere")
            drop = "-dac_override,-dac_read_search"
            proc = subprocess.run(
                ["setpriv", f"--inh-caps={drop}", f"--bounding-set={drop}", sys.executable, "-m", "warp_ricochet.cli", *argv],
                capture_output=True,
                text=True,
                env=ENV,
                timeout=120,
            )
            rc, out, err = proc.returncode, proc.stdout, proc.stderr
        assert rc == 2 and out == "", err
        assert err.strip().splitlines() == [PREFIX + f"output path = '{folder / 'o.h5'}': not writable (permission denied)"]
        assert sorted(os.listdir(folder)) == ["scene.toml"]
    finally:
        os.chmod(folder, 0o755)


def test_permission_denied_at_the_final_rename_is_one_line_and_keeps_the_result(tmp_path, monkeypatch, capsys):
    """The folder turned read-only during the run: the rename fails; the complete file stays as NAME.partial."""
    out = tmp_path / "o.h5"
    real_link, real_replace = os.link, os.replace

    def denied(real):
        def move(src, dst, *args, **kwargs):
            if Path(dst) == out:
                raise PermissionError(errno.EACCES, "Permission denied", str(src), None, str(dst))
            return real(src, dst, *args, **kwargs)

        return move

    monkeypatch.setattr(os, "link", denied(real_link))
    monkeypatch.setattr(os, "replace", denied(real_replace))
    assert main(["run", SCENE, "--device", "cpu", "--set", "shot.count=100", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(PREFIX + "Permission denied: ") and ".partial" in err, err
    assert not out.exists()
    with h5py.File(str(out) + ".partial", "r") as f:
        assert f.attrs["status"] == "complete" and f["progress/rows"][()] == 100


# ---------------------------------------------------------------------------------------------- watching


def test_a_second_process_reads_the_run_while_it_writes(tmp_path, reference):
    """The reader recipe of docs/output.md: open NAME.partial with swmr=True, read /progress/rows, then
    refresh the datasets and read the rows below it. It sees the count grow, and every row it reads is
    final (refreshing the datasets before reading the count could see fewer rows than the count)."""
    out = tmp_path / "w.h5"
    proc = start_run(out)
    partial = Path(str(out) + ".partial")
    seen = []
    with h5py.File(reference[0], "r") as ref:
        expected = ref["pellets/landing/range"][()]
        deadline = time.time() + 120
        while not partial.exists() and proc.poll() is None and time.time() < deadline:
            time.sleep(0.005)
        if not partial.exists():
            proc.wait()
            pytest.skip("the run ended before the reader could start")
        with h5py.File(partial, "r", swmr=True) as f:
            rows_ds, ranges = f["progress/rows"], f["pellets/landing/range"]
            while time.time() < deadline:
                rows_ds.refresh()
                rows = int(rows_ds[()])
                ranges.refresh()  # after reading the count: the rows below it were flushed before it
                if not seen or rows != seen[-1]:
                    seen.append(rows)
                    assert ranges.shape[0] >= rows
                    np.testing.assert_array_equal(ranges[:rows], expected[:rows])
                if rows == len(expected) or (proc.poll() is not None and rows == seen[-1] and len(seen) > 1):
                    break
                time.sleep(0.01)
    assert proc.wait(timeout=60) == 0, proc.stderr.read()
    assert seen[-1] == len(expected)
    assert len([r for r in seen if 0 < r < len(expected)]) >= 2, seen  # watched it grow
    assert_same_as_reference(out, reference)


def test_a_set_up_file_left_by_a_killed_run_is_reused_unless_in_use(tmp_path, reference):
    """A run killed while it set up its file leaves NAME.partial.new (no chunk in it): the next run
    replaces it; while another process holds it (a run setting up), the new run is refused."""
    out = tmp_path / "s.h5"
    staging = Path(str(out) + ".partial.new")
    staging.write_bytes(b"half an HDF5 header")
    with held(staging):
        rc, _, err = cli(["run", SCENE, *ARGS, "-o", out])
    assert rc == 2 and "in use by another process" in err and staging.read_bytes() == b"half an HDF5 header"
    assert cli(["run", SCENE, *ARGS, "-o", out])[0] == 0
    assert not staging.exists()
    assert_same_as_reference(out, reference)


def shared_lock_free(path) -> bool:
    """Whether a reader could take the shared lock HDF5 takes as it opens `path` (flock, LOCK_NB)."""
    import fcntl

    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    finally:
        os.close(fd)


@pytest.mark.parametrize("setup_fails", [False, True])
def test_the_partial_appears_only_once_a_reader_can_open_it(tmp_path, monkeypatch, setup_fails):
    """The moment NAME.partial appears (renamed from NAME.partial.new), the writer's lock on it is
    shared already, so a SWMR reader opening it at once is not refused ("unable to lock file"): after
    a normal set-up, and when the set-up fails (the file is closed, then published)."""
    from warp_ricochet.io import runfile

    seen = []

    def publish(staging, partial, *args):
        real_publish(staging, partial, *args)
        seen.append(shared_lock_free(partial))

    real_publish = runfile.publish
    monkeypatch.setattr(runfile, "publish", publish)
    if setup_fails:

        def fail(group):
            raise OSError(errno.EIO, "set-up failed")

        monkeypatch.setattr(writer, "name_run_dimensions", fail)
    out = tmp_path / "p.h5"
    scene = load_scene(SCENE, ["shot.count=100"])
    if setup_fails:
        with pytest.raises(OSError, match="set-up failed"):
            wr.run(scene, out, device="cpu")
    else:
        wr.run(scene, out, device="cpu")
    assert seen == [True]


READER = """
import sys, h5py, os
folder, n = sys.argv[1], int(sys.argv[2])
for i in range(n):
    path = os.path.join(folder, f"r{i}.h5.partial")
    while not os.path.exists(path):
        pass
    try:
        with h5py.File(path, "r", swmr=True):
            print("ok", flush=True)
    except Exception as exc:
        print("failed:", type(exc).__name__, " ".join(str(exc).split())[:100], flush=True)
"""


def test_200_immediate_opens_under_load_all_succeed(tmp_path):
    """200 run files set up one after another while every core is busy; a reader process opens each
    NAME.partial with swmr=True the moment it appears (the README's recipe): every open succeeds."""
    from warp_ricochet.io.runfile import OutputFile

    n = 200
    load = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(os.cpu_count() or 1)]
    reader = subprocess.Popen([sys.executable, "-c", READER, str(tmp_path), str(n)], stdout=subprocess.PIPE, text=True, env=ENV)
    answers = []
    try:
        for i in range(n):
            with OutputFile(tmp_path / f"r{i}.h5", overwrite=False, kind="run", device="cpu", scene_toml="") as out:
                out.h5.create_dataset("rows", data=0)
                out.start_watching()
                answers.append(reader.stdout.readline().strip())  # (the file stays until the reader opened it)
    finally:
        for proc in (*load, reader):
            proc.kill()
            proc.wait()
    assert answers == ["ok"] * n, [a for a in answers if a != "ok"][:5]


# ---------------------------------------------------------------------------------------------- special files


@contextlib.contextmanager
def watchdog(fifo, after=5.0):
    """After `after` s, opens `fifo` (both ends, so a command waiting on it goes on) and replaces it
    with an empty file (so it does not wait again); yields a list that is non-empty if it had to."""
    import threading

    fired, done = [], threading.Event()

    def unblock():
        if not done.wait(after):
            fired.append(True)
            fd = os.open(fifo, os.O_RDWR | os.O_NONBLOCK)
            os.unlink(fifo)
            Path(fifo).touch()
            os.close(fd)

    thread = threading.Thread(target=unblock, daemon=True)
    thread.start()
    try:
        yield fired
    finally:
        done.set()
        thread.join()


SPECIAL_CASES = {  # argv given the folder and a FIFO in it: the expected message's start
    "scene": (lambda d, fifo: ["run", fifo, *ARGS], "scene = '{fifo}': is a FIFO (named pipe), not a regular file"),
    "shot.file": (
        lambda d, fifo: ["run", SCENE, *ARGS, "--set", f"shot.file='{fifo}'", "--set", "shot.count=", "-o", d / "o.h5"],
        None,
    ),
    "output": (
        lambda d, fifo: ["run", SCENE, *ARGS, "-o", fifo, "--overwrite"],
        "output path = '{fifo}': is a FIFO (named pipe), not a regular file",
    ),
    "partial": (
        lambda d, fifo: ["run", SCENE, *ARGS, "-o", fifo[: -len(".partial")], "--overwrite"],
        "output path = '{out}': {name} is a FIFO (named pipe), not a regular file; remove it",
    ),
    "resumed partial": (
        lambda d, fifo: ["run", SCENE, *ARGS, "-o", fifo[: -len(".partial")], "--resume"],
        "output path = '{out}': {name} is a FIFO (named pipe), not a regular file; it cannot be resumed",
    ),
    "report": (lambda d, fifo: ["report", fifo], "report = '{fifo}': is a FIFO (named pipe), not a regular file"),
    "xdmf": (lambda d, fifo: ["xdmf", fifo], "file = '{fifo}': is a FIFO (named pipe), not a regular file"),
    "plot": (lambda d, fifo: ["plot", fifo, "-o", d / "plots"], "plot = '{fifo}': is a FIFO (named pipe), not a regular file"),
}


@pytest.mark.parametrize("case", list(SPECIAL_CASES))
def test_a_fifo_is_refused_in_one_line_without_opening_it(tmp_path, case):
    """A FIFO as the scene, the pellet file, the output, its partial, or a file to report, describe or
    plot: refused in one line (exit 2) before it is opened (opening it would wait for a writer),
    nothing made."""
    make, message = SPECIAL_CASES[case]
    name = {"shot.file": "pellets.npz", "partial": "o.h5.partial", "resumed partial": "o.h5.partial", "scene": "scene.toml"}.get(
        case, "o.h5"
    )
    fifo = str(tmp_path / name)
    os.mkfifo(fifo)
    argv = make(tmp_path, fifo)
    if case == "shot.file":  # a scene whose pellets come from the file (shot.count, speed, seed... left out)
        scene = tmp_path / "scene.toml"
        scene.write_text(
            f'[shot]\nfile = "{name}"\ndiameter = 0.0025\ndensity = 7000.0\n\n[[surfaces]]\n'
            "point = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nrestitution = 0.01\nmu_s = 0.5\n"
        )
        argv = ["run", scene, "--device", "cpu", "-o", tmp_path / "o.h5"]
        message = "shot.file = '{fifo}': is a FIFO (named pipe), not a regular file"
    with watchdog(fifo) as fired:
        rc, _, err = cli(argv)
    assert not fired, "the command waited on the FIFO"
    out = fifo[: -len(".partial")] if case.endswith("partial") else fifo
    expected = message.format(fifo=fifo, out=out, name=Path(fifo).name)  # (a scene's values are shortened)
    key, why = expected.split(" = ")[0], expected.split("': ", 1)[1]
    assert rc == 2 and err.count("\n") == 1 and err.startswith(f"{PREFIX}{key} = '") and err.endswith(f": {why}\n"), err
    assert sorted(os.listdir(tmp_path)) == sorted([name, *(["scene.toml"] if case == "shot.file" else [])])


def test_a_device_as_the_scene_is_refused_in_one_line():
    rc, _, err = cli(["run", os.devnull, "--device", "cpu"])
    assert rc == 2 and err == PREFIX + f"scene = '{os.devnull}': is a character device, not a regular file\n"


# ---------------------------------------------------------------------------------------------- report's status


def test_report_of_a_complete_file_takes_no_lock_a_reader_would_meet(tmp_path, monkeypatch):
    """`report` of a complete file takes no exclusive lock on it (which would refuse an HDF5 reader
    opening it at that instant, "unable to lock file"); with a SWMR reader holding it open it reports."""
    import fcntl

    from warp_ricochet.io import locks

    out = tmp_path / "done.h5"
    wr.run(load_scene(SCENE, SETS[1::2]), out, device="cpu")
    refused, plain = [], fcntl.flock

    def flock(fd, op):  # while an exclusive lock is held, a reader opens the file
        plain(fd, op)
        if op & fcntl.LOCK_EX:
            try:
                h5py.File(out, "r").close()
            except OSError as exc:
                refused.append(str(exc))

    monkeypatch.setattr(locks.fcntl, "flock", flock)
    with h5py.File(out, "r", swmr=True):
        rc, text, err = cli(["report", out])
    assert rc == 0 and "| status: complete |" in text, err
    rc, text, err = cli(["report", out])
    assert rc == 0 and not refused, refused


@pytest.mark.parametrize(
    "writer, lock, says",
    [
        ("alive", True, "running"),  # a run writing it: its process lives and holds its lock
        ("alive", False, "gone"),  # (no lock: its process is another one with the same id)
        ("dead", True, "gone"),  # a reader's lock keeps no dead writer "running"
        ("dead", False, "gone"),  # killed (SIGKILL)
    ],
)
def test_report_tells_a_killed_run_from_a_running_one(tmp_path, writer, lock, says):
    """`report NAME.partial` of a file marked "running": "running" only while its writer's process
    lives and a lock is held on the file; else "not finished (the writer is gone ...)"."""
    out = tmp_path / "k.h5"
    scene = load_scene(SCENE, SETS[1::2])
    interrupt_after(1, scene, out)
    partial = Path(str(out) + ".partial")
    pid = os.getpid() if writer == "alive" else _dead_pid()
    with h5py.File(partial, "r+") as f:
        f.attrs["status"] = "running"
        assert f.attrs["writer_host"]  # (the run recorded its writer)
        f.attrs["writer_pid"] = pid
    with held(partial) if lock else contextlib.nullcontext():
        rc, text, err = cli(["report", partial])
    assert rc == 0, err
    status = "running" if says == "running" else "not finished (the writer is gone: killed or crashed; --resume continues it)"
    assert f"| status: {status} |" in text, text.splitlines()[0]


def _dead_pid() -> int:
    """The id of a process that has ended."""
    proc = subprocess.Popen([sys.executable, "-c", "0"])
    proc.wait()
    return proc.pid


KILL_BEFORE_SIDECAR = """
import os, signal, sys
from warp_ricochet import cli
from warp_ricochet.io import runfile
runfile.publish_sidecar = lambda *args: os.kill(os.getpid(), signal.SIGKILL)
sys.argv = ["warp-ricochet", *sys.argv[1:]]
cli.entry()
"""


def test_a_kill_between_the_rename_and_the_sidecar_is_recovered_by_xdmf(tmp_path):
    """A SIGKILL after OUT.h5 is in place and before OUT.xmf is written (README: the sidecar comes
    after the rename) leaves the complete result without its sidecar; `warp-ricochet xdmf OUT.h5`
    writes the sidecar the run would have written."""
    killed, whole = tmp_path / "killed" / "k.h5", tmp_path / "whole" / "k.h5"
    for out in (killed, whole):
        out.parent.mkdir()
    argv = ["run", SCENE, "--device", "cpu", "--set", "shot.count=500"]
    proc = subprocess.run(
        [sys.executable, "-c", KILL_BEFORE_SIDECAR, *argv, "-o", str(killed)],
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert killed.exists() and not killed.with_suffix(".xmf").exists()
    assert not Path(str(killed) + ".partial").exists()
    with h5py.File(killed, "r") as f:
        assert f.attrs["status"] == "complete"
    assert cli(["xdmf", killed])[0] == 0
    assert cli([*argv, "-o", whole])[0] == 0
    assert killed.with_suffix(".xmf").read_text() == whole.with_suffix(".xmf").read_text()
