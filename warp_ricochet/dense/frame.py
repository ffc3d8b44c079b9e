"""The co-moving frame of each shot and each pellet's reference state in it: between events a
pellet flies the exact parabola of eq. (36) from its reference state, and gravity cancels in the
motion relative to the shot's drift (a straight line), which the lists, the skin and the step use."""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.ballistic import make_ballistic
from .constants import CLOCK_TIME, FLYING, HORIZON_RADII, SHOT_DONE, SHOT_STALL
from .state import dense_types


@functools.cache
def make_frame(spec) -> SimpleNamespace:
    """The frame functions of the dense phase."""
    d = dense_types(spec)
    scalar, vec3, Physics, Cloud, Pair = d.scalar, d.vec3, d.Physics, d.Cloud, d.Pair
    TINY_SPEED, NEVER = d.TINY_SPEED, d.NEVER
    _entry, _return, _contact, ballistic_position, ballistic_velocity = make_ballistic(scalar, spec.static_planes)

    @wp.func
    def drift_point(cloud: Cloud, shot: wp.int32, time: scalar, gravity: vec3):
        """The shot's co-moving reference point: its mean launch state in free flight."""
        return ballistic_position(cloud.drift_origin[shot], cloud.drift_velocity[shot], gravity, time)

    @wp.func
    def recentre(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32, time: scalar):
        """The shot's co-moving frame: the mean state of its flying pellets at `time`. One
        thread, in pellet order (deterministic). Returns the flying count and their mean speed
        (not the speed of their mean: a head-on pair has none)."""
        gravity = physics.gravity
        first = s * pair.count
        position_sum = vec3()
        velocity_sum = vec3()
        speed_sum = scalar(0.0)
        flying = wp.int32(0)
        for k in range(pair.count):
            i = first + k
            if cloud.phase[i] == FLYING:
                age = time - cloud.time[i]
                position_sum += ballistic_position(cloud.position[i], cloud.velocity[i], gravity, age)
                velocity_now = ballistic_velocity(cloud.velocity[i], gravity, age)
                velocity_sum += velocity_now
                speed_sum += wp.length(velocity_now)
                flying += 1
        speed = scalar(0.0)
        if flying > 0:
            inverse = scalar(1.0) / scalar(flying)
            mean_position = position_sum * inverse
            velocity = velocity_sum * inverse - gravity * time
            cloud.drift_velocity[s] = velocity
            cloud.drift_origin[s] = mean_position - velocity * time - (scalar(0.5) * time * time) * gravity
            speed = speed_sum * inverse
        return flying, speed

    @wp.func
    def passing_time(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32, time: scalar, speed: scalar):
        """The time the shot's flying pellets take to pass a point: HORIZON_RADII rms radii about
        the frame's point (`recentre` at `time`) over their mean speed `speed`, or over the
        free-fall speed over the cloud's size for a cloud at rest."""
        gravity = physics.gravity
        first = s * pair.count
        centre = drift_point(cloud, s, time, gravity)
        spread = scalar(0.0)
        flying = wp.int32(0)
        for k in range(pair.count):
            i = first + k
            if cloud.phase[i] == FLYING:
                d = ballistic_position(cloud.position[i], cloud.velocity[i], gravity, time - cloud.time[i]) - centre
                spread += wp.dot(d, d)
                flying += 1
        if flying == 0:
            return scalar(0.0)
        radius = wp.sqrt(spread / scalar(flying))
        return scalar(HORIZON_RADII) * radius / wp.max(speed + wp.sqrt(wp.length(gravity) * radius), TINY_SPEED)

    @wp.func
    def relative_to_frame(cloud: Cloud, physics: Physics, i: wp.int32, time: scalar, frame_point: vec3,
                          frame_velocity: vec3):
        """Pellet i's position and velocity at `time` relative to a frame there (gravity cancels:
        between events the relative motion is a straight line)."""
        gravity = physics.gravity
        age = time - cloud.time[i]
        relative = ballistic_position(cloud.position[i], cloud.velocity[i], gravity, age) - frame_point
        relative_velocity = ballistic_velocity(cloud.velocity[i], gravity, age) - frame_velocity
        return relative, relative_velocity

    @wp.func
    def relative_to_drift(cloud: Cloud, physics: Physics, i: wp.int32, s: wp.int32):
        """Pellet i's position and velocity relative to its shot's co-moving frame, at the shot's
        clock."""
        gravity = physics.gravity
        time = cloud.clock[s, CLOCK_TIME]
        return relative_to_frame(cloud, physics, i, time, drift_point(cloud, s, time, gravity),
                                 ballistic_velocity(cloud.drift_velocity[s], gravity, time))

    @wp.func
    def skin_exit(cloud: Cloud, physics: Physics, i: wp.int32, s: wp.int32, position: vec3, velocity: vec3, time: scalar):
        """When pellet i, at `position` with `velocity` at `time` (a new reference state), is half
        its shot's skin from where its list was built (relative to the frame its motion is a
        straight line: gravity cancels); `time` if it is there already and moving out."""
        gravity = physics.gravity
        moved = position - drift_point(cloud, s, time, gravity) - cloud.build_offset[i]
        relative_velocity = velocity - ballistic_velocity(cloud.drift_velocity[s], gravity, time)
        half_skin = cloud.half_skin[s]
        a = wp.dot(relative_velocity, relative_velocity)
        b = wp.dot(moved, relative_velocity)
        c = wp.dot(moved, moved) - half_skin * half_skin
        if a <= scalar(0.0):
            if c < scalar(0.0):
                return NEVER
            return time
        if c >= scalar(0.0) and b >= scalar(0.0):
            return time
        root = wp.sqrt(wp.max(b * b - a * c, scalar(0.0)))
        if b <= scalar(0.0):
            return time + (root - b) / a  # the later root (no cancellation: -b >= 0)
        return time - c / (b + root)  # the same root, written without cancellation (c < 0 here)

    @wp.func
    def stepping(cloud: Cloud, i: wp.int32, s: wp.int32):
        """Pellet i of shot s takes part in this step."""
        return cloud.phase[i] == FLYING and cloud.shot_flags[s, SHOT_DONE] == 0 and cloud.shot_flags[s, SHOT_STALL] == 0

    @wp.func
    def set_reference(cloud: Cloud, i: wp.int32, position: vec3, velocity: vec3, spin: vec3, time: scalar):
        """Pellet i's new reference state (its flight from here is the parabola of eq. 36)."""
        cloud.position[i] = position
        cloud.velocity[i] = velocity
        cloud.angular_velocity[i] = spin
        cloud.time[i] = time

    @wp.func
    def set_build_point(cloud: Cloud, physics: Physics, i: wp.int32, time: scalar, origin: vec3):
        """Pellet i's co-moving grid point at its shot's clock (`origin`: the drift point then),
        which its skin is measured from until the next build."""
        relative = ballistic_position(cloud.position[i], cloud.velocity[i], physics.gravity, time - cloud.time[i]) - origin
        cloud.build_offset[i] = relative
        cloud.grid_point[i] = relative
        return relative

    @wp.func
    def mark_stale(cloud: Cloud, i: wp.int32):
        """Pellet i changed (or ended): its event, and its neighbours', are found again (the
        lists are symmetric, so every pellet that could have chosen i is marked)."""
        cloud.stale[i] = 1
        for n in range(cloud.neighbour_count[i]):
            cloud.stale[cloud.neighbours[i, n]] = 1

    return SimpleNamespace(drift_point=drift_point, recentre=recentre, passing_time=passing_time, relative_to_frame=relative_to_frame, relative_to_drift=relative_to_drift, skin_exit=skin_exit, stepping=stepping, set_reference=set_reference, set_build_point=set_build_point, mark_stale=mark_stale)
