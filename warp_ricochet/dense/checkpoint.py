"""A shot's checkpoint, every block of its own steps: its horizon (the next event over all its pairs
and planes, exact), and then whether it stops, jumps to that event, or rebuilds its lists."""

import functools
from types import SimpleNamespace

import warp as wp

from .air import make_dense_air
from .constants import (
    CHECKPOINT,
    FLAG_REMAINING,
    FLAG_WIDENED,
    FLYING,
    FRAME_RECENTRE,
    LEAP_MAX_VALUE,
    SHOT_BUSY,
    SHOT_DONE,
    SHOT_FRAME,
    SHOT_LEAP,
    SHOT_REBUILD,
    SHOT_STALL,
)
from .events import make_events
from .kit import dense_kit
from .leap import make_leap


@functools.cache
def make_checkpoint(spec) -> SimpleNamespace:
    """horizon_pellet, now_pellet and settle_shot."""
    kit = dense_kit(spec)
    scalar, Surfaces, Physics, Cloud, Pair = kit.scalar, kit.Surfaces, kit.Physics, kit.Cloud, kit.Pair
    NEVER, AIR, BOUNCES = kit.NEVER, kit.AIR, kit.BOUNCES
    ballistic_position, ballistic_velocity = kit.ballistic.position, kit.ballistic.velocity
    next_contact = kit.flight.next_contact
    contact_time = make_events(spec).contact_time
    air = make_dense_air(spec) if AIR else None  # (their calls compile only in air)
    lp = make_leap(spec) if AIR else None
    LEAP_MAX = scalar(LEAP_MAX_VALUE)

    @wp.func(inline=True)
    def horizon_pellet(
        i: wp.int32, begin: wp.int32, end: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud
    ):
        """Per shot at each of its checkpoints: busy in its arrival window; after it, its next event over ALL
        its pairs (exact: their relative motion is linear; each pair once, O(count) per pellet)
        and planes, so that
        - the shot stops only when no pair at all can meet (pellets farther apart than the lists'
          reach may still converge): whether a shot is busy never depends on the lists;
        - it jumps to its next event instead of stepping through empty time with steps sized for
          its fastest pellets (typically two rebounds converging slowly for tens of milliseconds).
        The pairs with the pellets m = [begin, end) after it (all: [1, count / 2 + 1)); the planes
        with the piece that starts at 1. A large shot's horizon is split into pieces of m (one
        launch each, so the host can stop between them): the shot's minima and flags are the
        same for any split."""
        s = i / pair.count
        if cloud.state.phase[i] != FLYING or cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != CHECKPOINT:
            return
        time = cloud.clock.time[s]
        if time < cloud.clock.window[s]:
            # the arrival window: the cloud converges, meets the surface and passes it (wp.static:
            # see resolve_pellet, a constant used in a branch that returns, then on another path)
            cloud.shot_flags[s, wp.static(SHOT_BUSY)] = 1
            return
        x = cloud.now.position[i]
        v = cloud.now.velocity[i]
        speed = cloud.now.speed[i]
        reach = scalar(2.0) * physics.radius
        reach2 = reach * reach
        earliest = NEVER
        leap = NEVER  # in air (dense.leap): the earliest time anything may happen
        leaps = False
        margin = scalar(0.0)
        if wp.static(AIR):
            leaps = pair.leaps != 0
            margin = cloud.lists.half_skin[s]
        # each pair once (twice for the pairs half a shot apart when the count is even): pellet k
        # of the shot with the next count / 2 after it, cyclically, so every thread does as much
        first = s * pair.count
        for m in range(begin, end):
            j = first + (i - first + m) % pair.count
            if cloud.state.phase[j] == FLYING:
                d = cloud.now.position[j] - x
                u = cloud.now.velocity[j] - v
                if wp.dot(d, u) < scalar(0.0):  # closing (contact_time has no time for the others)
                    delay = contact_time(d, u, reach2, speed + cloud.now.speed[j])
                    if delay >= scalar(0.0):
                        earliest = wp.min(earliest, time + delay)
                if wp.static(AIR):
                    if leaps:
                        bound = cloud.now.bound[i] + cloud.now.bound[j]
                        leap = wp.min(leap, time + lp.pair_leap(d, u, reach, margin, bound, speed + cloud.now.speed[j]))
        if earliest < NEVER:
            cloud.shot_flags[s, wp.static(SHOT_BUSY)] = 1  # a pair can still meet
        if wp.static(AIR):
            # a pellet's landing after its last impact does not bound a leap (the leap flies it there)
            if leaps and begin == 1 and cloud.state.impacts[i] < wp.static(BOUNCES):
                leap = wp.min(leap, time + lp.plane_leap(x, v, cloud.now.bound[i], surfaces, physics))
            wp.atomic_min(cloud.clock.next, s, leap)
        else:
            # plane contacts bound the jump (they do not keep a shot stepping: the core's flight does them)
            if begin == 1:
                wait, k = next_contact(
                    cloud.state.position[i],
                    cloud.state.velocity[i],
                    cloud.state.angular_velocity[i],
                    cloud.state.touching[i],
                    surfaces,
                    physics,
                )
                if k >= 0:
                    earliest = wp.min(earliest, cloud.state.time[i] + wait)
            wp.atomic_min(cloud.clock.next, s, earliest)

    @wp.func(inline=True)
    def now_pellet(i: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """A flying pellet's state at its shot's checkpoint, for horizon_pellet (computed once,
        not once per pair)."""
        s = i / pair.count
        if cloud.state.phase[i] != FLYING or cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != CHECKPOINT:
            return
        time = cloud.clock.time[s]
        age = time - cloud.state.time[i]
        position = ballistic_position(cloud.state.position[i], cloud.state.velocity[i], physics.gravity, age)
        velocity = ballistic_velocity(cloud.state.velocity[i], physics.gravity, age)
        if wp.static(AIR):  # the end of its drift, and the bound on the air in a leap (dense.leap)
            position, velocity, _spin = air.drift_end(cloud, i, time, time, physics)
            speed = wp.length(velocity - physics.air.wind) + wp.length(physics.gravity) * LEAP_MAX
            cloud.now.bound[i] = air.acceleration_bound(speed, physics)
        cloud.now.position[i] = position
        cloud.now.velocity[i] = velocity
        cloud.now.speed[i] = wp.length(velocity)

    @wp.func
    def settle_shot(s: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """At a checkpoint (after block_steps of its own steps, so the
        decision does not depend on the other shots), a shot with nothing ahead, or out of steps,
        stops stepping; one still busy jumps to its next event and recentres its frame."""
        if cloud.shot_flags[s, SHOT_DONE] != 0:
            return
        steps = cloud.clock.steps[s]
        checkpoint = cloud.shot_flags[s, SHOT_STALL] == CHECKPOINT  # (not a stall for a rebuild)
        if checkpoint and (cloud.shot_flags[s, SHOT_BUSY] == 0 or steps >= pair.max_steps):
            cloud.shot_flags[s, SHOT_DONE] = 1
            cloud.clock.end[s] = cloud.clock.time[s]
        else:
            wp.atomic_add(cloud.flags, FLAG_REMAINING, 1)
            if cloud.shot_flags[s, SHOT_STALL] == 1:
                cloud.shot_flags[s, SHOT_REBUILD] = 1  # it waits for its lists
                if cloud.lists.step_travel[s] > scalar(0.0):
                    # a fixed step longer than its skin allows: the shot's skin widens so a list
                    # lasts a step (lists hold candidates only: the results do not change)
                    cloud.lists.half_skin[s] = scalar(1.25) * cloud.lists.step_travel[s]
                    cloud.lists.step_travel[s] = scalar(0.0)
                    wp.atomic_max(cloud.lists.widest_half_skin, 0, cloud.lists.half_skin[s])
                    cloud.flags[FLAG_WIDENED] = 1
            leaping = wp.int32(0)
            if checkpoint:
                # nothing happens before the shot's next event (horizon_kernel): jump to a step
                # before it (pellets carry reference states: only the clock moves); in air the
                # pellets leap there, flown through it (dense.leap), and then the frame follows
                time = cloud.clock.time[s]
                ahead = cloud.clock.next[s] - cloud.clock.step[s]
                if wp.static(AIR):
                    ahead = wp.min(ahead, time + LEAP_MAX)
                    if pair.leaps != 0 and cloud.clock.next[s] < NEVER and ahead > time:
                        cloud.clock.leap[s] = time
                        cloud.clock.time[s] = ahead
                        cloud.shot_flags[s, wp.static(SHOT_LEAP)] = 1
                        leaping = wp.int32(1)
                else:
                    if cloud.clock.next[s] < NEVER and ahead > time:
                        cloud.clock.time[s] = ahead
            if checkpoint and leaping == 0:
                # the co-moving frame follows the shot's flying pellets (after a ricochet they move
                # nothing like the launch): speeds relative to it set the step. The lists are
                # rebuilt in the new frame before the next step (dense.frame: framed_shot).
                cloud.shot_flags[s, wp.static(SHOT_FRAME)] = wp.static(FRAME_RECENTRE)
        cloud.shot_flags[s, SHOT_BUSY] = 0
        cloud.shot_flags[s, SHOT_STALL] = 0
        cloud.clock.next[s] = NEVER
        cloud.clock.cut[s] = NEVER
        cloud.clock.skin[s] = NEVER

    return SimpleNamespace(horizon_pellet=horizon_pellet, now_pellet=now_pellet, settle_shot=settle_shot)
