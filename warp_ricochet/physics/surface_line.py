"""A sliding or rolling phase along one line of a plane, integrated over distance around the
closed form of the Riccati law v' = -(A + B v^2), as `@wp.func`s for `surface_follow` (docs/ground.md 9).

A phase is on a line when the pellet's velocity v e, the slip, the drive and the spin's lift stay
in the plane of e and the normal n: the slip across e, R omega . n (the Magnus force across e),
the drive g . l and the wind across e (l = n x e) are at most LINE x the tolerance of their scales
(`line_of`). Dropping them moves the rest point by about that fraction of the path, 1e-5 at the
default tolerance. The spin is then w l plus its parts along n and e (kept), the state (s, E = v^2,
w): the distance along e, the speed squared and the spin about l (rolling: w = v / R). Along e,

    dv/dt = a_e - b |v| v - sigma mu_d N/m,  dw/dt = sigma mu_d (N/m) / (k R) + alpha . l   (sliding)
    dv/dt = (a_e - c N/m - b |v| v + k R alpha . l) / (1 + k)                            (rolling)

(a = g + a_air, N/m = -a . n, alpha = T_air / I; `surface_motion`'s laws along e with the friction's
side sigma frozen for the phase). With D = -dv/dt, over the distance dE/ds = -2 D, dw/ds = (dw/dt) / v,
dt/ds = 1 / v. Ploughing and quadratic drag make D nearly A + B E, in which E is linear: each step
freezes D = D_n + B (E - E_n) + G s (D_n at its start; rolling, B the secant of the last step, the
first between v / 2 and v, G = 0; sliding, B that secant at the step's w and G the drift of D with
w over the last step), whose solution, written without cancellation, is

    E_ref(s) = E_n - 2 s (D_n phi1(-2 B s) + G s phi2(-2 B s))   (phi1 = (e^x - 1)/x, phi2 = (phi1 - 1)/x;
                                                                  beyond 2 B s = 1, E* + (E_n - E*) e^(-2 B s)
                                                                  - 2 G s^2 phi2, E* = -A / B),
    E_ref(s) = 2 A d phi1(2 B d),  d = s* - s                   (A = D_n - B E_n > 0, then G = 0: s* the
                                                                  frozen stop, E_n / (2 A) L(B E_n / A),
                                                                  L(x) = log1p(x) / x),

and integrates only the departure Z = (E - E_ref) exp(2 B s), dZ/ds = -2 (D - D_ref(E, s)) exp(2 B s)
(Lawson's integrating factor on the remainder), with w, t and s, by the Dormand-Prince 5(4) pair:
exact (to rounding) where A and B are constant (vacuum), a few steps per e-fold of the speed in air
(the drag's Reynolds and Mach dependence and the lift's share of N are what is integrated). The
position is s itself: exact. The time of a decelerating step (A > 0) is the frozen law's,
t = tau G(A B tau^2), tau = (v_n - v) / (A + B v_n v), G(z) = atan(sqrt z) / sqrt z, plus the
integral of 1/v - 1/v_ref; otherwise the integral of 1/v. Events: another surface on the line at a
known distance (a cap on the step); the speed's goal (rolling: the frozen law's distance to it) and
the slip's zero (sliding: Illinois on the frozen law's v and t when A > 0, else Newton's linear aim),
aimed at, and finished to first order within BAND x the tolerance; lift-off and loss of grip by
Illinois on re-steps. A slide whose speed falls below a tenth of sqrt(g R) (it would reverse) is
handed back (HANDOVER) to the 3-D integrator.

Approximate maths (CUDA fast_math: __expf, __logf, approximate division and sqrt): no sin, cos or
tan; exp only of arguments within [-MAX_DECAY, MAX_DECAY]; log1p, phi1, phi2, L and G by series where
their direct forms cancel (|x| <= 1/2, phi2 |x| <= 1, z <= 1/4) and by exp, log and atan (not an intrinsic) elsewhere; the
stop's E from the distance left to the frozen stop; no division by a quantity that can reach 0
or a denormal (A only where it exceeds the rounding of D_n, v only through max(v, sqrt(g R) / 10),
exp(2 B s) >= 1; `make_line_maths` lists each form's error). `make_line_maths(precision, noise)` perturbs exp, log, sqrt and atan by
`noise` = (relative, absolute) for the tests.
"""

