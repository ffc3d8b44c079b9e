"""The hazard watched along a path (`tallies.path`) against closed forms in float64: the reach per
threshold of random vacuum parabolas (their body-height and threshold crossings are quadratics'
roots), the passes through a map's cells by level at entry, the named places, and rolling with
ploughing (its speed as a function of distance in closed form); a watch ended by an escape in the
dense phase (ESCAPED) counts nothing more."""

import math

import numpy as np
import pytest
import warp as wp

from warp_ricochet.physics.types import types_for
from warp_ricochet.tallies.counts import DeviceTally, TallySetup
from warp_ricochet.tallies.path import ESCAPED, make_path_roots
from warp_ricochet.tallies.path_chord import make_path_watch

G = 9.81
H = 1.8  # m, body height
SPEEDS = (30.0, 80.0, 150.0)  # m/s, the thresholds


def _setup(cell=0.5, extent=(0.0, 100.0, -10.0, 10.0), places=()):
    nu, nv = math.ceil((extent[1] - extent[0]) / cell), math.ceil((extent[3] - extent[2]) / cell)
    return TallySetup(
        names=tuple(f"t{i}" for i in range(len(SPEEDS))),
        kinds=("speed",) * len(SPEEDS),
        values=SPEEDS,
        thresholds2=tuple(s * s for s in SPEEDS),
        shooter=(0.0, 0.0, 0.0),
        up=(0.0, 1.0, 0.0),
        half_mass=1e-4,
        area=1e-5,
        fractions=(1e-3,),
        map_surface=0,
        map_origin=(0.0, 0.0, 0.0),
        map_u=(1.0, 0.0, 0.0),
        map_v=(0.0, 0.0, 1.0),
        map_u0=extent[0],
        map_v0=extent[2],
        map_cell=cell,
        map_nu=nu,
        map_nv=nv,
        body_height=H,
        ground_point=(0.0, 0.0, 0.0),
        ground_normal=(0.0, 1.0, 0.0),
        places=places,
    )


def _watch_kernel(precision, places, terrain=False, with_map=True):
    t = types_for(precision)
    w = make_path_watch(precision, len(SPEEDS), places, with_map, terrain)

    @wp.kernel
    def watch_parabolas(
        tally: w.Tally,
        x0: wp.array(dtype=t.vec3),
        v0: wp.array(dtype=t.vec3),
        g: t.vec3,
        dt: wp.array(dtype=t.scalar),
        reach_out: wp.array2d(dtype=t.scalar),
    ):
        i = wp.tid()
        track = w.start()
        track = w.parabola(track, tally, x0[i], v0[i], g, dt[i])
        w.write(track, reach_out, i)
        w.finish(track, tally, i)

    @wp.kernel
    def watch_lines(
        tally: w.Tally,
        x0: wp.array(dtype=t.vec3),
        direction: t.vec3,
        length: wp.array(dtype=t.scalar),
        v0: wp.array(dtype=t.scalar),
        a: t.scalar,
        b: t.scalar,
        reach_out: wp.array2d(dtype=t.scalar),
    ):
        i = wp.tid()
        track = w.start()
        track = w.line(track, tally, x0[i], direction, length[i], v0[i], a, b)
        w.write(track, reach_out, i)
        w.finish(track, tally, i)

    @wp.kernel
    def watch_hermite_steps(
        tally: w.Tally,
        x0: wp.array2d(dtype=t.vec3),
        direction: t.vec3,
        dt: wp.array2d(dtype=t.scalar),
        v0: wp.array2d(dtype=t.scalar),
        decel: wp.array2d(dtype=t.scalar),
        reach_out: wp.array2d(dtype=t.scalar),
    ):
        i = wp.tid()
        track = w.start()
        pending = w.straight_open()
        last = x0[i, 0]
        for k in range(dt.shape[1]):
            h = dt[i, k]
            d0 = (h * v0[i, k]) * direction
            e0 = (-h * h * decel[i, k]) * direction
            x1 = x0[i, k] + (h * v0[i, k] - t.scalar(0.5) * decel[i, k] * h * h) * direction
            v1 = v0[i, k] - decel[i, k] * h
            d1 = (h * v1) * direction
            track, pending = w.straight_segment(track, tally, pending, x0[i, k], d0, e0, x1, d1, e0, h, v0[i, k], v1)
            last = x1
        track, pending = w.straight_close(track, tally, pending, last)
        w.write(track, reach_out, i)
        w.finish(track, tally, i)

    return watch_parabolas, watch_lines, watch_hermite_steps


