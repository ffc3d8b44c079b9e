"""Float64 reference for a pellet's flight in air: drag, Magnus lift, spin decay and wind.

Pure NumPy + SciPy (imported when a flight is integrated), no Warp: the yardstick the package's
integrator is compared against in the tests and benchmarks. The laws are written here again, from
their sources (docs/air.md, whose section numbers are in brackets), independently of
`physics.air`. The air is the scene's `Air` (warp_ricochet.scene).

State y = (x, v, omega), 9 components. Equations of motion [docs/air.md 6]:
    dx/dt = v
    dv/dt = g + (F_D + F_L) / m
    domega/dt = T / I,          I = 2/5 m R^2
with u = v - wind the velocity relative to the air (drag and lift act on u), and the air at rest
apart from the uniform wind (no vorticity, so the torque acts on omega itself).
Buoyancy and added mass are left out (rho_air / rho_pellet ~ 1e-4).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..physics.drag_tables import BRAUN_CD, BRAUN_MACH, DRAG_TABLES, GS_CD, GS_MACH  # noqa: F401
from ..scene.schema import Air

GAMMA_AIR = 1.4  # ratio of specific heats of air, only in Loth 2021's low-Re (rarefaction) branch

# ---------------------------------------------------------------------------------------------
# Drag coefficient laws [docs/air.md 1]
# ---------------------------------------------------------------------------------------------


def clift_gauvin_cd(re: float) -> float:
    """Clift & Gauvin (1970) standard sphere drag, Re < 3e5 [docs/air.md 1.2]:
    C_D = 24/Re (1 + 0.15 Re^0.687) + 0.42 / (1 + 42500 Re^-1.16)."""
    return 24.0 / re * (1.0 + 0.15 * re**0.687) + 0.42 / (1.0 + 42500.0 * re**-1.16)


def loth2021_factors(mach: float) -> tuple[float, float, float]:
    """(C_M, G_M, H_M) of Loth et al. (2021) eqs. (7a,b) and (8b-e) [docs/air.md 1.1].

    Branch tests as in jCODE (strict <); FLEXI/elexi uses <= at 1.5 and 1.0 (same values up to
    the jumps listed in NOTES.md)."""
    if mach < 1.5:
        c_m = 1.65 + 0.65 * math.tanh(4.0 * mach - 3.4)
    else:
        c_m = 2.18 - 0.13 * math.tanh(0.9 * mach - 2.7)
    if mach < 0.8:
        g_m = 166.0 * mach**3 + 3.29 * mach**2 - 10.9 * mach + 20.0
    else:
        g_m = 5.0 + 40.0 / mach**3
    if mach < 1.0:
        h_m = 0.0239 * mach**3 + 0.212 * mach**2 - 0.074 * mach + 1.0
    else:
        h_m = 0.93 + 1.0 / (3.5 + mach**5)
    return c_m, g_m, h_m


def _loth_high_f(re: float, c_m: float, g_m: float, h_m: float) -> float:
    """f = C_D Re / 24 of Loth 2021 eq. (8a), compression-dominated branch (Re > 45)."""
    return (1.0 + 0.15 * re**0.687) * h_m + re / 24.0 * 0.42 * c_m / (1.0 + 42500.0 / re ** (1.16 * c_m) + g_m / math.sqrt(re))


def free_molecular_cd(s: float) -> float:
    """Free-molecular sphere drag at speed ratio s = M sqrt(gamma/2), diffuse reflection, wall at
    the gas temperature (the C_D,fm of Loth 2008/2021 with T_p = T). Its s^-3 and s^-4 terms cancel
    as s -> 0, so below s = 3e-3 the series (16/(3 sqrt pi) + 2 sqrt(pi)/3)/s + 16 s/(15 sqrt pi)
    is used (both forms within 1e-11 of the exact value there)."""
    sp = math.sqrt(math.pi)
    if s < 3e-3:
        return (16.0 / (3.0 * sp) + 2.0 * sp / 3.0) / s + 16.0 * s / (15.0 * sp)
    return (
        (1.0 + 2.0 * s * s) * math.exp(-s * s) / (s**3 * sp)
        + (4.0 * s**4 + 4.0 * s * s - 1.0) * math.erf(s) / (2.0 * s**4)
        + 2.0 * sp / (3.0 * s)
    )


def _loth_low_f(mach: float, re: float, kn: float, gamma: float) -> float:
    """f = C_D Re / 24 of Loth 2021's rarefaction-dominated branch (Re <= 45), as in jCODE
    particle_functions.f90 (case LOTH) [docs/air.md 1.1]. kn = sqrt(pi gamma / 2) M / Re."""
    f_kn = 1.0 / (1.0 + kn * (2.514 + 0.8 * math.exp(-0.55 / kn))) if kn > 0.0 else 1.0
    f1 = (1.0 + 0.15 * re**0.687) * f_kn
    m4 = mach**4
    if mach < 1e-12:  # Re/24 M^4 C_D2 <= Re/24 M^4 J_M ~ 0.26 M: below 1e-12 of f1; avoids inf/inf
        return f1 / (1.0 + m4)
    if mach <= 1.0:
        j_m = 2.26 - 0.1 / mach + 0.14 / mach**3
    else:
        j_m = 1.6 + 0.25 / mach + 0.11 / mach**2 + 0.44 / mach**3
    cd_fm = free_molecular_cd(mach * math.sqrt(0.5 * gamma))
    r = math.sqrt(re / 45.0)  # 1 + (C_Dfm/J_M - 1) r, written so that C_Dfm/J_M << eps survives
    cd2 = cd_fm / ((1.0 - r) + cd_fm / j_m * r)
    return f1 / (1.0 + m4) + re / 24.0 * m4 * cd2 / (1.0 + m4)


def loth2021_f(mach: float, re: float, kn: float | None = None, gamma: float = GAMMA_AIR) -> float:
    """Drag correction f = C_D Re / 24 of Loth et al. (2021), finite as Re -> 0 (Stokes: f -> 1).

    Re > 45: eq. (8a); Re <= 45: the paper's own rarefaction branch. kn defaults to
    sqrt(pi gamma/2) M/Re; pass it from the fluid (mu / (rho c d) form) to avoid 0/0 at u = 0."""
    if re > 45.0:
        return _loth_high_f(re, *loth2021_factors(mach))
    if kn is None:
        kn = math.sqrt(0.5 * math.pi * gamma) * mach / re
    return _loth_low_f(mach, re, kn, gamma)


def loth2021_cd(mach: float, re: float, gamma: float = GAMMA_AIR) -> float:
    """C_D(M, Re) of Loth, Daspit, Jeong, Nagata, Nonomura (2021), AIAA J 59(8):3261 [docs/air.md 1.1]."""
    return 24.0 / re * loth2021_f(mach, re, gamma=gamma)


def table_cd(mach: float, machs: Sequence[float], cds: Sequence[float]) -> float:
    """C_D from a Mach table: linear interpolation, held constant outside the table [docs/air.md 1.4]."""
    return float(np.interp(mach, machs, cds))


def constant_cd(mach: float, re: float, value: float) -> float:
    """A constant C_D (the `constant` law)."""
    return value


# ---------------------------------------------------------------------------------------------
# Magnus lift [docs/air.md 2]
# ---------------------------------------------------------------------------------------------

LIFT_LAWS = ("loth2008", "linear", "sawicki2003")


def lift_ratio(s: float, re: float, law: str = "loth2008", slope: float = 0.5, cap: float | None = None) -> float:
    """C_L(S)/S, finite as S -> 0, so that F_L = 1/2 rho A R (C_L/S) (omega x u) needs no unit
    vector of omega x u [docs/air.md 2.1]. S = R |omega x u| / |u|^2 (perpendicular spin). Every
    law is capped at C_L = cap (None: 0.4 for sawicki2003, 0.5 for the others; inf: the law alone)."""
    if cap is None:
        cap = 0.4 if law == "sawicki2003" else 0.5
    if law == "loth2008":  # Loth (2008) eq. for the spin lift, Omega* = omega d / u = 2 S
        t_re = math.tanh(0.18 * math.sqrt(re)) if math.isfinite(re) else 1.0
        ratio = 2.0 * (1.0 - (0.675 + 0.15 * (1.0 + math.tanh(0.28 * (2.0 * s - 2.0)))) * t_re)
    elif law == "linear":  # C_L = slope S; 0.5 is loth2008's high-Re, small-S limit (2 (1 - 0.7488))
        ratio = slope
    elif law == "sawicki2003":  # Sawicki, Hubbard & Stronge (2003)
        ratio = 1.5 if s <= 0.1 else 0.09 / s + 0.6
    else:
        raise ValueError(f"unknown lift law {law!r}; allowed: {LIFT_LAWS}")
    return min(ratio, cap / s) if s > 0.0 else ratio  # every law: C_L <= cap


def lift_coefficient(
    s: float, law: str = "loth2008", re: float = math.inf, slope: float = 0.5, cap: float | None = None
) -> float:
    """C_L(S) of the lift laws [docs/air.md 2]; loth2008 at Reynolds number re (default: high-Re saturation)."""
    return s * lift_ratio(s, re, law, slope, cap)


# ---------------------------------------------------------------------------------------------
# Spin decay [docs/air.md 3]
# ---------------------------------------------------------------------------------------------

SPIN_DECAY_LAWS = ("dennis1980", "loth2008")


def rotation_coefficient(re_r: float, law: str = "dennis1980") -> float:
    """C_R(Re_R), Re_R = rho d^2 |omega| / mu, torque T = -(rho/2) R^5 C_R |omega| omega [docs/air.md 3].

    dennis1980: max(64 pi/Re_R, 12.9/sqrt(Re_R) + 128.4/Re_R) (Stokes below Re_R = 31.7, the fit
    to Dennis, Singh & Ingham 1980 above; stated range 32-1000, extrapolated above).
    loth2008: 64 pi/Re_R (1 + 5/(64 pi) Re_R^0.6)."""
    return 64.0 * math.pi / re_r * rotation_factor(re_r, law)


def rotation_factor(re_r: float, law: str = "dennis1980") -> float:
    """h = C_R Re_R / (64 pi): the torque in Stokes form T = -8 pi mu R^3 h omega (h -> 1 at 0)."""
    if law == "dennis1980":
        return max(1.0, (12.9 * math.sqrt(re_r) + 128.4) / (64.0 * math.pi))
    if law == "loth2008":
        return 1.0 + 5.0 / (64.0 * math.pi) * re_r**0.6
    raise ValueError(f"unknown spin decay law {law!r}; allowed: {SPIN_DECAY_LAWS}")


# ---------------------------------------------------------------------------------------------
# Air, pellet
# ---------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Pellet:
    radius: float  # m
    density: float  # kg/m^3

    @property
    def mass(self) -> float:
        return 4.0 / 3.0 * math.pi * self.radius**3 * self.density

    @property
    def inertia(self) -> float:
        return 0.4 * self.mass * self.radius**2


def _as_pellet(pellet) -> Pellet:
    return pellet if isinstance(pellet, Pellet) else Pellet(*pellet)


# ---------------------------------------------------------------------------------------------
# Forces and equations of motion [docs/air.md 4, 6]
# ---------------------------------------------------------------------------------------------


def drag_force(u: np.ndarray, radius: float, air: Air) -> np.ndarray:
    """F_D = -1/2 rho C_D A |u| u * drag_factor, A = pi R^2 [docs/air.md 4].

    loth2021 is evaluated in Stokes form F_D = -3 pi mu d f(M, Re) u, f = C_D Re/24, finite at
    u -> 0; the Knudsen number is taken from the fluid, Kn = sqrt(pi gamma/2) mu/(rho c d)."""
    speed = math.sqrt(u @ u)
    d = 2.0 * radius
    if air.drag == "loth2021":
        re = air.density * speed * d / air.viscosity
        mach = speed / air.sound_speed
        kn = math.sqrt(0.5 * math.pi * GAMMA_AIR) * air.viscosity / (air.density * air.sound_speed * d)
        f = loth2021_f(mach, re, kn, GAMMA_AIR)
        return -3.0 * math.pi * air.viscosity * d * f * air.drag_factor * u
    if air.drag == "constant":
        cd = air.drag_coefficient
    else:
        machs, cds = zip(*air.table)
        cd = table_cd(speed / air.sound_speed, machs, cds)
    return -0.5 * air.density * cd * air.drag_factor * math.pi * radius**2 * speed * u


def lift_force(u: np.ndarray, omega: np.ndarray, radius: float, air: Air) -> np.ndarray:
    """F_L = 1/2 rho C_L A |u|^2 (omega x u)/|omega x u| = 1/2 rho A R (C_L/S) (omega x u),
    S = R |omega x u| / |u|^2 = R |omega_perp| / |u| [docs/air.md 2.1]. Zero when omega x u = 0."""
    cross = np.cross(omega, u)
    c2 = cross @ cross
    if c2 == 0.0:
        return np.zeros(3)
    speed2 = u @ u
    s = radius * math.sqrt(c2) / speed2
    re = air.density * math.sqrt(speed2) * 2.0 * radius / air.viscosity
    ratio = lift_ratio(s, re, air.lift, air.slope, air.cap)
    return 0.5 * air.density * math.pi * radius**3 * ratio * cross


def spin_torque(omega: np.ndarray, radius: float, air: Air) -> np.ndarray:
    """T = -(rho/2) R^5 C_R |omega| omega = -8 pi mu R^3 h(Re_R) omega, Re_R = rho d^2 |omega|/mu
    [docs/air.md 3]."""
    w = math.sqrt(omega @ omega)
    re_r = air.density * (2.0 * radius) ** 2 * w / air.viscosity
    h = rotation_factor(re_r, air.spin_decay_law)
    return -8.0 * math.pi * air.viscosity * radius**3 * h * omega


def derivatives(t: float, y: np.ndarray, pellet, air: Air, gravity) -> np.ndarray:
    """dy/dt for y = (x, v, omega) [docs/air.md 6]. density == 0 is the vacuum (gravity only)."""
    pellet = _as_pellet(pellet)
    v, omega = y[3:6], y[6:9]
    acc = np.array(gravity, dtype=float)
    dw = np.zeros(3)
    if air.density > 0.0:  # (the scene calls density 0 the vacuum)
        u = v - np.asarray(air.wind, dtype=float)
        force = drag_force(u, pellet.radius, air)
        if air.magnus:
            force = force + lift_force(u, omega, pellet.radius, air)
        acc = acc + force / pellet.mass
        if air.spin_decay:
            dw = spin_torque(omega, pellet.radius, air) / pellet.inertia
    return np.concatenate([v, acc, dw])


# ---------------------------------------------------------------------------------------------
# Flight to the planes
# ---------------------------------------------------------------------------------------------


class Contact(NamedTuple):
    t: float  # s, time of contact from the start of the flight
    plane: int  # index of the plane met
    x: np.ndarray  # m, centre at contact
    v: np.ndarray  # m/s
    omega: np.ndarray  # rad/s


def _gap_event(p, n, radius, direction=-1.0):
    def gap(t, y, *args):
        return (y[0] - p[0]) * n[0] + (y[1] - p[1]) * n[1] + (y[2] - p[2]) * n[2] - radius

    gap.terminal, gap.direction = True, direction
    return gap


def _normal_speed_event(n):
    def normal_speed(t, y, *args):
        return y[3] * n[0] + y[4] * n[1] + y[5] * n[2]

    normal_speed.terminal, normal_speed.direction = True, -1.0
    return normal_speed


def _integrate(y0, t0, t_max, events, pellet, air, gravity, rtol, atol, method="DOP853"):
    """Integrate to the first terminal event; returns (event index or -1, t, y)."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(derivatives, (t0, t_max), y0, method=method, rtol=rtol, atol=atol, events=events, args=(pellet, air, gravity))
    if sol.status == -1:
        raise RuntimeError(sol.message)
    best = (-1, sol.t[-1], sol.y[:, -1])
    for i, (te, ye) in enumerate(zip(sol.t_events, sol.y_events)):
        if len(te) and (best[0] < 0 or te[0] < best[1]):  # ties: the lower index (first seen)
            best = (i, te[0], ye[0])
    return best


