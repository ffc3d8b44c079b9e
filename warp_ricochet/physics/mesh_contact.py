"""The exact parabola of eq. (36) against a triangle mesh (boxes, meshes: docs/geometry.md, "Meshes
and boxes"); read only through `physics.geometry` (kernels compiled with meshes).

A mesh surface k holds a `wp.Mesh` (float32 BVH: `Surfaces.mesh`) and its vertices in the kernel's
precision (`mesh_points`, a triangle's rows of them in `mesh_triangles` from `mesh_first[k]`), with
their bounding box (`mesh_low`, `mesh_high`).
The BVH only proposes triangles; every test is on the kernel-precision vertices:

- the flight's time window near the mesh: until the centre, falling along gravity, is below the box
  by R (no gravity: the slab test of the straight line against the box grown by R);
- split into chords, each short enough that the parabola lies within its sagitta |g| h^2 / 8 of it
  (a chord per SAGITTA of the box's diagonal) and at most CHORD_EDGES median triangle edges long
  (so a chord's box holds a few triangles, not a strip of a terrain), at most MAX_CHORDS; each chord's box grown by
  R + sagitta + float32 slack is queried (`wp.mesh_query_aabb`), in time order, until a contact
  found lies within the chords searched;
- a triangle (a, b, c) with unit normal n = (b - a) x (c - a) / |.| is met where the centre's
  height h = n.(x - a) closes through R (the plane's quadratic, `ballistic.entry_time`; from
  behind the plane: its descending crossing) with the centre projected inside the triangle, or at
  the latest where the centre itself descends through the triangle (h = 0) inside it: a sphere that
  grazes an edge or a vertex is stopped there, so that a closed mesh is never crossed;
- inside: the three edge functions n.((b - a) x (y - a)) are >= -|b - a| (EDGE_ROUNDING eps (|y - a|_1
  + |b - a|_1) + STATE_ROUNDING eps |y|_1): the arithmetic's rounding and the stored centre's own
  (inclusive, so a centre on a shared edge or vertex is inside its neighbours too);
- every tolerance scales with the mesh's own frame (`scale`: its box's extent and the centre's
  distance from the box's centre) and the stored centre's own rounding (`state_rounding`), not with
  the world's coordinates (docs/geometry.md, "Far from the origin"); only the float32 BVH's query
  boxes are grown by FLOAT32_SLACK of those.

A mesh of at most FEW_FACES triangles (a box, a plane's two) has every triangle tested instead of the
chords' candidates: the same earliest contact (the chords' boxes only exclude triangles that cannot be
met), without the BVH's traversals. Its edges and corners are searched only from when the centre
first comes within R of the plane of every face that covers them (`physics.mesh_edges.covering_faces`:
all of them on or behind that plane, so each is farther from a centre in front than its height):
in a convex or a flat mesh, a face contact leaves none to search.
`make_mesh_search` runs that search, with what else each triangle owns: `physics.edge_contact`'s
adds the mesh's convex edges and corners each triangle owns to its face. In a scene whose solids are
all flat small meshes each is searched as its plane instead (`physics.flat_contact`), with the same
rules (`make_bound_rule`).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON, MAX_FLIGHT_TIME, NO_CONTACT, ROUNDING, make_ballistic
from .grid_walk import make_grid_cells, make_grid_walk
from .mesh_edges import FEW_FACES, INSET
from .types import KINDS, types_for

SAGITTA = 1.0 / 16.0  # a chord's sagitta, as a fraction of the mesh's bounding-box diagonal
MAX_CHORDS = 1024  # past it the chords are longer and their boxes grown by their larger sagitta
CHORD_EDGES = 4.0  # a chord's length at most this many of the mesh's median triangle edge
EDGE_ROUNDING = 8.0  # the inside test's tolerance, in machine epsilons of its operands' scale
FLOAT32_SLACK = 2.0**-20  # relative: the BVH's float32 boxes against the kernel's vertices
STATE_ROUNDING = 2.0  # a stored centre's rounding (and one placement's), in eps of its own coordinates


@functools.cache
def make_mesh_lookup(precision: str) -> SimpleNamespace:
    """`is_mesh(surfaces, k)`, `bounds(surfaces, k)` -> (wp.Mesh id, low, high) and `faces(surfaces, k)`:
    what the air's search asks of a mesh surface beside its triangles."""
    t = types_for(precision)
    Surfaces, MESH = t.Surfaces, KINDS["mesh"]

    @wp.func
    def is_mesh(surfaces: Surfaces, k: wp.int32):
        """Whether surface k is a mesh (a box is one)."""
        return surfaces.kind[k] == MESH

    @wp.func
    def bounds(surfaces: Surfaces, k: wp.int32):
        """Mesh k's `wp.Mesh` id and its vertices' box (m): (id, low, high)."""
        return surfaces.mesh[k], surfaces.mesh_low[k], surfaces.mesh_high[k]

    @wp.func
    def faces(surfaces: Surfaces, k: wp.int32):
        """Mesh k's triangles (at most FEW_FACES: tested whole, without the BVH)."""
        return surfaces.mesh_faces[k]

    return SimpleNamespace(is_mesh=is_mesh, bounds=bounds, faces=faces)


