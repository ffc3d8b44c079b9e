"""Landing tallies inside the core kernel: histograms for quantiles and danger distances, and the
hazard maps, all counted with integer atomics (so they are bitwise the same for any chunk size, any
thread order and after --resume: integer sums do not depend on their order).

Per landed pellet (docs/hazard.md):
- its range (eq. 42), binned (`tallies.bins`) into row ROW_RANGE of `hist`;
- its speed |v| at landing, binned into row ROW_SPEED (the kinetic energy m |v|^2 / 2 is a monotone
  function of it: its quantiles come from the same row);
- its hazard level: the number of thresholds it exceeds. Every threshold, on speed or on energy
  density E/A = rho d v^2 / 3 (A = pi R^2), is a threshold on v^2 (`thresholds2`), so the thresholds
  a pellet exceeds are the `level` lowest: one count per pellet says which;
- its distance from the shooter (horizontal: the landing centre minus `shooter`, less its component
  along `up`, the unit vector against gravity), binned into row ROW_DISTANCE + level;
- with a map: one count in (level, cell) of `map_counts` and its energy in `map_energy` as int64
  multiples of `quantum` J, on the map's surface (cell index, else the `outside` column CELLS; a
  landing on another surface in column CELLS + 1).
Following pellets to rest (physics.until = "rest"), each pellet that stopped (at rest or embedded)
is counted by its rest distance from the shooter (as the landing's distance) into `rest_hist`
(`add_rest`). Three histogram counts per landed pellet, each an atomic add on the device: the GPU's L2 cache
merges a warp's adds to the few busy bins of a narrow distribution. The histograms have COPIES
copies on CUDA (`counts.copies_for`, a power of two), a warp's pellets counting into one copy
chosen from its row, so that those few bins are not one address each for the whole GPU
(`counts.DeviceTally.fold` adds the copies to the run's totals when they are read). A map landing's
count and energy go together into its thread block's table in shared memory (`tallies.block`,
added to the maps once at the end of the block: the landings of a cloud are spread over many
cells, whose atomics the L2 cache cannot merge); one that finds no slot there is added at once.
"""

import functools
from types import SimpleNamespace
from typing import Any

import warp as wp

from ..physics.types import types_for
from ..struct_refs import read_only
from .bins import BINS, ROW_DISTANCE, ROW_RANGE, ROW_SPEED, make_bin_of
from .block import ADD, COUNT, END, ENERGY, KEY, LANE, PROBES, SLOTS, STRIDE, first_slot_steps, make_block_table

COPY_MIX = 37  # `copy_of`: consecutive segments' warps start at copies 37 apart
MAX_THRESHOLDS = 31  # hazard thresholds a `Tally` holds (a landing's exceeded ones are the bits of an int32)


@wp.func_native("""
#if defined(__CUDA_ARCH__)
    atomicAdd(hist.data + index, 1);
#else
    hist.data[index] += 1;  // (a CPU kernel runs on one thread)
#endif
""")
def count_one(hist: wp.array(dtype=wp.int32), index: wp.int32):
    """hist[index] += 1 (atomic on CUDA), for 0 <= index < hist.size: a flat contiguous array's
    element reached without the wrap of negative indices that Warp's indexing adds."""
    ...


@wp.func
def copy_of(row: wp.int32, copy_mask: wp.int32):
    """The histogram copy of a landing in chunk row `row`: its warp's (32 rows), offset by
    COPY_MIX a segment of 2^16 rows, so that the segments in flight at once use different copies."""
    return ((row >> 5) + (row >> 16) * COPY_MIX) & copy_mask


