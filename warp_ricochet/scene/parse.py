"""Scenes from TOML: tables validated into the dataclasses of `schema`; every problem one SceneError line."""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
import warnings
from pathlib import Path

import numpy as np

from ..errors import SceneWarning, not_regular
from ..fields import COLLISION_FIELDS, FIELDS, REST_FIELDS, default_fields
from ..launch.packing import MAX_PACKING, packing_fraction
from ..physics.limits import MAX_PLANES_IN_AIR
from . import materials
from .convert import SCHEMAS
from .keys import MISSING, _Shown, check_keys, err, suggest
from .keys import table as _table
from .loads import apply_load, required
from .overrides import apply_override
from .patterns import resolve_pattern
from .pellets import check_pellet_file, pellet_file_rows, position_pieces
from .schema import (
    CHECKPOINT_STEPS,
    FILE_EXCLUSIVE,
    FLOAT32_EXACT_STEPS,
    INT32_MAX,
    MAX_THRESHOLDS,
    MIN_FLIGHT_TOLERANCE,
    PERPENDICULAR,
    Air,
    Collisions,
    Hazard,
    Numerics,
    Output,
    Physics,
    Scene,
    Shot,
    Surface,
)
from .solids import SOLIDS, closed_triangles, envelope_gap, inside_rows, winding_level
from .stations import check_stations, parse_stations
from .terrain import TERRAIN_OPTIONAL, check_terrain, up_of
from .triangles import load_mesh
from .vectors import unit_vector


