"""A pellet followed on from its landing until it stops (`physics.until = "rest"`, docs/ground.md).

`make_to_rest(spec).to_rest(...)` moves one pellet through three modes until it ends:

- CONTACT: it meets surface k with its velocity. No closing speed: it is on the surface. Else an
  impact: the ground's draw for this impact (`physics.ground.draw`: rough ground's tilted normal and
  scattered restitution and friction, keyed by (seed, pellet, impact)), then either it enters the
  ground (`ground.embeds`: steeper than the critical angle, EMBEDDED) or the impact law
  (`physics.contact.impact`, eqs. 1-25) gives its rebound. It leaves the surface if the rebound's
  speed along the plane's own normal exceeds sqrt(2 R N/m) (`surface_motion.separates`, docs/ground.md
  5, N from gravity and the air at the rebound); else that normal speed is dropped and it moves along
  the surface (or, on water, `ground.sinks`, it is EMBEDDED).
- SURFACE: it slides, rolls or ploughs along surface k (`physics.surface_follow.follow`) until it
  rests (AT_REST), lifts off (FLIGHT: the net normal force pulls it away; it leaves with a normal
  speed of LIFT_OFF (|v| + sqrt(g R)), 7.6e-6 of its speed, so that the flight, which takes a
  pellet touching a plane without normal speed to be on it, sees it leave), reaches another surface (CONTACT), moves on for ever on an
  infinite plane (ESCAPED) or spends its steps (NOT_FINISHED).
- FLIGHT: it flies from surface k to the next contact (`physics.flight`), or escapes.

Wind: on the ground a pellet sits within the roughness length z0 of the wind's logarithmic profile
(u(z) = u*/kappa ln(z/z0), zero at z = z0; z0 is about 1 mm for smooth ground and 1-10 cm for grass:
Stull, An Introduction to Boundary Layer Meteorology, 1988, chapter 9: not read here), so along a surface and at
its rebounds' separation test the air is still: drag and lift act on the pellet's own velocity.
Without this a wind stronger than the rolling resistance (4 m/s against c = 0.01 for a 2.79 mm lead
pellet) rolls a pellet on for ever, which no flat field shows.

Budgets: `physics.max_impacts` impacts and `physics.max_steps` integration steps along surfaces; a
pellet past either, or whose flight integration gave up, is NOT_FINISHED (never called at rest).
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..ends import AT_REST, EMBEDDED, ESCAPED, NOT_FINISHED
from ..physics.air_flight import GAVE_UP
from ..physics.ballistic import EPSILON, ROUNDING
from ..physics.contact import make_contact
from ..physics.flight import make_flight
from ..physics.geometry import make_geometry
from ..physics.ground import make_ground
from ..physics.ground_contact import make_ground_contact
from ..physics.integrate import make_stepper
from ..physics.lanes import any_lane, lanes_here, meet
from ..physics.surface_follow import CONTACT as ENDS_IN_CONTACT
from ..physics.surface_follow import FLIGHT as LIFTS_OFF
from ..physics.surface_follow import FOREVER, REST, make_surface_follow
from ..physics.surface_motion import make_surface_laws
from ..physics.types import types_for
from ..tallies.path_replay import watch_for

CONTACT, SURFACE, FLIGHT = 0, 1, 2  # the modes of `to_rest`
# what it ended as before: DONE_ESCAPED, DONE_NOT_FINISHED, DONE_EMBEDDED (ended in the core's landing part)
DONE_ESCAPED, DONE_NOT_FINISHED, DONE_EMBEDDED = 4 + ESCAPED, 4 + NOT_FINISHED, 4 + EMBEDDED
# core.pellet's states: RESTING met a surface without closing speed (it stays there), EMBEDDED entered the ground
LANDING_FLYING, LANDING_ESCAPED, LANDING_RESTING, LANDING_EMBEDDED = 0, 1, 2, 3
LIFT_OFF = ROUNDING * EPSILON["float32"]  # a lift-off's normal speed, of |v| + sqrt(g R): above rounding in both precisions
EVENTS_PER_IMPACT = 4  # a loop's iterations per impact allowed (a guard: contact, surface, flight, contact)


@functools.cache
def make_to_rest(spec) -> SimpleNamespace:
    """`start_mode` and `to_rest` of a run spec (its precision, planes, flight model and air laws)."""
    t = types_for(spec.precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    flight = make_flight(
        spec.precision, spec.static_planes, spec.flight, spec.air_laws, watch=spec.watch, plates=spec.plates, out_of_line=True
    )
    surface = make_surface_follow(
        spec.precision,
        spec.static_planes,
        spec.flight,
        spec.air_laws,
        watch=spec.watch,
        plates=spec.plates,
        rough=spec.rough,
        log_steps=spec.log_steps,
    )
    watcher = watch_for(spec.precision, *spec.watch)
    Track, Tally = watcher.Track, watcher.Tally
    rests = make_contact(spec.precision)[0]
    ground_contact = make_ground_contact(spec.precision, spec.ground)
    geo, ground, laws = (
        make_geometry(spec.precision, spec.static_planes, plates=spec.plates),
        make_ground(spec.precision),
        make_surface_laws(spec.precision),
    )
    AIR = spec.in_air
    rates = make_stepper(spec.precision, spec.air_laws, out_of_line=True).rates if AIR else None

    @wp.func
    def applied(velocity: vec3, spin: vec3, physics: Physics):
        """g + a_air (m/s^2): every force on the pellet but a surface's, per unit mass."""
        if wp.static(AIR):
            acceleration, _spin_rate = rates(velocity, spin, physics)
            return acceleration
        return physics.gravity

    @wp.func
    def leaves(velocity: vec3, spin: vec3, normal: vec3, physics: Physics):
        """Whether a rebound with `velocity` leaves the plane of `normal` (docs/ground.md 5)."""
        load = laws.normal_load(normal, applied(velocity, spin, physics))
        return laws.separates(wp.dot(velocity, normal), load, physics.radius)

    @wp.func
    def start_mode(state: wp.int32, gave_up: wp.int32, landing_surface: wp.int32, resting_surface: wp.int32):
        """The mode a pellet goes on in after the core's landing part (core.pellet's `state`): at a
        contact with its landing (or resting) surface, else done (escaped, given up or embedded)."""
        mode = wp.int32(DONE_ESCAPED)
        if gave_up != 0:
            mode = wp.int32(DONE_NOT_FINISHED)
        if state == LANDING_EMBEDDED:
            mode = wp.int32(DONE_EMBEDDED)
        elif state == LANDING_RESTING or (state == LANDING_FLYING and landing_surface >= 0):
            mode = wp.int32(CONTACT)  # no closing speed: on the surface (a dense-phase landing has some)
        return mode

    @wp.func
    def to_rest(
        mode: wp.int32,
        k: wp.int32,
        position: vec3,
        velocity: vec3,
        spin: vec3,
        time: scalar,
        impacts: wp.int32,
        seed: wp.int32,
        pellet: wp.int32,
        surfaces: Surfaces,
        physics: Physics,
        track: Track,
        tally: Tally,
    ):
        """Follow a pellet from `mode` (CONTACT, SURFACE or FLIGHT, at or leaving surface k; or
        `start_mode`'s done) to its end, its path watched (`tallies.path`). Returns (end, position,
        velocity, spin, time, impacts, path along surfaces m, integration steps along surfaces and in
        flight, track): position and velocity NaN and time inf when it escaped."""
        end = wp.int32(-1)
        ground_air = physics  # on the ground: no wind (module docstring); in vacuum the same
        if wp.static(AIR):
            ground_air.air.wind = vec3()
        if mode >= DONE_ESCAPED:
            end = mode - 4
            if end == EMBEDDED:
                impacts += 1  # the impact it entered the ground at
        path = scalar(0.0)
        steps = wp.int32(0)  # along surfaces (the budget's)
        steps_in_air = wp.int32(0)
        events = wp.int32(0)
        guard = EVENTS_PER_IMPACT * physics.max_impacts + 8
        while end < 0:
            # a lane along a surface waits while another of its warp is at a contact or in flight,
            # so that the warp's surface phases, the long ones, run together (physics.lanes)
            hopping = any_lane(wp.int32(mode != SURFACE))
            if mode == SURFACE and hopping != 0:
                continue
            events += 1
            if events > guard:
                end = wp.int32(NOT_FINISHED)
            elif mode == CONTACT:
                normal = geo.contact_normal(surfaces, k, position, velocity, physics.radius)  # a mesh's: the face met
                if rests(velocity, normal):
                    mode = wp.int32(SURFACE)
                elif impacts >= physics.max_impacts:
                    end = wp.int32(NOT_FINISHED)
                else:
                    material, tilted, enters = ground_contact.drawn(
                        geo.material(surfaces, k, position), normal, velocity, seed, pellet, impacts
                    )
                    impacts += 1
                    if enters != 0:
                        end = wp.int32(EMBEDDED)
                    else:
                        velocity, spin, _slipped = ground_contact.rebound(material, tilted, velocity, spin, physics)
                        if leaves(velocity, spin, normal, ground_air) != 0:
                            mode = wp.int32(FLIGHT)
                        elif ground.sinks(material) != 0:
                            end = wp.int32(EMBEDDED)
                        else:
                            velocity = velocity - wp.dot(velocity, normal) * normal
                            mode = wp.int32(SURFACE)
            elif mode == SURFACE:
                material = geo.material(surfaces, k, position)
                if ground.sinks(material) != 0:
                    end = wp.int32(EMBEDDED)
                else:
                    here = lanes_here()
                    position, velocity, spin, elapsed, length, ended, taken, k_next, track, normal = surface.follow(
                        position,
                        velocity,
                        spin,
                        k,
                        surfaces,
                        ground_air,
                        material.mu_s,
                        material.mu_d,
                        material.rolling_resistance,
                        material.ploughing,
                        physics.rest_speed,
                        physics.max_steps - steps,
                        track,
                        tally,
                    )
                    meet(here)  # the lanes that came in together leave together (physics.lanes)
                    time += elapsed
                    path += length
                    steps += taken
                    if ended == REST:
                        end = wp.int32(AT_REST)
                    elif ended == LIFTS_OFF:  # it leaves with the least normal speed its precision tells from 0
                        scale = wp.length(velocity) + wp.sqrt(wp.length(physics.gravity) * physics.radius)
                        velocity = laws.tangential(velocity, normal) + (scalar(LIFT_OFF) * scale) * normal
                        mode = wp.int32(FLIGHT)
                    elif ended == ENDS_IN_CONTACT:
                        k = k_next
                        mode = wp.int32(CONTACT)
                    elif ended == FOREVER:
                        end = wp.int32(ESCAPED)
                    else:
                        end = wp.int32(NOT_FINISHED)
            else:
                here = lanes_here()
                dt, k_next, _normal, position_then, velocity_then, spin_then, flight_steps, track = flight.to_contact_watched(
                    position, velocity, spin, k, surfaces, physics, track, tally
                )
                meet(here)  # (as above)
                steps_in_air += flight_steps
                if k_next == GAVE_UP:
                    end = wp.int32(NOT_FINISHED)
                elif k_next < 0:
                    end = wp.int32(ESCAPED)
                else:
                    position = position_then
                    velocity = velocity_then
                    spin = spin_then
                    time += dt
                    k = k_next
                    mode = wp.int32(CONTACT)
        if end == ESCAPED:
            position = vec3(scalar(wp.nan))
            velocity = vec3(scalar(wp.nan))
            time = scalar(wp.inf)
        return end, position, velocity, spin, time, impacts, path, steps + steps_in_air, track

    return SimpleNamespace(start_mode=start_mode, to_rest=to_rest, Tally=Tally, start=watcher.start)