@functools.cache
def make_triangle_basics(precision: str) -> SimpleNamespace:
    """`vertices`, `single`, `l1`, `inside`, `descending`, `edge_distance` and `leaves_clear`: a mesh's triangles and the tests on them
    that its contacts, the air's search, posts and the motion along triangles share (one precision)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    entry_time = make_ballistic(precision).entry_time
    EDGE = scalar(EDGE_ROUNDING * EPSILON[precision])
    STATE = scalar(STATE_ROUNDING * EPSILON[precision])

    @wp.func
    def l1(x: vec3):
        return wp.abs(x[0]) + wp.abs(x[1]) + wp.abs(x[2])

    @wp.func
    def vertices(surfaces: Surfaces, k: wp.int32, face: wp.int32):
        """Triangle `face` of mesh k: its three vertices (m)."""
        rows = surfaces.mesh_triangles[surfaces.mesh_first[k] + face]
        return surfaces.mesh_points[rows[0]], surfaces.mesh_points[rows[1]], surfaces.mesh_points[rows[2]]

    @wp.func
    def frame(surfaces: Surfaces, k: wp.int32):
        """Mesh k's own origin (m): the centre of its vertices' box, about which its tolerances scale."""
        return scalar(0.5) * (surfaces.mesh_low[k] + surfaces.mesh_high[k])

    @wp.func
    def scale(surfaces: Surfaces, k: wp.int32, x: vec3):
        """The coordinates' scale (m) in mesh k's frame: its box's l1 extent and x's l1 distance
        from its origin (`frame`), not x's distance from the world's origin."""
        return l1(surfaces.mesh_high[k] - surfaces.mesh_low[k]) + l1(x - frame(surfaces, k))

    @wp.func
    def state_rounding(x: vec3):
        """How far (m) a stored centre x may lie from where it was computed: STATE_ROUNDING eps of
        its own (world) coordinates."""
        return STATE * l1(x)

    @wp.func
    def height_noise(surfaces: Surfaces, k: wp.int32, x: vec3, a: vec3, n: vec3):
        """The rounding scale (m) of x's height n.(x - a) over a triangle of mesh k (vertex a, unit
        normal n): sum_i |x_i - o_i| |n_i| + sum_i |a_i - o_i| |n_i| in the mesh's frame (o: `frame`),
        and the stored centre's own rounding (`state_rounding`) in ROUNDING eps."""
        o = frame(surfaces, k)
        noise = wp.abs((x[0] - o[0]) * n[0]) + wp.abs((x[1] - o[1]) * n[1]) + wp.abs((x[2] - o[2]) * n[2])
        noise += wp.abs((a[0] - o[0]) * n[0]) + wp.abs((a[1] - o[1]) * n[1]) + wp.abs((a[2] - o[2]) * n[2])
        along = wp.abs(x[0] * n[0]) + wp.abs(x[1] * n[1]) + wp.abs(x[2] * n[2])
        return noise + scalar(STATE_ROUNDING / ROUNDING) * along

    @wp.func
    def single(x: vec3):
        """x in float32 (the BVH's queries)."""
        return wp.vec3f(wp.float32(x[0]), wp.float32(x[1]), wp.float32(x[2]))

    @wp.func
    def edge_in(n: vec3, p: vec3, q: vec3, y: vec3):
        """y on the inner side of edge p -> q (counter-clockwise about n), inclusive within the
        rounding of the edge function in the edge's frame and of the stored point y itself."""
        e = q - p
        d = y - p
        return wp.dot(n, wp.cross(e, d)) >= -wp.length(e) * (EDGE * (l1(d) + l1(e)) + state_rounding(y))

    @wp.func
    def inside(n: vec3, a: vec3, b: vec3, c: vec3, y: vec3):
        """y projected along n onto triangle (a, b, c) lies on it (edges and vertices included)."""
        return edge_in(n, a, b, y) and edge_in(n, b, c, y) and edge_in(n, c, a, y)

    @wp.func
    def descending(c: scalar, speed: scalar, half: scalar):
        """First t >= 0 where c + speed t + half t^2 decreases through 0, or NO_CONTACT."""
        if c > scalar(0.0):
            return entry_time(c, speed, half)
        if c == scalar(0.0):
            if speed < scalar(0.0):
                return scalar(0.0)
            if half < scalar(0.0):
                return -speed / half
            return scalar(NO_CONTACT)
        if speed > scalar(0.0) and half < scalar(0.0):
            disc = speed * speed - scalar(4.0) * half * c
            if disc >= scalar(0.0):
                return -(speed + wp.sqrt(disc)) / (scalar(2.0) * half)
        return scalar(NO_CONTACT)

    @wp.func
    def edge_distance(n: vec3, p: vec3, q: vec3, y: vec3):
        """How far (m) y projected along n lies on the inner side of the edge p -> q (counter-clockwise
        about n): the edge function n.((q - p) x (y - p)) / |q - p|, negative beyond it."""
        return wp.dot(n, wp.cross(q - p, y - p)) / wp.length(q - p)

    @wp.func
    def leaves_clear(
        n: vec3,
        a: vec3,
        b: vec3,
        c: vec3,
        x: vec3,
        v: vec3,
        g: vec3,
        radius: scalar,
        height: scalar,
        gap: scalar,
        speed: scalar,
        half: scalar,
        deep: scalar,
    ):
        """Whether a centre x within R in front of triangle (a, b, c) (height in [0, R), gap =
        height - R, leaving at `speed` > 0, `half` = g.n / 2) gets out to R of its plane, and until
        then stays farther than R from every point on or behind its plane that projects outside the
        triangle or onto its edges (projected inside it by e (m), less its displacement until then
        and rounding, with e^2 + height^2 > R^2: such a point's distance is at least
        sqrt(e^2 + height^2)) or lies more than its overlap -gap deeper than the plane (`deep`, m:
        the least depth of those that project inside)."""
        disc = speed * speed - scalar(4.0) * half * gap
        if disc < scalar(0.0) or -gap >= deep:
            return False
        out = scalar(-2.0) * gap / (speed + wp.sqrt(disc))  # (s) when it is R out
        e0, e1, e2 = edge_distance(n, a, b, x), edge_distance(n, b, c, x), edge_distance(n, c, a, x)
        moved = (wp.length(v) + scalar(0.5) * wp.length(g) * out) * out
        spans = l1(b - a) + l1(c - b) + l1(a - c)  # (the inset `inner_depths` leaves, twice)
        rounded = EDGE * (l1(x - a) + spans) + state_rounding(x) + scalar(2.0 * INSET) * spans
        inner = wp.min(wp.min(e0, e1), e2) - moved - rounded
        return inner > scalar(0.0) and inner * inner + height * height > radius * radius

    return SimpleNamespace(
        vertices=vertices,
        edge_distance=edge_distance,
        leaves_clear=leaves_clear,
        single=single,
        l1=l1,
        inside=inside,
        descending=descending,
        frame=frame,
        scale=scale,
        state_rounding=state_rounding,
        height_noise=height_noise,
    )


