"""An air step's screen of a triangle before root finding (`physics.air_flight`'s mesh search):
from the quintic Bezier control points of the step's interpolant, whether the curve passes the
triangle by one of its edges wherever its face could be met (`off_step`). The curve lies in the
convex hull of its control points, and the gaps and edge functions are affine, so a hull that
stays beyond an edge or in front of a plane bounds the whole curve (Farin, "Curves and Surfaces
for CAGD", 5th ed., ch. 4-5: the convex hull property, de Casteljau subdivision)."""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON
from .mesh_contact import EDGE_ROUNDING, STATE_ROUNDING, make_mesh_contact
from .types import types_for

CLEAR_ROUNDING = 64.0  # `clear_of`'s margin for the control points' and the interpolant's rounding, in eps


@functools.cache
def make_step_screen(precision: str) -> SimpleNamespace:
    """`off_step(...)`: whether a triangle has no face contact on an air step, decided from the step's
    quintic Bezier control points before `make_solid_search`'s roots (`clear_of`, `reached`, `tail`);
    `off_plane(...)`: the same of a flat mesh's plane, before its triangles are asked."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    meshes = make_mesh_contact(precision)
    EDGE, STATE = scalar(EDGE_ROUNDING * EPSILON[precision]), scalar(STATE_ROUNDING * EPSILON[precision])
    CLEAR = scalar(CLEAR_ROUNDING * EPSILON[precision])
    ULPS = scalar(16.0 * EPSILON[precision])
    FOUR, FIVE = scalar(4.0), scalar(5.0)  # the degrees of the gap's derivative and of the gap

    @wp.func
    def controls(h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3):
        """The six control points of the step's quintic (Bezier form of `hermite_vec`'s interpolant)."""
        d0, dd0, d1, dd1 = h * v0, h * h * a0, h * v1, h * h * a1
        p1, p2 = x0 + d0 / scalar(5.0), x0 + scalar(0.4) * d0 + dd0 / scalar(20.0)
        return x0, p1, p2, x1 - scalar(0.4) * d1 + dd1 / scalar(20.0), x1 - d1 / scalar(5.0), x1

    @wp.func
    def clear_of(
        n: vec3, p: vec3, q: vec3, c0: vec3, c1: vec3, c2: vec3, c3: vec3, c4: vec3, c5: vec3, low: vec3, high: vec3, size: scalar
    ):
        """Whether the curve of control points c0..c5 stays beyond the edge p -> q of a triangle of
        unit normal n (counter-clockwise about n) by more than `mesh_contact.inside`'s tolerance
        anywhere in the box (low, high) and CLEAR eps of the step's scale `size` (m): every control
        point does (the curve is their convex combination; the edge function n.((q - p) x (y - p))
        is affine in y), so `inside` fails at every point of it."""
        e = q - p
        w = wp.cross(n, e)  # n.(e x (y - p)) = w.(y - p)
        reach = scalar(0.0)  # l1 bounds over the box of |y - p| and |y|
        span = scalar(0.0)
        for i in range(3):
            reach = reach + wp.max(wp.abs(low[i] - p[i]), wp.abs(high[i] - p[i]))
            span = span + wp.max(wp.abs(low[i]), wp.abs(high[i]))
        length = meshes.l1(e)
        margin = wp.length(e) * (EDGE * (reach + length) + STATE * span + CLEAR * (size + reach + span + length))
        clear = wp.dot(w, c0 - p) < -margin and wp.dot(w, c1 - p) < -margin and wp.dot(w, c2 - p) < -margin
        return clear and wp.dot(w, c3 - p) < -margin and wp.dot(w, c4 - p) < -margin and wp.dot(w, c5 - p) < -margin

    @wp.func
    def beyond_an_edge(
        n: vec3,
        a: vec3,
        b: vec3,
        c: vec3,
        c0: vec3,
        c1: vec3,
        c2: vec3,
        c3: vec3,
        c4: vec3,
        c5: vec3,
        low: vec3,
        high: vec3,
        size: scalar,
    ):
        """Whether the curve of control points c0..c5 stays beyond an edge of triangle (a, b, c)
        (`clear_of`, each edge in turn)."""
        if clear_of(n, a, b, c0, c1, c2, c3, c4, c5, low, high, size):
            return True
        if clear_of(n, b, c, c0, c1, c2, c3, c4, c5, low, high, size):
            return True
        return clear_of(n, c, a, c0, c1, c2, c3, c4, c5, low, high, size)

    @wp.func
    def crossing(t: scalar, i: wp.int32, di: scalar, j: wp.int32, dj: scalar, degree: scalar):
        """The least of t and where the segment from (i/degree, di > 0) to (j/degree, dj <= 0) of a
        Bernstein hull crosses zero."""
        if di > scalar(0.0) and dj <= scalar(0.0):
            t = wp.min(t, (scalar(i) + scalar(j - i) * (di / (di - dj))) / degree)
        return t

    @wp.func
    def hull_crossings(t: scalar, d0: scalar, d1: scalar, d2: scalar, d3: scalar, d4: scalar, degree: scalar):
        """`crossing` over every pair of the first five Bernstein coefficients d0..d4 of a hull of
        `degree` (the quartic's all, the quintic's but its last)."""
        t = crossing(t, 0, d0, 1, d1, degree)
        t = crossing(t, 0, d0, 2, d2, degree)
        t = crossing(t, 0, d0, 3, d3, degree)
        t = crossing(t, 0, d0, 4, d4, degree)
        t = crossing(t, 1, d1, 2, d2, degree)
        t = crossing(t, 1, d1, 3, d3, degree)
        t = crossing(t, 1, d1, 4, d4, degree)
        t = crossing(t, 2, d2, 3, d3, degree)
        t = crossing(t, 2, d2, 4, d4, degree)
        return crossing(t, 3, d3, 4, d4, degree)

    @wp.func
    def rounded_down(t: scalar):
        """A hull's first zero t less 16 eps for its own rounding, within [0, 1] (above 1: never)."""
        if t > scalar(1.0):
            return t
        return wp.max(t - ULPS, scalar(0.0))

    @wp.func
    def reached(n: vec3, level: scalar, c0: vec3, c1: vec3, c2: vec3, c3: vec3, c4: vec3, c5: vec3, margin: scalar):
        """A theta before which the gap n.x - level on the curve of control points c0..c5 stays above
        `margin` (m): where the hull of its Bernstein coefficients (i/5, n.c_i - level - margin) first
        reaches 0, less 16 eps for its own rounding (2: never; 0: at once)."""
        d0, d1, d2 = wp.dot(n, c0) - level - margin, wp.dot(n, c1) - level - margin, wp.dot(n, c2) - level - margin
        d3, d4, d5 = wp.dot(n, c3) - level - margin, wp.dot(n, c4) - level - margin, wp.dot(n, c5) - level - margin
        if not (d0 > scalar(0.0)):
            return scalar(0.0)
        t = hull_crossings(scalar(2.0), d0, d1, d2, d3, d4, FIVE)
        t = crossing(crossing(crossing(t, 0, d0, 5, d5, FIVE), 1, d1, 5, d5, FIVE), 2, d2, 5, d5, FIVE)
        return rounded_down(crossing(crossing(t, 3, d3, 5, d5, FIVE), 4, d4, 5, d5, FIVE))

    @wp.func
    def turned(n: vec3, c0: vec3, c1: vec3, c2: vec3, c3: vec3, c4: vec3, c5: vec3, margin: scalar):
        """A theta before which the gap's derivative along n on the curve of control points c0..c5
        stays above `margin`: where the hull of its quartic Bernstein coefficients n.(c_{i+1} - c_i)
        less `margin` first reaches 0, less 16 eps (2: never; 0: at once)."""
        e0, e1, e2 = wp.dot(n, c1 - c0) - margin, wp.dot(n, c2 - c1) - margin, wp.dot(n, c3 - c2) - margin
        e3, e4 = wp.dot(n, c4 - c3) - margin, wp.dot(n, c5 - c4) - margin
        if not (e0 > scalar(0.0)):
            return scalar(0.0)
        return rounded_down(hull_crossings(scalar(2.0), e0, e1, e2, e3, e4, FOUR))

    @wp.func
    def lerp(p: vec3, q: vec3, t: scalar):
        return p + t * (q - p)

    @wp.func
    def tail(t: scalar, c0: vec3, c1: vec3, c2: vec3, c3: vec3, c4: vec3, c5: vec3):
        """The control points of the curve's part on [t, 1] (de Casteljau)."""
        a0, a1, a2, a3, a4 = lerp(c0, c1, t), lerp(c1, c2, t), lerp(c2, c3, t), lerp(c3, c4, t), lerp(c4, c5, t)
        b0, b1, b2, b3 = lerp(a0, a1, t), lerp(a1, a2, t), lerp(a2, a3, t), lerp(a3, a4, t)
        e0, e1, e2 = lerp(b0, b1, t), lerp(b1, b2, t), lerp(b2, b3, t)
        f0, f1 = lerp(e0, e1, t), lerp(e1, e2, t)
        return lerp(f0, f1, t), f1, e2, b3, a4, c5

    @wp.func
    def head(t: scalar, c0: vec3, c1: vec3, c2: vec3, c3: vec3, c4: vec3, c5: vec3):
        """The control points of the curve's part on [0, t] (de Casteljau)."""
        a0, a1, a2, a3, a4 = lerp(c0, c1, t), lerp(c1, c2, t), lerp(c2, c3, t), lerp(c3, c4, t), lerp(c4, c5, t)
        b0, b1, b2, b3 = lerp(a0, a1, t), lerp(a1, a2, t), lerp(a2, a3, t), lerp(a3, a4, t)
        e0, e1, e2 = lerp(b0, b1, t), lerp(b1, b2, t), lerp(b2, b3, t)
        f0, f1 = lerp(e0, e1, t), lerp(e1, e2, t)
        return c0, a0, b0, e0, f0, lerp(f0, f1, t)

    @wp.func
    def first_met(
        n: vec3,
        plane: scalar,
        radius: scalar,
        h: scalar,
        x0: vec3,
        v0: vec3,
        c0: vec3,
        c1: vec3,
        c2: vec3,
        c3: vec3,
        c4: vec3,
        c5: vec3,
        margin: scalar,
    ):
        """A theta before which `face_thetas` meets neither the plane n.x = plane nor its offset by
        R (level): `reached`, or for a centre waiting within R of the plane and leaving it, its turn
        (`turned`) and then the offset plane's reach; the plane itself lies behind the offset one,
        which the centre meets first where it starts more than `margin` in front of the plane (2:
        never; 3: behind the plane by more than `margin`, where `face_thetas` finds nothing)."""
        level = plane + radius
        g0, s0 = wp.dot(x0, n) - plane, h * wp.dot(v0, n)  # as `face_thetas`
        if g0 < -margin:  # (beyond the rounding of g0 computed apart from `face_thetas`' own)
            return scalar(3.0)
        if g0 > radius or s0 <= scalar(0.0):
            return reached(n, level, c0, c1, c2, c3, c4, c5, margin)
        if not (g0 > margin):
            return scalar(0.0)
        t = turned(n, c0, c1, c2, c3, c4, c5, margin)
        if t > scalar(0.0) and t <= scalar(1.0):
            d0, d1, d2, d3, d4, d5 = tail(t, c0, c1, c2, c3, c4, c5)
            after = reached(n, level, d0, d1, d2, d3, d4, d5, margin)
            t = wp.where(after > scalar(1.0), scalar(2.0), t + (scalar(1.0) - t) * after)
        return t

    @wp.func
    def step_size(h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3):
        """The step's coordinates' scale (m): the l1 sizes of its Hermite data."""
        return (
            meshes.l1(x0) + meshes.l1(x1) + meshes.l1(h * v0) + meshes.l1(h * h * a0) + meshes.l1(h * v1) + meshes.l1(h * h * a1)
        )

    @wp.func
    def plane_met(
        n: vec3,
        a: vec3,
        radius: scalar,
        h: scalar,
        x0: vec3,
        v0: vec3,
        c0: vec3,
        c1: vec3,
        c2: vec3,
        c3: vec3,
        c4: vec3,
        c5: vec3,
        size: scalar,
    ):
        """`first_met` of the plane through a of unit normal n, its margin CLEAR eps of the step's
        scale `size` (m) and of the plane's."""
        plane = wp.dot(a, n)
        margin = CLEAR * (size + meshes.l1(a) + wp.abs(plane + radius))
        return first_met(n, plane, radius, h, x0, v0, c0, c1, c2, c3, c4, c5, margin)

    @wp.func
    def off_plane(
        n: vec3, a: vec3, radius: scalar, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3, bound: scalar
    ):
        """Whether the plane through a of unit normal n (a flat mesh's, `physics.flat_contact`) has
        no face contact on the step before theta `bound`: `first_met` there or later."""
        c0, c1, c2, c3, c4, c5 = controls(h, x0, v0, a0, x1, v1, a1)
        t = plane_met(n, a, radius, h, x0, v0, c0, c1, c2, c3, c4, c5, step_size(h, x0, v0, a0, x1, v1, a1))
        return t >= wp.min(bound, scalar(1.0))

    @wp.func
    def off_step(
        n: vec3,
        a: vec3,
        b: vec3,
        c: vec3,
        radius: scalar,
        h: scalar,
        x0: vec3,
        v0: vec3,
        a0: vec3,
        x1: vec3,
        v1: vec3,
        a1: vec3,
        low: vec3,
        high: vec3,
        bound: scalar,
    ):
        """Whether triangle (a, b, c) of unit normal n has no face contact on the step before theta
        `bound` (2: on the whole step): its curve stays beyond an edge (`clear_of`) on the whole step,
        or on its part from the first theta where `face_thetas` can meet the triangle's plane or its
        offset (`first_met`) to `bound`, or that part is empty."""
        c0, c1, c2, c3, c4, c5 = controls(h, x0, v0, a0, x1, v1, a1)
        size = step_size(h, x0, v0, a0, x1, v1, a1)
        if beyond_an_edge(n, a, b, c, c0, c1, c2, c3, c4, c5, low, high, size):
            return True
        t = plane_met(n, a, radius, h, x0, v0, c0, c1, c2, c3, c4, c5, size)
        top = wp.min(bound, scalar(1.0))
        if t >= top:
            return True
        if t <= scalar(0.0) and top >= scalar(1.0):
            return False
        if t > scalar(0.0):
            c0, c1, c2, c3, c4, c5 = tail(t, c0, c1, c2, c3, c4, c5)
        if top < scalar(1.0):
            c0, c1, c2, c3, c4, c5 = head((top - t) / (scalar(1.0) - t), c0, c1, c2, c3, c4, c5)
        return beyond_an_edge(n, a, b, c, c0, c1, c2, c3, c4, c5, low, high, size)

    return SimpleNamespace(controls=controls, clear_of=clear_of, off_step=off_step, off_plane=off_plane)
