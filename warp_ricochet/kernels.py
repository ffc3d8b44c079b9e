"""Warp kernels: thin loops over pellets that call the laws of `impact_law`, `flight`, `sampling`.

- `types_for(precision)`: the structs (surfaces, physics, launch source, outputs);
- `ricochet_kernel_for(precision, write_outputs, from_file)`: the whole no-collision pipeline
  per pellet: launch state (sampled or given), exact flight to the first surface, up to
  `bounces` impacts, exact flight to the landing, optional per-pellet writes, and per-thread
  partial statistics; specialised at code generation so a statistics-only kernel carries none
  of the output code;
- `kernels_for(precision)`: `reduce_kernel` (sums the per-thread partials of each segment in
  lane order) and `impact_kernel` (the impact law on given states, for `warp_ricochet.impact`).

Per thread, sums are accumulated in the working precision (float32 by default: at most
PER_THREAD = 256 terms, so a relative rounding error of order 1e-6) and counts in int32; they are
widened to float64 once per thread, and float64 from there on.

Threads and segments: thread t works on LANES consecutive-lane pellets at a time, so a warp
touches consecutive pellets (coalesced), and handles PER_THREAD of them. A segment is the
SEGMENT = LANES * PER_THREAD pellets of one group of LANES threads. Chunks start on segment
boundaries, so segment k always holds the same pellets and the reduction order (pellet order
within a thread, lane order within a segment, segment order on the host) is independent of the
chunk size.
"""


import functools
import math
from types import SimpleNamespace

import warp as wp

from .flight import EPSILON, ROUNDING, make_flight
from .impact_law import make_impact_law
from .sampling import make_sampler
from .stats import NUM_COUNTS, NUM_EXTREMES, NUM_FLOATS, NUM_SUMS, SUM

LANES = 256
PER_THREAD = 256
SEGMENT = LANES * PER_THREAD

SCALARS = {"float32": wp.float32, "float64": wp.float64}


