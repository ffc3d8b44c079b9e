"""The start and the end of the dense phase: each pellet's launch, each shot's clock, frame and
arrival window, the release (each pellet's state when its shot stopped stepping), each shot's
totals, and the pellets' centres for a trajectory frame (taken on the device; the host copies them)."""

import functools
from types import SimpleNamespace

import warp as wp

from ..launch.source import make_source
from .air import make_dense_air
from .constants import (
    CHECKPOINT,
    FLYING,
    FRAME_START,
    SHOT_BUSY,
    SHOT_DONE,
    SHOT_FRAME,
    SHOT_REBUILD,
    SHOT_STALL,
)
from .frame import make_frame
from .kit import dense_kit
from .watch import make_dense_watch


@functools.cache
def make_ends(spec) -> SimpleNamespace:
    """launch_pellet, start_shot, release_pellet, block_totals and shot_totals."""
    kit = dense_kit(spec)
    scalar, vec3, Surfaces, Physics, Cloud, Pair = kit.scalar, kit.vec3, kit.Surfaces, kit.Physics, kit.Cloud, kit.Pair
    Outputs, Source, NEVER, WRITE, AIR = kit.Outputs, kit.Source, kit.NEVER, kit.WRITE, kit.AIR
    ballistic_position, ballistic_velocity = kit.ballistic.position, kit.ballistic.velocity
    launch_state = make_source(kit.precision, spec.from_file, spec.pattern, spec.stations).launch_state
    write_initial = kit.outputs.write_initial
    # the arrival window: from each pellet's first contact in its own flight (in air: integrated)
    next_contact = kit.run_flight.next_contact
    air = make_dense_air(spec) if AIR else None  # (its calls compile only in air)
    fr = make_frame(spec)
    set_reference, block_range, drift_point, passing_time = fr.set_reference, fr.block_range, fr.drift_point, fr.passing_time
    watch = make_dense_watch(spec)

    @wp.func
    def launch_pellet(i: wp.int32, first_index: wp.int32, source: Source, cloud: Cloud, out: Outputs):
        """Launch state of each pellet (sampled from its global index, or given), phase FLYING."""
        position, velocity, spin = launch_state(source, first_index + i, i)
        if wp.static(WRITE):
            write_initial(out, i, position, velocity, spin)  # (bounces without an impact: the core kernel marks them)
        cloud.state.position[i] = position
        cloud.state.velocity[i] = velocity
        cloud.state.angular_velocity[i] = spin
        cloud.state.launch_velocity[i] = velocity
        cloud.state.launch_angular_velocity[i] = spin
        cloud.state.time[i] = scalar(0.0)
        cloud.state.phase[i] = FLYING
        watch.launch(cloud, i)
        cloud.state.end_surface[i] = -1
        cloud.state.touching[i] = -1
        cloud.state.impacts[i] = 0
        cloud.state.last_slipped[i] = 0
        cloud.state.ricochet_point[i] = vec3()
        cloud.state.ricochet_time[i] = scalar(0.0)
        cloud.state.first_surface[i] = -1
        cloud.state.first_slipped[i] = 0
        cloud.collisions.count[i] = 0
        cloud.collisions.energy_lost[i] = scalar(0.0)
        cloud.air.time[i] = scalar(0.0)
        cloud.air.kick_due[i] = 0
        cloud.air.rate[i] = scalar(0.0)
        cloud.air.position_error[i] = vec3()
        cloud.collisions.last_time[i] = scalar(wp.nan)
        cloud.lists.neighbour_count[i] = 0
        cloud.event.stale[i] = 1
        cloud.event.partner[i] = -1
        cloud.event.time[i] = NEVER

    @wp.func
    def start_shot(s: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """One thread per shot: the clock starts at 0; the co-moving frame at the launch and the
        arrival window are due (`dense.frame`, then `start_block` and `window_shot`)."""
        cloud.clock.time[s] = scalar(0.0)
        cloud.clock.step[s] = scalar(0.0)
        cloud.clock.drift[s] = scalar(0.0)
        cloud.clock.steps[s] = scalar(0.0)
        cloud.clock.end[s] = scalar(0.0)
        cloud.clock.window[s] = scalar(0.0)
        cloud.clock.overrun[s] = scalar(0.0)
        cloud.clock.air[s] = scalar(0.0)
        cloud.clock.leap[s] = scalar(0.0)
        cloud.clock.speed[s] = scalar(0.0)
        cloud.clock.next[s] = NEVER
        cloud.clock.cut[s] = NEVER
        cloud.clock.skin[s] = NEVER
        cloud.shot_flags[s, SHOT_FRAME] = FRAME_START
        cloud.shot_flags[s, SHOT_STALL] = CHECKPOINT  # the launch is its first checkpoint
        cloud.shot_flags[s, SHOT_DONE] = 0
        cloud.shot_flags[s, SHOT_BUSY] = 0
        cloud.shot_flags[s, SHOT_REBUILD] = 1
        cloud.lists.half_skin[s] = pair.half_skin
        cloud.lists.step_travel[s] = scalar(0.0)

    @wp.func
    def start_block(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, row: wp.int32):
        """At the launch, after the frame (one thread a block, as `frame.frame_block`): the block's
        squared distances of flying pellets from the frame's point, their count, and the latest
        first contact of its pellets in their own flights (0 if none meets a surface)."""
        s = row / pair.frame_blocks
        if cloud.shot_flags[s, SHOT_FRAME] != wp.static(FRAME_START):
            return
        first, last = block_range(pair, s, row - s * pair.frame_blocks)
        centre = drift_point(cloud, s, scalar(0.0), physics.gravity)
        spread = scalar(0.0)
        flying = wp.int32(0)
        last_arrival = scalar(0.0)
        for i in range(first, last):
            if cloud.state.phase[i] == FLYING:
                d = (
                    ballistic_position(cloud.state.position[i], cloud.state.velocity[i], physics.gravity, -cloud.state.time[i])
                    - centre
                )
                spread += wp.dot(d, d)
                flying += 1
            wait, plane = next_contact(
                cloud.state.position[i], cloud.state.velocity[i], cloud.state.angular_velocity[i], wp.int32(-1), surfaces, physics
            )
            if plane >= 0:
                last_arrival = wp.max(last_arrival, wait)
        cloud.frame.spread[row] = spread
        cloud.frame.flying[row] = flying
        cloud.frame.arrival[row] = last_arrival

    @wp.func
    def window_shot(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32):
        """The arrival window from the blocks (in order): the shot keeps stepping until its
        undisturbed pellets have all met their first surface and the cloud has passed it
        (pellets converging in flight, rebounds meeting the pellets still coming)."""
        if cloud.shot_flags[s, SHOT_FRAME] != wp.static(FRAME_START):
            return
        row = s * pair.frame_blocks
        spread = cloud.frame.spread[row]
        flying = cloud.frame.flying[row]
        last_arrival = cloud.frame.arrival[row]
        for b in range(1, pair.frame_blocks):
            spread += cloud.frame.spread[row + b]
            flying += cloud.frame.flying[row + b]
            last_arrival = wp.max(last_arrival, cloud.frame.arrival[row + b])
        cloud.clock.window[s] = last_arrival + passing_time(pair, physics, cloud, s, spread, flying)
        cloud.shot_flags[s, SHOT_FRAME] = 0

    @wp.func
    def trajectory_point(i: wp.int32, physics: Physics, cloud: Cloud, points: wp.array(dtype=wp.vec3d)):
        """Pellet i's centre (m, float64) at the first shot's clock, for a trajectory frame: eq. (36)
        from its reference state if it flies, else where its flight ended. The host's NumPy
        arithmetic it replaced, operation for operation: the age and x + v age in the run's
        precision, then the gravity term in float64 (exact there for float32 inputs)."""
        age = scalar(0.0)
        if cloud.state.phase[i] == FLYING:
            age = cloud.clock.time[0] - cloud.state.time[i]
        moved = cloud.state.position[i] + cloud.state.velocity[i] * age
        half_gravity = wp.float64(0.5) * wp.vec3d(physics.gravity)
        points[i] = wp.vec3d(moved) + half_gravity * wp.float64(age * age)

    @wp.func
    def release_pellet(i: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """The release outputs: each pellet's state when its shot left the dense phase (or where
        its flight ended in it), and the time of its last pair collision."""
        s = i / pair.count
        time = cloud.state.time[i]
        position = cloud.state.position[i]
        velocity = cloud.state.velocity[i]
        if cloud.state.phase[i] == FLYING:
            time = cloud.clock.end[s]
            age = time - cloud.state.time[i]
            position = ballistic_position(cloud.state.position[i], cloud.state.velocity[i], physics.gravity, age)
            velocity = ballistic_velocity(cloud.state.velocity[i], physics.gravity, age)
            if wp.static(AIR):  # the end of its drift, the air up to now; the core flies on from here
                position, velocity, spin = air.drift_end(cloud, i, time, time, physics)
                watch.to(cloud, surfaces, physics, i, position, time)  # (the hazard along its drift; the core goes on)
                air.air_until(cloud, i, time)
                set_reference(cloud, i, position, velocity, spin, time)
                cloud.state.touching[i] = -1  # (off the plane it left: the core's flight starts from the gap)
        if cloud.written.release_time.shape[0] > 0:
            cloud.written.release_time[i] = time
        if cloud.written.release_position.shape[0] > 0:
            cloud.written.release_position[i] = position
        if cloud.written.release_velocity.shape[0] > 0:
            cloud.written.release_velocity[i] = velocity
        if cloud.written.release_angular_velocity.shape[0] > 0:
            cloud.written.release_angular_velocity[i] = cloud.state.angular_velocity[i]
        if cloud.written.collisions_last_time.shape[0] > 0:
            cloud.written.collisions_last_time[i] = cloud.collisions.last_time[i]

    @wp.func
    def block_totals(row: wp.int32, pair: Pair, cloud: Cloud, blocks: wp.array2d(dtype=wp.float64)):
        """Block `row` (shot row / frame_blocks, `frame.block_range`) of a shot, in pellet order:
        its pellets that collided, its pair collisions and the energy they lost (J)."""
        s = row / pair.frame_blocks
        first, last = block_range(pair, s, row - s * pair.frame_blocks)
        collided = wp.float64(0.0)
        collisions = wp.float64(0.0)
        lost = wp.float64(0.0)
        for i in range(first, last):
            c = cloud.collisions.count[i]
            if c > 0:
                collided += wp.float64(1.0)
            collisions += wp.float64(c)
            lost += wp.float64(cloud.collisions.energy_lost[i])
        blocks[row, 0] = collided
        blocks[row, 1] = collisions
        blocks[row, 2] = lost

    @wp.func
    def shot_totals(
        s: wp.int32, pair: Pair, cloud: Cloud, blocks: wp.array2d(dtype=wp.float64), totals: wp.array2d(dtype=wp.float64)
    ):
        """A shot's totals, its blocks' (`block_totals`) added in block order (deterministic; for
        one block its sums in pellet order): pellets that collided, pair collisions, energy lost
        (J); then its steps, the time it stopped stepping (s), its largest skin overrun (half skins)."""
        row = s * pair.frame_blocks
        for k in range(3):
            total = blocks[row, k]
            for b in range(1, pair.frame_blocks):
                total += blocks[row + b, k]
            totals[s, k] = total
        totals[s, 3] = wp.float64(cloud.clock.steps[s])
        totals[s, 4] = wp.float64(cloud.clock.end[s])
        totals[s, 5] = wp.float64(cloud.clock.overrun[s])

    return SimpleNamespace(
        launch_pellet=launch_pellet,
        start_shot=start_shot,
        start_block=start_block,
        window_shot=window_shot,
        release_pellet=release_pellet,
        trajectory_point=trajectory_point,
        block_totals=block_totals,
        shot_totals=shot_totals,
    )
