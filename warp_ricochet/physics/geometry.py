"""The surfaces behind one interface: the only code that reads the `Surfaces` struct (SI units).

Solvers (the core's flight and impacts, the dense phase's events, kicks and leaps) ask these
`@wp.func`s about surface k, never its arrays, so that what a surface is (today an infinite
one-sided plane: a point p and a unit normal n towards the pellets) can change in one place:

- `count(surfaces)`: how many surfaces (loops over them are unrolled where `spec.static_planes`);
- `locate(surfaces, k, x) -> (height, noise, normal)`: the signed distance (m) of a point x from
  the surface along its normal (> 0 on the pellets' side; a sphere of radius R then has the gap
  height - R), the scale of that distance's rounding noise (m; a plane: sum_i (|x_i| + |p_i|) |n_i|),
  and the unit normal at the surface point nearest x;
- `gap(surfaces, k, x, radius) -> (height, gap, normal)`: `locate` with a sphere's gap height - R,
  snapped to 0 when within rounding of it (the touching band, below);
- `normal(surfaces, k, x) -> vec3`: that normal alone;
- `material(surfaces, k, x) -> Material`: restitution E, mu_s, mu_d and the ground's laws
  (`types.Material`) at the surface point nearest x (a plane: one material per surface);
- `step_gaps(surfaces, k, radius, h, x0, v0, a0, x1, v1, a1)`: a sphere's gap at both ends of an
  integration step of length h (s), with h and h^2 times its first and second time derivatives
  (the Hermite data the integrated flight searches for contacts, `physics.air_flight`);
- `contact_time(surfaces, k, ...)` and `next_contact(surfaces, ...)`: when the exact parabola of
  eq. (36) meets surface k, and the earliest of all surfaces (the rules of `physics.ballistic`).

Touching band: a gap within rounding noise of zero (|gap| <= ROUNDING eps (noise + R), noise as in
`locate`: subtracting x and p rounds at eps (|x_i| + |p_i|) per component) is taken as zero, so a
pellet resting on a tilted plane, or on one far from the origin, touches it rather than falling a
rounding error onto it or through it. `snap` False turns the band off in the parabola's search: the
dense phase in air, whose kicks move a pellet's reference state every few steps, would otherwise
meet a plane early wherever the pellet comes within the band of it (docs/air.md, section 3.2).

Meshes (`plates` MESHES, docs/geometry.md): surfaces of kind mesh (boxes too) and posts (cylinders)
answer `contact_time` and `normal` (`physics.mesh_contact` with `physics.edge_contact`'s convex edges and
corners, `physics.cylinder_contact`), `is_solid` and `clearance` (a lower bound on the distance to
them: the dense phase's air step and leaps); the motion along surfaces reads them through `face_gap`,
`on_face` and `face_reach` (a triangle, or a post's cap: `_faces`); `locate`, `gap`, `inside` and
`step_gaps` read their `point` and `normal` only; the air's search asks `physics.mesh_contact` and
`physics.cylinder_contact` itself.

Plates (`plates` True, docs/geometry.md): a surface of kind rectangle or disc is the part of its
plane around its point within half sides along axes u, v = n x u (`inside`: the pellet's centre
projected along n); a two-sided one turns n, the height and the normal towards the pellet's side
(`side`). The parabola meets a plate where the plane's quadratic gives the entering root and that
root's point is inside (`plate_time`); the integrated flight checks its step's crossing the same
way (`physics.air_flight`). Plane-only kernels compile none of it: they read no plate arrays.

A contact carries its normal: the flights' `to_contact` return (time, surface, normal, state)
(`physics.flight`). The host sees the same planes through `project` (the hazard map's grid).
Arithmetic is that of the code it replaced, operation for operation: results are bitwise those
before (tests/test_golden.py). The small queries are force-inlined, as the reads they replace were.
"""

import functools
from types import SimpleNamespace

import numpy as np
import warp as wp

