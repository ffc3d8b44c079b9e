"""The laws of a phase along one line of a plane (`make_line_laws`: the `Line`, the laws along it,
the frozen law, `line_of`) and its state over the distance with its Dormand-Prince step
(`make_line_steps`), for `surface_line`, whose module docstring says what they compute and why
(docs/ground.md 9). SI units."""

import functools
from types import SimpleNamespace

import warp as wp

from .air import make_air_laws
from .ballistic import EPSILON, ROUNDING
from .inlining import out_of_line_if
from .integrate import make_dormand_prince
from .line_maths import make_line_maths
from .surface_motion import make_surface_motion
from .types import types_for

LINE = 10.0  # a drive or wind across e up to LINE x the tolerance of its scale is dropped (surface_line)
STATE, STRAIGHT = 9, 6  # (Z, t, s, psi, X, Y, omega), not rough (Z, t, s, omega): make_line_steps


@functools.cache
def make_line_laws(
    precision: str, model: str = "ballistic", laws=None, noise: tuple = (0.0, 0.0), rough: bool = True
) -> SimpleNamespace:
    """The `Line`, the laws along it (`along`), the frozen law (`reference`) and `line_of`; not
    `rough`, only straight phases are taken (the heading compiled away: module docstring)."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    AIR, ROUGH = model == "air", rough
    sm, m = make_surface_motion(precision), make_line_maths(precision, noise)
    air_rates = make_air_laws(precision, *laws).air_rates if AIR else None
    ZERO, ONE, TWO = scalar(0.0), scalar(1.0), scalar(2.0)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))

    @wp.struct
    class Line:
        """A phase on a line: the step's frame (n, e, l = n x e), the slip's direction at the step's
        start (the friction's, where a stage's slip has turned past it), the ground's coefficients,
        the mode; and the step's frozen law: E_n, D_n, B, A = D_n - B E_n, the frozen stop s* (when
        A > 0: `stops` 1)."""

        normal: vec3
        direction: vec3
        lateral: vec3
        slip: vec3
        mu_d: scalar
        rolling_resistance: scalar
        ploughing: scalar
        rolling: wp.int32
        straight: wp.int32
        energy: scalar
        decel: scalar
        slope: scalar
        drift: scalar
        offset: scalar
        stop: scalar
        stops: wp.int32
        least: scalar

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
    def heading(psi: scalar, line: Line):
        """(e, l) turned by psi about n from the step's frame: e = cos psi e_n + sin psi l_n (|psi| <= 1/4;
        not `rough`, psi = 0: the frame)."""
        if wp.static(not ROUGH):
            return line.direction, line.lateral
        c, s = m.turn(psi)
        e = line.direction + c * line.direction + s * line.lateral
        return e, wp.cross(line.normal, e)

    @out_of_line_if(AIR)
    @wp.func
    def along(v: scalar, psi: scalar, spin: vec3, physics: Physics, line: Line, mu_s: scalar):
        """(dv/dt along e, dv/dt along l, domega/dt, N/m, the grip left mu_s N/m - |F|/m rolling or
        N/m sliding) at speed v along e(psi) with spin omega (rolling: omega_t = n x v / R): the laws
        of `surface_motion` (docs/ground.md 2-3, 8), the sliding friction against the slip, or
        against `line.slip` where a stage's slip has turned past it. N/m here is -(g + a_air) . n
        unclipped (< 0: lift-off), the friction's load clipped at 0. Not `rough`, no acceleration across e."""
        radius, k, n = physics.radius, physics.inertia_factor, line.normal
        e, lateral = heading(psi, line)
        velocity = v * e
        if line.rolling != 0:
            spin = wp.cross(n, velocity) * (ONE / radius) + wp.dot(spin, n) * n
        a, alpha = applied(velocity, spin, physics)
        pressed = -wp.dot(a, n)
        load = wp.max(pressed, ZERO)
        if wp.static(not ROUGH):
            if v > ZERO:  # one line: the parts along e as scalars (the rolling friction F/m = held e)
                drive = wp.dot(a, e) - line.ploughing * v * v
                if line.rolling != 0:
                    resisted = drive - line.rolling_resistance * load
                    dv = (resisted + k * radius * wp.dot(alpha, lateral)) / (ONE + k)
                    held = dv - resisted
                    return dv, ZERO, alpha - (held / (k * radius)) * lateral, pressed, mu_s * load - wp.abs(held)
                slid = -(line.mu_d * load) * line.slip
                return drive + wp.dot(slid, e), ZERO, wp.cross(slid, n) * (ONE / (k * radius)) + alpha, pressed, pressed
        grip = pressed
        acceleration = vec3()
        spin_rate = vec3()
        if line.rolling != 0:
            acceleration, spin_rate, held = sm.rolling_rates(
                velocity, n, a, alpha, radius, k, line.rolling_resistance, line.ploughing
            )
            grip = mu_s * load - held
        else:
            side = line.slip
            slip = sm.slip_velocity(velocity, spin, n, radius)
            if wp.static(ROUGH):
                if wp.dot(slip, side) > ZERO and line.straight == 0:
                    side = sm.unit(slip)
            friction = -(line.mu_d * load) * side
            acceleration = sm.tangential(a, n) + sm.plough(velocity, n, line.ploughing) + friction
            spin_rate = wp.cross(friction, n) * (ONE / (k * radius)) + alpha
        return wp.dot(acceleration, e), wp.dot(acceleration, lateral), spin_rate, pressed, grip

    @wp.func
    def freeze(line: Line, energy: scalar, decel: scalar, slope: scalar, drift: scalar):
        """The step's frozen law D = D_n + B (E - E_n) + G s from (E_n, D_n, B >= 0, G), its A and,
        when A > 0, its stop (then G is taken as 0: the law of a pellet slowing to rest)."""
        line.energy = energy
        line.decel = decel
        line.slope = wp.max(slope, ZERO)
        line.drift = drift
        line.offset = decel - line.slope * energy
        line.stops = wp.int32(0)
        line.stop = ZERO
        if line.offset > STOP_FRACTION * (wp.abs(decel) + line.slope * energy):  # (A/B, E/A finite)
            line.stops = wp.int32(1)
            line.drift = ZERO
            line.stop = energy / (TWO * line.offset) * m.log_ratio(line.slope * energy / line.offset)
        return line

    @wp.func
    def reference(s: scalar, line: Line):
        """E_ref(s) of the frozen law (module docstring): from the stop when A > 0, else from E_n."""
        b = line.slope
        if line.stops != 0:
            d = line.stop - s
            return TWO * line.offset * d * m.phi1(TWO * b * d)
        x = -TWO * b * s
        if x < -ONE:  # far along: from the frozen terminal E* = -A / B, without E_n's cancellation
            terminal = -line.offset / b
            return terminal + (line.energy - terminal) * m.exp(x) - TWO * line.drift * s * s * m.phi2(x)
        return line.energy - TWO * s * (line.decel * m.phi1(x) + line.drift * s * m.phi2(x))

    @wp.func
    def reach(goal2: scalar, line: Line):
        """The frozen law's distance from the step's start to E = goal2 (< E_n), or -1 if it never gets there."""
        b = line.slope
        if line.stops != 0:
            d = goal2 / (TWO * line.offset) * m.log_ratio(b * goal2 / line.offset)
            return wp.max(line.stop - d, ZERO)
        there = line.decel - b * (line.energy - goal2)  # D_ref(goal2)
        if there <= STOP_FRACTION * wp.abs(line.decel) or line.energy <= goal2:
            return scalar(-1.0)
        return (line.energy - goal2) / (TWO * there) * m.log_ratio(b * (line.energy - goal2) / there)

    @wp.func
    def frozen_time(v0: scalar, v1: scalar, line: Line):
        """The frozen law's time from v0 down to v1 (A > 0): tau G(A B tau^2), tau = (v0 - v1) / (A + B v0 v1)."""
        tau = (v0 - v1) / (line.offset + line.slope * v0 * v1)
        return tau * m.atan_ratio(line.offset * line.slope * tau * tau)

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
        """(1 if the phase is taken over the distance (module docstring) else 0, its `Line`)."""
        radius = physics.radius
        line = Line()
        line.normal = normal
        speed0 = wp.length(velocity)
        e = sm.unit(velocity)
        line.direction = e
        line.lateral = wp.cross(normal, e)
        line.mu_d = mu_d
        line.rolling_resistance = rolling_resistance
        line.ploughing = ploughing
        line.rolling = mode_rolling
        g = physics.gravity
        line.least = scalar(0.1) * wp.sqrt(wp.length(g) * radius)
        scale = speed0 + radius * wp.length(spin) + wp.sqrt(wp.length(g) * radius)
        bound = scalar(LINE) * tolerance
        ok = speed0 > ZERO
        across = wp.abs(wp.dot(g, line.lateral))
        ok = ok and across <= bound * rolling_resistance * sm.normal_load(normal, g) + STOP_FRACTION * wp.length(g)
        if wp.static(AIR):
            ok = ok and wp.abs(wp.dot(physics.air.wind, line.lateral)) <= bound * scale
        slip = sm.slip_velocity(velocity, spin, normal, radius)
        line.straight = wp.int32(0)
        if wp.abs(wp.dot(slip, line.lateral)) <= bound * scale and radius * wp.abs(wp.dot(spin, normal)) <= bound * scale:
            line.straight = wp.int32(1)  # within the bound: on one line, the parts across e dropped
            slip = wp.dot(slip, e) * e
        if wp.static(not ROUGH):
            ok = ok and line.straight != 0  # off the line: in 3-D (surface_follow.integrate_phase)
        line.slip = sm.unit(slip)
        if wp.length(slip) <= STOP_FRACTION * scale:  # from none, the slip grows along the drive
            line.slip = e
            dv, _l, _w, _n, _f = along(speed0, ZERO, spin, physics, line, ZERO)
            if dv < ZERO:
                line.slip = -e
        if ok:
            return wp.int32(1), line
        return wp.int32(0), line

    return SimpleNamespace(
        Line=Line,
        maths=m,
        applied=applied,
        heading=heading,
        along=along,
        freeze=freeze,
        reference=reference,
        reach=reach,
        frozen_time=frozen_time,
        line_of=line_of,
    )


