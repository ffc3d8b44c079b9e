"""Per-shot statistics partials of a run of several shots (`shot.shots`), for the ensemble's
confidence intervals (`tallies.ensemble`).

A second, statistics-only pass of the core over the pellets of each complete shot, by *pieces*
(`tallies.ensemble.PIECE` = 256 consecutive pellets of one shot, the last piece of a shot shorter)
cut into SUB_PIECES sub-pieces of SUB consecutive pellets: one thread a sub-piece follows its
pellets in order through `core.pellet.ricochet_pellet` (from the launch, or from the dense phase's
release in a run with pair collisions) and stores its partials as the core kernel's threads do
(`tallies.accumulate.store_partials`); a piece's row is then its sub-pieces' partials merged in
order as a statistics segment's lanes are (`tallies.reduce.reduce_kernel`: sums, Chan's squared
deviations, extremes), so that a GPU is kept busy by a few thousand shots of pellets followed to
rest (tens of integration steps each). A piece's partials depend only on its pellets, never on the chunk or on the other
shots, so per-shot values are bitwise the same for any chunk size and after --resume. Rows are
(shot, piece) in order, SEGMENT_WIDTH columns like a statistics segment's: sums, range minima,
range maxima.

Runs with pair collisions followed to rest (`spec.thread_pieces`) need no second pass: the core
kernel's threads follow consecutive slots of one piece, and `ThreadPieces` merges their partials
into the same rows (with another grouping of the sums than `ShotPass`'s, so other last bits).
"""

import dataclasses
import functools

import warp as wp

from ..launch.source import PelletSource, make_source
from ..physics.types import types_for
from ..tallies.accumulate import make_accumulators
from ..tallies.ensemble import PIECE, pieces_per_shot
from ..tallies.landing import make_landing_tally
from ..tallies.reduce import SEGMENT, SEGMENT_WIDTH, reduce_kernel
from ..tallies.sums import NUM_EXTREMES, NUM_SUMS
from .kernel import block_dim_for, kernel_options
from .outputs import make_outputs
from .pellet import make_ricochet_pellet
from .release import make_release

SUB = 32  # pellets a thread follows
SUB_PIECES = PIECE // SUB  # threads a piece


def shot_spec(spec):
    """`spec` statistics only (no outputs, no landing tallies: the core kernel counts each landing
    once): the per-piece kernel's."""
    return dataclasses.replace(spec, fields=(), tally=False, hazard_map=False)


@functools.cache
def shot_kernel_for(spec):
    """The per-piece kernel of `spec` (`shot_spec`'s), launched in blocks of `block_dim_for` its spec."""
    spec = shot_spec(spec)
    t = types_for(spec.precision)
    scalar, Surfaces, Physics = t.scalar, t.Surfaces, t.Physics
    Source, Outputs, Release = (
        make_source(spec.precision, spec.from_file, spec.pattern, spec.stations).Source,
        make_outputs(spec.precision).Outputs,
        make_release(spec.precision),
    )
    acc_fns, ricochet_pellet = make_accumulators(spec.precision, spec.to_rest), make_ricochet_pellet(spec)
    Tally = make_landing_tally(spec.precision).Tally
    floats_t, extremes_t, inf = acc_fns.floats_t, acc_fns.extremes_t, acc_fns.inf
    piece, sub, subs = PIECE, SUB, SUB_PIECES

    @wp.kernel(module="unique", enable_backward=False, **kernel_options(spec))  # (the core kernel's maths and registers)
    def shot_pieces_kernel(
        first_shot: wp.int32,  # global index of the first shot
        count: wp.int32,  # pellets per shot
        pieces: wp.int32,  # pieces per shot
        row_offset: wp.int32,  # global index of the source's (or release's) row 0
        source: Source,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
        release: Release,
        tally: Tally,  # not counted into (the spec's tally is off)
        partial_sums: wp.array2d(dtype=wp.float64),  # (NUM_SUMS, sub-pieces of the launch)
        partial_min: wp.array2d(dtype=wp.float64),
        partial_max: wp.array2d(dtype=wp.float64),
    ):
        tid = wp.tid()
        k = tid // subs  # the piece (of the launch's shots) and the sub-piece in it
        shot = k // pieces
        first = (k - shot * pieces) * piece + (tid - k * subs) * sub
        counts = wp.vec4i()
        acc = floats_t()
        lo = extremes_t(inf)
        hi = extremes_t(-inf)
        range_shift = scalar(0.0)
        for j in range(sub):
            member = first + j
            if member < count:
                index = (first_shot + shot) * count + member
                counts, acc, lo, hi, range_shift = ricochet_pellet(
                    index,
                    index - row_offset,
                    source,
                    surfaces,
                    physics,
                    out,
                    release,
                    tally,
                    counts,
                    acc,
                    lo,
                    hi,
                    range_shift,
                    tid,
                )
        acc_fns.store_partials(tid, counts, acc, lo, hi, range_shift, partial_sums, partial_min, partial_max)

    return shot_pieces_kernel