from .ballistic import EPSILON, MAX_FLIGHT_TIME, NO_CONTACT, ROUNDING, make_ballistic
from .cylinder_contact import make_cylinder_contact
from .edge_contact import make_edge_contact
from .mesh_contact import FLOAT32_SLACK, make_mesh_contact, make_mesh_faces, make_triangle_basics
from .types import KINDS, types_for

MESHES = 2  # `plates` when meshes are compiled in too (spec.MESHES): all their kinds' code
# with MESHES, what the scene's solids do not need, left out of the kernels (spec.solids):
NO_POSTS = 4  # no post (cylinder)
SMALL = 8  # every mesh has at most mesh_contact.FEW_FACES triangles: no BVH query in its search
NO_EDGES = 16  # no mesh owns edges or corners (terrain only): no edge or corner contact
LEANING = 32  # a post leans from gravity in a run to rest: motion along its side (`physics.side_follow`)
FLAT = 64  # with SMALL and NO_POSTS: every mesh is flat, searched as its plane (`physics.flat_contact`)


def make_geometry(precision: str, planes=None, snap: bool = True, plates: bool = False) -> SimpleNamespace:
    """The geometry `@wp.func`s of one precision. `planes`: the number of surfaces when fixed at
    code generation (the search over them unrolled), else None; `snap`: the parabola's search takes
    a gap within the touching band as zero (module docstring); `plates`: surfaces may be plates
    (True), or plates and meshes (MESHES, 2: `physics.mesh_contact`; or'ed with NO_POSTS, SMALL and
    NO_EDGES to leave out what the scene does not need, FLAT where every mesh is flat, LEANING for
    what only leaning posts need).
    One cached set per value of the four, however they are passed."""
    return _make_geometry(precision, planes, bool(snap), int(plates))


