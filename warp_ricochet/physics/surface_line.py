"""A sliding or rolling phase along one line of a plane, integrated in a variable in which
ploughing and drag decay is nearly linear (docs/ground.md 9), as `@wp.func`s for `surface_follow`.

A phase is on a line when the pellet's velocity v e, the slip, the drive and the spin's lift stay
in the plane of e and the normal n: the slip across e, R omega . n (the Magnus force across e),
the drive g . l and the wind across e (l = n x e) are at most LINE x the tolerance of their scales
(`line_of`). Dropping them moves the rest point by about that fraction of the path (to first order:
the slip across e changes v by at most its size, the lift across e is a share of the lift, g . l
of the resistance c N that stops the pellet), 1e-5 at the default tolerance, a tenth of the
issue's bar. The spin is then w l plus its parts along n and e (kept as they are), the state
(s, v, w): the distance along e, the speed along e and the spin about l (rolling: w = v / R).

    dv/dt = a_e - b |v| v - sigma mu_d N/m,  dw/dt = sigma mu_d (N/m) / (k R) + alpha . l   (sliding)
    dv/dt = (a_e - c N/m - b |v| v + k R alpha . l) / (1 + k)                            (rolling)

(a = g + a_air, N/m = -a . n, alpha = T_air / I; `surface_motion`'s laws along e, with the friction's
sign sigma and the resistance's direction frozen for the phase: no jump, so the phase's end is a
smooth root.) The deceleration is nearly D(v) = A + B v^2 (ploughing b v^2 and quadratic drag, under
c N or mu_d N), so the speed falls like 1/t: an RK in v needs ~16 steps per e-fold. The variable

    y = atan2(V, v) / V,   dy/dt = -(dv/dt) / (v^2 + V^2),   v = V cos(V y) / sin(V y)

makes it linear in t where D = A + B v^2 with V^2 = |A| / B (v' = -(A + B v^2) gives y' = B; it is
1 / v for v >> V and linear in v for v << V), so the Dormand-Prince pair takes few steps for what
D departs from it (drag's Reynolds and Mach dependence, the lift's share of N). A and B are measured
at the phase's start (D at 0 and at v0); V is capped at max(|v0|, sqrt(g R)) so that v keeps its
precision. The distance is carried as r = s less its closed-form part (ln sin(V y) - ln sin(V y0)) / B
over each step (B that step's starting dy/dt, where within a factor 2 of the phase's; d ln sin(V y)/dt
= v dy/dt), so dr/dt = v (1 - (dy/dt) / B) is small where the speed still falls like 1/t. Events (the
slip or the speed at its goal, lift-off or loss of grip, the other surfaces along the line) are roots
on the step's cubic Hermite (Illinois: Dowell & Jarratt, BIT 11 (1971) 168), then landed on by a step
of that length from the step's start and finished to first order (Newton on the quantity: `land`).
What is left stiff: a slide at the speed where the ploughing balances a friction that drives the
pellet (topspin) relaxes to it at 2 b V, and DOPRI5's steps stay below its stability bound of about
3.3 / (2 b V) (Hairer & Wanner, Solving ODEs II, IV.2).

In vacuum with ploughing the phase has a closed form (`make_line_closed_forms`): v' = a - b v^2 gives
v = V cot, V coth or V tanh of a linear function of t (and 1 / (1/v0 + b t) at a = 0), the distance
ln sin, ln sinh or ln cosh of it over b, the spin linear in t; the slip's zero is found by Illinois
iteration on these forms (a convex or concave function less a linear one: one sign change).
"""

import functools
import math
from types import SimpleNamespace

import warp as wp

from .air import make_air_laws
from .ballistic import EPSILON, ROUNDING
from .geometry import make_geometry
from .integrate import make_dense_output, make_dormand_prince
from .surface_motion import make_surface_motion
from .types import types_for

LINE = 10.0  # a part across the line up to LINE x the tolerance of its scale is dropped (docstring)
ITERATIONS = 40  # Illinois iterations on a step's dense output (to the rounding of theta)
LANDINGS = 6  # steps that land on an event (Newton or Illinois on its quantity) at most


