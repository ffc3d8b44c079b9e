"""The person and the named places of issue 26 (docs/hazard.md, section 9): the scene keys
hazard.body_height and [[hazard.points]], the statistics of tallies.points, their HDF5 datasets
and the summary lines."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import cli, make_scene, paper_raw

# the paper's shot (direction (1, -1, 0) onto the ground y = 0): u = x, v = n x u = -z
MAP = {"map_cell": 1.0, "map_extent": [0.0, 200.0, -50.0, 50.0]}
PLACES = [{"name": "car park", "position": [150.0, 0.0, 10.0]}, {"name": "footpath", "position": [50.0, 0.0, -3.0], "area": 0.5}]


def test_places_and_body_height_are_read_with_their_defaults_and_round_trip():
    scene = make_scene(hazard={**MAP, "points": PLACES})
    assert scene.hazard.body_height == 1.8
    assert [(p.name, p.position, p.area) for p in scene.hazard.points] == [
        ("car park", (150.0, 0.0, 10.0), 0.7),
        ("footpath", (50.0, 0.0, -3.0), 0.5),
    ]
    assert scene.hazard.radii == pytest.approx((0.7 / 3.6, 0.5 / 3.6), rel=1e-15)
    again = wr.scene.scene_from_dict(tomllib.loads(scene.to_toml()))
    assert again == scene and again.hazard.points == scene.hazard.points
    tall = make_scene(hazard={**MAP, "points": PLACES, "body_height": 2.0})
    assert tall.hazard.body_height == 2.0 and tall.hazard.radii[0] == pytest.approx(0.7 / 4.0)
    plain = make_scene(hazard={})
    assert plain.hazard.points == () and "points" not in plain.to_dict()["hazard"]


@pytest.mark.parametrize(
    "hazard, key, text",
    [
        ({"points": PLACES}, "hazard.map_cell", "is required with hazard.points"),
        ({"map_cell": 1.0, "points": PLACES}, "hazard.map_extent", "(missing)"),
        ({**MAP, "points": [{"name": "far", "position": [250.0, 0.0, 0.0]}]}, "hazard.points.0.position", "(u, v) = (250, 0)"),
        # v = -z: z = 60 is v = -60, below v_min
        (
            {**MAP, "points": [PLACES[0], {"name": "side", "position": [10.0, 0.0, 60.0]}]},
            "hazard.points.1.position",
            "(10, -60)",
        ),
        ({**MAP, "points": [PLACES[0], {**PLACES[1], "name": "car park"}]}, "hazard.points.1.name", "a name of its own"),
        ({**MAP, "points": [{"name": "", "position": [5.0, 0.0, 0.0]}]}, "hazard.points.0.name", "1 to 100 printable"),
        ({**MAP, "points": [{"name": "a\nb", "position": [5.0, 0.0, 0.0]}]}, "hazard.points.0.name", "printable"),
        ({**MAP, "points": [{"position": [5.0, 0.0, 0.0]}]}, "hazard.points.0.name", "(missing)"),
        ({**MAP, "points": [{"name": "a"}]}, "hazard.points.0.position", "(missing)"),
        ({**MAP, "points": [{"name": "a", "position": [5.0, 0.0, 0.0], "area": 0.0}]}, "hazard.points.0.area", "(0, 1e+06]"),
        ({**MAP, "points": [{"name": "a", "position": [5.0, 0.0, 0.0], "aera": 1.0}]}, "hazard.points.0.aera", "did you mean"),
        ({**MAP, "points": {"name": "a"}}, "hazard.points", "array of at most 64 tables"),
        ({**MAP, "points": [3]}, "hazard.points.0", "must be a table"),
        ({"body_height": 0.0}, "hazard.body_height", "(0, 1000] (m)"),
        ({"body_height": float("nan")}, "hazard.body_height", "finite"),
    ],
)
def test_bad_places_and_body_heights_are_refused_in_one_line(hazard, key, text):
    with pytest.raises(wr.SceneError) as info:
        make_scene(hazard=hazard)
    message = str(info.value)
    assert message.startswith(f"{key} = ") and text in message and "\n" not in message, message


def test_a_place_off_the_map_is_refused_by_the_cli_before_any_work(tmp_path):
    out = tmp_path / "x.h5"
    place = '{name = "far", position = [150.0, 0.0, 0.0]}'
    argv = ["run", "examples/paper.toml", "--set", "hazard.map_cell=1.0", "--set", "hazard.map_extent=[0, 100, -5, 5]"]
    rc, stdout, stderr = cli([*argv, "--set", f"hazard.points=[{place}]", "-o", out, "--device", "cpu"])
    assert rc == 2 and stderr.count("\n") == 1 and "hazard.points.0.position = [150.0, 0.0, 0.0]: lies at" in stderr
    assert not out.exists()


def test_set_and_sweep_reach_the_body_height_and_a_places_keys(tmp_path):
    from warp_ricochet.api import _point_scenes
    from warp_ricochet.scene import SweepPoints, load_scene
    from warp_ricochet.scene.toml_out import toml_lines

    raw = paper_raw()
    raw["hazard"] = {**MAP, "points": PLACES}
    path = tmp_path / "s.toml"
    path.write_text("\n".join(toml_lines(raw, "")) + "\n")
    scene = load_scene(path, ["hazard.body_height=1.5", "hazard.points.1.area=0.3", "hazard.points.0.position=[20.0, 0.0, 1.0]"])
    assert scene.hazard.body_height == 1.5 and scene.hazard.points[1].area == 0.3
    assert scene.hazard.points[0].position == (20.0, 0.0, 1.0)
    swept = _point_scenes(load_scene(path), SweepPoints({"hazard.body_height": [1.2, 2.0], "hazard.points.0.area": [0.4]}), False)
    assert [(s.hazard.body_height, s.hazard.points[0].area) for s in swept] == [(1.2, 0.4), (2.0, 0.4)]
    with pytest.raises(wr.SceneError, match=r"^hazard.points.0.position = \[300.0, 0.0, 10.0\]: lies at"):
        _point_scenes(load_scene(path), SweepPoints({"hazard.points.0.position.0": [300.0]}), False)


def test_above_thresholds_sums_the_levels_above_each_thresholds_rank():
    from warp_ricochet.tallies.points import above_thresholds

    # 3 thresholds, scene order ranked (2, 0, 1) by speed: order = argsort = [1, 2, 0]
    counts = np.array([[5, 0], [1, 2], [3, 0], [7, 4]])  # levels 0..3 x 2 places
    got = above_thresholds(counts, np.array([1, 2, 0]))
    # threshold 1 (rank 0): levels >= 1; threshold 2 (rank 1): >= 2; threshold 0 (rank 2): level 3
    assert got.tolist() == [[7, 11, 10], [4, 6, 4]] and got.dtype == np.int64


def test_clopper_pearson_is_scipys_exact_interval_and_solves_its_equations():
    from decimal import Decimal, getcontext
    from math import comb

    from scipy.stats import binomtest

    from warp_ricochet.tallies.points import clopper_pearson

    getcontext().prec = 50
    rng = np.random.default_rng(26)
    for _ in range(200):
        n = int(10 ** rng.uniform(0, 9))
        m = np.array([0, n, *rng.integers(0, n + 1, 3), min(n, int(rng.integers(0, 5)))])
        low, high = clopper_pearson(m, n)
        for k, lo, hi in zip(m, low, high):
            ref = binomtest(int(k), n).proportion_ci(0.95, method="exact")
            np.testing.assert_allclose([lo, hi], [ref.low, ref.high], rtol=1e-9, atol=4e-12)  # (brentq: xtol 2e-12)
            if 0 < k <= 3 < n:  # the defining equation of the upper end, in 50 digits: P(X <= k | high) = 2.5%
                q = Decimal(float(hi))
                cdf = sum(Decimal(comb(n, j)) * q**j * (1 - q) ** (n - j) for j in range(int(k) + 1))
                assert float(cdf) == pytest.approx(0.025, rel=1e-7)  # (scipy's beta quantile: ~3e-9 of q at n ~ 1e9)
    for n in (1, 7, 1000, 10**9):
        low, high = clopper_pearson([0, n], n)
        assert low[0] == 0.0 and high[0] == pytest.approx(1.0 - 0.025 ** (1.0 / n), rel=1e-12)
        assert high[1] == 1.0 and low[1] == pytest.approx(0.025 ** (1.0 / n), rel=1e-12)
    assert np.isnan(clopper_pearson([0], 0)).all()


def test_place_statistics_against_a_decimal_reference():
    from decimal import Decimal, getcontext

    from warp_ricochet.tallies.points import clopper_pearson, place_statistics

    getcontext().prec = 60
    rng = np.random.default_rng(7)
    for _ in range(50):
        places, thresholds, per_shot = int(rng.integers(1, 5)), int(rng.integers(1, 5)), int(rng.integers(1, 2000))
        shots = int(10 ** rng.uniform(0, 5))
        n = per_shot * shots
        counts = rng.multinomial(int(rng.integers(0, n + 1)), rng.dirichlet(np.ones(thresholds + 1)), size=places).T
        order = rng.permutation(thresholds)
        out = place_statistics(counts, order, n, per_shot)
        for p in range(places):
            for i in range(thresholds):
                rank = int(np.flatnonzero(order == i)[0])
                m = int(counts[rank + 1 :, p].sum())
                low, high = (float(x[0]) for x in clopper_pearson([m], n))
                assert out["pellets"][p, i] == m and out["fraction"][p, i] == m / n
                assert out["expected_per_shot"][p, i] == pytest.approx(m / shots, rel=1e-14)
                assert (out["expected_ci_low"][p, i], out["expected_ci_high"][p, i]) == (per_shot * low, per_shot * high)
                for name, q in (("probability", m / n), ("ci_low", low), ("ci_high", high)):
                    ref = float(1 - (1 - Decimal(q)) ** per_shot)
                    assert out[name][p, i] == pytest.approx(ref, rel=1e-13, abs=1e-300), (name, q, per_shot)
                assert out["ci_low"][p, i] <= out["probability"][p, i] <= out["ci_high"][p, i]
                assert out["probability"][p, i] <= out["expected_per_shot"][p, i] * (1 + 1e-15)
    assert (out["pellets_simulated"], out["pellets_per_shot"]) == (n, per_shot)


def test_place_statistics_of_none_and_of_all():
    from warp_ricochet.tallies.points import place_statistics

    none = place_statistics(np.array([[0], [0]]), np.array([0]), 0, 10)
    assert np.isnan(none["probability"]).all() and np.isnan(none["ci_high"]).all()
    n, per_shot = 4000, 400
    every = place_statistics(np.array([[0, 4000], [n, 0]]), np.array([0]), n, per_shot)
    assert every["probability"].tolist() == [[1.0], [0.0]] and every["ci_high"][0, 0] == 1.0
    assert every["ci_low"][1, 0] == 0.0
    assert every["ci_high"][1, 0] == pytest.approx(1 - 0.025 ** (per_shot / n), rel=1e-12)
    assert every["expected_per_shot"].tolist() == [[400.0], [0.0]]


@pytest.fixture(scope="module")
def places_file(tmp_path_factory):
    """A run of the paper's shot with two named places, and the scene."""
    raw = paper_raw()
    raw["shot"]["count"] = 300
    scene = make_scene(raw, "float64", hazard={**MAP, "points": PLACES, "body_height": 1.7, "fractions": [0.01]})
    path = tmp_path_factory.mktemp("places") / "run.h5"
    wr.run(scene, path, device="cpu")
    return scene, path