@functools.cache
def _make_geometry(precision: str, planes, snap: bool, plates: int) -> SimpleNamespace:
    t = types_for(precision)
    scalar, vec3, Surfaces, Material = t.scalar, t.vec3, t.Surfaces, t.Material
    ballistic = make_ballistic(precision)
    entry_time, return_time, _position = ballistic.entry_time, ballistic.return_time, ballistic.position
    STATIC_PLANES, SNAP, PLATES, WITH_MESHES = planes, snap, plates > 0, plates >= MESHES
    RECTANGLE, MESH, solids = KINDS["rectangle"], KINDS["mesh"], _solids(precision, *solid_needs(plates))
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])
    LATEST = scalar(MAX_FLIGHT_TIME)

    @wp.func(inline=True)
    def count(surfaces: Surfaces):
        """The number of surfaces."""
        return surfaces.point.shape[0]

    @wp.func(inline=True)
    def side(surfaces: Surfaces, k: wp.int32, x: vec3):
        """-1 where x is behind a two-sided plate k (its normal then turns to face x), else 1."""
        s = scalar(1.0)
        if surfaces.two_sided[k] != 0 and wp.dot(x - surfaces.point[k], surfaces.normal[k]) < scalar(0.0):
            s = scalar(-1.0)
        return s

    @wp.func(inline=True)
    def is_plate(surfaces: Surfaces, k: wp.int32):
        """Whether surface k is a plate (not an infinite plane)."""
        return surfaces.kind[k] != 0

    @wp.func(inline=True)
    def reach(surfaces: Surfaces, k: wp.int32, x: vec3):
        """A distance (m) from x beyond which every point is off plate k: |x - p| + a/2 + b/2."""
        return wp.length(x - surfaces.point[k]) + surfaces.half_u[k] + surfaces.half_v[k]

    @wp.func
    def inside(surfaces: Surfaces, k: wp.int32, x: vec3):
        """Whether x projected along surface k's normal lies on it (a plane: always; a rectangle:
        |u.(x - p)| <= a/2 and |v.(x - p)| <= b/2; a disc: (u.d)^2 + (v.d)^2 <= r^2)."""
        kind = surfaces.kind[k]
        if kind == 0:
            return True
        d = x - surfaces.point[k]
        a = wp.dot(d, surfaces.axis_u[k])
        b = wp.dot(d, surfaces.axis_v[k])
        if kind == RECTANGLE:
            return wp.abs(a) <= surfaces.half_u[k] and wp.abs(b) <= surfaces.half_v[k]
        return a * a + b * b <= surfaces.half_u[k] * surfaces.half_u[k]

    @wp.func(inline=True)
    def normal(surfaces: Surfaces, k: wp.int32, x: vec3):
        """The unit normal (towards the pellets) of surface k at the point nearest x."""
        if wp.static(WITH_MESHES):
            if surfaces.kind[k] >= MESH:  # a mesh or a post
                return solids.normal(surfaces, k, x)
        if wp.static(PLATES):
            return side(surfaces, k, x) * surfaces.normal[k]
        return surfaces.normal[k]

    @wp.func(inline=True)
    def locate(surfaces: Surfaces, k: wp.int32, x: vec3):
        """(height, noise, normal): x's signed distance from surface k (m), its rounding scale (m)
        and the unit normal there. A plane: n.(x - p) and sum_i |x_i| |n_i| + sum_i |p_i| |n_i|
        (the second sum kept with the surfaces: `types.surfaces_of`); a plate: its plane's, n
        turned towards x when two-sided."""
        n = surfaces.normal[k]
        if wp.static(PLATES):
            n = side(surfaces, k, x) * n
        noise = wp.abs(x[0] * n[0]) + wp.abs(x[1] * n[1]) + wp.abs(x[2] * n[2]) + surfaces.point_noise[k]
        return wp.dot(x - surfaces.point[k], n), noise, n

    @wp.func(inline=True)
    def gap(surfaces: Surfaces, k: wp.int32, x: vec3, radius: scalar):
        """(height, gap, normal): `locate`'s height and normal, and a sphere's gap height - R,
        0 within the touching band |gap| <= ROUNDING eps (noise + R)."""
        height, noise, n = locate(surfaces, k, x)
        g = height - radius
        if wp.abs(g) <= TOLERANCE * (noise + radius):
            g = scalar(0.0)  # touching, up to rounding
        return height, g, n

    @wp.func(inline=True)
    def material(surfaces: Surfaces, k: wp.int32, x: vec3):
        """Surface k's material at the point nearest x: restitution, mu_s, mu_d and the ground's
        laws (`types.Material`; a plane: one material per surface)."""
        m = Material()
        m.restitution = surfaces.restitution[k]
        m.mu_s = surfaces.mu_s[k]
        m.mu_d = surfaces.mu_d[k]
        m.rolling_resistance = surfaces.rolling_resistance[k]
        m.ploughing = surfaces.ploughing[k]
        m.critical_angle = surfaces.critical_angle[k]
        m.critical_angle_rise = surfaces.critical_angle_rise[k]
        m.critical_speed = surfaces.critical_speed[k]
        m.roughness = surfaces.roughness[k]
        m.restitution_scatter = surfaces.restitution_scatter[k]
        m.friction_scatter = surfaces.friction_scatter[k]
        m.skip_loss = surfaces.skip_loss[k]
        m.liquid = surfaces.liquid[k]
        return m

    @wp.func(inline=True)
    def step_gaps(
        surfaces: Surfaces, k: wp.int32, radius: scalar, h: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3
    ):
        """A sphere's gap to surface k at a step's ends (states 0 and 1, h s apart) with h and h^2
        times its first and second derivatives: (g0, h g0', h^2 g0'', g1, h g1', h^2 g1''). A
        plane: g = n.x - (n.p + R), linear in x (a two-sided plate: n towards x0)."""
        n = surfaces.normal[k]
        if wp.static(PLATES):
            n = side(surfaces, k, x0) * n
        level = wp.dot(surfaces.point[k], n) + radius
        return (
            wp.dot(x0, n) - level,
            h * wp.dot(v0, n),
            h * h * wp.dot(a0, n),
            wp.dot(x1, n) - level,
            h * wp.dot(v1, n),
            h * h * wp.dot(a1, n),
        )

    @wp.func
    def plate_time(
        surfaces: Surfaces, k: wp.int32, position: vec3, velocity: vec3, gravity: vec3, radius: scalar, touching: wp.int32
    ):
        """`contact_time` of plate k: the plane's entering root (its quadratic's, at most one per
        face), kept if the centre is `inside` there. A pellet in front within R of the plane beside
        the plate comes back over it at the larger root; a two-sided plate is also met on its other
        face, after the pellet passed its plane beside it (the root of height = -R rising again)."""
        height, gap_snapped, n = gap(surfaces, k, position, radius)
        normal_speed = wp.dot(velocity, n)
        normal_gravity = wp.dot(gravity, n)
        if wp.abs(normal_gravity) <= TOLERANCE * (wp.abs(gravity[0]) + wp.abs(gravity[1]) + wp.abs(gravity[2])):
            normal_gravity = scalar(0.0)
        half = scalar(0.5) * normal_gravity
        t = scalar(NO_CONTACT)
        if k == touching:
            t = return_time(normal_speed, half)
        elif height >= scalar(0.0):
            g = height - radius
            if wp.static(SNAP):
                g = gap_snapped
            if g > scalar(0.0) or inside(surfaces, k, position):
                t = entry_time(g, normal_speed, half)
            elif normal_speed > scalar(0.0) and half < scalar(0.0):  # beside it, within R of its plane
                disc = normal_speed * normal_speed - scalar(4.0) * half * g
                if disc >= scalar(0.0):
                    t = -(normal_speed + wp.sqrt(disc)) / (scalar(2.0) * half)
        if t >= scalar(0.0):
            if not inside(surfaces, k, _position(position, velocity, gravity, t)):
                t = scalar(NO_CONTACT)
        if surfaces.two_sided[k] != 0 and k != touching and normal_speed < scalar(0.0) and half > scalar(0.0):
            disc = normal_speed * normal_speed - scalar(4.0) * half * (height + radius)
            if disc >= scalar(0.0):
                back = (wp.sqrt(disc) - normal_speed) / (scalar(2.0) * half)
                if (t < scalar(0.0) or back < t) and inside(surfaces, k, _position(position, velocity, gravity, back)):
                    t = back
        if t > LATEST:
            t = scalar(NO_CONTACT)
        return t

    @wp.func
    def contact_time(
        surfaces: Surfaces,
        k: wp.int32,
        position: vec3,  # m, the sphere's centre
        velocity: vec3,  # m/s
        gravity: vec3,  # m/s^2
        radius: scalar,  # m
        touching: wp.int32,  # the surface it is leaving, or -1
    ):
        """Time (s) until the parabola of eq. (36) meets surface k, or NO_CONTACT (also beyond
        MAX_FLIGHT_TIME). A plane's gap is the quadratic of `physics.ballistic`; one-sided."""
        if wp.static(WITH_MESHES):
            if surfaces.kind[k] >= MESH:  # a mesh or a post
                return solids.time(surfaces, k, position, velocity, gravity, radius)  # touching: not needed
        if wp.static(PLATES):
            if surfaces.kind[k] != 0:
                return plate_time(surfaces, k, position, velocity, gravity, radius, touching)
        height, gap_snapped, n = gap(surfaces, k, position, radius)
        normal_speed = wp.dot(velocity, n)
        normal_gravity = wp.dot(gravity, n)
        if wp.abs(normal_gravity) <= TOLERANCE * (wp.abs(gravity[0]) + wp.abs(gravity[1]) + wp.abs(gravity[2])):
            normal_gravity = scalar(0.0)  # gravity along the plane, up to rounding
        half_normal_gravity = scalar(0.5) * normal_gravity
        t = scalar(NO_CONTACT)
        if k == touching:
            t = return_time(normal_speed, half_normal_gravity)
        elif height >= scalar(0.0):  # one-sided: centre behind the plane never touches
            g = height - radius
            if wp.static(SNAP):
                g = gap_snapped  # the touching band
            t = entry_time(g, normal_speed, half_normal_gravity)
        if t > LATEST:
            t = scalar(NO_CONTACT)
        return t

    @wp.func
    def next_contact(surfaces: Surfaces, position: vec3, velocity: vec3, gravity: vec3, radius: scalar, touching: wp.int32):
        """(time, surface) of the parabola's next contact; surface -1 when none (time NO_CONTACT).
        Ties go to the lower index."""
        best_time = scalar(NO_CONTACT)
        best_plane = wp.int32(-1)
        if wp.static(STATIC_PLANES is None):
            for k in range(count(surfaces)):
                t = contact_time(surfaces, k, position, velocity, gravity, radius, touching)
                if t >= scalar(0.0) and (best_plane < 0 or t < best_time):
                    best_time = t
                    best_plane = wp.int32(k)
        else:
            for k in range(wp.static(STATIC_PLANES)):  # unrolled
                t = contact_time(surfaces, k, position, velocity, gravity, radius, touching)
                if t >= scalar(0.0) and (best_plane < 0 or t < best_time):
                    best_time = t
                    best_plane = wp.int32(k)
        return best_time, best_plane

    return SimpleNamespace(
        **_faces(precision, gap, inside, reach, WITH_MESHES, solid_needs(plates)[0]),
        side=side,
        inside=inside,
        is_plate=is_plate,
        is_solid=solids.is_solid,
        clearance=_clearance(precision, plates),
        reach=reach,
        count=count,
        normal=normal,
        contact_normal=_contact_normal(precision, normal, WITH_MESHES, *solid_needs(plates)[1:]),
        touching=make_edge_contact(precision, *solid_needs(plates)[1:]).touching,
        locate=locate,
        gap=gap,
        material=material,
        step_gaps=step_gaps,
        contact_time=contact_time,
        next_contact=next_contact,
    )


