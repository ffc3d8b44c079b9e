"""The landing tallies of a run on the host: their constants from the scene (`TallySetup`), their
device arrays and struct (`DeviceTally`: the chunks' counts, added to the run's int64 totals on
the device) and those totals on the host (`TallyTotals`). Integer sums: the same for
any chunk size and after --resume.
What is counted, and how, is `tallies.landing`; what the counts mean, docs/hazard.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .bins import BINS, ROW_DISTANCE

PATH_PARTS = 4  # parts a path segment's piece is cut in (`tallies.path`: height and speed monotone on each)
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
    rest: bool = False  # physics.until = "rest": the rest distances' histogram too (`rest` of the totals)
    body_height: float = 1.8  # m (`tallies.path`)
    ground_point: tuple = (0.0, 0.0, 0.0)  # m, on the hazard's ground plane (the map's surface, else surface 0)
    ground_normal: tuple = (0.0, 0.0, 1.0)  # its normal / (normal . up)
    places: tuple = ()  # ((name, (x, y, z) m, radius m), ...): the named places
    terrain: object = field(default=None, compare=False, repr=False)  # the ground's `terrain_ground.TerrainGrid`

    @property
    def levels(self) -> int:
        """Hazard levels: 0 to the number of thresholds (how many a landing exceeds)."""
        return len(self.thresholds2) + 1

    @property
    def path(self) -> bool:
        """The hazard is watched along the path (`tallies.path`): a scene with thresholds."""
        return len(self.thresholds2) > 0

    @property
    def hist_rows(self) -> int:
        """Rows of `hist`: range, speed, distance by level, then each threshold's reach (with `path`)."""
        return ROW_DISTANCE + self.levels + (len(self.thresholds2) if self.path else 0)

    @property
    def reach_row(self) -> int:
        return ROW_DISTANCE + self.levels

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
    def of(cls, scene, mass: float, radius: float, launch_speed: float) -> TallySetup:
        """The setup of `scene` for pellets of `mass` (kg) and `radius` (m); `launch_speed` (m/s): the
        largest launch speed (the map's energy unit is m launch_speed^2 / 2 / 2^24)."""
        hazard = scene.hazard
        area = math.pi * radius * radius
        thresholds = () if hazard is None else hazard.thresholds
        # E/A = m v^2 / (2 A): a threshold on E/A is one on v^2 = 2 A (E/A) / m
        v2 = tuple(2.0 * area * value / mass if kind == "energy_density" else value * value for _name, kind, value in thresholds)
        shooter = scene.shot.envelope_center if scene.shot.file is None else (0.0, 0.0, 0.0)
        if hazard is not None and hazard.shooter is not None:
            shooter = hazard.shooter
        g = np.asarray(scene.physics.gravity, dtype=np.float64)
        up = tuple(-g / np.linalg.norm(g)) if np.any(g) else (0.0, 0.0, 0.0)
        wind = scene.air.wind if scene.in_air else (0.0, 0.0, 0.0)
        reference = 0.5 * mass * (launch_speed + math.hypot(*wind)) ** 2
        kw = dict(
            names=tuple(t[0] for t in thresholds),
            kinds=tuple(t[1] for t in thresholds),
            values=tuple(t[2] for t in thresholds),
            thresholds2=v2,
            shooter=tuple(map(float, shooter)),
            up=tuple(map(float, up)),
            half_mass=0.5 * mass,
            area=area,
            fractions=() if hazard is None else hazard.fractions,
            tail_distances=scene.output.tail_distances,
            quantum=reference / 2.0**ENERGY_QUANTUM_BITS if reference > 0 else 1e-30,
            rest=scene.physics.until == "rest",
        )
        if hazard is not None:
            kw.update(_ground(scene, hazard, np.asarray(up, dtype=np.float64)))
        if hazard is not None and hazard.has_map:
            kw.update(_map_geometry(scene, hazard, np.asarray(shooter, dtype=np.float64)))
        return cls(**kw)