def fly_to_planes(
    x0,
    v0,
    w0,
    pellet,
    air: Air,
    gravity,
    planes,
    touching: int = -1,
    t_max: float = 1000.0,
    rtol: float = 1e-12,
    atol=None,
    method: str = "DOP853",
) -> Contact | None:
    """Integrate the flight until the pellet meets a plane, or None if none before t_max.

    planes: list of (point, unit normal towards the pellet). The pellet meets plane k when its gap
    dot(x - p_k, n_k) - R reaches 0 while closing. As in the package's flight.py: planes are
    one-sided (a plane with the centre behind it at the start is ignored); a pellet touching or
    overlapping a plane and closing on it meets it at t = 0; the plane it is leaving (`touching`)
    is met at t = 0 if the normal speed is <= 0 ("stays on the surface"), else only after it has
    separated: the flight is integrated in two stages, first until the normal velocity turns
    towards that plane (the gap is then > 0), then with that plane's gap event armed. A single
    gap event from gap = 0 would fire at t = 0 whenever one step spans the whole excursion.
    Ties go to the lower index. method: solve_ivp's (the reference is DOP853 at rtol 1e-12; the
    benchmarks also time what a SciPy user would run at a looser tolerance).
    """
    pellet = _as_pellet(pellet)
    radius = pellet.radius
    y0 = np.concatenate([x0, v0, w0]).astype(float)
    if atol is None:
        atol = np.array([1e-12] * 6 + [1e-9] * 3)
    planes = [(np.asarray(p, float), np.asarray(n, float) / np.linalg.norm(n)) for p, n in planes]
    active = []
    for k, (p, n) in enumerate(planes):
        height, vn = (y0[:3] - p) @ n, y0[3:6] @ n
        if k == touching:
            if vn <= 0.0:
                return Contact(0.0, k, y0[:3], y0[3:6], y0[6:9])
            active.append(k)
        elif height >= 0.0:
            if height - radius <= 0.0 and vn < 0.0:
                return Contact(0.0, k, y0[:3], y0[3:6], y0[6:9])
            active.append(k)
    t0 = 0.0
    if touching >= 0:  # stage 1: the touching plane is disarmed until the normal speed turns
        others = [k for k in active if k != touching]
        events = [_gap_event(*planes[k], radius) for k in others]
        events.append(_normal_speed_event(planes[touching][1]))
        i, t0, y0 = _integrate(y0, 0.0, t_max, events, pellet, air, gravity, rtol, atol, method)
        if i < 0:
            return None
        if i < len(others):
            return Contact(t0, others[i], y0[:3], y0[3:6], y0[6:9])
    events = [_gap_event(*planes[k], radius) for k in active]
    i, t, y = _integrate(y0, t0, t_max, events, pellet, air, gravity, rtol, atol, method)
    if i < 0:
        return None
    return Contact(t, active[i], y[:3], y[3:6], y[6:9])


