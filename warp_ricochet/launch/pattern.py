"""A pellet's direction drawn from a shot pattern (scene.patterns, docs/scenes.md "Chokes and patterns").

The model: on any plane across the aim, the pellets' directions are a circular bivariate normal of
standard deviation `spread` (in tan of the polar angle theta) around the aim a. By inverse transform
from two uniforms in [0, 1): the radius rho = tan(theta) = spread sqrt(-2 ln(1 - u_a)) (Rayleigh), the
azimuth phi = 2 pi u_b around the aim, and the direction d = a + rho (cos(phi) e1 + sin(phi) e2), with
(a, e1, e2) orthonormal; d is returned unnormalised (|d| = sqrt(1 + rho^2)), as the jitter's is.

The frame e1, e2 is Duff et al.'s branchless orthonormal basis ("Building an orthonormal basis,
revisited", JCGT 6(1), 2017): continuous away from a_z = -1 and exact in rounding for every unit aim,
a_z = 0 and the poles included. The aim must be a unit vector (`launch.source` normalises the shot's
direction on the host, in float64, for a scene with a pattern). All in the working precision.
"""

import functools

import warp as wp

from ..physics.types import types_for

TWO_PI = 6.283185307179586


@functools.cache
def make_pattern_direction(precision: str):
    """Return the `@wp.func` pattern_direction(aim, spread, u_a, u_b) of one precision."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.func
    def pattern_direction(aim: vec3, spread: scalar, u_a: scalar, u_b: scalar):
        """The unit aim turned by a polar angle drawn from the pattern (u_a) at azimuth 2 pi u_b (unnormalised)."""
        one = scalar(1.0)
        a = aim
        sign = wp.where(a[2] >= scalar(0.0), one, -one)
        k = -one / (sign + a[2])
        b = a[0] * a[1] * k
        e1 = vec3(one + sign * a[0] * a[0] * k, sign * b, -sign * a[0])
        e2 = vec3(b, sign + a[1] * a[1] * k, -a[1])
        rho = spread * wp.sqrt(scalar(-2.0) * wp.log(one - u_a))
        phi = scalar(TWO_PI) * u_b
        return a + (rho * wp.cos(phi)) * e1 + (rho * wp.sin(phi)) * e2

    return pattern_direction
