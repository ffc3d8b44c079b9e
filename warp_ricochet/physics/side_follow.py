"""Motion along a leaning post's side (docs/geometry.md, "Posts (cylinders)", "Along a leaning side").

A pellet that stays on the side of post k (base centre p, unit axis a, radius r, length L) keeps its
centre on the cylinder rho = s = r + R about the axis, its constraint surface. With n the radial unit
normal at the centre (towards the pellet), u = v - (a.v) a its velocity round the axis (v is
tangential) and n' = u / s the normal's rate, a solid sphere (I = k m R^2) with Coulomb friction at
its contact point x - R n obeys, per unit mass (docs/ground.md 1-3 on the tangent plane, plus the
side's curvature; applied = g + a_air, alpha = T_air / I):

- load: N/m = -applied.n - |u|^2 / s, the centripetal term unloading a pellet moving round the
  convex side; N <= 0 is lift-off (frictionless from rest at the top of a level post: cos = 2/3);
- sliding: f = -mu_d (N/m) slip/|slip| (slip = (v - R w x n)_t), dv/dt = applied_t + f - (|u|^2/s) n,
  dw/dt = (f x n) / (k R) + alpha (`surface_motion.sliding_rates` with applied + (|u|^2/s) n);
- rolling: differentiating v = R w x n with w = w_n n + w_t gives (dv/dt)_t = (applied_t + r + k R
  alpha x n + k R w_n n x n') / (1 + k): the plane's law (r = -(c N/m + b |v|^2) v/|v|) and the
  turn of the normal under a drilling spin w_n; the static friction F/m = (dv/dt)_t - applied_t - r
  must stay within mu_s N/m, dw/dt = (F x n) / (k R) + alpha;
- rest: as on a plane (docs/ground.md 4), at most rest_speed where the rolling resistance holds it
  on the tangent plane, |g_t| <= c (-g.n); static friction cannot hold a rolling sphere.

`make_side_follow(...).follow_side` moves it until it rests (REST), lifts off (FLIGHT: N <= 0, or
its centre passes an end, z = a.(x - p) outside [0, L], over the cap's rim or the bottom, as over a
plate's edge), meets another surface (CONTACT) or spends its steps (UNFINISHED), phase after phase
(slide, roll, grip lost, stopped). Each phase is integrated with Dormand-Prince 5(4) steps on the
state (x, v, w) (`integrate.make_dormand_prince`) at `physics.surface_tolerance` in air (in vacuum
VACUUM_TOLERANCE); after each accepted step
the centre is put back on the cylinder along n and v's normal part dropped (its kinetic energy never
rises by it). Events on a step's dense output (quintic Hermite of x, cubic of w): the slip or the
speed reaching its target (stepped to, never across, ended to first order within the band, as on a
plane; a slip that spirals into 0, turned by the curvature and a drilling spin, ends within
0.1 sqrt(tolerance) of its scale once a step aimed at 0 has turned it), N = 0, the grip lost and an
end passed (Illinois), other surfaces (the flight's search).

Sources: Newton's and Euler's equations of a rigid sphere with Coulomb friction (docs/ground.md),
the constraint differentiated on the cylinder; cos = 2/3 is the classical particle leaving a smooth
cylinder (or sphere) from rest at its top, N = m g cos(phi) - m v^2 / s = 0 with v^2 = 2 g s (1 - cos).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .air_flight import make_plane_search
from .ballistic import EPSILON, ROUNDING
from .integrate import make_dense_output, make_dormand_prince
from .line_maths import make_line_maths
from .surface_motion import FLIGHT, REST, ROLLING, SLIDING, make_surface_motion
from .surface_rates import make_surface_rates
from .types import types_for

CONTACT, UNFINISHED, EDGE = 4, 6, 7  # `surface_follow`'s end codes (an end passed: EDGE)
LEAN = 1e-6  # sin of the lean from gravity above which a post's side is followed (a vertical post: its side carries no load; the pellet flies on)
VACUUM_TOLERANCE = {"float64": 1e-8, "float32": 1e-6}  # relative: the side's phases are short
MAX_SIDE_PHASES = 32
ENDS_SAMPLES = 8  # equal parts of a step searched for an end passed
STOP = {p: max(1e-9, ROUNDING * e) for p, e in EPSILON.items()}
BAND = 0.1


@functools.cache
def make_side_rates(precision: str, model: str = "ballistic", laws=None) -> SimpleNamespace:
    """`Side` (the post's frame, material and mode), `rates(y, physics, side)` of the state
    y = (x, v, w) and the events' quantities (module docstring)."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    State = wp.types.vector(length=9, dtype=scalar)
    from .cylinder_contact import make_cylinder_contact

    sm, posts = make_surface_motion(precision), make_cylinder_contact(precision)
    applied_at = make_surface_rates(precision, model, laws).applied_at
    ZERO, ONE = scalar(0.0), scalar(1.0)
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])

    @wp.struct
    class Side:
        """Post k's base centre p (m), unit axis a, the centre's radius s = r + R (m), length L (m),
        the material and the mode (rolling 1)."""

        point: vec3
        axis: vec3
        reach: scalar
        length: scalar
        mu_d: scalar
        rolling_resistance: scalar
        ploughing: scalar
        rolling: wp.int32

    @wp.func
    def side_of(surfaces: Surfaces, k: wp.int32, radius: scalar, mu_d: scalar, rolling_resistance: scalar, ploughing: scalar):
        """The `Side` of post k for a pellet of `radius` (m) and the material's coefficients."""
        side = Side()
        p, a, r, length = posts.post_frame(surfaces, k)
        side.point = p
        side.axis = a
        side.reach = r + radius
        side.length = length
        side.mu_d = mu_d
        side.rolling_resistance = rolling_resistance
        side.ploughing = ploughing
        return side

    @wp.func
    def leans(surfaces: Surfaces, k: wp.int32, g: vec3):
        """Whether post k's axis leans from gravity by more than LEAN (sin): gravity loads its side."""
        _p, a, _r, _length = posts.post_frame(surfaces, k)
        return wp.length(wp.cross(a, g)) > scalar(LEAN) * wp.length(g)

    @wp.func
    def radial(x: vec3, side: Side):
        """(n, rho): the unit normal from the axis to x and x's distance from the axis (m)."""
        d = x - side.point
        across = d - wp.dot(d, side.axis) * side.axis
        rho = wp.length(across)
        return across * (ONE / rho), rho

    @wp.func
    def pack(x: vec3, v: vec3, w: vec3):
        """The state vector (x, v, w)."""
        return State(x[0], x[1], x[2], v[0], v[1], v[2], w[0], w[1], w[2])

    @wp.func
    def part(y: State, i: wp.int32):
        """Component vector i of a state: 0 x, 1 v, 2 w."""
        return vec3(y[3 * i], y[3 * i + 1], y[3 * i + 2])

    @wp.func
    def loads(x: vec3, v: vec3, w: vec3, physics: Physics, side: Side):
        """(n, n' (1/s), applied + (|u|^2/s) n: the acceleration whose normal part the load balances,
        alpha, the centripetal |u|^2/rho (m/s^2), v's tangential part)."""
        n, rho = radial(x, side)
        vt = sm.tangential(v, n)
        applied, alpha = applied_at(vt, w, physics)
        u = vt - wp.dot(vt, side.axis) * side.axis
        bend = wp.dot(u, u) / rho
        return n, u * (ONE / rho), applied + bend * n, alpha, bend, vt

    @wp.func
    def sliding_slip(v: vec3, w: vec3, n: vec3, turn: vec3, drive: vec3, alpha: vec3, radius: scalar):
        """The slip the friction opposes: (v - R w x n)_t, or where that is rounding of |v| + R |w|
        (sliding from rolling that lost its grip), the way it starts to grow without friction,
        drive - R alpha x n - R w x n' (as `surface_motion.sliding_rates` takes the drive on a plane)."""
        slip = sm.slip_velocity(v, w, n, radius)
        if wp.length(slip) <= TOLERANCE * (wp.length(v) + radius * wp.length(w)):
            slip = sm.tangential(drive - radius * wp.cross(alpha, n) - radius * wp.cross(w, turn), n)
        return slip

    @wp.func
    def motion(x: vec3, v: vec3, w: vec3, physics: Physics, side: Side):
        """(dv/dt, dw/dt, |F|/m rolling (0 sliding), N/m unclipped) at the state (module docstring)."""
        n, turn, effective, alpha, bend, vt = loads(x, v, w, physics, side)
        radius, k = physics.radius, physics.inertia_factor
        load = -wp.dot(effective, n)
        if side.rolling != 0:
            a_t, w_dot, _f = sm.rolling_rates(vt, n, effective, alpha, radius, k, side.rolling_resistance, side.ploughing)
            friction = (k * radius) * wp.cross(n, w_dot - alpha)  # the plane's F/m
            extra = (k * radius * wp.dot(w, n) / (ONE + k)) * wp.cross(n, turn)  # the drilling spin's share
            friction = friction + extra
            w_dot = w_dot + wp.cross(extra, n) * (ONE / (k * radius))
            return a_t + extra - bend * n, w_dot, wp.length(friction), load
        drive = sm.tangential(effective, n) + sm.plough(vt, n, side.ploughing)
        slip = sliding_slip(vt, w, n, turn, drive, alpha, radius)
        friction = -(side.mu_d * wp.max(load, ZERO)) * sm.unit(slip)
        w_dot = wp.cross(friction, n) * (ONE / (k * radius)) + alpha
        return drive + friction - bend * n, w_dot, ZERO, load

    @wp.func
    def rates(y: State, physics: Physics, side: Side):
        """dy/dt of y = (x, v, w)."""
        x, v, w = part(y, 0), part(y, 1), part(y, 2)
        acceleration, spin_rate, _f, _load = motion(x, v, w, physics, side)
        return pack(v, acceleration, spin_rate)

    @wp.func
    def margin(x: vec3, v: vec3, w: vec3, physics: Physics, side: Side, mu_s: scalar):
        """(the lesser of N/m and, rolling, the grip left mu_s N/m - |F|/m; whether N/m is it)."""
        _a, _w, friction, load = motion(x, v, w, physics, side)
        grip = load
        if side.rolling != 0:
            grip = mu_s * wp.max(load, ZERO) - friction
        return wp.min(load, grip), load <= grip

    @wp.func
    def target(x: vec3, v: vec3, w: vec3, physics: Physics, side: Side, goal: scalar):
        """(q, dq/dt, direction) of the quantity a phase ends at: sliding, the slip's size (its
        rate with the normal's turn, -R w x n'); rolling, the speed minus `goal`."""
        acceleration, spin_rate, _f, _load = motion(x, v, w, physics, side)
        if side.rolling != 0:
            direction = sm.unit(v)
            return wp.length(v) - goal, wp.dot(acceleration, direction), direction
        n, turn, _e, _alpha, _bend, _vt = loads(x, v, w, physics, side)
        radius = physics.radius
        slip = sm.slip_velocity(v, w, n, radius)
        rate = sm.tangential(acceleration - radius * wp.cross(spin_rate, n) - radius * wp.cross(w, turn), n)
        direction = sm.unit(slip)
        if wp.length(slip) <= TOLERANCE * (wp.length(v) + radius * wp.length(w)):  # (as `sliding_slip`)
            direction = sm.unit(rate)
        return wp.length(slip), wp.dot(rate, direction), direction

    @wp.func
    def mode_of(x: vec3, v: vec3, w: vec3, physics: Physics, side: Side, mu_s: scalar, rest_speed: scalar):
        """`surface_motion.surface_mode` on the side: FLIGHT (N <= 0), SLIDING (slip above rounding,
        or rolling, its drilling share included, would need more than mu_s N), REST, else ROLLING."""
        n, _turn, effective, _alpha, _bend, vt = loads(x, v, w, physics, side)
        load = -wp.dot(effective, n)
        if load <= ZERO:
            return wp.int32(FLIGHT)
        if wp.length(sm.slip_velocity(vt, w, n, physics.radius)) > TOLERANCE * (wp.length(vt) + physics.radius * wp.length(w)):
            return wp.int32(SLIDING)
        if wp.length(vt) <= rest_speed and sm.held(n, physics.gravity, side.rolling_resistance):
            return wp.int32(REST)
        rolling = side
        rolling.rolling = wp.int32(1)
        _a, _w, friction, _load = motion(x, vt, w, physics, rolling)
        if friction > mu_s * load:
            return wp.int32(SLIDING)
        return wp.int32(ROLLING)

    @wp.func
    def put_back(x: vec3, v: vec3, side: Side):
        """The centre onto the cylinder along its normal, v's normal part dropped: (x, v, n, z)."""
        n, _rho = radial(x, side)
        z = wp.dot(x - side.point, side.axis)
        return side.point + z * side.axis + side.reach * n, sm.tangential(v, n), n, z

    stages = make_dormand_prince(precision, rates, Side, True, state=State).stages
    return SimpleNamespace(
        Side=Side,
        State=State,
        side_of=side_of,
        leans=leans,
        pack=pack,
        part=part,
        loads=loads,
        motion=motion,
        rates=rates,
        margin=margin,
        target=target,
        put_back=put_back,
        mode_of=mode_of,
        stages=stages,
    )