def _shot(raw, base_dir) -> Shot:
    kw = _table(raw, "shot", SCHEMAS["shot"])
    if "load" in kw:  # the pellets' size, material and charge (scene.loads), under the scene's own keys
        kw = apply_load(kw, raw, INT32_MAX)
    for key in ("diameter", "density"):
        required(kw, key, SCHEMAS["shot"][key].rule)
    kw = resolve_pattern(kw, raw)
    if "file" not in kw:
        for key in ("count", "speed"):
            if key not in kw:
                also = " (or shot.load.charge)" if key == "count" else ""
                raise err(f"shot.{key}", MISSING, f"is required without shot.file{also}; it {SCHEMAS['shot'][key].rule}")
        if kw["count"] * kw.get("shots", 1) > INT32_MAX:
            raise err("shot.shots", kw["shots"], f"times shot.count ({kw['count']}) must be at most {INT32_MAX} pellets")
        return Shot(**kw)
    for key in FILE_EXCLUSIVE:
        if key in kw:
            raise err(f"shot.{key}", raw[key], "not allowed together with shot.file")
    kw["file"] = os.path.abspath(os.path.join(os.fspath(base_dir), kw["file"]))
    n = pellet_file_rows(kw["file"])  # declared: nothing read yet
    shots = kw.get("shots", 1)
    if n % shots:
        raise err("shot.shots", shots, f"must divide the number of pellets in shot.file ({n}): consecutive blocks are shots")
    if kw.setdefault("count", n // shots) != n // shots:
        raise err("shot.count", kw["count"], f"must equal the pellets per shot in shot.file ({n} / {shots} shots) or be left out")
    check_pellet_file(kw["file"])  # the memory a run holds them in, then their values, a piece at a time
    return Shot(**kw)


def _surface(raw, path: str, base_dir=".") -> Surface:
    material = raw.get("material") if isinstance(raw, dict) else None
    kind = raw.get("kind") if isinstance(raw, dict) else None
    mesh = kind == "mesh"  # placed by an optional point; no normal
    placed = () if kind in ("terrain", "mesh") else ("point", "normal")  # (scene.terrain, scene.triangles)
    required = placed if material is not None else (*placed, "restitution", "mu_s")
    kw = _table(raw, path, SCHEMAS["surfaces"], required=required)
    if mesh:  # the triangles carry their normals: a mesh's own is unused (kept for round trips)
        kw = {"point": (0.0, 0.0, 0.0), "normal": (0.0, 0.0, 1.0), **kw}
    if "normal" in kw and abs(math.hypot(*kw["normal"]) - 1.0) > 1e-15:  # keeps normalisation idempotent (round trips)
        kw["normal"] = unit_vector(kw["normal"])  # scaled first: a tiny normal does not underflow
    if material is not None:
        kw = _with_material(kw, raw, path)
    if kw.setdefault("mu_d", kw["mu_s"]) > kw["mu_s"]:
        raise err(f"{path}.mu_d", raw["mu_d"], f"must be a number in [0, mu_s = {kw['mu_s']:g}]")
    kw = _plate(kw, raw, path)
    if mesh:
        kw["file"] = os.path.abspath(os.path.join(os.fspath(base_dir), kw["file"]))
        load_mesh(kw["file"], f"{path}.file", kw["point"])  # checked now: one line, before any work
    return Surface(**kw)


# the keys each kind of surface takes beside the plane's (docs/geometry.md)
PLATE_KEYS = {
    "plane": (),
    "rectangle": ("axis_u", "size", "two_sided"),
    "disc": ("radius", "two_sided"),
    "terrain": ("file", "axis_u", "origin", "elevation", "nodata"),
    "box": ("axis_u", "size"),
    "mesh": ("file",),
    "cylinder": ("radius", "length"),
}
OPTIONAL_KEYS = {"rectangle": ("two_sided",), "disc": ("two_sided",), "terrain": TERRAIN_OPTIONAL}
SIDES = {"rectangle": 2, "box": 3}  # the numbers in a size


def _plate(kw: dict, raw: dict, path: str) -> dict:
    """A surface's kind and its plate keys checked together: each kind's keys required (two_sided
    optional), no other kind's; a rectangle's axis_u perpendicular to its normal (within
    PERPENDICULAR) and made a unit vector. A plane keeps no kind (None), a one-sided plate no two_sided."""
    kind = kw.pop("kind", "plane")
    for key in ("axis_u", "size", "radius", "length", "two_sided", "file", "origin", "elevation", "nodata"):
        if key in kw and key not in PLATE_KEYS[kind]:
            owners = [k for k, keys in PLATE_KEYS.items() if key in keys]
            raise err(f"{path}.{key}", raw[key], f"is a key of kind = {' or '.join(map(repr, owners))} only (this is a {kind!r})")
    for key in PLATE_KEYS[kind]:
        if key not in OPTIONAL_KEYS.get(kind, ()) and key not in kw:
            raise err(f"{path}.{key}", MISSING, f"is required for kind = {kind!r}; it {SCHEMAS['surfaces'][key].rule}")
    if kind == "plane":
        return kw
    if kind == "terrain":  # placed and read once gravity and the site are known (scene.terrain.check_terrain)
        return {"point": (0.0, 0.0, 0.0), "normal": (0.0, 0.0, 0.0), **kw, "kind": kind}
    if "size" in kw and len(kw["size"]) != SIDES[kind]:
        raise err(f"{path}.size", raw["size"], f"must be a list of {SIDES[kind]} numbers for kind = {kind!r}")
    if "axis_u" in kw:
        u, n = kw["axis_u"], kw["normal"]
        if abs(math.hypot(*u) - 1.0) > 1e-15:
            u = unit_vector(u)
        if abs(sum(a * b for a, b in zip(u, n))) > PERPENDICULAR:
            raise err(f"{path}.axis_u", raw["axis_u"], f"must be perpendicular to the normal {list(n)} (in the plate's plane)")
        kw["axis_u"] = u
    if not kw.get("two_sided", True):
        del kw["two_sided"]
    return {**kw, "kind": kind}


def _with_material(kw: dict, raw: dict, path: str) -> dict:
    """The surface's keys with its catalogue material's values under the scene's own (scene.materials).
    A mu_s lowered below the material's mu_d takes mu_d = mu_s (as without a material)."""
    try:
        values = materials.resolve(kw["material"])
    except KeyError:
        allowed = materials.names()
        raise err(
            f"{path}.material",
            kw["material"],
            f"unknown material; {suggest(kw['material'], allowed)}allowed: " + ", ".join(allowed),
        ) from None
    if "mu_s" in kw and "mu_d" not in kw:
        values["mu_d"] = min(values["mu_d"], kw["mu_s"])
    return {**values, **kw}


def _collisions(raw) -> Collisions:
    kw = _table(raw, "collisions", SCHEMAS["collisions"])
    mu_s = kw.get("mu_s", Collisions.mu_s)
    if "mu_d" not in kw:
        kw["mu_d"] = min(Collisions.mu_d, mu_s)
    elif kw["mu_d"] > mu_s:
        raise err("collisions.mu_d", raw["mu_d"], f"must be a number in [0, mu_s = {mu_s:g}]")
    return Collisions(**kw)


_AIR_PARAMETERS = {"drag_coefficient": ("drag", "constant"), "drag_table": ("drag", "table"), "lift_slope": ("lift", "linear")}


def _air(raw):
    """The [air] table, or None when absent. A law's parameter is allowed only with its law."""
    if raw is None:
        return None
    kw = _table(raw, "air", SCHEMAS["air"])
    for key, (law_key, law) in _AIR_PARAMETERS.items():
        if key in kw and kw.get(law_key, getattr(Air, law_key)) != law:
            raise err(f"air.{key}", raw[key], f'only with air.{law_key} = "{law}"')
    if kw.get("drag") == "constant" and "drag_coefficient" not in kw:
        raise err("air.drag_coefficient", MISSING, 'is required with air.drag = "constant" (a number in (0, 100])')
    return Air(**kw)


def _hazard(raw, surfaces: tuple, shot: Shot):
    """The [hazard] table, or None when absent."""
    if raw is None:
        return None
    kw = _table(raw, "hazard", SCHEMAS["hazard"])
    hazard = Hazard(**kw)
    names = [t[0] for t in hazard.thresholds]
    if len(names) > MAX_THRESHOLDS:
        raise err(
            "hazard", f"{len(names)} thresholds", f"at most {MAX_THRESHOLDS} thresholds (energy_density and speed together)"
        )
    if len(set(names)) < len(names):
        twice = next(n for n in names if names.count(n) > 1)
        raise err("hazard", twice, "names a threshold twice (energy_density and speed together): give each a name of its own")
    if (hazard.map_cell is None) != (hazard.map_extent is None):
        key = "map_extent" if hazard.map_extent is None else "map_cell"
        raise err(f"hazard.{key}", MISSING, "is required for a map (hazard.map_cell and hazard.map_extent go together)")
    if hazard.has_map:
        (u0, u1, v0, v1), cell = hazard.map_extent, hazard.map_cell
        cells = math.ceil((u1 - u0) / cell) * math.ceil((v1 - v0) / cell)
        if cells > MAX_MAP_CELLS:
            raise err("hazard.map_cell", cell, f"makes {cells:,} cells of hazard.map_extent; at most {MAX_MAP_CELLS:,}")
        if hazard.map_surface >= len(surfaces):
            raise err("hazard.map_surface", hazard.map_surface, f"must be the index of a surface (0 to {len(surfaces) - 1})")
        if surfaces[hazard.map_surface].kind != "terrain":  # (a terrain's up is known later: check_terrain_ground)
            _check_map_axis(hazard, surfaces[hazard.map_surface].normal, shot)
    elif hazard.site is not None:
        raise err("hazard.site", "(a table)", "needs a map to place: give hazard.map_cell and hazard.map_extent")
    ground = surfaces[hazard.map_surface] if hazard.map_surface < len(surfaces) else None
    if hazard.points and not (ground is not None and ground.kind == "terrain"):  # (a terrain's: check_terrain_ground)
        _check_places(hazard, surfaces, shot)
    if ground is not None and not (ground.is_plane or ground.kind == "terrain"):
        raise err(
            "hazard.map_surface",
            hazard.map_surface,
            f"must be a plane or a terrain: surface {hazard.map_surface} is a {ground.kind} "
            "(the hazard's ground, its map and places lie on an infinite plane or a terrain's site grid)",
        )
    return hazard


def _check_places(hazard: Hazard, surfaces: tuple, shot: Shot) -> None:
    """Named places need the map and must lie inside its extent: their (u, v) as the map's grid has
    them (tallies.counts._map_geometry: u = map_axis or shot.direction projected on the map's plane,
    v = n x u, from the shooter's foot on the plane)."""
    if not hazard.has_map:
        key = "map_cell" if hazard.map_cell is None else "map_extent"
        raise err(
            f"hazard.{key}",
            MISSING,
            "is required with hazard.points (a named place lies on the map: give hazard.map_cell and hazard.map_extent)",
        )
    n = surfaces[hazard.map_surface].normal  # (unit: scene.parse._surface)
    axis = hazard.map_axis or shot.direction
    scale = max(map(abs, axis))
    a = [x / scale for x in axis]
    along = sum(x * y for x, y in zip(a, n))
    u = [x - along * y for x, y in zip(a, n)]
    length = math.hypot(*u)
    u = [x / length for x in u]
    v = [n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]]
    shooter = hazard.shooter or (shot.envelope_center if shot.file is None else (0.0, 0.0, 0.0))
    u0, u1, v0, v1 = hazard.map_extent
    for i, place in enumerate(hazard.points):
        d = [p - s for p, s in zip(place.position, shooter)]  # (u, v) of the foot of d on the plane: d's own
        pu, pv = math.fsum(x * y for x, y in zip(d, u)), math.fsum(x * y for x, y in zip(d, v))
        if not (u0 <= pu <= u1 and v0 <= pv <= v1):
            raise err(
                f"hazard.points.{i}.position",
                list(place.position),
                f"lies at (u, v) = ({pu:.6g}, {pv:.6g}) m on the map, outside hazard.map_extent "
                f"{list(hazard.map_extent)}: a named place must lie on the map",
            )