import functools
import math
from types import SimpleNamespace

import warp as wp

from .air import make_air_laws
from .ballistic import EPSILON, ROUNDING
from .geometry import make_geometry
from .integrate import make_dormand_prince
from .surface_motion import make_surface_motion
from .types import types_for

LINE = 10.0  # a part across the line up to LINE x the tolerance of its scale is dropped (docstring)
MAX_DECAY = 16.0  # 2 B h of a step at most: exp(+-16) stays far from overflow and denormals
HANDOVER = 7  # integrate_line's event: go on in 3-D (surface_follow.integrate_phase) from here
LANDINGS = 12  # re-steps onto a margin's root (lift-off, loss of grip) at most
BAND = 0.1  # events end within BAND x the tolerance of their scale (surface_follow's)


@functools.cache
def make_line_maths(precision: str, noise: tuple = (0.0, 0.0)) -> SimpleNamespace:
    """The float32-safe forms: log1p, L(x) = log1p(x)/x, phi1(x) = expm1(x)/x, G(z) = atan(sqrt z)/sqrt z.

    Each is a series where the direct form cancels (log1p and L: 2 atanh(u), u = x / (2 + x), for
    |x| <= 1/2, |u| <= 1/3, to u^17: 2e-9; phi1: Taylor to x^9 / 10! for |x| <= 1/2: 5e-10; G:
    to z^12 for z <= 1/4: 5e-10) and the direct form elsewhere, where an error of the transcendental
    of relative eps (or absolute eps over [0.5, 2], __logf's) gives at most ~3 eps relative: log(1 + x)
    for 1 + x >= 3/2 is >= 0.405, e^x - 1 for |x| >= 1/2 is >= 0.39 in size, atan(r) / r for r >= 1/2
    is >= 0.785. `noise` = (relative, absolute): every exp, log, sqrt and atan result r becomes
    r (1 + relative) + absolute (log: absolute over [0.5, 2], relative elsewhere) - the tests'
    stand-in for approximate maths."""
    t = types_for(precision)
    scalar = t.scalar
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    REL, ABS = scalar(noise[0]), scalar(noise[1])
    NOISY = noise != (0.0, 0.0)
    QUARTER = scalar(0.25)
    H3, H5, H7, H9, H11, H13 = (scalar(1.0 / n) for n in (3, 5, 7, 9, 11, 13))
    H15, H17, H19, H21, H23, H25 = (scalar(1.0 / n) for n in (15, 17, 19, 21, 23, 25))
    F2, F3, F4, F5, F6, F7, F8, F9, F10, F11, F12 = (scalar(1.0 / math.factorial(n)) for n in range(2, 13))

    @wp.func
    def exp_(x: scalar):
        """exp(x) (perturbed by `noise`, relative)."""
        r = wp.exp(x)
        if wp.static(NOISY):
            r = r * (ONE + REL * (ONE + wp.abs(x)))
        return r

    @wp.func
    def log_(x: scalar):
        """log(x) (perturbed by `noise`: absolute over [0.5, 2], relative elsewhere)."""
        r = wp.log(x)
        if wp.static(NOISY):
            if x >= HALF and x <= scalar(2.0):
                r = r + ABS
            else:
                r = r * (ONE + REL)
        return r

    @wp.func
    def sqrt_(x: scalar):
        """sqrt(x) of x >= 0 (perturbed by `noise`, relative)."""
        r = wp.sqrt(wp.max(x, ZERO))
        if wp.static(NOISY):
            r = r * (ONE + REL)
        return r

    @wp.func
    def atanh_series(u: scalar):
        """atanh(u) / u for |u| <= 1/3: 1 + u^2/3 + ... + u^16/17 (Horner)."""
        z = u * u
        s = H17
        s = H15 + z * s
        s = H13 + z * s
        s = H11 + z * s
        s = H9 + z * s
        s = H7 + z * s
        s = H5 + z * s
        s = H3 + z * s
        return ONE + z * s

    @wp.func
    def log_ratio(x: scalar):
        """L(x) = log1p(x) / x for x > -1 (1 at x = 0)."""
        if wp.abs(x) <= HALF:
            return scalar(2.0) / (scalar(2.0) + x) * atanh_series(x / (scalar(2.0) + x))
        return log_(ONE + x) / x

    @wp.func
    def log1p(x: scalar):
        """log(1 + x) for x > -1."""
        return x * log_ratio(x)

    @wp.func
    def phi2_series(x: scalar):
        """The sum of x^j / (j + 2)!, j <= 10 (Horner): phi2 for |x| <= 1 (to 2e-9), and phi1 = 1 + x phi2."""
        s = F12
        s = F11 + x * s
        s = F10 + x * s
        s = F9 + x * s
        s = F8 + x * s
        s = F7 + x * s
        s = F6 + x * s
        s = F5 + x * s
        s = F4 + x * s
        s = F3 + x * s
        return F2 + x * s

    @wp.func
    def phi1(x: scalar):
        """(e^x - 1) / x (1 at x = 0)."""
        if wp.abs(x) <= HALF:
            return ONE + x * phi2_series(x)
        return (exp_(x) - ONE) / x

    @wp.func
    def phi2(x: scalar):
        """(e^x - 1 - x) / x^2 (1/2 at x = 0)."""
        if wp.abs(x) <= ONE:
            return phi2_series(x)
        return (phi1(x) - ONE) / x

    @wp.func
    def secant(lo: scalar, hi: scalar, f_lo: scalar, f_hi: scalar):
        """The regula falsi point of a bracket (f_lo > 0 >= f_hi), or its middle."""
        mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not (mid > lo and mid < hi):
            mid = HALF * (lo + hi)
        return mid

    @wp.func
    def illinois(lo: scalar, hi: scalar, f_lo: scalar, f_hi: scalar, side: wp.int32, at: scalar, f: scalar):
        """The bracket (lo, hi, f_lo, f_hi, side) updated by f at `at`, the kept end's value halved
        after two moves to the same side (Illinois: Dowell & Jarratt, BIT 11 (1971) 168)."""
        if f > ZERO:
            if side == 1:
                f_hi = HALF * f_hi
            return at, hi, f, f_hi, wp.int32(1)
        if side == -1:
            f_lo = HALF * f_lo
        return lo, at, f_lo, f, wp.int32(-1)

    @wp.func
    def atan_ratio(z: scalar):
        """G(z) = atan(sqrt z) / sqrt z for z >= 0 (1 at z = 0)."""
        if z <= QUARTER:  # sum of (-z)^k / (2 k + 1), k <= 12 (Horner)
            s = H25
            s = H23 - z * s
            s = H21 - z * s
            s = H19 - z * s
            s = H17 - z * s
            s = H15 - z * s
            s = H13 - z * s
            s = H11 - z * s
            s = H9 - z * s
            s = H7 - z * s
            s = H5 - z * s
            s = H3 - z * s
            return ONE - z * s
        r = sqrt_(z)
        a = wp.atan(r)
        if wp.static(NOISY):
            a = a * (ONE + REL)
        return a / r

    return SimpleNamespace(
        exp=exp_,
        log=log_,
        sqrt=sqrt_,
        log_ratio=log_ratio,
        log1p=log1p,
        phi1=phi1,
        phi2=phi2,
        atan_ratio=atan_ratio,
        secant=secant,
        illinois=illinois,
    )