def _ground(scene, hazard, up) -> dict:
    """The hazard's ground plane (the map's surface) with its normal over its height per unit of
    normal distance, body height and the named places (radius: area / (2 body height))."""
    from ..physics.geometry import project  # (imports warp: not at the top, as the rest of this module)

    point, n = project(scene.surfaces[hazard.map_surface], np.zeros(3))
    n = n / np.linalg.norm(n)
    rise = float(n @ up) if np.any(up) else 1.0
    height = float(hazard.body_height)
    places = tuple((p.name, tuple(map(float, p.position)), float(r)) for p, r in zip(hazard.points, hazard.radii))
    return dict(
        body_height=height,
        ground_point=tuple(map(float, point)),
        ground_normal=tuple(n / rise) if abs(rise) > 1e-12 else tuple(n),
        places=places,
    )


def _map_geometry(scene, hazard, shooter) -> dict:
    """The grid on the map's plane: origin (the shooter projected on it), axes u (map_axis or the
    shot's direction, projected) and v = n x u, lower corner, cells (the extent rounded up to whole cells)."""
    from ..physics.geometry import project  # (imports warp: not at the top, as the rest of this module)

    origin, n = project(scene.surfaces[hazard.map_surface], shooter)
    axis = np.asarray(hazard.map_axis or scene.shot.direction, dtype=np.float64)
    u = axis - np.dot(axis, n) * n
    if np.linalg.norm(u) < 1e-9 * np.linalg.norm(axis):  # the axis is normal to the plane: any in-plane axis
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    (u0, u1, v0, v1), cell = hazard.map_extent, hazard.map_cell
    return dict(
        map_surface=hazard.map_surface,
        map_origin=tuple(origin),
        map_u=tuple(u),
        map_v=tuple(v),
        map_u0=u0,
        map_v0=v0,
        map_cell=cell,
        map_nu=math.ceil((u1 - u0) / cell - 1e-9),
        map_nv=math.ceil((v1 - v0) / cell - 1e-9),
    )


GZIP_ZEROS = 128  # gzip level 1 stores runs of zeros at least this many times smaller (zlib: 228x)
GZIP_WORD = 16  # bytes at most a nonzero int64 costs amid zeros at gzip level 1 (zlib: about 10)
GZIP_OVERHEAD = 1 << 16  # a compressed dataset's chunk index and headers


