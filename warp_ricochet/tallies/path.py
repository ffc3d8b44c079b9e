"""The hazard along a pellet's path (docs/hazard.md section 11), watched inside the core kernel as
the pellet moves: per threshold its reach (the farthest horizontal distance from the shooter at
which it is within body height with a speed at or above the threshold), its passes through the
map's cell columns within body height (counted by their hazard level at entry, integer atomics) and
its passages by the named places (its highest level there, counted once at its end).

Within body height: the pellet's centre at most `body_height` above the hazard's ground plane
(the map's surface, else surface 0), measured along `up`. A path is given to `segment` piece by
piece as quintic Hermite segments in theta in [0, 1] (values x, first and second derivatives
h v and h^2 a at both ends, h the segment's duration): an integration step's own interpolant in air
and along surfaces (`physics.integrate`), and the exact path itself where that is a polynomial of
degree <= 5 (a vacuum flight's parabola, eq. 36; a surface phase of constant acceleration), whose
crossings are then found to rounding. A segment above body height at both ends with no trough is
skipped; one within it at both ends with no crest (and no turn back along the map's axes) is one
part; any other is cut at its height's apex (in vacuum the speed's minimum too) and each piece in
`counts.PATH_PARTS` parts. On a part the height and the speed are taken as monotone: their
crossings of body height and of each threshold's speed are found by bisection on the interpolant.
`line` takes a straight stretch whose speed falls by a known law (rolling with ploughing in vacuum,
`physics.surface_follow.plough_roll`), with its crossings in closed form. The steps of a phase along
a line (`physics.surface_line`) are gathered along their common chord (`tallies.path_chord`,
docs/hazard.md "A phase's steps as one chord"). A flight that escapes is
watched until its centre falls below the ground plane (`escape_time`, `below`, `ground_theta`); a
watch the dense phase ended so (its cell ESCAPED, `dense.watch`) watches nothing more.

A part within body height is walked across the map's cells and tested against the named places
(`tallies.path_cells`). Loops, not unrolled; in CUDA code `segment` and `line` are each
one function that NVRTC does not inline (`out_of_line_on_cuda`), called from every site, so the
watch's code is in the kernel once (bench/RESULTS.md "The watch as one call"); the lanes of a warp
that enter either leave it together (`physics.lanes.meet`: its branches would otherwise leave them
apart for the rest of the pellet, bench/RESULTS.md "Lanes that meet").
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.inlining import out_of_line_on_cuda
from ..physics.integrate import make_dense_output
from ..physics.lanes import lanes_here, meet
from ..physics.types import types_for
from .bins import BINS, make_bin_of
from .landing import copy_of, count_one, make_landing_tally
from .path_cells import ESCAPED, NO_REACH, NONE, make_path_cells, make_path_curve, make_path_walk
from .path_roots import make_path_roots
from .terrain_walk import make_terrain_walk


@functools.cache
def make_path_write(precision: str, thresholds: int, points: int, with_map: bool):
    """`write(track, reach_out, row)`: the pellet's reaches into its row of `reach_out` (m; NaN:
    none), if that is written (nothing without thresholds)."""
    scalar = types_for(precision).scalar
    Track = make_path_cells(precision, thresholds, points, with_map).Track
    K, ON, ZERO = max(thresholds, 1), thresholds > 0, scalar(0.0)

    @wp.func
    def write(track: Track, reach_out: wp.array2d(dtype=scalar), row: wp.int32):
        if wp.static(ON):
            if reach_out.shape[0] > 0:
                for i in range(wp.static(K)):
                    value = track.reach[i]
                    if value < ZERO:
                        value = scalar(wp.nan)
                    reach_out[row, i] = value

    return write


@functools.cache
def make_path_span(precision: str, thresholds: int, points: int, with_map: bool) -> SimpleNamespace:
    """`span(track, tally, gp, gn, start, end, rate, x0, d0, e0, x1, d1, e1, inv_h2)`: watch [start,
    end] of a segment over the ground plane (gp, gn), in parts (`part`); `farther` (a reach at
    least a point's distance)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    cells = make_path_cells(precision, thresholds, points, with_map)
    Track, Tally, Reach = cells.Track, cells.Tally, cells.Reach
    near_places, curve = cells.near_places, make_path_curve(precision, thresholds, points, with_map).curve
    MAP = with_map
    hermite_vec = make_dense_output(precision).hermite_vec
    horizontal_distance = make_landing_tally(precision).horizontal_distance
    r = make_path_roots(precision)
    height_at, speed2_at, height_root, apex, speed_root = r.height_at, r.speed2_at, r.height_root, r.apex, r.speed_root
    height_over = r.height_over
    HAS_POINTS, K = points > 0, max(thresholds, 1)
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def farther(track: Track, tally: Tally, i: wp.int32, x: vec3):
        """reach_i at least the horizontal distance of x from the shooter (`landing.horizontal_distance`)."""
        track.reach[i] = wp.max(track.reach[i], horizontal_distance(tally, x))
        return track

    @wp.func
    def stretch(
        track: Track,
        tally: Tally,
        lo_t: scalar,
        hi_t: scalar,
        xa: vec3,
        xb: vec3,
        va: scalar,
        vb: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
        inv_h2: scalar,
    ):
        """A stretch [lo_t, hi_t] of a segment within body height (its ends xa, xb; their squared
        speeds va, vb; the speed monotone on it): each threshold's reach, its passes across the
        map's cells and by the named places."""
        span = hi_t - lo_t
        far_a = scalar(-1.0)  # the ends' horizontal distances, once a threshold needs them
        far_b = scalar(-1.0)
        lo = Reach()
        hi = Reach()
        for i in range(wp.static(K)):  # (unrolled: lo, hi and the thresholds held in registers)
            target = tally.thresholds2[i]
            lo[i] = ONE
            hi[i] = ZERO  # empty
            if i >= tally.path_thresholds:
                continue
            if va >= target or vb >= target:
                if va >= target and far_a < ZERO:
                    far_a = horizontal_distance(tally, xa)
                if vb >= target and far_b < ZERO:
                    far_b = horizontal_distance(tally, xb)
            if va >= target and vb >= target:
                lo[i] = ZERO
                hi[i] = ONE
                track.reach[i] = wp.max(wp.max(track.reach[i], far_a), far_b)
            elif va >= target or vb >= target:
                theta = speed_root(lo_t, hi_t, target, x0, d0, e0, x1, d1, e1, inv_h2)
                xc, _sc = hermite_vec(theta, x0, d0, e0, x1, d1, e1)
                lam = ZERO
                if span > ZERO:
                    lam = (theta - lo_t) / span
                if va >= target:
                    lo[i] = ZERO
                    hi[i] = lam
                    track.reach[i] = wp.max(track.reach[i], far_a)
                else:
                    lo[i] = lam
                    hi[i] = ONE
                    track.reach[i] = wp.max(track.reach[i], far_b)
                track = farther(track, tally, i, xc)
        if wp.static(MAP):
            track = curve(track, tally, lo_t, hi_t, x0, d0, e0, x1, d1, e1, lo, hi)
        if wp.static(HAS_POINTS):
            track = near_places(track, tally, xa, xb, lo, hi)
        return track

    @wp.func
    def part(
        track: Track,
        tally: Tally,
        gp: vec3,
        gn: vec3,
        a: scalar,
        b: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
        inv_h2: scalar,
    ):
        """One part [a, b] of a segment (height over the plane (gp, gn) and speed monotone on it):
        its stretch within body height (`stretch`)."""
        fa, _ra = height_at(tally, gp, gn, a, x0, d0, e0, x1, d1, e1)
        fb, _rb = height_at(tally, gp, gn, b, x0, d0, e0, x1, d1, e1)
        if fa > ZERO and fb > ZERO:
            track.cell = wp.int32(NONE)
            return track
        lo_t = a
        hi_t = b
        if fa > ZERO:
            track.cell = wp.int32(NONE)  # a pass begins here
            lo_t = height_root(tally, gp, gn, a, b, wp.int32(0), x0, d0, e0, x1, d1, e1)
        if fb > ZERO:
            hi_t = height_root(tally, gp, gn, a, b, wp.int32(1), x0, d0, e0, x1, d1, e1)
        xa, _sa = hermite_vec(lo_t, x0, d0, e0, x1, d1, e1)
        xb, _sb = hermite_vec(hi_t, x0, d0, e0, x1, d1, e1)
        va = speed2_at(lo_t, x0, d0, e0, x1, d1, e1, inv_h2)
        vb = speed2_at(hi_t, x0, d0, e0, x1, d1, e1, inv_h2)
        track = stretch(track, tally, lo_t, hi_t, xa, xb, va, vb, x0, d0, e0, x1, d1, e1, inv_h2)
        if fb > ZERO:
            track.cell = wp.int32(NONE)  # the pass ends here
        return track

    @wp.func
    def turns(tally: Tally, rate: vec3, slope: vec3):
        """1 if the segment's motion along the map's u or v axis (with a map or places) differs in
        sign at the start (its slope `rate` there) and at its end (`slope`: it may turn back
        between), else 0."""
        out = wp.int32(0)
        if wp.static(MAP or HAS_POINTS):
            if wp.dot(rate, tally.map_u_cell) * wp.dot(slope, tally.map_u_cell) <= ZERO:
                out = wp.int32(1)
            if wp.dot(rate, tally.map_v_cell) * wp.dot(slope, tally.map_v_cell) <= ZERO:
                out = wp.int32(1)
        return out

    @wp.func
    def span(
        track: Track,
        tally: Tally,
        gp: vec3,
        gn: vec3,
        start: scalar,
        theta_end: scalar,
        rate: vec3,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
        inv_h2: scalar,
    ):
        """Watch [start, theta_end] of a segment over the ground plane (gp, gn) (`rate`: its slope
        at start): cut at its height's apex, each piece in `tally.path_parts` parts (loops, not
        unrolled: one copy of the part's code wherever a segment is watched). A segment within body
        height throughout in one part is its own stretch, from its ends' values (`stretch`)."""
        x_start, slope_start = hermite_vec(start, x0, d0, e0, x1, d1, e1)
        x_end, slope_end = hermite_vec(theta_end, x0, d0, e0, x1, d1, e1)
        f0, r0 = height_over(tally, gp, gn, x_start), wp.dot(slope_start, gn)  # (`height_at` at both ends)
        f1, r1 = height_over(tally, gp, gn, x_end), wp.dot(slope_end, gn)
        crest = r0 > ZERO and r1 <= ZERO  # the height's maximum inside
        trough = r0 < ZERO and r1 > ZERO  # its minimum inside
        top = theta_end
        pieces = wp.int32(1)
        parts = tally.path_parts
        if f0 > ZERO and f1 > ZERO and not trough:  # above body height throughout
            track.cell = wp.int32(NONE)
            pieces = wp.int32(0)
        elif f0 <= ZERO and f1 <= ZERO and not crest and turns(tally, rate, slope_end) == 0:
            # within it throughout, no turn back along the map's axes: one part, its own stretch
            pieces = wp.int32(0)
            va = wp.dot(slope_start, slope_start) * inv_h2  # (`speed2_at` at both ends)
            vb = wp.dot(slope_end, slope_end) * inv_h2
            track = stretch(track, tally, start, theta_end, x_start, x_end, va, vb, x0, d0, e0, x1, d1, e1, inv_h2)
        elif crest:  # an apex inside: two pieces
            top = apex(tally, gp, gn, start, theta_end, x0, d0, e0, x1, d1, e1)
            pieces = wp.int32(2)
        for j in range(pieces * parts):
            first = start
            end = top
            if j >= parts:
                first = top
                end = theta_end
            width = (end - first) / scalar(parts)
            k = j % parts
            lo = first + scalar(k) * width
            hi = lo + width
            if k == parts - 1:
                hi = end
            track = part(track, tally, gp, gn, lo, hi, x0, d0, e0, x1, d1, e1, inv_h2)
        return track

    return SimpleNamespace(span=span, farther=farther)


@functools.cache
def make_path_lines(precision: str, thresholds: int, points: int, with_map: bool, terrain: bool = False) -> SimpleNamespace:
    """`Track` (a pellet's watch: reach per threshold in m, its level + 1 at each named place, the
    cell of the pass under way) and the functions that update it: `start`, `segment`, `line`,
    `finish`. With no thresholds the functions do nothing (compiled away); `terrain`: the hazard's
    ground is the terrain in `Tally.terrain` (`tallies.terrain_walk`), not its ground plane."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    cells = make_path_cells(precision, thresholds, points, with_map)
    Track, Tally, Reach, flush = cells.Track, cells.Tally, cells.Reach, cells.flush
    chord = make_path_walk(precision, thresholds, points, with_map).chord
    MAP, TERRAIN = with_map, terrain
    terrain = make_terrain_walk(precision, make_path_curve(precision, thresholds, points, with_map).crossing)
    hermite_vec = make_dense_output(precision).hermite_vec
    height = make_path_roots(precision).height
    spans = make_path_span(precision, thresholds, points, with_map)
    span, farther = spans.span, spans.farther
    bin_of = make_bin_of()
    K, P, ON, HAS_POINTS = max(thresholds, 1), max(points, 1), thresholds > 0, points > 0
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def start():
        track = Track()
        if wp.static(ON):
            for i in range(wp.static(K)):
                track.reach[i] = scalar(NO_REACH)
        track.cell = wp.int32(NONE)
        if wp.static(ON and MAP):
            track.run_row = wp.int32(NONE)
        return track

    @wp.func
    def seat(track: Track, tally: Tally, thread: wp.int32):
        """The track with its column of the step log (`physics.line_log`): the launch's `thread`'s
        (one shared column where the log has one: a CPU runs a kernel's threads one after another)."""
        if wp.static(ON):
            track.log_slot = thread % wp.max(tally.log_threads, 1)
        return track

    @wp.func
    def terrain_span(
        track: Track,
        tally: Tally,
        a: scalar,
        b: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
        inv_h2: scalar,
    ):
        """Watch [a, b] of a segment over the terrain: piece by piece across its triangles
        (`tallies.terrain_walk`), each over its plane (`span`)."""
        walk = terrain.begin(tally, a, b, x0, d0, e0, x1, d1, e1)
        for k in range(walk.budget):
            walk = terrain.next_piece(tally, walk, b, x0, d0, e0, x1, d1, e1)
            if k == walk.budget - 1:  # (budget spent, a turning curve: the rest over this plane)
                walk.end = b
            _x, rate = hermite_vec(walk.start, x0, d0, e0, x1, d1, e1)
            track = span(track, tally, walk.gp, walk.gn, walk.start, walk.end, rate, x0, d0, e0, x1, d1, e1, inv_h2)
            if walk.end >= b:
                break
        return track

    @wp.func
    def segment(
        track: Track, tally: Tally, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, h: scalar, theta_end: scalar
    ):
        """Watch the segment's [0, theta_end] (x, h v, h^2 a at theta 0 and 1; h in s): `span` over
        the ground plane, or over a terrain's triangles (`tallies.terrain_walk`); nothing once the
        watch has ended (cell ESCAPED)."""
        if wp.static(ON):
            here = lanes_here()
            if h > ZERO and theta_end > ZERO and track.cell != ESCAPED:
                inv_h2 = ONE / (h * h)
                if wp.static(TERRAIN):
                    first, last = terrain.window(tally, theta_end, x0, d0, e0, x1, d1, e1)
                    for stretch in range(2):  # [0, first], then [last, theta_end]; above body height between
                        a = ZERO
                        b = first
                        if stretch == 1:
                            a = last
                            b = theta_end
                            if first < last:
                                track.cell = wp.int32(NONE)
                        if b > a:
                            track = terrain_span(track, tally, a, b, x0, d0, e0, x1, d1, e1, inv_h2)
                else:
                    track = span(
                        track, tally, tally.ground_point, tally.ground_normal, ZERO, theta_end, d0, x0, d0, e0, x1, d1, e1, inv_h2
                    )
            meet(here)  # the lanes that came in together leave together (`physics.lanes`)
        return track

    @wp.func
    def parabola(track: Track, tally: Tally, x0: vec3, v0: vec3, g: vec3, dt: scalar):
        """Watch the exact flight x0 + v0 t + g t^2 / 2 over [0, dt] (eq. 36)."""
        d0 = dt * v0
        e0 = (dt * dt) * g
        x1 = x0 + d0 + scalar(0.5) * e0
        return segment(track, tally, x0, d0, e0, x1, d0 + e0, e0, dt, ONE)

    @wp.func
    def line_stretch(tally: Tally, length: scalar, v0: scalar, a: scalar, b: scalar):
        """Each threshold's stretch [lo_i, hi_i] of `line`'s (fractions of `length`; lo_i > hi_i:
        never exceeded): from its start to s_i (`line`)."""
        lo = Reach()
        hi = Reach()
        for i in range(wp.static(K)):
            target = tally.thresholds2[i]
            lo[i] = ONE
            hi[i] = ZERO
            if v0 * v0 >= target and length > ZERO:
                s = wp.log((a + b * v0 * v0) / (a + b * target)) / (scalar(2.0) * b)
                lo[i] = ZERO
                hi[i] = wp.min(s / length, ONE)
        return lo, hi

    @wp.func
    def line_watch(track: Track, tally: Tally, x0: vec3, direction: vec3, length: scalar, v0: scalar, a: scalar, b: scalar):
        """`line`'s work (whose one exit, where the lanes meet, is `line`'s)."""
        if wp.static(ON):
            if track.cell == ESCAPED:
                return track
            xb = x0 + length * direction
            ha = height(tally, x0)
            hb = height(tally, xb)
            if wp.static(TERRAIN):  # (its ends' heights over the terrain below them)
                ha = terrain.height(tally, x0)
                hb = terrain.height(tally, xb)
            if ha > ZERO and hb > ZERO:
                track.cell = wp.int32(NONE)
                return track
            lo, hi = line_stretch(tally, length, v0, a, b)
            for i in range(wp.static(K)):
                if lo[i] <= hi[i]:
                    track = farther(track, tally, i, x0)
                    track = farther(track, tally, i, x0 + (hi[i] * length) * direction)
            track = chord(track, tally, x0, xb, lo, hi)
        return track

    @wp.func
    def line(track: Track, tally: Tally, x0: vec3, direction: vec3, length: scalar, v0: scalar, a: scalar, b: scalar):
        """Watch a straight stretch x0 + s direction, s in [0, length], along which the speed falls as
        a + b v^2 = (a + b v0^2) exp(-2 b s) (b > 0): threshold v_i is crossed at
        s_i = ln((a + b v0^2) / (a + b v_i^2)) / (2 b). Nothing once the watch has ended (ESCAPED)."""
        if wp.static(ON):
            here = lanes_here()
            track = line_watch(track, tally, x0, direction, length, v0, a, b)
            meet(here)  # the lanes that came in together leave together (`physics.lanes`)
        return track

    if ON:  # (without a watch both are empty and inlined away)
        out_of_line_on_cuda(segment)
        out_of_line_on_cuda(line)

    @wp.func
    def finish(track: Track, tally: Tally, row: wp.int32):
        """Count the pellet's reaches (histogram rows reach_row + i of its warp's copy, chunk row
        `row`) and its named places (`place_counts`, level x places)."""
        if wp.static(ON):
            if wp.static(MAP):
                track = flush(track, tally)
            first = copy_of(row, tally.copy_mask) * tally.hist_stride
            for i in range(wp.static(K)):
                if track.reach[i] >= ZERO:
                    count_one(tally.hist, first + (tally.reach_row + i) * BINS + bin_of(wp.float32(track.reach[i])))
            if wp.static(HAS_POINTS):
                for p in range(wp.static(P)):
                    if track.places[p] > 0:
                        wp.atomic_add(tally.place_counts, (track.places[p] - 1) * wp.static(P) + p, wp.int32(1))

    return SimpleNamespace(
        write=make_path_write(precision, thresholds, points, with_map),
        Track=Track,
        Tally=Tally,
        Reach=Reach,
        start=start,
        seat=seat,
        segment=segment,
        parabola=parabola,
        line=line,
        finish=finish,
        ON=ON,
    )
