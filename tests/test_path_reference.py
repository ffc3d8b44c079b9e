"""The float64 path-hazard reference (reference/path_hazard.py) on closed forms: reach distances of a
parabola in vacuum (body height and speed crossings) and of a slide on a level plane, map passes of
a flight across a grid, near-misses and grazes within the tolerance, and point levels."""

import math

import numpy as np
import pytest

from warp_ricochet.reference import path_hazard as ph
from warp_ricochet.reference import surface_motion as sm

G = 9.81
H = 1.8
R = 0.00125
LEVEL = dict(shooter=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0), body_height=H)


def _times(h0, vy, height):
    """The times a vertical motion h0 + vy t - g t^2 / 2 is at `height` (up, down)."""
    root = math.sqrt(vy * vy - 2 * G * (height - h0))
    return (vy - root) / G, (vy + root) / G


def test_a_parabola_reaches_to_its_body_height_and_speed_crossings():
    """Shot up from 1 m at (40, 12) m/s, ended at 1.5 s, before it comes back below 1.8 m: each
    threshold's reach is where it first rises through body height or, earlier, slows to the
    threshold: v(t)^2 = vx^2 + (vy - g t)^2, h(t) = 1 + vy t - g t^2 / 2."""
    vx, vy, h0, end = 40.0, 12.0, 1.0, 1.5
    speeds = (30.0, 41.0, 41.7, 42.0)  # the launch speed is 41.76 m/s, the apex's 40
    path = ph.parabola((0.0, h0, 0.0), (vx, vy, 0.0), end)
    got = ph.reach(path, ph.Hazard(**LEVEL, speeds=speeds))
    up, down = _times(h0, vy, H)
    assert down > end  # it never comes back within body height
    want = [vx * min(up, (vy - math.sqrt(v * v - vx * vx)) / G) if v * v > vx * vx else vx * up for v in speeds[:3]]
    assert (vy - math.sqrt(41.0**2 - vx * vx)) / G > up and (vy - math.sqrt(41.7**2 - vx * vx)) / G < up  # both kinds
    np.testing.assert_allclose(got[:3], want, rtol=1e-12)
    assert math.isnan(got[3])  # above the launch speed: never


def test_a_descent_reaches_the_end_from_its_crossings():
    """Shot down from 3 m, level: within body height from t_H = sqrt(2 (3 - H) / g), at or above v
    from sqrt(v^2 - vx^2) / g; it ends at 0.7 s (in the air): the reach is the end's distance where
    both hold there, NaN for a threshold it reaches only after the end; the shooter off the line of
    fire measures horizontally: sqrt(x^2 + z^2)."""
    vx, end = (30.0, 0.0, 10.0), 0.7
    speeds = (20.0, 32.0, 33.0)
    path = ph.parabola((0.0, 3.0, 0.0), vx, end)
    hazard = ph.Hazard(**{**LEVEL, "shooter": (0.0, 1.0, -2.0)}, speeds=speeds)
    got = ph.reach(path, hazard)
    final = math.hypot(vx[0] * end, vx[2] * end + 2.0)
    speed_end = math.hypot(math.hypot(vx[0], vx[2]), G * end)
    assert speeds[1] < speed_end < speeds[2]
    np.testing.assert_allclose(got[:2], final, rtol=1e-12)
    assert math.isnan(got[2])


def test_a_pellet_never_within_body_height_has_no_reach_and_no_passes():
    """Thrown up from 2 m and ended at its apex's fall back to 1.9 m: never within body height."""
    grid = ph.Grid((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0), 0.0, -10.0, 1.0, 50, 20)
    hazard = ph.Hazard(**LEVEL, speeds=(1.0, 10.0), grid=grid)
    _, end = _times(2.0, 5.0, 1.9)
    out = ph.hazard_of(ph.parabola((0.0, 2.0, 0.0), (10.0, 5.0, 0.0), end), hazard, tolerance=(1e-3, 1e-3))
    assert np.isnan(out.reach).all() and out.passes == []