@functools.cache
def _clearance(precision: str, plates: int):
    """`clearance(surfaces, k, x)` of the kernels of `plates` (`make_geometry`)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    RECTANGLE, MESH, WITH_MESHES, solids = (
        KINDS["rectangle"],
        KINDS["mesh"],
        plates >= MESHES,
        _solids(precision, *solid_needs(plates)),
    )

    @wp.func
    def clearance(surfaces: Surfaces, k: wp.int32, x: vec3):
        """A lower bound (m) on the distance from x to surface k when it is not an infinite plane:
        a mesh's or a post's (`_solids`); a rectangle's or disc's exact distance (the offset from
        its plane beside the part of the projection that lies off it). A plane: its |height|."""
        if wp.static(WITH_MESHES):
            if surfaces.kind[k] >= MESH:
                return solids.clearance(surfaces, k, x)
        d = x - surfaces.point[k]
        off = wp.dot(d, surfaces.normal[k])
        kind = surfaces.kind[k]
        if kind == 0:
            return wp.abs(off)
        a = wp.dot(d, surfaces.axis_u[k])
        b = wp.dot(d, surfaces.axis_v[k])
        zero = scalar(0.0)
        if kind == RECTANGLE:
            out_a = wp.max(wp.abs(a) - surfaces.half_u[k], zero)
            out_b = wp.max(wp.abs(b) - surfaces.half_v[k], zero)
            return wp.sqrt(off * off + out_a * out_a + out_b * out_b)
        out = wp.max(wp.sqrt(a * a + b * b) - surfaces.half_u[k], zero)
        return wp.sqrt(off * off + out * out)

    return clearance


def has_posts(plates) -> bool:
    """Whether kernels of `plates` compile posts in (MESHES without NO_POSTS)."""
    return plates >= MESHES and not plates & NO_POSTS


def solid_needs(plates: int) -> tuple:
    """(posts, large meshes, edges, flat): the solids' code a kernel of `plates` compiles in (flat:
    only a flat mesh's search, `physics.flat_contact`)."""
    return not plates & NO_POSTS, not plates & SMALL, not plates & NO_EDGES, bool(plates & FLAT)