@functools.cache
def make_landing_tally(precision: str) -> SimpleNamespace:
    """The `Tally` struct of one precision and the functions that add a landing to it."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    Thresholds = wp.types.vector(length=MAX_THRESHOLDS, dtype=scalar)

    @wp.struct
    class Tally:
        """What the landings are counted into (`tallies.landing`), and the constants that needs (SI)."""

        hist: wp.array(dtype=wp.int32)  # copies x hist_stride, flat (copy, row, bin)
        hist_stride: wp.int32  # elements a copy: (ROW_DISTANCE + levels) * bins.BINS
        copy_mask: wp.int32  # copies - 1 (copies: a power of two)
        thresholds2: Thresholds  # (m/s)^2, every threshold as one on |v|^2, in scene order (the rest unused)
        shooter: vec3  # m
        up: vec3  # unit vector against gravity (zero without gravity: distances in 3-D)
        half_mass: scalar  # kg, m / 2
        inverse_area: scalar  # 1/m^2, 1 / (pi R^2)
        map_counts: wp.array(dtype=wp.int32)  # levels x (cells + 2), flat (level, column)
        map_energy: wp.array(dtype=wp.int64)  # (cells + 2), multiples of the energy quantum
        map_width: wp.int32  # cells + 2
        map_cells: wp.int32  # map_nu * map_nv
        map_surface: wp.int32
        map_nu: wp.int32  # cells along u and v
        map_u_cell: vec3  # 1/m, the grid's unit axes in the plane divided by the cell size
        map_v_cell: vec3
        map_u_start: scalar  # cells: a position p lies map_u_cell . p - map_u_start cells into the grid along u
        map_v_start: scalar
        map_nu_cells: scalar  # map_nu, map_nv
        map_nv_cells: scalar
        energy_scale: scalar  # quanta / (m/s)^2: m / 2 / the map's energy quantum
        rest_hist: wp.array(dtype=wp.int32)  # copies x BINS, flat: the rest distances (physics.until = "rest")
        reach_row: wp.int32  # hist's row of the reach of threshold 0 (`tallies.path`); those of the others follow
        path_thresholds: wp.int32  # thresholds watched along the path (`tallies.path`; 0: none)
        path_parts: wp.int32  # parts a path segment's piece is cut in (`tallies.path.SUB`)
        body_height: scalar  # m
        ground_point: vec3  # m, a point of the hazard's ground plane
        ground_normal: vec3  # its normal / (normal . up): x . it is a height along up
        exposure: wp.array(dtype=wp.int32)  # levels x (cells + 2), flat: passes by level at entry
        exposure_runs: wp.array(dtype=wp.int32)  # levels x nv x (nu + 1), flat: runs of passes along u, differenced
        place_position: wp.array(dtype=vec3)  # m, the named places
        place_radius2: wp.array(dtype=scalar)  # m^2, their radius squared
        place_counts: wp.array(dtype=wp.int32)  # levels x places, flat: pellets by their highest level there
        terrain: wp.array(dtype=scalar)  # the hazard's ground as a terrain (`tallies.terrain_walk`; empty: a plane)
        steps: wp.array(dtype=scalar)  # the step log (`physics.line_log`): steps x words x log_threads, flat (SI)
        log_threads: wp.int32  # the threads it has a column for
        log_words: wp.int32  # the words of a column

    @wp.func
    def horizontal_distance(tally: Tally, position: vec3):
        """m, from the shooter to the landing centre, perpendicular to `up`."""
        delta = position - tally.shooter
        return wp.length(delta - wp.dot(delta, tally.up) * tally.up)

    @wp.func
    def map_cell(tally: Tally, surface: wp.int32, position: vec3):
        """(column, u, v): the map column of a landing (its cell, CELLS outside the grid, CELLS + 1 on
        another surface) and its cell's indices along u and v (off the grid: the column and 0).
        In the run's precision, as the position is (float32: a rounding of ~1e-7 of the position's
        distance from the world origin, which moves only landings that close to a cell edge)."""
        column = tally.map_cells + 1
        iu = column
        iv = wp.int32(0)
        if surface == tally.map_surface:
            column = tally.map_cells
            iu = column
            fu = wp.dot(position, tally.map_u_cell) - tally.map_u_start
            fv = wp.dot(position, tally.map_v_cell) - tally.map_v_start
            # bounds before the cast: a landing far out in small cells is past int32 (NaN: outside)
            if fu >= scalar(0.0) and fv >= scalar(0.0) and fu < tally.map_nu_cells and fv < tally.map_nv_cells:
                iu = wp.int32(fu)
                iv = wp.int32(fv)
                column = iv * tally.map_nu + iu
        return column, iu, iv

    @wp.func
    def energy_quanta(tally: Tally, v2: scalar):
        """A landing's kinetic energy m v^2 / 2 in quanta, rounded to nearest (halves away from zero),
        in the run's precision (float32: exact to a quantum below 2^24 quanta, the reference energy)."""
        return wp.int64(wp.round(tally.energy_scale * v2))

    read_only(Tally)
    return SimpleNamespace(
        Tally=Tally,
        Thresholds=Thresholds,
        scalar=scalar,
        vec3=vec3,
        map_cell=map_cell,
        energy_quanta=energy_quanta,
        horizontal_distance=horizontal_distance,
    )


