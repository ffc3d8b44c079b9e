"""The watch of a surface phase's steps along one line (`physics.surface_line`: each step the time
Hermite of its ends), gathered along their common chord (docs/hazard.md, "A phase's steps as one
chord"). With a map (`STRAIGHT`) each threshold's stretch is an interval of the chord, whose reach
and walk across the map's cells are taken once where the phase ends. For the reach alone (`LIGHT`:
no map, no named places, no terrain) a step is looked at only where something changes: where the
chord begins, where the speed jumps or crosses a threshold's, where the chord ends. Else each step is
watched at once (`tallies.path`'s `segment`)."""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.inlining import out_of_line_on_cuda
from ..physics.lanes import lanes_here, meet
from ..physics.types import types_for
from .landing import make_landing_tally
from .path import make_path_lines, make_path_span
from .path_cells import ESCAPED, make_path_cells, make_path_walk
from .path_roots import make_path_roots


@functools.cache
def make_path_pending(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """`Straight` (the steps of a phase along a line whose watch waits) and `straight_open`,
    `straight_add`, `straight_close` (`make_path_straight`)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    cells = make_path_cells(precision, thresholds, points, with_map)
    Track, Tally, Reach = cells.Track, cells.Tally, cells.Reach
    walk_chord = make_path_walk(precision, thresholds, points, with_map).walk
    farther = make_path_span(precision, thresholds, points, with_map).farther
    horizontal_distance = make_landing_tally(precision).horizontal_distance
    K, ON, MAP, TERRAIN = max(thresholds, 1), thresholds > 0, with_map, terrain
    ZERO, ONE = scalar(0.0), scalar(1.0)

    # With a map, a phase's consecutive steps along one line (`straight_*`): each threshold's stretch
    # one interval of their chord, its reach (at the interval's ends) and its walk across the map's
    # cells taken where the phase ends; a step only adds its levels to theirs. Not over a terrain (its
    # height is not linear along a chord), nor for named places without a map: each step at once (`segment`).
    # For the reach alone (`LIGHT`: no map, no named places, no terrain) the steps need no more than
    # their end's squared speed: each threshold's reach is marked where the chord begins, where a step
    # crosses its speed and where the chord ends (`make_path_light`).
    STRAIGHT = ON and MAP and not TERRAIN
    LIGHT = ON and not MAP and points == 0 and not TERRAIN
    fields = {"length": scalar}  # m along the chord (< 0: none pending; for the reach alone >= 0 pending)
    if STRAIGHT:
        fields.update({"a": vec3, "b": vec3, "lo": Reach, "hi": Reach})  # its ends; threshold i's [lo_i, hi_i] (m)
    if LIGHT:
        fields.update({"speed2": scalar})  # m^2/s^2, the squared speed where the pending steps end
    Straight = wp.struct(
        type(
            "Straight",
            (),
            {"__annotations__": fields, "__module__": __name__, "__qualname__": "make_path_pending.<locals>.Straight"},
        )
    )

    @wp.func
    def straight_open():
        """No steps pending."""
        pending = Straight()
        pending.length = scalar(-1.0)
        return pending

    @wp.func
    def mark(track: Track, tally: Tally, x: vec3, v2: scalar):
        """Each threshold exceeded at squared speed v2 (m^2/s^2) reaches at least x's horizontal
        distance from the shooter (computed once)."""
        far = scalar(-1.0)
        for i in range(wp.static(K)):
            if v2 >= tally.thresholds2[i]:
                if far < ZERO:
                    far = horizontal_distance(tally, x)
                track.reach[i] = wp.max(track.reach[i], far)
        return track

    @wp.func
    def straight_settle(track: Track, tally: Tally, pending: Straight):
        """The pending steps' reach (the farthest of each interval's ends: the distance from the
        shooter is convex along a line) and their walk across the map's cells; then none pending."""
        if wp.static(STRAIGHT):
            if pending.length >= ZERO and track.cell != ESCAPED:
                lo = Reach()
                hi = Reach()
                for i in range(wp.static(K)):
                    lo[i] = ONE
                    hi[i] = ZERO
                    if pending.lo[i] <= pending.hi[i]:
                        lo[i] = ZERO
                        hi[i] = ZERO
                        if pending.length > ZERO:
                            lo[i] = wp.min(pending.lo[i] / pending.length, ONE)
                            hi[i] = wp.min(pending.hi[i] / pending.length, ONE)
                        track = farther(track, tally, i, pending.a + lo[i] * (pending.b - pending.a))
                        track = farther(track, tally, i, pending.a + hi[i] * (pending.b - pending.a))
                if wp.static(MAP):
                    track = walk_chord(track, tally, pending.a, pending.b, lo, hi)
        pending.length = scalar(-1.0)
        return track, pending

    @wp.func
    def straight_close(track: Track, tally: Tally, pending: Straight, x: vec3):
        """`straight_settle` (before any other watch of the pellet, and where the phase ends; x:
        where the pending steps end); for the reach alone, the pending steps' end marked (`mark`)."""
        if wp.static(STRAIGHT or LIGHT):
            here = lanes_here()
            if wp.static(STRAIGHT):
                track, pending = straight_settle(track, tally, pending)
            if wp.static(LIGHT):
                if pending.length >= ZERO and track.cell != ESCAPED:
                    track = mark(track, tally, x, pending.speed2)
                pending.length = scalar(-1.0)
            meet(here)  # the lanes that came in together leave together (`physics.lanes`)
        return track, pending

    @wp.func
    def straight_add(track: Track, tally: Tally, pending: Straight, x0: vec3, xb: vec3, length: scalar, lo: Reach, hi: Reach):
        """Add a step's chord x0 -> xb (`length` m; threshold i exceeded on [lo_i, hi_i] of it) to
        the pending steps', whose chord it continues; where a threshold would be exceeded again
        after it was not (its interval would have a gap), theirs settled first and a new chord
        begun. Returns (track, pending)."""
        s0 = pending.length
        for i in range(wp.static(K)):
            if lo[i] <= hi[i] and pending.lo[i] <= pending.hi[i] and pending.hi[i] < s0 + lo[i] * length:
                s0 = scalar(-1.0)
        if s0 < ZERO:
            if pending.length >= ZERO:
                track, pending = straight_close(track, tally, pending, x0)
            s0 = ZERO
            pending.a = x0
            for i in range(wp.static(K)):
                pending.lo[i] = ONE
                pending.hi[i] = ZERO
        for i in range(wp.static(K)):
            if lo[i] <= hi[i]:
                if pending.lo[i] > pending.hi[i]:
                    pending.lo[i] = s0 + lo[i] * length
                pending.hi[i] = s0 + hi[i] * length
        pending.length = s0 + wp.max(length, ZERO)
        pending.b = xb
        return track, pending

    if STRAIGHT or LIGHT:
        out_of_line_on_cuda(straight_close)
    return SimpleNamespace(
        Straight=Straight,
        mark=mark,
        straight_open=straight_open,
        straight_add=straight_add,
        straight_close=straight_close,
        STRAIGHT=STRAIGHT,
        LIGHT=LIGHT,
    )


