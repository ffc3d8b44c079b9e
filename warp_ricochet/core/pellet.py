"""One pellet through the core: its start (a launch, or the dense phase's release), each bounce
(the flight to the next surface, `physics.flight`, then an impact or the end of its flight there,
`physics.contact`; on rough ground, water or soft ground the ground's draw, penetration and skip of
`physics.ground` first), its landing (eq. 42) and, with physics.until = "rest", on from there to
where it ends (`core.rest`, `ends`), with its outputs written and its statistics added to the thread's partials (`tallies.accumulate`).

The partials are updated in this one function: helpers that take the partial vectors and return
several of them (a tuple) through branches make the CUDA kernel much slower (bench/RESULTS.md,
"The redesign"); helpers that return one vector do not.
"""

import functools

import warp as wp

from ..ends import AT_REST as ENDED_AT_REST
from ..ends import EMBEDDED as ENDED_EMBEDDED
from ..launch.source import make_source
from ..physics.air_flight import GAVE_UP
from ..physics.contact import make_contact
from ..physics.flight import make_flight
from ..physics.geometry import make_geometry
from ..physics.ground_contact import make_ground_contact
from ..physics.types import types_for
from ..tallies.accumulate import make_accumulators
from ..tallies.landing import make_add_landing, make_landing_tally
from ..tallies.path_keep import make_path_keep
from ..tallies.path_replay import watch_for
from ..tallies.sums import REST as X_REST
from .outputs import make_outputs
from .release import ENTERED_GROUND, make_release
from .rest import LANDING_EMBEDDED as EMBEDDED
from .rest import LANDING_ESCAPED as ESCAPED
from .rest import LANDING_FLYING as FLYING
from .rest import LANDING_RESTING as RESTING
from .rest import make_to_rest


@functools.cache
def make_first_normal(precision: str):
    """`first_normal(surfaces, release, row)`: the normal of a released pellet's first impact, the
    dense phase's contact normal there (`geometry.contact_normal`: a plane's, a two-sided plate's
    face closed on, a mesh's face, edge or corner met, a post's side or cap), kept at that impact:
    the last impact's point (`ricochet_point`) may lie elsewhere, on another surface."""
    t = types_for(precision)
    Surfaces, Release = t.Surfaces, make_release(precision)

    @wp.func(inline=True)
    def first_normal(surfaces: Surfaces, release: Release, row: wp.int32):
        return release.first_normal[row]

    return first_normal


