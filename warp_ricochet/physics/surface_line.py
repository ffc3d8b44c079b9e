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

from .ballistic import EPSILON, ROUNDING
from .lanes import any_in, lanes_here
from .line_ahead import make_line_ahead
from .line_laws import make_line_laws, make_line_steps
from .line_log import LOG_STEPS, make_line_log
from .types import types_for

MAX_DECAY = 16.0  # 2 B h of a step at most: exp(+-16) stays far from overflow and denormals
HANDOVER = 7  # integrate_line's event: go on in 3-D (surface_follow.integrate_phase) from here
LANDINGS = 12  # re-steps onto a margin's root (lift-off, loss of grip) at most
BAND = 0.1  # events end within BAND x the tolerance of their scale (surface_follow's)
# a slide off the line aims at SHORT x the linear distance to the slip's zero: near it the slip's
# direction relaxes at about 7/2 mu_d N / |s| (stiff), and a step aimed at the zero is rejected
# (turf: 80.4 steps a pellet aimed at 1, 62.3 at 1/2, 58.2 at 0.7, 59.3 at 0.8)
SHORT = 0.7
MAX_TURN = 0.25  # rad: the heading turns by at most this in a step (its sin and cos by series)


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
    """The helpers of `integrate_line` (module docstring), with `tallies.path`'s watch of `watch`
    (its steps given to it by `line_log`); not `rough`, for straight phases only; `plates`: the
    surfaces may hold plates, meshes and posts (`geometry.make_geometry`), kept at `line_ahead.free_of`."""
    from ..tallies.path_replay import watch_for  # (tallies imports physics: not at the top)

    watcher = watch_for(precision, *watch)
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
                y, _f2, _x2, p = st.stages_at(y0, f0, mid, physics, line)
                taken += 1
                lo, hi, m_lo, m_hi, side = m.illinois(lo, hi, m_lo, m_hi, side, mid, wp.min(p.load, st.grip_at(p, line, mu_s)))
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
        straight_open=watcher.straight_open,
        straight_close=watcher.straight_close,
        land_margin=land_margin,
        spin_of=spin_of,
        first_rates=first_rates,
        state=state,
        state_at=state_at,
        moved=st.moved,
        start=st.start,
        psi_of=st.psi_of,
        stages=stages,
        stages_at=st.stages_at,
        grip_at=st.grip_at,
        state_of=st.state_of,
        maths=m,
        Track=Track,
        Tally=Tally,
    )


@wp.func
def going_together(here: wp.int32, running: wp.int32):
    """`integrate_line`'s loop goes on while any lane of `here` runs: they meet at each step
    (`physics.lanes`; with a watched path)."""
    return any_in(here, running)


@wp.func
def going_alone(here: wp.int32, running: wp.int32):
    """`integrate_line`'s loop goes on while this lane runs (without a watched path)."""
    return running


def going_for(watch: tuple):
    """`integrate_line`'s loop condition: its lanes meet at each step where the watch runs in the loop
    (`going_together`), not where nothing is watched or the watch is recorded (`tallies.path_replay`)."""
    return going_together if watch[0] > 0 and not (len(watch) > 4 and watch[4]) else going_alone