def _reference_reach(x0, v0, dt, v2):
    """Reach of a parabola over [0, dt] for |v|^2 >= v2 within body height (float64 closed form)."""
    y0, vy = x0[1], v0[1]
    roots = [0.0, dt]
    # y(t) = y0 + vy t - g t^2 / 2 = H and |v|^2 = vx^2 + vz^2 + (vy - g t)^2 = v2
    for a, b, c in ((-0.5 * G, vy, y0 - H), (G * G, -2.0 * vy * G, v0 @ v0 - v2)):
        disc = b * b - 4 * a * c
        if disc >= 0:
            roots += [(-b - s * math.sqrt(disc)) / (2 * a) for s in (1, -1)]
    ts = sorted(r for r in roots if 0.0 <= r <= dt)
    best = -1.0
    for lo, hi in zip(ts[:-1], ts[1:]):
        m = 0.5 * (lo + hi)
        y = y0 + vy * m - 0.5 * G * m * m
        v = v0 + np.array([0.0, -G * m, 0.0])
        if y <= H and v @ v >= v2:
            for s in (lo, hi):
                p = x0 + v0 * s
                best = max(best, math.hypot(p[0], p[2]))
    return math.nan if best < 0 else best


def _random_parabolas(rng, n):
    x0 = np.column_stack([rng.uniform(-5, 20, n), rng.uniform(0.01, 3.0, n), rng.uniform(-3, 3, n)])
    speed = rng.uniform(20.0, 250.0, n)
    angle = np.radians(rng.uniform(-10.0, 25.0, n))
    side = np.radians(rng.uniform(-5.0, 5.0, n))
    v0 = speed[:, None] * np.column_stack([np.cos(angle) * np.cos(side), np.sin(angle), np.cos(angle) * np.sin(side)])
    # until it comes back to y = 0 (its landing) or for at most 2 s
    t_land = (v0[:, 1] + np.sqrt(v0[:, 1] ** 2 + 2 * G * x0[:, 1])) / G
    return x0, v0, np.minimum(t_land, 2.0)


def _flights(x0, v0, dt, precision, device):
    """The parabola kernel's inputs: launches (m, m/s) flown for dt (s) under g along -y."""
    t = types_for(precision)
    return [
        wp.array(x0, dtype=t.vec3, device=device),
        wp.array(v0, dtype=t.vec3, device=device),
        t.vec3(0.0, -G, 0.0),
        wp.array(np.asarray(dt, dtype=np.float64), dtype=t.scalar, device=device),
    ]


