"""Is a row of a report the paper's scene? The test behind `report --paper` and the paper's points in plots.

Zohdi (2021) reports one scene (`examples/paper.toml`, installed as `warp_ricochet/examples/paper.toml`)
at mu_s = 0, 0.05, ..., 0.5 with mu_d = 0.9 mu_s. A row (a run, or a sweep point: the file's base
scene with the point's swept and tied values set) is the paper's when its scene, normalised by the
scene loader (defaults filled in), equals the paper's in everything that changes the physics, apart
from the friction coefficients of the planes. Ignored as well: what does not change a pellet's
physics or only samples it (`shot.count`, `shot.shots`, `shot.seed`, plane names, `[numerics]`,
`[output]`), `[collisions]` when not enabled and `[air]` of zero density (vacuum).
Needs the standard library and numpy only (never warp).
"""

from __future__ import annotations

import math
import tomllib

from ..errors import RicochetError

__all__ = ["paper_scene", "signature", "row_scene", "differences", "is_papers"]

IGNORED_SHOT = ("count", "shots", "seed")
IGNORED_SURFACE = ("mu_s", "mu_d", "name")
IGNORED_TABLES = ("numerics", "output")

_PAPER: dict = {}


def _normalised(raw: dict) -> dict | None:
    """A raw scene dict through the loader and back (defaults filled in); None if it does not load."""
    from ..scene import scene_from_dict

    try:
        return tomllib.loads(scene_from_dict(raw).to_toml())
    except (RicochetError, ValueError, TypeError, KeyError, OSError):
        return None


def paper_scene() -> dict:
    """The paper's scene (the package's examples/paper.toml), normalised."""
    if not _PAPER:
        from ..examples import example_text

        _PAPER.update(_normalised(tomllib.loads(example_text("paper"))) or {})
    return _PAPER


def signature(scene: dict) -> dict:
    """What of a normalised scene must equal the paper's (see the module docstring)."""
    out = {k: v for k, v in scene.items() if k not in IGNORED_TABLES}
    out["shot"] = {k: v for k, v in scene.get("shot", {}).items() if k not in IGNORED_SHOT}
    out["surfaces"] = [{k: v for k, v in s.items() if k not in IGNORED_SURFACE} for s in scene.get("surfaces", [])]
    if not out.get("collisions", {}).get("enabled", False):
        out.pop("collisions", None)
    if "air" in out and float(out["air"].get("density", 1.0)) == 0.0:
        out.pop("air")
    return out


def row_scene(base_toml: str, row: dict, keys) -> dict | None:
    """The normalised scene of a row: `base_toml` with the row's values of the dotted `keys` set."""
    from ..scene import set_dotted

    try:
        raw = tomllib.loads(str(base_toml))
        for key in keys:
            value = row.get(key)
            if isinstance(value, float) and math.isfinite(value) and value == int(value) and _is_int(raw, key):
                value = int(value)
            raw = set_dotted(raw, key, value)
    except (RicochetError, ValueError, TypeError):
        return None
    return _normalised(raw)


def _is_int(raw: dict, key: str) -> bool:
    """Whether the base scene holds an integer at dotted `key` (sweeps store every value as float64)."""
    node = raw
    for part in key.split("."):
        try:
            node = node[int(part)] if isinstance(node, list) else node[part]
        except (KeyError, IndexError, ValueError, TypeError):
            return False
    return isinstance(node, int) and not isinstance(node, bool)


def _flat(value, prefix="") -> dict:
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out.update(_flat(v, f"{prefix}{k}."))
        return out
    if isinstance(value, list) and value and isinstance(value[0], dict):
        out = {}
        for i, v in enumerate(value):
            out.update(_flat(v, f"{prefix}{i}."))
        return out
    return {prefix[:-1]: value}


def differences(scene: dict | None) -> list[tuple[str, object, object]]:
    """[(dotted key, this scene's value, the paper's)] where a normalised scene is not the paper's."""
    if scene is None:
        return [("scene_toml", "unreadable", "the paper's scene")]
    ours, theirs = _flat(signature(scene)), _flat(signature(paper_scene()))
    return [(k, ours.get(k), theirs.get(k)) for k in sorted(set(ours) | set(theirs)) if ours.get(k) != theirs.get(k)]


def is_papers(base_toml: str, row: dict, keys) -> bool:
    """Whether a report row is the paper's scene (apart from friction)."""
    return not differences(row_scene(base_toml, row, keys))