@functools.cache
def make_bound_rule(precision: str, over, leaves):
    """`bound(surfaces, k, face, a, b, c, n, x, v, g, radius, before, deep)` -> (time, clear): the
    parabola of eq. (36) against the plane through a of unit normal n, offset by R (the plane's
    quadratic, `ballistic.entry_time`; from behind the plane: its descending crossing), met where
    `over(surfaces, k, face, n, a, b, c, y)` holds of the centre y then, or at the latest where the
    centre itself descends through the plane over it; clear (s): when the centre, more than R in
    front, or touching (within the touching band) and leaving, or within R and leaving as
    `leaves(surfaces, k, face, n, a, b, c, x, v, g, radius, height, gap, speed, half, deep)` allows,
    first comes within R of the plane (MAX_FLIGHT_TIME: never), else 0. NO_CONTACT where the offset
    plane is reached no earlier than `before` (>= 0; s). A triangle's (`triangle_bound`: `inside`)
    and a flat mesh's (`physics.flat_contact`: on any of its triangles)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    ballistic = make_ballistic(precision)
    entry_time, position = ballistic.entry_time, ballistic.position
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])
    LATEST = scalar(MAX_FLIGHT_TIME)
    basics = make_triangle_basics(precision)
    l1, descending = basics.l1, basics.descending

    @wp.func
    def bound(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        a: vec3,
        b: vec3,
        c: vec3,
        n: vec3,
        x: vec3,
        v: vec3,
        g: vec3,
        radius: scalar,
        before: scalar,
        deep: scalar,
    ):
        """(time, clear) on the plane through a of unit normal n (`make_bound_rule`)."""
        height = wp.dot(x - a, n)
        noise = basics.height_noise(surfaces, k, x, a, n)
        speed = wp.dot(v, n)
        half = scalar(0.5) * wp.dot(g, n)
        if wp.abs(half) <= TOLERANCE * l1(g):
            half = scalar(0.0)  # gravity along the triangle, up to rounding
        gap = height - radius
        if wp.abs(gap) <= TOLERANCE * (noise + radius):
            gap = scalar(0.0)  # the touching band
        best = scalar(NO_CONTACT)
        clear = scalar(0.0)
        if height >= scalar(0.0):
            best = entry_time(gap, speed, half)  # the plane's rule, overlapping included
            if gap > scalar(0.0) or (gap == scalar(0.0) and speed > scalar(0.0)):
                clear = wp.where(best >= scalar(0.0), best, LATEST)
            elif speed > scalar(0.0) and leaves(surfaces, k, face, n, a, b, c, x, v, g, radius, height, gap, speed, half, deep):
                clear = wp.where(best >= scalar(0.0), best, LATEST)
        else:
            best = descending(gap, speed, half)
        if before >= scalar(0.0) and best >= before:
            return scalar(NO_CONTACT), clear
        if best >= scalar(0.0) and not over(surfaces, k, face, n, a, b, c, position(x, v, g, best)):
            best = scalar(NO_CONTACT)
        if best >= scalar(0.0):  # (the centre reaches the triangle itself no earlier)
            return best, clear
        if wp.abs(height) <= TOLERANCE * noise:
            height = scalar(0.0)
        through = descending(height, speed, half)  # the centre reaching the triangle itself
        if through >= scalar(0.0) and over(surfaces, k, face, n, a, b, c, position(x, v, g, through)):
            best = through
        return best, clear

    return bound


@functools.cache
def make_mesh_contact(precision: str, large: bool = True) -> SimpleNamespace:
    """`mesh_time(surfaces, k, x, v, g, R)`, `mesh_normal(surfaces, k, x)` and the helpers the air's
    search and posts share (`vertices`, `inside`, `l1`, `single`, `descending`) of one precision.
    `large` False: every mesh has at most FEW_FACES triangles (`touched` compiles no BVH query)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    TOLERANCE, EDGE = scalar(ROUNDING * EPSILON[precision]), scalar(EDGE_ROUNDING * EPSILON[precision])
    LATEST = scalar(MAX_FLIGHT_TIME)
    basics = make_triangle_basics(precision)
    vertices, single, l1, inside = basics.vertices, basics.single, basics.l1, basics.inside
    cells = make_grid_cells(precision)

    @wp.func
    def face_over(surfaces: Surfaces, k: wp.int32, face: wp.int32, n: vec3, a: vec3, b: vec3, c: vec3, y: vec3):
        """Whether y projected along n lies on triangle (a, b, c) (`inside`)."""
        return inside(n, a, b, c, y)

    @wp.func
    def face_leaves(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        n: vec3,
        a: vec3,
        b: vec3,
        c: vec3,
        x: vec3,
        v: vec3,
        g: vec3,
        radius: scalar,
        height: scalar,
        gap: scalar,
        speed: scalar,
        half: scalar,
        deep: scalar,
    ):
        """`leaves_clear` of triangle (a, b, c)."""
        return basics.leaves_clear(n, a, b, c, x, v, g, radius, height, gap, speed, half, deep)

    bound_rule = make_bound_rule(precision, face_over, face_leaves)

    @wp.func
    def triangle_bound(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        x: vec3,
        v: vec3,
        g: vec3,
        radius: scalar,
        before: scalar,
        deep: scalar,
    ):
        """(`triangle_time`, clear): clear (s) is when the centre, starting more than R in front of
        the triangle's plane, or touching it (within the touching band) and leaving it, or within R
        and leaving it over the triangle clear of its edges (`leaves_clear`, with `deep`), first
        comes within R of it (MAX_FLIGHT_TIME: never); else 0. The time is NO_CONTACT too
        where the offset plane is reached no earlier than `before` (>= 0; s): the triangle itself
        no earlier, then."""
        a, b, c = vertices(surfaces, k, face)
        n = wp.cross(b - a, c - a)
        size = wp.length(n)
        if size == scalar(0.0):
            return scalar(NO_CONTACT), scalar(0.0)
        return bound_rule(surfaces, k, face, a, b, c, n / size, x, v, g, radius, before, deep)

    @wp.func
    def triangle_time(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar):
        """When the parabola meets triangle `face` of mesh k (module docstring), or NO_CONTACT."""
        best, _clear = triangle_bound(surfaces, k, face, x, v, g, radius, scalar(NO_CONTACT), scalar(0.0))
        return best

    @wp.func
    def triangle_before(
        surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar, before: scalar
    ):
        """`triangle_time`, NO_CONTACT where the triangle is met no earlier than `before` (>= 0; s)."""
        best, _clear = triangle_bound(surfaces, k, face, x, v, g, radius, before, scalar(0.0))
        return best

    @wp.func
    def earlier(best: scalar, when: scalar):
        """The earlier of two contact times, NO_CONTACT (< 0) for none."""
        if when >= scalar(0.0) and (best < scalar(0.0) or when < best):
            return when
        return best

    @wp.func
    def window(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, g: vec3, grow: scalar):
        """A time (s) after which the centre stays off mesh k's box grown by `grow` (0: never near)."""
        low = surfaces.mesh_low[k] - vec3(grow, grow, grow)
        high = surfaces.mesh_high[k] + vec3(grow, grow, grow)
        gravity = wp.length(g)
        if gravity > scalar(0.0):  # below the box along gravity and falling: never back
            down = g / gravity
            floor = scalar(0.0)
            for i in range(3):  # the box's farthest corner along gravity
                floor = floor + wp.max(low[i] * down[i], high[i] * down[i])
            depth = floor - wp.dot(x, down)  # how far it may fall before it is past the box
            speed = wp.dot(v, down)
            if depth < scalar(0.0) and speed >= scalar(0.0):
                return scalar(0.0)
            disc = speed * speed + scalar(2.0) * gravity * wp.max(depth, scalar(0.0))
            return wp.min((wp.sqrt(disc) - speed) / gravity, LATEST)
        last = LATEST  # a straight line: the slab test
        for i in range(3):
            if v[i] == scalar(0.0):
                if x[i] < low[i] or x[i] > high[i]:
                    return scalar(0.0)
            else:
                last = wp.min(last, wp.max((low[i] - x[i]) / v[i], (high[i] - x[i]) / v[i]))
        return wp.max(last, scalar(0.0))

    @wp.func
    def mesh_normal(surfaces: Surfaces, k: wp.int32, x: vec3):
        """The unit normal of the triangle of mesh k nearest x (the BVH's closest point, float32)."""
        query = wp.mesh_query_point_no_sign(surfaces.mesh[k], single(x), wp.float32(1.0e30))
        if not query.result:
            return surfaces.normal[k]
        a, b, c = vertices(surfaces, k, query.face)
        return wp.normalize(wp.cross(b - a, c - a))

    @wp.func
    def steeper(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        x: vec3,
        v: vec3,
        slack: scalar,
        grow: scalar,
        fine: scalar,
        steepest: scalar,
        best: vec3,
        over: wp.bool,
        chosen: wp.int32,
    ):
        """(closing speed, normal, over, face) of triangle `face` if x touches it (0 to R in front,
        within R beside its edges) and v approaches it more steeply than `steepest` (as steeply and
        `face` < `chosen`, the triangle that gave it: the lowest-numbered at a tie, in any order), else
        the arguments; `over` or'ed with whether x is over it as a face contact leaves it (R or 0 in
        front, within `slack`; beside it within `fine`)."""
        a, b, c = vertices(surfaces, k, face)
        n = wp.cross(b - a, c - a)
        if wp.length(n) > scalar(0.0):
            n = wp.normalize(n)
            height = wp.dot(x - a, n)
            closing = wp.dot(v, n)
            if height >= -slack and height <= grow:
                y = x - n * height  # the edge functions within R of the triangle
                far = -wp.max(grow, fine)  # (past it on one edge: neither test below can pass)
                beside = basics.edge_distance(n, a, b, y)
                if beside >= far:
                    beside = wp.min(beside, basics.edge_distance(n, b, c, y))
                if beside >= far:
                    beside = wp.min(beside, basics.edge_distance(n, c, a, y))
                if beside >= -fine and (height <= slack or height >= grow - scalar(2.0) * slack):
                    over = True  # as the faces' two rules leave a centre: R or 0 in front
                tie = closing == steepest and closing < scalar(0.0) and face < chosen
                if (closing < steepest or tie) and beside >= -grow:
                    return closing, n, over, face
        return steepest, best, over, chosen

    @wp.func
    def boxed(surfaces: Surfaces, k: wp.int32, face: wp.int32, low: wp.vec3f, high: wp.vec3f):
        """Whether triangle `face`'s float32 box meets the box (low, high), as the BVH's leaf test."""
        a, b, c = vertices(surfaces, k, face)
        a32, b32, c32 = single(a), single(b), single(c)
        lo, hi = wp.min(wp.min(a32, b32), c32), wp.max(wp.max(a32, b32), c32)
        return not (low[0] > hi[0] or low[1] > hi[1] or low[2] > hi[2] or high[0] < lo[0] or high[1] < lo[1] or high[2] < lo[2])

    @wp.func
    def touched(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, radius: scalar):
        """(`contact_normal`, whether x is over a triangle of mesh k as its contact leaves it: R or
        0 in front of it within FLOAT32_SLACK of the coordinates' scale in the mesh's frame
        (`scale`) and the centre's own rounding, projected on it within EDGE_ROUNDING eps of that
        scale). The BVH's query box is grown by its float32 rounding of the world's coordinates."""
        low, high = surfaces.mesh_low[k], surfaces.mesh_high[k]
        size, rounded = basics.scale(surfaces, k, x), basics.state_rounding(x) + TOLERANCE * radius
        slack = scalar(FLOAT32_SLACK) * size + rounded
        fine = EDGE * size + rounded
        grow = radius + slack
        box = radius + scalar(FLOAT32_SLACK) * (l1(low) + l1(high) + l1(x)) + rounded
        best = vec3()
        steepest = scalar(0.0)
        over = wp.bool(False)
        chosen = wp.int32(2147483647)
        faces = surfaces.mesh_faces[k]
        if faces <= FEW_FACES or not wp.static(large):
            for face in range(faces):
                steepest, best, over, chosen = steeper(surfaces, k, face, x, v, slack, grow, fine, steepest, best, over, chosen)
        elif wp.static(large):
            box_low, box_high = single(x - vec3(box, box, box)), single(x + vec3(box, box, box))
            if cells.walked(surfaces, k):  # the BVH's candidates: in the cells near x, boxes meeting its box
                i0, i1, j0, j1 = cells.around(surfaces, k, x, scalar(3.0) * (box + grow))
                for j in range(j0, j1 + 1):
                    for i in range(i0, i1 + 1):
                        face = cells.face_of(surfaces, k, i, j)
                        for f in range(face, wp.where(face >= 0, face + 2, face)):
                            if boxed(surfaces, k, f, box_low, box_high):
                                steepest, best, over, chosen = steeper(
                                    surfaces, k, f, x, v, slack, grow, fine, steepest, best, over, chosen
                                )
            else:
                query = wp.mesh_query_aabb(surfaces.mesh[k], box_low, box_high)
                face = wp.int32(0)
                while wp.mesh_query_aabb_next(query, face):
                    steepest, best, over, chosen = steeper(
                        surfaces, k, face, x, v, slack, grow, fine, steepest, best, over, chosen
                    )
        if steepest < scalar(0.0):
            return best, over
        return mesh_normal(surfaces, k, x), over

    @wp.func
    def contact_normal(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, radius: scalar):
        """The normal of the triangle touched at x (centre 0 to R in front, within R beside its
        edges) that v approaches most steeply; else the nearest triangle's (`mesh_normal`)."""
        n, _over = touched(surfaces, k, x, v, radius)
        return n

    helpers = {**vars(basics), **vars(make_mesh_lookup(precision))}
    return SimpleNamespace(
        triangle_time=triangle_time,
        triangle_bound=triangle_bound,
        triangle_before=triangle_before,
        earlier=earlier,
        window=window,
        mesh_normal=mesh_normal,
        touched=touched,
        contact_normal=contact_normal,
        boxed=boxed,
        walked=cells.walked,
        face_of=cells.face_of,
        around=cells.around,
        across=cells.across,
        **helpers,
    )