class ShotPass:
    """Launches the per-sub-piece kernel for the shots a chunk completes and merges each piece's
    sub-pieces, keeping their rows on the device (`rows`, (pieces, SEGMENT_WIDTH) float64) until
    the host copies them."""

    def __init__(self, scene, model, spec, max_shots: int, arrays=None):
        self.model, self.spec = model, spec
        self.count = scene.shot.count
        self.pieces = pieces_per_shot(self.count)
        self.kernel, self.block_dim = shot_kernel_for(spec), block_dim_for(shot_spec(spec))
        dev = model.device
        n = max(max_shots, 1) * self.pieces
        self.partial_sums, self.partial_min, self.partial_max, self.rows = _arrays(dev, n)
        self.merge = reduce_kernel(SUB_PIECES)
        # a pellet file: its own rows, the shots may start in an earlier chunk
        self.source = (
            PelletSource(scene, model.precision, dev, max(max_shots, 1) * self.count, arrays)
            if arrays is not None and not spec.collisions
            else None
        )

    def launch(self, first_shot: int, shots: int, source, outputs, release, tally, row_offset: int) -> int:
        """Per-piece partials of shots [first_shot, first_shot + shots) into the first rows of
        `rows` (the kernel writes them through strided views; no wait for the device: the host
        copies them with the chunk); returns the pieces."""
        if shots <= 0:
            return 0
        if self.source is not None:
            self.source.load(first_shot * self.count, shots * self.count)
            source, row_offset = self.source.struct, first_shot * self.count
        m, pieces = self.model, shots * self.pieces
        wp.launch(
            self.kernel,
            dim=pieces * SUB_PIECES,
            inputs=[first_shot, self.count, self.pieces, row_offset, source, m.surfaces, m.physics, outputs, release, tally],
            outputs=[self.partial_sums, self.partial_min, self.partial_max],
            device=m.device,
            block_dim=self.block_dim,  # (as its register cap: `core.kernel.block_dim_for`)
        )
        wp.launch(
            self.merge,
            dim=(pieces, NUM_SUMS + NUM_EXTREMES),
            inputs=[self.partial_sums, self.partial_min, self.partial_max, 1, SUB_PIECES, 0],
            outputs=[self.rows],
            device=m.device,
        )
        return pieces


class ThreadPieces:
    """Per-piece partials of a chunk's shots merged from the core kernel's own threads, with no second
    pass over the pellets (`spec.thread_pieces`: a thread follows consecutive slots of one piece of
    one shot in the shot-padded layout of `stride` slots a shot). Piece p of shot s is the
    threads from column (s * stride + p * PIECE) / per_thread, PIECE / per_thread of them (a
    shot's stride of them when it is shorter), merged in order as `ShotPass` merges its
    sub-pieces; `rows` as `ShotPass.rows`."""

    def __init__(self, scene, model, state, stride: int, max_shots: int):
        per_thread = SEGMENT // state.lanes
        self.state, self.device = state, model.device
        self.pieces = pieces_per_shot(scene.shot.count)
        self.cols = (stride // per_thread, PIECE // per_thread)
        self.merge = reduce_kernel(min(PIECE, stride) // per_thread)
        self.rows = wp.empty((max(max_shots, 1) * self.pieces, SEGMENT_WIDTH), dtype=wp.float64, device=model.device)

    def launch(self, first_shot: int, shots: int, *_args) -> int:
        """Per-piece partials of the chunk's `shots` shots (from its core launch) into the first rows
        of `rows`; returns the pieces."""
        if shots <= 0:
            return 0
        pieces, st = shots * self.pieces, self.state
        wp.launch(
            self.merge,
            dim=(pieces, NUM_SUMS + NUM_EXTREMES),
            inputs=[st.partial_sums, st.partial_min, st.partial_max, self.pieces, *self.cols],
            outputs=[self.rows],
            device=self.device,
        )
        return pieces


_KEPT: dict = {}  # CUDA: the last pass's device rows, reused by the next of the same size (hundreds of MB)


def _arrays(dev, n: int):
    """The partials of up to `n` pieces' sub-pieces as the kernel writes them (sums, minima,
    maxima: a column a sub-piece) and the pieces' rows as the host takes them (`rows`: a piece a
    row, SEGMENT_WIDTH columns), float64. On CUDA the last pass's if they have this size (one run
    at a time: pipeline's lock), so a run does not allocate them again."""
    key = (dev.alias, n)
    if key in _KEPT:
        return _KEPT[key]
    if dev.is_cuda:
        _KEPT.clear()  # (the old ones freed before the new ones are made)
    width = n * SUB_PIECES
    out = (
        wp.empty((NUM_SUMS, width), dtype=wp.float64, device=dev),
        wp.empty((NUM_EXTREMES, width), dtype=wp.float64, device=dev),
        wp.empty((NUM_EXTREMES, width), dtype=wp.float64, device=dev),
        wp.empty((n, SEGMENT_WIDTH), dtype=wp.float64, device=dev),
    )
    if dev.is_cuda:
        _KEPT[key] = out
    return out