def _check_terrain_ground(hazard: Hazard, terrain, shot: Shot, physics) -> None:
    """A terrain as the hazard's ground: its map lies on the horizontal site grid, perpendicular to
    up = -g/|g|, so the terrain's up (`normal`) must be that up; the map's axis must not be vertical;
    named places must lie on the map (their (u, v) on the terrain's base plane)."""
    up = up_of(physics.gravity)
    if up is not None and abs(sum(a * b for a, b in zip(terrain.normal, up)) - 1.0) > PERPENDICULAR:
        raise err(
            f"surfaces.{hazard.map_surface}.normal",
            list(terrain.normal),
            f"must be the scene's up (-gravity: {list(up)}) for a terrain that is the hazard's ground "
            "(its map lies on the horizontal site grid)",
        )
    if hazard.has_map:
        _check_map_axis(hazard, terrain.normal, shot)
    if hazard.points:
        _check_places(hazard, {hazard.map_surface: terrain}, shot)


def _check_map_axis(hazard: Hazard, normal, shot: Shot) -> None:
    """The map's u axis (map_axis, else shot.direction) projected on its plane must not vanish: an axis
    along the normal has no downrange direction (tallies.counts._map_geometry projects it)."""
    axis = hazard.map_axis or shot.direction
    scale = max(map(abs, axis))
    a = [x / scale for x in axis]  # (scaled first: a tiny axis does not underflow)
    along = sum(x * n for x, n in zip(a, normal))
    if math.hypot(*(x - along * n for x, n in zip(a, normal))) >= 1e-9 * math.hypot(*a):
        return
    if hazard.map_axis is not None:
        raise err(
            "hazard.map_axis",
            list(hazard.map_axis),
            f"is along the normal {list(normal)} of the map's surface "
            f"(hazard.map_surface = {hazard.map_surface}): give an axis in that plane",
        )
    raise err(
        "hazard.map_axis",
        MISSING,
        f"is required: its default, shot.direction = {list(shot.direction)}, is along "
        f"the normal of the map's surface (hazard.map_surface = {hazard.map_surface}); give an axis in that plane",
    )