@functools.cache
def make_mesh_search(precision: str, features_time=None, large: bool = True, flat_bound=None) -> SimpleNamespace:
    """`mesh_time(surfaces, k, x, v, g, R)`: the earliest of `triangle_time` and, with
    `features_time(surfaces, k, face, x, v, g, R, start, stop)` (what else the triangle owns, met
    in [start, stop] s, else NO_CONTACT), of that, over the triangles the chords' boxes find (their
    chord's times) or, for a small mesh, every triangle: its faces first, then their features
    until the earliest face contact (at equal times the face; module docstring), and in a small
    mesh from when the centre first comes within R of every covering face's plane (`face_cover`,
    the times from `triangle_bound`); the raster walk takes `triangle_before`, cut short at the
    contact found. `large` False: every mesh is small (no chords' BVH queries compiled in);
    `flat_bound(surfaces, k, x, v, g, R)` -> (time, clear): every mesh is small and flat, searched
    as its plane (`physics.flat_contact`), its first triangle covering its border."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    position = make_ballistic(precision).position
    LATEST = scalar(MAX_FLIGHT_TIME)
    mc = make_mesh_contact(precision, large)
    face_time = mc.triangle_time
    single, l1, earlier, window = mc.single, mc.l1, mc.earlier, mc.window
    FEATURES, FLAT = features_time is not None, flat_bound is not None
    grid = make_grid_walk(precision, mc.triangle_before)  # (a terrain owns no edges or corners)

    @wp.func
    def near(low: vec3, high: vec3, grow: scalar, x: vec3, v: vec3, g: vec3, end: scalar):
        """(start, stop) s: the times within [0, end] where the centre is within the cylinder along
        gravity around the box (low, high) grown by `grow` (m): across gravity the path is a
        straight line (stop < start: never; no gravity: [0, end])."""
        gravity = wp.length(g)
        start = scalar(0.0)
        stop = end
        if gravity > scalar(0.0):
            down = g / gravity
            d = x - scalar(0.5) * (low + high)
            d = d - wp.dot(d, down) * down
            u = v - wp.dot(v, down) * down
            reach = scalar(0.5) * wp.length(high - low) + grow
            a, b, c = wp.dot(u, u), wp.dot(d, u), wp.dot(d, d) - reach * reach
            if a > scalar(0.0):
                disc = b * b - a * c
                if disc < scalar(0.0):
                    stop = scalar(-1.0)
                else:
                    start = wp.max(start, (-b - wp.sqrt(disc)) / a)
                    stop = wp.min(stop, (wp.sqrt(disc) - b) / a)
            elif c > scalar(0.0):
                stop = scalar(-1.0)
        return start, stop

    @wp.func
    def chords_time(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar, end: scalar, slack: scalar):
        """`mesh_time` of a mesh of more than FEW_FACES triangles: its chords' boxes queried in time
        order over the window [0, end] s (module docstring)."""
        low, high = surfaces.mesh_low[k], surfaces.mesh_high[k]
        best = scalar(NO_CONTACT)
        gravity = wp.length(g)
        span = wp.length(v) * end + scalar(0.5) * gravity * end * end  # >= the arc: CHORD_EDGES edges a chord ...
        wanted = span / (scalar(CHORD_EDGES) * wp.max(surfaces.mesh_edge[k], radius))
        if gravity > scalar(0.0):  # ... and of sagitta |g| h^2 / 8 at most SAGITTA of the diagonal
            target = wp.max(scalar(SAGITTA) * wp.length(high - low), radius)
            wanted = wp.max(wanted, end * wp.sqrt(gravity / (scalar(8.0) * target)))
        chords = wp.int32(wp.min(wanted, scalar(MAX_CHORDS))) + 1
        h = end / scalar(chords)
        grow = radius + slack + scalar(0.125) * gravity * h * h
        start = x
        face = wp.int32(0)
        for i in range(chords):
            stop = position(x, v, g, h * scalar(i + 1))
            a = wp.min(start, stop) - vec3(grow, grow, grow)
            b = wp.max(start, stop) + vec3(grow, grow, grow)
            spread = scalar(FLOAT32_SLACK) * (l1(a) + l1(b))
            a = a - vec3(spread, spread, spread)
            b = b + vec3(spread, spread, spread)
            query = wp.mesh_query_aabb(surfaces.mesh[k], single(a), single(b))
            while wp.mesh_query_aabb_next(query, face):
                when = face_time(surfaces, k, face, x, v, g, radius)
                if wp.static(FEATURES):  # what it owns, met before it within this chord
                    until = h * scalar(i + 1)
                    if when >= scalar(0.0):
                        until = wp.min(until, when)
                    when = earlier(when, features_time(surfaces, k, face, x, v, g, radius, h * scalar(i), until))
                best = earlier(best, when)
            if best >= scalar(0.0) and best <= h * scalar(i + 1):
                break
            start = stop
        return best

    @wp.func
    def mesh_time(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar):
        """Time (s) until the parabola of eq. (36) meets mesh k, or NO_CONTACT (module docstring)."""
        low, high = surfaces.mesh_low[k], surfaces.mesh_high[k]
        slack = scalar(FLOAT32_SLACK) * (l1(low) + l1(high) + scalar(1.0e-30))
        end = window(surfaces, k, x, v, g, radius + slack)
        best = scalar(NO_CONTACT)
        if end <= scalar(0.0):
            return best
        faces = surfaces.mesh_faces[k]
        if wp.static(large):
            if faces > FEW_FACES:
                walked = wp.bool(False)
                if grid.walked(surfaces, k):
                    best, walked = grid.grid_time(surfaces, k, x, v, g, radius, end)
                if not walked:
                    best = chords_time(surfaces, k, x, v, g, radius, end, slack)
                return wp.where(best > LATEST, scalar(NO_CONTACT), best)
        clear = scalar(0.0)  # a small mesh: every triangle, then what they own
        first = surfaces.face_first[k]
        if wp.static(FLAT):  # one plane (its first triangle covers its border)
            best, clear = flat_bound(surfaces, k, x, v, g, radius)
        else:
            for face in range(faces):
                if wp.static(FEATURES):  # no edge or corner is met before a covering face's offset plane
                    covers = first >= 0 and surfaces.face_cover[first + face] != 0
                    deep = scalar(0.0)
                    if covers:
                        deep = surfaces.face_depth[first + face]
                    when, bound = mc.triangle_bound(surfaces, k, face, x, v, g, radius, best, deep)
                    if covers:
                        clear = wp.max(clear, bound)
                    best = earlier(best, when)
                else:
                    best = earlier(best, face_time(surfaces, k, face, x, v, g, radius))
        if wp.static(FEATURES):
            if clear < wp.where(best >= scalar(0.0), best, LATEST):  # (at equal times the face)
                after, until = near(low, high, radius + slack, x, v, g, end)
                after = wp.max(after, clear)
                if best >= scalar(0.0):
                    until = wp.min(best, until)
                if after < until or (after == until and best < scalar(0.0)):
                    for face in range(faces):
                        best = earlier(best, features_time(surfaces, k, face, x, v, g, radius, after, until))
        return wp.where(best > LATEST, scalar(NO_CONTACT), best)

    return SimpleNamespace(mesh_time=mesh_time)


@functools.cache
def make_mesh_faces(precision: str) -> SimpleNamespace:
    """`face_plane`, `on_face` and `face_reach` of one triangle of a mesh (`physics.triangle_follow`)."""
    t = types_for(precision)
    vec3, Surfaces = t.vec3, t.Surfaces
    mc = make_mesh_contact(precision)
    vertices, inside = mc.vertices, mc.inside

    @wp.func
    def face_plane(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3):
        """(height, noise, normal) of x over triangle `face` of mesh k's plane, as `geometry.locate`'s."""
        a, b, c = vertices(surfaces, k, face)
        n = wp.normalize(wp.cross(b - a, c - a))
        return wp.dot(x - a, n), mc.height_noise(surfaces, k, x, a, n), n

    @wp.func
    def on_face(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3):
        """Whether x projected along triangle `face`'s normal lies on it (`inside`)."""
        a, b, c = vertices(surfaces, k, face)
        return inside(wp.normalize(wp.cross(b - a, c - a)), a, b, c, x)

    @wp.func
    def face_reach(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3):
        """A distance (m) from x beyond which every point is off triangle `face`."""
        a, b, c = vertices(surfaces, k, face)
        return wp.length(x - a) + wp.length(b - a) + wp.length(c - a)

    return SimpleNamespace(face_plane=face_plane, on_face=on_face, face_reach=face_reach)
