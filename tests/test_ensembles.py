"""Ensembles of shots (`tallies.ensemble`, `core.shots`): 95% intervals over shots cover a known
mean at their level, per-shot values equal the NumPy statistics of each shot's pellets, and
everything is bitwise the same for any chunk size and after --resume (collision runs: in
test_resume_collisions.py)."""

import math

import h5py
import numpy as np
import pytest
from helpers import assert_same_stats, interrupt_after
from scipy.stats import t as stats_t

import warp_ricochet as wr
from warp_ricochet.cli import main as cli_main
from warp_ricochet.io.dimensions import is_dimension
from warp_ricochet.report import format_tables, read_results
from warp_ricochet.scene import load_scene
from warp_ricochet.tallies.ensemble import STAT_KIND, ensemble_of, has_ensemble, t_interval
from warp_ricochet.tallies.sums import statistics_from_arrays

SCENE = "examples/paper.toml"
COUNT, SHOTS = 30_000, 5  # 150,000 pellets: shots straddle chunks of 65,536
BASE = [
    f"shot.count={COUNT}",
    f"shot.shots={SHOTS}",
    'numerics.precision="float64"',
    "surfaces.0.mu_s=0.2",
    "surfaces.0.mu_d=0.18",
    'output.fields=["initial", "impact", "landing"]',
]


def _coverage(draw, truth, ensembles=2000, shots=200):
    rng = np.random.default_rng(20261126)
    covered = 0
    for _ in range(ensembles):
        low, high = t_interval(draw(rng, shots))
        covered += low <= truth <= high
    return covered / ensembles


@pytest.mark.parametrize(
    "name, draw, truth",
    [
        ("normal", lambda rng, n: rng.normal(3.0, 2.0, n), 3.0),
        ("exponential (skewed)", lambda rng, n: rng.exponential(5.0, n), 5.0),
        ("uniform", lambda rng, n: rng.uniform(-1.0, 2.0, n), 0.5),
    ],
)
def test_intervals_cover_a_known_mean_at_their_level(name, draw, truth):
    """2,000 synthetic ensembles of 200 shots each: the 95% interval covers the true mean in 95% of
    them, within 3 binomial standard deviations (0.0146)."""
    coverage = _coverage(draw, truth)
    assert abs(coverage - 0.95) <= 3 * math.sqrt(0.95 * 0.05 / 2000), (name, coverage)


def test_interval_kinds_and_undefined_values():
    """Totals scale by the shots; NaN shots are left out; one value gives no interval."""
    x = np.array([1.0, 2.0, 4.0, math.nan])
    e = ensemble_of({"landed": x, "range_mean": x, "range_max": x}, shots=4)
    low, high = t_interval(x[:3])
    assert (e.low["range_mean"], e.high["range_mean"]) == (low, high) == (e.low["range_max"], e.high["range_max"])
    assert (e.low["landed"], e.high["landed"]) == (4 * low, 4 * high)
    mean, half = 7 / 3, 4.302652729749464 * np.std([1.0, 2.0, 4.0], ddof=1) / math.sqrt(3)  # t_{0.975, 2}
    assert low == pytest.approx(mean - half, rel=1e-10) and high == pytest.approx(mean + half, rel=1e-10)
    assert all(math.isnan(v) for v in t_interval([1.0, math.nan]))
    assert STAT_KIND["range_max"] == "extreme" and STAT_KIND["hits"] == "total" and STAT_KIND["range_std"] == "mean"
    assert not has_ensemble(load_scene(SCENE)) and has_ensemble(load_scene(SCENE, ["shot.shots=2"]))


@pytest.fixture(scope="module")
def multi(tmp_path_factory):
    path = tmp_path_factory.mktemp("ensembles") / "multi.h5"
    stats = wr.run(load_scene(SCENE, BASE + ["numerics.chunk_size=65536"]), path, device="cpu")
    return path, stats