@functools.cache
def make_add_landing(precision: str, with_map: bool, thresholds: int = 0, slots: int = SLOTS, probes: int = PROBES):
    """exceeded(tally, v2) -> the bit mask of the `thresholds` (the first of thresholds2, tested
    unrolled) a landing with |v|^2 = v2 exceeds (bit i: v2 >= thresholds2[i]);
    add_landing(tally, row, surface, range, position, v2, mask) counts it (and, `with_map`, maps it:
    through the block's table, `tallies.block` with `slots` and `probes`, first slot on its lattice); flush(tally) adds the block's table to the maps (with a map, every thread of the block at its
    end, after `table(BEGIN, ...)` at its start). A table key is a flat index of map_counts."""
    fns = make_landing_tally(precision)
    Tally, scalar, vec3, map_cell, horizontal_distance = fns.Tally, fns.scalar, fns.vec3, fns.map_cell, fns.horizontal_distance
    energy_quanta = fns.energy_quanta
    bin_of, table = make_bin_of(), make_block_table(slots, probes)
    MAP, THRESHOLDS = with_map, thresholds
    LATTICE, LEVEL_STEP = first_slot_steps(slots)  # a landing's first table slot: u + LATTICE v + LEVEL_STEP level
    if not 0 <= thresholds <= MAX_THRESHOLDS:
        raise ValueError(f"thresholds must be in [0, {MAX_THRESHOLDS}]: {thresholds}")

    @wp.func
    def exceeded(tally: Tally, v2: scalar):
        mask = wp.int32(0)
        for i in range(wp.static(THRESHOLDS)):
            if v2 >= tally.thresholds2[i]:
                mask = mask | (wp.int32(1) << i)
        return mask

    @wp.func
    def add_landing(
        tally: Tally, row: wp.int32, surface: wp.int32, landing_range: scalar, position: vec3, v2: scalar, mask: wp.int32
    ):
        level = wp.int32(wp.bit_count(mask))  # the thresholds are nested: it exceeds the `level` lowest
        first = copy_of(row, tally.copy_mask) * tally.hist_stride
        one = wp.int32(1)
        count_one(tally.hist, first + ROW_RANGE * BINS + bin_of(wp.float32(landing_range)))
        count_one(tally.hist, first + ROW_SPEED * BINS + bin_of(wp.float32(wp.sqrt(v2))))
        distance = horizontal_distance(tally, position)
        count_one(tally.hist, first + (ROW_DISTANCE + level) * BINS + bin_of(wp.float32(distance)))
        if wp.static(MAP):
            column, iu, iv = map_cell(tally, surface, position)
            key = level * tally.map_width + column
            energy = energy_quanta(tally, v2)
            if table(ADD, key, energy, iu + iv * LATTICE + level * LEVEL_STEP) == wp.int64(0):
                wp.atomic_add(tally.map_counts, key, one)
                wp.atomic_add(tally.map_energy, column, energy)

    @wp.func
    def add_rest(tally: Tally, row: wp.int32, position: vec3):
        """Count a pellet that stopped (at rest or embedded) at `position` by its horizontal distance
        from the shooter (into its warp's copy of the rest histogram); returns the distance (m)."""
        distance = horizontal_distance(tally, position)
        count_one(tally.rest_hist, copy_of(row, tally.copy_mask) * BINS + bin_of(wp.float32(distance)))
        return distance

    @wp.func
    def flush(tally: Tally):
        """The block's table added to the maps (every thread of the block, at its end)."""
        slots_here = wp.int32(table(END, 0, wp.int64(0), 0))
        for s in range(wp.int32(table(LANE, 0, wp.int64(0), 0)), slots_here, wp.int32(table(STRIDE, 0, wp.int64(0), 0))):
            key = wp.int32(table(KEY, s, wp.int64(0), 0))
            if key >= 0:
                wp.atomic_add(tally.map_counts, key, wp.int32(table(COUNT, s, wp.int64(0), 0)))
                wp.atomic_add(tally.map_energy, key % tally.map_width, table(ENERGY, s, wp.int64(0), 0))

    return SimpleNamespace(
        exceeded=exceeded, add_landing=add_landing, add_rest=add_rest, flush=flush, table=table, copy_of=copy_of
    )


