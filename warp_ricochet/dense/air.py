"""The air in the dense phase, by Strang splitting: between kicks every pellet flies the exact
parabola (so pair and plane contact times stay exact), and the air's own flow (drag, lift and
spin decay, no gravity: `physics.air`) acts in kicks, half an interval's worth at each end
(K(H/2) D(H) K(H/2): second order in H). Each pellet keeps the time up to which it has had the air
(`Cloud.air.time`) and the step of its shot at which its next kick is due (`Cloud.air.kick_due`). A
kick (`kick_pellet`, at a step's start) gives it the air up to the middle of its next interval:
up to the shot's next multiple of KICK_STEPS steps (so a shot's pellets are kicked together, in
the same steps), sooner where `air_step_fraction` of its own air rate, its next plane contact or
its kept pair event asks (`kick_steps`). The drift that a kick ends had the air only up to the
previous kick's predicted middle: its end (`drift_end`) adds the air it missed to the position,
so a drift of any length is second order at its end. Between kicks a pellet keeps its cached
event. An event (a plane or a pair contact, which changes its velocity) first gives it the air up
to the event's time and makes its next step kick it (`air_until`); the release gives the rest
(or takes back what it had beyond the release). An event inside an interval costs a local error
of order |a| H^2 (a few a pellet; H is at most KICK_STEPS skin-sized steps). A pellet leaving a
plane with little normal speed under a strong lift returns within a fraction of a millisecond:
the plane share of its rate keeps its interval short.

The adaptive step is at most `collisions.air_step_fraction` of the shortest time the air takes to
change a pellet's motion in its shot (|u| / |a_air|), or its motion towards a plane within a step's
reach (|v.n| / |a_air.n|: `air_rate`; `pellet_rate` finds it anew for a pellet due a kick, and keeps
it otherwise); a fixed step is kept as given, and every pellet is kicked every step (to measure
convergence). Past its arrival window a shot leaps instead of stepping through empty time
(`dense.leap`).
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.air import make_air_laws
from ..physics.geometry import MESHES
from .constants import KICK_STEPS
from .frame import make_frame
from .kit import dense_kit
from .watch import make_dense_watch


@functools.cache
def make_dense_air(spec) -> SimpleNamespace:
    """`air_rate`, `acceleration_bound`, `kicked`, `drift_end`, `kick_pellet` and `air_until` for a
    spec in air."""
    kit = dense_kit(spec)
    scalar, vec3, Surfaces, Physics, Cloud, Pair = kit.scalar, kit.vec3, kit.Surfaces, kit.Physics, kit.Cloud, kit.Pair
    ballistic_position, ballistic_velocity = kit.ballistic.position, kit.ballistic.velocity
    next_contact, geo, STATIC_PLANES = kit.flight.next_contact, kit.geo, kit.STATIC_PLANES  # (the exact flight)
    TINY_RATE = 1e-30  # 1/s: no air (a pellet at rest in still air)
    laws = make_air_laws(kit.precision, *spec.air_laws)
    fr = make_frame(spec)
    stepping, set_reference = fr.stepping, fr.set_reference
    LIFT = spec.air_laws[1] is not None
    watch = make_dense_watch(spec)
    SOLIDS = spec.plates >= MESHES  # meshes and posts (physics.geometry)

    @wp.func
    def plane_rate(
        k: wp.int32, position: vec3, velocity: vec3, acceleration: vec3, reach_time: scalar, surfaces: Surfaces, physics: Physics
    ):
        """Plane k's share of air_rate: |a_air.n| / (|v.n| + speed floor) if the pellet can reach
        the plane within `reach_time` (s), else 0. Planes are one-sided: none behind the centre.
        A mesh or a post: its clearance from the centre and its normal at the nearest point."""
        height, _noise, n = geo.locate(surfaces, k, position)
        if wp.static(SOLIDS):
            if geo.is_solid(surfaces, k):
                height = geo.clearance(surfaces, k, position)
                n = geo.normal(surfaces, k, position)
        if height < scalar(0.0):
            return scalar(0.0)
        speed = wp.length(velocity) + physics.air.speed_floor
        reach = (
            speed * reach_time + scalar(0.5) * (wp.length(physics.gravity) + wp.length(acceleration)) * reach_time * reach_time
        )
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
            for k in range(geo.count(surfaces)):
                rate = wp.max(rate, plane_rate(k, position, velocity, acceleration, reach_time, surfaces, physics))
        else:
            for k in range(wp.static(STATIC_PLANES)):  # unrolled
                rate = wp.max(rate, plane_rate(k, position, velocity, acceleration, reach_time, surfaces, physics))
        return rate

    @wp.func
    def pellet_rate(i: wp.int32, time: scalar, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """Pellet i's `air_rate` at the shot's clock `time` (s), for the step's bound: found
        anew in a step that kicks it (kept for its kick), else the one found at its last kick
        (its motion has changed by at most air_step_fraction since)."""
        if wp.int32(cloud.clock.steps[i / pair.count]) >= cloud.air.kick_due[i]:
            age = time - cloud.state.time[i]
            cloud.air.rate[i] = air_rate(
                ballistic_position(cloud.state.position[i], cloud.state.velocity[i], physics.gravity, age),
                ballistic_velocity(cloud.state.velocity[i], physics.gravity, age),
                cloud.state.angular_velocity[i],
                pair,
                surfaces,
                physics,
            )
        return cloud.air.rate[i]

    @wp.func
    def acceleration_bound(speed: scalar, physics: Physics):
        """The most the air can accelerate a pellet (m/s^2; drag and lift, not gravity) moving at
        up to `speed` (m/s) relative to the air, whatever its spin: the drag at that speed (the
        drag force grows with speed, as every law of physics.air does: tested) and the lift at
        its cap C_L = lift_max, lift R (C_L / S) |omega x u| <= lift lift_max |u|^2 / R."""
        bound = wp.length(laws.drag_acceleration(vec3(speed, scalar(0.0), scalar(0.0)), speed, physics.air))
        if wp.static(LIFT):
            bound += physics.air.lift * physics.air.lift_max * speed * speed / physics.air.radius
        return bound

    @wp.func
    def kicked_from(velocity: vec3, spin: vec3, a1: vec3, d1: vec3, duration: scalar, physics: Physics):
        """`kicked`, given the air's rates at its start (a1, d1)."""
        half = scalar(0.5) * duration
        a2, d2 = laws.air_rates(velocity + half * a1, spin + half * d1, physics.air)
        return velocity + duration * a2, spin + duration * d2

    @wp.func
    def kicked(velocity: vec3, spin: vec3, duration: scalar, physics: Physics):
        """Velocity and spin after the air's flow alone over `duration` (s): the explicit midpoint
        rule, second order like the splitting (a kick is at most a small fraction of the time the
        air takes to change the motion)."""
        a1, d1 = laws.air_rates(velocity, spin, physics.air)
        return kicked_from(velocity, spin, a1, d1, duration, physics)

    @wp.func
    def two_sum(a: vec3, b: vec3):
        """a + b rounded, and its rounding error exactly (Knuth's TwoSum, TAOCP vol. 2, 4.2.2)."""
        total = a + b
        b_part = total - a
        return total, (a - (total - b_part)) + (b - b_part)

    @wp.func
    def drifted(cloud: Cloud, i: wp.int32, time: scalar, until: scalar, physics: Physics):
        """`drift_end`'s state, and the rounding its position lost (m): the displacement is added
        to the reference position with the error the last kick kept (`Cloud.air.position_error`),
        compensated (Kahan summation), so the thousands of kicks of a flight do not accumulate
        rounding in the position (in float32, ulp(10 m) = 1e-6 m a kick: a random walk that a
        grazing landing turns into millimetres)."""
        age = time - cloud.state.time[i]
        velocity = ballistic_velocity(cloud.state.velocity[i], physics.gravity, age)
        spin = cloud.state.angular_velocity[i]
        acceleration, spin_change = laws.air_rates(velocity, spin, physics.air)
        lag = scalar(0.5) * (cloud.state.time[i] + time) - cloud.air.time[i]
        moved = cloud.state.velocity[i] * age + (scalar(0.5) * age * age) * physics.gravity + (lag * age) * acceleration
        position, error = two_sum(cloud.state.position[i], moved + cloud.air.position_error[i])
        velocity, spin = kicked_from(velocity, spin, acceleration, spin_change, until - cloud.air.time[i], physics)
        return position, velocity, spin, error

    @wp.func
    def drift_end(cloud: Cloud, i: wp.int32, time: scalar, until: scalar, physics: Physics):
        """Pellet i's state at `time` (s), the end of a drift from its reference state, with the
        air up to `until` (s): the exact flight from it, in position the air the drift missed
        (its velocity had the air up to the air time, not up to the drift's middle: a (t_mid -
        t_air) (t - t_ref), which makes a drift of any length second order at its end), and in
        velocity and spin one kick from the air time to `until`."""
        position, velocity, spin, _error = drifted(cloud, i, time, until, physics)
        return position, velocity, spin

    @wp.func
    def kick_steps(
        i: wp.int32,
        time: scalar,
        position: vec3,
        velocity: vec3,
        spin: vec3,
        pair: Pair,
        surfaces: Surfaces,
        physics: Physics,
        cloud: Cloud,
    ):
        """How many of its shot's steps pellet i's kick lasts: to the next multiple of KICK_STEPS
        of the shot's steps (so a shot's pellets are kicked together, in the same steps), but
        no longer than `air_step_fraction` of the time the air takes to change its motion
        (`air_rate`) or gravity its speed relative to the air (|u| / |g|), nor than to its next
        plane contact or its kept pair event (an event then falls at the kick's end), and at
        least one step (every step with a fixed step, as given: to measure convergence)."""
        if pair.fixed_step > scalar(0.0):
            return wp.int32(1)
        s = i / pair.count
        steps = wp.int32(cloud.clock.steps[s])
        aligned = (steps / KICK_STEPS + 1) * KICK_STEPS - steps
        rate = cloud.air.rate[i]  # (pellet_rate's, found in this step: the pellet is due)
        falling = wp.length(physics.gravity) / (wp.length(velocity - physics.air.wind) + physics.air.speed_floor)
        interval = pair.air_step_fraction / wp.max(wp.max(rate, falling), scalar(TINY_RATE))
        wait, k = next_contact(position, velocity, spin, wp.int32(-1), surfaces, physics)
        if k >= 0:
            interval = wp.min(interval, wait)
        if cloud.event.stale[i] == 0 and cloud.event.partner[i] >= 0:
            interval = wp.min(interval, cloud.event.time[i] - time)
        within = interval / cloud.clock.step[s]
        if within >= scalar(aligned):
            return aligned
        return wp.max(wp.int32(within), wp.int32(1))

    @wp.func
    def kick_pellet(i: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """At a step's start, pellet i's kick if it is due: its drift ends (`drift_end`), and it
        gets the air up to the middle of its next kick (`kick_steps` of the current step: the
        next drift's end corrects for steps of other lengths), at the shot's clock, where its
        reference state moves to. Between kicks it flies the exact parabola and keeps its
        event."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        steps = wp.int32(cloud.clock.steps[s])
        if steps < cloud.air.kick_due[i]:
            return
        time = cloud.clock.time[s]
        age = time - cloud.state.time[i]
        count = kick_steps(
            i,
            time,
            ballistic_position(cloud.state.position[i], cloud.state.velocity[i], physics.gravity, age),
            ballistic_velocity(cloud.state.velocity[i], physics.gravity, age),
            cloud.state.angular_velocity[i],
            pair,
            surfaces,
            physics,
            cloud,
        )
        middle = time + scalar(0.5) * scalar(count) * cloud.clock.step[s]
        position, velocity, spin, error = drifted(cloud, i, time, middle, physics)
        watch.to(cloud, surfaces, physics, i, position, time)  # (the hazard along its drift)
        cloud.air.time[i] = middle
        cloud.air.kick_due[i] = steps + count
        set_reference(cloud, i, position, velocity, spin, time)
        cloud.air.position_error[i] = error
        cloud.state.touching[i] = -1  # (its reference state is off the plane it left: plane times from the gap)
        cloud.event.stale[i] = 1

    @wp.func
    def air_until(cloud: Cloud, i: wp.int32, time: scalar):
        """Pellet i has had the air up to `time` (s: an event's, its release's): its next step
        kicks it; its new reference position keeps no rounding error (below an ulp)."""
        cloud.air.time[i] = time
        cloud.air.kick_due[i] = 0
        cloud.air.position_error[i] = vec3()

    return SimpleNamespace(
        air_rate=air_rate,
        pellet_rate=pellet_rate,
        acceleration_bound=acceleration_bound,
        kicked=kicked,
        drift_end=drift_end,
        kick_pellet=kick_pellet,
        air_until=air_until,
    )
