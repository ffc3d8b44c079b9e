"""A pellet's motion along the surface it lies on, until it rests, lifts off, meets another surface
or spends its steps, as a `@wp.func` the core kernel calls (docs/ground.md 9).

`make_surface_follow(precision, planes, model, laws)` (the arguments of `physics.flight.make_flight`)
returns `follow(position, velocity, spin, k, surfaces, physics, mu_s, mu_d, rolling_resistance,
ploughing, rest_speed, max_steps) -> (position, velocity, spin, elapsed, path, end, steps, k_next)`.
The pellet touches surface k (gap 0; a normal speed or gap left by the caller is rounding and is
dropped); on a post, one of its caps, followed as a disc plate; from a vertical post's side it flies
on at once, along a leaning one's it moves by `physics.side_follow`.
It slides and rolls by the laws of `physics.surface_motion` (with the ploughing resistance b |v|^2
beside c N) until one of the end codes:

- REST: its speed fell to rest_speed where the slope cannot restart it (v = 0, spin along n kept;
  on a post's cap with its centre beyond the rim it falls off instead: FLIGHT, `rest_end`);
- FLIGHT: the net normal force pulls it away (the caller flies it with touching = k);
- CONTACT: it meets surface k_next (gap 0) while moving along k (the caller impacts it);
- FOREVER: in vacuum, a phase of constant acceleration that never ends (it moves on for ever from
  the state returned: a slope too steep to stop on);
- UNFINISHED: max_steps integration steps spent (the state where they ran out).

In vacuum the phases with constant accelerations (`surface_motion`'s closed forms, without
ploughing) and rolling on a level plane with ploughing (v' = -(5/7)(c g + b v^2): tan/atan) are
exact; the rest (a drive across the friction, sliding with ploughing) and everything in air is
integrated with Dormand-Prince 5(4) steps (`physics.integrate`) at the relative tolerance of the
phases along surfaces (`physics.surface_tolerance`, numerics.surface_tolerance): a phase along one line of the plane (a level
plane, or along a slope's fall line) over the distance around the closed form of v' = -(A + B v^2)
(`physics.surface_line`, few steps; exact in vacuum), the others in 3-D as follows. Events: the slip or the speed reaching its
target (slide to roll; rest or stop) by steps aimed at it (never across: the friction's direction
jumps there) and ended to first order within BAND x the tolerance of its scale (at least STOP);
lift-off (N = 0) and loss of grip (|F| = mu_s N) by Illinois on the step's dense output; other
surfaces by the flight's search
(`air_flight.make_plane_search`, at most limits.MAX_PLANES_IN_AIR surfaces in integrated phases).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .air_flight import make_plane_search
from .ballistic import EPSILON, ROUNDING
from .cylinder_contact import make_cylinder_contact
from .geometry import LEANING, MESHES, has_posts, make_geometry
from .integrate import make_dense_output
from .line_ahead import make_line_ahead
from .line_log import LOG_STEPS
from .mesh_contact import make_mesh_lookup
from .plate_edge import make_plate_edge
from .side_follow import make_side_follow
from .surface_line import HANDOVER, make_line_integrator
from .surface_motion import FLIGHT, NEVER, REST, ROLLING, SLIDING, make_surface_motion
from .surface_rates import make_surface_rates
from .triangle_follow import CHANGE, POCKET, make_triangle_follow
from .types import types_for

CONTACT, FOREVER, UNFINISHED = 4, 5, 6  # end codes beside surface_motion's FLIGHT (0) and REST (3)
EDGE = 7  # a phase's end over a plate's edge (`plate_edge`): `follow` ends it in FLIGHT
ENDS = {FLIGHT: "flight", REST: "rest", CONTACT: "contact", FOREVER: "forever", UNFINISHED: "unfinished"}
MAX_FOLLOW_PHASES = 32  # slide, roll, grip lost, ...: more phases than this end UNFINISHED
# a slip or a speed within STOP x its scale of its target has reached it (the rest to first order);
# integrated phases widen the band to BAND x the tolerance, below the integrator's own error
STOP = {p: max(1e-9, ROUNDING * e) for p, e in EPSILON.items()}
BAND = 0.1


@functools.cache
def make_surface_closed_phases(precision: str, planes=None, plates: bool = False) -> SimpleNamespace:
    """The phases in vacuum in closed form, with the first other surface on their way: constant
    accelerations (`surface_motion`) and rolling on a level plane with ploughing."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    sm, geo, edge = (
        make_surface_motion(precision),
        make_geometry(precision, planes, True, plates),
        make_plate_edge(precision, plates),
    )
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])
    PLATES, WITH_MESHES, meshes = plates, plates >= MESHES, make_mesh_lookup(precision)
    WITH_POSTS, posts = has_posts(plates), make_cylinder_contact(precision)

    surface_count = make_line_ahead(precision, planes, plates).surface_count

    @wp.func
    def contact_within(position: vec3, velocity: vec3, acceleration: vec3, k: wp.int32, surfaces: Surfaces, physics: Physics):
        """(time, surface) of the first surface other than k that the path x + v t + a t^2 / 2
        meets (the parabola's quadratic, `geometry.contact_time`), or (NEVER, -1)."""
        best = scalar(NEVER)
        best_k = wp.int32(-1)
        for j in range(surface_count(surfaces)):
            if j != k:
                tj = geo.contact_time(surfaces, j, position, velocity, acceleration, physics.radius, wp.int32(-1))
                if tj >= ZERO and (best_k < 0 or tj < best):
                    best = tj
                    best_k = wp.int32(j)
        return best, best_k

    @wp.func
    def log1p(x: scalar):
        """log(1 + x) for x >= 0, accurate for small x (Kahan)."""
        w = ONE + x
        if w == ONE:
            return x
        return wp.log(w) * x / (w - ONE)

    @wp.func
    def plough_roll(
        velocity: vec3,
        k: wp.int32,
        face: wp.int32,
        position: vec3,
        surfaces: Surfaces,
        physics: Physics,
        rolling_resistance: scalar,
        ploughing: scalar,
        goal: scalar,
    ):
        """Rolling on a level plane in vacuum with ploughing: v' = -(A + B v^2), A = c g/(1 + k),
        B = b/(1 + k), along a fixed line: A + B v^2 = (A + B v0^2) exp(-2 B s) and t(v) =
        atan(x)/sqrt(A B), x = (v0 - v) sqrt(A B)/(A + B v0 v) (t = (v0 - v)/(B v0 v) at A = 0).
        To the speed `goal`, or to the first other surface on the line: (duration, distance, speed
        then, surface met or -1; -EDGE: over plate k's edge, or triangle `face`'s of mesh k)."""
        v0 = wp.length(velocity)
        direction = sm.unit(velocity)
        share = ONE / (ONE + physics.inertia_factor)
        a = share * rolling_resistance * wp.length(physics.gravity)
        b = share * ploughing
        distance = scalar(0.5) / b * log1p(b * (v0 * v0 - goal * goal) / (a + b * goal * goal))
        if goal <= ZERO and a <= ZERO:
            distance = scalar(NEVER)
        met = wp.int32(-1)
        for j in range(surface_count(surfaces)):
            if j != k:
                height, gap, n = geo.gap(surfaces, j, position, physics.radius)
                closing = -wp.dot(direction, n)
                solid = False
                if wp.static(WITH_MESHES):  # a mesh or a post: its contact along the line (no gravity)
                    solid = meshes.is_mesh(surfaces, j)
                    if wp.static(WITH_POSTS):
                        solid = solid or posts.is_post(surfaces, j)
                    if solid:
                        gap = geo.contact_time(surfaces, j, position, direction, vec3(), physics.radius, wp.int32(-1))
                        height = gap
                        closing = ONE
                if height >= ZERO and closing > ZERO:
                    s = wp.max(gap, ZERO) / closing
                    if distance < ZERO or s < distance:
                        if wp.static(PLATES):  # a plate is met only where the line crosses it
                            if solid or geo.inside(surfaces, j, position + s * direction):
                                distance = s
                                met = wp.int32(j)
                        else:
                            distance = s
                            met = wp.int32(j)
        if wp.static(PLATES):
            if geo.is_plate(surfaces, k):  # over its edge first?
                off = edge.leave_time(surfaces, k, face, position, direction, vec3(), distance)
                if off >= ZERO and (distance < ZERO or off < distance):
                    distance = off
                    met = wp.int32(-EDGE)
        if distance < ZERO:
            return scalar(NEVER), scalar(NEVER), ZERO, met
        v = goal
        if wp.static(PLATES):
            if met != -1:  # the speed where it meets the surface or leaves the plate
                v = wp.sqrt(wp.max(((a + b * v0 * v0) * wp.exp(scalar(-2.0) * b * distance) - a) / b, ZERO))
        elif met >= 0:  # the speed where it meets the surface
            v = wp.sqrt(wp.max(((a + b * v0 * v0) * wp.exp(scalar(-2.0) * b * distance) - a) / b, ZERO))
        root = wp.sqrt(a * b)
        x = (v0 - v) * root / (a + b * v0 * v)
        ratio = ONE  # atan(x) / x
        if x > TOLERANCE:
            ratio = wp.atan(x) / x
        return (v0 - v) / (a + b * v0 * v) * ratio, distance, v, met

    @wp.func
    def rest_state(position: vec3, spin: vec3, normal: vec3, elapsed: scalar, path: scalar, steps: wp.int32, k: wp.int32):
        """The end at rest: no velocity, the spin's part along n kept (docs/ground.md 4)."""
        return position, vec3(), wp.dot(spin, normal) * normal, elapsed, path, wp.int32(REST), steps, k

    @wp.func
    def rest_end(
        surfaces: Surfaces,
        k: wp.int32,
        face: wp.int32,
        x: vec3,
        v: vec3,
        spin: vec3,
        n: vec3,
        elapsed: scalar,
        path: scalar,
        steps: wp.int32,
    ):
        """`rest_state` at x, but a pellet stopped on a post's cap (face < -1) with its centre beyond
        the rim, within the slack, flies on from just past it (`cylinder_contact.off_rim`)."""
        if wp.static(WITH_POSTS):
            if face < -1:
                beyond, y, w = posts.off_rim(surfaces, k, x, v)
                if beyond:
                    return y, w, spin, elapsed, path, wp.int32(FLIGHT), steps, k
        return rest_state(x, spin, n, elapsed, path, steps, k)

    @wp.func
    def constant_phase(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        k: wp.int32,
        face: wp.int32,
        normal: vec3,
        mode: wp.int32,
        surfaces: Surfaces,
        physics: Physics,
        mu_d: scalar,
        rolling_resistance: scalar,
        rest_speed: scalar,
    ):
        """A vacuum phase without ploughing by `surface_motion`'s closed forms: (x, v, w, duration,
        path, outcome, k_next), outcome 0: done, at its end (slip 0, or stopped: 1 at rest), CONTACT,
        FOREVER, EDGE (plate k's, or triangle `face`'s of mesh k); -1: no closed form (the state unchanged)."""
        g = physics.gravity
        radius, inertia = physics.radius, physics.inertia_factor
        duration = ZERO
        exact = ONE
        at_rest = wp.int32(0)
        acceleration = vec3()
        spin_rate = vec3()
        zero = vec3()
        if mode == SLIDING:
            duration, exact = sm.slide_end(velocity, spin, normal, g, radius, inertia, mu_d)
            acceleration, spin_rate = sm.sliding_rates(velocity, spin, normal, g, zero, radius, inertia, mu_d, ZERO)
        else:
            duration, at_rest, exact = sm.roll_end(velocity, normal, g, inertia, rolling_resistance, rest_speed)
            acceleration, spin_rate, _f = sm.rolling_rates(velocity, normal, g, zero, radius, inertia, rolling_resistance, ZERO)
        if exact < ONE:
            return position, velocity, spin, ZERO, ZERO, wp.int32(-1), k
        t_c, k_c = contact_within(position, velocity, acceleration, k, surfaces, physics)
        outcome = wp.int32(0)
        if wp.static(PLATES):
            if geo.is_plate(surfaces, k):  # over its edge first? (the end of the phase, or its contact)
                end = duration
                if k_c >= 0 and (duration < ZERO or t_c <= duration):
                    end = t_c
                off = edge.leave_time(surfaces, k, face, position, velocity, acceleration, end)
                if off >= ZERO and (end < ZERO or off < end):
                    x = position + velocity * off + (HALF * off * off) * acceleration
                    path = sm.arc_length(velocity, acceleration, off)
                    return x, velocity + acceleration * off, spin + spin_rate * off, off, path, wp.int32(EDGE), k
        if k_c >= 0 and (duration < ZERO or t_c <= duration):
            duration = t_c
            outcome = wp.int32(CONTACT)
        elif duration < ZERO:
            return position, velocity, spin, ZERO, ZERO, wp.int32(FOREVER), k
        elif mode == ROLLING:
            outcome = at_rest
        path = sm.arc_length(velocity, acceleration, duration)
        position = position + velocity * duration + (HALF * duration * duration) * acceleration
        velocity = velocity + acceleration * duration
        spin = spin + spin_rate * duration
        return position, velocity, spin, duration, path, outcome, k_c

    return SimpleNamespace(
        surface_count=surface_count,
        contact_within=contact_within,
        plough_roll=plough_roll,
        rest_state=rest_state,
        rest_end=rest_end,
        constant_phase=constant_phase,
    )