def test_the_summary_of_a_run_to_rest_gives_the_rest_distances_intervals():
    """`run`'s summary printed the rest distance of several shots without its interval (`report`
    had it): its rows now come with the range's."""
    from warp_ricochet.report.tables import SUMMARY_INTERVALS, format_intervals

    row = {"range_mean": 40.0, "rest_distance_mean": 45.0, "rest_distance_max": 90.0, "rest_not_finished": 0.0}
    intervals = {name: (0.9 * x, 1.1 * x) for name, x in row.items()}
    text = format_intervals(row, intervals, 3, "text", SUMMARY_INTERVALS)
    rows = {line.split()[0]: line.split() for line in text.splitlines() if line.split() and line.split()[0] in row}
    assert rows["rest_distance_mean"][-2:] == ["per", "shot"] and rows["rest_distance_max"][-3:] == ["one", "shot's", "extreme"]
    assert set(rows) == set(row)


def test_per_shot_values_are_each_shots_numpy_statistics(multi):
    """/stats/shots/<name>[s] is the statistic of shot s's pellets alone (NumPy from its per-pellet
    outputs), for shots inside one chunk and across two; /stats keeps the whole run's values, and
    the intervals contain the mean of the per-shot values."""
    path, stats = multi
    with h5py.File(path, "r") as f:
        p = {
            name: ds[()]
            for group in ("initial", "impact", "landing")
            for name, ds in ((f"{group}.{k}", v) for k, v in f[f"pellets/{group}"].items())
        }
        mass, inertia = float(f["constants/mass"][()]), float(f["constants/inertia"][()])
        per_shot = {name: ds[()] for name, ds in f["stats/shots"].items() if not is_dimension(ds)}
        intervals = {
            name: (ds.attrs["ci_low"], ds.attrs["ci_high"]) for name, ds in f["stats"].items() if isinstance(ds, h5py.Dataset)
        }
        assert f["stats/shots"].attrs["shots"] == SHOTS and f["progress/shot_partials"].shape[0] == SHOTS * 118
    normals = np.array([[0.0, 1.0, 0.0]])
    for s in range(SHOTS):
        sl = slice(s * COUNT, (s + 1) * COUNT)
        hit = p["impact.surface"][sl, 0] >= 0
        landed = p["landing.surface"][sl] >= 0
        ref = statistics_from_arrays(
            pellets=COUNT,
            mass=mass,
            inertia=inertia,
            launch_velocity=p["initial.velocity"][sl],
            launch_angular_velocity=p["initial.angular_velocity"][sl],
            hit=hit,
            normal=np.repeat(normals, COUNT, 0),
            velocity_before=p["impact.velocity_before"][sl, 0],
            angular_velocity_before=p["impact.angular_velocity_before"][sl, 0],
            velocity_after=p["impact.velocity"][sl, 0],
            angular_velocity_after=p["impact.angular_velocity"][sl, 0],
            slipped_first=p["impact.slipped"][sl, 0] == 1,
            landed=landed,
            range_=p["landing.range"][sl],
            slipped_last=p["impact.slipped"][sl, 0] == 1,
            time_aloft=p["landing.time"][sl] - p["impact.time"][sl, 0],
            landing_velocity=np.nan_to_num(p["landing.velocity"][sl]),
        )
        for name, value in ref.items():
            if name == "flight_scale_max":  # not recomputable from the outputs (statistics_from_arrays gives NaN)
                continue
            got = per_shot[name][s]
            assert (math.isnan(got) and math.isnan(value)) or got == pytest.approx(value, rel=1e-9, abs=1e-9), (
                s,
                name,
                got,
                value,
            )
    for name, (low, high) in intervals.items():
        values = per_shot[name][np.isfinite(per_shot[name])]
        scale = SHOTS if STAT_KIND[name] == "total" else 1
        if len(values) >= 2:  # Student t over the shots, computed here with SciPy
            half = stats_t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / math.sqrt(len(values))
            assert (low, high) == pytest.approx(
                (scale * (values.mean() - half), scale * (values.mean() + half)), rel=1e-12, abs=1e-12
            ), name
    assert stats["range_mean"] == pytest.approx(np.mean(per_shot["range_mean"]), rel=1e-3)
    assert stats.ensemble.shots == SHOTS and stats.ensemble.low["range_mean"] == intervals["range_mean"][0]


