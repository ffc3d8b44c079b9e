"""The other surfaces ahead of a phase over the distance along a plane (`surface_line`, docs/ground.md
9): the distance along the line to the first infinite plane it closes on (`ahead_of`, exact on a
straight line), and how far the centre may move on any path before the sphere can touch a plate, a
mesh or a post (`free_of`: their least clearance less R), by which `capped` bounds a step."""

import functools
from types import SimpleNamespace

import warp as wp

from .geometry import make_geometry
from .types import types_for

NEAR = 0.25  # a plate, mesh or post nearer than NEAR x the step: the phase goes on in 3-D


@functools.cache
def make_line_ahead(precision: str, planes=None, plates=False) -> SimpleNamespace:
    """`surface_count`, `ahead_of`, `free_of` and `capped` for one precision, number of planes (None: read at run
    time) and `plates` (`geometry.make_geometry`'s: whether plates, meshes and posts are compiled in)."""
    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    STATIC, PLATES = planes, bool(plates)
    geo = make_geometry(precision, planes, True, plates)
    ZERO, FAR = scalar(0.0), scalar(1e30)

    @wp.func
    def surface_count(surfaces: Surfaces):
        """The number of surfaces (fixed at code generation when `planes` is given)."""
        count = geo.count(surfaces)
        if wp.static(STATIC is not None):
            count = wp.static(STATIC)
        return count

    @wp.func
    def ahead_of(position: vec3, k: wp.int32, surfaces: Surfaces, physics: Physics, direction: vec3):
        """(distance along `direction` to the first other infinite plane on the line, surface) or (FAR, -1)."""
        ahead = FAR
        k_ahead = wp.int32(-1)
        for j in range(surface_count(surfaces)):
            plane = j != k
            if wp.static(PLATES):
                plane = plane and not geo.is_plate(surfaces, j)  # (`free_of`'s)
            if plane:
                height, gap, n = geo.gap(surfaces, j, position, physics.radius)
                closing = -wp.dot(direction, n)
                if height >= ZERO and closing > ZERO:
                    s = wp.max(gap, ZERO) / closing
                    if s < ahead:
                        ahead = s
                        k_ahead = wp.int32(j)
        return ahead, k_ahead

    @wp.func
    def free_of(position: vec3, k: wp.int32, surfaces: Surfaces, physics: Physics):
        """How far (m) the centre can move from `position`, along any path, before the sphere can
        touch a plate, mesh or post other than k: their least clearance less R (FAR: none)."""
        free = FAR
        if wp.static(PLATES):
            for j in range(surface_count(surfaces)):
                if j != k and geo.is_plate(surfaces, j):
                    free = wp.min(free, geo.clearance(surfaces, j, position) - physics.radius)
        return free

    @wp.func
    def capped(position: vec3, k: wp.int32, surfaces: Surfaces, physics: Physics, h: scalar):
        """(the step h within `free_of`, whether a plate, mesh or post is nearer than NEAR h: the
        phase then goes on in 3-D, which meets it)."""
        near = False
        if wp.static(PLATES):
            free = free_of(position, k, surfaces, physics)
            if free < h:
                near = free < scalar(NEAR) * h
                h = free
        return h, near

    return SimpleNamespace(surface_count=surface_count, ahead_of=ahead_of, free_of=free_of, capped=capped)
