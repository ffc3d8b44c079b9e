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
moves no reference state: the core flies on from the last event's, and watches from there.

Escapes (the core's rule, `tallies.path_roots`): a piece that `to` watches (up to a pair contact,
a kick, the release, a leap's start) from a reference state with no surface ahead is watched only
until the centre is below the hazard's ground plane and falling: in vacuum while the parabola meets
no surface (`next_contact`), up to `escape_time`; in air while the pellet at the piece's end is
behind every plane (`make_plane_search`'s start: none watched nor waiting), up to `ground_theta`.
There its watch ends for good (cell ESCAPED: `tallies.path` watches it no more, in the dense phase
or the core), whatever a later pair contact does to it."""

import functools
from types import SimpleNamespace

import warp as wp

from ..physics.air import make_air_laws
from ..physics.air_flight import GAVE_UP, make_air_flight, make_plane_search
from ..tallies.path import ESCAPED
from ..tallies.path_chord import make_path_watch
from ..tallies.path_keep import make_path_keep
from ..tallies.path_roots import make_path_roots
from .kit import dense_kit


@functools.cache
def make_dense_watch(spec) -> SimpleNamespace:
    """`launch`, `arc`, `to` and (in air) `flight_within` for `spec`."""
    kit = dense_kit(spec)
    scalar, vec3, Surfaces, Physics, Cloud = kit.scalar, kit.vec3, kit.Surfaces, kit.Physics, kit.Cloud
    watcher = make_path_watch(kit.precision, *spec.watch[:4])  # (the dense phase watches at once)
    load, store = make_path_keep(kit.precision, *spec.watch[:3])
    ON, AIR, ZERO, ONE = watcher.ON, kit.AIR, scalar(0.0), scalar(1.0)
    laws = make_air_laws(kit.precision, *spec.air_laws) if AIR else None
    ground, next_contact = make_path_roots(kit.precision), kit.flight.next_contact
    planes = make_plane_search(kit.precision, spec.static_planes, spec.plates) if AIR else None

    @wp.func
    def launch(cloud: Cloud, i: wp.int32):
        """Pellet i's watch starts at its launch."""
        if wp.static(ON):
            store(watcher.start(), cloud.watch.reach, cloud.watch.ints, i)

    @wp.func
    def drift(cloud: Cloud, physics: Physics, i: wp.int32, v0: vec3, w0: vec3, t0: scalar, t1: scalar):
        """The watched flight from velocity v0 (spin w0) at t0 to t1 (s) as a quintic's h v and h^2 a
        (module notes): (h v at t0, h^2 a, h v at t1)."""
        h = t1 - t0
        a = physics.gravity
        u0 = v0
        u1 = v0 + h * physics.gravity
        if wp.static(AIR):
            drag, _spin_change = laws.air_rates(v0, w0, physics.air)
            a = a + drag
            u0 = u0 + (t0 - cloud.air.time[i]) * drag
            u1 = u1 + (t1 - cloud.air.time[i]) * drag
        return h * u0, (h * h) * a, h * u1

    @wp.func
    def arc(cloud: Cloud, physics: Physics, i: wp.int32, x0: vec3, v0: vec3, w0: vec3, t0: scalar, x1: vec3, t1: scalar):
        """Pellet i's flight from reference state (x0, v0, spin w0) at t0 (s) to x1 at t1, watched
        (module notes): the parabola of eq. 36 in vacuum; in air the drift with the air's
        acceleration a at its start, its velocity v0 + (t - t_air) a + g (t - t0) (t_air: the time
        up to which v0 has had the air, `Cloud.air.time`)."""
        if wp.static(ON):
            h = t1 - t0
            if h > ZERO:
                d0, e, d1 = drift(cloud, physics, i, v0, w0, t0, t1)
                track = load(cloud.watch.reach, cloud.watch.ints, i)
                track = watcher.segment(track, cloud.watch.tally, x0, d0, e, x1, d1, e, h, ONE)
                store(track, cloud.watch.reach, cloud.watch.ints, i)

    @wp.func
    def escape_end(
        cloud: Cloud,
        surfaces: Surfaces,
        physics: Physics,
        i: wp.int32,
        x0: vec3,
        d0: vec3,
        e: vec3,
        x1: vec3,
        d1: vec3,
        h: scalar,
    ):
        """Whether pellet i escapes on the piece from its reference state x0 to x1, h s later (its
        segment's h v and h^2 a: d0, e; d1, e; module notes), and where on it (theta in [0, 1]) its
        watch then ends."""
        tally = cloud.watch.tally
        if wp.static(AIR):
            if ground.below(tally, x1, d1 / h):
                watched, waiting, now = planes.start(x1, d1 / h, cloud.state.touching[i], surfaces, physics)
                if watched == 0 and waiting == 0 and now < 0:
                    return True, ground.ground_theta(tally, x0, d0, e, x1, d1, e)
        else:
            v0 = cloud.state.velocity[i]
            escape = ground.escape_time(tally, x0, v0, physics.gravity)
            if escape < h:
                _wait, k = next_contact(x0, v0, cloud.state.angular_velocity[i], cloud.state.touching[i], surfaces, physics)
                if k < 0:
                    return True, wp.max(escape, ZERO) / h
        return False, ONE

    @wp.func
    def to(cloud: Cloud, surfaces: Surfaces, physics: Physics, i: wp.int32, x1: vec3, time: scalar):
        """`arc` from pellet i's reference state to x1 at `time` (s), before that becomes its new
        one (and before its air time moves), but only up to its escape (`escape_end`), where its
        watch ends for good."""
        if wp.static(ON):
            x0 = cloud.state.position[i]
            t0 = cloud.state.time[i]
            h = time - t0
            if h > ZERO:
                track = load(cloud.watch.reach, cloud.watch.ints, i)
                if track.cell != ESCAPED:
                    d0, e, d1 = drift(cloud, physics, i, cloud.state.velocity[i], cloud.state.angular_velocity[i], t0, time)
                    gone, end = escape_end(cloud, surfaces, physics, i, x0, d0, e, x1, d1, h)
                    track = watcher.segment(track, cloud.watch.tally, x0, d0, e, x1, d1, e, h, end)
                    if gone:
                        track.cell = wp.int32(ESCAPED)
                    store(track, cloud.watch.reach, cloud.watch.ints, i)

    out = SimpleNamespace(launch=launch, arc=arc, to=to, ON=ON)
    if kit.AIR:
        flight = make_air_flight(kit.precision, spec.static_planes, tuple(spec.air_laws), spec.watch[:4], spec.plates)
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