def gzip_bytes(words: int, nonzero: int) -> int:
    """Bytes at most that `words` int64 holding at most `nonzero` nonzero ones take gzip-compressed
    (level 1, as io.tally_out stores them): the zeros' runs plus each nonzero word, never more than
    stored plainly."""
    dense = 8 * words
    return min(dense, dense // GZIP_ZEROS + GZIP_WORD * min(nonzero, words)) + GZIP_OVERHEAD


def tally_bytes(setup: TallySetup, device, with_file: bool, pellets: int) -> tuple[int, int, int]:
    """(host, device, file) bytes the landing tallies of a run of `pellets` on `device` take at
    most. Memory: every page touched, as when landings cover the whole map (a sparse run's resident
    memory is less: 1e6 cells x 31 thresholds, 200 pellets, CPU, with a file: 1.2 GB measured, 1.8
    GB estimated). What is alive at once at the end of a run: the device's counts (int32; the
    histograms in `copies_for` copies) and int64 totals (F bytes); on the host the dense totals (F),
    with a file a host slot's copy of them (one per slot: 2 on CUDA) and `flat()`'s for /progress (F
    each), on CUDA the dense copy `receive` makes (F), and `quantiles.summarize`'s map layers ((levels
    + thresholds + 2) int64 per cell); on the CPU the device's arrays are host memory too. The file,
    every dataset gzip-compressed (`gzip_bytes`): /progress/tally's two slots (a landing adds to at
    most one bin of each histogram row and one cell of each map row), the histogram counts, and the
    map's count, energy and above layers (at most one cell each a landing)."""
    levels, thresholds, cells = setup.levels, setup.levels - 1, setup.cells if setup.has_map else 0
    width = cells + 2 if setup.has_map else 0
    hist = (setup.hist_rows + int(setup.rest)) * BINS  # (with the rest distances' row)
    exposed = levels * width if setup.path else 0  # the passes' map (`tallies.path`)
    words = hist + levels * width + width + exposed
    flat = 8 * words
    on_device = 4 * (hist * copies_for(device, hist * 4) + levels * width + exposed) + 8 * width + flat
    host = flat + 8 * (levels + thresholds + 2) * cells * (2 if setup.path else 1)
    if with_file:
        host += (2 if device.is_cuda else 1) * flat + flat
    if device.is_cuda:
        host += flat
    else:
        host, on_device = host + on_device, 0
    file = 0
    if with_file:
        touched = (ROW_DISTANCE + levels) + (levels + 1 if setup.has_map else 0)  # words a landing adds to
        file = 2 * gzip_bytes(words, pellets * touched) + gzip_bytes(hist, pellets * (ROW_DISTANCE + levels))
        if setup.has_map:
            file += (thresholds + 2) * gzip_bytes(cells, pellets)
            if setup.path:  # the passes' layers: a pellet passes many cells, any of them may be nonzero
                file += (thresholds + 1) * gzip_bytes(cells, cells)
    return host, on_device, file


CUDA_COPIES = 256  # copies of the histograms on CUDA (see `tallies.landing`), a power of two
MAX_COPY_BYTES = 1 << 30  # at most this much device memory for the copies


def copies_for(device, nbytes: int) -> int:
    """How many copies (a power of two) of histograms of `nbytes` a device counts into."""
    if not device.is_cuda:
        return 1
    most = max(1, min(CUDA_COPIES, MAX_COPY_BYTES // max(nbytes, 1)))
    return 1 << (most.bit_length() - 1)


_POOL: dict = {}  # device arrays and pinned host arrays kept between runs (allocating 200 MB costs a run ~0.5 ms)
_CLEAN: set = set()  # the pooled count arrays known to be all zero (`DeviceTally.fold` and `receive` leave them so)


def pooled_bytes(device) -> int:
    """Device bytes of the arrays kept for the next run on `device` (`_buffer`): free for a run's
    planning (`chunks.free_device_bytes`), as a run frees them before it allocates unless it repeats
    the last one's chunks (`pipeline.release_kept`)."""
    import warp as wp

    return sum(a.capacity for (where, _role), a in _POOL.items() if where == str(device) and isinstance(a, wp.array))


def release_pool(device) -> None:
    """Free the device arrays kept for the next run on `device` (`_buffer`); pinned host buffers stay."""
    import warp as wp

    for key in [k for k, a in _POOL.items() if k[0] == str(device) and isinstance(a, wp.array)]:
        del _POOL[key]
        _CLEAN.discard(key)


def _unset(shape, dtype, device):
    """A device array left as allocated (tests fill it instead, to show that nothing reads it unwritten)."""
    import warp as wp

    return wp.empty(shape, dtype=dtype, device=device)


def _buffer(device, role: str, size, dtype, zeroed: bool = True):
    """A device array of `size` (or shape); on CUDA the one kept for `role` if it has that shape and
    dtype (one CUDA run at a time: pipeline._DEVICE_LOCK), else a new one, zeroed (or, not `zeroed`,
    left as allocated), that replaces it."""
    import warp as wp

    make = wp.zeros if zeroed else _unset
    shape = tuple(size) if isinstance(size, tuple) else (size,)
    key = (str(device), role)
    if not device.is_cuda or not size:
        if device.is_cuda:  # (a role this run does not need: its kept array freed, as its plan counted it free)
            _POOL.pop(key, None)
            _CLEAN.discard(key)
        return make(shape, dtype=dtype, device=device)
    kept = _POOL.get(key)
    if kept is None or kept.shape != shape or kept.dtype != dtype:
        _POOL[key] = None  # (freed before the new one is made)
        _POOL[key] = make(shape, dtype=dtype, device=device)
        if zeroed:
            _CLEAN.add(key)
    return _POOL[key]


def log_buffer(device, words: int, dtype, limit: int):
    """The step log of `words` words: (a flat array of them, None) up to `limit` words; past it (an
    array's dimension holds less than 2^31) (a flat view of the first `limit` words of rows of `limit`
    words that hold them all, those rows). Kernels reach the words past the view's shape by raw
    64-bit index (`tallies.path_replay`). Not zeroed: a column's words are written before they
    are read."""
    import warp as wp

    if words <= limit:
        return _buffer(device, "step log", words, dtype, zeroed=False), None
    rows = _buffer(device, "step log", (-(-words // limit), limit), dtype, zeroed=False)
    return wp.array(ptr=rows.ptr, dtype=dtype, shape=(limit,), device=device), rows


FOLD_LIMIT = (1 << 31) - 1  # pellets whose histogram counts may wait unfolded (int32 bins)
SPARSE_CAPACITY = 1 << 16  # nonzero totals a run's end fetches as (index, value) pairs (`DeviceTally.request`)
COUNTS = ("hist", "map_counts", "map_energy", "rest", "exposure", "places")  # the counts, in `TallyTotals.flat` order
HISTOGRAMS = ("hist", "rest")  # the counts in copies, folded together


def _pinned(device, arrays: dict) -> dict:
    """Host arrays like `arrays` ({name: device array}), pinned on CUDA and kept between runs."""
    import warp as wp

    key = (str(device), tuple((name, arr.shape, arr.dtype) for name, arr in arrays.items()))
    if key not in _POOL:
        _POOL[key] = {
            name: wp.empty(arr.shape, dtype=arr.dtype, device="cpu", pinned=device.is_cuda) for name, arr in arrays.items()
        }
    return _POOL[key]


class DeviceTally:
    """The device arrays of the landing tallies and the kernels' `Tally` struct over them (empty
    arrays when the run counts nothing: `active` false): the counts of a chunk (int32, the
    histograms in copies), which `fold` adds to the run's totals on the device (`totals`, int64,
    flat: what the host copies back) and sets to zero again, so no chunk needs its own zeroing.
    `log` = (threads, words): the step log of a run to rest that watches its path (`physics.line_log`:
    `words` a thread; (0, 0): none); `wide`: it may hold more than INDEX_LIMIT words (a record log,
    indexed in 64 bits: `tallies.path_replay`; `log_buffer`)."""

    def __init__(
        self, setup: TallySetup, precision: str, device, active: bool, log: tuple[int, int] = (0, 0), wide: bool = False
    ):
        import warp as wp

        from ..physics.line_log import INDEX_LIMIT
        from ..physics.types import types_for
        from .landing import MAX_THRESHOLDS, make_landing_tally

        t = types_for(precision)
        self.setup, self.active, self.device = setup, active, device
        self.requested = None  # the event of `request`'s copies (CUDA)
        levels, width = setup.levels, setup.cells + 2
        mapped = active and setup.has_map
        sizes = {
            "hist": setup.hist_rows * BINS if active else 0,
            "map_counts": levels * width if mapped else 0,
            "map_energy": width if mapped else 0,
            "rest": BINS if active and setup.rest else 0,
            "exposure": levels * width if mapped and setup.path else 0,
            "places": levels * len(setup.places) if active and setup.path else 0,
        }
        self.copies = copies_for(device, (sizes["hist"] + sizes["rest"]) * 4)
        dtypes = {name: wp.int32 for name in sizes}
        dtypes["map_energy"] = wp.int64
        self.counts = {
            name: _buffer(device, "counts " + name, size * (self.copies if name in HISTOGRAMS else 1), dtypes[name])
            for name, size in sizes.items()
        }
        bounds = np.cumsum([0, *sizes.values()])  # the totals: one array (one pack, one copy), a view a name
        self.flat = _buffer(device, "totals", int(bounds[-1]), wp.int64)
        self.totals = {
            name: self.flat[int(bounds[i]) : int(bounds[i + 1])] if sizes[name] else wp.zeros(0, dtype=wp.int64, device=device)
            for i, name in enumerate(sizes)
        }
        capacity = SPARSE_CAPACITY if active else 0
        self.sparse = {
            "count": _buffer(device, "sparse count", 1, wp.int32),
            "index": _buffer(device, "sparse index", capacity, wp.int32),
            "value": _buffer(device, "sparse value", capacity, wp.int64),
        }
        runs = levels * setup.map_nv * (setup.map_nu + 1) if mapped and setup.path else 0
        self.runs = _buffer(device, "runs", runs, wp.int32)  # (`runs_kernel` leaves it zero)
        fns = make_landing_tally(precision)
        s = fns.Tally()
        s.hist, s.map_counts, s.map_energy = self.counts["hist"], self.counts["map_counts"], self.counts["map_energy"]
        s.rest_hist = self.counts["rest"]
        s.exposure, s.place_counts, s.exposure_runs = self.counts["exposure"], self.counts["places"], self.runs
        s.reach_row, s.body_height = setup.reach_row, t.scalar(setup.body_height)
        s.path_thresholds, s.path_parts = (len(setup.thresholds2) if setup.path else 0), PATH_PARTS
        s.ground_point, s.ground_normal = t.vec3(*setup.ground_point), t.vec3(*setup.ground_normal)
        s.place_position = wp.array([p[1] for p in setup.places], dtype=t.vec3, device=device)
        s.place_radius2 = wp.array([p[2] ** 2 for p in setup.places], dtype=t.scalar, device=device)
        s.terrain = wp.array(setup.terrain.packed() if setup.terrain is not None else [], dtype=t.scalar, device=device)
        if log[0] * log[1] > INDEX_LIMIT and not wide:  # (a kernel indexes it in 32 bits: `chunks.log_rows` keeps within)
            raise ValueError(f"step log of {log[0]} threads x {log[1]} words: past {INDEX_LIMIT} elements")
        s.log_threads, s.log_words = log
        s.steps, held = log_buffer(device, log[0] * log[1], t.scalar, INDEX_LIMIT)  # (written before it is read)
        self.places = (s.place_position, s.place_radius2, s.terrain, s.steps, held)  # (kept alive with the struct)
        s.hist_stride, s.copy_mask, s.map_width = sizes["hist"], self.copies - 1, width
        unused = (math.inf,) * (MAX_THRESHOLDS - len(setup.thresholds2))
        s.thresholds2 = fns.Thresholds(*(float(np.dtype(precision).type(v)) for v in setup.thresholds2), *unused)
        s.shooter, s.up = t.vec3(*setup.shooter), t.vec3(*setup.up)
        s.half_mass, s.inverse_area = t.scalar(setup.half_mass), t.scalar(1.0 / setup.area)
        s.map_surface, s.map_cells, s.map_nu = setup.map_surface, setup.cells, setup.map_nu
        origin, u, v = (np.asarray(x, dtype=np.float64) for x in (setup.map_origin, setup.map_u, setup.map_v))
        s.map_u_cell, s.map_v_cell = t.vec3(*(u / setup.map_cell)), t.vec3(*(v / setup.map_cell))
        s.map_u_start = t.scalar((origin @ u + setup.map_u0) / setup.map_cell)
        s.map_v_start = t.scalar((origin @ v + setup.map_v0) / setup.map_cell)
        s.map_nu_cells, s.map_nv_cells = t.scalar(setup.map_nu), t.scalar(setup.map_nv)
        s.energy_scale = t.scalar(setup.half_mass / setup.quantum)
        self.struct = s

    def start(self, totals: TallyTotals | None, every_chunk: bool = False):
        """Before a run's first chunk: its totals from `totals` (a resumed run's), else set by their
        first fold (`unset`), and its count arrays zero (unless a fold left them so); `every_chunk`:
        the totals are read after every chunk (a run with a file), so every fold folds them all."""
        self.every_chunk, self.unfolded, self.unset = every_chunk, 0, set()
        if not self.active:
            return
        import warp as wp

        for name in COUNTS:
            if self.device.is_cuda and (str(self.device), "counts " + name) not in _CLEAN:  # (CPU: fresh zeros)
                self.counts[name].zero_()
        if self.device.is_cuda and (str(self.device), "runs") not in _CLEAN:
            self.runs.zero_()
        if totals is None:
            self.unset = set(COUNTS)
        else:
            wp.copy(self.flat, wp.array(totals.flat(), dtype=wp.int64, device="cpu"))

    def resolve(self):
        """The chunk's runs of passes along the map's rows (`tallies.path.flush`) added into its
        exposure counts, one entry a cell of each run, and zeroed."""
        if self.runs.size:
            import warp as wp

            from .landing import runs_kernel

            setup = self.setup
            wp.launch(
                runs_kernel(),
                dim=setup.levels * setup.map_nv,
                inputs=[self.runs, setup.map_nu, setup.map_nv, setup.cells + 2],
                outputs=[self.counts["exposure"]],
                device=self.device,
            )

    def fold(self, rows: int, last: bool):
        """After a chunk's kernel (`rows` pellets; `last`: the totals are read after it): its map
        counts added to the totals, then zeroed; its histogram counts (every copy) too when `last`,
        when the run reads its totals after every chunk (`start`), or when one more chunk of `rows`
        could take a bin past int32 (a pellet adds at most one count to a bin). Folding the copies
        (hundreds of MB on CUDA) once a run instead of once a chunk spares their reading."""
        if not self.active:
            return
        import warp as wp

        from .landing import fold_kernel

        self.resolve()
        self.unfolded += rows
        names = ["map_counts", "map_energy", "exposure", "places"]
        if last or self.every_chunk or self.unfolded + rows > FOLD_LIMIT:
            names += HISTOGRAMS
            self.unfolded = 0
        for name in names:
            total, add = self.totals[name], int(name not in self.unset)
            if total.size:
                wp.launch(
                    fold_kernel(),
                    dim=total.size,
                    inputs=[self.counts[name], total.size, add],
                    outputs=[total],
                    device=self.device,
                )
            self.unset.discard(name)
        if self.device.is_cuda:
            _CLEAN.update((str(self.device), "counts " + name) for name in names)
            _CLEAN.add((str(self.device), "runs"))

    def request(self):
        """Queue the totals' copy to the host behind the work already queued (no wait). Only their
        nonzero elements travel, as (index, value) pairs: most bins and cells are empty, and a dense
        copy means writing megabytes of fresh host memory."""
        import warp as wp

        from .landing import pack_kernel

        for name in self.unset:  # (no fold yet: a run of no chunks)
            self.totals[name].zero_()
        self.unset = set()
        sparse, host, key = self.sparse, _pinned(self.device, self.sparse), (str(self.device), "sparse count")
        if key not in _CLEAN:
            sparse["count"].zero_()
        _CLEAN.discard(key)
        if self.flat.size:
            wp.launch(
                pack_kernel(),
                dim=self.flat.size,
                inputs=[self.flat],
                outputs=[sparse["count"], sparse["index"], sparse["value"]],
                device=self.device,
            )
        for name in ("count", "index", "value"):
            wp.copy(host[name], sparse[name])
        self.requested = self.device.stream.record_event() if self.device.is_cuda else None

    def receive(self, tally: TallyTotals):
        """The totals `request` queued, into `tally`, once copied; the dense arrays when more than
        SPARSE_CAPACITY elements are nonzero. The pairs' count is zeroed again after it is read,
        off the next run's path (the count is known zero in `_CLEAN`)."""
        import warp as wp

        sparse, host, key = self.sparse, _pinned(self.device, self.sparse), (str(self.device), "sparse count")
        if self.requested is not None:
            wp.synchronize_event(self.requested)
        count = int(host["count"].numpy()[0])
        sparse["count"].zero_()
        if self.device.is_cuda:
            _CLEAN.add(key)
        if count > host["index"].size:
            tally.set({name: arr.numpy() for name, arr in self.totals.items()})
        else:
            tally.scatter(host["index"].numpy()[:count], host["value"].numpy()[:count])

    def before_chunk(self):
        """Before a chunk's kernel: its count arrays are no longer known to be zero (an inactive
        tally's kernel counts nothing: the kept arrays stay as they are)."""
        if self.active:
            _CLEAN.difference_update((str(self.device), "counts " + name) for name in COUNTS)


class TallyTotals:
    """The run's landing counts so far (int64): `hist` (rows: range, speed, distance by hazard
    level; bins of `tallies.bins`), `map_counts` (level, cell; then outside, elsewhere),
    `map_energy` (per column, in quanta) and, following pellets to rest, `rest` (the rest
    distances from the shooter of the pellets at rest or embedded, bins of `tallies.bins`). Held as their nonzero elements after `scatter` (most
    bins and cells are empty), as dense arrays from the first read of one of them on."""

    def __init__(self, setup: TallySetup):
        levels, width = setup.levels, setup.cells + 2
        self.setup = setup
        self.shapes = {
            "hist": (setup.hist_rows, BINS),
            "map_counts": (levels, width) if setup.has_map else (0, 0),
            "map_energy": (width,) if setup.has_map else (0,),
            "rest": (BINS,) if setup.rest else (0,),
            "exposure": (levels, width) if setup.has_map and setup.path else (0, 0),
            "places": (levels, len(setup.places)) if setup.path else (0, 0),
        }
        self._dense: dict | None = None
        self._pairs = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))  # (flat index, value), nonzero only

    @property
    def hist(self) -> np.ndarray:
        return self._arrays()["hist"]

    @property
    def map_counts(self) -> np.ndarray:
        return self._arrays()["map_counts"]

    @property
    def map_energy(self) -> np.ndarray:
        return self._arrays()["map_energy"]

    @property
    def rest(self) -> np.ndarray:
        return self._arrays()["rest"]

    @property
    def exposure(self) -> np.ndarray:
        """Passes within body height by level at entry (level, cell; then off the grid, unused)."""
        return self._arrays()["exposure"]

    @property
    def points(self) -> np.ndarray:
        """Pellets by their highest level at each named place (level, place)."""
        return self._arrays()["places"]

    def _arrays(self) -> dict:
        if self._dense is None:
            flat = np.zeros(sum(int(np.prod(shape)) for shape in self.shapes.values()), dtype=np.int64)
            flat[self._pairs[0]] = self._pairs[1]
            self._dense = self._split(flat)
        return self._dense

    def _split(self, flat) -> dict:
        bounds = np.cumsum([0] + [int(np.prod(shape)) for shape in self.shapes.values()])
        return {name: flat[bounds[i] : bounds[i + 1]].reshape(shape) for i, (name, shape) in enumerate(self.shapes.items())}

    def set(self, totals: dict):
        """The counts so far, from `DeviceTally.totals` ({name: flat int64 array}) copied to the host."""
        self._dense = {name: np.array(totals[name], dtype=np.int64).reshape(self.shapes[name]) for name in COUNTS}

    def scatter(self, index, value):
        """The counts so far from their nonzero elements: `value` at `index` of `flat()`'s order, the
        rest zero (`DeviceTally.receive`)."""
        self._pairs = (np.asarray(index, dtype=np.int64).copy(), np.asarray(value, dtype=np.int64).copy())
        self._dense = None

    def flat(self) -> np.ndarray:
        """All counts in one int64 vector (what /progress keeps for --resume)."""
        return np.concatenate([self._arrays()[name].ravel() for name in COUNTS])

    def load(self, flat) -> TallyTotals:
        """Counts from `flat` (as `flat()` made them)."""
        self._dense = self._split(np.array(flat, dtype=np.int64))
        return self
