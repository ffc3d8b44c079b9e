"""Converters: conv(value, dotted_key) -> validated value, each with the `rule` its one-line errors state; the schemas of the scene's tables."""

from __future__ import annotations

import math

from ..fields import ALL_FIELDS, FIELDS, GROUPS
from .keys import MISSING, check_keys, join, table
from .keys import err as _err
from .loads import LOAD_RULE, check_load
from .materials import RANGES
from .patterns import check_choke
from .schema import (
    COMPRESSIONS,
    INT32_MAX,
    MAX_AIR_DENSITY,
    MAX_COORDINATE,
    MAX_DENSITY,
    MAX_DIAMETER,
    MAX_FRICTION,
    MAX_GRAVITY,
    MAX_IMPACT_DURATION,
    MAX_PLACES,
    MAX_SPEED,
    MAX_SPIN,
    MAX_WIND,
    MIN_DENSITY,
    MIN_DIAMETER,
    SURFACE_KINDS,
    Bound,
    Place,
    Reference,
    Site,
)
from .units import to_unit


def _rule(rule):
    def deco(conv):
        conv.rule = rule
        return conv

    return deco


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_scalar(v) -> bool:
    """A number, or a string that may be a number with its unit (scene.units)."""
    return _is_number(v) or isinstance(v, str)


def _finite(v, path: str, rule: str) -> float:
    """A finite float; a string is a value with its unit, converted to the key's (scene.units.KEY_UNITS)."""
    if not _is_scalar(v):
        raise _err(path, v, rule)
    try:
        x = to_unit(v, path, rule) if isinstance(v, str) else float(v)
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise _err(path, v, "must be finite")
    return x


def _number(lo=None, hi=None, *, above=False, unit=""):
    if hi is not None:
        rule = f"must be a number in [{lo:g}, {hi:g}]"
    else:
        rule = "must be a number" + ("" if lo is None else f" {'>' if above else '>='} {lo:g}")
    rule += f" ({unit})" if unit else ""

    @_rule(rule)
    def conv(v, path):
        x = _finite(v, path, rule)
        if (lo is not None and (x <= lo if above else x < lo)) or (hi is not None and x > hi):
            raise _err(path, v, rule)
        return x

    return conv


def _range(lo, hi, *, above=False, unit=""):
    """A number in [lo, hi] ((lo, hi] with above), with the bounds in its one-line rule."""
    rule = f"must be a number in {'(' if above else '['}{lo:g}, {hi:g}]" + (f" ({unit})" if unit else "")

    @_rule(rule)
    def conv(v, path):
        x = _finite(v, path, rule)
        if x < lo or (above and x == lo) or x > hi:
            raise _err(path, v, rule)
        return x

    return conv


def _int(lo: int, hi: int):
    rule = f"must be an integer in [{lo}, {hi}]"

    @_rule(rule)
    def conv(v, path):
        if isinstance(v, float) and not math.isfinite(v):
            raise _err(path, v, "must be finite")
        n = int(v) if isinstance(v, float) and v.is_integer() else v  # TOML's 1e6: an integer written as a float
        if isinstance(n, bool) or not isinstance(n, int) or not lo <= n <= hi:
            raise _err(path, v, rule)
        return int(n)

    return conv


def _vec3(*, nonzero=False, nonneg=False, scalar=False, unit="", bound=None):
    rule = "must be a list of 3 numbers" + (" or one number" if scalar else "") + (f" ({unit})" if unit else "")

    @_rule(rule)
    def conv(v, path):
        if scalar and _is_scalar(v):
            xs = (_finite(v, path, rule),) * 3
        elif isinstance(v, (list, tuple)) and len(v) == 3 and all(map(_is_scalar, v)):
            xs = tuple(_finite(x, path, rule) for x in v)
        else:
            raise _err(path, v, rule)
        if nonzero and not any(xs):
            raise _err(path, v, "must not be the zero vector")
        if nonneg and min(xs) < 0:
            raise _err(path, v, "must be >= 0 in each component")
        if bound is not None and max(map(abs, xs)) > bound:
            raise _err(path, v, f"each component must be within +-{bound:g}" + (f" {unit}" if unit else ""))
        return xs

    return conv