@functools.cache
def types_for(precision: str) -> SimpleNamespace:
    """The scalar, vector and struct types of one precision ("float32" or "float64")."""
    scalar = SCALARS[precision]
    vec3 = wp.types.vector(3, scalar)

    @wp.struct
    class Surfaces:
        """Planes: a point (m), the unit normal towards the pellets, E, mu_s, mu_d."""

        point: wp.array(dtype=vec3)
        normal: wp.array(dtype=vec3)
        restitution: wp.array(dtype=scalar)
        mu_s: wp.array(dtype=scalar)
        mu_d: wp.array(dtype=scalar)

    @wp.struct
    class Physics:
        radius: scalar  # m
        inertia_factor: scalar  # I / (m R^2)
        gravity: vec3  # m/s^2
        impact_duration: scalar  # s, the paper's delta t

    @wp.struct
    class Source:
        """Launch states: sampled from the seed, or (from_file) read from the arrays."""

        seed: wp.int32
        speed: scalar
        direction: vec3
        jitter: vec3
        envelope_center: vec3
        envelope_radius: scalar
        spin: vec3
        position: wp.array(dtype=vec3)  # chunk-local explicit states (empty when sampling)
        velocity: wp.array(dtype=vec3)
        angular_velocity: wp.array(dtype=vec3)

    @wp.struct
    class Outputs:
        """Per-pellet results (chunk-local rows); an empty array is not written."""

        initial_position: wp.array(dtype=vec3)
        initial_velocity: wp.array(dtype=vec3)
        initial_angular_velocity: wp.array(dtype=vec3)
        impact_time: wp.array2d(dtype=scalar)  # (pellets, bounces)
        impact_position: wp.array2d(dtype=vec3)
        impact_velocity_before: wp.array2d(dtype=vec3)
        impact_angular_velocity_before: wp.array2d(dtype=vec3)
        impact_velocity: wp.array2d(dtype=vec3)
        impact_angular_velocity: wp.array2d(dtype=vec3)
        impact_slipped: wp.array2d(dtype=wp.int8)
        impact_surface: wp.array2d(dtype=wp.int16)
        landing_time: wp.array(dtype=scalar)
        landing_position: wp.array(dtype=vec3)
        landing_velocity: wp.array(dtype=vec3)
        landing_range: wp.array(dtype=scalar)
        landing_surface: wp.array(dtype=wp.int16)

    @wp.struct
    class Cloud:
        """Per-pellet and per-shot arrays of the dense phase (`collisions`). Each pellet's state is
        a reference state (position, velocity at `time`), valid until its next event: the core
        kernel continues from it exactly as from a launch."""

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
        # each pellet's earliest event (plane or listed pair), kept until it or a neighbour changes
        event_time: wp.array(dtype=scalar)  # s since launch
        event_partner: wp.array(dtype=wp.int32)  # pellet row, -2 - plane, -1 none
        event_exit: wp.array(dtype=scalar)  # s: when the pellet would leave its skin after that event
        stale: wp.array(dtype=wp.int32)  # 1: the event above must be found again
        round_applied: wp.array(dtype=wp.int32)  # (rounds,) 1: round r of this step applied an event
        # states at a shot's checkpoint (horizon_kernel: each is read by O(count) pairs)
        now_position: wp.array(dtype=vec3)
        now_velocity: wp.array(dtype=vec3)
        now_speed: wp.array(dtype=scalar)
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
        release_last_collision: wp.array(dtype=scalar)
        # shots
        drift_origin: wp.array(dtype=vec3)
        drift_velocity: wp.array(dtype=vec3)
        clock: wp.array2d(dtype=scalar)  # (shots, NUM_CLOCK)
        shot_flags: wp.array2d(dtype=wp.int32)
        flags: wp.array(dtype=wp.int32)
        step_travel: wp.array(dtype=scalar)  # (shots,) m: the most a pellet moves in one step relative to its frame, when beyond half the skin
        half_skin: wp.array(dtype=scalar)  # (shots,) m: the shot's half skin (widened for a fixed step that outruns it)
        widest_half_skin: wp.array(dtype=scalar)  # (1,) m: the widest of them (the grid's cells)
        # slot -> pellet of the core kernel's release mode: slot s * stride + k is pellet s * count + k
        shot_count: wp.int32
        shot_stride: wp.int32

    @wp.struct
    class Pair:
        """Pellet-pellet law and stepping parameters (SI)."""

        count: wp.int32  # pellets per shot
        mass: scalar  # kg
        inertia: scalar  # kg m^2
        restitution: scalar
        mu_s: scalar
        mu_d: scalar
        contact_duration: scalar  # s, TC model
        fixed_step: scalar  # s, 0: adaptive
        step_fraction: scalar
        half_skin: scalar  # m, the configured one (a shot's own may widen: Cloud.half_skin)
        max_steps: scalar
        block_steps: wp.int32  # a shot's checkpoints (settling, frames) are every this many of its steps
        pellets: wp.int32  # pellets launched (rows [0, pellets))
        span: wp.int32  # pellets per thread of the per-pellet kernels: 1 on CUDA, many on the CPU

    return SimpleNamespace(scalar=scalar, vec3=vec3, Surfaces=Surfaces, Physics=Physics, Source=Source, Outputs=Outputs,
                           Cloud=Cloud, Pair=Pair)


@functools.cache
def output_writers_for(precision: str):
    """`write_impact` and `mark_missing`: the per-bounce impact outputs of one pellet (rows of
    Outputs; an empty array is not written), shared by the ricochet kernel and the dense phase."""
    t = types_for(precision)
    scalar, vec3, Outputs = t.scalar, t.vec3, t.Outputs

    @wp.func
    def write_impact(out: Outputs, row: wp.int32, bounce: wp.int32, time: scalar, position: vec3,
                     velocity_before: vec3, angular_velocity_before: vec3, velocity: vec3, angular_velocity: vec3,
                     slipped: wp.int32, surface: wp.int32):
        if out.impact_time.shape[0] > 0:
            out.impact_time[row, bounce] = time
        if out.impact_position.shape[0] > 0:
            out.impact_position[row, bounce] = position
        if out.impact_velocity_before.shape[0] > 0:
            out.impact_velocity_before[row, bounce] = velocity_before
        if out.impact_angular_velocity_before.shape[0] > 0:
            out.impact_angular_velocity_before[row, bounce] = angular_velocity_before
        if out.impact_velocity.shape[0] > 0:
            out.impact_velocity[row, bounce] = velocity
        if out.impact_angular_velocity.shape[0] > 0:
            out.impact_angular_velocity[row, bounce] = angular_velocity
        if out.impact_slipped.shape[0] > 0:
            out.impact_slipped[row, bounce] = wp.int8(slipped)
        if out.impact_surface.shape[0] > 0:
            out.impact_surface[row, bounce] = wp.int16(surface)

    @wp.func
    def mark_missing(out: Outputs, row: wp.int32, bounce: wp.int32):
        """No impact at this bounce: NaN states, slipped and surface -1."""
        missing = vec3(scalar(wp.nan))
        write_impact(out, row, bounce, scalar(wp.nan), missing, missing, missing, missing, missing, -1, -1)

    return write_impact, mark_missing


