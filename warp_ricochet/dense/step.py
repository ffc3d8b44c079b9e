"""One step of a shot: its speed bound and step, the skin check, the rounds (`rounds`), the plane
contacts left in the step, and the clock; `block_shot` runs a block of them for the CPU in one
thread, with the same functions in the order the per-step kernels run them."""

import functools
from types import SimpleNamespace

import warp as wp

from .air import make_dense_air
from .constants import (
    CHECKPOINT,
    FLAG_STALL,
    FLYING,
    SHOT_DONE,
    SHOT_REBUILD,
    SHOT_STALL,
    SKIN_EDGE,
    SKIN_STEPS,
)
from .events import make_events
from .frame import make_frame
from .kit import dense_kit
from .rounds import make_rounds


@functools.cache
def make_step(spec) -> SimpleNamespace:
    """The step functions of the dense phase."""
    kit = dense_kit(spec)
    scalar, vec3, Surfaces, Physics = kit.scalar, kit.vec3, kit.Surfaces, kit.Physics
    Outputs, Cloud, Pair = kit.Outputs, kit.Cloud, kit.Pair
    TINY_SPEED, QUIET_STEP, NEVER, BOUNCES, AIR = kit.TINY_SPEED, kit.QUIET_STEP, kit.NEVER, kit.BOUNCES, kit.AIR
    ballistic_velocity = kit.ballistic.velocity
    fr, ro = make_frame(spec), make_rounds(spec)
    stepping, relative_to_drift, relative_to_frame, drift_point = (
        fr.stepping,
        fr.relative_to_drift,
        fr.relative_to_frame,
        fr.drift_point,
    )
    choose_pellet, resolve_pellet, step_end_of = ro.choose_pellet, ro.resolve_pellet, ro.step_end_of
    plane_contacts_until = make_events(spec).plane_contacts_until
    air = make_dense_air(spec) if AIR else None  # (its calls compile only in air)

    @wp.func(inline=True)
    def bounds_pellet(i: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """Pellet i's speed relative to its shot's drift, into the shot's largest (a pair closes at
        most at twice it). It sets the next step; it depends on the shot alone, never on the
        neighbour lists, so the steps (and results) do not depend on when lists are rebuilt."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        _relative, relative_velocity = relative_to_drift(cloud, physics, i, s)
        # (an atomic only where it can raise the shot's value: most pellets' cannot, and skip it)
        speed = wp.length(relative_velocity)
        if speed > cloud.clock.drift[s]:
            wp.atomic_max(cloud.clock.drift, s, speed)
        if wp.static(AIR):
            rate = air.pellet_rate(i, cloud.clock.time[s], pair, surfaces, physics, cloud)
            if rate > cloud.clock.air[s]:
                wp.atomic_max(cloud.clock.air, s, rate)

    @wp.func(inline=True)
    def drift_and_edge(
        i: wp.int32,
        time: scalar,
        frame_point: vec3,
        frame_velocity: vec3,
        edge_distance: scalar,
        pair: Pair,
        surfaces: Surfaces,
        physics: Physics,
        cloud: Cloud,
    ):
        """For block_shot (its shot is stepping; the frame's point and velocity at the shot's
        clock, computed once a step): bounds_pellet's speed, without writing it, and whether the
        pellet is near the edge of its skin (beyond SKIN_EDGE of half the skin since the build):
        with the adaptive step (at most a ninth of half the skin at its speed) a pellet within it
        can neither break its list in the step nor have overrun it, and prepare_pellet has
        nothing to do for it."""
        speed = scalar(0.0)
        edge = wp.int32(0)
        rate = scalar(0.0)
        if cloud.state.phase[i] == FLYING:
            relative, relative_velocity = relative_to_frame(cloud, physics, i, time, frame_point, frame_velocity)
            speed = wp.length(relative_velocity)
            if wp.length(relative - cloud.lists.build_offset[i]) > edge_distance:
                edge = wp.int32(1)
            if wp.static(AIR):
                # (as bounds_pellet: the same bits on every schedule)
                rate = air.pellet_rate(i, time, pair, surfaces, physics, cloud)
        return speed, edge, rate

    @wp.func(inline=True)
    def plan_shot(s: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """Shot s's step, fixed or adaptive (a pair closes by at most
        step_fraction of a diameter in a step; the list lasts SKIN_STEPS steps at these speeds)."""
        cloud.shot_flags[s, SHOT_REBUILD] = 0  # (built before this block)
        for r in range(cloud.event.round_applied.shape[0]):
            cloud.event.round_applied[r] = 0  # (every shot's thread writes the same)
        if cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != 0:
            return
        step = pair.fixed_step
        if step <= scalar(0.0):
            diameter = scalar(2.0) * physics.radius
            drift = wp.max(cloud.clock.drift[s], TINY_SPEED)
            step = wp.min(pair.step_fraction * diameter / (scalar(2.0) * drift), pair.half_skin / (scalar(SKIN_STEPS) * drift))
            step = wp.min(step, QUIET_STEP)
            if wp.static(AIR):
                step = wp.min(step, pair.air_step_fraction / wp.max(cloud.clock.air[s], TINY_SPEED))
        if wp.static(AIR):
            cloud.clock.air[s] = scalar(0.0)
        cloud.clock.step[s] = step
        cloud.clock.drift[s] = scalar(0.0)
        cloud.clock.cut[s] = NEVER
        cloud.clock.skin[s] = NEVER

    @wp.func(inline=True)
    def prepare_pellet(i: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """A step that could carry a pellet beyond half the skin (relative to the drift) since the
        last build waits for a rebuild: no pair is missed. That holds for the motion known at the
        step's start; an event in the step can make a pellet faster (a plane rebound much faster
        than the step allowed for), and a pellet found beyond half the skin here overran it: the
        largest overrun is reported (stats skin_overrun_max, a warning above 1)."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        step = cloud.clock.step[s]
        relative, relative_velocity = relative_to_drift(cloud, physics, i, s)
        moved = relative - cloud.lists.build_offset[i]  # since the build
        half_skin = cloud.lists.half_skin[s]
        overrun = wp.length(moved) / half_skin
        if overrun > scalar(1.0):
            wp.atomic_max(cloud.clock.overrun, s, overrun)
        if wp.length(moved + relative_velocity * step) > half_skin:
            cloud.shot_flags[s, SHOT_STALL] = 1
            cloud.flags[FLAG_STALL] = 1
            travel = wp.length(relative_velocity) * step
            if travel > half_skin:  # one step alone outruns the skin (a fixed step): it must grow
                wp.atomic_max(cloud.lists.step_travel, s, travel)

    @wp.func(inline=True)
    def finish_pellet(i: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        """End of the step: plane contacts left in it (no pellet ends a step inside a plane). Only
        a pellet whose earliest event falls in the step can have one."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        step_end = step_end_of(cloud, s)
        if cloud.event.partner[i] != -1 and cloud.event.time[i] <= step_end:
            plane_contacts_until(i, step_end, wp.static(BOUNCES + 1), cloud, surfaces, physics, out)

    @wp.func(inline=True)
    def end_step_shot(s: wp.int32, pair: Pair, cloud: Cloud):
        """Shot s's clock moves on (unless the step waits for a rebuild); after block_steps of its
        own steps it waits at a checkpoint."""
        if cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != 0:
            return
        cloud.clock.time[s] = step_end_of(cloud, s)
        steps = cloud.clock.steps[s] + scalar(1.0)
        cloud.clock.steps[s] = steps
        if wp.int32(steps) % pair.block_steps == 0:
            cloud.shot_flags[s, SHOT_STALL] = CHECKPOINT  # wait for the horizon check and settle

    @wp.func
    def block_shot(
        s: wp.int32,
        steps: wp.int32,
        rounds: wp.int32,
        pair: Pair,
        surfaces: Surfaces,
        physics: Physics,
        cloud: Cloud,
        out: Outputs,
    ):
        """On the CPU (one thread), up to `steps` steps of shot s: each step is the per-step
        kernels' work for its pellets, in their order; it ends early when the shot waits (a
        checkpoint, or a rebuild) or is done, and mid-step once `cloud.stop` is set (an interrupt:
        the host abandons the chunk)."""
        first = s * pair.count
        last = first + pair.count
        cloud.shot_flags[s, SHOT_REBUILD] = 0  # (as plan_shot: built before this block)
        for _ in range(steps):
            if cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != 0:
                break  # (until its checkpoint, or its rebuild)
            if cloud.stop[0] != 0:
                return
            # bounds_pellet and the part of prepare_pellet that most pellets need, in one pass:
            # the full check only when some pellet is near the edge of its skin (or the step is
            # fixed: no bound on how far it carries a pellet)
            drift = scalar(0.0)
            edge = wp.int32(0)
            rate = scalar(0.0)
            time = cloud.clock.time[s]
            frame_point = drift_point(cloud, s, time, physics.gravity)
            frame_velocity = ballistic_velocity(cloud.frame.drift_velocity[s], physics.gravity, time)
            edge_distance = scalar(SKIN_EDGE) * cloud.lists.half_skin[s]
            for i in range(first, last):
                speed, near, pellet_rate = drift_and_edge(
                    i, time, frame_point, frame_velocity, edge_distance, pair, surfaces, physics, cloud
                )
                drift = wp.max(drift, speed)
                edge = wp.max(edge, near)
                rate = wp.max(rate, pellet_rate)
            wp.atomic_max(cloud.clock.drift, s, drift)
            if wp.static(AIR):
                wp.atomic_max(cloud.clock.air, s, rate)
            plan_shot(s, pair, physics, cloud)
            if edge != 0 or pair.fixed_step > scalar(0.0):
                for i in range(first, last):
                    prepare_pellet(i, pair, physics, cloud)
            if wp.static(AIR):
                for i in range(first, last):
                    air.kick_pellet(i, pair, surfaces, physics, cloud)
            # A pellet whose kept event is after the step (most are) has nothing to do in it
            # until a neighbour's event makes it stale: the per-pellet functions would return at
            # once, after reading the shot's flags and clock (step_end_of is never after the full
            # step). round_applied is this shot's alone here: a round after one in which the
            # shot applied nothing is skipped, as the per-step kernels skip one nobody applied in.
            step_end = cloud.clock.time[s] + cloud.clock.step[s]
            for r in range(rounds):
                if cloud.stop[0] != 0:
                    return
                if r == 0 or cloud.event.round_applied[r - 1] != 0:
                    for i in range(first, last):
                        if cloud.event.stale[i] != 0 or cloud.event.time[i] <= step_end:
                            choose_pellet(i, 0, pair, surfaces, physics, cloud)
                    for i in range(first, last):
                        if cloud.event.stale[i] != 0 or cloud.event.time[i] <= step_end:
                            resolve_pellet(i, r, pair, surfaces, physics, cloud, out)
            for i in range(first, last):
                if cloud.event.stale[i] != 0 or cloud.event.time[i] <= step_end:
                    choose_pellet(i, 1, pair, surfaces, physics, cloud)
            for i in range(first, last):
                if cloud.event.stale[i] != 0 or cloud.event.time[i] <= step_end:
                    finish_pellet(i, pair, surfaces, physics, cloud, out)
            end_step_shot(s, pair, cloud)

    return SimpleNamespace(
        bounds_pellet=bounds_pellet,
        drift_and_edge=drift_and_edge,
        plan_shot=plan_shot,
        prepare_pellet=prepare_pellet,
        finish_pellet=finish_pellet,
        end_step_shot=end_step_shot,
        block_shot=block_shot,
    )
