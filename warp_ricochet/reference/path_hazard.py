"""Float64 reference for the hazard along a pellet's whole path (issue 26, docs/hazard.md).

`path_of(follow(...))` turns `surface_motion.follow`'s phases into one path: each phase's SciPy dense
output (DOP853, rtol 1e-12) and, in vacuum, the exact parabola x0 + v0 t + g t^2 / 2 of each flight.
`hazard_of(path, hazard)` then finds by brute force, sampling the path at most every 1 mm (at least
`MIN_SAMPLES` points a phase) and refining every change between two samples by bisection on the
dense output to 1e-15 of the phase's duration:

- reach_i: the largest horizontal distance from the shooter of a point where the centre is within
  body height (its height above the hazard's plane along `up`, h = (x - p).n / (n.up), at most H)
  and the speed is at least v_i; NaN if none;
- passes: each entry of the horizontal position into a map column (a cell, or OUTSIDE off the grid)
  while within body height, a stretch within body height starting in a cell entering it, with its
  level (the number of thresholds its speed reaches) at the entry point; each with the cells and
  levels it could have had under a perturbation of `tolerance` (a length; a speed), whether it
  could be absent, and the near-misses that could add one (`Pass.ghost`);
- points: per named point, the highest level over the stretches where the centre is within the
  person's radius of the point's vertical and within body height (None if never).

Between samples 1 mm apart a function can hide an excursion only near one of its extrema; those of
the height, the grid coordinates, the speed and the distances to the points are refined
(bounded scalar minimisation) wherever a sample lies within a few steps of a level that matters,
and added to the samples. NumPy and SciPy only: no code of the kernels.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .air import derivatives
from .surface_motion import Model, _event, _solve

STEP = 1e-3  # m of path between samples
MIN_SAMPLES = 64  # a phase's samples at least
MAX_SAMPLES = 400_000  # a phase's samples at most (a longer phase is sampled more coarsely)
BISECTIONS = 80  # halvings of a change's interval at most (to the float64 spacing)
RESOLUTION = 1e-13  # m: a change's interval is halved until the pellet moves less than this across it
OUTSIDE = -1  # the column of a position over the plane but off the grid


@dataclasses.dataclass(frozen=True)
class Grid:
    """The map's grid: origin (the shooter projected on the plane), unit axes u and v in the plane,
    the lower corner (u0, v0) m, square cells of `cell` m, nu x nv cells; column iv nu + iu."""

    origin: tuple
    u: tuple
    v: tuple
    u0: float
    v0: float
    cell: float
    nu: int
    nv: int

    def fractional(self, x):
        """(fu, fv): the position's cells from the grid's corner along u and v (float64)."""
        x = np.asarray(x, float) - np.asarray(self.origin, float)
        return (x @ np.asarray(self.u, float) - self.u0) / self.cell, (x @ np.asarray(self.v, float) - self.v0) / self.cell

    def column(self, fu, fv):
        """The column of fractional positions: iv nu + iu, OUTSIDE off the grid."""
        fu, fv = np.asarray(fu, float), np.asarray(fv, float)
        inside = (fu >= 0) & (fv >= 0) & (fu < self.nu) & (fv < self.nv)
        iu, iv = np.floor(np.where(inside, fu, 0)).astype(np.int64), np.floor(np.where(inside, fv, 0)).astype(np.int64)
        return np.where(inside, iv * self.nu + iu, OUTSIDE)


@dataclasses.dataclass(frozen=True)
class Hazard:
    """What the hazard along a path is measured against (SI): the shooter, `up` (unit), the hazard's
    plane (point, normal), the body height H, the threshold speeds in scene order, the grid (or
    None), the named points ((x, y, z), radius m) and a terrain on the plane (None, or a callable
    giving the ground's height above the plane under points: `reference.terrain.TerrainHeight`)."""

    shooter: tuple
    up: tuple
    point: tuple
    normal: tuple
    body_height: float
    speeds: tuple
    grid: Grid | None = None
    points: tuple = ()
    terrain: object = None

    def level(self, speed):
        """The number of thresholds the speed reaches (|v| >= v_i)."""
        return np.sum(np.asarray(speed, float)[..., None] >= np.asarray(self.speeds, float), axis=-1)


class Path:
    """A pellet's path: segments (t0, t1, y) in time order, y(t) -> (x, v) arrays of shape (3, n)
    for t an array in [t0, t1]; positions continuous, velocities jumping at impacts."""

    def __init__(self, segments):
        self.segments = [s for s in segments if s[1] > s[0]]

    def state(self, k, t):
        x, v = self.segments[k][2](np.atleast_1d(np.asarray(t, float)))
        return x.T, v.T

    def length(self, k, samples=257):
        """m: the segment's path length (trapezoid rule on its speed)."""
        t0, t1, _ = self.segments[k]
        t = np.linspace(t0, t1, samples)
        return float(np.trapezoid(np.linalg.norm(self.state(k, t)[1], axis=1), t))


def path_of(result, gravity=(0.0, -9.81, 0.0), vacuum=True) -> Path:
    """The Path of a `surface_motion.follow` result; in `vacuum` each flight is the exact parabola
    from its start (the dense output elsewhere: along the plane, or in air)."""
    g = np.asarray(gravity, float)
    segments = []
    for phase in result.phases:
        for sol in phase.sols:
            t0, t1 = float(sol.t_min), float(sol.t_max)
            if phase.mode == "flight" and vacuum:
                y0 = sol(t0)

                def y(t, x0=y0[0:3], v0=y0[3:6], t0=t0):
                    s = t - t0
                    return x0[:, None] + v0[:, None] * s + 0.5 * g[:, None] * s * s, v0[:, None] + g[:, None] * s

            else:

                def y(t, sol=sol):
                    out = sol(t)
                    return out[0:3], out[3:6]

            segments.append((t0, t1, y))
    return Path(segments)


def parabola(x0, v0, t_end, gravity=(0.0, -9.81, 0.0)) -> Path:
    """The path of a flight in vacuum from x0 with v0 for t_end s (tests' closed forms)."""
    g, x0, v0 = (np.asarray(a, float) for a in (gravity, x0, v0))

    def y(t):
        return x0[:, None] + v0[:, None] * t + 0.5 * g[:, None] * t * t, v0[:, None] + g[:, None] * t

    return Path([(0.0, float(t_end), y)])


def escape_path(x0, v0, omega0, hazard: Hazard, *, radius, density, gravity=(0.0, -9.81, 0.0), air=None, t_max=1e4) -> Path:
    """The path of a flight that meets no surface (an escape; docs/hazard.md section 11) up to where
    its watch stops: its centre's height over the hazard's plane falling through 0, or, if it starts
    below the plane and never comes above it, its height's apex (none if it starts below and
    falling). Found by SciPy's events on `surface_motion`'s flight (DOP853, rtol 1e-12; `air`: a
    `scene.schema.Air`); in vacuum the path is then the exact parabola to there."""
    model = Model(radius, density, gravity, air)
    n, p = np.asarray(hazard.normal, float), np.asarray(hazard.point, float)
    n = n / (n @ np.asarray(hazard.up, float))  # x.n: a height along up

    def height(_t, y):
        return (y[0:3] - p) @ n

    def apex_below(_t, y):  # its height's rate, while below the plane
        return y[3:6] @ n if height(_t, y) < 0.0 else 1.0

    def rhs(_t, y):
        if model.air is None:
            return np.concatenate([y[3:6], model.g, np.zeros(4)])
        return np.concatenate([derivatives(_t, y[:9], model.pellet, model.air, model.g), [0.0]])

    y0 = np.concatenate([np.asarray(x0, float), np.asarray(v0, float), np.asarray(omega0, float), [0.0]])
    if height(0.0, y0) < 0.0 and y0[3:6] @ n <= 0.0:
        return Path([])
    (_i, t_end, _y), sol = _solve(rhs, y0, 0.0, t_max, [_event(height, -1.0), _event(apex_below, -1.0)], 1e-12)
    if model.air is None:
        return parabola(x0, v0, t_end, gravity)

    def y(t):
        out = sol(t)
        return out[0:3], out[3:6]

    return Path([(0.0, float(t_end), y)])


@dataclasses.dataclass
class Pass:
    """An entry into `column` within body height at time t (segment k), at `level`; `columns` and
    `levels` the ones a perturbation by the tolerance could give instead; `absent`: it could be
    missing (a stretch or a cell entered by less than the tolerance); `ghost`: not a pass of the
    path, a near-miss (within the tolerance) that could add one."""

    t: float
    k: int
    column: int
    level: int
    columns: frozenset
    levels: frozenset
    absent: bool = False
    ghost: bool = False

    @property
    def certain(self) -> bool:
        return not self.absent and not self.ghost and len(self.columns) == 1 and len(self.levels) == 1


class _Measures:
    """The functions of the state the hazard needs, vectorised over samples."""

    def __init__(self, hazard: Hazard):
        self.h = hazard
        self.up, self.n, self.p = (np.asarray(a, float) for a in (hazard.up, hazard.normal, hazard.point))
        self.n = self.n / np.linalg.norm(self.n)
        self.shooter = np.asarray(hazard.shooter, float)

    def height(self, x):
        """m, above the ground along up: (x - p).n / (n.up), less the terrain's height there."""
        h = (x - self.p) @ self.n / (self.n @ self.up)
        return h if self.h.terrain is None else h - self.h.terrain(x)

    def distance(self, x, origin=None):
        """m, horizontal (perpendicular to up) from `origin` (the shooter)."""
        d = x - (self.shooter if origin is None else np.asarray(origin, float))
        return np.linalg.norm(d - np.outer(d @ self.up, self.up), axis=1)


def _samples(path: Path, k: int):
    t0, t1, _ = path.segments[k]
    n = int(min(max(math.ceil(path.length(k) / STEP) + 1, MIN_SAMPLES), MAX_SAMPLES))
    return np.linspace(t0, t1, n)


def _extrema(path, k, t, values, function, near, window):
    """Times of the refined interior extrema of `function` (of (x, v) at t) whose sample value
    lies within `window` of a level in `near` (values: the samples)."""
    from scipy.optimize import minimize_scalar

    out = []
    d = np.diff(values)
    close = (
        np.min(np.abs(np.subtract.outer(values, np.asarray(list(near), float))), axis=1) <= window
        if len(near)
        else values < -np.inf
    )
    for sign in (1.0, -1.0):  # minima, then maxima
        for i in np.flatnonzero((sign * d[:-1] < 0) & (sign * d[1:] > 0) & close[1:-1]) + 1:
            r = minimize_scalar(
                lambda s, sign=sign: sign * float(function(*path.state(k, s))[0]),
                bounds=(t[i - 1], t[i + 1]),
                method="bounded",
                options={"xatol": 1e-15 * max(1.0, abs(t[i]))},
            )
            out.append(float(r.x))
    return out


def _bisect(path, k, ta, tb, key, dt=0.0):
    """(t_a', t_b'): the two ends, within float spacing (or BISECTIONS halvings), of one change of
    `key(x, v)` between ta and tb (key(ta) != key(tb)); the change nearest ta where there are several."""
    ka = key(*path.state(k, ta))
    for _ in range(BISECTIONS):
        tm = 0.5 * (ta + tb)
        if tm <= ta or tm >= tb or tb - ta <= dt:
            break
        if key(*path.state(k, tm)) == ka:
            ta = tm
        else:
            tb = tm
    return ta, tb


def _max_over(path, inside, value, samples, arrays=None):
    """The largest `value(x, v)` over the points of the path where `inside(x, v)` holds (NaN if
    none): over the samples in the set, the set's ends refined by bisection, and the refined
    interior maxima of `value`. `samples`: `_sampled`'s; `arrays`: per segment (inside, value) at
    them, when already computed."""
    from scipy.optimize import minimize_scalar

    best = -math.inf
    for k in range(len(path.segments)):
        t, x, v = samples[k]
        ins, val = arrays[k] if arrays is not None else (inside(x, v), value(x, v))
        dt = RESOLUTION / max(np.linalg.norm(v, axis=1).max(), 1e-30)
        if ins.any():
            best = max(best, float(val[ins].max()))
        for j in np.flatnonzero(ins[:-1] != ins[1:]):  # the set's ends: the inside point of each change

            def key(x, v):
                return bool(inside(x, v)[0])

            ta, tb = _bisect(path, k, t[j], t[j + 1], key, dt)
            edge = ta if ins[j] else tb
            xe, ve = path.state(k, edge)
            if inside(xe, ve)[0]:
                best = max(best, float(value(xe, ve)[0]))
        peak = np.flatnonzero(ins[1:-1] & ins[:-2] & ins[2:] & (val[1:-1] >= val[:-2]) & (val[1:-1] >= val[2:])) + 1
        for j in peak:
            r = minimize_scalar(
                lambda s, k=k: -float(value(*path.state(k, s))[0]),
                bounds=(t[j - 1], t[j + 1]),
                method="bounded",
                options={"xatol": 1e-15},
            )
            xr, vr = path.state(k, r.x)
            if inside(xr, vr)[0]:
                best = max(best, float(value(xr, vr)[0]))
    return best if best > -math.inf else math.nan


def _sampled(path: Path, hazard: Hazard):
    """Per segment: (t, x, v) at its samples and at the refined extrema near the levels that matter
    (body height, thresholds, cell edges, point radii), where an excursion could hide between samples."""
    m = _Measures(hazard)
    out = []
    for k in range(len(path.segments)):
        t = _samples(path, k)
        x, v = path.state(k, t)
        step = np.max(np.linalg.norm(np.diff(x, axis=0), axis=1)) if len(t) > 1 else 0.0
        window = 3.0 * step + 1e-12
        found = []
        found += _extrema(path, k, t, m.height(x), lambda x, v: m.height(x), [hazard.body_height], window)
        speed = np.linalg.norm(v, axis=1)
        jump = 3.0 * np.max(np.abs(np.diff(speed))) if len(t) > 1 else 0.0
        found += _extrema(path, k, t, speed, lambda x, v: np.linalg.norm(v, axis=1), hazard.speeds, jump)
        if hazard.grid is not None:
            fu, fv = hazard.grid.fractional(x)
            for i, f in enumerate((fu, fv)):
                near = np.round(f)
                found += _extrema(
                    path,
                    k,
                    t,
                    f - near,
                    lambda x, v, i=i, near=near: hazard.grid.fractional(x)[i] - np.round(hazard.grid.fractional(x)[i]),
                    [0.0],
                    window / hazard.grid.cell,
                )
        for position, radius in hazard.points:
            found += _extrema(path, k, t, m.distance(x, position), lambda x, v, p=position: m.distance(x, p), [radius], window)
        if found:
            t = np.concatenate([t, found])
            x, v = np.concatenate([x, path.state(k, found)[0]]), np.concatenate([v, path.state(k, found)[1]])
            t, first = np.unique(t, return_index=True)
            x, v = x[first], v[first]
        out.append((t, x, v))
    return out


def reach(path: Path, hazard: Hazard, samples=None) -> np.ndarray:
    """reach_i (m) per threshold in scene order, NaN where the pellet is never within body height
    at or above v_i."""
    m = _Measures(hazard)
    samples = _sampled(path, hazard) if samples is None else samples
    measured = [(m.height(x), np.linalg.norm(v, axis=1), m.distance(x)) for _t, x, v in samples]
    out = []
    for speed in hazard.speeds:

        def inside(x, v, speed=speed):
            return (m.height(x) <= hazard.body_height) & (np.linalg.norm(v, axis=1) >= speed)

        arrays = [((h <= hazard.body_height) & (speed_ >= speed), d) for h, speed_, d in measured]
        out.append(_max_over(path, inside, lambda x, v: m.distance(x), samples, arrays))
    return np.asarray(out)


def point_levels(path: Path, hazard: Hazard, samples=None) -> list:
    """Per named point: the highest level over the path's stretches within the point's radius of its
    vertical and within body height (None if it never comes there)."""
    m = _Measures(hazard)
    samples = _sampled(path, hazard) if samples is None else samples
    out = []
    for position, radius in hazard.points:

        def inside(x, v, position=position, radius=radius):
            return (m.height(x) <= hazard.body_height) & (m.distance(x, position) <= radius)

        top = _max_over(path, inside, lambda x, v: np.linalg.norm(v, axis=1), samples)
        out.append(None if math.isnan(top) else int(hazard.level(top)))
    return out


def _state(m: _Measures, hazard: Hazard, x):
    """Per sample: the column the centre is in while within body height, else None (as -2)."""
    fu, fv = hazard.grid.fractional(x)
    return np.where(m.height(x) <= hazard.body_height, hazard.grid.column(fu, fv), -2)


def _depth(m: _Measures, hazard: Hazard, x, state):
    """m: how far inside its region (within body height in its column; or above body height) each
    sample is, the smallest perturbation of its position that would change its state."""
    g, up = hazard.grid, m.h.body_height - m.height(x)
    fu, fv = g.fractional(x)
    iu, iv = np.floor(fu), np.floor(fv)
    in_cell = g.cell * np.minimum.reduce([fu - iu, iu + 1 - fu, fv - iv, iv + 1 - fv])
    off_grid = g.cell * np.maximum.reduce([-fu, fu - g.nu, -fv, fv - g.nv])
    return np.where(state == -2, -up, np.minimum(up, np.where(state == OUTSIDE, off_grid, in_cell)))


def _changes(key, ta, tb, sa, sb, out, dt, depth=BISECTIONS):
    """Every change of key(t) between ta and tb seen by recursive halving to dt: (t, new state) in order."""
    tm = 0.5 * (ta + tb)
    if depth == 0 or tm <= ta or tm >= tb or tb - ta <= dt:
        out.append((tb, sb))
        return
    sm = key(tm)
    if sm != sa:
        _changes(key, ta, tm, sa, sm, out, dt, depth - 1)
    if sm != sb:
        _changes(key, tm, tb, sm, sb, out, dt, depth - 1)


def _around(hazard: Hazard, x, du, dv):
    """The columns of the points (fu +- du, fv +- dv) about x (cells)."""
    fu, fv = hazard.grid.fractional(x[None])
    return frozenset(int(c) for a in (-du, 0.0, du) for b in (-dv, 0.0, dv) for c in hazard.grid.column(fu + a, fv + b))


def _levels(hazard: Hazard, speed, dv):
    return frozenset(range(int(hazard.level(speed - dv)), int(hazard.level(speed + dv)) + 1))


def passes(path: Path, hazard: Hazard, tolerance=(0.0, 0.0), samples=None) -> list:
    """The path's passes (module docstring) and, with a tolerance (dx m, dv m/s), the near-misses
    within it as ghost passes; in time order."""
    m, g = _Measures(hazard), hazard.grid
    dx, dv = tolerance
    samples = _sampled(path, hazard) if samples is None else samples
    stretches = []  # (t, k, state, x, v): the start of each stretch of one state
    depth = []  # the deepest sample of each stretch
    ghosts = []
    for k in range(len(path.segments)):
        t, x, v = samples[k]
        s = _state(m, hazard, x)
        d = _depth(m, hazard, x, s)
        dt = RESOLUTION / max(np.linalg.norm(v, axis=1).max(), 1e-30)

        def key(tm, k=k):
            return int(_state(m, hazard, path.state(k, tm)[0])[0])

        if not stretches or stretches[-1][2] != s[0]:
            stretches.append((t[0], k, int(s[0]), x[0], v[0]))
            depth.append(-math.inf)
        for j in range(len(t)):
            if j and s[j] != s[j - 1]:
                found = []
                _changes(key, t[j - 1], t[j], int(s[j - 1]), int(s[j]), found, dt)
                for tc, sc in found:
                    xc, vc = path.state(k, tc)
                    stretches.append((tc, k, sc, xc[0], vc[0]))
                    depth.append(-math.inf)
            depth[-1] = max(depth[-1], d[j])
        # near-misses: a local extremum of the depth that stays within dx of a change (not made)
        same = (s[1:-1] == s[:-2]) & (s[1:-1] == s[2:])  # (a change's neighbours are near it, not near-misses)
        near = np.flatnonzero(same & (d[1:-1] < d[:-2]) & (d[1:-1] <= d[2:]) & (d[1:-1] > 0) & (d[1:-1] <= dx)) + 1
        for j in near:  # into the columns about it (a stretch within body height starting, or a neighbour) and back
            here = {int(s[j])} if s[j] != -2 else set()
            speed = np.linalg.norm(v[j])
            for col in sorted(_around(hazard, x[j], dx / g.cell, dx / g.cell) - here) + sorted(here):
                level = int(hazard.level(speed))
                ghosts.append(Pass(t[j], k, col, level, frozenset([col]), _levels(hazard, speed, dv), ghost=True))
    out = []
    for i, (t, k, state, x, v) in enumerate(stretches):
        if state == -2:
            continue
        speed = float(np.linalg.norm(v))
        spread = dx / g.cell
        du = dvv = spread
        if i and stretches[i - 1][2] != -2:  # across an edge (the entry lies on it): the other coordinate only
            f = np.concatenate(g.fractional(x[None]))
            on_edge = np.abs(f - np.round(f)) * g.cell <= 1e-9 * (1.0 + np.abs(x).max())
            if on_edge.sum() == 1:  # (at a corner both)
                du, dvv = (0.0 if on_edge[0] else spread), (0.0 if on_edge[1] else spread)
        cols = _around(hazard, x, du, dvv)
        shallow = bool(depth[i] < dx or (i > 0 and depth[i - 1] < dx))
        out.append(
            Pass(t, k, int(state), int(hazard.level(speed)), cols | {int(state)}, _levels(hazard, speed, dv), absent=shallow)
        )
    return sorted(out + ghosts, key=lambda p: p.t)


@dataclasses.dataclass
class PathHazard:
    """What `hazard_of` finds on one path."""

    reach: np.ndarray  # m, per threshold (scene order), NaN: none
    reach_low: np.ndarray  # the reach with the body height lowered and the thresholds raised by the rounding
    reach_high: np.ndarray  # ... raised and lowered
    passes: list  # Pass, in time order (ghosts included)
    points: list  # per named point: its highest level, or None
    length: float  # m, the path's length


def hazard_of(path: Path, hazard: Hazard, tolerance=(0.0, 0.0), rounding=(0.0, 0.0), samples=None) -> PathHazard:
    """The reach, passes (with `tolerance`) and point levels of a path; the reach again with the body
    height and thresholds moved by `rounding` (dx m, dv m/s) against and for the pellet, whose
    spread shows a reach a rounding could move by more than that (a stretch grazing body height).
    `samples`: `_sampled(path, hazard)` when already made (they depend on neither)."""
    samples = _sampled(path, hazard) if samples is None else samples
    moved = [
        reach(
            path,
            dataclasses.replace(
                hazard, body_height=hazard.body_height + s * rounding[0], speeds=tuple(np.add(hazard.speeds, -s * rounding[1]))
            ),
            samples,
        )
        for s in (-1.0, 1.0)
    ]
    return PathHazard(
        reach=reach(path, hazard, samples),
        reach_low=moved[0],
        reach_high=moved[1],
        passes=passes(path, hazard, tolerance, samples) if hazard.grid is not None else [],
        points=point_levels(path, hazard, samples),
        length=sum(path.length(k) for k in range(len(path.segments))),
    )
