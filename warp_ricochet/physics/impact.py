"""The impact law of a sphere on a fixed plane with stick-slip Coulomb friction (Zohdi 2021, eqs. 1-25).

All quantities are per unit mass (impulses in m/s): the pellet's mass cancels from every
equation, so the law needs only its radius R and the inertia factor k = I / (m R^2)
(2/5 for a solid sphere, eq. 17).

Frame (eqs. 3-6, 13): e_n is the unit plane normal pointing to the pellet's side; the contact
point is p = c - R e_n, so r_{c->p} = -R e_n and the contact point's velocity is
v_p = v_c + omega x r_{c->p} (eq. 6). Its tangential part v_{p,t} (eq. 4) gives e_t (eq. 3)
and e_o = e_t x e_n (eq. 13).

Normal (eqs. 1, 7-10, 30): v_n' = -E v_n, and the normal impulse per unit mass is
    N* / m = -(1 + E) v_n - (g . e_n) delta_t,
the second term being the paper's m g delta_t (gravity resisted during the contact). It is
clamped at zero: a contact cannot pull.

Stick (eqs. 18-21, 27-29): the impulse that brings the contact point's tangential velocity to
zero is J_stick = -k / (1 + k) v_{p,t} (= -2/7 v_{p,t} for a solid sphere: the 5/7 rolling
rule when the pellet has no incoming spin).

Slip (eqs. 22-25, 31-33): if |J_stick| > mu_s N*/m, the friction impulse is
J = -mu_d (N*/m) e_t instead. Since mu_d <= mu_s, it never overshoots the stick impulse, so
no impact adds energy.

Update (eqs. 15, 17, 20, 24): v' = v_t + J + v_n' e_n and omega' = omega + (J x e_n) / (k R).
J is parallel to e_t, so the e_o component of v is unchanged (eq. 14).

Tangential gravity during the contact is neglected, as in the paper (it is O(g delta_t)).

Pellet-pellet collisions (`physics.pair`) use the same stick-slip rule (`coulomb_impulse`).
"""

import functools

import warp as wp

from .types import types_for

SOLID_SPHERE_INERTIA_FACTOR = 0.4  # I = 2/5 m R^2 (eq. 17)


@functools.cache
def make_coulomb_impulse(precision: str):
    """The stick-slip friction rule shared by the plane law and the pair law (eqs. 18-23)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.func
    def coulomb_impulse(
        slip_velocity: vec3,  # m/s, tangential velocity of the contact point (relative, for a pair)
        slip_speed: scalar,  # m/s, its length
        normal_impulse: scalar,  # m/s, normal impulse per unit (reduced) mass
        stick_fraction: scalar,  # the sticking impulse is -stick_fraction * slip_velocity (eq. 19)
        mu_s: scalar,
        mu_d: scalar,
    ):
        """Return (friction impulse per unit mass, slipped): the sticking impulse if it is within
        mu_s times the normal impulse (eq. 22), else kinetic friction mu_d along -e_t (eq. 23).
        mu_d <= mu_s, so the slip impulse never overshoots the sticking one: no energy gain."""
        friction_impulse = -stick_fraction * slip_velocity  # no division: zero slip velocity is safe
        slipped = wp.int32(0)
        if stick_fraction * slip_speed > mu_s * normal_impulse and slip_speed > scalar(0.0):
            friction_impulse = -(mu_d * normal_impulse / slip_speed) * slip_velocity
            slipped = wp.int32(1)
        return friction_impulse, slipped

    return coulomb_impulse


@functools.cache
def make_impact_law(precision: str):
    """Return the `@wp.func` impact law of one precision ("float32" or "float64")."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    coulomb_impulse = make_coulomb_impulse(precision)

    @wp.func
    def impact_law(
        velocity: vec3,  # m/s, pellet centre c before the impact
        angular_velocity: vec3,  # rad/s, before the impact
        normal: vec3,  # unit plane normal e_n, towards the pellet
        radius: scalar,  # m
        inertia_factor: scalar,  # I / (m R^2)
        restitution: scalar,  # E in [0, 1]
        mu_s: scalar,
        mu_d: scalar,
        gravity_normal_impulse: scalar,  # (g . e_n) * delta_t, m/s
    ):
        """Return (velocity', angular_velocity', slipped) just after the impact.

        A pellet not moving into the plane (v . e_n >= 0) is returned unchanged, slipped = 0.
        """
        normal_speed = wp.dot(velocity, normal)  # v_{c,n} (eq. 9), negative when approaching
        if normal_speed >= scalar(0.0):
            return velocity, angular_velocity, wp.int32(0)

        # eq. (10): N* / m, clamped at zero (no adhesion)
        normal_impulse = wp.max(-(scalar(1.0) + restitution) * normal_speed - gravity_normal_impulse, scalar(0.0))

        # eqs. (4), (6): tangential velocity of the contact point p
        contact_velocity = velocity - radius * wp.cross(angular_velocity, normal)
        slip_velocity = contact_velocity - wp.dot(contact_velocity, normal) * normal
        slip_speed = wp.length(slip_velocity)

        # eqs. (19), (22), (23): stick, or slip with kinetic friction along -e_t
        stick_fraction = inertia_factor / (scalar(1.0) + inertia_factor)
        friction_impulse, slipped = coulomb_impulse(slip_velocity, slip_speed, normal_impulse, stick_fraction, mu_s, mu_d)

        # eqs. (15), (21)/(25), (30): tangential part plus the rebound -E v_n along e_n
        tangential_velocity = velocity - normal_speed * normal
        velocity_after = tangential_velocity + friction_impulse - restitution * normal_speed * normal
        # eqs. (17), (20)/(24): omega' = omega + (r_cp x f dt)/I with r_cp = -R e_n
        angular_velocity_after = angular_velocity + wp.cross(friction_impulse, normal) * (scalar(1.0) / (inertia_factor * radius))
        return velocity_after, angular_velocity_after, slipped

    return impact_law