def trajectory(x0, v0, w0, pellet, air: Air, gravity, t_end: float, rtol: float = 1e-12, atol=None):
    """Dense solution of the flight over [0, t_end] (no planes), for tests and plots."""
    if atol is None:
        atol = np.array([1e-12] * 6 + [1e-9] * 3)
    from scipy.integrate import solve_ivp

    y0 = np.concatenate([x0, v0, w0]).astype(float)
    return solve_ivp(
        derivatives,
        (0.0, t_end),
        y0,
        method="DOP853",
        rtol=rtol,
        atol=atol,
        dense_output=True,
        args=(_as_pellet(pellet), air, gravity),
    )


# ---------------------------------------------------------------------------------------------
# Terminal speed and maximum range
# ---------------------------------------------------------------------------------------------


def drag_magnitude(speed: float, pellet, air: Air) -> float:
    """|F_D| at relative speed `speed` (no spin)."""
    pellet = _as_pellet(pellet)
    return float(np.linalg.norm(drag_force(np.array([speed, 0.0, 0.0]), pellet.radius, air)))


def terminal_speed(pellet, air: Air, g: float = 9.81) -> float:
    """Speed at which drag balances weight (vertical fall in still air), by root finding."""
    from scipy.optimize import brentq

    pellet = _as_pellet(pellet)
    weight = pellet.mass * g
    return brentq(lambda s: drag_magnitude(s, pellet, air) - weight, 1e-9, 3.0 * air.sound_speed, xtol=1e-14, rtol=1e-15)


