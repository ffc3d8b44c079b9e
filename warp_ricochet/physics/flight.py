"""The flight interface: how a pellet moves between contacts, chosen at code generation.

`make_flight(precision, planes, model)` returns `@wp.func`s with one signature for every model:

- `next_contact(position, velocity, spin, touching, surfaces, physics) -> (dt, k)`: the time (s)
  until the pellet meets a plane and the plane's index (k = -1, dt = NO_CONTACT: none);
- `to_contact(position, velocity, spin, touching, surfaces, physics) -> (dt, k, normal, position,
  velocity, spin, steps)`: the contact with its normal (the surface's there, `physics.geometry`;
  0 when none), the state there (unchanged when k = -1 in vacuum) and the integration steps it
  took (0 in vacuum); k = GAVE_UP when an integration gave up;
- `advance(position, velocity, spin, dt, physics) -> (position, velocity, spin)`: the state `dt`
  later, with no contact in between.

`touching` is the plane the pellet is leaving (-1: none). The core kernel flies every pellet
with `to_contact`; the dense phase, whose exact contact times rest on linear relative motion,
moves pellets within a step with the ballistic model (and feels the air at step boundaries).
Models: "ballistic", the exact parabola of eq. (36) (`physics.ballistic`); "air", integrated
with error control (`physics.air_flight`; `laws` = (drag, lift or None, spin_decay or None) of
`physics.air`). A new model is a new branch here, not a change to the kernels.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .air_flight import GAVE_UP, make_air_flight
from .ballistic import NO_CONTACT, make_ballistic
from .geometry import make_geometry
from .types import types_for

MODELS = ("ballistic", "air")


@functools.cache
def make_flight(
    precision: str,
    planes=None,
    model: str = "ballistic",
    laws=None,
    snap: bool = True,
    watch: tuple = (0, 0, False),
    plates: bool = False,
    out_of_line: bool = False,
) -> SimpleNamespace:
    """The flight functions of `model`; `planes`: the number of planes when fixed at code
    generation (loops over them unrolled), else None; `snap`: the ballistic model takes a gap
    within the touching band as zero (`physics.geometry`); `watch`: (thresholds, places, map) of
    the hazard watched along the path by `to_contact_watched` (`tallies.path`); `plates`: surfaces
    may be finite plates (`physics.geometry`); `out_of_line`: in air, `make_air_flight`'s (kernels to rest)."""
    if model not in MODELS:
        raise ValueError(f"flight model {model!r}: must be one of {MODELS}")
    if model == "air":
        return _air_flight(precision, planes, laws, watch, plates, out_of_line)
    from ..tallies.path import make_path_roots  # (tallies imports physics: not at the top)
    from ..tallies.path_replay import watch_for  # (tallies imports physics: not at the top)

    watcher, ground = watch_for(precision, *watch), make_path_roots(precision)
    Track, Tally = watcher.Track, watcher.Tally
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    ballistic = make_ballistic(precision)
    position_at, velocity_at = ballistic.position, ballistic.velocity
    geo = make_geometry(precision, planes, snap, plates)

    @wp.func
    def next_contact(position: vec3, velocity: vec3, spin: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics):
        """The exact parabola's next plane contact (eqs. 36-40): (dt, plane index)."""
        return geo.next_contact(surfaces, position, velocity, physics.gravity, physics.radius, touching)

    @wp.func
    def advance(position: vec3, velocity: vec3, spin: vec3, dt: scalar, physics: Physics):
        """Eq. (36) `dt` later; the spin does not change in vacuum."""
        return position_at(position, velocity, physics.gravity, dt), velocity_at(velocity, physics.gravity, dt), spin

    @wp.func
    def to_contact(position: vec3, velocity: vec3, spin: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics):
        """The next plane contact, its normal and the state there."""
        dt, k = next_contact(position, velocity, spin, touching, surfaces, physics)
        if k < 0:
            return dt, k, vec3(), position, velocity, spin, wp.int32(0)
        position_then, velocity_then, spin_then = advance(position, velocity, spin, dt, physics)
        n = geo.contact_normal(surfaces, k, position_then, velocity_then, physics.radius)
        return dt, k, n, position_then, velocity_then, spin_then, wp.int32(0)

    @wp.func
    def to_contact_watched(
        position: vec3,
        velocity: vec3,
        spin: vec3,
        touching: wp.int32,
        surfaces: Surfaces,
        physics: Physics,
        track: Track,
        tally: Tally,
    ):
        """`to_contact`, the parabola to the contact watched (`tallies.path`), or an escape's until it
        falls below the hazard's ground plane: its values and the track."""
        dt, k, normal, x, v, w, steps = to_contact(position, velocity, spin, touching, surfaces, physics)
        if wp.static(watcher.ON):
            watched = dt
            if k < 0:
                watched = ground.escape_time(tally, position, velocity, physics.gravity)
            track = watcher.parabola(track, tally, position, velocity, physics.gravity, watched)  # (one call: inlined once)
        return dt, k, normal, x, v, w, steps, track

    return SimpleNamespace(
        model=model,
        next_contact=next_contact,
        to_contact=to_contact,
        to_contact_watched=to_contact_watched,
        advance=advance,
        NO_CONTACT=NO_CONTACT,
        GAVE_UP=GAVE_UP,
    )


def _air_flight(precision: str, planes, laws, watch, plates, out_of_line) -> SimpleNamespace:
    t = types_for(precision)
    vec3, Surfaces, Physics = t.vec3, t.Surfaces, t.Physics
    air = make_air_flight(precision, planes, tuple(laws), watch, plates, out_of_line=out_of_line)

    @wp.func
    def next_contact(position: vec3, velocity: vec3, spin: vec3, touching: wp.int32, surfaces: Surfaces, physics: Physics):
        """The integrated flight's next plane contact: (dt, plane index)."""
        dt, k, _normal, _x, _v, _w, _steps = air.to_contact(position, velocity, spin, touching, surfaces, physics)
        return dt, k

    return SimpleNamespace(
        model="air",
        next_contact=next_contact,
        to_contact=air.to_contact,
        to_contact_watched=air.to_contact_watched,
        advance=air.advance,
        to_contact_within=air.to_contact_within,
        NO_CONTACT=NO_CONTACT,
        GAVE_UP=GAVE_UP,
    )
