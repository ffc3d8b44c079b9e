"""Model (static scene constants on a device) and State (per-pellet buffers of one chunk).

Shaped after Newton: a `Model` holds what does not change during a run (pellet size, surfaces,
gravity) in the kernels' structs; a `State` holds the device arrays of one chunk, allocated only
for the output fields the run asks for (none for a statistics-only run).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import warp as wp

from .core.outputs import element_type, outputs_struct
from .fields import FIELDS, bytes_per_pellet, shape
from .physics.air import GAMMA_AIR
from .physics.impact import SOLID_SPHERE_INERTIA_FACTOR
from .physics.types import GROUND_FIELDS, surfaces_of, types_for
from .scene.materials import critical_angle, is_liquid, ploughing_rate
from .scene.triangles import TriangleSurface, file_stamp, triangles_of
from .tallies.reduce import LANES, SEGMENT_WIDTH, partial_bytes_per_pellet, threads_for
from .tallies.sums import NUM_EXTREMES, NUM_SUMS


@dataclass
class Model:
    """Scene constants on one device, in the kernels' structs (SI units). Its precision is its
    `types`' (`physics.types.types_for`), read from the scene's numerics.precision."""

    device: object  # wp.Device
    radius: float  # m
    mass: float  # kg
    inertia: float  # kg m^2, I = k m R^2
    bounces: int
    surfaces: object  # physics.types Surfaces
    physics: object  # physics.types Physics
    types: object = field(repr=False)
    thresholds: int = 0  # hazard thresholds (the columns of per-threshold fields)
    meshes: tuple = field(default=(), repr=False)  # per surface: its TriangleSurface, or None (plane, plate)

    @property
    def precision(self) -> str:
        """The kernels' precision, "float32" or "float64" (its `types`')."""
        return self.types.precision

    @classmethod
    def from_scene(cls, scene, device) -> Model:
        """The model of `scene` on `device`; recent ones are reused (their arrays never change)
        while their mesh and raster files are unchanged (`file_stamp`), but for a scene with a
        terrain placed through a site (`[hazard.site]`), placed from the whole scene each time."""
        air = scene.air if scene.in_air else None
        site = None if scene.hazard is None else scene.hazard.site
        if site is not None and any(s.kind == "terrain" for s in scene.surfaces):
            meshes = [
                terrain_triangles(scene, i) if s.kind == "terrain" else triangles_of(s) for i, s in enumerate(scene.surfaces)
            ]
            model = Model._build(
                scene.shot.diameter,
                scene.shot.density,
                scene.surfaces,
                scene.physics,
                scene.numerics.precision,
                wp.get_device(device.alias),
                air,
                (scene.numerics.flight_tolerance, scene.numerics.surface_tolerance),
                meshes=meshes,
            )
            return dataclasses.replace(model, thresholds=0 if scene.hazard is None else len(scene.hazard.thresholds))
        model = _cached_model(
            scene.shot.diameter,
            scene.shot.density,
            scene.surfaces,
            scene.physics,
            scene.numerics.precision,
            device.alias,
            air,
            (scene.numerics.flight_tolerance, scene.numerics.surface_tolerance),
            tuple(file_stamp(s.file) if s.kind in ("mesh", "terrain") else None for s in scene.surfaces),
        )
        return dataclasses.replace(model, thresholds=0 if scene.hazard is None else len(scene.hazard.thresholds))

    @classmethod
    def _build(
        cls, diameter, density, planes, physics_scene, precision, device, air=None, tolerances=(1e-6, 1e-6), meshes=None
    ) -> Model:
        """`tolerances`: numerics' (flight_tolerance, surface_tolerance)."""
        t = types_for(precision)
        radius = 0.5 * diameter
        mass = density * 4.0 / 3.0 * math.pi * radius**3
        if meshes is None:  # (a terrain without a site: placed from its surface alone)
            meshes = [
                terrain_triangles(SimpleNamespace(surfaces=planes, hazard=None), i) if p.kind == "terrain" else triangles_of(p)
                for i, p in enumerate(planes)
            ]
        surfaces = surfaces_of(
            precision,
            [p.point for p in planes],
            [p.normal for p in planes],
            [(p.restitution, p.mu_s, p.mu_d) for p in planes],
            device,
            ground=ground_of(planes, radius, density),
            liquid=[is_liquid(p.material) for p in planes],
            plates=[plate_of(p) for p in planes],
            meshes=meshes,
        )
        physics = t.Physics()
        physics.radius = t.scalar(radius)
        physics.inertia_factor = t.scalar(SOLID_SPHERE_INERTIA_FACTOR)
        physics.gravity = t.vec3(*physics_scene.gravity)
        physics.impact_duration = t.scalar(physics_scene.impact_duration)
        physics.rest_speed = t.scalar(physics_scene.rest_speed_for(radius))
        physics.max_impacts = physics_scene.max_impacts
        physics.max_steps = physics_scene.max_steps
        physics.surface_tolerance = t.scalar(tolerances[1])
        physics.air = air_struct(air, precision, device, radius, mass, physics_scene.gravity, tolerances[0])
        return cls(
            device=device,
            radius=radius,
            mass=mass,
            inertia=SOLID_SPHERE_INERTIA_FACTOR * mass * radius**2,
            bounces=physics_scene.bounces,
            surfaces=surfaces,
            physics=physics,
            types=t,
            meshes=tuple(meshes),
        )