@functools.cache
def launch_funcs_for(precision: str, from_file: bool):
    """`launch_state` (a pellet's launch: given in the pellet file, or sampled from its global
    index) and `write_initial` (its initial outputs), shared by the ricochet kernel and the dense
    phase, so both launch exactly the same pellets."""
    t = types_for(precision)
    scalar, vec3, Source, Outputs = t.scalar, t.vec3, t.Source, t.Outputs
    sample_pellet = make_sampler(scalar)
    FROM_FILE = from_file

    @wp.func
    def launch_state(source: Source, index: wp.int32, row: wp.int32):
        """Position (m), velocity (m/s), angular velocity (rad/s) of global pellet `index` at `row`."""
        position = vec3()
        velocity = vec3()
        spin = vec3()
        if wp.static(FROM_FILE):
            position = source.position[row]
            velocity = source.velocity[row]
            spin = source.angular_velocity[row]
        else:
            position, velocity, spin = sample_pellet(
                source.seed, index, source.speed, source.direction, source.jitter,
                source.envelope_center, source.envelope_radius, source.spin,
            )
        return position, velocity, spin

    @wp.func
    def write_initial(out: Outputs, row: wp.int32, position: vec3, velocity: vec3, spin: vec3):
        if out.initial_position.shape[0] > 0:
            out.initial_position[row] = position
        if out.initial_velocity.shape[0] > 0:
            out.initial_velocity[row] = velocity
        if out.initial_angular_velocity.shape[0] > 0:
            out.initial_angular_velocity[row] = spin

    return launch_state, write_initial


# Register cap of the CUDA ricochet kernel per (precision, fast_math) (None: the compiler's
# choice), chosen by measurement on an H200 (`python -m bench.variants`, bench/results/): 80 for
# float32 with IEEE maths (more resident warps outweigh a few spills); none with fast maths (2.36 to
# 2.38 ms for 1e8 pellets, against 2.46 at 96 and 2.91 to 2.97 at 80) and for float64 (a cap spills).
CUDA_MAX_REGISTERS = {("float32", False): 80, ("float32", True): None, ("float64", False): None, ("float64", True): None}
MAX_STATIC_PLANES = 4  # scenes with more planes loop over them at run time
CUDA_BLOCK_DIM = 256  # threads per CUDA block of the ricochet kernel (64, 128: no faster, variants-blocks.txt)