@functools.cache
def make_line_laws(precision: str, model: str = "ballistic", laws=None, noise: tuple = (0.0, 0.0)) -> SimpleNamespace:
    """The `Line`, the laws along it (`along`), the frozen law (`reference`) and `line_of`."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    AIR = model == "air"
    sm, m = make_surface_motion(precision), make_line_maths(precision, noise)
    air_rates = make_air_laws(precision, *laws).air_rates if AIR else None
    ZERO, ONE, TWO = scalar(0.0), scalar(1.0), scalar(2.0)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))

    @wp.struct
    class Line:
        """A phase on a line: its frame (n, e, l = n x e), the spin's parts along n and e (kept), the
        friction's side, the ground's coefficients, the mode; and the step's frozen law: E_n, D_n,
        B, A = D_n - B E_n, the frozen stop s* (when A > 0: `stops` 1)."""

        normal: vec3
        direction: vec3
        lateral: vec3
        rest_spin: vec3
        sign: scalar
        mu_d: scalar
        rolling_resistance: scalar
        ploughing: scalar
        rolling: wp.int32
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
    def along(v: scalar, w: scalar, physics: Physics, line: Line, mu_s: scalar):
        """(dv/dt, dw/dt, N/m, the grip left mu_s N/m - |F|/m rolling or N/m sliding) at (v, w); N/m
        here is -(g + a_air) . n unclipped (< 0: lift-off), the friction's load clipped at 0."""
        radius, k = physics.radius, physics.inertia_factor
        if line.rolling != 0:
            w = v / radius
        a, alpha = applied(v * line.direction, w * line.lateral + line.rest_spin, physics)
        pressed = -wp.dot(a, line.normal)
        load = wp.max(pressed, ZERO)
        drive = wp.dot(a, line.direction) - line.ploughing * wp.abs(v) * v
        if line.rolling != 0:
            resisted = drive - line.rolling_resistance * load
            dv = (resisted + k * radius * wp.dot(alpha, line.lateral)) / (ONE + k)
            return dv, ZERO, pressed, mu_s * load - wp.abs(dv - resisted)
        friction = line.sign * line.mu_d * load
        return drive - friction, friction / (k * radius) + wp.dot(alpha, line.lateral), pressed, pressed

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
        """(1 if the phase is on a line (module docstring) else 0, its `Line`)."""
        radius = physics.radius
        line = Line()
        line.normal = normal
        speed0 = wp.length(velocity)
        e = sm.unit(velocity)
        line.direction = e
        line.lateral = wp.cross(normal, e)
        line.rest_spin = spin - wp.dot(spin, line.lateral) * line.lateral
        line.mu_d = mu_d
        line.rolling_resistance = rolling_resistance
        line.ploughing = ploughing
        line.rolling = mode_rolling
        g = physics.gravity
        line.least = scalar(0.1) * wp.sqrt(wp.length(g) * radius)
        scale = speed0 + radius * wp.length(spin) + wp.sqrt(wp.length(g) * radius)
        bound = scalar(LINE) * tolerance
        slip = sm.slip_velocity(velocity, spin, normal, radius)
        ok = speed0 > ZERO
        ok = ok and wp.abs(wp.dot(slip, line.lateral)) <= bound * scale
        ok = ok and radius * wp.abs(wp.dot(spin, normal)) <= bound * scale
        across = wp.abs(wp.dot(g, line.lateral))
        ok = ok and across <= bound * rolling_resistance * sm.normal_load(normal, g) + STOP_FRACTION * wp.length(g)
        if wp.static(AIR):
            ok = ok and wp.abs(wp.dot(physics.air.wind, line.lateral)) <= bound * scale
        v0 = wp.dot(velocity, e)
        q = v0 - radius * wp.dot(spin, line.lateral)  # the slip along e; from none, it grows along the drive
        if wp.abs(q) <= STOP_FRACTION * scale:
            dv, _w, _n, _f = along(v0, wp.dot(spin, line.lateral), physics, line, ZERO)
            q = dv
        line.sign = ONE
        if q < ZERO:
            line.sign = -ONE
        if ok:
            return wp.int32(1), line
        return wp.int32(0), line

    return SimpleNamespace(
        Line=Line,
        maths=m,
        applied=applied,
        along=along,
        freeze=freeze,
        reference=reference,
        reach=reach,
        frozen_time=frozen_time,
        line_of=line_of,
    )