def _str(choices=(), *, empty=False):
    rule = (
        ("must be one of " + ", ".join(map(repr, choices))) if choices else "must be a string" + ("" if empty else " (not empty)")
    )

    @_rule(rule)
    def conv(v, path):
        if not isinstance(v, str) or (choices and v not in choices) or (not empty and not v):
            raise _err(path, v, rule)
        return v

    return conv


def _path():
    rule = "must be a file name (a string, not empty, without NUL characters)"

    @_rule(rule)
    def conv(v, path):
        if not isinstance(v, str) or not v or "\0" in v:
            raise _err(path, v, rule)
        return v

    return conv


@_rule("must be true or false")
def _bool(v, path):
    if not isinstance(v, bool):
        raise _err(path, v, "must be true or false")
    return v


def _two(v, path, rule, ok, lengths=(2,)):
    """A list of `lengths` finite numbers, each `ok`."""
    if not (isinstance(v, (list, tuple)) and len(v) in lengths):
        raise _err(path, v, rule)
    xs = tuple(_finite(x, path, rule) for x in v)
    if not all(map(ok, xs)):
        raise _err(path, v, rule)
    return xs


@_rule(f"must be a list of 2 (a rectangle) or 3 (a box) numbers in (0, {2 * MAX_COORDINATE:g}] (m)")
def _size(v, path):
    return _two(v, path, _size.rule, lambda x: 0 < x <= 2 * MAX_COORDINATE, lengths=(2, 3))


MAX_MAP_COORDINATE = 1e8  # a raster's CRS coordinates (terrain's origin): UTM northings reach 1e7 m


@_rule(f"must be a list of 2 numbers, each within +-{MAX_MAP_COORDINATE:g} (the raster's CRS units)")
def _pair(v, path):
    return _two(v, path, _pair.rule, lambda x: abs(x) <= MAX_MAP_COORDINATE)


@_rule("must be a list of field names")
def _fields(v, path):
    if not isinstance(v, (list, tuple)):
        raise _err(path, v, "must be a list of field names")
    chosen = set()
    for name in v:
        if isinstance(name, str) and name in GROUPS:
            chosen.update(f"{name}.{f}" for f in GROUPS[name])
        elif isinstance(name, str) and name in FIELDS:
            chosen.add(name)
        else:
            raise _err(path, name, "unknown field; allowed: " + ", ".join((*GROUPS, *ALL_FIELDS)))
    return tuple(f for f in ALL_FIELDS if f in chosen)


def _open_range(lo, hi, *, unit=""):
    """A number in the open interval (lo, hi)."""
    rule = f"must be a number in ({lo:g}, {hi:g})" + (f" ({unit})" if unit else "")

    @_rule(rule)
    def conv(v, path):
        x = _finite(v, path, rule)
        if not lo < x < hi:
            raise _err(path, v, rule)
        return x

    return conv


_SHOT = {
    "count": _int(1, INT32_MAX),
    "shots": _int(1, INT32_MAX),
    "diameter": _range(MIN_DIAMETER, MAX_DIAMETER, unit="m"),
    "density": _range(MIN_DENSITY, MAX_DENSITY, unit="kg/m^3"),
    "speed": _range(0, MAX_SPEED, above=True, unit="m/s"),
    "direction": _vec3(nonzero=True, bound=MAX_COORDINATE),
    "direction_jitter": _vec3(nonneg=True, scalar=True, bound=MAX_COORDINATE),
    "envelope_radius": _range(0, MAX_COORDINATE, unit="m"),
    "envelope_center": _vec3(unit="m", bound=MAX_COORDINATE),
    "spin": _vec3(unit="rad/s", bound=MAX_SPIN),
    "seed": _int(0, INT32_MAX),
    "file": _path(),
    "choke": check_choke,  # scene.patterns: a choke's pattern, or `pattern` itself (docs/scenes.md)
    "pattern": _open_range(0, 100, unit="percent"),  # of the charge in a 30-inch circle at 40 yards
}
MAX_CHARGE = 100.0  # kg, a shot's charge (shot.load.charge)


