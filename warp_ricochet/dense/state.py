"""The dense phase's state: the `Cloud` (per-pellet and per-shot arrays) and `Pair` (the pair law's and
the stepping's parameters) structs, and their allocation on the host (what the stages' factories
share beside them: `dense.kit`).
"""

import functools

import warp as wp

from ..core.release import RELEASE_ARRAYS, make_release
from ..fields import COLLISION_FIELDS, FIELDS
from ..physics.types import types_for
from .constants import FRAME_BLOCK, NUM_CLOCK, NUM_FLAGS, NUM_SHOT_FLAGS
from .schedule import shot_stride


@functools.cache
def make_state(precision: str):
    """The `Cloud` and `Pair` structs of one precision."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.struct
    class Cloud:
        """Per-pellet and per-shot arrays of the dense phase (`collisions`). Each pellet's state is
        a reference state (position, velocity at `time`), valid until its next event: the core
        kernel continues from it exactly as from a launch (`core.release`)."""

        position: wp.array(dtype=vec3)  # m, at `time` (or where the flight ended, ENDED)
        velocity: wp.array(dtype=vec3)  # m/s
        angular_velocity: wp.array(dtype=vec3)  # rad/s
        time: wp.array(dtype=scalar)  # s since launch
        phase: wp.array(dtype=wp.int32)  # FLYING 0, ENDED 1 (landed, or at rest on a surface)
        end_surface: wp.array(dtype=wp.int32)
        touching: wp.array(dtype=wp.int32)  # the plane just left (flight.next_contact), or -1
        impacts: wp.array(dtype=wp.int32)
        last_slipped: wp.array(dtype=wp.int32)
        ricochet_point: wp.array(dtype=vec3)  # m, contact point of the last ricochet
        ricochet_time: wp.array(dtype=scalar)
        first_surface: wp.array(dtype=wp.int32)  # the first impact, for the statistics
        first_slipped: wp.array(dtype=wp.int32)
        first_velocity_before: wp.array(dtype=vec3)
        first_angular_velocity_before: wp.array(dtype=vec3)
        first_velocity_after: wp.array(dtype=vec3)
        first_angular_velocity_after: wp.array(dtype=vec3)
        launch_velocity: wp.array(dtype=vec3)
        launch_angular_velocity: wp.array(dtype=vec3)
        collision_count: wp.array(dtype=wp.int32)
        last_collision: wp.array(dtype=scalar)  # s since launch, NaN: never
        energy_lost: wp.array(dtype=scalar)  # J, half of each of its pair collisions' losses
        air_time: wp.array(dtype=scalar)  # s: in air, the air has acted on it up to this time (dense.air)
        air_rate: wp.array(dtype=scalar)  # 1/s: in air, its air rate at its last kick (dense.air)
        position_error: wp.array(dtype=vec3)  # m: in air, the rounding its position lost at its last kick (dense.air)
        # each pellet's earliest event (plane or listed pair), kept until it or a neighbour changes
        event_time: wp.array(dtype=scalar)  # s since launch
        event_partner: wp.array(dtype=wp.int32)  # pellet row, -2 - plane, -1 none
        event_exit: wp.array(dtype=scalar)  # s: when the pellet would leave its skin after that event
        stale: wp.array(dtype=wp.int32)  # 1: the event above must be found again
        kick_due: wp.array(dtype=wp.int32)  # in air: it is kicked at the start of its shot's step of this count (dense.air)
        round_applied: wp.array(dtype=wp.int32)  # (rounds,) 1: round r of this step applied an event
        # states at a shot's checkpoint (horizon_kernel: each is read by O(count) pairs)
        now_position: wp.array(dtype=vec3)
        now_velocity: wp.array(dtype=vec3)
        now_speed: wp.array(dtype=scalar)
        now_bound: wp.array(dtype=scalar)  # m/s^2, in air: the most the air can accelerate it in a leap (dense.leap)
        # neighbour lists
        grid_point: wp.array(dtype=vec3)
        build_offset: wp.array(dtype=vec3)
        neighbours: wp.array2d(dtype=wp.int32)
        neighbour_count: wp.array(dtype=wp.int32)
        # release outputs (empty unless asked for)
        release_time: wp.array(dtype=scalar)
        release_position: wp.array(dtype=vec3)
        release_velocity: wp.array(dtype=vec3)
        release_angular_velocity: wp.array(dtype=vec3)
        collisions_last_time: wp.array(dtype=scalar)
        # shots
        drift_origin: wp.array(dtype=vec3)
        drift_velocity: wp.array(dtype=vec3)
        # per block of a shot (dense.frame: shots x Pair.frame_blocks): its flying pellets' sums
        # (position m, velocity m/s, speed m/s, squared distance from the frame's point m^2), their
        # count, and the latest first contact among them (s)
        frame_position: wp.array(dtype=vec3)
        frame_velocity: wp.array(dtype=vec3)
        frame_speed: wp.array(dtype=scalar)
        frame_spread: wp.array(dtype=scalar)
        frame_arrival: wp.array(dtype=scalar)
        frame_flying: wp.array(dtype=wp.int32)
        clock: wp.array2d(dtype=scalar)  # (shots, NUM_CLOCK)
        shot_flags: wp.array2d(dtype=wp.int32)
        flags: wp.array(dtype=wp.int32)
        # (shots,) m: the most a pellet moves in one step relative to its frame, when beyond half the skin
        step_travel: wp.array(dtype=scalar)
        half_skin: wp.array(dtype=scalar)  # (shots,) m: the shot's half skin (widened for a fixed step that outruns it)
        widest_half_skin: wp.array(dtype=scalar)  # (1,) m: the widest of them (the grid's cells)
        stop: wp.array(dtype=wp.int32)  # (1,) 1: the host asks the CPU's long launches to return (an interrupt)

    @wp.struct
    class Pair:
        """Pellet-pellet law and stepping parameters (SI)."""

        count: wp.int32  # pellets per shot
        frame_block: wp.int32  # pellets a block of the frame sums (FRAME_BLOCK; dense.frame)
        frame_blocks: wp.int32  # such blocks a shot
        mass: scalar  # kg
        inertia: scalar  # kg m^2
        restitution: scalar
        mu_s: scalar
        mu_d: scalar
        contact_duration: scalar  # s, TC model
        fixed_step: scalar  # s, 0: adaptive
        step_fraction: scalar
        air_step_fraction: scalar  # in air: the adaptive step is at most this of |u| / |a_air|
        half_skin: scalar  # m, the configured one (a shot's own may widen: Cloud.half_skin)
        leaps: wp.int32  # in air: 1, a shot past its arrival window leaps to its next possible event (dense.leap)
        max_steps: scalar
        block_steps: wp.int32  # a shot's checkpoints (settling, frames) are every this many of its steps
        pellets: wp.int32  # pellets launched (rows [0, pellets))
        span: wp.int32  # pellets per thread of the per-pellet kernels: 1 on CUDA, many on the CPU

    return Cloud, Pair


VECTORS = (
    "position",
    "velocity",
    "angular_velocity",
    "ricochet_point",
    "first_velocity_before",
    "first_angular_velocity_before",
    "first_velocity_after",
    "first_angular_velocity_after",
    "launch_velocity",
    "launch_angular_velocity",
    "grid_point",
    "build_offset",
    "now_position",
    "now_velocity",
    "position_error",
)
SCALARS = (
    "time",
    "ricochet_time",
    "energy_lost",
    "event_time",
    "event_exit",
    "last_collision",
    "now_speed",
    "now_bound",
    "air_time",
    "air_rate",
)
INTEGERS = (
    "phase",
    "end_surface",
    "touching",
    "impacts",
    "last_slipped",
    "first_surface",
    "first_slipped",
    "collision_count",
    "event_partner",
    "stale",
    "neighbour_count",
    "kick_due",
)
# the dense phase's output arrays (fields.FIELDS, stage "collide"), by their Cloud members;
# collisions.count is the Cloud's own collision_count
OUTPUT_FIELDS = tuple(name for name in COLLISION_FIELDS if name != "collisions.count")


def frame_blocks(count: int) -> int:
    """Blocks of FRAME_BLOCK pellets in a shot of `count` (dense.frame)."""
    return max(1, -(-count // FRAME_BLOCK))  # (FRAME_BLOCK read here: a test sets it smaller)


def allocate_cloud(precision: str, device, capacity: int, shots: int, count: int, rounds: int, max_neighbours: int, fields):
    """A Cloud for up to `capacity` pellets in `shots` shots of `count`, with the output arrays of
    `fields` (others empty); returns it and {field: its device array}."""
    t = types_for(precision)
    kinds = {"vec3": t.vec3, "scalar": t.scalar}

    def arr(dtype, shape=capacity):
        return wp.zeros(shape, dtype=dtype, device=device)

    cloud = make_state(precision)[0]()
    for names, dtype in ((VECTORS, t.vec3), (SCALARS, t.scalar), (INTEGERS, wp.int32)):
        for name in names:
            setattr(cloud, name, arr(dtype))
    cloud.neighbours = arr(wp.int32, (capacity, max_neighbours))
    cloud.round_applied = arr(wp.int32, max(rounds, 1))
    field_arrays = {}
    for name in OUTPUT_FIELDS:
        a = arr(kinds[FIELDS[name].kind], capacity if name in fields else 0)
        setattr(cloud, FIELDS[name].member, a)
        if name in fields:
            field_arrays[name] = a
    if "collisions.count" in fields:
        field_arrays["collisions.count"] = cloud.collision_count
    for name, dtype in (("drift_origin", t.vec3), ("drift_velocity", t.vec3), ("step_travel", t.scalar), ("half_skin", t.scalar)):
        setattr(cloud, name, arr(dtype, shots))
    blocks = shots * frame_blocks(count)
    for name, dtype in (
        ("frame_position", t.vec3),
        ("frame_velocity", t.vec3),
        ("frame_speed", t.scalar),
        ("frame_spread", t.scalar),
        ("frame_arrival", t.scalar),
        ("frame_flying", wp.int32),
    ):
        setattr(cloud, name, arr(dtype, blocks))
    cloud.clock = arr(t.scalar, (shots, NUM_CLOCK))
    cloud.shot_flags = arr(wp.int32, (shots, NUM_SHOT_FLAGS))
    cloud.flags = arr(wp.int32, NUM_FLAGS)
    cloud.widest_half_skin = arr(t.scalar, 1)
    cloud.stop = arr(wp.int32, 1)
    return cloud, field_arrays


def pair_struct(precision: str, model, collisions, count: int, block_steps: int):
    """The Pair struct of a scene's [collisions] table for shots of `count` pellets (SI)."""
    t = types_for(precision)
    scalar = t.scalar
    pair = make_state(precision)[1]()
    pair.count = count
    pair.frame_block = FRAME_BLOCK
    pair.frame_blocks = frame_blocks(count)
    pair.mass = scalar(model.mass)
    pair.inertia = scalar(model.inertia)
    pair.restitution = scalar(collisions.restitution)
    pair.mu_s = scalar(collisions.mu_s)
    pair.mu_d = scalar(collisions.mu_d)
    pair.contact_duration = scalar(collisions.contact_duration)
    pair.fixed_step = scalar(collisions.time_step or 0.0)
    pair.step_fraction = scalar(collisions.step_fraction)
    pair.air_step_fraction = scalar(collisions.air_step_fraction)
    skin = collisions.skin * 2.0 * model.radius  # m
    pair.half_skin = scalar(0.5 * skin)
    pair.leaps = int(collisions.air_leaps)
    pair.max_steps = scalar(collisions.max_steps)
    pair.block_steps = block_steps
    return pair


def release_struct(precision: str, cloud, count: int):
    """The core kernel's view of a cloud (`core.release`): the same arrays, and the shot layout."""
    release = make_release(precision)()
    for name in RELEASE_ARRAYS:
        setattr(release, name, getattr(cloud, name))
    release.shot_count = count
    release.shot_stride = shot_stride(count)
    return release