@pytest.mark.parametrize("c", [0.05, 0.2])
def test_a_slide_on_a_level_plane_reaches_where_its_speed_crosses(c):
    """On the plane (within body height all along), no spin, vacuum: it slides at -mu g until it rolls
    at 5/7 v0, after 12 v0^2 / (49 mu g), then rolls at -5/7 c g (docs/ground.md). A threshold v above
    5/7 v0 is crossed (v0^2 - v^2) / (2 mu g) out, one below it (5/7 v0)^2 - v^2) / (2 5/7 c g) past
    the rolling point, from the start 1 m out: the reach (the followed path's dense output)."""
    v0, mu = 20.0, 0.4
    r = sm.follow([1.0, R, 0.0], [v0, 0.0, 0.0], [0.0, 0.0, 0.0], radius=R, ground=sm.Ground(0.3, 0.5, mu, c), rest_speed=0.1)
    assert r.state == "rest"
    speeds = (18.0, 15.0, 10.0, 1.0, 0.1, 25.0)
    got = ph.reach(ph.path_of(r), ph.Hazard(**LEVEL, speeds=speeds))
    rolling = 12 * v0**2 / (49 * mu * G)
    want = [
        1.0 + ((v0**2 - v**2) / (2 * mu * G) if v > 5 / 7 * v0 else rolling + ((5 / 7 * v0) ** 2 - v**2) / (2 * 5 / 7 * c * G))
        for v in speeds[:5]
    ]
    np.testing.assert_allclose(got[:5], want, rtol=1e-9)
    np.testing.assert_allclose(got[4], r.x[0], rtol=1e-9)  # the rest speed: where it rests
    assert math.isnan(got[5])


def test_the_path_is_the_followed_pellet_s():
    """A ricochet, flights and a slide to rest: the dense path is continuous, ends where `follow`
    rests, and its length is follow's path length; the vacuum's parabolas match the flights' dense
    outputs (both float64)."""
    r = sm.follow([0.0, 1.0, 0.3], [30.0, -2.0, 1.3], [0.0, 0.0, 0.0], radius=R, ground=sm.Ground(0.3, 0.5, 0.45, 0.1, 5.0))
    exact, dense = ph.path_of(r), ph.path_of(r, vacuum=False)
    assert len(exact.segments) >= 5
    for k, (t0, t1, _) in enumerate(exact.segments):
        t = np.linspace(t0, t1, 11)
        np.testing.assert_allclose(exact.state(k, t)[0], dense.state(k, t)[0], rtol=1e-10, atol=1e-10)
        if k:
            np.testing.assert_allclose(exact.state(k, t0)[0], exact.state(k - 1, exact.segments[k - 1][1])[0], atol=1e-9)
    np.testing.assert_allclose(exact.state(len(exact.segments) - 1, exact.segments[-1][1])[0][0], r.x, atol=1e-8)
    length = sum(exact.length(k, 4001) for k in range(len(exact.segments)))
    assert length == pytest.approx(r.path_length, rel=1e-6)


GRID = ph.Grid((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0), 0.0, -10.0, 0.5, 40, 40)


def _columns(x, z):
    """The grid's column at (x, z) (GRID: u = x, v = -z from v0 = -10, 0.5 m cells)."""
    return int(GRID.column(x / 0.5, (-z + 10.0) / 0.5))


def test_passes_of_a_flight_across_the_grid_are_its_cell_crossings():
    """A low flight (1.2 m down to 0.1 m) at (30, -, -7) m/s across 0.5 m cells: a pass at its start,
    then one at each crossing of a cell edge x = 0.5 i or z = -0.5 j (their times in closed form),
    into the cell beyond, at the level of its speed there; no ghost, all certain."""
    x0, v, end = np.array([0.2, 1.2, 0.1]), np.array([30.0, 0.5, -7.0]), 0.45
    speeds = (30.9, 31.0, 40.0)
    hazard = ph.Hazard(**LEVEL, speeds=speeds, grid=GRID)
    out = ph.hazard_of(ph.parabola(x0, v, end), hazard, tolerance=(1e-6, 1e-6))
    cross = sorted(
        [(0.5 * i - x0[0]) / v[0] for i in range(1, 40) if 0 < (0.5 * i - x0[0]) / v[0] < end]
        + [(-0.5 * j - x0[2]) / v[2] for j in range(0, 40) if 0 < (-0.5 * j - x0[2]) / v[2] < end]
    )
    want = [(0.0, _columns(x0[0], x0[2]))]
    for t in cross:  # the cell just beyond the edge
        position = x0 + v * (t + 1e-9)
        want.append((t, _columns(position[0], position[2])))
    assert [p.column for p in out.passes] == [c for _, c in want]
    np.testing.assert_allclose([p.t for p in out.passes], [t for t, _ in want], atol=1e-12)
    level = [int(np.sum(math.hypot(v[0], v[2], v[1] - G * t) >= np.asarray(speeds))) for t, _ in want]
    assert [p.level for p in out.passes] == level and len(set(level)) == 3  # three levels met
    assert all(p.certain for p in out.passes)