@functools.cache
def make_surface_integrator(
    precision: str, planes=None, model: str = "ballistic", laws=None, watch: tuple = (0, 0, False), plates: bool = False
) -> SimpleNamespace:
    """`integrate_phase`: one sliding or rolling phase integrated to its end (module docstring),
    each accepted step given to `tallies.path`'s watch of `watch` = (thresholds, places, map)."""
    from ..tallies.path_replay import watch_for  # (tallies imports physics: not at the top)

    watcher = watch_for(precision, *watch)
    Track, Tally = watcher.Track, watcher.Tally
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    sm, dense = make_surface_motion(precision), make_dense_output(precision)
    geo, search = make_geometry(precision, planes, True, plates), make_plane_search(precision, planes, plates, out_of_line=True)
    r = make_surface_rates(precision, model, laws)
    Contact, rates, stages, margin, margin_root = r.Contact, r.rates, r.stages, r.margin, r.margin_root
    target, error_norm, simpson = r.target, r.error_norm, r.simpson
    surface_count = make_surface_closed_phases(precision, planes, plates).surface_count
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    PLATES, edge = plates, make_plate_edge(precision, plates)
    WITH_MESHES, meshes = plates >= MESHES, make_mesh_lookup(precision)
    WITH_POSTS, posts = has_posts(plates), make_cylinder_contact(precision)
    STOP_FRACTION = scalar(STOP[precision])

    @wp.func
    def watch_start(position: vec3, velocity: vec3, k: wp.int32, surfaces: Surfaces, physics: Physics):
        """(watched, waiting, met now or -1) of the surfaces other than k, as the flight's start:
        touching one while closing on it meets it now; touching one while not, waits for the turn."""
        watched = wp.int32(0)
        waiting = wp.int32(0)
        now = wp.int32(-1)
        for j in range(surface_count(surfaces)):
            if j != k:
                height, gap, n = geo.gap(surfaces, j, position, physics.radius)
                if wp.static(PLATES):  # beside a plate, within R of its plane, or a mesh: watched
                    if gap <= ZERO and not geo.inside(surfaces, j, position):
                        gap = scalar(1.0)
                if wp.static(WITH_MESHES):
                    solid = meshes.is_mesh(surfaces, j)
                    if wp.static(WITH_POSTS):
                        solid = solid or posts.is_post(surfaces, j)
                    if solid:  # watched: the search applies its rules
                        height = scalar(1.0)
                        gap = scalar(1.0)
                if height >= ZERO:
                    if gap > ZERO:
                        watched = watched | (wp.int32(1) << j)
                    elif wp.dot(velocity, n) < ZERO:
                        if now < 0:
                            now = j
                    else:
                        waiting = waiting | (wp.int32(1) << j)
        return watched, waiting, now

    @wp.func
    def integrate_phase(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        k: wp.int32,
        face: wp.int32,
        contact: Contact,
        goal: scalar,
        surfaces: Surfaces,
        physics: Physics,
        mu_s: scalar,
        steps_left: wp.int32,
        track: Track,
        tally: Tally,
    ):
        """Integrate one sliding or rolling phase (`contact.rolling`) until its quantity (`target`)
        reaches `goal`, `margin` reaches 0, or another surface is met. Returns (x, v, w, elapsed,
        path, event, k_next, steps, track); event 0: the target reached, 1: the margin, CONTACT, EDGE
        (over plate k's edge, or triangle `face`'s of mesh k), or UNFINISHED (steps_left spent)."""
        radius = physics.radius
        floor = wp.sqrt(wp.length(physics.gravity) * radius) + scalar(1e-6)
        tolerance = physics.surface_tolerance
        band = wp.max(STOP_FRACTION, scalar(BAND) * tolerance)
        watched, waiting, now = watch_start(position, velocity, k, surfaces, physics)
        if now >= 0:
            return position, velocity, spin, ZERO, ZERO, wp.int32(CONTACT), now, wp.int32(0), track
        acceleration, spin_rate = rates(velocity, spin, physics, contact)
        scale = wp.length(velocity) + radius * wp.length(spin) + floor
        h = scalar(0.1) * wp.pow(tolerance, scalar(0.2)) * scale / (wp.length(acceleration) + floor / scalar(1e3))
        elapsed = ZERO
        path = ZERO
        steps = wp.int32(0)
        growth = scalar(5.0)  # the step's largest growth: 1 after a rejection (Hairer & Wanner's facmax)
        while steps < steps_left:
            q, rate, direction = target(velocity, spin, acceleration, spin_rate, contact, radius, goal)
            if rate < ZERO:
                if q <= band * scale:  # the rest of the way to first order
                    dt = q / (-rate)
                    moved = velocity * dt
                    track = watcher.segment(
                        track,
                        tally,
                        position,
                        moved,
                        acceleration * (dt * dt),
                        position + moved,
                        moved + acceleration * (dt * dt),
                        acceleration * (dt * dt),
                        dt,
                        ONE,
                    )
                    position = position + moved
                    path += wp.length(velocity) * dt
                    velocity = velocity + acceleration * dt
                    spin = spin + spin_rate * dt
                    return position, velocity, spin, elapsed + dt, path, wp.int32(0), k, steps, track
                h = wp.min(h, (q - HALF * band * scale) / (-rate))  # into the band's middle
            x1, v1, w1, a1, d1, ex, ev, ew = stages(position, velocity, spin, acceleration, spin_rate, h, physics, contact)
            steps += 1
            error = error_norm(position, velocity, spin, x1, v1, w1, ex, ev, ew, tolerance, floor, radius)
            if error > ONE:
                h = h * wp.clamp(scalar(0.9) * wp.pow(error, scalar(-0.2)), scalar(0.2), ONE)
                growth = ONE
                continue
            q1, _rate1, _d1 = target(v1, w1, a1, d1, contact, radius, goal)
            crossed = q1 < ZERO
            if contact.rolling == 0 or goal <= ZERO:  # the slip or the velocity reversed
                after = sm.slip_velocity(v1, w1, contact.normal, radius)
                if contact.rolling != 0:
                    after = v1
                crossed = wp.dot(after, direction) < ZERO and q > ZERO
            if crossed:  # stepped past the switch, where the friction jumps: aim short of it
                h = HALF * h
                growth = ONE
                continue
            theta = scalar(2.0)
            event = wp.int32(-1)
            f1 = margin(v1, w1, physics, contact, mu_s)
            if f1 <= ZERO:
                theta = margin_root(
                    h, position, x1, velocity, acceleration, spin, spin_rate, v1, a1, w1, d1, f1, physics, contact, mu_s
                )
                event = wp.int32(1)
            theta_c, k_c, watched, waiting = search.search(
                h, position, velocity, acceleration, x1, v1, a1, watched, waiting, surfaces, physics
            )
            if k_c >= 0 and theta_c <= theta:
                theta = theta_c
                event = wp.int32(CONTACT)
            if wp.static(PLATES):
                if geo.is_plate(surfaces, k):  # over its edge first?
                    off = edge.leave_theta(
                        surfaces, k, face, position, h * velocity, h * h * acceleration, x1, h * v1, h * h * a1
                    )
                    if off <= ONE and off <= theta:  # (2: the step ends on it)
                        theta = off
                        event = wp.int32(EDGE)
            end = ONE
            if event >= 0:
                end = theta
            track = watcher.segment(track, tally, position, h * velocity, h * h * acceleration, x1, h * v1, h * h * a1, h, end)
            if event >= 0:
                x, slope = dense.hermite_vec(theta, position, h * velocity, h * h * acceleration, x1, h * v1, h * h * a1)
                w = dense.cubic_vec(theta, spin, h * spin_rate, w1, h * d1)
                path += simpson(h, theta, position, velocity, acceleration, x1, v1, a1)
                k_next = k
                if event == CONTACT:
                    k_next = k_c
                return x, slope / h, w, elapsed + theta * h, path, event, k_next, steps, track
            path += simpson(h, ONE, position, velocity, acceleration, x1, v1, a1)
            elapsed += h
            position = x1
            velocity = v1
            spin = w1
            acceleration = a1
            spin_rate = d1
            h = h * wp.clamp(scalar(0.9) * wp.pow(wp.max(error, scalar(1e-10)), scalar(-0.2)), scalar(0.2), growth)
            growth = scalar(5.0)
        return position, velocity, spin, elapsed, path, wp.int32(UNFINISHED), k, steps, track

    return SimpleNamespace(integrate_phase=integrate_phase, watch_start=watch_start)


