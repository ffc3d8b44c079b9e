"""Exact ballistic flight between surfaces (Zohdi 2021, eqs. 36-42), without time stepping.

A pellet's centre follows r(t) = r0 + v0 t + g t^2 / 2 (eq. 36). Against a plane (point p,
unit normal e_n towards the pellet) the gap between the sphere and the plane is the quadratic
    gap(t) = (g . e_n)/2 t^2 + (v0 . e_n) t + (e_n . (r0 - p) - R),
and the pellet meets the plane at the first t >= 0 where the gap reaches zero while closing.
Leaving the plane it just hit (gap 0, normal speed v_n' > 0) it returns after
    t* = -2 v_n' / (g . e_n)  (= 2 v_n / g for gravity along -e_n),
which is what the paper's tables use; eqs. (40) and (42) print a square root by mistake.

Planes are one-sided: a pellet whose centre is behind a plane does not interact with it.

Rounding: a normal gravity component within rounding noise of zero (ROUNDING machine epsilons of
its scale) is taken as zero, so gravity along a plane does not give a time of flight of 1e17 s; a
gap within rounding of zero is the touching band of `physics.geometry`; a contact later than
MAX_FLIGHT_TIME counts as none.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .types import types_for

NO_CONTACT = -1.0  # returned as the time when a pellet never meets a plane
MAX_FLIGHT_TIME = 1.0e6  # s: a later contact counts as none (keeps every float32 product finite)
ROUNDING = 64.0  # rounding-noise tolerances are this many machine epsilons of the quantities' scale
EPSILON = {"float32": 1.1920929e-07, "float64": 2.220446049250313e-16}


@functools.cache
def make_ballistic(precision: str) -> SimpleNamespace:
    """The flight `@wp.func`s of one precision ("float32" or "float64"): `entry_time` and
    `return_time` (the roots of a gap's quadratic) and eq. (36)'s `position` and `velocity`. The
    search over the surfaces is `physics.geometry.make_geometry(...).next_contact`."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.func
    def entry_time(gap: scalar, normal_speed: scalar, half_normal_gravity: scalar):
        """First t >= 0 with gap(t) = 0 while closing, or NO_CONTACT. Stable quadratic roots.

        A pellet touching or overlapping the plane (gap <= 0, centre in front of it) is in
        contact: now if it closes; if it moves away while gravity pulls it back, when it next
        closes (the larger root, or the apex if it never separates)."""
        if gap <= scalar(0.0):
            if normal_speed < scalar(0.0):
                return scalar(0.0)
            if half_normal_gravity < scalar(0.0):
                disc = normal_speed * normal_speed - scalar(4.0) * half_normal_gravity * gap
                if disc < scalar(0.0):
                    return -normal_speed / (scalar(2.0) * half_normal_gravity)  # apex, still overlapping
                return -(normal_speed + wp.sqrt(disc)) / (scalar(2.0) * half_normal_gravity)
            return scalar(NO_CONTACT)
        if half_normal_gravity == scalar(0.0):
            if normal_speed < scalar(0.0):
                return -gap / normal_speed
            return scalar(NO_CONTACT)
        disc = normal_speed * normal_speed - scalar(4.0) * half_normal_gravity * gap
        if disc < scalar(0.0):
            return scalar(NO_CONTACT)
        root = wp.sqrt(disc)
        # the closing root is (-b - sqrt(disc)) / (2a) for either sign of a; avoid cancellation
        t = scalar(0.0)
        if normal_speed >= scalar(0.0):
            t = -(normal_speed + root) / (scalar(2.0) * half_normal_gravity)
        else:
            t = scalar(2.0) * gap / (root - normal_speed)
        if t > scalar(0.0):
            return t
        return scalar(NO_CONTACT)

    @wp.func
    def return_time(normal_speed: scalar, half_normal_gravity: scalar):
        """Time to come back to the plane the pellet is leaving (gap 0); eq. (40) corrected.

        A pellet that leaves with no normal speed stays on the surface: it lands at once.
        """
        if normal_speed <= scalar(0.0):
            return scalar(0.0)
        if half_normal_gravity < scalar(0.0):
            return -normal_speed / half_normal_gravity
        return scalar(NO_CONTACT)

    @wp.func
    def ballistic_position(position: vec3, velocity: vec3, gravity: vec3, t: scalar):
        """Eq. (36): r(t) = r0 + v0 t + g t^2 / 2."""
        return position + velocity * t + (scalar(0.5) * t * t) * gravity

    @wp.func
    def ballistic_velocity(velocity: vec3, gravity: vec3, t: scalar):
        """dr/dt of eq. (36)."""
        return velocity + gravity * t

    return SimpleNamespace(
        entry_time=entry_time, return_time=return_time, position=ballistic_position, velocity=ballistic_velocity
    )
