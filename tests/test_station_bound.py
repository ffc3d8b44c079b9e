"""Stations with [hazard.bound] (docs/scenes.md, "Stations, arcs of fire and aim error"): the
weighted sequence's every prefix is within one shot of the weights' proportions, a bounded run's
pieces give every station its share at every check, and a bounded station run stops at a check
with per-station results that sum to the combined, resumed bitwise."""

import dataclasses
import random
from fractions import Fraction

import h5py
import numpy as np
import pytest
from helpers import assert_opens_in_xarray, make_scene, stats_equal
from test_stations import STATIONS, resume_matches, run_to_file, station_raw

import warp_ricochet as wr
from warp_ricochet.bound import BoundPlan, station_pieces
from warp_ricochet.errors import SceneError
from warp_ricochet.scene.stations import interleave_counts, interleaved, period, reference_aims, station_shots

WEIGHTS = (1.0, 1.5, 2.5)  # integers 2, 3, 5: the sequence repeats every 10 shots


def bounded_raw(width=60.0, shots=4, max_pellets=20_000, weights=WEIGHTS):
    raw = station_raw(count=50, shots=shots, stations=[{**s, "weight": w} for s, w in zip(STATIONS, weights)])
    raw["physics"]["until"] = "landing"
    raw["hazard"] = {
        "energy_density": {"low": 237_000.0},
        "fractions": [0.01],
        "map_cell": 20.0,
        "map_extent": [0.0, 400.0, -300.0, 300.0],
        "bound": {"threshold": "low", "fraction": 0.01, "width": width, "max_pellets": max_pellets},
    }
    return raw


@pytest.mark.parametrize("seed", range(4))
def test_every_prefix_of_the_weighted_sequence_is_within_one_shot_of_the_weights(seed):
    """Tijdeman's bound, 1 - 1/(2m - 2) for m stations, for every prefix of 600 shots, with integer
    and decimal weights, read as written (exact arithmetic)."""
    rng = random.Random(seed)
    for _ in range(25):
        m = rng.randint(1, 8)
        weights = [rng.choice([rng.randint(1, 9), rng.uniform(0.1, 5.0)]) for _ in range(m)]
        share = [Fraction(repr(w)) / sum(Fraction(repr(v)) for v in weights) for w in weights]
        bound = 1 - Fraction(1, 2 * m - 2) if m > 1 else 0
        c = [0] * m
        for n, k in enumerate(interleaved(weights, 600), start=1):
            c[k] += 1
            assert max(abs(c[i] - n * share[i]) for i in range(m)) <= bound, (weights, n, c)


def test_counts_at_checks_are_the_sequences_and_repeat_each_period():
    weights = [1.0, 1.5, 2.5]
    assert period(weights) == 10 and period([0.25, 0.75]) == 4
    sequence = list(interleaved(weights, 137))
    points = [1, 9, 10, 11, 40, 99, 137]
    assert interleave_counts(weights, points) == [[sequence[:n].count(k) for k in range(3)] for n in points]
    assert interleave_counts(weights, [10, 1000]) == [[2, 3, 5], [200, 300, 500]]