def _run(kernel, setup, precision, device, inputs, n):
    t = types_for(precision)
    tally = DeviceTally(setup, precision, wp.get_device(device), active=True)
    tally.start(None)
    tally.before_chunk()  # (as a run does: on CUDA the pooled counts are then no longer known zero)
    reach = wp.zeros((n, len(SPEEDS)), dtype=t.scalar, device=device)
    wp.launch(kernel, dim=n, inputs=[tally.struct, *inputs], outputs=[reach], device=device)
    tally.resolve()
    return tally, reach.numpy().astype(np.float64)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_reach_of_parabolas_is_the_closed_form(device, precision):
    """Random vacuum flights (crossing body height up and down, thresholds on the way): the reach
    per threshold within 1e-9 (float64) / 2e-5 (float32) of the path's length of its closed form."""
    rng = np.random.default_rng(26)
    n = 256
    x0, v0, dt = _random_parabolas(rng, n)
    parabolas, _lines, _hermite = _watch_kernel(precision, 0)
    inputs = _flights(x0, v0, dt, precision, device)
    _tally, reach = _run(parabolas, _setup(), precision, device, inputs, n)
    length = np.linalg.norm(v0, axis=1) * dt  # about the path's length
    tolerance = 1e-9 if precision == "float64" else 2e-5
    found = 0
    for i in range(n):
        for k, s in enumerate(SPEEDS):
            want = _reference_reach(x0[i], v0[i], dt[i], s * s)
            if math.isnan(want):
                assert math.isnan(reach[i, k]), (i, k, reach[i, k])
            else:
                found += 1
                assert abs(reach[i, k] - want) <= tolerance * length[i] + 1e-9, (i, k, reach[i, k], want)
    assert found > n  # most flights reach above some threshold within body height


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_escapes_are_watched_until_below_the_ground(device, precision):
    """Random vacuum flights that meet no surface (`escape_time`), from 2 m below to 3 m above the ground
    plane y = 0, up to 60 degrees up: watched until they fall below the plane (the later root of
    y(t) = 0), or, never above it, to their apex; the reach per threshold as the closed form's of
    that flight (`_reference_reach`), within the parabolas' tolerance."""
    rng = np.random.default_rng(29)
    n = 256
    t = types_for(precision)
    w = make_path_watch(precision, len(SPEEDS), 0, False)  # (the reach alone: a shorter compilation)
    roots = make_path_roots(precision)

    @wp.kernel
    def watch_escapes(
        tally: w.Tally, x0: wp.array(dtype=t.vec3), v0: wp.array(dtype=t.vec3), g: t.vec3, reach_out: wp.array2d(dtype=t.scalar)
    ):
        i = wp.tid()
        track = w.parabola(w.start(), tally, x0[i], v0[i], g, roots.escape_time(tally, x0[i], v0[i], g))
        w.write(track, reach_out, i)

    x0 = np.column_stack([rng.uniform(-5, 20, n), rng.uniform(-2.0, 3.0, n), rng.uniform(-3, 3, n)])
    angle = np.radians(rng.uniform(-10.0, 60.0, n))
    v0 = rng.uniform(5.0, 250.0, n)[:, None] * np.column_stack([np.cos(angle), np.sin(angle), np.zeros(n)])
    disc = v0[:, 1] ** 2 + 2 * G * x0[:, 1]
    end = np.where(disc >= 0, (v0[:, 1] + np.sqrt(np.maximum(disc, 0))) / G, v0[:, 1] / G)  # the later root, or the apex
    _tally, reach = _run(watch_escapes, _setup(), precision, device, _flights(x0, v0, end, precision, device)[:3], n)
    length = np.linalg.norm(v0, axis=1) * np.maximum(end, 0.0)
    tolerance = 1e-9 if precision == "float64" else 2e-5
    found = 0
    for i in range(n):
        for k, s in enumerate(SPEEDS):
            want = _reference_reach(x0[i], v0[i], end[i], s * s) if end[i] > 0 else math.nan  # below, falling: none
            if math.isnan(want):
                assert math.isnan(reach[i, k]), (i, k, reach[i, k], end[i])
            else:
                found += 1
                assert abs(reach[i, k] - want) <= tolerance * length[i] + 1e-9, (i, k, reach[i, k], want)
    assert found > n and (end <= 0).sum() > 5 and (disc < 0).sum() > 5  # (all three cases drawn)


def _reference_passes(x0, v0, dt, setup):
    """(level, column) passes of level flights below body height (straight along x and z)."""
    counts = np.zeros((setup.levels, setup.cells + 2), dtype=np.int64)
    order = np.asarray(setup.thresholds2)
    for x, v, d in zip(x0, v0, dt):
        # the cell boundaries crossed along u (x) and v (z), as times
        times = [0.0]
        for axis, start, size in ((0, setup.map_u0, setup.map_cell), (2, setup.map_v0, setup.map_cell)):
            if v[axis] != 0:
                a, b = sorted(((x[axis] - start) / size, (x[axis] + v[axis] * d - start) / size))
                times += [(start + j * size - x[axis]) / v[axis] for j in range(math.floor(a) + 1, math.floor(b) + 1)]
        last = None
        for s in sorted(times):
            p = x + v * s + np.array([0.0, -0.5 * G * s * s, 0.0])
            # the cell entered at s: its position just after the crossing
            q = x + v * (s + 1e-9)
            iu, iv = math.floor((q[0] - setup.map_u0) / setup.map_cell), math.floor((q[2] - setup.map_v0) / setup.map_cell)
            column = iv * setup.map_nu + iu if 0 <= iu < setup.map_nu and 0 <= iv < setup.map_nv else setup.cells
            if column != last:
                speed2 = v @ v - 2 * v[1] * G * s + (G * s) ** 2
                counts[int(np.sum(speed2 >= order)), column] += 1
                last = column
            del p
    return counts