@functools.cache
def ricochet_kernel_for(precision: str, write_outputs: bool, from_file: bool, bounces: int, planes: int,
                        max_registers="default", fast_math=False, from_release=False):
    """The fused ricochet kernel, specialised at code generation (`wp.static`): without
    `write_outputs` it holds no per-pellet output code at all (statistics-only runs); it reads
    launch states from arrays only `from_file`; its loops over `bounces` and (up to
    MAX_STATIC_PLANES) `planes` are unrolled. Fewer live values and branches, more threads per SM.

    `from_release`: each pellet continues from where the dense phase of `collisions` left it
    (its reference state, impacts made, flight ended or not); threads run over the slots of the
    shot-padded layout (`Cloud.shot_stride` slots per shot), so statistics segments hold whole
    shots and the statistics do not depend on the chunk size.
    """
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics, Source, Outputs = t.scalar, t.vec3, t.Surfaces, t.Physics, t.Source, t.Outputs
    Cloud = t.Cloud
    RELEASE = from_release
    floats_t = wp.types.vector(NUM_FLOATS, scalar)
    extremes_t = wp.types.vector(NUM_EXTREMES, scalar)
    impact_law = make_impact_law(scalar)
    static_planes = planes if planes <= MAX_STATIC_PLANES else None
    _entry, _return, next_contact, ballistic_position, ballistic_velocity = make_flight(scalar, static_planes)
    launch_state, write_initial = launch_funcs_for(precision, from_file)
    write_impact, mark_missing = output_writers_for(precision)
    BOUNCES = bounces

    # constants captured by the kernel: offsets into the float accumulator (counts are separate)
    F_PRE, F_POST = SUM["vt_pre"] - NUM_COUNTS, SUM["vt_post"] - NUM_COUNTS  # vt, vn, wx, wy, wz, v2, w2
    F_V2_LAUNCH, F_W2_LAUNCH = SUM["v2_launch"] - NUM_COUNTS, SUM["w2_launch"] - NUM_COUNTS
    F_RANGE, F_RANGE2 = SUM["range"] - NUM_COUNTS, SUM["range_m2"] - NUM_COUNTS  # deviations from the thread's first range
    F_RANGE_STICK, F_RANGE_SLIP = SUM["range_stick"] - NUM_COUNTS, SUM["range_slip"] - NUM_COUNTS
    F_TIME_ALOFT, F_V2_LANDING = SUM["time_aloft"] - NUM_COUNTS, SUM["v2_landing"] - NUM_COUNTS
    WRITE = write_outputs
    FLYING, ESCAPED, RESTING = 0, 1, 2
    CLOSING_TOLERANCE2 = scalar((ROUNDING * EPSILON[precision]) ** 2)  # normal speeds within rounding of 0
    lanes, per_thread, segment = LANES, PER_THREAD, SEGMENT
    num_counts, num_floats, num_extremes = NUM_COUNTS, NUM_FLOATS, NUM_EXTREMES
    inf = scalar(math.inf)
    cap = CUDA_MAX_REGISTERS[precision, bool(fast_math)] if max_registers == "default" else max_registers
    kernel_options = {} if cap is None else {"cuda_max_registers": cap}
    if fast_math:
        kernel_options["module_options"] = {"fast_math": True}

    @wp.func
    def add_impact_sums(acc: floats_t, base: wp.int32, velocity: vec3, angular_velocity: vec3, normal: vec3):
        """Accumulate vt, vn, omega, |v|^2, |omega|^2 of one pellet at `base` (a constant)."""
        vn = wp.dot(velocity, normal)
        acc[base + 0] += wp.length(velocity - vn * normal)
        acc[base + 1] += vn
        acc[base + 2] += angular_velocity[0]
        acc[base + 3] += angular_velocity[1]
        acc[base + 4] += angular_velocity[2]
        acc[base + 5] += wp.dot(velocity, velocity)
        acc[base + 6] += wp.dot(angular_velocity, angular_velocity)
        return acc

    @wp.func
    def ricochet_pellet(
        index: wp.int32,  # global pellet index (RNG stream)
        row: wp.int32,  # chunk-local row
        source: Source,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
        cloud: Cloud,
        counts: wp.vec4i,  # hits, slip, landed, landed_slip
        acc: floats_t,
        lo: extremes_t,
        hi: extremes_t,
        range_shift: scalar,  # the thread's first range: range sums are of deviations from it
    ):
        """Follow one pellet from launch to landing; returns the updated partial statistics."""
        position = vec3()
        velocity = vec3()
        spin = vec3()
        if wp.static(RELEASE):
            position = cloud.position[row]
            velocity = cloud.velocity[row]
            spin = cloud.angular_velocity[row]
        else:
            position, velocity, spin = launch_state(source, index, row)
        if wp.static(WRITE and not RELEASE):  # (the dense phase wrote them)
            write_initial(out, row, position, velocity, spin)
        launch_v2 = wp.dot(velocity, velocity)
        launch_w2 = wp.dot(spin, spin)

        gravity = physics.gravity
        radius = physics.radius
        time = scalar(0.0)
        touching = wp.int32(-1)
        ricochet_point = vec3()
        ricochet_time = scalar(0.0)
        last_slipped = wp.int32(0)
        impacts = wp.int32(0)
        # FLYING, ESCAPED (never meets a surface again), RESTING (met one without closing speed:
        # it stays on it, the flight ends there; not an impact)
        flight_state = wp.int32(FLYING)
        resting_surface = wp.int32(-1)
        if wp.static(RELEASE):
            launch_velocity = cloud.launch_velocity[row]
            launch_spin = cloud.launch_angular_velocity[row]
            launch_v2 = wp.dot(launch_velocity, launch_velocity)
            launch_w2 = wp.dot(launch_spin, launch_spin)
            time = cloud.time[row]
            touching = cloud.touching[row]
            ricochet_point = cloud.ricochet_point[row]
            ricochet_time = cloud.ricochet_time[row]
            last_slipped = cloud.last_slipped[row]
            impacts = cloud.impacts[row]
            if cloud.phase[row] != 0:  # its flight ended in the dense phase, on end_surface
                flight_state = RESTING
                resting_surface = cloud.end_surface[row]
            if impacts > 0:  # the first impact happened in the dense phase
                first_normal = surfaces.normal[cloud.first_surface[row]]
                counts[0] += 1
                counts[1] += cloud.first_slipped[row]
                acc = add_impact_sums(acc, F_PRE, cloud.first_velocity_before[row], cloud.first_angular_velocity_before[row], first_normal)
                acc = add_impact_sums(acc, F_POST, cloud.first_velocity_after[row], cloud.first_angular_velocity_after[row], first_normal)
                acc[F_V2_LAUNCH] += launch_v2
                acc[F_W2_LAUNCH] += launch_w2
        start_impacts = impacts
        for bounce in range(wp.static(BOUNCES)):  # unrolled (bounces <= 16)
            impacted = wp.int32(0)
            if flight_state == FLYING and bounce >= start_impacts:
                dt, k = next_contact(position, velocity, gravity, radius, surfaces.point, surfaces.normal, touching)
                if k < 0:
                    flight_state = ESCAPED
                else:
                    normal = surfaces.normal[k]
                    position = ballistic_position(position, velocity, gravity, dt)
                    velocity = ballistic_velocity(velocity, gravity, dt)
                    time = time + dt
                    # closing only beyond rounding noise (an overlapping pellet meets the plane at its
                    # apex, where v_n is 0 give or take an FMA): else it rests on the surface
                    normal_speed = wp.dot(velocity, normal)
                    if normal_speed >= scalar(0.0) or normal_speed * normal_speed <= CLOSING_TOLERANCE2 * wp.dot(velocity, velocity):
                        flight_state = RESTING
                        resting_surface = k
                    else:
                        impacted = 1
                        velocity_after, spin_after, slipped = impact_law(
                            velocity, spin, normal, radius, physics.inertia_factor,
                            surfaces.restitution[k], surfaces.mu_s[k], surfaces.mu_d[k],
                            wp.dot(gravity, normal) * physics.impact_duration,
                        )
                        if wp.static(WRITE):
                            write_impact(out, row, bounce, time, position, velocity, spin, velocity_after, spin_after,
                                         slipped, k)
                        if bounce == 0:
                            counts[0] += 1
                            counts[1] += slipped
                            acc = add_impact_sums(acc, F_PRE, velocity, spin, normal)
                            acc = add_impact_sums(acc, F_POST, velocity_after, spin_after, normal)
                            acc[F_V2_LAUNCH] += launch_v2
                            acc[F_W2_LAUNCH] += launch_w2
                        speed_before2 = wp.dot(velocity, velocity)
                        velocity = velocity_after
                        spin = spin_after
                        touching = k
                        impacts = impacts + 1
                        last_slipped = slipped
                        ricochet_point = position - radius * normal
                        ricochet_time = time
                        # leaving with no normal speed (E = 0, up to rounding of the speed before the
                        # impact, not of the residue left): it stays on the surface
                        leaving_speed = wp.dot(velocity, normal)
                        if leaving_speed * leaving_speed <= CLOSING_TOLERANCE2 * speed_before2:
                            flight_state = RESTING
                            resting_surface = k
            if wp.static(WRITE):
                if impacted == 0 and bounce >= start_impacts:  # no impact at this bounce: mark it missing
                    mark_missing(out, row, bounce)

        # landing, after at least one ricochet: where the flight ended on a surface (resting), or
        # the next surface met after the last of `bounces` ricochets
        landing_time = scalar(wp.inf)
        landing_position = vec3(scalar(wp.nan))
        landing_velocity = vec3(scalar(wp.nan))
        landing_range = scalar(wp.nan)
        landing_surface = wp.int32(-1)
        if impacts > 0 and flight_state != ESCAPED:
            k = resting_surface
            if flight_state == FLYING:
                dt, k = next_contact(position, velocity, gravity, radius, surfaces.point, surfaces.normal, touching)
                if k >= 0:
                    position = ballistic_position(position, velocity, gravity, dt)
                    velocity = ballistic_velocity(velocity, gravity, dt)
                    time = time + dt
            if k >= 0:
                landing_surface = k
                landing_time = time
                landing_position = position
                landing_velocity = velocity
                # eq. (42): distance from the ricochet point to the landing point (contact points)
                landing_range = wp.length(landing_position - radius * surfaces.normal[k] - ricochet_point)
                counts[2] += 1
                if counts[2] == 1:
                    range_shift = landing_range
                deviation = landing_range - range_shift
                acc[F_RANGE] += deviation
                acc[F_RANGE2] += deviation * deviation
                acc[F_TIME_ALOFT] += time - ricochet_time
                acc[F_V2_LANDING] += wp.dot(landing_velocity, landing_velocity)
                lo[0] = wp.min(lo[0], landing_range)
                hi[0] = wp.max(hi[0], landing_range)
                if last_slipped != 0:
                    counts[3] += 1
                    acc[F_RANGE_SLIP] += landing_range
                    lo[2] = wp.min(lo[2], landing_range)
                    hi[2] = wp.max(hi[2], landing_range)
                else:
                    acc[F_RANGE_STICK] += landing_range
                    lo[1] = wp.min(lo[1], landing_range)
                    hi[1] = wp.max(hi[1], landing_range)
        if wp.static(WRITE):
            if out.landing_time.shape[0] > 0:
                out.landing_time[row] = landing_time
            if out.landing_position.shape[0] > 0:
                out.landing_position[row] = landing_position
            if out.landing_velocity.shape[0] > 0:
                out.landing_velocity[row] = landing_velocity
            if out.landing_range.shape[0] > 0:
                out.landing_range[row] = landing_range
            if out.landing_surface.shape[0] > 0:
                out.landing_surface[row] = wp.int16(landing_surface)
        return counts, acc, lo, hi, range_shift

    @wp.kernel(module="unique", enable_backward=False, **kernel_options)
    def ricochet_kernel(
        first_index: wp.int32,  # global index of the chunk's first pellet (a multiple of SEGMENT)
        count: wp.int32,  # pellets in the chunk
        source: Source,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
        cloud: Cloud,  # the dense phase's release state (from_release), else empty
        partial_sums: wp.array2d(dtype=wp.float64),  # (NUM_SUMS, threads): counts, then floats
        partial_min: wp.array2d(dtype=wp.float64),  # (NUM_EXTREMES, threads)
        partial_max: wp.array2d(dtype=wp.float64),
    ):
        tid = wp.tid()
        group = tid // lanes
        lane = tid - group * lanes
        counts = wp.vec4i()
        acc = floats_t()
        lo = extremes_t(inf)
        hi = extremes_t(-inf)
        range_shift = scalar(0.0)
        for j in range(per_thread):
            row = group * segment + j * lanes + lane
            if row < count:
                if wp.static(RELEASE):  # slot -> pellet; padding slots hold none
                    shot = row / cloud.shot_stride
                    member = row - shot * cloud.shot_stride
                    if member < cloud.shot_count:
                        counts, acc, lo, hi, range_shift = ricochet_pellet(
                            0, shot * cloud.shot_count + member, source, surfaces, physics, out, cloud,
                            counts, acc, lo, hi, range_shift
                        )
                else:
                    counts, acc, lo, hi, range_shift = ricochet_pellet(
                        first_index + row, row, source, surfaces, physics, out, cloud, counts, acc, lo, hi, range_shift
                    )
        # widen once per thread: float64 from here on. Ranges were summed as deviations from the
        # thread's first range: the range row gets the plain sum back, the m2 row the squared
        # deviations about the thread's mean (no cancellation; merged across threads by Chan).
        for c in range(num_counts):
            partial_sums[c, tid] = wp.float64(counts[c])
        for f in range(num_floats):
            partial_sums[num_counts + f, tid] = wp.float64(acc[f])
        landed = wp.float64(counts[2])
        deviations = wp.float64(acc[F_RANGE])
        partial_sums[num_counts + F_RANGE, tid] = landed * wp.float64(range_shift) + deviations
        m2 = wp.float64(0.0)
        if counts[2] > 0:
            m2 = wp.max(wp.float64(acc[F_RANGE2]) - deviations * deviations / landed, wp.float64(0.0))
        partial_sums[num_counts + F_RANGE2, tid] = m2
        for e in range(num_extremes):
            partial_min[e, tid] = wp.float64(lo[e])
            partial_max[e, tid] = wp.float64(hi[e])

    return ricochet_kernel


