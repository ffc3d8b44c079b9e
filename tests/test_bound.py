"""Runs that go on until the danger distance is bounded ([hazard.bound], issue 26 part 1,
warp_ricochet.bound): a bound met stops the run early, a budget spent says "not bounded", the
shots added are the pellets an ordinary run of as many shots has, the bits do not depend on the
chunk size, --resume continues to the bits of an uninterrupted run, and bad input is refused."""

import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import (
    assert_opens_in_xarray,
    assert_resume_refused,
    assert_same_run,
    cli,
    interrupt_after,
    make_scene,
    paper_raw,
)
from warp_ricochet import display
from warp_ricochet.bound import BoundPlan
from warp_ricochet.errors import PrecisionWarning, SceneError
from warp_ricochet.io.bound_out import read

# the paper's shot in vacuum to its landing: every pellet is within body height above `low` at its
# launch (1 m up at 411 m/s), and 368 reaching above it bound p = 0.01, so the interval is infinite
# for the first two checks; it then narrows to one bin (0.0625 m at 124 m)
HAZARD = {"energy_density": {"low": 237_000.0}, "speed": {"fast": 212.0}, "fractions": [0.01]}


def bounded(count=100, shots=2, width=1.0, max_pellets=20_000, chunk=None, bound=True, **tables):
    raw = paper_raw(until="landing")
    raw["shot"].update(count=count, shots=shots)
    hazard = {**HAZARD, "bound": {"threshold": "low", "fraction": 0.01, "width": width, "max_pellets": max_pellets}}
    if not bound:
        del hazard["bound"]
    numerics = {"chunk_size": chunk} if chunk else {}
    return make_scene(raw, hazard=hazard, output={"fields": ["landing"]}, numerics=numerics, **tables)


def test_checks_follow_the_shots_and_the_budget_only():
    plan = BoundPlan.of(bounded(count=100, shots=2, max_pellets=2_050))
    assert plan.checks() == [200, 300, 400, 500, 600, 700, 800, 1000, 1200, 1500, 1800, 2000]
    assert BoundPlan.of(bounded(shots=3, max_pellets=300)).checks() == [300]
    # segments: each stretch between checks starts its own (65,536 pellets a segment)
    big = BoundPlan.of(bounded(count=70_000, shots=1, max_pellets=210_000))
    assert big.checks() == [70_000, 140_000, 210_000]
    assert [big.segments(n, False) for n in (65_536, 70_000, 135_536, 140_000, 210_000)] == [1, 2, 3, 4, 6]
    # where a chunk can end (what --resume accepts as rows complete)
    ends = (0, 65_536, 70_000, 135_536, 140_000, 210_000)
    assert all(big.chunk_end(n, False) for n in ends)
    assert not any(big.chunk_end(n, False) for n in (1, 65_535, 69_999, 131_072, 200_000, 210_001))


def test_a_bound_met_stops_the_run_early(tmp_path):
    out = tmp_path / "run.h5"
    stats = wr.run(bounded(width=1.0), out, device="cpu")
    b = stats.bound
    # 368 pellets reaching above `low` (all of them) bound the interval: the third check, 4 shots
    assert b.met and b.pellets == 400 and b.shots == 4 and b.checks == 3 and stats["pellets"] == 400
    assert np.isfinite(b.ci_high) and b.ci_high - b.ci_low < 1.0 and b.ci_low <= b.distance <= b.ci_high
    with h5py.File(out, "r") as f:
        found = read(f)
        assert f["constants/pellets"][()] == 400 and f["pellets/landing/range"].shape == (400,)
        assert f["stats/shots/range_mean"].shape == (4,) and f["stats/shots"].attrs["shots"] == 4
        for name in ("threshold_name", "p", "width", "max_pellets", "met", "pellets", "final_width"):
            assert "units" in f[f"hazard/bound/{name}"].attrs and f[f"hazard/bound/{name}"].attrs["description"]
    assert found["met"] and found["pellets"] == 400 and found["shots"] == 4 and found["threshold"] == "low"
    assert found["width"] == 1.0 and found["max_pellets"] == 20_000 and found["final_width"] == b.ci_high - b.ci_low
    # the interval of the file's own danger distance (summarize's) at the same p is the one the run stopped on
    with h5py.File(out, "r") as f:
        assert f["hazard/danger_distance/ci_high"][0, 0] == b.ci_high
    # its pellets are those of an ordinary run of as many shots: shots are added, pellet by index
    plain = tmp_path / "plain.h5"
    raw = paper_raw(until="landing")
    raw["shot"].update(count=100, shots=4)
    wr.run(make_scene(raw, hazard=HAZARD, output={"fields": ["landing"]}), plain, device="cpu")
    with h5py.File(out, "r") as a, h5py.File(plain, "r") as p:
        for name in ("range", "position", "velocity"):
            np.testing.assert_array_equal(a[f"pellets/landing/{name}"][()], p[f"pellets/landing/{name}"][()])
        np.testing.assert_array_equal(a["stats/histograms/counts"][()], p["stats/histograms/counts"][()])
        np.testing.assert_allclose(a["stats/range_mean"][()], p["stats/range_mean"][()], rtol=1e-12)