@functools.cache
def make_line_laws(precision: str, model: str = "ballistic", laws=None) -> SimpleNamespace:
    """The `Line`, the rates in (r, y, path) and w, their Dormand-Prince step and `line_of`."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    AIR = model == "air"
    sm = make_surface_motion(precision)
    air_rates = make_air_laws(precision, *laws).air_rates if AIR else None
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))

    @wp.struct
    class Line:
        """A phase on a line: its frame (n, e, l = n x e), the spin's parts along n and e (kept),
        V, the friction's sign along e, the ground's coefficients and the mode."""

        normal: vec3
        direction: vec3
        lateral: vec3
        rest_spin: vec3
        scale: scalar
        decay: scalar
        inverse: scalar
        forward: scalar
        sign: scalar
        mu_d: scalar
        rolling_resistance: scalar
        ploughing: scalar
        rolling: wp.int32

    @wp.func
    def applied(velocity: vec3, spin: vec3, physics: Physics):
        """(g + a_air, T_air / I)."""
        a = physics.gravity
        alpha = vec3()
        if wp.static(AIR):
            acceleration, alpha = air_rates(velocity, spin, physics.air)
            a = a + acceleration
        return a, alpha

    @wp.func
    def speed(y: scalar, line: Line):
        """v = V cos(V y) / sin(V y)."""
        angle = line.scale * y
        return line.scale * wp.cos(angle) / wp.sin(angle)

    @wp.func
    def along(v: scalar, w: scalar, physics: Physics, line: Line, mu_s: scalar):
        """(dv/dt, dw/dt, N/m, the grip left mu_s N/m - |F|/m rolling or N/m sliding) at (v, w); N/m
        here is -(g + a_air) . n unclipped (< 0: lift-off), the friction's load clipped at 0."""
        radius, k = physics.radius, physics.inertia_factor
        if line.rolling != 0:
            w = v / radius
        a, alpha = applied(v * line.direction, w * line.lateral + line.rest_spin, physics)
        pressed = -wp.dot(a, line.normal)  # N/m, < 0 pulling away (the margin's, unclipped)
        load = wp.max(pressed, ZERO)
        drive = wp.dot(a, line.direction) - line.ploughing * wp.abs(v) * v
        if line.rolling != 0:
            resisted = drive - line.rolling_resistance * load
            dv = (resisted + k * radius * wp.dot(alpha, line.lateral)) / (ONE + k)
            return dv, ZERO, pressed, mu_s * load - wp.abs(dv - resisted)  # w = v / R: not a state
        friction = line.sign * line.mu_d * load
        return drive - friction, friction / (k * radius) + wp.dot(alpha, line.lateral), pressed, pressed

    @wp.func
    def rates(state: vec3, spin: vec3, physics: Physics, line: Line):
        """d/dt of the state (r, y, path) and of (w, 0, 0), as `make_dormand_prince` takes them (in
        its velocity and spin slots; its position slot is unused): r = s - `shift`, the distance
        less its part in closed form, dr/dt = v (1 - dy/dt / B) (`integrate_line`)."""
        v = speed(state[1], line)
        dv, dw, _load, _grip = along(v, spin[0], physics, line, ZERO)
        dy = -dv / (v * v + line.scale * line.scale)
        return rebase(vec3(ZERO, dy, ZERO), v, line), vec3(dw, ZERO, ZERO)

    @wp.func
    def rebase(rate: vec3, v: scalar, line: Line):
        """The state's rates for the step's B (1 / `line.inverse`) from dy/dt."""
        along_path = line.inverse * v * rate[1]
        return vec3(v - along_path, rate[1], wp.abs(v) - line.forward * along_path)

    @wp.func
    def shift(y0: scalar, y1: scalar, line: Line):
        """(ln sin(V y1) - ln sin(V y0)) / B: the distance from y0 to y1 where dy/dt = B exactly
        (d ln sin(V y)/dt = v dy/dt), as log1p(cos(V d) - 1 + cot(V y0) sin(V d)), d = y1 - y0."""
        d = line.scale * (y1 - y0)
        half = wp.sin(HALF * d)
        x = wp.cos(line.scale * y0) / wp.sin(line.scale * y0) * wp.sin(d) - scalar(2.0) * half * half
        return line.inverse * log1p(x)

    @wp.func
    def log1p(x: scalar):
        """log(1 + x) for x > -1, accurate for small x (Kahan)."""
        w = ONE + x
        if w == ONE:
            return x
        return wp.log(w) * x / (w - ONE)

    @wp.func
    def unwrap(raw: vec3, y0: scalar, line: Line):
        """(s, y, path) from (r, y, path) on a step from y0."""
        moved = shift(y0, raw[1], line)
        return vec3(raw[0] + moved, raw[1], raw[2] + line.forward * moved)

    stages = make_dormand_prince(precision, rates, Line, True).stages

    @wp.func
    def line_of(
        velocity: vec3,
        spin: vec3,
        normal: vec3,
        mode_rolling: wp.int32,
        physics: Physics,
        mu_d: scalar,
        rolling_resistance: scalar,
        ploughing: scalar,
        tolerance: scalar,
    ):
        """(1 if the phase is on a line (module docstring) else 0, its `Line`)."""
        radius = physics.radius
        line = Line()
        line.normal = normal
        speed0 = wp.length(velocity)
        e = sm.unit(velocity)
        if speed0 <= ZERO:  # from rest: along the drive
            e = sm.unit(sm.tangential(physics.gravity, normal))
        line.direction = e
        line.lateral = wp.cross(normal, e)
        line.rest_spin = spin - wp.dot(spin, line.lateral) * line.lateral
        line.mu_d = mu_d
        line.rolling_resistance = rolling_resistance
        line.ploughing = ploughing
        line.rolling = mode_rolling
        g = physics.gravity
        floor = wp.sqrt(wp.length(g) * radius)
        scale = speed0 + radius * wp.length(spin) + floor
        bound = scalar(LINE) * tolerance
        slip = sm.slip_velocity(velocity, spin, normal, radius)
        ok = wp.length(e) > ZERO
        ok = ok and wp.abs(wp.dot(slip, line.lateral)) <= bound * scale
        ok = ok and radius * wp.abs(wp.dot(spin, normal)) <= bound * scale
        across = wp.abs(wp.dot(g, line.lateral))
        ok = ok and across <= bound * rolling_resistance * sm.normal_load(normal, g) + STOP_FRACTION * wp.length(g)
        if wp.static(AIR):
            ok = ok and wp.abs(wp.dot(physics.air.wind, line.lateral)) <= bound * scale
        w0 = wp.dot(spin, line.lateral)
        v0 = wp.dot(velocity, e)
        q = v0 - radius * w0  # the slip along e; from none (to rounding), it grows along the drive
        if wp.abs(q) <= STOP_FRACTION * scale:
            a, _alpha = applied(velocity, spin, physics)
            q = wp.dot(a, e) - ploughing * wp.abs(v0) * v0
        line.sign = ONE
        if q < ZERO:
            line.sign = -ONE
        # V from D(v) = A + B v^2 at v = 0 and v0
        line.scale = ONE
        d0, _w, _n, _f = along(ZERO, w0, physics, line, ZERO)
        d1, _w1, _n1, _f1 = along(v0, w0, physics, line, ZERO)
        cap = wp.max(v0, floor)
        b = ZERO
        if v0 > ZERO:
            b = (d0 - d1) / (v0 * v0)
        line.scale = cap
        line.decay = b
        if b > ZERO:
            line.scale = wp.max(wp.min(wp.sqrt(wp.abs(d0) / b), cap), scalar(1e-3) * floor)
        if ok:
            return wp.int32(1), line
        return wp.int32(0), line

    return SimpleNamespace(
        Line=Line,
        applied=applied,
        log1p=log1p,
        speed=speed,
        along=along,
        rates=rates,
        rebase=rebase,
        unwrap=unwrap,
        stages=stages,
        line_of=line_of,
    )


