"""Model (static scene constants on a device) and State (per-pellet buffers of one chunk).

Shaped after Newton: a `Model` holds what does not change during a run (pellet size,
surfaces, gravity); a `State` holds the per-pellet arrays of one chunk, allocated only for the
output fields the scene asks for (none for a statistics-only run).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from .impact_law import SOLID_SPHERE_INERTIA_FACTOR
from .kernels import LANES, PER_THREAD, kernels_for
from .stats import NUM_EXTREMES, NUM_SUMS

# "group.field" -> (Outputs member, element kind, per bounce?, unit, description)
FIELD_SPECS = {
    "initial.position": ("initial_position", "vec3", False, "m", "centre at launch"),
    "initial.velocity": ("initial_velocity", "vec3", False, "m/s", "velocity at launch"),
    "initial.angular_velocity": ("initial_angular_velocity", "vec3", False, "rad/s", "angular velocity at launch"),
    "impact.time": ("impact_time", "scalar", True, "s", "time of the impact since launch (NaN: no impact)"),
    "impact.position": ("impact_position", "vec3", True, "m", "centre at the impact"),
    "impact.velocity_before": ("impact_velocity_before", "vec3", True, "m/s", "velocity just before the impact"),
    "impact.angular_velocity_before": ("impact_angular_velocity_before", "vec3", True, "rad/s", "angular velocity just before the impact"),
    "impact.velocity": ("impact_velocity", "vec3", True, "m/s", "velocity just after the impact (eq. 15)"),
    "impact.angular_velocity": ("impact_angular_velocity", "vec3", True, "rad/s", "angular velocity just after the impact (eqs. 20, 24)"),
    "impact.slipped": ("impact_slipped", "int8", True, "1", "1 slip (eq. 22 met), 0 stick, -1 no impact"),
    "impact.surface": ("impact_surface", "int16", True, "1", "index of the surface hit, -1 none"),
    "landing.time": ("landing_time", "scalar", False, "s", "landing time since launch (inf: never lands)"),
    "landing.position": ("landing_position", "vec3", False, "m", "centre at landing (NaN: never lands)"),
    "landing.velocity": ("landing_velocity", "vec3", False, "m/s", "velocity at landing"),
    "landing.range": ("landing_range", "scalar", False, "m", "distance from the last ricochet point to the landing point (eq. 42)"),
    "landing.surface": ("landing_surface", "int16", False, "1", "index of the surface landed on, -1 none"),
    # runs with pellet-pellet collisions (written from the dense phase's arrays, not Outputs)
    "collisions.count": (None, "int32", False, "1", "pellet-pellet collisions of the pellet"),
    "collisions.last_time": (None, "scalar", False, "s", "time of its last pellet-pellet collision since launch (NaN: none)"),
    "release.time": (None, "scalar", False, "s", "when the time stepping handed it to the exact flight (or its flight ended in it)"),
    "release.position": (None, "vec3", False, "m", "centre at release"),
    "release.velocity": (None, "vec3", False, "m/s", "velocity at release"),
    "release.angular_velocity": (None, "vec3", False, "rad/s", "angular velocity at release"),
}

_INT_DTYPES = {"int8": (wp.int8, np.int8), "int16": (wp.int16, np.int16), "int32": (wp.int32, np.int32)}


def field_numpy_dtype(kind: str, precision: str):
    if kind in _INT_DTYPES:
        return np.dtype(_INT_DTYPES[kind][1])
    return np.dtype(precision)


def field_shape(kind: str, per_bounce: bool, rows: int, bounces: int) -> tuple[int, ...]:
    shape = (rows, bounces) if per_bounce else (rows,)
    return shape + ((3,) if kind == "vec3" else ())


@dataclass
class Model:
    """Scene constants on one device, in the kernels' structs (SI units)."""

    device: object  # wp.Device
    precision: str
    radius: float  # m
    mass: float  # kg
    inertia: float  # kg m^2, I = k m R^2
    bounces: int
    surfaces: object  # kernels.Surfaces
    physics: object  # kernels.Physics
    kernels: object = field(repr=False)

    @classmethod
    def from_scene(cls, scene, device) -> "Model":
        """The model of `scene` on `device`; recent ones are reused (their arrays never change)."""
        return _cached_model(scene.shot.diameter, scene.shot.density, scene.surfaces, scene.physics,
                             scene.numerics.precision, device.alias)

    def state(self, capacity: int, fields) -> "State":
        """The last run's chunk buffers if they fit (device, precision, bounces, capacity, fields),
        else new ones, which replace them: one set is kept in all, so device memory does not
        grow with the runs of a sweep. Only for runs holding api's CUDA lock (one at a time)."""
        key = (self.device.alias, self.precision, self.bounces, capacity, tuple(fields))
        if _LAST_STATE.get("key") != key:
            _LAST_STATE.clear()  # free the old buffers before allocating new ones
            _LAST_STATE.update(key=key, state=State(self, capacity, fields))
        return _LAST_STATE["state"]

    @classmethod
    def _build(cls, diameter, density, planes, physics_scene, precision, device) -> "Model":
        kern = kernels_for(precision)
        scalar, vec3 = kern.scalar, kern.vec3
        radius = 0.5 * diameter
        mass = density * 4.0 / 3.0 * math.pi * radius**3
        surfaces = kern.Surfaces()
        np_dtype = np.dtype(precision)

        def column(values, dtype):
            shape = (len(planes), 3) if dtype is vec3 else (len(planes),)
            return wp.array(np.asarray(values, dtype=np_dtype).reshape(shape), dtype=dtype, device=device)

        surfaces.point = column([p.point for p in planes], vec3)
        surfaces.normal = column([p.normal for p in planes], vec3)
        surfaces.restitution = column([p.restitution for p in planes], scalar)
        surfaces.mu_s = column([p.mu_s for p in planes], scalar)
        surfaces.mu_d = column([p.mu_d for p in planes], scalar)
        physics = kern.Physics()
        physics.radius = scalar(radius)
        physics.inertia_factor = scalar(SOLID_SPHERE_INERTIA_FACTOR)
        physics.gravity = vec3(*physics_scene.gravity)
        physics.impact_duration = scalar(physics_scene.impact_duration)
        return cls(
            device=device, precision=precision, radius=radius, mass=mass,
            inertia=SOLID_SPHERE_INERTIA_FACTOR * mass * radius**2, bounces=physics_scene.bounces,
            surfaces=surfaces, physics=physics, kernels=kern,
        )


