"""Where every pellet ends (physics.until = "rest", issue 25 part 5): the /pellets/rest fields, the
statistics and the rest-distance histogram, their files, readers, summary, report and plot. These
test the outputs' consistency with each other (counts, distances, quantiles, chunk sizes, resume),
not the physics of where a pellet stops (tests of the continuation do that)."""

import math
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from warp_ricochet.ends import AT_REST, EMBEDDED, ESCAPED, NOT_FINISHED, STATES, STOPPED
from warp_ricochet.errors import SceneError
from warp_ricochet.fields import FIELDS, REST_FIELDS, default_fields
from warp_ricochet.io.xdmf import xdmf_text
from warp_ricochet.report import format_run_summary, format_tables, read_results
from warp_ricochet.report.rest import draw_rest_distance
from warp_ricochet.scene import load_scene, scene_from_dict
from warp_ricochet.tallies.bins import RELATIVE_WIDTH
from warp_ricochet.tallies.reduce import SEGMENT
from warp_ricochet.tallies.sums import REST_STATS

PAPER = "examples/paper.toml"
PLATE = "examples/steel_plate.toml"  # two planes: some pellets never land (escaped)
REST = ['physics.until="rest"', 'output.fields=["landing", "rest"]', "surfaces.0.rolling_resistance=0.05"]  # c > 0: they stop


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    """The steel plate, 20,000 pellets followed to rest, with its file."""
    path = tmp_path_factory.mktemp("rest") / "plate.h5"
    scene = load_scene(PLATE, ["shot.count=20000", 'output.fields=["landing", "rest", "impact"]'])
    return scene, path, wr.run(scene, path, device="cpu")


def horizontal_distance(scene, positions):
    """m, from the landing tallies' shooter (here the envelope centre) perpendicular to gravity."""
    g = np.asarray(scene.physics.gravity, np.float64)
    up = -g / np.linalg.norm(g)
    offset = np.asarray(positions, np.float64) - np.asarray(scene.shot.envelope_center, np.float64)
    return np.linalg.norm(offset - np.outer(offset @ up, up), axis=1)


def test_rest_fields_only_with_until_rest(tmp_path, plate):
    """The default fields hold the rest group with until = "rest" (units, the states attribute), a
    run with until = "landing" has no rest field, statistic, quantile or histogram."""
    raw = tomllib.loads(Path(PAPER).read_text())
    del raw["output"]["fields"], raw["physics"]["until"]  # the defaults: until = "rest", no fields named
    assert set(REST_FIELDS) <= set(scene_from_dict(raw).output.fields)
    raw["physics"]["until"] = "landing"
    assert not set(REST_FIELDS) & set(scene_from_dict(raw).output.fields)
    assert not set(REST_FIELDS) & set(default_fields(True, True, False))
    _, path, stats = plate
    with h5py.File(path, "r") as f:
        for name in REST_FIELDS:
            ds = f[FIELDS[name].path]
            assert ds.attrs["units"] == FIELDS[name].unit and len(ds) == 20000, name
        assert [s.decode() for s in f["pellets/rest/state"].attrs["states"]] == list(STATES)
        assert f["pellets/rest/state"].dtype == np.int8 and f["pellets/rest/impacts"].dtype == np.int32
        assert f["stats/rest_distance_mean"].attrs["units"] == "m"
        assert "rest_distance" in f["stats/quantiles"] and "rest_counts" in f["stats/histograms"]
        # on the dimensions of the landing's (no scales of their own: io.dimensions)
        assert sorted(f["stats/quantiles"]) == ["distance", "energy", "level", "lower", "range", "rest_distance", "speed"]
        assert sorted(f["stats/histograms"]) == ["bin", "bin_edge", "counts", "edges", "histogram_row", "rest_counts"]
    assert set(REST_STATS) <= set(stats)
    landing = tmp_path / "landing.h5"
    stats = wr.run(load_scene(PAPER, ["shot.count=500"]), landing, device="cpu")  # paper.toml: until = "landing"
    assert not set(REST_STATS) & set(stats)
    with h5py.File(landing, "r") as f:
        assert "rest" not in f["pellets"] and not any(name.startswith("rest") for name in f["stats"])
        assert "rest_distance" not in f["stats/quantiles"] and "rest_counts" not in f["stats/histograms"]
        assert f["progress/tally"].shape[1] == stats.tally.flat().size  # (no rest bins in /progress)


