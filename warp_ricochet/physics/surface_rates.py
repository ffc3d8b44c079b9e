"""The right-hand side of a pellet's motion along a surface (`surface_motion`'s rates with the
air's forces), its Dormand-Prince step and the events' margins and roots, for
`physics.surface_follow`'s integrated phases (docs/ground.md 9; SI units)."""

import functools
from types import SimpleNamespace

import warp as wp

from .ballistic import EPSILON
from .inlining import out_of_line_if
from .integrate import make_dense_output, make_dormand_prince
from .line_laws import make_line_laws
from .surface_motion import make_surface_motion
from .types import types_for


@functools.cache
def make_surface_rates(precision: str, model: str = "ballistic", laws=None) -> SimpleNamespace:
    """The right-hand side of sliding and rolling (`surface_motion`'s rates with the air's forces in
    `model` "air"), its Dormand-Prince step, the events' margins and roots, the step's error and path."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    sm, dense = make_surface_motion(precision), make_dense_output(precision)
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    THETA_TOLERANCE = scalar(4.0 * EPSILON[precision])
    ITERATIONS = 64 if precision == "float64" else 40

    @wp.struct
    class Contact:
        """What the surface rates read beside the state: the plane's normal and material, the mode."""

        normal: vec3
        mu_d: scalar
        rolling_resistance: scalar
        ploughing: scalar
        rolling: wp.int32

    line_laws = make_line_laws(precision, model, laws)
    applied_at, maths = line_laws.applied, line_laws.maths  # (g + a_air, T_air / I); Illinois

    @out_of_line_if(model == "air")
    @wp.func
    def rates(velocity: vec3, spin: vec3, physics: Physics, contact: Contact):
        """(dv/dt, domega/dt) sliding or rolling (`surface_motion`), the air's forces included."""
        applied, alpha = applied_at(velocity, spin, physics)
        n = contact.normal
        if contact.rolling != 0:
            acceleration, spin_rate, _f = sm.rolling_rates(
                velocity, n, applied, alpha, physics.radius, physics.inertia_factor, contact.rolling_resistance, contact.ploughing
            )
            return acceleration, spin_rate
        return sm.sliding_rates(
            velocity, spin, n, applied, alpha, physics.radius, physics.inertia_factor, contact.mu_d, contact.ploughing
        )

    stages = make_dormand_prince(precision, rates, Contact, True).stages

    @wp.func
    def margins(velocity: vec3, spin: vec3, physics: Physics, contact: Contact, mu_s: scalar):
        """(N/m, the grip left mu_s N/m - |F|/m rolling; N/m sliding): a phase ends where either
        falls to 0 (lift-off; loss of grip)."""
        applied, alpha = applied_at(velocity, spin, physics)
        load = -wp.dot(applied, contact.normal)
        grip = load
        if contact.rolling != 0:
            _a, _w, friction = sm.rolling_rates(
                velocity,
                contact.normal,
                applied,
                alpha,
                physics.radius,
                physics.inertia_factor,
                contact.rolling_resistance,
                contact.ploughing,
            )
            grip = mu_s * wp.max(load, ZERO) - friction
        return load, grip

    @wp.func
    def margin(velocity: vec3, spin: vec3, physics: Physics, contact: Contact, mu_s: scalar):
        """How far the phase is from its end by the forces (> 0 inside): the lesser `margins`."""
        load, grip = margins(velocity, spin, physics, contact, mu_s)
        return wp.min(load, grip)

    @wp.func
    def lifts(velocity: vec3, spin: vec3, physics: Physics, contact: Contact, mu_s: scalar):
        """At a `margin` root: 1 if the load ended the phase (lift-off), 0 if the grip did."""
        load, grip = margins(velocity, spin, physics, contact, mu_s)
        if load <= grip:
            return wp.int32(1)
        return wp.int32(0)

    @wp.func
    def margin_root(
        h: scalar,
        x0: vec3,
        x1: vec3,
        v0: vec3,
        a0: vec3,
        w0: vec3,
        d0: vec3,
        v1: vec3,
        a1: vec3,
        w1: vec3,
        d1: vec3,
        f1: scalar,
        physics: Physics,
        contact: Contact,
        mu_s: scalar,
    ):
        """Where on the step `margin` falls from > 0 (theta = 0) to f1 <= 0 (theta = 1), on the
        dense output (v: the quintic's slope, omega: the cubic Hermite; Illinois, the bracket's upper end)."""
        lo = ZERO
        hi = ONE
        f_lo = margin(v0, w0, physics, contact, mu_s)
        f_hi = f1
        side = wp.int32(0)
        for _ in range(ITERATIONS):
            if hi - lo > THETA_TOLERANCE:
                mid = maths.secant(lo, hi, f_lo, f_hi)
                _x, slope = dense.hermite_vec(mid, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
                v = slope / h
                w = dense.cubic_vec(mid, w0, h * d0, w1, h * d1)
                lo, hi, f_lo, f_hi, side = maths.illinois(lo, hi, f_lo, f_hi, side, mid, margin(v, w, physics, contact, mu_s))
        return hi

    @wp.func
    def target(velocity: vec3, spin: vec3, acceleration: vec3, spin_rate: vec3, contact: Contact, radius: scalar, goal: scalar):
        """(q, dq/dt, direction) of the quantity a phase ends at: sliding, the slip's size (its
        direction: the slip's, or at zero slip its rate's); rolling, the speed minus `goal`."""
        n = contact.normal
        if contact.rolling != 0:
            direction = sm.unit(velocity)
            return wp.length(velocity) - goal, wp.dot(acceleration, direction), direction
        slip = sm.slip_velocity(velocity, spin, n, radius)
        rate = sm.tangential(acceleration - radius * wp.cross(spin_rate, n), n)
        direction = sm.unit(slip)
        if wp.length(slip) <= ZERO:
            direction = sm.unit(rate)
        return wp.length(slip), wp.dot(rate, direction), direction

    @wp.func
    def error_norm(
        x0: vec3,
        v0: vec3,
        w0: vec3,
        x1: vec3,
        v1: vec3,
        w1: vec3,
        ex: vec3,
        ev: vec3,
        ew: vec3,
        tolerance: scalar,
        floor: scalar,
        radius: scalar,
    ):
        """The step's error over tolerance, as `physics.integrate`'s: x, v and omega each over
        tolerance x (the step's displacement + R, the speed + floor, the spin + floor / R)."""
        error = wp.max(
            wp.length(ex) / (tolerance * (wp.length(x1 - x0) + radius)),
            wp.length(ev) / (tolerance * (wp.max(wp.length(v0), wp.length(v1)) + floor)),
        )
        return wp.max(error, wp.length(ew) / (tolerance * (wp.max(wp.length(w0), wp.length(w1)) + floor / radius)))

    @wp.func
    def simpson(h: scalar, theta: scalar, x0: vec3, v0: vec3, a0: vec3, x1: vec3, v1: vec3, a1: vec3):
        """The path length over [0, theta] of a step: Simpson's rule on the dense output's speed."""
        _xm, slope_m = dense.hermite_vec(HALF * theta, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
        _xe, slope_e = dense.hermite_vec(theta, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
        return theta / scalar(6.0) * (h * wp.length(v0) + scalar(4.0) * wp.length(slope_m) + wp.length(slope_e))

    return SimpleNamespace(
        Contact=Contact,
        applied_at=applied_at,
        rates=rates,
        stages=stages,
        margin=margin,
        lifts=lifts,
        margin_root=margin_root,
        target=target,
        error_norm=error_norm,
        simpson=simpson,
    )
