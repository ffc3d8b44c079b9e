"""Hazard thresholds, maps and danger distances (issue 15, section 2): per-pellet fields against
NumPy, maps summed against the per-pellet totals, danger distances against NumPy's quantiles of the
per-pellet data, and the coverage of their confidence intervals on a case with a known answer."""

import math

import h5py
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import warp_ricochet as wr
from tests.helpers import cli, make_scene, paper_raw
from warp_ricochet.tallies import bins
from warp_ricochet.tallies.quantiles import binomial_point, danger_distance, needed_landings

# thresholds inside the landing distribution (E/A 2.2e5 to 2.9e5 J/m^2, speeds 190 to 225 m/s), so each
# splits the landings and a wrong E/A or |v| would show
HAZARD = {
    "energy_density": {"low": 237_000.0, "high": 267_000.0},
    "speed": {"fast": 212.0},
    "fractions": [0.01, 1e-6],
    "map_cell": 0.5,
    "map_extent": [100.0, 140.0, -20.0, 20.0],
}


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    raw = paper_raw()
    raw["shot"]["count"] = 20_000
    scene = make_scene(raw, "float64", hazard=HAZARD, output={"fields": ["landing", "hazard"]})
    path = tmp_path_factory.mktemp("hazard") / "run.h5"
    stats = wr.run(scene, path, device="cpu")
    return scene, path, stats


def _per_pellet(f):
    r = f["pellets/landing/range"][()]
    landed = np.isfinite(r)
    return {
        "landed": landed,
        "position": f["pellets/landing/position"][()][landed],
        "velocity": f["pellets/landing/velocity"][()][landed],
        "energy": f["pellets/hazard/energy"][()][landed],
        "density": f["pellets/hazard/energy_density"][()][landed],
        "exceeds": f["pellets/hazard/exceeds"][()][landed],
    }


def test_per_pellet_energy_density_and_thresholds(run_file):
    scene, path, stats = run_file
    with h5py.File(path, "r") as f:
        p = _per_pellet(f)
        mass, radius = f["constants/mass"][()], f["constants/radius"][()]
        assert f["pellets/hazard/exceeds"][()][~p["landed"]].tolist() == [0] * int((~p["landed"]).sum())
    v2 = (p["velocity"] ** 2).sum(axis=1)
    np.testing.assert_allclose(p["energy"], 0.5 * mass * v2, rtol=1e-14)
    np.testing.assert_allclose(p["density"], 0.5 * mass * v2 / (math.pi * radius**2), rtol=1e-14)
    # E/A = rho d v^2 / 3 for a sphere
    np.testing.assert_allclose(p["density"], scene.shot.density * scene.shot.diameter * v2 / 3, rtol=1e-12)
    for bit, (_name, kind, value) in enumerate(scene.hazard.thresholds):
        above = p["density"] >= value if kind == "energy_density" else np.sqrt(v2) >= value
        near = np.isclose(p["density"] if kind == "energy_density" else np.sqrt(v2), value, rtol=1e-12)
        got = (p["exceeds"] >> bit & 1).astype(bool)
        assert np.array_equal(got[~near], above[~near]), kind
        assert 0.1 * len(above) < above.sum() < 0.9 * len(above), (kind, above.mean())


def test_maps_sum_to_the_per_pellet_totals(run_file):
    scene, path, stats = run_file
    with h5py.File(path, "r") as f:
        p = _per_pellet(f)
        m = {
            name: f[f"hazard/map/{name}"][()]
            for name in (
                "count",
                "outside",
                "elsewhere",
                "energy",
                "above",
                "u_edges",
                "v_edges",
                "origin",
                "u_axis",
                "v_axis",
                "quantum",
            )
        }
    assert m["count"].sum() + m["outside"] + m["elsewhere"] == stats["landed"]
    local = p["position"] - m["origin"]
    u, v = local @ m["u_axis"], local @ m["v_axis"]
    i = np.floor((u - m["u_edges"][0]) / 0.5).astype(int)
    j = np.floor((v - m["v_edges"][0]) / 0.5).astype(int)
    inside = (i >= 0) & (j >= 0) & (i < len(m["u_edges"]) - 1) & (j < len(m["v_edges"]) - 1)
    assert inside.sum() > 0.9 * len(inside) and m["outside"] == (~inside).sum()
    expected = np.zeros_like(m["count"])
    np.add.at(expected, (j[inside], i[inside]), 1)
    np.testing.assert_array_equal(m["count"], expected)
    energy = np.zeros(m["count"].shape)
    np.add.at(energy, (j[inside], i[inside]), p["energy"][inside])
    np.testing.assert_allclose(m["energy"], energy, rtol=0, atol=0.5 * m["quantum"] * m["count"].max() + 1e-300)
    assert abs(m["energy"].sum() - p["energy"][inside].sum()) <= 0.5 * m["quantum"] * inside.sum()
    for bit in range(len(scene.hazard.thresholds)):
        above = np.zeros_like(m["count"])
        hit = inside & (p["exceeds"] >> bit & 1).astype(bool)
        np.add.at(above, (j[hit], i[hit]), 1)
        np.testing.assert_array_equal(m["above"][bit], above)