@functools.cache
def make_line_events(precision: str, planes=None, model: str = "ballistic", laws=None) -> SimpleNamespace:
    """What ends a phase on a line: the other surfaces on it (`reach`), the quantities (`quantity`)
    and their roots on a step's dense output (`root`)."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    STATIC = planes
    geo, dense = make_geometry(precision, planes), make_dense_output(precision)
    ll = make_line_laws(precision, model, laws)
    Line, speed, along, unwrap = ll.Line, ll.speed, ll.along, ll.unwrap
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    THETA_TOLERANCE = scalar(4.0 * EPSILON[precision])
    FAR = scalar(1e30)

    @wp.func
    def reach(position: vec3, k: wp.int32, surfaces: Surfaces, physics: Physics, line: Line):
        """(distance ahead along e, surface; distance behind along -e, surface) to the first other
        surface on the line (FAR, -1 where none); 0 for one touched and closed on now."""
        ahead = FAR
        behind = FAR
        k_ahead = wp.int32(-1)
        k_behind = wp.int32(-1)
        count = geo.count(surfaces)
        if wp.static(STATIC is not None):
            count = wp.static(STATIC)
        for j in range(count):
            if j != k:
                height, gap, n = geo.gap(surfaces, j, position, physics.radius)
                closing = -wp.dot(line.direction, n)
                if height >= ZERO and closing != ZERO:
                    s = wp.max(gap, ZERO) / wp.abs(closing)
                    if closing > ZERO and s < ahead:
                        ahead = s
                        k_ahead = wp.int32(j)
                    if closing < ZERO and s < behind:
                        behind = s
                        k_behind = wp.int32(j)
        return ahead, k_ahead, behind, k_behind

    @wp.func
    def quantity(
        kind: wp.int32,
        state: vec3,
        spin: vec3,
        physics: Physics,
        line: Line,
        mu_s: scalar,
        goal: scalar,
        ahead: scalar,
        behind: scalar,
    ):
        """(q, dq/dt) of what ends the phase when it falls to 0: kind 0 the slip along sigma e
        (sliding) or the speed minus `goal` (rolling), 1 the margin (N/m; rolling, the grip left),
        2 the distance to the nearer other surface on the line."""
        v = speed(state[1], line)
        dv, dw, load, grip = along(v, spin[0], physics, line, mu_s)
        if kind == 0:
            if line.rolling != 0:
                return v - goal, dv
            return line.sign * (v - physics.radius * spin[0]), line.sign * (dv - physics.radius * dw)
        if kind == 1:
            return wp.min(load, grip), ZERO
        if v >= ZERO:
            return ahead - state[0], -v
        return behind + state[0], v

    @wp.func
    def illinois(lo: scalar, hi: scalar, q_lo: scalar, q_hi: scalar, side: wp.int32, at: scalar, q: scalar):
        """The bracket (lo, hi) of a root of q (> 0 at lo) updated by its value q at `at`, the kept
        end's value halved after two moves to the same side (Illinois)."""
        if q > ZERO:
            if side == 1:
                q_hi = HALF * q_hi
            return at, hi, q, q_hi, wp.int32(1)
        if side == -1:
            q_lo = HALF * q_lo
        return lo, at, q_lo, q, wp.int32(-1)

    @wp.func
    def root(
        kind: wp.int32,
        h: scalar,
        s0: vec3,
        f0: vec3,
        w0: vec3,
        d0: vec3,
        s1: vec3,
        f1: vec3,
        w1: vec3,
        d1: vec3,
        physics: Physics,
        line: Line,
        mu_s: scalar,
        goal: scalar,
        ahead: scalar,
        behind: scalar,
    ):
        """theta in (0, 1] where `quantity` falls from > 0 to <= 0 on the step (Illinois on the cubic
        Hermite of the state (r, y, path) from s0 to the raw end s1), or 2 if it does not."""
        q_lo, _r0 = quantity(kind, s0, w0, physics, line, mu_s, goal, ahead, behind)
        q_hi, _r1 = quantity(kind, unwrap(s1, s0[1], line), w1, physics, line, mu_s, goal, ahead, behind)
        if not (q_lo > ZERO and q_hi <= ZERO):
            return scalar(2.0)
        lo = ZERO
        hi = ONE
        side = wp.int32(0)
        for _ in range(ITERATIONS):
            if hi - lo > THETA_TOLERANCE:
                mid = (lo * q_hi - hi * q_lo) / (q_hi - q_lo)
                if not (mid > lo and mid < hi):
                    mid = HALF * (lo + hi)
                state = dense.cubic_vec(mid, s0, h * f0, s1, h * f1)
                spin = dense.cubic_vec(mid, w0, h * d0, w1, h * d1)
                q_mid, _r = quantity(kind, unwrap(state, s0[1], line), spin, physics, line, mu_s, goal, ahead, behind)
                lo, hi, q_lo, q_hi, side = illinois(lo, hi, q_lo, q_hi, side, mid, q_mid)
        return hi

    return SimpleNamespace(reach=reach, quantity=quantity, illinois=illinois, root=root)