@pytest.mark.parametrize("precision,heading", [("float64", 0.0), ("float32", 0.0), ("float64", 90.0), ("float64", 200.0)])
def test_passes_are_the_cells_entered_by_level(device, precision, heading):
    """Low flights (all within body height) across a grid of 0.5 m cells, some off it: every cell
    entered counted once with the level at its entry, as the closed form's crossings say; headed
    along +u (runs along the rows), along v (walked along v, rows crossed at every cell) and back
    along -u, +-20 degrees."""
    rng = np.random.default_rng(7)
    n = 64
    x0 = np.column_stack([rng.uniform(-4.0, 50.0, n), np.full(n, 1.0), rng.uniform(-12.0, 12.0, n)])
    x0 += 1e-3 * rng.uniform(size=(n, 3))  # off the cell edges
    speed = rng.uniform(20.0, 200.0, n)
    side = np.radians(heading + rng.uniform(-20.0, 20.0, n))
    v0 = speed[:, None] * np.column_stack([np.cos(side), np.zeros(n), np.sin(side)])
    dt = np.minimum(0.25, 30.0 / speed)  # it falls at most 0.31 m: within body height
    setup = _setup()
    parabolas, _lines, _hermite = _watch_kernel(precision, 0)
    inputs = _flights(x0, v0, dt, precision, device)
    tally, _reach = _run(parabolas, setup, precision, device, inputs, n)
    got = tally.counts["exposure"].numpy().reshape(setup.levels, setup.cells + 2).astype(np.int64)
    want = _reference_passes(x0, v0, dt, setup)
    assert got.sum() == want.sum()
    np.testing.assert_array_equal(got, want)


def test_places_count_the_pellets_that_pass_within_their_radius(device):
    """Two places beside a straight low flight: the one within its radius counts the pellet once,
    at the level it passes with; the one just outside does not."""
    precision = "float64"
    places = (("near", (20.0, 0.0, 0.3), 0.25), ("far", (20.0, 0.0, -0.3), 0.25))
    setup = _setup(places=places)
    parabolas, _lines, _hermite = _watch_kernel(precision, len(places))
    x0 = np.array([[0.0, 1.0, 0.1], [0.0, 1.0, 0.1]])
    v0 = np.array([[100.0, 0.0, 0.0], [60.0, 0.0, 0.0]])  # above 80 m/s and between 30 and 80 m/s
    inputs = _flights(x0, v0, [0.5, 0.5], precision, device)
    tally, _reach = _run(parabolas, setup, precision, device, inputs, 2)
    counts = tally.counts["places"].numpy().reshape(setup.levels, len(places))
    np.testing.assert_array_equal(counts[:, 1], 0)  # 0.4 m off: outside its 0.25 m
    np.testing.assert_array_equal(counts[:, 0], [0, 1, 1, 0])  # levels 1 (60 m/s) and 2 (100 m/s)