@functools.cache
def make_path_light(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """`light_segment`: the reach alone of a phase's steps along a line (`make_path_pending`'s
    `LIGHT`). Each threshold's stretches along the chord begin or end where the chord begins, where
    the speed jumps between steps, where a step crosses its speed, or where the chord ends
    (`straight_close`); the distance from the shooter is convex along a line, so those points carry
    the stretches' reach. A step needs one look at its end speeds (the integrator's)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    cells = make_path_cells(precision, thresholds, points, with_map)
    Track, Tally = cells.Track, cells.Tally
    lines = make_path_lines(precision, thresholds, points, with_map, terrain)
    segment, farther = lines.segment, make_path_span(precision, thresholds, points, with_map).farther
    pending_of = make_path_pending(precision, thresholds, points, with_map, terrain)
    Straight, straight_close, mark = pending_of.Straight, pending_of.straight_close, pending_of.mark
    roots = make_path_roots(precision)
    height, chord_root = roots.height, roots.chord_root
    K = max(thresholds, 1)
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def changes(pending: Straight, v02: scalar, v12: scalar, tally: Tally):
        """Whether a step from squared speed v02 to v12 (m^2/s^2) begins a chord, starts at another
        speed than the pending steps end, or crosses a threshold's speed."""
        out = pending.length < ZERO or v02 != pending.speed2
        for i in range(wp.static(K)):
            target = tally.thresholds2[i]
            if (v02 >= target) != (v12 >= target):
                out = True
        return out

    @wp.func
    def begin_mark(track: Track, tally: Tally, pending: Straight, x0: vec3, v02: scalar):
        """A step's start x0 (squared speed v02) marked where a chord begins, or where the speed
        jumps between steps (up: stretches begin there; down: they end there, at the faster of the
        two speeds). Returns (track, pending), a chord pending."""
        if pending.length < ZERO:
            track = mark(track, tally, x0, v02)
        elif v02 != pending.speed2:
            track = mark(track, tally, x0, wp.max(v02, pending.speed2))
        pending.length = ZERO
        return track, pending

    @wp.func
    def light_cross(
        track: Track, tally: Tally, pending: Straight, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, h: scalar, v0: scalar, v1: scalar
    ):  # fmt: skip
        """`light_segment`'s step where something changes: its start marked (`begin_mark`); each
        threshold whose speed it crosses marked at the crossing on its Hermite (`chord_root`).
        Returns (track, pending)."""
        here = lanes_here()
        v02 = v0 * v0
        v12 = v1 * v1
        track, pending = begin_mark(track, tally, pending, x0, v02)
        for i in range(wp.static(K)):
            target = tally.thresholds2[i]
            if (v02 >= target) != (v12 >= target):
                s, u = chord_root(target, x0, d0, e0, x1, d1, e1, h)
                track = farther(track, tally, i, x0 + s * u)
        meet(here)  # the lanes that came in together leave together (`physics.lanes`)
        return track, pending

    @wp.func
    def light_segment(
        track: Track, tally: Tally, pending: Straight, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, h: scalar, v0: scalar, v1: scalar
    ):  # fmt: skip
        """`straight_segment` for the reach alone (v0, v1: its end speeds, m/s; its speed taken
        monotone): moving on along the line and within body height at both ends, pending
        (`light_cross` where something changes); else the pending steps closed and the step
        watched alone (`segment`). Returns (track, pending)."""
        if track.cell != ESCAPED and h > ZERO:
            v12 = v1 * v1
            on = wp.dot(d0, x1 - x0) > ZERO and wp.dot(d1, x1 - x0) >= ZERO
            if on and height(tally, x0) <= ZERO and height(tally, x1) <= ZERO:
                if changes(pending, v0 * v0, v12, tally):
                    track, pending = light_cross(track, tally, pending, x0, d0, e0, x1, d1, e1, h, v0, v1)
                pending.speed2 = v12
            else:
                track, pending = straight_close(track, tally, pending, x0)
                track = segment(track, tally, x0, d0, e0, x1, d1, e1, h, ONE)
        return track, pending

    return SimpleNamespace(light_segment=light_segment)


@functools.cache
def make_path_straight(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """`straight_segment`: the watch of a phase's steps along a line, gathered (`make_path_pending`)
    with a map or for the reach alone (`make_path_light`), else each at once (`segment` of
    `make_path_lines`)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    cells = make_path_cells(precision, thresholds, points, with_map)
    Track, Tally, Reach, near_places = cells.Track, cells.Tally, cells.Reach, cells.near_places
    lines = make_path_lines(precision, thresholds, points, with_map, terrain)
    segment = lines.segment
    pending_of = make_path_pending(precision, thresholds, points, with_map, terrain)
    Straight, straight_add, straight_close, STRAIGHT, LIGHT = (
        pending_of.Straight, pending_of.straight_add, pending_of.straight_close, pending_of.STRAIGHT, pending_of.LIGHT
    )  # fmt: skip
    light = make_path_light(precision, thresholds, points, with_map, terrain)
    roots = make_path_roots(precision)
    height, speed2_at, chord_root = roots.height, roots.speed2_at, roots.chord_root
    K, HAS_POINTS = max(thresholds, 1), points > 0
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def straight_crossing(
        track: Track, tally: Tally, pending: Straight, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, h: scalar
    ):
        """`straight_segment`'s step across a threshold's speed, or above body height at an end:
        within it at both ends, its levels (the crossings by `chord_root`) added to the pending
        steps'; else theirs settled, then `segment`. Returns (track, pending)."""
        here = lanes_here()
        merged = wp.int32(0)
        if height(tally, x0) <= ZERO and height(tally, x1) <= ZERO:
            merged = wp.int32(1)
            inv_h2 = ONE / (h * h)
            va = speed2_at(ZERO, x0, d0, e0, x1, d1, e1, inv_h2)
            vb = speed2_at(ONE, x0, d0, e0, x1, d1, e1, inv_h2)
            length = wp.length(x1 - x0)
            lo = Reach()
            hi = Reach()
            for i in range(wp.static(K)):  # (as `span`'s one part over [0, 1]; unrolled, as there)
                target = tally.thresholds2[i]
                lo[i] = ONE
                hi[i] = ZERO  # empty
                if i >= tally.path_thresholds:
                    continue
                if va >= target and vb >= target:
                    lo[i] = ZERO
                    hi[i] = ONE
                elif va >= target or vb >= target:
                    lam = ZERO
                    if length > ZERO:
                        s, _u = chord_root(target, x0, d0, e0, x1, d1, e1, h)
                        lam = wp.clamp(s / length, ZERO, ONE)
                    if va >= target:
                        lo[i] = ZERO
                        hi[i] = lam
                    else:
                        lo[i] = lam
                        hi[i] = ONE
            track, pending = straight_add(track, tally, pending, x0, x1, length, lo, hi)
            if wp.static(HAS_POINTS):
                track = near_places(track, tally, x0, x1, lo, hi)
        meet(here)  # the lanes that came in together leave together (`physics.lanes`)
        if merged == 0:
            track, pending = straight_close(track, tally, pending, x0)
            track = segment(track, tally, x0, d0, e0, x1, d1, e1, h, ONE)
        return track, pending

    @wp.func
    def straight_segment(
        track: Track, tally: Tally, pending: Straight, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, h: scalar, v0: scalar, v1: scalar
    ):  # fmt: skip
        """`segment` of one step of a phase along a line (the time Hermite of its ends along it,
        moving on along it at both ends; its speed taken monotone): within body height at both
        ends (over the ground plane: throughout) and across no threshold's speed, its levels (each
        threshold exceeded throughout or nowhere) added to the pending steps'; else
        `straight_crossing`. For the reach alone `light_segment` (v0, v1: its end speeds, m/s);
        without either, `segment`. Returns (track, pending)."""
        if wp.static(LIGHT):
            return light.light_segment(track, tally, pending, x0, d0, e0, x1, d1, e1, h, v0, v1)
        if wp.static(not STRAIGHT):
            return segment(track, tally, x0, d0, e0, x1, d1, e1, h, ONE), pending
        if wp.static(STRAIGHT):
            if track.cell != ESCAPED and h > ZERO:
                forward = wp.dot(d0, x1 - x0) > ZERO and wp.dot(d1, x1 - x0) >= ZERO
                if not forward:
                    track, pending = straight_close(track, tally, pending, x0)
                    track = segment(track, tally, x0, d0, e0, x1, d1, e1, h, ONE)
                    return track, pending
                inv_h2 = ONE / (h * h)
                va = wp.dot(d0, d0) * inv_h2  # (the Hermite's slopes at its ends)
                vb = wp.dot(d1, d1) * inv_h2
                quick = height(tally, x0) <= ZERO and height(tally, x1) <= ZERO
                lo = Reach()
                hi = Reach()
                for i in range(wp.static(K)):
                    target = tally.thresholds2[i]
                    lo[i] = ONE
                    hi[i] = ZERO
                    if va >= target and vb >= target:
                        lo[i] = ZERO
                        hi[i] = ONE
                    elif va >= target or vb >= target:
                        quick = False
                if quick:
                    track, pending = straight_add(track, tally, pending, x0, x1, wp.length(x1 - x0), lo, hi)
                    if wp.static(HAS_POINTS):
                        track = near_places(track, tally, x0, x1, lo, hi)
                else:
                    track, pending = straight_crossing(track, tally, pending, x0, d0, e0, x1, d1, e1, h)
        return track, pending

    return SimpleNamespace(straight_segment=straight_segment)


@functools.cache
def make_path_watch(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """`make_path_lines`' watch (`Track`, `start`, `segment`, `line`, `finish`, ...) with the
    steps of a phase along a line (`Straight`, `straight_open`, `straight_segment`,
    `straight_close`)."""
    pending = make_path_pending(precision, thresholds, points, with_map, terrain)
    return SimpleNamespace(
        **vars(make_path_lines(precision, thresholds, points, with_map, terrain)),
        **vars(make_path_straight(precision, thresholds, points, with_map, terrain)),
        Straight=pending.Straight,
        straight_open=pending.straight_open,
        straight_close=pending.straight_close,
    )
