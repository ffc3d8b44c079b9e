"""The per-pellet output fields: one registry, from which the kernels' output struct, the scene's
validation of `output.fields` and the writer's datasets are made.

A field is named "group.name" (its HDF5 path is /pellets/group/name). Its `stage` says which part
of the pipeline produces it: "launch", "impact", "landing" and "rest" fields are written by the core
kernel (members of its Outputs struct, `core.types`; "rest" only in runs with physics.until = "rest",
where each pellet ends: `ends`), "collide" fields by the dense phase of pellet-pellet
collisions (only runs with collisions have them). Units are SI. This module imports nothing heavy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Field",
    "FIELDS",
    "GROUPS",
    "CORE_FIELDS",
    "COLLISION_FIELDS",
    "ALL_FIELDS",
    "core_fields",
    "collision_fields",
    "default_fields",
    "HAZARD_FIELDS",
    "REST_FIELDS",
    "numpy_dtype",
    "shape",
    "bytes_per_pellet",
]

INTEGER_KINDS = {"int8": np.int8, "int16": np.int16, "int32": np.int32}


@dataclass(frozen=True)
class Field:
    """One per-pellet output: `kind` is "vec3" or "scalar" (the run's precision) or an integer
    kind; `per_bounce` fields have one entry per ricochet followed, `per_threshold` fields one per
    hazard threshold (in scene order)."""

    name: str
    kind: str
    per_bounce: bool
    unit: str
    stage: str
    description: str
    per_threshold: bool = False

    @property
    def member(self) -> str:
        """Its member in the kernels' structs and its HDF5 path below /pellets."""
        return self.name.replace(".", "_")

    @property
    def path(self) -> str:
        return "pellets/" + self.name.replace(".", "/")


_F = Field
FIELDS: dict[str, Field] = {
    f.name: f
    for f in (
        _F("initial.position", "vec3", False, "m", "launch", "centre at launch"),
        _F("initial.velocity", "vec3", False, "m/s", "launch", "velocity at launch"),
        _F("initial.angular_velocity", "vec3", False, "rad/s", "launch", "angular velocity at launch"),
        _F("impact.time", "scalar", True, "s", "impact", "time of the impact since launch (NaN: no impact)"),
        _F("impact.position", "vec3", True, "m", "impact", "centre at the impact"),
        _F("impact.velocity_before", "vec3", True, "m/s", "impact", "velocity just before the impact"),
        _F("impact.angular_velocity_before", "vec3", True, "rad/s", "impact", "angular velocity just before the impact"),
        _F("impact.velocity", "vec3", True, "m/s", "impact", "velocity just after the impact (eq. 15)"),
        _F("impact.angular_velocity", "vec3", True, "rad/s", "impact", "angular velocity just after the impact (eqs. 20, 24)"),
        _F("impact.slipped", "int8", True, "1", "impact", "1 slip (eq. 22 met), 0 stick, -1 no impact"),
        _F("impact.surface", "int16", True, "1", "impact", "index of the surface hit, -1 none"),
        _F("landing.time", "scalar", False, "s", "landing", "landing time since launch (inf: never lands)"),
        _F("landing.position", "vec3", False, "m", "landing", "centre at landing (NaN: never lands)"),
        _F("landing.velocity", "vec3", False, "m/s", "landing", "velocity at landing"),
        _F(
            "landing.range",
            "scalar",
            False,
            "m",
            "landing",
            "distance from the last ricochet point to the landing point (eq. 42)",
        ),
        _F("landing.surface", "int16", False, "1", "landing", "index of the surface landed on, -1 none"),
        _F(
            "hazard.energy",
            "scalar",
            False,
            "J",
            "landing",
            "translational kinetic energy m |v|^2 / 2 at landing (NaN: never lands)",
        ),
        _F(
            "hazard.energy_density",
            "scalar",
            False,
            "J/m^2",
            "landing",
            "energy density E / (pi R^2) at landing (NaN: never lands)",
        ),
        _F(
            "hazard.exceeds",
            "int32",
            False,
            "1",
            "landing",
            "bit i set: at landing it exceeds hazard threshold i (/hazard/thresholds, in scene order); 0 when it never lands",
        ),
        _F(
            "hazard.reach",
            "scalar",
            False,
            "m",
            "landing",
            "per threshold (scene order): the farthest horizontal distance from the shooter at which it is within body height "
            "at or above the threshold, along its whole path (NaN: never; docs/hazard.md)",
            per_threshold=True,
        ),
        _F(
            "rest.position",
            "vec3",
            False,
            "m",
            "rest",
            "centre where it ends: at rest, entering the ground, or when its budget ran out (NaN: escaped)",
        ),
        _F(
            "rest.velocity",
            "vec3",
            False,
            "m/s",
            "rest",
            "velocity where it ends: 0 at rest, the entry velocity when embedded (NaN: escaped)",
        ),
        _F("rest.time", "scalar", False, "s", "rest", "time it ends since launch (inf: escaped)"),
        _F("rest.state", "int8", False, "1", "rest", "how it ends: the code of a name in the attribute states (ends.STATES)"),
        _F("rest.impacts", "int32", False, "1", "rest", "all its impacts, the dense phase's included"),
        _F("rest.path_length", "scalar", False, "m", "rest", "length of its path along surfaces (sliding, rolling, ploughing)"),
        _F("collisions.count", "int32", False, "1", "collide", "pellet-pellet collisions of the pellet"),
        _F(
            "collisions.last_time",
            "scalar",
            False,
            "s",
            "collide",
            "time of its last pellet-pellet collision since launch (NaN: none)",
        ),
        _F(
            "release.time",
            "scalar",
            False,
            "s",
            "collide",
            "when the time stepping handed it to the exact flight (or its flight ended in it)",
        ),
        _F("release.position", "vec3", False, "m", "collide", "centre at release"),
        _F("release.velocity", "vec3", False, "m/s", "collide", "velocity at release"),
        _F("release.angular_velocity", "vec3", False, "rad/s", "collide", "angular velocity at release"),
    )
}

# "group" -> its field names, in registry order (a scene may name a whole group in output.fields)
GROUPS: dict[str, tuple[str, ...]] = {}
for _name in FIELDS:
    GROUPS.setdefault(_name.split(".")[0], ())
    GROUPS[_name.split(".")[0]] += (_name.split(".")[1],)

CORE_FIELDS = tuple(name for name, f in FIELDS.items() if f.stage != "collide")
# written only when output.fields names them, or by default in a scene with a [hazard] table
HAZARD_FIELDS = tuple(name for name in FIELDS if name.startswith("hazard."))
COLLISION_FIELDS = tuple(name for name, f in FIELDS.items() if f.stage == "collide")
# written only in runs with physics.until = "rest" (by default there)
REST_FIELDS = tuple(name for name, f in FIELDS.items() if f.stage == "rest")
ALL_FIELDS = CORE_FIELDS + COLLISION_FIELDS


def core_fields(fields) -> tuple[str, ...]:
    """Those of `fields` the core kernel writes."""
    return tuple(f for f in fields if FIELDS[f].stage != "collide")


def collision_fields(fields) -> tuple[str, ...]:
    """Those of `fields` the dense phase writes."""
    return tuple(f for f in fields if FIELDS[f].stage == "collide")


def default_fields(pair_collisions: bool, hazard: bool, rest: bool = False) -> tuple[str, ...]:
    """output.fields when a scene names none: the core's (and the dense phase's with pair
    collisions), the hazard group only in a scene with a [hazard] table, the rest group only in a
    run that follows pellets to rest (physics.until = "rest")."""
    return tuple(
        f
        for f in (ALL_FIELDS if pair_collisions else CORE_FIELDS)
        if (hazard or f not in HAZARD_FIELDS) and (rest or f not in REST_FIELDS)
    )


def numpy_dtype(name: str, precision: str) -> np.dtype:
    kind = FIELDS[name].kind
    return np.dtype(INTEGER_KINDS.get(kind, precision))


def shape(name: str, rows: int, bounces: int, thresholds: int = 0) -> tuple[int, ...]:
    f = FIELDS[name]
    columns = (bounces,) if f.per_bounce else (thresholds,) if f.per_threshold else ()
    return (rows,) + columns + ((3,) if f.kind == "vec3" else ())


def bytes_per_pellet(fields, precision: str, bounces: int, thresholds: int = 0) -> int:
    """Bytes per pellet of these fields (on the device, and again on the host)."""
    return sum(numpy_dtype(n, precision).itemsize * int(np.prod(shape(n, 1, bounces, thresholds))) for n in fields)