@_rule(LOAD_RULE)
def _load(v, path):
    """shot.load (scene.loads): its size, material and charge validated, the size's diameter found."""
    return check_load(v, path, _range(0, MAX_CHARGE, above=True, unit="kg"), _SHOT["diameter"])


_SHOT["load"] = _load
_SURFACE = {
    "name": _str(empty=True),
    "point": _vec3(unit="m", bound=MAX_COORDINATE),
    "normal": _vec3(nonzero=True, bound=MAX_COORDINATE),
    "restitution": _number(0, 1),
    "mu_s": _range(0, MAX_FRICTION),
    "mu_d": _range(0, MAX_FRICTION),
    "material": _str(),  # a catalogue name (scene.materials), checked with a did-you-mean in scene.parse
    "kind": _str(SURFACE_KINDS),  # plates' keys checked together in scene.parse._plate
    "axis_u": _vec3(nonzero=True, bound=MAX_COORDINATE),
    "size": _size,
    "radius": _range(0, MAX_COORDINATE, above=True, unit="m"),
    "length": _range(0, MAX_COORDINATE, above=True, unit="m"),
    "two_sided": _bool,
    "file": _path(),  # a mesh's (scene.triangles) or terrain's raster (scene.terrain), relative to the scene's folder
    "origin": _pair,
    "elevation": _range(-MAX_COORDINATE, MAX_COORDINATE, unit="m"),
    "nodata": _number(),
    **{key: _range(lo, hi, unit="" if unit == "1" else unit) for key, (lo, hi, unit, _why) in RANGES.items()},
}
_PHYSICS = {
    "gravity": _vec3(unit="m/s^2", bound=MAX_GRAVITY),
    "impact_duration": _range(0, MAX_IMPACT_DURATION, unit="s"),
    "bounces": _int(1, 16),
    "until": _str(("rest", "landing")),
    "rest_speed": _range(0, MAX_SPEED, above=True, unit="m/s"),
    "max_impacts": _int(1, 1_000_000),
    "max_steps": _int(1, INT32_MAX),
}
_COLLISIONS = {
    "enabled": _bool,
    "separate": _bool,
    "restitution": _number(0, 1),
    "mu_s": _range(0, MAX_FRICTION),
    "mu_d": _range(0, MAX_FRICTION),
    "contact_duration": _range(0, MAX_IMPACT_DURATION, unit="s"),
    "time_step": _range(0, MAX_IMPACT_DURATION, above=True, unit="s"),
    "step_fraction": _range(0, 1, above=True),
    "air_step_fraction": _range(0, 1, above=True),
    "air_leaps": _bool,
    "skin": _range(0, 10, above=True),
    "rounds": _int(1, 64),
    "max_neighbours": _int(1, 256),
    "max_steps": _int(1, INT32_MAX),
    "frame_every": _int(0, INT32_MAX),
}
FLOAT32_EXACT_STEPS = 2**24  # float32 counts every integer up to here
_NUMERICS = {
    "precision": _str(("float32", "float64")),
    "chunk_size": _int(1, INT32_MAX),
    "fast_math": _bool,
    "flight_tolerance": _range(1e-12, 1e-2),
    "surface_tolerance": _range(1e-12, 1e-2),
}