@functools.cache
def _solids(
    precision: str, with_posts: bool = True, large: bool = True, edges: bool = True, flat: bool = False
) -> SimpleNamespace:
    """`time(surfaces, k, x, v, g, R)`, `normal(surfaces, k, x)` and `clearance(surfaces, k, x)` of
    a mesh or a post k (`physics.mesh_contact`, `physics.cylinder_contact`), and `is_solid(surfaces, k)`;
    posts, large meshes' BVH queries, edges and a flat mesh's search compiled in only as asked
    (`solid_needs`)."""
    t = types_for(precision)
    Surfaces, vec3, scalar = t.Surfaces, t.vec3, t.scalar
    meshes, posts, mesh_normal = (
        make_edge_contact(precision, large, edges, flat),
        make_cylinder_contact(precision),
        make_mesh_contact(precision).mesh_normal,
    )
    basics, MESH = make_triangle_basics(precision), KINDS["mesh"]

    @wp.func(inline=True)
    def is_solid(surfaces: Surfaces, k: wp.int32):
        """Whether surface k is a mesh or a post."""
        return surfaces.kind[k] >= MESH

    @wp.func
    def solid_time(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, g: vec3, radius: scalar):
        """When the parabola of eq. (36) meets mesh or post k, or NO_CONTACT."""
        if wp.static(with_posts):
            if posts.is_post(surfaces, k):
                return posts.post_time(surfaces, k, x, v, g, radius)
        return meshes.mesh_time(surfaces, k, x, v, g, radius)

    @wp.func
    def solid_normal(surfaces: Surfaces, k: wp.int32, x: vec3):
        """The unit normal of mesh or post k at the point nearest x."""
        if wp.static(with_posts):
            if posts.is_post(surfaces, k):
                return posts.post_normal(surfaces, k, x)
        return mesh_normal(surfaces, k, x)

    @wp.func
    def solid_clearance(surfaces: Surfaces, k: wp.int32, x: vec3):
        """A lower bound (m) on the distance from x to mesh or post k: to the post's bounding box;
        to the mesh's point nearest x (the BVH's float32 query, evaluated on the kernel's vertices),
        less FLOAT32_SLACK of the coordinates' scale (the float32 triangles' rounding)."""
        zero = scalar(0.0)
        if wp.static(with_posts):
            if posts.is_post(surfaces, k):
                low, high = posts.post_box(surfaces, k)
                out = vec3(
                    wp.max(wp.max(low[0] - x[0], x[0] - high[0]), zero),
                    wp.max(wp.max(low[1] - x[1], x[1] - high[1]), zero),
                    wp.max(wp.max(low[2] - x[2], x[2] - high[2]), zero),
                )
                return wp.length(out)
        query = wp.mesh_query_point_no_sign(surfaces.mesh[k], basics.single(x), wp.float32(1.0e30))
        if not query.result:
            return zero
        a, b, c = basics.vertices(surfaces, k, query.face)
        u, v = scalar(query.u), scalar(query.v)
        nearest = u * a + v * b + (scalar(1.0) - u - v) * c  # (wp.mesh_eval_position's weights)
        scale = basics.l1(x) + basics.l1(surfaces.mesh_low[k]) + basics.l1(surfaces.mesh_high[k])
        return wp.max(wp.length(x - nearest) - scalar(FLOAT32_SLACK) * scale, zero)

    return SimpleNamespace(time=solid_time, normal=solid_normal, clearance=solid_clearance, is_solid=is_solid)


