"""Stations, arcs of fire and aim error (docs/scenes.md): the shot's station and aim against the
NumPy reference, uniform arcs, per-station tallies summing to the combined, chunk-size invariance
and resume, the bad-input lines, and the example fields."""

import dataclasses
import math
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import cli, interrupt_after, make_scene, stats_equal

import warp_ricochet as wr
from warp_ricochet.scene.stations import allocate, reference_aims, shot_pieces

ROOT = Path(__file__).resolve().parents[1]
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.3, "mu_s": 0.4}
STATIONS = [
    {"name": "left", "position": [0.0, -5.0, 1.5], "azimuth": [-30.0, 30.0], "elevation": [2.0, 15.0]},
    {"name": "mid", "position": [0.0, 0.0, 1.5], "azimuth": 10.0, "elevation": [2.0, 15.0], "aim": "normal", "aim_sigma": 4.0},
    {"name": "right", "position": [0.0, 5.0, 1.5], "azimuth": [-90.0, 90.0], "elevation": 5.0, "weight": 2.0},
]


def station_raw(count=4, shots=40, stations=STATIONS, **shot):
    return {
        "shot": {
            "count": count,
            "shots": shots,
            "diameter": 0.0024,
            "density": 11340.0,
            "speed": 400.0,
            "direction": [1.0, 0.0, 0.0],
            "seed": 7,
            **shot,
        },
        "surfaces": [dict(GROUND)],
        "physics": {"gravity": [0.0, 0.0, -9.81], "bounces": 1},
        "stations": [dict(s) for s in stations],
    }


def test_allocation_is_proportional_contiguous_and_exact():
    assert allocate([1, 1, 2], 40) == [10, 10, 20]
    assert allocate([1, 1, 1], 10) == [4, 3, 3]  # the remainder's tie to the earlier station
    scene = make_scene(station_raw(), precision="float64")
    assert shot_pieces(scene) == [(0, 10, 0), (10, 20, 1), (20, 40, 2)]


def test_uniform_arcs_stay_in_their_range_and_are_uniform():
    raw = station_raw(shots=20000, stations=[STATIONS[0]])
    scene = make_scene(raw, precision="float64")
    _k, _p, aim = reference_aims(scene, range(scene.shot.shots))
    azimuth = np.degrees(np.arctan2(aim[:, 1], aim[:, 0]))  # x downrange, y to the left: clockwise is -y
    azimuth = -azimuth
    elevation = np.degrees(np.arcsin(aim[:, 2]))
    assert azimuth.min() >= -30.0 - 1e-9 and azimuth.max() <= 30.0 + 1e-9
    assert elevation.min() >= 2.0 - 1e-9 and elevation.max() <= 15.0 + 1e-9
    for values, lo, hi in ((azimuth, -30.0, 30.0), (elevation, 2.0, 15.0)):  # chi-square, 20 bins, 19 dof
        counts = np.histogram(values, bins=20, range=(lo, hi))[0]
        expected = len(values) / 20
        assert ((counts - expected) ** 2 / expected).sum() < 43.8  # the 0.999 quantile of chi2(19)


def test_with_a_site_azimuths_are_from_north_as_the_sites():
    """[hazard.site] azimuth 37: the downrange axis is at 37 degrees from north, so a station's
    azimuth 37 aims down it, 127 a quarter turn clockwise (to the right: -y)."""
    pytest.importorskip("pyproj")
    ahead = {"name": "ahead", "position": [0.0, 0.0, 1.5], "azimuth": 37.0}
    right = {"name": "right", "position": [0.0, 0.0, 1.5], "azimuth": 127.0}
    raw = station_raw(shots=2, stations=[ahead, right])
    raw["hazard"] = {
        "map_cell": 10.0,
        "map_extent": [0.0, 100.0, -50.0, 50.0],
        "site": {"crs": "EPSG:32630", "shooter": [500000.0, 4200000.0], "azimuth": 37.0},
    }
    _k, _p, aim = reference_aims(make_scene(raw, precision="float64"), range(2))
    np.testing.assert_allclose(aim, [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0]], atol=1e-15)