def test_float32_map_cells_move_only_landings_at_a_cell_edge(tmp_path, device):
    """A float32 run maps its landings in float32 (`tallies.landing.map_cell`): against cells found
    in float64 from the same positions, only landings within rounding of a cell edge may move."""
    raw = paper_raw()
    raw["shot"]["count"] = 20_000
    scene = make_scene(raw, "float32", hazard=HAZARD, output={"fields": ["landing", "hazard"]})
    stats = wr.run(scene, tmp_path / "run.h5", device=device)
    with h5py.File(tmp_path / "run.h5", "r") as f:
        p = _per_pellet(f)
        m = {
            name: f[f"hazard/map/{name}"][()] for name in ("count", "outside", "u_edges", "v_edges", "origin", "u_axis", "v_axis")
        }
    assert m["count"].sum() + m["outside"] == stats["landed"]
    local = p["position"].astype(np.float64) - m["origin"]
    fu, fv = (local @ m["u_axis"] - m["u_edges"][0]) / 0.5, (local @ m["v_axis"] - m["v_edges"][0]) / 0.5
    i, j = np.floor(fu).astype(int), np.floor(fv).astype(int)
    inside = (i >= 0) & (j >= 0) & (i < len(m["u_edges"]) - 1) & (j < len(m["v_edges"]) - 1)
    edge = (np.abs(fu - np.round(fu)) < 1e-3) | (np.abs(fv - np.round(fv)) < 1e-3)  # 0.5 mm of a cell edge
    expected = np.zeros_like(m["count"])
    np.add.at(expected, (j[inside], i[inside]), 1)
    assert inside.sum() > 0.9 * len(inside) and edge.sum() < 0.01 * len(edge)
    assert np.abs(m["count"] - expected).sum() <= 2 * edge.sum()
    assert abs(int(m["outside"]) - int((~inside).sum())) <= edge.sum()


def test_danger_distances_hold_numpys_quantiles_of_the_hazardous_landings(run_file):
    scene, path, stats = run_file
    with h5py.File(path, "r") as f:
        p = _per_pellet(f)
        d = {
            name: f[f"hazard/landing_danger_distance/{name}"][()] for name in ("distance", "ci_low", "ci_high", "needed_landings")
        }
        landings = f["hazard/thresholds/landings"][()]
    delta = p["position"] - np.asarray(scene.shot.envelope_center)
    distance = np.hypot(delta[:, 0], delta[:, 2])  # gravity along -y
    for bit in range(len(scene.hazard.thresholds)):
        hazardous = distance[(p["exceeds"] >> bit & 1).astype(bool)]
        assert landings[bit] == len(hazardous)
        for j, fraction in enumerate(scene.hazard.fractions):
            if not len(hazardous):
                assert np.isnan(d["distance"][bit, j])
                continue
            true = np.quantile(hazardous, 1 - fraction, method="inverted_cdf")
            value = d["distance"][bit, j]
            assert value / (1 + bins.RELATIVE_WIDTH) * (1 - 1e-7) <= true <= value * (1 + 1e-7), (bit, fraction)
            assert d["ci_low"][bit, j] <= true <= d["ci_high"][bit, j]
            assert d["needed_landings"][bit, j] == needed_landings(fraction)
            assert math.isinf(d["ci_high"][bit, j]) == (len(hazardous) < needed_landings(fraction))


def test_danger_distances_are_numpys_quantiles_of_the_per_pellet_reach(run_file):
    """Along the path (issue 26): /hazard/danger_distance from the reach histograms against NumPy's
    quantiles of /pellets/hazard/reach, the pellets reaching above each threshold counted."""
    scene, path, _stats = run_file
    with h5py.File(path, "r") as f:
        reach = f["pellets/hazard/reach"][()].astype(np.float64)
        d = {name: f[f"hazard/danger_distance/{name}"][()] for name in ("distance", "ci_low", "ci_high")}
        reaching = f["hazard/thresholds/reaching"][()]
    assert reach.shape == (scene.shot.pellets, len(scene.hazard.thresholds))
    for i in range(reach.shape[1]):
        above = reach[np.isfinite(reach[:, i]), i]
        assert reaching[i] == len(above)
        for j, fraction in enumerate(scene.hazard.fractions):
            if not len(above):
                assert np.isnan(d["distance"][i, j])
                continue
            true = np.quantile(above, 1 - fraction, method="inverted_cdf")
            value = d["distance"][i, j]
            assert value / (1 + bins.RELATIVE_WIDTH) * (1 - 1e-7) <= true <= value * (1 + 1e-7), (i, fraction)
            assert d["ci_low"][i, j] <= true <= d["ci_high"][i, j]


