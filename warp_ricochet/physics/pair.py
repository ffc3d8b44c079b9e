"""The pellet-pellet law: the plane law of `physics.impact` generalised to two spheres (the reduced
mass, both spins, the relative slip velocity of the contact points, the same stick-slip rule
`coulomb_impulse` and restitution on the normal relative velocity). See docs/collisions.md."""

import functools

import warp as wp

from .impact import make_coulomb_impulse
from .types import types_for


@functools.cache
def make_pair_law(precision: str):
    """Return the `@wp.func` pair law (pellet-pellet impact) of one precision ("float32" or "float64").

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
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    coulomb_impulse = make_coulomb_impulse(precision)

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
        relative = (
            velocity_b
            - velocity_a
            - wp.cross((scale * radius_b) * angular_velocity_b + (scale * radius_a) * angular_velocity_a, normal)
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
