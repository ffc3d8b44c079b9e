"""The dense phase: pellets in flight colliding with each other and with the planes, time-stepped
on a hash grid, until no pair can touch again; then every pellet goes to the core's exact flight.

One thread per pellet; every pellet belongs to one shot (rows [s * count, (s + 1) * count)) and
meets only pellets of its own shot. Each shot has its own clock and step, so a shot's results do
not depend on which shots share a launch (chunk-size invariance) and finished shots stop early.

Each pellet carries a *reference state*: position and velocity at the time of its last event
(launch, plane impact or pair collision), from which its flight is the exact parabola of eq. (36);
nothing is integrated. Gravity is the same for all pellets, so the relative motion of a pair is
linear and its time of contact is exact (no tunnelling); plane contacts are the exact
parabola-plane times of `flight.py`, from the same reference states as the core, so a pellet that
never meets another gets bitwise the collisions-off result.

Events in a step are resolved in `rounds`: each pellet knows its earliest event (plane contact,
or contact with a listed neighbour); a plane event, or a pair event that both pellets picked
(mutual), is applied at its exact time if it falls in the step. A pellet takes part in at most
one event per round, and a pair is applied by one thread, in place: impulses are never summed,
momentum is conserved, energy never rises, and the result does not depend on thread order. A
pair event still ahead after the last round ends the shot's step at its time (no pellet flies
past it into its partner); it is resolved first in the next step.

A pellet's earliest event is kept from step to step and found again only when it is stale: when
it or a neighbour changed, or its list was rebuilt. A pair's contact time is computed from the
later of the two reference times (as collision_reference does), so it is one number whoever
asks and whenever, and a kept event is the one a new search would find: results do not depend
on when events are found again. Most pellets in most steps have no event, and their step costs
a few reads.

On the CPU a kernel runs on one thread anyway, and entering a Warp kernel thread costs more
than a quiet pellet's step (its struct arguments and locals are set up per thread), so the
per-pellet kernels loop over `pair.span` pellets per thread (all of them on the CPU, one on
CUDA). On the CPU the whole dense phase of a group of shots is one launch of `phase_kernel`
(without trajectory frames; with them a block of steps is one launch of `block_kernel`): each
shot in turn builds its lists, passes its checkpoints and steps, with the same per-pellet
functions in the order the per-step kernels run them (the results are bitwise the same).

Each pellet keeps, with its event, when it would leave its skin after it; the earliest of those
among a round's events in the step ends the step, and only events up to it are applied (a plane
rebound can be far faster than the step was sized for).

Neighbour lists (reach 2R + skin) are built in co-moving coordinates (positions relative to each
shot's ballistic drift): on CUDA from a `wp.HashGrid` whose groups keep shots apart (overlapping
shots cost nothing), on the CPU from `cell_lists_kernel` (the same lists; HashGrid's CPU build has
a fixed cost larger than a shot's whole build). A shot's lists are rebuilt only when it needs it:
a pellet could move by half the skin relative to the drift (checked before each step; a step that
could break a list waits for the rebuild), or its frame was recentred at a checkpoint; the
adaptive step lets a list last SKIN_STEPS steps, one more than a block, so the lists built at a
checkpoint last its block. The adaptive step depends on the shot's own speeds only (a skin cut,
rare, on its own lists' build points), so its results do not depend on the other shots.

At checkpoints (every `block_steps` of its own steps) a shot stops stepping once its arrival
window is over (its undisturbed pellets have all met their first surface and the cloud has passed
it) and no pair of the shot can meet again (all pairs, not only listed ones, checked exactly); see
docs/collisions.md for what this neglects. At each checkpoint a shot past that window finds its
next event over all its pairs and planes and jumps to it: the rare
pair of rebounds converging slowly for tens of milliseconds no longer costs tens of thousands of
small steps.
"""

import functools
import math

import warp as wp

from .flight import EPSILON, ROUNDING, make_flight
from .impact_law import make_impact_law, make_pair_law
from .kernels import launch_funcs_for, output_writers_for, types_for
from .scene import CHECKPOINT_STEPS

FLYING, ENDED = 0, 1  # pellet phases; ENDED: landed after its last ricochet, or at rest on a surface
# global flags (int32 array): a shot waits for a rebuild; shots still stepping; list overflow; a
# shot's skin widened
FLAG_STALL, FLAG_REMAINING, FLAG_OVERFLOW, FLAG_WIDENED = 0, 1, 2, 3
NUM_FLAGS = 4
# per-shot clock (scalar array, shots x 8): time, step, speed bound relative to the drift, steps
# taken, the time the shot stopped stepping, the end of its arrival window (the last first contact
# of its undisturbed pellets, plus the time the cloud takes to pass a point: 4 rms radii / speed),
# the soonest event of all (any pair of the shot, or a plane; horizon_kernel), and the earliest
# pair event left unresolved after the step's rounds (the step ends there), the largest overrun
# of the skin (see prepare_pellet), and the earliest time a pellet changed in the step leaves its
# skin (the step ends there too, and no event after it is applied)
CLOCK_TIME, CLOCK_STEP, CLOCK_DRIFT, CLOCK_STEPS, CLOCK_END, CLOCK_WINDOW, CLOCK_NEXT, CLOCK_CUT, CLOCK_OVERRUN, CLOCK_SKIN = range(10)
NUM_CLOCK = 10
# an overrun below this (in half skins) is rounding of the float32 positions the skin is measured from
OVERRUN_TOLERANCE = 1.01
# a step cut at an unresolved event still advances by this fraction of itself (a pair the law does
# not collide, e.g. one closing within rounding, can never stop the clock)
MIN_CUT_FRACTION = 1.0 / 64.0
HORIZON_RADII = 4.0
# per-shot int flags (shots x 4): waits for a rebuild, finished, a pair or ricochet still ahead,
# its lists are rebuilt at the next build (a shot's lists are rebuilt when it needs it, whatever
# the other shots need, so its list-dependent diagnostics do not depend on the chunk)
SHOT_STALL, SHOT_DONE, SHOT_BUSY, SHOT_REBUILD = 0, 1, 2, 3
CHECKPOINT = 2  # shot_flags[s, SHOT_STALL]: waits at a checkpoint (1: waits for a rebuild)
NUM_SHOT_FLAGS = 4
# hash-grid cells CELL_REACHES reaches wide: a query visits 2 x 2 x 2 cells, not 3 x 3 x 3 (the
# lists are sparse, about one neighbour per pellet in the paper's shot: the cells cost, not the candidates)
CELL_REACHES = 2.0
BLOCK_STEPS = CHECKPOINT_STEPS  # steps between checkpoints (the host reads three integers there, never inside a block)
# the adaptive step lets a list last this many steps at the current speeds: a list built at a
# checkpoint lasts its block (of the default 8 steps; frame_every sets another) with a step to
# spare (speeds change in a block); with a list that lasted exactly a block, a third of the blocks
# stalled at their last step for a rebuild one step before the checkpoint's
SKIN_STEPS = float(BLOCK_STEPS + 1)
# a pellet within this fraction of half its skin since the build, moving at most half the skin /
# SKIN_STEPS in a step (the adaptive step), ends the step within 0.96 of it: no check needed
SKIN_EDGE = 0.85


