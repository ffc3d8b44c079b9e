"""Values written with their units ("2.4 mm", "1350 ft/s", "40 yd", "1 1/8 oz", "30 deg"): parsed
with pint and converted to the unit of the scene key they are given for (`KEY_UNITS`), before any
other check. A plain number keeps meaning the key's unit (SI; degrees where the key is in degrees).

pint is imported, and its registry built (~0.2 s), only when a value with a unit is met. The
registry is pint's own definitions with one change: the radian is a base dimension ([angle]), as
in SI brochure practice it is a unit, so that "30 deg" is refused for a dimensionless key and
"3000 rpm" is taken for an angular speed (pint's default makes angles dimensionless).
"""

from __future__ import annotations

import functools
import math
import re
from decimal import Decimal

from .keys import err
from .materials import RANGES

# The unit of each scalar scene key (and of each number of a list key), as the files write it;
# "*" stands for one part of the dotted key (an index of [[surfaces]], a threshold's name). A key
# missing here takes numbers only. "1": dimensionless.
KEY_UNITS = {
    "shot.diameter": "m",
    "shot.density": "kg/m^3",
    "shot.count": "1",
    "shot.shots": "1",
    "shot.seed": "1",
    "shot.speed": "m/s",
    "shot.direction_jitter": "1",
    "shot.pattern": "percent",  # of the charge in a 30-inch circle at 40 yards (scene.patterns)
    "stations.*.position": "m",  # [[stations]] (scene.stations)
    "stations.*.azimuth": "deg",
    "stations.*.elevation": "deg",
    "stations.*.aim_sigma": "deg",
    "stations.*.weight": "1",
    "shot.envelope_radius": "m",
    "shot.envelope_center": "m",
    "shot.spin": "rad/s",
    "shot.load.charge": "kg",
    "shot.load.size": "m",  # a size given as its diameter ("2.4 mm"; scene.loads)
    "surfaces.*.point": "m",
    "surfaces.*.restitution": "1",
    "surfaces.*.mu_s": "1",
    "surfaces.*.mu_d": "1",
    "surfaces.*.size": "m",
    "surfaces.*.radius": "m",
    "surfaces.*.length": "m",  # a post's (kind = "cylinder")
    "surfaces.*.elevation": "m",
    **{f"surfaces.*.{key}": unit for key, (_lo, _hi, unit, _why) in RANGES.items()},
    "physics.gravity": "m/s^2",
    "physics.impact_duration": "s",
    "physics.bounces": "1",
    "physics.rest_speed": "m/s",
    "physics.max_impacts": "1",
    "physics.max_steps": "1",
    "collisions.restitution": "1",
    "collisions.mu_s": "1",
    "collisions.mu_d": "1",
    "collisions.contact_duration": "s",
    "collisions.time_step": "s",
    "collisions.step_fraction": "1",
    "collisions.air_step_fraction": "1",
    "collisions.skin": "1",  # diameters
    "air.density": "kg/m^3",
    "air.viscosity": "Pa s",
    "air.sound_speed": "m/s",
    "air.wind": "m/s",
    "air.drag_coefficient": "1",
    "air.drag_factor": "1",
    "air.lift_slope": "1",
    "air.lift_max": "1",
    "numerics.chunk_size": "1",
    "numerics.flight_tolerance": "1",
    "numerics.surface_tolerance": "1",
    "output.tail_distances": "m",
    "hazard.energy_density.*": "J/m^2",
    "hazard.speed.*": "m/s",
    "hazard.fractions": "1",
    "hazard.shooter": "m",
    "hazard.map_cell": "m",
    "hazard.map_extent": "m",
    "hazard.body_height": "m",
    "hazard.points.*.position": "m",
    "hazard.points.*.area": "m^2",
    "hazard.references.*.distance": "m",
    "hazard.site.azimuth": "deg",
    "hazard.bound.fraction": "1",
    "hazard.bound.width": "m",
}

# The quantity a dimension is, for the one-line errors (pint's dimensionality as text -> words)
QUANTITIES = {
    "[length]": "a length",
    "[mass]": "a mass",
    "[time]": "a time",
    "[angle]": "an angle",
    "[length] / [time]": "a speed",
    "[length] / [time] ** 2": "an acceleration",
    "[mass] / [length] ** 3": "a density",
    "[mass] / [length] / [time]": "a dynamic viscosity",
    "[angle] / [time]": "an angular speed",
    "[length] ** 2": "an area",
    "[mass] / [time] ** 2": "an energy per area",
    "[length] ** 2 * [mass] / [time] ** 2": "an energy",
    "[angle] * [time] / [length]": "an angle per speed",
    "dimensionless": "a pure number",
}
MAX_TEXT = 64  # characters of a value with a unit (pint is never handed a long expression)
# a number, then an optional fraction ("1 1/8", "1-1/8" or "7/8"), then the unit
_VALUE = re.compile(
    r"\s*(?P<number>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)"
    r"(?:(?:\s+|-)(?P<num>\d+)\s*/\s*(?P<den>\d+)|\s*/\s*(?P<over>\d+)(?![\d.]))?"
    r"\s*(?P<unit>[A-Za-z_%°µ][\w%°µ\s/*^().-]*)?\s*"
)