@functools.cache
def make_line_steps(
    precision: str, model: str = "ballistic", laws=None, noise: tuple = (0.0, 0.0), rough: bool = True
) -> SimpleNamespace:
    """The state over the distance, y = (Z, t, s, psi, X, Y, omega) (module docstring; not `rough`,
    (Z, t, s, omega): psi = X = Y = 0), its rates, their Dormand-Prince 5(4) step and the state (E,
    v, omega, D, ...) at a step's point."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    ROUGH = rough
    W = 6 if rough else 3  # omega's first component
    state = wp.types.vector(length=STATE if rough else STRAIGHT, dtype=scalar)
    AIR = model == "air"  # (its steps out of line in CUDA code: `physics.inlining`)
    ll = make_line_laws(precision, model, laws, noise, rough)
    Line, along, reference, m = ll.Line, ll.along, ll.reference, ll.maths
    ZERO, ONE, TWO = scalar(0.0), scalar(1.0), scalar(2.0)

    @wp.func
    def spin_in(y: state):
        """omega, the state's last three components."""
        return vec3(y[W], y[W + 1], y[W + 2])

    @wp.func
    def psi_of(y: state):
        """The heading psi (not `rough`: 0)."""
        if wp.static(ROUGH):
            return y[3]
        return ZERO

    @wp.func
    def moved(position: vec3, y: state, line: Line):
        """The position at the step's point: x_n + (s + X) e_n + Y l_n (not `rough`: x_n + s e_n)."""
        if wp.static(ROUGH):
            return position + (y[2] + y[4]) * line.direction + y[5] * line.lateral
        return position + y[2] * line.direction

    @wp.func
    def start(spin: vec3):
        """y at the step's start: 0 but omega = spin."""
        if wp.static(ROUGH):
            return state(ZERO, ZERO, ZERO, ZERO, ZERO, ZERO, spin[0], spin[1], spin[2])
        else:
            return state(ZERO, ZERO, ZERO, spin[0], spin[1], spin[2])

    @out_of_line_if(AIR)
    @wp.func
    def state_at(y: state, physics: Physics, line: Line, mu_s: scalar):
        """(E, v, omega, D, dv/dt along l, domega/dt, N/m, the grip left) at the step's point s = y[2]
        with departure Z = y[0] and heading psi = y[3]."""
        s = y[2]
        energy = reference(s, line) + y[0] / m.exp(TWO * line.slope * s)
        v = m.sqrt(energy)
        spin = spin_in(y)
        dv, dl, dw, load, grip = along(v, psi_of(y), spin, physics, line, mu_s)
        return energy, v, spin, -dv, dl, dw, load, grip

    @wp.struct
    class Point:
        """`state_at`'s values at a step's point with mu_s = 0: E (m^2/s^2), v (m/s), omega (rad/s),
        D and dv/dt along l (m/s^2), domega/dt (rad/s^2), N/m (m/s^2) and the grip left (`grip_at`)."""

        energy: scalar
        v: scalar
        spin: vec3
        decel: scalar
        lateral: scalar
        dw: vec3
        load: scalar
        grip: scalar

    @wp.func
    def point_at(y: state, physics: Physics, line: Line):
        """`state_at(y, physics, line, 0)` as a `Point`."""
        energy, v, spin, decel, lateral, dw, load, grip = state_at(y, physics, line, ZERO)
        p = Point()
        p.energy = energy
        p.v = v
        p.spin = spin
        p.decel = decel
        p.lateral = lateral
        p.dw = dw
        p.load = load
        p.grip = grip
        return p

    @wp.func
    def grip_at(p: Point, line: Line, mu_s: scalar):
        """The grip left at mu_s, bitwise `state_at`'s: rolling, mu_s N/m - |F|/m, where p.grip is
        0 N/m - |F|/m = -|F|/m exactly (and a - b is a + (-b)); sliding, N/m whatever mu_s."""
        if line.rolling != 0:
            return mu_s * p.load + p.grip
        return p.grip

    @wp.func
    def state_of(p: Point, line: Line, mu_s: scalar):
        """`state_at`'s values from a `Point`, the grip left at mu_s (`grip_at`)."""
        return p.energy, p.v, p.spin, p.decel, p.lateral, p.dw, p.load, grip_at(p, line, mu_s)

    @wp.func
    def rates_of(y: state, p: Point, line: Line):
        """d/ds of y: Z' = -2 (D - D_ref) exp(2 B s), t' = 1/v (decelerating, less the frozen law's),
        s' = 1, psi' = a_l / v^2, X' = cos psi - 1, Y' = sin psi, omega' = (domega/dt) / v (rolling:
        its part along n; the rest is n x v / R), from y's `Point` p."""
        energy = p.energy
        v = p.v
        decel = p.decel
        lateral = p.lateral
        dw = p.dw
        if line.straight != 0:
            lateral = ZERO
        remainder = decel - line.decel - line.slope * (energy - line.energy) - line.drift * y[2]
        slow = ONE / wp.max(v, line.least)
        late = slow  # dt/ds; decelerating (A > 0), less the frozen law's (its time is in closed form)
        if line.stops != 0:
            late = slow - ONE / wp.max(m.sqrt(reference(y[2], line)), line.least)
        if line.rolling != 0:
            dw = wp.dot(dw, line.normal) * line.normal
        dw = dw * slow
        decay = -TWO * remainder * m.exp(TWO * line.slope * y[2])
        if wp.static(not ROUGH):
            return state(decay, late, ONE, dw[0], dw[1], dw[2])
        else:
            bend, sway = m.turn(y[3])
            return state(decay, late, ONE, lateral * slow * slow, bend, sway, dw[0], dw[1], dw[2])

    @out_of_line_if(AIR)
    @wp.func
    def rates(y: state, physics: Physics, line: Line):
        """d/ds of y (`rates_of`)."""
        return rates_of(y, point_at(y, physics, line), line)

    @wp.func
    def ends(y: state, physics: Physics, line: Line):
        """d/ds of y and y's `Point`."""
        p = point_at(y, physics, line)
        return rates_of(y, p, line), p

    dp = make_dormand_prince(precision, rates, Line, True, state, ends, out_of_line=AIR)

    return SimpleNamespace(
        state=state,
        spin_in=spin_in,
        moved=moved,
        start=start,
        psi_of=psi_of,
        state_at=state_at,
        rates=rates,
        stages=dp.stages,
        six=dp.six,  # (the stages' shared body: out of line in CUDA code in air)
        stages_at=dp.stages_at,
        Point=Point,
        grip_at=grip_at,
        state_of=state_of,
    )
