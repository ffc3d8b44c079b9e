"""Neighbour lists (reach 2R + skin), built in co-moving coordinates: on CUDA from a `wp.HashGrid`
whose groups keep shots apart (`grid_point_pellet`, then `grid_list`); on the CPU from cell lists
(`cell_lists_shot`: the same lists, as sets; HashGrid's CPU build has a fixed cost larger than a
shot's whole list build)."""

import functools
from types import SimpleNamespace

import warp as wp

from .constants import CELL_MARGIN, FLAG_OVERFLOW, FLYING, SHOT_DONE, SHOT_REBUILD
from .frame import make_frame
from .kit import dense_kit


@functools.cache
def make_lists(spec) -> SimpleNamespace:
    """The list builders of the dense phase."""
    kit = dense_kit(spec)
    scalar, vec3, Physics, Cloud, Pair = kit.scalar, kit.vec3, kit.Physics, kit.Cloud, kit.Pair
    fr = make_frame(spec)
    set_build_point, drift_point = fr.set_build_point, fr.drift_point

    @wp.func
    def grid_point_pellet(i: wp.int32, pair: Pair, physics: Physics, cloud: Cloud):
        """Co-moving grid coordinates: the position relative to the shot's drift point (small
        numbers, and the skin is measured from them); the grid's group is the shot. Shots whose
        lists stay keep their offsets (their points in the grid are never asked for: groups)."""
        s = i / pair.count
        if cloud.shot_flags[s, SHOT_REBUILD] == 0:
            return
        time = cloud.clock.time[s]
        set_build_point(cloud, physics, i, time, drift_point(cloud, s, time, physics.gravity))

    @wp.func
    def grid_list(i: wp.int32, grid: wp.uint64, pair: Pair, physics: Physics, cloud: Cloud):
        """The listed neighbours of each flying pellet of a shot being rebuilt: flying pellets of
        its shot within the reach."""
        s = i / pair.count
        if cloud.shot_flags[s, SHOT_REBUILD] == 0:
            return
        cloud.lists.neighbour_count[i] = 0
        if cloud.state.phase[i] != FLYING or cloud.shot_flags[s, SHOT_DONE] != 0:
            return
        point = cloud.lists.grid_point[i]
        reach = scalar(2.0) * (physics.radius + cloud.lists.half_skin[s])
        reach2 = reach * reach
        capacity = cloud.lists.neighbours.shape[1]
        found = wp.int32(0)
        query = wp.hash_grid_query(grid, point, reach, s)  # grouped: pellets of shot s only
        j = wp.int32(0)
        while wp.hash_grid_query_next(query, j):
            if j != i and cloud.state.phase[j] == FLYING:
                d = cloud.lists.grid_point[j] - point
                if wp.dot(d, d) <= reach2:  # the query returns candidates: filter by distance
                    if found < capacity:
                        cloud.lists.neighbours[i, found] = j
                    found += 1
        if found > capacity:
            wp.atomic_max(cloud.flags, FLAG_OVERFLOW, found)
            found = capacity
        cloud.lists.neighbour_count[i] = found
        cloud.event.stale[i] = 1  # a new list: its earliest event is found again

    @wp.func
    def cell_bucket(cell: wp.vec3i, mask: wp.uint32):
        """A cell's bucket in a table of mask + 1 (a power of two) buckets."""
        h = (
            (wp.uint32(cell[0]) * wp.uint32(73856093))
            ^ (wp.uint32(cell[1]) * wp.uint32(19349663))
            ^ (wp.uint32(cell[2]) * wp.uint32(83492791))
        )
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
        found = cloud.lists.neighbour_count[i]
        if found < capacity:
            cloud.lists.neighbours[i, found] = j
        cloud.lists.neighbour_count[i] = found + 1
        found = cloud.lists.neighbour_count[j]
        if found < capacity:
            cloud.lists.neighbours[j, found] = i
        cloud.lists.neighbour_count[j] = found + 1

    @wp.func
    def cell_lists_shot(
        s: wp.int32,
        pair: Pair,
        physics: Physics,
        cloud: Cloud,
        bucket_end: wp.array(dtype=wp.int32),
        rows: wp.array(dtype=wp.int32),
        cells: wp.array(dtype=wp.vec3i),
    ):
        """Shot s's lists on the CPU (one thread), in place of grid_points_kernel, wp.HashGrid and
        neighbours_kernel, whose CPU build has a fixed cost (two radix passes over 65,536 bins)
        larger than a shot's whole list build. The same lists (as sets: the same points, the
        same distance test; no result depends on a list's order): the shot's flying pellets are
        counting-sorted into hashed cells one reach wide, and each pair is found once, from the
        lower cell (its own cell and the 13 after it around each pellet). `bucket_end` has a power
        of two plus one entries; `rows` one per pellet of a shot, `cells` one per pellet. A list
        that overflows sets FLAG_OVERFLOW (to its length). It returns early, lists unfinished, once
        `cloud.stop` is set (an interrupt)."""
        buckets = bucket_end.shape[0] - 1
        mask = wp.uint32(buckets - 1)
        capacity = cloud.lists.neighbours.shape[1]
        first = s * pair.count
        time = cloud.clock.time[s]
        origin = drift_point(cloud, s, time, physics.gravity)
        done = cloud.shot_flags[s, SHOT_DONE] != 0
        reach = scalar(2.0) * (physics.radius + cloud.lists.half_skin[s])
        reach2 = reach * reach
        inverse = wp.float64(1.0) / (wp.float64(reach) * wp.float64(CELL_MARGIN))
        for b in range(buckets + 1):
            bucket_end[b] = 0
        for k in range(pair.count):
            i = first + k
            relative = set_build_point(cloud, physics, i, time, origin)
            cloud.lists.neighbour_count[i] = 0
            if cloud.state.phase[i] == FLYING and not done:
                cloud.event.stale[i] = 1  # a new list: its earliest event is found again
                cell = cell_of(relative, inverse)
                cells[i] = cell
                b = cell_bucket(cell, mask)
                bucket_end[b + 1] = bucket_end[b + 1] + 1
        for b in range(buckets):
            bucket_end[b + 1] = bucket_end[b + 1] + bucket_end[b]
        # (bucket_end[b] is where bucket b starts; filling moves it to where b ends)
        for k in range(pair.count):
            i = first + k
            if cloud.state.phase[i] == FLYING and not done:
                b = cell_bucket(cells[i], mask)
                rows[bucket_end[b]] = i
                bucket_end[b] = bucket_end[b] + 1
        for k in range(pair.count):
            i = first + k
            if cloud.stop[0] != 0:  # an interrupt: the host abandons the chunk
                return
            if cloud.state.phase[i] != FLYING or done:
                continue
            point = cloud.lists.grid_point[i]
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
                                d = cloud.lists.grid_point[j] - point
                                if wp.dot(d, d) <= reach2:
                                    list_pair(cloud, i, j, capacity)
        for k in range(pair.count):
            i = first + k
            found = cloud.lists.neighbour_count[i]
            if found > capacity:
                wp.atomic_max(cloud.flags, FLAG_OVERFLOW, found)
                cloud.lists.neighbour_count[i] = capacity

    return SimpleNamespace(
        grid_point_pellet=grid_point_pellet,
        grid_list=grid_list,
        cell_bucket=cell_bucket,
        cell_of=cell_of,
        list_pair=list_pair,
        cell_lists_shot=cell_lists_shot,
    )
