"""The landing tallies of a run on the host: their constants from the scene (`TallySetup`), their
device arrays and struct (`DeviceTally`, zeroed before each chunk) and the run's running totals
(`TallyTotals`, int64, added chunk by chunk: integer sums, so the same for any chunk size).
What is counted, and how, is `tallies.landing`; what the counts mean, docs/hazard.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .bins import BINS, ROW_DISTANCE

ENERGY_QUANTUM_BITS = 24  # the map's energy unit: the reference energy / 2^24


@dataclass(frozen=True)
class TallySetup:
    """What the landing tallies of one scene need (SI): thresholds as |v|^2 in scene order, with
    their names, kinds and values; the shooter and `up`; the map's geometry and energy quantum."""

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    values: tuple[float, ...]
    thresholds2: tuple[float, ...]  # (m/s)^2
    shooter: tuple[float, float, float]
    up: tuple[float, float, float]
    half_mass: float
    area: float
    fractions: tuple[float, ...]
    tail_distances: tuple[float, ...] = ()  # m
    map_surface: int = -1  # -1: no map
    map_origin: tuple = (0.0, 0.0, 0.0)
    map_u: tuple = (0.0, 0.0, 0.0)
    map_v: tuple = (0.0, 0.0, 0.0)
    map_u0: float = 0.0
    map_v0: float = 0.0
    map_cell: float = 1.0
    map_nu: int = 0
    map_nv: int = 0
    quantum: float = 1.0  # J

    @property
    def levels(self) -> int:
        """Hazard levels: 0 to the number of thresholds (how many a landing exceeds)."""
        return len(self.thresholds2) + 1

    @property
    def cells(self) -> int:
        return self.map_nu * self.map_nv

    @property
    def has_map(self) -> bool:
        return self.map_surface >= 0

    @property
    def order(self) -> np.ndarray:
        """Threshold indices by increasing |v|^2 (stable): a landing at level L exceeds order[:L]."""
        return np.argsort(np.asarray(self.thresholds2, dtype=np.float64), kind="stable")

    @classmethod
    def of(cls, scene, mass: float, radius: float, launch_speed: float) -> "TallySetup":
        """The setup of `scene` for pellets of `mass` (kg) and `radius` (m); `launch_speed` (m/s): the
        largest launch speed (the map's energy unit is m launch_speed^2 / 2 / 2^24)."""
        hazard = scene.hazard
        area = math.pi * radius * radius
        thresholds = () if hazard is None else hazard.thresholds
        # E/A = m v^2 / (2 A): a threshold on E/A is one on v^2 = 2 A (E/A) / m
        v2 = tuple(2.0 * area * value / mass if kind == "energy_density" else value * value
                   for _name, kind, value in thresholds)
        shooter = scene.shot.envelope_center if scene.shot.file is None else (0.0, 0.0, 0.0)
        if hazard is not None and hazard.shooter is not None:
            shooter = hazard.shooter
        g = np.asarray(scene.physics.gravity, dtype=np.float64)
        up = tuple(-g / np.linalg.norm(g)) if np.any(g) else (0.0, 0.0, 0.0)
        wind = scene.air.wind if scene.in_air else (0.0, 0.0, 0.0)
        reference = 0.5 * mass * (launch_speed + math.hypot(*wind)) ** 2
        kw = dict(names=tuple(t[0] for t in thresholds), kinds=tuple(t[1] for t in thresholds),
                  values=tuple(t[2] for t in thresholds), thresholds2=v2, shooter=tuple(map(float, shooter)),
                  up=tuple(map(float, up)), half_mass=0.5 * mass, area=area,
                  fractions=() if hazard is None else hazard.fractions, tail_distances=scene.output.tail_distances,
                  quantum=reference / 2.0**ENERGY_QUANTUM_BITS if reference > 0 else 1e-30)
        if hazard is not None and hazard.has_map:
            kw.update(_map_geometry(scene, hazard, np.asarray(shooter, dtype=np.float64)))
        return cls(**kw)


def _map_geometry(scene, hazard, shooter) -> dict:
    """The grid on the map's plane: origin (the shooter projected on it), axes u (map_axis or the
    shot's direction, projected) and v = n x u, lower corner, cells (the extent rounded up to whole cells)."""
    plane = scene.surfaces[hazard.map_surface]
    n = np.asarray(plane.normal, dtype=np.float64)
    origin = shooter - np.dot(shooter - np.asarray(plane.point), n) * n
    axis = np.asarray(hazard.map_axis or scene.shot.direction, dtype=np.float64)
    u = axis - np.dot(axis, n) * n
    if np.linalg.norm(u) < 1e-9 * np.linalg.norm(axis):  # the axis is normal to the plane: any in-plane axis
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    (u0, u1, v0, v1), cell = hazard.map_extent, hazard.map_cell
    return dict(map_surface=hazard.map_surface, map_origin=tuple(origin), map_u=tuple(u), map_v=tuple(v),
                map_u0=u0, map_v0=v0, map_cell=cell, map_nu=math.ceil((u1 - u0) / cell - 1e-9),
                map_nv=math.ceil((v1 - v0) / cell - 1e-9))


CUDA_COPIES = 256  # copies of the counts on CUDA (see `tallies.landing`)
MAX_COPY_BYTES = 1 << 30  # at most this much device memory for the copies of each array