@pytest.mark.parametrize(
    "precision,heading", [("float64", 0.0), ("float32", 7.0), ("float64", 90.0), ("float64", 183.0), ("float64", 250.0)]
)
def test_straight_stretches_pass_the_cells_entered_by_level(device, precision, heading):
    """Rolling with ploughing along straight stretches across a grid of 0.5 m cells, some off it
    (`line`: runs along u counted at once): every cell entered counted once with the level at its
    entry, as the closed form's speed and the line's crossings say."""
    t = types_for(precision)
    rng = np.random.default_rng(11)
    n, a, b = 48, 0.35, 0.02
    x0 = np.column_stack([rng.uniform(-4.0, 60.0, n), np.full(n, 0.00125), rng.uniform(-12.0, 12.0, n)])
    x0 += 1e-3 * rng.uniform(size=(n, 3))  # off the cell edges
    angle = math.radians(heading)
    direction = np.array([math.cos(angle), 0.0, math.sin(angle)])
    length, v0 = rng.uniform(2.0, 60.0, n), rng.uniform(20.0, 200.0, n)
    setup = _setup()
    _parabolas, lines, _hermite = _watch_kernel(precision, 0)
    inputs = [
        wp.array(x0, dtype=t.vec3, device=device),
        t.vec3(*direction),
        wp.array(length, dtype=t.scalar, device=device),
        wp.array(v0, dtype=t.scalar, device=device),
        t.scalar(a),
        t.scalar(b),
    ]
    tally, _reach = _run(lines, setup, precision, device, inputs, n)
    got = tally.counts["exposure"].numpy().reshape(setup.levels, setup.cells + 2).astype(np.int64)
    want = _reference_step_passes(x0, direction, length[:, None], setup, _law_level(v0[:, None], a, b))
    assert want[:, : setup.cells].sum() > 10 * n  # (runs along the rows, and off the grid too)
    np.testing.assert_array_equal(got, want)


def _reference_step_passes(x0, heading, lengths, setup, level_at, within=None):
    """(level, column) passes of pellets moving along `heading` in steps of `lengths` (m) from x0:
    each cell entered once along the line, at `level_at(i, k, into)` (pellet i, step k, m into it);
    a step not `within[i, k]` body height enters none, and the next cell after it counts again."""
    counts = np.zeros((setup.levels, setup.cells + 2), dtype=np.int64)
    for i, (x, steps) in enumerate(zip(x0, lengths)):
        ends = np.cumsum(steps)
        total = ends[-1]
        times = [0.0] + list(ends[:-1])  # (a step's start: where a pass may begin again)
        for axis, start, size in ((0, setup.map_u0, setup.map_cell), (2, setup.map_v0, setup.map_cell)):
            if heading[axis] != 0:
                lo, hi = sorted(((x[axis] - start) / size, (x[axis] + heading[axis] * total - start) / size))
                times += [(start + j * size - x[axis]) / heading[axis] for j in range(math.floor(lo) + 1, math.floor(hi) + 1)]
        last = None
        for s in sorted(set(times)):
            k = min(int(np.searchsorted(ends, s, side="right")), len(steps) - 1)
            if within is not None and not within[i, k]:
                last = None
                continue
            q = x + heading * (s + 1e-9)  # just past the edge crossed at s
            iu, iv = math.floor((q[0] - setup.map_u0) / setup.map_cell), math.floor((q[2] - setup.map_v0) / setup.map_cell)
            column = iv * setup.map_nu + iu if 0 <= iu < setup.map_nu and 0 <= iv < setup.map_nv else setup.cells
            if column != last:
                counts[level_at(i, k, s - (ends[k] - steps[k])), column] += 1
                last = column
    return counts


def _law_level(v0s, a, b):
    """`_reference_step_passes`' level under the law a + b v^2 = (a + b v0^2) exp(-2 b s) of each step."""
    speeds = np.sqrt(np.asarray([s * s for s in SPEEDS]))

    def level_at(i, k, into):
        v = v0s[i, k]
        return sum(1 for c in speeds if v >= c and into <= math.log((a + b * v * v) / (a + b * c * c)) / (2 * b))

    return level_at


