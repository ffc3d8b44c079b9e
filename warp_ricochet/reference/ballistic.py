"""Vectorised NumPy float64 reference of the whole no-collision pipeline.

It is the yardstick of the tests and the NumPy side of the benchmarks. It is written in the
paper's explicit frame form (scalars along e_t, e_n, e_o: eqs. 13-15, 19-25), not in the
kernels' vector form, so the two implementations check each other.
"""

from __future__ import annotations

import math

import numpy as np

from ..physics.ballistic import MAX_FLIGHT_TIME, ROUNDING
from ..physics.impact import SOLID_SPHERE_INERTIA_FACTOR
from ..scene.vectors import scale_exponent, scaled, unit_vector
from ..tallies.sums import statistics_from_arrays
from .launch import pattern_directions

TOLERANCE = ROUNDING * np.finfo(np.float64).eps  # rounding noise, relative (physics.ballistic's rule in float64)
CLOSING_TOLERANCE = TOLERANCE  # normal speeds within rounding noise of 0 do not close


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def impact_law(
    velocity,
    angular_velocity,
    normal,
    *,
    radius,
    restitution,
    mu_s,
    mu_d,
    gravity=(0.0, -9.81, 0.0),
    duration=0.0,
    inertia_factor=SOLID_SPHERE_INERTIA_FACTOR,
):
    """Eqs. (1)-(25) for (N, 3) states; `normal` (3,) or (N, 3) unit normals. Returns
    (velocity', angular_velocity', slipped). Pellets not moving into the plane are unchanged.
    restitution, mu_s, mu_d may be scalars or (N,) arrays."""
    v = np.asarray(velocity, np.float64)
    w = np.asarray(angular_velocity, np.float64)
    e_n = np.broadcast_to(np.asarray(normal, np.float64), v.shape)
    E, mu_s, mu_d = (np.broadcast_to(np.asarray(x, np.float64), v.shape[:1]) for x in (restitution, mu_s, mu_d))
    R = radius
    k = inertia_factor  # I / (m R^2)

    v_cn = _dot(v, e_n)  # eq. (9)
    approaching = v_cn < 0.0
    # eq. (6): v_p = v_c + omega x r_{c->p}, r_{c->p} = -R e_n
    v_p = v + np.cross(w, -R * e_n)
    v_pt_vec = v_p - _dot(v_p, e_n)[:, None] * e_n  # eq. (4)
    # project again: when v_p is (nearly) along e_n the first projection leaves a rounding residue
    # whose direction is not tangential, and e_t built from it would not be orthogonal to e_n (the
    # frame sums below would then turn a normal impact into a sideways one)
    v_pt_vec = v_pt_vec - _dot(v_pt_vec, e_n)[:, None] * e_n
    v_pt = np.linalg.norm(v_pt_vec, axis=1)
    safe = v_pt > 0.0
    e_t = np.zeros_like(v)
    e_t[safe] = v_pt_vec[safe] / v_pt[safe, None]  # eq. (3)
    e_o = np.cross(e_t, e_n)  # eq. (13)
    v_ct = _dot(v, e_t)
    v_co = _dot(v, e_o)

    # specific impulses (per unit mass, times delta t): N* = N dt / m, f* = f dt / m
    g_n = _dot(np.broadcast_to(np.asarray(gravity, np.float64), v.shape), e_n)
    N_star = np.maximum(-v_cn * (1.0 + E) - g_n * duration, 0.0)  # eq. (10), no adhesion
    # eq. (19): f dt / m = I/(I + m R^2) ((omega x r_cp) . e_t + v_ct) = k/(1+k) v_pt
    f_stick = k / (1.0 + k) * v_pt
    slipped = approaching & (f_stick > mu_s * N_star) & safe  # eq. (22)
    f = np.where(slipped, mu_d * N_star, f_stick)  # eq. (23) when slipping

    v_ct_after = v_ct - f  # eqs. (21), (25)
    v_cn_after = -E * v_cn  # eq. (30)
    v_after = v_ct_after[:, None] * e_t + v_cn_after[:, None] * e_n + v_co[:, None] * e_o  # eqs. (14), (15)
    # no slip velocity: no e_t, no friction; the tangential velocity of the centre stays
    v_after = np.where(safe[:, None], v_after, v + (v_cn_after - v_cn)[:, None] * e_n)
    # eqs. (20), (24): omega' = omega - f R dt / I e_o  ->  per unit mass: f* / (k R)
    w_after = w - (f / (k * R))[:, None] * e_o
    v_after = np.where(approaching[:, None], v_after, v)
    w_after = np.where(approaching[:, None], w_after, w)
    return v_after, w_after, slipped