@functools.cache
def make_surface_follow(
    precision: str,
    planes=None,
    model: str = "ballistic",
    laws=None,
    watch: tuple = (0, 0, False),
    plates: bool = False,
    rough: bool = True,
    log_steps: int = LOG_STEPS,
) -> SimpleNamespace:
    """`follow` (module docstring) for one precision, number of planes (None: read at run time) and
    flight model ("ballistic": vacuum; "air" with `laws` = (drag, lift, spin_decay) of `physics.air`);
    the path is watched by `tallies.path`'s watch of `watch` = (thresholds, places, map); not
    `rough` (no rough ground), only straight phases go over the distance (`surface_line`), their
    steps watched `log_steps` at a time (`line_log`)."""
    from ..tallies.path_replay import watch_for  # (tallies imports physics: not at the top)

    watcher = watch_for(precision, *watch)
    Track, Tally = watcher.Track, watcher.Tally
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    AIR = model == "air"
    sm, geo = make_surface_motion(precision), make_geometry(precision, planes, True, plates)
    r = make_surface_rates(precision, model, laws)
    Contact, applied_at, lifts = r.Contact, r.applied_at, r.lifts
    closed = make_surface_closed_phases(precision, planes, plates)
    plough_roll, rest_end, constant_phase = closed.plough_roll, closed.rest_end, closed.constant_phase
    integrator = make_surface_integrator(precision, planes, model, laws, watch, plates)
    integrate_phase = integrator.integrate_phase
    PLATES = plates
    WITH_MESHES, meshes, tri = plates >= MESHES, make_mesh_lookup(precision), make_triangle_follow(precision)
    WITH_POSTS, posts = has_posts(plates), make_cylinder_contact(precision)
    WITH_SIDES = WITH_POSTS and bool(plates & LEANING)  # a leaning post's side followed (else flown from)
    sides = make_side_follow(precision, planes, model, laws, watch, plates, integrator.watch_start) if WITH_SIDES else None
    lines = make_line_integrator(precision, planes, model, laws, watch, rough=rough, plates=plates, log_steps=log_steps)
    line_of, integrate_line = lines.line_of, lines.integrate_line
    ZERO, ONE = scalar(0.0), scalar(1.0)

    @wp.func
    def follow(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        k: wp.int32,
        surfaces: Surfaces,
        physics: Physics,
        mu_s: scalar,
        mu_d: scalar,
        rolling_resistance: scalar,
        ploughing: scalar,
        rest_speed: scalar,
        max_steps: wp.int32,
        track: Track,
        tally: Tally,
    ):
        """Follow the pellet along surface k from gap 0 (module docstring): (position, velocity,
        spin, elapsed s, path length m, end code, integration steps, k_next: the surface met at
        CONTACT, else k), the watch's track and the normal of the surface (triangle) it ended on."""
        radius, inertia = physics.radius, physics.inertia_factor
        g = physics.gravity
        elapsed = ZERO
        path = ZERO
        steps = wp.int32(0)
        forced = wp.int32(-1)  # the mode a phase must take after a loss of grip
        face = wp.int32(-1)  # on a mesh: the triangle it moves along (physics.triangle_follow)
        slow = wp.int32(0)  # crossings in a row at the rest speed or less
        n = vec3()
        if wp.static(WITH_MESHES):
            if meshes.is_mesh(surfaces, k):
                face = tri.start_face(surfaces, k, position, radius)
                if face < 0:  # beside every triangle: on an edge or a corner it rolls off to one side
                    n = geo.normal(surfaces, k, position)
                    gap, radial, reach = geo.touching(surfaces, k, position, radius)
                    if gap < reach:
                        y = position - gap * radial
                        face, position, velocity, n = tri.ridge(surfaces, k, position, velocity, y, radial, g, radius)
                    if face < 0:  # none: it flies on
                        return position, velocity, spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
                    steps += 1  # (a change of plane's cost)
        if wp.static(WITH_POSTS):
            if posts.is_post(surfaces, k):
                face = posts.cap_face(surfaces, k, position)  # a cap: as a disc plate
                if face == -1:  # the side: along it if the post leans, else it flies on (docs/geometry.md)
                    n = geo.normal(surfaces, k, position)
                    if wp.static(WITH_SIDES):
                        if sides.leans(surfaces, k, g):
                            xs, vs, ws, es, ps, ends, taken, ks, track, n = sides.follow_side(
                                position, velocity, spin, k, surfaces, physics, mu_s, mu_d, rolling_resistance, ploughing,
                                rest_speed, max_steps, track, tally,
                            )  # fmt: skip
                            return xs, vs, ws, es, ps, ends, taken, ks, track, n
                    return position, velocity, spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
        phase = wp.int32(0)
        while phase < MAX_FOLLOW_PHASES:
            phase += 1
            height, _gap, n = geo.face_gap(surfaces, k, face, position, radius)
            position = position - (height - radius) * n  # on the plane, and moving along it
            velocity = sm.tangential(velocity, n)
            if wp.static(PLATES):
                if not geo.on_face(surfaces, k, face, position):  # off a plate's edge: it flies on
                    return position, velocity, spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
            applied, alpha = applied_at(velocity, spin, physics)
            mode = sm.surface_mode(
                velocity, spin, n, applied, alpha, g, radius, inertia, mu_s, rolling_resistance, ploughing, rest_speed
            )
            if forced >= 0 and mode == ROLLING:
                mode = forced
            forced = wp.int32(-1)
            if mode == REST:
                rx, rv, rw, re, rp, rc, rs, rk = rest_end(surfaces, k, face, position, velocity, spin, n, elapsed, path, steps)
                return rx, rv, rw, re, rp, rc, rs, rk, track, n
            if mode == FLIGHT:
                return position, velocity, spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
            holds = sm.held(n, g, rolling_resistance)
            goal = ZERO
            if mode == ROLLING and holds:
                goal = rest_speed
            outcome = wp.int32(-1)
            k_c = wp.int32(-1)
            if wp.static(not AIR):
                if ploughing <= ZERO:
                    start_x = position
                    start_v = velocity
                    position, velocity, spin, dt, dp, outcome, k_c = constant_phase(
                        position, velocity, spin, k, face, n, mode, surfaces, physics, mu_d, rolling_resistance, rest_speed
                    )
                    if dt > ZERO:  # constant acceleration: the Hermite quintic is the path itself
                        bend = (velocity - start_v) * dt  # h^2 a
                        track = watcher.segment(track, tally, start_x, start_v * dt, bend, position, velocity * dt, bend, dt, ONE)
                    elapsed += dt
                    path += dp
                elif mode == ROLLING and sm.across(g, n, wp.length(g)) == 0:  # level: g along n
                    dt, ds, speed, k_c = plough_roll(
                        velocity, k, face, position, surfaces, physics, rolling_resistance, ploughing, goal
                    )
                    if dt < ZERO:
                        return position, velocity, spin, elapsed, path, wp.int32(FOREVER), steps, k, track, n
                    direction = sm.unit(velocity)
                    share = ONE / (ONE + inertia)
                    track = watcher.line(
                        track,
                        tally,
                        position,
                        direction,
                        ds,
                        wp.length(velocity),
                        share * rolling_resistance * wp.length(g),
                        share * ploughing,
                    )
                    position = position + ds * direction
                    velocity = speed * direction
                    spin = wp.dot(spin, n) * n + wp.cross(n, velocity) * (ONE / radius)
                    elapsed += dt
                    path += ds
                    outcome = wp.int32(0)
                    if k_c >= 0:
                        outcome = wp.int32(CONTACT)
                    elif holds:
                        outcome = wp.int32(1)
            if outcome < 0:  # integrate the phase
                contact = Contact()
                contact.normal = n
                contact.mu_d = mu_d
                contact.rolling_resistance = rolling_resistance
                contact.ploughing = ploughing
                contact.rolling = wp.int32(0)
                if mode == ROLLING:
                    contact.rolling = wp.int32(1)
                tolerance = physics.surface_tolerance
                event = wp.int32(HANDOVER)
                on_plane = True  # a plate's edges and a mesh's are met by the phase integrator only
                if wp.static(PLATES):
                    on_plane = face < 0 and not geo.is_plate(surfaces, k)
                if on_plane:
                    on_line, line = line_of(
                        velocity, spin, n, contact.rolling, physics, mu_d, rolling_resistance, ploughing, tolerance
                    )
                    if on_line != 0:  # along one line of the plane: over the distance (surface_line)
                        position, velocity, spin, dt, dp, event, k_c, taken, track = integrate_line(
                            position,
                            velocity,
                            spin,
                            k,
                            line,
                            goal,
                            surfaces,
                            physics,
                            mu_s,
                            max_steps - steps,
                            tolerance,
                            track,
                            tally,
                        )
                        elapsed += dt
                        path += dp
                        steps += taken
                if event == HANDOVER:
                    position, velocity, spin, dt, dp, event, k_c, taken, track = integrate_phase(
                        position, velocity, spin, k, face, contact, goal, surfaces, physics, mu_s, max_steps - steps, track, tally
                    )
                    elapsed += dt
                    path += dp
                    steps += taken
                if event == UNFINISHED:
                    return position, velocity, spin, elapsed, path, wp.int32(UNFINISHED), steps, k, track, n
                outcome = event
                if event == 1:  # lift-off, or rolling lost its grip
                    if lifts(velocity, spin, physics, contact, mu_s) != 0:
                        return position, sm.tangential(velocity, n), spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
                    forced = wp.int32(SLIDING)
                    outcome = wp.int32(-1)
                elif event == 0 and mode == ROLLING and holds and rest_speed > ZERO:
                    outcome = wp.int32(1)
            if outcome == CONTACT:
                return position, velocity, spin, elapsed, path, wp.int32(CONTACT), steps, k_c, track, n
            if wp.static(PLATES):
                if outcome == EDGE or k_c == -EDGE:  # over a plate's edge: it flies on from there
                    ended = wp.int32(FLIGHT)
                    if wp.static(WITH_MESHES):
                        if face >= 0:  # over a triangle's: on along its neighbour, or off (triangle_follow)
                            pushed, _alpha = applied_at(velocity, spin, physics)
                            ended, face, position, velocity, spin = tri.cross(
                                surfaces,
                                k,
                                face,
                                position,
                                velocity,
                                spin,
                                n,
                                wp.int32(mode == ROLLING),
                                pushed,
                                physics,
                                rest_speed,
                            )
                    if ended == CHANGE and wp.length(velocity) <= rest_speed:  # a slow crossing
                        slow += 1
                        if slow >= POCKET:  # in a pocket of triangles it cannot climb out of: at rest
                            ended = wp.int32(REST)
                    elif ended == CHANGE:
                        slow = wp.int32(0)
                    if ended != FLIGHT:  # (a crossing is no phase: its cost is a step of the budget)
                        steps += 1
                    if ended == CHANGE:
                        phase -= 1
                        if steps >= max_steps:
                            return position, velocity, spin, elapsed, path, wp.int32(UNFINISHED), steps, k, track, n
                        continue
                    if ended == REST:
                        outcome = wp.int32(1)
                    elif ended == CONTACT:
                        return position, velocity, spin, elapsed, path, wp.int32(CONTACT), steps, k, track, n
                    else:
                        return position, sm.tangential(velocity, n), spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
            if outcome == FOREVER:
                return position, velocity, spin, elapsed, path, wp.int32(FOREVER), steps, k, track, n
            if outcome == 1:
                rx, rv, rw, re, rp, rc, rs, rk = rest_end(surfaces, k, face, position, velocity, spin, n, elapsed, path, steps)
                return rx, rv, rw, re, rp, rc, rs, rk, track, n
            if outcome == 0:
                if mode == SLIDING:  # the slip is zero now: remove its rounding (omega_t = n x v / R)
                    spin = wp.dot(spin, n) * n + wp.cross(n, velocity) * (ONE / radius)
                else:  # stopped where the resistance cannot hold it: it rolls back from rest
                    velocity = vec3()
                    spin = wp.dot(spin, n) * n
        return position, velocity, spin, elapsed, path, wp.int32(UNFINISHED), steps, k, track, n

    return SimpleNamespace(
        follow=follow,
        Contact=Contact,
        rates=r.rates,
        integrate_phase=integrate_phase,
        Track=Track,
        Tally=Tally,
        start=watcher.start,
    )
