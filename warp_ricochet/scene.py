"""Scenes: a TOML file describing one shot fired at planes, loaded into validated frozen dataclasses.

All quantities are SI: lengths and positions in m, times in s, velocities in m/s, angular velocities in rad/s,
densities in kg/m^3, accelerations in m/s^2; restitution and friction coefficients are dimensionless.

Layout of a scene file::

    [shot]        pellets: sampled (count, speed, direction, jitter, envelope, spin, seed) or read from `file`
    [[surfaces]]  planes: point, normal (towards the incoming pellets), restitution, mu_s, mu_d, name
    [physics]     gravity, impact_duration (the paper's delta t), bounces
    [collisions]  pellet-pellet collisions (off by default): enabled, restitution, mu_s, mu_d, and the
                  time stepping of the dense phase (see docs/collisions.md)
    [numerics]    precision, chunk_size, fast_math
    [output]      path (HDF5), fields

Every problem raises SceneError with a one-line message: the dotted key, the value and what is allowed.
This module imports numpy and the standard library only (h5py lazily, for .h5 pellet files); never warp.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
import tomllib
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from warp_ricochet.errors import SceneError

__all__ = ["Vec3", "Shot", "Surface", "Physics", "Collisions", "Numerics", "Output", "Scene", "OUTPUT_FIELDS",
           "load_scene", "scene_from_dict", "apply_override", "set_dotted", "parse_sweep", "parse_tie",
           "load_pellet_file"]

Vec3 = tuple[float, float, float]
INT32_MAX = 2**31 - 1
MAX_SWEEP_POINTS = 100_000

OUTPUT_FIELDS = {
    "initial": ("position", "velocity", "angular_velocity"),
    "impact": ("time", "position", "velocity_before", "angular_velocity_before", "velocity", "angular_velocity",
               "slipped", "surface"),
    "landing": ("time", "position", "velocity", "range", "surface"),
}
CORE_FIELDS = tuple(f"{group}.{name}" for group, names in OUTPUT_FIELDS.items() for name in names)
# written only by runs with pellet-pellet collisions
COLLISION_OUTPUT_FIELDS = {
    "collisions": ("count", "last_time"),
    "release": ("time", "position", "velocity", "angular_velocity"),
}
COLLISION_FIELDS = tuple(f"{group}.{name}" for group, names in COLLISION_OUTPUT_FIELDS.items() for name in names)
ALL_FIELDS = CORE_FIELDS + COLLISION_FIELDS


@dataclass(frozen=True)
class Shot:
    """The pellets: sampled from count/speed/direction/... or read from a pellet file (`file`, absolute path)."""
    diameter: float                                   # m
    density: float                                    # kg/m^3
    count: int = 0                                    # pellets per shot
    shots: int = 1                                    # independent shots of `count` pellets each
    speed: float = 0.0                                # m/s
    direction: Vec3 = (1.0, -1.0, 0.0)                # not normalised
    direction_jitter: Vec3 = (0.0, 0.0, 0.0)
    envelope_radius: float = 0.0                      # m
    envelope_center: Vec3 = (0.0, 0.0, 0.0)           # m
    spin: Vec3 = (0.0, 0.0, 0.0)                      # rad/s
    seed: int = 0
    file: str | None = None

    @property
    def pellets(self) -> int:
        """All pellets of the run: count per shot times shots."""
        return self.count * self.shots


@dataclass(frozen=True)
class Surface:
    """A plane through `point` (m) with unit `normal` pointing to the side the pellets come from."""
    point: Vec3
    normal: Vec3
    restitution: float
    mu_s: float
    mu_d: float | None = None
    name: str = ""


@dataclass(frozen=True)
class Physics:
    gravity: Vec3 = (0.0, -9.81, 0.0)                 # m/s^2
    impact_duration: float = 0.0                      # s
    bounces: int = 1


# Steel on steel (docs/collisions.md): restitution 0.9 for hardened steel spheres at low speed
# (Goldsmith, "Impact", 1960); dry friction mu_s 0.74, mu_d 0.57 (Serway & Jewett, Physics for
# Scientists and Engineers, table 5.1). contact_duration: the Hertz contact time of two 2.5 mm steel
# spheres at 10 m/s is about 0.3 us; 1 us is the TC model's default window.
@dataclass(frozen=True)
class Collisions:
    """Pellet-pellet collisions (the paper neglects them). Off unless `enabled`."""
    enabled: bool = False
    restitution: float = 0.9                          # pair E, on the normal relative velocity
    mu_s: float = 0.74
    mu_d: float | None = 0.57                         # <= mu_s; defaults to min(0.57, mu_s)
    contact_duration: float = 1e-6                    # s, TC model: a pellet hit again within it rebounds elastically
    time_step: float | None = None                    # s, fixed step of the dense phase; None adapts it
    step_fraction: float = 0.25                       # adaptive step: closing displacement per step / diameter
    skin: float = 2.25                                # neighbour-list skin, in diameters (9 x step_fraction: a list lasts a block of 8 steps, and one more)
    rounds: int = 4                                   # event rounds per step (several contacts of one pellet)
    max_neighbours: int = 32                          # per pellet in the neighbour list at first (grows when needed)
    max_steps: int = 1_000_000                        # the dense phase stops (and says so) after these
    frame_every: int = 0                              # H5MD trajectory frame every k steps (0: none)


@dataclass(frozen=True)
class Numerics:
    precision: str = "float32"
    chunk_size: int | None = None                     # None: automatic
    fast_math: bool = True                            # CUDA float32: approximate div/sqrt/sin (see README)


@dataclass(frozen=True)
class Output:
    path: str | None = None                           # relative to the current working directory
    fields: tuple[str, ...] = CORE_FIELDS             # "group.field", canonical order


@dataclass(frozen=True)
class Scene:
    shot: Shot
    surfaces: tuple[Surface, ...]
    physics: Physics
    numerics: Numerics
    output: Output
    source: str = dataclasses.field(default="", compare=False)
    collisions: Collisions = Collisions()

    @property
    def pair_collisions(self) -> bool:
        """Pellets of a shot can meet each other: collisions enabled and more than one pellet per
        shot (the run goes through the dense phase, `collisions.run_collision_scene`)."""
        return self.collisions.enabled and self.shot.count > 1

    def to_dict(self) -> dict:
        """Plain TOML-able dict (None omitted, tuples as lists); scene_from_dict(s.to_dict()) == s."""
        shot = _plain(self.shot)
        if self.shot.file is not None:
            for key in _FILE_EXCLUSIVE:
                shot.pop(key, None)
        out = {"shot": shot, "surfaces": [_plain(s) for s in self.surfaces], "physics": _plain(self.physics),
               "numerics": _plain(self.numerics), "output": _plain(self.output)}
        if self.collisions.enabled:
            out["collisions"] = _plain(self.collisions)
        return out

    def to_toml(self) -> str:
        return "\n".join(_toml_lines(self.to_dict(), "")).lstrip("\n") + "\n"

    def replace(self, **changes) -> "Scene":
        return dataclasses.replace(self, **changes)


# ---------------------------------------------------------------------------------------------- errors, keys

class _Missing:
    def __repr__(self):
        return "(missing)"


class _Shown:
    """A value shown by a given one-line text (for values whose repr spans lines or fails)."""
    def __init__(self, text):
        self.text = text

    def __repr__(self):
        return self.text


_MISSING = _Missing()


def _err(key: str, value, allowed: str) -> SceneError:
    """SceneError whose message is guaranteed to be one line."""
    key = key if key.isprintable() else repr(key)[1:-1]
    try:
        text = repr(value)
        ok = text.isprintable()
    except Exception:  # noqa: BLE001 - any user value must give a SceneError, even one whose repr fails
        text, ok = f"<{type(value).__name__}>", False
    if not ok:
        text = " ".join(text.split())
        value = _Shown(text if text.isprintable() else repr(text)[1:-1])
    return SceneError(key, value, " ".join(str(allowed).split()))


def _quote(text: str) -> str:
    """TOML basic string."""
    esc = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b", "\f": "\\f"}
    return '"' + "".join(esc.get(c) or (f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c)
                         for c in text) + '"'


def _bare(key) -> bool:
    return isinstance(key, str) and key != "" and all(c.isascii() and (c.isalnum() or c in "_-") for c in key)


def _join(path: str, key) -> str:
    name = key if _bare(key) else _quote(str(key))
    return f"{path}.{name}" if path else name


def _check_keys(raw: dict, path: str, allowed) -> None:
    for key in raw:
        if key not in allowed:
            raise _err(_join(path, key), raw[key], "unknown key; allowed keys: " + ", ".join(allowed))


# ---------------------------------------------------------------------------------------------- converters
# Each converter is conv(value, dotted_path) -> validated value, with a `rule` text used in messages.

def _rule(rule):
    def deco(conv):
        conv.rule = rule
        return conv
    return deco


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _finite(v, path: str, rule: str) -> float:
    if not _is_number(v):
        raise _err(path, v, rule)
    try:
        x = float(v)
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


# The physical domain the kernels are built for: every product they form stays far inside float32
# (speeds^2 ~ 1e10, spins times radii ~ 1e8), so a float32 run cannot overflow or lose a pellet.
MIN_DIAMETER, MAX_DIAMETER = 1e-6, 1.0  # m
MIN_DENSITY, MAX_DENSITY = 1.0, 1e5  # kg/m^3
MAX_SPEED = 1e5  # m/s
MAX_SPIN = 1e8  # rad/s, each component
MAX_COORDINATE = 1e6  # m, each component of positions (and of direction vectors)
MAX_GRAVITY = 1e4  # m/s^2, each component
MAX_FRICTION = 100.0
MAX_IMPACT_DURATION = 1.0  # s


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
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise _err(path, v, rule)
        return int(v)
    return conv


def _vec3(*, nonzero=False, nonneg=False, scalar=False, unit="", bound=None):
    rule = "must be a list of 3 numbers" + (" or one number" if scalar else "") + (f" ({unit})" if unit else "")

    @_rule(rule)
    def conv(v, path):
        if scalar and _is_number(v):
            xs = (_finite(v, path, rule),) * 3
        elif isinstance(v, (list, tuple)) and len(v) == 3 and all(map(_is_number, v)):
            try:
                xs = tuple(map(float, v))
            except OverflowError:
                xs = (math.inf,)
            if not all(map(math.isfinite, xs)):
                raise _err(path, v, "must be finite")
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
    rule = ("must be one of " + ", ".join(map(repr, choices))) if choices else \
        "must be a string" + ("" if empty else " (not empty)")

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


@_rule("must be a list of field names")
def _fields(v, path):
    if not isinstance(v, (list, tuple)):
        raise _err(path, v, "must be a list of field names")
    chosen = set()
    for name in v:
        if isinstance(name, str) and name in OUTPUT_FIELDS:
            chosen.update(f"{name}.{f}" for f in OUTPUT_FIELDS[name])
        elif isinstance(name, str) and name in COLLISION_OUTPUT_FIELDS:
            chosen.update(f"{name}.{f}" for f in COLLISION_OUTPUT_FIELDS[name])
        elif isinstance(name, str) and name in ALL_FIELDS:
            chosen.add(name)
        else:
            raise _err(path, name, "unknown field; allowed: " + ", ".join((*OUTPUT_FIELDS, *COLLISION_OUTPUT_FIELDS, *ALL_FIELDS)))
    return tuple(f for f in ALL_FIELDS if f in chosen)


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
}
_FILE_EXCLUSIVE = ("speed", "direction", "direction_jitter", "envelope_radius", "envelope_center", "spin", "seed")
_SURFACE = {
    "name": _str(empty=True),
    "point": _vec3(unit="m", bound=MAX_COORDINATE),
    "normal": _vec3(nonzero=True, bound=MAX_COORDINATE),
    "restitution": _number(0, 1),
    "mu_s": _range(0, MAX_FRICTION),
    "mu_d": _range(0, MAX_FRICTION),
}
_PHYSICS = {"gravity": _vec3(unit="m/s^2", bound=MAX_GRAVITY), "impact_duration": _range(0, MAX_IMPACT_DURATION, unit="s"),
            "bounces": _int(1, 16)}
_COLLISIONS = {
    "enabled": _bool,
    "restitution": _number(0, 1),
    "mu_s": _range(0, MAX_FRICTION),
    "mu_d": _range(0, MAX_FRICTION),
    "contact_duration": _range(0, MAX_IMPACT_DURATION, unit="s"),
    "time_step": _range(0, MAX_IMPACT_DURATION, above=True, unit="s"),
    "step_fraction": _range(0, 1, above=True),
    "skin": _range(0, 10, above=True),
    "rounds": _int(1, 64),
    "max_neighbours": _int(1, 256),
    "max_steps": _int(1, INT32_MAX),
    "frame_every": _int(0, INT32_MAX),
}
FLOAT32_EXACT_STEPS = 2**24  # float32 counts every integer up to here
CHECKPOINT_STEPS = 8  # a shot's steps between checkpoints when collisions.frame_every is 0 (collisions.BLOCK_STEPS)
_NUMERICS = {"precision": _str(("float32", "float64")), "chunk_size": _int(1, INT32_MAX), "fast_math": _bool}
_OUTPUT = {"path": _path(), "fields": _fields}
_TOP = ("shot", "surfaces", "physics", "collisions", "numerics", "output")


def _table(raw, path: str, schema: dict, required=()) -> dict:
    """Validated values of the keys given in table `raw` (None counts as absent); defaults are the dataclass's."""
    raw = {} if raw is None else raw
    if not isinstance(raw, dict):
        raise _err(path, raw, "must be a table")
    _check_keys(raw, path, schema)
    out = {}
    for key, conv in schema.items():
        if raw.get(key) is not None:
            out[key] = conv(raw[key], _join(path, key))
        elif key in required:
            raise _err(_join(path, key), _MISSING, f"is required; it {conv.rule}")
    return out


