"""Tests of the `warp-ricochet` command line (cli), the report tables (report, paper) and the progress bar.

A few end-to-end calls run `python -m warp_ricochet.cli` in a subprocess; the rest call `main([...])`
in-process. Scenes are small (200 pellets, CPU) so the whole file runs in seconds.
"""

import io
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from warp_ricochet import cli
from warp_ricochet.cli import main
from warp_ricochet.progress import ProgressBar
from warp_ricochet.report import Results, format_tables, frictional_case, read_results
from warp_ricochet.report.paper import PAPER_ROWS, TABLE1, TABLE2, TABLE3, paper_row

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
SMALL = ["--set", "shot.count=200", "--device", "cpu"]
PREFIX = "warp-ricochet: error: "


def cli_subprocess(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "warp_ricochet.cli", *args], capture_output=True, text=True, cwd=cwd, timeout=120
    )


def error_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith(PREFIX)]


def table_blocks(out: str) -> dict[str, list[str]]:
    """Text output -> {"Table 1": [data rows], ...} for our own tables (not the paper's)."""
    tables = {}
    for block in out.split("\n\n"):
        lines = block.strip("\n").splitlines()
        if lines and lines[0].startswith("Table ") and "[paper" not in lines[0]:
            tables[lines[0].split(".")[0]] = lines[3:]  # title, header, dashes, rows
    return tables


@pytest.fixture(scope="module")
def sweep_run(tmp_path_factory):
    """The sweep of the brief, run once in-process: (path, stdout)."""
    path = tmp_path_factory.mktemp("sweep") / "sweep.h5"
    capture = io.StringIO()
    old, sys.stdout = sys.stdout, capture
    try:
        rc = main(
            ["sweep", SCENE, *SMALL, "--param", "surfaces.0.mu_s=0:0.1:0.05", "--tie", "surfaces.0.mu_d=0.9*", "-o", str(path)]
        )
    finally:
        sys.stdout = old
    assert rc == 0
    return path, capture.getvalue()


# ---------------------------------------------------------------------------------------------- run