def test_a_run_file_holds_the_body_height_and_the_places(places_file):
    import h5py

    scene, path = places_file
    with h5py.File(path, "r") as f:
        h = f["hazard"]
        assert h["body_height"][()] == 1.7 and h["body_height"].attrs["units"] == "m"
        g = h["points"]
        assert [n.decode() for n in g["name"][()]] == ["car park", "footpath"]
        assert g["position"][()].tolist() == [[150.0, 0.0, 10.0], [50.0, 0.0, -3.0]]
        assert g["area"][()].tolist() == [0.7, 0.5] and g["radius"][()].tolist() == [0.7 / 3.4, 0.5 / 3.4]
        assert g.attrs["pellets_per_shot"] == 300 and g.attrs["confidence"] == 0.95
        for name in ("pellets", "expected_per_shot", "expected_ci_low", "expected_ci_high", "probability", "ci_low", "ci_high"):
            assert g[name].shape == (2, 4) and g[name].attrs["units"] == "1" and g[name].attrs["description"]
        assert g["pellets"].dtype == np.int64
        assert [d[0].name for d in g["probability"].dims] == ["/hazard/place", "/hazard/threshold"]
        assert [d[0].name for d in g["position"].dims] == ["/hazard/place", "/xyz"]


def _fill(path, scene, counts, monkeypatch, pellets=None):
    """Write the run's results again as io.writer does at its end, from a TallyTotals whose point
    passages by level are `counts` (levels, places): summarize's "points" (the kernel's)."""
    import h5py

    from warp_ricochet.io import tally_out
    from warp_ricochet.tallies.counts import TallySetup, TallyTotals

    plain = tally_out.summarize
    monkeypatch.setattr(tally_out, "summarize", lambda *a, **k: {**plain(*a, **k), "points": {"counts": counts}})
    tally = TallyTotals(TallySetup.of(scene, 6.0e-5, 0.00125, 411.0))
    with h5py.File(path, "r+") as f:
        tally_out.write_results(f, tally, 0, pellets)
    return tally.setup.order