def range_at(angle_deg: float, speed: float, pellet, air: Air, g: float = 9.81, spin=(0.0, 0.0, 0.0)) -> Contact:
    """Launch from flat ground (plane y = 0, pellet touching it) at angle_deg above horizontal;
    returns the landing contact (its x[0] is the range)."""
    pellet = _as_pellet(pellet)
    a = math.radians(angle_deg)
    contact = fly_to_planes(
        [0.0, pellet.radius, 0.0],
        [speed * math.cos(a), speed * math.sin(a), 0.0],
        spin,
        pellet,
        air,
        [0.0, -g, 0.0],
        [([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])],
        touching=0,
    )
    if contact is None:
        raise RuntimeError("no landing")
    return contact


def max_range(
    speed: float, pellet, air: Air, g: float = 9.81, bounds=(5.0, 55.0), step: float = 2.5
) -> tuple[float, float, float]:
    """Maximum range over launch angles: a coarse scan, then a bounded scalar minimisation.
    Returns (range m, best angle deg, time of flight s)."""
    from scipy.optimize import minimize_scalar

    angles = np.arange(bounds[0], bounds[1] + 0.5 * step, step)
    ranges = [range_at(a, speed, pellet, air, g).x[0] for a in angles]
    i = int(np.argmax(ranges))
    lo, hi = angles[max(i - 1, 0)], angles[min(i + 1, len(angles) - 1)]
    res = minimize_scalar(
        lambda a: -range_at(a, speed, pellet, air, g).x[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-3}
    )
    best = range_at(res.x, speed, pellet, air, g)
    return float(best.x[0]), float(res.x), float(best.t)
