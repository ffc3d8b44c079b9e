"""The fused ricochet kernel: a thin loop over the pellets of one chunk (`core.pellet` does the
work), one thread per lane-interleaved set of pellets of a segment (LANES threads of PER_THREAD
pellets, or REST_LANES threads for costly pellets, `spec.RunSpec.lanes`: `tallies.reduce`; consecutive slots
with `spec.thread_pieces`), ending in the thread's statistics partials (`tallies`).
"""

import functools

import warp as wp

from ..launch.source import make_source
from ..physics import grid_constant
from ..physics.geometry import MESHES, SMALL
from ..physics.lanes import WARP_SIZE, sync_lanes
from ..physics.types import types_for
from ..tallies.accumulate import make_accumulators
from ..tallies.block import BEGIN
from ..tallies.landing import make_add_landing, make_landing_tally
from ..tallies.path_replay import OVERFLOWED
from ..tallies.reduce import SEGMENT
from .outputs import make_outputs
from .pellet import make_ricochet_pellet
from .release import make_release

# Register cap of the CUDA ricochet kernel per (precision, fast_math) (None: the compiler's
# choice), chosen by measurement on an H200 (bench/RESULTS.md, `python -m bench.variants`).
CUDA_MAX_REGISTERS = {("float32", False): 80, ("float32", True): None, ("float64", False): None, ("float64", True): None}
# The same for a kernel that flies in air among meshes or posts to their landing, where it differs
# (bench/RESULTS.md, "An air step's triangles screened by the contact found so far").
AIR_SOLIDS_MAX_REGISTERS = {("float32", True): 128}
# ... and for one that flies in vacuum among small solids (meshes of at most FEW_FACES triangles,
# posts) to the landing, launched in blocks of SMALL_SOLIDS_BLOCK_DIM threads: 12 warps an SM, not 8
# (bench/RESULTS.md, "Blocks of 128 threads for a small mesh's kernel").
SMALL_SOLIDS_MAX_REGISTERS = {("float32", True): 168}
CUDA_BLOCK_DIM, SMALL_SOLIDS_BLOCK_DIM = 256, 128  # threads per CUDA block of the ricochet kernel (`block_dim_for`)
# Kernels to rest unroll constant loops of up to this many iterations (Warp's default: 16), for less
# code (bench/RESULTS.md, "Warps that wait for their surface phases").
REST_MAX_UNROLL = 4


def kernel_options(spec, max_registers="default", in_place=True) -> dict:
    """`wp.kernel`'s options for a kernel that follows `spec`'s pellets (the core's, `core.shots`'):
    its register cap (CUDA_MAX_REGISTERS, AIR_SOLIDS_ or SMALL_SOLIDS_MAX_REGISTERS, or `max_registers`), fast maths
    and, to rest, the loops it unrolls; where `in_place`, its parameters read in place on CUDA
    (`physics.grid_constant`)."""
    cap = max_registers
    if max_registers == "default":
        key = spec.precision, spec.fast_math
        cap = CUDA_MAX_REGISTERS[key]
        if spec.flight == "air" and spec.plates >= MESHES and not spec.to_rest:
            cap = AIR_SOLIDS_MAX_REGISTERS.get(key, cap)
        elif _small_solids_landing(spec):
            cap = SMALL_SOLIDS_MAX_REGISTERS.get(key, cap)
    options = {} if cap is None else {"cuda_max_registers": cap}
    module = {"fast_math": True} if spec.fast_math else {}
    if in_place:  # parameters read in place on CUDA, not copied to each thread
        module |= grid_constant.module_options()
    if spec.to_rest:  # loops of up to REST_MAX_UNROLL constant iterations unrolled, not 16 (Warp's default)
        module["max_unroll"] = REST_MAX_UNROLL
    if module:
        options["module_options"] = module
    return options


def _small_solids_landing(spec) -> bool:
    """Whether `spec`'s kernel flies in vacuum among small solids only (`geometry.SMALL`) to the
    landing, without a hazard map (whose landings are summed per block in shared memory,
    `tallies.block`: its blocks keep their size)."""
    small = spec.plates >= MESHES and bool(spec.plates & SMALL)
    return small and spec.flight != "air" and not spec.to_rest and not spec.hazard_map


def block_dim_for(spec) -> int:
    """Threads per CUDA block of a kernel following `spec`'s pellets (the core's, `core.shots`'):
    SMALL_SOLIDS_BLOCK_DIM where `kernel_options` caps it at SMALL_SOLIDS_MAX_REGISTERS, else
    CUDA_BLOCK_DIM. Each thread's pellets, and so the results, are the same for any."""
    small = _small_solids_landing(spec) and (spec.precision, spec.fast_math) in SMALL_SOLIDS_MAX_REGISTERS
    return SMALL_SOLIDS_BLOCK_DIM if small else CUDA_BLOCK_DIM


