"""The smaller promises of issue 13 (item 4): a dangling symlink at the output refused before any work;
a partial held by a live process reported as in use (also with --overwrite and --resume); race-
dependent failures (a partial removed during the run, HDF5's open errors) as one plain line; huge
keys and values not echoed whole; `report` of a killed run's partial says how far it got; a scene
in which no pellet hits anything warns in one line."""

import ast
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import h5py
import pytest

import warp_ricochet as wr
from tests.helpers import cli, digest, held, interrupt_after
from warp_ricochet.errors import MAX_MESSAGE
from warp_ricochet.io import runfile
from warp_ricochet.scene import load_scene
from warp_ricochet.tallies.reduce import SEGMENT

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
SMALL = ["--device", "cpu", "--set", "shot.count=200"]
CHUNKED = ["shot.count=" + str(3 * SEGMENT - 10), "numerics.chunk_size=65536", 'output.fields=["landing.range"]']
PREFIX = "warp-ricochet: error: "


def one_line_error(rc, err, *words):
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith(PREFIX), err
    for w in words:
        assert w in err, err


def test_a_dangling_symlink_at_the_output_is_refused_before_any_work(tmp_path):
    out = tmp_path / "out.h5"
    out.symlink_to(tmp_path / "gone" / "target.h5")
    rc, _, err = cli(["run", SCENE, *SMALL, "-o", out])
    one_line_error(rc, err, "dangling symbolic link", "--overwrite")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5"] and out.is_symlink()
    assert cli(["run", SCENE, *SMALL, "-o", out, "--overwrite"])[0] == 0  # replaces the link itself
    assert not out.is_symlink() and h5py.is_hdf5(out)


@pytest.mark.parametrize("extra", [[], ["--overwrite"], ["--resume"]])
def test_a_partial_held_by_a_live_process_is_in_use(tmp_path, extra):
    """A live run holds a lock on its partial (shared once readers may come): not "an earlier
    interrupted run", whatever the options; the partial is left as it is."""
    out = tmp_path / "live.h5"
    partial = Path(str(out) + ".partial")
    partial.write_bytes(b"a run writing")
    with held(partial):
        rc, _, err = cli(["run", SCENE, *SMALL, "-o", out, *extra])
    one_line_error(rc, err, "live.h5.partial is in use by another process")
    assert "earlier interrupted" not in err and partial.read_bytes() == b"a run writing" and not out.exists()


def test_a_partial_removed_during_the_run_is_one_plain_line(tmp_path):
    out = tmp_path / "gone.h5"
    partial = Path(str(out) + ".partial")

    def remove_after_first_chunk(done, total):
        if partial.exists():
            partial.unlink()

    with pytest.raises(wr.OutputError) as caught:
        wr.run(load_scene(SCENE, CHUNKED), out, device="cpu", progress=remove_after_first_chunk)
    text = str(caught.value)
    assert text == (
        f"output path = {str(out)!r}: gone.h5.partial was removed during the run (by another process?); "
        "its results are lost: run it again"
    )
    assert not out.exists()


def test_hdf5_open_errors_are_one_plain_line(tmp_path, monkeypatch):
    # a damaged partial (HDF5 signature, then nothing): HDF5's own text is not echoed
    out = tmp_path / "cut.h5"
    interrupt_after(1, load_scene(SCENE, CHUNKED), out)
    partial = Path(str(out) + ".partial")
    with open(partial, "r+b") as f:
        f.truncate(4096)
    rc, _, err = cli(["run", SCENE, "--device", "cpu", *sum((["--set", s] for s in CHUNKED), []), "-o", out, "--resume"])
    one_line_error(rc, err, "cut.h5.partial cannot be resumed: HDF5 cannot open it (")
    for raw in ("Unable to", "errno =", "flags =", "[Errno"):
        assert raw not in err, err
    # the folder removed between the check and the creation of the file
    folder = tmp_path / "vanishing"
    folder.mkdir()
    check = runfile.check_output_path

    def check_then_remove(path, overwrite):
        found = check(path, overwrite)
        folder.rmdir()
        return found

    monkeypatch.setattr(runfile, "check_output_path", check_then_remove)
    rc, _, err = cli(["run", SCENE, *SMALL, "-o", folder / "x.h5"])
    one_line_error(rc, err, "x.h5.partial.new cannot be created (No such file or directory)")
    for raw in ("Unable to", "errno =", "flags ="):
        assert raw not in err, err


@pytest.mark.parametrize(
    "argv",
    [
        ["run", SCENE, "--set", "k" * 100_000 + "=1"],
        ["run", SCENE, "--set", "shot.count=" + "9" * 100_000],
        ["sweep", SCENE, "--param", "surfaces.0.mu_s=" + "x" * 100_000],
        ["run", "SCENE_FILE"],
    ],
)
def test_huge_keys_and_values_are_not_echoed_whole(tmp_path, argv):
    if argv[1] == "SCENE_FILE":  # an unknown key of 100,000 characters in a scene file
        scene = tmp_path / "long.toml"
        scene.write_text(Path(SCENE).read_text() + f"\n[{'q' * 100_000}]\nx = 1\n")
        argv = ["run", scene]
    rc, _, err = cli([*argv, "--device", "cpu"])
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith(PREFIX), err[:300]
    assert len(err) <= len(PREFIX) + MAX_MESSAGE + 1 and "..." in err


