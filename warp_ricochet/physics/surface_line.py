"""A sliding or rolling phase along a plane, integrated over the distance around the closed form
of the Riccati law v' = -(A + B v^2) along the velocity, as `@wp.func`s for `surface_follow`
(docs/ground.md 9).

A phase is taken so (`line_of`) on a level plane, or on a slope with the velocity along its fall
line, without wind across it: the drive g . l and the wind across e (l = n x e, e the velocity's
direction) at most LINE x the tolerance of their scales. A slip across e and a spin about n up to
that bound are dropped too (`straight`: along one line, as the paper's symmetric scene); larger ones
(what rough ground leaves after an impact on a tilted facet, docs/ground.md 11) are followed: each step
starts from a frame (n, e_n, l_n) at its start, and the state y = (Z, t, s, psi, X, Y, omega) holds,
beside the speed's departure Z below, the heading psi (e = cos psi e_n + sin psi l_n), the
position's shortfall X along e_n and its offset Y along l_n, and the spin omega (3-D; rolling, only
its part along n: the rest is n x v / R), with

    dpsi/ds = a_l / v^2,  dX/ds = cos psi - 1,  dY/ds = sin psi,  domega/ds = (domega/dt) / v,

a_l the acceleration across e. Built not `rough` (a scene without rough ground: `spec.RunSpec.rough`),
only straight phases are taken (`line_of` hands the others to 3-D): y = (Z, t, s, omega), the laws
along e as scalars (`along`), the frame kept: the same steps to rounding, at less cost. The laws are `surface_motion`'s (docs/ground.md 2-3 and 8), the
friction -mu_d N/m along the slip v e - R omega x n (or, where a stage's slip has turned past its
direction at the step's start, along that). Along e, D = -dv/dt:

    D = -a_e + b |v| v + mu_d N/m u . e   (sliding, u the friction's direction)
    D = -(a_e - c N/m - b |v| v + k R alpha . l) / (1 + k)   (rolling; + the part of the drive across e in a_l)

(a = g + a_air, N/m = -a . n, alpha = T_air / I). Over the distance dE/ds = -2 D, dt/ds = 1 / v. Ploughing and quadratic drag make D nearly A + B E, in which E is linear: each step
freezes D = D_n + B (E - E_n) + G s (D_n at its start; rolling, B the secant of the last step, the
first between v / 2 and v, G = 0; sliding, B that secant at the step's spin and G the drift of D
with the spin over the last step), whose solution, written without cancellation, is

    E_ref(s) = E_n - 2 s (D_n phi1(-2 B s) + G s phi2(-2 B s))   (phi1 = (e^x - 1)/x, phi2 = (phi1 - 1)/x;
                                                                  beyond 2 B s = 1, E* + (E_n - E*) e^(-2 B s)
                                                                  - 2 G s^2 phi2, E* = -A / B),
    E_ref(s) = 2 A d phi1(2 B d),  d = s* - s                   (A = D_n - B E_n > 0, then G = 0: s* the
                                                                  frozen stop, E_n / (2 A) L(B E_n / A),
                                                                  L(x) = log1p(x) / x),

and integrates only the departure Z = (E - E_ref) exp(2 B s), dZ/ds = -2 (D - D_ref(E, s)) exp(2 B s)
(Lawson's integrating factor on the remainder), with the rest of y, by the Dormand-Prince 5(4) pair:
exact (to rounding) where A and B are constant (vacuum), a few steps per e-fold of the speed in air
(the drag's Reynolds and Mach dependence and the lift's share of N are what is integrated). The
position is x_n + (s + X) e_n + Y l_n (on a line, X = Y = 0: exact); the heading turns by at most
MAX_TURN a step (its sin and cos by series). The time of a decelerating step (A > 0) is the frozen law's,
t = tau G(A B tau^2), tau = (v_n - v) / (A + B v_n v), G(z) = atan(sqrt z) / sqrt z, plus the
integral of 1/v - 1/v_ref; otherwise the integral of 1/v. Events: another surface on the line at a
known distance (a cap on the step); the speed's goal (rolling: the frozen law's distance to it) and
the slip's zero (sliding: Illinois on the frozen law's v and t when A > 0, else Newton's linear aim),
aimed at (off the line SHORT of it), and finished to first order within BAND x the tolerance (a
slip off the line within the tolerance: below the integration's own error its direction is noise);
lift-off and loss of grip by
Illinois on re-steps. A slide whose speed falls below a tenth of sqrt(g R) (it would reverse) is
handed back (HANDOVER) to the 3-D integrator, and so is a step that curves onto another surface.
Plates, meshes and posts (other than the plane the pellet is on) are kept off by the step: no step
is longer than their least clearance less R (`line_ahead.free_of`: then no path of the step can touch
them), and a phase that comes nearer to one than a quarter of its step goes on in 3-D (HANDOVER), where the
contact is found.

Approximate maths (CUDA fast_math: __expf, __logf, approximate division and sqrt): no sin, cos or
tan (the heading's by series); exp only of arguments within [-MAX_DECAY, MAX_DECAY]; log1p, phi1, phi2, L and G by series where
their direct forms cancel (|x| <= 1/2, phi2 |x| <= 1, z <= 1/4) and by exp, log and atan (not an intrinsic) elsewhere; the
stop's E from the distance left to the frozen stop; no division by a quantity that can reach 0
or a denormal (A only where it exceeds the rounding of D_n, v only through max(v, sqrt(g R) / 10),
exp(2 B s) >= 1; `make_line_maths` lists each form's error). `make_line_maths(precision, noise)` perturbs exp, log, sqrt and atan by
`noise` = (relative, absolute) for the tests.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .air import make_air_laws
from .ballistic import EPSILON, ROUNDING
from .inlining import out_of_line_if
from .integrate import make_dormand_prince
from .line_ahead import make_line_ahead
from .line_maths import make_line_maths
from .surface_motion import make_surface_motion
from .types import types_for

LINE = 10.0  # a drive or wind across e up to LINE x the tolerance of its scale is dropped (docstring)
MAX_DECAY = 16.0  # 2 B h of a step at most: exp(+-16) stays far from overflow and denormals
HANDOVER = 7  # integrate_line's event: go on in 3-D (surface_follow.integrate_phase) from here
LANDINGS = 12  # re-steps onto a margin's root (lift-off, loss of grip) at most
BAND = 0.1  # events end within BAND x the tolerance of their scale (surface_follow's)
# a slide off the line aims at SHORT x the linear distance to the slip's zero: near it the slip's
# direction relaxes at about 7/2 mu_d N / |s| (stiff), and a step aimed at the zero is rejected
# (turf: 80.4 steps a pellet aimed at 1, 62.3 at 1/2, 58.2 at 0.7, 59.3 at 0.8)
SHORT = 0.7
MAX_TURN = 0.25  # rad: the heading turns by at most this in a step (its sin and cos by series)
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

    @out_of_line_if(AIR)
    @wp.func
    def rates(y: state, physics: Physics, line: Line):
        """d/ds of y: Z' = -2 (D - D_ref) exp(2 B s), t' = 1/v (decelerating, less the frozen law's),
        s' = 1, psi' = a_l / v^2, X' = cos psi - 1, Y' = sin psi, omega' = (domega/dt) / v (rolling:
        its part along n; the rest is n x v / R)."""
        energy, v, _w, decel, lateral, dw, _load, _grip = state_at(y, physics, line, ZERO)
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

    stages = make_dormand_prince(precision, rates, Line, True, state, out_of_line=AIR).stages

    return SimpleNamespace(
        state=state,
        spin_in=spin_in,
        moved=moved,
        start=start,
        psi_of=psi_of,
        state_at=state_at,
        rates=rates,
        stages=stages,
    )


@functools.cache
def make_surface_line(
    precision: str,
    planes=None,
    model: str = "ballistic",
    laws=None,
    watch: tuple = (0, 0, False),
    noise: tuple = (0.0, 0.0),
    rough=True,
    plates=False,
) -> SimpleNamespace:
    """The helpers of `integrate_line` (module docstring), each accepted step given to
    `tallies.path`'s watch of `watch`; not `rough`, for straight phases only; `plates`: the
    surfaces may hold plates, meshes and posts (`geometry.make_geometry`), kept at `line_ahead.free_of`."""
    from ..tallies.path import make_path_watch  # (tallies imports physics: not at the top)

    watcher = make_path_watch(precision, *watch)
    Track, Tally = watcher.Track, watcher.Tally
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    ahead = make_line_ahead(precision, planes, plates)
    ll, st = make_line_laws(precision, model, laws, noise, rough), make_line_steps(precision, model, laws, noise, rough)
    ROUGH = rough
    Line, m, state, state_at, stages = ll.Line, ll.maths, st.state, st.state_at, st.stages
    reference, frozen_time = ll.reference, ll.frozen_time
    ZERO, ONE, TWO, HALF = scalar(0.0), scalar(1.0), scalar(2.0), scalar(0.5)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))

    @wp.func
    def first_slope(v: scalar, spin: vec3, dv: scalar, physics: Physics, line: Line):
        """B of the first step: the secant of D between v / 2 and v (0 at v = 0)."""
        half_dv, _dl, _dw, _load, _grip = ll.along(HALF * v, ZERO, spin, physics, line, ZERO)
        if v <= line.least:
            return ZERO
        return (half_dv - dv) / (scalar(0.75) * v * v)

    @wp.func
    def target(v: scalar, e: vec3, lateral: vec3, spin: vec3, decel: scalar, dl: scalar, dw: vec3, line: Line, radius: scalar, goal: scalar):  # fmt: skip
        """(q, dq/ds) of what ends the phase at q = 0: rolling, v - goal; sliding, the slip
        v e - R omega x n along its direction at the step's start (`line.slip`)."""
        slow = ONE / wp.max(v, line.least)
        if line.rolling != 0:
            return v - goal, -decel * slow
        slip = v * e - radius * wp.cross(spin, line.normal)
        rate = -decel * e + dl * lateral - radius * wp.cross(dw, line.normal)
        return wp.dot(slip, line.slip), wp.dot(rate, line.slip) * slow

    @wp.func
    def step_error(e0: scalar, e1: scalar, v1: scalar, w0: vec3, w1: vec3, error: state, h: scalar, line: Line, tolerance: scalar, floor: scalar, radius: scalar):  # fmt: skip
        """The step's error over tolerance: E's (Z's over exp(2 B h)) over max(E) + floor^2; the
        heading's over 1 + floor / v (a velocity's direction, as the 3-D integrator's); X's and
        Y's over h + R; omega's over |omega| + floor / R. The distance s is exact; t does not feed back."""
        out = wp.abs(error[0]) / m.exp(TWO * line.slope * h) / (tolerance * (wp.max(e0, e1) + floor * floor))
        spin_error = ZERO
        if wp.static(not ROUGH):
            spin_error = wp.length(vec3(error[3], error[4], error[5]))
        else:
            out = wp.max(out, wp.abs(error[3]) / (tolerance * (ONE + floor / wp.max(v1, line.least))))
            out = wp.max(out, wp.max(wp.abs(error[4]), wp.abs(error[5])) / (tolerance * (h + radius)))
            spin_error = wp.length(vec3(error[6], error[7], error[8]))
        return wp.max(out, spin_error / (tolerance * (wp.max(wp.length(w0), wp.length(w1)) + floor / radius)))

    @wp.func
    def step_time(v0: scalar, h: scalar, integrated: scalar, line: Line):
        """The step's time: decelerating (A > 0), the frozen law's to its speed at h plus the
        integrated difference; else the integrated time."""
        if line.stops != 0:
            return frozen_time(v0, m.sqrt(reference(h, line)), line) + integrated
        return integrated

    @wp.func
    def watch_step(track: Track, tally: Tally, x0: vec3, x1: vec3, line: Line, h: scalar, dt: scalar, v0: scalar, v1: scalar, d1: scalar):  # fmt: skip
        """Give the step (path h from x0 to x1) to the watch: along its chord, under the frozen law
        (A, B > 0), else the time Hermite of its ends (not `rough`: the chord is along e)."""
        e = line.direction
        if wp.static(ROUGH):
            e = x1 - x0
            if wp.length(e) > ZERO:
                e = e * (ONE / wp.length(e))
        if line.stops != 0 and line.slope > ZERO:
            return watcher.line(track, tally, x0, e, h, v0, line.offset, line.slope)
        d0 = (dt * v0) * e
        e0 = (-dt * dt * line.decel) * e
        e1 = (-dt * dt * d1) * e
        return watcher.segment(track, tally, x0, d0, e0, x1, (dt * v1) * e, e1, dt, ONE)

    @wp.func
    def land_margin(h: scalar, m0: scalar, m1: scalar, y0: state, f0: state, physics: Physics, line: Line, mu_s: scalar):
        """(length, y there, re-steps) of a step onto the margin's root (N or the grip left falls
        to 0 inside [0, h]: m0 > 0 >= m1): Illinois on the step's length, the end where m <= 0."""
        lo = ZERO
        hi = h
        m_lo = m0
        m_hi = m1
        side = wp.int32(0)
        taken = wp.int32(0)
        y_hi, _f, _x = stages(y0, f0, h, physics, line)
        tiny = STOP_FRACTION * wp.length(physics.gravity)
        for _ in range(LANDINGS):
            if hi - lo > STOP_FRACTION * (hi + physics.radius) and -m_hi > tiny:
                mid = m.secant(lo, hi, m_lo, m_hi)
                y, _f2, _x2 = stages(y0, f0, mid, physics, line)
                taken += 1
                _e, _v, _w, _dc, _dl, _dw, load, grip = state_at(y, physics, line, mu_s)
                lo, hi, m_lo, m_hi, side = m.illinois(lo, hi, m_lo, m_hi, side, mid, wp.min(load, grip))
                if hi == mid:
                    y_hi = y
        return hi, y_hi, taken

    @wp.func
    def spin_of(v: scalar, spin: vec3, line: Line, radius: scalar):
        """The spin at speed v along e (rolling: n x v / R and the part along n)."""
        if line.rolling != 0:
            return wp.cross(line.normal, v * line.direction) * (ONE / radius) + wp.dot(spin, line.normal) * line.normal
        return spin

    @wp.func
    def first_rates(v: scalar, dl: scalar, dw: vec3, line: Line):
        """The state's rates at the step's start (y = 0 but omega; no remainder; decelerating, no
        time beyond the frozen law's)."""
        slow = ONE / wp.max(v, line.least)
        late = slow
        if line.stops != 0:
            late = ZERO
        if line.straight != 0:
            dl = ZERO
        if line.rolling != 0:
            dw = wp.dot(dw, line.normal) * line.normal
        dw = dw * slow
        if wp.static(not ROUGH):
            return state(ZERO, late, ONE, dw[0], dw[1], dw[2])
        else:
            return state(ZERO, late, ONE, dl * slow * slow, ZERO, ZERO, dw[0], dw[1], dw[2])

    return SimpleNamespace(
        Line=Line,
        line_of=ll.line_of,
        along=ll.along,
        heading=ll.heading,
        freeze=ll.freeze,
        reach=ll.reach,
        reference=ll.reference,
        frozen_time=ll.frozen_time,
        ahead_of=ahead.ahead_of,
        capped=ahead.capped,
        first_slope=first_slope,
        target=target,
        step_error=step_error,
        step_time=step_time,
        watch_step=watch_step,
        land_margin=land_margin,
        spin_of=spin_of,
        first_rates=first_rates,
        state=state,
        state_at=state_at,
        moved=st.moved,
        start=st.start,
        psi_of=st.psi_of,
        stages=stages,
        maths=m,
        Track=Track,
        Tally=Tally,
    )


