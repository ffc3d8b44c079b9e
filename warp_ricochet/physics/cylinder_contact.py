"""Posts: the flight against a finite right circular cylinder closed by its two end caps
(docs/geometry.md, "Posts (cylinders)"); read only through `physics.geometry` and the air's search
(kernels compiled with meshes, `plates` MESHES).

Post k: base centre p = `point`, unit axis a = `normal` (base to top), radius r = `half_u`, length
L = `half_v`. With d = x - p: axial z = a.d, radial rho = |d - (a.d) a|. A sphere of radius R meets
it where, first:
- the side: rho closes to r + R with z in [0, L] (normal: radial);
- a cap: its height (z - L on top, -z below) closes to R with rho <= r (normal: a, -a);
- at the latest, the centre itself reaches the side (rho = r, z in [0, L]) or a cap (height 0,
  rho <= r): a sphere passing the rim with its centre beyond it, within R of the rim, flies by
  (edges are no contacts, as on plates), but its centre never passes into the post;
- where the centre comes onto the length through an end with rho in [r, r + R], closing on the axis
  (met there as a flight starting there is met at once; not an edge's search, r = 0).
"On the length" and "over a cap" are inclusive within `slack` (EDGE_ROUNDING eps of the coordinates'
scale in the post's own frame, |x - p|_1 + L + r, and the stored centre's own rounding,
`mesh_contact.state_rounding`; not the world's coordinates: docs/geometry.md, "Far from the
origin"), so that a centre crossing exactly at a rim is on both faces; but a cap is met at once
(t = 0) only by a centre that starts over it (rho <= r, no slack), so that one left beyond the rim
within the slack flies by rather than meeting the cap at t = 0 again and again.
Vacuum (`post_time`): on the parabola of eq. (36), rho^2 - s^2 (s = r + R or r) is a quartic in t
whose t^4 and t^3 terms vanish when gravity is along the axis (a vertical post): then a quadratic,
solved in closed form (one entering root, from the closest approach: t_c - sqrt((s^2 - m^2) / |B|^2)
with m = |A + B t_c| formed as a vector, so that it keeps eps |x| at a post far from the centre). Otherwise its roots are isolated exactly: the quadratic
second derivative's roots split [0, T] into pieces where the cubic derivative is monotone, whose
roots (bracketed, Illinois) split it into pieces where the quartic is monotone, each holding at
most one entering root (found, bracketed, to rounding of t); T bounds every root (|P(t)| >= |C| t^2 - |B| t - |A|).
Caps: the plane's quadratic (`ballistic.entry_time`, `mesh_contact.descending`).
Air (`side_theta`, with the caps as faces in `physics.air_flight`): rho^2 - s^2 on the step's
quintic Hermite, sampled at SIDE_SAMPLES equal parts: a part whose end is inside, or whose slope
turns from closing to opening with its minimum inside (a graze), is bisected to rounding of theta;
one starting off the length and ending on it within [r, s], closing, is bisected on that test.
A dip in and out within one part between two such samples is not seen (the parts are 1/16 of a
step the integrator keeps within its error tolerance).
Followed to rest (`physics.surface_follow`): a pellet on a cap moves along it as along a disc plate
(`cap_face`, `cap_plane`; `geometry.face_gap`), and one that stops with its centre beyond the rim,
within the slack, falls off (`off_rim`); on a vertical post's side it flies on (the caller's
lift-off), along a leaning post's side it moves (`physics.side_follow`).
The side's searches (`side_time`, `line_theta`) also meet a mesh's convex edges (r = 0) and corners
(a = 0: rho the distance from p) (`physics.edge_contact`).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON, MAX_FLIGHT_TIME, NO_CONTACT, ROUNDING, make_ballistic
from .integrate import make_dense_output
from .mesh_contact import EDGE_ROUNDING, STATE_ROUNDING, make_mesh_contact, make_triangle_basics
from .types import KINDS, types_for

TOP_CAP, BOTTOM_CAP = -2, -3  # a post's caps as the faces a pellet moves along (`cap_face`, `cap_plane`)
SIDE_SAMPLES = 16  # equal parts of an air step searched for the side's crossing
BISECTIONS = {"float32": 48, "float64": 96}  # at most: halvings of [0, T] to rounding of t


@functools.cache
def make_cylinder_contact(precision: str) -> SimpleNamespace:
    """`is_post`, `post_time`, `post_normal`, `post_box`, `on_cap`, `cap_face`, `cap_plane` and
    `side_theta` (module docstring) of one precision."""
    return SimpleNamespace(**vars(_post_shape(precision)), **vars(_post_vacuum(precision)), **vars(_post_air(precision)))


@functools.cache
def _post_shape(precision: str) -> SimpleNamespace:
    """What a post is: `is_post`, `across`, `along`, `post_normal`, `post_box`, `on_cap`,
    `cap_face`, `cap_plane`."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    ZERO, HALF, ONE = scalar(0.0), scalar(0.5), scalar(1.0)
    POST, EDGE, basics = KINDS["cylinder"], scalar(EDGE_ROUNDING * EPSILON[precision]), make_triangle_basics(precision)
    l1, state_rounding = basics.l1, basics.state_rounding

    @wp.func
    def is_post(surfaces: Surfaces, k: wp.int32):
        """Whether surface k is a post (a cylinder)."""
        return surfaces.kind[k] == POST

    @wp.func
    def across(d: vec3, a: vec3):
        """d's part across the axis a: d - (a.d) a."""
        return d - wp.dot(d, a) * a

    @wp.func
    def along(z: scalar, length: scalar, slack: scalar):
        """Whether an axial coordinate lies on the post's length (inclusive within `slack`, m)."""
        return z >= -slack and z <= length + slack

    @wp.func
    def post_normal(surfaces: Surfaces, k: wp.int32, x: vec3):
        """The unit normal of post k at the face nearest the centre x: of the side (radial), the
        top (a) or the bottom (-a), whichever x lies farthest out from (its signed distance's gradient)."""
        a, r, length = surfaces.normal[k], surfaces.half_u[k], surfaces.half_v[k]
        d = x - surfaces.point[k]
        z, radial = wp.dot(d, a), across(d, a)
        rho = wp.length(radial)
        n = a
        out = z - length
        if -z > out:
            n = -a
            out = -z
        if rho - r > out and rho > ZERO:
            n = radial / rho
        return n

    @wp.func
    def post_frame(surfaces: Surfaces, k: wp.int32):
        """Post k's base centre p (m), unit axis a, radius r (m) and length L (m)."""
        return surfaces.point[k], surfaces.normal[k], surfaces.half_u[k], surfaces.half_v[k]

    @wp.func
    def post_box(surfaces: Surfaces, k: wp.int32):
        """Post k's bounding box (m): (low, high)."""
        a, r, length = surfaces.normal[k], surfaces.half_u[k], surfaces.half_v[k]
        centre = surfaces.point[k] + HALF * length * a
        e = vec3(
            HALF * length * wp.abs(a[0]) + r * wp.sqrt(wp.max(ZERO, ONE - a[0] * a[0])),
            HALF * length * wp.abs(a[1]) + r * wp.sqrt(wp.max(ZERO, ONE - a[1] * a[1])),
            HALF * length * wp.abs(a[2]) + r * wp.sqrt(wp.max(ZERO, ONE - a[2] * a[2])),
        )
        return centre - e, centre + e

    @wp.func
    def on_cap(surfaces: Surfaces, k: wp.int32, x: vec3, slack: scalar):
        """Whether x projected along post k's axis lies on its caps (rho <= r + slack)."""
        return wp.length(across(x - surfaces.point[k], surfaces.normal[k])) <= surfaces.half_u[k] + slack

    @wp.func
    def slack(surfaces: Surfaces, k: wp.int32, x: vec3):
        """The rounding allowed the inside tests of post k near a flight from x (m): EDGE_ROUNDING
        eps (|x - p|_1 + L + r), the scale of the contact's coordinates in the post's frame, and
        the stored centre's own rounding (`mesh_contact.state_rounding`: 2 eps |x|_1)."""
        return EDGE * (l1(x - surfaces.point[k]) + surfaces.half_v[k] + surfaces.half_u[k]) + state_rounding(x)

    @wp.func
    def off_rim(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3):
        """(beyond, y, w) for a pellet stopped (velocity v, m/s) on a cap of post k with its centre
        at x: whether x lies beyond the rim (rho > r, within the slack the cap is followed with),
        and then the point it falls from, x moved out across the axis to rho = r + 2 `slack`, clear
        of the slack a flight meets a cap with at once (`post_time`, `side_theta`'s caps), and v
        less any part towards the axis (closing on it the side would be met at its top, again and
        again), so that it falls past the rim as the float64 run's pellet does (docs/geometry.md,
        "Posts, plates and planes far from the origin"); else x and v."""
        radial = across(x - surfaces.point[k], surfaces.normal[k])
        rho = wp.length(radial)
        r = surfaces.half_u[k]
        beyond = rho > r
        y = vec3(x)
        w = vec3(v)
        if beyond:
            y = x + ((r + scalar(2.0) * slack(surfaces, k, x) - rho) / rho) * radial
            inward = wp.dot(v, radial) / rho
            if inward < ZERO:
                w = v - (inward / rho) * radial
        return beyond, y, w

    @wp.func
    def cap_face(surfaces: Surfaces, k: wp.int32, x: vec3):
        """The face of post k a pellet centred at x touches: TOP_CAP or BOTTOM_CAP where `post_normal`
        is the axis (+a or -a), else -1 (the side)."""
        along_axis = wp.dot(post_normal(surfaces, k, x), surfaces.normal[k])  # 1, -1, or 0 (radial)
        face = wp.int32(-1)
        if along_axis > HALF:
            face = wp.int32(TOP_CAP)
        elif along_axis < -HALF:
            face = wp.int32(BOTTOM_CAP)
        return face

    @wp.func
    def cap_plane(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3):
        """(height, noise, normal) of x over cap `face` of post k: its plane through p + L a (top,
        normal a) or p (bottom, normal -a), as `geometry.locate` of a plane (noise: the rounding
        scale of the signed distance from the cap's centre c in the post's frame, sum_i |(x - p)_i
        n_i| + L, and the stored centre's own rounding along n, as `mesh_contact.height_noise`)."""
        a = surfaces.normal[k]
        p = surfaces.point[k]
        c = vec3(p)
        n = -a
        if face == TOP_CAP:
            n = a
            c = c + surfaces.half_v[k] * a
        d = x - p
        noise = wp.abs(d[0] * n[0]) + wp.abs(d[1] * n[1]) + wp.abs(d[2] * n[2]) + surfaces.half_v[k]
        along = wp.abs(x[0] * n[0]) + wp.abs(x[1] * n[1]) + wp.abs(x[2] * n[2])
        return wp.dot(x - c, n), noise + scalar(STATE_ROUNDING / ROUNDING) * along, n

    return SimpleNamespace(
        is_post=is_post,
        across=across,
        along=along,
        cap_face=cap_face,
        cap_plane=cap_plane,
        post_frame=post_frame,
        post_normal=post_normal,
        post_box=post_box,
        on_cap=on_cap,
        slack=slack,
        off_rim=off_rim,
    )


