"""The flight in air between contacts: adaptive Dormand-Prince steps (`physics.integrate`), each
accepted step searched for plane contacts on its dense output, so a contact is located on the
step's interpolant (to rounding) rather than stepped past.

The rules at the planes are those of the exact flight (`physics.ballistic`): planes are one-sided
(one with the pellet's centre behind it at the start is never met); a pellet touching (within the
touching band of `physics.geometry`) or overlapping a plane, or leaving the plane it just hit,
meets it at once if it is not moving away from it. Otherwise a plane it touches (the one it is
leaving, or one it overlaps) waits until the pellet's normal velocity turns towards it: the
pellet meets it then if it is still touching, else the plane is watched from there. A watched plane is met where its gap n.(x - p) - R reaches
0, also inside a step whose ends are both clear of it (a graze: the gap's minimum on the step).
Ties go to the lower index; a contact later than MAX_FLIGHT_TIME counts as none, and a flight
that takes more than MAX_FLIGHT_STEPS steps is given up (plane -2, counted in the statistics).
The planes' states live in the bits of an int32: at most `limits.MAX_PLANES_IN_AIR` planes. The
planes are read through `physics.geometry` (heights at the start, a step's gaps, the contact's normal).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .air_screen import make_step_screen
from .ballistic import EPSILON, MAX_FLIGHT_TIME, NO_CONTACT
from .cylinder_contact import make_cylinder_contact
from .edge_contact import make_edge_contact
from .flat_contact import make_flat_contact
from .geometry import MESHES, make_geometry, solid_needs
from .inlining import out_of_line_if
from .integrate import make_dense_output, make_stepper
from .mesh_contact import FEW_FACES, FLOAT32_SLACK, make_mesh_contact
from .types import types_for

MAX_FLIGHT_STEPS = 1 << 16  # per flight between contacts
GAVE_UP = -2  # the plane index of a flight given up after MAX_FLIGHT_STEPS


@functools.cache
def make_roots(precision: str, out_of_line: bool = False) -> SimpleNamespace:
    """`root(lo, hi, slope, sign, g0, s0, q0, g1, s1, q1)`: where the quintic gap on a step (or,
    `slope`, its derivative), times `sign`, falls from > 0 at lo to <= 0 at hi (Illinois); and
    `plane_theta` (where on the step a plane's gap is met). `out_of_line`: `root` one function in
    CUDA code (`physics.inlining`; kernels to rest)."""
    t = types_for(precision)
    scalar = t.scalar
    hermite = make_dense_output(precision).hermite
    THETA_TOLERANCE = scalar(4.0 * EPSILON[precision])
    ITERATIONS = 64 if precision == "float64" else 40

    @wp.func
    def evaluate(
        theta: scalar, slope: wp.int32, sign: scalar, g0: scalar, s0: scalar, q0: scalar, g1: scalar, s1: scalar, q1: scalar
    ):
        value, derivative = hermite(theta, g0, s0, q0, g1, s1, q1)
        if slope != 0:
            return sign * derivative
        return sign * value

    @out_of_line_if(out_of_line)
    @wp.func
    def root(
        lo: scalar,
        hi: scalar,
        slope: wp.int32,
        sign: scalar,
        g0: scalar,
        s0: scalar,
        q0: scalar,
        g1: scalar,
        s1: scalar,
        q1: scalar,
    ):
        """The bracket's upper end once it is narrower than a few rounding errors of theta."""
        f_lo = evaluate(lo, slope, sign, g0, s0, q0, g1, s1, q1)
        f_hi = evaluate(hi, slope, sign, g0, s0, q0, g1, s1, q1)
        side = wp.int32(0)
        steps = wp.int32(0)
        while hi - lo > THETA_TOLERANCE and steps < ITERATIONS:  # (at most ITERATIONS)
            steps += 1
            mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            if not (mid > lo and mid < hi):
                mid = scalar(0.5) * (lo + hi)
            f_mid = evaluate(mid, slope, sign, g0, s0, q0, g1, s1, q1)
            if f_mid > scalar(0.0):
                lo = mid
                f_lo = f_mid
                if side == 1:
                    f_hi = scalar(0.5) * f_hi
                side = wp.int32(1)
            else:
                hi = mid
                f_hi = f_mid
                if side == -1:
                    f_lo = scalar(0.5) * f_lo
                side = wp.int32(-1)
        return hi

    @wp.func
    def plane_theta(watch: wp.int32, g0: scalar, s0: scalar, q0: scalar, g1: scalar, s1: scalar, q1: scalar):
        """Where on the step a plane's gap (values g, h n.v and h^2 n.a at its ends) is met, 2 if
        not; and whether a waiting plane turned to watched. watch: 1 watched, 2 waiting."""
        theta = scalar(2.0)
        now_watched = wp.int32(0)
        low = scalar(0.0)
        if watch == 2 and s1 < scalar(0.0):  # its normal velocity turned towards it in this step
            turn = root(scalar(0.0), scalar(1.0), 1, scalar(1.0), g0, s0, q0, g1, s1, q1)
            gap_turn, _slope = hermite(turn, g0, s0, q0, g1, s1, q1)
            if gap_turn <= scalar(0.0):
                theta = turn
            else:
                now_watched = wp.int32(1)
                low = turn
        if watch == 1 or now_watched != 0:
            if g1 <= scalar(0.0):
                theta = root(low, scalar(1.0), 0, scalar(1.0), g0, s0, q0, g1, s1, q1)
            elif s0 < scalar(0.0) and s1 > scalar(0.0):  # a minimum inside: a graze?
                bottom = root(scalar(0.0), scalar(1.0), 1, scalar(-1.0), g0, s0, q0, g1, s1, q1)
                gap_bottom, _slope = hermite(bottom, g0, s0, q0, g1, s1, q1)
                if gap_bottom <= scalar(0.0):
                    theta = root(scalar(0.0), bottom, 0, scalar(1.0), g0, s0, q0, g1, s1, q1)
        return theta, now_watched

    return SimpleNamespace(root=root, plane_theta=plane_theta)


@functools.cache
def make_face_thetas(precision: str, out_of_line: bool = False) -> SimpleNamespace:
    """`offset_theta`, `through_theta` and `face_thetas`: where on an accepted step a face's plane,
    offset by R or not, is met as a plane's (`make_roots`' `plane_theta`; `out_of_line`: its)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    plane_theta = make_roots(precision, out_of_line=out_of_line).plane_theta

    @wp.func
    def offset_theta(
        n: vec3, level: scalar, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3, radius: scalar
    ):
        """Where on the step the plane n.x = level offset by R is met as a plane's (2: not): watched
        from in front, waiting where the centre starts within R of it, met at once if touching and
        closing."""
        g0, s0, q0 = wp.dot(x0, n) - level, h * wp.dot(v0, n), h * h * wp.dot(a0, n)
        g1, s1, q1 = wp.dot(x1, n) - level, h * wp.dot(v1, n), h * h * wp.dot(a1, n)
        theta = scalar(2.0)
        if g0 > radius:
            theta, _watched = plane_theta(1, g0 - radius, s0, q0, g1 - radius, s1, q1)
        elif g0 >= scalar(0.0):
            if s0 <= scalar(0.0):
                theta = scalar(0.0)  # touching or overlapping it, closing: met now
            else:
                theta, _watched = plane_theta(2, g0 - radius, s0, q0, g1 - radius, s1, q1)
        return theta

    @wp.func
    def through_theta(n: vec3, level: scalar, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3):
        """Where on the step the centre itself first reaches the plane n.x = level from in front (2: not)."""
        g0, s0, q0 = wp.dot(x0, n) - level, h * wp.dot(v0, n), h * h * wp.dot(a0, n)
        g1, s1, q1 = wp.dot(x1, n) - level, h * wp.dot(v1, n), h * h * wp.dot(a1, n)
        through = scalar(2.0)
        if g0 > scalar(0.0):
            through, _watched = plane_theta(1, g0, s0, q0, g1, s1, q1)
        return through

    @wp.func
    def face_thetas(
        n: vec3, level: scalar, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3, radius: scalar
    ):
        """Where on the step a face of unit normal n in the plane n.x = level is met, before its
        inside test (2: not): its plane offset by R (`offset_theta`), and the plane itself met by
        the centre from in front (`through_theta`)."""
        theta = offset_theta(n, level, h, x0, v0, a0, x1, v1, a1, radius)
        return theta, through_theta(n, level, h, x0, v0, a0, x1, v1, a1)

    return SimpleNamespace(offset_theta=offset_theta, through_theta=through_theta, face_thetas=face_thetas)


@functools.cache
def make_solid_search(
    precision: str, out_of_line: bool = False, large: bool = True, edges: bool = True, flat: bool = False
) -> SimpleNamespace:
    """`mesh_theta(...)` and `post_theta(...)`: where on an accepted step a mesh or a post is met
    (`physics.mesh_contact`, `physics.cylinder_contact`), and `face_theta(...)` (a triangle's face,
    unscreened: the tests' reference); `out_of_line`: `make_roots`'; `large` False: no mesh has more than FEW_FACES triangles, `edges` False: none owns edges or
    corners (`geometry.solid_needs`: their code left out); `flat` True: every mesh is small and flat,
    its faces met as its plane's (`physics.flat_contact`)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    screen, flats = make_step_screen(precision), make_flat_contact(precision)
    off_step = screen.off_step
    hermite_vec, planes = make_dense_output(precision).hermite_vec, make_face_thetas(precision, out_of_line)
    offset_theta, through_theta, face_thetas = planes.offset_theta, planes.through_theta, planes.face_thetas
    meshes, posts, features = make_mesh_contact(precision), make_cylinder_contact(precision), make_edge_contact(precision)
    LARGE, EDGES, FLAT = large, edges, flat

    @wp.func
    def bezier_box(h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3):
        """The box (low, high) of the step's quintic Bezier control points: the curve lies in it."""
        d0, dd0, d1, dd1 = h * v0, h * h * a0, h * v1, h * h * a1
        p1, p2 = x0 + d0 / scalar(5.0), x0 + scalar(0.4) * d0 + dd0 / scalar(20.0)
        p3, p4 = x1 - scalar(0.4) * d1 + dd1 / scalar(20.0), x1 - d1 / scalar(5.0)
        low = wp.min(wp.min(wp.min(x0, x1), wp.min(p1, p2)), wp.min(p3, p4))
        high = wp.max(wp.max(wp.max(x0, x1), wp.max(p1, p2)), wp.max(p3, p4))
        return low, high

    @wp.func
    def flat_theta(
        surfaces: Surfaces,
        k: wp.int32,
        h: scalar,
        x0: vec3,
        v0: vec3,
        a0: vec3,
        x1: vec3,
        v1: vec3,
        a1: vec3,
        radius: scalar,
        bound: scalar,
    ):
        """Where on the step a face of flat mesh k is met (2: not): its plane offset by R
        (`offset_theta`) where the interpolant's centre is then over one of its triangles, else the
        plane itself reached by the centre (`through_theta`) over one (the centre, coming from in
        front or waiting within R, reaches the plane no earlier than its offset: tests/
        test_air_screen.py); none where its plane is met no earlier than `bound`
        (`air_screen.off_plane`)."""
        a, n = flats.plane_of(surfaces, k)
        if screen.off_plane(n, a, radius, h, x0, v0, a0, x1, v1, a1, bound):
            return scalar(2.0)
        level = wp.dot(a, n)
        theta = offset_theta(n, level, h, x0, v0, a0, x1, v1, a1, radius)
        if theta <= scalar(1.0):
            x, _slope = hermite_vec(theta, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
            if flats.over_any(surfaces, k, x):
                return theta  # (the centre reaches the plane itself no earlier)
        through = through_theta(n, level, h, x0, v0, a0, x1, v1, a1)
        theta = scalar(2.0)
        if through <= scalar(1.0):
            x, _slope = hermite_vec(through, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
            if flats.over_any(surfaces, k, x):
                theta = through
        return theta

    @wp.func
    def flat_apart(
        surfaces: Surfaces, k: wp.int32, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3, radius: scalar
    ):
        """Whether the step starts more than R in front of flat mesh k's plane and stays so (its
        control points' hull, `air_screen.off_plane`), with the margin of its vertices' distance
        from that plane (`flat_contact.flat_slack`): then neither a
        face nor an edge or corner of its border (all on the plane) is met on it."""
        a, n = flats.plane_of(surfaces, k)
        off = flats.flat_slack(surfaces, k)
        far = wp.dot(x0 - a, n) > radius + off
        return far and screen.off_plane(n, a, radius + off, h, x0, v0, a0, x1, v1, a1, scalar(2.0))

    @wp.func
    def face_theta(
        n: vec3, a: vec3, b: vec3, c: vec3, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3, radius: scalar
    ):
        """Where on the step the face of triangle (a, b, c), of unit normal n, is met (2: not):
        `face_thetas`, each kept where the interpolant's centre is inside the triangle."""
        theta, through = face_thetas(n, wp.dot(a, n), h, x0, v0, a0, x1, v1, a1, radius)
        if theta <= scalar(1.0):
            x, _slope = hermite_vec(theta, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
            if not meshes.inside(n, a, b, c, x):
                theta = scalar(2.0)
        if through < theta:
            x, _slope = hermite_vec(through, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
            if meshes.inside(n, a, b, c, x):
                theta = through
        return theta

    @wp.func
    def triangle_theta(
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
        bound: scalar,
    ):
        """Where on the step triangle `face` of mesh k, or an edge or corner it owns
        (`edge_contact.features_theta`, within the box (low, high) of the step), is met (2: not):
        `face_thetas`, each kept where the interpolant's centre is inside the triangle; a face met no
        earlier than `bound` (the contact found so far) may be reported as not met."""
        best = scalar(2.0)
        if wp.static(EDGES):
            best = features.features_theta(surfaces, k, face, h, x0, v0, a0, x1, v1, a1, radius, low, high)
        a, b, c = meshes.vertices(surfaces, k, face)
        n = wp.cross(b - a, c - a)
        if wp.length(n) == scalar(0.0):
            return best
        n = wp.normalize(n)
        if off_step(n, a, b, c, radius, h, x0, v0, a0, x1, v1, a1, low, high, bound):  # (`physics.air_screen`)
            return best
        theta = face_theta(n, a, b, c, h, x0, v0, a0, x1, v1, a1, radius)
        if theta <= best:  # ties: the face
            return theta
        return best

    @wp.func
    def post_theta(
        surfaces: Surfaces, k: wp.int32, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3, radius: scalar
    ):
        """The earliest theta on the step where post k is met (2: none; `physics.cylinder_contact`):
        none where the box of the step's quintic Bezier control points grown by R misses the
        post's box; else its side (offset by R, then the centre's) and its caps as faces kept
        where the centre is over them."""
        low, high = bezier_box(h, x0, v0, a0, x1, v1, a1)
        post_low, post_high = posts.post_box(surfaces, k)
        grow = radius + scalar(FLOAT32_SLACK) * (meshes.l1(low) + meshes.l1(high))
        best = scalar(2.0)
        near = True
        for i in range(3):
            if low[i] - grow > post_high[i] or high[i] + grow < post_low[i]:
                near = False
        if not near:
            return best
        base, axis, r, length = posts.post_frame(surfaces, k)
        d0, e0, d1, e1 = h * v0, h * h * a0, h * v1, h * h * a1
        slack = posts.slack(surfaces, k, x0)
        best = posts.side_theta(surfaces, k, r + radius, slack, x0, d0, e0, x1, d1, e1)
        best = wp.min(best, posts.side_theta(surfaces, k, r, slack, x0, d0, e0, x1, d1, e1))
        over = posts.on_cap(surfaces, k, x0, scalar(0.0))  # a cap met at once only from over it
        for j in range(2):
            n = axis
            level = wp.dot(base, axis) + length
            if j == 1:
                n = -axis
                level = -wp.dot(base, axis)
            theta, through = face_thetas(n, level, h, x0, v0, a0, x1, v1, a1, radius)
            for m in range(2):
                cap = theta
                if m == 1:
                    cap = through
                if cap < best and (cap > scalar(0.0) or over):
                    x, _slope = hermite_vec(cap, x0, d0, e0, x1, d1, e1)
                    if posts.on_cap(surfaces, k, x, slack):
                        best = cap
        return best

    @wp.func
    def mesh_theta(
        surfaces: Surfaces, k: wp.int32, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3, radius: scalar
    ):
        """The earliest theta on the step where mesh k is met (2: none): the triangles whose boxes
        meet the box of the step's quintic Bezier control points grown by R (the curve lies in
        their hull), each by `triangle_theta`."""
        best = scalar(2.0)
        faces = meshes.faces(surfaces, k)
        low, high = bezier_box(h, x0, v0, a0, x1, v1, a1)
        if wp.static(FLAT):  # its border's edges and corners, then its plane
            if flat_apart(surfaces, k, h, x0, v0, a0, x1, v1, a1, radius):
                return best
            if wp.static(EDGES):
                for face in range(faces):
                    best = wp.min(best, features.features_theta(surfaces, k, face, h, x0, v0, a0, x1, v1, a1, radius, low, high))
            return wp.min(best, flat_theta(surfaces, k, h, x0, v0, a0, x1, v1, a1, radius, best))  # (ties: the face)
        if faces <= FEW_FACES:  # a small mesh: every triangle (`mesh_contact`)
            for face in range(faces):
                best = wp.min(best, triangle_theta(surfaces, k, face, h, x0, v0, a0, x1, v1, a1, radius, low, high, best))
            return best
        if wp.static(LARGE):
            mesh, mesh_low, mesh_high = meshes.bounds(surfaces, k)
            grow = radius + scalar(FLOAT32_SLACK) * (
                meshes.l1(low) + meshes.l1(high) + meshes.l1(mesh_low) + meshes.l1(mesh_high)
            )
            box_low, box_high = meshes.single(low - vec3(grow, grow, grow)), meshes.single(high + vec3(grow, grow, grow))
            if meshes.walked(surfaces, k):  # a terrain: the BVH's candidates, from the cells the box spans
                reach = scalar(0.5) * wp.length(high - low) + scalar(2.0) * grow
                i0, i1, j0, j1 = meshes.around(surfaces, k, scalar(0.5) * (low + high), reach)
                ni, nj = i1 - i0 + 1, j1 - j0 + 1
                du, dw = meshes.across(surfaces, k, x1 - x0)
                along_i = wp.abs(du) >= wp.abs(dw)
                inner = wp.where(along_i, nj, ni)
                for m in range(ni * nj):  # rows across the step's main direction from its start: earlier contacts first
                    p, q = m / inner, m % inner
                    i, j = wp.where(along_i, p, q), wp.where(along_i, q, p)
                    i, j = wp.where(du >= scalar(0.0), i0 + i, i1 - i), wp.where(dw >= scalar(0.0), j0 + j, j1 - j)
                    first = meshes.face_of(surfaces, k, i, j)
                    for face in range(first, wp.where(first >= 0, first + 2, first)):
                        if meshes.boxed(surfaces, k, face, box_low, box_high):
                            best = wp.min(
                                best, triangle_theta(surfaces, k, face, h, x0, v0, a0, x1, v1, a1, radius, low, high, best)
                            )
                return best
            query = wp.mesh_query_aabb(mesh, box_low, box_high)
            face = wp.int32(0)
            while wp.mesh_query_aabb_next(query, face):
                best = wp.min(best, triangle_theta(surfaces, k, face, h, x0, v0, a0, x1, v1, a1, radius, low, high, best))
        return best

    return SimpleNamespace(
        mesh_theta=mesh_theta,
        post_theta=post_theta,
        bezier_box=bezier_box,
        face_theta=face_theta,
    )


@functools.cache
def make_plane_search(precision: str, planes, plates: bool = False, out_of_line: bool = False) -> SimpleNamespace:
    """`start(...)` (the planes' states at a flight's start) and `search(...)` (the earliest
    contact on an accepted step); `planes`: fixed at code generation (unrolled) or None; `plates`:
    surfaces may be finite plates (module docstring); `out_of_line`: `make_roots`'."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    roots, geo = make_roots(precision, out_of_line=out_of_line), make_geometry(precision, planes, True, plates)
    hermite_vec = make_dense_output(precision).hermite_vec
    STATIC, PLATES, WITH_MESHES = planes, plates, plates >= MESHES
    WITH_POSTS, large, edges, flat = solid_needs(plates)
    meshes, posts, solids = (
        make_mesh_contact(precision),
        make_cylinder_contact(precision),
        make_solid_search(precision, out_of_line=out_of_line, large=large, edges=edges, flat=flat),
    )
    plane_theta = roots.plane_theta

    @wp.func
    def start_plane(k: wp.int32, position: vec3, velocity: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics):
        """Plane k at a flight's start: 0 never met, 1 watched, 2 waiting for the turn, 3 met now."""
        height, gap, normal = geo.gap(surfaces, k, position, physics.radius)
        moving_away = wp.dot(velocity, normal) > scalar(0.0)
        state = wp.int32(0)
        if k == touching:
            state = wp.int32(3)
            if moving_away:
                state = wp.int32(2)
        elif height >= scalar(0.0):
            state = wp.int32(1)
            if gap <= scalar(0.0):
                state = wp.int32(3)
                if moving_away:
                    state = wp.int32(2)
        return state

    @wp.func
    def start_plate(k: wp.int32, position: vec3, velocity: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics):
        """`start_plane` where k may be a plate: one overlapping its plane beside it is watched."""
        state = start_plane(k, position, velocity, touching, surfaces, physics)
        if state == 3 or state == 2:
            if k != touching and not geo.inside(surfaces, k, position):
                state = wp.int32(1)
        return state

    @wp.func
    def start(position: vec3, velocity: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics):
        """(watched, waiting) bit masks, and the first plane met at once (-1 none)."""
        watched = wp.int32(0)
        waiting = wp.int32(0)
        now = wp.int32(-1)
        count = geo.count(surfaces)
        if wp.static(STATIC is not None):
            count = wp.static(STATIC)
        for k in range(count):
            if wp.static(PLATES):
                state = start_plate(k, position, velocity, touching, surfaces, physics)
                if wp.static(WITH_MESHES):
                    if meshes.is_mesh(surfaces, k) or posts.is_post(surfaces, k):
                        state = wp.int32(1)  # watched: `mesh_theta`, `post_theta` apply their rules
            else:
                state = start_plane(k, position, velocity, touching, surfaces, physics)
            if state == 1:
                watched = watched | (wp.int32(1) << k)
            elif state == 2:
                waiting = waiting | (wp.int32(1) << k)
            elif state == 3 and now < 0:
                now = k
        return watched, waiting, now

    @wp.func
    def plate_theta(k: wp.int32, watch: wp.int32, x: vec3, theta: scalar, now_watched: wp.int32, surfaces: Surfaces):
        """A step's crossing (theta, with the step's point x there) of surface k's plane kept if x is
        on it (a plate; a waiting plate turns to watched where it is not)."""
        if theta <= scalar(1.0) and not geo.inside(surfaces, k, x):
            theta = scalar(2.0)
            if watch == 2:
                now_watched = wp.int32(1)
        return theta, now_watched

    @wp.func
    def search(
        h: scalar,
        x0: vec3,
        v0: vec3,
        a0: vec3,
        x1: vec3,
        v1: vec3,
        a1: vec3,
        watched: wp.int32,
        waiting: wp.int32,
        surfaces: Surfaces,
        physics: Physics,
    ):
        """The earliest contact on an accepted step from state 0 to state 1: (theta in [0, 1],
        plane; -1 and 2 for none) and the planes' states after the step."""
        best_theta = scalar(2.0)
        best = wp.int32(-1)
        count = geo.count(surfaces)
        if wp.static(STATIC is not None):
            count = wp.static(STATIC)
        for k in range(count):
            bit = wp.int32(1) << k
            watch = wp.int32(0)
            if (watched & bit) != 0:
                watch = wp.int32(1)
            elif (waiting & bit) != 0:
                watch = wp.int32(2)
            if watch != 0:
                theta = scalar(2.0)
                now_watched = wp.int32(0)
                solid = wp.bool(False)  # a mesh or a post: its own rules, not its plane's
                if wp.static(WITH_MESHES):
                    solid = meshes.is_mesh(surfaces, k) or posts.is_post(surfaces, k)
                if not solid:
                    g0, s0, q0, g1, s1, q1 = geo.step_gaps(surfaces, k, physics.radius, h, x0, v0, a0, x1, v1, a1)
                    if wp.static(PLATES):  # a plate not clear of its plane at the start (beside it, behind it): not this step
                        plate = geo.is_plate(surfaces, k)
                        if not (plate and watch == 1 and g0 <= scalar(0.0)):
                            theta, now_watched = plane_theta(watch, g0, s0, q0, g1, s1, q1)
                        if plate and theta <= scalar(1.0):
                            x, _slope = hermite_vec(theta, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
                            theta, now_watched = plate_theta(k, watch, x, theta, now_watched, surfaces)
                    else:
                        theta, now_watched = plane_theta(watch, g0, s0, q0, g1, s1, q1)
                if wp.static(WITH_MESHES):
                    if meshes.is_mesh(surfaces, k):
                        theta = solids.mesh_theta(surfaces, k, h, x0, v0, a0, x1, v1, a1, physics.radius)
                    if wp.static(WITH_POSTS):
                        if posts.is_post(surfaces, k):
                            theta = solids.post_theta(surfaces, k, h, x0, v0, a0, x1, v1, a1, physics.radius)
                if now_watched != 0:
                    watched = watched | bit
                    waiting = waiting & ~bit
                if theta < best_theta:
                    best_theta = theta
                    best = k
        return best_theta, best, watched, waiting

    return SimpleNamespace(start=start, search=search)


@functools.cache
def make_air_flight(
    precision: str, planes, laws: tuple, watch: tuple = (0, 0, False), plates: bool = False, out_of_line: bool = False
) -> SimpleNamespace:
    """`to_contact` and `advance` in air (the flight interface of `physics.flight`; the steps a
    `to_contact` took are its sixth value), `to_contact_within` (the flight up to a time) and
    `to_contact_watched` (`to_contact` with each accepted step given to `tallies.path`'s watch of
    `watch` = (thresholds, places, map)); `watched_loop` (`make_flight_loop`'s, watched when `watch` is).
    `out_of_line`: the flight's loop, its root finder and the air's rates one function each in CUDA
    code (`physics.inlining`): for kernels to rest, which call them from several sites."""
    from ..tallies.path import ESCAPED, make_path_roots  # (tallies imports physics: not at the top)
    from ..tallies.path_replay import watch_for  # (tallies imports physics: not at the top)

    watcher, ground = watch_for(precision, *watch), make_path_roots(precision)
    Track, Tally = watcher.Track, watcher.Tally
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    stepper, dense = make_stepper(precision, laws, out_of_line=out_of_line), make_dense_output(precision)
    search, geo = (
        make_plane_search(precision, planes, plates, out_of_line=out_of_line),
        make_geometry(precision, planes, True, plates),
    )
    LATEST, MAX_STEPS = scalar(MAX_FLIGHT_TIME), MAX_FLIGHT_STEPS
    SPIN_CHANGES = laws[2] is not None

    @wp.func
    def scaled(velocity_part: vec3, spin_part: vec3, velocity: vec3, spin: vec3, physics: Physics):
        """The step error's norm of a (velocity, spin) pair (`physics.integrate.step`): the larger
        of each over tolerance x its scale (spin only where it changes)."""
        air = physics.air
        norm = wp.length(velocity_part) / (air.tolerance * (wp.length(velocity) + air.speed_floor))
        if wp.static(SPIN_CHANGES):
            norm = wp.max(norm, wp.length(spin_part) / (air.tolerance * (wp.length(spin) + air.speed_floor / air.radius)))
        return norm

    @wp.func
    def first_step(velocity: vec3, spin: vec3, acceleration: vec3, spin_change: vec3, physics: Physics):
        """The starting step of Hairer, Norsett & Wanner (Solving ODEs I, 2nd ed., II.4, p. 169;
        SciPy's `select_initial_step`), in the step error's norm: d0 = |y|, d1 = |f(y)|, h0 =
        0.01 d0 / d1, an explicit Euler step of h0 for d2 = |f(y + h0 f) - f(y)| / h0, then
        min(100 h0, (0.01 / max(d1, d2))^(1/5)) (the error estimate's order 4, plus 1)."""
        d0 = scaled(velocity, spin, velocity, spin, physics)
        d1 = scaled(acceleration, spin_change, velocity, spin, physics)
        h0 = scalar(1e-6)
        if d0 >= scalar(1e-5) and d1 >= scalar(1e-5):
            h0 = scalar(0.01) * d0 / d1
        a1, c1 = stepper.rates(velocity + h0 * acceleration, spin + h0 * spin_change, physics)
        d2 = scaled(a1 - acceleration, c1 - spin_change, velocity, spin, physics) / h0
        largest = wp.max(d1, d2)
        h1 = wp.max(scalar(1e-6), h0 * scalar(1e-3))
        if largest > scalar(1e-15):
            h1 = wp.pow(scalar(0.01) / largest, scalar(0.2))
        return wp.min(scalar(100.0) * h0, h1)

    @wp.func
    def next_step(h: scalar, error: scalar):
        """The step after one of length h with this scaled error (safety 0.9, within 0.2 to 5 x h)."""
        factor = scalar(5.0)
        if error > scalar(0.0):
            factor = wp.clamp(scalar(0.9) * wp.pow(error, scalar(-0.2)), scalar(0.2), scalar(5.0))
        return h * factor

    def make_flight_loop(WATCH: bool):
        """The flight to the next plane contact within `latest` (s): `loop(position, velocity, spin,
        touching, surfaces, physics, latest, track, tally)` -> (dt, plane, normal, x, v, w, steps,
        track). One loop for both builds: with WATCH (`tallies.path`'s watch) each accepted step's
        interpolant up to the contact is given to the watch, and a flight with no plane left to meet
        is flown on, watched, until it is below the hazard's ground plane falling (`ground.below`,
        to `ground_theta` of its last step; within a `latest` short of MAX_FLIGHT_TIME, a dense
        phase's leap, it is flown on to `latest`, its watch ended for good: ESCAPED); without it
        (track and tally unused int32s) the code is that of the flight alone."""
        TrackT, TallyT = (Track, Tally) if WATCH else (wp.int32, wp.int32)

        @out_of_line_if(out_of_line)
        @wp.func
        def loop(
            position: vec3,
            velocity: vec3,
            spin: vec3,
            touching: wp.int32,
            surfaces: Surfaces,
            physics: Physics,
            latest: scalar,
            track: TrackT,
            tally: TallyT,
        ):
            watched, waiting, now = search.start(position, velocity, touching, surfaces, physics)
            if now >= 0:
                return scalar(0.0), now, geo.normal(surfaces, now, position), position, velocity, spin, wp.int32(0), track
            if watched == 0 and waiting == 0 and latest >= LATEST:
                stop = True
                if wp.static(WATCH):
                    stop = ground.below(tally, position, velocity)
                if stop:
                    return scalar(NO_CONTACT), wp.int32(-1), vec3(), position, velocity, spin, wp.int32(0), track
            acceleration, spin_change = stepper.rates(velocity, spin, physics)
            h = first_step(velocity, spin, acceleration, spin_change, physics)
            time = scalar(0.0)
            steps = wp.int32(0)
            while steps < MAX_STEPS and time < latest:
                h = wp.min(h, latest - time)
                x1, v1, w1, a1, d1, error = stepper.step(position, velocity, spin, acceleration, spin_change, h, physics)
                steps += 1
                if error <= scalar(1.0):
                    theta, k, watched, waiting = search.search(
                        h, position, velocity, acceleration, x1, v1, a1, watched, waiting, surfaces, physics
                    )
                    if wp.static(WATCH):
                        d0, e0, d1s, e1 = h * velocity, h * h * acceleration, h * v1, h * h * a1
                        end = scalar(1.0)
                        gone = False
                        if k >= 0:
                            end = theta
                        elif watched == 0 and waiting == 0 and ground.below(tally, x1, v1):
                            end = ground.ground_theta(tally, position, d0, e0, x1, d1s, e1)
                            gone = True  # it escapes: nothing left to meet, below the ground
                        track = watcher.segment(track, tally, position, d0, e0, x1, d1s, e1, h, end)
                        if gone:
                            if latest >= LATEST:
                                return scalar(NO_CONTACT), wp.int32(-1), vec3(), x1, v1, w1, steps, track
                            track.cell = wp.int32(ESCAPED)  # (flown on to `latest`: a dense phase's leap)
                    if k >= 0:
                        x, slope = dense.hermite_vec(theta, position, h * velocity, h * h * acceleration, x1, h * v1, h * h * a1)
                        w = dense.cubic_vec(theta, spin, h * spin_change, w1, h * d1)
                        n = geo.contact_normal(surfaces, k, x, slope / h, physics.radius)
                        return time + theta * h, k, n, x, slope / h, w, steps, track
                    position = x1
                    velocity = v1
                    spin = w1
                    acceleration = a1
                    spin_change = d1
                    time = time + h
                h = next_step(h, error)
            stopped = wp.int32(-1)
            if steps >= MAX_STEPS:
                stopped = wp.int32(GAVE_UP)
            return scalar(NO_CONTACT), stopped, vec3(), position, velocity, spin, steps, track

        return loop

    flight_loop, watched_loop = make_flight_loop(False), make_flight_loop(watcher.ON)

    @wp.func
    def to_contact_within(
        position: vec3, velocity: vec3, spin: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics, latest: scalar
    ):
        """(dt, plane, normal, x, v, w, steps) at the next plane contact within `latest` (s) (its
        normal: the plane's there); plane -1 (none by then: the state `latest` later) or GAVE_UP
        with the state where the flight stopped, normal 0."""
        dt, k, n, x, v, w, steps, _track = flight_loop(
            position, velocity, spin, touching, surfaces, physics, latest, wp.int32(0), wp.int32(0)
        )
        return dt, k, n, x, v, w, steps

    @wp.func
    def to_contact(position: vec3, velocity: vec3, spin: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics):
        """(dt, plane, normal, x, v, w, steps) at the next plane contact; plane -1 (none before
        MAX_FLIGHT_TIME) or GAVE_UP with the state where the flight stopped."""
        return to_contact_within(position, velocity, spin, touching, surfaces, physics, LATEST)

    @wp.func
    def to_contact_watched(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        touching: wp.int32,
        surfaces: Surfaces,
        physics: Physics,
        track: Track,
        tally: Tally,
    ):
        """`to_contact`, watched (`make_flight_loop`; without thresholds the flight alone): its values and the track."""
        if wp.static(watcher.ON):
            return watched_loop(position, velocity, spin, touching, surfaces, physics, LATEST, track, tally)
        dt, k, n, x, v, w, steps = to_contact_within(position, velocity, spin, touching, surfaces, physics, LATEST)
        return dt, k, n, x, v, w, steps, track

    @wp.func
    def advance(position: vec3, velocity: vec3, spin: vec3, dt: scalar, physics: Physics):
        """The state dt (s) later, no contact looked for."""
        acceleration, spin_change = stepper.rates(velocity, spin, physics)
        h = wp.min(first_step(velocity, spin, acceleration, spin_change, physics), dt)
        time = scalar(0.0)
        steps = wp.int32(0)
        while time < dt and steps < MAX_STEPS:
            h = wp.min(h, dt - time)
            x1, v1, w1, a1, d1, error = stepper.step(position, velocity, spin, acceleration, spin_change, h, physics)
            steps += 1
            if error <= scalar(1.0):
                position = x1
                velocity = v1
                spin = w1
                acceleration = a1
                spin_change = d1
                time = time + h
            h = next_step(h, error)
        return position, velocity, spin

    return SimpleNamespace(
        to_contact=to_contact,
        to_contact_within=to_contact_within,
        advance=advance,
        to_contact_watched=to_contact_watched,
        watched_loop=watched_loop,
    )