@functools.lru_cache(maxsize=16)
def _cached_model(diameter, density, surfaces, physics, precision, device_alias, air, tolerances, stamps) -> Model:
    """`Model._build`, reused while its arguments and its mesh and raster files' `stamps` (`file_stamp`)
    are the same."""
    return Model._build(diameter, density, surfaces, physics, precision, wp.get_device(device_alias), air, tolerances)


def terrain_triangles(scene, index: int):
    """Terrain surface `index` of `scene` as triangles in scene coordinates (`scene.terrain.place_terrain`)."""
    from .scene.terrain import place_terrain

    vertices, triangles, grid = place_terrain(scene, index, grid=True)
    name = scene.surfaces[index].name or f"surfaces.{index}"
    surface = TriangleSurface(vertices, triangles.astype(np.int32), f"terrain {name!r}", edges=False, grid=grid)
    return surface.check(f"surfaces.{index}.file")


def plate_of(surface):
    """`types.plate_arrays`' entry of a scene surface: None for a plane, else (kind, axis_u,
    half_u, half_v, two_sided); a disc's radius is both half sides, a cylinder's (radius, length)."""
    if surface.is_plane:
        return None
    if surface.is_mesh:
        return ("mesh", (0.0, 0.0, 0.0), 0.0, 0.0, False)
    if surface.kind == "disc":
        return (surface.kind, (0.0, 0.0, 0.0), surface.radius, surface.radius, surface.two_sided)
    if surface.kind == "cylinder":  # half_u: its radius, half_v: its length
        return (surface.kind, (0.0, 0.0, 0.0), surface.radius, surface.length, False)
    return (surface.kind, surface.axis_u, 0.5 * surface.size[0], 0.5 * surface.size[1], surface.two_sided)


def ground_of(planes, radius: float, density: float) -> dict:
    """The kernels' ground values of a scene's surfaces (`types.GROUND_FIELDS`: angles in radians,
    the ploughing b in 1/m for this pellet; scene.materials) for a pellet of `radius` (m) and
    `density` (kg/m^3), in float64."""
    out = {name: [] for name in GROUND_FIELDS}
    for p in planes:
        out["rolling_resistance"].append(p.ground("rolling_resistance"))
        out["ploughing"].append(ploughing_rate(p.ground("ploughing"), p.ground("ploughing_area"), radius, density))
        out["critical_angle"].append(critical_angle(p, density))
        for name in ("critical_angle_rise", "roughness"):
            out[name].append(math.radians(p.ground(name)))
        for name in ("critical_speed", "restitution_scatter", "friction_scatter", "skip_loss"):
            out[name].append(p.ground(name))
    return out


