"""Float64 reference: one pellet on one plane of any orientation, followed until it rests.

SciPy `solve_ivp` (DOP853) with terminal events moves the pellet through its phases: flight (gravity,
and the air of `reference.air` when given), impact (`reference.ballistic.impact_law`), sliding,
rolling, lift-off and rest. The laws of motion along the plane (docs/ground.md) are written here again
in the plane's own frame (e1, e2, n), component by component, independently of the vector form of
`physics.surface_motion`: the yardstick of its tests and, later, of the pipeline's.

Plane frame: e1 any unit vector along the plane, e2 = n x e1 (e1 x e2 = n). On the plane the centre is
x = point + R n + a1 e1 + a2 e2; spin omega = w1 e1 + w2 e2 + wn n. Since omega x n = w2 e1 - w1 e2, the
contact point's slip is s = (v1 - R w2, v2 + R w1); a force f at the contact point (-R n) turns the
spin at -(n x f) / (k R) per unit mass, i.e. (dw1, dw2) = (f2, -f1) / (k R).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .air import Pellet, derivatives, drag_force, lift_force, spin_torque
from .ballistic import impact_law

INERTIA_FACTOR = 0.4  # I = 2/5 m R^2
# a slip or a speed below STOP times the phase's speed scale (|v| + R |omega| at its start) ends the
# phase, the state then set exactly: well above the integrator's noise (rtol 1e-12), which near a
# zero of the slip would otherwise chatter around it with the friction's direction
STOP = 1e-9


@dataclasses.dataclass(frozen=True)
class Ground:
    """The plane's material: restitution, friction, the rolling resistance c (force c N) and the
    ploughing resistance b (1/m: force b m |v|^2 against the velocity, through the centre)."""

    restitution: float = 0.01
    mu_s: float = 0.5
    mu_d: float = 0.45
    rolling_resistance: float = 0.0
    ploughing: float = 0.0


@dataclasses.dataclass
class Phase:
    mode: str  # "flight", "sliding", "rolling"
    t: float  # s, when it begins
    sols: list  # solve_ivp dense solutions, one after the other: y(t) = (x, v, omega, path), world frame


@dataclasses.dataclass
class Result:
    state: str  # "rest", "escaped" (flies away for good), "moving" (t_max reached), "impacts" (budget spent)
    t: float
    x: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    path_length: float
    impacts: int
    phases: list


class Plane:
    """A plane (point, unit normal n) and its frame e1, e2 = n x e1."""

    def __init__(self, point, normal):
        self.p = np.asarray(point, float)
        self.n = np.asarray(normal, float) / np.linalg.norm(normal)
        helper = np.eye(3)[np.argmin(np.abs(self.n))]
        self.e1 = np.cross(helper, self.n)
        self.e1 /= np.linalg.norm(self.e1)
        self.e2 = np.cross(self.n, self.e1)

    def components(self, vector):
        return vector @ self.e1, vector @ self.e2, vector @ self.n

    def world(self, c1, c2, cn=0.0):
        return c1 * self.e1 + c2 * self.e2 + cn * self.n


class Model:
    """The forces on one pellet: gravity, and the air when given (per unit mass)."""

    def __init__(self, radius, density, gravity, air):
        self.pellet = Pellet(radius, density)
        self.g = np.asarray(gravity, float)
        self.air = air if air is not None and air.density > 0.0 else None

    def applied(self, v, omega):
        """(g + a_air, T_air / I)."""
        if self.air is None:
            return self.g, np.zeros(3)
        u = v - np.asarray(self.air.wind, float)
        force = drag_force(u, self.pellet.radius, self.air)
        if self.air.magnus:
            force = force + lift_force(u, omega, self.pellet.radius, self.air)
        torque = spin_torque(omega, self.pellet.radius, self.air) if self.air.spin_decay else np.zeros(3)
        return self.g + force / self.pellet.mass, torque / self.pellet.inertia


def surface_rates(y, plane: Plane, model: Model, ground: Ground, rolling: bool):
    """(dy/dt, N/m, |F|/m) sliding or rolling on the plane, y = (x, v, omega, path) in the world
    frame; |F|/m the static friction rolling needs (0 sliding)."""
    R, k = model.pellet.radius, INERTIA_FACTOR
    v, omega = y[3:6], y[6:9]
    acc, alpha = model.applied(v, omega)
    g1, g2, gn = plane.components(acc)
    al1, al2, aln = plane.components(alpha)
    v1, v2, _ = plane.components(v)
    w1, w2, _ = plane.components(omega)
    load = -gn
    speed = math.hypot(v1, v2)
    p1, p2 = -ground.ploughing * speed * v1, -ground.ploughing * speed * v2  # -b |v| v, no torque
    if not rolling:
        s1, s2 = v1 - R * w2, v2 + R * w1
        slip = math.hypot(s1, s2)
        if slip == 0.0:  # no slip yet: it grows along the drive without friction
            s1, s2 = g1 + p1, g2 + p2
            slip = math.hypot(s1, s2)
        f1, f2 = (-ground.mu_d * load * s1 / slip, -ground.mu_d * load * s2 / slip) if slip > 0.0 else (0.0, 0.0)
        a1, a2, needed = g1 + p1 + f1, g2 + p2 + f2, 0.0
    else:
        c = ground.rolling_resistance
        if speed > 0.0:
            r1, r2 = -c * load * v1 / speed + p1, -c * load * v2 / speed + p2
        else:  # at rest the resistance holds up to c N
            drive = math.hypot(g1, g2)
            hold = min(c * load, drive) / drive if drive > 0.0 else 0.0
            r1, r2 = -hold * g1, -hold * g2
        # the slip's rates vanish: a1 - R dw2 = 0 and a2 + R dw1 = 0, with a = g + r + F and
        # (dw1, dw2) = (F2, -F1) / (k R) + alpha:  F (1 + 1/k) = -(g + r) + R (alpha2, -alpha1)
        F1 = (-(g1 + r1) + R * al2) / (1.0 + 1.0 / k)
        F2 = (-(g2 + r2) - R * al1) / (1.0 + 1.0 / k)
        a1, a2, needed = g1 + r1 + F1, g2 + r2 + F2, math.hypot(F1, F2)
        f1, f2 = F1, F2
    dw = plane.world(f2 / (k * R) + al1, -f1 / (k * R) + al2, aln)
    return np.concatenate([v, plane.world(a1, a2), dw, [speed]]), load, needed


def _solve(rhs, y0, t0, t_max, events, rtol):
    from scipy.integrate import solve_ivp

    atol = np.array([1e-13] * 6 + [1e-10] * 3 + [1e-13])
    sol = solve_ivp(rhs, (t0, t_max), y0, method="DOP853", rtol=rtol, atol=atol, events=events, dense_output=True)
    if sol.status == -1:
        raise RuntimeError(sol.message)
    best = (-1, sol.t[-1], sol.y[:, -1])
    for i, (te, ye) in enumerate(zip(sol.t_events, sol.y_events)):
        if len(te) and (best[0] < 0 or te[0] < best[1]):
            best = (i, te[0], ye[0])
    return best, sol.sol


def _event(function, direction):
    function.terminal, function.direction = True, direction
    return function


def _on_plane(y, plane: Plane, radius):
    """y with the centre put at height R exactly and no normal speed."""
    y = y.copy()
    y[0:3] -= ((y[0:3] - plane.p) @ plane.n - radius) * plane.n
    y[3:6] -= (y[3:6] @ plane.n) * plane.n
    return y


def _held(y, plane: Plane, model: Model, ground: Ground) -> bool:
    """Whether the slope cannot restart a pellet at rest: |g_t| <= c (-g . n) (no air force at rest)."""
    g1, g2, gn = plane.components(model.g)
    return math.hypot(g1, g2) <= ground.rolling_resistance * -gn


def _to_zero(y, t, dy, n, radius, speed):
    """(t, y) moved on at the rates dy until the slip (speed False) or the speed (True), of size
    STOP times its scale, reaches 0: the last 1e-9 of the phase, to first order."""
    q, rate = (y[3:6], dy[3:6]) if speed else (y[3:6] - radius * np.cross(y[6:9], n), dy[3:6] - radius * np.cross(dy[6:9], n))
    length = np.linalg.norm(q)
    closing = q @ rate / length if length > 0.0 else 0.0
    if closing >= 0.0:
        return t, y
    dt = length / -closing
    return t + dt, y + dy * dt


def _surface_phase(y, t, t_max, plane, model, ground, rest_speed, rtol):
    """Slide or roll from y (on the plane) to the next switch; (phase, next mode, t, y)."""
    R = model.pellet.radius
    v1, v2, _ = plane.components(y[3:6])
    w1, w2, _ = plane.components(y[6:9])
    acc, _alpha = model.applied(y[3:6], y[6:9])
    g1, g2, gn = plane.components(acc)
    load = -gn
    if load <= 0.0:
        return None, "flight", t, y
    slip = math.hypot(v1 - R * w2, v2 + R * w1)
    scale = math.hypot(v1, v2) + R * np.linalg.norm(y[6:9])
    rolling = slip <= 1e-12 * scale
    speed0 = math.hypot(v1, v2)
    if rolling:
        if speed0 <= rest_speed * (1.0 + 1e-9) and _held(y, plane, model, ground):
            return None, "rest", t, y
        if surface_rates(y, plane, model, ground, True)[2] > ground.mu_s * load:
            rolling = False

    def rhs(_t, y):
        return surface_rates(y, plane, model, ground, rolling)[0]

    def lift(_t, y):
        return surface_rates(y, plane, model, ground, rolling)[1]

    events = [_event(lift, -1.0)]
    if rolling:
        # to the rest speed (where it rests if the slope cannot restart it), else on to a stop
        resting = speed0 > rest_speed * (1.0 + 1e-9) and rest_speed > STOP * scale
        stop_speed = rest_speed if resting else STOP * scale

        def speed(_t, y):
            return np.linalg.norm(y[3:6]) - stop_speed

        def grip(_t, y):
            _, load, needed = surface_rates(y, plane, model, ground, True)
            return needed - ground.mu_s * load

        events += [_event(speed, -1.0), _event(grip, 1.0)]
    else:

        def slip_event(_t, y):
            a1, a2, _ = plane.components(y[3:6])
            b1, b2, _ = plane.components(y[6:9])
            return math.hypot(a1 - R * b2, a2 + R * b1) - STOP * scale

        events.append(_event(slip_event, -1.0))
    (i, t_end, y_end), sol = _solve(rhs, y, t, t_max, events, rtol)
    phase = Phase("rolling" if rolling else "sliding", t, [sol])
    y_end = _on_plane(y_end, plane, R)
    if i < 0:
        return phase, "moving", t_end, y_end
    if i == 0:
        return phase, "flight", t_end, y_end
    if i == 1 and not (rolling and resting):  # a slip or a speed at STOP: on to 0
        t_end, y_end = _to_zero(y_end, t_end, rhs(t_end, y_end), plane.n, R, rolling)
    if not rolling:  # the slip vanished: set it to zero exactly (omega_t = n x v / R)
        a1, a2, _ = plane.components(y_end[3:6])
        wn = y_end[6:9] @ plane.n
        y_end[6:9] = plane.world(-a2 / R, a1 / R, wn)
        return phase, "surface", t_end, y_end
    if i == 1 and _held(y_end, plane, model, ground):
        return phase, "rest", t_end, y_end
    if i == 1 and not resting:  # stopped on a slope too steep to rest on: rolls back from rest
        wn = y_end[6:9] @ plane.n
        y_end[3:6], y_end[6:9] = 0.0, wn * plane.n
    return phase, "surface", t_end, y_end


def _flight_phase(y, t, t_max, plane, model, rtol):
    """Fly from y until the pellet meets the plane; (phase, "impact" or "escaped", t, y)."""
    R = model.pellet.radius
    pellet, air = model.pellet, model.air

    def rhs(_t, y):
        if air is None:
            d = np.concatenate([y[3:6], model.g, np.zeros(3)])
        else:
            d = derivatives(_t, y[:9], pellet, air, model.g)
        return np.concatenate([d, [np.linalg.norm(y[3:6])]])

    def gap(_t, y):
        return (y[0:3] - plane.p) @ plane.n - R

    def closing(_t, y):
        return y[3:6] @ plane.n

    sols = []
    if y[3:6] @ plane.n > 0.0:  # leaving the plane: its gap is armed once the pellet turns back
        (i, t, y), sol = _solve(rhs, y, t, t_max, [_event(closing, -1.0)], rtol)
        sols.append(sol)
        if i < 0:
            return Phase("flight", t, sols), "escaped", t, y
    (i, t, y), sol = _solve(rhs, y, t, t_max, [_event(gap, -1.0)], rtol)
    sols.append(sol)
    if i < 0:
        return Phase("flight", t, sols), "escaped", t, y
    y = y.copy()
    y[0:3] -= ((y[0:3] - plane.p) @ plane.n - R) * plane.n
    return Phase("flight", t, sols), "impact", t, y


def follow(
    x0,
    v0,
    omega0,
    *,
    radius: float,
    point=(0.0, 0.0, 0.0),
    normal=(0.0, 1.0, 0.0),
    gravity=(0.0, -9.81, 0.0),
    ground: Ground = Ground(),
    rest_speed: float = 0.0,
    density: float = 7000.0,
    air=None,
    t_max: float = 1e4,
    max_impacts: int = 100,
    rtol: float = 1e-12,
) -> Result:
    """Follow one pellet (centre x0, velocity v0, spin omega0) over the plane until it rests.

    A pellet at height R with no normal speed (within 1e-12 |v|, its rounding) starts on the plane, one closing on it starts with an
    impact. After an impact it leaves the plane if its rebound normal speed exceeds sqrt(2 R N/m)
    (N/m = -(g + a_air) . n), else its normal speed is dropped and it moves along the plane.
    `air`: a `scene.schema.Air` (with the pellet's `density`), None: the vacuum."""
    plane, model = Plane(point, normal), Model(radius, density, gravity, air)
    y = np.concatenate([np.asarray(x0, float), np.asarray(v0, float), np.asarray(omega0, float), [0.0]])
    t, impacts, phases = 0.0, 0, []
    gap, vn = (y[0:3] - plane.p) @ plane.n - radius, y[3:6] @ plane.n
    touching = abs(gap) <= 1e-12 * max(radius, np.abs(y[0:3] - plane.p).max())
    still = abs(vn) <= 1e-12 * np.linalg.norm(y[3:6])  # no normal speed but its rounding
    mode = ("surface" if still else "impact" if vn < 0.0 else "flight") if touching else "flight"
    if touching and still:
        y = _on_plane(y, plane, radius)

    def result(state):
        return Result(state, t, y[0:3], y[3:6], y[6:9], float(y[9]), impacts, phases)

    while True:
        if mode == "flight":
            phase, mode, t, y = _flight_phase(y, t, t_max, plane, model, rtol)
            phases.append(phase)
            if mode == "escaped":
                return result("escaped")
        elif mode == "impact":
            if impacts >= max_impacts:
                return result("impacts")
            impacts += 1
            v, omega, _ = impact_law(
                y[3:6][None],
                y[6:9][None],
                plane.n,
                radius=radius,
                restitution=ground.restitution,
                mu_s=ground.mu_s,
                mu_d=ground.mu_d,
                gravity=model.g,
            )
            y[3:6], y[6:9] = v[0], omega[0]
            load = -(model.applied(y[3:6], y[6:9])[0] @ plane.n)
            rebound = y[3:6] @ plane.n
            leaves = rebound >= 0.0 if load <= 0.0 else rebound > math.sqrt(2.0 * radius * load)
            mode = "flight" if leaves else "surface"
            if not leaves:
                y = _on_plane(y, plane, radius)
        elif mode == "surface":
            phase, mode, t, y = _surface_phase(y, t, t_max, plane, model, ground, rest_speed, rtol)
            if phase is not None:
                phases.append(phase)
            if mode == "rest":  # at rest: no velocity, no rolling spin (docs/ground.md 4)
                y = y.copy()
                y[3:6], y[6:9] = 0.0, (y[6:9] @ plane.n) * plane.n
            if mode in ("rest", "moving"):
                return result(mode)