def test_report_and_plot_of_a_killed_runs_partial(tmp_path):
    out = tmp_path / "killed.h5"
    scene = load_scene(SCENE, CHUNKED)
    interrupt_after(2, scene, out)
    partial = Path(str(out) + ".partial")
    # a writer killed while the file was open for writing (SWMR) leaves flags that refuse a plain open
    code = (
        "import h5py, os, sys; f = h5py.File(sys.argv[1], 'r+', libver=('v110', 'latest'), locking=False); "
        "f.swmr_mode = True; f.attrs['status'] = 'running'; f.flush(); os._exit(0)"
    )
    subprocess.run([sys.executable, "-c", code, str(partial)], check=True)
    with pytest.raises(OSError):
        h5py.File(partial, "r").close()
    before = digest(partial)
    rc, out_text, err = cli(["report", partial])
    assert rc == 0, err
    assert (
        "status: not finished (the writer is gone: killed or crashed; --resume continues it)" in out_text
        and f"note: the run's writer is gone (killed or crashed): {2 * SEGMENT:,} of {scene.shot.count:,} pellets "
        "complete (66.7%); the statistics are written when the run completes (warp-ricochet run ... --resume "
        "continues it)"
        in out_text
    ), out_text
    rc, out_text, err = cli(["plot", partial, "-o", tmp_path / "plots"])  # plot opens it too (what needs the
    assert rc == 0 and ("wrote" in out_text or "skipped" in out_text), err  # run's final counts is skipped)
    assert digest(partial) == before


def test_a_scene_where_no_pellet_hits_anything_warns_in_one_line(tmp_path):
    scene = load_scene(SCENE, ["shot.count=300", "surfaces.0.normal=[0, -1, 0]"])  # the plane faces away
    with pytest.warns(wr.SceneWarning, match=r"no pellet hit any surface \(all 300 missed\)"):
        stats = wr.run(scene, device="cpu")
    assert stats["hits"] == 0
    proc = subprocess.run(
        [sys.executable, "-m", "warp_ricochet.cli", "run", SCENE, *SMALL, "--set", "surfaces.0.normal=[0, -1, 0]"],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert proc.returncode == 0 and proc.stderr.startswith("warp-ricochet: warning: no pellet hit any surface (all 200")
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    with warnings.catch_warnings(record=True) as record:  # a scene with hits: no SceneWarning
        warnings.simplefilter("always")
        wr.run(load_scene(SCENE, ["shot.count=300"]), device="cpu")
    assert not [w for w in record if issubclass(w.category, wr.SceneWarning)]


def test_a_launch_envelope_reaching_below_the_ground_warns_with_the_pellets_lost(tmp_path):
    """A shot whose launch envelope reaches behind the ground plane loses the pellets launched there
    (they never meet it: missed) and every statistic is of the others: the run says so in one line
    naming shot.envelope_center, how many of the pellets were lost and how high it must be."""
    scene = load_scene(SCENE, ["shot.count=300", "shot.envelope_center=[0, 0.005, 0]", "output.fields=['initial.position']"])
    path = tmp_path / "low.h5"
    with pytest.warns(wr.SceneWarning) as record:
        stats = wr.run(scene, path, device="cpu")
    with h5py.File(path) as f:
        behind = int((f["pellets/initial/position"][:, 1] < 0.0).sum())  # centres launched below the ground
    assert behind > 0 and stats["missed"] == behind  # (the pellets the warning is about)
    (message,) = [str(w.message) for w in record if issubclass(w.category, wr.SceneWarning)]
    assert message.startswith("shot.envelope_center = [0.0, 0.005, 0.0]: ") and "\n" not in message
    assert f"{behind:,} of 300 pellets" in message and "surfaces.0" in message and "0.02625 m" in message  # R + R^e
    with warnings.catch_warnings(record=True) as record:  # the envelope clear of the ground: no SceneWarning
        warnings.simplefilter("always")
        wr.run(load_scene(SCENE, ["shot.count=300", "shot.envelope_center=[0, 0.03, 0]"]), device="cpu")
    assert not [w for w in record if issubclass(w.category, wr.SceneWarning)]


def test_a_station_whose_envelope_reaches_below_the_ground_warns_with_the_pellets_lost():
    """The same for a station standing on the ground (its position the envelope's centre, the gun):
    the warning names the station's key and how many pellets missed."""
    scene = load_scene(
        ROOT / "examples" / "trap_field.toml",
        ["shot.shots=5", "stations.2.position=[-14.63, 0.0, 0.005]"],
    )
    with pytest.warns(wr.SceneWarning) as record:
        stats = wr.run(scene, device="cpu")
    assert stats["missed"] > 0
    (message,) = [str(w.message) for w in record if issubclass(w.category, wr.SceneWarning)]
    assert message.startswith("stations.2.position = [-14.63, 0.0, 0.005]: ")
    assert f"{int(stats['missed']):,} of {int(stats['pellets']):,} pellets" in message and "0.015 m behind surfaces.0" in message


def test_messages_name_an_option_to_add_in_one_wording():
    """Issue 28: every message (and any text) of the package that tells the user to add an option says
    "give --option" (the run, sweep and xdmf files said "pass --overwrite", report, plot, export and
    example "give --overwrite"); the messages themselves are tested where they arise (test_xdmf,
    test_faults, test_plots, test_gis, test_report_html, test_cluster)."""
    verbs = {}
    for path in sorted(Path(wr.__file__).parent.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                for verb in re.findall(r"\b(pass|give|supply|add|use)\s+--[a-z]", node.value):
                    verbs.setdefault(verb, []).append(path.name)
    assert set(verbs) == {"give"} and len(verbs["give"]) >= 8, verbs
