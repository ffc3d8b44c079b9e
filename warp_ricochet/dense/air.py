"""The air in the dense phase, by Strang splitting: within a step every pellet flies the exact
parabola (so pair and plane contact times stay exact), and the air's own flow (drag, lift and
spin decay, no gravity: `physics.air`) acts at the step's ends, half a step's worth at each
(K(h/2) D(h) K(h/2): second order in h). Each pellet keeps the time up to which it has had the air
(`Cloud.air_time`): a kick at a step's start gives it the air from there to the step's middle; an
event (a plane or a pair contact, which changes its velocity) first gives it the air up to the
event's time; the release gives the rest (or takes back what it had beyond the release). So the
air acts on the velocity the pellet had, and an event costs a local error of order h^2 (a few a
pellet). Kicks every step, not over longer intervals: a pellet leaving a plane with little normal
speed under a strong lift returns within a fraction of a millisecond, which longer intervals miss.

The adaptive step is at most `collisions.air_step_fraction` of the shortest time the air takes to
change a pellet's motion in its shot (|u| / |a_air|), or its motion towards a plane within a step's
reach (|v.n| / |a_air.n|: `air_rate`); a fixed step is kept as given (to measure convergence).
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.air import make_air_laws
from ..physics.ballistic import make_ballistic
from .constants import CLOCK_STEP, CLOCK_TIME
from .frame import make_frame
from .state import dense_types


@functools.cache
def make_dense_air(spec) -> SimpleNamespace:
    """`air_rate`, `kicked` and `kick_pellet` for a spec in air."""
    d = dense_types(spec)
    scalar, vec3, Surfaces, Physics, Cloud, Pair = d.scalar, d.vec3, d.Surfaces, d.Physics, d.Cloud, d.Pair
    TINY_RATE = 1e-30  # 1/s: no air (a pellet at rest in still air)
    laws = make_air_laws(spec.precision, *spec.air_laws)
    _entry, _return, _contact, ballistic_position, ballistic_velocity = make_ballistic(scalar, spec.static_planes)
    fr = make_frame(spec)
    stepping, set_reference = fr.stepping, fr.set_reference

    STATIC_PLANES = spec.static_planes

    @wp.func
    def plane_rate(k: wp.int32, position: vec3, velocity: vec3, acceleration: vec3, reach_time: scalar,
                   surfaces: Surfaces, physics: Physics):
        """Plane k's share of air_rate: |a_air.n| / (|v.n| + speed floor) if the pellet can reach
        the plane within `reach_time` (s), else 0. Planes are one-sided: none behind the centre."""
        n = surfaces.normal[k]
        height = wp.dot(position - surfaces.point[k], n)
        if height < scalar(0.0):
            return scalar(0.0)
        speed = wp.length(velocity) + physics.air.speed_floor
        reach = speed * reach_time + scalar(0.5) * (wp.length(physics.gravity) + wp.length(acceleration)) * reach_time * reach_time
        if height - physics.radius > reach:
            return scalar(0.0)
        return wp.abs(wp.dot(acceleration, n)) / (wp.abs(wp.dot(velocity, n)) + physics.air.speed_floor)

    @wp.func
    def air_rate(position: vec3, velocity: vec3, spin: vec3, pair: Pair, surfaces: Surfaces, physics: Physics):
        """How fast the air changes a pellet's motion (1/s), which bounds the adaptive step (at
        most air_step_fraction over it): |a_air| / (|u| + speed floor), and for each plane within
        a step's reach at that rate, |a_air.n| / (|v.n| + speed floor). Within a step the exact
        flight leaves the air out, a position error up to |a_air| h^2 / 8 that moves a plane
        contact by |a_air.n| h^2 / (8 |v.n|): the second rate keeps that a small fraction of a
        step, also for a pellet leaving a plane slowly under a strong lift."""
        acceleration, _spin_change = laws.air_rates(velocity, spin, physics.air)
        rate = wp.length(acceleration) / (wp.length(velocity - physics.air.wind) + physics.air.speed_floor)
        reach_time = pair.air_step_fraction / wp.max(rate, scalar(TINY_RATE))
        if wp.static(STATIC_PLANES is None):
            for k in range(surfaces.normal.shape[0]):
                rate = wp.max(rate, plane_rate(k, position, velocity, acceleration, reach_time, surfaces, physics))
        else:
            for k in range(wp.static(STATIC_PLANES)):  # unrolled
                rate = wp.max(rate, plane_rate(k, position, velocity, acceleration, reach_time, surfaces, physics))
        return rate

    @wp.func
    def kicked(velocity: vec3, spin: vec3, duration: scalar, physics: Physics):
        """Velocity and spin after the air's flow alone over `duration` (s): the explicit midpoint
        rule, second order like the splitting (a kick is at most a small fraction of the time the
        air takes to change the motion)."""
        a1, d1 = laws.air_rates(velocity, spin, physics.air)
        half = scalar(0.5) * duration
        a2, d2 = laws.air_rates(velocity + half * a1, spin + half * d1, physics.air)
        return velocity + duration * a2, spin + duration * d2

    @wp.func
    def kick_pellet(i: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """Before a step of pellet i's shot: the air from its air time to the step's middle, at
        the shot's clock, where its reference state moves to."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        time = cloud.clock[s, CLOCK_TIME]
        middle = time + scalar(0.5) * cloud.clock[s, CLOCK_STEP]
        duration = middle - cloud.air_time[i]
        cloud.air_time[i] = middle
        age = time - cloud.time[i]
        position = ballistic_position(cloud.position[i], cloud.velocity[i], physics.gravity, age)
        velocity, spin = kicked(ballistic_velocity(cloud.velocity[i], physics.gravity, age), cloud.angular_velocity[i],
                                duration, physics)
        set_reference(cloud, i, position, velocity, spin, time)
        cloud.touching[i] = -1  # (its reference state is off the plane it left: plane times from the gap)
        cloud.stale[i] = 1  # (every flying pellet of the shot is kicked: all are found again)

    return SimpleNamespace(air_rate=air_rate, kicked=kicked, kick_pellet=kick_pellet)