def air_struct(air, precision: str, device, radius: float, mass: float, gravity, tolerance: float):
    """The kernels' Air struct of a scene's [air] (None: zeros, as in vacuum): the constants the
    laws of physics.air read, premultiplied here in float64 (SI)."""
    t = types_for(precision)
    out = t.Air()
    np_dtype = np.dtype(precision)
    table = np.zeros((0, 2))
    if air is not None:
        d, area = 2.0 * radius, math.pi * radius**2
        inertia = SOLID_SPHERE_INERTIA_FACTOR * mass * radius**2
        constants = {
            "inverse_sound_speed": 1.0 / air.sound_speed,
            "re_per_speed": air.density * d / air.viscosity,
            "knudsen": math.sqrt(0.5 * math.pi * GAMMA_AIR) * air.viscosity / (air.density * air.sound_speed * d),
            "stokes": 3.0 * math.pi * air.viscosity * d * air.drag_factor / mass,
            "quadratic": air.density * area * air.drag_factor / (2.0 * mass),
            "drag_coefficient": air.drag_coefficient or 0.0,
            "lift": air.density * area * radius / (2.0 * mass),
            "radius": radius,
            "lift_slope": air.slope,
            "lift_max": air.cap,
            "spin": 8.0 * math.pi * air.viscosity * radius**3 / inertia,
            "re_r_per_spin": air.density * d * d / air.viscosity,
            "tolerance": tolerance,
            "speed_floor": max(math.sqrt(math.hypot(*gravity) * radius), 1e-6),
        }
        for name, value in constants.items():
            setattr(out, name, t.scalar(value))
        out.wind = t.vec3(*air.wind)
        if air.drag == "table":
            table = np.asarray(air.table, dtype=np.float64)
    out.table_mach = wp.array(np.ascontiguousarray(table[:, 0], dtype=np_dtype), dtype=t.scalar, device=device)
    out.table_cd = wp.array(np.ascontiguousarray(table[:, 1], dtype=np_dtype), dtype=t.scalar, device=device)
    return out


class State:
    """Per-pellet device buffers of one chunk of up to `capacity` pellets (core kernel rows), for
    the core `fields` only, and the statistics partials of its threads and segments."""

    def __init__(self, model: Model, capacity: int, fields, lanes: int = LANES):
        self.capacity, self.lanes = capacity, lanes
        self.fields = tuple(fields)
        self.arrays = {
            name: wp.empty(
                shape(name, capacity, model.bounces, model.thresholds)[:2]
                if FIELDS[name].per_bounce or FIELDS[name].per_threshold
                else capacity,
                dtype=element_type(name, model.precision),
                device=model.device,
            )
            for name in self.fields
        }
        self.outputs = outputs_struct(model.precision, model.device, self.arrays)
        threads = threads_for(capacity, lanes)
        self.partial_sums = wp.empty((NUM_SUMS, threads), dtype=wp.float64, device=model.device)
        self.partial_min = wp.empty((NUM_EXTREMES, threads), dtype=wp.float64, device=model.device)
        self.partial_max = wp.empty((NUM_EXTREMES, threads), dtype=wp.float64, device=model.device)
        self.segments = wp.empty((threads // lanes, SEGMENT_WIDTH), dtype=wp.float64, device=model.device)
        self.scratch_partials = None  # a rerun's partials, thrown away (`pipeline.launch_core`)

    @staticmethod
    def bytes_per_pellet(precision: str, fields, bounces: int, lanes: int = LANES) -> float:
        """Device bytes per pellet: the output fields plus the partial statistics."""
        return partial_bytes_per_pellet(lanes) + bytes_per_pellet(fields, precision, bounces)


_LAST_STATE: dict = {}


def held_state_bytes(device) -> int:
    """Device bytes of the chunk buffers kept from the last run on `device` (`reused_state`): free
    for a run's planning, as a run frees them before it allocates unless it reuses them
    (`pipeline.release_kept`)."""
    state = _LAST_STATE.get("state")
    if state is None or _LAST_STATE["key"][0] != getattr(device, "alias", None):
        return 0
    arrays = [*state.arrays.values(), state.partial_sums, state.partial_min, state.partial_max, state.segments]
    return sum(a.capacity for a in arrays + list(state.scratch_partials or ()))


def state_key(model: Model, capacity: int, fields, lanes: int = LANES) -> tuple:
    """What `reused_state` keeps its buffers by: device, precision, bounces, thresholds, capacity,
    fields and lanes."""
    return (model.device.alias, model.precision, model.bounces, model.thresholds, capacity, tuple(fields), lanes)


def release_kept_state(unless=None) -> bool:
    """Free the chunk buffers kept from the last run, unless they are kept by the key `unless`.
    Returns whether they were kept."""
    if unless is not None and _LAST_STATE.get("key") == unless:
        return True
    _LAST_STATE.clear()
    return False


def reused_state(model: Model, capacity: int, fields, lanes: int = LANES) -> State:
    """The last run's chunk buffers if they fit (device, precision, bounces, capacity, fields),
    else new ones, which replace them: one set is kept in all, so device memory does not grow with
    the runs of a sweep. Only for CUDA runs, one at a time (pipeline's lock)."""
    key = state_key(model, capacity, fields, lanes)
    if _LAST_STATE.get("key") != key:
        _LAST_STATE.clear()  # free the old buffers before allocating new ones
        _LAST_STATE.update(key=key, state=State(model, capacity, fields, lanes))
    return _LAST_STATE["state"]