def _shot(raw, base_dir) -> Shot:
    kw = _table(raw, "shot", _SHOT, required=("diameter", "density"))
    if "file" not in kw:
        for key in ("count", "speed"):
            if key not in kw:
                raise _err(f"shot.{key}", _MISSING, f"is required without shot.file; it {_SHOT[key].rule}")
        if kw["count"] * kw.get("shots", 1) > INT32_MAX:
            raise _err("shot.shots", kw["shots"], f"times shot.count ({kw['count']}) must be at most {INT32_MAX} pellets")
        return Shot(**kw)
    for key in _FILE_EXCLUSIVE:
        if key in kw:
            raise _err(f"shot.{key}", raw[key], "not allowed together with shot.file")
    kw["file"] = os.path.abspath(os.path.join(os.fspath(base_dir), kw["file"]))
    n = len(load_pellet_file(kw["file"])["position"])
    if n > INT32_MAX:
        raise _err("shot.file", kw["file"], f"holds {n} pellets; at most {INT32_MAX} are allowed")
    shots = kw.get("shots", 1)
    if n % shots:
        raise _err("shot.shots", shots, f"must divide the number of pellets in shot.file ({n}): consecutive blocks are shots")
    if kw.setdefault("count", n // shots) != n // shots:
        raise _err("shot.count", kw["count"], f"must equal the pellets per shot in shot.file ({n} / {shots} shots) or be left out")
    return Shot(**kw)


def _surface(raw, path: str) -> Surface:
    kw = _table(raw, path, _SURFACE, required=("point", "normal", "restitution", "mu_s"))
    norm = math.hypot(*kw["normal"])
    if abs(norm - 1.0) > 1e-15:  # keeps normalisation idempotent (round trips)
        kw["normal"] = tuple(x / norm for x in kw["normal"])
    if kw.setdefault("mu_d", kw["mu_s"]) > kw["mu_s"]:
        raise _err(f"{path}.mu_d", raw["mu_d"], f"must be a number in [0, mu_s = {kw['mu_s']:g}]")
    return Surface(**kw)


def _collisions(raw) -> Collisions:
    kw = _table(raw, "collisions", _COLLISIONS)
    mu_s = kw.get("mu_s", Collisions.mu_s)
    if "mu_d" not in kw:
        kw["mu_d"] = min(Collisions.mu_d, mu_s)
    elif kw["mu_d"] > mu_s:
        raise _err("collisions.mu_d", raw["mu_d"], f"must be a number in [0, mu_s = {mu_s:g}]")
    return Collisions(**kw)


def scene_from_dict(raw: dict, base_dir=".") -> Scene:
    """Validate a raw scene dict (as read from TOML); shot.file is resolved relative to `base_dir`."""
    if not isinstance(raw, dict):
        raise _err("scene", raw, "must be a table")
    _check_keys(raw, "", _TOP)
    if raw.get("shot") is None:
        raise _err("shot", _MISSING, "is required (a [shot] table)")
    surfaces = [] if raw.get("surfaces") is None else raw["surfaces"]
    if not isinstance(surfaces, (list, tuple)):
        raise _err("surfaces", surfaces, "must be an array of tables ([[surfaces]])")
    collisions = _collisions(raw.get("collisions"))
    shot = _shot(raw["shot"], base_dir)
    pairs = collisions.enabled and shot.count > 1  # as Scene.pair_collisions: the run has a dense phase
    output = _table(raw.get("output"), "output", _OUTPUT)
    if "fields" not in output:
        output["fields"] = ALL_FIELDS if pairs else CORE_FIELDS
    elif not pairs:
        extra = [f for f in output["fields"] if f in COLLISION_FIELDS]
        if extra:
            raise _err("output.fields", extra[0], "needs pellet-pellet collisions: collisions.enabled = true and "
                       "more than one pellet per shot (shot.count > 1)")
    numerics = Numerics(**_table(raw.get("numerics"), "numerics", _NUMERICS))
    if pairs and numerics.precision == "float32":
        # A shot's step counter is a float32 in a float32 run: it stops counting at 2^24, and a shot
        # stops (max_steps) only at a checkpoint, every frame_every steps (or CHECKPOINT_STEPS), so
        # the checkpoint at or after max_steps must come by then, or the shot never stops.
        every = collisions.frame_every or CHECKPOINT_STEPS
        if every > FLOAT32_EXACT_STEPS:
            raise _err("collisions.frame_every", collisions.frame_every, f"at most {FLOAT32_EXACT_STEPS:,} with "
                       "numerics.precision = \"float32\" (a shot's step counter is exact up to 2^24); use float64")
        if -(-collisions.max_steps // every) * every > FLOAT32_EXACT_STEPS:
            raise _err("collisions.max_steps", collisions.max_steps, f"with numerics.precision = \"float32\", its "
                       f"checkpoint (a multiple of {every} steps) must come by step {FLOAT32_EXACT_STEPS:,}, where the "
                       "step counter stops being exact: at most "
                       f"{FLOAT32_EXACT_STEPS // every * every:,}; use float64 for more")
    return Scene(
        shot=shot,
        surfaces=tuple(_surface(s, f"surfaces.{i}") for i, s in enumerate(surfaces)),
        physics=Physics(**_table(raw.get("physics"), "physics", _PHYSICS)),
        numerics=numerics,
        output=Output(**output),
        collisions=collisions,
    )


def load_scene(path, overrides=()) -> Scene:
    """Read a TOML scene, apply "KEY=VALUE" overrides, validate; shot.file is relative to the scene's folder."""
    overrides = (overrides,) if isinstance(overrides, str) else overrides
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, ValueError) as exc:
        raise _err("scene", str(path), f"cannot be read: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        raw = tomllib.loads(text)
    except (ValueError, RecursionError) as exc:
        raise _err("scene", str(path), f"is not valid TOML: {exc}") from None
    for assignment in overrides:
        raw = apply_override(raw, assignment)
    return dataclasses.replace(scene_from_dict(raw, base_dir=Path(path).parent), source=str(path))


# ---------------------------------------------------------------------------------------------- TOML output

def _plain(obj):
    if dataclasses.is_dataclass(obj):
        return {f.name: _plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if getattr(obj, f.name) is not None}
    return [_plain(x) for x in obj] if isinstance(obj, (list, tuple)) else obj


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if v != v else "inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return _quote(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(map(_toml_value, v)) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_join('', k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_lines(d: dict, prefix: str) -> list[str]:
    def is_aot(v):
        return isinstance(v, list) and v and all(isinstance(x, dict) for x in v)
    lines = [f"{_join('', k)} = {_toml_value(v)}" for k, v in d.items() if not isinstance(v, dict) and not is_aot(v)]
    for k, v in d.items():
        name = _join(prefix, k)
        if isinstance(v, dict):
            lines += ["", f"[{name}]", *_toml_lines(v, name)]
        elif is_aot(v):
            for item in v:
                lines += ["", f"[[{name}]]", *_toml_lines(item, name)]
    return lines


# ---------------------------------------------------------------------------------------------- overrides, sweeps

def _dotted(key: str, spec: str, what: str) -> str:
    key = key.strip()
    if not key or not all(part.strip() == part and part for part in key.split(".")):
        raise _err(key or what, spec, "must be KEY=VALUE with KEY a dotted key like surfaces.0.mu_s")
    return key


def set_dotted(raw: dict, key: str, value) -> dict:
    """A deep copy of `raw` with dotted `key` set to `value`; numeric parts index lists, missing tables are made."""
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
            node[part] = [] if nxt.isascii() and nxt.isdigit() else {}
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


def parse_sweep(spec: str) -> tuple[str, list[float]]:
    """ "KEY=start:stop:step" (inclusive; ints stay ints) or "KEY=a,b,c" -> (KEY, values)."""
    key, eq, rhs = str(spec).partition("=")
    if not eq:
        raise _err("sweep", spec, "must be KEY=start:stop:step or KEY=a,b,c")
    key = _dotted(key, spec, "sweep")
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
            raise _err(key, spec, f"gives more than {MAX_SWEEP_POINTS} points")
        as_type = int if all(isinstance(n, int) for n in nums) else float
        values = [as_type(start + i * step) for i in range(int(q) + 1)]
    if len(values) > MAX_SWEEP_POINTS:
        raise _err(key, spec, f"gives more than {MAX_SWEEP_POINTS} points")
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


# ---------------------------------------------------------------------------------------------- pellet files

_PELLET_ARRAYS = ("position", "velocity", "angular_velocity")


def _read_arrays(path: str) -> dict:
    suffix = Path(path).suffix.lower()
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in _PELLET_ARRAYS if k in data.files}
    if suffix in (".h5", ".hdf5"):
        import h5py  # lazily: only pellet files need it
        with h5py.File(path, "r") as f:
            group = f["pellets/initial"] if isinstance(f.get("pellets/initial"), h5py.Group) else f
            return {k: group[k][()] for k in _PELLET_ARRAYS if isinstance(group.get(k), h5py.Dataset)}
    raise _err("shot.file", path, "must be a .npz, .h5 or .hdf5 file")


_FILE_BOUNDS = {"position": (MAX_COORDINATE, "m"), "velocity": (MAX_SPEED, "m/s"), "angular_velocity": (MAX_SPIN, "rad/s")}


def load_pellet_file(path) -> dict[str, np.ndarray]:
    """Initial pellet state from .npz or .h5/.hdf5: position (N,3) m, velocity (N,3) m/s, angular_velocity
    (N,3) rad/s (zeros if absent), as float64. HDF5 arrays sit at the root or under /pellets/initial/."""
    path = os.fspath(path)
    try:
        arrays = _read_arrays(path)
    except SceneError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy, zipfile and h5py raise many kinds for a bad file
        raise _err("shot.file", path, f"cannot be read: {type(exc).__name__}: {exc}") from None
    out, n = {}, None
    for name in _PELLET_ARRAYS:
        key = f"shot.file:{name}"
        if name not in arrays:
            if name == "angular_velocity":
                out[name] = np.zeros((n, 3))
                continue
            raise _err(key, path, "is missing: the file needs position and velocity arrays of shape (N, 3)")
        a = np.asarray(arrays[name])
        if a.dtype.kind not in "iuf":
            raise _err(key, str(a.dtype), "must be a real numeric array")
        if a.ndim != 2 or a.shape[1] != 3:
            raise _err(key, a.shape, "must have shape (N, 3)")
        if a.shape[0] == 0:
            raise _err(key, a.shape, "must hold at least one pellet")
        if n is not None and a.shape[0] != n:
            raise _err(key, a.shape, f"must have the same N as position ({n})")
        n = a.shape[0]
        a = np.ascontiguousarray(a, dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if bad.size:
            raise _err(key, a[bad[0]].tolist(), f"must be finite (pellet {bad[0]})")
        bound, unit = _FILE_BOUNDS[name]
        bad = np.flatnonzero((np.abs(a) > bound).any(axis=1))
        if bad.size:
            raise _err(key, a[bad[0]].tolist(), f"each component must be within +-{bound:g} {unit} (pellet {bad[0]})")
        out[name] = a
    return out
