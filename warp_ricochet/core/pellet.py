"""One pellet through the core, as `@wp.func`s over its `Flight` state: its start (a launch, or the
dense phase's release), each bounce (flight to the next surface, then an impact or the end of its
flight, `physics.contact`), and its landing (eq. 42). Every pellet goes through the same functions
whether it is written out or only counted (`tallies.accumulate`).
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..launch.source import make_source
from ..physics.contact import make_contact
from ..physics.flight import make_flight
from ..physics.types import types_for
from ..tallies.accumulate import make_accumulators
from .outputs import make_outputs
from .release import make_release

FLYING, ESCAPED, RESTING = 0, 1, 2  # RESTING: met a surface without closing speed, it stays there


@functools.cache
def make_flight_state(precision: str):
    """The `Flight` struct: a pellet's state between the stages of the core."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.struct
    class Flight:
        position: vec3  # m
        velocity: vec3  # m/s
        spin: vec3  # rad/s
        time: scalar  # s since launch
        touching: wp.int32  # the plane it is leaving, -1 none
        impacts: wp.int32
        state: wp.int32  # FLYING, ESCAPED (never meets a surface again), RESTING
        resting_surface: wp.int32
        last_slipped: wp.int32
        ricochet_point: vec3  # m, the contact point of its last ricochet
        ricochet_time: scalar  # s

    return Flight


