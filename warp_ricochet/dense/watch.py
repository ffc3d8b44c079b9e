"""The hazard along the path inside the dense phase (docs/hazard.md section 11): each pellet's
watch (`tallies.path`) is kept in `Cloud.watch` from its launch (`launch`), fed every piece of
path the dense phase flies it, and handed to the core kernel with the release
(`core.release.Release.watch_reach`, `watch_ints`), which goes on with it; its passes count into
the run's tally (`Cloud.watch.tally`), the map cell of a pass under way kept across the hand-over,
so a cell is entered once. Compiled away when the run watches nothing (`spec.watch`).

The pieces: between its events a pellet flies the exact parabola from its reference state (eq.
36), given to the watch as the Hermite quintic of its two ends (values, h v and h^2 g: the parabola
itself, to the rounding of its end), from the old reference state to the new one at each event
(`to`, `arc`: a plane contact, a pair contact, in air a kick and the release). In air a drift has
the air only in its kicks (`dense.air`: Strang splitting); the watch takes it as the quadratic
with the air's acceleration a at its start beside gravity, velocity v0 + (t - t_air) a + g (t - t0)
(v0 has had the air up to t_air, `Cloud.air.time`): its position ends where the drift's end puts it
(`dense.air.drift_end`) and its speed is the pellet's at each time, not the kicked one (half an
interval ahead). A drift ended by a contact ends on the parabola (no air in the position): the
quintic through both ends takes in the difference, at most |a| h^2 / 2. A leap is flown by the
core's integrated flight, each step's interpolant watched (`flight_within`). In vacuum the release
moves no reference state: the core flies on from the last event's, and watches from there."""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.air import make_air_laws
from ..physics.air_flight import GAVE_UP, make_air_flight
from ..tallies.path import make_path_watch
from ..tallies.path_keep import make_path_keep
from .kit import dense_kit


@functools.cache
def make_dense_watch(spec) -> SimpleNamespace:
    """`launch`, `arc`, `to` and (in air) `flight_within` for `spec`."""
    kit = dense_kit(spec)
    scalar, vec3, Surfaces, Physics, Cloud = kit.scalar, kit.vec3, kit.Surfaces, kit.Physics, kit.Cloud
    watcher = make_path_watch(kit.precision, *spec.watch)
    load, store = make_path_keep(kit.precision, *spec.watch[:3])
    ON, AIR, ZERO, ONE = watcher.ON, kit.AIR, scalar(0.0), scalar(1.0)
    laws = make_air_laws(kit.precision, *spec.air_laws) if AIR else None

    @wp.func
    def launch(cloud: Cloud, i: wp.int32):
        """Pellet i's watch starts at its launch."""
        if wp.static(ON):
            store(watcher.start(), cloud.watch.reach, cloud.watch.ints, i)

    @wp.func
    def arc(cloud: Cloud, physics: Physics, i: wp.int32, x0: vec3, v0: vec3, w0: vec3, t0: scalar, x1: vec3, t1: scalar):
        """Pellet i's flight from reference state (x0, v0, spin w0) at t0 (s) to x1 at t1, watched
        (module notes): the parabola of eq. 36 in vacuum; in air the drift with the air's
        acceleration a at its start, its velocity v0 + (t - t_air) a + g (t - t0) (t_air: the time
        up to which v0 has had the air, `Cloud.air.time`)."""
        if wp.static(ON):
            h = t1 - t0
            if h > ZERO:
                a = physics.gravity
                u0 = v0
                u1 = v0 + h * physics.gravity
                if wp.static(AIR):
                    drag, _spin_change = laws.air_rates(v0, w0, physics.air)
                    a = a + drag
                    u0 = u0 + (t0 - cloud.air.time[i]) * drag
                    u1 = u1 + (t1 - cloud.air.time[i]) * drag
                e = (h * h) * a
                track = load(cloud.watch.reach, cloud.watch.ints, i)
                track = watcher.segment(track, cloud.watch.tally, x0, h * u0, e, x1, h * u1, e, h, ONE)
                store(track, cloud.watch.reach, cloud.watch.ints, i)

    @wp.func
    def to(cloud: Cloud, physics: Physics, i: wp.int32, x1: vec3, time: scalar):
        """`arc` from pellet i's reference state to x1 at `time` (s), before that becomes its new
        one (and before its air time moves)."""
        arc(
            cloud,
            physics,
            i,
            cloud.state.position[i],
            cloud.state.velocity[i],
            cloud.state.angular_velocity[i],
            cloud.state.time[i],
            x1,
            time,
        )

    out = SimpleNamespace(launch=launch, arc=arc, to=to, ON=ON)
    if kit.AIR:
        flight = make_air_flight(kit.precision, spec.static_planes, tuple(spec.air_laws), spec.watch, spec.plates)
        to_contact_within = flight.to_contact_within
        within_watched = flight.watched_loop  # (the flight's loop, watched: `physics.air_flight`)

        @wp.func
        def flight_within(
            cloud: Cloud,
            i: wp.int32,
            position: vec3,
            velocity: vec3,
            spin: vec3,
            touching: wp.int32,
            surfaces: Surfaces,
            physics: Physics,
            latest: scalar,
        ):
            """`to_contact_within` of the integrated flight, pellet i's path on it watched (a
            flight given up on is not: the pellet is stepped on from where it was)."""
            if wp.static(ON):
                track = load(cloud.watch.reach, cloud.watch.ints, i)
                dt, k, n, x, v, w, steps, track = within_watched(
                    position, velocity, spin, touching, surfaces, physics, latest, track, cloud.watch.tally
                )
                if k != GAVE_UP:
                    store(track, cloud.watch.reach, cloud.watch.ints, i)
                return dt, k, n, x, v, w, steps
            return to_contact_within(position, velocity, spin, touching, surfaces, physics, latest)

        out.flight_within = flight_within
    return out
