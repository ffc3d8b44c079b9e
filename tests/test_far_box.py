"""A box far from the origin, float32 (issue 27; docs/geometry.md, "Meshes and boxes", "Far from the
origin"): its triangle tests scale their rounding with the box's own frame and the pellet's stored
centre, not with the world's coordinates, so pellets dropped onto its top edges and corners 1 km
away end as they do at the origin (before: 124 of 3,000 NOT_FINISHED, a pellet 2 mm past an edge
counted as over the top face)."""

import functools
import tempfile
from pathlib import Path

import numpy as np
import pytest
from helpers import explicit_scene
from scipy import stats
from test_box_ridge import BOX, GROUND, SMOOTH, R, _dropped, _rest

from bench.far_solids import run_rests
from bench.meshes import inside_box
from warp_ricochet.ends import AT_REST

N = 3000
EAST, NORTH_EAST = (1.0, 0.0, 0.0), (0.6, 0.0, 0.8)  # unit directions of the box's offset


@functools.cache
def _far_rests(distance, direction, precision, n=N):
    """The box-ridge scene (tests/test_box_ridge.py: n pellets dropped onto the top edges and
    corners of a concrete box) moved `distance` m along `direction` (the ground stays, it is an
    infinite plane through the origin): {state, position less the offset (float64), impacts}
    at rest, and the warnings the run gave."""
    shift = distance * np.asarray(direction)
    x0, v0 = _dropped(n)
    box = {**BOX, "material": "concrete", "point": list(np.add(BOX["point"], shift))}
    folder = Path(tempfile.mkdtemp(prefix="far-box-"))
    physics = {"gravity": [0.0, -9.81, 0.0], "until": "rest"}
    scene = explicit_scene(folder, x0 + shift, v0, surfaces=[box, GROUND], physics=physics, precision=precision)
    return run_rests({**scene.to_dict(), "output": {"fields": ["rest"]}}, folder, shift)


def _on_top_or_ground(where, tol):
    """Whether each centre (the box's frame) lies R above its top over it, or R above the ground beside it."""
    over = (np.abs(where[:, [0, 2]]) <= 0.5 + tol).all(axis=1)
    on_top = over & (np.abs(where[:, 1] - (1.0 + R)) <= tol)
    beside = (np.abs(where[:, [0, 2]]) >= 0.5 + R - tol).any(axis=1)
    return on_top | (beside & (np.abs(where[:, 1] - R) <= tol))


def _agree(one, other):
    """The share of rests on the box's top (Fisher's exact test) and their distances from its
    vertical axis (two-sample KS) of two runs agree (p > 1e-3)."""
    on_top = [end["position"][:, 1] > 0.5 for end in (one, other)]
    assert stats.fisher_exact([[top.sum(), (~top).sum()] for top in on_top]).pvalue > 1e-3, [top.sum() for top in on_top]
    axis = [np.linalg.norm(end["position"][:, [0, 2]], axis=1) for end in (one, other)]
    assert stats.ks_2samp(*axis, method="asymp").pvalue > 1e-3


def test_a_pellet_dropped_beside_the_top_edge_of_a_box_1_km_away_goes_to_its_centres_side(tmp_path):
    """float32, a smooth box 1,000 m east: pellets dropped 1 cm straight down with their centres
    0.3 R to 0.9 R either side of its top edge (beyond the inside test's rounding there, 2 eps of
    the centre's coordinates: 2.4e-4 m = 0.19 R) rest where they fell over the top, or roll off the
    edge onto the ground beside the side (before: centres up to 1.9 mm past the edge counted as over
    the top face)."""
    rng = np.random.default_rng(3)
    n, shift = 40, np.array([1000.0, 0.0, 0.0])
    offset = rng.choice([-1.0, 1.0], n) * rng.uniform(0.3, 0.9, n) * R
    z = rng.uniform(-0.45, 0.45, n)
    x0 = np.c_[0.5 + offset, np.full(n, 1.01 + R), z]
    box = {**BOX, **SMOOTH, "point": list(np.add(BOX["point"], shift))}
    end = _rest(tmp_path, "far-edge", x0 + shift, np.zeros((n, 3)), box, "float32")
    where = end["position"].astype(np.float64) - shift
    assert (end["state"] == AT_REST).all() and end["impacts"].max() <= 6, end["impacts"]
    top = offset < 0
    np.testing.assert_allclose(where[top], np.c_[x0[top, 0], np.full(top.sum(), 1.0 + R), z[top]], atol=1e-4)
    assert (np.abs(where[~top, 1] - R) <= 1e-4).all() and (where[~top, 0] >= 0.5 + R - 1e-4).all(), where[~top]


@pytest.mark.parametrize("direction", [EAST, NORTH_EAST], ids=["east", "north-east"])
def test_a_box_1_km_away_float32_brings_every_pellet_to_rest_on_its_top_or_the_ground(direction):
    """3,000 pellets onto the edges and corners of a box 1,000 m from the origin, float32: every
    one at rest (before: 124 NOT_FINISHED east), on the top (over it within the inside test's
    rounding there, 2 eps of the centre's l1 coordinates: 2.4e-4 m east, 3.3e-4 m north-east) or
    the ground, none inside the box, none after many impacts; no PrecisionWarning
    (float32 resolves the scene: half an ulp of 1 km is 3e-5 m, under R/16)."""
    end = _far_rests(1000.0, direction, "float32")
    where = end["position"]
    assert (end["state"] == AT_REST).all(), np.flatnonzero(end["state"] != AT_REST)
    assert _on_top_or_ground(where, 4e-4).all(), where[~_on_top_or_ground(where, 4e-4)]
    assert not inside_box(where, BOX, -R * 0.9).any()
    assert end["impacts"].max() <= 20
    assert not end["warnings"], end["warnings"]


def test_a_box_1_km_away_rests_as_the_same_box_at_the_origin():
    """float32, 1,000 m east against the same scene at the origin: the share resting on the top
    (Fisher's exact test) and the rest positions' distance from the box's axis (two-sample KS) agree,
    and most pellets rest within 1 mm of where they do at the origin (their paths may part at an
    edge by rounding)."""
    far, near = _far_rests(1000.0, EAST, "float32"), _far_rests(0.0, EAST, "float32")
    _agree(far, near)
    apart = np.linalg.norm(far["position"] - near["position"], axis=1)
    assert np.mean(apart < 1e-3) > 0.8, np.mean(apart < 1e-3)


def test_a_box_1_km_away_float32_rests_agree_with_float64():
    """The same at 1,000 m north-east, float32 against float64 (which ends every pellet at rest):
    the share on the top and the distances from the box's axis agree statistically."""
    single, double = _far_rests(1000.0, NORTH_EAST, "float32"), _far_rests(1000.0, NORTH_EAST, "float64")
    assert (double["state"] == AT_REST).all()
    _agree(single, double)


def test_a_box_10_km_away_float32_is_warned_about():
    """At 10 km float32's half ulp (4.9e-4 m) is 0.39 R: the run says so in its PrecisionWarning
    (and some pellets do end NOT_FINISHED there, decided by rounding)."""
    end = _far_rests(1.0e4, EAST, "float32", 300)
    assert any("float32 resolves" in line and "float64" in line for line in end["warnings"]), end["warnings"]