@functools.cache
def make_ricochet_pellet(spec):
    """`ricochet_pellet` for `spec`: with `spec.collisions` a pellet continues from the release."""
    t = types_for(spec.precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    src, outs = make_source(spec.precision, spec.from_file, spec.pattern, spec.stations), make_outputs(spec.precision)
    acc_fns = make_accumulators(spec.precision, spec.to_rest)
    Source, Outputs, Release = src.Source, outs.Outputs, make_release(spec.precision)
    floats_t, extremes_t = acc_fns.floats_t, acc_fns.extremes_t
    F_RANGE_STICK, F_RANGE_SLIP, F_ENTERED = acc_fns.offsets.RANGE_STICK, acc_fns.offsets.RANGE_SLIP, acc_fns.offsets.ENTERED
    X_SCALE, flight_scale = acc_fns.flight_scale_index, acc_fns.flight_scale  # the precision rule's statistic
    flight = make_flight(  # (in air, its large functions out of line in kernels to rest: `physics.inlining`)
        spec.precision, spec.static_planes, spec.flight, spec.air_laws, watch=spec.watch, plates=spec.plates,
        out_of_line=spec.to_rest,
    )  # fmt: skip
    watcher = watch_for(spec.precision, *spec.watch)
    load_track = make_path_keep(spec.precision, *spec.watch[:3])[0]
    rests, stays, _impact, _meet, contact_point, landing_range = make_contact(spec.precision)
    geo, ground_contact = make_geometry(spec.precision, plates=spec.plates), make_ground_contact(spec.precision, spec.ground)
    follow, first_normal = make_to_rest(spec) if spec.to_rest else None, make_first_normal(spec.precision)
    RELEASE, WRITE, BOUNCES, AIR = spec.collisions, bool(spec.core_fields), spec.bounces, spec.flight == "air"
    Tally = make_landing_tally(spec.precision).Tally
    landing_tally = make_add_landing(spec.precision, spec.hazard_map, spec.thresholds)
    TALLY, HAZARD_OUT = spec.tally, any(f.startswith("hazard.") for f in spec.core_fields)
    REPLAYED, WATCH_ONLY, COUNTED, WRITE = (
        spec.watch[4],
        spec.watch_only,
        TALLY and not spec.watch_only,
        WRITE and not spec.watch_only,
    )
    TO_REST, horizontal_distance = spec.to_rest, make_landing_tally(spec.precision).horizontal_distance

    @wp.func
    def ricochet_pellet(
        index: wp.int32,
        row: wp.int32,
        source: Source,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
        release: Release,
        tally: Tally,
        counts: wp.vec4i,
        acc: floats_t,
        lo: extremes_t,
        hi: extremes_t,
        range_shift: scalar,
        thread: wp.int32,
    ):
        """Follow one pellet (global `index`, chunk row `row`; `thread`: the launch's) from its start;
        returns the thread's partials with it added."""
        position, velocity, spin = vec3(), vec3(), vec3()
        time = scalar(0.0)
        touching = wp.int32(-1)  # the plane it is leaving
        impacts, state = wp.int32(0), wp.int32(FLYING)
        gave_up = wp.int32(0)  # its flight's integration gave up (state ESCAPED)
        resting_surface = wp.int32(-1)
        last_slipped = wp.int32(0)
        ricochet_point, ricochet_time = vec3(), scalar(0.0)  # the contact point (m) and time (s) of its last ricochet
        launch_velocity, launch_spin = vec3(), vec3()
        track = watcher.start()  # the hazard along its path (`tallies.path`)
        if wp.static(RELEASE):  # where the dense phase left it (its flight may have ended there)
            if wp.static(watcher.ON and not REPLAYED):  # its watch so far: the dense phase's (`dense.watch`; else the replay's)
                track = load_track(release.watch_reach, release.watch_ints, row)
            position = release.position[row]
            velocity = release.velocity[row]
            spin = release.angular_velocity[row]
            launch_velocity = release.launch_velocity[row]
            launch_spin = release.launch_angular_velocity[row]
            time = release.time[row]
            touching = release.touching[row]
            impacts = release.impacts[row]
            last_slipped = release.last_slipped[row]
            ricochet_point = release.ricochet_point[row]
            ricochet_time = release.ricochet_time[row]
            if release.phase[row] != 0:  # its flight ended: on a surface, or in the ground (dense.events)
                state = wp.where(release.phase[row] == ENTERED_GROUND, wp.int32(EMBEDDED), wp.int32(RESTING))
                resting_surface = release.end_surface[row]
        else:
            position, velocity, spin = src.launch_state(source, index, row)
            launch_velocity = velocity
            launch_spin = spin
            if wp.static(WRITE):
                outs.write_initial(out, row, position, velocity, spin)
        track = watcher.seat(track, tally, wp.where(wp.static(REPLAYED), row, thread))  # (its log's column: a row's, a thread's)
        launch_v2 = wp.dot(launch_velocity, launch_velocity)
        launch_w2 = wp.dot(launch_spin, launch_spin)
        if wp.static(RELEASE):
            if impacts > 0:  # its first impact was in the dense phase
                counts[0] += 1
                counts[1] += release.first_slipped[row]
                acc = acc_fns.add_first_impact_sums(
                    acc,
                    release.first_velocity_before[row],
                    release.first_angular_velocity_before[row],
                    release.first_velocity_after[row],
                    release.first_angular_velocity_after[row],
                    first_normal(surfaces, release, row),
                    launch_v2,
                    launch_w2,
                )
            elif state == EMBEDDED:  # it entered the ground at its first impact, without a ricochet
                acc[F_ENTERED] += scalar(1.0)
        first_bounce = impacts  # (bounces made in the dense phase are its outputs)
        for b in range(wp.static(BOUNCES)):  # unrolled (bounces <= 16)
            impacted = wp.int32(0)
            if state == FLYING and b >= first_bounce:
                dt, k, normal, position_then, velocity_then, spin_then, steps, track = flight.to_contact_watched(
                    position, velocity, spin, touching, surfaces, physics, track, tally
                )
                if wp.static(AIR):
                    acc = acc_fns.add_flight_sums(acc, steps, k)
                if k < 0:
                    state = wp.int32(ESCAPED)  # it never meets a surface again
                    if k == GAVE_UP:
                        gave_up = wp.int32(1)
                else:
                    hi[X_SCALE] = wp.max(hi[X_SCALE], flight_scale(position, velocity, dt, physics.gravity))
                    position = position_then
                    velocity = velocity_then
                    spin = spin_then
                    time = time + dt
                    if rests(velocity, normal):
                        state = wp.int32(RESTING)
                        resting_surface = k
                    else:
                        impacted = 1
                        material, tilted, enters = ground_contact.drawn(  # rough ground, entry (physics.ground)
                            geo.material(surfaces, k, position), normal, velocity, source.seed, index, impacts
                        )
                        if enters != 0:
                            state = wp.int32(EMBEDDED)  # it ends here: its landing if after a ricochet
                            resting_surface = k
                            impacted = 0
                            if impacts == 0:  # at its first impact: it hit, without a ricochet
                                acc[F_ENTERED] += scalar(1.0)
                        if impacted != 0:
                            velocity_after, spin_after, slipped = ground_contact.rebound(
                                material, tilted, velocity, spin, physics
                            )
                            if wp.static(WRITE):
                                outs.write_impact(
                                    out, row, b, time, position, velocity, spin, velocity_after, spin_after, slipped, k
                                )
                            if b == 0:
                                counts[0] += 1
                                counts[1] += slipped
                                acc = acc_fns.add_first_impact_sums(
                                    acc, velocity, spin, velocity_after, spin_after, normal, launch_v2, launch_w2
                                )
                            speed_before2 = wp.dot(velocity, velocity)
                            velocity = velocity_after
                            spin = spin_after
                            touching = k
                            impacts = impacts + 1
                            last_slipped = slipped
                            ricochet_point = contact_point(position, physics.radius, normal)
                            ricochet_time = time
                            if stays(velocity, normal, speed_before2):
                                state = wp.int32(RESTING)
                                resting_surface = k
            if wp.static(WRITE):
                if impacted == 0 and b >= first_bounce:  # no impact at this bounce: mark it missing
                    outs.mark_missing(out, row, b)
        # the landing, after at least one ricochet: where its flight ended on a surface, or the
        # next surface met after its last ricochet
        landing_time = scalar(wp.inf)
        landing_position = vec3(scalar(wp.nan))
        landing_velocity = vec3(scalar(wp.nan))
        distance = scalar(wp.nan)
        landing_surface = wp.int32(-1)
        exceeds = wp.int32(0)
        if impacts > 0 and state != ESCAPED:
            k = resting_surface
            landing_normal = vec3()  # eq. 42's contact point along it: the flight's contact normal
            if state == FLYING:
                dt, k_next, landing_normal, position_then, velocity_then, spin_then, steps, track = flight.to_contact_watched(
                    position, velocity, spin, touching, surfaces, physics, track, tally
                )
                if wp.static(AIR):
                    acc = acc_fns.add_flight_sums(acc, steps, k_next)
                k = k_next
                if k_next == GAVE_UP:
                    gave_up = wp.int32(1)
                if k >= 0:
                    hi[X_SCALE] = wp.max(hi[X_SCALE], flight_scale(position, velocity, dt, physics.gravity))
                    position = position_then
                    velocity = velocity_then
                    spin = spin_then
                    time = time + dt
            if k >= 0:
                landing_surface = k
                landing_time = time
                landing_position = position
                landing_velocity = velocity
                if state != FLYING:  # at rest where its last impact or the dense phase left it
                    landing_normal = geo.normal(surfaces, k, position)
                distance = landing_range(position, physics.radius, landing_normal, ricochet_point)
                counts[2] += 1
                if wp.static(TALLY or HAZARD_OUT):
                    v2 = wp.dot(velocity, velocity)
                    exceeds = landing_tally.exceeded(tally, v2)
                    if wp.static(COUNTED):
                        landing_tally.add_landing(tally, row, k, distance, position, v2, exceeds)
                if counts[2] == 1:
                    range_shift = distance
                acc = acc_fns.add_landing_sums(acc, distance - range_shift, time - ricochet_time, landing_velocity)
                lo[0] = wp.min(lo[0], distance)
                hi[0] = wp.max(hi[0], distance)
                if last_slipped != 0:  # by the branch of its last ricochet (constant indices: registers)
                    counts[3] += 1
                    acc[F_RANGE_SLIP] += distance
                    lo[2] = wp.min(lo[2], distance)
                    hi[2] = wp.max(hi[2], distance)
                else:
                    acc[F_RANGE_STICK] += distance
                    lo[1] = wp.min(lo[1], distance)
                    hi[1] = wp.max(hi[1], distance)
        if wp.static(TO_REST):  # on from the landing until it stops (core.rest)
            mode, k_rest = (
                follow.start_mode(state, gave_up, landing_surface, resting_surface),
                wp.max(landing_surface, resting_surface),
            )
            rest_state, rest_position, rest_velocity, spin, rest_time, rest_impacts, rest_path, rest_steps, track = (
                follow.to_rest(
                    mode, k_rest, position, velocity, spin, time, impacts, source.seed, index, surfaces, physics, track, tally
                )
            )
        watcher.finish(track, tally, row)
        if wp.static(HAZARD_OUT and (WRITE or WATCH_ONLY)):
            watcher.write(track, out.hazard_reach, row)
        if wp.static(WRITE):
            outs.write_landing(out, row, landing_time, landing_position, landing_velocity, distance, landing_surface)
            if wp.static(HAZARD_OUT):
                energy = tally.half_mass * wp.dot(landing_velocity, landing_velocity)  # NaN: never landed
                outs.write_hazard(out, row, energy, energy * tally.inverse_area, exceeds)
        if wp.static(TO_REST):  # where it ends: its statistics, its rest distance's count, its outputs
            rest_distance = scalar(wp.nan)  # m, from the shooter (horizontal), of a pellet that stopped
            if rest_state == ENDED_AT_REST or rest_state == ENDED_EMBEDDED:
                if wp.static(COUNTED):
                    rest_distance = landing_tally.add_rest(tally, row, rest_position)
                else:
                    rest_distance = horizontal_distance(tally, rest_position)
                lo[X_REST] = wp.min(lo[X_REST], rest_distance)
                hi[X_REST] = wp.max(hi[X_REST], rest_distance)
            acc = acc_fns.add_rest_sums(acc, rest_state, rest_distance, rest_path, rest_impacts, rest_steps)
            if wp.static(WRITE):
                outs.write_rest(out, row, rest_state, rest_position, rest_velocity, rest_time, rest_impacts, rest_path)
        return counts, acc, lo, hi, range_shift

    return ricochet_pellet
