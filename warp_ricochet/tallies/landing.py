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
Three atomics per landed pellet, five with a map. On CUDA each array has COPIES copies (the
leading axis), a warp's pellets counting into copy (row / 32) mod copies, so that a narrow
distribution's few busy bins are not one address each for the whole GPU (`counts.DeviceTally`
sums the copies after the chunk).
"""


import functools
from types import SimpleNamespace

import warp as wp

from ..physics.types import types_for
from .bins import ROW_DISTANCE, ROW_RANGE, ROW_SPEED, make_bin_of


@functools.cache
def make_landing_tally(precision: str) -> SimpleNamespace:
    """The `Tally` struct of one precision and the functions that add a landing to it."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.struct
    class Tally:
        """What the landings are counted into (`tallies.landing`), and the constants that needs (SI)."""

        hist: wp.array3d(dtype=wp.int32)  # (copies, ROW_DISTANCE + levels, bins.BINS)
        thresholds2: wp.array(dtype=scalar)  # (m/s)^2, every threshold as one on |v|^2, in scene order
        shooter: vec3  # m
        up: vec3  # unit vector against gravity (zero without gravity: distances in 3-D)
        half_mass: scalar  # kg, m / 2
        inverse_area: scalar  # 1/m^2, 1 / (pi R^2)
        map_counts: wp.array3d(dtype=wp.int32)  # (copies, levels, cells + 2)
        map_energy: wp.array2d(dtype=wp.int64)  # (copies, cells + 2), multiples of `quantum`
        map_surface: wp.int32
        map_origin: vec3  # m, the grid's (u, v) = (0, 0) on the map's plane
        map_u: vec3  # unit vectors of the grid's axes in the plane
        map_v: vec3
        map_u0: wp.float64  # m, the grid's lower corner in (u, v)
        map_v0: wp.float64
        map_inverse_cell: wp.float64  # 1/m
        map_nu: wp.int32  # cells along u and v
        map_nv: wp.int32
        inverse_quantum: wp.float64  # 1/J

    @wp.func
    def horizontal_distance(tally: Tally, position: vec3):
        """m, from the shooter to the landing centre, perpendicular to `up`."""
        delta = position - tally.shooter
        return wp.length(delta - wp.dot(delta, tally.up) * tally.up)

    @wp.func
    def map_cell(tally: Tally, surface: wp.int32, position: vec3):
        """The map column of a landing: its cell, CELLS outside the grid, CELLS + 1 on another surface."""
        cells = tally.map_nu * tally.map_nv
        column = cells + 1
        if surface == tally.map_surface:
            column = cells
            local = position - tally.map_origin
            fu = (wp.float64(wp.dot(local, tally.map_u)) - tally.map_u0) * tally.map_inverse_cell
            fv = (wp.float64(wp.dot(local, tally.map_v)) - tally.map_v0) * tally.map_inverse_cell
            # bounds in float64 before the cast: a landing far out in small cells is past int32
            if fu >= wp.float64(0.0) and fv >= wp.float64(0.0) and fu < wp.float64(tally.map_nu) and fv < wp.float64(tally.map_nv):
                column = wp.int32(wp.floor(fv)) * tally.map_nu + wp.int32(wp.floor(fu))
        return column

    return SimpleNamespace(Tally=Tally, scalar=scalar, vec3=vec3, map_cell=map_cell,
                           horizontal_distance=horizontal_distance)


@functools.cache
def make_add_landing(precision: str, with_map: bool):
    """exceeded(tally, v2) -> the bit mask of the thresholds a landing with |v|^2 = v2 exceeds (bit i:
    v2 >= thresholds2[i]); add_landing(tally, surface, range, position, v2, mask) counts it (and,
    `with_map`, maps it)."""
    fns = make_landing_tally(precision)
    Tally, scalar, vec3, map_cell, horizontal_distance = fns.Tally, fns.scalar, fns.vec3, fns.map_cell, fns.horizontal_distance
    bin_of = make_bin_of()
    MAP = with_map

    @wp.func
    def exceeded(tally: Tally, v2: scalar):
        mask = wp.int32(0)
        for i in range(tally.thresholds2.shape[0]):
            if v2 >= tally.thresholds2[i]:
                mask = mask | (wp.int32(1) << i)
        return mask

    @wp.func
    def add_landing(tally: Tally, row: wp.int32, surface: wp.int32, landing_range: scalar, position: vec3, v2: scalar,
                    mask: wp.int32):
        level = wp.int32(wp.bit_count(mask))  # the thresholds are nested: it exceeds the `level` lowest
        one = wp.int32(1)
        warp = row / 32
        c = warp % tally.hist.shape[0]
        wp.atomic_add(tally.hist, c, ROW_RANGE, bin_of(wp.float32(landing_range)), one)
        wp.atomic_add(tally.hist, c, ROW_SPEED, bin_of(wp.float32(wp.sqrt(v2))), one)
        distance = horizontal_distance(tally, position)
        wp.atomic_add(tally.hist, c, ROW_DISTANCE + level, bin_of(wp.float32(distance)), one)
        if wp.static(MAP):
            column = map_cell(tally, surface, position)
            m = warp % tally.map_counts.shape[0]
            wp.atomic_add(tally.map_counts, m, level, column, one)
            energy = wp.float64(tally.half_mass * v2)
            wp.atomic_add(tally.map_energy, m, column, wp.int64(wp.floor(energy * tally.inverse_quantum + wp.float64(0.5))))

    return SimpleNamespace(exceeded=exceeded, add_landing=add_landing)


@functools.cache
def sum_copies_kernels():
    """Kernels summing the copies (leading axis) of the counts into one array each."""

    @wp.kernel(enable_backward=False)
    def sum_int32(wide: wp.array3d(dtype=wp.int32), out: wp.array2d(dtype=wp.int32)):
        i, j = wp.tid()
        total = wp.int32(0)
        for c in range(wide.shape[0]):
            total += wide[c, i, j]
        out[i, j] = total

    @wp.kernel(enable_backward=False)
    def sum_int64(wide: wp.array2d(dtype=wp.int64), out: wp.array(dtype=wp.int64)):
        j = wp.tid()
        total = wp.int64(0)
        for c in range(wide.shape[0]):
            total += wide[c, j]
        out[j] = total

    return sum_int32, sum_int64