def _contact_normal(precision: str, normal, with_meshes: bool, large: bool = True, edges: bool = True, flat: bool = False):
    """`contact_normal(surfaces, k, x, v, radius)`: the unit normal of a contact with surface k at
    centre x, velocity v: `normal`'s; a mesh's: of the triangle touched there that v approaches
    most steeply (`flat`: the flat mesh's plane), or radial from an edge or corner it touches beside
    every triangle (`physics.edge_contact.contact_normal`)."""
    t = types_for(precision)
    Surfaces, vec3, scalar = t.Surfaces, t.vec3, t.scalar
    MESH, meshes = KINDS["mesh"], make_edge_contact(precision, large, edges, flat)

    @wp.func(inline=True)
    def contact_normal(surfaces: Surfaces, k: wp.int32, x: vec3, v: vec3, radius: scalar):
        """The unit normal of a contact with surface k at x, velocity v (`_contact_normal`)."""
        if wp.static(with_meshes):
            if surfaces.kind[k] == MESH:
                return meshes.contact_normal(surfaces, k, x, v, radius)
        return normal(surfaces, k, x)

    return contact_normal


def project(surface, x):
    """On the host, in float64: (foot, normal) of a scene's surface (a `scene.schema` plane) seen
    from the point x (m): the point of the surface below x along its normal, and the unit normal.
    A terrain is seen as its horizontal plane, through its `point` perpendicular to its up (`normal`,
    -g/|g|: the site grid a terrain's map lies on, docs/hazard.md section 5). A plate is refused (the
    hazard's ground is a plane or a terrain: `scene.parse` checks hazard.map_surface)."""
    if not (surface.is_plane or surface.kind == "terrain"):
        raise ValueError(f"project: surface {surface.name!r} is a {surface.kind}, not a plane")
    n = np.asarray(surface.normal, dtype=np.float64)
    return x - np.dot(x - np.asarray(surface.point), n) * n, n