@functools.cache
def make_surface_line(precision: str, planes=None, model: str = "ballistic", laws=None) -> SimpleNamespace:
    """`line_of` (whether a phase is on a line, and its `Line`) and `integrate_line` (module docstring)."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    ll, ev = make_line_laws(precision, model, laws), make_line_events(precision, planes, model, laws)
    Line, speed, rates, rebase, unwrap, stages = ll.Line, ll.speed, ll.rates, ll.rebase, ll.unwrap, ll.stages
    reach, quantity, illinois, root = ev.reach, ev.quantity, ev.illinois, ev.root
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    TINY = scalar(4.0 * EPSILON[precision])

    @wp.func
    def error_norm(
        s0: vec3, w0: vec3, s1: vec3, w1: vec3, es: vec3, ew: vec3, line: Line, tolerance: scalar, radius: scalar, floor: scalar
    ):
        """The step's error over tolerance, as the 3-D phases' (`surface_follow`): s and the path
        over the step's length + R, v (from y's, dv = (v^2 + V^2) dy) over |v| + floor, w over
        |w| + floor / R (sliding; rolling, w = v / R)."""
        v0 = speed(s0[1], line)
        v1 = speed(s1[1], line)
        fastest = wp.max(v0 * v0, v1 * v1)
        error = wp.max(wp.abs(es[0]) / (wp.abs(s1[0] - s0[0]) + radius), wp.abs(es[2]) / (s1[2] - s0[2] + radius))
        error = wp.max(error, wp.abs(es[1]) * (fastest + line.scale * line.scale) / (wp.sqrt(fastest) + floor))
        if line.rolling == 0:
            error = wp.max(error, wp.abs(ew[0]) / (wp.max(wp.abs(w0[0]), wp.abs(w1[0])) + floor / radius))
        return error / tolerance

    @wp.func
    def land(
        kind: wp.int32,
        theta: scalar,
        h: scalar,
        state: vec3,
        spin: vec3,
        f: vec3,
        d: vec3,
        physics: Physics,
        line: Line,
        mu_s: scalar,
        goal: scalar,
        ahead: scalar,
        behind: scalar,
        band: scalar,
        floor: scalar,
        q_end: scalar,
    ):
        """Step from (state, spin) to the event at theta h, by `LANDINGS` steps at most (between them
        Newton on its quantity, or for the margin Illinois with its value q_end at h); kinds 0
        and 2 are then finished to first order. (state, w, elapsed, steps)."""
        dt = theta * h
        s1 = state
        w1 = spin
        f1 = f
        d1 = d
        taken = wp.int32(0)
        lo = ZERO  # the margin's bracket in time (kind 1: regula falsi between the landings)
        hi = h
        q_lo, _r0 = quantity(kind, state, spin, physics, line, mu_s, goal, ahead, behind)
        q_hi = q_end
        side = wp.int32(0)
        for _ in range(LANDINGS):
            _x, raw, w1, f1, d1, _ex, _es, _ew = stages(vec3(), state, spin, f, d, dt, physics, line)
            s1 = unwrap(raw, state[1], line)
            taken += 1
            q, rate = quantity(kind, s1, w1, physics, line, mu_s, goal, ahead, behind)
            scale = wp.abs(speed(s1[1], line)) + physics.radius * wp.abs(w1[0]) + floor
            if kind == 1:  # the lift-off's load, to its rounding (a shallow crossing)
                scale = wp.length(physics.gravity) * TINY / band
            if wp.abs(q) <= band * scale:
                break
            if kind == 1:
                lo, hi, q_lo, q_hi, side = illinois(lo, hi, q_lo, q_hi, side, dt, q)
                dt = (lo * q_hi - hi * q_lo) / (q_hi - q_lo)
            elif rate < ZERO:
                dt = dt + q / (-rate)
            else:
                break
        q, rate = quantity(kind, s1, w1, physics, line, mu_s, goal, ahead, behind)
        if kind != 1 and rate < ZERO:  # the rest of the way to first order
            finish = q / (-rate)
            v = speed(s1[1], line)
            dv = -f1[1] * (v * v + line.scale * line.scale)
            v_end = v + dv * finish
            s_end = s1[0] + v * finish
            if kind == 2:
                s_end = s1[0] + q * wp.sign(v)
            s1 = vec3(s_end, wp.atan2(line.scale, v_end) / line.scale, s1[2] + wp.abs(v) * finish)
            w1 = w1 + d1 * finish
            dt = dt + finish
        return s1, w1, dt, taken

    @wp.func
    def integrate_line(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        k: wp.int32,
        line: Line,
        goal: scalar,
        surfaces: Surfaces,
        physics: Physics,
        mu_s: scalar,
        steps_left: wp.int32,
        tolerance: scalar,
        band: scalar,
    ):
        """`surface_follow`'s integrate_phase on a line: (x, v, w, elapsed, path, event, k_next,
        steps); event 0 the target reached, 1 the margin, 4 (CONTACT) or 6 (UNFINISHED)."""
        radius = physics.radius
        floor = wp.sqrt(wp.length(physics.gravity) * radius) + scalar(1e-6)
        e = line.direction
        ahead, k_ahead, behind, k_behind = reach(position, k, surfaces, physics, line)
        v0 = wp.dot(velocity, e)
        state = vec3(ZERO, wp.atan2(line.scale, v0) / line.scale, ZERO)
        line.inverse = ZERO
        line.forward = ONE
        w = vec3(wp.dot(spin, line.lateral), ZERO, ZERO)
        if line.rolling != 0:
            w = vec3(v0 / radius, ZERO, ZERO)
        if (ahead <= ZERO and v0 >= ZERO) or (behind <= ZERO and v0 < ZERO):
            k_c = k_ahead
            if v0 < ZERO:
                k_c = k_behind
            return position, velocity, spin, ZERO, ZERO, wp.int32(4), k_c, wp.int32(0)
        f, d = rates(state, w, physics, line)
        dv = -f[1] * (v0 * v0 + line.scale * line.scale)
        h = scalar(0.1) * wp.pow(tolerance, scalar(0.2)) * (wp.abs(v0) + floor) / (wp.abs(dv) + floor / scalar(1e3))
        elapsed = ZERO
        steps = wp.int32(0)
        event = wp.int32(6)
        growth = scalar(5.0)
        while steps < steps_left:
            v_start = speed(state[1], line)
            line.forward = ONE
            if v_start < ZERO:
                line.forward = -ONE
            line.inverse = ZERO  # the closed-form part's 1 / B, where dy/dt is near the phase's B
            if f[1] >= HALF * line.decay and f[1] <= scalar(2.0) * line.decay and line.decay > ZERO:
                line.inverse = ONE / f[1]
            f = rebase(f, v_start, line)
            _x, raw, w1, f1, d1, _ex, es, ew = stages(vec3(), state, w, f, d, h, physics, line)
            s1 = unwrap(raw, state[1], line)
            steps += 1
            error = error_norm(state, w, s1, w1, es, ew, line, tolerance, radius, floor)
            if not (error <= ONE):
                h = h * wp.clamp(scalar(0.9) * wp.pow(error, scalar(-0.2)), scalar(0.2), ONE)
                growth = ONE
                continue
            theta = scalar(2.0)
            kind = wp.int32(-1)
            for candidate in range(3):
                at = root(candidate, h, state, f, w, d, raw, f1, w1, d1, physics, line, mu_s, goal, ahead, behind)
                if at < theta:
                    theta = at
                    kind = wp.int32(candidate)
            if kind >= 0:
                q_end, _rate = quantity(kind, s1, w1, physics, line, mu_s, goal, ahead, behind)
                state, w, dt, taken = land(
                    kind, theta, h, state, w, f, d, physics, line, mu_s, goal, ahead, behind, band, floor, q_end
                )
                steps += taken
                elapsed += dt
                event = kind
                break
            elapsed += h
            state = s1
            w = w1
            f = f1
            d = d1
            h = h * wp.clamp(scalar(0.9) * wp.pow(wp.max(error, scalar(1e-10)), scalar(-0.2)), scalar(0.2), growth)
            growth = scalar(5.0)
        v = speed(state[1], line)
        k_next = k
        if event == 2:
            event = wp.int32(4)
            k_next = k_ahead
            if v < ZERO:
                k_next = k_behind
        spin_out = w[0] * line.lateral + line.rest_spin
        if line.rolling != 0:
            spin_out = (v / radius) * line.lateral + line.rest_spin
        return position + state[0] * e, v * e, spin_out, elapsed, state[2], event, k_next, steps

    return SimpleNamespace(Line=Line, line_of=ll.line_of, integrate_line=integrate_line)


@functools.cache
def make_line_closed_forms(precision: str, planes=None) -> SimpleNamespace:
    """A phase on a line in vacuum with ploughing in closed form (docs/ground.md 9): v' = a - b v^2
    (sliding: a = g . e - sigma mu_d N/m, b the ploughing; rolling: both over 1 + k) with v >= 0,
    the spin linear in t while sliding; `closed_line` returns `integrate_line`'s tuple with 0 steps,
    after a flag (0 where the phase leaves these forms: v would reach 0 while sliding, another
    surface would be met while sliding, or a rolling phase that does not slow down)."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    ll, ev = make_line_laws(precision, "ballistic", None), make_line_events(precision, planes, "ballistic", None)
    Line, reach, illinois, log1p = ll.Line, ev.reach, ev.illinois, ll.log1p
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    THETA_TOLERANCE = scalar(4.0 * EPSILON[precision])
    TINY = scalar(4.0 * EPSILON[precision])
    QUARTER_TURN = scalar(0.5 * math.pi)

    @wp.func
    def log_sinh(x: scalar):
        """log(sinh(x)) for x > 0."""
        if x < ONE:
            return wp.log(wp.sinh(x))
        return x + wp.log(HALF * (ONE - wp.exp(scalar(-2.0) * x)))

    @wp.func
    def log_cosh(x: scalar):
        """log(cosh(x))."""
        return x + wp.log(HALF * (ONE + wp.exp(scalar(-2.0) * x)))

    @wp.func
    def motion(v0: scalar, a: scalar, b: scalar, time: scalar):
        """(v, s) at `time` of v' = a - b v^2 from v0 >= 0 (b > 0), while v >= 0, with V = sqrt(|a| / b),
        k = sqrt(|a| b): a < 0, v = V cot(psi0 + k t), s = ln(sin(psi0 + k t) / sin(psi0)) / b,
        psi0 = atan2(V, v0); a > 0, v = V coth(x0 + k t), s = ln(sinh(x) / sinh(x0)) / b above V, and
        v = V tanh(x0 + k t), s = ln(cosh(x) / cosh(x0)) / b below it (x0 = atanh of V / v0, v0 / V);
        a = 0, v = v0 / (1 + b v0 t), s = ln(1 + b v0 t) / b."""
        if wp.abs(a) <= TINY * b * v0 * v0:
            return v0 / (ONE + b * v0 * time), log1p(b * v0 * time) / b
        speed = wp.sqrt(wp.abs(a) / b)
        rate = wp.sqrt(wp.abs(a) * b)
        if a < ZERO:
            psi0 = wp.atan2(speed, v0)
            d = rate * time
            half = wp.sin(HALF * d)
            x = wp.cos(psi0) / wp.sin(psi0) * wp.sin(d) - scalar(2.0) * half * half  # sin(psi)/sin(psi0) - 1
            psi = psi0 + d
            return speed * wp.cos(psi) / wp.sin(psi), log1p(x) / b
        if v0 > speed:
            x0 = HALF * wp.log((v0 + speed) / (v0 - speed))
            x = x0 + rate * time
            return speed / wp.tanh(x), (log_sinh(x) - log_sinh(x0)) / b
        if v0 < speed:
            x0 = HALF * wp.log((speed + v0) / (speed - v0))
            x = x0 + rate * time
            return speed * wp.tanh(x), (log_cosh(x) - log_cosh(x0)) / b
        return speed, speed * time

    @wp.func
    def stop_time(v0: scalar, a: scalar, b: scalar):
        """When v' = a - b v^2 brings v0 to 0 (a < 0: (pi/2 - psi0) / k), or -1 if it never does."""
        if a >= ZERO or v0 <= ZERO:
            return scalar(-1.0)
        return (QUARTER_TURN - wp.atan2(wp.sqrt(-a / b), v0)) / wp.sqrt(-a * b)

    @wp.func
    def slide_end(v0: scalar, w0: scalar, a: scalar, b: scalar, line: Line, load: scalar, physics: Physics):
        """(1, time) when the slip sigma (v - R w) falls to 0 (Illinois: it is v's convex or concave
        closed form less a linear term, so it changes sign once on the bracket; from no slip, after
        it has grown), or (0, 0) if v reaches 0 first. w = w0 + sigma mu_d (N/m) t / (k R)."""
        fall = line.mu_d * load / physics.inertia_factor  # d(sigma R w)/dt
        lo = ZERO
        q_lo = line.sign * (v0 - physics.radius * w0)
        hi = (wp.max(v0, wp.sqrt(wp.abs(a) / b)) + wp.abs(q_lo)) / fall
        stop = stop_time(v0, a, b)
        if stop >= ZERO:
            hi = wp.min(hi, stop)
        v_hi, _s = motion(v0, a, b, hi)
        q_hi = q_lo + line.sign * (v_hi - v0) - fall * hi
        q0 = q_lo
        if q_lo <= ZERO:  # from no slip (to rounding) it grows first: a start of the bracket where q > 0
            lo = hi
            for _ in range(ITERATIONS):
                if q_lo <= ZERO:
                    lo = HALF * lo
                    v_lo, _s_lo = motion(v0, a, b, lo)
                    q_lo = q0 + line.sign * (v_lo - v0) - fall * lo
        if q_lo <= ZERO or q_hi > ZERO:
            return wp.int32(0), ZERO
        side = wp.int32(0)
        for _ in range(ITERATIONS * 2):
            if hi - lo > THETA_TOLERANCE * hi:
                mid = (lo * q_hi - hi * q_lo) / (q_hi - q_lo)
                if not (mid > lo and mid < hi):
                    mid = HALF * (lo + hi)
                v_mid, _s_mid = motion(v0, a, b, mid)
                q_mid = q0 + line.sign * (v_mid - v0) - fall * mid
                lo, hi, q_lo, q_hi, side = illinois(lo, hi, q_lo, q_hi, side, mid, q_mid)
        return wp.int32(1), hi

    @wp.func
    def closed_line(
        position: vec3, velocity: vec3, spin: vec3, k: wp.int32, line: Line, goal: scalar, surfaces: Surfaces, physics: Physics
    ):
        """(flag, then `integrate_line`'s (x, v, w, elapsed, path, event, k_next, steps)): a sliding
        phase to its slip's zero, a rolling one to `goal` (or to another surface on its way)."""
        radius, inertia = physics.radius, physics.inertia_factor
        e = line.direction
        g = physics.gravity
        load = wp.max(-wp.dot(g, line.normal), ZERO)
        v0 = wp.dot(velocity, e)
        w0 = wp.dot(spin, line.lateral)
        a = wp.dot(g, e) - line.sign * line.mu_d * load
        b = line.ploughing
        if line.rolling != 0:
            a = (wp.dot(g, e) - line.rolling_resistance * load) / (ONE + inertia)
            b = line.ploughing / (ONE + inertia)
        ahead, k_ahead, _behind, _k_behind = reach(position, k, surfaces, physics, line)
        no = wp.int32(0)
        if b <= ZERO or v0 < ZERO:
            return no, position, velocity, spin, ZERO, ZERO, wp.int32(0), k, wp.int32(0)
        if line.rolling != 0:
            stop = stop_time(v0, a, b)
            if stop < ZERO or goal < ZERO:  # does not slow down to rest: integrated
                return no, position, velocity, spin, ZERO, ZERO, wp.int32(0), k, wp.int32(0)
            speed = wp.sqrt(-a / b)
            rate = wp.sqrt(-a * b)
            psi0 = wp.atan2(speed, v0)
            time = (wp.atan2(speed, goal) - psi0) / rate
            v1, s1 = motion(v0, a, b, time)
            v1 = goal
            event = wp.int32(0)
            k_next = k
            if ahead < s1:  # met on the way: sin(psi) = sin(psi0) exp(b s)
                psi = wp.asin(wp.min(wp.sin(psi0) * wp.exp(b * ahead), ONE))
                time = (psi - psi0) / rate
                v1 = speed * wp.cos(psi) / wp.sin(psi)
                s1 = ahead
                event = wp.int32(4)
                k_next = k_ahead
            spin1 = (v1 / radius) * line.lateral + line.rest_spin
            return wp.int32(1), position + s1 * e, v1 * e, spin1, time, s1, event, k_next, wp.int32(0)
        found, time = slide_end(v0, w0, a, b, line, load, physics)
        v1, s1 = motion(v0, a, b, time)
        if found == 0 or ahead < s1:
            return no, position, velocity, spin, ZERO, ZERO, wp.int32(0), k, wp.int32(0)
        w1 = w0 + line.sign * line.mu_d * load * time / (inertia * radius)
        return wp.int32(1), position + s1 * e, v1 * e, w1 * line.lateral + line.rest_spin, time, s1, wp.int32(0), k, wp.int32(0)

    return SimpleNamespace(motion=motion, closed_line=closed_line)
