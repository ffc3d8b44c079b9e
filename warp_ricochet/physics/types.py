"""The kernels' precision and the scene constants the laws read, as Warp structs (SI units).

`types_for(precision)` gives the scalar and 3-vector types of "float32" or "float64" and the
`Surfaces` (planes) and `Physics` (pellet and gravity) structs that `model.Model` fills once per
scene and device.
"""

import functools
from types import SimpleNamespace

import warp as wp

SCALARS = {"float32": wp.float32, "float64": wp.float64}


@functools.cache
def types_for(precision: str) -> SimpleNamespace:
    """scalar, vec3, Surfaces and Physics of one precision ("float32" or "float64")."""
    scalar = SCALARS[precision]
    vec3 = wp.types.vector(3, scalar)

    @wp.struct
    class Surfaces:
        """Planes: a point (m), the unit normal towards the pellets, E, mu_s, mu_d."""

        point: wp.array(dtype=vec3)
        normal: wp.array(dtype=vec3)
        restitution: wp.array(dtype=scalar)
        mu_s: wp.array(dtype=scalar)
        mu_d: wp.array(dtype=scalar)

    @wp.struct
    class Physics:
        radius: scalar  # m
        inertia_factor: scalar  # I / (m R^2)
        gravity: vec3  # m/s^2
        impact_duration: scalar  # s, the paper's delta t

    return SimpleNamespace(precision=precision, scalar=scalar, vec3=vec3, Surfaces=Surfaces, Physics=Physics)