@functools.cache
def make_line_steps(precision: str, model: str = "ballistic", laws=None, noise: tuple = (0.0, 0.0)) -> SimpleNamespace:
    """The rates over the distance of (Z, t, s) and w (module docstring), their Dormand-Prince step
    and the state (E, v, w, D) at a step's point."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    ll = make_line_laws(precision, model, laws, noise)
    Line, along, reference, m = ll.Line, ll.along, ll.reference, ll.maths
    ZERO, ONE, TWO = scalar(0.0), scalar(1.0), scalar(2.0)

    @wp.func
    def state_at(z: vec3, spin: vec3, physics: Physics, line: Line, mu_s: scalar):
        """(E, v, w, D, dw/dt, N/m, the grip left) at the step's point s = z[2] with departure Z = z[0]."""
        s = z[2]
        energy = reference(s, line) + z[0] / m.exp(TWO * line.slope * s)
        v = m.sqrt(energy)
        dv, dw, load, grip = along(v, spin[0], physics, line, mu_s)
        return energy, v, spin[0], -dv, dw, load, grip

    @wp.func
    def rates(z: vec3, spin: vec3, physics: Physics, line: Line):
        """d/ds of (Z, t, s) and of (w, 0, 0), as `make_dormand_prince` takes them (its velocity and
        spin slots; its position slot is unused)."""
        energy, v, _w, decel, dw, _load, _grip = state_at(z, spin, physics, line, ZERO)
        remainder = decel - line.decel - line.slope * (energy - line.energy) - line.drift * z[2]
        slow = ONE / wp.max(v, line.least)
        late = slow  # dt/ds; decelerating (A > 0), less the frozen law's (its time is in closed form)
        if line.stops != 0:
            late = slow - ONE / wp.max(m.sqrt(reference(z[2], line)), line.least)
        spin_rate = ZERO
        if line.rolling == 0:
            spin_rate = dw * slow
        return vec3(-TWO * remainder * m.exp(TWO * line.slope * z[2]), late, ONE), vec3(spin_rate, ZERO, ZERO)

    stages = make_dormand_prince(precision, rates, Line, True).stages

    return SimpleNamespace(state_at=state_at, rates=rates, stages=stages)


