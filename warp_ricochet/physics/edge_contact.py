"""A sphere against a mesh's convex edges and corners (docs/geometry.md, "Meshes and boxes"); read
only through `physics.geometry` and the air's search (kernels compiled with meshes).

Where two faces of a mesh meet at a convex edge (or a face ends at a border), the R-offsets of the
faces leave a wedge uncovered: a sphere whose centre passes through it within R of the edge touches
the edge but neither face's offset plane over the face. The host keeps those edges and their end
points (`physics.mesh_edges`); each is owned by one triangle, tested where that triangle is a
candidate (`mesh_contact.make_mesh_search`: the chords' BVH queries, or every triangle of a mesh
of at most FEW_FACES).

- An edge from p to q is a post of radius 0 (`cylinder_contact`): met where the centre's distance
  from the line closes to R with its projection on the segment (inclusive within EDGE_ROUNDING eps
  of the centre's and the edge's coordinates from its end: the edge's own frame), or at once where it is within R there and closing. A corner is a
  post of zero axis: met where |x - c| closes to R. Vacuum: `side_time`'s roots of the quartic on
  the parabola of eq. (36); air: `line_theta` on the step's Hermite.
- The edges and corners are met from every side (a border edge of an open mesh from behind it too).
- The earliest of a mesh's faces, edges and corners is its contact; at equal times the face.
- The normal (`contact_normal`): where the contact's centre is over no face (projected inside a
  triangle, 0 to R in front of it, within rounding) but within R of a kept edge or corner, the
  radial one from the nearest such point to the centre; otherwise the faces' (`mesh_contact`).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON, NO_CONTACT, ROUNDING, make_ballistic
from .cylinder_contact import make_cylinder_contact
from .flat_contact import make_flat_contact
from .inlining import out_of_line_if
from .mesh_contact import EDGE_ROUNDING, FEW_FACES, FLOAT32_SLACK, make_mesh_contact, make_mesh_search
from .types import types_for


@functools.cache
def make_edge_contact(precision: str, large: bool = True, edges: bool = True, flat: bool = False) -> SimpleNamespace:
    """`mesh_time` (faces, edges and corners), `features_time` (its edges and corners), `features_theta`, `contact_normal` and `touching`
    (module docstring). `large` False: every mesh has at most FEW_FACES triangles (no BVH queries compiled
    in); `edges` False: no mesh owns edges or corners (their tests compiled out); `flat` True: every
    mesh is small and flat, its faces searched as its plane (`physics.flat_contact`)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    ZERO, ONE, TWO = scalar(0.0), scalar(1.0), scalar(2.0)
    mc, posts, flats = make_mesh_contact(precision, large), make_cylinder_contact(precision), make_flat_contact(precision)
    side_time, line_theta, l1, earlier = posts.side_time, posts.line_theta, mc.l1, mc.earlier
    position = make_ballistic(precision).position
    EDGE, TOLERANCE = scalar(EDGE_ROUNDING * EPSILON[precision]), scalar(ROUNDING * EPSILON[precision])

    @wp.func
    def ends(surfaces: Surfaces, e: wp.int32):
        """Edge e's end points (m)."""
        return surfaces.edge_ends[2 * e], surfaces.edge_ends[2 * e + 1]

    @wp.func
    def edge(surfaces: Surfaces, e: wp.int32):
        """Edge e: its first end p (m), unit direction a and length L (m)."""
        p, q = surfaces.edge_ends[2 * e], surfaces.edge_ends[2 * e + 1]
        length = wp.length(q - p)
        return p, (q - p) / length, length

    @wp.func
    def owned(surfaces: Surfaces, k: wp.int32, face: wp.int32):
        """The edges and corners triangle `face` of mesh k owns (-1: none)."""
        first = surfaces.face_first[k]
        if first < 0:  # a mesh without (a terrain)
            return wp.vec3i(-1, -1, -1), wp.vec3i(-1, -1, -1)
        return surfaces.face_edges[first + face], surfaces.face_corners[first + face]

    @wp.func
    def apart(p: vec3, q: vec3, low: vec3, high: vec3, grow: scalar):
        """Whether the box of the segment p-q grown by `grow` (m) misses the box (low, high)."""
        a, b = wp.min(p, q) - vec3(grow, grow, grow), wp.max(p, q) + vec3(grow, grow, grow)
        return a[0] > high[0] or a[1] > high[1] or a[2] > high[2] or b[0] < low[0] or b[1] < low[1] or b[2] < low[2]

    @wp.func
    def segment_gap(p: vec3, q: vec3, c0: vec3, c1: vec3):
        """The least distance (m) between the segments p-q and c0-c1, either of them a point
        (Ericson, Real-Time Collision Detection, 2005, 5.1.9)."""
        d1, d2, r = q - p, c1 - c0, p - c0
        a, e, f = wp.dot(d1, d1), wp.dot(d2, d2), wp.dot(d2, r)
        s = ZERO
        u = ZERO
        if a > ZERO and e == ZERO:
            s = wp.clamp(-wp.dot(d1, r) / a, ZERO, ONE)
        elif a == ZERO and e > ZERO:
            u = wp.clamp(f / e, ZERO, ONE)
        elif a > ZERO:
            c, b = wp.dot(d1, r), wp.dot(d1, d2)
            denominator = a * e - b * b
            if denominator > ZERO:
                s = wp.clamp((b * f - c * e) / denominator, ZERO, ONE)
            u = (b * s + f) / e
            if u < ZERO:
                u = ZERO
                s = wp.clamp(-c / a, ZERO, ONE)
            elif u > ONE:
                u = ONE
                s = wp.clamp((b - c) / a, ZERO, ONE)
        return wp.length(p + s * d1 - (c0 + u * d2))

    @out_of_line_if(True)
    @wp.func
    def features_time(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        x: vec3,
        v: vec3,
        g: vec3,
        radius: scalar,
        start: scalar,
        stop: scalar,
    ):
        """When the parabola of eq. (36) first meets an edge or corner triangle `face` owns, or
        NO_CONTACT; one that the chord from `start` to `stop` (s) passes farther from than R, its
        sagitta |g| (stop - start)^2 / 8 and rounding is not met in that time and is skipped
        (stop < start: none is). One function in CUDA code (`physics.inlining`): run only where no
        covering face rules the edges out, its inlined copies only cost the kernels room."""
        best = scalar(NO_CONTACT)
        if stop < start or surfaces.face_first[k] < 0:  # (no edges: a terrain)
            return best
        edges, corners = owned(surfaces, k, face)
        _mesh, mesh_low, mesh_high = mc.bounds(surfaces, k)
        c0, c1 = position(x, v, g, start), position(x, v, g, stop)
        near = radius + scalar(0.125) * wp.length(g) * (stop - start) * (stop - start)  # (rounding: the
        near += EDGE * (l1(c0) + l1(c1) + radius + scalar(2.0) * (l1(mesh_low) + l1(mesh_high)))  # mesh's scale)
        low, high = wp.min(c0, c1), wp.max(c0, c1)
        features = wp.int32(6)  # a run-time loop (edges 0-2, corners 3-5): one copy of the quartic
        for j in range(features):
            index = wp.int32(-1)
            p = vec3()
            q = vec3()
            if j < 3:
                index = edges[j]
                if index >= 0:
                    p, q = ends(surfaces, index)
            else:
                index = corners[j - 3]
                if index >= 0:
                    p = surfaces.corner_points[index]
                    q = p
            if index >= 0:
                if not apart(p, q, low, high, near) and segment_gap(p, q, c0, c1) <= near:
                    length = wp.length(q - p)  # (0: a corner, a post of zero axis)
                    axis = vec3()
                    if length > ZERO:
                        axis = (q - p) / length
                    slack = EDGE * (l1(x - p) + length)  # (the edge's own frame: x - p, not x)
                    best = earlier(best, side_time(x - p, v, g, axis, radius, ZERO, length, slack))
        return best

    @wp.func
    def features_theta(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        h: scalar,
        x0: vec3,
        v0: vec3,
        a0: vec3,
        x1: vec3,
        v1: vec3,
        a1: vec3,
        radius: scalar,
        low: vec3,
        high: vec3,
    ):
        """The first theta in [0, 1] on an air step where an edge or corner triangle `face` owns is
        met (2: none); one whose box grown by R and rounding misses the box (low, high) that holds
        the step's interpolant is skipped."""
        best = TWO
        if surfaces.face_first[k] < 0:  # no edges (a terrain)
            return best
        edges, corners = owned(surfaces, k, face)
        d0, e0, d1, e1 = h * v0, h * h * a0, h * v1, h * h * a1
        grow = radius + EDGE * (l1(low) + l1(high) + radius)
        for j in range(3):
            if edges[j] >= 0:
                p, a, length = edge(surfaces, edges[j])
                if not apart(p, p + length * a, low, high, grow + EDGE * (l1(p) + length)):
                    slack = EDGE * (l1(x0 - p) + length)
                    best = wp.min(best, line_theta(p, a, ZERO, length, radius, slack, x0, d0, e0, x1, d1, e1))
            if corners[j] >= 0:
                c = surfaces.corner_points[corners[j]]
                if not apart(c, c, low, high, grow + EDGE * l1(c)):
                    slack = EDGE * l1(x0 - c)
                    best = wp.min(best, line_theta(c, vec3(), ZERO, ZERO, radius, slack, x0, d0, e0, x1, d1, e1))
        return best

    @wp.func
    def nearest(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3, found: scalar, radial: vec3):
        """(distance, unit direction) from the nearest point of the edges and corners triangle
        `face` owns to x, if nearer than `found`; else (found, radial)."""
        edges, corners = owned(surfaces, k, face)
        for j in range(3):
            r = vec3()
            if edges[j] >= 0:
                p, axis, length = edge(surfaces, edges[j])
                r = x - (p + wp.clamp(wp.dot(x - p, axis), ZERO, length) * axis)
                if wp.length(r) < found and wp.length(r) > ZERO:
                    found = wp.length(r)
                    radial = r / found
            if corners[j] >= 0:
                r = x - surfaces.corner_points[corners[j]]
                if wp.length(r) < found and wp.length(r) > ZERO:
                    found = wp.length(r)
                    radial = r / found
        return found, radial

    @wp.func
    def touching(surfaces: Surfaces, k: wp.int32, x: vec3, radius: scalar):
        """(distance m, unit radial, reach m): from the nearest point of a kept edge or corner of
        mesh k to x, if nearer than reach = R + rounding (FLOAT32_SLACK of the coordinates' scale
        in the mesh's frame, `scale`, and the centre's own rounding); else (reach, 0, reach)."""
        mesh, low, high = mc.bounds(surfaces, k)
        rounded = mc.state_rounding(x) + TOLERANCE * radius
        grow = radius + scalar(FLOAT32_SLACK) * mc.scale(surfaces, k, x) + rounded
        found = grow
        radial = vec3()
        if wp.static(edges):
            faces = mc.faces(surfaces, k)
            if faces <= FEW_FACES or not wp.static(large):
                for face in range(faces):
                    found, radial = nearest(surfaces, k, face, x, found, radial)
            elif wp.static(large):
                reach = radius + scalar(FLOAT32_SLACK) * (l1(low) + l1(high) + l1(x)) + rounded  # (the BVH's)
                box = vec3(reach, reach, reach)
                query = wp.mesh_query_aabb(mesh, mc.single(x - box), mc.single(x + box))
                face = wp.int32(0)
                while wp.mesh_query_aabb_next(query, face):
                    found, radial = nearest(surfaces, k, face, x, found, radial)
        return found, radial, grow

    @wp.func
    def contact_normal(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, radius: scalar):
        """The unit normal of a contact with mesh k at centre x, velocity v (module docstring)."""
        if wp.static(flat):  # (a constant: one branch compiled)
            n, over = flats.flat_touched(surfaces, k, x, radius)
        else:
            n, over = mc.touched(surfaces, k, x, v, radius)
        if over or not wp.static(edges):
            return n
        found, radial, grow = touching(surfaces, k, x, radius)
        if found < grow:
            return radial
        return n

    flat_bound = flats.flat_bound if flat else None
    mesh_time = make_mesh_search(precision, features_time if edges else None, large, flat_bound).mesh_time
    return SimpleNamespace(
        mesh_time=mesh_time,
        features_time=features_time,
        features_theta=features_theta,
        contact_normal=contact_normal,
        touching=touching,
    )
