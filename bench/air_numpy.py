"""A vectorised NumPy version of a ricochet in air, for the CPU comparison of `bench.air cpu`:
fixed-step classical RK4 over all pellets at once (float64), a contact located on the step's
cubic Hermite position by bisection and reached by one partial RK4 step, the impact law of
`warp_ricochet.reference.ballistic`. One plane, the default laws of docs/air.md (loth2021 drag
above Re = 45 and Clift-Gauvin's M -> 0 form of it below, loth2008 lift, dennis1980 spin decay),
still air. It is what a careful NumPy user would write; it is not a reference."""

from __future__ import annotations

import math

import numpy as np

from warp_ricochet.reference.ballistic import impact_law


def _loth_f(re, mach):
    """C_D Re / 24 of Loth et al. (2021) eq. (8a), subsonic factors (M < 0.8 for G_M, < 1 for H_M,
    < 1.5 for C_M); below Re = 45 the M -> 0 (Clift-Gauvin) form."""
    c_m = 1.65 + 0.65 * np.tanh(4.0 * mach - 3.4)
    g_m = np.where(mach < 0.8, 166.0 * mach**3 + 3.29 * mach**2 - 10.9 * mach + 20.0, 5.0 + 40.0 / mach**3)
    h_m = np.where(mach < 1.0, 0.0239 * mach**3 + 0.212 * mach**2 - 0.074 * mach + 1.0, 0.93 + 1.0 / (3.5 + mach**5))
    re = np.maximum(re, 1e-300)
    high = (1.0 + 0.15 * re**0.687) * h_m + re / 24.0 * 0.42 * c_m / (1.0 + 42500.0 / re ** (1.16 * c_m) + g_m / np.sqrt(re))
    low = 1.0 + 0.15 * re**0.687 + re / 24.0 * 0.42 / (1.0 + 42500.0 * re**-1.16)
    return np.where(re > 45.0, high, low)


def derivatives(y, radius, mass, air, gravity):
    """dy/dt for states y (N, 9) = (x, v, omega) in still air."""
    v, w = y[:, 3:6], y[:, 6:9]
    speed = np.sqrt(np.einsum("ij,ij->i", v, v))
    d, mu, rho = 2.0 * radius, air.viscosity, air.density
    re, mach = rho * speed * d / mu, speed / air.sound_speed
    drag = -3.0 * math.pi * mu * d * _loth_f(re, mach)[:, None] * air.drag_factor * v
    cross = np.cross(w, v)
    c = np.sqrt(np.einsum("ij,ij->i", cross, cross))
    s = radius * c / np.maximum(speed * speed, 1e-300)
    ratio = 2.0 * (1.0 - (0.675 + 0.15 * (1.0 + np.tanh(0.28 * (2.0 * s - 2.0)))) * np.tanh(0.18 * np.sqrt(re)))
    lift = 0.5 * rho * math.pi * radius**3 * ratio[:, None] * cross
    wn = np.sqrt(np.einsum("ij,ij->i", w, w))
    h = np.maximum(1.0, (12.9 * np.sqrt(rho * d * d * wn / mu) + 128.4) / (64.0 * math.pi))
    dw = -8.0 * math.pi * mu * radius**3 * h[:, None] * w / (0.4 * mass * radius**2)
    return np.concatenate([v, gravity + (drag + lift) / mass, dw], axis=1)


def rk4(y, h, f):
    """One classical RK4 step of sizes h (scalar or (N,)); returns (y', f(y))."""
    h = np.asarray(h, float).reshape(-1, 1) if np.ndim(h) else h
    k1 = f(y)
    k2 = f(y + 0.5 * h * k1)
    k3 = f(y + 0.5 * h * k2)
    k4 = f(y + h * k3)
    return y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), k1


def fly(y, h, f, point, normal, radius, leaving):
    """Fly every pellet until its gap n.(x - p) - R reaches 0 (pellets `leaving` the plane: once
    the gap has opened at a step's end, or at the step's end where the normal speed has turned
    if it is back at the plane by then); returns the states at contact, NaN where none in 600 s."""
    gap = lambda s: (s[:, :3] - point) @ normal - radius  # noqa: E731
    flying, out = np.ones(len(y), bool), np.full_like(y, np.nan)
    opened = ~leaving
    for _ in range(int(600.0 / h)):
        if not flying.any():
            break
        idx = np.flatnonzero(flying)
        y0 = y[idx]
        y1, f0 = rk4(y0, h, f)
        g0, g1 = gap(y0), gap(y1)
        met = opened[idx] & (g0 > 0.0) & (g1 <= 0.0)
        if met.any():
            out[idx[met]] = _contact(y0[met], y1[met], f0[met], f(y1[met]), h, f, gap)
            flying[idx[met]] = False
        # a pellet leaving the plane that is back at it when its normal speed turns: met there
        back = ~opened[idx] & (g1 <= 0.0) & (y1[:, 3:6] @ normal <= 0.0)
        out[idx[back]] = y1[back]
        flying[idx[back]] = False
        opened[idx] |= g1 > 0.0
        y[idx] = y1
    return out


def _contact(y0, y1, f0, f1, h, f, gap):
    """The contact inside a step: bisection on the cubic Hermite gap, then a partial RK4 step."""
    lo, hi = np.zeros(len(y0)), np.ones(len(y0))
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        t = mid[:, None]
        h00, h10, h01, h11 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t, -2 * t**3 + 3 * t**2, t**3 - t**2
        x = h00 * y0[:, :3] + h10 * h * f0[:, :3] + h01 * y1[:, :3] + h11 * h * f1[:, :3]
        above = gap(np.concatenate([x, y0[:, 3:]], 1)) > 0.0
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    return rk4(y0, hi * h, f)[0]


def ricochet(scene, position, velocity, spin, h):
    """Launch -> first contact -> impact law -> landing on the scene's first plane; returns
    (contact states (N, 9), landing states (N, 9)), NaN where a flight found no contact."""
    shot, surface, air = scene.shot, scene.surfaces[0], scene.air
    radius = 0.5 * shot.diameter
    mass = shot.density * 4.0 / 3.0 * math.pi * radius**3
    gravity = np.asarray(scene.physics.gravity, float)
    point, normal = np.asarray(surface.point, float), np.asarray(surface.normal, float)
    f = lambda y: derivatives(y, radius, mass, air, gravity)  # noqa: E731
    y = np.concatenate([position, velocity, spin], axis=1).astype(float)
    contact = fly(y.copy(), h, f, point, normal, radius, np.zeros(len(y), bool))
    hit = np.isfinite(contact[:, 0])
    v2, w2, _ = impact_law(
        contact[hit, 3:6],
        contact[hit, 6:9],
        normal,
        radius=radius,
        restitution=surface.restitution,
        mu_s=surface.mu_s,
        mu_d=surface.mu_d,
        gravity=gravity,
        duration=scene.physics.impact_duration,
    )
    after = np.concatenate([contact[hit, :3], v2, w2], axis=1)
    landing = np.full_like(contact, np.nan)
    landing[hit] = fly(after, h, f, point, normal, radius, np.ones(len(after), bool))
    return contact, landing
