"""Stations with pellet-pellet collisions (docs/scenes.md, "Stations, arcs of fire and aim error"):
the dense phase's shots start at their stations (launch separation redraws around the shot's own
station; a single station with zero-width arcs is bitwise the plain shot placed there), the
per-station results sum to the combined, are the same for two chunk sizes and after --resume, and
two stations' pellets never meet (each shot is its own dense phase). Small: shots of 40 pellets."""

import copy
import dataclasses

import h5py
import numpy as np
import pytest
from helpers import make_scene, stats_equal
from test_stations import resume_matches, run_to_file, station_raw

import warp_ricochet as wr
from warp_ricochet.scene.stations import reference_aims, shot_pieces
from warp_ricochet.tallies.by_station import segments_of, stretch_segments

FIELDS = ["initial.position", "initial.velocity", "collisions.count", "landing.range"]
RADIUS = 0.0075  # m: 40 pellets of 2.4 mm fill 0.16 of it, so launches are redrawn
POSTS = [
    {"name": "west", "position": [-20.0, -8.0, 1.5], "azimuth": [-20.0, 20.0], "elevation": [4.0, 12.0]},
    {"name": "centre", "position": [0.0, 0.0, 1.5], "azimuth": 5.0, "elevation": 6.0},
    {"name": "east", "position": [20.0, 8.0, 1.5], "azimuth": [-10.0, 40.0], "elevation": 8.0, "weight": 2.0},
]


def collision_raw(stations=POSTS, shots=8, fields=FIELDS, **shot):
    raw = station_raw(count=40, shots=shots, stations=stations, envelope_radius=RADIUS, **shot)
    raw["collisions"] = {"enabled": True}
    raw["output"] = {"fields": list(fields)}
    return raw


def pellets(path, name):
    with h5py.File(path) as f:
        return f[f"pellets/{name}"][()]