def test_a_spent_budget_says_not_bounded(tmp_path):
    # below one bin's width (0.0625 m at 124 m): never bounded
    with pytest.warns(PrecisionWarning, match="NOT BOUNDED"):
        stats = wr.run(bounded(width=0.01, max_pellets=1_050), tmp_path / "run.h5", device="cpu")
    b = stats.bound
    assert not b.met and b.pellets == 1_000 and b.shots == 10 and stats["pellets"] == 1_000
    assert b.final_width >= 0.0625
    with display.using("imperial"):  # the width asked, in yards to 4 digits as every distance (was 0.0109361 yd)
        assert b.summary().endswith("not below 0.01094 yd; raise max_pellets or the width")
    with h5py.File(tmp_path / "run.h5", "r") as f:
        assert not f["hazard/bound/met"][()] and f["hazard/bound/pellets"][()] == 1_000
    rc, out, _ = cli(["report", tmp_path / "run.h5"])  # the file's report says it too
    assert rc == 0 and out.rstrip().endswith("not below 0.01 m; raise max_pellets or the width")
    assert "NOT BOUNDED: the budget of 1,000 pellets (10 shots, 8 checks) is spent" in out
    # the command line says it plainly, and so does the summary
    rc, out, err = cli(
        ["run", _toml(tmp_path), "--device", "cpu", "--set", "hazard.bound.width=0.01", "--set", "hazard.bound.max_pellets=300"]
    )
    assert rc == 0
    assert "NOT BOUNDED: the budget of 300 pellets (3 shots, 2 checks) is spent" in out
    assert "width inf m, not below 0.01 m; raise max_pellets or the width" in out
    rc, out, err = cli(["run", _toml(tmp_path), "--device", "cpu"])
    assert rc == 0 and "bounded after 400 pellets (4 shots, 3 checks)" in out and "< 1 m" in out


def test_a_budget_of_one_check_says_one_shot_and_one_check(tmp_path):
    """A budget of one shot is one check: the summary reads "(1 shot, 1 check)", not "1 checks"."""
    with pytest.warns(PrecisionWarning, match=r"NOT BOUNDED: the budget of 100 pellets \(1 shot, 1 check\) is spent"):
        stats = wr.run(bounded(shots=1, width=0.01, max_pellets=100), tmp_path / "run.h5", device="cpu")
    assert stats.bound.checks == 1 and stats.bound.shots == 1


def test_the_html_report_states_the_bound_and_the_shots_run(tmp_path):
    """`report --html` of a bounded run says, in its summary, whether the bound was met (a warning
    when not), and counts the shots run, not the first check's `shot.shots`."""
    with pytest.warns(PrecisionWarning, match="NOT BOUNDED"):
        wr.run(bounded(width=0.01, max_pellets=300), tmp_path / "run.h5", device="cpu")
    rc, _out, err = cli(["report", tmp_path / "run.h5", "--html", tmp_path / "run.html"])
    assert (rc, err) == (0, "")
    page = " ".join((tmp_path / "run.html").read_text().split())
    assert '<li class="warning">NOT BOUNDED: the budget of 300 pellets (3 shots, 2 checks) is spent' in page
    assert "3 shots of 100 pellets" in page and "2 shots of 100 pellets" not in page