@functools.cache
def fold_kernel():
    """fold(counts, n, add, totals), for int32 or int64 counts: one thread an element i < n sums
    the copies of `counts` (flat, copy c's element i at c * n + i), zeroes them (writing only the
    nonzero ones: most bins of a histogram stay empty) and adds the sum to totals[i] (int64), or
    with `add` 0 sets totals[i] to it (a run's first fold: no zeroing of the totals before)."""

    @wp.kernel(enable_backward=False)
    def fold(counts: wp.array(dtype=Any), n: wp.int32, add: wp.int32, totals: wp.array(dtype=wp.int64)):
        i = wp.tid()
        total = wp.int64(0)
        for c in range(counts.shape[0] / n):
            value = counts[c * n + i]
            if wp.int64(value) != wp.int64(0):
                total += wp.int64(value)
                counts[c * n + i] = value - value
        if add == 0:
            totals[i] = total
        elif total != wp.int64(0):
            totals[i] += total

    return fold


@functools.cache
def runs_kernel():
    """runs(runs, nu, nv, width, counts): one thread a (level, row) of the map: the row's runs of
    passes along u (+1 at a run's first cell and -1 past its last, `tallies.path.flush`) summed
    along it into counts[level * width + row * nu + iu], and zeroed."""

    @wp.kernel(enable_backward=False)
    def runs(diff: wp.array(dtype=wp.int32), nu: wp.int32, nv: wp.int32, width: wp.int32, counts: wp.array(dtype=wp.int32)):
        k = wp.tid()
        level = k / nv
        row = k - level * nv
        first = k * (nu + 1)
        running = wp.int32(0)
        for iu in range(nu):
            value = diff[first + iu]
            if value != 0:
                running += value
                diff[first + iu] = 0
            if running != 0:
                counts[level * width + row * nu + iu] += running
        diff[first + nu] = 0

    return runs


@functools.cache
def pack_kernel():
    """pack(totals, count, index, value): each nonzero totals[i] as a pair (i, value) at the next
    slot of `count` (pairs past the capacity of `index` are dropped; `count` still counts them).
    The pairs' order varies from run to run; their set does not."""

    @wp.kernel(enable_backward=False)
    def pack(
        totals: wp.array(dtype=wp.int64),
        count: wp.array(dtype=wp.int32),
        index: wp.array(dtype=wp.int32),
        value: wp.array(dtype=wp.int64),
    ):
        i = wp.tid()
        v = totals[i]
        if v != wp.int64(0):
            slot = wp.atomic_add(count, 0, 1)
            if slot < index.shape[0]:
                index[slot] = i
                value[slot] = v

    return pack
