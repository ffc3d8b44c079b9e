"""The points of a parameter sweep, generated lazily: counted first, refused above `MAX_SWEEP_POINTS`.

`SweepPoints(params, ties)` is a sequence of {dotted key: value} dicts, the Cartesian product of
the swept values (the first key varies slowest) with the tied keys set from them. Point i is made
from i alone (mixed-radix digits), so nothing but the value lists is ever held in memory and a
product of any size is refused in one line before a single point is made.
"""

from __future__ import annotations

import math

from .keys import _Shown
from .keys import err as _err
from .units import to_unit, unit_of

MAX_SWEEP_POINTS = 10_000  # points of one sweep (each is a run group of the sweep file)


class SweepPoints:
    """The points of a sweep. params: {key: [values]}; ties: [(key, factor, source key or None)]:
    key = round(factor * value of source, 12) at each point (source None: the one swept key)."""

    def __init__(self, params: dict, ties=()):
        self.keys = list(params)
        self.values = [[_in_unit(k, v) for v in params[k]] for k in self.keys]
        if not self.keys:
            raise _err("--param", "(none)", "a sweep needs at least one swept key")
        for key, values in zip(self.keys, self.values):
            if not values:
                raise _err(key, values, "has no values")
        count = math.prod(len(v) for v in self.values)
        if count > MAX_SWEEP_POINTS:
            shown = " x ".join(f"{k} ({len(v):,} values)" for k, v in zip(self.keys, self.values))
            raise _err(
                "--param",
                _Shown(f"{len(self.keys)} keys"),
                f"{shown} give {count:,} points; a sweep may have at most {MAX_SWEEP_POINTS:,} (MAX_SWEEP_POINTS)",
            )
        self.count = count
        self.ties = []
        for key, factor, src in ties:
            if src is None:
                if len(self.keys) != 1:
                    raise _err("--tie", key, "must name the parameter it follows (KEY=F*PARAM) when several are swept")
                src = self.keys[0]
            if src not in self.keys:
                raise _err("--tie", _Shown(f"{key}={factor}*{src}"), f"{src} is not a swept parameter")
            if any(isinstance(v, (list, tuple)) for v in self.values[self.keys.index(src)]):
                raise _err("--tie", _Shown(f"{key}={factor}*{src}"), f"{src} is swept over vectors; a tie follows a number")
            if key in self.keys or key in (t[0] for t in self.ties):
                raise _err(
                    "--tie",
                    _Shown(f"{key}={factor}*{src}"),
                    f"{key} is already "
                    + ("swept (--param)" if key in self.keys else "tied")
                    + ": give each key one --param or --tie",
                )
            self.ties.append((key, factor, src))

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, index: int) -> dict:
        if not -self.count <= index < self.count:
            raise IndexError(index)
        index %= self.count
        point = {}
        for key, values in zip(reversed(self.keys), reversed(self.values)):  # the last key varies fastest
            index, digit = divmod(index, len(values))
            point[key] = values[digit]
        point = {k: point[k] for k in self.keys}
        for key, factor, src in self.ties:
            point[key] = round(factor * point[src], 12)
        return point

    def __iter__(self):
        return (self[i] for i in range(self.count))

    @property
    def columns(self) -> list[str]:
        """Every key set at a point: the swept keys, then the tied ones."""
        return self.keys + [t[0] for t in self.ties if t[0] not in self.keys]


def _in_unit(key: str, value):
    """A swept value written with its unit ("1350 ft/s"; in a vector, ["0 yd", "4 ft", 0]) as the
    number it means in the key's unit, as the scene reads it (scene.units), so that the points, the
    manifest and /sweep hold numbers; any other value as given."""
    if isinstance(value, (list, tuple)):
        return [_in_unit(key, v) for v in value]
    if isinstance(value, str) and unit_of(key) is not None:
        return to_unit(value, key, f"a value of --param {key}")
    return value