def test_asking_for_rest_fields_without_following_to_rest_is_refused(tmp_path):
    """output.fields naming the rest group with until = "landing": one line naming the key, the value
    and what is allowed, from a scene file and from a scene made in code, no file written."""
    with pytest.raises(SceneError, match=r"output.fields = 'rest.position': needs physics.until = \"rest\""):
        load_scene(PAPER, ['output.fields=["landing", "rest"]'])
    with pytest.raises(SceneError, match=r"output.fields = 'rest.state': needs physics.until = \"rest\""):
        load_scene(PAPER, ['output.fields=["rest.state"]'])
    import dataclasses

    scene = load_scene(PAPER, ["shot.count=100"])
    scene = dataclasses.replace(scene, output=dataclasses.replace(scene.output, fields=("landing.range", "rest.time")))
    out = tmp_path / "refused.h5"
    with pytest.raises(SceneError, match="output.fields = 'rest.time': needs physics.until"):
        wr.run(scene, out, device="cpu")
    assert not out.exists() and not (tmp_path / "refused.h5.partial").exists()


def test_statistics_are_those_of_the_per_pellet_outputs(plate):
    """Counts by end state, the rest distance's mean, spread and extremes, the mean path along
    surfaces and impacts, recomputed from /pellets/rest; the quantiles from the histogram hold
    NumPy's sample quantiles within their bin."""
    scene, path, stats = plate
    with h5py.File(path, "r") as f:
        state = f["pellets/rest/state"][()]
        position = f["pellets/rest/position"][()]
        path_length = f["pellets/rest/path_length"][()]
        impacts = f["pellets/rest/impacts"][()]
        quantiles = f["stats/quantiles/rest_distance"][()], f["stats/quantiles/lower/rest_distance"][()]
        levels = f["stats/quantiles"].attrs["levels"]
        counts = f["stats/histograms/rest_counts"][()]
    for code, name in ((AT_REST, "at_rest"), (EMBEDDED, "embedded"), (ESCAPED, "escaped"), (NOT_FINISHED, "not_finished")):
        assert stats[f"rest_{name}"] == np.count_nonzero(state == code), name
    assert stats["rest_at_rest"] > 0
    stopped = np.isin(state, STOPPED)
    assert np.isnan(position[state == ESCAPED]).all() and np.isfinite(position[stopped]).all()
    d = horizontal_distance(scene, position[stopped])
    assert stats["rest_distance_mean"] == pytest.approx(d.mean(), rel=1e-6)
    assert stats["rest_distance_std"] == pytest.approx(d.std(), rel=1e-4)
    assert stats["rest_distance_max"] == pytest.approx(d.max(), rel=1e-6)
    assert stats["rest_distance_min"] == pytest.approx(d.min(), rel=1e-6)
    assert stats["rest_path_mean"] == pytest.approx(path_length[stopped].mean(), rel=1e-6, abs=1e-12)
    assert stats["rest_impacts_mean"] == pytest.approx(impacts.mean(), rel=1e-9)
    assert counts.sum() == stopped.sum() == stats.tally.rest.sum()
    value, lower = quantiles
    want = np.quantile(d, levels, method="inverted_cdf")
    slack = 1.0 + RELATIVE_WIDTH  # float32 distances in the kernel: at most a bin off
    assert np.all(want <= value * slack) and np.all(want >= lower / slack), (want, value, lower)


def test_pellets_that_escape_have_no_rest_position(tmp_path):
    """Gravity pointing away from the ground: every pellet ricochets once and never meets it again.
    All escaped, NaN position and velocity, time inf; no rest distance (NaN statistics, no counts)."""
    out = tmp_path / "escape.h5"
    stats = wr.run(load_scene(PAPER, ["shot.count=2000", "physics.gravity=[0.0, 9.81, 0.0]"] + REST), out, device="cpu")
    assert (stats["rest_escaped"], stats["rest_at_rest"], stats["rest_not_finished"]) == (2000, 0, 0)
    text = format_run_summary(stats, out, "cpu")  # (issue 28: each count in its own words, the columns kept)
    assert "hit, never landed             2,000\nmissed                        0\n" in text
    assert "ended escaped / not finished  2,000 / 0\n" in text
    assert all(math.isnan(stats[f"rest_distance_{s}"]) for s in ("mean", "std", "min", "max"))
    assert math.isnan(stats["rest_path_mean"]) and stats["rest_impacts_mean"] == 1.0
    with h5py.File(out, "r") as f:
        assert (f["pellets/rest/state"][()] == ESCAPED).all() and np.isinf(f["pellets/rest/time"][()]).all()
        assert np.isnan(f["pellets/rest/position"][()]).all() and np.isnan(f["pellets/rest/velocity"][()]).all()
        assert f["stats/histograms/rest_counts"][()].sum() == 0 and np.isnan(f["stats/quantiles/rest_distance"][()]).all()


def rest_results(stats, path=None):
    """The rest statistics, the rest histogram and (with a file) its rest datasets."""
    out = {name: stats[name] for name in REST_STATS}
    out["hist"] = stats.tally.rest.copy()
    if path is not None:
        with h5py.File(path, "r") as f:
            out["file_hist"] = f["stats/histograms/rest_counts"][()]
            out["quantiles"] = f["stats/quantiles/rest_distance"][()]
            out.update({f"file_{name}": f[f"stats/{name}"][()] for name in REST_STATS})
    return out