def test_confidence_intervals_cover_a_known_quantile_95_percent_of_the_time():
    rng = np.random.default_rng(15)
    p, n, trials = 0.01, 2000, 400
    true = -math.log(p)  # the 1 - p quantile of Exp(1)
    covered = 0
    for _ in range(trials):
        x = rng.exponential(size=n).astype(np.float32)
        _value, low, high, _needed = danger_distance(np.bincount(bins.bin_index(x), minlength=bins.BINS), p)
        covered += low <= true <= high
    rate = covered / trials
    sd = math.sqrt(0.95 * 0.05 / trials)
    assert 0.95 - 3 * sd <= rate <= 0.95 + 0.04, rate  # the interval is conservative (>= 95% by construction)


def test_binomial_points_and_the_pellets_a_fraction_needs():
    from scipy import stats as sps

    for n, p, alpha in ((100, 0.01, 0.025), (5000, 0.001, 0.975), (2000, 0.3, 0.025), (10**9, 1e-3, 0.975)):
        assert abs(binomial_point(n, p, alpha) - sps.binom.ppf(alpha, n, p)) <= (1 if n * p > 1e5 else 0), (n, p)
    assert needed_landings(1e-3) == 3688 and needed_landings(1e-6) == 3_688_878
    value, low, high, needed = danger_distance(
        np.bincount(bins.bin_index(np.arange(1, 101, dtype=np.float32)), minlength=bins.BINS), 1e-3
    )
    assert math.isinf(high) and needed == 3688 and 99 <= value <= 100.1 and low <= 100


@given(log_n=st.floats(0.0, 9.5), log_p=st.floats(-7.0, -0.5), upper=st.booleans())
@settings(max_examples=200, deadline=None)
def test_binomial_points_are_scipys_in_the_exact_regime(log_n, log_p, upper):
    from scipy import stats as sps

    n, p, alpha = int(10**log_n), 10**log_p, 0.975 if upper else 0.025
    assume(n * p * (1 - p) <= 1e4)  # (above: the normal approximation, tested above)
    assert binomial_point(n, p, alpha) == sps.binom.ppf(alpha, n, p)


@pytest.mark.parametrize(
    "override, key",
    [
        ("hazard.speed={a=-1.0}", "hazard.speed.a"),
        ("hazard.energy_density=[1, 2]", "hazard.energy_density"),
        ("hazard.fractions=[0.7]", "hazard.fractions"),
        ("hazard.map_cell=1.0", "hazard.map_extent"),
        ("hazard.map_extent=[1, 0, 0, 1]", "hazard.map_extent"),
        ("hazard.colour=1", "hazard.colour"),
        ("output.tail_distances=[5.0, 1.0]", "output.tail_distances"),
        # contradictions (issue 24, item 7): an axis along the map surface's normal (all landings would fall
        # outside a grid on another axis); no histograms for a [hazard] table's answers
        ("hazard={map_cell = 1.0, map_extent = [0, 10, -5, 5], map_axis = [0, -3, 0]}", "hazard.map_axis"),
        ("hazard={map_cell = 1.0, map_extent = [0, 10, -5, 5], map_axis = [1e-12, 1, 0]}", "hazard.map_axis"),
        ("hazard={}", "output.quantiles"),  # (with --set output.quantiles=false below)
    ],
)
def test_bad_hazard_keys_are_refused_in_one_line_before_any_work(tmp_path, override, key):
    out = tmp_path / "x.h5"
    extra = ["--set", "output.quantiles=false"] if key == "output.quantiles" else []
    rc, stdout, stderr = cli(["run", "examples/paper.toml", "--set", override, *extra, "-o", out, "--device", "cpu"])
    assert rc == 2 and stderr.count("\n") == 1 and key in stderr and not out.exists(), stderr