def test_a_normal_aim_is_truncated_to_its_arc():
    raw = station_raw(shots=4000, stations=[{**STATIONS[0], "aim": "normal", "aim_sigma": 10.0}])
    _k, _p, aim = reference_aims(make_scene(raw, precision="float64"), range(4000))
    azimuth = -np.degrees(np.arctan2(aim[:, 1], aim[:, 0]))
    assert azimuth.min() >= -30.0 and azimuth.max() <= 30.0
    assert abs(azimuth.std() - 10.0) < 1.5  # (truncated at 3 sigma: 9.73)


@pytest.fixture(scope="module")
def big_scene():
    """200,000 pellets in three stations (50k, 50k, 100k), statistics and a hazard map."""
    raw = station_raw(count=1000, shots=200)
    raw["hazard"] = {"map_cell": 20.0, "map_extent": [0.0, 400.0, -300.0, 300.0]}
    return make_scene(raw)


def test_per_station_results_sum_to_the_combined_for_any_chunk_size(big_scene):
    one = wr.run(big_scene, device="cpu")
    small = big_scene.replace(numerics=dataclasses.replace(big_scene.numerics, chunk_size=65_536))
    two = wr.run(small, device="cpu")
    assert stats_equal(dict(one), dict(two))
    assert list(one.stations) == ["left", "mid", "right"]
    for name in one.stations:
        assert stats_equal(dict(one.stations[name]), dict(two.stations[name]))
        np.testing.assert_array_equal(one.stations[name].tally.flat(), two.stations[name].tally.flat())
    parts = list(one.stations.values())
    assert [p["pellets"] for p in parts] == [50_000, 50_000, 100_000]
    for key in ("landed", "hits", "escaped"):
        assert sum(p[key] for p in parts) == one[key]
    np.testing.assert_array_equal(sum(p.tally.flat() for p in parts), one.tally.flat())
    assert all(p.tally.map_counts.sum() > 0 for p in parts)
    assert max(p["range_max"] for p in parts) == one["range_max"]
    for part, (first, end, _k) in zip(parts, shot_pieces(big_scene)):  # intervals over each station's shots
        assert part.ensemble.shots == end - first
        np.testing.assert_array_equal(part.ensemble.per_shot["range_mean"], one.ensemble.per_shot["range_mean"][first:end])


@pytest.fixture(scope="module")
def chunked(big_scene, tmp_path_factory):
    """The big scene in chunks of 65,536 pellets (left, mid, then right in two), and its run file."""
    scene = big_scene.replace(numerics=dataclasses.replace(big_scene.numerics, chunk_size=65_536))
    ref = tmp_path_factory.mktemp("stations") / "ref.h5"
    wr.run(scene, ref, device="cpu")
    return scene, ref


def run_to_file(tmp_path_factory, raw, name):
    """(the float64 scene of `raw`, its run file, its statistics) of one uninterrupted run."""
    scene = make_scene(raw, precision="float64")
    ref = tmp_path_factory.mktemp(name) / "ref.h5"
    return scene, ref, wr.run(scene, ref, device="cpu")


def resume_matches(tmp_path, scene, ref, chunks, station_keys, keys):
    """Interrupt `scene`'s run after `chunks` chunks, resume it, and compare each station's
    `station_keys` and the run's `keys` bitwise with `ref` (an uninterrupted run's file); returns the
    resumed file."""
    out = tmp_path / "out.h5"
    interrupt_after(chunks, scene, out)
    wr.run(scene, out, device="cpu", resume=True)
    with h5py.File(out) as a, h5py.File(ref) as b:
        for key in [f"stations/{s.name}/{k}" for s in scene.stations for k in station_keys] + list(keys):
            np.testing.assert_array_equal(a[key][()], b[key][()], err_msg=key)
    return out