@pytest.mark.parametrize("with_map", [True, False], ids=["map", "reach-alone"])
@pytest.mark.parametrize("precision,heading", [("float64", 0.0), ("float32", 11.0), ("float64", 200.0)])
def test_a_phase_s_hermite_steps_walked_as_one_chord_pass_the_cells_entered_by_level(device, precision, heading, with_map):
    """A phase's steps given as time Hermites along a line (`straight_segment`), of constant
    acceleration (the Hermite is the motion): slowing or speeding up across thresholds inside a step
    (`straight_crossing`'s roots), a step starting slower than the last ended (a threshold reached
    again inside a step after a drop begins a new chord), a step above body height now and then (watched alone: no pass, the next cell counted again): every cell
    entered counted once with the level at its entry, and the reach, as the closed form says."""
    t = types_for(precision)
    rng = np.random.default_rng(17)
    n, m = 48, 6
    start = np.column_stack([rng.uniform(-4.0, 60.0, n), np.zeros(n), rng.uniform(-12.0, 12.0, n)])
    start += 1e-3 * rng.uniform(size=(n, 3))  # off the cell edges
    angle = math.radians(heading)
    direction = np.array([math.cos(angle), 0.0, math.sin(angle)])
    dt = rng.uniform(0.01, 0.12, (n, m))
    v0 = np.empty((n, m))
    decel = rng.uniform(-300.0, 900.0, (n, m))  # m/s^2: most slow down, some speed up
    v0[:, 0] = rng.uniform(20.0, 200.0, n)
    drops = rng.uniform(size=(n, m)) < 0.25  # a step that starts slower than the last ended, then speeds up past it
    drops[:, 0] = False
    for k in range(m):
        if k > 0:
            ended = v0[:, k - 1] - decel[:, k - 1] * dt[:, k - 1]
            v0[:, k] = np.where(drops[:, k], 0.6 * ended, ended)
            decel[:, k] = np.where(drops[:, k], -1.5 * (ended - v0[:, k]) / dt[:, k], decel[:, k])
        decel[:, k] = np.minimum(decel[:, k], 0.9 * v0[:, k] / dt[:, k])  # moving on throughout
    lengths = v0 * dt - 0.5 * decel * dt * dt
    within = rng.uniform(size=(n, m)) > 0.1
    height = np.where(within, 0.00125, 2.5)  # m: 2.5 m is above body height (1.8 m)
    x0 = np.empty((n, m, 3))
    for k in range(m):
        x0[:, k] = start + (np.cumsum(lengths, axis=1)[:, k] - lengths[:, k])[:, None] * direction
        x0[:, k, 1] = height[:, k]
    setup = _setup()
    *_others, hermite = _watch_kernel(precision, 0, with_map=with_map)
    inputs = [
        wp.array(x0, dtype=t.vec3, device=device),
        t.vec3(*direction),
        wp.array(dt, dtype=t.scalar, device=device),
        wp.array(v0, dtype=t.scalar, device=device),
        wp.array(decel, dtype=t.scalar, device=device),
    ]
    tally, reach = _run(hermite, setup, precision, device, inputs, n)

    def level_at(i, k, into):
        v = math.sqrt(max(v0[i, k] ** 2 - 2.0 * decel[i, k] * into, 0.0))
        return sum(1 for c in SPEEDS if v >= c)

    want = _reference_step_passes(start, direction, lengths, setup, level_at, within)
    ended = np.column_stack([np.full(n, np.inf), (v0 - decel * dt)[:, :-1]])
    gaps = [
        (i, k)
        for i in range(n)
        for k in range(1, m)
        if within[i, k] and any(ended[i, k] >= c > v0[i, k] and v0[i, k] - decel[i, k] * dt[i, k] >= c for c in SPEEDS)
    ]
    rising = (
        (decel < 0)
        & within
        & np.array([[any(v0[i, k] < c <= v0[i, k] - decel[i, k] * dt[i, k] for c in SPEEDS) for k in range(m)] for i in range(n)])
    )
    assert rising.sum() >= 5 and len(gaps) >= 5 and (~within).sum() >= 10 and want[:, : setup.cells].sum() > 10 * n
    if with_map:
        got = tally.counts["exposure"].numpy().reshape(setup.levels, setup.cells + 2).astype(np.int64)
        np.testing.assert_array_equal(got, want)
    for i in range(n):
        for j, c in enumerate(SPEEDS):
            far = []
            for k in range(m):
                v_end = v0[i, k] - decel[i, k] * dt[i, k]
                if (v0[i, k] < c and v_end < c) or not within[i, k]:  # (above body height: no reach)
                    continue
                # the stretch of the step above c: from its start or the crossing, to its end or the crossing
                cross = (v0[i, k] ** 2 - c * c) / (2.0 * decel[i, k]) if (v0[i, k] >= c) != (v_end >= c) else None
                ends = [0.0 if v0[i, k] >= c else cross, lengths[i, k] if v_end >= c else cross]
                far += [np.hypot(*(x0[i, k] + direction * e)[[0, 2]]) for e in ends]
            if far:
                assert reach[i, j] == pytest.approx(max(far), rel=2e-5 if precision == "float32" else 1e-9)
            else:
                assert math.isnan(reach[i, j])


