"""Model (static scene constants on a device) and State (per-pellet buffers of one chunk).

Shaped after Newton: a `Model` holds what does not change during a run (pellet size, surfaces,
gravity) in the kernels' structs; a `State` holds the device arrays of one chunk, allocated only
for the output fields the run asks for (none for a statistics-only run).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from .core.outputs import element_type, outputs_struct
from .fields import FIELDS, bytes_per_pellet
from .physics.impact import SOLID_SPHERE_INERTIA_FACTOR
from .physics.types import types_for
from .tallies.reduce import LANES, SEGMENT_WIDTH, partial_bytes_per_pellet, threads_for
from .tallies.sums import NUM_EXTREMES, NUM_SUMS


@dataclass
class Model:
    """Scene constants on one device, in the kernels' structs (SI units)."""

    device: object  # wp.Device
    precision: str
    radius: float  # m
    mass: float  # kg
    inertia: float  # kg m^2, I = k m R^2
    bounces: int
    surfaces: object  # physics.types Surfaces
    physics: object  # physics.types Physics
    types: object = field(repr=False)

    @classmethod
    def from_scene(cls, scene, device) -> "Model":
        """The model of `scene` on `device`; recent ones are reused (their arrays never change)."""
        return _cached_model(scene.shot.diameter, scene.shot.density, scene.surfaces, scene.physics,
                             scene.numerics.precision, device.alias)

    @classmethod
    def _build(cls, diameter, density, planes, physics_scene, precision, device) -> "Model":
        t = types_for(precision)
        radius = 0.5 * diameter
        mass = density * 4.0 / 3.0 * math.pi * radius**3
        np_dtype = np.dtype(precision)

        def column(values, dtype):
            shape = (len(planes), 3) if dtype is t.vec3 else (len(planes),)
            return wp.array(np.asarray(values, dtype=np_dtype).reshape(shape), dtype=dtype, device=device)

        surfaces = t.Surfaces()
        surfaces.point = column([p.point for p in planes], t.vec3)
        surfaces.normal = column([p.normal for p in planes], t.vec3)
        surfaces.restitution = column([p.restitution for p in planes], t.scalar)
        surfaces.mu_s = column([p.mu_s for p in planes], t.scalar)
        surfaces.mu_d = column([p.mu_d for p in planes], t.scalar)
        physics = t.Physics()
        physics.radius = t.scalar(radius)
        physics.inertia_factor = t.scalar(SOLID_SPHERE_INERTIA_FACTOR)
        physics.gravity = t.vec3(*physics_scene.gravity)
        physics.impact_duration = t.scalar(physics_scene.impact_duration)
        return cls(device=device, precision=precision, radius=radius, mass=mass,
                   inertia=SOLID_SPHERE_INERTIA_FACTOR * mass * radius**2, bounces=physics_scene.bounces,
                   surfaces=surfaces, physics=physics, types=t)


@functools.lru_cache(maxsize=16)
def _cached_model(diameter, density, surfaces, physics, precision, device_alias) -> Model:
    return Model._build(diameter, density, surfaces, physics, precision, wp.get_device(device_alias))


class State:
    """Per-pellet device buffers of one chunk of up to `capacity` pellets (core kernel rows), for
    the core `fields` only, and the statistics partials of its threads and segments."""

    def __init__(self, model: Model, capacity: int, fields):
        self.capacity = capacity
        self.fields = tuple(fields)
        self.arrays = {name: wp.empty((capacity, model.bounces) if FIELDS[name].per_bounce else capacity,
                                      dtype=element_type(name, model.precision), device=model.device)
                       for name in self.fields}
        self.outputs = outputs_struct(model.precision, model.device, self.arrays)
        threads = threads_for(capacity)
        self.partial_sums = wp.empty((NUM_SUMS, threads), dtype=wp.float64, device=model.device)
        self.partial_min = wp.empty((NUM_EXTREMES, threads), dtype=wp.float64, device=model.device)
        self.partial_max = wp.empty((NUM_EXTREMES, threads), dtype=wp.float64, device=model.device)
        self.segments = wp.empty((threads // LANES, SEGMENT_WIDTH), dtype=wp.float64, device=model.device)

    @staticmethod
    def bytes_per_pellet(precision: str, fields, bounces: int) -> float:
        """Device bytes per pellet: the output fields plus the partial statistics."""
        return partial_bytes_per_pellet() + bytes_per_pellet(fields, precision, bounces)


_LAST_STATE: dict = {}


def reused_state(model: Model, capacity: int, fields) -> State:
    """The last run's chunk buffers if they fit (device, precision, bounces, capacity, fields),
    else new ones, which replace them: one set is kept in all, so device memory does not grow with
    the runs of a sweep. Only for CUDA runs, one at a time (pipeline's lock)."""
    key = (model.device.alias, model.precision, model.bounces, capacity, tuple(fields))
    if _LAST_STATE.get("key") != key:
        _LAST_STATE.clear()  # free the old buffers before allocating new ones
        _LAST_STATE.update(key=key, state=State(model, capacity, fields))
    return _LAST_STATE["state"]