@pytest.mark.parametrize("chunks", [2, 3])  # stopped at mid's end, then inside right
def test_a_resumed_station_run_is_bitwise_the_uninterrupted_one(tmp_path, chunked, chunks):
    scene, ref = chunked
    station_keys = ("stats/landed", "stats/range_mean", "stats/histograms/counts", "hazard/map/energy")
    out = resume_matches(tmp_path, scene, ref, chunks, station_keys, ("stats/histograms/counts", "stats/range_mean"))
    with h5py.File(out) as a:
        assert a["stations"].attrs["order"].tolist() == ["left", "mid", "right"]
        assert a["stations/right"].attrs["shots"] == 100
        np.testing.assert_array_equal(a["stations/right/stats/shots/landed"][()], a["stats/shots/landed"][100:])


def test_launch_states_are_the_reference_aims_and_the_cli_lists_each_station(tmp_path):
    """Kernel against `reference_aims` (no jitter, no envelope): each pellet starts at its shot's
    station and flies along its shot's aim; `run`'s summary and `report` list each station and the
    combined."""
    raw = station_raw()
    raw["output"] = {"fields": ["initial.position", "initial.velocity"]}
    scene = make_scene(raw)
    scene_path, out = tmp_path / "s.toml", tmp_path / "s.h5"
    scene_path.write_text(scene.to_toml())
    rc, summary, _err = cli(["run", str(scene_path), "-o", str(out), "--device", "cpu"])
    assert rc == 0
    with h5py.File(out) as f:
        position, velocity = f["pellets/initial/position"][()], f["pellets/initial/velocity"][()]
    shots = np.arange(len(position)) // scene.shot.count
    k, where, aim = reference_aims(scene, range(scene.shot.shots))
    np.testing.assert_array_equal(position, where[shots].astype(np.float32))
    np.testing.assert_allclose(velocity / scene.shot.speed, aim[shots], rtol=0, atol=2e-6)  # (float32)
    assert k.tolist() == [0] * 10 + [1] * 10 + [2] * 20
    rc, report, _err = cli(["report", str(out)])
    for text in (summary, report):
        block = text[text.index("Stations") :].splitlines()
        assert [line.split()[0] for line in block[3:7]] == ["left", "mid", "right", "combined"]
        assert "distance P99 (m)" in block[1]


@pytest.mark.parametrize(
    "edit, start",
    [
        (lambda r: r["stations"][0].update(azimuth=[-200.0, 200.0]), "stations.0.azimuth = [-200.0, 200.0]: is an arc 400"),
        (lambda r: r["stations"][1].update(position=[0.0, 0.0, -0.5]), "stations.1.position = [0.0, 0.0, -0.5]: is 0.5 m below"),
        (lambda r: r["stations"][2].update(name="left"), "stations.2.name = 'left': is the name of stations.0"),
        (lambda r: r["shot"].update(file="pellets.npz"), "shot.file = "),
        (lambda r: r["stations"][0].update(aim="gaussian"), "stations.0.aim = 'gaussian': must be one of"),
        (lambda r: r["stations"][1].pop("aim_sigma"), "stations.1.aim_sigma = (missing)"),
        (lambda r: r["stations"][2].update(weight=0), "stations.2.weight = 0: must be a number > 0"),
        (lambda r: r["shot"].update(shots=2), "shot.shots = 2: gives stations.1"),
        (lambda r: r["stations"][0].update(weight=1e308), "stations.0.weight = 1e+308: must be a number > 0 and at most 1e+06"),
        (  # (once "raise shot.shots to 3 or more": it had 40)
            lambda r: r["stations"][0].update(weight=1e-3),
            "shot.shots = 40: gives stations.0 ('left') no shot by the weights; at least one per station "
            "(3,001 shots give every station one; or raise that station's weight)",
        ),
        (lambda r: r["shot"].update(envelope_center=[0, 0, 1]), "shot.envelope_center = [0, 0, 1]: not allowed"),
    ],
)
def test_bad_station_input_is_one_line_before_any_work(tmp_path, edit, start):
    from warp_ricochet.errors import SceneError
    from warp_ricochet.scene import scene_from_dict

    raw = station_raw()
    edit(raw)
    if "file" in raw["shot"]:
        np.savez(tmp_path / "pellets.npz", position=np.zeros((4, 3)), velocity=np.ones((4, 3)))
        for key in ("speed", "direction", "seed", "count"):
            raw["shot"].pop(key)
        raw["shot"]["shots"] = 1
    with pytest.raises(SceneError) as info:
        scene_from_dict(raw, tmp_path)
    text = str(info.value)
    assert len(text.splitlines()) == 1 and text.startswith(start), text


