"""A pellet's events in the dense phase: a plane contact (an impact, eqs. 1-25, or the end of its
flight, by the rules of `physics.contact`), and a pair contact (the pair law of `physics.pair`)
at the exact time two reference states meet.

A scene with the ground's laws (`spec.ground`: rough ground, a critical angle, water) applies them
at the dense phase's impacts as the core does at its own (`core.pellet`): the draw keyed by (seed,
global pellet index, impact), entry into the ground (the flight ends, phase ENTERED) and the skip
off water (`physics.ground`)."""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.contact import make_contact
from ..physics.ground_contact import make_ground_contact
from ..physics.pair import make_pair_law
from .air import make_dense_air
from .constants import ENDED, ENTERED
from .frame import make_frame
from .kit import dense_kit
from .watch import make_dense_watch


@functools.cache
def make_events(spec) -> SimpleNamespace:
    """The event functions of the dense phase."""
    kit = dense_kit(spec)
    scalar, vec3, Surfaces, Physics = kit.scalar, kit.vec3, kit.Surfaces, kit.Physics
    Outputs, Cloud, Pair = kit.Outputs, kit.Cloud, kit.Pair
    CLOSING_TOLERANCE2, BOUNCES, WRITE, AIR = kit.CLOSING_TOLERANCE2, kit.BOUNCES, kit.WRITE, kit.AIR
    ballistic_position, ballistic_velocity = kit.ballistic.position, kit.ballistic.velocity
    # within a step: the exact ballistic flight
    next_contact, advance, geo = kit.flight.next_contact, kit.flight.advance, kit.geo
    rests, stays, _impact, meet_surface, contact_point, _range = make_contact(kit.precision, kit.PLATES)
    ground_contact, GROUND = make_ground_contact(kit.precision, kit.GROUND), kit.GROUND
    pair_law, write_impact = make_pair_law(kit.precision), kit.outputs.write_impact
    fr = make_frame(spec)
    set_reference, mark_stale = fr.set_reference, fr.mark_stale
    air = make_dense_air(spec) if AIR else None  # (its calls compile only in air)
    watch = make_dense_watch(spec)

    @wp.func
    def meet_ground(
        i: wp.int32,
        k: wp.int32,
        position: vec3,
        velocity: vec3,
        spin: vec3,
        normal: vec3,
        cloud: Cloud,
        surfaces: Surfaces,
        physics: Physics,
    ):
        """`physics.contact.meet_surface` with the ground's laws (module docstring), on surface k
        of unit `normal` there: (velocity', spin', slipped, impacted: 1 an impact, 0 none, ENTERED
        the pellet entered the ground, flies_on)."""
        if rests(velocity, normal):
            return velocity, spin, wp.int32(0), wp.int32(0), wp.int32(0)
        pellet, impacts = cloud.keys[1] + i, cloud.state.impacts[i]
        material, tilted, enters = ground_contact.drawn(
            geo.material(surfaces, k, position), normal, velocity, cloud.keys[0], pellet, impacts
        )
        if enters != 0:
            return velocity, spin, wp.int32(0), wp.int32(ENTERED), wp.int32(0)
        velocity_after, spin_after, slipped = ground_contact.rebound(material, tilted, velocity, spin, physics)
        flies_on = wp.int32(1)
        if stays(velocity_after, normal, wp.dot(velocity, velocity)):
            flies_on = wp.int32(0)
        return velocity_after, spin_after, slipped, wp.int32(1), flies_on

    @wp.func
    def plane_outcome(
        i: wp.int32,
        k: wp.int32,
        wait: scalar,
        position: vec3,
        velocity: vec3,
        spin: vec3,
        time: scalar,
        cloud: Cloud,
        surfaces: Surfaces,
        physics: Physics,
    ):
        """What plane_contact does to pellet i, without doing it: its position, velocity and spin
        before and after, slipped, the contact time, whether it flies on, whether it is an impact
        (1; 0 the end of its flight; ENTERED it entered the ground). The contact's normal is the
        core's (`geometry.contact_normal`: on a mesh the face met, on a post its side or a cap)."""
        position, velocity, spin = advance(position, velocity, spin, wait, physics)
        time = time + wait
        if wp.static(AIR):  # the air up to the contact (dense.air)
            velocity, spin = air.kicked(velocity, spin, time - cloud.air.time[i], physics)
        normal = geo.contact_normal(surfaces, k, position, velocity, physics.radius)
        flying = wp.int32(1)
        impacted = wp.int32(0)
        velocity_after = velocity
        spin_after = spin
        slipped = wp.int32(0)
        if cloud.state.impacts[i] >= wp.static(BOUNCES):
            flying = wp.int32(0)  # the landing after the last ricochet
        elif wp.static(GROUND):
            velocity_after, spin_after, slipped, impacted, flying = meet_ground(
                i, k, position, velocity, spin, normal, cloud, surfaces, physics
            )
        else:  # an impact, or no closing speed: it stays on the surface (physics.contact)
            velocity_after, spin_after, slipped, impacted, flying = meet_surface(
                k, position, velocity, spin, normal, surfaces, physics
            )
        return position, velocity, spin, velocity_after, spin_after, slipped, time, flying, impacted

    @wp.func
    def plane_contact(
        i: wp.int32,
        k: wp.int32,
        wait: scalar,
        position: vec3,
        velocity: vec3,
        spin: vec3,
        time: scalar,
        cloud: Cloud,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
    ):
        """Pellet i (reference state at `time`) meets plane k `wait` later: an impact (eqs. 1-25,
        exactly as the core kernel), or the end of its flight (its contact after `bounces`
        ricochets, or no closing speed). Returns the new reference state and whether it flies on."""
        radius = physics.radius
        x0 = position  # (copies, each its own line: tests/test_warp_rules.py)
        v0 = velocity
        w0 = spin
        t0 = time
        position, velocity, spin, velocity_after, spin_after, slipped, time, flying, impacted = plane_outcome(
            i, k, wait, position, velocity, spin, time, cloud, surfaces, physics
        )
        watch.arc(cloud, physics, i, x0, v0, w0, t0, position, time)  # (the hazard along its path to the contact)
        if wp.static(AIR):
            air.air_until(cloud, i, time)
        normal = geo.contact_normal(surfaces, k, position, velocity, radius)  # (as in plane_outcome)
        impacts = cloud.state.impacts[i]
        if impacted == 1:
            if wp.static(WRITE):
                write_impact(out, i, impacts, time, position, velocity, spin, velocity_after, spin_after, slipped, k)
            if impacts == 0:
                cloud.state.first_surface[i] = k
                cloud.state.first_slipped[i] = slipped
                cloud.state.first_velocity_before[i] = velocity
                cloud.state.first_angular_velocity_before[i] = spin
                cloud.state.first_velocity_after[i] = velocity_after
                cloud.state.first_angular_velocity_after[i] = spin_after
                cloud.state.first_normal[i] = normal
            cloud.state.impacts[i] = impacts + 1
            cloud.state.last_slipped[i] = slipped
            cloud.state.ricochet_point[i] = contact_point(position, radius, normal)
            cloud.state.ricochet_time[i] = time
            cloud.state.touching[i] = k
            velocity = velocity_after
            spin = spin_after
        if flying == 0:
            cloud.state.phase[i] = ENDED
            if impacted == ENTERED:
                cloud.state.phase[i] = ENTERED
            cloud.state.end_surface[i] = k
            set_reference(cloud, i, position, velocity, spin, time)
        return position, velocity, spin, time, flying

    @wp.func
    def contact_time(d: vec3, u: vec3, reach2: scalar, speeds: scalar):
        """First s >= 0 with |d + u s|^2 = reach2 while closing; 0 when within it and closing; -1 none.
        `speeds` = |v_a| + |v_b|: a closing speed within rounding of it is none (after an E = 0
        collision the normal relative velocity is rounding residue, as reference.collisions does)."""
        du = wp.dot(d, u)
        if du >= scalar(0.0) or du * du <= CLOSING_TOLERANCE2 * wp.dot(d, d) * speeds * speeds:
            return scalar(-1.0)
        dd = wp.dot(d, d)
        gap = dd - reach2
        if gap <= scalar(0.0):
            return scalar(0.0)
        disc = du * du - wp.dot(u, u) * gap
        if disc < scalar(0.0):
            return scalar(-1.0)
        return gap / (-du + wp.sqrt(disc))  # the smaller root, without cancellation

    @wp.func
    def plane_contacts_until(
        i: wp.int32, step_end: scalar, most: wp.int32, cloud: Cloud, surfaces: Surfaces, physics: Physics, out: Outputs
    ):
        """Pellet i's plane contacts up to `step_end` (at most `most`), applied to its reference
        state; it is marked stale if it had one. Returns how many it had."""
        position = cloud.state.position[i]
        velocity = cloud.state.velocity[i]
        spin = cloud.state.angular_velocity[i]
        time = cloud.state.time[i]
        flying = wp.int32(1)
        contacts = wp.int32(0)
        for _ in range(wp.static(BOUNCES + 1)):
            if flying != 0 and contacts < most:
                wait, k = next_contact(position, velocity, spin, cloud.state.touching[i], surfaces, physics)
                if k >= 0 and time + wait <= step_end:
                    position, velocity, spin, time, flying = plane_contact(
                        i, k, wait, position, velocity, spin, time, cloud, surfaces, physics, out
                    )
                    contacts += 1
        if contacts > 0:
            if flying != 0:
                set_reference(cloud, i, position, velocity, spin, time)
            mark_stale(cloud, i)
        return contacts

    @wp.func
    def pair_outcome(a: wp.int32, b: wp.int32, when: scalar, pair: Pair, physics: Physics, cloud: Cloud):
        """The pair law for pellets a < b meeting at `when`, not applied: their states then and
        their velocities and spins after."""
        gravity = physics.gravity
        # TC model: a pellet hit again within the contact duration rebounds elastically
        restitution = pair.restitution
        last_a = cloud.collisions.last_time[a]
        last_b = cloud.collisions.last_time[b]
        if (not wp.isnan(last_a) and when - last_a <= pair.contact_duration) or (
            not wp.isnan(last_b) and when - last_b <= pair.contact_duration
        ):  # (<=, as reference.collisions)
            restitution = scalar(1.0)
        age_a = when - cloud.state.time[a]
        age_b = when - cloud.state.time[b]
        xa = ballistic_position(cloud.state.position[a], cloud.state.velocity[a], gravity, age_a)
        va = ballistic_velocity(cloud.state.velocity[a], gravity, age_a)
        wa = cloud.state.angular_velocity[a]
        xb = ballistic_position(cloud.state.position[b], cloud.state.velocity[b], gravity, age_b)
        vb = ballistic_velocity(cloud.state.velocity[b], gravity, age_b)
        wb = cloud.state.angular_velocity[b]
        if wp.static(AIR):  # the air up to the contact (dense.air)
            va, wa = air.kicked(va, wa, when - cloud.air.time[a], physics)
            vb, wb = air.kicked(vb, wb, when - cloud.air.time[b], physics)
        va2, wa2, vb2, wb2, collided, _slipped = pair_law(
            xa,
            va,
            wa,
            physics.radius,
            pair.mass,
            xb,
            vb,
            wb,
            physics.radius,
            pair.mass,
            physics.inertia_factor,
            restitution,
            pair.mu_s,
            pair.mu_d,
        )
        return xa, va, wa, xb, vb, wb, va2, wa2, vb2, wb2, collided

    return SimpleNamespace(
        plane_outcome=plane_outcome,
        plane_contact=plane_contact,
        contact_time=contact_time,
        plane_contacts_until=plane_contacts_until,
        pair_outcome=pair_outcome,
    )