@functools.cache
def make_slide_aim(precision: str, model: str = "ballistic", laws=None, noise: tuple = (0.0, 0.0), rough=True):
    """`slide_aim(v, spin, dwdt, q, goal, line, radius)`: where a sliding phase's slip falls to `goal`
    under its frozen law (`integrate_line`'s aim)."""
    scalar, vec3 = types_for(precision).scalar, types_for(precision).vec3
    ll = make_line_laws(precision, model, laws, noise, rough)
    Line, m, reference, frozen_time = ll.Line, ll.maths, ll.reference, ll.frozen_time
    ZERO = scalar(0.0)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))
    AIMS = 40 if precision == "float64" else 30

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

    return slide_aim


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
    log_steps: int = LOG_STEPS,
) -> SimpleNamespace:
    """`integrate_line`: `surface_follow`'s integrate_phase for a phase over the distance (module
    docstring); not `rough`, straight phases only (`line_of` refuses the rest), with the heading
    and the offset compiled away; `plates`: steps kept within `line_ahead.free_of` (module docstring);
    the steps watched after, `log_steps` at a time (`physics.line_log`)."""
    sl = make_surface_line(precision, planes, model, laws, watch, noise, rough, plates)
    logs = make_line_log(precision, model, laws, watch, noise, rough, log_steps)
    ROUGH = rough
    Line, Track, Tally = sl.Line, sl.Track, sl.Tally
    along, heading, freeze, reach, state_at = sl.along, sl.heading, sl.freeze, sl.reach, sl.state_at
    ahead_of, capped, target, step_error, step_time, land_margin = (
        sl.ahead_of, sl.capped, sl.target, sl.step_error, sl.step_time, sl.land_margin
    )  # fmt: skip
    log_open, log_step, log_close = logs.log_open, logs.log_step, logs.log_close
    first_slope, spin_of, first_rates, start, moved, psi_of = (
        sl.first_slope, sl.spin_of, sl.first_rates, sl.start, sl.moved, sl.psi_of
    )  # fmt: skip
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    ZERO, ONE, TWO, HALF = scalar(0.0), scalar(1.0), scalar(2.0), scalar(0.5)
    STOP_FRACTION = scalar(max(1e-9, ROUNDING * EPSILON[precision]))
    FAR = scalar(1e30)
    CONTACT, UNFINISHED = 4, 6  # surface_follow's end codes (it imports this module)
    slide_aim, going = make_slide_aim(precision, model, laws, noise, rough), going_for(watch)

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
        # One pass of the inner loop a step (its break ends the lane's run). With a watch the steps
        # are warp-uniform (`going`): the lanes that came in meet at each step, so that a watch's
        # branches do not leave them apart (bench/RESULTS.md, "Lanes that meet"); a lane done
        # waits. The same steps and bits as a plain loop.
        pending = sl.straight_open()  # the phase's steps along e whose walk waits (`tallies.path`)
        log, track, pending = log_open(track, tally, pending, line, position, v, -dv)  # (`physics.line_log`)
        here = lanes_here()
        running = wp.int32(1)
        while going(here, running) != 0:
            once = running
            if steps >= steps_left:
                once = wp.int32(0)
                running = wp.int32(0)
            while once != 0:
                once = wp.int32(0)
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
                    running = wp.int32(0)
                    break
                if line.rolling == 0 and v < line.least:
                    event = wp.int32(HANDOVER)
                    running = wp.int32(0)
                    break
                q, rate = target(v, e, line.lateral, spin, decel, dl, dw, line, radius, goal)
                finish = band
                if line.rolling == 0 and wp.abs(wp.dot(line.slip, line.lateral)) > STOP_FRACTION:
                    finish = wp.max(band, tolerance)  # off the line, a slip below the integration's own error is zero
                if rate < ZERO and q <= finish * scale:  # the rest of the way to first order
                    ds = q / (-rate)
                    dt = ds * slow
                    ends = wp.sqrt(wp.max(v * v - TWO * decel * ds, ZERO))  # (watched at constant deceleration over ds)
                    watched = dt
                    if v + ends > ZERO:
                        watched = TWO * ds / (v + ends)
                    track, pending, log = log_step(
                        track, tally, pending, log, line, position, position + ds * e, watched, v, ends, decel
                    )
                    position = position + ds * e
                    s += ds
                    elapsed += dt
                    spin = spin + dw * dt
                    v = wp.max(v - decel * dt, ZERO)
                    if line.rolling != 0:
                        v = goal
                    event = wp.int32(0)
                    running = wp.int32(0)
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
                    running = wp.int32(0)
                    break
                to_contact = False
                if h >= ahead:
                    h = ahead
                    to_contact = True
                y0 = start(spin)
                f0 = first_rates(v, dl, dw, line)
                y1, _f1, error_vector, p1 = sl.stages_at(y0, f0, h, physics, line)  # (the last stage is y1's point)
                steps += 1
                e1, v1, w1, dec1, dl1, dw1, load1, grip1 = sl.state_of(p1, line, mu_s)
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
                            running = wp.int32(0)
                            break
                track, pending, log = log_step(track, tally, pending, log, line, position, x1, dt, v, v1, dec1)
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
                    running = wp.int32(0)
                    break
                if to_contact:
                    event = wp.int32(CONTACT)
                    k_next = k_ahead
                    running = wp.int32(0)
                    break
                h = h * wp.clamp(scalar(0.9) * wp.pow(wp.max(error, scalar(1e-10)), scalar(-0.2)), scalar(0.2), growth)
                growth = scalar(5.0)
        track, pending = log_close(track, tally, pending, log, line)
        if wp.static(not ROUGH):  # (rough: each step watched at once)
            track, _pending = sl.straight_close(track, tally, pending, position)
        return position, v * line.direction, spin_of(v, spin, line, radius), elapsed, s, event, k_next, steps, track

    return SimpleNamespace(Line=Line, line_of=sl.line_of, integrate_line=integrate_line)