def test_chunk_size_and_resume_leave_every_bit(tmp_path, multi):
    """Another chunk size, statistics only, and a run interrupted after its first chunk and resumed:
    per-shot values, intervals and partials bitwise those of the reference run."""
    path, _ = multi
    big = tmp_path / "big.h5"
    wr.run(load_scene(SCENE, BASE + ["numerics.chunk_size=131072"]), big, device="cpu")
    resumed = tmp_path / "resumed.h5"
    scene = load_scene(SCENE, BASE + ["numerics.chunk_size=65536"])
    interrupt_after(1, scene, resumed)
    with h5py.File(str(resumed) + ".partial", "r") as f:
        assert f["progress/rows"][()] == 65536 and len(f["progress/shot_partials"]) == 2 * 118
    wr.run(scene, resumed, device="cpu", resume=True)
    for other in (big, resumed):
        with h5py.File(other, "r") as a, h5py.File(path, "r") as b:
            assert_same_stats(a["stats"], b["stats"])
            np.testing.assert_array_equal(a["progress/shot_partials"][()], b["progress/shot_partials"][()])
    stats_only = wr.run(load_scene(SCENE, BASE + ["numerics.chunk_size=131072"]), device="cpu")
    with h5py.File(path, "r") as b:
        for name, values in stats_only.ensemble.per_shot.items():
            np.testing.assert_array_equal(values, b[f"stats/shots/{name}"][()], err_msg=name)


def test_summary_and_report_show_the_intervals(multi, capsys):
    """`report` prints the intervals table of a run of several shots; a single shot has none."""
    path, stats = multi
    text = format_tables(read_results(path))
    assert "95% confidence intervals over 5 shots" in text
    table = {x.split()[0]: x.split() for x in text.split("95% confidence intervals")[1].split("\n\n")[0].splitlines()[3:]}
    columns = ("all shots", "mean over shots", "95% low", "95% high")
    for name, cells in table.items():  # every row's numbers apart: the value over all shots, the mean of
        if "n/a" in cells[1:5]:  # the per-shot values and the interval around that mean
            continue
        value, centre, low, high = (float(c.replace(",", "")) for c in cells[1:5])
        assert low <= centre <= high, (name, cells)
        got = dict(zip(columns, cells[1:5]))
        if name in ("pellets", "hits", "landed", "missed", "stick", "slip", "escaped"):
            assert "." not in "".join(got.values()), (name, cells)  # counts are whole: 150,000, not 150,000.0000
        else:
            decimals = len(got["95% low"].partition(".")[2])
            want_low, want_high = stats.ensemble.low[name], stats.ensemble.high[name]
            assert (low, high) == pytest.approx((want_low, want_high), abs=0.51 * 10.0**-decimals), name
            assert value == pytest.approx(stats[name], abs=0.51 * 10.0**-decimals), name
    assert table["range_mean"][-2:] == ["per", "shot"] and table["pellets"][1] == f"{int(stats['pellets']):,}"
    assert table["range_max"][-3:] == ["one", "shot's", "extreme"]
    assert float(table["range_max"][1]) >= float(table["range_max"][4])  # the extreme of all shots, said apart
    assert cli_main(["run", SCENE, "--device", "cpu", "--set", "shot.count=200", "--set", "shot.shots=3"]) == 0
    assert "95% confidence intervals over 3 shots" in capsys.readouterr().out
    assert cli_main(["run", SCENE, "--device", "cpu", "--set", "shot.count=200"]) == 0
    assert "confidence" not in capsys.readouterr().out


def test_intervals_cover_on_real_runs():
    """The paper's shot (collisions off), 2,000 shots of 50 pellets, statistics only: split into 100
    ensembles of 20 shots, the 95% intervals of the mean range and of the mean v_t after impact
    cover the 2,000-shot mean (its own error is a tenth of an interval's half width) in 95% of
    them, within 3 binomial standard deviations (0.065). (One shot's L+, skewness -3, needs about
    100 shots for that: docs/output.md.)"""
    stats = wr.run(
        load_scene(SCENE, ["shot.count=50", "shot.shots=2000", "surfaces.0.mu_s=0.2", "surfaces.0.mu_d=0.18"]), device="cpu"
    )
    for name in ("range_mean", "post_mean_vt"):
        values = stats.ensemble.per_shot[name]
        truth = values.mean()
        covered = [low <= truth <= high for low, high in (t_interval(part) for part in values.reshape(100, 20))]
        assert abs(np.mean(covered) - 0.95) <= 3 * math.sqrt(0.95 * 0.05 / 100), (name, np.mean(covered))


