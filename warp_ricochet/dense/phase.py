"""The dense phase's host wiring: `DensePhase` runs one chunk of whole shots on a device, from the
launch until no pair of any shot can touch again, and leaves each pellet's release state for the
core kernel. No host sync inside a block of steps: the host reads the global flags at checkpoints
and after each list build (one small read each).

How it runs (the results are bitwise the same in every mode, tested):
- CUDA: lists from a `wp.HashGrid`, the host loop of checkpoints, rebuilds and blocks, each block
  of per-step kernels captured once as a CUDA graph and replayed;
- CPU (`DenseOptions`): by default a group of shots' whole dense phase is one launch of
  `phase_kernel` on cell lists ("phase"); "block" runs the host loop with a block of steps a
  launch; "kernels" the per-step kernels, as CUDA; lists from cell lists ("cells") or, as on CUDA,
  `wp.HashGrid` ("hashgrid"). Trajectory frames need the host loop (they are taken at checkpoints).

Interrupts (`interrupts`): the host loop checks for one before each block, and on CUDA between
the pieces of a large shot's horizon and launch separation (`in_pieces`); on the CPU the long
launches (phase_kernel, block_kernel, separate_kernel) run in a worker thread while the main thread waits, and an
interrupt sets `cloud.stop`, which ends them at their next block, pass or pellet; the chunk is
then abandoned (KeyboardInterrupt), its state unfinished.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from .. import interrupts
from ..errors import SceneError
from ..launch.packing import MAX_REDRAWS
from ..tallies.collisions import SHOT_TOTALS
from .constants import (
    BLOCK_STEPS,
    CELL_REACHES,
    FLAG_OVERFLOW,
    FLAG_REMAINING,
    FLAG_STALL,
    FLAG_WIDENED,
    HORIZON_PAIRS_PER_LAUNCH,
    SEPARATION_PELLETS_PER_LAUNCH,
)
from .kernels import make_setup_kernels, make_step_kernels
from .schedule import separation_table
from .state import allocate_cloud, pair_struct, release_struct

CPU_STEPS = ("phase", "block", "kernels")
CPU_LISTS = ("cells", "hashgrid")


@dataclass(frozen=True)
class DenseOptions:
    """How the CPU runs the dense phase (see the module notes); `phase_pellets`: about this many
    pellets' shots per launch of the one-launch phase (about a second: Ctrl-C and SIGTERM are
    seen within it)."""

    cpu_steps: str = "phase"
    cpu_lists: str = "cells"
    phase_pellets: int = 4096

    def __post_init__(self):
        if self.cpu_steps not in CPU_STEPS or self.cpu_lists not in CPU_LISTS or self.phase_pellets < 1:
            raise ValueError(f"DenseOptions: cpu_steps in {CPU_STEPS}, cpu_lists in {CPU_LISTS}, phase_pellets >= 1")


class DensePhase:
    """Buffers for up to `capacity` pellets (whole shots of `scene.shot.count`), the kernels of
    `spec`, and the loop that steps them."""

    def __init__(self, model, scene, spec, capacity: int, options: DenseOptions | None = None):
        options = options or DenseOptions()
        coll = scene.collisions
        self.model, self.device, self.count, self.capacity = model, model.device, scene.shot.count, capacity
        self.rounds, self.block_steps = coll.rounds, coll.frame_every or BLOCK_STEPS
        self.kernels, self.in_air = {**vars(make_setup_kernels(spec)), **vars(make_step_kernels(spec))}, spec.in_air
        shots = -(-capacity // self.count)
        self.cloud, self.field_arrays = allocate_cloud(
            model.precision,
            self.device,
            capacity,
            shots,
            self.count,
            coll.rounds,
            coll.max_neighbours,
            spec.collision_fields,
            spec.watch,
        )
        self.release = release_struct(model.precision, self.cloud, self.count)
        self.totals = wp.zeros((shots, len(SHOT_TOTALS)), dtype=wp.float64, device=self.device)
        self.sampled = not spec.from_file and coll.separate  # separated launches (a pellet file's are as given)
        self.envelope_radius = scene.shot.envelope_radius
        self.redraws, self.heads, self.chain = separation_buffers(self.device, shots, self.count, self.sampled)
        self.pair = pair_struct(model.precision, model, coll, self.count, self.block_steps)
        # a shot's collision totals a frame block at a time (dense.ends.block_totals)
        self.block_totals = wp.zeros((shots * self.pair.frame_blocks, 3), dtype=wp.float64, device=self.device)
        cpu = not self.device.is_cuda
        self.fused = cpu and options.cpu_steps != "kernels"
        self.cell_lists = cpu and options.cpu_lists == "cells"
        self.one_launch = self.cell_lists and options.cpu_steps == "phase"
        self.phase_pellets = options.phase_pellets
        if self.cell_lists:  # one shot at a time: a table for one shot, rows of one shot
            self.bucket_end = wp.zeros(separation_table(self.count) + 1, dtype=wp.int32, device=self.device)
            self.rows = wp.zeros(self.count, dtype=wp.int32, device=self.device)
            self.cells = wp.zeros(capacity, dtype=wp.vec3i, device=self.device)
        else:
            self.groups = wp.zeros(capacity, dtype=wp.int32, device=self.device)
            cells = min(max(int(round((2.0 * capacity) ** (1.0 / 3.0))), 8), 256)
            self.grid = wp.HashGrid(cells, cells, cells, device=self.device, dtype=model.types.scalar)
        self.reach = 2.0 * model.radius + coll.skin * 2.0 * model.radius
        self.graph = None
        self.last_frame_step = None
        self.frame_points = None  # (capacity,) float64 centres of a trajectory frame (take_frame)
        self.stop = self.cloud.stop.numpy() if cpu else None  # (a view: the host sets it, a launch reads it)

    def run(self, first_index: int, shots: int, source, outputs, frames=None, tally=None):
        """Launch `shots` whole shots (global pellet index `first_index` on), step them until no
        pair can touch again, and leave the release state for the core kernel (`self.release`).
        `frames(step, time, positions)` receives trajectory frames at checkpoints; `tally`: the
        run's `Tally` struct, which the hazard along the path counts into (`dense.watch`)."""
        pellets = shots * self.count
        c, p = self.cloud, self.pair
        if tally is not None:
            c.watch.tally = tally
        self.shots, self._outputs = shots, outputs
        self.release.first_pellet = first_index
        c.keys.assign(np.array([source.seed, first_index], dtype=np.int32))  # (the ground's draws: dense.events)
        self.launch_shots(first_index, shots, source, outputs)
        start_shots(self, shots)
        if not self.cell_lists:
            self._launch("groups_kernel", pellets, [p, self.groups])
        if self.one_launch and frames is None:
            whole_phase(self)
        else:
            self._host_loop(pellets, shots, outputs, frames)
        self._launch("release_kernel", self.threads, [p, self.model.surfaces, self.model.physics, c])
        self._launch("block_totals_kernel", shots * p.frame_blocks, [p, c, self.block_totals])
        self._launch("shot_totals_kernel", shots, [p, c, self.block_totals, self.totals])

    def launch_shots(self, first_index: int, shots: int, source, outputs):
        """Each pellet's launch state, each shot of sampled launches separated (no overlaps; one
        that cannot be is refused before it steps)."""
        if self.stop is not None:  # (a stop left by an interrupted launch of an earlier chunk)
            self.stop[0] = 0
        self.threads = self._threads(shots * self.count)
        self._launch("launch_kernel", self.threads, [first_index, self.pair, source, self.cloud, outputs])
        if self.sampled:
            args = [first_index, self.pair, self.model.physics, source, self.cloud, outputs, self.redraws, self.heads, self.chain]
            parts = pieces(self.count, SEPARATION_PELLETS_PER_LAUNCH)
            if self.stop is not None:  # the CPU: each launch reads the stop flag
                for begin, end in parts:
                    self._long("separate_kernel", shots, [begin, end, *args])
            else:
                in_pieces(
                    self.device, [self._launch("separate_kernel", shots, [begin, end, *args], True) for begin, end in parts]
                )
            check_redraws(self, shots)

    def _threads(self, pellets):
        """Threads of a per-pellet kernel: one per pellet on CUDA; on the CPU one for all."""
        self.pair.pellets = pellets
        self.pair.span = 1 if self.device.is_cuda else max(pellets, 1)
        return -(-pellets // self.pair.span)

    def _launch(self, name, dim, inputs, record=False):
        return wp.launch(self.kernels[name], dim=dim, inputs=inputs, device=self.device, record_cmd=record)

    def _long(self, name, dim, inputs):
        """A launch that may run long: on the CPU through `interrupts.wait` (a worker thread; an
        interrupt sets `cloud.stop`, which the kernel reads and returns early)."""
        command = self._launch(name, dim, inputs, True)
        if self.stop is None:
            command.launch()
        else:
            interrupts.wait(command.launch, self.stop)

    def _host_loop(self, pellets, shots, outputs, frames):
        """Checkpoints, rebuilds and blocks of steps launched from the host."""
        c = self.cloud
        self._record()
        self._rebuild(pellets)
        commands = self._step_commands(pellets, shots, outputs)
        self.graph = None
        while True:
            interrupts.check()
            flags = self._checkpoint()  # host syncs: here, at checkpoints, and one per rebuild
            if frames is not None:
                take_frame(self, pellets, frames)
            if flags[FLAG_REMAINING] == 0:
                break
            c.flags.zero_()
            if flags[FLAG_STALL]:
                if flags[FLAG_WIDENED]:  # the grid's cells follow the widest reach (a shot's skin widened)
                    self.reach = 2.0 * self.model.radius + 2.0 * float(c.lists.widest_half_skin.numpy()[0])
                if self._rebuild(pellets):
                    commands = self._step_commands(pellets, shots, outputs)
                    self.graph = None
            self._block(commands)

    def _record(self):
        """The launches of the checkpoints and the rebuilds, recorded once per run (packing the
        structs' parameters costs more than a small launch on the CPU) and again when the lists
        grow (the cloud's struct then holds a new array)."""
        m, c, p = self.model, self.cloud, self.pair
        partners = pieces(self.count // 2, max(1, HORIZON_PAIRS_PER_LAUNCH // max(p.pellets, 1)))
        self.now_command = self._launch("now_kernel", self.threads, [p, m.physics, c], True)
        self.horizon_commands = [
            self._launch("horizon_kernel", self.threads, [1 + begin, 1 + end, p, m.surfaces, m.physics, c], True)
            for begin, end in partners
        ]
        self.checkpoint_commands = [self._launch("settle_kernel", self.shots, [p, m.physics, c], True)]
        if self.in_air:  # (dense.leap)
            self.checkpoint_commands += [
                self._launch("leap_kernel", self.threads, [p, m.surfaces, m.physics, c, self._outputs], True),
                self._launch("leaped_kernel", self.shots, [p, m.physics, c], True),
            ]
        self.checkpoint_commands += [
            self._launch("frame_block_kernel", self.shots * p.frame_blocks, [p, m.physics, c], True),
            self._launch("framed_kernel", self.shots, [p, m.physics, c], True),
        ]
        if self.cell_lists:
            self.list_commands = [
                self._launch("cell_lists_kernel", 1, [p, m.physics, c, self.bucket_end, self.rows, self.cells], True)
            ]
        else:
            self.list_commands = [
                self._launch("grid_points_kernel", self.threads, [p, m.physics, c], True),
                self._launch("neighbours_kernel", self.threads, [self.grid.id, p, m.physics, c], True),
            ]

    def _checkpoint(self):
        """Each shot at its checkpoint: its horizon, and whether it stops, jumps or rebuilds;
        returns the global flags (one host sync)."""
        self.now_command.launch()
        in_pieces(self.device, self.horizon_commands)
        for command in self.checkpoint_commands:
            command.launch()
        return self.cloud.flags.numpy().copy()  # (a copy: CPU arrays share memory)

    def _rebuild(self, pellets) -> bool:
        """Build the neighbour lists; a list that overflowed grows them and builds again, so no
        step ever runs on a truncated list. Returns whether they grew (the recorded commands then
        hold the old array, and are recorded again)."""
        grew = False
        while True:
            self.list_commands[0].launch()  # cell lists (CPU), or the grid points
            if not self.cell_lists:
                # (one shot: no groups; a grouped build costs twice as much on the CPU, and a grouped
                # query of an ungrouped grid filters nothing)
                groups = self.groups[:pellets] if pellets > self.count else None
                self.grid.build(self.cloud.lists.grid_point[:pellets], CELL_REACHES * self.reach, groups=groups)
                self.list_commands[1].launch()
            if not self._grew_lists():
                return grew
            self._record()
            grew = True

    def _block(self, commands):
        run_block(self, commands)

    def _grew_lists(self) -> bool:
        """After a build: if a list overflowed, longer lists (1.25 x the longest needed), to be
        built again. One integer read per build."""
        c = self.cloud
        found = int(c.flags.numpy()[FLAG_OVERFLOW])
        if found == 0:
            return False
        c.lists.neighbours = wp.zeros((self.capacity, int(found * 1.25) + 1), dtype=wp.int32, device=self.device)
        c.flags[FLAG_OVERFLOW:].zero_()
        return True

    def _step_commands(self, pellets, shots, outputs):
        """One step's launches, recorded once and replayed; on CUDA a block of them is captured as
        a graph; on the CPU (fused) a block of steps is one launch."""
        m, c, p = self.model, self.cloud, self.pair
        if self.fused:
            return [self._launch("block_kernel", 1, [self.block_steps, self.rounds, p, m.surfaces, m.physics, c, outputs], True)]
        threads = self.threads
        commands = [
            self._launch("bounds_kernel", threads, [p, m.surfaces, m.physics, c], True),
            self._launch("plan_kernel", shots, [p, m.physics, c], True),
            self._launch("prepare_kernel", threads, [p, m.physics, c], True),
        ]
        if self.in_air:
            commands.append(self._launch("kick_kernel", threads, [p, m.surfaces, m.physics, c], True))
        for r in range(self.rounds):
            commands.append(self._launch("choose_kernel", threads, [r, 0, p, m.surfaces, m.physics, c], True))
            commands.append(self._launch("resolve_kernel", threads, [r, p, m.surfaces, m.physics, c, outputs], True))
        # events still ahead after the rounds: the step ends at the earliest (no pellet flies into its partner)
        commands.append(self._launch("choose_kernel", threads, [self.rounds, 1, p, m.surfaces, m.physics, c], True))
        commands.append(self._launch("finish_kernel", threads, [p, m.surfaces, m.physics, c, outputs], True))
        commands.append(self._launch("end_step_kernel", shots, [p, c], True))
        return commands


def start_shots(dense: DensePhase, shots: int):
    """Each shot's clock, its co-moving frame at the launch and its arrival window (the frame's
    sums a block of pellets a thread: dense.frame)."""
    m, c, p = dense.model, dense.cloud, dense.pair
    blocks = shots * p.frame_blocks
    dense._launch("drift_kernel", shots, [p, m.surfaces, m.physics, c])
    dense._launch("frame_block_kernel", blocks, [p, m.physics, c])
    dense._launch("framed_kernel", shots, [p, m.physics, c])
    dense._launch("start_block_kernel", blocks, [p, m.surfaces, m.physics, c])
    dense._launch("window_kernel", shots, [p, m.physics, c])


def in_pieces(device, commands):
    """Launch `commands` in order; with more than one (a large shot), wait for each and see
    whether an interrupt came before the next, so none waits for the rest."""
    for command in commands:
        command.launch()
        if len(commands) > 1:
            wp.synchronize_device(device)
            interrupts.check()


def pieces(count: int, size: int) -> list[tuple[int, int]]:
    """[begin, end) pieces of at most `size` covering range(count) (one, empty, for count 0)."""
    return [(begin, min(begin + size, count)) for begin in range(0, max(count, 1), size)]


def run_block(dense: DensePhase, commands):
    """A block of steps: on CUDA a graph of `block_steps` steps, captured once and replayed; on the
    CPU one launch of block_kernel (fused) or the per-step launches."""
    if dense.graph is not None:
        wp.capture_launch(dense.graph)
        return
    if dense.device.is_cuda:
        with wp.ScopedCapture(device=dense.device) as capture:
            for _ in range(dense.block_steps):
                for command in commands:
                    command.launch()
        dense.graph = capture.graph
        wp.capture_launch(dense.graph)
        return
    if dense.fused:
        interrupts.wait(commands[0].launch, dense.stop)
        return
    for _ in range(dense.block_steps):
        interrupts.check()
        for command in commands:
            command.launch()


def whole_phase(dense: DensePhase):
    """The CPU: the dense phase of a group of shots is one launch of phase_kernel (again after a
    list overflowed, with longer lists)."""
    m, c = dense.model, dense.cloud
    c.flags.zero_()
    group = max(1, dense.phase_pellets // dense.count)
    first = 0
    while first < dense.shots:
        end = min(first + group, dense.shots)
        dense._long(
            "phase_kernel",
            1,
            [
                first,
                end,
                dense.block_steps,
                dense.rounds,
                dense.pair,
                m.surfaces,
                m.physics,
                c,
                dense._outputs,
                dense.bucket_end,
                dense.rows,
                dense.cells,
            ],
        )
        if not dense._grew_lists():  # (else the same group again: its shots before the overflow are done)
            first = end


def take_frame(dense, pellets: int, frames):
    """A trajectory frame at a checkpoint every `block_steps` steps (of the first shot): each pellet's
    centre then (where its flight ended, for those that ended), to `frames(step, time, positions)`;
    the centres are computed on the device (`trajectory_frame_kernel`), the host copies them."""
    clock = dense.cloud.clock
    steps = int(clock.steps.numpy()[0])
    if steps % dense.block_steps or steps == dense.last_frame_step:
        return  # a block cut short by a list rebuild: not a frame
    dense.last_frame_step = steps
    now = float(clock.time.numpy()[0])
    if dense.frame_points is None:
        dense.frame_points = wp.empty(dense.capacity, dtype=wp.vec3d, device=dense.device)
    dense._launch("trajectory_frame_kernel", pellets, [dense.model.physics, dense.cloud, dense.frame_points])
    frames(steps, now, dense.frame_points.numpy()[:pellets].copy())  # (a copy: CPU arrays share memory)


def separation_buffers(device, shots: int, count: int, sampled: bool):
    """The launch separation's arrays: the most redraws of each shot, its cell buckets and a chain
    entry a pellet (`dense.separation`; empty buckets and chain without sampled launches)."""
    table = separation_table(count) if sampled else 0
    return (
        wp.zeros(shots, dtype=wp.int32, device=device),
        wp.empty(shots * table, dtype=wp.int32, device=device),
        wp.empty(shots * count if sampled else 0, dtype=wp.int32, device=device),
    )


def check_redraws(phase: DensePhase, shots: int):
    """Refuse (one line) shots where a pellet found no place free of overlaps (the scene check
    keeps this from happening below `launch.packing.MAX_PACKING`)."""
    if phase.sampled and int(phase.redraws.numpy()[:shots].max()) > MAX_REDRAWS:
        raise SceneError(
            "shot.envelope_radius",
            phase.envelope_radius,
            f"a pellet found no place free of overlaps in {MAX_REDRAWS:,} draws: the envelope is too "
            "dense to sample without overlaps; make it larger",
        )