@functools.cache
def _post_vacuum(precision: str) -> SimpleNamespace:
    """`post_time`: the parabola of eq. (36) against a post (module docstring)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    ZERO, HALF, ONE, TWO = scalar(0.0), scalar(0.5), scalar(1.0), scalar(2.0)
    ballistic, meshes, shape = make_ballistic(precision), make_mesh_contact(precision), _post_shape(precision)
    entry_time, descending, l1, across, along = ballistic.entry_time, meshes.descending, meshes.l1, shape.across, shape.along
    ITERATIONS, TOLERANCE = BISECTIONS[precision], scalar(ROUNDING * EPSILON[precision])
    RESOLUTION, LATEST = scalar(4.0 * EPSILON[precision]), scalar(MAX_FLIGHT_TIME)

    @wp.func
    def side_value(t: scalar, slope: wp.int32, sign: scalar, A: vec3, B: vec3, C: vec3, ss: scalar):
        """sign f(t), or with `slope` sign f'(t), of f = |A + B t + C t^2|^2 - ss."""
        P = A + t * (B + t * C)
        if slope != 0:
            return sign * TWO * wp.dot(P, B + TWO * t * C)
        return sign * (wp.dot(P, P) - ss)

    @wp.func
    def bisect(lo: scalar, hi: scalar, slope: wp.int32, sign: scalar, A: vec3, B: vec3, C: vec3, ss: scalar):
        """Where sign f (or sign f') falls from > 0 at lo to <= 0 at hi: hi once the bracket is
        within rounding of t (Illinois: regula falsi halving a stuck end's value, a midpoint where
        the secant leaves the bracket; as `air_flight.make_roots`)."""
        f_lo = side_value(lo, slope, sign, A, B, C, ss)
        f_hi = side_value(hi, slope, sign, A, B, C, ss)
        stuck = wp.int32(0)
        for _ in range(ITERATIONS):
            if hi - lo > RESOLUTION * hi:
                mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
                if not (mid > lo and mid < hi):
                    mid = HALF * (lo + hi)
                f_mid = side_value(mid, slope, sign, A, B, C, ss)
                if f_mid > ZERO:
                    lo = mid
                    f_lo = f_mid
                    if stuck == 1:
                        f_hi = HALF * f_hi
                    stuck = wp.int32(1)
                else:
                    hi = mid
                    f_hi = f_mid
                    if stuck == -1:
                        f_lo = HALF * f_lo
                    stuck = wp.int32(-1)
        return hi

    @wp.func
    def touching(t: scalar, A: vec3, B: vec3, C: vec3, ss: scalar, inner: scalar):
        """Whether rho(t) lies in [inner, s] with the centre closing on the axis (met at once)."""
        P = A + t * (B + t * C)
        rr = wp.dot(P, P)
        return rr <= ss and rr >= inner * inner and wp.dot(P, B + TWO * t * C) < ZERO

    @wp.func
    def entering(
        lo: scalar,
        hi: scalar,
        A: vec3,
        B: vec3,
        C: vec3,
        ss: scalar,
        z0: scalar,
        w: scalar,
        q: scalar,
        length: scalar,
        slack: scalar,
    ):
        """On a piece [lo, hi] where f is monotone: its root if f falls through 0 there with z on
        the length, else NO_CONTACT."""
        if hi > lo and side_value(lo, 0, ONE, A, B, C, ss) > ZERO and side_value(hi, 0, ONE, A, B, C, ss) <= ZERO:
            root = bisect(lo, hi, 0, ONE, A, B, C, ss)
            if along(z0 + root * (w + root * q), length, slack):
                return root
        return scalar(NO_CONTACT)

    @wp.func
    def closing_time(d0: vec3, v: vec3, g: vec3, a: vec3, s: scalar, inner: scalar, length: scalar, slack: scalar):
        """First t >= 0 where the centre (d0 from the base, velocity v, gravity g) closes to s of
        the axis a with z on the length (met at once where rho in [inner, s], closing), or NO_CONTACT
        (a = 0: of the point itself)."""
        A, B, C = across(d0, a), across(v, a), HALF * across(g, a)
        z0, w, q = wp.dot(d0, a), wp.dot(v, a), HALF * wp.dot(g, a)
        ss = s * s
        f0, ab = wp.dot(A, A) - ss, wp.dot(A, B)
        if f0 <= ZERO and ab < ZERO and along(z0, length, slack) and wp.dot(A, A) >= inner * inner:
            return ZERO  # touching or overlapping the side, closing
        if l1(C) <= TOLERANCE * l1(g):  # gravity along the axis: a straight line across it
            if f0 > ZERO and ab < ZERO:
                closest = -ab / wp.dot(B, B)  # the closest approach, its distance as a vector (no cancellation)
                miss = A + closest * B
                room = (s - wp.length(miss)) * (s + wp.length(miss))
                if room >= ZERO:
                    root = wp.max(ZERO, closest - wp.sqrt(room / wp.dot(B, B)))
                    if along(z0 + root * (w + root * q), length, slack):
                        return root
            return scalar(NO_CONTACT)
        c, b, a0 = wp.length(C), wp.length(B), wp.length(A)
        end = wp.min(LATEST, scalar(1.5) * (b + wp.sqrt(b * b + scalar(4.0) * c * (a0 + s))) / (TWO * c))
        # f''/2 = 6 C.C t^2 + 6 B.C t + (B.B + 2 A.C): where f' turns
        cc, bc = wp.dot(C, C), wp.dot(B, C)
        disc = scalar(36.0) * bc * bc - scalar(24.0) * cc * (wp.dot(B, B) + TWO * wp.dot(A, C))
        first = ZERO
        second = ZERO
        if disc > ZERO:
            root = wp.sqrt(disc)
            first = wp.clamp((-scalar(6.0) * bc - root) / (scalar(12.0) * cc), ZERO, end)
            second = wp.clamp((-scalar(6.0) * bc + root) / (scalar(12.0) * cc), ZERO, end)
        lo = ZERO
        piece = ZERO
        found = scalar(NO_CONTACT)
        pieces = wp.int32(3)  # a run-time loop: one copy of its body in the kernel
        for j in range(pieces):
            top = end
            if j == 0:
                top = first
            elif j == 1:
                top = second
            if top > piece:
                d_lo, d_hi = side_value(piece, 1, ONE, A, B, C, ss), side_value(top, 1, ONE, A, B, C, ss)
                turn = scalar(-1.0)
                if d_lo < ZERO and d_hi > ZERO:
                    turn = bisect(piece, top, 1, scalar(-1.0), A, B, C, ss)
                elif d_lo > ZERO and d_hi < ZERO:
                    turn = bisect(piece, top, 1, ONE, A, B, C, ss)
                if turn >= ZERO:
                    if found < ZERO:
                        found = entering(lo, turn, A, B, C, ss, z0, w, q, length, slack)
                    lo = turn
                piece = top
        if found < ZERO:
            found = entering(lo, end, A, B, C, ss, z0, w, q, length, slack)
        return found

    @wp.func
    def side_time(d0: vec3, v: vec3, g: vec3, a: vec3, s: scalar, inner: scalar, length: scalar, slack: scalar):
        """First t >= 0 where the centre (d0 from the base, velocity v, gravity g) closes to s of
        the axis a with z on the length, or (inner > 0: a post) comes onto the length through an
        end with rho in [inner, s], closing (met at once there, as at t = 0), or NO_CONTACT (a = 0:
        of the point itself)."""
        found = closing_time(d0, v, g, a, s, inner, length, slack)
        A, B, C = across(d0, a), across(v, a), HALF * across(g, a)
        z0, w, q = wp.dot(d0, a), wp.dot(v, a), HALF * wp.dot(g, a)
        if inner > ZERO:
            for j in range(2):
                sign = ONE
                level = length
                if j == 1:
                    sign = scalar(-1.0)
                    level = ZERO
                gap = sign * (z0 - level) - slack
                if gap > ZERO:
                    onto = entry_time(gap, sign * w, sign * q)
                    if onto >= ZERO and (found < ZERO or onto < found) and touching(onto, A, B, C, s * s, inner):
                        found = onto
        return found

    @wp.func
    def cap_time(height: scalar, speed: scalar, half: scalar, offset: scalar, over: wp.bool):
        """When a cap's height (speed, half its gravity) closes to `offset` (the plane's rule in
        front of it, clear or over the cap: `entry_time`; else when it comes back down through it)."""
        g = height - offset
        if height >= ZERO and (g > ZERO or over):
            return entry_time(g, speed, half)
        return descending(g, speed, half)

    @wp.func
    def post_time(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar):
        """When the parabola of eq. (36) first meets post k (module docstring), or NO_CONTACT."""
        p, a, r, length = surfaces.point[k], surfaces.normal[k], surfaces.half_u[k], surfaces.half_v[k]
        d = x - p
        tolerance = shape.slack(surfaces, k, x)
        best = side_time(d, v, g, a, r + radius, r, length, tolerance)
        inner = side_time(d, v, g, a, r, r, length, tolerance)
        if inner >= ZERO and (best < ZERO or inner < best):
            best = inner
        z, w, q = wp.dot(d, a), wp.dot(v, a), HALF * wp.dot(g, a)
        if wp.abs(q) <= TOLERANCE * l1(g):
            q = ZERO  # gravity across the axis, up to rounding
        over = wp.length(across(d, a)) <= r
        for j in range(4):
            sign = ONE
            base = length
            offset = radius
            if j >= 2:
                sign = scalar(-1.0)
                base = ZERO
            if j % 2 == 1:
                offset = ZERO
            cap = cap_time(sign * (z - base), sign * w, sign * q, offset, over)
            if cap >= ZERO and (best < ZERO or cap < best):
                # the centre's own crossing (offset 0) at once counts only over the cap: one starting
                # at the cap's plane beyond the rim (within the slack) would be stopped there for ever
                if wp.length(across(d + cap * (v + HALF * cap * g), a)) <= r + tolerance and (
                    cap > ZERO or offset > ZERO or over
                ):
                    best = cap
        if best > LATEST:
            best = scalar(NO_CONTACT)
        return best

    return SimpleNamespace(post_time=post_time, side_time=side_time)