@functools.cache
def kernels_for(precision: str) -> SimpleNamespace:
    """Types of `types_for` plus the kernels that do not depend on the scene: the segment
    reduction and the impact law on given states."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    impact_law = make_impact_law(scalar)
    lanes, num_sums, num_extremes = LANES, NUM_SUMS, NUM_EXTREMES
    ROW_LANDED, ROW_RANGE, ROW_M2 = SUM["landed"], SUM["range"], SUM["range_m2"]
    inf64 = wp.float64(math.inf)

    @wp.kernel(module="unique", enable_backward=False)
    def reduce_kernel(
        partial_sums: wp.array2d(dtype=wp.float64),
        partial_min: wp.array2d(dtype=wp.float64),
        partial_max: wp.array2d(dtype=wp.float64),
        segments: wp.array2d(dtype=wp.float64),  # (segments, NUM_SUMS + 2 NUM_EXTREMES): sums, minima, maxima
    ):
        """One thread per (segment, row): add the segment's LANES partials in lane order."""
        seg, row = wp.tid()
        base = seg * lanes
        if row == ROW_M2:
            # squared deviations about the segment mean: the lanes' own, plus n (mean_lane - mean)^2
            count = wp.float64(0.0)
            total = wp.float64(0.0)
            for lane in range(lanes):
                count += partial_sums[ROW_LANDED, base + lane]
                total += partial_sums[ROW_RANGE, base + lane]
            m2 = wp.float64(0.0)
            if count > wp.float64(0.0):
                mean = total / count
                for lane in range(lanes):
                    n = partial_sums[ROW_LANDED, base + lane]
                    if n > wp.float64(0.0):
                        delta = partial_sums[ROW_RANGE, base + lane] / n - mean
                        m2 += partial_sums[ROW_M2, base + lane] + n * delta * delta
            segments[seg, row] = m2
        elif row < num_sums:
            total = wp.float64(0.0)
            for lane in range(lanes):
                total += partial_sums[row, base + lane]
            segments[seg, row] = total
        else:
            e = row - num_sums
            low = inf64
            high = -inf64
            for lane in range(lanes):
                low = wp.min(low, partial_min[e, base + lane])
                high = wp.max(high, partial_max[e, base + lane])
            segments[seg, num_sums + e] = low
            segments[seg, num_sums + num_extremes + e] = high

    @wp.kernel(module="unique", enable_backward=False)
    def impact_kernel(
        velocity: wp.array(dtype=vec3),
        angular_velocity: wp.array(dtype=vec3),
        normal: wp.array(dtype=vec3),  # (1,) for one plane, else one per pellet
        radius: scalar,
        inertia_factor: scalar,
        restitution: scalar,
        mu_s: scalar,
        mu_d: scalar,
        gravity: vec3,
        impact_duration: scalar,
        velocity_after: wp.array(dtype=vec3),
        angular_velocity_after: wp.array(dtype=vec3),
        slipped: wp.array(dtype=wp.int8),
    ):
        i = wp.tid()
        n = normal[0]
        if normal.shape[0] > 1:
            n = normal[i]
        v, w, s = impact_law(
            velocity[i], angular_velocity[i], n, radius, inertia_factor, restitution, mu_s, mu_d,
            wp.dot(gravity, n) * impact_duration,
        )
        velocity_after[i] = v
        angular_velocity_after[i] = w
        slipped[i] = wp.int8(s)

    return SimpleNamespace(**vars(t), reduce_kernel=reduce_kernel, impact_kernel=impact_kernel)