def test_a_bounded_runs_pieces_give_every_station_its_share_at_every_check():
    """Each stretch between two checks is cut into the stations' contiguous pieces in scene order;
    the shots fired by each check are the weighted sequence's counts there (within one shot of
    n p_k), the same from the scene and from the budget's scene a run is planned as."""
    scene = make_scene(bounded_raw(), precision="float64")
    plan = BoundPlan.of(scene)
    pieces = station_pieces(scene)
    assert [(a, b) for a, b, _k in pieces] == list(zip([0] + [b for _a, b, _k in pieces[:-1]], [b for _a, b, _k in pieces]))
    assert pieces[-1][1] == plan.budget
    ends = {b for _a, b, _k in pieces}
    share = np.asarray(WEIGHTS) / sum(WEIGHTS)
    for n in (c // 50 for c in plan.checks()):
        assert n in ends  # (a check ends a piece)
        fired = [len(station_shots(pieces, k, n)) for k in range(3)]
        assert fired == interleave_counts(WEIGHTS, [n])[0] and np.all(np.abs(np.asarray(fired) - n * share) < 1)
    from warp_ricochet.bound import planned

    assert station_pieces(planned(scene)) == pieces and BoundPlan.of(planned(scene)) == plan


@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    """A bounded station run met at its fifth check (8 shots of 50 pellets, of a 400-shot budget)."""
    return run_to_file(tmp_path_factory, bounded_raw(), "bounded")


def test_a_bounded_station_run_stops_with_every_station_by_its_weight(stopped):
    scene, ref, stats = stopped
    b = stats.bound
    assert b.met and b.shots == 8 and b.checks == 5 and stats["pellets"] == 400
    parts = [stats.stations[s.name] for s in scene.stations]
    assert [p["pellets"] for p in parts] == [100, 100, 200]  # 8 shots by 2:3:5: 1.6, 2.4, 4 -> 2, 2, 4
    for key in ("landed", "hits", "escaped"):
        assert sum(p[key] for p in parts) == stats[key]
    np.testing.assert_array_equal(sum(p.tally.flat() for p in parts), stats.tally.flat())
    pieces = station_pieces(scene)
    for k, part in enumerate(parts):  # intervals over each station's own (interleaved) shots
        shots = station_shots(pieces, k, 8)
        np.testing.assert_array_equal(part.ensemble.per_shot["range_mean"], stats.ensemble.per_shot["range_mean"][shots])
    # each shot from its own station: the launch positions the reference's for the pieces
    k, _where, _aim = reference_aims(scene, range(8), pieces)
    assert k.tolist() == [owner for a, b, owner in pieces for _shot in range(a, b)][:8]
    with h5py.File(ref) as f:
        assert f["stations"].attrs["piece_ends"].tolist()[:4] == [50, 100, 200, 250]
        assert f["stations/left/stats/pellets"][()] == 100 and f["hazard/bound/pellets"][()] == 400
        np.testing.assert_array_equal(f["stations/mid"].attrs["pieces"], [[a, b] for a, b, owner in pieces if owner == 1])
    variables = assert_opens_in_xarray(ref)  # (xarray: every group, /hazard/bound too)
    # a station's datasets are named as the run's, each station's dimensions its own (its shots)
    for name in ("hazard/map/energy", "hazard/map/exposure_outside", "hazard/danger_distance/distance", "stats/shots/hits"):
        assert variables[f"stations/right/{name}"].dims == variables[name].dims, name
    assert variables["stations/left/stats/shots/hits"].shape == (2,) and variables["stats/shots/hits"].shape == (8,)


def test_a_bounded_station_run_is_the_same_for_two_chunk_sizes(stopped):
    scene, _ref, stats = stopped
    other = wr.run(scene.replace(numerics=dataclasses.replace(scene.numerics, chunk_size=100)), device="cpu")
    assert stats_equal(dict(stats), dict(other)) and other.bound == stats.bound
    for name, part in stats.stations.items():
        assert stats_equal(dict(part), dict(other.stations[name]))


@pytest.mark.parametrize("chunks", [2, 6])  # stopped inside the first check's stretch, then past two checks
def test_a_resumed_bounded_station_run_is_bitwise_the_uninterrupted_one(tmp_path, stopped, chunks):
    scene, ref, _stats = stopped
    station_keys = ("stats/landed", "stats/range_mean", "stats/histograms/counts", "hazard/map/energy")
    keys = ("stats/range_mean", "stats/histograms/counts", "hazard/bound/pellets", "hazard/bound/ci_high")
    resume_matches(tmp_path, scene, ref, chunks, station_keys, keys)


def test_weights_that_repeat_too_late_for_the_budget_are_refused_in_one_line():
    from warp_ricochet.scene import scene_from_dict

    with pytest.raises(SceneError) as info:
        scene_from_dict(bounded_raw(weights=(1.0, 1.234567, 1.0), max_pellets=2**30))
    text = str(info.value)
    assert len(text.splitlines()) == 1 and text.startswith("hazard.bound.max_pellets = 1073741824: gives 21,474,836 shots")
    assert scene_from_dict(bounded_raw(weights=(1.0, 1.234567, 1.0))).stations[1].weight == 1.234567  # (400 shots)
    assert period([0.7, 0.3]) == 10 and scene_from_dict(bounded_raw(weights=(0.7, 0.3), max_pellets=2**30))