@_rule('must be "braun", "gs", or a list of at least 2 [Mach, C_D] pairs, Mach increasing in [0, 1e6], C_D > 0')
def _drag_table(v, path):
    rule = _drag_table.rule
    if isinstance(v, str):
        if v not in ("braun", "gs"):
            raise _err(path, v, rule)
        return v
    if not isinstance(v, (list, tuple)) or len(v) < 2 or len(v) > MAX_TABLE_POINTS:
        raise _err(path, v, rule + f" (at most {MAX_TABLE_POINTS} pairs)")
    pairs = []
    for i, pair in enumerate(v):
        if not isinstance(pair, (list, tuple)) or len(pair) != 2 or not all(map(_is_number, pair)):
            raise _err(path, v, f"pair {i} ({pair!r}) must be a [Mach, C_D] pair of numbers")
        mach, cd = (_finite(x, path, "must be finite") for x in pair)
        if not 0 <= mach <= MAX_TABLE_MACH or cd <= 0 or cd > 100 or (pairs and mach <= pairs[-1][0]):
            raise _err(
                path,
                v,
                f"pair {i} ({pair!r}) must have Mach in [0, {MAX_TABLE_MACH:g}] and above the pair before, and C_D in (0, 100]",
            )
        pairs.append((mach, cd))
    return tuple(pairs)


MAX_TABLE_POINTS = 1024
# Mach of a table's points: 10 times the domain's fastest flight (MAX_SPEED at the least sound_speed, 1 m/s),
# exact enough and finite in float32 (a Mach of 1e300 would be inf there)
MAX_TABLE_MACH = 1e6
_AIR = {
    "density": _range(0, MAX_AIR_DENSITY, unit="kg/m^3"),
    "viscosity": _range(0, 1, above=True, unit="Pa s"),
    "sound_speed": _range(1, 1e4, unit="m/s"),
    "wind": _vec3(unit="m/s", bound=MAX_WIND),
    "drag": _str(("loth2021", "constant", "table")),
    "drag_coefficient": _range(0, 100, above=True),
    "drag_table": _drag_table,
    "drag_factor": _range(0, 10, above=True),
    "magnus": _bool,
    "lift": _str(("loth2008", "linear", "sawicki2003")),
    "lift_slope": _range(0, 10),
    "lift_max": _range(0, 10),
    "spin_decay": _bool,
    "spin_decay_law": _str(("dennis1980", "loth2008")),
}


@_rule("must be a list of at most 64 numbers in (0, 1e7] (m), increasing")
def _distances(v, path):
    if isinstance(v, (list, tuple)) and len(v) > 64:  # (the length first: nothing per element of a long list)
        raise _err(path, v, _distances.rule)
    if not isinstance(v, (list, tuple)) or not all(map(_is_scalar, v)):
        raise _err(path, v, _distances.rule)
    xs = tuple(_finite(x, path, _distances.rule) for x in v)
    if any(x <= 0 or x > 1e7 for x in xs) or any(b <= a for a, b in zip(xs, xs[1:])):
        raise _err(path, v, _distances.rule)
    return xs


def _thresholds(unit, hi):
    rule = (
        f"must be a table of name = value (names of letters, digits, _ and -; values in (0, {hi:g}] {unit}), "
        "e.g. {corneal_abrasion = 1503.0}"
    )

    @_rule(rule)
    def conv(v, path):
        pairs = v.items() if isinstance(v, dict) else v if isinstance(v, (list, tuple)) else None
        if pairs is None:
            raise _err(path, v, rule)
        out = []
        for pair in pairs:
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise _err(path, v, rule)
            name, value = pair
            if not isinstance(name, str) or not name or not all(c.isascii() and (c.isalnum() or c in "_-") for c in name):
                raise _err(f"{path}.{name}", value, rule)
            x = _finite(value, f"{path}.{name}", rule)
            if not 0 < x <= hi:
                raise _err(f"{path}.{name}", value, rule)
            out.append((name, x))
        return tuple(out)

    return conv


@_rule("must be a list of numbers in (0, 0.5], each the fraction of hazardous landings left beyond a danger distance")
def _fractions(v, path):
    if not isinstance(v, (list, tuple)) or not v or len(v) > 16 or not all(map(_is_number, v)):
        raise _err(path, v, _fractions.rule)
    xs = tuple(_finite(x, path, _fractions.rule) for x in v)
    if any(not 0 < x <= 0.5 for x in xs):
        raise _err(path, v, _fractions.rule)
    return xs


