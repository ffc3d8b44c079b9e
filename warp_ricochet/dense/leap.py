"""Leaps in air: at a checkpoint past its arrival window, a shot moves its clock to just before the
earliest time at which anything could happen to it, and each of its pellets flies there by the
core's integrated flight (`physics.air_flight`, with error control), landing on the way where its
flight ends. In vacuum the shot jumps its clock and nothing else (`checkpoint.settle_shot`); in
air the pellets slow down and turn in the time skipped, so they are flown through it.

What a leap may not skip is found over all pairs and planes of the shot (`horizon_pellet`), from
each pellet's state at the checkpoint (`now_pellet`: its reference state, with the air up to the
checkpoint) and a bound A on its air acceleration in the leap: `acceleration_bound` at its speed
relative to the air plus |g| LEAP_MAX (no leap is longer). The air moves a pellet off the exact
ballistic path from that state by at most A t^2 / 2 in a time t, so
- a pair (A = A_i + A_j) cannot touch while its ballistic distance less A t^2 / 2 stays above 2R:
  |d + u t| >= |d| + (d.u / |d|) t (the distance is convex in t); closing, also its
  straight line's closest approach, or the time it comes within 2R + M (M: the shot's half skin),
  up to sqrt(2 M / A), whichever is latest (`pair_leap`);
- a pellet that may rebound (fewer than `bounces` impacts) cannot meet a plane while its gap under
  gravity and A towards the plane stays positive (`plane_leap`: physics.ballistic's entry time),
  nor a mesh or a post while it cannot close its clearance to it (`geometry.clearance`) less R at
  its whole speed under |g| + A;
- a pellet after its last impact may land in the leap: its flight ends there, as in a step.
No impact can fall inside a leap by these bounds; one found there anyway (rounding) is applied as
in a step (`events.plane_contact`). They rest on the drag growing with speed (every drag law of
`physics.air`, tested) and on the lift's cap C_L <= lift_max. A flight the integrator gives up on
in a leap (MAX_FLIGHT_STEPS) leaves that pellet where the leap began, to be stepped on from there.
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.geometry import MESHES
from .air import make_dense_air
from .constants import (
    FLYING,
    FRAME_RECENTRE,
    SHOT_FRAME,
    SHOT_LEAP,
    TINY_ACCELERATION_VALUE,
)
from .events import make_events
from .frame import make_frame
from .kit import dense_kit
from .watch import make_dense_watch


@functools.cache
def make_leap(spec) -> SimpleNamespace:
    """pair_leap, plane_leap, leap_pellet and leaped_shot, for a spec in air."""
    kit = dense_kit(spec)
    scalar, vec3, Surfaces, Physics = kit.scalar, kit.vec3, kit.Surfaces, kit.Physics
    Outputs, Cloud, Pair = kit.Outputs, kit.Cloud, kit.Pair
    NEVER, CLOSING_TOLERANCE2, BOUNCES = kit.NEVER, kit.CLOSING_TOLERANCE2, kit.BOUNCES
    TINY_ACCELERATION = scalar(TINY_ACCELERATION_VALUE)
    SOLIDS = kit.PLATES >= MESHES  # meshes and posts (physics.geometry)
    entry_time, geo, STATIC_PLANES, PLATES = kit.ballistic.entry_time, kit.geo, kit.STATIC_PLANES, kit.PLATES
    flight_within = make_dense_watch(spec).flight_within  # (the integrated flight, its path watched)
    watch_to = make_dense_watch(spec).to
    air, ev, fr = make_dense_air(spec), make_events(spec), make_frame(spec)
    contact_time, plane_contact = ev.contact_time, ev.plane_contact
    set_reference = fr.set_reference

    @wp.func
    def pair_leap(d: vec3, u: vec3, reach: scalar, margin: scalar, bound: scalar, speeds: scalar):
        """How long (s) a pair at offset d with relative velocity u (a straight line, gravity
        cancels) cannot come within `reach` when the air may move each off its line by up to
        bound t^2 / 4 (`bound`: the sum of their bounds, m/s^2); `speeds`: |v_a| + |v_b|."""
        dd = wp.dot(d, d)
        distance = wp.sqrt(dd)
        gap = distance - reach
        if gap <= scalar(0.0):
            return scalar(0.0)
        a = wp.max(bound, TINY_ACCELERATION)
        du = wp.dot(d, u)
        closing = du < scalar(0.0) and du * du > CLOSING_TOLERANCE2 * dd * speeds * speeds  # (not within rounding)
        rate = scalar(0.0)
        if closing:
            rate = du / distance
        # the distance is convex in t: gap + rate t - a t^2 / 2 > 0 up to its positive root
        root = wp.sqrt(rate * rate + scalar(2.0) * a * gap)
        delay = (rate + root) / a
        if not closing:
            return delay
        delay = scalar(2.0) * gap / (root - rate)  # (the same root without cancellation)
        # or the straight line's closest approach, less a t^2 / 2
        closest = wp.sqrt(wp.max(dd - du * du / wp.dot(u, u), scalar(0.0))) - reach
        delay = wp.max(delay, wp.sqrt(scalar(2.0) * wp.max(closest, scalar(0.0)) / a))
        # or until the line comes within reach + margin, up to a t^2 / 2 = margin
        wide = reach + margin
        enter = contact_time(d, u, wide * wide, speeds)
        if enter >= scalar(0.0):
            delay = wp.max(delay, wp.min(enter, wp.sqrt(scalar(2.0) * margin / a)))
        return delay

    @wp.func
    def plane_gap_leap(k: wp.int32, position: vec3, velocity: vec3, bound: scalar, surfaces: Surfaces, physics: Physics):
        """How long (s) the pellet cannot meet plane k with up to `bound` (m/s^2) of air towards it.
        A plate is met no sooner than its plane; one behind a one-sided plate may pass beside it
        to its front and come back onto it, no sooner than its centre rises R in front of it. A
        mesh or a post no sooner than the pellet closes its clearance less R at its whole speed,
        under |g| and `bound` towards it."""
        if wp.static(SOLIDS):
            if geo.is_solid(surfaces, k):
                gap = wp.max(geo.clearance(surfaces, k, position) - physics.radius, scalar(0.0))
                pull = scalar(-0.5) * (wp.length(physics.gravity) + bound)
                delay = entry_time(gap, -wp.length(velocity), pull)
                if delay < scalar(0.0):
                    return NEVER
                return delay
        height, _noise, n = geo.locate(surfaces, k, position)
        if wp.static(PLATES):
            if height < scalar(0.0) and geo.is_plate(surfaces, k):
                rise = physics.radius - height  # (its centre's way to R in front, against n)
                ahead = entry_time(rise, -wp.dot(velocity, n), scalar(-0.5) * (wp.dot(physics.gravity, n) + bound))
                if ahead < scalar(0.0):
                    return NEVER
                return ahead
        if height < scalar(0.0):
            return NEVER  # planes are one-sided: never met from behind
        gap = wp.max(height - physics.radius, scalar(0.0))
        delay = entry_time(gap, wp.dot(velocity, n), scalar(0.5) * (wp.dot(physics.gravity, n) - bound))
        if delay < scalar(0.0):
            return NEVER
        return delay

    @wp.func
    def plane_leap(position: vec3, velocity: vec3, bound: scalar, surfaces: Surfaces, physics: Physics):
        """How long (s) the pellet cannot meet any plane (`plane_gap_leap`, every plane)."""
        delay = NEVER
        if wp.static(STATIC_PLANES is None):
            for k in range(geo.count(surfaces)):
                delay = wp.min(delay, plane_gap_leap(k, position, velocity, bound, surfaces, physics))
        else:
            for k in range(wp.static(STATIC_PLANES)):  # unrolled
                delay = wp.min(delay, plane_gap_leap(k, position, velocity, bound, surfaces, physics))
        return delay

    @wp.func
    def leap_pellet(i: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        """Pellet i of a leaping shot flies from the leap's start to its end (the shot's clock) by
        the integrated flight, its contacts on the way applied as in a step; its reference state
        and air time move to where it is then."""
        s = i / pair.count
        if cloud.state.phase[i] != FLYING or cloud.shot_flags[s, SHOT_LEAP] == 0:
            return
        start = cloud.clock.leap[s]
        end = cloud.clock.time[s]
        position, velocity, spin = air.drift_end(cloud, i, start, start, physics)
        watch_to(cloud, surfaces, physics, i, position, start)  # (the hazard along its drift)
        set_reference(cloud, i, position, velocity, spin, start)
        air.air_until(cloud, i, start)
        cloud.state.touching[i] = -1  # (off any plane it left: plane times from the gap)
        time = start
        touching = wp.int32(-1)
        flying = wp.int32(1)
        for _ in range(wp.static(BOUNCES + 1)):
            if flying != 0 and time < end:
                wait, k, _normal, x, v, w, _steps = flight_within(
                    cloud, i, position, velocity, spin, touching, surfaces, physics, end - time
                )
                if k >= 0:
                    time = time + wait
                    air.air_until(cloud, i, time)
                    position, velocity, spin, time, flying = plane_contact(
                        i, k, scalar(0.0), x, v, w, time, cloud, surfaces, physics, out
                    )
                    touching = k
                elif k == -1:
                    position = x
                    velocity = v
                    spin = w
                    time = end
                else:
                    flying = wp.int32(0)  # given up: it stays at the leap's start (set above), stepped on from there
        if cloud.state.phase[i] == FLYING and time > start:
            set_reference(cloud, i, position, velocity, spin, time)
            air.air_until(cloud, i, time)
            cloud.state.touching[i] = -1
        cloud.event.stale[i] = 1

    @wp.func
    def leaped_shot(s: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """After its pellets leapt: the shot's frame follows them, and its lists are rebuilt."""
        if cloud.shot_flags[s, SHOT_LEAP] == 0:
            return
        cloud.shot_flags[s, SHOT_LEAP] = 0
        cloud.shot_flags[s, SHOT_FRAME] = FRAME_RECENTRE  # (dense.frame: framed_shot)

    return SimpleNamespace(pair_leap=pair_leap, plane_leap=plane_leap, leap_pellet=leap_pellet, leaped_shot=leaped_shot)