@functools.cache
def dense_kernels(precision: str, bounces: int, planes: int, write_outputs: bool, from_file: bool):  # noqa: C901
    """The kernels of the dense phase, specialised like the core kernel (precision, bounces,
    planes, per-pellet outputs or not, launch states sampled or given)."""
    t = types_for(precision)
    scalar, vec3, Source, Surfaces, Physics, Outputs = t.scalar, t.vec3, t.Source, t.Surfaces, t.Physics, t.Outputs
    Cloud, Pair = t.Cloud, t.Pair
    impact_law = make_impact_law(scalar)
    pair_law = make_pair_law(scalar)
    _entry, _return, next_contact, ballistic_position, ballistic_velocity = make_flight(scalar, planes if planes <= 4 else None)
    launch_state, write_initial = launch_funcs_for(precision, from_file)
    write_impact, _mark_missing = output_writers_for(precision)
    BOUNCES, WRITE = bounces, write_outputs
    CLOSING_TOLERANCE2 = scalar((ROUNDING * EPSILON[precision]) ** 2)
    TINY_SPEED = scalar(1e-30)
    NEVER = scalar(1e30)  # s: no event ahead
    QUIET_STEP = scalar(1.0)  # s: the longest step, when nothing moves relative to the drift
    opts = {"module": "unique", "enable_backward": False}

    @wp.func
    def drift_point(cloud: Cloud, shot: wp.int32, time: scalar, gravity: vec3):
        """The shot's co-moving reference point: its mean launch state in free flight."""
        return ballistic_position(cloud.drift_origin[shot], cloud.drift_velocity[shot], gravity, time)

    @wp.func
    def recentre(pair: Pair, physics: Physics, cloud: Cloud, s: wp.int32, time: scalar):
        """The shot's co-moving frame: the mean state of its flying pellets at `time`. One
        thread, in pellet order (deterministic). Returns the flying count and the time the cloud
        takes to pass a point (HORIZON_RADII rms radii over the pellets' mean speed)."""
        gravity = physics.gravity
        first = s * pair.count
        position_sum = vec3()
        velocity_sum = vec3()
        speed_sum = scalar(0.0)
        flying = wp.int32(0)
        passing = scalar(0.0)
        for k in range(pair.count):
            i = first + k
            if cloud.phase[i] == FLYING:
                age = time - cloud.time[i]
                position_sum += ballistic_position(cloud.position[i], cloud.velocity[i], gravity, age)
                velocity_now = ballistic_velocity(cloud.velocity[i], gravity, age)
                velocity_sum += velocity_now
                speed_sum += wp.length(velocity_now)
                flying += 1
        if flying > 0:
            inverse = scalar(1.0) / scalar(flying)
            mean_position = position_sum * inverse
            mean_velocity = velocity_sum * inverse
            spread = scalar(0.0)
            for k in range(pair.count):
                i = first + k
                if cloud.phase[i] == FLYING:
                    d = ballistic_position(cloud.position[i], cloud.velocity[i], gravity, time - cloud.time[i]) - mean_position
                    spread += wp.dot(d, d)
            velocity = mean_velocity - gravity * time
            cloud.drift_velocity[s] = velocity
            cloud.drift_origin[s] = mean_position - velocity * time - (scalar(0.5) * time * time) * gravity
            radius = wp.sqrt(spread * inverse)
            # the pellets' mean speed (not the speed of their mean: a head-on pair has none), or the
            # free-fall speed over the cloud's size for a cloud at rest
            speed = speed_sum * inverse + wp.sqrt(wp.length(gravity) * radius)
            passing = scalar(HORIZON_RADII) * radius / wp.max(speed, TINY_SPEED)
        return flying, passing

    @wp.func
    def relative_to_frame(cloud: Cloud, physics: Physics, i: wp.int32, time: scalar, frame_point: vec3,
                          frame_velocity: vec3):
        """Pellet i's position and velocity at `time` relative to a frame there (gravity cancels:
        between events the relative motion is a straight line)."""
        gravity = physics.gravity
        age = time - cloud.time[i]
        relative = ballistic_position(cloud.position[i], cloud.velocity[i], gravity, age) - frame_point
        relative_velocity = ballistic_velocity(cloud.velocity[i], gravity, age) - frame_velocity
        return relative, relative_velocity

    @wp.func
    def relative_to_drift(cloud: Cloud, physics: Physics, i: wp.int32, s: wp.int32):
        """Pellet i's position and velocity relative to its shot's co-moving frame, at the shot's
        clock."""
        gravity = physics.gravity
        time = cloud.clock[s, CLOCK_TIME]
        return relative_to_frame(cloud, physics, i, time, drift_point(cloud, s, time, gravity),
                                 ballistic_velocity(cloud.drift_velocity[s], gravity, time))

    @wp.func
    def skin_exit(cloud: Cloud, physics: Physics, i: wp.int32, s: wp.int32, position: vec3, velocity: vec3, time: scalar):
        """When pellet i, at `position` with `velocity` at `time` (a new reference state), is half
        its shot's skin from where its list was built (relative to the frame its motion is a
        straight line: gravity cancels); `time` if it is there already and moving out."""
        gravity = physics.gravity
        moved = position - drift_point(cloud, s, time, gravity) - cloud.build_offset[i]
        relative_velocity = velocity - ballistic_velocity(cloud.drift_velocity[s], gravity, time)
        half_skin = cloud.half_skin[s]
        a = wp.dot(relative_velocity, relative_velocity)
        b = wp.dot(moved, relative_velocity)
        c = wp.dot(moved, moved) - half_skin * half_skin
        if a <= scalar(0.0):
            if c < scalar(0.0):
                return NEVER
            return time
        if c >= scalar(0.0) and b >= scalar(0.0):
            return time
        root = wp.sqrt(wp.max(b * b - a * c, scalar(0.0)))
        if b <= scalar(0.0):
            return time + (root - b) / a  # the later root (no cancellation: -b >= 0)
        return time - c / (b + root)  # the same root, written without cancellation (c < 0 here)

    @wp.func
    def stepping(cloud: Cloud, i: wp.int32, s: wp.int32):
        """Pellet i of shot s takes part in this step."""
        return cloud.phase[i] == FLYING and cloud.shot_flags[s, SHOT_DONE] == 0 and cloud.shot_flags[s, SHOT_STALL] == 0

    @wp.func
    def set_reference(cloud: Cloud, i: wp.int32, position: vec3, velocity: vec3, spin: vec3, time: scalar):
        """Pellet i's new reference state (its flight from here is the parabola of eq. 36)."""
        cloud.position[i] = position
        cloud.velocity[i] = velocity
        cloud.angular_velocity[i] = spin
        cloud.time[i] = time

    @wp.func
    def plane_outcome(
        i: wp.int32, k: wp.int32, wait: scalar,
        position: vec3, velocity: vec3, spin: vec3, time: scalar,
        cloud: Cloud, surfaces: Surfaces, physics: Physics,
    ):
        """What plane_contact does to pellet i, without doing it: its position, velocity before
        and after, spin after, slipped, the contact time, whether it flies on, whether it is an
        impact (not the end of its flight)."""
        gravity = physics.gravity
        position = ballistic_position(position, velocity, gravity, wait)
        velocity = ballistic_velocity(velocity, gravity, wait)
        time = time + wait
        normal = surfaces.normal[k]
        normal_speed = wp.dot(velocity, normal)
        flying = wp.int32(1)
        impacted = wp.int32(0)
        velocity_after = velocity
        spin_after = spin
        slipped = wp.int32(0)
        if cloud.impacts[i] >= wp.static(BOUNCES):
            flying = wp.int32(0)  # the landing after the last ricochet
        elif normal_speed >= scalar(0.0) or normal_speed * normal_speed <= CLOSING_TOLERANCE2 * wp.dot(velocity, velocity):
            flying = wp.int32(0)  # no closing speed: it stays on the surface
        else:
            velocity_after, spin_after, slipped = impact_law(
                velocity, spin, normal, physics.radius, physics.inertia_factor,
                surfaces.restitution[k], surfaces.mu_s[k], surfaces.mu_d[k],
                wp.dot(gravity, normal) * physics.impact_duration,
            )
            impacted = wp.int32(1)
            leaving = wp.dot(velocity_after, normal)  # E = 0, up to rounding of the speed before: it stays on the surface
            if leaving * leaving <= CLOSING_TOLERANCE2 * wp.dot(velocity, velocity):
                flying = wp.int32(0)
        return position, velocity, velocity_after, spin_after, slipped, time, flying, impacted

    @wp.func
    def plane_contact(
        i: wp.int32, k: wp.int32, wait: scalar,
        position: vec3, velocity: vec3, spin: vec3, time: scalar,
        cloud: Cloud, surfaces: Surfaces, physics: Physics, out: Outputs,
    ):
        """Pellet i (reference state at `time`) meets plane k `wait` later: an impact (eqs. 1-25,
        exactly as the core kernel), or the end of its flight (its contact after `bounces`
        ricochets, or no closing speed). Returns the new reference state and whether it flies on."""
        radius = physics.radius
        position, velocity, velocity_after, spin_after, slipped, time, flying, impacted = plane_outcome(
            i, k, wait, position, velocity, spin, time, cloud, surfaces, physics
        )
        normal = surfaces.normal[k]
        impacts = cloud.impacts[i]
        if impacted != 0:
            if wp.static(WRITE):
                write_impact(out, i, impacts, time, position, velocity, spin, velocity_after, spin_after, slipped, k)
            if impacts == 0:
                cloud.first_surface[i] = k
                cloud.first_slipped[i] = slipped
                cloud.first_velocity_before[i] = velocity
                cloud.first_angular_velocity_before[i] = spin
                cloud.first_velocity_after[i] = velocity_after
                cloud.first_angular_velocity_after[i] = spin_after
            cloud.impacts[i] = impacts + 1
            cloud.last_slipped[i] = slipped
            cloud.ricochet_point[i] = position - radius * normal
            cloud.ricochet_time[i] = time
            cloud.touching[i] = k
            velocity = velocity_after
            spin = spin_after
        if flying == 0:
            cloud.phase[i] = ENDED
            cloud.end_surface[i] = k
            set_reference(cloud, i, position, velocity, spin, time)
        return position, velocity, spin, time, flying

    @wp.func
    def contact_time(d: vec3, u: vec3, reach2: scalar, speeds: scalar):
        """First s >= 0 with |d + u s|^2 = reach2 while closing; 0 when within it and closing; -1 none.
        `speeds` = |v_a| + |v_b|: a closing speed within rounding of it is none (after an E = 0
        collision the normal relative velocity is rounding residue, as collision_reference does)."""
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

    # ------------------------------------------------------------------ set-up

    @wp.kernel(**opts)
    def launch_kernel(first_index: wp.int32, pair: Pair, source: Source, cloud: Cloud, out: Outputs):
        """Launch state of each pellet (sampled from its global index, or given), phase FLYING."""
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            position, velocity, spin = launch_state(source, first_index + i, i)
            if wp.static(WRITE):
                write_initial(out, i, position, velocity, spin)  # (bounces without an impact: the core kernel marks them)
            cloud.position[i] = position
            cloud.velocity[i] = velocity
            cloud.angular_velocity[i] = spin
            cloud.launch_velocity[i] = velocity
            cloud.launch_angular_velocity[i] = spin
            cloud.time[i] = scalar(0.0)
            cloud.phase[i] = FLYING
            cloud.end_surface[i] = -1
            cloud.touching[i] = -1
            cloud.impacts[i] = 0
            cloud.last_slipped[i] = 0
            cloud.ricochet_point[i] = vec3()
            cloud.ricochet_time[i] = scalar(0.0)
            cloud.first_surface[i] = -1
            cloud.first_slipped[i] = 0
            cloud.collision_count[i] = 0
            cloud.energy_lost[i] = scalar(0.0)
            cloud.last_collision[i] = scalar(wp.nan)
            cloud.neighbour_count[i] = 0
            cloud.stale[i] = 1
            cloud.event_partner[i] = -1
            cloud.event_time[i] = NEVER

    @wp.kernel(**opts)
    def drift_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """One thread per shot: the clock starts at 0, the co-moving frame at the launch, and the
        arrival window: the shot keeps stepping until its undisturbed pellets have all met their
        first surface and the cloud has passed it (pellets converging in flight, rebounds meeting
        the pellets still coming)."""
        s = wp.tid()
        for c in range(wp.static(NUM_CLOCK)):
            cloud.clock[s, c] = scalar(0.0)
        cloud.clock[s, CLOCK_NEXT] = NEVER
        cloud.clock[s, CLOCK_CUT] = NEVER
        cloud.clock[s, CLOCK_SKIN] = NEVER
        _flying, passing = recentre(pair, physics, cloud, s, scalar(0.0))
        last_arrival = scalar(0.0)
        first = s * pair.count
        for k in range(pair.count):
            i = first + k
            wait, plane = next_contact(cloud.position[i], cloud.velocity[i], physics.gravity, physics.radius,
                                       surfaces.point, surfaces.normal, wp.int32(-1))
            if plane >= 0:
                last_arrival = wp.max(last_arrival, wait)
        cloud.clock[s, CLOCK_WINDOW] = last_arrival + passing
        cloud.shot_flags[s, SHOT_STALL] = CHECKPOINT  # the launch is its first checkpoint
        cloud.shot_flags[s, SHOT_DONE] = 0
        cloud.shot_flags[s, SHOT_BUSY] = 0
        cloud.shot_flags[s, SHOT_REBUILD] = 1
        cloud.half_skin[s] = pair.half_skin
        cloud.step_travel[s] = scalar(0.0)

    # ------------------------------------------------------------------ neighbour lists

    @wp.kernel(**opts)
    def groups_kernel(pair: Pair, groups: wp.array(dtype=wp.int32)):
        """Each pellet's hash-grid group: its shot (shots never meet, however they overlap)."""
        i = wp.tid()
        groups[i] = i / pair.count

    @wp.func
    def set_build_point(cloud: Cloud, physics: Physics, i: wp.int32, time: scalar, origin: vec3):
        """Pellet i's co-moving grid point at its shot's clock (`origin`: the drift point then),
        which its skin is measured from until the next build."""
        relative = ballistic_position(cloud.position[i], cloud.velocity[i], physics.gravity, time - cloud.time[i]) - origin
        cloud.build_offset[i] = relative
        cloud.grid_point[i] = relative
        return relative

    @wp.kernel(**opts)
    def grid_points_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        """Co-moving grid coordinates: the position relative to the shot's drift point (small
        numbers, and the skin is measured from them); the grid's group is the shot. Shots whose
        lists stay keep their offsets (their points in the grid are never asked for: groups)."""
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            s = i / pair.count
            if cloud.shot_flags[s, SHOT_REBUILD] == 0:
                continue
            time = cloud.clock[s, CLOCK_TIME]
            set_build_point(cloud, physics, i, time, drift_point(cloud, s, time, physics.gravity))

    @wp.kernel(**opts)
    def neighbours_kernel(grid: wp.uint64, pair: Pair, physics: Physics, cloud: Cloud):
        """The listed neighbours of each flying pellet of a shot being rebuilt: flying pellets of
        its shot within the reach."""
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            s = i / pair.count
            if cloud.shot_flags[s, SHOT_REBUILD] == 0:
                continue
            cloud.neighbour_count[i] = 0
            if cloud.phase[i] != FLYING or cloud.shot_flags[s, SHOT_DONE] != 0:
                continue
            point = cloud.grid_point[i]
            reach = scalar(2.0) * (physics.radius + cloud.half_skin[s])
            reach2 = reach * reach
            capacity = cloud.neighbours.shape[1]
            found = wp.int32(0)
            query = wp.hash_grid_query(grid, point, reach, s)  # grouped: pellets of shot s only
            j = wp.int32(0)
            while wp.hash_grid_query_next(query, j):
                if j != i and cloud.phase[j] == FLYING:
                    d = cloud.grid_point[j] - point
                    if wp.dot(d, d) <= reach2:  # the query returns candidates: filter by distance
                        if found < capacity:
                            cloud.neighbours[i, found] = j
                        found += 1
            if found > capacity:
                wp.atomic_max(cloud.flags, FLAG_OVERFLOW, found)
                found = capacity
            cloud.neighbour_count[i] = found
            cloud.stale[i] = 1  # a new list: its earliest event is found again

    @wp.func
    def cell_bucket(cell: wp.vec3i, mask: wp.uint32):
        """A cell's bucket in a table of mask + 1 (a power of two) buckets."""
        h = (wp.uint32(cell[0]) * wp.uint32(73856093)) ^ (wp.uint32(cell[1]) * wp.uint32(19349663)) ^ (wp.uint32(cell[2]) * wp.uint32(83492791))
        return wp.int32(h & mask)

    @wp.func
    def cell_of(point: vec3, inverse: wp.float64):
        """The cell (one reach wide, and a little more) holding a co-moving grid point, in float64:
        a pellet within reach of another is in one of the 27 cells around it, at any distance
        from the drift point."""
        limit = wp.float64(1.0e9)
        x = wp.clamp(wp.floor(wp.float64(point[0]) * inverse), -limit, limit)
        y = wp.clamp(wp.floor(wp.float64(point[1]) * inverse), -limit, limit)
        z = wp.clamp(wp.floor(wp.float64(point[2]) * inverse), -limit, limit)
        return wp.vec3i(wp.int32(x), wp.int32(y), wp.int32(z))

    @wp.func
    def list_pair(cloud: Cloud, i: wp.int32, j: wp.int32, capacity: wp.int32):
        """i and j are neighbours: each goes on the other's list (counted beyond its capacity)."""
        found = cloud.neighbour_count[i]
        if found < capacity:
            cloud.neighbours[i, found] = j
        cloud.neighbour_count[i] = found + 1
        found = cloud.neighbour_count[j]
        if found < capacity:
            cloud.neighbours[j, found] = i
        cloud.neighbour_count[j] = found + 1

    @wp.func
    def cell_lists_shot(s: wp.int32, pair: Pair, physics: Physics, cloud: Cloud, bucket_end: wp.array(dtype=wp.int32),
                        rows: wp.array(dtype=wp.int32), cells: wp.array(dtype=wp.vec3i)):
        """Shot s's lists on the CPU (one thread), in place of grid_points_kernel, wp.HashGrid and
        neighbours_kernel: HashGrid's CPU build costs a fixed 0.15 to 0.3 ms (two radix passes
        over 65,536 bins) for any number of points. The same lists (as sets: the same points, the
        same distance test; no result depends on a list's order): the shot's flying pellets are
        counting-sorted into hashed cells one reach wide, and each pair is found once, from the
        lower cell (its own cell and the 13 after it around each pellet). `bucket_end` has a power
        of two plus one entries; `rows` one per pellet of a shot, `cells` one per pellet. A list
        that overflows sets FLAG_OVERFLOW (to its length)."""
        buckets = bucket_end.shape[0] - 1
        mask = wp.uint32(buckets - 1)
        capacity = cloud.neighbours.shape[1]
        first = s * pair.count
        time = cloud.clock[s, CLOCK_TIME]
        origin = drift_point(cloud, s, time, physics.gravity)
        done = cloud.shot_flags[s, SHOT_DONE] != 0
        reach = scalar(2.0) * (physics.radius + cloud.half_skin[s])
        reach2 = reach * reach
        inverse = wp.float64(1.0) / (wp.float64(reach) * wp.float64(1.001))
        for b in range(buckets + 1):
            bucket_end[b] = 0
        for k in range(pair.count):
            i = first + k
            relative = set_build_point(cloud, physics, i, time, origin)
            cloud.neighbour_count[i] = 0
            if cloud.phase[i] == FLYING and not done:
                cloud.stale[i] = 1  # a new list: its earliest event is found again
                cell = cell_of(relative, inverse)
                cells[i] = cell
                b = cell_bucket(cell, mask)
                bucket_end[b + 1] = bucket_end[b + 1] + 1
        for b in range(buckets):
            bucket_end[b + 1] = bucket_end[b + 1] + bucket_end[b]
        # (bucket_end[b] is where bucket b starts; filling moves it to where b ends)
        for k in range(pair.count):
            i = first + k
            if cloud.phase[i] == FLYING and not done:
                b = cell_bucket(cells[i], mask)
                rows[bucket_end[b]] = i
                bucket_end[b] = bucket_end[b] + 1
        for k in range(pair.count):
            i = first + k
            if cloud.phase[i] != FLYING or done:
                continue
            point = cloud.grid_point[i]
            cell = cells[i]
            # the cells around it from its own on (dz, dy, dx after 0, 0, 0): each pair once
            for dz in range(2):
                for dy in range(-dz, 2):
                    for dx in range(-1, 2):
                        if dz == 0 and dy == 0 and dx < 0:
                            continue
                        around = wp.vec3i(cell[0] + dx, cell[1] + dy, cell[2] + dz)
                        own = dz == 0 and dy == 0 and dx == 0
                        b = cell_bucket(around, mask)
                        start = wp.int32(0)
                        if b > 0:
                            start = bucket_end[b - 1]
                        for m in range(start, bucket_end[b]):
                            j = rows[m]
                            if (j > i or not own) and cells[j] == around:
                                d = cloud.grid_point[j] - point
                                if wp.dot(d, d) <= reach2:
                                    list_pair(cloud, i, j, capacity)
        for k in range(pair.count):
            i = first + k
            found = cloud.neighbour_count[i]
            if found > capacity:
                wp.atomic_max(cloud.flags, FLAG_OVERFLOW, found)
                cloud.neighbour_count[i] = capacity

    @wp.kernel(**opts)
    def cell_lists_kernel(pair: Pair, physics: Physics, cloud: Cloud, bucket_end: wp.array(dtype=wp.int32),
                          rows: wp.array(dtype=wp.int32), cells: wp.array(dtype=wp.vec3i)):
        """The CPU's lists of every shot being rebuilt, in one launch (one thread)."""
        for s in range(pair.pellets / pair.count):
            if cloud.shot_flags[s, SHOT_REBUILD] != 0:
                cell_lists_shot(s, pair, physics, cloud, bucket_end, rows, cells)

    # ------------------------------------------------------------------ one step

    @wp.func(inline=True)
    def bounds_pellet(i: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """Pellet i's speed relative to its shot's drift, into the shot's largest (a pair closes at
        most at twice it). It sets the next step; it depends on the shot alone, never on the
        neighbour lists, so the steps (and results) do not depend on when lists are rebuilt."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        _relative, relative_velocity = relative_to_drift(cloud, physics, i, s)
        wp.atomic_max(cloud.clock, s, CLOCK_DRIFT, wp.length(relative_velocity))

    @wp.func(inline=True)
    def drift_and_edge(i: wp.int32, time: scalar, frame_point: vec3, frame_velocity: vec3, edge_distance: scalar,
                       physics: Physics, cloud: Cloud):
        """For block_shot (its shot is stepping; the frame's point and velocity at the shot's
        clock, computed once a step): bounds_pellet's speed, without writing it, and whether the
        pellet is near the edge of its skin (beyond SKIN_EDGE of half the skin since the build):
        with the adaptive step (at most a ninth of half the skin at its speed) a pellet within it
        can neither break its list in the step nor have overrun it, and prepare_pellet has
        nothing to do for it."""
        speed = scalar(0.0)
        edge = wp.int32(0)
        if cloud.phase[i] == FLYING:
            relative, relative_velocity = relative_to_frame(cloud, physics, i, time, frame_point, frame_velocity)
            speed = wp.length(relative_velocity)
            if wp.length(relative - cloud.build_offset[i]) > edge_distance:
                edge = wp.int32(1)
        return speed, edge

    @wp.kernel(**opts)
    def bounds_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            bounds_pellet(i, pair, physics, cloud)

    @wp.func(inline=True)
    def plan_shot(s: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """Shot s's step, fixed or adaptive (a pair closes by at most
        step_fraction of a diameter in a step; the list lasts SKIN_STEPS steps at these speeds)."""
        cloud.shot_flags[s, SHOT_REBUILD] = 0  # (built before this block)
        for r in range(cloud.round_applied.shape[0]):
            cloud.round_applied[r] = 0  # (every shot's thread writes the same)
        if cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != 0:
            return
        step = pair.fixed_step
        if step <= scalar(0.0):
            diameter = scalar(2.0) * physics.radius
            drift = wp.max(cloud.clock[s, CLOCK_DRIFT], TINY_SPEED)
            step = wp.min(pair.step_fraction * diameter / (scalar(2.0) * drift), pair.half_skin / (scalar(SKIN_STEPS) * drift))
            step = wp.min(step, QUIET_STEP)
        cloud.clock[s, CLOCK_STEP] = step
        cloud.clock[s, CLOCK_DRIFT] = scalar(0.0)
        cloud.clock[s, CLOCK_CUT] = NEVER
        cloud.clock[s, CLOCK_SKIN] = NEVER

    @wp.kernel(**opts)
    def plan_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        plan_shot(wp.tid(), pair, physics, cloud)

    @wp.func(inline=True)
    def prepare_pellet(i: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """A step that could carry a pellet beyond half the skin (relative to the drift) since the
        last build waits for a rebuild: no pair is missed. That holds for the motion known at the
        step's start; an event in the step can make a pellet faster (a plane rebound much faster
        than the step allowed for), and a pellet found beyond half the skin here overran it: the
        largest overrun is reported (stats skin_overrun_max, a warning above 1)."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        step = cloud.clock[s, CLOCK_STEP]
        relative, relative_velocity = relative_to_drift(cloud, physics, i, s)
        moved = relative - cloud.build_offset[i]  # since the build
        half_skin = cloud.half_skin[s]
        overrun = wp.length(moved) / half_skin
        if overrun > scalar(1.0):
            wp.atomic_max(cloud.clock, s, CLOCK_OVERRUN, overrun)
        if wp.length(moved + relative_velocity * step) > half_skin:
            cloud.shot_flags[s, SHOT_STALL] = 1
            cloud.flags[FLAG_STALL] = 1
            travel = wp.length(relative_velocity) * step
            if travel > half_skin:  # one step alone outruns the skin (a fixed step): it must grow
                wp.atomic_max(cloud.step_travel, s, travel)

    @wp.kernel(**opts)
    def prepare_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            prepare_pellet(i, pair, physics, cloud)

    @wp.func
    def mark_stale(cloud: Cloud, i: wp.int32):
        """Pellet i changed (or ended): its event, and its neighbours', are found again (the
        lists are symmetric, so every pellet that could have chosen i is marked)."""
        cloud.stale[i] = 1
        for n in range(cloud.neighbour_count[i]):
            cloud.stale[cloud.neighbours[i, n]] = 1

    @wp.func
    def plane_contacts_until(i: wp.int32, step_end: scalar, most: wp.int32, cloud: Cloud, surfaces: Surfaces,
                             physics: Physics, out: Outputs):
        """Pellet i's plane contacts up to `step_end` (at most `most`), applied to its reference
        state; it is marked stale if it had one. Returns how many it had."""
        position = cloud.position[i]
        velocity = cloud.velocity[i]
        spin = cloud.angular_velocity[i]
        time = cloud.time[i]
        flying = wp.int32(1)
        contacts = wp.int32(0)
        for _ in range(wp.static(BOUNCES + 1)):
            if flying != 0 and contacts < most:
                wait, k = next_contact(position, velocity, physics.gravity, physics.radius, surfaces.point,
                                       surfaces.normal, cloud.touching[i])
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
        last_a = cloud.last_collision[a]
        last_b = cloud.last_collision[b]
        if (not wp.isnan(last_a) and when - last_a <= pair.contact_duration) or (
            not wp.isnan(last_b) and when - last_b <= pair.contact_duration
        ):  # (<=, as collision_reference)
            restitution = scalar(1.0)
        age_a = when - cloud.time[a]
        age_b = when - cloud.time[b]
        xa = ballistic_position(cloud.position[a], cloud.velocity[a], gravity, age_a)
        va = ballistic_velocity(cloud.velocity[a], gravity, age_a)
        wa = cloud.angular_velocity[a]
        xb = ballistic_position(cloud.position[b], cloud.velocity[b], gravity, age_b)
        vb = ballistic_velocity(cloud.velocity[b], gravity, age_b)
        wb = cloud.angular_velocity[b]
        va2, wa2, vb2, wb2, collided, _slipped = pair_law(
            xa, va, wa, physics.radius, pair.mass, xb, vb, wb, physics.radius, pair.mass,
            physics.inertia_factor, restitution, pair.mu_s, pair.mu_d,
        )
        return xa, va, wa, xb, vb, wb, va2, wa2, vb2, wb2, collided

    @wp.func(inline=True)
    def choose_pellet(i: wp.int32, look: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """Each flying pellet's earliest event: its next plane contact, or contact with a listed
        neighbour (ties: a plane, then the lower row). It is found again only when the pellet is
        stale (it or a neighbour changed, or its list was rebuilt): a pair's time is computed
        from the later of the two reference times, as in collision_reference, so it is one
        number whoever asks and whenever, and a kept event is the one a new search would find.
        With its event it keeps when it would leave its skin after it (as if applied: a pair as
        if both chose it), and each round the earliest of those among events in the step is the
        round's skin limit (resolve_pellet applies no event after it; the step ends there).
        `look` (after the last round): pair events still ahead in the step cut it, so no pellet
        flies past an event left unresolved (into its partner). A round after one that applied
        nothing has nothing to do (no pellet is stale, every choice is the same)."""
        if cloud.stale[i] == 0 and cloud.event_partner[i] == -1:
            return  # nothing ahead
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        if cloud.stale[i] != 0:
            cloud.stale[i] = 0
            gravity = physics.gravity
            position = cloud.position[i]
            velocity = cloud.velocity[i]
            time = cloud.time[i]
            wait, k = next_contact(position, velocity, gravity, physics.radius, surfaces.point, surfaces.normal, cloud.touching[i])
            best_time = NEVER
            best = wp.int32(-1)
            if k >= 0:
                best_time = time + wait
                best = -2 - k
            reach2 = scalar(4.0) * physics.radius * physics.radius
            for n in range(cloud.neighbour_count[i]):
                j = cloud.neighbours[i, n]
                if cloud.phase[j] == FLYING:
                    other_time = cloud.time[j]
                    start = wp.max(time, other_time)  # both reference states hold from here
                    d = ballistic_position(cloud.position[j], cloud.velocity[j], gravity, start - other_time) - ballistic_position(position, velocity, gravity, start - time)
                    vj = ballistic_velocity(cloud.velocity[j], gravity, start - other_time)
                    vi = ballistic_velocity(velocity, gravity, start - time)
                    delay = contact_time(d, vj - vi, reach2, wp.length(vi) + wp.length(vj))
                    if delay >= scalar(0.0):
                        when = start + delay
                        if when < best_time or (when == best_time and best >= 0 and j < best):
                            best_time = when
                            best = j
            cloud.event_time[i] = best_time
            cloud.event_partner[i] = best
            exit = NEVER
            if best <= -2:
                at, _v, velocity_after, _w, _slipped, contact, flying, impacted = plane_outcome(
                    i, k, wait, position, velocity, cloud.angular_velocity[i], time, cloud, surfaces, physics
                )
                if flying != 0 and impacted != 0:
                    exit = skin_exit(cloud, physics, i, s, at, velocity_after, contact)
            elif best >= 0:
                a = wp.min(i, best)
                xa, _va, _wa, xb, _vb, _wb, va2, _wa2, vb2, _wb2, _collided = pair_outcome(a, wp.max(i, best), best_time, pair, physics, cloud)
                if i == a:
                    exit = skin_exit(cloud, physics, i, s, xa, va2, best_time)
                else:
                    exit = skin_exit(cloud, physics, i, s, xb, vb2, best_time)
            cloud.event_exit[i] = exit
        step_start = cloud.clock[s, wp.static(CLOCK_TIME)]
        step_end = step_start + cloud.clock[s, wp.static(CLOCK_STEP)]
        if cloud.event_time[i] <= step_end:
            # (after the last round too: finish_kernel applies the plane contacts left in the step)
            wp.atomic_min(cloud.clock, s, wp.static(CLOCK_SKIN), cloud.event_exit[i])
            if look != 0 and cloud.event_partner[i] >= 0 and cloud.event_time[i] < step_end:
                wp.atomic_min(cloud.clock, s, wp.static(CLOCK_CUT), wp.max(cloud.event_time[i], step_start))

    @wp.kernel(**opts)
    def choose_kernel(round: wp.int32, look: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        if round > 0 and look == 0 and cloud.round_applied[round - 1] == 0:
            return  # a round after one that applied nothing: no pellet is stale, every choice is the same
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            choose_pellet(i, look, pair, surfaces, physics, cloud)

    @wp.func
    def step_end_of(cloud: Cloud, s: wp.int32):
        """Where the shot's step ends: its full step, or the earliest pair event its rounds left
        unresolved (but at least MIN_CUT_FRACTION of the step), or the earliest time a pellet
        changed in the step leaves its skin (no minimum there: no pellet outruns its list)."""
        time = cloud.clock[s, CLOCK_TIME]
        step = cloud.clock[s, CLOCK_STEP]
        cut = time + wp.max(wp.min(step, cloud.clock[s, CLOCK_CUT] - time), step * scalar(MIN_CUT_FRACTION))
        return wp.min(cut, cloud.clock[s, CLOCK_SKIN])

    @wp.func(inline=True)
    def resolve_pellet(i: wp.int32, round: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud,
                       out: Outputs):
        """Apply each pellet's event if it falls in the step: a plane event, or a pair event both
        pellets chose (mutual), applied by the lower row's thread to both. A pellet takes part in
        at most one event per round, so every state is read and written by one thread only.
        Only events up to the round's skin limit are applied (choose_pellet: the earliest time a
        pellet changed by an event of the round would leave its skin), so no pellet outruns its
        list (the skin was sized for the motion known at the step's start; a plane rebound can be
        far faster)."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        partner = cloud.event_partner[i]
        if partner == -1 or (partner >= 0 and partner < i):
            return
        step_start = cloud.clock[s, CLOCK_TIME]
        step_end = step_start + cloud.clock[s, CLOCK_STEP]
        # (wp.static for CLOCK_SKIN here: Warp 1.19 merges a module constant used inside a branch
        # that returns into a variable set only on that path, and a later use on another path
        # read it unset: a wrong index into the clock)
        skin_limit = cloud.clock[s, wp.static(CLOCK_SKIN)]
        when = cloud.event_time[i]
        gravity = physics.gravity
        if partner <= -2:
            if when <= step_end and when <= skin_limit:
                if plane_contacts_until(i, step_end, 1, cloud, surfaces, physics, out) > 0:  # the one it chose
                    cloud.round_applied[round] = 1
            return
        if when >= step_end or cloud.event_partner[partner] != i or cloud.phase[partner] != FLYING:
            return
        a = i
        b = partner
        when = wp.max(when, step_start)  # (an event the step passed after a cut at MIN_CUT_FRACTION)
        xa, va, wa, xb, vb, wb, va2, wa2, vb2, wb2, collided = pair_outcome(a, b, when, pair, physics, cloud)
        if when > skin_limit:
            return  # after a pellet changed in this round leaves its skin: the next step
        if collided != 0:
            # kinetic energy the pair lost; each pellet books half
            before = pair.mass * (wp.dot(va, va) + wp.dot(vb, vb)) + pair.inertia * (wp.dot(wa, wa) + wp.dot(wb, wb))
            after = pair.mass * (wp.dot(va2, va2) + wp.dot(vb2, vb2)) + pair.inertia * (wp.dot(wa2, wa2) + wp.dot(wb2, wb2))
            half = scalar(0.25) * (before - after)
            cloud.energy_lost[a] = cloud.energy_lost[a] + half
            cloud.energy_lost[b] = cloud.energy_lost[b] + half
            cloud.collision_count[a] = cloud.collision_count[a] + 1
            cloud.collision_count[b] = cloud.collision_count[b] + 1
            cloud.last_collision[a] = when
            cloud.last_collision[b] = when
            cloud.touching[a] = -1  # they may have left the plane: plane times from the actual gap
            cloud.touching[b] = -1
        # (a pair the law does not collide, grazing within rounding, moves its reference states to
        # `when` too: found again from there, it is no longer closing, and the clock moves on)
        set_reference(cloud, a, xa, va2, wa2, when)
        set_reference(cloud, b, xb, vb2, wb2, when)
        cloud.round_applied[round] = 1
        mark_stale(cloud, a)
        mark_stale(cloud, b)

    @wp.kernel(**opts)
    def resolve_kernel(round: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        if round > 0 and cloud.round_applied[round - 1] == 0:
            return  # a round after one that applied nothing has nothing to apply
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            resolve_pellet(i, round, pair, surfaces, physics, cloud, out)

    @wp.func(inline=True)
    def finish_pellet(i: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        """End of the step: plane contacts left in it (no pellet ends a step inside a plane). Only
        a pellet whose earliest event falls in the step can have one."""
        s = i / pair.count
        if not stepping(cloud, i, s):
            return
        step_end = step_end_of(cloud, s)
        if cloud.event_partner[i] != -1 and cloud.event_time[i] <= step_end:
            plane_contacts_until(i, step_end, wp.static(BOUNCES + 1), cloud, surfaces, physics, out)

    @wp.kernel(**opts)
    def finish_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            finish_pellet(i, pair, surfaces, physics, cloud, out)

    @wp.func(inline=True)
    def end_step_shot(s: wp.int32, pair: Pair, cloud: Cloud):
        """Shot s's clock moves on (unless the step waits for a rebuild); after block_steps of its
        own steps it waits at a checkpoint."""
        if cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != 0:
            return
        cloud.clock[s, CLOCK_TIME] = step_end_of(cloud, s)
        steps = cloud.clock[s, CLOCK_STEPS] + scalar(1.0)
        cloud.clock[s, CLOCK_STEPS] = steps
        if wp.int32(steps) % pair.block_steps == 0:
            cloud.shot_flags[s, SHOT_STALL] = CHECKPOINT  # wait for the horizon check and settle

    @wp.kernel(**opts)
    def end_step_kernel(pair: Pair, cloud: Cloud):
        end_step_shot(wp.tid(), pair, cloud)


    @wp.func
    def block_shot(s: wp.int32, steps: wp.int32, rounds: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics,
                   cloud: Cloud, out: Outputs):
        """On the CPU (one thread), up to `steps` steps of shot s: each step is the per-step
        kernels' work for its pellets, in their order; it ends early when the shot waits (a
        checkpoint, or a rebuild) or is done."""
        first = s * pair.count
        last = first + pair.count
        cloud.shot_flags[s, SHOT_REBUILD] = 0  # (as plan_shot: built before this block)
        for _ in range(steps):
            if cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != 0:
                break  # (until its checkpoint, or its rebuild)
            # bounds_pellet and the part of prepare_pellet that most pellets need, in one pass:
            # the full check only when some pellet is near the edge of its skin (or the step is
            # fixed: no bound on how far it carries a pellet)
            drift = scalar(0.0)
            edge = wp.int32(0)
            time = cloud.clock[s, CLOCK_TIME]
            frame_point = drift_point(cloud, s, time, physics.gravity)
            frame_velocity = ballistic_velocity(cloud.drift_velocity[s], physics.gravity, time)
            edge_distance = scalar(SKIN_EDGE) * cloud.half_skin[s]
            for i in range(first, last):
                speed, near = drift_and_edge(i, time, frame_point, frame_velocity, edge_distance, physics, cloud)
                drift = wp.max(drift, speed)
                edge = wp.max(edge, near)
            wp.atomic_max(cloud.clock, s, CLOCK_DRIFT, drift)
            plan_shot(s, pair, physics, cloud)
            if edge != 0 or pair.fixed_step > scalar(0.0):
                for i in range(first, last):
                    prepare_pellet(i, pair, physics, cloud)
            # A pellet whose kept event is after the step (most are) has nothing to do in it
            # until a neighbour's event makes it stale: the per-pellet functions would return at
            # once, after reading the shot's flags and clock (step_end_of is never after the full
            # step). round_applied is this shot's alone here: a round after one in which the
            # shot applied nothing is skipped, as the per-step kernels skip one nobody applied in.
            step_end = cloud.clock[s, CLOCK_TIME] + cloud.clock[s, CLOCK_STEP]
            for r in range(rounds):
                if r == 0 or cloud.round_applied[r - 1] != 0:
                    for i in range(first, last):
                        if cloud.stale[i] != 0 or cloud.event_time[i] <= step_end:
                            choose_pellet(i, 0, pair, surfaces, physics, cloud)
                    for i in range(first, last):
                        if cloud.stale[i] != 0 or cloud.event_time[i] <= step_end:
                            resolve_pellet(i, r, pair, surfaces, physics, cloud, out)
            for i in range(first, last):
                if cloud.stale[i] != 0 or cloud.event_time[i] <= step_end:
                    choose_pellet(i, 1, pair, surfaces, physics, cloud)
            for i in range(first, last):
                if cloud.stale[i] != 0 or cloud.event_time[i] <= step_end:
                    finish_pellet(i, pair, surfaces, physics, cloud, out)
            end_step_shot(s, pair, cloud)

    @wp.kernel(**opts)
    def block_kernel(steps: wp.int32, rounds: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud,
                     out: Outputs):
        """The CPU's block of steps in one launch (one thread): each step is the per-step
        kernels' work in their order. A CPU kernel runs its threads one after another anyway, so
        the results are those of the per-step kernels (tested), without 14 launches a step.
        Shots never meet, so it takes them one after another, all its steps each: a shot's
        pellets stay in cache, and a shot that is done or waits costs nothing."""
        for s in range(pair.pellets / pair.count):
            block_shot(s, steps, rounds, pair, surfaces, physics, cloud, out)

    # ------------------------------------------------------------------ end of a block of steps

    @wp.func(inline=True)
    def horizon_pellet(i: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """Per shot at each of its checkpoints: busy in its arrival window; after it, its next event over ALL
        its pairs (exact: their relative motion is linear; each pair once, O(count) per pellet)
        and planes, so that
        - the shot stops only when no pair at all can meet (pellets farther apart than the lists'
          reach may still converge): whether a shot is busy never depends on the lists (which
          checked only listed pairs before, and missed such pairs);
        - it jumps to its next event instead of stepping through empty time with steps sized for
          its fastest pellets (typically two rebounds converging slowly for tens of milliseconds).
        Measured against a check every 16 steps: 14% fewer steps, the same run time on the CPU."""
        s = i / pair.count
        if cloud.phase[i] != FLYING or cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != CHECKPOINT:
            return
        time = cloud.clock[s, CLOCK_TIME]
        if time < cloud.clock[s, CLOCK_WINDOW]:
            # the arrival window: the cloud converges, meets the surface and passes it (wp.static:
            # see resolve_pellet, a constant used in a branch that returns, then on another path)
            cloud.shot_flags[s, wp.static(SHOT_BUSY)] = 1
            return
        x = cloud.now_position[i]
        v = cloud.now_velocity[i]
        speed = cloud.now_speed[i]
        reach2 = scalar(4.0) * physics.radius * physics.radius
        earliest = NEVER
        for j in range(i + 1, (s + 1) * pair.count):
            if cloud.phase[j] == FLYING:
                d = cloud.now_position[j] - x
                u = cloud.now_velocity[j] - v
                if wp.dot(d, u) < scalar(0.0):  # closing (contact_time has no time for the others)
                    delay = contact_time(d, u, reach2, speed + cloud.now_speed[j])
                    if delay >= scalar(0.0):
                        earliest = wp.min(earliest, time + delay)
        if earliest < NEVER:
            cloud.shot_flags[s, wp.static(SHOT_BUSY)] = 1  # a pair can still meet
        # plane contacts bound the jump (they do not keep a shot stepping: the core's flight does them)
        wait, k = next_contact(cloud.position[i], cloud.velocity[i], physics.gravity, physics.radius, surfaces.point,
                               surfaces.normal, cloud.touching[i])
        if k >= 0:
            earliest = wp.min(earliest, cloud.time[i] + wait)
        wp.atomic_min(cloud.clock, s, CLOCK_NEXT, earliest)

    @wp.kernel(**opts)
    def horizon_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            horizon_pellet(i, pair, surfaces, physics, cloud)

    @wp.func(inline=True)
    def now_pellet(i: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """A flying pellet's state at its shot's checkpoint, for horizon_pellet (computed once,
        not once per pair)."""
        s = i / pair.count
        if cloud.phase[i] != FLYING or cloud.shot_flags[s, SHOT_DONE] != 0 or cloud.shot_flags[s, SHOT_STALL] != CHECKPOINT:
            return
        age = cloud.clock[s, CLOCK_TIME] - cloud.time[i]
        velocity = ballistic_velocity(cloud.velocity[i], physics.gravity, age)
        cloud.now_position[i] = ballistic_position(cloud.position[i], cloud.velocity[i], physics.gravity, age)
        cloud.now_velocity[i] = velocity
        cloud.now_speed[i] = wp.length(velocity)

    @wp.kernel(**opts)
    def now_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            now_pellet(i, pair, physics, cloud)

    @wp.func
    def settle_shot(s: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """At a checkpoint (after block_steps of its own steps, so the
        decision does not depend on the other shots), a shot with nothing ahead, or out of steps,
        stops stepping; one still busy jumps to its next event and recentres its frame."""
        if cloud.shot_flags[s, SHOT_DONE] != 0:
            return
        steps = cloud.clock[s, CLOCK_STEPS]
        checkpoint = cloud.shot_flags[s, SHOT_STALL] == CHECKPOINT  # (not a stall for a rebuild)
        if checkpoint and (cloud.shot_flags[s, SHOT_BUSY] == 0 or steps >= pair.max_steps):
            cloud.shot_flags[s, SHOT_DONE] = 1
            cloud.clock[s, CLOCK_END] = cloud.clock[s, CLOCK_TIME]
        else:
            wp.atomic_add(cloud.flags, FLAG_REMAINING, 1)
            if cloud.shot_flags[s, SHOT_STALL] == 1:
                cloud.shot_flags[s, SHOT_REBUILD] = 1  # it waits for its lists
                if cloud.step_travel[s] > scalar(0.0):
                    # a fixed step longer than its skin allows: the shot's skin widens so a list
                    # lasts a step (lists hold candidates only: the results do not change)
                    cloud.half_skin[s] = scalar(1.25) * cloud.step_travel[s]
                    cloud.step_travel[s] = scalar(0.0)
                    wp.atomic_max(cloud.widest_half_skin, 0, cloud.half_skin[s])
                    cloud.flags[FLAG_WIDENED] = 1
            if checkpoint:
                # nothing happens before the shot's next event (horizon_kernel): jump to a step
                # before it (pellets carry reference states: only the clock moves)
                time = cloud.clock[s, CLOCK_TIME]
                ahead = cloud.clock[s, CLOCK_NEXT] - cloud.clock[s, CLOCK_STEP]
                if cloud.clock[s, CLOCK_NEXT] < NEVER and ahead > time:
                    cloud.clock[s, CLOCK_TIME] = ahead
                # the co-moving frame follows the shot's flying pellets (after a ricochet they move
                # nothing like the launch): speeds relative to it set the step. The lists are
                # rebuilt in the new frame before the next step.
                flying, _passing = recentre(pair, physics, cloud, s, cloud.clock[s, CLOCK_TIME])
                if flying > 0:
                    cloud.shot_flags[s, SHOT_REBUILD] = 1
                    cloud.flags[FLAG_STALL] = 1
        cloud.shot_flags[s, SHOT_BUSY] = 0
        cloud.shot_flags[s, SHOT_STALL] = 0
        cloud.clock[s, CLOCK_NEXT] = NEVER
        cloud.clock[s, CLOCK_CUT] = NEVER
        cloud.clock[s, CLOCK_SKIN] = NEVER

    @wp.kernel(**opts)
    def settle_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        settle_shot(wp.tid(), pair, physics, cloud)

    @wp.kernel(**opts)
    def phase_kernel(first_shot: wp.int32, end_shot: wp.int32, steps: wp.int32, rounds: wp.int32, pair: Pair,
                     surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs, bucket_end: wp.array(dtype=wp.int32),
                     rows: wp.array(dtype=wp.int32), cells: wp.array(dtype=wp.vec3i)):
        """The CPU's whole dense phase of shots [first_shot, end_shot) in one launch (one
        thread): each shot, one after another, goes through what the host loop does with it (its
        lists, its checkpoint, a block of steps) until it is done; no host round trip between. A
        list that overflows ends the launch: the host grows the lists and launches again, and
        that shot builds its lists again first (the shots before it are done)."""
        for s in range(first_shot, end_shot):
            while cloud.shot_flags[s, SHOT_DONE] == 0:
                if cloud.shot_flags[s, SHOT_REBUILD] != 0:
                    cell_lists_shot(s, pair, physics, cloud, bucket_end, rows, cells)
                    if cloud.flags[FLAG_OVERFLOW] != 0:
                        return
                if cloud.shot_flags[s, SHOT_STALL] != 0:
                    first = s * pair.count
                    for i in range(first, first + pair.count):
                        now_pellet(i, pair, physics, cloud)
                    for i in range(first, first + pair.count):
                        horizon_pellet(i, pair, surfaces, physics, cloud)
                    settle_shot(s, pair, physics, cloud)
                else:
                    block_shot(s, steps, rounds, pair, surfaces, physics, cloud, out)

    @wp.kernel(**opts)
    def release_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        """The release outputs: each pellet's state when its shot left the dense phase (or where
        its flight ended in it), and the time of its last pair collision."""
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            s = i / pair.count
            time = cloud.time[i]
            position = cloud.position[i]
            velocity = cloud.velocity[i]
            if cloud.phase[i] == FLYING:
                time = cloud.clock[s, CLOCK_END]
                age = time - cloud.time[i]
                position = ballistic_position(cloud.position[i], cloud.velocity[i], physics.gravity, age)
                velocity = ballistic_velocity(cloud.velocity[i], physics.gravity, age)
            if cloud.release_time.shape[0] > 0:
                cloud.release_time[i] = time
            if cloud.release_position.shape[0] > 0:
                cloud.release_position[i] = position
            if cloud.release_velocity.shape[0] > 0:
                cloud.release_velocity[i] = velocity
            if cloud.release_angular_velocity.shape[0] > 0:
                cloud.release_angular_velocity[i] = cloud.angular_velocity[i]
            if cloud.release_last_collision.shape[0] > 0:
                cloud.release_last_collision[i] = cloud.last_collision[i]

    @wp.kernel(**opts)
    def shot_totals_kernel(pair: Pair, cloud: Cloud, totals: wp.array2d(dtype=wp.float64)):
        """One thread per shot, in pellet order: pellets that collided, pair collisions, energy
        lost (J), steps, the time it stopped stepping (s), the largest skin overrun (half skins)."""
        s = wp.tid()
        first = s * pair.count
        collided = wp.float64(0.0)
        collisions = wp.float64(0.0)
        lost = wp.float64(0.0)
        for k in range(pair.count):
            c = cloud.collision_count[first + k]
            if c > 0:
                collided += wp.float64(1.0)
            collisions += wp.float64(c)
            lost += wp.float64(cloud.energy_lost[first + k])
        totals[s, 0] = collided
        totals[s, 1] = collisions
        totals[s, 2] = lost
        totals[s, 3] = wp.float64(cloud.clock[s, CLOCK_STEPS])
        totals[s, 4] = wp.float64(cloud.clock[s, CLOCK_END])
        totals[s, 5] = wp.float64(cloud.clock[s, CLOCK_OVERRUN])

    return dict(
        launch=launch_kernel, drift=drift_kernel, groups=groups_kernel, grid_points=grid_points_kernel, neighbours=neighbours_kernel,
        bounds=bounds_kernel, plan=plan_kernel, prepare=prepare_kernel, choose=choose_kernel,
        cell_lists=cell_lists_kernel, phase=phase_kernel,
        resolve=resolve_kernel, finish=finish_kernel, end_step=end_step_kernel, block=block_kernel, now=now_kernel,
        horizon=horizon_kernel,
        settle=settle_kernel, release=release_kernel, shot_totals=shot_totals_kernel,
    )


# ---------------------------------------------------------------------------------------------- host wiring

SHOT_TOTALS = ("collided", "pair_collisions", "pair_energy_lost", "dense_steps", "dense_end_time", "skin_overrun")


def shot_stride(count: int) -> int:
    """Slots per shot in the core kernel's release mode: the next power of two >= count, so a
    statistics segment (a power of two) holds whole shots, or a shot whole segments."""
    return 1 << max(0, (count - 1).bit_length())


def shot_granule(count: int) -> int:
    """The fewest shots a chunk (all but the last) is a multiple of: whole statistics segments of
    slots, so a chunk starts on a segment boundary and the statistics do not depend on the chunk size."""
    from .kernels import SEGMENT

    return max(1, SEGMENT // shot_stride(count))


def segments_of_shots(shots: int, count: int) -> int:
    """Statistics segments holding the slots of the first `shots` shots of `count` pellets."""
    from .kernels import SEGMENT

    return -(-shots * shot_stride(count) // SEGMENT)


class DensePhase:
    """The dense phase of one chunk of whole shots on one device: buffers for up to `capacity`
    pellets, the kernels, and the loop of blocks of steps (no host sync inside a block)."""

    def __init__(self, model, scene, capacity: int, *, write_outputs: bool, from_file: bool, release_fields=()):
        coll = scene.collisions
        self.model = model
        self.device = model.device
        self.count = scene.shot.count
        self.capacity = capacity
        self.rounds = coll.rounds
        self.block_steps = coll.frame_every or BLOCK_STEPS
        kern = model.kernels
        self.kern = kern
        self.kernels = dense_kernels(model.precision, model.bounces, len(scene.surfaces), write_outputs, from_file)
        scalar, vec3 = kern.scalar, kern.vec3
        dev = self.device
        n = capacity
        shots = -(-capacity // self.count)

        def arr(dtype, shape=n):
            return wp.zeros(shape, dtype=dtype, device=dev)

        cloud = kern.Cloud()
        for name in ("position", "velocity", "angular_velocity", "ricochet_point", "first_velocity_before",
                     "first_angular_velocity_before", "first_velocity_after", "first_angular_velocity_after",
                     "launch_velocity", "launch_angular_velocity", "grid_point", "build_offset", "now_position",
                     "now_velocity"):
            setattr(cloud, name, arr(vec3))
        for name in ("time", "ricochet_time", "energy_lost", "event_time", "event_exit", "last_collision", "now_speed"):
            setattr(cloud, name, arr(scalar))
        for name in ("phase", "end_surface", "touching", "impacts", "last_slipped", "first_surface", "first_slipped",
                     "collision_count", "event_partner", "stale", "neighbour_count"):
            setattr(cloud, name, arr(wp.int32))
        cloud.neighbours = arr(wp.int32, (n, coll.max_neighbours))
        cloud.round_applied = arr(wp.int32, max(self.rounds, 1))
        release = {"release.time": ("release_time", scalar), "release.position": ("release_position", vec3),
                   "release.velocity": ("release_velocity", vec3),
                   "release.angular_velocity": ("release_angular_velocity", vec3),
                   "collisions.last_time": ("release_last_collision", scalar)}
        self.field_arrays = {}
        for field, (member, dtype) in release.items():
            a = arr(dtype) if field in release_fields else arr(dtype, 0)
            setattr(cloud, member, a)
            if field in release_fields:
                self.field_arrays[field] = a
        if "collisions.count" in release_fields:
            self.field_arrays["collisions.count"] = cloud.collision_count
        cloud.drift_origin = arr(vec3, shots)
        cloud.drift_velocity = arr(vec3, shots)
        cloud.clock = arr(scalar, (shots, NUM_CLOCK))
        cloud.shot_flags = arr(wp.int32, (shots, NUM_SHOT_FLAGS))
        cloud.flags = arr(wp.int32, NUM_FLAGS)
        cloud.step_travel = arr(scalar, shots)
        cloud.half_skin = arr(scalar, shots)
        cloud.widest_half_skin = arr(scalar, 1)
        cloud.shot_count = self.count
        cloud.shot_stride = shot_stride(self.count)
        self.cloud = cloud
        self.totals = wp.zeros((shots, len(SHOT_TOTALS)), dtype=wp.float64, device=dev)

        pair = kern.Pair()
        radius = model.radius
        skin = coll.skin * 2.0 * radius
        pair.count = self.count
        pair.mass = scalar(model.mass)
        pair.inertia = scalar(model.inertia)
        pair.restitution = scalar(coll.restitution)
        pair.mu_s = scalar(coll.mu_s)
        pair.mu_d = scalar(coll.mu_d)
        pair.contact_duration = scalar(coll.contact_duration)
        pair.fixed_step = scalar(coll.time_step or 0.0)
        pair.step_fraction = scalar(coll.step_fraction)
        pair.half_skin = scalar(0.5 * skin)
        pair.max_steps = scalar(coll.max_steps)
        pair.block_steps = self.block_steps
        self.pair = pair
        self.cell_lists = not dev.is_cuda and self.CELL_LISTS_ON_CPU
        if self.cell_lists:  # one shot at a time: a table for one shot, rows of one shot
            self.bucket_end = arr(wp.int32, (1 << max(3, (2 * self.count - 1).bit_length())) + 1)
            self.rows = arr(wp.int32, self.count)
            self.cells = arr(wp.vec3i)
        else:
            self.groups = arr(wp.int32)
            cells = min(max(int(round((2.0 * n) ** (1.0 / 3.0))), 8), 256)
            self.grid = wp.HashGrid(cells, cells, cells, device=dev, dtype=scalar)
        self.reach = 2.0 * radius + skin
        self.graph = None
        self.fused = not dev.is_cuda and self.FUSED_ON_CPU

    # on the CPU a block of steps is one launch of block_kernel (False: the per-step kernels, as on CUDA)
    FUSED_ON_CPU = True
    # on the CPU the lists come from cell_lists_kernel (False: wp.HashGrid, as on CUDA; the same lists)
    CELL_LISTS_ON_CPU = True
    # on the CPU (cell lists, no frames) the whole dense phase is one launch of phase_kernel
    # (False: the host loop of checkpoints, rebuilds and blocks, as on CUDA)
    ONE_LAUNCH_ON_CPU = True

    def _threads(self, pellets):
        """Threads of a per-pellet kernel: one per pellet on CUDA; on the CPU (one thread runs
        a launch anyway) one for all, since a thread's entry costs more than a quiet pellet."""
        self.pair.pellets = pellets
        self.pair.span = 1 if self.device.is_cuda else max(pellets, 1)
        return -(-pellets // self.pair.span)

    def _launch(self, name, dim, inputs, record=False):
        return wp.launch(self.kernels[name], dim=dim, inputs=inputs, device=self.device, record_cmd=record)

    def _record(self):
        """The launches of the checkpoints and the rebuilds, recorded once per run (packing the
        structs' parameters costs more than a small launch on the CPU) and again when the lists
        grow (the cloud's struct then holds a new array)."""
        m, c, p = self.model, self.cloud, self.pair
        self.checkpoint_commands = [
            self._launch("now", self.threads, [p, m.physics, c], True),
            self._launch("horizon", self.threads, [p, m.surfaces, m.physics, c], True),
            self._launch("settle", self.shots, [p, m.physics, c], True),
        ]
        if self.cell_lists:
            self.list_commands = [self._launch("cell_lists", 1, [p, m.physics, c, self.bucket_end, self.rows, self.cells], True)]
        else:
            self.list_commands = [self._launch("grid_points", self.threads, [p, m.physics, c], True),
                                  self._launch("neighbours", self.threads, [self.grid.id, p, m.physics, c], True)]

    def _checkpoint(self):
        """Each shot at its checkpoint: its horizon, and whether it stops, jumps or rebuilds;
        returns the global flags (one host sync)."""
        for command in self.checkpoint_commands:
            command.launch()
        return self.cloud.flags.numpy().copy()  # (a copy: CPU arrays share memory)

    def _rebuild(self, pellets) -> bool:
        """Build the neighbour lists; a list that overflowed (a denser cloud than the lists hold)
        grows them and builds again, so no step ever runs on a truncated list. Returns whether
        they grew (the recorded commands then hold the old array, and are recorded again)."""
        c = self.cloud
        grew = False
        while True:
            self.list_commands[0].launch()  # cell lists (CPU), or the grid points
            if not self.cell_lists:
                # (one shot: no groups, a grouped build costs twice as much on the CPU; a grouped query
                # of an ungrouped grid filters nothing)
                groups = self.groups[:pellets] if pellets > self.count else None
                self.grid.build(c.grid_point[:pellets], CELL_REACHES * self.reach, groups=groups)
                self.list_commands[1].launch()
            if not self._grew_lists():
                return grew
            self._record()
            grew = True

    def _grew_lists(self) -> bool:
        """After a build: if a list overflowed, longer lists (1.25 x the longest needed), to be
        built again. One integer read per build."""
        c = self.cloud
        found = int(c.flags.numpy()[FLAG_OVERFLOW])
        if found == 0:
            return False
        c.neighbours = wp.zeros((self.capacity, int(found * 1.25) + 1), dtype=wp.int32, device=self.device)
        c.flags[FLAG_OVERFLOW:].zero_()
        return True

    def _step_commands(self, pellets, shots, outputs):
        """One step's launches, recorded once (packing the structs' parameters costs more than a
        small launch) and replayed; on CUDA a block of them is captured as a graph."""
        m, c, p = self.model, self.cloud, self.pair
        if self.fused:  # the CPU: a block of steps is one launch
            return [self._launch("block", 1, [self.block_steps, self.rounds, p, m.surfaces, m.physics, c, outputs], True)]
        threads = self.threads
        commands = [
            self._launch("bounds", threads, [p, m.physics, c], True),
            self._launch("plan", shots, [p, m.physics, c], True),
            self._launch("prepare", threads, [p, m.physics, c], True),
        ]
        for r in range(self.rounds):
            commands.append(self._launch("choose", threads, [r, 0, p, m.surfaces, m.physics, c], True))
            commands.append(self._launch("resolve", threads, [r, p, m.surfaces, m.physics, c, outputs], True))
        # events still ahead after the rounds: the step ends at the earliest (no pellet flies into its partner)
        commands.append(self._launch("choose", threads, [self.rounds, 1, p, m.surfaces, m.physics, c], True))
        commands.append(self._launch("finish", threads, [p, m.surfaces, m.physics, c, outputs], True))
        commands.append(self._launch("end_step", shots, [p, c], True))
        return commands

    def _block(self, commands):
        if self.graph is not None:
            wp.capture_launch(self.graph)
            return
        if self.device.is_cuda:
            with wp.ScopedCapture(device=self.device) as capture:
                for _ in range(self.block_steps):
                    for command in commands:
                        command.launch()
            self.graph = capture.graph
            wp.capture_launch(self.graph)
            return
        for _ in range(1 if self.fused else self.block_steps):
            for command in commands:
                command.launch()

    def run(self, first_index: int, shots: int, source, outputs, frames=None):
        """Launch `shots` whole shots (global pellet index `first_index` on), step them until no
        pair can touch again, and leave the release state in `self.cloud` for the core kernel.
        `frames(step, time, positions)` receives trajectory frames (single-shot runs)."""
        pellets = shots * self.count
        c, p = self.cloud, self.pair
        self.threads = self._threads(pellets)
        self.shots = shots
        self._outputs = outputs
        self._launch("launch", self.threads, [first_index, p, source, c, outputs])
        self._launch("drift", shots, [p, self.model.surfaces, self.model.physics, c])
        if not self.cell_lists:
            self._launch("groups", pellets, [p, self.groups])
        if self.cell_lists and self.fused and self.ONE_LAUNCH_ON_CPU and frames is None:
            self._whole_phase()
        else:
            self._host_loop(pellets, shots, outputs, frames)
        self._launch("release", self.threads, [p, self.model.physics, c])
        self._launch("shot_totals", shots, [p, c, self.totals])

    # the CPU's one-launch dense phase takes about this many pellets' shots a launch (about a
    # second), so that Ctrl-C and SIGTERM are seen within about a second, not at the chunk's end
    PHASE_PELLETS = 4096

    def _whole_phase(self):
        """The CPU, without trajectory frames: the dense phase of a group of shots is one launch
        of phase_kernel (again after a list overflowed, with longer lists)."""
        m, c = self.model, self.cloud
        c.flags.zero_()
        group = max(1, self.PHASE_PELLETS // self.count)
        first = 0
        while first < self.shots:
            end = min(first + group, self.shots)
            self._launch("phase", 1, [first, end, self.block_steps, self.rounds, self.pair, m.surfaces, m.physics, c,
                                      self._outputs, self.bucket_end, self.rows, self.cells])
            if not self._grew_lists():  # (else the same group again: its shots before the overflow are done)
                first = end

    def _host_loop(self, pellets, shots, outputs, frames):
        """Checkpoints, rebuilds and blocks of steps launched from the host (CUDA; the CPU with
        frames, or with wp.HashGrid's lists)."""
        c = self.cloud
        self._record()
        self._rebuild(pellets)
        commands = self._step_commands(pellets, shots, outputs)
        self.graph = None
        while True:
            flags = self._checkpoint()  # host syncs: here, at checkpoints, and one per rebuild
            if frames is not None:
                frames(self, pellets)
            if flags[FLAG_REMAINING] == 0:
                break
            c.flags.zero_()
            if flags[FLAG_STALL]:
                if flags[FLAG_WIDENED]:  # the grid's cells follow the widest reach (a shot's skin widened)
                    self.reach = 2.0 * self.model.radius + 2.0 * float(c.widest_half_skin.numpy()[0])
                if self._rebuild(pellets):
                    commands = self._step_commands(pellets, shots, outputs)
                    self.graph = None
            self._block(commands)


HASH_GRID_BYTES = 48  # wp.HashGrid per point: cell, id (4 B each) and grouped key (8 B), each x2 (sort scratch) x1.5 (headroom)


def dense_bytes_per_pellet(precision: str, max_neighbours: int) -> int:
    """Bytes per pellet of the dense phase's CUDA arrays (the chunk plan on a GPU), release
    outputs included: 17 vectors, 9 scalars, 12 integers (the grid's group among them), the
    neighbour list, and wp.HashGrid's per-point buffers."""
    size = 4 if precision == "float32" else 8
    return 3 * size * 17 + size * 9 + 4 * (12 + max_neighbours) + HASH_GRID_BYTES


CPU_CHUNK_PELLETS = 1 << 20  # CPU: pellets per chunk of the dense phase


def plan_shots(scene, device, shots: int) -> int:
    """Shots per chunk on `device` (a Warp device): whole statistics segments of slots (so
    statistics do not depend on it), within the device memory budget (or numerics.chunk_size
    pellets)."""
    from .api import DEVICE_FRACTION

    count = scene.shot.count
    granule = shot_granule(count)
    if scene.numerics.chunk_size:
        pellets = scene.numerics.chunk_size
    elif device.is_cuda:
        pellets = int(DEVICE_FRACTION * device.free_memory
                      / (dense_bytes_per_pellet(scene.numerics.precision, scene.collisions.max_neighbours) + 64))
    else:
        pellets = CPU_CHUNK_PELLETS
    per_chunk = max(granule, (max(pellets // count, 1) // granule) * granule)
    return min(per_chunk, shots)


def _frame_recorder(writer, every: int):
    """H5MD trajectory frames: each checkpoint's positions, to the writer's frame datasets (made
    with the file, before it is readable while written: SWMR creates no objects)."""
    import numpy as np

    def record(dense, n):
        cloud = dense.cloud
        clock = cloud.clock.numpy()[0]
        steps = int(clock[CLOCK_STEPS])
        if steps % every or steps == writer.last_frame_step:
            return  # a block cut short by a list rebuild: not a frame
        now = float(clock[CLOCK_TIME])
        x, v, t = cloud.position.numpy()[:n], cloud.velocity.numpy()[:n], cloud.time.numpy()[:n]
        flying = cloud.phase.numpy()[:n] == FLYING
        g = np.asarray(dense.model.physics.gravity, np.float64)
        age = np.where(flying, now - t, 0.0)[:, None]
        writer.append_frame(steps, now, x + v * age + 0.5 * g * age**2)

    return record


def run_collision_scene(scene, model, *, writer=None, progress=None, source=None) -> dict:
    """`api.run_scene` for scenes with pellet-pellet collisions: per chunk of whole shots, the
    dense phase, then the core kernel continuing every pellet from its release state. A writer
    reopened by `--resume` (rows already complete: whole chunks of whole shots) brings the
    statistics partials and per-shot totals of those chunks; the run goes on from the next shot."""
    import numpy as np

    from .api import CUDA_BLOCK_DIM, LANES, Source, _HostSlot, source_struct
    from .kernels import ricochet_kernel_for
    from .model import FIELD_SPECS, State, threads_for
    from .stats import NUM_EXTREMES, NUM_SUMS, combine, empty_totals, finalize

    source = source or Source.from_scene(scene)
    count = scene.shot.count
    pellets = source.count
    shots = pellets // count
    stride = shot_stride(count)
    fields = writer.fields if writer is not None else ()
    core_fields = tuple(f for f in fields if FIELD_SPECS[f][0] is not None)
    release_fields = tuple(f for f in fields if FIELD_SPECS[f][0] is None)
    per_chunk = plan_shots(scene, model.device, shots)
    dev = model.device
    state = State(model, per_chunk * stride, core_fields)
    dense = DensePhase(model, scene, per_chunk * count, write_outputs=bool(core_fields),
                       from_file=source.arrays is not None, release_fields=release_fields)
    kern = model.kernels
    src = source_struct(scene, model)
    explicit = None
    if source.arrays is not None:
        explicit = {k: wp.empty(per_chunk * count, dtype=kern.vec3, device=dev) for k in ("position", "velocity", "angular_velocity")}
        src.position, src.velocity, src.angular_velocity = (explicit[k] for k in ("position", "velocity", "angular_velocity"))
    ricochet_kernel = ricochet_kernel_for(model.precision, bool(core_fields), False, model.bounces, len(scene.surfaces),
                                          fast_math=scene.numerics.fast_math and model.precision == "float32",
                                          from_release=True)
    slot = _HostSlot(wp, state, pinned=dev.is_cuda, index=0)
    frames = None
    if scene.collisions.frame_every and writer is not None:
        frames = _frame_recorder(writer, scene.collisions.frame_every)
    totals = empty_totals()
    shot_totals = []
    done = 0
    if writer is not None and writer.rows:  # resuming: the whole chunks written, and their partials
        done = writer.rows
        totals = combine(totals, writer.completed_segment_results())
        shot_totals.append(writer.completed_shot_totals())
    for first_shot in range(done // count, shots, per_chunk):
        chunk_shots = min(per_chunk, shots - first_shot)
        rows = chunk_shots * count
        slots = chunk_shots * stride
        start = first_shot * count
        if explicit is not None:
            for key, arr in explicit.items():
                arr[:rows].assign(np.ascontiguousarray(source.arrays[key][start : start + rows], dtype=np.dtype(model.precision)))
        dense.run(start, chunk_shots, src, state.outputs, frames=frames)
        threads = threads_for(slots)
        segments = threads // LANES
        wp.launch(ricochet_kernel, dim=threads, inputs=[0, slots, src, model.surfaces, model.physics, state.outputs, dense.cloud],
                  outputs=[state.partial_sums, state.partial_min, state.partial_max], device=dev, block_dim=CUDA_BLOCK_DIM)
        wp.launch(kern.reduce_kernel, dim=(segments, NUM_SUMS + NUM_EXTREMES),
                  inputs=[state.partial_sums, state.partial_min, state.partial_max], outputs=[state.segments], device=dev)
        segment_results = state.segments[:segments].numpy().copy()  # (only the rows used cross to the host)
        totals = combine(totals, segment_results)
        chunk_totals = dense.totals[:chunk_shots].numpy().copy()
        shot_totals.append(chunk_totals)
        if writer is not None:
            for name, arr in state.arrays.items():
                wp.copy(slot.arrays[name], arr, count=rows * (arr.size // arr.shape[0]))
            wp.synchronize_device(dev)
            arrays = {name: slot.arrays[name][:rows].numpy() for name in state.arrays}
            for name, arr in dense.field_arrays.items():
                arrays[name] = arr[:rows].numpy()
            writer.append(arrays, rows, segment_results, chunk_totals)
        done += rows
        if progress is not None:
            progress(done, pellets)
    stats = finalize(totals, pellets=pellets, mass=model.mass, inertia=model.inertia)
    table = np.concatenate(shot_totals)
    stats.update(collision_statistics(table, pellets, dense))
    if stats["skin_overrun_max"] > OVERRUN_TOLERANCE:
        import warnings

        from .api import PrecisionWarning

        warnings.warn(SKIN_OVERRUN.format(stats["skin_overrun_max"]), PrecisionWarning, stacklevel=3)
    return stats


# before the step ended at the earliest skin exit, seen on the paper's shot on a surface of
# restitution 0.9 (1.24 half skins); since then only a planted one (tests)
SKIN_OVERRUN = ("a pellet moved {:.2f} half skins between neighbour-list builds (an event in a step, such as a plane "
                "rebound, made it faster than the step allowed for): a pair contact beyond the lists could have been "
                "missed; lower collisions.step_fraction, raise collisions.skin, or set a collisions.time_step short "
                "enough for the rebound speed (docs/collisions.md)")


def collision_statistics(table, pellets: int, dense) -> dict:
    """Per-shot totals (shot order) -> the run's collision statistics; sums with math.fsum
    (exact, so they do not depend on how shots were chunked)."""
    collided = math.fsum(table[:, 0])
    return {
        "collided_fraction": collided / pellets,
        "pair_collisions": math.fsum(table[:, 1]) / 2.0,
        "pair_energy_lost": math.fsum(table[:, 2]),
        "pair_energy_lost_mean": math.fsum(table[:, 2]) / pellets,
        "dense_steps_max": float(table[:, 3].max()),
        "dense_time_max": float(table[:, 4].max()),
        "dense_steps_mean": math.fsum(table[:, 3]) / len(table),
        "dense_time_mean": math.fsum(table[:, 4]) / len(table),
        "skin_overrun_max": float(table[:, 5].max()),
    }
