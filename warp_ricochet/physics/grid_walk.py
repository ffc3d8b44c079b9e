"""A terrain's raster walked along the flight (docs/geometry.md, "Terrain"); read only through
`physics.mesh_contact` (kernels compiled with large meshes).

A terrain placed without a site keeps its triangles two to a cell of a regular grid
(`scene.terrain.TerrainGrid`). Across its `up` the centre of the parabola of eq. (36) moves on a
straight line (gravity's part along the raster, if any, is a drift in the margin), so the flight
crosses the cells in order. The walk follows that line through a maximum mipmap of the cells'
heights (Tevs, Ihrke & Seidel 2008, "Maximum mipmaps for fast, accurate, and scalable dynamic height
field rendering", I3D; `physics.mipmap.max_pyramid`):

- starting from a single cell (a ricochet starts on the ground), a block of 2^L x 2^L cells is
  passed when the centre's lowest height over the time the line spends in it (the ends, or the
  vertex when gravity points up) is more than the margin above the block's top (the highest vertex
  of its cells and of those within one cell): no triangle within the margin across can be met, its
  distance being at least that height gap;
- otherwise the walk goes down a level; a cell reached at level 0 has the triangles of every cell
  within the margin of its stretch of the line tested (`face_time`), but those of a cell whose own
  top the centre passes more than the margin above while the line is within the margin of that cell,
  of one the line comes within the margin of only after the contact found so far, and of the last
  four cells tested (a triangle test itself stops where its offset plane is reached no earlier than
  that contact); then it goes up a level, as after every block passed;
- a stretch that leaves the raster runs to where the line is past the raster's margin, and a
  block's is then passed only above the whole raster's top (beyond the edge the line may run
  along it; not where the flight's window ends inside the raster);
- it stops at the first contact no later than the stretches searched: the earliest contact of the
  mesh, as the chords' search (`mesh_contact.make_mesh_search`) finds it.

The margin: R, the face test's touching band (ROUNDING eps of the centre's and the triangles' scale
in the mesh's frame, `triangle_time`), RECKONING eps of the walk's own operands, the drift and how
far the vertices lie from their cells' corners (`grid_slack`: float32, a skewed axis_u; the tops are
the kernel's own vertices', rounded up, so no float32 slack of the BVH's); a margin over a third of a
cell, or a walk past its bound on steps, returns not walked (the caller searches the chords).
`make_grid_cells` gives the cells near a point, for the contact's normal and the air's steps.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON, MAX_FLIGHT_TIME, NO_CONTACT, ROUNDING
from .types import types_for

RECKONING = 8.0  # the walk's own rounding of heights and cells, in eps of their operands' scale
WIDEST = 1.0 / 3.0  # the largest margin walked, in cells (the mipmap's tops cover one cell beside a block)


@functools.cache
def make_grid_cells(precision: str) -> SimpleNamespace:
    """`walked(surfaces, k)` (whether mesh k is a terrain with its raster's grid), `face_of(surfaces,
    k, i, j)` (the first of cell (i, j)'s two triangles, -1: a hole), `around(surfaces, k, x, reach)`
    (the cells (i0, i1, j0, j1) within `reach` m of x across the raster, none when i0 > i1 or j0 > j1)
    and `across(surfaces, k, d)` (a displacement d in columns and rows)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces

    @wp.func
    def walked(surfaces: Surfaces, k: wp.int32):
        """Whether mesh k is a terrain with its raster's grid."""
        return surfaces.grid_dims[k][2] > 0

    @wp.func
    def face_of(surfaces: Surfaces, k: wp.int32, i: wp.int32, j: wp.int32):
        """The first triangle of cell (i, j) of terrain k (-1: a hole)."""
        return surfaces.grid_cell[surfaces.grid_first[k][1] + j * surfaces.grid_dims[k][0] + i]

    @wp.func
    def around(surfaces: Surfaces, k: wp.int32, x: vec3, reach: scalar):
        """The cells (i0, i1, j0, j1) of terrain k within `reach` (m) of x across its raster."""
        d = x - surfaces.grid_origin[k]
        per_col, per_row = surfaces.grid_col[k], surfaces.grid_row[k]
        u, w = wp.dot(d, per_col), wp.dot(d, per_row)
        du, dw = reach * wp.length(per_col), reach * wp.length(per_row)
        cols, rows = surfaces.grid_dims[k][0], surfaces.grid_dims[k][1]
        i0 = wp.int32(wp.floor(wp.min(wp.max(u - du, scalar(-1.0)), scalar(cols))))
        i1 = wp.int32(wp.floor(wp.min(wp.max(u + du, scalar(-1.0)), scalar(cols))))
        j0 = wp.int32(wp.floor(wp.min(wp.max(w - dw, scalar(-1.0)), scalar(rows))))
        j1 = wp.int32(wp.floor(wp.min(wp.max(w + dw, scalar(-1.0)), scalar(rows))))
        return wp.max(i0, 0), wp.min(i1, cols - 1), wp.max(j0, 0), wp.min(j1, rows - 1)

    @wp.func
    def across(surfaces: Surfaces, k: wp.int32, d: vec3):
        """The displacement d (m) in columns and rows of terrain k's raster."""
        return wp.dot(d, surfaces.grid_col[k]), wp.dot(d, surfaces.grid_row[k])

    return SimpleNamespace(walked=walked, face_of=face_of, around=around, across=across)


@functools.cache
def make_grid_walk(precision: str, face_time) -> SimpleNamespace:
    """`walked(surfaces, k)` and `grid_time(surfaces, k, x, v, g, R, end)` -> (time or
    NO_CONTACT, walked) of terrain k over [0, end] s, with `face_time(surfaces, k, face, x, v, g, R,
    before)` (when the parabola meets triangle `face`, NO_CONTACT where not before `before` s if
    that is >= 0; module docstring)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    LATEST, NONE = scalar(MAX_FLIGHT_TIME), scalar(NO_CONTACT)
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])
    SUMS = scalar(RECKONING * EPSILON[precision])
    vec4 = wp.types.vector(4, scalar)

    @wp.func
    def l1(a: vec3):
        return wp.abs(a[0]) + wp.abs(a[1]) + wp.abs(a[2])

    walked = make_grid_cells(precision).walked

    @wp.func
    def lowest(h0: scalar, rise: scalar, half: scalar, a: scalar, b: scalar):
        """The least of h0 + rise t + half t^2 (m) over [a, b] s."""
        low = wp.min(h0 + (rise + half * a) * a, h0 + (rise + half * b) * b)
        if half > scalar(0.0):
            apex = -rise / (scalar(2.0) * half)
            if apex > a and apex < b:
                low = wp.min(low, h0 + (rise + half * apex) * apex)
        return low

    @wp.func
    def leave(p0: scalar, s: scalar, lo: wp.int32, hi: wp.int32):
        """When p0 + s t (cells) leaves [lo, hi] forwards (LATEST: never)."""
        if s > scalar(0.0):
            return (scalar(hi) - p0) / s
        if s < scalar(0.0):
            return (scalar(lo) - p0) / s
        return LATEST

    @wp.func
    def clip(p0: scalar, s: scalar, lo: scalar, hi: scalar, start: scalar, stop: scalar):
        """[start, stop] cut to the times p0 + s t lies in [lo, hi] (stop < start: never)."""
        if s == scalar(0.0):
            if p0 < lo or p0 > hi:
                return start, scalar(-1.0)
            return start, stop
        a, b = (lo - p0) / s, (hi - p0) / s
        return wp.max(start, wp.min(a, b)), wp.min(stop, wp.max(a, b))

    @wp.func
    def span(a: scalar, b: scalar, pad: scalar, count: wp.int32):
        """The cells (first, last) of [min(a, b) - pad, max(a, b) + pad] among 0 to count - 1."""
        first = wp.int32(wp.floor(wp.max(wp.min(a, b) - pad, scalar(-1.0))))
        last = wp.int32(wp.floor(wp.min(wp.max(a, b) + pad, scalar(count))))
        return wp.max(first, 0), wp.min(last, count - 1)

    @wp.func
    def inside(p: scalar, lo: wp.int32, hi: wp.int32):
        """The cell of p (cells), kept within lo to hi."""
        return wp.min(wp.max(wp.int32(wp.floor(p)), lo), hi)

    @wp.func
    def top(surfaces: Surfaces, levels_at: wp.int32, cols: wp.int32, level: wp.int32, i: wp.int32, j: wp.int32):
        """The top (m) of block (i, j) of `level` of a mipmap of `cols` columns whose levels start at
        row `levels_at` of grid_level."""
        across = (cols + (1 << level) - 1) >> level
        return surfaces.grid_top[surfaces.grid_level[levels_at + level] + j * across + i]

    @wp.func
    def cells_time(
        surfaces: Surfaces,
        k: wp.int32,
        x: vec3,
        v: vec3,
        g: vec3,
        radius: scalar,
        cells: wp.vec4i,
        line: vec4,
        path: vec3,
        pads: vec3,
        now: scalar,
        then: scalar,
        best: scalar,
        seen: wp.vec4i,
    ):
        """(the earlier of `best` and the contacts with the triangles of mesh k in `cells` (columns
        cells[0] to cells[1] by rows cells[2] to cells[3]), but those of a cell among `seen`, or whose
        top the centre passes more than the margin above while the line is within the margin of the
        cell in [now, then] s, or that the line comes within the margin of only from `best` on;
        `seen`, the last four cells tested (-1: none), updated). `line`: (u0,
        su, w0, sw), the line in cells; `path`: (h0, rise, half), the centre's height (m); `pads`:
        the margin in m, across columns and across rows in cells."""
        dims, first = surfaces.grid_dims[k], surfaces.grid_first[k]
        level = surfaces.grid_level[first[0]]
        for j in range(cells[2], cells[3] + 1):
            for i in range(cells[0], cells[1] + 1):
                cell = j * dims[0] + i
                face = surfaces.grid_cell[first[1] + cell]
                if cell == seen[0] or cell == seen[1] or cell == seen[2] or cell == seen[3]:
                    face = -1
                if face >= 0:
                    lo, hi = clip(line[0], line[1], scalar(i) - pads[1], scalar(i + 1) + pads[1], now, then)
                    lo, hi = clip(line[2], line[3], scalar(j) - pads[2], scalar(j + 1) + pads[2], lo, hi)
                    if hi < lo or (best >= scalar(0.0) and best <= lo):  # (met no earlier than best)
                        face = -1
                    elif lowest(path[0], path[1], path[2], lo, hi) - pads[0] > surfaces.grid_top[level + cell]:
                        face = -1
                if face >= 0:
                    seen = wp.vec4i(cell, seen[0], seen[1], seen[2])
                    for f in range(face, face + 2):
                        when = face_time(surfaces, k, f, x, v, g, radius, best)
                        if when >= scalar(0.0) and (best < scalar(0.0) or when < best):
                            best = when
        return best, seen

    @wp.func
    def grid_time(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar, end: scalar):
        """(the earliest contact (s) of the parabola with terrain k within [0, end], or NO_CONTACT;
        whether it was walked) (module docstring)."""
        dims = surfaces.grid_dims[k]
        o, up = surfaces.grid_origin[k], surfaces.grid_up[k]
        per_col, per_row = surfaces.grid_col[k], surfaces.grid_row[k]
        d = x - o
        u0, w0, h0 = wp.dot(d, per_col), wp.dot(d, per_row), wp.dot(d, up)
        su, sw, rise = wp.dot(v, per_col), wp.dot(v, per_row), wp.dot(v, up)
        half = scalar(0.5) * wp.dot(g, up)
        drift = scalar(0.5) * wp.length(g - scalar(2.0) * half * up) * end * end
        low, high = surfaces.mesh_low[k], surfaces.mesh_high[k]
        band = l1(x - scalar(0.5) * (low + high)) + scalar(0.5) * l1(high - low) + l1(x) / scalar(32.0) + radius
        reckoning = l1(x) + l1(o) + (wp.length(v) + wp.length(g) * end) * end
        margin = radius + drift + TOLERANCE * band + SUMS * reckoning + surfaces.grid_slack[k]
        mu, mw = margin * wp.length(per_col), margin * wp.length(per_row)
        if mu > scalar(WIDEST) or mw > scalar(WIDEST):
            return NONE, False
        cols, rows, levels = dims[0], dims[1], dims[2]
        levels_at = surfaces.grid_first[k][0]
        start, stop = clip(u0, su, -mu, scalar(cols) + mu, scalar(0.0), end)
        start, stop = clip(w0, sw, -mw, scalar(rows) + mw, start, stop)
        best = NONE
        if stop < start:
            return best, True
        ci = inside(u0 + su * start, 0, cols - 1)
        cj = inside(w0 + sw * start, 0, rows - 1)
        level = wp.int32(0)
        now = start
        seen = wp.vec4i(-1, -1, -1, -1)  # the cells tested last
        for _step in range((cols + rows + 2) * (levels + 1)):
            lo_u, lo_w = (ci >> level) << level, (cj >> level) << level
            hi_u, hi_w = wp.min(lo_u + (1 << level), cols), wp.min(lo_w + (1 << level), rows)
            tu, tw = leave(u0, su, lo_u, hi_u), leave(w0, sw, lo_w, hi_w)
            then = wp.max(wp.min(wp.min(tu, tw), stop), now)
            ni = ci  # (plain assignments: tests/test_warp_rules.py)
            nj = cj
            if tu <= tw:
                ni = wp.where(su > scalar(0.0), hi_u, lo_u - 1)
            if tw <= tu:
                nj = wp.where(sw > scalar(0.0), hi_w, lo_w - 1)
            off = ni < 0 or ni >= cols or nj < 0 or nj >= rows  # the next cell is off the raster
            leaving = then >= stop or off
            if leaving:
                then = stop
            if level > 0:
                floor = lowest(h0, rise, half, now, then) - margin
                limit = top(surfaces, levels_at, cols, level, ci >> level, cj >> level)
                if off:  # past the raster's edge the line may run along cells beyond the block
                    limit = wp.max(limit, top(surfaces, levels_at, cols, levels - 1, 0, 0))
                if floor <= limit:
                    level -= 1
                    continue
                if best >= scalar(0.0) and best <= then:
                    return best, True
            else:
                i0, i1 = span(u0 + su * now, u0 + su * then, mu, cols)
                j0, j1 = span(w0 + sw * now, w0 + sw * then, mw, rows)
                cells = wp.vec4i(i0, i1, j0, j1)
                line, path = vec4(u0, su, w0, sw), vec3(h0, rise, half)
                best, seen = cells_time(
                    surfaces, k, x, v, g, radius, cells, line, path, vec3(margin, mu, mw), now, then, best, seen
                )
                if best >= scalar(0.0) and best <= then:
                    return best, True
            if leaving:
                return best, True
            if ni == ci:
                ni = inside(u0 + su * then, lo_u, hi_u - 1)
            if nj == cj:
                nj = inside(w0 + sw * then, lo_w, hi_w - 1)
            ci = ni
            cj = nj
            now = then
            level = wp.min(level + 1, levels - 1)
        return NONE, False

    return SimpleNamespace(walked=walked, grid_time=grid_time)