# hand-made phases along x of constant-deceleration steps (from x, direction sign, each step's dt s,
# start speed m/s and deceleration m/s^2) and the reach of the thresholds 30, 80, 150 m/s: a speed that
# drops across thresholds between steps and never comes back (the stretch ends at the drop), one that
# rises across 30 m/s inside a step moving toward the shooter (the stretch begins at the crossing,
# 0.7375 m into it), a jump up then down (the stretch is the middle step)
_HAND_MADE = {
    "drop": (10.0, 1.0, [0.05, 0.05], [100.0, 20.0], [200.0, 20.0], [14.75, 14.75, math.nan]),
    "rise": (20.0, -1.0, [0.05, 0.05], [29.0, 31.0], [-40.0, 200.0], [19.2625, math.nan, math.nan]),
    "up-down": (10.0, 1.0, [0.05, 0.05, 0.05], [20.0, 100.0, 20.0], [20.0, 100.0, 20.0], [15.85, 15.85, math.nan]),
}


@pytest.mark.parametrize("case", list(_HAND_MADE))
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_hand_made_steps_reach_as_their_stretches_say(device, precision, case):
    """Steps whose speed jumps between steps or rises inside one (`straight_segment`): the reach
    alone (`make_path_light`) and the map's chord give each threshold's farthest stretch end."""
    t = types_for(precision)
    x, sign, dt, v0, decel, want = _HAND_MADE[case]
    dt, v0, decel = np.array([dt]), np.array([v0]), np.array([decel])
    lengths = v0 * dt - 0.5 * decel * dt * dt
    starts = x + sign * (np.cumsum(lengths, axis=1) - lengths)
    x0 = np.stack([starts, np.full_like(starts, 0.00125), np.zeros_like(starts)], axis=-1)
    inputs = [
        wp.array(x0, dtype=t.vec3, device=device),
        t.vec3(sign, 0.0, 0.0),
        wp.array(dt, dtype=t.scalar, device=device),
        wp.array(v0, dtype=t.scalar, device=device),
        wp.array(decel, dtype=t.scalar, device=device),
    ]
    for with_map in (False, True):
        *_others, hermite = _watch_kernel(precision, 0, with_map=with_map)
        _tally, reach = _run(hermite, _setup(), precision, device, inputs, 1)
        np.testing.assert_allclose(reach[0], want, rtol=1e-6, err_msg=f"with_map={with_map}")


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_rolling_with_ploughing_reaches_where_its_speed_falls_to_the_threshold(device, precision):
    """v' = -(a + b v^2) along a line: the reach of threshold v_i is at
    s_i = ln((a + b v0^2) / (a + b v_i^2)) / (2 b) (or the stretch's end)."""
    t = types_for(precision)
    a, b = 0.35, 0.02  # m/s^2, 1/m
    v0 = np.array([200.0, 120.0, 50.0, 20.0])
    length = np.array([40.0, 300.0, 300.0, 300.0])
    x0 = np.array([[5.0, 0.00125, 0.0]] * 4)
    _parabolas, lines, _hermite = _watch_kernel(precision, 0)
    inputs = [
        wp.array(x0, dtype=t.vec3, device=device),
        t.vec3(1.0, 0.0, 0.0),
        wp.array(length, dtype=t.scalar, device=device),
        wp.array(v0, dtype=t.scalar, device=device),
        t.scalar(a),
        t.scalar(b),
    ]
    _tally, reach = _run(lines, _setup(), precision, device, inputs, 4)
    for i in range(4):
        for k, s in enumerate(SPEEDS):
            if v0[i] < s:
                assert math.isnan(reach[i, k])
            else:
                d = min(math.log((a + b * v0[i] ** 2) / (a + b * s * s)) / (2 * b), length[i])
                assert reach[i, k] == pytest.approx(5.0 + d, rel=1e-5 if precision == "float32" else 1e-12)


