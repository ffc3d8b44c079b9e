"""Issue 14's smaller items: `report --paper` only for the paper's scene, collision statistics in the
summary and `report`, the installed example scenes (`warp-ricochet example`), LICENSE and CHANGELOG.
CPU, 200 pellets a point."""

import io
import os
import tomllib
from contextlib import redirect_stdout
from pathlib import Path

import h5py
import numpy as np
import pytest

from warp_ricochet.cli import main
from warp_ricochet.examples import example_text, examples
from warp_ricochet.report import Results, format_tables
from warp_ricochet.report.papercheck import differences, is_papers, paper_scene, row_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
SMALL = ["--set", "shot.count=200", "--device", "cpu"]
PREFIX = "warp-ricochet: error: "


def run_main(argv) -> tuple[int, str]:
    out = io.StringIO()
    with redirect_stdout(out):
        rc = main(argv)
    return rc, out.getvalue()


def paper_blocks(text: str) -> list[str]:
    return [b for b in text.split("\n\n") if "[paper: Zohdi 2021]" in b.splitlines()[0]]


# ---------------------------------------------------------------------------------------------- --paper


def test_paper_comparison_only_where_the_scene_is_the_papers(tmp_path):
    """A sweep over mu_s and shot.speed: the paper's values beside ours at 411.48 m/s only; the
    other speed's points get one line naming the key that differs."""
    out = tmp_path / "speed.h5"
    rc, text = run_main(
        [
            "sweep",
            SCENE,
            *SMALL,
            "--param",
            "surfaces.0.mu_s=0,0.05",
            "--param",
            "shot.speed=300,411.48",
            "--tie",
            "surfaces.0.mu_d=0.9*surfaces.0.mu_s",
            "-o",
            str(out),
            "--paper",
        ]
    )
    assert rc == 0
    notes = [line for line in text.splitlines() if line.startswith("paper: ")]
    assert len(notes) == 1 and "2 of 4 points" in notes[0] and "shot.speed = 300.0 (paper: 411.48)" in notes[0]
    table3 = [b for b in paper_blocks(text) if b.startswith("Table 3.")][0].splitlines()
    rows = [r.split() for r in table3[3:]]
    assert [(r[0], r[1]) for r in rows] == [("0.050", "411.480"), ("0.000", "411.480")]
    with h5py.File(out, "r") as f:  # our <L> at mu_s = 0, 411.48 m/s, then the paper's
        point = int(np.flatnonzero((f["sweep/surfaces.0.mu_s"][()] == 0.0) & (f["sweep/shot.speed"][()] == 411.48))[0])
        ours = f"{f['stats/range_mean'][point]:.3f}"
    assert rows[1][2:4] == [ours, "172.016"] and ours != "172.016"
    assert all(r[-1].endswith("%") for r in rows)


def test_paper_comparison_does_not_apply_in_air(tmp_path):
    out = tmp_path / "air.h5"
    assert run_main(["run", SCENE, *SMALL, "--set", "air.density=1.225", "-o", str(out)])[0] == 0
    rc, text = run_main(["report", str(out), "--paper"])
    assert rc == 0 and not paper_blocks(text)
    notes = [line for line in text.splitlines() if line.startswith("paper: ")]
    assert len(notes) == 1 and "does not apply to this run" in notes[0] and "air.density = 1.225" in notes[0]
    assert "Table 3." in text  # our values always


def test_the_papers_scene_test():
    base = Path(SCENE).read_text()
    assert paper_scene()["shot"]["speed"] == 411.48
    assert is_papers(base, {}, [])
    point = {"surfaces.0.mu_s": 0.2, "surfaces.0.mu_d": 0.18, "shot.count": 1000.0, "shot.seed": 7.0}
    assert is_papers(base, point, list(point))  # friction, count and seed do not matter
    for key, value in (
        ("shot.speed", 300.0),
        ("surfaces.0.restitution", 0.5),
        ("physics.bounces", 2.0),
        ("collisions.enabled", True),
        ("air.density", 1.0),
    ):
        diffs = differences(row_scene(base, {key: value}, [key]))
        assert diffs and diffs[0][0].startswith(key.split(".")[0]), key
    assert not is_papers("not toml [", {}, [])