@functools.cache
def ricochet_kernel_for(spec, max_registers="default"):
    """The core kernel of `spec` (a `spec.RunSpec`): statistics-only kernels carry no output code;
    with `spec.collisions` each pellet continues from the dense phase's release state, and
    threads run over the slots of the shot-padded layout (`Release.shot_stride` slots a shot), so
    statistics segments hold whole shots and do not depend on the chunk size."""
    t = types_for(spec.precision)
    scalar, Surfaces, Physics = t.scalar, t.Surfaces, t.Physics
    Source, Outputs, Release = (
        make_source(spec.precision, spec.from_file, spec.pattern, spec.stations).Source,
        make_outputs(spec.precision).Outputs,
        make_release(spec.precision),
    )
    acc_fns, ricochet_pellet = make_accumulators(spec.precision, spec.to_rest), make_ricochet_pellet(spec)
    Tally, landing = make_landing_tally(spec.precision).Tally, make_add_landing(spec.precision, spec.hazard_map, spec.thresholds)
    TABLE = spec.hazard_map  # the map's block table (`tallies.block`)
    floats_t, extremes_t, inf = acc_fns.floats_t, acc_fns.extremes_t, acc_fns.inf
    RELEASE, CONSECUTIVE, WATCH_ONLY = spec.collisions, spec.thread_pieces, spec.watch_only
    lanes, segment = spec.lanes, SEGMENT
    per_thread = segment // lanes
    if lanes % WARP_SIZE:  # (the pellet loop's warp-uniform passes assume whole warps a group)
        raise ValueError(f"threads a segment must be a multiple of {WARP_SIZE}: {lanes}")
    options = kernel_options(spec, max_registers)

    @wp.func
    def wanted(tally: Tally, row: wp.int32):
        """Whether the kernel follows chunk row `row`: every row, or where it reruns the watch of the
        pellets whose records did not fit (`spec.watch_only`), those only (`core.replay`)."""
        if wp.static(WATCH_ONLY):
            return tally.steps[row] == scalar(OVERFLOWED)
        return True

    @wp.func
    def pellet_at(row: wp.int32, first_index: wp.int32, release: Release):
        """(global index, chunk row, whether it holds a pellet) of the chunk's slot `row`: the row
        itself, or with pair collisions the pellet of the shot-padded slot (padding slots hold none)."""
        if wp.static(RELEASE):
            shot = row / release.shot_stride
            member = row - shot * release.shot_stride
            pellet = shot * release.shot_count + member
            return release.first_pellet + pellet, pellet, member < release.shot_count
        return first_index + row, row, True

    @wp.kernel(module="unique", enable_backward=False, **options)
    def ricochet_kernel(
        first_index: wp.int32,  # global index of the chunk's first pellet (a multiple of SEGMENT)
        count: wp.int32,  # pellets (slots, from a release) in the chunk
        source: Source,
        surfaces: Surfaces,
        physics: Physics,
        out: Outputs,
        release: Release,  # the dense phase's release state (spec.collisions), else empty
        tally: Tally,  # landing histograms and maps (spec.tally), else empty
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
        if wp.static(TABLE):  # every thread of the block: launches cover whole blocks
            landing.table(BEGIN, 0, wp.int64(0), 0)
        # Every lane of a warp runs as many slots as its first lane (the most; a slot past `count`
        # does nothing) and meets its warp at each (`sync_lanes`): lanes split by one pellet's
        # branches start the next one together. (A bound known at run time only: Warp unrolls
        # constant loops of up to 16 iterations.)
        first_lane = lane - lane % WARP_SIZE  # (lanes is a multiple of WARP_SIZE)
        if wp.static(CONSECUTIVE):
            last = wp.max(wp.min(per_thread, count - group * segment - first_lane * per_thread), 0)
        else:
            last = wp.min(per_thread, (count - group * segment - first_lane + lanes - 1) // lanes)
        for j in range(last):
            sync_lanes()
            if wp.static(CONSECUTIVE):  # a thread's slots lie in one piece of one shot (`core.shots`)
                row = group * segment + lane * per_thread + j
            else:
                row = group * segment + j * lanes + lane
            if row < count:
                index, pellet, held = pellet_at(row, first_index, release)
                if held and wanted(tally, pellet):
                    counts, acc, lo, hi, range_shift = ricochet_pellet(
                        index, pellet, source, surfaces, physics, out, release, tally, counts, acc, lo, hi, range_shift, tid
                    )
        if wp.static(TABLE):
            landing.flush(tally)
        acc_fns.store_partials(tid, counts, acc, lo, hi, range_shift, partial_sums, partial_min, partial_max)

    return ricochet_kernel
