"""Where a pellet meets a plane: an impact (the law of `physics.impact`) or the end of its flight,
and the range of eq. (42). The core kernel and the dense phase both decide with these functions;
the surface's normal and material at the contact come from `physics.geometry`.

A pellet that meets a plane without closing speed beyond rounding noise rests on it: its flight
ends there and it is not an impact (an overlapping pellet meets the plane at its apex, where v_n
is 0 give or take an FMA). A pellet that leaves an impact with no normal speed (E = 0, up to
rounding of the speed it came in with, not of the residue left) stays on the surface too.
"""

import functools

import warp as wp

from .ballistic import EPSILON, ROUNDING
from .geometry import make_geometry
from .impact import make_impact_law
from .types import types_for


def make_contact(precision: str, plates: bool = False):
    """`rests`, `stays`, `impact`, `meet_surface`, `contact_point` and `landing_range` for one
    precision; `plates`: surfaces may be finite plates (the geometry `meet_surface` reads the
    material through; its caller gives the normal). One cached set per value of the two."""
    return _make_contact(precision, bool(plates))


@functools.cache
def _make_contact(precision: str, plates: bool):
    t = types_for(precision)
    scalar, vec3, Surfaces, Material, Physics = t.scalar, t.vec3, t.Surfaces, t.Material, t.Physics
    impact_law, geo = make_impact_law(precision), make_geometry(precision, plates=plates)
    CLOSING_TOLERANCE2 = scalar((ROUNDING * EPSILON[precision]) ** 2)  # normal speeds within rounding of 0

    @wp.func
    def rests(velocity: vec3, normal: vec3):
        """No closing speed at the plane beyond rounding noise: the flight ends, no impact."""
        normal_speed = wp.dot(velocity, normal)
        return normal_speed >= scalar(0.0) or normal_speed * normal_speed <= CLOSING_TOLERANCE2 * wp.dot(velocity, velocity)

    @wp.func
    def stays(velocity_after: vec3, normal: vec3, speed_before2: scalar):
        """After an impact, no normal speed beyond rounding of the incoming speed (squared, m^2/s^2)."""
        leaving_speed = wp.dot(velocity_after, normal)
        return leaving_speed * leaving_speed <= CLOSING_TOLERANCE2 * speed_before2

    @wp.func
    def impact(material: Material, normal: vec3, velocity: vec3, spin: vec3, physics: Physics):
        """The impact law (eqs. 1-25) on a surface of `material` and unit `normal` at the contact
        (`physics.geometry`), gravity resisted during the contact (eq. 10): (velocity', spin', slipped)."""
        return impact_law(
            velocity,
            spin,
            normal,
            physics.radius,
            physics.inertia_factor,
            material.restitution,
            material.mu_s,
            material.mu_d,
            wp.dot(physics.gravity, normal) * physics.impact_duration,
        )

    @wp.func
    def meet_surface(k: wp.int32, position: vec3, velocity: vec3, spin: vec3, normal: vec3, surfaces: Surfaces, physics: Physics):
        """A pellet at `position` (m) with `velocity` (m/s) and `spin` (rad/s) meets surface k of
        unit `normal` there (`geometry.contact_normal`: a mesh's is the face met): returns
        (velocity', spin', slipped, impacted, flies_on). Not an impact if it rests there (unchanged state)."""
        if rests(velocity, normal):
            return velocity, spin, wp.int32(0), wp.int32(0), wp.int32(0)
        velocity_after, spin_after, slipped = impact(geo.material(surfaces, k, position), normal, velocity, spin, physics)
        flies_on = wp.int32(1)
        if stays(velocity_after, normal, wp.dot(velocity, velocity)):
            flies_on = wp.int32(0)
        return velocity_after, spin_after, slipped, wp.int32(1), flies_on

    @wp.func
    def contact_point(position: vec3, radius: scalar, normal: vec3):
        """The point where a sphere centred at `position` touches the plane of `normal` (m)."""
        return position - radius * normal

    @wp.func
    def landing_range(position: vec3, radius: scalar, normal: vec3, ricochet_point: vec3):
        """Eq. (42): the distance from the last ricochet's contact point to the landing's (m)."""
        return wp.length(contact_point(position, radius, normal) - ricochet_point)

    return rests, stays, impact, meet_surface, contact_point, landing_range
