"""The rounds of a step: each pellet's earliest event is found (kept until it or a neighbour
changes), then the events in the step are applied, a plane event by its pellet and a mutual pair
event by the lower row's thread, up to the round's skin limit."""

import functools
from types import SimpleNamespace

import warp as wp

from .air import make_dense_air
from .constants import (
    FLYING,
    MIN_CUT_FRACTION,
)
from .events import make_events
from .frame import make_frame
from .kit import dense_kit
from .watch import make_dense_watch


@functools.cache
def make_rounds(spec) -> SimpleNamespace:
    """choose_pellet, step_end_of and resolve_pellet."""
    kit = dense_kit(spec)
    scalar, Surfaces, Physics, Outputs, Cloud, Pair = kit.scalar, kit.Surfaces, kit.Physics, kit.Outputs, kit.Cloud, kit.Pair
    NEVER, AIR, BOUNCES = kit.NEVER, kit.AIR, kit.BOUNCES
    ballistic_position, ballistic_velocity = kit.ballistic.position, kit.ballistic.velocity
    next_contact = kit.flight.next_contact
    ev, fr = make_events(spec), make_frame(spec)
    contact_time, plane_outcome, pair_outcome = ev.contact_time, ev.plane_outcome, ev.pair_outcome
    plane_contacts_until, mark_stale = ev.plane_contacts_until, fr.mark_stale
    stepping, skin_exit, set_reference = fr.stepping, fr.skin_exit, fr.set_reference
    air = make_dense_air(spec) if AIR else None  # (its calls compile only in air)
    watch = make_dense_watch(spec)

    @wp.func(inline=True)
    def choose_pellet(i: wp.int32, look: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """Each flying pellet's earliest event: its next plane contact, or contact with a listed
        neighbour (ties: a plane, then the lower row). It is found again only when the pellet is
        stale (it or a neighbour changed, or its list was rebuilt): a pair's time is computed
        from the later of the two reference times, as in reference.collisions, so it is one
        number whoever asks and whenever, and a kept event is the one a new search would find.
        With its event it keeps when it would leave its skin after it (as if applied: a pair as
        if both chose it), and each round the earliest of those among events in the step is the
        round's skin limit (resolve_pellet applies no event after it; the step ends there).
        `look` (after the last round): pair events still ahead in the step cut it, so no pellet
        flies past an event left unresolved (into its partner). In air a plane rebound is also a
        skin limit at its own time: the step ends there, and the next one is sized by the air
        for the motion after it (a slow rebound under a strong lift returns within microseconds). A round after one that applied
        nothing has nothing to do (no pellet is stale, every choice is the same)."""
        if cloud.event.stale[i] == 0 and cloud.event.partner[i] == -1:
            return  # nothing ahead
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        if cloud.event.stale[i] != 0:
            cloud.event.stale[i] = 0
            gravity = physics.gravity
            position = cloud.state.position[i]
            velocity = cloud.state.velocity[i]
            time = cloud.state.time[i]
            wait, k = next_contact(
                position, velocity, cloud.state.angular_velocity[i], cloud.state.touching[i], surfaces, physics
            )
            best_time = NEVER
            best = wp.int32(-1)
            if k >= 0:
                best_time = time + wait
                best = -2 - k
            reach2 = scalar(4.0) * physics.radius * physics.radius
            for n in range(cloud.lists.neighbour_count[i]):
                j = cloud.lists.neighbours[i, n]
                if cloud.state.phase[j] == FLYING:
                    other_time = cloud.state.time[j]
                    start = wp.max(time, other_time)  # both reference states hold from here
                    d = ballistic_position(
                        cloud.state.position[j], cloud.state.velocity[j], gravity, start - other_time
                    ) - ballistic_position(position, velocity, gravity, start - time)
                    vj = ballistic_velocity(cloud.state.velocity[j], gravity, start - other_time)
                    vi = ballistic_velocity(velocity, gravity, start - time)
                    delay = contact_time(d, vj - vi, reach2, wp.length(vi) + wp.length(vj))
                    if delay >= scalar(0.0):
                        when = start + delay
                        if when < best_time or (when == best_time and best >= 0 and j < best):
                            best_time = when
                            best = j
            cloud.event.time[i] = best_time
            cloud.event.partner[i] = best
            exit = NEVER
            if best <= -2 and cloud.state.impacts[i] < wp.static(BOUNCES):
                # (the contact after the last ricochet ends the flight: no skin after it, no outcome to find)
                at, _v, _w, velocity_after, _w_after, _slipped, contact, flying, impacted = plane_outcome(
                    i, k, wait, position, velocity, cloud.state.angular_velocity[i], time, cloud, surfaces, physics
                )
                if flying != 0 and impacted != 0:
                    exit = skin_exit(cloud, physics, i, s, at, velocity_after, contact)
                    if wp.static(AIR):  # a rebound ends the step: the next is sized for the motion after it
                        exit = wp.min(exit, contact)
            elif best >= 0:
                a = wp.min(i, best)
                xa, _va, _wa, xb, _vb, _wb, va2, _wa2, vb2, _wb2, _collided = pair_outcome(
                    a, wp.max(i, best), best_time, pair, physics, cloud
                )
                if i == a:
                    exit = skin_exit(cloud, physics, i, s, xa, va2, best_time)
                else:
                    exit = skin_exit(cloud, physics, i, s, xb, vb2, best_time)
            cloud.event.exit_time[i] = exit
        step_start = cloud.clock.time[s]
        step_end = step_start + cloud.clock.step[s]
        if cloud.event.time[i] <= step_end:
            # (after the last round too: finish_kernel applies the plane contacts left in the step)
            # (an atomic only where it can lower the shot's value)
            if cloud.event.exit_time[i] < cloud.clock.skin[s]:
                wp.atomic_min(cloud.clock.skin, s, cloud.event.exit_time[i])
            if look != 0 and cloud.event.partner[i] >= 0 and cloud.event.time[i] < step_end:
                cut = wp.max(cloud.event.time[i], step_start)
                if cut < cloud.clock.cut[s]:
                    wp.atomic_min(cloud.clock.cut, s, cut)

    @wp.func
    def step_end_of(cloud: Cloud, s: wp.int32):
        """Where the shot's step ends: its full step, or the earliest pair event its rounds left
        unresolved (but at least MIN_CUT_FRACTION of the step), or the earliest time a pellet
        changed in the step leaves its skin (no minimum there: no pellet outruns its list)."""
        time = cloud.clock.time[s]
        step = cloud.clock.step[s]
        cut = time + wp.max(wp.min(step, cloud.clock.cut[s] - time), step * scalar(MIN_CUT_FRACTION))
        return wp.min(cut, cloud.clock.skin[s])

    @wp.func(inline=True)
    def resolve_pellet(
        i: wp.int32, round: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs
    ):
        """Apply each pellet's event if it falls in the step: a plane event, or a pair event both
        pellets chose (mutual), applied by the lower row's thread to both. A pellet takes part in
        at most one event per round, so every state is read and written by one thread only.
        Only events up to the round's skin limit are applied (choose_pellet: the earliest time a
        pellet changed by an event of the round would leave its skin), so no pellet outruns its
        list (the skin was sized for the motion known at the step's start; a plane rebound can be
        far faster)."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        partner = cloud.event.partner[i]
        if partner == -1 or (partner >= 0 and partner < i):
            return
        step_start = cloud.clock.time[s]
        step_end = step_start + cloud.clock.step[s]
        skin_limit = cloud.clock.skin[s]
        when = cloud.event.time[i]
        if partner <= -2:
            if when <= step_end and when <= skin_limit:
                if plane_contacts_until(i, step_end, 1, cloud, surfaces, physics, out) > 0:  # the one it chose
                    cloud.event.round_applied[round] = 1
            return
        if when >= step_end or cloud.event.partner[partner] != i or cloud.state.phase[partner] != FLYING:
            return
        a = i
        b = partner
        when = wp.max(when, step_start)  # (an event the step passed after a cut at MIN_CUT_FRACTION)
        if when > skin_limit:
            return  # after a pellet changed in this round leaves its skin: the next step
        xa, va, wa, xb, vb, wb, va2, wa2, vb2, wb2, collided = pair_outcome(a, b, when, pair, physics, cloud)
        if collided != 0:
            # kinetic energy the pair lost; each pellet books half
            before = pair.mass * (wp.dot(va, va) + wp.dot(vb, vb)) + pair.inertia * (wp.dot(wa, wa) + wp.dot(wb, wb))
            after = pair.mass * (wp.dot(va2, va2) + wp.dot(vb2, vb2)) + pair.inertia * (wp.dot(wa2, wa2) + wp.dot(wb2, wb2))
            half = scalar(0.25) * (before - after)
            cloud.collisions.energy_lost[a] = cloud.collisions.energy_lost[a] + half
            cloud.collisions.energy_lost[b] = cloud.collisions.energy_lost[b] + half
            cloud.collisions.count[a] = cloud.collisions.count[a] + 1
            cloud.collisions.count[b] = cloud.collisions.count[b] + 1
            cloud.collisions.last_time[a] = when
            cloud.collisions.last_time[b] = when
            cloud.state.touching[a] = -1  # they may have left the plane: plane times from the actual gap
            cloud.state.touching[b] = -1
        # (a pair the law does not collide, grazing within rounding, moves its reference states to
        # `when` too: found again from there, it is no longer closing, and the clock moves on)
        watch.to(cloud, surfaces, physics, a, xa, when)  # (the hazard along their paths to the contact)
        watch.to(cloud, surfaces, physics, b, xb, when)
        set_reference(cloud, a, xa, va2, wa2, when)
        set_reference(cloud, b, xb, vb2, wb2, when)
        if wp.static(AIR):  # (pair_outcome gave them the air up to the contact)
            air.air_until(cloud, a, when)
            air.air_until(cloud, b, when)
        cloud.event.round_applied[round] = 1
        mark_stale(cloud, a)
        mark_stale(cloud, b)

    return SimpleNamespace(choose_pellet=choose_pellet, step_end_of=step_end_of, resolve_pellet=resolve_pellet)
