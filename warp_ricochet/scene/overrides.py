"""`--set KEY=VALUE` overrides and `sweep --param/--tie` specifications on raw scene dicts."""

from __future__ import annotations

import copy
import math
import tomllib
from decimal import Decimal, InvalidOperation

from .keys import err as _err
from .schema import HAZARD_ENERGY_DENSITY, HAZARD_SPEED
from .sweep import MAX_SWEEP_POINTS
from .units import split_unit, to_unit


def _dotted(key: str, spec: str, what: str) -> str:
    key = key.strip()
    if not key or not all(part.strip() == part and part for part in key.split(".")):
        raise _err(key or what, spec, "must be KEY=VALUE with KEY a dotted key like surfaces.0.mu_s")
    return key


# Tables of names whose defaults a dotted key inside adds to: `--set hazard.energy_density.eye=2e4` (as
# `--param`) keeps the default thresholds beside `eye`, as a key set in any table keeps that table's
# other defaults; `--set 'hazard.energy_density={eye = 2e4}'` replaces them (docs/hazard.md, section 3).
DEFAULT_TABLES = {"hazard.energy_density": dict(HAZARD_ENERGY_DENSITY), "hazard.speed": dict(HAZARD_SPEED)}


def set_dotted(raw: dict, key: str, value) -> dict:
    """A deep copy of `raw` with dotted `key` set to `value`; numeric parts index lists, missing tables are
    made (with their defaults for `DEFAULT_TABLES`)."""
    out = copy.deepcopy(raw)
    parts = _dotted(key, key, "key").split(".")
    node = out
    for i, part in enumerate(parts):
        last, where = i == len(parts) - 1, ".".join(parts[:i])
        if isinstance(node, list):
            if not (part.isascii() and part.isdigit()) or int(part) >= len(node):
                raise _err(key, value, f"index {part} is out of range: {where} has {len(node)} entries")
            part = int(part)
        elif not isinstance(node, dict):
            raise _err(key, value, f"cannot set it: {where} is not a table or array")
        elif not last and node.get(part) is None:
            nxt = parts[i + 1]
            defaults = DEFAULT_TABLES.get(".".join(parts[: i + 1]), {})
            node[part] = [] if nxt.isascii() and nxt.isdigit() else dict(defaults)
        if last:
            node[part] = value
        else:
            node = node[part]
    return out


def apply_override(raw: dict, assignment: str) -> dict:
    """A deep copy of `raw` with "KEY=VALUE" applied; VALUE is a TOML value, or else a plain string."""
    key, eq, text = str(assignment).partition("=")
    if not eq:
        raise _err("override", assignment, "must be KEY=VALUE, e.g. shot.count=1000")
    key, text = _dotted(key, assignment, "override"), text.strip()
    try:
        parsed = tomllib.loads("v = " + text)
        value = parsed["v"] if list(parsed) == ["v"] else text
    except (ValueError, RecursionError):
        value = text
    return set_dotted(raw, key, value)


def _sweep_number(text: str, key: str, spec: str):
    text = text.strip()
    try:
        return int(text)
    except ValueError:
        pass
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise _err(key, spec, f"{text!r} is not a finite number")
    return x


def _sweep_array(key: str, spec: str, rhs: str) -> list:
    """ "KEY=[[0, 1, 0], [0, 2, 0]]": the values as a TOML array, for a vector key (a value written
    with its unit is converted by scene.sweep)."""
    rule = "must be KEY=[v1, v2, ...], a TOML array of the values, e.g. shot.envelope_center=[[0, 1, 0], [0, 2, 0]]"
    try:
        parsed = tomllib.loads("v = " + rhs)
    except (ValueError, RecursionError):
        raise _err(key, spec, rule) from None
    values = parsed["v"]
    if list(parsed) != ["v"] or not isinstance(values, list) or not values:
        raise _err(key, spec, rule)
    if len(values) > MAX_SWEEP_POINTS:
        raise _err(key, spec, f"gives {len(values):,} points; a sweep may have at most {MAX_SWEEP_POINTS:,}")
    return values


def parse_sweep(spec: str) -> tuple[str, list[float]]:
    """ "KEY=start:stop:step" (inclusive; ints stay ints), "KEY=a,b,c" or, for vectors, a TOML array
    "KEY=[[0, 1, 0], [0, 2, 0]]" -> (KEY, values). One unit may be written, once or after every
    number ("30:50:10 yd"): the values are made in it, then converted to the key's (scene.units)."""
    key, eq, rhs = str(spec).partition("=")
    if not eq:
        raise _err("sweep", spec, "must be KEY=start:stop:step or KEY=a,b,c")
    key = _dotted(key, spec, "sweep")
    if rhs.lstrip().startswith("["):
        return key, _sweep_array(key, spec, rhs)
    if ":" not in rhs and rhs.count(",") >= MAX_SWEEP_POINTS:  # (before anything per value)
        raise _err(key, spec, f"gives {rhs.count(',') + 1:,} points; a sweep may have at most {MAX_SWEEP_POINTS:,}")
    texts = [split_unit(t) for t in rhs.split(":" if ":" in rhs else ",")]
    units = {unit for _, unit in texts if unit}
    if len(units) > 1:
        raise _err(key, spec, "must write one unit for all its values (once, or after each), e.g. 30:50:10 yd")
    if units:
        unit = units.pop()
        _, values = parse_sweep(f"{key}={(':' if ':' in rhs else ',').join(t for t, _ in texts)}")
        return key, [to_unit(f"{v!r} {unit}", key, f"a value of --param {key}") for v in values]
    if ":" not in rhs:
        values = [_sweep_number(t, key, spec) for t in rhs.split(",")]
        if not all(isinstance(v, int) for v in values):
            values = [float(v) for v in values]
    else:
        texts = rhs.split(":")
        if len(texts) != 3:
            raise _err(key, spec, "must be KEY=start:stop:step or KEY=a,b,c")
        nums = [_sweep_number(t, key, spec) for t in texts]
        try:  # exact decimal arithmetic on the numbers as typed: 0:0.5:0.05 gives 0.15, not 0.15000000000000002
            start, stop, step = (Decimal(str(n)) for n in nums)
        except InvalidOperation:
            raise _err(key, spec, "start, stop and step must be numbers") from None
        if step == 0 or (stop - start) * step < 0:
            raise _err(key, spec, "step must be nonzero and have the sign of stop - start")
        q = (stop - start) / step
        if q >= MAX_SWEEP_POINTS:
            shown = f"{int(q) + 1:,}" if q < 10**15 else f"about {q:.2E}"
            raise _err(key, spec, f"gives {shown} points; a sweep may have at most {MAX_SWEEP_POINTS:,}")
        as_type = int if all(isinstance(n, int) for n in nums) else float
        values = [as_type(start + i * step) for i in range(int(q) + 1)]
    return key, values


def parse_tie(spec: str) -> tuple[str, float, str | None]:
    """ "KEY=F*" (F times the swept parameter), "KEY=F*OTHER", "KEY=*" -> (KEY, F, OTHER or None)."""
    key, eq, rhs = str(spec).partition("=")
    factor_text, star, other = rhs.partition("*")
    if not eq or not star:
        raise _err(key.strip() or "tie", spec, "must be KEY=FACTOR* or KEY=FACTOR*OTHER_KEY")
    key = _dotted(key, spec, "tie")
    factor = 1.0 if not factor_text.strip() else float(_sweep_number(factor_text, key, spec))
    other = _dotted(other, spec, "tie") if other.strip() else None
    return key, factor, other