def test_the_xarray_reader_gives_intervals_and_per_shot_values(multi):
    """`open_run(...).stats`: each statistic with its ci_low / ci_high attributes, and its per-shot
    values as shots_<name> along the dimension `shot`."""
    pytest.importorskip("xarray")
    from warp_ricochet.io.reader import open_run

    path, stats = multi
    with open_run(path) as run:
        assert run.stats["range_mean"].attrs["ci_low"] == stats.ensemble.low["range_mean"]
        assert run.stats["shots_range_mean"].dims == ("shot",)
        np.testing.assert_array_equal(run.stats["shots_range_mean"].values, stats.ensemble.per_shot["range_mean"])


def test_a_pellet_file_gives_the_same_per_shot_values(tmp_path, multi):
    """Launch states from a pellet file (shots straddling chunks read from the file's rows): the
    sampled run's states give bitwise its per-shot values."""
    path, stats = multi
    with h5py.File(path, "r") as f:
        states = {k: f[f"pellets/initial/{k}"][()] for k in ("position", "velocity", "angular_velocity")}
    np.savez(tmp_path / "pellets.npz", **states)
    import tomllib

    from warp_ricochet.scene import scene_from_dict

    with open(SCENE, "rb") as fh:
        raw = tomllib.load(fh)
    raw["shot"] = {
        "file": str(tmp_path / "pellets.npz"),
        "shots": SHOTS,
        "diameter": raw["shot"]["diameter"],
        "density": raw["shot"]["density"],
    }
    raw["surfaces"][0].update(mu_s=0.2, mu_d=0.18)
    raw["numerics"].update(precision="float64", chunk_size=65536)
    raw["output"] = {"fields": ["landing.range"]}
    scene = scene_from_dict(raw)
    assert scene.shot.count == COUNT and scene.shot.shots == SHOTS
    again = wr.run(scene, device="cpu")
    for name, values in stats.ensemble.per_shot.items():
        np.testing.assert_array_equal(again.ensemble.per_shot[name], values, err_msg=name)


@pytest.mark.parametrize("collisions", ["false", "true"])
def test_the_per_shot_pass_counts_no_landing_twice(tmp_path, collisions):
    """The per-shot pass runs the core with the landing tallies off: the histograms hold each
    landing once."""
    path = tmp_path / "q.h5"
    stats = wr.run(load_scene(SCENE, ["shot.shots=4", "shot.count=100", f"collisions.enabled={collisions}"]), path, device="cpu")
    assert stats.ensemble is not None
    with h5py.File(path, "r") as f:
        assert (f["stats/histograms/counts"][()].sum(axis=1)[:2] == stats["landed"]).all()


def test_a_sweep_keeps_each_points_intervals(tmp_path):
    """A sweep's top-level /stats carry each point's intervals as arrays (one per point), equal to
    its /runs/NNNN/stats attributes; a point of one shot has none (NaN)."""
    scene = load_scene(SCENE, ["shot.count=200", "output.fields=[]"])
    out = tmp_path / "sweep.h5"
    wr.sweep(scene, {"shot.shots": [3, 1]}, output=str(out), device="cpu")
    with h5py.File(out, "r") as f:
        ds = f["stats/range_mean"]
        low, high = ds.attrs["ci_low"], ds.attrs["ci_high"]
        point = f["runs/0000/stats/range_mean"].attrs
        assert low.shape == high.shape == (2,) and ds.attrs["ci_method"] == point["ci_method"]
        assert (low[0], high[0]) == (point["ci_low"], point["ci_high"]) and low[0] < ds[0] < high[0]
        assert np.isnan(low[1]) and np.isnan(high[1])


def test_a_piece_is_a_core_thread_of_pellets_cut_into_whole_sub_pieces():
    """A stored piece holds PIECE pellets, as a core kernel's thread does (short sums); core.shots
    follows SUB of them a thread, whole sub-pieces merged in order."""
    from warp_ricochet.core.shots import SUB, SUB_PIECES
    from warp_ricochet.tallies.ensemble import PIECE
    from warp_ricochet.tallies.reduce import PER_THREAD

    assert PIECE == PER_THREAD and SUB * SUB_PIECES == PIECE
