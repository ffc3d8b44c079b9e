"""Motion of a sphere along a plane: sliding, rolling, lift-off and rest, as `@wp.func`s (docs/ground.md).

A solid sphere (radius R, mass m, I = k m R^2, k = 2/5) touches a plane of unit normal n (towards
the pellet) with its centre at height R. Everything is per unit mass (accelerations in m/s^2):
`applied` = g + a_air is the acceleration of every force but the plane's (gravity, drag and lift),
`spin_rate_air` = T_air / I the air's torque. The plane supplies the normal load and friction.
Newton's and Euler's equations of a rigid sphere with Coulomb friction at its contact point (the
textbook "bowling ball" problem); each law is derived in docs/ground.md, sections 1-6.

- Normal load (docs/ground.md 1): the centre keeps its height, so N/m = -(g + a_air) . n, clipped at
  0; N <= 0 is lift-off (the net normal force pulls the pellet away).
- Slip (1): the contact point p = c - R n moves at v_c = v + omega x (-R n); its tangential part s
  is the slip.
- Sliding (2): kinetic Coulomb friction f = -mu_d (N/m) s/|s| at p:
      dv/dt = (g + a_air)_t + f,   domega/dt = (f x n) / (k R) + T_air / I    [torque R(-n) x m f]
  so ds/dt = (g + a_air)_t + (1 + 1/k) f (+ the air torque's part): |s| falls at 7/2 mu_d N/m on a
  level plane in vacuum, and a sphere launched without spin rolls after t = 2 v0 / (7 mu_d g), having
  run 12 v0^2 / (49 mu_d g), at 5/7 v0.
- Rolling (3): s = 0 is kept by static friction F; the resisting force c N (c = rolling_resistance)
  opposes the velocity. Then dv/dt = R domega/dt x n gives
      dv/dt = ((g + a_air)_t - c (N/m) v/|v| + k R (T_air/I) x n) / (1 + k),
  5/7 of the drive: a level plane's deceleration is 5/7 c g, an incline's acceleration 5/7 g sin(theta)
  (c = 0). The friction it needs, F/m = dv/dt - drive, must stay within mu_s N/m (else sliding).
  A rolling ball held back by c N as on a golf green: Penner, "The physics of putting", Can. J. Phys.
  80 (2002) 83, and "The run of a golf ball", Can. J. Phys. 80 (2002) 931.
- Ploughing (8): a resisting acceleration b |v|^2 against the velocity (b = `ploughing`, 1/m), through
  the centre (no torque), sliding and rolling, beside c N: Poncelet's F = A (c0 + c2 v^2). Rolling, a
  sphere feels 5/7 of it, like c N. The closed forms here leave it out (b = 0); `surface_follow` has
  rolling on a level plane with it in closed form and integrates the rest.
- Rest (4): speed <= rest_speed and the slope cannot restart it: |g_t| <= c (-g . n) (static friction
  cannot hold a sphere on a slope: it rolls; the rolling resistance can, up to c N; the air's forces
  vanish on a pellet at rest).
- Separation after an impact (5): the rebound leaves the plane only if its normal speed rises above
  one pellet radius against the net normal load, v_n' > sqrt(2 R N/m); below it the pellet stays on.

Closed forms (6): in vacuum the applied acceleration is g, constant. A sliding phase then has constant
accelerations when the drive g_t is along the slip (a level plane: g_t = 0), a rolling phase when g_t
is along the velocity (or c = 0): `follow_on_plane` chains them to rest. A phase with a drive across
the slip or the velocity turns the friction's direction as it goes: no closed form here, `exact` = 0
(integrated by `surface_follow`, as is everything in air).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON, ROUNDING
from .types import types_for

FLIGHT, SLIDING, ROLLING, REST = 0, 1, 2, 3  # the modes of `surface_mode`
NEVER = -1.0  # the time of a phase that does not end (on an infinite plane)
MAX_PHASES = 4  # slide, roll, stop on a slope and roll back: `follow_on_plane` needs at most 3


@functools.cache
def make_surface_laws(precision: str) -> SimpleNamespace:
    """The laws (docs/ground.md 1-5) as `@wp.func`s of one precision ("float32" or "float64")."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])
    ZERO = scalar(0.0)
    ONE = scalar(1.0)

    @wp.func
    def tangential(vector: vec3, normal: vec3):
        """The part of `vector` along the plane."""
        return vector - wp.dot(vector, normal) * normal

    @wp.func
    def unit(vector: vec3):
        """vector / |vector|, or zero."""
        length = wp.length(vector)
        if length > ZERO:
            return vector * (ONE / length)
        return vec3()

    @wp.func
    def normal_load(normal: vec3, applied: vec3):
        """N/m = -(g + a_air) . n, clipped at 0 (m/s^2); 0 is lift-off."""
        return wp.max(-wp.dot(applied, normal), ZERO)

    @wp.func
    def slip_velocity(velocity: vec3, spin: vec3, normal: vec3, radius: scalar):
        """Tangential velocity of the contact point: (v + omega x (-R n))_t."""
        return tangential(velocity - radius * wp.cross(spin, normal), normal)

    @wp.func
    def plough(velocity: vec3, normal: vec3, ploughing: scalar):
        """The ploughing resistance -b |v_t| v_t (m/s^2; b in 1/m): Poncelet's quadratic term."""
        along = tangential(velocity, normal)
        return -(ploughing * wp.length(along)) * along

    @wp.func
    def sliding_rates(
        velocity: vec3,
        spin: vec3,
        normal: vec3,
        applied: vec3,  # m/s^2, g + a_air
        spin_rate_air: vec3,  # rad/s^2, T_air / I
        radius: scalar,
        inertia_factor: scalar,
        mu_d: scalar,
        ploughing: scalar,  # 1/m
    ):
        """(dv/dt, domega/dt) while sliding: Coulomb friction -mu_d N/m against the slip (against the
        drive when there is no slip yet) and the ploughing resistance -b |v| v through the centre."""
        drive = tangential(applied, normal) + plough(velocity, normal, ploughing)
        slip = slip_velocity(velocity, spin, normal, radius)
        if wp.length(slip) <= ZERO:  # sliding from no slip (rolling cannot hold): it grows along the drive
            slip = drive
        friction = -(mu_d * normal_load(normal, applied)) * unit(slip)
        spin_rate = wp.cross(friction, normal) * (ONE / (inertia_factor * radius)) + spin_rate_air
        return drive + friction, spin_rate

    @wp.func
    def rolling_rates(
        velocity: vec3,
        normal: vec3,
        applied: vec3,
        spin_rate_air: vec3,
        radius: scalar,
        inertia_factor: scalar,
        rolling_resistance: scalar,
        ploughing: scalar,  # 1/m
    ):
        """(dv/dt, domega/dt, |F|/m) while rolling: the resisting force c N/m + b |v|^2 against the
        velocity (rolling and ploughing resistance, through the centre), the static friction F that
        keeps the slip zero and its size. At rest, the resistance holds up to c N/m of the drive
        (so a pellet held by it does not move)."""
        load = normal_load(normal, applied)
        drive = tangential(applied, normal)
        resistance = vec3()
        if wp.length(tangential(velocity, normal)) > ZERO:
            resistance = -(rolling_resistance * load) * unit(tangential(velocity, normal)) + plough(velocity, normal, ploughing)
        else:
            resistance = -wp.min(rolling_resistance * load, wp.length(drive)) * unit(drive)
        acceleration = (drive + resistance + (inertia_factor * radius) * wp.cross(spin_rate_air, normal)) * (
            ONE / (ONE + inertia_factor)
        )
        friction = acceleration - drive - resistance
        spin_rate = wp.cross(friction, normal) * (ONE / (inertia_factor * radius)) + spin_rate_air
        return acceleration, spin_rate, wp.length(friction)

    @wp.func
    def held(normal: vec3, gravity: vec3, rolling_resistance: scalar):
        """Whether a pellet at rest stays so: |g_t| <= c N/m with N/m = -g . n. The air's forces
        vanish at rest (no wind at the ground): drag only resists a motion, it cannot restart one."""
        return wp.length(tangential(gravity, normal)) <= rolling_resistance * normal_load(normal, gravity)

    @wp.func
    def surface_mode(
        velocity: vec3,
        spin: vec3,
        normal: vec3,
        applied: vec3,
        spin_rate_air: vec3,
        gravity: vec3,
        radius: scalar,
        inertia_factor: scalar,
        mu_s: scalar,
        rolling_resistance: scalar,
        ploughing: scalar,
        rest_speed: scalar,
    ):
        """FLIGHT (N <= 0), SLIDING (slip above rounding, or rolling would need more than mu_s N),
        REST (speed <= rest_speed and `held`), else ROLLING."""
        load = normal_load(normal, applied)
        if load <= ZERO:
            return wp.int32(FLIGHT)
        scale = wp.length(velocity) + radius * wp.length(spin)
        if wp.length(slip_velocity(velocity, spin, normal, radius)) > TOLERANCE * scale:
            return wp.int32(SLIDING)
        if wp.length(tangential(velocity, normal)) <= rest_speed and held(normal, gravity, rolling_resistance):
            return wp.int32(REST)
        _a, _w, friction = rolling_rates(
            velocity, normal, applied, spin_rate_air, radius, inertia_factor, rolling_resistance, ploughing
        )
        if friction > mu_s * load:
            return wp.int32(SLIDING)
        return wp.int32(ROLLING)

    @wp.func
    def separation_speed(load: scalar, radius: scalar):
        """sqrt(2 R N/m): the normal speed that lifts the pellet one radius against the load."""
        return wp.sqrt(scalar(2.0) * radius * load)

    @wp.func
    def separates(rebound_normal_speed: scalar, load: scalar, radius: scalar):
        """Whether a rebound leaves the plane (1) or the pellet stays on it (0)."""
        leaves = rebound_normal_speed > separation_speed(load, radius)
        if load <= ZERO:
            leaves = rebound_normal_speed >= ZERO
        if leaves:
            return wp.int32(1)
        return wp.int32(0)

    return SimpleNamespace(
        tangential=tangential,
        unit=unit,
        normal_load=normal_load,
        plough=plough,
        slip_velocity=slip_velocity,
        sliding_rates=sliding_rates,
        rolling_rates=rolling_rates,
        held=held,
        surface_mode=surface_mode,
        separation_speed=separation_speed,
        separates=separates,
    )