def test_a_stretch_within_body_height_starting_in_a_cell_enters_it():
    """Down from 2.5 m through body height at t_H over cell (u, v): its first pass is there, at t_H."""
    x0, v = np.array([1.1, 2.5, -0.3]), np.array([20.0, 0.0, 0.0])
    out = ph.hazard_of(ph.parabola(x0, v, 0.5), ph.Hazard(**LEVEL, speeds=(), grid=GRID), tolerance=(1e-6, 0.0))
    t = math.sqrt(2 * (2.5 - H) / G)
    first = out.passes[0]
    assert first.t == pytest.approx(t, abs=1e-12) and first.column == _columns(1.1 + 20 * t, -0.3) and first.level == 0


@pytest.mark.parametrize("apex", [1e-3, -1e-3])
def test_a_graze_of_body_height_within_the_tolerance_is_flagged(apex):
    """A rise to 1 mm above body height and back (an exit and entry a rounding could miss: the entry
    is flagged `absent`) or to 1 mm below (a near-miss: a ghost pass a rounding could add), with a
    tolerance of 5 mm; with 0.1 mm neither is flagged."""
    vy = 3.0
    h0 = H + apex - vy * vy / (2 * G)  # the apex at H + apex, after vy / g
    path = ph.parabola((0.1, h0, 0.2), (2.0, vy, 0.0), 2 * vy / G)  # ends at h0 again
    hazard = ph.Hazard(**LEVEL, speeds=(3.0,), grid=GRID)
    loose = ph.hazard_of(path, hazard, tolerance=(5e-3, 1e-6)).passes
    tight = ph.hazard_of(path, hazard, tolerance=(1e-4, 1e-6)).passes
    assert all(p.certain for p in tight)
    flagged = [p for p in loose if not p.certain]
    at_apex = [p for p in flagged if abs(p.t - vy / G) < 0.05]
    assert at_apex and all(p.ghost == (apex < 0) for p in at_apex)
    assert len(tight) == len([p for p in loose if not p.ghost])
    if apex > 0:  # it leaves body height for a moment: the entry after counts again
        assert len([p for p in tight if p.column == _columns(0.1 + 2.0 * vy / G, 0.2)]) == 2


def test_a_point_s_level_is_the_highest_over_its_passage():
    """A descending flight past a person's vertical at 0.2 m (radius 0.3 m) within body height: its
    level there is that of its speed leaving the cylinder (the speed grows on the way down); a point
    1 m off the line is never passed (None); one above body height only neither."""
    x0, v = np.array([0.0, 1.5, 0.0]), np.array([25.0, 0.0, 0.0])
    b, r = 0.2, 0.3
    leave = (10.0 + math.sqrt(r * r - b * b)) / v[0]
    speed = math.hypot(v[0], G * leave)
    speeds = (speed - 1e-3, speed + 1e-3, 10.0)
    points = (((10.0, 0.0, b), r), ((10.0, 0.0, 1.0), r))
    hazard = ph.Hazard(**LEVEL, speeds=speeds, points=points)
    assert ph.point_levels(ph.parabola(x0, v, 0.6), hazard) == [2, None]
    high = ph.Hazard(**{**LEVEL, "body_height": 0.2}, speeds=speeds, points=points)
    assert ph.point_levels(ph.parabola(x0, v, 0.6), high) == [None, None]
