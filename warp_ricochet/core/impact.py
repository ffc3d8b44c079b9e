"""The impact law on given states: the kernel behind `warp_ricochet.impact`."""

import functools

import warp as wp

from ..physics.impact import make_impact_law
from ..physics.types import types_for


@functools.cache
def impact_kernel_for(precision: str):
    """One thread per state: the law of eqs. 1-25 on a pellet about to hit a plane."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    impact_law = make_impact_law(precision)

    @wp.kernel(module="unique", enable_backward=False)
    def impact_kernel(
        velocity: wp.array(dtype=vec3),
        angular_velocity: wp.array(dtype=vec3),
        normal: wp.array(dtype=vec3),  # (1,) for one plane, else one per pellet
        radius: scalar,
        inertia_factor: scalar,
        restitution: scalar,
        mu_s: scalar,
        mu_d: scalar,
        gravity: vec3,
        impact_duration: scalar,
        velocity_after: wp.array(dtype=vec3),
        angular_velocity_after: wp.array(dtype=vec3),
        slipped: wp.array(dtype=wp.int8),
    ):
        i = wp.tid()
        n = normal[0]
        if normal.shape[0] > 1:
            n = normal[i]
        v, w, s = impact_law(
            velocity[i],
            angular_velocity[i],
            n,
            radius,
            inertia_factor,
            restitution,
            mu_s,
            mu_d,
            wp.dot(gravity, n) * impact_duration,
        )
        velocity_after[i] = v
        angular_velocity_after[i] = w
        slipped[i] = wp.int8(s)

    return impact_kernel