def test_a_watch_ended_by_an_escape_counts_nothing_more(device):
    """A track whose watch the dense phase ended (cell ESCAPED, `dense.watch`) given low flights and
    rolling stretches: no reach, no pass, no place, where the same track not ended counts them all."""
    precision = "float32"
    t = types_for(precision)
    places = (("all", (20.0, 0.0, 0.0), 100.0),)
    w = make_path_watch(precision, len(SPEEDS), len(places), True)

    @wp.kernel
    def watch_after(
        tally: w.Tally,
        ended: wp.int32,
        x0: wp.array(dtype=t.vec3),
        v0: wp.array(dtype=t.vec3),
        g: t.vec3,
        dt: wp.array(dtype=t.scalar),
        reach_out: wp.array2d(dtype=t.scalar),
    ):
        i = wp.tid()
        track = w.start()
        if ended != 0:
            track.cell = wp.int32(ESCAPED)
        track = w.parabola(track, tally, x0[i], v0[i], g, dt[i])
        rolling = x0[i] + dt[i] * v0[i]
        track = w.line(
            track, tally, rolling, wp.normalize(v0[i]), t.scalar(20.0), wp.length(v0[i]), t.scalar(0.35), t.scalar(0.02)
        )
        w.write(track, reach_out, i)
        w.finish(track, tally, i)

    rng = np.random.default_rng(41)
    n = 32
    x0 = np.column_stack([rng.uniform(-4.0, 50.0, n), np.full(n, 1.0), rng.uniform(-8.0, 8.0, n)])
    v0 = rng.uniform(40.0, 200.0, n)[:, None] * np.column_stack([np.ones(n), np.zeros(n), rng.uniform(-0.2, 0.2, n)])
    dt = np.minimum(0.25, 30.0 / np.linalg.norm(v0, axis=1))  # within body height
    setup = _setup(places=places)
    found = {}
    for ended in (0, 1):
        inputs = [ended, *_flights(x0, v0, dt, precision, device)]
        tally, reach = _run(watch_after, setup, precision, device, inputs, n)
        found[ended] = (reach, tally.counts["exposure"].numpy().sum(), tally.counts["places"].numpy().sum())
    reach, passes, visits = found[0]
    assert np.isfinite(reach[:, 0]).all() and passes >= 2 * n and visits == n, (passes, visits)
    reach, passes, visits = found[1]
    assert np.isnan(reach).all() and passes == 0 and visits == 0, (passes, visits)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_chord_of_the_reach_alone_after_an_escape_counts_nothing(device, precision):
    """The reach alone's chord (`make_path_light`) of a track whose watch ended (cell ESCAPED): a
    step within body height, above every threshold, leaves no reach, where the same step of a track
    not ended reaches its end."""
    t = types_for(precision)
    w = make_path_watch(precision, len(SPEEDS), 0, False)

    @wp.kernel
    def steps_after(tally: w.Tally, ended: wp.int32, reach_out: wp.array2d(dtype=t.scalar)):
        i = wp.tid()
        track = w.start()
        if ended != 0:
            track.cell = wp.int32(ESCAPED)
        pending = w.straight_open()
        e = t.vec3(1.0, 0.0, 0.0)
        x = t.vec3(10.0, 0.00125, 0.0)
        h = t.scalar(0.01)
        x1 = x + (h * t.scalar(199.0)) * e
        d0 = (h * t.scalar(199.0)) * e
        track, pending = w.straight_segment(track, tally, pending, x, d0, t.vec3(), x1, d0, t.vec3(), h, t.scalar(199.0), t.scalar(199.0))  # fmt: skip
        track, pending = w.straight_close(track, tally, pending, x1)
        w.write(track, reach_out, i)

    for ended in (0, 1):
        _tally, reach = _run(steps_after, _setup(), precision, device, [ended], 1)
        if ended:
            assert np.isnan(reach).all()
        else:
            np.testing.assert_allclose(reach[0], 10.0 + 0.01 * 199.0, rtol=1e-6)