def test_a_map_axis_defaulting_to_a_shot_along_the_normal_is_required():
    """shot.direction straight down onto the ground: the map's default u axis has no direction in
    the plane, so map_axis is required (it was replaced by an arbitrary axis); given, it is taken."""
    raw = paper_raw()
    raw["shot"].update(direction=[0.0, -1.0, 0.0], direction_jitter=[0.0, 0.0, 0.0])
    hazard = {"map_cell": 1.0, "map_extent": [0.0, 10.0, -5.0, 5.0]}
    with pytest.raises(wr.SceneError, match=r"^hazard.map_axis = \(missing\): is required: its default, shot.direction"):
        make_scene(raw, hazard=hazard)
    assert make_scene(raw, hazard={**hazard, "map_axis": [0.0, 0.0, 1.0]}).hazard.map_axis == (0.0, 0.0, 1.0)


@pytest.mark.parametrize(
    "hazard",
    [None, {"fractions": [0.01]}, {"energy_density": {"corneal_abrasion": 1503.0}}],
    ids=["no table", "defaults", "one threshold"],
)
def test_setting_one_threshold_adds_it_to_the_scenes_in_run_and_sweep(tmp_path, hazard):
    """One rule for `run --set` and `sweep --param` (issue 24, item 7): a dotted key inside
    hazard.energy_density or hazard.speed sets that threshold among the scene's own, the defaults
    when the scene gives none; a whole table replaces them. (`run --set` replaced the defaults
    and `sweep --param` kept them.)"""
    from warp_ricochet.api import _point_scenes
    from warp_ricochet.scene import SweepPoints, load_scene
    from warp_ricochet.scene.schema import HAZARD_ENERGY_DENSITY
    from warp_ricochet.scene.toml_out import toml_lines

    raw = paper_raw()
    if hazard is not None:
        raw["hazard"] = hazard
    path = tmp_path / "s.toml"
    path.write_text("\n".join(toml_lines(raw, "")) + "\n")
    own = dict(hazard["energy_density"]) if hazard and "energy_density" in hazard else dict(HAZARD_ENERGY_DENSITY)
    ran = load_scene(path, ["hazard.energy_density.eye=20000.0"]).hazard.energy_density
    swept = _point_scenes(load_scene(path), SweepPoints({"hazard.energy_density.eye": [20000.0]}), False)[0]
    assert ran == swept.hazard.energy_density == tuple({**own, "eye": 20000.0}.items())
    replaced = load_scene(path, ["hazard.energy_density={eye = 20000.0}"]).hazard.energy_density
    assert replaced == (("eye", 20000.0),)


def test_a_sweep_refuses_a_key_set_twice(tmp_path):
    """--param over a --set key, or --tie onto a swept or tied key: the later would silently win."""
    out = tmp_path / "x.h5"
    for argv, key in (
        (["--set", "surfaces.0.mu_s=0.6", "--param", "surfaces.0.mu_s=0.5,0.6"], "surfaces.0.mu_s"),
        (["--param", "surfaces.0.mu_s=0.1,0.2", "--tie", "surfaces.0.mu_s=0.9*"], "--tie"),
        (["--param", "surfaces.0.mu_s=0.1,0.2", "--tie", "surfaces.0.mu_d=0.9*", "--tie", "surfaces.0.mu_d=0.8*"], "--tie"),
    ):
        rc, stdout, stderr = cli(["sweep", "examples/paper.toml", *argv, "-o", out, "--device", "cpu"])
        assert rc == 2 and stderr.count("\n") == 1 and f": error: {key} = " in stderr and not out.exists(), stderr


def test_the_summary_and_report_show_quantiles_tails_and_danger_distances(tmp_path):
    out = tmp_path / "run.h5"
    rc, stdout, stderr = cli(
        [
            "run",
            "examples/paper.toml",
            "--set",
            "shot.count=2000",
            "--set",
            "hazard.fractions=[0.01]",
            "-o",
            out,
            "--device",
            "cpu",
        ]
    )
    assert rc == 0, stderr
    rc, report, stderr = cli(["report", out])
    assert rc == 0, stderr
    for text in (stdout, report):
        assert "quantiles P50 / P75 / P90 / P99 / P99.9 / 1-1e-6" in text and "  range " in text
        assert "landed beyond" in text and "corneal_abrasion (1503 J/m^2, 2,000 landings): p=0.01:" in text
        assert "(1,000,000 for 1-1e-6), this run has 2,000" in text
    tail = [line for line in stdout.splitlines() if line.startswith("  distance")]
    assert tail and tail == [line for line in report.splitlines() if line.startswith("  distance")]


