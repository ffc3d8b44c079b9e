"""The co-moving frame of each shot and each pellet's reference state in it: between events a
pellet flies the exact parabola of eq. (36) from its reference state, and gravity cancels in the
motion relative to the shot's drift (a straight line), which the lists, the skin and the step use."""

import functools
from types import SimpleNamespace

import warp as wp

from .constants import (
    FLAG_STALL,
    FLYING,
    FRAME_START,
    HORIZON_RADII,
    SHOT_DONE,
    SHOT_FRAME,
    SHOT_REBUILD,
    SHOT_STALL,
)
from .kit import dense_kit


@functools.cache
def make_frame(spec) -> SimpleNamespace:
    """The frame functions of the dense phase."""
    kit = dense_kit(spec)
    scalar, vec3, Physics, Cloud, Pair = kit.scalar, kit.vec3, kit.Physics, kit.Cloud, kit.Pair
    TINY_SPEED, NEVER = kit.TINY_SPEED, kit.NEVER
    ballistic_position, ballistic_velocity = kit.ballistic.position, kit.ballistic.velocity

    @wp.func
    def drift_point(cloud: Cloud, shot: wp.int32, time: scalar, gravity: vec3):
        """The shot's co-moving reference point: its mean launch state in free flight."""
        return ballistic_position(cloud.frame.drift_origin[shot], cloud.frame.drift_velocity[shot], gravity, time)

    @wp.func
    def block_range(pair: Pair, s: wp.int32, b: wp.int32):
        """The rows [first, last) of block b of shot s (`Pair.frame_block` pellets, FRAME_BLOCK; the
        last may be short)."""
        first = s * pair.count + b * pair.frame_block
        return first, wp.min(first + pair.frame_block, (s + 1) * pair.count)

    @wp.func
    def frame_block(pair: Pair, physics: Physics, cloud: Cloud, row: wp.int32):
        """Block `row` (shot row / frame_blocks) of a shot whose frame is due (SHOT_FRAME): the sums
        of its flying pellets' positions, velocities and speeds at the shot's clock, and their
        count, in pellet order (one thread a block on CUDA; `frame_shot` for the CPU)."""
        s = row / pair.frame_blocks
        if cloud.shot_flags[s, SHOT_FRAME] == 0:
            return
        gravity = physics.gravity
        time = cloud.clock.time[s]
        first, last = block_range(pair, s, row - s * pair.frame_blocks)
        position_sum = vec3()
        velocity_sum = vec3()
        speed_sum = scalar(0.0)
        flying = wp.int32(0)
        for i in range(first, last):
            if cloud.state.phase[i] == FLYING:
                age = time - cloud.state.time[i]
                position_sum += ballistic_position(cloud.state.position[i], cloud.state.velocity[i], gravity, age)
                velocity_now = ballistic_velocity(cloud.state.velocity[i], gravity, age)
                velocity_sum += velocity_now
                speed_sum += wp.length(velocity_now)
                flying += 1
        cloud.frame.position[row] = position_sum
        cloud.frame.velocity[row] = velocity_sum
        cloud.frame.speed[row] = speed_sum
        cloud.frame.flying[row] = flying

    @wp.func
    def recentre(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32):
        """The shot's co-moving frame from its blocks' sums (`frame_block`, added in block order:
        deterministic, and for one block the sums in pellet order): the mean state of its flying
        pellets at its clock. Returns the flying count and their mean speed (not the speed of
        their mean: a head-on pair has none)."""
        gravity = physics.gravity
        time = cloud.clock.time[s]
        row = s * pair.frame_blocks
        position_sum = cloud.frame.position[row]
        velocity_sum = cloud.frame.velocity[row]
        speed_sum = cloud.frame.speed[row]
        flying = cloud.frame.flying[row]
        for b in range(1, pair.frame_blocks):
            position_sum += cloud.frame.position[row + b]
            velocity_sum += cloud.frame.velocity[row + b]
            speed_sum += cloud.frame.speed[row + b]
            flying += cloud.frame.flying[row + b]
        speed = scalar(0.0)
        if flying > 0:
            inverse = scalar(1.0) / scalar(flying)
            mean_position = position_sum * inverse
            velocity = velocity_sum * inverse - gravity * time
            cloud.frame.drift_velocity[s] = velocity
            cloud.frame.drift_origin[s] = mean_position - velocity * time - (scalar(0.5) * time * time) * gravity
            speed = speed_sum * inverse
        return flying, speed

    @wp.func
    def framed_shot(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32):
        """After its blocks' sums: a shot whose frame was due (a checkpoint, a leap) takes it, and
        its lists are rebuilt in it; at the launch the frame and the mean speed (`clock.speed`, for
        the arrival window: `dense.ends`)."""
        due = cloud.shot_flags[s, SHOT_FRAME]
        if due == 0:
            return
        flying, speed = recentre(pair, physics, cloud, s)
        if due == wp.static(FRAME_START):
            cloud.clock.speed[s] = speed
            return  # (the window's pass clears the flag)
        cloud.shot_flags[s, SHOT_FRAME] = 0
        if flying > 0:
            cloud.shot_flags[s, SHOT_REBUILD] = 1
            cloud.flags[FLAG_STALL] = 1

    @wp.func
    def frame_shot(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32):
        """The CPU's `frame_block` of each block of shot s, in order, then `framed_shot`: the same
        sums and the same frame as CUDA's thread a block."""
        if cloud.shot_flags[s, SHOT_FRAME] == 0:
            return
        for b in range(pair.frame_blocks):
            frame_block(pair, physics, cloud, s * pair.frame_blocks + b)
        framed_shot(pair, physics, cloud, s)

    @wp.func
    def passing_time(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32, spread: scalar, flying: wp.int32):
        """The time the shot's flying pellets take to pass a point: HORIZON_RADII rms radii about
        the frame's point (`spread`: the sum of their squared distances from it, m^2) over their
        mean speed (`clock.speed`), or over the free-fall speed over the cloud's size for a cloud at
        rest."""
        if flying == 0:
            return scalar(0.0)
        radius = wp.sqrt(spread / scalar(flying))
        speed = cloud.clock.speed[s]
        return scalar(HORIZON_RADII) * radius / wp.max(speed + wp.sqrt(wp.length(physics.gravity) * radius), TINY_SPEED)

    @wp.func
    def relative_to_frame(cloud: Cloud, physics: Physics, i: wp.int32, time: scalar, frame_point: vec3, frame_velocity: vec3):
        """Pellet i's position and velocity at `time` relative to a frame there (gravity cancels:
        between events the relative motion is a straight line)."""
        gravity = physics.gravity
        age = time - cloud.state.time[i]
        relative = ballistic_position(cloud.state.position[i], cloud.state.velocity[i], gravity, age) - frame_point
        relative_velocity = ballistic_velocity(cloud.state.velocity[i], gravity, age) - frame_velocity
        return relative, relative_velocity

    @wp.func
    def relative_to_drift(cloud: Cloud, physics: Physics, i: wp.int32, s: wp.int32):
        """Pellet i's position and velocity relative to its shot's co-moving frame, at the shot's
        clock."""
        gravity = physics.gravity
        time = cloud.clock.time[s]
        return relative_to_frame(
            cloud,
            physics,
            i,
            time,
            drift_point(cloud, s, time, gravity),
            ballistic_velocity(cloud.frame.drift_velocity[s], gravity, time),
        )

    @wp.func
    def skin_exit(cloud: Cloud, physics: Physics, i: wp.int32, s: wp.int32, position: vec3, velocity: vec3, time: scalar):
        """When pellet i, at `position` with `velocity` at `time` (a new reference state), is half
        its shot's skin from where its list was built (relative to the frame its motion is a
        straight line: gravity cancels); `time` if it is there already and moving out."""
        gravity = physics.gravity
        moved = position - drift_point(cloud, s, time, gravity) - cloud.lists.build_offset[i]
        relative_velocity = velocity - ballistic_velocity(cloud.frame.drift_velocity[s], gravity, time)
        half_skin = cloud.lists.half_skin[s]
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
        return cloud.state.phase[i] == FLYING and cloud.shot_flags[s, SHOT_DONE] == 0 and cloud.shot_flags[s, SHOT_STALL] == 0

    @wp.func
    def set_reference(cloud: Cloud, i: wp.int32, position: vec3, velocity: vec3, spin: vec3, time: scalar):
        """Pellet i's new reference state (its flight from here is the parabola of eq. 36)."""
        cloud.state.position[i] = position
        cloud.state.velocity[i] = velocity
        cloud.state.angular_velocity[i] = spin
        cloud.state.time[i] = time

    @wp.func
    def set_build_point(cloud: Cloud, physics: Physics, i: wp.int32, time: scalar, origin: vec3):
        """Pellet i's co-moving grid point at its shot's clock (`origin`: the drift point then),
        which its skin is measured from until the next build."""
        relative = (
            ballistic_position(cloud.state.position[i], cloud.state.velocity[i], physics.gravity, time - cloud.state.time[i])
            - origin
        )
        cloud.lists.build_offset[i] = relative
        cloud.lists.grid_point[i] = relative
        return relative

    @wp.func
    def mark_stale(cloud: Cloud, i: wp.int32):
        """Pellet i changed (or ended): its event, and its neighbours', are found again (the
        lists are symmetric, so every pellet that could have chosen i is marked)."""
        cloud.event.stale[i] = 1
        for n in range(cloud.lists.neighbour_count[i]):
            cloud.event.stale[cloud.lists.neighbours[i, n]] = 1

    return SimpleNamespace(
        drift_point=drift_point,
        block_range=block_range,
        frame_block=frame_block,
        recentre=recentre,
        framed_shot=framed_shot,
        frame_shot=frame_shot,
        passing_time=passing_time,
        relative_to_frame=relative_to_frame,
        relative_to_drift=relative_to_drift,
        skin_exit=skin_exit,
        stepping=stepping,
        set_reference=set_reference,
        set_build_point=set_build_point,
        mark_stale=mark_stale,
    )
