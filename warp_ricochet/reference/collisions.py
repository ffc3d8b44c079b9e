"""Event-driven float64 NumPy reference of pellet-pellet collisions, for small clouds.

It is the exact yardstick of the time-stepped collision solver: no time step, every event at its
exact time, one at a time in time order. It is meant for up to a few thousand pellets.

Physics (SI units throughout: m, s, kg, m/s, rad/s, J):

- Flight between events is the exact parabola r(t) = r0 + v0 t + g t^2 / 2 (physics.ballistic). Every
  pellet has the same gravity, so the relative motion of two pellets is a straight line and the
  time two spheres of radius R touch is a root of |d + u t| = 2R (a quadratic).
- Planes, impacts, resting, landing and ranges are exactly those of `reference.simulate` (the
  no-collision float64 reference), reusing its `next_contact` and `impact_law` with the same
  expressions, so a pellet that never meets another gets its numbers (bitwise, in practice).
- Pair collisions use `pair_law`: the plane law generalised to two spheres (reduced mass, both
  spins, contact arms scaled to the centre distance), the same stick-slip Coulomb rule, and
  restitution on the normal relative velocity. See its docstring.
- TC model (Luding & McNamara 1998) against inelastic collapse: a pair collision uses the pair
  restitution only if both pellets' previous pair collisions were more than `contact_duration`
  before; otherwise it is elastic (E = 1). Friction is unchanged.

Semantics chosen where the physics leaves a choice (see `simulate_collisions`):

- A pellet whose flight ended (landed, or resting on a plane) is frozen: other pellets pass
  through it. Pellets of different shots never collide.
- At equal times a plane event goes before a pair event; among plane events the lower pellet
  index first; among pair events the pair (i, j), i < j, lowest in lexicographic order first.
- A pair is "approaching" when its normal relative speed is below minus the rounding noise of
  the two speeds (`CLOSING_TOLERANCE`, as `reference.simulate` uses for planes), and "touching"
  when its gap is within the rounding noise of the positions (`TOLERANCE`). Touching or
  overlapping approaching pairs collide at once; overlapping separating ones are left alone (in
  straight relative motion they only separate further).
- Each pair's contact time is computed from the two pellets' states at the later of their last
  events, so it is the same number however it is reached (deterministic, and the per-pellet
  caches below can never disagree).

Algorithm: each pellet caches its next plane contact (time from its last event) and the earliest
pair event among all its partners. The next event is the earliest of the 2N cached times (one
argmin, O(N)). After an event only the pellets it changed recompute their pair events against
all others (O(N) each); a pellet whose cached partner changed recomputes its own in full; every
other pellet just takes an earlier time with a changed pellet if there is one. So the caches
always hold the exact minima, and the cost per event is O(N).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..physics.ballistic import MAX_FLIGHT_TIME
from ..physics.impact import SOLID_SPHERE_INERTIA_FACTOR
from ..tallies.sums import statistics_from_arrays
from .ballistic import (
    CLOSING_TOLERANCE,
    TOLERANCE,
    empty_impact_outputs,
    flight_scale,
    impact_law,
    next_contact,
)

__all__ = ["PairImpact", "pair_law", "pair_contact_time", "simulate_collisions"]

ROW_CHUNK = 256  # pellets whose pair events are recomputed together: bounds the (rows, N, 3) temporaries


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _norm(a):
    return np.sqrt(_dot(a, a))


# ---------------------------------------------------------------------------------------------- the pair law


class PairImpact(NamedTuple):
    """What `pair_law` returns: new states, and whether (and how) the spheres collided."""

    velocity_a: np.ndarray  # m/s
    angular_velocity_a: np.ndarray  # rad/s
    velocity_b: np.ndarray  # m/s
    angular_velocity_b: np.ndarray  # rad/s
    collided: np.ndarray  # bool: the contact points approached (u_n < 0), so an impulse was applied
    slipped: np.ndarray  # bool: kinetic friction (the sticking impulse exceeded mu_s times the normal one)
    energy_lost: np.ndarray  # J, translational + rotational kinetic energy lost (>= 0)


def pair_law(
    position_a,
    velocity_a,
    angular_velocity_a,
    position_b,
    velocity_b,
    angular_velocity_b,
    *,
    mass_a,
    mass_b,
    radius_a,
    radius_b,
    restitution,
    mu_s,
    mu_d,
    inertia_factor=SOLID_SPHERE_INERTIA_FACTOR,
) -> PairImpact:
    """Impact of sphere a on sphere b: the plane law (physics.impact) generalised to two spheres.

    Vectorised: vectors are (..., 3) arrays, the scalars broadcast against their leading shape.
    Units: positions m, velocities m/s, angular velocities rad/s, masses kg, radii m;
    restitution E and the friction coefficients mu_s >= mu_d are dimensionless; the inertia
    factor is k = I / (m R^2) (0.4, solid sphere) for both spheres. A mass may be `inf` (a fixed
    body: then this is the plane law with normal -n, no gravity term).

    n = (x_b - x_a) / d is the unit normal from a to b. The contact arms are scaled so that they
    sum to d, s = d / (R_a + R_b): arm of a s R_a n, of b -s R_b n. Then angular momentum about
    any point is conserved exactly even for overlapping spheres (s < 1); touching ones have s = 1.

    Relative velocity of the contact points (b's minus a's):
        u = v_b - v_a - s R_b (w_b x n) - s R_a (w_a x n),
    normal part u_n = u . n (spins do not contribute: (w x n) . n = 0, so it is computed as
    (v_b - v_a) . n, exactly the quantity the event detection tests), tangential u_t = u - (u.n) n.
    Nothing happens unless u_n < 0 (approaching); d = 0 (no normal) never collides.

    With m* = m_a m_b / (m_a + m_b) and P the impulse on b (-P on a), per unit reduced mass:
        normal  P_n / m* = -(1 + E) u_n                  (so u_n' = -E u_n)
        stick   P_t / m* = -k / (k + s^2) u_t            (u_t' = 0; k/(1+k) = 2/7 at contact, as eq. 19)
        slip    P_t / m* = -mu_d (P_n / m*) u_t / |u_t|  if k/(k+s^2) |u_t| > mu_s P_n/m*  (eqs. 22-23)
    and v_b += P/m_b, v_a -= P/m_a, w_b -= s (n x P) / (k m_b R_b), w_a -= s (n x P) / (k m_a R_a).

    The energy lost is evaluated in closed form (Kelvin: the work of an impulse is P . (u + u')/2),
        m*/2 [(1 - E^2) u_n^2 + k/(k+s^2) |u_t|^2]               (stick)
        m*/2 [(1 - E^2) u_n^2 + f (2 |u_t| - f (k+s^2)/k)],  f = mu_d P_n/m*   (slip),
    which is >= 0 when mu_d <= mu_s and free of the cancellation of a difference of energies.
    """
    xa, va, wa, xb, vb, wb = np.broadcast_arrays(
        *(
            np.asarray(x, np.float64)
            for x in (position_a, velocity_a, angular_velocity_a, position_b, velocity_b, angular_velocity_b)
        )
    )
    lead = xa.shape[:-1]
    ma, mb, Ra, Rb, E, mus, mud, k = (
        np.broadcast_to(np.asarray(x, np.float64), lead)
        for x in (mass_a, mass_b, radius_a, radius_b, restitution, mu_s, mu_d, inertia_factor)
    )

    offset = xb - xa
    distance = _norm(offset)
    valid = distance > 0.0
    n = offset / np.where(valid, distance, 1.0)[..., None]
    s = distance / (Ra + Rb)
    u = vb - va - np.cross((s * Rb)[..., None] * wb + (s * Ra)[..., None] * wa, n)
    un = _dot(vb - va, n)
    collided = valid & (un < 0.0)
    ut = u - _dot(u, n)[..., None] * n
    slip_speed = _norm(ut)

    normal_impulse = -(1.0 + E) * un  # P_n / m*, >= 0 when approaching
    stick_fraction = k / (k + s * s)
    # the plane law's rule (eq. 22): stick if the sticking impulse is within mu_s P_n; zero slip: stick
    slipped = collided & (stick_fraction * slip_speed > mus * normal_impulse) & (slip_speed > 0.0)
    kinetic = mud * normal_impulse  # |P_t| / m* when slipping
    friction = np.where(
        slipped[..., None],
        -(kinetic / np.where(slip_speed > 0.0, slip_speed, 1.0))[..., None] * ut,
        -stick_fraction[..., None] * ut,
    )
    impulse = normal_impulse[..., None] * n + friction  # P / m*, on b

    reduced = 1.0 / (1.0 / ma + 1.0 / mb)  # m*; this form allows one infinite mass
    share_a, share_b = reduced / ma, reduced / mb
    moment = np.cross(n, impulse)  # n x P / m*
    va2 = va - share_a[..., None] * impulse
    vb2 = vb + share_b[..., None] * impulse
    wa2 = wa - (s * share_a / (k * Ra))[..., None] * moment
    wb2 = wb - (s * share_b / (k * Rb))[..., None] * moment

    tangential_loss = np.where(slipped, kinetic * (2.0 * slip_speed - kinetic / stick_fraction), stick_fraction * slip_speed**2)
    lost = 0.5 * reduced * ((1.0 - E * E) * un * un + tangential_loss)

    c = collided[..., None]
    return PairImpact(
        np.where(c, va2, va),
        np.where(c, wa2, wa),
        np.where(c, vb2, vb),
        np.where(c, wb2, wb),
        collided,
        slipped,
        np.where(collided, lost, 0.0),
    )


# ---------------------------------------------------------------------------------------------- pair contact times


def pair_contact_time(offset, relative_velocity, *, diameter, position_scale, speed_scale):
    """Time (s) until two spheres of equal `diameter` (m) touch while approaching; inf if never.

    offset = x_b - x_a (m) and relative_velocity = v_b - v_a (m/s), (..., 3): the relative motion
    is straight (equal gravity), so the gap closes at the smallest t >= 0 with |d + u t| = 2R.
    position_scale (m) and speed_scale (m/s), (...): magnitudes whose rounding noise the offset and
    the relative velocity carry (|x_a|_1 + |x_b|_1 and |v_a| + |v_b|).

    - not approaching (d . u >= -CLOSING_TOLERANCE |d| speed_scale): inf (this includes d = 0);
    - touching (|gap| within TOLERANCE (position_scale + 2R)) or overlapping, approaching: 0;
    - apart, approaching: the first root, c / (-b + sqrt(b^2 - a c)) (no cancellation), or inf
      if the spheres pass each other; later than MAX_FLIGHT_TIME counts as never.
    """
    d2 = _dot(offset, offset)
    b = _dot(offset, relative_velocity)  # |d| u_n
    a = _dot(relative_velocity, relative_velocity)
    distance = np.sqrt(d2)
    gap = distance - diameter
    gap = np.where(np.abs(gap) <= TOLERANCE * (position_scale + diameter), 0.0, gap)  # touching, up to rounding
    approaching = b < -CLOSING_TOLERANCE * distance * speed_scale
    c = gap * (distance + diameter)  # d^2 - (2R)^2, exact 0 when touching
    disc = b * b - a * c
    ahead = approaching & (gap > 0.0) & (disc >= 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(ahead, c / (np.sqrt(np.where(ahead, disc, 0.0)) - b), np.inf)
    t = np.where(approaching & (gap <= 0.0), 0.0, t)
    return np.where(t > MAX_FLIGHT_TIME, np.inf, t)


# ---------------------------------------------------------------------------------------------- the solver


def _pair_parameters(scene, collisions, restitution, mu_s, mu_d, contact_duration):
    """Explicit keywords first, then `collisions`, then scene.collisions; check their ranges."""
    section = collisions if collisions is not None else getattr(scene, "collisions", None)

    def pick(value, name):
        return getattr(section, name, None) if value is None else value

    # an explicit mu_s without mu_d means mu_d = mu_s (as for surfaces), never the section's mu_d,
    # which was checked against the section's mu_s only
    if mu_s is not None and mu_d is None:
        mu_d = mu_s
    E, mu_s, mu_d, tc = (
        pick(restitution, "restitution"),
        pick(mu_s, "mu_s"),
        pick(mu_d, "mu_d"),
        pick(contact_duration, "contact_duration"),
    )
    if E is None or mu_s is None:
        raise ValueError(
            "simulate_collisions: the pair restitution and mu_s are needed (keywords, collisions=..., or scene.collisions)"
        )
    mu_d = mu_s if mu_d is None else mu_d
    tc = 0.0 if tc is None else tc
    E, mu_s, mu_d, tc = float(E), float(mu_s), float(mu_d), float(tc)
    if not 0.0 <= E <= 1.0:
        raise ValueError(f"simulate_collisions: restitution = {E!r} must be in [0, 1]")
    if not (0.0 <= mu_d <= mu_s and math.isfinite(mu_s)):
        raise ValueError(f"simulate_collisions: need 0 <= mu_d ({mu_d!r}) <= mu_s ({mu_s!r}) < inf")
    if not (0.0 <= tc < math.inf):
        raise ValueError(f"simulate_collisions: contact_duration = {tc!r} s must be finite and >= 0")
    return E, mu_s, mu_d, tc


class _Events:
    """What the event-driven simulation does at an event (a plane contact, a pair contact, the end
    of a flight), on the state of `_Cloud`."""

    def end_flight(self, p, time, position, velocity, plane):
        """The flight of p ends on `plane` (landing, or resting): it is frozen from now on."""
        self.flying[p] = False
        self.r0[p], self.v0[p], self.t0[p] = position, velocity, time
        if self.impacts[p] > 0:  # as reference.simulate: only a ricocheted pellet lands
            self.landed[p] = True
            self.land_time[p] = time
            self.land_position[p] = position
            self.land_velocity[p] = velocity
            self.land_surface[p] = plane
            contact = position - self.radius * self.normals[plane]
            self.land_range[p] = np.linalg.norm((contact - self.ricochet_point[p])[None], axis=1)[0]

    def plane_event(self, p):
        """Pellet p meets plane k: impact, rest or landing, as one bounce of reference.simulate."""
        self.plane_events += 1
        dt, k = self.plane_dt[p : p + 1], int(self.plane_k[p])
        sl = slice(p, p + 1)
        self.scale[p] = np.fmax(self.scale[p], flight_scale(self.r0[p], self.v0[p], self.g, dt[0]))
        # the same expressions as reference.simulate, so a pellet that meets no other matches bitwise
        r = self.r0[sl] + self.v0[sl] * dt[:, None] + 0.5 * self.g * dt[:, None] ** 2
        v = self.v0[sl] + self.g * dt[:, None]
        time = self.t0[p] + dt[0]
        self.now = max(self.now, time)
        nrm = self.normals[k][None, :]
        normal_speed = np.einsum("ij,ij->i", v, nrm)
        closing = bool((normal_speed < 0) & (normal_speed**2 > CLOSING_TOLERANCE**2 * np.einsum("ij,ij->i", v, v)))
        if self.impacts[p] >= self.B or not closing:
            # after B impacts the next contact is the landing; without closing speed it rests there
            self.end_flight(p, time, r[0], v[0], k)
        else:
            v2, w2, s2 = impact_law(
                v,
                self.w[sl],
                nrm,
                radius=self.radius,
                restitution=self.plane_E[k],
                mu_s=self.plane_mu_s[k],
                mu_d=self.plane_mu_d[k],
                gravity=self.g,
                duration=self.duration,
                inertia_factor=self.k,
            )
            b = self.impacts[p]
            self.out["impact.time"][p, b] = time
            self.out["impact.position"][p, b] = r[0]
            self.out["impact.velocity_before"][p, b] = v[0]
            self.out["impact.angular_velocity_before"][p, b] = self.w[p]
            self.out["impact.velocity"][p, b] = v2[0]
            self.out["impact.angular_velocity"][p, b] = w2[0]
            self.out["impact.slipped"][p, b] = s2[0]
            self.out["impact.surface"][p, b] = k
            if b == 0:
                self.first_normal[p] = nrm[0]
            self.impacts[p] += 1
            self.last_slipped[p] = s2[0]
            self.ricochet_point[p] = r[0] - self.radius * nrm[0]
            self.ricochet_time[p] = time
            self.touching[p] = k
            self.w[p] = w2[0]
            leaving = np.einsum("ij,ij->i", v2, nrm)
            if leaving[0] ** 2 <= CLOSING_TOLERANCE**2 * np.einsum("ij,ij->i", v, v)[0]:  # of the speed before
                self.end_flight(p, time, r[0], v2[0], k)  # no normal speed left (E = 0): it stays
            else:
                self.r0[p], self.v0[p], self.t0[p] = r[0], v2[0], time
        self.refresh([p])

    def pair_event(self, i, j):
        """Pellets i and j (i the lower index) touch while approaching: apply the pair law, with
        the TC model's restitution."""
        self.pair_events += 1
        time = max(self.pair_t[i], self.now)  # never earlier than now (rounding guard; no-op in practice)
        self.now = time
        xi, vi = self.advance(i, time)
        xj, vj = self.advance(j, time)
        # TC model: within contact_duration of a pellet's previous pair collision, elastic
        elastic = (time - self.pair_last[i] <= self.tc) or (time - self.pair_last[j] <= self.tc)
        hit = pair_law(
            xi,
            vi,
            self.w[i],
            xj,
            vj,
            self.w[j],
            mass_a=self.mass,
            mass_b=self.mass,
            radius_a=self.radius,
            radius_b=self.radius,
            restitution=1.0 if elastic else self.E,
            mu_s=self.mu_s,
            mu_d=self.mu_d,
            inertia_factor=self.k,
        )
        for p, x, v, w in ((i, xi, hit.velocity_a, hit.angular_velocity_a), (j, xj, hit.velocity_b, hit.angular_velocity_b)):
            if self.t0[p] != time:
                # it has flown since its last event, so it no longer sits on the plane it left at
                # that event: the gap is computed afresh (still touching up to rounding if it is)
                self.touching[p] = -1
            # else no time has passed since its last event (an impact at this very instant): it is
            # still leaving that plane with gap 0, and next_contact's return time uses the new v_n
            self.r0[p], self.v0[p], self.w[p], self.t0[p] = x, v, w, time
        if hit.collided:
            self.pair_collisions += 1
            self.pair_count[[i, j]] += 1
            self.pair_last[[i, j]] = time
            self.pair_energy_lost += float(hit.energy_lost)
            self.last_collision_time = time
        # re-basing both states at `time` also retires the event if the law found no approach
        self.refresh([i, j])


class _Cloud(_Events):
    """State of the event-driven simulation. Each pellet's state (r0, v0, w) holds at its time t0,
    the time of its last event; between events it flies on the parabola."""

    def __init__(self, scene, position, velocity, angular_velocity, shot_index, pair, inertia_factor):
        self.radius = 0.5 * scene.shot.diameter
        self.mass = scene.shot.density * 4.0 / 3.0 * math.pi * self.radius**3  # as reference.simulate
        self.inertia = inertia_factor * self.mass * self.radius**2
        self.k = inertia_factor
        self.g = np.asarray(scene.physics.gravity, np.float64)
        self.duration = scene.physics.impact_duration
        self.B = scene.physics.bounces
        planes = scene.surfaces
        self.points = np.array([s.point for s in planes], np.float64).reshape(-1, 3)
        self.normals = np.array([s.normal for s in planes], np.float64).reshape(-1, 3)
        self.plane_E = [s.restitution for s in planes]
        self.plane_mu_s = [s.mu_s for s in planes]
        self.plane_mu_d = [s.mu_s if s.mu_d is None else s.mu_d for s in planes]
        self.E, self.mu_s, self.mu_d, self.tc = pair

        n = self.n = position.shape[0]
        self.shot = shot_index
        self.r0 = position.copy()
        self.v0 = velocity.copy()
        self.w = angular_velocity.copy()
        self.t0 = np.zeros(n)
        self.now = 0.0
        self.flying = np.ones(n, bool)
        self.touching = np.full(n, -1)  # plane the pellet is leaving (gap 0 at t0), as in reference.simulate
        self.impacts = np.zeros(n, int)
        self.pair_count = np.zeros(n, np.int32)
        self.pair_last = np.full(n, -np.inf)  # time of each pellet's last pair collision (TC model)
        self.pair_energy_lost = 0.0
        self.pair_collisions = 0
        self.pair_events = 0  # processed pair events (collisions plus the rare grazes that were not)
        self.plane_events = 0
        self.last_collision_time = math.nan

        B = self.B
        self.out = empty_impact_outputs(n, B)
        self.ricochet_point = np.full((n, 3), np.nan)
        self.ricochet_time = np.zeros(n)
        self.first_normal = np.zeros((n, 3))
        self.last_slipped = np.zeros(n, bool)
        self.landed = np.zeros(n, bool)
        self.land_time = np.full(n, np.inf)
        self.land_position = np.full((n, 3), np.nan)
        self.land_velocity = np.full((n, 3), np.nan)
        self.land_range = np.full(n, np.nan)
        self.land_surface = np.full(n, -1, np.int16)
        self.scale = np.full(n, np.nan)  # largest scale of a flight that met a plane (m), as reference.simulate

        # caches: next plane contact (from t0) and earliest pair event (absolute time, partner)
        dt, plane = next_contact(self.r0, self.v0, self.g, self.radius, self.points, self.normals, self.touching)
        self.plane_dt, self.plane_k = dt, plane
        self.plane_at = np.where(plane >= 0, self.t0 + dt, np.inf)
        self.pair_t = np.full(n, np.inf)
        self.pair_q = np.full(n, -1)
        for start in range(0, n, ROW_CHUNK):
            rows = np.arange(start, min(start + ROW_CHUNK, n))
            self.pair_t[rows], self.pair_q[rows] = self._row_minima(rows)

    # ------------------------------------------------------------------ kinematics

    def advance(self, p, time):
        """(position, velocity) of pellet p at `time` (s), on its parabola from t0."""
        dt = time - self.t0[p]
        return self.r0[p] + self.v0[p] * dt + 0.5 * self.g * dt**2, self.v0[p] + self.g * dt

    def pair_times(self, rows):
        """(len(rows), N) absolute times of the pair events of `rows` with every pellet (inf: none).

        Each pair is evaluated at the later of its two pellets' t0 (both states are known there and
        have not changed since), so a pair's time is one number whichever pellet asks."""
        times = np.full((len(rows), self.n), np.inf)
        if not self.flying[rows].any():
            return times
        # frozen pellets take no part: skip their columns (no copies while all fly)
        if self.flying.all():
            cols, r0, v0, t0 = np.arange(self.n), self.r0, self.v0, self.t0
        else:
            cols = np.nonzero(self.flying)[0]
            r0, v0, t0 = self.r0[cols], self.v0[cols], self.t0[cols]
        t_row, t_col = self.t0[rows][:, None], t0[None, :]
        t_ref = np.maximum(t_row, t_col)
        dq = (t_ref - t_col)[..., None]
        dk = (t_ref - t_row)[..., None]
        xq = r0[None] + v0[None] * dq + 0.5 * self.g * dq**2
        vq = v0[None] + self.g * dq
        xk = self.r0[rows][:, None] + self.v0[rows][:, None] * dk + 0.5 * self.g * dk**2
        vk = self.v0[rows][:, None] + self.g * dk
        tau = pair_contact_time(
            xq - xk,
            vq - vk,
            diameter=2.0 * self.radius,
            position_scale=np.abs(xq).sum(-1) + np.abs(xk).sum(-1),
            speed_scale=_norm(vq) + _norm(vk),
        )
        live = (
            self.flying[rows][:, None] & (self.shot[rows][:, None] == self.shot[cols][None, :]) & (rows[:, None] != cols[None, :])
        )
        times[:, cols] = np.where(live, t_ref + tau, np.inf)
        return times

    def _row_minima(self, rows):
        times = self.pair_times(rows)
        q = np.argmin(times, axis=1)  # ties: the lower partner index
        t = times[np.arange(len(rows)), q]
        return t, np.where(np.isfinite(t), q, -1)

    # ------------------------------------------------------------------ cache maintenance

    def refresh(self, changed):
        """Pellets `changed` (sorted) have a new state at t0 = now: renew their plane and pair
        caches, and those of the pellets whose cached partner they were."""
        changed = np.asarray(changed)
        for p in changed:
            if self.flying[p]:
                sl = slice(p, p + 1)
                dt, plane = next_contact(
                    self.r0[sl], self.v0[sl], self.g, self.radius, self.points, self.normals, self.touching[sl]
                )
                self.plane_dt[p], self.plane_k[p] = dt[0], plane[0]
                self.plane_at[p] = self.t0[p] + dt[0] if plane[0] >= 0 else np.inf
            else:
                self.plane_dt[p], self.plane_k[p], self.plane_at[p] = np.nan, -1, np.inf
        rows = self.pair_times(changed)
        in_changed = np.zeros(self.n, bool)
        in_changed[changed] = True
        dependants = np.nonzero(np.isin(self.pair_q, changed) & ~in_changed)[0]
        for p, times in zip(changed, rows):
            q = int(np.argmin(times))
            self.pair_t[p] = times[q]
            self.pair_q[p] = q if np.isfinite(times[q]) else -1
        # every other pellet keeps its minimum unless a changed pellet now offers an earlier one
        # (ties: the lower partner index); `changed` is ascending, so ties settle to the lowest
        keep = ~in_changed
        keep[dependants] = False
        for p, times in zip(changed, rows):
            better = keep & ((times < self.pair_t) | ((times == self.pair_t) & (p < self.pair_q)))
            self.pair_t[better] = times[better]
            self.pair_q[better] = p
        # a pellet whose earliest partner changed may now have any other partner first: in full
        for start in range(0, len(dependants), ROW_CHUNK):
            chunk = dependants[start : start + ROW_CHUNK]
            self.pair_t[chunk], self.pair_q[chunk] = self._row_minima(chunk)

    def check_caches(self):
        """Assert the caches are exactly what recomputing every pellet gives (O(N^2); tests)."""
        for start in range(0, self.n, ROW_CHUNK):
            rows = np.arange(start, min(start + ROW_CHUNK, self.n))
            t, q = self._row_minima(rows)
            assert np.array_equal(t, self.pair_t[rows]) and np.array_equal(q, self.pair_q[rows]), "pair-event cache out of date"

    # ------------------------------------------------------------------ events

    def run(self, max_events, check_caches=False):
        while self.n:
            p = int(np.argmin(self.plane_at))
            q = int(np.argmin(self.pair_t))
            if not (np.isfinite(self.plane_at[p]) or np.isfinite(self.pair_t[q])):
                return
            if self.plane_at[p] <= self.pair_t[q]:  # at equal times the plane first
                self.plane_event(p)
            else:
                if self.pair_events >= max_events:
                    raise RuntimeError(
                        f"simulate_collisions: more than max_events = {max_events} pair events (t = {self.now:.9g} s, "
                        f"{self.pair_collisions} collisions); inelastic collapse suspected: raise contact_duration "
                        f"(TC model) or max_events"
                    )
                self.pair_event(q, int(self.pair_q[q]))
            if check_caches:
                self.check_caches()


def simulate_collisions(
    scene,
    position,
    velocity,
    angular_velocity=None,
    shot_index=None,
    *,
    restitution=None,
    mu_s=None,
    mu_d=None,
    contact_duration=None,
    collisions=None,
    inertia_factor=SOLID_SPHERE_INERTIA_FACTOR,
    max_events=None,
    check_caches=False,
):
    """Follow pellets from launch to landing with pair collisions, event by event (float64).

    scene: a `Scene` (or any object with the same attributes): scene.shot.diameter (m) and
        .density (kg/m^3) (all pellets alike), scene.surfaces (one-sided planes with restitution,
        mu_s, mu_d), scene.physics.gravity (m/s^2), .impact_duration (s), .bounces (B).
    position (N, 3) m, velocity (N, 3) m/s, angular_velocity (N, 3) rad/s (None: no spin): launch
        states at t = 0.
    shot_index (N,) ints: only pellets of one shot collide. None: consecutive blocks of
        scene.shot.count when scene.shot.shots > 1 and N is count * shots, else all one shot.
    restitution, mu_s, mu_d, contact_duration (s): the pair law's parameters and the TC model's
        t_c. Each one not given is read from `collisions` (an object with those attributes), or
        else from getattr(scene, "collisions", None); but mu_d is taken as mu_s when mu_s is
        given and mu_d is not (or the section has none), and contact_duration defaults to 0.
        The section's `enabled` flag is not looked at: this function always simulates pair
        collisions (`reference.simulate` is the run without them).
    inertia_factor: I / (m R^2) of both the pair law and the plane law (0.4, solid sphere).
    max_events: at most this many pair events (default 10 N + 100000); one more raises
        RuntimeError (inelastic collapse suspected). Plane events need no cap: each one adds an
        impact or ends a flight, so there are at most (B + 1) N of them.
    check_caches: for tests, verify the event caches against a full O(N^2) recomputation after
        every event.

    Planes follow `reference.simulate`: a contact while closing (beyond rounding) is an impact
    (plane law with gravity/duration term) recorded in impact.* column = impacts so far; a contact
    without closing speed, or an impact leaving no normal speed, ends the flight there (resting);
    after B impacts the next contact is the landing. A pellet whose flight ended is frozen and
    takes no part in later pair collisions. A pellet never meeting a plane again keeps flying
    (and colliding); with at least one impact and no landing it counts as escaped. Landing range
    is from the last ricochet contact point to the landing contact point. A pair collision that
    catches a pellet at the instant of a plane impact leaves it leaving that plane (its return
    time uses its new normal speed); later, the gap to every plane is computed afresh.

    Returns (out, stats):
    out: per-pellet arrays, those of `reference.simulate` ("initial.*", "impact.*", "landing.*")
        plus "collisions.count" (int32, pair collisions of each pellet), "collisions.last_time"
        (s, its last pair collision, NaN if none) and "final.time" (s), "final.position" (m),
        "final.velocity" (m/s), "final.angular_velocity" (rad/s): the state when its flight ended,
        or, for pellets still flying, at the time of the last event of the run.
    stats: `statistics_from_arrays` as reference.simulate, plus "collided_fraction" (pellets with
        at least one pair collision / N), "pair_energy_lost" (J, kinetic energy lost in all pair
        collisions), "pair_energy_lost_mean" (J, the same per pellet launched, as in
        stats.STAT_UNITS), "pair_collisions" (pair collisions), "pair_events" (pair events processed),
        "plane_events", "last_collision_time" (s, the last pair collision, NaN if none) and
        "end_time" (s, the last event).
    """
    r = np.array(position, np.float64).reshape(-1, 3)
    n = r.shape[0]
    v = np.array(velocity, np.float64).reshape(n, 3)
    w = np.zeros((n, 3)) if angular_velocity is None else np.array(angular_velocity, np.float64).reshape(n, 3)
    if shot_index is None:
        shot = getattr(scene, "shot", None)
        count, shots = getattr(shot, "count", 0), getattr(shot, "shots", 1)
        shot_index = np.arange(n) // count if shots > 1 and count * shots == n else np.zeros(n, int)
    shot_index = np.asarray(shot_index).reshape(n)
    pair = _pair_parameters(scene, collisions, restitution, mu_s, mu_d, contact_duration)
    max_events = 10 * n + 100_000 if max_events is None else int(max_events)

    cloud = _Cloud(scene, r, v, w, shot_index, pair, inertia_factor)
    if check_caches:
        cloud.check_caches()
    cloud.run(max_events, check_caches)

    out = cloud.out
    final_position, final_velocity = r.copy(), v.copy()
    final_time = np.where(cloud.flying, cloud.now, cloud.t0)
    for p in range(n):
        final_position[p], final_velocity[p] = cloud.advance(p, final_time[p])
    out.update(
        {
            "initial.position": r,
            "initial.velocity": v,
            "initial.angular_velocity": w,
            "landing.time": cloud.land_time,
            "landing.position": cloud.land_position,
            "landing.velocity": cloud.land_velocity,
            "landing.range": cloud.land_range,
            "landing.surface": cloud.land_surface,
            "collisions.count": cloud.pair_count,
            "collisions.last_time": np.where(cloud.pair_count > 0, cloud.pair_last, np.nan),
            "final.time": final_time,
            "final.position": final_position,
            "final.velocity": final_velocity,
            "final.angular_velocity": cloud.w.copy(),
        }
    )
    hit_any = out["impact.surface"][:, 0] >= 0
    stats = statistics_from_arrays(
        pellets=n,
        mass=cloud.mass,
        inertia=cloud.inertia,
        launch_velocity=v,
        launch_angular_velocity=w,
        hit=hit_any,
        normal=cloud.first_normal,
        velocity_before=out["impact.velocity_before"][:, 0],
        angular_velocity_before=out["impact.angular_velocity_before"][:, 0],
        velocity_after=out["impact.velocity"][:, 0],
        angular_velocity_after=out["impact.angular_velocity"][:, 0],
        slipped_first=out["impact.slipped"][:, 0] == 1,
        landed=cloud.landed,
        range_=cloud.land_range,
        slipped_last=cloud.last_slipped,
        time_aloft=cloud.land_time - cloud.ricochet_time,
        landing_velocity=np.nan_to_num(cloud.land_velocity),
        flight_scale=cloud.scale,
    )
    stats.update(
        {
            "collided_fraction": float((cloud.pair_count > 0).mean()) if n else math.nan,
            "pair_energy_lost": cloud.pair_energy_lost,
            "pair_energy_lost_mean": cloud.pair_energy_lost / n if n else math.nan,
            "pair_collisions": float(cloud.pair_collisions),
            "pair_events": float(cloud.pair_events),
            "plane_events": float(cloud.plane_events),
            "last_collision_time": cloud.last_collision_time,
            "end_time": cloud.now,
        }
    )
    return out, stats
