"""On a path segment's Hermite quintic (`tallies.path`): the height over body height above a ground
plane and its rate, v^2, and where they cross (bisection, to rounding; along a line, a safeguarded
Newton on the speed); where an escape's watch
stops (docs/hazard.md section 11, "Escapes")."""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.ballistic import EPSILON, MAX_FLIGHT_TIME
from ..physics.integrate import make_dense_output
from ..physics.types import types_for
from .landing import make_landing_tally


@functools.cache
def make_path_roots(precision: str) -> SimpleNamespace:
    """On a segment's Hermite quintic: the height over body height and its rate, v^2, and where
    they cross (bisection, to rounding)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    Tally = make_landing_tally(precision).Tally
    hermite, hermite_vec = make_dense_output(precision).hermite, make_dense_output(precision).hermite_vec
    ITERATIONS = 30 if precision == "float32" else 60
    TOLERANCE = scalar(4e-7) if precision == "float32" else scalar(1e-15)  # theta's Newton steps
    NOISE = 2.0 * EPSILON[precision]  # a slope this close to its target (relative to its terms) is a root
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def height_over(tally: Tally, gp: vec3, gn: vec3, x: vec3):
        """m: how far the centre at x is above body height over the ground plane through gp (gn: its
        normal / (normal . up); <= 0: within it)."""
        return wp.dot(x - gp, gn) - tally.body_height

    @wp.func
    def height(tally: Tally, x: vec3):
        """`height_over` the hazard's ground plane."""
        return height_over(tally, tally.ground_point, tally.ground_normal, x)

    @wp.func
    def speed2_at(theta: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, inv_h2: scalar):
        _x, slope = hermite_vec(theta, x0, d0, e0, x1, d1, e1)
        return wp.dot(slope, slope) * inv_h2

    @wp.func
    def height_at(tally: Tally, gp: vec3, gn: vec3, theta: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        x, slope = hermite_vec(theta, x0, d0, e0, x1, d1, e1)
        return height_over(tally, gp, gn, x), wp.dot(slope, gn)

    @wp.func
    def height_root(
        tally: Tally,
        gp: vec3,
        gn: vec3,
        a: scalar,
        b: scalar,
        rising: wp.int32,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
    ):
        """Where the height (rising: from <= 0 to > 0; else from > 0 to <= 0) crosses body height on [a, b]."""
        for _ in range(ITERATIONS):
            m = scalar(0.5) * (a + b)
            f, _slope = height_at(tally, gp, gn, m, x0, d0, e0, x1, d1, e1)
            if (f > ZERO) == (rising != 0):
                b = m
            else:
                a = m
        return scalar(0.5) * (a + b)

    @wp.func
    def apex(tally: Tally, gp: vec3, gn: vec3, a: scalar, b: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        """Where the height's rate falls from > 0 to <= 0 on [a, b]."""
        for _ in range(ITERATIONS):
            m = scalar(0.5) * (a + b)
            _f, rate = height_at(tally, gp, gn, m, x0, d0, e0, x1, d1, e1)
            if rate > ZERO:
                a = m
            else:
                b = m
        return scalar(0.5) * (a + b)

    @wp.func
    def speed_root(
        a: scalar, b: scalar, target: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, inv_h2: scalar
    ):
        """Where v^2 crosses `target` on [a, b] (taken monotone; above at a or at b)."""
        above_a = speed2_at(a, x0, d0, e0, x1, d1, e1, inv_h2) >= target
        for _ in range(ITERATIONS):
            m = scalar(0.5) * (a + b)
            if (speed2_at(m, x0, d0, e0, x1, d1, e1, inv_h2) >= target) == above_a:
                a = m
            else:
                b = m
        if above_a:
            return a
        return b

    @wp.func
    def along_root(w: scalar, p0: scalar, a0: scalar, length: scalar, p1: scalar, a1: scalar):
        """theta in [0, 1] where the slope of the quintic Hermite along a line (0 and `length` at
        its ends, slopes p0, p1 and second derivatives a0, a1 per unit theta) equals w, taken
        crossed once: Newton's steps kept inside the bracket, else bisection (Numerical Recipes'
        rtsafe), to rounding. The slope and the distance in `hermite`'s basis (its powers of theta
        cancel in float32), its derivative in powers of theta. Returns (theta, the distance along
        the line there, m)."""
        c3 = scalar(10.0) * length - scalar(6.0) * p0 - scalar(4.0) * p1 - scalar(1.5) * a0 + scalar(0.5) * a1
        c4 = scalar(-15.0) * length + scalar(8.0) * p0 + scalar(7.0) * p1 + scalar(1.5) * a0 - a1
        c5 = scalar(6.0) * length - scalar(3.0) * p0 - scalar(3.0) * p1 - scalar(0.5) * a0 + scalar(0.5) * a1
        lo = ZERO
        hi = ONE
        rising = p1 > p0
        theta = wp.clamp((w - p0) / (p1 - p0), ZERO, ONE)
        noise = scalar(NOISE) * (wp.abs(p0) + wp.abs(p1) + wp.abs(a0) + wp.abs(a1) + wp.abs(length))  # the slope's rounding
        for _ in range(ITERATIONS):
            _s, slope = hermite(theta, ZERO, p0, a0, length, p1, a1)
            f = slope - w
            if wp.abs(f) <= noise:
                break
            df = a0 + theta * (scalar(6.0) * c3 + theta * (scalar(12.0) * c4 + theta * scalar(20.0) * c5))
            if (f < ZERO) == rising:
                lo = theta
            else:
                hi = theta
            step = theta - f / df
            if not (step > lo and step < hi):
                step = scalar(0.5) * (lo + hi)
            done = wp.abs(step - theta) <= TOLERANCE
            theta = step
            if done:
                break
        s, _slope = hermite(theta, ZERO, p0, a0, length, p1, a1)
        return theta, s

    @wp.func
    def chord_root(target: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3, h: scalar):
        """(m along the chord x0 -> x1 (length > 0), its unit direction) where the time Hermite of a
        step along it (h s) reaches the squared speed `target` (`along_root` on its components along
        the chord)."""
        length = wp.length(x1 - x0)
        u = (x1 - x0) * (ONE / length)
        _theta, s = along_root(h * wp.sqrt(target), wp.dot(d0, u), wp.dot(e0, u), length, wp.dot(d1, u), wp.dot(e1, u))
        return s, u

    @wp.func
    def ground_theta(tally: Tally, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        """On a step that ends below the hazard's ground plane and falling: where an escape's watch
        stops (docs/hazard.md section 11): its crossing of the plane from above if it starts above
        it, else its height's apex if it starts rising, else 0 (bisection, to rounding)."""
        gp, gn = tally.ground_point, tally.ground_normal
        f0, r0 = height_at(tally, gp, gn, ZERO, x0, d0, e0, x1, d1, e1)
        a = ZERO
        b = scalar(1.0)
        if f0 + tally.body_height >= ZERO:
            for _ in range(ITERATIONS):
                m = scalar(0.5) * (a + b)
                f, _rate = height_at(tally, gp, gn, m, x0, d0, e0, x1, d1, e1)
                if f + tally.body_height >= ZERO:
                    a = m
                else:
                    b = m
            return a
        if r0 > ZERO:
            return apex(tally, gp, gn, a, b, x0, d0, e0, x1, d1, e1)
        return ZERO

    @wp.func
    def below(tally: Tally, x: vec3, v: vec3):
        """Whether the centre is below the hazard's ground plane and not rising: an escaping flight's
        watch ends there (no person stands below the ground; docs/hazard.md section 11)."""
        n = tally.ground_normal
        return wp.dot(x - tally.ground_point, n) < ZERO and wp.dot(v, n) <= ZERO

    @wp.func
    def escape_time(tally: Tally, x0: vec3, v0: vec3, g: vec3):
        """s: how long a vacuum flight that meets no surface again is watched, until its centre goes
        below the hazard's ground plane falling: the later root of its height there, c + b t + a t^2
        = 0 (a = n.g / 2 < 0; the root in the form without cancellation); a flight never above the
        plane up to its height's apex (<= 0, none, if falling); one whose gravity does not point
        into the plane for MAX_FLIGHT_TIME, as long as a contact is looked for."""
        n = tally.ground_normal
        c = wp.dot(x0 - tally.ground_point, n)
        b = wp.dot(v0, n)
        a = scalar(0.5) * wp.dot(g, n)
        dt = scalar(MAX_FLIGHT_TIME)
        if a < ZERO:
            dt = -b / (scalar(2.0) * a)  # the apex
            disc = b * b - scalar(4.0) * a * c
            if disc >= ZERO:
                root = wp.sqrt(disc)
                if b >= ZERO:
                    dt = (b + root) / (scalar(-2.0) * a)
                else:
                    dt = scalar(2.0) * c / (root - b)
        return dt

    return SimpleNamespace(
        below=below,
        escape_time=escape_time,
        height=height,
        height_over=height_over,
        height_at=height_at,
        speed2_at=speed2_at,
        height_root=height_root,
        apex=apex,
        speed_root=speed_root,
        along_root=along_root,
        chord_root=chord_root,
        ground_theta=ground_theta,
    )