def test_a_bad_station_is_refused_by_the_cli_in_one_line_and_writes_nothing(tmp_path):
    scene_path = tmp_path / "s.toml"
    scene_path.write_text(make_scene(station_raw()).to_toml().replace("azimuth = [-30.0, 30.0]", "azimuth = [0.0, 361.0]"))
    rc, stdout, err = cli(["run", str(scene_path), "-o", str(tmp_path / "s.h5"), "--device", "cpu"])
    assert rc == 2 and stdout == "" and len(err.splitlines()) == 1
    assert err.startswith("warp-ricochet: error: stations.0.azimuth = [0.0, 361.0]: is an arc 361 degrees wide"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


@pytest.mark.parametrize("name", ["trap_field", "skeet_field", "sporting_layout"])
def test_example_fields_run_with_few_shots(tmp_path, name):
    path = ROOT / "examples" / f"{name}.toml"
    scene = wr.load_scene(path, ["shot.count=20", f"shot.shots={8 if name != 'sporting_layout' else 12}"])
    stats = wr.run(scene, device="cpu")
    assert stats["pellets"] == scene.shot.pellets and len(stats.stations) == len(scene.stations)
    assert math.isfinite(stats["range_mean"]) and stats["landed"] > 0


def test_a_station_under_a_terrain_ground_is_refused():
    """The first surface a terrain (the trap field's raster, ground falling 2% east from 120 m): a
    station 1.7 m above it loads, one 0.8 m under it is refused in one line."""
    from warp_ricochet.errors import SceneError
    from warp_ricochet.scene import scene_from_dict

    raw = station_raw(stations=[dict(STATIONS[0], position=[10.0, -50.0, 1.5])])
    raw["physics"]["until"] = "landing"
    raw["surfaces"] = [
        {
            "kind": "terrain",
            "file": str(ROOT / "warp_ricochet/examples/terrain/trap_field.asc"),
            "elevation": 120.0,
            "restitution": 0.3,
            "mu_s": 0.4,
        }
    ]
    assert scene_from_dict(raw).stations[0].position[2] == 1.5
    raw["stations"][0]["position"] = [10.0, -50.0, -1.0]
    with pytest.raises(
        SceneError, match=r"^stations\.0\.position = \[10\.0, -50\.0, -1\.0\]: is 0\.8 m below the ground \(surfaces\.0"
    ):
        scene_from_dict(raw)


def test_the_station_table_prints_lengths_in_the_chosen_units():
    from warp_ricochet import display
    from warp_ricochet.report.stations import station_block

    rows = [("post 1", {"pellets": 10, "range_mean": 9.144, "range_max": 0.9144, "distance_p99": 91.44, "landing_mean_WT": 0.5})]
    metric = station_block(rows)
    with display.using("imperial"):
        imperial = station_block(rows)
    assert "L+ (m)" in metric and "9.144" in metric and "0.5" in metric
    assert "L+ (yd)" in imperial and "10.000" in imperial and "1.000" in imperial and "100.0" in imperial
    assert "(J)" in imperial and "0.500000" in imperial  # energies stay in joules


def test_the_html_report_lists_the_stations(tmp_path):
    """The report says the shots leave from the stations (not from shot.direction) and lists them."""
    from warp_ricochet.report.html import write_html

    scene = wr.load_scene(ROOT / "examples" / "trap_field.toml", ["shot.count=20", "shot.shots=5", "output.fields=[]"])
    wr.run(scene, tmp_path / "t.h5", device="cpu")
    write_html(tmp_path / "t.h5", tmp_path / "t.html")
    text = (tmp_path / "t.html").read_text()
    assert "from 5 stations (below), each shot aimed within its station" in text
    assert text.count("-30 to 30 (60 wide)") == 5 and text.count("3 to 15 (12 wide)") == 5
    assert "0 degrees above level" not in text