@functools.cache
def make_surface_closed_forms(precision: str) -> SimpleNamespace:
    """The closed forms in vacuum (docs/ground.md 6) of one precision, on `make_surface_laws`."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    TOLERANCE = scalar(ROUNDING * EPSILON[precision])
    ZERO = scalar(0.0)
    ONE = scalar(1.0)
    laws = make_surface_laws(precision)
    tangential, unit, normal_load, slip_velocity = laws.tangential, laws.unit, laws.normal_load, laws.slip_velocity
    sliding_rates, rolling_rates, surface_mode, held = laws.sliding_rates, laws.rolling_rates, laws.surface_mode, laws.held

    @wp.func
    def across(drive: vec3, direction: vec3, scale: scalar):
        """Whether `drive` has a part across the unit `direction` above the rounding of `scale` (1) or not (0)."""
        along = wp.dot(drive, direction)
        if wp.length(drive - along * direction) > TOLERANCE * scale:
            return wp.int32(1)
        return wp.int32(0)

    @wp.func
    def slide_end(velocity: vec3, spin: vec3, normal: vec3, gravity: vec3, radius: scalar, inertia_factor: scalar, mu_d: scalar):
        """(time until the slip vanishes, or NEVER; exact): in vacuum |s| changes at
        g_t . s/|s| - (1 + 1/k) mu_d N/m, constant when g_t is along s (exact = 1)."""
        slip = slip_velocity(velocity, spin, normal, radius)
        slip_speed = wp.length(slip)
        drive = tangential(gravity, normal)
        direction = unit(slip)
        if slip_speed <= ZERO:  # no slip: it grows along the drive, if at all
            direction = unit(drive)
        exact = ONE - scalar(across(drive, direction, wp.length(gravity)))
        rate = wp.dot(drive, direction) - (ONE + ONE / inertia_factor) * mu_d * normal_load(normal, gravity)
        if rate >= ZERO:
            return scalar(NEVER), exact
        return slip_speed / (-rate), exact

    @wp.func
    def roll_end(
        velocity: vec3, normal: vec3, gravity: vec3, inertia_factor: scalar, rolling_resistance: scalar, rest_speed: scalar
    ):
        """(time, ends at rest, exact) of a rolling phase in vacuum: until the speed falls to
        rest_speed where the resistance can hold the pellet, else to 0 (it then rolls back), or
        NEVER. Its speed changes at (g_t . v/|v| - c N/m) / (1 + k), constant when g_t is along v;
        v across g_t keeps a part across it, so never stops (exact only for c = 0: dv/dt = g_t/(1+k))."""
        load = normal_load(normal, gravity)
        drive = tangential(gravity, normal)
        holds = held(normal, gravity, rolling_resistance)
        speed = wp.length(tangential(velocity, normal))
        if speed <= rest_speed and holds:
            return ZERO, wp.int32(1), ONE
        if speed <= ZERO:  # from rest, not held: rolls down the slope, faster and faster
            return scalar(NEVER), wp.int32(0), ONE
        direction = unit(tangential(velocity, normal))
        if across(drive, direction, wp.length(gravity)) == 1:  # v across the drive line: never stops
            if rolling_resistance > ZERO:  # the resistance turns with v: no closed form
                return scalar(NEVER), wp.int32(0), ZERO
            return scalar(NEVER), wp.int32(0), ONE  # c = 0: dv/dt = 5/7 g_t, constant, for ever
        exact = ONE
        rate = (wp.dot(drive, direction) - rolling_resistance * load) / (ONE + inertia_factor)
        if rate >= ZERO:
            return scalar(NEVER), wp.int32(0), exact
        if holds:
            return (speed - rest_speed) / (-rate), wp.int32(1), exact
        return speed / (-rate), wp.int32(0), exact

    @wp.func
    def asinh(x: scalar):
        """asinh(x) for x >= 0 = log1p(x + x^2 / (1 + sqrt(1 + x^2))), log1p by Kahan's
        log(w) y / (w - 1), accurate for small x too (Warp has neither asinh nor log1p)."""
        y = x + x * x / (ONE + wp.sqrt(ONE + x * x))
        w = ONE + y
        if w == ONE:
            return y
        return wp.log(w) * y / (w - ONE)

    @wp.func
    def half_integral(lo: scalar, hi: scalar, q: scalar):
        """The integral of sqrt(u^2 + q^2) over 0 <= lo <= u <= hi:
        (hi s_hi - lo s_lo + q^2 (asinh(hi/q) - asinh(lo/q))) / 2, s = sqrt(u^2 + q^2)."""
        s_lo = wp.sqrt(lo * lo + q * q)
        s_hi = wp.sqrt(hi * hi + q * q)
        width = hi - lo
        product = ZERO  # hi s_hi - lo s_lo = (hi^2 s_hi^2 - lo^2 s_lo^2) / (hi s_hi + lo s_lo)
        if hi > ZERO:
            product = width * (hi + lo) * (hi * hi + lo * lo + q * q) / (hi * s_hi + lo * s_lo)
        logs = ZERO  # asinh(A) - asinh(B) = asinh(A sqrt(1 + B^2) - B sqrt(1 + A^2))
        if q > TOLERANCE * hi:
            logs = q * q * asinh(width * (hi + lo) / (hi * s_lo + lo * s_hi))
        return scalar(0.5) * (product + logs)

    @wp.func
    def arc_length(velocity: vec3, acceleration: vec3, duration: scalar):
        """Length of the path x(t) = v t + a t^2 / 2 over [0, duration]: the integral of
        |v + a t| = |a| sqrt(u^2 + q^2), u = t + v.a/|a|^2, q = |v x a| / |a|^2, written without
        cancellation (split where the speed is least; differences of u s(u) and asinh in product form)."""
        a = wp.length(acceleration)
        if a <= ZERO or duration <= ZERO:
            return wp.length(velocity) * duration
        u0 = wp.dot(velocity, acceleration) / (a * a)
        q = wp.length(wp.cross(velocity, acceleration)) / (a * a)
        u1 = u0 + duration
        total = ZERO
        if u0 < ZERO and u1 > ZERO:  # the speed is least at u = 0: two pieces from there
            total = half_integral(ZERO, -u0, q) + half_integral(ZERO, u1, q)
        elif u1 <= ZERO:
            total = half_integral(-u1, -u0, q)
        else:
            total = half_integral(u0, u1, q)
        return a * total

    @wp.func
    def follow_on_plane(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        normal: vec3,
        gravity: vec3,
        radius: scalar,
        inertia_factor: scalar,
        mu_s: scalar,
        mu_d: scalar,
        rolling_resistance: scalar,
        rest_speed: scalar,
    ):
        """Chain the closed forms in vacuum from a pellet on the plane (normal speed 0).

        Returns (position, velocity, spin, elapsed s, path length m, mode, exact): mode REST or
        FLIGHT: the pellet ends so (at REST v = 0 and the spin keeps only its part along n); SLIDING or ROLLING with exact = 1: it moves on for ever (a
        slope too steep to stop on); exact = 0: the phase `mode` has a drive across its friction
        (no closed form): the state is where it begins."""
        elapsed = ZERO
        path = ZERO
        zero = vec3()
        for _phase in range(MAX_PHASES):
            mode = surface_mode(
                velocity, spin, normal, gravity, zero, gravity, radius, inertia_factor, mu_s, rolling_resistance, ZERO, rest_speed
            )
            if mode == REST:  # at rest: no velocity, no rolling spin (docs/ground.md 4)
                return position, vec3(), wp.dot(spin, normal) * normal, elapsed, path, mode, wp.int32(1)
            if mode == FLIGHT:
                return position, velocity, spin, elapsed, path, mode, wp.int32(1)
            duration = ZERO
            exact = ONE
            at_rest = wp.int32(0)
            acceleration = vec3()
            spin_rate = vec3()
            if mode == SLIDING:
                duration, exact = slide_end(velocity, spin, normal, gravity, radius, inertia_factor, mu_d)
                acceleration, spin_rate = sliding_rates(velocity, spin, normal, gravity, zero, radius, inertia_factor, mu_d, ZERO)
            else:
                duration, at_rest, exact = roll_end(velocity, normal, gravity, inertia_factor, rolling_resistance, rest_speed)
                acceleration, spin_rate, _f = rolling_rates(
                    velocity, normal, gravity, zero, radius, inertia_factor, rolling_resistance, ZERO
                )
            if exact < ONE or duration < ZERO:
                return position, velocity, spin, elapsed, path, mode, wp.int32(exact)
            path += arc_length(velocity, acceleration, duration)
            position = position + velocity * duration + (scalar(0.5) * duration * duration) * acceleration
            velocity = velocity + acceleration * duration
            spin = spin + spin_rate * duration
            elapsed += duration
            if mode == SLIDING:  # the slip is zero now: remove its rounding (omega_t = n x v / R)
                spin = wp.dot(spin, normal) * normal + wp.cross(normal, velocity) * (ONE / radius)
            elif at_rest == 1:
                return position, vec3(), wp.dot(spin, normal) * normal, elapsed, path, wp.int32(REST), wp.int32(1)
            else:  # stopped on a slope it cannot rest on: it rolls back from rest
                velocity = vec3()
                spin = wp.dot(spin, normal) * normal
        return position, velocity, spin, elapsed, path, wp.int32(ROLLING), wp.int32(0)

    return SimpleNamespace(
        across=across, slide_end=slide_end, roll_end=roll_end, arc_length=arc_length, follow_on_plane=follow_on_plane
    )


def make_surface_motion(precision: str) -> SimpleNamespace:
    """Every surface-motion `@wp.func` of one precision: the laws and the closed forms."""
    return SimpleNamespace(**vars(make_surface_laws(precision)), **vars(make_surface_closed_forms(precision)))