@_rule("must be a list of 4 numbers [u_min, u_max, v_min, v_max] (m), each min below its max")
def _extent(v, path):
    if not isinstance(v, (list, tuple)) or len(v) != 4 or not all(map(_is_scalar, v)):
        raise _err(path, v, _extent.rule)
    xs = tuple(_finite(x, path, _extent.rule) for x in v)
    if xs[0] >= xs[1] or xs[2] >= xs[3] or max(map(abs, xs)) > MAX_COORDINATE:
        raise _err(path, v, _extent.rule + f", within +-{MAX_COORDINATE:g}")
    return xs


MAX_PLACE_NAME = 100  # characters of a named place's name (one line of a table)


@_rule(f"must be a string of 1 to {MAX_PLACE_NAME} printable characters")
def _place_name(v, path):
    if not isinstance(v, str) or not 0 < len(v) <= MAX_PLACE_NAME or not v.isprintable():
        raise _err(path, v, _place_name.rule)
    return v


_PLACE = {
    "name": _place_name,
    "position": _vec3(unit="m", bound=MAX_COORDINATE),
    "area": _range(0, 1e6, above=True, unit="m^2"),
}


@_rule(f"must be an array of at most {MAX_PLACES} tables [[hazard.points]] with name, position (m) and area (m^2)")
def _places(v, path):
    """Named places (schema.Place): each a table of _PLACE's keys (name and position required), the names distinct."""
    if not isinstance(v, (list, tuple)) or len(v) > MAX_PLACES:
        raise _err(path, v, _places.rule)
    out = []
    for i, raw in enumerate(v):
        where = join(path, str(i))
        kw = table(raw, where, _PLACE, required=("name", "position"))
        if any(p.name == kw["name"] for p in out):
            raise _err(join(where, "name"), kw["name"], "names another place too: give each place a name of its own")
        out.append(Place(**kw))
    return tuple(out)


_REFERENCE = {"name": _str(), "distance": _range(0, MAX_COORDINATE, above=True, unit="m"), "source": _str(empty=True)}


@_rule("must be an array of tables [[hazard.references]], each with name, distance (m) and source")
def _references(v, path):
    """Reference distances the report compares the danger distances with (docs/hazard.md, "The report")."""
    if not isinstance(v, (list, tuple)):
        raise _err(path, v, _references.rule)
    out = []
    for i, item in enumerate(v):
        where = f"{path}.{i}"
        if not isinstance(item, dict):
            raise _err(where, item, "must be a table with name, distance (m) and source")
        check_keys(item, where, _REFERENCE)
        for key in ("name", "distance"):
            if item.get(key) is None:
                raise _err(f"{where}.{key}", MISSING, f"is required; it {_REFERENCE[key].rule}")
        kw = {key: conv(item[key], f"{where}.{key}") for key, conv in _REFERENCE.items() if item.get(key) is not None}
        if any(r.name == kw["name"] for r in out):
            raise _err(f"{where}.name", kw["name"], "names a reference twice: give each its own name")
        out.append(Reference(**kw))
    return tuple(out)


# [hazard.site]: the map's georeference (docs/hazard.md, "Outlines and GIS files"); the CRS is checked
# with pyproj (the gis extra) when the scene is read, before any work
CRS_RULE = 'must be a projected or geographic CRS pyproj knows by an authority code, e.g. "EPSG:32630"'
SHOOTER_RULE = "must be a list of 2 numbers: the shooter's [easting, northing] (projected CRS) or [lon, lat] (geographic)"
AZIMUTH_RULE = "must be a number in [0, 360) (deg clockwise from north)"


