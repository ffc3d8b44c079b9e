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
  of the coordinates' scale), or at once where it is within R there and closing. A corner is a
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

from .ballistic import EPSILON, NO_CONTACT, ROUNDING
from .cylinder_contact import make_cylinder_contact
from .mesh_contact import EDGE_ROUNDING, FEW_FACES, FLOAT32_SLACK, make_mesh_contact, make_mesh_search
from .types import types_for


@functools.cache
def make_edge_contact(precision: str) -> SimpleNamespace:
    """`mesh_time` (faces, edges and corners), `features_theta` and `contact_normal` (module docstring)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    ZERO, TWO = scalar(0.0), scalar(2.0)
    mc, posts = make_mesh_contact(precision), make_cylinder_contact(precision)
    side_time, line_theta, l1, earlier = posts.side_time, posts.line_theta, mc.l1, mc.earlier
    EDGE, TOLERANCE = scalar(EDGE_ROUNDING * EPSILON[precision]), scalar(ROUNDING * EPSILON[precision])

    @wp.func
    def edge(surfaces: Surfaces, e: wp.int32):
        """Edge e: its first end p (m), unit direction a and length L (m)."""
        p, q = surfaces.edge_ends[2 * e], surfaces.edge_ends[2 * e + 1]
        length = wp.length(q - p)
        return p, (q - p) / length, length

    @wp.func
    def owned(surfaces: Surfaces, k: wp.int32, face: wp.int32):
        """The edges and corners triangle `face` of mesh k owns (-1: none)."""
        row = surfaces.face_first[k] + face
        return surfaces.face_edges[row], surfaces.face_corners[row]

    @wp.func
    def features_time(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar):
        """When the parabola of eq. (36) first meets an edge or corner triangle `face` owns, or NO_CONTACT."""
        edges, corners = owned(surfaces, k, face)
        best = scalar(NO_CONTACT)
        for j in range(3):
            if edges[j] >= 0:
                p, a, length = edge(surfaces, edges[j])
                best = earlier(best, side_time(x - p, v, g, a, radius, ZERO, length, EDGE * (l1(x - p) + l1(p) + length)))
            if corners[j] >= 0:
                c = surfaces.corner_points[corners[j]]
                best = earlier(best, side_time(x - c, v, g, vec3(), radius, ZERO, ZERO, EDGE * (l1(x - c) + l1(c))))
        return best

    @wp.func
    def face_time(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar):
        """The earlier of triangle `face` (`mesh_contact`) and its edges and corners; ties: the face."""
        return earlier(mc.triangle_time(surfaces, k, face, x, v, g, radius), features_time(surfaces, k, face, x, v, g, radius))

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
    ):
        """The first theta in [0, 1] on an air step where an edge or corner triangle `face` owns is met (2: none)."""
        edges, corners = owned(surfaces, k, face)
        d0, e0, d1, e1 = h * v0, h * h * a0, h * v1, h * h * a1
        best = TWO
        for j in range(3):
            if edges[j] >= 0:
                p, a, length = edge(surfaces, edges[j])
                slack = EDGE * (l1(x0 - p) + l1(p) + length)
                best = wp.min(best, line_theta(p, a, ZERO, length, radius, slack, x0, d0, e0, x1, d1, e1))
            if corners[j] >= 0:
                c = surfaces.corner_points[corners[j]]
                slack = EDGE * (l1(x0 - c) + l1(c))
                best = wp.min(best, line_theta(c, vec3(), ZERO, ZERO, radius, slack, x0, d0, e0, x1, d1, e1))
        return best

    @wp.func
    def nearest(
        surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3, slack: scalar, grow: scalar, found: scalar, radial: vec3
    ):
        """(distance, unit direction) from the nearest point of the edges and corners triangle
        `face` owns to x, if nearer than `found`; and whether x is over the triangle (projected
        inside it, -slack to `grow` = R + slack in front of it)."""
        a, b, c = mc.vertices(surfaces, k, face)
        n = wp.cross(b - a, c - a)
        over = wp.bool(False)
        if wp.length(n) > ZERO:
            n = wp.normalize(n)
            height = wp.dot(x - a, n)
            over = height >= -slack and height <= grow and mc.inside(n, a, b, c, x)
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
        return found, radial, over

    @wp.func
    def contact_normal(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, radius: scalar):
        """The unit normal of a contact with mesh k at centre x, velocity v (module docstring)."""
        mesh, low, high = mc.bounds(surfaces, k)
        slack = scalar(FLOAT32_SLACK) * (l1(low) + l1(high) + l1(x)) + TOLERANCE * radius
        grow = radius + slack
        found = grow
        radial = vec3()
        over = wp.bool(False)
        faces = mc.faces(surfaces, k)
        if faces <= FEW_FACES:
            for face in range(faces):
                found, radial, on = nearest(surfaces, k, face, x, slack, grow, found, radial)
                over = over or on
        else:
            query = wp.mesh_query_aabb(mesh, mc.single(x - vec3(grow, grow, grow)), mc.single(x + vec3(grow, grow, grow)))
            face = wp.int32(0)
            while wp.mesh_query_aabb_next(query, face):
                found, radial, on = nearest(surfaces, k, face, x, slack, grow, found, radial)
                over = over or on
        if found < grow and not over:
            return radial
        return mc.contact_normal(surfaces, k, x, v, radius)

    mesh_time = make_mesh_search(precision, face_time).mesh_time
    return SimpleNamespace(mesh_time=mesh_time, features_theta=features_theta, contact_normal=contact_normal)