def test_a_sweep_names_the_point_a_spent_budget_belongs_to(tmp_path):
    """A sweep of bounded runs warns NOT BOUNDED for each point that spent its budget, naming it:
    the points' warnings are otherwise alike, and the sweep's tables do not show the bounds."""
    scene = bounded(width=0.01, max_pellets=200)  # (one check, never met)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        wr.sweep(scene, {"shot.speed": [400.0, 420.0]}, output=tmp_path / "sweep.h5", device="cpu")
    said = [str(w.message) for w in caught if issubclass(w.category, PrecisionWarning)]
    assert [m.split(": NOT BOUNDED: ")[0] for m in said] == [
        "sweep point 0 (shot.speed = 400.0)",
        "sweep point 1 (shot.speed = 420.0)",
    ]


def test_every_group_of_a_bounded_run_file_opens_in_xarray_and_old_files_still_read(tmp_path):
    """The settings `threshold` and `fraction` of /hazard/bound were once stored under those names,
    the names of dimensions of /hazard: h5netcdf took the scalars for their coordinates and failed
    ("Illegal slicing argument for scalar dataspace"), so xarray's open_datatree failed on every
    bounded run file. Stored as `threshold_name` and `p`, every group opens with the file's values;
    `read`, open_run and `report` still read a file of the old names."""
    out, old = tmp_path / "run.h5", tmp_path / "old.h5"
    wr.run(bounded(width=1.0), out, device="cpu")
    variables = assert_opens_in_xarray(out)
    assert variables["hazard/bound/threshold_name"].values.item() == b"low" and variables["hazard/bound/p"].values == 0.01
    assert variables["hazard/bound/pellets"].values == 400 and variables["hazard/danger_distance/distance"].dims[0] == "threshold"
    with h5py.File(out, "r") as f:
        now = read(f)
    old.write_bytes(out.read_bytes())
    with h5py.File(old, "r+") as f:  # the layout before
        f.move("hazard/bound/threshold_name", "hazard/bound/threshold")
        f.move("hazard/bound/p", "hazard/bound/fraction")
    with h5py.File(old, "r") as f:
        assert read(f) == now and now["threshold"] == "low" and now["fraction"] == 0.01
    with wr.open_run(old) as run:
        assert run.hazard_results.bound_threshold.item() == "low" and run.hazard_results.bound_met.item()
    rc, text, _ = cli(["report", old])
    assert rc == 0 and "bounded after 400 pellets (4 shots, 3 checks)" in text


def _toml(tmp_path) -> Path:
    path = tmp_path / "scene.toml"
    path.write_text(bounded().to_toml())
    return path


def test_the_bits_do_not_depend_on_the_chunk_size(tmp_path):
    # shots of 70,000 pellets: chunks of 65,536 cut each stretch between checks in two
    small, whole = tmp_path / "small.h5", tmp_path / "whole.h5"
    for chunk, out in ((65_536, small), (1 << 20, whole)):
        stats = wr.run(bounded(count=70_000, shots=1, width=1e-3, max_pellets=210_000, chunk=chunk), out, device="cpu")
        assert stats.bound.pellets == 210_000 and not stats.bound.met
    assert_same_run(small, whole, ["landing/range", "landing/position"])
    with h5py.File(small, "r") as f:
        assert len(f["progress/segment_results"]) == 6


@pytest.mark.parametrize("chunks", [1, 2, 3, 4])
def test_resume_continues_to_the_uninterrupted_bits(tmp_path, chunks):
    """Interrupted inside a stretch between checks (1, 3: 65,536 or 135,536 pellets) or at a check
    (2, 4: 70,000 or 140,000, where a segment count from the run's start would be one short)."""
    scene = bounded(count=70_000, shots=1, width=1e-3, max_pellets=210_000, chunk=65_536)
    ref, out = tmp_path / "ref.h5", tmp_path / "out.h5"
    wr.run(scene, ref, device="cpu")
    interrupt_after(chunks, scene, out)
    with h5py.File(str(out) + ".partial", "r") as f:
        assert f["progress/rows"][()] == (65_536, 70_000, 135_536, 140_000)[chunks - 1]
    stats = wr.run(scene, out, device="cpu", resume=True)
    assert stats.bound.pellets == 210_000 and stats.bound.checks == 3
    assert_same_run(out, ref, ["landing/range", "landing/position"])


