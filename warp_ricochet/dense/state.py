"""The dense phase's state: the `Cloud` (per-pellet and per-shot arrays) and `Pair` (the pair law's and
the stepping's parameters) structs, and their allocation on the host (what the stages' factories
share beside them: `dense.kit`).

The Cloud's arrays are grouped by the stage that owns them, one nested struct each: `state` (each
pellet's reference state and record, handed to the core), `collisions`, `event` (`dense.rounds`),
`air` (`dense.air`), `now` (`dense.checkpoint`), `lists` (`dense.lists`, the skin), `written` (the
output fields), `frame` (`dense.frame`), `clock` (each shot's clock, by name) and `watch` (each
pellet's hazard watch and the tally it counts into: `dense.watch`); beside them the per-shot and
global flags and the host's stop.
"""

import functools

import warp as wp

from ..core.release import RELEASE_ARRAYS, make_release
from ..fields import COLLISION_FIELDS, FIELDS
from ..physics.types import types_for
from ..tallies.landing import make_landing_tally
from ..tallies.path_keep import kept_shapes
from .constants import FRAME_BLOCK, NUM_FLAGS, NUM_SHOT_FLAGS
from .schedule import shot_stride


@functools.cache
def make_state(precision: str):
    """The `Cloud` and `Pair` structs of one precision."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.struct
    class PelletState:
        """Each pellet's reference state (position, velocity at `time`), valid until its next
        event, and its record: what the core kernel continues from exactly as from a launch
        (`core.release.RELEASE_ARRAYS`, the same names). The launch and the events write it."""

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
        first_normal: wp.array(dtype=vec3)  # the first impact's (its contact normal)
        launch_velocity: wp.array(dtype=vec3)
        launch_angular_velocity: wp.array(dtype=vec3)

    @wp.struct
    class Collisions:
        """Each pellet's pair collisions (`dense.events`)."""

        count: wp.array(dtype=wp.int32)
        last_time: wp.array(dtype=scalar)  # s since launch, NaN: never
        energy_lost: wp.array(dtype=scalar)  # J, half of each of its pair collisions' losses

    @wp.struct
    class Events:
        """Each pellet's earliest event (plane or listed pair), kept until it or a neighbour
        changes (`dense.rounds`)."""

        time: wp.array(dtype=scalar)  # s since launch
        partner: wp.array(dtype=wp.int32)  # pellet row, -2 - plane, -1 none
        exit_time: wp.array(dtype=scalar)  # s: when the pellet would leave its skin after that event
        stale: wp.array(dtype=wp.int32)  # 1: the event above must be found again
        round_applied: wp.array(dtype=wp.int32)  # (rounds,) 1: round r of this step applied an event

    @wp.struct
    class AirState:
        """In air, each pellet's kicks (`dense.air`)."""

        time: wp.array(dtype=scalar)  # s: the air has acted on it up to this time
        rate: wp.array(dtype=scalar)  # 1/s: its air rate at its last kick
        position_error: wp.array(dtype=vec3)  # m: the rounding its position lost at its last kick
        kick_due: wp.array(dtype=wp.int32)  # it is kicked at the start of its shot's step of this count

    @wp.struct
    class Now:
        """Each pellet's state at its shot's checkpoint (`dense.checkpoint`: each is read by O(count) pairs)."""

        position: wp.array(dtype=vec3)
        velocity: wp.array(dtype=vec3)
        speed: wp.array(dtype=scalar)
        bound: wp.array(dtype=scalar)  # m/s^2, in air: the most the air can accelerate it in a leap (dense.leap)

    @wp.struct
    class Lists:
        """Neighbour lists (`dense.lists`) and the skin they are built with."""

        grid_point: wp.array(dtype=vec3)  # co-moving coordinates at the build
        build_offset: wp.array(dtype=vec3)
        neighbours: wp.array2d(dtype=wp.int32)
        neighbour_count: wp.array(dtype=wp.int32)
        # (shots,) m: the most a pellet moves in one step relative to its frame, when beyond half the skin
        step_travel: wp.array(dtype=scalar)
        half_skin: wp.array(dtype=scalar)  # (shots,) m: the shot's half skin (widened for a fixed step that outruns it)
        widest_half_skin: wp.array(dtype=scalar)  # (1,) m: the widest of them (the grid's cells)

    @wp.struct
    class Written:
        """The dense phase's own output fields (fields.COLLISION_FIELDS by their members; empty
        unless asked for), written at release (`dense.ends`)."""

        release_time: wp.array(dtype=scalar)
        release_position: wp.array(dtype=vec3)
        release_velocity: wp.array(dtype=vec3)
        release_angular_velocity: wp.array(dtype=vec3)
        collisions_last_time: wp.array(dtype=scalar)

    @wp.struct
    class Frame:
        """Each shot's co-moving frame (`dense.frame`): its ballistic drift (shots,), and per block
        of a shot (shots x Pair.frame_blocks) its flying pellets' sums (position m, velocity m/s,
        speed m/s, squared distance from the frame's point m^2), their count, and the latest first
        contact among them (s)."""

        drift_origin: wp.array(dtype=vec3)
        drift_velocity: wp.array(dtype=vec3)
        position: wp.array(dtype=vec3)
        velocity: wp.array(dtype=vec3)
        speed: wp.array(dtype=scalar)
        spread: wp.array(dtype=scalar)
        arrival: wp.array(dtype=scalar)
        flying: wp.array(dtype=wp.int32)

    @wp.struct
    class Clock:
        """Each shot's clock (shots,) (`dense.step`, `dense.checkpoint`)."""

        time: wp.array(dtype=scalar)  # s since launch
        step: wp.array(dtype=scalar)  # s: the step being taken
        drift: wp.array(dtype=scalar)  # m/s: its pellets' largest speed relative to the drift
        steps: wp.array(dtype=scalar)  # steps taken
        end: wp.array(dtype=scalar)  # s: when the shot stopped stepping
        # s: the end of its arrival window (the last first contact of its undisturbed pellets, plus
        # the time the cloud takes to pass a point: HORIZON_RADII rms radii / speed)
        window: wp.array(dtype=scalar)
        next: wp.array(dtype=scalar)  # s: the soonest event of all (any pair of the shot, or a plane; horizon)
        cut: wp.array(dtype=scalar)  # s: the earliest pair event left unresolved after the step's rounds
        overrun: wp.array(dtype=scalar)  # m: the largest overrun of the skin (step.prepare_pellet)
        skin: wp.array(dtype=scalar)  # s: the earliest time a pellet changed in the step leaves its skin
        air: wp.array(dtype=scalar)  # 1/s, in air: its fastest air rate |a_air| / |u| (dense.air)
        leap: wp.array(dtype=scalar)  # s, in air: where its last leap began (dense.leap)
        speed: wp.array(dtype=scalar)  # m/s: the mean speed of its flying pellets at its launch (dense.frame)

    @wp.struct
    class Watch:
        """Each pellet's hazard watch along its path (`tallies.path_keep`: empty when the run
        watches none) and the run's tally its passes count into (`dense.watch`)."""

        reach: wp.array2d(dtype=scalar)
        ints: wp.array2d(dtype=wp.int32)
        tally: make_landing_tally(precision).Tally

    @wp.struct
    class Cloud:
        """The dense phase's arrays, by the stage that owns them (`collisions`)."""

        state: PelletState
        collisions: Collisions
        event: Events
        air: AirState
        now: Now
        lists: Lists
        written: Written
        frame: Frame
        clock: Clock
        watch: Watch
        shot_flags: wp.array2d(dtype=wp.int32)  # (shots, NUM_SHOT_FLAGS)
        flags: wp.array(dtype=wp.int32)  # (NUM_FLAGS,)
        stop: wp.array(dtype=wp.int32)  # (1,) 1: the host asks the CPU's long launches to return (an interrupt)
        keys: wp.array(dtype=wp.int32)  # (2,) the run's seed, the chunk's first pellet's global index (the ground's draws)

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
        half_skin: scalar  # m, the configured one (a shot's own may widen: Cloud.lists.half_skin)
        leaps: wp.int32  # in air: 1, a shot past its arrival window leaps to its next possible event (dense.leap)
        max_steps: scalar
        block_steps: wp.int32  # a shot's checkpoints (settling, frames) are every this many of its steps
        pellets: wp.int32  # pellets launched (rows [0, pellets))
        span: wp.int32  # pellets per thread of the per-pellet kernels: 1 on CUDA, many on the CPU

    return Cloud, Pair