@functools.cache
def make_side_events(precision: str, model: str = "ballistic", laws=None) -> SimpleNamespace:
    """`ends_theta` and `event_root` on a side step's dense output (module docstring)."""
    t = types_for(precision)
    scalar, Physics = t.scalar, t.Physics
    dense, maths, s = make_dense_output(precision), make_line_maths(precision), make_side_rates(precision, model, laws)
    Side, State, part, margin = s.Side, s.State, s.part, s.margin
    ZERO = scalar(0.0)
    THETA_TOLERANCE = scalar(4.0 * EPSILON[precision])
    ITERATIONS = 64 if precision == "float64" else 40
    SAMPLES = ENDS_SAMPLES

    @wp.func
    def event_value(
        kind: wp.int32,
        theta: scalar,
        h: scalar,
        y0: State,
        f0: State,
        y1: State,
        f1: State,
        physics: Physics,
        side: Side,
        mu_s: scalar,
        slack: scalar,
    ):
        """On a step's dense output at theta: kind 0, `margin`; 1, how far the centre is inside the
        ends (min(z, L - z) + slack, m)."""
        x, slope = dense.hermite_vec(
            theta, part(y0, 0), h * part(y0, 1), h * h * part(f0, 1), part(y1, 0), h * part(y1, 1), h * h * part(f1, 1)
        )
        if kind == 1:
            z = wp.dot(x - side.point, side.axis)
            return wp.min(z, side.length - z) + slack
        w = dense.cubic_vec(theta, part(y0, 2), h * part(f0, 2), part(y1, 2), h * part(f1, 2))
        value, _lifted = margin(x, slope / h, w, physics, side, mu_s)
        return value

    @wp.func
    def event_root(
        kind: wp.int32,
        lo: scalar,
        hi: scalar,
        f_lo: scalar,
        f_hi: scalar,
        h: scalar,
        y0: State,
        f0: State,
        y1: State,
        f1: State,
        physics: Physics,
        side: Side,
        mu_s: scalar,
        slack: scalar,
    ):
        """Where `event_value` falls from f_lo > 0 at lo to f_hi <= 0 at hi (Illinois, the upper end)."""
        sense = wp.int32(0)
        for _ in range(ITERATIONS):
            if hi - lo > THETA_TOLERANCE:
                mid = maths.secant(lo, hi, f_lo, f_hi)
                value = event_value(kind, mid, h, y0, f0, y1, f1, physics, side, mu_s, slack)
                lo, hi, f_lo, f_hi, sense = maths.illinois(lo, hi, f_lo, f_hi, sense, mid, value)
        return hi

    @wp.func
    def ends_theta(
        h: scalar, y0: State, f0: State, y1: State, f1: State, physics: Physics, side: Side, mu_s: scalar, slack: scalar
    ):
        """The first theta in (0, 1] where the centre passes an end (SAMPLES equal parts, then
        Illinois), or 2."""
        lo = ZERO
        f_lo = event_value(wp.int32(1), ZERO, h, y0, f0, y1, f1, physics, side, mu_s, slack)
        for i in range(SAMPLES):
            at = scalar(i + 1) / scalar(SAMPLES)
            value = event_value(wp.int32(1), at, h, y0, f0, y1, f1, physics, side, mu_s, slack)
            if value <= ZERO:
                return event_root(wp.int32(1), lo, at, f_lo, value, h, y0, f0, y1, f1, physics, side, mu_s, slack)
            lo = at
            f_lo = value
        return scalar(2.0)

    return SimpleNamespace(event_root=event_root, ends_theta=ends_theta)