def test_resume_refuses_rows_that_no_chunk_ends_at(tmp_path):
    scene = bounded(count=70_000, shots=1, width=1e-3, max_pellets=210_000, chunk=65_536)
    path, out = tmp_path / "scene.toml", tmp_path / "out.h5"
    path.write_text(scene.to_toml())
    interrupt_after(1, scene, out)

    def edit(f):
        f["progress/rows"][()] = 65_535

    argv = ["run", path, "-o", out, "--device", "cpu", "--resume"]
    assert_resume_refused(argv, out, edit, f"output path = '{out}.partial': is inconsistent (65535 rows complete, neither")


def test_shots_are_added_whole_with_pair_collisions(tmp_path):
    """With pair collisions a shot's pellets meet each other: the run adds whole shots, and stops
    after S with the pellets and collisions of an ordinary run of S shots; --resume goes on to
    the uninterrupted bits (the shots' collision totals too)."""
    collisions = {"collisions": {"enabled": True}}
    scene = bounded(count=24, shots=4, max_pellets=24 * 12 + 5, **collisions)
    ref, plain, out = tmp_path / "ref.h5", tmp_path / "plain.h5", tmp_path / "out.h5"
    stats = wr.run(scene, ref, device="cpu")
    assert not stats.bound.met and stats.bound.shots == 12 and stats["pellets"] == 288  # checks: 4, 5, 6, 7, 8, 10, 12
    assert stats.bound.checks == 7 and stats["pair_collisions"] > 0
    other = wr.run(bounded(count=24, shots=12, bound=False, **collisions), plain, device="cpu")
    assert other["pair_collisions"] == stats["pair_collisions"]
    with h5py.File(ref, "r") as a, h5py.File(plain, "r") as p:
        np.testing.assert_array_equal(a["pellets/landing/range"][()], p["pellets/landing/range"][()])
        np.testing.assert_array_equal(a["progress/shot_totals"][()], p["progress/shot_totals"][()])
    interrupt_after(3, scene, out)  # after the third check
    with h5py.File(str(out) + ".partial", "r") as f:
        assert f["progress/rows"][()] == 6 * 24
    wr.run(scene, out, device="cpu", resume=True)
    assert_same_run(out, ref, ["landing/range"], progress=("segment_results", "shot_totals"))


def test_a_threshold_never_reached_is_not_bounded(tmp_path):
    raw = paper_raw(until="landing")
    raw["shot"].update(count=100, shots=1)
    hazard = {
        **HAZARD,
        "speed": {"fast": 1000.0},
        "bound": {"threshold": "fast", "fraction": 0.01, "width": 5.0, "max_pellets": 300},
    }
    with pytest.warns(PrecisionWarning, match="no pellet above fast: no danger distance"):
        stats = wr.run(make_scene(raw, hazard=hazard, output={"fields": []}), device="cpu")
    assert not stats.bound.met and stats.bound.pellets == 300 and np.isnan(stats.bound.distance)


def test_resume_of_a_run_that_met_its_bound_at_the_interruption(tmp_path):
    scene = bounded(width=1.0)
    ref, out = tmp_path / "ref.h5", tmp_path / "out.h5"
    wr.run(scene, ref, device="cpu")
    interrupt_after(3, scene, out)  # the third check's chunk is kept: it met the bound
    stats = wr.run(scene, out, device="cpu", resume=True)
    assert stats.bound.met and stats.bound.pellets == 400
    assert_same_run(out, ref, ["landing/range"])


def test_a_complete_file_killed_before_its_move_resumes_to_its_end(tmp_path, monkeypatch):
    """Stopped after its file was closed, before the move into place: OUT.h5.partial is complete,
    /constants/pellets the 400 pellets run, not the budget's 20,000. --resume once refused it as
    inconsistent; it meets the bound again at once, from the counts kept, and finishes the file."""
    from warp_ricochet.io import runfile

    scene = bounded(width=1.0)
    ref, out = tmp_path / "ref.h5", tmp_path / "out.h5"
    wr.run(scene, ref, device="cpu")

    def killed(*args):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(runfile, "move_into_place", killed)
        with pytest.raises(KeyboardInterrupt):
            wr.run(scene, out, device="cpu")
    with h5py.File(str(out) + ".partial", "r") as f:
        assert f.attrs["status"] == "complete" and f["constants/pellets"][()] == 400 and not out.exists()
    other = tmp_path / "other.h5"  # (the same file saying the bound was not met there: refused)
    Path(str(other) + ".partial").write_bytes(Path(str(out) + ".partial").read_bytes())

    def unmet(f):
        f["hazard/bound/met"][()] = False

    argv = ["run", _toml(tmp_path), "-o", other, "--device", "cpu", "--resume"]
    start = f"output path = '{other}.partial': is inconsistent (400 pellets in /constants/pellets for a run of 20000, no bound"
    assert_resume_refused(argv, other, unmet, start)
    stats = wr.run(scene, out, device="cpu", resume=True)
    assert stats.bound.met and stats.bound.pellets == 400 and stats.bound.checks == 3
    assert_same_run(out, ref, ["landing/range", "landing/position"])
    assert not Path(str(out) + ".partial").exists()