_LAST_STATE: dict = {}


@functools.lru_cache(maxsize=16)
def _cached_model(diameter, density, surfaces, physics, precision, device_alias) -> Model:
    return Model._build(diameter, density, surfaces, physics, precision, wp.get_device(device_alias))


@functools.lru_cache(maxsize=8)
def _empty_outputs(precision: str, device_alias: str):
    """An Outputs struct whose arrays are all empty: what a statistics-only run passes."""
    kern = kernels_for(precision)
    device = wp.get_device(device_alias)
    outputs = kern.Outputs()
    for member, kind, per_bounce, _unit, _doc in FIELD_SPECS.values():
        if member is None:
            continue
        dtype = {"vec3": kern.vec3, "scalar": kern.scalar}.get(kind) or _INT_DTYPES[kind][0]
        setattr(outputs, member, wp.empty((0, 0) if per_bounce else 0, dtype=dtype, device=device))
    return outputs


@functools.lru_cache(maxsize=8)
def empty_cloud(precision: str, device_alias: str):
    """A Cloud struct whose arrays are all empty: what runs without collisions pass."""
    kern = kernels_for(precision)
    device = wp.get_device(device_alias)
    cloud = kern.Cloud()
    for name, var in kern.Cloud.vars.items():
        if wp.types.is_array(var.type):
            setattr(cloud, name, wp.empty((0,) * var.type.ndim, dtype=var.type.dtype, device=device))
    return cloud


def threads_for(rows: int) -> int:
    """Threads (a whole number of LANES groups) that cover `rows` pellets."""
    segments = -(-rows // (LANES * PER_THREAD))
    return max(segments, 1) * LANES


class State:
    """Per-pellet device buffers of one chunk of up to `capacity` pellets, for `fields` only."""

    def __init__(self, model: Model, capacity: int, fields):
        kern = model.kernels
        self.capacity = capacity
        self.fields = tuple(fields)
        self.arrays = {}
        self.outputs = _empty_outputs(model.precision, model.device.alias)
        self.cloud = empty_cloud(model.precision, model.device.alias)
        if self.fields:
            empty = self.outputs
            self.outputs = kern.Outputs()
            for name, (member, kind, per_bounce, _unit, _doc) in FIELD_SPECS.items():
                if member is None:
                    continue  # collision fields: the dense phase's arrays (api)
                arr = getattr(empty, member)
                if name in self.fields:
                    shape = (capacity, model.bounces) if per_bounce else (capacity,)
                    arr = self.arrays[name] = wp.empty(shape, dtype=arr.dtype, device=model.device)
                setattr(self.outputs, member, arr)
        threads = threads_for(capacity)
        self.partial_sums = wp.empty((NUM_SUMS, threads), dtype=wp.float64, device=model.device)
        self.partial_min = wp.empty((NUM_EXTREMES, threads), dtype=wp.float64, device=model.device)
        self.partial_max = wp.empty((NUM_EXTREMES, threads), dtype=wp.float64, device=model.device)
        segments = threads // LANES
        self.segments = wp.empty((segments, NUM_SUMS + 2 * NUM_EXTREMES), dtype=wp.float64, device=model.device)

    @staticmethod
    def field_bytes_per_pellet(precision: str, fields, bounces: int) -> int:
        """Bytes per pellet of these output fields (on the device, and again on the host)."""
        total = 0
        for name in fields:
            _member, kind, per_bounce, _unit, _doc = FIELD_SPECS[name]
            size = field_numpy_dtype(kind, precision).itemsize * (3 if kind == "vec3" else 1)
            total += size * (bounces if per_bounce else 1)
        return total

    @staticmethod
    def bytes_per_pellet(precision: str, fields, bounces: int) -> float:
        """Device bytes per pellet: the output fields plus the partial statistics."""
        return (NUM_SUMS + 2 * NUM_EXTREMES) * 8 / PER_THREAD + State.field_bytes_per_pellet(precision, fields, bounces)
