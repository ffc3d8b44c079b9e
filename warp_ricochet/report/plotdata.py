"""Arrays for plots, read from an open run file or run group (`/` of a run file, `/runs/NNNN` of a sweep).

Only the rows below `/progress/rows` are read (those are final, also in an unfinished file), at most
`MAX_ROWS` of them. Needs h5py and numpy only (never warp or matplotlib). SI units throughout.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass

import numpy as np

from ..io.h5open import rows_final

__all__ = ["MAX_ROWS", "Landings", "read_landings", "rows_final", "top_view", "axis_name", "scene_dict"]

MAX_ROWS = 5_000_000  # per-pellet rows read for a plot: the first ones, a random sample (pellet i depends only
# on the seed and i; whole shots with collisions); about 0.5 GB of float64 arrays at most


def _value(group, path, default=None):
    ds = group.get(path)
    return default if ds is None else ds[()]


def scene_dict(group) -> dict:
    """The scene as run (the group's or else the file's `scene_toml` attribute), parsed; {} if absent."""
    for node in (group, group.file):
        text = node.attrs.get("scene_toml")
        if text is not None:
            try:
                return tomllib.loads(text.decode() if isinstance(text, bytes) else str(text))
            except ValueError:
                return {}
    return {}


@dataclass
class Landings:
    """Per-pellet landing data of one run (pellets that landed only), SI units.

    position (n, 3) m; distance (n,) m horizontal distance from the shooter; range (n,) m (eq. 42);
    energy (n,) J translational kinetic energy at landing; slipped (n,) int8 or None (first impact:
    1 slip, 0 stick); shooter (3,) m; up (3,) unit vector against gravity; planes: [(name, point,
    normal)]; rows: the rows read; total: the run's pellets; aim (3,): the line of fire (the mean
    launch velocity when stored, else the scene's shot.direction), or None."""

    position: np.ndarray
    distance: np.ndarray
    range: np.ndarray | None
    energy: np.ndarray | None
    slipped: np.ndarray | None
    shooter: np.ndarray
    up: np.ndarray
    planes: list
    rows: int
    total: int
    aim: np.ndarray | None = None


def _up(group) -> np.ndarray:
    g = np.asarray(_value(group, "constants/gravity", (0.0, -9.81, 0.0)), dtype=np.float64).reshape(3)
    norm = np.linalg.norm(g)
    return -g / norm if norm > 0 else np.array([0.0, 1.0, 0.0])


def _shooter(scene) -> np.ndarray:
    """The shooter as the landing tallies take it (`tallies.counts.TallySetup.of`), so a plot's
    distances are those of /stats/quantiles/distance and the danger distances: `[hazard] shooter`,
    else the envelope centre, or the origin for a pellet file."""
    shot, hazard = scene.get("shot", {}), scene.get("hazard") or {}
    if hazard.get("shooter") is not None:
        return np.asarray(hazard["shooter"], dtype=np.float64)
    if shot.get("file"):
        return np.zeros(3)
    return np.asarray(shot.get("envelope_center", (0.0, 0.0, 0.0)), dtype=np.float64)


def _aim(group, scene, rows):
    ds = group.get("pellets/initial/velocity")
    if ds is not None and rows:
        return np.asarray(ds[: min(rows, 1_000_000)], dtype=np.float64).mean(axis=0)
    direction = scene.get("shot", {}).get("direction")
    return None if direction is None else np.asarray(direction, dtype=np.float64)


def _planes(group, scene) -> list:
    points = _value(group, "constants/surfaces/point")
    normals = _value(group, "constants/surfaces/normal")
    if points is None or normals is None:
        return []
    surfaces = scene.get("surfaces", [])
    names = [s.get("name", "") for s in surfaces]
    kinds = [s.get("kind", "plane") for s in surfaces]
    return [
        (
            names[i] if i < len(names) and names[i] else f"plane {i}",
            np.asarray(p, float),
            np.asarray(n, float),
            kinds[i] if i < len(kinds) else "plane",
        )
        for i, (p, n) in enumerate(zip(points, normals))
    ]


def read_landings(group) -> Landings | None:
    """The landing data of a run group, or None when it holds no `pellets/landing/position`."""
    pos_ds = group.get("pellets/landing/position")
    if pos_ds is None:
        return None
    total = int(np.asarray(_value(group, "constants/pellets", 0)).reshape(-1)[0])
    rows = min(rows_final(group), MAX_ROWS, len(pos_ds))
    scene = scene_dict(group)
    position = np.asarray(pos_ds[:rows], dtype=np.float64)
    keep = np.all(np.isfinite(position), axis=1)
    up, shooter = _up(group), _shooter(scene)
    offset = position[keep] - shooter
    horizontal = offset - np.outer(offset @ up, up)
    energy = None
    vel_ds, mass = group.get("pellets/landing/velocity"), _value(group, "constants/mass")
    if vel_ds is not None and mass is not None:
        v = np.asarray(vel_ds[:rows], dtype=np.float64)[keep]
        energy = 0.5 * float(np.asarray(mass).reshape(-1)[0]) * np.einsum("ij,ij->i", v, v)
    rng = group.get("pellets/landing/range")
    slipped = group.get("pellets/impact/slipped")
    return Landings(
        position=position[keep],
        distance=np.linalg.norm(horizontal, axis=1),
        range=None if rng is None else np.asarray(rng[:rows], dtype=np.float64)[keep],
        energy=energy,
        slipped=None if slipped is None else np.asarray(slipped[:rows]).reshape(rows, -1)[keep, 0],
        shooter=shooter,
        up=up,
        planes=_planes(group, scene),
        rows=rows,
        total=total,
        aim=_aim(group, scene, rows),
    )


def top_view(landings: Landings, directions=None):
    """A horizontal basis seen from above: e1 (downrange) the horizontal part of `directions`, else of
    the line of fire (`landings.aim`), else of the mean way from the shooter to the landings (a world
    axis when within 2 degrees of it), e2 = up x e1 (cross-range, to the left of downrange),
    so that (e1, e2) drawn as (right, up) is the view from above, not its mirror. Returns (e1, e2)."""
    up = landings.up
    if directions is None:
        directions = landings.aim if landings.aim is not None else (landings.position - landings.shooter).mean(axis=0)
    d = np.asarray(directions, dtype=np.float64)
    d = d - (d @ up) * up
    axes = np.eye(3)
    if not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-12:  # straight up or down: the flattest axis
        d = axes[int(np.argmin(np.abs(up)))]
        d = d - (d @ up) * up
    i = int(np.argmax(np.abs(d)))
    if abs(d[i]) > np.cos(np.radians(2.0)) * np.linalg.norm(d):  # within 2 degrees of an axis: the axis
        d = np.sign(d[i]) * axes[i]
        d = d - (d @ up) * up
    e1 = d / np.linalg.norm(d)
    e2 = np.cross(up, e1)
    return e1, e2


def axis_name(vector) -> str:
    """A unit vector as text: "+x", "-z" for an axis, else "(0.87, 0, 0.5)"."""
    v = np.asarray(vector, dtype=np.float64)
    for i, name in enumerate("xyz"):
        if math.isclose(abs(v[i]), 1.0, abs_tol=1e-9):
            return ("+" if v[i] > 0 else "-") + name
    return "(" + ", ".join(f"{c:.3g}" for c in v) + ")"