def test_run_end_to_end_writes_complete_file(tmp_path):
    out = tmp_path / "run.h5"
    proc = cli_subprocess("run", SCENE, *SMALL, "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "pellets" in proc.stdout and "mean range <L>" in proc.stdout and " m/s" in proc.stdout
    assert "Warp 1.19" not in proc.stdout  # warp's banner stays off our output
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == "warp-ricochet"
        assert f.attrs["kind"] == "run"
        assert f.attrs["status"] == "complete"
        assert math.isfinite(float(f["stats/range_mean"][()]))
        assert float(f["stats/pellets"][()]) == 200


def test_run_refuses_to_overwrite_then_overwrites(tmp_path):
    out = tmp_path / "run.h5"
    assert main(["run", SCENE, *SMALL, "-o", str(out)]) == 0
    before, mtime = out.read_bytes(), out.stat().st_mtime_ns

    proc = cli_subprocess("run", SCENE, *SMALL, "-o", str(out))
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(PREFIX) and "exists" in lines[0] and "--overwrite" in lines[0]
    assert out.read_bytes() == before and out.stat().st_mtime_ns == mtime

    assert main(["run", SCENE, *SMALL, "-o", str(out), "--overwrite"]) == 0
    assert out.stat().st_mtime_ns != mtime
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "complete"


@pytest.mark.parametrize(
    "assignment, key",
    [
        ("surfaces.0.restitution=1.5", "surfaces.0.restitution"),
        ("shot.count=0", "shot.count"),
        ("shot.no_such_key=1", "shot.no_such_key"),
    ],
)
def test_bad_set_is_one_line_and_writes_nothing(tmp_path, capsys, assignment, key):
    out = tmp_path / "bad.h5"
    assert main(["run", SCENE, "--device", "cpu", "--set", assignment, "-o", str(out)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(PREFIX) and key in lines[0]
    assert captured.out == ""
    assert not out.exists()


def test_bad_set_end_to_end_has_no_traceback(tmp_path):
    out = tmp_path / "bad.h5"
    proc = cli_subprocess("run", SCENE, "--set", "surfaces.0.restitution=1.5", "-o", str(out))
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert proc.stderr.startswith(PREFIX) and "surfaces.0.restitution" in proc.stderr
    assert not out.exists()


def test_unavailable_device_is_one_line(tmp_path, capsys):
    import warp as wp

    if wp.get_cuda_device_count() > 7:
        pytest.skip("this machine has a cuda:7")
    out = tmp_path / "dev.h5"
    assert main(["run", SCENE, "--set", "shot.count=200", "--device", "cuda:7", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    lines = error_lines(err)
    assert len(lines) == 1 and "cuda:7" in lines[0]
    assert "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("name", ["cuda:7", "cuda", "gpu"])
def test_unknown_device_is_exactly_one_stderr_line_in_a_fresh_process(tmp_path, name):
    """Warp's native start-up warnings and errors (no CUDA driver) must not make it more lines."""
    import warp as wp

    if name.startswith("cuda") and wp.get_cuda_device_count() > (7 if name == "cuda:7" else 0):
        pytest.skip(f"this machine has {name}")
    proc = cli_subprocess("run", SCENE, "--set", "shot.count=20", "--device", name, "-o", str(tmp_path / "d.h5"))
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith(f"warp-ricochet: error: device = '{name}'")


def test_run_without_output_prints_summary(capsys):
    assert main(["run", SCENE, *SMALL]) == 0
    out = capsys.readouterr().out
    assert "no output file" in out and "L+ (longest)" in out and "L- (shortest)" in out


def test_os_error_and_interrupt(monkeypatch, capsys, tmp_path):
    from warp_ricochet import api

    def disk_full(*args, **kwargs):
        raise OSError(28, "No space left on device", str(tmp_path / "x.h5"))

    monkeypatch.setattr(api, "run", disk_full)
    assert main(["run", SCENE, *SMALL]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(PREFIX) and "No space left" in lines[0]

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(api, "run", interrupted)
    assert main(["run", SCENE, *SMALL]) == 130
    assert capsys.readouterr().err.strip() == "warp-ricochet: interrupted"  # no -o: nothing kept


# ---------------------------------------------------------------------------------------------- sweep and report


def test_sweep_writes_file_and_prints_three_tables(sweep_run):
    path, out = sweep_run
    with h5py.File(path, "r") as f:
        assert f.attrs["kind"] == "sweep" and f.attrs["status"] == "complete"
        assert list(f["sweep"].attrs["parameters"]) == ["surfaces.0.mu_s"]
        mu_s = f["sweep/surfaces.0.mu_s"][()]
        np.testing.assert_allclose(f["sweep/surfaces.0.mu_d"][()], 0.9 * mu_s)
        assert f["stats/range_mean"].shape == (3,)
    tables = table_blocks(out)
    assert sorted(tables) == ["Table 1", "Table 2", "Table 3"]
    for name in ("Table 1", "Table 2"):  # the pre-impact row, the same at every point, once; a post row per point
        assert [r.split()[:2] for r in tables[name]] == [
            ["all", "pre"],
            ["0.100", "post"],
            ["0.050", "post"],
            ["0.000", "post"],
        ], tables[name]
    rows = tables["Table 3"]
    assert len(rows) == 3
    assert [r.split()[0] for r in rows] == ["0.100", "0.050", "0.000"]  # the paper's order: descending
    assert rows[-1].split()[4] == "All-slip"  # mu_s = 0: nothing can stick
    assert "device: cpu" in out and "status: complete" in out and "pellets: 200" in out
    results = read_results(path)
    assert [r["surfaces.0.mu_s"] for r in results.rows] == [0.1, 0.05, 0.0]
    assert results.params == ["surfaces.0.mu_s"] and results.tied == ["surfaces.0.mu_d"]


def test_report_text_is_the_sweep_output(sweep_run, capsys):
    path, out = sweep_run
    assert main(["report", str(path)]) == 0
    assert capsys.readouterr().out == out
    header = out.splitlines()[0]
    assert str(path) in header


def test_report_markdown(sweep_run, capsys):
    path, _ = sweep_run
    assert main(["report", str(path), "--format", "markdown"]) == 0
    out = capsys.readouterr().out
    blocks = [b for b in out.split("\n\n") if b.startswith("| ")]
    assert len(blocks) == 3
    for block in blocks:
        lines = block.splitlines()
        assert lines[1].startswith("|---") or lines[1].startswith("|:--")
        assert all(line.startswith("| ") and line.endswith(" |") for line in lines[2:])
    assert len(blocks[2].splitlines()) == 2 + 3
    assert "\\<L\\> (m)" in blocks[2]  # no raw <...>: GitHub would read it as HTML; no &lt;: a terminal shows it raw
    assert "\\|\\|\\<omega\\>\\|\\|" in blocks[0] and "&lt;" not in out and "&gt;" not in out


def test_report_paper(sweep_run, capsys):
    path, _ = sweep_run
    assert main(["report", str(path), "--paper"]) == 0
    out = capsys.readouterr().out
    assert "[paper: Zohdi 2021]" in out
    assert "172.016" in out and "92.908" in out and "21.888" in out  # <L> at mu_s = 0, 0.05, 0.1
    paper3 = [b for b in out.split("\n\n") if b.startswith("Table 3.") and "[paper" in b][0].splitlines()[3:]
    assert [r.split()[0] for r in paper3] == ["0.100", "0.050", "0.000"]
    assert all(r.rstrip().endswith("%") for r in paper3)


def test_report_run_file(tmp_path, capsys):
    out = tmp_path / "run.h5"
    assert main(["run", SCENE, *SMALL, "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["report", str(out), "--paper"]) == 0
    text = capsys.readouterr().out
    ours = table_blocks(text)
    assert [r.split()[0] for r in ours["Table 3"]] == ["run"]
    assert [r.split()[:2] for r in ours["Table 1"]] == [["run", "pre"], ["run", "post"]]
    assert "21.888" in text  # the paper's row for the scene's mu_s = 0.5


def test_report_puts_vacuum_and_air_side_by_side(sweep_run, tmp_path, capsys):
    """Two sweeps of the same points (vacuum, air): one Table 3 with each file's columns, matched
    by mu_s, the same numbers as each file's own report; different sweeps are refused in one line."""
    vacuum, _ = sweep_run
    air = tmp_path / "air.h5"
    assert (
        main(
            [
                "sweep",
                SCENE,
                *SMALL,
                "--set",
                "air.density=1.225",
                "--param",
                "surfaces.0.mu_s=0:0.1:0.05",
                "--tie",
                "surfaces.0.mu_d=0.9*",
                "-o",
                str(air),
            ]
        )
        == 0
    )
    capsys.readouterr()
    assert main(["report", str(vacuum), str(air)]) == 0
    out = capsys.readouterr().out
    block = [b for b in out.split("\n\n") if b.startswith("Table 3.")][0].splitlines()
    assert "vacuum, air" in block[0] and "<L> (m) vacuum" in block[1] and "<L> (m) air" in block[1]
    rows = [r.split() for r in block[3:]]
    column = {h: i for i, h in enumerate(re.split(r"\s{2,}", block[1].strip()))}
    assert [r[0] for r in rows] == ["0.100", "0.050", "0.000"]
    for path, label in ((vacuum, "vacuum"), (air, "air")):
        want = {round(r["surfaces.0.mu_s"], 3): r["range_mean"] for r in read_results(path).rows}
        with h5py.File(path) as f:  # the distance from the shooter: each point's landing quantiles
            levels = list(f["runs/0000/stats/quantiles"].attrs["levels"])
            far = {
                round(mu, 3): f[f"runs/{i:04d}/stats/quantiles/distance"][levels.index(0.999)]
                for i, mu in enumerate(f["sweep/surfaces.0.mu_s"][()])
            }
        for r in rows:
            assert float(r[column[f"<L> (m) {label}"]].replace(",", "")) == pytest.approx(want[float(r[0])], abs=5e-4)
            assert float(r[column[f"distance P99.9 (m) {label}"]].replace(",", "")) == pytest.approx(far[float(r[0])], abs=5e-4)
    assert float(rows[2][column["<L> (m) air"]]) < 0.5 * float(rows[2][column["<L> (m) vacuum"]].replace(",", ""))
    assert "distance: horizontal, from the shooter" in block[0]
    other = tmp_path / "other.h5"
    assert main(["sweep", SCENE, *SMALL, "--param", "surfaces.0.restitution=0.1,0.2", "-o", str(other)]) == 0
    capsys.readouterr()
    assert main(["report", str(vacuum), str(other)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "side by side needs the same sweep" in err[0]


def test_report_missing_and_bad_inputs(tmp_path, capsys):
    text = tmp_path / "notes.txt"
    text.write_text("not hdf5\n")
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = 1
    for path, words in (
        (tmp_path / "missing.h5", "does not exist"),
        (text, "not an HDF5 file"),
        (foreign, "not a warp-ricochet output file"),
        (tmp_path, "directory"),
    ):
        assert main(["report", str(path)]) == 2
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(PREFIX + "report = ") and words in lines[0], lines
        assert captured.out == ""


def test_report_missing_file_end_to_end(tmp_path):
    proc = cli_subprocess("report", str(tmp_path / "missing.h5"))
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [PREFIX + f"report = {str(tmp_path / 'missing.h5')!r}: does not exist"]


# ---------------------------------------------------------------------------------------------- argparse


@pytest.mark.parametrize("argv", [["--help"], ["run", "--help"], ["sweep", "--help"], ["report", "--help"], ["--version"]])
def test_help_and_version_exit_0(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip()


def test_usage_errors_are_one_line_exit_2(capsys):
    """The README's promise: argparse's errors too are one line `warp-ricochet: error: ...`, exit 2."""
    for argv, words in (
        ([], "COMMAND"),
        (["run"], "SCENE.toml"),
        (["sweep", SCENE], "--param"),
        (["report", "x.h5", "--format", "html"], "invalid choice: 'html'"),
        (["run", SCENE, "--bogus"], "unrecognized arguments: --bogus"),
    ):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and err.startswith(PREFIX) and words in err, (argv, err)
        assert "--help)" in err and "usage:" not in err


def test_help_end_to_end():
    proc = cli_subprocess("sweep", "--help")
    assert proc.returncode == 0 and "--param" in proc.stdout and "--tie" in proc.stdout


def test_bad_param_and_tie_are_one_line(capsys):
    for extra in (
        ["--param", "surfaces.0.mu_s=0:0.1:-0.05"],
        ["--param", "surfaces.0.mu_s=0,0.1", "--tie", "x"],
        ["--param", "surfaces.0.mu_s=0.1", "--param", "surfaces.0.mu_s=0.2"],
    ):
        assert main(["sweep", SCENE, *SMALL, *extra]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(PREFIX)


# ---------------------------------------------------------------------------------------------- units


def test_progress_bar_is_silent_without_a_tty():
    stream = io.StringIO()
    bar = ProgressBar("run", stream)
    bar(1, 2)
    bar(2, 2)
    bar.close()
    assert stream.getvalue() == ""


def test_progress_bar_draws_on_a_tty():
    stream = io.StringIO()
    with ProgressBar("run", stream, enabled=True) as bar:
        bar(0, 1000)
        bar(1000, 1000)
    text = stream.getvalue()
    assert text.startswith("\rrun:") and text.endswith("\n") and text.count("\n") == 1
    assert "100%" in text and "pellets/s" in text and "1.00k/1.00k" in text


def test_progress_rate_and_eta_count_only_this_session(monkeypatch):
    """After --resume the first report already counts the rows done before: the rate is this
    session's rows over this session's time, and the time left follows from it."""
    import tqdm.std

    now = [1000.0]
    monkeypatch.setattr(tqdm.std, "time", lambda: now[0])
    stream = io.StringIO()
    with ProgressBar("run", stream, enabled=True) as bar:
        bar(5000, 10000)  # resumed at 5,000 rows
        now[0] += 2.0
        bar(7000, 10000)  # 2,000 rows in 2 s
    lines = stream.getvalue().split("\r")
    second = [line for line in lines if "7.00k/10.0k" in line][0]
    assert "1.00k pellets/s" in second and "00:02<00:03" in second  # 3,000 rows left at 1,000/s


def test_frictional_case_and_tables_from_rows():
    assert frictional_case({"stick": 5.0, "slip": 0.0}) == "All-stick"
    assert frictional_case({"stick": 0.0, "slip": 5.0}) == "All-slip"
    assert frictional_case({"stick": 1200.0, "slip": 3.0}) == "Mixed: stick+slip (1,200 stick / 3 slip)"
    rows = [
        {"surfaces.0.mu_s": mu, "pellets": 1.0, "stick": 1.0, "slip": 0.0, "post_norm_mean_omega": 29880.2391}
        for mu in (0.0, 0.5)
    ]
    text = format_tables(Results(rows=rows, params=["surfaces.0.mu_s"], meta={"kind": "sweep"}))
    assert "29,880.239" in text and "n/a" in text and "mu_s" in text


def test_pre_impact_rows_are_shown_once_only_when_the_same_at_every_point():
    """Sweeping friction leaves the pre-impact means alone: one pre row; sweeping the speed does not."""

    def row(mu, speed):
        return {"surfaces.0.mu_s": mu, "pre_mean_vt": speed, "post_mean_vt": 0.7 * speed * (1 - mu)}

    same = table_blocks(
        format_tables(Results(rows=[row(0.1, 290.0), row(0.0, 290.0)], params=["surfaces.0.mu_s"], meta={"kind": "sweep"}))
    )
    assert [r.split()[:3] for r in same["Table 1"]] == [
        ["all", "pre", "290.000"],
        ["0.100", "post", "182.700"],
        ["0.000", "post", "203.000"],
    ]
    differ = table_blocks(
        format_tables(Results(rows=[row(0.1, 290.0), row(0.0, 300.0)], params=["surfaces.0.mu_s"], meta={"kind": "sweep"}))
    )
    assert [r.split()[:3] for r in differ["Table 1"]] == [
        ["0.100", "pre", "290.000"],
        ["0.100", "post", "182.700"],
        ["0.000", "pre", "300.000"],
        ["0.000", "post", "210.000"],
    ]


def test_paper_tables_are_consistent():
    assert len(TABLE1) == len(TABLE2) == 22 and len(TABLE3) == 11
    assert sorted(PAPER_ROWS, reverse=True) == [round(0.5 - 0.05 * i, 3) for i in range(11)]
    row = paper_row(0.05)
    assert row["post_mean_vt"] == 158.212 and row["range_max"] == 164.918 and row["case"] == "Mixed: stick+slip"
    assert paper_row(0.0)["range_min"] == 169.308 and paper_row(0.42) is None
    assert all(len(r) == len(PAPER_ROWS[0.5]) for r in PAPER_ROWS.values())


def test_cli_imports_no_warp():
    proc = subprocess.run(
        [sys.executable, "-c", "import sys, warp_ricochet.cli, warp_ricochet.report; print('warp' in sys.modules)"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.stdout.strip() == "False"
    assert cli.PROG == "warp-ricochet" and os.path.exists(SCENE)


def test_sigterm_marks_the_partial_file_interrupted(tmp_path):
    import signal
    import time

    import h5py

    out = tmp_path / "long.h5"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "warp_ricochet.cli",
            "run",
            SCENE,
            "--device",
            "cpu",
            "--set",
            "shot.count=60000000",
            "--set",
            'output.fields=["landing.range"]',
            "--set",
            "numerics.chunk_size=1000000",
            "-o",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    partial = tmp_path / "long.h5.partial"
    deadline = time.time() + 60
    while time.time() < deadline:  # wait until some chunks are on disk
        time.sleep(0.2)
        if partial.exists() and partial.stat().st_size > 8_000_000:
            break
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err  # (the handler only records it: never swallowed, interrupts.py)
    assert len(err.splitlines()) == 1 and err.startswith("warp-ricochet: interrupted"), err
    assert not out.exists()
    with h5py.File(partial, "r") as f:
        assert f.attrs["status"] == "interrupted"
        assert f["pellets/landing/range"].shape[0] >= 1_000_000  # whole chunks
        assert f["pellets/landing/range"].shape[0] % (1 << 16) == 0


# ---------------------------------------------------------------------------------------------- --version, -q, -v


def test_version_names_the_package_warp_and_the_devices():
    import warp

    from warp_ricochet import __version__

    proc = cli_subprocess("--version")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == f"warp-ricochet {__version__}"
    assert lines[1] == f"Warp {warp.__version__}"
    assert lines[2].startswith("devices: ") and "cpu" in lines[2]


def test_quiet_and_verbose_set_the_logging_level(tmp_path):
    """A scene in which no pellet hits warns (SceneWarning, through `py.warnings`); -q hides it, -v adds
    the package's informational lines; an error stays one line, exit 2, even with -q."""
    away = [*SMALL, "--set", "surfaces.0.normal=[0, -1, 0]"]
    plain = cli_subprocess("run", SCENE, *away)
    quiet = cli_subprocess("-q", "run", SCENE, *away)
    verbose = cli_subprocess("run", SCENE, *away, "--verbose")
    assert plain.returncode == quiet.returncode == verbose.returncode == 0
    assert plain.stderr.splitlines() == [
        "warp-ricochet: warning: no pellet hit any surface (all 200 missed): check "
        "shot.direction and the surfaces' points and normals (a plane is hit only "
        "from the side its normal points to)"
    ]
    assert quiet.stderr == "" and quiet.stdout == plain.stdout
    info = [line for line in verbose.stderr.splitlines() if line.startswith("warp-ricochet: info: ")]
    assert info[0] == "warp-ricochet: info: 200 pellets on cpu, float32, in vacuum" and "pellets/s" in info[1]
    assert plain.stderr.splitlines()[0] in verbose.stderr.splitlines()
    bad = cli_subprocess("run", SCENE, "--set", "shot.count=-1", "-q")
    assert bad.returncode == 2 and bad.stderr.splitlines() == error_lines(bad.stderr) and len(error_lines(bad.stderr)) == 1
    debug = cli_subprocess("-vv", "run", SCENE, *SMALL)
    assert "warp-ricochet: debug: 200 of 200 pellets complete" in debug.stderr.splitlines(), debug.stderr
    assert "debug" not in verbose.stderr
    both = cli_subprocess("run", SCENE, "-q", "-v")
    assert both.returncode == 2 and "not allowed with argument" in both.stderr


def test_a_standard_output_that_cannot_be_written_ends_with_status_120(tmp_path):
    """`entry` ends with os._exit, which flushes nothing: output left in the buffer that cannot be
    written (a full disk: /dev/full) must still fail the command, with CPython's own status 120."""
    script = (
        "import warp_ricochet.cli as c\n"
        "def main():\n"
        "    print('x' * 100)  # (buffered: stdout is a file)\n"
        "    return 0\n"
        "c.main = main\n"
        "c.entry()\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    env.pop("PYTHONUNBUFFERED", None)  # (buffered, as a plain shell runs it)
    with open("/dev/full", "w") as full:
        proc = subprocess.run([sys.executable, "-c", script], stdout=full, stderr=subprocess.PIPE, env=env, timeout=120)
    assert proc.returncode == 120, proc.stderr