def assert_bitwise(a, b):
    assert a.keys() == b.keys()
    for name in a:
        x, y = np.asarray(a[name]), np.asarray(b[name])
        assert x.tobytes() == y.tobytes() or (np.isnan(x).all() and np.isnan(y).all()), (name, x, y)


def test_rest_statistics_are_bitwise_the_same_for_any_chunk_size_and_after_resume(tmp_path):
    """Three segments of pellets in chunks of one, two or three segments, and a run interrupted after
    its first chunk and resumed: the rest statistics and histogram bitwise the same."""
    sets = ["shot.count=" + str(3 * SEGMENT), 'output.fields=["rest"]']
    scene = load_scene(PLATE, sets + [f"numerics.chunk_size={SEGMENT}"])
    reference = rest_results(wr.run(load_scene(PLATE, sets + [f"numerics.chunk_size={3 * SEGMENT}"]), device="cpu"))
    assert reference["rest_at_rest"] == 3 * SEGMENT
    assert_bitwise(
        rest_results(wr.run(load_scene(PLATE, sets + [f"numerics.chunk_size={2 * SEGMENT}"]), device="cpu")), reference
    )
    whole = tmp_path / "whole.h5"
    want = rest_results(wr.run(scene, whole, device="cpu"), whole)
    assert_bitwise({k: v for k, v in want.items() if k in reference}, reference)
    out, calls = tmp_path / "resumed.h5", []

    def progress(done, total):
        calls.append(done)
        if len(calls) == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        wr.run(scene, out, device="cpu", progress=progress)
    with h5py.File(str(out) + ".partial", "r") as f:
        assert f["progress/rows"][()] == SEGMENT
    assert_bitwise(rest_results(wr.run(scene, out, device="cpu", resume=True), out), want)
    with h5py.File(out, "r") as a, h5py.File(whole, "r") as b:
        for name in REST_FIELDS:
            assert a[FIELDS[name].path][()].tobytes() == b[FIELDS[name].path][()].tobytes(), name


def test_shots_count_their_ends(tmp_path):
    """A run of several shots: each shot's end counts add up to the run's (`tallies.ensemble`)."""
    stats = wr.run(load_scene(PLATE, ["shot.count=3000", "shot.shots=3", 'output.fields=["rest"]']), device="cpu")
    for name in ("rest_at_rest", "rest_escaped", "rest_embedded", "rest_not_finished"):
        assert stats.ensemble.per_shot[name].sum() == stats[name], name
    assert stats.ensemble.per_shot["rest_distance_max"].max() == stats["rest_distance_max"]
    assert stats.ensemble.low["rest_distance_mean"] <= stats.ensemble.high["rest_distance_mean"]


def test_summary_report_reader_xdmf_and_plot_show_where_pellets_end(plate, tmp_path):
    """The run summary and `report` show the end states and rest distances beside the landing's, the
    rest distance's quantiles, and a warning line (never "at rest") when a pellet is not finished;
    open_run exposes /pellets/rest with its states; the XDMF has a `rest` cloud; the plot draws."""
    scene, path, stats = plate
    text = format_run_summary(stats, path, "cpu")
    assert f"ended at rest / embedded      {int(stats['rest_at_rest']):,} / 0" in text
    assert f"ended escaped / not finished  {int(stats['rest_escaped']):,} / 0" in text
    # issue 28: "escaped" names one count, the end state; the pellets that hit and never landed
    # have their own row, in the same columns (the end state counts them, and the missed, too)
    missed, hit_only = int(stats["missed"]), int(stats["escaped"])
    assert f"hit, never landed             {hit_only:,}\nmissed                        {missed:,}\n" in text
    assert text.count("escaped") == 1
    assert f"mean rest distance            {stats['rest_distance_mean']:.3f} m" in text
    assert "  rest_distance " in text and "  distance " in text and "not finished:" not in text
    unfinished = type(stats)(stats, rest_not_finished=7.0)
    unfinished.tally = stats.tally
    text = format_run_summary(unfinished, path, "cpu")
    assert "warning: 7 pellets not finished" in text and "never as at rest" in text
    report = format_tables(read_results(path))
    assert "where the pellets end" in report and "mean rest distance" in report and "  rest_distance " in report
    landing = tmp_path / "landing.h5"
    wr.run(load_scene(PAPER, ["shot.count=300"]), landing, device="cpu")
    assert "where the pellets end" not in format_tables(read_results(landing))
    assert "ended at rest" not in format_run_summary(wr.run(load_scene(PAPER, ["shot.count=300"]), device="cpu"))
    with wr.open_run(path) as run:
        assert run.rest.state.attrs["states"] == list(STATES)
        assert int((run.rest.state.values == AT_REST).sum()) == stats["rest_at_rest"]
    assert 'Grid Name="rest"' in xdmf_text(path) and "/pellets/rest/state" in xdmf_text(path)
    assert 'Grid Name="rest"' not in xdmf_text(landing)
    figure = pytest.importorskip("matplotlib.figure")
    with h5py.File(path, "r") as f:
        assert draw_rest_distance(figure.Figure(), f)
    with h5py.File(landing, "r") as f:
        assert not draw_rest_distance(figure.Figure(), f)