@functools.cache
def make_side_follow(
    precision: str, planes=None, model: str = "ballistic", laws=None, watch: tuple = (0, 0, False), plates=0, watch_start=None
) -> SimpleNamespace:
    """`leans(surfaces, k, g)` and `follow_side` (module docstring) for `surface_follow.follow`'s
    arguments; `watch_start` is its integrator's (the surfaces other than k watched at a phase's start)."""
    from ..tallies.path_replay import watch_for  # (tallies imports physics: not at the top)
    from .cylinder_contact import make_cylinder_contact

    watcher = watch_for(precision, *watch)
    Track, Tally = watcher.Track, watcher.Tally
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    AIR = model == "air"
    sm, dense = make_surface_motion(precision), make_dense_output(precision)
    events = make_side_events(precision, model, laws)
    event_root, ends_theta = events.event_root, events.ends_theta
    s, r = make_side_rates(precision, model, laws), make_surface_rates(precision, model, laws)
    Side, pack, part, stages, margin, target = s.Side, s.pack, s.part, s.stages, s.margin, s.target
    posts, search = make_cylinder_contact(precision), make_plane_search(precision, planes, plates, out_of_line=True)
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    STOP_FRACTION, IN_VACUUM = scalar(STOP[precision]), scalar(VACUUM_TOLERANCE[precision])
    TWO_EPS = scalar(2.0 * EPSILON[precision])

    @wp.func
    def integrate_side(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        k: wp.int32,
        side: Side,
        goal: scalar,
        slack: scalar,
        surfaces: Surfaces,
        physics: Physics,
        mu_s: scalar,
        steps_left: wp.int32,
        track: Track,
        tally: Tally,
    ):
        """One phase along the side (`side.rolling`) until its `target` reaches `goal` (event 0),
        the margin reaches 0 (1), an end is passed (EDGE), another surface is met (CONTACT) or
        steps_left are spent (UNFINISHED): (x, v, w, elapsed, path, event, k_next, steps, lifted, track)."""
        radius = physics.radius
        floor = wp.sqrt(wp.length(physics.gravity) * radius) + scalar(1e-6)
        tolerance = IN_VACUUM
        if wp.static(AIR):
            tolerance = physics.surface_tolerance
        band = wp.max(STOP_FRACTION, scalar(BAND) * tolerance)
        watched, waiting, now = watch_start(position, velocity, k, surfaces, physics)
        if now >= 0:
            return position, velocity, spin, ZERO, ZERO, wp.int32(CONTACT), now, wp.int32(0), False, track
        y = pack(position, velocity, spin)
        f = s.rates(y, physics, side)
        scale = wp.length(velocity) + radius * wp.length(spin) + floor
        # the slip's rounding: n's (the centre's, 2 eps |x|_1, over s) times the speeds it turns
        turned = TWO_EPS * (wp.abs(position[0]) + wp.abs(position[1]) + wp.abs(position[2]))
        band_q = band * scale + turned / side.reach * (wp.length(velocity) + radius * wp.length(spin))
        h = scalar(0.1) * wp.pow(tolerance, scalar(0.2)) * scale / (wp.length(part(f, 1)) + floor / scalar(1e3))
        # a slip turning round the normal as it falls (the side's curvature and a drilling spin) spirals
        # into 0 in ever shorter turns: once a step aimed at 0 has turned it past its start (or left
        # it above half its size), it ends within this band
        spun = wp.bool(False)
        spun_band = scalar(BAND) * wp.sqrt(tolerance) * scale
        elapsed = ZERO
        path = ZERO
        steps = wp.int32(0)
        growth = scalar(5.0)
        while steps < steps_left:
            x, v, w, a, d = part(y, 0), part(y, 1), part(y, 2), part(f, 1), part(f, 2)
            q, rate, direction = target(x, v, w, physics, side, goal)
            aimed = wp.bool(False)
            if rate < ZERO:
                if q <= band_q or (spun and q <= spun_band):  # the rest of the way to first order
                    dt = q / (-rate)
                    moved = v * dt
                    bend = a * (dt * dt)
                    track = watcher.segment(track, tally, x, moved, bend, x + moved, moved + bend, bend, dt, ONE)
                    x2, v2, _n, _z = s.put_back(x + moved, v + a * dt, side)
                    return x2, v2, w + d * dt, elapsed + dt, path + wp.length(v) * dt, wp.int32(0), k, steps, False, track
                aim = (q - HALF * band_q) / (-rate)
                if aim <= h:
                    h = aim
                    aimed = wp.bool(True)
            y1, f1, e = stages(y, f, h, physics, side)
            steps += 1
            x1, v1, w1, a1 = part(y1, 0), part(y1, 1), part(y1, 2), part(f1, 1)
            error = r.error_norm(x, v, w, x1, v1, w1, part(e, 0), part(e, 1), part(e, 2), tolerance, floor, radius)
            if error > ONE:
                h = h * wp.clamp(scalar(0.9) * wp.pow(error, scalar(-0.2)), scalar(0.2), ONE)
                growth = ONE
                continue
            q1, _rate1, _d1 = target(x1, v1, w1, physics, side, goal)
            crossed = q1 < ZERO
            if side.rolling == 0 or goal <= ZERO:  # the slip or the velocity reversed
                n1, _turn, _e, _alpha, _bend, _vt = s.loads(x1, v1, w1, physics, side)
                after = sm.slip_velocity(v1, w1, n1, radius)
                if side.rolling != 0:
                    after = v1
                crossed = wp.dot(after, direction) < ZERO and q > ZERO
            if aimed and q1 > HALF * q:  # aimed at the switch, it turned (or chattered) round it
                spun = wp.bool(True)
            if crossed:  # stepped past the switch, where the friction jumps: aim short of it
                spun = wp.bool(True)
                h = HALF * h
                growth = ONE
                continue
            theta = scalar(2.0)
            event = wp.int32(-1)
            m1, lifted = margin(x1, v1, w1, physics, side, mu_s)
            if m1 <= ZERO:
                m0, _l0 = margin(x, v, w, physics, side, mu_s)
                theta = event_root(wp.int32(0), ZERO, ONE, m0, m1, h, y, f, y1, f1, physics, side, mu_s, slack)
                event = wp.int32(1)
            off = ends_theta(h, y, f, y1, f1, physics, side, mu_s, slack)
            if off <= ONE and off <= theta:
                theta = off
                event = wp.int32(EDGE)
            theta_c, k_c, watched, waiting = search.search(h, x, v, a, x1, v1, a1, watched, waiting, surfaces, physics)
            if k_c >= 0 and theta_c <= theta:
                theta = theta_c
                event = wp.int32(CONTACT)
            end = ONE
            if event >= 0:
                end = theta
            track = watcher.segment(track, tally, x, h * v, h * h * a, x1, h * v1, h * h * a1, h, end)
            if event >= 0:
                xe, slope = dense.hermite_vec(theta, x, h * v, h * h * a, x1, h * v1, h * h * a1)
                we = dense.cubic_vec(theta, w, h * d, w1, h * part(f1, 2))
                ve = slope / h
                if event != CONTACT:  # (at a contact the centre stays where it meets the other surface)
                    xe, ve, _n, _z = s.put_back(xe, ve, side)
                if event == 1:
                    _m, lifted = margin(xe, ve, we, physics, side, mu_s)
                path += r.simpson(h, theta, x, v, a, x1, v1, a1)
                k_next = k
                if event == CONTACT:
                    k_next = k_c
                return xe, ve, we, elapsed + theta * h, path, event, k_next, steps, lifted, track
            path += r.simpson(h, ONE, x, v, a, x1, v1, a1)
            elapsed += h
            x1, v1, _n, _z = s.put_back(x1, v1, side)
            y = pack(x1, v1, w1)
            f = s.rates(y, physics, side)
            h = h * wp.clamp(scalar(0.9) * wp.pow(wp.max(error, scalar(1e-10)), scalar(-0.2)), scalar(0.2), growth)
            growth = scalar(5.0)
        return part(y, 0), part(y, 1), part(y, 2), elapsed, path, wp.int32(UNFINISHED), k, steps, False, track

    @wp.func
    def follow_side(
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
        """Follow the pellet along post k's side, phase after phase (module docstring): as
        `surface_follow.follow`'s (position, velocity, spin, elapsed, path, end, steps, k_next,
        track, normal); FLIGHT also where the centre passes an end (the normal: the side's there)."""
        radius, g = physics.radius, physics.gravity
        side = s.side_of(surfaces, k, radius, mu_d, rolling_resistance, ploughing)
        slack = posts.slack(surfaces, k, position)
        elapsed = ZERO
        path = ZERO
        steps = wp.int32(0)
        forced = wp.int32(-1)  # the mode a phase must take after a loss of grip
        n = vec3()
        phase = wp.int32(0)
        while phase < MAX_SIDE_PHASES:
            phase += 1
            position, velocity, n, z = s.put_back(position, velocity, side)
            if not posts.along(z, side.length, slack):  # past an end: it flies on
                return position, velocity, spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
            mode = s.mode_of(position, velocity, spin, physics, side, mu_s, rest_speed)
            if forced >= 0 and mode == ROLLING:
                mode = forced
            forced = wp.int32(-1)
            if mode == REST:
                return position, vec3(), wp.dot(spin, n) * n, elapsed, path, wp.int32(REST), steps, k, track, n
            if mode == FLIGHT:
                return position, velocity, spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
            holds = sm.held(n, g, rolling_resistance)
            goal = ZERO
            side.rolling = wp.int32(0)
            if mode == ROLLING:
                side.rolling = wp.int32(1)
                if holds:
                    goal = rest_speed
            position, velocity, spin, dt, dp, event, k_c, taken, lifted, track = integrate_side(
                position, velocity, spin, k, side, goal, slack, surfaces, physics, mu_s, max_steps - steps, track, tally
            )
            elapsed += dt
            path += dp
            steps += taken
            if event == UNFINISHED:
                return position, velocity, spin, elapsed, path, wp.int32(UNFINISHED), steps, k, track, n
            if event == CONTACT:
                return position, velocity, spin, elapsed, path, wp.int32(CONTACT), steps, k_c, track, n
            n_end, _turn_end, _e_end, _a_end, _b_end, _v_end = s.loads(position, velocity, spin, physics, side)
            n = n_end
            if event == EDGE or (event == 1 and lifted):
                return position, sm.tangential(velocity, n), spin, elapsed, path, wp.int32(FLIGHT), steps, k, track, n
            if event == 1:  # rolling lost its grip
                forced = wp.int32(SLIDING)
            elif side.rolling == 0:  # the slip is zero now: remove its rounding (omega_t = n x v / R)
                spin = wp.dot(spin, n) * n + wp.cross(n, velocity) * (ONE / radius)
            elif goal > ZERO:  # at the rest speed: at rest where the resistance holds it here
                if sm.held(n, g, rolling_resistance):
                    return position, vec3(), wp.dot(spin, n) * n, elapsed, path, wp.int32(REST), steps, k, track, n
            else:  # stopped where the resistance cannot hold it: it rolls back from rest
                velocity = vec3()
                spin = wp.dot(spin, n) * n
        return position, velocity, spin, elapsed, path, wp.int32(UNFINISHED), steps, k, track, n

    return SimpleNamespace(leans=s.leans, follow_side=follow_side)
