"""A flat mesh searched as its plane (docs/geometry.md, "Flat meshes"); read only through
`physics.edge_contact` and the air's search (kernels of scenes whose solids are all flat small
meshes, `geometry.FLAT`).

A small mesh whose triangles all lie in its first triangle's plane, wound the same way, within the
rounding of its coordinates (`physics.mesh_edges.flat_mesh`, float64 on the host), has one offset
plane: the parabola of eq. (36) meets it at one time for every triangle, and the triangles differ
only in whether the centre's projection lies on them. So the plane's quadratic is solved once, on
the first triangle's vertex a and unit normal n from float64 (`Surfaces.flat_point`, `flat_normal`),
with a triangle's rules (`mesh_contact.make_bound_rule`), and the contact is where the centre's
projection lies on any triangle (`mesh_contact.inside`, edges included), or at the latest where the
centre itself descends through the plane on one. The earliest contact is the triangles' one by one
up to the rounding of their own normals; the contact normal is n. Border edges and corners are
searched as every small mesh's (`physics.edge_contact`): the first triangle covers them (all on its
plane), so only where its face is not met first.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON, ROUNDING
from .mesh_contact import EDGE_ROUNDING, FLOAT32_SLACK, make_bound_rule, make_triangle_basics
from .types import types_for


@functools.cache
def make_flat_contact(precision: str) -> SimpleNamespace:
    """`plane_of`, `over_any`, `flat_bound` and `flat_touched` of a flat mesh (module docstring),
    one precision."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    basics = make_triangle_basics(precision)
    vertices, l1 = basics.vertices, basics.l1
    TOLERANCE, EDGE = scalar(ROUNDING * EPSILON[precision]), scalar(EDGE_ROUNDING * EPSILON[precision])

    @wp.func
    def plane_of(surfaces: Surfaces, k: wp.int32):
        """Flat mesh k's plane: its first triangle's first vertex a (m) and unit normal n (from float64)."""
        return surfaces.flat_point[k], surfaces.flat_normal[k]

    @wp.func
    def beside(surfaces: Surfaces, k: wp.int32, face: wp.int32, y: vec3):
        """How far (m) y, in flat mesh k's frame (y - `mesh_contact.frame`), lies inside the nearest
        edge of triangle `face` in its plane (`mesh_edges.flat_edges`; negative beyond it)."""
        row = wp.int32(3) * (surfaces.face_first[k] + face)
        d0 = wp.dot(surfaces.flat_edge[row], y) - surfaces.flat_offset[row]
        d1 = wp.dot(surfaces.flat_edge[row + 1], y) - surfaces.flat_offset[row + 1]
        d2 = wp.dot(surfaces.flat_edge[row + 2], y) - surfaces.flat_offset[row + 2]
        return wp.min(wp.min(d0, d1), d2)

    @wp.func
    def over_any(surfaces: Surfaces, k: wp.int32, y: vec3):
        """Whether y projected on flat mesh k's plane lies on one of its triangles, edges included: inside
        each edge within EDGE_ROUNDING eps of |y - o|_1 and twice the mesh's extent (o: its frame)
        and y's own rounding, at least `mesh_contact.inside`'s tolerance."""
        low, high = surfaces.mesh_low[k], surfaces.mesh_high[k]
        local = y - basics.frame(surfaces, k)
        tolerance = EDGE * (l1(local) + scalar(2.0) * l1(high - low)) + basics.state_rounding(y)
        over = wp.bool(False)
        for face in range(surfaces.mesh_faces[k]):
            if not over:
                over = beside(surfaces, k, face, local) >= -tolerance
        return over

    @wp.func
    def mesh_over(surfaces: Surfaces, k: wp.int32, face: wp.int32, n: vec3, a: vec3, b: vec3, c: vec3, y: vec3):
        """`over_any` as `mesh_contact.make_bound_rule` asks it."""
        return over_any(surfaces, k, y)

    @wp.func
    def mesh_leaves(
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
        """Whether a centre within R in front of flat mesh k's plane, leaving it, leaves over a
        covering triangle clear of its edges (`mesh_contact.leaves_clear` on each, its own depth)."""
        first = surfaces.face_first[k]
        clear = wp.bool(False)
        for j in range(surfaces.mesh_faces[k]):
            if not clear and first >= 0 and surfaces.face_cover[first + j] != 0:
                p, q, r = vertices(surfaces, k, j)
                clear = basics.leaves_clear(n, p, q, r, x, v, g, radius, height, gap, speed, half, surfaces.face_depth[first + j])
        return clear

    bound_rule = make_bound_rule(precision, mesh_over, mesh_leaves)

    @wp.func
    def flat_bound(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar):
        """(time, clear) of flat mesh k: `mesh_contact.triangle_bound`'s rules on its plane, met
        where the centre's projection lies on any of its triangles (module docstring)."""
        a, n = plane_of(surfaces, k)
        return bound_rule(surfaces, k, 0, a, a, a, n, x, v, g, radius, scalar(-1.0), scalar(0.0))

    @wp.func
    def flat_touched(surfaces: Surfaces, k: wp.int32, x: vec3, radius: scalar):
        """(n, whether x is over a triangle of flat mesh k as its contact leaves it): `mesh_contact.touched`'s
        rule, R or 0 in front of the plane within FLOAT32_SLACK of the coordinates' scale in the
        mesh's frame and the centre's own rounding, projected on a triangle within EDGE_ROUNDING eps
        of that scale; the normal is the plane's whichever way the centre moves."""
        a, n = plane_of(surfaces, k)
        size, rounded = basics.scale(surfaces, k, x), basics.state_rounding(x) + TOLERANCE * radius
        slack = scalar(FLOAT32_SLACK) * size + rounded
        fine = EDGE * size + rounded
        grow = radius + slack
        height = wp.dot(x - a, n)
        over = wp.bool(False)
        if height >= -slack and height <= grow and (height <= slack or height >= grow - scalar(2.0) * slack):
            local = x - n * height - basics.frame(surfaces, k)
            for face in range(surfaces.mesh_faces[k]):
                if not over:
                    over = beside(surfaces, k, face, local) >= -fine
        return n, over

    @wp.func
    def flat_slack(surfaces: Surfaces, k: wp.int32):
        """How far (m) flat mesh k's vertices may lie from its plane (`mesh_edges.flat_edges`)."""
        return surfaces.flat_slack[k]

    return SimpleNamespace(
        plane_of=plane_of, over_any=over_any, flat_bound=flat_bound, flat_touched=flat_touched, flat_slack=flat_slack
    )
