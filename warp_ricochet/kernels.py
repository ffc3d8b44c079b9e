"""Warp kernels: thin loops over pellets that call the laws of `impact_law`, `flight`, `sampling`.

`kernels_for(scalar)` builds (once per precision) the structs and kernels:

- `impact_kernel`: the impact law on given states (the `warp_ricochet.impact` API);
- `ricochet_kernel`: the whole no-collision pipeline per pellet: launch state (sampled or
  given), exact flight to the first surface, up to `bounces` impacts, exact flight to the
  landing, optional per-pellet writes, and per-thread partial statistics;
- `reduce_kernel`: sums the per-thread partials of each segment in lane order.

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

from .flight import make_flight
from .impact_law import make_impact_law
from .sampling import make_sampler
from .stats import NUM_EXTREMES, NUM_SUMS, SUM

LANES = 256
PER_THREAD = 256
SEGMENT = LANES * PER_THREAD

SCALARS = {"float32": wp.float32, "float64": wp.float64}


@functools.cache
def kernels_for(precision: str) -> SimpleNamespace:
    """Structs and kernels for "float32" or "float64"."""
    scalar = SCALARS[precision]
    vec3 = wp.types.vector(3, scalar)
    sums_t = wp.types.vector(NUM_SUMS, wp.float64)
    extremes_t = wp.types.vector(NUM_EXTREMES, wp.float64)
    impact_law = make_impact_law(scalar)
    _entry, _return, next_contact, ballistic_position, ballistic_velocity = make_flight(scalar)
    sample_pellet = make_sampler(scalar)

    # constants captured by the kernels
    S_HITS, S_STICK, S_SLIP = SUM["hits"], SUM["stick"], SUM["slip"]
    S_PRE, S_POST = SUM["vt_pre"], SUM["vt_post"]  # vt, vn, wx, wy, wz, v2, w2 follow in order
    S_V2_LAUNCH, S_W2_LAUNCH = SUM["v2_launch"], SUM["w2_launch"]
    S_LANDED, S_RANGE, S_RANGE2 = SUM["landed"], SUM["range"], SUM["range2"]
    S_LANDED_STICK, S_RANGE_STICK = SUM["landed_stick"], SUM["range_stick"]
    S_LANDED_SLIP, S_RANGE_SLIP = SUM["landed_slip"], SUM["range_slip"]
    S_TIME_ALOFT, S_V2_LANDING = SUM["time_aloft"], SUM["v2_landing"]
    lanes, per_thread, segment = LANES, PER_THREAD, SEGMENT
    num_sums, num_extremes = NUM_SUMS, NUM_EXTREMES
    inf64 = wp.float64(math.inf)

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
        bounces: wp.int32

    @wp.struct
    class Source:
        """Launch states: sampled from the seed, or read from `position` when it is not empty."""

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

    @wp.func
    def add_impact_sums(
        acc: sums_t, base: wp.int32, velocity: vec3, angular_velocity: vec3, normal: vec3
    ):
        """Accumulate vt, vn, omega, |v|^2, |omega|^2 of one pellet at `base`."""
        vn = wp.dot(velocity, normal)
        acc[base + 0] += wp.float64(wp.length(velocity - vn * normal))
        acc[base + 1] += wp.float64(vn)
        acc[base + 2] += wp.float64(angular_velocity[0])
        acc[base + 3] += wp.float64(angular_velocity[1])
        acc[base + 4] += wp.float64(angular_velocity[2])
        acc[base + 5] += wp.float64(wp.dot(velocity, velocity))
        acc[base + 6] += wp.float64(wp.dot(angular_velocity, angular_velocity))
        return acc

    @wp.func
    def ricochet_pellet(
        index: wp.int32,  # global pellet index (RNG stream)
        row: wp.int32,  # chunk-local row
        source: Source,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
        acc: sums_t,
        lo: extremes_t,
        hi: extremes_t,
    ):
        """Follow one pellet from launch to landing; returns the updated partial statistics."""
        position = vec3()
        velocity = vec3()
        spin = vec3()
        if source.position.shape[0] > 0:
            position = source.position[row]
            velocity = source.velocity[row]
            spin = source.angular_velocity[row]
        else:
            position, velocity, spin = sample_pellet(
                source.seed, index, source.speed, source.direction, source.jitter,
                source.envelope_center, source.envelope_radius, source.spin,
            )
        if out.initial_position.shape[0] > 0:
            out.initial_position[row] = position
        if out.initial_velocity.shape[0] > 0:
            out.initial_velocity[row] = velocity
        if out.initial_angular_velocity.shape[0] > 0:
            out.initial_angular_velocity[row] = spin
        launch_v2 = wp.float64(wp.dot(velocity, velocity))
        launch_w2 = wp.float64(wp.dot(spin, spin))

        gravity = physics.gravity
        radius = physics.radius
        time = scalar(0.0)
        touching = wp.int32(-1)
        impacts = wp.int32(0)
        ricochet_point = vec3()
        last_slipped = wp.int32(0)
        escaped = wp.int32(0)
        for bounce in range(physics.bounces):
            if escaped == 0:
                dt, k = next_contact(position, velocity, gravity, radius, surfaces.point, surfaces.normal, touching)
                if k < 0:
                    escaped = 1
                else:
                    normal = surfaces.normal[k]
                    position = ballistic_position(position, velocity, gravity, dt)
                    velocity = ballistic_velocity(velocity, gravity, dt)
                    time = time + dt
                    velocity_after, spin_after, slipped = impact_law(
                        velocity, spin, normal, radius, physics.inertia_factor,
                        surfaces.restitution[k], surfaces.mu_s[k], surfaces.mu_d[k],
                        wp.dot(gravity, normal) * physics.impact_duration,
                    )
                    if out.impact_time.shape[0] > 0:
                        out.impact_time[row, bounce] = time
                    if out.impact_position.shape[0] > 0:
                        out.impact_position[row, bounce] = position
                    if out.impact_velocity_before.shape[0] > 0:
                        out.impact_velocity_before[row, bounce] = velocity
                    if out.impact_angular_velocity_before.shape[0] > 0:
                        out.impact_angular_velocity_before[row, bounce] = spin
                    if out.impact_velocity.shape[0] > 0:
                        out.impact_velocity[row, bounce] = velocity_after
                    if out.impact_angular_velocity.shape[0] > 0:
                        out.impact_angular_velocity[row, bounce] = spin_after
                    if out.impact_slipped.shape[0] > 0:
                        out.impact_slipped[row, bounce] = wp.int8(slipped)
                    if out.impact_surface.shape[0] > 0:
                        out.impact_surface[row, bounce] = wp.int16(k)
                    if bounce == 0:
                        acc[S_HITS] += wp.float64(1.0)
                        acc[S_SLIP] += wp.float64(slipped)
                        acc[S_STICK] += wp.float64(1 - slipped)
                        acc = add_impact_sums(acc, S_PRE, velocity, spin, normal)
                        acc = add_impact_sums(acc, S_POST, velocity_after, spin_after, normal)
                        acc[S_V2_LAUNCH] += launch_v2
                        acc[S_W2_LAUNCH] += launch_w2
                    velocity = velocity_after
                    spin = spin_after
                    touching = k
                    impacts = impacts + 1
                    last_slipped = slipped
                    ricochet_point = position - radius * normal
            if escaped != 0:  # no impact at this bounce: mark it missing
                if out.impact_time.shape[0] > 0:
                    out.impact_time[row, bounce] = scalar(wp.nan)
                if out.impact_position.shape[0] > 0:
                    out.impact_position[row, bounce] = vec3(scalar(wp.nan))
                if out.impact_velocity_before.shape[0] > 0:
                    out.impact_velocity_before[row, bounce] = vec3(scalar(wp.nan))
                if out.impact_angular_velocity_before.shape[0] > 0:
                    out.impact_angular_velocity_before[row, bounce] = vec3(scalar(wp.nan))
                if out.impact_velocity.shape[0] > 0:
                    out.impact_velocity[row, bounce] = vec3(scalar(wp.nan))
                if out.impact_angular_velocity.shape[0] > 0:
                    out.impact_angular_velocity[row, bounce] = vec3(scalar(wp.nan))
                if out.impact_slipped.shape[0] > 0:
                    out.impact_slipped[row, bounce] = wp.int8(-1)
                if out.impact_surface.shape[0] > 0:
                    out.impact_surface[row, bounce] = wp.int16(-1)

        # landing: the next surface met after the last of `bounces` ricochets
        landing_time = scalar(wp.inf)
        landing_position = vec3(scalar(wp.nan))
        landing_velocity = vec3(scalar(wp.nan))
        landing_range = scalar(wp.nan)
        landing_surface = wp.int32(-1)
        if escaped == 0:
            dt, k = next_contact(position, velocity, gravity, radius, surfaces.point, surfaces.normal, touching)
            if k >= 0:
                landing_surface = k
                landing_time = time + dt
                landing_position = ballistic_position(position, velocity, gravity, dt)
                landing_velocity = ballistic_velocity(velocity, gravity, dt)
                # eq. (42): distance from the ricochet point to the landing point (contact points)
                landing_range = wp.length(landing_position - radius * surfaces.normal[k] - ricochet_point)
                r64 = wp.float64(landing_range)
                acc[S_LANDED] += wp.float64(1.0)
                acc[S_RANGE] += r64
                acc[S_RANGE2] += r64 * r64
                acc[S_TIME_ALOFT] += wp.float64(dt)
                acc[S_V2_LANDING] += wp.float64(wp.dot(landing_velocity, landing_velocity))
                lo[0] = wp.min(lo[0], r64)
                hi[0] = wp.max(hi[0], r64)
                if last_slipped != 0:
                    acc[S_LANDED_SLIP] += wp.float64(1.0)
                    acc[S_RANGE_SLIP] += r64
                    lo[2] = wp.min(lo[2], r64)
                    hi[2] = wp.max(hi[2], r64)
                else:
                    acc[S_LANDED_STICK] += wp.float64(1.0)
                    acc[S_RANGE_STICK] += r64
                    lo[1] = wp.min(lo[1], r64)
                    hi[1] = wp.max(hi[1], r64)
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
        return acc, lo, hi

    @wp.kernel(module="unique")
    def ricochet_kernel(
        first_index: wp.int32,  # global index of the chunk's first pellet (a multiple of SEGMENT)
        count: wp.int32,  # pellets in the chunk
        source: Source,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
        partial_sums: wp.array2d(dtype=wp.float64),  # (NUM_SUMS, threads)
        partial_min: wp.array2d(dtype=wp.float64),  # (NUM_EXTREMES, threads)
        partial_max: wp.array2d(dtype=wp.float64),
    ):
        tid = wp.tid()
        group = tid // lanes
        lane = tid - group * lanes
        acc = sums_t()
        lo = extremes_t(inf64)
        hi = extremes_t(-inf64)
        for j in range(per_thread):
            row = group * segment + j * lanes + lane
            if row < count:
                acc, lo, hi = ricochet_pellet(first_index + row, row, source, surfaces, physics, out, acc, lo, hi)
        for s in range(num_sums):
            partial_sums[s, tid] = acc[s]
        for e in range(num_extremes):
            partial_min[e, tid] = lo[e]
            partial_max[e, tid] = hi[e]

    @wp.kernel(module="unique")
    def reduce_kernel(
        partial_sums: wp.array2d(dtype=wp.float64),
        partial_min: wp.array2d(dtype=wp.float64),
        partial_max: wp.array2d(dtype=wp.float64),
        segment_sums: wp.array2d(dtype=wp.float64),  # (segments, NUM_SUMS)
        segment_min: wp.array2d(dtype=wp.float64),  # (segments, NUM_EXTREMES)
        segment_max: wp.array2d(dtype=wp.float64),
    ):
        """One thread per segment: add its LANES partials in lane order (deterministic)."""
        seg = wp.tid()
        for s in range(num_sums):
            total = wp.float64(0.0)
            for lane in range(lanes):
                total += partial_sums[s, seg * lanes + lane]
            segment_sums[seg, s] = total
        for e in range(num_extremes):
            low = inf64
            high = -inf64
            for lane in range(lanes):
                low = wp.min(low, partial_min[e, seg * lanes + lane])
                high = wp.max(high, partial_max[e, seg * lanes + lane])
            segment_min[seg, e] = low
            segment_max[seg, e] = high

    @wp.kernel(module="unique")
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

    return SimpleNamespace(
        scalar=scalar, vec3=vec3, Surfaces=Surfaces, Physics=Physics, Source=Source, Outputs=Outputs,
        ricochet_kernel=ricochet_kernel, reduce_kernel=reduce_kernel, impact_kernel=impact_kernel,
    )