def _faces(precision: str, gap, inside, reach, with_meshes: bool, with_posts: bool = True) -> dict:
    """`face_gap`, `on_face`, `face_reach`: `gap`, `inside`, `reach` of triangle `face` of mesh k
    (`physics.triangle_follow`), or of cap `face` (TOP_CAP, BOTTOM_CAP) of post k, a disc of its
    radius (`cylinder_contact.cap_plane`, `on_cap`; `reach` of a post is its caps'); face -1: of
    surface k itself."""
    t = types_for(precision)
    Surfaces, vec3, scalar = t.Surfaces, t.vec3, t.scalar
    meshes, WITH_MESHES = make_mesh_faces(precision), with_meshes
    WITH_POSTS, posts = with_meshes and with_posts, make_cylinder_contact(precision)
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])

    @wp.func(inline=True)
    def band(g: scalar, noise: scalar, radius: scalar):
        """A gap g (m) snapped to 0 within the touching band (`gap`)."""
        if wp.abs(g) <= TOLERANCE * (noise + radius):
            g = scalar(0.0)
        return g

    @wp.func(inline=True)
    def face_gap(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3, radius: scalar):
        """`gap` on triangle `face` of mesh k (its plane: `mesh_contact.face_plane`), on a post's cap
        (face < -1: `cylinder_contact.cap_plane`); face -1: `gap`."""
        if wp.static(WITH_MESHES):
            if face >= 0:
                height, noise, n = meshes.face_plane(surfaces, k, face, x)
                return height, band(height - radius, noise, radius), n
        if wp.static(WITH_POSTS):
            if face < -1:  # a post's cap
                height, noise, n = posts.cap_plane(surfaces, k, face, x)
                return height, band(height - radius, noise, radius), n
        return gap(surfaces, k, x, radius)

    @wp.func(inline=True)
    def on_face(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3):
        """`inside` triangle `face` of mesh k (`mesh_contact.on_face`); over a post's cap (face < -1:
        within the slack its flights meet the cap with, `cylinder_contact.slack`); face -1: `inside`
        surface k."""
        if wp.static(WITH_MESHES):
            if face >= 0:
                return meshes.on_face(surfaces, k, face, x)
        if wp.static(WITH_POSTS):
            if face < -1:
                return posts.on_cap(surfaces, k, x, posts.slack(surfaces, k, x))
        return inside(surfaces, k, x)

    @wp.func(inline=True)
    def face_reach(surfaces: Surfaces, k: wp.int32, face: wp.int32, x: vec3):
        """`reach` of triangle `face` of mesh k; face < 0: of plate k."""
        if wp.static(WITH_MESHES):
            if face >= 0:
                return meshes.face_reach(surfaces, k, face, x)
        return reach(surfaces, k, x)

    return {"face_gap": face_gap, "on_face": on_face, "face_reach": face_reach}