# the dense phase's output arrays (fields.FIELDS, stage "collide") in Cloud.written, by their
# members; collisions.count is the Cloud's own collisions.count
OUTPUT_FIELDS = tuple(name for name in COLLISION_FIELDS if name != "collisions.count")
# the groups of per-shot and per-block arrays, and the members of other groups that are per shot
PER_SHOT, PER_BLOCK = ("clock",), ("frame",)
SHOT_MEMBERS = {("lists", "step_travel"), ("lists", "half_skin"), ("frame", "drift_origin"), ("frame", "drift_velocity")}


def frame_blocks(count: int) -> int:
    """Blocks of FRAME_BLOCK pellets in a shot of `count` (dense.frame)."""
    return max(1, -(-count // FRAME_BLOCK))  # (FRAME_BLOCK read here: a test sets it smaller)


def allocate_cloud(
    precision: str, device, capacity: int, shots: int, count: int, rounds: int, max_neighbours: int, fields, watch=(0, 0)
):
    """A Cloud for up to `capacity` pellets in `shots` shots of `count`, with the output arrays of
    `fields` (others empty) and the hazard watch of `watch` (`spec.watch`: thresholds, places);
    returns it and {field: its device array}. Each group's arrays are one a pellet, a shot
    (PER_SHOT, SHOT_MEMBERS) or a frame block (PER_BLOCK), but for those sized below."""
    Cloud = make_state(precision)[0]
    sizes = {
        ("lists", "neighbours"): (capacity, max_neighbours),
        ("lists", "widest_half_skin"): 1,
        ("event", "round_applied"): max(rounds, 1),
    }
    sizes |= {("written", FIELDS[name].member): capacity if name in fields else 0 for name in OUTPUT_FIELDS}
    cloud = Cloud()
    for group, var in Cloud.vars.items():
        if not isinstance(var.type, type(Cloud)) or group == "watch":  # (a group: a nested struct)
            continue
        part = var.type()
        for name, member in var.type.vars.items():
            size = shots if group in PER_SHOT or (group, name) in SHOT_MEMBERS else capacity
            size = shots * frame_blocks(count) if group in PER_BLOCK and (group, name) not in SHOT_MEMBERS else size
            setattr(part, name, wp.zeros(sizes.get((group, name), size), dtype=member.type.dtype, device=device))
        setattr(cloud, group, part)
    cloud.watch = Cloud.vars["watch"].type()  # (its tally: the run's, set by `DensePhase.run`)
    reach, ints = kept_shapes(capacity, *watch[:2])
    cloud.watch.reach = wp.zeros(reach, dtype=types_for(precision).scalar, device=device)
    cloud.watch.ints = wp.zeros(ints, dtype=wp.int32, device=device)
    cloud.shot_flags = wp.zeros((shots, NUM_SHOT_FLAGS), dtype=wp.int32, device=device)
    cloud.flags = wp.zeros(NUM_FLAGS, dtype=wp.int32, device=device)
    cloud.stop = wp.zeros(1, dtype=wp.int32, device=device)
    cloud.keys = wp.zeros(2, dtype=wp.int32, device=device)
    field_arrays = {name: getattr(cloud.written, FIELDS[name].member) for name in OUTPUT_FIELDS if name in fields}
    if "collisions.count" in fields:
        field_arrays["collisions.count"] = cloud.collisions.count
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
        setattr(release, name, getattr(cloud.state, name))
    release.watch_reach, release.watch_ints = cloud.watch.reach, cloud.watch.ints
    release.shot_count = count
    release.shot_stride = shot_stride(count)
    return release
