"""Scenes: a TOML file describing one shot fired at planes, loaded into validated frozen dataclasses.

All quantities are SI: lengths and positions in m, times in s, velocities in m/s, angular velocities in rad/s,
densities in kg/m^3, accelerations in m/s^2; restitution and friction coefficients are dimensionless.

Layout of a scene file::

    [shot]        pellets: sampled (count, speed, direction, jitter, envelope, spin, seed) or read from `file`
    [[surfaces]]  planes: point, normal (towards the incoming pellets), restitution, mu_s, mu_d, name
    [physics]     gravity, impact_duration (the paper's delta t), bounces, until (rest or landing),
                  rest_speed, max_impacts, max_steps (docs/ground.md)
    [collisions]  pellet-pellet collisions (off by default): enabled, restitution, mu_s, mu_d, and the
                  time stepping of the dense phase (see docs/collisions.md)
    [air]         flight in air (absent: vacuum): density, viscosity, sound_speed, wind, the drag, lift
                  and spin-decay laws (see docs/air.md)
    [numerics]    precision, chunk_size, fast_math, flight_tolerance, surface_tolerance
    [output]      path (HDF5), fields

Every problem raises SceneError with a one-line message: the dotted key, the value and what is allowed.
This package imports numpy and the standard library only (h5py lazily, for .h5 pellet files); never warp.
Modules: `schema` (the dataclasses and the physical domain), `convert` (one converter per key),
`parse` (tables into a Scene), `overrides` (--set, --param, --tie), `pellets` (pellet files), `toml_out`.
"""

from ..fields import ALL_FIELDS, COLLISION_FIELDS, CORE_FIELDS, GROUPS
from .overrides import (
    apply_override,
    parse_sweep,
    parse_tie,
    set_dotted,
)
from .parse import load_scene, scene_from_dict
from .pellets import load_pellet_file
from .schema import (
    CHECKPOINT_STEPS,
    FLOAT32_EXACT_STEPS,
    INT32_MAX,
    MAX_COORDINATE,
    MAX_DENSITY,
    MAX_DIAMETER,
    MAX_FRICTION,
    MAX_GRAVITY,
    MAX_IMPACT_DURATION,
    MAX_SPEED,
    MAX_SPIN,
    MIN_DENSITY,
    MIN_DIAMETER,
    Air,
    Collisions,
    Hazard,
    Numerics,
    Output,
    Physics,
    Place,
    Reference,
    Scene,
    Shot,
    Surface,
    Vec3,
)
from .sweep import MAX_SWEEP_POINTS, SweepPoints

__all__ = [
    "Vec3",
    "Shot",
    "Surface",
    "Physics",
    "Collisions",
    "Air",
    "Hazard",
    "Place",
    "Reference",
    "Numerics",
    "Output",
    "Scene",
    "GROUPS",
    "CORE_FIELDS",
    "COLLISION_FIELDS",
    "ALL_FIELDS",
    "load_scene",
    "scene_from_dict",
    "apply_override",
    "set_dotted",
    "parse_sweep",
    "parse_tie",
    "load_pellet_file",
    "MAX_SWEEP_POINTS",
    "SweepPoints",
    "CHECKPOINT_STEPS",
    "FLOAT32_EXACT_STEPS",
    "INT32_MAX",
    "MAX_COORDINATE",
    "MAX_DENSITY",
    "MAX_DIAMETER",
    "MAX_FRICTION",
    "MAX_GRAVITY",
    "MAX_IMPACT_DURATION",
    "MAX_SPEED",
    "MAX_SPIN",
    "MIN_DENSITY",
    "MIN_DIAMETER",
]
