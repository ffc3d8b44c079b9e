"""The map's cells and the named places a watched path passes (`tallies.path`): a pellet's `Track`,
its passes counted into the cell columns within body height by their hazard level at entry (integer
atomics) and its passages by the named places.

A part within body height is walked across the map's cells along its curve (`make_path_curve`:
row by row along the axis it moves farther along, each edge of the other axis crossed found by
Newton's steps in the bracket; a straight stretch by Amanatides & Woo, Eurographics 1987, its cells
along a row at one level taken at once, `make_path_walk`): a cell entered is counted once, with the
level at its entry, the region off the grid being one more cell. Consecutive entries along a map row
at one level are counted as one run (`flush`: +1 and -1 at its ends in `exposure_runs`, summed along
the rows by `landing.runs_kernel` after each chunk). The part's chord's nearest approach to each named
place's vertical is tested against the place's radius.
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.ballistic import EPSILON
from ..physics.integrate import make_dense_output
from ..physics.types import types_for
from .landing import make_landing_tally

NONE = -1  # the cell of a pellet above body height (no pass under way)
ESCAPED = -2  # the cell of a pellet whose watch has ended for good (an escape in the dense phase)
NO_REACH = -1.0  # a reach not yet found (reported as NaN)


@functools.cache
def make_path_cells(precision: str, thresholds: int, points: int, with_map: bool) -> SimpleNamespace:
    """`Track` (a pellet's watch) and the functions that count its passes into the map's cells
    (`enter`, `flush`) and by the named places (`near_places`), at their levels (`level_at`)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    Tally = make_landing_tally(precision).Tally
    K, P, MAP = max(thresholds, 1), max(points, 1), with_map
    HAS_POINTS = points > 0
    Reach = wp.types.vector(length=K, dtype=scalar)
    Levels = wp.types.vector(length=P, dtype=wp.int32)
    ZERO, ONE = scalar(0.0), scalar(1.0)

    # The members the watch uses, and no others (a byte of it cost the CUDA kernel's stack ~10 bytes,
    # even where nothing is watched: bench/RESULTS.md "The watch as one call"):
    fields = {"cell": wp.int32}  # the map column of the pass under way (NONE: above body height; ESCAPED)
    if thresholds > 0:
        fields["reach"] = Reach  # m, per threshold in scene order (NO_REACH: none yet)
        fields["log_slot"] = wp.int32  # its thread's column of the step log (`physics.line_log`)
        if MAP:
            fields["run_row"] = wp.int32  # the pending run of entries (`enter`): its row (NONE: no run)
            fields["run_lo"] = wp.int32  # its first and last cell along u
            fields["run_hi"] = wp.int32
            fields["run_level"] = wp.int32  # the level of its entries
        if HAS_POINTS:
            fields["places"] = Levels  # per named place: 1 + its highest level there (0: never there)
    Track = wp.struct(
        type("Track", (), {"__annotations__": fields, "__module__": __name__, "__qualname__": "make_path_cells.<locals>.Track"})
    )

    @wp.func
    def level_at(lo: Reach, hi: Reach, lam: scalar):
        """The thresholds exceeded at chord parameter lam (threshold i on [lo_i, hi_i])."""
        level = wp.int32(0)
        for i in range(wp.static(K)):  # (a straight stretch's: a few call sites)
            if lo[i] <= lam and lam <= hi[i]:
                level += 1
        return level

    @wp.func
    def level_bound(lo: Reach, hi: Reach, lam: scalar):
        """The least chord parameter past lam at which `level_at` may change: a cell entered at a
        parameter from lam up to (not at) it has lam's level. 2 where none comes."""
        bound = scalar(2.0)
        for i in range(wp.static(K)):
            if lo[i] <= hi[i]:  # (an empty stretch never counts)
                if lo[i] > lam:
                    bound = wp.min(bound, lo[i])
                if hi[i] >= lam:
                    bound = wp.min(bound, hi[i])
        return bound

    @wp.func
    def column_of(tally: Tally, iu: wp.int32, iv: wp.int32):
        """The map column of cell (iu, iv): the cell, or the off-grid column."""
        column = tally.map_cells
        if iu >= 0 and iv >= 0 and iu < tally.map_nu and iv < wp.int32(tally.map_nv_cells):
            column = iv * tally.map_nu + iu
        return column

    @wp.func
    def flush(track: Track, tally: Tally):
        """Count the pending run: one entry into each of its cells (a cell alone into `exposure`,
        a longer run as +1 and -1 at its ends in its row of `exposure_runs`)."""
        if track.run_row != NONE:
            row = track.run_row
            if track.run_lo == track.run_hi:
                column = row * tally.map_nu + track.run_lo
                wp.atomic_add(tally.exposure, track.run_level * tally.map_width + column, wp.int32(1))
            else:
                first = (track.run_level * wp.int32(tally.map_nv_cells) + row) * (tally.map_nu + 1)
                wp.atomic_add(tally.exposure_runs, first + track.run_lo, wp.int32(1))
                wp.atomic_add(tally.exposure_runs, first + track.run_hi + 1, wp.int32(-1))
            track.run_row = wp.int32(NONE)
        return track

    @wp.func
    def enter(track: Track, tally: Tally, iu: wp.int32, iv: wp.int32, level: wp.int32):
        """Count a pass into cell (iu, iv)'s column (if it is not the one under way): off the grid
        at once, else into the pending run when it extends it along its row at its level."""
        column = column_of(tally, iu, iv)
        if column != track.cell:
            track.cell = column
            if column == tally.map_cells:
                wp.atomic_add(tally.exposure, level * tally.map_width + column, wp.int32(1))
            elif track.run_row == iv and track.run_level == level and (iu == track.run_hi + 1 or iu == track.run_lo - 1):
                track.run_lo = wp.min(track.run_lo, iu)
                track.run_hi = wp.max(track.run_hi, iu)
            else:
                track = flush(track, tally)
                track.run_row = iv
                track.run_lo = iu
                track.run_hi = iu
                track.run_level = level
        return track

    @wp.func
    def cell_index(f: scalar, n: scalar, step: wp.int32):
        """The cell along one axis of grid coordinate f (clamped off the grid to -1 or n) that a
        motion of sign `step` is in just after f: on an edge, the one it moves into."""
        cell = wp.floor(f)
        if step < 0:
            cell = wp.ceil(f) - scalar(1.0)
        return wp.int32(wp.clamp(cell, scalar(-1.0), n))

    @wp.func
    def near_places(track: Track, tally: Tally, xa: vec3, xb: vec3, lo: Reach, hi: Reach):
        """The named places the chord xa -> xb comes within their radius of (horizontally): its
        highest level on the stretch inside each place's circle."""
        for p in range(wp.static(P)):
            a = xa - tally.place_position[p]
            d = xb - xa
            a = a - wp.dot(a, tally.up) * tally.up
            d = d - wp.dot(d, tally.up) * tally.up
            dd = wp.dot(d, d)
            ad = wp.dot(a, d)
            c = wp.dot(a, a) - tally.place_radius2[p]
            lam_in = ZERO
            lam_out = ZERO
            inside = wp.int32(0)
            if dd > ZERO:
                disc = ad * ad - dd * c
                if disc >= ZERO:
                    root = wp.sqrt(disc)
                    lam_in = wp.max((-ad - root) / dd, ZERO)
                    lam_out = wp.min((-ad + root) / dd, ONE)
                    if lam_in <= lam_out:
                        inside = 1
            elif c <= ZERO:
                inside = 1
                lam_out = ONE
            if inside != 0:
                level = wp.max(level_at(lo, hi, lam_in), level_at(lo, hi, lam_out))
                track.places[p] = wp.max(track.places[p], level + 1)
        return track

    return SimpleNamespace(
        Track=Track,
        Tally=Tally,
        Reach=Reach,
        near_places=near_places,
        level_at=level_at,
        level_bound=level_bound,
        enter=enter,
        flush=flush,
        column_of=column_of,
        cell_index=cell_index,
    )


@functools.cache
def make_path_walk(precision: str, thresholds: int, points: int, with_map: bool) -> SimpleNamespace:
    """`chord(track, tally, xa, xb, lo, hi)`: a straight stretch within body height from xa to xb,
    threshold i exceeded on [lo_i, hi_i] of it, walked across the map's cells (Amanatides & Woo,
    Eurographics 1987; a row's cells at one level at once, `run_along_u`) and tested against the
    named places."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    cells = make_path_cells(precision, thresholds, points, with_map)
    Track, Tally, Reach = cells.Track, cells.Tally, cells.Reach
    enter, level_at, level_bound, cell_index, near_places = (
        cells.enter, cells.level_at, cells.level_bound, cells.cell_index, cells.near_places
    )  # fmt: skip
    MAP, HAS_POINTS = with_map, points > 0
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def crosses(lam: scalar, next_v: scalar, bound: scalar):
        """Whether a u edge at chord parameter lam is crossed within a run: before the next v edge,
        the chord's end and the level's `bound`."""
        return lam <= next_v and lam <= ONE and lam < bound

    @wp.func
    def along_u(iu: wp.int32, step_u: wp.int32, du: scalar, next_u: scalar, next_v: scalar, bound: scalar, left: wp.int32, nu: wp.int32):  # fmt: skip
        """How many u edges from cell iu (the next at chord parameter next_u, then every 1 / |du|) are
        crossed within a run (`crosses`), at most `left`, without leaving the grid's columns: in
        closed form, then stepped back past any edge that rounding let through (at most twice; one
        too few is taken up by the walk, an edge at a time)."""
        n = wp.int32(0)
        if crosses(next_u, next_v, bound):
            span = wp.abs(du)
            n = wp.min(left, wp.where(step_u > 0, nu - 1 - iu, iu))
            n = wp.min(n, wp.int32(wp.min((wp.min(next_v, ONE) - next_u) * span, scalar(nu))) + 1)
            n = wp.min(n, wp.int32(wp.min(wp.ceil((bound - next_u) * span), scalar(nu))))
            for _k in range(2):
                if n > 0 and not crosses(next_u + scalar(n - 1) / span, next_v, bound):
                    n -= 1
        return wp.max(n, 0)

    @wp.func
    def run_along_u(
        track: Track,
        tally: Tally,
        iu: wp.int32,
        iv: wp.int32,
        level: wp.int32,
        step_u: wp.int32,
        du: scalar,
        next_u: scalar,
        next_v: scalar,
        bound: scalar,
        gone: wp.int32,
        budget: wp.int32,
    ):
        """After `enter` of cell (iu, iv) at `level` by `walk`: where that cell ends the pending run
        (its row and level) in the direction of motion, the cells entered next across u's edges, up
        to the next v edge, the level's `bound`, the chord's end or the grid's, extend the run at
        once, as `enter` would one by one (the same cells, the same next_u). Returns (track, iu,
        next_u, gone)."""
        at_end = (step_u > 0 and iu == track.run_hi) or (step_u < 0 and iu == track.run_lo)
        if track.run_row == iv and track.run_level == level and track.cell == iv * tally.map_nu + iu and at_end:
            start = iu
            n = along_u(iu, step_u, du, next_u, next_v, bound, budget - gone, tally.map_nu)
            gone += n
            iu += n * step_u
            next_u = next_u + scalar(n) / wp.abs(du)
            if iu != start:
                track.run_lo = wp.min(track.run_lo, iu)
                track.run_hi = wp.max(track.run_hi, iu)
                track.cell = iv * tally.map_nu + iu
        return track, iu, next_u, gone

    @wp.func
    def walk(track: Track, tally: Tally, xa: vec3, xb: vec3, lo: Reach, hi: Reach):
        """Count the passes of the chord xa -> xb across the cells (in order along it)."""
        fu0 = wp.dot(xa, tally.map_u_cell) - tally.map_u_start
        fv0 = wp.dot(xa, tally.map_v_cell) - tally.map_v_start
        du = wp.dot(xb, tally.map_u_cell) - tally.map_u_start - fu0
        dv = wp.dot(xb, tally.map_v_cell) - tally.map_v_start - fv0
        step_u = wp.int32(1)
        if du < ZERO:
            step_u = wp.int32(-1)
        step_v = wp.int32(1)
        if dv < ZERO:
            step_v = wp.int32(-1)
        iu = cell_index(fu0, tally.map_nu_cells, step_u)
        iv = cell_index(fv0, tally.map_nv_cells, step_v)
        level = level_at(lo, hi, ZERO)
        track = enter(track, tally, iu, iv, level)
        big = scalar(1e30)
        next_u = big  # chord parameter of the next u (v) cell boundary
        next_v = big
        if du != ZERO:
            next_u = (scalar(iu + wp.max(step_u, 0)) - fu0) / du
        if dv != ZERO:
            next_v = (scalar(iv + wp.max(step_v, 0)) - fv0) / dv
        gone = wp.int32(0)  # the cells left on the way: at most |du| + |dv| + 2 inside the grid's span
        budget = wp.int32(wp.min(wp.abs(du) + wp.abs(dv), scalar(tally.map_nu) + tally.map_nv_cells)) + 4
        bound = level_bound(lo, hi, ZERO)  # the level holds for parameters up to (not at) it
        track, iu, next_u, gone = run_along_u(track, tally, iu, iv, level, step_u, du, next_u, next_v, bound, gone, budget)
        while gone < budget and wp.min(next_u, next_v) <= ONE:
            gone += 1
            lam = ZERO
            if next_u <= next_v:
                lam = next_u
                iu += step_u
                next_u = next_u + ONE / wp.abs(du)
            else:
                lam = next_v
                iv += step_v
                next_v = next_v + ONE / wp.abs(dv)
            if (iu < -1 or iu > tally.map_nu) or (iv < -1 or iv > wp.int32(tally.map_nv_cells)):
                break  # off the grid for good: it counts as one off-grid cell
            if not (lam < bound):  # (lam only grows: before `bound`, level_at and level_bound stay)
                level = level_at(lo, hi, lam)
                bound = level_bound(lo, hi, lam)
            track = enter(track, tally, iu, iv, level)
            track, iu, next_u, gone = run_along_u(track, tally, iu, iv, level, step_u, du, next_u, next_v, bound, gone, budget)
        return track

    @wp.func
    def chord(track: Track, tally: Tally, xa: vec3, xb: vec3, lo: Reach, hi: Reach):
        """A stretch within body height from xa to xb, threshold i exceeded on [lo_i, hi_i] of it."""
        if wp.static(MAP):
            track = walk(track, tally, xa, xb, lo, hi)
        if wp.static(HAS_POINTS):
            track = near_places(track, tally, xa, xb, lo, hi)
        return track

    return SimpleNamespace(chord=chord, walk=walk)


@functools.cache
def make_path_curve(precision: str, thresholds: int, points: int, with_map: bool) -> SimpleNamespace:
    """`curve(track, tally, a, b, x0, d0, e0, x1, d1, e1, lo, hi)`: the passes of a segment's
    stretch [a, b] within body height, walked across the map's cells along its Hermite quintic (u
    and v taken as monotone on the stretch): row by row along the major axis p (the one it moves
    farther along), each edge of the minor axis q crossed found by Newton's steps in the bracket,
    the cells between two crossings those whose p edges lie between them. Each cell entered counts
    with the level at its entry: threshold i is exceeded on [lo_i, hi_i] of the stretch (as
    fractions of it, from the part's speed crossings), mapped to an interval of p edges."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    cells = make_path_cells(precision, thresholds, points, with_map)
    Track, Tally, enter, cell_index = cells.Track, cells.Tally, cells.enter, cells.cell_index
    Reach, level_at = cells.Reach, cells.level_at
    dense = make_dense_output(precision)
    ITERATIONS = 30 if precision == "float32" else 60
    K = max(thresholds, 1)
    ZERO, ONE, HALF, BIG = scalar(0.0), scalar(1.0), scalar(0.5), scalar(1e30)
    TOLERANCE = scalar(4.0 * EPSILON[precision])

    @wp.func
    def enter_pq(track: Track, tally: Tally, swap: wp.bool, ip: wp.int32, iq: wp.int32, level: wp.int32):
        """`enter` cell (ip, iq) of the (major, minor) axes: (iu, iv), or (iv, iu) when `swap`."""
        iu = ip
        iv = iq
        if swap:
            iu = iq
            iv = ip
        return enter(track, tally, iu, iv, level)

    @wp.func
    def crossing(a: scalar, b: scalar, edge: scalar, g0: scalar, s0: scalar, q0: scalar, g1: scalar, s1: scalar, q1: scalar):
        """Where the quintic (g0, s0, q0; g1, s1, q1), below `edge` at a and not at b, reaches it on
        [a, b]: Newton's steps kept in the shrinking bracket (a bisection where one would leave it),
        to rounding."""
        fa, _sa = dense.hermite(a, g0, s0, q0, g1, s1, q1)
        fb, _sb = dense.hermite(b, g0, s0, q0, g1, s1, q1)
        m = a + (b - a) * wp.clamp((edge - fa) / (fb - fa), ZERO, ONE)  # the chord's guess
        for _ in range(ITERATIONS):
            value, slope = dense.hermite(m, g0, s0, q0, g1, s1, q1)
            if value < edge:
                a = m
            else:
                b = m
            step = m
            if slope > ZERO:
                step = m - (value - edge) / slope
            if not (step > a and step < b):
                step = HALF * (a + b)
            if wp.abs(step - m) <= TOLERANCE * (ONE + wp.abs(m)) or b - a <= TOLERANCE:
                return wp.clamp(step, a, b)
            m = step
        return b

    @wp.func
    def signed_edges(
        a: scalar,
        span: scalar,
        lo: Reach,
        hi: Reach,
        sp: scalar,
        p0: scalar,
        ps0: scalar,
        pq0: scalar,
        p1: scalar,
        ps1: scalar,
        pq1: scalar,
    ):
        """Threshold i's stretch [lo_i, hi_i] as an interval of sp p (the major coordinate, rising on
        the stretch): an edge crossed inside it is entered at that level. Ends at the stretch's own
        ends are open (every edge crossed lies inside them)."""
        glo = Reach()
        ghi = Reach()
        for i in range(wp.static(K)):
            glo[i] = -BIG
            ghi[i] = BIG
            if lo[i] > hi[i]:
                glo[i] = BIG  # never exceeded on the stretch
                ghi[i] = -BIG
            else:
                if lo[i] > ZERO:
                    value, _slope = dense.hermite(a + lo[i] * span, p0, ps0, pq0, p1, ps1, pq1)
                    glo[i] = sp * value
                if hi[i] < ONE:
                    value, _slope = dense.hermite(a + hi[i] * span, p0, ps0, pq0, p1, ps1, pq1)
                    ghi[i] = sp * value
        return glo, ghi

    @wp.func
    def curve(
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
        lo: Reach,
        hi: Reach,
    ):
        span = b - a
        # the major axis p (the one it moves farther along) and the minor q: (u, v), or (v, u) when `swap`
        swap = wp.abs(wp.dot(x1 - x0, tally.map_v_cell)) > wp.abs(wp.dot(x1 - x0, tally.map_u_cell))
        axis_p, axis_q = wp.where(swap, tally.map_v_cell, tally.map_u_cell), wp.where(swap, tally.map_u_cell, tally.map_v_cell)
        start_p, start_q = (
            wp.where(swap, tally.map_v_start, tally.map_u_start),
            wp.where(swap, tally.map_u_start, tally.map_v_start),
        )
        np_cells, nq_cells = (
            wp.where(swap, tally.map_nv_cells, tally.map_nu_cells),
            wp.where(swap, tally.map_nu_cells, tally.map_nv_cells),
        )
        p0, p1 = wp.dot(x0, axis_p) - start_p, wp.dot(x1, axis_p) - start_p
        q0, q1 = wp.dot(x0, axis_q) - start_q, wp.dot(x1, axis_q) - start_q
        ps0, pq0, ps1, pq1 = wp.dot(d0, axis_p), wp.dot(e0, axis_p), wp.dot(d1, axis_p), wp.dot(e1, axis_p)
        qs0, qq0, qs1, qq1 = wp.dot(d0, axis_q), wp.dot(e0, axis_q), wp.dot(d1, axis_q), wp.dot(e1, axis_q)
        fp, _sp = dense.hermite(a, p0, ps0, pq0, p1, ps1, pq1)
        fq, _sq = dense.hermite(a, q0, qs0, qq0, q1, qs1, qq1)
        fp_end, _sp1 = dense.hermite(b, p0, ps0, pq0, p1, ps1, pq1)
        fq_end, _sq1 = dense.hermite(b, q0, qs0, qq0, q1, qs1, qq1)
        step_p = wp.int32(1)
        if fp_end < fp:
            step_p = wp.int32(-1)
        step_q = wp.int32(1)
        if fq_end < fq:
            step_q = wp.int32(-1)
        sp = scalar(step_p)
        sq = scalar(step_q)
        ip = cell_index(fp, np_cells, step_p)
        iq = cell_index(fq, nq_cells, step_q)
        track = enter_pq(track, tally, swap, ip, iq, level_at(lo, hi, ZERO))
        glo, ghi = signed_edges(a, span, lo, hi, sp, p0, ps0, pq0, p1, ps1, pq1)
        theta = a
        budget = wp.int32(wp.min(wp.abs(fp_end - fp) + wp.abs(fq_end - fq), scalar(tally.map_nu) + tally.map_nv_cells)) + 4
        nq = wp.int32(nq_cells)
        n_p = wp.int32(np_cells)
        for _ in range(budget):  # a row of cells along p each, then into the next along q
            edge_q = scalar(iq + wp.max(step_q, 0))
            at_q = b + ONE  # none
            if (iq >= nq and step_q > 0) or (iq < 0 and step_q < 0):
                break  # off the grid along q and moving away: every cell left is off-grid
            if (fq - edge_q) * sq < ZERO and (fq_end - edge_q) * sq >= ZERO:
                at_q = crossing(theta, b, sq * edge_q, sq * q0, sq * qs0, sq * qq0, sq * q1, sq * qs1, sq * qq1)
            row_end = fp_end
            if at_q <= b:
                row_end, _slope = dense.hermite(at_q, p0, ps0, pq0, p1, ps1, pq1)
            ip_end = cell_index(row_end, np_cells, step_p)
            while (ip_end - ip) * step_p > 0:  # the cells entered across p's edges
                ip += step_p
                g = scalar(ip)  # sp times the edge entered
                if step_p < 0:
                    g = -scalar(ip + 1)
                level = wp.int32(0)
                more = scalar((ip_end - ip) * step_p)  # cells after this one at its level, in its run
                for i in range(wp.static(K)):
                    if glo[i] <= g and g <= ghi[i]:
                        level += 1
                    if glo[i] > g:  # edges g + k below glo: k <= ceil(glo - g) - 1
                        more = wp.min(more, wp.ceil(glo[i] - g) - ONE)
                    if ghi[i] >= g:  # edges g + k up to ghi: k <= floor(ghi - g)
                        more = wp.min(more, wp.floor(ghi[i] - g))
                track = enter_pq(track, tally, swap, ip, iq, level)
                if not swap and track.run_row == iq and more >= ONE:  # a run along u on the grid: the rest at once
                    last = ip + step_p * wp.int32(more)
                    if step_p > 0:
                        last = wp.min(last, n_p - 1)
                    else:
                        last = wp.max(last, 0)
                    if (last - ip) * step_p > 0:
                        track.run_lo = wp.min(track.run_lo, last)
                        track.run_hi = wp.max(track.run_hi, last)
                        track.cell = iq * n_p + last
                        ip = last
            if at_q > b:
                break
            theta = at_q
            iq += step_q
            fq = edge_q
            lam = ZERO
            if span > ZERO:
                lam = (theta - a) / span
            track = enter_pq(track, tally, swap, ip, iq, level_at(lo, hi, lam))
        return track

    return SimpleNamespace(curve=curve, crossing=crossing)