def test_launches_are_separated_around_each_shots_station(tmp_path):
    """Each pellet starts within shot.envelope_radius of its shot's station, redrawn ones too (a
    redraw around shot.envelope_center put them at the origin, metres away)."""
    scene = make_scene(collision_raw(), precision="float64")
    wr.run(scene, tmp_path / "a.h5", device="cpu")
    apart = scene.replace(collisions=dataclasses.replace(scene.collisions, separate=False))
    wr.run(apart, tmp_path / "b.h5", device="cpu")
    position = pellets(tmp_path / "a.h5", "initial/position")
    _k, where, _aim = reference_aims(scene, range(scene.shot.shots))
    offset = np.linalg.norm(position - where[np.arange(len(position)) // scene.shot.count], axis=1)
    redrawn = np.any(position != pellets(tmp_path / "b.h5", "initial/position"), axis=1)
    assert redrawn.sum() >= 10  # (the test means something: many launches were redrawn)
    assert offset.max() <= RADIUS * (1 + 1e-12), offset.max()
    assert pellets(tmp_path / "a.h5", "collisions/count").sum() > 0


@pytest.mark.filterwarnings("ignore::warp_ricochet.errors.PrecisionWarning")  # (float32's, the same in both)
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_fixed_station_is_bitwise_the_plain_shot_placed_there(tmp_path, precision):
    """One station, zero-width arcs: its shots are the plain scene's whose envelope_center is the
    station and whose direction is the station's aim (the same launch inputs: the aim, computed in
    float64 and cast, equals the reference's cast; the same pellet keys), bit for bit through the
    dense phase and the core kernel, and its station results are the combined."""
    post = {"name": "post", "position": [3.0, -7.0, 1.5], "azimuth": 0.0, "elevation": 8.0}
    raw = collision_raw(stations=[post], shots=4, direction_jitter=[0.02, 0.02, 0.02])
    scene = make_scene(raw, precision=precision)
    _k, _where, aim = reference_aims(scene, [0])
    plain = copy.deepcopy(raw)
    plain.pop("stations")
    plain["shot"].update(envelope_center=post["position"], direction=aim[0].tolist())
    a = wr.run(scene, tmp_path / "s.h5", device="cpu")
    b = wr.run(make_scene(plain, precision=precision), tmp_path / "p.h5", device="cpu")
    for name in ("initial/position", "initial/velocity", "collisions/count", "landing/range"):
        np.testing.assert_array_equal(pellets(tmp_path / "s.h5", name), pellets(tmp_path / "p.h5", name), err_msg=name)
    assert stats_equal(dict(a), dict(b)) and a["pair_collisions"] > 0
    assert stats_equal(dict(a.stations["post"]), dict(a))


@pytest.fixture(scope="module")
def posts(tmp_path_factory):
    """Three stations (2, 2 and 4 shots), collisions on, and the run file of one uninterrupted run."""
    return run_to_file(tmp_path_factory, collision_raw(), "posts")


def test_per_station_collision_results_sum_to_the_combined_for_two_chunk_sizes(posts):
    """(A collision chunk is at least `shot_granule` shots, 1,024 of 40 pellets: both chunk sizes
    here end their chunks at the stations' ends, which the loop does for any size.)"""
    scene, _ref, one = posts
    small = scene.replace(numerics=dataclasses.replace(scene.numerics, chunk_size=40))
    two = wr.run(small, device="cpu")
    assert stats_equal(dict(one), dict(two))
    parts = [one.stations[s.name] for s in scene.stations]
    for part, other in zip(parts, (two.stations[s.name] for s in scene.stations)):
        assert stats_equal(dict(part), dict(other))
        np.testing.assert_array_equal(part.tally.flat(), other.tally.flat())
    assert [p["pellets"] for p in parts] == [80, 80, 160]
    for key in ("landed", "hits", "pair_collisions", "pair_energy_lost"):
        assert sum(p[key] for p in parts) == pytest.approx(one[key], rel=1e-12), key
    assert sum(p["collided_fraction"] * p["pellets"] for p in parts) == pytest.approx(one["collided_fraction"] * 320)
    assert max(p["dense_steps_max"] for p in parts) == one["dense_steps_max"]
    np.testing.assert_array_equal(sum(p.tally.flat() for p in parts), one.tally.flat())
    for part, (first, end, _k) in zip(parts, shot_pieces(scene)):  # intervals over each station's own shots
        np.testing.assert_array_equal(part.ensemble.per_shot["range_mean"], one.ensemble.per_shot["range_mean"][first:end])


@pytest.mark.parametrize("chunks", [1, 2])  # stopped at west's end, then at centre's
def test_a_resumed_station_collision_run_is_bitwise_the_uninterrupted_one(tmp_path, posts, chunks):
    scene, ref, _stats = posts
    station_keys = ("stats/landed", "stats/pair_collisions", "stats/collided_fraction", "stats/histograms/counts")
    keys = ("stats/pair_collisions", "stats/range_mean", "pellets/collisions/count", "pellets/initial/position")
    resume_matches(tmp_path, scene, ref, chunks, station_keys, keys)


def test_a_station_stretch_counts_segments_of_slots_with_collisions():
    """A resumed station run splits its partials by stretch: with collisions a stretch's segments
    are of its shots' slots (40 pellets a shot in 64 slots), not of its pellets."""
    assert stretch_segments(1200 * 40, 40, False) == 1  # 48,000 pellets: one segment of 65,536
    assert stretch_segments(1200 * 40, 40, True) == 2  # 76,800 slots
    assert segments_of([1200 * 40, 2400 * 40], 2400 * 40, 40, True) == 4
    assert segments_of([1200 * 40, 2400 * 40], 2400 * 40) == 2


def test_stations_far_apart_never_collide_with_each_other(tmp_path):
    """Two stations 30 m apart shooting at each other along one line: shot 0 (from west) and shot 1
    (from east) are bitwise what each station fires alone (a shot is its own dense phase, so
    pellets of different shots, and so of different stations, never meet)."""
    west = {"name": "west", "position": [0.0, 0.0, 1.5], "azimuth": 0.0, "elevation": 0.5}
    east = {"name": "east", "position": [30.0, 0.0, 1.5], "azimuth": 180.0, "elevation": 0.5}
    fields = ["collisions.count", "landing.range", "landing.position"]
    runs = {}
    for name, stations in (("both", [west, east]), ("west", [west]), ("east", [east])):
        wr.run(
            make_scene(collision_raw(stations=stations, shots=2, fields=fields), precision="float64"),
            tmp_path / f"{name}.h5",
            device="cpu",
        )
        runs[name] = {f: pellets(tmp_path / f"{name}.h5", f.replace(".", "/")) for f in fields}
    for f in fields:
        np.testing.assert_array_equal(runs["both"][f][:40], runs["west"][f][:40], err_msg=f)
        np.testing.assert_array_equal(runs["both"][f][40:], runs["east"][f][40:], err_msg=f)
    assert runs["both"]["collisions.count"].sum() > 0
    landing = runs["both"]["landing.position"]
    assert landing[:40, 0].min() > 30.0 and landing[40:, 0].max() < 0.0  # each flew through the other's station
