"""Integrating a pellet's flight in air: the Dormand-Prince 5(4) pair with its error estimate
(Dormand & Prince 1980, J Comput Appl Math 6:19; Hairer, Norsett & Wanner, Solving ODEs I, II.5)
and a quintic Hermite dense output of the position, on which plane contacts are found as roots.

The state is the centre x, velocity v and angular velocity w; dx/dt = v, dv/dt = g + a_air(v, w),
dw/dt = w_air(v, w) (`physics.air`): nothing depends on x or t, so a step needs the derivatives of
v and w only (the stage velocities are x's). The error of a step is the largest of its position,
velocity and spin errors, each over tolerance x (its scale): the step's displacement plus R, the
speed plus sqrt(|g| R), the spin plus that over R. So a landing point's error is about the
tolerance times the distance flown.

Dense output on a step of length h, theta in [0, 1]: x(theta) is the quintic Hermite of x, h v and
h^2 a at both ends (fifth order, as the step), v(theta) its derivative, w(theta) the cubic Hermite
of w and h dw/dt. A plane's gap n.(x - p) - R on the step is then a quintic in theta.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .air import make_air_laws
from .inlining import out_of_line_if
from .types import types_for

# Dormand-Prince 5(4): nodes, stages, fifth-order weights (the seventh stage is the next step's first)
A21 = 1.0 / 5.0
A31, A32 = 3.0 / 40.0, 9.0 / 40.0
A41, A42, A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
A51, A52, A53, A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
A61, A62, A63, A64, A65 = 9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0
B1, B3, B4, B5, B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
# fifth minus fourth order weights: the error estimate
E1, E3, E4, E5, E6, E7 = (71.0 / 57600.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0)


@functools.cache
def make_dormand_prince(
    precision: str, rates, Context, spin_changes: bool, state=None, ends=None, out_of_line: bool = False
) -> SimpleNamespace:
    """`stages(x, v, w, a, dw, h, physics, context) -> (x', v', w', a', dw', x error, v error, w
    error)`: one Dormand-Prince step of length h for the right-hand side `rates(v, w, physics,
    context) -> (dv/dt, dw/dt)` (a `@wp.func`; `context` of the Warp type `Context` carries what
    else it reads); `spin_changes` False: w is constant (its stages not computed). With `state` (a
    Warp vector type): `stages(y, f, h, physics, context) -> (y', f', error)` for dy/dt =
    rates(y, physics, context) = f; and with `ends(y, physics, context) -> (f, point)` (the same f
    and what else the caller needs at y'), `stages_at(y, f, h, physics, context) -> (y', f', error,
    point)`: the step's last stage is its end, so the point costs no evaluation of the laws more;
    `out_of_line`: the stages 2 to 6 both share (`six`) one function in CUDA code (`physics.inlining`:
    the air's surface lines call the step from several sites)."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    SPIN_CHANGES = spin_changes
    c = {k: scalar(v) for k, v in globals().items() if k[0] in "ABE" and k[1:].isdigit()}
    a21, a31, a32, a41, a42, a43 = c["A21"], c["A31"], c["A32"], c["A41"], c["A42"], c["A43"]
    a51, a52, a53, a54 = c["A51"], c["A52"], c["A53"], c["A54"]
    a61, a62, a63, a64, a65 = c["A61"], c["A62"], c["A63"], c["A64"], c["A65"]
    b1, b3, b4, b5, b6 = c["B1"], c["B3"], c["B4"], c["B5"], c["B6"]
    e1, e3, e4, e5, e6, e7 = c["E1"], c["E3"], c["E4"], c["E5"], c["E6"], c["E7"]

    if state is not None:

        @out_of_line_if(out_of_line)
        @wp.func
        def state_six(y: state, f1: state, h: scalar, physics: Physics, context: Context):
            """y at h (fifth order) and the stages 3 to 6 its error estimate takes."""
            f2 = rates(y + (h * a21) * f1, physics, context)
            f3 = rates(y + h * (a31 * f1 + a32 * f2), physics, context)
            f4 = rates(y + h * (a41 * f1 + a42 * f2 + a43 * f3), physics, context)
            f5 = rates(y + h * (a51 * f1 + a52 * f2 + a53 * f3 + a54 * f4), physics, context)
            f6 = rates(y + h * (a61 * f1 + a62 * f2 + a63 * f3 + a64 * f4 + a65 * f5), physics, context)
            return y + h * (b1 * f1 + b3 * f3 + b4 * f4 + b5 * f5 + b6 * f6), f3, f4, f5, f6

        @wp.func
        def state_error(h: scalar, f1: state, f3: state, f4: state, f5: state, f6: state, f7: state):
            """The error estimate, fifth minus fourth order."""
            return h * (e1 * f1 + e3 * f3 + e4 * f4 + e5 * f5 + e6 * f6 + e7 * f7)

        @wp.func
        def state_stages(y: state, f1: state, h: scalar, physics: Physics, context: Context):
            """y and its rates at h and the error estimate (fifth minus fourth order)."""
            y7, f3, f4, f5, f6 = state_six(y, f1, h, physics, context)
            f7 = rates(y7, physics, context)
            return y7, f7, state_error(h, f1, f3, f4, f5, f6, f7)

        if ends is None:
            return SimpleNamespace(stages=state_stages, six=state_six)

        @wp.func
        def state_stages_at(y: state, f1: state, h: scalar, physics: Physics, context: Context):
            """`state_stages` and `ends`' point at h (from the last stage's evaluation)."""
            y7, f3, f4, f5, f6 = state_six(y, f1, h, physics, context)
            f7, point = ends(y7, physics, context)
            return y7, f7, state_error(h, f1, f3, f4, f5, f6, f7), point

        return SimpleNamespace(stages=state_stages, stages_at=state_stages_at, six=state_six)

    @wp.func
    def combine(
        y: vec3,
        h: scalar,
        k1: vec3,
        k2: vec3,
        k3: vec3,
        k4: vec3,
        k5: vec3,
        w1: scalar,
        w2: scalar,
        w3: scalar,
        w4: scalar,
        w5: scalar,
    ):
        """y + h (w1 k1 + ... + w5 k5)."""
        return y + h * (w1 * k1 + w2 * k2 + w3 * k3 + w4 * k4 + w5 * k5)

    @wp.func
    def stages(position: vec3, velocity: vec3, spin: vec3, a1: vec3, d1: vec3, h: scalar, physics: Physics, context: Context):
        """The fifth-order state, its derivatives (the next step's first stage) and the error
        estimates of x, v and w (fifth minus fourth order)."""
        zero = vec3()
        v2 = velocity + (h * a21) * a1
        w2 = spin + (h * a21) * d1
        a2, d2 = rates(v2, w2, physics, context)
        v3 = combine(velocity, h, a1, a2, zero, zero, zero, a31, a32, scalar(0.0), scalar(0.0), scalar(0.0))
        w3 = spin
        if wp.static(SPIN_CHANGES):
            w3 = combine(spin, h, d1, d2, zero, zero, zero, a31, a32, scalar(0.0), scalar(0.0), scalar(0.0))
        a3, d3 = rates(v3, w3, physics, context)
        v4 = combine(velocity, h, a1, a2, a3, zero, zero, a41, a42, a43, scalar(0.0), scalar(0.0))
        w4 = spin
        if wp.static(SPIN_CHANGES):
            w4 = combine(spin, h, d1, d2, d3, zero, zero, a41, a42, a43, scalar(0.0), scalar(0.0))
        a4, d4 = rates(v4, w4, physics, context)
        v5 = combine(velocity, h, a1, a2, a3, a4, zero, a51, a52, a53, a54, scalar(0.0))
        w5 = spin
        if wp.static(SPIN_CHANGES):
            w5 = combine(spin, h, d1, d2, d3, d4, zero, a51, a52, a53, a54, scalar(0.0))
        a5, d5 = rates(v5, w5, physics, context)
        v6 = combine(velocity, h, a1, a2, a3, a4, a5, a61, a62, a63, a64, a65)
        w6 = spin
        if wp.static(SPIN_CHANGES):
            w6 = combine(spin, h, d1, d2, d3, d4, d5, a61, a62, a63, a64, a65)
        a6, d6 = rates(v6, w6, physics, context)
        v7 = combine(velocity, h, a1, a3, a4, a5, a6, b1, b3, b4, b5, b6)
        w7 = spin
        if wp.static(SPIN_CHANGES):
            w7 = combine(spin, h, d1, d3, d4, d5, d6, b1, b3, b4, b5, b6)
        x7 = combine(position, h, velocity, v3, v4, v5, v6, b1, b3, b4, b5, b6)
        a7, d7 = rates(v7, w7, physics, context)
        position_error = h * (e1 * velocity + e3 * v3 + e4 * v4 + e5 * v5 + e6 * v6 + e7 * v7)
        velocity_error = h * (e1 * a1 + e3 * a3 + e4 * a4 + e5 * a5 + e6 * a6 + e7 * a7)
        spin_error = vec3()
        if wp.static(SPIN_CHANGES):
            spin_error = h * (e1 * d1 + e3 * d3 + e4 * d4 + e5 * d5 + e6 * d6 + e7 * d7)
        return x7, v7, w7, a7, d7, position_error, velocity_error, spin_error

    return SimpleNamespace(stages=stages)


@functools.cache
def make_stepper(precision: str, laws: tuple, out_of_line: bool = False) -> SimpleNamespace:
    """`rates(v, w, physics) -> (dv/dt, dw/dt)` and `step(x, v, w, a, dw, h, physics) -> (x', v',
    w', a', dw', error)` for the air laws `laws` = (drag, lift or None, spin_decay or None);
    `out_of_line`: `rates` one function in CUDA code (`physics.inlining`; kernels to rest)."""
    t = types_for(precision)
    scalar, vec3, Physics = t.scalar, t.vec3, t.Physics
    air_rates = make_air_laws(precision, *laws).air_rates
    SPIN_CHANGES = laws[2] is not None

    @out_of_line_if(out_of_line)
    @wp.func
    def rates(velocity: vec3, spin: vec3, physics: Physics):
        """dv/dt (m/s^2) and dw/dt (rad/s^2) in air."""
        acceleration, spin_change = air_rates(velocity, spin, physics.air)
        return physics.gravity + acceleration, spin_change

    @wp.func
    def air_only(velocity: vec3, spin: vec3, physics: Physics, context: wp.int32):
        """`rates` in the form `make_dormand_prince` takes."""
        return rates(velocity, spin, physics)

    stages = make_dormand_prince(precision, air_only, wp.int32, SPIN_CHANGES).stages

    @wp.func
    def step(position: vec3, velocity: vec3, spin: vec3, a1: vec3, d1: vec3, h: scalar, physics: Physics):
        """One Dormand-Prince step of length h (s) from a state whose derivatives are (a1, d1):
        the fifth-order state, its derivatives (the next step's first stage) and the error
        estimate over tolerance (accept the step when it is at most 1)."""
        x7, v7, w7, a7, d7, position_error, velocity_error, spin_error = stages(
            position, velocity, spin, a1, d1, h, physics, wp.int32(0)
        )
        air = physics.air
        tolerance = air.tolerance
        error = wp.max(
            wp.length(position_error) / (tolerance * (wp.length(x7 - position) + air.radius)),
            wp.length(velocity_error) / (tolerance * (wp.max(wp.length(velocity), wp.length(v7)) + air.speed_floor)),
        )
        if wp.static(SPIN_CHANGES):
            spin_floor = air.speed_floor / air.radius
            error = wp.max(error, wp.length(spin_error) / (tolerance * (wp.max(wp.length(spin), wp.length(w7)) + spin_floor)))
        return x7, v7, w7, a7, d7, error

    return SimpleNamespace(rates=rates, step=step)


@functools.cache
def make_dense_output(precision: str) -> SimpleNamespace:
    """The quintic Hermite on a step, and the root finder on it."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.func
    def hermite(theta: scalar, y0: scalar, dy0: scalar, ddy0: scalar, y1: scalar, dy1: scalar, ddy1: scalar):
        """The quintic with values y, first derivatives dy and second derivatives ddy (per unit
        theta) at theta = 0 and 1, and its derivative, at theta."""
        s = theta
        s2 = s * s
        s3 = s2 * s
        h0 = scalar(1.0) + s3 * (scalar(-10.0) + s * (scalar(15.0) - scalar(6.0) * s))
        h1 = s + s3 * (scalar(-6.0) + s * (scalar(8.0) - scalar(3.0) * s))
        h2 = scalar(0.5) * s2 + s3 * (scalar(-1.5) + s * (scalar(1.5) - scalar(0.5) * s))
        h4 = s3 * (scalar(-4.0) + s * (scalar(7.0) - scalar(3.0) * s))
        h5 = s3 * (scalar(0.5) + s * (scalar(-1.0) + scalar(0.5) * s))
        value = h0 * y0 + h1 * dy0 + h2 * ddy0 + (scalar(1.0) - h0) * y1 + h4 * dy1 + h5 * ddy1
        q = s2 * (scalar(-30.0) + s * (scalar(60.0) - scalar(30.0) * s))  # d(h0)/ds
        d1 = scalar(1.0) + s2 * (scalar(-18.0) + s * (scalar(32.0) - scalar(15.0) * s))
        d2 = s + s2 * (scalar(-4.5) + s * (scalar(6.0) - scalar(2.5) * s))
        d4 = s2 * (scalar(-12.0) + s * (scalar(28.0) - scalar(15.0) * s))
        d5 = s2 * (scalar(1.5) + s * (scalar(-4.0) + scalar(2.5) * s))
        slope = q * (y0 - y1) + d1 * dy0 + d2 * ddy0 + d4 * dy1 + d5 * ddy1
        return value, slope

    @wp.func
    def hermite_vec(theta: scalar, y0: vec3, dy0: vec3, ddy0: vec3, y1: vec3, dy1: vec3, ddy1: vec3):
        """`hermite` of each component of a vector."""
        x, dx = hermite(theta, y0[0], dy0[0], ddy0[0], y1[0], dy1[0], ddy1[0])
        y, dy = hermite(theta, y0[1], dy0[1], ddy0[1], y1[1], dy1[1], ddy1[1])
        z, dz = hermite(theta, y0[2], dy0[2], ddy0[2], y1[2], dy1[2], ddy1[2])
        return vec3(x, y, z), vec3(dx, dy, dz)

    @wp.func
    def cubic_vec(theta: scalar, y0: vec3, dy0: vec3, y1: vec3, dy1: vec3):
        """The cubic Hermite of values y and derivatives dy (per unit theta) at theta."""
        s = theta
        s2 = s * s
        h00 = scalar(1.0) + s2 * (scalar(2.0) * s - scalar(3.0))
        h10 = s + s2 * (s - scalar(2.0))
        h11 = s2 * (s - scalar(1.0))
        return h00 * y0 + h10 * dy0 + (scalar(1.0) - h00) * y1 + h11 * dy1

    return SimpleNamespace(hermite=hermite, hermite_vec=hermite_vec, cubic_vec=cubic_vec)