def empty_impact_outputs(n: int, bounces: int) -> dict:
    """Per-bounce impact arrays of n pellets, all marked missing (NaN, slipped and surface -1)."""
    return {
        "impact.time": np.full((n, bounces), np.nan),
        "impact.position": np.full((n, bounces, 3), np.nan),
        "impact.velocity_before": np.full((n, bounces, 3), np.nan),
        "impact.angular_velocity_before": np.full((n, bounces, 3), np.nan),
        "impact.velocity": np.full((n, bounces, 3), np.nan),
        "impact.angular_velocity": np.full((n, bounces, 3), np.nan),
        "impact.slipped": np.full((n, bounces), -1, np.int8),
        "impact.surface": np.full((n, bounces), -1, np.int16),
    }


def next_contact(position, velocity, gravity, radius, points, normals, touching):
    """Vectorised over pellets: (time, plane) of the next contact, plane -1 (time nan) if none."""
    n_pellets = position.shape[0]
    best_t = np.full(n_pellets, np.inf)
    best_k = np.full(n_pellets, -1)
    g = np.asarray(gravity, np.float64)
    for k, (p, nrm) in enumerate(zip(points, normals)):
        b = velocity @ nrm
        a = 0.5 * (g @ nrm)
        if abs(2 * a) <= TOLERANCE * np.abs(g).sum():
            a = 0.0  # gravity along the plane, up to rounding
        height = (position - p) @ nrm
        c = height - radius
        noise = ((np.abs(position) + np.abs(np.asarray(p, np.float64))) * np.abs(nrm)).sum(axis=1)  # of x - p
        c = np.where(np.abs(c) <= TOLERANCE * (noise + radius), 0.0, c)  # touching (physics.geometry's band)
        t = np.full(n_pellets, np.nan)
        # leaving the plane just hit: t* = -2 v_n / (g . e_n)   (eq. 40 as the tables use it)
        leave = touching == k
        t = np.where(leave & (b <= 0), 0.0, t)
        if a < 0:
            t = np.where(leave & (b > 0), -b / a, t)
        other = ~leave & (height >= 0)
        now = other & (c <= 0) & (b < 0)
        t = np.where(now, 0.0, t)
        # touching or overlapping and moving away: contact when it next closes (larger root or apex)
        inside = other & (c <= 0) & (b >= 0)
        if a < 0:
            with np.errstate(invalid="ignore"):
                disc_in = b * b - 4.0 * a * c
                t = np.where(
                    inside, np.where(disc_in < 0, -b / (2.0 * a), -(b + np.sqrt(np.maximum(disc_in, 0.0))) / (2.0 * a)), t
                )
        rest = other & (c > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            if a == 0.0:
                t = np.where(rest & (b < 0), -c / b, t)
            else:
                disc = b * b - 4.0 * a * c
                ok = rest & (disc >= 0)
                root = np.sqrt(np.where(ok, disc, 0.0))
                closing = np.where(b >= 0, -(b + root) / (2.0 * a), 2.0 * c / (root - b))
                t = np.where(ok & (closing > 0), closing, t)
        t = np.where(t > MAX_FLIGHT_TIME, np.nan, t)
        better = np.isfinite(t) & (t >= 0) & (t < best_t)
        best_t = np.where(better, t, best_t)
        best_k = np.where(better, k, best_k)
    return np.where(best_k >= 0, best_t, np.nan), best_k


def sample_launch(shot, rng: np.random.Generator):
    """Launch states with NumPy's RNG (same distribution as the kernels, not the same draws)."""
    n = shot.pellets
    z = rng.uniform(-1.0, 1.0, n)  # uniform in the unit ball, as the kernels sample it
    azimuth = rng.uniform(0.0, 2.0 * np.pi, n)
    r = np.cbrt(rng.uniform(0.0, 1.0, n))
    ring = r * np.sqrt(1.0 - z * z)
    offset = np.stack([ring * np.cos(azimuth), ring * np.sin(azimuth), r * z], axis=1)
    k = scale_exponent(shot.direction, shot.direction_jitter)  # as the kernels: no underflow in |d|^2
    if shot.pattern is not None:  # a choke's pattern (launch.pattern)
        u_a, u_b = rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
        d = pattern_directions(unit_vector(shot.direction), shot.pattern_spread, u_a, u_b)
    else:
        jitter = np.asarray(scaled(shot.direction_jitter, k)) * rng.uniform(-1.0, 1.0, (n, 3))
        d = np.asarray(scaled(shot.direction, k)) + jitter
    velocity = shot.speed * d / np.linalg.norm(d, axis=1)[:, None]
    position = np.asarray(shot.envelope_center) + shot.envelope_radius * offset
    spin = np.broadcast_to(np.asarray(shot.spin, np.float64), (n, 3)).copy()
    return position, velocity, spin


def flight_scale(position, velocity, gravity, dt):
    """M = |x0| + |v0| t + |g| t^2 / 2 (m) of flights of `dt` (s), |.| the largest absolute component
    (tallies.sums)."""
    g = np.abs(np.asarray(gravity, np.float64)).max()
    return np.abs(position).max(axis=-1) + dt * (np.abs(velocity).max(axis=-1) + 0.5 * dt * g)


def plane_contact(scene):
    """The next contact of `simulate` with the scene's surfaces taken as planes: a function of
    (position, velocity, touching) giving (time, surface, its unit normal (N, 3)) (`next_contact`)."""
    radius = 0.5 * scene.shot.diameter
    g = np.asarray(scene.physics.gravity, np.float64)
    points = np.array([s.point for s in scene.surfaces], np.float64).reshape(-1, 3)
    normals = np.array([s.normal for s in scene.surfaces], np.float64).reshape(-1, 3)

    def contact(r, v, touching):
        dt, k = next_contact(r, v, g, radius, points, normals, touching)
        return dt, k, normals[np.maximum(k, 0)] if len(normals) else np.zeros_like(r)

    return contact


def simulate(scene, position, velocity, angular_velocity, contact=None):
    """Follow pellets from launch to landing (float64). Returns (per-pellet dict, statistics).
    `contact`: the next contact (`plane_contact`'s signature; default: every surface a plane;
    reference.shapes: plates and triangles)."""
    radius = 0.5 * scene.shot.diameter
    mass = scene.shot.density * 4.0 / 3.0 * math.pi * radius**3
    inertia = SOLID_SPHERE_INERTIA_FACTOR * mass * radius**2
    g = np.asarray(scene.physics.gravity, np.float64)
    planes = scene.surfaces
    contact = plane_contact(scene) if contact is None else contact
    E = np.array([s.restitution for s in planes] + [0.0])  # index -1 -> dummy
    mu_s = np.array([s.mu_s for s in planes] + [0.0])
    mu_d = np.array([s.mu_d for s in planes] + [0.0])
    n = position.shape[0]
    B = scene.physics.bounces
    r = np.array(position, np.float64)
    v = np.array(velocity, np.float64)
    w = np.array(angular_velocity, np.float64)
    launch_v, launch_w = v.copy(), w.copy()
    time = np.zeros(n)
    touching = np.full(n, -1)
    active = np.ones(n, bool)
    out = empty_impact_outputs(n, B)
    ricochet_point = np.full((n, 3), np.nan)
    ricochet_time = np.zeros(n)
    first_normal = np.zeros((n, 3))
    last_slipped = np.zeros(n, bool)
    impacts = np.zeros(n, int)
    resting = np.zeros(n, bool)  # met a surface without closing speed: the flight ends there
    resting_surface = np.full(n, -1)
    resting_normal = np.zeros((n, 3))
    scale = np.full(n, np.nan)  # each pellet's largest flight scale (m)
    for bounce in range(B):
        dt, k, normal_k = contact(r, v, touching)
        meet = active & (k >= 0)
        active &= meet
        dt = np.where(meet, dt, 0.0)
        scale = np.where(meet, np.fmax(scale, flight_scale(r, v, g, dt)), scale)
        nrm = np.where(meet[:, None], normal_k, 0.0)
        r = np.where(meet[:, None], r + v * dt[:, None] + 0.5 * g * dt[:, None] ** 2, r)
        v = np.where(meet[:, None], v + g * dt[:, None], v)
        time = time + dt
        normal_speed = np.einsum("ij,ij->i", v, nrm)
        closing = (normal_speed < 0) & (normal_speed**2 > CLOSING_TOLERANCE**2 * np.einsum("ij,ij->i", v, v))
        rests = meet & ~closing
        resting |= rests
        resting_surface = np.where(rests, k, resting_surface)
        resting_normal = np.where(rests[:, None], nrm, resting_normal)
        active &= ~rests
        hit = meet & closing
        safe_n = np.where(hit[:, None], nrm, np.array([0.0, 1.0, 0.0]))
        v2, w2, s2 = impact_law(
            v,
            w,
            safe_n,
            radius=radius,
            restitution=E[k],
            mu_s=mu_s[k],
            mu_d=mu_d[k],
            gravity=g,
            duration=scene.physics.impact_duration,
        )
        out["impact.time"][hit, bounce] = time[hit]
        out["impact.position"][hit, bounce] = r[hit]
        out["impact.velocity_before"][hit, bounce] = v[hit]
        out["impact.angular_velocity_before"][hit, bounce] = w[hit]
        out["impact.velocity"][hit, bounce] = v2[hit]
        out["impact.angular_velocity"][hit, bounce] = w2[hit]
        out["impact.slipped"][hit, bounce] = s2[hit]
        out["impact.surface"][hit, bounce] = k[hit]
        if bounce == 0:
            first_normal = np.where(hit[:, None], nrm, 0.0)
        speed_before2 = np.einsum("ij,ij->i", v, v)
        v = np.where(hit[:, None], v2, v)
        w = np.where(hit[:, None], w2, w)
        touching = np.where(hit, k, touching)
        impacts += hit
        last_slipped = np.where(hit, s2, last_slipped)
        ricochet_point = np.where(hit[:, None], r - radius * nrm, ricochet_point)
        ricochet_time = np.where(hit, time, ricochet_time)
        # leaving with no normal speed (E = 0, up to rounding of the speed before the impact)
        leaving = np.einsum("ij,ij->i", v, nrm)
        stays = hit & (leaving**2 <= CLOSING_TOLERANCE**2 * speed_before2)
        resting |= stays
        resting_surface = np.where(stays, k, resting_surface)
        resting_normal = np.where(stays[:, None], nrm, resting_normal)
        active &= ~stays
    dt, k, normal_k = contact(r, v, touching)
    flying_lands = active & (k >= 0)
    dt = np.where(flying_lands, dt, 0.0)
    scale = np.where(flying_lands, np.fmax(scale, flight_scale(r, v, g, dt)), scale)
    k = np.where(resting, resting_surface, k)
    landed = (impacts > 0) & (flying_lands | resting)
    land_pos = np.where(landed[:, None], r + v * dt[:, None] + 0.5 * g * dt[:, None] ** 2, np.nan)
    land_vel = np.where(landed[:, None], v + g * dt[:, None], np.nan)
    land_time = time + dt
    touch = land_pos - radius * np.where(resting[:, None], resting_normal, normal_k)
    out.update(
        {
            "initial.position": np.asarray(position, np.float64),
            "initial.velocity": launch_v,
            "initial.angular_velocity": launch_w,
            "landing.time": np.where(landed, land_time, np.inf),
            "landing.position": land_pos,
            "landing.velocity": land_vel,
            "landing.range": np.where(landed, np.linalg.norm(touch - ricochet_point, axis=1), np.nan),
            "landing.surface": np.where(landed, k, -1).astype(np.int16),
        }
    )
    hit_any = out["impact.surface"][:, 0] >= 0
    stats = statistics_from_arrays(
        pellets=n,
        mass=mass,
        inertia=inertia,
        launch_velocity=launch_v,
        launch_angular_velocity=launch_w,
        hit=hit_any,
        normal=first_normal,
        velocity_before=out["impact.velocity_before"][:, 0],
        angular_velocity_before=out["impact.angular_velocity_before"][:, 0],
        velocity_after=out["impact.velocity"][:, 0],
        angular_velocity_after=out["impact.angular_velocity"][:, 0],
        slipped_first=out["impact.slipped"][:, 0] == 1,
        landed=landed,
        range_=out["landing.range"],
        slipped_last=last_slipped,
        time_aloft=land_time - ricochet_time,
        landing_velocity=np.nan_to_num(land_vel),
        flight_scale=scale,
    )
    return out, stats
