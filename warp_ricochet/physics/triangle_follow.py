"""A pellet moving along a triangle mesh (boxes, meshes, terrain): which triangle it lies on, and
what it does where its centre leaves that triangle (docs/geometry.md, "Rest on triangles"; SI units).

`physics.surface_follow` moves a pellet along one triangle of mesh k at a time, as along a plate:
in that triangle's plane, with the mesh's material, a phase ending where the centre, projected along
the triangle's normal, leaves it (`plate_edge`). Then `cross` takes the contact point y = x - R n
(on the edge, just past it) and, of the triangles other than the one left over which y lies within
rounding of their plane, the one y moving on along v stays on longest (the neighbour across the
edge, or the one around a vertex the path goes into). With u = v.n' the
velocity's speed along the neighbour's normal n' and N' the load on it (`surface_motion`):

- no neighbour (the mesh's border, a hole): the pellet lifts off (FLIGHT), as over a plate's edge;
- a convex edge (u >= 0) it would leave by the rule of a rebound (u > sqrt(2 R N'/m): a hop higher
  than its radius, docs/ground.md 5; or N' <= 0): it lifts off, and its flight meets the neighbour;
- a concave edge (u < 0) closing faster than sqrt(2 R N'/m): CONTACT, an impact on the neighbour
  (the caller's impact law, with the normal of the face it closes on, `geometry.contact_normal`);
- otherwise a change of plane: the centre goes to R in front of the neighbour over y (a convex
  edge: the pivot about the edge; concave: the overlap of R (1 - cos) removed), the velocity loses
  u (as a rebound that does not separate loses its normal speed) and, if the centre rose against
  gravity, the kinetic energy that takes; a rolling pellet rolls on (its spin about the normal
  kept, its rolling spin that of its new velocity): the energy never rises. A pellet that changes plane
  into a concave crease at rest speed or less, pushed into it by both faces' slopes, rests there
  (REST: it cannot climb a step of its radius, `physics.rest_speed`); so does one that changes plane
  POCKET times in a row at the rest speed or less (a pocket of several triangles, as the corner
  where a valley meets a slope; `physics.surface_follow`).

A pellet that stays on the mesh with its centre over no triangle but on a convex edge or corner
at y (`edge_contact.touching`; radial unit normal r from y) rolls off it to one side, as a sphere on
a ridge (`ridge`): of the triangles through y, onto the one its velocity pivots it towards fastest
(about y, r turning along the unit tangent d towards the triangle's normal n': v.d largest, > 0) if
(v.d)^2 / 2 pays the centre's rise g.R (r - n'); else onto the one gravity pulls it towards most
(g.d largest; its speed along -d lost). Its centre goes to y + R n' and its velocity into that
plane, paying any rise. Gravity pulling it off every one (a border), it pivots to where its radial
r' is level (g.r' = 0) and flies from y + R r', its speed along r' dropped (as off a vertical side).

Each change of plane is one step of the pellet's budget (`physics.max_steps`), so a pellet crossing
many nearly coplanar triangles (a terrain's cells) costs one BVH query and one phase per triangle.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON, ROUNDING
from .mesh_contact import FLOAT32_SLACK, make_mesh_contact, make_mesh_faces
from .surface_motion import FLIGHT, REST, make_surface_motion
from .types import types_for

CHANGE = -1  # `cross`: the pellet goes on along the neighbour (the other codes: surface_follow's)
CONTACT = 4  # surface_follow.CONTACT (an impact on the neighbour)
POCKET = 16  # changes of plane in a row at the rest speed or less that end at rest (surface_follow)


@functools.cache
def make_triangle_follow(precision: str) -> SimpleNamespace:
    """`start_face`, `ridge` and `cross` (module docstring) of one precision."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    mc, sm, faces = make_mesh_contact(precision), make_surface_motion(precision), make_mesh_faces(precision)
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])
    ZERO = scalar(0.0)

    @wp.func
    def slack(surfaces: Surfaces, k: wp.int32, x: vec3, radius: scalar):
        """The rounding of heights at x (m) in mesh k's frame, as `mesh_contact.contact_normal`'s."""
        return scalar(FLOAT32_SLACK) * mc.scale(surfaces, k, x) + mc.state_rounding(x) + TOLERANCE * radius

    @wp.func
    def query(surfaces: Surfaces, k: wp.int32, x: vec3, grow: scalar):
        """The BVH's query of mesh k's triangles within `grow` (m) of x, the box grown by the
        float32 BVH's rounding of the world's coordinates."""
        mesh, low, high = mc.bounds(surfaces, k)
        grow = grow + scalar(FLOAT32_SLACK) * (mc.l1(low) + mc.l1(high) + mc.l1(x))
        return wp.mesh_query_aabb(mesh, mc.single(x - vec3(grow, grow, grow)), mc.single(x + vec3(grow, grow, grow)))

    @wp.func
    def exit_time(n: vec3, a: vec3, b: vec3, c: vec3, y: vec3, v: vec3):
        """How long (s) y moves along v (projected on the triangle's plane) before it leaves the
        triangle (a, b, c) of unit normal n: the least over its edges closing on y (1e30: none)."""
        along = v - wp.dot(v, n) * n
        least = scalar(1.0e30)
        for i in range(3):
            p = a
            q = b
            if i == 1:
                p = b
                q = c
            elif i == 2:
                p = c
                q = a
            rate = wp.dot(n, wp.cross(q - p, along))
            if rate < ZERO:
                least = wp.min(least, wp.max(wp.dot(n, wp.cross(q - p, y - p)), ZERO) / (-rate))
        return least

    @wp.func
    def next_face(surfaces: Surfaces, k: wp.int32, skip: wp.int32, y: vec3, v: vec3, grow: scalar):
        """Of mesh k's triangles other than `skip` over which the contact point y lies within `grow`
        of its plane, the one y moving along v stays on longest (`exit_time`): the one the path goes
        on into, not one it touches at an edge or a vertex behind it; -1 if none."""
        found = query(surfaces, k, y, grow)
        face = wp.int32(0)
        best = wp.int32(-1)
        longest = ZERO
        while wp.mesh_query_aabb_next(found, face):
            if face != skip:
                a, b, c = mc.vertices(surfaces, k, face)
                n = wp.cross(b - a, c - a)
                if wp.length(n) > ZERO:
                    n = wp.normalize(n)
                    if wp.abs(wp.dot(y - a, n)) <= grow and mc.inside(n, a, b, c, y):
                        stay = exit_time(n, a, b, c, y, v)
                        if best < 0 or stay > longest:
                            best = face
                            longest = stay
        return best

    @wp.func
    def start_face(surfaces: Surfaces, k: wp.int32, x: vec3, radius: scalar):
        """The triangle of mesh k a pellet touching it with centre x lies on: of those it is over
        within R (+ rounding) in front of, the one its centre is nearest (the deepest); -1: none."""
        grow = slack(surfaces, k, x, radius)
        low = -grow
        high = radius + grow
        found = query(surfaces, k, x, high)
        face = wp.int32(0)
        best = wp.int32(-1)
        least = ZERO
        while wp.mesh_query_aabb_next(found, face):
            a, b, c = mc.vertices(surfaces, k, face)
            n = wp.cross(b - a, c - a)
            if wp.length(n) > ZERO:
                n = wp.normalize(n)
                height = wp.dot(x - a, n)
                if height >= low and height <= high and mc.inside(n, a, b, c, x):
                    if best < 0 or height < least:
                        best = face
                        least = height
        return best

    @wp.func
    def rise_paid(v: vec3, x: vec3, x2: vec3, g: vec3):
        """v, less the kinetic energy the centre's rise from x to x2 against g takes (J/kg); 0 if it
        cannot pay it (the energy never rises)."""
        rise = -wp.dot(g, x2 - x)
        speed2 = wp.dot(v, v)
        if rise > ZERO:
            scale = ZERO
            if speed2 > scalar(2.0) * rise:
                scale = wp.sqrt(scalar(1.0) - scalar(2.0) * rise / speed2)
            return scale * v
        return v

    @wp.func
    def ridge(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, y: vec3, r: vec3, g: vec3, radius: scalar):
        """A pellet staying on mesh k with its centre x over no triangle, touching an edge or a
        corner at y (r: the unit radial from y to x), rolls off it to one side, as a sphere on a
        ridge (module docstring): (face, x', v', its normal) on the triangle through y it goes onto;
        face -1: none, gravity pulling it off every one (a border): it pivots to where r' is level
        (g.r' = 0) and flies from x' = y + R r' (normal r')."""
        grow = slack(surfaces, k, y, radius)
        found = query(surfaces, k, y, grow)
        face = wp.int32(0)
        on = wp.int32(-1)
        way = wp.int32(-1)  # the triangle its velocity pivots it towards fastest, at `speed` (m/s)
        down = wp.int32(-1)  # the one gravity pulls it towards most, with `pull` (m/s^2)
        speed = ZERO
        pull = ZERO
        n_way = vec3()
        d_down = vec3()
        n_down = vec3()
        while wp.mesh_query_aabb_next(found, face):
            a, b, c = mc.vertices(surfaces, k, face)
            n = wp.cross(b - a, c - a)
            if wp.length(n) > ZERO:
                n = wp.normalize(n)
                if wp.abs(wp.dot(y - a, n)) <= grow and mc.inside(n, a, b, c, y):
                    d = n - wp.dot(n, r) * r  # the way r turns towards n as the sphere pivots about y
                    if wp.length(d) <= TOLERANCE:
                        on = face
                    else:
                        d = wp.normalize(d)
                        if way < 0 or wp.dot(v, d) > speed:
                            way = face
                            speed = wp.dot(v, d)
                            n_way = n
                        if down < 0 or wp.dot(g, d) > pull:
                            down = face
                            pull = wp.dot(g, d)
                            d_down = d
                            n_down = n
        if on >= 0:
            return on, x, v, r
        if way >= 0 and speed > ZERO and scalar(0.5) * speed * speed >= -wp.dot(g, radius * (n_way - r)):
            x2 = y + radius * n_way  # it rolls over to where its velocity takes it
            return way, x2, rise_paid(sm.tangential(v, n_way), x, x2, g), n_way
        if down < 0 or pull < ZERO:  # gravity pulls it off every triangle (a border)
            level = sm.tangential(g, r)  # gravity turns r along it, to where g.r' = 0
            if wp.length(level) <= TOLERANCE * wp.length(g) or wp.dot(g, r) >= ZERO:
                return wp.int32(-1), x, v, r
            r2 = wp.normalize(wp.normalize(level) * (-wp.dot(g, r)) + r * wp.length(level))
            return wp.int32(-1), y + radius * r2, sm.tangential(v, r2), r2
        x2 = y + radius * n_down  # gravity rolls it down, its speed the other way lost
        v2 = v - wp.min(wp.dot(v, d_down), ZERO) * d_down
        return down, x2, rise_paid(sm.tangential(v2, n_down), x, x2, g), n_down

    @wp.func
    def cross(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        x: vec3,
        v: vec3,
        w: vec3,
        n: vec3,
        rolling: wp.int32,
        applied: vec3,
        physics: Physics,
        rest_speed: scalar,
    ):
        """Where the centre x (velocity v, spin w) leaves triangle `face` (normal n) of mesh k:
        (code, the neighbour, x', v', w'), code CHANGE (go on along the neighbour from x', v', w'),
        FLIGHT, CONTACT or REST (module docstring); `applied`: g + the air's forces per unit mass.
        A `rolling` pellet rolls on along the neighbour: w' = (w.n) n' + n' x v' / R."""
        radius = physics.radius
        y = x - radius * n  # the contact point, on the edge
        grow = slack(surfaces, k, y, radius)
        beyond = next_face(surfaces, k, face, y, v, grow)
        if beyond < 0:
            return wp.int32(FLIGHT), face, x, v, w
        height, _noise, n2 = faces.face_plane(surfaces, k, beyond, y)
        u = wp.dot(v, n2)
        load = sm.normal_load(n2, applied)
        if u < ZERO:
            if load <= ZERO or -u > sm.separation_speed(load, radius):
                return wp.int32(CONTACT), face, x, v, w
        elif sm.separates(u, load, radius) != 0:
            return wp.int32(FLIGHT), face, x, v, w
        x2 = y + (radius - height) * n2
        v2 = rise_paid(v - u * n2, x, x2, physics.gravity)
        if u < ZERO and wp.length(v2) <= rest_speed:  # pushed into a concave crease from both sides?
            if wp.dot(sm.tangential(applied, n), v) > ZERO and wp.dot(sm.tangential(applied, n2), v2) < ZERO:
                return wp.int32(REST), beyond, x2, vec3(), wp.dot(w, n) * n2
        w2 = w
        if rolling != 0:
            w2 = wp.dot(w, n) * n2 + wp.cross(n2, v2) / radius
        return wp.int32(CHANGE), beyond, x2, v2, w2

    return SimpleNamespace(start_face=start_face, ridge=ridge, cross=cross)