@functools.cache
def make_start(spec) -> SimpleNamespace:
    """`launch_pellet` (from the launch state) and `resume_pellet` (from the dense phase's release)."""
    t = types_for(spec.precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    Flight = make_flight_state(spec.precision)
    src, out, acc = make_source(spec.precision, spec.from_file), make_outputs(spec.precision), make_accumulators(spec.precision)
    Source, Outputs, Release = src.Source, out.Outputs, make_release(spec.precision)
    launch_state, write_initial, add_first_impact = src.launch_state, out.write_initial, acc.add_first_impact
    floats_t, WRITE = acc.floats_t, bool(spec.core_fields)

    @wp.func
    def launch_pellet(source: Source, index: wp.int32, row: wp.int32, out: Outputs):
        """Global pellet `index` (row `row` of the chunk) at launch; also its launch |v|^2, |omega|^2."""
        position, velocity, spin = launch_state(source, index, row)
        if wp.static(WRITE):
            write_initial(out, row, position, velocity, spin)
        f = Flight()
        f.position = position
        f.velocity = velocity
        f.spin = spin
        f.time = scalar(0.0)
        f.touching = wp.int32(-1)
        f.impacts = wp.int32(0)
        f.state = wp.int32(FLYING)
        f.resting_surface = wp.int32(-1)
        f.last_slipped = wp.int32(0)
        f.ricochet_point = vec3()
        f.ricochet_time = scalar(0.0)
        return f, wp.dot(f.velocity, f.velocity), wp.dot(f.spin, f.spin)

    @wp.func
    def resume_pellet(release: Release, row: wp.int32, surfaces: Surfaces, counts: wp.vec4i, acc: floats_t):
        """The pellet where the dense phase left it (its flight may have ended there); a first
        impact made in the dense phase is counted here."""
        f = Flight()
        f.position = release.position[row]
        f.velocity = release.velocity[row]
        f.spin = release.angular_velocity[row]
        launch_velocity = release.launch_velocity[row]
        launch_spin = release.launch_angular_velocity[row]
        launch_v2 = wp.dot(launch_velocity, launch_velocity)
        launch_w2 = wp.dot(launch_spin, launch_spin)
        f.time = release.time[row]
        f.touching = release.touching[row]
        f.ricochet_point = release.ricochet_point[row]
        f.ricochet_time = release.ricochet_time[row]
        f.last_slipped = release.last_slipped[row]
        f.impacts = release.impacts[row]
        f.state = wp.int32(FLYING)
        f.resting_surface = wp.int32(-1)
        if release.phase[row] != 0:
            f.state = wp.int32(RESTING)
            f.resting_surface = release.end_surface[row]
        if f.impacts > 0:
            counts, acc = add_first_impact(
                counts, acc, release.first_slipped[row], release.first_velocity_before[row],
                release.first_angular_velocity_before[row], release.first_velocity_after[row],
                release.first_angular_velocity_after[row], surfaces.normal[release.first_surface[row]], launch_v2, launch_w2,
            )
        return f, counts, acc, launch_v2, launch_w2

    return SimpleNamespace(launch_pellet=launch_pellet, resume_pellet=resume_pellet)


@functools.cache
def make_course(spec) -> SimpleNamespace:
    """`bounce` (one flight to a surface and what happens there) and `land` (the flight after the
    last ricochet, and the landing's range and statistics)."""
    t = types_for(spec.precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    Flight = make_flight_state(spec.precision)
    flight = make_flight(spec.precision, spec.static_planes, spec.flight)
    _rests, _stays, meet_surface, contact_point, landing_range = make_contact(spec.precision)
    out, acc = make_outputs(spec.precision), make_accumulators(spec.precision)
    Outputs, floats_t, extremes_t = out.Outputs, acc.floats_t, acc.extremes_t
    write_impact, write_landing, add_first_impact, add_landing = out.write_impact, out.write_landing, acc.add_first_impact, acc.add_landing
    WRITE = bool(spec.core_fields)

    @wp.func
    def bounce(b: wp.int32, row: wp.int32, f: Flight, counts: wp.vec4i, acc: floats_t, launch_v2: scalar,
               launch_w2: scalar, surfaces: Surfaces, physics: Physics, out: Outputs):
        """Ricochet `b` of a flying pellet: the next surface, then an impact (eqs. 1-25) or the end
        of its flight there (escaped when it meets none). Returns the pellet, the partials and
        whether it was an impact."""
        impacted = wp.int32(0)
        dt, k, position, velocity, spin = flight.to_contact(f.position, f.velocity, f.spin, f.touching, surfaces, physics)
        if k < 0:
            f.state = wp.int32(ESCAPED)
        else:
            f.position = position
            f.velocity = velocity
            f.spin = spin
            f.time = f.time + dt
            velocity_after, spin_after, slipped, impacted, flies_on = meet_surface(k, f.velocity, f.spin, surfaces, physics)
            if impacted == 0:
                f.state = wp.int32(RESTING)
                f.resting_surface = k
            else:
                normal = surfaces.normal[k]
                if wp.static(WRITE):
                    write_impact(out, row, b, f.time, f.position, f.velocity, f.spin, velocity_after, spin_after, slipped, k)
                if b == 0:
                    counts, acc = add_first_impact(counts, acc, slipped, f.velocity, f.spin, velocity_after, spin_after,
                                                   normal, launch_v2, launch_w2)
                f.velocity = velocity_after
                f.spin = spin_after
                f.touching = k
                f.impacts = f.impacts + 1
                f.last_slipped = slipped
                f.ricochet_point = contact_point(f.position, physics.radius, normal)
                f.ricochet_time = f.time
                if flies_on == 0:
                    f.state = wp.int32(RESTING)
                    f.resting_surface = k
        return f, counts, acc, impacted

    @wp.func
    def land(row: wp.int32, f: Flight, counts: wp.vec4i, acc: floats_t, lo: extremes_t, hi: extremes_t,
             range_shift: scalar, surfaces: Surfaces, physics: Physics, out: Outputs):
        """After at least one ricochet: where the flight ended on a surface (resting), or the
        next surface met after the last ricochet. Writes the landing outputs."""
        landing_time = scalar(wp.inf)
        landing_position = vec3(scalar(wp.nan))
        landing_velocity = vec3(scalar(wp.nan))
        distance = scalar(wp.nan)
        landing_surface = wp.int32(-1)
        if f.impacts > 0 and f.state != ESCAPED:
            k = f.resting_surface
            if f.state == FLYING:
                dt, k_next, position, velocity, spin = flight.to_contact(f.position, f.velocity, f.spin, f.touching,
                                                                         surfaces, physics)
                k = k_next
                if k >= 0:
                    f.position = position
                    f.velocity = velocity
                    f.spin = spin
                    f.time = f.time + dt
            if k >= 0:
                landing_surface = k
                landing_time = f.time
                landing_position = f.position
                landing_velocity = f.velocity
                distance = landing_range(landing_position, physics.radius, surfaces.normal[k], f.ricochet_point)
                counts, acc, lo, hi, range_shift = add_landing(counts, acc, lo, hi, range_shift, distance,
                                                               f.time - f.ricochet_time, landing_velocity, f.last_slipped)
        if wp.static(WRITE):
            write_landing(out, row, landing_time, landing_position, landing_velocity, distance, landing_surface)
        return counts, acc, lo, hi, range_shift

    return SimpleNamespace(bounce=bounce, land=land)