def test_the_places_statistics_are_written_and_read_back_by_report_and_open_run(places_file, tmp_path, monkeypatch):
    import shutil

    import h5py

    from warp_ricochet.report.hazard_tables import from_file, tally_lines
    from warp_ricochet.tallies.points import place_statistics

    scene, original = places_file
    path = tmp_path / "run.h5"
    shutil.copy(original, path)
    counts = np.array([[100, 3], [50, 0], [0, 2], [7, 0], [1, 0]], dtype=np.int64)  # 5 levels x 2 places
    order = _fill(path, scene, counts, monkeypatch)  # n: /stats/pellets
    expected = place_statistics(counts, order, 300, 300)
    with h5py.File(path, "r") as f:
        for name in ("pellets", "probability", "ci_low", "ci_high", "expected_per_shot", "expected_ci_low", "expected_ci_high"):
            np.testing.assert_array_equal(f[f"hazard/points/{name}"][()], expected[name])
        lines = tally_lines(from_file(f), 300)
    head = lines.index(next(line for line in lines if line.startswith("probability of a hit at named places")))
    assert "per shot of 300 pellets, from 300" in lines[head] and len(lines) == head + 2 + 8
    names = [n for n, _kind, _value in scene.hazard.thresholds]
    row = lines[head + 2 + names.index("skin_perforation")].split()  # car park, skin_perforation
    m = int(expected["pellets"][0, names.index("skin_perforation")])
    assert row[:4] == ["car", "park", "skin_perforation", f"{m:,}"], row
    assert row[4] == f"{expected['probability'][0, 3]:.4g}" and row[5] == f"[{expected['ci_low'][0, 3]:.4g},"
    rc, report, stderr = cli(["report", path])
    assert rc == 0 and "\n".join(lines[head:]) in report, stderr
    pytest.importorskip("xarray")
    with wr.open_run(path) as run:
        probability = run.hazard_results["points_probability"]
        assert probability.dims == ("place", "threshold") and probability.attrs["units"] == "1"
        np.testing.assert_array_equal(probability.values, expected["probability"])
        assert list(run.hazard_results["points_name"].values) == ["car park", "footpath"]
        assert float(run.hazard_results["body_height"]) == 1.7


