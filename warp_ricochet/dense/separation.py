"""Launches without overlaps (runs with pellet-pellet collisions, issue 15): each shot's sampled
pellets placed in order, a pellet redrawn from its own counter-based stream while it lies closer
than a diameter to one placed before it (random sequential addition; `launch.packing` bounds how
dense an envelope may be). Placed pellets are chained into cell buckets one diameter wide, so a
pellet looks at the 27 cells around it (cells a little wider than a diameter, hashed as the
neighbour lists' are): O(1) a pellet, the same answers as comparing with every
earlier pellet of its shot."""

import functools
from types import SimpleNamespace

import warp as wp

from ..launch.packing import MAX_REDRAWS
from ..launch.sampling import make_redraw
from .constants import CELL_MARGIN
from .kit import dense_kit
from .lists import make_lists


@functools.cache
def make_separation(spec) -> SimpleNamespace:
    """separate_shot for a spec (does nothing for pellets from a file: they are used as given)."""
    kit = dense_kit(spec)
    scalar, vec3, Physics, Outputs = kit.scalar, kit.vec3, kit.Physics, kit.Outputs
    Source, Cloud, Pair = kit.Source, kit.Cloud, kit.Pair
    WRITE, write_initial = kit.WRITE, kit.outputs.write_initial
    redraw_position = make_redraw(kit.precision)
    cell_bucket = make_lists(spec).cell_bucket
    SAMPLED = not spec.from_file
    STATIONS = SAMPLED and spec.stations

    @wp.func
    def cell_of(position: vec3, centre: vec3, inverse_cell: wp.float64):
        """Integer cell coordinates of `position` (float64, from the envelope centre) in cells a
        little wider than a diameter: two pellets closer than a diameter are in neighbouring cells
        whatever the rounding."""
        q = position - centre
        return wp.vec3i(
            wp.int32(wp.floor(wp.float64(q[0]) * inverse_cell)),
            wp.int32(wp.floor(wp.float64(q[1]) * inverse_cell)),
            wp.int32(wp.floor(wp.float64(q[2]) * inverse_cell)),
        )

    @wp.func
    def overlaps_earlier(
        position: vec3,
        centre: vec3,
        inverse_cell: wp.float64,
        diameter2: scalar,
        base: wp.int32,
        table: wp.int32,
        heads: wp.array(dtype=wp.int32),
        chain: wp.array(dtype=wp.int32),
        cloud: Cloud,
    ):
        """Whether `position` lies closer than a diameter to a pellet already placed in the shot:
        those are chained by cell (one diameter wide) into the shot's buckets `heads[base:base +
        table]`, so only the 27 cells around it are looked at (the same answer as comparing with
        every earlier pellet, at O(1) a pellet instead of O(count))."""
        c = cell_of(position, centre, inverse_cell)
        hit = wp.int32(0)
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    j = heads[base + cell_bucket(c + wp.vec3i(dx, dy, dz), wp.uint32(table - 1))]
                    while j >= 0 and hit == 0:
                        if wp.length_sq(position - cloud.state.position[j]) < diameter2:
                            hit = wp.int32(1)
                        j = chain[j]
        return hit

    @wp.func
    def separate_shot(
        s: wp.int32,
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
        """One thread per shot of sampled launches: its pellets [begin, end) in order (a large
        shot in pieces, one launch each, the same as in one: the buckets and `redraws` carry
        over; the first piece begins at 0 and empties them), each redrawn
        (`launch.sampling.redraw_position`) while it overlaps an earlier one, then chained into the
        shot's cell buckets (`heads`: `heads.shape[0] / shots` a shot, a power of two; `chain`: one
        a pellet); `redraws[s]`: the most attempts a pellet took, MAX_REDRAWS + 1 when one still
        overlaps. Redraws fill the shot's envelope: around its station with [[stations]]
        (`source.shot_center`, `launch.source`), else around shot.envelope_center."""
        diameter = scalar(2.0) * physics.radius
        diameter2 = diameter * diameter
        inverse_cell = wp.float64(1.0) / (wp.float64(CELL_MARGIN) * wp.float64(diameter))
        first = s * pair.count
        centre = source.envelope_center
        if wp.static(STATIONS):  # the shot's station (`PelletSource.load` filled the chunk's shots)
            centre = source.shot_center[(first_index + first) / pair.count - source.shot_first]
        table = heads.shape[0] / redraws.shape[0]
        base = s * table
        worst = wp.int32(0)
        if begin > 0:
            worst = redraws[s]
        if wp.static(SAMPLED):
            if begin == 0:
                for b in range(table):
                    heads[base + b] = -1
            for k in range(begin, wp.min(end, pair.count)):
                i = first + k
                if cloud.stop[0] != 0:  # an interrupt (the host abandons the chunk)
                    return
                position = cloud.state.position[i]
                attempt = wp.int32(0)
                clash = overlaps_earlier(position, centre, inverse_cell, diameter2, base, table, heads, chain, cloud)
                while clash != 0 and attempt < wp.static(MAX_REDRAWS):
                    attempt += 1
                    position = redraw_position(source.seed, first_index + i, attempt, centre, source.envelope_radius)
                    clash = overlaps_earlier(position, centre, inverse_cell, diameter2, base, table, heads, chain, cloud)
                if attempt > 0:
                    cloud.state.position[i] = position
                    if wp.static(WRITE):
                        write_initial(out, i, position, cloud.state.velocity[i], cloud.state.angular_velocity[i])
                bucket = base + cell_bucket(cell_of(position, centre, inverse_cell), wp.uint32(table - 1))
                chain[i] = heads[bucket]
                heads[bucket] = i
                worst = wp.max(worst, attempt + clash)
        redraws[s] = worst

    return SimpleNamespace(separate_shot=separate_shot)
