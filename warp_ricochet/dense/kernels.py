"""The dense phase's kernels: thin loops over pellets or shots that call the stage functions
(`ends`, `lists`, `step`, `rounds`, `checkpoint`). On CUDA a per-pellet kernel has one thread a
pellet; on the CPU (where a kernel runs on one thread anyway, and entering a kernel thread costs
more than a quiet pellet's step) one thread loops over all (`Pair.span`).

The per-pellet kernels of a step are capped at STEP_MAX_REGISTERS registers a CUDA thread: most
of their threads read a few flags and return, and the rare event or kick (the air laws, the
impact law) would otherwise set the register count, and so the occupancy, of all of them."""

import functools
from types import SimpleNamespace

import warp as wp

from .air import make_dense_air
from .checkpoint import make_checkpoint
from .constants import FLAG_OVERFLOW, SHOT_DONE, SHOT_LEAP, SHOT_REBUILD, SHOT_STALL
from .ends import make_ends
from .frame import make_frame
from .kit import dense_kit
from .leap import make_leap
from .lists import make_lists
from .rounds import make_rounds
from .separation import make_separation
from .step import make_step

STEP_MAX_REGISTERS = 40  # CUDA registers a thread of a step's per-pellet kernels (bench/RESULTS.md)


@functools.cache
def make_setup_kernels(spec) -> SimpleNamespace:
    """Kernels of the launch, the lists, the release and the totals."""
    kit = dense_kit(spec)
    Surfaces, Physics, Outputs, Source, Cloud, Pair = kit.Surfaces, kit.Physics, kit.Outputs, kit.Source, kit.Cloud, kit.Pair
    opts = kit.opts
    end_fns, list_fns = make_ends(spec), make_lists(spec)
    separate_shot = make_separation(spec).separate_shot

    @wp.kernel(**opts)
    def groups_kernel(pair: Pair, groups: wp.array(dtype=wp.int32)):
        """Each pellet's hash-grid group: its shot (shots never meet, however they overlap)."""
        i = wp.tid()
        groups[i] = i / pair.count

    @wp.kernel(**opts)
    def cell_lists_kernel(
        pair: Pair,
        physics: Physics,
        cloud: Cloud,
        bucket_end: wp.array(dtype=wp.int32),
        rows: wp.array(dtype=wp.int32),
        cells: wp.array(dtype=wp.vec3i),
    ):
        """The CPU's lists of every shot being rebuilt, in one launch (one thread)."""
        for s in range(pair.pellets / pair.count):
            if cloud.shot_flags[s, SHOT_REBUILD] != 0:
                list_fns.cell_lists_shot(s, pair, physics, cloud, bucket_end, rows, cells)

    @wp.kernel(**opts)
    def launch_kernel(first_index: wp.int32, pair: Pair, source: Source, cloud: Cloud, out: Outputs):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            end_fns.launch_pellet(i, first_index, source, cloud, out)

    @wp.kernel(**opts)
    def separate_kernel(
        begin: wp.int32,
        end: wp.int32,
        first_index: wp.int32,
        pair: Pair,
        physics: Physics,
        source: Source,
        cloud: Cloud,
        out: Outputs,
        redraws: wp.array(dtype=wp.int32),
        heads: wp.array(dtype=wp.int32),
        chain: wp.array(dtype=wp.int32),
    ):
        """Each shot's pellets [begin, end) without overlaps at launch (one thread a shot)."""
        separate_shot(wp.tid(), begin, end, first_index, pair, physics, source, cloud, out, redraws, heads, chain)

    @wp.kernel(**opts)
    def drift_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        end_fns.start_shot(wp.tid(), pair, surfaces, physics, cloud)

    @wp.kernel(**opts)
    def start_block_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """At the launch: each block's spread and arrivals (one thread a block of a shot)."""
        end_fns.start_block(pair, surfaces, physics, cloud, wp.tid())

    @wp.kernel(**opts)
    def window_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        end_fns.window_shot(pair, physics, cloud, wp.tid())

    @wp.kernel(**opts)
    def grid_points_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            list_fns.grid_point_pellet(i, pair, physics, cloud)

    @wp.kernel(**opts)
    def neighbours_kernel(grid: wp.uint64, pair: Pair, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            list_fns.grid_list(i, grid, pair, physics, cloud)

    @wp.kernel(**opts)
    def release_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            end_fns.release_pellet(i, pair, surfaces, physics, cloud)

    @wp.kernel(**opts)
    def trajectory_frame_kernel(physics: Physics, cloud: Cloud, points: wp.array(dtype=wp.vec3d)):
        """One thread a pellet: its centre for a trajectory frame (dense.ends.trajectory_point)."""
        end_fns.trajectory_point(wp.tid(), physics, cloud, points)

    @wp.kernel(**opts)
    def block_totals_kernel(pair: Pair, cloud: Cloud, blocks: wp.array2d(dtype=wp.float64)):
        """One thread a block of a shot (frame blocks): its collision totals."""
        end_fns.block_totals(wp.tid(), pair, cloud, blocks)

    @wp.kernel(**opts)
    def shot_totals_kernel(pair: Pair, cloud: Cloud, blocks: wp.array2d(dtype=wp.float64), totals: wp.array2d(dtype=wp.float64)):
        end_fns.shot_totals(wp.tid(), pair, cloud, blocks, totals)

    return SimpleNamespace(
        groups_kernel=groups_kernel,
        cell_lists_kernel=cell_lists_kernel,
        launch_kernel=launch_kernel,
        separate_kernel=separate_kernel,
        drift_kernel=drift_kernel,
        start_block_kernel=start_block_kernel,
        window_kernel=window_kernel,
        grid_points_kernel=grid_points_kernel,
        neighbours_kernel=neighbours_kernel,
        release_kernel=release_kernel,
        trajectory_frame_kernel=trajectory_frame_kernel,
        block_totals_kernel=block_totals_kernel,
        shot_totals_kernel=shot_totals_kernel,
    )


@functools.cache
def make_step_kernels(spec) -> SimpleNamespace:
    """Kernels of a step, of a checkpoint, and of the CPU's block and whole phase."""
    kit = dense_kit(spec)
    Surfaces, Physics, Outputs, Cloud, Pair, AIR = kit.Surfaces, kit.Physics, kit.Outputs, kit.Cloud, kit.Pair, kit.AIR
    opts = kit.opts
    hot = {**opts, "cuda_max_registers": STEP_MAX_REGISTERS}  # (ignored on the CPU)
    step_fns, round_fns, checkpoint_fns, list_fns = make_step(spec), make_rounds(spec), make_checkpoint(spec), make_lists(spec)
    frame_fns = make_frame(spec)
    air = make_dense_air(spec) if AIR else None
    leap_fns = make_leap(spec) if AIR else None

    @wp.kernel(**hot)
    def bounds_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            step_fns.bounds_pellet(i, pair, surfaces, physics, cloud)

    @wp.kernel(**hot)
    def kick_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """In air: each pellet's kick before a step, when due (dense.air)."""
        t = wp.tid()
        if wp.static(AIR):
            for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
                air.kick_pellet(i, pair, surfaces, physics, cloud)

    @wp.kernel(**opts)
    def plan_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        step_fns.plan_shot(wp.tid(), pair, physics, cloud)

    @wp.kernel(**hot)
    def prepare_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            step_fns.prepare_pellet(i, pair, physics, cloud)

    @wp.kernel(**hot)
    def choose_kernel(round: wp.int32, look: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        if round > 0 and look == 0 and cloud.event.round_applied[round - 1] == 0:
            return  # a round after one that applied nothing: no pellet is stale, every choice is the same
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            round_fns.choose_pellet(i, look, pair, surfaces, physics, cloud)

    @wp.kernel(**hot)
    def resolve_kernel(round: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        if round > 0 and cloud.event.round_applied[round - 1] == 0:
            return  # a round after one that applied nothing has nothing to apply
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            round_fns.resolve_pellet(i, round, pair, surfaces, physics, cloud, out)

    @wp.kernel(**hot)
    def finish_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            step_fns.finish_pellet(i, pair, surfaces, physics, cloud, out)

    @wp.kernel(**opts)
    def end_step_kernel(pair: Pair, cloud: Cloud):
        step_fns.end_step_shot(wp.tid(), pair, cloud)

    @wp.kernel(**opts)
    def block_kernel(
        steps: wp.int32, rounds: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs
    ):
        """The CPU's block of steps in one launch (one thread): each step is the per-step
        kernels' work in their order. A CPU kernel runs its threads one after another anyway, so
        the results are those of the per-step kernels (tested), without 14 launches a step.
        Shots never meet, so it takes them one after another, all its steps each: a shot's
        pellets stay in cache, and a shot that is done or waits costs nothing."""
        for s in range(pair.pellets / pair.count):
            step_fns.block_shot(s, steps, rounds, pair, surfaces, physics, cloud, out)

    @wp.kernel(**opts)
    def now_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            checkpoint_fns.now_pellet(i, pair, physics, cloud)

    @wp.kernel(**opts)
    def horizon_kernel(begin: wp.int32, end: wp.int32, pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud):
        """The pairs with the pellets [begin, end) after each (a piece of the horizon: `horizon_pellet`)."""
        t = wp.tid()
        for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
            checkpoint_fns.horizon_pellet(i, begin, end, pair, surfaces, physics, cloud)

    @wp.kernel(**opts)
    def settle_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        checkpoint_fns.settle_shot(wp.tid(), pair, physics, cloud)

    @wp.kernel(**opts)
    def frame_block_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        """The frame sums of each block of a shot whose frame is due (one thread a block; dense.frame)."""
        frame_fns.frame_block(pair, physics, cloud, wp.tid())

    @wp.kernel(**opts)
    def framed_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        frame_fns.framed_shot(pair, physics, cloud, wp.tid())

    @wp.kernel(**opts)
    def leap_kernel(pair: Pair, surfaces: Surfaces, physics: Physics, cloud: Cloud, out: Outputs):
        """In air: the pellets of each shot that leaps at this checkpoint fly through it (dense.leap)."""
        t = wp.tid()
        if wp.static(AIR):
            for i in range(t * pair.span, wp.min((t + 1) * pair.span, pair.pellets)):
                leap_fns.leap_pellet(i, pair, surfaces, physics, cloud, out)

    @wp.kernel(**opts)
    def leaped_kernel(pair: Pair, physics: Physics, cloud: Cloud):
        if wp.static(AIR):
            leap_fns.leaped_shot(wp.tid(), pair, physics, cloud)

    @wp.kernel(**opts)
    def phase_kernel(
        first_shot: wp.int32,
        end_shot: wp.int32,
        steps: wp.int32,
        rounds: wp.int32,
        pair: Pair,
        surfaces: Surfaces,
        physics: Physics,
        cloud: Cloud,
        out: Outputs,
        bucket_end: wp.array(dtype=wp.int32),
        rows: wp.array(dtype=wp.int32),
        cells: wp.array(dtype=wp.vec3i),
    ):
        """The CPU's whole dense phase of shots [first_shot, end_shot) in one launch (one
        thread): each shot, one after another, goes through what the host loop does with it (its
        lists, its checkpoint, a block of steps) until it is done; no host round trip between. A
        list that overflows ends the launch: the host grows the lists and launches again, and
        that shot builds its lists again first (the shots before it are done). `cloud.stop` set
        by the host (an interrupt) ends it early, at the next block, pass or pellet's horizon:
        the host then abandons the chunk."""
        for s in range(first_shot, end_shot):
            while cloud.shot_flags[s, SHOT_DONE] == 0:
                if cloud.stop[0] != 0:
                    return
                if cloud.shot_flags[s, SHOT_REBUILD] != 0:
                    list_fns.cell_lists_shot(s, pair, physics, cloud, bucket_end, rows, cells)
                    if cloud.flags[FLAG_OVERFLOW] != 0 or cloud.stop[0] != 0:
                        return
                if cloud.shot_flags[s, SHOT_STALL] != 0:
                    first = s * pair.count
                    for i in range(first, first + pair.count):
                        checkpoint_fns.now_pellet(i, pair, physics, cloud)
                    for i in range(first, first + pair.count):
                        if cloud.stop[0] != 0:  # (a pellet's horizon is O(count))
                            return
                        checkpoint_fns.horizon_pellet(i, 1, pair.count / 2 + 1, pair, surfaces, physics, cloud)
                    checkpoint_fns.settle_shot(s, pair, physics, cloud)
                    if wp.static(AIR):
                        if cloud.shot_flags[s, SHOT_LEAP] != 0:
                            for i in range(first, first + pair.count):
                                leap_fns.leap_pellet(i, pair, surfaces, physics, cloud, out)
                            leap_fns.leaped_shot(s, pair, physics, cloud)
                    frame_fns.frame_shot(pair, physics, cloud, s)
                else:
                    step_fns.block_shot(s, steps, rounds, pair, surfaces, physics, cloud, out)

    return SimpleNamespace(
        frame_block_kernel=frame_block_kernel,
        framed_kernel=framed_kernel,
        bounds_kernel=bounds_kernel,
        kick_kernel=kick_kernel,
        plan_kernel=plan_kernel,
        prepare_kernel=prepare_kernel,
        choose_kernel=choose_kernel,
        resolve_kernel=resolve_kernel,
        finish_kernel=finish_kernel,
        end_step_kernel=end_step_kernel,
        block_kernel=block_kernel,
        now_kernel=now_kernel,
        horizon_kernel=horizon_kernel,
        settle_kernel=settle_kernel,
        leap_kernel=leap_kernel,
        leaped_kernel=leaped_kernel,
        phase_kernel=phase_kernel,
    )