@_rule("must be a table: crs, shooter and azimuth (docs/hazard.md)")
def _site(raw, path):
    """The validated [hazard.site] table (a Site); refuses a CRS pyproj does not know, or any CRS
    when pyproj is missing."""
    if not isinstance(raw, dict):
        raise _err(path, raw, "must be a table with keys crs, shooter and azimuth")
    keys = {"crs": CRS_RULE, "shooter": SHOOTER_RULE, "azimuth": AZIMUTH_RULE}
    check_keys(raw, path, keys)
    for key in ("crs", "shooter"):
        if raw.get(key) is None:
            raise _err(join(path, key), MISSING, f"is required; it {keys[key]}")
    crs, shooter = raw["crs"], raw["shooter"]
    if not isinstance(crs, str) or not crs.strip():
        raise _err(join(path, "crs"), crs, CRS_RULE)
    if not isinstance(shooter, (list, tuple)) or len(shooter) != 2:
        raise _err(join(path, "shooter"), shooter, SHOOTER_RULE)
    xy = tuple(_finite(x, join(path, "shooter"), SHOOTER_RULE) for x in shooter)
    azimuth = 0.0 if raw.get("azimuth") is None else _finite(raw["azimuth"], join(path, "azimuth"), AZIMUTH_RULE)
    if not 0.0 <= azimuth < 360.0:
        raise _err(join(path, "azimuth"), raw["azimuth"], AZIMUTH_RULE)
    try:
        from ..gis.site import check_site  # (pyproj: the gis extra)
    except ImportError as exc:
        raise _err(
            join(path, "crs"), crs, f"needs pyproj to be checked ({exc.name} is missing): pip install 'warp-ricochet[gis]'"
        ) from None
    problem = check_site(crs, xy)
    if problem is not None:
        key, why = problem
        raise _err(join(path, key), crs if key == "crs" else list(shooter), why)
    return Site(crs=crs, shooter=xy, azimuth=azimuth)


@_rule("must be a number in (0, 1): the fraction p of the pellets above the threshold left beyond the danger distance")
def _probability(v, path):
    x = _finite(v, path, _probability.rule)
    if not 0 < x < 1:
        raise _err(path, v, _probability.rule)
    return x


_BOUND = {
    "threshold": _str(),  # a threshold's name: checked against the scene's in scene.parse
    "fraction": _probability,
    "width": _range(0, MAX_COORDINATE, above=True, unit="m"),
    "max_pellets": _int(1, INT32_MAX),
}
BOUND_REQUIRED = ("threshold", "fraction", "width", "max_pellets")


@_rule("must be a table (keys: " + ", ".join(_BOUND) + ")")
def _bound(v, path):
    """[hazard.bound]: its keys' values (`schema.Bound`; checked against the scene in scene.parse)."""
    if not isinstance(v, dict):
        raise _err(path, v, _bound.rule)
    check_keys(v, path, _BOUND)
    for key in BOUND_REQUIRED:
        if v.get(key) is None:
            raise _err(join(path, key), MISSING, f"is required; it {_BOUND[key].rule}")
    return Bound(**{key: conv(v[key], join(path, key)) for key, conv in _BOUND.items()})


_HAZARD = {
    "energy_density": _thresholds("J/m^2", 1e12),
    "speed": _thresholds("m/s", MAX_SPEED),
    "fractions": _fractions,
    "shooter": _vec3(unit="m", bound=MAX_COORDINATE),
    "map_cell": _range(0, MAX_COORDINATE, above=True, unit="m"),
    "map_extent": _extent,
    "map_surface": _int(0, 1_000_000),
    "map_axis": _vec3(nonzero=True, bound=MAX_COORDINATE),
    "body_height": _range(0, 1e3, above=True, unit="m"),
    "points": _places,
    "references": _references,
    "site": _site,
    "bound": _bound,
}
_OUTPUT = {
    "path": _path(),
    "fields": _fields,
    "quantiles": _bool,
    "tail_distances": _distances,
    "compression": _str(tuple(COMPRESSIONS)),
}
_TOP = (
    "shot",
    "surfaces",
    "physics",
    "collisions",
    "air",
    "numerics",
    "output",
    "hazard",
    "stations",
)  # stations: scene.stations
# table -> its schema (the top level: the names of the tables)
SCHEMAS = {
    "shot": _SHOT,
    "surfaces": _SURFACE,
    "physics": _PHYSICS,
    "collisions": _COLLISIONS,
    "air": _AIR,
    "numerics": _NUMERICS,
    "output": _OUTPUT,
    "hazard": _HAZARD,
    "": _TOP,
}