@functools.cache
def _post_air(precision: str) -> SimpleNamespace:
    """`side_theta`: a post's side on an air step's Hermite (module docstring)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    ZERO, HALF, ONE, TWO = scalar(0.0), scalar(0.5), scalar(1.0), scalar(2.0)
    hermite_vec, shape = make_dense_output(precision).hermite_vec, _post_shape(precision)
    across, along = shape.across, shape.along
    ITERATIONS, RESOLUTION = BISECTIONS[precision], scalar(4.0 * EPSILON[precision])

    @wp.func
    def hermite_side(
        theta: scalar,
        slope: wp.int32,
        sign: scalar,
        p: vec3,
        a: vec3,
        ss: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
    ):
        """sign f(theta) (or sign f') of f = rho^2 - ss on a step's Hermite (d, e: h and h^2 times
        the derivatives)."""
        x, dx = hermite_vec(theta, x0, d0, e0, x1, d1, e1)
        radial = across(x - p, a)
        if slope != 0:
            return sign * TWO * wp.dot(radial, across(dx, a))
        return sign * (wp.dot(radial, radial) - ss)

    @wp.func
    def hermite_bisect(
        lo: scalar,
        hi: scalar,
        slope: wp.int32,
        sign: scalar,
        p: vec3,
        a: vec3,
        ss: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
    ):
        """`bisect` on a step's Hermite (theta in [0, 1])."""
        for _ in range(ITERATIONS):
            if hi - lo > RESOLUTION:
                mid = HALF * (lo + hi)
                if hermite_side(mid, slope, sign, p, a, ss, x0, d0, e0, x1, d1, e1) > ZERO:
                    lo = mid
                else:
                    hi = mid
        return hi

    @wp.func
    def touching(
        theta: scalar,
        p: vec3,
        a: vec3,
        r: scalar,
        length: scalar,
        ss: scalar,
        slack: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
    ):
        """Whether the centre at theta is met at once: rho in [r, s], z on the length, closing."""
        x, dx = hermite_vec(theta, x0, d0, e0, x1, d1, e1)
        radial = across(x - p, a)
        rr = wp.dot(radial, radial)
        closing = wp.dot(radial, across(dx, a)) < ZERO
        return rr <= ss and rr >= r * r and closing and along(wp.dot(x - p, a), length, slack)

    @wp.func
    def touch_bisect(
        lo: scalar,
        hi: scalar,
        p: vec3,
        a: vec3,
        r: scalar,
        length: scalar,
        ss: scalar,
        slack: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
    ):
        """Where `touching` turns true from false at lo to true at hi, to rounding of theta: hi."""
        for _ in range(ITERATIONS):
            if hi - lo > RESOLUTION:
                mid = HALF * (lo + hi)
                if touching(mid, p, a, r, length, ss, slack, x0, d0, e0, x1, d1, e1):
                    hi = mid
                else:
                    lo = mid
        return hi

    @wp.func
    def line_theta(
        p: vec3,
        a: vec3,
        r: scalar,
        length: scalar,
        s: scalar,
        slack: scalar,
        x0: vec3,
        d0: vec3,
        e0: vec3,
        x1: vec3,
        d1: vec3,
        e1: vec3,
    ):
        """`side_theta` of the axis from p along the unit a (a = 0: the point p itself) of radius r
        and length L (m): rho is the distance across a (a = 0: |x - p|)."""
        ss = s * s
        f_lo = hermite_side(ZERO, 0, ONE, p, a, ss, x0, d0, e0, x1, d1, e1)
        df_lo = hermite_side(ZERO, 1, ONE, p, a, ss, x0, d0, e0, x1, d1, e1)
        if f_lo <= ZERO and df_lo < ZERO and along(wp.dot(x0 - p, a), length, slack) and f_lo + ss >= r * r:
            return ZERO
        best = TWO
        lo = ZERO
        for i in range(SIDE_SAMPLES):
            if best > ONE:
                hi = scalar(i + 1) / scalar(SIDE_SAMPLES)
                f_hi = hermite_side(hi, 0, ONE, p, a, ss, x0, d0, e0, x1, d1, e1)
                df_hi = hermite_side(hi, 1, ONE, p, a, ss, x0, d0, e0, x1, d1, e1)
                root = TWO
                if f_lo > ZERO and f_hi <= ZERO:
                    root = hermite_bisect(lo, hi, 0, ONE, p, a, ss, x0, d0, e0, x1, d1, e1)
                elif f_lo > ZERO and df_lo < ZERO and df_hi > ZERO:  # a minimum inside: a graze?
                    bottom = hermite_bisect(lo, hi, 1, scalar(-1.0), p, a, ss, x0, d0, e0, x1, d1, e1)
                    if hermite_side(bottom, 0, ONE, p, a, ss, x0, d0, e0, x1, d1, e1) <= ZERO:
                        root = hermite_bisect(lo, bottom, 0, ONE, p, a, ss, x0, d0, e0, x1, d1, e1)
                if root <= ONE:
                    x, _dx = hermite_vec(root, x0, d0, e0, x1, d1, e1)
                    if along(wp.dot(x - p, a), length, slack):
                        best = root
                if best > ONE and r > ZERO and f_hi <= ZERO:
                    # a post's centre coming onto the length through an end already within s, closing
                    x_lo, _dx_lo = hermite_vec(lo, x0, d0, e0, x1, d1, e1)
                    if not along(wp.dot(x_lo - p, a), length, slack):
                        if touching(hi, p, a, r, length, ss, slack, x0, d0, e0, x1, d1, e1):
                            best = touch_bisect(lo, hi, p, a, r, length, ss, slack, x0, d0, e0, x1, d1, e1)
                lo = hi
                f_lo = f_hi
                df_lo = df_hi
        return best

    @wp.func
    def side_theta(
        surfaces: Surfaces, k: wp.int32, s: scalar, slack: scalar, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3
    ):
        """The first theta in [0, 1] on a step's Hermite where the centre closes to s of post k's
        axis with z on its length (met at once where rho in [r, s], closing), or 2."""
        p, a, r, length = surfaces.point[k], surfaces.normal[k], surfaces.half_u[k], surfaces.half_v[k]
        return line_theta(p, a, r, length, s, slack, x0, d0, e0, x1, d1, e1)

    return SimpleNamespace(side_theta=side_theta, line_theta=line_theta)