def test_report_paper_keeps_our_values_for_a_row_the_paper_lacks():
    rows = [{"surfaces.0.mu_s": 0.42, "surfaces.0.mu_d": 0.378, "pellets": 1.0, "stick": 1.0, "slip": 0.0, "range_mean": 123.0}]
    results = Results(
        rows=rows,
        params=["surfaces.0.mu_s"],
        tied=["surfaces.0.mu_d"],
        meta={"kind": "sweep", "scene_toml": Path(SCENE).read_text()},
    )
    text = format_tables(results, paper=True)
    assert "123.000" in text and not paper_blocks(text)
    assert "paper: Zohdi (2021) has no row for mu_s = 0.42" in text


# ---------------------------------------------------------------------------------------------- collisions


def test_collision_statistics_in_the_summary_and_report(tmp_path):
    out = tmp_path / "c.h5"
    rc, summary = run_main(
        [
            "run",
            SCENE,
            "--device",
            "cpu",
            "--set",
            "shot.count=60",
            "--set",
            "shot.shots=2",
            "--set",
            "collisions.enabled=true",
            "--set",
            'numerics.precision="float64"',
            "-o",
            str(out),
        ]
    )
    assert rc == 0
    for label in ("collided (fraction)", "pair collisions", "energy lost in them", "dense steps mean/max"):
        assert label in summary
    rc, text = run_main(["report", str(out)])
    block = [b for b in text.split("\n\n") if b.startswith("Pellet-pellet collisions")][0].splitlines()
    assert rc == 0 and "pair collisions" in block[1] and block[3].startswith("run")


def test_no_collision_table_without_collisions(tmp_path):
    out = tmp_path / "r.h5"
    rc, summary = run_main(["run", SCENE, *SMALL, "-o", str(out)])
    assert rc == 0 and "pair collisions" not in summary
    assert "Pellet-pellet collisions" not in run_main(["report", str(out)])[1]


# ---------------------------------------------------------------------------------------------- examples


def test_every_example_scene_is_installed_once():
    """The package's example scenes are the checkout's examples/*.toml (links, one copy); its
    example rasters ship as package data."""
    package = ROOT / "warp_ricochet" / "examples"
    scenes = sorted(p.name for p in (ROOT / "examples").glob("*.toml"))
    assert sorted(p.name for p in package.glob("*.toml")) == scenes
    for name in scenes:
        assert (package / name).resolve() == (ROOT / "examples" / name).resolve(), name
    assert [name for name, _ in examples()] == [n[:-5] for n in scenes]
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert data["warp_ricochet.examples"] == ["*.toml", "terrain/*.asc"]  # the scenes, and the trap field's raster
    assert (package / "terrain" / "trap_field.asc").is_file()


def test_example_command(tmp_path, capsys):
    assert main(["example"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert any(line.startswith("paper ") and "Zohdi (2021)" in line for line in listed)
    assert main(["example", "paper"]) == 0
    assert capsys.readouterr().out == Path(SCENE).read_text()
    target = tmp_path / "mine.toml"
    assert main(["example", "steel_plate", "-o", str(target)]) == 0
    assert target.read_text() == example_text("steel_plate")
    capsys.readouterr()
    for argv in (["example", "nope"], ["example", "paper", "-o", str(target)], ["example", "paper", "-o", str(tmp_path)]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(PREFIX), argv
    assert target.read_text() == example_text("steel_plate")  # not overwritten
    assert main(["example", "paper", "-o", str(target), "--overwrite"]) == 0
    assert target.read_text() == Path(SCENE).read_text()
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


@pytest.mark.parametrize("name", ["LICENSE", "CHANGELOG.md"])
def test_license_and_changelog(name):
    text = (ROOT / name).read_text()
    if name == "LICENSE":
        assert text.startswith("MIT License") and "2026 the warp-ricochet authors" in text
        project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
        assert project["license"] == "MIT" and project["license-files"] == ["LICENSE"]
    else:
        assert "## [Unreleased]" in text and "## [0.1.0]" in text and "keepachangelog.com" in text