@functools.cache
def make_line_integrator(
    precision: str,
    planes=None,
    model: str = "ballistic",
    laws=None,
    watch: tuple = (0, 0, False),
    noise: tuple = (0.0, 0.0),
    rough=True,
    plates=False,
) -> SimpleNamespace:
    """`integrate_line`: `surface_follow`'s integrate_phase for a phase over the distance (module
    docstring); not `rough`, straight phases only (`line_of` refuses the rest), with the heading
    and the offset compiled away; `plates`: steps kept within `line_ahead.free_of` (module docstring)."""
    sl = make_surface_line(precision, planes, model, laws, watch, noise, rough, plates)
    ROUGH = rough
    m, Line, Track, Tally = sl.maths, sl.Line, sl.Track, sl.Tally
    along, heading, freeze, reach, stages, state_at = sl.along, sl.heading, sl.freeze, sl.reach, sl.stages, sl.state_at
    ahead_of, capped, target, step_error, step_time, watch_step, land_margin = (
        sl.ahead_of, sl.capped, sl.target, sl.step_error, sl.step_time, sl.watch_step, sl.land_margin
    )  # fmt: skip
    first_slope = sl.first_slope
    spin_of, first_rates, start, moved, psi_of = sl.spin_of, sl.first_rates, sl.start, sl.moved, sl.psi_of
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    ZERO, ONE, TWO, HALF = scalar(0.0), scalar(1.0), scalar(2.0), scalar(0.5)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))
    FAR = scalar(1e30)
    reference, frozen_time = sl.reference, sl.frozen_time
    AIMS = 40 if precision == "float64" else 30
    CONTACT, UNFINISHED = 4, 6  # surface_follow's end codes (it imports this module)

    @wp.func
    def slip_ahead(s: scalar, v: scalar, spin: vec3, dwdt: vec3, line: Line, radius: scalar):
        """The slip along `line.slip` at s under the frozen law (A > 0): v from E_ref, omega + domega/dt t."""
        v1 = m.sqrt(reference(s, line))
        turned = spin + dwdt * frozen_time(v, v1, line)
        return wp.dot(v1 * line.direction - radius * wp.cross(turned, line.normal), line.slip)

    @wp.func
    def slide_aim(v: scalar, spin: vec3, dwdt: vec3, q: scalar, goal: scalar, line: Line, radius: scalar):
        """Where the slip falls to `goal` under the frozen law (A > 0; exact in vacuum), by Illinois
        on [0, s*], or -1 if not before the stop (Newton's linear aim would creep along v's decay)."""
        lo = ZERO
        hi = line.stop
        f_lo = q - goal
        f_hi = slip_ahead(hi, v, spin, dwdt, line, radius) - goal
        if f_hi > ZERO:
            return scalar(-1.0)
        side = wp.int32(0)
        for _ in range(AIMS):
            if hi - lo > STOP_FRACTION * hi:
                mid = m.secant(lo, hi, f_lo, f_hi)
                f = slip_ahead(mid, v, spin, dwdt, line, radius) - goal
                lo, hi, f_lo, f_hi, side = m.illinois(lo, hi, f_lo, f_hi, side, mid, f)
        return lo

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
        track: Track,
        tally: Tally,
    ):
        """One phase over the distance to its target (`target`: goal speed rolling, zero slip
        sliding), its margin (lift-off, loss of grip), another surface or HANDOVER: (x, v, omega,
        elapsed, path, event, k_next, steps, track), event 0, 1, 4 (CONTACT), 6 (UNFINISHED) or HANDOVER."""
        radius, n = physics.radius, line.normal
        floor = wp.sqrt(wp.length(physics.gravity) * radius) + scalar(1e-6)
        band = wp.max(STOP_FRACTION, scalar(BAND) * tolerance)
        v = wp.dot(velocity, line.direction)
        energy = v * v
        dv, dl, dw, load, grip = along(v, ZERO, spin, physics, line, mu_s)
        slope = first_slope(v, spin, dv, physics, line)
        drift = ZERO
        s = ZERO
        elapsed = ZERO
        steps = wp.int32(0)
        event = wp.int32(UNFINISHED)
        k_next = k
        h = FAR
        growth = scalar(5.0)
        while steps < steps_left:
            e = line.direction
            spin = spin_of(v, spin, line, radius)
            decel = -dv
            scale = v + radius * wp.length(spin) + floor
            if line.rolling == 0:  # sliding: the friction's side from the slip now; B at this omega, G from the last step
                slip = v * e - radius * wp.cross(spin, n)
                if line.straight == 0 and wp.length(slip) > STOP_FRACTION * scale:
                    line.slip = slip * (ONE / wp.length(slip))
                if steps > 0:
                    slope = first_slope(v, spin, dv, physics, line)
            line = freeze(line, energy, decel, slope, drift)
            slow = ONE / wp.max(v, line.least)
            ahead, k_ahead = ahead_of(position, k, surfaces, physics, e)
            if ahead <= ZERO:
                event = wp.int32(CONTACT)
                k_next = k_ahead
                break
            if line.rolling == 0 and v < line.least:
                event = wp.int32(HANDOVER)
                break
            q, rate = target(v, e, line.lateral, spin, decel, dl, dw, line, radius, goal)
            finish = band
            if line.rolling == 0 and wp.abs(wp.dot(line.slip, line.lateral)) > STOP_FRACTION:
                finish = wp.max(band, tolerance)  # off the line, a slip below the integration's own error is zero
            if rate < ZERO and q <= finish * scale:  # the rest of the way to first order
                ds = q / (-rate)
                dt = ds * slow
                track = watch_step(track, tally, position, position + ds * e, line, ds, dt, v, v - decel * dt, decel)
                position = position + ds * e
                s += ds
                elapsed += dt
                spin = spin + dw * dt
                v = wp.max(v - decel * dt, ZERO)
                if line.rolling != 0:
                    v = goal
                event = wp.int32(0)
                break
            if h >= FAR:
                h = (
                    HALF
                    * (energy + floor * floor)
                    / (TWO * wp.abs(decel) + TWO * line.slope * energy + floor * floor * scalar(1e-3))
                )
            if line.slope > ZERO:
                h = wp.min(h, scalar(MAX_DECAY) / (TWO * line.slope))
            if line.rolling != 0:
                aim = reach((goal + HALF * band * scale) * (goal + HALF * band * scale), line)
                if aim > ZERO:
                    h = wp.min(h, aim)
            elif rate < ZERO:
                aim = (q - HALF * band * scale) / (-rate)
                if line.stops != 0:
                    ahead_aim = slide_aim(v, spin, dw, q, HALF * band * scale, line, radius)
                    if ahead_aim > ZERO:
                        aim = ahead_aim
                if wp.abs(wp.dot(line.slip, line.lateral)) > STOP_FRACTION:  # off the line: short of it (below)
                    aim = scalar(SHORT) * aim
                h = wp.min(h, aim)
            h, near = capped(position, k, surfaces, physics, h)  # a plate, mesh or post near: 3-D meets it
            if near:
                event = wp.int32(HANDOVER)
                break
            to_contact = False
            if h >= ahead:
                h = ahead
                to_contact = True
            y0 = start(spin)
            f0 = first_rates(v, dl, dw, line)
            y1, _f1, error_vector = stages(y0, f0, h, physics, line)
            steps += 1
            e1, v1, w1, dec1, dl1, dw1, load1, grip1 = state_at(y1, physics, line, mu_s)
            error = step_error(energy, e1, v1, spin, w1, error_vector, h, line, tolerance, floor, radius)
            dt = step_time(v, h, y1[1], line)
            head1, lateral1 = heading(psi_of(y1), line)
            if not (error <= ONE):
                h = h * wp.clamp(scalar(0.9) * wp.pow(error, scalar(-0.2)), scalar(0.2), ONE)
                growth = ONE
                continue
            if wp.abs(psi_of(y1)) > scalar(MAX_TURN):  # turned too far for the series: a shorter step
                h = HALF * h
                growth = ONE
                continue
            q1, _rate1 = target(v1, head1, lateral1, w1, dec1, dl1, dw1, line, radius, goal)
            if e1 < ZERO or (q1 < ZERO and q > ZERO):  # past the target: aim short of it
                h = HALF * h
                growth = ONE
                continue
            margin1 = wp.min(load1, grip1)
            if margin1 <= ZERO:  # lift-off or loss of grip inside: onto its root
                h, y1, taken = land_margin(h, wp.min(load, grip), margin1, y0, f0, physics, line, mu_s)
                steps += taken
                e1, v1, w1, dec1, dl1, dw1, load1, grip1 = state_at(y1, physics, line, mu_s)
                head1, lateral1 = heading(psi_of(y1), line)
                dt = step_time(v, h, y1[1], line)
                event = wp.int32(1)
                to_contact = False
            x1 = moved(position, y1, line)
            if wp.static(ROUGH):
                if not to_contact:  # curved onto another surface: the 3-D integrator finds where
                    after, _k = ahead_of(x1, k, surfaces, physics, head1)
                    if after <= ZERO:
                        event = wp.int32(HANDOVER)
                        break
            track = watch_step(track, tally, position, x1, line, h, dt, v, v1, dec1)
            position = x1
            s += h
            elapsed += dt
            if line.rolling == 0 and h > STOP_FRACTION * (s + radius):
                drift = (dec1 - decel - line.slope * (e1 - energy)) / h
            elif wp.abs(e1 - energy) > scalar(0.05) * energy:
                slope = (dec1 - decel) / (e1 - energy)
            if wp.static(ROUGH):  # the next step's frame (not rough: the line's)
                line.direction = head1 * (ONE / wp.length(head1))
                line.lateral = wp.cross(n, line.direction)
            energy = e1
            v = v1
            spin = w1
            dv = -dec1
            dl = dl1
            dw = dw1
            load = load1
            grip = grip1
            if event == 1:
                break
            if to_contact:
                event = wp.int32(CONTACT)
                k_next = k_ahead
                break
            h = h * wp.clamp(scalar(0.9) * wp.pow(wp.max(error, scalar(1e-10)), scalar(-0.2)), scalar(0.2), growth)
            growth = scalar(5.0)
        return position, v * line.direction, spin_of(v, spin, line, radius), elapsed, s, event, k_next, steps, track

    return SimpleNamespace(Line=Line, line_of=sl.line_of, integrate_line=integrate_line)