@functools.cache
def make_surface_line(
    precision: str, planes=None, model: str = "ballistic", laws=None, watch: tuple = (0, 0, False), noise: tuple = (0.0, 0.0)
) -> SimpleNamespace:
    """`line_of` (whether a phase is on a line, and its `Line`) and `integrate_line` (module
    docstring), each accepted step given to `tallies.path`'s watch of `watch`."""
    from ..tallies.path import make_path_watch  # (tallies imports physics: not at the top)

    watcher = make_path_watch(precision, *watch)
    Track, Tally = watcher.Track, watcher.Tally
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    STATIC = planes
    geo = make_geometry(precision, planes)
    ll, st = make_line_laws(precision, model, laws, noise), make_line_steps(precision, model, laws, noise)
    Line, along, freeze, reach, frozen_time, m = ll.Line, ll.along, ll.freeze, ll.reach, ll.frozen_time, ll.maths
    reference = ll.reference
    state_at, stages = st.state_at, st.stages
    ZERO, ONE, TWO = scalar(0.0), scalar(1.0), scalar(2.0)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))
    FAR = scalar(1e30)

    @wp.func
    def ahead_of(position: vec3, k: wp.int32, surfaces: Surfaces, physics: Physics, direction: vec3):
        """(distance along `direction` to the first other surface on the line, surface) or (FAR, -1)."""
        ahead = FAR
        k_ahead = wp.int32(-1)
        count = geo.count(surfaces)
        if wp.static(STATIC is not None):
            count = wp.static(STATIC)
        for j in range(count):
            if j != k:
                height, gap, n = geo.gap(surfaces, j, position, physics.radius)
                closing = -wp.dot(direction, n)
                if height >= ZERO and closing > ZERO:
                    s = wp.max(gap, ZERO) / closing
                    if s < ahead:
                        ahead = s
                        k_ahead = wp.int32(j)
        return ahead, k_ahead

    @wp.func
    def target(energy: scalar, v: scalar, w: scalar, decel: scalar, dw: scalar, line: Line, radius: scalar, goal: scalar):
        """(q, dq/ds) of what ends the phase at q = 0: rolling, v - goal; sliding, the slip sigma (v - R w)."""
        slow = ONE / wp.max(v, line.least)
        if line.rolling != 0:
            return v - goal, -decel * slow
        return line.sign * (v - radius * w), line.sign * (-decel - radius * dw) * slow

    @wp.func
    def step_error(e0: scalar, e1: scalar, w0: scalar, w1: scalar, ez: vec3, ew: vec3, h: scalar, line: Line, tolerance: scalar, floor: scalar, radius: scalar):  # fmt: skip
        """The step's error over tolerance: E's (Z's over exp(2 B h)) over max(E) + floor^2; w's
        over |w| + floor / R sliding. The position (s) is exact; the time does not feed back."""
        error = wp.abs(ez[0]) / m.exp(TWO * line.slope * h) / (tolerance * (wp.max(e0, e1) + floor * floor))
        if line.rolling == 0:
            error = wp.max(error, wp.abs(ew[0]) / (tolerance * (wp.max(wp.abs(w0), wp.abs(w1)) + floor / radius)))
        return error

    @wp.func
    def step_time(v0: scalar, h: scalar, integrated: scalar, line: Line):
        """The step's time: decelerating (A > 0), the frozen law's to its speed at h plus the
        integrated difference; else the integrated time."""
        if line.stops != 0:
            return frozen_time(v0, m.sqrt(reference(h, line)), line) + integrated
        return integrated

    @wp.func
    def watch_step(track: Track, tally: Tally, x0: vec3, line: Line, h: scalar, dt: scalar, v0: scalar, v1: scalar, d1: scalar):  # fmt: skip
        """Give the step to the watch: a straight stretch under the frozen law (A, B > 0), else the
        time Hermite of its ends."""
        e = line.direction
        if line.stops != 0 and line.slope > ZERO:
            return watcher.line(track, tally, x0, e, h, v0, line.offset, line.slope)
        d0 = (dt * v0) * e
        e0 = (-dt * dt * line.decel) * e
        e1 = (-dt * dt * d1) * e
        return watcher.segment(track, tally, x0, d0, e0, x0 + h * e, (dt * v1) * e, e1, dt, ONE)

    @wp.func
    def land_margin(
        h: scalar, m0: scalar, m1: scalar, w0: scalar, f0: vec3, d0: vec3, physics: Physics, line: Line, mu_s: scalar
    ):
        """(length, (Z, t, s), w, re-steps) of a step onto the margin's root (N or the grip left
        falls to 0 inside [0, h]: m0 > 0 >= m1): Illinois on the step's length, the end where m <= 0."""
        lo = ZERO
        hi = h
        m_lo = m0
        m_hi = m1
        side = wp.int32(0)
        taken = wp.int32(0)
        _x, z_hi, w_hi, _f, _d, _ex, _ez, _ew = stages(vec3(), vec3(), vec3(w0, ZERO, ZERO), f0, d0, h, physics, line)
        tiny = STOP_FRACTION * wp.length(physics.gravity)
        for _ in range(LANDINGS):
            if hi - lo > STOP_FRACTION * (hi + physics.radius) and -m_hi > tiny:
                mid = m.secant(lo, hi, m_lo, m_hi)
                _x2, z, w, _f2, _d2, _ex2, _ez2, _ew2 = stages(vec3(), vec3(), vec3(w0, ZERO, ZERO), f0, d0, mid, physics, line)
                taken += 1
                _e, _v, _w, _dc, _dw, load, grip = state_at(z, w, physics, line, mu_s)
                lo, hi, m_lo, m_hi, side = m.illinois(lo, hi, m_lo, m_hi, side, mid, wp.min(load, grip))
                if hi == mid:
                    z_hi = z
                    w_hi = w
        return hi, z_hi, w_hi, taken

    return SimpleNamespace(
        Line=Line,
        line_of=ll.line_of,
        along=along,
        freeze=freeze,
        reach=reach,
        reference=reference,
        frozen_time=frozen_time,
        ahead_of=ahead_of,
        target=target,
        step_error=step_error,
        step_time=step_time,
        watch_step=watch_step,
        land_margin=land_margin,
        state_at=state_at,
        stages=stages,
        maths=m,
        Track=Track,
        Tally=Tally,
    )


