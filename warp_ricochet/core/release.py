"""What the dense phase hands to the core kernel: each pellet's reference state when its shot left
the time stepping (or where its flight ended in it), what its impacts so far were, and how the
core's threads map onto shots. The dense phase fills a `Release` struct with its own arrays.
"""

import functools

import warp as wp

from ..physics.types import types_for

FLIGHT_ENDED, ENTERED_GROUND = 1, 2  # `phase` values beside 0 (flying): dense.constants' ENDED, ENTERED

# member -> element kind ("vec3", "scalar", "int32"), per pellet
RELEASE_ARRAYS = {
    "position": "vec3",  # m, at `time` (or where the flight ended)
    "velocity": "vec3",  # m/s
    "angular_velocity": "vec3",  # rad/s
    "time": "scalar",  # s since launch
    "phase": "int32",  # 0 flying, 1 its flight ended (landed, or at rest on a surface), 2 it entered the ground
    "end_surface": "int32",  # where it ended, -1
    "touching": "int32",  # the plane just left, -1
    "impacts": "int32",  # plane impacts so far
    "last_slipped": "int32",
    "ricochet_point": "vec3",  # m, contact point of the last ricochet
    "ricochet_time": "scalar",
    "first_surface": "int32",  # the first impact, for the statistics
    "first_slipped": "int32",
    "first_velocity_before": "vec3",
    "first_angular_velocity_before": "vec3",
    "first_velocity_after": "vec3",
    "first_angular_velocity_after": "vec3",
    "first_normal": "vec3",  # the first impact's normal (`geometry.contact_normal`: a mesh's face met)
    "launch_velocity": "vec3",
    "launch_angular_velocity": "vec3",
}


@functools.cache
def make_release(precision: str):
    """The `Release` struct: the arrays above, and `shot_count` pellets per shot laid out in
    `shot_stride` slots each (slot s * stride + k is pellet s * count + k; the rest is padding);
    `first_pellet` the global index of the chunk's first pellet; `watch_reach` and `watch_ints`
    each pellet's hazard watch at the release (`tallies.path_keep`; empty when none is watched)."""
    t = types_for(precision)
    kinds = {"vec3": t.vec3, "scalar": t.scalar, "int32": wp.int32}
    members = {name: wp.array(dtype=kinds[kind]) for name, kind in RELEASE_ARRAYS.items()}
    members.update(shot_count=wp.int32, shot_stride=wp.int32, first_pellet=wp.int32)
    members.update(watch_reach=wp.array2d(dtype=t.scalar), watch_ints=wp.array2d(dtype=wp.int32))
    return wp.struct(
        type("Release", (), {"__annotations__": members, "__module__": __name__, "__qualname__": f"Release_{precision}"})
    )


@functools.cache
def empty_release(precision: str, device_alias: str):
    """A Release whose arrays are all empty: what runs without collisions pass."""
    t = types_for(precision)
    kinds = {"vec3": t.vec3, "scalar": t.scalar, "int32": wp.int32}
    release = make_release(precision)()
    for name, kind in RELEASE_ARRAYS.items():
        setattr(release, name, wp.empty(0, dtype=kinds[kind], device=device_alias))
    release.watch_reach = wp.empty((0, 1), dtype=t.scalar, device=device_alias)
    release.watch_ints = wp.empty((0, 1), dtype=wp.int32, device=device_alias)
    return release