MAX_MAP_CELLS = 4_000_000


def _check_bound(hazard, shot: Shot, collisions: Collisions) -> None:
    """[hazard.bound] against the rest of the scene (docs/hazard.md, "Running until the answer is
    bounded"): a threshold of the scene, shots to add, and a budget that holds the first check."""
    bound = None if hazard is None else hazard.bound
    if bound is None:
        return
    names = [t[0] for t in hazard.thresholds]
    if bound.threshold not in names:
        allowed = ", ".join(names) if names else "none: the scene has no thresholds"
        raise err(
            "hazard.bound.threshold",
            bound.threshold,
            f"must name a threshold of the scene; {suggest(bound.threshold, names)}allowed: {allowed}",
        )
    if shot.file is not None:
        raise err(
            "shot.file",
            shot.file,
            "not allowed with [hazard.bound]: a pellet file's pellets are fixed, and a bounded run adds shots",
        )
    first = shot.count * shot.shots
    if bound.max_pellets < first:
        raise err(
            "hazard.bound.max_pellets",
            bound.max_pellets,
            f"must be at least shot.count x shot.shots = {first} (the pellets of the run's first check) and at most {INT32_MAX}",
        )
    if collisions.enabled and shot.count > 1 and collisions.frame_every:
        raise err(
            "collisions.frame_every",
            collisions.frame_every,
            "must be 0 with [hazard.bound] (trajectory frames need the whole run in one chunk, and a bounded run checks between chunks)",
        )


