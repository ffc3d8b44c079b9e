"""A float64 reference for a pellet along a leaning post's side (docs/geometry.md, "Along a leaning
side"), written in the cylinder's own coordinates and sharing no code with `physics/side_follow.py`.

The centre moves on the cylinder of radius s = r + R about the axis a: its angle phi about the axis
(from e1, with e2 = a x e1) and its height z along it; frame e_rho (the normal), e_phi, a, turning
at phi' = v_phi / s about a. Per unit mass, with g's components g_rho, g_phi, g_z there and the spin's
components (w_rho, w_phi, w_z) in the turning frame (d/dt of a component = the torque's minus
(phi' a x w)'s):

- load N = -g_rho - v_phi^2 / s (lift-off where it falls to 0);
- slip (v_phi - R w_z, v_z + R w_phi) (the contact point's velocity, v + w x (-R e_rho));
- sliding: F = -mu_d N slip/|slip|; v_phi' = g_phi + F_phi, v_z' = g_z + F_z; the torque
  (-R e_rho) x F gives w_rho' = phi' w_phi, w_phi' = F_z/(k R) - phi' w_rho, w_z' = -F_phi/(k R);
- rolling (w_z = v_phi / R, w_phi = -v_z / R kept; rolling resistance r = -c N v/|v|):
  v_phi' = (g_phi + r_phi)/(1 + k), v_z' = (g_z + r_z + k R phi' w_rho)/(1 + k), w_rho' = phi' w_phi;
  the friction F = v' - g - r must stay within mu_s N;
- rest: speed <= rest_speed where |g_t| <= c (-g_rho) (docs/ground.md 4).

`follow_side(...)` integrates the phases with `solve_ivp` (DOP853, rtol 1e-12) and terminal events:
N = 0 ("flight"), z = 0 or L ("end"), the slip to 1e-9 of the speed scale (sliding to rolling), the
grip lost (rolling to sliding), the speed to the rest speed ("rest" where held, else on from a stop).
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

K = 0.4  # I = K m R^2


@dataclass
class SideEnd:
    """Where the side's phases end: state "flight", "end", "rest" or "unfinished"; centre x (m),
    velocity v (m/s), spin w (rad/s), time t (s), path (m) along the side, phases taken."""

    state: str
    x: np.ndarray
    v: np.ndarray
    w: np.ndarray
    t: float
    path: float
    phases: int


def _frame(a):
    e1 = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def follow_side(
    x0, v0, w0, *, radius, point, axis, post_radius, length, gravity=(0.0, -9.81, 0.0), mu_s=0.5, mu_d=0.45, c=0.0,
    rest_speed=0.0, t_max=100.0, max_phases=32,
):  # fmt: skip
    """Follow a pellet on the side of the post (base centre `point`, `axis`, radius, length) from
    x0 (on it), v0 (along it), w0 (module docstring)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    p, g, R = np.asarray(point, float), np.asarray(gravity, float), float(radius)
    e1, e2 = _frame(a)
    s = post_radius + R
    d = np.asarray(x0, float) - p
    z = d @ a
    phi = math.atan2(d @ e2, d @ e1)

    def basis(phi):
        er = math.cos(phi) * e1 + math.sin(phi) * e2
        return er, np.cross(a, er)

    er, ef = basis(phi)
    v0, w0 = np.asarray(v0, float), np.asarray(w0, float)
    y = np.array([phi, z, v0 @ ef, v0 @ a, w0 @ er, w0 @ ef, w0 @ a, 0.0])
    t = 0.0

    def parts(y):
        er, ef = basis(y[0])
        return er, ef, g @ er, g @ ef, g @ a

    def load(y):
        return -parts(y)[2] - y[2] ** 2 / s

    def sliding(t, y):
        _er, _ef, gr, gf, gz = parts(y)
        n = max(-gr - y[2] ** 2 / s, 0.0)
        slip = np.array([y[2] - R * y[6], y[3] + R * y[5]])
        size = np.hypot(*slip)
        f = -mu_d * n * slip / size if size > 0 else np.zeros(2)
        turn = y[2] / s
        return [
            turn,
            y[3],
            gf + f[0],
            gz + f[1],
            turn * y[5],
            f[1] / (K * R) - turn * y[4],
            -f[0] / (K * R),
            np.hypot(y[2], y[3]),
        ]

    def rolling_parts(y):
        _er, _ef, gr, gf, gz = parts(y)
        n = max(-gr - y[2] ** 2 / s, 0.0)
        speed = np.hypot(y[2], y[3])
        r = -c * n * y[2:4] / speed if speed > 0 else np.zeros(2)
        turn = y[2] / s
        dvf = (gf + r[0]) / (1 + K)
        dvz = (gz + r[1] + K * R * turn * y[4]) / (1 + K)
        return n, turn, dvf, dvz, np.hypot(dvf - gf - r[0], dvz - gz - r[1])

    def rolling(t, y):
        _n, turn, dvf, dvz, _f = rolling_parts(y)
        return [turn, y[3], dvf, dvz, turn * (-y[3] / R), -dvz / R, dvf / R, np.hypot(y[2], y[3])]

    def held(y):
        _er, _ef, gr, gf, gz = parts(y)
        return math.hypot(gf, gz) <= c * (-gr)

    def result(state, y, t, phases):
        er, ef = basis(y[0])
        x = p + y[1] * a + s * er
        v = y[2] * ef + y[3] * a
        w = y[4] * er + y[5] * ef + y[6] * a
        return SideEnd(state, x, v, w, t, y[7], phases)

    def event(f, direction=-1):
        f.terminal, f.direction = True, direction
        return f

    forced = None
    for phase in range(1, max_phases + 1):
        if load(y) <= 0:
            return result("flight", y, t, phase - 1)
        scale = np.hypot(y[2], y[3]) + R * np.linalg.norm(y[4:7]) + math.sqrt(np.linalg.norm(g) * R)
        slip = np.hypot(y[2] - R * y[6], y[3] + R * y[5])
        mode = "sliding" if slip > 1e-9 * scale or forced == "sliding" else "rolling"
        forced = None
        speed = np.hypot(y[2], y[3])
        if mode == "rolling":
            y[5], y[6] = -y[3] / R, y[2] / R
            if speed <= rest_speed and held(y):
                return result("rest", y, t, phase - 1)
            n, _turn, _dvf, _dvz, f = rolling_parts(y)
            if f > mu_s * n:
                mode = "sliding"
        events = [event(lambda t, y: load(y)), event(lambda t, y: y[1]), event(lambda t, y: length - y[1], -1)]
        names = ["flight", "end", "end"]
        if mode == "sliding":
            events.append(event(lambda t, y, scale=scale: np.hypot(y[2] - R * y[6], y[3] + R * y[5]) - 1e-9 * scale))
            names.append("slip")
            rhs = sliding
        else:
            goal = rest_speed if held(y) else 0.0
            events.append(event(lambda t, y: mu_s * rolling_parts(y)[0] - rolling_parts(y)[4]))
            stop = max(goal, 1e-9 * scale)
            events.append(event(lambda t, y, stop=stop: np.hypot(y[2], y[3]) - stop))
            names += ["grip", "stop"]
            rhs = rolling
        sol = solve_ivp(rhs, (t, t + t_max), y, method="DOP853", rtol=1e-12, atol=1e-15, events=events)
        if sol.status != 1:
            return result("unfinished", sol.y[:, -1], sol.t[-1], phase)
        hit = min(range(len(events)), key=lambda i: sol.t_events[i][0] if len(sol.t_events[i]) else math.inf)
        t, y = float(sol.t_events[hit][0]), sol.y_events[hit][0].copy()
        if names[hit] in ("flight", "end"):
            return result(names[hit], y, t, phase)
        if names[hit] == "grip":
            forced = "sliding"
        elif names[hit] == "slip":
            y[5], y[6] = -y[3] / R, y[2] / R
        elif names[hit] == "stop":
            if held(y) and np.hypot(y[2], y[3]) <= rest_speed * (1 + 1e-9):
                return result("rest", y, t, phase)
            y[2:4] = 0.0
            y[5:7] = 0.0
    return result("unfinished", y, t, max_phases)