def test_a_not_finished_pellet_is_never_counted_at_rest():
    """`add_rest_sums`' bookkeeping through `finalize`: rows of end-state counts give the four counts,
    not finished apart; the distance statistics only over the pellets at rest or embedded."""
    from warp_ricochet.tallies.sums import SUM, empty_totals, finalize

    sums, mins, maxs, _ = empty_totals()
    sums[SUM["end_stopped"]], sums[SUM["end_at_rest"]], sums[SUM["end_not_finished"]] = 5, 3, 4
    sums[SUM["end_distance"]], sums[SUM["end_impacts"]] = 50.0, 40.0
    spread = np.array([[0.0, 0.0, 0.0, 5.0, 50.0, 2.5]])
    stats = finalize((sums, mins, maxs, spread), pellets=10, mass=1.0, inertia=1.0, rest=True)
    assert (stats["rest_at_rest"], stats["rest_embedded"], stats["rest_not_finished"], stats["rest_escaped"]) == (3, 2, 4, 1)
    assert stats["rest_distance_mean"] == 10.0 and stats["rest_distance_std"] == math.sqrt(0.5)
    assert stats["rest_impacts_mean"] == 4.0
    assert "rest_at_rest" not in finalize((sums, mins, maxs, spread), pellets=10, mass=1.0, inertia=1.0)


def test_the_rest_distance_is_from_the_hazard_shooter_where_given(tmp_path):
    """With `[hazard] shooter` the rest distances (statistics and quantiles) are measured from it, as
    the landing distances are."""
    shooter = (5.0, 0.0, 3.0)
    sets = ["shot.count=2000", "hazard.speed={fast=100.0}", f"hazard.shooter={list(shooter)}", *REST]
    out = tmp_path / "shooter.h5"
    stats = wr.run(load_scene(PAPER, sets), out, device="cpu")
    with h5py.File(out, "r") as f:
        position = f["pellets/rest/position"][()]
    offset = position.astype(np.float64) - shooter
    d = np.hypot(offset[:, 0], offset[:, 2])  # gravity along -y
    assert stats["rest_distance_mean"] == pytest.approx(d.mean(), rel=1e-6)
    assert stats["rest_distance_max"] == pytest.approx(d.max(), rel=1e-6)


def test_a_sweep_file_holds_each_points_rest_statistics(tmp_path):
    """A sweep followed to rest: /stats holds every rest statistic by point (with units), equal to
    the point runs' own, and each /runs/NNNN its rest quantiles."""
    out = tmp_path / "sweep.h5"
    scene = load_scene(PAPER, ["shot.count=500", "surfaces.0.mu_d=0.15", *REST])
    results = wr.sweep(scene, {"surfaces.0.mu_s": [0.2, 0.4]}, output=out, device="cpu")
    with h5py.File(out, "r") as f:
        for name in REST_STATS:
            assert f[f"stats/{name}"].attrs["units"] == wr.STAT_UNITS[name][0], name
            np.testing.assert_array_equal(f[f"stats/{name}"][()], [stats[name] for _, stats in results], err_msg=name)
        assert all(np.isfinite(f[f"runs/{i:04d}/stats/quantiles/rest_distance"][()]).all() for i in range(2))


def test_the_plot_draws_pellets_embedded_at_their_first_impact(tmp_path):
    """Pellets fired steeply into water embed at their first impact and never land: the plot's
    survival of the rest distance counts them (its quantiles do), without a legend warning."""
    import warnings

    figure = pytest.importorskip("matplotlib.figure")
    path = tmp_path / "pond.h5"
    scene = load_scene(PAPER, ["shot.count=40", 'surfaces.0.material="water"', "shot.direction=[1.0, -1.0, 0.0]", *REST])
    stats = wr.run(scene, path, device="cpu")
    assert stats["rest_embedded"] == 40 and stats["landed"] == 0
    fig = figure.Figure()
    with h5py.File(path, "r") as f, warnings.catch_warnings():
        warnings.simplefilter("error")  # (before: "No artists with labels found to put in legend")
        assert draw_rest_distance(fig, f)
    (rest,) = fig.axes[1].get_lines()
    assert rest.get_label() == "rest (40)"