def copies_for(device, nbytes: int) -> int:
    """How many copies of an array of `nbytes` a device counts into."""
    return max(1, min(CUDA_COPIES, MAX_COPY_BYTES // max(nbytes, 1))) if device.is_cuda else 1


_POOL: dict = {}  # (device, role) -> CUDA array kept between runs (allocating 200 MB costs a run ~0.5 ms)


def _buffer(device, role: str, shape, dtype):
    """A device array of `shape`; on CUDA the one kept for `role` if it has that shape and dtype (its
    contents are zeroed before each chunk, `DeviceTally.zero`, or overwritten whole, `reduce`; one
    CUDA run at a time: pipeline._DEVICE_LOCK), else a new one that replaces it: one array a role."""
    import warp as wp

    if not device.is_cuda:
        return wp.zeros(shape, dtype=dtype, device=device)
    key = (str(device), role)
    kept = _POOL.get(key)
    if kept is None or kept.shape != tuple(shape) or kept.dtype != dtype:
        _POOL[key] = None  # (freed before the new one is made)
        _POOL[key] = wp.zeros(shape, dtype=dtype, device=device)
    return _POOL[key]


class DeviceTally:
    """The device arrays of the landing tallies and the kernels' `Tally` struct over their copies
    (empty arrays when the run counts nothing: `active` false). After a chunk's kernel, `reduce`
    sums the copies into `arrays`, the counts the host copies back."""

    def __init__(self, setup: TallySetup, precision: str, device, active: bool):
        import warp as wp

        from ..physics.types import types_for
        from .landing import make_landing_tally

        t = types_for(precision)
        self.setup, self.active, self.device = setup, active, device
        levels, width = setup.levels, setup.cells + 2
        mapped = active and setup.has_map
        shapes = {"hist": (ROW_DISTANCE + levels, BINS) if active else (0, 0),
                  "map_counts": (levels, width) if mapped else (0, 0), "map_energy": (width,) if mapped else (0,)}
        dtypes = {"hist": wp.int32, "map_counts": wp.int32, "map_energy": wp.int64}
        self.arrays = {name: _buffer(device, "sum " + name, shape, dtypes[name]) for name, shape in shapes.items()}
        self.wide = {}
        for name, shape in shapes.items():
            copies = copies_for(device, int(np.prod(shape)) * 8)
            self.wide[name] = _buffer(device, "wide " + name, (copies,) + shape if np.prod(shape) else (1,) + (0,) * len(shape),
                                      dtypes[name])
        s = make_landing_tally(precision).Tally()
        s.hist, s.map_counts, s.map_energy = self.wide["hist"], self.wide["map_counts"], self.wide["map_energy"]
        s.thresholds2 = wp.array(np.asarray(setup.thresholds2, dtype=precision), dtype=t.scalar, device=device)
        s.shooter, s.up = t.vec3(*setup.shooter), t.vec3(*setup.up)
        s.half_mass, s.inverse_area = t.scalar(setup.half_mass), t.scalar(1.0 / setup.area)
        s.map_surface = setup.map_surface
        s.map_origin, s.map_u, s.map_v = t.vec3(*setup.map_origin), t.vec3(*setup.map_u), t.vec3(*setup.map_v)
        s.map_u0, s.map_v0 = wp.float64(setup.map_u0), wp.float64(setup.map_v0)
        s.map_inverse_cell = wp.float64(1.0 / setup.map_cell)
        s.map_nu, s.map_nv = setup.map_nu, setup.map_nv
        s.inverse_quantum = wp.float64(1.0 / setup.quantum)
        self.struct = s

    def zero(self):
        """Before a chunk: its counts start from zero."""
        if self.active:
            for arr in self.wide.values():
                arr.zero_()

    def reduce(self):
        """After a chunk's kernel: the copies summed into `arrays`."""
        if not self.active:
            return
        import warp as wp

        from .landing import sum_copies_kernels

        sum_int32, sum_int64 = sum_copies_kernels()
        for name, kernel in (("hist", sum_int32), ("map_counts", sum_int32), ("map_energy", sum_int64)):
            out = self.arrays[name]
            if out.size:
                wp.launch(kernel, dim=out.shape, inputs=[self.wide[name]], outputs=[out], device=self.device)


class TallyTotals:
    """The run's landing counts so far (int64): `hist` (rows: range, speed, distance by hazard
    level; bins of `tallies.bins`), `map_counts` (level, cell; then outside, elsewhere) and
    `map_energy` (per column, in quanta)."""

    def __init__(self, setup: TallySetup):
        levels, width = setup.levels, setup.cells + 2
        self.setup = setup
        self.hist = np.zeros((ROW_DISTANCE + levels, BINS), dtype=np.int64)
        self.map_counts = np.zeros((levels, width) if setup.has_map else (0, 0), dtype=np.int64)
        self.map_energy = np.zeros(width if setup.has_map else 0, dtype=np.int64)

    def add(self, chunk: dict):
        """Add one chunk's counts ({name: array} as `DeviceTally.arrays`)."""
        for name in ("hist", "map_counts", "map_energy"):
            if chunk[name].size:
                getattr(self, name)[...] += chunk[name]

    def flat(self) -> np.ndarray:
        """All counts in one int64 vector (what /progress keeps for --resume)."""
        return np.concatenate([self.hist.ravel(), self.map_counts.ravel(), self.map_energy.ravel()])

    def load(self, flat) -> "TallyTotals":
        """Counts from `flat` (as `flat()` made them)."""
        flat = np.asarray(flat, dtype=np.int64)
        i = 0
        for name in ("hist", "map_counts", "map_energy"):
            arr = getattr(self, name)
            arr[...] = flat[i:i + arr.size].reshape(arr.shape)
            i += arr.size
        return self