def _numerics(raw) -> Numerics:
    numerics = Numerics(**_table(raw, "numerics", SCHEMAS["numerics"]))
    least = MIN_FLIGHT_TOLERANCE[numerics.precision]
    for key in ("flight_tolerance", "surface_tolerance"):
        if getattr(numerics, key) < least:
            raise err(
                f"numerics.{key}",
                getattr(numerics, key),
                f"at least {least:g} with numerics.precision = "
                f'"{numerics.precision}" (it cannot resolve less)' + ("; use float64" if least > 1e-12 else ""),
            )
    return numerics


def scene_from_dict(raw: dict, base_dir=".") -> Scene:
    """Validate a raw scene dict (as read from TOML); shot.file is resolved relative to `base_dir`."""
    if not isinstance(raw, dict):
        raise err("scene", raw, "must be a table")
    check_keys(raw, "", SCHEMAS[""])
    if raw.get("shot") is None:
        raise err("shot", MISSING, "is required (a [shot] table)")
    surfaces = [] if raw.get("surfaces") is None else raw["surfaces"]
    if not isinstance(surfaces, (list, tuple)):
        raise err("surfaces", surfaces, "must be an array of tables ([[surfaces]])")
    collisions = _collisions(raw.get("collisions"))
    shot = _shot(raw["shot"], base_dir)
    pairs = collisions.enabled and shot.count > 1  # as Scene.pair_collisions: the run has a dense phase
    output = _table(raw.get("output"), "output", SCHEMAS["output"])
    planes = tuple(_surface(s, f"surfaces.{i}", base_dir) for i, s in enumerate(surfaces))
    hazard = _hazard(raw.get("hazard"), planes, shot)
    _check_bound(hazard, shot, collisions)
    if hazard is not None and output.get("quantiles") is False:
        raise err(
            "output.quantiles",
            _Shown("false"),
            "must be true with a [hazard] table: its thresholds' landings, danger "
            "distances and map are counted in the landing histograms (leave [hazard] out for none)",
        )
    physics = Physics(**_table(raw.get("physics"), "physics", SCHEMAS["physics"]))
    unwatched = hazard is not None and not hazard.thresholds  # (a per-threshold field would have no column)
    if "fields" not in output:
        fields = default_fields(pairs, hazard is not None, physics.until == "rest")
        output["fields"] = tuple(f for f in fields if not (unwatched and FIELDS[f].per_threshold))
    elif unwatched and any(FIELDS[f].per_threshold for f in output["fields"]):
        raise err(
            "output.fields",
            next(f for f in output["fields"] if FIELDS[f].per_threshold),
            "has a column per hazard threshold: give a threshold (hazard.energy_density or hazard.speed) or leave it out",
        )
    elif physics.until != "rest" and any(f in REST_FIELDS for f in output["fields"]):
        raise err(
            "output.fields",
            next(f for f in output["fields"] if f in REST_FIELDS),
            'needs physics.until = "rest" (with "landing" no pellet is followed past its landing)',
        )
    if "fields" in output and not pairs:
        extra = [f for f in output["fields"] if f in COLLISION_FIELDS]
        if extra:
            raise err(
                "output.fields",
                extra[0],
                "needs pellet-pellet collisions: collisions.enabled = true and more than one pellet per shot (shot.count > 1)",
            )
    numerics = _numerics(raw.get("numerics"))
    if (
        pairs and shot.file is None and collisions.separate
    ):  # sampled without overlaps (launch.sampling): the envelope must leave room
        fraction = packing_fraction(shot.count, shot.diameter, shot.envelope_radius)
        if fraction > MAX_PACKING:
            least = shot.envelope_radius * (fraction / MAX_PACKING) ** (1 / 3)
            raise err(
                "shot.envelope_radius",
                shot.envelope_radius,
                f"too small for {shot.count} pellets of {shot.diameter:g} m without overlaps (collisions on): "
                f"they fill {fraction:.3g} of it, at most {MAX_PACKING} can be sampled (random sequential "
                f"addition); at least {least:.4g} m",
            )
    if pairs and numerics.precision == "float32":
        # A shot's step counter is a float32 in a float32 run: it stops counting at 2^24, and a shot
        # stops (max_steps) only at a checkpoint, every frame_every steps (or CHECKPOINT_STEPS), so
        # the checkpoint at or after max_steps must come by then, or the shot never stops.
        every = collisions.frame_every or CHECKPOINT_STEPS
        if every > FLOAT32_EXACT_STEPS:
            raise err(
                "collisions.frame_every",
                collisions.frame_every,
                f"at most {FLOAT32_EXACT_STEPS:,} with "
                'numerics.precision = "float32" (a shot\'s step counter is exact up to 2^24); use float64',
            )
        if -(-collisions.max_steps // every) * every > FLOAT32_EXACT_STEPS:
            raise err(
                "collisions.max_steps",
                collisions.max_steps,
                f'with numerics.precision = "float32", its '
                f"checkpoint (a multiple of {every} steps) must come by step {FLOAT32_EXACT_STEPS:,}, where the "
                "step counter stops being exact: at most "
                f"{FLOAT32_EXACT_STEPS // every * every:,}; use float64 for more",
            )
    planes = tuple(check_terrain(s, f"surfaces.{i}", physics, hazard, base_dir) for i, s in enumerate(planes))
    if hazard is not None and hazard.map_surface < len(planes) and planes[hazard.map_surface].kind == "terrain":
        _check_terrain_ground(hazard, planes[hazard.map_surface], shot, physics)
    air = _air(raw.get("air"))
    if air is not None and len(surfaces) > MAX_PLANES_IN_AIR:
        raise err(
            "surfaces",
            f"{len(surfaces)} surfaces",
            f"at most {MAX_PLANES_IN_AIR} with [air] (a flight in air tracks its planes in the bits of an int32)",
        )
    stations = parse_stations(raw.get("stations"))
    if stations:
        check_stations(stations, shot, raw["shot"], planes, physics, hazard)
    if shot.file is None:
        _check_launch_outside(planes, shot, stations)
    else:
        _check_file_outside(planes, shot)
    _warn_post_creases(planes, shot, physics)
    return Scene(
        shot=shot,
        surfaces=planes,
        physics=physics,
        numerics=numerics,
        output=Output(**output),
        collisions=collisions,
        air=air,
        hazard=hazard,
        stations=stations,
    )


def _check_launch_outside(surfaces: tuple, shot: Shot, stations: tuple = ()) -> None:
    """The launch envelope (its sphere of radius shot.envelope_radius about shot.envelope_center,
    or about each station's position when the scene has [[stations]]) lies outside every post, box
    and closed mesh (`scene.solids`; inside a closed mesh wound inwards): they are met from outside
    only, so pellets launched inside one would fly through it as if it were not there."""
    if stations:
        launches = [(f"stations.{k}.position", st.position, f"station {st.name!r} ") for k, st in enumerate(stations)]
    else:
        launches = [("shot.envelope_center", shot.envelope_center, "")]
    solids = [(i, s) for i, s in enumerate(surfaces) if s.kind in SOLIDS]
    for key, value, who in launches:
        centre = np.asarray(value, dtype=np.float64)
        for i, s in solids:
            gap = envelope_gap(s, centre)  # m, negative inside (None: an open mesh)
            if gap is not None and gap < shot.envelope_radius:
                where = f"is {_inside_words(s)}" if gap < 0.0 else f"is {gap:.4g} m from"
                raise err(
                    key,
                    list(value),
                    f"{who}{where} surfaces.{i} ({s.name!r}, a {_solid_name(s)}), a solid met only from outside, and "
                    f"the launch envelope (radius {shot.envelope_radius:.4g} m) reaches {shot.envelope_radius - gap:.4g} m "
                    f"into it: pellets launched inside it fly through it; the envelope must lie {ALLOWED}",
                )


def _warn_post_creases(surfaces: tuple, shot: Shot, physics: Physics) -> None:
    """SceneWarning for a leaning post followed to rest whose bottom cap, tilted towards an infinite
    plane, reaches from within a pellet's diameter of it to above it (docs/geometry.md, "Along a leaning
    side"): pellets rolling into the acute crease under the cap may bounce there until their impacts
    run out (NOT_FINISHED). Buried so that the cap lies below the plane, the post forms none."""
    if physics.until != "rest":
        return
    for i, s in enumerate(surfaces):
        if s.kind != "cylinder":
            continue
        a = np.asarray(s.normal, dtype=np.float64) / np.linalg.norm(s.normal)
        for j, plane in enumerate(surfaces):
            if not plane.is_plane:
                continue
            n = np.asarray(plane.normal, dtype=np.float64) / np.linalg.norm(plane.normal)
            tilt = float(np.linalg.norm(n - (n @ a) * a))  # sin of the cap's tilt from the plane
            centre = float(n @ (np.asarray(s.point, dtype=np.float64) - np.asarray(plane.point, dtype=np.float64)))
            low, high = centre - s.radius * tilt, centre + s.radius * tilt
            if n @ a > 0.0 and tilt > 1e-6 and low < shot.diameter and high > 0.0:
                warnings.warn(
                    f"surfaces.{i} ({s.name!r}): the bottom cap of this leaning post stands {high:.3g} m above the plane "
                    f"of surfaces.{j} ({plane.name!r}), tilted {math.degrees(math.asin(min(1.0, tilt))):.3g} degrees: "
                    "pellets rolling into the acute crease under it may bounce there until their impacts run out "
                    f"(not finished); bury its base at least {s.radius * tilt + shot.diameter:.3g} m below that plane",
                    SceneWarning,
                    stacklevel=4,
                )


def _check_file_outside(surfaces: tuple, shot: Shot) -> None:
    """Every pellet of shot.file starts with its centre outside every post, box and closed mesh
    (inside a closed mesh wound inwards; `_check_launch_outside`), read a piece at a time; one line names the file, its first pellet
    inside one and the solid."""
    solids = [(i, s) for i, s in enumerate(surfaces) if s.kind in SOLIDS and (s.kind != "mesh" or closed_triangles(s))]
    if not solids:
        return
    for start, x in position_pieces(shot.file):
        first = None
        for i, s in solids:
            rows = np.flatnonzero(inside_rows(s, x))
            if rows.size and (first is None or rows[0] < first[0]):
                first = (int(rows[0]), i, s)
        if first is not None:
            row, i, s = first
            raise err(
                "shot.file:position",
                x[row].tolist(),
                f"{shot.file}: pellet {start + row} starts {_inside_words(s)} surfaces.{i} ({s.name!r}, a {_solid_name(s)}), "
                "a solid met only from outside (pellets launched inside it fly through it); every pellet must start with "
                f"its centre {ALLOWED}",
            )


def _solid_name(s) -> str:
    """How messages name a solid's kind."""
    if s.kind == "mesh" and winding_level(closed_triangles(s)) < 0.0:
        return "closed mesh wound inwards, whose solid is all outside it"
    return {"cylinder": "post (cylinder)", "mesh": "closed mesh"}.get(s.kind, s.kind)


def _inside_words(s) -> str:
    """How messages say that a point lies in solid s (outside a closed mesh wound inwards)."""
    return "outside" if s.kind == "mesh" and winding_level(closed_triangles(s)) < 0.0 else "inside"


ALLOWED = "outside every post, box and closed mesh (inside a closed mesh wound inwards)"


MAX_SCENE_CHARS = 1 << 20  # a scene's text; the largest valid one (a drag table of 1,024 pairs) is ~40 kB


def load_scene(path, overrides=()) -> Scene:
    """Read a TOML scene, apply "KEY=VALUE" overrides, validate; shot.file is relative to the scene's folder."""
    overrides = (overrides,) if isinstance(overrides, str) else overrides
    special = not_regular(path)  # (a FIFO would wait for a writer)
    if special:
        raise err("scene", str(path), special)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, ValueError) as exc:
        raise err("scene", str(path), f"cannot be read: {getattr(exc, 'strerror', None) or exc}") from None
    if len(text) > MAX_SCENE_CHARS:  # before the parser, whose time grows with the text (~10 s for 18 MB)
        raise err(
            "scene", str(path), f"has {len(text):,} characters; a scene is at most {MAX_SCENE_CHARS:,} (pellets go in shot.file)"
        )
    try:
        raw = tomllib.loads(text)
    except (ValueError, RecursionError) as exc:
        raise err("scene", str(path), f"is not valid TOML: {exc}") from None
    for assignment in overrides:
        raw = apply_override(raw, assignment)
    return dataclasses.replace(scene_from_dict(raw, base_dir=Path(path).parent), source=str(path))