@pytest.mark.parametrize(
    ("bound", "key", "allowed"),
    [
        (
            {"threshold": "lo"},
            "hazard.bound.threshold = 'lo'",
            "must name a threshold of the scene; did you mean low? allowed: low, fast",
        ),
        ({"fraction": 1.0}, "hazard.bound.fraction = 1.0", "must be a number in (0, 1)"),
        ({"fraction": 0}, "hazard.bound.fraction = 0", "must be a number in (0, 1)"),
        ({"width": 0.0}, "hazard.bound.width = 0.0", "must be a number in (0, 1e+06] (m)"),
        ({"width": "1 s"}, "hazard.bound.width = '1 s'", "hazard.bound.width takes a length (m); 's' is a time"),
        ({"max_pellets": 199}, "hazard.bound.max_pellets = 199", "must be at least shot.count x shot.shots = 200"),
        ({"max_pellets": 1.5}, "hazard.bound.max_pellets = 1.5", "must be an integer in [1, 2147483647]"),
        ({"max_pellets": None}, "hazard.bound.max_pellets = (missing)", "is required; it must be an integer"),
        ({"budget": 3}, "hazard.bound.budget = 3", "unknown key; allowed keys: threshold, fraction, width, max_pellets"),
    ],
)
def test_bad_input_is_refused_in_one_line(bound, key, allowed):
    raw = paper_raw(until="landing")
    raw["shot"].update(count=100, shots=2)
    table = {"threshold": "low", "fraction": 0.01, "width": 1.0, "max_pellets": 1000, **bound}
    with pytest.raises(SceneError) as info:
        make_scene(raw, hazard={**HAZARD, "bound": {k: v for k, v in table.items() if v is not None}})
    text = str(info.value)
    assert text.startswith(key) and allowed in text and "\n" not in text, text


def test_the_command_line_refuses_before_any_work(tmp_path):
    scene, out = _toml(tmp_path), tmp_path / "x.h5"
    for setting, start in (
        ("hazard.bound.width=-1", "hazard.bound.width = -1: must be a number in (0, 1e+06] (m)"),
        ("hazard.bound.threshold='eye'", "hazard.bound.threshold = 'eye': must name a threshold of the scene"),
        ("shot.shots=300", "hazard.bound.max_pellets = 20000: must be at least shot.count x shot.shots = 30000"),
        ("collisions={enabled = true, frame_every = 5}", "collisions.frame_every = 5: must be 0 with [hazard.bound]"),
    ):
        rc, stdout, err = cli(["run", scene, "-o", out, "--device", "cpu", "--set", setting])
        assert rc == 2 and stdout == "" and len(err.splitlines()) == 1, err
        assert err.startswith("warp-ricochet: error: " + start), err
        assert not out.exists() and not Path(str(out) + ".partial").exists()


def test_a_pellet_file_is_refused(tmp_path):
    from tests.helpers import explicit_scene

    plain = explicit_scene(tmp_path, [[0.0, 1.0, 0.0]] * 4, [[100.0, -100.0, 0.0]] * 4, surfaces=[paper_raw()["surfaces"][0]])
    raw = plain.to_dict()
    raw["hazard"] = {**HAZARD, "bound": {"threshold": "low", "fraction": 0.01, "width": 1.0, "max_pellets": 100}}
    from warp_ricochet.scene import scene_from_dict

    with pytest.raises(SceneError, match=r"^shot.file = .*not allowed with \[hazard.bound\]: a pellet file's pellets are fixed"):
        scene_from_dict(raw)