def test_plots_write_pngs_of_the_map_and_the_survival_curve(run_file, tmp_path):
    pytest.importorskip("matplotlib")
    from warp_ricochet.report.hazard_plots import plot_map, plot_survival, read_plot_data

    _scene, path, _stats = run_file
    with h5py.File(path, "r") as f:
        data = read_plot_data(f)
        plot_map(f, tmp_path / "map.png")
    plot_survival(data, tmp_path / "survival.png")  # from arrays as well
    for name in ("map.png", "survival.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_landing_far_past_a_fine_map_counts_outside(tmp_path):
    """Cells of 50 nm and landings 170 m out: the cell index is past int32, so the bounds are
    checked before the cast; every landing is counted outside (this wrote outside the map before)."""
    raw = paper_raw()
    raw["shot"].update(count=64, direction_jitter=[0.0, 0.0, 0.0], envelope_radius=1e-9)
    hazard = {**HAZARD, "map_cell": 5e-8, "map_extent": [0.0, 5e-5, -2.5e-5, 2.5e-5]}
    stats = wr.run(make_scene(raw, "float64", hazard=hazard, output={"fields": []}), tmp_path / "fine.h5", device="cpu")
    with h5py.File(tmp_path / "fine.h5", "r") as f:
        assert f["hazard/map/count"][()].sum() == 0 and f["hazard/map/outside"][()] == stats["landed"] == 64


def test_the_tally_estimate_bounds_what_a_run_allocates_and_writes(tmp_path):
    """`tallies.counts.tally_bytes` (checked before any work, `chunks.check_tallies`) against the
    arrays a CPU run makes (the device's counts and totals, the dense totals, `summarize`'s layers)
    and the file it writes; the map's layers are stored compressed (mostly empty cells)."""
    from warp_ricochet.device import resolve_device
    from warp_ricochet.fields import bytes_per_pellet
    from warp_ricochet.tallies.counts import DeviceTally, TallySetup, TallyTotals, tally_bytes
    from warp_ricochet.tallies.quantiles import summarize

    raw = paper_raw()
    raw["shot"]["count"] = 2000
    scene = make_scene(raw, "float64", hazard={**HAZARD, "map_cell": 0.05}, output={"fields": ["landing"]})
    setup, cpu = TallySetup.of(scene, 1.0, 1.0, 1.0), resolve_device("cpu")
    assert setup.cells == 640_000 and setup.levels == 4
    device = DeviceTally(setup, "float64", cpu, True)
    made = sum(a.capacity for a in (*device.counts.values(), device.flat))
    totals = TallyTotals(setup)
    made += totals.flat().nbytes + sum(np.asarray(v).nbytes for v in summarize(totals, 0)["map"].values())
    host, on_device, file = tally_bytes(setup, cpu, False, scene.shot.pellets)
    assert on_device == 0 and made <= host < 2 * made
    out = tmp_path / "run.h5"
    wr.run(scene, out, device="cpu")
    pellets = scene.shot.pellets * bytes_per_pellet(scene.output.fields, "float64", 1)
    file = tally_bytes(setup, cpu, True, scene.shot.pellets)[2]
    # the landing layers (count, energy, above) and the passes' (passes, exposure: any cell a pellet crosses)
    dense = 8 * ((len(setup.names) + 2) + (len(setup.names) + 1)) * setup.cells
    assert out.stat().st_size <= pellets + file < dense  # a bound, not more than dense
    assert out.stat().st_size < dense / 10  # compressed: dense layers take 10 times more
    with h5py.File(out, "r") as f:
        assert f["hazard/map/above"].compression == "gzip"
        assert f["hazard/map/count"][()].sum() + f["hazard/map/outside"][()] + f["hazard/map/elsewhere"][()] == 2000


def test_a_hazard_without_thresholds_writes_its_map_and_no_reach(tmp_path):
    """A [hazard] table with no threshold once failed to write (/pellets/hazard/reach, one column per
    threshold, had none); naming that field then is one line."""
    from warp_ricochet.errors import SceneError
    from warp_ricochet.scene import scene_from_dict

    raw = paper_raw(until="landing")
    raw["shot"]["count"] = 20
    raw["hazard"] = {"map_cell": 0.5, "map_extent": [-5.0, 140.0, -25.0, 25.0], "energy_density": [], "speed": []}
    wr.run(scene_from_dict(raw), tmp_path / "run.h5", device="cpu")
    with h5py.File(tmp_path / "run.h5") as f:
        assert "reach" not in f["pellets/hazard"] and "energy" in f["pellets/hazard"]
        assert f["hazard/map/count"][()].sum() + f["hazard/map/outside"][()] == 20
    raw["output"] = {"fields": ["landing.position", "hazard.reach"]}
    with pytest.raises(SceneError, match="^output.fields .*has a column per hazard threshold") as info:
        scene_from_dict(raw)
    assert "\n" not in str(info.value)
