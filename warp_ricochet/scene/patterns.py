"""Chokes and shot patterns: `shot.choke` or `shot.pattern` (percent), the fitted angular spread.

A pattern is the percentage of the charge inside a 30-inch (0.762 m) circle at 40 yards (36.576 m)
(docs/scenes.md, "Chokes and patterns"). The chokes' percentages are the traditional ones, the same
in every table read:

- DEFRA, QUARRY: a program to assess the effectiveness of shotgun ammunition (1998), "Editing the
  Current Data for the Gun": true cylinder 40, improved cylinder 50, 1/4 choke 55, 1/2 choke 60,
  3/4 choke 65, full 70;
- Wikipedia, "Choke (firearms)" (revision 601395503, 2014), its table of lead shot in a 30-inch
  circle at 40 yards: cylinder 40, skeet 1 45, improved cylinder 50, skeet 2 (light modified) 55,
  modified 60, improved modified 65, full 70 (and cylinder 70, skeet 75 at 25 yards);
- C. Hawks, "Shotgun chokes" (chuckhawks.com), J. O'Connor's ranges: cylinder 35-40, improved
  cylinder 45-50, 1/4 choke 50-55, modified 55-65, improved modified 65-70, full 70-80.

The model: seen from the muzzle, the pellets' directions are a circular bivariate normal around
the aim on any plane across it, so the radius of a hit on a board at distance D is Rayleigh
distributed, r = D tan(theta) ~ Rayleigh(D s), s the spread (the standard deviation of tan(theta) per
axis; s ~ theta in rad for these small angles). The fraction inside radius R at D is
1 - exp(-(R/D)^2 / (2 s^2)), so the spread that puts p of the charge inside 15 in at 40 yd is, in
closed form, s = (R/D) / sqrt(-2 ln(1 - p)). It neglects what turns pellets after the muzzle: drag
slows them along their paths (it barely turns them), gravity drops the whole pattern alike, and
the pattern grows in proportion to the distance (docs/scenes.md gives the check at 25 yards).
This module imports the standard library only.
"""

from __future__ import annotations

import math

from .keys import MISSING, err, suggest

YARD = 0.9144  # m (exact, international yard of 1959)
INCH = 0.0254  # m (exact)
PATTERN_DISTANCE = 40 * YARD  # m: the patterning distance, 36.576 m
PATTERN_RADIUS = 15 * INCH  # m: the 30-inch circle's radius, 0.381 m

# choke -> percentage of the charge inside 30 in at 40 yd (the sources above agree on every row)
CHOKES = {
    "cylinder": 40.0,
    "skeet": 45.0,
    "improved cylinder": 50.0,
    "light modified": 55.0,
    "modified": 60.0,
    "improved modified": 65.0,
    "full": 70.0,
}


def pattern_spread(percent: float) -> float:
    """The spread s (tan of the polar angle, per axis; ~ rad) that puts `percent` of the charge
    inside PATTERN_RADIUS at PATTERN_DISTANCE: s = (R/D) / sqrt(-2 ln(1 - p))."""
    p = percent / 100.0
    return (PATTERN_RADIUS / PATTERN_DISTANCE) / math.sqrt(-2.0 * math.log1p(-p))


def inside_fraction(spread: float, radius: float, distance: float) -> float:
    """The fraction of the charge within `radius` (m) of the pattern's centre at `distance` (m),
    by the model (straight flight from the muzzle)."""
    return -math.expm1(-((radius / distance) ** 2) / (2.0 * spread**2))


def resolve_pattern(kw: dict, raw: dict) -> dict:
    """[shot]'s `choke` or `pattern` checked against the other keys; a choke resolves `pattern`
    (percent). One-line errors: both given, with a pellet file, or with a nonzero direction_jitter."""
    given = [key for key in ("choke", "pattern") if key in kw]
    if not given:
        return kw
    if len(given) == 2:
        raise err("shot.pattern", raw["pattern"], "not allowed together with shot.choke (a choke gives its pattern)")
    key = given[0]
    if "file" in kw:
        raise err(f"shot.{key}", raw[key], "not allowed together with shot.file")
    if any(kw.get("direction_jitter", (0.0,))):
        raise err(
            "shot.direction_jitter",
            raw["direction_jitter"],
            f"must be 0 with shot.{key}: the pattern gives the pellets' directions",
        )
    if key == "choke":
        kw["pattern"] = CHOKES[kw["choke"]]
    return kw


def check_choke(value, path: str) -> str:
    """A choke's name, else a one-line error with a did-you-mean and the valid names."""
    if not isinstance(value, str) or value not in CHOKES:
        shown = "" if value is MISSING else suggest(value, CHOKES)
        raise err(path, value, f"unknown choke; {shown}allowed: " + ", ".join(map(repr, CHOKES)))
    return value


check_choke.rule = "must be one of " + ", ".join(map(repr, CHOKES))
