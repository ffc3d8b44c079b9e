"""The hazard's ground when it is a terrain (docs/hazard.md section 11, "Above a terrain"): a path
segment cut where its horizontal position crosses the edges of the raster's triangles, each piece
watched over its triangle's plane (`tallies.path`'s `span`).

The terrain is the raster's grid (`tallies.terrain_ground.TerrainGrid`, packed in `Tally.terrain`):
vertex (i, j) (row, column) at O + j A + i B + z_ij up; cell (i, j) holds triangle A (vertices 00,
01, 11: s >= t) and triangle B (00, 11, 10: s <= t), s = fc - j, t = fr - i, with the grid
coordinates fc = (x - O).A*, fr = (x - O).B* (A*, B* dual to A, B in the horizontal plane). The
edges are the lines fc = integer, fr = integer and fd = fc - fr = integer: along a segment each is a
quintic Hermite in theta, its crossing found by `crossing` (Newton's steps kept in the bracket, to
rounding; exact to rounding for a vacuum flight, whose horizontal motion is linear). A cell off the
grid or with a nodata vertex (no triangle) is ground at the terrain's base plane (the hazard's
ground plane: `point` and up). Each grid coordinate is taken as monotone on a segment (as the map's
walk takes u and v on a part): a turn back across an edge and back within one segment is not seen.
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.integrate import make_dense_output
from ..physics.types import types_for
from .landing import make_landing_tally
from .path_roots import make_path_roots

HEADER = 18  # scalars of `Tally.terrain` before the heights (`terrain_ground.TerrainGrid.packed`)
TRIANGLE_A, TRIANGLE_B, SQUARE = 0, 1, 2  # a cell's part the walk is in (SQUARE: base-plane ground)
C_UP, C_DOWN, R_UP, R_DOWN, DIAGONAL = 0, 1, 2, 3, 4  # the edge a piece ends at


@functools.cache
def make_terrain_ground(precision: str) -> SimpleNamespace:
    """The grid's cells and triangles over `Tally.terrain` (module docstring): `plane` of a cell's
    part, `index` and `settle` (the cell and part a motion is in), `vec_at`, `height` of a point
    above body height over the ground below it, `window` of a segment possibly within it."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    Tally = make_landing_tally(precision).Tally
    roots = make_path_roots(precision)
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def vec_at(tally: Tally, k: wp.int32):
        return vec3(tally.terrain[k], tally.terrain[k + 1], tally.terrain[k + 2])

    @wp.func
    def z_at(tally: Tally, i: wp.int32, j: wp.int32):
        """m: vertex (i, j)'s height above the base plane (NaN: nodata)."""
        return tally.terrain[HEADER + i * wp.int32(tally.terrain[16]) + j]

    @wp.func
    def valid(tally: Tally, i: wp.int32, j: wp.int32):
        """Whether cell (i, j) is on the grid with its four vertices (two triangles)."""
        ok = i >= 0 and j >= 0 and i < wp.int32(tally.terrain[15]) - 1 and j < wp.int32(tally.terrain[16]) - 1
        if ok:
            total = z_at(tally, i, j) + z_at(tally, i, j + 1) + z_at(tally, i + 1, j) + z_at(tally, i + 1, j + 1)
            ok = not wp.isnan(total)
        return ok

    @wp.func
    def plane(tally: Tally, i: wp.int32, j: wp.int32, part: wp.int32):
        """The ground plane of a cell's part: its triangle's (through vertex 00, normal up - grad z),
        or the base plane (SQUARE)."""
        gp = tally.ground_point
        gn = tally.ground_normal
        if part != SQUARE:
            z00 = z_at(tally, i, j)
            z11 = z_at(tally, i + 1, j + 1)
            a = z11 - z_at(tally, i + 1, j)  # dz/dfc and dz/dfr on triangle B
            b = z_at(tally, i + 1, j) - z00
            if part == TRIANGLE_A:
                a = z_at(tally, i, j + 1) - z00
                b = z11 - z_at(tally, i, j + 1)
            gp = vec_at(tally, 0) + scalar(j) * vec_at(tally, 9) + scalar(i) * vec_at(tally, 12) + z00 * tally.up
            gn = tally.up - a * vec_at(tally, 3) - b * vec_at(tally, 6)
        return gp, gn

    @wp.func
    def index(f: scalar, n: scalar, rising: wp.bool):
        """The cell along one grid axis of coordinate f (clamped to -1 or n cells) that a motion
        (rising or not) is in just after f: on an edge, the one it moves into."""
        cell = wp.floor(f)
        if not rising:
            cell = wp.ceil(f) - ONE
        return wp.int32(wp.clamp(cell, scalar(-1.0), n))

    @wp.func
    def settle(tally: Tally, i: wp.int32, j: wp.int32, fd: scalar, rising: wp.bool):
        """The part of cell (i, j) at diagonal coordinate fd (moving up in it or not)."""
        part = wp.int32(SQUARE)
        if valid(tally, i, j):
            side = fd - scalar(j - i)
            part = wp.int32(TRIANGLE_B)
            if side > ZERO or (side == ZERO and rising):
                part = wp.int32(TRIANGLE_A)
        return part

    @wp.func
    def window(tally: Tally, theta_end: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        """(first, last): the segment is above body height over the terrain's highest point (the top
        plane, above every ground) on (first, last), so only [0, first] and [last, theta_end] need
        the walk; (theta_end, theta_end): all of it (a height with a trough, or never that high).
        Bisection on the height above the top plane, cut at its apex (a unimodal height)."""
        gp = vec_at(tally, 0) + tally.terrain[17] * tally.up
        gn = tally.up
        f0, s0 = roots.height_at(tally, gp, gn, ZERO, x0, d0, e0, x1, d1, e1)
        f1, r1 = roots.height_at(tally, gp, gn, theta_end, x0, d0, e0, x1, d1, e1)
        first = theta_end
        last = theta_end
        if not (s0 < ZERO and r1 > ZERO):
            top = ZERO  # the highest point: falling throughout
            if s0 > ZERO and r1 <= ZERO:
                top = roots.apex(tally, gp, gn, ZERO, theta_end, x0, d0, e0, x1, d1, e1)
            elif s0 > ZERO:
                top = theta_end
            f_top, _r = roots.height_at(tally, gp, gn, top, x0, d0, e0, x1, d1, e1)
            if f_top > ZERO:
                first = ZERO
                if f0 <= ZERO:
                    first = roots.height_root(tally, gp, gn, ZERO, top, wp.int32(1), x0, d0, e0, x1, d1, e1)
                if f1 <= ZERO:
                    last = roots.height_root(tally, gp, gn, top, theta_end, wp.int32(0), x0, d0, e0, x1, d1, e1)
        return first, last

    @wp.func
    def height(tally: Tally, x: vec3):
        """m: how far the centre at x is above body height over the terrain below it (<= 0: within)."""
        o = vec_at(tally, 0)
        fc = wp.dot(x - o, vec_at(tally, 3))
        fr = wp.dot(x - o, vec_at(tally, 6))
        i = index(fr, tally.terrain[15] - ONE, True)
        j = index(fc, tally.terrain[16] - ONE, True)
        gp, gn = plane(tally, i, j, settle(tally, i, j, fc - fr, True))
        return wp.dot(x - gp, gn) - tally.body_height

    return SimpleNamespace(vec_at=vec_at, valid=valid, plane=plane, index=index, settle=settle, window=window, height=height)


@functools.cache
def make_terrain_walk(precision: str, crossing) -> SimpleNamespace:
    """`Walk`, `begin` and `next_piece` (the pieces of a segment, module docstring), with
    `make_terrain_ground`'s `window` and `height`; `crossing`: `tallies.path_cells.make_path_curve`'s root
    of a quintic reaching an edge."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    Tally = make_landing_tally(precision).Tally
    hermite = make_dense_output(precision).hermite
    ground = make_terrain_ground(precision)
    vec_at, plane, index, settle = ground.vec_at, ground.plane, ground.index, ground.settle
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.struct
    class Walk:
        start: scalar  # the piece [start, end] of the segment (theta)
        end: scalar
        gp: vec3  # its ground plane: a point, the normal / (normal . up)
        gn: vec3
        i: wp.int32  # the cell the walk is in after `end` (row, column; -1 or n: off the grid)
        j: wp.int32
        part: wp.int32  # TRIANGLE_A, TRIANGLE_B or SQUARE
        budget: wp.int32  # pieces at most

    @wp.func
    def along(w: vec3, o: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        """A grid coordinate (x . w - o) along the segment: its Hermite data at theta 0 and 1."""
        return wp.dot(x0, w) - o, wp.dot(d0, w), wp.dot(e0, w), wp.dot(x1, w) - o, wp.dot(d1, w), wp.dot(e1, w)

    @wp.func
    def first_exit(
        exit: scalar,
        kind: wp.int32,
        which: wp.int32,
        sign: scalar,
        edge: scalar,
        a: scalar,
        b: scalar,
        g0: scalar,
        s0: scalar,
        q0: scalar,
        g1: scalar,
        s1: scalar,
        q1: scalar,
    ):
        """(exit, kind) with the crossing of `edge` by sign * g (sign +1: rising past it) on [a, b]
        when it is past it at b and earlier than `exit`."""
        end, _slope = hermite(b, g0, s0, q0, g1, s1, q1)
        if sign * end > sign * edge:
            at = crossing(a, b, sign * edge, sign * g0, sign * s0, sign * q0, sign * g1, sign * s1, sign * q1)
            if at < exit:
                exit = at
                kind = which
        return exit, kind

    @wp.func
    def begin(tally: Tally, theta_start: scalar, theta_end: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        """The walk of [theta_start, theta_end] at its start: its cell and part, its budget of pieces."""
        o = vec_at(tally, 0)
        c0, cs0, cq0, c1, cs1, cq1 = along(vec_at(tally, 3), wp.dot(o, vec_at(tally, 3)), x0, d0, e0, x1, d1, e1)
        r0, rs0, rq0, r1, rs1, rq1 = along(vec_at(tally, 6), wp.dot(o, vec_at(tally, 6)), x0, d0, e0, x1, d1, e1)
        c_end, _c = hermite(theta_end, c0, cs0, cq0, c1, cs1, cq1)
        r_end, _r = hermite(theta_end, r0, rs0, rq0, r1, rs1, rq1)
        c0, _cs = hermite(theta_start, c0, cs0, cq0, c1, cs1, cq1)  # (at 0: c0 itself)
        r0, _rs = hermite(theta_start, r0, rs0, rq0, r1, rs1, rq1)
        rows = tally.terrain[15] - ONE  # cells along each axis
        cols = tally.terrain[16] - ONE
        w = Walk()
        w.i = index(r0, rows, r_end >= r0)
        w.j = index(c0, cols, c_end >= c0)
        w.part = settle(tally, w.i, w.j, c0 - r0, c_end - r_end >= c0 - r0)
        spread = wp.min(wp.abs(c_end - c0) + wp.abs(r_end - r0), scalar(2.0) * (rows + cols))
        w.budget = wp.int32(scalar(2.0) * spread) + 4
        w.end = theta_start
        return w

    @wp.func
    def next_piece(tally: Tally, w: Walk, theta_end: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        """The next piece: from the walk's end to the first edge crossed (or theta_end), with its
        plane; consecutive off-raster cells make one piece. The walk's cell is then the next one."""
        o = vec_at(tally, 0)
        c0, cs0, cq0, c1, cs1, cq1 = along(vec_at(tally, 3), wp.dot(o, vec_at(tally, 3)), x0, d0, e0, x1, d1, e1)
        r0, rs0, rq0, r1, rs1, rq1 = along(vec_at(tally, 6), wp.dot(o, vec_at(tally, 6)), x0, d0, e0, x1, d1, e1)
        rows = tally.terrain[15] - ONE
        cols = tally.terrain[16] - ONE
        w.start = w.end
        gp, gn = plane(tally, w.i, w.j, w.part)
        w.gp = gp
        w.gn = gn
        for _ in range(w.budget):
            a = w.end
            exit = theta_end
            kind = wp.int32(-1)
            ci = scalar(w.i)
            cj = scalar(w.j)
            if w.part == TRIANGLE_A:
                exit, kind = first_exit(exit, kind, R_DOWN, -ONE, ci, a, theta_end, r0, rs0, rq0, r1, rs1, rq1)
                exit, kind = first_exit(exit, kind, C_UP, ONE, cj + ONE, a, theta_end, c0, cs0, cq0, c1, cs1, cq1)
                exit, kind = first_exit(
                    exit,
                    kind,
                    DIAGONAL,
                    -ONE,
                    cj - ci,
                    a,
                    theta_end,
                    c0 - r0,
                    cs0 - rs0,
                    cq0 - rq0,
                    c1 - r1,
                    cs1 - rs1,
                    cq1 - rq1,
                )
            elif w.part == TRIANGLE_B:
                exit, kind = first_exit(exit, kind, C_DOWN, -ONE, cj, a, theta_end, c0, cs0, cq0, c1, cs1, cq1)
                exit, kind = first_exit(exit, kind, R_UP, ONE, ci + ONE, a, theta_end, r0, rs0, rq0, r1, rs1, rq1)
                exit, kind = first_exit(
                    exit, kind, DIAGONAL, ONE, cj - ci, a, theta_end, c0 - r0, cs0 - rs0, cq0 - rq0, c1 - r1, cs1 - rs1, cq1 - rq1
                )
            else:
                if cj < cols:
                    exit, kind = first_exit(exit, kind, C_UP, ONE, cj + ONE, a, theta_end, c0, cs0, cq0, c1, cs1, cq1)
                if cj >= ZERO:
                    exit, kind = first_exit(exit, kind, C_DOWN, -ONE, cj, a, theta_end, c0, cs0, cq0, c1, cs1, cq1)
                if ci < rows:
                    exit, kind = first_exit(exit, kind, R_UP, ONE, ci + ONE, a, theta_end, r0, rs0, rq0, r1, rs1, rq1)
                if ci >= ZERO:
                    exit, kind = first_exit(exit, kind, R_DOWN, -ONE, ci, a, theta_end, r0, rs0, rq0, r1, rs1, rq1)
            w.end = wp.max(exit, a)
            if kind < 0:
                w.end = theta_end
                break
            was = w.part
            if kind == DIAGONAL:
                w.part = TRIANGLE_A + TRIANGLE_B - w.part
            else:
                if kind == C_UP:
                    w.j = wp.min(w.j + 1, wp.int32(cols))
                elif kind == C_DOWN:
                    w.j = wp.max(w.j - 1, -1)
                elif kind == R_UP:
                    w.i = wp.min(w.i + 1, wp.int32(rows))
                else:
                    w.i = wp.max(w.i - 1, -1)
                fd, _fd = hermite(w.end, c0 - r0, cs0 - rs0, cq0 - rq0, c1 - r1, cs1 - rs1, cq1 - rq1)
                fd_end, _e = hermite(theta_end, c0 - r0, cs0 - rs0, cq0 - rq0, c1 - r1, cs1 - rs1, cq1 - rq1)
                w.part = settle(tally, w.i, w.j, fd, fd_end >= fd)
            if not (was == SQUARE and w.part == SQUARE):
                break
        return w

    return SimpleNamespace(Walk=Walk, window=ground.window, begin=begin, next_piece=next_piece, height=ground.height)