@functools.cache
def make_line_integrator(
    precision: str, planes=None, model: str = "ballistic", laws=None, watch: tuple = (0, 0, False), noise: tuple = (0.0, 0.0)
) -> SimpleNamespace:
    """`integrate_line`: `surface_follow`'s integrate_phase for a phase on a line (module docstring)."""
    sl = make_surface_line(precision, planes, model, laws, watch, noise)
    m = sl.maths
    Line, Track, Tally, along, freeze, reach, stages, state_at = (
        sl.Line, sl.Track, sl.Tally, sl.along, sl.freeze, sl.reach, sl.stages, sl.state_at
    )  # fmt: skip
    ahead_of, target, step_error, step_time, watch_step, land_margin = (
        sl.ahead_of, sl.target, sl.step_error, sl.step_time, sl.watch_step, sl.land_margin
    )  # fmt: skip
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    ZERO, ONE, TWO, HALF = scalar(0.0), scalar(1.0), scalar(2.0), scalar(0.5)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))
    FAR = scalar(1e30)
    reference, frozen_time = sl.reference, sl.frozen_time
    AIMS = 40 if precision == "float64" else 30
    CONTACT, UNFINISHED = 4, 6  # surface_follow's end codes (it imports this module)

    @wp.func
    def first_slope(v: scalar, w: scalar, dv: scalar, physics: Physics, line: Line):
        """B of the first step: the secant of D between v / 2 and v (0 at v = 0)."""
        half_dv, _dw, _load, _grip = along(HALF * v, w, physics, line, ZERO)
        if v <= line.least:
            return ZERO
        return (half_dv - dv) / (scalar(0.75) * v * v)

    @wp.func
    def slip_ahead(s: scalar, v: scalar, w: scalar, dwdt: scalar, line: Line, radius: scalar):
        """The slip sigma (v - R w) at s under the frozen law (A > 0): v from E_ref, w + dw/dt t."""
        v1 = m.sqrt(reference(s, line))
        return line.sign * (v1 - radius * (w + dwdt * frozen_time(v, v1, line)))

    @wp.func
    def slide_aim(v: scalar, w: scalar, dwdt: scalar, q: scalar, goal: scalar, line: Line, radius: scalar):
        """Where the slip falls to `goal` under the frozen law (A > 0; exact in vacuum), by Illinois
        on [0, s*], or -1 if not before the stop (Newton's linear aim would creep along v's decay)."""
        lo = ZERO
        hi = line.stop
        f_lo = q - goal
        f_hi = slip_ahead(hi, v, w, dwdt, line, radius) - goal
        if f_hi > ZERO:
            return scalar(-1.0)
        side = wp.int32(0)
        for _ in range(AIMS):
            if hi - lo > STOP_FRACTION * hi:
                mid = m.secant(lo, hi, f_lo, f_hi)
                f = slip_ahead(mid, v, w, dwdt, line, radius) - goal
                lo, hi, f_lo, f_hi, side = m.illinois(lo, hi, f_lo, f_hi, side, mid, f)
        return lo

    @wp.func
    def spin_of(v: scalar, w: scalar, line: Line, radius: scalar):
        """The spin vector of (v, w) on the line (rolling: w = v / R)."""
        if line.rolling != 0:
            return (v / radius) * line.lateral + line.rest_spin
        return w * line.lateral + line.rest_spin

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
        """One phase on a line to its target (`target`: goal speed rolling, zero slip sliding), its
        margin (lift-off, loss of grip), another surface or HANDOVER: (x, v, w, elapsed, path,
        event, k_next, steps, track), event 0, 1, 4 (CONTACT), 6 (UNFINISHED) or HANDOVER."""
        radius = physics.radius
        floor = wp.sqrt(wp.length(physics.gravity) * radius) + scalar(1e-6)
        band = wp.max(STOP_FRACTION, scalar(BAND) * tolerance)
        e = line.direction
        ahead, k_ahead = ahead_of(position, k, surfaces, physics, e)
        v = wp.dot(velocity, e)
        w = wp.dot(spin, line.lateral)
        energy = v * v
        dv, dw, load, grip = along(v, w, physics, line, mu_s)
        slope = first_slope(v, w, dv, physics, line)
        drift = ZERO
        s = ZERO
        elapsed = ZERO
        steps = wp.int32(0)
        event = wp.int32(UNFINISHED)
        k_next = k
        h = FAR
        growth = scalar(5.0)
        while steps < steps_left:
            if line.rolling != 0:
                w = v / radius
            decel = -dv
            if line.rolling == 0 and steps > 0:  # sliding, D also drifts with w: B at this w, G from the last step
                slope = first_slope(v, w, dv, physics, line)
            line = freeze(line, energy, decel, slope, drift)
            scale = v + radius * wp.abs(w) + floor
            slow = ONE / wp.max(v, line.least)
            if ahead - s <= ZERO:
                event = wp.int32(CONTACT)
                k_next = k_ahead
                break
            if line.rolling == 0 and v < line.least:
                event = wp.int32(HANDOVER)
                break
            q, rate = target(energy, v, w, decel, dw, line, radius, goal)
            if rate < ZERO and q <= band * scale:  # the rest of the way to first order
                ds = q / (-rate)
                x0 = position + s * e
                dt = ds * slow
                track = watch_step(track, tally, x0, line, ds, dt, v, v - decel * dt, decel)
                s += ds
                elapsed += dt
                w = w + dw * dt
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
                    ahead_aim = slide_aim(v, w, dw, q, HALF * band * scale, line, radius)
                    if ahead_aim > ZERO:
                        aim = ahead_aim
                h = wp.min(h, aim)
            to_contact = False
            if h >= ahead - s:
                h = ahead - s
                to_contact = True
            spin_rate = ZERO
            if line.rolling == 0:
                spin_rate = dw * slow
            f0 = vec3(ZERO, slow, ONE)  # (rates' d/ds at the start: no remainder, dt/ds less the frozen law's)
            if line.stops != 0:
                f0 = vec3(ZERO, ZERO, ONE)
            d0 = vec3(spin_rate, ZERO, ZERO)
            _x, z1, w1v, _f1, _d1, _ex, ez, ew = stages(vec3(), vec3(), vec3(w, ZERO, ZERO), f0, d0, h, physics, line)
            steps += 1
            e1, v1, w1, dec1, dw1, load1, grip1 = state_at(z1, w1v, physics, line, mu_s)
            error = step_error(energy, e1, w, w1, ez, ew, h, line, tolerance, floor, radius)
            if not (error <= ONE):
                h = h * wp.clamp(scalar(0.9) * wp.pow(error, scalar(-0.2)), scalar(0.2), ONE)
                growth = ONE
                continue
            q1, _rate1 = target(e1, v1, w1, dec1, dw1, line, radius, goal)
            if e1 < ZERO or (q1 < ZERO and q > ZERO):  # past the target: aim short of it
                h = HALF * h
                growth = ONE
                continue
            margin1 = wp.min(load1, grip1)
            if margin1 <= ZERO:  # lift-off or loss of grip inside: onto its root
                h, z1, w1v, taken = land_margin(h, wp.min(load, grip), margin1, w, f0, d0, physics, line, mu_s)
                steps += taken
                e1, v1, w1, dec1, dw1, load1, grip1 = state_at(z1, w1v, physics, line, mu_s)
                event = wp.int32(1)
                to_contact = False
            dt = step_time(v, h, z1[1], line)
            track = watch_step(track, tally, position + s * e, line, h, dt, v, v1, dec1)
            s += h
            elapsed += dt
            if line.rolling == 0 and h > STOP_FRACTION * (s + radius):
                drift = (dec1 - decel - line.slope * (e1 - energy)) / h
            elif wp.abs(e1 - energy) > scalar(0.05) * energy:
                slope = (dec1 - decel) / (e1 - energy)
            energy = e1
            v = v1
            w = w1
            dv = -dec1
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
        return position + s * e, v * e, spin_of(v, w, line, radius), elapsed, s, event, k_next, steps, track

    return SimpleNamespace(Line=Line, line_of=sl.line_of, integrate_line=integrate_line)