def test_the_run_summary_shows_the_places_table(places_file, monkeypatch):
    """From the counts a run returns (`RunStats.tally`; summarize's "points", the kernel's)."""
    from warp_ricochet.pipeline import RunStats
    from warp_ricochet.report import format_run_summary
    from warp_ricochet.tallies import quantiles
    from warp_ricochet.tallies.counts import TallySetup, TallyTotals

    scene, _path = places_file
    counts = np.array([[0, 0], [0, 0], [0, 0], [0, 0], [2, 0]], dtype=np.int64)
    plain = quantiles.summarize
    monkeypatch.setattr(quantiles, "summarize", lambda *a, **k: {**plain(*a, **k), "points": {"counts": counts}})
    stats = RunStats({"pellets": 600.0, "landed": 0.0})
    stats.tally = TallyTotals(TallySetup.of(scene, 6.0e-5, 0.00125, 411.0))
    text = format_run_summary(stats, scene=scene)
    # every threshold at level 4: m = 2 of n = 600, N = 300: P = 1 - (1 - 1/300)^300
    row = next(line for line in text.splitlines() if line.startswith("  car park  skin_perforation"))
    assert f"{-np.expm1(300 * np.log1p(-2 / 600)):.4g} [" in row and "  1 [" in row, row
    assert "footpath" in text and "per shot of 300 pellets, from 600" in text
    assert "named places" not in format_run_summary(stats)  # (no scene: no names)


def test_the_writer_takes_the_runs_pellets_for_n(places_file, tmp_path, monkeypatch):
    import shutil

    import h5py

    from warp_ricochet.tallies.points import place_statistics

    scene, original = places_file
    path = tmp_path / "run.h5"
    shutil.copy(original, path)
    counts = np.array([[0, 0], [0, 0], [0, 0], [0, 0], [3, 0]], dtype=np.int64)
    order = _fill(path, scene, counts, monkeypatch, pellets=900)
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(f["hazard/points/ci_high"][()], place_statistics(counts, order, 900, 300)["ci_high"])
        assert f["hazard/points/ci_high"][1, 0] == pytest.approx(1 - 0.025 ** (300 / 900), rel=1e-12)  # m = 0