def unit_of(key: str) -> str | None:
    """The unit of dotted `key` in KEY_UNITS ("*" matching any one part), None when it has none."""
    return _unit_of(key)


@functools.lru_cache(maxsize=4096)
def _unit_of(key: str) -> str | None:
    if key in KEY_UNITS:
        return KEY_UNITS[key]
    parts = key.split(".")
    for pattern, unit in KEY_UNITS.items():
        pp = pattern.split(".")
        if len(pp) == len(parts) and all(p == "*" or p == k for p, k in zip(pp, parts)):
            return unit
    return None


@functools.lru_cache(maxsize=1)
def registry():
    """pint's registry with the radian a base dimension [angle] (see the module's docstring)."""
    from pathlib import Path

    import pint

    here = Path(pint.__file__).parent
    lines = []
    for name in ("constants_en.txt", "default_en.txt"):
        for line in (here / name).read_text(encoding="utf-8").splitlines():
            if line.startswith("@import"):  # (both files are read here)
                continue
            lines.append("radian = [angle] = rad" if line.startswith("radian = [] = rad") else line)
    ureg = pint.UnitRegistry(None, cache_folder=None)
    ureg.load_definitions(lines)
    ureg._build_cache()
    return ureg


def quantity_name(dimensionality) -> str:
    text = str(dimensionality)
    return QUANTITIES.get(text, f"of dimension {text}")


def to_unit(value: str, key: str, rule: str) -> float:
    """The number `value` ("28 g", "1 1/8 oz", "2.4") means in `key`'s unit (KEY_UNITS); a SceneError
    naming key, value and the unit expected for a key without one, a value that is no number with a
    unit, or a unit of the wrong dimension. A number without a unit is in the key's unit."""
    target = unit_of(key)
    if target is None or len(value) > MAX_TEXT:
        raise err(key, value, rule)
    found = _VALUE.fullmatch(value)
    if found is None:
        raise err(key, value, f"{rule}, or a number with a unit of {_expected(target)}, e.g. {_example(target)!r}")
    whole, num, den = found["number"], found["num"], found["over"] or found["den"]
    if den is not None and int(den) == 0:
        raise err(key, value, f"divides by zero; {rule}")
    try:
        number = Decimal(whole)
        if num is not None:
            if not whole.isdigit():
                raise err(key, value, f"a mixed number is a whole number and a fraction, e.g. '1 1/8 oz'; {rule}")
            number += Decimal(num) / Decimal(den)
        elif den is not None:
            number /= Decimal(den)
    except ArithmeticError:  # (an exponent past Decimal's: refused by the key's own check)
        return math.inf
    text = (found["unit"] or "").strip().replace("°", " deg ")
    if not text:
        return float(number)
    ureg = registry()
    try:
        given = ureg.Quantity(1.0, ureg.parse_units(text))
    except Exception:  # noqa: BLE001 - pint's many errors for an unknown or malformed unit: one line
        raise err(key, value, f"{text!r} is not a unit pint knows; {key} takes {_expected(target)}") from None
    wanted = ureg.Quantity(1.0, ureg.parse_units(_pint_unit(target)))
    if given.dimensionality != wanted.dimensionality:
        raise err(
            key,
            value,
            f"{key} takes {_expected(target)}; {text!r} is {quantity_name(given.dimensionality)}",
        )
    factor = Decimal(f"{given.to(wanted.units).magnitude:.15g}")  # (pint's chains of factors, to their exact decimals)
    try:
        return float(number * factor)
    except ArithmeticError:
        return math.inf


def _pint_unit(unit: str) -> str:
    return "dimensionless" if unit == "1" else unit


def _expected(unit: str) -> str:
    """ "a length (m)", "a pure number (1)"."""
    ureg = registry()
    return f"{quantity_name(ureg.Quantity(1.0, ureg.parse_units(_pint_unit(unit))).dimensionality)} ({unit})"


EXAMPLES = {"m": "40 yd", "m/s": "1350 ft/s", "kg": "1 1/8 oz", "deg": "0.5 rad", "kg/m^3": "11.1 g/cm^3", "s": "5 us"}


def _example(unit: str) -> str:
    return EXAMPLES.get(unit, f"1 {unit}" if unit != "1" else "50 %")


_NUMBER_UNIT = re.compile(
    r"\s*(?P<number>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*(?P<unit>[A-Za-z_%°µ][\w%°µ\s/*^().-]*?)?\s*"
)


def split_unit(text: str) -> tuple[str, str]:
    """ "1350 ft/s" -> ("1350", "ft/s"); "0.5" -> ("0.5", ""); text that is no number with a unit
    comes back whole, without a unit."""
    found = _NUMBER_UNIT.fullmatch(text)
    return (text.strip(), "") if found is None else (found["number"], found["unit"] or "")
