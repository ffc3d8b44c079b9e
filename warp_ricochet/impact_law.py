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

Pellet-pellet collisions (`make_pair_law`) use the same law generalised to two spheres: the
reduced mass, both spins, the relative slip velocity of the contact points, the same stick-slip
rule (`coulomb_impulse`, shared) and restitution on the normal relative velocity. See
docs/collisions.md.
"""


import functools

import warp as wp

SOLID_SPHERE_INERTIA_FACTOR = 0.4  # I = 2/5 m R^2 (eq. 17)


@functools.cache
def make_coulomb_impulse(scalar):
    """The stick-slip friction rule shared by the plane law and the pair law (eqs. 18-23)."""
    vec3 = wp.types.vector(3, scalar)

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
def make_impact_law(scalar):
    """Return the `@wp.func` impact law for a Warp scalar type (wp.float32 or wp.float64)."""
    vec3 = wp.types.vector(3, scalar)
    coulomb_impulse = make_coulomb_impulse(scalar)

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
        normal_impulse = wp.max(
            -(scalar(1.0) + restitution) * normal_speed - gravity_normal_impulse, scalar(0.0)
        )

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
        angular_velocity_after = angular_velocity + wp.cross(friction_impulse, normal) * (
            scalar(1.0) / (inertia_factor * radius)
        )
        return velocity_after, angular_velocity_after, slipped

    return impact_law


@functools.cache
def make_pair_law(scalar):
    """Return the `@wp.func` pair law (pellet-pellet impact) for a Warp scalar type.

    Spheres a and b; n = (x_b - x_a) / d. The contact arms are scaled so they sum to d
    (s = d / (R_a + R_b), arms s R_a n and -s R_b n): angular momentum is then conserved exactly
    even for overlapping spheres, and for touching ones (s = 1) they are the radii.
    Relative velocity of the contact points: u = v_b - v_a - (s R_b w_b + s R_a w_a) x n.
    With P the impulse on b (-P on a) per unit reduced mass m* = m_a m_b / (m_a + m_b):
      normal     P_n = -(1 + E) u_n                          (restitution on the normal relative velocity)
      stick      P_t = -k / (k + s^2) u_t                    (k/(1+k) at contact: the plane law's eq. 19)
      slip       P_t = -mu_d P_n e_t  if k/(k+s^2)|u_t| > mu_s P_n   (eqs. 22-23, shared rule)
      update     v_a -= (m*/m_a) P, v_b += (m*/m_b) P,
                 w_a -= s (m*/m_a) (n x P) / (k R_a), w_b -= s (m*/m_b) (n x P) / (k R_b).
    Linear and angular momentum are conserved; energy never rises (the impulse is at most the
    sticking one). As m_b -> inf this is the plane law with normal -n and no gravity term.
    """
    vec3 = wp.types.vector(3, scalar)
    coulomb_impulse = make_coulomb_impulse(scalar)

    @wp.func
    def pair_law(
        position_a: vec3,  # m
        velocity_a: vec3,  # m/s
        angular_velocity_a: vec3,  # rad/s
        radius_a: scalar,  # m
        mass_a: scalar,  # kg (only the ratio m*/m_a matters)
        position_b: vec3,
        velocity_b: vec3,
        angular_velocity_b: vec3,
        radius_b: scalar,
        mass_b: scalar,
        inertia_factor: scalar,  # I / (m R^2), both spheres
        restitution: scalar,
        mu_s: scalar,
        mu_d: scalar,
    ):
        """Return (v_a', w_a', v_b', w_b', collided, slipped); unchanged, collided = 0, unless the
        contact points approach (u . n < 0)."""
        offset = position_b - position_a
        distance = wp.length(offset)
        if distance <= scalar(0.0):
            return velocity_a, angular_velocity_a, velocity_b, angular_velocity_b, wp.int32(0), wp.int32(0)
        normal = offset / distance
        scale = distance / (radius_a + radius_b)
        relative = velocity_b - velocity_a - wp.cross(
            (scale * radius_b) * angular_velocity_b + (scale * radius_a) * angular_velocity_a, normal
        )
        normal_speed = wp.dot(relative, normal)
        if normal_speed >= scalar(0.0):
            return velocity_a, angular_velocity_a, velocity_b, angular_velocity_b, wp.int32(0), wp.int32(0)
        normal_impulse = -(scalar(1.0) + restitution) * normal_speed
        slip_velocity = relative - normal_speed * normal
        stick_fraction = inertia_factor / (inertia_factor + scale * scale)
        friction_impulse, slipped = coulomb_impulse(
            slip_velocity, wp.length(slip_velocity), normal_impulse, stick_fraction, mu_s, mu_d
        )
        impulse = normal_impulse * normal + friction_impulse  # on b, per unit reduced mass
        reduced = mass_a * mass_b / (mass_a + mass_b)
        share_a = reduced / mass_a
        share_b = reduced / mass_b
        moment = wp.cross(normal, impulse)
        velocity_a_after = velocity_a - share_a * impulse
        velocity_b_after = velocity_b + share_b * impulse
        angular_velocity_a_after = angular_velocity_a - (scale * share_a / (inertia_factor * radius_a)) * moment
        angular_velocity_b_after = angular_velocity_b - (scale * share_b / (inertia_factor * radius_b)) * moment
        return velocity_a_after, angular_velocity_a_after, velocity_b_after, angular_velocity_b_after, wp.int32(1), slipped

    return pair_law
