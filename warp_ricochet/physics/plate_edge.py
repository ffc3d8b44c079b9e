"""Where a pellet moving along a plate leaves it over its edge (docs/geometry.md; SI units).

`physics.surface_follow` ends a phase along plate k where the pellet's centre, projected along
the plate's normal, leaves the plate (`geometry.inside`), and the pellet flies on from there:
- `leave_time(surfaces, k, face, x0, v, a, span)`: on the path x0 + v t + a t^2 / 2 of a phase of
  constant acceleration (or a straight line: a = 0, t a distance), the first of SAMPLES equal
  parts of [0, span] that ends off the plate, then bisected (BISECTIONS halvings) to the first
  point off it; span < 0: the phase has no end, and span grows (doubling) until the path is
  beyond the plate (`geometry.reach`). -1: the path stays on the plate.
- `leave_theta(surfaces, k, face, x0, d0, e0, x1, d1, e1)`: the same on an integration step's quintic
  Hermite (`integrate.hermite_vec`, theta in [0, 1]) that ends off the plate; 2 if it does not.
A path that leaves and comes back within one of the SAMPLES parts is taken to stay on. `face` >= 0:
the plate is triangle `face` of mesh k (`geometry.on_face`, `physics.triangle_follow`).
"""

import functools
from types import SimpleNamespace

import warp as wp

from .geometry import make_geometry
from .integrate import make_dense_output
from .types import types_for

SAMPLES = 32  # equal parts of a phase checked for the first one ending off the plate
BISECTIONS = 60  # halvings of that part: to rounding in float64 (2^-60 of it)
DOUBLINGS = 96  # of an endless phase's span, from MIN_SPAN s (a constant-acceleration path leaves by then)
MIN_SPAN = 1e-3


@functools.cache
def make_plate_edge(precision: str, plates=True) -> SimpleNamespace:
    """`leave_time` and `leave_theta` (module docstring) of one precision (`plates`: the geometry's)."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    geo, hermite_vec = make_geometry(precision, None, True, plates), make_dense_output(precision).hermite_vec
    HALF = scalar(0.5)

    @wp.func
    def leave_time(surfaces: Surfaces, k: wp.int32, face: wp.int32, x0: vec3, v: vec3, a: vec3, span: scalar):
        """The first time (or distance) in (0, span] where x0 + v t + a t^2 / 2 is off plate k, -1
        if none (span < 0: unbounded)."""
        if span < scalar(0.0):
            reach = geo.face_reach(surfaces, k, face, x0)
            span = scalar(MIN_SPAN)
            grown = wp.int32(0)
            while grown < DOUBLINGS and wp.length(v * span + (HALF * span * span) * a) <= reach:
                span = span * scalar(2.0)
                grown += 1
        lo = scalar(0.0)
        hi = scalar(-1.0)
        i = wp.int32(1)
        while i <= SAMPLES and hi < scalar(0.0):
            time = span * scalar(i) / scalar(SAMPLES)
            if geo.on_face(surfaces, k, face, x0 + v * time + (HALF * time * time) * a):
                lo = time
            else:
                hi = time
            i += 1
        if hi < scalar(0.0):
            return scalar(-1.0)
        for _ in range(BISECTIONS):
            mid = HALF * (lo + hi)
            if geo.on_face(surfaces, k, face, x0 + v * mid + (HALF * mid * mid) * a):
                lo = mid
            else:
                hi = mid
        return hi

    @wp.func
    def leave_theta(surfaces: Surfaces, k: wp.int32, face: wp.int32, x0: vec3, d0: vec3, e0: vec3, x1: vec3, d1: vec3, e1: vec3):
        """The first theta in (0, 1] where a step's Hermite (values x, h v, h^2 a at its ends) is
        off plate k, 2 if its end is on it."""
        if geo.on_face(surfaces, k, face, x1):
            return scalar(2.0)
        lo = scalar(0.0)
        hi = scalar(1.0)
        i = wp.int32(1)
        found = wp.int32(0)
        while i < SAMPLES and found == 0:
            theta = scalar(i) / scalar(SAMPLES)
            x, _slope = hermite_vec(theta, x0, d0, e0, x1, d1, e1)
            if geo.on_face(surfaces, k, face, x):
                lo = theta
            else:
                hi = theta
                found = wp.int32(1)
            i += 1
        for _ in range(BISECTIONS):
            mid = HALF * (lo + hi)
            x, _slope = hermite_vec(mid, x0, d0, e0, x1, d1, e1)
            if geo.on_face(surfaces, k, face, x):
                lo = mid
            else:
                hi = mid
        return hi

    return SimpleNamespace(leave_time=leave_time, leave_theta=leave_theta)
