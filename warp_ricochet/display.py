"""The units summaries and reports are printed in: metric (SI, the default) or imperial (`--units
imperial`): distances in yards (heights in feet and small lengths in inches where a caller asks: `SHORT`), speeds in
feet per second, areas in square feet. Energies stay in
joules (J, and J/m^2 for the energy densities: the hazard thresholds are published in them), times
in seconds, spins in rad/s. Files are SI whatever the choice; this module only changes what is
printed, at the points where a number and its unit are formatted together.

`using("imperial")` sets the system for the code run inside it (a context variable: the default
elsewhere, and in other threads)."""

from __future__ import annotations

import contextlib
import contextvars
import re

SYSTEMS = ("metric", "imperial")
YARD, FOOT, INCH = 0.9144, 0.3048, 0.0254  # m, exact (the international yard, foot and inch, 1959)
# SI unit -> (imperial unit, factor from SI)
IMPERIAL = {"m": ("yd", 1.0 / YARD), "m/s": ("ft/s", 1.0 / FOOT), "m^2": ("ft^2", 1.0 / FOOT**2), "m/s^2": ("ft/s^2", 1.0 / FOOT)}
_SYSTEM = contextvars.ContextVar("warp_ricochet_units", default="metric")
_HEADER_UNIT = re.compile(r"\((m|m/s|m\^2|m/s\^2)\)")


@contextlib.contextmanager
def using(system: str | None):
    """Print in `system` ("metric" or "imperial"; None: metric) inside the block."""
    if system not in (None, *SYSTEMS):
        raise ValueError(f"units must be one of {SYSTEMS}, not {system!r}")
    token = _SYSTEM.set(system or "metric")
    try:
        yield
    finally:
        _SYSTEM.reset(token)


def imperial() -> bool:
    return _SYSTEM.get() == "imperial"


def unit(si_unit: str) -> str:
    """The unit a value of `si_unit` is printed in."""
    return IMPERIAL[si_unit][0] if imperial() and si_unit in IMPERIAL else si_unit


def value(x, si_unit: str):
    """A value of `si_unit` in the unit it is printed in (None, NaN and non-numbers pass)."""
    if not imperial() or si_unit not in IMPERIAL or isinstance(x, bool):
        return x
    if isinstance(x, (tuple, list)):  # a vector (a swept shot.envelope_center)
        return tuple(value(v, si_unit) for v in x)
    try:
        return float(x) * IMPERIAL[si_unit][1]
    except (TypeError, ValueError):
        return x


def factor(si_unit: str) -> float:
    """What a value of `si_unit` is multiplied by to be printed (1 in metric, 1/0.9144 for m in imperial)."""
    return IMPERIAL[si_unit][1] if imperial() and si_unit in IMPERIAL else 1.0


def text(x, si_unit: str, spec: str = ".4g") -> str:
    """ "12.3 yd": a value and its printed unit ("n/a" for None)."""
    x = value(x, si_unit)
    return "n/a" if x is None else f"{x:{spec}} {unit(si_unit)}"


def header(label: str) -> str:
    """A table header with its unit in parentheses in the printed unit: "L+ (m)" -> "L+ (yd)"."""
    return _HEADER_UNIT.sub(lambda m: f"({unit(m.group(1))})", label) if imperial() else label


def row(values: dict, units: dict) -> dict:
    """A copy of `values` with each value whose unit `units[name]` gives in the printed unit."""
    if not imperial():
        return dict(values)
    return {name: value(x, units[name]) if name in units else x for name, x in values.items()}


SHORT = {"ft": FOOT, "in": INCH}  # the units of heights and small lengths (the HTML report's scene)
